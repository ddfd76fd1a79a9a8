// SPDX-License-Identifier: MIT
#pragma once

#include "util/config.h"

#include <CLI/CLI.hpp>

#include <functional>

namespace occ::cli {

// Each subcommand registers itself and its options on the app and returns the action to run
// when it is chosen. Actions return the process exit status; errors are thrown (InputError, UsageError).
struct Command {
    CLI::App* app;
    std::function<int()> run;
};

// Parses a viewport "WxH" (1 <= W, H <= kMaxViewportSide, util/config.h); throws UsageError naming `option` otherwise.
void parseViewportSize(const std::string& option, const std::string& text, uint32_t& width, uint32_t& height);

// Parses --pvs-occluders: "auto" (PipelineOptions::kAutoOccluderTriangles) or a triangle count
// (0 = off); throws UsageError otherwise.
uint64_t parseOccluderTriangles(const std::string& text);
// Parses --budget: "auto" (both 0), a vertex count (>= 1) or a share of the scene's vertices
// ("10%", into share as 0.1); UsageError otherwise.
void parseBudget(const std::string& text, double& vertices, double& share);

Command addInfoCommand(CLI::App& app);
Command addGenCommand(CLI::App& app);
Command addPrepCommand(CLI::App& app);
Command addVerifyCommand(CLI::App& app);
Command addPathCommand(CLI::App& app);
Command addRenderCommand(CLI::App& app);
Command addBenchCommand(CLI::App& app);

}  // namespace occ::cli
