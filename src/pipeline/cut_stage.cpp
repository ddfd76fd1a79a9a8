// SPDX-License-Identifier: MIT
#include "pipeline/cut_stage.h"

#include "box_projection.h"
#include "hzm_test.h"
#include "lod_select.h"
#include "pipeline/pipeline.h"

#include <algorithm>
#include <cmath>
#include <execution>
#include <numeric>

namespace occ {

CutStage::CutStage(const DeviceScene& scene, const PipelineOptions& options, std::vector<float> lod_error,
                   std::vector<float> scale)
    : scene_(scene), options_(options), lod_error_(std::move(lod_error)), scale_(std::move(scale)) {}

uint32_t CutStage::triangles(uint32_t item, float allowed) const {
    const k::ObjectInfo& o = scene_.host_objects[item];
    if (o.vertex_count == 0) return 0;
    // The level k::lodSelectByError will choose.
    const uint32_t k = k::levelWithinError(lod_error_.data() + scene_.host_map_first[o.mesh], o.q, o.vertex_count,
                                           allowed / std::max(scale_[item], 1e-30f));
    return scene_.file->allMaps()[scene_.host_map_first[o.mesh] + k];
}

bool CutStage::allowance(uint32_t item, const k::Camera& camera, float share, float& allowed) const {
    const k::Projection pr = k::projectBox(scene_.host_objects[item], camera);
    if (pr.area < options_.pet) return false;
    allowed = options_.tau * pr.depth / (pixels_at_1_ * std::max(share, 1e-30f));
    return true;
}

uint8_t CutStage::decideNode(uint32_t id, const k::Camera& camera, float share) {
    const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
    if (options_.lod != LodRule::Error || options_.mode == CullMode::Full) {
        if (node.child_count == 0) return kCutStop;
        if (options_.mode == CullMode::Full) return kCutRefined;
        // The budget rule: the node's own error within tau (Eq. 1 then chooses its level).
        const k::Aabb& box = scene_.host_objects[id].aabb;
        const float distance = std::max(glm::length(glm::clamp(camera.eye, box.min, box.max) - camera.eye),
                                        camera.near_plane);
        return node.error * share * pixels_at_1_ / distance <= options_.tau ? kCutStop : kCutRefined;
    }
    // The error rule: what the node costs drawn within tau (infinite where its own error leaves
    // its level nothing; 0 under the pixel threshold: not drawn), and the fine cut's stop: its
    // own error within kFineCutShare of what may be given up.
    float a = 0.0f;
    if (!allowance(id, camera, share, a)) {
        cost_[id] = 0.0;
        return kCutStop;
    }
    cost_[id] = node.error < a ? double(triangles(id, a - node.error)) + options_.draw_cost : INFINITY;
    return node.child_count == 0 || node.error <= PipelineOptions::kFineCutShare * a ? kCutStop : kCutRefined;
}

const std::vector<uint32_t>& CutStage::refine(const k::Camera& camera, k::DevicePtr<const uint8_t> in_frustum,
                                              const k::HzmLevels* hzm) {
    const uint32_t n = scene_.item_count;
    in_frustum_.resize(n);
    k::copyToHost(in_frustum_.data(), in_frustum, n);
    const bool occlusion = hzm != nullptr;
    const bool weighted = occlusion && options_.visibility_weighted;
    const bool coarsening = options_.lod == LodRule::Error && options_.mode != CullMode::Full;
    pixels_at_1_ = float(options_.height) / (2.0f * std::tan(0.5f * camera.fovy));
    if (state_.size() != n) {
        state_.assign(n, kCutNone);
        cost_.assign(coarsening ? n : 0, 0.0);
        covered_.assign(coarsening ? n : 0, 0);
    }
    cut_.clear();
    fine_cut_.clear();
    hidden_ids_.clear();
    nodes_tested_ = 0;
    // Top-down, a level at a time: the HZM tests the level's nodes in one batch, each node
    // decides on its own (both cores), the refined ones' children in the frustum make the next.
    size_t depth = 0;
    if (levels_.empty()) levels_.emplace_back();
    levels_[0].clear();
    if (in_frustum_[0]) levels_[0].push_back(0);
    while (!levels_[depth].empty()) {
        if (levels_.size() <= depth + 1) levels_.emplace_back();  // before the references
        const std::vector<uint32_t>& level = levels_[depth];
        const uint32_t count = uint32_t(level.size());
        nodes_tested_ += count;
        if (occlusion) {
            level_device_.growTo(count);
            k::copyToDevice(level_device_.ptr(), level.data(), count);
            occluded_device_.growTo(count);
            k::hzmTest(scene_.objects.ptr(), level_device_.ptr(), count, camera, *hzm, occluded_device_.ptr());
            hidden_.resize(count);
            k::copyToHost(hidden_.data(), occluded_device_.ptr(), count);
            if (weighted) {
                share_device_.growTo(count);
                k::hzmVisibleShare(scene_.objects.ptr(), level_device_.ptr(), count, camera, *hzm, share_device_.ptr());
                share_.resize(count);
                k::copyToHost(share_.data(), share_device_.ptr(), count);
            }
        }
        const auto decide = [&](uint32_t j) {
            const uint32_t id = level[j];
            state_[id] = occlusion && hidden_[j] ? uint8_t(kCutHidden) : decideNode(id, camera, weighted ? share_[j] : 1.0f);
        };
        if (count >= 256) {
            index_.resize(count);
            std::iota(index_.begin(), index_.end(), 0u);
            std::for_each(std::execution::par, index_.begin(), index_.end(), decide);
        } else {
            for (uint32_t j = 0; j < count; ++j) decide(j);
        }
        std::vector<uint32_t>& next = levels_[depth + 1];
        next.clear();
        for (const uint32_t id : level) {
            const uint8_t state = state_[id];
            if (state == kCutHidden) {
                hidden_ids_.push_back(id);
                continue;
            }
            if (state == kCutStop) {
                (coarsening ? fine_cut_ : cut_).push_back(id);
                continue;
            }
            const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                if (in_frustum_[c]) next.push_back(c);
        }
        ++depth;
    }
    if (coarsening) coarsen(depth);
    std::sort(cut_.begin(), cut_.end());
    if (occlusion) {
        // The frustum's share of the refinement: the cut and the nodes found hidden.
        hidden_ids_.insert(hidden_ids_.end(), cut_.begin(), cut_.end());
        std::sort(hidden_ids_.begin(), hidden_ids_.end());
    }
    return cut_;
}

void CutStage::coarsen(size_t depth) {
    // Bottom-up over what was refined: a node replaces its children's cuts where it is within
    // tau and costs no more (triangles, and draw_cost per draw). A child out of the frustum
    // costs nothing; every other child was decided, hidden ones cost nothing.
    for (size_t d = depth; d-- > 0;)
        for (const uint32_t id : levels_[d]) {
            if (state_[id] == kCutHidden) cost_[id] = 0.0;
            if (state_[id] != kCutRefined) continue;
            const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
            double children = 0.0;
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                if (in_frustum_[c]) children += cost_[c];
            if (cost_[id] <= children) state_[id] = kCutMerged;
            else cost_[id] = children;
        }
    // Top-down: the stopped and merged nodes no merged node lies above.
    for (size_t d = 0; d < depth; ++d)
        for (const uint32_t id : levels_[d]) {
            const uint8_t state = state_[id];
            const bool covered = covered_[id];
            covered_[id] = 0;
            if (state == kCutHidden || (state == kCutStop && covered)) continue;
            if (!covered && (state == kCutStop || state == kCutMerged)) cut_.push_back(id);
            if (state == kCutStop) continue;
            const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                if (in_frustum_[c]) covered_[c] = covered || state == kCutMerged;
        }
}

}  // namespace occ
