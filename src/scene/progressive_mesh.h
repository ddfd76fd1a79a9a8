// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

namespace occ {

// A progressive mesh after Algorithm 1 of Peng & Cao 2012 (data re-arrangement): for every
// k in [q, vertexCount()], the first k vertices and the first map[k] triangles, with each
// triangle corner walked through ecol until it is < k, form the level of detail with k vertices.
struct ProgressiveMesh {
    std::vector<glm::vec3> positions;  // re-arranged vertex positions
    std::vector<int32_t> ecol;         // ecol[v] < v for v >= q; -1 for v < q (never collapsed)
    std::vector<float> error;          // error of the collapse that removes v; 0 for v < q
    std::vector<uint32_t> triangles;   // 3 corners per triangle, full-detail, re-arranged numbering
    std::vector<uint32_t> map;         // vertexCount() + 1 entries, non-decreasing, map[n] = triangleCount()
    // Per vertex, its colour (oss::kWhite layout: RGBA8, sRGB), multiplied into its object's;
    // empty: every vertex white. HLODs carry the colours of the objects they stand for.
    std::vector<uint32_t> colours;
    // Per vertex, its normal (oss::encodeNormal; oss::kNoNormal: none); empty: none at all.
    // HLODs carry the normals of the full detail their vertices stand for (hlodVertexNormals).
    std::vector<uint32_t> normals;
    uint32_t q = 0;                    // vertices never collapsed (locked: non-manifold, where borders meet)
    uint32_t refused_faces = 0;        // faces the collapser could not take (kept, never removed)
    uint32_t source_vertices = 0;      // vertex count of the input, before welding
    uint32_t dropped_triangles = 0;    // input triangles degenerate after welding (not stored)

    uint32_t vertexCount() const { return uint32_t(positions.size()); }
    uint32_t triangleCount() const { return uint32_t(triangles.size() / 3); }
};

}  // namespace occ
