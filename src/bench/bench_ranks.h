// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace occ::bench {

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

struct BenchLinksOptions {
    std::string out;                                  // results folder (created if missing)
    std::string scene;                                // an existing .oss instead of the 4x4x4 engine grid
    std::string model;                                // the grid's model (default: the 2CylinderEngine)
    std::vector<int> layouts{3, 4};                   // rank counts: the 3-rank switch, 2 + P
    std::vector<double> latencies_ms{0, 0.2, 1, 5, 20};
    std::vector<double> mbps{100, 1000, 10000};
    uint32_t frames = 60;                             // cameras of the walk
    double path_fps = 30;                             // render --pace recorded --path-fps
    double saturate_fps = 10;                         // the bandwidth-bound run aims at this many fps (0: none)
    std::string size = "320x240";
    double run_timeout_s = 1800;
};

// `occswitch bench links --out DIR` (issue 17): the walk with paced cameras (--pace recorded)
// through every layout, first without emulation, then over every emulated link of latency x
// bandwidth (render --link): displayed fps, camera-to-display latency in frames and ms, poses
// skipped, bytes per frame by kind, the time each rank waits; SWITCH's bandwidth formula
// (Govindaraju et al. 2003: 8n + nh/b + 3(72 + h) bytes per frame) from the measured n and our
// header size beside the measured bytes; the largest frame rate each link carries, and one run
// on a link just narrow enough to hold the switch to `saturate_fps`. Writes links.md, links.csv,
// plots/links.png (with gnuplot) into --out and prints the summary's path.
int runBenchLinks(const BenchLinksOptions& options);

}  // namespace occ::bench
