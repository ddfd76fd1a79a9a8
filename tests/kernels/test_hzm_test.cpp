// SPDX-License-Identifier: MIT
#include "hzm_test.h"
#include "simd_level.h"

#include "device_test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <set>
#include <vector>

namespace occ::k {
namespace {

using test::boxObject;
using test::toDevice;
using test::toHost;

using HzmTest = test::DeviceTest;

constexpr float kEpsilon = 1e-6f;  // what hzmTest adds to every stored depth

// Eye at the origin looking down -z, 90 degrees vertical field of view, near 1, far 100.
Camera straightAhead(uint32_t width, uint32_t height) {
    Camera c{};
    c.near_plane = 1;
    c.far_plane = 100;
    c.fovy = std::numbers::pi_v<float> / 2;
    c.view_proj = glm::perspective(c.fovy, float(width) / float(height), c.near_plane, c.far_plane);
    c.eye = {0, 0, 0};
    c.forward = {0, 0, -1};
    c.width = width;
    c.height = height;
    return c;
}

glm::vec4 project(const Camera& camera, const glm::vec3& p) { return camera.view_proj * glm::vec4(p, 1); }

// Window depth of the points `distance` in front of the eye.
float windowDepth(const Camera& camera, float distance) {
    const glm::vec4 clip = project(camera, {0, 0, -distance});
    return clip.z / clip.w * 0.5f + 0.5f;
}

// The max-depth pyramid of a level-0 buffer, built by a plain loop on the host (hzmBuild is
// tested on its own) and uploaded; levels.data points at the device copy.
struct Pyramid {
    std::vector<float> texels;
    DeviceArray<float> device_texels;
    HzmLevels levels{};
};

Pyramid buildPyramid(const std::vector<float>& depth, uint32_t width, uint32_t height) {
    Pyramid p;
    hzmLayout(width, height, p.levels);
    p.texels.resize(hzmTotalTexels(width, height));
    std::copy(depth.begin(), depth.end(), p.texels.begin());
    const HzmLevels& l = p.levels;
    for (uint32_t k = 1; k < l.level_count; ++k)
        for (uint32_t y = 0; y < l.height[k]; ++y)
            for (uint32_t x = 0; x < l.width[k]; ++x) {
                float m = 0;
                for (uint32_t cy = 2 * y; cy < std::min(2 * y + 2, l.height[k - 1]); ++cy)
                    for (uint32_t cx = 2 * x; cx < std::min(2 * x + 2, l.width[k - 1]); ++cx)
                        m = std::max(m, p.texels[l.offset[k - 1] + cy * l.width[k - 1] + cx]);
                p.texels[l.offset[k] + y * l.width[k] + x] = m;
            }
    p.device_texels = toDevice(p.texels);
    p.levels.data = p.device_texels.ptr();
    return p;
}

std::vector<uint8_t> runTest(const std::vector<ObjectInfo>& boxes, const Camera& camera, const HzmLevels& hzm) {
    const DeviceArray<ObjectInfo> objects = toDevice(boxes);
    // Test the boxes in reverse order, so the ids are not just 0..n-1.
    std::vector<uint32_t> ids(boxes.size());
    for (size_t j = 0; j < boxes.size(); ++j) ids[j] = uint32_t(boxes.size() - 1 - j);
    const DeviceArray<uint32_t> ids_d = toDevice(ids);
    DeviceArray<uint8_t> occluded_d = test::filledDevice<uint8_t>(boxes.size(), 7);  // every byte must be written
    hzmTest(objects.ptr(), ids_d.ptr(), uint32_t(boxes.size()), camera, hzm, occluded_d.ptr());
    const std::vector<uint8_t> occluded = toHost(occluded_d);
    std::vector<uint8_t> by_object(boxes.size());
    for (size_t j = 0; j < boxes.size(); ++j) by_object[ids[j]] = occluded[j];
    return by_object;
}

// 64 x 64 pixels; a wall 5 in front of the eye covers the left half (x < 32), the rest is clear
// (far). At distance d the viewport spans |x|, |y| <= d, and pixel column 32 starts at x = 0.
class NearWallLeftHalf : public test::DeviceTest {
protected:
    void SetUp() override {
        test::DeviceTest::SetUp();
        if (IsSkipped()) return;
        std::vector<float> depth(64 * 64, 1.0f);
        for (uint32_t y = 0; y < 64; ++y)
            for (uint32_t x = 0; x < 32; ++x) depth[y * 64 + x] = windowDepth(camera, 5);
        pyramid = buildPyramid(depth, 64, 64);
    }
    uint8_t occluded(const glm::vec3& lo, const glm::vec3& hi) {
        return runTest({boxObject(lo, hi)}, camera, pyramid.levels)[0];
    }

    Camera camera = straightAhead(64, 64);
    Pyramid pyramid;
};

// hzmVisibleShare: the share of a box's image rectangle not proven hidden (visibility weighting).
float visibleShare(const ObjectInfo& box, const Camera& camera, const HzmLevels& hzm) {
    const DeviceArray<ObjectInfo> objects = toDevice(std::vector<ObjectInfo>{box});
    const DeviceArray<uint32_t> ids = toDevice(std::vector<uint32_t>{0});
    DeviceArray<float> share = test::filledDevice<float>(1, -7.0f);
    hzmVisibleShare(objects.ptr(), ids.ptr(), 1, camera, hzm, share.ptr());
    return toHost(share)[0];
}

TEST_F(NearWallLeftHalf, VisibleShareIsWhatTheWallLeavesOfTheBoxsImage) {
    // Behind the wall's edge, half its image on each side (x from -4 to 4 at depth 12 -> 32 px
    // around column 32): about half visible, never less than what the pixels say.
    const float half = visibleShare(boxObject({-4, -3, -12}, {4, 3, -11}), camera, pyramid.levels);
    EXPECT_GE(half, 0.45f);
    EXPECT_LE(half, 0.60f);
    // In the clear half: all of it; behind the wall entirely: none; in front of the wall: all.
    EXPECT_FLOAT_EQ(visibleShare(boxObject({2, -3, -12}, {8, 3, -10}), camera, pyramid.levels), 1.0f);
    EXPECT_FLOAT_EQ(visibleShare(boxObject({-8, -3, -12}, {-1, 3, -10}), camera, pyramid.levels), 0.0f);
    EXPECT_FLOAT_EQ(visibleShare(boxObject({-3, -1, -4}, {-2, 1, -3}), camera, pyramid.levels), 1.0f);
    // Crossing the near plane: counted as all visible.
    EXPECT_FLOAT_EQ(visibleShare(boxObject({-1, -1, -3}, {1, 1, 0}), camera, pyramid.levels), 1.0f);
}

TEST_F(NearWallLeftHalf, VisibleShareCountsTheBoxsFacesNotItsNearestCorner) {
    // A long bar left of the view axis, x in [-2, -1], from 4.5 to 60 in front of the eye: its
    // near face (pixel columns 17.8 to 24.9, rows 28.4 to 35.6, about 50 pixels) is in front of
    // the wall at 5; its right side face (x = -1) runs from column 24.9 towards the vanishing
    // point at 32 (about 25 pixels), behind the wall from 5 on (column 25.6). So about 55 of
    // 75 pixels show. The nearest corner alone (4.5, in front of the wall) said all of them.
    const float share = visibleShare(boxObject({-2, -0.5f, -60}, {-1, 0.5f, -4.5f}), camera, pyramid.levels);
    EXPECT_GE(share, 0.6f);
    EXPECT_LE(share, 0.85f);
    // The same bar with its near face behind the wall too: nothing shows.
    EXPECT_FLOAT_EQ(visibleShare(boxObject({-2, -0.5f, -60}, {-1, 0.5f, -5.5f}), camera, pyramid.levels), 0.0f);
    // A box between the pixels' rays (far and thin) falls back to its nearest corner: in the
    // clear half all of it shows, behind the wall none.
    EXPECT_FLOAT_EQ(visibleShare(boxObject({10, 0.01f, -90}, {10.01f, 0.02f, -89.99f}), camera, pyramid.levels), 1.0f);
    EXPECT_FLOAT_EQ(visibleShare(boxObject({-10.01f, 0.01f, -90}, {-10, 0.02f, -89.99f}), camera, pyramid.levels), 0.0f);
}

TEST_F(NearWallLeftHalf, BoxBehindWallIsOccluded) { EXPECT_EQ(occluded({-8, -3, -12}, {-1, 3, -10}), 1); }

TEST_F(NearWallLeftHalf, BoxPeekingOverTheRightHalfIsVisible) {
    EXPECT_EQ(occluded({-8, -3, -12}, {2, 3, -10}), 0);
    // Its right edge projects to x = 32 + 0.1/12 * 32: inside pixel column 32, which is clear.
    EXPECT_EQ(occluded({-8, -3, -12}, {0.1f, 3, -10}), 0);
}

TEST_F(NearWallLeftHalf, BoxInFrontOfWallIsVisible) {
    EXPECT_EQ(occluded({-3, -1, -4}, {-2, 1, -3}), 0);
    // Its front face lies exactly at the wall's depth: not strictly behind.
    EXPECT_EQ(occluded({-8, -3, -12}, {-6, 3, -5}), 0);
    // A little behind it is.
    EXPECT_EQ(occluded({-8, -3, -12}, {-6, 3, -5.05f}), 1);
}

TEST_F(NearWallLeftHalf, BoxCrossingOrBehindNearPlaneIsVisible) {
    EXPECT_EQ(occluded({-3, -1, -12}, {-2, 1, -0.5f}), 0);
    EXPECT_EQ(occluded({-3, -1, 1}, {-2, 1, 2}), 0);
    // Behind the eye and projecting into the left half when w is ignored: still visible.
    EXPECT_EQ(occluded({2, -1, 10}, {3, 1, 12}), 0);
}

TEST_F(NearWallLeftHalf, BoxPartlyOffScreenIsTestedWhereItIsOnScreen) {
    // Reaching far out to the left and above the viewport, behind the wall where it is on screen.
    EXPECT_EQ(occluded({-40, -3, -12}, {-1, 40, -10}), 1);
    // The same, reaching into the right half as well.
    EXPECT_EQ(occluded({-40, -3, -12}, {1, 40, -10}), 0);
}

TEST_F(NearWallLeftHalf, BoxEntirelyOffScreenIsVisible) { EXPECT_EQ(occluded({-40, -3, -12}, {-30, 3, -10}), 0); }

TEST_F(NearWallLeftHalf, NaNBoxIsVisible) { EXPECT_EQ(occluded({NAN, -3, -12}, {-1, 3, -10}), 0); }

TEST_F(NearWallLeftHalf, EmptyPyramidOrInput) {
    HzmLevels none{};
    EXPECT_EQ(runTest({boxObject({-8, -3, -12}, {-1, 3, -10})}, camera, none)[0], 0);
    hzmTest(nullptr, nullptr, 0, camera, pyramid.levels, nullptr);
}

TEST_F(HzmTest, SixteenByOneViewportAnswersAsLevel0Does) {
    // A 16 x 1 buffer (levels 16, 8, 4, 2, 1 wide): a near wall everywhere but pixel 13.
    const Camera camera = straightAhead(16, 1);
    std::vector<float> depth(16, windowDepth(camera, 5));
    depth[13] = 1.0f;
    const Pyramid pyramid = buildPyramid(depth, 16, 1);
    ASSERT_EQ(pyramid.levels.level_count, 5u);
    // With aspect 16, window x = x / (2d) + 8: at d = 10, pixel p covers x in [20p - 160, 20p - 140).
    // The boxes are 0.01 deep, so d = 10.01 moves these edges by less than 0.2.
    const auto slab = [](float lo, float hi) { return boxObject({lo, -1, -10.01f}, {hi, 1, -10}); };
    const std::vector<ObjectInfo> boxes = {
        slab(-159, -101),  // pixels 0..2, level 1 texels 0..1 (pixels 0..3): occluded
        slab(-159, 99),    // pixels 0..12: level 3 texels 0..1 take in pixel 13, so the test opens
                           // texel 1 down to level 0, where pixels 8..12 prove it hidden: occluded
        slab(-159, 101),   // pixels 0..13: visible
        slab(121, 139),    // pixel 14 alone: occluded
        slab(101, 119),    // pixel 13 alone: visible
        slab(-39, 19),     // pixels 6..8, level 1 texels 3..4: occluded
        slab(-39, 79),     // pixels 6..11: 3 texels at level 1, 2 at level 2 (pixels 4..11):
                           // occluded, where level 3 (= ceil(log2(6))) would have taken in pixel 13
    };
    EXPECT_EQ(runTest(boxes, camera, pyramid.levels), (std::vector<uint8_t>{1, 1, 0, 1, 0, 1, 1}));
}

// Plain per-box data both references below need: the rectangle of touched pixels and z_min, or
// nothing when the box crosses the near plane or is entirely off screen.
struct Footprint {
    bool testable = false;
    uint32_t x0 = 0, x1 = 0, y0 = 0, y1 = 0;
    float z_min = 0;
};

Footprint footprint(const Aabb& box, const Camera& camera, uint32_t width, uint32_t height) {
    Footprint f;
    float xmin = INFINITY, xmax = -INFINITY, ymin = INFINITY, ymax = -INFINITY, z_min = INFINITY;
    for (int c = 0; c < 8; ++c) {
        const glm::vec4 clip =
            project(camera, {c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y, c & 4 ? box.max.z : box.min.z});
        if (clip.w <= camera.near_plane || clip.z < -clip.w) return f;
        xmin = std::min(xmin, (clip.x / clip.w * 0.5f + 0.5f) * float(width));
        xmax = std::max(xmax, (clip.x / clip.w * 0.5f + 0.5f) * float(width));
        ymin = std::min(ymin, (clip.y / clip.w * 0.5f + 0.5f) * float(height));
        ymax = std::max(ymax, (clip.y / clip.w * 0.5f + 0.5f) * float(height));
        z_min = std::min(z_min, clip.z / clip.w * 0.5f + 0.5f);
    }
    if (xmax < 0 || ymax < 0 || xmin >= float(width) || ymin >= float(height)) return f;
    f.testable = true;
    f.x0 = uint32_t(std::floor(std::max(xmin, 0.0f)));
    f.x1 = uint32_t(std::floor(std::min(xmax, float(width - 1))));
    f.y0 = uint32_t(std::floor(std::max(ymin, 0.0f)));
    f.y1 = uint32_t(std::floor(std::min(ymax, float(height - 1))));
    f.z_min = z_min;
    return f;
}

// What hzmTest promises exactly, and the most a conservative test may say: occluded iff z_min is
// behind every level-0 pixel touched.
uint8_t referenceAtLevel0(const Footprint& f, const std::vector<float>& depth, uint32_t width) {
    if (!f.testable) return 0;
    for (uint32_t y = f.y0; y <= f.y1; ++y)
        for (uint32_t x = f.x0; x <= f.x1; ++x)
            if (!(f.z_min > depth[y * width + x] + kEpsilon)) return 0;
    return 1;
}

// A random level 0 for camera's viewport: far, or a back wall across the whole view, then a few
// walls at random distances over random rectangles (nearest wins).
std::vector<float> randomWalls(std::mt19937& rng, const Camera& camera, bool back_wall) {
    std::uniform_real_distribution<float> unit(0, 1);
    const uint32_t width = camera.width, height = camera.height;
    std::vector<float> depth(size_t(width) * height, back_wall ? windowDepth(camera, 10 + 20 * unit(rng)) : 1.0f);
    for (int wall = 0; wall < 6; ++wall) {
        const uint32_t x0 = rng() % width, y0 = rng() % height;
        const uint32_t x1 = x0 + rng() % (width - x0), y1 = y0 + rng() % (height - y0);
        const float d = windowDepth(camera, 2 + 20 * unit(rng));
        for (uint32_t y = y0; y <= y1; ++y)
            for (uint32_t x = x0; x <= x1; ++x) depth[y * width + x] = std::min(depth[y * width + x], d);
    }
    return depth;
}

TEST_F(HzmTest, RandomScenesAnswerExactlyAsLevel0Does) {
    std::mt19937 rng(4242);
    std::uniform_real_distribution<float> unit(0, 1);
    uint64_t total = 0, occluded_by_kernel = 0, occluded_at_level0 = 0;
    for (int scene = 0; scene < 24; ++scene) {
        // Odd and even, tiny and non-power-of-two viewports.
        const uint32_t width = 1 + rng() % 97, height = 1 + rng() % 61;
        const Camera camera = straightAhead(width, height);
        const std::vector<float> depth = randomWalls(rng, camera, scene % 2 == 1);
        const Pyramid pyramid = buildPyramid(depth, width, height);
        const float aspect = float(width) / float(height);
        std::vector<ObjectInfo> boxes;
        for (int i = 0; i < 4000; ++i) {
            // Mostly in view, some across the edges, some across the near plane.
            const float dist = 0.5f + 40 * unit(rng);
            const glm::vec3 centre((unit(rng) * 2.4f - 1.2f) * dist * aspect, (unit(rng) * 2.4f - 1.2f) * dist, -dist);
            const glm::vec3 half = glm::vec3(unit(rng), unit(rng), unit(rng)) * (0.02f + 0.3f * dist * unit(rng));
            boxes.push_back(boxObject(centre - half, centre + half));
        }
        const std::vector<uint8_t> result = runTest(boxes, camera, pyramid.levels);
        for (size_t i = 0; i < boxes.size(); ++i) {
            const Footprint f = footprint(boxes[i].aabb, camera, width, height);
            const uint8_t level0 = referenceAtLevel0(f, depth, width);
            ASSERT_LE(result[i], level0) << "scene " << scene << " box " << i << ": culled a box level 0 sees";
            ASSERT_EQ(result[i], level0) << "scene " << scene << " box " << i << ": kept a box level 0 hides";
            // Behind the farthest depth of the whole buffer (the 1x1 level) it must be culled.
            const float farthest = pyramid.texels[pyramid.levels.offset[pyramid.levels.level_count - 1]];
            if (f.testable && f.z_min > farthest + kEpsilon) {
                ASSERT_EQ(result[i], 1) << "scene " << scene << " box " << i;
            }
            total += 1;
            occluded_by_kernel += result[i];
            occluded_at_level0 += level0;
        }
    }
    // The fixtures must exercise both answers.
    EXPECT_GT(occluded_by_kernel, total / 10);
    EXPECT_LT(occluded_by_kernel, total * 9 / 10);
    EXPECT_EQ(occluded_by_kernel, occluded_at_level0);
}

// The CPU build's box images go a SIMD vector of boxes at a time (kernels/hzm_test_cpu.cpp): at
// every instruction set this machine runs, hzmTest answers exactly as the one-box-a-thread loop
// does and as level 0 does, on random scenes with boxes across the edges, across and behind the
// near plane, huge, and with NaN and infinite corners, over counts that end mid-vector.
TEST_F(HzmTest, EverySimdLevelAnswersAsTheScalarLoopAndLevel0) {
    struct Restore {
        ~Restore() { setSimdCeiling(SimdLevel::Avx512); }
    } restore;
    std::set<SimdLevel> ran;
    for (int level = 0; level < kSimdLevels; ++level) {
        setSimdCeiling(SimdLevel(level));
        if (!ran.insert(simdLevel()).second) continue;  // this CPU has no such level
        std::mt19937 rng(777 + level);
        std::uniform_real_distribution<float> unit(0, 1);
        uint64_t occluded = 0, total = 0;
        for (int scene = 0; scene < 6; ++scene) {
            const uint32_t width = 1 + rng() % 97, height = 1 + rng() % 61;
            const Camera camera = straightAhead(width, height);
            const std::vector<float> depth = randomWalls(rng, camera, scene % 2 == 1);
            const Pyramid pyramid = buildPyramid(depth, width, height);
            const float aspect = float(width) / float(height);
            std::vector<ObjectInfo> boxes;
            const uint32_t count = 1500 + uint32_t(rng() % 17);  // not a whole number of vectors
            for (uint32_t i = 0; i < count; ++i) {
                const float dist = (i % 50 == 0 ? -5.0f : 0.5f) + 40 * unit(rng);  // some behind the eye
                const glm::vec3 centre((unit(rng) * 2.4f - 1.2f) * dist * aspect, (unit(rng) * 2.4f - 1.2f) * dist, -dist);
                glm::vec3 half = glm::vec3(unit(rng), unit(rng), unit(rng)) * (0.02f + 0.3f * dist * unit(rng));
                if (i % 97 == 0) half *= 1e4f;  // far beyond the viewport
                ObjectInfo box = boxObject(centre - half, centre + half);
                if (i % 101 == 0) box.aabb.min.x = NAN;
                if (i % 103 == 0) box.aabb.max.y = INFINITY;
                boxes.push_back(box);
            }
            const DeviceArray<ObjectInfo> objects = toDevice(boxes);
            std::vector<uint32_t> ids(count);
            for (uint32_t j = 0; j < count; ++j) ids[j] = (j * 7919u) % count;  // scattered
            const DeviceArray<uint32_t> ids_d = toDevice(ids);
            DeviceArray<uint8_t> simd = test::filledDevice<uint8_t>(count, 7), scalar = test::filledDevice<uint8_t>(count, 9);
            hzmTest(objects.ptr(), ids_d.ptr(), count, camera, pyramid.levels, simd.ptr());
            hzmTestScalar(objects.ptr(), ids_d.ptr(), count, camera, pyramid.levels, scalar.ptr());
            const std::vector<uint8_t> got = toHost(simd), want = toHost(scalar);
            ASSERT_EQ(got, want) << simdLevelName(simdLevel()) << " scene " << scene;
            for (uint32_t j = 0; j < count; ++j) {
                const ObjectInfo& box = boxes[ids[j]];
                if (box.aabb.min.x != box.aabb.min.x || std::isinf(box.aabb.max.y)) {
                    EXPECT_EQ(got[j], 0) << "a box with a NaN or infinite corner is never culled";
                    continue;
                }
                const Footprint f = footprint(box.aabb, camera, width, height);
                ASSERT_EQ(got[j], referenceAtLevel0(f, depth, width)) << simdLevelName(simdLevel()) << " box " << j;
                occluded += got[j];
                ++total;
            }
        }
        EXPECT_GT(occluded, total / 10) << simdLevelName(simdLevel());
        EXPECT_LT(occluded, total * 9 / 10) << simdLevelName(simdLevel());
    }
    EXPECT_GE(ran.size(), 2u);
}

}  // namespace
}  // namespace occ::k
