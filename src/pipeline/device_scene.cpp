// SPDX-License-Identifier: MIT
#include "pipeline/device_scene.h"

#include "depth_raster.h"

#include <algorithm>
#include <cstring>
#include <execution>
#include <numeric>
#include <vector>

namespace occ {

namespace {

template <class T>
void copyInto(k::KernelArray<T>& dst, std::span<const T> src) {
    dst.resize(src.size());
    if (!src.empty()) std::memcpy(dst.data(), src.data(), src.size_bytes());
}

}  // namespace

DeviceScene DeviceScene::upload(const OssFile& file) {
    DeviceScene d;
    d.file = &file;
    d.object_count = file.objectCount();
    d.mesh_count = file.meshCount();

    const std::span<const oss::MeshRecord> meshes = file.meshRecords();
    d.vertex_first.resize(d.mesh_count);
    d.triangle_first.resize(d.mesh_count);
    d.map_first.resize(d.mesh_count);
    for (uint32_t m = 0; m < d.mesh_count; ++m) {
        d.vertex_first[m] = meshes[m].vertex_first;
        d.triangle_first[m] = meshes[m].triangle_first;
        d.map_first[m] = meshes[m].map_first;
    }
    copyInto(d.ecol, file.allEcol());
    copyInto(d.maps, file.allMaps());
    copyInto(d.cos, file.cos());

    // Meshes are independent and most are small: one task each.
    const std::span<const uint32_t> triangles = file.allTriangles();
    d.edge_flags.resize(triangles.size() / 3);
    d.edge_neighbours.resize(triangles.size());
    std::vector<uint32_t> mesh_ids(d.mesh_count);
    std::iota(mesh_ids.begin(), mesh_ids.end(), 0u);
    std::for_each(std::execution::par, mesh_ids.begin(), mesh_ids.end(), [&](uint32_t m) {
        k::sharedEdgeFlags(triangles.data() + 3 * meshes[m].triangle_first, meshes[m].triangle_count,
                           d.edge_flags.data() + meshes[m].triangle_first,
                           d.edge_neighbours.data() + 3 * meshes[m].triangle_first);
    });

    const std::span<const oss::ObjectDisk> objects = file.objects();
    d.objects.resize(d.object_count);
    d.world.resize(d.object_count);
    for (uint32_t i = 0; i < d.object_count; ++i) {
        const oss::ObjectDisk& o = objects[i];
        const oss::MeshRecord& m = meshes[o.mesh];
        k::ObjectInfo& info = d.objects[i];
        info.aabb.min = glm::vec3(o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]);
        info.aabb.max = glm::vec3(o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]);
        info.occluder_normal = glm::vec3(o.occluder_normal[0], o.occluder_normal[1], o.occluder_normal[2]);
        info.compactness = o.compactness;
        info.mesh = o.mesh;
        info.vertex_count = m.vertex_count;
        info.q = m.q;
        info.triangle_count = m.triangle_count;
        std::memcpy(&d.world[i], o.world, sizeof(glm::mat4));
    }
    return d;
}

}  // namespace occ
