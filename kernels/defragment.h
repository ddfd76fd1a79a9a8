// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "stream_collect.h"

// Streaming with frame-to-frame coherence (SC, Algorithm 3 of Peng & Cao 2012), part 2 of 2:
// the blocks of the active arrays that changed this frame are updated in place. The layout is
// stable (placeLayout in block_layout.h places the blocks): a block that keeps its place keeps
// its bytes and is not touched; a block that grew past its room moved to a new place, where its
// kept prefix is copied device to device; every block's streamed part comes from the staging
// buffer that streamBlocks filled. Compaction (all blocks into a fresh buffer) is the same call
// with src != dst.

namespace occ::k {

// One active array, double-buffered so that compaction has somewhere to go: buffers[current]
// holds the blocks; the other is empty until a compaction fills it and it becomes current. The
// buffers live in device memory of their own or in a display's GL buffers
// (ProvidedBuffer::lendFrom), which OpenGL then draws from.
template <class T>
struct ActiveBuffer {
    ProvidedBuffer<T> buffers[2];
    uint32_t current = 0;

    DevicePtr<const T> data() const { return buffers[current].ptr(); }
};

// Peng & Cao's active vertex array (glm::vec3, object space, each resident object's first vc
// vertices at its block's vertex offset) and active triangle array (3 uint32 corners per
// triangle in the object's own numbering, before reformation: its first tc triangles at its
// block's triangle offset). Owned by the caller and kept from frame to frame.
struct ActiveArrays {
    ActiveBuffer<glm::vec3> vertices;
    ActiveBuffer<uint32_t> triangles;
    DeviceArray<uint32_t> lengths;  // defragment's per-block bookkeeping; no meaning outside it
    DeviceArray<uint64_t> offsets;
};

// What one block of one array (vertices, or triangles) does in a frame, in elements. The block
// is at `to` now; its first `kept` elements are there already (moved = 0) or are copied from
// `from` (moved = kept); after them come `staged` elements from staging[staged_offset, ...).
// Blocks with nothing to do are not listed.
struct BlockMove {
    uint64_t from;
    uint64_t to;
    uint64_t staged_offset;
    uint32_t kept;
    uint32_t moved;   // 0 or kept
    uint32_t staged;
    uint32_t pad;     // keeps the struct 8-byte aligned on both compilers
};
static_assert(sizeof(BlockMove) == 40);

// Applies `count` moves (device memory) to one array: reads src, writes dst (the same buffer,
// except when compacting into a fresh one), staging as streamCollect left it (device side).
// Within one call the ranges read by moves must not overlap the ranges written (the allocator
// frees a block's old place only after the frame). Elements are vertices (W = 1 glm::vec3) or
// triangles (W = 3 uint32 corners). Returns the elements written: moved + staged.
uint64_t defragmentVertices(DevicePtr<const BlockMove> moves, uint32_t count, DevicePtr<const glm::vec3> src,
                            DevicePtr<glm::vec3> dst, DevicePtr<const glm::vec3> staging, ActiveArrays& scratch);
uint64_t defragmentTriangles(DevicePtr<const BlockMove> moves, uint32_t count, DevicePtr<const uint32_t> src,
                             DevicePtr<uint32_t> dst, DevicePtr<const uint32_t> staging, ActiveArrays& scratch);

// The NS baseline of Peng & Cao's Table 1, no streaming batch: every listed part (host memory,
// `count` entries, placeLayout's stream list) copied from `host` straight to its place in
// `vertices` and `triangles` (device memory with room for the offsets plus sizes), one bus copy
// per block and array, with no staging. Returns the counts.
StreamCounts streamObjectByObject(const StreamBlock* blocks, uint32_t count, const HostGeometry& host,
                                  DevicePtr<glm::vec3> vertices, DevicePtr<uint32_t> triangles);

}  // namespace occ::k
