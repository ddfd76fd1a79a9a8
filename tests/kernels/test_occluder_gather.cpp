// SPDX-License-Identifier: MIT
#include "occluder_gather.h"

#include "depth_raster.h"

#include "device_test_support.h"
#include "raster_fixtures.h"
#include "simd_level.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace occ::k {
namespace {

using test::toDevice;
using test::toHost;

using GatherOccluders = test::DeviceTest;

constexpr uint32_t kNone = UINT32_MAX;  // no triangle across the edge

// Two meshes, resident as MeshGeometry wants them. Mesh 0 is one lone triangle, there so that
// mesh 1 starts at vertex 3 and triangle 1, not at 0. Mesh 1 is the unit quad 0 -> 1 -> 2,
// 0 -> 2 -> 3 in z = 0, whose diagonal is edge 2 of its triangle 0 and edge 0 of its triangle 1
// (sharedEdgeFlags' answer: flags 4 and 1, each triangle naming the other across it).
// Objects 1 and 2 instance mesh 1 under different world matrices; object 0 is mesh 0.
struct TwoMeshScene {
    std::vector<glm::vec3> positions = {{100, 100, 100}, {101, 100, 100}, {100, 101, 100},  // mesh 0
                                        {0, 0, 0},       {1, 0, 0},       {1, 1, 0},       {0, 1, 0}};
    std::vector<uint32_t> triangles = {0, 1, 2,  0, 1, 2, 0, 2, 3};
    std::vector<uint8_t> edge_flags = {0, 4, 1};
    std::vector<uint32_t> edge_neighbours = {kNone, kNone, kNone,  kNone, kNone, 1, 0, kNone, kNone};
    std::vector<uint64_t> vertex_first = {0, 3}, triangle_first = {0, 1};
    std::vector<ObjectInfo> objects = {object(0, 3, 1), object(1, 4, 2), object(1, 4, 2)};
    std::vector<glm::mat4> world = {glm::mat4(1.0f), glm::translate(glm::mat4(1.0f), glm::vec3(10, 0, 0)),
                                    glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, -5)), glm::vec3(2))};

    DeviceArray<glm::vec3> positions_d = toDevice(positions);
    DeviceArray<uint32_t> triangles_d = toDevice(triangles);
    DeviceArray<uint8_t> edge_flags_d = toDevice(edge_flags);
    DeviceArray<uint32_t> edge_neighbours_d = toDevice(edge_neighbours);
    DeviceArray<uint64_t> vertex_first_d = toDevice(vertex_first), triangle_first_d = toDevice(triangle_first);
    DeviceArray<ObjectInfo> objects_d = toDevice(objects);
    DeviceArray<glm::mat4> world_d = toDevice(world);

    static ObjectInfo object(uint32_t mesh, uint32_t vertices, uint32_t triangles) {
        ObjectInfo o{};
        o.mesh = mesh;
        o.vertex_count = vertices;
        o.triangle_count = triangles;
        return o;
    }
    MeshGeometry meshes() const {
        return {positions_d.ptr(),      triangles_d.ptr(),     edge_flags_d.ptr(), edge_neighbours_d.ptr(),
                vertex_first_d.ptr(),   triangle_first_d.ptr()};
    }
    void gather(const std::vector<uint32_t>& ids, OccluderGeometry& out, const glm::vec3* eye = nullptr) const {
        const DeviceArray<uint32_t> ids_d = toDevice(ids);
        gatherOccluders(objects_d.ptr(), world_d.ptr(), meshes(), ids_d.ptr(), uint32_t(ids.size()), out, eye);
    }
};

TEST_F(GatherOccluders, InstancesOfOneMeshAreTransformedAndPutBackToBack) {
    const TwoMeshScene scene;
    OccluderGeometry out;
    scene.gather({2, 1}, out);  // not in id order: occluder 0 is object 2
    ASSERT_EQ(out.vertex_total, 8u);
    ASSERT_EQ(out.triangle_total, 4u);
    // Object 2 scales the quad by 2 and moves it to z = -5; object 1 moves it to x = 10.
    EXPECT_EQ(toHost(out.positions, 8), (std::vector<glm::vec3>{{0, 0, -5}, {2, 0, -5}, {2, 2, -5}, {0, 2, -5},
                                                                 {10, 0, 0}, {11, 0, 0}, {11, 1, 0}, {10, 1, 0}}));
    // The second occluder's corners count from its first vertex, 4.
    EXPECT_EQ(toHost(out.triangles, 12), (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7}));
    EXPECT_EQ(toHost(out.edge_flags, 4), (std::vector<uint8_t>{4, 1, 4, 1}));
    // Neighbours count from the occluder's first triangle, 2 for the second; none stays none.
    EXPECT_EQ(toHost(out.edge_neighbours, 12),
              (std::vector<uint32_t>{kNone, kNone, 1, 0, kNone, kNone, kNone, kNone, 3, 2, kNone, kNone}));
}

TEST_F(GatherOccluders, EachOccluderReadsItsOwnMesh) {
    const TwoMeshScene scene;
    OccluderGeometry out;
    scene.gather({1, 0}, out);  // the quad at x = 10, then the lone triangle (identity world)
    ASSERT_EQ(out.vertex_total, 7u);
    ASSERT_EQ(out.triangle_total, 3u);
    EXPECT_EQ(toHost(out.positions, 7), (std::vector<glm::vec3>{{10, 0, 0}, {11, 0, 0}, {11, 1, 0}, {10, 1, 0},
                                                                 {100, 100, 100}, {101, 100, 100}, {100, 101, 100}}));
    EXPECT_EQ(toHost(out.triangles, 9), (std::vector<uint32_t>{0, 1, 2, 0, 2, 3, 4, 5, 6}));
    EXPECT_EQ(toHost(out.edge_flags, 3), (std::vector<uint8_t>{4, 1, 0}));
    EXPECT_EQ(toHost(out.edge_neighbours, 9),
              (std::vector<uint32_t>{kNone, kNone, 1, 0, kNone, kNone, kNone, kNone, kNone}));
}

// Back faces may be skipped (kEdgeFlagSkipBackFace) only on closed meshes' triangles
// (kEdgeFlagClosedMesh), of objects whose box does not hold the eye and that are not mirrored,
// and only when the gather is given the eye; the closed-mesh bit itself is not passed on.
TEST_F(GatherOccluders, BackFacesMaySkipOnlyOnClosedMeshesSeenFromOutsideUnmirrored) {
    TwoMeshScene scene;
    scene.edge_flags = {0, 4 | kEdgeFlagClosedMesh, 1 | kEdgeFlagClosedMesh};
    scene.objects.push_back(TwoMeshScene::object(1, 4, 2));
    scene.world.push_back(glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1)));  // object 3: mirrored
    const std::pair<glm::vec3, glm::vec3> boxes[] = {
        {{100, 100, 100}, {101, 101, 100}}, {{10, 0, 0}, {11, 1, 0}}, {{0, 0, -5}, {2, 2, -5}}, {{-1, 0, 0}, {0, 1, 0}}};
    for (size_t i = 0; i < 4; ++i) scene.objects[i].aabb = Aabb{boxes[i].first, boxes[i].second};
    scene.edge_flags_d = toDevice(scene.edge_flags);
    scene.objects_d = toDevice(scene.objects);
    scene.world_d = toDevice(scene.world);
    const uint8_t skip = kEdgeFlagSkipBackFace;
    OccluderGeometry out;
    const glm::vec3 outside(5, 0.5f, 3);
    scene.gather({0, 1, 2, 3}, out, &outside);
    ASSERT_EQ(out.triangle_total, 7u);
    EXPECT_EQ(toHost(out.edge_flags, 7), (std::vector<uint8_t>{0, 4 | skip, 1 | skip, 4 | skip, 1 | skip, 4, 1}));
    const glm::vec3 in_object_1(10.5f, 0.5f, 0);
    scene.gather({0, 1, 2, 3}, out, &in_object_1);
    EXPECT_EQ(toHost(out.edge_flags, 7), (std::vector<uint8_t>{0, 4, 1, 4 | skip, 1 | skip, 4, 1}));
    scene.gather({0, 1, 2, 3}, out);  // no eye: none
    EXPECT_EQ(toHost(out.edge_flags, 7), (std::vector<uint8_t>{0, 4, 1, 4, 1, 4, 1}));
}

TEST_F(GatherOccluders, AnEmptyListGathersNothingAndResetsTheTotals) {
    const TwoMeshScene scene;
    OccluderGeometry out;
    scene.gather({1, 2}, out);
    EXPECT_EQ(out.vertex_total, 8u);
    scene.gather({}, out);
    EXPECT_EQ(out.vertex_total, 0u);
    EXPECT_EQ(out.triangle_total, 0u);
    gatherOccluders(nullptr, nullptr, MeshGeometry{}, nullptr, 0, out);
    EXPECT_EQ(out.vertex_total, 0u);
}

TEST_F(GatherOccluders, AReusedOutputHoldsOnlyTheLatestGather) {
    // Arrays grow and never shrink: after a larger gather, a smaller one reports its own totals
    // and writes its own geometry at the front.
    const TwoMeshScene scene;
    OccluderGeometry out;
    scene.gather({2, 1, 0}, out);
    EXPECT_EQ(out.vertex_total, 11u);
    EXPECT_EQ(out.triangle_total, 5u);
    scene.gather({0}, out);
    ASSERT_EQ(out.vertex_total, 3u);
    ASSERT_EQ(out.triangle_total, 1u);
    EXPECT_EQ(toHost(out.positions, 3), (std::vector<glm::vec3>{{100, 100, 100}, {101, 100, 100}, {100, 101, 100}}));
    EXPECT_EQ(toHost(out.triangles, 3), (std::vector<uint32_t>{0, 1, 2}));
    EXPECT_EQ(toHost(out.edge_neighbours, 3), (std::vector<uint32_t>{kNone, kNone, kNone}));
}

// A scene for rasterOccluders: closed spheres (back faces skippable), open grids (shared edges)
// and triangle soups, instanced many times under random world matrices, some mirrored, some
// across the near plane, one around the eye.
struct RandomOccluderScene {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    std::vector<uint8_t> edge_flags;
    std::vector<uint32_t> edge_neighbours;
    std::vector<uint64_t> vertex_first, triangle_first;
    std::vector<ObjectInfo> objects;
    std::vector<glm::mat4> world;
    bool closed = false;  // whether markClosedMesh took the sphere

    void addMesh(const std::vector<glm::vec3>& p, const std::vector<uint32_t>& t) {
        vertex_first.push_back(positions.size());
        triangle_first.push_back(triangles.size() / 3);
        const auto count = uint32_t(t.size() / 3);
        std::vector<uint8_t> flags(count);
        std::vector<uint32_t> across(3 * size_t(count));
        sharedEdgeFlags(t.data(), count, flags.data(), across.data());
        closed = markClosedMesh(t.data(), count, p.data(), flags.data()) || closed;
        positions.insert(positions.end(), p.begin(), p.end());
        triangles.insert(triangles.end(), t.begin(), t.end());
        edge_flags.insert(edge_flags.end(), flags.begin(), flags.end());
        edge_neighbours.insert(edge_neighbours.end(), across.begin(), across.end());
    }
    // A latitude-longitude sphere of radius 1, wound counter-clockwise seen from outside.
    void addSphere(uint32_t rings, uint32_t segments) {
        std::vector<glm::vec3> p{{0, 1, 0}};
        for (uint32_t r = 1; r < rings; ++r)
            for (uint32_t s = 0; s < segments; ++s) {
                const float theta = 3.14159265f * float(r) / float(rings), phi = 6.2831853f * float(s) / float(segments);
                p.emplace_back(std::sin(theta) * std::cos(phi), std::cos(theta), -std::sin(theta) * std::sin(phi));
            }
        p.emplace_back(0, -1, 0);
        const auto at = [&](uint32_t r, uint32_t s) { return 1 + (r - 1) * segments + s % segments; };
        const auto south = uint32_t(p.size() - 1);
        std::vector<uint32_t> t;
        for (uint32_t s = 0; s < segments; ++s) {
            t.insert(t.end(), {0, at(1, s), at(1, s + 1)});
            for (uint32_t r = 1; r + 1 < rings; ++r)
                t.insert(t.end(), {at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s), at(r + 1, s + 1), at(r, s + 1)});
            t.insert(t.end(), {at(rings - 1, s), south, at(rings - 1, s + 1)});
        }
        addMesh(p, t);
    }
    // An n x n grid of quads in the unit square of z = 0.
    void addGrid(uint32_t n) {
        std::vector<glm::vec3> p;
        for (uint32_t y = 0; y <= n; ++y)
            for (uint32_t x = 0; x <= n; ++x) p.emplace_back(float(x) / float(n), float(y) / float(n), 0.0f);
        std::vector<uint32_t> t;
        for (uint32_t y = 0; y < n; ++y)
            for (uint32_t x = 0; x < n; ++x) {
                const uint32_t a = y * (n + 1) + x;
                t.insert(t.end(), {a, a + 1, a + n + 2, a, a + n + 2, a + n + 1});
            }
        addMesh(p, t);
    }
    void addObject(uint32_t mesh, const glm::mat4& m) {
        ObjectInfo o{};
        o.mesh = mesh;
        const uint64_t end_v = mesh + 1 < vertex_first.size() ? vertex_first[mesh + 1] : positions.size();
        const uint64_t end_t = mesh + 1 < triangle_first.size() ? triangle_first[mesh + 1] : triangles.size() / 3;
        o.vertex_count = uint32_t(end_v - vertex_first[mesh]);
        o.triangle_count = uint32_t(end_t - triangle_first[mesh]);
        o.aabb = Aabb{glm::vec3(1e30f), glm::vec3(-1e30f)};
        for (uint64_t v = vertex_first[mesh]; v < end_v; ++v) {
            const glm::vec3 w = occluderVertex(m, positions[v]);
            o.aabb.min = glm::min(o.aabb.min, w), o.aabb.max = glm::max(o.aabb.max, w);
        }
        objects.push_back(o);
        world.push_back(m);
    }
};

template <class T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

// rasterOccluders (the CPU's one-pass front end) against the three calls it stands for: the
// same geometry and the same depth image, bit for bit, over several chunks of occluders, with
// near-plane crossings, mirrored and skippable objects, reusing its buffers between calls.
TEST_F(GatherOccluders, RasterOccludersEqualsGatherNearClipAndDepthRaster) {
    RandomOccluderScene scene;
    scene.addSphere(12, 16);
    scene.addGrid(10);
    const test::Mesh soup = [] {
        std::mt19937 rng(3);
        return test::randomScene(rng, 150, 2.0f);
    }();
    scene.addMesh(soup.positions, soup.triangles);
    ASSERT_TRUE(scene.closed);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f), depth_of(0.2f, 30.0f), size_of(0.2f, 4.0f);
    for (uint32_t i = 0; i < 400; ++i) {
        const float z = -depth_of(rng);
        const glm::vec3 at(unit(rng) * 0.7f * -z, unit(rng) * 0.6f * -z, z);
        glm::mat4 m = glm::translate(glm::mat4(1.0f), at);
        m = glm::rotate(m, 3.0f * unit(rng), glm::normalize(glm::vec3(unit(rng), unit(rng), unit(rng)) + 0.01f));
        glm::vec3 scale(size_of(rng));
        if (i % 7 == 3) scale.x = -scale.x;  // mirrored
        scene.addObject(i % 3, glm::scale(m, scale));
    }
    scene.addObject(0, glm::scale(glm::mat4(1.0f), glm::vec3(3.0f)));  // a sphere around the eye
    const DeviceArray<glm::vec3> positions_d = toDevice(scene.positions);
    const DeviceArray<uint32_t> triangles_d = toDevice(scene.triangles);
    const DeviceArray<uint8_t> flags_d = toDevice(scene.edge_flags);
    const DeviceArray<uint32_t> neighbours_d = toDevice(scene.edge_neighbours);
    const DeviceArray<uint64_t> vertex_first_d = toDevice(scene.vertex_first), triangle_first_d = toDevice(scene.triangle_first);
    const DeviceArray<ObjectInfo> objects_d = toDevice(scene.objects);
    const DeviceArray<glm::mat4> world_d = toDevice(scene.world);
    const MeshGeometry meshes{positions_d.ptr(),      triangles_d.ptr(),     flags_d.ptr(), neighbours_d.ptr(),
                              vertex_first_d.ptr(),   triangle_first_d.ptr()};
    const Camera c = test::perspectiveCamera(160, 128, 0.5f, 100.0f);
    std::vector<uint32_t> all(scene.objects.size());  // shuffled below
    for (uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    std::shuffle(all.begin(), all.end(), rng);
    const std::vector<uint32_t> some(all.begin(), all.begin() + 120);
    const std::vector<uint32_t> far(all.begin() + 1, all.begin() + 200);
    struct Restore {
        ~Restore() { setSimdCeiling(SimdLevel::Avx512); }
    } restore;
    std::set<std::string> ran;
    uint64_t clipped_runs = 0;
    // Every SIMD level this machine runs (the vertices' transform and projection go a vector at
    // a time on the CPU).
    for (int level = 0; level < kSimdLevels; ++level) {
        setSimdCeiling(SimdLevel(level));
        if (!ran.insert(depthRasterTarget()).second) continue;  // CUDA, or no such level here
        OccluderGeometry fused, split;
        DepthRasterScratch fused_scratch, split_scratch;
        DeviceArray<float> fused_depth(c.width * c.height), split_depth(c.width * c.height);
        for (const std::vector<uint32_t>* ids : {&std::as_const(all), &some, &far, &std::as_const(all)}) {
            const DeviceArray<uint32_t> ids_d = toDevice(*ids);
            const auto count = uint32_t(ids->size());
            const uint64_t n = rasterOccluders(objects_d.ptr(), world_d.ptr(), meshes, ids_d.ptr(), count, c, fused,
                                               fused_depth.ptr(), fused_scratch);
            gatherOccluders(objects_d.ptr(), world_d.ptr(), meshes, ids_d.ptr(), count, split, &c.eye);
            const uint64_t gathered = split.triangle_total;
            clipped_runs += appendNearClipped(split, c) > 0 ? 1 : 0;
            depthRaster(split.positions.ptr(), split.triangles.ptr(), uint32_t(split.triangle_total), split.edge_flags.ptr(),
                        split.edge_neighbours.ptr(), c, split_depth.ptr(), split_scratch, /*seams=*/true);
            ASSERT_GT(gathered, 4 * 4096u) << "several chunks";
            ASSERT_EQ(n, split.triangle_total);
            ASSERT_EQ(fused.vertex_total, split.vertex_total);
            ASSERT_EQ(fused.triangle_total, split.triangle_total);
            EXPECT_TRUE(sameBits(toHost(fused.positions, fused.vertex_total), toHost(split.positions, split.vertex_total)));
            EXPECT_EQ(toHost(fused.triangles, 3 * n), toHost(split.triangles, 3 * n));
            EXPECT_EQ(toHost(fused.edge_flags, n), toHost(split.edge_flags, n));
            EXPECT_EQ(toHost(fused.edge_neighbours, 3 * n), toHost(split.edge_neighbours, 3 * n));
            ASSERT_EQ(fused_scratch.drawn_count, split_scratch.drawn_count);
            EXPECT_GT(fused_scratch.drawn_count, 1000u);
            EXPECT_EQ(toHost(fused_scratch.drawn_ids, fused_scratch.drawn_count),
                      toHost(split_scratch.drawn_ids, split_scratch.drawn_count));
            const std::vector<float> a = toHost(fused_depth, c.width * c.height), b = toHost(split_depth, c.width * c.height);
            EXPECT_TRUE(sameBits(a, b));
            EXPECT_GT(std::count_if(a.begin(), a.end(), [](float d) { return d < 1.0f; }), int64_t(c.width * c.height / 4));
        }
    }
    EXPECT_GE(clipped_runs, 2u) << "the sphere around the eye crosses the near plane";
}

}  // namespace
}  // namespace occ::k
