// SPDX-License-Identifier: MIT
#pragma once

#include "scene/prepared_scene.h"

#include <atomic>
#include <functional>

namespace occ {

enum class Collapser {
    Fast,      // ours: flat arrays, own heap (default)
    OpenMesh,  // reference: OpenMesh's Decimater with ModQuadric and our recording module
};

struct PrepOptions {
    float ct = 0.55f;           // compactness threshold CT for the candidate occluder set
    unsigned threads = 0;       // 0: all hardware threads
    Collapser collapser = Collapser::Fast;
    int compactness_resolution = 64;  // raster size of Eq. 2's projections, longer side
};

// Counters that prepareScene advances while it works, readable from another thread.
struct PrepProgress {
    std::atomic<uint64_t> meshes_done{0}, triangles_done{0};
    uint64_t meshes_total = 0, triangles_total = 0;
};

// Weld + collapse sequence + §4.2 arrays + Algorithm 1 for one mesh (local space).
ProgressiveMesh buildProgressiveMesh(const Mesh& mesh, Collapser collapser);

// Preprocesses a scene: one progressive mesh per unique mesh (instances share it), computed in
// parallel over meshes, largest first; per object the world AABB, OOBB, occluder normal and
// compactness; the candidate occluder set. Throws UsageError for a ct outside [0, 1].
PreparedScene prepareScene(const Scene& scene, const PrepOptions& options, PrepProgress* progress = nullptr);

}  // namespace occ
