// SPDX-License-Identifier: MIT
#pragma once

#include "host_device.h"

namespace occ::k {

// Exclusive prefix sums, the avn / atn arrays of Peng & Cao 2012: out[i] = in[0] + ... + in[i-1],
// out[0] = 0. Returns the total in[0] + ... + in[count-1]. out has count entries and must not
// overlap in. count may be 0 (nothing is written, returns 0). Sums are 64-bit, so no total of
// 32-bit counts overflows.
uint64_t exclusiveScan(const uint32_t* in, uint32_t count, uint64_t* out);

// Where every drawn object of one frame sits in the active arrays: lodSelect's output over the
// PVS and its two exclusive scans. All pointers are kernel memory with `count` entries (none
// read when count is 0, so ActiveLayout{} is the empty layout: "nothing drawn", the previous
// layout of the first frame).
//   objects          object ids, strictly ascending (streaming matches frames by binary search)
//   vertex_count     vc_i, the LOD's vertex count; 0 = not drawn (the entry is then ignored)
//   triangle_count   tc_i = map_i[vc_i]; 0 when vc_i is 0
//   vertex_offset    exclusiveScan(vertex_count): where the object's vc_i vertices start
//   triangle_offset  exclusiveScan(triangle_count), in triangles (3 indices each)
// vertex_total and triangle_total are the two scans' returned totals.
struct ActiveLayout {
    const uint32_t* objects = nullptr;
    const uint32_t* vertex_count = nullptr;
    const uint32_t* triangle_count = nullptr;
    const uint64_t* vertex_offset = nullptr;
    const uint64_t* triangle_offset = nullptr;
    uint32_t count = 0;
    uint64_t vertex_total = 0;
    uint64_t triangle_total = 0;
};

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

// One half of an ActiveLayout, so that code moving blocks is written once for vertices and
// triangles: block j of object objects[j] has size[j] elements starting at offset[j].
struct BlockColumn {
    const uint32_t* objects;
    const uint32_t* size;
    const uint64_t* offset;
    uint32_t count;
    uint64_t total;
};

inline BlockColumn vertexBlocks(const ActiveLayout& layout) {
    return {layout.objects, layout.vertex_count, layout.vertex_offset, layout.count, layout.vertex_total};
}
inline BlockColumn triangleBlocks(const ActiveLayout& layout) {
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
