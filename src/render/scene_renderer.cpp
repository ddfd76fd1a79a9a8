// SPDX-License-Identifier: MIT
#include "render/scene_renderer.h"

#include "render/gl_check.h"
#include "render/shaders.h"
#include "scene/colour.h"
#include "scene/splitmix.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <span>
#include <unordered_map>

namespace occ::render {

namespace {

constexpr float kBackground[4] = {0.08f, 0.09f, 0.11f, 1.0f};
constexpr GLuint kWorldBinding = 0, kColourBinding = 1, kBoxBinding = 2, kItemVertexColourBinding = 3,
                 kVertexColourBinding = 4, kVertexNormalBinding = 5;
constexpr GLint kViewProjLocation = 0, kEyeLocation = 1, kTiePullLocation = 2;

GLuint makeBuffer() {
    GLuint b = 0;
    glCreateBuffers(1, &b);
    return b;
}

// Points `vao` at positions (location 0, vec3 floats), the per-draw attributes (object id at
// location 1 and depth floor at location 2, divisor 1, k::DrawAttributes) and the indices.
void bindVertexArray(GLuint vao, GLuint positions, GLuint attributes, GLuint indices) {
    glVertexArrayVertexBuffer(vao, 0, positions, 0, sizeof(glm::vec3));
    glEnableVertexArrayAttrib(vao, 0);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, 0, 0);
    glVertexArrayVertexBuffer(vao, 1, attributes, 0, sizeof(k::DrawAttributes));
    glVertexArrayBindingDivisor(vao, 1, 1);
    glEnableVertexArrayAttrib(vao, 1);
    glVertexArrayAttribIFormat(vao, 1, 1, GL_UNSIGNED_INT, offsetof(k::DrawAttributes, object));
    glVertexArrayAttribBinding(vao, 1, 1);
    glEnableVertexArrayAttrib(vao, 2);
    glVertexArrayAttribFormat(vao, 2, 1, GL_FLOAT, GL_FALSE, offsetof(k::DrawAttributes, depth_floor));
    glVertexArrayAttribBinding(vao, 2, 1);
    glVertexArrayElementBuffer(vao, indices);
}

}  // namespace

glm::vec3 objectColour(uint32_t id) {
    const uint64_t r = SplitMix64(0x6f63637377697463ull ^ id).next();
    // Pastels: every channel in [0.35, 0.95].
    return {0.35f + 0.6f * float(r & 0xff) / 255.0f, 0.35f + 0.6f * float((r >> 8) & 0xff) / 255.0f,
            0.35f + 0.6f * float((r >> 16) & 0xff) / 255.0f};
}

std::vector<glm::vec4> itemColours(const DeviceScene& scene, ColourMode mode) {
    const uint32_t n = scene.item_count;
    const auto linear = [](glm::vec3 srgb) {
        return glm::vec4(srgbToLinear(srgb.r), srgbToLinear(srgb.g), srgbToLinear(srgb.b), 1.0f);
    };
    // The grey of --colours uniform (sRGB 0.65).
    std::vector<glm::vec4> colours(n, linear(glm::vec3(0.65f)));
    if (mode == ColourMode::Uniform) return colours;
    const std::span<const oss::ObjectDisk> objects =
        scene.file ? scene.file->objects() : std::span<const oss::ObjectDisk>{};
    const auto colourOf = [&](uint32_t object) {
        if (mode == ColourMode::Object) return linear(objectColour(object));
        if (object >= objects.size()) return colours[0];
        const float* c = objects[object].color;
        return glm::vec4(glm::clamp(glm::vec3(c[0], c[1], c[2]), 0.0f, 1.0f), 1.0f);
    };
    if (!scene.nodes) {
        for (uint32_t i = 0; i < n; ++i) colours[i] = colourOf(i);
        return colours;
    }
    if (mode == ColourMode::Model) {
        // An HLOD's vertices carry its objects' colours (the .oss's COLOURS): its own is white.
        for (uint32_t i = 0; i < n; ++i)
            colours[i] = scene.host_nodes[i].child_count == 0 ? colourOf(scene.host_nodes[i].object) : glm::vec4(1.0f);
        return colours;
    }
    std::vector<glm::dvec4> sum(n, glm::dvec4(0.0));  // rgb x area, area
    for (uint32_t i = n; i-- > 0;) {  // children come after their parent
        const DeviceScene::NodeLinks& node = scene.host_nodes[i];
        if (node.child_count == 0) {
            colours[i] = colourOf(node.object);
            const glm::vec3 e = scene.host_objects[i].aabb.max - scene.host_objects[i].aabb.min;
            const double area = std::max(1e-12, 2.0 * (double(e.x) * e.y + double(e.y) * e.z + double(e.z) * e.x));
            sum[i] = glm::dvec4(glm::dvec3(colours[i]) * area, area);
            continue;
        }
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) sum[i] += sum[c];
        if (sum[i].w > 0) colours[i] = glm::vec4(glm::vec3(glm::dvec3(sum[i]) / sum[i].w), 1.0f);
    }
    return colours;
}

FrameTarget::FrameTarget(uint32_t width, uint32_t height) : width_(width), height_(height) {
    glCreateFramebuffers(1, &fbo_);
    glCreateRenderbuffers(1, &colour_);
    glCreateRenderbuffers(1, &items_);
    glCreateRenderbuffers(1, &depth_);
    OCC_GL_CHECK(glNamedRenderbufferStorage(colour_, GL_RGBA8, GLsizei(width), GLsizei(height)));
    OCC_GL_CHECK(glNamedRenderbufferStorage(items_, GL_R32UI, GLsizei(width), GLsizei(height)));
    OCC_GL_CHECK(glNamedRenderbufferStorage(depth_, GL_DEPTH_COMPONENT32F, GLsizei(width), GLsizei(height)));
    glNamedFramebufferRenderbuffer(fbo_, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour_);
    glNamedFramebufferRenderbuffer(fbo_, GL_COLOR_ATTACHMENT1, GL_RENDERBUFFER, items_);
    glNamedFramebufferRenderbuffer(fbo_, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, depth_);
    const GLenum status = glCheckNamedFramebufferStatus(fbo_, GL_FRAMEBUFFER);
    if (status != GL_FRAMEBUFFER_COMPLETE)
        throw SystemError("OpenGL: the " + std::to_string(width) + "x" + std::to_string(height) +
                          " colour + item + depth framebuffer is incomplete (status 0x" + std::to_string(status) + ")");
}

FrameTarget::~FrameTarget() {
    glDeleteFramebuffers(1, &fbo_);
    glDeleteRenderbuffers(1, &colour_);
    glDeleteRenderbuffers(1, &items_);
    glDeleteRenderbuffers(1, &depth_);
}

void FrameTarget::begin(bool with_items) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, GLsizei(width_), GLsizei(height_));
    const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fbo_, 2, both);
    const GLuint no_item[4] = {0, 0, 0, 0};
    const float far_depth = 1.0f;
    glClearNamedFramebufferfv(fbo_, GL_COLOR, 0, kBackground);
    glClearNamedFramebufferuiv(fbo_, GL_COLOR, 1, no_item);
    glClearNamedFramebufferfv(fbo_, GL_DEPTH, 0, &far_depth);
    if (!with_items) glNamedFramebufferDrawBuffers(fbo_, 1, both);
    OCC_GL_CHECK(glEnable(GL_DEPTH_TEST));
}

void FrameTarget::beginTiePass() {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    const GLuint no_item[4] = {0, 0, 0, 0};
    const GLenum items_only[2] = {GL_NONE, GL_COLOR_ATTACHMENT1};
    glNamedFramebufferDrawBuffers(fbo_, 2, items_only);
    glClearNamedFramebufferuiv(fbo_, GL_COLOR, 1, no_item);
    glDepthMask(GL_FALSE);
    OCC_GL_CHECK(glDepthFunc(GL_LEQUAL));
}

void FrameTarget::endTiePass() {
    glDepthFunc(GL_LESS);
    glDepthMask(GL_TRUE);
    const GLenum both[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    OCC_GL_CHECK(glNamedFramebufferDrawBuffers(fbo_, 2, both));
}

void FrameTarget::readColour(std::vector<uint8_t>& rgb) const {
    rgb.resize(size_t(3) * width_ * height_);
    glNamedFramebufferReadBuffer(fbo_, GL_COLOR_ATTACHMENT0);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 1);
    OCC_GL_CHECK(glReadPixels(0, 0, GLsizei(width_), GLsizei(height_), GL_RGB, GL_UNSIGNED_BYTE, rgb.data()));
}

void FrameTarget::readItems(std::vector<uint32_t>& items) const {
    items.resize(size_t(width_) * height_);
    glNamedFramebufferReadBuffer(fbo_, GL_COLOR_ATTACHMENT1);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    OCC_GL_CHECK(
        glReadPixels(0, 0, GLsizei(width_), GLsizei(height_), GL_RED_INTEGER, GL_UNSIGNED_INT, items.data()));
}

void FrameTarget::readDepth(std::vector<float>& depth) const {
    depth.resize(size_t(width_) * height_);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glPixelStorei(GL_PACK_ALIGNMENT, 4);
    OCC_GL_CHECK(
        glReadPixels(0, 0, GLsizei(width_), GLsizei(height_), GL_DEPTH_COMPONENT, GL_FLOAT, depth.data()));
}

SceneRenderer::SceneRenderer(const DeviceScene& scene, ColourMode colour_mode) : scene_(scene) {
    shaded_program_ = compileProgram("shaded", shaders::kShadedVert, shaders::kShadedFrag);
    box_program_ = compileProgram("box", shaders::kBoxVert, shaders::kBoxFrag);

    const uint32_t n = scene.item_count;
    world_buffer_ = makeBuffer();
    colour_buffer_ = makeBuffer();
    box_buffer_ = makeBuffer();
    const std::vector<glm::vec4> colours = itemColours(scene, colour_mode);
    OCC_GL_CHECK(glNamedBufferStorage(world_buffer_, GLsizeiptr(std::max<size_t>(1, n) * sizeof(glm::mat4)),
                                      n ? scene.host_world.data() : nullptr, n ? 0 : GL_DYNAMIC_STORAGE_BIT));
    OCC_GL_CHECK(glNamedBufferStorage(colour_buffer_, GLsizeiptr(std::max<size_t>(1, n) * sizeof(glm::vec4)),
                                      n ? colours.data() : nullptr, n ? 0 : GL_DYNAMIC_STORAGE_BIT));
    // The HLODs' vertex colours (ColourMode::Model; white in the other modes) and normals: each
    // HLOD mesh's COLOURS and NORMALS once, and per item where its mesh's start among them
    // (UINT32_MAX: none, the item's colour alone, lit by its faces). The shader reads a vertex's
    // at the draw's first plus gl_VertexID - gl_BaseVertex: a drawn LOD is a prefix of its mesh's
    // vertices. Resident, not streamed, as the full-detail occluder meshes are.
    std::vector<uint32_t> first(std::max<uint32_t>(1, n), UINT32_MAX), vertex_colours, vertex_normals;
    if (scene.nodes && scene.file) {
        std::unordered_map<uint32_t, uint32_t> first_of_mesh;
        for (uint32_t i = 0; i < n; ++i) {
            if (scene.host_nodes[i].child_count == 0) continue;
            const uint32_t mesh = scene.host_objects[i].mesh;
            const auto [at, added] = first_of_mesh.try_emplace(mesh, uint32_t(vertex_colours.size()));
            if (added) {
                const OssFile::MeshView view = scene.file->mesh(mesh);
                if (vertex_colours.size() + view.colours.size() >= UINT32_MAX)
                    throw SystemError("OpenGL: the HLODs' vertex colours do not fit 32-bit offsets");
                if (colour_mode == ColourMode::Model)
                    vertex_colours.insert(vertex_colours.end(), view.colours.begin(), view.colours.end());
                else
                    vertex_colours.resize(vertex_colours.size() + view.colours.size(), oss::kWhite);
                vertex_normals.insert(vertex_normals.end(), view.normals.begin(), view.normals.end());
            }
            first[i] = at->second;
        }
    }
    item_vertex_colours_ = makeBuffer();
    vertex_colours_ = makeBuffer();
    vertex_normals_ = makeBuffer();
    OCC_GL_CHECK(glNamedBufferStorage(item_vertex_colours_, GLsizeiptr(first.size() * sizeof(uint32_t)), first.data(), 0));
    if (vertex_colours.empty()) vertex_colours.push_back(oss::kWhite);
    OCC_GL_CHECK(glNamedBufferStorage(vertex_colours_, GLsizeiptr(vertex_colours.size() * sizeof(uint32_t)),
                                      vertex_colours.data(), 0));
    if (vertex_normals.empty()) vertex_normals.push_back(oss::kNoNormal);
    OCC_GL_CHECK(glNamedBufferStorage(vertex_normals_, GLsizeiptr(vertex_normals.size() * sizeof(uint32_t)),
                                      vertex_normals.data(), 0));
    glCreateVertexArrays(1, &empty_vao_);
    glCreateVertexArrays(1, &lod_vao_);
    for (uint32_t slot = 0; slot < kSlotCount; ++slot) reserve(slot, 4096);

    full_vertices_ = makeBuffer();
    full_indices_ = makeBuffer();
    full_attributes_ = makeBuffer();
    full_commands_ = makeBuffer();
    glCreateVertexArrays(1, &full_vao_);
    bindVertexArray(full_vao_, full_vertices_, full_attributes_, full_indices_);
    checkGlError("SceneRenderer setup", __FILE__, __LINE__);
}

SceneRenderer::~SceneRenderer() {
    if (drawn_) glDeleteSync(drawn_);
    for (GlSlot& slot : slots_) {
        slot.view.reset();
        glDeleteBuffers(1, &slot.buffer);
    }
    const GLuint buffers[] = {world_buffer_, colour_buffer_, box_buffer_, full_vertices_, full_indices_,
                              full_attributes_, full_commands_, item_vertex_colours_, vertex_colours_,
                              vertex_normals_};
    glDeleteBuffers(GLsizei(std::size(buffers)), buffers);
    const GLuint arrays[] = {empty_vao_, lod_vao_, full_vao_};
    glDeleteVertexArrays(GLsizei(std::size(arrays)), arrays);
    glDeleteProgram(shaded_program_);
    glDeleteProgram(box_program_);
}

void SceneRenderer::reserve(uint32_t slot, size_t bytes) {
    GlSlot& s = slots_[slot];
    if (bytes <= s.capacity) return;
    // Immutable storage cannot grow: a new buffer replaces the old one, once GL no longer reads it.
    waitForLastDraw();
    s.view.reset();
    glDeleteBuffers(1, &s.buffer);
    s.buffer = makeBuffer();
    if (k::GlBufferView::usesInterop()) {
        OCC_GL_CHECK(glNamedBufferStorage(s.buffer, GLsizeiptr(bytes), nullptr, 0));
        s.view = std::make_unique<k::GlBufferView>(s.buffer, nullptr);
        if (writing_) s.view->map();
    } else {
        // The device (this CPU) writes GL's memory directly: persistent, coherent mapping.
        const GLbitfield access = GL_MAP_READ_BIT | GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
        OCC_GL_CHECK(glNamedBufferStorage(s.buffer, GLsizeiptr(bytes), nullptr, access));
        void* mapped = glMapNamedBufferRange(s.buffer, 0, GLsizeiptr(bytes), access);
        if (!mapped)
            throw SystemError("OpenGL: cannot map a " + std::to_string(bytes) +
                              "-byte buffer persistently (GL 4.4 buffer storage)");
        s.view = std::make_unique<k::GlBufferView>(s.buffer, mapped);
    }
    s.capacity = bytes;
    checkGlError("allocating a device-written buffer", __FILE__, __LINE__);
}

k::DevicePtr<void> SceneRenderer::pointer(uint32_t slot) const { return slots_[slot].view->ptr(); }

void SceneRenderer::waitForLastDraw() {
    if (!drawn_) return;
    const GLenum r = glClientWaitSync(drawn_, GL_SYNC_FLUSH_COMMANDS_BIT, GLuint64(60) * 1000000000);
    glDeleteSync(drawn_);
    drawn_ = nullptr;
    if (r == GL_TIMEOUT_EXPIRED || r == GL_WAIT_FAILED)
        throw SystemError("OpenGL: the last frame's draw did not finish within 60 s");
}

void SceneRenderer::beginDeviceWrites() {
    // The last frame's draw reads the buffers the device is about to write.
    waitForLastDraw();
    for (GlSlot& slot : slots_) slot.view->map();
    writing_ = true;
}

void SceneRenderer::endDeviceWrites() {
    // The kernels have finished when they return (Thrust synchronises); GL may read now.
    k::deviceSynchronize();
    for (GlSlot& slot : slots_) slot.view->unmap();
    writing_ = false;
}

void SceneRenderer::attach(Pipeline& pipeline) {
    if (attached_ == &pipeline) return;
    if (attached_) throw std::logic_error("SceneRenderer::attach: already drawing another pipeline");
    pipeline.lendActiveArrays(*this);
    attached_ = &pipeline;
}

void SceneRenderer::setCamera(GLuint program, const k::Camera& camera) {
    glProgramUniformMatrix4fv(program, kViewProjLocation, 1, GL_FALSE, &camera.view_proj[0][0]);
    if (program == shaded_program_) glProgramUniform3fv(program, kEyeLocation, 1, &camera.eye[0]);
}

DrawCounts SceneRenderer::drawFrame(const Pipeline& pipeline, const k::Camera& camera) {
    if (attached_ != &pipeline) throw std::logic_error("SceneRenderer::drawFrame: the pipeline is not attached");
    DrawCounts counts;
    const uint32_t draws = pipeline.drawCount();
    // The device writes the frame's commands into GL's buffers.
    beginDeviceWrites();
    reserve(kCommandSlot, std::max<size_t>(1, draws) * sizeof(k::DrawCommand));
    reserve(kDrawAttributeSlot, std::max<size_t>(1, draws) * sizeof(k::DrawAttributes));
    k::writeDrawCommands(pipeline.drawBlocks(), draws, scene_.objects.ptr(), camera,
                         k::devicePtrCast<k::DrawCommand>(pointer(kCommandSlot)),
                         k::devicePtrCast<k::DrawAttributes>(pointer(kDrawAttributeSlot)));
    endDeviceWrites();
    counts.blocks = draws;
    bindVertexArray(lod_vao_, slots_[pipeline.activeVertexSlot()].buffer, slots_[kDrawAttributeSlot].buffer,
                    slots_[Pipeline::kIndexSlot].buffer);
    if (draws > 0) {
        glBindBuffer(GL_DRAW_INDIRECT_BUFFER, slots_[kCommandSlot].buffer);
        multiDraw(lod_vao_, draws, camera);
        counts.multi_draws = 1;
    }
    drawn_ = glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
    checkGlError("drawing the frame", __FILE__, __LINE__);
    return counts;
}

void SceneRenderer::multiDraw(GLuint vao, uint32_t draws, const k::Camera& camera) {
    glUseProgram(shaded_program_);
    setCamera(shaded_program_, camera);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kWorldBinding, world_buffer_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kColourBinding, colour_buffer_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kItemVertexColourBinding, item_vertex_colours_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kVertexColourBinding, vertex_colours_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kVertexNormalBinding, vertex_normals_);
    glBindVertexArray(vao);
    glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, nullptr, GLsizei(draws), 0);
}

void SceneRenderer::uploadFullDetail() {
    const OssFile& file = *scene_.file;
    const auto positions = file.allPositions();
    const auto triangles = file.allTriangles();
    OCC_GL_CHECK(glNamedBufferStorage(full_vertices_, GLsizeiptr(std::max<size_t>(1, positions.size_bytes())),
                                      positions.empty() ? nullptr : positions.data(),
                                      positions.empty() ? GL_DYNAMIC_STORAGE_BIT : 0));
    OCC_GL_CHECK(glNamedBufferStorage(full_indices_, GLsizeiptr(std::max<size_t>(1, triangles.size_bytes())),
                                      triangles.empty() ? nullptr : triangles.data(),
                                      triangles.empty() ? GL_DYNAMIC_STORAGE_BIT : 0));
    full_uploaded_ = true;
}

void SceneRenderer::drawFullDetail(const uint32_t* ids, size_t count, const k::Camera& camera, float tie_pull) {
    if (!full_uploaded_) uploadFullDetail();
    const auto meshes = scene_.file->meshRecords();
    full_draws_.clear();
    full_commands_host_.clear();
    for (size_t j = 0; j < count; ++j) {
        const k::ObjectInfo& o = scene_.host_objects[ids[j]];
        const oss::MeshRecord& m = meshes[o.mesh];
        if (m.triangle_count == 0) continue;
        full_commands_host_.push_back({3 * m.triangle_count, 1, uint32_t(3 * m.triangle_first),
                                       int32_t(m.vertex_first), uint32_t(full_draws_.size())});
        full_draws_.push_back({ids[j], k::objectDepthFloor(o.aabb, camera.view_proj, camera.near_plane)});
    }
    if (!full_draws_.empty()) {
        glNamedBufferData(full_attributes_, GLsizeiptr(full_draws_.size() * sizeof(k::DrawAttributes)),
                          full_draws_.data(), GL_STREAM_DRAW);
        glNamedBufferData(full_commands_, GLsizeiptr(full_commands_host_.size() * sizeof(k::DrawCommand)),
                          full_commands_host_.data(), GL_STREAM_DRAW);
        glBindBuffer(GL_DRAW_INDIRECT_BUFFER, full_commands_);
        glProgramUniform1f(shaded_program_, kTiePullLocation, tie_pull);
        multiDraw(full_vao_, uint32_t(full_draws_.size()), camera);
        glProgramUniform1f(shaded_program_, kTiePullLocation, 0.0f);
    }
    checkGlError("drawing at full detail", __FILE__, __LINE__);
}

void SceneRenderer::drawBoxes(const std::vector<Box>& boxes, const k::Camera& camera, bool depth_test) {
    if (boxes.empty()) return;
    glNamedBufferData(box_buffer_, GLsizeiptr(boxes.size() * sizeof(Box)), boxes.data(), GL_STREAM_DRAW);
    GLint fbo = 0;
    glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &fbo);
    // Boxes write colour only: the item buffer keeps what the geometry wrote.
    if (fbo != 0) {
        const GLenum colour_only = GL_COLOR_ATTACHMENT0;
        glNamedFramebufferDrawBuffers(GLuint(fbo), 1, &colour_only);
    }
    if (!depth_test) glDisable(GL_DEPTH_TEST);
    glUseProgram(box_program_);
    setCamera(box_program_, camera);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kBoxBinding, box_buffer_);
    glBindVertexArray(empty_vao_);
    glDrawArraysInstanced(GL_LINES, 0, 24, GLsizei(boxes.size()));
    glEnable(GL_DEPTH_TEST);
    checkGlError("drawing boxes", __FILE__, __LINE__);
}

}  // namespace occ::render
