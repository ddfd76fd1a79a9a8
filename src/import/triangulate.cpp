// SPDX-License-Identifier: MIT
#include "import/triangulate.h"

#include "scene/errors.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace occ {

namespace {

double cross2(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// p inside triangle abc (counter-clockwise) or on its boundary.
bool inTriangle(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
    return cross2(a, b, p) >= 0 && cross2(b, c, p) >= 0 && cross2(c, a, p) >= 0;
}

}  // namespace

bool triangulatePolygon(const std::vector<glm::vec3>& positions, std::vector<uint32_t> corners,
                        std::vector<uint32_t>& triangles) {
    corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
    while (corners.size() > 1 && corners.front() == corners.back()) corners.pop_back();
    const size_t n = corners.size();
    if (n < 3) return false;
    if (n == 3) {
        triangles.insert(triangles.end(), corners.begin(), corners.end());
        return true;
    }

    // The plane: Newell's normal, which points along the polygon's counter-clockwise side.
    glm::dvec3 normal(0.0);
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 a(positions[corners[i]]), b(positions[corners[(i + 1) % n]]);
        normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
    }
    const double length = glm::length(normal);
    if (!(length > 0)) {
        // No area: a fan of zero-area triangles, which preprocessing counts and drops.
        for (size_t i = 2; i < n; ++i) triangles.insert(triangles.end(), {corners[0], corners[i - 1], corners[i]});
        return true;
    }
    normal /= length;
    const glm::dvec3 helper = std::abs(normal.x) < 0.9 ? glm::dvec3(1, 0, 0) : glm::dvec3(0, 1, 0);
    const glm::dvec3 t = glm::normalize(glm::cross(helper, normal));
    const glm::dvec3 b = glm::cross(normal, t);  // (t, b, normal) right-handed: CCW stays CCW
    std::vector<glm::dvec2> p(n);
    for (size_t i = 0; i < n; ++i) {
        const glm::dvec3 q(positions[corners[i]]);
        p[i] = {glm::dot(q, t), glm::dot(q, b)};
    }

    // Ear clipping over a ring of the remaining corners. An ear is a convex corner whose triangle
    // holds no other remaining corner (corners at the same place as one of its own, as a bridge
    // edge to a hole makes them, do not count).
    std::vector<size_t> next(n), prev(n);
    for (size_t i = 0; i < n; ++i) next[i] = (i + 1) % n, prev[i] = (i + n - 1) % n;
    const auto same = [&](size_t i, size_t j) { return p[i] == p[j]; };
    const auto isEar = [&](size_t i) {
        const size_t a = prev[i], c = next[i];
        if (cross2(p[a], p[i], p[c]) <= 0) return false;
        for (size_t j = next[c]; j != a; j = next[j]) {
            if (same(j, a) || same(j, i) || same(j, c)) continue;
            if (inTriangle(p[j], p[a], p[i], p[c])) return false;
        }
        return true;
    };
    size_t remaining = n, i = 0, since_last = 0;
    bool strict = true;
    while (remaining > 3) {
        const bool convex = cross2(p[prev[i]], p[i], p[next[i]]) > 0;
        if (strict ? isEar(i) : (convex || since_last >= 2 * remaining)) {
            triangles.insert(triangles.end(), {corners[prev[i]], corners[i], corners[next[i]]});
            next[prev[i]] = next[i];
            prev[next[i]] = prev[i];
            --remaining;
            i = next[i];
            since_last = 0;
            strict = true;
            continue;
        }
        i = next[i];
        // A whole turn without an ear (a self-intersecting or numerically flat outline): clip
        // convex corners regardless, and any corner after another turn, so n - 2 triangles still come out.
        if (++since_last >= remaining) strict = false;
    }
    triangles.insert(triangles.end(), {corners[prev[i]], corners[i], corners[next[i]]});
    return true;
}

std::string readModelFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot open: " + std::string(std::strerror(errno)));
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw InputError(path, "read error");
    return bytes;
}

std::string readTextModelFile(const std::string& path) {
    std::string bytes = readModelFile(path);
    const auto starts = [&](const char* mark, size_t n) { return bytes.size() >= n && bytes.compare(0, n, mark, n) == 0; };
    if (starts("\xEF\xBB\xBF", 3)) return bytes.substr(3);
    const bool big = starts("\xFE\xFF", 2), little = starts("\xFF\xFE", 2);
    if (!big && !little) return bytes;
    if (bytes.size() % 2) throw InputError(path, "truncated: UTF-16 text with an odd number of bytes");
    std::string text;
    text.reserve(bytes.size() / 2);
    const auto unit = [&](size_t at) {
        const unsigned a = static_cast<unsigned char>(bytes[at]), b = static_cast<unsigned char>(bytes[at + 1]);
        return big ? (a << 8 | b) : (b << 8 | a);
    };
    for (size_t at = 2; at < bytes.size(); at += 2) {
        uint32_t c = unit(at);
        if (c >= 0xD800 && c < 0xDC00 && at + 3 < bytes.size()) {  // a surrogate pair
            const uint32_t low = unit(at + 2);
            if (low >= 0xDC00 && low < 0xE000) {
                c = 0x10000 + ((c - 0xD800) << 10) + (low - 0xDC00);
                at += 2;
            }
        }
        if (c < 0x80) {
            text += char(c);
        } else if (c < 0x800) {
            text += char(0xC0 | c >> 6);
            text += char(0x80 | (c & 0x3F));
        } else if (c < 0x10000) {
            text += char(0xE0 | c >> 12);
            text += char(0x80 | (c >> 6 & 0x3F));
            text += char(0x80 | (c & 0x3F));
        } else {
            text += char(0xF0 | c >> 18);
            text += char(0x80 | (c >> 12 & 0x3F));
            text += char(0x80 | (c >> 6 & 0x3F));
            text += char(0x80 | (c & 0x3F));
        }
    }
    return text;
}

std::vector<std::string> lineWords(std::string_view line) {
    std::vector<std::string> out;
    size_t p = 0;
    const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v' || c == '\n'; };
    while (p < line.size()) {
        while (p < line.size() && blank(line[p])) ++p;
        if (p < line.size() && line[p] == '#') break;
        size_t q = p;
        while (q < line.size() && !blank(line[q])) ++q;
        if (q > p) out.emplace_back(line.substr(p, q - p));
        p = q;
    }
    return out;
}

void addPolygonObjects(const PolygonSoup& soup, const std::string& path, Scene& scene) {
    if (soup.faceCount() == 0 && !soup.positions.empty() && scene.skipped.points == 0 && scene.skipped.lines == 0)
        throw InputError(path, "no triangles to draw: " + std::to_string(soup.positions.size()) +
                                   " vertices and no faces (a point cloud? occswitch draws triangles)");
    const std::string name = std::filesystem::path(path).stem().string();
    const uint32_t groups = soup.face_group.empty() ? 1u : uint32_t(soup.group_names.size());
    std::vector<uint32_t> remap(soup.positions.size(), UINT32_MAX), triangles;
    for (uint32_t g = 0; g < groups; ++g) {
        Mesh mesh;
        mesh.name = soup.face_group.empty() ? name : soup.group_names[g];
        std::fill(remap.begin(), remap.end(), UINT32_MAX);
        glm::dvec3 colour_sum(0.0);
        for (size_t f = 0; f < soup.faceCount(); ++f) {
            if (!soup.face_group.empty() && soup.face_group[f] != g) continue;
            triangles.clear();
            if (!triangulatePolygon(soup.positions,
                                    std::vector<uint32_t>(soup.corners.begin() + soup.face_offsets[f],
                                                          soup.corners.begin() + soup.face_offsets[f + 1]),
                                    triangles)) {
                ++scene.skipped.degenerate;
                continue;
            }
            for (uint32_t v : triangles) {
                if (remap[v] == UINT32_MAX) {
                    remap[v] = uint32_t(mesh.positions.size());
                    mesh.positions.push_back(soup.positions[v]);
                    if (!soup.vertex_colours.empty()) colour_sum += glm::dvec3(soup.vertex_colours[v]);
                }
                mesh.indices.push_back(remap[v]);
            }
        }
        if (mesh.indices.empty()) continue;
        if (g < soup.group_colours.size() && soup.group_coloured[g])
            mesh.color = soup.group_colours[g];
        else if (!soup.vertex_colours.empty())
            mesh.color = glm::vec4(glm::vec3(colour_sum / double(mesh.positions.size())), 1.0f);
        Object object;
        object.mesh = uint32_t(scene.meshes.size());
        object.color = mesh.color;
        scene.meshes.push_back(std::move(mesh));
        scene.objects.push_back(object);
    }
}

}  // namespace occ
