// SPDX-License-Identifier: MIT
#include "import/import.h"

#include "import/gltf_common.h"

#include "scene/errors.h"

#include <tiny_gltf.h>

#include <draco/compression/decode.h>
#include <meshoptimizer.h>
#include <nlohmann/json.hpp>

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

using gltf::componentSize;
using gltf::componentValue;
using gltf::indexValue;
using gltf::isSupportedExtension;
using gltf::triangulatePrimitive;

using gltf::kGlbChunkBin;
using gltf::kGlbChunkJson;
using gltf::kGlbMagic;

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

class GltfFlattener {
public:
    GltfFlattener(const std::string& path, const tinygltf::Model& model, int scene)
        : path_(path), model_(model), scene_index_(scene) {}

    Scene run() {
        for (const std::string& ext : model_.extensionsRequired)
            if (!isSupportedExtension(ext))
                throw InputError(path_, "extensionsRequired: unsupported required extension " + ext);

        const std::vector<int64_t> roots = gltf::sceneRoots(
            path_, scene_index_, model_.defaultScene, model_.scenes.size(), model_.nodes.size(),
            [&](size_t scene) -> const std::vector<int>& { return model_.scenes[scene].nodes; },
            [&](const auto& f) {
                for (const tinygltf::Node& n : model_.nodes)
                    for (int c : n.children) f(int64_t(c));
            });
        gltf::walkNodeForest(
            path_, model_.nodes.size(), roots,
            [&](int64_t node) { return model_.nodes[size_t(node)].children.size(); },
            [&](int64_t node, size_t i) { return model_.nodes[size_t(node)].children[i]; },
            [&](int64_t node) { return localMatrix(int(node)); },
            [&](int64_t node, const glm::mat4& world) { emitPrimitives(int(node), world); });
        return std::move(scene_);
    }

private:
    glm::mat4 localMatrix(int node_index) const {
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        const auto given = [](const std::vector<double>& v, size_t n) { return v.size() == n ? v.data() : nullptr; };
        return gltf::nodeMatrix(path_, size_t(node_index), given(node.matrix, 16), given(node.translation, 3),
                                given(node.rotation, 4), given(node.scale, 3));
    }

    void emitPrimitives(int node_index, const glm::mat4& world) {
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        if (node.mesh < 0) return;
        if (size_t(node.mesh) >= model_.meshes.size())
            throw InputError(path_, "/nodes/" + std::to_string(node_index) + "/mesh: mesh index " +
                                        std::to_string(node.mesh) + " out of range (" +
                                        std::to_string(model_.meshes.size()) + " meshes)");
        const tinygltf::Mesh& mesh = model_.meshes[size_t(node.mesh)];
        const std::vector<glm::mat4> instances = nodeInstances(node_index);
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
            o.color = scene_.meshes[mesh_id].color;
            for (const glm::mat4& instance : instances) {
                o.world = world * instance;
                scene_.objects.push_back(o);
            }
        }
    }

    // EXT_mesh_gpu_instancing: the node's mesh drawn once per instance, each an object of its own
    // (transform: the node's, times the instance's translation, rotation and scale). One identity
    // instance for a node without the extension.
    std::vector<glm::mat4> nodeInstances(int node_index) const {
        const tinygltf::Node& node = model_.nodes[size_t(node_index)];
        const auto ext = node.extensions.find("EXT_mesh_gpu_instancing");
        if (ext == node.extensions.end()) return {glm::mat4(1.0f)};
        const std::string at = "/nodes/" + std::to_string(node_index) + "/extensions/EXT_mesh_gpu_instancing";
        const tinygltf::Value& attributes = ext->second.Get("attributes");
        if (!attributes.IsObject()) throw InputError(path_, at + ": no attributes");
        std::vector<float> t, r, sc;
        size_t count = SIZE_MAX;
        const auto read = [&](const char* name, int type, std::vector<float>& out) {
            if (!attributes.Has(name)) return;
            const tinygltf::Value& v = attributes.Get(name);
            if (!v.IsInt()) throw InputError(path_, at + "/attributes/" + name + ": not an accessor index");
            readFloats(v.Get<int>(), at + "/attributes/" + name, type, out);
            const size_t n = out.size() / (type == TINYGLTF_TYPE_VEC4 ? 4 : 3);
            if (count != SIZE_MAX && n != count)
                throw InputError(path_, at + "/attributes/" + name + ": " + std::to_string(n) +
                                            " instances, the other attributes have " + std::to_string(count));
            count = n;
        };
        read("TRANSLATION", TINYGLTF_TYPE_VEC3, t);
        read("ROTATION", TINYGLTF_TYPE_VEC4, r);
        read("SCALE", TINYGLTF_TYPE_VEC3, sc);
        if (count == SIZE_MAX) throw InputError(path_, at + ": no TRANSLATION, ROTATION or SCALE attribute");
        std::vector<glm::mat4> out(count);
        for (size_t i = 0; i < count; ++i) {
            glm::dvec3 tr(0.0), s(1.0);
            glm::dquat q(1.0, 0.0, 0.0, 0.0);
            if (!t.empty()) tr = glm::dvec3(t[3 * i], t[3 * i + 1], t[3 * i + 2]);
            if (!sc.empty()) s = glm::dvec3(sc[3 * i], sc[3 * i + 1], sc[3 * i + 2]);
            if (!r.empty()) q = glm::normalize(glm::dquat(r[4 * i + 3], r[4 * i], r[4 * i + 1], r[4 * i + 2]));
            out[i] = glm::mat4(glm::translate(glm::dmat4(1.0), tr) * glm::mat4_cast(q) * glm::scale(glm::dmat4(1.0), s));
            for (int c = 0; c < 4; ++c)
                for (int k = 0; k < 4; ++k)
                    if (!std::isfinite(out[i][c][k]))
                        throw InputError(path_, at + ": instance " + std::to_string(i) + " has a non-finite transform");
        }
        return out;
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
        std::vector<uint32_t> raw;
        const auto draco = prim.extensions.find("KHR_draco_mesh_compression");
        if (draco != prim.extensions.end()) {
            decodeDraco(draco->second, where + "/extensions/KHR_draco_mesh_compression", mesh.positions, raw);
        } else {
            readPositions(pos->second, where + "/attributes/POSITION", mesh.positions);
        }

        if (draco != prim.extensions.end()) {
            // The decoded faces are the indices.
        } else if (prim.indices >= 0) {
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
        triangulatePrimitive(path_, draco != prim.extensions.end() ? TINYGLTF_MODE_TRIANGLES : prim.mode, raw, mesh.indices);

        if (prim.material >= 0) {
            if (size_t(prim.material) >= model_.materials.size())
                throw InputError(path_, where + "/material: material index " + std::to_string(prim.material) +
                                            " out of range");
            const std::vector<double>& f = model_.materials[size_t(prim.material)].pbrMetallicRoughness.baseColorFactor;
            if (f.size() == 4) mesh.color = glm::vec4(float(f[0]), float(f[1]), float(f[2]), float(f[3]));
        }
        // COLOR_0 multiplies the base colour (glTF 2.0, 3.9.2); the .oss keeps one colour per
        // object, so the primitive takes its vertices' mean. Draco-decoded primitives keep the
        // material's colour.
        if (const auto colour = prim.attributes.find("COLOR_0");
            colour != prim.attributes.end() && draco == prim.extensions.end()) {
            checkAccessorIndex(colour->second, where + "/attributes/COLOR_0");
            const int type = model_.accessors[size_t(colour->second)].type == TINYGLTF_TYPE_VEC4 ? TINYGLTF_TYPE_VEC4
                                                                                                 : TINYGLTF_TYPE_VEC3;
            std::vector<float> c;
            readFloats(colour->second, where + "/attributes/COLOR_0", type, c);
            const size_t components = type == TINYGLTF_TYPE_VEC4 ? 4 : 3;
            if (c.size() / components != mesh.positions.size())
                throw InputError(path_, where + "/attributes/COLOR_0: " + std::to_string(c.size() / components) +
                                            " colours for " + std::to_string(mesh.positions.size()) + " vertices");
            if (!c.empty()) {
                glm::dvec3 sum(0.0);
                for (size_t i = 0; i < c.size(); i += components)
                    sum += glm::clamp(glm::dvec3(c[i], c[i + 1], c[i + 2]), 0.0, 1.0);
                mesh.color *= glm::vec4(glm::vec3(sum / double(c.size() / components)), 1.0f);
            }
        }
        const uint32_t id = uint32_t(scene_.meshes.size());
        scene_.meshes.push_back(std::move(mesh));
        mesh_ids_.emplace(key, id);
        return id;
    }

    // KHR_draco_mesh_compression: the primitive's positions and triangles from its compressed
    // buffer view, decoded by Google's Draco library.
    void decodeDraco(const tinygltf::Value& ext, const std::string& where, std::vector<glm::vec3>& positions,
                     std::vector<uint32_t>& indices) const {
        if (!ext.Has("bufferView") || !ext.Get("bufferView").IsInt())
            throw InputError(path_, where + ": no bufferView");
        const tinygltf::Value& attributes = ext.Get("attributes");
        if (!attributes.IsObject() || !attributes.Has("POSITION") || !attributes.Get("POSITION").IsInt())
            throw InputError(path_, where + ": no POSITION attribute id");
        const int view_index = ext.Get("bufferView").Get<int>();
        size_t stride = 0;
        const size_t length = view_index >= 0 && size_t(view_index) < model_.bufferViews.size()
                                  ? model_.bufferViews[size_t(view_index)].byteLength
                                  : 0;
        const unsigned char* bytes = viewBytes(view_index, 0, 1, length, true, where, stride);
        draco::DecoderBuffer buffer;
        buffer.Init(reinterpret_cast<const char*>(bytes), length);
        draco::Decoder decoder;
        auto decoded = decoder.DecodeMeshFromBuffer(&buffer);
        if (!decoded.ok())
            throw InputError(path_, where + ": Draco cannot decode it: " + decoded.status().error_msg_string());
        const std::unique_ptr<draco::Mesh> mesh = std::move(decoded).value();
        const int id = attributes.Get("POSITION").Get<int>();
        const draco::PointAttribute* attribute = id >= 0 ? mesh->GetAttributeByUniqueId(uint32_t(id)) : nullptr;
        if (!attribute || attribute->num_components() != 3)
            throw InputError(path_, where + ": no 3-component attribute with id " + std::to_string(id));
        positions.resize(mesh->num_points());
        for (draco::PointIndex i(0); i < mesh->num_points(); ++i) {
            float v[3];
            if (!attribute->ConvertValue<float, 3>(attribute->mapped_index(i), v))
                throw InputError(path_, where + ": POSITION of point " + std::to_string(i.value()) + " does not convert");
            positions[i.value()] = glm::vec3(v[0], v[1], v[2]);
            if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2]))
                throw InputError(path_, where + ": POSITION of point " + std::to_string(i.value()) + " is not finite");
        }
        indices.resize(size_t(mesh->num_faces()) * 3);
        for (draco::FaceIndex f(0); f < mesh->num_faces(); ++f)
            for (int k = 0; k < 3; ++k) indices[3 * size_t(f.value()) + size_t(k)] = mesh->face(f)[k].value();
    }

    // The bytes of `count` elements of `element_size` from byte `byte_offset` of buffer view
    // `view_index`, after checking that all lie inside the view and its buffer. stride: the
    // view's byteStride, or the element size when it has none (or `packed`, as sparse data is).
    const unsigned char* viewBytes(int view_index, size_t byte_offset, size_t count, size_t element_size, bool packed,
                                   const std::string& at, size_t& stride) const {
        if (view_index < 0 || size_t(view_index) >= model_.bufferViews.size())
            throw InputError(path_, at + ": bufferView " + std::to_string(view_index) + " out of range (" +
                                        std::to_string(model_.bufferViews.size()) + " buffer views)");
        const tinygltf::BufferView& view = model_.bufferViews[size_t(view_index)];
        const std::string vat = "/bufferViews/" + std::to_string(view_index);
        if (view.buffer < 0 || size_t(view.buffer) >= model_.buffers.size())
            throw InputError(path_, vat + ": buffer index " + std::to_string(view.buffer) + " out of range");
        const tinygltf::Buffer& buffer = model_.buffers[size_t(view.buffer)];
        if (uint64_t(view.byteOffset) + view.byteLength > buffer.data.size())
            throw InputError(path_, vat + ": buffer view [" + std::to_string(view.byteOffset) + ", +" +
                                        std::to_string(view.byteLength) + ") exceeds buffer " +
                                        std::to_string(view.buffer) + " of " + std::to_string(buffer.data.size()) +
                                        " bytes");
        stride = view.byteStride && !packed ? size_t(view.byteStride) : element_size;
        if (stride < element_size)
            throw InputError(path_, vat + ": byteStride " + std::to_string(stride) + " smaller than the element");
        if (count > 0) {
            const uint64_t end = uint64_t(byte_offset) + uint64_t(count - 1) * stride + element_size;
            if (end > view.byteLength)
                throw InputError(path_, at + ": needs " + std::to_string(end) + " bytes, buffer view " +
                                            std::to_string(view_index) + " has " + std::to_string(view.byteLength));
        }
        return buffer.data.data() + view.byteOffset + byte_offset;
    }

    // Returns the bytes of an accessor's elements after checking that every element lies inside
    // its buffer view and buffer. stride is set to the distance between elements.
    const unsigned char* accessorData(int accessor_index, const std::string& where, size_t element_size,
                                      size_t& stride) const {
        const tinygltf::Accessor& acc = model_.accessors[size_t(accessor_index)];
        const std::string at = "/accessors/" + std::to_string(accessor_index);
        if (acc.sparse.isSparse) throw InputError(path_, at + ": unsupported sparse accessor (" + where + ")");
        return viewBytes(acc.bufferView, acc.byteOffset, acc.count, element_size, false, at, stride);
    }

    // Every element of an accessor of `type` (VEC3, VEC4) as floats, count x components: float
    // or integer components (normalized or not, KHR_mesh_quantization), sparse substitutions
    // applied (on top of zeros when the accessor has no buffer view).
    void readFloats(int accessor_index, const std::string& where, int type, std::vector<float>& out) const {
        checkAccessorIndex(accessor_index, where);
        const tinygltf::Accessor& acc = model_.accessors[size_t(accessor_index)];
        const std::string at = "/accessors/" + std::to_string(accessor_index);
        const size_t components = type == TINYGLTF_TYPE_VEC4 ? 4 : type == TINYGLTF_TYPE_VEC3 ? 3 : 1;
        const size_t csize = componentSize(acc.componentType);
        if (acc.type != type || csize == 0 || acc.componentType == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT)
            throw InputError(path_, at + ": unsupported accessor type for " + where + " (must be VEC" +
                                        std::to_string(components) + " of floats or of 8- or 16-bit integers)");
        out.assign(acc.count * components, 0.0f);
        const size_t element = csize * components;
        if (acc.bufferView >= 0) {
            size_t stride = 0;
            const unsigned char* data = viewBytes(acc.bufferView, acc.byteOffset, acc.count, element, false, at, stride);
            for (size_t i = 0; i < acc.count; ++i)
                for (size_t k = 0; k < components; ++k)
                    out[i * components + k] = componentValue(data + i * stride + k * csize, acc.componentType, acc.normalized);
        } else if (!acc.sparse.isSparse) {
            throw InputError(path_, at + ": accessor has neither a bufferView nor sparse values (" + where + ")");
        }
        if (!acc.sparse.isSparse) return;
        const size_t count = size_t(std::max(acc.sparse.count, 0));
        if (acc.sparse.count < 1 || count > acc.count)
            throw InputError(path_, at + "/sparse: count " + std::to_string(acc.sparse.count) + " not in [1, " +
                                        std::to_string(acc.count) + "]");
        const int itype = acc.sparse.indices.componentType;
        const size_t isize = componentSize(itype);
        if (isize == 0 || itype == TINYGLTF_COMPONENT_TYPE_FLOAT || itype == TINYGLTF_COMPONENT_TYPE_BYTE ||
            itype == TINYGLTF_COMPONENT_TYPE_SHORT)
            throw InputError(path_, at + "/sparse/indices: unsupported component type " + std::to_string(itype));
        size_t istride = 0, vstride = 0;
        const unsigned char* indices = viewBytes(acc.sparse.indices.bufferView, size_t(std::max(acc.sparse.indices.byteOffset, 0)),
                                                 count, isize, true, at + "/sparse/indices", istride);
        const unsigned char* values = viewBytes(acc.sparse.values.bufferView, size_t(std::max(acc.sparse.values.byteOffset, 0)),
                                                count, element, true, at + "/sparse/values", vstride);
        for (size_t j = 0; j < count; ++j) {
            const size_t index = indexValue(indices + j * isize, itype);
            if (index >= acc.count)
                throw InputError(path_, at + "/sparse/indices: index " + std::to_string(index) + " at element " +
                                            std::to_string(j) + " out of range (" + std::to_string(acc.count) + " elements)");
            for (size_t k = 0; k < components; ++k)
                out[index * components + k] = componentValue(values + j * element + k * csize, acc.componentType, acc.normalized);
        }
    }

    void checkAccessorIndex(int accessor_index, const std::string& where) const {
        if (accessor_index < 0 || size_t(accessor_index) >= model_.accessors.size())
            throw InputError(path_, where + ": accessor index " + std::to_string(accessor_index) + " out of range (" +
                                        std::to_string(model_.accessors.size()) + " accessors)");
    }

    void readPositions(int accessor_index, const std::string& where, std::vector<glm::vec3>& out) const {
        std::vector<float> f;
        readFloats(accessor_index, where, TINYGLTF_TYPE_VEC3, f);
        out.resize(f.size() / 3);
        for (size_t i = 0; i < out.size(); ++i) {
            out[i] = glm::vec3(f[3 * i], f[3 * i + 1], f[3 * i + 2]);
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
        for (size_t i = 0; i < acc.count; ++i) out[i] = indexValue(data + i * stride, acc.componentType);
    }

    const std::string& path_;
    const tinygltf::Model& model_;
    int scene_index_;
    Scene scene_;
    std::map<std::pair<int, int>, uint32_t> mesh_ids_;
};

// ---- EXT_meshopt_compression (and KHR_meshopt_compression, the same bitstream) ------------
//
// gltfpack -cc keeps the compressed bytes in one buffer and points each compressed view at a
// "fallback" buffer that has a length but no data. tinygltf cannot load such a buffer (in a GLB
// it would read it from the BIN chunk, in a .gltf from a missing file), so the fallbacks are
// rewritten to one byte before loading and get their real size afterwards, when every
// compressed view is decoded into its place with meshoptimizer's own decoders.

const char* meshoptExtension(const tinygltf::ExtensionMap& extensions) {
    for (const char* name : {"EXT_meshopt_compression", "KHR_meshopt_compression"})
        if (extensions.count(name)) return name;
    return nullptr;
}

// What tinygltf cannot load as it is, rewritten in the JSON before it parses it: meshopt's
// fallback buffers stubbed to one byte (their lengths go to `lengths`), and the indices of
// Draco-compressed primitives dropped (tinygltf requires index accessors to have a buffer view;
// the Draco stream holds the faces). A required extension this importer does not read is refused
// here, by name, before tinygltf fails on what it cannot parse. Returns the file as it is when
// there is nothing to rewrite.
std::vector<unsigned char> prepareForTinygltf(const std::string& path, const std::vector<unsigned char>& bytes,
                                              bool binary, std::map<int, size_t>& lengths) {
    size_t json_begin = 0, json_length = bytes.size();
    if (binary) {
        json_begin = 20;
        json_length = readU32(bytes, 12);
    }
    const std::string text(bytes.begin() + long(json_begin), bytes.begin() + long(json_begin + json_length));
    const bool meshopt = text.find("meshopt_compression") != std::string::npos;
    const bool draco = text.find("KHR_draco_mesh_compression") != std::string::npos;
    if (!meshopt && !draco && text.find("extensionsRequired") == std::string::npos) return bytes;
    nlohmann::json json = nlohmann::json::parse(text, nullptr, false);
    if (json.is_discarded() || !json.is_object()) return bytes;  // tinygltf says what is wrong
    if (json.contains("extensionsRequired") && json["extensionsRequired"].is_array())
        for (const nlohmann::json& e : json["extensionsRequired"])
            if (e.is_string() && !isSupportedExtension(e.get<std::string>()))
                throw InputError(path, "extensionsRequired: unsupported required extension " + e.get<std::string>());
    bool changed = false;
    if (meshopt && json.contains("buffers") && json["buffers"].is_array()) {
        nlohmann::json& buffers = json["buffers"];
        for (size_t i = 0; i < buffers.size(); ++i) {
            nlohmann::json& b = buffers[i];
            if (!b.is_object() || !b.contains("extensions") || !b["extensions"].is_object()) continue;
            bool fallback = false;
            for (const char* name : {"EXT_meshopt_compression", "KHR_meshopt_compression"})
                if (b["extensions"].contains(name) && b["extensions"][name].is_object() &&
                    b["extensions"][name].value("fallback", false))
                    fallback = true;
            if (!fallback || b.contains("uri") || !b.contains("byteLength") || !b["byteLength"].is_number_unsigned())
                continue;
            lengths[int(i)] = b["byteLength"].get<size_t>();
            b["byteLength"] = 1;
            if (!binary) b["uri"] = "data:application/octet-stream;base64,AA==";
            changed = true;
        }
    }
    if (draco && json.contains("meshes") && json["meshes"].is_array())
        for (nlohmann::json& m : json["meshes"]) {
            if (!m.is_object() || !m.contains("primitives") || !m["primitives"].is_array()) continue;
            for (nlohmann::json& p : m["primitives"])
                if (p.is_object() && p.contains("extensions") && p["extensions"].is_object() &&
                    p["extensions"].contains("KHR_draco_mesh_compression") && p.contains("indices")) {
                    p.erase("indices");
                    changed = true;
                }
        }
    if (!changed) return bytes;
    std::string out_json = json.dump();
    if (!binary) return std::vector<unsigned char>(out_json.begin(), out_json.end());
    while (out_json.size() % 4) out_json += ' ';
    std::vector<unsigned char> out(20);
    const auto put = [&](size_t at, uint32_t v) { std::memcpy(out.data() + at, &v, 4); };
    out.insert(out.end(), out_json.begin(), out_json.end());
    out.insert(out.end(), bytes.begin() + long(json_begin + json_length), bytes.end());
    put(0, kGlbMagic);
    put(4, 2);
    put(8, uint32_t(out.size()));
    put(12, uint32_t(out_json.size()));
    put(16, kGlbChunkJson);
    return out;
}

// The version of a glTF 1.0 file ("1.0", the asset's version or the shape of its objects), or ""
// when the JSON does not look like glTF 1.0.
std::string gltfOneVersion(const std::vector<unsigned char>& bytes, bool binary) {
    size_t begin = 0, length = bytes.size();
    if (binary) {
        if (bytes.size() < 20) return "";
        begin = 20;
        length = std::min<size_t>(readU32(bytes, 12), bytes.size() - 20);
    }
    const nlohmann::json json = nlohmann::json::parse(bytes.begin() + long(begin), bytes.begin() + long(begin + length),
                                                      nullptr, false);
    if (json.is_discarded() || !json.is_object()) return "";
    if (json.contains("asset") && json["asset"].is_object() && json["asset"].contains("version")) {
        const nlohmann::json& v = json["asset"]["version"];
        if (v.is_number()) return v.dump() + ".0";
        if (v.is_string() && v.get<std::string>().rfind("1.", 0) == 0) return v.get<std::string>();
    }
    for (const char* key : {"accessors", "meshes", "nodes"})
        if (json.contains(key) && json[key].is_object()) return "1.0";
    return "";
}

void decodeMeshopt(const std::string& path, tinygltf::Model& model, const std::map<int, size_t>& lengths) {
    for (const auto& [buffer, length] : lengths)
        if (size_t(buffer) < model.buffers.size()) model.buffers[size_t(buffer)].data.assign(length, 0);
    for (size_t v = 0; v < model.bufferViews.size(); ++v) {
        tinygltf::BufferView& view = model.bufferViews[v];
        const char* name = meshoptExtension(view.extensions);
        if (!name) continue;
        const std::string at = "/bufferViews/" + std::to_string(v) + "/extensions/" + name;
        const tinygltf::Value& e = view.extensions.at(name);
        const auto number = [&](const char* key, bool required, int64_t otherwise) -> int64_t {
            if (!e.Has(key)) {
                if (required) throw InputError(path, at + ": no " + key);
                return otherwise;
            }
            const tinygltf::Value& x = e.Get(key);
            if (!x.IsNumber() || x.GetNumberAsDouble() < 0) throw InputError(path, at + "/" + key + ": not a count");
            return int64_t(x.GetNumberAsDouble());
        };
        const auto text = [&](const char* key, const char* otherwise) -> std::string {
            return e.Has(key) && e.Get(key).IsString() ? e.Get(key).Get<std::string>() : otherwise;
        };
        const int64_t source = number("buffer", true, 0), offset = number("byteOffset", false, 0);
        const int64_t length = number("byteLength", true, 0), stride = number("byteStride", true, 0);
        const int64_t count = number("count", true, 0);
        const std::string mode = text("mode", ""), filter = text("filter", "NONE");
        if (size_t(source) >= model.buffers.size())
            throw InputError(path, at + "/buffer: index " + std::to_string(source) + " out of range");
        const std::vector<unsigned char>& from = model.buffers[size_t(source)].data;
        if (uint64_t(offset) + uint64_t(length) > from.size())
            throw InputError(path, at + ": compressed bytes [" + std::to_string(offset) + ", +" + std::to_string(length) +
                                       ") exceed buffer " + std::to_string(source) + " of " + std::to_string(from.size()));
        if (view.buffer < 0 || size_t(view.buffer) >= model.buffers.size())
            throw InputError(path, "/bufferViews/" + std::to_string(v) + ": buffer index out of range");
        std::vector<unsigned char>& to = model.buffers[size_t(view.buffer)].data;
        const uint64_t size = uint64_t(count) * uint64_t(stride);
        if (size > view.byteLength || uint64_t(view.byteOffset) + size > to.size())
            throw InputError(path, at + ": " + std::to_string(count) + " x " + std::to_string(stride) +
                                       " decoded bytes do not fit the view's " + std::to_string(view.byteLength));
        unsigned char* dst = to.data() + view.byteOffset;
        const unsigned char* src = from.data() + offset;
        int rc = -1;
        if (mode == "ATTRIBUTES") {
            if (stride == 0 || stride % 4 != 0 || stride > 256)
                throw InputError(path, at + "/byteStride: " + std::to_string(stride) + " (a multiple of 4 up to 256)");
            rc = meshopt_decodeVertexBuffer(dst, size_t(count), size_t(stride), src, size_t(length));
        } else if (mode == "TRIANGLES" || mode == "INDICES") {
            if (stride != 2 && stride != 4) throw InputError(path, at + "/byteStride: " + std::to_string(stride) + " (2 or 4)");
            if (mode == "TRIANGLES" && count % 3 != 0)
                throw InputError(path, at + "/count: " + std::to_string(count) + " is not a multiple of 3");
            rc = mode == "TRIANGLES" ? meshopt_decodeIndexBuffer(dst, size_t(count), size_t(stride), src, size_t(length))
                                     : meshopt_decodeIndexSequence(dst, size_t(count), size_t(stride), src, size_t(length));
        } else {
            throw InputError(path, at + "/mode: unknown mode '" + mode + "'");
        }
        if (rc != 0) throw InputError(path, at + ": meshoptimizer cannot decode it (error " + std::to_string(rc) + ")");
        if (filter == "OCTAHEDRAL" && (stride == 4 || stride == 8))
            meshopt_decodeFilterOct(dst, size_t(count), size_t(stride));
        else if (filter == "QUATERNION" && stride == 8)
            meshopt_decodeFilterQuat(dst, size_t(count), size_t(stride));
        else if (filter == "EXPONENTIAL" && stride % 4 == 0)
            meshopt_decodeFilterExp(dst, size_t(count), size_t(stride));
        else if (filter != "NONE")
            throw InputError(path, at + "/filter: '" + filter + "' with byteStride " + std::to_string(stride));
    }
}

}  // namespace

Scene importGltf(const std::string& path, const ImportOptions& options) {
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
    std::map<int, size_t> fallbacks;
    const std::vector<unsigned char> loaded = prepareForTinygltf(path, bytes, binary, fallbacks);
    try {
        if (binary)
            ok = loader.LoadBinaryFromMemory(&model, &err, &warn, loaded.data(), unsigned(loaded.size()), base_dir);
        else
            ok = loader.LoadASCIIFromString(&model, &err, &warn, reinterpret_cast<const char*>(loaded.data()),
                                            unsigned(loaded.size()), base_dir);
    } catch (const std::exception& e) {
        // tinygltf indexes some arrays with at(); a file that breaks its assumptions ends here.
        throw InputError(path, std::string("invalid glTF json or buffer: ") + e.what());
    }
    if (!ok) {
        // glTF 1.0 (objects keyed by name, asset.version a number or "1.x") fails tinygltf's 2.0
        // schema with an unrelated message; name the version instead.
        const std::string version = gltfOneVersion(loaded, binary);
        if (!version.empty())
            throw InputError(path, "/asset/version: unsupported glTF version '" + version +
                                       "' (expected 2.x; convert glTF 1.0 files to 2.0 first)");
        std::string what = oneLine(err.empty() ? warn : err);
        // tinygltf names a failed external buffer "File not found"; say which kind of thing.
        if (what.find("File not found") != std::string::npos || what.find("Failed to load external") != std::string::npos)
            throw InputError(path, "missing buffer file: " + what);
        if (what.find("not found") != std::string::npos) throw InputError(path, "invalid glTF json, missing member: " + what);
        throw InputError(path, "invalid glTF json or buffer: " + what);
    }
    if (model.asset.version.rfind("2.", 0) != 0)
        throw InputError(path, "/asset/version: unsupported glTF version '" + model.asset.version + "' (expected 2.x)");
    decodeMeshopt(path, model, fallbacks);
    return GltfFlattener(path, model, options.scene).run();
}

}  // namespace occ
