// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

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

// A progressive mesh after Algorithm 1 of Peng & Cao 2012 (data re-arrangement): for every
// k in [q, vertexCount()], the first k vertices and the first map[k] triangles, with each
// triangle corner walked through ecol until it is < k, form the level of detail with k vertices.
struct ProgressiveMesh {
    std::vector<glm::vec3> positions;  // re-arranged vertex positions
    std::vector<int32_t> ecol;         // ecol[v] < v for v >= q; -1 for v < q (never collapsed)
    std::vector<float> error;          // error of the collapse that removes v; 0 for v < q
    std::vector<uint32_t> triangles;   // 3 corners per triangle, full-detail, re-arranged numbering
    std::vector<uint32_t> map;         // vertexCount() + 1 entries, non-decreasing, map[n] = triangleCount()
    uint32_t q = 0;                    // vertices never collapsed (locked: non-manifold, where borders meet)
    uint32_t refused_faces = 0;        // faces the collapser could not take (kept, never removed)
    uint32_t source_vertices = 0;      // vertex count of the input, before welding
    uint32_t dropped_triangles = 0;    // input triangles degenerate after welding (not stored)

    uint32_t vertexCount() const { return uint32_t(positions.size()); }
    uint32_t triangleCount() const { return uint32_t(triangles.size() / 3); }
};

}  // namespace occ
