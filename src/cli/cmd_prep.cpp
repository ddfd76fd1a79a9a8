// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "cli/model_cache.h"
#include "cli/progress.h"
#include "import/import.h"
#include "prep/prepare.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>

namespace occ::cli {

void prepareModel(const std::string& input, const std::string& output, const ImportOptions& import,
                  const PrepOptions& prep, ReadMode stream) {
    const auto start = std::chrono::steady_clock::now();
    std::unique_ptr<SceneSource> source;
    ReadProgress reading;
    {
        ProgressBar bar("prep: reading", "MB", "B", [&reading] {
            return ProgressBar::Sample{double(reading.done) / 1e6, double(reading.total) / 1e6, double(reading.done)};
        });
        source = openSceneSource(input, import, stream, &reading);
    }
    const double read_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    PrepProgress progress;
    PrepSummary s;
    {
        ProgressBar bar("prep", "meshes", "tri", [&progress] {
            return ProgressBar::Sample{double(progress.meshes_done), double(progress.meshes_total),
                                       double(progress.triangles_done)};
        });
        s = prepareToFile(*source, output, prep, &progress);
    }
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const unsigned threads = prep.threads ? prep.threads : std::max(1u, std::thread::hardware_concurrency());
    // What import skipped, in info's words (points, lines, degenerate_faces), when it skipped any.
    std::string skipped;
    const auto add = [&](uint64_t n, const char* what) {
        if (n) skipped += (skipped.empty() ? "; skipped at import: " : ", ") + std::to_string(n) + " " + what;
    };
    add(s.skipped.points, "points");
    add(s.skipped.lines, "lines");
    add(s.skipped.degenerate, "degenerate faces");
    std::fprintf(stderr,
                 "prep: %s -> %s: %llu objects, %llu progressive meshes (%llu triangles, %llu with instances; "
                 "%llu repeated-corner triangles dropped%s), |COS| = %llu at CT %.2f, %.2f s on %u threads "
                 "(%.2f M unique triangles/s; %s, %.2f s to open), %llu bytes\n",
                 input.c_str(), output.c_str(), (unsigned long long)s.objects, (unsigned long long)s.meshes,
                 (unsigned long long)s.unique_triangles, (unsigned long long)s.instanced_triangles,
                 (unsigned long long)s.dropped_triangles, skipped.c_str(), (unsigned long long)s.cos,
                 double(prep.ct), seconds, threads, s.unique_triangles / seconds / 1e6, source->how(), read_seconds,
                 (unsigned long long)std::filesystem::file_size(output));
}

namespace {

struct PrepCommandOptions {
    std::string input, output;
    PrepOptions prep;
    std::string collapser = "fast";
    std::string stream = "auto";
    ImportOptions import;
};

int runPrep(PrepCommandOptions o) {
    if (std::filesystem::path(o.output).extension() != ".oss")
        throw UsageError("-o " + o.output + ": the output must be a .oss file");
    const std::filesystem::path dir = std::filesystem::path(o.output).parent_path();
    std::error_code ec;
    if (!dir.empty() && !std::filesystem::is_directory(dir, ec))
        throw UsageError("-o " + o.output + ": folder " + dir.string() + " does not exist");
    if (o.prep.threads > 1024) throw UsageError("--threads " + std::to_string(o.prep.threads) + " is not a sensible thread count");
    o.prep.collapser = o.collapser == "openmesh" ? Collapser::OpenMesh : Collapser::Fast;

    prepareModel(o.input, o.output, o.import, o.prep,
                 o.stream == "always" ? ReadMode::Stream : o.stream == "never" ? ReadMode::Whole : ReadMode::Auto);
    return 0;
}

int runVerify(const std::string& path) {
    const auto start = std::chrono::steady_clock::now();
    const OssFile file = OssFile::open(path);
    file.verifyLodPrefix();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::printf("ok: %s: %u objects, %u meshes, %llu vertices, %llu triangles; header, sections, checksums, "
                "indices and LOD prefixes verified in %.2f s\n",
                path.c_str(), file.objectCount(), file.meshCount(), (unsigned long long)file.vertexCount(),
                (unsigned long long)file.triangleCount(), seconds);
    return 0;
}

}  // namespace

Command addPrepCommand(CLI::App& app) {
    auto o = std::make_shared<PrepCommandOptions>();
    CLI::App* sub = app.add_subcommand(
        "prep", "Preprocess a model into a .oss scene: per mesh a progressive mesh (quadric half-edge\n"
                "collapses, Peng & Cao 2012 arrays), per object AABB, OOBB and compactness (Peng 2014),\n"
                "and the candidate occluder set. Uses all cores; instanced meshes are processed once.");
    sub->add_option("input", o->input, "model file (glTF, GLB, OBJ, PLY, OFF, STL)")->required();
    sub->add_option("-o,--out", o->output, "output .oss file")->required();
    sub->add_option("--scene", o->import.scene, "glTF: the scene to prepare (default: the file's default scene)");
    sub->add_option("--ct", o->prep.ct, "compactness threshold CT for candidate occluders, in [0, 1]")
        ->capture_default_str();
    sub->add_option("--threads", o->prep.threads, "worker threads (0 = all cores)")->capture_default_str();
    sub->add_option("--stream", o->stream,
                    "glTF: read meshes one at a time from the file instead of importing it whole: auto (files\n"
                    "over 256 MiB), always, never. Meshopt, Draco, sparse or instanced files import whole.")
        ->check(CLI::IsMember({"auto", "always", "never"}))
        ->capture_default_str();
    sub->add_option("--collapser", o->collapser, "fast (ours) or openmesh (reference Decimater)")
        ->check(CLI::IsMember({"fast", "openmesh"}))
        ->capture_default_str();
    return {sub, [o] { return runPrep(*o); }};
}

Command addVerifyCommand(CLI::App& app) {
    auto path = std::make_shared<std::string>();
    CLI::App* sub = app.add_subcommand(
        "verify", "Check a .oss file completely: header, section table, checksums, every index, and the\n"
                  "LOD prefix property of every progressive mesh. Exit 0 if sound, 2 with the first defect.");
    sub->add_option("file", *path, ".oss file")->required();
    return {sub, [path] { return runVerify(*path); }};
}

}  // namespace occ::cli
