// SPDX-License-Identifier: MIT
#pragma once

#include "prep/progressive_mesh.h"
#include "scene/scene.h"

#include <cstdint>
#include <vector>

namespace occ {

// Oriented bounding box: center + orthonormal axes (right-handed) + half extents along them.
struct OrientedBox {
    glm::vec3 center{0.0f};
    glm::vec3 axis[3]{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    glm::vec3 half_extent{0.0f};
};

// What the runtime needs per object, in world space (Peng 2014 §5.1 for the occluder part).
struct ObjectRecord {
    uint32_t mesh = 0;  // index into PreparedScene::meshes
    glm::vec4 color{0.8f, 0.8f, 0.8f, 1.0f};
    glm::mat4 world{1.0f};
    Bounds aabb;                          // exact, over the transformed full-detail vertices
    OrientedBox oobb;                     // tight oriented box
    glm::vec3 occluder_normal{0, 0, 1};   // normal of the OOBB's largest face (Eq. 3's N)
    float compactness = 0.0f;             // Eq. 2, in [0, 1]
};

// The content of a .oss file.
struct PreparedScene {
    std::vector<ProgressiveMesh> meshes;  // one per unique input mesh (instances share)
    std::vector<ObjectRecord> objects;
    std::vector<uint32_t> cos;            // candidate occluder set: ids with compactness >= ct,
                                          // sorted by compactness, highest first
    float ct = 0.55f;                     // compactness threshold CT used to build cos
};

}  // namespace occ
