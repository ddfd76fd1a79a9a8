// SPDX-License-Identifier: MIT
#pragma once

#include "import/scene_source.h"
#include "prep/cluster_collapse.h"
#include "scene/prepared_scene.h"

#include <atomic>
#include <functional>
#include <span>
#include <string>
#include <vector>

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
    // The object hierarchy and its HLODs (prep/hierarchy.h; written by the command line's prep,
    // not by prepareScene / prepareToFile, which make the flat scene it starts from).
    bool hierarchy = true;
    uint32_t fanout = 8;              // children per node at most
    uint32_t node_triangles = 2048;   // HlodOptions::node_triangles
    uint32_t hlod_reduction = 4;      // HlodOptions::reduction
    bool hlod_cluster = true;         // HlodOptions::cluster
    bool hlod_place = true;           // HlodOptions::place
    bool hlod_place_edges = false;    // HlodOptions::place_edges
    bool hlod_colour_borders = true;  // HlodOptions::colour_borders
    bool hlod_normals = true;         // HlodOptions::normals
    bool hlod_fine_input = true;      // HlodOptions::fine_input
    bool hlod_share = true;           // HlodOptions::share_repeats
};

// Counters that prepareScene advances while it works, readable from another thread.
struct PrepProgress {
    std::atomic<uint64_t> meshes_done{0}, triangles_done{0};
    uint64_t meshes_total = 0, triangles_total = 0;
};

// Weld + collapse sequence + §4.2 arrays + Algorithm 1 for one mesh (local space). colours
// (one per mesh position, or empty): the vertices' colours, carried to ProgressiveMesh::colours
// (of positions welded together, the first's).
ProgressiveMesh buildProgressiveMesh(const Mesh& mesh, Collapser collapser, std::span<const uint32_t> colours = {});
// The same with the fast collapser's sequence continued by vertex clustering
// (cluster_collapse.h), for HLODs: components may vanish and join, clusters move onto placed
// vertices. colours (one per mesh position, or empty): the vertices' colours, carried to
// ProgressiveMesh::colours (a placed vertex's is its members' mix); empty: none.
ProgressiveMesh buildClusteredProgressiveMesh(const Mesh& mesh, std::span<const uint32_t> colours = {},
                                             const ClusterOptions& options = {});

// What a preparation made, for its summary line.
struct PrepSummary {
    uint64_t objects = 0, meshes = 0, cos = 0;
    uint64_t unique_triangles = 0, instanced_triangles = 0, dropped_triangles = 0;
    SkippedPrimitives skipped;
};

// Preprocesses a scene: one progressive mesh per used mesh (instances share it), in the
// source's mesh order, computed in parallel (options.threads) and handed to add_mesh in that
// order as each is done, so that only a few meshes per thread are held at a time; per object
// the world AABB, OOBB, occluder normal and compactness; the candidate occluder set. Objects
// whose mesh has no triangles are dropped (the rest keep their order). The output does not
// depend on the thread count. Throws OptionError for a ct outside [0, 1]; rethrows the first
// failure of a worker (a mesh the source cannot read) after stopping the others.
PrepSummary prepareFromSource(const SceneSource& source, const PrepOptions& options, PrepProgress* progress,
                              const std::function<uint32_t(ProgressiveMesh&&)>& add_mesh,
                              std::vector<ObjectRecord>& objects, std::vector<uint32_t>& cos);

// prepareFromSource of a scene in memory, collected into a PreparedScene.
PreparedScene prepareScene(const Scene& scene, const PrepOptions& options, PrepProgress* progress = nullptr);

// prepareFromSource streamed into a .oss file at `path` (OssStreamWriter): memory stays a few
// meshes per thread plus the object records, however large the scene. InputError(path) for a
// source without triangles; nothing is left at `path` on failure. durable false: the file is
// not synced to disk (a temporary this process reads back and removes, such as prep's flat
// scene before its hierarchy).
PrepSummary prepareToFile(const SceneSource& source, const std::string& path, const PrepOptions& options,
                          PrepProgress* progress = nullptr, bool durable = true);

}  // namespace occ
