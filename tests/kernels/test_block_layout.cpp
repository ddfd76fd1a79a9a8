// SPDX-License-Identifier: MIT
// placeLayout: the layout of the active arrays, built on the device frame after frame.
#include "block_layout.h"
#include "device_test_support.h"

#include <map>

namespace occ::k {

bool operator==(const BlockMove& a, const BlockMove& b) {
    return a.from == b.from && a.to == b.to && a.staged_offset == b.staged_offset && a.kept == b.kept &&
           a.moved == b.moved && a.staged == b.staged;
}
std::ostream& operator<<(std::ostream& os, const BlockMove& m) {
    return os << "{from " << m.from << " to " << m.to << " staged at " << m.staged_offset << " kept " << m.kept
              << " moved " << m.moved << " staged " << m.staged << "}";
}

namespace {

using test::DeviceTest;
using test::toDevice;
using test::toHost;

class BlockLayout : public DeviceTest {};

// Objects 0..4, each with a mesh of its own (100, 100, 200, 20, 100 vertices) whose LOD with v
// vertices has 2 v - 1 triangles. Rooms come in size classes (4, 5, 6, 7, 8, 10, 12, 14, 16, 20,
// 24, 28, 32, 40, 48, 56, 64, 80, ...).
struct Frames {
    std::vector<uint32_t> full{100, 100, 200, 20, 100};
    DeviceArray<ObjectInfo> objects;
    DeviceArray<uint64_t> map_first;
    DeviceArray<uint32_t> maps;
    DeviceArray<LayoutBlock> layouts[2];
    uint32_t counts[2] = {0, 0};
    uint32_t cur = 0;
    DeviceArray<BlockPlace> places;
    LayoutHeap heap;
    LayoutLists lists;
    LayoutScratch scratch;
    LayoutOptions options;
    uint64_t frame_number = 0;

    Frames() {
        std::vector<ObjectInfo> o(full.size(), ObjectInfo{});
        std::vector<uint64_t> first;
        std::vector<uint32_t> m;
        for (uint32_t i = 0; i < full.size(); ++i) {
            o[i].mesh = i;
            o[i].vertex_count = full[i];
            o[i].triangle_count = 2 * full[i] - 1;
            first.push_back(m.size());
            for (uint32_t v = 0; v <= full[i]; ++v) m.push_back(v ? 2 * v - 1 : 0);
        }
        objects = toDevice(o);
        map_first = toDevice(first);
        maps = toDevice(m);
        for (DeviceArray<LayoutBlock>& l : layouts) l.resize(full.size());
        places = toDevice(std::vector<BlockPlace>(full.size(), BlockPlace{}));
        options.coherent = true;
        options.retain_frames = 0;
        options.resident_cap = 1e9;
    }

    // One frame with this visible set: (object, vertices drawn), ascending objects.
    LayoutTotals frame(const std::vector<std::pair<uint32_t, uint32_t>>& visible) {
        std::vector<uint32_t> ids, vc, tc;
        for (const auto& [id, v] : visible) {
            ids.push_back(id);
            vc.push_back(v);
            tc.push_back(v ? 2 * v - 1 : 0);
        }
        const DeviceArray<uint32_t> dids = toDevice(ids), dvc = toDevice(vc), dtc = toDevice(tc);
        options.frame = frame_number++;
        const uint32_t last = cur ^ 1;
        const LayoutTotals t =
            placeLayout({dids.ptr(), dvc.ptr(), dtc.ptr(), uint32_t(ids.size())}, layouts[last].ptr(), counts[last],
                        layouts[cur].ptr(), places.ptr(), {objects.ptr(), map_first.ptr(), maps.ptr()}, options, heap,
                        lists, scratch);
        counts[cur] = t.blocks;
        cur ^= 1;
        return t;
    }
    std::map<uint32_t, LayoutBlock> layout() const {
        std::map<uint32_t, LayoutBlock> out;
        for (const LayoutBlock& b : toHost(layouts[cur ^ 1].ptr(), counts[cur ^ 1])) out[b.object] = b;
        return out;
    }
    std::vector<StreamBlock> streams() const { return toHost(lists.streams.ptr(), lists.stream_count); }
    std::vector<BlockMove> vertexMoves() const { return toHost(lists.vertex_moves.ptr(), lists.vertex_move_count); }
    std::vector<BlockMove> triangleMoves() const {
        return toHost(lists.triangle_moves.ptr(), lists.triangle_move_count);
    }
    std::vector<ReformBlock> reforms() const { return toHost(lists.reforms.ptr(), lists.reform_count); }
    std::vector<DrawBlock> draws() const { return toHost(lists.draws.ptr(), lists.draw_count); }
};

TEST_F(BlockLayout, TheFirstFramePlacesEveryBlockBackToBackWithRoomToGrow) {
    Frames run;
    const LayoutTotals t = run.frame({{0, 10}, {2, 40}, {3, 5}});
    EXPECT_EQ(t.blocks, 3u);
    EXPECT_TRUE(t.compacted);
    EXPECT_TRUE(t.relocated);
    EXPECT_EQ(t.active_vertices, 55u);
    EXPECT_EQ(t.active_triangles, 19u + 79u + 9u);
    EXPECT_EQ(t.objects_drawn, 3u);
    EXPECT_EQ(t.streamed_vertices, 55u);
    EXPECT_EQ(t.moved_bytes, 0u);
    // Rooms: 10 + 32 -> class 48; 40 + 32 -> 80; object 3's whole mesh, 20. Triangles of those
    // LODs: 95 -> 96, 159 -> 160, 39 -> 40.
    const auto l = run.layout();
    EXPECT_EQ(l.at(0).vertex_offset, 0u);
    EXPECT_EQ(l.at(2).vertex_offset, 48u);
    EXPECT_EQ(l.at(3).vertex_offset, 128u);
    EXPECT_EQ(l.at(0).triangle_offset, 0u);
    EXPECT_EQ(l.at(2).triangle_offset, 96u);
    EXPECT_EQ(l.at(3).triangle_offset, 256u);
    EXPECT_EQ(run.heap.vertex_top, 148u);
    EXPECT_EQ(run.heap.triangle_top, 296u);
    EXPECT_EQ(run.heap.vertex_used, 148u);
    // Everything streams whole, staged back to back in layout order; every block is reformed
    // and drawn.
    const std::vector<StreamBlock> s = run.streams();
    ASSERT_EQ(s.size(), 3u);
    EXPECT_EQ(s[1].object, 2u);
    EXPECT_EQ(s[1].vertex_kept, 0u);
    EXPECT_EQ(s[1].vertex_staged, 40u);
    EXPECT_EQ(s[1].triangle_staged, 79u);
    EXPECT_EQ(run.vertexMoves()[2], (BlockMove{0, 128, 50, 0, 0, 5, 0}));
    EXPECT_EQ(run.reforms().size(), 3u);
    const std::vector<DrawBlock> d = run.draws();
    ASSERT_EQ(d.size(), 3u);
    EXPECT_EQ(d[2].object, 3u);
    EXPECT_EQ(d[2].base_vertex, 128u);
    EXPECT_EQ(d[2].first_triangle, 256u);
    EXPECT_EQ(d[2].triangle_count, 9u);
}

TEST_F(BlockLayout, ABlockKeepsItsPlaceWhileItsLodFitsItsRoomAndMovesWhenItOutgrowsIt) {
    Frames run;
    run.frame({{0, 10}, {2, 40}, {3, 5}});
    const LayoutTotals t = run.frame({{0, 15}, {2, 100}, {3, 5}});
    EXPECT_FALSE(t.relocated);
    const auto l = run.layout();
    // Object 0 grows within its room: it stays and only its 5 new vertices (10 triangles) stream.
    EXPECT_EQ(l.at(0).vertex_offset, 0u);
    // Object 2 outgrows its room (80): a new room of 100 + 32 -> 160 on top of the heap, where its
    // kept 40 vertices (79 triangles) are copied.
    EXPECT_EQ(l.at(2).vertex_offset, 148u);
    EXPECT_EQ(l.at(2).triangle_offset, 296u);
    // Object 3 did not change: it keeps its place and appears in no list but the draws.
    EXPECT_EQ(l.at(3).vertex_offset, 128u);
    const std::vector<BlockMove> vm = run.vertexMoves();
    ASSERT_EQ(vm.size(), 2u);
    EXPECT_EQ(vm[0], (BlockMove{0, 0, 0, 10, 0, 5, 0}));
    EXPECT_EQ(vm[1], (BlockMove{48, 148, 5, 40, 40, 60, 0}));
    const std::vector<BlockMove> tm = run.triangleMoves();
    ASSERT_EQ(tm.size(), 2u);
    EXPECT_EQ(tm[0], (BlockMove{0, 0, 0, 19, 0, 10, 0}));
    EXPECT_EQ(tm[1], (BlockMove{96, 296, 10, 79, 79, 120, 0}));
    EXPECT_EQ(t.moved_bytes, 40u * 12 + 79u * 12);
    EXPECT_EQ(t.streamed_vertices, 65u);
    EXPECT_EQ(t.streamed_triangles, 130u);
    const std::vector<StreamBlock> s = run.streams();
    ASSERT_EQ(s.size(), 2u);
    EXPECT_EQ(s[0].object, 0u);
    EXPECT_EQ(s[0].vertex_kept, 10u);
    EXPECT_EQ(s[0].vertex_staged, 5u);
    EXPECT_EQ(s[1].object, 2u);
    EXPECT_EQ(s[1].triangle_kept, 79u);
    EXPECT_EQ(s[1].triangle_staged, 120u);
    const std::vector<ReformBlock> r = run.reforms();
    ASSERT_EQ(r.size(), 2u);
    EXPECT_EQ(r[0].object, 0u);
    EXPECT_EQ(r[1].object, 2u);
    EXPECT_EQ(r[1].triangle_offset, 296u);
    EXPECT_EQ(run.draws().size(), 3u);
    // Object 2's old ranges are free from the next frame on.
    EXPECT_EQ(run.heap.vertex_free_count, 1u);
    EXPECT_EQ(run.heap.triangle_free_count, 1u);

    // An unchanged frame: nothing streams, moves or is reformed.
    const LayoutTotals same = run.frame({{0, 15}, {2, 100}, {3, 5}});
    EXPECT_EQ(same.streamed_vertices + same.streamed_triangles + same.moved_bytes, 0u);
    EXPECT_EQ(run.lists.vertex_move_count + run.lists.triangle_move_count + run.lists.reform_count, 0u);
    EXPECT_EQ(run.lists.stream_count, 0u);
}

TEST_F(BlockLayout, FreedRangesServeLaterBlocksOfTheirClass) {
    Frames run;
    run.frame({{0, 10}, {2, 40}, {3, 5}});
    run.frame({{0, 15}, {2, 100}, {3, 5}});  // object 2 leaves 48 (room 80) / 96 (room 160)
    // Object 2 leaves, object 4 arrives with 40 vertices: room 80, 160 triangles, the class of
    // object 2's first ranges.
    const LayoutTotals t = run.frame({{0, 15}, {3, 5}, {4, 40}});
    EXPECT_FALSE(t.relocated);
    const auto l = run.layout();
    EXPECT_EQ(l.count(2), 0u);
    EXPECT_EQ(l.at(4).vertex_offset, 48u);
    EXPECT_EQ(l.at(4).triangle_offset, 96u);
    EXPECT_EQ(run.heap.vertex_top, 308u);  // nothing went on top
    // Object 2's second ranges (148 / 296) are free now.
    EXPECT_EQ(run.heap.vertex_free_count, 1u);
    EXPECT_EQ(toHost(run.heap.vertex_free.ptr(), 1)[0].offset, 148u);
    EXPECT_EQ(run.heap.vertex_used, 48u + 20u + 80u);
}

TEST_F(BlockLayout, CoherentStreamingRetainsBlocksForAWhileAndUnderTheCap) {
    Frames run;
    run.options.retain_frames = 1;
    run.frame({{0, 30}, {3, 5}});
    // Object 0 shrinks: it keeps its 30 vertices resident and draws 8 (reformed, nothing streams).
    LayoutTotals t = run.frame({{0, 8}, {3, 5}});
    auto l = run.layout();
    EXPECT_EQ(l.at(0).vertex_count, 30u);
    EXPECT_EQ(l.at(0).draw_vertex_count, 8u);
    EXPECT_EQ(t.streamed_vertices, 0u);
    ASSERT_EQ(run.reforms().size(), 1u);
    EXPECT_EQ(run.reforms()[0].walk_vertex_count, 8u);
    // Object 3 leaves the visible set: resident, not drawn, for one frame more.
    t = run.frame({{0, 8}});
    l = run.layout();
    ASSERT_EQ(l.count(3), 1u);
    EXPECT_EQ(l.at(3).draw_vertex_count, 0u);
    EXPECT_EQ(t.objects_drawn, 1u);
    EXPECT_EQ(t.resident_vertices, 35u);
    EXPECT_EQ(run.draws().size(), 1u);
    // It comes back: nothing streams.
    t = run.frame({{0, 8}, {3, 5}});
    EXPECT_EQ(t.streamed_vertices, 0u);
    run.frame({{0, 8}});
    run.frame({{0, 8}});
    EXPECT_EQ(run.layout().count(3), 0u) << "two frames without being drawn";
    // Over the cap residency starts again from what is drawn.
    run.options.resident_cap = 10;
    t = run.frame({{0, 8}});
    EXPECT_EQ(run.layout().at(0).vertex_count, 8u);
    EXPECT_EQ(t.resident_vertices, 8u);
}

TEST_F(BlockLayout, WithoutCoherenceEveryFrameIsPlacedAfreshAndStreamedWhole) {
    Frames run;
    run.options.coherent = false;
    run.frame({{0, 10}, {2, 40}});
    const LayoutTotals t = run.frame({{0, 15}, {2, 40}});
    EXPECT_TRUE(t.compacted);
    EXPECT_EQ(t.streamed_vertices, 55u);
    EXPECT_EQ(t.moved_bytes, 0u);
    for (const StreamBlock& s : run.streams()) EXPECT_EQ(s.vertex_kept + s.triangle_kept, 0u);
    EXPECT_EQ(run.reforms().size(), 2u);
}

TEST_F(BlockLayout, AHeapShortOfRoomGrowsAndEveryBlockKeepsItsPlace) {
    Frames run;
    run.frame({{0, 10}});  // capacity 4096 (the least)
    // Shrink the capacity as if it were full: the next new block does not fit on top.
    run.heap.vertex_capacity = run.heap.vertex_top + 10;
    const LayoutTotals t = run.frame({{0, 10}, {1, 20}});
    EXPECT_TRUE(t.relocated);
    EXPECT_FALSE(t.compacted);
    EXPECT_GE(run.heap.vertex_capacity, 2 * run.heap.vertex_top);
    const auto l = run.layout();
    EXPECT_EQ(l.at(0).vertex_offset, 0u);
    // Block 0 is copied whole to its same place in the other buffer; block 1 streams.
    const std::vector<BlockMove> vm = run.vertexMoves();
    ASSERT_EQ(vm.size(), 2u);
    EXPECT_EQ(vm[0], (BlockMove{0, 0, 0, 10, 10, 0, 0}));
    EXPECT_EQ(run.reforms().size(), 2u) << "the index buffer may have grown: every drawn block is reformed";
}

TEST_F(BlockLayout, AnEmptyFrameEmptiesTheLayout) {
    Frames run;
    run.frame({{0, 10}, {2, 40}});
    const LayoutTotals t = run.frame({});
    EXPECT_EQ(t.blocks, 0u);
    EXPECT_EQ(run.lists.draw_count + run.lists.stream_count + run.lists.reform_count, 0u);
    // Everything the objects had is free, and they come back streamed whole.
    run.frame({{2, 40}});
    EXPECT_EQ(run.streams().at(0).vertex_kept, 0u);
}

}  // namespace
}  // namespace occ::k
