// SPDX-License-Identifier: MIT
#include "bench/bench_ranks.h"

#include "bench/runner.h"
#include "cli/commands.h"
#include "net/messages.h"
#include "scene/atomic_file.h"
#include "scene/oss_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <map>
#include <set>

namespace occ::bench {

namespace {


// `mpirun -np N` with this project's fault grace (docs/protocol.md), as root where needed.
std::vector<std::string> mpirunArgv(const std::string& mpirun, int ranks) {
    std::vector<std::string> argv{mpirun, "-np", std::to_string(ranks), "--oversubscribe", "--mca",
                                  "odls_base_sigkill_timeout", "3"};
    if (::geteuid() == 0) argv.push_back("--allow-run-as-root");
    return argv;
}

// A benchmark's own scene in OUT/scenes: generated (gen_args after `occswitch gen`) and prepared
// (prep_args after the output) once, reused by later runs.
fs::path sceneOnce(Runner& runner, const std::string& exe, const fs::path& oss, std::vector<std::string> gen_args,
                   const std::vector<std::string>& prep_args) {
    if (fs::exists(oss)) return oss;
    fs::path glb = oss;
    glb.replace_extension(".glb");
    std::vector<std::string> gen{exe, "gen"};
    gen.insert(gen.end(), gen_args.begin(), gen_args.end());
    gen.insert(gen.end(), {"-o", glb.string()});
    runner.run("gen", gen);
    std::vector<std::string> prep{exe, "prep", glb.string(), "-o", oss.string()};
    prep.insert(prep.end(), prep_args.begin(), prep_args.end());
    runner.run("prep", prep);
    fs::remove(glb);
    return oss;
}

// What one layout's run measured (frames after the first).
struct Layout {
    int ranks = 0;
    uint64_t frames = 0;
    double camera = 0, delta = 0, eof = 0, composite = 0;  // bytes per frame, every rank's
    double ms_composite = 0;                               // rank 0, per frame
    double latency_frames = 0, latency_ms = 0;
    struct Rank {
        std::string role, partition;
        double busy = 0, wait = 0;  // ms per frame
        double active_triangles = 0;
    };
    std::map<int, Rank> per_rank;
    std::vector<std::string> full_set_hash;  // per frame, the whole visible set
    // Stage costs (ms per frame): the switch's OR and HC, the display's streaming + reform + draw.
    double or_ms = 0, hc_ms = 0, rvg_ms = 0;
    double max_partition_share = 1;  // the busiest display rank's share of active triangles (mean)
    uint64_t same_pictures = 0, pictures = 0;
};

double num(const CsvTable& t, size_t row, const char* column) {
    if (!t.has(column)) return 0;
    const double v = t.num(row, column);
    return std::isfinite(v) ? v : 0;
}

Layout measure(int ranks, const fs::path& csv) {
    const CsvTable t = CsvTable::read(csv.string());
    Layout l;
    l.ranks = ranks;
    std::map<uint64_t, std::string> hashes;
    std::map<int, uint64_t> rows_of;
    std::map<uint64_t, std::vector<double>> partition_triangles;
    uint64_t or_rows = 0, rvg_rows = 0;
    for (size_t r = 0; r < t.rows(); ++r) {
        const uint64_t frame = uint64_t(t.num(r, "frame"));
        const int rank = int(t.num(r, "rank"));
        const std::string role = t.text(r, t.col("role"));
        const bool display = role != "or+hc";
        const bool whole = ranks <= 3 ? rank == 0 : !display;  // the row that carries the whole set
        if (whole) hashes[frame] = t.text(r, t.col("visible_hash"));
        if (frame == 0) continue;
        l.camera += num(t, r, "bytes_camera");
        l.delta += num(t, r, "bytes_delta");
        l.eof += num(t, r, "bytes_eof");
        l.composite += num(t, r, "bytes_composite");
        Layout::Rank& k = l.per_rank[rank];
        k.role = role;
        k.partition = t.text(r, t.col("partition"));
        k.busy += num(t, r, "ms_total") + num(t, r, "ms_draw") + num(t, r, "ms_composite");
        k.wait += num(t, r, "ms_wait");
        k.active_triangles += display ? num(t, r, "active_triangles") : 0;
        rows_of[rank] += 1;
        if (rank == 0) {
            l.frames += 1;
            l.ms_composite += num(t, r, "ms_composite");
            l.latency_frames += num(t, r, "latency_frames");
            l.latency_ms += num(t, r, "latency_ms");
        }
        if (role != "rvg") {  // OR + HC (the culling ranks, or the one rank)
            l.or_ms += num(t, r, "ms_occluder_select") + num(t, r, "ms_depth_raster") + num(t, r, "ms_hzm_build");
            l.hc_ms += num(t, r, "ms_frustum_cull") + num(t, r, "ms_hzm_test") + num(t, r, "ms_lod_select") +
                       num(t, r, "ms_scan");
            ++or_rows;
        }
        if (display) {
            l.rvg_ms += num(t, r, "ms_stream_collect") + num(t, r, "ms_defragment") + num(t, r, "ms_reform") +
                        num(t, r, "ms_draw");
            ++rvg_rows;
            partition_triangles[frame].push_back(num(t, r, "active_triangles"));
        }
    }
    const double n = double(std::max<uint64_t>(1, l.frames));
    l.camera /= n, l.delta /= n, l.eof /= n, l.composite /= n, l.ms_composite /= n;
    l.latency_frames /= n, l.latency_ms /= n;
    for (auto& [rank, k] : l.per_rank) {
        const double m = double(std::max<uint64_t>(1, rows_of[rank]));
        k.busy /= m, k.wait /= m, k.active_triangles /= m;
    }
    l.or_ms /= double(std::max<uint64_t>(1, or_rows));
    l.hc_ms /= double(std::max<uint64_t>(1, or_rows));
    // The display work of a frame, all display ranks together (what one display would do).
    l.rvg_ms /= double(std::max<size_t>(1, partition_triangles.size()));
    (void)rvg_rows;
    double share = 0;
    for (const auto& [frame, tri] : partition_triangles) {
        double sum = 0, most = 0;
        for (double v : tri) sum += v, most = std::max(most, v);
        share += sum > 0 ? most / sum : 1.0 / double(tri.size());
    }
    l.max_partition_share = partition_triangles.empty() ? 1 : share / double(partition_triangles.size());
    for (const auto& [frame, h] : hashes) l.full_set_hash.push_back(h);
    return l;
}

// The cluster model of docs/scaling.md: ms per frame of each stage for 2 + P ranks (P = 1: the
// 3-rank switch) on a link of `gbps`, from the stage costs measured on one machine.
struct Prediction {
    double switch_ms, display_ms, composite_ms, fps;
};

Prediction predict(const Layout& measured, int partitions, double gbps, uint32_t width, uint32_t height,
                   double imbalance) {
    constexpr double kLinkLatencyMs = 0.005;  // one MPI message between nodes (5 us)
    constexpr double kMergeNsPerPixel = 1.0;  // the compositing op, memory-bound
    const double pixels = double(width) * double(height);
    const double image_bytes = pixels * 12.0;  // DepthPixel
    const double bytes_per_ms = gbps * 1e9 / 8.0 / 1000.0;
    const double p = double(partitions);
    Prediction r{};
    // The switch: each of its ranks has two frame periods for one OR and one HC (they alternate).
    r.switch_ms = 0.5 * (measured.or_ms + measured.hc_ms) + 2 * kLinkLatencyMs;
    // A display rank: its partition's share of streaming, reform and drawing (the busiest one's).
    r.display_ms = measured.rvg_ms * std::min(1.0, imbalance / p);
    // Reduce-scatter then gather: each rank sends (P-1)/P of its image and receives as much, then
    // one block to rank 0, which receives (P-1)/P of an image; log2 P message rounds.
    if (partitions > 1)
        r.composite_ms = (2.0 * (p - 1.0) / p * image_bytes) / bytes_per_ms +
                         std::ceil(std::log2(p)) * 2 * kLinkLatencyMs + (p - 1.0) / p * pixels * kMergeNsPerPixel / 1e6;
    r.fps = 1000.0 / std::max(r.switch_ms, r.display_ms + r.composite_ms);
    return r;
}

}  // namespace

int runBenchRanks(const BenchRanksOptions& o) {
    uint32_t width = 0, height = 0;
    cli::parseViewportSize("--size", o.size, width, height);
    if (o.ranks.empty()) throw UsageError("bench ranks: --ranks needs at least one layout");
    for (int n : o.ranks)
        if (n < 1 || n > 64) throw UsageError("bench ranks: --ranks " + std::to_string(n) + ": expected 1 to 64");
    if (o.frames < 3) throw UsageError("bench ranks: --frames must be at least 3");
    const std::string mpirun = findInPath("mpirun");
    if (mpirun.empty() && (o.ranks.size() > 1 || o.ranks.front() > 1))
        throw SystemError("bench ranks: mpirun not found (run launch/setup)");
    const InterruptHandlers interrupts;
    const fs::path out(o.out);
    makeOutputFolder(o.out);
    for (const char* sub : {"scenes", "raw", "logs", "frames"}) fs::create_directories(out / sub);
    Runner runner(out / "logs", o.run_timeout_s, "bench ranks");
    const std::string exe = selfExecutable();

    fs::path scene = o.scene;
    if (scene.empty())
        // Flat: render refines a hierarchy on 1 to 3 ranks but not on 2 + P (partitions of
        // objects), and every layout here must cull the same sets (issue 49).
        scene = sceneOnce(runner, exe, out / "scenes" / ("plant_" + std::to_string(o.objects) + ".oss"),
                          {"plant", "--objects", std::to_string(o.objects)}, {"--hierarchy", "off"});
    const OssFile file = OssFile::open(scene.string());
    const fs::path cam = out / "scenes" / ("walk" + std::to_string(o.frames) + ".cam");
    runner.run("path", {exe, "path", "walk", scene.string(), "--frames", std::to_string(o.frames), "-o", cam.string()});

    std::vector<Layout> layouts;
    for (int n : o.ranks) {
        const std::string name = "np" + std::to_string(n);
        std::vector<std::string> argv = n > 1 ? mpirunArgv(mpirun, n) : std::vector<std::string>();
        const fs::path frames = out / "frames" / name;
        fs::remove_all(frames);
        // Every layout with the 3-rank switch's occluders (the PVS two frames back), so that all
        // must cull the same sets and draw the same pictures.
        for (const std::string& a : {exe, std::string("render"), scene.string(), std::string("--path"), cam.string(),
                                     std::string("--headless"), std::string("--size"), o.size, std::string("--budget"),
                                     std::string("10%"), std::string("--pvs-occluder-lag"), std::string("2"),
                                     std::string("--stats"), (out / "raw" / (name + ".csv")).string(),
                                     std::string("--out"), frames.string(), std::string("--sort-last-cells"),
                                     std::to_string(o.sort_last_cells)})
            argv.push_back(a);
        const RunResult r = runner.run(name, argv);
        Layout l = measure(n, out / "raw" / (name + ".csv"));
        for (const auto& entry : fs::directory_iterator(frames)) {
            const fs::path first = out / "frames" / ("np" + std::to_string(o.ranks.front())) / entry.path().filename();
            l.pictures += 1;
            l.same_pictures += fs::exists(first) && readText(first) == readText(entry.path());
        }
        std::fprintf(stderr, "bench ranks: %d rank%s: %llu frames, %.0f bytes/frame of messages, %.0f composited, "
                             "latency %.2f frames (%.1f s)\n",
                     n, n > 1 ? "s" : "", static_cast<unsigned long long>(l.frames), l.camera + l.delta + l.eof,
                     l.composite, l.latency_frames, r.seconds);
        layouts.push_back(std::move(l));
    }
    const Layout& reference = layouts.front();

    std::ostringstream md, csv, per_rank;
    csv << "ranks,displays,frames,bytes_camera,bytes_delta,bytes_eof,bytes_composite,ms_composite,latency_frames,"
           "latency_ms,same_visible_sets,same_pictures,pictures,max_partition_share\n";
    md << "# Layouts against ranks (`occswitch bench ranks`)\n\n"
       << "Scene " << scene.filename().string() << " (" << file.objectCount() << " objects), a " << o.frames
       << "-camera walk, `render --headless --size " << o.size << " --budget 10% --pvs-occluder-lag 2 --sort-last-cells "
       << o.sort_last_cells << "`,\n"
       << "every layout through mpirun on this one machine (oversubscribed: the bytes, latency and\n"
       << "correctness carry over to a cluster, the times do not). Per frame after the first; bytes are\n"
       << "what every rank sent. Visible sets and pictures are compared with the " << reference.ranks
       << "-rank run's.\n\n"
       << "| ranks | display ranks | camera B | delta B | end-of-frame B | composite B | composite ms | "
          "latency frames | latency ms | same visible sets | same pictures |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|\n";
    per_rank << "| ranks | rank | role | partition | busy ms | wait ms | active triangles |\n|---|---|---|---|---|---|---|\n";
    std::string rank_csv = "ranks,rank,role,partition,busy_ms,wait_ms,active_triangles\n";
    for (const Layout& l : layouts) {
        const int displays = l.ranks <= 3 ? 1 : l.ranks - 2;
        const bool same_sets = l.full_set_hash == reference.full_set_hash;
        csv << l.ranks << "," << displays << "," << l.frames << "," << fixed(l.camera, 1) << "," << fixed(l.delta, 1)
            << "," << fixed(l.eof, 1) << "," << fixed(l.composite, 1) << "," << fixed(l.ms_composite, 3) << ","
            << fixed(l.latency_frames, 3) << "," << fixed(l.latency_ms, 3) << "," << (same_sets ? 1 : 0) << ","
            << l.same_pictures << "," << l.pictures << "," << fixed(l.max_partition_share, 3) << "\n";
        md << "| " << l.ranks << " | " << displays << " | " << fixed(l.camera, 0) << " | " << fixed(l.delta, 0) << " | "
           << fixed(l.eof, 0) << " | " << fixed(l.composite, 0) << " | " << fixed(l.ms_composite, 2) << " | "
           << fixed(l.latency_frames, 2) << " | " << fixed(l.latency_ms, 2) << " | " << (same_sets ? "yes" : "**no**")
           << " | " << l.same_pictures << " of " << l.pictures << " |\n";
        for (const auto& [rank, k] : l.per_rank) {
            per_rank << "| " << l.ranks << " | " << rank << " | " << k.role << " | " << k.partition << " | "
                     << fixed(k.busy, 2) << " | " << fixed(k.wait, 2) << " | " << fixed(k.active_triangles, 0) << " |\n";
            rank_csv += std::to_string(l.ranks) + "," + std::to_string(rank) + "," + k.role + "," + k.partition + "," +
                        fixed(k.busy, 3) + "," + fixed(k.wait, 3) + "," + fixed(k.active_triangles, 0) + "\n";
        }
    }
    md << "\nBusy is a rank's own work per frame (its pipeline stages, drawing and compositing), wait the\n"
       << "time it spent blocked on a message.\n\n" << per_rank.str();

    // The model, fed with the 3-rank run's stage costs (or the largest measured layout's).
    const Layout* base = &layouts.back();
    for (const Layout& l : layouts)
        if (l.ranks == 3) base = &l;
    // The busiest display rank's triangle share times P, mean of the sort-last runs (1: balanced).
    double imbalance = 0;
    int sort_last = 0;
    for (const Layout& l : layouts)
        if (l.ranks > 3) imbalance += l.max_partition_share * double(l.ranks - 2), ++sort_last;
    imbalance = sort_last ? imbalance / double(sort_last) : 1.0;
    std::ostringstream model_csv;
    model_csv << "display_ranks,ranks,link_gbps,width,height,switch_ms,display_ms,composite_ms,fps\n";
    md << "\n## The cluster model (docs/scaling.md)\n\nStage costs measured here (" << base->ranks
       << " ranks): OR " << fixed(base->or_ms, 2) << " ms, HC " << fixed(base->hc_ms, 2)
       << " ms, the display's streaming + reform + draw " << fixed(base->rvg_ms, 2)
       << " ms per frame; display imbalance (busiest display rank's triangle share x P) " << fixed(imbalance, 2)
       << ". Predicted fps:\n\n| display ranks |";
    for (double g : o.link_gbps) md << " " << fixed(g, 0) << " Gb/s, " << o.size << " | " << fixed(g, 0) << " Gb/s, 2048x2048 |";
    md << "\n|---|";
    for (size_t i = 0; i < o.link_gbps.size(); ++i) md << "---|---|";
    md << "\n";
    for (int p : {1, 2, 4, 8, 16}) {
        md << "| " << p << " |";
        for (double g : o.link_gbps)
            for (const auto& [w, h] : {std::pair<uint32_t, uint32_t>{width, height}, {2048u, 2048u}}) {
                const Prediction r = predict(*base, p, g, w, h, imbalance);
                model_csv << p << "," << (p == 1 ? 3 : p + 2) << "," << g << "," << w << "," << h << ","
                          << fixed(r.switch_ms, 3) << "," << fixed(r.display_ms, 3) << "," << fixed(r.composite_ms, 3)
                          << "," << fixed(r.fps, 1) << "\n";
                md << " " << fixed(r.fps, 1) << " |";
            }
        md << "\n";
    }
    writeFileAtomic((out / "ranks.csv").string(), csv.str());
    writeFileAtomic((out / "ranks_per_rank.csv").string(), rank_csv);
    writeFileAtomic((out / "model.csv").string(), model_csv.str());
    writeFileAtomic((out / "ranks.md").string(), md.str());
    std::printf("%s\n", (out / "ranks.md").c_str());
    bool all_same = true;
    for (const Layout& l : layouts) all_same = all_same && l.full_set_hash == reference.full_set_hash;
    if (!all_same) {
        std::fprintf(stderr, "bench ranks: a layout culled other visible sets than %d rank(s): see %s\n",
                     reference.ranks, (out / "ranks.md").c_str());
        return 1;
    }
    return 0;
}

namespace {

// One run of bench links: a layout over one link (or none).
struct LinkRun {
    int ranks = 0;
    double latency_ms = 0, mbps = 0;  // mbps 0: no emulation (when latency is 0 too)
    bool saturating = false;
    Layout layout;
    uint64_t shown = 0, skipped = 0, poses = 0;
    double fps = 0;                       // frames shown per second of the path
    double n = 0, delta_messages = 0;     // delta entries (added + removed + changed), messages, per frame
    double busiest_rank_bytes = 0;        // the most a rank sent per frame
    double display_wait = 0, max_wait = 0;  // ms per frame
};

std::string linkLabel(const LinkRun& r) {
    if (r.latency_ms == 0 && r.mbps == 0) return "none";
    return fixed(r.latency_ms, r.latency_ms < 1 && r.latency_ms > 0 ? 1 : 0) + " ms, " +
           (r.mbps >= 1000 ? fixed(r.mbps / 1000, 0) + " Gb/s" : fixed(r.mbps, r.mbps < 10 ? 3 : 0) + " Mb/s");
}

// SWITCH's bytes per frame, Govindaraju et al. 2003: 8n + nh/b + 3(72 + h), n entries of the
// visible set's change, h header bytes, b entries per packet (so nh/b = h per packet sent).
double switchModelBytes(double n, double packets, double h) { return 8.0 * n + packets * h + 3.0 * (72.0 + h); }

}  // namespace

namespace {

void checkLinksOptions(const BenchLinksOptions& o) {
    uint32_t width = 0, height = 0;
    cli::parseViewportSize("--size", o.size, width, height);
    if (o.layouts.empty()) throw UsageError("bench links: --layouts needs at least one rank count");
    for (int n : o.layouts)
        if (n < 3 || n > 64) throw UsageError("bench links: --layouts " + std::to_string(n) + ": expected 3 to 64 (the switch, or 2 + P)");
    for (double l : o.latencies_ms)
        if (!(l >= 0 && l <= 10000)) throw UsageError("bench links: --latencies " + fixed(l, 3) + ": expected 0 to 10000 ms");
    for (double b : o.mbps)
        if (!(b > 0 && b <= 1e7)) throw UsageError("bench links: --mbps " + fixed(b, 3) + ": expected (0, 10^7] Mb/s");
    if (o.frames < 10) throw UsageError("bench links: --frames must be at least 10");
    if (!(o.path_fps > 0 && o.path_fps <= 1000)) throw UsageError("bench links: --path-fps must be in (0, 1000]");
    if (!(o.saturate_fps >= 0 && o.saturate_fps < o.path_fps))
        throw UsageError("bench links: --saturate-fps must be in [0, --path-fps)");
}

// The runs of bench links: the scene, its walk and mpirun, and one paced render per link.
struct LinkPlayer {
    const BenchLinksOptions& o;
    Runner& runner;
    const std::string& exe;
    const std::string& mpirun;
    const fs::path& out;
    const fs::path& scene;
    const fs::path& cam;

    LinkRun play(int ranks, double latency_ms, double mbps, bool saturating) {
    LinkRun run;
    run.ranks = ranks, run.latency_ms = latency_ms, run.mbps = mbps, run.saturating = saturating;
    std::string name = "np" + std::to_string(ranks) + "_";
    name += (latency_ms == 0 && mbps == 0) ? std::string("none") : fixed(latency_ms, 1) + "ms_" + fixed(mbps, 3) + "mbps";
    const fs::path csv = out / "raw" / (name + ".csv");
    std::vector<std::string> argv = mpirunArgv(mpirun, ranks);
    for (const std::string& a : {exe, std::string("render"), scene.string(), std::string("--path"), cam.string(),
                                 std::string("--headless"), std::string("--size"), o.size, std::string("--pace"),
                                 std::string("recorded"), std::string("--path-fps"), fixed(o.path_fps, 3),
                                 std::string("--stats"), csv.string()})
        argv.push_back(a);
    if (latency_ms > 0 || mbps > 0) {
        argv.push_back("--link");
        argv.push_back(fixed(latency_ms, 3) + (mbps > 0 ? ":" + fixed(mbps, 6) : std::string()));
    }
    const fs::path summary = out / "raw" / (name + ".summary.json");
    argv.push_back("--summary");
    argv.push_back(summary.string());
    const RunResult r = runner.run(name, argv);
    run.layout = measure(ranks, csv);
    // The poses the paced run showed and skipped, from its summary (render --summary).
    try {
        const nlohmann::json pace = nlohmann::json::parse(readText(summary)).at("pace");
        run.shown = pace.at("frames_shown").get<uint64_t>();
        run.skipped = pace.at("poses_skipped").get<uint64_t>();
    } catch (const nlohmann::json::exception& e) {
        throw InputError(summary.string(), std::string("no pace in the render summary: ") + e.what());
    }
    const uint64_t shown = run.shown, skipped = run.skipped;
    run.poses = shown + skipped;
    run.fps = double(shown) * o.path_fps / double(std::max<uint64_t>(1, run.poses));
    // Per frame: the delta entries and messages, and the bytes each rank sent.
    const CsvTable t = CsvTable::read(csv.string());
    std::map<int, double> sent;
    double rows0 = 0;
    for (size_t i = 0; i < t.rows(); ++i) {
        if (t.num(i, "frame") == 0) continue;
        const int rank = int(t.num(i, "rank"));
        run.n += num(t, i, "delta_added") + num(t, i, "delta_removed") + num(t, i, "delta_changed");
        run.delta_messages += num(t, i, "msgs_delta");
        sent[rank] += num(t, i, "bytes_camera") + num(t, i, "bytes_delta") + num(t, i, "bytes_eof") +
                      num(t, i, "bytes_composite");
        rows0 += rank == 0;
    }
    const double frames = std::max(1.0, rows0);
    run.n /= frames, run.delta_messages /= frames;
    for (const auto& [rank, bytes] : sent) run.busiest_rank_bytes = std::max(run.busiest_rank_bytes, bytes / frames);
    for (const auto& [rank, k] : run.layout.per_rank) {
        run.max_wait = std::max(run.max_wait, k.wait);
        if (rank == 0) run.display_wait = k.wait;
    }
    std::fprintf(stderr, "bench links: %d ranks, link %s: %.1f fps shown, latency %.2f frames / %.1f ms, %llu of %llu "
                         "poses skipped (%.1f s)\n",
                 ranks, linkLabel(run).c_str(), run.fps, run.layout.latency_frames, run.layout.latency_ms,
                 static_cast<unsigned long long>(skipped), static_cast<unsigned long long>(shown + skipped), r.seconds);
    return run;
    }
};

// links.csv and links.md from the runs.
void writeLinksTables(const BenchLinksOptions& o, const std::vector<LinkRun>& runs, const fs::path& out,
                      const fs::path& scene, const OssFile& file) {
    const double h = double(kMessageHeaderSize);
    std::ostringstream md, csv;
    csv << "ranks,link,latency_ms,mbps,saturating,frames_shown,poses_skipped,fps,latency_frames,display_latency_ms,"
           "bytes_camera,bytes_delta,bytes_eof,bytes_total,delta_entries,delta_messages,switch_model_bytes,"
           "busiest_rank_bytes,max_fps_link,display_wait_ms,max_wait_ms\n";
    md << "# Emulated links (`occswitch bench links`)\n\n"
       << "Scene " << scene.filename().string() << " (" << file.objectCount() << " objects), a " << o.frames
       << "-camera walk played in real time (`--pace recorded --path-fps " << fixed(o.path_fps, 0)
       << "`), `render --headless --size " << o.size << "` with deltas, through mpirun on this one machine,\n"
       << "every link emulated in the transport (`render --link LATENCY_MS:MBPS`, between every pair of ranks).\n"
       << "fps: frames shown per second of the path; latency: camera to display, in frames and ms; bytes: per\n"
       << "frame after the first, every rank's; wait: ms per frame a rank was blocked on a message (the\n"
       << "display's, and the most of any rank). SWITCH's model: 8n + nh/b + 3(72 + h) with n the measured\n"
       << "delta entries, h = " << fixed(h, 0) << " (our header), n/b the delta messages. Max fps: what the busiest rank's bytes\n"
       << "per frame (messages and sort-last pixels) allow on the link (all its destinations together, so a\n"
       << "bound from below: each of its links carries only part of them). The narrow link is the one that bound puts at --saturate-fps\n"
       << "for the run without emulation.\n\n"
       << "| ranks | link | fps | latency frames | latency ms | skipped | camera B | delta B | eof B | SWITCH model B | "
          "measured / model | max fps on the link | display wait ms | max wait ms |\n"
       << "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for (const LinkRun& r : runs) {
        const double total = r.layout.camera + r.layout.delta + r.layout.eof;
        const double model = switchModelBytes(r.n, r.delta_messages, h);
        const double max_fps = r.mbps > 0 && r.busiest_rank_bytes > 0 ? r.mbps * 1e6 / 8.0 / r.busiest_rank_bytes : 0;
        std::string label = linkLabel(r);
        std::replace(label.begin(), label.end(), ',', ';');  // a CSV field
        csv << r.ranks << "," << label << "," << fixed(r.latency_ms, 3) << "," << fixed(r.mbps, 6) << ","
            << (r.saturating ? 1 : 0) << "," << r.shown << "," << r.skipped << "," << fixed(r.fps, 2) << ","
            << fixed(r.layout.latency_frames, 3) << "," << fixed(r.layout.latency_ms, 3) << "," << fixed(r.layout.camera, 1)
            << "," << fixed(r.layout.delta, 1) << "," << fixed(r.layout.eof, 1) << "," << fixed(total, 1) << ","
            << fixed(r.n, 2) << "," << fixed(r.delta_messages, 3) << "," << fixed(model, 1) << ","
            << fixed(r.busiest_rank_bytes, 1) << "," << fixed(max_fps, 1) << "," << fixed(r.display_wait, 3) << ","
            << fixed(r.max_wait, 3) << "\n";
        md << "| " << r.ranks << " | " << linkLabel(r) << (r.saturating ? " (narrow)" : "") << " | " << fixed(r.fps, 1)
           << " | " << fixed(r.layout.latency_frames, 2) << " | " << fixed(r.layout.latency_ms, 1) << " | " << r.skipped
           << " of " << r.poses << " | " << fixed(r.layout.camera, 0) << " | " << fixed(r.layout.delta, 0) << " | "
           << fixed(r.layout.eof, 0) << " | " << fixed(model, 0) << " | " << fixed(model > 0 ? total / model : 0, 2)
           << " | " << (max_fps > 0 ? fixed(max_fps, max_fps < 100 ? 1 : 0) : std::string("-")) << " | "
           << fixed(r.display_wait, 2) << " | " << fixed(r.max_wait, 2) << " |\n";
    }
    // Where a frame's time goes on the slowest link of each layout, against no emulation.
    md << "\n## The latency budget\n\nPer layout, the run without emulation and the one over the longest link\n"
       << "latency at the lowest bandwidth: the display's frame (1000 / fps shown), the display's wait for\n"
       << "messages, its own work (streaming, reform, drawing, and with 2 + P compositing, of which the\n"
       << "composite column, the pixels' time on the link included), the culling ranks' occluder raster + HZM\n"
       << "(OR) and culling + LOD (HC) per frame, and the camera-to-display latency. One frame of latency\n"
       << "holds when the switch skips cameras instead of falling further behind.\n\n"
       << "| ranks | link | frame ms | display wait ms | display work ms | composite ms | OR ms | HC ms | latency frames | latency ms |\n"
       << "|---|---|---|---|---|---|---|---|---|---|\n";
    for (int ranks : o.layouts) {
        const LinkRun* none = nullptr;
        const LinkRun* slow = nullptr;
        for (const LinkRun& r : runs) {
            if (r.ranks != ranks || r.saturating) continue;
            if (r.latency_ms == 0 && r.mbps == 0) none = &r;
            else if (!slow || r.latency_ms > slow->latency_ms ||
                     (r.latency_ms == slow->latency_ms && r.mbps < slow->mbps))
                slow = &r;
        }
        for (const LinkRun* r : {none, slow}) {
            if (!r) continue;
            const auto d = r->layout.per_rank.find(0);
            const double work = d == r->layout.per_rank.end() ? 0 : d->second.busy;
            md << "| " << ranks << " | " << linkLabel(*r) << " | " << fixed(r->fps > 0 ? 1000.0 / r->fps : 0, 1) << " | "
               << fixed(r->display_wait, 2) << " | " << fixed(work, 2) << " | " << fixed(r->layout.ms_composite, 2) << " | "
               << fixed(r->layout.or_ms, 2) << " | "
               << fixed(r->layout.hc_ms, 2) << " | " << fixed(r->layout.latency_frames, 2) << " | "
               << fixed(r->layout.latency_ms, 1) << " |\n";
        }
    }
    md << "\nMeasured bytes differ from SWITCH's formula where our messages differ from its packets: a\n"
       << "camera packet is " << fixed(h + kCameraPayloadSize, 0) << " bytes (72 + h would be " << fixed(72 + h, 0)
       << "), a delta carries a " << kDeltaPayloadHeaderSize << "-byte payload header with its hash,\n"
       << "a removal costs 4 bytes and an addition or LOD change 8, and every frame adds end-of-frame\n"
       << "messages (" << fixed(h + kEndOfFramePayloadSize, 0) << " bytes each) that the formula has no term for.\n";
    writeFileAtomic((out / "links.csv").string(), csv.str());
    writeFileAtomic((out / "links.md").string(), md.str());
}

// plots/links.png (fps and latency against the link's latency), when gnuplot is there.
void plotLinks(const BenchLinksOptions& o, Runner& runner, const fs::path& out) {
    const std::string gnuplot = findInPath("gnuplot");
    if (!gnuplot.empty()) {
        const fs::path script = out / "plots" / "links.gp";
        std::string gp =
            "# links.png from links.csv of `occswitch bench links`; run from the results folder\n"
            "set datafile separator ','\nset terminal pngcairo size 1100,460 font 'sans,10' noenhanced\n"
            "set output 'plots/links.png'\nset grid ytics lc rgb '#dddddd'\nset key autotitle columnhead\n"
            "set multiplot layout 1,2 title 'Emulated links: the switch with paced cameras'\n"
            "set xlabel 'link latency (ms)'\nset logscale x 10\nset ylabel 'fps shown'\n"
            "set title 'frames per second'\nplot ";
        std::string lat = "set title 'camera-to-display latency'\nset ylabel 'ms'\nplot ";
        bool first = true;
        for (int ranks : o.layouts)
            for (double mbps : o.mbps) {
                const std::string filter = "(column('ranks') == " + std::to_string(ranks) + " && column('mbps') == " +
                                           fixed(mbps, 6) + " && column('saturating') == 0 ? ";
                const std::string title = std::to_string(ranks) + " ranks, " +
                                          (mbps >= 1000 ? fixed(mbps / 1000, 0) + " Gb/s" : fixed(mbps, 0) + " Mb/s");
                gp += std::string(first ? "" : ", ") + "'links.csv' using (column('latency_ms') > 0 ? column('latency_ms') : 0.05):" +
                      filter + "column('fps') : 1/0) with linespoints title '" + title + "'";
                lat += std::string(first ? "" : ", ") + "'links.csv' using (column('latency_ms') > 0 ? column('latency_ms') : 0.05):" +
                       filter + "column('display_latency_ms') : 1/0) with linespoints title '" + title + "'";
                first = false;
            }
        writeFileAtomic(script.string(), gp + "\n" + lat + "\nunset multiplot\n");
        runner.run("gnuplot_links", {gnuplot, "-e", "cd '" + fs::absolute(out).string() + "'", fs::absolute(script).string()});
    }
}

}  // namespace

int runBenchLinks(const BenchLinksOptions& o) {
    checkLinksOptions(o);
    const std::string mpirun = findInPath("mpirun");
    if (mpirun.empty()) throw SystemError("bench links: mpirun not found (run launch/setup)");
    const InterruptHandlers interrupts;
    const fs::path out(o.out);
    makeOutputFolder(o.out);
    for (const char* sub : {"scenes", "raw", "logs", "plots"}) fs::create_directories(out / sub);
    Runner runner(out / "logs", o.run_timeout_s, "bench links");
    const std::string exe = selfExecutable();

    fs::path scene = o.scene;
    if (scene.empty())
        scene = sceneOnce(runner, exe, out / "scenes" / "grid_4x4x4.oss", {"grid", "--nx", "4", "--ny", "4", "--nz", "4"},
                          {"--hierarchy", "off"});
    const OssFile file = OssFile::open(scene.string());
    const fs::path cam = out / "scenes" / ("walk" + std::to_string(o.frames) + ".cam");
    runner.run("path", {exe, "path", "walk", scene.string(), "--frames", std::to_string(o.frames), "-o", cam.string()});

    LinkPlayer player{o, runner, exe, mpirun, out, scene, cam};
    std::vector<LinkRun> runs;
    for (int ranks : o.layouts) {
        runs.push_back(player.play(ranks, 0, 0, false));
        const LinkRun base = runs.back();
        for (double mbps : o.mbps)
            for (double latency : o.latencies_ms) runs.push_back(player.play(ranks, latency, mbps, false));
        if (o.saturate_fps > 0 && base.busiest_rank_bytes > 0)
            runs.push_back(player.play(ranks, 0, base.busiest_rank_bytes * 8.0 * o.saturate_fps / 1e6, true));
    }
    writeLinksTables(o, runs, out, scene, file);
    plotLinks(o, runner, out);
    std::printf("%s\n", (out / "links.md").c_str());
    return 0;
}

}  // namespace occ::bench
