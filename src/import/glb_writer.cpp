// SPDX-License-Identifier: MIT
#include "import/glb_writer.h"

#include "import/gltf_common.h"

#include "scene/errors.h"

#include <charconv>
#include <cstring>
#include <filesystem>

namespace occ {

namespace {

using gltf::kGlbMagic;
constexpr uint64_t kGlbLimit = 0xFFFFFFFFull;   // the GLB header's 32-bit length

bool isIdentity(const glm::mat4& m) { return m == glm::mat4(1.0f); }

// JSON text written through a buffer into an AtomicFile.
class JsonOut {
public:
    explicit JsonOut(AtomicFile& file) : file_(file) { buffer_.reserve(kFlush + 4096); }
    JsonOut& operator<<(std::string_view s) {
        buffer_.append(s);
        if (buffer_.size() >= kFlush) flush();
        return *this;
    }
    JsonOut& operator<<(uint64_t v) {
        char b[24];
        const auto r = std::to_chars(b, b + sizeof b, v);
        return *this << std::string_view(b, size_t(r.ptr - b));
    }
    JsonOut& operator<<(uint32_t v) { return *this << uint64_t(v); }
    JsonOut& operator<<(int32_t v) {
        if (v < 0) *this << "-";
        return *this << uint64_t(v < 0 ? -int64_t(v) : v);
    }
    // Shortest text that reads back as the same float.
    JsonOut& number(float v) {
        char b[32];
        const auto r = std::to_chars(b, b + sizeof b, v);
        return *this << std::string_view(b, size_t(r.ptr - b));
    }
    JsonOut& string(std::string_view s) {
        *this << "\"";
        for (const char c : s) {
            if (c == '"' || c == '\\') {
                const char e[2] = {'\\', c};
                *this << std::string_view(e, 2);
            } else if (static_cast<unsigned char>(c) < 0x20) {
                char e[8];
                std::snprintf(e, sizeof e, "\\u%04x", unsigned(static_cast<unsigned char>(c)));
                *this << std::string_view(e, 6);
            } else {
                buffer_.push_back(c);
            }
        }
        return *this << "\"";
    }
    void flush() {
        file_.write(buffer_);
        buffer_.clear();
    }

private:
    static constexpr size_t kFlush = 1 << 20;
    AtomicFile& file_;
    std::string buffer_;
};

void putU32(unsigned char* out, uint32_t v) { std::memcpy(out, &v, 4); }

}  // namespace

GltfStreamWriter::GltfStreamWriter(const std::string& path) : path_(path) {
    const std::string ext = std::filesystem::path(path).extension().string();
    binary_ = ext == ".glb";
    if (!binary_ && ext != ".gltf") throw InputError(path, "a glTF output must end in .glb or .gltf");
    const std::filesystem::path bin = std::filesystem::path(path).replace_extension(".bin");
    bin_name_ = bin.filename().string();
    // The .glb's buffer is a scratch file copied into it; the .gltf's is committed beside it.
    bin_ = std::make_unique<AtomicFile>(binary_ ? path + ".bin" : bin.string());
}

uint32_t GltfStreamWriter::addMesh(const Mesh& mesh) {
    MeshEntry e;
    e.name = mesh.name;
    e.vertices = uint32_t(mesh.positions.size());
    e.indices = uint32_t(mesh.indices.size());
    e.lo = e.hi = mesh.positions.empty() ? glm::vec3(0.0f) : mesh.positions[0];
    for (const glm::vec3& p : mesh.positions) {
        e.lo = glm::min(e.lo, p);
        e.hi = glm::max(e.hi, p);
    }
    static const unsigned char zeros[4] = {};
    const auto padded = [&](const void* data, size_t bytes) {
        bin_->write(data, bytes);
        bin_->write(zeros, (4 - bytes % 4) % 4);
    };
    e.position_offset = bin_->size();
    padded(mesh.positions.data(), mesh.positions.size() * sizeof(glm::vec3));
    // 16-bit indices halve the index bytes of the many small CAD parts.
    e.narrow = mesh.positions.size() <= 65535;
    e.index_offset = bin_->size();
    if (e.narrow) {
        std::vector<uint16_t> small(mesh.indices.begin(), mesh.indices.end());
        padded(small.data(), small.size() * 2);
    } else {
        padded(mesh.indices.data(), mesh.indices.size() * 4);
    }
    if (binary_ && bin_->size() > kGlbLimit - (64u << 20))
        throw InputError(path_, "the scene's buffer passes the 4 GiB a .glb file can hold; write a .gltf "
                                "(its buffer goes to a .bin file beside it)");

    const std::array<float, 4> key{mesh.color.r, mesh.color.g, mesh.color.b, mesh.color.a};
    const auto [it, added] = material_of_color_.emplace(key, uint32_t(materials_.size()));
    if (added) materials_.push_back(key);
    e.material = it->second;
    meshes_.push_back(std::move(e));
    return uint32_t(meshes_.size() - 1);
}

uint32_t GltfStreamWriter::addNode(const GltfNode& node) {
    nodes_.push_back(node);
    return uint32_t(nodes_.size() - 1);
}

void GltfStreamWriter::finish(const std::vector<uint32_t>& roots) {
    AtomicFile out(path_);
    unsigned char head[20] = {};
    if (binary_) out.write(head, sizeof head);  // GLB header and JSON chunk header, filled in below
    const uint64_t json_start = out.size();
    {
        JsonOut j(out);
        j << "{\"asset\":{\"version\":\"2.0\",\"generator\":\"occswitch\"},\"scene\":0,\"scenes\":[{\"nodes\":[";
        for (size_t i = 0; i < roots.size(); ++i) j << (i ? "," : "") << roots[i];
        j << "]}],\"nodes\":[";
        for (size_t i = 0; i < nodes_.size(); ++i) {
            const GltfNode& n = nodes_[i];
            j << (i ? ",{" : "{");
            const char* sep = "";
            if (n.mesh >= 0) j << "\"mesh\":" << n.mesh, sep = ",";
            if (!n.children.empty()) {
                j << sep << "\"children\":[";
                for (size_t c = 0; c < n.children.size(); ++c) j << (c ? "," : "") << n.children[c];
                j << "]";
                sep = ",";
            }
            if (!isIdentity(n.matrix)) {
                j << sep << "\"matrix\":[";
                for (int c = 0; c < 4; ++c)
                    for (int r = 0; r < 4; ++r) j.number(n.matrix[c][r]) << (c == 3 && r == 3 ? "]" : ",");
            }
            j << "}";
        }
        j << "],\"meshes\":[";
        for (size_t m = 0; m < meshes_.size(); ++m) {
            j << (m ? ",{\"name\":" : "{\"name\":");
            j.string(meshes_[m].name) << ",\"primitives\":[{\"attributes\":{\"POSITION\":" << uint64_t(2 * m)
                                      << "},\"indices\":" << uint64_t(2 * m + 1)
                                      << ",\"material\":" << meshes_[m].material << ",\"mode\":4}]}";
        }
        j << "],\"materials\":[";
        for (size_t k = 0; k < materials_.size(); ++k) {
            j << (k ? "," : "") << "{\"pbrMetallicRoughness\":{\"baseColorFactor\":[";
            for (int c = 0; c < 4; ++c) j.number(materials_[k][size_t(c)]) << (c < 3 ? "," : "");
            j << "],\"metallicFactor\":0}}";
        }
        j << "],\"accessors\":[";
        for (size_t m = 0; m < meshes_.size(); ++m) {
            const MeshEntry& e = meshes_[m];
            j << (m ? "," : "") << "{\"bufferView\":" << uint64_t(2 * m) << ",\"componentType\":5126,\"count\":"
              << e.vertices << ",\"type\":\"VEC3\",\"min\":[";
            j.number(e.lo.x) << ",";
            j.number(e.lo.y) << ",";
            j.number(e.lo.z) << "],\"max\":[";
            j.number(e.hi.x) << ",";
            j.number(e.hi.y) << ",";
            j.number(e.hi.z) << "]},{\"bufferView\":" << uint64_t(2 * m + 1)
                             << ",\"componentType\":" << (e.narrow ? 5123u : 5125u) << ",\"count\":" << e.indices
                             << ",\"type\":\"SCALAR\"}";
        }
        j << "],\"bufferViews\":[";
        for (size_t m = 0; m < meshes_.size(); ++m) {
            const MeshEntry& e = meshes_[m];
            j << (m ? "," : "") << "{\"buffer\":0,\"byteOffset\":" << e.position_offset
              << ",\"byteLength\":" << uint64_t(e.vertices) * 12 << ",\"target\":34962},{\"buffer\":0,\"byteOffset\":"
              << e.index_offset << ",\"byteLength\":" << uint64_t(e.indices) * (e.narrow ? 2 : 4)
              << ",\"target\":34963}";
        }
        j << "],\"buffers\":[{\"byteLength\":" << bin_->size();
        if (!binary_) {
            j << ",\"uri\":";
            j.string(bin_name_);
        }
        j << "}]}";
        j.flush();
    }
    if (!binary_) {
        out.commit();
        bin_->commit();
        return;
    }
    const uint64_t json_length = out.size() - json_start;
    static const char spaces[4] = {' ', ' ', ' ', ' '};
    out.write(spaces, (4 - json_length % 4) % 4);
    const uint64_t json_chunk = out.size() - json_start;
    unsigned char bin_head[8];
    putU32(bin_head, uint32_t(bin_->size()));
    putU32(bin_head + 4, gltf::kGlbChunkBin);
    const uint64_t total = out.size() + (bin_->size() ? 8 + bin_->size() : 0);
    if (total > kGlbLimit)
        throw InputError(path_, "the scene needs " + std::to_string(total) +
                                    " bytes, over the 4 GiB a .glb file can hold; write a .gltf");
    if (bin_->size()) {
        out.write(bin_head, sizeof bin_head);
        out.append(*bin_);
    }
    putU32(head, kGlbMagic);
    putU32(head + 4, 2);
    putU32(head + 8, uint32_t(total));
    putU32(head + 12, uint32_t(json_chunk));
    putU32(head + 16, gltf::kGlbChunkJson);
    out.writeAt(0, head, sizeof head);
    out.commit();
    bin_.reset();  // the scratch buffer goes
}

void writeGlb(const std::string& path, const std::vector<Mesh>& meshes, const std::vector<GltfNode>& nodes,
              const std::vector<uint32_t>& roots) {
    GltfStreamWriter writer(path);
    for (const Mesh& m : meshes) writer.addMesh(m);
    for (const GltfNode& n : nodes) writer.addNode(n);
    writer.finish(roots);
}

void writeSceneGlb(const std::string& path, const Scene& scene) {
    GltfStreamWriter writer(path);
    for (const Mesh& m : scene.meshes) writer.addMesh(m);
    std::vector<uint32_t> roots(scene.objects.size());
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        GltfNode node;
        node.mesh = int32_t(scene.objects[i].mesh);
        node.matrix = scene.objects[i].world;
        roots[i] = writer.addNode(node);
    }
    writer.finish(roots);
}

}  // namespace occ
