// SPDX-License-Identifier: MIT
#include "occluder_gather.h"

#include "depth_raster.h"

#include "device_test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cstdint>
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

}  // namespace
}  // namespace occ::k
