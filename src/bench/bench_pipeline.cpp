// SPDX-License-Identifier: MIT
#include "bench/bench_pipeline.h"

#include "device_memory.h"
#include "pipeline/pipeline.h"
#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "view/camera_path.h"

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <sstream>
#include <fstream>
#include <vector>

namespace occ::bench {

namespace {

struct RunSummary {
    std::string name;
    double frames = 0;
    double ms[size_t(Stage::Count)] = {};
    double ms_total = 0;
    double streamed_bytes = 0, streamed_triangles = 0, moved_bytes = 0;
    double bus_h2d_bytes = 0, bus_d2h_bytes = 0;
    double active_triangles = 0, resident_triangles = 0;
    double in_frustum = 0, occluded = 0, visible = 0;
    double reform_triangles = 0;  // triangles the reform kernel walked (resident ones)
};

RunSummary runPath(const OssFile& file, const std::vector<CameraPose>& cameras, PipelineOptions options,
                   const std::string& name) {
    Pipeline pipeline(file, options);
    RunSummary r;
    r.name = name;
    for (size_t f = 0; f < cameras.size(); ++f) {
        const FrameStats s = pipeline.runFrame(cameras[f], f);
        if (f == 0) continue;  // the first frame streams everything in every mode
        r.frames += 1;
        for (size_t i = 0; i < size_t(Stage::Count); ++i) r.ms[i] += s.ms[i];
        r.ms_total += s.ms_total;
        r.streamed_bytes += double(s.streamed_bytes);
        r.streamed_triangles += double(s.streamed_triangles);
        r.moved_bytes += double(s.moved_bytes);
        r.bus_h2d_bytes += double(s.bus_h2d_bytes);
        r.bus_d2h_bytes += double(s.bus_d2h_bytes);
        r.active_triangles += double(s.active_triangles);
        r.resident_triangles += double(s.resident_triangles);
        r.in_frustum += double(s.objects_in_frustum);
        r.occluded += double(s.objects_occluded);
        r.visible += double(s.objects_visible);
    }
    return r;
}

double mean(double sum, const RunSummary& r) { return r.frames > 0 ? sum / r.frames : 0.0; }

// Seconds for a plain single-threaded memcpy of `bytes`, best of a few tries.
double memcpySeconds(size_t bytes) {
    std::vector<char> src(bytes, 1), dst(bytes);
    double best = 1e30;
    for (int i = 0; i < 5; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        std::memcpy(dst.data(), src.data(), bytes);
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        best = std::min(best, s);
    }
    if (dst[bytes / 2] != 1) std::abort();  // keeps the copy from being optimised away
    return best;
}

}  // namespace

int runPipelineBench(const PipelineBenchOptions& o) {
    const OssFile file = OssFile::open(o.scene);
    const std::vector<CameraPose> cameras = readCameraPath(o.path);
    if (cameras.size() < 2) throw UsageError("bench pipeline: the path needs at least 2 cameras");

    PipelineOptions base;
    base.width = o.width;
    base.height = o.height;
    base.pvs_occluder_triangles = o.pvs_occluder_triangles;
    base.budget_share = 0.1;  // the papers' sizing, as every bench result in docs/ has it

    std::vector<RunSummary> runs;
    for (auto [mode, name] : {std::pair{StreamMode::Coherent, "sc"}, std::pair{StreamMode::NonCoherent, "snc"},
                              std::pair{StreamMode::None, "ns"}}) {
        std::fprintf(stderr, "bench pipeline: streaming %s over %zu frames ...\n", name, cameras.size());
        PipelineOptions options = base;
        options.stream = mode;
        runs.push_back(runPath(file, cameras, options, name));
    }
    std::fprintf(stderr, "bench pipeline: lod without occlusion culling ...\n");
    PipelineOptions lod = base;
    lod.mode = CullMode::Lod;
    const RunSummary no_occlusion = runPath(file, cameras, lod, "lod");
    const RunSummary& sc = runs[0];
    const RunSummary& snc = runs[1];

    // Reform throughput from the no-coherence run: it reforms the whole active set each frame.
    const double reform_seconds = snc.ms[size_t(Stage::Reform)] / 1000.0;
    const double reform_rate = reform_seconds > 0 ? snc.active_triangles / reform_seconds : 0.0;
    const size_t frame_bytes = size_t(std::max(1.0, mean(snc.active_triangles, snc))) * 3 * sizeof(uint32_t);
    const double memcpy_rate = double(frame_bytes / (3 * sizeof(uint32_t))) / memcpySeconds(frame_bytes);

    std::printf("# occswitch bench pipeline: %s, path %s (%zu frames, first excluded), %ux%u, backend %s\n",
                o.scene.c_str(), o.path.c_str(), cameras.size(), o.width, o.height, k::deviceBackend());
    std::printf("\n%-5s %14s %12s %12s %12s %12s %12s %10s %10s %10s %10s\n", "mode", "streamed B/f", "streamed t/f",
                "active t/f", "moved B/f", "bus h2d B/f", "bus d2h B/f", "ms_collect", "ms_defrag", "ms_reform",
                "ms_total");
    for (const RunSummary& r : runs)
        std::printf("%-5s %14.0f %12.1f %12.0f %12.0f %12.0f %12.0f %10.3f %10.3f %10.3f %10.3f\n", r.name.c_str(),
                    mean(r.streamed_bytes, r), mean(r.streamed_triangles, r), mean(r.active_triangles, r),
                    mean(r.moved_bytes, r), mean(r.bus_h2d_bytes, r), mean(r.bus_d2h_bytes, r),
                    mean(r.ms[size_t(Stage::StreamCollect)], r), mean(r.ms[size_t(Stage::Defragment)], r),
                    mean(r.ms[size_t(Stage::Reform)], r), mean(r.ms_total, r));
    // The paper's ideal bus carries the streamed geometry and nothing else.
    for (const RunSummary& r : runs)
        std::printf("bus %-3s %12.0f B/frame = streamed %12.0f + %9.0f other (%.1f B per visible object); ideal %.0f\n",
                    r.name.c_str(), mean(r.bus_h2d_bytes + r.bus_d2h_bytes, r), mean(r.streamed_bytes, r),
                    mean(r.bus_h2d_bytes + r.bus_d2h_bytes - r.streamed_bytes, r),
                    r.visible > 0 ? (r.bus_h2d_bytes + r.bus_d2h_bytes - r.streamed_bytes) / r.visible : 0.0,
                    mean(r.streamed_bytes, r));
    const double sc_share = snc.streamed_triangles > 0 ? 100.0 * sc.streamed_triangles / snc.streamed_triangles : 0.0;
    std::printf("\nSC streams %.3f %% of the triangles SnC streams per frame (target <= 0.1 %%, Peng & Cao 0.04 %%)\n",
                sc_share);
    std::printf("frame time SC %.3f ms, SnC %.3f ms, NS %.3f ms (target: SC lowest)\n", mean(sc.ms_total, sc),
                mean(snc.ms_total, snc), mean(runs[2].ms_total, runs[2]));
    std::printf("reform %.1f M triangles/s, plain memcpy of the same bytes %.1f M triangles/s: %.0f %% (target >= 50 %%)\n",
                reform_rate / 1e6, memcpy_rate / 1e6, memcpy_rate > 0 ? 100.0 * reform_rate / memcpy_rate : 0.0);
    const double objects = double(file.objectCount());
    std::printf("culled share of all objects: lod (frustum only) %.1f %%, oc+lod %.1f %%; occlusion culls %.1f %% of "
                "the frustum's objects\n",
                100.0 * (1.0 - mean(no_occlusion.visible, no_occlusion) / objects),
                100.0 * (1.0 - mean(sc.visible, sc) / objects),
                sc.in_frustum > 0 ? 100.0 * sc.occluded / sc.in_frustum : 0.0);

    if (!o.out_dir.empty()) {
        makeOutputFolder(o.out_dir);
        std::ostringstream csv;
        csv << "mode,frames,streamed_bytes_per_frame,streamed_triangles_per_frame,active_triangles_per_frame,"
               "resident_triangles_per_frame,moved_bytes_per_frame,visible_per_frame,occluded_per_frame,"
               "bus_h2d_bytes_per_frame,bus_d2h_bytes_per_frame";
        for (uint32_t s = 0; s < uint32_t(Stage::Count); ++s) csv << ",ms_" << stageName(Stage(s));
        csv << ",ms_total\n";
        std::vector<const RunSummary*> all;
        for (const RunSummary& r : runs) all.push_back(&r);
        all.push_back(&no_occlusion);
        for (const RunSummary* r : all) {
            csv << r->name << ',' << r->frames << ',' << mean(r->streamed_bytes, *r) << ','
                << mean(r->streamed_triangles, *r) << ',' << mean(r->active_triangles, *r) << ','
                << mean(r->resident_triangles, *r) << ',' << mean(r->moved_bytes, *r) << ','
                << mean(r->visible, *r) << ',' << mean(r->occluded, *r) << ',' << mean(r->bus_h2d_bytes, *r) << ','
                << mean(r->bus_d2h_bytes, *r);
            for (double ms : r->ms) csv << ',' << mean(ms, *r);
            csv << ',' << mean(r->ms_total, *r) << '\n';
        }
        writeFileAtomic((std::filesystem::path(o.out_dir) / "pipeline_bench.csv").string(), csv.str());
        std::fprintf(stderr, "bench pipeline: wrote %s\n",
                     (std::filesystem::path(o.out_dir) / "pipeline_bench.csv").string().c_str());
    }
    return 0;
}

}  // namespace occ::bench
