// SPDX-License-Identifier: MIT
#pragma once

// The object hierarchy and its HLODs (issue 16; Erikson et al. 2001's hierarchical levels of
// detail, as Govindaraju et al. 2003 and Charalambos 2006 draw them): a spatial tree over the
// objects with at most `fanout` children per node, and for every inner node a progressive mesh
// of its subtree's geometry, merged and simplified, that can be drawn instead of all of it.

#include "kernel_types.h"
#include "prep/collapse_sequence.h"
#include "scene/oss_file.h"

#include <atomic>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace occ {

// Nodes in breadth-first order (SceneNode): nodes[0] is the root, a node's children are
// contiguous and come after it, every level after the one above. One leaf per object; the
// inner nodes' meshes are set by buildHlods.
struct ObjectHierarchy {
    std::vector<SceneNode> nodes;
    uint32_t levels = 0;  // depth of the deepest leaf + 1
};

// Top-down: a node of more than `fanout` objects is cut into `fanout` groups by k-d splits across
// the widest axis of the box centres, each split in the widest gap between centres among the
// middle third of the objects around the balanced position (so groups hold between a third and
// two thirds of the objects a balanced split would give each side); a node of at most `fanout`
// objects gets one leaf child each, ordered by triangles, then centre. Splits and leaf order
// depend on the boxes, not on object ids (but for exact ties), so that copies of an arrangement
// get copies of a subtree (findRepeatedSubtrees). Deterministic. boxes and triangles have one
// entry per object. Throws std::invalid_argument for fanout < 2, no objects, or sizes that
// differ.
ObjectHierarchy buildObjectHierarchy(std::span<const k::Aabb> boxes, std::span<const uint64_t> triangles,
                                     uint32_t fanout);

// Subtrees that repeat (issue 34, item 3): node n repeats node r when their subtrees are the same
// tree of the same object classes (object_class: equal for objects of the same mesh in the same
// colour, < 2^32) and each of n's children sits where r's does relative to the first
// leaf (the linear parts' entries within 1e-5; translations within 1e-5 of the diagonal plus
// 1e-6 of the largest coordinate, about what float coordinates can tell apart), so that n's
// geometry is r's moved by the motion (n's first leaf's world) x (r's)^-1, a similarity without
// mirror (rotation, translation, uniform scale). Nodes are matched in `order`, so a
// representative comes before its repeats in it, and buildHlods, which builds in that order,
// builds it first. An engine tiled a thousand times gets one HLOD per distinct subtree instead
// of one per node.
struct SubtreeRepeats {
    struct Repeat {
        uint32_t of = 0;        // the representative
        float scale = 1.0f;     // the motion's scale
        float slack = 0.0f;     // the translation slack the match allowed
        glm::mat4 motion{1.0f};
    };
    std::vector<uint32_t> index;  // per node: its entry in `list`, UINT32_MAX where it repeats nothing
    std::vector<Repeat> list;     // one per repeated inner node (4 bytes per node plus this: prep's memory)
    const Repeat* find(uint32_t n) const { return index[n] == UINT32_MAX ? nullptr : &list[index[n]]; }
    uint32_t of(uint32_t n) const { return index[n] == UINT32_MAX ? n : list[index[n]].of; }
};
// `order`: the inner nodes, children before parents, in the order their HLODs are built (the
// first of a class in it is its representative); empty: from the last node to the first.
SubtreeRepeats findRepeatedSubtrees(std::span<const SceneNode> nodes, std::span<const uint32_t> object_class,
                                    std::span<const glm::mat4> object_world, std::span<const uint32_t> order = {});

// The level of detail with k vertices of a progressive mesh (the first k positions, the first
// map[k] triangles with each corner walked through ecol until it is below k, degenerate ones
// left out), appended to positions / triangles with positions transformed by `world`.
void appendLevel(std::span<const glm::vec3> positions, std::span<const int32_t> ecol,
                 std::span<const uint32_t> triangles, std::span<const uint32_t> map, uint32_t k,
                 const glm::mat4& world, std::vector<glm::vec3>& out_positions, std::vector<uint32_t>& out_triangles);

// The smallest k >= q whose level has at least `want` triangles (the full detail when it has
// fewer): map is non-decreasing.
uint32_t levelWithTriangles(std::span<const uint32_t> map, uint32_t q, uint64_t want);

// The levels of a node's children that its merged input takes (issue 34, item 2): the least
// error E whose levels fit `budget` triangles together, each child at its coarsest level within
// E, so that the node's error (the largest of its children's) is as small as the budget allows.
// Equal shares of triangles, as before, left a node's error to its hardest child. What E leaves
// of the budget is not spent: filling it (the children with the largest errors a level finer
// while it fits) made the HLODs above larger and their errors larger too (the 10^6 plant's
// orbit drew 8 942 items instead of 4 857). Child c's candidate levels are k in
// [q[c], errors[c].size() - 1], with errors[c][k] (non-increasing in k) and maps[c][k]
// triangles. Where no choice fits, every child is at its coarsest.
struct ChildLevelChoice {
    std::vector<uint32_t> levels;
    float error = 0.0f;      // the largest of the chosen levels' errors
    uint64_t triangles = 0;  // of the chosen levels together
};
ChildLevelChoice chooseChildLevels(std::span<const std::span<const float>> errors,
                                   std::span<const std::span<const uint32_t>> maps, std::span<const uint32_t> q,
                                   uint64_t budget);

struct HlodOptions {
    // What a node's merged input aims at: each of its c children contributes its level with
    // about 2 x node_triangles / c triangles (objects at their own LOD, inner children at their
    // HLOD), so an HLOD starts from about twice node_triangles and is simplified from there.
    uint32_t node_triangles = 2048;
    // ... and at most 1 / reduction of the child's subtree's full-detail triangles, so that the
    // HLODs of a level hold about 1 / reduction of the level below (all of them about
    // 1 / (reduction - 1) of the scene), however small the objects are.
    uint32_t reduction = 4;
    // The children's shares are a budget, not a quota: a child may take up to child_cap times
    // its share where its siblings need less for the same error (chooseChildLevels).
    uint32_t child_cap = 4;
    // Continue each HLOD's edge collapses with vertex clustering (cluster_collapse.h), so that
    // the objects' floors vanish and neighbours join; off: edge collapses only.
    bool cluster = true;
    // Clusters move onto placed vertices (ClusterOptions::place); off: onto a member.
    bool place = true;
    // Edge collapses place too (ClusterOptions::place_edges).
    bool place_edges = false;
    // Clusters do not mix colours (ClusterOptions::colour_borders): on the 10^5 plant's orbit
    // mixed clusters changed 1.24 % of the pixels perceptibly, kept borders 0.58 %.
    bool colour_borders = true;
    // An HLOD is simplified from its children's levels up to their share (objects at full
    // detail where it fits) and only its levels up to 1 / reduction of its subtree are kept;
    // off: from levels already cut to 1 / reduction, whose errors (a box at a quarter of its
    // triangles is a tetrahedron) every HLOD above inherits.
    bool fine_input = true;
    // Each HLOD vertex carries the normal of the full detail it stands for (hlodVertexNormals),
    // which the display lights it by; off: HLODs are lit by their faces' normals.
    bool normals = true;
    // Subtrees that repeat share one HLOD (findRepeatedSubtrees); off: every inner node its own.
    bool share_repeats = true;
    unsigned threads = 0;  // 0: all hardware threads
};

// One progressive mesh per inner node (leaves get none: their objects' meshes are theirs),
// world space, built bottom-up, level by level from the deepest, in parallel within a level
// (options.threads) and handed to add_mesh in node order within a level, as each batch is done;
// add_mesh returns the mesh index, which goes to the node's `mesh`. A subtree that repeats an
// earlier one (findRepeatedSubtrees, options.share_repeats) is not built again: it takes its
// representative's mesh, placed by the motion (SceneNode::world), with the error scaled and the
// match's slack added. A node's parent merges its children's levels that chooseChildLevels
// picks: only each child's progressive mesh up to child_cap times its share is kept for it (and
// the progressive meshes of representatives whose repeats a parent still has to merge), so
// memory stays a batch of HLODs plus small meshes per node of the level below. The objects' meshes
// come from `file`, whose objects the hierarchy was built for. Each HLOD vertex carries the colour
// of what it stands for (ProgressiveMesh::colours): its object's colour times the vertex's own. `done` (if given) counts inner
// nodes built or shared.
struct HlodProgress {
    std::atomic<uint64_t> done{0};
    uint64_t total = 0;
};
void buildHlods(const OssFile& file, ObjectHierarchy& hierarchy, const HlodOptions& options,
                const std::function<uint32_t(ProgressiveMesh&&)>& add_mesh, HlodProgress* progress = nullptr);

// The hierarchy of a prepared scene's objects (their boxes and triangle counts).
ObjectHierarchy buildObjectHierarchy(const OssFile& file, uint32_t fanout);

// Writes `file`'s scene with a hierarchy and its HLODs to `path` (atomically, OssStreamWriter):
// the same meshes, then one HLOD mesh per inner node, the same objects and COS, and the nodes.
// Returns the hierarchy written; counts (if given) gets what OssFile::hlodCounts would say of
// the written file.
ObjectHierarchy writeWithHierarchy(const OssFile& file, const std::string& path, uint32_t fanout,
                                   const HlodOptions& options, HlodProgress* progress = nullptr,
                                   OssFile::HlodCounts* counts = nullptr);

}  // namespace occ
