// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"

#include <cstdint>

namespace occ::k {

// Beyond Peng & Cao, the "assumed visible" rule of CHC++ (Mattausch, Bittner and Wimmer 2008,
// "CHC++: Coherent hierarchical culling revisited"): an object the HZM test found visible stays
// in the visible set for keep_frames more frames while it is in the frustum, even where a later
// HZM hides it. A conservative depth raster leaves a crack of up to a pixel where two occluders
// meet without sharing an edge (inner coverage proves neither covers the pixel), and as the
// camera moves by less than a pixel a frame such cracks open and close: on the plant walks
// whole groups of distant objects show through one frame and hide the next. Keeping them turns
// that flicker into one addition and one removal; culling stays conservative (nothing is
// culled that the HZM test would keep).
//
// For j < count, with id = ids[j] (an object index) and occluded[j] as hzmTest wrote it:
// - occluded[j] == 0: last_visible[id] = frame + 1, drop[j] = 0;
// - else drop[j] = 0 (kept) if last_visible[id] != 0 and frame + 1 - last_visible[id] <=
//   keep_frames (the object was found visible at most keep_frames frames before `frame`),
//   else drop[j] = 1.
// last_visible holds one entry per object (0 = never seen; the caller zeroes it once) and
// records frame + 1 modulo 2^32; a frame earlier than the one recorded keeps nothing. Only
// visible objects update it: a kept object is not seen again by being kept. keep_frames == 0
// keeps nothing (drop = occluded) but still records. All arrays in device memory; ids in
// parallel.
void keepRecentlyVisible(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> occluded, uint32_t count,
                         uint64_t frame, uint32_t keep_frames, DevicePtr<uint32_t> last_visible,
                         DevicePtr<uint8_t> drop);

// The late pass's test (niagara's two-phase occlusion culling, Kapoulkine 2020): flags[j] = 1
// for each j < count whose object ids[j] the HZM test found visible (occluded[j] == 0) and, as
// last_visible records it (keepRecentlyVisible: frame + 1 of the last frame seen, 0 = never),
// was never seen or not within the `window` frames before `frame` (last_visible[id] + window <
// frame + 1), else 0. The pipeline's window covers the frames whose visible sets gave this
// frame's occluders. Call it before keepRecentlyVisible records this frame. All arrays in
// device memory; ids in parallel.
void markNewlyVisible(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> occluded, uint32_t count, uint64_t frame,
                      uint32_t window, DevicePtr<const uint32_t> last_visible, DevicePtr<uint8_t> flags);

// depth[i] = min(depth[i], other[i]) for i < count: two depth buffers of one view as one.
void mergeNearest(DevicePtr<float> depth, DevicePtr<const float> other, uint32_t count);

// occluded[indices[i]] = values[i] for i < count (indices distinct); device memory.
void scatterFlags(DevicePtr<const uint32_t> indices, DevicePtr<const uint8_t> values, uint32_t count,
                  DevicePtr<uint8_t> occluded);

}  // namespace occ::k
