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
                  const PrepOptions& prep) {
    const auto start = std::chrono::steady_clock::now();
    const Scene scene = importModel(input, import);
    PrepProgress progress;
    PreparedScene prepared;
    {
        ProgressBar bar("prep", "meshes", "tri", [&progress] {
            return ProgressBar::Sample{double(progress.meshes_done), double(progress.meshes_total),
                                       double(progress.triangles_done)};
        });
        prepared = prepareScene(scene, prep, &progress);
    }
    writeOss(output, prepared);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    uint64_t unique_triangles = 0, instanced_triangles = 0, dropped = 0;
    for (const ProgressiveMesh& m : prepared.meshes) unique_triangles += m.triangleCount(), dropped += m.dropped_triangles;
    for (const ObjectRecord& r : prepared.objects) instanced_triangles += prepared.meshes[r.mesh].triangleCount();
    const unsigned threads = prep.threads ? prep.threads : std::max(1u, std::thread::hardware_concurrency());
    // What import skipped, in info's words (points, lines, degenerate_faces), when it skipped any.
    std::string skipped;
    const auto add = [&](uint64_t n, const char* what) {
        if (n) skipped += (skipped.empty() ? "; skipped at import: " : ", ") + std::to_string(n) + " " + what;
    };
    add(scene.skipped.points, "points");
    add(scene.skipped.lines, "lines");
    add(scene.skipped.degenerate, "degenerate faces");
    std::fprintf(stderr,
                 "prep: %s -> %s: %zu objects, %zu progressive meshes (%llu triangles, %llu with instances; "
                 "%llu repeated-corner triangles dropped%s), |COS| = %zu at CT %.2f, %.2f s on %u threads "
                 "(%.2f M unique triangles/s), %llu bytes\n",
                 input.c_str(), output.c_str(), prepared.objects.size(), prepared.meshes.size(),
                 (unsigned long long)unique_triangles, (unsigned long long)instanced_triangles,
                 (unsigned long long)dropped, skipped.c_str(), prepared.cos.size(),
                 double(prepared.ct), seconds, threads, unique_triangles / seconds / 1e6,
                 (unsigned long long)std::filesystem::file_size(output));
}

namespace {

struct PrepCommandOptions {
    std::string input, output;
    PrepOptions prep;
    std::string collapser = "fast";
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

    prepareModel(o.input, o.output, o.import, o.prep);
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
