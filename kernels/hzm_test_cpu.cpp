// SPDX-License-Identifier: MIT
// The CPU's box images for the HZM test (hzm_box_image.h): what hzm_test.cu's boxImage computes
// for one box, here for a vector of boxes at once (16 with AVX-512). The projection of the eight
// corners and their bounds were half of the HZM test's time on the 10^5 plant orbit. Every
// operation is boxImage's, in its order, one IEEE operation each (-ffp-contract=off, as for
// the rasters), so the images are the same bits and the CUDA build's answer is the same.
// Compiled once per instruction set by Highway, the copy picked at run time (simd_level.h).

#include "simd_level_targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "hzm_test_cpu.cpp"
#include <hwy/foreach_target.h>  // re-includes this file once per instruction set

#include <hwy/highway.h>

#include "hzm_box_image.h"

#include <algorithm>

HWY_BEFORE_NAMESPACE();
namespace occ::k::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void BoxImages(const ObjectInfo* objects, const uint32_t* ids, uint32_t count, const float* m, float near_plane,
               float w0, float h0, BoxImage* images, uint8_t* valid, const float* texels, uint32_t level_count,
               const int32_t* level_width, const int32_t* level_offset, uint8_t* settled) {
    static_assert(sizeof(ObjectInfo) % sizeof(float) == 0 && offsetof(ObjectInfo, aabb) == 0,
                  "the box's six floats at the start of each object");
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(df)> di;
    const uint32_t n = uint32_t(hn::Lanes(df));
    const float* const words = reinterpret_cast<const float*>(objects);
    const int32_t stride = int32_t(sizeof(ObjectInfo) / sizeof(float));
    const auto zero = hn::Zero(df), half = hn::Set(df, 0.5f), one = hn::Set(df, 1.0f);
    const auto vw0 = hn::Set(df, w0), vh0 = hn::Set(df, h0), vnear = hn::Set(df, near_plane);
    HWY_ALIGN int32_t lane_ids[hn::MaxLanes(di)] = {};
    HWY_ALIGN int32_t out_x0[hn::MaxLanes(di)], out_x1[hn::MaxLanes(di)], out_y0[hn::MaxLanes(di)],
        out_y1[hn::MaxLanes(di)];
    HWY_ALIGN float out_z[hn::MaxLanes(df)];
    HWY_ALIGN int32_t out_ok[hn::MaxLanes(di)], out_settled[hn::MaxLanes(di)];
    const hn::RebindToUnsigned<decltype(di)> du;
    const auto izero = hn::Zero(di), ione = hn::Set(di, 1), top = hn::Set(di, int32_t(level_count) - 1);
    const auto epsilon = hn::Set(df, kHzmTestEpsilon);
    for (uint32_t j0 = 0; j0 < count; j0 += n) {
        const uint32_t lanes = std::min(n, count - j0);
        // Lanes past the end read the first box of this vector again.
        for (uint32_t i = 0; i < n; ++i) lane_ids[i] = int32_t(ids[j0 + (i < lanes ? i : 0)]);
        const auto word = hn::Mul(hn::Load(di, lane_ids), hn::Set(di, stride));
        hn::Vec<decltype(df)> lo[3], extent[3];
        for (int a = 0; a < 3; ++a) {
            lo[a] = hn::GatherIndex(df, words, hn::Add(word, hn::Set(di, a)));
            extent[a] = hn::Sub(hn::GatherIndex(df, words, hn::Add(word, hn::Set(di, 3 + a))), lo[a]);
        }
        // Row r of view_proj * vec4(min, 1), as glm sums it: (m0 x + m1 y) + (m2 z + m3 * 1);
        // and the images of the box's edges, view_proj[axis] * extent.
        hn::Vec<decltype(df)> base[4], edge[3][4];
        for (int r = 0; r < 4; ++r) {
            const auto col = [&](int c) { return hn::Set(df, m[4 * c + r]); };
            base[r] = hn::Add(hn::Add(hn::Mul(col(0), lo[0]), hn::Mul(col(1), lo[1])),
                              hn::Add(hn::Mul(col(2), lo[2]), hn::Mul(col(3), one)));
            for (int a = 0; a < 3; ++a) edge[a][r] = hn::Mul(col(a), extent[a]);
        }
        auto behind = hn::Lt(zero, zero);  // false
        auto nan = behind;
        hn::Vec<decltype(df)> xmin, xmax, ymin, ymax, zmin;
        for (int c = 0; c < 8; ++c) {
            hn::Vec<decltype(df)> v[4];
            for (int r = 0; r < 4; ++r) {
                v[r] = hn::Add(base[r], c & 1 ? edge[0][r] : zero);
                v[r] = hn::Add(v[r], c & 2 ? edge[1][r] : zero);
                v[r] = hn::Add(v[r], c & 4 ? edge[2][r] : zero);
            }
            behind = hn::Or(behind, hn::Or(hn::Not(hn::Gt(v[3], vnear)), hn::Not(hn::Ge(v[2], hn::Neg(v[3])))));
            const auto inv_w = hn::Div(one, v[3]);
            const auto x = hn::Mul(hn::Add(hn::Mul(hn::Mul(v[0], inv_w), half), half), vw0);
            const auto y = hn::Mul(hn::Add(hn::Mul(hn::Mul(v[1], inv_w), half), half), vh0);
            const auto z = hn::Add(hn::Mul(hn::Mul(v[2], inv_w), half), half);
            nan = hn::Or(nan, hn::Or(hn::Ne(x, x), hn::Or(hn::Ne(y, y), hn::Ne(z, z))));
            // boxImage's running bounds, taking the new corner where it is strictly beyond (the
            // same as Min and Max on the values that get this far: no NaN, no -0).
            if (c == 0) {
                xmin = xmax = x, ymin = ymax = y, zmin = z;
            } else {
                xmin = hn::IfThenElse(hn::Lt(x, xmin), x, xmin);
                xmax = hn::IfThenElse(hn::Gt(x, xmax), x, xmax);
                ymin = hn::IfThenElse(hn::Lt(y, ymin), y, ymin);
                ymax = hn::IfThenElse(hn::Gt(y, ymax), y, ymax);
                zmin = hn::IfThenElse(hn::Lt(z, zmin), z, zmin);
            }
        }
        const auto on_screen = hn::And(hn::And(hn::Ge(xmax, zero), hn::Lt(xmin, vw0)),
                                       hn::And(hn::Ge(ymax, zero), hn::Lt(ymin, vh0)));
        const auto ok = hn::AndNot(hn::Or(behind, nan), on_screen);
        // Clamped in float, then floored: in [0, 32767] where ok.
        const auto x_lo = hn::Floor(hn::IfThenElse(hn::Gt(xmin, zero), xmin, zero));
        const auto x_hi = hn::Floor(hn::IfThenElse(hn::Lt(xmax, hn::Sub(vw0, one)), xmax, hn::Sub(vw0, one)));
        const auto y_lo = hn::Floor(hn::IfThenElse(hn::Gt(ymin, zero), ymin, zero));
        const auto y_hi = hn::Floor(hn::IfThenElse(hn::Lt(ymax, hn::Sub(vh0, one)), ymax, hn::Sub(vh0, one)));
        // Lanes that are not ok may hold anything (NaN, out of range): convert zeros there.
        const auto x0 = hn::ConvertTo(di, hn::IfThenElseZero(ok, x_lo));
        const auto x1 = hn::ConvertTo(di, hn::IfThenElseZero(ok, x_hi));
        const auto y0 = hn::ConvertTo(di, hn::IfThenElseZero(ok, y_lo));
        const auto y1 = hn::ConvertTo(di, hn::IfThenElseZero(ok, y_hi));
        hn::Store(x0, di, out_x0);
        hn::Store(x1, di, out_x1);
        hn::Store(y0, di, out_y0);
        hn::Store(y1, di, out_y1);
        hn::Store(zmin, df, out_z);
        hn::Store(hn::VecFromMask(di, hn::RebindMask(di, ok)), di, out_ok);

        // HzmOcclusion::hidden's start level: ceil(log2(side)) (from the exponent of side - 1 as a
        // float, exact: side <= 32768), one less unless 0, at most the top, then up while the
        // image spans more than 2 texels (once at most, but checked).
        const auto side = hn::Add(hn::Max(hn::Sub(x1, x0), hn::Sub(y1, y0)), ione);
        const auto exponent = hn::Sub(
            hn::BitCast(di, hn::ShiftRight<23>(hn::BitCast(du, hn::ConvertTo(df, hn::Sub(side, ione))))),
            hn::Set(di, 126));
        auto level = hn::IfThenElse(hn::Gt(side, ione), exponent, izero);
        level = hn::IfThenElse(hn::Gt(level, izero), hn::Sub(level, ione), level);
        level = hn::Min(level, top);
        // Whether the image spans more than 2 texels across or down at level l.
        const auto spans = [&](auto l) {
            const auto ul = hn::BitCast(du, l);
            const auto shifted = [&](auto v) { return hn::BitCast(di, hn::BitCast(du, v) >> ul); };
            return hn::Or(hn::Gt(hn::Sub(shifted(x1), shifted(x0)), ione), hn::Gt(hn::Sub(shifted(y1), shifted(y0)), ione));
        };
        for (int step = 0; step < 2; ++step)
            level = hn::IfThenElse(hn::And(hn::Lt(level, top), spans(level)), hn::Add(level, ione), level);
        // Where it still spans more (the top of a pyramid cut short, or a third step needed) the
        // test reads more than these 2x2 texels: not settled here.
        const auto settled_level = hn::Not(spans(level));
        // The (up to) 2x2 texels there; a side of one texel reads it twice.
        const auto ul = hn::BitCast(du, level);
        const auto tx0 = hn::BitCast(di, hn::BitCast(du, x0) >> ul), tx1 = hn::BitCast(di, hn::BitCast(du, x1) >> ul);
        const auto ty0 = hn::BitCast(di, hn::BitCast(du, y0) >> ul), ty1 = hn::BitCast(di, hn::BitCast(du, y1) >> ul);
        const auto row = hn::GatherIndex(di, level_width, level), first = hn::GatherIndex(di, level_offset, level);
        auto hidden = hn::RebindMask(di, ok);
        for (const auto& ty : {ty0, ty1})
            for (const auto& tx : {tx0, tx1}) {
                const auto texel = hn::GatherIndex(df, texels, hn::Add(first, hn::Add(hn::Mul(ty, row), tx)));
                hidden = hn::And(hidden, hn::RebindMask(di, hn::Gt(zmin, hn::Add(texel, epsilon))));
            }
        hn::Store(hn::VecFromMask(di, hn::And(hidden, settled_level)), di, out_settled);
        for (uint32_t i = 0; i < lanes; ++i) {
            valid[j0 + i] = out_ok[i] != 0;
            settled[j0 + i] = out_settled[i] != 0;
            images[j0 + i] = BoxImage{uint32_t(out_x0[i]), uint32_t(out_x1[i]), uint32_t(out_y0[i]), uint32_t(out_y1[i]),
                                      out_z[i]};
        }
    }
}

}  // namespace occ::k::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace occ::k {

void boxImagesCpu(const ObjectInfo* objects, const uint32_t* ids, uint32_t count, const float* view_proj,
                  float near_plane, float w0, float h0, BoxImage* images, uint8_t* valid, const float* texels,
                  uint32_t level_count, const int32_t* level_width, const int32_t* level_offset, uint8_t* settled) {
    using Function = void (*)(const ObjectInfo*, const uint32_t*, uint32_t, const float*, float, float, float, BoxImage*,
                              uint8_t*, const float*, uint32_t, const int32_t*, const int32_t*, uint8_t*);
    static const Function kImages[kSimdLevels] = {HWY_CHOOSE_AVX3(BoxImages), HWY_CHOOSE_AVX2(BoxImages),
                                                  HWY_CHOOSE_SSE4(BoxImages), HWY_CHOOSE_FALLBACK(BoxImages)};
    pickSimd(kImages)(objects, ids, count, view_proj, near_plane, w0, h0, images, valid, texels, level_count, level_width,
                      level_offset, settled);
}

}  // namespace occ::k
#endif
