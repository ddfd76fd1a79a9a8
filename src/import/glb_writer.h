// SPDX-License-Identifier: MIT
#pragma once

#include "scene/atomic_file.h"
#include "scene/scene.h"

#include <cstdint>
#include <array>
#include <map>
#include <memory>
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

// Writes glTF 2.0 one mesh at a time, so a scene larger than memory can be written: each
// mesh's bytes go to the binary buffer as it is added and only a small record per mesh and
// node is kept until finish() writes the JSON. Every mesh becomes one glTF mesh with one
// triangle primitive (positions + indices, 16-bit when they fit, a material carrying
// Mesh::color shared by equal colours); one scene whose roots finish() is given.
//
// `path` ending in .glb gives one binary glTF file (at most 4 GiB, the format's limit: the
// writer stops with an InputError naming the path as soon as the buffer would pass it);
// ending in .gltf gives PATH and its buffer beside it, PATH's stem + ".bin". The output depends
// only on what was added (same input, same bytes). Files are written to temporaries renamed
// over the final names by finish(), so a failure or a writer destroyed without finish()
// never leaves a partial file. Failures are InputError naming the path.
class GltfStreamWriter {
public:
    explicit GltfStreamWriter(const std::string& path);
    uint32_t addMesh(const Mesh& mesh);
    uint32_t addNode(const GltfNode& node);
    void finish(const std::vector<uint32_t>& roots);

private:
    struct MeshEntry {
        std::string name;
        uint64_t position_offset, index_offset;
        uint32_t vertices, indices, material;
        bool narrow;
        glm::vec3 lo, hi;
    };
    std::string path_, bin_name_;
    bool binary_;
    std::unique_ptr<AtomicFile> bin_;
    std::vector<MeshEntry> meshes_;
    std::vector<GltfNode> nodes_;
    std::map<std::array<float, 4>, uint32_t> material_of_color_;
    std::vector<std::array<float, 4>> materials_;
};

// Convenience over GltfStreamWriter: the given meshes and nodes, and one scene whose roots
// are `roots`.
void writeGlb(const std::string& path, const std::vector<Mesh>& meshes,
              const std::vector<GltfNode>& nodes, const std::vector<uint32_t>& roots);

// One root node per object, carrying the object's world matrix and its mesh. Object colours
// are taken from their meshes (glTF keeps colour on the primitive's material).
void writeSceneGlb(const std::string& path, const Scene& scene);

}  // namespace occ
