// SPDX-License-Identifier: MIT
#pragma once

#include "cut_refine.h"
#include "device_memory.h"
#include "hzm.h"
#include "kernel_types.h"
#include "pipeline/device_scene.h"

#include <vector>

namespace occ {

struct PipelineOptions;

// The hierarchy's cut (prep --hierarchy on), on the device: each frame refined from the root a
// level at a time, a level's nodes tested against the frustum and, with occlusion, the HZM in
// one batch, each node deciding on its own whether it stops (PipelineOptions::hierarchy says
// how); with the error rule the fine cut is then coarsened bottom-up wherever a node costs no
// more than its children's cuts. Only the nodes the refinement reaches are touched: no pass
// over every item, and nothing but counts crosses the bus (kernels/cut_refine.h).
class CutStage {
public:
    // options must outlive the stage (the mode may change between frames). lod_error and scale:
    // the error rule's device tables (LodStage::lodErrors, itemScales), null with the budget rule.
    CutStage(const DeviceScene& scene, const PipelineOptions& options, k::DevicePtr<const float> lod_error,
             k::DevicePtr<const float> scale);

    // Refines the cut for `camera`: every node it reaches is tested against `frustum` and its
    // flag written to in_frustum (by id; the flags of other items stay as they were); hzm: also
    // test against it (occlusion), or null.
    void refine(const k::Camera& camera, const k::Frustum& frustum, k::DevicePtr<uint8_t> in_frustum,
                const k::HzmLevels* hzm);
    // The cut, ascending node ids, on the device.
    k::DevicePtr<const uint32_t> cut() const { return cut_.ptr(); }
    uint32_t cutCount() const { return cut_count_; }
    // With occlusion, the cut and the nodes it found hidden (ascending): the frustum's share.
    k::DevicePtr<const uint32_t> frustumShare() const { return share_.ptr(); }
    uint32_t frustumShareCount() const { return share_count_; }
    // With the error rule, the visible cut before coarsening (its leaves are occluders; HLODs
    // are not), ascending; 0 entries otherwise.
    k::DevicePtr<const uint32_t> fineCut() const { return fine_.ptr(); }
    uint32_t fineCutCount() const { return fine_count_; }
    uint64_t nodesTested() const { return nodes_tested_; }
    // The tau (pixels) the last refinement's cut is bounded by: PipelineOptions::tau, or a
    // finer one where the cut was small (PipelineOptions::finer_cut_items).
    float tau() const { return tau_; }
    // `ids` (ascending) and the leaves among their children, ascending, each once, into out:
    // occluder candidates. An HLOD is no occluder; its leaf children may be.
    uint32_t withLeafChildren(k::DevicePtr<const uint32_t> ids, uint32_t count, k::DeviceArray<uint32_t>& out);

private:
    k::CutRule rule(const k::Camera& camera, float tau) const;
    // false (and the cut left unfinished) where it would test more than `most` nodes or draw
    // more than `most_items` items (0: no bound); the items are counted as levels stop, so a
    // cut that outgrows the bound is given up where it does, not at its last level.
    bool refineAt(const k::Camera& camera, const k::Frustum& frustum, k::DevicePtr<uint8_t> in_frustum,
                  const k::HzmLevels* hzm, float tau, uint64_t most = 0, uint64_t most_items = 0);
    // Appends the level's entries whose flag is `value` to `list` (ascending as the levels are).
    void append(size_t depth, k::DevicePtr<const uint8_t> flags, uint8_t value, k::DeviceArray<uint32_t>& list,
                uint32_t& count);

    const DeviceScene& scene_;
    const PipelineOptions& options_;
    k::DevicePtr<const float> lod_error_, scale_;
    k::DeviceArray<k::CutNode> nodes_;  // per item
    // Per item, valid for the nodes the last refinement reached: its k::CutState, with the
    // error rule its best cut's cost and, while the cut is gathered, whether a merged node
    // lies above it.
    k::DeviceArray<uint8_t> state_, covered_;
    k::DeviceArray<double> cost_;
    // The refinement's levels: the nodes tested at each depth (in the frustum, ascending).
    std::vector<k::DeviceArray<uint32_t>> levels_;
    std::vector<uint32_t> level_counts_;
    k::DeviceArray<uint32_t> candidates_, child_counts_;
    k::DeviceArray<uint64_t> child_offsets_;
    k::DeviceArray<uint8_t> occluded_, level_state_, flags_;
    k::DeviceArray<float> share_of_level_;
    k::DeviceArray<uint32_t> cut_, fine_, hidden_, share_, leaf_children_;
    // The cut a finer refinement (PipelineOptions::finer_cut_items) started from, kept until it
    // finishes within its bound or is given up.
    k::DeviceArray<uint32_t> kept_cut_, kept_hidden_, kept_share_;
    uint32_t cut_count_ = 0, fine_count_ = 0, hidden_count_ = 0, share_count_ = 0;
    uint64_t nodes_tested_ = 0;
    float tau_ = 1.0f;
};

}  // namespace occ
