// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"

#include <cstdint>

namespace occ::k {

// Upper bound of the pyramid: a side of 32768 = 2^15 texels needs 16 levels down to 1.
inline constexpr uint32_t kHzmMaxLevels = 16;
inline constexpr uint32_t kHzmMaxSide = 32768;

// The Hierarchical Z-Map (HZM of Peng 2014, Eq. 4) as a max-depth pyramid. Level 0 is the full
// W x H depth buffer; level l+1 has ceil(w/2) x ceil(h/2) texels, each the MAX of the (up to)
// 2x2 texels below it (non-power-of-two: the last odd row/column folds in, so texel (x, y) of
// level l+1 covers texels [2x, min(2x+2, w)) x [2y, min(2y+2, h)) of level l). Levels are
// stored back to back in one array, level l at offset[l], row-major (index y*width[l]+x).
// level_count counts levels down to 1x1 inclusive. Plain data: kernels take it by value.
struct HzmLevels {
    DevicePtr<const float> data;
    uint32_t level_count;
    uint32_t width[kHzmMaxLevels];
    uint32_t height[kHzmMaxLevels];
    uint64_t offset[kHzmMaxLevels];
};

// Fills every field of `out` but data (left null) for a w x h level 0. w and h must be in
// [1, 32768]; a zero side gives level_count 0.
inline void hzmLayout(uint32_t w, uint32_t h, HzmLevels& out) {
    out.data = {};
    out.level_count = 0;
    if (w == 0 || h == 0) return;
    uint64_t offset = 0;
    for (uint32_t l = 0; l < kHzmMaxLevels; ++l) {
        out.width[l] = w;
        out.height[l] = h;
        out.offset[l] = offset;
        out.level_count = l + 1;
        offset += uint64_t(w) * h;
        if (w == 1 && h == 1) break;
        w = (w + 1) / 2;
        h = (h + 1) / 2;
    }
}

// Floats the whole pyramid of a w x h depth buffer takes (all levels, level 0 included).
inline uint64_t hzmTotalTexels(uint32_t w, uint32_t h) {
    HzmLevels layout;
    hzmLayout(w, h, layout);
    if (layout.level_count == 0) return 0;
    const uint32_t last = layout.level_count - 1;
    return layout.offset[last] + uint64_t(layout.width[last]) * layout.height[last];
}

}  // namespace occ::k
