// SPDX-License-Identifier: MIT
#include "defragment.h"
#include "scan.h"
#include "stream_collect.h"

#include "device_test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

using namespace occ::k;
using namespace occ::k::test;

using Streaming = DeviceTest;
using Defragment = DeviceTest;

namespace {

using Blocks = std::map<uint32_t, uint32_t>;  // object id -> vc (0 = listed but not drawn)

// Meshes whose every vertex and triangle is distinguishable: vertex i of mesh m is (m, i, 0.5),
// triangle t of mesh m is (m, t, 1000 + t). Objects instance meshes; two share mesh 1.
struct Scene {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    std::vector<uint64_t> vertex_first, triangle_first;
    std::vector<uint32_t> mesh_vertices, mesh_triangles;
    std::vector<ObjectInfo> objects;  // the host's copy, as DeviceScene::host_objects

    Scene(const std::vector<uint32_t>& vertices_per_mesh, const std::vector<uint32_t>& mesh_of_object) {
        for (uint32_t m = 0; m < vertices_per_mesh.size(); ++m) {
            vertex_first.push_back(positions.size());
            triangle_first.push_back(triangles.size() / 3);
            const uint32_t nv = vertices_per_mesh[m], nt = 2 * nv;
            for (uint32_t i = 0; i < nv; ++i) positions.emplace_back(float(m), float(i), 0.5f);
            for (uint32_t t = 0; t < nt; ++t) triangles.insert(triangles.end(), {m, t, 1000 + t});
            mesh_vertices.push_back(nv);
            mesh_triangles.push_back(nt);
        }
        objects.resize(mesh_of_object.size(), ObjectInfo{});
        for (size_t i = 0; i < mesh_of_object.size(); ++i) {
            objects[i].mesh = mesh_of_object[i];
            objects[i].vertex_count = vertices_per_mesh[mesh_of_object[i]];
        }
    }
    HostGeometry host() const {
        return {positions.data(), triangles.data(), vertex_first.data(), triangle_first.data(), objects.data()};
    }
    // A stand-in for map: the LOD with vc vertices has 2 vc - 1 triangles (0 for vc = 0).
    static uint32_t trianglesFor(uint32_t vc) { return vc ? 2 * vc - 1 : 0; }

    // Elements [first, first + n) of object `object`'s mesh.
    std::vector<glm::vec3> vertexRange(uint32_t object, uint32_t first, uint32_t n) const {
        const auto begin = positions.begin() + int64_t(vertex_first[objects[object].mesh] + first);
        return {begin, begin + n};
    }
    std::vector<uint32_t> triangleRange(uint32_t object, uint32_t first, uint32_t n) const {
        const auto begin = triangles.begin() + int64_t(3 * (triangle_first[objects[object].mesh] + first));
        return {begin, begin + 3 * int64_t(n)};
    }
};

// One frame's layout, the host's copy and the device's, from the same blocks (packed offsets).
LayoutPair layoutOf(const Blocks& blocks) {
    std::vector<uint32_t> ids, vc, tc;
    for (const auto& [object, vertices] : blocks) {
        ids.push_back(object);
        vc.push_back(vertices);
        tc.push_back(Scene::trianglesFor(vertices));
    }
    return LayoutPair(std::move(ids), std::move(vc), std::move(tc));
}

// What streamCollect must stage going from `before` to `after`: block by block in layout order,
// the elements [kept, size) with kept = min(old size, new size) for an object already resident.
struct Staged {
    std::vector<glm::vec3> vertices;
    std::vector<uint32_t> triangles;
};

Staged lackingParts(const Scene& scene, const Blocks& before, const Blocks& after) {
    Staged s;
    for (const auto& [object, vc] : after) {
        const auto it = before.find(object);
        const uint32_t kept_v = it == before.end() ? 0 : std::min(it->second, vc);
        const uint32_t tc = Scene::trianglesFor(vc);
        const uint32_t kept_t = it == before.end() ? 0 : std::min(Scene::trianglesFor(it->second), tc);
        const std::vector<glm::vec3> v = scene.vertexRange(object, kept_v, vc - kept_v);
        const std::vector<uint32_t> t = scene.triangleRange(object, kept_t, tc - kept_t);
        s.vertices.insert(s.vertices.end(), v.begin(), v.end());
        s.triangles.insert(s.triangles.end(), t.begin(), t.end());
    }
    return s;
}

// Runs streamCollect and checks what it staged, on both sides, and what crossed the bus.
StreamCounts collectAndCheck(const Scene& scene, const LayoutPair* previous, const Blocks& before,
                             const LayoutPair& current, const Blocks& after, StagingBuffers& staging) {
    const BusCounters start = busCounters();
    const StreamCounts sent =
        streamCollect(previous ? previous->host() : HostLayout{}, current.host(), scene.host(), staging);
    const BusCounters end = busCounters();
    // What was gathered crosses the bus in the one transfer, and nothing else does.
    EXPECT_EQ(end.h2d_bytes - start.h2d_bytes, sent.bytes());
    EXPECT_EQ(end.d2h_bytes, start.d2h_bytes);
    const Staged e = lackingParts(scene, previous ? before : Blocks{}, after);
    EXPECT_EQ(sent.vertices, e.vertices.size());
    EXPECT_EQ(3 * sent.triangles, e.triangles.size());
    EXPECT_EQ(staging.vertex_count, sent.vertices);
    EXPECT_EQ(staging.triangle_count, sent.triangles);
    EXPECT_EQ(std::vector<glm::vec3>(staging.vertices.begin(), staging.vertices.begin() + int64_t(sent.vertices)),
              e.vertices);
    EXPECT_EQ(
        std::vector<uint32_t>(staging.triangles.begin(), staging.triangles.begin() + 3 * int64_t(sent.triangles)),
        e.triangles);
    if (sent.vertices > 0) {
        EXPECT_EQ(toHost(staging.device_vertices, sent.vertices), e.vertices);
    }
    if (sent.triangles > 0) {
        EXPECT_EQ(toHost(staging.device_triangles, 3 * sent.triangles), e.triangles);
    }
    return sent;
}

const Scene& smallScene() {
    // Objects 0..4 on meshes 0, 1, 1, 2, 3 of 6, 8, 5, 7 vertices.
    static const Scene scene({6, 8, 5, 7}, {0, 1, 1, 2, 3});
    return scene;
}

const glm::vec3 kVertexSentinel(-7.0f, -7.0f, -7.0f);
constexpr uint32_t kCornerSentinel = 0xdeadbeef;

glm::vec3 stagedVertex(uint32_t i) { return glm::vec3(100.0f + float(i), 0.25f, -1.0f); }
glm::vec3 oldVertex(uint32_t i) { return glm::vec3(float(i), -0.5f, 2.0f); }

}  // namespace

// ---- streamCollect -------------------------------------------------------------------------

TEST_F(Streaming, CollectStagesWhatThePreviousFrameLackedFrameAfterFrame) {
    const Scene& scene = smallScene();
    const std::vector<Blocks> frames{
        {{0, 3}, {2, 5}},                  // first frame: everything staged
        {{0, 5}, {2, 5}},                  // object 0 grows: its two new vertices
        {{0, 2}, {2, 5}},                  // object 0 shrinks: nothing
        {{0, 2}, {1, 4}, {2, 5}, {4, 7}},  // objects 1 and 4 appear: whole
        {{1, 4}, {2, 3}, {4, 7}},          // object 0 disappears, 2 shrinks: nothing
        {{1, 4}, {2, 3}, {3, 0}, {4, 7}},  // object 3 listed but not drawn (vc = 0): nothing
        {{1, 6}, {2, 3}, {4, 7}},          // object 1 grows past its old size
        {{1, 6}, {2, 3}, {4, 7}},          // unchanged: nothing
    };
    StagingBuffers staging, whole_staging;
    std::unique_ptr<LayoutPair> previous;
    Blocks before;
    for (size_t f = 0; f < frames.size(); ++f) {
        SCOPED_TRACE(testing::Message() << "frame " << f);
        auto current = std::make_unique<LayoutPair>(layoutOf(frames[f]));
        collectAndCheck(scene, previous.get(), before, *current, frames[f], staging);
        // SNC: no previous layout, every block staged whole.
        const StreamCounts whole = collectAndCheck(scene, nullptr, {}, *current, frames[f], whole_staging);
        EXPECT_EQ(whole.vertices, current->vertex_total);
        EXPECT_EQ(whole.triangles, current->triangle_total);
        previous = std::move(current);
        before = frames[f];
    }
    EXPECT_EQ(staging.vertex_count + staging.triangle_count, 0u) << "the last two frames are the same";
}

TEST_F(Streaming, CollectOfAnEmptyFrameStagesNothing) {
    const Scene& scene = smallScene();
    StagingBuffers staging;
    const LayoutPair a = layoutOf({{0, 2}, {3, 4}}), empty = layoutOf({});
    collectAndCheck(scene, nullptr, {}, a, {{0, 2}, {3, 4}}, staging);
    const StreamCounts none = collectAndCheck(scene, &a, {{0, 2}, {3, 4}}, empty, {}, staging);
    EXPECT_EQ(none.vertices + none.triangles, 0u);
    const StreamCounts back = collectAndCheck(scene, &empty, {}, a, {{0, 2}, {3, 4}}, staging);
    EXPECT_EQ(back.vertices, 6u);
}

TEST_F(Streaming, LayoutsWhoseIdsAreNotAscendingAreRejected) {
    const Scene& scene = smallScene();
    StagingBuffers staging;
    const LayoutPair a = layoutOf({{0, 3}, {2, 5}});
    LayoutPair unsorted = layoutOf({{0, 3}, {2, 5}});
    unsorted.setObjects({2, 0});
    EXPECT_THROW(streamCollect(a.host(), unsorted.host(), scene.host(), staging), std::invalid_argument);
    LayoutPair repeated = layoutOf({{0, 3}, {2, 5}});
    repeated.setObjects({2, 2});
    EXPECT_THROW(streamCollect(HostLayout{}, repeated.host(), scene.host(), staging), std::invalid_argument);
}

// ---- defragmentVertices / defragmentTriangles: hand-checked moves ---------------------------

TEST_F(Defragment, ABlockThatStaysKeepsItsPrefixAndAppendsItsStagedPart) {
    // The block is at 10 with 3 vertices; it grows by 2 in place, from staging[2, 4).
    std::vector<glm::vec3> buffer(20, kVertexSentinel);
    for (uint32_t i = 0; i < 3; ++i) buffer[10 + i] = oldVertex(i);
    DeviceArray<glm::vec3> active = toDevice(buffer);
    std::vector<glm::vec3> staged;
    for (uint32_t i = 0; i < 5; ++i) staged.push_back(stagedVertex(i));
    const DeviceArray<glm::vec3> staging = toDevice(staged);
    const DeviceArray<BlockMove> moves = toDevice(std::vector<BlockMove>{{10, 10, 2, 3, 0, 2, 0}});
    ActiveArrays scratch;
    const BusCounters before = busCounters();
    EXPECT_EQ(defragmentVertices(moves.ptr(), 1, active.ptr(), active.ptr(), staging.ptr(), scratch), 2u);
    EXPECT_EQ(busCounters().h2d_bytes, before.h2d_bytes) << "defragment works on the device only";
    buffer[13] = stagedVertex(2);
    buffer[14] = stagedVertex(3);
    EXPECT_EQ(toHost(active), buffer);
}

TEST_F(Defragment, ABlockThatMovesCopiesItsKeptPrefixAndAppends) {
    // Two blocks in one buffer: A (4 vertices at 0) moves to 20 keeping 3 and appending 2;
    // B (2 vertices at 6) stays and appends 1. A's old place is left as it was.
    std::vector<glm::vec3> buffer(30, kVertexSentinel);
    for (uint32_t i = 0; i < 4; ++i) buffer[i] = oldVertex(i);
    buffer[6] = oldVertex(50), buffer[7] = oldVertex(51);
    DeviceArray<glm::vec3> active = toDevice(buffer);
    std::vector<glm::vec3> staged;
    for (uint32_t i = 0; i < 3; ++i) staged.push_back(stagedVertex(i));
    const DeviceArray<glm::vec3> staging = toDevice(staged);
    const DeviceArray<BlockMove> moves =
        toDevice(std::vector<BlockMove>{{0, 20, 0, 3, 3, 2, 0}, {6, 6, 2, 2, 0, 1, 0}});
    ActiveArrays scratch;
    EXPECT_EQ(defragmentVertices(moves.ptr(), 2, active.ptr(), active.ptr(), staging.ptr(), scratch), 3u + 2 + 1);
    std::vector<glm::vec3> expected = buffer;
    for (uint32_t i = 0; i < 3; ++i) expected[20 + i] = oldVertex(i);
    expected[23] = stagedVertex(0), expected[24] = stagedVertex(1);
    expected[8] = stagedVertex(2);
    EXPECT_EQ(toHost(active), expected);
}

TEST_F(Defragment, TrianglesMoveAndAppendThreeCornersAtATime) {
    // Triangle block A (2 triangles at 1) moves to 5, keeping 1 and appending 2 from staging[1];
    // block B (1 triangle at 3) stays and appends 1 from staging[0].
    std::vector<uint32_t> buffer(3 * 10, kCornerSentinel);
    const std::vector<uint32_t> a{10, 11, 12, 13, 14, 15}, b{20, 21, 22};
    std::copy(a.begin(), a.end(), buffer.begin() + 3);
    std::copy(b.begin(), b.end(), buffer.begin() + 9);
    DeviceArray<uint32_t> active = toDevice(buffer);
    const DeviceArray<uint32_t> staging = toDevice(std::vector<uint32_t>{30, 31, 32, 40, 41, 42, 43, 44, 45});
    const DeviceArray<BlockMove> moves =
        toDevice(std::vector<BlockMove>{{1, 5, 1, 1, 1, 2, 0}, {3, 3, 0, 1, 0, 1, 0}});
    ActiveArrays scratch;
    EXPECT_EQ(defragmentTriangles(moves.ptr(), 2, active.ptr(), active.ptr(), staging.ptr(), scratch), 1u + 2 + 1);
    std::vector<uint32_t> expected = buffer;
    const std::vector<uint32_t> moved_a{10, 11, 12, 40, 41, 42, 43, 44, 45};
    std::copy(moved_a.begin(), moved_a.end(), expected.begin() + 15);
    const std::vector<uint32_t> grown_b{30, 31, 32};
    std::copy(grown_b.begin(), grown_b.end(), expected.begin() + 12);
    EXPECT_EQ(toHost(active), expected);
}

TEST_F(Defragment, CompactionWritesAFreshBufferAndLeavesTheSourceAlone) {
    // Three blocks scattered in src (at 9, 2 and 15) are written back to back into dst, each
    // with its kept prefix and (for two of them) a staged part; a fourth is new (kept 0).
    std::vector<glm::vec3> src(20, kVertexSentinel);
    for (uint32_t i = 0; i < 3; ++i) src[9 + i] = oldVertex(i);
    for (uint32_t i = 0; i < 5; ++i) src[2 + i] = oldVertex(10 + i);
    for (uint32_t i = 0; i < 2; ++i) src[15 + i] = oldVertex(20 + i);
    const DeviceArray<glm::vec3> src_d = toDevice(src);
    DeviceArray<glm::vec3> dst = filledDevice<glm::vec3>(24, kVertexSentinel);
    std::vector<glm::vec3> staged;
    for (uint32_t i = 0; i < 6; ++i) staged.push_back(stagedVertex(i));
    const DeviceArray<glm::vec3> staging = toDevice(staged);
    const DeviceArray<BlockMove> moves = toDevice(std::vector<BlockMove>{
        {9, 0, 0, 3, 3, 1, 0},    // 3 kept + 1 staged at 0
        {2, 4, 1, 4, 4, 0, 0},    // shrunk: 4 of its 5 kept, at 4
        {15, 10, 1, 2, 2, 2, 0},  // 2 kept + 2 staged at 10 (a gap of 2 before it)
        {0, 16, 3, 0, 0, 3, 0},   // new: 3 staged at 16
    });
    ActiveArrays scratch;
    EXPECT_EQ(defragmentVertices(moves.ptr(), 4, src_d.ptr(), dst.ptr(), staging.ptr(), scratch),
              4u + 4 + 4 + 3);
    std::vector<glm::vec3> expected(24, kVertexSentinel);
    for (uint32_t i = 0; i < 3; ++i) expected[i] = oldVertex(i);
    expected[3] = stagedVertex(0);
    for (uint32_t i = 0; i < 4; ++i) expected[4 + i] = oldVertex(10 + i);
    expected[10] = oldVertex(20), expected[11] = oldVertex(21);
    expected[12] = stagedVertex(1), expected[13] = stagedVertex(2);
    for (uint32_t i = 0; i < 3; ++i) expected[16 + i] = stagedVertex(3 + i);
    EXPECT_EQ(toHost(dst), expected);
    EXPECT_EQ(toHost(src_d), src) << "the source of a compaction is read only";
}

TEST_F(Defragment, NoMovesWriteNothing) {
    std::vector<glm::vec3> vertices(8, kVertexSentinel);
    std::vector<uint32_t> corners(3 * 8, kCornerSentinel);
    DeviceArray<glm::vec3> v = toDevice(vertices);
    DeviceArray<uint32_t> t = toDevice(corners);
    const DeviceArray<glm::vec3> vs = toDevice(std::vector<glm::vec3>{stagedVertex(0)});
    const DeviceArray<uint32_t> ts = toDevice(std::vector<uint32_t>{1, 2, 3});
    // The one move there is, not passed: count 0.
    const DeviceArray<BlockMove> moves = toDevice(std::vector<BlockMove>{{0, 0, 0, 0, 0, 1, 0}});
    ActiveArrays scratch;
    EXPECT_EQ(defragmentVertices(moves.ptr(), 0, v.ptr(), v.ptr(), vs.ptr(), scratch), 0u);
    EXPECT_EQ(defragmentTriangles(moves.ptr(), 0, t.ptr(), t.ptr(), ts.ptr(), scratch), 0u);
    EXPECT_EQ(toHost(v), vertices);
    EXPECT_EQ(toHost(t), corners);
}

TEST_F(Defragment, ListedBlocksWithNothingToDoWriteNothing) {
    // Entries of no work (kept in place, nothing staged) among others, first, between and last.
    std::vector<glm::vec3> buffer(12, kVertexSentinel);
    buffer[0] = oldVertex(0);
    DeviceArray<glm::vec3> active = toDevice(buffer);
    const DeviceArray<glm::vec3> staging = toDevice(std::vector<glm::vec3>{stagedVertex(0), stagedVertex(1)});
    const DeviceArray<BlockMove> moves = toDevice(std::vector<BlockMove>{
        {0, 0, 0, 1, 0, 0, 0}, {0, 4, 0, 0, 0, 1, 0}, {0, 0, 1, 1, 0, 0, 0}, {0, 8, 1, 0, 0, 1, 0}, {0, 0, 2, 1, 0, 0, 0}});
    ActiveArrays scratch;
    EXPECT_EQ(defragmentVertices(moves.ptr(), 5, active.ptr(), active.ptr(), staging.ptr(), scratch), 2u);
    buffer[4] = stagedVertex(0);
    buffer[8] = stagedVertex(1);
    EXPECT_EQ(toHost(active), buffer);
}

TEST_F(Defragment, ManyBlocksAcrossTilesLandWhereTheirMovesSay) {
    // Enough blocks and elements that the work spans many tiles of the CPU kernel (4096
    // elements each) and blocks straddle tile boundaries.
    std::mt19937 rng(3);
    const uint32_t blocks = 700;
    std::vector<BlockMove> list;
    std::vector<uint32_t> src(3 * 400000, kCornerSentinel), staged;
    uint64_t from = 0, to = 0;
    for (uint32_t j = 0; j < blocks; ++j) {
        const uint32_t kept = std::uniform_int_distribution<uint32_t>(0, 120)(rng);
        const uint32_t extra = std::uniform_int_distribution<uint32_t>(0, 120)(rng);
        const bool moves = rng() % 2 == 0;
        for (uint32_t i = 0; i < 3 * kept; ++i) src[3 * from + i] = j << 12 | i;
        list.push_back({from, moves ? to : from, staged.size() / 3, kept, moves ? kept : 0, extra, 0});
        for (uint32_t i = 0; i < 3 * extra; ++i) staged.push_back(0x80000000u | j << 12 | i);
        from += kept + extra + std::uniform_int_distribution<uint32_t>(0, 5)(rng);
        to += kept + extra;
    }
    // Moved blocks go to a separate region of dst, after where the blocks staying in place end.
    for (BlockMove& m : list)
        if (m.moved) m.to += from;
    ASSERT_LE(from + to, src.size() / 3);
    const DeviceArray<uint32_t> src_d = toDevice(src), staging = toDevice(staged);
    DeviceArray<uint32_t> dst = toDevice(src);  // staying blocks keep what they had
    const DeviceArray<BlockMove> moves = toDevice(list);
    ActiveArrays scratch;
    uint64_t work = 0;
    std::vector<uint32_t> expected = src;
    for (const BlockMove& m : list) {
        work += m.moved + m.staged;
        for (uint32_t i = 0; i < 3 * m.moved; ++i) expected[3 * m.to + i] = src[3 * m.from + i];
        for (uint32_t i = 0; i < 3 * m.staged; ++i) expected[3 * (m.to + m.kept) + i] = staged[3 * m.staged_offset + i];
    }
    EXPECT_EQ(defragmentTriangles(moves.ptr(), blocks, src_d.ptr(), dst.ptr(), staging.ptr(), scratch), work);
    EXPECT_EQ(toHost(dst), expected);
}

// ---- streamCollect + defragment over random frames, the test playing allocator -------------

namespace {

// Where one object's blocks are, and what they hold (the allocator's and the pipeline's books).
struct Place {
    bool resident = false;
    uint64_t voff = 0, toff = 0;
    uint32_t vcap = 0, tcap = 0;  // room
    uint32_t vc = 0, tc = 0;      // held
};

// A block's room: its LOD plus a little to grow, never more than the whole mesh.
uint32_t roomFor(uint32_t n, uint32_t full) { return std::min(full, n + std::max<uint32_t>(n / 4, 8)); }

// First fit over [0, capacity) avoiding `taken` (ranges [first, first + n)); kNone when full.
constexpr uint64_t kNone = ~uint64_t(0);
uint64_t firstFit(std::vector<std::pair<uint64_t, uint64_t>> taken, uint64_t n, uint64_t capacity) {
    if (n == 0) return 0;
    std::sort(taken.begin(), taken.end());
    uint64_t at = 0;
    for (const auto& [first, length] : taken) {
        if (length == 0) continue;
        if (first >= at + n) break;
        at = std::max(at, first + length);
    }
    return at + n <= capacity ? at : kNone;
}

// One active array on the device, double-buffered, with a host mirror of both buffers that the
// test updates by the moves' definition.
template <class T, int W>
struct MirroredArray {
    DeviceArray<T> device[2];
    std::vector<T> mirror[2];
    T sentinel;

    explicit MirroredArray(T s) : sentinel(s) {}
    void fresh(uint32_t buffer, uint64_t capacity) {
        mirror[buffer].assign(W * capacity, sentinel);
        device[buffer] = toDevice(mirror[buffer]);
    }
    void applyToMirror(const std::vector<BlockMove>& moves, uint32_t from, uint32_t to, const std::vector<T>& staged) {
        std::vector<T> out = mirror[to];
        for (const BlockMove& m : moves) {
            for (uint64_t i = 0; i < W * uint64_t(m.moved); ++i) out[W * m.to + i] = mirror[from][W * m.from + i];
            for (uint64_t i = 0; i < W * uint64_t(m.staged); ++i)
                out[W * (m.to + m.kept) + i] = staged[W * m.staged_offset + i];
        }
        mirror[to] = std::move(out);
    }
};

}  // namespace

TEST_F(Streaming, RandomFrameSequencesKeepEveryBlockEqualToItsMeshPrefix) {
    // Mostly coherent frames (a few LODs change by a little, an object now and then appears or
    // disappears), with now and then a cut to an unrelated view. Blocks keep their place while
    // they fit their room, move by first fit when they outgrow it, and everything is compacted
    // into the other buffers when a heap is full (or, now and then, for no reason).
    std::mt19937 rng(11);
    std::vector<uint32_t> mesh_vertices, mesh_of_object;
    const uint32_t object_count = 80;
    for (int m = 0; m < 12; ++m) mesh_vertices.push_back(std::uniform_int_distribution<uint32_t>(1, 1500)(rng));
    for (uint32_t o = 0; o < object_count; ++o)
        mesh_of_object.push_back(std::uniform_int_distribution<uint32_t>(0, 11)(rng));
    const Scene scene(mesh_vertices, mesh_of_object);

    MirroredArray<glm::vec3, 1> vertices(kVertexSentinel);
    MirroredArray<uint32_t, 3> triangles(kCornerSentinel);
    uint32_t current = 0;
    uint64_t vcapacity = 4096, tcapacity = 4096;
    vertices.fresh(0, vcapacity), triangles.fresh(0, tcapacity);
    std::vector<Place> places(object_count);
    StagingBuffers staging;
    ActiveArrays scratch;
    Blocks blocks, before;
    // The previous frame's host layout (ids, sizes, offsets where the blocks are).
    std::vector<uint32_t> prev_ids, prev_vc, prev_tc;
    std::vector<uint64_t> prev_voff, prev_toff;
    HostLayout previous;

    const auto randomLevel = [&](uint32_t object) {
        return std::uniform_int_distribution<uint32_t>(0, scene.objects[object].vertex_count)(rng);
    };
    uint64_t stayed_and_grew = 0, moved_blocks = 0, compactions = 0;
    for (int f = 0; f < 150; ++f) {
        SCOPED_TRACE(testing::Message() << "frame " << f);
        if (f % 40 == 39) blocks.clear();
        const int changes = std::uniform_int_distribution<int>(0, f % 40 == 0 ? 80 : 5)(rng);
        for (int c = 0; c < changes; ++c) {
            const uint32_t object = std::uniform_int_distribution<uint32_t>(0, object_count - 1)(rng);
            const int what = std::uniform_int_distribution<int>(0, 9)(rng);
            if (what == 0) {
                blocks.erase(object);
            } else if (what == 1 || !blocks.count(object)) {
                blocks[object] = randomLevel(object);
            } else {
                const int delta = std::uniform_int_distribution<int>(-30, 40)(rng);
                blocks[object] = uint32_t(std::clamp<int64_t>(int64_t(blocks[object]) + delta, 0,
                                                              scene.objects[object].vertex_count));
            }
        }

        // This frame's layout and places, the test playing a first-fit allocator (the pipeline's is
        // block_layout.h's segregated fit; defragment takes any placement without overlaps).
        std::vector<uint32_t> ids, vc, tc;
        for (const auto& [object, n] : blocks) ids.push_back(object), vc.push_back(n), tc.push_back(Scene::trianglesFor(n));
        const uint32_t n = uint32_t(ids.size());
        std::vector<uint64_t> voff(n), toff(n);
        std::vector<uint32_t> vcap(n), tcap(n);
        // Old ranges stay taken until after the frame, so that no move writes where another reads.
        std::vector<std::pair<uint64_t, uint64_t>> vtaken, ttaken;
        for (const Place& p : places)
            if (p.resident) vtaken.emplace_back(p.voff, p.vcap), ttaken.emplace_back(p.toff, p.tcap);
        bool compact = rng() % 16 == 0;
        for (uint32_t j = 0; j < n && !compact; ++j) {
            const Place& p = places[ids[j]];
            if (p.resident && vc[j] <= p.vcap && tc[j] <= p.tcap) {
                voff[j] = p.voff, toff[j] = p.toff, vcap[j] = p.vcap, tcap[j] = p.tcap;
                continue;
            }
            vcap[j] = roomFor(vc[j], scene.objects[ids[j]].vertex_count);
            tcap[j] = Scene::trianglesFor(vcap[j]);
            voff[j] = firstFit(vtaken, vcap[j], vcapacity);
            toff[j] = firstFit(ttaken, tcap[j], tcapacity);
            if (voff[j] == kNone || toff[j] == kNone) compact = true;
            vtaken.emplace_back(voff[j], vcap[j]), ttaken.emplace_back(toff[j], tcap[j]);
        }
        const uint32_t to = compact ? current ^ 1 : current;
        if (compact) {
            uint64_t v = 0, t = 0;
            for (uint32_t j = 0; j < n; ++j) {
                vcap[j] = roomFor(vc[j], scene.objects[ids[j]].vertex_count);
                tcap[j] = Scene::trianglesFor(vcap[j]);
                voff[j] = v, toff[j] = t;
                v += vcap[j], t += tcap[j];
            }
            vcapacity = std::max<uint64_t>(4096, v + v / 2);
            tcapacity = std::max<uint64_t>(4096, t + t / 2);
            vertices.fresh(to, vcapacity), triangles.fresh(to, tcapacity);
            ++compactions;
        }

        // The moves, block by block in layout order, which is the order streamCollect stages in.
        std::vector<BlockMove> vmoves, tmoves;
        uint64_t staged_v = 0, staged_t = 0;
        for (uint32_t j = 0; j < n; ++j) {
            const Place& p = places[ids[j]];
            const uint32_t kept_v = p.resident ? std::min(p.vc, vc[j]) : 0;
            const uint32_t kept_t = p.resident ? std::min(p.tc, tc[j]) : 0;
            const bool placed = !p.resident || voff[j] != p.voff || toff[j] != p.toff || compact;
            const uint32_t sv = vc[j] - kept_v, st = tc[j] - kept_t;
            const uint32_t mv = placed ? kept_v : 0, mt = placed ? kept_t : 0;
            if (mv + sv > 0) vmoves.push_back({p.voff, voff[j], staged_v, kept_v, mv, sv, 0});
            if (mt + st > 0) tmoves.push_back({p.toff, toff[j], staged_t, kept_t, mt, st, 0});
            staged_v += sv, staged_t += st;
            if (!compact) {
                stayed_and_grew += !placed && (sv > 0 || st > 0);
                moved_blocks += placed && p.resident && (mv > 0 || mt > 0);
            }
        }

        const HostLayout layout{ids.data(), vc.data(), tc.data(), voff.data(), toff.data(), n, 0, 0};
        const StreamCounts sent = streamCollect(previous, layout, scene.host(), staging);
        ASSERT_EQ(sent.vertices, staged_v);
        ASSERT_EQ(sent.triangles, staged_t);
        const Staged expected_staging = lackingParts(scene, before, blocks);
        ASSERT_EQ(std::vector<glm::vec3>(staging.vertices.begin(), staging.vertices.begin() + int64_t(staged_v)),
                  expected_staging.vertices);

        const DeviceArray<BlockMove> vmoves_d = toDevice(vmoves), tmoves_d = toDevice(tmoves);
        const BusCounters bus = busCounters();
        uint64_t work_v = 0, work_t = 0;
        for (const BlockMove& m : vmoves) work_v += m.moved + m.staged;
        for (const BlockMove& m : tmoves) work_t += m.moved + m.staged;
        EXPECT_EQ(defragmentVertices(vmoves_d.ptr(), uint32_t(vmoves.size()), vertices.device[current].ptr(),
                                     vertices.device[to].ptr(), staging.device_vertices.ptr(), scratch),
                  work_v);
        EXPECT_EQ(defragmentTriangles(tmoves_d.ptr(), uint32_t(tmoves.size()), triangles.device[current].ptr(),
                                      triangles.device[to].ptr(), staging.device_triangles.ptr(), scratch),
                  work_t);
        EXPECT_EQ(busCounters().h2d_bytes, bus.h2d_bytes) << "defragment works on the device only";

        // The whole destination buffers equal the moves applied by hand: nothing outside the
        // listed blocks' writes changed.
        vertices.applyToMirror(vmoves, current, to, expected_staging.vertices);
        triangles.applyToMirror(tmoves, current, to, expected_staging.triangles);
        ASSERT_EQ(toHost(vertices.device[to]), vertices.mirror[to]);
        ASSERT_EQ(toHost(triangles.device[to]), triangles.mirror[to]);
        // And every block is its object's mesh prefix, where its place says.
        for (uint32_t j = 0; j < n; ++j) {
            SCOPED_TRACE(testing::Message() << "object " << ids[j]);
            const auto v = vertices.mirror[to].begin() + int64_t(voff[j]);
            ASSERT_EQ(std::vector<glm::vec3>(v, v + vc[j]), scene.vertexRange(ids[j], 0, vc[j]));
            const auto t = triangles.mirror[to].begin() + 3 * int64_t(toff[j]);
            ASSERT_EQ(std::vector<uint32_t>(t, t + 3 * int64_t(tc[j])), scene.triangleRange(ids[j], 0, tc[j]));
        }

        // After the frame: old places are given back, the new ones recorded.
        for (Place& p : places) p.resident = false;
        for (uint32_t j = 0; j < n; ++j) places[ids[j]] = {true, voff[j], toff[j], vcap[j], tcap[j], vc[j], tc[j]};
        current = to;
        prev_ids = ids, prev_vc = vc, prev_tc = tc, prev_voff = voff, prev_toff = toff;
        previous = {prev_ids.data(), prev_vc.data(), prev_tc.data(), prev_voff.data(), prev_toff.data(), n, 0, 0};
        before = blocks;
    }
    // Every kind of frame was exercised.
    EXPECT_GT(stayed_and_grew, 0u);
    EXPECT_GT(moved_blocks, 0u);
    EXPECT_GT(compactions, 1u);
}

// ---- streamObjectByObject --------------------------------------------------------------------

TEST_F(Streaming, ObjectByObjectCopiesEveryBlockWholeToItsPlace) {
    // Blocks at non-contiguous offsets, out of offset order: each gets its object's full prefix,
    // with one bus copy per block and array; the gaps keep the sentinel.
    const Scene& scene = smallScene();
    const std::vector<uint32_t> ids{0, 2, 3, 4}, vc{3, 5, 5, 1}, tc{5, 9, 9, 1};
    const std::vector<uint64_t> voff{10, 0, 20, 8}, toff{30, 2, 12, 0};
    const HostLayout layout{ids.data(), vc.data(), tc.data(), voff.data(), toff.data(), 4, 14, 24};
    DeviceArray<glm::vec3> vertices = filledDevice<glm::vec3>(30, kVertexSentinel);
    DeviceArray<uint32_t> triangles = filledDevice<uint32_t>(3 * 40, kCornerSentinel);
    const std::vector<StreamBlock> list = streamList(HostLayout{}, layout);
    const BusCounters before = busCounters();
    const StreamCounts c = streamObjectByObject(list.data(), uint32_t(list.size()), scene.host(), vertices.ptr(),
                                                triangles.ptr());
    EXPECT_EQ(c.vertices, 14u);
    EXPECT_EQ(c.triangles, 24u);
    EXPECT_EQ(busCounters().h2d_bytes - before.h2d_bytes, c.bytes());
    EXPECT_EQ(busCounters().h2d_copies - before.h2d_copies, 2u * ids.size());
    std::vector<glm::vec3> ev(30, kVertexSentinel);
    std::vector<uint32_t> et(3 * 40, kCornerSentinel);
    for (size_t j = 0; j < ids.size(); ++j) {
        const std::vector<glm::vec3> v = scene.vertexRange(ids[j], 0, vc[j]);
        const std::vector<uint32_t> t = scene.triangleRange(ids[j], 0, tc[j]);
        std::copy(v.begin(), v.end(), ev.begin() + int64_t(voff[j]));
        std::copy(t.begin(), t.end(), et.begin() + 3 * int64_t(toff[j]));
    }
    EXPECT_EQ(toHost(vertices), ev);
    EXPECT_EQ(toHost(triangles), et);
}

TEST_F(Streaming, ObjectByObjectAndDefragmentMayAlternate) {
    // NS fills the blocks of one frame; the next frame streams coherently from what it wrote.
    const Scene& scene = smallScene();
    const std::vector<uint32_t> ids{0, 2}, vc{3, 5}, tc{5, 9};
    const std::vector<uint64_t> voff{0, 10}, toff{0, 20};
    const HostLayout a{ids.data(), vc.data(), tc.data(), voff.data(), toff.data(), 2, 8, 14};
    DeviceArray<glm::vec3> vertices = filledDevice<glm::vec3>(32, kVertexSentinel);
    DeviceArray<uint32_t> triangles = filledDevice<uint32_t>(3 * 48, kCornerSentinel);
    const std::vector<StreamBlock> whole = streamList(HostLayout{}, a);
    streamObjectByObject(whole.data(), uint32_t(whole.size()), scene.host(), vertices.ptr(), triangles.ptr());
    // Next: object 0 grows to 4 in place, object 2 shrinks to 2 in place, object 4 (3) is new.
    const std::vector<uint32_t> ids2{0, 2, 4}, vc2{4, 2, 3}, tc2{7, 3, 5};
    const std::vector<uint64_t> voff2{0, 10, 20}, toff2{0, 20, 30};
    const HostLayout b{ids2.data(), vc2.data(), tc2.data(), voff2.data(), toff2.data(), 3, 9, 15};
    StagingBuffers staging;
    const StreamCounts sent = streamCollect(a, b, scene.host(), staging);
    EXPECT_EQ(sent.vertices, 1u + 0 + 3);
    EXPECT_EQ(sent.triangles, 2u + 0 + 5);
    const DeviceArray<BlockMove> vm = toDevice(std::vector<BlockMove>{{0, 0, 0, 3, 0, 1, 0}, {0, 20, 1, 0, 0, 3, 0}});
    const DeviceArray<BlockMove> tm = toDevice(std::vector<BlockMove>{{0, 0, 0, 5, 0, 2, 0}, {0, 30, 2, 0, 0, 5, 0}});
    ActiveArrays scratch;
    defragmentVertices(vm.ptr(), 2, vertices.ptr(), vertices.ptr(), staging.device_vertices.ptr(), scratch);
    defragmentTriangles(tm.ptr(), 2, triangles.ptr(), triangles.ptr(), staging.device_triangles.ptr(), scratch);
    const std::vector<glm::vec3> v = toHost(vertices);
    const std::vector<uint32_t> t = toHost(triangles);
    for (uint32_t j = 0; j < 3; ++j) {
        SCOPED_TRACE(testing::Message() << "object " << ids2[j]);
        EXPECT_EQ(std::vector<glm::vec3>(v.begin() + int64_t(voff2[j]), v.begin() + int64_t(voff2[j] + vc2[j])),
                  scene.vertexRange(ids2[j], 0, vc2[j]));
        EXPECT_EQ(std::vector<uint32_t>(t.begin() + 3 * int64_t(toff2[j]), t.begin() + 3 * int64_t(toff2[j] + tc2[j])),
                  scene.triangleRange(ids2[j], 0, tc2[j]));
    }
}
