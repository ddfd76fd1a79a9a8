// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

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

}  // namespace occ::k
