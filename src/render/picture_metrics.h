// SPDX-License-Identifier: MIT
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

// How far a rendered picture is from a reference picture of the same view, in four measures
// that each answer a different question:
//   PSNR              how large the byte errors are, pooled (frame_display's psnrDb, summed);
//   perceptible share which pixels an observer would see change (CIEDE2000 above a threshold);
//   SSIM              whether structure (edges, texture) survived, as scikit-image scores it;
//   bound p99         how far a changed pixel lies from where the reference shows its item,
//                     i.e. whether a simplification keeps its silhouettes within a pixel bound.
// Pictures are 8-bit RGB, 3 bytes a pixel, width * height pixels in rows of `width`; which row
// comes first does not matter as long as both pictures (and both item buffers) agree.
namespace occ::render {

// CIELAB with the D65 white: l in [0, 100], a and b roughly in [-128, 128].
struct Lab {
    double l, a, b;
};

// An 8-bit sRGB colour in CIELAB, as scikit-image 0.19's rgb2lab computes it with its defaults
// (illuminant D65, 2-degree observer): sRGB -> linear (IEC 61966-2-1 piecewise curve) -> XYZ
// (the sRGB D65 matrix) -> Lab against the white (0.95047, 1, 1.08883), with scikit-image's
// constants 0.008856 and 7.787 for the linear toe. White therefore comes out at
// (100, -0.002, 0.005) rather than exactly (100, 0, 0), as it does in scikit-image.
Lab srgbToLab(uint8_t r, uint8_t g, uint8_t b);

// The CIEDE2000 colour difference with kL = kC = kH = 1 (Sharma, Wu & Dalal, "The CIEDE2000
// color-difference formula: implementation notes, supplementary test data, and mathematical
// observations", 2005). Symmetric; 0 only for equal colours.
double ciede2000(const Lab& a, const Lab& b);

// A CIEDE2000 of about 1 to 2 is the just-noticeable difference commonly quoted; 2 counts only
// differences that an observer sees with the two pictures side by side, so anti-aliasing
// flicker and rounding in the shading do not count as changes.
inline constexpr double kPerceptibleDeltaE = 2.0;

// The number of pixels (of `pixels`, in a and b) whose colours differ by a CIEDE2000 above
// `threshold`. Identical pixels are skipped before any colour conversion, so the cost follows
// the number of changed pixels.
uint64_t perceptiblyChangedPixels(const uint8_t* a, const uint8_t* b, uint64_t pixels,
                                  double threshold = kPerceptibleDeltaE);

// The mean structural similarity of two width x height RGB pictures, equal (to rounding, about
// 1e-12) to scikit-image 0.19's structural_similarity(a, b, channel_axis=-1, data_range=255)
// with its defaults (Wang, Bovik, Sheikh & Simoncelli, "Image quality assessment: from error
// visibility to structural similarity", 2004, Eq. 13, with scikit-image's choices):
// 7 x 7 uniform windows, K1 = 0.01, K2 = 0.03, sample (co)variances (scaled by 49/48), the
// mean taken over the windows that lie wholly inside the picture (scikit-image crops 3 pixels
// from every border), per channel, then over the three channels. 1 for identical pictures.
// Returns NaN when either side is below 7 pixels: no window fits (scikit-image raises there).
double ssim(const uint8_t* a, const uint8_t* b, uint32_t width, uint32_t height);

// The bound check. For every pixel p whose RGB differs in any byte between ours_rgb and
// ref_rgb, appends to `distances` the Euclidean distance in pixels from p to the nearest pixel
// q with ref_items[q] == ours_items[p]: 0 when the reference shows the same item at p, more when
// ours draws the item where the reference does not. Item ids share one id space; 0 (background)
// matches like any other id, so a hole where ours shows background measures to the nearest
// reference background. A changed pixel with no match within max_radius appends
// max_radius + 1, the sentinel for "farther than max_radius". Pixels are appended in buffer
// order; `distances` is not cleared. All four buffers hold width * height pixels.
// tied_ref_items (each width * height ids): more items per reference pixel, those whose surface
// ties in depth with ref_items' there (IFC walls, slabs and their layers overlap): any of them
// matches, for a picture within the bound could show any of them.
// Cost: a ring search that stops once a ring cannot hold anything nearer than the best found,
// so a pixel next to its item costs a few lookups and no pixel costs more than
// (2 max_radius + 1)^2.
void changedPixelItemDistances(const uint8_t* ours_rgb, const uint8_t* ref_rgb, const uint32_t* ours_items,
                               const uint32_t* ref_items, uint32_t width, uint32_t height, uint32_t max_radius,
                               std::vector<float>& distances,
                               std::span<const uint32_t* const> tied_ref_items = {});

// The p-th percentile (p in [0, 100], clamped) of `values` by nearest rank: the smallest value
// v such that at least p percent of the values are <= v (the way bench_massive reads its p99),
// so the answer is always one of the values. 0 for no values. Reorders `values`.
double percentile(std::vector<float>& values, double p);

// How far comparePictures searches for a changed pixel's item, in pixels. A simplification is
// meant to keep its error within a pixel or two; 16 leaves room to see how far a failure goes
// while bounding the cost of a pixel whose item vanished to 33 x 33 lookups.
inline constexpr uint32_t kBoundSearchRadiusPx = 16;

// The distance the bound check allows a changed pixel from its item: tau, but at least one pixel.
// Distances between pixel centres are whole pixels or longer, and an edge that moves by any
// fraction of a pixel flips the pixels it crosses, so one pixel is the finest bound the raster
// can show; a sub-pixel tau is held to it.
inline float boundCheckPixels(float tau) { return tau > 1.0f ? tau : 1.0f; }

// Sum of the squared differences of two byte strings of `bytes` bytes (exact: integers).
double squaredError(const uint8_t* a, const uint8_t* b, uint64_t bytes);

// 10 log10(255^2 / (squared_error / bytes)), capped at 100 dB, the cap that stands for "no
// difference" (also for no error or no bytes). A run pools its frames by summing both.
double psnrFromSquaredError(double squared_error, uint64_t bytes);

// One frame's comparison. Runs pool frames through these fields (the stats CSV and the run
// summary): PSNR from the summed squared error, perceptible pixels and bound counts as sums,
// SSIM as the mean of the frames'.
struct PictureDifference {
    double psnr_db = 100;
    double mse = 0;                  // squared error per byte
    double perceptible_percent = 0;  // pixels changed by a CIEDE2000 above kPerceptibleDeltaE
    double ssim = 1;                 // NaN below 7 x 7 pixels
    // With item buffers: the changed pixels' distances to their item (changedPixelItemDistances,
    // out to kBoundSearchRadiusPx): their nearest-rank 99th percentile, how many were measured
    // and how many lie farther than tau.
    double bound_p99_px = 0;
    uint64_t bound_pixels = 0, bound_beyond_tau = 0;
};

// Compares our width x height RGB picture with the reference. ours_items and ref_items are both
// null (no bound check: the bound fields stay 0) or both width * height item ids (0 =
// background) in one id space; tau is the distance in pixels the bound allows; tied_ref_items as
// changedPixelItemDistances takes them.
PictureDifference comparePictures(const uint8_t* ours_rgb, const uint8_t* ref_rgb, const uint32_t* ours_items,
                                  const uint32_t* ref_items, uint32_t width, uint32_t height, float tau,
                                  std::span<const uint32_t* const> tied_ref_items = {});

}  // namespace occ::render
