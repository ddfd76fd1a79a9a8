// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "depth_raster.h"
#include "host_device.h"
#include "kernel_types.h"

#include <glm/glm.hpp>

namespace occ::k {

// Every mesh of a scene at full detail, resident on the device once (instanced meshes once):
// the .oss POSITIONS and TRIANGLES sections with their per-mesh starts, and per triangle the
// edges it shares within its mesh (sharedEdgeFlags) and the triangle across each, mesh-local.
struct MeshGeometry {
    DevicePtr<const glm::vec3> positions;       // mesh after mesh, object space
    DevicePtr<const uint32_t> triangles;        // 3 corners each, the mesh's own vertex numbering
    DevicePtr<const uint8_t> edge_flags;        // per triangle
    DevicePtr<const uint32_t> edge_neighbours;  // 3 per triangle, UINT32_MAX across unshared edges
    DevicePtr<const uint64_t> vertex_first;     // per mesh, into positions
    DevicePtr<const uint64_t> triangle_first;   // per mesh, in triangles
};

// The occluders of a frame as depthRaster takes them: their full-detail meshes transformed to
// world space and put back to back. Kept by the caller from frame to frame (arrays grow, never
// shrink); vertex_total and triangle_total say what the last gatherOccluders wrote.
struct OccluderGeometry {
    DeviceArray<glm::vec3> positions;
    DeviceArray<uint32_t> triangles;        // 3 per triangle, into positions
    DeviceArray<uint8_t> edge_flags;        // per triangle
    DeviceArray<uint32_t> edge_neighbours;  // 3 per triangle, into this list
    uint64_t vertex_total = 0, triangle_total = 0;
    DeviceArray<uint32_t> sizes;            // scratch: per occluder, vertex then triangle counts
    DeviceArray<uint64_t> offsets;          // scratch: their exclusive scans
    DeviceArray<uint8_t> front;             // scratch: per vertex, in front of the near plane
};

// Gathers objects ids[0, count) (device memory, any order, count may be 0): occluder j's
// vertices go after those of occluders 0..j-1, each multiplied by world[id] (as
// glm::vec3(world * vec4(p, 1))), its triangles likewise with corners offset by its first
// vertex, its edge flags copied (see eye below) and its edge neighbours offset by its first triangle (UINT32_MAX
// kept). objects and world have one entry per object. Everything runs on the device; the
// host reads back only the two totals (24 bytes).
// eye: null, or the camera's world position: then the triangles of closed meshes
// (kEdgeFlagClosedMesh) of objects whose world box does not hold it and whose world matrix does
// not mirror get kEdgeFlagSkipBackFace (depth_raster.h), and the raster skips their back faces.
// The flags copied keep the three shared-edge bits and that one, nothing else.
void gatherOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const glm::mat4> world, const MeshGeometry& meshes,
                     DevicePtr<const uint32_t> ids, uint32_t count, OccluderGeometry& out,
                     const glm::vec3* eye = nullptr);

// What gatherOccluders and appendNearClipped do to one occluder, vertex or triangle, shared with
// rasterOccluders' CPU front end so that both write the same bits.
// The world position of object-space vertex p under world matrix m.
OCC_HD inline glm::vec3 occluderVertex(const glm::mat4& m, const glm::vec3& p) { return glm::vec3(m * glm::vec4(p, 1.0f)); }

// Whether the closed-mesh triangles of an object with world box `box` and matrix m skip their back
// faces (see gatherOccluders' eye).
OCC_HD inline bool occluderSkipsBackFaces(const Aabb& box, const glm::mat4& m, const glm::vec3& eye, bool has_eye) {
    const bool outside = !(eye.x >= box.min.x && eye.x <= box.max.x && eye.y >= box.min.y && eye.y <= box.max.y &&
                           eye.z >= box.min.z && eye.z <= box.max.z);
    return has_eye && outside && glm::determinant(glm::mat3(m)) > 0.0f;
}

// Triangles [from, from + length) of the meshes' arrays to [to, to + length) of an occluder list:
// corners offset by `base` (the occluder's first vertex there), neighbours by `first_triangle`
// (its first triangle there; UINT32_MAX kept), flags cut to the shared-edge bits plus
// kEdgeFlagSkipBackFace on closed-mesh triangles when skip_back.
OCC_HD inline void copyOccluderTriangles(const uint32_t* triangles, const uint8_t* edge_flags,
                                         const uint32_t* edge_neighbours, uint64_t from, uint64_t to, uint64_t length,
                                         uint32_t base, uint32_t first_triangle, bool skip_back,
                                         uint32_t* out_triangles, uint8_t* out_flags, uint32_t* out_neighbours) {
    for (uint64_t c = 0; c < 3 * length; ++c) {
        out_triangles[3 * to + c] = triangles[3 * from + c] + base;
        const uint32_t across = edge_neighbours[3 * from + c];
        out_neighbours[3 * to + c] = across == UINT32_MAX ? UINT32_MAX : across + first_triangle;
    }
    const uint8_t skip = skip_back ? kEdgeFlagSkipBackFace : 0u;
    for (uint64_t t = 0; t < length; ++t) {
        const uint8_t f = edge_flags[from + t];
        out_flags[to + t] = uint8_t((f & 7u) | ((f & kEdgeFlagClosedMesh) ? skip : 0u));
    }
}

// clip.z + clip.w of a world point, >= 0 in front of the camera's near plane (OpenGL clip
// space): the row of view_proj that appendNearClipped measures sides with.
OCC_HD inline glm::vec4 nearPlaneRow(const glm::mat4& view_proj) {
    const glm::mat4& m = view_proj;  // m[column][row]
    return glm::vec4(m[0][2] + m[0][3], m[1][2] + m[1][3], m[2][2] + m[2][3], m[3][2] + m[3][3]);
}
OCC_HD inline float nearPlaneDistance(const glm::vec4& row, const glm::vec3& p) {
    return row.x * p.x + row.y * p.y + row.z * p.z + row.w;
}
OCC_HD inline bool inFrontOfNearPlane(const glm::vec4& row, const glm::vec3& p) { return nearPlaneDistance(row, p) > 0.0f; }

// The depth raster skips a triangle whole when a corner is behind the near plane (it has no
// screen position), so a floor or wall the camera stands on or beside would occlude nothing.
// appendNearClipped appends to g, for each of its triangle_total triangles that crosses the
// camera's near plane, the part in front of it as one or two new triangles on new vertices
// (winding kept, every edge a boundary: edge flag 0, neighbours UINT32_MAX). The new corners on
// the plane are pulled 0.1 % of their edge toward the corners in front, so each new triangle is
// inside the original one: what the raster writes stays a subset of the occluder, and the
// culling conservative. Updates the totals and returns how many triangles it appended (the
// original ones stay, and stay skipped). Runs on the device; reads back 8 bytes.
uint64_t appendNearClipped(OccluderGeometry& g, const Camera& camera);

#if !defined(__CUDACC__)
// appendNearClipped's appended triangles when the crossing ones are known (rasterOccluders'
// CPU front end finds them while it copies each occluder): appends, after g's current totals,
// the parts in front of the near plane of crossing[0, n), counts[i] being how many corners of
// crossing[i] are in front (1 or 2: the new triangles it gives). Given every crossing triangle
// of g in ascending order, in one list or in several calls in turn, it appends what
// appendNearClipped appends. Host code of the CPU build.
uint64_t appendNearClippedList(OccluderGeometry& g, const Camera& camera, const uint32_t* crossing,
                               const uint8_t* counts, uint64_t n);
#endif

// The occluders' depth image: gatherOccluders(objects, world, meshes, ids, count, g, &camera.eye),
// appendNearClipped(g, camera), then depthRaster of g with seams into depth, W x H as the
// camera says; returns g.triangle_total. The same bits in g, scratch and depth as those three
// calls. On the CPU the gather, the near plane's sides, the projection and the triangles' setup
// run in one pass over the occluders (chunks of them in parallel), an occluder's vertices and
// triangles still in cache when its triangles are set up, instead of one pass over all of them
// per step; the next occluders' meshes are prefetched.
uint64_t rasterOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const glm::mat4> world,
                         const MeshGeometry& meshes, DevicePtr<const uint32_t> ids, uint32_t count,
                         const Camera& camera, OccluderGeometry& g, DevicePtr<float> depth,
                         DepthRasterScratch& scratch);

}  // namespace occ::k
