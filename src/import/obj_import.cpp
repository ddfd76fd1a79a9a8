// SPDX-License-Identifier: MIT
// Wavefront OBJ: "v" positions (x y z, optionally w or an r g b colour), "f" polygons (v, v/t,
// v//n or v/t/n corners, negative = relative to the last vertex), "g" / "o" groups and "usemtl"
// materials (one object per group and material when more than one has faces), "mtllib" files
// whose "newmtl" materials give their diffuse colour "Kd" (sRGB, as viewers show it), "p" and "l"
// records counted as skipped points and lines. Everything else (vt, vn, s, other material
// fields, ...) is read past. Every line that cannot be read is an error with its file and line
// number: nothing is dropped silently. A material no library defines (or a library that cannot
// be read) is counted in SkippedPrimitives::unknown_materials and drawn in Mesh's grey.
#include "import/import.h"

#include "import/triangulate.h"
#include "scene/colour.h"
#include "scene/errors.h"

#include <algorithm>
#include <map>
#include <set>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace occ {

namespace {

// Reads the "newmtl" / "Kd" pairs of one material library into `colours` (linear RGB); a
// malformed Kd is InputError(path, "line N: ...").
void readMaterialLibrary(const std::string& path, std::map<std::string, glm::vec4>& colours) {
    const std::string text = readTextModelFile(path);
    std::string material;
    forEachLineWords(text, [&](size_t line_no, const std::vector<std::string>& w) {
        if (w[0] == "newmtl") {
            material.clear();
            for (size_t k = 1; k < w.size(); ++k) material += (k > 1 ? " " : "") + w[k];
            colours.emplace(material, glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
        } else if (w[0] == "Kd") {
            if (w.size() < 2 || w[1] == "spectral" || w[1] == "xyz") return;  // not an RGB colour: Mesh's grey
            glm::vec4 kd(0, 0, 0, 1);
            for (size_t k = 0; k < 3; ++k) {
                // "Kd r" alone means r g b all r.
                const std::string& word = w[std::min(k + 1, w.size() - 1)];
                char* after = nullptr;
                const double v = std::strtod(word.c_str(), &after);
                if (after == word.c_str() || *after != '\0' || !std::isfinite(v))
                    throw InputError(path, "line " + std::to_string(line_no) + ": Kd '" + word + "' is not a number");
                kd[int(k)] = srgbToLinear(float(std::clamp(v, 0.0, 1.0)));
            }
            if (!material.empty()) colours[material] = kd;
        }
    });
}

}  // namespace

Scene importObj(const std::string& path) {
    const std::string text = readTextModelFile(path);

    Scene scene;
    PolygonSoup soup;
    soup.group_names.assign(1, "default");
    soup.group_colours.assign(1, glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
    soup.group_coloured.assign(1, false);
    std::vector<bool> group_has_faces(1, false);
    // The current "g" / "o" name and "usemtl" material; a group is one (name, material) pair.
    std::string group_name = "default", material;
    std::map<std::pair<std::string, std::string>, uint32_t> group_of{{{"default", ""}, 0}};
    std::map<std::string, glm::vec4> material_colours;
    std::set<std::string> unknown_materials;
    bool vertex_colours = false;
    uint32_t group = 0;
    const auto selectGroup = [&] {
        const auto [it, added] = group_of.emplace(std::make_pair(group_name, material), uint32_t(soup.group_names.size()));
        group = it->second;
        if (!added) return;
        soup.group_names.push_back(material.empty() ? group_name : group_name + " (" + material + ")");
        group_has_faces.push_back(false);
        const auto colour = material_colours.find(material);
        soup.group_coloured.push_back(colour != material_colours.end());
        soup.group_colours.push_back(colour != material_colours.end() ? colour->second : glm::vec4(0.8f, 0.8f, 0.8f, 1.0f));
        if (colour == material_colours.end() && !material.empty() && unknown_materials.insert(material).second)
            ++scene.skipped.unknown_materials;
    };
    std::vector<uint32_t> face;
    forEachLineWords(text, [&](size_t line_no, const std::vector<std::string>& w) {
        const auto bad = [&](const std::string& what) {
            throw InputError(path, "line " + std::to_string(line_no) + ": " + what);
        };
        const std::string& key = w[0];
        if (key == "v") {
            if (w.size() != 4 && w.size() != 5 && w.size() != 7 && w.size() != 8)
                bad("a vertex needs 3 coordinates (and optionally w, or r g b), found " + std::to_string(w.size() - 1) +
                    " numbers");
            double c[6] = {0, 0, 0, 0, 0, 0};
            for (size_t k = 1; k < w.size(); ++k) {
                char* after = nullptr;
                const double v = std::strtod(w[k].c_str(), &after);
                if (after == w[k].c_str() || *after != '\0') bad("'" + w[k] + "' is not a number");
                if (k <= 6) c[k - 1] = v;
            }
            const glm::vec3 p{float(c[0]), float(c[1]), float(c[2])};
            if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) bad("vertex is not finite (nan or inf)");
            // A colour per vertex (x y z r g b, sRGB) is kept only when the first vertex has one.
            if (soup.positions.empty()) vertex_colours = w.size() == 7;
            if (vertex_colours) {
                glm::vec3 rgb(0.8f);
                if (w.size() == 7)
                    for (int a = 0; a < 3; ++a)
                        rgb[a] = srgbToLinear(float(std::isfinite(c[3 + a]) ? std::clamp(c[3 + a], 0.0, 1.0) : 0.0));
                soup.vertex_colours.push_back(rgb);
            }
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
        } else if (key == "g" || key == "o" || key == "usemtl") {
            // The name is the rest of the line (which may hold several words).
            std::string name;
            for (size_t k = 1; k < w.size(); ++k) name += (k > 1 ? " " : "") + w[k];
            if (key == "usemtl")
                material = name;
            else
                group_name = name.empty() ? "default" : name;
            selectGroup();
        } else if (key == "mtllib") {
            // Libraries are named relative to the OBJ's folder; one that cannot be read leaves its
            // materials unknown (counted), as a viewer shows them, rather than refusing the model.
            const std::filesystem::path folder = std::filesystem::path(path).parent_path();
            for (size_t k = 1; k < w.size(); ++k) {
                const std::string library = (folder / w[k]).string();
                std::error_code ec;
                if (std::filesystem::is_regular_file(library, ec)) readMaterialLibrary(library, material_colours);
            }
        } else if (key == "p") {
            ++scene.skipped.points;
        } else if (key == "l") {
            ++scene.skipped.lines;
        }
    });
    // One object for the file when at most one group has faces.
    if (std::count(group_has_faces.begin(), group_has_faces.end(), true) <= 1) {
        soup.face_group.clear();
        const auto faced = std::find(group_has_faces.begin(), group_has_faces.end(), true);
        const size_t g = faced == group_has_faces.end() ? 0 : size_t(faced - group_has_faces.begin());
        soup.group_colours = {soup.group_colours[g]};
        soup.group_coloured = {soup.group_coloured[g]};
    }
    addPolygonObjects(soup, path, scene);
    return scene;
}

}  // namespace occ
