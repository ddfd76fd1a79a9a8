// SPDX-License-Identifier: MIT
#pragma once

// What both glTF readers share: the whole-file importer (tinygltf, gltf_import.cpp) and the
// streaming one prep uses for large files (gltf_stream.cpp). Constants are the spec's.

#include "scene/errors.h"

#include <glm/glm.hpp>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace occ::gltf {

inline constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123,
                     kUnsignedInt = 5125, kFloat = 5126;
inline constexpr int kPoints = 0, kLines = 1, kLineLoop = 2, kLineStrip = 3, kTriangles = 4, kTriangleStrip = 5,
                     kTriangleFan = 6;
// The binary container (GLB): its magic and its two chunk types.
inline constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
inline constexpr uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
inline constexpr uint32_t kGlbChunkBin = 0x004E4942;   // "BIN\0"

// The extensions the importers read (the geometry ones) or may ignore (they change how a
// model looks, not its triangles). Any other required extension is refused by name.
bool isSupportedExtension(const std::string& name);

// Bytes per component of a glTF component type (0 for an unknown one).
size_t componentSize(int type);

// One unsigned integer component (an index).
uint32_t indexValue(const unsigned char* p, int type);

// One component as a float: normalized integers as the spec maps them to [-1, 1] or [0, 1],
// others by value (KHR_mesh_quantization puts the dequantization into the node transform).
float componentValue(const unsigned char* p, int type, bool normalized);

// A primitive's indices of `mode` (triangles, strip, fan) as a triangle list, one winding;
// InputError naming `path` for a list that is not a multiple of 3 or another mode.
void triangulatePrimitive(const std::string& path, int mode, const std::vector<uint32_t>& raw,
                          std::vector<uint32_t>& out);

// A node's local transform as glTF defines it: its matrix (16 column-major values) when it has
// one, else translation * rotation (x, y, z, w) * scale, composed in double; null arguments
// take their defaults. InputError naming `path` and /nodes/`node` for a non-finite result.
glm::mat4 nodeMatrix(const std::string& path, size_t node, const double* matrix, const double* translation,
                     const double* rotation, const double* scale);

// The nodes a reader starts its walk from, as the spec picks them: scene `option` when it is
// >= 0 (InputError naming `path` when the file has no such scene), else the file's default
// scene (`default_scene` >= 0), else scene 0; a file without scenes draws every node that is
// nobody's child. scene_nodes(s) gives scene s's node list; for_each_child(f) calls f(child) for
// every child index the file lists. InputError for an empty scene.
template <class SceneNodes, class ForEachChild>
std::vector<int64_t> sceneRoots(const std::string& path, int64_t option, int64_t default_scene, size_t scene_count,
                                size_t node_count, SceneNodes scene_nodes, ForEachChild for_each_child) {
    std::vector<int64_t> roots;
    if (option >= 0 && size_t(option) >= std::max<size_t>(1, scene_count))
        throw InputError(path, "/scenes: scene " + std::to_string(option) + " does not exist (" +
                                   std::to_string(scene_count) + " scenes)");
    if (scene_count > 0) {
        const int64_t scene = option >= 0 ? option : default_scene >= 0 ? default_scene : 0;
        if (scene >= int64_t(scene_count))
            throw InputError(path, "/scene: index " + std::to_string(scene) + " out of range (" +
                                       std::to_string(scene_count) + " scenes)");
        for (const auto node : scene_nodes(size_t(scene))) roots.push_back(int64_t(node));
    } else {
        std::vector<bool> is_child(node_count, false);
        for_each_child([&](int64_t c) {
            if (c >= 0 && uint64_t(c) < node_count) is_child[size_t(c)] = true;
        });
        for (size_t i = 0; i < node_count; ++i)
            if (!is_child[i]) roots.push_back(int64_t(i));
    }
    if (roots.empty()) throw InputError(path, "/scenes: empty scene, it has no nodes (no triangles)");
    return roots;
}

// The node forest under `roots` walked depth first without recursion (a broken file's chains
// can be deeper than the call stack): visit(node, world) for each node as it is entered, world
// = its parent's world x local(node). child_count(node) and child_at(node, i) give a node's
// children. InputError naming `path` and the JSON pointer for a node index out of range, a cycle
// (which glTF forbids) or a node with more than one parent.
template <class ChildCount, class ChildAt, class Local, class Visit>
void walkNodeForest(const std::string& path, size_t node_count, const std::vector<int64_t>& roots,
                    ChildCount child_count, ChildAt child_at, Local local, Visit visit) {
    // `where` makes the JSON pointer only for an error: a 10^6-node file checks 10^6 children.
    const auto check = [&](int64_t node, const auto& where) {
        if (node < 0 || uint64_t(node) >= node_count)
            throw InputError(path, where() + ": node index " + std::to_string(node) + " out of range (" +
                                       std::to_string(node_count) + " nodes)");
    };
    enum : uint8_t { Unvisited, OnPath, Done };
    std::vector<uint8_t> state(node_count, Unvisited);
    struct Frame {
        int64_t node;
        glm::mat4 world;
        size_t next_child;
    };
    std::vector<Frame> stack;
    const auto enter = [&](int64_t node, const glm::mat4& world) {
        state[size_t(node)] = OnPath;
        stack.push_back({node, world, 0});
        visit(node, world);
    };
    for (size_t i = 0; i < roots.size(); ++i) {
        check(roots[i], [&] { return "/scenes/nodes/" + std::to_string(i); });
        if (state[size_t(roots[i])] == Done)
            throw InputError(path, "/nodes/" + std::to_string(roots[i]) + ": node has more than one parent");
        enter(roots[i], local(roots[i]));
        while (!stack.empty()) {
            Frame& top = stack.back();
            if (top.next_child == size_t(child_count(top.node))) {
                state[size_t(top.node)] = Done;
                stack.pop_back();
                continue;
            }
            const size_t ci = top.next_child++;
            const int64_t child = int64_t(child_at(top.node, ci));
            const auto at = [&] { return "/nodes/" + std::to_string(top.node) + "/children/" + std::to_string(ci); };
            check(child, at);
            if (state[size_t(child)] == OnPath)
                throw InputError(path, at() + ": node graph has a cycle through node " + std::to_string(child));
            if (state[size_t(child)] == Done)
                throw InputError(path, at() + ": node " + std::to_string(child) + " has more than one parent");
            const glm::mat4 world = top.world * local(child);  // before enter() moves the stack
            enter(child, world);
        }
    }
}

}  // namespace occ::gltf
