// SPDX-License-Identifier: MIT
#include "import/import.h"

#include "scene/errors.h"

#include <tiny_gltf.h>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>

namespace occ {

namespace {

constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
constexpr uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kGlbChunkBin = 0x004E4942;   // "BIN\0"

std::vector<unsigned char> readWholeFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    in.seekg(0, std::ios::beg);
    std::vector<unsigned char> bytes(size_t(std::max<std::streamoff>(size, 0)));
    if (!bytes.empty() && !in.read(reinterpret_cast<char*>(bytes.data()), size))
        throw InputError(path, "read error");
    return bytes;
}

uint32_t readU32(const std::vector<unsigned char>& b, size_t offset) {
    uint32_t v;
    std::memcpy(&v, b.data() + offset, 4);
    return v;
}

// tinygltf trusts the GLB container more than we want to (it only checks part of it), so the
// header and chunk table are validated here first, with byte offsets in every message.
void validateGlbContainer(const std::string& path, const std::vector<unsigned char>& b) {
    if (b.size() < 12)
        throw InputError(path, "truncated: " + std::to_string(b.size()) + " bytes, a GLB header needs 12");
    if (readU32(b, 0) != kGlbMagic) throw InputError(path, "offset 0: bad magic, not a binary glTF (GLB) file");
    const uint32_t version = readU32(b, 4);
    if (version != 2)
        throw InputError(path, "offset 4: unsupported GLB version " + std::to_string(version) + " (expected 2)");
    const uint32_t length = readU32(b, 8);
    if (length > b.size())
        throw InputError(path, "offset 8: truncated: header says " + std::to_string(length) + " bytes, file has " +
                                   std::to_string(b.size()));
    if (length < b.size())
        throw InputError(path, "offset 8: header says " + std::to_string(length) + " bytes, file has " +
                                   std::to_string(b.size()) + " (trailing bytes)");
    size_t offset = 12;
    int chunk = 0;
    while (offset < length) {
        if (length - offset < 8)
            throw InputError(path, "offset " + std::to_string(offset) + ": truncated chunk header");
        const uint32_t chunk_length = readU32(b, offset);
        const uint32_t chunk_type = readU32(b, offset + 4);
        if (uint64_t(chunk_length) > length - offset - 8)
            throw InputError(path, "offset " + std::to_string(offset) + ": truncated: chunk of " +
                                       std::to_string(chunk_length) + " bytes runs past the end of the file");
        if (chunk == 0 && chunk_type != kGlbChunkJson)
            throw InputError(path, "offset " + std::to_string(offset + 4) + ": first chunk is not JSON");
        if (chunk == 1 && chunk_type != kGlbChunkBin)
            throw InputError(path, "offset " + std::to_string(offset + 4) + ": second chunk is not BIN");
        offset += 8 + size_t(chunk_length);
        ++chunk;
    }
    if (chunk == 0) throw InputError(path, "offset 12: truncated: no JSON chunk");
}

std::string oneLine(std::string s) {
    for (char& c : s)
        if (c == '\n' || c == '\r') c = ' ';
    while (!s.empty() && s.back() == ' ') s.pop_back();
    return s;
}

// Textures are irrelevant to geometry; skipping their decoding keeps import fast and lets a model
// with a missing or broken image still load.
bool ignoreImage(tinygltf::Image*, const int, std::string*, std::string*, int, int, const unsigned char*, int,
                 void*) {
    return true;
}

bool isGeometryNeutralExtension(const std::string& name) {
    return name.rfind("KHR_materials_", 0) == 0 || name == "KHR_texture_transform" ||
           name == "KHR_lights_punctual" || name == "KHR_texture_basisu" || name == "EXT_texture_webp";
}

class GltfFlattener {
public:
    GltfFlattener(const std::string& path, const tinygltf::Model& model) : path_(path), model_(model) {}

    Scene run() {
        for (const std::string& ext : model_.extensionsRequired)
            if (!isGeometryNeutralExtension(ext))
                throw InputError(path_, "extensionsRequired: unsupported required extension " + ext);

        std::vector<int> roots;
        if (!model_.scenes.empty()) {
            const int scene = model_.defaultScene >= 0 ? model_.defaultScene : 0;
            if (scene >= int(model_.scenes.size()))
                throw InputError(path_, "/scene: index " + std::to_string(scene) + " out of range (" +
                                            std::to_string(model_.scenes.size()) + " scenes)");
            roots = model_.scenes[size_t(scene)].nodes;
        } else {
            // Without scenes, the spec leaves the choice to us: every node that is nobody's
            // child is drawn.
            std::vector<bool> is_child(model_.nodes.size(), false);
            for (const tinygltf::Node& n : model_.nodes)
                for (int c : n.children)
                    if (c >= 0 && size_t(c) < is_child.size()) is_child[size_t(c)] = true;
            for (size_t i = 0; i < model_.nodes.size(); ++i)
                if (!is_child[i]) roots.push_back(int(i));
        }
        if (roots.empty()) throw InputError(path_, "/scenes: empty scene, it has no nodes (no triangles)");

        state_.assign(model_.nodes.size(), NodeState::Unvisited);
        for (size_t i = 0; i < roots.size(); ++i) {
            checkNodeIndex(roots[i], "/scenes/nodes/" + std::to_string(i));
            flatten(roots[i]);
        }
        return std::move(scene_);
    }

private:
    enum class NodeState : uint8_t { Unvisited, OnPath, Done };

    void checkNodeIndex(int node, const std::string& where) const {
        if (node < 0 || size_t(node) >= model_.nodes.size())
            throw InputError(path_, where + ": node index " + std::to_string(node) + " out of range (" +
                                        std::to_string(model_.nodes.size()) + " nodes)");
    }

    glm::mat4 localMatrix(int node_index) const {
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        glm::mat4 m(1.0f);
        if (node.matrix.size() == 16) {
            m = glm::mat4(glm::make_mat4(node.matrix.data()));
        } else {
            glm::dvec3 t(0.0), s(1.0);
            glm::dquat r(1.0, 0.0, 0.0, 0.0);
            if (node.translation.size() == 3) t = glm::make_vec3(node.translation.data());
            if (node.scale.size() == 3) s = glm::make_vec3(node.scale.data());
            if (node.rotation.size() == 4)
                r = glm::dquat(node.rotation[3], node.rotation[0], node.rotation[1], node.rotation[2]);
            const glm::dmat4 trs = glm::translate(glm::dmat4(1.0), t) * glm::mat4_cast(r) * glm::scale(glm::dmat4(1.0), s);
            m = glm::mat4(trs);
        }
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r)
                if (!std::isfinite(m[c][r]))
                    throw InputError(path_, "/nodes/" + std::to_string(node_index) + ": non-finite (nan or inf) transform");
        return m;
    }

    // Iterative depth-first walk: a malicious or broken file can have node chains far deeper
    // than the call stack, and cycles (which glTF forbids) must be reported, not followed.
    void flatten(int root) {
        struct Frame {
            int node;
            glm::mat4 world;
            size_t next_child;
        };
        if (state_[size_t(root)] == NodeState::Done)
            throw InputError(path_, "/nodes/" + std::to_string(root) + ": node has more than one parent");
        std::vector<Frame> stack;
        stack.push_back({root, localMatrix(root), 0});
        state_[size_t(root)] = NodeState::OnPath;
        emitPrimitives(root, stack.back().world);
        while (!stack.empty()) {
            Frame& top = stack.back();
            const tinygltf::Node& node = model_.nodes[size_t(top.node)];
            if (top.next_child == node.children.size()) {
                state_[size_t(top.node)] = NodeState::Done;
                stack.pop_back();
                continue;
            }
            const size_t ci = top.next_child++;
            const int child = node.children[ci];
            const std::string where = "/nodes/" + std::to_string(top.node) + "/children/" + std::to_string(ci);
            checkNodeIndex(child, where);
            if (state_[size_t(child)] == NodeState::OnPath)
                throw InputError(path_, where + ": node graph has a cycle through node " + std::to_string(child));
            if (state_[size_t(child)] == NodeState::Done)
                throw InputError(path_, where + ": node " + std::to_string(child) + " has more than one parent");
            const glm::mat4 world = top.world * localMatrix(child);
            state_[size_t(child)] = NodeState::OnPath;
            stack.push_back({child, world, 0});
            emitPrimitives(child, world);
        }
    }

    void emitPrimitives(int node_index, const glm::mat4& world) {
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        if (node.mesh < 0) return;
        if (size_t(node.mesh) >= model_.meshes.size())
            throw InputError(path_, "/nodes/" + std::to_string(node_index) + "/mesh: mesh index " +
                                        std::to_string(node.mesh) + " out of range (" +
                                        std::to_string(model_.meshes.size()) + " meshes)");
        const tinygltf::Mesh& mesh = model_.meshes[size_t(node.mesh)];
        for (size_t p = 0; p < mesh.primitives.size(); ++p) {
            const int mode = mesh.primitives[p].mode;
            if (mode == TINYGLTF_MODE_POINTS) {
                ++scene_.skipped.points;
                continue;
            }
            if (mode == TINYGLTF_MODE_LINE || mode == TINYGLTF_MODE_LINE_LOOP || mode == TINYGLTF_MODE_LINE_STRIP) {
                ++scene_.skipped.lines;
                continue;
            }
            const uint32_t mesh_id = meshFor(node.mesh, int(p));
            if (scene_.meshes[mesh_id].indices.empty()) continue;
            Object o;
            o.mesh = mesh_id;
            o.world = world;
            o.color = scene_.meshes[mesh_id].color;
            scene_.objects.push_back(o);
        }
    }

    // One Mesh per glTF (mesh, primitive): instances of the same primitive share it.
    uint32_t meshFor(int mesh_index, int primitive_index) {
        const auto key = std::make_pair(mesh_index, primitive_index);
        if (auto it = mesh_ids_.find(key); it != mesh_ids_.end()) return it->second;
        const std::string where =
            "/meshes/" + std::to_string(mesh_index) + "/primitives/" + std::to_string(primitive_index);
        const tinygltf::Mesh& gm = model_.meshes[size_t(mesh_index)];
        const tinygltf::Primitive& prim = gm.primitives[size_t(primitive_index)];

        Mesh mesh;
        mesh.name = (gm.name.empty() ? "mesh" + std::to_string(mesh_index) : gm.name) + "/" +
                    std::to_string(primitive_index);
        const auto pos = prim.attributes.find("POSITION");
        if (pos == prim.attributes.end()) throw InputError(path_, where + ": primitive has no POSITION attribute");
        readPositions(pos->second, where + "/attributes/POSITION", mesh.positions);

        std::vector<uint32_t> raw;
        if (prim.indices >= 0) {
            readIndices(prim.indices, where + "/indices", raw);
        } else {
            raw.resize(mesh.positions.size());
            for (size_t i = 0; i < raw.size(); ++i) raw[i] = uint32_t(i);
        }
        for (size_t i = 0; i < raw.size(); ++i)
            if (raw[i] >= mesh.positions.size())
                throw InputError(path_, where + "/indices: index value " + std::to_string(raw[i]) + " at element " +
                                            std::to_string(i) + " out of range (" +
                                            std::to_string(mesh.positions.size()) + " vertices)");
        triangulate(prim.mode, raw, mesh.indices);

        if (prim.material >= 0) {
            if (size_t(prim.material) >= model_.materials.size())
                throw InputError(path_, where + "/material: material index " + std::to_string(prim.material) +
                                            " out of range");
            const std::vector<double>& f = model_.materials[size_t(prim.material)].pbrMetallicRoughness.baseColorFactor;
            if (f.size() == 4) mesh.color = glm::vec4(float(f[0]), float(f[1]), float(f[2]), float(f[3]));
        }
        const uint32_t id = uint32_t(scene_.meshes.size());
        scene_.meshes.push_back(std::move(mesh));
        mesh_ids_.emplace(key, id);
        return id;
    }

    void triangulate(int mode, const std::vector<uint32_t>& raw, std::vector<uint32_t>& out) {
        if (mode == TINYGLTF_MODE_TRIANGLES) {
            if (raw.size() % 3 != 0)
                throw InputError(path_, "triangle list has " + std::to_string(raw.size()) +
                                            " indices, not a multiple of 3");
            out = raw;
        } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
            for (size_t i = 2; i < raw.size(); ++i) {
                // Every other triangle of a strip is flipped back to keep one winding.
                const bool odd = (i % 2) == 1;
                out.insert(out.end(), {raw[i - 2 + odd], raw[i - 1 - odd], raw[i]});
            }
        } else if (mode == TINYGLTF_MODE_TRIANGLE_FAN) {
            for (size_t i = 2; i < raw.size(); ++i) out.insert(out.end(), {raw[0], raw[i - 1], raw[i]});
        } else {
            throw InputError(path_, "unsupported primitive mode " + std::to_string(mode));
        }
    }

    // Returns the bytes of an accessor's elements after checking that every element lies inside
    // its buffer view and buffer. stride is set to the distance between elements.
    const unsigned char* accessorData(int accessor_index, const std::string& where, size_t element_size,
                                      size_t& stride) const {
        const tinygltf::Accessor& acc = model_.accessors[size_t(accessor_index)];
        const std::string at = "/accessors/" + std::to_string(accessor_index);
        if (acc.sparse.isSparse) throw InputError(path_, at + ": unsupported sparse accessor (" + where + ")");
        if (acc.bufferView < 0 || size_t(acc.bufferView) >= model_.bufferViews.size())
            throw InputError(path_, at + ": accessor bufferView " + std::to_string(acc.bufferView) + " out of range (" +
                                        std::to_string(model_.bufferViews.size()) + " buffer views)");
        const tinygltf::BufferView& view = model_.bufferViews[size_t(acc.bufferView)];
        const std::string vat = "/bufferViews/" + std::to_string(acc.bufferView);
        if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
            throw InputError(path_, vat + ": buffer index " + std::to_string(view.buffer) + " out of range");
        const tinygltf::Buffer& buffer = model_.buffers[size_t(view.buffer)];
        if (uint64_t(view.byteOffset) + view.byteLength > buffer.data.size())
            throw InputError(path_, vat + ": buffer view [" + std::to_string(view.byteOffset) + ", +" +
                                        std::to_string(view.byteLength) + ") exceeds buffer " +
                                        std::to_string(view.buffer) + " of " + std::to_string(buffer.data.size()) +
                                        " bytes");
        stride = view.byteStride ? size_t(view.byteStride) : element_size;
        if (stride < element_size)
            throw InputError(path_, vat + ": byteStride " + std::to_string(stride) + " smaller than the element");
        if (acc.count > 0) {
            const uint64_t end = uint64_t(acc.byteOffset) + uint64_t(acc.count - 1) * stride + element_size;
            if (end > view.byteLength)
                throw InputError(path_, at + ": accessor needs " + std::to_string(end) + " bytes, buffer view " +
                                            std::to_string(acc.bufferView) + " has " +
                                            std::to_string(view.byteLength));
        }
        return buffer.data.data() + view.byteOffset + acc.byteOffset;
    }

    void checkAccessorIndex(int accessor_index, const std::string& where) const {
        if (accessor_index < 0 || size_t(accessor_index) >= model_.accessors.size())
            throw InputError(path_, where + ": accessor index " + std::to_string(accessor_index) + " out of range (" +
                                        std::to_string(model_.accessors.size()) + " accessors)");
    }

    void readPositions(int accessor_index, const std::string& where, std::vector<glm::vec3>& out) const {
        checkAccessorIndex(accessor_index, where);
        const tinygltf::Accessor& acc = model_.accessors[size_t(accessor_index)];
        if (acc.type != TINYGLTF_TYPE_VEC3 || acc.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT)
            throw InputError(path_, "/accessors/" + std::to_string(accessor_index) +
                                        ": unsupported POSITION accessor type (must be VEC3 of FLOAT)");
        size_t stride = 0;
        const unsigned char* data = accessorData(accessor_index, where, 12, stride);
        out.resize(acc.count);
        for (size_t i = 0; i < acc.count; ++i) {
            std::memcpy(&out[i], data + i * stride, 12);
            if (!std::isfinite(out[i].x) || !std::isfinite(out[i].y) || !std::isfinite(out[i].z))
                throw InputError(path_, "/accessors/" + std::to_string(accessor_index) + ": POSITION element " +
                                            std::to_string(i) + " is not finite (nan or inf)");
        }
    }

    void readIndices(int accessor_index, const std::string& where, std::vector<uint32_t>& out) const {
        checkAccessorIndex(accessor_index, where);
        const tinygltf::Accessor& acc = model_.accessors[size_t(accessor_index)];
        size_t size = 0;
        switch (acc.componentType) {
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: size = 1; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: size = 2; break;
        case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT: size = 4; break;
        default:
            throw InputError(path_, "/accessors/" + std::to_string(accessor_index) +
                                        ": unsupported index accessor component type " +
                                        std::to_string(acc.componentType));
        }
        if (acc.type != TINYGLTF_TYPE_SCALAR)
            throw InputError(path_, "/accessors/" + std::to_string(accessor_index) + ": index accessor is not SCALAR");
        size_t stride = 0;
        const unsigned char* data = accessorData(accessor_index, where, size, stride);
        out.resize(acc.count);
        for (size_t i = 0; i < acc.count; ++i) {
            const unsigned char* e = data + i * stride;
            if (size == 1) {
                out[i] = *e;
            } else if (size == 2) {
                uint16_t v;
                std::memcpy(&v, e, 2);
                out[i] = v;
            } else {
                std::memcpy(&out[i], e, 4);
            }
        }
    }

    const std::string& path_;
    const tinygltf::Model& model_;
    Scene scene_;
    std::vector<NodeState> state_;
    std::map<std::pair<int, int>, uint32_t> mesh_ids_;
};

}  // namespace

Scene importGltf(const std::string& path) {
    const std::vector<unsigned char> bytes = readWholeFile(path);
    if (bytes.empty()) throw InputError(path, "truncated: empty file (0 bytes)");
    if (bytes.size() > std::numeric_limits<uint32_t>::max()) throw InputError(path, "unsupported: larger than 4 GiB");

    tinygltf::TinyGLTF loader;
    loader.SetImageLoader(ignoreImage, nullptr);
    tinygltf::Model model;
    std::string err, warn;
    std::string base_dir = std::filesystem::path(path).parent_path().string();
    if (base_dir.empty()) base_dir = ".";
    const bool binary = bytes.size() >= 4 && readU32(bytes, 0) == kGlbMagic;
    bool ok = false;
    if (binary || std::filesystem::path(path).extension() == ".glb") validateGlbContainer(path, bytes);
    try {
        if (binary)
            ok = loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), unsigned(bytes.size()), base_dir);
        else
            ok = loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(bytes.data()),
                                            unsigned(bytes.size()), base_dir);
    } catch (const std::exception& e) {
        // tinygltf indexes some arrays with at(); a file that breaks its assumptions ends here.
        throw InputError(path, std::string("invalid glTF json or buffer: ") + e.what());
    }
    if (!ok) {
        std::string what = oneLine(err.empty() ? warn : err);
        // tinygltf names a failed external buffer "File not found"; say which kind of thing.
        if (what.find("File not found") != std::string::npos || what.find("Failed to load external") != std::string::npos)
            throw InputError(path, "missing buffer file: " + what);
        if (what.find("not found") != std::string::npos) throw InputError(path, "invalid glTF json, missing member: " + what);
        throw InputError(path, "invalid glTF json or buffer: " + what);
    }
    if (model.asset.version.rfind("2.", 0) != 0)
        throw InputError(path, "/asset/version: unsupported glTF version '" + model.asset.version + "' (expected 2.x)");
    return GltfFlattener(path, model).run();
}

}  // namespace occ
