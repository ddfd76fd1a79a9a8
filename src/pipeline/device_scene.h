// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_memory.h"
#include "kernel_types.h"
#include "scene/oss_file.h"

namespace occ {

// What the kernels read every frame, uploaded once from a mapped .oss into kernel memory
// (device memory under CUDA). Mesh positions and triangles stay in the mapped file, on the
// host: streaming moves only the parts of them a frame needs.
struct DeviceScene {
    const OssFile* file = nullptr;
    uint32_t object_count = 0, mesh_count = 0;
    k::KernelArray<k::ObjectInfo> objects;  // per object
    k::KernelArray<glm::mat4> world;        // per object, local -> world
    k::KernelArray<uint32_t> cos;           // candidate occluder ids, most compact first
    k::KernelArray<uint64_t> vertex_first;  // per mesh, into ecol (and the file's positions)
    k::KernelArray<uint64_t> triangle_first;  // per mesh, in triangles, into the file's triangles
    k::KernelArray<uint64_t> map_first;     // per mesh, into maps
    k::KernelArray<int32_t> ecol;           // all meshes back to back
    k::KernelArray<uint32_t> maps;          // all meshes back to back, vertex_count + 1 each
    // Per triangle, the edges it shares within its mesh (k::sharedEdgeFlags), all meshes back to
    // back like the file's triangles: mesh m's triangle t is at triangle_first[m] + t.
    k::KernelArray<uint8_t> edge_flags;
    // Per triangle, 3 entries: the triangle of the same mesh across each shared edge (mesh-local
    // index), UINT32_MAX across the others (k::sharedEdgeFlags' neighbours).
    k::KernelArray<uint32_t> edge_neighbours;

    // file must outlive the DeviceScene.
    static DeviceScene upload(const OssFile& file);
};

}  // namespace occ
