// SPDX-License-Identifier: MIT
#include "hzm_test.h"

#include "device_access.h"
#include "hzm_box_image.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/transform.h>

#include <glm/matrix.hpp>

#include <cfloat>

#if !defined(__CUDACC__)
#include <tbb/parallel_for.h>

#include <algorithm>
#endif

namespace occ::k {

namespace {

// A box's image as both tests read it (BoxImage). False when no texel can say anything about the
// box: a corner on or behind the near plane, a non-finite corner, or a rectangle entirely outside
// the viewport. The CPU build's hzmTest computes the same bits a vector of boxes at a time
// (boxImagesCpu); keep the two in step.
OCC_HD inline bool boxImage(const Aabb& box, const glm::mat4& view_proj, float near_plane, float w0, float h0,
                            BoxImage& image) {
    // The projection is linear, so corner c is the min corner's image plus the images of the
    // box edges selected by its bits: 3 adds per coordinate instead of a matrix product. The
    // corners go into arrays, coordinate by coordinate, and every test and bound is taken over
    // all eight without an early exit, so that the compiler can do the eight at once (the
    // answer is the same as stopping at the first corner that fails).
    const glm::vec4 base = view_proj * glm::vec4(box.min, 1.0f);
    const glm::vec4 ex = view_proj[0] * (box.max.x - box.min.x);
    const glm::vec4 ey = view_proj[1] * (box.max.y - box.min.y);
    const glm::vec4 ez = view_proj[2] * (box.max.z - box.min.z);
    float cx[8], cy[8], cz[8], cw[8];
    for (int c = 0; c < 8; ++c) {
        cx[c] = base.x + (c & 1 ? ex.x : 0.0f) + (c & 2 ? ey.x : 0.0f) + (c & 4 ? ez.x : 0.0f);
        cy[c] = base.y + (c & 1 ? ex.y : 0.0f) + (c & 2 ? ey.y : 0.0f) + (c & 4 ? ez.y : 0.0f);
        cz[c] = base.z + (c & 1 ? ex.z : 0.0f) + (c & 2 ? ey.z : 0.0f) + (c & 4 ? ez.z : 0.0f);
        cw[c] = base.w + (c & 1 ? ex.w : 0.0f) + (c & 2 ? ey.w : 0.0f) + (c & 4 ? ez.w : 0.0f);
    }
    // Written so that NaN (from a NaN or infinite corner) lands on the visible side.
    int behind = 0;
    for (int c = 0; c < 8; ++c) behind |= !(cw[c] > near_plane) | !(cz[c] >= -cw[c]);
    if (behind) return false;
    float x[8], y[8], z[8];
    int nan = 0;
    for (int c = 0; c < 8; ++c) {
        const float inv_w = 1.0f / cw[c];
        x[c] = (cx[c] * inv_w * 0.5f + 0.5f) * w0;
        y[c] = (cy[c] * inv_w * 0.5f + 0.5f) * h0;
        z[c] = cz[c] * inv_w * 0.5f + 0.5f;
        // An infinite coordinate can still give a NaN here.
        nan |= (x[c] != x[c]) | (y[c] != y[c]) | (z[c] != z[c]);
    }
    if (nan) return false;
    // Plain comparisons: g++ calls libm for fminf/fmaxf, which took a fifth of the time.
    float xmin = x[0], xmax = x[0], ymin = y[0], ymax = y[0], z_min = z[0];
    for (int c = 1; c < 8; ++c) {
        xmin = x[c] < xmin ? x[c] : xmin;
        xmax = x[c] > xmax ? x[c] : xmax;
        ymin = y[c] < ymin ? y[c] : ymin;
        ymax = y[c] > ymax ? y[c] : ymax;
        z_min = z[c] < z_min ? z[c] : z_min;
    }
    if (!(xmax >= 0.0f && xmin < w0 && ymax >= 0.0f && ymin < h0)) return false;
    // Clamp in float before converting: the bounds may be far outside the int range.
    image.x0 = uint32_t(floorf(xmin > 0.0f ? xmin : 0.0f));
    image.x1 = uint32_t(floorf(xmax < w0 - 1.0f ? xmax : w0 - 1.0f));
    image.y0 = uint32_t(floorf(ymin > 0.0f ? ymin : 0.0f));
    image.y1 = uint32_t(floorf(ymax < h0 - 1.0f ? ymax : h0 - 1.0f));
    image.z_min = z_min;
    return true;
}

struct HzmOcclusion {
    const ObjectInfo* objects;
    const uint32_t* ids;
    glm::mat4 view_proj;
    float near_plane;
    HzmLevels hzm;
    const float* texels;  // hzm.data

    OCC_HD uint8_t operator()(uint32_t j) const {
        if (hzm.level_count == 0) return 0;
        const float w0 = float(hzm.width[0]), h0 = float(hzm.height[0]);
        BoxImage image;
        if (!boxImage(objects[ids[j]].aabb, view_proj, near_plane, w0, h0, image)) return 0;
        return hidden(image);
    }

    // Whether the pyramid hides the box whose image this is.
    OCC_HD uint8_t hidden(const BoxImage& image) const {
        const uint32_t x0 = image.x0, x1 = image.x1, y0 = image.y0, y1 = image.y1;
        const float z_min = image.z_min;

        // n pixels span at most 2 texels from level ceil(log2(n)) on, and at least 3 below level
        // ceil(log2(n)) - 1, so the finest level with at most 2x2 texels is one of those two.
        const uint32_t side = (x1 - x0 > y1 - y0 ? x1 - x0 : y1 - y0) + 1;
        uint32_t level = 0;
        while (level < 31 && (1u << level) < side) ++level;
        if (level > 0) --level;
        if (level > hzm.level_count - 1) level = hzm.level_count - 1;
        while (level + 1 < hzm.level_count && ((x1 >> level) - (x0 >> level) > 1 || (y1 >> level) - (y0 >> level) > 1))
            ++level;

        // Every texel of the rectangle at `level` that does not prove the box hidden is opened
        // into its (up to) 2x2 children inside the rectangle, down to level 0, where one such
        // pixel proves the box visible. So the answer is the per-pixel test over the whole
        // rectangle, and the pyramid only decides how little of it is read: a box whose coarse
        // texels already prove it hidden reads at most 4 of them (the test of Peng & Cao 2013);
        // beyond the paper, a box the coarse texels cannot prove hidden is not given up as
        // visible but looked at more closely. Depth-first with an explicit stack: each step down
        // pops one texel and pushes at most 4, so it never holds more than 4 + 3 per level.
        // (More than 2x2 texels at `level` remain only at the top of a pyramid cut short, a side
        // over kHzmMaxSide; they are all pushed, and the stack is sized for that too.)
        // A texel pushed is at level >= 1 of a pyramid at most 32768 pixels across: its x and y
        // fit in 14 bits each and its level in 4, one word (a small stack frame on a GPU).
        struct Texel {
            uint32_t bits;
            Texel() = default;
            OCC_HD Texel(uint32_t l, uint32_t x, uint32_t y) : bits(l << 28 | x << 14 | y) {}
            OCC_HD uint32_t level() const { return bits >> 28; }
            OCC_HD uint32_t x() const { return bits >> 14 & 0x3fffu; }
            OCC_HD uint32_t y() const { return bits & 0x3fffu; }
        };
        static_assert(kHzmMaxSide <= 2u << 14 && kHzmMaxLevels <= 16, "a pushed texel must fit one word");
        constexpr uint32_t kStack = 4 + 3 * kHzmMaxLevels + 64;
        Texel stack[kStack];
        uint32_t top = 0;
        const auto settles = [&](uint32_t l, uint32_t x, uint32_t y) {
            return z_min > texels[hzm.offset[l] + uint64_t(y) * hzm.width[l] + x] + kHzmTestEpsilon;
        };
        for (uint32_t ty = y0 >> level; ty <= y1 >> level; ++ty)
            for (uint32_t tx = x0 >> level; tx <= x1 >> level; ++tx)
                if (!settles(level, tx, ty)) {
                    if (level == 0 || top == kStack) return 0;
                    stack[top++] = Texel(level, tx, ty);
                }
        while (top > 0) {
            const Texel t = stack[--top];
            const uint32_t l = t.level() - 1, tx = t.x(), ty = t.y();
            // Children of t at level l, clipped to the rectangle's texels there (which also
            // keeps them inside the level: the rectangle is inside the viewport).
            const uint32_t cx0 = 2 * tx > (x0 >> l) ? 2 * tx : (x0 >> l);
            const uint32_t cx1 = 2 * tx + 1 < (x1 >> l) ? 2 * tx + 1 : (x1 >> l);
            const uint32_t cy0 = 2 * ty > (y0 >> l) ? 2 * ty : (y0 >> l);
            const uint32_t cy1 = 2 * ty + 1 < (y1 >> l) ? 2 * ty + 1 : (y1 >> l);
            for (uint32_t cy = cy0; cy <= cy1; ++cy)
                for (uint32_t cx = cx0; cx <= cx1; ++cx)
                    if (!settles(l, cx, cy)) {
                        if (l == 0 || top == kStack) return 0;
                        stack[top++] = Texel(l, cx, cy);
                    }
        }
        return 1;
    }
};

// The share of a box's image that the occluders leave visible, as an occlusion query of the
// box would count it (Charalambos 2006's q / alpha): at the finest level where the box's
// rectangle spans at most 8 x 8 texels, a ray through the middle of each texel's part of the
// rectangle is cut with the box; where it enters the box (the box's front faces there) is
// compared with the texel's farthest depth. share = the pixels whose ray enters the box in
// front of the texel, over the pixels whose ray enters the box at all. The rectangle's corners
// the box leaves empty and the far parts of a box whose near corner pokes out in front of an
// occluder no longer count as visible (the nearest-corner rule below counted every such texel).
// A box no ray meets (smaller than the texels' spacing) falls back to that rule: the pixels under
// texels whose depth does not hide the box's nearest point. 1 for a box that crosses the near
// plane or that no depth map covers.
struct VisibleShare {
    const ObjectInfo* objects;
    const uint32_t* ids;
    glm::mat4 view_proj;
    float near_plane;
    HzmLevels hzm;
    const float* texels;
    // The rays start at the eye; the direction through NDC (nx, ny) is ray_x nx + ray_y ny +
    // ray_0 (up to a positive factor, which does not move where a ray enters a box).
    glm::vec3 eye, ray_x, ray_y, ray_0;

    // Where the ray through window pixel (px, py) enters `box`: its window depth, or false when
    // it misses the box.
    OCC_HD bool entryDepth(const Aabb& box, float px, float py, float w0, float h0, float& depth) const {
        const glm::vec3 dir = ray_x * (2.0f * px / w0 - 1.0f) + ray_y * (2.0f * py / h0 - 1.0f) + ray_0;
        float t0 = 0.0f, t1 = FLT_MAX;
        for (int axis = 0; axis < 3; ++axis) {
            const float o = eye[axis], d = dir[axis];
            if (d == 0.0f) {
                if (o < box.min[axis] || o > box.max[axis]) return false;
                continue;
            }
            float ta = (box.min[axis] - o) / d, tb = (box.max[axis] - o) / d;
            if (ta > tb) {
                const float t = ta;
                ta = tb;
                tb = t;
            }
            t0 = ta > t0 ? ta : t0;
            t1 = tb < t1 ? tb : t1;
            if (!(t0 <= t1)) return false;  // also a NaN
        }
        const glm::vec4 clip = view_proj * glm::vec4(eye + t0 * dir, 1.0f);
        depth = clip.z / clip.w * 0.5f + 0.5f;
        return depth == depth;
    }

    OCC_HD float operator()(uint32_t j) const {
        if (hzm.level_count == 0) return 1.0f;
        const float w0 = float(hzm.width[0]), h0 = float(hzm.height[0]);
        const Aabb& box = objects[ids[j]].aabb;
        BoxImage image;
        if (!boxImage(box, view_proj, near_plane, w0, h0, image)) return 1.0f;
        const uint32_t x0 = image.x0, x1 = image.x1, y0 = image.y0, y1 = image.y1;
        const float z_min = image.z_min;
        uint32_t level = 0;
        while (level + 1 < hzm.level_count && ((x1 >> level) - (x0 >> level) > 7 || (y1 >> level) - (y0 >> level) > 7))
            ++level;
        double hit = 0, hit_open = 0, open = 0;
        for (uint32_t ty = y0 >> level; ty <= y1 >> level; ++ty)
            for (uint32_t tx = x0 >> level; tx <= x1 >> level; ++tx) {
                const float texel = texels[hzm.offset[level] + uint64_t(ty) * hzm.width[level] + tx];
                // The texel's pixels inside the rectangle.
                const uint32_t px0 = (tx << level) > x0 ? (tx << level) : x0;
                const uint32_t px1 = ((tx + 1) << level) - 1 < x1 ? ((tx + 1) << level) - 1 : x1;
                const uint32_t py0 = (ty << level) > y0 ? (ty << level) : y0;
                const uint32_t py1 = ((ty + 1) << level) - 1 < y1 ? ((ty + 1) << level) - 1 : y1;
                const double pixels = double(px1 - px0 + 1) * double(py1 - py0 + 1);
                if (!(z_min > texel + kHzmTestEpsilon)) open += pixels;
                float depth;
                if (!entryDepth(box, 0.5f * float(px0 + px1 + 1), 0.5f * float(py0 + py1 + 1), w0, h0, depth)) continue;
                hit += pixels;
                if (!(depth > texel + kHzmTestEpsilon)) hit_open += pixels;
            }
        if (hit > 0) return float(hit_open / hit);
        const double all = double(x1 - x0 + 1) * double(y1 - y0 + 1);
        return float(open / all);
    }
};

}  // namespace

void hzmVisibleShare(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                     const Camera& camera, const HzmLevels& hzm, DevicePtr<float> share) {
    if (count == 0) return;
    // A far-plane point in homogeneous world coordinates is linear in NDC x and y:
    // inverse(view_proj) x (nx, ny, 1, 1). Its direction from the eye, times its w (> 0), is too.
    const glm::mat4 inverse = glm::inverse(camera.view_proj);
    const auto fromEye = [&](const glm::vec4& v) { return glm::vec3(v) - camera.eye * v.w; };
    thrust::transform(onDevice(), thrust::counting_iterator<uint32_t>(0), thrust::counting_iterator<uint32_t>(count),
                      raw(share),
                      VisibleShare{raw(objects), raw(ids), camera.view_proj, camera.near_plane, hzm, raw(hzm.data),
                                   camera.eye, fromEye(inverse[0]), fromEye(inverse[1]),
                                   fromEye(inverse[2] + inverse[3])});
}

void hzmTestScalar(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                   const Camera& camera, const HzmLevels& hzm, DevicePtr<uint8_t> occluded) {
    if (count == 0) return;
    thrust::transform(onDevice(), thrust::counting_iterator<uint32_t>(0), thrust::counting_iterator<uint32_t>(count),
                      raw(occluded),
                      HzmOcclusion{raw(objects), raw(ids), camera.view_proj, camera.near_plane, hzm, raw(hzm.data)});
}

void hzmTest(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count, const Camera& camera,
             const HzmLevels& hzm, DevicePtr<uint8_t> occluded) {
#if defined(__CUDACC__)
    hzmTestScalar(objects, ids, count, camera, hzm, occluded);
#else
    if (count == 0) return;
    if (hzm.level_count == 0) {
        std::fill(raw(occluded), raw(occluded) + count, uint8_t(0));
        return;
    }
    // Blocks of boxes in parallel, each block's images and first texels a SIMD vector of boxes at
    // a time. The levels' sizes fit 32 bits: at most 4/3 of 32768^2 texels in all.
    const HzmOcclusion test{raw(objects), raw(ids), camera.view_proj, camera.near_plane, hzm, raw(hzm.data)};
    float m[16];
    for (int i = 0; i < 16; ++i) m[i] = camera.view_proj[i / 4][i % 4];
    int32_t level_width[kHzmMaxLevels], level_offset[kHzmMaxLevels];
    for (uint32_t l = 0; l < hzm.level_count; ++l) level_width[l] = int32_t(hzm.width[l]), level_offset[l] = int32_t(hzm.offset[l]);
    constexpr uint32_t kBlock = 1024;
    tbb::parallel_for(0u, (count + kBlock - 1) / kBlock, [&](uint32_t block) {
        const uint32_t begin = block * kBlock, n = std::min(count - begin, kBlock);
        BoxImage images[kBlock];
        uint8_t valid[kBlock], settled[kBlock];
        boxImagesCpu(raw(objects), raw(ids) + begin, n, m, camera.near_plane, float(hzm.width[0]),
                     float(hzm.height[0]), images, valid, raw(hzm.data), hzm.level_count, level_width, level_offset,
                     settled);
        // Most boxes are settled by their first texels, the rest go down the pyramid one by one.
        uint8_t* const out = raw(occluded) + begin;
        for (uint32_t i = 0; i < n; ++i) out[i] = !valid[i] ? 0 : settled[i] ? 1 : test.hidden(images[i]);
    });
#endif
}

}  // namespace occ::k
