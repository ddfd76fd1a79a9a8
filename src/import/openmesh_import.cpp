// SPDX-License-Identifier: MIT
#include "import/import.h"

#include "scene/errors.h"

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>

namespace occ {

namespace {

using OpenMesh::EdgeHandle;
using OpenMesh::FaceHandle;
using OpenMesh::HalfedgeHandle;
using OpenMesh::Vec2f;
using OpenMesh::Vec3d;
using OpenMesh::Vec3f;
using OpenMesh::Vec3uc;
using OpenMesh::Vec4f;
using OpenMesh::Vec4uc;
using OpenMesh::VertexHandle;

// Receives what OpenMesh's readers parse into flat arrays, without building half-edge
// connectivity: CAD files are often non-manifold, and the reader's own mesh would split or
// drop such faces. Connectivity is built later, by preprocessing, where it is needed.
class FlatImporter : public OpenMesh::IO::BaseImporter {
public:
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> face_offsets{0};  // polygon f spans corners[face_offsets[f], face_offsets[f+1])
    std::vector<uint32_t> corners;
    std::string first_error;

    VertexHandle add_vertex(const Vec3f& p) override {
        positions.emplace_back(p[0], p[1], p[2]);
        return VertexHandle(int(positions.size() - 1));
    }
    VertexHandle add_vertex(const Vec3d& p) override { return add_vertex(Vec3f(float(p[0]), float(p[1]), float(p[2]))); }
    VertexHandle add_vertex() override { return add_vertex(Vec3f(0.0f, 0.0f, 0.0f)); }
    FaceHandle add_face(const VHandles& vs) override {
        for (const VertexHandle& v : vs) {
            if (!v.is_valid() || size_t(v.idx()) >= positions.size()) {
                if (first_error.empty())
                    first_error = "face " + std::to_string(face_offsets.size() - 1) + ": vertex index " +
                                  std::to_string(v.idx()) + " out of range (" + std::to_string(positions.size()) +
                                  " vertices)";
                return FaceHandle();
            }
            corners.push_back(uint32_t(v.idx()));
        }
        face_offsets.push_back(uint32_t(corners.size()));
        return FaceHandle(int(face_offsets.size() - 2));
    }
    size_t n_vertices() const override { return positions.size(); }
    size_t n_faces() const override { return face_offsets.size() - 1; }
    size_t n_edges() const override { return 0; }

    // Everything below carries attributes (normals, colours, texture coordinates, status) that a
    // geometry-only import does not keep.
    HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
    FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec2f>&) override {}
    void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<Vec3f>&) override {}
    void set_face_texindex(FaceHandle, int) override {}
    void set_point(VertexHandle v, const Vec3f& p) override {
        if (v.is_valid() && size_t(v.idx()) < positions.size()) positions[size_t(v.idx())] = glm::vec3(p[0], p[1], p[2]);
    }
    void set_halfedge(VertexHandle, HalfedgeHandle) override {}
    void set_normal(VertexHandle, const Vec3f&) override {}
    void set_normal(VertexHandle, const Vec3d&) override {}
    void set_color(VertexHandle, const Vec3uc&) override {}
    void set_color(VertexHandle, const Vec4uc&) override {}
    void set_color(VertexHandle, const Vec3f&) override {}
    void set_color(VertexHandle, const Vec4f&) override {}
    void set_texcoord(VertexHandle, const Vec2f&) override {}
    void set_status(VertexHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_next(HalfedgeHandle, HalfedgeHandle) override {}
    void set_face(HalfedgeHandle, FaceHandle) override {}
    void request_face_texcoords2D() override {}
    void set_texcoord(HalfedgeHandle, const Vec2f&) override {}
    void set_texcoord(VertexHandle, const Vec3f&) override {}
    void set_texcoord(HalfedgeHandle, const Vec3f&) override {}
    void set_status(HalfedgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_color(EdgeHandle, const Vec3uc&) override {}
    void set_color(EdgeHandle, const Vec4uc&) override {}
    void set_color(EdgeHandle, const Vec3f&) override {}
    void set_color(EdgeHandle, const Vec4f&) override {}
    void set_status(EdgeHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void set_normal(FaceHandle, const Vec3f&) override {}
    void set_normal(FaceHandle, const Vec3d&) override {}
    void set_color(FaceHandle, const Vec3uc&) override {}
    void set_color(FaceHandle, const Vec4uc&) override {}
    void set_color(FaceHandle, const Vec3f&) override {}
    void set_color(FaceHandle, const Vec4f&) override {}
    void set_status(FaceHandle, const OpenMesh::Attributes::StatusInfo&) override {}
    void add_texture_information(int, std::string) override {}
};

// OpenMesh reports problems on its global omerr/omlog streams. They are redirected, once per
// process, into a buffer, so that the first complaint can go into our one-line error and
// nothing else reaches the terminal. (OpenMesh never frees a target it disconnects, hence once;
// the streams are global, hence the lock.)
class CapturedOpenMeshLog {
public:
    CapturedOpenMeshLog() : lock_(mutex()) {
        static const bool redirected = [] {
            omerr().disconnect(std::cerr);
            omlog().disconnect(std::cerr);
            omlog().disconnect(std::clog);
            omerr().connect(buffer());
            return true;
        }();
        (void)redirected;
        buffer().str("");
    }
    std::string firstLine() {
        omerr().flush();
        std::string line;
        std::istringstream in(buffer().str());
        while (std::getline(in, line))
            if (!line.empty()) return line;
        return "";
    }

private:
    static std::mutex& mutex() {
        static std::mutex m;
        return m;
    }
    static std::ostringstream& buffer() {
        static std::ostringstream b;
        return b;
    }
    std::lock_guard<std::mutex> lock_;
};

// OpenMesh's OBJ reader has no notion of groups, but it reports faces in file order, so the
// group of every "f" line is read from the text beforehand. Returns one group id per face
// (empty when the file has at most one group with faces).
std::vector<uint32_t> objFaceGroups(const std::string& path, std::vector<std::string>& names) {
    std::ifstream in(path);
    std::vector<uint32_t> groups;
    std::string line;
    uint32_t current = 0;
    names.assign(1, "default");
    std::vector<bool> has_faces(1, false);
    while (std::getline(in, line)) {
        size_t i = line.find_first_not_of(" \t");
        if (i == std::string::npos || i + 1 >= line.size()) continue;
        const char c = line[i];
        const char next = line[i + 1];
        if ((c == 'g' || c == 'o') && (next == ' ' || next == '\t')) {
            std::string name = line.substr(i + 2);
            while (!name.empty() && (name.back() == '\r' || name.back() == ' ')) name.pop_back();
            const auto it = std::find(names.begin(), names.end(), name);
            current = uint32_t(it - names.begin());
            if (it == names.end()) {
                names.push_back(name);
                has_faces.push_back(false);
            }
        } else if (c == 'f' && (next == ' ' || next == '\t')) {
            groups.push_back(current);
            has_faces[current] = true;
        }
    }
    if (std::count(has_faces.begin(), has_faces.end(), true) <= 1) groups.clear();
    return groups;
}

// An ASCII OFF file must hold at least as many data lines as its header promises vertices and
// faces; OpenMesh's reader otherwise reads past the end as zeros and reports success.
void validateOff(const std::string& path, const std::string& text) {
    std::istringstream in(text);
    std::string line, magic;
    size_t line_no = 0;
    const auto nextDataLine = [&]() {
        while (std::getline(in, line)) {
            ++line_no;
            const size_t i = line.find_first_not_of(" \t\r");
            if (i != std::string::npos && line[i] != '#') return true;
        }
        return false;
    };
    if (!nextDataLine()) throw InputError(path, "empty file, an OFF file starts with 'OFF'");
    std::istringstream header(line);
    header >> magic;
    if (magic.size() < 3 || magic.compare(magic.size() - 3, 3, "OFF") != 0)
        throw InputError(path, "line " + std::to_string(line_no) + ": bad magic '" + magic +
                                   "', an OFF file starts with 'OFF' (or COFF, NOFF, STOFF, ...)");
    // The counts follow the magic word on the same line or on the next data line.
    std::string rest((std::istreambuf_iterator<char>(header)), std::istreambuf_iterator<char>());
    if (rest.find("BINARY") != std::string::npos) return;  // binary OFF sizes are the reader's to check
    if (rest.find_first_not_of(" \t\r") == std::string::npos) rest = nextDataLine() ? line : "";
    long long counts[2] = {-1, -1};
    std::istringstream(rest) >> counts[0] >> counts[1];
    if (counts[0] < 0 || counts[1] < 0)
        throw InputError(path, "line " + std::to_string(line_no) + ": missing vertex and face counts after 'OFF'");
    long long data_lines = 0;
    while (nextDataLine()) ++data_lines;
    if (data_lines < counts[0] + counts[1])
        throw InputError(path, "truncated: header says " + std::to_string(counts[0]) + " vertices and " +
                                   std::to_string(counts[1]) + " faces, the file has " + std::to_string(data_lines) +
                                   " data lines");
}

// OpenMesh's OBJ reader silently drops a vertex it cannot parse ("v nan 0 0"), which shifts
// every later index; non-finite vertices are found here, with their line.
void validateObjVertices(const std::string& path, const std::string& text) {
    size_t line_no = 0, start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        ++line_no;
        if (end - start > 2 && text[start] == 'v' && (text[start + 1] == ' ' || text[start + 1] == '\t')) {
            const char* p = text.c_str() + start + 2;
            for (int k = 0; k < 3; ++k) {
                char* after = nullptr;
                const float v = std::strtof(p, &after);
                if (after == p) break;
                if (!std::isfinite(v))
                    throw InputError(path, "line " + std::to_string(line_no) + ": vertex is not finite (nan or inf)");
                p = after;
            }
        }
        start = end + 1;
    }
}

// OpenMesh's readers trust lengths and accept non-finite numbers in places, so the parts of
// the formats that can be checked cheaply are checked here first: magic words, and for binary
// STL the exact size and every coordinate (the format is a flat array of 50-byte records).
void validateContainer(const std::string& path, const std::string& ext) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot open: " + std::string(std::strerror(errno)));
    std::vector<char> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string head(bytes.begin(), bytes.begin() + long(std::min<size_t>(bytes.size(), 256)));
    if (ext == ".ply" && head.rfind("ply", 0) != 0) throw InputError(path, "offset 0: bad magic, a PLY file starts with 'ply'");
    if (ext == ".off") validateOff(path, std::string(bytes.begin(), bytes.end()));
    if (ext == ".obj") validateObjVertices(path, std::string(bytes.begin(), bytes.end()));
    if (ext == ".stl" && head.rfind("solid", 0) != 0) {
        if (bytes.size() < 84)
            throw InputError(path, "truncated: " + std::to_string(bytes.size()) + " bytes, a binary STL header needs 84");
        uint32_t count;
        std::memcpy(&count, bytes.data() + 80, 4);
        const uint64_t expected = 84 + uint64_t(count) * 50;
        if (bytes.size() < expected)
            throw InputError(path, "offset 80: truncated: header says " + std::to_string(count) + " triangles (" +
                                       std::to_string(expected) + " bytes), file has " + std::to_string(bytes.size()));
        for (uint32_t t = 0; t < count; ++t)
            for (int k = 0; k < 9; ++k) {
                const size_t offset = 84 + size_t(t) * 50 + 12 + size_t(k) * 4;
                float v;
                std::memcpy(&v, bytes.data() + offset, 4);
                if (!std::isfinite(v))
                    throw InputError(path, "offset " + std::to_string(offset) + ": triangle " + std::to_string(t) +
                                               " has a non-finite coordinate (nan or inf)");
            }
    }
}

}  // namespace

Scene importWithOpenMesh(const std::string& path) {
    const std::string ext = lowerExtension(path);
    validateContainer(path, ext);
    FlatImporter importer;
    std::string reader_error;
    bool ok = false;
    {
        CapturedOpenMeshLog log;
        OpenMesh::IO::Options options;
        ok = OpenMesh::IO::IOManager().read(path, importer, options);
        reader_error = log.firstLine();
    }
    if (!importer.first_error.empty()) throw InputError(path, importer.first_error);
    if (!ok)
        throw InputError(path, "unreadable or truncated file, OpenMesh's reader rejected it" +
                                   (reader_error.empty() ? std::string() : ": " + reader_error));
    for (size_t i = 0; i < importer.positions.size(); ++i) {
        const glm::vec3& p = importer.positions[i];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw InputError(path, "vertex " + std::to_string(i) + " is not finite (nan or inf)");
    }

    std::vector<std::string> group_names;
    std::vector<uint32_t> face_group;
    const size_t face_count = importer.face_offsets.size() - 1;
    if (ext == ".obj") {
        face_group = objFaceGroups(path, group_names);
        // The reader may skip a face it cannot parse; then lines and faces no longer pair up,
        // and one object for the whole file is the honest answer.
        if (face_group.size() != face_count) face_group.clear();
    }
    const uint32_t group_count = face_group.empty() ? 1u : uint32_t(group_names.size());

    Scene scene;
    // Vertices are renumbered per group so that each object only holds what it uses.
    std::vector<uint32_t> remap(importer.positions.size(), UINT32_MAX);
    for (uint32_t g = 0; g < group_count; ++g) {
        Mesh mesh;
        mesh.name = face_group.empty() ? std::filesystem::path(path).stem().string() : group_names[g];
        std::fill(remap.begin(), remap.end(), UINT32_MAX);
        std::vector<uint32_t> poly;
        for (size_t f = 0; f < face_count; ++f) {
            if (!face_group.empty() && face_group[f] != g) continue;
            poly.assign(importer.corners.begin() + importer.face_offsets[f],
                        importer.corners.begin() + importer.face_offsets[f + 1]);
            // A polygon that repeats a corner in a row collapses an edge; drop the repeat.
            poly.erase(std::unique(poly.begin(), poly.end()), poly.end());
            while (poly.size() > 1 && poly.front() == poly.back()) poly.pop_back();
            if (poly.size() < 3) {
                ++scene.skipped.degenerate;
                continue;
            }
            for (uint32_t& v : poly) {
                if (remap[v] == UINT32_MAX) {
                    remap[v] = uint32_t(mesh.positions.size());
                    mesh.positions.push_back(importer.positions[v]);
                }
                v = remap[v];
            }
            for (size_t i = 2; i < poly.size(); ++i) mesh.indices.insert(mesh.indices.end(), {poly[0], poly[i - 1], poly[i]});
        }
        if (mesh.indices.empty()) continue;
        Object object;
        object.mesh = uint32_t(scene.meshes.size());
        object.color = mesh.color;
        scene.meshes.push_back(std::move(mesh));
        scene.objects.push_back(object);
    }
    return scene;
}

}  // namespace occ
