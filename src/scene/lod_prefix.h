// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace occ {

// Buffers checkLodPrefix reuses between meshes, so that checking 20 000 small meshes does not
// allocate 20 000 times. One per thread.
struct LodPrefixScratch {
    std::vector<uint32_t> corners;                    // current (walked) corners, 3 per triangle
    std::vector<uint8_t> degenerate;                  // per triangle, at the current level
    std::vector<std::vector<uint32_t>> triangles_of;  // per vertex: live triangles with it as a corner
};

struct LodPrefixViolation {
    uint32_t k;        // the level at which the property first fails
    std::string what;  // which triangle and why
};

// Checks the prefix property of a re-arranged progressive mesh (Peng & Cao 2012, §4): for
// every k in [q, n] the first map[k] triangles, corners walked through ecol until < k, are
// non-degenerate, and every later triangle is degenerate at level k. Lowers k one vertex at a
// time and re-lists a triangle under the vertex it moved to only while it stays
// non-degenerate, so the work is the sum of the collapsed vertices' valences (chains of
// collapses stay linear). Expects the structural checks done (ecol[v] < v for v >= q, map has
// n + 1 entries, map[n] = triangle count, corners < n). Returns the first violation, if any.
std::optional<LodPrefixViolation> checkLodPrefix(uint32_t n, std::span<const int32_t> ecol,
                                                 std::span<const uint32_t> triangles, std::span<const uint32_t> map,
                                                 uint32_t q, LodPrefixScratch& scratch);

}  // namespace occ
