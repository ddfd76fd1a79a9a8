// SPDX-License-Identifier: MIT
#include "draw_commands.h"

#include "device_access.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

struct WriteCommand {
    const DrawBlock* blocks;
    const ObjectInfo* objects;
    glm::mat4 view_proj;
    float near_plane;
    DrawCommand* commands;
    DrawAttributes* attributes;

    OCC_HD void operator()(uint32_t k) const {
        const DrawBlock b = blocks[k];
        commands[k] = {3 * b.triangle_count, 1, 3 * b.first_triangle, int32_t(b.base_vertex), k};
        attributes[k] = {b.object, objectDepthFloor(objects[b.object].aabb, view_proj, near_plane)};
    }
};

}  // namespace

void writeDrawCommands(DevicePtr<const DrawBlock> blocks, uint32_t count, DevicePtr<const ObjectInfo> objects,
                       const Camera& camera, DevicePtr<DrawCommand> commands, DevicePtr<DrawAttributes> attributes) {
    if (count == 0) return;
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), count,
                       WriteCommand{raw(blocks), raw(objects), camera.view_proj, camera.near_plane, raw(commands),
                                    raw(attributes)});
}

}  // namespace occ::k
