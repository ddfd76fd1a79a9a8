// SPDX-License-Identifier: MIT
#pragma once

#include "depth_raster.h"
#include "device_memory.h"
#include "hzm.h"
#include "kernel_types.h"
#include "masked_raster.h"
#include "occluder_gather.h"
#include "occluder_weight.h"
#include "pipeline/device_scene.h"
#include "pipeline/frame_stats.h"
#include "pipeline/frustum_stage.h"

#include <vector>

namespace occ {

struct PipelineOptions;
class CutStage;

// Where a frame's PVS occluders come from: the PVS `pvs_occluder_lag` frames back (newer) and
// the one twice as far (older), item ids on the device (either may be empty).
struct OccluderSources {
    k::DevicePtr<const uint32_t> newer;
    uint32_t newer_count = 0;
    k::DevicePtr<const uint32_t> older;
    uint32_t older_count = 0;
    bool has_older = false;  // older is a culled frame's (possibly with no occluders)
};

// Occlusion culling against a Hierarchical Z-Map (Peng & Cao 2013; Zhang et al. 1997): the
// occluder raster's role (OR: the occluders chosen, rastered at full detail into a depth buffer,
// the HZM built over it) and the culling role's test (HC: each frustum item's box against the
// HZM, with niagara's late pass and CHC++'s keeping of recently visible items). Owns the
// occluders, their geometry, the depth buffer and HZM, and the per-item records of the last
// frames.
class OcclusionStage {
public:
    // options must outlive the stage; its pvs_occluder_triangles resolved (not auto).
    OcclusionStage(const DeviceScene& scene, const PipelineOptions& options);

    // OR: Eq. 3's AOS among the frustum's COS and the best of `sources` per triangle (or, with
    // no earlier PVS or one the camera left, of a first pass's own PVS), rastered, and the HZM.
    // With the hierarchy (cut: its stage; null without), no frame tests every item: the AOS is
    // chosen among the sources in the frustum, and a first pass among the cut refined without
    // occlusion; the frustum's list is left as one of those.
    void buildHzm(const k::Camera& camera, FrustumStage& frustum, const OccluderSources& sources, FrameStats& stats,
                  CutStage* cut);
    // HC of `frame` against the last buildHzm's HZM: the frustum items it does not prove hidden
    // (and, with the records, those kept visible), ascending into out; returns how many. Laps
    // `clock` for the late pass's stages.
    uint32_t cull(const k::Camera& camera, uint64_t frame, const FrustumStage& frustum, k::DevicePtr<uint32_t> out,
                  FrameStats& stats, StageClock& clock);

    // With the records (keep_visible or the late pass, without the hierarchy): what the last
    // cull's HZM test alone found visible, the later frames' occluder candidates.
    bool keepsRecords() const { return last_visible_.size() > 0; }
    k::DevicePtr<const uint32_t> seen() const { return seen_.ptr(); }
    uint32_t seenCount() const { return seen_count_; }

    k::HzmLevels hzmLevels() const;
    k::DevicePtr<const float> occluderDepth() const { return hzm_.ptr(); }
    const k::OccluderGeometry& occluderGeometry() const { return occluder_geometry_; }
    std::vector<uint32_t> downloadOccluders() const;  // the last buildHzm's, AOS first

private:
    void chooseOccluders(const k::Camera& camera, const FrustumStage& frustum, k::DevicePtr<const uint32_t> source,
                         uint32_t source_count);
    void rasterOccluders(const k::Camera& camera, FrameStats& stats);
    // Gathers items ids[0, count) at full detail, near-clips them and rasters them into depth
    // (W x H, cleared first) with the chosen raster; returns the triangles rastered.
    uint64_t rasterObjects(const k::Camera& camera, k::DevicePtr<const uint32_t> ids, uint32_t count,
                           k::OccluderGeometry& geometry, k::DevicePtr<float> depth);
    void adaptOccluderBudget(const FrameStats& stats);
    // The frustum items the HZM does not prove hidden, into out (ascending); returns how many.
    uint32_t hzmCull(const k::Camera& camera, const FrustumStage& frustum, k::DevicePtr<uint32_t> out);
    // A per-item record's part for frame's parity (lag 2; the whole record with lag 1).
    k::DevicePtr<uint32_t> lastVisible(uint64_t frame, k::DeviceArray<uint32_t>& record);
    void latePass(const k::Camera& camera, uint64_t frame, const FrustumStage& frustum, FrameStats& stats,
                  StageClock& clock);

    const DeviceScene& scene_;
    const PipelineOptions& options_;
    k::DeviceArray<uint8_t> occluded_;  // per frustum entry, the HZM test's answer
    // keep_visible: the frame + 1 each item was last found visible (0 = never), the frustum
    // items neither visible nor kept, and the HZM-visible ones (the later occluder candidates).
    k::DeviceArray<uint32_t> last_visible_, returned_;  // returned_: k::keepRecentlyVisible's
    k::DeviceArray<uint8_t> dropped_;
    k::DeviceArray<uint32_t> seen_;
    uint32_t seen_count_ = 0;
    // late_pass: the newly visible items (ids, their places in the frustum list, their second
    // test), the ones rastered, their geometry and depth buffer.
    k::DeviceArray<uint32_t> late_ids_, late_index_, late_occluders_;
    k::DeviceArray<uint8_t> late_occluded_;
    k::OccluderGeometry late_geometry_;
    k::DeviceArray<float> late_depth_;
    k::DeviceArray<float> weights_;
    k::DeviceArray<uint8_t> in_cos_;  // one byte per item: in the COS (without the hierarchy)
    k::DeviceArray<uint64_t> topk_keys_;
    k::DeviceArray<uint32_t> occluders_;  // AOS, then the PVS occluders
    uint32_t occluder_count_ = 0;
    double occluder_budget_ = 0;  // triangles of PVS occluders this frame may raster
    double raster_rate_ = 0;      // occluder triangles per ms, smoothed over the last frames (occluder_ms)
    k::PvsOccluderScratch pvs_occluder_scratch_;
    k::OccluderGeometry occluder_geometry_;
    k::DepthRasterScratch raster_scratch_;
    k::DeviceArray<float> occluder_keys_;  // sortFrontToBack's scratch
    k::DeviceArray<float> hzm_;
    // The first frames have no earlier PVS: the occluders then come from the frame culled once
    // with the AOS alone (bootstrap_pvs_), so that the first frame does not stream every item
    // the AOS leaves visible. candidates_: the union of the sources; leaf_candidates_: with the
    // hierarchy, that and the leaf children of its HLODs.
    k::DeviceArray<uint32_t> bootstrap_pvs_, candidates_, leaf_candidates_;
};

}  // namespace occ
