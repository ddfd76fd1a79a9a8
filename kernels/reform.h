// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_types.h"
#include "scan.h"

namespace occ::k {

// Triangle reformation, Algorithm 4 of Peng & Cao 2012: the frame's index buffer. For every
// active triangle, each corner c (in its object's own vertex numbering, as the active triangle
// array holds it) is walked through the object's ecol until c < vc, then the object's vertex
// offset in the active vertex array is added.
//   layout            the frame's layout, which the active triangle array holds (per object
//                     ranges: block j's triangles start at triangle_offset[j]);
//   objects           per object, .mesh and .vertex_count (device memory); blocks at full
//                     detail (vc = vertex_count) skip the walk;
//   vertex_first      per mesh, index of its first vertex in ecol (device memory);
//   ecol              every mesh's ecol back to back, the .oss ECOL section copied to kernel
//                     memory once: ecol[v] < v for v >= q, so every walk ends;
//   active_triangles  3 * layout.triangle_total corners (ActiveArrays::triangles.data());
//   indices           out: 3 * layout.triangle_total entries (device memory), triangle t of the
//                     active array becoming indices[3t, 3t+3).
//   walk_vertex_count optional, per block: walk corners below this many vertices instead of
//                     layout.vertex_count (a block may hold more vertices than the frame draws,
//                     kept resident for later frames; its triangles past the drawn LOD's map
//                     come out degenerate and are not drawn). Blocks with 0 are skipped.
// Requires layout.vertex_total <= 2^32 (indices are 32-bit) and, for every drawn block,
// vc >= the mesh's q (lodSelect's floor) so that no walk reaches ecol = -1. Nothing is written
// when triangle_total is 0. On the GPU one thread reforms one triangle; on the CPU a thread
// takes a run of consecutive triangles.
void reform(const ActiveLayout& layout, DevicePtr<const ObjectInfo> objects, DevicePtr<const uint64_t> vertex_first,
            DevicePtr<const int32_t> ecol, DevicePtr<const uint32_t> active_triangles, DevicePtr<uint32_t> indices,
            DevicePtr<const uint32_t> walk_vertex_count = nullptr);

}  // namespace occ::k
