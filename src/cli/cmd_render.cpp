// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "kernel_memory.h"
#include "pipeline/pipeline.h"
#include "scene/errors.h"
#include "view/camera_path.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>

namespace occ::cli {

namespace {

struct RenderOptions {
    std::string scene, path, stats, size = "512x512", mode = "oc+lod", stream = "sc";
    bool no_display = false;
    PipelineOptions pipeline;
};


int runRender(RenderOptions o) {
    parseViewportSize("--size", o.size, o.pipeline.width, o.pipeline.height);
    o.pipeline.mode = parseCullMode(o.mode);
    o.pipeline.stream = parseStreamMode(o.stream);
    if (!o.no_display)
        throw UsageError("render: drawing needs the display (a later issue); run with --no-display for now");
    if (o.path.empty()) throw UsageError("render: --path P.cam is required with --no-display");

    const OssFile file = OssFile::open(o.scene);
    const std::vector<CameraPose> cameras = readCameraPath(o.path);
    Pipeline pipeline(file, o.pipeline);

    std::ofstream csv;
    std::string tmp;
    // The stats file appears whole or not at all: a failed run removes its partial temporary.
    struct RemoveOnFailure {
        std::string* path;
        ~RemoveOnFailure() {
            if (!path->empty()) std::remove(path->c_str());
        }
    } cleanup{&tmp};
    if (!o.stats.empty()) {
        tmp = o.stats + ".tmp";
        csv.open(tmp, std::ios::trunc);
        if (!csv) throw InputError(o.stats, "cannot write the stats file");
        csv << frameStatsHeader() << '\n';
    }
    double total_ms = 0, visible = 0, in_frustum = 0, occluded = 0, streamed = 0, active = 0;
    for (size_t f = 0; f < cameras.size(); ++f) {
        const FrameStats s = pipeline.runFrame(cameras[f], f);
        if (csv.is_open()) csv << frameStatsRow(s) << '\n';
        total_ms += s.ms_total;
        visible += double(s.objects_visible);
        in_frustum += double(s.objects_in_frustum);
        occluded += double(s.objects_occluded);
        streamed += double(s.streamed_triangles);
        active += double(s.active_triangles);
    }
    if (csv.is_open()) {
        csv.close();
        if (!csv) throw InputError(o.stats, "write failed");
        std::filesystem::rename(tmp, o.stats);
        tmp.clear();
    }
    const double frames = double(cameras.size());
    std::printf("render: %s, %zu frames at %ux%u, mode %s, stream %s, backend %s: mean %.2f ms/frame (%.1f fps); "
                "%.1f of %u objects in the frustum, %.1f%% of those occluded, %.1f visible; "
                "%.0f active triangles, %.4f%% of them streamed per frame\n",
                o.scene.c_str(), cameras.size(), o.pipeline.width, o.pipeline.height, o.mode.c_str(),
                o.stream.c_str(), k::kernelBackend(), total_ms / frames, 1000.0 * frames / total_ms,
                in_frustum / frames, file.objectCount(), in_frustum > 0 ? 100.0 * occluded / in_frustum : 0.0,
                visible / frames, active / frames, active > 0 ? 100.0 * streamed / active : 0.0);
    return 0;
}

}  // namespace

void parseViewportSize(const std::string& option, const std::string& text, uint32_t& width, uint32_t& height) {
    unsigned long a = 0, b = 0;
    char x = 0, extra = 0;
    if (std::sscanf(text.c_str(), "%lu%c%lu%c", &a, &x, &b, &extra) != 3 || x != 'x' || a == 0 || b == 0 ||
        a > 16384 || b > 16384)
        throw UsageError(option + " " + text + ": expected WxH with 1 <= W, H <= 16384, e.g. 512x512");
    width = uint32_t(a);
    height = uint32_t(b);
}

Command addRenderCommand(CLI::App& app) {
    auto o = std::make_shared<RenderOptions>();
    CLI::App* sub = app.add_subcommand(
        "render", "Run a camera path through the frame pipeline: frustum culling, active occluders (Eq. 3),\n"
                  "HZM occlusion culling, LOD selection under a vertex budget (Eq. 1), streaming and\n"
                  "triangle reformation. Writes one CSV row per frame with --stats.");
    sub->add_option("scene", o->scene, "preprocessed scene (.oss)")->required();
    sub->add_option("--path", o->path, "camera path file (see `occswitch path`)");
    sub->add_flag("--no-display", o->no_display, "run every stage except drawing");
    sub->add_option("--stats", o->stats, "write per-frame statistics to this CSV file");
    sub->add_option("--size", o->size, "viewport and occlusion buffer size WxH")->capture_default_str();
    sub->add_option("--mode", o->mode, "full (no LOD, no occlusion), lod ([PC12]) or oc+lod")->capture_default_str();
    sub->add_option("--stream", o->stream, "sc (coherent), snc (no coherence) or ns (object by object)")
        ->capture_default_str();
    sub->add_option("--aos", o->pipeline.aos, "active occluders per frame (top-K of Eq. 3)")->capture_default_str();
    sub->add_option("--pvs-occluders", o->pipeline.pvs_occluder_triangles,
                    "also raster last frame's largest visible objects up to this many triangles (0 = off)")
        ->capture_default_str();
    sub->add_option("--budget", o->pipeline.budget, "vertex budget N per frame (0 = 10% of the scene's vertices)")
        ->capture_default_str();
    sub->add_option("--pet", o->pipeline.pet, "pixel error threshold: smaller objects are not drawn")
        ->capture_default_str();
    sub->add_option("--alpha", o->pipeline.alpha, "exponent of the LOD metric (Eq. 1)")->capture_default_str();
    return {sub, [o] { return runRender(*o); }};
}

}  // namespace occ::cli
