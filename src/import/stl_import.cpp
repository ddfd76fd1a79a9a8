// SPDX-License-Identifier: MIT
// STL, binary and ASCII. Binary: an 80-byte header, a triangle count, 50 bytes per triangle
// (normal, three corners, attribute bytes); a file is binary exactly when its size is 84 + 50 x
// its count (binary files may begin with "solid" too). ASCII: "solid" ... facets of "outer
// loop", three "vertex x y z" lines, "endloop", "endfacet" ... "endsolid", possibly several
// solids. Corners at bit-identical places are merged, as STL repeats every shared vertex.
#include "import/import.h"

#include "import/triangulate.h"
#include "scene/errors.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <unordered_map>

namespace occ {

namespace {

struct Corners {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    std::unordered_map<uint64_t, std::vector<uint32_t>> buckets;  // hash of the bits -> vertices

    uint32_t add(const glm::vec3& p) {
        uint32_t bits[3];
        for (int k = 0; k < 3; ++k) {
            const float v = p[k] == 0.0f ? 0.0f : p[k];  // -0 and +0 are one place
            std::memcpy(&bits[k], &v, 4);
        }
        const uint64_t h = (uint64_t(bits[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(bits[1]) * 0xBF58476D1CE4E5B9ull) ^
                           (uint64_t(bits[2]) * 0x94D049BB133111EBull);
        std::vector<uint32_t>& bucket = buckets[h];
        for (uint32_t v : bucket)
            if (positions[v] == p) return v;
        bucket.push_back(uint32_t(positions.size()));
        positions.push_back(p);
        return bucket.back();
    }
};

void readAscii(const std::string& path, const std::string& text, Corners& corners) {
    size_t facet_line = 0, in_loop = 0;
    uint32_t facet[3];
    int count = 0;
    bool in_facet = false, in_solid = false;
    forEachLineWords(text, [&](size_t line_no, const std::vector<std::string>& w) {
        const auto bad = [&](size_t line, const std::string& what) {
            throw InputError(path, "line " + std::to_string(line) + ": " + what);
        };
        const std::string& key = w[0];
        if (key == "solid") {
            if (in_solid) bad(line_no, "solid inside a solid (missing endsolid)");
            in_solid = true;
        } else if (key == "endsolid") {
            if (in_facet) bad(facet_line, "the facet has no endfacet");
            in_solid = false;
        } else if (key == "facet") {
            if (!in_solid) bad(line_no, "facet outside a solid");
            if (in_facet) bad(line_no, "facet inside a facet (missing endfacet)");
            in_facet = true;
            count = 0;
            facet_line = line_no;
        } else if (key == "outer") {
            if (!in_facet) bad(line_no, "outer loop outside a facet");
            in_loop = line_no;
        } else if (key == "endloop") {
            if (!in_loop) bad(line_no, "endloop without outer loop");
            in_loop = 0;
        } else if (key == "vertex") {
            if (!in_facet) bad(line_no, "vertex outside a facet");
            if (w.size() != 4) bad(line_no, "a vertex needs 3 coordinates, found " + std::to_string(w.size() - 1));
            double c[3];
            for (int k = 0; k < 3; ++k) {
                char* after = nullptr;
                c[k] = std::strtod(w[size_t(k) + 1].c_str(), &after);
                if (after == w[size_t(k) + 1].c_str() || *after != '\0') bad(line_no, "'" + w[size_t(k) + 1] + "' is not a number");
            }
            const glm::vec3 p{float(c[0]), float(c[1]), float(c[2])};
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) bad(line_no, "vertex is not finite (nan or inf)");
            if (count == 3) bad(facet_line, "the facet has more than 3 vertices, an STL facet has 3");
            facet[count++] = corners.add(p);
        } else if (key == "endfacet") {
            if (!in_facet) bad(line_no, "endfacet without a facet");
            if (count != 3) bad(facet_line, "the facet has " + std::to_string(count) + " vertices, an STL facet has 3");
            corners.triangles.insert(corners.triangles.end(), facet, facet + 3);
            in_facet = false;
        } else {
            bad(line_no, "unknown keyword '" + key + "'");
        }
    });
    if (in_facet) throw InputError(path, "truncated: the facet of line " + std::to_string(facet_line) + " has no endfacet");
    if (in_solid) throw InputError(path, "truncated: no endsolid");
}

}  // namespace

Scene importStl(const std::string& path) {
    const std::string bytes = readModelFile(path);
    Corners corners;
    uint32_t count = 0;
    if (bytes.size() >= 84) std::memcpy(&count, bytes.data() + 80, 4);
    const bool binary = bytes.size() >= 84 && 84 + uint64_t(count) * 50 == bytes.size();
    if (binary) {
        for (uint32_t t = 0; t < count; ++t) {
            uint32_t facet[3];
            for (int k = 0; k < 3; ++k) {
                const size_t offset = 84 + size_t(t) * 50 + 12 + size_t(k) * 12;
                float c[3];
                std::memcpy(c, bytes.data() + offset, 12);
                if (!std::isfinite(c[0]) || !std::isfinite(c[1]) || !std::isfinite(c[2]))
                    throw InputError(path, "offset " + std::to_string(offset) + ": triangle " + std::to_string(t) +
                                               " has a non-finite coordinate (nan or inf)");
                facet[k] = corners.add({c[0], c[1], c[2]});
            }
            corners.triangles.insert(corners.triangles.end(), facet, facet + 3);
        }
    } else if (bytes.compare(0, 5, "solid") == 0) {
        readAscii(path, bytes, corners);
    } else if (bytes.size() < 84) {
        throw InputError(path, "truncated: " + std::to_string(bytes.size()) + " bytes, a binary STL header needs 84");
    } else {
        throw InputError(path, "offset 80: header says " + std::to_string(count) + " triangles (" +
                                   std::to_string(84 + uint64_t(count) * 50) + " bytes), file has " +
                                   std::to_string(bytes.size()) + (84 + uint64_t(count) * 50 > bytes.size() ? " (truncated)" : ""));
    }
    Scene scene;
    PolygonSoup soup;
    soup.positions = std::move(corners.positions);
    soup.corners = std::move(corners.triangles);
    const size_t faces = soup.corners.size() / 3;
    soup.face_offsets.reserve(faces + 1);  // already holds the leading 0
    for (size_t f = 1; f <= faces; ++f) soup.face_offsets.push_back(uint32_t(3 * f));
    addPolygonObjects(soup, path, scene);
    return scene;
}

}  // namespace occ
