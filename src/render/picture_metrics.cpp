// SPDX-License-Identifier: MIT
#include "render/picture_metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

namespace occ::render {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// sRGB's decoding curve (IEC 61966-2-1) for each 8-bit value, computed once: the pow in it
// costs more than the rest of a colour conversion together.
const std::array<double, 256>& srgbToLinear() {
    static const std::array<double, 256> table = [] {
        std::array<double, 256> t{};
        for (int i = 0; i < 256; ++i) {
            const double v = i / 255.0;
            t[size_t(i)] = v > 0.04045 ? std::pow((v + 0.055) / 1.055, 2.4) : v / 12.92;
        }
        return t;
    }();
    return table;
}

// CIELAB's compression of a white-relative tristimulus value, with scikit-image's constants
// (0.008856 and 7.787 rather than the exact 216/24389 and 841/108) so that ours matches it.
double labCurve(double t) { return t > 0.008856 ? std::cbrt(t) : 7.787 * t + 16.0 / 116.0; }

// Sums over boxes of the five quantities SSIM needs (x, y, x^2, y^2, xy), one array each so
// that the loops over a row vectorise. 32 bits hold them: a 7 x 7 sum of squares is at most
// 49 * 255^2 = 3 186 225, and n * sum(x^2) - sum(x)^2 at most 49 * 3 186 225 = 156 125 025.
struct BoxSums {
    std::vector<int32_t> x, y, xx, yy, xy;
    explicit BoxSums(size_t n) : x(n), y(n), xx(n), yy(n), xy(n) {}
};

// One window's SSIM from its exact integer sums over the n = 49 pixels. The variances come from
// n * sum(x^2) - sum(x)^2, also exact, so only the final divisions round (scikit-image's
// float filter sums round a little more, about 1e-14 on 512 x 512 pictures). The sample
// (co)variance's n / (n - 1) makes their divisor n (n - 1).
double windowSsim(int32_t x, int32_t y, int32_t xx, int32_t yy, int32_t xy) {
    constexpr int32_t kN = 49;
    constexpr double kC1 = (0.01 * 255) * (0.01 * 255), kC2 = (0.03 * 255) * (0.03 * 255);
    constexpr double kMeanScale = 1.0 / kN, kVarianceScale = 1.0 / (kN * (kN - 1));
    const double mx = x * kMeanScale, my = y * kMeanScale;
    const double vx = (kN * xx - x * x) * kVarianceScale;
    const double vy = (kN * yy - y * y) * kVarianceScale;
    const double vxy = (kN * xy - x * y) * kVarianceScale;
    return ((2 * mx * my + kC1) * (2 * vxy + kC2)) / ((mx * mx + my * my + kC1) * (vx + vy + kC2));
}

}  // namespace

Lab srgbToLab(uint8_t r, uint8_t g, uint8_t b) {
    const std::array<double, 256>& linear = srgbToLinear();
    const double lr = linear[r], lg = linear[g], lb = linear[b];
    // scikit-image's xyz_from_rgb (sRGB primaries, D65) and D65 / 2-degree white.
    const double x = (0.412453 * lr + 0.357580 * lg + 0.180423 * lb) / 0.95047;
    const double y = 0.212671 * lr + 0.715160 * lg + 0.072169 * lb;
    const double z = (0.019334 * lr + 0.119193 * lg + 0.950227 * lb) / 1.08883;
    const double fx = labCurve(x), fy = labCurve(y), fz = labCurve(z);
    return {116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)};
}

// Eqs. 2-22 of Sharma, Wu & Dalal 2005, in radians. Written for speed as well, since it runs on
// every changed pixel of every frame: hypot and pow(x, 7) become products and roots, and the
// four cosines of T come from one sine and cosine of the mean hue by the multiple-angle
// identities, which changes results only in the last bits.
double ciede2000(const Lab& a, const Lab& b) {
    constexpr double kPi = std::numbers::pi, kTwoPi = 2 * std::numbers::pi, kDegree = std::numbers::pi / 180;
    constexpr double k25Pow7 = 6103515625.0;
    constexpr double kCos30 = std::numbers::sqrt3 / 2, kSin30 = 0.5;
    constexpr double kCos6 = 0.9945218953682733, kSin6 = 0.10452846326765347;
    constexpr double kCos63 = 0.4539904997395468, kSin63 = 0.8910065241883678;
    const auto pow7 = [](double v) {
        const double v3 = v * v * v;
        return v3 * v3 * v;
    };
    const double c_mean_ab = 0.5 * (std::sqrt(a.a * a.a + a.b * a.b) + std::sqrt(b.a * b.a + b.b * b.b));
    const double c7 = pow7(c_mean_ab);
    const double g = 0.5 * (1 - std::sqrt(c7 / (c7 + k25Pow7)));
    const double a1 = (1 + g) * a.a, a2 = (1 + g) * b.a;
    const double c1 = std::sqrt(a1 * a1 + a.b * a.b), c2 = std::sqrt(a2 * a2 + b.b * b.b);
    // atan2(0, 0) is 0, the hue Eq. 7 gives an achromatic colour.
    double h1 = std::atan2(a.b, a1), h2 = std::atan2(b.b, a2);
    if (h1 < 0) h1 += kTwoPi;
    if (h2 < 0) h2 += kTwoPi;

    const double chroma_product = c1 * c2;
    double dh = h2 - h1;
    if (chroma_product == 0) dh = 0;
    else if (dh > kPi) dh -= kTwoPi;
    else if (dh < -kPi) dh += kTwoPi;
    const double dl = b.l - a.l, dc = c2 - c1;
    const double dh_big = 2 * std::sqrt(chroma_product) * std::sin(dh / 2);

    const double l_mean = 0.5 * (a.l + b.l), c_mean = 0.5 * (c1 + c2);
    // The mean hue goes the short way round the circle; with an achromatic colour the other's
    // hue stands alone (Eq. 14's h1 + h2 case).
    double h_mean = h1 + h2;
    if (chroma_product != 0) {
        if (std::abs(h1 - h2) > kPi) h_mean += h_mean < kTwoPi ? kTwoPi : -kTwoPi;
        h_mean *= 0.5;
    }
    const double cos_h = std::cos(h_mean), sin_h = std::sin(h_mean);
    const double cos_2h = 2 * cos_h * cos_h - 1, sin_2h = 2 * sin_h * cos_h;
    const double cos_3h = cos_2h * cos_h - sin_2h * sin_h, sin_3h = sin_2h * cos_h + cos_2h * sin_h;
    const double cos_4h = 2 * cos_2h * cos_2h - 1, sin_4h = 2 * sin_2h * cos_2h;
    const double t = 1 - 0.17 * (cos_h * kCos30 + sin_h * kSin30) + 0.24 * cos_2h +
                     0.32 * (cos_3h * kCos6 - sin_3h * kSin6) - 0.20 * (cos_4h * kCos63 + sin_4h * kSin63);
    const double hue_from_blue = (h_mean / kDegree - 275) / 25;
    const double d_theta = 30 * kDegree * std::exp(-hue_from_blue * hue_from_blue);
    const double c_mean7 = pow7(c_mean);
    const double r_c = 2 * std::sqrt(c_mean7 / (c_mean7 + k25Pow7));
    const double l_offset = (l_mean - 50) * (l_mean - 50);
    const double s_l = 1 + 0.015 * l_offset / std::sqrt(20 + l_offset);
    const double s_c = 1 + 0.045 * c_mean;
    const double s_h = 1 + 0.015 * c_mean * t;
    const double r_t = -std::sin(2 * d_theta) * r_c;

    const double l_term = dl / s_l, c_term = dc / s_c, h_term = dh_big / s_h;
    // The rotation term can make the sum a rounding below 0 for nearly equal colours.
    return std::sqrt(std::max(0.0, l_term * l_term + c_term * c_term + h_term * h_term + r_t * c_term * h_term));
}

uint64_t perceptiblyChangedPixels(const uint8_t* a, const uint8_t* b, uint64_t pixels, double threshold) {
    uint64_t count = 0;
    for (uint64_t p = 0; p < pixels; ++p) {
        const uint8_t* pa = a + 3 * p;
        const uint8_t* pb = b + 3 * p;
        if (pa[0] == pb[0] && pa[1] == pb[1] && pa[2] == pb[2]) continue;
        count += ciede2000(srgbToLab(pa[0], pa[1], pa[2]), srgbToLab(pb[0], pb[1], pb[2])) > threshold;
    }
    return count;
}

// The windows' sums come from running sums rather than full summed-area tables: a band of 7
// rows keeps one sum per column (and channel), updated by the row that enters and the row that
// leaves as the band moves down, and along the band each window is the one before it less a
// column plus one. That is O(pixels) like a summed-area table, but holds one row of sums
// instead of five tables the size of the picture, and keeps the window's sums in registers.
double ssim(const uint8_t* a, const uint8_t* b, uint32_t width, uint32_t height) {
    constexpr size_t kWindow = 7;
    if (width < kWindow || height < kWindow) return kNaN;
    const size_t row_values = size_t(width) * 3, window_values = (width - kWindow + 1) * 3;
    BoxSums columns(row_values);
    const std::vector<uint8_t> zero_row(row_values, 0);
    // Adds row `in` of both pictures to the column sums and takes row `out` away.
    const auto slide = [&](const uint8_t* in_a, const uint8_t* in_b, const uint8_t* out_a, const uint8_t* out_b) {
        for (size_t i = 0; i < row_values; ++i) {
            const int32_t xi = in_a[i], yi = in_b[i], xo = out_a[i], yo = out_b[i];
            columns.x[i] += xi - xo;
            columns.y[i] += yi - yo;
            columns.xx[i] += xi * xi - xo * xo;
            columns.yy[i] += yi * yi - yo * yo;
            columns.xy[i] += xi * yi - xo * yo;
        }
    };
    for (size_t row = 0; row < kWindow; ++row)
        slide(a + row * row_values, b + row * row_values, zero_row.data(), zero_row.data());

    const int32_t* cx = columns.x.data();
    const int32_t* cy = columns.y.data();
    const int32_t* cxx = columns.xx.data();
    const int32_t* cyy = columns.yy.data();
    const int32_t* cxy = columns.xy.data();
    // One channel's columns lie 3 values apart (the channels interleave), so a window spans 21.
    constexpr size_t kSpan = 3 * kWindow;
    double total = 0;
    for (size_t top = 0;; ++top) {
        // Summed a band at a time so that no one accumulator gathers hundreds of thousands of terms.
        double band = 0;
        for (size_t channel = 0; channel < 3; ++channel) {
            int32_t x = 0, y = 0, xx = 0, yy = 0, xy = 0;
            for (size_t k = channel; k < kSpan; k += 3) {
                x += cx[k];
                y += cy[k];
                xx += cxx[k];
                yy += cyy[k];
                xy += cxy[k];
            }
            band += windowSsim(x, y, xx, yy, xy);
            for (size_t j = channel + 3; j < window_values; j += 3) {
                const size_t in = j + kSpan - 3, out = j - 3;
                x += cx[in] - cx[out];
                y += cy[in] - cy[out];
                xx += cxx[in] - cxx[out];
                yy += cyy[in] - cyy[out];
                xy += cxy[in] - cxy[out];
                band += windowSsim(x, y, xx, yy, xy);
            }
        }
        total += band;
        if (top + kWindow == height) break;
        const size_t in = (top + kWindow) * row_values, out = top * row_values;
        slide(a + in, b + in, a + out, b + out);
    }
    return total / (double(window_values) * double(height - kWindow + 1));
}

void changedPixelItemDistances(const uint8_t* ours_rgb, const uint8_t* ref_rgb, const uint32_t* ours_items,
                               const uint32_t* ref_items, uint32_t width, uint32_t height, uint32_t max_radius,
                               std::vector<float>& distances, std::span<const uint32_t* const> tied_ref_items) {
    const int64_t w = width, h = height, reach = max_radius;
    for (int64_t y = 0; y < h; ++y) {
        for (int64_t x = 0; x < w; ++x) {
            const int64_t p = y * w + x;
            if (std::memcmp(ours_rgb + 3 * p, ref_rgb + 3 * p, 3) == 0) continue;
            const uint32_t item = ours_items[p];
            // Squared distances are integers, so the search compares them exactly.
            int64_t best = std::numeric_limits<int64_t>::max();
            const auto consider = [&](int64_t qx, int64_t qy) {
                if (qx < 0 || qy < 0 || qx >= w || qy >= h) return;
                const int64_t q = qy * w + qx;
                bool match = ref_items[q] == item;
                for (const uint32_t* tied : tied_ref_items) match = match || tied[q] == item;
                if (!match) return;
                best = std::min(best, (qx - x) * (qx - x) + (qy - y) * (qy - y));
            };
            consider(x, y);
            // Ring r holds the pixels at Chebyshev distance r, none nearer than r in Euclidean
            // distance, so once r * r reaches the best found no later ring can improve on it.
            for (int64_t r = 1; r <= reach && r * r < best; ++r) {
                for (int64_t dx = -r; dx <= r; ++dx) {
                    consider(x + dx, y - r);
                    consider(x + dx, y + r);
                }
                for (int64_t dy = -r + 1; dy <= r - 1; ++dy) {
                    consider(x - r, y + dy);
                    consider(x + r, y + dy);
                }
            }
            // A ring corner can lie beyond max_radius though its ring does not.
            distances.push_back(best <= reach * reach ? float(std::sqrt(double(best))) : float(max_radius + 1));
        }
    }
}

double percentile(std::vector<float>& values, double p) {
    if (values.empty()) return 0;
    const double n = double(values.size());
    // p * n first: for whole p and n it is exact, so a rank like 99 * 100 / 100 is not 99.0000001.
    const double rank = std::ceil(std::clamp(p, 0.0, 100.0) * n / 100.0);
    const size_t index = size_t(std::clamp(rank, 1.0, n)) - 1;
    std::nth_element(values.begin(), values.begin() + std::ptrdiff_t(index), values.end());
    return values[index];
}

double squaredError(const uint8_t* a, const uint8_t* b, uint64_t bytes) {
    // Exact in 64 bits up to 2^64 / 255^2 bytes, and vectorised where a double sum would not be.
    uint64_t sum = 0;
    for (uint64_t i = 0; i < bytes; ++i) {
        const int32_t d = int32_t(a[i]) - int32_t(b[i]);
        sum += uint64_t(d * d);
    }
    return double(sum);
}

double psnrFromSquaredError(double squared_error, uint64_t bytes) {
    if (squared_error == 0 || bytes == 0) return 100.0;
    return std::min(100.0, 10.0 * std::log10(255.0 * 255.0 / (squared_error / double(bytes))));
}

PictureDifference comparePictures(const uint8_t* ours_rgb, const uint8_t* ref_rgb, const uint32_t* ours_items,
                                  const uint32_t* ref_items, uint32_t width, uint32_t height, float tau,
                                  std::span<const uint32_t* const> tied_ref_items) {
    const uint64_t pixels = uint64_t(width) * height, bytes = 3 * pixels;
    PictureDifference d;
    const double squared = squaredError(ours_rgb, ref_rgb, bytes);
    d.psnr_db = psnrFromSquaredError(squared, bytes);
    d.mse = bytes ? squared / double(bytes) : 0.0;
    d.perceptible_percent =
        pixels == 0 ? 0.0 : 100.0 * double(perceptiblyChangedPixels(ours_rgb, ref_rgb, pixels)) / double(pixels);
    d.ssim = ssim(ours_rgb, ref_rgb, width, height);
    if (ours_items && ref_items) {
        std::vector<float> distances;
        changedPixelItemDistances(ours_rgb, ref_rgb, ours_items, ref_items, width, height, kBoundSearchRadiusPx,
                                  distances, tied_ref_items);
        d.bound_pixels = distances.size();
        for (float distance : distances) d.bound_beyond_tau += distance > tau;
        d.bound_p99_px = percentile(distances, 99);
    }
    return d;
}

}  // namespace occ::render
