// SPDX-License-Identifier: MIT
#include "pipeline/pipeline.h"

#include "frustum_cull.h"
#include "hzm.h"
#include "hzm_build.h"
#include "hzm_test.h"
#include "lod_select.h"
#include "occluder_weight.h"
#include "reform.h"
#include "scene/errors.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <execution>
#include <numeric>

namespace occ {

CullMode parseCullMode(const std::string& s) {
    if (s == "full") return CullMode::Full;
    if (s == "lod") return CullMode::Lod;
    if (s == "oc+lod") return CullMode::OcLod;
    throw UsageError("--mode " + s + ": expected full, lod or oc+lod");
}

StreamMode parseStreamMode(const std::string& s) {
    if (s == "sc") return StreamMode::Coherent;
    if (s == "snc") return StreamMode::NonCoherent;
    if (s == "ns") return StreamMode::None;
    throw UsageError("--stream " + s + ": expected sc, snc or ns");
}

Pipeline::Pipeline(const OssFile& file, const PipelineOptions& options) : file_(file), options_(options) {
    if (options.width == 0 || options.height == 0 || options.width > 16384 || options.height > 16384)
        throw UsageError("--size: width and height must be in [1, 16384]");
    if (options.aos > 65536) throw UsageError("--aos " + std::to_string(options.aos) + " is more than 65536 occluders");
    if (!(options.alpha > 1.0f)) throw UsageError("--alpha must be > 1");
    if (!(options.pet >= 0.0f)) throw UsageError("--pet must be >= 0");
    if (!(options.budget >= 0.0)) throw UsageError("--budget must be >= 0");
    if (!(options.lod_hysteresis >= 0.0f && options.lod_hysteresis < 1.0f))
        throw UsageError("--lod-hysteresis must be in [0, 1)");
    if (options.pvs_occluder_lag < 1 || options.pvs_occluder_lag > 2)
        throw UsageError("--pvs-occluder-lag must be 1 or 2");

    scene_ = DeviceScene::upload(file);
    const uint32_t n = scene_.object_count;
    double scene_vertices = 0;
    for (uint32_t i = 0; i < n; ++i) scene_vertices += scene_.host_objects[i].vertex_count;
    budget_ = options.budget > 0 ? options.budget : 0.1 * scene_vertices;
    if (options_.pvs_occluder_triangles == PipelineOptions::kAutoOccluderTriangles)
        options_.pvs_occluder_triangles =
            std::max(PipelineOptions::kMinAutoOccluderTriangles, uint64_t(std::llround(budget_ / 4)));
    host_ = {file.allPositions().data(), file.allTriangles().data(), scene_.host_vertex_first.data(),
             scene_.host_triangle_first.data(), scene_.host_objects.data()};

    // Every array a frame needs, sized once for the worst case (every object in the frustum,
    // visible and drawn): no frame allocates but the ones whose sizes depend on geometry.
    const size_t room = std::max<uint32_t>(1, n);
    in_frustum_.resize(room);
    occluded_.resize(room);
    frustum_ids_.resize(room);
    weights_.resize(std::max<uint32_t>(1, scene_.cos_count));
    occluders_.resize(room);
    occluder_source_.resize(room);
    pvs_occluder_scratch_.taken.resize(room);
    k::deviceMemset(pvs_occluder_scratch_.taken.ptr(), 0, room);
    hzm_.resize(size_t(k::hzmTotalTexels(options.width, options.height)));
    pvs_device_.resize(room);
    pvs_vc_device_.resize(room);
    pvs_tc_device_.resize(room);
    for (HostLayoutArrays& l : host_layouts_) {
        for (std::vector<uint32_t>* a : {&l.ids, &l.vc, &l.tc, &l.draw_vc, &l.draw_tc}) a->resize(room);
        l.voff.resize(room);
        l.toff.resize(room);
    }
    for (DeviceLayoutArrays& l : device_layouts_) {
        for (k::DeviceArray<uint32_t>* a : {&l.ids, &l.vc, &l.tc, &l.draw_vc}) a->resize(room);
        l.voff.resize(room);
        l.toff.resize(room);
    }
    pvs_vc_.resize(n);
    pvs_tc_.resize(n);
    resident_vc_.assign(n, 0);
    last_drawn_.assign(n, 0);
}

void Pipeline::lendActiveArrays(k::BufferProvider& lender) {
    lender.beginDeviceWrites();
    for (uint32_t b = 0; b < 2; ++b)
        active_.vertices.buffers[b].lendFrom(&lender, kActiveVertexSlot + b,
                                             b == active_.vertices.current ? active_.vertices.count : 0);
    indices_.lendFrom(&lender, kIndexSlot, index_count_);
    lender.endDeviceWrites();
    lender_ = &lender;
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
void Pipeline::chooseOccluders(const k::Camera& camera, std::span<const uint32_t> occluder_source) {
    uint32_t aos = 0;
    if (scene_.cos_count > 0 && options_.aos > 0) {
        k::occluderWeight(scene_.objects.ptr(), scene_.cos.ptr(), scene_.cos_count, in_frustum_.ptr(), camera,
                          weights_.ptr());
        aos = k::selectTopK(scene_.cos.ptr(), weights_.ptr(), scene_.cos_count, options_.aos, occluders_.ptr(),
                            topk_keys_);
    }
    uint32_t extra = 0;
    if (options_.pvs_occluder_triangles > 0 && !occluder_source.empty()) {
        const uint32_t count = uint32_t(std::min<size_t>(occluder_source.size(), scene_.object_count));
        k::copyToDevice(occluder_source_.ptr(), occluder_source.data(), count);
        extra = k::selectPvsOccluders(scene_.objects.ptr(), occluder_source_.ptr(), count, in_frustum_.ptr(), camera,
                                      occluders_.ptr(), aos, options_.pvs_occluder_triangles, pvs_occluder_scratch_,
                                      occluders_.ptr() + aos);
    }
    occluder_count_ = aos + extra;
}

void Pipeline::rasterOccluders(const k::Camera& camera, FrameStats& stats) {
    // Occluders are rastered at full detail, in world space, from the resident meshes.
    k::gatherOccluders(scene_.objects.ptr(), scene_.world.ptr(), scene_.meshes(), occluders_.ptr(), occluder_count_,
                       occluder_geometry_);
    const k::OccluderGeometry& g = occluder_geometry_;
    k::depthRaster(g.positions.ptr(), g.triangles.ptr(), uint32_t(g.triangle_total), g.edge_flags.ptr(),
                   g.edge_neighbours.ptr(), camera, hzm_.ptr(), raster_scratch_);
    stats.aos_size = occluder_count_;
    stats.occluder_triangles = g.triangle_total;
}

// The blocks of this frame's active arrays: every object drawn now, and (coherent streaming)
// every object still resident from recent frames, with at least the vertices it draws.
void Pipeline::buildLayout(uint64_t frame, FrameStats& stats) {
    HostLayoutArrays& l = host_layouts_[cur_index_];
    const bool retain = options_.stream == StreamMode::Coherent && options_.retain_frames > 0;
    const uint32_t* prev_ids = prev_host_.objects;
    uint32_t a = 0, b = 0, out = 0;
    uint64_t resident = 0;
    const auto residentTriangles = [&](uint32_t id, uint32_t vc) {
        return scene_.lodTriangles(scene_.host_objects[id].mesh, vc);
    };
    // Merge last frame's resident ids with this frame's PVS (both ascending).
    while (a < prev_host_.count || b < pvs_.size()) {
        const uint32_t pa = a < prev_host_.count ? prev_ids[a] : UINT32_MAX;
        const uint32_t pb = b < pvs_.size() ? pvs_[b] : UINT32_MAX;
        const uint32_t id = std::min(pa, pb);
        uint32_t draw = 0, draw_tc = 0;
        if (pb == id) {
            draw = pvs_vc_[b];
            draw_tc = pvs_tc_[b];
            ++b;
        }
        if (pa == id) ++a;
        if (draw > 0) last_drawn_[id] = frame;
        uint32_t keep = draw;
        if (retain && resident_vc_[id] > draw && frame - last_drawn_[id] <= options_.retain_frames)
            keep = resident_vc_[id];
        if (keep == 0) {
            resident_vc_[id] = 0;
            continue;
        }
        l.ids[out] = id;
        l.vc[out] = keep;
        l.tc[out] = keep == draw ? draw_tc : residentTriangles(id, keep);
        l.draw_vc[out] = draw;
        l.draw_tc[out] = draw_tc;
        resident += keep;
        stats.active_vertices += draw;
        stats.active_triangles += draw_tc;
        stats.objects_drawn += draw > 0;
        ++out;
    }
    // Over the memory cap, residency starts again from what this frame draws.
    if (retain && double(resident) > options_.resident_factor * budget_) {
        uint32_t kept = 0;
        for (uint32_t j = 0; j < out; ++j) {
            if (l.draw_vc[j] == 0) continue;
            l.ids[kept] = l.ids[j];
            l.vc[kept] = l.draw_vc[j];
            l.tc[kept] = l.draw_tc[j];
            l.draw_vc[kept] = l.draw_vc[j];
            l.draw_tc[kept] = l.draw_tc[j];
            ++kept;
        }
        out = kept;
    }
    std::fill(resident_vc_.begin(), resident_vc_.end(), 0u);
    for (uint32_t j = 0; j < out; ++j) resident_vc_[l.ids[j]] = l.vc[j];
    layout_count_ = out;
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

void Pipeline::frustumPass(const CameraPose& pose, FrameStats& stats) {
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    const uint32_t n = scene_.object_count;
    const k::Frustum frustum = k::frustumFromViewProj(camera.view_proj);
    frustum_count_ = k::frustumCull(scene_.objects.ptr(), n, frustum, in_frustum_.ptr(), frustum_ids_.ptr());
    frustum_pose_ = pose;
    has_frustum_pose_ = true;
    clock.lap(Stage::FrustumCull);
}

bool Pipeline::frustumIsFor(const CameraPose& pose) const {
    return has_frustum_pose_ && std::memcmp(&frustum_pose_, &pose, sizeof pose) == 0;
}

void Pipeline::occluderPass(const CameraPose& pose, std::span<const uint32_t> occluder_source, FrameStats& stats) {
    if (options_.mode != CullMode::OcLod) return;
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    chooseOccluders(camera, occluder_source);
    clock.lap(Stage::OccluderSelect);
    rasterOccluders(camera, stats);
    clock.lap(Stage::DepthRaster);
    k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
}

void Pipeline::cullPass(const CameraPose& pose, FrameStats& stats,
                        std::span<const std::pair<uint32_t, uint32_t>> previous_lod) {
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    const uint32_t in_count = frustum_count_;
    stats.objects_in_frustum = in_count;
    uint32_t count = in_count;
    k::DevicePtr<const uint32_t> pvs = frustum_ids_.ptr();
    if (options_.mode == CullMode::OcLod) {
        k::hzmTest(scene_.objects.ptr(), frustum_ids_.ptr(), in_count, camera, hzmLevels(), occluded_.ptr());
        count = k::compactSelected(frustum_ids_.ptr(), occluded_.ptr(), in_count, 0, pvs_device_.ptr());
        pvs = pvs_device_.ptr();
        clock.lap(Stage::HzmTest);
    }
    stats.objects_visible = count;
    stats.objects_occluded = in_count - count;
    // The visible set comes back to the host: the network sends it and the layout is built from it.
    pvs_.resize(count);
    k::copyToHost(pvs_.data(), pvs, count);

    if (options_.mode == CullMode::Full) {
        for (uint32_t j = 0; j < count; ++j) {
            pvs_vc_[j] = scene_.host_objects[pvs_[j]].vertex_count;
            pvs_tc_[j] = scene_.host_objects[pvs_[j]].triangle_count;
        }
    } else {
        const k::LodParams params{float(budget_), options_.alpha, options_.pet};
        k::lodSelect(scene_.objects.ptr(), pvs, count, camera, params, scene_.map_first.ptr(), scene_.maps.ptr(),
                     pvs_vc_device_.ptr(), pvs_tc_device_.ptr(), lod_shares_);
        k::copyToHost(pvs_vc_.data(), pvs_vc_device_.ptr(), count);
        k::copyToHost(pvs_tc_.data(), pvs_tc_device_.ptr(), count);
        if (options_.lod_hysteresis > 0) keepSimilarLods(previous_lod);
    }
    clock.lap(Stage::LodSelect);
}

// For each PVS object that was visible last frame with a vertex count p, keeps p where Eq. 1's
// new count v is within lod_hysteresis * p of it (both are valid LODs: p >= q). Kept counts
// that raise the total above max(N, what Eq. 1 chose) are given back, largest raise first.
void Pipeline::keepSimilarLods(std::span<const std::pair<uint32_t, uint32_t>> previous) {
    const uint32_t count = uint32_t(pvs_.size());
    double total = 0, chosen = 0;
    std::vector<std::pair<uint32_t, uint32_t>> raised;  // (p - v, j) where p > v was kept
    std::vector<uint32_t> eq1(count);
    size_t i = 0;
    for (uint32_t j = 0; j < count; ++j) {
        const uint32_t v = pvs_vc_[j];
        eq1[j] = v;
        chosen += v;
        while (i < previous.size() && previous[i].first < pvs_[j]) ++i;
        if (v > 0 && i < previous.size() && previous[i].first == pvs_[j]) {
            const uint32_t p = previous[i].second;
            if (p > 0 && p != v && std::abs(double(v) - double(p)) <= options_.lod_hysteresis * double(p)) {
                pvs_vc_[j] = p;
                if (p > v) raised.emplace_back(p - v, j);
            }
        }
        total += pvs_vc_[j];
    }
    const double limit = std::max(budget_, chosen);
    if (total > limit) {
        std::sort(raised.begin(), raised.end(), std::greater<>());
        for (const auto& [extra, j] : raised) {
            if (total <= limit) break;
            pvs_vc_[j] = eq1[j];
            total -= extra;
        }
    }
    for (uint32_t j = 0; j < count; ++j)
        if (pvs_vc_[j] != eq1[j]) pvs_tc_[j] = scene_.lodTriangles(scene_.host_objects[pvs_[j]].mesh, pvs_vc_[j]);
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
}

void Pipeline::streamPass(uint64_t frame, FrameStats& stats) {
    StageClock clock(stats);
    stats.frame = frame;
    stats.budget_vertices = uint64_t(budget_);
    stats.objects_visible = pvs_.size();
    buildLayout(frame, stats);
    HostLayoutArrays& l = host_layouts_[cur_index_];
    DeviceLayoutArrays& d = device_layouts_[cur_index_];
    const uint32_t blocks = layout_count_;
    // The host's copy of the layout, for the gather and the display.
    uint64_t vertex_total = 0, triangle_total = 0;
    for (uint32_t j = 0; j < blocks; ++j) {
        l.voff[j] = vertex_total;
        l.toff[j] = triangle_total;
        vertex_total += l.vc[j];
        triangle_total += l.tc[j];
    }
    cur_host_ = {l.ids.data(), l.vc.data(), l.tc.data(), l.voff.data(), l.toff.data(), blocks, vertex_total, triangle_total};
    // The device's: the per-block counts cross the bus, the offsets are scanned there.
    k::copyToDevice(d.ids.ptr(), l.ids.data(), blocks);
    k::copyToDevice(d.vc.ptr(), l.vc.data(), blocks);
    k::copyToDevice(d.tc.ptr(), l.tc.data(), blocks);
    k::copyToDevice(d.draw_vc.ptr(), l.draw_vc.data(), blocks);
    k::exclusiveScan(d.vc.ptr(), blocks, d.voff.ptr());
    k::exclusiveScan(d.tc.ptr(), blocks, d.toff.ptr());
    cur_ = {d.ids.ptr(), d.vc.ptr(), d.tc.ptr(), d.voff.ptr(), d.toff.ptr(), blocks, vertex_total, triangle_total};
    stats.resident_vertices = vertex_total;
    stats.resident_triangles = triangle_total;
    clock.lap(Stage::Scan);
    k::StreamCounts sent;
    k::DefragmentCounts moved;
    // The active arrays may be the display's buffers: the kernels write them only in here.
    if (lender_) lender_->beginDeviceWrites();
    if (options_.stream == StreamMode::None) {
        sent = k::streamObjectByObject(cur_host_, host_, active_);
        clock.lap(Stage::StreamCollect);
        clock.lap(Stage::Defragment);
    } else {
        // Without coherence nothing of the last frame is reused: the previous layout is empty.
        const bool coherent = options_.stream == StreamMode::Coherent;
        sent = k::streamCollect(coherent ? prev_host_ : k::HostLayout{}, cur_host_, host_, staging_);
        clock.lap(Stage::StreamCollect);
        moved = k::defragment(coherent ? prev_ : k::ActiveLayout{}, cur_, staging_, active_);
        clock.lap(Stage::Defragment);
    }
    stats.streamed_vertices = sent.vertices;
    stats.streamed_triangles = sent.triangles;
    stats.streamed_bytes = sent.bytes();
    stats.moved_bytes = (moved.vertices_moved + moved.vertices_bounced) * sizeof(glm::vec3) +
                        (moved.triangles_moved + moved.triangles_bounced) * 3 * sizeof(uint32_t);

    // Beyond the paper: a frame that draws exactly what the last one drew, from blocks that did
    // not move, has last frame's index buffer already; only the checks above cost anything.
    const HostLayoutArrays& p = host_layouts_[cur_index_ ^ 1];
    const auto same = [&](const auto& a, const auto& b) {
        return std::memcmp(a.data(), b.data(), size_t(blocks) * sizeof(a[0])) == 0;
    };
    const bool unchanged = options_.stream == StreamMode::Coherent && moved.vertices_moved == 0 &&
                           moved.vertices_bounced == 0 && moved.vertices_copied == 0 && moved.triangles_moved == 0 &&
                           moved.triangles_bounced == 0 && moved.triangles_copied == 0 && prev_host_.count == blocks &&
                           index_count_ == 3 * triangle_total && same(l.ids, p.ids) && same(l.vc, p.vc) &&
                           same(l.draw_vc, p.draw_vc);
    if (!unchanged) {
        indices_.reserve(size_t(3 * triangle_total));
        k::reform(cur_, scene_.objects.ptr(), scene_.vertex_first.ptr(), scene_.ecol.ptr(), active_.triangles.data(),
                  indices_.ptr(), d.draw_vc.ptr());
        index_count_ = 3 * triangle_total;
    }
    if (lender_) lender_->endDeviceWrites();
    clock.lap(Stage::Reform);

    prev_ = cur_;
    prev_host_ = cur_host_;
    cur_index_ ^= 1;
}

FrameStats Pipeline::runFrame(const CameraPose& pose, uint64_t frame) {
    FrameStats stats;
    stats.frame = frame;
    const k::BusCounters bus_before = k::busCounters();
    // The PVS `pvs_occluder_lag` frames back supplies this frame's extra occluders.
    occluderPass(pose, pvs_history_[options_.pvs_occluder_lag - 1], stats);
    cullPass(pose, stats, last_lod_);
    last_lod_.resize(pvs_.size());
    for (size_t j = 0; j < pvs_.size(); ++j) last_lod_[j] = {pvs_[j], pvs_vc_[j]};
    pvs_history_[1].swap(pvs_history_[0]);
    pvs_history_[0] = pvs_;
    streamPass(frame, stats);
    stats.bus_h2d_bytes = k::busCounters().h2d_bytes - bus_before.h2d_bytes;
    stats.bus_d2h_bytes = k::busCounters().d2h_bytes - bus_before.d2h_bytes;
    return stats;
}


}  // namespace occ
