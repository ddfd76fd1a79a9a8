// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace occ {

// Axis-aligned box; an empty box has min > max so that any point extends it.
struct Bounds {
    glm::vec3 min{std::numeric_limits<float>::max()};
    glm::vec3 max{std::numeric_limits<float>::lowest()};

    bool empty() const { return min.x > max.x; }
    void extend(const glm::vec3& p) {
        min = glm::min(min, p);
        max = glm::max(max, p);
    }
    void extend(const Bounds& b) {
        if (!b.empty()) {
            extend(b.min);
            extend(b.max);
        }
    }
};

// Shared geometry in its own (local) space: one glTF triangle primitive, or one OBJ group /
// PLY / OFF / STL file. Many objects may reference the same mesh (glTF instancing), so
// per-mesh work (simplification) is done once per mesh, not once per object.
struct Mesh {
    std::string name;
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> indices;  // triangle list; every index < positions.size()
    glm::vec4 color{0.8f, 0.8f, 0.8f, 1.0f};  // base colour of the primitive's material, linear RGB (scene/colour.h)

    size_t triangleCount() const { return indices.size() / 3; }
};

// One renderable object: a mesh placed in the world. In glTF terms one (node, primitive) pair.
struct Object {
    uint32_t mesh = 0;          // index into Scene::meshes
    glm::mat4 world{1.0f};      // local -> world, node hierarchy already flattened
    glm::vec4 color{0.8f, 0.8f, 0.8f, 1.0f};
};

// What an importer left out, reported in summaries instead of silently dropped.
struct SkippedPrimitives {
    uint64_t points = 0;      // point primitives (glTF mode POINTS)
    uint64_t lines = 0;       // line primitives (LINES, LINE_LOOP, LINE_STRIP)
    uint64_t degenerate = 0;  // faces with fewer than three distinct vertices
    uint64_t unknown_materials = 0;  // OBJ materials no readable library defines: drawn in Mesh's grey
};

struct Scene {
    std::vector<Mesh> meshes;
    std::vector<Object> objects;
    SkippedPrimitives skipped;

    uint64_t triangleCount() const;  // over objects, counting instances
    uint64_t vertexCount() const;    // over objects, counting instances
    Bounds meshBounds(uint32_t mesh) const;  // local space
    Bounds objectBounds(uint32_t object) const;  // world space, exact over transformed vertices
    Bounds worldBounds() const;  // union of objectBounds, computed in parallel
};

}  // namespace occ
