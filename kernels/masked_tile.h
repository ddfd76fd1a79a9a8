// SPDX-License-Identifier: MIT
#pragma once

// One subtile of the masked raster (kernels/masked_raster.h) and what a triangle does to it,
// written once for both back ends: the CPU's band loop (kernels/masked_raster_cpu.cpp, its
// coverage masks in SIMD) and the CUDA thread per subtile (kernels/masked_raster.cu) call the
// same functions, so both give the same bits.

#include "raster_setup.h"

#include <cmath>

namespace occ::k {

inline constexpr uint32_t kSubtileWidth = 8, kSubtileHeight = 4;
inline constexpr uint32_t kSubtileFull = 0xffffffffu;
// Rows per band, the CPU's unit of parallel work (8 rows of subtiles): 2^5.
inline constexpr uint32_t kMaskedBandRowsLog2 = 5;

// Two depth layers per subtile (Hasselgren et al. 2016, Section 3): every pixel's depth is at
// most z0 (the reference layer), and the pixels whose bit is set in `mask` (bit 8 * y + x for
// pixel (x, y) of the subtile, y up) are at most z1 (the working layer), which is below z0
// whenever mask is not 0.
struct MaskedSubtile {
    float z0;
    float z1;
    uint32_t mask;
};

// The bits of the pixels of subtile (px0, py0) outside a width x height viewport: they never get
// a triangle, so they count as covered when the layers check for a full subtile.
OCC_HD inline uint32_t subtileOutside(uint32_t px0, uint32_t py0, uint32_t width, uint32_t height) {
    uint32_t outside = 0;
    for (uint32_t y = 0; y < kSubtileHeight; ++y)
        for (uint32_t x = 0; x < kSubtileWidth; ++x)
            if (px0 + x >= width || py0 + y >= height) outside |= 1u << (8 * y + x);
    return outside;
}

// The part of a triangle's pixel box inside subtile (px0, py0), inclusive; empty when the
// triangle's box misses the subtile.
struct SubtileBox {
    uint32_t x_lo, x_hi, y_lo, y_hi;
    bool empty;

    OCC_HD SubtileBox(const DepthRasterTriangle& s, uint32_t px0, uint32_t py0) {
        x_lo = s.x_lo > px0 ? s.x_lo : px0;
        x_hi = uint32_t(s.x_hi) < px0 + kSubtileWidth - 1 ? s.x_hi : px0 + kSubtileWidth - 1;
        y_lo = s.y_lo > py0 ? s.y_lo : py0;
        y_hi = uint32_t(s.y_hi) < py0 + kSubtileHeight - 1 ? s.y_hi : py0 + kSubtileHeight - 1;
        empty = s.x_lo > s.x_hi || x_lo > x_hi || y_lo > y_hi;
    }
    // The box as subtile bits (rows y_lo..y_hi, columns x_lo..x_hi of the subtile at px0, py0).
    OCC_HD uint32_t bits(uint32_t px0, uint32_t py0) const {
        const uint32_t row = (0xffu << (x_lo - px0)) & (0xffu >> (kSubtileWidth - 1 - (x_hi - px0)));
        uint32_t out = 0;
        for (uint32_t y = y_lo - py0; y <= y_hi - py0; ++y) out |= row << (8 * y);
        return out;
    }
    // A bound on the depth the triangle takes at every pixel of the box: its plane, in
    // depthRaster's float arithmetic, at the box's corner farthest along the plane's gradient.
    // Rounding to nearest is monotone, and so are the products with a fixed factor and the
    // sums, so the float value there is at least depthRaster's at any pixel of the box.
    OCC_HD float farDepth(const DepthRasterTriangle& s) const {
        return raster::planeDepth(s, s.gx >= 0.0f ? x_hi : x_lo, s.gy >= 0.0f ? y_hi : y_lo);
    }
};

// The centres of the box the triangle covers, as subtile bits, one pixel at a time in 64-bit
// integers: the reference the CPU's SIMD masks are checked against, and the CUDA path.
OCC_HD inline uint32_t subtileCoverage(const raster::EdgeFunctions& edges, const SubtileBox& box, uint32_t px0,
                                       uint32_t py0) {
    uint32_t bits = 0;
    for (uint32_t y = box.y_lo; y <= box.y_hi; ++y)
        for (uint32_t x = box.x_lo; x <= box.x_hi; ++x)
            if (edges.covers(x, y)) bits |= 1u << (8 * (y - py0) + (x - px0));
    return bits;
}

// What a triangle that covers the pixels `covered` of the subtile, each at depth at most `z`,
// does to its layers (Hasselgren et al. 2016, Section 3.2, with depth growing away from the
// eye): nothing unless it is nearer than the reference layer; a whole subtile becomes the
// reference layer; otherwise it joins the working layer, which becomes the reference once it
// covers the subtile, unless the working layer is farther from it than the reference is (the
// paper's heuristic), in which case the working layer is dropped and the triangle starts a new
// one. Every step keeps each pixel's bound at or above what it was built from: conservative.
// outside: subtileOutside's bits, counted as covered.
OCC_HD inline void updateSubtile(MaskedSubtile& t, uint32_t covered, float z, uint32_t outside) {
    if (covered == 0 || !(z < t.z0)) return;
    if ((covered | outside) == kSubtileFull) {
        t.z0 = z;
        if (t.mask != 0 && !(t.z1 < z)) t.mask = 0;
        return;
    }
    if (t.mask != 0 && fabsf(z - t.z1) > t.z0 - z) t.mask = 0;
    if (t.mask == 0) {
        t.mask = covered;
        t.z1 = z;
    } else {
        t.mask |= covered;
        t.z1 = maxf(t.z1, z);
    }
    if ((t.mask | outside) == kSubtileFull) {
        t.z0 = t.z1;
        t.mask = 0;
    }
}

// The depth bound of pixel bit `bit` of the subtile.
OCC_HD inline float subtileDepth(const MaskedSubtile& t, uint32_t bit) {
    return t.mask >> bit & 1u ? t.z1 : t.z0;
}

}  // namespace occ::k

namespace occ::k {

// The bands of a masked raster, as the CPU's band loop takes them: the set-up triangles binned
// to bands of 2^kMaskedBandRowsLog2 rows (bins.tiles_x == 1), and the depth buffer to fill.
struct MaskedBands {
    const DepthRasterTriangle* setup;
    TileBins bins;
    float* depth;
    uint32_t width, height;
};

// The bits of subtile (px0, py0) inside a width x height viewport (the complement of
// subtileOutside), without loops.
OCC_HD inline uint32_t subtileInside(uint32_t px0, uint32_t py0, uint32_t width, uint32_t height) {
    const uint32_t columns = width - px0 >= kSubtileWidth ? kSubtileWidth : width - px0;
    const uint32_t rows = height - py0 >= kSubtileHeight ? kSubtileHeight : height - py0;
    const uint32_t row = 0xffu >> (kSubtileWidth - columns);
    uint32_t out = 0;
    for (uint32_t y = 0; y < rows; ++y) out |= row << (8 * y);
    return out;
}

#if !defined(__CUDACC__)
// The CPU's band loop (kernels/masked_raster_cpu.cpp): every band in parallel, each pixel of
// the viewport written once.
void maskedRasterBandsCpu(const MaskedBands& bands);
// The instruction set that loop runs with on this machine (simdLevelName).
const char* maskedRasterCpuTarget();
#endif

}  // namespace occ::k
