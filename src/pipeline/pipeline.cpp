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

#include <xxhash.h>

#include <algorithm>
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
    places_.resize(n);
    pvs_vc_.resize(n);
    pvs_tc_.resize(n);
    resident_vc_.assign(n, 0);
    last_drawn_.assign(n, 0);
}

void Pipeline::lendActiveArrays(k::BufferProvider& lender) {
    lender.beginDeviceWrites();
    for (uint32_t b = 0; b < 2; ++b)
        active_.vertices.buffers[b].lendFrom(&lender, kActiveVertexSlot + b,
                                             b == active_.vertices.current ? vertex_heap_.extent() : 0);
    indices_.lendFrom(&lender, kIndexSlot, 3 * triangle_heap_.extent());
    lender.endDeviceWrites();
    lender_ = &lender;
    upload(draw_blocks_device_, draw_blocks_, draw_count_);
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
        k::occluderWeight(scene_.objects.ptr(), scene_.cos.ptr(), scene_.cos_count, in_frustum_.ptr(), camera,
                          weights_.ptr());
        aos = k::selectTopK(scene_.cos.ptr(), weights_.ptr(), scene_.cos_count, options_.aos, occluders_.ptr(),
                            topk_keys_);
    }
    uint32_t extra = 0;
    if (options_.pvs_occluder_triangles > 0 && source_count > 0) {
        extra = k::selectPvsOccluders(scene_.objects.ptr(), source, source_count, in_frustum_.ptr(), camera,
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

void Pipeline::occluderPass(const CameraPose& pose, uint64_t frame, FrameStats& stats) {
    if (options_.mode != CullMode::OcLod) return;
    // The earlier PVS stays on the device for this: nothing crosses the bus.
    k::DevicePtr<const uint32_t> source;
    uint32_t source_count = 0;
    for (const CulledFrame& h : history_)
        if (frame >= options_.pvs_occluder_lag && h.frame == frame - options_.pvs_occluder_lag)
            source = h.device_pvs.ptr(), source_count = uint32_t(h.pvs.size());
    if (!frustumIsFor(pose)) frustumPass(pose, stats);
    StageClock clock(stats);
    const k::Camera camera = toKernelCamera(pose, options_.width, options_.height);
    chooseOccluders(camera, source, source_count);
    clock.lap(Stage::OccluderSelect);
    rasterOccluders(camera, stats);
    clock.lap(Stage::DepthRaster);
    k::hzmBuild(hzm_.ptr(), options_.width, options_.height);
    clock.lap(Stage::HzmBuild);
}

void Pipeline::cullPass(const CameraPose& pose, uint64_t frame, FrameStats& stats,
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
        if (options_.lod_hysteresis > 0 && !previous_lod.empty()) {
            // The last frame's visible set goes up (the switch's comes from the other rank).
            previous_lod_.resize(previous_lod.size());
            for (size_t j = 0; j < previous_lod.size(); ++j)
                previous_lod_[j] = {previous_lod[j].first, previous_lod[j].second};
            upload(previous_lod_device_, previous_lod_, previous_lod.size());
            k::keepSimilarLods(pvs, count, previous_lod_device_.ptr(), uint32_t(previous_lod.size()),
                               options_.lod_hysteresis, budget_, scene_.objects.ptr(), scene_.map_first.ptr(),
                               scene_.maps.ptr(), pvs_vc_device_.ptr(), pvs_tc_device_.ptr(), hysteresis_scratch_);
        }
        k::copyToHost(pvs_vc_.data(), pvs_vc_device_.ptr(), count);
        k::copyToHost(pvs_tc_.data(), pvs_tc_device_.ptr(), count);
    }
    std::swap(history_[0], history_[1]);
    CulledFrame& h = history_[0];
    h.frame = frame;
    h.pvs.assign(pvs_.begin(), pvs_.end());
    h.device_pvs.growTo(std::max<uint32_t>(1, count));
    k::copyOnDevice(h.device_pvs.ptr(), pvs, count);
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
}

namespace {

// A block's room: its LOD plus a quarter for growth (at least 32 vertices), never more than the
// full mesh, so that LOD changes within it (Eq. 1 and the hysteresis move by a few percent a
// frame) write only the new vertices and triangles where the block already is.
uint32_t roomFor(uint32_t vertices, uint32_t full) {
    const uint64_t room = uint64_t(vertices) + std::max<uint32_t>(vertices / 4, 32);
    return uint32_t(std::min<uint64_t>(room, full));
}

// Heaps are compacted when more than half of what they span is holes (and they are not small).
bool fragmented(const RangeAllocator& heap) {
    const uint64_t extent = heap.extent();
    return extent > (uint64_t(1) << 16) && extent - heap.used() > extent / 2;
}


}  // namespace

bool Pipeline::placeBlocks(HostLayoutArrays& l, uint32_t blocks, FrameStats& stats) {
    const bool coherent = options_.stream == StreamMode::Coherent;
    for (k::PinnedArray<k::BlockMove>* moves : {&vertex_moves_, &triangle_moves_}) moves->growTo(std::max<uint32_t>(1, blocks));
    reforms_.growTo(std::max<uint32_t>(1, blocks));
    draw_blocks_.growTo(std::max<uint32_t>(1, blocks));
    vertex_move_count_ = triangle_move_count_ = reform_count_ = draw_count_ = 0;

    // The last frame's blocks that this frame's layout no longer has (both lists ascending).
    std::vector<uint32_t> dropped;
    for (uint32_t a = 0, b = 0; a < prev_host_.count; ++a) {
        const uint32_t id = prev_host_.objects[a];
        while (b < blocks && l.ids[b] < id) ++b;
        if (!(b < blocks && l.ids[b] == id)) dropped.push_back(id);
    }
    // Without coherence nothing of the last frame is reused (SnC and NS): every block is new.
    if (!coherent)
        for (uint32_t j = 0; j < prev_host_.count; ++j) places_[prev_host_.objects[j]] = BlockPlace{};

    // Each block keeps its place while its LOD fits its room; a block that outgrew it, or is new,
    // gets a new range. Old ranges are given back after the frame, so that no move of this frame
    // writes where another reads. When the heaps are full or mostly holes, everything is
    // compacted into the other buffers instead. Places go straight into the layout (l.voff, l.toff).
    std::vector<std::pair<uint64_t, uint64_t>> vertex_frees, triangle_frees;
    std::vector<uint32_t> next_vcap(blocks), next_tcap(blocks);
    const auto giveRoom = [&](uint32_t j) {
        const k::ObjectInfo& o = scene_.host_objects[l.ids[j]];
        next_vcap[j] = roomFor(l.vc[j], o.vertex_count);
        next_tcap[j] = scene_.lodTriangles(o.mesh, next_vcap[j]);
    };
    bool compact = !coherent || fragmented(vertex_heap_) || fragmented(triangle_heap_);
    for (uint32_t j = 0; j < blocks && !compact; ++j) {
        const BlockPlace& p = places_[l.ids[j]];
        if (p.resident && l.vc[j] <= p.vcap && l.tc[j] <= p.tcap) {
            next_vcap[j] = p.vcap, next_tcap[j] = p.tcap, l.voff[j] = p.voff, l.toff[j] = p.toff;
            continue;
        }
        giveRoom(j);
        l.voff[j] = next_vcap[j] ? vertex_heap_.allocate(next_vcap[j]) : 0;
        l.toff[j] = next_tcap[j] ? triangle_heap_.allocate(next_tcap[j]) : 0;
        if (l.voff[j] == RangeAllocator::kNone || l.toff[j] == RangeAllocator::kNone) compact = true;
        if (p.resident) {
            vertex_frees.emplace_back(p.voff, p.vcap);
            triangle_frees.emplace_back(p.toff, p.tcap);
        }
    }
    if (compact) {
        // Every block afresh, back to back, with room to grow and heaps half as large again.
        uint64_t vertices = 0, triangles = 0;
        for (uint32_t j = 0; j < blocks; ++j) {
            giveRoom(j);
            l.voff[j] = vertices, l.toff[j] = triangles;
            vertices += next_vcap[j];
            triangles += next_tcap[j];
        }
        vertex_heap_.reset(std::max<uint64_t>(4096, vertices + vertices / 2));
        triangle_heap_.reset(std::max<uint64_t>(4096, triangles + triangles / 2));
        for (uint32_t j = 0; j < blocks; ++j) {
            if (next_vcap[j]) vertex_heap_.allocate(next_vcap[j]);
            if (next_tcap[j]) triangle_heap_.allocate(next_tcap[j]);
        }
        // The display draws with 32-bit first indices and base vertices.
        if (vertex_heap_.capacity() > uint64_t(INT32_MAX) || 3 * triangle_heap_.capacity() > uint64_t(UINT32_MAX))
            throw SystemError("the active arrays would hold " + std::to_string(vertices) + " vertices and " +
                              std::to_string(triangles) + " triangles, more than 32-bit indices reach: lower --budget");
    } else {
        // Blocks that left the layout give their ranges back too.
        for (uint32_t id : dropped) {
            vertex_frees.emplace_back(places_[id].voff, places_[id].vcap);
            triangle_frees.emplace_back(places_[id].toff, places_[id].tcap);
        }
        for (const auto& [offset, n] : vertex_frees) vertex_heap_.release(offset, n);
        for (const auto& [offset, n] : triangle_frees) triangle_heap_.release(offset, n);
    }

    // The moves and reforms of the frame, block by block in layout order, which is also the order
    // streamCollect stages the blocks' new parts in.
    uint64_t staged_vertices = 0, staged_triangles = 0, moved = 0;
    for (uint32_t j = 0; j < blocks; ++j) {
        const uint32_t id = l.ids[j];
        BlockPlace& p = places_[id];
        const uint32_t kept_v = p.resident ? std::min(p.vc, l.vc[j]) : 0;
        const uint32_t kept_t = p.resident ? std::min(p.tc, l.tc[j]) : 0;
        const bool placed = !p.resident || l.voff[j] != p.voff || l.toff[j] != p.toff || compact;
        const uint32_t staged_v = l.vc[j] - kept_v, staged_t = l.tc[j] - kept_t;
        const uint32_t moved_v = placed ? kept_v : 0, moved_t = placed ? kept_t : 0;
        if (moved_v + staged_v > 0)
            vertex_moves_[vertex_move_count_++] = {p.voff, l.voff[j], staged_vertices, kept_v, moved_v, staged_v, 0};
        if (moved_t + staged_t > 0)
            triangle_moves_[triangle_move_count_++] = {p.toff, l.toff[j], staged_triangles, kept_t, moved_t, staged_t, 0};
        staged_vertices += staged_v;
        staged_triangles += staged_t;
        moved += moved_v * sizeof(glm::vec3) + moved_t * 3 * sizeof(uint32_t);
        // Indices are local to the block: only a block whose drawn LOD or triangles changed, or
        // that moved, is reformed.
        if (l.draw_vc[j] > 0 && (placed || staged_t > 0 || p.draw_vc != l.draw_vc[j]))
            reforms_[reform_count_++] = {l.toff[j], id, l.draw_vc[j], l.draw_tc[j], 0};
        if (l.draw_vc[j] > 0)
            draw_blocks_[draw_count_++] = {id, l.draw_tc[j], uint32_t(l.toff[j]), uint32_t(l.voff[j])};
        p = {l.voff[j], l.toff[j], next_vcap[j], next_tcap[j], l.vc[j], l.tc[j], l.draw_vc[j], true};
    }
    for (uint32_t id : dropped) places_[id] = BlockPlace{};
    stats.moved_bytes = moved;
    return compact;
}

void Pipeline::streamPass(uint64_t frame, FrameStats& stats) {
    StageClock clock(stats);
    stats.frame = frame;
    stats.budget_vertices = uint64_t(budget_);
    stats.objects_visible = pvs_.size();
    stats.pvs_hash = XXH3_64bits(pvs_.data(), pvs_.size() * sizeof(uint32_t));
    buildLayout(frame, stats);
    HostLayoutArrays& l = host_layouts_[cur_index_];
    const uint32_t blocks = layout_count_;
    const bool compacted = placeBlocks(l, blocks, stats);
    uint64_t vertex_total = 0, triangle_total = 0;
    for (uint32_t j = 0; j < blocks; ++j) vertex_total += l.vc[j], triangle_total += l.tc[j];
    cur_host_ = {l.ids.data(), l.vc.data(), l.tc.data(), l.voff.data(), l.toff.data(), blocks, vertex_total, triangle_total};
    stats.resident_vertices = vertex_total;
    stats.resident_triangles = triangle_total;
    clock.lap(Stage::Scan);

    // The active arrays may be the display's buffers: the kernels write them only in here.
    if (lender_) lender_->beginDeviceWrites();
    // Compaction writes every block into the other buffers, which then become current.
    k::ActiveBuffer<glm::vec3>& vertices = active_.vertices;
    k::ActiveBuffer<uint32_t>& triangles = active_.triangles;
    const uint32_t vertex_to = compacted ? vertices.current ^ 1 : vertices.current;
    const uint32_t triangle_to = compacted ? triangles.current ^ 1 : triangles.current;
    vertices.buffers[vertex_to].reserve(vertex_heap_.capacity());
    triangles.buffers[triangle_to].reserve(3 * triangle_heap_.capacity());
    indices_.reserve(3 * triangle_heap_.capacity());
    k::StreamCounts sent;
    if (options_.stream == StreamMode::None) {
        sent = k::streamObjectByObject(cur_host_, host_, vertices.buffers[vertex_to].ptr(),
                                       triangles.buffers[triangle_to].ptr());
        clock.lap(Stage::StreamCollect);
        clock.lap(Stage::Defragment);
    } else {
        sent = k::streamCollect(options_.stream == StreamMode::Coherent ? prev_host_ : k::HostLayout{}, cur_host_,
                                host_, staging_);
        clock.lap(Stage::StreamCollect);
        // Only the blocks that changed: their lists cross the bus, then their elements move.
        upload(vertex_moves_device_, vertex_moves_, vertex_move_count_);
        upload(triangle_moves_device_, triangle_moves_, triangle_move_count_);
        k::defragmentVertices(vertex_moves_device_.ptr(), vertex_move_count_, vertices.buffers[vertices.current].ptr(),
                              vertices.buffers[vertex_to].ptr(), staging_.device_vertices.ptr(), active_);
        k::defragmentTriangles(triangle_moves_device_.ptr(), triangle_move_count_,
                               triangles.buffers[triangles.current].ptr(), triangles.buffers[triangle_to].ptr(),
                               staging_.device_triangles.ptr(), active_);
        clock.lap(Stage::Defragment);
    }
    vertices.current = vertex_to;
    triangles.current = triangle_to;
    stats.streamed_vertices = sent.vertices;
    stats.streamed_triangles = sent.triangles;
    stats.streamed_bytes = sent.bytes();

    upload(reforms_device_, reforms_, reform_count_);
    stats.reformed_triangles = k::reformBlocks(reforms_device_.ptr(), reform_count_, scene_.objects.ptr(), scene_.vertex_first.ptr(),
                    scene_.ecol.ptr(), triangles.data(), indices_.ptr(), reform_scratch_);
    if (lender_) {
        upload(draw_blocks_device_, draw_blocks_, draw_count_);
        lender_->endDeviceWrites();
    }
    clock.lap(Stage::Reform);

    prev_host_ = cur_host_;
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
