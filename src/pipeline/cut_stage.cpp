// SPDX-License-Identifier: MIT
#include "pipeline/cut_stage.h"

#include "frustum_cull.h"
#include "hzm_test.h"
#include "pipeline/pipeline.h"
#include "scan.h"

#include <algorithm>
#include <cmath>

namespace occ {

CutStage::CutStage(const DeviceScene& scene, const PipelineOptions& options, k::DevicePtr<const float> lod_error,
                   k::DevicePtr<const float> scale)
    : scene_(scene), options_(options), lod_error_(lod_error), scale_(scale) {
    const uint32_t n = std::max<uint32_t>(1, scene.item_count);
    std::vector<k::CutNode> nodes(n);
    for (uint32_t i = 0; i < scene.item_count; ++i) {
        const DeviceScene::NodeLinks& l = scene.host_nodes[i];
        nodes[i] = {l.first_child, l.child_count, l.error};
    }
    nodes_.resize(n);
    k::copyToDevice(nodes_.ptr(), nodes.data(), n);
    // Every array sized once for the worst case (the whole tree in view): no frame allocates.
    state_.resize(n);
    covered_.resize(n);
    k::deviceMemset(state_.ptr(), 0, n);
    k::deviceMemset(covered_.ptr(), 0, n);
    if (options.lod == LodRule::Error) cost_.resize(n);
    for (auto* a : {&candidates_, &child_counts_, &cut_, &fine_, &hidden_, &share_}) a->resize(n);
    child_offsets_.resize(n);
    for (auto* a : {&occluded_, &level_state_, &flags_}) a->resize(n);
    if (options.visibility_weighted) share_of_level_.resize(n);
}

k::CutRule CutStage::rule(const k::Camera& camera, float tau) const {
    k::CutRule r;
    const bool error = options_.lod == LodRule::Error && options_.mode != CullMode::Full;
    r.kind = options_.mode == CullMode::Full ? k::CutRule::kLeaves : error ? k::CutRule::kCost : k::CutRule::kOwnError;
    r.tau = tau;
    r.pet = options_.pet;
    r.draw_cost = options_.draw_cost;
    r.fine_share = PipelineOptions::kFineCutShare;
    r.pixels_at_1 = float(options_.height) / (2.0f * std::tan(0.5f * camera.fovy));
    if (error) {
        r.lod_error = lod_error_;
        r.scale = scale_;
        r.map_first = scene_.map_first.ptr();
        r.maps = scene_.maps;
    }
    return r;
}

void CutStage::append(size_t depth, k::DevicePtr<const uint8_t> flags, uint8_t value, k::DeviceArray<uint32_t>& list,
                      uint32_t& count) {
    count += k::compactSelected(levels_[depth].ptr(), flags, level_counts_[depth], value, list.ptr() + count);
}

void CutStage::refine(const k::Camera& camera, const k::Frustum& frustum, k::DevicePtr<uint8_t> in_frustum,
                      const k::HzmLevels* hzm) {
    tau_ = options_.tau;
    refineAt(camera, frustum, in_frustum, hzm, tau_);
    // The budget rule may draw finer: again at half the tau while the cut draws at most
    // finer_cut_items (and its refinement tests at most kFinerCutNodesPerItem times as many
    // nodes); the first that would not is given up, at the level where it outgrows either, and
    // the cut before it taken again.
    // A finer cut reaches every node the coarser one did, so every in_frustum flag it needs is
    // written again. Each frame decides from its own camera and HZM alone: any rank that
    // refines a frame gets the same cut.
    const uint64_t items = options_.finer_cut_items, most = items * PipelineOptions::kFinerCutNodesPerItem;
    if (options_.mode == CullMode::Full || options_.lod != LodRule::Budget || items == 0) return;
    if (kept_cut_.size() < cut_.size())
        for (auto* a : {&kept_cut_, &kept_hidden_, &kept_share_}) a->resize(cut_.size());
    for (int step = 0; step < PipelineOptions::kFinerCutSteps && cut_count_ <= items && nodes_tested_ <= most; ++step) {
        // The finer refinement writes into the spare lists; the cut so far waits in kept_*.
        std::swap(cut_, kept_cut_), std::swap(hidden_, kept_hidden_), std::swap(share_, kept_share_);
        const uint32_t counts[3] = {cut_count_, hidden_count_, share_count_};
        if (!refineAt(camera, frustum, in_frustum, hzm, 0.5f * tau_, most, items) || cut_count_ > items) {
            std::swap(cut_, kept_cut_), std::swap(hidden_, kept_hidden_), std::swap(share_, kept_share_);
            cut_count_ = counts[0], hidden_count_ = counts[1], share_count_ = counts[2];
            break;
        }
        tau_ *= 0.5f;
    }
}

bool CutStage::refineAt(const k::Camera& camera, const k::Frustum& frustum, k::DevicePtr<uint8_t> in_frustum,
                        const k::HzmLevels* hzm, float tau, uint64_t most, uint64_t most_items) {
    const bool occlusion = hzm != nullptr;
    const bool weighted = occlusion && options_.visibility_weighted;
    const k::CutRule r = rule(camera, tau);
    const bool coarsening = r.kind == k::CutRule::kCost;
    cut_count_ = fine_count_ = hidden_count_ = share_count_ = 0;
    nodes_tested_ = 0;
    level_counts_.clear();
    // Top-down, a level at a time: the level's candidates (the root, then the refined nodes'
    // children) against the frustum, those in it against the HZM in one batch, each deciding
    // on its own; the refined ones' children are the next level's candidates.
    uint32_t candidates = scene_.item_count > 0 ? 1 : 0;
    if (candidates) k::deviceMemset(candidates_.ptr(), 0, sizeof(uint32_t));  // the root, id 0
    for (size_t depth = 0; candidates > 0; ++depth) {
        if (most > 0 && nodes_tested_ + candidates > most) return false;
        if (levels_.size() <= depth) levels_.emplace_back();
        k::DeviceArray<uint32_t>& level = levels_[depth];
        level.growTo(candidates);
        const uint32_t count =
            k::frustumCullIds(scene_.objects.ptr(), candidates_.ptr(), candidates, frustum, in_frustum, level.ptr());
        level_counts_.push_back(count);
        nodes_tested_ += count;
        if (occlusion) {
            k::hzmTest(scene_.objects.ptr(), level.ptr(), count, camera, *hzm, occluded_.ptr());
            if (weighted)
                k::hzmVisibleShare(scene_.objects.ptr(), level.ptr(), count, camera, *hzm, share_of_level_.ptr());
        }
        k::cutDecide(scene_.objects.ptr(), nodes_.ptr(), level.ptr(), count, camera, r,
                     occlusion ? k::DevicePtr<const uint8_t>(occluded_.ptr()) : nullptr,
                     weighted ? k::DevicePtr<const float>(share_of_level_.ptr()) : nullptr, state_.ptr(), cost_.ptr(),
                     level_state_.ptr());
        append(depth, level_state_.ptr(), k::kCutStop, coarsening ? fine_ : cut_, coarsening ? fine_count_ : cut_count_);
        if (occlusion) append(depth, level_state_.ptr(), k::kCutHidden, hidden_, hidden_count_);
        if (most_items > 0 && cut_count_ > most_items) return false;
        candidates = k::cutChildren(nodes_.ptr(), level.ptr(), level_state_.ptr(), count, child_counts_.ptr(),
                                    child_offsets_.ptr(), candidates_.ptr());
    }
    if (coarsening) {
        // Bottom-up: a node replaces its children's cuts where it is within tau and costs no
        // more; then top-down, the stopped and merged nodes no merged node lies above.
        for (size_t d = level_counts_.size(); d-- > 0;)
            k::cutCoarsen(nodes_.ptr(), levels_[d].ptr(), level_counts_[d], in_frustum, state_.ptr(), cost_.ptr());
        if (!level_counts_.empty()) k::deviceMemset(covered_.ptr(), 0, 1);  // nothing above the root
        for (size_t d = 0; d < level_counts_.size(); ++d) {
            k::cutGather(nodes_.ptr(), levels_[d].ptr(), level_counts_[d], state_.ptr(), covered_.ptr(), flags_.ptr());
            append(d, flags_.ptr(), 1, cut_, cut_count_);
        }
    }
    if (occlusion) share_count_ = k::unionAscending(cut_.ptr(), cut_count_, hidden_.ptr(), hidden_count_, share_.ptr());
    return true;
}

uint32_t CutStage::withLeafChildren(k::DevicePtr<const uint32_t> ids, uint32_t count, k::DeviceArray<uint32_t>& out) {
    const uint32_t leaves =
        k::cutLeafChildren(nodes_.ptr(), ids, count, child_counts_.ptr(), child_offsets_.ptr(), leaf_children_);
    out.growTo(std::max<uint32_t>(1, count + leaves));
    return k::unionAscending(ids, count, leaf_children_.ptr(), leaves, out.ptr());
}

}  // namespace occ
