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
#include "util/number_format.h"

#include <xxhash.h>

#include <algorithm>
#include <cmath>
#include <chrono>
#include <cstring>
#include <execution>
#include <numeric>

namespace occ {

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

FrameMemoryNeed frameMemoryNeed(const OssFile& file, const PipelineOptions& options, double budget) {
    uint64_t all_vertices = 0, all_triangles = 0;
    const auto meshes = file.meshRecords();
    for (const oss::ObjectDisk& o : file.objects()) {
        all_vertices += meshes[o.mesh].vertex_count;
        all_triangles += meshes[o.mesh].triangle_count;
    }
    FrameMemoryNeed n;
    n.vertices = options.mode == CullMode::Full
                     ? all_vertices
                     : std::min<uint64_t>(all_vertices, uint64_t(std::max(0.0, std::floor(budget))));
    n.triangles = all_vertices ? uint64_t(double(n.vertices) * double(all_triangles) / double(all_vertices)) : 0;
    // vertices: heap + staging (12 bytes each); triangles: heap, index buffer, staging.
    n.active_bytes = n.vertices * 2 * sizeof(glm::vec3) + n.triangles * 3 * 3 * sizeof(uint32_t);
    if (options.mode == CullMode::OcLod) {
        n.occluder_triangles = std::min<uint64_t>(options.pvs_occluder_triangles, all_triangles);
        // Per triangle: its corners' positions (about one vertex each), its three indices,
        // edge flags and neighbours (OccluderGeometry), then drawn, drawn_ids and the scan of
        // boundary edges (DepthRasterScratch); the per-triangle setup is not counted.
        n.raster_bytes = n.occluder_triangles * (sizeof(glm::vec3) + 3 * sizeof(uint32_t) + 1 + 3 * sizeof(uint32_t) +
                                                 1 + 2 * sizeof(uint32_t));
    }
    n.local_bytes = k::kernelLocalMemoryBytes();
    return n;
}

std::string FrameMemoryNeed::detail() const {
    std::string t = "beyond the scene and its per-object arrays: active arrays for " + std::to_string(vertices) +
                    " vertices and " + std::to_string(triangles) + " triangles " + mebibytes(active_bytes);
    if (occluder_triangles)
        t += ", occluder raster of " + std::to_string(occluder_triangles) + " triangles " + mebibytes(raster_bytes);
    if (local_bytes) t += ", kernels' local memory " + mebibytes(local_bytes);
    return t;
}

Pipeline::Pipeline(const OssFile& file, const PipelineOptions& options) : file_(file), options_(options) {
    validatePipelineOptions(options);
    if (options.hierarchy && file.nodeCount() == 0)
        throw OptionError("hierarchy", "on: " + file.path() +
                                           " has no hierarchy (prepare it with occswitch prep --hierarchy on)");
    scene_ = DeviceScene::upload(file, options.hierarchy);
    lod_ = std::make_unique<LodStage>(file, scene_, options_);
    if (options_.pvs_occluder_triangles == PipelineOptions::kAutoOccluderTriangles)
        options_.pvs_occluder_triangles =
            std::max(PipelineOptions::kMinAutoOccluderTriangles, uint64_t(std::llround(lod_->budget() / 4)));
    if (!(options_.occluder_ms >= 0) || !std::isfinite(options_.occluder_ms))
        throw OptionError("occluder_ms", std::to_string(options_.occluder_ms) + ": must be a finite number >= 0");
    frustum_ = std::make_unique<FrustumStage>(scene_);
    occlusion_ = std::make_unique<OcclusionStage>(scene_, options_);
    if (scene_.nodes) cut_ = std::make_unique<CutStage>(scene_, options_, lod_->lodErrors(), lod_->itemScales());
    const bool coherent = options_.stream == StreamMode::Coherent;
    stream_ = std::make_unique<StreamStage>(
        file, scene_,
        StreamStage::Options{coherent, options_.stream == StreamMode::None, coherent ? options_.retain_frames : 0u,
                             options_.resident_factor * lod_->budget()});
    visible_.reserve(scene_.item_count);
    // What the frames need beyond what is allocated now: said before the first frame.
    const FrameMemoryNeed need = frameMemoryNeed(file, options_, lod_->budget());
    k::requireDeviceMemory(need.total(), "the frames of " + file.path(), need.detail());
}

void Pipeline::frustumPass(const CameraPose& pose, FrameStats& stats, FrustumUse use) {
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    frustum_->run(pose, camera);
    // With nodes the frustum's cut is the visible set of modes full and lod; oc+lod refines once,
    // against the HZM, in cullPass (its frustum list is then the cut and the nodes found hidden).
    if (cut_ && (options_.mode != CullMode::OcLod || use == FrustumUse::Measure)) {
        cut_->refine(camera, frustum_->frustum(), frustum_->flags(), nullptr);
        frustum_->replace(cut_->cut(), cut_->cutCount());
    }
    clock.lap(Stage::FrustumCull);
}

void Pipeline::requireFrustum(const CameraPose& pose, const char* pass) const {
    if (!frustum_->isFor(pose))
        throw std::logic_error(std::string("Pipeline::") + pass + ": frustumPass for this camera first");
}

void Pipeline::occluderPass(const CameraPose& pose, uint64_t frame, FrameStats& stats) {
    requireFrustum(pose, "occluderPass");
    if (options_.mode != CullMode::OcLod) return;
    const OccluderSources sources = history_.occluderSources(frame, options_.pvs_occluder_lag);
    occlusion_->buildHzm(toKernelCamera(pose, options_.width, options_.height), *frustum_, sources, stats, cut_.get());
}

void Pipeline::cullPass(const CameraPose& pose, uint64_t frame, FrameStats& stats) {
    requireFrustum(pose, "cullPass");
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    uint32_t count = frustum_->count();
    const k::DevicePtr<uint32_t> pvs = visible_.device_ids.ptr();
    if (options_.mode == CullMode::OcLod) {
        if (cut_) {
            const k::HzmLevels hzm = occlusion_->hzmLevels();
            cut_->refine(camera, frustum_->frustum(), frustum_->flags(), &hzm);
            frustum_->replace(cut_->frustumShare(), cut_->frustumShareCount());
            count = cut_->cutCount();
            k::copyOnDevice(pvs, cut_->cut(), count);
        } else {
            count = occlusion_->cull(camera, frame, *frustum_, pvs, stats, clock);
        }
        clock.lap(Stage::HzmTest);
    } else {
        k::copyOnDevice(pvs, frustum_->ids(), count);
    }
    const uint32_t in_count = frustum_->count();  // with nodes in oc+lod, the cut's share
    stats.objects_in_frustum = in_count;
    stats.objects_visible = count;
    stats.objects_occluded = in_count - std::min(in_count, count);
    // The visible set comes back to the host, for the network and the history; it stays on the
    // device for the layout.
    visible_.ids.resize(count);
    k::copyToHost(visible_.ids.data(), pvs, count);
    const bool weighted = options_.visibility_weighted && options_.mode == CullMode::OcLod;
    const k::HzmLevels hzm = occlusion_->hzmLevels();
    // The hysteresis starts from the last frame's set: this pipeline's, or the other switch rank's.
    lod_->select(camera, visible_, history_.lastFrameLods(frame), weighted ? &hzm : nullptr, cut_ ? cut_->tau() : options_.tau);

    std::vector<VisibleSet::Entry> entries(count);
    for (size_t j = 0; j < count; ++j) entries[j] = {visible_.ids[j], visible_.vertices[j]};
    VisibleHistory::Frame& h = history_.push(frame, VisibleSet(std::move(entries)));
    if (cut_ && cut_->fineCutCount() > 0) {
        // The coarsened cut's HLODs are no occluders: the fine cut's visible items before the
        // coarsening (the leaves among them) are the candidates.
        h.occluder_count = cut_->fineCutCount();
        h.occluders.growTo(std::max<uint32_t>(1, h.occluder_count));
        k::copyOnDevice(h.occluders.ptr(), cut_->fineCut(), h.occluder_count);
    } else {
        const bool kept = options_.mode == CullMode::OcLod && occlusion_->keepsRecords();
        h.occluder_count = kept ? occlusion_->seenCount() : count;
        h.occluders.growTo(std::max<uint32_t>(1, h.occluder_count));
        k::copyOnDevice(h.occluders.ptr(), kept ? occlusion_->seen() : k::DevicePtr<const uint32_t>(pvs),
                        h.occluder_count);
    }
    clock.lap(Stage::LodSelect);
}

void Pipeline::recordCulledElsewhere(uint64_t frame, VisibleSet set) { history_.push(frame, std::move(set)); }

void Pipeline::setVisible(const VisibleSet& set) {
    std::vector<uint32_t> ids(set.size()), counts(set.size());
    for (size_t j = 0; j < set.size(); ++j) ids[j] = set.entries()[j].first, counts[j] = set.entries()[j].second;
    setVisible(ids, counts);
}

void Pipeline::setVisible(std::span<const uint32_t> ids, std::span<const uint32_t> vertex_counts) {
    if (ids.size() != vertex_counts.size() || ids.size() > scene_.item_count)
        throw std::invalid_argument("Pipeline::setVisible: ids and vertex counts differ in size");
    for (size_t j = 0; j < ids.size(); ++j) {
        if ((j > 0 && ids[j] <= ids[j - 1]) || ids[j] >= scene_.item_count)
            throw std::invalid_argument("Pipeline::setVisible: entry " + std::to_string(j) + " is not a valid LOD");
        const k::ObjectInfo& o = scene_.host_objects[ids[j]];
        if (vertex_counts[j] > o.vertex_count || (vertex_counts[j] != 0 && vertex_counts[j] < o.q))
            throw std::invalid_argument("Pipeline::setVisible: entry " + std::to_string(j) + " is not a valid LOD");
    }
    visible_.ids.assign(ids.begin(), ids.end());
    for (size_t j = 0; j < ids.size(); ++j) {
        visible_.vertices[j] = vertex_counts[j];
        visible_.triangles[j] = scene_.lodTriangles(scene_.host_objects[ids[j]].mesh, vertex_counts[j]);
    }
    // The layout is built on the device: the visible set goes up.
    const size_t n = ids.size();
    k::copyToDevice(visible_.device_ids.ptr(), visible_.ids.data(), n);
    k::copyToDevice(visible_.device_vertices.ptr(), visible_.vertices.data(), n);
    k::copyToDevice(visible_.device_triangles.ptr(), visible_.triangles.data(), n);
}

void Pipeline::streamPass(uint64_t frame, FrameStats& stats) {
    stats.frame = frame;
    stats.budget_vertices = uint64_t(lod_->budget());
    stats.objects_visible = visible_.size();
    stream_->run(visible_.device(), visible_.ids, frame, stats);
}

FrameStats Pipeline::runFrame(const CameraPose& pose, uint64_t frame) {
    FrameStats stats;
    stats.frame = frame;
    BusWindow bus;
    frustumPass(pose, stats);
    // The PVS `pvs_occluder_lag` frames back supplies this frame's extra occluders.
    occluderPass(pose, frame, stats);
    cullPass(pose, frame, stats);
    streamPass(frame, stats);
    bus.take(stats);
    return stats;
}

}  // namespace occ
