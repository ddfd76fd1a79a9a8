// SPDX-License-Identifier: MIT
#pragma once

#include "scene/progressive_mesh.h"

#include <cstdint>
#include <vector>

namespace occ {

// Per vertex of a progressive mesh, the normal of the full detail it stands for (issue 49, item
// 2), oss::encodeNormal'd: the principal axis of the area-weighted normal tensor (sum of area
// n n^T, so that a face and its back count alike: the display lights both sides) of the
// full-detail faces around the vertex; a vertex placed by clustering (one no full-detail face
// uses) gathers its members' tensors, clusters of clusters theirs. oss::kNoNormal where the
// surface there has no one direction: the axis holds less than `planarity` of the tensor's trace
// (a box's corner 1/3, its edge 1/2, two faces of a 16-sided pipe 0.96), or no face at all. Such
// vertices are lit by their faces' normals, as the full detail is.
// Only the first `keep` vertices get one (those past it are left kNoNormal: the caller drops
// them, as truncateLevels does), though every full-detail face still counts.
std::vector<uint32_t> hlodVertexNormals(const ProgressiveMesh& pm, float planarity = 0.8f,
                                        uint32_t keep = UINT32_MAX);

}  // namespace occ
