// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "host_device.h"
#include "kernel_types.h"

// GPU-driven drawing: the device writes the frame's indirect draw commands and per-draw
// attributes straight into the display's GL buffers, so that drawing costs the bus nothing.

namespace occ::k {

// OpenGL's DrawElementsIndirectCommand.
struct DrawCommand {
    uint32_t count;          // indices
    uint32_t instance_count;
    uint32_t first_index;
    int32_t base_vertex;
    uint32_t base_instance;  // the draw's index, where its DrawAttributes are
};
static_assert(sizeof(DrawCommand) == 20);

// Read by the vertex shader as instanced attributes (divisor 1) at the draw's base instance.
struct DrawAttributes {
    uint32_t object;    // object id
    float depth_floor;  // objectDepthFloor of the object's box for the frame's camera
};
static_assert(sizeof(DrawAttributes) == 8);

// The window depth of the nearest point of `box` seen through view_proj, a hair (1e-6) nearer,
// or 0 when the box reaches the near plane (a corner with clip.w <= near_plane or in front of
// the near clip plane) or a corner projects to NaN. No surface inside the box is nearer; the
// display clamps each fragment's depth to it, because a rasteriser may extrapolate a sliver
// triangle's depth plane nearer than any of its vertices (llvmpipe does, by 1e-3).
OCC_HD inline float objectDepthFloor(const Aabb& box, const glm::mat4& view_proj, float near_plane) {
    float nearest = 1.0f;
    for (int c = 0; c < 8; ++c) {
        const glm::vec4 clip = view_proj * glm::vec4(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y,
                                                     c & 4 ? box.max.z : box.min.z, 1.0f);
        if (!(clip.w > near_plane) || !(clip.z >= -clip.w)) return 0.0f;
        const float depth = clip.z / clip.w * 0.5f + 0.5f;
        nearest = depth < nearest ? depth : nearest;
    }
    const float floor = nearest - 1e-6f;
    return floor > 0.0f ? floor : 0.0f;
}

// One block the frame draws: object `object`'s first triangle_count triangles, whose block-local
// indices start at first_triangle in the index buffer and whose vertices start at base_vertex.
struct DrawBlock {
    uint32_t object;
    uint32_t triangle_count;
    uint32_t first_triangle;
    uint32_t base_vertex;
};
static_assert(sizeof(DrawBlock) == 16);

// For each of blocks[0, count) (device memory): commands[k] = {3 triangle_count, 1,
// 3 first_triangle, base_vertex, k} and attributes[k] = {object, objectDepthFloor(its box,
// camera)}. commands and attributes have room for count entries.
void writeDrawCommands(DevicePtr<const DrawBlock> blocks, uint32_t count, DevicePtr<const ObjectInfo> objects,
                       const Camera& camera, DevicePtr<DrawCommand> commands, DevicePtr<DrawAttributes> attributes);

}  // namespace occ::k
