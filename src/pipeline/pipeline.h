// SPDX-License-Identifier: MIT
#pragma once

#include "block_layout.h"
#include "device_memory.h"
#include "draw_commands.h"
#include "hzm.h"
#include "occluder_gather.h"
#include "pipeline/cut_stage.h"
#include "pipeline/device_scene.h"
#include "pipeline/frame_stats.h"
#include "pipeline/frustum_stage.h"
#include "pipeline/lod_stage.h"
#include "pipeline/occlusion_stage.h"
#include "pipeline/stream_stage.h"
#include "pipeline/visible_history.h"
#include "view/camera.h"

#include <memory>
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

// How a frame's LODs are chosen: Eq. 1 under the vertex budget N (Peng & Cao), or the coarsest
// level of each object whose simplification error projects to at most tau pixels (SWITCH and
// CHLOD's rule; no budget, the error bounds the picture).
enum class LodRule { Budget, Error };

enum class OccluderRaster { Masked, Exact };

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
    // > 0: that budget adapts to the raster, frame by frame, so that gathering and rastering
    // the occluders takes about this many milliseconds: the next frame's budget is the
    // smoothed triangles per ms of the last frames times occluder_ms, within
    // [kMinAdaptiveOccluderTriangles, kMaxAdaptiveOccluderTriangles] (pvs_occluder_triangles
    // is the first frame's). Occluders stay full detail. Timing makes the choice differ from
    // run to run, so recorded-path measurements leave it off (0, the default) unless asked.
    double occluder_ms = 0;
    static constexpr uint64_t kMinAdaptiveOccluderTriangles = 10000;
    static constexpr uint64_t kMaxAdaptiveOccluderTriangles = 16000000;
    // Which frame's PVS supplies those: 1 = the last frame's (one rank); 2 = the one before,
    // as the 3-rank occlusion switch has it (its occluder rank works on frame i+1 while the
    // other culls frame i). runFrame with 2 gives the 3-rank answer in one process.
    uint32_t pvs_occluder_lag = 1;
    // N, vertices per frame. 0 (the default) follows the screen, not the scene: kVerticesPerPixel
    // for each pixel of the view, at most the scene's vertices, so a small model draws at full
    // detail and a massive one is bounded by what a frame of this size can show (about two
    // triangles per pixel). budget_share > 0 takes that share of the scene's vertices instead
    // (the benchmarks' 10 %, as the papers size N).
    double budget = 0;
    double budget_share = 0;
    static constexpr double kVerticesPerPixel = 1.0;
    // Beyond the paper: with coherent streaming, vertices a frame no longer draws stay resident
    // in the active arrays (an object that shrinks keeps its finer prefix, one that leaves the
    // PVS keeps its block) for this many frames, so LOD oscillation and objects that come back
    // cost no streaming; resident vertices are capped at resident_factor x the budget.
    uint32_t retain_frames = 60;
    double resident_factor = 2.0;
    // Beyond the papers: an object that stays in the PVS keeps last frame's vertex count when
    // Eq. 1's new count is within this fraction of it (and the budget allows), so LODs do not
    // flicker by a few vertices every frame: fewer visible-set changes to send, stream and
    // reform. With a hierarchy, a level raised to the error bound goes on up to the next of
    // levels this fraction apart (k::levelOnRaiseGrid; no state between frames): on the 10^6
    // plant's orbit 57 k triangles reformed per frame instead of 682 k, for 11 % more drawn.
    // 0 = Eq. 1's count every frame and raised levels at the bound.
    float lod_hysteresis = 0.1f;
    // Beyond the papers, after CHC++'s "assumed visible" (k::keepRecentlyVisible): in oc+lod an
    // object that came back into view after a gap of at most this many frames stays in the
    // visible set through its next such gaps while it is in the frustum, so the cracks a
    // conservative raster leaves between occluders, which open and close as the camera moves,
    // do not make it flicker (0 = off; not with the hierarchy). Objects that simply go out of
    // sight are dropped at once. Only what the HZM test found visible becomes a later frame's
    // occluder. 2 by default: the flicker is mostly a two-frame cycle (docs/results.md).
    uint32_t keep_visible = kDefaultKeepVisible;
    static constexpr uint32_t kDefaultKeepVisible = 2;
    // Beyond Peng & Cao, niagara's two-phase culling: in oc+lod (without the hierarchy), when at
    // least kLatePassMinObjects objects the HZM test finds visible were visible in neither of the
    // two frames before (whose visible sets gave this frame's occluders: a turn, a door opened,
    // a jump), the best of them within the occluder budget are rastered too, merged into the
    // depth buffer, the HZM rebuilt and those objects tested again. A turn's first frame then
    // draws and streams what it shows, not everything the old occluders cannot hide.
    bool late_pass = true;
    static constexpr uint32_t kLatePassMinObjects = 16;
    float alpha = 3.0f;                  // Eq. 1 exponent
    float pet = 1.0f;                    // pixel error threshold
    LodRule lod = LodRule::Budget;
    float tau = 1.0f;                    // LodRule::Error: pixels of simplification error allowed (> 0)
    // oc+lod: weigh each visible object by the share of its image the HZM leaves visible
    // (k::hzmVisibleShare): Eq. 1 spends on what shows, the error rule allows tau / share
    // (Charalambos 2006's eps q / alpha). Off: the projected area, as Peng & Cao.
    bool visibility_weighted = false;
    // The occluders' depth raster: the masked one (k::maskedDepthRaster: coverage masks and a
    // conservative depth per 8 x 4 subtile) or the exact one (k::depthRaster: a depth per pixel).
    // Exact by default: the masked one is not faster yet on our occluder sets and culls less
    // (docs/results.md, "A masked occluder raster").
    OccluderRaster raster = OccluderRaster::Exact;
    // Refine the file's object hierarchy (prep --hierarchy on) instead of testing every object:
    // each frame a cut of nodes, breadth-first from the root, a node tested against the frustum
    // (and in oc+lod the HZM) level by level. Items are then nodes: the visible set, LODs,
    // streaming and drawing work on node ids (DeviceScene). Mode full refines to the leaves.
    // The budget rule stops at a node whose own error (what its children gave up to make its
    // input) projects to at most tau pixels. The error rule draws a node where it fits within
    // tau (its own error plus its HLOD level's) and costs no more than its children's best
    // cuts, a draw counted as draw_cost triangles (with the visible share: error x q / alpha).
    bool hierarchy = false;
    // The error rule's cut: what one more draw costs, in triangles; 0 minimises triangles
    // alone. On the 10^5-object plant's orbit (docs/results.md) against every object on its
    // own: 0 drew 5.4x fewer items (5.7x fewer triangles), 8 9.5x (4.0x), 12 12.4x (3.2x),
    // 16 15.2x (2.7x), all within 0.4 dB.
    float draw_cost = kDefaultDrawCost;
    static constexpr float kDefaultDrawCost = 12.0f;
    // The error rule refines first to where a node's own error is within this share of what
    // may be given up there, then coarsens bottom-up wherever a node costs no more than its
    // children's cuts.
    static constexpr float kFineCutShare = 0.1f;
    // The budget rule may draw finer, never coarser (issue 49, item 4): with the hierarchy, the
    // cut at tau is refined again at half the tau, and so on down to tau / 2^kFinerCutSteps, as
    // long as the finer cut draws at most finer_cut_items items; the first that would draw more
    // is given up and the cut before it kept (one that would test over kFinerCutNodesPerItem
    // times as many nodes, drawn or hidden, is stopped before the level that would). A view
    // with few items (a walk inside the model) or most of them hidden spends its spare frame on
    // a finer picture; a view of the whole model keeps a cut near tau. Levels then keep within
    // the tau used (CutStage::tau). The frame's cost is in the items drawn (their levels,
    // streaming and reformation); testing a thousand nodes costs about 0.1 ms on this 2-core
    // machine (docs/results.md). 0: always tau.
    uint32_t finer_cut_items = 20000;
    static constexpr uint32_t kFinerCutNodesPerItem = 4;
    static constexpr int kFinerCutSteps = 3;
};

LodRule parseLodRule(const std::string& s);  // "budget" or "error"; OptionError("lod") otherwise

// The one-rank pipeline: every stage of a frame over the kernels (docs/architecture.md, "One frame").
// Keeps the previous frame's active set and layout for coherent streaming.
//
// Where the data lives: every per-object stage works on device arrays (frustum culling and its
// compaction, the occluders (Eq. 3 and the earlier PVS's) and their full-detail geometry, the
// depth raster, HZM, HZM test and PVS compaction, LOD selection and its hysteresis, the layout
// of the active arrays with its move, reform and draw lists). The host gets back the PVS with
// its LOD counts (for the network and the history), the blocks that lack geometry and a few
// totals; it gathers what those blocks lack from the mapped file and sends it over the bus.
// FrameStats' bus columns count every byte.
// Throws OptionError naming the first parameter outside its range (the viewport, the AOS, alpha,
// pet, the budget, the LOD hysteresis, the occluder lag, tau, the draw cost). Pipeline's
// constructor calls it; a command line calls it once the options are resolved, before it loads
// anything.
void validatePipelineOptions(const PipelineOptions& options);

// The device memory a pipeline's frames need beyond what its constructor allocates (the scene
// and the per-object arrays), counted before the first frame so that a GPU too small says so
// at once (issue 35): at least the active arrays for the vertices a frame may draw (every
// object's full detail in mode full, else the vertex budget, at most the scene's instanced
// vertices; triangles in the scene's proportion), each once in the heap, once in the index buffer
// (triangles) and once in the device staging of the first frame, which streams all of it; in
// oc+lod the occluder raster's lists for its triangle budget (at most the scene's); and the
// kernels' local memory CUDA reserves. A lower bound of what frames use (arrays grow by half
// again when short; defragmentation and the raster's bins take more): enough to refuse a
// configuration that cannot run, never one that could.
struct FrameMemoryNeed {
    uint64_t vertices = 0, triangles = 0;  // what the active arrays hold for a full frame
    uint64_t active_bytes = 0;
    uint64_t occluder_triangles = 0;  // 0 outside oc+lod
    uint64_t raster_bytes = 0;
    uint64_t local_bytes = 0;
    uint64_t total() const { return active_bytes + raster_bytes + local_bytes; }
    // What the bytes are, for requireDeviceMemory's message.
    std::string detail() const;
};
// `options` resolved (pvs_occluder_triangles not automatic), `budget` the LOD stage's vertices.
FrameMemoryNeed frameMemoryNeed(const OssFile& file, const PipelineOptions& options, double budget);

class Pipeline {
public:
    // file must outlive the pipeline. Throws UsageError for impossible options.
    Pipeline(const OssFile& file, const PipelineOptions& options);
    // The stages refer to the pipeline's scene and options: it stays where it was made.
    Pipeline(const Pipeline&) = delete;
    Pipeline& operator=(const Pipeline&) = delete;

    // The pipeline's steps of one frame, without messages: frustumPass, occluderPass, cullPass
    // and streamPass, as the frame loop (roles::runRanks) runs them on one rank. For the library's
    // tests and `bench pipeline`. Returns the frame's counts, stage times and bus bytes.
    // Drawing is the display's job.
    FrameStats runFrame(const CameraPose& pose, uint64_t frame);

    // The stages in three groups, the occlusion-switch roles (roles/), each adding its counts
    // and stage times to `stats`. The pipeline keeps one history of the visible sets of the
    // last frames (VisibleHistory): the ones its cullPass chose and those recorded as culled
    // elsewhere; every layout uses it for the occluders, the hysteresis and the deltas.
    // Frustum culling for `pose` (with the hierarchy in modes full and lod, also the cut): the
    // first step of a frame on the rank that culls it, and a display's for its measurements
    // when its pipeline did not cull the frame (frustumObjects()).
    // use Measure: a display's pass (it did not cull the frame); with the hierarchy in oc+lod it
    // refines the cut without occlusion, which Cull leaves to cullPass.
    enum class FrustumUse { Cull, Measure };
    void frustumPass(const CameraPose& pose, FrameStats& stats, FrustumUse use = FrustumUse::Cull);
    // OR of `frame`, after frustumPass(pose) (std::logic_error otherwise): the occluders (Eq. 3's
    // AOS and the largest objects of the PVS this pipeline chose for frame -
    // options().pvs_occluder_lag, if it culled that frame), their depth raster and the HZM.
    // Nothing in modes full and lod.
    void occluderPass(const CameraPose& pose, uint64_t frame, FrameStats& stats);
    // HC of `frame`, after frustumPass(pose) (std::logic_error otherwise): the HZM test against
    // the HZM of the last occluderPass (oc+lod) and LOD selection: visibleObjects()
    // and visibleLodVertices(), recorded in the history. The LOD hysteresis starts from the
    // history's set of frame - 1 (this pipeline's, or in the switch the other rank's).
    void cullPass(const CameraPose& pose, uint64_t frame, FrameStats& stats);
    // HC in the switch: the other culling rank's visible set of `frame`, rebuilt from its delta,
    // into the history (the next cullPass's hysteresis and delta base).
    void recordCulledElsewhere(uint64_t frame, VisibleSet set);
    // The history's visible set of `frame` (this pipeline's cullPass, or recorded), or null.
    const VisibleSet* culledSet(uint64_t frame) const { return history_.find(frame); }
    // RVG: the visible set a cullPass elsewhere chose (ascending ids with their Eq. 1 vertex
    // counts, 0 = not drawn); throws std::invalid_argument for an entry that is not a valid
    // LOD (ids unsorted or >= object count, count above the object's vertices or below its q).
    void setVisible(std::span<const uint32_t> ids, std::span<const uint32_t> vertex_counts);
    void setVisible(const VisibleSet& set);
    // RVG: layout, streaming, defragmentation and reformation of the visible set.
    void streamPass(uint64_t frame, FrameStats& stats);

    const PipelineOptions& options() const { return options_; }
    // Changes what the next frames remove and simplify (the window's 1/2/3 keys).
    void setMode(CullMode mode) { options_.mode = mode; }
    CullMode mode() const { return options_.mode; }

    // Results of the last frame, valid until the next runFrame. Host memory:
    const std::vector<uint32_t>& visibleObjects() const { return visible_.ids; }  // PVS, ascending ids
    // Eq. 1's vertex count for each PVS object, in visibleObjects() order (0 = below the PET).
    std::span<const uint32_t> visibleLodVertices() const { return {visible_.vertices.data(), visible_.ids.size()}; }
    // The layout of the active arrays, read back over the bus (for tests and measurements, not
    // part of a frame's work): one block per resident object, ascending ids, with what it holds
    // and what this frame draws of it (a prefix); blocks keep their place from frame to frame
    // and there may be gaps between them. Block j's triangles to draw are
    // indices()[3 * triangle_offset, + 3 * draw_triangle_count), local to the block: vertex v of
    // the block is activeVertices()[vertex_offset + v].
    std::vector<k::LayoutBlock> downloadLayout() const { return stream_->downloadLayout(); }
    uint32_t frustumCount() const { return frustum_->count(); }
    const DeviceScene& scene() const { return scene_; }
    double budget() const { return lod_->budget(); }
    // Device memory:
    // The active vertex array (vertexExtent() elements hold blocks) and the index buffer (3 x
    // triangleExtent() entries hold blocks).
    k::DevicePtr<const glm::vec3> activeVertices() const { return stream_->activeVertices(); }
    k::DevicePtr<const uint32_t> indices() const { return stream_->indices(); }
    uint64_t vertexExtent() const { return stream_->vertexExtent(); }
    uint64_t triangleExtent() const { return stream_->triangleExtent(); }
    // The blocks the last frame draws, drawCount() of them, for the display's draw commands.
    k::DevicePtr<const k::DrawBlock> drawBlocks() const { return stream_->drawBlocks(); }
    uint32_t drawCount() const { return stream_->drawCount(); }
    k::DevicePtr<const float> occluderDepth() const { return occlusion_->occluderDepth(); }  // W x H, level 0 of the HZM
    // The occluder triangles the last occluder raster drew (world space, near-clipped parts included).
    const k::OccluderGeometry& occluderGeometry() const { return occlusion_->occluderGeometry(); }
    // Every level of the HZM (meaningful after an oc+lod frame).
    k::HzmLevels hzmLevels() const { return occlusion_->hzmLevels(); }
    // Objects in the frustum, ascending ids, frustumCount() of them (with the hierarchy: the
    // nodes of the cut refined without occlusion; in oc+lod, after the cull, the cut and the
    // nodes its refinement found hidden, and before it the occluder candidates in the frustum,
    // in no particular order: no frame tests every item).
    k::DevicePtr<const uint32_t> frustumIds() const { return frustum_->ids(); }
    // Items the visible set, the deltas and the layout are over: objects, or nodes.
    uint32_t itemCount() const { return scene_.item_count; }
    // The last cut's nodes tested (all levels), with the hierarchy; 0 without.
    uint64_t nodesTested() const { return cut_ ? cut_->nodesTested() : 0; }
    // The tau the last cut was refined to (PipelineOptions::finer_cut_items), or options' tau.
    float cutTau() const { return cut_ ? cut_->tau() : options_.tau; }
    // From now on the active vertex array's two buffers and the index buffer live in the
    // lender's slots kActiveVertexSlot + 0 / 1 and kIndexSlot (the display's GL buffers), which
    // streamPass brackets with its write calls; what they hold is copied over once. The lender
    // must outlive the pipeline. activeVertexSlot(): the slot the last frame's vertices are in.
    static constexpr uint32_t kActiveVertexSlot = 0, kIndexSlot = 2;
    void lendActiveArrays(k::BufferProvider& lender) { stream_->lendActiveArrays(lender, kActiveVertexSlot, kIndexSlot); }
    uint32_t activeVertexSlot() const { return kActiveVertexSlot + stream_->currentVertexBuffer(); }
    // Read back over the bus, for measurements and debug pictures (not part of a frame's work):
    std::vector<uint32_t> downloadFrustumObjects() const { return frustum_->download(); }
    std::vector<uint32_t> downloadOccluders() const { return occlusion_->downloadOccluders(); }  // AOS first

private:
    void requireFrustum(const CameraPose& pose, const char* pass) const;

    // The frame's stages, each owning its device memory (src/pipeline/*_stage.h), and what
    // passes between them: the visible set and the history of the visible sets culled here.
    const OssFile& file_;
    PipelineOptions options_;
    DeviceScene scene_;
    std::unique_ptr<LodStage> lod_;
    std::unique_ptr<FrustumStage> frustum_;
    std::unique_ptr<OcclusionStage> occlusion_;
    std::unique_ptr<CutStage> cut_;  // with the hierarchy
    std::unique_ptr<StreamStage> stream_;
    VisibleItems visible_;
    VisibleHistory history_;
};

CullMode parseCullMode(const std::string& s);      // "full", "lod", "oc+lod"
StreamMode parseStreamMode(const std::string& s);  // "sc", "snc", "ns"

}  // namespace occ
