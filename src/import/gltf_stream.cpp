// SPDX-License-Identifier: MIT
// The streaming glTF reader prep uses for files larger than memory: the JSON is parsed once as
// SAX events into compact tables (a few tens of bytes per node, mesh, accessor and view, no
// document tree, no copy of the buffers), the node forest is flattened into objects, and each
// mesh's bytes are read with pread when the mesh is asked for.
#include "import/gltf_common.h"
#include "import/scene_source.h"

#include "scene/errors.h"

#include <nlohmann/json.hpp>

#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <streambuf>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace occ {

namespace {

using gltf::kGlbChunkBin;
using gltf::kGlbChunkJson;
using gltf::kGlbMagic;

struct Accessor {
    int64_t view = -1;
    uint64_t offset = 0, count = 0;
    int32_t component = 0;
    uint8_t components = 0;  // 1 SCALAR, 2..4 VECn, 0 anything else
    bool normalized = false;
};
struct View {
    int64_t buffer = -1;
    uint64_t offset = 0, length = 0;
    uint32_t stride = 0;
};
struct Buffer {
    uint64_t length = 0;
    std::string uri;
    int fd = -1;
    uint64_t file_offset = 0, available = 0;  // where its bytes start in the file, and how many there are
};
struct Primitive {
    int64_t position = -1, indices = -1, material = -1, colour = -1;  // colour: COLOR_0
    int32_t mode = gltf::kTriangles;
};
struct MeshDef {
    uint32_t first = 0, count = 0;  // primitives
};
struct NodeDef {
    int64_t mesh = -1;
    uint32_t first_child = 0, child_count = 0;
    glm::mat4 local{1.0f};
};
struct NodeFields {  // the node being parsed
    std::array<double, 16> matrix{};
    std::array<double, 3> t{0, 0, 0}, s{1, 1, 1};
    std::array<double, 4> r{0, 0, 0, 1};
    bool has_matrix = false, has_trs = false;
};

// The parsed document: only what geometry needs.
struct Document {
    std::string version;
    int64_t scene = -1;
    std::vector<std::vector<int64_t>> scenes;
    std::vector<NodeDef> nodes;
    std::vector<int64_t> children;
    std::vector<MeshDef> meshes;
    std::vector<Primitive> primitives;
    std::vector<Accessor> accessors;
    std::vector<View> views;
    std::vector<Buffer> buffers;
    std::vector<glm::vec4> materials;
    std::vector<std::string> required;
    std::string unstreamable;  // the first feature this reader does not handle, if any
};

using json = nlohmann::json;

// SAX events into a Document. A frame per open object or array: for an object the key being
// read, for an array the index of the element being read.
class Handler : public nlohmann::json_sax<json> {
public:
    Handler(const std::string& path, Document& doc) : path_(path), doc_(doc) {}

    bool null() override { return scalar(Value{}); }
    bool boolean(bool v) override { return scalar(Value{Value::Bool, double(v), {}}); }
    bool number_integer(number_integer_t v) override { return scalar(Value{Value::Number, double(v), {}}); }
    bool number_unsigned(number_unsigned_t v) override { return scalar(Value{Value::Number, double(v), {}}); }
    bool number_float(number_float_t v, const string_t&) override { return scalar(Value{Value::Number, v, {}}); }
    bool string(string_t& v) override { return scalar(Value{Value::String, 0, v}); }
    bool binary(binary_t&) override { return scalar(Value{}); }
    bool start_object(std::size_t) override {
        opened();
        frames_.push_back({false, {}, 0});
        return true;
    }
    bool key(string_t& k) override {
        frames_.back().key = k;
        const size_t d = frames_.size();
        // Features this reader leaves to the whole-file importer.
        if (d == 4 && top() == "nodes" && keyAt(2) == "extensions" && k == "EXT_mesh_gpu_instancing")
            unstreamable("EXT_mesh_gpu_instancing");
        if (d == 3 && top() == "accessors" && k == "sparse") unstreamable("sparse accessors");
        if (d == 4 && top() == "bufferViews" && keyAt(2) == "extensions" &&
            (k == "EXT_meshopt_compression" || k == "KHR_meshopt_compression"))
            unstreamable("meshopt compression");
        if (d == 6 && top() == "meshes" && keyAt(4) == "extensions" && k == "KHR_draco_mesh_compression")
            unstreamable("Draco compression");
        return true;
    }
    bool end_object() override {
        if (frames_.size() == 3 && top() == "nodes" && inElement()) finishNode();
        frames_.pop_back();
        closed();
        return true;
    }
    bool start_array(std::size_t) override {
        opened();
        frames_.push_back({true, {}, 0});
        return true;
    }
    bool end_array() override {
        frames_.pop_back();
        closed();
        return true;
    }
    bool parse_error(std::size_t position, const std::string&, const nlohmann::detail::exception& e) override {
        throw InputError(path_, "invalid glTF json at byte " + std::to_string(position) + ": " + e.what());
    }

private:
    struct Frame {
        bool array;
        std::string key;
        uint64_t index;
    };
    struct Value {
        enum Kind { Null, Bool, Number, String } kind = Null;
        double number = 0;
        std::string text;
    };

    const std::string& top() const { return frames_[0].key; }
    const std::string& keyAt(size_t d) const { return frames_[d].key; }
    uint64_t indexAt(size_t d) const { return frames_[d].index; }
    void unstreamable(const char* what) {
        if (doc_.unstreamable.empty()) doc_.unstreamable = what;
    }
    // A value or container starts at the current position.
    void opened() {
        const size_t d = frames_.size();
        if (d == 2 && frames_[1].array) {
            const std::string& t = top();
            if (t == "nodes") {
                doc_.nodes.emplace_back();
                doc_.nodes.back().first_child = uint32_t(doc_.children.size());
                node_ = NodeFields{};
            } else if (t == "meshes") doc_.meshes.push_back({uint32_t(doc_.primitives.size()), 0});
            else if (t == "accessors") doc_.accessors.emplace_back();
            else if (t == "bufferViews") doc_.views.emplace_back();
            else if (t == "buffers") doc_.buffers.emplace_back();
            else if (t == "materials") doc_.materials.emplace_back(1.0f);
            else if (t == "scenes") doc_.scenes.emplace_back();
        }
        if (d == 4 && top() == "meshes" && inElement() && keyAt(2) == "primitives" && frames_[3].array) {
            doc_.primitives.emplace_back();
            ++doc_.meshes.back().count;
        }
    }
    // A value or container ended: the next element of an enclosing array follows.
    void closed() {
        if (!frames_.empty() && frames_.back().array) ++frames_.back().index;
    }

    bool scalar(const Value& v) {
        opened();
        handle(v);
        closed();
        return true;
    }

    int64_t integer(const Value& v, const char* what) const {
        if (v.kind != Value::Number || v.number != std::floor(v.number) || std::fabs(v.number) > 9e15)
            throw InputError(path_, where() + ": " + what + " is not an integer");
        return int64_t(v.number);
    }
    double number(const Value& v) const {
        if (v.kind != Value::Number) throw InputError(path_, where() + ": not a number");
        return v.number;
    }
    std::string where() const {
        std::string w;
        for (const Frame& f : frames_) w += "/" + (f.array ? std::to_string(f.index) : f.key);
        return w;
    }

    // Inside an object that is an element of a top-level array (whose entry opened() made).
    bool inElement() const { return frames_.size() >= 3 && frames_[1].array && !frames_[2].array; }

    void handle(const Value& v) {
        const size_t d = frames_.size();
        if (d == 0 || frames_[0].array) return;
        const std::string& t = top();
        if (d >= 3 && !inElement()) return;  // not the shape glTF gives these members: ignored
        if (t == "asset" && d == 2 && !frames_[1].array && keyAt(1) == "version") {
            doc_.version = v.kind == Value::String ? v.text : std::to_string(v.number);
        } else if (t == "scene" && d == 1) {
            doc_.scene = integer(v, "scene");
        } else if (t == "scenes" && d == 4 && keyAt(2) == "nodes" && frames_[3].array) {
            doc_.scenes.back().push_back(integer(v, "node index"));
        } else if (t == "extensionsRequired" && d == 2 && v.kind == Value::String) {
            doc_.required.push_back(v.text);
        } else if (t == "nodes" && d >= 3 && (d == 3 || frames_[3].array)) {
            node(v, d);
        } else if (t == "meshes" && d >= 5 && keyAt(2) == "primitives" && frames_[3].array && !frames_[4].array) {
            Primitive& p = doc_.primitives.back();
            if (d == 5 && keyAt(4) == "indices") p.indices = integer(v, "indices");
            else if (d == 5 && keyAt(4) == "material") p.material = integer(v, "material");
            else if (d == 5 && keyAt(4) == "mode") p.mode = int32_t(integer(v, "mode"));
            else if (d == 6 && keyAt(4) == "attributes" && keyAt(5) == "POSITION") p.position = integer(v, "POSITION");
            else if (d == 6 && keyAt(4) == "attributes" && keyAt(5) == "COLOR_0") p.colour = integer(v, "COLOR_0");
        } else if (t == "accessors" && d == 3) {
            Accessor& a = doc_.accessors.back();
            const std::string& k = keyAt(2);
            if (k == "bufferView") a.view = integer(v, k.c_str());
            else if (k == "byteOffset") a.offset = uint64_t(integer(v, k.c_str()));
            else if (k == "count") a.count = uint64_t(integer(v, k.c_str()));
            else if (k == "componentType") a.component = int32_t(integer(v, k.c_str()));
            else if (k == "normalized") a.normalized = v.kind == Value::Bool && v.number != 0;
            else if (k == "type")
                a.components = v.text == "SCALAR" ? 1 : v.text == "VEC2" ? 2 : v.text == "VEC3" ? 3 : v.text == "VEC4" ? 4 : 0;
        } else if (t == "bufferViews" && d == 3) {
            View& w = doc_.views.back();
            const std::string& k = keyAt(2);
            if (k == "buffer") w.buffer = integer(v, k.c_str());
            else if (k == "byteOffset") w.offset = uint64_t(integer(v, k.c_str()));
            else if (k == "byteLength") w.length = uint64_t(integer(v, k.c_str()));
            else if (k == "byteStride") w.stride = uint32_t(integer(v, k.c_str()));
        } else if (t == "buffers" && d == 3) {
            Buffer& b = doc_.buffers.back();
            if (keyAt(2) == "byteLength") b.length = uint64_t(integer(v, "byteLength"));
            else if (keyAt(2) == "uri" && v.kind == Value::String) b.uri = v.text;
        } else if (t == "materials" && d == 5 && keyAt(2) == "pbrMetallicRoughness" && !frames_[3].array &&
                   keyAt(3) == "baseColorFactor" && frames_[4].array) {
            if (indexAt(4) < 4) doc_.materials.back()[int(indexAt(4))] = float(number(v));
        }
    }

    void node(const Value& v, size_t d) {
        const std::string& k = keyAt(2);
        if (d == 3 && k == "mesh") {
            doc_.nodes.back().mesh = integer(v, "mesh");
        } else if (d == 4 && k == "children") {
            doc_.children.push_back(integer(v, "child"));
            ++doc_.nodes.back().child_count;
        } else if (d == 4 && k == "matrix" && indexAt(3) < 16) {
            node_.matrix[indexAt(3)] = number(v);
            node_.has_matrix = true;
        } else if (d == 4 && k == "translation" && indexAt(3) < 3) {
            node_.t[indexAt(3)] = number(v);
            node_.has_trs = true;
        } else if (d == 4 && k == "rotation" && indexAt(3) < 4) {
            node_.r[indexAt(3)] = number(v);
            node_.has_trs = true;
        } else if (d == 4 && k == "scale" && indexAt(3) < 3) {
            node_.s[indexAt(3)] = number(v);
            node_.has_trs = true;
        }
    }

    // The node's local matrix, as the whole-file importer composes it.
    void finishNode() {
        doc_.nodes.back().local =
            gltf::nodeMatrix(path_, doc_.nodes.size() - 1, node_.has_matrix ? node_.matrix.data() : nullptr,
                             node_.has_trs ? node_.t.data() : nullptr, node_.has_trs ? node_.r.data() : nullptr,
                             node_.has_trs ? node_.s.data() : nullptr);
    }

    const std::string& path_;
    Document& doc_;
    std::vector<Frame> frames_;
    NodeFields node_;
};

uint32_t u32At(const unsigned char* p) {
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

// The JSON's bytes for the parser: a range of the file read a MiB at a time with pread (no
// per-character locking as with a FILE*), counting what it has read for a progress line.
class RangeReader : public std::streambuf {
public:
    RangeReader(const std::string& path, int fd, uint64_t offset, uint64_t length, ReadProgress* progress)
        : path_(path), fd_(fd), next_(offset), end_(offset + length), progress_(progress), buffer_(1 << 20) {
        if (progress_) progress_->total = length;
    }

protected:
    int_type underflow() override {
        if (gptr() < egptr()) return traits_type::to_int_type(*gptr());
        if (next_ >= end_) return traits_type::eof();
        const size_t want = size_t(std::min<uint64_t>(buffer_.size(), end_ - next_));
        ssize_t n;
        do n = ::pread(fd_, buffer_.data(), want, off_t(next_));
        while (n < 0 && errno == EINTR);
        if (n < 0) throw InputError(path_, std::string("cannot read the JSON: ") + std::strerror(errno));
        if (n == 0) return traits_type::eof();
        next_ += uint64_t(n);
        if (progress_) progress_->done += uint64_t(n);
        setg(buffer_.data(), buffer_.data(), buffer_.data() + n);
        return traits_type::to_int_type(*gptr());
    }

private:
    const std::string& path_;
    int fd_;
    uint64_t next_, end_;
    ReadProgress* progress_;
    std::vector<char> buffer_;
};

class FileCloser {
public:
    explicit FileCloser(std::FILE* f) : f_(f) {}
    ~FileCloser() {
        if (f_) std::fclose(f_);
    }
    std::FILE* get() const { return f_; }

private:
    std::FILE* f_;
};

class GltfStreamSource final : public SceneSource {
public:
    // Made in two steps, openBuffers then flatten (which reads COLOR_0 accessors' bytes), so that
    // the source owns its file descriptors before anything can throw.
    GltfStreamSource(std::string path, Document doc) : path_(std::move(path)), doc_(std::move(doc)) {}
    ~GltfStreamSource() override {
        for (const int fd : fds_) ::close(fd);
    }

    const std::vector<Object>& objects() const override { return objects_; }
    uint32_t meshCount() const override { return uint32_t(mesh_keys_.size()); }
    uint64_t meshTriangles(uint32_t m) const override {
        const Primitive& p = doc_.primitives[mesh_keys_[m]];
        const uint64_t n = p.indices >= 0 ? doc_.accessors[size_t(p.indices)].count : doc_.accessors[size_t(p.position)].count;
        return p.mode == gltf::kTriangles ? n / 3 : n > 2 ? n - 2 : 0;
    }
    SkippedPrimitives skipped() const override { return skipped_; }
    const char* how() const override { return "streamed"; }

    Mesh mesh(uint32_t m) const override {
        const uint32_t pi = mesh_keys_[m];
        const Primitive& prim = doc_.primitives[pi];
        const std::string where = "/meshes/" + std::to_string(mesh_of_primitive_[pi]) + "/primitives/" +
                                  std::to_string(pi - doc_.meshes[mesh_of_primitive_[pi]].first);
        Mesh mesh;
        // Positions: VEC3 of floats, or of (normalized) 8/16-bit integers (KHR_mesh_quantization).
        {
            const Accessor& a = accessor(prim.position, where + "/attributes/POSITION");
            const size_t csize = gltf::componentSize(a.component);
            if (a.components != 3 || csize == 0 || a.component == gltf::kUnsignedInt)
                throw InputError(path_, "/accessors/" + std::to_string(prim.position) +
                                            ": unsupported accessor type for POSITION (must be VEC3 of floats or of "
                                            "8- or 16-bit integers)");
            size_t stride = 0;
            const std::vector<unsigned char> bytes = read(a, prim.position, 3 * csize, stride);
            mesh.positions.resize(a.count);
            for (size_t i = 0; i < a.count; ++i) {
                float c[3];
                for (size_t k = 0; k < 3; ++k)
                    c[k] = gltf::componentValue(bytes.data() + i * stride + k * csize, a.component, a.normalized);
                if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2]))
                    throw InputError(path_, "/accessors/" + std::to_string(prim.position) + ": POSITION element " +
                                                std::to_string(i) + " is not finite (nan or inf)");
                mesh.positions[i] = glm::vec3(c[0], c[1], c[2]);
            }
        }
        std::vector<uint32_t> raw;
        if (prim.indices >= 0) {
            const Accessor& a = accessor(prim.indices, where + "/indices");
            const std::string at = "/accessors/" + std::to_string(prim.indices);
            if (a.component != gltf::kUnsignedByte && a.component != gltf::kUnsignedShort &&
                a.component != gltf::kUnsignedInt)
                throw InputError(path_, at + ": unsupported index accessor component type " + std::to_string(a.component));
            if (a.components != 1) throw InputError(path_, at + ": index accessor is not SCALAR");
            size_t stride = 0;
            const std::vector<unsigned char> bytes = read(a, prim.indices, gltf::componentSize(a.component), stride);
            raw.resize(a.count);
            for (size_t i = 0; i < a.count; ++i) raw[i] = gltf::indexValue(bytes.data() + i * stride, a.component);
        } else {
            raw.resize(mesh.positions.size());
            for (size_t i = 0; i < raw.size(); ++i) raw[i] = uint32_t(i);
        }
        for (size_t i = 0; i < raw.size(); ++i)
            if (raw[i] >= mesh.positions.size())
                throw InputError(path_, where + "/indices: index value " + std::to_string(raw[i]) + " at element " +
                                            std::to_string(i) + " out of range (" +
                                            std::to_string(mesh.positions.size()) + " vertices)");
        gltf::triangulatePrimitive(path_, prim.mode, raw, mesh.indices);
        mesh.color = colour(prim, where);
        return mesh;
    }

    // Opens the buffers: the GLB's BIN chunk, or files named by uri beside the .gltf.
    void openBuffers(int glb_fd, uint64_t bin_offset, uint64_t bin_length) {
        if (glb_fd >= 0) fds_.push_back(glb_fd);
        const std::filesystem::path dir = std::filesystem::path(path_).parent_path();
        for (size_t i = 0; i < doc_.buffers.size(); ++i) {
            Buffer& b = doc_.buffers[i];
            const std::string at = "/buffers/" + std::to_string(i);
            if (b.uri.empty()) {
                if (glb_fd < 0 || i != 0) throw InputError(path_, at + ": buffer has no uri and is not the GLB's BIN chunk");
                b.fd = glb_fd;
                b.file_offset = bin_offset;
                b.available = bin_length;
            } else {
                const std::string file = (dir / decodeUri(b.uri)).string();
                b.fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
                if (b.fd < 0) throw InputError(path_, "missing buffer file: " + at + ": " + file + ": " + std::strerror(errno));
                fds_.push_back(b.fd);
                struct stat st{};
                ::fstat(b.fd, &st);
                b.available = uint64_t(st.st_size);
            }
            if (b.length > b.available)
                throw InputError(path_, at + ": byteLength " + std::to_string(b.length) + " but only " +
                                            std::to_string(b.available) + " bytes are there (truncated?)");
        }
    }

    // The node forest walked as the whole-file importer walks it (gltf::walkNodeForest):
    // one object per (node, triangle primitive), meshes numbered as first met.
    void flatten(int scene_option) {
        for (const std::string& ext : doc_.required)
            if (!gltf::isSupportedExtension(ext))
                throw InputError(path_, "extensionsRequired: unsupported required extension " + ext);
        mesh_of_primitive_.resize(doc_.primitives.size());
        for (uint32_t m = 0; m < doc_.meshes.size(); ++m)
            for (uint32_t p = 0; p < doc_.meshes[m].count; ++p) mesh_of_primitive_[doc_.meshes[m].first + p] = m;

        const std::vector<int64_t> roots = gltf::sceneRoots(
            path_, scene_option, doc_.scene, doc_.scenes.size(), doc_.nodes.size(),
            [&](size_t scene) -> const std::vector<int64_t>& { return doc_.scenes[scene]; },
            [&](const auto& f) {
                for (int64_t c : doc_.children) f(c);
            });
        std::vector<uint32_t> id_of_primitive(doc_.primitives.size(), UINT32_MAX);
        gltf::walkNodeForest(
            path_, doc_.nodes.size(), roots, [&](int64_t node) { return doc_.nodes[size_t(node)].child_count; },
            [&](int64_t node, size_t i) { return doc_.children[doc_.nodes[size_t(node)].first_child + i]; },
            [&](int64_t node) -> const glm::mat4& { return doc_.nodes[size_t(node)].local; },
            [&](int64_t node, const glm::mat4& world) { emit(node, world, id_of_primitive); });
        // The tree is not needed any more; the tables meshes are read through are.
        doc_.nodes = {};
        doc_.children = {};
        doc_.scenes = {};
    }

    void emit(int64_t node_index, const glm::mat4& world, std::vector<uint32_t>& id_of_primitive) {
        const NodeDef& node = doc_.nodes[size_t(node_index)];
        if (node.mesh < 0) return;
        if (uint64_t(node.mesh) >= doc_.meshes.size())
            throw InputError(path_, "/nodes/" + std::to_string(node_index) + "/mesh: mesh index " +
                                        std::to_string(node.mesh) + " out of range (" +
                                        std::to_string(doc_.meshes.size()) + " meshes)");
        const MeshDef& m = doc_.meshes[size_t(node.mesh)];
        for (uint32_t p = m.first; p < m.first + m.count; ++p) {
            const Primitive& prim = doc_.primitives[p];
            if (prim.mode == gltf::kPoints) {
                ++skipped_.points;
                continue;
            }
            if (prim.mode == gltf::kLines || prim.mode == gltf::kLineLoop || prim.mode == gltf::kLineStrip) {
                ++skipped_.lines;
                continue;
            }
            const std::string where = "/meshes/" + std::to_string(node.mesh) + "/primitives/" + std::to_string(p - m.first);
            if (prim.position < 0) throw InputError(path_, where + ": primitive has no POSITION attribute");
            accessor(prim.position, where + "/attributes/POSITION");
            if (prim.indices >= 0) accessor(prim.indices, where + "/indices");
            if (id_of_primitive[p] == UINT32_MAX) {
                id_of_primitive[p] = uint32_t(mesh_keys_.size());
                mesh_keys_.push_back(p);
            }
            objects_.push_back(Object{id_of_primitive[p], world, colour(prim, where, true)});
        }
    }

private:
    static std::string decodeUri(const std::string& uri) {
        std::string out;
        for (size_t i = 0; i < uri.size(); ++i) {
            if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(uint8_t(uri[i + 1])) && std::isxdigit(uint8_t(uri[i + 2]))) {
                out.push_back(char(std::stoi(uri.substr(i + 1, 2), nullptr, 16)));
                i += 2;
            } else {
                out.push_back(uri[i]);
            }
        }
        return out;
    }

    const Accessor& accessor(int64_t index, const std::string& where) const {
        if (index < 0 || uint64_t(index) >= doc_.accessors.size())
            throw InputError(path_, where + ": accessor index " + std::to_string(index) + " out of range (" +
                                        std::to_string(doc_.accessors.size()) + " accessors)");
        return doc_.accessors[size_t(index)];
    }

    // The bytes of an accessor's elements, read from its buffer after checking they lie inside
    // its view and buffer.
    std::vector<unsigned char> read(const Accessor& a, int64_t index, size_t element, size_t& stride) const {
        const std::string at = "/accessors/" + std::to_string(index);
        if (a.view < 0 || uint64_t(a.view) >= doc_.views.size())
            throw InputError(path_, at + ": bufferView " + std::to_string(a.view) + " out of range (" +
                                        std::to_string(doc_.views.size()) + " buffer views)");
        const View& v = doc_.views[size_t(a.view)];
        const std::string vat = "/bufferViews/" + std::to_string(a.view);
        if (v.buffer < 0 || uint64_t(v.buffer) >= doc_.buffers.size())
            throw InputError(path_, vat + ": buffer index " + std::to_string(v.buffer) + " out of range");
        const Buffer& b = doc_.buffers[size_t(v.buffer)];
        if (v.offset + v.length > b.length || v.offset + v.length < v.offset)
            throw InputError(path_, vat + ": buffer view [" + std::to_string(v.offset) + ", +" + std::to_string(v.length) +
                                        ") exceeds buffer " + std::to_string(v.buffer) + " of " +
                                        std::to_string(b.length) + " bytes");
        stride = v.stride ? v.stride : element;
        if (stride < element)
            throw InputError(path_, vat + ": byteStride " + std::to_string(stride) + " smaller than the element");
        if (a.count == 0) return {};
        const uint64_t end = a.offset + (a.count - 1) * stride + element;
        if (a.count > (1ull << 40) || end > v.length)
            throw InputError(path_, at + ": needs " + std::to_string(end) + " bytes, buffer view " +
                                        std::to_string(a.view) + " has " + std::to_string(v.length));
        std::vector<unsigned char> bytes(end - a.offset);
        const uint64_t from = b.file_offset + v.offset + a.offset;
        for (size_t done = 0; done < bytes.size();) {
            const ssize_t n = ::pread(b.fd, bytes.data() + done, bytes.size() - done, off_t(from + done));
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) throw InputError(path_, at + ": cannot read its bytes: " + (n < 0 ? std::strerror(errno) : "end of file"));
            done += size_t(n);
        }
        return bytes;
    }

    // The material's base colour times the mean of COLOR_0 where the primitive has vertex colours
    // (glTF 2.0, 3.9.2: they multiply; the .oss keeps one colour per object). flatten (one
    // thread) remembers each accessor's mean, as every instance asks again; mesh(), which may
    // run on several threads, only reads what it remembered.
    glm::vec4 colour(const Primitive& p, const std::string& where, bool remember = false) const {
        glm::vec4 c = Mesh{}.color;
        if (p.material >= 0) {
            if (uint64_t(p.material) >= doc_.materials.size())
                throw InputError(path_, where + "/material: material index " + std::to_string(p.material) + " out of range");
            c = doc_.materials[size_t(p.material)];
        }
        if (p.colour < 0) return c;
        const auto cached = vertex_colour_mean_.find(p.colour);
        if (cached != vertex_colour_mean_.end()) return c * cached->second;
        const Accessor& a = accessor(p.colour, where + "/attributes/COLOR_0");
        const size_t csize = gltf::componentSize(a.component);
        if ((a.components != 3 && a.components != 4) || csize == 0 || a.component == gltf::kUnsignedInt)
            throw InputError(path_, "/accessors/" + std::to_string(p.colour) +
                                        ": unsupported accessor type for COLOR_0 (must be VEC3 or VEC4 of floats or of "
                                        "normalized 8- or 16-bit integers)");
        size_t stride = 0;
        const std::vector<unsigned char> bytes = read(a, p.colour, a.components * csize, stride);
        glm::dvec3 sum(0.0);
        for (size_t i = 0; i < a.count; ++i)
            for (int k = 0; k < 3; ++k) {
                const float v = gltf::componentValue(bytes.data() + i * stride + size_t(k) * csize, a.component, a.normalized);
                sum[k] += std::isfinite(v) ? std::clamp(double(v), 0.0, 1.0) : 0.0;
            }
        const glm::vec4 mean = a.count ? glm::vec4(glm::vec3(sum / double(a.count)), 1.0f) : glm::vec4(1.0f);
        if (remember) vertex_colour_mean_.emplace(p.colour, mean);
        return c * mean;
    }

    std::string path_;
    Document doc_;
    std::vector<int> fds_;
    mutable std::map<int64_t, glm::vec4> vertex_colour_mean_;  // per COLOR_0 accessor: its mean colour
    std::vector<Object> objects_;
    std::vector<uint32_t> mesh_keys_;          // mesh id -> primitive
    std::vector<uint32_t> mesh_of_primitive_;  // primitive -> glTF mesh
    SkippedPrimitives skipped_;
};

}  // namespace

std::unique_ptr<SceneSource> streamGltf(const std::string& path, const ImportOptions& options, std::string* why,
                                        ReadProgress* progress) {
    std::FILE* raw = std::fopen(path.c_str(), "rb");
    if (!raw) throw InputError(path, std::string("cannot open: ") + std::strerror(errno));
    FileCloser file(raw);
    struct stat st{};
    ::fstat(::fileno(raw), &st);
    const uint64_t size = uint64_t(st.st_size);
    if (size == 0) throw InputError(path, "truncated: empty file (0 bytes)");

    unsigned char head[20] = {};
    const size_t got = std::fread(head, 1, sizeof head, raw);
    const bool binary = got >= 4 && u32At(head) == kGlbMagic;
    uint64_t json_offset = 0, json_length = size, bin_offset = 0, bin_length = 0;
    if (binary) {
        // The container as the whole-file importer checks it.
        if (got < 20) throw InputError(path, "truncated: a GLB header and its first chunk header need 20 bytes");
        if (u32At(head + 4) != 2) throw InputError(path, "offset 4: unsupported GLB version " + std::to_string(u32At(head + 4)) + " (expected 2)");
        if (u32At(head + 8) != size)
            throw InputError(path, "offset 8: header says " + std::to_string(u32At(head + 8)) + " bytes, file has " +
                                       std::to_string(size));
        if (u32At(head + 16) != kGlbChunkJson) throw InputError(path, "offset 16: first chunk is not JSON");
        json_offset = 20;
        json_length = u32At(head + 12);
        if (json_offset + json_length > size) throw InputError(path, "offset 12: truncated: JSON chunk runs past the end of the file");
        const uint64_t next = json_offset + json_length;
        if (next + 8 <= size) {
            unsigned char chunk[8];
            if (::pread(::fileno(raw), chunk, 8, off_t(next)) != 8) throw InputError(path, "cannot read the BIN chunk header");
            if (u32At(chunk + 4) != kGlbChunkBin) throw InputError(path, "offset " + std::to_string(next + 4) + ": second chunk is not BIN");
            bin_offset = next + 8;
            bin_length = u32At(chunk);
            if (bin_offset + bin_length > size)
                throw InputError(path, "offset " + std::to_string(next) + ": truncated: chunk of " +
                                           std::to_string(bin_length) + " bytes runs past the end of the file");
        }
    }

    Document doc;
    Handler handler(path, doc);
    RangeReader reader(path, ::fileno(raw), json_offset, json_length, progress);
    // Not strict: parsing stops after the one JSON value, before the GLB's padding.
    try {
        json::sax_parse(std::istreambuf_iterator<char>(&reader), std::istreambuf_iterator<char>(), &handler,
                        json::input_format_t::json, false);
    } catch (const nlohmann::json::exception& e) {
        throw InputError(path, std::string("invalid glTF json: ") + e.what());
    }
    if (doc.version.rfind("2.", 0) != 0)
        throw InputError(path, "/asset/version: unsupported glTF version '" + doc.version + "' (expected 2.x)");
    for (const Buffer& b : doc.buffers)
        if (b.uri.rfind("data:", 0) == 0 && doc.unstreamable.empty()) doc.unstreamable = "data: URIs";
    for (const std::string& e : doc.required)
        if (e == "EXT_mesh_gpu_instancing" || e == "EXT_meshopt_compression" || e == "KHR_meshopt_compression" ||
            e == "KHR_draco_mesh_compression")
            if (doc.unstreamable.empty()) doc.unstreamable = e;
    if (!doc.unstreamable.empty()) {
        if (why) *why = doc.unstreamable;
        return nullptr;
    }
    auto source = std::make_unique<GltfStreamSource>(path, std::move(doc));
    const int fd = binary ? ::dup(::fileno(raw)) : -1;
    source->openBuffers(fd, bin_offset, bin_length);
    source->flatten(options.scene);
    return source;
}

}  // namespace occ
