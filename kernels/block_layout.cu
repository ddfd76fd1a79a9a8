// SPDX-License-Identifier: MIT
#include "block_layout.h"

#include "block_runs.h"
#include "device_access.h"
#include "scan.h"
#include "device_policy.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/constant_iterator.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/binary_search.h>
#include <thrust/fill.h>
#include <thrust/set_operations.h>
#include <thrust/sort.h>
#include <thrust/transform_reduce.h>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace occ::k {

namespace {

constexpr uint32_t kNotVisible = UINT32_MAX;

// Rooms come in size classes, four per octave (4, 5, 6, 7, 8, 10, 12, 14, 16, 20, ...: at most
// a fifth more than asked), so that a freed range serves any later block of its class.
OCC_HD inline uint32_t sizeClass(uint32_t n) {
    if (n <= 4) return 0;
    uint32_t k = 0;
    while ((8ull << k) <= n) ++k;  // n in [4 << k, 8 << k)
    const uint32_t step = 1u << k;
    uint32_t m = (n + step - 1) / step - 4;  // ceil(n / step) - 4, in [0, 4]
    if (m == 4) ++k, m = 0;
    return 4 * k + m;
}
OCC_HD inline uint32_t classSize(uint32_t c) {
    return uint32_t((4ull + c % 4) << (c / 4));
}

struct Tables {
    const ObjectInfo* objects;
    const uint64_t* map_first;
    const uint32_t* maps;
    // Triangles of the object's LOD with v vertices.
    OCC_HD uint32_t triangles(uint32_t object, uint32_t v) const {
        return v ? maps[map_first[objects[object].mesh] + v] : 0u;
    }
    // A block's room: its LOD plus a quarter (at least 32 vertices), never more than the mesh,
    // rounded up to its size class.
    OCC_HD uint32_t room(uint32_t object, uint32_t v) const {
        const uint64_t grown = uint64_t(v) + (v / 4 > 32 ? v / 4 : 32);
        const uint32_t full = objects[object].vertex_count;
        return classSize(sizeClass(grown < full ? uint32_t(grown) : full));
    }
    // The triangle room that goes with a vertex room: the triangles of that LOD (the full mesh's
    // at most), rounded up to their size class (0 for none).
    OCC_HD uint32_t triangleRoom(uint32_t object, uint32_t vertex_room) const {
        const uint32_t full = objects[object].vertex_count;
        const uint32_t t = triangles(object, vertex_room < full ? vertex_room : full);
        return t ? classSize(sizeClass(t)) : 0u;
    }
};

struct ObjectOf {
    OCC_HD uint32_t operator()(const LayoutBlock& b) const { return b.object; }
};

// One block of the union of last frame's resident objects and this frame's visible set: what it
// draws (Eq. 1's choice, 0 if not visible) and what it keeps (coherent streaming retains an
// object's larger block for a while after it was drawn). Notes when it was drawn.
struct Candidate {
    const uint32_t* ids;
    const uint32_t* source;  // index into the visible set, kNotVisible
    const uint32_t* vertex_counts;
    const uint32_t* triangle_counts;
    BlockPlace* places;
    Tables tables;
    uint64_t frame;
    uint32_t retain_frames;
    bool retain;
    LayoutBlock* out;

    OCC_HD void operator()(uint32_t i) const {
        const uint32_t id = ids[i];
        uint32_t draw = 0, draw_tc = 0;
        if (source[i] != kNotVisible) draw = vertex_counts[source[i]], draw_tc = triangle_counts[source[i]];
        BlockPlace& p = places[id];
        if (draw > 0) p.last_drawn = frame;
        uint32_t keep = draw;
        if (retain && p.vertex_count > draw && frame - p.last_drawn <= retain_frames) keep = p.vertex_count;
        LayoutBlock b{};
        b.object = id;
        b.vertex_count = keep;
        b.triangle_count = keep == draw ? draw_tc : tables.triangles(id, keep);
        b.draw_vertex_count = draw;
        b.draw_triangle_count = draw_tc;
        out[i] = b;
    }
};

struct KeepCount {
    OCC_HD uint64_t operator()(const LayoutBlock& b) const { return b.vertex_count; }
};

struct OnlyDrawn {
    OCC_HD void operator()(LayoutBlock& b) const {
        b.vertex_count = b.draw_vertex_count;
        b.triangle_count = b.draw_triangle_count;
    }
};

struct Holds {
    OCC_HD bool operator()(const LayoutBlock& b) const { return b.vertex_count > 0; }
};

// The room a block needs anew (0 when it keeps its place).
struct Need {
    const LayoutBlock* blocks;
    const BlockPlace* places;
    Tables tables;
    bool compact;
    uint32_t* vertex_need;
    uint32_t* triangle_need;

    OCC_HD void operator()(uint32_t j) const {
        const LayoutBlock& b = blocks[j];
        const BlockPlace& p = places[b.object];
        if (!compact && p.vertex_count > 0 && b.vertex_count <= p.vertex_room && b.triangle_count <= p.triangle_room) {
            vertex_need[j] = triangle_need[j] = 0;
            return;
        }
        vertex_need[j] = tables.room(b.object, b.vertex_count);
        triangle_need[j] = tables.triangleRoom(b.object, vertex_need[j]);
    }
};

// What block j shares with its last place, and whether it is written somewhere new.
struct Change {
    uint32_t kept_v, kept_t, moved_v, moved_t, staged_v, staged_t;
    bool placed;
};

OCC_HD inline Change changeOf(const LayoutBlock& b, const BlockPlace& was, bool coherent, bool relocate) {
    Change c{};
    const bool resident = coherent && was.vertex_count > 0;
    c.kept_v = resident ? (was.vertex_count < b.vertex_count ? was.vertex_count : b.vertex_count) : 0;
    c.kept_t = resident ? (was.triangle_count < b.triangle_count ? was.triangle_count : b.triangle_count) : 0;
    c.placed = !resident || relocate || b.vertex_offset != was.vertex_offset || b.triangle_offset != was.triangle_offset;
    c.moved_v = c.placed ? c.kept_v : 0;
    c.moved_t = c.placed ? c.kept_t : 0;
    c.staged_v = b.vertex_count - c.kept_v;
    c.staged_t = b.triangle_count - c.kept_t;
    return c;
}

// Places block j (its old place, or base + its offset among the new ones) and notes what it
// streams and whether its indices are reformed.
struct Place {
    LayoutBlock* blocks;
    const BlockPlace* places;
    const uint32_t* vertex_need;
    const uint32_t* triangle_need;
    const uint64_t* vertex_place;    // where a block that needs room goes
    const uint64_t* triangle_place;
    uint64_t stamp;
    bool coherent, relocate;
    BlockPlace* next;
    uint32_t* vertex_staged;
    uint32_t* triangle_staged;
    uint8_t* reformed;

    OCC_HD void operator()(uint32_t j) const {
        LayoutBlock& b = blocks[j];
        const BlockPlace& was = places[b.object];
        BlockPlace p = was;
        if (vertex_need[j] > 0) {
            p.vertex_offset = vertex_place[j];
            p.triangle_offset = triangle_need[j] ? triangle_place[j] : 0;
            p.vertex_room = vertex_need[j];
            p.triangle_room = triangle_need[j];
        }
        b.vertex_offset = p.vertex_offset;
        b.triangle_offset = p.triangle_offset;
        const Change c = changeOf(b, was, coherent, relocate);
        vertex_staged[j] = c.staged_v;
        triangle_staged[j] = c.staged_t;
        reformed[j] = b.draw_vertex_count > 0 &&
                      (c.placed || c.staged_t > 0 || was.draw_vertex_count != b.draw_vertex_count);
        p.layout_stamp = stamp;
        p.vertex_count = b.vertex_count;
        p.triangle_count = b.triangle_count;
        p.draw_vertex_count = b.draw_vertex_count;
        next[j] = p;
    }
};

// The per-block list entries, built from the block, its old place and the staged offsets.
struct ListInputs {
    const LayoutBlock* blocks;
    const BlockPlace* places;  // the old places (before the scatter)
    const uint64_t* vertex_staged_offset;
    const uint64_t* triangle_staged_offset;
    const uint8_t* reformed;
    bool coherent, relocate;
    OCC_HD Change change(uint32_t j) const { return changeOf(blocks[j], places[blocks[j].object], coherent, relocate); }
};

struct MakeVertexMove {
    ListInputs in;
    OCC_HD BlockMove operator()(uint32_t j) const {
        const Change c = in.change(j);
        return {in.places[in.blocks[j].object].vertex_offset, in.blocks[j].vertex_offset, in.vertex_staged_offset[j],
                c.kept_v, c.moved_v, c.staged_v, 0};
    }
};
struct HasVertexMove {
    ListInputs in;
    OCC_HD bool operator()(uint32_t j) const {
        const Change c = in.change(j);
        return c.moved_v + c.staged_v > 0;
    }
};
struct MakeTriangleMove {
    ListInputs in;
    OCC_HD BlockMove operator()(uint32_t j) const {
        const Change c = in.change(j);
        return {in.places[in.blocks[j].object].triangle_offset, in.blocks[j].triangle_offset,
                in.triangle_staged_offset[j], c.kept_t, c.moved_t, c.staged_t, 0};
    }
};
struct HasTriangleMove {
    ListInputs in;
    OCC_HD bool operator()(uint32_t j) const {
        const Change c = in.change(j);
        return c.moved_t + c.staged_t > 0;
    }
};
struct MakeReform {
    const LayoutBlock* blocks;
    OCC_HD ReformBlock operator()(uint32_t j) const {
        const LayoutBlock& b = blocks[j];
        return {b.triangle_offset, b.object, b.draw_vertex_count, b.draw_triangle_count, 0};
    }
};
struct IsReformed {
    const uint8_t* reformed;
    OCC_HD bool operator()(uint32_t j) const { return reformed[j] != 0; }
};
struct MakeDraw {
    const LayoutBlock* blocks;
    OCC_HD DrawBlock operator()(uint32_t j) const {
        const LayoutBlock& b = blocks[j];
        return {b.object, b.draw_triangle_count, uint32_t(b.triangle_offset), uint32_t(b.vertex_offset)};
    }
};
struct IsDrawn {
    const LayoutBlock* blocks;
    OCC_HD bool operator()(uint32_t j) const { return blocks[j].draw_vertex_count > 0; }
};
struct MakeStream {
    ListInputs in;
    OCC_HD StreamBlock operator()(uint32_t j) const {
        const Change c = in.change(j);
        const LayoutBlock& b = in.blocks[j];
        return {b.vertex_offset, b.triangle_offset, b.object, c.kept_v, c.staged_v, c.kept_t, c.staged_t, 0};
    }
};
struct IsStreamed {
    ListInputs in;
    OCC_HD bool operator()(uint32_t j) const {
        const Change c = in.change(j);
        return c.staged_v + c.staged_t > 0;
    }
};

struct Sums {
    uint64_t active_v = 0, active_t = 0, drawn = 0, resident_v = 0, resident_t = 0, moved = 0, used_v = 0, used_t = 0;
};
struct AddSums {
    OCC_HD Sums operator()(const Sums& a, const Sums& b) const {
        return {a.active_v + b.active_v, a.active_t + b.active_t, a.drawn + b.drawn, a.resident_v + b.resident_v,
                a.resident_t + b.resident_t, a.moved + b.moved, a.used_v + b.used_v, a.used_t + b.used_t};
    }
};
struct BlockSums {
    ListInputs in;
    const BlockPlace* next;
    OCC_HD Sums operator()(uint32_t j) const {
        const LayoutBlock& b = in.blocks[j];
        const Change c = in.change(j);
        Sums s;
        s.active_v = b.draw_vertex_count;
        s.active_t = b.draw_triangle_count;
        s.drawn = b.draw_vertex_count > 0;
        s.resident_v = b.vertex_count;
        s.resident_t = b.triangle_count;
        s.moved = uint64_t(c.moved_v) * 12u + uint64_t(c.moved_t) * 12u;  // a vec3, or 3 indices
        s.used_v = next[j].vertex_room;
        s.used_t = next[j].triangle_room;
        return s;
    }
};

struct Scatter {
    const LayoutBlock* blocks;
    const BlockPlace* next;
    BlockPlace* places;
    OCC_HD void operator()(uint32_t j) const { places[blocks[j].object] = next[j]; }
};

// Objects of last frame's layout that this frame's has not: no longer resident.
struct ClearDropped {
    const LayoutBlock* previous;
    BlockPlace* places;
    uint64_t stamp;
    OCC_HD void operator()(uint32_t i) const {
        BlockPlace& p = places[previous[i].object];
        if (p.layout_stamp != stamp) p = BlockPlace{};
    }
};

// ---- Segregated fit: requests of one heap matched with its free ranges, class by class.

struct NeedsRoom {
    const uint32_t* need;
    OCC_HD bool operator()(uint32_t j) const { return need[j] > 0; }
};
struct ClassOfRequest {
    const uint32_t* need;
    OCC_HD uint32_t operator()(uint32_t j) const { return sizeClass(need[j]); }
};
// The first of count entries whose key (key_of(entry), ascending) is at least `key`.
template <class T, class KeyOf>
OCC_HD inline uint32_t firstAtLeast(const T* entries, uint32_t count, uint32_t key, KeyOf key_of) {
    uint32_t lo = 0, hi = count;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (key_of(entries[mid]) < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}
struct Itself {
    OCC_HD uint32_t operator()(uint32_t x) const { return x; }
};
struct SizeClassOf {
    OCC_HD uint32_t operator()(const FreeRange& r) const { return r.size_class; }
};

// Request i (sorted by class, block order within one) takes the class's i-th free range, where
// there is one; the others go on top (their sizes, for the scan).
struct Assign {
    const uint32_t* requests;
    const uint32_t* classes;
    uint32_t request_count;
    const uint32_t* need;
    const FreeRange* free;
    uint32_t free_count;
    uint8_t* taken;
    uint32_t* bump_size;
    uint64_t* place;
    OCC_HD void operator()(uint32_t i) const {
        const uint32_t c = classes[i];
        const uint32_t rank = i - firstAtLeast(classes, request_count, c, Itself());
        const uint32_t first = firstAtLeast(free, free_count, c, SizeClassOf());
        const uint32_t last = firstAtLeast(free, free_count, c + 1, SizeClassOf());
        if (rank < last - first) {
            place[requests[i]] = free[first + rank].offset;
            taken[first + rank] = 1;
            bump_size[i] = 0;
        } else {
            bump_size[i] = need[requests[i]];
        }
    }
};
struct OnTop {
    const uint32_t* requests;
    const uint32_t* bump_size;
    const uint64_t* bump_offset;
    uint64_t top;
    uint64_t* place;
    OCC_HD void operator()(uint32_t i) const {
        if (bump_size[i] > 0) place[requests[i]] = top + bump_offset[i];
    }
};

struct IsFree {
    OCC_HD bool operator()(uint8_t taken) const { return taken == 0; }
};
struct RangeOrder {
    OCC_HD bool operator()(const FreeRange& a, const FreeRange& b) const {
        return a.size_class < b.size_class || (a.size_class == b.size_class && a.offset < b.offset);
    }
};

// The range a resident block's place holds in one heap.
OCC_HD inline FreeRange rangeOf(const BlockPlace& p, bool vertices) {
    return vertices ? FreeRange{sizeClass(p.vertex_room), 0, p.vertex_offset}
                    : FreeRange{sizeClass(p.triangle_room), 0, p.triangle_offset};
}
OCC_HD inline bool holdsRange(const BlockPlace& p, bool vertices) {
    return p.vertex_count > 0 && (vertices ? p.vertex_room : p.triangle_room) > 0;
}

// The ranges a frame frees: those of blocks that got a new place, and of objects that left.
struct FreedByMove {
    const LayoutBlock* blocks;
    const BlockPlace* places;  // the old places
    const uint32_t* need;      // > 0: the block got a new place
    bool vertices;
    OCC_HD bool keep(uint32_t j) const { return need[j] > 0 && holdsRange(places[blocks[j].object], vertices); }
    OCC_HD FreeRange operator()(uint32_t j) const { return rangeOf(places[blocks[j].object], vertices); }
};
struct MovedPred {
    FreedByMove f;
    OCC_HD bool operator()(uint32_t j) const { return f.keep(j); }
};
struct FreedByLeaving {
    const LayoutBlock* previous;
    const BlockPlace* places;
    uint64_t stamp;
    bool vertices;
    OCC_HD bool keep(uint32_t i) const {
        const BlockPlace& p = places[previous[i].object];
        return p.layout_stamp != stamp && holdsRange(p, vertices);
    }
    OCC_HD FreeRange operator()(uint32_t i) const { return rangeOf(places[previous[i].object], vertices); }
};
struct LeftPred {
    FreedByLeaving f;
    OCC_HD bool operator()(uint32_t i) const { return f.keep(i); }
};

// Places every block of `need` > 0 (absolute offsets into place[j]): free ranges of its class
// first, then the top. Marks the free ranges taken; returns what went on top.
uint64_t allocate(uint32_t n, DevicePtr<const uint32_t> need, const DeviceArray<FreeRange>& free, uint32_t free_count,
                  uint64_t top, DevicePtr<uint64_t> place, DeviceArray<uint8_t>& taken, LayoutScratch& s) {
    taken.growTo(std::max<uint32_t>(1, free_count));
    thrust::fill_n(onDevice(), raw(taken.ptr()), std::max<uint32_t>(1, free_count), uint8_t(0));
    if (n == 0) return 0;
    const thrust::counting_iterator<uint32_t> j0(0);
    uint32_t* const requests = raw(s.requests.ptr());
    uint32_t* const classes = raw(s.request_classes.ptr());
    const uint32_t count =
        uint32_t(thrust::copy_if(onDevice(), j0, j0 + n, requests, NeedsRoom{raw(need)}) - requests);
    countReadback(sizeof(uint32_t));
    if (count == 0) return 0;
    thrust::transform(onDevice(), requests, requests + count, classes, ClassOfRequest{raw(need)});
    thrust::stable_sort_by_key(onDevice(), classes, classes + count, requests);
    thrust::for_each_n(onDevice(), j0, count,
                       Assign{requests, classes, count, raw(need), raw(free.ptr()), free_count, raw(taken.ptr()),
                              raw(s.bump_size.ptr()), raw(place)});
    const uint64_t bumped = exclusiveScan(s.bump_size.ptr(), count, s.bump_offset.ptr());
    thrust::for_each_n(onDevice(), j0, count,
                       OnTop{requests, raw(s.bump_size.ptr()), raw(s.bump_offset.ptr()), top, raw(place)});
    return bumped;
}

// The free list after the frame, in two steps around the scatter of the new places: first the
// ranges not taken and those of blocks that got a new place (from the old places), then those
// of objects that left (known once the new places are stamped); sorted into `free`.
uint32_t freeMoved(const DeviceArray<FreeRange>& free, uint32_t free_count, const DeviceArray<uint8_t>& taken,
                   const FreedByMove& moved, uint32_t blocks, uint32_t previous_count, DeviceArray<FreeRange>& out) {
    const thrust::counting_iterator<uint32_t> j0(0);
    out.growTo(std::max<uint32_t>(1, free_count + blocks + previous_count));
    FreeRange* const first = raw(out.ptr());
    FreeRange* end = first;
    if (free_count > 0) {
        end = thrust::copy_if(onDevice(), raw(free.ptr()), raw(free.ptr()) + free_count, raw(taken.ptr()), first,
                              IsFree());
        countReadback(sizeof(uint32_t));
    }
    if (blocks > 0) {
        const auto made = thrust::make_transform_iterator(j0, moved);
        end = thrust::copy_if(onDevice(), made, made + blocks, j0, end, MovedPred{moved});
        countReadback(sizeof(uint32_t));
    }
    return uint32_t(end - first);
}

uint32_t freeLeft(DeviceArray<FreeRange>& out, uint32_t count, const FreedByLeaving& left, uint32_t previous_count,
                  DeviceArray<FreeRange>& free) {
    const thrust::counting_iterator<uint32_t> j0(0);
    FreeRange* const first = raw(out.ptr());
    FreeRange* end = first + count;
    if (previous_count > 0) {
        const auto made = thrust::make_transform_iterator(j0, left);
        end = thrust::copy_if(onDevice(), made, made + previous_count, j0, end, LeftPred{left});
        countReadback(sizeof(uint32_t));
    }
    const uint32_t total = uint32_t(end - first);
    thrust::sort(onDevice(), first, end, RangeOrder());
    free.growTo(std::max<uint32_t>(1, total));
    copyOnDevice(free.ptr(), DevicePtr<const FreeRange>(out.ptr()), total);
    return total;
}

// Heaps are compacted when more than half of what they span is holes (and they are not small).
bool fragmented(uint64_t top, uint64_t used) {
    return top > (uint64_t(1) << 16) && top - used > top / 2;
}

template <class T, class Make, class Pred>
uint32_t compactList(uint32_t blocks, Make make, Pred pred, DeviceArray<T>& out) {
    out.growTo(std::max<uint32_t>(1, blocks));
    if (blocks == 0) return 0;
    const thrust::counting_iterator<uint32_t> j(0);
    const auto made = thrust::make_transform_iterator(j, make);
    T* const end = thrust::copy_if(onDevice(), made, made + blocks, j, raw(out.ptr()), pred);
    countReadback(sizeof(uint32_t));
    return uint32_t(end - raw(out.ptr()));
}

}  // namespace

LayoutTotals placeLayout(const VisibleLods& visible, DevicePtr<const LayoutBlock> previous, uint32_t previous_count,
                         DevicePtr<LayoutBlock> current, DevicePtr<BlockPlace> places, const LayoutScene& scene,
                         const LayoutOptions& options, LayoutHeap& heap, LayoutLists& lists, LayoutScratch& s) {
    const Tables tables{raw(scene.objects), raw(scene.map_first), raw(scene.maps)};
    const uint32_t most = previous_count + visible.count;
    // Room for the union, sized by twice the larger set rather than their sum, so that the first
    // frame (nothing before it) already has the room of the frames after it.
    const uint32_t room = std::max<uint32_t>(1, 2 * std::max(previous_count, visible.count));
    for (DeviceArray<uint32_t>* a : {&s.union_ids, &s.union_source, &s.vertex_need, &s.triangle_need, &s.vertex_staged,
                                     &s.triangle_staged})
        a->growTo(room);
    for (DeviceArray<uint64_t>* a : {&s.vertex_need_offset, &s.triangle_need_offset, &s.vertex_staged_offset,
                                     &s.triangle_staged_offset})
        a->growTo(room);
    s.candidates.growTo(room);
    s.next_places.growTo(room);
    s.reformed.growTo(room);
    BlockPlace* const place = raw(places);
    const LayoutBlock* const prev = raw(previous);
    LayoutBlock* const blocks = raw(current);
    const bool retain = options.coherent && options.retain_frames > 0;
    const uint64_t stamp = ++heap.layouts;
    LayoutTotals totals;

    // 1. The union of last frame's resident objects and this frame's visible ones (both
    //    ascending), each with what it draws and keeps.
    uint32_t candidates = 0;
    if (most > 0) {
        const auto prev_ids = thrust::make_transform_iterator(prev, ObjectOf());
        const auto ends = thrust::set_union_by_key(
            onDevice(), raw(visible.ids), raw(visible.ids) + visible.count, prev_ids, prev_ids + previous_count,
            thrust::counting_iterator<uint32_t>(0), thrust::constant_iterator<uint32_t>(kNotVisible),
            raw(s.union_ids.ptr()), raw(s.union_source.ptr()));
        candidates = uint32_t(ends.first - raw(s.union_ids.ptr()));
        countReadback(sizeof(uint32_t));
        thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), candidates,
                           Candidate{raw(s.union_ids.ptr()), raw(s.union_source.ptr()), raw(visible.vertex_counts),
                                     raw(visible.triangle_counts), place, tables, options.frame,
                                     options.retain_frames, retain, raw(s.candidates.ptr())});
        // Over the memory cap, residency starts again from what this frame draws.
        if (retain) {
            const uint64_t resident = thrust::transform_reduce(onDevice(), raw(s.candidates.ptr()),
                                                               raw(s.candidates.ptr()) + candidates, KeepCount(),
                                                               uint64_t(0), thrust::plus<uint64_t>());
            countReadback(sizeof(uint64_t));
            if (double(resident) > options.resident_cap)
                thrust::for_each_n(onDevice(), raw(s.candidates.ptr()), candidates, OnlyDrawn());
        }
        LayoutBlock* const end =
            thrust::copy_if(onDevice(), raw(s.candidates.ptr()), raw(s.candidates.ptr()) + candidates, blocks, Holds());
        countReadback(sizeof(uint32_t));
        totals.blocks = uint32_t(end - blocks);
    }
    const uint32_t n = totals.blocks;
    const thrust::counting_iterator<uint32_t> j0(0);

    // 2. Rooms: a block keeps its place while its LOD fits; the others take free ranges of their
    //    class or go on top of the heap, unless they do not fit there or the heap is mostly
    //    holes: then every block is placed afresh, back to back.
    for (DeviceArray<uint32_t>* a : {&s.requests, &s.request_classes, &s.bump_size}) a->growTo(room);
    s.bump_offset.growTo(room);
    // The display draws with 32-bit first indices and base vertices.
    const auto drawable = [](uint64_t vertices, uint64_t triangles) {
        return vertices <= uint64_t(INT32_MAX) && 3 * triangles <= uint64_t(UINT32_MAX);
    };
    bool compact = !options.coherent || heap.vertex_capacity == 0 || fragmented(heap.vertex_top, heap.vertex_used) ||
                   fragmented(heap.triangle_top, heap.triangle_used);
    bool relocate = compact;  // every block written into the other buffers
    uint64_t need_v = 0, need_t = 0;
    if (!compact) {
        thrust::for_each_n(onDevice(), j0, n,
                           Need{blocks, place, tables, false, raw(s.vertex_need.ptr()), raw(s.triangle_need.ptr())});
        need_v = allocate(n, s.vertex_need.ptr(), heap.vertex_free, heap.vertex_free_count, heap.vertex_top,
                          s.vertex_need_offset.ptr(), s.vertex_taken, s);
        need_t = allocate(n, s.triangle_need.ptr(), heap.triangle_free, heap.triangle_free_count, heap.triangle_top,
                          s.triangle_need_offset.ptr(), s.triangle_taken, s);
        const uint64_t top_v = heap.vertex_top + need_v, top_t = heap.triangle_top + need_t;
        if (top_v > heap.vertex_capacity || top_t > heap.triangle_capacity) {
            // Short of room but not of holes: the heaps grow to twice what they span, every block
            // copied to the same place in the other, larger buffers (indices reformed).
            const uint64_t grown_v = std::max(heap.vertex_capacity, 2 * top_v);
            const uint64_t grown_t = std::max(heap.triangle_capacity, 2 * top_t);
            if (drawable(grown_v, grown_t)) {
                heap.vertex_capacity = grown_v;
                heap.triangle_capacity = grown_t;
                relocate = true;
            } else {
                compact = relocate = true;
            }
        }
    }
    if (compact) {
        thrust::for_each_n(onDevice(), j0, n,
                           Need{blocks, place, tables, true, raw(s.vertex_need.ptr()), raw(s.triangle_need.ptr())});
        need_v = exclusiveScan(s.vertex_need.ptr(), n, s.vertex_need_offset.ptr());
        need_t = exclusiveScan(s.triangle_need.ptr(), n, s.triangle_need_offset.ptr());
        const uint64_t vertex_capacity = std::max<uint64_t>(4096, need_v + need_v / 2);
        const uint64_t triangle_capacity = std::max<uint64_t>(4096, need_t + need_t / 2);
        if (!drawable(vertex_capacity, triangle_capacity))
            throw std::length_error("the active arrays would hold " + std::to_string(need_v) + " vertices and " +
                                    std::to_string(need_t) +
                                    " triangles, more than 32-bit indices reach: lower the vertex budget");
        heap.vertex_capacity = vertex_capacity;
        heap.triangle_capacity = triangle_capacity;
        heap.vertex_top = need_v;
        heap.triangle_top = need_t;
        heap.vertex_free_count = heap.triangle_free_count = 0;
    } else {
        heap.vertex_top += need_v;
        heap.triangle_top += need_t;
    }
    totals.compacted = compact;
    totals.relocated = relocate;

    // 3. Places, what each block streams, and the staged offsets (layout order, the order the
    //    host stages in).
    thrust::for_each_n(onDevice(), j0, n,
                       Place{blocks, place, raw(s.vertex_need.ptr()), raw(s.triangle_need.ptr()),
                             raw(s.vertex_need_offset.ptr()), raw(s.triangle_need_offset.ptr()), stamp, options.coherent, relocate, raw(s.next_places.ptr()),
                             raw(s.vertex_staged.ptr()), raw(s.triangle_staged.ptr()), raw(s.reformed.ptr())});
    totals.streamed_vertices = exclusiveScan(s.vertex_staged.ptr(), n, s.vertex_staged_offset.ptr());
    totals.streamed_triangles = exclusiveScan(s.triangle_staged.ptr(), n, s.triangle_staged_offset.ptr());

    // 4. The frame's lists, and its totals.
    const ListInputs in{blocks, place, raw(s.vertex_staged_offset.ptr()), raw(s.triangle_staged_offset.ptr()),
                        raw(s.reformed.ptr()), options.coherent, relocate};
    lists.vertex_move_count = compactList(n, MakeVertexMove{in}, HasVertexMove{in}, lists.vertex_moves);
    lists.triangle_move_count = compactList(n, MakeTriangleMove{in}, HasTriangleMove{in}, lists.triangle_moves);
    lists.reform_count = compactList(n, MakeReform{blocks}, IsReformed{raw(s.reformed.ptr())}, lists.reforms);
    lists.draw_count = compactList(n, MakeDraw{blocks}, IsDrawn{blocks}, lists.draws);
    lists.stream_count = compactList(n, MakeStream{in}, IsStreamed{in}, lists.streams);
    if (n > 0) {
        const Sums sums = thrust::transform_reduce(onDevice(), j0, j0 + n, BlockSums{in, raw(s.next_places.ptr())},
                                                   Sums{}, AddSums());
        countReadback(sizeof(Sums));
        totals.active_vertices = sums.active_v;
        totals.active_triangles = sums.active_t;
        totals.objects_drawn = sums.drawn;
        totals.resident_vertices = sums.resident_v;
        totals.resident_triangles = sums.resident_t;
        totals.moved_bytes = sums.moved;
        heap.vertex_used = sums.used_v;
        heap.triangle_used = sums.used_t;
    } else {
        heap.vertex_used = heap.triangle_used = 0;
    }

    // 5. The new places; the ranges of blocks that moved or left are free from the next frame on
    //    (a compaction starts with none).
    uint32_t freed_v = 0, freed_t = 0;
    if (!compact) {
        freed_v = freeMoved(heap.vertex_free, heap.vertex_free_count, s.vertex_taken,
                            FreedByMove{blocks, place, raw(s.vertex_need.ptr()), true}, n, previous_count,
                            s.vertex_freed);
        freed_t = freeMoved(heap.triangle_free, heap.triangle_free_count, s.triangle_taken,
                            FreedByMove{blocks, place, raw(s.vertex_need.ptr()), false}, n, previous_count,
                            s.triangle_freed);
    }
    thrust::for_each_n(onDevice(), j0, n, Scatter{blocks, raw(s.next_places.ptr()), place});
    if (!compact) {
        heap.vertex_free_count =
            freeLeft(s.vertex_freed, freed_v, FreedByLeaving{prev, place, stamp, true}, previous_count, heap.vertex_free);
        heap.triangle_free_count = freeLeft(s.triangle_freed, freed_t, FreedByLeaving{prev, place, stamp, false},
                                            previous_count, heap.triangle_free);
    }
    thrust::for_each_n(onDevice(), j0, previous_count, ClearDropped{prev, place, stamp});
    return totals;
}

}  // namespace occ::k
