// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

namespace occ {

struct WeldedMesh {
    std::vector<glm::vec3> positions;  // unique positions, in order of first use
    std::vector<uint32_t> triangles;   // 3 per triangle; triangles with a repeated corner dropped
    std::vector<uint32_t> source;      // per position: the first input vertex welded into it
    uint32_t dropped_triangles = 0;    // triangles that became degenerate (two corners welded)
};

// Merges vertices with bit-identical positions (+0 and -0 count as equal). Exporters split
// vertices along hard edges, seams and per-face attributes; without welding every such edge
// looks like a boundary and is locked, so nothing simplifies.
// triangles: 3 indices per triangle, each < positions.size().
WeldedMesh weldPositions(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles);

}  // namespace occ
