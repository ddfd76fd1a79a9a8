// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "cli/model_cache.h"
#include "util/progress.h"
#include "import/import.h"
#include "prep/hierarchy.h"
#include "prep/prepare.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <chrono>
#include <filesystem>
#include <iostream>
#include <thread>

#include <unistd.h>

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
    // With a hierarchy the flat scene goes to a temporary beside the output first: its HLODs are
    // built from the mapped file, then both go to the output.
    const std::string flat = prep.hierarchy ? output + ".flat." + std::to_string(::getpid()) + ".tmp" : output;
    struct RemoveFlat {
        std::string path;
        ~RemoveFlat() {
            std::error_code ec;
            if (!path.empty()) std::filesystem::remove(path, ec);
        }
    } remove_flat{prep.hierarchy ? flat : std::string()};
    {
        ProgressBar bar("prep", "meshes", "tri", [&progress] {
            return ProgressBar::Sample{double(progress.meshes_done), double(progress.meshes_total),
                                       double(progress.triangles_done)};
        });
        s = prepareToFile(*source, flat, prep, &progress, !prep.hierarchy);
    }
    const double flat_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    std::string hierarchy = "; no hierarchy";
    if (prep.hierarchy) {
        const uint64_t flat_bytes = std::filesystem::file_size(flat);
        HlodProgress built;
        HlodOptions hlod;
        hlod.node_triangles = prep.node_triangles;
        hlod.reduction = prep.hlod_reduction;
        hlod.cluster = prep.hlod_cluster;
        hlod.place = prep.hlod_place;
        hlod.place_edges = prep.hlod_place_edges;
        hlod.colour_borders = prep.hlod_colour_borders;
        hlod.fine_input = prep.hlod_fine_input;
        hlod.normals = prep.hlod_normals;
        hlod.share_repeats = prep.hlod_share;
        hlod.threads = prep.threads;
        ObjectHierarchy h;
        OssFile::HlodCounts hlods;
        {
            ProgressBar bar("prep: HLODs", "nodes", "nodes", [&built] {
                return ProgressBar::Sample{double(built.done), double(built.total), double(built.done)};
            });
            h = writeWithHierarchy(OssFile::open(flat, OssFile::Pages::Release), output, prep.fanout, hlod, &built, &hlods);
        }
        const uint64_t sharing = hlods.inner - hlods.meshes;  // repeated subtrees drawing another's HLOD
        const uint64_t hlod_triangles = hlods.triangles;
        const double hlod_seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() - flat_seconds;
        char b[256];
        std::snprintf(b, sizeof b,
                      "; hierarchy: %zu nodes in %u levels (fanout %u), %llu inner (%llu sharing a repeated subtree's "
                      "HLOD) with %llu HLOD triangles, %.2f s, +%llu bytes",
                      h.nodes.size(), h.levels, prep.fanout, (unsigned long long)built.total,
                      (unsigned long long)sharing, (unsigned long long)hlod_triangles, hlod_seconds,
                      (unsigned long long)(std::filesystem::file_size(output) - flat_bytes));
        hierarchy = b;
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
    add(s.skipped.unknown_materials, "unknown materials (drawn grey)");
    std::fprintf(stderr,
                 "prep: %s -> %s: %llu objects, %llu progressive meshes (%llu triangles, %llu with instances; "
                 "%llu repeated-corner triangles dropped%s), |COS| = %llu at CT %.2f, %.2f s on %u threads "
                 "(%.2f M unique triangles/s; %s, %.2f s to open), %llu bytes%s\n",
                 input.c_str(), output.c_str(), (unsigned long long)s.objects, (unsigned long long)s.meshes,
                 (unsigned long long)s.unique_triangles, (unsigned long long)s.instanced_triangles,
                 (unsigned long long)s.dropped_triangles, skipped.c_str(), (unsigned long long)s.cos,
                 double(prep.ct), seconds, threads, s.unique_triangles / flat_seconds / 1e6, source->how(), read_seconds,
                 (unsigned long long)std::filesystem::file_size(output), hierarchy.c_str());
}

namespace {

struct PrepCommandOptions {
    std::string input, output;
    PrepOptions prep;
    std::string collapser = "fast";
    std::string stream = "auto";
    std::string hierarchy = "on";
    std::string hlod_cluster = "on";
    std::string hlod_share = "on";
    std::string hlod_place = "clusters";
    std::string hlod_colour_borders = "on";
    std::string hlod_input = "fine";
    std::string hlod_normals = "on";
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
    o.prep.hierarchy = o.hierarchy == "on";
    o.prep.hlod_cluster = o.hlod_cluster == "on";
    o.prep.hlod_share = o.hlod_share == "on";
    o.prep.hlod_place = o.hlod_place != "off";
    o.prep.hlod_place_edges = o.hlod_place == "all";
    o.prep.hlod_colour_borders = o.hlod_colour_borders == "on";
    o.prep.hlod_fine_input = o.hlod_input == "fine";
    o.prep.hlod_normals = o.hlod_normals == "on";
    if (o.prep.fanout < 2 || o.prep.fanout > 64)
        throw UsageError("--fanout " + std::to_string(o.prep.fanout) + ": must be in [2, 64]");
    if (o.prep.node_triangles < 16)
        throw UsageError("--node-triangles " + std::to_string(o.prep.node_triangles) + ": must be at least 16");

    prepareModel(o.input, o.output, o.import, o.prep,
                 o.stream == "always" ? ReadMode::Stream : o.stream == "never" ? ReadMode::Whole : ReadMode::Auto);
    return 0;
}

int runVerify(const std::string& path) {
    const auto start = std::chrono::steady_clock::now();
    const OssFile file = OssFile::open(path, OssFile::Pages::Release);
    file.verifyLodPrefix();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    const std::string nodes = file.nodeCount() ? ", " + std::to_string(file.nodeCount()) + " hierarchy nodes" : ", no hierarchy";
    std::printf("ok: %s: %u objects, %u meshes, %llu vertices, %llu triangles%s; header, sections, checksums, "
                "indices, the hierarchy and LOD prefixes verified in %.2f s\n",
                path.c_str(), file.objectCount(), file.meshCount(), (unsigned long long)file.vertexCount(),
                (unsigned long long)file.triangleCount(), nodes.c_str(), seconds);
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
    sub->add_option("--hierarchy", o->hierarchy,
                    "on: also a spatial hierarchy over the objects and, per inner node, an HLOD (the merged\n"
                    "subtree simplified into a progressive mesh of its own); off: the flat scene only")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub->add_option("--fanout", o->prep.fanout, "hierarchy: children per node at most, in [2, 64]")->capture_default_str();
    sub->add_option("--hlod-reduction", o->prep.hlod_reduction,
                    "hierarchy: a child gives its parent's HLOD at most 1/N of its subtree's triangles, so an HLOD\n"
                    "is at finest 1/N of what it stands for (lower: finer HLODs that can stand in nearer the eye,\n"
                    "more triangles stored: all HLODs about 1/(N-1) of the scene)")
        ->check(CLI::Range(2u, 64u))
        ->capture_default_str();
    sub->add_option("--node-triangles", o->prep.node_triangles,
                    "hierarchy: about how many triangles an HLOD starts from, halved (its merged input is\n"
                    "twice this; the progressive mesh then reaches every size below)")
        ->capture_default_str();
    sub->add_option("--hlod-cluster", o->hlod_cluster,
                    "hierarchy: on: an HLOD's edge collapses go on as vertex clustering (a grid whose cell\n"
                    "doubles), so small objects vanish and neighbours join; off: edge collapses only, which\n"
                    "keep every object's floor")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub->add_option("--hlod-place", o->hlod_place,
                    "hierarchy: clusters: a cluster's vertices move onto a new vertex where the squared distances\n"
                    "to the planes they stand for are least (Lindstrom 2000), so flat parts stay flat; all: the\n"
                    "edge collapses before clustering place their vertices so too (Garland & Heckbert); off: onto\n"
                    "the member nearest the cluster's centre")
        ->check(CLI::IsMember({"clusters", "all", "off"}))
        ->capture_default_str();
    sub->add_option("--hlod-colour-borders", o->hlod_colour_borders,
                    "hierarchy: on: clustering never joins vertices of different colours (a cell keeps one\n"
                    "cluster per colour); off: a cluster mixes its members' colours")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub->add_option("--hlod-normals", o->hlod_normals,
                    "hierarchy: on: each HLOD vertex carries the normal of the full detail it stands for, and\n"
                    "the display lights it by that; off: HLODs are lit by their faces' normals")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub->add_option("--hlod-input", o->hlod_input,
                    "hierarchy: fine: an HLOD is simplified from its children's levels up to their share of\n"
                    "--node-triangles (objects at full detail where they fit) and keeps its levels up to\n"
                    "1/--hlod-reduction of what it stands for; reduced: from children's levels already at\n"
                    "1/--hlod-reduction (faster prep; a box there is a tetrahedron, and every HLOD above shows it)")
        ->check(CLI::IsMember({"fine", "reduced"}))
        ->capture_default_str();
    sub->add_option("--hlod-share", o->hlod_share,
                    "hierarchy: on: a subtree that repeats an earlier one (the same meshes under the same\n"
                    "relative transforms, moved rigidly: a tiled or instanced assembly) shares its HLOD, placed\n"
                    "by the motion, instead of getting one of its own; off: one HLOD per inner node")
        ->check(CLI::IsMember({"on", "off"}))
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
