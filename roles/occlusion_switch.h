// SPDX-License-Identifier: MIT
#pragma once

#include "net/transport.h"
#include "pipeline/frame_record.h"
#include "pipeline/pipeline.h"
#include "view/camera.h"

#include <chrono>
#include <functional>
#include <optional>
#include <string>
#include <vector>

namespace occ::roles {

// Who does what, from the number of ranks (docs/architecture.md, "Roles and ranks"; docs/scaling.md):
//   1 rank:  rank 0 does OR, HC and RVG of every frame, in that order;
//   2 ranks: rank 0 is RVG; rank 1 does OR then HC of every frame;
//   3 ranks: rank 0 is RVG; ranks 1 and 2 form the occlusion switch (Govindaraju et al. 2003):
//            rank 1 + f % 2 culls frame f (HC) with the HZM it built in the step before, while
//            the other rank rasters the occluders of frame f + 1 (OR): they swap every frame;
//   2 + P ranks (P >= 2): the same switch culls every object, and P display ranks (sort-last:
//            rank 0 and ranks 3 .. P + 1) each stream, reform and draw the visible objects of
//            its own spatial partition (partitionObjects); their pictures are depth-composited
//            into rank 0's.
class RankLayout {
public:
    static constexpr int kMaxRanks = 64;
    // Throws UsageError for a size outside [1, kMaxRanks].
    explicit RankLayout(int size);
    int size() const { return size_; }
    // The rank that rasters frame f's occluders and then culls frame f.
    int culler(uint64_t frame) const { return size_ == 1 ? 0 : size_ == 2 ? 1 : 1 + int(frame % 2); }
    // How many frames back the PVS lies whose largest objects the OR rasters as extra
    // occluders: the switch's OR works on frame f + 1 while frame f is being culled, so its
    // newest PVS is frame f - 1's.
    uint32_t occluderLag() const { return size_ >= 3 ? 2 : 1; }
    // The occluder lag a run of this layout uses when `requested` was asked for: 0 takes
    // occluderLag(); less than it throws OptionError (the occluder rank has no newer PVS). The one
    // place the lag is defaulted and checked against the ranks; the pipeline checks its range.
    uint32_t resolveOccluderLag(uint32_t requested) const;
    // Frames between the display sending a camera and drawing it: 0 with one rank; with more,
    // the display sends frame f + 1's camera before it draws frame f, so that the other ranks
    // work on f + 1 meanwhile.
    uint32_t cameraLead() const { return size_ == 1 ? 0 : 1; }
    // Display ranks, one per partition: 1 up to 3 ranks, size - 2 beyond.
    int displays() const { return size_ <= 3 ? 1 : size_ - 2; }
    // The rank that displays partition p (0 <= p < displays()).
    int displayRank(int partition) const { return partition == 0 ? 0 : partition + 2; }
    // The partition `rank` displays, -1 for a culling rank.
    int partitionOf(int rank) const {
        if (rank == 0) return 0;
        return size_ > 3 && rank >= 3 ? rank - 2 : -1;
    }
    std::vector<int> displayRanks() const;
    std::vector<int> cullingRanks() const;  // {0}, {1} or {1, 2}
    // "or+hc+rvg", "rvg" or "or+hc": what `rank` does.
    const char* roleOf(int rank) const;

private:
    int size_;
};

// The sort-last partitions of the 2 + P layout: partition[i] of every object, `parts` groups
// balanced by full-detail triangles. A k-d split of the objects' box centres into parts x cells
// leaves: a group of k leaves is cut across its widest axis where the triangles before the cut
// are floor(k / 2) / k of the group's, recursively. cells = 1: leaf L is partition L, one
// coherent region each; more: the heaviest leaf first to the lightest partition, each partition
// the union of about `cells` regions spread over the scene, so that any view sees every
// partition (docs/scaling.md).
// Deterministic (the same on every rank). Throws std::invalid_argument for parts outside
// [1, 65535] or cells outside [1, 1024].
std::vector<uint16_t> partitionObjects(const OssFile& file, int parts, int cells = 1);

struct RunOptions {
    std::vector<CameraPose> cameras;
    bool deltas = true;  // false: every visible-set message carries the full set (--no-deltas)
    int sort_last_cells = 1;  // 2 + P ranks: regions per display partition (partitionObjects)
    // How long a rank waits for a message before it declares the sender dead.
    std::chrono::milliseconds timeout{5000};
    // The display's drawing (RVG: rank 0, and the sort-last display ranks), called after each
    // frame's streaming with the pipeline whose visible set and active arrays are that frame's
    // and the frame's figures so far; returns what it drew and measured (the frame's record
    // keeps it). display_columns: which of those figures the stats CSV shows (none: a run that
    // does not draw, or a window).
    std::function<DisplayStats(Pipeline& pipeline, const CameraPose& pose, uint64_t frame, const FrameStats& stats)> draw;
    std::optional<DisplayColumns> display_columns;
    // Called on rank 0 after every displayed frame (progress).
    std::function<void(uint64_t frames_done)> on_frame;
    // A live run (a window under mpirun, or a path replayed in real time with --pace recorded;
    // every rank sets it): the cameras come one by one instead of from `cameras`, and the run
    // ends when rank 0 says so. Rank 0's next_camera(frame, pose) gives that frame's camera, the
    // newest pose when it is asked: poses made while the switch was busy are skipped, never
    // queued (the paper's camera buffer of one); false ends the run before `frame`. idle() is
    // called while the display waits for a culling rank (a window keeps answering and shows the
    // newest complete frame).
    bool live = false;
    // false (every rank the same): no frame records are kept or reported, for a long live run
    // that writes no stats (a window); runRanks then returns none and the summary counts the
    // frames only.
    bool keep_records = true;
    std::function<bool(uint64_t frame, CameraPose& pose)> next_camera;
    std::function<void()> idle;
};

// What rank 0 prints after a run, made from every rank's frame records (summarize).
struct RunSummary {
    uint64_t frames = 0;
    double ms_frame = 0;                  // rank 0: mean wall time per displayed frame
    double objects_in_frustum = 0, objects_visible = 0, active_triangles = 0, streamed_triangles = 0;  // sums
    uint64_t bytes_delta = 0, full_pvs_bytes = 0, bytes_camera = 0, bytes_eof = 0;  // all ranks
    uint64_t bytes_composite = 0;         // all ranks: pixels sent for compositing
    double ms_composite = 0;              // rank 0: sum over frames
    int displays = 1;                     // partitions (display ranks)
    // Rank 0, from the reports: the most active triangles one display rank held (mean over
    // frames), per partition; with one display its own.
    std::vector<double> partition_triangles;
    double latency_ms = 0;                // mean camera send -> frame drawn, frames after the first
    uint32_t latency_frames = 0;          // for frames after the first
    double ms_wait = 0;                   // rank 0: mean per frame
    // Rank 0, frames after the first: host <-> device bytes and the streamed geometry among them.
    uint64_t bus_h2d_bytes = 0, bus_d2h_bytes = 0, streamed_bytes = 0;
    double pvs_churn = 0;                 // rank 0, frames after the first: sum of pvs_added + pvs_removed
    // Rank 0's display, over the frames it drew: sums (exact_churn: frames after the first) and
    // the lowest PSNR.
    double ms_draw = 0, false_culls = 0, exact_occluded = 0, culling_accuracy = 0, exact_churn = 0;
    double psnr_db = 0, min_psnr_db = 0, changed_pixel_share = 0;
    double mse = 0, perceptible_share = 0, ssim = 0, max_bound_p99_px = 0;
    uint64_t bound_pixels = 0, bound_beyond_tau = 0;
    // The run's pictures pooled as one long picture: PSNR from the mean squared error.
    double pooledPsnrDb() const;
};

// The run's summary from every rank's records (runRanks' on rank 0).
RunSummary summarize(const std::vector<FrameRecord>& records, const RankLayout& layout);

// The --stats CSV of a run: "rank,role," + frameStatsHeader() + the message columns
// (netFiguresHeader) + the display's (run.display_columns), and one row per record, in order.
std::string rankStatsHeader(const RunOptions& run);
std::string rankStatsRows(const std::vector<FrameRecord>& records, const RankLayout& layout, const RunOptions& run);

// Runs the camera path as rank transport.rank() of transport.size() ranks (all ranks call it
// with the same file, options and cameras). Returns this rank's frame records; rank 0's are
// every rank's (one per rank and frame, ordered by frame, then rank), from which it fills
// `summary`. Throws RankError when a rank fails (after telling the others), UsageError for a
// layout that does not exist.
std::vector<FrameRecord> runRanks(Transport& transport, const OssFile& file, const PipelineOptions& options,
                                  const RunOptions& run, RunSummary& summary);

}  // namespace occ::roles
