// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_types.h"
#include "pipeline/pipeline.h"

#include <epoxy/gl.h>

#include <cstdint>
#include <vector>

namespace occ::render {

// Colour of object `id` in every picture: a fixed pastel per object, so that neighbours differ.
glm::vec3 objectColour(uint32_t id);

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
    uint64_t uploaded_bytes = 0;  // vertex + index bytes sent to GL this frame
    uint64_t blocks = 0;          // objects drawn
    uint64_t multi_draws = 0;     // glMultiDrawElementsIndirect calls
};

// Draws a scene with OpenGL 4.5 (a context must be current): the pipeline's reformed LOD
// meshes, the full-detail model, and boxes. Every object's world matrix and colour live in
// shader storage buffers, uploaded once; a draw of many objects is one
// glMultiDrawElementsIndirect call whose per-draw object id is an instanced attribute read at
// the command's base instance.
class SceneRenderer {
public:
    explicit SceneRenderer(const DeviceScene& scene);
    ~SceneRenderer();
    SceneRenderer(const SceneRenderer&) = delete;
    SceneRenderer& operator=(const SceneRenderer&) = delete;

    // Draws what pipeline.runFrame just produced, into the bound target. The active vertex and
    // index arrays are mirrored in GL buffers: only the ranges whose contents changed since the
    // last call are uploaded (a block whose object, offsets and counts are unchanged costs
    // nothing; a block that grew in place uploads its new suffix).
    DrawCounts drawFrame(const Pipeline& pipeline, const k::Camera& camera);

    // Draws objects ids[0, count) at full detail (every triangle of their meshes) into the bound
    // target. The first call uploads every mesh of the file once.
    void drawFullDetail(const uint32_t* ids, size_t count, const k::Camera& camera);

    struct Box {
        glm::vec4 lo, hi, colour;  // w unused
    };
    // Draws the edges of each box as lines; with depth_test false they show through everything.
    void drawBoxes(const std::vector<Box>& boxes, const k::Camera& camera, bool depth_test);

private:
    struct BlockRecord {  // where an object's block was in the last frame's active arrays
        uint64_t frame = ~uint64_t(0);
        uint64_t voff = 0, toff = 0;
        uint32_t vc = 0, tc = 0, draw_vc = 0;
    };
    void uploadFullDetail();
    // One glMultiDrawElementsIndirect of commands_ (5 words each) for the objects draw_ids_
    // (the per-draw attribute buffer `ids`) with the shaded program.
    void multiDraw(GLuint vao, GLuint ids, uint64_t& ids_capacity, GLuint commands, const k::Camera& camera);
    void updateDepthFloors(const k::Camera& camera);
    void setCamera(GLuint program, const k::Camera& camera);

    const DeviceScene& scene_;
    GLuint shaded_program_ = 0, box_program_ = 0;
    GLuint world_buffer_ = 0, colour_buffer_ = 0, box_buffer_ = 0, empty_vao_ = 0, floor_buffer_ = 0;
    std::vector<float> depth_floors_;  // per object, for the camera below
    glm::mat4 floors_view_proj_{0.0f};
    // The active arrays' mirror.
    GLuint lod_vao_ = 0, lod_vertices_ = 0, lod_indices_ = 0, lod_ids_ = 0, lod_commands_ = 0;
    uint64_t lod_vertex_capacity_ = 0, lod_index_capacity_ = 0, lod_draw_capacity_ = 0;
    std::vector<BlockRecord> records_;
    uint64_t frames_drawn_ = 0;
    // The full-detail model.
    GLuint full_vao_ = 0, full_vertices_ = 0, full_indices_ = 0, full_ids_ = 0, full_commands_ = 0;
    uint64_t full_draw_capacity_ = 0;
    bool full_uploaded_ = false;
    std::vector<uint32_t> draw_ids_;
    std::vector<uint32_t> commands_;  // 5 words per DrawElementsIndirectCommand
};

}  // namespace occ::render
