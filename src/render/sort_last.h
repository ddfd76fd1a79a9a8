// SPDX-License-Identifier: MIT
#pragma once

#include "net/transport.h"
#include "render/frame_display.h"

#include <chrono>
#include <cstdint>
#include <functional>
#include <vector>

namespace occ::render {

// The display side of sort-last compositing (2 + P ranks, docs/scaling.md): every display rank
// hands its last drawn frame (colour, depth and object ids; FrameDisplay with
// DisplayOptions::items) to Transport::composite, and the group's first rank gets the picture
// of all partitions. Stages through host memory.
class SortLastCompositor {
public:
    SortLastCompositor(Transport& transport, std::vector<int> group, std::chrono::milliseconds timeout)
        : transport_(transport), group_(std::move(group)), timeout_(timeout) {}

    // Composites `display`'s last frame with the other display ranks' of the same frame. Returns
    // the picture (3 * W * H bytes, bottom row first) on the group's first rank, nullptr on the others.
    // While the others are not there yet it calls `idle` (when given; Transport::composite).
    const std::vector<uint8_t>* composite(FrameDisplay& display, const std::function<void()>& idle = {});

private:
    Transport& transport_;
    std::vector<int> group_;
    std::chrono::milliseconds timeout_;
    std::vector<DepthPixel> pixels_;
    std::vector<float> depth_;
    std::vector<uint32_t> items_;
    std::vector<uint8_t> rgb_;
};

}  // namespace occ::render
