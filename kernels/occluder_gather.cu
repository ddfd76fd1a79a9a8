// SPDX-License-Identifier: MIT
#include "occluder_gather.h"

#include "layout_access.h"
#include "scan.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

struct SizesOf {
    const ObjectInfo* objects;
    const uint32_t* ids;
    uint32_t count;
    uint32_t* sizes;  // vertex counts, then triangle counts
    OCC_HD void operator()(uint32_t j) const {
        const ObjectInfo& o = objects[ids[j]];
        sizes[j] = o.vertex_count;
        sizes[count + j] = o.triangle_count;
    }
};

struct TransformVertices {
    const ObjectInfo* objects;
    const glm::mat4* world;
    const uint32_t* ids;
    const uint64_t* offsets;  // per occluder, its first vertex
    uint32_t count;
    uint64_t total;
    const glm::vec3* positions;
    const uint64_t* vertex_first;
    glm::vec3* out;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(offsets, count, total, tile * kRunTile, tileEnd(tile, total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint32_t id = ids[j];
                       const glm::mat4 m = world[id];
                       const glm::vec3* src = positions + vertex_first[objects[id].mesh] + first;
                       glm::vec3* dst = out + offsets[j] + first;
                       for (uint64_t v = 0; v < length; ++v) dst[v] = glm::vec3(m * glm::vec4(src[v], 1.0f));
                   });
    }
};

struct OffsetTriangles {
    const ObjectInfo* objects;
    const uint32_t* ids;
    const uint64_t* vertex_offsets;    // per occluder
    const uint64_t* triangle_offsets;  // per occluder
    uint32_t count;
    uint64_t total;
    const uint32_t* triangles;
    const uint8_t* edge_flags;
    const uint32_t* edge_neighbours;
    const uint64_t* triangle_first;
    uint32_t* out_triangles;
    uint8_t* out_flags;
    uint32_t* out_neighbours;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(triangle_offsets, count, total, tile * kRunTile, tileEnd(tile, total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint64_t from = triangle_first[objects[ids[j]].mesh] + first;
                       const uint64_t to = triangle_offsets[j] + first;
                       const uint32_t base = uint32_t(vertex_offsets[j]);
                       const uint32_t first_triangle = uint32_t(triangle_offsets[j]);
                       for (uint64_t c = 0; c < 3 * length; ++c) {
                           out_triangles[3 * to + c] = triangles[3 * from + c] + base;
                           const uint32_t across = edge_neighbours[3 * from + c];
                           out_neighbours[3 * to + c] = across == UINT32_MAX ? UINT32_MAX : across + first_triangle;
                       }
                       for (uint64_t t = 0; t < length; ++t) out_flags[to + t] = edge_flags[from + t];
                   });
    }
};

}  // namespace

void gatherOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const glm::mat4> world, const MeshGeometry& meshes,
                     DevicePtr<const uint32_t> ids, uint32_t count, OccluderGeometry& out) {
    out.vertex_total = out.triangle_total = 0;
    if (count == 0) return;
    out.sizes.growTo(2 * uint64_t(count));
    out.offsets.growTo(2 * uint64_t(count));
    uint32_t* const sizes = raw(out.sizes.ptr());
    uint64_t* const offsets = raw(out.offsets.ptr());
    thrust::for_each_n(thrust::device, thrust::counting_iterator<uint32_t>(0), count,
                       SizesOf{raw(objects), raw(ids), count, sizes});
    out.vertex_total = exclusiveScan(out.sizes.ptr(), count, out.offsets.ptr());
    out.triangle_total = exclusiveScan(out.sizes.ptr() + count, count, out.offsets.ptr() + count);
    out.positions.growTo(out.vertex_total);
    out.triangles.growTo(3 * out.triangle_total);
    out.edge_flags.growTo(out.triangle_total);
    out.edge_neighbours.growTo(3 * out.triangle_total);
    forEachTile(out.vertex_total, TransformVertices{raw(objects), raw(world), raw(ids), offsets, count, out.vertex_total,
                                                    raw(meshes.positions), raw(meshes.vertex_first),
                                                    raw(out.positions.ptr())});
    forEachTile(out.triangle_total,
                OffsetTriangles{raw(objects), raw(ids), offsets, offsets + count, count, out.triangle_total,
                                raw(meshes.triangles), raw(meshes.edge_flags), raw(meshes.edge_neighbours),
                                raw(meshes.triangle_first), raw(out.triangles.ptr()), raw(out.edge_flags.ptr()),
                                raw(out.edge_neighbours.ptr())});
}

}  // namespace occ::k
