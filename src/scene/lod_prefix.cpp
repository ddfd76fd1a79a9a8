// SPDX-License-Identifier: MIT
#include "scene/lod_prefix.h"

namespace occ {

namespace {

std::string decimal(uint64_t v) { return std::to_string(v); }

bool isDegenerate(const uint32_t* c) { return c[0] == c[1] || c[1] == c[2] || c[0] == c[2]; }

}  // namespace

std::optional<LodPrefixViolation> checkLodPrefix(uint32_t n, std::span<const int32_t> ecol,
                                                 std::span<const uint32_t> triangles, std::span<const uint32_t> map,
                                                 uint32_t q, LodPrefixScratch& s) {
    const uint32_t t_count = uint32_t(triangles.size() / 3);
    s.corners.assign(triangles.begin(), triangles.end());
    s.degenerate.assign(t_count, 0);
    if (s.triangles_of.size() < n) s.triangles_of.resize(n);
    for (uint32_t v = 0; v < n; ++v) s.triangles_of[v].clear();

    // Level n is the full mesh: every triangle must be non-degenerate.
    for (uint32_t t = 0; t < t_count; ++t) {
        const uint32_t* c = &s.corners[size_t(t) * 3];
        if (isDegenerate(c))
            return LodPrefixViolation{n, "triangle " + decimal(t) + " (" + decimal(c[0]) + ", " + decimal(c[1]) + ", " +
                                             decimal(c[2]) + ") is degenerate at full detail, but map[" + decimal(n) +
                                             "] = " + decimal(map[n])};
        for (int j = 0; j < 3; ++j) s.triangles_of[c[j]].push_back(t);
    }

    // Invariant entering each step: the non-degenerate triangles are exactly [0, map[k]).
    // Removing vertex k - 1 moves its corners onto ecol[k - 1]; the triangles that become
    // degenerate must be exactly [map[k - 1], map[k]).
    for (uint32_t k = n; k > q; --k) {
        const uint32_t v = k - 1, target = uint32_t(ecol[v]);
        const uint32_t lo = map[k - 1], hi = map[k];
        uint32_t removed = 0;
        for (const uint32_t t : s.triangles_of[v]) {
            if (s.degenerate[t]) continue;
            uint32_t* c = &s.corners[size_t(t) * 3];
            for (int j = 0; j < 3; ++j)
                if (c[j] == v) c[j] = target;
            if (isDegenerate(c)) {
                if (t < lo)
                    return LodPrefixViolation{k - 1, "triangle " + decimal(t) + " degenerates when vertex " +
                                                         decimal(v) + " collapses into " + decimal(target) +
                                                         ", but it is below map[" + decimal(k - 1) +
                                                         "] = " + decimal(lo)};
                s.degenerate[t] = 1;
                ++removed;
            } else {
                s.triangles_of[target].push_back(t);
            }
        }
        s.triangles_of[v].clear();
        if (removed != hi - lo) {
            uint32_t survivor = lo;
            while (survivor < hi && s.degenerate[survivor]) ++survivor;
            return LodPrefixViolation{k - 1, "collapsing vertex " + decimal(v) + " into " + decimal(target) +
                                                 " removes " + decimal(removed) + " triangles, but map[" + decimal(k) +
                                                 "] - map[" + decimal(k - 1) + "] = " + decimal(hi - lo) +
                                                 "; triangle " + decimal(survivor) + " stays non-degenerate"};
        }
    }
    return std::nullopt;
}

}  // namespace occ
