// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <string>

namespace occ::bench {

struct BenchMassiveOptions {
    std::string out;                  // results folder (created if missing)
    std::string scenes;               // where the plant is made once and reused (default OUT/scenes)
    uint32_t objects = 1000000;       // the plant's objects (10^6: 193 M triangles; 1.72 x 10^6: the Boeing's 332 M)
    uint32_t frames = 300;            // cameras of the walk and of the orbit
    uint32_t exact_frames = 30;       // the walk's prefix run with the exact visible set
    // With a hierarchy in the scene (prep's default): the orbit's prefix drawn against the
    // full-detail picture (--reference), flat and with the hierarchy, and a plant of this many
    // objects walked and orbited with the hierarchy for the growth (none when not below objects).
    uint32_t reference_frames = 30;
    uint32_t growth_objects = 10000;
    // With a hierarchy and reference frames, the picture stage (issue 49): the walk's and the
    // orbit's prefixes of the plant, of a plant of picture_objects objects (none when 0 or not
    // below objects) and, with village, of the KIT house tiled 10 x 1 x 10 (made with assimp
    // from assimp-testmodels' IFC; skipped, with the reason in the report, where either is
    // missing), each drawn against full detail in model and uniform colours, flat and with the
    // hierarchy.
    uint32_t picture_objects = 100000;
    bool village = true;
    // With a hierarchy: the engine tiled grid x grid x grid times (gen grid) prepared without and
    // with it, for the time and size of sharing HLODs among repeated subtrees (0: none).
    uint32_t grid = 10;
    double run_timeout_s = 7200;      // a run that takes longer is stopped and reported
    std::string budget = "auto";      // render --budget: what a frame draws (auto: one vertex per pixel)
};

// `occswitch bench massive --out DIR`: a plant of the papers' Boeing class, generated (gen
// plant, streamed) and preprocessed (prep, streamed) once into the scenes folder, their time
// and peak memory kept beside the files; then a walk and an orbit with oc+lod, the walk with
// lod alone, and a prefix of the walk against the exact visible set, each a child process.
// Writes DIR/massive.md and DIR/massive.csv (frame time median / p99 / max and the first
// frames, streamed share, PVS churn against exact churn, occluder triangles and raster ms,
// false culls, peak memory of gen, prep and every render), DIR/raw (per-frame stats) and
// DIR/logs; prints the summary's path on stdout. With a hierarchy in the scene, also the walk
// and the orbit with it (items drawn, triangles, cut churn), the orbit's prefix against the
// full-detail picture flat and with it (PSNR), the growth from a small plant, and the engine grid
// prepared without and with the hierarchy (time, peak, size; issue 34). With a hierarchy and
// --reference-frames, the picture stage (issue 49): for the plant, the picture plant and the
// KIT village, the walk's and the orbit's prefixes in model and uniform colours, each drawn
// flat and with the hierarchy against full detail; a row each (pooled PSNR, perceptibly changed
// share, SSIM, the bound's beyond-tau share, the three targets' verdicts with their margins) in
// massive.md's section "Pictures against full detail" and in DIR/pictures.csv. massive.csv's
// rows are the same with or without it. Throws UsageError for impossible options.
int runBenchMassive(const BenchMassiveOptions& options);

}  // namespace occ::bench
