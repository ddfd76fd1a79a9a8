// SPDX-License-Identifier: MIT
#include "render/picture_metrics.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace occ::render {
namespace {

// Sharma, Wu & Dalal 2005, Table 1: all 34 published pairs and their CIEDE2000, to 4 decimals.
// Pairs 7-16 are the edge cases of the hue angle: an achromatic colour (7, 8), hues either
// side of 0/360 whose mean wraps one way or the other (9-12) and hues 180 degrees apart
// (13-16); 17-24 vary one of L, C, h; 25-34 are real samples.
struct SharmaPair {
    Lab a, b;
    double delta_e;
};
const SharmaPair kSharmaPairs[] = {
    {{50.0000, 2.6772, -79.7751}, {50.0000, 0.0000, -82.7485}, 2.0425},
    {{50.0000, 3.1571, -77.2803}, {50.0000, 0.0000, -82.7485}, 2.8615},
    {{50.0000, 2.8361, -74.0200}, {50.0000, 0.0000, -82.7485}, 3.4412},
    {{50.0000, -1.3802, -84.2814}, {50.0000, 0.0000, -82.7485}, 1.0000},
    {{50.0000, -1.1848, -84.8006}, {50.0000, 0.0000, -82.7485}, 1.0000},
    {{50.0000, -0.9009, -85.5211}, {50.0000, 0.0000, -82.7485}, 1.0000},
    {{50.0000, 0.0000, 0.0000}, {50.0000, -1.0000, 2.0000}, 2.3669},
    {{50.0000, -1.0000, 2.0000}, {50.0000, 0.0000, 0.0000}, 2.3669},
    {{50.0000, 2.4900, -0.0010}, {50.0000, -2.4900, 0.0009}, 7.1792},
    {{50.0000, 2.4900, -0.0010}, {50.0000, -2.4900, 0.0010}, 7.1792},
    {{50.0000, 2.4900, -0.0010}, {50.0000, -2.4900, 0.0011}, 7.2195},
    {{50.0000, 2.4900, -0.0010}, {50.0000, -2.4900, 0.0012}, 7.2195},
    {{50.0000, -0.0010, 2.4900}, {50.0000, 0.0009, -2.4900}, 4.8045},
    {{50.0000, -0.0010, 2.4900}, {50.0000, 0.0010, -2.4900}, 4.8045},
    {{50.0000, -0.0010, 2.4900}, {50.0000, 0.0011, -2.4900}, 4.7461},
    {{50.0000, 2.5000, 0.0000}, {50.0000, 0.0000, -2.5000}, 4.3065},
    {{50.0000, 2.5000, 0.0000}, {73.0000, 25.0000, -18.0000}, 27.1492},
    {{50.0000, 2.5000, 0.0000}, {61.0000, -5.0000, 29.0000}, 22.8977},
    {{50.0000, 2.5000, 0.0000}, {56.0000, -27.0000, -3.0000}, 31.9030},
    {{50.0000, 2.5000, 0.0000}, {58.0000, 24.0000, 15.0000}, 19.4535},
    {{50.0000, 2.5000, 0.0000}, {50.0000, 3.1736, 0.5854}, 1.0000},
    {{50.0000, 2.5000, 0.0000}, {50.0000, 3.2972, 0.0000}, 1.0000},
    {{50.0000, 2.5000, 0.0000}, {50.0000, 1.8634, 0.5757}, 1.0000},
    {{50.0000, 2.5000, 0.0000}, {50.0000, 3.2592, 0.3350}, 1.0000},
    {{60.2574, -34.0099, 36.2677}, {60.4626, -34.1751, 39.4387}, 1.2644},
    {{63.0109, -31.0961, -5.8663}, {62.8187, -29.7946, -4.0864}, 1.2630},
    {{61.2901, 3.7196, -5.3901}, {61.4292, 2.2480, -4.9620}, 1.8731},
    {{35.0831, -44.1164, 3.7933}, {35.0232, -40.0716, 1.5901}, 1.8645},
    {{22.7233, 20.0904, -46.6940}, {23.0331, 14.9730, -42.5619}, 2.0373},
    {{36.4612, 47.8580, 18.3852}, {36.2715, 50.5065, 21.2231}, 1.4146},
    {{90.8027, -2.0831, 1.4410}, {91.1528, -1.6435, 0.0447}, 1.4441},
    {{90.9257, -0.5406, -0.9208}, {88.6381, -0.8985, -0.7239}, 1.5381},
    {{6.7747, -0.2908, -2.4247}, {5.8714, -0.0985, -2.2286}, 0.6377},
    {{2.0776, 0.0795, -1.1350}, {0.9033, -0.0636, -0.5514}, 0.9082},
};

TEST(Ciede2000, MatchesSharmasPublishedPairsToFourDecimals) {
    for (size_t i = 0; i < std::size(kSharmaPairs); ++i) {
        const SharmaPair& pair = kSharmaPairs[i];
        EXPECT_NEAR(ciede2000(pair.a, pair.b), pair.delta_e, 0.5e-4) << "pair " << i + 1;
    }
}

TEST(Ciede2000, IsSymmetricAndZeroForEqualColours) {
    for (const SharmaPair& pair : kSharmaPairs) {
        EXPECT_NEAR(ciede2000(pair.a, pair.b), ciede2000(pair.b, pair.a), 1e-12);
        EXPECT_EQ(ciede2000(pair.a, pair.a), 0.0);
    }
}

// scikit-image's white is (100, -0.0025, 0.0047): its sRGB matrix's white and its D65 white
// differ in the sixth decimal. The other values are scikit-image 0.19.3's, from
// `rgb2lab(np.array([[[R, G, B]]], np.uint8))[0, 0]`.
TEST(SrgbToLab, WhiteIsLightnessHundredAndNeutral) {
    const Lab white = srgbToLab(255, 255, 255);
    EXPECT_NEAR(white.l, 100.0, 1e-9);
    EXPECT_NEAR(white.a, 0.0, 0.01);
    EXPECT_NEAR(white.b, 0.0, 0.01);
    EXPECT_NEAR(white.a, -0.0024549378620508655, 1e-9);
    EXPECT_NEAR(white.b, 0.004653421154054982, 1e-9);
    const Lab black = srgbToLab(0, 0, 0);
    EXPECT_EQ(black.l, 0.0);
    EXPECT_EQ(black.a, 0.0);
    EXPECT_EQ(black.b, 0.0);
}

TEST(SrgbToLab, PrimariesMatchScikitImage) {
    const Lab red = srgbToLab(255, 0, 0);
    EXPECT_NEAR(red.l, 53.2405879437449, 1e-9);
    EXPECT_NEAR(red.a, 80.0923082256922, 1e-9);
    EXPECT_NEAR(red.b, 67.2027510444287, 1e-9);
    const Lab blue = srgbToLab(0, 0, 255);
    EXPECT_NEAR(blue.l, 32.29567256501351, 1e-9);
    EXPECT_NEAR(blue.a, 79.18559091176556, 1e-9);
    EXPECT_NEAR(blue.b, -107.85730020669489, 1e-9);
    const Lab green = srgbToLab(10, 200, 30);
    EXPECT_NEAR(green.l, 70.5001319946117, 1e-9);
    EXPECT_NEAR(green.a, -70.51383107333548, 1e-9);
    EXPECT_NEAR(green.b, 64.94083996261953, 1e-9);
}

// Six pixels whose CIEDE2000s (scikit-image's deltaE_ciede2000 of rgb2lab) are, in order:
// 0 (identical), 0.157, 1.138, 2.226, 100 and 0 again.
TEST(PerceptiblyChangedPixels, CountsPixelsAboveTheThreshold) {
    const std::vector<uint8_t> a = {30, 60, 90, 0, 0, 0, 128, 128, 128, 128, 128, 128, 0, 0, 0, 7, 7, 7};
    const std::vector<uint8_t> b = {30, 60, 90, 1, 1, 1, 130, 128, 128, 132, 128, 128, 255, 255, 255, 7, 7, 7};
    EXPECT_EQ(perceptiblyChangedPixels(a.data(), b.data(), 6), 2u);
    EXPECT_EQ(perceptiblyChangedPixels(b.data(), a.data(), 6), 2u);
    EXPECT_EQ(perceptiblyChangedPixels(a.data(), b.data(), 6, 0.0), 4u);
    EXPECT_EQ(perceptiblyChangedPixels(a.data(), b.data(), 6, 1.0), 3u);
    EXPECT_EQ(perceptiblyChangedPixels(a.data(), b.data(), 6, 50.0), 1u);
    EXPECT_EQ(perceptiblyChangedPixels(a.data(), b.data(), 0), 0u);
}

// Two 16 x 12 pictures (numpy shape (12, 16, 3)) filled by formulas of x, y and the channel c:
//   A = (37 x + 91 y + 53 c) % 256
//   B = (7 x^2 + 13 y + 101 c + 3 x y) % 256
//   C = clip(A + (5 x + 3 y + c) % 11 - 5, 0, 255)
std::vector<uint8_t> formulaPicture(char which, uint32_t width, uint32_t height) {
    std::vector<uint8_t> picture;
    for (int y = 0; y < int(height); ++y)
        for (int x = 0; x < int(width); ++x)
            for (int c = 0; c < 3; ++c) {
                const int a = (x * 37 + y * 91 + c * 53) % 256;
                if (which == 'A') picture.push_back(uint8_t(a));
                else if (which == 'B') picture.push_back(uint8_t((x * x * 7 + y * 13 + c * 101 + x * y * 3) % 256));
                else picture.push_back(uint8_t(std::clamp(a + (x * 5 + y * 3 + c) % 11 - 5, 0, 255)));
            }
    return picture;
}

TEST(Ssim, IdenticalPicturesScoreOne) {
    const std::vector<uint8_t> a = formulaPicture('A', 16, 12);
    EXPECT_DOUBLE_EQ(ssim(a.data(), a.data(), 16, 12), 1.0);
    const std::vector<uint8_t> flat(7 * 7 * 3, 200);
    EXPECT_DOUBLE_EQ(ssim(flat.data(), flat.data(), 7, 7), 1.0);
}

// Expected values from scikit-image 0.19.3, with A, B, C built as above by numpy:
//   y, x, c = np.mgrid[0:12, 0:16, 0:3]
//   structural_similarity(A, B, channel_axis=-1, data_range=255)  # and (A, C)
// and for 7 x 7 the same formulas over np.mgrid[0:7, 0:7, 0:3].
TEST(Ssim, MatchesScikitImageOnFormulaPictures) {
    const std::vector<uint8_t> a = formulaPicture('A', 16, 12), b = formulaPicture('B', 16, 12);
    const std::vector<uint8_t> c = formulaPicture('C', 16, 12);
    EXPECT_NEAR(ssim(a.data(), b.data(), 16, 12), -0.06727157209502964, 1e-12);
    EXPECT_NEAR(ssim(a.data(), c.data(), 16, 12), 0.9991086997350744, 1e-12);
    EXPECT_NEAR(ssim(b.data(), a.data(), 16, 12), -0.06727157209502964, 1e-12);
    const std::vector<uint8_t> a7 = formulaPicture('A', 7, 7), b7 = formulaPicture('B', 7, 7);
    EXPECT_NEAR(ssim(a7.data(), b7.data(), 7, 7), -0.057064794244472195, 1e-12);
}

// No 7 x 7 window fits; scikit-image raises there.
TEST(Ssim, IsUndefinedBelowSevenPixelsASide) {
    const std::vector<uint8_t> a(6 * 7 * 3, 10);
    EXPECT_TRUE(std::isnan(ssim(a.data(), a.data(), 6, 7)));
    EXPECT_TRUE(std::isnan(ssim(a.data(), a.data(), 7, 6)));
    EXPECT_TRUE(std::isnan(ssim(a.data(), a.data(), 0, 0)));
}

// Item pictures drawn as text: '.' is background (0), letters are items 'A' - '@' (A = 1, ...).
std::vector<uint32_t> items(const std::vector<std::string>& rows) {
    std::vector<uint32_t> ids;
    for (const std::string& row : rows)
        for (char ch : row) ids.push_back(ch == '.' ? 0u : uint32_t(ch - '@'));
    return ids;
}

// Each item gets its own colour, so a pixel's colour changes exactly where its item does.
std::vector<uint8_t> colours(const std::vector<uint32_t>& ids) {
    std::vector<uint8_t> rgb;
    for (uint32_t id : ids) {
        rgb.push_back(uint8_t(40 * id));
        rgb.push_back(uint8_t(255 - 30 * id));
        rgb.push_back(uint8_t(90));
    }
    return rgb;
}

// Ours moves the 3 x 3 item A one pixel right and draws item B at the opposite corner from
// the reference's, and shades one background pixel differently.
TEST(ChangedPixelItemDistances, MeasuresToTheNearestReferencePixelOfTheSameItem) {
    const std::vector<uint32_t> ref = items({
        "........",
        "........",
        "..AAA...",
        "..AAA...",
        "..AAA...",
        "........",
        "........",
        "B.......",
    });
    const std::vector<uint32_t> ours = items({
        "........",
        "........",
        "...AAA..",
        "...AAA..",
        "...AAA..",
        "........",
        "........",
        ".......B",
    });
    std::vector<uint8_t> ours_rgb = colours(ours);
    const std::vector<uint8_t> ref_rgb = colours(ref);
    ours_rgb[3 * 6] += 1;  // pixel (6, 0): same item, other shade

    std::vector<float> distances;
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 8, distances);
    // In buffer order: the reshaded pixel finds its background in place; each row of A's left
    // edge (ours background) finds background one pixel left, its right edge finds A one
    // pixel left; (0, 7) finds background beside it; ours' B at (7, 7) is 7 from the reference's.
    EXPECT_EQ(distances, (std::vector<float>{0, 1, 1, 1, 1, 1, 1, 1, 7}));

    // Within 4 pixels B has no match: the sentinel 4 + 1 stands in. The list is appended to.
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 4, distances);
    ASSERT_EQ(distances.size(), 18u);
    EXPECT_EQ(distances.back(), 5.0f);
}

// From ours' item C at (0, 0) the reference has C at (3, 3), in ring 3, and at (4, 0), in ring
// 4: the search must go on past the first ring with a match, since 4 < sqrt(18) = 4.24.
TEST(ChangedPixelItemDistances, FindsTheEuclideanNearestNotTheFirstRingsMatch) {
    std::vector<uint32_t> ref(8 * 8, 0), ours(8 * 8, 0);
    ours[0] = 3;
    ref[3 * 8 + 3] = 3;
    std::vector<float> distances;
    const std::vector<uint8_t> ours_rgb = colours(ours), ref_rgb = colours(ref);
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 8, distances);
    ASSERT_EQ(distances.size(), 2u);  // (0, 0) and (3, 3) changed
    EXPECT_FLOAT_EQ(distances[0], std::sqrt(18.0f));
    EXPECT_EQ(distances[1], 1.0f);  // ours' background at (3, 3): background beside it

    ref[4] = 3;
    const std::vector<uint8_t> ref_rgb2 = colours(ref);
    distances.clear();
    changedPixelItemDistances(ours_rgb.data(), ref_rgb2.data(), ours.data(), ref.data(), 8, 8, 8, distances);
    EXPECT_EQ(distances[0], 4.0f);

    // Ring 3 lies within radius 4, but its corner (3, 3) does not: still "farther than 4".
    ref[4] = 0;
    distances.clear();
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 4, distances);
    EXPECT_EQ(distances[0], 5.0f);
}

// An item the reference hides behind a tied surface (coplanar walls: the reference showed item 2
// where item 5 lies at the same depth) matches where a tie buffer holds it, in either buffer,
// and only there.
TEST(ChangedPixelItemDistances, TiedReferenceItemsMatchLikeTheShownOnes) {
    std::vector<uint32_t> ref(8 * 8, 2), ours(8 * 8, 2), tied_a(8 * 8, 2), tied_b(8 * 8, 2);
    ours[2 * 8 + 2] = 5;  // ours shows 5 at (2, 2), the reference 2 everywhere
    const std::vector<uint8_t> ours_rgb = colours(ours), ref_rgb = colours(ref);
    std::vector<float> distances;
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 4, distances);
    EXPECT_EQ(distances, std::vector<float>{5.0f});  // no 5 within 4 pixels

    tied_b[2 * 8 + 5] = 5;  // 5 ties with 2 three pixels right of (2, 2)
    const uint32_t* const tied[2] = {tied_a.data(), tied_b.data()};
    distances.clear();
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 4, distances, tied);
    EXPECT_EQ(distances, std::vector<float>{3.0f});

    tied_a[2 * 8 + 2] = 5;  // and at (2, 2) itself, in the other buffer
    distances.clear();
    changedPixelItemDistances(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 4, distances, tied);
    EXPECT_EQ(distances, std::vector<float>{0.0f});
    const PictureDifference d =
        comparePictures(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 1.0f, tied);
    EXPECT_EQ(d.bound_pixels, 1u);
    EXPECT_EQ(d.bound_beyond_tau, 0u);
}

TEST(Percentile, IsTheNearestRank) {
    std::vector<float> values = {5, 1, 4, 2, 3};
    EXPECT_EQ(percentile(values, 0), 1.0);
    EXPECT_EQ(percentile(values, 20), 1.0);   // rank ceil(1.0) = 1
    EXPECT_EQ(percentile(values, 21), 2.0);   // rank ceil(1.05) = 2
    EXPECT_EQ(percentile(values, 50), 3.0);   // rank ceil(2.5) = 3
    EXPECT_EQ(percentile(values, 99), 5.0);
    EXPECT_EQ(percentile(values, 100), 5.0);
    std::vector<float> hundred(100, 1.0f);
    hundred[7] = 9.0f;
    EXPECT_EQ(percentile(hundred, 99), 1.0);  // rank 99 of 100: the one 9 is the 100th
    std::vector<float> none;
    EXPECT_EQ(percentile(none, 99), 0.0);
}

// Two frames of different sizes pool as the one picture that holds both: squared errors add
// up, rather than their per-frame PSNRs being averaged.
TEST(ComparePictures, FramesPoolAsOneConcatenatedPictureThroughTheirSquaredErrors) {
    const std::vector<uint8_t> a1 = formulaPicture('A', 16, 12), b1 = formulaPicture('C', 16, 12);
    const std::vector<uint8_t> a2 = formulaPicture('A', 9, 8), b2 = formulaPicture('B', 9, 8);
    const PictureDifference first = comparePictures(a1.data(), b1.data(), nullptr, nullptr, 16, 12, 1.0f);
    const PictureDifference second = comparePictures(a2.data(), b2.data(), nullptr, nullptr, 9, 8, 1.0f);

    std::vector<uint8_t> a = a1, b = b1;
    a.insert(a.end(), a2.begin(), a2.end());
    b.insert(b.end(), b2.begin(), b2.end());
    const uint32_t pixels = 16 * 12 + 9 * 8;
    const PictureDifference joined = comparePictures(a.data(), b.data(), nullptr, nullptr, pixels, 1, 1.0f);

    const double pooled = psnrFromSquaredError(first.mse * 3 * 16 * 12 + second.mse * 3 * 9 * 8, 3 * pixels);
    EXPECT_NEAR(pooled, joined.psnr_db, 1e-12);
    EXPECT_GT(pooled, second.psnr_db);  // pooled, the good first frame outweighs the bad
    EXPECT_LT(pooled, first.psnr_db);
    EXPECT_NEAR(first.perceptible_percent * 16 * 12 + second.perceptible_percent * 9 * 8,
                joined.perceptible_percent * pixels, 1e-9);
    EXPECT_TRUE(std::isnan(joined.ssim));  // one row: no window fits
    EXPECT_EQ(psnrFromSquaredError(0, 3), 100.0);
    EXPECT_EQ(psnrFromSquaredError(5, 0), 100.0);
}

TEST(ComparePictures, WithoutItemsSkipsTheBoundCheck) {
    const std::vector<uint8_t> a = formulaPicture('A', 16, 12), b = formulaPicture('B', 16, 12);
    const PictureDifference d = comparePictures(a.data(), b.data(), nullptr, nullptr, 16, 12, 1.0f);
    EXPECT_EQ(d.bound_p99_px, 0.0);
    EXPECT_EQ(d.bound_pixels, 0u);
    EXPECT_NEAR(d.ssim, -0.06727157209502964, 1e-12);
    EXPECT_LT(d.psnr_db, 20.0);
    EXPECT_GT(d.perceptible_percent, 50.0);
}

TEST(ComparePictures, IdenticalPicturesShowNoDifference) {
    const std::vector<uint8_t> a = formulaPicture('A', 16, 12);
    const std::vector<uint32_t> ids(16 * 12, 1);
    const PictureDifference d = comparePictures(a.data(), a.data(), ids.data(), ids.data(), 16, 12, 1.0f);
    EXPECT_EQ(d.psnr_db, 100.0);
    EXPECT_EQ(d.perceptible_percent, 0.0);
    EXPECT_EQ(d.ssim, 1.0);
    EXPECT_EQ(d.bound_p99_px, 0.0);
}

// The 8 x 8 fixture above, through comparePictures: the one far item (7 px) is the top 1 of 8.
TEST(ComparePictures, BoundP99IsTheFrameNearestRankOfItsDistances) {
    const std::vector<uint32_t> ref = items({"........", "........", "..AAA...", "..AAA...", "..AAA...", "........",
                                             "........", "B......."});
    const std::vector<uint32_t> ours = items({"........", "........", "...AAA..", "...AAA..", "...AAA..", "........",
                                              "........", ".......B"});
    const std::vector<uint8_t> ours_rgb = colours(ours), ref_rgb = colours(ref);
    const PictureDifference d = comparePictures(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 1.0f);
    EXPECT_EQ(d.bound_p99_px, 7.0);  // 8 distances: rank ceil(7.92) = 8, the largest
    EXPECT_EQ(d.bound_pixels, 8u);
    EXPECT_EQ(d.bound_beyond_tau, 1u);  // seven at 1 px are within tau = 1, the 7 px one is not
    const PictureDifference tight = comparePictures(ours_rgb.data(), ref_rgb.data(), ours.data(), ref.data(), 8, 8, 0.5f);
    EXPECT_EQ(tight.bound_beyond_tau, 8u);
}

}  // namespace
}  // namespace occ::render
