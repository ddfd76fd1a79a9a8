// SPDX-License-Identifier: MIT
#pragma once

// Vertex clustering after the edge collapses, for HLODs (issue 16). A half-edge collapse never
// removes or joins connected components, so a node's merged input keeps every object's floor
// (4 triangles for a closed object) in every ancestor. Clustering (Rossignac & Borrel 1993) does
// what the collapses cannot: on a grid whose cell doubles level by level, every vertex of a cell
// moves onto one of them, components shrink to points and vanish, neighbours join. Each such move
// is recorded as one more contraction of the same sequence (removed -> kept, the triangles it
// makes degenerate), so the result is a progressive mesh with the same arrays and the prefix
// property; only the kept vertex need not be a neighbour.

#include "prep/collapse_sequence.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

namespace occ {

struct ClusterOptions {
    // The first grid's cell edge as a fraction of the largest extent of the mesh's box; each
    // following grid doubles it. Edge collapses of error above the first cell's diagonal are
    // dropped from the sequence (clustering takes over from there). On the 10^5-object plant's
    // orbit (docs/results.md) 1/32 drew the fewest triangles at the best PSNR of 1/1024, 1/128,
    // 1/32 and 1/8: smaller cells cut the edge collapses short, where they simplify better.
    float first_cell = 1.0f / 32.0f;
    // The last grid's cell edge as a fraction of the largest extent: clustering stops there, so
    // the coarsest level keeps a few clusters and the triangles between them.
    float last_cell = 1.0f / 4.0f;
};

// Extends `sequence` (a collapse sequence over positions / triangles, e.g. fastCollapseSequence's)
// with clustering contractions of the vertices it leaves. A contraction's error is the largest
// distance from any vertex merged into the cluster so far to the cluster's kept vertex, an upper
// bound of how far the level moved the input's vertices. Deterministic.
// positions: welded; triangles: 3 per triangle, no repeated corner.
CollapseSequence clusterAfterCollapses(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                       CollapseSequence sequence, const ClusterOptions& options = {});

}  // namespace occ
