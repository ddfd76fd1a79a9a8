// SPDX-License-Identifier: MIT
// OFF as Geomview defines it and CGAL, Meshlab and assimp's test files write it: an optional
// [ST][C][N][4][n]OFF header word, the vertex, face and edge counts, then one vertex and one face
// per line. '#' starts a comment anywhere; blank lines may come anywhere. Vertex lines may carry
// a normal, a colour and texture coordinates after the position, face lines a colour after the
// corner indices; those are read past (geometry only).
#include "import/import.h"

#include "import/triangulate.h"
#include "scene/errors.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace occ {

namespace {

struct DataLine {
    size_t number;  // 1-based line in the file
    std::string text;
};

// The lines that hold data, without comments and surrounding blanks.
std::vector<DataLine> dataLines(const std::string& text) {
    std::vector<DataLine> out;
    size_t start = 0, number = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        ++number;
        std::string line = text.substr(start, end - start);
        const size_t hash = line.find('#');
        if (hash != std::string::npos) line.erase(hash);
        const size_t first = line.find_first_not_of(" \t\r\f\v");
        if (first != std::string::npos) {
            const size_t last = line.find_last_not_of(" \t\r\f\v");
            out.push_back({number, line.substr(first, last - first + 1)});
        }
        start = end + 1;
    }
    return out;
}

bool parseDouble(const std::string& s, double& v) {
    char* end = nullptr;
    errno = 0;
    v = std::strtod(s.c_str(), &end);
    return end != s.c_str() && *end == '\0';
}

bool parseIndex(const std::string& s, long long& v) {
    char* end = nullptr;
    errno = 0;
    v = std::strtoll(s.c_str(), &end, 10);
    return end != s.c_str() && *end == '\0' && errno == 0;
}

}  // namespace

Scene importOff(const std::string& path) {
    const std::string text = readTextModelFile(path);
    const std::vector<DataLine> lines = dataLines(text);
    const auto where = [&](size_t line) { return "line " + std::to_string(line) + ": "; };
    if (lines.empty()) throw InputError(path, "empty file, an OFF file starts with 'OFF'");

    // The header word and the counts, on its line or the next data line.
    std::vector<std::string> head = lineWords(lines[0].text);
    std::string magic = head[0];
    size_t next = 1;
    int dimension = 3;
    const bool has_magic = magic.size() >= 3 && magic.compare(magic.size() - 3, 3, "OFF") == 0;
    if (has_magic) {
        const std::string prefix = magic.substr(0, magic.size() - 3);
        for (size_t k = 0; k < prefix.size(); ++k) {
            const char c = prefix[k];
            if (c == 'S' && k + 1 < prefix.size() && prefix[k + 1] == 'T') {
                ++k;
            } else if (c == '4') {
                dimension = 4;
            } else if (c == 'n') {
                dimension = -1;  // given next
            } else if (c != 'C' && c != 'N') {
                throw InputError(path, where(lines[0].number) + "unknown header word '" + magic +
                                           "' (expected [ST][C][N][4][n]OFF)");
            }
        }
        head.erase(head.begin());
        if (!head.empty() && head[0] == "BINARY")
            throw InputError(path, where(lines[0].number) + "binary OFF is not supported (write it as text)");
        if (head.empty()) {
            if (lines.size() < 2) throw InputError(path, "truncated: no vertex and face counts after '" + magic + "'");
            head = lineWords(lines[1].text);
            next = 2;
        }
        if (dimension < 0) {
            long long d = 0;
            if (!parseIndex(head[0], d) || d < 3 || d > 16)
                throw InputError(path, where(lines[next - 1].number) + "bad dimension '" + head[0] + "' after nOFF");
            dimension = int(d) + (magic.find('4') != std::string::npos ? 1 : 0);
            head.erase(head.begin());
            if (head.empty()) {
                if (lines.size() <= next) throw InputError(path, "truncated: no vertex and face counts");
                head = lineWords(lines[next].text);
                ++next;
            }
        }
    } else {
        // The header word is optional: then the first data line holds the counts.
        long long probe = 0;
        if (!parseIndex(magic, probe))
            throw InputError(path, where(lines[0].number) + "bad magic '" + magic +
                                       "', an OFF file starts with 'OFF' (or COFF, NOFF, STOFF, ...)");
    }
    const size_t counts_line = lines[next - 1].number;
    long long nv = -1, nf = -1, ne = 0;
    if (head.size() < 2 || !parseIndex(head[0], nv) || !parseIndex(head[1], nf) || nv < 0 || nf < 0 ||
        (head.size() > 2 && !parseIndex(head[2], ne)))
        throw InputError(path, where(counts_line) + "expected the vertex, face and edge counts, found '" +
                                   lines[next - 1].text + "'");
    if (head.size() > 3) throw InputError(path, where(counts_line) + "more than three counts: '" + lines[next - 1].text + "'");
    if (uint64_t(nv) + uint64_t(nf) > lines.size() - next)
        throw InputError(path, "truncated: header says " + std::to_string(nv) + " vertices and " + std::to_string(nf) +
                                   " faces, the file has " + std::to_string(lines.size() - next) + " data lines after it");
    if (uint64_t(nv) + uint64_t(nf) < lines.size() - next)
        throw InputError(path, where(lines[next + size_t(nv + nf)].number) + "data after the last of the " +
                                   std::to_string(nf) + " faces the header promises");

    Scene scene;
    std::vector<glm::vec3> positions(static_cast<size_t>(nv));
    for (long long v = 0; v < nv; ++v) {
        const DataLine& line = lines[next + size_t(v)];
        const std::vector<std::string> t = lineWords(line.text);
        if (t.size() < size_t(dimension))
            throw InputError(path, where(line.number) + "vertex " + std::to_string(v) + " has " + std::to_string(t.size()) +
                                       " numbers, expected " + std::to_string(dimension) + " coordinates");
        double c[4] = {0, 0, 0, 1};
        for (int k = 0; k < dimension; ++k) {
            double x = 0;
            if (!parseDouble(t[size_t(k)], x))
                throw InputError(path, where(line.number) + "vertex " + std::to_string(v) + ": '" + t[size_t(k)] +
                                           "' is not a number");
            if (k < 4) c[k] = x;
        }
        for (size_t k = 0; k < t.size(); ++k) {
            double x = 0;
            if (!parseDouble(t[k], x))
                throw InputError(path, where(line.number) + "vertex " + std::to_string(v) + ": '" + t[k] +
                                           "' is not a number");
        }
        // 4OFF: homogeneous coordinates.
        if (dimension == 4) {
            if (c[3] == 0) throw InputError(path, where(line.number) + "vertex " + std::to_string(v) + " has w = 0");
            c[0] /= c[3], c[1] /= c[3], c[2] /= c[3];
        }
        positions[size_t(v)] = glm::vec3(float(c[0]), float(c[1]), float(c[2]));
        const glm::vec3& p = positions[size_t(v)];
        if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
            throw InputError(path, where(line.number) + "vertex " + std::to_string(v) + " is not finite (nan or inf)");
    }

    PolygonSoup soup;
    soup.positions = std::move(positions);
    std::vector<uint32_t> corners;
    for (long long f = 0; f < nf; ++f) {
        const DataLine& line = lines[next + size_t(nv + f)];
        const std::vector<std::string> t = lineWords(line.text);
        long long count = 0;
        if (!parseIndex(t[0], count) || count < 0)
            throw InputError(path, where(line.number) + "face " + std::to_string(f) + ": '" + t[0] +
                                       "' is not a corner count");
        if (t.size() < size_t(count) + 1)
            throw InputError(path, where(line.number) + "face " + std::to_string(f) + " lists " +
                                       std::to_string(t.size() - 1) + " of its " + std::to_string(count) + " corners");
        if (t.size() > size_t(count) + 1 + 4)
            throw InputError(path, where(line.number) + "face " + std::to_string(f) + " has " +
                                       std::to_string(t.size() - 1 - size_t(count)) +
                                       " numbers after its corners (a colour has at most 4)");
        corners.clear();
        for (long long k = 0; k < count; ++k) {
            long long index = 0;
            if (!parseIndex(t[size_t(k) + 1], index) || index < 0 || index >= nv)
                throw InputError(path, where(line.number) + "face " + std::to_string(f) + ": vertex index '" +
                                           t[size_t(k) + 1] + "' out of range (" + std::to_string(nv) + " vertices)");
            corners.push_back(uint32_t(index));
        }
        if (count == 1) {
            ++scene.skipped.points;
        } else if (count == 2) {
            ++scene.skipped.lines;
        } else {
            soup.addFace(corners);
        }
    }
    addPolygonObjects(soup, path, scene);
    return scene;
}

}  // namespace occ
