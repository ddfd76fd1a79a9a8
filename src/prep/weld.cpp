// SPDX-License-Identifier: MIT
#include "prep/weld.h"

#include <cstring>
#include <unordered_map>

namespace occ {

namespace {

struct PositionKey {
    uint32_t bits[3];
    bool operator==(const PositionKey& o) const { return std::memcmp(bits, o.bits, sizeof(bits)) == 0; }
};

struct PositionHash {
    size_t operator()(const PositionKey& k) const {
        uint64_t h = 0x9E3779B97F4A7C15ull;
        for (uint32_t b : k.bits) h = (h ^ b) * 0xBF58476D1CE4E5B9ull;
        return size_t(h ^ (h >> 31));
    }
};

PositionKey keyOf(const glm::vec3& p) {
    PositionKey k;
    for (int i = 0; i < 3; ++i) {
        const float v = p[i] == 0.0f ? 0.0f : p[i];  // -0 and +0 are the same place
        std::memcpy(&k.bits[i], &v, 4);
    }
    return k;
}

}  // namespace

WeldedMesh weldPositions(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles) {
    WeldedMesh out;
    std::unordered_map<PositionKey, uint32_t, PositionHash> index_of;
    index_of.reserve(positions.size());
    std::vector<uint32_t> remap(positions.size(), UINT32_MAX);
    out.triangles.reserve(triangles.size());
    for (size_t t = 0; t + 2 < triangles.size(); t += 3) {
        uint32_t c[3];
        for (int i = 0; i < 3; ++i) {
            const uint32_t v = triangles[t + i];
            if (remap[v] == UINT32_MAX) {
                auto [it, added] = index_of.emplace(keyOf(positions[v]), uint32_t(out.positions.size()));
                if (added) out.positions.push_back(positions[v]), out.source.push_back(v);
                remap[v] = it->second;
            }
            c[i] = remap[v];
        }
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) {
            ++out.dropped_triangles;
            continue;
        }
        out.triangles.insert(out.triangles.end(), c, c + 3);
    }
    return out;
}

}  // namespace occ
