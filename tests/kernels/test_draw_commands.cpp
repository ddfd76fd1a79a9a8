// SPDX-License-Identifier: MIT
#include "draw_commands.h"

#include "device_test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

using namespace occ::k;
using namespace occ::k::test;

using DrawCommands = DeviceTest;

namespace {

// Eye at the origin looking down -z, near 1, far 100.
Camera perspectiveCamera() {
    Camera c{};
    c.fovy = glm::radians(90.0f);
    c.near_plane = 1.0f;
    c.far_plane = 100.0f;
    c.view_proj = glm::perspective(c.fovy, 1.0f, c.near_plane, c.far_plane);
    c.eye = glm::vec3(0.0f);
    c.forward = glm::vec3(0, 0, -1);
    c.width = c.height = 64;
    return c;
}

// Window depth of a point at view distance d in front of that camera: f (d - n) / ((f - n) d).
double windowDepth(double d, double n = 1.0, double f = 100.0) { return f * (d - n) / ((f - n) * d); }

Aabb box(glm::vec3 lo, glm::vec3 hi) { return {lo, hi}; }

bool operator==(const DrawCommand& a, const DrawCommand& b) {
    return a.count == b.count && a.instance_count == b.instance_count && a.first_index == b.first_index &&
           a.base_vertex == b.base_vertex && a.base_instance == b.base_instance;
}

}  // namespace

TEST(ObjectDepthFloor, ABoxInFrontIsFlooredAHairNearerThanItsNearestCorner) {
    const Camera c = perspectiveCamera();
    // Nearest corners at view distance 5 (the box spans 5..10).
    const float floor = objectDepthFloor(box({-1, -1, -10}, {1, 1, -5}), c.view_proj, c.near_plane);
    EXPECT_NEAR(floor, windowDepth(5.0) - 1e-6, 3e-7);
    // Exactly: the nearest corner's depth as the function computes it, minus 1e-6.
    const glm::vec4 clip = c.view_proj * glm::vec4(-1, -1, -5, 1);
    EXPECT_EQ(floor, clip.z / clip.w * 0.5f + 0.5f - 1e-6f);
    // Farther boxes get larger floors; the floor is below every corner's depth.
    const float farther = objectDepthFloor(box({-1, -1, -30}, {1, 1, -20}), c.view_proj, c.near_plane);
    EXPECT_NEAR(farther, windowDepth(20.0) - 1e-6, 3e-7);
    EXPECT_GT(farther, floor);
}

TEST(ObjectDepthFloor, IdentityViewProjGivesWindowDepthDirectly) {
    // Clip = world, w = 1: window depth = z / 2 + 1/2, the nearest corner at z = -0.5: 0.25.
    const glm::mat4 identity(1.0f);
    EXPECT_EQ(objectDepthFloor(box({-0.5f, -0.5f, -0.5f}, {0.5f, 0.5f, 0.5f}), identity, 0.5f), 0.25f - 1e-6f);
    // On the near clip plane (z = -w): depth 0, floored at 0, never negative.
    EXPECT_EQ(objectDepthFloor(box({0, 0, -1}, {0.5f, 0.5f, 0.5f}), identity, 0.5f), 0.0f);
    // In front of the near clip plane (z < -w).
    EXPECT_EQ(objectDepthFloor(box({0, 0, -1.5f}, {0.5f, 0.5f, 0.5f}), identity, 0.5f), 0.0f);
    // clip.w = 1 not beyond the near plane given.
    EXPECT_EQ(objectDepthFloor(box({0, 0, 0}, {0.5f, 0.5f, 0.5f}), identity, 1.0f), 0.0f);
}

TEST(ObjectDepthFloor, ABoxReachingTheNearPlaneGetsZero) {
    const Camera c = perspectiveCamera();
    // Crossing the near plane (view distance 0.5 .. 10).
    EXPECT_EQ(objectDepthFloor(box({-1, -1, -10}, {1, 1, -0.5f}), c.view_proj, c.near_plane), 0.0f);
    // Around the eye, and wholly behind it.
    EXPECT_EQ(objectDepthFloor(box({-1, -1, -1}, {1, 1, 1}), c.view_proj, c.near_plane), 0.0f);
    EXPECT_EQ(objectDepthFloor(box({-1, -1, 2}, {1, 1, 5}), c.view_proj, c.near_plane), 0.0f);
    // Wholly between the eye and the near plane.
    EXPECT_EQ(objectDepthFloor(box({-0.1f, -0.1f, -0.9f}, {0.1f, 0.1f, -0.2f}), c.view_proj, c.near_plane), 0.0f);
}

TEST(ObjectDepthFloor, NaNGivesZero) {
    const Camera c = perspectiveCamera();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(objectDepthFloor(box({nan, -1, -10}, {1, 1, -5}), c.view_proj, c.near_plane), 0.0f);
    EXPECT_EQ(objectDepthFloor(box({-1, -1, -10}, {1, 1, nan}), c.view_proj, c.near_plane), 0.0f);
    glm::mat4 broken = c.view_proj;
    broken[3][3] = nan;
    EXPECT_EQ(objectDepthFloor(box({-1, -1, -10}, {1, 1, -5}), broken, c.near_plane), 0.0f);
}

TEST_F(DrawCommands, EachBlockGetsItsCommandAndAttributes) {
    const Camera c = perspectiveCamera();
    std::vector<ObjectInfo> objects(4, ObjectInfo{});
    objects[0].aabb = box({-1, -1, -10}, {1, 1, -5});
    objects[1].aabb = box({-1, -1, -1}, {1, 1, 1});  // around the eye: floor 0
    objects[2].aabb = box({2, 0, -40}, {3, 1, -30});
    objects[3].aabb = box({-5, -5, -60}, {5, 5, -50});
    const DeviceArray<ObjectInfo> objects_d = toDevice(objects);
    // Not in object order, one object twice (two blocks of one object are still two draws).
    const std::vector<DrawBlock> blocks{{2, 7, 100, 40}, {0, 1, 0, 0}, {3, 12345, 7, 900000}, {1, 2, 50, 3},
                                        {2, 7, 200, 80}};
    const DeviceArray<DrawBlock> blocks_d = toDevice(blocks);
    const uint32_t n = uint32_t(blocks.size());
    DeviceArray<DrawCommand> commands = filledDevice<DrawCommand>(n + 1, DrawCommand{9, 9, 9, 9, 9});
    DeviceArray<DrawAttributes> attributes = filledDevice<DrawAttributes>(n + 1, DrawAttributes{9, 9.0f});
    const BusCounters before = busCounters();
    writeDrawCommands(blocks_d.ptr(), n, objects_d.ptr(), c, commands.ptr(), attributes.ptr());
    EXPECT_EQ(busCounters().h2d_bytes, before.h2d_bytes);
    EXPECT_EQ(busCounters().d2h_bytes, before.d2h_bytes) << "drawing costs the bus nothing";
    const std::vector<DrawCommand> got = toHost(commands);
    const std::vector<DrawAttributes> attrs = toHost(attributes);
    for (uint32_t k = 0; k < n; ++k) {
        SCOPED_TRACE(testing::Message() << "draw " << k);
        const DrawBlock& b = blocks[k];
        EXPECT_TRUE(got[k] == (DrawCommand{3 * b.triangle_count, 1, 3 * b.first_triangle, int32_t(b.base_vertex), k}))
            << got[k].count << " " << got[k].instance_count << " " << got[k].first_index << " " << got[k].base_vertex
            << " " << got[k].base_instance;
        EXPECT_EQ(attrs[k].object, b.object);
        // The device may fuse multiply-adds the host does not: a few ulps apart at most.
        EXPECT_NEAR(attrs[k].depth_floor, objectDepthFloor(objects[b.object].aabb, c.view_proj, c.near_plane), 5e-7);
    }
    EXPECT_NEAR(attrs[1].depth_floor, windowDepth(5.0) - 1e-6, 3e-7);
    EXPECT_EQ(attrs[3].depth_floor, 0.0f);
    EXPECT_GT(attrs[2].depth_floor, attrs[1].depth_floor);
    // Room for n entries: the one after them is not written.
    EXPECT_TRUE(got[n] == (DrawCommand{9, 9, 9, 9, 9}));
    EXPECT_EQ(attrs[n].object, 9u);
}

TEST_F(DrawCommands, NoBlocksWriteNothing) {
    const DeviceArray<DrawBlock> blocks = toDevice(std::vector<DrawBlock>{{0, 1, 2, 3}});
    DeviceArray<DrawCommand> commands = filledDevice<DrawCommand>(1, DrawCommand{9, 9, 9, 9, 9});
    DeviceArray<DrawAttributes> attributes = filledDevice<DrawAttributes>(1, DrawAttributes{9, 9.0f});
    writeDrawCommands(blocks.ptr(), 0, nullptr, perspectiveCamera(), commands.ptr(), attributes.ptr());
    EXPECT_TRUE(toHost(commands)[0] == (DrawCommand{9, 9, 9, 9, 9}));
    EXPECT_EQ(toHost(attributes)[0].object, 9u);
    EXPECT_EQ(toHost(attributes)[0].depth_floor, 9.0f);
}
