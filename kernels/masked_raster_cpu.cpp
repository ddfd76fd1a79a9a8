// SPDX-License-Identifier: MIT
// The CPU's band loop of the masked raster (kernels/masked_raster.h): bands of 32 rows in
// parallel (TBB), in each the band's triangles in index order, and per triangle the subtiles of
// its box: a depth bound and an early-out against the reference layer first, then the coverage
// mask of the subtile's 32 pixel centres in SIMD, then the layer update of masked_tile.h.
// Compiled once per instruction set by Highway (foreach_target) and dispatched at run time; with
// -ffp-contract=off, since a fused multiply-add would change the depth's bits (CMakeLists.txt).
// Highway is used as headers only, the copy picked by kernels/simd_level.h.

#include "simd_level_targets.h"
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "masked_raster_cpu.cpp"
#include <hwy/foreach_target.h>  // re-includes this file once per instruction set

#include <hwy/highway.h>

#include "masked_tile.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <vector>

HWY_BEFORE_NAMESPACE();
namespace occ::k::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

// Edge values within a subtile are base + offset, base the 64-bit value at the subtile's first
// pixel clamped to +-2^30 and offset the edge's steps to each of the 32 pixels. When every
// offset is below 2^30 in magnitude, clamping keeps the sign of base + offset at every pixel
// (a base beyond 2^30 outweighs any offset) and the sum stays within int32: the mask is exact.
constexpr int64_t kClamp = int64_t(1) << 30;

alignas(64) constexpr int32_t kColumn[32] = {0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7,
                                             0, 1, 2, 3, 4, 5, 6, 7, 0, 1, 2, 3, 4, 5, 6, 7};
alignas(64) constexpr int32_t kRow[32] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1,
                                          2, 2, 2, 2, 2, 2, 2, 2, 3, 3, 3, 3, 3, 3, 3, 3};

struct SimdEdges {
    alignas(64) int32_t offset[3][32];
};

// Whether every edge's offsets within a subtile stay below 2^30; fills them when they do.
bool makeOffsets(const raster::EdgeFunctions& e, SimdEdges& out) {
    const hn::ScalableTag<int32_t> d;
    const size_t n = hn::Lanes(d);
    for (int k = 0; k < 3; ++k) {
        const int64_t step_x = -e.ey[k] * raster::kUnits, step_y = e.ex[k] * raster::kUnits;
        if (7 * raster::abs64(step_x) + 3 * raster::abs64(step_y) >= kClamp) return false;
        const auto sx = hn::Set(d, int32_t(step_x)), sy = hn::Set(d, int32_t(step_y));
        for (size_t j = 0; j < 32; j += n)
            hn::Store(hn::Add(hn::Mul(hn::Load(d, kColumn + j), sx), hn::Mul(hn::Load(d, kRow + j), sy)), d,
                      out.offset[k] + j);
    }
    return true;
}

int32_t clampBase(int64_t v) { return int32_t(v < -kClamp ? -kClamp : v > kClamp ? kClamp : v); }

// The covered centres of subtile (px0, py0) as its 32 bits (before the box is applied).
uint32_t simdCoverage(const raster::EdgeFunctions& e, const SimdEdges& edges, uint32_t px0, uint32_t py0) {
    const hn::ScalableTag<int32_t> d;
    const size_t n = hn::Lanes(d);
    const auto b0 = hn::Set(d, clampBase(e.inside(0, px0, py0)));
    const auto b1 = hn::Set(d, clampBase(e.inside(1, px0, py0)));
    const auto b2 = hn::Set(d, clampBase(e.inside(2, px0, py0)));
    const auto minus_one = hn::Set(d, -1);
    uint32_t bits = 0;
    for (size_t j = 0; j < 32; j += n) {
        const auto v = hn::Or(hn::Or(hn::Add(b0, hn::Load(d, edges.offset[0] + j)), hn::Add(b1, hn::Load(d, edges.offset[1] + j))),
                              hn::Add(b2, hn::Load(d, edges.offset[2] + j)));
        uint8_t bytes[8] = {};
        hn::StoreMaskBits(d, hn::Gt(v, minus_one), bytes);
        uint64_t word = 0;
        std::memcpy(&word, bytes, (n + 7) / 8);
        if (n < 64) word &= (uint64_t(1) << n) - 1;
        bits |= uint32_t(word << j);
    }
    return bits;
}

}  // namespace

void RasterBand(const MaskedBands& job, uint32_t band) {
    const uint32_t band_y = band << kMaskedBandRowsLog2;
    const uint32_t rows = std::min<uint32_t>(1u << kMaskedBandRowsLog2, job.height - band_y);
    const uint32_t subtiles_x = (job.width + kSubtileWidth - 1) / kSubtileWidth;
    const uint32_t subtiles_y = (rows + kSubtileHeight - 1) / kSubtileHeight;
    thread_local std::vector<MaskedSubtile> tiles;
    tiles.assign(size_t(subtiles_x) * subtiles_y, MaskedSubtile{1.0f, 0.0f, 0u});
    SimdEdges edges;

    for (uint64_t p = job.bins.tileBegin(band); p < job.bins.tileEnd(band); ++p) {
        const DepthRasterTriangle& s = job.setup[job.bins.pair_triangle[p]];
        const uint32_t y_lo = std::max<uint32_t>(s.y_lo, band_y), y_hi = std::min<uint32_t>(s.y_hi, band_y + rows - 1);
        const uint32_t ty0 = (y_lo - band_y) / kSubtileHeight, ty1 = (y_hi - band_y) / kSubtileHeight;
        const uint32_t tx0 = s.x_lo / kSubtileWidth, tx1 = s.x_hi / kSubtileWidth;
        const raster::EdgeFunctions e(s);
        bool offsets = false, simd = false;
        for (uint32_t ty = ty0; ty <= ty1; ++ty) {
            const uint32_t py0 = band_y + ty * kSubtileHeight;
            MaskedSubtile* row = tiles.data() + size_t(ty) * subtiles_x;
            for (uint32_t tx = tx0; tx <= tx1; ++tx) {
                const uint32_t px0 = tx * kSubtileWidth;
                MaskedSubtile& tile = row[tx];
                const SubtileBox box(s, px0, py0);
                if (box.empty) continue;
                const float z = box.farDepth(s);
                if (!(z < tile.z0)) continue;
                if (!offsets) simd = makeOffsets(e, edges), offsets = true;
                const uint32_t covered =
                    simd ? simdCoverage(e, edges, px0, py0) & box.bits(px0, py0) : subtileCoverage(e, box, px0, py0);
                updateSubtile(tile, covered, z, ~subtileInside(px0, py0, job.width, job.height));
            }
        }
    }

    for (uint32_t y = 0; y < rows; ++y) {
        float* out = job.depth + uint64_t(band_y + y) * job.width;
        const MaskedSubtile* row = tiles.data() + size_t(y / kSubtileHeight) * subtiles_x;
        const uint32_t shift = 8 * (y % kSubtileHeight);
        for (uint32_t x = 0; x < job.width; ++x) out[x] = subtileDepth(row[x / kSubtileWidth], shift + x % kSubtileWidth);
    }
}

}  // namespace occ::k::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace occ::k {

namespace {
using BandFunction = void (*)(const MaskedBands&, uint32_t);
const BandFunction kBands[kSimdLevels] = {HWY_CHOOSE_AVX3(RasterBand), HWY_CHOOSE_AVX2(RasterBand),
                                          HWY_CHOOSE_SSE4(RasterBand), HWY_CHOOSE_FALLBACK(RasterBand)};
}  // namespace

void maskedRasterBandsCpu(const MaskedBands& bands) {
    const uint32_t band_count = bands.bins.tiles_y;
    const BandFunction raster = pickSimd(kBands);
    tbb::parallel_for(0u, band_count, [&](uint32_t b) { raster(bands, b); });
}

const char* maskedRasterCpuTarget() {
    SimdLevel level;
    pickSimd(kBands, &level);
    return simdLevelName(level);
}

}  // namespace occ::k
#endif
