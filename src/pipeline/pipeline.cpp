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
    for (uint32_t i = 0; i < n; ++i) scene_vertices += scene_.objects[i].vertex_count;
    budget_ = options.budget > 0 ? options.budget : 0.1 * scene_vertices;
    if (options_.pvs_occluder_triangles == PipelineOptions::kAutoOccluderTriangles)
        options_.pvs_occluder_triangles =
            std::max(PipelineOptions::kMinAutoOccluderTriangles, uint64_t(std::llround(budget_ / 4)));
    host_ = {file.allPositions().data(), file.allTriangles().data(), scene_.vertex_first.data(),
             scene_.triangle_first.data(), scene_.objects.data()};

    in_frustum_.resize(n);
    occluded_.resize(n);
    frustum_ids_.resize(n);
    weights_.resize(scene_.cos.size());
    aos_.resize(options.aos);
    hzm_.resize(size_t(k::hzmTotalTexels(options.width, options.height)));
    for (LayoutArrays& l : layouts_) {
        for (k::KernelArray<uint32_t>* a : {&l.ids, &l.vc, &l.tc, &l.draw_vc, &l.draw_tc}) a->resize(n);
        l.voff.resize(n);
        l.toff.resize(n);
    }
    pvs_vc_.resize(n);
    pvs_tc_.resize(n);
    resident_vc_.assign(n, 0);
    last_drawn_.assign(n, 0);
}

k::HzmLevels Pipeline::hzmLevels() const {
    k::HzmLevels levels;
    k::hzmLayout(options_.width, options_.height, levels);
    levels.data = hzm_.data();
    return levels;
}

void Pipeline::chooseOccluders(const k::Camera& camera, std::span<const uint32_t> occluder_source) {
    occluders_.clear();
    const uint32_t cos_count = uint32_t(scene_.cos.size());
    if (cos_count > 0 && options_.aos > 0) {
        k::occluderWeight(scene_.objects.data(), scene_.cos.data(), cos_count, in_frustum_.data(), camera,
                          weights_.data());
        const uint32_t chosen = k::selectTopK(scene_.cos.data(), weights_.data(), cos_count, options_.aos, aos_.data());
        occluders_.assign(aos_.data(), aos_.data() + chosen);
    }
    if (options_.pvs_occluder_triangles == 0) return;
    // The two-pass idea of occlusion-switches and GPU-driven renderers: what was visible last
    // frame is likely to occlude now. Most screen per rastered triangle first: (extent over
    // distance)^2 x compactness (Eq. 2: how solid the object is) / triangles.
    std::vector<std::pair<float, uint32_t>> ranked;
    for (uint32_t id : occluder_source) {
        if (!in_frustum_[id]) continue;
        const k::Aabb& b = scene_.objects[id].aabb;
        const glm::vec3 nearest = glm::clamp(camera.eye, b.min, b.max);
        const float distance = std::max(glm::length(nearest - camera.eye), camera.near_plane);
        const float size = glm::length(b.max - b.min) / distance;
        const float triangles = float(std::max(1u, scene_.objects[id].triangle_count));
        ranked.emplace_back(-size * size * scene_.objects[id].compactness / triangles, id);
    }
    std::sort(ranked.begin(), ranked.end());
    std::vector<uint8_t> taken(scene_.object_count, 0);
    for (uint32_t id : occluders_) taken[id] = 1;
    uint64_t triangles = 0;
    for (const auto& [negative_size, id] : ranked) {
        if (taken[id]) continue;
        const uint64_t t = scene_.objects[id].triangle_count;
        if (triangles + t > options_.pvs_occluder_triangles) continue;
        triangles += t;
        occluders_.push_back(id);
    }
}

void Pipeline::rasterOccluders(const k::Camera& camera, FrameStats& stats) {
    // Occluders are rastered at full detail, in world space.
    std::vector<uint64_t> vertex_base(occluders_.size() + 1, 0), triangle_base(occluders_.size() + 1, 0);
    for (size_t j = 0; j < occluders_.size(); ++j) {
        const k::ObjectInfo& o = scene_.objects[occluders_[j]];
        vertex_base[j + 1] = vertex_base[j] + o.vertex_count;
        triangle_base[j + 1] = triangle_base[j] + o.triangle_count;
    }
    raster_positions_.resize(vertex_base.back());
    raster_triangles_.resize(3 * triangle_base.back());
    raster_edge_flags_.resize(triangle_base.back());
    raster_neighbours_.resize(3 * triangle_base.back());
    std::vector<uint32_t> slots(occluders_.size());
    std::iota(slots.begin(), slots.end(), 0u);
    std::for_each(std::execution::par, slots.begin(), slots.end(), [&](uint32_t j) {
        const uint32_t id = occluders_[j];
        const k::ObjectInfo& o = scene_.objects[id];
        const glm::mat4& world = scene_.world[id];
        const glm::vec3* src = host_.positions + scene_.vertex_first[o.mesh];
        glm::vec3* dst = raster_positions_.data() + vertex_base[j];
        for (uint32_t v = 0; v < o.vertex_count; ++v) dst[v] = glm::vec3(world * glm::vec4(src[v], 1.0f));
        const uint32_t* tri = host_.triangles + 3 * scene_.triangle_first[o.mesh];
        uint32_t* out = raster_triangles_.data() + 3 * triangle_base[j];
        const uint32_t base = uint32_t(vertex_base[j]);
        for (uint64_t c = 0; c < 3ull * o.triangle_count; ++c) out[c] = tri[c] + base;
        std::copy_n(scene_.edge_flags.data() + scene_.triangle_first[o.mesh], o.triangle_count,
                    raster_edge_flags_.data() + triangle_base[j]);
        const uint32_t* across = scene_.edge_neighbours.data() + 3 * scene_.triangle_first[o.mesh];
        uint32_t* across_out = raster_neighbours_.data() + 3 * triangle_base[j];
        const uint32_t first = uint32_t(triangle_base[j]);
        for (uint64_t e = 0; e < 3ull * o.triangle_count; ++e)
            across_out[e] = across[e] == UINT32_MAX ? UINT32_MAX : across[e] + first;
    });
    k::depthRaster(raster_positions_.data(), raster_triangles_.data(), uint32_t(triangle_base.back()),
                   raster_edge_flags_.data(), raster_neighbours_.data(), camera, hzm_.data(), raster_scratch_);
    stats.aos_size = occluders_.size();
    stats.occluder_triangles = triangle_base.back();
}

// The blocks of this frame's active arrays: every object drawn now, and (coherent streaming)
// every object still resident from recent frames, with at least the vertices it draws.
void Pipeline::buildLayout(uint64_t frame, FrameStats& stats) {
    LayoutArrays& l = layouts_[cur_index_];
    const bool retain = options_.stream == StreamMode::Coherent && options_.retain_frames > 0;
    const uint32_t* prev_ids = prev_.objects;
    uint32_t a = 0, b = 0, out = 0;
    uint64_t resident = 0;
    const auto residentTriangles = [&](uint32_t id, uint32_t vc) {
        return vc ? scene_.maps[scene_.map_first[scene_.objects[id].mesh] + vc] : 0u;
    };
    // Merge last frame's resident ids with this frame's PVS (both ascending).
    while (a < prev_.count || b < pvs_.size()) {
        const uint32_t pa = a < prev_.count ? prev_ids[a] : UINT32_MAX;
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
        k::kernelSynchronize();
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
    k::frustumCull(scene_.objects.data(), n, frustum, in_frustum_.data());
    uint32_t in_count = 0;
    for (uint32_t i = 0; i < n; ++i)
        if (in_frustum_[i]) frustum_ids_[in_count++] = i;
    frustum_count_ = in_count;
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
    k::hzmBuild(hzm_.data(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
}

void Pipeline::cullPass(const CameraPose& pose, FrameStats& stats,
                        std::span<const std::pair<uint32_t, uint32_t>> previous_lod) {
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    const k::ObjectInfo* objects = scene_.objects.data();
    const uint32_t in_count = frustum_count_;
    stats.objects_in_frustum = in_count;
    pvs_.clear();
    if (options_.mode == CullMode::OcLod) {
        const k::HzmLevels levels = hzmLevels();
        k::hzmTest(objects, frustum_ids_.data(), in_count, camera, levels, occluded_.data());
        for (uint32_t j = 0; j < in_count; ++j)
            if (!occluded_[j]) pvs_.push_back(frustum_ids_[j]);
        clock.lap(Stage::HzmTest);
    } else {
        pvs_.assign(frustum_ids_.data(), frustum_ids_.data() + in_count);
    }
    stats.objects_visible = pvs_.size();
    stats.objects_occluded = in_count - pvs_.size();

    const uint32_t count = uint32_t(pvs_.size());
    if (options_.mode == CullMode::Full) {
        for (uint32_t j = 0; j < count; ++j) {
            pvs_vc_[j] = objects[pvs_[j]].vertex_count;
            pvs_tc_[j] = objects[pvs_[j]].triangle_count;
        }
    } else {
        const k::LodParams params{float(budget_), options_.alpha, options_.pet};
        k::lodSelect(objects, pvs_.data(), count, camera, params, scene_.map_first.data(), scene_.maps.data(),
                     pvs_vc_.data(), pvs_tc_.data());
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
    for (uint32_t j = 0; j < count; ++j) {
        const k::ObjectInfo& o = scene_.objects[pvs_[j]];
        if (pvs_vc_[j] != eq1[j]) pvs_tc_[j] = scene_.maps[scene_.map_first[o.mesh] + pvs_vc_[j]];
    }
}

void Pipeline::setVisible(std::span<const uint32_t> ids, std::span<const uint32_t> vertex_counts) {
    if (ids.size() != vertex_counts.size() || ids.size() > scene_.object_count)
        throw std::invalid_argument("Pipeline::setVisible: ids and vertex counts differ in size");
    pvs_.assign(ids.begin(), ids.end());
    for (size_t j = 0; j < ids.size(); ++j) {
        const k::ObjectInfo& o = scene_.objects[ids[j]];
        if ((j > 0 && ids[j] <= ids[j - 1]) || ids[j] >= scene_.object_count || vertex_counts[j] > o.vertex_count ||
            (vertex_counts[j] != 0 && vertex_counts[j] < o.q))
            throw std::invalid_argument("Pipeline::setVisible: entry " + std::to_string(j) + " is not a valid LOD");
        pvs_vc_[j] = vertex_counts[j];
        pvs_tc_[j] = vertex_counts[j] ? scene_.maps[scene_.map_first[o.mesh] + vertex_counts[j]] : 0;
    }
}

void Pipeline::streamPass(uint64_t frame, FrameStats& stats) {
    StageClock clock(stats);
    stats.frame = frame;
    stats.budget_vertices = uint64_t(budget_);
    stats.objects_visible = pvs_.size();
    const k::ObjectInfo* objects = scene_.objects.data();
    buildLayout(frame, stats);
    LayoutArrays& l = layouts_[cur_index_];
    const uint32_t blocks = layout_count_;
    const uint64_t vertex_total = k::exclusiveScan(l.vc.data(), blocks, l.voff.data());
    const uint64_t triangle_total = k::exclusiveScan(l.tc.data(), blocks, l.toff.data());
    cur_ = {l.ids.data(), l.vc.data(), l.tc.data(), l.voff.data(), l.toff.data(), blocks, vertex_total, triangle_total};
    stats.resident_vertices = vertex_total;
    stats.resident_triangles = triangle_total;
    clock.lap(Stage::Scan);
    k::StreamCounts sent;
    k::DefragmentCounts moved;
    if (options_.stream == StreamMode::None) {
        sent = k::streamObjectByObject(cur_, host_, active_);
        clock.lap(Stage::StreamCollect);
        clock.lap(Stage::Defragment);
    } else {
        // Without coherence nothing of the last frame is reused: the previous layout is empty.
        const k::ActiveLayout previous = options_.stream == StreamMode::Coherent ? prev_ : k::ActiveLayout{};
        sent = k::streamCollect(previous, cur_, host_, staging_);
        clock.lap(Stage::StreamCollect);
        moved = k::defragment(previous, cur_, staging_, active_);
        clock.lap(Stage::Defragment);
    }
    stats.streamed_vertices = sent.vertices;
    stats.streamed_triangles = sent.triangles;
    stats.streamed_bytes = sent.bytes();
    stats.moved_bytes = (moved.vertices_moved + moved.vertices_bounced) * sizeof(glm::vec3) +
                        (moved.triangles_moved + moved.triangles_bounced) * 3 * sizeof(uint32_t);

    // Beyond the paper: a frame that draws exactly what the last one drew, from blocks that did
    // not move, has last frame's index buffer already; only the checks above cost anything.
    const LayoutArrays& p = layouts_[cur_index_ ^ 1];
    const auto same = [&](const auto& a, const auto& b) {
        return std::memcmp(a.data(), b.data(), size_t(blocks) * sizeof(a[0])) == 0;
    };
    const bool unchanged = options_.stream == StreamMode::Coherent && moved.vertices_moved == 0 &&
                           moved.vertices_bounced == 0 && moved.vertices_copied == 0 && moved.triangles_moved == 0 &&
                           moved.triangles_bounced == 0 && moved.triangles_copied == 0 && prev_.count == blocks &&
                           indices_.size() == 3 * triangle_total && same(l.ids, p.ids) && same(l.vc, p.vc) &&
                           same(l.draw_vc, p.draw_vc);
    if (!unchanged) {
        indices_.resize(size_t(3 * triangle_total));
        k::reform(cur_, objects, scene_.vertex_first.data(), scene_.ecol.data(), active_.triangles.data(),
                  indices_.data(), l.draw_vc.data());
    }
    clock.lap(Stage::Reform);

    prev_ = cur_;
    cur_index_ ^= 1;
}

FrameStats Pipeline::runFrame(const CameraPose& pose, uint64_t frame) {
    FrameStats stats;
    stats.frame = frame;
    // The PVS `pvs_occluder_lag` frames back supplies this frame's extra occluders.
    occluderPass(pose, pvs_history_[options_.pvs_occluder_lag - 1], stats);
    cullPass(pose, stats, last_lod_);
    last_lod_.resize(pvs_.size());
    for (size_t j = 0; j < pvs_.size(); ++j) last_lod_[j] = {pvs_[j], pvs_vc_[j]};
    pvs_history_[1].swap(pvs_history_[0]);
    pvs_history_[0] = pvs_;
    streamPass(frame, stats);
    return stats;
}


}  // namespace occ
