// SPDX-License-Identifier: MIT
#include "render/frame_display.h"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

namespace occ::render {
namespace {

TEST(DisplayMetrics, IdenticalImagesHave100Db) {
    const std::vector<uint8_t> a = {0, 17, 255, 128, 3, 9};
    EXPECT_EQ(psnrDb(a.data(), a.data(), a.size()), 100.0);
    EXPECT_EQ(changedPixelPercent(a.data(), a.data(), 2, 3), 0.0);
}

TEST(DisplayMetrics, EmptyImagesCountAsIdentical) {
    const uint8_t a = 1, b = 2;
    EXPECT_EQ(psnrDb(&a, &b, 0), 100.0);
    EXPECT_EQ(changedPixelPercent(&a, &b, 0, 3), 0.0);
}

// One byte off by 255 in a 3-byte image: MSE = 255^2 / 3, so PSNR = 10 log10(3).
TEST(DisplayMetrics, OneByteOffBy255InThreeBytes) {
    const std::vector<uint8_t> a = {0, 50, 100}, b = {255, 50, 100};
    EXPECT_NEAR(psnrDb(a.data(), b.data(), 3), 10.0 * std::log10(3.0), 1e-9);
    EXPECT_NEAR(psnrDb(b.data(), a.data(), 3), 10.0 * std::log10(3.0), 1e-9);
}

// Every byte off by 1: MSE = 1, so PSNR = 20 log10(255) = 48.13 dB.
TEST(DisplayMetrics, EveryByteOffByOne) {
    const std::vector<uint8_t> a = {10, 20, 30, 40}, b = {11, 19, 31, 39};
    EXPECT_NEAR(psnrDb(a.data(), b.data(), 4), 20.0 * std::log10(255.0), 1e-9);
}

// A difference too small to reach 100 dB's MSE is still reported as the cap, not above it.
TEST(DisplayMetrics, PsnrIsCappedAt100) {
    std::vector<uint8_t> a(3'000'000, 7), b = a;
    b[5] = 8;  // MSE = 1 / 3e6: 10 log10(255^2 * 3e6) = 112.9 dB uncapped
    EXPECT_EQ(psnrDb(a.data(), b.data(), a.size()), 100.0);
}

TEST(DisplayMetrics, ChangedPixelsCountAnyChannel) {
    // Four RGB pixels: the second differs in blue only, the fourth in all channels.
    const std::vector<uint8_t> a = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
    const std::vector<uint8_t> b = {1, 2, 3, 4, 5, 0, 7, 8, 9, 0, 0, 0};
    EXPECT_DOUBLE_EQ(changedPixelPercent(a.data(), b.data(), 4, 3), 50.0);
    // Read as twelve one-byte pixels, four of them differ.
    EXPECT_DOUBLE_EQ(changedPixelPercent(a.data(), b.data(), 12, 1), 100.0 * 4.0 / 12.0);
}

TEST(DisplayMetrics, SeenObjectsAreCountedOnce) {
    // Ids are object + 1; 0 is background.
    const std::vector<uint32_t> items = {0, 1, 3, 3, 0, 1, 3};
    std::vector<uint8_t> seen;
    EXPECT_EQ(markSeenObjects(items.data(), items.size(), 4, seen), 2u);
    EXPECT_EQ(seen, (std::vector<uint8_t>{1, 0, 1, 0}));
}

TEST(DisplayMetrics, ItemsPastTheObjectCountAreIgnored) {
    const std::vector<uint32_t> items = {4, 5, 0xffffffffu, 2, 0};
    std::vector<uint8_t> seen;
    EXPECT_EQ(markSeenObjects(items.data(), items.size(), 3, seen), 1u);
    EXPECT_EQ(seen, (std::vector<uint8_t>{0, 1, 0}));
}

TEST(DisplayMetrics, SeenIsClearedAndResizedFirst) {
    std::vector<uint8_t> seen(10, 1);
    const uint32_t background[3] = {0, 0, 0};
    EXPECT_EQ(markSeenObjects(background, 3, 2, seen), 0u);
    EXPECT_EQ(seen, (std::vector<uint8_t>{0, 0}));
    EXPECT_EQ(markSeenObjects(background, 0, 0, seen), 0u);
    EXPECT_TRUE(seen.empty());
}

}  // namespace
}  // namespace occ::render
