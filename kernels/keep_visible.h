// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"

#include <cstdint>

namespace occ::k {

// Beyond Peng & Cao, after the "assumed visible" rule of CHC++ (Mattausch, Bittner and Wimmer
// 2008, "CHC++: Coherent hierarchical culling revisited"), but only for objects that flicker. A
// conservative depth raster leaves a crack of up to a pixel where two occluders meet without
// sharing an edge (inner coverage proves neither covers the pixel), and as the camera moves by
// less than a pixel a frame such cracks open and close: on the plant walks whole groups of
// distant objects show through one frame and hide the next. An object that came back after
// such a short gap stays in the visible set through the next gaps of up to keep_frames frames,
// for kFlickerMemory frames after it last came back; an object that simply goes out of sight is
// dropped at once (keeping every object CHC++'s way cost a few per cent of culling on the
// walks). Culling stays conservative: nothing is culled that the HZM test would keep.
//
// Records per object (one entry each, 0 = never; the caller zeroes them once), frame + 1
// modulo 2^32 of: last_visible, the last frame the object was found visible; returned, the last
// frame it was found visible after a gap of more than `step` and at most step + keep_frames
// frames (step: the frames between two culls of this record, 1, or 2 for a record per parity).
// For j < count, with id = ids[j] (an object index), now = frame + 1 and occluded[j] as
// hzmTest wrote it:
// - occluded[j] == 0: drop[j] = 0; returned[id] = now if last_visible[id] != 0 and step <
//   now - last_visible[id] <= step + keep_frames; then last_visible[id] = now;
// - else drop[j] = 0 (kept) if both records are set, now - last_visible[id] <= keep_frames and
//   now - returned[id] <= kFlickerMemory, else drop[j] = 1.
// A frame earlier than the one recorded keeps nothing. Only visible objects update the
// records: being kept is not being seen. keep_frames == 0 keeps nothing (drop = occluded) but
// still records. All arrays in device memory; ids in parallel.
inline constexpr uint32_t kFlickerMemory = 32;
void keepRecentlyVisible(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> occluded, uint32_t count,
                         uint64_t frame, uint32_t keep_frames, uint32_t step, DevicePtr<uint32_t> last_visible,
                         DevicePtr<uint32_t> returned, DevicePtr<uint8_t> drop);

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
