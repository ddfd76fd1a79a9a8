// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <cstdint>
#include <string>
#include <vector>

namespace occ {

// A glTF node as the writer sees it: an optional mesh (index into the mesh list), a local
// matrix, and children (indices into the node list). The node graph must be a forest.
struct GltfNode {
    int32_t mesh = -1;
    glm::mat4 matrix{1.0f};
    std::vector<uint32_t> children;
};

// Writes a binary glTF 2.0 file (.glb): one glTF mesh with one triangle primitive per entry of
// meshes (positions + indices, a material carrying Mesh::color), the given nodes and one scene
// whose roots are `roots`. The output depends only on the arguments (same input, same bytes).
// The file is written to a temporary name next to `path` and renamed over it, so a failure
// never leaves a partial file; on failure throws InputError naming `path`.
void writeGlb(const std::string& path, const std::vector<Mesh>& meshes,
              const std::vector<GltfNode>& nodes, const std::vector<uint32_t>& roots);

// Convenience: one root node per object, carrying the object's world matrix and its mesh.
// Object colours are taken from their meshes (glTF keeps colour on the primitive's material).
void writeSceneGlb(const std::string& path, const Scene& scene);

}  // namespace occ
