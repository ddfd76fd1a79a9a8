// SPDX-License-Identifier: MIT
#pragma once

// The object hierarchy and its HLODs (issue 16; Erikson et al. 2001's hierarchical levels of
// detail, as Govindaraju et al. 2003 and Charalambos 2006 draw them): a spatial tree over the
// objects with at most `fanout` children per node, and for every inner node a progressive mesh
// of its subtree's geometry, merged and simplified, that can be drawn instead of all of it.

#include "kernel_types.h"
#include "prep/progressive_mesh.h"
#include "scene/oss_file.h"

#include <cstdint>
#include <span>
#include <vector>

namespace occ {

struct HierarchyNode {
    k::Aabb box{};                          // world space, the union of its subtree's boxes
    uint32_t first_child = 0, child_count = 0;  // inner nodes: children nodes[first_child ..]
    uint32_t object = UINT32_MAX;           // leaves: the object (child_count = 0)
    uint32_t depth = 0;                     // 0 at the root
    uint64_t triangles = 0;                 // full-detail triangles of the subtree's objects
};

// Nodes in breadth-first order: nodes[0] is the root, a node's children are contiguous and come
// after it, every level after the one above. One leaf per object.
struct ObjectHierarchy {
    std::vector<HierarchyNode> nodes;
    uint32_t levels = 0;  // depth of the deepest leaf + 1
};

// Top-down: a node of more than `fanout` objects is cut into `fanout` groups of about equal
// object count by k-d splits across the widest axis of the box centres (ties by object id);
// a node of at most `fanout` objects gets one leaf child each. Deterministic. boxes and
// triangles have one entry per object. Throws std::invalid_argument for fanout < 2, no
// objects, or sizes that differ.
ObjectHierarchy buildObjectHierarchy(std::span<const k::Aabb> boxes, std::span<const uint64_t> triangles,
                                     uint32_t fanout);

// The level of detail with k vertices of a progressive mesh (the first k positions, the first
// map[k] triangles with each corner walked through ecol until it is below k, degenerate ones
// left out), appended to positions / triangles with positions transformed by `world`.
void appendLevel(std::span<const glm::vec3> positions, std::span<const int32_t> ecol,
                 std::span<const uint32_t> triangles, std::span<const uint32_t> map, uint32_t k,
                 const glm::mat4& world, std::vector<glm::vec3>& out_positions, std::vector<uint32_t>& out_triangles);

// The smallest k >= q whose level has at least `want` triangles (the full detail when it has
// fewer): map is non-decreasing.
uint32_t levelWithTriangles(std::span<const uint32_t> map, uint32_t q, uint64_t want);

struct HlodOptions {
    // What a node's merged input aims at: each of its c children contributes its level with
    // about 2 x node_triangles / c triangles (objects at their own LOD, inner children at their
    // HLOD), so an HLOD starts from about twice node_triangles and is simplified from there.
    uint32_t node_triangles = 2048;
};

// One progressive mesh per inner node (in node order; leaves get none: their objects' meshes
// are theirs), world space, built bottom-up. objects' meshes come from `file`, whose object
// count the hierarchy was built for.
std::vector<ProgressiveMesh> buildHlods(const OssFile& file, const ObjectHierarchy& hierarchy,
                                        const HlodOptions& options);

}  // namespace occ
