// SPDX-License-Identifier: MIT
#include "import/scene_source.h"

#include "scene/errors.h"

#include <cstdio>
#include <filesystem>

namespace occ {

namespace {

// A scene in memory as a source: its own (owned_ holds it) or another's.
class InMemorySource final : public SceneSource {
public:
    explicit InMemorySource(std::unique_ptr<Scene> owned) : owned_(std::move(owned)), scene_(*owned_) {}
    explicit InMemorySource(const Scene& scene) : scene_(scene) {}
    const std::vector<Object>& objects() const override { return scene_.objects; }
    uint32_t meshCount() const override { return uint32_t(scene_.meshes.size()); }
    uint64_t meshTriangles(uint32_t m) const override { return scene_.meshes[m].triangleCount(); }
    Mesh mesh(uint32_t m) const override { return scene_.meshes[m]; }
    SkippedPrimitives skipped() const override { return scene_.skipped; }
    const char* how() const override { return "imported whole"; }

private:
    std::unique_ptr<Scene> owned_;
    const Scene& scene_;
};

}  // namespace

std::unique_ptr<SceneSource> sceneSource(Scene scene) {
    return std::make_unique<InMemorySource>(std::make_unique<Scene>(std::move(scene)));
}
std::unique_ptr<SceneSource> sceneView(const Scene& scene) { return std::make_unique<InMemorySource>(scene); }

std::unique_ptr<SceneSource> openSceneSource(const std::string& path, const ImportOptions& options, ReadMode mode,
                                             ReadProgress* progress) {
    const std::string ext = lowerExtension(path);
    if (mode != ReadMode::Whole && (ext == ".glb" || ext == ".gltf")) {
        std::error_code ec;
        const uint64_t bytes = std::filesystem::file_size(path, ec);
        // A .gltf's size is its JSON; its buffers are what is large.
        uint64_t total = ec ? 0 : bytes;
        if (ext == ".gltf" && !ec) {
            for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(path).parent_path().empty()
                                                                               ? std::filesystem::path(".")
                                                                               : std::filesystem::path(path).parent_path(),
                                                                           ec))
                if (entry.path().extension() == ".bin" &&
                    entry.path().stem() == std::filesystem::path(path).stem())
                    total += entry.file_size(ec);
        }
        if (mode == ReadMode::Stream || total > kStreamAboveBytes) {
            std::string why;
            if (auto source = streamGltf(path, options, &why, progress)) return source;
            if (mode == ReadMode::Stream || total > kStreamAboveBytes)
                std::fprintf(stderr, "note: %s uses %s, which only the whole-file import reads: importing it whole\n",
                             path.c_str(), why.c_str());
        }
    }
    return sceneSource(importModel(path, options));
}

}  // namespace occ
