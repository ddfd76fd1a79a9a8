// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <map>

namespace occ {

// Ranges of [0, capacity) elements for the blocks of an active array: first fit over the free
// ranges, which are merged with their neighbours when released. What the stable layout of the
// active arrays is built on (DESIGN.md, "Memory and the bus"): a block keeps its range until it
// outgrows it or leaves.
class RangeAllocator {
public:
    static constexpr uint64_t kNone = ~uint64_t(0);

    // Everything free, `capacity` elements.
    void reset(uint64_t capacity);
    // The lowest free range of at least n elements (n > 0): its first element, or kNone when
    // no free range is large enough.
    uint64_t allocate(uint64_t n);
    // Gives back [offset, offset + n), which allocate returned (with this n) and which was not
    // released since; n = 0 does nothing.
    void release(uint64_t offset, uint64_t n);

    uint64_t capacity() const { return capacity_; }
    uint64_t used() const { return used_; }
    // One past the last allocated element (0 when nothing is).
    uint64_t extent() const;

private:
    std::map<uint64_t, uint64_t> free_;  // first element -> length, ranges disjoint and not adjacent
    uint64_t capacity_ = 0, used_ = 0;
};

}  // namespace occ
