// SPDX-License-Identifier: MIT
#include "occluder_gather.h"

#include "depth_raster.h"

#include "device_access.h"
#include "layout_access.h"
#include "scan.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/count.h>

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
                       for (uint64_t v = 0; v < length; ++v) dst[v] = occluderVertex(m, src[v]);
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
    const glm::mat4* world;
    glm::vec3 eye;
    bool has_eye;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(triangle_offsets, count, total, tile * kRunTile, tileEnd(tile, total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint32_t id = ids[j];
                       copyOccluderTriangles(triangles, edge_flags, edge_neighbours,
                                             triangle_first[objects[id].mesh] + first, triangle_offsets[j] + first,
                                             length, uint32_t(vertex_offsets[j]), uint32_t(triangle_offsets[j]),
                                             occluderSkipsBackFaces(objects[id].aabb, world[id], eye, has_eye),
                                             out_triangles, out_flags, out_neighbours);
                   });
    }
};

}  // namespace

void gatherOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const glm::mat4> world, const MeshGeometry& meshes,
                     DevicePtr<const uint32_t> ids, uint32_t count, OccluderGeometry& out, const glm::vec3* eye) {
    out.vertex_total = out.triangle_total = 0;
    if (count == 0) return;
    out.sizes.growTo(2 * uint64_t(count));
    out.offsets.growTo(2 * uint64_t(count));
    uint32_t* const sizes = raw(out.sizes.ptr());
    uint64_t* const offsets = raw(out.offsets.ptr());
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), count,
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
                                raw(out.edge_neighbours.ptr()), raw(world), eye ? *eye : glm::vec3(0.0f),
                                eye != nullptr});
}

namespace {

// clip.z + clip.w of a world point: >= 0 in front of the near plane (OpenGL clip space).
struct NearDistance {
    glm::vec4 row;  // nearPlaneRow
    OCC_HD float operator()(const glm::vec3& p) const { return nearPlaneDistance(row, p); }
};

// Per vertex, 1 when it is in front of the near plane.
struct NearSides {
    const glm::vec3* positions;
    glm::vec4 row;
    uint8_t* front;
    OCC_HD void operator()(uint64_t v) const { front[v] = inFrontOfNearPlane(row, positions[v]) ? 1u : 0u; }
};

struct CountNearClipped {
    const uint8_t* front;
    const uint32_t* triangles;
    uint32_t* counts;
    OCC_HD void operator()(uint32_t t) const {
        const uint32_t in = front[triangles[3 * t]] + front[triangles[3 * t + 1]] + front[triangles[3 * t + 2]];
        counts[t] = in == 1 ? 1u : in == 2 ? 2u : 0u;  // 0 and 3: nothing to add
    }
};

struct WriteNearClipped {
    glm::vec3* positions;
    uint32_t* triangles;
    uint8_t* edge_flags;
    uint32_t* neighbours;
    const uint32_t* counts;
    const uint64_t* offsets;
    NearDistance near;
    uint64_t vertex_base, triangle_base;

    // The point of edge from -> to (from in front, to behind) 0.1 % short of the plane.
    OCC_HD glm::vec3 onPlane(const glm::vec3& from, float d_from, const glm::vec3& to, float d_to) const {
        const float t = 0.999f * d_from / (d_from - d_to);
        return from + t * (to - from);
    }
    OCC_HD void put(uint64_t k, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) const {
        const uint64_t v = vertex_base + 3 * k, tri = triangle_base + k;
        positions[v] = a;
        positions[v + 1] = b;
        positions[v + 2] = c;
        for (uint32_t j = 0; j < 3; ++j) {
            triangles[3 * tri + j] = uint32_t(v + j);
            neighbours[3 * tri + j] = UINT32_MAX;
        }
        edge_flags[tri] = 0;
    }
    OCC_HD void operator()(uint32_t t) const {
        if (counts[t] != 0) write(t, counts[t], offsets[t]);
    }
    // Triangle t, `count` (1 or 2) of whose corners are in front, as new triangles k (and k + 1).
    OCC_HD void write(uint32_t t, uint32_t count, uint64_t k) const {
        glm::vec3 p[3];
        float d[3];
        for (int c = 0; c < 3; ++c) {
            p[c] = positions[triangles[3 * t + c]];
            d[c] = near(p[c]);
        }
        // Rotate so that the lone corner (in front for one new triangle, behind for two) is
        // first, keeping the cyclic order and so the winding.
        const bool one = count == 1;
        int lone = 0;
        for (int c = 0; c < 3; ++c)
            if ((d[c] > 0.0f) == one) lone = c;
        const glm::vec3 a = p[lone], b = p[(lone + 1) % 3], c = p[(lone + 2) % 3];
        const float da = d[lone], db = d[(lone + 1) % 3], dc = d[(lone + 2) % 3];
        if (one) {
            put(k, a, onPlane(a, da, b, db), onPlane(a, da, c, dc));
        } else {
            // a behind, b and c in front: the quad b, c, c->a, b->a.
            const glm::vec3 ca = onPlane(c, dc, a, da), ba = onPlane(b, db, a, da);
            put(k, b, c, ca);
            put(k + 1, b, ca, ba);
        }
    }
};

template <class T>
void growKeeping(DeviceArray<T>& a, uint64_t n) {
    if (a.size() < n) a.resizeKeep(n + n / 2);
}

// Room in g for `added` clipped triangles on 3 new vertices each, after its current totals.
void growForClipped(OccluderGeometry& g, uint64_t added) {
    growKeeping(g.positions, g.vertex_total + 3 * added);
    growKeeping(g.triangles, 3 * (g.triangle_total + added));
    growKeeping(g.edge_flags, g.triangle_total + added);
    growKeeping(g.edge_neighbours, 3 * (g.triangle_total + added));
}

// The writer of clipped triangles after g's current totals (arrays grown by growForClipped).
WriteNearClipped clippedWriter(OccluderGeometry& g, const Camera& camera, const uint32_t* counts,
                               const uint64_t* offsets) {
    return WriteNearClipped{raw(g.positions.ptr()), raw(g.triangles.ptr()),      raw(g.edge_flags.ptr()),
                            raw(g.edge_neighbours.ptr()), counts, offsets, NearDistance{nearPlaneRow(camera.view_proj)},
                            g.vertex_total, g.triangle_total};
}

}  // namespace

uint64_t appendNearClipped(OccluderGeometry& g, const Camera& camera) {
    const uint64_t triangles = g.triangle_total, vertices = g.vertex_total;
    if (triangles == 0 || triangles > UINT32_MAX) return 0;
    // Which side each vertex is on, once: when every vertex is on one side no triangle crosses
    // (the usual case away from walls and floors), and the triangles' count reads a byte a
    // corner instead of a position.
    g.front.growTo(vertices);
    uint8_t* const front = raw(g.front.ptr());
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint64_t>(0), vertices,
                       NearSides{raw(g.positions.ptr()), nearPlaneRow(camera.view_proj), front});
    const uint64_t in_front = uint64_t(thrust::count(onDevice(), front, front + vertices, uint8_t(1)));
    countReadback(sizeof in_front);
    if (in_front == 0 || in_front == vertices) return 0;
    g.sizes.growTo(triangles);
    g.offsets.growTo(triangles);
    const auto n = uint32_t(triangles);
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), n,
                       CountNearClipped{front, raw(g.triangles.ptr()), raw(g.sizes.ptr())});
    const uint64_t added = exclusiveScan(g.sizes.ptr(), n, g.offsets.ptr());
    if (added == 0) return 0;
    growForClipped(g, added);
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), n,
                       clippedWriter(g, camera, raw(g.sizes.ptr()), raw(g.offsets.ptr())));
    g.vertex_total += 3 * added;
    g.triangle_total += added;
    return added;
}

#if !defined(__CUDACC__)
uint64_t appendNearClippedList(OccluderGeometry& g, const Camera& camera, const uint32_t* crossing,
                               const uint8_t* counts, uint64_t n) {
    uint64_t added = 0;
    for (uint64_t i = 0; i < n; ++i) added += counts[i];
    if (added == 0) return 0;
    growForClipped(g, added);
    const WriteNearClipped write = clippedWriter(g, camera, nullptr, nullptr);
    uint64_t k = 0;
    for (uint64_t i = 0; i < n; ++i) {
        write.write(crossing[i], counts[i], k);
        k += counts[i];
    }
    g.vertex_total += 3 * added;
    g.triangle_total += added;
    return added;
}
#endif

}  // namespace occ::k
