// SPDX-License-Identifier: MIT
// The CPU's tile loop of the exact occluder raster (depthRaster, kernels/depth_raster.h): the
// same bits as the one-thread-per-tile loop of depth_raster.cu (RasterTiles), faster.
//  - A triangle's covered centres along each row of its box are one span, the intersection of
//    its three edges' half-rows. The rows where the edges' crossings (in doubles, with a bound
//    on their error) leave no room for a centre are found for the whole box at once, a vector
//    of rows at a time, and skipped (EdgeRows, candidateRows).
//  - The other rows get their exact span in integers, searched from the approximate crossing
//    (a step either side at most), instead of the scalar loop's three 64-bit divisions a row.
//  - The span's depths are written a vector of columns at a time (the tile's 32 columns in 2,
//    4 or 8 vectors), with the plane evaluated in the same float operations as the scalar loop.
//  - The test that skips a triangle whose box is already nearer than its nearest corner runs a
//    vector of columns at a time too.
// Compiled once per instruction set by Highway (foreach_target), the copy picked at run time by
// kernels/simd_level.h; with -ffp-contract=off, so that no multiply-add is fused and the depth
// keeps its bits (CMakeLists.txt).

#include "simd_level_targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "depth_raster_cpu.cpp"
#include <hwy/foreach_target.h>  // re-includes this file once per instruction set

#include <hwy/highway.h>

#include "raster_setup.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

HWY_BEFORE_NAMESPACE();
namespace occ::k::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

namespace {

using namespace raster;

// One edge of a triangle over the rows of its box in one tile (the box clipped to the tile).
// Column i of row j, both counted from the box's first pixel, is inside the edge when
// n0 + j * sy + i * sx >= 0, with n0 = e - threshold at the box's first centre, sx and sy the
// edge function's steps (EdgeFunctions, RasterTiles). The edge crosses row j at column
// alpha + beta * j, which doubles give to within `error`: enough to tell the rows where no
// centre can be covered (most of them: on the plant walks, 9 rows in 10 of a box miss the
// triangle, whose thin slivers have wide boxes), and to start the exact search of the others.
// Bits 0 to count - 1 (count <= 32).
inline uint32_t lowBits(uint32_t count) { return count >= 32 ? ~0u : (1u << count) - 1; }

struct EdgeRows {
    int64_t n0 = 0, sx = 0, sy = 0;
    double alpha = 0.0, beta = 0.0, error = 0.0;

    void start(int64_t n, int64_t step_x, int64_t step_y) {
        n0 = n, sx = step_x, sy = step_y;
        if (sx == 0) return;
        alpha = -double(n0) / double(sx), beta = -double(sy) / double(sx);
        // Each of the two quotients is within 2^-53 of its value, the product and the sum
        // within 2^-53 of theirs, over at most 32 rows.
        error = (std::fabs(alpha) + 64.0 * std::fabs(beta) + 1.0) * 0x1p-48;
    }
    // The rows j in [0, rows) where the edge's half-row is not empty when sx == 0, as bits.
    uint32_t flatRows(uint32_t rows) const {
        int64_t from = 0, to = int64_t(rows) - 1;  // n0 + j * sy >= 0 for j in [from, to]
        if (sy > 0) {
            if (n0 < 0) from = (-n0 + sy - 1) / sy;
        } else if (sy < 0) {
            to = n0 < 0 ? -1 : min64(to, n0 / -sy);
        } else if (n0 < 0) {
            to = -1;
        }
        if (from > to) return 0;
        return lowBits(uint32_t(to) + 1) & ~lowBits(uint32_t(from));
    }
    // Narrows [first, last] (columns of the box, `columns` of them) to this edge's half of row
    // j, exactly in integers: from the approximate crossing, the smallest (sx > 0) or the
    // largest (sx < 0) inside column is at most a step away. sx != 0.
    void narrow(uint32_t j, int64_t columns, int64_t& first, int64_t& last) const {
        const int64_t n = n0 + int64_t(j) * sy;
        const double b = alpha + beta * double(j);
        if (sx > 0) {
            int64_t c = b <= 0.0 ? 0 : b >= double(columns) ? columns : int64_t(std::ceil(b));
            while (c > 0 && n + (c - 1) * sx >= 0) --c;
            while (c < columns && n + c * sx < 0) ++c;
            first = max64(first, c);
        } else {
            int64_t c = b < 0.0 ? -1 : b >= double(columns - 1) ? columns - 1 : int64_t(std::floor(b));
            while (c >= 0 && n + c * sx < 0) --c;
            while (c + 1 < columns && n + (c + 1) * sx >= 0) ++c;
            last = min64(last, c);
        }
    }
};

// The rows j in [0, rows) of the box (columns wide) where the approximate crossings leave a
// column that may be covered, as bits: a superset of the rows with a covered centre.
// jota: the lanes' indices 0, 1, 2, ... as doubles.
template <class VD>
uint32_t candidateRows(const EdgeRows (&edges)[3], uint32_t rows, int64_t columns, VD jota) {
    const hn::ScalableTag<double> dd;
    const uint32_t n = uint32_t(hn::Lanes(dd));
    double error = 0.0;
    for (const EdgeRows& e : edges) error = std::max(error, e.error);
    const auto eps = hn::Set(dd, error);
    const auto lo0 = hn::Set(dd, 0.0), hi0 = hn::Set(dd, double(columns - 1));
    uint32_t bits = 0;
    for (uint32_t j0 = 0; j0 < rows; j0 += n) {
        const auto j = hn::Add(jota, hn::Set(dd, double(j0)));
        auto lo = lo0, hi = hi0;
        for (const EdgeRows& e : edges) {
            const auto b = hn::MulAdd(hn::Set(dd, e.beta), j, hn::Set(dd, e.alpha));
            if (e.sx > 0) lo = hn::Max(lo, b);
            if (e.sx < 0) hi = hn::Min(hi, b);
        }
        const auto open = hn::Le(hn::Ceil(hn::Sub(lo, eps)), hn::Floor(hn::Add(hi, eps)));
        uint8_t out[8] = {};
        hn::StoreMaskBits(dd, open, out);
        bits |= (out[0] & lowBits(n)) << j0;
    }
    bits &= lowBits(rows);
    for (const EdgeRows& e : edges)
        if (e.sx == 0) bits &= e.flatRows(rows);
    return bits;
}

// The lanes of the vector of tile columns starting at c0 that lie in [lo, hi]. iota: the lanes'
// indices 0, 1, 2, ... (Highway's Iota goes through memory, hence made once per tile).
template <class VI>
auto columnsIn(VI iota, uint32_t c0, uint32_t lo, uint32_t hi) {
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(df)> di;
    const auto c = hn::Add(iota, hn::Set(di, int32_t(c0)));
    return hn::RebindMask(df, hn::And(hn::Gt(c, hn::Set(di, int32_t(lo) - 1)), hn::Lt(c, hn::Set(di, int32_t(hi) + 1))));
}

// Whether every pixel of the box (tile coordinates, inclusive) is already at or nearer than
// `bound` (RasterTiles::hidden).
template <class VI>
bool hidden(const float* nearest, float bound, uint32_t x_lo, uint32_t x_hi, uint32_t y_lo, uint32_t y_hi, VI iota) {
    const hn::ScalableTag<float> df;
    const uint32_t n = uint32_t(hn::Lanes(df));
    const auto vbound = hn::Set(df, bound);
    for (uint32_t c0 = x_lo / n * n; c0 <= x_hi; c0 += n) {
        const auto in_box = columnsIn(iota, c0, x_lo, x_hi);
        for (uint32_t y = y_lo; y <= y_hi; ++y)
            if (!hn::AllFalse(df, hn::And(in_box, hn::Gt(hn::Load(df, nearest + y * kTile + c0), vbound)))) return false;
    }
    return true;
}

// Writes min(depth, plane) over columns [a, b] of one tile row: the plane is
// row_depth + gx * (column_base + c) at tile column c, in the scalar loop's float operations.
template <class VI>
void fillSpan(float* row, uint32_t a, uint32_t b, float row_depth, float gx, int32_t column_base, VI iota) {
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(df)> di;
    const uint32_t n = uint32_t(hn::Lanes(df));
    const auto vrow = hn::Set(df, row_depth), vgx = hn::Set(df, gx);
    for (uint32_t c0 = a / n * n; c0 <= b; c0 += n) {
        const auto in_span = columnsIn(iota, c0, a, b);
        const auto column = hn::Add(iota, hn::Set(di, column_base + int32_t(c0)));
        const auto d = hn::Add(vrow, hn::Mul(vgx, hn::ConvertTo(df, column)));
        const auto old = hn::Load(df, row + c0);
        hn::Store(hn::IfThenElse(hn::And(in_span, hn::Lt(d, old)), d, old), df, row + c0);
    }
}

}  // namespace

// The signed doubled area (v1 - v0) x (v2 - v0) of each lane's snapped triangle, exactly: the
// differences fit 32 bits (corners within the guard band, 2^28 units), the products need 64,
// made a pair of lanes at a time. Per 32-bit lane: all ones where the area is not 0, and where
// it is negative.
template <class DI, class V>
void areaSigns(DI di, const V (&x)[3], const V (&y)[3], V& nonzero, V& negative) {
    const V dx1 = hn::Sub(x[1], x[0]), dy1 = hn::Sub(y[1], y[0]);
    const V dx2 = hn::Sub(x[2], x[0]), dy2 = hn::Sub(y[2], y[0]);
#if HWY_TARGET == HWY_SCALAR
    // One lane: no pairs to make.
    const int64_t area = int64_t(hn::GetLane(dx1)) * hn::GetLane(dy2) - int64_t(hn::GetLane(dy1)) * hn::GetLane(dx2);
    nonzero = hn::Set(di, area != 0 ? -1 : 0);
    negative = hn::Set(di, area < 0 ? -1 : 0);
#else
    const hn::Repartition<int64_t, DI> dw;
    // The odd lanes moved down into the even ones, which MulEven multiplies.
    const auto odd = [&](V v) { return hn::BitCast(di, hn::ShiftRight<32>(hn::BitCast(dw, v))); };
    const auto even_area = hn::Sub(hn::MulEven(dx1, dy2), hn::MulEven(dy1, dx2));
    const auto odd_area = hn::Sub(hn::MulEven(odd(dx1), odd(dy2)), hn::MulEven(odd(dy1), odd(dx2)));
    const auto zero = hn::Zero(dw);
    // A 64-bit lane of all ones is two 32-bit lanes of all ones: take the even 32-bit lanes
    // from the even areas and the odd ones from the odd areas.
    nonzero = hn::OddEven(hn::BitCast(di, hn::VecFromMask(dw, hn::Ne(odd_area, zero))),
                          hn::BitCast(di, hn::VecFromMask(dw, hn::Ne(even_area, zero))));
    negative = hn::OddEven(hn::BitCast(di, hn::VecFromMask(dw, hn::Lt(odd_area, zero))),
                           hn::BitCast(di, hn::VecFromMask(dw, hn::Lt(even_area, zero))));
#endif
}

uint32_t SetupCandidates(const DepthRasterVertex* vertices, const uint32_t* triangles, const uint8_t* edge_flags,
                         uint32_t begin, uint32_t end, int32_t last_x, int32_t last_y, uint32_t* out) {
    static_assert(sizeof(DepthRasterVertex) == 16, "4 words a vertex: x, y, z, drawn");
    const hn::ScalableTag<int32_t> di;
    const hn::ScalableTag<uint32_t> du;
    const hn::Rebind<uint8_t, decltype(di)> d8;
    const uint32_t n = uint32_t(hn::Lanes(di));
    const int32_t* const words = reinterpret_cast<const int32_t*>(vertices);
    const auto iota = hn::Iota(di, 0);
    const auto zero = hn::Zero(di);
    const auto half = hn::Set(di, int32_t(kHalfPixel)), round_up = hn::Set(di, int32_t(kUnits - 1));
    const auto vlast_x = hn::Set(di, last_x), vlast_y = hn::Set(di, last_y);
    const auto shared_bits = hn::Set(di, 7), back_face_bit = hn::Set(di, int32_t(kEdgeFlagSkipBackFace));
    const auto margin = hn::Set(di, int32_t(kMargin));
    static_assert(kUnits == 256, "snapped units to pixels by a shift of 8");
    HWY_ALIGN uint8_t flag_lanes[hn::MaxLanes(d8)] = {};
    uint32_t count = 0;
    for (uint32_t t0 = begin; t0 < end; t0 += n) {
        const uint32_t lanes = std::min(n, end - t0);
        const auto live = hn::FirstN(di, lanes);
        const auto t = hn::Add(iota, hn::Set(di, int32_t(t0)));
        // Lanes past the end read triangle t0 again (Highway 1.0 has no masked gather).
        const auto corner0 = hn::Mul(hn::IfThenElse(live, t, hn::Set(di, int32_t(t0))), hn::Set(di, 3));
        hn::Vec<decltype(di)> x[3], y[3];
        auto drawn = hn::Set(di, 1);
        for (int c = 0; c < 3; ++c) {
            const auto index =
                hn::GatherIndex(di, reinterpret_cast<const int32_t*>(triangles), hn::Add(corner0, hn::Set(di, c)));
            const auto word = hn::ShiftLeft<2>(index);  // 4 words a vertex
            x[c] = hn::GatherIndex(di, words, word);
            y[c] = hn::GatherIndex(di, words + 1, word);
            drawn = hn::And(drawn, hn::GatherIndex(di, words + 3, word));
        }
        auto flags = zero;
        if (edge_flags) {
            std::copy(edge_flags + t0, edge_flags + t0 + lanes, flag_lanes);
            flags = hn::PromoteTo(di, hn::Load(d8, flag_lanes));
        }
        // SetupTriangles' tests in its order: corners drawn, a non-zero area, not a back face
        // it may skip, a pixel centre in the box, shrunk by the margin when no edge is shared
        // (sharing that the neighbours' test may take away, never add).
        hn::Vec<decltype(di)> nonzero, negative;
        areaSigns(di, x, y, nonzero, negative);
        const auto back_face = hn::And(negative, hn::VecFromMask(di, hn::Ne(hn::And(flags, back_face_bit), zero)));
        const auto pad = hn::IfThenElseZero(hn::Eq(hn::And(flags, shared_bits), zero), margin);
        const auto x_min = hn::Min(x[0], hn::Min(x[1], x[2])), x_max = hn::Max(x[0], hn::Max(x[1], x[2]));
        const auto y_min = hn::Min(y[0], hn::Min(y[1], y[2])), y_max = hn::Max(y[0], hn::Max(y[1], y[2]));
        // SetupTriangles::pixelBox: the first centre at or after the padded minimum (a ceiling,
        // by flooring after adding 255) and the last at or before the padded maximum.
        const auto x_lo = hn::Max(zero, hn::ShiftRight<8>(hn::Add(hn::Sub(hn::Add(x_min, pad), half), round_up)));
        const auto x_hi = hn::Min(vlast_x, hn::ShiftRight<8>(hn::Sub(hn::Sub(x_max, pad), half)));
        const auto y_lo = hn::Max(zero, hn::ShiftRight<8>(hn::Add(hn::Sub(hn::Add(y_min, pad), half), round_up)));
        const auto y_hi = hn::Min(vlast_y, hn::ShiftRight<8>(hn::Sub(hn::Sub(y_max, pad), half)));
        const auto keep = hn::And(hn::And(hn::And(live, hn::Gt(drawn, zero)),
                                          hn::And(hn::Not(hn::Gt(x_lo, x_hi)), hn::Not(hn::Gt(y_lo, y_hi)))),
                                  hn::And(hn::Ne(nonzero, zero), hn::Eq(back_face, zero)));
        count += uint32_t(hn::CompressStore(hn::BitCast(du, t), hn::RebindMask(du, keep), du, out + count));
    }
    return count;
}

uint32_t TransformProject(const OccluderVertexJob& job, const glm::vec3* src, uint32_t count, glm::vec3* world,
                          DepthRasterVertex* out, uint8_t* front, uint32_t& in_front) {
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(df)> di;
    const hn::Rebind<uint8_t, decltype(di)> d8;
    const uint32_t n = uint32_t(hn::Lanes(df));
    const float* const w = job.world;
    const float* const m = job.view_proj;
    const auto zero = hn::Zero(df), half = hn::Set(df, 0.5f), one = hn::Set(df, 1.0f);
    const auto vwidth = hn::Set(df, job.width), vheight = hn::Set(df, job.height);
    const auto units = hn::Set(df, float(kUnits)), guard = hn::Set(df, kDepthRasterGuardBand);
    const auto max_depth = hn::Set(df, kDepthRasterMaxDepth);
    uint32_t done = 0, ahead = 0;
    for (; done + n <= count; done += n) {
        hn::Vec<decltype(df)> x, y, z;
        hn::LoadInterleaved3(df, reinterpret_cast<const float*>(src + done), x, y, z);
        // occluderVertex: glm's m * vec4(p, 1), (m0 x + m1 y) + (m2 z + m3), component by component.
        hn::Vec<decltype(df)> p[3];
        for (int c = 0; c < 3; ++c)
            p[c] = hn::Add(hn::Add(hn::Mul(hn::Set(df, w[c]), x), hn::Mul(hn::Set(df, w[4 + c]), y)),
                           hn::Add(hn::Mul(hn::Set(df, w[8 + c]), z), hn::Set(df, w[12 + c])));
        hn::StoreInterleaved3(p[0], p[1], p[2], df, reinterpret_cast<float*>(world + done));
        // inFrontOfNearPlane: ((r.x x + r.y y) + r.z z) + r.w > 0.
        const auto near = hn::Add(hn::Add(hn::Add(hn::Mul(hn::Set(df, job.near_row[0]), p[0]),
                                                  hn::Mul(hn::Set(df, job.near_row[1]), p[1])),
                                          hn::Mul(hn::Set(df, job.near_row[2]), p[2])),
                                  hn::Set(df, job.near_row[3]));
        const auto in = hn::Gt(near, zero);
        ahead += uint32_t(hn::CountTrue(df, in));
        hn::StoreU(hn::DemoteTo(d8, hn::IfThenElseZero(hn::RebindMask(di, in), hn::Set(di, 1))), d8, front + done);
        // ProjectVertices, in its float operations.
        hn::Vec<decltype(df)> clip[4];
        for (int r = 0; r < 4; ++r)
            clip[r] = hn::Add(hn::Add(hn::Add(hn::Mul(hn::Set(df, m[r]), p[0]), hn::Mul(hn::Set(df, m[4 + r]), p[1])),
                                      hn::Mul(hn::Set(df, m[8 + r]), p[2])),
                              hn::Set(df, m[12 + r]));
        const auto visible = hn::And(hn::Gt(clip[3], zero), hn::Ge(clip[2], hn::Neg(clip[3])));
        const auto inv_w = hn::Div(one, clip[3]);
        const auto wx = hn::Mul(hn::Add(hn::Mul(hn::Mul(clip[0], inv_w), half), half), vwidth);
        const auto wy = hn::Mul(hn::Add(hn::Mul(hn::Mul(clip[1], inv_w), half), half), vheight);
        const auto wz = hn::Add(hn::Mul(hn::Mul(clip[2], inv_w), half), half);
        const auto drawn = hn::And(visible, hn::And(hn::And(hn::Le(hn::Abs(wx), guard), hn::Le(hn::Abs(wy), guard)),
                                                    hn::Le(wz, max_depth)));
        const auto sx = hn::ConvertTo(di, hn::IfThenElseZero(drawn, hn::Floor(hn::Add(hn::Mul(wx, units), half))));
        const auto sy = hn::ConvertTo(di, hn::IfThenElseZero(drawn, hn::Floor(hn::Add(hn::Mul(wy, units), half))));
        const auto bits_z = hn::BitCast(di, hn::IfThenElseZero(visible, wz));
        const auto flag = hn::IfThenElseZero(hn::RebindMask(di, drawn), hn::Set(di, 1));
        hn::StoreInterleaved4(sx, sy, bits_z, flag, di, reinterpret_cast<int32_t*>(out + done));
    }
    in_front = ahead;
    return done;
}

void RasterTile(const DepthTiles& job, uint32_t tile) {
    const TileBins& bins = job.bins;
    const uint32_t px0 = tile % bins.tiles_x * kTile, py0 = tile / bins.tiles_x * kTile;
    const uint32_t px1 = std::min(px0 + kTile, job.width), py1 = std::min(py0 + kTile, job.height);
    HWY_ALIGN float nearest[kTile * kTile];
    std::fill(nearest, nearest + kTile * kTile, kFar);
    const auto iota = hn::Iota(hn::ScalableTag<int32_t>(), 0);
    const auto jota = hn::Iota(hn::ScalableTag<double>(), 0.0);

    const uint64_t begin = bins.tileBegin(tile), end = bins.tileEnd(tile);
    for (uint64_t i = begin; i < end; ++i) {
        if (i + kPrefetchDistance < end) prefetch(&job.setup[bins.pair_triangle[i + kPrefetchDistance]]);
        const DepthRasterTriangle& s = job.setup[bins.pair_triangle[i]];
        const uint32_t x_lo = std::max<uint32_t>(s.x_lo, px0), x_hi = std::min<uint32_t>(s.x_hi, px1 - 1);
        const uint32_t y_lo = std::max<uint32_t>(s.y_lo, py0), y_hi = std::min<uint32_t>(s.y_hi, py1 - 1);
        if (x_lo > x_hi || y_lo > y_hi) continue;
        // The edge functions of RasterTiles.
        const EdgeFunctions e(s);
        if (!e.mayCover(x_lo, x_hi, y_lo, y_hi)) continue;
        if (hidden(nearest, s.lower_bound, x_lo - px0, x_hi - px0, y_lo - py0, y_hi - py0, iota)) continue;
        // From the centre of pixel (x_lo, y_lo).
        EdgeRows edges[3];
        for (int k = 0; k < 3; ++k) edges[k].start(e.inside(k, x_lo, y_lo), -e.ey[k] * kUnits, e.ex[k] * kUnits);
        const int64_t columns = int64_t(x_hi - x_lo) + 1;
        const int32_t column_base = int32_t(px0 - s.x_lo);
        for (uint32_t rows = candidateRows(edges, y_hi - y_lo + 1, columns, jota); rows != 0; rows &= rows - 1) {
            const uint32_t j = uint32_t(__builtin_ctz(rows));
            int64_t first = 0, last = columns - 1;
            for (const EdgeRows& edge : edges)
                if (edge.sx != 0) edge.narrow(j, columns, first, last);
            if (first > last) continue;
            const uint32_t y = y_lo + j;
            const float row_depth = addRn(s.z_ref, mulRn(s.gy, float(int32_t(y - s.y_lo))));
            fillSpan(nearest + (y - py0) * kTile, uint32_t(x_lo - px0 + first), uint32_t(x_lo - px0 + last), row_depth,
                     s.gx, column_base, iota);
        }
    }

    for (uint32_t y = py0; y < py1; ++y) {
        const float* row = nearest + (y - py0) * kTile;
        float* out = job.depth + uint64_t(y) * job.width + px0;
        for (uint32_t x = 0; x < px1 - px0; ++x) out[x] = row[x] < 1.0f ? row[x] : 1.0f;
    }
}

}  // namespace occ::k::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace occ::k {

namespace {
using TileFunction = void (*)(const DepthTiles&, uint32_t);
const TileFunction kTiles[kSimdLevels] = {HWY_CHOOSE_AVX3(RasterTile), HWY_CHOOSE_AVX2(RasterTile),
                                          HWY_CHOOSE_SSE4(RasterTile), HWY_CHOOSE_FALLBACK(RasterTile)};
}  // namespace

void depthRasterTilesCpu(const DepthTiles& tiles) {
    const TileFunction raster = pickSimd(kTiles);
    tbb::parallel_for(0u, tiles.bins.tiles_x * tiles.bins.tiles_y, [&](uint32_t t) { raster(tiles, t); });
}

uint32_t setupCandidatesCpu(const DepthRasterVertex* vertices, const uint32_t* triangles, const uint8_t* edge_flags,
                            uint32_t begin, uint32_t end, int32_t last_x, int32_t last_y, uint32_t* out) {
    using CandidateFunction = uint32_t (*)(const DepthRasterVertex*, const uint32_t*, const uint8_t*, uint32_t, uint32_t,
                                           int32_t, int32_t, uint32_t*);
    static const CandidateFunction kCandidates[kSimdLevels] = {
        HWY_CHOOSE_AVX3(SetupCandidates), HWY_CHOOSE_AVX2(SetupCandidates), HWY_CHOOSE_SSE4(SetupCandidates),
        HWY_CHOOSE_FALLBACK(SetupCandidates)};
    return pickSimd(kCandidates)(vertices, triangles, edge_flags, begin, end, last_x, last_y, out);
}

uint32_t transformProjectCpu(const OccluderVertexJob& job, const glm::vec3* src, uint32_t count, glm::vec3* world,
                             DepthRasterVertex* out, uint8_t* front, uint32_t& in_front) {
    using Function = uint32_t (*)(const OccluderVertexJob&, const glm::vec3*, uint32_t, glm::vec3*, DepthRasterVertex*,
                                  uint8_t*, uint32_t&);
    static const Function kFunctions[kSimdLevels] = {
        HWY_CHOOSE_AVX3(TransformProject), HWY_CHOOSE_AVX2(TransformProject), HWY_CHOOSE_SSE4(TransformProject),
        HWY_CHOOSE_FALLBACK(TransformProject)};
    return pickSimd(kFunctions)(job, src, count, world, out, front, in_front);
}

const char* depthRasterCpuTarget() {
    SimdLevel level;
    pickSimd(kTiles, &level);
    return simdLevelName(level);
}

}  // namespace occ::k
#endif
