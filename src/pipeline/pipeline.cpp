// SPDX-License-Identifier: MIT
#include "pipeline/pipeline.h"

#include "box_projection.h"
#include "frustum_cull.h"
#include "hzm.h"
#include "occluder_order.h"
#include "hzm_build.h"
#include "hzm_test.h"
#include "lod_select.h"
#include "occluder_weight.h"
#include "reform.h"
#include "scene/errors.h"
#include "util/config.h"

#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstring>
#include <execution>
#include <numeric>

namespace occ {

namespace {

// The first `count` entries of a host list to its device copy, which grows as needed.
template <class T, class Host>
void upload(k::DeviceArray<T>& device, const Host& host, size_t count) {
    device.growTo(std::max<size_t>(1, count));
    k::copyToDevice(device.ptr(), host.data(), count);
}

}  // namespace

CullMode parseCullMode(const std::string& s) {
    if (s == "full") return CullMode::Full;
    if (s == "lod") return CullMode::Lod;
    if (s == "oc+lod") return CullMode::OcLod;
    throw OptionError("mode", "'" + s + "': expected full, lod or oc+lod");
}

LodRule parseLodRule(const std::string& s) {
    if (s == "budget") return LodRule::Budget;
    if (s == "error") return LodRule::Error;
    throw OptionError("lod", "'" + s + "': expected budget (Eq. 1 under the vertex budget) or error (within tau pixels)");
}

StreamMode parseStreamMode(const std::string& s) {
    if (s == "sc") return StreamMode::Coherent;
    if (s == "snc") return StreamMode::NonCoherent;
    if (s == "ns") return StreamMode::None;
    throw OptionError("stream", "'" + s + "': expected sc, snc or ns");
}

void validatePipelineOptions(const PipelineOptions& options) {
    if (options.width == 0 || options.height == 0 || options.width > kMaxViewportSide || options.height > kMaxViewportSide)
        throw OptionError("viewport", std::to_string(options.width) + "x" + std::to_string(options.height) +
                          ": width and height must be in [1, " + std::to_string(kMaxViewportSide) + "]");
    if (options.aos > 65536) throw OptionError("aos", std::to_string(options.aos) + " is more than 65536 occluders");
    if (!(options.alpha > 1.0f)) throw OptionError("alpha", OptionError::value(options.alpha) + ": must be > 1");
    if (!(options.pet >= 0.0f)) throw OptionError("pet", OptionError::value(options.pet) + ": must be >= 0");
    if (!(options.budget >= 0.0)) throw OptionError("budget", "must be >= 0");
    if (!(options.budget_share >= 0.0 && options.budget_share <= 1.0))
        throw OptionError("budget", "a share of the scene's vertices must be in (0, 100] %");
    if (!(options.lod_hysteresis >= 0.0f && options.lod_hysteresis < 1.0f))
        throw OptionError("lod_hysteresis", OptionError::value(options.lod_hysteresis) + ": must be in [0, 1)");
    if (options.pvs_occluder_lag < 1 || options.pvs_occluder_lag > 2)
        throw OptionError("pvs_occluder_lag", std::to_string(options.pvs_occluder_lag) + ": must be 1 or 2");

    if (!(options.tau > 0.0f && std::isfinite(options.tau)))
        throw OptionError("tau", OptionError::value(options.tau) + ": must be a positive number of pixels");
    if (!(options.draw_cost >= 0.0f && std::isfinite(options.draw_cost)))
        throw OptionError("draw_cost", OptionError::value(options.draw_cost) + ": must be a number of triangles >= 0");
}

Pipeline::Pipeline(const OssFile& file, const PipelineOptions& options) : file_(file), options_(options) {
    validatePipelineOptions(options);
    if (options.hierarchy && file.nodeCount() == 0)
        throw OptionError("hierarchy", "on: " + file.path() +
                                           " has no hierarchy (prepare it with occswitch prep --hierarchy on)");
    scene_ = DeviceScene::upload(file, options.hierarchy);
    if (options.lod == LodRule::Error) {
        // The error of the level with k vertices is the largest error of the collapses it has
        // undone, those of vertices k .. n - 1: a suffix maximum, 0 at full detail.
        std::vector<float> lod_error(std::max<size_t>(1, file.allMaps().size()), 0.0f);
        for (uint32_t m = 0; m < scene_.mesh_count; ++m) {
            const OssFile::MeshView mesh = file.mesh(m);
            float* e = lod_error.data() + scene_.host_map_first[m];
            const uint32_t nv = mesh.vertexCount();
            e[nv] = 0.0f;
            for (uint32_t k = nv; k-- > 0;) e[k] = std::max(e[k + 1], mesh.error[k]);
        }
        std::vector<float> scale(std::max<uint32_t>(1, scene_.object_count), 1.0f);
        for (uint32_t i = 0; i < scene_.object_count; ++i) {
            const glm::mat4& w = scene_.host_world[i];
            scale[i] = std::max({glm::length(glm::vec3(w[0])), glm::length(glm::vec3(w[1])), glm::length(glm::vec3(w[2]))});
        }
        lod_error_.resize(lod_error.size());
        k::copyToDevice(lod_error_.ptr(), lod_error.data(), lod_error.size());
        object_scale_.resize(scale.size());
        k::copyToDevice(object_scale_.ptr(), scale.data(), scale.size());
        if (scene_.nodes) {
            // An HLOD's level gets what its node's own error leaves of tau.
            std::vector<float> item_error(std::max<uint32_t>(1, scene_.object_count), 0.0f);
            for (uint32_t i = 0; i < scene_.object_count; ++i) item_error[i] = scene_.host_nodes[i].error;
            item_error_.resize(item_error.size());
            k::copyToDevice(item_error_.ptr(), item_error.data(), item_error.size());
            host_lod_error_ = std::move(lod_error);
            host_scale_ = std::move(scale);
        }
    }
    const uint32_t n = scene_.object_count;
    double scene_vertices = 0;
    for (uint32_t i = 0; i < n; ++i) scene_vertices += scene_.host_objects[i].vertex_count;
    budget_ = options.budget > 0        ? options.budget
              : options.budget_share > 0 ? options.budget_share * scene_vertices
                                         : std::min(scene_vertices, PipelineOptions::kVerticesPerPixel *
                                                                        double(options.width) * double(options.height));
    if (options_.pvs_occluder_triangles == PipelineOptions::kAutoOccluderTriangles)
        options_.pvs_occluder_triangles =
            std::max(PipelineOptions::kMinAutoOccluderTriangles, uint64_t(std::llround(budget_ / 4)));
    if (!(options_.occluder_ms >= 0) || !std::isfinite(options_.occluder_ms))
        throw OptionError("occluder_ms", std::to_string(options_.occluder_ms) + ": must be a finite number >= 0");
    occluder_budget_ = double(options_.pvs_occluder_triangles);
    host_ = {file.allPositions().data(), file.allTriangles().data(), scene_.host_vertex_first.data(),
             scene_.host_triangle_first.data(), scene_.host_objects.data()};

    // Every array a frame needs, sized once for the worst case (every object in the frustum,
    // visible and drawn): no frame allocates but the ones whose sizes depend on geometry.
    const size_t room = std::max<uint32_t>(1, n);
    in_frustum_.resize(room);
    occluded_.resize(room);
    if ((options_.keep_visible > 0 || options_.late_pass) && options_.mode == CullMode::OcLod && !scene_.nodes) {
        // One record per frame parity with a lag of 2: what the 3-rank switch's culling rank,
        // which sees every other frame, records, so that one rank with lag 2 gives its answer.
        last_visible_.resize(room * options_.pvs_occluder_lag);
        k::deviceMemset(last_visible_.ptr(), 0, last_visible_.size() * sizeof(uint32_t));
        returned_.resize(room * options_.pvs_occluder_lag);
        k::deviceMemset(returned_.ptr(), 0, returned_.size() * sizeof(uint32_t));
        dropped_.resize(room);
        seen_.resize(room);
        if (options_.late_pass) {
            late_ids_.resize(room);
            late_index_.resize(room);
            late_occluders_.resize(room);
            late_occluded_.resize(room);
            late_depth_.resize(size_t(options.width) * options.height);
        }
    }
    frustum_ids_.resize(room);
    weights_.resize(std::max<uint32_t>(1, scene_.cos_count));
    if (!scene_.nodes && scene_.cos_count > 0) {
        // Eq. 3 then weighs the frustum's COS members, not the whole COS (on the 10^6-object
        // plant 695 K candidates, of which about 10^5 are in the frustum on a walk).
        std::vector<uint8_t> in_cos(room, 0);
        for (const uint32_t id : file.cos()) in_cos[id] = 1;
        in_cos_.resize(room);
        k::copyToDevice(in_cos_.ptr(), in_cos.data(), room);
        weights_.resize(room);
    }
    occluders_.resize(room);
    pvs_occluder_scratch_.taken.resize(room);
    k::deviceMemset(pvs_occluder_scratch_.taken.ptr(), 0, room);
    hzm_.resize(size_t(k::hzmTotalTexels(options.width, options.height)));
    pvs_device_.resize(room);
    bootstrap_pvs_.resize(room);
    pvs_vc_device_.resize(room);
    pvs_tc_device_.resize(room);
    for (k::DeviceArray<k::LayoutBlock>& l : layouts_) l.resize(room);
    places_.resize(room);
    k::deviceMemset(places_.ptr(), 0, room * sizeof(k::BlockPlace));
    pvs_vc_.resize(n);
    pvs_tc_.resize(n);
}

void Pipeline::lendActiveArrays(k::BufferProvider& lender) {
    lender.beginDeviceWrites();
    for (uint32_t b = 0; b < 2; ++b)
        active_.vertices.buffers[b].lendFrom(&lender, kActiveVertexSlot + b,
                                             b == active_.vertices.current ? heap_.vertex_top : 0);
    indices_.lendFrom(&lender, kIndexSlot, 3 * heap_.triangle_top);
    lender.endDeviceWrites();
    lender_ = &lender;
}

std::vector<k::LayoutBlock> Pipeline::downloadLayout() const {
    const uint32_t last = cur_index_ ^ 1;
    std::vector<k::LayoutBlock> blocks(layout_counts_[last]);
    k::copyToHost(blocks.data(), layouts_[last].ptr(), blocks.size());
    return blocks;
}

std::vector<uint32_t> Pipeline::downloadFrustumObjects() const {
    std::vector<uint32_t> ids(frustum_count_);
    k::copyToHost(ids.data(), frustum_ids_.ptr(), ids.size());
    return ids;
}

std::vector<uint32_t> Pipeline::downloadOccluders() const {
    std::vector<uint32_t> ids(occluder_count_);
    k::copyToHost(ids.data(), occluders_.ptr(), ids.size());
    return ids;
}

k::HzmLevels Pipeline::hzmLevels() const {
    k::HzmLevels levels;
    k::hzmLayout(options_.width, options_.height, levels);
    levels.data = hzm_.ptr();
    return levels;
}

// The AOS (Eq. 3's top-K of the COS), then the earlier PVS's best occluders per triangle, all
// chosen on the device; only their count comes back.
void Pipeline::chooseOccluders(const k::Camera& camera, k::DevicePtr<const uint32_t> source, uint32_t source_count) {
    uint32_t aos = 0;
    if (scene_.cos_count > 0 && options_.aos > 0) {
        // The same top-K either way: the frustum's objects masked by COS membership, or the COS
        // masked by the frustum.
        const bool by_frustum = in_cos_.size() > 0;
        const k::DevicePtr<const uint32_t> candidates = by_frustum ? k::DevicePtr<const uint32_t>(frustum_ids_.ptr())
                                                                   : k::DevicePtr<const uint32_t>(scene_.cos.ptr());
        const uint32_t count = by_frustum ? frustum_count_ : scene_.cos_count;
        k::occluderWeight(scene_.objects.ptr(), candidates, count, by_frustum ? in_cos_.ptr() : in_frustum_.ptr(),
                          camera, weights_.ptr());
        aos = k::selectTopK(candidates, weights_.ptr(), count, options_.aos, occluders_.ptr(), topk_keys_);
    }
    uint32_t extra = 0;
    if (options_.pvs_occluder_triangles > 0 && source_count > 0) {
        extra = k::selectPvsOccluders(scene_.objects.ptr(), source, source_count, in_frustum_.ptr(), camera,
                                      occluders_.ptr(), aos, uint64_t(occluder_budget_), pvs_occluder_scratch_,
                                      occluders_.ptr() + aos);
    }
    occluder_count_ = aos + extra;
}

void Pipeline::rasterOccluders(const k::Camera& camera, FrameStats& stats) {
    // Occluders are rastered at full detail, in world space, from the resident meshes; for the
    // masked raster nearest first, which keeps near depths in its subtiles (the exact raster's
    // minimum does not depend on the order). Closed meshes seen from outside their box skip
    // their back faces (gatherOccluders): on the plant walks a quarter to a third of the
    // raster's time, with the same culling (docs/results.md).
    if (options_.raster == OccluderRaster::Masked)
        k::sortFrontToBack(scene_.objects.ptr(), occluders_.ptr(), occluder_count_, camera, occluder_keys_);
    stats.aos_size = occluder_count_;
    stats.occluder_triangles = rasterObjects(camera, occluders_.ptr(), occluder_count_, occluder_geometry_, hzm_.ptr());
}

uint64_t Pipeline::rasterObjects(const k::Camera& camera, k::DevicePtr<const uint32_t> ids, uint32_t count,
                                 k::OccluderGeometry& geometry, k::DevicePtr<float> depth) {
    if (options_.raster == OccluderRaster::Exact)
        return k::rasterOccluders(scene_.objects.ptr(), scene_.world.ptr(), scene_.meshes(), ids, count, camera, geometry,
                                  depth, raster_scratch_);
    k::gatherOccluders(scene_.objects.ptr(), scene_.world.ptr(), scene_.meshes(), ids, count, geometry, &camera.eye);
    k::appendNearClipped(geometry, camera);
    const k::OccluderGeometry& g = geometry;
    k::maskedDepthRaster(g.positions.ptr(), g.triangles.ptr(), uint32_t(g.triangle_total), g.edge_flags.ptr(),
                         g.edge_neighbours.ptr(), camera, depth, raster_scratch_, /*seams=*/true);
    return g.triangle_total;
}

k::DevicePtr<const float> Pipeline::visibleShares(const k::Camera& camera, k::DevicePtr<const uint32_t> pvs,
                                                  uint32_t count) {
    if (!options_.visibility_weighted || options_.mode != CullMode::OcLod) return nullptr;
    visible_share_.growTo(std::max<uint32_t>(1, count));
    k::hzmVisibleShare(scene_.objects.ptr(), pvs, count, camera, hzmLevels(), visible_share_.ptr());
    return visible_share_.ptr();
}

k::DevicePtr<uint32_t> Pipeline::lastVisible(uint64_t frame, k::DeviceArray<uint32_t>& record) {
    const size_t room = record.size() / options_.pvs_occluder_lag;
    return record.ptr() + (frame % options_.pvs_occluder_lag) * room;
}

uint32_t Pipeline::hzmCull(const k::Camera& camera, k::DevicePtr<uint32_t> out) {
    k::hzmTest(scene_.objects.ptr(), frustum_ids_.ptr(), frustum_count_, camera, hzmLevels(), occluded_.ptr());
    return k::compactSelected(frustum_ids_.ptr(), occluded_.ptr(), frustum_count_, 0, out);
}

uint32_t Pipeline::cutTriangles(uint32_t item, float allowed) const {
    const k::ObjectInfo& o = scene_.host_objects[item];
    if (o.vertex_count == 0) return 0;
    // The level k::lodSelectByError will choose.
    const uint32_t k = k::levelWithinError(host_lod_error_.data() + scene_.host_map_first[o.mesh], o.q, o.vertex_count,
                                           allowed / std::max(host_scale_[item], 1e-30f));
    return scene_.file->allMaps()[scene_.host_map_first[o.mesh] + k];
}

bool Pipeline::cutAllowance(uint32_t item, const k::Camera& camera, float share, float& allowed) const {
    const k::Projection pr = k::projectBox(scene_.host_objects[item], camera);
    if (pr.area < options_.pet) return false;
    allowed = options_.tau * pr.depth / (cut_pixels_at_1_ * std::max(share, 1e-30f));
    return true;
}

uint8_t Pipeline::decideNode(uint32_t id, const k::Camera& camera, float share) {
    const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
    if (options_.lod != LodRule::Error || options_.mode == CullMode::Full) {
        if (node.child_count == 0) return kCutStop;
        if (options_.mode == CullMode::Full) return kCutRefined;
        // The budget rule: the node's own error within tau (Eq. 1 then chooses its level).
        const k::Aabb& box = scene_.host_objects[id].aabb;
        const float distance = std::max(glm::length(glm::clamp(camera.eye, box.min, box.max) - camera.eye),
                                        camera.near_plane);
        return node.error * share * cut_pixels_at_1_ / distance <= options_.tau ? kCutStop : kCutRefined;
    }
    // The error rule: what the node costs drawn within tau (infinite where its own error leaves
    // its level nothing; 0 under the pixel threshold: not drawn), and the fine cut's stop: its
    // own error within kFineCutShare of what may be given up.
    float a = 0.0f;
    if (!cutAllowance(id, camera, share, a)) {
        cut_cost_[id] = 0.0;
        return kCutStop;
    }
    cut_cost_[id] = node.error < a ? double(cutTriangles(id, a - node.error)) + options_.draw_cost : INFINITY;
    return node.child_count == 0 || node.error <= PipelineOptions::kFineCutShare * a ? kCutStop : kCutRefined;
}

uint32_t Pipeline::refineCut(const k::Camera& camera, bool occlusion, k::DevicePtr<uint32_t> out) {
    const uint32_t n = scene_.object_count;
    cut_in_frustum_.resize(n);
    k::copyToHost(cut_in_frustum_.data(), in_frustum_.ptr(), n);
    const bool weighted = occlusion && options_.visibility_weighted;
    const bool coarsen = options_.lod == LodRule::Error && options_.mode != CullMode::Full;
    cut_pixels_at_1_ = float(options_.height) / (2.0f * std::tan(0.5f * camera.fovy));
    if (cut_state_.size() != n) {
        cut_state_.assign(n, kCutNone);
        cut_cost_.assign(coarsen ? n : 0, 0.0);
        cut_covered_.assign(coarsen ? n : 0, 0);
    }
    cut_.clear();
    fine_cut_.clear();
    cut_hidden_ids_.clear();
    nodes_tested_ = 0;
    // Top-down, a level at a time: the HZM tests the level's nodes in one batch, each node
    // decides on its own (both cores), the refined ones' children in the frustum make the next.
    size_t depth = 0;
    if (cut_levels_.empty()) cut_levels_.emplace_back();
    cut_levels_[0].clear();
    if (cut_in_frustum_[0]) cut_levels_[0].push_back(0);
    while (!cut_levels_[depth].empty()) {
        if (cut_levels_.size() <= depth + 1) cut_levels_.emplace_back();  // before the references
        const std::vector<uint32_t>& level = cut_levels_[depth];
        const uint32_t count = uint32_t(level.size());
        nodes_tested_ += count;
        if (occlusion) {
            cut_level_device_.growTo(count);
            k::copyToDevice(cut_level_device_.ptr(), level.data(), count);
            occluded_.growTo(count);
            k::hzmTest(scene_.objects.ptr(), cut_level_device_.ptr(), count, camera, hzmLevels(), occluded_.ptr());
            cut_hidden_.resize(count);
            k::copyToHost(cut_hidden_.data(), occluded_.ptr(), count);
            if (weighted) {
                cut_share_device_.growTo(count);
                k::hzmVisibleShare(scene_.objects.ptr(), cut_level_device_.ptr(), count, camera, hzmLevels(),
                                   cut_share_device_.ptr());
                cut_share_.resize(count);
                k::copyToHost(cut_share_.data(), cut_share_device_.ptr(), count);
            }
        }
        const auto decide = [&](uint32_t j) {
            const uint32_t id = level[j];
            cut_state_[id] = occlusion && cut_hidden_[j] ? uint8_t(kCutHidden) : decideNode(id, camera, weighted ? cut_share_[j] : 1.0f);
        };
        if (count >= 256) {
            cut_index_.resize(count);
            std::iota(cut_index_.begin(), cut_index_.end(), 0u);
            std::for_each(std::execution::par, cut_index_.begin(), cut_index_.end(), decide);
        } else {
            for (uint32_t j = 0; j < count; ++j) decide(j);
        }
        std::vector<uint32_t>& next = cut_levels_[depth + 1];
        next.clear();
        for (const uint32_t id : level) {
            const uint8_t state = cut_state_[id];
            if (state == kCutHidden) {
                cut_hidden_ids_.push_back(id);
                continue;
            }
            if (state == kCutStop) {
                (coarsen ? fine_cut_ : cut_).push_back(id);
                continue;
            }
            const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                if (cut_in_frustum_[c]) next.push_back(c);
        }
        ++depth;
    }
    if (coarsen) {
        // Bottom-up over what was refined: a node replaces its children's cuts where it is
        // within tau and costs no more (triangles, and draw_cost per draw). A child out of the
        // frustum costs nothing; every other child was decided, hidden ones cost nothing.
        for (size_t d = depth; d-- > 0;)
            for (const uint32_t id : cut_levels_[d]) {
                if (cut_state_[id] == kCutHidden) cut_cost_[id] = 0.0;
                if (cut_state_[id] != kCutRefined) continue;
                const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
                double children = 0.0;
                for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                    if (cut_in_frustum_[c]) children += cut_cost_[c];
                if (cut_cost_[id] <= children) cut_state_[id] = kCutMerged;
                else cut_cost_[id] = children;
            }
        // Top-down: the stopped and merged nodes no merged node lies above.
        for (size_t d = 0; d < depth; ++d)
            for (const uint32_t id : cut_levels_[d]) {
                const uint8_t state = cut_state_[id];
                const bool covered = cut_covered_[id];
                cut_covered_[id] = 0;
                if (state == kCutHidden || (state == kCutStop && covered)) continue;
                if (!covered && (state == kCutStop || state == kCutMerged)) cut_.push_back(id);
                if (state == kCutStop) continue;
                const DeviceScene::NodeLinks& node = scene_.host_nodes[id];
                for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                    if (cut_in_frustum_[c]) cut_covered_[c] = covered || state == kCutMerged;
            }
    }
    std::sort(cut_.begin(), cut_.end());
    if (occlusion) {
        // The frustum's share of the refinement: the cut and the nodes found hidden.
        cut_hidden_ids_.insert(cut_hidden_ids_.end(), cut_.begin(), cut_.end());
        std::sort(cut_hidden_ids_.begin(), cut_hidden_ids_.end());
        frustum_count_ = uint32_t(cut_hidden_ids_.size());
        k::copyToDevice(frustum_ids_.ptr(), cut_hidden_ids_.data(), frustum_count_);
    }
    k::copyToDevice(out, cut_.data(), cut_.size());
    return uint32_t(cut_.size());
}

namespace {

using Clock = std::chrono::steady_clock;

// Adds the time since the last lap (or since construction) to a stage's column, after the
// kernels finished.
class StageClock {
public:
    explicit StageClock(FrameStats& stats) : stats_(stats), mark_(Clock::now()) {}
    void lap(Stage s) {
        k::deviceSynchronize();
        const Clock::time_point now = Clock::now();
        stats_.ms[uint32_t(s)] += std::chrono::duration<double, std::milli>(now - mark_).count();
        stats_.ms_total += std::chrono::duration<double, std::milli>(now - mark_).count();
        mark_ = now;
    }

private:
    FrameStats& stats_;
    Clock::time_point mark_;
};

}  // namespace

// niagara's late pass (PipelineOptions::late_pass), after the HZM test of cullPass wrote
// occluded_ for frustum_ids_.
template <class StageClockT>
void Pipeline::latePass(const k::Camera& camera, uint64_t frame, FrameStats& stats, StageClockT& clock) {
    const uint32_t n = frustum_count_;
    k::markNewlyVisible(frustum_ids_.ptr(), occluded_.ptr(), n, frame, 2 * options_.pvs_occluder_lag, lastVisible(frame, last_visible_),
                        dropped_.ptr());
    const uint32_t fresh = k::compactSelected(frustum_ids_.ptr(), dropped_.ptr(), n, 1, late_ids_.ptr());
    if (fresh < PipelineOptions::kLatePassMinObjects || occluder_budget_ < 1) return;
    k::compactIndices(dropped_.ptr(), n, 1, late_index_.ptr());
    clock.lap(Stage::HzmTest);
    const uint32_t chosen =
        k::selectPvsOccluders(scene_.objects.ptr(), late_ids_.ptr(), fresh, in_frustum_.ptr(), camera, {}, 0,
                              uint64_t(occluder_budget_), pvs_occluder_scratch_, late_occluders_.ptr());
    clock.lap(Stage::OccluderSelect);
    if (chosen == 0) return;
    stats.aos_size += chosen;
    stats.occluder_triangles += rasterObjects(camera, late_occluders_.ptr(), chosen, late_geometry_, late_depth_.ptr());
    clock.lap(Stage::DepthRaster);
    k::mergeNearest(hzm_.ptr(), late_depth_.ptr(), options_.width * options_.height);
    k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
    // Only the new ones are tested again: what they hide of the old ones stays drawn.
    k::hzmTest(scene_.objects.ptr(), late_ids_.ptr(), fresh, camera, hzmLevels(), late_occluded_.ptr());
    k::scatterFlags(late_index_.ptr(), late_occluded_.ptr(), fresh, occluded_.ptr());
}

void Pipeline::frustumPass(const CameraPose& pose, FrameStats& stats) {
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    const uint32_t n = scene_.object_count;
    const k::Frustum frustum = k::frustumFromViewProj(camera.view_proj);
    frustum_count_ = k::frustumCull(scene_.objects.ptr(), n, frustum, in_frustum_.ptr(), frustum_ids_.ptr());
    // With nodes the frustum's cut is the visible set of modes full and lod; oc+lod refines
    // against the HZM only (its in-frustum items are then the cut and the nodes found hidden),
    // and its first frame's occluders come from every item the frustum holds.
    if (scene_.nodes && options_.mode != CullMode::OcLod) frustum_count_ = refineCut(camera, false, frustum_ids_.ptr());
    frustum_pose_ = pose;
    has_frustum_pose_ = true;
    clock.lap(Stage::FrustumCull);
}

bool Pipeline::frustumIsFor(const CameraPose& pose) const {
    return has_frustum_pose_ && std::memcmp(&frustum_pose_, &pose, sizeof pose) == 0;
}

void Pipeline::occluderPass(const CameraPose& pose, uint64_t frame, FrameStats& stats) {
    if (options_.mode != CullMode::OcLod) return;
    // The earlier PVS stays on the device for this: nothing crosses the bus.
    k::DevicePtr<const uint32_t> source;
    uint32_t source_count = 0;
    const CulledFrame* older = nullptr;
    const uint64_t lag = options_.pvs_occluder_lag;
    if (frame >= lag)
        for (const CulledFrame& h : history_) {
            if (h.frame == frame - lag) source = h.device_pvs.ptr(), source_count = h.occluder_count;
            if (frame >= 2 * lag && h.frame == frame - 2 * lag && !h.pvs.empty()) older = &h;
        }
    if (older && source_count > 0) {
        occluder_candidates_.growTo(source_count + older->occluder_count);
        if (!scene_.nodes) {
            // Both sets, each id once: the ranking then sorts about half as many keys (both
            // are ascending without the hierarchy: compactions of the frustum's ids).
            source_count = k::unionAscending(source, source_count, older->device_pvs.ptr(), older->occluder_count,
                                             occluder_candidates_.ptr());
        } else {
            // Both sets, one after the other; the choice takes an id listed twice once.
            k::copyOnDevice(occluder_candidates_.ptr(), source, source_count);
            k::copyOnDevice(occluder_candidates_.ptr() + source_count, older->device_pvs.ptr(), older->occluder_count);
            source_count += older->occluder_count;
        }
        source = occluder_candidates_.ptr();
    }
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    // No earlier PVS (the first frame, or the first two of the switch), or one the camera has
    // left (a jump: less than half of it is still in the frustum): a first pass with the AOS and
    // what is left of that PVS gives this frame's own PVS as the candidates.
    const bool jumped = source_count > 0 && 2 * k::countInFrustum(source, source_count, in_frustum_.ptr()) < source_count;
    if ((source_count == 0 || jumped) && options_.pvs_occluder_triangles > 0 && frustum_count_ > 0) {
        chooseOccluders(camera, source, source_count);
        rasterOccluders(camera, stats);
        k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
        source_count = hzmCull(camera, bootstrap_pvs_.ptr());
        source = bootstrap_pvs_.ptr();
    }
    chooseOccluders(camera, source, source_count);
    clock.lap(Stage::OccluderSelect);
    rasterOccluders(camera, stats);
    clock.lap(Stage::DepthRaster);
    adaptOccluderBudget(stats);
    k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
}

void Pipeline::adaptOccluderBudget(const FrameStats& stats) {
    const double ms = stats.ms[size_t(Stage::DepthRaster)];
    // Too few triangles or too short a time say little about the rate.
    if (options_.occluder_ms <= 0 || options_.pvs_occluder_triangles == 0 || stats.occluder_triangles < 2000 ||
        !(ms > 0.05))
        return;
    const double rate = double(stats.occluder_triangles) / ms;
    raster_rate_ = raster_rate_ > 0 ? 0.7 * raster_rate_ + 0.3 * rate : rate;
    occluder_budget_ = std::clamp(raster_rate_ * options_.occluder_ms, double(PipelineOptions::kMinAdaptiveOccluderTriangles),
                                  double(PipelineOptions::kMaxAdaptiveOccluderTriangles));
}

void Pipeline::cullPass(const CameraPose& pose, uint64_t frame, FrameStats& stats,
                        std::span<const std::pair<uint32_t, uint32_t>> previous_lod) {
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    uint32_t count = frustum_count_;
    k::DevicePtr<const uint32_t> pvs = frustum_ids_.ptr();
    if (options_.mode == CullMode::OcLod) {
        if (scene_.nodes) {
            count = refineCut(camera, true, pvs_device_.ptr());
        } else if (last_visible_.size() > 0) {
            k::hzmTest(scene_.objects.ptr(), frustum_ids_.ptr(), frustum_count_, camera, hzmLevels(), occluded_.ptr());
            if (options_.late_pass) latePass(camera, frame, stats, clock);
            // What the HZM shows supplies later occluders; what it showed lately is drawn too.
            seen_count_ = k::compactSelected(frustum_ids_.ptr(), occluded_.ptr(), frustum_count_, 0, seen_.ptr());
            k::keepRecentlyVisible(frustum_ids_.ptr(), occluded_.ptr(), frustum_count_, frame, options_.keep_visible,
                                   options_.pvs_occluder_lag, lastVisible(frame, last_visible_), lastVisible(frame, returned_),
                                   dropped_.ptr());
            count = k::compactSelected(frustum_ids_.ptr(), dropped_.ptr(), frustum_count_, 0, pvs_device_.ptr());
        } else {
            count = hzmCull(camera, pvs_device_.ptr());
        }
        pvs = pvs_device_.ptr();
        clock.lap(Stage::HzmTest);
    }
    const uint32_t in_count = frustum_count_;  // with nodes in oc+lod, refineCut's
    stats.objects_in_frustum = in_count;
    stats.objects_visible = count;
    stats.objects_occluded = in_count - std::min(in_count, count);
    // The visible set comes back to the host, for the network and the history; it stays on the
    // device for the layout.
    if (options_.mode != CullMode::OcLod) {
        k::copyOnDevice(pvs_device_.ptr(), pvs, count);
        pvs = pvs_device_.ptr();
    }
    pvs_.resize(count);
    k::copyToHost(pvs_.data(), pvs, count);

    if (options_.mode == CullMode::Full) {
        // The baseline draws every object whole: its counts go up.
        for (uint32_t j = 0; j < count; ++j) {
            pvs_vc_[j] = scene_.host_objects[pvs_[j]].vertex_count;
            pvs_tc_[j] = scene_.host_objects[pvs_[j]].triangle_count;
        }
        k::copyToDevice(pvs_vc_device_.ptr(), pvs_vc_.data(), count);
        k::copyToDevice(pvs_tc_device_.ptr(), pvs_tc_.data(), count);
    } else if (options_.lod == LodRule::Error) {
        // No hysteresis: keeping a coarser level than the bound allows would break it.
        k::lodSelectByError(scene_.objects.ptr(), pvs, count, camera, options_.tau, options_.pet, visibleShares(camera, pvs, count), scene_.map_first.ptr(),
                            lod_error_.ptr(), object_scale_.ptr(), scene_.nodes ? item_error_.ptr() : nullptr, scene_.maps, pvs_vc_device_.ptr(),
                            pvs_tc_device_.ptr());
        k::copyToHost(pvs_vc_.data(), pvs_vc_device_.ptr(), count);
    } else {
        const k::LodParams params{float(budget_), options_.alpha, options_.pet, visibleShares(camera, pvs, count)};
        k::lodSelect(scene_.objects.ptr(), pvs, count, camera, params, scene_.map_first.ptr(), scene_.maps,
                     pvs_vc_device_.ptr(), pvs_tc_device_.ptr(), lod_shares_);
        if (options_.lod_hysteresis > 0 && !previous_lod.empty()) {
            // The last frame's visible set goes up (the switch's comes from the other rank).
            previous_lod_.resize(previous_lod.size());
            for (size_t j = 0; j < previous_lod.size(); ++j)
                previous_lod_[j] = {previous_lod[j].first, previous_lod[j].second};
            upload(previous_lod_device_, previous_lod_, previous_lod.size());
            k::keepSimilarLods(pvs, count, previous_lod_device_.ptr(), uint32_t(previous_lod.size()),
                               options_.lod_hysteresis, budget_, scene_.objects.ptr(), scene_.map_first.ptr(),
                               scene_.maps, pvs_vc_device_.ptr(), pvs_tc_device_.ptr(), hysteresis_scratch_);
        }
        k::copyToHost(pvs_vc_.data(), pvs_vc_device_.ptr(), count);
    }
    std::rotate(history_, history_ + kHistory - 1, history_ + kHistory);  // the oldest becomes [0]
    CulledFrame& h = history_[0];
    h.frame = frame;
    h.pvs.assign(pvs_.begin(), pvs_.end());
    if (scene_.nodes && !fine_cut_.empty()) {
        // The coarsened cut's HLODs are no occluders: the fine cut's visible items before the
        // coarsening (the leaves among them) are the candidates.
        h.occluder_count = uint32_t(fine_cut_.size());
        h.device_pvs.growTo(std::max<uint32_t>(1, h.occluder_count));
        k::copyToDevice(h.device_pvs.ptr(), fine_cut_.data(), h.occluder_count);
    } else {
        const bool kept = options_.mode == CullMode::OcLod && last_visible_.size() > 0;
        h.occluder_count = kept ? seen_count_ : count;
        h.device_pvs.growTo(std::max<uint32_t>(1, h.occluder_count));
        k::copyOnDevice(h.device_pvs.ptr(), kept ? k::DevicePtr<const uint32_t>(seen_.ptr()) : pvs, h.occluder_count);
    }
    h.lod.resize(pvs_.size());
    for (size_t j = 0; j < pvs_.size(); ++j) h.lod[j] = {pvs_[j], pvs_vc_[j]};
    clock.lap(Stage::LodSelect);
}

void Pipeline::setVisible(std::span<const uint32_t> ids, std::span<const uint32_t> vertex_counts) {
    if (ids.size() != vertex_counts.size() || ids.size() > scene_.object_count)
        throw std::invalid_argument("Pipeline::setVisible: ids and vertex counts differ in size");
    for (size_t j = 0; j < ids.size(); ++j) {
        if ((j > 0 && ids[j] <= ids[j - 1]) || ids[j] >= scene_.object_count)
            throw std::invalid_argument("Pipeline::setVisible: entry " + std::to_string(j) + " is not a valid LOD");
        const k::ObjectInfo& o = scene_.host_objects[ids[j]];
        if (vertex_counts[j] > o.vertex_count || (vertex_counts[j] != 0 && vertex_counts[j] < o.q))
            throw std::invalid_argument("Pipeline::setVisible: entry " + std::to_string(j) + " is not a valid LOD");
    }
    pvs_.assign(ids.begin(), ids.end());
    for (size_t j = 0; j < ids.size(); ++j) {
        pvs_vc_[j] = vertex_counts[j];
        pvs_tc_[j] = scene_.lodTriangles(scene_.host_objects[ids[j]].mesh, vertex_counts[j]);
    }
    // The layout is built on the device: the visible set goes up.
    k::copyToDevice(pvs_device_.ptr(), pvs_.data(), pvs_.size());
    k::copyToDevice(pvs_vc_device_.ptr(), pvs_vc_.data(), pvs_.size());
    k::copyToDevice(pvs_tc_device_.ptr(), pvs_tc_.data(), pvs_.size());
}

void Pipeline::streamPass(uint64_t frame, FrameStats& stats) {
    StageClock clock(stats);
    stats.frame = frame;
    stats.budget_vertices = uint64_t(budget_);
    stats.objects_visible = pvs_.size();
    stats.pvs_hash = XXH3_64bits(pvs_.data(), pvs_.size() * sizeof(uint32_t));
    const Churn churn = setChurn(drawn_pvs_, pvs_);
    stats.pvs_added = churn.added;
    stats.pvs_removed = churn.removed;
    drawn_pvs_ = pvs_;
    // The layout, on the device; the host gets back what it must stream and a few totals.
    const bool coherent = options_.stream == StreamMode::Coherent;
    const k::VisibleLods visible{pvs_device_.ptr(), pvs_vc_device_.ptr(), pvs_tc_device_.ptr(), uint32_t(pvs_.size())};
    const k::LayoutOptions layout{frame, coherent, coherent ? options_.retain_frames : 0u,
                                  options_.resident_factor * budget_};
    const uint32_t last = cur_index_ ^ 1;
    k::LayoutTotals totals;
    try {
        totals = k::placeLayout(visible, layouts_[last].ptr(), layout_counts_[last], layouts_[cur_index_].ptr(),
                                places_.ptr(), {scene_.objects.ptr(), scene_.map_first.ptr(), scene_.maps},
                                layout, heap_, lists_, layout_scratch_);
    } catch (const std::length_error& e) {
        throw SystemError(e.what());
    }
    layout_counts_[cur_index_] = totals.blocks;
    stats.active_vertices = totals.active_vertices;
    stats.active_triangles = totals.active_triangles;
    stats.objects_drawn = totals.objects_drawn;
    stats.resident_vertices = totals.resident_vertices;
    stats.resident_triangles = totals.resident_triangles;
    stats.moved_bytes = totals.moved_bytes;
    stream_list_.growTo(std::max<uint32_t>(1, lists_.stream_count));
    k::copyToHost(stream_list_.data(), lists_.streams.ptr(), lists_.stream_count);
    clock.lap(Stage::Scan);

    // The active arrays may be the display's buffers: the kernels write them only in here.
    if (lender_) lender_->beginDeviceWrites();
    // Compaction and growth write every block into the other buffers, which then become current.
    k::ActiveBuffer<glm::vec3>& vertices = active_.vertices;
    k::ActiveBuffer<uint32_t>& triangles = active_.triangles;
    const uint32_t vertex_to = totals.relocated ? vertices.current ^ 1 : vertices.current;
    const uint32_t triangle_to = totals.relocated ? triangles.current ^ 1 : triangles.current;
    vertices.buffers[vertex_to].reserve(heap_.vertex_capacity);
    triangles.buffers[triangle_to].reserve(3 * heap_.triangle_capacity);
    indices_.reserve(3 * heap_.triangle_capacity);
    k::StreamCounts sent;
    if (options_.stream == StreamMode::None) {
        sent = k::streamObjectByObject(stream_list_.data(), lists_.stream_count, host_,
                                       vertices.buffers[vertex_to].ptr(), triangles.buffers[triangle_to].ptr());
        clock.lap(Stage::StreamCollect);
        clock.lap(Stage::Defragment);
    } else {
        sent = k::streamBlocks(stream_list_.data(), lists_.stream_count, host_, staging_);
        clock.lap(Stage::StreamCollect);
        // Only the blocks that changed move; their lists never left the device.
        k::defragmentVertices(lists_.vertex_moves.ptr(), lists_.vertex_move_count,
                              vertices.buffers[vertices.current].ptr(), vertices.buffers[vertex_to].ptr(),
                              staging_.device_vertices.ptr(), active_);
        k::defragmentTriangles(lists_.triangle_moves.ptr(), lists_.triangle_move_count,
                               triangles.buffers[triangles.current].ptr(), triangles.buffers[triangle_to].ptr(),
                               staging_.device_triangles.ptr(), active_);
        clock.lap(Stage::Defragment);
    }
    vertices.current = vertex_to;
    triangles.current = triangle_to;
    stats.streamed_vertices = sent.vertices;
    stats.streamed_triangles = sent.triangles;
    stats.streamed_bytes = sent.bytes();

    stats.reformed_triangles =
        k::reformBlocks(lists_.reforms.ptr(), lists_.reform_count, scene_.objects.ptr(), scene_.vertex_first.ptr(),
                        scene_.ecol, triangles.data(), indices_.ptr(), reform_scratch_);
    if (lender_) lender_->endDeviceWrites();
    clock.lap(Stage::Reform);
    cur_index_ ^= 1;
}

FrameStats Pipeline::runFrame(const CameraPose& pose, uint64_t frame) {
    FrameStats stats;
    stats.frame = frame;
    BusWindow bus;
    // The PVS `pvs_occluder_lag` frames back supplies this frame's extra occluders.
    occluderPass(pose, frame, stats);
    // The last frame's visible set, if this pipeline culled it, for the hysteresis.
    const bool last = frame > 0 && history_[0].frame == frame - 1;
    static const std::vector<std::pair<uint32_t, uint32_t>> none;
    cullPass(pose, frame, stats, last ? history_[0].lod : none);
    streamPass(frame, stats);
    bus.take(stats);
    return stats;
}


}  // namespace occ
