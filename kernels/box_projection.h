// SPDX-License-Identifier: MIT
#pragma once

#include "host_device.h"
#include "kernel_types.h"

#include <cmath>

namespace occ::k {

// What the LOD rules need of a box and of a mesh's errors, on the device and on the host.

// Pixels of the bounding rectangle of an object's projected AABB, clamped to the viewport, and
// its nearest view depth (at least near_plane); an AABB with a corner nearer than the near
// plane gets the whole viewport and depth near_plane.
struct Projection {
    float area, depth;
};

OCC_HD inline Projection projectBox(const ObjectInfo& o, const Camera& camera) {
    const float width = float(camera.width), height = float(camera.height);
    // Clip position and view depth are affine in the corner, so the eight corners are sums
    // of one term per axis: 6 column products instead of 8 matrix products.
    const glm::mat4& m = camera.view_proj;
    const glm::vec3 lo = o.aabb.min - camera.eye, hi = o.aabb.max - camera.eye;
    const glm::vec4 cx[2] = {m[0] * o.aabb.min.x, m[0] * o.aabb.max.x};
    const glm::vec4 cy[2] = {m[1] * o.aabb.min.y, m[1] * o.aabb.max.y};
    const glm::vec4 cz[2] = {m[2] * o.aabb.min.z + m[3], m[2] * o.aabb.max.z + m[3]};
    const float dx[2] = {lo.x * camera.forward.x, hi.x * camera.forward.x};
    const float dy[2] = {lo.y * camera.forward.y, hi.y * camera.forward.y};
    const float dz[2] = {lo.z * camera.forward.z, hi.z * camera.forward.z};
    float area = width * height, depth = camera.near_plane;
    bool crosses_near = false;
    float x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY, nearest = INFINITY;
    for (int c = 0; c < 8; ++c) {
        const int ix = c & 1, iy = (c >> 1) & 1, iz = c >> 2;
        const float d = dx[ix] + dy[iy] + dz[iz];
        const glm::vec4 clip = cx[ix] + cy[iy] + cz[iz];
        // A corner behind the near plane has no meaningful projection (w may be <= 0).
        if (d < camera.near_plane || clip.w <= 0.0f) {
            crosses_near = true;
            break;
        }
        nearest = glm::min(nearest, d);
        const float x = (clip.x / clip.w * 0.5f + 0.5f) * width;
        const float y = (clip.y / clip.w * 0.5f + 0.5f) * height;
        x0 = glm::min(x0, x), x1 = glm::max(x1, x);
        y0 = glm::min(y0, y), y1 = glm::max(y1, y);
    }
    if (!crosses_near) {
        x0 = fmaxf(x0, 0.0f), y0 = fmaxf(y0, 0.0f);
        x1 = fminf(x1, width), y1 = fminf(y1, height);
        area = fmaxf(x1 - x0, 0.0f) * fmaxf(y1 - y0, 0.0f);
        depth = fmaxf(nearest, camera.near_plane);
    }
    return {area, depth};
}

// The error-bounded level of a mesh: e holds its vertex_count + 1 non-increasing suffix maxima
// of the collapse errors (e[vertex_count] = 0); the smallest k in [min(q, vertex_count),
// vertex_count] with e[k] <= allowed (vertex_count when allowed < 0).
OCC_HD inline uint32_t levelWithinError(const float* e, uint32_t q, uint32_t vertex_count, float allowed) {
    uint32_t lo = q < vertex_count ? q : vertex_count, hi = vertex_count;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (e[mid] <= allowed) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

// levelWithinError(e, q, vertex_count, allowed), searched outwards from `hint` (any value; the
// answer does not depend on it): where the answer lies near the hint, as a level does from one
// frame to the next, it costs a probe or two in one cache line instead of log2(vertex_count)
// probes across the mesh's errors, each a likely cache miss.
OCC_HD inline uint32_t levelWithinErrorNear(const float* e, uint32_t q, uint32_t vertex_count, float allowed,
                                            uint32_t hint) {
    const uint32_t first = q < vertex_count ? q : vertex_count;
    if (hint < first || hint > vertex_count) return levelWithinError(e, first, vertex_count, allowed);
    // The answer is the smallest k >= first with e[k] <= allowed (e does not grow with k).
    if (e[hint] <= allowed) {
        // At or below the hint: gallop down while the level below is within too.
        uint32_t hi = hint, step = 1;
        while (hi > first) {
            const uint32_t probe = hi - first > step ? hi - step : first;
            if (e[probe] > allowed) return levelWithinError(e, probe + 1, hi, allowed);
            hi = probe;
            step *= 2;
        }
        return first;
    }
    // Above the hint: gallop up to the first level within (vertex_count always is, or is the
    // answer when nothing is).
    uint32_t lo = hint + 1, step = 1;
    while (lo < vertex_count) {
        const uint32_t probe = vertex_count - lo > step ? lo + step : vertex_count;
        if (e[probe] <= allowed) return levelWithinError(e, lo, probe, allowed);
        lo = probe + 1;
        step *= 2;
    }
    return vertex_count;
}

// The level a raise to k vertices (of vertex_count) lands on when raised levels step in
// fractions `step` (0: k itself): the grid vertex_count, v - floor(v * step) (at least 1 less),
// ... down to k; the smallest grid level at or above k. A level raised to a bound that moves
// with the camera then changes only where the bound crosses a grid level, not at every vertex,
// and no frame's choice depends on another's.
OCC_HD inline uint32_t levelOnRaiseGrid(uint32_t k, uint32_t vertex_count, float step) {
    if (!(step > 0.0f) || k == 0 || k >= vertex_count) return k;
    uint32_t v = vertex_count;
    while (true) {
        const uint32_t down = float(v) * step >= 1.0f ? uint32_t(float(v) * step) : 1u;
        if (v - k < down) return v;
        v -= down;
    }
}

}  // namespace occ::k
