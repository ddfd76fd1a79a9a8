// SPDX-License-Identifier: MIT
#pragma once

#include "prep/progressive_mesh.h"

namespace occ {

enum class CollapseCost {
    Quadric,     // Garland & Heckbert 1997, quadrics of both endpoints evaluated at the kept one
    EdgeLength,  // length of the collapsed edge (hand-checkable fixtures, Peng & Cao's Figure 3)
};

// Computes a half-edge collapse sequence run to the end: each step moves one vertex onto a
// neighbour (the kept endpoint), cheapest first, until no legal collapse is left. Vertices are
// classified as meshoptimizer does (welded positions, so no attribute seams): interior
// (manifold), border (on exactly two border edges, one open fan) or locked (on a non-manifold
// edge, used by three or more triangles, or where border chains meet). With the Quadric cost a
// border vertex collapses along its border onto a neighbour on it, and border edges add a
// plane at right angles to the face to both ends' quadrics (the outline resists moving); with
// EdgeLength every border vertex is locked. Locked vertices are never removed, so q = vertex
// count - sequence size. A collapse is legal when it keeps the
// neighbourhood a disk (link condition), creates no duplicate triangle and flips no normal.
// Flat arrays and our own heap, no half-edge structure: several times faster than OpenMesh's
// Decimater, same invariants (see tests/unit/test_collapse.cpp).
// positions: welded (no two equal); triangles: 3 per triangle, no repeated corner.
CollapseSequence fastCollapseSequence(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                      CollapseCost cost = CollapseCost::Quadric);

}  // namespace occ
