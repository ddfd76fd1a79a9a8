// SPDX-License-Identifier: MIT
#include "view/camera_path.h"

#include "scene/atomic_file.h"
#include "scene/errors.h"
#include "scene/oss_file.h"
#include "scene/splitmix.h"

#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <charconv>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <stdexcept>

#include <unistd.h>

namespace occ {

// ---- The path file ----------------------------------------------------------------------------

namespace {

constexpr int kFieldCount = 12;
constexpr const char* kFieldNames[kFieldCount] = {"eye.x",    "eye.y",    "eye.z", "target.x",     "target.y", "target.z",
                                                  "up.x",     "up.y",     "up.z",  "fovy_degrees", "near",     "far"};

// Nine significant digits in "%g" style: enough for any float to read back bit-identical. to_chars
// with a precision is specified as printf's %.9g, without printf's dependence on the C locale.
void appendNumber(std::string& out, float x) {
    char text[32];
    const std::to_chars_result r = std::to_chars(text, text + sizeof(text), x, std::chars_format::general, 9);
    out.append(text, r.ptr);
}

void appendLine(std::string& out, const CameraPose& c) {
    const float fields[kFieldCount] = {c.eye.x, c.eye.y, c.eye.z, c.target.x, c.target.y, c.target.z,
                                       c.up.x,  c.up.y,  c.up.z,  c.fovy_degrees, c.near_plane, c.far_plane};
    for (int i = 0; i < kFieldCount; ++i) {
        if (i) out += ' ';
        appendNumber(out, fields[i]);
    }
    out += '\n';
}

std::string systemError() { return std::strerror(errno); }  // before anything else touches errno

// A token as a message can show it: printable, and not a whole line of garbage.
std::string quoted(std::string_view token) {
    std::string shown;
    for (char ch : token.substr(0, 32)) shown += (ch >= 0x20 && ch < 0x7f) ? ch : '?';
    if (token.size() > 32) shown += "...";
    return "'" + shown + "'";
}

bool isBlank(char ch) { return ch == ' ' || ch == '\t' || ch == '\r'; }

// Parses one line; false for a blank or comment line. Throws InputError(path, "line L: ...").
bool parseLine(std::string_view line, uint64_t number, const std::string& path, CameraPose& pose) {
    const auto fail = [&](const std::string& what) { throw InputError(path, "line " + std::to_string(number) + ": " + what); };
    std::vector<std::string_view> tokens;
    for (size_t at = 0; at < line.size();) {
        if (isBlank(line[at])) {
            ++at;
            continue;
        }
        if (tokens.empty() && line[at] == '#') return false;
        size_t end = at;
        while (end < line.size() && !isBlank(line[end])) ++end;
        tokens.push_back(line.substr(at, end - at));
        at = end;
    }
    if (tokens.empty()) return false;
    if (tokens.size() != kFieldCount)
        fail("expected " + std::to_string(kFieldCount) +
             " numbers (eye.xyz target.xyz up.xyz fovy_degrees near far), found " + std::to_string(tokens.size()));

    float fields[kFieldCount];
    for (int i = 0; i < kFieldCount; ++i) {
        std::string_view token = tokens[i];
        const std::string field = "field " + std::to_string(i + 1) + " (" + kFieldNames[i] + ") = " + quoted(token);
        // from_chars takes no '+' sign; people editing a file may write one.
        if (token.size() > 1 && token[0] == '+' && token[1] != '-') token.remove_prefix(1);
        const std::from_chars_result r = std::from_chars(token.data(), token.data() + token.size(), fields[i]);
        if (r.ec == std::errc::result_out_of_range) fail(field + " is outside the float range");
        if (r.ec != std::errc() || r.ptr != token.data() + token.size()) fail(field + " is not a number");
        if (!std::isfinite(fields[i])) fail(field + " is not finite");
    }
    pose.eye = {fields[0], fields[1], fields[2]};
    pose.target = {fields[3], fields[4], fields[5]};
    pose.up = {fields[6], fields[7], fields[8]};
    pose.fovy_degrees = fields[9];
    pose.near_plane = fields[10];
    pose.far_plane = fields[11];
    if (const std::string defect = poseDefect(pose); !defect.empty()) fail(defect);
    return true;
}

}  // namespace

void writeCameraPath(const std::string& path, std::span<const CameraPose> cameras) {
    if (cameras.empty()) throw std::invalid_argument("writeCameraPath: no cameras");
    for (size_t i = 0; i < cameras.size(); ++i)
        if (const std::string defect = poseDefect(cameras[i]); !defect.empty())
            throw std::invalid_argument("writeCameraPath: camera " + std::to_string(i) + ": " + defect);

    AtomicFile file(path);
    std::string text = std::string(kCameraPathHeader) + "\n";
    for (size_t i = 0; i < cameras.size(); ++i) {
        appendLine(text, cameras[i]);
        // In chunks, so that ten million cameras do not need a gigabyte of text at once.
        if (text.size() >= (1u << 20) || i + 1 == cameras.size()) {
            file.write(text);
            text.clear();
        }
    }
    file.commit();
}

std::vector<CameraPose> readCameraPath(const std::string& path) {
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) throw InputError(path, "is a folder, not a camera path file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw InputError(path, "cannot open: " + systemError());
    std::vector<CameraPose> cameras;
    std::string line;
    for (uint64_t number = 1; std::getline(in, line); ++number) {
        CameraPose pose;
        if (parseLine(line, number, path, pose)) cameras.push_back(pose);
    }
    if (in.bad()) throw InputError(path, "cannot read: " + systemError());
    if (cameras.empty()) throw InputError(path, "no cameras: every line is blank or a comment");
    return cameras;
}

double eyePathLength(std::span<const CameraPose> cameras) {
    double length = 0.0;
    for (size_t i = 1; i < cameras.size(); ++i)
        length += glm::length(glm::dvec3(cameras[i].eye) - glm::dvec3(cameras[i - 1].eye));
    return length;
}

// ---- Scenes -----------------------------------------------------------------------------------

PathScene pathSceneOf(const OssFile& file) {
    PathScene scene{file.path(), {}, {}};
    scene.objects.reserve(file.objectCount());
    for (const oss::ObjectDisk& o : file.objects())
        scene.objects.push_back({{o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]}, {o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]}});
    scene.triangles = [&file](uint32_t object, std::vector<glm::vec3>& corners) {
        const oss::ObjectDisk& o = file.objects()[object];
        const glm::mat4 world = glm::make_mat4(o.world);
        const OssFile::MeshView mesh = file.mesh(o.mesh);
        std::vector<glm::vec3> placed(mesh.positions.size());
        for (size_t v = 0; v < placed.size(); ++v) placed[v] = glm::vec3(world * glm::vec4(mesh.positions[v], 1.0f));
        corners.resize(mesh.triangles.size());
        for (size_t k = 0; k < corners.size(); ++k) corners[k] = placed[mesh.triangles[k]];
    };
    return scene;
}

namespace {

struct Box {
    glm::dvec3 min, max;
    glm::dvec3 centre() const { return (min + max) * 0.5; }
    glm::dvec3 size() const { return max - min; }
};

void checkFrames(const char* who, uint32_t frames) {
    if (frames == 0 || frames > kMaxPathFrames)
        throw std::invalid_argument(std::string(who) + ": " + std::to_string(frames) + " frames, expected 1 to " +
                                    std::to_string(kMaxPathFrames));
}

// Union of the objects' AABBs, after checking each.
Box sceneBounds(const PathScene& scene) {
    if (scene.objects.empty()) throw InputError(scene.name, "the scene has no objects");
    Box bounds{glm::dvec3(std::numeric_limits<double>::max()), glm::dvec3(std::numeric_limits<double>::lowest())};
    for (size_t i = 0; i < scene.objects.size(); ++i) {
        const k::Aabb& a = scene.objects[i];
        const glm::dvec3 lo(a.min), hi(a.max);
        for (int axis = 0; axis < 3; ++axis)
            if (!std::isfinite(lo[axis]) || !std::isfinite(hi[axis]) || !(lo[axis] <= hi[axis]))
                throw InputError(scene.name, "object " + std::to_string(i) + ": its AABB is not finite or inverted");
        bounds.min = glm::min(bounds.min, lo);
        bounds.max = glm::max(bounds.max, hi);
    }
    return bounds;
}

// Cameras computed in double may still be unusable in float (a tiny scene far from the origin
// rounds eye onto target); say so instead of writing a file nobody can read.
void checkCameras(const PathScene& scene, const char* what, std::span<const CameraPose> cameras) {
    for (size_t i = 0; i < cameras.size(); ++i)
        if (const std::string defect = poseDefect(cameras[i]); !defect.empty())
            throw InputError(scene.name, std::string(what) + ": camera " + std::to_string(i) + ": " + defect +
                                             " (the scene is too small for float coordinates where it lies)");
}

const glm::vec3 kUp{0.0f, 1.0f, 0.0f};
constexpr float kFovyDegrees = 60.0f;

}  // namespace

// ---- Orbit ------------------------------------------------------------------------------------

namespace {

constexpr double kOrbitMargin = 1.05;         // the sphere's radius, plus 5 %, fills the field of view
constexpr double kOrbitElevationDegrees = 25.0;
constexpr double kOrbitNear = 0.01;           // in radii; the nearest object is >= 0.3 R away

}  // namespace

std::vector<CameraPose> orbitPath(const PathScene& scene, uint32_t frames) {
    checkFrames("orbitPath", frames);
    const Box bounds = sceneBounds(scene);
    const glm::dvec3 centre = bounds.centre();
    const double radius = glm::length(bounds.size()) / 2;
    if (!(radius > 0.0)) throw InputError(scene.name, "orbit: the scene's bounds are a single point");
    // The whole bounding sphere in view: at distance d its silhouette subtends 2 asin(R / d),
    // which the vertical field of view (the narrower one, at aspect >= 1) must hold.
    const double distance = kOrbitMargin * radius / std::sin(kFovyDegrees / 2 * std::numbers::pi / 180.0);
    const double elevation = kOrbitElevationDegrees * std::numbers::pi / 180.0;

    std::vector<CameraPose> cameras(frames);
    for (uint32_t i = 0; i < frames; ++i) {
        const double azimuth = 2.0 * std::numbers::pi * double(i) / double(frames);
        // Counter-clockwise seen from +y (looking down -y, x right, z down the screen).
        const glm::dvec3 offset(std::cos(elevation) * std::cos(azimuth), std::sin(elevation),
                                -std::cos(elevation) * std::sin(azimuth));
        CameraPose& c = cameras[i];
        c.eye = glm::vec3(centre + distance * offset);
        c.target = glm::vec3(centre);
        c.up = kUp;
        c.fovy_degrees = kFovyDegrees;
        c.near_plane = float(kOrbitNear * radius);
        c.far_plane = float(distance + 2.0 * radius);
    }
    checkCameras(scene, "orbit", cameras);
    return cameras;
}

// ---- Walk -------------------------------------------------------------------------------------

namespace {

// Floors and eye height (the plant's units are metres; see import/plant.h).
constexpr double kFlatRatio = 0.05;        // a floor slab's height is at most this share of its width
constexpr double kFloorCoverage = 0.25;    // of the scene's x/z footprint, by one floor's slabs together
constexpr double kEyeAboveFloor = 1.7;
constexpr double kFloorCell = 0.25;
constexpr uint32_t kMaxGridCells = 2048;   // per side, for floors; larger scenes get a window
// Scenes without floors.
constexpr uint32_t kGenericCells = 512;    // along the longer of x and z: 50 per tile of a 10-wide lattice
constexpr int kCandidateHeights = 16;
constexpr int kNearbyCells = 16;           // an object this close along a ray surrounds a cell
// The walkable region.
constexpr uint16_t kWalkClearance = 3;     // cells from the nearest occupied cell or the grid's edge
constexpr uint16_t kEyeClearance = 2;      // what the smoothed path keeps: one free cell in between
static_assert(kWalkClearance >= kEyeClearance + 1, "smoothWalk needs room to move points");
constexpr size_t kMinWalkCells = 64;
// The random walk, in cells.
constexpr int kTurnDistance = 8;     // start turning when an obstacle is this close ahead
constexpr int kRunCap = 48;          // how far the walker looks along a direction
constexpr int kOpenRun = 16;         // a side way this long counts as open
constexpr int kExploreAfter = 32;    // straight steps before a side way tempts the walker
constexpr double kExploreChance = 0.02;  // per cell, of taking an open side way then
constexpr int kPeek = 6;             // visited cells this far along a way make it less attractive
// Smoothing and cameras.
constexpr double kSmoothSigma = 3.0;  // in walk steps
constexpr double kSpeed = kWalkCellsPerFrame;
constexpr double kLookAhead = 6.0;    // cells
constexpr double kMaxTurnDegrees = kWalkMaxTurnDegreesPerFrame;
constexpr double kNearInCells = 0.2;

// The walk's random choices, on our own generator (scene/splitmix.h).
class Random : public SplitMix64 {
public:
    using SplitMix64::SplitMix64;
    double uniform() { return double(next() >> 11) * 0x1.0p-53; }  // [0, 1)
    uint64_t below(uint64_t n) { return uint64_t(uniform() * double(n)); }
};

// Directions of rays and of the walk in cells, in 45 degree steps from +x towards +z.
constexpr int kStepX[8] = {1, 1, 0, -1, -1, -1, 0, 1};
constexpr int kStepZ[8] = {0, 1, 1, 1, 0, -1, -1, -1};
int turned(int direction, int by) { return ((direction + by) % 8 + 8) % 8; }

// Square cells over x/z: cell (i, j) covers x in x0 + [i, i + 1) cell, z in z0 + [j, j + 1) cell.
struct Grid {
    double x0 = 0, z0 = 0, cell = 1;
    int nx = 0, nz = 0;

    size_t count() const { return size_t(nx) * size_t(nz); }
    size_t at(int i, int j) const { return size_t(j) * size_t(nx) + size_t(i); }
    bool inside(int i, int j) const { return i >= 0 && j >= 0 && i < nx && j < nz; }
    // Monotone in x, so a point inside a box always maps into the box's cell range.
    int64_t column(double x) const { return index(std::floor((x - x0) / cell)); }
    int64_t row(double z) const { return index(std::floor((z - z0) / cell)); }
    // Cells whose centre lies in [lo, hi] along x (or z with z0).
    int64_t firstCentre(double lo, double origin) const { return index(std::ceil((lo - origin) / cell - 0.5)); }
    int64_t lastCentre(double hi, double origin) const { return index(std::floor((hi - origin) / cell - 0.5)); }

    // Far outside cells stay far outside (and defined: a float scene may span 1e38 / 0.25 cells).
    static int64_t index(double cells) { return int64_t(std::clamp(cells, -1e15, 1e15)); }
};

// A grid of at most max_cells per side centred on the bounds' x/z centre, never past the bounds.
Grid centredGrid(const Box& bounds, double cell, uint32_t max_cells) {
    Grid g;
    g.cell = cell;
    const glm::dvec3 size = bounds.size(), centre = bounds.centre();
    g.nx = int(std::min<double>(std::floor(size.x / cell), max_cells));
    g.nz = int(std::min<double>(std::floor(size.z / cell), max_cells));
    g.x0 = centre.x - g.nx * cell / 2;
    g.z0 = centre.z - g.nz * cell / 2;
    return g;
}

// Adds 1 over the cell rectangle [i0, i1] x [j0, j1] (clipped) of a (nx+1) x (nz+1)
// difference array; prefix sums turn it into per-cell counts, so each box costs O(1).
void addRectangle(const Grid& g, std::vector<int64_t>& diff, int64_t i0, int64_t i1, int64_t j0, int64_t j1) {
    i0 = std::max<int64_t>(i0, 0), j0 = std::max<int64_t>(j0, 0);
    i1 = std::min<int64_t>(i1, g.nx - 1), j1 = std::min<int64_t>(j1, g.nz - 1);
    if (i0 > i1 || j0 > j1) return;
    const size_t w = size_t(g.nx) + 1;
    diff[size_t(j0) * w + size_t(i0)] += 1;
    diff[size_t(j0) * w + size_t(i1) + 1] -= 1;
    diff[size_t(j1 + 1) * w + size_t(i0)] -= 1;
    diff[size_t(j1 + 1) * w + size_t(i1) + 1] += 1;
}

std::vector<uint8_t> cellsCovered(const Grid& g, const std::vector<int64_t>& diff) {
    const size_t w = size_t(g.nx) + 1;
    std::vector<int64_t> sum(diff);
    std::vector<uint8_t> covered(g.count());
    for (int j = 0; j < g.nz; ++j)
        for (int i = 0; i < g.nx; ++i) {
            const size_t k = size_t(j) * w + size_t(i);
            if (i > 0) sum[k] += sum[k - 1];
            if (j > 0) sum[k] += sum[k - w];
            if (i > 0 && j > 0) sum[k] -= sum[k - w - 1];
            covered[g.at(i, j)] = sum[k] > 0;
        }
    return covered;
}

// Appends to `diff` the cells of the x/z bounding rectangle of the part of triangle (a, b, c)
// with y in [y_lo, y_hi] (Sutherland-Hodgman against the two planes).
void addTriangleSlice(const Grid& g, std::vector<int64_t>& diff, const glm::dvec3& a, const glm::dvec3& b,
                      const glm::dvec3& c, double y_lo, double y_hi) {
    glm::dvec3 polygon[5] = {a, b, c}, clipped[5];
    int count = 3;
    for (int side = 0; side < 2; ++side) {
        const auto keep = [&](const glm::dvec3& p) { return side == 0 ? p.y >= y_lo : p.y <= y_hi; };
        const double plane = side == 0 ? y_lo : y_hi;
        int kept = 0;
        for (int k = 0; k < count; ++k) {
            const glm::dvec3 &p = polygon[k], &q = polygon[(k + 1) % count];
            if (keep(p)) clipped[kept++] = p;
            if (keep(p) != keep(q)) clipped[kept++] = p + (q - p) * ((plane - p.y) / (q.y - p.y));
        }
        count = kept;
        std::copy(clipped, clipped + kept, polygon);
        if (count == 0) return;
    }
    double x_min = polygon[0].x, x_max = x_min, z_min = polygon[0].z, z_max = z_min;
    for (int k = 1; k < count; ++k) {
        x_min = std::min(x_min, polygon[k].x), x_max = std::max(x_max, polygon[k].x);
        z_min = std::min(z_min, polygon[k].z), z_max = std::max(z_max, polygon[k].z);
    }
    addRectangle(g, diff, g.column(x_min), g.column(x_max), g.row(z_min), g.row(z_max));
}

// Cells the eye must keep clear of, for objects whose AABB's y range overlaps (y_lo, y_hi): every
// cell their AABB touches (boundaries included), or with Avoid::triangles every cell under the
// x/z bounding rectangle of a triangle's part inside the slab.
std::vector<uint8_t> occupancy(const Grid& g, const PathScene& scene, Avoid avoid, double y_lo, double y_hi) {
    std::vector<int64_t> diff((size_t(g.nx) + 1) * (size_t(g.nz) + 1));
    std::vector<glm::vec3> corners;
    for (uint32_t i = 0; i < scene.objects.size(); ++i) {
        const k::Aabb& a = scene.objects[i];
        if (!(double(a.min.y) < y_hi && double(a.max.y) > y_lo)) continue;
        if (avoid == Avoid::boxes) {
            addRectangle(g, diff, g.column(a.min.x), g.column(a.max.x), g.row(a.min.z), g.row(a.max.z));
            continue;
        }
        if (g.column(a.max.x) < 0 || g.column(a.min.x) >= g.nx || g.row(a.max.z) < 0 || g.row(a.min.z) >= g.nz) continue;
        corners.clear();
        scene.triangles(i, corners);
        for (size_t k = 0; k + 2 < corners.size(); k += 3)
            addTriangleSlice(g, diff, corners[k], corners[k + 1], corners[k + 2], y_lo, y_hi);
    }
    return cellsCovered(g, diff);
}

// Chebyshev distance in cells from each cell to the nearest occupied cell or to the outside of
// the grid (a free cell on the edge is 1 away). Two chamfer passes with unit weights on all 8
// neighbours are exact for this metric (Rosenfeld & Pfaltz, "Distance functions on digital
// pictures", 1968).
std::vector<uint16_t> clearance(const Grid& g, const std::vector<uint8_t>& occupied) {
    std::vector<uint16_t> d(g.count());
    const auto get = [&](int i, int j) -> uint32_t { return g.inside(i, j) ? d[g.at(i, j)] : 0u; };
    for (int j = 0; j < g.nz; ++j)
        for (int i = 0; i < g.nx; ++i) {
            if (occupied[g.at(i, j)]) continue;
            const uint32_t m = std::min({get(i - 1, j - 1), get(i, j - 1), get(i + 1, j - 1), get(i - 1, j)});
            d[g.at(i, j)] = uint16_t(std::min<uint32_t>(m + 1, UINT16_MAX));
        }
    for (int j = g.nz - 1; j >= 0; --j)
        for (int i = g.nx - 1; i >= 0; --i) {
            if (occupied[g.at(i, j)]) continue;
            const uint32_t m = std::min({get(i + 1, j + 1), get(i, j + 1), get(i - 1, j + 1), get(i + 1, j)});
            d[g.at(i, j)] = uint16_t(std::min<uint32_t>({uint32_t(d[g.at(i, j)]), m + 1, UINT16_MAX}));
        }
    return d;
}

// How a cell sits among the occupied ones, from the eight rays (axes and diagonals) leaving it.
struct Surroundings {
    // At least kEnclosingRays rays meet an occupied cell: inside the scene rather than in the
    // empty margin around it. Streets between the rows and columns of a lattice qualify (two
    // sides and four diagonals), and so do their crossings (four diagonals); a cell beside the
    // lattice sees it along at most three rays.
    std::vector<uint8_t> enclosed;
    std::vector<uint8_t> nearby;  // rays meeting an occupied cell within kNearbyCells, 0 to 8
};

Surroundings surroundings(const Grid& g, const std::vector<uint8_t>& occupied) {
    constexpr int kEnclosingRays = 4;
    std::vector<uint8_t> hit(g.count()), near(g.count());  // bit per ray
    std::vector<uint16_t> distance(g.count());             // to the first occupied cell along the ray, 0 = none
    for (int ray = 0; ray < 8; ++ray) {
        const int dx = kStepX[ray], dz = kStepZ[ray];
        // Visit each cell after the cell the ray enters next, so that one step settles it.
        for (int jj = 0; jj < g.nz; ++jj)
            for (int ii = 0; ii < g.nx; ++ii) {
                const int i = dx > 0 ? g.nx - 1 - ii : ii, j = dz > 0 ? g.nz - 1 - jj : jj;
                const size_t c = g.at(i, j);
                uint32_t d = 0;
                if (g.inside(i + dx, j + dz)) {
                    const size_t next = g.at(i + dx, j + dz);
                    d = occupied[next] ? 1 : distance[next] ? std::min<uint32_t>(distance[next] + 1, UINT16_MAX) : 0;
                }
                distance[c] = uint16_t(d);
                if (d > 0) hit[c] |= uint8_t(1 << ray);
                if (d > 0 && d <= kNearbyCells) near[c] |= uint8_t(1 << ray);
            }
    }
    Surroundings s{std::vector<uint8_t>(g.count()), std::vector<uint8_t>(g.count())};
    for (size_t c = 0; c < g.count(); ++c) {
        s.enclosed[c] = std::popcount(hit[c]) >= kEnclosingRays;
        s.nearby[c] = uint8_t(std::popcount(near[c]));
    }
    return s;
}

// The largest 4-connected set of walkable cells, in breadth-first order from its lowest index
// (ties go to the component found first).
std::vector<uint32_t> largestRegion(const Grid& g, const std::vector<uint8_t>& walkable) {
    std::vector<uint8_t> seen(g.count());
    std::vector<uint32_t> best, region;
    for (size_t start = 0; start < g.count(); ++start) {
        if (!walkable[start] || seen[start]) continue;
        region.clear();
        region.push_back(uint32_t(start));
        seen[start] = 1;
        for (size_t k = 0; k < region.size(); ++k) {
            const int i = int(region[k] % uint32_t(g.nx)), j = int(region[k] / uint32_t(g.nx));
            const int ni[4] = {i + 1, i - 1, i, i}, nj[4] = {j, j, j + 1, j - 1};
            for (int n = 0; n < 4; ++n) {
                if (!g.inside(ni[n], nj[n])) continue;
                const size_t c = g.at(ni[n], nj[n]);
                if (walkable[c] && !seen[c]) seen[c] = 1, region.push_back(uint32_t(c));
            }
        }
        if (region.size() > best.size()) best.swap(region);
    }
    return best;
}

// One candidate eye height, rasterized.
struct Plan {
    Grid grid;
    double eye_y = 0;
    bool on_floor = false;
    double floor_top = 0;
    std::vector<uint16_t> clear;
    std::vector<uint8_t> walkable;
    std::vector<uint32_t> region;  // where the walk starts and stays
};

// A floor: flat AABBs whose tops agree, covering enough of the footprint together.
struct Floor {
    double top = 0;
    std::vector<uint32_t> slabs;
};

std::vector<Floor> findFloors(std::span<const k::Aabb> objects, const Box& bounds) {
    std::vector<uint32_t> flat;
    for (uint32_t i = 0; i < objects.size(); ++i) {
        const glm::dvec3 size = glm::dvec3(objects[i].max) - glm::dvec3(objects[i].min);
        const double width = std::min(size.x, size.z);
        if (width > 0 && size.y <= kFlatRatio * width) flat.push_back(i);
    }
    std::sort(flat.begin(), flat.end(), [&](uint32_t a, uint32_t b) {
        return objects[a].max.y != objects[b].max.y ? objects[a].max.y < objects[b].max.y : a < b;
    });
    // Tops of one floor's slabs differ by rounding only; random heights (cable trays) must not chain.
    const double tolerance = 1e-6 * glm::length(bounds.size());
    const double footprint = bounds.size().x * bounds.size().z;
    std::vector<Floor> floors;
    for (size_t first = 0; first < flat.size();) {
        size_t last = first + 1;
        while (last < flat.size() && double(objects[flat[last]].max.y) - double(objects[flat[last - 1]].max.y) <= tolerance)
            ++last;
        double area = 0;
        Floor floor{objects[flat[last - 1]].max.y, {}};  // the highest top of the group
        for (size_t k = first; k < last; ++k) {
            const k::Aabb& a = objects[flat[k]];
            area += (double(a.max.x) - a.min.x) * (double(a.max.z) - a.min.z);
            floor.slabs.push_back(flat[k]);
        }
        if (area >= kFloorCoverage * footprint) floors.push_back(std::move(floor));
        first = last;
    }
    return floors;
}

// Walkable cells: far enough from everything, and `allowed`.
void finishPlan(Plan& plan, const std::vector<uint8_t>& occupied, const std::vector<uint8_t>& allowed) {
    plan.clear = clearance(plan.grid, occupied);
    plan.walkable.assign(plan.grid.count(), 0);
    for (size_t c = 0; c < plan.grid.count(); ++c) plan.walkable[c] = allowed[c] && plan.clear[c] >= kWalkClearance;
    plan.region = largestRegion(plan.grid, plan.walkable);
}

// The lowest floor with a walkable region at eye height inside the bounds, if any.
bool planOnFloor(const PathScene& scene, Avoid avoid, const Box& bounds, Plan& plan) {
    for (const Floor& floor : findFloors(scene.objects, bounds)) {
        const double eye_y = floor.top + kEyeAboveFloor;
        if (!(eye_y < bounds.max.y)) continue;
        Plan candidate;
        candidate.grid = centredGrid(bounds, kFloorCell, kMaxGridCells);
        const Grid& g = candidate.grid;
        if (g.nx == 0 || g.nz == 0) continue;
        candidate.eye_y = eye_y;
        candidate.on_floor = true;
        candidate.floor_top = floor.top;
        // Over the floor: cells whose centre lies on one of its slabs (closed, so that abutting
        // slabs leave no seam).
        std::vector<int64_t> diff((size_t(g.nx) + 1) * (size_t(g.nz) + 1));
        for (uint32_t s : floor.slabs) {
            const k::Aabb& a = scene.objects[s];
            addRectangle(g, diff, g.firstCentre(a.min.x, g.x0), g.lastCentre(a.max.x, g.x0), g.firstCentre(a.min.z, g.z0),
                         g.lastCentre(a.max.z, g.z0));
        }
        finishPlan(candidate, occupancy(g, scene, avoid, eye_y - g.cell, eye_y + g.cell), cellsCovered(g, diff));
        if (candidate.region.size() >= kMinWalkCells) {
            plan = std::move(candidate);
            return true;
        }
    }
    return false;
}

// Among kCandidateHeights cuts, the one whose largest enclosed walkable region is most
// surrounded: the sum over its cells of the rays that meet an object within kNearbyCells.
// Without any enclosed region, the cut with the largest walkable region.
bool planAtBestHeight(const PathScene& scene, Avoid avoid, const Box& bounds, Plan& plan) {
    const double longest = std::max(bounds.size().x, bounds.size().z);
    if (!(longest > 0)) return false;
    const Grid g = centredGrid(bounds, longest / kGenericCells, kGenericCells);
    if (g.nx == 0 || g.nz == 0) return false;
    Plan best_enclosed, best_open;
    uint64_t best_score = 0;
    for (int h = 0; h < kCandidateHeights; ++h) {
        const double eye_y = bounds.min.y + bounds.size().y * (h + 0.5) / kCandidateHeights;
        const std::vector<uint8_t> occupied = occupancy(g, scene, avoid, eye_y - g.cell, eye_y + g.cell);
        const Surroundings around = surroundings(g, occupied);
        Plan enclosed{g, eye_y, false, 0.0, {}, {}, {}};
        finishPlan(enclosed, occupied, around.enclosed);
        uint64_t score = 0;
        for (uint32_t c : enclosed.region) score += around.nearby[c];
        if (enclosed.region.size() >= kMinWalkCells && score > best_score)
            best_score = score, best_enclosed = std::move(enclosed);
        Plan open{g, eye_y, false, 0.0, {}, {}, {}};
        finishPlan(open, occupied, std::vector<uint8_t>(g.count(), 1));
        if (open.region.size() > best_open.region.size()) best_open = std::move(open);
    }
    if (best_score > 0) plan = std::move(best_enclosed);
    else if (best_open.region.size() >= kMinWalkCells) plan = std::move(best_open);
    else return false;
    return true;
}

// A random walk over the walkable cells that prefers to go straight and turns by at most 45
// degrees per cell (unless cornered), towards the most open and least visited way.
class Walker {
public:
    Walker(const Plan& plan, uint64_t seed) : plan_(plan), random_(seed), visits_(plan.grid.count()) {
        const uint32_t start = plan.region[random_.below(plan.region.size())];
        i_ = int(start % uint32_t(plan.grid.nx));
        j_ = int(start / uint32_t(plan.grid.nx));
        int longest = -1;
        for (int d = 0; d < 8; ++d) {
            const int r = run(d);
            if (r > longest) longest = r, direction_ = d;
        }
        goal_ = direction_;
        visits_[plan.grid.at(i_, j_)] = 1;
    }

    glm::dvec2 position() const { return {i_ + 0.5, j_ + 0.5}; }  // in cells

    void step() {
        if (goal_ == direction_) {
            if (run(direction_) < kTurnDistance) {
                chooseTurn();
            } else if (straight_ >= kExploreAfter && random_.uniform() < kExploreChance) {
                const bool open_left = opensUp(turned(direction_, 2));
                const bool open_right = opensUp(turned(direction_, -2));
                if (open_left || open_right) {
                    turn_sign_ = open_left && open_right ? (random_.below(2) ? 1 : -1) : open_left ? 1 : -1;
                    goal_ = turned(direction_, 2 * turn_sign_);
                }
            }
        }
        int next = towardsGoal();
        if (!canStep(next)) {
            // Cornered: the steppable direction closest to the goal (an axis neighbour always
            // exists, the region being 4-connected and larger than one cell).
            int best = -1, best_distance = 9;
            for (int by : {0, 1, -1, 2, -2, 3, -3, 4}) {
                const int d = turned(goal_, by);
                if (canStep(d) && std::abs(by) < best_distance) best = d, best_distance = std::abs(by);
            }
            if (best < 0) throw std::logic_error("walkPath: the walker is stuck in a single cell");
            next = goal_ = best;
        }
        i_ += kStepX[next];
        j_ += kStepZ[next];
        straight_ = next == direction_ ? straight_ + 1 : 0;
        direction_ = next;
        uint16_t& v = visits_[plan_.grid.at(i_, j_)];
        v = uint16_t(std::min<int>(v + 1, UINT16_MAX));
    }

private:
    bool walkable(int i, int j) const { return plan_.grid.inside(i, j) && plan_.walkable[plan_.grid.at(i, j)]; }

    // Diagonal steps also need both axis neighbours, so a step never cuts an obstacle's corner.
    bool canStep(int i, int j, int d) const {
        if (!walkable(i + kStepX[d], j + kStepZ[d])) return false;
        return d % 2 == 0 || (walkable(i + kStepX[d], j) && walkable(i, j + kStepZ[d]));
    }
    bool canStep(int d) const { return canStep(i_, j_, d); }

    // A side way worth exploring: open for kOpenRun cells, and not walked at its start.
    bool opensUp(int d) const {
        return run(d) >= kOpenRun && visits_[plan_.grid.at(i_ + kPeek * kStepX[d], j_ + kPeek * kStepZ[d])] == 0;
    }

    int run(int d) const {
        int i = i_, j = j_, steps = 0;
        while (steps < kRunCap && canStep(i, j, d)) i += kStepX[d], j += kStepZ[d], ++steps;
        return steps;
    }

    // An obstacle ahead: turn by 45 or 90 degrees into the most open way that is open for
    // kTurnDistance, else by up to 135 degrees into any way, else round. A way counts less the
    // more of its first cells were walked before, so the walk explores instead of pacing.
    void chooseTurn() {
        double best_score = -1;
        int best = 0;
        for (int widest : {2, 3}) {
            for (int by = -widest; by <= widest; ++by) {
                const int d = turned(direction_, by);
                const int r = run(d);
                if (by == 0 || r == 0 || (widest == 2 && r < kTurnDistance)) continue;
                int visited = 0;
                for (int k = 1; k <= std::min(r, kPeek); ++k) visited += visits_[plan_.grid.at(i_ + k * kStepX[d], j_ + k * kStepZ[d])] > 0;
                const double score = r * (1.0 - 0.75 * visited / std::min(r, kPeek)) + random_.uniform();
                if (score > best_score) best_score = score, best = by;
            }
            if (best != 0) break;
        }
        if (best == 0) {
            goal_ = turned(direction_, 4);
            turn_sign_ = random_.below(2) ? 1 : -1;
        } else {
            goal_ = turned(direction_, best);
            turn_sign_ = best > 0 ? 1 : -1;
        }
    }

    int towardsGoal() const {
        const int delta = turned(goal_, -direction_);
        if (delta == 0 || delta == 1 || delta == 7) return goal_;
        return turned(direction_, delta == 4 ? turn_sign_ : delta < 4 ? 1 : -1);
    }

    const Plan& plan_;
    Random random_;
    std::vector<uint16_t> visits_;
    int i_ = 0, j_ = 0, direction_ = 0, goal_ = 0, turn_sign_ = 1;
    int straight_ = 0;  // steps since the last turn
};

// Gaussian low-pass of the walk, each point's displacement limited (in the max norm) to what its
// cell and its neighbours' cells allow: a point q displaced by at most c - 3 cells from a cell of
// clearance c >= 3, and every point of a segment between two such points, lies in a cell of
// clearance >= 2 (the segment between adjacent cell centres stays within half a cell of one of
// them, and c - 3 + 1/2 rounds to at most c - 2 cells away).
std::vector<glm::dvec2> smoothWalk(const Plan& plan, const std::vector<glm::dvec2>& walk) {
    const int reach = int(std::ceil(3 * kSmoothSigma));
    std::vector<double> weights(size_t(2 * reach + 1));
    double total = 0;
    for (int k = -reach; k <= reach; ++k) total += weights[size_t(k + reach)] = std::exp(-0.5 * k * k / (kSmoothSigma * kSmoothSigma));
    for (double& w : weights) w /= total;

    const auto clear = [&](size_t k) {
        const glm::dvec2 p = walk[std::min(k, walk.size() - 1)];
        return int(plan.clear[plan.grid.at(int(p.x), int(p.y))]);
    };
    const int n = int(walk.size());
    std::vector<glm::dvec2> smooth(walk.size());
    for (int k = 0; k < n; ++k) {
        glm::dvec2 average(0.0);
        for (int t = -reach; t <= reach; ++t) average += weights[size_t(t + reach)] * walk[size_t(std::clamp(k + t, 0, n - 1))];
        const int room = std::min({clear(size_t(std::max(k - 1, 0))), clear(size_t(k)), clear(size_t(k + 1))});
        const double allowed = std::max(0, room - (kEyeClearance + 1));
        glm::dvec2 shift = average - walk[size_t(k)];
        const double reach_max = std::max(std::abs(shift.x), std::abs(shift.y));
        if (reach_max > allowed) shift *= allowed / reach_max;
        smooth[size_t(k)] = walk[size_t(k)] + shift;
    }
    return smooth;
}

// Positions along a polyline by arc length, for arc lengths that only grow.
class ArcCursor {
public:
    explicit ArcCursor(const std::vector<glm::dvec2>& points) : points_(points) {}
    double segmentEnd() const { return start_ + glm::length(points_[segment_ + 1] - points_[segment_]); }
    glm::dvec2 at(double s) {
        while (segment_ + 2 < points_.size() && s > segmentEnd()) start_ = segmentEnd(), ++segment_;
        const glm::dvec2 a = points_[segment_], b = points_[segment_ + 1];
        const double length = glm::length(b - a);
        const double t = length > 0 ? std::clamp((s - start_) / length, 0.0, 1.0) : 0.0;
        return a + t * (b - a);
    }

private:
    const std::vector<glm::dvec2>& points_;
    size_t segment_ = 0;
    double start_ = 0;
};

double polylineLength(const std::vector<glm::dvec2>& points) {
    double length = 0;
    for (size_t k = 1; k < points.size(); ++k) length += glm::length(points[k] - points[k - 1]);
    return length;
}

double wrapAngle(double a) {
    while (a > std::numbers::pi) a -= 2 * std::numbers::pi;
    while (a <= -std::numbers::pi) a += 2 * std::numbers::pi;
    return a;
}

}  // namespace

WalkPath walkPath(const PathScene& scene, uint32_t frames, uint64_t seed, Avoid avoid) {
    checkFrames("walkPath", frames);
    const Box bounds = sceneBounds(scene);
    Plan plan;
    if (avoid == Avoid::triangles && !scene.triangles)
        throw std::invalid_argument("walkPath: Avoid::triangles needs the scene's triangles");
    if (!planOnFloor(scene, avoid, bounds, plan) && !planAtBestHeight(scene, avoid, bounds, plan))
        throw InputError(scene.name, "walk: no free region of " + std::to_string(kMinWalkCells) +
                                         " cells or more at eye height inside the scene's bounds, at any height tried");
    const Grid& g = plan.grid;

    // Walk until the smoothed path covers every frame plus the look-ahead of the last one.
    const double needed = (frames - 1) * kSpeed + kLookAhead;
    Walker walker(plan, seed);
    std::vector<glm::dvec2> walk{walker.position()};
    std::vector<glm::dvec2> smooth;
    for (double target = needed * 1.25 + 8 * kSmoothSigma;; target *= 2) {
        for (double length = polylineLength(walk); length < target;) {
            walker.step();
            walk.push_back(walker.position());
            length += glm::length(walk.back() - walk[walk.size() - 2]);
        }
        smooth = smoothWalk(plan, walk);
        if (polylineLength(smooth) >= needed) break;
    }

    WalkPath result;
    result.eye_height = float(plan.eye_y);
    result.on_floor = plan.on_floor;
    result.floor_top = float(plan.floor_top);
    result.cell_size = float(g.cell);
    result.grid_x = uint32_t(g.nx);
    result.grid_z = uint32_t(g.nz);
    result.free_cells = plan.region.size();
    result.cameras.resize(frames);

    const auto world = [&](const glm::dvec2& p) { return glm::dvec3(g.x0 + p.x * g.cell, plan.eye_y, g.z0 + p.y * g.cell); };
    const double near_plane = kNearInCells * g.cell, far_plane = glm::length(bounds.size());
    const double max_turn = kMaxTurnDegrees * std::numbers::pi / 180;
    ArcCursor eye_cursor(smooth), ahead_cursor(smooth);
    double heading = 0;
    for (uint32_t f = 0; f < frames; ++f) {
        const double s = f * kSpeed;
        const glm::dvec2 eye = eye_cursor.at(s), ahead = ahead_cursor.at(s + kLookAhead);
        const glm::dvec2 chord = ahead - eye;
        // On a cusp (a dead end the walk had to turn round in) the chord can vanish: keep the heading.
        const double wanted = glm::length(chord) > 1e-9 ? std::atan2(chord.y, chord.x) : heading;
        heading = f == 0 ? wanted : wrapAngle(heading + std::clamp(wrapAngle(wanted - heading), -max_turn, max_turn));
        const glm::dvec2 look = eye + kLookAhead * glm::dvec2(std::cos(heading), std::sin(heading));
        CameraPose& c = result.cameras[f];
        c.eye = glm::vec3(world(eye));
        c.target = glm::vec3(world(look));
        c.up = kUp;
        c.fovy_degrees = kFovyDegrees;
        c.near_plane = float(near_plane);
        c.far_plane = float(far_plane);
    }
    checkCameras(scene, "walk", result.cameras);

    // The promise of the header, checked on the floats written: each eye inside the bounds and in
    // a free cell (Grid::column and row are monotone, so a point inside an AABB or a triangle's
    // rectangle in the slab maps to one of the cells it occupies).
    for (uint32_t f = 0; f < frames; ++f) {
        const glm::dvec3 eye(result.cameras[f].eye);
        const int64_t i = g.column(eye.x), j = g.row(eye.z);
        const bool in_grid = i >= 0 && j >= 0 && i < g.nx && j < g.nz;
        if (!in_grid || plan.clear[g.at(int(i), int(j))] < 1 || glm::any(glm::lessThan(eye, bounds.min)) ||
            glm::any(glm::greaterThan(eye, bounds.max)))
            throw std::logic_error("walkPath: camera " + std::to_string(f) + " left the free space");
    }
    return result;
}

}  // namespace occ
