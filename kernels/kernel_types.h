// SPDX-License-Identifier: MIT
#pragma once

#include "host_device.h"

// Structs that both the CPU and the kernels read, defined once. Sizes are fixed so that the
// CUDA and C++ compilers agree on the layout (glm::vec3 is 12 bytes, 4-byte aligned).
namespace occ::k {

// World-space axis-aligned box.
struct Aabb {
    glm::vec3 min;
    glm::vec3 max;
};
static_assert(sizeof(Aabb) == 24);

// What one frame is seen with. view_proj maps world to clip space (OpenGL conventions:
// right-handed view looking down -z, clip z in [-w, w]); depth in the depth buffer and the
// HZM is window depth in [0, 1] (0 = near plane, 1 = far plane), larger is farther.
struct Camera {
    glm::mat4 view_proj;
    glm::vec3 eye;      // world-space position
    float near_plane;
    glm::vec3 forward;  // world-space unit view direction (E of Eq. 3)
    float far_plane;
    uint32_t width;     // viewport in pixels
    uint32_t height;
    float fovy;         // vertical field of view, radians
    float pad;          // keeps the struct a multiple of 16 bytes
};
static_assert(sizeof(Camera) == 64 + 16 + 16 + 16);

// The six frustum planes as (n, d) with n pointing inside: a point p is inside when
// dot(n, p) + d >= 0 for all six. Order: left, right, bottom, top, near, far.
struct Frustum {
    glm::vec4 planes[6];
};

// Per-object data the per-frame kernels read (built once from the .oss).
struct ObjectInfo {
    Aabb aabb;
    glm::vec3 occluder_normal;  // N of Eq. 3, unit
    float compactness;
    uint32_t mesh;              // index into the mesh tables
    uint32_t vertex_count;      // full detail (P_i of Eq. 1)
    uint32_t q;                 // vertex floor: never fewer (boundary and locked vertices)
    uint32_t triangle_count;    // full detail
};
static_assert(sizeof(ObjectInfo) == 24 + 12 + 4 + 16);

}  // namespace occ::k
