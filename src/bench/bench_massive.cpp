// SPDX-License-Identifier: MIT
#include "bench/bench_massive.h"

#include "bench/runner.h"
#include "scene/atomic_file.h"
#include "scene/oss_file.h"

#include <algorithm>
#include <ctime>
#include <iomanip>
#include <map>

namespace occ::bench {

namespace {


// What one step that makes a file cost, kept beside the file so that a later run that reuses
// it can still report it.
struct StepCost {
    double seconds = NAN, peak_mb = NAN;
    bool known = false;
};

StepCost readCost(const fs::path& path) {
    StepCost c;
    std::ifstream in(path);
    if (in >> c.seconds >> c.peak_mb) c.known = true;
    else c = StepCost{};
    return c;
}

void writeCost(const fs::path& path, const RunResult& r) {
    writeFileAtomic(path.string(), fixed(r.seconds, 2) + " " + fixed(r.peak_mb, 1) + "\n");
}

// Per-frame figures of one render run, over the display's frames.
struct WalkFigures {
    size_t frames = 0;
    double first_ms = NAN, second_ms = NAN, median_ms = NAN, p99_ms = NAN, max_ms = NAN;
    size_t over_2x_median = 0;  // frames after the first two slower than twice the median
    double streamed_share = NAN;  // % of active triangles streamed, frames 10 onwards
    size_t frames_streaming = 0;
    double churn = NAN, visible = NAN, occluder_triangles = NAN, raster_ms = NAN;
    double occlusion_ms = NAN, raster_rate = NAN;  // medians over frames 1 on; rate per core
    double exact_churn = NAN, false_culls = NAN, accuracy = NAN;
    double peak_mb = NAN, seconds = NAN;
    // Means: items drawn (a vertex count above 0) and active triangles over frames `from` on;
    // the visible set's churn as a share of it, over frames 1 on; PSNR against the full-detail
    // picture (--reference runs) over frames `from` on.
    double drawn = NAN, triangles = NAN, churn_pct = NAN, psnr_db = NAN;
    // Where the run wrote them (--reference), over frames `from` on: PSNR pooled over the run
    // (from the mean squared error per byte; 100 where it is 0, as render caps it), the mean
    // share of pixels changed perceptibly (%) and mean SSIM, and the share of the measured
    // changed pixels that lie farther than tau from their item (%; 0 where none was measured).
    double pooled_psnr_db = NAN, perceptible_pct = NAN, ssim = NAN, beyond_tau_pct = NAN;
};

// Means over the frames from `from` on (the first ones stream the first view and warm the caches).
WalkFigures figures(const fs::path& stats_csv, const RunResult& run, size_t from) {
    const RenderStats s(stats_csv);
    const CsvTable& t = s.csv;
    WalkFigures f;
    f.frames = s.display.size();
    f.peak_mb = run.peak_mb;
    f.seconds = run.seconds;
    std::vector<double> ms;
    for (size_t i = 0; i < s.display.size(); ++i) {
        const double m = s.frameMs(s.display[i]);  // with drawing where the run drew
        if (i == 0) f.first_ms = m;
        else if (i == 1) f.second_ms = m;
        else ms.push_back(m);
    }
    if (!ms.empty()) {
        std::vector<double> sorted = ms;
        std::sort(sorted.begin(), sorted.end());
        f.median_ms = sorted[sorted.size() / 2];
        f.p99_ms = sorted[std::min(sorted.size() - 1, size_t(std::ceil(0.99 * double(sorted.size()))) - 1)];
        f.max_ms = sorted.back();
        for (double m : ms) f.over_2x_median += m > 2 * f.median_ms;
    }
    double streamed = 0, active = 0, churn = 0, visible = 0, occ = 0, raster = 0, exact = 0, false_culls = 0, acc = 0;
    double drawn = 0, churn_share = 0, psnr = 0, mse = 0, perceptible = 0, ssim = 0, bound_pixels = 0, beyond_tau = 0;
    size_t later = 0, n = 0;
    const bool has_exact = t.has("exact_added"), has_psnr = t.has("psnr_db"), has_pictures = t.has("mse");
    for (size_t i = 0; i < s.display.size(); ++i) {
        const size_t r = s.display[i];
        if (i >= 1) {  // churn is what changed since the frame before
            churn += t.num(r, "pvs_added") + t.num(r, "pvs_removed");
            churn_share += (t.num(r, "pvs_added") + t.num(r, "pvs_removed")) / std::max(1.0, t.num(r, "objects_visible"));
            if (has_exact) exact += t.num(r, "exact_added") + t.num(r, "exact_removed");
            ++later;
        }
        if (i < from) continue;
        ++n;
        streamed += t.num(r, "streamed_triangles");
        active += t.num(r, "active_triangles");
        f.frames_streaming += t.num(r, "streamed_triangles") > 0;
        visible += t.num(r, "objects_visible");
        drawn += t.num(r, "objects_drawn");
        if (has_psnr) psnr += t.num(r, "psnr_db");
        if (has_pictures) {
            mse += t.num(r, "mse");
            perceptible += t.num(r, "perceptible_share");
            ssim += t.num(r, "ssim");
            bound_pixels += t.num(r, "bound_pixels");
            beyond_tau += t.num(r, "bound_beyond_tau");
        }
        occ += t.num(r, "occluder_triangles");
        raster += t.num(r, "ms_depth_raster");
        if (has_exact) false_culls += t.num(r, "false_culls"), acc += t.num(r, "culling_accuracy");
    }
    f.occlusion_ms = s.medianOcclusionMs();
    f.raster_rate = s.medianRasterRatePerCore();
    if (later) {
        f.churn = churn / double(later);
        f.churn_pct = 100.0 * churn_share / double(later);
        if (has_exact) f.exact_churn = exact / double(later);
    }
    if (n) {
        f.streamed_share = active > 0 ? 100.0 * streamed / active : 0.0;
        f.visible = visible / double(n);
        f.drawn = drawn / double(n);
        f.triangles = active / double(n);
        if (has_psnr) f.psnr_db = psnr / double(n);
        if (has_pictures) {
            // Frames are the same size, so the run's squared error per byte is the mean of theirs.
            const double mean_mse = mse / double(n);
            f.pooled_psnr_db = mean_mse > 0 ? std::min(100.0, 10.0 * std::log10(255.0 * 255.0 / mean_mse)) : 100.0;
            f.perceptible_pct = perceptible / double(n);
            f.ssim = ssim / double(n);
            f.beyond_tau_pct = bound_pixels > 0 ? 100.0 * beyond_tau / bound_pixels : 0.0;
        }
        f.occluder_triangles = occ / double(n);
        f.raster_ms = raster / double(n);
        if (has_exact) f.false_culls = false_culls, f.accuracy = acc / double(n);
    }
    return f;
}

// Issue 49's village: assimp-testmodels' KIT house (the FZK-Haus of the Karlsruhe Institute of
// Technology, IFC), exported to glb by assimp-utils' `assimp export` and tiled 10 x 1 x 10 (29 400
// objects, 3.6 M triangles).
constexpr const char* kKitHouseIfc = "/usr/share/assimp/models/IFC/AC14-FZK-Haus.ifc";

// Issue 49's picture targets for one scene, path and colours: the hierarchy's run against the
// flat one, both against full detail.
struct PictureVerdict {
    double psnr_margin_db = NAN, perceptible_margin_points = NAN;  // at least 0: met, with that to spare
    bool psnr_met = false, perceptible_met = false, bound_met = false;
    int met() const { return psnr_met + perceptible_met + bound_met; }
};

// Issue 49's PSNR target: at least the flat run's less 1 dB, or 45 dB where the flat run is
// nearly exact (its example: the village walk's 79 dB). Nearly exact is read strictly: a flat run
// of at least 60 dB (a mean squared error of 0.07 per byte), so that a flat run at 50 dB, which
// differs visibly from full detail in places, still holds the hierarchy to flat less 1 dB.
constexpr double kNearlyExactFlatPsnrDb = 60.0, kNearlyExactTargetPsnrDb = 45.0;

// The PSNR target: pooled PSNR at least flat - 1 dB, or 45 dB where flat is nearly exact; the perceptible target: the
// perceptibly changed share at most 1 point above the flat run's; the bound target: the bound's
// 99th percentile within tau, i.e. at most 1 % of the measured changed pixels beyond it. A
// figure the runs did not write (NaN) misses.
PictureVerdict pictureVerdict(const WalkFigures& flat, const WalkFigures& hierarchy) {
    PictureVerdict v;
    const double wanted = flat.pooled_psnr_db >= kNearlyExactFlatPsnrDb ? kNearlyExactTargetPsnrDb : flat.pooled_psnr_db - 1.0;
    v.psnr_margin_db = hierarchy.pooled_psnr_db - wanted;
    v.psnr_met = v.psnr_margin_db >= 0;
    v.perceptible_margin_points = flat.perceptible_pct + 1.0 - hierarchy.perceptible_pct;
    v.perceptible_met = v.perceptible_margin_points >= 0;
    v.bound_met = hierarchy.beyond_tau_pct <= 1.0;
    return v;
}

class Massive {
public:
    explicit Massive(const BenchMassiveOptions& o)
        : o_(o), out_(o.out), scenes_(o.scenes.empty() ? out_ / "scenes" : fs::path(o.scenes)),
          runner_(out_ / "logs", o.run_timeout_s, "bench massive") {
        exe_ = selfExecutable();
    }

    int run() {
        const auto start = Clock::now();
        for (const fs::path& dir : {out_, scenes_, out_ / "logs", out_ / "raw"}) makeOutputFolder(dir.string());
        std::fprintf(stderr, "bench massive: a %u-object plant in %s, %u-frame walk and orbit, logs in %s\n",
                     o_.objects, scenes_.c_str(), o_.frames, (out_ / "logs").c_str());

        // 1. The scene, made once and reused (its cost kept beside it).
        const Scene scene = makeScene(o_.objects, "", "");
        gen_ = scene.gen;
        prep_ = scene.prep;
        prep_flat_ = scene.prep_flat;
        {
            // Pages released as validation goes: this process stays small (Runner::run).
            const OssFile file = OssFile::open(scene.oss.string(), OssFile::Pages::Release);
            objects_ = file.objectCount();
            triangles_ = 0;
            for (const oss::ObjectDisk& d : file.objects()) triangles_ += file.meshRecords()[d.mesh].triangle_count;
            oss_bytes_ = file.fileSize();
            hierarchy_ = file.nodeCount() > 0;
        }
        input_bytes_ = scene.input_bytes;
        const fs::path& oss = scene.oss;

        // 2. Camera paths.
        const fs::path walk = out_ / "walk.cam", orbit = out_ / "orbit.cam", exact = out_ / "walk_exact.cam",
                       orbit_prefix = out_ / "orbit_reference.cam";
        paths(oss, walk, orbit, "");
        writePrefix(walk, exact, o_.exact_frames);
        writePrefix(orbit, orbit_prefix, o_.reference_frames);

        // 3. The runs.
        walk_ = render("walk_oclod", oss, walk, {"--mode", "oc+lod", "--no-display"});
        walk_lod_ = render("walk_lod", oss, walk, {"--mode", "lod", "--no-display"});
        orbit_ = render("orbit_oclod", oss, orbit, {"--mode", "oc+lod", "--no-display"});
        exact_ = render("walk_exact", oss, exact, {"--mode", "oc+lod", "--headless", "--exact"}, 1);
        // With drawing (OpenGL through EGL, llvmpipe here): what a slow renderer makes of the same walk.
        walk_drawn_ = render("walk_oclod_drawn", oss, walk, {"--mode", "oc+lod", "--headless"});
        walk_lod_drawn_ = render("walk_lod_drawn", oss, walk, {"--mode", "lod", "--headless"});
        if (hierarchy_) {
            // Issue 34: the same walk and orbit with the hierarchy, a small plant's walk and orbit
            // with it (growth), then the orbit's prefix against the full-detail picture flat and
            // with it. The growth's runs go small, large, small, large, one right after the other:
            // this machine's speed drifts over minutes (a shared host), and a ratio of two medians
            // measured ten minutes apart once read 2.8x for frames doing the same work.
            const std::vector<std::string> h = {"--mode", "oc+lod", "--hierarchy", "on"};
            if (o_.growth_objects < o_.objects) {
                const Scene small = makeScene(o_.growth_objects, "small_", "growth");
                const fs::path small_walk = out_ / "small_walk.cam", small_orbit = out_ / "small_orbit.cam";
                paths(small.oss, small_walk, small_orbit, "small_");
                small_walk_h_ = render("small_walk_hierarchy", small.oss, small_walk, join(h, {"--no-display"}));
                walk_h_ = render("walk_hierarchy", oss, walk, join(h, {"--no-display"}));
                small_orbit_h_ = render("small_orbit_hierarchy", small.oss, small_orbit, join(h, {"--no-display"}));
                orbit_h_ = render("orbit_hierarchy", oss, orbit, join(h, {"--no-display"}));
            } else {
                walk_h_ = render("walk_hierarchy", oss, walk, join(h, {"--no-display"}));
                orbit_h_ = render("orbit_hierarchy", oss, orbit, join(h, {"--no-display"}));
            }
            if (o_.reference_frames > 0) {
                orbit_ref_ = render("orbit_reference", oss, orbit_prefix,
                                    {"--mode", "oc+lod", "--hierarchy", "off", "--headless", "--reference"}, 1);
                orbit_h_ref_ = render("orbit_hierarchy_reference", oss, orbit_prefix, join(h, {"--headless", "--reference"}), 1);
            }
            if (o_.reference_frames > 0) pictures(oss, walk, orbit_prefix);
        }

        if (hierarchy_ && o_.grid > 0) prepareGrid();

        write(std::chrono::duration<double>(Clock::now() - start).count());
        return 0;
    }

private:
    struct Scene {
        fs::path oss;
        StepCost gen, prep, prep_flat;  // prep_flat: the same input prepared with --hierarchy off
        uint64_t input_bytes = 0;
    };
    // One row of issue 49's picture table: a scene's path in one colour mode, flat and with the
    // hierarchy, both against full detail.
    struct PictureRow {
        std::string scene, label, path, colours;  // scene: the key in pictures.csv; label: in massive.md
        WalkFigures flat, hierarchy;
    };
    // The plant of `objects` objects in the scenes folder, generated and prepared unless it is
    // there (each step's cost kept beside the files). log_prefix empty: the benchmark's plant;
    // otherwise `purpose` names what the extra plant is for in the progress lines.
    Scene makeScene(uint32_t objects, const std::string& log_prefix, const std::string& purpose) {
        const std::string stem = "plant_" + std::to_string(objects);
        const fs::path gltf = scenes_ / (stem + ".gltf");
        Scene s{scenes_ / (stem + ".oss"), {}, {}, 0};
        if (!fs::exists(s.oss)) {
            if (!fs::exists(gltf) || !fs::exists(scenes_ / (stem + ".bin"))) {
                step(log_prefix.empty() ? "gen plant" : "gen plant of " + std::to_string(objects) + " objects (" + purpose + ")");
                const RunResult r = runner_.run(log_prefix + "gen", command({"gen", "plant", "--objects", std::to_string(objects),
                                                                             "--seed", "1", "-o", gltf.string()}));
                writeCost(scenes_ / (stem + ".gen.cost"), r);
                made_ = made_ || log_prefix.empty();
                done(r);
            }
            step(log_prefix.empty() ? "prep" : "prep of the " + std::to_string(objects) + "-object plant (" + purpose + ")");
            const RunResult r = runner_.run(log_prefix + "prep", command({"prep", gltf.string(), "-o", s.oss.string()}));
            writeCost(scenes_ / (stem + ".prep.cost"), r);
            made_ = made_ || log_prefix.empty();
            done(r);
            if (log_prefix.empty()) {
                // Issue 34: prep's time with the hierarchy against without it, right after, by
                // the same build; the flat file is not kept.
                step("prep with --hierarchy off (the time it takes without the hierarchy)");
                const fs::path flat = scenes_ / (stem + ".flat.oss");
                const RunResult f = runner_.run("prep_flat", command({"prep", gltf.string(), "-o", flat.string(), "--hierarchy", "off"}));
                writeCost(scenes_ / (stem + ".prep_flat.cost"), f);
                std::error_code ec;
                fs::remove(flat, ec);
                done(f);
            }
        }
        s.gen = readCost(scenes_ / (stem + ".gen.cost"));
        s.prep = readCost(scenes_ / (stem + ".prep.cost"));
        s.prep_flat = readCost(scenes_ / (stem + ".prep_flat.cost"));
        std::error_code ec;
        s.input_bytes = fs::file_size(gltf, ec) + fs::file_size(scenes_ / (stem + ".bin"), ec);
        return s;
    }
    // Issue 34: the engine grid prepared without and with the hierarchy, each time afresh (the
    // grid's .glb is made once: it is a few MB of instancing nodes).
    void prepareGrid() {
        const std::string n = std::to_string(o_.grid);
        const fs::path glb = scenes_ / ("grid_" + n + ".glb");
        if (!fs::exists(glb)) {
            step("gen grid " + n + "x" + n + "x" + n);
            done(runner_.run("grid_gen", command({"gen", "grid", "--nx", n, "--ny", n, "--nz", n, "-o", glb.string()})));
        }
        const fs::path flat = out_ / "grid_flat.oss", with = out_ / "grid_hierarchy.oss";
        step("prep of the grid without the hierarchy");
        grid_flat_ = runner_.run("grid_prep_flat", command({"prep", glb.string(), "-o", flat.string(), "--hierarchy", "off"}));
        done(grid_flat_);
        step("prep of the grid with the hierarchy");
        grid_h_ = runner_.run("grid_prep_hierarchy", command({"prep", glb.string(), "-o", with.string()}));
        done(grid_h_);
        grid_flat_bytes_ = fs::file_size(flat);
        grid_h_bytes_ = fs::file_size(with);
        const OssFile::HlodCounts hlods = OssFile::open(with.string(), OssFile::Pages::Release).hlodCounts();
        grid_inner_ = hlods.inner;
        grid_hlods_ = hlods.meshes;
    }
    // Issue 49's picture stage: each scene's walk and orbit prefixes drawn against full detail
    // in the model's colours and in one, flat and with the hierarchy, a row each in
    // picture_rows_. The plant's orbit in model colours is the issue-34 reference pair
    // (orbit_ref_, orbit_h_ref_), which must have run; it is not run again.
    void pictures(const fs::path& oss, const fs::path& walk, const fs::path& orbit_prefix) {
        const auto start = Clock::now();
        const fs::path walk_prefix = out_ / "walk_reference.cam";
        writePrefix(walk, walk_prefix, o_.reference_frames);
        pictureRuns("plant_" + std::to_string(o_.objects), "plant, " + std::to_string(o_.objects) + " objects", oss,
                    walk_prefix, orbit_prefix, true);
        if (o_.picture_objects > 0 && o_.picture_objects < o_.objects) {
            const Scene plant = makeScene(o_.picture_objects, "picture_", "pictures");
            pictureScene("plant_" + std::to_string(o_.picture_objects),
                         "plant, " + std::to_string(o_.picture_objects) + " objects", plant.oss, "picture_");
        }
        if (!o_.village) village_note_ = "not run (`--village off`)";
        else if (const fs::path village = makeVillage(); !village.empty())
            pictureScene("kit_village", "KIT village 10x1x10", village, "village_");
        else std::fprintf(stderr, "bench massive: KIT village %s\n", village_note_.c_str());
        picture_seconds_ = std::chrono::duration<double>(Clock::now() - start).count();
    }
    // A scene's own walk and orbit (the files named after `prefix`), their prefixes, and its rows.
    void pictureScene(const std::string& key, const std::string& label, const fs::path& oss, const std::string& prefix) {
        const fs::path walk = out_ / (prefix + "walk.cam"), orbit = out_ / (prefix + "orbit.cam");
        const fs::path walk_prefix = out_ / (prefix + "walk_reference.cam"), orbit_prefix = out_ / (prefix + "orbit_reference.cam");
        paths(oss, walk, orbit, prefix);
        writePrefix(walk, walk_prefix, o_.reference_frames);
        writePrefix(orbit, orbit_prefix, o_.reference_frames);
        pictureRuns(key, label, oss, walk_prefix, orbit_prefix, false);
    }
    // The rows of one scene: its walk and orbit prefixes x model and uniform colours, each run
    // flat and with the hierarchy (measured from frame 1, as the reference pair). With
    // orbit_model_measured, the orbit in model colours is the issue-34 pair.
    void pictureRuns(const std::string& key, const std::string& label, const fs::path& oss, const fs::path& walk_prefix,
                     const fs::path& orbit_prefix, bool orbit_model_measured) {
        for (const auto& [path, cam] : {std::pair<std::string, fs::path>{"walk", walk_prefix}, {"orbit", orbit_prefix}})
            for (const std::string colours : {"model", "uniform"}) {
                PictureRow row{key, label, path, colours, {}, {}};
                if (orbit_model_measured && path == "orbit" && colours == "model") {
                    row.flat = orbit_ref_;
                    row.hierarchy = orbit_h_ref_;
                } else {
                    const std::string name = "pictures_" + key + "_" + path + "_" + colours;
                    const std::vector<std::string> args = {"--headless", "--reference", "--colours", colours, "--hierarchy"};
                    row.flat = render(name + "_flat", oss, cam, join(args, {"off"}), 1);
                    row.hierarchy = render(name + "_hierarchy", oss, cam, join(args, {"on"}), 1);
                    picture_runs_ += 2;
                }
                picture_rows_.push_back(row);
            }
    }
    // The KIT village in the scenes folder: the house exported from the IFC, tiled and
    // prepared, each step skipped when its output is there (the .glb steps write a temporary
    // and rename it, so a stopped step is not taken for done). Empty, with the reason in
    // village_note_, when a step that must run lacks `assimp` or the IFC.
    fs::path makeVillage() {
        const fs::path house = scenes_ / "kit_house.glb", glb = scenes_ / "kit_village.glb", oss = scenes_ / "kit_village.oss";
        if (fs::exists(oss)) return oss;
        if (!fs::exists(glb)) {
            if (!fs::exists(house)) {
                const std::string assimp = findInPath("assimp");
                if (assimp.empty()) {
                    village_note_ = "skipped: no `assimp` on PATH to export the KIT house (Debian's assimp-utils)";
                    return {};
                }
                if (!fs::exists(kKitHouseIfc)) {
                    village_note_ = std::string("skipped: no ") + kKitHouseIfc + " (Debian's assimp-testmodels)";
                    return {};
                }
                step("assimp export of the KIT house");
                const fs::path part = scenes_ / "kit_house.part.glb";
                done(runner_.run("village_export", {assimp, "export", kKitHouseIfc, part.string(), "-fglb2"}));
                fs::rename(part, house);
            }
            step("gen grid of the KIT house, 10x1x10");
            const fs::path part = scenes_ / "kit_village.part.glb";
            done(runner_.run("village_gen", command({"gen", "grid", "--model", house.string(), "--nx", "10", "--ny", "1",
                                                     "--nz", "10", "-o", part.string()})));
            fs::rename(part, glb);
        }
        step("prep of the KIT village");
        done(runner_.run("village_prep", command({"prep", glb.string(), "-o", oss.string()})));
        return oss;
    }
    void paths(const fs::path& oss, const fs::path& walk, const fs::path& orbit, const std::string& log_prefix) {
        runner_.run(log_prefix + "path_walk",
                    command({"path", "walk", oss.string(), "--frames", std::to_string(o_.frames), "-o", walk.string()}));
        runner_.run(log_prefix + "path_orbit",
                    command({"path", "orbit", oss.string(), "--frames", std::to_string(o_.frames), "-o", orbit.string()}));
    }
    // The first `frames` + 1 cameras of a path (the runs' first frame is measured apart).
    static void writePrefix(const fs::path& path, const fs::path& prefix, uint32_t frames) {
        std::ifstream in(path);
        std::ostringstream head;
        std::string line;
        for (uint32_t n = 0; std::getline(in, line) && n < frames + 1;) {
            head << line << "\n";
            if (!line.empty() && line[0] != '#') ++n;
        }
        writeFileAtomic(prefix.string(), head.str());
    }
    static std::vector<std::string> join(std::vector<std::string> a, std::initializer_list<std::string> b) {
        a.insert(a.end(), b);
        return a;
    }
    std::vector<std::string> command(std::initializer_list<std::string> args) const {
        std::vector<std::string> argv{exe_};
        argv.insert(argv.end(), args);
        return argv;
    }
    void step(const std::string& what) {
        std::fprintf(stderr, "bench massive: %s ...\n", what.c_str());
        step_ = what;
    }
    void done(const RunResult& r) {
        std::fprintf(stderr, "bench massive: %s: %.1f s, peak %.0f MB\n", step_.c_str(), r.seconds, r.peak_mb);
    }
    WalkFigures render(const std::string& name, const fs::path& oss, const fs::path& cam, std::vector<std::string> extra,
                       size_t from = 10) {
        step(name);
        const fs::path stats = out_ / "raw" / (name + ".csv");
        std::vector<std::string> argv = command({"render", oss.string(), "--path", cam.string(), "--size", "512x512",
                                                 "--budget", o_.budget, "--stats", stats.string()});
        // Runs that do not name --hierarchy are the flat ones (render's default refines a
        // .oss's hierarchy, issue 49).
        if (std::find(extra.begin(), extra.end(), "--hierarchy") == extra.end()) argv.insert(argv.end(), {"--hierarchy", "off"});
        argv.insert(argv.end(), extra.begin(), extra.end());
        const RunResult r = runner_.run(name, argv);
        done(r);
        return figures(stats, r, from);
    }

    void write(double total) {
        std::time_t now = std::time(nullptr);
        char date[32];
        std::strftime(date, sizeof date, "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
        const auto cost = [](const StepCost& c) {
            return std::isfinite(c.seconds) ? fixed(c.seconds, 1) + " s, " + fixed(c.peak_mb, 0) + " MB peak" : std::string("n/a");
        };
        std::ostringstream md;
        md << "# occswitch bench massive\n\n"
           << "Written by `occswitch bench massive --objects " << o_.objects << " --frames " << o_.frames
           << " --budget " << o_.budget << "` on " << date << " in " << fixed(total, 0) << " s (scene: " << (made_ ? "made by this run" : "reused; its cost from when it was made") << ").\n\n"
           << "- scene: `gen plant --objects " << o_.objects << " --seed 1`: " << objects_ << " objects, " << triangles_
           << " triangles; glTF + buffer " << fixed(double(input_bytes_) / 1e9, 2) << " GB, .oss "
           << fixed(double(oss_bytes_) / 1e9, 2) << " GB\n"
           << "- gen: " << cost(gen_) << "; prep: " << cost(prep_) << " (a quarter of the input: "
           << fixed(double(input_bytes_) / 4e6, 0) << " MB)\n"
           << "- runs: 512x512, `--budget " << o_.budget << "`, `--no-display` (every stage but drawing) for the "
           << o_.frames << "-camera walk and orbit; the exact visible set (`--headless --exact`, all frustum objects drawn "
           << "at full detail) over the walk's first " << o_.exact_frames << " frames; the walk again with drawing "
           << "(`--headless`: OpenGL through EGL, on this machine's renderer)\n"
           << "- occlusion ms: occluder choice + depth raster + HZM build + HZM test; raster rate: occluder triangles "
              "per second per core of the depth raster (" << RenderStats::cores() << " cores); both medians over frames 1 on\n"
           << "- frame 0 and 1 apart; median, p99, max and 'frames > 2x median' over frames 2 on; streamed share, "
              "visible, occluder triangles and raster ms over frames 10 on (the exact run: 1 on); churn over frames 1 on\n\n";
        md << "| run | frames | frame 0 ms | frame 1 ms | median ms | p99 ms | max ms | frames > 2x median | "
              "streamed share % | frames streaming | visible | PVS churn | exact churn | occluder tri | raster ms | "
              "occlusion ms | raster M tri/s per core | false culls | accuracy % | peak MB | s | drawn | triangles | "
              "churn % of visible | PSNR dB |\n";
        md << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
              "---:|---:|---:|---:|\n";
        std::ostringstream csv;
        csv << "run,frames,frame0_ms,frame1_ms,median_ms,p99_ms,max_ms,over_2x_median,streamed_share_pct,frames_streaming,"
               "visible,pvs_churn,exact_churn,occluder_triangles,raster_ms,occlusion_ms,raster_mtri_per_s_per_core,false_culls,"
               "accuracy_pct,peak_mb,seconds,drawn,triangles,churn_pct,psnr_db\n";
        struct Row {
            const char *key, *name;
            const WalkFigures* f;
        };
        std::vector<Row> rows = {{"walk_oclod", "walk, oc+lod", &walk_},
                                 {"walk_lod", "walk, lod", &walk_lod_},
                                 {"orbit_oclod", "orbit, oc+lod", &orbit_},
                                 {"walk_exact", "walk prefix, oc+lod, exact", &exact_},
                                 {"walk_oclod_drawn", "walk, oc+lod, drawn", &walk_drawn_},
                                 {"walk_lod_drawn", "walk, lod, drawn", &walk_lod_drawn_}};
        if (hierarchy_) {
            rows.push_back({"walk_hierarchy", "walk, oc+lod, hierarchy", &walk_h_});
            rows.push_back({"orbit_hierarchy", "orbit, oc+lod, hierarchy", &orbit_h_});
            if (o_.reference_frames > 0) {
                rows.push_back({"orbit_reference", "orbit prefix, oc+lod, reference", &orbit_ref_});
                rows.push_back({"orbit_hierarchy_reference", "orbit prefix, oc+lod, hierarchy, reference", &orbit_h_ref_});
            }
            if (o_.growth_objects < o_.objects) {
                rows.push_back({"small_walk_hierarchy", "small plant: walk, oc+lod, hierarchy", &small_walk_h_});
                rows.push_back({"small_orbit_hierarchy", "small plant: orbit, oc+lod, hierarchy", &small_orbit_h_});
            }
        }
        for (const auto& [key, name, f] : rows) {
            const std::vector<std::string> cells = {
                std::to_string(f->frames), fixed(f->first_ms, 1), fixed(f->second_ms, 1), fixed(f->median_ms, 1),
                fixed(f->p99_ms, 1), fixed(f->max_ms, 1), std::to_string(f->over_2x_median), fixed(f->streamed_share, 3),
                std::to_string(f->frames_streaming), fixed(f->visible, 0), fixed(f->churn, 1), fixed(f->exact_churn, 1),
                fixed(f->occluder_triangles, 0), fixed(f->raster_ms, 2), fixed(f->occlusion_ms, 2), fixed(f->raster_rate / 1e6, 2),
                fixed(f->false_culls, 0), fixed(f->accuracy, 1),
                fixed(f->peak_mb, 0), fixed(f->seconds, 1), fixed(f->drawn, 0), fixed(f->triangles, 0),
                fixed(f->churn_pct, 2), fixed(f->psnr_db, 2)};
            md << "| " << name;
            csv << key;
            for (const std::string& c : cells) md << " | " << c, csv << "," << c;
            md << " |\n";
            csv << "\n";
        }
        md << "\nTargets (issue 14): streamed share <= 0.1 %, p99 <= 2x median, frame 0 <= 5x median, PVS churn "
              "within 2x the exact churn, 0 false culls, oc+lod no slower than lod; gen peak < 2 GB, prep peak <= a "
              "quarter of the input plus a fixed amount.\n\n"
           << "- oc+lod against lod on the walk, median, without drawing (the pipeline alone, a fast GPU's case): "
           << fixed(walk_.median_ms, 1) << " ms against " << fixed(walk_lod_.median_ms, 1) << " ms ("
           << fixed(walk_lod_.median_ms / walk_.median_ms, 2) << "x; issue 32's target, at most 1.25 x lod + 1 ms = "
           << fixed(1.25 * walk_lod_.median_ms + 1.0, 1) << " ms: " << (walk_.median_ms <= 1.25 * walk_lod_.median_ms + 1.0 ? "met" : "missed")
           << "); with drawing: " << fixed(walk_drawn_.median_ms, 1) << " ms against " << fixed(walk_lod_drawn_.median_ms, 1)
           << " ms (" << fixed(walk_lod_drawn_.median_ms / walk_drawn_.median_ms, 2) << "x)\n"
           << "- occlusion stage on the walk: " << fixed(walk_.occlusion_ms, 2) << " ms (issue 32's target: at most 6 ms on "
              "the 10^6 walk), raster " << fixed(walk_.raster_rate / 1e6, 1) << " M occluder triangles/s per core (target 40)\n"
           << "- p99 / median: walk " << fixed(walk_.p99_ms / walk_.median_ms, 2) << ", orbit "
           << fixed(orbit_.p99_ms / orbit_.median_ms, 2) << "; frame 0 / median: walk "
           << fixed(walk_.first_ms / walk_.median_ms, 1) << ", orbit " << fixed(orbit_.first_ms / orbit_.median_ms, 1) << "\n"
           << "- PVS churn / exact churn over the walk's prefix: " << fixed(exact_.churn / exact_.exact_churn, 2) << "\n";
        if (hierarchy_) writeHierarchyTargets(md);
        std::ostringstream pictures_csv;
        if (!picture_rows_.empty()) writePictures(md, pictures_csv);
        writeFileAtomic((out_ / "massive.md").string(), md.str());
        writeFileAtomic((out_ / "massive.csv").string(), csv.str());
        std::error_code ec;
        if (!picture_rows_.empty()) writeFileAtomic((out_ / "pictures.csv").string(), pictures_csv.str());
        else fs::remove(out_ / "pictures.csv", ec);  // an earlier run's would read as this one's
        std::fprintf(stderr, "bench massive: done in %.0f s\n", total);
        std::printf("%s\n", (out_ / "massive.md").c_str());
    }

    const BenchMassiveOptions& o_;
    fs::path out_, scenes_;
    Runner runner_;
    std::string exe_, step_;
    StepCost gen_, prep_, prep_flat_;
    bool made_ = false;
    uint64_t objects_ = 0, triangles_ = 0, oss_bytes_ = 0, input_bytes_ = 0;
    bool hierarchy_ = false;
    WalkFigures walk_, walk_lod_, orbit_, exact_, walk_drawn_, walk_lod_drawn_;
    WalkFigures walk_h_, orbit_h_, orbit_ref_, orbit_h_ref_, small_walk_h_, small_orbit_h_;
    std::vector<PictureRow> picture_rows_;
    std::string village_note_;  // why the village has no rows, where it has none
    size_t picture_runs_ = 0;    // the picture stage's own runs (the reference pair not counted)
    double picture_seconds_ = 0;
    RunResult grid_flat_, grid_h_;
    uint64_t grid_flat_bytes_ = 0, grid_h_bytes_ = 0, grid_inner_ = 0, grid_hlods_ = 0;

    // Issue 34's targets, each with its figure and whether it is met.
    void writeHierarchyTargets(std::ostringstream& md) const {
        const auto verdict = [](bool met) { return met ? "met" : "missed"; };
        md << "\nTargets (issue 34, the hierarchy; pipeline without drawing):\n\n"
           << "- orbit with the hierarchy: median " << fixed(orbit_h_.median_ms, 1) << " ms, p99 " << fixed(orbit_h_.p99_ms, 1)
           << " ms (target at most 16 / 32: " << verdict(orbit_h_.median_ms <= 16 && orbit_h_.p99_ms <= 32) << "); flat "
           << fixed(orbit_.median_ms, 1) << " / " << fixed(orbit_.p99_ms, 1) << " ms\n"
           << "- walk with the hierarchy: median " << fixed(walk_h_.median_ms, 1) << " ms, p99 " << fixed(walk_h_.p99_ms, 1)
           << " ms (target at most 16 / 32: " << verdict(walk_h_.median_ms <= 16 && walk_h_.p99_ms <= 32) << "); flat "
           << fixed(walk_.median_ms, 1) << " / " << fixed(walk_.p99_ms, 1) << " ms\n"
           << "- items drawn on the orbit with the hierarchy: " << fixed(orbit_h_.drawn, 0) << " (target at most 20000: "
           << verdict(orbit_h_.drawn <= 20000) << "); flat " << fixed(orbit_.drawn, 0) << "\n"
           << "- cut churn on the orbit: " << fixed(orbit_h_.churn_pct, 2) << " % of the cut per frame (target at most 2 %: "
           << verdict(orbit_h_.churn_pct <= 2) << ")\n";
        if (o_.reference_frames > 0)
            md << "- PSNR against the full-detail picture over the orbit's first " << o_.reference_frames << " frames: "
               << fixed(orbit_h_ref_.psnr_db, 2) << " dB with the hierarchy, " << fixed(orbit_ref_.psnr_db, 2)
               << " dB flat (target: equal or better: " << verdict(orbit_h_ref_.psnr_db >= orbit_ref_.psnr_db) << ")\n";
        if (o_.growth_objects < o_.objects)
            md << "- growth from the " << o_.growth_objects << "-object plant, medians with the hierarchy: orbit "
               << fixed(orbit_h_.median_ms / small_orbit_h_.median_ms, 2) << "x, walk "
               << fixed(walk_h_.median_ms / small_walk_h_.median_ms, 2) << "x (target at most 2x: "
               << verdict(orbit_h_.median_ms <= 2 * small_orbit_h_.median_ms && walk_h_.median_ms <= 2 * small_walk_h_.median_ms)
               << ")\n";
        const double bound_mb = double(input_bytes_) / 4e6 + 1536.0;
        md << "- prep with the hierarchy (prep's default): " << (std::isfinite(prep_.peak_mb) ? fixed(prep_.peak_mb, 0) + " MB peak" : std::string("n/a"))
           << " (target at most a quarter of the input plus 1.5 GB, " << fixed(bound_mb, 0) << " MB: "
           << (std::isfinite(prep_.peak_mb) ? verdict(prep_.peak_mb <= bound_mb) : "not known") << ")\n";
        if (std::isfinite(prep_.seconds) && std::isfinite(prep_flat_.seconds) && prep_flat_.seconds > 0)
            md << "- prep's time with the hierarchy: " << fixed(prep_.seconds, 1) << " s against " << fixed(prep_flat_.seconds, 1)
               << " s with `--hierarchy off`, run right after it (target at most 1.5x: "
               << verdict(prep_.seconds <= 1.5 * prep_flat_.seconds) << ", " << fixed(prep_.seconds / prep_flat_.seconds, 2) << "x)\n";
        else
            md << "- prep's time with the hierarchy against without: not measured (the scene was made by a build "
                  "that did not time `--hierarchy off`; remove it from the scenes folder to measure)\n";
        if (o_.grid > 0 && grid_flat_bytes_ > 0) {
            const std::string n = std::to_string(o_.grid);
            const double size_ratio = double(grid_h_bytes_) / double(grid_flat_bytes_);
            md << "- the engine grid (`gen grid --nx " << n << " --ny " << n << " --nz " << n << "`) prepared with the hierarchy: "
               << fixed(grid_h_.seconds, 1) << " s, " << fixed(grid_h_.peak_mb, 0) << " MB peak, "
               << fixed(double(grid_h_bytes_) / 1e6, 1) << " MB, " << grid_hlods_ << " HLODs for " << grid_inner_
               << " inner nodes; without it " << fixed(grid_flat_.seconds, 1) << " s, "
               << fixed(double(grid_flat_bytes_) / 1e6, 1) << " MB (target at most 10 s and 1.5x the size: "
               << verdict(grid_h_.seconds <= 10.0 && size_ratio <= 1.5) << ", " << fixed(size_ratio, 2) << "x)\n";
        }
    }

    // Issue 49's picture targets: massive.md's section, a row per scene, path and colours, then
    // the overall verdict; the same rows into `csv` (pictures.csv).
    void writePictures(std::ostringstream& md, std::ostringstream& csv) const {
        const auto verdict = [](bool met) { return std::string(met ? "met" : "missed"); };
        const auto by = [&](bool met, double margin, const char* unit) {
            return verdict(met) + " by " + fixed(std::fabs(margin), 2) + " " + unit;
        };
        md << "\n## Pictures against full detail (issue 49)\n\n"
           << "Each scene's walk and orbit, their first " << o_.reference_frames << " frames after the first, drawn with "
           << "`render --headless --reference --colours C --hierarchy off|on` (512x512, `--budget " << o_.budget
           << "`) against the full-detail picture: PSNR pooled over the frames (from their mean squared error), "
              "perceptible: mean % of pixels with CIEDE2000 > 2, SSIM: mean, beyond tau: % of the changed pixels "
              "measured that lie farther than tau (at least a pixel) from their item. Targets for the hierarchy against flat: PSNR at "
              "least flat - 1 dB, or " << fixed(kNearlyExactTargetPsnrDb, 0) << " dB where the flat run is nearly exact "
              "(at least " << fixed(kNearlyExactFlatPsnrDb, 0) << " dB); perceptible at most 1 point above flat; bound: "
              "at most 1 % beyond tau (its 99th percentile within tau). "
           << picture_runs_ << " runs and their scenes in " << fixed(picture_seconds_, 0)
           << " s; the plant's orbit in model colours is the reference pair above.\n\n"
           << "| scene | path | colours | PSNR dB flat | PSNR dB hierarchy | perceptible % flat | perceptible % hierarchy "
              "| SSIM flat | SSIM hierarchy | beyond tau % hierarchy | PSNR target | perceptible target | bound target |\n"
           << "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|---|\n";
        csv << "scene,path,colours,flat_psnr_db,hierarchy_psnr_db,flat_perceptible_pct,hierarchy_perceptible_pct,flat_ssim,"
               "hierarchy_ssim,hierarchy_beyond_tau_pct,psnr_target,psnr_margin_db,perceptible_target,"
               "perceptible_margin_points,bound_target\n";
        int met = 0, targets = 0;
        for (const PictureRow& row : picture_rows_) {
            const WalkFigures &f = row.flat, &h = row.hierarchy;
            const PictureVerdict v = pictureVerdict(f, h);
            met += v.met();
            targets += 3;
            const std::vector<std::string> figures = {
                fixed(f.pooled_psnr_db, 2), fixed(h.pooled_psnr_db, 2), fixed(f.perceptible_pct, 3),
                fixed(h.perceptible_pct, 3), fixed(f.ssim, 4), fixed(h.ssim, 4), fixed(h.beyond_tau_pct, 2)};
            md << "| " << row.label << " | " << row.path << " | " << row.colours;
            for (const std::string& c : figures) md << " | " << c;
            md << " | " << by(v.psnr_met, v.psnr_margin_db, "dB") << " | "
               << by(v.perceptible_met, v.perceptible_margin_points, "points") << " | " << verdict(v.bound_met) << " |\n";
            csv << row.scene << "," << row.path << "," << row.colours;
            for (const std::string& c : figures) csv << "," << c;
            csv << "," << verdict(v.psnr_met) << "," << fixed(v.psnr_margin_db, 2) << "," << verdict(v.perceptible_met)
                << "," << fixed(v.perceptible_margin_points, 3) << "," << verdict(v.bound_met) << "\n";
        }
        md << "\n";
        if (!village_note_.empty()) md << "- KIT village: " << village_note_ << "\n";
        md << "- every picture target met: " << (met == targets ? "yes" : "no") << " (" << met << " of " << targets << ")\n";
    }
};

}  // namespace

int runBenchMassive(const BenchMassiveOptions& options) {
    if (options.out.empty()) throw UsageError("bench massive: --out DIR is required");
    if (options.objects < 1000) throw UsageError("bench massive: --objects " + std::to_string(options.objects) + ": at least 1000");
    if (options.frames < 12) throw UsageError("bench massive: --frames " + std::to_string(options.frames) + ": at least 12");
    if (options.exact_frames < 2 || options.exact_frames > options.frames)
        throw UsageError("bench massive: --exact-frames " + std::to_string(options.exact_frames) + ": 2 to --frames");
    if (options.reference_frames == 1 || options.reference_frames > options.frames)
        throw UsageError("bench massive: --reference-frames " + std::to_string(options.reference_frames) +
                         ": 0 (none) or 2 to --frames");
    if (options.picture_objects > 0 && options.picture_objects < 100)
        throw UsageError("bench massive: --picture-objects " + std::to_string(options.picture_objects) +
                         ": 0 (none) or at least 100");
    const InterruptHandlers interrupts;  // Ctrl-C and SIGTERM stop the running child, then the benchmark
    return Massive(options).run();
}

}  // namespace occ::bench
