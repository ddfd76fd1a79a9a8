// SPDX-License-Identifier: MIT
#pragma once

#include "defragment.h"
#include "depth_raster.h"
#include "kernel_memory.h"
#include "pipeline/device_scene.h"
#include "pipeline/frame_stats.h"
#include "scan.h"
#include "stream_collect.h"
#include "view/camera.h"

#include "hzm.h"

#include <span>
#include <vector>

namespace occ {

// What a frame removes and simplifies: [PC12] is `Lod` (frustum culling + LOD); `OcLod` adds
// occlusion culling against the HZM (Peng & Cao 2013); `Full` draws every object in the frustum
// at full detail.
enum class CullMode { Full, Lod, OcLod };

// How the active arrays reach the device (Peng & Cao 2012, Table 1): with coherence, only what
// the last frame lacked (Alg. 3, plus our in-place update); without coherence, the whole active
// set gathered and copied each frame; no streaming, object by object.
enum class StreamMode { Coherent, NonCoherent, None };

struct PipelineOptions {
    uint32_t width = 512, height = 512;  // viewport, also the occlusion depth buffer's size
    CullMode mode = CullMode::OcLod;
    StreamMode stream = StreamMode::Coherent;
    uint32_t aos = 16;                   // active occluders chosen by Eq. 3 (top-K of the COS)
    // Beyond the paper: also raster the previous frame's largest visible objects, up to this
    // many full-detail triangles (0 = Eq. 3's AOS only). On the plant walk 30 000 triangles
    // raise the occluded share of the frustum's objects from 30 % to 67 % for about 2 ms of
    // rastering (docs/results.md), hence on by default. kAutoOccluderTriangles (the default)
    // takes a quarter of the vertex budget N, at least 30 000: the occluders then grow with
    // what a frame draws. On the 10^8-triangle grid walk that is 1.5 M triangles, which lifts
    // what we cull from 25 % to over 80 % of what exact culling culls and saves more drawing
    // than it costs rastering.
    static constexpr uint64_t kAutoOccluderTriangles = ~uint64_t(0);
    static constexpr uint64_t kMinAutoOccluderTriangles = 30000;
    uint64_t pvs_occluder_triangles = kAutoOccluderTriangles;
    // Which frame's PVS supplies those: 1 = the last frame's (one rank); 2 = the one before,
    // as the 3-rank occlusion switch has it (its occluder rank works on frame i+1 while the
    // other culls frame i). runFrame with 2 gives the 3-rank answer in one process.
    uint32_t pvs_occluder_lag = 1;
    double budget = 0;                   // N, vertices per frame; 0 = 10 % of the scene's vertices
    // Beyond the paper: with coherent streaming, vertices a frame no longer draws stay resident
    // in the active arrays (an object that shrinks keeps its finer prefix, one that leaves the
    // PVS keeps its block) for this many frames, so LOD oscillation and objects that come back
    // cost no streaming; resident vertices are capped at resident_factor x the budget.
    uint32_t retain_frames = 60;
    double resident_factor = 2.0;
    // Beyond the papers: an object that stays in the PVS keeps last frame's vertex count when
    // Eq. 1's new count is within this fraction of it (and the budget allows), so LODs do not
    // flicker by a few vertices every frame: fewer visible-set changes to send, stream and
    // reform. 0 = Eq. 1's count every frame.
    float lod_hysteresis = 0.1f;
    float alpha = 3.0f;                  // Eq. 1 exponent
    float pet = 1.0f;                    // pixel error threshold
};

// The one-rank pipeline: every stage of a frame over the kernels (DESIGN.md, "One frame").
// Keeps the previous frame's active set and layout for coherent streaming.
class Pipeline {
public:
    // file must outlive the pipeline. Throws UsageError for impossible options.
    Pipeline(const OssFile& file, const PipelineOptions& options);

    // Runs every stage for one camera (drawing is the display's job) and returns the counts and
    // the time of each stage: occluderPass, cullPass and streamPass in a row.
    FrameStats runFrame(const CameraPose& pose, uint64_t frame);

    // The stages in three groups, the occlusion-switch roles (roles/), each adding its counts
    // and stage times to `stats`:
    // OR: frustum culling for `pose`, the occluders (Eq. 3's AOS and the largest objects of
    // occluder_source, a PVS of an earlier frame, ascending ids), their depth raster and the
    // HZM. Nothing in modes full and lod.
    void occluderPass(const CameraPose& pose, std::span<const uint32_t> occluder_source, FrameStats& stats);
    // HC: frustum culling (reused when the last occluderPass had this pose), the HZM test
    // against the HZM of the last occluderPass (oc+lod) and LOD selection: visibleObjects()
    // and visibleLodVertices(). previous_lod: the last frame's visible set as (id, vertex
    // count) pairs, ascending ids, for the LOD hysteresis (empty: none).
    void cullPass(const CameraPose& pose, FrameStats& stats,
                  std::span<const std::pair<uint32_t, uint32_t>> previous_lod = {});
    // RVG: the visible set a cullPass elsewhere chose (ascending ids with their Eq. 1 vertex
    // counts, 0 = not drawn); throws std::invalid_argument for an entry that is not a valid
    // LOD (ids unsorted or >= object count, count above the object's vertices or below its q).
    void setVisible(std::span<const uint32_t> ids, std::span<const uint32_t> vertex_counts);
    // RVG: frustum culling only, for the display's measurements (frustumObjects()).
    void frustumPass(const CameraPose& pose, FrameStats& stats);
    // Whether frustumObjects() are the last frustumPass's for exactly this pose.
    bool frustumIsFor(const CameraPose& pose) const;
    // RVG: layout, streaming, defragmentation and reformation of the visible set.
    void streamPass(uint64_t frame, FrameStats& stats);

    const PipelineOptions& options() const { return options_; }
    // Changes what the next frames remove and simplify (the window's 1/2/3 keys).
    void setMode(CullMode mode) { options_.mode = mode; }
    CullMode mode() const { return options_.mode; }

    // Results of the last frame, valid until the next runFrame.
    const std::vector<uint32_t>& visibleObjects() const { return pvs_; }  // PVS, ascending ids
    // Blocks of the active arrays: resident vertex / triangle counts, offsets, ids (ascending).
    const k::ActiveLayout& layout() const { return cur_; }
    // Per block of layout(): what this frame draws, a prefix of the resident block (0 = resident
    // only). Block j's triangles to draw are indices()[3 * triangle_offset[j], + 3 * drawTriangles()[j]).
    const uint32_t* drawVertices() const { return layouts_[cur_index_ ^ 1].draw_vc.data(); }
    const uint32_t* drawTriangles() const { return layouts_[cur_index_ ^ 1].draw_tc.data(); }
    const glm::vec3* activeVertices() const { return active_.vertices.data(); }
    const uint32_t* activeTriangles() const { return active_.triangles.data(); }
    const uint32_t* indices() const { return indices_.data(); }     // 3 * layout().triangle_total
    const float* occluderDepth() const { return hzm_.data(); }      // W x H, level 0 of the HZM
    // Every level of the HZM (meaningful after an oc+lod frame).
    k::HzmLevels hzmLevels() const;
    // Objects in the frustum, ascending ids.
    std::span<const uint32_t> frustumObjects() const { return {frustum_ids_.data(), frustum_count_}; }
    // Eq. 1's vertex count for each PVS object, in visibleObjects() order (0 = below the PET).
    std::span<const uint32_t> visibleLodVertices() const { return {pvs_vc_.data(), pvs_.size()}; }
    const std::vector<uint32_t>& occluders() const { return occluders_; }
    const DeviceScene& scene() const { return scene_; }
    double budget() const { return budget_; }

private:
    struct LayoutArrays {
        k::KernelArray<uint32_t> ids, vc, tc, draw_vc, draw_tc;
        k::KernelArray<uint64_t> voff, toff;
    };
    void keepSimilarLods(std::span<const std::pair<uint32_t, uint32_t>> previous);
    void chooseOccluders(const k::Camera& camera, std::span<const uint32_t> occluder_source);
    void rasterOccluders(const k::Camera& camera, FrameStats& stats);
    void buildLayout(uint64_t frame, FrameStats& stats);

    const OssFile& file_;
    PipelineOptions options_;
    DeviceScene scene_;
    double budget_ = 0;
    k::HostGeometry host_{};

    k::KernelArray<uint8_t> in_frustum_, occluded_;
    k::KernelArray<uint32_t> frustum_ids_;
    uint32_t frustum_count_ = 0;
    k::KernelArray<float> weights_;
    k::KernelArray<uint32_t> aos_;
    std::vector<uint32_t> occluders_, pvs_;
    std::vector<uint32_t> pvs_history_[2];  // the PVS of the last frame and of the one before
    std::vector<std::pair<uint32_t, uint32_t>> last_lod_;  // runFrame's last visible set with counts
    CameraPose frustum_pose_{};
    bool has_frustum_pose_ = false;
    k::KernelArray<glm::vec3> raster_positions_;
    k::KernelArray<uint32_t> raster_triangles_;
    k::KernelArray<uint8_t> raster_edge_flags_;  // per triangle of raster_triangles_
    k::KernelArray<uint32_t> raster_neighbours_;  // 3 per triangle of raster_triangles_
    k::DepthRasterScratch raster_scratch_;
    k::KernelArray<float> hzm_;
    k::KernelArray<uint32_t> pvs_vc_, pvs_tc_;  // Eq. 1's choice for each PVS object
    std::vector<uint32_t> resident_vc_;         // per object, vertices in the active arrays
    std::vector<uint64_t> last_drawn_;          // per object, last frame it was drawn

    LayoutArrays layouts_[2];
    uint32_t cur_index_ = 0;
    uint32_t layout_count_ = 0;
    k::ActiveLayout prev_{}, cur_{};
    k::StagingBuffers staging_;
    k::ActiveArrays active_;
    k::KernelArray<uint32_t> indices_;
};

CullMode parseCullMode(const std::string& s);      // "full", "lod", "oc+lod"
StreamMode parseStreamMode(const std::string& s);  // "sc", "snc", "ns"

}  // namespace occ
