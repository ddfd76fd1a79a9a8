// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

namespace occ::k {

// One block to reform: object `object`'s first triangle_count triangles, at triangle_offset in
// the active triangle array and in the index buffer alike, walked below walk_vertex_count.
struct ReformBlock {
    uint64_t triangle_offset;
    uint32_t object;
    uint32_t walk_vertex_count;
    uint32_t triangle_count;
    uint32_t pad;  // keeps the struct 8-byte aligned on both compilers
};
static_assert(sizeof(ReformBlock) == 24);

// Scratch of reformBlocks, kept by the caller between frames.
struct ReformScratch {
    DeviceArray<uint32_t> lengths;
    DeviceArray<uint64_t> offsets;
};

// Triangle reformation, Algorithm 4 of Peng & Cao 2012, for the blocks that changed: for every
// triangle t < triangle_count of each listed block, each corner c (in its object's own vertex
// numbering, as the active triangle array holds it) is walked through the object's ecol until
// c < walk_vertex_count, and written to indices[3 (triangle_offset + t) + k]. Indices are local
// to the block: the display draws each block with its vertex offset as base vertex, so a block
// that does not change keeps its indices wherever others go.
//   blocks            count entries (device memory); walk_vertex_count >= the mesh's q, so that
//                     no walk reaches ecol = -1; blocks with walk_vertex_count 0 are skipped;
//                     a block may hold more triangles than the walked LOD draws (kept resident
//                     for later frames): those come out degenerate and are not drawn;
//   objects           per object, .mesh and .vertex_count; blocks walked at full detail
//                     (walk_vertex_count >= vertex_count) are copied;
//   vertex_first      per mesh, index of its first vertex in ecol;
//   ecol              every mesh's ecol back to back: ecol[v] < v for v >= q, so every walk ends;
//   active_triangles  the active triangle array; indices: the index buffer (both device memory).
// On the GPU one thread reforms one triangle; on the CPU a thread takes a run of them. Returns
// the triangles of the listed blocks (skipped ones included).
uint64_t reformBlocks(DevicePtr<const ReformBlock> blocks, uint32_t count, DevicePtr<const ObjectInfo> objects,
                      DevicePtr<const uint64_t> vertex_first, DevicePtr<const int32_t> ecol,
                      DevicePtr<const uint32_t> active_triangles, DevicePtr<uint32_t> indices, ReformScratch& scratch);

}  // namespace occ::k
