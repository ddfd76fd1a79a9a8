// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "util/progress.h"

#include "device_memory.h"
#include "net/emulated_link.h"
#include "net/process_transport.h"
#include "net/transport.h"
#include "pipeline/pipeline.h"
#include "render/colour_mode.h"
#include "render/picture_metrics.h"
#include "roles/occlusion_switch.h"
#include "cli/model_cache.h"
#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "util/number_format.h"
#include "view/camera_path.h"

#ifdef OCC_HAVE_GL
#include "render/frame_display.h"
#include "render/headless_context.h"
#include "render/png_writer.h"
#include "render/sort_last.h"
#include "render/window.h"
#include "util/config.h"
#endif

#include <nlohmann/json.hpp>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#if __has_include(<malloc.h>)
#include <malloc.h>  // mallopt (glibc)
#endif
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <set>
#include <thread>

namespace occ::cli {

namespace {

// The occluders' raster time a window aims at per frame (--occluder-ms): a tenth of a 10 fps frame.
constexpr double kWindowOccluderMs = 10.0;

// The command line as given (CLI11 fills it).
struct RenderOptions {
    std::string scene, path, stats, size = "512x512", mode = "oc+lod", stream = "sc", pvs_occluders = "auto", budget = "auto";
    std::string pace = "fast", lod = "budget", visibility_weighted = "off", hierarchy = "auto", late_pass = "on", colours = "model";
    std::string raster = "exact";
    double path_fps = 60;
    bool no_display = false, headless = false, exact = false, reference = false, no_deltas = false;
    double occluder_ms = -1;  // -1: the default of the mode (on in a window)
    double rank_timeout = 5.0;
    std::string link;  // --link LATENCY_MS[:MBPS[:JITTER_MS]]
    std::string link_file;  // --link-file F: per pair of ranks
    int sort_last_cells = 1;
    int device = -1;
    std::string out, debug_views, summary;
    std::vector<uint64_t> debug_frames;
    PipelineOptions pipeline;
};

// The run a command line asks for, every option parsed and checked (resolveRender), and once the
// ranks are known their layout's (resolveForLayout), before the scene is opened.
struct RenderConfig {
    RenderOptions cli;  // as given: names for messages and the summary
    PipelineOptions pipeline;
    LinkSpec link;
    bool draws = false;   // draws frames (not --no-display)
    bool window = false;  // in a window (drawing, not --headless)
    bool paced = false;   // --pace recorded
    bool hierarchy_auto = false;  // --hierarchy auto: pipeline.hierarchy follows the .oss, once opened
    render::ColourMode colours = render::ColourMode::Model;  // --colours
    std::chrono::milliseconds rank_timeout{5000};
};

std::string onOff(const std::string& option, const std::string& value) {
    if (value != "on" && value != "off") throw UsageError(option + " " + value + ": expected on or off");
    return value;
}

RenderConfig resolveRender(const RenderOptions& o) {
    RenderConfig c;
    c.cli = o;
    PipelineOptions& p = c.pipeline = o.pipeline;
    parseViewportSize("--size", o.size, p.width, p.height);
    p.pvs_occluder_triangles = parseOccluderTriangles(o.pvs_occluders);
    parseBudget(o.budget, p.budget, p.budget_share);
    p.mode = parseCullMode(o.mode);
    p.lod = parseLodRule(o.lod);
    p.visibility_weighted = onOff("--visibility-weighted", o.visibility_weighted) == "on";
    if (o.raster != "masked" && o.raster != "exact")
        throw UsageError("--raster " + o.raster + ": expected masked or exact");
    p.raster = o.raster == "masked" ? OccluderRaster::Masked : OccluderRaster::Exact;
    p.late_pass = onOff("--late-pass", o.late_pass) == "on";
    if (o.hierarchy != "auto" && o.hierarchy != "on" && o.hierarchy != "off")
        throw UsageError("--hierarchy " + o.hierarchy + ": expected auto, on or off");
    c.hierarchy_auto = o.hierarchy == "auto";
    p.hierarchy = o.hierarchy == "on";
    p.stream = parseStreamMode(o.stream);
    if (o.occluder_ms >= 0) p.occluder_ms = o.occluder_ms;
    if (o.no_display && o.headless) throw UsageError("render: --no-display and --headless exclude each other");
    c.draws = !o.no_display;
    c.window = c.draws && !o.headless;
    if (!c.draws && (o.exact || o.reference || !o.out.empty() || !o.debug_views.empty()))
        throw UsageError("render: --exact, --reference, --out and --debug-views need drawing; drop --no-display");
    if (!o.debug_frames.empty() && o.debug_views.empty())
        throw UsageError("render: --debug-frames chooses frames for --debug-views DIR, which is missing");
#ifndef OCC_HAVE_GL
    if (c.draws)
        throw UsageError("render: this occswitch was built without the OpenGL display (OCC_GL=OFF); "
                         "run with --no-display");
#endif
    if (o.pace != "fast" && o.pace != "recorded")
        throw UsageError("--pace " + o.pace + ": expected fast (every pose, as fast as the frames go) or recorded "
                         "(the path in real time at --path-fps)");
    c.paced = o.pace == "recorded";
    c.colours = o.colours == "uniform" ? render::ColourMode::Uniform
                : o.colours == "object" ? render::ColourMode::Object
                                        : render::ColourMode::Model;
    if (!(o.path_fps > 0 && o.path_fps <= 100000)) {
        char v[64];
        std::snprintf(v, sizeof v, "%g", o.path_fps);
        throw UsageError(std::string("--path-fps ") + v + ": expected poses per second in (0, 100000]");
    }
    if (o.path.empty() && !c.window)
        throw UsageError(std::string("render: --path P.cam is required with ") +
                         (o.headless ? "--headless" : "--no-display"));
    if (!(o.rank_timeout > 0 && o.rank_timeout <= 3600))
        throw UsageError("render: --rank-timeout must be in (0, 3600] seconds");
    c.rank_timeout = std::chrono::milliseconds(int64_t(o.rank_timeout * 1000));
    if (!o.link.empty()) {
        try {
            c.link = parseLinkSpec(o.link);
        } catch (const std::invalid_argument& e) {
            throw UsageError(std::string("--link ") + e.what());
        }
    }
    if (c.window) {
        // In a window the frame rate is what matters: the occluders follow the raster's speed.
        if (o.occluder_ms < 0) p.occluder_ms = kWindowOccluderMs;
        if (o.exact || o.reference || !o.debug_views.empty())
            throw UsageError("render: --exact, --reference and --debug-views measure recorded runs: add --headless "
                             "and --path P.cam");
        if (c.paced)
            throw UsageError("render: --pace recorded replays --path headless (--headless or --no-display); a window "
                             "plays the path one pose per frame, then you fly");
        if (!o.summary.empty())
            throw UsageError("render: --summary describes recorded runs: add --headless or --no-display and --path P.cam");
    }
    return c;
}

// What the ranks' layout adds: the occluder lag, and the options a layout cannot run.
void resolveForLayout(RenderConfig& c, const roles::RankLayout& layout) {
    const RenderOptions& o = c.cli;
    c.pipeline.pvs_occluder_lag = layout.resolveOccluderLag(c.pipeline.pvs_occluder_lag);
    validatePipelineOptions(c.pipeline);
    if (c.window && layout.size() == 1 && !o.stats.empty())
        throw UsageError("render: --stats in a window needs 2 or more ranks (mpirun); on one rank record a path (R) "
                         "and render it with --headless --stats");
    if (layout.size() > 1 && !o.debug_views.empty())
        throw UsageError("render: --debug-views draws the occluders' depth, which only the culling ranks have: "
                         "run it with one rank");
    if (layout.displays() > 1 && (o.exact || o.reference))
        throw UsageError("render: --exact and --reference draw the whole scene on one display; with " +
                         std::to_string(layout.size()) + " ranks each display rank holds a part: run them with 3 ranks");
}

roles::RunOptions runOptions(const RenderConfig& c) {
    roles::RunOptions run;
    run.deltas = !c.cli.no_deltas;
    run.sort_last_cells = c.cli.sort_last_cells;
    run.timeout = c.rank_timeout;
    return run;
}

std::string frameName(uint64_t frame) {
    char b[32];
    std::snprintf(b, sizeof b, "frame_%06llu", static_cast<unsigned long long>(frame));
    return b;
}

// The stats CSV appears whole or not at all: opened (a temporary beside it) before the run, so
// that a path that cannot be written fails at once; it replaces the file only when the run
// succeeds.
class StatsFile {
public:
    StatsFile(const std::string& path, const std::string& header) {
        if (path.empty()) return;
        file_ = std::make_unique<AtomicFile>(path);
        file_->write(header + "\n");
    }
    void commit(const std::string& rows) {
        if (!file_) return;
        file_->write(rows);
        file_->commit();
        file_.reset();
    }

private:
    std::unique_ptr<AtomicFile> file_;
};

// --pace recorded: pose i of the path is due i / path_fps seconds after the first; each frame
// takes the newest pose due when it starts (a slow frame skips poses, as a user's would), and a
// frame quicker than the path waits for the next pose.
class PathPacer {
public:
    PathPacer(const std::vector<CameraPose>& cameras, double fps) : cameras_(cameras), fps_(fps) {}

    bool next(uint64_t f, CameraPose& pose) {
        using namespace std::chrono;
        const auto now = steady_clock::now();
        if (f == 0) start_ = now;
        uint64_t i = uint64_t(duration<double>(now - start_).count() * fps_);
        if (f > 0 && i <= shown_.back()) {
            i = shown_.back() + 1;
            if (i < cameras_.size())
                std::this_thread::sleep_until(start_ + duration_cast<steady_clock::duration>(duration<double>(double(i) / fps_)));
        }
        if (i >= cameras_.size()) return false;
        pose = cameras_[i];
        shown_.push_back(i);
        return true;
    }
    // The path's poses done after `frames` frames: the newest one shown.
    uint64_t posesDone(uint64_t frames) const { return shown_.at(frames - 1) + 1; }

    uint64_t framesShown() const { return shown_.size(); }
    uint64_t posesSkipped() const { return cameras_.size() - shown_.size(); }
    // The longest run of poses no frame showed.
    uint64_t longestSkip() const {
        uint64_t longest = shown_.empty() ? 0 : shown_.front();
        for (size_t j = 1; j < shown_.size(); ++j) longest = std::max(longest, shown_[j] - shown_[j - 1] - 1);
        return longest;
    }

    void print() const {
        const uint64_t longest = longestSkip(), shown = framesShown(), skipped = posesSkipped();
        std::printf("pace: recorded, the path's %zu poses at %g per second (%.2f s): %llu frames shown, %llu poses "
                    "skipped (%.1f%%), at most %llu in a row\n",
                    cameras_.size(), fps_, double(cameras_.size()) / fps_, static_cast<unsigned long long>(shown),
                    static_cast<unsigned long long>(skipped), 100.0 * double(skipped) / double(cameras_.size()),
                    static_cast<unsigned long long>(longest));
    }

private:
    const std::vector<CameraPose>& cameras_;
    double fps_;
    std::chrono::steady_clock::time_point start_;
    std::vector<uint64_t> shown_;  // the pose each frame showed
};

#ifdef OCC_HAVE_GL
// The drawing of a headless run on a display rank: each frame offscreen, composited (sort-last),
// measured and written as the options ask. `install` makes it the run's drawing.
class HeadlessDrawing {
public:
    HeadlessDrawing(const RenderConfig& c, const roles::RankLayout& layout, Transport& transport, int device_ordinal,
                    std::set<uint64_t> debug_frames)
        : c_(c), debug_frames_(std::move(debug_frames)) {
        options_.exact = c.cli.exact;
        options_.reference = c.cli.reference;
        options_.colours = c.colours;
        options_.tau = c.pipeline.tau;
        // Sort-last: every display rank draws its partition; the pictures are composited into rank 0's.
        const std::vector<int> display_ranks = layout.displayRanks();
        options_.items = display_ranks.size() > 1;
        if (layout.partitionOf(transport.rank()) < 0) return;
        if (display_ranks.size() > 1)
            compositor_ = std::make_unique<render::SortLastCompositor>(transport, display_ranks, c.rank_timeout);
        context_ = std::make_unique<render::HeadlessContext>(device_ordinal);
    }
    ~HeadlessDrawing() { display_.reset(); }

    void install(roles::RunOptions& run) {
        run.display_columns = render::displayColumns(options_);  // every rank's rows have the columns
        if (!context_) return;
        run.draw = [this](Pipeline& pipeline, const CameraPose& pose, uint64_t f, const FrameStats&) {
            return draw(pipeline, pose, f);
        };
    }
    std::string description() const { return context_ ? context_->description() : std::string(); }

private:
    DisplayStats draw(Pipeline& pipeline, const CameraPose& pose, uint64_t f) {
        const PipelineOptions& p = c_.pipeline;
        if (!display_) display_ = std::make_unique<render::FrameDisplay>(pipeline, p.width, p.height, options_);
        const DisplayStats d = display_->display(pipeline, pose);
        const std::vector<uint8_t>* picture = &display_->picture();
        if (compositor_) {
            picture = compositor_->composite(*display_);
            if (!picture) return d;  // not rank 0
        }
        if (!c_.cli.out.empty())
            render::writePng(c_.cli.out + "/" + frameName(f) + ".png", p.width, p.height, 3, picture->data());
        if (debug_frames_.count(f)) display_->writeDebugViews(pipeline, pose, c_.cli.debug_views, frameName(f));
        return d;
    }

    const RenderConfig& c_;
    std::set<uint64_t> debug_frames_;
    render::DisplayOptions options_;
    std::unique_ptr<render::SortLastCompositor> compositor_;
    std::unique_ptr<render::HeadlessContext> context_;
    std::unique_ptr<render::FrameDisplay> display_;
};

// `render` in a window: rank 0 opens the one window and displays (with one rank it also culls);
// under mpirun the other ranks cull (no window, no GL) or, 2 + P, draw their partitions offscreen.
int runInWindow(const RenderConfig& c, const OssFile& file, Transport& transport, int device_ordinal) {
    const roles::RankLayout layout(transport.size());
    render::WindowOptions w;
    w.width = c.pipeline.width;
    w.height = c.pipeline.height;
    w.path = c.cli.path;
    w.out = c.cli.out.empty() ? "." : c.cli.out;
    w.device = c.cli.device;
    w.colours = c.colours;
    const bool rank0 = transport.rank() == 0;
    if (rank0 && !c.cli.out.empty()) makeOutputFolder(c.cli.out);
    roles::RunOptions run = runOptions(c);
    run.live = true;
    // A window's records are kept only for --stats (a session may run for hours).
    run.keep_records = !c.cli.stats.empty();
    try {
        if (!rank0) {
            // A sort-last display rank (2 + P) draws its partition offscreen for rank 0's window.
            std::unique_ptr<render::HeadlessContext> context;
            std::unique_ptr<render::FrameDisplay> display;
            std::unique_ptr<render::SortLastCompositor> compositor;
            if (layout.partitionOf(transport.rank()) > 0) {
                context = std::make_unique<render::HeadlessContext>(device_ordinal);
                compositor = std::make_unique<render::SortLastCompositor>(transport, layout.displayRanks(), run.timeout);
                run.draw = [&](Pipeline& pipeline, const CameraPose& pose, uint64_t, const FrameStats&) {
                    render::DisplayOptions d;
                    d.items = true;
                    d.colours = c.colours;
                    if (!display) display = std::make_unique<render::FrameDisplay>(pipeline, w.width, w.height, d);
                    const DisplayStats drawn = display->display(pipeline, pose);
                    compositor->composite(*display);
                    return drawn;
                };
            }
            roles::RunSummary ignored;
            roles::runRanks(transport, file, c.pipeline, run, ignored);
            display.reset();
            return 0;
        }
        StatsFile stats(c.cli.stats, roles::rankStatsHeader(run));
        roles::RunSummary sum;
        std::vector<FrameRecord> records;
        try {
            records = render::runWindow(transport, file, c.pipeline, w, run, sum);
        } catch (const render::WindowUnavailable& e) {
            transport.fail(0, e.what());  // the culling ranks stop at once instead of timing out
            throw;
        }
        stats.commit(roles::rankStatsRows(records, layout, run));
        return 0;
    } catch (const render::WindowUnavailable& e) {
        throw SystemError(std::string(e.what()) + "; --headless renders without a window");
    }
}
#endif

// The debug views' frames: those asked for (default first, middle, last), each on the path.
std::set<uint64_t> debugFrames(const RenderOptions& o, size_t cameras) {
    std::set<uint64_t> frames(o.debug_frames.begin(), o.debug_frames.end());
    if (!o.debug_views.empty() && frames.empty()) frames = {0, cameras / 2, cameras - 1};
    for (uint64_t f : frames)
        if (f >= cameras)
            throw UsageError("render: --debug-frames " + std::to_string(f) + " is past the path's last frame " +
                             std::to_string(cameras - 1));
    return frames;
}

// What a run printed, as printed and (--summary) as JSON.
struct RunReport {
    const RenderConfig& config;
    const roles::RankLayout& layout;
    const OssFile& file;
    const roles::RunSummary& sum;
    const roles::RunOptions& run;
    const k::DeviceInfo& device;
    std::string links, renderer;  // the emulated links, the GL renderer (empty: none)
    const PathPacer* pacer = nullptr;
};

void printRunSummary(const RunReport& r) {
    const RenderOptions& o = r.config.cli;
    const roles::RunSummary& sum = r.sum;
    const double frames = double(std::max<uint64_t>(1, sum.frames));
    std::printf("render: %s, %zu frames at %ux%u, mode %s, stream %s, backend %s, %d rank%s: mean %.2f ms/frame "
                "(%.1f fps); %.1f of %u objects in the frustum, %.1f%% of those occluded, %.1f visible; "
                "%.0f active triangles, %.4f%% of them streamed per frame\n",
                o.scene.c_str(), size_t(sum.frames), r.config.pipeline.width, r.config.pipeline.height, o.mode.c_str(),
                o.stream.c_str(), k::deviceBackend(), r.layout.size(), r.layout.size() > 1 ? "s" : "",
                sum.ms_frame / frames, 1000.0 * frames / sum.ms_frame, sum.objects_in_frustum / frames,
                r.file.objectCount(),
                sum.objects_in_frustum > 0 ? 100.0 * (sum.objects_in_frustum - sum.objects_visible) / sum.objects_in_frustum
                                           : 0.0,
                sum.objects_visible / frames, sum.active_triangles / frames,
                sum.active_triangles > 0 ? 100.0 * sum.streamed_triangles / sum.active_triangles : 0.0);
    std::printf("messages: %s; visible-set messages %.0f bytes/frame, full sets would be %.0f (%.1f%% less); "
                "cameras %.0f, end-of-frames %.0f bytes/frame; camera-to-display latency %u frame%s, %.2f ms; "
                "display waited %.2f ms/frame\n",
                r.run.deltas ? "deltas" : "full sets (--no-deltas)", double(sum.bytes_delta) / frames,
                double(sum.full_pvs_bytes) / frames,
                sum.full_pvs_bytes ? 100.0 * (1.0 - double(sum.bytes_delta) / double(sum.full_pvs_bytes)) : 0.0,
                double(sum.bytes_camera) / frames, double(sum.bytes_eof) / frames, sum.latency_frames,
                sum.latency_frames == 1 ? "" : "s", frames > 1 ? sum.latency_ms / (frames - 1) : 0.0,
                sum.ms_wait / frames);
    if (!r.links.empty())
        std::printf("link: %s (each message delayed by the latency, its bytes at the bandwidth, one queue per "
                    "destination)\n",
                    r.links.c_str());
    if (r.pacer) r.pacer->print();
    if (sum.displays > 1) {
        std::string parts;
        for (size_t p = 0; p < sum.partition_triangles.size(); ++p)
            parts += (p ? ", " : "") + std::to_string(int64_t(std::llround(sum.partition_triangles[p])));
        std::printf("sort-last: %d display ranks (partitions balanced by triangles); active triangles per display "
                    "rank %s (mean per frame); composite %.0f bytes/frame over all ranks, %.2f ms/frame on rank 0\n",
                    sum.displays, parts.c_str(), double(sum.bytes_composite) / frames, sum.ms_composite / frames);
    }
    const double later = std::max(1.0, frames - 1);
    const k::DeviceInfo& device = r.device;
    std::printf("device: %s%s%s; host <-> device bus on rank 0: %.0f bytes/frame to the device, %.0f back "
                "(frames after the first), of which streamed geometry %.0f\n",
                device.ordinal >= 0 ? ("CUDA device " + std::to_string(device.ordinal) + ", ").c_str() : "",
                device.name.c_str(), device.uuid.empty() ? "" : (", UUID " + device.uuid).c_str(),
                double(sum.bus_h2d_bytes) / later, double(sum.bus_d2h_bytes) / later, double(sum.streamed_bytes) / later);
    if (r.config.draws)
        std::printf("display: %s, mean %.2f ms/frame to draw\n", r.renderer.c_str(), sum.ms_draw / frames);
    if (o.exact)
        std::printf("exact: %.0f false culls in all (must be 0), %.1f exactly occluded objects per frame, "
                    "culling accuracy %.2f%% (mean over frames); churn per frame (added + removed) of the PVS "
                    "%.1f, of the exact visible set %.1f\n",
                    sum.false_culls, sum.exact_occluded / frames, sum.culling_accuracy / frames, sum.pvs_churn / later,
                    sum.exact_churn / later);
    if (o.reference) {
        const double beyond = sum.bound_pixels ? 100.0 * double(sum.bound_beyond_tau) / double(sum.bound_pixels) : 0.0;
        std::printf("reference: PSNR %.2f dB pooled (%.2f mean, %.2f lowest); %.3f%% of pixels changed, %.3f%% "
                    "perceptibly (CIEDE2000 > 2); SSIM %.4f (mean); bound: %.2f%% of changed pixels lie farther "
                    "than %g px (tau, at least a pixel) from their item (99th percentile within it: %s; worst frame's "
                    "p99 %.2f px)\n",
                    sum.pooledPsnrDb(), sum.psnr_db / frames, sum.min_psnr_db, sum.changed_pixel_share / frames,
                    sum.perceptible_share / frames, sum.ssim / frames, beyond, double(render::boundCheckPixels(r.config.pipeline.tau)),
                    beyond <= 1.0 ? "yes" : "no", sum.max_bound_p99_px);
    }
    if (!o.out.empty()) std::printf("frames: %s/frame_*.png\n", o.out.c_str());
    if (!o.debug_views.empty()) std::printf("debug views: %s/\n", o.debug_views.c_str());
}

// --summary F.json: the run's figures for programs (bench all reads the backend and renderer).
void writeSummaryJson(const std::string& path, const RunReport& r) {
    if (path.empty()) return;
    const roles::RunSummary& sum = r.sum;
    const double frames = double(std::max<uint64_t>(1, sum.frames));
    nlohmann::ordered_json j;
    j["scene"] = r.config.cli.scene;
    j["frames"] = sum.frames;
    j["ranks"] = r.layout.size();
    j["backend"] = k::deviceBackend();
    j["device"] = r.device.name;
    j["renderer"] = r.renderer;
    j["ms_frame"] = sum.ms_frame / frames;
    j["objects_in_frustum"] = sum.objects_in_frustum / frames;
    j["objects_visible"] = sum.objects_visible / frames;
    j["active_triangles"] = sum.active_triangles / frames;
    j["delta_bytes"] = double(sum.bytes_delta) / frames;
    j["full_set_bytes"] = double(sum.full_pvs_bytes) / frames;
    j["latency_frames"] = sum.latency_frames;
    if (r.config.draws) j["ms_draw"] = sum.ms_draw / frames;
    if (r.config.cli.exact) {
        j["false_culls"] = sum.false_culls;
        j["culling_accuracy"] = sum.culling_accuracy / frames;
    }
    if (r.config.cli.reference) {
        j["min_psnr_db"] = sum.min_psnr_db;
        j["psnr_db"] = sum.pooledPsnrDb();
        j["perceptible_share"] = sum.perceptible_share / frames;
        j["ssim"] = sum.ssim / frames;
        j["bound_beyond_tau_share"] =
            sum.bound_pixels ? 100.0 * double(sum.bound_beyond_tau) / double(sum.bound_pixels) : 0.0;
    }
    if (r.pacer)
        j["pace"] = {{"poses", r.pacer->framesShown() + r.pacer->posesSkipped()},
                     {"frames_shown", r.pacer->framesShown()},
                     {"poses_skipped", r.pacer->posesSkipped()},
                     {"longest_skip", r.pacer->longestSkip()}};
    writeFileAtomic(path, j.dump(2) + "\n");
}

int runRender(const RenderOptions& options) {
#if defined(M_TRIM_THRESHOLD)
    // Memory freed in the frame loop (a stage's scratch that grew, a kernel's host-side table)
    // stays with the process for the next frame instead of going back to the system: fresh
    // memory costs a page fault per 4 KiB on first write (30-45 us each on a virtual machine),
    // which made frames that grew a buffer several times slower than their neighbours.
    mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest: bigger blocks are mapped as before
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
#endif
    RenderConfig c = resolveRender(options);
    // Before anything touches the device: each rank on a node its own GPU.
    const k::DeviceInfo device = k::selectDevice(c.cli.device);
    // Under mpirun every rank runs this command; rank 0 displays, writes and prints.
    ProcessTransport process = openProcessTransport(c.link, c.cli.link_file);
    Transport& transport = *process.transport;
    const roles::RankLayout layout(transport.size());
    resolveForLayout(c, layout);
    const OssFile file = OssFile::open(preparedScene(c.cli.scene));
    // --hierarchy auto (issue 49, item 6): the hierarchy of a .oss that has one, on 1 to 3
    // ranks (sort-last's 2 + P partitions are of objects: flat there).
    if (c.hierarchy_auto) c.pipeline.hierarchy = file.nodeCount() > 0 && layout.displays() <= 1;
#ifdef OCC_HAVE_GL
    if (c.window) return runInWindow(c, file, transport, device.ordinal);
#endif
    const std::vector<CameraPose> cameras = readCameraPath(c.cli.path);
    const std::set<uint64_t> debug_frames = debugFrames(c.cli, cameras.size());
    const bool rank0 = transport.rank() == 0;
    // Folders only once every option is known to be good: a refused run creates nothing.
    if (rank0 && !c.cli.out.empty()) makeOutputFolder(c.cli.out);
    if (rank0 && !c.cli.debug_views.empty()) makeOutputFolder(c.cli.debug_views);

    roles::RunOptions run = runOptions(c);
    run.cameras = cameras;
    PathPacer pacer(cameras, c.cli.path_fps);
    if (c.paced) {
        run.live = true;
        run.next_camera = [&](uint64_t f, CameraPose& pose) { return pacer.next(f, pose); };
    }
#ifdef OCC_HAVE_GL
    std::unique_ptr<HeadlessDrawing> drawing;
    if (c.draws) {
        drawing = std::make_unique<HeadlessDrawing>(c, layout, transport, device.ordinal, debug_frames);
        drawing->install(run);
    }
#endif
    StatsFile stats(rank0 ? c.cli.stats : std::string(), roles::rankStatsHeader(run));
    // Progress counts the path's poses (paced: the newest one shown).
    std::atomic<uint64_t> frames_done{0};
    run.on_frame = [&](uint64_t done) { frames_done = c.paced ? pacer.posesDone(done) : done; };
    std::unique_ptr<ProgressBar> progress;
    if (rank0)
        progress = std::make_unique<ProgressBar>("render", "frames", "frames", [&] {
            const double done = double(frames_done.load());
            return ProgressBar::Sample{done, double(cameras.size()), done};
        });
    roles::RunSummary sum;
    const std::vector<FrameRecord> records = roles::runRanks(transport, file, c.pipeline, run, sum);
    progress.reset();
    if (!rank0) return 0;
    stats.commit(roles::rankStatsRows(records, layout, run));
    RunReport report{c, layout, file, sum, run, device, process.links, {}, c.paced ? &pacer : nullptr};
#ifdef OCC_HAVE_GL
    if (drawing) report.renderer = drawing->description();
#endif
    printRunSummary(report);
    writeSummaryJson(c.cli.summary, report);
    return 0;
}

}  // namespace

void parseViewportSize(const std::string& option, const std::string& text, uint32_t& width, uint32_t& height) {
    unsigned long a = 0, b = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%lu%c%lu%c", &a, &x, &b, &extra) != 3 || x != 'x' || a == 0 || b == 0 ||
        a > kMaxViewportSide || b > kMaxViewportSide)
        throw UsageError(option + " " + text + ": expected WxH with 1 <= W, H <= " + std::to_string(kMaxViewportSide) +
                         ", e.g. 512x512");
    width = uint32_t(a);
    height = uint32_t(b);
}

uint64_t parseOccluderTriangles(const std::string& text) {
    if (text == "auto") return PipelineOptions::kAutoOccluderTriangles;
    unsigned long long n = 0;
    char extra = 0;
    if (text.empty() || text[0] == '-' || std::sscanf(text.c_str(), "%llu%c", &n, &extra) != 1 ||
        n >= PipelineOptions::kAutoOccluderTriangles)
        throw UsageError("--pvs-occluders " + text + ": expected auto or a number of triangles (0 = off)");
    return n;
}

void parseBudget(const std::string& text, double& vertices, double& share) {
    vertices = share = 0;
    if (text == "auto") return;
    double v = 0;
    char unit = 0, extra = 0;
    const int n = std::sscanf(text.c_str(), "%lf%c%c", &v, &unit, &extra);
    if (n == 2 && unit == '%' && v > 0 && v <= 100) {
        share = v / 100;
        return;
    }
    if (n == 1 && v >= 1 && v < 1e15 && text[0] != '-') {
        vertices = std::floor(v);
        return;
    }
    throw UsageError("--budget " + text + ": expected auto, a number of vertices (>= 1) or a share of the scene's "
                     "vertices such as 10%");
}

Command addRenderCommand(CLI::App& app) {
    auto o = std::make_shared<RenderOptions>();
    o->pipeline.pvs_occluder_lag = 0;  // 0 = what the rank layout has
    CLI::App* sub = app.add_subcommand(
        "render", "Render a scene through the frame pipeline: frustum culling, active occluders (Eq. 3),\n"
                  "HZM occlusion culling, LOD selection under a vertex budget (Eq. 1), streaming,\n"
                  "triangle reformation and OpenGL drawing.\n"
                  "  occswitch render S.oss                          a window: fly with the mouse and WASD/QE\n"
                  "  occswitch render S.oss --path P.cam --headless --out frames/   PNG frames, no X server\n"
                  "  occswitch render S.oss --path P.cam --no-display --stats s.csv every stage but drawing\n"
                  "  mpirun -np 3 occswitch render S.oss --path P.cam --headless    the occlusion switch:\n"
                  "      rank 0 displays, ranks 1 and 2 swap occluder raster and culling every frame\n"
                  "  mpirun -np 3 occswitch render S.oss       one window on rank 0, flown through the switch\n"
                  "      (launch/mpi-render adds the flags mpirun needs)");
    sub->add_option("scene", o->scene,
                    "preprocessed scene (.oss), or a model file (glTF, OBJ, PLY, OFF, STL), prepared once into\n"
                    "MODEL.oss beside it and reused while the model is unchanged")->required();
    sub->add_option("--path", o->path, "camera path file (see `occswitch path`); in a window, played then flown");
    sub->add_option("--pace", o->pace,
                    "fast: every pose of --path, each frame as soon as the last is done; recorded: the path in\n"
                    "real time at --path-fps, each frame taking the newest pose due (slow frames skip poses, as a\n"
                    "user's camera would)")
        ->capture_default_str();
    sub->add_option("--path-fps", o->path_fps, "poses per second of --path for --pace recorded (paths are made at 60)")
        ->capture_default_str();
    sub->add_flag("--headless", o->headless, "draw offscreen with EGL (no window, no X server)");
    sub->add_flag("--no-display", o->no_display, "run every stage except drawing");
    sub->add_option("--out", o->out, "write each frame as DIR/frame_NNNNNN.png (window: where P saves screenshots)");
    sub->add_flag("--exact", o->exact,
                  "also draw the full-detail model into an item buffer and depth buffer every frame and add the\n"
                  "columns exact_visible, false_culls, exact_occluded, culling_accuracy");
    sub->add_flag("--reference", o->reference,
                  "also draw the full-detail unculled frame and compare: the columns psnr_db, changed_pixel_share,\n"
                  "mse, perceptible_share (CIEDE2000 > 2), ssim, bound_p99_px, bound_pixels and bound_beyond_tau\n"
                  "(changed pixels farther than --tau, at least a pixel, from their item in the reference); pooled\n"
                  "in the summary");
    sub->add_option("--debug-views", o->debug_views,
                    "write the occluders' depth, the HZM levels and the culling view of chosen frames into DIR");
    sub->add_option("--debug-frames", o->debug_frames, "frames for --debug-views (default: first, middle, last)")
        ->delimiter(',');
    sub->add_option("--stats", o->stats,
                    "write per-frame statistics to this CSV file (under mpirun: every rank's rows, with a rank column)");
    sub->add_option("--summary", o->summary,
                    "also write the run's summary (backend, renderer, mean figures per frame) as JSON to this file");
    sub->add_flag("--no-deltas", o->no_deltas, "send the full visible set every frame instead of what changed");
    sub->add_option("--sort-last-cells", o->sort_last_cells,
                    "with more than 3 ranks: regions of the scene per display rank (1 = one coherent region\n"
                    "each; more spreads each rank's objects so that every view is shared, docs/scaling.md)")
        ->check(CLI::Range(1, kMaxSortLastCells))
        ->capture_default_str();
    sub->add_option("--link", o->link,
                    "LATENCY_MS[:MBPS[:JITTER_MS]]: emulate a network link between every pair of ranks, e.g. 1:100\n"
                    "(1 ms, 100 Mb/s), 0.2:10000, 20:100:2 (seeded jitter); every rank must get the same")
        ->type_name("SPEC");
    sub->add_option("--link-file", o->link_file,
                    "a link per pair of ranks: lines 'RANK RANK SPEC' (SPEC as --link), e.g. '0 1 5:100' for a slow\n"
                    "display <-> culler link and '1 2 0.05:10000' between the switch pair; other pairs get --link")
        ->type_name("FILE");
    sub->add_option("--rank-timeout", o->rank_timeout,
                    "seconds a rank waits for a message before it declares the sender dead")
        ->capture_default_str();
    sub->add_option("--size", o->size, "viewport and occlusion buffer size WxH")->capture_default_str();
    sub->add_option("--device", o->device,
                    "CUDA device for occswitch-cuda (default -1: the node-local MPI rank modulo the GPU count)")
        ->capture_default_str();
    sub->add_option("--mode", o->mode, "full (no LOD, no occlusion), lod ([PC12]) or oc+lod")->capture_default_str();
    sub->add_option("--stream", o->stream, "sc (coherent), snc (no coherence) or ns (object by object)")
        ->capture_default_str();
    sub->add_option("--aos", o->pipeline.aos, "active occluders per frame (top-K of Eq. 3)")->capture_default_str();
    sub->add_option("--pvs-occluders", o->pvs_occluders,
                    "also raster last frame's largest visible objects up to this many triangles (0 = off;\n"
                    "auto = a quarter of the vertex budget N, at least 30000)")
        ->capture_default_str();
    sub->add_option("--occluder-ms", o->occluder_ms,
                    "adapt the PVS occluders' triangles frame by frame so that rastering them takes about this\n"
                    "many ms (0 = off: a fixed budget, the same choice every run; default: 10 in a window, off\n"
                    "for recorded paths)");
    sub->add_option("--pvs-occluder-lag", o->pipeline.pvs_occluder_lag,
                    "take those from the PVS this many frames back: 1 or 2 (default: 1, and 2 with 3 ranks,\n"
                    "whose occluder rank works a frame ahead; 2 with 1 rank gives the 3-rank answer)");
    sub->add_option("--budget", o->budget,
                    "vertex budget N per frame: a count, a share of the scene's vertices (10%), or auto =\n"
                    "one vertex per pixel of --size, at most the scene's vertices (small models draw whole)")
        ->capture_default_str();
    sub->add_option("--pet", o->pipeline.pet, "pixel error threshold: smaller objects are not drawn")
        ->capture_default_str();
    sub->add_option("--lod", o->lod,
                    "budget: Eq. 1 shares the vertex budget (--budget, --alpha); error: each object at the\n"
                    "coarsest level whose simplification error projects to at most --tau pixels (no budget)")
        ->capture_default_str();
    sub->add_option("--tau", o->pipeline.tau,
                    "--lod error: pixels of simplification error allowed; --hierarchy on: also where the cut stops")
        ->capture_default_str();
    sub->add_option("--raster", o->raster,
                    "occluder depth raster: exact (a depth per pixel) or masked (coverage masks and a conservative\n"
                    "depth per 8x4 subtile, SIMD: Hasselgren et al. 2016); both never cull what is seen")
        ->capture_default_str();
    sub->add_option("--visibility-weighted", o->visibility_weighted,
                    "on: weigh each object by the share of its image the occluders leave visible (HZM), in Eq. 1\n"
                    "and in --lod error's bound (Charalambos 2006); off: the projected area (oc+lod only)")
        ->capture_default_str();
    sub->add_option("--hierarchy", o->hierarchy,
                    "auto: on where the .oss has a hierarchy (prep's default) and 1 to 3 ranks run, else off;\n"
                    "on: refine the scene's object hierarchy each frame into a cut of nodes, an inner node drawn\n"
                    "as its HLOD where its error projects to at most --tau pixels (tested against the frustum and\n"
                    "the HZM level by level); off: every object on its own (the flat pipeline of Peng & Cao)")
        ->capture_default_str();
    sub->add_option("--finer-cut-items", o->pipeline.finer_cut_items,
                    "--hierarchy on, budget rule: refine the cut again at half the --tau, down to tau/8, while the\n"
                    "finer cut draws at most this many items (the first that would draw more is given up and the\n"
                    "cut before it kept): a view with few items, or most of them hidden, gets a finer picture from\n"
                    "its spare frame time (0: always --tau)")
        ->capture_default_str();
    sub->add_option("--draw-cost", o->pipeline.draw_cost,
                    "--hierarchy on --lod error: what one draw is worth in triangles; the cut stops at a node\n"
                    "whose HLOD within --tau costs no more than its children within --tau (0: fewest triangles)")
        ->capture_default_str();
    sub->add_option("--colours", o->colours,
                    "model: each object in its model's colours (glTF baseColorFactor, OBJ Kd, PLY vertex colours),\n"
                    "an HLOD's vertices in those of the objects they stand for; object: a pastel per object id, so\n"
                    "parts stand apart (an HLOD: its objects' area-weighted mean); uniform: every item grey\n"
                    "(--reference then compares geometry and shading only)")
        ->check(CLI::IsMember({"model", "object", "uniform"}))
        ->capture_default_str();
    sub->add_option("--lod-hysteresis", o->pipeline.lod_hysteresis,
                    "keep an object's last vertex count while Eq. 1's is within this fraction of it; with the\n"
                    "hierarchy, levels raised to the error bound also step by this fraction (0 = off)")
        ->capture_default_str();
    sub->add_option("--keep-visible", o->pipeline.keep_visible,
                    "oc+lod: an object that came back into view after a gap of at most this many frames stays\n"
                    "drawn through its next such gaps, so cracks between occluders that open and close as the\n"
                    "camera moves do not make it flicker (0 = off)")
        ->capture_default_str();
    sub->add_option("--late-pass", o->late_pass,
                    "oc+lod: where 16 or more objects show that the last two frames did not (a turn, a jump),\n"
                    "raster the best of them too and test them again (niagara's two-phase culling)")
        ->capture_default_str();
    sub->add_option("--alpha", o->pipeline.alpha, "exponent of the LOD metric (Eq. 1)")->capture_default_str();
    return {sub, [o] { return runRender(*o); }};
}

}  // namespace occ::cli
