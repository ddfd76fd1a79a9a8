// SPDX-License-Identifier: MIT
#pragma once

#include "import/import.h"
#include "scene/scene.h"

#include <atomic>
#include <memory>
#include <string>
#include <vector>

namespace occ {

// A scene whose objects are known up front and whose meshes are read one at a time, so that a
// model larger than memory can be preprocessed (prep holds a few meshes at once, never all).
class SceneSource {
public:
    virtual ~SceneSource() = default;
    // Every object; Object::mesh indexes [0, meshCount()). An object whose mesh turns out to
    // have no triangles is dropped by whoever consumes the source.
    virtual const std::vector<Object>& objects() const = 0;
    virtual uint32_t meshCount() const = 0;
    // Triangles the mesh will have, or an estimate (for progress and scheduling).
    virtual uint64_t meshTriangles(uint32_t mesh) const = 0;
    // Mesh `mesh` decoded (positions, triangle list, colour); safe to call from several threads.
    // Throws InputError naming the file and where in it for anything invalid.
    virtual Mesh mesh(uint32_t mesh) const = 0;
    // Primitives skipped so far (points, lines, degenerate faces); complete once every mesh was read.
    virtual SkippedPrimitives skipped() const = 0;
    // How the meshes are read, for messages: "streamed" or "imported whole".
    virtual const char* how() const = 0;
};

// Bytes of a model file read so far while a source is opened (the JSON of a streamed glTF).
struct ReadProgress {
    std::atomic<uint64_t> done{0}, total{0};
};

// A scene already in memory as a source: taken over, or (sceneView) read where it is, which
// must outlive the source.
std::unique_ptr<SceneSource> sceneSource(Scene scene);
std::unique_ptr<SceneSource> sceneView(const Scene& scene);

enum class ReadMode {
    Auto,    // stream glTF files above kStreamAboveBytes that only use streamable features
    Stream,  // stream every glTF file that only uses streamable features
    Whole,   // import whole (importModel)
};
inline constexpr uint64_t kStreamAboveBytes = 256ull << 20;

// Opens a model for preprocessing. glTF (.glb and .gltf with external buffers) is read
// without loading its buffers or building a document: the JSON is parsed once as events into
// compact tables, and each mesh's bytes are read from the file when the mesh is asked for.
// That covers float and KHR_mesh_quantization positions, 8/16/32-bit indices and triangle
// lists, strips and fans; a file using sparse accessors, EXT_mesh_gpu_instancing, meshopt or
// Draco compression or data: URIs is imported whole instead (importModel), as is every other
// format. Same objects, meshes and errors' meaning either way.
std::unique_ptr<SceneSource> openSceneSource(const std::string& path, const ImportOptions& options = {},
                                             ReadMode mode = ReadMode::Auto, ReadProgress* progress = nullptr);

// The streaming glTF reader alone: nullptr when the file uses something it does not read
// (*why says what); throws InputError for a malformed file.
std::unique_ptr<SceneSource> streamGltf(const std::string& path, const ImportOptions& options, std::string* why,
                                        ReadProgress* progress = nullptr);

}  // namespace occ
