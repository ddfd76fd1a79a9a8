// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"
#include "scan.h"

#include <vector>

// Streaming with frame-to-frame coherence (SC, Algorithm 3 of Peng & Cao 2012), part 1 of 2:
// gather on the host what the device's active arrays lack and send it over the bus. Part 2,
// defragment.h, writes it, and moves the blocks that changed place, in the active arrays.
//
// One frame, as src/pipeline/pipeline.cpp drives it. The device builds the layout
// (block_layout.h) and hands back the blocks that lack something, in layout order:
//   placeLayout(...);                          // the layout, its moves, reforms and stream list
//   streamBlocks(list, host, staging);         // what they lack, gathered and sent to the device
//   defragmentVertices(moves, ..., staging.device_vertices, ...);   // the changed blocks only
//   defragmentTriangles(moves, ..., staging.device_triangles, ...);
//   reformBlocks(...);                         // indices of the blocks whose drawn LOD changed
// StagingBuffers is reused from frame to frame; its contents matter only between the gather and
// defragment of one frame. A layout the host holds (HostLayout) gets its list from streamList,
// or both steps at once from streamCollect. Baselines of Peng & Cao's Table 1: SnC (streaming
// without coherence) treats every block as new every frame, so every block is gathered and
// copied whole; NS (no streaming batch: one copy per object) is streamObjectByObject in
// defragment.h.

namespace occ::k {

// The whole scene's geometry where the host keeps it: the mmap'd .oss (POSITIONS and TRIANGLES
// sections, MeshRecord::vertex_first / triangle_first). Only the host reads it: on a GPU build
// this is exactly the data that must cross to the device.
struct HostGeometry {
    const glm::vec3* positions;      // every mesh's re-arranged vertices, mesh after mesh
    const uint32_t* triangles;       // 3 corners per triangle, each mesh's own vertex numbering
    const uint64_t* vertex_first;    // per mesh: index of its first vertex in positions
    const uint64_t* triangle_first;  // per mesh: index of its first triangle in triangles
    const ObjectInfo* objects;       // per object, the host's copy (DeviceScene::host_objects): .mesh
};

// What travels host -> device in one frame: for every current block, in layout order, the
// elements [kept, size) the previous frame lacked (kept = the shared prefix, see keptPrefix).
// Owned by the caller and reused from frame to frame; streamCollect sizes it (capacity grows
// by half again when short, never shrinks). vertex_count / triangle_count say what the last
// streamCollect wrote: vertices[0, vertex_count), triangles[0, 3 * triangle_count).
// The gather writes pinned host memory; the transfer copies it over the bus into the device
// side, which defragment reads.
struct StagingBuffers {
    PinnedArray<glm::vec3> vertices;
    PinnedArray<uint32_t> triangles;
    DeviceArray<glm::vec3> device_vertices;
    DeviceArray<uint32_t> device_triangles;
    uint64_t vertex_count = 0;
    uint64_t triangle_count = 0;
    std::vector<uint64_t> offsets;  // per-entry bookkeeping of the gather; no meaning outside it
};

// What the host must stream for one block: elements [kept, kept + staged) of its object's mesh,
// which land at offset + kept. Listed in layout order, which is the order they are staged in.
struct StreamBlock {
    uint64_t vertex_offset, triangle_offset;
    uint32_t object;
    uint32_t vertex_kept, vertex_staged;
    uint32_t triangle_kept, triangle_staged;
    uint32_t pad;
};
static_assert(sizeof(StreamBlock) == 40);

struct StreamCounts {
    uint64_t vertices = 0;   // gathered (host -> device)
    uint64_t triangles = 0;
    uint64_t bytes() const { return vertices * sizeof(glm::vec3) + triangles * 3 * sizeof(uint32_t); }
};

// Fills `staging` with the parts the list names (host memory, `count` entries, staged in list
// order: vertex parts back to back, then likewise the triangle parts), gathered from `host`,
// copies them to the device side of `staging` (the frame's one bulk host -> device transfer)
// and returns the counts. The gather is thread-parallel on the host.
StreamCounts streamBlocks(const StreamBlock* blocks, uint32_t count, const HostGeometry& host, StagingBuffers& staging);

// Per block of `current`, in order: what it needs beyond what `previous` held (the shared
// prefix is kept). The layouts may share arrays (an unchanged frame); previous may be
// HostLayout{} (first frame, or the SnC baseline). Throws std::invalid_argument if current's
// ids are not strictly ascending.
std::vector<StreamBlock> streamList(const HostLayout& previous, const HostLayout& current);

// streamBlocks(streamList(previous, current)).
StreamCounts streamCollect(const HostLayout& previous, const HostLayout& current, const HostGeometry& host,
                           StagingBuffers& staging);

}  // namespace occ::k
