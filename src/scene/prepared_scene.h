// SPDX-License-Identifier: MIT
#pragma once

#include "scene/progressive_mesh.h"
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

// A node of the object hierarchy (issue 16; Erikson et al. 2001's HLODs): a leaf stands for one
// object, an inner node for its subtree, drawn at once through its HLOD, a progressive mesh in
// world space of the subtree's merged and simplified geometry. Nodes are in breadth-first
// order: nodes[0] is the root, a node's children are contiguous and come after it, every level
// after the one above.
struct SceneNode {
    Bounds box;                              // world space, the union of its subtree's boxes
    uint32_t first_child = 0, child_count = 0;  // inner nodes: children nodes[first_child ..]
    uint32_t object = UINT32_MAX;            // leaves (child_count = 0): the object
    uint32_t mesh = UINT32_MAX;              // inner nodes: the HLOD, an index into the meshes
    uint32_t depth = 0;                      // 0 at the root
    uint64_t triangles = 0;                  // full-detail triangles of the subtree's objects
    // Inner nodes: how far the HLOD at full detail is from the subtree at full detail, world
    // units: the largest, over the children, of the error of the level merged (the largest
    // collapse error it undid, scaled by the object's world matrix) plus the child's own. The
    // collapse errors are the collapser's distance estimates, not bounds. Leaves: 0.
    float error = 0.0f;
    // Inner nodes: where the HLOD mesh is placed. The identity for an HLOD built for the node
    // (its positions are world space); a subtree that repeats an earlier one (the same meshes
    // under the same relative transforms, moved rigidly) shares that one's HLOD, placed here by
    // the motion. Leaves: the identity.
    glm::mat4 world{1.0f};
};

// The content of a .oss file.
struct PreparedScene {
    std::vector<ProgressiveMesh> meshes;  // one per unique input mesh (instances share)
    std::vector<ObjectRecord> objects;
    std::vector<uint32_t> cos;            // candidate occluder set: ids with compactness >= ct,
                                          // sorted by compactness, highest first
    float ct = 0.55f;                     // compactness threshold CT used to build cos
    std::vector<SceneNode> nodes;         // the hierarchy; empty: none (the HLODs are meshes
                                          // after the objects' own)
};

}  // namespace occ
