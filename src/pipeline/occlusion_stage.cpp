// SPDX-License-Identifier: MIT
#include "pipeline/occlusion_stage.h"

#include "hzm_build.h"
#include "hzm_test.h"
#include "keep_visible.h"
#include "occluder_order.h"
#include "pipeline/cut_stage.h"
#include "pipeline/pipeline.h"
#include "scan.h"

#include <algorithm>

namespace occ {

OcclusionStage::OcclusionStage(const DeviceScene& scene, const PipelineOptions& options)
    : scene_(scene), options_(options) {
    occluder_budget_ = double(options.pvs_occluder_triangles);
    // Every array a frame needs, sized once for the worst case (every item in the frustum and
    // visible): no frame allocates but the ones whose sizes depend on geometry.
    const size_t room = std::max<uint32_t>(1, scene.item_count);
    occluded_.resize(room);
    if ((options.keep_visible > 0 || options.late_pass) && options.mode == CullMode::OcLod && !scene.nodes) {
        // One record per frame parity with a lag of 2: what the 3-rank switch's culling rank,
        // which sees every other frame, records, so that one rank with lag 2 gives its answer.
        last_visible_.resize(room * options.pvs_occluder_lag);
        k::deviceMemset(last_visible_.ptr(), 0, last_visible_.size() * sizeof(uint32_t));
        returned_.resize(room * options.pvs_occluder_lag);
        k::deviceMemset(returned_.ptr(), 0, returned_.size() * sizeof(uint32_t));
        dropped_.resize(room);
        seen_.resize(room);
        if (options.late_pass) {
            late_ids_.resize(room);
            late_index_.resize(room);
            late_occluders_.resize(room);
            late_occluded_.resize(room);
            late_depth_.resize(size_t(options.width) * options.height);
        }
    }
    weights_.resize(std::max<uint32_t>(1, scene.cos_count));
    if (scene.cos_count > 0) {
        // Eq. 3 then weighs the frustum's COS members, not the whole COS (on the 10^6-object
        // plant 695 K candidates, of which about 10^5 are in the frustum on a walk); with the
        // hierarchy, the COS members among the candidates in the frustum.
        std::vector<uint32_t> cos(scene.cos_count);  // item ids (the file's are object ids)
        k::copyToHost(cos.data(), scene.cos.ptr(), cos.size());
        std::vector<uint8_t> in_cos(room, 0);
        for (const uint32_t id : cos) in_cos[id] = 1;
        in_cos_.resize(room);
        k::copyToDevice(in_cos_.ptr(), in_cos.data(), room);
        weights_.resize(room);
    }
    occluders_.resize(room);
    pvs_occluder_scratch_.taken.resize(room);
    k::deviceMemset(pvs_occluder_scratch_.taken.ptr(), 0, room);
    hzm_.resize(size_t(k::hzmTotalTexels(options.width, options.height)));
    bootstrap_pvs_.resize(room);
}

k::HzmLevels OcclusionStage::hzmLevels() const {
    k::HzmLevels levels;
    k::hzmLayout(options_.width, options_.height, levels);
    levels.data = hzm_.ptr();
    return levels;
}

std::vector<uint32_t> OcclusionStage::downloadOccluders() const {
    std::vector<uint32_t> ids(occluder_count_);
    k::copyToHost(ids.data(), occluders_.ptr(), ids.size());
    return ids;
}

// The AOS (Eq. 3's top-K of the COS), then the earlier PVS's best occluders per triangle, all
// chosen on the device; only their count comes back.
void OcclusionStage::chooseOccluders(const k::Camera& camera, const FrustumStage& frustum,
                                     k::DevicePtr<const uint32_t> source, uint32_t source_count) {
    uint32_t aos = 0;
    if (scene_.cos_count > 0 && options_.aos > 0) {
        // The same top-K either way: the frustum's items masked by COS membership, or the COS
        // masked by the frustum.
        const bool by_frustum = in_cos_.size() > 0;
        const k::DevicePtr<const uint32_t> candidates = by_frustum ? frustum.ids() : k::DevicePtr<const uint32_t>(scene_.cos.ptr());
        const uint32_t count = by_frustum ? frustum.count() : scene_.cos_count;
        k::occluderWeight(scene_.objects.ptr(), candidates, count,
                          by_frustum ? k::DevicePtr<const uint8_t>(in_cos_.ptr()) : frustum.inFrustum(), camera,
                          weights_.ptr());
        aos = k::selectTopK(candidates, weights_.ptr(), count, options_.aos, occluders_.ptr(), topk_keys_);
    }
    uint32_t extra = 0;
    if (options_.pvs_occluder_triangles > 0 && source_count > 0) {
        extra = k::selectPvsOccluders(scene_.objects.ptr(), source, source_count, frustum.inFrustum(), camera,
                                      occluders_.ptr(), aos, uint64_t(occluder_budget_), pvs_occluder_scratch_,
                                      occluders_.ptr() + aos);
    }
    occluder_count_ = aos + extra;
}

void OcclusionStage::rasterOccluders(const k::Camera& camera, FrameStats& stats) {
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

uint64_t OcclusionStage::rasterObjects(const k::Camera& camera, k::DevicePtr<const uint32_t> ids, uint32_t count,
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

void OcclusionStage::adaptOccluderBudget(const FrameStats& stats) {
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

uint32_t OcclusionStage::hzmCull(const k::Camera& camera, const FrustumStage& frustum, k::DevicePtr<uint32_t> out) {
    k::hzmTest(scene_.objects.ptr(), frustum.ids(), frustum.count(), camera, hzmLevels(), occluded_.ptr());
    return k::compactSelected(frustum.ids(), occluded_.ptr(), frustum.count(), 0, out);
}

k::DevicePtr<uint32_t> OcclusionStage::lastVisible(uint64_t frame, k::DeviceArray<uint32_t>& record) {
    const size_t room = record.size() / options_.pvs_occluder_lag;
    return record.ptr() + (frame % options_.pvs_occluder_lag) * room;
}

void OcclusionStage::buildHzm(const k::Camera& camera, FrustumStage& frustum, const OccluderSources& sources,
                              FrameStats& stats, CutStage* cut) {
    // The earlier PVS stays on the device for this: nothing crosses the bus.
    k::DevicePtr<const uint32_t> source = sources.newer;
    uint32_t source_count = sources.newer_count;
    if (sources.has_older && source_count > 0) {
        candidates_.growTo(source_count + sources.older_count);
        // Both sets, each id once: the ranking then sorts about half as many keys (both are
        // ascending: compactions of the frustum's ids, or with the hierarchy its fine cuts).
        source_count = k::unionAscending(source, source_count, sources.older, sources.older_count, candidates_.ptr());
        source = candidates_.ptr();
    }
    StageClock clock(stats);
    if (cut && source_count > 0) {
        // The last frames' HLODs are no occluders, but their leaf children may be: the higher
        // the cut stops (the better the HLODs), the fewer objects it holds.
        source_count = cut->withLeafChildren(source, source_count, leaf_candidates_);
        source = leaf_candidates_.ptr();
    }
    // With the hierarchy only the candidates are tested against the frustum (their flags, and
    // the list: those in it).
    if (cut) frustum.cullIds(source, source_count);
    // No earlier PVS (the first frame, or the first two of the switch), or one the camera has
    // left (a jump: less than half of it is still in the frustum): a first pass with the AOS and
    // what is left of that PVS gives this frame's own PVS as the candidates. With the hierarchy
    // that pass starts from the cut refined without occlusion.
    const bool jumped =
        source_count > 0 && 2 * k::countInFrustum(source, source_count, frustum.inFrustum()) < source_count;
    if ((source_count == 0 || jumped) && cut) {
        cut->refine(camera, frustum.frustum(), frustum.flags(), nullptr);
        frustum.replace(cut->cut(), cut->cutCount());
    }
    if ((source_count == 0 || jumped) && options_.pvs_occluder_triangles > 0 && frustum.count() > 0) {
        chooseOccluders(camera, frustum, source, source_count);
        rasterOccluders(camera, stats);
        k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
        source_count = hzmCull(camera, frustum, bootstrap_pvs_.ptr());
        source = bootstrap_pvs_.ptr();
    }
    chooseOccluders(camera, frustum, source, source_count);
    clock.lap(Stage::OccluderSelect);
    rasterOccluders(camera, stats);
    clock.lap(Stage::DepthRaster);
    adaptOccluderBudget(stats);
    k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
}

// niagara's late pass (PipelineOptions::late_pass), after cull's HZM test wrote occluded_ for
// the frustum's items.
void OcclusionStage::latePass(const k::Camera& camera, uint64_t frame, const FrustumStage& frustum, FrameStats& stats,
                              StageClock& clock) {
    const uint32_t n = frustum.count();
    k::markNewlyVisible(frustum.ids(), occluded_.ptr(), n, frame, 2 * options_.pvs_occluder_lag,
                        lastVisible(frame, last_visible_), dropped_.ptr());
    const uint32_t fresh = k::compactSelected(frustum.ids(), dropped_.ptr(), n, 1, late_ids_.ptr());
    if (fresh < PipelineOptions::kLatePassMinObjects || occluder_budget_ < 1) return;
    k::compactIndices(dropped_.ptr(), n, 1, late_index_.ptr());
    clock.lap(Stage::HzmTest);
    const uint32_t chosen =
        k::selectPvsOccluders(scene_.objects.ptr(), late_ids_.ptr(), fresh, frustum.inFrustum(), camera, {}, 0,
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

uint32_t OcclusionStage::cull(const k::Camera& camera, uint64_t frame, const FrustumStage& frustum,
                              k::DevicePtr<uint32_t> out, FrameStats& stats, StageClock& clock) {
    if (!keepsRecords()) return hzmCull(camera, frustum, out);
    const uint32_t n = frustum.count();
    k::hzmTest(scene_.objects.ptr(), frustum.ids(), n, camera, hzmLevels(), occluded_.ptr());
    if (options_.late_pass) latePass(camera, frame, frustum, stats, clock);
    // What the HZM shows supplies later occluders; what it showed lately is drawn too.
    seen_count_ = k::compactSelected(frustum.ids(), occluded_.ptr(), n, 0, seen_.ptr());
    k::keepRecentlyVisible(frustum.ids(), occluded_.ptr(), n, frame, options_.keep_visible, options_.pvs_occluder_lag,
                           lastVisible(frame, last_visible_), lastVisible(frame, returned_), dropped_.ptr());
    return k::compactSelected(frustum.ids(), dropped_.ptr(), n, 0, out);
}

}  // namespace occ
