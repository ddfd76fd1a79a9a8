// SPDX-License-Identifier: MIT
#include "pipeline/device_scene.h"

#include "depth_raster.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <execution>
#include <numeric>

namespace occ {

namespace {

template <class T>
void copyUp(k::DeviceArray<T>& dst, std::span<const T> src) {
    dst.resize(std::max<size_t>(1, src.size()));
    k::copyToDevice(dst.ptr(), src.data(), src.size());
}

template <class T>
void copyUp(k::DeviceArray<T>& dst, const std::vector<T>& src) {
    copyUp(dst, std::span<const T>(src));
}

}  // namespace

k::MeshGeometry DeviceScene::meshes() const {
    return {positions, triangles, edge_flags.ptr(), edge_neighbours.ptr(), vertex_first.ptr(), triangle_first.ptr()};
}

uint32_t DeviceScene::lodTriangles(uint32_t mesh, uint32_t vertices) const {
    return vertices ? file->allMaps()[host_map_first[mesh] + vertices] : 0u;
}

DeviceScene DeviceScene::upload(const OssFile& file, bool hierarchy) {
    DeviceScene d;
    d.file = &file;
    d.nodes = hierarchy;
    d.item_count = hierarchy ? file.nodeCount() : file.objectCount();
    d.mesh_count = file.meshCount();
    if (hierarchy && file.nodeCount() == 0)
        throw std::invalid_argument("DeviceScene::upload: " + file.path() + " has no hierarchy");

    const std::span<const oss::MeshRecord> meshes = file.meshRecords();
    d.host_vertex_first.resize(d.mesh_count);
    d.host_triangle_first.resize(d.mesh_count);
    d.host_map_first.resize(d.mesh_count);
    for (uint32_t m = 0; m < d.mesh_count; ++m) {
        d.host_vertex_first[m] = meshes[m].vertex_first;
        d.host_triangle_first[m] = meshes[m].triangle_first;
        d.host_map_first[m] = meshes[m].map_first;
    }

    const std::span<const uint32_t> triangles = file.allTriangles();

    const std::span<const oss::ObjectDisk> objects = file.objects();
    d.host_objects.resize(d.item_count);
    d.host_world.resize(d.item_count);
    std::vector<uint32_t> item_of_object;  // with nodes: each object's leaf
    if (hierarchy) {
        const std::span<const oss::Node> nodes = file.nodes();
        d.host_nodes.resize(d.item_count);
        item_of_object.resize(file.objectCount());
        for (uint32_t i = d.item_count; i-- > 0;) {
            const oss::Node& n = nodes[i];
            NodeLinks& links = d.host_nodes[i];
            links.first_child = n.first_child;
            links.child_count = n.child_count;
            links.error = n.error;
            if (n.child_count == 0) {
                links.object = n.object;
                item_of_object[n.object] = i;
                continue;
            }
            const oss::MeshRecord& m = meshes[n.mesh];
            k::ObjectInfo& info = d.host_objects[i];
            info.aabb.min = glm::make_vec3(n.box_min);
            info.aabb.max = glm::make_vec3(n.box_max);
            info.occluder_normal = glm::vec3(0, 0, 1);
            info.compactness = -1.0f;  // an HLOD is never an occluder: it is not the real surface
            info.mesh = n.mesh;
            info.vertex_count = m.vertex_count;
            info.q = m.q;
            info.triangle_count = m.triangle_count;
            std::memcpy(&d.host_world[i], n.world, sizeof(glm::mat4));  // a shared HLOD's placement
        }
    }
    for (uint32_t object = 0; object < file.objectCount(); ++object) {
        const uint32_t i = hierarchy ? item_of_object[object] : object;
        const oss::ObjectDisk& o = objects[object];
        const oss::MeshRecord& m = meshes[o.mesh];
        k::ObjectInfo& info = d.host_objects[i];
        info.aabb.min = glm::vec3(o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]);
        info.aabb.max = glm::vec3(o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]);
        info.occluder_normal = glm::vec3(o.occluder_normal[0], o.occluder_normal[1], o.occluder_normal[2]);
        info.compactness = o.compactness;
        info.mesh = o.mesh;
        info.vertex_count = m.vertex_count;
        info.q = m.q;
        info.triangle_count = m.triangle_count;
        std::memcpy(&d.host_world[i], o.world, sizeof(glm::mat4));
    }

    // Once, at start-up: everything the frames read on the device. A GPU too small for it says so.
    const bool in_place = k::deviceReadsHostMemory();
    const uint64_t needed = uint64_t(d.item_count) * (sizeof(k::ObjectInfo) + sizeof(glm::mat4)) +
                            uint64_t(d.mesh_count) * 3 * sizeof(uint64_t) + file.cos().size_bytes() +
                            (in_place ? 0
                                      : file.allEcol().size_bytes() + file.allMaps().size_bytes() +
                                            file.allPositions().size_bytes() + triangles.size_bytes()) +
                            triangles.size() / 3 + triangles.size_bytes();
    k::requireDeviceMemory(needed, "the scene " + file.path());
    copyUp(d.objects, d.host_objects);
    copyUp(d.world, d.host_world);
    copyUp(d.vertex_first, d.host_vertex_first);
    copyUp(d.triangle_first, d.host_triangle_first);
    copyUp(d.map_first, d.host_map_first);
    // Read in place where the device can (views into the mapping), else copied up.
    const auto place = [in_place](auto& copy, auto section) {
        if (in_place && !section.empty()) return k::hostView(section.data());
        copyUp(copy, section);
        return decltype(k::hostView(section.data()))(copy.ptr());
    };
    d.ecol = place(d.ecol_copy, file.allEcol());
    d.maps = place(d.maps_copy, file.allMaps());
    if (hierarchy) {
        std::vector<uint32_t> cos(file.cos().begin(), file.cos().end());
        for (uint32_t& c : cos) c = item_of_object[c];
        copyUp(d.cos, cos);
    } else {
        copyUp(d.cos, file.cos());
    }
    d.cos_count = uint32_t(file.cos().size());
    d.positions = place(d.positions_copy, file.allPositions());
    d.triangles = place(d.triangles_copy, triangles);

    // The shared edges of every mesh, computed in batches of meshes through a host buffer of at
    // most about kEdgeBatchTriangles triangles (13 bytes each), not for the whole scene at once:
    // on a 3.3 x 10^8-triangle scene that whole-scene buffer was 4.3 GB on top of the device's
    // copy. Meshes are independent and most are small: one task each.
    constexpr uint64_t kEdgeBatchTriangles = uint64_t(1) << 24;
    const uint64_t triangle_total = triangles.size() / 3;
    d.edge_flags.resize(std::max<uint64_t>(1, triangle_total));
    d.edge_neighbours.resize(std::max<uint64_t>(1, 3 * triangle_total));
    std::vector<uint8_t> edge_flags;
    std::vector<uint32_t> edge_neighbours;
    std::vector<uint32_t> batch;
    // Only objects are occluders (an HLOD never is: compactness -1 above), so the meshes no
    // object uses, the HLODs', get no shared edges: a quarter of the 10^6 plant's triangles,
    // and of the start-up's time.
    std::vector<uint8_t> occluder_mesh(d.mesh_count, 0);
    for (const oss::ObjectDisk& o : objects) occluder_mesh[o.mesh] = 1;
    for (uint32_t first = 0; first < d.mesh_count;) {
        const uint64_t base = meshes[first].triangle_first;
        uint32_t last = first;
        while (last < d.mesh_count &&
               (last == first || meshes[last].triangle_first + meshes[last].triangle_count - base <= kEdgeBatchTriangles))
            ++last;
        const uint64_t count = meshes[last - 1].triangle_first + meshes[last - 1].triangle_count - base;
        edge_flags.resize(count);
        edge_neighbours.resize(3 * count);
        batch.resize(last - first);
        std::iota(batch.begin(), batch.end(), first);
        std::for_each(std::execution::par, batch.begin(), batch.end(), [&](uint32_t m) {
            if (!occluder_mesh[m]) {
                const uint64_t at = meshes[m].triangle_first - base, n = meshes[m].triangle_count;
                std::fill_n(edge_flags.data() + at, n, uint8_t(0));
                std::fill_n(edge_neighbours.data() + 3 * at, 3 * n, UINT32_MAX);
                return;
            }
            k::sharedEdgeFlags(triangles.data() + 3 * meshes[m].triangle_first, meshes[m].triangle_count,
                               edge_flags.data() + (meshes[m].triangle_first - base),
                               edge_neighbours.data() + 3 * (meshes[m].triangle_first - base));
            k::markClosedMesh(triangles.data() + 3 * meshes[m].triangle_first, meshes[m].triangle_count,
                              file.allPositions().data() + meshes[m].vertex_first,
                              edge_flags.data() + (meshes[m].triangle_first - base));
        });
        k::copyToDevice(d.edge_flags.ptr() + base, edge_flags.data(), count);
        k::copyToDevice(d.edge_neighbours.ptr() + 3 * base, edge_neighbours.data(), 3 * count);
        first = last;
    }
    return d;
}

}  // namespace occ
