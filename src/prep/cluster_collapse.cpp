// SPDX-License-Identifier: MIT
#include "prep/cluster_collapse.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace occ {

CollapseSequence clusterAfterCollapses(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                       CollapseSequence sequence, const ClusterOptions& options) {
    if (!(options.first_cell > 0.0f && options.first_cell <= options.last_cell))
        throw std::invalid_argument("clusterAfterCollapses: need 0 < first_cell <= last_cell");
    const uint32_t n = uint32_t(positions.size());
    const uint32_t tc = uint32_t(triangles.size() / 3);
    if (n == 0 || tc == 0) return sequence;

    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const float extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    if (!(extent > 0.0f) || !std::isfinite(extent)) return sequence;
    const float first_cell = extent * options.first_cell;

    // The edge collapses up to the first one that moves more than the first grid would.
    size_t keep = 0;
    const float limit = first_cell * std::sqrt(3.0f);
    while (keep < sequence.size() && sequence.error[keep] <= limit) ++keep;
    sequence.removed.resize(keep);
    sequence.kept.resize(keep);
    sequence.error.resize(keep);
    sequence.triangle_offsets.resize(keep + 1);
    sequence.triangles.resize(sequence.triangle_offsets[keep]);

    // The state the collapses leave: each vertex's survivor, the triangles alive and their corners.
    std::vector<uint32_t> survivor(n);
    std::iota(survivor.begin(), survivor.end(), 0u);
    std::vector<uint8_t> alive(n, 1), dead(tc, 0);
    for (size_t i = 0; i < keep; ++i) {
        survivor[sequence.removed[i]] = sequence.kept[i];
        alive[sequence.removed[i]] = 0;
    }
    for (uint32_t t : sequence.triangles) dead[t] = 1;
    const auto find = [&](uint32_t v) {
        uint32_t r = v;
        while (survivor[r] != r) r = survivor[r];
        while (survivor[v] != r) {
            const uint32_t next = survivor[v];
            survivor[v] = r;
            v = next;
        }
        return r;
    };
    std::vector<uint32_t> corners(triangles.size());
    std::vector<std::vector<uint32_t>> incident(n);
    for (uint32_t t = 0; t < tc; ++t) {
        if (dead[t]) continue;
        for (int c = 0; c < 3; ++c) {
            corners[3 * t + c] = find(triangles[3 * t + c]);
            incident[corners[3 * t + c]].push_back(t);
        }
    }

    std::vector<float> radius(n, 0.0f);
    std::vector<uint32_t> members, order, died;
    std::vector<std::pair<uint64_t, uint32_t>> keyed;
    const float last_cell = extent * options.last_cell * 1.0001f;
    for (float cell = first_cell; cell <= last_cell; cell *= 2.0f) {
        keyed.clear();
        for (uint32_t v = 0; v < n; ++v) {
            if (!alive[v]) continue;
            const glm::vec3 g = glm::floor((positions[v] - lo) / cell);
            const uint64_t key = (uint64_t(uint32_t(g.x)) << 42) | (uint64_t(uint32_t(g.y)) << 21) | uint64_t(uint32_t(g.z));
            keyed.push_back({key, v});
        }
        if (keyed.size() <= 1) break;
        std::sort(keyed.begin(), keyed.end());
        for (size_t b = 0; b < keyed.size();) {
            size_t e = b + 1;
            while (e < keyed.size() && keyed[e].first == keyed[b].first) ++e;
            if (e - b > 1) {
                members.clear();
                glm::dvec3 centre(0.0);
                for (size_t j = b; j < e; ++j) {
                    members.push_back(keyed[j].second);
                    centre += glm::dvec3(positions[keyed[j].second]);
                }
                centre /= double(members.size());
                // The kept vertex: the member nearest the cell's centroid (lowest id on ties).
                uint32_t kept = members[0];
                double best = INFINITY;
                for (uint32_t v : members) {
                    const glm::dvec3 d = glm::dvec3(positions[v]) - centre;
                    const double d2 = glm::dot(d, d);
                    if (d2 < best) best = d2, kept = v;
                }
                order.clear();
                for (uint32_t v : members)
                    if (v != kept) order.push_back(v);
                const auto dist = [&](uint32_t v) { return glm::length(positions[v] - positions[kept]); };
                std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t c) { return dist(a) < dist(c); });
                for (uint32_t v : order) {
                    const float r = std::max(radius[kept], radius[v] + dist(v));
                    radius[kept] = r;
                    died.clear();
                    for (uint32_t t : incident[v]) {
                        if (dead[t]) continue;
                        uint32_t* c = &corners[3 * t];
                        if (c[0] == kept || c[1] == kept || c[2] == kept) {
                            dead[t] = 1;
                            died.push_back(t);
                            continue;
                        }
                        for (int k = 0; k < 3; ++k)
                            if (c[k] == v) c[k] = kept;
                        incident[kept].push_back(t);
                    }
                    std::sort(died.begin(), died.end());
                    died.erase(std::unique(died.begin(), died.end()), died.end());
                    sequence.push(v, kept, r, died.data(), died.size());
                    alive[v] = 0;
                    std::vector<uint32_t>().swap(incident[v]);
                }
            }
            b = e;
        }
    }
    return sequence;
}

}  // namespace occ
