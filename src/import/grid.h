// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <string>

namespace occ {

struct GridOptions {
    uint32_t nx = 10, ny = 10, nz = 10;
    float spacing = 0.0f;  // distance between tile origins; 0 = 1.25 x the model's largest extent
};

// Writes `model` tiled nx*ny*nz times as a GLB by node instancing: the meshes are stored once,
// and each tile is one node (a translation) whose children place the model's objects, so the
// file grows with the number of nodes, not triangles. Importing the result yields
// nx*ny*nz*model.objects.size() objects sharing model.meshes.size() meshes.
// Throws UsageError for a zero or absurd tile count or a negative spacing.
void writeGrid(const std::string& path, const Scene& model, const GridOptions& options);

}  // namespace occ
