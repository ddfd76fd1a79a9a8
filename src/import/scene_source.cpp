// SPDX-License-Identifier: MIT
#include "import/scene_source.h"

#include "scene/errors.h"

#include <cstdio>
#include <filesystem>

namespace occ {

namespace {

class InMemorySource final : public SceneSource {
public:
    explicit InMemorySource(Scene scene) : scene_(std::move(scene)) {}
    const std::vector<Object>& objects() const override { return scene_.objects; }
    uint32_t meshCount() const override { return uint32_t(scene_.meshes.size()); }
    uint64_t meshTriangles(uint32_t m) const override { return scene_.meshes[m].triangleCount(); }
    Mesh mesh(uint32_t m) const override { return scene_.meshes[m]; }
    SkippedPrimitives skipped() const override { return scene_.skipped; }
    const char* how() const override { return "imported whole"; }

private:
    Scene scene_;
};

}  // namespace

std::unique_ptr<SceneSource> sceneSource(Scene scene) { return std::make_unique<InMemorySource>(std::move(scene)); }

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
