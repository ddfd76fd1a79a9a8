// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace occ::cli {

struct BenchRanksOptions {
    std::string out;                          // results folder (created if missing)
    std::vector<int> ranks{1, 2, 3, 4, 6, 8};  // the layouts measured
    uint32_t objects = 3000;                  // the plant made when --scene is not given
    uint32_t frames = 60;                     // cameras of the walk
    std::string scene;                        // an existing .oss instead of the plant
    std::string size = "320x240";             // render --size
    int sort_last_cells = 1;                  // render --sort-last-cells
    double run_timeout_s = 1800;
    std::vector<double> link_gbps{10, 100};   // link speeds the cluster model predicts for
};

// `occswitch bench ranks --out DIR`: the same walk rendered headless by every layout of
// --ranks (1 rank, 2, the 3-rank switch, 2 + P sort-last), each through mpirun, one machine
// (oversubscribed: correctness, bytes and latency, not speed). Writes DIR/ranks.md and
// DIR/ranks.csv: bytes per frame by message kind, composite bytes and ms, latency in frames and
// ms, busy and wait ms per rank, whether every layout culled the visible sets of 1 rank and drew
// its pictures; and DIR/model.csv, the cluster model of docs/scaling.md fed with the stage costs
// measured here. Prints the summary's path on stdout.
int runBenchRanks(const BenchRanksOptions& options);

}  // namespace occ::cli
