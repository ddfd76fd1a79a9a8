// SPDX-License-Identifier: MIT
#include "frustum_cull.h"

#include "device_test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

namespace occ::k {
namespace {

using test::boxObject;
using test::filledDevice;
using test::toDevice;
using test::toHost;

using FrustumCull = test::DeviceTest;

// Eye at the origin looking down -z, 90 degrees both ways, near 1, far 100: at distance d in
// front of the eye the frustum is |x| <= d, |y| <= d, so every expectation below is checked by eye.
glm::mat4 straightAhead() {
    return glm::perspective(std::numbers::pi_v<float> / 2, 1.0f, 1.0f, 100.0f);
}

// Runs frustumCull over the boxes on the device, once without and once with the ids output;
// returns the flags and checks that both runs agree, that the count is the number of 1s and
// that the ids are exactly the indices of the 1s, ascending.
std::vector<uint8_t> cull(const std::vector<ObjectInfo>& boxes, const glm::mat4& view_proj) {
    const auto count = uint32_t(boxes.size());
    const Frustum frustum = frustumFromViewProj(view_proj);
    const DeviceArray<ObjectInfo> objects = toDevice(boxes);
    DeviceArray<uint8_t> in_frustum = filledDevice<uint8_t>(count, 7);  // every byte must be written
    const uint32_t n = frustumCull(objects.ptr(), count, frustum, in_frustum.ptr());
    const std::vector<uint8_t> flags = toHost(in_frustum);
    EXPECT_EQ(n, uint32_t(std::count(flags.begin(), flags.end(), uint8_t(1))));

    DeviceArray<uint8_t> again = filledDevice<uint8_t>(count, 7);
    DeviceArray<uint32_t> ids = filledDevice<uint32_t>(count, UINT32_MAX);
    const uint32_t n_ids = frustumCull(objects.ptr(), count, frustum, again.ptr(), ids.ptr());
    EXPECT_EQ(toHost(again), flags);
    EXPECT_EQ(n_ids, n);
    std::vector<uint32_t> expected_ids;
    for (uint32_t i = 0; i < count; ++i)
        if (flags[i] == 1) expected_ids.push_back(i);
    std::vector<uint32_t> got = toHost(ids);
    EXPECT_TRUE(std::all_of(got.begin() + std::min(n_ids, count), got.end(), [](uint32_t id) { return id == UINT32_MAX; }))
        << "ids written past the count";
    got.resize(std::min(n_ids, count));
    EXPECT_EQ(got, expected_ids);
    return flags;
}

uint8_t cullOne(const glm::vec3& lo, const glm::vec3& hi, const glm::mat4& view_proj = straightAhead()) {
    return cull({boxObject(lo, hi)}, view_proj)[0];
}

TEST(FrustumFromViewProj, PlanesAreNormalizedInwardInOrder) {
    const Frustum f = frustumFromViewProj(straightAhead());
    const float s = std::sqrt(0.5f);
    const glm::vec4 expected[6] = {{s, 0, -s, 0},  {-s, 0, -s, 0}, {0, s, -s, 0},
                                   {0, -s, -s, 0}, {0, 0, -1, -1}, {0, 0, 1, 100}};
    // The float matrix itself places the far plane only to about 3e-6 relative: the plane is row 3
    // minus row 2, whose -(f+n)/(f-n) is rounded to a float first and nearly cancels the -1.
    for (int i = 0; i < 6; ++i)
        for (int c = 0; c < 4; ++c) EXPECT_NEAR(f.planes[i][c], expected[i][c], 1e-5f * (1 + std::abs(expected[i][c]))) << "plane " << i << " coefficient " << c;
}

TEST(FrustumFromViewProj, FollowsTheView) {
    // Looking down +x from (5, 0, 0): the point (15, 0, 0) is inside, (-5, 0, 0) behind the eye.
    const glm::mat4 view_proj = straightAhead() * glm::lookAt(glm::vec3(5, 0, 0), glm::vec3(6, 0, 0), glm::vec3(0, 1, 0));
    const Frustum f = frustumFromViewProj(view_proj);
    const auto inside = [&](const glm::vec3& p) {
        for (const glm::vec4& pl : f.planes)
            if (glm::dot(glm::vec3(pl), p) + pl.w < 0) return false;
        return true;
    };
    EXPECT_TRUE(inside({15, 0, 0}));
    EXPECT_TRUE(inside({15, 9, -9}));
    EXPECT_FALSE(inside({-5, 0, 0}));
    EXPECT_FALSE(inside({15, 11, 0}));
    EXPECT_FALSE(inside({200, 0, 0}));
}

TEST_F(FrustumCull, BoxInsideIsKept) { EXPECT_EQ(cullOne({-1, -1, -11}, {1, 1, -9}), 1); }

TEST_F(FrustumCull, BoxOutsideEachPlaneIsCulled) {
    EXPECT_EQ(cullOne({-30, -1, -11}, {-25, 1, -9}), 0) << "left";
    EXPECT_EQ(cullOne({25, -1, -11}, {30, 1, -9}), 0) << "right";
    EXPECT_EQ(cullOne({-1, -30, -11}, {1, -25, -9}), 0) << "bottom";
    EXPECT_EQ(cullOne({-1, 25, -11}, {1, 30, -9}), 0) << "top";
    EXPECT_EQ(cullOne({-0.1f, -0.1f, -0.8f}, {0.1f, 0.1f, -0.2f}), 0) << "between eye and near plane";
    EXPECT_EQ(cullOne({-1, -1, 1}, {1, 1, 2}), 0) << "behind the eye";
    EXPECT_EQ(cullOne({-1, -1, -120}, {1, 1, -110}), 0) << "beyond far";
}

TEST_F(FrustumCull, BoxStraddlingAPlaneIsKept) {
    EXPECT_EQ(cullOne({-12, -1, -11}, {-8, 1, -9}), 1) << "left";
    EXPECT_EQ(cullOne({-1, 8, -11}, {1, 12, -9}), 1) << "top";
    EXPECT_EQ(cullOne({-0.1f, -0.1f, -2}, {0.1f, 0.1f, 0.5f}), 1) << "near";
    EXPECT_EQ(cullOne({-1, -1, -105}, {1, 1, -95}), 1) << "far";
}

TEST_F(FrustumCull, BoxTouchingAPlaneIsKept) {
    // The face x = -10 lies in the left plane at z = -10; rounding must not drop it.
    EXPECT_EQ(cullOne({-12, -1, -10}, {-10, 1, -9}), 1);
    EXPECT_EQ(cullOne({-1, -1, -102}, {1, 1, -100}), 1);
}

TEST_F(FrustumCull, HugeBoxContainingEyeAndFrustumIsKept) { EXPECT_EQ(cullOne(glm::vec3(-1000), glm::vec3(1000)), 1); }

TEST_F(FrustumCull, CameraInsideBoxIsKept) {
    EXPECT_EQ(cullOne(glm::vec3(-2), glm::vec3(2)), 1);
    // A box around the eye that ends before the near plane is not in the view volume.
    EXPECT_EQ(cullOne(glm::vec3(-0.5f), glm::vec3(0.5f)), 0);
}

TEST_F(FrustumCull, BoxOutsideNearAnEdgeMayBeKept) {
    // Beyond the edge where the left and far planes meet: every point of it with z >= -100 has
    // x < z, yet it reaches the inner side of each plane on its own, so the p-vertex test keeps it
    // (the documented false positive).
    EXPECT_EQ(cullOne({-101.5f, -1, -101}, {-100.5f, 1, -99}), 1);
}

TEST_F(FrustumCull, NaNBoxIsKept) { EXPECT_EQ(cullOne({NAN, 0, -10}, {1, 1, -9}), 1); }

TEST_F(FrustumCull, EmptyInput) {
    EXPECT_EQ(frustumCull(nullptr, 0, frustumFromViewProj(straightAhead()), nullptr), 0u);
    EXPECT_EQ(frustumCull(nullptr, 0, frustumFromViewProj(straightAhead()), nullptr, nullptr), 0u);
    EXPECT_TRUE(cull({}, straightAhead()).empty());
}

// The ids output on a hand-checked row: boxes 1 and 3 are in front of the eye, 0 behind it, 2
// far to the left and 4 beyond the far plane.
TEST_F(FrustumCull, IdsOfTheKeptBoxesAreCompactedInOrder) {
    const std::vector<ObjectInfo> boxes = {
        boxObject({-1, -1, 1}, {1, 1, 2}),        boxObject({-1, -1, -11}, {1, 1, -9}),
        boxObject({-30, -1, -11}, {-25, 1, -9}),  boxObject({3, 3, -21}, {4, 4, -20}),
        boxObject({-1, -1, -120}, {1, 1, -110}),
    };
    const DeviceArray<ObjectInfo> objects = toDevice(boxes);
    DeviceArray<uint8_t> in_frustum(boxes.size());
    DeviceArray<uint32_t> ids = filledDevice<uint32_t>(boxes.size(), UINT32_MAX);
    const uint32_t n = frustumCull(objects.ptr(), uint32_t(boxes.size()), frustumFromViewProj(straightAhead()),
                                   in_frustum.ptr(), ids.ptr());
    EXPECT_EQ(toHost(in_frustum), (std::vector<uint8_t>{0, 1, 0, 1, 0}));
    ASSERT_EQ(n, 2u);
    EXPECT_EQ(toHost(ids), (std::vector<uint32_t>{1, 3, UINT32_MAX, UINT32_MAX, UINT32_MAX}));
}

// A plain loop over the 8 corners: a box is out when all its corners are outside one plane.
uint8_t referenceCull(const Aabb& box, const Frustum& f) {
    for (const glm::vec4& pl : f.planes) {
        bool all_out = true;
        for (int c = 0; c < 8; ++c) {
            const glm::vec3 p(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y, c & 4 ? box.max.z : box.min.z);
            if (pl.x * p.x + pl.y * p.y + pl.z * p.z + pl.w >= 0) all_out = false;
        }
        if (all_out) return 0;
    }
    return 1;
}

TEST_F(FrustumCull, RandomBoxesMatchCornerLoopAndKeepEveryVisiblePoint) {
    std::mt19937 rng(20240611);
    std::uniform_real_distribution<float> coord(-60, 60), size(0.01f, 15), unit(0, 1);
    for (int view = 0; view < 8; ++view) {
        const glm::vec3 eye(coord(rng) * 0.2f, coord(rng) * 0.2f, coord(rng) * 0.2f);
        const glm::vec3 target = eye + glm::vec3(coord(rng), coord(rng), coord(rng));
        const glm::mat4 view_proj = glm::perspective(0.4f + 1.2f * unit(rng), 0.5f + 1.5f * unit(rng), 0.1f + unit(rng), 80.0f) *
                                    glm::lookAt(eye, target, glm::vec3(0, 1, 0));
        std::vector<ObjectInfo> boxes;
        for (int i = 0; i < 20000; ++i) {
            const glm::vec3 lo(coord(rng), coord(rng), coord(rng));
            boxes.push_back(boxObject(lo, lo + glm::vec3(size(rng), size(rng), size(rng))));
        }
        const std::vector<uint8_t> flags = cull(boxes, view_proj);
        const Frustum f = frustumFromViewProj(view_proj);
        uint32_t kept = 0;
        for (size_t i = 0; i < boxes.size(); ++i) {
            ASSERT_EQ(flags[i], referenceCull(boxes[i].aabb, f)) << "view " << view << " box " << i;
            kept += flags[i];
            if (flags[i]) continue;
            // A culled box has no point in the clip volume: try its corners, centre and samples.
            for (int s = 0; s < 16; ++s) {
                const glm::vec3 t = s < 8 ? glm::vec3(s & 1, (s >> 1) & 1, (s >> 2) & 1)
                                          : (s == 8 ? glm::vec3(0.5f) : glm::vec3(unit(rng), unit(rng), unit(rng)));
                const glm::vec4 clip = view_proj * glm::vec4(glm::mix(boxes[i].aabb.min, boxes[i].aabb.max, t), 1);
                const bool inside = std::abs(clip.x) <= clip.w && std::abs(clip.y) <= clip.w && std::abs(clip.z) <= clip.w;
                ASSERT_FALSE(inside) << "view " << view << " box " << i << " sample " << s;
            }
        }
        EXPECT_GT(kept, 0u) << "view " << view;
        EXPECT_LT(kept, boxes.size()) << "view " << view;
    }
}

}  // namespace
}  // namespace occ::k
