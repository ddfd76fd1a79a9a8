// SPDX-License-Identifier: MIT
#pragma once

#include <string>
#include <vector>

namespace occ::bench {

struct BenchAllOptions {
    std::string out;       // results folder (created if missing)
    std::string size = "small";  // tiny | small | full
    std::string scenes;    // folder of prepared scenes, reused between runs (default OUT/scenes)
    std::string model;     // the model the engine grids tile
    bool no_mpi = false;   // measure the layouts with one rank only, without mpirun
    std::vector<int> only;  // the experiments to run, 1-9 (empty: all); the others' sections say so
};

// `occswitch bench all --out DIR`: prepares the scenes it needs (engine grids, a plant) unless
// they are already in the scenes folder, runs every experiment of the papers as child
// processes of this same executable (and of mpirun for 2 and 3 ranks), and writes into DIR:
// one CSV per experiment, summary.md with our figures beside the papers', gnuplot scripts and
// their PNG plots (DIR/plots), the per-frame stats of every run (DIR/raw) and each run's log
// (DIR/logs). Prints a progress line per run on stderr and the summary's path on stdout.
// Throws UsageError for impossible options, SystemError when a run fails (naming its log).
int runBenchAll(const BenchAllOptions& options);

}  // namespace occ::bench
