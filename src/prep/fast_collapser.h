// SPDX-License-Identifier: MIT
#pragma once

#include "prep/collapse_sequence.h"

#include <span>

namespace occ {

enum class CollapseCost {
    Quadric,     // Garland & Heckbert 1997, the removed vertex's quadric evaluated at the kept one
    EdgeLength,  // length of the collapsed edge (hand-checkable fixtures, Peng & Cao's Figure 3)
};

// Computes a half-edge collapse sequence run to the end: each step moves one vertex onto a
// neighbour (the kept endpoint), cheapest first, until no legal collapse is left. Vertices are
// classified as meshoptimizer does (welded positions, so no attribute seams): interior
// (manifold), border (on exactly two border edges, one open fan) or locked (on a non-manifold
// edge, used by three or more triangles, or where border chains meet). With the Quadric cost
// (the removed vertex's quadric at the kept position; planes weighted by the square root of
// twice their triangle's area, border edges adding a plane at right angles to the face with 10 x
// the edge's length, as meshoptimizer 0.18 weighs them) a border vertex collapses along its
// border onto a neighbour on it; with EdgeLength every border vertex is locked. Locked vertices
// are never removed, so q = vertex count - sequence size. A collapse is legal when it keeps the
// neighbourhood a disk (link condition), creates no duplicate triangle and turns no triangle
// over; the one exception closes a hole whose border loop is down to three vertices (the third
// vertex turns interior, or from locked to border where loops met there).
// Flat arrays and our own heap, no half-edge structure: several times faster than OpenMesh's
// Decimater, same invariants (see tests/unit/test_collapse.cpp).
// place (issue 49, item 3; Quadric cost only): a collapse of an edge between two interior
// vertices, or two border vertices along their border, may move both ends to a new vertex at
// the point of least squared distance to their summed planes (Garland & Heckbert's optimal
// placement), recorded as two entries onto a vertex past the input's (CollapseSequence::placed),
// where that point is cheaper than the kept end's position and keeps every triangle around
// both ends within 60 degrees of its normal (else the half-edge collapse, if legal). Ranking is
// then by the summed quadric at the placement. A thin slab's top face then meets its bottom
// face half way instead of taking its corners, so its facets do not tilt. colours (one per
// position, or empty): only ends of the same colour are placed (a colour border stays sharp).
// positions: welded (no two equal); triangles: 3 per triangle, no repeated corner.
CollapseSequence fastCollapseSequence(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                      CollapseCost cost = CollapseCost::Quadric, bool place = false,
                                      std::span<const uint32_t> colours = {});

}  // namespace occ
