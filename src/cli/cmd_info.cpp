// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "import/import.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <iostream>

namespace occ::cli {

namespace {

struct InfoOptions {
    std::string file;
};

nlohmann::json vec3Json(const glm::vec3& v) { return {v.x, v.y, v.z}; }

int runInfo(const InfoOptions& o) {
    const auto start = std::chrono::steady_clock::now();
    const Scene scene = importModel(o.file);
    const Bounds bounds = scene.worldBounds();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    nlohmann::ordered_json j;
    j["file"] = o.file;
    j["objects"] = scene.objects.size();
    j["meshes"] = scene.meshes.size();
    j["triangles"] = scene.triangleCount();
    j["vertices"] = scene.vertexCount();
    j["bounds"] = {{"min", vec3Json(bounds.min)}, {"max", vec3Json(bounds.max)}};
    j["skipped"] = {{"points", scene.skipped.points},
                    {"lines", scene.skipped.lines},
                    {"degenerate_faces", scene.skipped.degenerate}};
    j["import_seconds"] = std::round(seconds * 1000.0) / 1000.0;
    std::cout << j.dump(2) << std::endl;
    return 0;
}

}  // namespace

Command addInfoCommand(CLI::App& app) {
    auto options = std::make_shared<InfoOptions>();
    CLI::App* sub = app.add_subcommand("info", "Print a JSON summary of a model (glTF, GLB, OBJ, PLY, OFF, STL):\n"
                                               "objects, meshes, triangles, vertices, bounds, skipped primitives.");
    sub->add_option("file", options->file, "model file")->required();
    return {sub, [options] { return runInfo(*options); }};
}

}  // namespace occ::cli
