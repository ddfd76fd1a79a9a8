// SPDX-License-Identifier: MIT
#include "prep/error_calibration.h"

#include "prep/hausdorff.h"
#include "prep/hierarchy.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <span>

namespace occ {

namespace {

// The extent (bounding-box diagonal) of each vertex's connected component (vertices joined by
// triangles); 0 for a vertex no triangle uses.
std::vector<float> componentExtents(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles) {
    const uint32_t n = uint32_t(positions.size());
    std::vector<uint32_t> parent(n);
    std::iota(parent.begin(), parent.end(), 0u);
    const auto find = [&](uint32_t v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    for (size_t i = 0; i + 2 < triangles.size(); i += 3) {
        const uint32_t a = find(triangles[i]), b = find(triangles[i + 1]), c = find(triangles[i + 2]);
        parent[b] = a;
        parent[c == b ? a : c] = a;
    }
    std::vector<glm::vec3> lo(n, glm::vec3(INFINITY)), hi(n, glm::vec3(-INFINITY));
    std::vector<uint8_t> used(n, 0);
    for (uint32_t v : triangles) used[v] = 1;
    for (uint32_t v = 0; v < n; ++v)
        if (used[v]) {
            const uint32_t r = find(v);
            lo[r] = glm::min(lo[r], positions[v]), hi[r] = glm::max(hi[r], positions[v]);
        }
    std::vector<float> extent(n, 0.0f);
    for (uint32_t v = 0; v < n; ++v)
        if (used[v]) {
            const uint32_t r = find(v);
            extent[v] = glm::length(hi[r] - lo[r]);
        }
    return extent;
}

}  // namespace

ErrorCalibration calibrateRecordedErrors(ProgressiveMesh& pm, uint32_t samples) {
    ErrorCalibration result;
    const uint32_t n = pm.vertexCount(), q = std::min(pm.q, n), total = pm.triangleCount();
    if (n <= q || total == 0 || pm.error.size() != n) return result;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : pm.positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const double diagonal = glm::length(glm::dvec3(hi - lo));
    if (!(diagonal > 0.0) || !std::isfinite(diagonal)) return result;
    // Distances below this are float noise of the positions, not simplification.
    const double noise = 1e-6 * diagonal;

    // Level errors before calibration: suffix maxima (level k drops vertices k..n-1).
    std::vector<float> level_error(size_t(n) + 1, 0.0f);
    for (uint32_t v = n; v-- > 0;) level_error[v] = std::max(level_error[v + 1], pm.error[v]);

    // The measured levels, finest first: k_0 = n (exact; it takes the next one's ratio), then
    // each quartering of the triangles.
    std::vector<uint32_t> ks{n};
    std::vector<double> ratio{1.0}, measured{0.0};
    // Both directions from area samples; the full detail's vertices that a level dropped (its
    // own are a prefix of them, at distance 0) at most kVertexSamples of them, evenly strided.
    HausdorffOptions options;
    options.samples = samples;
    options.vertices = false;
    // A sample of the full detail counts at most its connected component's extent: a part that
    // vanishes whole (an HLOD's small objects) changes the picture only within its own extent,
    // however far the nearest surface left is (the rule that leaves out objects under a pixel).
    const std::vector<float> extent = componentExtents(pm.positions, pm.triangles);
    std::vector<float> triangle_cap(pm.triangles.size() / 3);
    for (size_t t = 0; t < triangle_cap.size(); ++t) triangle_cap[t] = extent[pm.triangles[3 * t]];
    const SampledSurface full(pm.positions, pm.triangles, options, triangle_cap);
    constexpr uint32_t kVertexSamples = 128;
    std::vector<glm::vec3> level_positions, dropped;
    std::vector<float> dropped_cap;
    std::vector<uint32_t> level_triangles;
    for (uint64_t want = total / 4;; want /= 4) {
        const uint32_t k = want == 0 ? q : std::max(q, levelWithTriangles(pm.map, q, want));
        if (k < ks.back()) {
            level_positions.clear();
            level_triangles.clear();
            appendLevel(pm.positions, pm.ecol, pm.triangles, pm.map, k, glm::mat4(1.0f), level_positions,
                        level_triangles);
            const SampledSurface level(level_positions, level_triangles, options);
            dropped.clear();
            dropped_cap.clear();
            const uint32_t stride = std::max(1u, (n - k + kVertexSamples - 1) / kVertexSamples);
            for (uint32_t v = k; v < n; v += stride) dropped.push_back(pm.positions[v]), dropped_cap.push_back(extent[v]);
            const double d = std::max(full.maxDistanceTo(level), level.farthestFrom(dropped, dropped_cap));
            const double h = std::isfinite(d) ? std::min(d, diagonal) : diagonal;
            const double e = level_error[k];
            ks.push_back(k);
            measured.push_back(h);
            ratio.push_back(h <= noise ? 1.0 : e > 0.0 ? std::max(1.0, h / e) : 1.0);
            ++result.levels_measured;
        }
        if (k <= q || want == 0) break;
    }
    if (ks.size() < 2) return result;
    ratio[0] = ratio[1];

    // Segment i holds the vertices removed between the measured levels ks[i] and ks[i+1]: v in
    // [ks[i+1], ks[i]) (below the last, v < q, nothing is removed). Within a segment the factor
    // goes geometrically from the finer end's ratio to the coarser end's.
    for (size_t i = 0; i + 1 < ks.size(); ++i) {
        const double fine = std::log(ratio[i]), coarse = std::log(ratio[i + 1]);
        const double span = double(ks[i] - ks[i + 1]);
        result.largest_factor = std::max(result.largest_factor, float(std::max(ratio[i], ratio[i + 1])));
        for (uint32_t v = ks[i + 1]; v < ks[i]; ++v) {
            const double t = double(ks[i] - v) / span;  // 0 at the fine end, 1 at the coarse one
            pm.error[v] *= float(std::exp(fine + (coarse - fine) * t));
        }
    }
    for (size_t i = 1; i < ks.size(); ++i)
        if (ks[i] < n && measured[i] > noise) pm.error[ks[i]] = std::max(pm.error[ks[i]], float(measured[i]));
    return result;
}

}  // namespace occ
