// SPDX-License-Identifier: MIT
#include "pipeline/stream_stage.h"

#include "scene/errors.h"

#include <xxhash.h>

#include <algorithm>
#include <stdexcept>

namespace occ {

StreamStage::StreamStage(const OssFile& file, const DeviceScene& scene, const Options& options)
    : scene_(scene), options_(options) {
    host_ = {file.allPositions().data(), file.allTriangles().data(), scene.host_vertex_first.data(),
             scene.host_triangle_first.data(), scene.host_objects.data()};
    const size_t room = std::max<uint32_t>(1, scene.item_count);
    for (k::DeviceArray<k::LayoutBlock>& l : layouts_) l.resize(room);
    places_.resize(room);
    k::deviceMemset(places_.ptr(), 0, room * sizeof(k::BlockPlace));
}

void StreamStage::lendActiveArrays(k::BufferProvider& lender, uint32_t first_vertex_slot, uint32_t index_slot) {
    lender.beginDeviceWrites();
    for (uint32_t b = 0; b < 2; ++b)
        active_.vertices.buffers[b].lendFrom(&lender, first_vertex_slot + b,
                                             b == active_.vertices.current ? heap_.vertex_top : 0);
    indices_.lendFrom(&lender, index_slot, 3 * heap_.triangle_top);
    lender.endDeviceWrites();
    lender_ = &lender;
}

std::vector<k::LayoutBlock> StreamStage::downloadLayout() const {
    const uint32_t last = cur_index_ ^ 1;
    std::vector<k::LayoutBlock> blocks(layout_counts_[last]);
    k::copyToHost(blocks.data(), layouts_[last].ptr(), blocks.size());
    return blocks;
}

void StreamStage::run(const k::VisibleLods& visible, const std::vector<uint32_t>& ids, uint64_t frame,
                      FrameStats& stats) {
    StageClock clock(stats);
    stats.pvs_hash = XXH3_64bits(ids.data(), ids.size() * sizeof(uint32_t));
    const Churn churn = setChurn(drawn_, ids);
    stats.pvs_added = churn.added;
    stats.pvs_removed = churn.removed;
    drawn_ = ids;
    // The layout, on the device; the host gets back what it must stream and a few totals.
    const k::LayoutOptions layout{frame, options_.coherent, options_.retain_frames, options_.resident_vertices};
    const uint32_t last = cur_index_ ^ 1;
    k::LayoutTotals totals;
    try {
        totals = k::placeLayout(visible, layouts_[last].ptr(), layout_counts_[last], layouts_[cur_index_].ptr(),
                                places_.ptr(), {scene_.objects.ptr(), scene_.map_first.ptr(), scene_.maps}, layout,
                                heap_, lists_, layout_scratch_);
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
    if (options_.object_by_object) {
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

}  // namespace occ
