// SPDX-License-Identifier: MIT
#include "keep_visible.h"

#include "device_access.h"
#include "for_each_index.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/scatter.h>
#include <thrust/transform.h>

namespace occ::k {

namespace {

struct KeepRecent {
    const uint32_t* ids;
    const uint8_t* occluded;
    uint32_t now;  // frame + 1
    uint32_t keep_frames, step;
    uint32_t* last_visible;
    uint32_t* returned;
    uint8_t* drop;

    OCC_HD void operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        const uint32_t seen = last_visible[id];
        if (occluded[j] == 0) {
            if (seen != 0 && seen < now && now - seen > step && now - seen <= step + keep_frames) returned[id] = now;
            last_visible[id] = now;
            drop[j] = 0;
            return;
        }
        const uint32_t back = returned[id];
        const bool flickers = back != 0 && back <= now && now - back <= kFlickerMemory;
        drop[j] = (flickers && seen != 0 && seen <= now && now - seen <= keep_frames) ? 0 : 1;
    }
};

struct NewlyVisible {
    const uint32_t* ids;
    const uint8_t* occluded;
    const uint32_t* last_visible;
    uint32_t now;  // frame + 1
    uint32_t window;

    OCC_HD uint8_t operator()(uint32_t j) const {
        if (occluded[j] != 0) return 0;
        const uint32_t seen = last_visible[ids[j]];
        return seen == 0 || (seen < now && now - seen > window) ? 1 : 0;
    }
};

struct Nearest {
    OCC_HD float operator()(float a, float b) const { return b < a ? b : a; }
};

}  // namespace

void markNewlyVisible(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> occluded, uint32_t count, uint64_t frame,
                      uint32_t window, DevicePtr<const uint32_t> last_visible, DevicePtr<uint8_t> flags) {
    if (count == 0) return;
    const thrust::counting_iterator<uint32_t> first(0);
    withPolicy(count, [&](auto policy) {
        thrust::transform(policy, first, first + count, raw(flags),
                          NewlyVisible{raw(ids), raw(occluded), raw(last_visible), uint32_t(frame + 1), window});
    });
}

void mergeNearest(DevicePtr<float> depth, DevicePtr<const float> other, uint32_t count) {
    if (count == 0) return;
    thrust::transform(onDevice(), raw(depth), raw(depth) + count, raw(other), raw(depth), Nearest{});
}

void scatterFlags(DevicePtr<const uint32_t> indices, DevicePtr<const uint8_t> values, uint32_t count,
                  DevicePtr<uint8_t> occluded) {
    if (count == 0) return;
    withPolicy(count, [&](auto policy) { thrust::scatter(policy, raw(values), raw(values) + count, raw(indices), raw(occluded)); });
}

void keepRecentlyVisible(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> occluded, uint32_t count,
                         uint64_t frame, uint32_t keep_frames, uint32_t step, DevicePtr<uint32_t> last_visible,
                         DevicePtr<uint32_t> returned, DevicePtr<uint8_t> drop) {
    if (count == 0) return;
    const thrust::counting_iterator<uint32_t> first(0);
    forEachIndex(count, KeepRecent{raw(ids), raw(occluded), uint32_t(frame + 1), keep_frames, step, raw(last_visible),
                                   raw(returned), raw(drop)});
}

}  // namespace occ::k
