// SPDX-License-Identifier: MIT
// `occswitch bench ...`: the subcommands and their options; the benchmarks themselves are in
// src/bench/.
#include "cli/commands.h"
#include "bench/bench_all.h"
#include "bench/bench_massive.h"
#include "bench/bench_pipeline.h"
#include "bench/bench_prep.h"
#include "bench/bench_ranks.h"
#include "scene/errors.h"

#include <memory>
#include <string>

namespace occ::cli {

using namespace bench;

Command addBenchCommand(CLI::App& app) {
    CLI::App* bench = app.add_subcommand("bench", "Run the experiments of the papers and print their numbers\n"
                                                  "(tables on stdout, CSV and Markdown with --out).");
    bench->require_subcommand(1);
    auto o = std::make_shared<BenchPrepOptions>();
    CLI::App* prep = bench->add_subcommand(
        "prep", "Preprocessing: triangles/s of prepareScene (fast collapser, all threads and one; the OpenMesh\n"
                "reference on one), of meshopt_simplify at 50, 10 and 1 % of each mesh's triangles, and the\n"
                "sampled Hausdorff error of both at those targets, on the same unique meshes.");
    prep->add_option("input", o->input, "model file (glTF, GLB, OBJ, PLY, OFF, STL)")->capture_default_str();
    prep->add_option("--out", o->out, "folder for prep_bench.csv and prep_summary.md (created if missing)");
    prep->add_option("--threads", o->threads, "worker threads for the all-threads run and the error (0 = all cores)")
        ->capture_default_str();
    prep->add_option("--repeat", o->repeat,
                     "timed runs of each measurement, at least (short ones repeat for 2 s); the fastest counts")
        ->check(CLI::Range(1u, 100u))
        ->capture_default_str();
    prep->add_option("--samples", o->samples, "area samples per surface for the error, at most")->capture_default_str();
    prep->add_option("--samples-per-triangle", o->samples_per_triangle,
                     "area samples per full-detail triangle, for small meshes")
        ->check(CLI::Range(1u, 100000u))
        ->capture_default_str();
    prep->add_option("--openmesh-seconds", o->openmesh_seconds,
                     "time budget of the OpenMesh reference (meshes in a fixed random order until spent)")
        ->capture_default_str();
    prep->add_flag("--meshopt-lock-border", o->meshopt_lock_border,
                   "pass meshopt_SimplifyLockBorder, so meshopt keeps border vertices (as ours did before they could collapse)");

    auto po = std::make_shared<PipelineBenchOptions>();
    auto size = std::make_shared<std::string>("512x512");
    CLI::App* pipeline = bench->add_subcommand(
        "pipeline", "Frame pipeline: per streaming mode (SC, SnC, NS) bytes streamed per frame and the time of\n"
                    "each step; reform throughput against a plain memcpy; culled share with and without\n"
                    "occlusion culling (Peng & Cao 2012 Table 1, Peng & Cao 2013).");
    pipeline->add_option("scene", po->scene, "preprocessed scene (.oss)")->required();
    pipeline->add_option("path", po->path, "camera path (.cam)")->required();
    pipeline->add_option("--out", po->out_dir, "folder for pipeline_bench.csv (created if missing)");
    pipeline->add_option("--size", *size, "viewport WxH")->capture_default_str();
    auto pvs = std::make_shared<std::string>("auto");
    pipeline->add_option("--pvs-occluders", *pvs,
                         "also raster last frame's largest visible objects up to this many triangles (0 = off;\n"
                         "auto = a quarter of the vertex budget N, at least 30000)")
        ->capture_default_str();

    auto ao = std::make_shared<BenchAllOptions>();
    ao->model = kDefaultModel;
    CLI::App* all = bench->add_subcommand(
        "all", "Every experiment in one run: prepares the scenes (engine grid, plant) unless the scenes folder\n"
               "has them, then frame time per stage (Peng 2014 Table 3), culling accuracy against exact culling\n"
               "(Table 4), SC/SnC/NS streaming (Peng & Cao 2012 Table 1), visible-set bytes with and without\n"
               "deltas (Govindaraju et al. 2003 Figure 3), latency and waiting on 1, 2 and 3 ranks, fps over\n"
               "the walk (Peng 2014 Figure 6) and scaling from 10^5 triangles up. Writes CSVs, summary.md and\n"
               "gnuplot PNGs into --out. Sizes: tiny (seconds, for tests), small (about 10 minutes: 7 M-triangle\n"
               "grid, 5 000-object plant, scaling up to 1.1x10^8 triangles), full (longer than small: 110 M-triangle\n"
               "grid, 20 000-object plant; docs/results.md).");
    all->add_option("--out", ao->out, "results folder (created if missing)")->required();
    all->add_option("--size", ao->size, "tiny, small or full")
        ->check(CLI::IsMember({"tiny", "small", "full"}))
        ->capture_default_str();
    all->add_option("--scenes", ao->scenes, "folder of prepared scenes, reused by later runs (default: OUT/scenes)");
    all->add_option("--model", ao->model, "the model the engine grids tile")->capture_default_str();
    all->add_flag("--no-mpi", ao->no_mpi, "measure the layouts on 1 rank only, without mpirun");
    all->add_option("--only", ao->only,
                    "run only these experiments, by the numbers of the progress lines and the summary's\n"
                    "sections (e.g. 5,8; 1 and 6 come from the same runs, as do 4 and 5); the others'\n"
                    "sections say they were not run")
        ->delimiter(',')
        ->check(CLI::Range(1, 9));
    auto mo = std::make_shared<BenchMassiveOptions>();
    CLI::App* massive = bench->add_subcommand(
        "massive", "A scene of the papers' Boeing class: a plant of --objects objects (10^6 = 193 M triangles)\n"
                   "generated and preprocessed once (both stream; time and peak memory kept beside the files),\n"
                   "then a walk and an orbit (oc+lod) without drawing, the walk with lod alone, a prefix of it\n"
                   "against the exact visible set, and the walk drawn (OpenGL) with oc+lod and with lod. Writes\n"
                   "massive.md and massive.csv into --out: frame time median, p99 and max, the first frames,\n"
                   "streamed share, PVS churn against exact churn, occluder triangles, raster ms, occlusion ms and\n"
                   "the raster's occluder triangles/s per core, false culls, peak memory of gen, prep and render.\n"
                   "With a hierarchy in the scene (prep's default) also the walk and the orbit with it, the\n"
                   "orbit's prefix against the full-detail picture flat and with it, a small plant's walk\n"
                   "and orbit with it (growth), and the engine grid prepared without and with it; when it makes\n"
                   "the plant, it also times prep with --hierarchy off (the flat file is not kept). With a\n"
                   "hierarchy and --reference-frames, the picture stage (issue 49): the walk's and the orbit's\n"
                   "prefixes of the plant, of a --picture-objects plant and of the KIT village (assimp-testmodels'\n"
                   "KIT house exported by assimp, then gen grid 10x1x10; skipped, with the reason, without them),\n"
                   "each in --colours model and uniform, drawn flat and with the hierarchy against full detail:\n"
                   "pooled PSNR, perceptibly changed share, SSIM, the bound's share beyond tau and the targets'\n"
                   "verdicts, in massive.md's section \"Pictures against full detail\" and in pictures.csv.\n"
                   "On 2 cores: about 10 minutes to make the 10^6-object scene (4 more for the flat prep), then\n"
                   "about 12 minutes of runs,\n"
                   "and with a hierarchy about 40 more, mostly the two reference runs, which draw the full-detail\n"
                   "plant every frame (docs/results.md); the picture stage adds 22 such runs, 6 of them on the\n"
                   "plant itself (2 orbits), the rest on scenes a tenth of its size or less.");
    massive->add_option("--out", mo->out, "results folder (created if missing)")->required();
    massive->add_option("--scenes", mo->scenes, "where the plant is made once and reused (default: OUT/scenes)");
    massive->add_option("--objects", mo->objects, "objects of the plant")->check(CLI::Range(1000u, 10000000u))->capture_default_str();
    massive->add_option("--frames", mo->frames, "cameras of the walk and of the orbit")->check(CLI::Range(12u, 100000u))->capture_default_str();
    massive->add_option("--exact-frames", mo->exact_frames, "frames of the walk's prefix run against the exact visible set")
        ->capture_default_str();
    massive->add_option("--reference-frames", mo->reference_frames,
                        "with a hierarchy: frames of the orbit's prefix drawn against the full-detail picture, flat "
                        "and with the hierarchy (PSNR), and of each path of the picture stage (0: neither)")
        ->capture_default_str();
    massive->add_option("--picture-objects", mo->picture_objects,
                        "with a hierarchy and reference frames: a plant of this many objects in the picture stage "
                        "(0, or not below --objects: none)")
        ->check(CLI::Range(0u, 10000000u))
        ->capture_default_str();
    auto village = std::make_shared<std::string>("on");
    massive->add_option("--village", *village,
                        "with a hierarchy and reference frames: the KIT village in the picture stage (on needs "
                        "`assimp`, Debian's assimp-utils, and assimp-testmodels' IFC; skipped, with the reason, "
                        "without them)")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    massive->add_option("--growth-objects", mo->growth_objects,
                        "with a hierarchy: a plant of this many objects also walked and orbited with it, for the "
                        "growth of the frame with the scene (none when not below --objects)")
        ->check(CLI::Range(100u, 10000000u))
        ->capture_default_str();
    massive->add_option("--grid", mo->grid,
                        "with a hierarchy: the engine tiled N x N x N times (gen grid) prepared without and with it, "
                        "for the time and size of HLODs shared among repeated subtrees (0: none)")
        ->check(CLI::Range(0u, 40u))
        ->capture_default_str();
    massive->add_option("--budget", mo->budget, "the renders' vertex budget, as render --budget takes it")
        ->capture_default_str();
    massive->add_option("--run-timeout", mo->run_timeout_s, "seconds after which a run is stopped and reported")
        ->capture_default_str();
    auto ro = std::make_shared<BenchRanksOptions>();
    CLI::App* ranks = bench->add_subcommand(
        "ranks", "The same walk rendered headless by every layout of --ranks through mpirun on this machine (1\n"
                 "rank, 2, the 3-rank switch, 2 + P sort-last display ranks): bytes per frame by message kind,\n"
                 "composite bytes and ms, latency in frames and ms, busy and wait time per rank, and whether\n"
                 "every layout culled the same visible sets and drew the same pictures as the first; then the\n"
                 "cluster model of docs/scaling.md fed with the stage costs measured. Writes ranks.md,\n"
                 "ranks.csv, ranks_per_rank.csv and model.csv into --out; exit 1 if a layout culled differently.");
    ranks->add_option("--out", ro->out, "results folder (created if missing)")->required();
    ranks->add_option("--ranks", ro->ranks, "the layouts, as rank counts")->delimiter(',')->capture_default_str();
    ranks->add_option("--objects", ro->objects, "objects of the plant made when --scene is not given")
        ->check(CLI::Range(10u, 10000000u))->capture_default_str();
    ranks->add_option("--scene", ro->scene, "an existing .oss scene instead of the plant");
    ranks->add_option("--frames", ro->frames, "cameras of the walk")->check(CLI::Range(3u, 100000u))->capture_default_str();
    ranks->add_option("--size", ro->size, "render --size WxH")->capture_default_str();
    ranks->add_option("--sort-last-cells", ro->sort_last_cells, "render --sort-last-cells")
        ->check(CLI::Range(1, 1024))->capture_default_str();
    ranks->add_option("--link-gbps", ro->link_gbps, "link speeds the model predicts for")->delimiter(',')
        ->capture_default_str();
    ranks->add_option("--run-timeout", ro->run_timeout_s, "seconds after which a run is stopped and reported")
        ->capture_default_str();
    auto lo = std::make_shared<BenchLinksOptions>();
    CLI::App* links = bench->add_subcommand(
        "links", "Latency and bandwidth experiments: the walk with paced cameras (--pace recorded) through the\n"
                 "3-rank switch and 2 + P, without emulation and over every emulated link of --latencies x\n"
                 "--mbps (render --link): fps shown, camera-to-display latency, poses skipped, bytes per frame\n"
                 "by kind against SWITCH's bandwidth formula, the fps each link can carry, rank waits; one run\n"
                 "on a link just narrow enough for --saturate-fps. Writes links.md, links.csv and\n"
                 "plots/links.png into --out. Default scene: the 4x4x4 engine grid (made once in OUT/scenes).");
    links->add_option("--out", lo->out, "results folder (created if missing)")->required();
    links->add_option("--scene", lo->scene, "an existing .oss scene instead of the 4x4x4 engine grid");
    links->add_option("--layouts", lo->layouts, "rank counts: 3 (the switch), 2 + P")->delimiter(',')->capture_default_str();
    links->add_option("--latencies", lo->latencies_ms, "link latencies, ms")->delimiter(',')->capture_default_str();
    links->add_option("--mbps", lo->mbps, "link bandwidths, Mb/s")->delimiter(',')->capture_default_str();
    links->add_option("--frames", lo->frames, "cameras of the walk")->check(CLI::Range(10u, 100000u))->capture_default_str();
    links->add_option("--path-fps", lo->path_fps, "cameras per second the path is played at")->capture_default_str();
    links->add_option("--saturate-fps", lo->saturate_fps, "the narrow link's target fps (0: no such run)")
        ->capture_default_str();
    links->add_option("--size", lo->size, "render --size WxH")->capture_default_str();
    links->add_option("--run-timeout", lo->run_timeout_s, "seconds after which a run is stopped and reported")
        ->capture_default_str();
    return {bench, [o, prep, po, size, pvs, ao, all, mo, massive, village, ro, ranks, lo, links] {
                if (links->parsed()) return runBenchLinks(*lo);
                if (ranks->parsed()) return runBenchRanks(*ro);
                if (prep->parsed()) return runBenchPrep(*o);
                if (all->parsed()) return runBenchAll(*ao);
                if (massive->parsed()) {
                    mo->village = *village == "on";
                    return runBenchMassive(*mo);
                }
                parseViewportSize("--size", *size, po->width, po->height);
                po->pvs_occluder_triangles = parseOccluderTriangles(*pvs);
                return runPipelineBench(*po);
            }};
}

}  // namespace occ::cli
