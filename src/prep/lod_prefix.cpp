// SPDX-License-Identifier: MIT
#include "prep/lod_prefix.h"

#include <vector>

namespace occ {

std::string checkLodPrefix(uint32_t n, std::span<const int32_t> ecol, std::span<const uint32_t> triangles,
                           std::span<const uint32_t> map, uint32_t q) {
    const uint32_t tc = uint32_t(triangles.size() / 3);
    std::vector<uint32_t> corner(triangles.begin(), triangles.end());
    const auto degenerate = [&](uint32_t t) {
        return corner[3 * t] == corner[3 * t + 1] || corner[3 * t + 1] == corner[3 * t + 2] ||
               corner[3 * t] == corner[3 * t + 2];
    };
    if (map[n] != tc) return "map[" + std::to_string(n) + "] = " + std::to_string(map[n]) + " is not the triangle count " + std::to_string(tc);
    for (uint32_t t = 0; t < tc; ++t)
        if (degenerate(t)) return "triangle " + std::to_string(t) + " is degenerate at full detail";

    // Triangles per vertex as singly linked lists; a vertex's list moves to ecol[v] when v goes.
    std::vector<uint32_t> head(n, UINT32_MAX), next(corner.size(), UINT32_MAX), tail(n, UINT32_MAX);
    for (uint32_t i = 0; i < corner.size(); ++i) {
        const uint32_t v = corner[i];
        if (head[v] == UINT32_MAX) head[v] = i; else next[tail[v]] = i;
        tail[v] = i;
    }
    std::vector<uint8_t> dead(tc, 0);
    for (uint32_t k = n; k > q; --k) {
        const uint32_t v = k - 1, target = uint32_t(ecol[v]);
        for (uint32_t i = head[v]; i != UINT32_MAX; i = next[i]) {
            const uint32_t t = i / 3;
            if (dead[t]) continue;
            corner[i] = target;
            if (!degenerate(t)) continue;
            dead[t] = 1;
            if (t < map[v] || t >= map[k])
                return "level " + std::to_string(v) + ": triangle " + std::to_string(t) +
                       " degenerates but map says triangles [" + std::to_string(map[v]) + ", " +
                       std::to_string(map[k]) + ") go";
        }
        if (head[v] != UINT32_MAX) {
            if (head[target] == UINT32_MAX) head[target] = head[v]; else next[tail[target]] = head[v];
            tail[target] = tail[v];
        }
        // Everything map says goes at this step must have gone.
        for (uint32_t t = map[v]; t < map[k]; ++t)
            if (!dead[t])
                return "level " + std::to_string(v) + ": triangle " + std::to_string(t) +
                       " should be gone (map) but is not degenerate";
    }
    return "";
}

}  // namespace occ
