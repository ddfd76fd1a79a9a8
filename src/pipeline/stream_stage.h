// SPDX-License-Identifier: MIT
#pragma once

#include "block_layout.h"
#include "defragment.h"
#include "device_memory.h"
#include "reform.h"
#include "stream_collect.h"
#include "pipeline/device_scene.h"
#include "pipeline/frame_stats.h"

#include <vector>

namespace occ {

// Streaming (Peng & Cao 2012): the layout of the active arrays for a frame's visible set, the
// geometry its blocks lack gathered from the mapped file and sent over the bus, the blocks that
// moved defragmented on the device, and the triangles whose LOD changed reformed into the index
// buffer the display draws. Keeps the last frame's layout and what it holds (coherence).
class StreamStage {
public:
    struct Options {
        bool coherent = true;      // only what the last frame lacked (sc); false: the whole set (snc, ns)
        bool object_by_object = false;  // ns: no batching
        uint32_t retain_frames = 0;
        double resident_vertices = 0;   // the cap on what stays resident
    };
    StreamStage(const OssFile& file, const DeviceScene& scene, const Options& options);

    // Lays out, streams, defragments and reforms `visible` (ascending ids with their LOD vertex
    // and triangle counts on the device; `ids` its ids on the host) for `frame`, adding the
    // counts and stage times to `stats`.
    void run(const k::VisibleLods& visible, const std::vector<uint32_t>& ids, uint64_t frame, FrameStats& stats);

    // Where the arrays live: see Pipeline::lendActiveArrays.
    void lendActiveArrays(k::BufferProvider& lender, uint32_t first_vertex_slot, uint32_t index_slot);
    std::vector<k::LayoutBlock> downloadLayout() const;
    k::DevicePtr<const glm::vec3> activeVertices() const { return active_.vertices.data(); }
    k::DevicePtr<const uint32_t> indices() const { return indices_.ptr(); }
    uint64_t vertexExtent() const { return heap_.vertex_top; }
    uint64_t triangleExtent() const { return heap_.triangle_top; }
    k::DevicePtr<const k::DrawBlock> drawBlocks() const { return lists_.draws.ptr(); }
    uint32_t drawCount() const { return lists_.draw_count; }
    uint32_t currentVertexBuffer() const { return active_.vertices.current; }

private:
    const DeviceScene& scene_;
    Options options_;
    k::HostGeometry host_{};
    std::vector<uint32_t> drawn_;  // the visible set last laid out, for the churn
    // The last frame's and this frame's blocks (layouts_[cur_index_ ^ 1] is the last built),
    // each resident object's place, the heap's few totals (host) and the frame's lists; the host
    // gets back the stream list.
    k::DeviceArray<k::LayoutBlock> layouts_[2];
    uint32_t layout_counts_[2] = {0, 0};
    uint32_t cur_index_ = 0;
    k::DeviceArray<k::BlockPlace> places_;
    k::LayoutHeap heap_;
    k::LayoutLists lists_;
    k::LayoutScratch layout_scratch_;
    k::PinnedArray<k::StreamBlock> stream_list_;
    k::ReformScratch reform_scratch_;
    k::StagingBuffers staging_;
    k::ActiveArrays active_;
    k::ProvidedBuffer<uint32_t> indices_;
    k::BufferProvider* lender_ = nullptr;  // what indices_ holds: 3 x the triangles of the last reform
};

}  // namespace occ
