// SPDX-License-Identifier: MIT
#include "render/scene_renderer.h"

#include "render/gl_check.h"
#include "render/shaders.h"
#include "scene/splitmix.h"

#include <algorithm>

namespace occ::render {

namespace {

constexpr float kBackground[4] = {0.08f, 0.09f, 0.11f, 1.0f};
constexpr GLuint kWorldBinding = 0, kColourBinding = 1, kBoxBinding = 2, kDepthFloorBinding = 3;
constexpr GLint kViewProjLocation = 0, kEyeLocation = 1;
constexpr uint32_t kCommandWords = 5;  // count, instanceCount, firstIndex, baseVertex, baseInstance

GLuint makeBuffer() {
    GLuint b = 0;
    glCreateBuffers(1, &b);
    return b;
}

// (Re)allocates `buffer` to hold at least `bytes`, growing by half again so that a slowly
// growing frame does not reallocate every time. Returns true if it reallocated (contents lost).
bool reserve(GLuint buffer, uint64_t& capacity, uint64_t bytes) {
    if (bytes <= capacity && capacity > 0) return false;
    capacity = std::max<uint64_t>({bytes + bytes / 2, 4096, capacity});
    OCC_GL_CHECK(glNamedBufferData(buffer, GLsizeiptr(capacity), nullptr, GL_DYNAMIC_DRAW));
    return true;
}

// A vertex array of position (location 0, vec3 floats) and per-draw object id (location 1,
// uint, divisor 1) with its element buffer.
GLuint makeVertexArray(GLuint positions, GLuint ids, GLuint indices) {
    GLuint vao = 0;
    glCreateVertexArrays(1, &vao);
    glVertexArrayVertexBuffer(vao, 0, positions, 0, sizeof(glm::vec3));
    glEnableVertexArrayAttrib(vao, 0);
    glVertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);
    glVertexArrayAttribBinding(vao, 0, 0);
    glVertexArrayVertexBuffer(vao, 1, ids, 0, sizeof(uint32_t));
    glVertexArrayBindingDivisor(vao, 1, 1);
    glEnableVertexArrayAttrib(vao, 1);
    glVertexArrayAttribIFormat(vao, 1, 1, GL_UNSIGNED_INT, 0);
    glVertexArrayAttribBinding(vao, 1, 1);
    glVertexArrayElementBuffer(vao, indices);
    return vao;
}

}  // namespace

glm::vec3 objectColour(uint32_t id) {
    const uint64_t r = SplitMix64(0x6f63637377697463ull ^ id).next();
    // Pastels: every channel in [0.35, 0.95].
    return {0.35f + 0.6f * float(r & 0xff) / 255.0f, 0.35f + 0.6f * float((r >> 8) & 0xff) / 255.0f,
            0.35f + 0.6f * float((r >> 16) & 0xff) / 255.0f};
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

SceneRenderer::SceneRenderer(const DeviceScene& scene) : scene_(scene) {
    shaded_program_ = compileProgram("shaded", shaders::kShadedVert, shaders::kShadedFrag);
    box_program_ = compileProgram("box", shaders::kBoxVert, shaders::kBoxFrag);

    const uint32_t n = scene.object_count;
    world_buffer_ = makeBuffer();
    colour_buffer_ = makeBuffer();
    box_buffer_ = makeBuffer();
    std::vector<glm::vec4> colours(n);
    for (uint32_t i = 0; i < n; ++i) colours[i] = glm::vec4(objectColour(i), 1.0f);
    OCC_GL_CHECK(glNamedBufferStorage(world_buffer_, GLsizeiptr(std::max<size_t>(1, n) * sizeof(glm::mat4)),
                                      n ? scene.world.data() : nullptr, n ? 0 : GL_DYNAMIC_STORAGE_BIT));
    OCC_GL_CHECK(glNamedBufferStorage(colour_buffer_, GLsizeiptr(std::max<size_t>(1, n) * sizeof(glm::vec4)),
                                      n ? colours.data() : nullptr, n ? 0 : GL_DYNAMIC_STORAGE_BIT));
    glCreateVertexArrays(1, &empty_vao_);
    floor_buffer_ = makeBuffer();
    depth_floors_.assign(std::max<uint32_t>(1, n), 0.0f);
    OCC_GL_CHECK(glNamedBufferStorage(floor_buffer_, GLsizeiptr(depth_floors_.size() * sizeof(float)),
                                      depth_floors_.data(), GL_DYNAMIC_STORAGE_BIT));

    lod_vertices_ = makeBuffer();
    lod_indices_ = makeBuffer();
    lod_ids_ = makeBuffer();
    lod_commands_ = makeBuffer();
    lod_vao_ = makeVertexArray(lod_vertices_, lod_ids_, lod_indices_);
    records_.resize(n);

    full_vertices_ = makeBuffer();
    full_indices_ = makeBuffer();
    full_ids_ = makeBuffer();
    full_commands_ = makeBuffer();
    full_vao_ = makeVertexArray(full_vertices_, full_ids_, full_indices_);
    checkGlError("SceneRenderer setup", __FILE__, __LINE__);
}

SceneRenderer::~SceneRenderer() {
    const GLuint buffers[] = {floor_buffer_, world_buffer_,  colour_buffer_, box_buffer_,   lod_vertices_,  lod_indices_,
                              lod_ids_,       lod_commands_,  full_vertices_, full_indices_, full_ids_,
                              full_commands_};
    glDeleteBuffers(GLsizei(std::size(buffers)), buffers);
    const GLuint arrays[] = {empty_vao_, lod_vao_, full_vao_};
    glDeleteVertexArrays(GLsizei(std::size(arrays)), arrays);
    glDeleteProgram(shaded_program_);
    glDeleteProgram(box_program_);
}

void SceneRenderer::updateDepthFloors(const k::Camera& camera) {
    if (camera.view_proj == floors_view_proj_) return;
    floors_view_proj_ = camera.view_proj;
    const glm::mat4& m = camera.view_proj;
    for (uint32_t i = 0; i < scene_.object_count; ++i) {
        const k::Aabb& b = scene_.objects[i].aabb;
        float nearest = 1.0f;
        for (int c = 0; c < 8; ++c) {
            const glm::vec4 clip = m * glm::vec4(c & 1 ? b.max.x : b.min.x, c & 2 ? b.max.y : b.min.y,
                                                 c & 4 ? b.max.z : b.min.z, 1.0f);
            // A box reaching the near plane (or NaN) gets no floor.
            if (!(clip.w > camera.near_plane) || !(clip.z >= -clip.w)) {
                nearest = 0.0f;
                break;
            }
            nearest = std::min(nearest, clip.z / clip.w * 0.5f + 0.5f);
        }
        // A hair nearer than the box, for the rounding of this float projection.
        depth_floors_[i] = std::max(0.0f, nearest - 1e-6f);
    }
    if (scene_.object_count > 0)
        glNamedBufferSubData(floor_buffer_, 0, GLsizeiptr(scene_.object_count * sizeof(float)), depth_floors_.data());
}

void SceneRenderer::setCamera(GLuint program, const k::Camera& camera) {
    glProgramUniformMatrix4fv(program, kViewProjLocation, 1, GL_FALSE, &camera.view_proj[0][0]);
    if (program == shaded_program_) {
        glProgramUniform3fv(program, kEyeLocation, 1, &camera.eye[0]);
        updateDepthFloors(camera);
        glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kDepthFloorBinding, floor_buffer_);
    }
}

DrawCounts SceneRenderer::drawFrame(const Pipeline& pipeline, const k::Camera& camera) {
    DrawCounts counts;
    const k::ActiveLayout& layout = pipeline.layout();
    const uint32_t* draw_vc = pipeline.drawVertices();
    const uint32_t* draw_tc = pipeline.drawTriangles();
    const uint64_t frame = frames_drawn_++;

    const bool vertices_lost =
        reserve(lod_vertices_, lod_vertex_capacity_, std::max<uint64_t>(1, layout.vertex_total) * sizeof(glm::vec3));
    const bool indices_lost = reserve(lod_indices_, lod_index_capacity_,
                                      std::max<uint64_t>(1, layout.triangle_total) * 3 * sizeof(uint32_t));
    const glm::vec3* vertices = pipeline.activeVertices();
    const uint32_t* indices = pipeline.indices();
    // Dirty ranges, merged when adjacent so that a frame that moved everything is one upload.
    uint64_t v_begin = 0, v_end = 0, i_begin = 0, i_end = 0;
    const auto flushVertices = [&] {
        if (v_end == v_begin) return;
        glNamedBufferSubData(lod_vertices_, GLintptr(v_begin * sizeof(glm::vec3)),
                             GLsizeiptr((v_end - v_begin) * sizeof(glm::vec3)), vertices + v_begin);
        counts.uploaded_bytes += (v_end - v_begin) * sizeof(glm::vec3);
        v_begin = v_end = 0;
    };
    const auto flushIndices = [&] {
        if (i_end == i_begin) return;
        glNamedBufferSubData(lod_indices_, GLintptr(i_begin * sizeof(uint32_t)),
                             GLsizeiptr((i_end - i_begin) * sizeof(uint32_t)), indices + i_begin);
        counts.uploaded_bytes += (i_end - i_begin) * sizeof(uint32_t);
        i_begin = i_end = 0;
    };
    const auto dirtyVertices = [&](uint64_t b, uint64_t e) {
        if (b == e) return;
        if (v_end != b) flushVertices(), v_begin = b;
        v_end = e;
    };
    const auto dirtyIndices = [&](uint64_t b, uint64_t e) {
        if (b == e) return;
        if (i_end != b) flushIndices(), i_begin = b;
        i_end = e;
    };

    draw_ids_.clear();
    commands_.clear();
    for (uint32_t j = 0; j < layout.count; ++j) {
        const uint32_t id = layout.objects[j];
        BlockRecord& r = records_[id];
        const uint64_t voff = layout.vertex_offset[j], toff = layout.triangle_offset[j];
        const uint32_t vc = layout.vertex_count[j], tc = layout.triangle_count[j];
        // A block's vertices are its mesh's first vc positions, so a block that stayed where it
        // was holds them already up to the old count.
        const bool was_here = !vertices_lost && r.frame + 1 == frame && r.voff == voff;
        dirtyVertices(voff + (was_here ? std::min(vc, r.vc) : 0), voff + vc);
        const bool same_indices = !indices_lost && was_here && r.toff == toff &&
                                  r.vc == vc && r.tc == tc && r.draw_vc == draw_vc[j];
        if (!same_indices) dirtyIndices(3 * toff, 3 * (toff + tc));
        r = {frame, voff, toff, vc, tc, draw_vc[j]};
        if (draw_tc[j] == 0) continue;
        commands_.insert(commands_.end(), {3 * draw_tc[j], 1, uint32_t(3 * toff), 0, uint32_t(draw_ids_.size())});
        draw_ids_.push_back(id);
    }
    flushVertices();
    flushIndices();
    counts.blocks = draw_ids_.size();

    if (!draw_ids_.empty()) {
        multiDraw(lod_vao_, lod_ids_, lod_draw_capacity_, lod_commands_, camera);
        counts.multi_draws = 1;
    }
    checkGlError("drawing the frame", __FILE__, __LINE__);
    return counts;
}

void SceneRenderer::multiDraw(GLuint vao, GLuint ids, uint64_t& ids_capacity, GLuint commands,
                              const k::Camera& camera) {
    reserve(ids, ids_capacity, draw_ids_.size() * sizeof(uint32_t));
    glNamedBufferSubData(ids, 0, GLsizeiptr(draw_ids_.size() * sizeof(uint32_t)), draw_ids_.data());
    glNamedBufferData(commands, GLsizeiptr(commands_.size() * sizeof(uint32_t)), commands_.data(), GL_STREAM_DRAW);
    glUseProgram(shaded_program_);
    setCamera(shaded_program_, camera);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kWorldBinding, world_buffer_);
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, kColourBinding, colour_buffer_);
    glBindVertexArray(vao);
    glBindBuffer(GL_DRAW_INDIRECT_BUFFER, commands);
    glMultiDrawElementsIndirect(GL_TRIANGLES, GL_UNSIGNED_INT, nullptr, GLsizei(draw_ids_.size()), 0);
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

void SceneRenderer::drawFullDetail(const uint32_t* ids, size_t count, const k::Camera& camera) {
    if (!full_uploaded_) uploadFullDetail();
    const auto meshes = scene_.file->meshRecords();
    draw_ids_.clear();
    commands_.clear();
    for (size_t j = 0; j < count; ++j) {
        const oss::MeshRecord& m = meshes[scene_.objects[ids[j]].mesh];
        if (m.triangle_count == 0) continue;
        commands_.insert(commands_.end(), {3 * m.triangle_count, 1, uint32_t(3 * m.triangle_first),
                                           uint32_t(m.vertex_first), uint32_t(draw_ids_.size())});
        draw_ids_.push_back(ids[j]);
    }
    if (!draw_ids_.empty()) multiDraw(full_vao_, full_ids_, full_draw_capacity_, full_commands_, camera);
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
