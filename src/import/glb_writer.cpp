// SPDX-License-Identifier: MIT
#include "import/glb_writer.h"

#include "scene/atomic_file.h"
#include "scene/errors.h"

#include <nlohmann/json.hpp>

#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <unistd.h>

namespace occ {

namespace {

using nlohmann::json;

void appendPadded(std::vector<unsigned char>& bin, const void* data, size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    bin.insert(bin.end(), p, p + size);
    while (bin.size() % 4 != 0) bin.push_back(0);
}

void putU32(std::vector<unsigned char>& out, uint32_t v) {
    unsigned char b[4];
    std::memcpy(b, &v, 4);
    out.insert(out.end(), b, b + 4);
}

bool isIdentity(const glm::mat4& m) { return m == glm::mat4(1.0f); }

}  // namespace

void writeGlb(const std::string& path, const std::vector<Mesh>& meshes, const std::vector<GltfNode>& nodes,
              const std::vector<uint32_t>& roots) {
    std::vector<unsigned char> bin;
    json accessors = json::array(), views = json::array(), gmeshes = json::array(), materials = json::array();
    std::map<std::array<float, 4>, size_t> material_of_color;

    for (const Mesh& mesh : meshes) {
        glm::vec3 lo(0.0f), hi(0.0f);
        if (!mesh.positions.empty()) lo = hi = mesh.positions[0];
        for (const glm::vec3& p : mesh.positions) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
        const size_t pos_offset = bin.size();
        appendPadded(bin, mesh.positions.data(), mesh.positions.size() * sizeof(glm::vec3));
        views.push_back({{"buffer", 0}, {"byteOffset", pos_offset},
                         {"byteLength", mesh.positions.size() * sizeof(glm::vec3)}, {"target", 34962}});
        accessors.push_back({{"bufferView", views.size() - 1}, {"componentType", 5126},
                             {"count", mesh.positions.size()}, {"type", "VEC3"},
                             {"min", {lo.x, lo.y, lo.z}}, {"max", {hi.x, hi.y, hi.z}}});

        // 16-bit indices halve the index bytes of the many small CAD parts.
        const bool narrow = mesh.positions.size() <= 65535;
        const size_t idx_offset = bin.size();
        size_t idx_bytes = 0;
        if (narrow) {
            std::vector<uint16_t> small(mesh.indices.begin(), mesh.indices.end());
            idx_bytes = small.size() * 2;
            appendPadded(bin, small.data(), idx_bytes);
        } else {
            idx_bytes = mesh.indices.size() * 4;
            appendPadded(bin, mesh.indices.data(), idx_bytes);
        }
        views.push_back({{"buffer", 0}, {"byteOffset", idx_offset}, {"byteLength", idx_bytes}, {"target", 34963}});
        accessors.push_back({{"bufferView", views.size() - 1}, {"componentType", narrow ? 5123 : 5125},
                             {"count", mesh.indices.size()}, {"type", "SCALAR"}});

        const std::array<float, 4> key{mesh.color.r, mesh.color.g, mesh.color.b, mesh.color.a};
        auto [it, added] = material_of_color.emplace(key, materials.size());
        if (added)
            materials.push_back({{"pbrMetallicRoughness",
                                  {{"baseColorFactor", {key[0], key[1], key[2], key[3]}}, {"metallicFactor", 0.0}}}});
        json prim = {{"attributes", {{"POSITION", accessors.size() - 2}}},
                     {"indices", accessors.size() - 1},
                     {"material", it->second},
                     {"mode", 4}};
        gmeshes.push_back({{"name", mesh.name}, {"primitives", json::array({prim})}});
    }

    json gnodes = json::array();
    for (const GltfNode& n : nodes) {
        json node = json::object();
        if (n.mesh >= 0) node["mesh"] = n.mesh;
        if (!n.children.empty()) node["children"] = n.children;
        if (!isIdentity(n.matrix)) {
            json m = json::array();
            for (int c = 0; c < 4; ++c)
                for (int r = 0; r < 4; ++r) m.push_back(n.matrix[c][r]);
            node["matrix"] = m;
        }
        gnodes.push_back(node);
    }

    json doc = {{"asset", {{"version", "2.0"}, {"generator", "occswitch"}}},
                {"scene", 0},
                {"scenes", json::array({json{{"nodes", roots}}})},
                {"nodes", gnodes},
                {"meshes", gmeshes},
                {"materials", materials},
                {"accessors", accessors},
                {"bufferViews", views},
                {"buffers", json::array({json{{"byteLength", bin.size()}}})}};
    std::string text = doc.dump();
    while (text.size() % 4 != 0) text.push_back(' ');

    std::vector<unsigned char> out;
    out.reserve(28 + text.size() + bin.size());
    putU32(out, 0x46546C67);  // "glTF"
    putU32(out, 2);
    putU32(out, uint32_t(12 + 8 + text.size() + (bin.empty() ? 0 : 8 + bin.size())));
    putU32(out, uint32_t(text.size()));
    putU32(out, 0x4E4F534A);  // "JSON"
    out.insert(out.end(), text.begin(), text.end());
    if (!bin.empty()) {
        putU32(out, uint32_t(bin.size()));
        putU32(out, 0x004E4942);  // "BIN\0"
        out.insert(out.end(), bin.begin(), bin.end());
    }
    if (out.size() > UINT32_MAX) throw InputError(path, "scene too large for one GLB file (over 4 GiB)");

    // Readers see the old file or the whole new one.
    writeFileAtomic(path, std::string_view(reinterpret_cast<const char*>(out.data()), out.size()));
}

void writeSceneGlb(const std::string& path, const Scene& scene) {
    std::vector<GltfNode> nodes(scene.objects.size());
    std::vector<uint32_t> roots(scene.objects.size());
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        nodes[i].mesh = int32_t(scene.objects[i].mesh);
        nodes[i].matrix = scene.objects[i].world;
        roots[i] = uint32_t(i);
    }
    writeGlb(path, scene.meshes, nodes, roots);
}

}  // namespace occ
