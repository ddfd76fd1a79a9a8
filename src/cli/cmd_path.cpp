// SPDX-License-Identifier: MIT
#include "cli/commands.h"
#include "cli/model_cache.h"

#include "scene/errors.h"
#include "scene/oss_file.h"
#include "view/camera_path.h"

#include <cstdio>
#include <filesystem>
#include <memory>

namespace occ::cli {

namespace {

struct PathOptions {
    std::string scene, output;
    int64_t frames = 300;  // signed, so that "--frames -1" gets our message rather than a wrap
    uint64_t seed = 1;
    std::string avoid = "triangles";  // the plant's bent pipes have AABBs over most corridors
};

void checkOptions(const PathOptions& o) {
    if (o.frames < 1 || o.frames > int64_t(kMaxPathFrames))
        throw UsageError("--frames " + std::to_string(o.frames) + ": expected 1 to " + std::to_string(kMaxPathFrames));
    const std::filesystem::path out(o.output);
    if (out.extension() != ".cam") throw UsageError("-o " + o.output + ": the output must be a .cam file");
    const std::filesystem::path dir = out.parent_path().empty() ? "." : out.parent_path();
    std::error_code ec;
    if (!std::filesystem::is_directory(dir, ec))
        throw UsageError("-o " + o.output + ": folder " + dir.string() + " does not exist");
}

int runOrbit(const PathOptions& o) {
    checkOptions(o);
    const OssFile file = OssFile::open(preparedScene(o.scene));
    const std::vector<CameraPose> cameras = orbitPath(pathSceneOf(file), uint32_t(o.frames));
    writeCameraPath(o.output, cameras);
    const CameraPose& first = cameras.front();
    std::fprintf(stderr, "path: orbit of %s -> %s: %zu cameras, path length %.6g scene units "
                 "(around (%.6g, %.6g, %.6g) at distance %.6g, near %.6g, far %.6g)\n",
                 o.scene.c_str(), o.output.c_str(), cameras.size(), eyePathLength(cameras), double(first.target.x),
                 double(first.target.y), double(first.target.z), double(glm::length(first.eye - first.target)),
                 double(first.near_plane), double(first.far_plane));
    return 0;
}

int runWalk(const PathOptions& o) {
    checkOptions(o);
    const OssFile file = OssFile::open(preparedScene(o.scene));
    const Avoid avoid = o.avoid == "triangles" ? Avoid::triangles : Avoid::boxes;
    const WalkPath walk = walkPath(pathSceneOf(file), uint32_t(o.frames), o.seed, avoid);
    writeCameraPath(o.output, walk.cameras);
    char height[96];
    if (walk.on_floor)
        std::snprintf(height, sizeof(height), "%.6g (floor at y = %.6g, + 1.7)", double(walk.eye_height), double(walk.floor_top));
    else
        std::snprintf(height, sizeof(height), "%.6g (no floors: the most enclosed cut)", double(walk.eye_height));
    std::fprintf(stderr, "path: walk through %s -> %s: %zu cameras, path length %.6g scene units, eye height %s; "
                 "avoiding %s on %ux%u cells of %.6g, free region %llu cells, seed %llu\n",
                 o.scene.c_str(), o.output.c_str(), walk.cameras.size(), eyePathLength(walk.cameras), height,
                 o.avoid.c_str(), walk.grid_x, walk.grid_z, double(walk.cell_size),
                 (unsigned long long)walk.free_cells, (unsigned long long)o.seed);
    return 0;
}

void addCommonOptions(CLI::App* sub, PathOptions& o) {
    sub->add_option("scene", o.scene, "prepared scene (.oss, from occswitch prep)")->required();
    sub->add_option("--frames", o.frames, "cameras to write, 1 to 10000000")->capture_default_str();
    sub->add_option("-o,--out", o.output, "output camera path (.cam text: one camera per line)")->required();
}

}  // namespace

Command addPathCommand(CLI::App& app) {
    auto o = std::make_shared<PathOptions>();
    CLI::App* path = app.add_subcommand(
        "path", "Write a camera path: a text file with one camera per line (eye, target, up, vertical fov\n"
                "in degrees, near, far), which `render` plays and people may edit.");
    path->require_subcommand(1);

    CLI::App* orbit = path->add_subcommand(
        "orbit", "Circle the scene from outside: one full turn over --frames cameras far enough from the\n"
                 "centre (2.1 bounding-sphere radii) that the whole model is in view, 25 degrees above it,\n"
                 "looking at the centre.");
    addCommonOptions(orbit, *o);

    CLI::App* walk = path->add_subcommand(
        "walk", "Fly through the scene's interior at eye height, turning smoothly: the case where occlusion\n"
                "matters. With floors (large flat slabs) the eye is 1.7 above the lowest floor with room\n"
                "(units taken as metres); without, at the most enclosed of 16 horizontal cuts. A seeded\n"
                "random walk over a free-space grid, smoothed, at 0.4 cells per frame.\n"
                "Same scene, frames, seed and --avoid: same file.");
    addCommonOptions(walk, *o);
    walk->add_option("--seed", o->seed, "random seed of the walk")->capture_default_str();
    walk->add_option("--avoid", o->avoid,
                     "what eyes keep a cell away from: boxes (every object's AABB; the AABBs of bent pipes\n"
                     "can close corridors) or triangles (the geometry itself)")
        ->check(CLI::IsMember({"boxes", "triangles"}))
        ->capture_default_str();

    return {path, [o, orbit] { return orbit->parsed() ? runOrbit(*o) : runWalk(*o); }};
}

}  // namespace occ::cli
