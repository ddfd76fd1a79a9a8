// SPDX-License-Identifier: MIT
#include "pipeline/visible_history.h"

#include <algorithm>

namespace occ {

VisibleHistory::Frame& VisibleHistory::push(uint64_t frame, VisibleSet set) {
    std::rotate(frames_, frames_ + kFrames - 1, frames_ + kFrames);  // the oldest becomes [0]
    Frame& h = frames_[0];
    h.frame = frame;
    h.set = std::move(set);
    h.occluder_count = 0;
    return h;
}

const VisibleSet* VisibleHistory::find(uint64_t frame) const {
    for (const Frame& h : frames_)
        if (h.frame == frame) return &h.set;
    return nullptr;
}

OccluderSources VisibleHistory::occluderSources(uint64_t frame, uint32_t lag) const {
    OccluderSources s;
    if (frame < lag) return s;
    for (const Frame& h : frames_) {
        if (h.frame == frame - lag) s.newer = h.occluders.ptr(), s.newer_count = h.occluder_count;
        if (frame >= 2 * uint64_t(lag) && h.frame == frame - 2 * uint64_t(lag) && !h.set.empty()) {
            s.older = h.occluders.ptr();
            s.older_count = h.occluder_count;
            s.has_older = true;
        }
    }
    return s;
}

std::span<const VisibleSet::Entry> VisibleHistory::lastFrameLods(uint64_t frame) const {
    if (frame > 0 && frames_[0].frame == frame - 1) return frames_[0].set.entries();
    return {};
}

}  // namespace occ
