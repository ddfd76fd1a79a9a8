// SPDX-License-Identifier: MIT
#include "cli/commands.h"

#include "device_memory.h"
#include "import/import.h"
#include "prep/weld.h"
#include "scene/oss_file.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>

namespace occ::cli {

namespace {

struct InfoOptions {
    std::string file;
    bool device = false;
    ImportOptions import;
};

nlohmann::json vec3Json(const glm::vec3& v) { return {v.x, v.y, v.z}; }

// Summary of a preprocessed scene: counts, occluders, how much can simplify, section sizes.
int runOssInfo(const std::string& path) {
    const OssFile file = OssFile::open(path);
    // The objects' meshes come first, the hierarchy's HLODs after them.
    uint32_t object_meshes = file.meshCount();
    uint32_t levels = 0;
    for (const oss::Node& n : file.nodes()) {
        levels = std::max(levels, n.depth + 1);
        if (n.child_count > 0) object_meshes = std::min(object_meshes, n.mesh);
    }
    const OssFile::HlodCounts hlods = file.hlodCounts();
    uint64_t q_sum = 0, n_sum = 0, refused = 0, instanced_triangles = 0, vertices = 0, triangles = 0;
    float error_min = INFINITY, error_max = 0.0f;
    for (uint32_t m = 0; m < object_meshes; ++m) {
        const OssFile::MeshView mesh = file.mesh(m);
        q_sum += mesh.q;
        n_sum += mesh.vertexCount();
        vertices += mesh.vertexCount();
        triangles += mesh.triangleCount();
        refused += mesh.refused_faces;
        for (uint32_t v = mesh.q; v < mesh.vertexCount(); ++v) {
            error_min = std::min(error_min, mesh.error[v]);
            error_max = std::max(error_max, mesh.error[v]);
        }
    }
    Bounds bounds;
    for (const oss::ObjectDisk& o : file.objects()) {
        instanced_triangles += file.mesh(o.mesh).triangleCount();
        bounds.extend(glm::vec3(o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]));
        bounds.extend(glm::vec3(o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]));
    }
    const float diagonal = glm::length(bounds.max - bounds.min);

    nlohmann::ordered_json j;
    j["file"] = path;
    j["format_bytes"] = file.fileSize();
    j["objects"] = file.objectCount();
    j["meshes"] = object_meshes;
    j["vertices"] = vertices;
    j["triangles"] = triangles;
    j["triangles_with_instances"] = instanced_triangles;
    j["cos"] = file.cos().size();
    j["ct"] = file.ct();
    j["boundary_vertex_share"] = n_sum ? double(q_sum) / double(n_sum) : 0.0;
    j["refused_faces"] = refused;
    j["bounds"] = {{"min", vec3Json(bounds.min)}, {"max", vec3Json(bounds.max)}};
    if (file.nodeCount() > 0)
        j["hierarchy"] = {{"nodes", file.nodeCount()},
                          {"levels", levels},
                          {"inner_nodes", hlods.inner},
                          {"inner_nodes_sharing_an_hlod", hlods.inner - hlods.meshes},
                          {"hlod_meshes", file.meshCount() - object_meshes},
                          {"hlod_triangles", file.triangleCount() - triangles}};
    else
        j["hierarchy"] = nullptr;
    if (error_min <= error_max)
        j["simplification_error"] = {{"min", error_min}, {"max", error_max},
                                     {"max_relative_to_diagonal", diagonal > 0 ? error_max / diagonal : 0.0f}};
    nlohmann::ordered_json sections = nlohmann::ordered_json::object();
    for (const OssFile::SectionInfo& s : file.sections())
        sections[s.name] = {{"offset", s.offset}, {"bytes", s.size}, {"count", s.count}};
    j["sections"] = sections;
    std::cout << j.dump(2) << std::endl;
    return 0;
}

// The device this build's kernels run on, or the one line that says why they cannot (exit 1):
// what launch/gpu-check asks before anything else.
int runDeviceInfo() {
    const k::DeviceInfo d = k::selectDevice(-1);
    nlohmann::ordered_json j;
    j["backend"] = k::deviceBackend();
    j["device"] = d.name;
    j["ordinal"] = d.ordinal;
    if (d.ordinal >= 0) {
        j["uuid"] = d.uuid;
        j["memory_mib"] = d.total_bytes >> 20;
        j["compute_capability"] = std::to_string(d.major) + "." + std::to_string(d.minor);
        j["driver_cuda"] = std::to_string(d.driver_version / 1000) + "." + std::to_string(d.driver_version % 1000 / 10);
        j["runtime_cuda"] = std::to_string(d.runtime_version / 1000) + "." + std::to_string(d.runtime_version % 1000 / 10);
        j["built_for"] = k::builtArchitectures();
    }
    std::cout << j.dump(2) << std::endl;
    return 0;
}

int runInfo(const InfoOptions& o) {
    if (o.device) {
        if (!o.file.empty()) throw UsageError("info: --device takes no file");
        return runDeviceInfo();
    }
    if (o.file.empty()) throw UsageError("info: a model or .oss file, or --device");
    if (lowerExtension(o.file) == ".oss") return runOssInfo(o.file);
    const auto start = std::chrono::steady_clock::now();
    const Scene scene = importModel(o.file, o.import);
    const Bounds bounds = scene.worldBounds();
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

    nlohmann::ordered_json j;
    j["file"] = o.file;
    j["objects"] = scene.objects.size();
    j["meshes"] = scene.meshes.size();
    j["triangles"] = scene.triangleCount();
    j["vertices"] = scene.vertexCount();
    j["bounds"] = {{"min", vec3Json(bounds.min)}, {"max", vec3Json(bounds.max)}};
    // What prep drops on top of what import skipped: triangles with a repeated corner once
    // vertices at the same place are welded (per mesh, as prep counts them; and with instances).
    uint64_t repeated = 0, repeated_instances = 0;
    std::vector<uint64_t> per_mesh(scene.meshes.size());
    for (size_t m = 0; m < scene.meshes.size(); ++m) {
        per_mesh[m] = weldPositions(scene.meshes[m].positions, scene.meshes[m].indices).dropped_triangles;
        repeated += per_mesh[m];
    }
    for (const Object& object : scene.objects) repeated_instances += per_mesh[object.mesh];
    j["skipped"] = {{"points", scene.skipped.points},
                    {"lines", scene.skipped.lines},
                    {"degenerate_faces", scene.skipped.degenerate},
                    {"unknown_materials", scene.skipped.unknown_materials},
                    {"repeated_corner_triangles", repeated},
                    {"repeated_corner_triangles_with_instances", repeated_instances}};
    j["triangles_kept"] = scene.triangleCount() - repeated_instances;
    j["import_seconds"] = std::round(seconds * 1000.0) / 1000.0;
    std::cout << j.dump(2) << std::endl;
    return 0;
}

}  // namespace

Command addInfoCommand(CLI::App& app) {
    auto options = std::make_shared<InfoOptions>();
    CLI::App* sub = app.add_subcommand("info", "Print a JSON summary of a model (glTF, GLB, OBJ, PLY, OFF, STL): objects, meshes,\n"
                                               "triangles, vertices, bounds, skipped primitives; or of a .oss scene: counts, |COS|,\n"
                                               "boundary-vertex share, simplification error range, section sizes.");
    sub->add_option("file", options->file, "model file or .oss scene");
    sub->add_flag("--device", options->device,
                  "instead: the device this build's kernels run on (occswitch-cuda: the GPU, its memory, compute\n"
                  "capability, driver and the architectures built), or why they cannot (exit 1)");
    sub->add_option("--scene", options->import.scene, "glTF: the scene to summarize (default: the file's default scene)");
    return {sub, [options] { return runInfo(*options); }};
}

}  // namespace occ::cli
