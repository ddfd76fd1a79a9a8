// SPDX-License-Identifier: MIT
#pragma once

#include "defragment.h"
#include "device_memory.h"
#include "draw_commands.h"
#include "kernel_types.h"
#include "reform.h"

// The layout of the active arrays, built on the device every frame (Peng & Cao 2012's resident
// set, kept in place): which objects are resident, how much of each, where its block sits, and
// what of it changed. The host gets back only the blocks whose new parts it must stream and a
// few totals.
//
// A block that keeps its place keeps its bytes. Each block has room for its LOD plus a quarter
// (at least 32 vertices, at most the full mesh), rounded up to a size class (four per octave):
// LOD changes within the room append where the block is. A new block, or one that outgrew its
// room, takes a free range of its class (segregated fit), else a range on top of the heap. The
// ranges of blocks that moved or left are freed after the frame, so no move of a frame writes
// where another reads. When the new blocks do not fit, the heaps grow to twice what they span
// (every block copied to its same place in the other, larger buffers). They are compacted
// (every block afresh, back to back, into the other buffers) when more than half of what they
// span is holes, and every frame without coherence.

namespace occ::k {

// One block of a frame's layout (device memory), blocks in ascending object order.
struct LayoutBlock {
    uint64_t vertex_offset;    // where its vertices start in the active vertex array
    uint64_t triangle_offset;  // where its triangles start, in triangles (3 indices each)
    uint32_t object;
    uint32_t vertex_count;         // vc_i, what the block holds (> 0)
    uint32_t triangle_count;       // map_i[vc_i]
    uint32_t draw_vertex_count;    // what this frame draws, a prefix (0 = resident only)
    uint32_t draw_triangle_count;
    uint32_t pad;
};
static_assert(sizeof(LayoutBlock) == 40);

// Where an object's block is while it is resident (device memory, one per object, kept from
// frame to frame; all zero when not resident).
struct BlockPlace {
    uint64_t vertex_offset, triangle_offset;
    uint64_t last_drawn;       // the last frame it was drawn in
    uint64_t layout_stamp;     // which placeLayout call last placed it (LayoutHeap::layouts)
    uint32_t vertex_room, triangle_room;  // its room: vertices, and the triangles of that LOD
    uint32_t vertex_count, triangle_count;  // what it holds (vertex_count 0: not resident)
    uint32_t draw_vertex_count;  // what its indices are reformed for
    uint32_t pad;
};
static_assert(sizeof(BlockPlace) == 56);

// A hole of one heap, left by a block that moved or left: a range of one size class.
struct FreeRange {
    uint32_t size_class;
    uint32_t pad;
    uint64_t offset;
};
static_assert(sizeof(FreeRange) == 16);

// The heaps' state between frames: a few values on the host (top = the end of the highest
// block, capacity = what the buffers hold, used = the rooms of the resident blocks) and the
// free ranges on the device, sorted by size class and offset.
struct LayoutHeap {
    DeviceArray<FreeRange> vertex_free, triangle_free;
    uint32_t vertex_free_count = 0, triangle_free_count = 0;
    uint64_t vertex_top = 0, triangle_top = 0;
    uint64_t vertex_capacity = 0, triangle_capacity = 0;
    uint64_t vertex_used = 0, triangle_used = 0;
    uint64_t layouts = 0;  // placeLayout calls so far
};

struct LayoutOptions {
    uint64_t frame = 0;
    bool coherent = true;          // SC; false for SnC and NS (every block new, compacted)
    uint32_t retain_frames = 0;    // coherent only: keep a block resident that long after it was drawn
    double resident_cap = 0;       // vertices: over it, residency starts again from what is drawn
};

// The mesh tables placeLayout reads (device memory).
struct LayoutScene {
    DevicePtr<const ObjectInfo> objects;
    DevicePtr<const uint64_t> map_first;
    DevicePtr<const uint32_t> maps;
};

// This frame's visible set with its LODs (device memory, ascending ids).
struct VisibleLods {
    DevicePtr<const uint32_t> ids, vertex_counts, triangle_counts;
    uint32_t count = 0;
};

// The lists placeLayout writes (device memory, grown as needed) and their lengths.
struct LayoutLists {
    DeviceArray<BlockMove> vertex_moves, triangle_moves;  // for defragmentVertices / Triangles
    DeviceArray<ReformBlock> reforms;                     // for reformBlocks
    DeviceArray<DrawBlock> draws;                         // the blocks drawn, for the display
    DeviceArray<StreamBlock> streams;                     // what the host streams
    uint32_t vertex_move_count = 0, triangle_move_count = 0, reform_count = 0, draw_count = 0, stream_count = 0;
};

struct LayoutTotals {
    uint32_t blocks = 0;
    bool compacted = false;  // every block placed afresh, back to back
    bool relocated = false;  // every block written into the other buffers (compacted, or the heaps grew)
    uint64_t active_vertices = 0, active_triangles = 0, objects_drawn = 0;  // what is drawn
    uint64_t resident_vertices = 0, resident_triangles = 0;                 // what the blocks hold
    uint64_t streamed_vertices = 0, streamed_triangles = 0;
    uint64_t moved_bytes = 0;  // kept prefixes copied to a new place
};

// Persistent scratch of placeLayout.
struct LayoutScratch {
    DeviceArray<uint32_t> union_ids, union_source, vertex_need, triangle_need;
    DeviceArray<uint64_t> vertex_need_offset, triangle_need_offset, vertex_staged_offset, triangle_staged_offset;
    DeviceArray<LayoutBlock> candidates;
    DeviceArray<BlockPlace> next_places;
    DeviceArray<uint32_t> vertex_staged, triangle_staged;
    DeviceArray<uint8_t> reformed;
    // The allocation of one heap.
    DeviceArray<uint32_t> requests, request_classes, bump_size;
    DeviceArray<uint64_t> bump_offset;
    DeviceArray<uint8_t> vertex_taken, triangle_taken;
    DeviceArray<FreeRange> vertex_freed, triangle_freed;
};

// Builds this frame's layout into `current` (room for every object of both frames: the object
// count always suffices)
// from the last frame's (`previous`, previous_count blocks) and this frame's visible set,
// updates `places` (one per object) and `heap`, and writes the frame's lists. Throws
// std::length_error (before anything is written) when a compacted heap would pass what 32-bit
// draw offsets reach.
LayoutTotals placeLayout(const VisibleLods& visible, DevicePtr<const LayoutBlock> previous, uint32_t previous_count,
                         DevicePtr<LayoutBlock> current, DevicePtr<BlockPlace> places, const LayoutScene& scene,
                         const LayoutOptions& options, LayoutHeap& heap, LayoutLists& lists, LayoutScratch& scratch);

}  // namespace occ::k
