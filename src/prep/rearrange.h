// SPDX-License-Identifier: MIT
#pragma once

#include "prep/collapse_sequence.h"

namespace occ {

// Records the arrays of Peng & Cao 2012 §4.2 (ecol, permuteV, permuteT, map) from a collapse
// sequence over a mesh of vertex_count vertices and triangle_count triangles. With m vertices
// and t triangles alive before collapse i, the removed vertex gets position m-1, its removed
// triangles (ascending) get t-1, t-2, ..., and map[m-1] = t - (removed triangles). Vertices and
// triangles never removed take the first positions in their original order.
CollapseArrays recordCollapseArrays(uint32_t vertex_count, uint32_t triangle_count, const CollapseSequence& sequence);

// Algorithm 1 of Peng & Cao 2012 (data re-arrangement): stores vertices and triangles at their
// permuted positions, so that a level of detail is a prefix of both arrays, and renumbers ecol
// and the triangle corners accordingly (after which ecol[v] < v for every collapsible v).
// triangles: 3 per triangle, corners < positions.size().
ProgressiveMesh rearrange(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                          const CollapseSequence& sequence, const CollapseArrays& arrays);

}  // namespace occ
