// SPDX-License-Identifier: MIT
#include "draw_commands.h"

#include "device_access.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

struct IsDrawn {
    const uint32_t* draw_vertices;
    OCC_HD bool operator()(uint32_t j) const { return draw_vertices[j] > 0; }
};

struct WriteCommand {
    const uint32_t* blocks;  // the drawn blocks' indices into the layout
    HostLayout layout;       // device pointers, raw
    const uint32_t* draw_vertices;
    const ObjectInfo* objects;
    const uint64_t* map_first;
    const uint32_t* maps;
    glm::mat4 view_proj;
    float near_plane;
    DrawCommand* commands;
    DrawAttributes* attributes;

    OCC_HD void operator()(uint32_t k) const {
        const uint32_t j = blocks[k];
        const uint32_t id = layout.objects[j];
        const ObjectInfo& o = objects[id];
        const uint32_t tc = maps[map_first[o.mesh] + draw_vertices[j]];
        commands[k] = {3 * tc, 1, uint32_t(3 * layout.triangle_offset[j]), 0, k};
        attributes[k] = {id, objectDepthFloor(o.aabb, view_proj, near_plane)};
    }
};

}  // namespace

uint32_t writeDrawCommands(const ActiveLayout& layout, DevicePtr<const uint32_t> draw_vertices,
                           DevicePtr<const ObjectInfo> objects, DevicePtr<const uint64_t> map_first,
                           DevicePtr<const uint32_t> maps, const Camera& camera, DevicePtr<DrawCommand> commands,
                           DevicePtr<DrawAttributes> attributes, DeviceArray<uint32_t>& blocks) {
    if (layout.count == 0) return 0;
    if (blocks.size() < layout.count) blocks.resize(layout.count);
    const thrust::counting_iterator<uint32_t> first(0);
    uint32_t* const end = thrust::copy_if(thrust::device, first, first + layout.count, raw(blocks.ptr()),
                                          IsDrawn{raw(draw_vertices)});
    countReadback(sizeof(uint32_t));  // copy_if's count
    const uint32_t draws = uint32_t(end - raw(blocks.ptr()));
    thrust::for_each_n(thrust::device, first, draws,
                       WriteCommand{raw(blocks.ptr()),
                                    {raw(layout.objects), raw(layout.vertex_count), raw(layout.triangle_count),
                                     raw(layout.vertex_offset), raw(layout.triangle_offset), layout.count,
                                     layout.vertex_total, layout.triangle_total},
                                    raw(draw_vertices), raw(objects), raw(map_first), raw(maps), camera.view_proj,
                                    camera.near_plane, raw(commands), raw(attributes)});
    return draws;
}

}  // namespace occ::k
