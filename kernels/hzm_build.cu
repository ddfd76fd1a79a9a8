// SPDX-License-Identifier: MIT
#include "hzm_build.h"

#include "host_device.h"
#include "device_access.h"
#include "for_each_index.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

// One texel of level l+1 from the (up to) 2x2 texels of level l below it: the far edge of an
// odd-sized level has a single column or row under the last texel.
struct ReduceMax {
    const float* below;
    float* above;
    uint32_t below_width, below_height, above_width;

    OCC_HD void operator()(uint32_t i) const {
        const uint32_t x = i % above_width, y = i / above_width;
        const uint32_t x0 = 2 * x, y0 = 2 * y;
        const uint32_t x1 = x0 + 1 < below_width ? x0 + 1 : x0;
        const uint32_t y1 = y0 + 1 < below_height ? y0 + 1 : y0;
        const float* row0 = below + uint64_t(y0) * below_width;
        const float* row1 = below + uint64_t(y1) * below_width;
        above[i] = maxf(maxf(row0[x0], row0[x1]), maxf(row1[x0], row1[x1]));
    }
};

}  // namespace

void hzmBuild(DevicePtr<float> level_memory, uint32_t width, uint32_t height) {
    float* const levels = raw(level_memory);
    HzmLevels layout;
    hzmLayout(width, height, layout);
    for (uint32_t l = 1; l < layout.level_count; ++l) {
        const uint32_t texels = layout.width[l] * layout.height[l];
        forEachIndex(texels, ReduceMax{levels + layout.offset[l - 1], levels + layout.offset[l], layout.width[l - 1],
                                     layout.height[l - 1], layout.width[l]});
    }
}

}  // namespace occ::k
