// SPDX-License-Identifier: MIT
// Wavefront OBJ, geometry only: "v" positions (x y z, optionally w or an r g b colour), "f"
// polygons (v, v/t, v//n or v/t/n corners, negative = relative to the last vertex), "g" / "o"
// groups (one object each when more than one has faces), "p" and "l" records counted as
// skipped points and lines. Everything else (vt, vn, usemtl, mtllib, s, ...) is read past.
// Every line that cannot be read is an error with its number: nothing is dropped silently.
#include "import/import.h"

#include "import/triangulate.h"
#include "scene/errors.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace occ {

Scene importObj(const std::string& path) {
    const std::string text = readTextModelFile(path);

    Scene scene;
    PolygonSoup soup;
    soup.group_names.assign(1, "default");
    std::vector<bool> group_has_faces(1, false);
    uint32_t group = 0;
    std::vector<std::string> w;
    std::vector<uint32_t> face;
    size_t line_no = 0, start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        ++line_no;
        w = lineWords(std::string_view(text).substr(start, end - start));
        start = end + 1;
        if (w.empty()) continue;
        const auto bad = [&](const std::string& what) {
            throw InputError(path, "line " + std::to_string(line_no) + ": " + what);
        };
        const std::string& key = w[0];
        if (key == "v") {
            if (w.size() != 4 && w.size() != 5 && w.size() != 7 && w.size() != 8)
                bad("a vertex needs 3 coordinates (and optionally w, or r g b), found " + std::to_string(w.size() - 1) +
                    " numbers");
            double c[3];
            for (size_t k = 1; k < w.size(); ++k) {
                char* after = nullptr;
                const double v = std::strtod(w[k].c_str(), &after);
                if (after == w[k].c_str() || *after != '\0') bad("'" + w[k] + "' is not a number");
                if (k <= 3) c[k - 1] = v;
            }
            const glm::vec3 p{float(c[0]), float(c[1]), float(c[2])};
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) bad("vertex is not finite (nan or inf)");
            soup.positions.push_back(p);
        } else if (key == "f") {
            if (w.size() < 4) bad("a face needs at least 3 corners, found " + std::to_string(w.size() - 1));
            face.clear();
            for (size_t k = 1; k < w.size(); ++k) {
                const std::string index = w[k].substr(0, w[k].find('/'));
                char* after = nullptr;
                errno = 0;
                const long long v = std::strtoll(index.c_str(), &after, 10);
                if (after == index.c_str() || *after != '\0' || v == 0 || errno != 0)
                    bad("'" + w[k] + "' is not a corner (v, v/t, v//n or v/t/n)");
                const long long n = (long long)soup.positions.size();
                const long long absolute = v > 0 ? v - 1 : n + v;
                if (absolute < 0 || absolute >= n)
                    bad("vertex index " + index + " out of range (" + std::to_string(n) + " vertices so far)");
                face.push_back(uint32_t(absolute));
            }
            soup.addFace(face);
            soup.face_group.push_back(group);
            group_has_faces[group] = true;
        } else if (key == "g" || key == "o") {
            // The group's name is the rest of the line (which may hold several words).
            std::string name;
            for (size_t k = 1; k < w.size(); ++k) name += (k > 1 ? " " : "") + w[k];
            if (name.empty()) name = "default";
            const auto it = std::find(soup.group_names.begin(), soup.group_names.end(), name);
            group = uint32_t(it - soup.group_names.begin());
            if (it == soup.group_names.end()) {
                soup.group_names.push_back(name);
                group_has_faces.push_back(false);
            }
        } else if (key == "p") {
            ++scene.skipped.points;
        } else if (key == "l") {
            ++scene.skipped.lines;
        }
    }
    // One object for the file when at most one group has faces.
    if (std::count(group_has_faces.begin(), group_has_faces.end(), true) <= 1) soup.face_group.clear();
    addPolygonObjects(soup, path, scene);
    return scene;
}

}  // namespace occ
