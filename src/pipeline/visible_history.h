// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "pipeline/occlusion_stage.h"
#include "pipeline/visible_set.h"

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace occ {

// The visible sets of the last frames, newest first: the ones this pipeline culled and, in the
// occlusion switch, the other culling rank's (from its deltas). The one history of a culling
// rank: it gives a later frame its occluder candidates (the PVS `pvs_occluder_lag` and twice that
// many frames back, this pipeline's own), the LOD hysteresis its last frame's set and the next
// delta its base.
class VisibleHistory {
public:
    struct Frame {
        uint64_t frame = UINT64_MAX;  // UINT64_MAX: none yet
        VisibleSet set;
        // For the occluder choice: the HZM-visible ids (or with the error rule's coarsened cut,
        // the fine cut) on the device; none for a set culled elsewhere.
        k::DeviceArray<uint32_t> occluders;
        uint32_t occluder_count = 0;
    };
    // Four frames, so that one rank with lag 2 has what the 3-rank switch's occluder rank has
    // (frames f - 2 and f - 4). An item visible in either of a frame's two candidate sets stays
    // a candidate, so that the PVS cannot swing between two occluder sets frame by frame (a
    // large PVS giving many occluders, then a small PVS giving few).
    static constexpr size_t kFrames = 4;

    // The slot of newly culled `frame`: the oldest, which becomes the newest (with its set and
    // no occluders).
    Frame& push(uint64_t frame, VisibleSet set);
    // The occluder candidates of `frame`: the culled frames frame - lag and frame - 2 lag.
    OccluderSources occluderSources(uint64_t frame, uint32_t lag) const;
    // The visible set of frame - 1 when it is the newest (empty otherwise): the hysteresis' base.
    std::span<const VisibleSet::Entry> lastFrameLods(uint64_t frame) const;
    // The set of `frame`, or null when the history no longer (or never) had it.
    const VisibleSet* find(uint64_t frame) const;

private:
    Frame frames_[kFrames];
};

}  // namespace occ
