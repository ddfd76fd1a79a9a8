// SPDX-License-Identifier: MIT
#include "pipeline/visible_history.h"

#include <algorithm>

namespace occ {

VisibleHistory::Frame& VisibleHistory::push(uint64_t frame) {
    std::rotate(frames_, frames_ + kFrames - 1, frames_ + kFrames);  // the oldest becomes [0]
    frames_[0].frame = frame;
    return frames_[0];
}

OccluderSources VisibleHistory::occluderSources(uint64_t frame, uint32_t lag, bool ascending) const {
    OccluderSources s;
    s.ascending = ascending;
    if (frame < lag) return s;
    for (const Frame& h : frames_) {
        if (h.frame == frame - lag) s.newer = h.occluders.ptr(), s.newer_count = h.occluder_count;
        if (frame >= 2 * uint64_t(lag) && h.frame == frame - 2 * uint64_t(lag) && !h.pvs.empty()) {
            s.older = h.occluders.ptr();
            s.older_count = h.occluder_count;
            s.has_older = true;
        }
    }
    return s;
}

std::span<const std::pair<uint32_t, uint32_t>> VisibleHistory::lastFrameLods(uint64_t frame) const {
    if (frame > 0 && frames_[0].frame == frame - 1) return frames_[0].lod;
    return {};
}

}  // namespace occ
