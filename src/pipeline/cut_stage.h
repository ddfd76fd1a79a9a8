// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "hzm.h"
#include "kernel_types.h"
#include "pipeline/device_scene.h"

#include <vector>

namespace occ {

struct PipelineOptions;

// The hierarchy's cut (prep --hierarchy on): each frame a cut of nodes refined from the root,
// level by level, a level's nodes tested against the frustum and, with occlusion, the HZM in one
// batch, each node deciding on its own whether it stops (PipelineOptions::hierarchy says how).
// With the error rule the fine cut is then coarsened bottom-up wherever a node costs no more than
// its children's cuts. Host-side: the decisions need the tree.
class CutStage {
public:
    // options must outlive the stage (the mode may change between frames). lod_error and scale:
    // the error rule's tables (per mesh the largest collapse error of each level, per item its
    // world scale), empty with the budget rule.
    CutStage(const DeviceScene& scene, const PipelineOptions& options, std::vector<float> lod_error,
             std::vector<float> scale);

    // The cut for `camera` (ascending node ids), from the items in_frustum flags (the frustum
    // stage's); hzm: also test against it (occlusion), or null.
    const std::vector<uint32_t>& refine(const k::Camera& camera, k::DevicePtr<const uint8_t> in_frustum,
                                        const k::HzmLevels* hzm);
    // With occlusion, the last cut and the nodes it found hidden (ascending): the frustum's share.
    const std::vector<uint32_t>& frustumShare() const { return hidden_ids_; }
    // With the error rule, the visible cut before coarsening (its leaves are occluders; HLODs are not).
    const std::vector<uint32_t>& fineCut() const { return fine_cut_; }
    uint64_t nodesTested() const { return nodes_tested_; }

private:
    enum : uint8_t { kCutNone = 0, kCutRefined, kCutStop, kCutHidden, kCutMerged };
    // The error rule: the world error item may show (tau at its nearest depth, / share), or
    // false when it is under the pixel threshold (not drawn).
    bool allowance(uint32_t item, const k::Camera& camera, float share, float& allowed) const;
    // A visible tested node's kCutStop or kCutRefined (its visible share: 1 without the
    // weighting); with the error rule also its cost drawn (cost_). Nodes in parallel.
    uint8_t decideNode(uint32_t id, const k::Camera& camera, float share);
    // The error rule: triangles of item's coarsest level that gives up at most `allowed` world units.
    uint32_t triangles(uint32_t item, float allowed) const;
    void coarsen(size_t depth);

    const DeviceScene& scene_;
    const PipelineOptions& options_;
    std::vector<float> lod_error_, scale_;
    // Level by level: host lists and flags, the level's ids on the device.
    std::vector<uint8_t> in_frustum_, hidden_;
    // Per item, valid for the items the last refinement tested (the root, and the in-frustum
    // children of refined nodes): its kCut* state; with the error rule its best cut's cost
    // (triangles + draw_cost per draw) and, while the cut is gathered, whether a merged node
    // lies above it.
    std::vector<uint8_t> state_, covered_;
    std::vector<double> cost_;
    std::vector<float> share_;
    std::vector<std::vector<uint32_t>> levels_;  // the tested nodes, by depth
    std::vector<uint32_t> index_;
    std::vector<uint32_t> cut_, fine_cut_, hidden_ids_;
    k::DeviceArray<uint32_t> level_device_;
    k::DeviceArray<uint8_t> occluded_device_;
    k::DeviceArray<float> share_device_;
    uint64_t nodes_tested_ = 0;
    float pixels_at_1_ = 0.0f;  // this refinement's pixels per world unit at depth 1
};

}  // namespace occ
