// SPDX-License-Identifier: MIT
#pragma once

#include "pipeline/pipeline.h"

#include <cstdint>
#include <string>

namespace occ::bench {

struct PipelineBenchOptions {
    std::string scene, path, out_dir;
    uint32_t width = 512, height = 512;
    uint64_t pvs_occluder_triangles = PipelineOptions::kAutoOccluderTriangles;
};

// `occswitch bench pipeline SCENE.oss P.cam`: in one run, per streaming mode (SC, SnC, NS) the
// bytes streamed host -> device per frame and the time of each step; reform throughput against
// a plain memcpy of the same bytes; the culled share with and without occlusion culling.
// Prints a table; with out_dir, also writes pipeline_bench.csv there.
int runPipelineBench(const PipelineBenchOptions& options);

}  // namespace occ::bench
