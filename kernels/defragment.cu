// SPDX-License-Identifier: MIT
#include "defragment.h"
#include "layout_access.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/reduce.h>
#include <thrust/sort.h>

#include <stdexcept>
#include <string>

namespace occ::k {

namespace {

template <class T>
void reserve(DeviceArray<T>& array, uint64_t n) {
    if (n > array.size()) array.resize(n + n / 2);
}

template <class T, int W>
OCC_HD inline void copyElements(const T* src, T* dst, uint64_t n) {
    for (uint64_t i = 0; i < W * n; ++i) dst[i] = src[i];
}

// Per block of the current layout: what it keeps of the previous frame, what comes from staging,
// and what of the kept prefix changes place.
struct Plan {
    uint32_t* kept;
    uint32_t* staged;
    uint32_t* moved;
    uint32_t* written;           // moved + staged: what the in-place strategy writes to the block
    uint64_t* previous_offset;   // where the kept prefix is now
    uint64_t* staged_offset;     // exclusive scans of the lengths above
    uint64_t* moved_offset;
    uint64_t* written_offset;
};

struct PlanBlock {
    BlockColumn previous, current;
    Plan plan;
    OCC_HD void operator()(uint32_t j) const {
        const KeptPrefix k = keptPrefix(previous, current, j);
        const uint32_t moved = k.length > 0 && k.previous_offset != current.offset[j] ? k.length : 0;
        plan.kept[j] = k.length;
        plan.staged[j] = current.size[j] - k.length;
        plan.moved[j] = moved;
        plan.written[j] = moved + current.size[j] - k.length;
        plan.previous_offset[j] = k.previous_offset;
    }
};

struct Widen {
    OCC_HD uint64_t operator()(uint32_t x) const { return x; }
};

OCC_HD inline uint64_t tileEnd(uint64_t tile, uint64_t total) {
    return (tile + 1) * kRunTile < total ? (tile + 1) * kRunTile : total;
}

// In place, step 1: the kept prefixes that move go to the workspace, because their new places
// may overlap other blocks' old ones that are still to be read.
template <class T, int W>
struct Bounce {
    BlockColumn current;
    Plan plan;
    uint64_t moved_total;
    const T* active;
    T* workspace;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(plan.moved_offset, current.count, moved_total, tile * kRunTile, tileEnd(tile, moved_total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       copyElements<T, W>(active + W * (plan.previous_offset[j] + first),
                                          workspace + W * (plan.moved_offset[j] + first), length);
                   });
    }
};

// In place, step 2: each block gets its moved prefix back from the workspace and its streamed
// part from staging. A block that did not move is written only past its kept prefix.
template <class T, int W>
struct PlaceInPlace {
    BlockColumn current;
    Plan plan;
    uint64_t written_total;
    const T* workspace;
    const T* staging;
    T* active;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(plan.written_offset, current.count, written_total, tile * kRunTile, tileEnd(tile, written_total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint64_t moved = plan.moved[j], stop = first + length;
                       T* block = active + W * (current.offset[j] + plan.kept[j] - moved);
                       uint64_t i = first;
                       if (i < moved) {
                           const uint64_t n = (stop < moved ? stop : moved) - i;
                           copyElements<T, W>(workspace + W * (plan.moved_offset[j] + i), block + W * i, n);
                           i += n;
                       }
                       if (i < stop)
                           copyElements<T, W>(staging + W * (plan.staged_offset[j] + i - moved), block + W * i,
                                              stop - i);
                   });
    }
};

// Double buffering: every block of the new layout is written into the other buffer, its kept
// prefix from the old buffer and the rest from staging.
template <class T, int W>
struct PlaceDoubleBuffered {
    BlockColumn current;
    Plan plan;
    const T* old_active;
    const T* staging;
    T* new_active;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(current.offset, current.count, current.total, tile * kRunTile, tileEnd(tile, current.total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint64_t kept = plan.kept[j], stop = first + length;
                       T* block = new_active + W * current.offset[j];
                       uint64_t i = first;
                       if (i < kept) {
                           const uint64_t n = (stop < kept ? stop : kept) - i;
                           copyElements<T, W>(old_active + W * (plan.previous_offset[j] + i), block + W * i, n);
                           i += n;
                       }
                       if (i < stop)
                           copyElements<T, W>(staging + W * (plan.staged_offset[j] + i - kept), block + W * i,
                                              stop - i);
                   });
    }
};

template <class F>
void forEachTile(uint64_t total, const F& f) {
    if (total == 0) return;
    thrust::for_each_n(thrust::device, thrust::counting_iterator<uint64_t>(0), (total + kRunTile - 1) / kRunTile, f);
}

// exclusiveScan on the raw pointers of a plan.
uint64_t scanRaw(const uint32_t* in, uint32_t n, uint64_t* out) {
    return exclusiveScan(DeviceAccess::wrap(in), n, DeviceAccess::wrap(out));
}

struct ColumnPlan {
    Plan plan;
    uint64_t staged_total = 0, moved_total = 0, kept_total = 0;
};

// lengths and offsets have room for 4 * current.count entries each.
ColumnPlan planColumn(const BlockColumn& previous, const BlockColumn& current, uint32_t* lengths, uint64_t* offsets) {
    const uint32_t n = current.count;
    ColumnPlan c;
    c.plan = {lengths, lengths + n, lengths + 2 * n, lengths + 3 * n, offsets, offsets + n, offsets + 2 * n, offsets + 3 * n};
    if (n == 0) return c;
    thrust::for_each_n(thrust::device, thrust::counting_iterator<uint32_t>(0), n, PlanBlock{previous, current, c.plan});
    c.staged_total = scanRaw(c.plan.staged, n, c.plan.staged_offset);
    c.moved_total = scanRaw(c.plan.moved, n, c.plan.moved_offset);
    const auto wide = thrust::make_transform_iterator(c.plan.kept, Widen());
    c.kept_total = thrust::reduce(thrust::device, wide, wide + n, uint64_t(0));
    countReadback(sizeof c.kept_total);
    return c;
}

void checkStaging(const ColumnPlan& c, uint64_t staging_count, const char* what) {
    if (c.staged_total != staging_count)
        throw std::invalid_argument(std::string("defragment: staging holds ") + std::to_string(staging_count) + " " +
                                    what + " but the layouts need " + std::to_string(c.staged_total) +
                                    " (was it collected for these two layouts?)");
}

struct ColumnCounts {
    uint64_t copied, moved, bounced;
};

template <class T, int W>
ColumnCounts applyColumn(const ColumnPlan& c, const BlockColumn& current, const T* staging, ActiveBuffer<T>& buffer) {
    ProvidedBuffer<T>& now = buffer.buffers[buffer.current];
    ProvidedBuffer<T>& other = buffer.buffers[1 - buffer.current];
    const bool in_place = W * current.total <= now.capacity() && 2 * c.moved_total <= c.kept_total;
    if (in_place) {
        if (c.moved_total > 0) {
            other.reserve(W * c.moved_total);
            forEachTile(c.moved_total, Bounce<T, W>{current, c.plan, c.moved_total, raw(now.ptr()), raw(other.ptr())});
        }
        const uint64_t written_total =
            current.count > 0 ? scanRaw(c.plan.written, current.count, c.plan.written_offset) : 0;
        forEachTile(written_total,
                    PlaceInPlace<T, W>{current, c.plan, written_total, raw(other.ptr()), staging, raw(now.ptr())});
    } else {
        other.reserve(W * current.total);
        forEachTile(current.total, PlaceDoubleBuffered<T, W>{current, c.plan, raw(now.ptr()), staging, raw(other.ptr())});
        buffer.current = 1 - buffer.current;
    }
    buffer.count = current.total;
    return {c.staged_total, in_place ? c.moved_total : c.kept_total, in_place ? c.moved_total : 0};
}

}  // namespace

DefragmentCounts defragment(const ActiveLayout& previous, const ActiveLayout& current, const StagingBuffers& staging,
                            ActiveArrays& active) {
    if (previous.count > 0 && (previous.vertex_total != active.vertices.count ||
                               previous.triangle_total != active.triangles.count))
        throw std::invalid_argument("defragment: the active arrays hold " + std::to_string(active.vertices.count) +
                                    " vertices and " + std::to_string(active.triangles.count) +
                                    " triangles but the previous layout has " + std::to_string(previous.vertex_total) +
                                    " and " + std::to_string(previous.triangle_total));
    // Blocks are matched across frames by binary search on the ids.
    countReadback(1);  // is_sorted's answer
    if (!thrust::is_sorted(thrust::device, raw(current.objects), raw(current.objects) + current.count,
                           thrust::less_equal<uint32_t>()))
        throw std::invalid_argument("defragment: the current layout's object ids are not strictly ascending");
    // Both columns are planned and checked before either is touched.
    const uint64_t n = current.count;
    reserve(active.lengths, 8 * n);
    reserve(active.offsets, 8 * n);
    uint32_t* const lengths = raw(active.lengths.ptr());
    uint64_t* const offsets = raw(active.offsets.ptr());
    const ColumnPlan vp = planColumn(vertexBlocks(previous), vertexBlocks(current), lengths, offsets);
    const ColumnPlan tp = planColumn(triangleBlocks(previous), triangleBlocks(current), lengths + 4 * n, offsets + 4 * n);
    checkStaging(vp, staging.vertex_count, "vertices");
    checkStaging(tp, staging.triangle_count, "triangles");
    const ColumnCounts v =
        applyColumn<glm::vec3, 1>(vp, vertexBlocks(current), raw(staging.device_vertices.ptr()), active.vertices);
    const ColumnCounts t =
        applyColumn<uint32_t, 3>(tp, triangleBlocks(current), raw(staging.device_triangles.ptr()), active.triangles);
    return {v.copied, t.copied, v.moved, t.moved, v.bounced, t.bounced};
}

namespace {

template <class T, int W>
uint64_t copyObjectByObject(const BlockColumn& current, const T* source, const uint64_t* mesh_first,
                            const ObjectInfo* objects, ActiveBuffer<T>& buffer) {
    buffer.buffers[buffer.current].reserve(W * current.total);
    const DevicePtr<T> active = buffer.buffers[buffer.current].ptr();
    for (uint32_t j = 0; j < current.count; ++j) {
        if (current.size[j] == 0) continue;
        const T* src = source + W * mesh_first[objects[current.objects[j]].mesh];
        copyToDevice(active + W * current.offset[j], src, W * uint64_t(current.size[j]));
    }
    buffer.count = current.total;
    return current.total;
}

}  // namespace

StreamCounts streamObjectByObject(const HostLayout& current, const HostGeometry& host, ActiveArrays& active) {
    StreamCounts counts;
    counts.vertices = copyObjectByObject<glm::vec3, 1>(vertexBlocks(current), host.positions, host.vertex_first,
                                                       host.objects, active.vertices);
    counts.triangles = copyObjectByObject<uint32_t, 3>(triangleBlocks(current), host.triangles, host.triangle_first,
                                                       host.objects, active.triangles);
    return counts;
}

}  // namespace occ::k
