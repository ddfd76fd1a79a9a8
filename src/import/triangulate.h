// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace occ {

// Triangulates one polygon face (corner indices into `positions`, in order) by ear clipping in
// the plane of its Newell normal, appending n - 2 triangles for n corners to `triangles` (as
// indices). Convex, concave and holed polygons (a hole joined to the outline by a bridge edge,
// traversed twice, as OBJ and OFF exporters write them) come out with their own winding and
// without filling concave notches or holes. Corners repeated in a row and a last corner equal
// to the first are dropped first. Returns false (appending nothing) for a face with fewer than
// three distinct corners or no area (all corners on one line): a degenerate face.
bool triangulatePolygon(const std::vector<glm::vec3>& positions, std::vector<uint32_t> corners,
                        std::vector<uint32_t>& triangles);

// Polygons as OBJ, OFF, PLY and STL readers collect them: shared positions, faces as runs of
// corners, and optionally a group per face (OBJ's g / o, one per group and material) with its
// material's colour, and a colour per position (PLY's red / green / blue, OBJ's "v x y z r g b").
// Colours are linear RGB in [0, 1], as Mesh::color.
struct PolygonSoup {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> vertex_colours;  // empty, or one per position
    std::vector<uint32_t> face_offsets{0};  // face f is corners[face_offsets[f], face_offsets[f + 1])
    std::vector<uint32_t> corners;          // each < positions.size()
    std::vector<uint32_t> face_group;       // empty, or one entry per face into group_names
    std::vector<std::string> group_names;
    std::vector<glm::vec4> group_colours;   // empty, or one per group name (a material's colour);
                                            // without face_group, entry 0 colours the whole soup
    std::vector<bool> group_coloured;       // with group_colours: whether that group's colour was given

    size_t faceCount() const { return face_offsets.size() - 1; }
    void addFace(const std::vector<uint32_t>& face) {
        corners.insert(corners.end(), face.begin(), face.end());
        face_offsets.push_back(uint32_t(corners.size()));
    }
};

// The whole of a model file, for the text and binary readers; InputError(path, ...) if it cannot
// be read.
std::string readModelFile(const std::string& path);
// The same for a text format (OBJ, OFF): a UTF-8 byte-order mark is dropped and UTF-16 text (with
// its byte-order mark, as Windows tools write it) is converted to UTF-8, so that the first record
// is not lost to the mark.
std::string readTextModelFile(const std::string& path);

// The whitespace-separated words of one line, up to a '#' comment.
std::vector<std::string> lineWords(std::string_view line);

// Calls visit(line_number, words) for every line of `text` that has words (lineWords; line
// numbers from 1, as messages name them).
template <class Visit>
void forEachLineWords(std::string_view text, Visit&& visit) {
    size_t line_no = 0, start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string_view::npos) end = text.size();
        ++line_no;
        const std::vector<std::string> words = lineWords(text.substr(start, end - start));
        start = end + 1;
        if (!words.empty()) visit(line_no, words);
    }
}

// Appends to `scene` one mesh and object per group that has triangles (one for the whole soup,
// named after the file `path`, when it has no groups), each holding only the vertices it uses,
// coloured by its group's material where it has one, else by the mean of its vertices' colours
// where the soup has them (the .oss keeps a colour per object, not per vertex), else Mesh's grey;
// faces are triangulated by triangulatePolygon, and the degenerate ones counted in scene.skipped.
// Vertices without any face, point or line (a point cloud) are InputError(path, ...).
void addPolygonObjects(const PolygonSoup& soup, const std::string& path, Scene& scene);

}  // namespace occ
