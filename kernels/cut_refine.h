// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "hzm.h"
#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

// The object hierarchy's cut on the device (PipelineOptions::hierarchy), refined top-down a
// level at a time: a level's nodes (in the frustum) are decided in parallel, the refined ones'
// children make the next level. Node ids are breadth-first (a level's ids all precede the next
// level's and a node's children are contiguous), so a level kept in ascending order gives its
// children in ascending order and the cut, gathered level by level, comes out ascending.
// Nothing here visits a node the refinement does not reach.

// A node as the cut reads it: its children and its own error (SceneNode::error).
struct CutNode {
    uint32_t first_child = 0, child_count = 0;  // child_count 0: a leaf
    float error = 0.0f;
};

// A node's state in the last refinement (kCutNone: not decided in it).
enum CutState : uint8_t { kCutNone = 0, kCutStop, kCutRefined, kCutHidden, kCutMerged };

// How a node decides (PipelineOptions' mode and LOD rule).
struct CutRule {
    enum Kind : uint32_t {
        kLeaves,    // mode full: refine to the leaves
        kOwnError,  // the budget rule: stop where the node's own error projects to at most tau
        kCost,      // the error rule: stop where the own error is within fine_share of what may be
                    // given up; cost[id] = the node drawn within tau (triangles + draw_cost)
    };
    uint32_t kind = kLeaves;
    float tau = 1.0f, pet = 1.0f, draw_cost = 0.0f, fine_share = 0.1f;
    float pixels_at_1 = 1.0f;  // pixels per world unit at view depth 1
    // kCost: the LOD error tables (device memory): per mesh the suffix maxima of its collapse
    // errors (map_first[mesh] into them and into maps), per item its world scale.
    DevicePtr<const float> lod_error, scale;
    DevicePtr<const uint64_t> map_first;
    DevicePtr<const uint32_t> maps;
};

// For j < count, the node id = ids[j] (in the frustum): state[id] = level_state[j] = kCutHidden
// where occluded[j] (occluded null: none hidden), else kCutStop or kCutRefined by `rule`, with
// share[j] its visible share (null: 1); with kCost, cost[id] = what it costs drawn (0 hidden or
// under the pixel threshold, infinite where its own error leaves its HLOD nothing).
void cutDecide(DevicePtr<const ObjectInfo> objects, DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids,
               uint32_t count, const Camera& camera, const CutRule& rule, DevicePtr<const uint8_t> occluded,
               DevicePtr<const float> share, DevicePtr<uint8_t> state, DevicePtr<double> cost,
               DevicePtr<uint8_t> level_state);

// The children of the listed nodes whose level_state[j] is kCutRefined, in list order, into out
// (room for every child of every listed node); returns how many. counts / offsets: scratch of
// count entries.
uint32_t cutChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> level_state,
                     uint32_t count, DevicePtr<uint32_t> counts, DevicePtr<uint64_t> offsets, DevicePtr<uint32_t> out);

// The leaves among the children of the listed nodes, in list order, into out (grown to fit);
// returns how many. With breadth-first ids and an ascending list they come out ascending.
// counts / offsets: scratch of count entries.
uint32_t cutLeafChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
                         DevicePtr<uint32_t> counts, DevicePtr<uint64_t> offsets, DeviceArray<uint32_t>& out);

// The error rule's coarsening, one level bottom-up (the level below already done): a refined
// node whose cost is at most its children's (those out of the frustum cost nothing) becomes
// kCutMerged; otherwise its cost becomes its children's.
void cutCoarsen(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
                DevicePtr<const uint8_t> in_frustum, DevicePtr<uint8_t> state, DevicePtr<double> cost);

// The coarsened cut, one level top-down (covered[id] set for the level by the one above; 0 for
// the root): flags[j] = 1 for a stopped or merged node no merged node lies above, else 0; the
// children of refined and merged nodes get covered = covered || merged.
void cutGather(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
               DevicePtr<const uint8_t> state, DevicePtr<uint8_t> covered, DevicePtr<uint8_t> flags);

}  // namespace occ::k
