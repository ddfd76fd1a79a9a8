// SPDX-License-Identifier: MIT
#include "import/import.h"

#include "scene/errors.h"

#include <algorithm>
#include <filesystem>

namespace occ {

std::string lowerExtension(const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

Scene importModel(const std::string& path, const ImportOptions& options) {
    std::error_code ec;
    if (!std::filesystem::exists(path, ec)) throw InputError(path, "missing: no such file");
    if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a directory, not a model file");

    const std::string ext = lowerExtension(path);
    Scene scene;
    if (options.scene < -1) throw InputError(path, "scene " + std::to_string(options.scene) + " does not exist");
    if (options.scene > 0 && ext != ".gltf" && ext != ".glb")
        throw InputError(path, "has one scene, scene " + std::to_string(options.scene) + " does not exist");
    if (ext == ".gltf" || ext == ".glb")
        scene = importGltf(path, options);
    else if (ext == ".off")
        scene = importOff(path);
    else if (ext == ".obj")
        scene = importObj(path);
    else if (ext == ".ply")
        scene = importPly(path);
    else if (ext == ".stl")
        scene = importStl(path);
    else
        throw InputError(path, "unsupported file extension '" + ext +
                                   "' (expected .gltf, .glb, .obj, .ply, .off or .stl)");

    if (scene.triangleCount() == 0) {
        // Say what the file did have, so that a point cloud or a wireframe is not taken for a
        // broken reader.
        const SkippedPrimitives& s = scene.skipped;
        std::string had;
        const auto add = [&](uint64_t n, const char* what) {
            if (n) had += (had.empty() ? "" : ", ") + std::to_string(n) + " " + what;
        };
        add(s.points, s.points == 1 ? "point primitive" : "point primitives");
        add(s.lines, s.lines == 1 ? "line primitive" : "line primitives");
        add(s.degenerate, s.degenerate == 1 ? "degenerate face" : "degenerate faces");
        if (had.empty()) throw InputError(path, "no triangles in the scene (empty model)");
        throw InputError(path, "no triangles to draw: the scene has only " + had + " (occswitch draws triangles)");
    }
    return scene;
}

}  // namespace occ
