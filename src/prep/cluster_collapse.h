// SPDX-License-Identifier: MIT
#pragma once

// Vertex clustering after the edge collapses, for HLODs (issue 16). A half-edge collapse never
// removes or joins connected components, so a node's merged input keeps every object's floor
// (4 triangles for a closed object) in every ancestor. Clustering (Rossignac & Borrel 1993) does
// what the collapses cannot: on a grid whose cell doubles level by level, every vertex of a cell
// moves onto one point, components shrink to points and vanish, neighbours join.
//
// The point is placed (issue 49, item 3): a new vertex where the squared distances to the
// planes of the input triangles its members stand for are least (Lindstrom 2000's out-of-core
// clustering: the quadrics summed over the cluster, minimised with small eigenvalues left out,
// so that a flat cluster stays on its plane and an edge on its edge), clamped to the members'
// box. A slab's top face no longer takes its bottom corners, so its facets do not tilt.
//
// Each move is recorded as a contraction of the same sequence (removed -> kept, the triangles
// it makes degenerate). A placed vertex gets the next free index; it is kept by its members and
// may itself be removed by a later, coarser cluster. So the result is a progressive mesh with
// the same arrays and the prefix property (recordCollapseArrays puts a placed vertex before the
// vertices that collapse onto it): at a level, a placed vertex whose members are all still
// there is in the prefix but no triangle uses it. A level then holds up to about twice the
// vertices it draws; the triangles are the same.

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
    // A cluster's vertices move onto a placed vertex (above); off: onto the member nearest the
    // cell's centroid, no vertex added. A placement that would turn a surviving triangle over
    // falls back to that member too.
    bool place = true;
    // The edge collapses before clustering place too (fastCollapseSequence's place).
    bool place_edges = false;
    // Vertices of different colours (the `colours` given) are not clustered together: a cell
    // keeps one cluster per colour, so a red part beside a grey one stays red.
    bool colour_borders = false;
};

// Extends `sequence` (a collapse sequence over positions / triangles, e.g. fastCollapseSequence's)
// with clustering contractions of the vertices it leaves. A contraction's error is the largest
// distance from any vertex merged into the cluster so far to the cluster's point, an upper
// bound of how far the level moved the input's vertices. Placed vertices are appended to
// `positions` and, when `colours` is given (one sRGB RGBA8 per vertex, oss::kWhite's layout),
// to it: the members' mean in linear light, weighted by their surface. Deterministic.
// positions: welded; triangles: 3 per triangle, no repeated corner.
CollapseSequence clusterAfterCollapses(std::vector<glm::vec3>& positions, std::vector<uint32_t>* colours,
                                       const std::vector<uint32_t>& triangles, CollapseSequence sequence,
                                       const ClusterOptions& options = {});

}  // namespace occ
