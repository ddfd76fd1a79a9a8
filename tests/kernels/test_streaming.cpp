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
};

// One frame's layout, the host's copy and the device's, from the same blocks.
LayoutPair layoutOf(const Blocks& blocks) {
    std::vector<uint32_t> ids, vc, tc;
    for (const auto& [object, vertices] : blocks) {
        ids.push_back(object);
        vc.push_back(vertices);
        tc.push_back(Scene::trianglesFor(vertices));
    }
    return LayoutPair(std::move(ids), std::move(vc), std::move(tc));
}

// The active arrays built from scratch, by a plain loop.
struct Expected {
    std::vector<glm::vec3> vertices;
    std::vector<uint32_t> triangles;
};

Expected fromScratch(const Scene& scene, const Blocks& blocks) {
    Expected e;
    for (const auto& [object, vertices] : blocks) {
        const uint32_t mesh = scene.objects[object].mesh;
        for (uint32_t i = 0; i < vertices; ++i) e.vertices.push_back(scene.positions[scene.vertex_first[mesh] + i]);
        for (uint32_t t = 0; t < Scene::trianglesFor(vertices); ++t)
            for (int c = 0; c < 3; ++c) e.triangles.push_back(scene.triangles[3 * (scene.triangle_first[mesh] + t) + c]);
    }
    return e;
}

void expectHolds(const ActiveArrays& active, const Expected& e) {
    ASSERT_EQ(active.vertices.count, e.vertices.size());
    ASSERT_EQ(active.triangles.count * 3, e.triangles.size());
    EXPECT_EQ(toHost(active.vertices.data(), e.vertices.size()), e.vertices);
    EXPECT_EQ(toHost(active.triangles.data(), e.triangles.size()), e.triangles);
}

// Drives one pipeline across frames the way the renderer does: previous layout kept, active
// arrays and staging reused.
struct Streamer {
    explicit Streamer(const Scene& s, bool use_previous = true) : scene(s), coherent(use_previous) {}

    const Scene& scene;
    bool coherent;
    std::unique_ptr<LayoutPair> previous;
    ActiveArrays active;
    StagingBuffers staging;
    StreamCounts sent;
    DefragmentCounts written;

    void frame(const Blocks& blocks) {
        auto current = std::make_unique<LayoutPair>(layoutOf(blocks));
        const bool keep = previous && coherent;
        const BusCounters before = busCounters();
        sent = streamCollect(keep ? previous->host() : HostLayout{}, current->host(), scene.host(), staging);
        // What was gathered crosses the bus in the one transfer, and nothing else does.
        const BusCounters collected = busCounters();
        EXPECT_EQ(collected.h2d_bytes - before.h2d_bytes, sent.bytes());
        EXPECT_EQ(collected.d2h_bytes, before.d2h_bytes);
        written = defragment(keep ? previous->device() : ActiveLayout{}, current->device(), staging, active);
        EXPECT_EQ(busCounters().h2d_bytes, collected.h2d_bytes) << "defragment works on the device only";
        previous = std::move(current);
    }
};

// Vertices the last frame lacked: sum over blocks of vc_new - min(vc_old, vc_new).
uint64_t lacking(const Blocks& before, const Blocks& after,
                 uint32_t (*count)(uint32_t)) {
    uint64_t n = 0;
    for (const auto& [object, vertices] : after) {
        const auto it = before.find(object);
        const uint32_t kept = it == before.end() ? 0 : std::min(count(it->second), count(vertices));
        n += count(vertices) - kept;
    }
    return n;
}

uint32_t identity(uint32_t vc) { return vc; }

const Scene& smallScene() {
    // Objects 0..4 on meshes 0, 1, 1, 2, 3 of 6, 8, 5, 7 vertices.
    static const Scene scene({6, 8, 5, 7}, {0, 1, 1, 2, 3});
    return scene;
}

}  // namespace

TEST_F(Streaming, FramesGrowShrinkAppearDisappearAndStayEqualToAFreshBuild) {
    const Scene& scene = smallScene();
    const std::vector<Blocks> frames{
        {{0, 3}, {2, 5}},                   // first frame: everything streamed
        {{0, 5}, {2, 5}},                   // object 0 grows: object 2 moves right
        {{0, 2}, {2, 5}},                   // object 0 shrinks: object 2 moves left
        {{0, 2}, {1, 4}, {2, 5}, {4, 7}},   // objects 1 and 4 appear
        {{1, 4}, {2, 3}, {4, 7}},           // object 0 disappears, 2 shrinks
        {{1, 4}, {2, 3}, {3, 0}, {4, 7}},   // object 3 listed but not drawn (vc = 0)
        {{1, 4}, {2, 3}, {4, 7}},           // unchanged drawn set and LODs
    };
    Streamer coherent(scene);
    Streamer whole(scene, false);  // SNC
    Blocks before;
    for (size_t f = 0; f < frames.size(); ++f) {
        SCOPED_TRACE(testing::Message() << "frame " << f);
        coherent.frame(frames[f]);
        whole.frame(frames[f]);
        const Expected e = fromScratch(scene, frames[f]);
        expectHolds(coherent.active, e);
        expectHolds(whole.active, e);
        EXPECT_EQ(coherent.sent.vertices, lacking(before, frames[f], identity));
        EXPECT_EQ(coherent.sent.triangles, lacking(before, frames[f], Scene::trianglesFor));
        EXPECT_EQ(coherent.written.vertices_copied, coherent.sent.vertices);
        EXPECT_EQ(whole.sent.vertices, e.vertices.size());
        EXPECT_EQ(whole.sent.triangles * 3, e.triangles.size());
        before = frames[f];
    }
    // The last two frames draw the same blocks: nothing streamed, nothing written.
    EXPECT_EQ(coherent.sent.vertices + coherent.sent.triangles, 0u);
    EXPECT_EQ(coherent.written.vertices_moved + coherent.written.triangles_moved + coherent.written.vertices_bounced +
                  coherent.written.triangles_bounced + coherent.written.vertices_copied +
                  coherent.written.triangles_copied,
              0u);
}

TEST_F(Streaming, AGrowingLastBlockIsExtendedInPlace) {
    Streamer s(smallScene());
    s.frame({{0, 3}, {1, 2}, {4, 3}});
    s.frame({{0, 3}, {1, 2}, {4, 6}});
    expectHolds(s.active, fromScratch(smallScene(), {{0, 3}, {1, 2}, {4, 6}}));
    EXPECT_EQ(s.written.vertices_copied, 3u);
    EXPECT_EQ(s.written.vertices_moved, 0u);
    EXPECT_EQ(s.written.triangles_copied, 6u);
    EXPECT_EQ(s.written.triangles_moved, 0u);
}

TEST_F(Streaming, AFewMovedBlocksAreBouncedInPlace) {
    Streamer s(smallScene());
    s.frame({{0, 6}, {1, 8}, {2, 5}, {4, 1}});
    s.frame({{0, 6}, {1, 8}, {2, 4}, {4, 1}});  // the last block moves one to the left
    expectHolds(s.active, fromScratch(smallScene(), {{0, 6}, {1, 8}, {2, 4}, {4, 1}}));
    EXPECT_EQ(s.written.vertices_moved, 1u);
    EXPECT_EQ(s.written.vertices_bounced, 1u);
    EXPECT_EQ(s.written.vertices_copied, 0u);
}

TEST_F(Streaming, WhenMostBlocksMoveTheOtherBufferIsWrittenOnce) {
    Streamer s(smallScene());
    s.frame({{0, 2}, {1, 8}, {2, 5}, {4, 7}});
    s.frame({{0, 3}, {1, 8}, {2, 5}, {4, 7}});  // every later block moves one to the right
    expectHolds(s.active, fromScratch(smallScene(), {{0, 3}, {1, 8}, {2, 5}, {4, 7}}));
    EXPECT_EQ(s.written.vertices_copied, 1u);
    EXPECT_EQ(s.written.vertices_moved, 2u + 8 + 5 + 7);
    EXPECT_EQ(s.written.vertices_bounced, 0u);
}

TEST_F(Streaming, AnEmptyFrameEmptiesTheActiveArrays) {
    Streamer s(smallScene());
    s.frame({{0, 2}, {3, 4}});
    s.frame({});
    expectHolds(s.active, {});
    s.frame({{3, 4}});
    expectHolds(s.active, fromScratch(smallScene(), {{3, 4}}));
    EXPECT_EQ(s.sent.vertices, 4u);
}

TEST_F(Streaming, ObjectByObjectCopiesTheSameActiveArrays) {
    const Scene& scene = smallScene();
    ActiveArrays active;
    for (const Blocks& blocks :
         {Blocks{{0, 3}, {2, 5}}, {{0, 6}, {1, 1}, {2, 5}, {3, 7}}, {{4, 2}}}) {
        const LayoutPair l = layoutOf(blocks);
        const BusCounters before = busCounters();
        const StreamCounts c = streamObjectByObject(l.host(), scene.host(), active);
        // One copy per drawn object and array (every block here has vertices and triangles).
        EXPECT_EQ(busCounters().h2d_bytes - before.h2d_bytes, c.bytes());
        EXPECT_EQ(busCounters().h2d_copies - before.h2d_copies, 2 * blocks.size());
        const Expected e = fromScratch(scene, blocks);
        expectHolds(active, e);
        EXPECT_EQ(c.vertices, e.vertices.size());
    }
}

TEST_F(Streaming, ObjectByObjectAndDefragmentMayAlternate) {
    const Scene& scene = smallScene();
    ActiveArrays active;
    StagingBuffers staging;
    const LayoutPair a = layoutOf({{0, 3}, {2, 5}}), b = layoutOf({{0, 4}, {2, 2}, {4, 3}});
    streamObjectByObject(a.host(), scene.host(), active);
    streamCollect(a.host(), b.host(), scene.host(), staging);
    defragment(a.device(), b.device(), staging, active);
    expectHolds(active, fromScratch(scene, {{0, 4}, {2, 2}, {4, 3}}));
}

TEST_F(Streaming, DefragmentRejectsAPreviousLayoutTheActiveArraysDoNotHold) {
    const Scene& scene = smallScene();
    Streamer s(scene);
    s.frame({{0, 3}, {2, 5}});
    const LayoutPair wrong = layoutOf({{0, 4}, {2, 5}}), next = layoutOf({{0, 5}});
    streamCollect(wrong.host(), next.host(), scene.host(), s.staging);
    EXPECT_THROW(defragment(wrong.device(), next.device(), s.staging, s.active), std::invalid_argument);
}

TEST_F(Streaming, DefragmentRejectsStagingCollectedForOtherLayouts) {
    const Scene& scene = smallScene();
    Streamer s(scene);
    s.frame({{0, 3}, {2, 5}});
    const LayoutPair other = layoutOf({{0, 6}}), next = layoutOf({{0, 5}, {2, 5}});
    streamCollect(s.previous->host(), other.host(), scene.host(), s.staging);
    EXPECT_THROW(defragment(s.previous->device(), next.device(), s.staging, s.active), std::invalid_argument);
    expectHolds(s.active, fromScratch(scene, {{0, 3}, {2, 5}}));  // untouched
}

TEST_F(Streaming, LayoutsWhoseIdsAreNotAscendingAreRejected) {
    const Scene& scene = smallScene();
    Streamer s(scene);
    s.frame({{0, 3}, {2, 5}});
    LayoutPair unsorted = layoutOf({{0, 3}, {2, 5}});
    unsorted.setObjects({2, 0});
    EXPECT_THROW(streamCollect(s.previous->host(), unsorted.host(), scene.host(), s.staging), std::invalid_argument);
    EXPECT_THROW(defragment(s.previous->device(), unsorted.device(), s.staging, s.active), std::invalid_argument);
}

TEST_F(Streaming, RandomFrameSequencesMatchAFreshBuild) {
    // Mostly coherent frames (a few LODs change by a little, an object now and then appears or
    // disappears), with now and then a cut to an unrelated view.
    std::mt19937 rng(11);
    std::vector<uint32_t> mesh_vertices, mesh_of_object;
    for (int m = 0; m < 12; ++m) mesh_vertices.push_back(std::uniform_int_distribution<uint32_t>(1, 9000)(rng));
    for (int o = 0; o < 80; ++o) mesh_of_object.push_back(std::uniform_int_distribution<uint32_t>(0, 11)(rng));
    const Scene scene(mesh_vertices, mesh_of_object);
    Streamer coherent(scene);
    ActiveArrays by_object;
    Blocks blocks;
    const auto randomLevel = [&](uint32_t object) {
        return std::uniform_int_distribution<uint32_t>(0, scene.objects[object].vertex_count)(rng);
    };
    uint64_t in_place = 0, double_buffered = 0;
    for (int f = 0; f < 120; ++f) {
        SCOPED_TRACE(testing::Message() << "frame " << f);
        if (f % 40 == 39) blocks.clear();
        const int changes = std::uniform_int_distribution<int>(0, f % 40 == 0 ? 80 : 4)(rng);
        for (int c = 0; c < changes; ++c) {
            const uint32_t object = std::uniform_int_distribution<uint32_t>(0, 79)(rng);
            const int what = std::uniform_int_distribution<int>(0, 9)(rng);
            if (what == 0) {
                blocks.erase(object);
            } else if (what == 1 || !blocks.count(object)) {
                blocks[object] = randomLevel(object);
            } else {
                const int delta = std::uniform_int_distribution<int>(-30, 30)(rng);
                blocks[object] = uint32_t(std::clamp<int64_t>(int64_t(blocks[object]) + delta, 0,
                                                              scene.objects[object].vertex_count));
            }
        }
        coherent.frame(blocks);
        const Expected e = fromScratch(scene, blocks);
        expectHolds(coherent.active, e);
        const LayoutPair l = layoutOf(blocks);
        streamObjectByObject(l.host(), scene.host(), by_object);
        expectHolds(by_object, e);
        (coherent.written.vertices_bounced > 0 ? in_place : double_buffered) += coherent.written.vertices_moved > 0;
    }
    // Both strategies were exercised.
    EXPECT_GT(in_place, 0u);
    EXPECT_GT(double_buffered, 0u);
}
