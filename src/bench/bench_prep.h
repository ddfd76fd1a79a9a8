// SPDX-License-Identifier: MIT
#pragma once

#include "util/config.h"

#include <cstdint>
#include <string>

namespace occ::bench {

// `occswitch bench prep`: the preprocessing's speed and error against meshoptimizer's and the
// OpenMesh reference's on the unique meshes of one model.
struct BenchPrepOptions {
    std::string input = kDefaultModel;
    std::string out;
    unsigned threads = 0;
    uint32_t samples = 20000;
    uint32_t samples_per_triangle = 10;
    unsigned repeat = 3;
    double openmesh_seconds = 20.0;
    bool meshopt_lock_border = false;
};

// Runs it: a table on stdout, prep_bench.csv and prep_summary.md into `out` when given. Throws
// UsageError for impossible options.
int runBenchPrep(const BenchPrepOptions& options);

}  // namespace occ::bench
