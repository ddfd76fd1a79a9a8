// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

namespace occ {

// The stages of one frame, in order; each has a milliseconds column in the stats CSV.
enum class Stage : uint32_t {
    FrustumCull,
    OccluderSelect,  // Eq. 3 weights, top-K, plus last frame's large visible objects
    DepthRaster,
    HzmBuild,
    HzmTest,
    LodSelect,
    Scan,
    StreamCollect,
    Defragment,
    Reform,
    Count,
};
const char* stageName(Stage s);  // "frustum_cull", ... (the CSV column is "ms_" + name)

// One row of `occswitch render --stats`: counts of the frame and the time of each stage.
struct FrameStats {
    uint64_t frame = 0;
    uint64_t objects_in_frustum = 0;
    uint64_t objects_occluded = 0;
    uint64_t objects_visible = 0;     // the PVS: in the frustum and not occluded
    uint64_t objects_drawn = 0;       // visible and above the pixel error threshold
    uint64_t aos_size = 0;            // active occluders rastered (Eq. 3 top-K + extra)
    uint64_t occluder_triangles = 0;  // triangles rastered into the depth buffer
    uint64_t active_triangles = 0;    // drawn this frame
    uint64_t active_vertices = 0;
    uint64_t resident_triangles = 0;  // in the active arrays (drawn + kept for later frames)
    uint64_t resident_vertices = 0;
    uint64_t budget_vertices = 0;
    uint64_t streamed_triangles = 0;  // host -> device this frame
    uint64_t streamed_vertices = 0;
    uint64_t streamed_bytes = 0;
    uint64_t moved_bytes = 0;         // device -> device by defragmentation
    uint64_t reformed_triangles = 0;  // reformed this frame (only blocks whose drawn LOD changed or that moved)
    // Every byte that crossed between host and device memory for this frame's work on this
    // rank, all purposes (streaming, layouts, results read back, the display's copies), counted
    // by the bus (kernels/device_memory.h); measurement passes (--exact, --reference) excluded.
    uint64_t bus_h2d_bytes = 0;
    uint64_t bus_d2h_bytes = 0;
    // XXH3-64 of the PVS's ids (not their LOD counts): what must be the same on every back end.
    uint64_t pvs_hash = 0;
    // PVS churn: objects in this frame's visible set that the previous frame drawn here did not
    // have, and the other way round (on the display; 0 on a culling rank, which draws nothing).
    uint64_t pvs_added = 0;
    uint64_t pvs_removed = 0;
    double ms[size_t(Stage::Count)] = {};
    double ms_total = 0;
};

// Adds the time since the last lap (or since construction) to a stage's column and to the total,
// once the kernels finished: each stage of a frame laps its clock when it is done.
class StageClock {
public:
    explicit StageClock(FrameStats& stats) : stats_(stats), mark_(std::chrono::steady_clock::now()) {}
    void lap(Stage s) {
        k::deviceSynchronize();
        const auto now = std::chrono::steady_clock::now();
        const double ms = std::chrono::duration<double, std::milli>(now - mark_).count();
        stats_.ms[uint32_t(s)] += ms;
        stats_.ms_total += ms;
        mark_ = now;
    }

private:
    FrameStats& stats_;
    std::chrono::steady_clock::time_point mark_;
};

// The bus columns of a row: how far this thread's bus counters (kernels/device_memory.h) grew
// since the last take, or since construction.
class BusWindow {
public:
    BusWindow() : last_(k::busCounters()) {}
    void take(FrameStats& s);

private:
    k::BusCounters last_;
};

// How many ids of ascending `now` are not in ascending `before` (added), and the other way round.
struct Churn {
    uint64_t added = 0, removed = 0;
};
Churn setChurn(const std::vector<uint32_t>& before, const std::vector<uint32_t>& now);

// Writes the CSV header line and rows; the columns are the fields above in order.
std::string frameStatsHeader();
std::string frameStatsRow(const FrameStats& s);

}  // namespace occ
