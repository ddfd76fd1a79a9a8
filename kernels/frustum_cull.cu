// SPDX-License-Identifier: MIT
#include "frustum_cull.h"

#include "device_access.h"
#include "for_each_index.h"
#include "scan.h"
#include "device_policy.h"

#include <thrust/copy.h>
#include <thrust/count.h>
#include <thrust/execution_policy.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/transform.h>

namespace occ::k {

Frustum frustumFromViewProj(const glm::mat4& view_proj) {
    // In double: near + far (or far - near) planes subtract rows that nearly cancel when far/near
    // is large, and float would lose most digits of the result.
    const glm::dmat4 m(view_proj);
    // glm is column-major: m[c][r] is row r, column c.
    const auto row = [&](int r) { return glm::dvec4(m[0][r], m[1][r], m[2][r], m[3][r]); };
    const glm::dvec4 r0 = row(0), r1 = row(1), r2 = row(2), r3 = row(3);
    const glm::dvec4 planes[6] = {r3 + r0, r3 - r0, r3 + r1, r3 - r1, r3 + r2, r3 - r2};
    Frustum f;
    for (int i = 0; i < 6; ++i) {
        const double len = glm::length(glm::dvec3(planes[i]));
        f.planes[i] = glm::vec4(len > 0.0 ? planes[i] / len : planes[i]);
    }
    return f;
}

namespace {

struct PVertexTest {
    Frustum frustum;
    const ObjectInfo* objects;

    OCC_HD uint8_t operator()(uint32_t i) const {
        const Aabb box = objects[i].aabb;
        // All six planes without early exit: whether a box is out is a coin toss for the branch
        // predictor, and six planes cost less than its mispredictions (0.7 ms instead of 1.8 ms
        // for 10^5 boxes on 2 cores).
        bool outside = false;
        for (int k = 0; k < 6; ++k) {
            const glm::vec4 pl = frustum.planes[k];
            // The p-vertex: the corner farthest along the inward normal. If even it is outside,
            // the whole box is.
            const float px = pl.x >= 0.0f ? box.max.x : box.min.x;
            const float py = pl.y >= 0.0f ? box.max.y : box.min.y;
            const float pz = pl.z >= 0.0f ? box.max.z : box.min.z;
            const float tx = pl.x * px, ty = pl.y * py, tz = pl.z * pz;
            const float dist = tx + ty + tz + pl.w;
            // Rounding the plane to floats and this sum cost a few float ulps of the terms; a box
            // that touches the plane must not be lost to them, so allow about ten.
            // NaN compares false and so stays in.
            const float slack = 1e-6f * (fabsf(tx) + fabsf(ty) + fabsf(tz) + fabsf(pl.w));
            outside |= dist < -slack;
        }
        return outside ? 0 : 1;
    }
};

struct PVertexTestIds {
    PVertexTest test;
    const uint32_t* ids;
    uint8_t* in_frustum;

    OCC_HD void operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        in_frustum[id] = test(id);
    }
};

struct FlagOfId {
    const uint8_t* in_frustum;
    OCC_HD bool operator()(uint32_t id) const { return in_frustum[id] != 0; }
};

}  // namespace

uint32_t frustumCullIds(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                        const Frustum& frustum, DevicePtr<uint8_t> in_frustum, DevicePtr<uint32_t> out) {
    if (count == 0) return 0;
    forEachIndex(count, PVertexTestIds{PVertexTest{frustum, raw(objects)}, raw(ids), raw(in_frustum)});
    uint32_t* const end = withPolicy(count, [&](auto policy) {
        return thrust::copy_if(policy, raw(ids), raw(ids) + count, raw(out), FlagOfId{raw(in_frustum)});
    });
    countReadback(sizeof(uint32_t));
    return uint32_t(end - raw(out));
}

uint32_t frustumCull(DevicePtr<const ObjectInfo> objects, uint32_t count, const Frustum& frustum,
                     DevicePtr<uint8_t> in_frustum, DevicePtr<uint32_t> ids) {
    if (count == 0) return 0;
    thrust::transform(onDevice(), thrust::counting_iterator<uint32_t>(0), thrust::counting_iterator<uint32_t>(count),
                      raw(in_frustum), PVertexTest{frustum, raw(objects)});
    if (ids) return compactIndices(in_frustum, count, 1, ids);
    countReadback(sizeof(uint32_t));
    return uint32_t(thrust::count(onDevice(), raw(in_frustum), raw(in_frustum) + count, uint8_t(1)));
}

}  // namespace occ::k
