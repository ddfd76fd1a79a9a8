// SPDX-License-Identifier: MIT
#include "hzm_build.h"

#include "device_test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

namespace occ::k {
namespace {

using test::toDevice;
using test::toHost;

using HzmBuild = test::DeviceTest;

// A device pyramid whose level 0 is `base`, with one sentinel float after the last level so
// that a write past hzmTotalTexels shows (the other levels start as sentinels too).
constexpr float kSentinel = -7.0f;

DeviceArray<float> pyramidOf(const std::vector<float>& base, uint32_t width, uint32_t height) {
    std::vector<float> levels(hzmTotalTexels(width, height) + 1, kSentinel);
    std::copy(base.begin(), base.end(), levels.begin());
    return toDevice(levels);
}

std::vector<float> level(const DeviceArray<float>& levels, const HzmLevels& layout, uint32_t l) {
    return toHost(levels.ptr() + layout.offset[l], uint64_t(layout.width[l]) * layout.height[l]);
}

// Plain scalar pyramid: every texel of level l+1 the max over its 2x2 block, clamped at the edge.
std::vector<float> referencePyramid(const std::vector<float>& base, uint32_t width, uint32_t height) {
    std::vector<float> out = base;
    std::vector<float> below = base;
    uint32_t w = width, h = height;
    while (w > 1 || h > 1) {
        const uint32_t aw = (w + 1) / 2, ah = (h + 1) / 2;
        std::vector<float> above(uint64_t(aw) * ah);
        for (uint32_t y = 0; y < ah; ++y)
            for (uint32_t x = 0; x < aw; ++x) {
                float m = below[uint64_t(2 * y) * w + 2 * x];
                for (uint32_t by = 2 * y; by < std::min(2 * y + 2, h); ++by)
                    for (uint32_t bx = 2 * x; bx < std::min(2 * x + 2, w); ++bx)
                        m = std::max(m, below[uint64_t(by) * w + bx]);
                above[uint64_t(y) * aw + x] = m;
            }
        out.insert(out.end(), above.begin(), above.end());
        below = std::move(above);
        w = aw, h = ah;
    }
    return out;
}

TEST(HzmLayout, FiveByThreeHasFourLevelsDownToOneTexel) {
    HzmLevels layout;
    hzmLayout(5, 3, layout);
    EXPECT_EQ(layout.data, nullptr);
    ASSERT_EQ(layout.level_count, 4u);
    const uint32_t widths[] = {5, 3, 2, 1}, heights[] = {3, 2, 1, 1};
    const uint64_t offsets[] = {0, 15, 21, 23};
    for (uint32_t l = 0; l < 4; ++l) {
        EXPECT_EQ(layout.width[l], widths[l]) << "level " << l;
        EXPECT_EQ(layout.height[l], heights[l]) << "level " << l;
        EXPECT_EQ(layout.offset[l], offsets[l]) << "level " << l;
    }
    EXPECT_EQ(hzmTotalTexels(5, 3), 24u);
}

TEST(HzmLayout, CountsLevelsOfSquareThinAndLimitSizes) {
    HzmLevels layout;
    hzmLayout(8, 8, layout);
    EXPECT_EQ(layout.level_count, 4u);
    EXPECT_EQ(hzmTotalTexels(8, 8), 64u + 16 + 4 + 1);
    hzmLayout(1, 1, layout);
    EXPECT_EQ(layout.level_count, 1u);
    EXPECT_EQ(hzmTotalTexels(1, 1), 1u);
    hzmLayout(1, 9, layout);  // 9, 5, 3, 2, 1
    EXPECT_EQ(layout.level_count, 5u);
    EXPECT_EQ(hzmTotalTexels(1, 9), 9u + 5 + 3 + 2 + 1);
    hzmLayout(32768, 32768, layout);
    EXPECT_EQ(layout.level_count, 16u);
    EXPECT_EQ(layout.width[15], 1u);
    EXPECT_EQ(layout.height[15], 1u);
    hzmLayout(512, 0, layout);
    EXPECT_EQ(layout.level_count, 0u);
    EXPECT_EQ(hzmTotalTexels(512, 0), 0u);
}

// 5x3: the last odd column and row fold in as single-texel columns and rows.
TEST_F(HzmBuild, FiveByThreeTakesMaxOverPartialBlocks) {
    // rows bottom (y = 0) to top
    const std::vector<float> base = {
        0.10f, 0.20f, 0.30f, 0.40f, 0.50f,
        0.60f, 0.15f, 0.25f, 0.35f, 0.05f,
        0.90f, 0.11f, 0.12f, 0.13f, 0.95f,
    };
    DeviceArray<float> levels = pyramidOf(base, 5, 3);
    hzmBuild(levels.ptr(), 5, 3);
    HzmLevels layout;
    hzmLayout(5, 3, layout);
    EXPECT_EQ(level(levels, layout, 0), base);
    EXPECT_EQ(level(levels, layout, 1), (std::vector<float>{0.60f, 0.40f, 0.50f, 0.90f, 0.13f, 0.95f}));
    EXPECT_EQ(level(levels, layout, 2), (std::vector<float>{0.90f, 0.95f}));
    EXPECT_EQ(level(levels, layout, 3), (std::vector<float>{0.95f}));
    EXPECT_EQ(toHost(levels)[24], kSentinel);
}

// 8x8 at 0.25 with one 0.75 spike in some 2x2 blocks, in a different corner each time, and
// one 1.0: max (not mean, not a fixed corner) must carry each spike up.
TEST_F(HzmBuild, EightByEightCarriesEverySpikeUp) {
    std::vector<float> base(64, 0.25f);
    auto at = [&](uint32_t x, uint32_t y) -> float& { return base[y * 8 + x]; };
    at(0, 0) = 0.75f;  // block (0,0), bottom-left
    at(3, 0) = 0.75f;  // block (1,0), bottom-right
    at(4, 3) = 0.75f;  // block (2,1), top-left
    at(7, 7) = 0.75f;  // block (3,3), top-right
    at(5, 6) = 1.00f;  // block (2,3)
    DeviceArray<float> levels = pyramidOf(base, 8, 8);
    hzmBuild(levels.ptr(), 8, 8);
    HzmLevels layout;
    hzmLayout(8, 8, layout);
    const float q = 0.25f, s = 0.75f;
    EXPECT_EQ(level(levels, layout, 1), (std::vector<float>{
                                            s, s, q, q,
                                            q, q, s, q,
                                            q, q, q, q,
                                            q, q, 1, s,
                                        }));
    EXPECT_EQ(level(levels, layout, 2), (std::vector<float>{s, s, q, 1}));
    EXPECT_EQ(level(levels, layout, 3), (std::vector<float>{1}));
    EXPECT_EQ(toHost(levels)[85], kSentinel);
}

TEST_F(HzmBuild, OneTexelBufferIsLeftAlone) {
    DeviceArray<float> levels = pyramidOf({0.5f}, 1, 1);
    hzmBuild(levels.ptr(), 1, 1);
    EXPECT_EQ(toHost(levels), (std::vector<float>{0.5f, kSentinel}));
}

TEST_F(HzmBuild, RandomBuffersMatchScalarReference) {
    std::mt19937 rng(20240611);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    const uint32_t sizes[][2] = {{1, 2}, {2, 1}, {7, 1}, {1, 9}, {3, 3}, {33, 17}, {64, 64}, {100, 37}, {513, 511}};
    for (const auto& size : sizes) {
        const uint32_t w = size[0], h = size[1];
        std::vector<float> base(uint64_t(w) * h);
        for (float& d : base) d = unit(rng);
        DeviceArray<float> levels = pyramidOf(base, w, h);
        hzmBuild(levels.ptr(), w, h);
        const std::vector<float> expected = referencePyramid(base, w, h);
        ASSERT_EQ(expected.size(), hzmTotalTexels(w, h)) << w << "x" << h;
        const std::vector<float> built = toHost(levels);
        EXPECT_TRUE(std::equal(expected.begin(), expected.end(), built.begin())) << w << "x" << h;
        EXPECT_EQ(built[expected.size()], kSentinel) << w << "x" << h;
    }
}

}  // namespace
}  // namespace occ::k
