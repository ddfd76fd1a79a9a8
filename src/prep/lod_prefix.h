// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <span>
#include <string>

namespace occ {

// Checks the prefix property of a re-arranged progressive mesh (Peng & Cao 2012, §4): for
// every k in [q, n] the first map[k] triangles, corners walked through ecol until < k, are
// non-degenerate, and every later triangle is degenerate at level k. Runs in O(triangles +
// total vertex degree) by lowering k one vertex at a time. Expects the structural checks done
// (ecol[v] < v for v >= q, -1 below; map has n + 1 non-decreasing entries; corners < n).
// Returns "" when the property holds, otherwise what failed first.
std::string checkLodPrefix(uint32_t vertex_count, std::span<const int32_t> ecol, std::span<const uint32_t> triangles,
                           std::span<const uint32_t> map, uint32_t q);

}  // namespace occ
