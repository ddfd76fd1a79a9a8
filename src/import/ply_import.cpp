// SPDX-License-Identifier: MIT
// PLY (Stanford polygon files), ASCII and binary of either byte order. The header declares
// elements, each a count of records of scalar and list properties; this reader takes the
// "vertex" element's x, y, z (any numeric type) and red, green, blue where it has all three
// (8-bit sRGB as scanners write them when integer, [0, 1] when float; the object's colour is
// their mean), the "face" element's "vertex_indices" (or "vertex_index") list, and reads past
// every other element and property. Every read is checked
// against the file: counts that promise more than the file holds, indices out of range,
// non-numbers and non-finite positions are errors with their line or byte offset.
#include "import/import.h"

#include "import/triangulate.h"
#include "scene/colour.h"
#include "scene/errors.h"

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace occ {

namespace {

enum class Type : uint8_t { Int8, Uint8, Int16, Uint16, Int32, Uint32, Float32, Float64 };

bool parseType(const std::string& name, Type& t) {
    static const std::pair<const char*, Type> names[] = {
        {"char", Type::Int8},     {"int8", Type::Int8},     {"uchar", Type::Uint8},     {"uint8", Type::Uint8},
        {"short", Type::Int16},   {"int16", Type::Int16},   {"ushort", Type::Uint16},   {"uint16", Type::Uint16},
        {"int", Type::Int32},     {"int32", Type::Int32},   {"uint", Type::Uint32},     {"uint32", Type::Uint32},
        {"float", Type::Float32}, {"float32", Type::Float32}, {"double", Type::Float64}, {"float64", Type::Float64}};
    for (const auto& [n, type] : names)
        if (name == n) {
            t = type;
            return true;
        }
    return false;
}

size_t typeSize(Type t) {
    switch (t) {
    case Type::Int8:
    case Type::Uint8: return 1;
    case Type::Int16:
    case Type::Uint16: return 2;
    case Type::Int32:
    case Type::Uint32:
    case Type::Float32: return 4;
    default: return 8;
    }
}

bool isInteger(Type t) { return t != Type::Float32 && t != Type::Float64; }

// A number read from the file, for a message (it may be far outside any integer's range).
std::string shown(double v) {
    char text[32];
    std::snprintf(text, sizeof text, "%.17g", v);
    return text;
}

struct Property {
    std::string name;
    bool list = false;
    Type count_type = Type::Uint8;  // lists only
    Type type = Type::Float32;
};

struct Element {
    std::string name;
    uint64_t count = 0;
    std::vector<Property> properties;
};

enum class Format { Ascii, Little, Big };

// The records after the header, as numbers, one at a time.
class Reader {
public:
    Reader(const std::string& path, const std::string& bytes, size_t offset, Format format, size_t first_line)
        : path_(path), bytes_(bytes), at_(offset), format_(format), line_(first_line) {}

    double read(Type t) {
        if (format_ == Format::Ascii) return readAscii(t);
        const size_t n = typeSize(t);
        if (bytes_.size() - at_ < n)
            throw InputError(path_, "offset " + std::to_string(at_) + ": truncated: the header promises more data");
        unsigned char b[8];
        std::memcpy(b, bytes_.data() + at_, n);
        if ((format_ == Format::Big) != (std::endian::native == std::endian::big))
            for (size_t i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
        at_ += n;
        switch (t) {
        case Type::Int8: return double(int8_t(b[0]));
        case Type::Uint8: return double(b[0]);
        case Type::Int16: { int16_t v; std::memcpy(&v, b, 2); return v; }
        case Type::Uint16: { uint16_t v; std::memcpy(&v, b, 2); return v; }
        case Type::Int32: { int32_t v; std::memcpy(&v, b, 4); return v; }
        case Type::Uint32: { uint32_t v; std::memcpy(&v, b, 4); return v; }
        case Type::Float32: { float v; std::memcpy(&v, b, 4); return v; }
        default: { double v; std::memcpy(&v, b, 8); return v; }
        }
    }
    // How many more values the rest of the file can hold at most (to refuse counts that promise
    // more before anything is allocated for them).
    uint64_t room(Type t) const {
        const uint64_t left = bytes_.size() - at_;
        return format_ == Format::Ascii ? left / 2 + 1 : left / typeSize(t);
    }
    std::string where() const {
        return format_ == Format::Ascii ? "line " + std::to_string(line_) : "offset " + std::to_string(at_);
    }
    void expectEnd() {
        if (format_ == Format::Ascii) {
            while (at_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[at_]))) ++at_;
        }
        if (at_ != bytes_.size())
            throw InputError(path_, where() + ": data after the last element the header declares");
    }

private:
    double readAscii(Type t) {
        while (at_ < bytes_.size() && std::isspace(static_cast<unsigned char>(bytes_[at_]))) {
            if (bytes_[at_] == '\n') ++line_;
            ++at_;
        }
        if (at_ == bytes_.size()) throw InputError(path_, "truncated: the header promises more data than the file has");
        size_t end = at_;
        while (end < bytes_.size() && !std::isspace(static_cast<unsigned char>(bytes_[end]))) ++end;
        const std::string word = bytes_.substr(at_, end - at_);
        char* after = nullptr;
        const double v = std::strtod(word.c_str(), &after);
        if (after == word.c_str() || *after != '\0')
            throw InputError(path_, "line " + std::to_string(line_) + ": '" + word + "' is not a number");
        if (isInteger(t) && !(std::isfinite(v) && v == std::floor(v)))
            throw InputError(path_, "line " + std::to_string(line_) + ": '" + word + "' is not an integer");
        at_ = end;
        return v;
    }

    const std::string& path_;
    const std::string& bytes_;
    size_t at_;
    Format format_;
    size_t line_;
};

}  // namespace

Scene importPly(const std::string& path) {
    const std::string bytes = readModelFile(path);
    if (bytes.compare(0, 3, "ply") != 0 || (bytes.size() > 3 && bytes[3] != '\n' && bytes[3] != '\r'))
        throw InputError(path, "offset 0: bad magic, a PLY file starts with 'ply'");

    // The header, line by line, up to end_header.
    std::vector<Element> elements;
    Format format = Format::Ascii;
    bool has_format = false;
    size_t at = 0, line_no = 0;
    for (;;) {
        if (at >= bytes.size()) throw InputError(path, "truncated: no end_header");
        size_t end = bytes.find('\n', at);
        if (end == std::string::npos) throw InputError(path, "truncated: no end_header");
        ++line_no;
        std::string line = bytes.substr(at, end - at);
        at = end + 1;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream words(line);
        std::string key;
        words >> key;
        const auto bad = [&](const std::string& what) {
            throw InputError(path, "line " + std::to_string(line_no) + ": " + what);
        };
        if (line_no == 1 || key.empty() || key == "comment" || key == "obj_info") continue;
        if (key == "end_header") break;
        if (key == "format") {
            std::string f, version;
            words >> f >> version;
            if (f == "ascii")
                format = Format::Ascii;
            else if (f == "binary_little_endian")
                format = Format::Little;
            else if (f == "binary_big_endian")
                format = Format::Big;
            else
                bad("unknown format '" + f + "'");
            if (version != "1.0") bad("unsupported PLY version '" + version + "'");
            has_format = true;
        } else if (key == "element") {
            Element e;
            std::string count;
            words >> e.name >> count;
            char* after = nullptr;
            e.count = std::strtoull(count.c_str(), &after, 10);
            if (e.name.empty() || count.empty() || *after != '\0' || count[0] == '-') bad("expected 'element NAME COUNT'");
            elements.push_back(e);
        } else if (key == "property") {
            if (elements.empty()) bad("property before any element");
            Property p;
            std::string type;
            words >> type;
            if (type == "list") {
                std::string count_type, item_type;
                words >> count_type >> item_type >> p.name;
                p.list = true;
                if (!parseType(count_type, p.count_type) || !isInteger(p.count_type) || !parseType(item_type, p.type))
                    bad("bad list property types '" + count_type + " " + item_type + "'");
            } else {
                words >> p.name;
                if (!parseType(type, p.type)) bad("unknown property type '" + type + "'");
            }
            if (p.name.empty()) bad("property without a name");
            elements.back().properties.push_back(p);
        }
        // Any other header line is read as a comment: old exporters (Blender 2.4x) wrote their
        // credit line without the 'comment' keyword. A misspelt element or property line then leaves
        // the data longer than the header declares, which fails below as data left over.
    }
    if (!has_format) throw InputError(path, "the header has no format line");

    Scene scene;
    PolygonSoup soup;
    bool has_vertices = false;
    Reader reader(path, bytes, at, format, line_no + 1);
    std::vector<uint32_t> face;
    for (const Element& e : elements) {
        const bool vertex = e.name == "vertex", faces = e.name == "face";
        int xyz[3] = {-1, -1, -1}, rgb[3] = {-1, -1, -1};
        int indices = -1;
        for (size_t k = 0; k < e.properties.size(); ++k) {
            const Property& p = e.properties[k];
            if (vertex && !p.list && (p.name == "x" || p.name == "y" || p.name == "z")) xyz[p.name[0] - 'x'] = int(k);
            if (vertex && !p.list) {
                const int channel = p.name == "red" ? 0 : p.name == "green" ? 1 : p.name == "blue" ? 2 : -1;
                if (channel >= 0) rgb[channel] = int(k);
            }
            if (faces && p.list && (p.name == "vertex_indices" || p.name == "vertex_index") && isInteger(p.type))
                indices = int(k);
        }
        if (vertex) {
            if (xyz[0] < 0 || xyz[1] < 0 || xyz[2] < 0) throw InputError(path, "element vertex has no x, y and z");
            has_vertices = true;
        }
        if (faces && indices < 0) throw InputError(path, "element face has no integer vertex_indices list");
        if (e.properties.empty()) continue;  // nothing to read, whatever the count
        if (e.count > reader.room(Type::Uint8))
            throw InputError(path, "element " + e.name + ": " + std::to_string(e.count) +
                                       " records do not fit in the rest of the file");
        const bool coloured = vertex && rgb[0] >= 0 && rgb[1] >= 0 && rgb[2] >= 0;
        if (vertex) soup.positions.reserve(size_t(e.count));
        if (coloured) soup.vertex_colours.reserve(size_t(e.count));
        for (uint64_t r = 0; r < e.count; ++r) {
            double c[3] = {0, 0, 0}, colour[3] = {0, 0, 0};
            face.clear();
            for (size_t k = 0; k < e.properties.size(); ++k) {
                const Property& p = e.properties[k];
                if (!p.list) {
                    const double v = reader.read(p.type);
                    for (int a = 0; a < 3; ++a) {
                        if (xyz[a] == int(k)) c[a] = v;
                        if (rgb[a] == int(k)) {
                            const double full = isInteger(p.type) ? (p.type == Type::Uint16 ? 65535.0 : 255.0) : 1.0;
                            colour[a] = std::isfinite(v) ? std::clamp(v / full, 0.0, 1.0) : 0.0;
                        }
                    }
                    continue;
                }
                const std::string where = reader.where();
                const double n = reader.read(p.count_type);
                if (n < 0 || n > double(reader.room(p.type)))
                    throw InputError(path, where + ": " + e.name + " " + std::to_string(r) + ": list of " +
                                               shown(n) + " items does not fit in the file");
                for (uint64_t i = 0; i < uint64_t(n); ++i) {
                    const double v = reader.read(p.type);
                    if (int(k) != indices) continue;
                    if (v < 0 || v >= 4294967295.0)
                        throw InputError(path, where + ": face " + std::to_string(r) + ": vertex index " +
                                                   shown(v) + " out of range");
                    face.push_back(uint32_t(v));
                }
            }
            if (vertex) {
                const glm::vec3 p{float(c[0]), float(c[1]), float(c[2])};
                if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
                    throw InputError(path, "vertex " + std::to_string(soup.positions.size()) + " is not finite (nan or inf)");
                soup.positions.push_back(p);
                if (coloured)
                    soup.vertex_colours.emplace_back(srgbToLinear(float(colour[0])), srgbToLinear(float(colour[1])),
                                                     srgbToLinear(float(colour[2])));
            } else if (faces) {
                if (face.size() == 1) {
                    ++scene.skipped.points;
                } else if (face.size() == 2) {
                    ++scene.skipped.lines;
                } else {
                    soup.addFace(face);
                }
            }
        }
    }
    reader.expectEnd();
    if (!has_vertices && soup.faceCount() > 0) throw InputError(path, "faces but no vertex element");
    for (size_t i = 0; i < soup.corners.size(); ++i)
        if (soup.corners[i] >= soup.positions.size())
            throw InputError(path, "face vertex index " + std::to_string(soup.corners[i]) + " out of range (" +
                                       std::to_string(soup.positions.size()) + " vertices)");
    addPolygonObjects(soup, path, scene);
    return scene;
}

}  // namespace occ
