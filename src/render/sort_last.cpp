// SPDX-License-Identifier: MIT
#include "render/sort_last.h"

namespace occ::render {

const std::vector<uint8_t>* SortLastCompositor::composite(FrameDisplay& display, const std::function<void()>& idle) {
    display.target().readDepth(depth_);
    display.target().readItems(items_);
    const std::vector<uint8_t>& own = display.picture();
    pixels_.resize(depth_.size());
    for (size_t i = 0; i < depth_.size(); ++i)
        pixels_[i] = {depth_[i], items_[i],
                      uint32_t(own[3 * i]) | uint32_t(own[3 * i + 1]) << 8 | uint32_t(own[3 * i + 2]) << 16};
    transport_.composite(group_, pixels_, timeout_, idle);
    if (transport_.rank() != group_.front()) return nullptr;
    rgb_.resize(3 * pixels_.size());
    for (size_t i = 0; i < pixels_.size(); ++i)
        for (int c = 0; c < 3; ++c) rgb_[3 * i + size_t(c)] = uint8_t(pixels_[i].rgb >> (8 * c));
    return &rgb_;
}

}  // namespace occ::render
