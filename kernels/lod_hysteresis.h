// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

namespace occ::k {

// One object of a visible set with its LOD's vertex count.
struct LodEntry {
    uint32_t object;
    uint32_t vertices;
};

// Scratch of keepSimilarLods, kept by the caller between frames.
struct LodHysteresisScratch {
    DeviceArray<uint32_t> eq1;     // Eq. 1's counts, before the hysteresis
    DeviceArray<uint64_t> raised;  // (extra << 32 | j) of the counts raised by the hysteresis
    DeviceArray<uint64_t> sums;    // their running sums, largest raise first
};

// Beyond the papers, the LOD hysteresis: for each object ids[j] (count of them, with Eq. 1's
// vertex count v = vertex_count[j]) that the last frame drew with p vertices (previous, sorted
// by object, previous_count entries), p is kept where 0 < v, 0 < p != v and |v - p| <=
// hysteresis * p (both are valid LODs). Kept counts that raise the total above max(budget, the
// sum of Eq. 1's counts) are given back, largest raise first (equal raises: larger j first),
// until the total fits. triangle_count[j] becomes maps[map_first[mesh] + vertex_count[j]] where
// the count changed. All arrays are device memory; ids ascending. Reads back three sums and
// two counts.
void keepSimilarLods(DevicePtr<const uint32_t> ids, uint32_t count, DevicePtr<const LodEntry> previous,
                     uint32_t previous_count, float hysteresis, double budget, DevicePtr<const ObjectInfo> objects,
                     DevicePtr<const uint64_t> map_first, DevicePtr<const uint32_t> maps,
                     DevicePtr<uint32_t> vertex_count, DevicePtr<uint32_t> triangle_count,
                     LodHysteresisScratch& scratch);

}  // namespace occ::k
