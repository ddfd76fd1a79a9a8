// SPDX-License-Identifier: MIT
#pragma once

#include "draw_commands.h"
#include "kernel_types.h"
#include "pipeline/pipeline.h"
#include "render/colour_mode.h"

#include <epoxy/gl.h>

#include <cstdint>
#include <memory>
#include <vector>

namespace occ::render {

// Colour of object `id` in ColourMode::Object: a fixed pastel per object (sRGB), so that
// neighbours differ.
glm::vec3 objectColour(uint32_t id);

// Per item of `scene`, the linear RGB colour `mode` gives it (alpha 1; scene/colour.h: the shader
// lights linear colours and writes sRGB). With a hierarchy an HLOD is white in ColourMode::Model
// (its vertices carry its objects' colours); with ColourMode::Object it takes the mean of its
// subtree's objects' colours weighted by their boxes' surface areas: the single colour closest in
// squared error to the mix of objects it covers.
std::vector<glm::vec4> itemColours(const DeviceScene& scene, ColourMode mode);

// An offscreen W x H target: RGBA8 colour, R32UI item buffer (object id + 1 per pixel, 0 =
// background) and 32-bit float depth, window depth in [0, 1] as the kernels use it.
class FrameTarget {
public:
    FrameTarget(uint32_t width, uint32_t height);
    ~FrameTarget();
    FrameTarget(const FrameTarget&) = delete;
    FrameTarget& operator=(const FrameTarget&) = delete;

    uint32_t width() const { return width_; }
    uint32_t height() const { return height_; }
    GLuint framebuffer() const { return fbo_; }
    // Binds the framebuffer, sets the viewport and clears colour to the background, items to 0
    // and depth to 1 (far). with_items: later draws also write the item buffer.
    void begin(bool with_items);
    // After a drawing with items: clears the item buffer, and until endTiePass later draws write
    // items only, without depth writes, where their depth is at most the drawn depth (GL_LEQUAL):
    // the last one drawn wins, so drawing the same list again pulled towards the eye
    // (SceneRenderer::drawFullDetail's tie_pull) leaves at each pixel the last item whose surface
    // lies within the pull behind the one drawn there (or that one). Colour and depth stay.
    void beginTiePass();
    void endTiePass();
    // Read back, bottom row first (GL's order, also the kernels' "y up" order):
    void readColour(std::vector<uint8_t>& rgb) const;   // 3 * W * H bytes
    void readItems(std::vector<uint32_t>& items) const;  // W * H
    void readDepth(std::vector<float>& depth) const;     // W * H

private:
    uint32_t width_, height_;
    GLuint fbo_ = 0, colour_ = 0, items_ = 0, depth_ = 0;
};

// What drawing one pipeline frame cost the display.
struct DrawCounts {
    uint64_t uploaded_bytes = 0;  // bytes the host handed GL for the frame (geometry, commands)
    uint64_t blocks = 0;          // objects drawn
    uint64_t multi_draws = 0;     // glMultiDrawElementsIndirect calls
};

// Draws a scene with OpenGL 4.5 (a context must be current): the pipeline's reformed LOD
// meshes, the full-detail model, and boxes. Every object's world matrix and colour live in
// shader storage buffers, uploaded once; a draw of many objects is one
// glMultiDrawElementsIndirect call whose per-draw object id and depth floor are instanced
// attributes read at the command's base instance.
//
// The pipeline's active vertex arrays and index buffer are this renderer's GL buffers (it is
// their BufferProvider, slots Pipeline::kActiveVertexSlot + 0 / 1 and kIndexSlot), and so are
// the indirect commands and per-draw attributes (kCommandSlot, kDrawAttributeSlot), which the
// device writes (k::writeDrawCommands): a frame's drawing hands GL nothing from the host. CPU
// build: buffer storage mapped persistent and coherent, with a fence after each frame's draw
// that the next frame's device writes wait on. CUDA build: the same buffers registered with
// CUDA-OpenGL interop, mapped for the device's writes.
class SceneRenderer : public k::BufferProvider {
public:
    // Items coloured as `colours` says (itemColours).
    explicit SceneRenderer(const DeviceScene& scene, ColourMode colours = ColourMode::Model);
    ~SceneRenderer() override;
    SceneRenderer(const SceneRenderer&) = delete;
    SceneRenderer& operator=(const SceneRenderer&) = delete;

    // From now on the pipeline's active arrays live in this renderer's buffers (once per
    // pipeline; the renderer must outlive the pipeline's frames).
    void attach(Pipeline& pipeline);

    // Draws what the attached pipeline's last streamPass produced, into the bound target.
    DrawCounts drawFrame(const Pipeline& pipeline, const k::Camera& camera);

    // Draws objects ids[0, count) at full detail (every triangle of their meshes) into the bound
    // target. The first call uploads every mesh of the file once. tie_pull (FrameTarget's tie
    // pass): each vertex moves that fraction of its distance towards the eye, which keeps its
    // pixel and brings its depth nearer; 0 draws the objects where they are.
    void drawFullDetail(const uint32_t* ids, size_t count, const k::Camera& camera, float tie_pull = 0.0f);

    struct Box {
        glm::vec4 lo, hi, colour;  // w unused
    };
    // Draws the edges of each box as lines; with depth_test false they show through everything.
    void drawBoxes(const std::vector<Box>& boxes, const k::Camera& camera, bool depth_test);

    // k::BufferProvider: the GL buffers the device writes.
    static constexpr uint32_t kCommandSlot = 3, kDrawAttributeSlot = 4, kSlotCount = 5;
    void reserve(uint32_t slot, size_t bytes) override;
    size_t capacity(uint32_t slot) const override { return slots_[slot].capacity; }
    k::DevicePtr<void> pointer(uint32_t slot) const override;
    void beginDeviceWrites() override;
    void endDeviceWrites() override;

private:
    struct GlSlot {
        GLuint buffer = 0;
        size_t capacity = 0;
        std::unique_ptr<k::GlBufferView> view;
    };
    void uploadFullDetail();
    // Waits until GL has finished the last frame's draw (the fence after it), at most 60 s.
    void waitForLastDraw();
    // One glMultiDrawElementsIndirect of `draws` commands from the bound indirect buffer with
    // the shaded program and `vao`.
    void multiDraw(GLuint vao, uint32_t draws, const k::Camera& camera);
    void setCamera(GLuint program, const k::Camera& camera);

    const DeviceScene& scene_;
    const Pipeline* attached_ = nullptr;
    GLuint shaded_program_ = 0, box_program_ = 0;
    GLuint world_buffer_ = 0, colour_buffer_ = 0, box_buffer_ = 0, empty_vao_ = 0;
    GLuint item_vertex_colours_ = 0, vertex_colours_ = 0;  // HLODs' vertex colours (ColourMode::Model)
    GLuint vertex_normals_ = 0;                            // HLODs' vertex normals (oss NORMALS)
    GlSlot slots_[kSlotCount];
    GLsync drawn_ = nullptr;  // after the last frame's draw: the device may write again
    bool writing_ = false;    // between beginDeviceWrites and endDeviceWrites
    GLuint lod_vao_ = 0;
    // The full-detail model (measurements only): uploaded once, commands from the host.
    GLuint full_vao_ = 0, full_vertices_ = 0, full_indices_ = 0, full_attributes_ = 0, full_commands_ = 0;
    bool full_uploaded_ = false;
    std::vector<k::DrawAttributes> full_draws_;
    std::vector<k::DrawCommand> full_commands_host_;
};

}  // namespace occ::render
