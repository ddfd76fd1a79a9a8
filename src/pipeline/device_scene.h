// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"
#include "occluder_gather.h"
#include "scene/oss_file.h"

#include <vector>

namespace occ {

// What the kernels read every frame, copied once from a mapped .oss into device memory, and
// the few per-object and per-mesh tables the host decides with, kept apart in host memory.
// The full-detail meshes are resident too, for the occluder raster (each instanced mesh once).
// Streaming reads the mapped file's positions and triangles on the host: only the parts a frame
// needs cross to the active arrays.
//
// The per-object arrays are per item: the objects, or with a hierarchy (upload's `hierarchy`)
// the file's nodes: a leaf is its object (mesh, world matrix, box, occluder data), an inner
// node its HLOD (world space: the identity matrix; compactness -1, so never an occluder). The
// visible set, the LODs, the streaming and the drawing then work on node ids unchanged.
struct DeviceScene {
    const OssFile* file = nullptr;
    uint32_t item_count = 0, mesh_count = 0, cos_count = 0;  // items: objects, or with nodes the nodes
    bool nodes = false;  // the items are the hierarchy's nodes

    // Host memory.
    std::vector<k::ObjectInfo> host_objects;      // per item
    std::vector<glm::mat4> host_world;            // per item, local -> world
    // Per item, with nodes: the node's children (child_count 0: a leaf), its error
    // (SceneNode::error) and the object it is (a leaf; UINT32_MAX for an HLOD). Without nodes: empty.
    struct NodeLinks {
        uint32_t first_child = 0, child_count = 0;
        float error = 0.0f;
        uint32_t object = UINT32_MAX;
    };
    std::vector<NodeLinks> host_nodes;
    std::vector<uint64_t> host_vertex_first;      // per mesh, into the file's positions and ecol
    std::vector<uint64_t> host_triangle_first;    // per mesh, in triangles
    std::vector<uint64_t> host_map_first;         // per mesh, into the file's maps

    // Device memory.
    k::DeviceArray<k::ObjectInfo> objects;  // per object
    k::DeviceArray<glm::mat4> world;        // per object, local -> world
    k::DeviceArray<uint32_t> cos;           // candidate occluder ids, most compact first
    k::DeviceArray<uint64_t> vertex_first;  // per mesh, into ecol and positions
    k::DeviceArray<uint64_t> triangle_first;  // per mesh, in triangles, into triangles
    k::DeviceArray<uint64_t> map_first;     // per mesh, into maps
    // The file's ECOL, MAP, POSITIONS and TRIANGLES sections: read in place from the mapping
    // where the device reads host memory (the CPU build: no second copy of the scene's largest
    // arrays), else copied into the *_copy arrays.
    k::DevicePtr<const int32_t> ecol;       // all meshes back to back
    k::DevicePtr<const uint32_t> maps;      // all meshes back to back, vertex_count + 1 each
    k::DevicePtr<const glm::vec3> positions;  // all meshes at full detail, object space
    k::DevicePtr<const uint32_t> triangles;   // all meshes at full detail, 3 mesh-local corners each
    k::DeviceArray<int32_t> ecol_copy;
    k::DeviceArray<uint32_t> maps_copy;
    k::DeviceArray<glm::vec3> positions_copy;
    k::DeviceArray<uint32_t> triangles_copy;
    // Per triangle, the edges it shares within its mesh (k::sharedEdgeFlags), all meshes back to
    // back like the file's triangles: mesh m's triangle t is at triangle_first[m] + t.
    k::DeviceArray<uint8_t> edge_flags;
    // Per triangle, 3 entries: the triangle of the same mesh across each shared edge (mesh-local
    // index), UINT32_MAX across the others (k::sharedEdgeFlags' neighbours).
    k::DeviceArray<uint32_t> edge_neighbours;

    // The full-detail meshes as gatherOccluders reads them.
    k::MeshGeometry meshes() const;
    // Triangles of mesh `mesh`'s LOD with `vertices` vertices (maps[vertices]; 0 for 0),
    // from the mapped file.
    uint32_t lodTriangles(uint32_t mesh, uint32_t vertices) const;

    // file must outlive the DeviceScene. Throws std::bad_alloc when the device has no room.
    // hierarchy: items are the file's nodes (the file must have them).
    static DeviceScene upload(const OssFile& file, bool hierarchy = false);
};

}  // namespace occ
