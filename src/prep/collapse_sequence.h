// SPDX-License-Identifier: MIT
#pragma once

#include "scene/progressive_mesh.h"

#include <cstdint>
#include <vector>

namespace occ {

// A half-edge collapse sequence: in collapse i, vertex removed[i] moves onto kept[i] (an edge
// endpoint), and the triangles that contained both disappear: removedTriangles(i), ascending.
// Indices are those of the mesh the sequence was computed on (before re-arrangement).
struct CollapseSequence {
    std::vector<uint32_t> removed;
    std::vector<uint32_t> kept;
    std::vector<float> error;                // cost of each collapse as a distance: RMS distance to the
                                             // quadric's planes (fast), sqrt of the quadric (OpenMesh), or length
    std::vector<uint32_t> triangle_offsets{0};  // collapse i removed triangles[offsets[i], offsets[i+1])
    std::vector<uint32_t> triangles;
    uint32_t refused_faces = 0;              // faces the collapser kept as they are (never removed)
    // Vertices the collapses placed (issue 49, item 3): vertex count + i is at placed[i]. A
    // placing collapse of the edge a-b is two entries, a -> w (nothing removed) then b -> w (the
    // edge's triangles); placed_share[i] is a's share of the pair's surface, to mix attributes.
    std::vector<glm::vec3> placed;
    std::vector<float> placed_share;

    size_t size() const { return removed.size(); }
    void push(uint32_t removed_vertex, uint32_t kept_vertex, float cost, const uint32_t* tris, size_t tri_count) {
        removed.push_back(removed_vertex);
        kept.push_back(kept_vertex);
        error.push_back(cost);
        triangles.insert(triangles.end(), tris, tris + tri_count);
        triangle_offsets.push_back(uint32_t(triangles.size()));
    }
};

// The arrays of Peng & Cao 2012, §4.2, recorded while collapsing, in the original numbering:
//   ecol[v]      vertex v collapses to (original index), or -1 if v is never collapsed;
//   permuteV[v]  position of v after re-arrangement (removed vertices go to the end, the first
//                removed last);
//   permuteT[t]  position of triangle t after re-arrangement (same rule for triangles);
//   map[k]       number of triangles alive when k vertices remain, for k in [0, vertex_count]
//                (entries below q repeat map[q]).
struct CollapseArrays {
    std::vector<int32_t> ecol;
    std::vector<uint32_t> permuteV;
    std::vector<uint32_t> permuteT;
    std::vector<uint32_t> map;
    uint32_t q = 0;
};

}  // namespace occ
