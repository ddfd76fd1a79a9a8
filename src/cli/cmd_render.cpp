// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "util/progress.h"

#include "device_memory.h"
#include "net/emulated_link.h"
#include "net/process_transport.h"
#include "net/transport.h"
#include "pipeline/pipeline.h"
#include "roles/occlusion_switch.h"
#include "cli/model_cache.h"
#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "view/camera_path.h"

#ifdef OCC_HAVE_GL
#include "render/frame_display.h"
#include "render/headless_context.h"
#include "render/png_writer.h"
#include "render/sort_last.h"
#include "render/window.h"
#include "util/config.h"
#endif

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstdio>
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

struct RenderOptions {
    std::string scene, path, stats, size = "512x512", mode = "oc+lod", stream = "sc", pvs_occluders = "auto", budget = "auto";
    std::string pace = "fast", lod = "budget", visibility_weighted = "off", hierarchy = "off", late_pass = "on", colours = "object";
    std::string raster = "exact";
    double path_fps = 60;
    bool no_display = false, headless = false, exact = false, reference = false, no_deltas = false;
    double occluder_ms = -1;  // -1: the default of the mode (on in a window)
    double rank_timeout = 5.0;
    std::string link;  // --link LATENCY_MS[:MBPS[:JITTER_MS]]
    std::string link_file;  // --link-file F: per pair of ranks
    LinkSpec link_spec;
    int sort_last_cells = 1;
    int device = -1;
    std::string out, debug_views;
    std::vector<uint64_t> debug_frames;
    PipelineOptions pipeline;
};


std::string frameName(uint64_t frame) {
    char b[32];
    std::snprintf(b, sizeof b, "frame_%06llu", static_cast<unsigned long long>(frame));
    return b;
}

// The stats CSV appears whole or not at all: rows go to a temporary that replaces the file
// only when the run succeeds.
class StatsFile {
public:
    StatsFile(const std::string& path, const std::string& header) {
        if (path.empty()) return;
        file_ = std::make_unique<AtomicFile>(path);
        file_->write(header + "\n");
    }
    void write(const std::string& rows) {
        if (file_) file_->write(rows);
    }
    void commit() {
        if (file_) file_->commit();
        file_.reset();
    }

private:
    std::unique_ptr<AtomicFile> file_;
};

#ifdef OCC_HAVE_GL
// `render` in a window: with one rank the single-process pipeline; under mpirun with 2 or more
// ranks rank 0 opens the one window and displays, the others cull (no window, no GL).
int runInWindow(RenderOptions& o, const OssFile& file, Transport& transport, int device_ordinal) {
    const roles::RankLayout layout(transport.size());
    // In a window the frame rate is what matters: the occluders follow the raster's speed.
    if (o.occluder_ms < 0) o.pipeline.occluder_ms = kWindowOccluderMs;
    render::WindowOptions w;
    w.width = o.pipeline.width;
    w.height = o.pipeline.height;
    w.path = o.path;
    w.out = o.out.empty() ? "." : o.out;
    if (o.exact || o.reference || !o.debug_views.empty())
        throw UsageError("render: --exact, --reference and --debug-views measure recorded runs: add --headless "
                         "and --path P.cam");
    if (o.pace != "fast")
        throw UsageError("render: --pace recorded replays --path headless (--headless or --no-display); a window "
                         "plays the path one pose per frame, then you fly");
    if (layout.size() == 1 && !o.stats.empty())
        throw UsageError("render: --stats in a window needs 2 or more ranks (mpirun); on one rank record a path (R) "
                         "and render it with --headless --stats");
    const bool rank0 = transport.rank() == 0;
    if (rank0 && !o.out.empty()) makeOutputFolder(o.out);
    roles::RunOptions run;
    run.deltas = !o.no_deltas;
    run.sort_last_cells = o.sort_last_cells;
    run.timeout = std::chrono::milliseconds(int64_t(o.rank_timeout * 1000));
    run.live = true;
    try {
        if (layout.size() == 1) {
            return render::runWindow(file, o.pipeline, w);
        }
        if (!rank0) {
            // A sort-last display rank (2 + P) draws its partition offscreen for rank 0's window.
            std::unique_ptr<render::HeadlessContext> context;
            std::unique_ptr<render::FrameDisplay> display;
            std::unique_ptr<render::SortLastCompositor> compositor;
            if (layout.partitionOf(transport.rank()) > 0) {
                context = std::make_unique<render::HeadlessContext>(device_ordinal);
                compositor = std::make_unique<render::SortLastCompositor>(transport, layout.displayRanks(), run.timeout);
                run.draw = [&](Pipeline& pipeline, const CameraPose& pose, uint64_t) {
                    render::DisplayOptions d;
                    d.items = true;
                    if (!display)
                        display = std::make_unique<render::FrameDisplay>(pipeline, w.width, w.height, d);
                    display->display(pipeline, pose);
                    compositor->composite(*display);
                    return std::string();
                };
            }
            roles::RunSummary ignored;
            roles::runRanks(transport, file, o.pipeline, run, ignored);
            display.reset();
            return 0;
        }
        StatsFile stats(o.stats, roles::rankStatsHeader(run));
        roles::RunSummary sum;
        std::string rows;
        try {
            rows = render::runWindowRanks(transport, file, o.pipeline, w, run, sum);
        } catch (const render::WindowUnavailable& e) {
            transport.fail(0, e.what());  // the culling ranks stop at once instead of timing out
            throw;
        }
        stats.write(rows);
        stats.commit();
        return 0;
    } catch (const render::WindowUnavailable& e) {
        throw SystemError(std::string(e.what()) + "; --headless renders without a window");
    }
}
#endif

int runRender(RenderOptions o) {
    parseViewportSize("--size", o.size, o.pipeline.width, o.pipeline.height);
    o.pipeline.pvs_occluder_triangles = parseOccluderTriangles(o.pvs_occluders);
    parseBudget(o.budget, o.pipeline.budget, o.pipeline.budget_share);
    o.pipeline.mode = parseCullMode(o.mode);
    o.pipeline.lod = parseLodRule(o.lod);
    if (o.visibility_weighted != "on" && o.visibility_weighted != "off")
        throw UsageError("--visibility-weighted " + o.visibility_weighted + ": expected on or off");
    o.pipeline.visibility_weighted = o.visibility_weighted == "on";
    if (o.raster != "masked" && o.raster != "exact")
        throw UsageError("--raster " + o.raster + ": expected masked or exact");
    o.pipeline.raster = o.raster == "masked" ? OccluderRaster::Masked : OccluderRaster::Exact;
    if (o.late_pass != "on" && o.late_pass != "off")
        throw UsageError("--late-pass " + o.late_pass + ": expected on or off");
    o.pipeline.late_pass = o.late_pass == "on";
    if (o.hierarchy != "on" && o.hierarchy != "off")
        throw UsageError("--hierarchy " + o.hierarchy + ": expected on or off");
    o.pipeline.hierarchy = o.hierarchy == "on";
    o.pipeline.stream = parseStreamMode(o.stream);
    if (o.occluder_ms >= 0) o.pipeline.occluder_ms = o.occluder_ms;
    if (o.no_display && o.headless) throw UsageError("render: --no-display and --headless exclude each other");
    const bool draws = !o.no_display;
    if (!draws && (o.exact || o.reference || !o.out.empty() || !o.debug_views.empty()))
        throw UsageError("render: --exact, --reference, --out and --debug-views need drawing; drop --no-display");
    if (!o.debug_frames.empty() && o.debug_views.empty())
        throw UsageError("render: --debug-frames chooses frames for --debug-views DIR, which is missing");
#ifndef OCC_HAVE_GL
    if (draws)
        throw UsageError("render: this occswitch was built without the OpenGL display (OCC_GL=OFF); "
                         "run with --no-display");
#endif
    if (o.pace != "fast" && o.pace != "recorded")
        throw UsageError("--pace " + o.pace + ": expected fast (every pose, as fast as the frames go) or recorded "
                         "(the path in real time at --path-fps)");
    if (!(o.path_fps > 0 && o.path_fps <= 100000))
    {
        char v[64];
        std::snprintf(v, sizeof v, "%g", o.path_fps);
        throw UsageError(std::string("--path-fps ") + v + ": expected poses per second in (0, 100000]");
    }
    if (o.path.empty() && (o.no_display || o.headless))
        throw UsageError(std::string("render: --path P.cam is required with ") +
                         (o.headless ? "--headless" : "--no-display"));

    if (!(o.rank_timeout > 0 && o.rank_timeout <= 3600))
        throw UsageError("render: --rank-timeout must be in (0, 3600] seconds");
    if (!o.link.empty()) {
        try {
            o.link_spec = parseLinkSpec(o.link);
        } catch (const std::invalid_argument& e) {
            throw UsageError(std::string("--link ") + e.what());
        }
    }
    // Before anything touches the device: each rank on a node its own GPU.
    const k::DeviceInfo device = k::selectDevice(o.device);
    // Under mpirun every rank runs this command; rank 0 displays, writes and prints.
    ProcessTransport process = openProcessTransport(o.link_spec, o.link_file);
    std::unique_ptr<Transport>& transport = process.transport;
    const std::string& link_summary = process.links;
    // The options are whole once the ranks are known (the occluder lag follows their layout);
    // checked before the scene is opened.
    o.pipeline.pvs_occluder_lag = roles::RankLayout(transport->size()).resolveOccluderLag(o.pipeline.pvs_occluder_lag);
    validatePipelineOptions(o.pipeline);
    const OssFile file = OssFile::open(preparedScene(o.scene));
#ifdef OCC_HAVE_GL
    if (draws && !o.headless) return runInWindow(o, file, *transport, device.ordinal);
#endif
    const std::vector<CameraPose> cameras = readCameraPath(o.path);
    const bool rank0 = transport->rank() == 0;
    const roles::RankLayout layout(transport->size());
    if (layout.size() > 1 && !o.debug_views.empty())
        throw UsageError("render: --debug-views draws the occluders' depth, which only the culling ranks have: "
                         "run it with one rank");
    if (layout.displays() > 1 && (o.exact || o.reference))
        throw UsageError("render: --exact and --reference draw the whole scene on one display; with " +
                         std::to_string(layout.size()) + " ranks each display rank holds a part: run them with 3 ranks");
    const int partition = layout.partitionOf(transport->rank());
    const bool displays = partition >= 0;  // this rank draws (its partition)
    std::set<uint64_t> debug_frames(o.debug_frames.begin(), o.debug_frames.end());
    if (!o.debug_views.empty() && debug_frames.empty())
        debug_frames = {0, cameras.size() / 2, cameras.size() - 1};
    for (uint64_t f : debug_frames)
        if (f >= cameras.size())
            throw UsageError("render: --debug-frames " + std::to_string(f) + " is past the path's last frame " +
                             std::to_string(cameras.size() - 1));
    // Folders only once every option is known to be good: a refused run creates nothing.
    if (rank0 && !o.out.empty()) makeOutputFolder(o.out);
    if (rank0 && !o.debug_views.empty()) makeOutputFolder(o.debug_views);

    roles::RunOptions run;
    run.cameras = cameras;
    run.deltas = !o.no_deltas;
    run.sort_last_cells = o.sort_last_cells;
    run.timeout = std::chrono::milliseconds(int64_t(o.rank_timeout * 1000));
    // --pace recorded: pose i of the path is due i / path_fps seconds after the first; each frame
    // takes the newest pose due when it starts (a slow frame skips poses, as a user's would), and a
    // frame quicker than the path waits for the next pose.
    const bool paced = o.pace == "recorded";
    std::vector<uint64_t> pose_of;  // rank 0, paced: the pose each frame showed
    std::chrono::steady_clock::time_point pace_start;
    if (paced) {
        run.live = true;
        run.next_camera = [&](uint64_t f, CameraPose& pose) {
            using namespace std::chrono;
            const auto now = steady_clock::now();
            if (f == 0) pace_start = now;
            uint64_t i = uint64_t(duration<double>(now - pace_start).count() * o.path_fps);
            if (f > 0 && i <= pose_of.back()) {
                i = pose_of.back() + 1;
                if (i < cameras.size())
                    std::this_thread::sleep_until(pace_start + duration_cast<steady_clock::duration>(
                                                                   duration<double>(double(i) / o.path_fps)));
            }
            if (i >= cameras.size()) return false;
            pose = cameras[i];
            pose_of.push_back(i);
            return true;
        };
    }
    double false_culls = 0, accuracy = 0, exact_occluded = 0, psnr = 0, min_psnr = 1e9, changed = 0, draw_ms = 0;
    double exact_churn = 0;  // frames after the first
#ifdef OCC_HAVE_GL
    std::unique_ptr<render::HeadlessContext> context;
    std::unique_ptr<render::FrameDisplay> display;
    render::DisplayOptions display_options;
    display_options.exact = o.exact;
    display_options.reference = o.reference;
    display_options.uniform_colour = o.colours == "uniform";
    // Sort-last: every display rank draws its partition; the pictures are composited into rank 0's.
    const std::vector<int> display_ranks = layout.displayRanks();
    std::unique_ptr<render::SortLastCompositor> compositor;
    if (display_ranks.size() > 1)
        compositor = std::make_unique<render::SortLastCompositor>(*transport, display_ranks, run.timeout);
    display_options.items = display_ranks.size() > 1;
    if (draws && displays) {
        context = std::make_unique<render::HeadlessContext>(device.ordinal);
        run.draw_header = render::displayStatsHeader(display_options);
        run.draw = [&](Pipeline& pipeline, const CameraPose& pose, uint64_t f) {
            if (!display)
                display = std::make_unique<render::FrameDisplay>(pipeline, o.pipeline.width, o.pipeline.height,
                                                                 display_options);
            const render::DisplayStats d = display->display(pipeline, pose);
            const std::vector<uint8_t>* picture = &display->picture();
            if (compositor) {
                picture = compositor->composite(*display);
                if (!picture) return render::displayStatsRow(d, display_options);  // not rank 0
            }
            draw_ms += d.ms_draw;
            false_culls += double(d.false_culls);
            exact_occluded += double(d.exact_occluded);
            accuracy += d.culling_accuracy;
            if (f > 0) exact_churn += double(d.exact_added + d.exact_removed);
            psnr += d.psnr_db;
            min_psnr = std::min(min_psnr, d.psnr_db);
            changed += d.changed_pixel_share;
            if (!o.out.empty())
                render::writePng(o.out + "/" + frameName(f) + ".png", o.pipeline.width, o.pipeline.height, 3,
                                 picture->data());
            if (debug_frames.count(f)) display->writeDebugViews(pipeline, pose, o.debug_views, frameName(f));
            return render::displayStatsRow(d, display_options);
        };
    } else if (draws) {
        // The other ranks' rows leave the display's columns empty; the header must match.
        run.draw_header = render::displayStatsHeader(display_options);
    }
#endif
    StatsFile stats(rank0 ? o.stats : std::string(), roles::rankStatsHeader(run));
    std::atomic<uint64_t> frames_done{0};
    // Progress counts the path's poses (paced: the newest one shown).
    run.on_frame = [&](uint64_t done) { frames_done = paced ? pose_of.at(done - 1) + 1 : done; };
    std::unique_ptr<ProgressBar> progress;
    if (rank0)
        progress = std::make_unique<ProgressBar>("render", "frames", "frames", [&] {
            const double done = double(frames_done.load());
            return ProgressBar::Sample{done, double(cameras.size()), done};
        });
    roles::RunSummary sum;
    const std::string rows = roles::runRanks(*transport, file, o.pipeline, run, sum);
    progress.reset();
    if (!rank0) return 0;
    stats.write(rows);
    stats.commit();
    const double frames = double(std::max<uint64_t>(1, sum.frames));
    std::printf("render: %s, %zu frames at %ux%u, mode %s, stream %s, backend %s, %d rank%s: mean %.2f ms/frame "
                "(%.1f fps); %.1f of %u objects in the frustum, %.1f%% of those occluded, %.1f visible; "
                "%.0f active triangles, %.4f%% of them streamed per frame\n",
                o.scene.c_str(), size_t(sum.frames), o.pipeline.width, o.pipeline.height, o.mode.c_str(),
                o.stream.c_str(), k::deviceBackend(), layout.size(), layout.size() > 1 ? "s" : "", sum.ms_frame / frames,
                1000.0 * frames / sum.ms_frame, sum.objects_in_frustum / frames, file.objectCount(),
                sum.objects_in_frustum > 0 ? 100.0 * (sum.objects_in_frustum - sum.objects_visible) / sum.objects_in_frustum
                                           : 0.0,
                sum.objects_visible / frames, sum.active_triangles / frames,
                sum.active_triangles > 0 ? 100.0 * sum.streamed_triangles / sum.active_triangles : 0.0);
    std::printf("messages: %s; visible-set messages %.0f bytes/frame, full sets would be %.0f (%.1f%% less); "
                "cameras %.0f, end-of-frames %.0f bytes/frame; camera-to-display latency %u frame%s, %.2f ms; "
                "display waited %.2f ms/frame\n",
                run.deltas ? "deltas" : "full sets (--no-deltas)", double(sum.bytes_delta) / frames,
                double(sum.full_pvs_bytes) / frames,
                sum.full_pvs_bytes ? 100.0 * (1.0 - double(sum.bytes_delta) / double(sum.full_pvs_bytes)) : 0.0,
                double(sum.bytes_camera) / frames, double(sum.bytes_eof) / frames, sum.latency_frames,
                sum.latency_frames == 1 ? "" : "s", frames > 1 ? sum.latency_ms / (frames - 1) : 0.0,
                sum.ms_wait / frames);
    if (!link_summary.empty())
        std::printf("link: %s (each message delayed by the latency, its bytes at the bandwidth, one queue per "
                    "destination)\n",
                    link_summary.c_str());
    if (paced) {
        // The longest run of poses no frame showed.
        uint64_t longest = pose_of.empty() ? 0 : pose_of.front();
        for (size_t j = 1; j < pose_of.size(); ++j) longest = std::max(longest, pose_of[j] - pose_of[j - 1] - 1);
        const uint64_t shown = pose_of.size(), skipped = cameras.size() - shown;
        std::printf("pace: recorded, the path's %zu poses at %g per second (%.2f s): %llu frames shown, %llu poses "
                    "skipped (%.1f%%), at most %llu in a row\n",
                    cameras.size(), o.path_fps, double(cameras.size()) / o.path_fps,
                    static_cast<unsigned long long>(shown), static_cast<unsigned long long>(skipped),
                    100.0 * double(skipped) / double(cameras.size()), static_cast<unsigned long long>(longest));
    }
    if (sum.displays > 1) {
        std::string parts;
        for (size_t p = 0; p < sum.partition_triangles.size(); ++p)
            parts += (p ? ", " : "") + std::to_string(int64_t(std::llround(sum.partition_triangles[p])));
        std::printf("sort-last: %d display ranks (partitions balanced by triangles); active triangles per display "
                    "rank %s (mean per frame); composite %.0f bytes/frame over all ranks, %.2f ms/frame on rank 0\n",
                    sum.displays, parts.c_str(), double(sum.bytes_composite) / frames, sum.ms_composite / frames);
    }
    const double later = std::max(1.0, frames - 1);
    std::printf("device: %s%s%s; host <-> device bus on rank 0: %.0f bytes/frame to the device, %.0f back "
                "(frames after the first), of which streamed geometry %.0f\n",
                device.ordinal >= 0 ? ("CUDA device " + std::to_string(device.ordinal) + ", ").c_str() : "",
                device.name.c_str(), device.uuid.empty() ? "" : (", UUID " + device.uuid).c_str(),
                double(sum.bus_h2d_bytes) / later, double(sum.bus_d2h_bytes) / later, double(sum.streamed_bytes) / later);
#ifdef OCC_HAVE_GL
    if (draws) std::printf("display: %s, mean %.2f ms/frame to draw\n", context->description().c_str(), draw_ms / frames);
    if (o.exact)
        std::printf("exact: %.0f false culls in all (must be 0), %.1f exactly occluded objects per frame, "
                    "culling accuracy %.2f%% (mean over frames); churn per frame (added + removed) of the PVS "
                    "%.1f, of the exact visible set %.1f\n",
                    false_culls, exact_occluded / frames, accuracy / frames, sum.pvs_churn / later,
                    exact_churn / later);
    if (o.reference)
        std::printf("reference: PSNR %.2f dB mean, %.2f dB lowest; %.3f%% of pixels changed (mean)\n", psnr / frames,
                    min_psnr, changed / frames);
    if (!o.out.empty()) std::printf("frames: %s/frame_*.png\n", o.out.c_str());
    if (!o.debug_views.empty()) std::printf("debug views: %s/\n", o.debug_views.c_str());
#else
    (void)false_culls, (void)exact_churn, (void)accuracy, (void)exact_occluded, (void)psnr, (void)min_psnr, (void)changed, (void)draw_ms;
#endif
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
                  "also draw the full-detail unculled frame and add the columns psnr_db, changed_pixel_share");
    sub->add_option("--debug-views", o->debug_views,
                    "write the occluders' depth, the HZM levels and the culling view of chosen frames into DIR");
    sub->add_option("--debug-frames", o->debug_frames, "frames for --debug-views (default: first, middle, last)")
        ->delimiter(',');
    sub->add_option("--stats", o->stats,
                    "write per-frame statistics to this CSV file (under mpirun: every rank's rows, with a rank column)");
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
                    "on: refine the scene's object hierarchy (prep --hierarchy on) each frame into a cut of\n"
                    "nodes, an inner node drawn as its HLOD where its error projects to at most --tau pixels\n"
                    "(tested against the frustum and the HZM level by level); off: every object on its own")
        ->capture_default_str();
    sub->add_option("--draw-cost", o->pipeline.draw_cost,
                    "--hierarchy on --lod error: what one draw is worth in triangles; the cut stops at a node\n"
                    "whose HLOD within --tau costs no more than its children within --tau (0: fewest triangles)")
        ->capture_default_str();
    sub->add_option("--colours", o->colours,
                    "headless pictures: object (each object its colour, an HLOD its objects' mean) or uniform\n"
                    "(every item grey: --reference then compares geometry and shading only)")
        ->check(CLI::IsMember({"object", "uniform"}))
        ->capture_default_str();
    sub->add_option("--lod-hysteresis", o->pipeline.lod_hysteresis,
                    "keep an object's last vertex count while Eq. 1's is within this fraction of it (0 = off)")
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
