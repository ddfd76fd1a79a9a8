// SPDX-License-Identifier: MIT
#pragma once

// Walking the blocks of a layout (scan.h) element by element, on host arrays or, in kernel
// sources, on a device layout's raw pointers (layout_access.h).
#include "host_device.h"
#include "scan.h"

namespace occ::k {

// The inverse of an exclusive scan, for kernels that give every element of the scanned index
// space its own work: calls run(segment, first, length) for each maximal run of elements of
// [begin, end) that lie in one segment, in order; `first` counts from the segment's start.
// offsets = exclusive scan of the segment sizes (count entries), total = their sum; empty
// segments are never visited. Requires begin < end <= total.
// One binary search per call, then a linear walk: a caller that hands each thread a tile of
// consecutive elements pays for the search once per tile, not once per element.
template <class Run>
OCC_HD inline void forEachRun(const uint64_t* offsets, uint32_t count, uint64_t total, uint64_t begin,
                              uint64_t end, Run&& run) {
    // Last segment starting at or before `begin`: empty segments share their offset with the
    // next non-empty one and sort before it, so the last such segment is the non-empty one.
    uint32_t lo = 0, hi = count;
    while (hi - lo > 1) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (offsets[mid] <= begin)
            lo = mid;
        else
            hi = mid;
    }
    uint32_t segment = lo;
    uint64_t element = begin;
    while (element < end) {
        while (segment + 1 < count && offsets[segment + 1] <= element) ++segment;
        const uint64_t segment_end = segment + 1 < count ? offsets[segment + 1] : total;
        const uint64_t stop = segment_end < end ? segment_end : end;
        run(segment, element - offsets[segment], stop - element);
        element = stop;
    }
}

// Elements per thread for forEachRun's callers. On the CPU a few thousand amortise the search
// and still leave TBB thousands of tasks on a frame's millions of elements; on the GPU one element
// per thread keeps a warp's loads and stores on neighbouring addresses.
inline constexpr uint64_t kHostRunTile = 4096;
#if defined(__CUDACC__)
inline constexpr uint64_t kRunTile = 1;
#else
inline constexpr uint64_t kRunTile = kHostRunTile;
#endif

// Widening before a scan or a sum makes Thrust accumulate 32-bit counts in 64 bits (it sums in
// the input's value type).
struct Widen {
    OCC_HD uint64_t operator()(uint32_t x) const { return x; }
};

// One past the last element of tile `tile` of kRunTile elements, out of `total`.
OCC_HD inline uint64_t tileEnd(uint64_t tile, uint64_t total) {
    return (tile + 1) * kRunTile < total ? (tile + 1) * kRunTile : total;
}

// One half of a HostLayout, so that code moving blocks is written once for vertices and
// triangles: block j of object objects[j] has size[j] elements starting at offset[j].
struct BlockColumn {
    const uint32_t* objects;
    const uint32_t* size;
    const uint64_t* offset;
    uint32_t count;
    uint64_t total;
};

inline BlockColumn vertexBlocks(const HostLayout& layout) {
    return {layout.objects, layout.vertex_count, layout.vertex_offset, layout.count, layout.vertex_total};
}
inline BlockColumn triangleBlocks(const HostLayout& layout) {
    return {layout.objects, layout.triangle_count, layout.triangle_offset, layout.count, layout.triangle_total};
}


// What block j of `current` shares with `previous`: the same object's first `length` elements
// (the shorter of the two blocks; 0 if the object had no block), which `previous` held at
// previous_offset. Both LODs are prefixes of the same re-arranged mesh, so these elements are
// equal in both frames.
struct KeptPrefix {
    uint32_t length;
    uint64_t previous_offset;
};

OCC_HD inline KeptPrefix keptPrefix(const BlockColumn& previous, const BlockColumn& current, uint32_t j) {
    const uint32_t object = current.objects[j];
    uint32_t lo = 0, hi = previous.count;  // first entry of previous with an id >= object
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (previous.objects[mid] < object)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == previous.count || previous.objects[lo] != object) return {0, 0};
    const uint32_t now = current.size[j], before = previous.size[lo];
    return {now < before ? now : before, previous.offset[lo]};
}

}  // namespace occ::k
