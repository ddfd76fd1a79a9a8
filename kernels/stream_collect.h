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
// One frame, as src/pipeline/pipeline.cpp drives it. The host keeps the layout (HostLayout:
// per resident block its object, vertex and triangle counts and its place, which a stable
// allocator chooses) of the last frame and of this one:
//   streamCollect(prev, cur, host, staging);   // what prev lacks, gathered and sent to the device
//   defragmentVertices(moves, ..., staging.device_vertices, ...);   // the changed blocks only
//   defragmentTriangles(moves, ..., staging.device_triangles, ...);
//   reformBlocks(...);                         // indices of the blocks whose drawn LOD changed
//   prev = cur
// The first frame passes HostLayout{} as prev. StagingBuffers is reused from frame to frame; its
// contents matter only between streamCollect and defragment of one frame. Baselines of Peng &
// Cao's Table 1: SnC (streaming without coherence) passes HostLayout{} as prev every frame, so
// every block is gathered and copied whole; NS (no streaming batch: one copy per object) is
// streamObjectByObject in defragment.h.

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
    std::vector<uint32_t> lengths;  // per-block bookkeeping of streamCollect; no meaning outside it
    std::vector<uint64_t> offsets;
};

struct StreamCounts {
    uint64_t vertices = 0;   // gathered (host -> device)
    uint64_t triangles = 0;
    uint64_t bytes() const { return vertices * sizeof(glm::vec3) + triangles * 3 * sizeof(uint32_t); }
};

// Fills `staging` with what `current` needs beyond what `previous` held, gathered from `host`,
// copies it to the device side of `staging` (the frame's one bulk host -> device transfer) and
// returns the counts. The layouts are the host's copies of the device layouts defragment gets
// (same blocks), read only; they may share arrays (an unchanged frame); previous may be
// HostLayout{} (first frame, or the SNC baseline). Objects in `current` with vc = 0 contribute
// nothing. Throws std::invalid_argument if current's ids are not strictly ascending. The gather
// is thread-parallel on the host.
StreamCounts streamCollect(const HostLayout& previous, const HostLayout& current, const HostGeometry& host,
                           StagingBuffers& staging);

}  // namespace occ::k
