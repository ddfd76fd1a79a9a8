// SPDX-License-Identifier: MIT
#include "import/import.h"

#include "import/triangulate.h"
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

// The whitespace-separated words of one line.
std::vector<std::string> words(const char* begin, const char* end) {
    std::vector<std::string> out;
    const char* p = begin;
    while (p < end) {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\r')) ++p;
        const char* q = p;
        while (q < end && *q != ' ' && *q != '\t' && *q != '\r') ++q;
        if (q > p) out.emplace_back(p, q);
        p = q;
    }
    return out;
}

bool isNumber(const std::string& w, double* value = nullptr) {
    char* after = nullptr;
    const double v = std::strtod(w.c_str(), &after);
    if (value) *value = v;
    return after != w.c_str() && *after == '\0';
}

// ASCII STL: every "vertex" line with three numbers, every facet with three vertices (OpenMesh's
// reader reads past both). A binary STL may begin with "solid" too: it is the one whose size is
// 84 + 50 x its triangle count.
bool isBinaryStl(const std::vector<char>& bytes) {
    if (bytes.size() < 84) return false;
    uint32_t count;
    std::memcpy(&count, bytes.data() + 80, 4);
    return 84 + uint64_t(count) * 50 == bytes.size();
}

void validateAsciiStl(const std::string& path, const std::string& text) {
    size_t line_no = 0, start = 0, corners = 0, facet_line = 0;
    bool in_facet = false;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        ++line_no;
        const std::vector<std::string> w = words(text.c_str() + start, text.c_str() + end);
        start = end + 1;
        if (w.empty()) continue;
        const auto bad = [&](size_t line, const std::string& what) {
            throw InputError(path, "line " + std::to_string(line) + ": " + what);
        };
        if (w[0] == "facet") {
            if (in_facet) bad(line_no, "facet inside a facet (missing endfacet)");
            in_facet = true;
            corners = 0;
            facet_line = line_no;
        } else if (w[0] == "vertex") {
            if (!in_facet) bad(line_no, "vertex outside a facet");
            if (w.size() != 4) bad(line_no, "a vertex needs 3 coordinates, found " + std::to_string(w.size() - 1));
            for (size_t k = 1; k < 4; ++k) {
                double v = 0;
                if (!isNumber(w[k], &v)) bad(line_no, "'" + w[k] + "' is not a number");
                if (!std::isfinite(float(v))) bad(line_no, "vertex is not finite (nan or inf)");
            }
            ++corners;
        } else if (w[0] == "endfacet") {
            if (!in_facet) bad(line_no, "endfacet without a facet");
            if (corners != 3) bad(facet_line, "the facet has " + std::to_string(corners) + " vertices, an STL facet has 3");
            in_facet = false;
        }
    }
    if (in_facet)
        throw InputError(path, "truncated: the facet of line " + std::to_string(facet_line) + " has no endfacet");
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
    if (ext == ".stl" && head.rfind("solid", 0) == 0 && !isBinaryStl(bytes))
        validateAsciiStl(path, std::string(bytes.begin(), bytes.end()));
    if (ext == ".stl" && (head.rfind("solid", 0) != 0 || isBinaryStl(bytes))) {
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

    Scene scene;
    PolygonSoup soup;
    soup.positions = std::move(importer.positions);
    soup.face_offsets = std::move(importer.face_offsets);
    soup.corners = std::move(importer.corners);
    addPolygonObjects(soup, std::filesystem::path(path).stem().string(), scene);
    return scene;
}

}  // namespace occ
