// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "pipeline/frame_record.h"
#include "pipeline/pipeline.h"
#include "render/picture_metrics.h"
#include "render/scene_renderer.h"

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace occ::render {

struct DisplayOptions {
    // Every frame, also draw the full-detail model into an item buffer and a depth buffer and
    // measure culling against them (Peng 2014's "exact culling").
    bool exact = false;
    // Every frame, also compare the picture with the full-detail, unculled one.
    bool reference = false;
    // Also write each pixel's object (id + 1, 0 = background) into the target's item buffer:
    // sort-last compositing breaks depth ties by it, as one display's draw order (ascending
    // ids, GL_LESS: the first drawn wins) does.
    bool items = false;
    // How items are coloured: the model's colours by default; ColourMode::Uniform (every item
    // grey) makes pictures differ only in geometry and shading, the part of a comparison a
    // simplification is answerable for.
    ColourMode colours = ColourMode::Model;
    // The pixel error bound the reference's bound check counts against (PipelineOptions::tau),
    // at least one pixel (boundCheckPixels).
    float tau = 1.0f;
};

// What DisplayOptions measures, as the stats CSV's columns.
inline DisplayColumns displayColumns(const DisplayOptions& options) { return {options.exact, options.reference}; }

// Exact visibility from an item buffer (object id + 1 per pixel, 0 = background): marks every
// object with a pixel in `seen` (object_count bytes, cleared first) and returns how many.
uint64_t markSeenObjects(const uint32_t* items, uint64_t pixels, uint32_t object_count, std::vector<uint8_t>& seen);

// PSNR in dB of two same-sized byte images (100 when identical, the cap for "no difference"),
// and the percent of pixels (groups of `channels` bytes) that differ in any byte.
double psnrDb(const uint8_t* a, const uint8_t* b, uint64_t bytes);
double changedPixelPercent(const uint8_t* a, const uint8_t* b, uint64_t pixels, int channels);

// Draws pipeline frames with OpenGL (a context must be current on the calling thread) into an
// offscreen target the size of the pipeline's viewport, and measures them when asked.
class FrameDisplay {
public:
    // Attaches the renderer to the pipeline: its active arrays become the display's GL buffers.
    FrameDisplay(Pipeline& pipeline, uint32_t width, uint32_t height, const DisplayOptions& options);

    // Draws the frame pipeline.runFrame(pose) just produced, then the exact and reference passes
    // the options ask for. The picture stays in target() until the next call.
    DisplayStats display(const Pipeline& pipeline, const CameraPose& pose);

    // The last frame's picture, 3 * W * H bytes, bottom row first.
    const std::vector<uint8_t>& picture();
    FrameTarget& target() { return frame_; }
    SceneRenderer& renderer() { return renderer_; }

    // Draws the last frame from `camera` (its own or another, to inspect it from elsewhere)
    // with the frustum objects it culled by occlusion as red boxes and its occluders as purple
    // boxes, both drawn through everything (Peng 2014, Figure 5), into target().
    void drawCullingView(const Pipeline& pipeline, const k::Camera& camera);

    // Writes the debug pictures of the last frame into dir: NAME_aos_depth.png (the occluders'
    // depth, level 0 of the HZM), NAME_hzm_L.png for every level (scaled up to W x H), and
    // NAME_culling.png (the frame with occlusion-culled objects as red boxes and the frame's
    // occluders as purple boxes, both drawn through everything).
    void writeDebugViews(const Pipeline& pipeline, const CameraPose& pose, const std::string& dir,
                         const std::string& name);

private:
    // Replaces each reference item id + 1 in `items` by the id + 1 of the item this frame drew
    // for it (itself, or with a hierarchy the node above it in the cut); 0 stays 0.
    void mapToDrawnItems(const Pipeline& pipeline, std::vector<uint32_t>& items);
    // The item drawn for `item` (id + 1, as the item buffer holds them; 0: the background): the
    // item or the node above it in the frame's visible set; UINT32_MAX - 1 where none is drawn.
    // Cached per frame (drawn_cached_).
    uint32_t drawnItem(const Pipeline& pipeline, uint32_t item);

    const DisplayOptions options_;
    uint32_t width_, height_;
    SceneRenderer renderer_;
    FrameTarget frame_;
    std::unique_ptr<FrameTarget> full_;
    std::vector<uint8_t> picture_, full_picture_, in_pvs_, seen_;
    std::vector<uint32_t> exact_before_, exact_now_;  // the exact visible set of the last frame and this one
    bool picture_read_ = false;
    std::vector<uint32_t> items_, tied_items_[2], candidates_, our_items_, drawn_of_, tie_leaves_;
    std::vector<float> bound_distances_;
    std::vector<uint8_t> suspect_;  // by item + 1: has changed pixels beyond the bound
    bool drawn_cached_ = false;
    std::vector<uint32_t> parent_;  // with a hierarchy: each node's parent (UINT32_MAX at the root)
    k::DeviceArray<float> full_hzm_;
    k::DeviceArray<uint8_t> occluded_;
};

}  // namespace occ::render
