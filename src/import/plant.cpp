// SPDX-License-Identifier: MIT
#include "import/plant.h"

#include "import/glb_writer.h"

#include "scene/errors.h"
#include "scene/splitmix.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace occ {
namespace {

constexpr uint32_t kObjectsPerBayFloor = 40;
constexpr uint32_t kMaxFloors = 6;
// One object of 15-20 K triangles per this many bay-floors (about one per 1000 objects): the
// heavy tail that per-object LOD and the triangle budget have to cope with.
constexpr uint64_t kHeroEvery = 25;
constexpr uint32_t kHeroMinTriangles = 16'500;
constexpr uint32_t kHeroMaxTriangles = 19'900;

// Equipment stays this far inside the bay edges, clear of columns and walls.
constexpr float kQuadrantInset = 0.6f;
// Each quadrant's floor is a 3 x 3 grid of cells that equipment claims, so nothing overlaps.
constexpr uint32_t kCellsPerSide = 3;
constexpr uint32_t kCellsPerQuadrant = kCellsPerSide * kCellsPerSide;
constexpr float kWallThickness = 0.25f;
constexpr float kGirderDepth = 0.5f;
// Heights above the floor where pipes run horizontally. The lowest point of an elbow is the run
// height minus bend radius (3 r) minus pipe radius r <= 0.3 m, so 3.5 m keeps it above 2.2 m.
constexpr float kRackLow = 3.5f;
constexpr float kRackHigh = 4.6f;
constexpr float kTrayLow = 4.3f;
constexpr float kTrayHigh = 4.75f;
// Straight part a route leg keeps beyond its elbows, so no two frames coincide.
constexpr float kMinStraight = 0.1f;
// Routes stop this far inside the building's outline.
constexpr float kBuildingMargin = 0.5f;

const glm::vec3 kUp{0.0f, 1.0f, 0.0f};
const glm::vec3 kDown{0.0f, -1.0f, 0.0f};
const glm::vec3 kAlongX{1.0f, 0.0f, 0.0f};
const glm::vec3 kAlongZ{0.0f, 0.0f, 1.0f};

const glm::vec4 kSlabColour{0.55f, 0.55f, 0.53f, 1.0f};
const glm::vec4 kWallColour{0.78f, 0.76f, 0.70f, 1.0f};
const glm::vec4 kConcreteColour{0.64f, 0.64f, 0.62f, 1.0f};
const glm::vec4 kSteelColour{0.85f, 0.55f, 0.15f, 1.0f};
const glm::vec4 kMotorColour{0.20f, 0.30f, 0.70f, 1.0f};
const glm::vec4 kTrayColour{0.70f, 0.72f, 0.75f, 1.0f};
const glm::vec4 kCopperColour{0.72f, 0.45f, 0.20f, 1.0f};
const std::array<glm::vec4, 2> kTankColours{{{0.92f, 0.92f, 0.90f, 1.0f}, {0.25f, 0.45f, 0.75f, 1.0f}}};
const std::array<glm::vec4, 3> kEquipmentColours{
    {{0.30f, 0.55f, 0.35f, 1.0f}, {0.45f, 0.50f, 0.60f, 1.0f}, {0.85f, 0.80f, 0.60f, 1.0f}}};
// Process pipes by service colour: yellow gas, green water, red fire, grey, blue air, orange.
const std::array<glm::vec4, 6> kPipeColours{{{0.95f, 0.80f, 0.10f, 1.0f},
                                             {0.20f, 0.60f, 0.30f, 1.0f},
                                             {0.80f, 0.15f, 0.10f, 1.0f},
                                             {0.55f, 0.57f, 0.60f, 1.0f},
                                             {0.30f, 0.50f, 0.85f, 1.0f},
                                             {0.95f, 0.50f, 0.10f, 1.0f}}};

// The plant's random choices, on our own generator (scene/splitmix.h).
class Random : public SplitMix64 {
public:
    using SplitMix64::SplitMix64;
    float unit() { return float(next() >> 40) * 0x1p-24f; }  // [0, 1)
    float uniform(float lo, float hi) { return lo + (hi - lo) * unit(); }
    // Sizes and tessellations in a plant are heavy-tailed: many small pipes, few large ones.
    float logUniform(float lo, float hi) { return lo * std::pow(hi / lo, unit()); }
    uint32_t below(uint32_t n) { return uint32_t(((next() >> 32) * n) >> 32); }
    bool chance(float p) { return unit() < p; }
    float sign() { return chance(0.5f) ? 1.0f : -1.0f; }
    template <class T, size_t N>
    const T& pick(const std::array<T, N>& items) {
        return items[below(uint32_t(N))];
    }
};

glm::mat4 translation(const glm::vec3& t) {
    glm::mat4 m(1.0f);
    m[3] = glm::vec4(t, 1.0f);
    return m;
}

// A quarter turn taking local y (a lathe's axis) onto world x or z, then a translation. The
// entries are exactly 0 and +-1 so placing adds no rounding, and the determinant is +1 so
// outward winding stays outward.
glm::mat4 lyingAlong(bool along_x, const glm::vec3& t) {
    glm::mat4 m(1.0f);
    if (along_x) {
        m[0] = glm::vec4(0.0f, -1.0f, 0.0f, 0.0f);
        m[1] = glm::vec4(1.0f, 0.0f, 0.0f, 0.0f);
    } else {
        m[1] = glm::vec4(0.0f, 0.0f, 1.0f, 0.0f);
        m[2] = glm::vec4(0.0f, -1.0f, 0.0f, 0.0f);
    }
    m[3] = glm::vec4(t, 1.0f);
    return m;
}

// A closed 2D cross-section to sweep: the outline counter-clockwise without repeated points,
// and a triangulation of its inside over the outline's own vertices (counter-clockwise).
struct Profile {
    std::vector<glm::vec2> outline;
    std::vector<uint32_t> cap;
};

Profile rectangleProfile(float width, float height) {
    const float w = width / 2, h = height / 2;
    return {{{-w, -h}, {w, -h}, {w, h}, {-w, h}}, {0, 1, 2, 0, 2, 3}};
}

Profile circleProfile(float radius, uint32_t segments) {
    Profile p;
    for (uint32_t i = 0; i < segments; ++i) {
        const double a = 2.0 * std::numbers::pi * i / segments;
        p.outline.emplace_back(float(radius * std::cos(a)), float(radius * std::sin(a)));
    }
    // A fan from one rim vertex closes a pipe end without a centre vertex, as CAD exports do.
    for (uint32_t i = 1; i + 1 < segments; ++i) p.cap.insert(p.cap.end(), {0, i, i + 1});
    return p;
}

// H-section centred on the origin, flanges across x, web along y.
Profile iSectionProfile(float width, float depth, float flange, float web) {
    const float w = width / 2, d = depth / 2, f = d - flange, t = web / 2;
    return {{{-w, -d}, {w, -d}, {w, -f}, {t, -f}, {t, f}, {w, f},
             {w, d}, {-w, d}, {-w, f}, {-t, f}, {-t, -f}, {-w, -f}},
            {0, 1, 2, 0, 2, 3, 0, 3, 10, 0, 10, 11,   // bottom flange
             10, 3, 4, 10, 4, 9,                      // web
             6, 7, 8, 6, 8, 9, 6, 9, 4, 6, 4, 5}};    // top flange
}

// Cable-tray channel (a U open towards +y): floor at y = 0, sides up to `height`.
Profile channelProfile(float width, float height, float sheet) {
    const float w = width / 2, i = w - sheet;
    return {{{-w, 0.0f}, {w, 0.0f}, {w, height}, {i, height},
             {i, sheet}, {-i, sheet}, {-i, height}, {-w, height}},
            {0, 1, 4, 0, 4, 5, 1, 2, 3, 1, 3, 4, 0, 5, 6, 0, 6, 7}};
}

// Where a profile sits along a sweep; cross(normal, binormal) is the direction of travel, so a
// counter-clockwise profile gives outward side faces.
struct Frame {
    glm::vec3 origin;
    glm::vec3 normal;    // profile x
    glm::vec3 binormal;  // profile y
};

// One straight stretch of a Manhattan route, measured corner to corner.
struct Leg {
    glm::vec3 direction;  // a unit world axis
    float length;
};

// Frames along a route from `start`: consecutive legs must be perpendicular, joined by
// 90-degree elbows of radius `bend` cut into `arc_steps` (>= 2) pieces; the first and last legs
// must be longer than bend + kMinStraight, the others longer than 2 * bend + kMinStraight.
// Horizontal routes start with binormal = up, so trays open upwards and I-beam webs stand
// upright; later frames are carried along by projection (parallel transport), which for
// 90-degree elbows in >= 2 steps never loses the normal.
std::vector<Frame> routeFrames(const glm::vec3& start, const std::vector<Leg>& legs, float bend,
                               uint32_t arc_steps) {
    std::vector<glm::vec3> points{start};
    std::vector<glm::vec3> tangents{legs.front().direction};
    glm::vec3 corner = start;
    for (size_t i = 0; i < legs.size(); ++i) {
        const glm::vec3 d1 = legs[i].direction;
        corner += d1 * legs[i].length;
        if (i + 1 == legs.size()) {
            points.push_back(corner);
            tangents.push_back(d1);
            break;
        }
        const glm::vec3 d2 = legs[i + 1].direction;
        const glm::vec3 centre = corner + bend * (d2 - d1);
        for (uint32_t s = 0; s <= arc_steps; ++s) {
            const double phi = std::numbers::pi / 2 * s / arc_steps;
            const float c = s == arc_steps ? 0.0f : float(std::cos(phi));
            const float sn = s == arc_steps ? 1.0f : float(std::sin(phi));
            points.push_back(centre + bend * (d1 * sn - d2 * c));
            tangents.push_back(d1 * c + d2 * sn);
        }
    }
    const glm::vec3 side = glm::cross(kUp, tangents.front());
    glm::vec3 normal = glm::dot(side, side) > 0.5f ? side : kAlongX;
    std::vector<Frame> frames;
    frames.reserve(points.size());
    for (size_t k = 0; k < points.size(); ++k) {
        const glm::vec3& t = tangents[k];
        normal = glm::normalize(normal - glm::dot(normal, t) * t);
        frames.push_back({points[k], normal, glm::cross(t, normal)});
    }
    return frames;
}

// The profile swept through the frames: a closed tube with both ends capped, one ring of
// shared vertices per frame. 2 n (frames - 1) + 2 caps triangles for an n-point outline.
Mesh sweep(const Profile& profile, const std::vector<Frame>& frames) {
    Mesh mesh;
    const uint32_t n = uint32_t(profile.outline.size());
    const uint32_t rings = uint32_t(frames.size());
    mesh.positions.reserve(size_t(n) * rings);
    for (const Frame& f : frames)
        for (const glm::vec2& q : profile.outline)
            mesh.positions.push_back(f.origin + q.x * f.normal + q.y * f.binormal);
    mesh.indices.reserve(6 * size_t(n) * (rings - 1) + 2 * profile.cap.size());
    for (uint32_t k = 0; k + 1 < rings; ++k) {
        const uint32_t a = k * n, b = a + n;
        for (uint32_t q = 0; q < n; ++q) {
            const uint32_t r = (q + 1) % n;
            mesh.indices.insert(mesh.indices.end(), {a + q, a + r, b + r, a + q, b + r, b + q});
        }
    }
    // The first cap looks back along the route, so its triangles turn the other way.
    const std::vector<uint32_t>& cap = profile.cap;
    for (size_t t = 0; t < cap.size(); t += 3)
        mesh.indices.insert(mesh.indices.end(), {cap[t], cap[t + 2], cap[t + 1]});
    const uint32_t last = (rings - 1) * n;
    for (size_t t = 0; t < cap.size(); t += 3)
        mesh.indices.insert(mesh.indices.end(), {last + cap[t], last + cap[t + 1], last + cap[t + 2]});
    return mesh;
}

// A box centred on the origin: 8 shared corners, 12 triangles.
Mesh boxMesh(const glm::vec3& size) {
    return sweep(rectangleProfile(size.x, size.y),
                 routeFrames({0.0f, 0.0f, -size.z / 2}, {{kAlongZ, size.z}}, 0.0f, 0));
}

// The profile, (radius, height) points from a pole on the y axis to another pole with only the
// two poles at radius 0, revolved about y in `segments` steps: 2 segments (points - 2)
// triangles, outward when the profile runs bottom to top.
Mesh lathe(const std::vector<glm::vec2>& profile, uint32_t segments) {
    Mesh mesh;
    const uint32_t rings = uint32_t(profile.size()) - 2;
    std::vector<glm::vec2> around(segments);
    for (uint32_t j = 0; j < segments; ++j) {
        const double a = 2.0 * std::numbers::pi * j / segments;
        around[j] = {float(std::cos(a)), float(std::sin(a))};
    }
    mesh.positions.reserve(size_t(rings) * segments + 2);
    mesh.positions.emplace_back(0.0f, profile.front().y, 0.0f);
    for (uint32_t r = 1; r <= rings; ++r)
        for (const glm::vec2& cs : around)
            mesh.positions.emplace_back(profile[r].x * cs.x, profile[r].y, profile[r].x * cs.y);
    mesh.positions.emplace_back(0.0f, profile.back().y, 0.0f);

    const uint32_t top = 1 + rings * segments;
    auto ringVertex = [segments](uint32_t ring, uint32_t j) { return 1 + ring * segments + j % segments; };
    mesh.indices.reserve(6 * size_t(rings) * segments);
    for (uint32_t j = 0; j < segments; ++j)
        mesh.indices.insert(mesh.indices.end(), {0, ringVertex(0, j), ringVertex(0, j + 1)});
    for (uint32_t r = 0; r + 1 < rings; ++r) {
        for (uint32_t j = 0; j < segments; ++j) {
            const uint32_t a0 = ringVertex(r, j), a1 = ringVertex(r, j + 1);
            const uint32_t b0 = ringVertex(r + 1, j), b1 = ringVertex(r + 1, j + 1);
            mesh.indices.insert(mesh.indices.end(), {a0, b0, a1, a1, b0, b1});
        }
    }
    for (uint32_t j = 0; j < segments; ++j)
        mesh.indices.insert(mesh.indices.end(), {ringVertex(rings - 1, j), top, ringVertex(rings - 1, j + 1)});
    return mesh;
}

// Lathe profile of a vessel standing on its bottom pole: an elliptical bottom head of height
// `bottom` in `bottom_steps`, a cylindrical shell of height `shell` in `shell_steps`, a top
// head of height `top` in `top_steps`. A head of height 0 is flat (extra steps put rings on
// it), a top head in one step is a cone, and shell 0 with heads of height `radius` is a sphere.
// Gives bottom_steps + top_steps + shell_steps - 1 points between the poles (shell_steps is
// ignored, counted as 0, when shell is 0).
std::vector<glm::vec2> vesselProfile(float radius, float bottom, uint32_t bottom_steps, float shell,
                                     uint32_t shell_steps, float top, uint32_t top_steps) {
    std::vector<glm::vec2> points{{0.0f, 0.0f}};
    for (uint32_t i = 1; i <= bottom_steps; ++i) {
        const double phi = std::numbers::pi / 2 * i / bottom_steps;
        points.emplace_back(float(radius * std::sin(phi)), float(bottom * (1.0 - std::cos(phi))));
    }
    for (uint32_t i = 1; i < shell_steps && shell > 0; ++i)
        points.emplace_back(radius, bottom + shell * float(i) / float(shell_steps));
    const float rim = bottom + shell;
    // Without a shell the top head's first ring would repeat the bottom head's last one.
    for (uint32_t i = shell > 0 ? 0 : 1; i < top_steps; ++i) {
        const double phi = std::numbers::pi / 2 * i / top_steps;
        points.emplace_back(float(radius * std::cos(phi)), float(rim + top * std::sin(phi)));
    }
    points.emplace_back(0.0f, rim + top);
    return points;
}

uint32_t roundToUint(float x) { return uint32_t(x + 0.5f); }

class PlantGenerator {
public:
    PlantGenerator(uint64_t seed, const PlantLayout& layout, const PlantSink& sink)
        : seed_(seed), layout_(layout), sink_(sink) {}

    // Appends exactly `budget` objects for bay-floor `index` (x fastest, then z, then floor):
    // the structure first, then equipment and overhead runs until the budget is spent.
    void generateBayFloor(uint64_t index, uint32_t budget) {
        remaining_ = budget;
        rng_ = Random(Random(seed_ ^ (index * 0xd1b54a32d192ed03ull)).next());
        bayX_ = uint32_t(index % layout_.baysX);
        bayZ_ = uint32_t(index / layout_.baysX % layout_.baysZ);
        floor_ = uint32_t(index / layout_.baysX / layout_.baysZ);
        origin_ = {float(bayX_) * layout_.bayPitch, float(floor_) * layout_.storeyHeight,
                   float(bayZ_) * layout_.bayPitch};
        usedCells_.fill(false);

        addStructure();
        if (index % kHeroEvery == 0) {
            if (index / kHeroEvery % 2 == 0)
                addHeroTank();
            else
                addHeroCoil();
        }
        while (remaining_ > 0) addFurnishing();
    }

private:
    struct Area {  // bay-local floor rectangle
        float x0, z0, x1, z1;
        float centreX() const { return (x0 + x1) / 2; }
        float centreZ() const { return (z0 + z1) / 2; }
    };

    float pitch() const { return layout_.bayPitch; }
    float ceiling() const { return layout_.storeyHeight - layout_.slabThickness; }
    float quadrantSpan() const { return layout_.corridorMin - kQuadrantInset; }
    glm::vec3 bayPoint(float x, float y, float z) const { return origin_ + glm::vec3(x, y, z); }

    void emit(const char* kind, Mesh&& mesh, const glm::mat4& world, const glm::vec4& colour) {
        mesh.name = std::string(kind) + "_" + std::to_string(emitted_++);
        mesh.color = colour;
        sink_(std::move(mesh), world);
        --remaining_;
    }

    // Claims a free cells_x x cells_z block of one quadrant's cell grid, searching from a
    // random cell; nothing when the floor has no such block left.
    std::optional<Area> takeCells(uint32_t cells_x, uint32_t cells_z) {
        const uint32_t count = uint32_t(usedCells_.size());
        const uint32_t first = rng_.below(count);
        const float cell = quadrantSpan() / kCellsPerSide;
        for (uint32_t k = 0; k < count; ++k) {
            const uint32_t c = (first + k) % count;
            const uint32_t q = c / kCellsPerQuadrant, cx = c % kCellsPerSide, cz = c / kCellsPerSide % kCellsPerSide;
            if (cx + cells_x > kCellsPerSide || cz + cells_z > kCellsPerSide) continue;
            bool vacant = true;
            for (uint32_t z = cz; z < cz + cells_z; ++z)
                for (uint32_t x = cx; x < cx + cells_x; ++x) vacant = vacant && !usedCells_[cellIndex(q, x, z)];
            if (!vacant) continue;
            for (uint32_t z = cz; z < cz + cells_z; ++z)
                for (uint32_t x = cx; x < cx + cells_x; ++x) usedCells_[cellIndex(q, x, z)] = true;
            const glm::vec2 o = quadrantOrigin(q);
            return Area{o.x + cx * cell, o.y + cz * cell, o.x + (cx + cells_x) * cell, o.y + (cz + cells_z) * cell};
        }
        return std::nullopt;
    }
    static uint32_t cellIndex(uint32_t q, uint32_t x, uint32_t z) { return q * kCellsPerQuadrant + z * kCellsPerSide + x; }
    glm::vec2 quadrantOrigin(uint32_t q) const {
        return {(q & 1) ? layout_.corridorMax : kQuadrantInset, (q & 2) ? layout_.corridorMax : kQuadrantInset};
    }

    // Distance a route may still run from world point p along axis direction d.
    float roomAlong(const glm::vec3& p, const glm::vec3& d) const {
        const glm::vec3 far{float(layout_.baysX) * pitch(), 0.0f, float(layout_.baysZ) * pitch()};
        if (d.x > 0) return far.x - kBuildingMargin - p.x;
        if (d.x < 0) return p.x - kBuildingMargin;
        if (d.z > 0) return far.z - kBuildingMargin - p.z;
        return p.z - kBuildingMargin;
    }

    // True when world point p lies over a quadrant (not a corridor) with `margin` to spare.
    bool overQuadrant(const glm::vec3& p, float margin) const {
        auto inside = [&](float v) {
            const float local = v - std::floor(v / pitch()) * pitch();
            const float lo = local < layout_.corridorMin ? kQuadrantInset : layout_.corridorMax;
            return local >= lo + margin && local <= lo + quadrantSpan() - margin;
        };
        return inside(p.x) && inside(p.z);
    }

    // A horizontal leg from p along a random sign of `axis`, log-uniform in length up to
    // max_length. It turns round when its way is shorter than that length and the other way is
    // longer, and is cut short at the building's margin. Nothing when it cannot reach min_length.
    std::optional<Leg> horizontalLeg(const glm::vec3& p, const glm::vec3& axis, float min_length, float max_length) {
        const float length = rng_.logUniform(min_length, std::max(max_length, min_length));
        glm::vec3 d = axis * rng_.sign();
        if (roomAlong(p, d) < length && roomAlong(p, -d) > roomAlong(p, d)) d = -d;
        const float room = roomAlong(p, d);
        if (room < min_length) return std::nullopt;
        return Leg{d, std::min(length, room)};
    }

    void addStructure() {
        const bool last_x = bayX_ + 1 == layout_.baysX, last_z = bayZ_ + 1 == layout_.baysZ;
        const float p = pitch();
        addSlab(0.0f);
        if (floor_ + 1 == layout_.floors) addSlab(layout_.storeyHeight);
        // Each bay owns the column at its low corner and the girders on its low edges; bays on
        // the far sides of the grid also own the far ones.
        addColumn(0.0f, 0.0f);
        if (last_x) addColumn(p, 0.0f);
        if (last_z) addColumn(0.0f, p);
        if (last_x && last_z) addColumn(p, p);
        addGirder(0.0f, 0.0f, kAlongX, kGirderDepth);
        addGirder(0.0f, 0.0f, kAlongZ, kGirderDepth);
        if (last_x) addGirder(p, 0.0f, kAlongZ, kGirderDepth);
        if (last_z) addGirder(0.0f, p, kAlongX, kGirderDepth);
        if (bayX_ == 0) addWall(0.0f, 0.0f, kAlongZ, p);
        if (last_x) addWall(p, 0.0f, kAlongZ, p);
        if (bayZ_ == 0) addWall(0.0f, 0.0f, kAlongX, p);
        if (last_z) addWall(0.0f, p, kAlongX, p);
        // Inner walls keep a door where the corridor crosses them.
        const float end = p - kQuadrantInset / 2;
        if (bayX_ > 0 && rng_.chance(0.2f)) {
            addWall(0.0f, kQuadrantInset / 2, kAlongZ, layout_.corridorMin - kQuadrantInset / 2);
            addWall(0.0f, layout_.corridorMax, kAlongZ, end - layout_.corridorMax);
        }
        if (bayZ_ > 0 && rng_.chance(0.2f)) {
            addWall(kQuadrantInset / 2, 0.0f, kAlongX, layout_.corridorMin - kQuadrantInset / 2);
            addWall(layout_.corridorMax, 0.0f, kAlongX, end - layout_.corridorMax);
        }
    }

    // The slab whose top is `top` above this floor's surface, covering the bay.
    void addSlab(float top) {
        if (remaining_ == 0) return;
        const float p = pitch(), t = layout_.slabThickness;
        emit("slab", boxMesh({p, t, p}), translation(bayPoint(p / 2, top - t / 2, p / 2)), kSlabColour);
    }

    // Concrete on the ground floor, steel H-sections above.
    void addColumn(float x, float z) {
        if (remaining_ == 0) return;
        const float height = ceiling();
        if (floor_ == 0) {
            emit("column", boxMesh({0.5f, height, 0.5f}), translation(bayPoint(x, height / 2, z)), kConcreteColour);
            return;
        }
        // 0.24 m keeps the section inside the walls it stands in, so no faces are coplanar.
        Mesh mesh = sweep(iSectionProfile(0.24f, 0.24f, 0.02f, 0.012f),
                          routeFrames(glm::vec3(0.0f), {{kUp, height}}, 0.0f, 0));
        emit("column", std::move(mesh), translation(bayPoint(x, 0.0f, z)), kSteelColour);
    }

    // An I-beam one bay long from bay-local (x, z) along `direction`, under the slab above.
    void addGirder(float x, float z, const glm::vec3& direction, float depth) {
        if (remaining_ == 0) return;
        // Flanges narrower than a wall, so a girder over a wall never shares its faces.
        Mesh mesh = sweep(iSectionProfile(0.45f * depth, depth, depth / 20, depth / 33),
                          routeFrames(glm::vec3(0.0f), {{direction, pitch()}}, 0.0f, 0));
        emit("girder", std::move(mesh), translation(bayPoint(x, ceiling() - depth / 2, z)), kSteelColour);
    }

    // A wall from floor to slab, centred on a bay edge, from bay-local (x, z) along `direction`.
    void addWall(float x, float z, const glm::vec3& direction, float length) {
        if (remaining_ == 0) return;
        const float h = ceiling();
        const glm::vec3 size = direction.x > 0 ? glm::vec3(length, h, kWallThickness)
                                               : glm::vec3(kWallThickness, h, length);
        const glm::vec3 centre = bayPoint(x, h / 2, z) + direction * (length / 2);
        emit("wall", boxMesh(size), translation(centre), kWallColour);
    }

    // One non-structural object. Floor-standing kinds give way to a pipe when the bay's floor
    // is full: a pipe always fits overhead.
    void addFurnishing() {
        const uint32_t roll = rng_.below(100);
        bool placed = true;
        if (roll < 26)
            addRiserPipe();
        else if (roll < 38)
            addRackPipe();
        else if (roll < 46)
            addTray();
        else if (roll < 48)
            addBeam();
        else if (roll < 72)
            placed = addEquipment();
        else if (roll < 84)
            placed = addMotor();
        else if (roll < 94)
            placed = addTank();
        else if (roll < 98)
            placed = addVessel();
        else
            placed = floor_ == 0 ? addSphere() : addTank();
        if (!placed) addRiserPipe();
    }

    bool addEquipment() {
        const uint32_t cells_x = rng_.chance(0.3f) ? 2 : 1, cells_z = rng_.chance(0.3f) ? 2 : 1;
        const std::optional<Area> area = takeCells(cells_x, cells_z);
        if (!area) return false;
        const glm::vec3 size{rng_.uniform(0.4f, area->x1 - area->x0 - 0.2f), rng_.uniform(0.4f, 2.4f),
                             rng_.uniform(0.4f, area->z1 - area->z0 - 0.2f)};
        emit("equipment", boxMesh(size), translation(bayPoint(area->centreX(), size.y / 2, area->centreZ())),
             rng_.pick(kEquipmentColours));
        return true;
    }

    // A motor or pump body: a short horizontal cylinder, 0.1 m up on feet that are not modelled.
    bool addMotor() {
        const std::optional<Area> area = takeCells(1, 1);
        if (!area) return false;
        const float radius = rng_.uniform(0.12f, 0.35f), length = rng_.uniform(0.5f, 1.2f);
        const uint32_t segments = roundToUint(rng_.logUniform(8.0f, 32.0f));
        const glm::vec3 axis = rng_.chance(0.5f) ? kAlongX : kAlongZ;
        Mesh mesh = sweep(circleProfile(radius, segments), routeFrames(-axis * (length / 2), {{axis, length}}, 0.0f, 0));
        emit("motor", std::move(mesh), translation(bayPoint(area->centreX(), radius + 0.1f, area->centreZ())), kMotorColour);
        return true;
    }

    // A vertical tank: a whole quadrant for a big one, one cell for a small one.
    bool addTank() {
        const bool big = rng_.chance(0.35f);
        std::optional<Area> area = big ? takeCells(kCellsPerSide, kCellsPerSide) : std::nullopt;
        const bool got_big = area.has_value();
        if (!got_big) area = takeCells(1, 1);
        if (!area) return false;
        const float radius = got_big ? rng_.uniform(1.0f, 1.85f) : rng_.uniform(0.3f, 0.6f);
        const float height = got_big ? rng_.uniform(2.5f, 4.8f) : rng_.uniform(1.0f, 3.0f);
        const uint32_t segments = roundToUint(rng_.logUniform(12.0f, 72.0f));
        const uint32_t head_steps = 2 + rng_.below(segments / 6);
        const float bottom = rng_.chance(0.5f) ? 0.0f : radius / 2;  // flat or 2:1 elliptical
        const uint32_t roof = rng_.below(3);                          // elliptical, cone or flat
        const float top = roof == 0 ? radius / 2 : roof == 1 ? radius * 0.3f : 0.0f;
        // Drawn before the call, whose arguments have no evaluation order.
        const uint32_t floor_rings = 1 + rng_.below(3);
        const uint32_t shell_steps = 1 + rng_.below(1 + segments / 8);
        const std::vector<glm::vec2> profile =
            vesselProfile(radius, bottom, bottom > 0 ? head_steps : floor_rings, height - bottom - top, shell_steps,
                          top, roof == 0 ? head_steps : 1);
        emit("tank", lathe(profile, segments), translation(bayPoint(area->centreX(), 0.0f, area->centreZ())),
             rng_.pick(kTankColours));
        return true;
    }

    // A horizontal pressure vessel with 2:1 elliptical heads, along a row of cells and 0.4 m up
    // on saddles that are not modelled.
    bool addVessel() {
        const bool along_x = rng_.chance(0.5f);
        const std::optional<Area> area = along_x ? takeCells(kCellsPerSide, 1) : takeCells(1, kCellsPerSide);
        if (!area) return false;
        const float radius = rng_.uniform(0.3f, 0.6f);
        const float length = rng_.uniform(2.0f, (along_x ? area->x1 - area->x0 : area->z1 - area->z0) - 0.2f);
        const uint32_t segments = roundToUint(rng_.logUniform(12.0f, 64.0f));
        const uint32_t head_steps = 2 + rng_.below(segments / 6);
        const std::vector<glm::vec2> profile = vesselProfile(radius, radius / 2, head_steps, length - radius,
                                                             1 + rng_.below(4), radius / 2, head_steps);
        const glm::vec3 axis = along_x ? kAlongX : kAlongZ;
        const glm::vec3 start = bayPoint(area->centreX(), radius + 0.4f, area->centreZ()) - axis * (length / 2);
        emit("vessel", lathe(profile, segments), lyingAlong(along_x, start), rng_.pick(kTankColours));
        return true;
    }

    // A spherical storage tank filling a quadrant.
    bool addSphere() {
        const std::optional<Area> area = takeCells(kCellsPerSide, kCellsPerSide);
        if (!area) return false;
        const float radius = rng_.uniform(1.2f, 1.9f);
        const uint32_t stacks = roundToUint(rng_.logUniform(8.0f, 48.0f));
        const std::vector<glm::vec2> profile =
            vesselProfile(radius, radius, stacks / 2, 0.0f, 0, radius, stacks - stacks / 2);
        emit("sphere", lathe(profile, 2 * stacks), translation(bayPoint(area->centreX(), 0.0f, area->centreZ())),
             kTankColours[0]);
        return true;
    }

    // A secondary I-beam across the bay under the slab, over a quadrant.
    void addBeam() {
        const bool along_x = rng_.chance(0.5f);
        const float across = rng_.chance(0.5f) ? rng_.uniform(1.0f, layout_.corridorMin - 1.0f)
                                               : rng_.uniform(layout_.corridorMax + 1.0f, pitch() - 1.0f);
        if (along_x)
            addGirder(0.0f, across, kAlongX, 0.3f);
        else
            addGirder(across, 0.0f, kAlongZ, 0.3f);
    }

    // A process pipe: rises from equipment in a quadrant to rack height, runs along one or two
    // horizontal legs, and may drop back down where it ends over a quadrant.
    void addRiserPipe() {
        const float radius = rng_.logUniform(0.025f, 0.3f), bend = 3 * radius;
        const uint32_t q = rng_.below(4);
        const glm::vec2 o = quadrantOrigin(q);
        const float margin = radius + 0.05f;
        // Braced, so the three draws happen in order (function arguments have no order).
        const glm::vec3 local{rng_.uniform(o.x + margin, o.x + quadrantSpan() - margin), rng_.uniform(0.3f, 1.2f),
                              rng_.uniform(o.y + margin, o.y + quadrantSpan() - margin)};
        const glm::vec3 start = origin_ + local;
        const float rack = origin_.y + rng_.uniform(kRackLow, kRackHigh);
        std::vector<Leg> legs{{kUp, rack - start.y}};
        glm::vec3 corner = start + kUp * legs[0].length;
        const float min_leg = 2 * bend + kMinStraight;
        const bool first_along_x = rng_.chance(0.5f);
        // The building is at least one bay wide, so one sign always has room for this leg.
        const std::optional<Leg> run = horizontalLeg(corner, first_along_x ? kAlongX : kAlongZ, min_leg, 30.0f);
        legs.push_back(*run);
        corner += run->direction * run->length;
        if (rng_.chance(0.5f)) {
            if (const std::optional<Leg> turn = horizontalLeg(corner, first_along_x ? kAlongZ : kAlongX, min_leg, 15.0f)) {
                legs.push_back(*turn);
                corner += turn->direction * turn->length;
            }
        }
        if (rng_.chance(0.4f) && overQuadrant(corner, margin))
            legs.push_back({kDown, rack - origin_.y - rng_.uniform(0.3f, 1.0f)});
        addPipe(start, legs, radius, bend);
    }

    // A pipe in a rack over a corridor, long and straight with at most one turn.
    void addRackPipe() {
        const float radius = rng_.logUniform(0.025f, 0.3f), bend = 3 * radius;
        const bool along_x = rng_.chance(0.5f);
        const float lane = rng_.uniform(layout_.corridorMin + radius + 0.1f, layout_.corridorMax - radius - 0.1f);
        const float y = rng_.uniform(kRackLow, kRackHigh), along = rng_.uniform(0.0f, pitch());
        const glm::vec3 start = along_x ? bayPoint(along, y, lane) : bayPoint(lane, y, along);
        const float min_leg = 2 * bend + kMinStraight;
        std::vector<Leg> legs{*horizontalLeg(start, along_x ? kAlongX : kAlongZ, min_leg, 60.0f)};
        if (rng_.chance(0.25f)) {
            const glm::vec3 corner = start + legs[0].direction * legs[0].length;
            if (const std::optional<Leg> turn = horizontalLeg(corner, along_x ? kAlongZ : kAlongX, min_leg, 30.0f))
                legs.push_back(*turn);
        }
        addPipe(start, legs, radius, bend);
    }

    void addPipe(const glm::vec3& start, const std::vector<Leg>& legs, float radius, float bend) {
        const uint32_t segments = std::min(48u, roundToUint(rng_.logUniform(8.0f, 12.0f + 120.0f * radius)));
        const uint32_t arc_steps = 2 + rng_.below(1 + uint32_t(radius * 30.0f));
        emit("pipe", sweep(circleProfile(radius, segments), routeFrames(glm::vec3(0.0f), legs, bend, arc_steps)),
             translation(start), rng_.pick(kPipeColours));
    }

    // A cable tray over a corridor, open side up, with at most one horizontal turn.
    void addTray() {
        const float width = rng_.uniform(0.3f, 0.9f), bend = width;
        const bool along_x = rng_.chance(0.5f);
        const float lane = rng_.uniform(layout_.corridorMin + width / 2 + 0.1f, layout_.corridorMax - width / 2 - 0.1f);
        const float y = rng_.uniform(kTrayLow, kTrayHigh), along = rng_.uniform(0.0f, pitch());
        const glm::vec3 start = along_x ? bayPoint(along, y, lane) : bayPoint(lane, y, along);
        const float min_leg = 2 * bend + kMinStraight;
        std::vector<Leg> legs{*horizontalLeg(start, along_x ? kAlongX : kAlongZ, min_leg, 60.0f)};
        if (rng_.chance(0.4f)) {
            const glm::vec3 corner = start + legs[0].direction * legs[0].length;
            if (const std::optional<Leg> turn = horizontalLeg(corner, along_x ? kAlongZ : kAlongX, min_leg, 30.0f))
                legs.push_back(*turn);
        }
        const Profile profile = channelProfile(width, rng_.uniform(0.1f, 0.15f), 0.015f);
        emit("tray", sweep(profile, routeFrames(glm::vec3(0.0f), legs, bend, 2 + rng_.below(5))), translation(start),
             kTrayColour);
    }

    // A finely tessellated process column filling a quadrant: 2 s rings triangles for a
    // log-uniform s in [96, 128] and rings = target / 2 s, so within 2 s below the target.
    void addHeroTank() {
        if (remaining_ == 0) return;
        const std::optional<Area> area = takeCells(kCellsPerSide, kCellsPerSide);
        if (!area) return;
        const float radius = 1.7f, head = radius / 2, height = 4.6f;
        const uint32_t segments = roundToUint(rng_.logUniform(96.0f, 128.0f));
        const uint32_t target = kHeroMinTriangles + rng_.below(kHeroMaxTriangles - kHeroMinTriangles + 1);
        const uint32_t rings = target / (2 * segments);
        const uint32_t head_steps = rings * 3 / 10;
        const std::vector<glm::vec2> profile = vesselProfile(radius, head, head_steps, height - 2 * head,
                                                             rings - 2 * head_steps + 1, head, head_steps);
        emit("tank", lathe(profile, segments), translation(bayPoint(area->centreX(), 0.0f, area->centreZ())),
             kTankColours[0]);
    }

    // A heat-exchanger coil filling a quadrant: a serpentine pipe whose many elbows are cut
    // fine enough to land within 2 s * elbows triangles below the target.
    void addHeroCoil() {
        if (remaining_ == 0) return;
        const std::optional<Area> area = takeCells(kCellsPerSide, kCellsPerSide);
        if (!area) return;
        const float radius = 0.04f, bend = 0.12f, rise = 2.8f, pitch_x = 2 * bend + 0.06f;
        const uint32_t segments = 32, turns = 8 + rng_.below(3);
        std::vector<Leg> legs;
        for (uint32_t k = 0; k < turns; ++k) {
            legs.push_back({k % 2 == 0 ? kUp : kDown, rise});
            if (k + 1 < turns) legs.push_back({kAlongX, pitch_x});
        }
        // A route with e elbows of m - 1 steps has 2 + e m frames, so the swept pipe has
        // 2 s (1 + e m) + 2 (s - 2) triangles.
        const uint32_t elbows = uint32_t(legs.size()) - 1;
        const uint32_t target = kHeroMinTriangles + rng_.below(kHeroMaxTriangles - kHeroMinTriangles + 1);
        const uint32_t m = (target - 4 * segments + 4) / (2 * segments * elbows);
        const glm::vec3 start = bayPoint(area->x0 + 0.3f, 0.3f, rng_.uniform(area->z0 + 0.5f, area->z1 - 0.5f));
        emit("pipe", sweep(circleProfile(radius, segments), routeFrames(glm::vec3(0.0f), legs, bend, m - 1)),
             translation(start), kCopperColour);
    }

    const uint64_t seed_;
    const PlantLayout layout_;
    const PlantSink& sink_;
    uint64_t emitted_ = 0;
    Random rng_{0};
    uint32_t remaining_ = 0;
    uint32_t floor_ = 0;
    uint32_t bayX_ = 0;
    uint32_t bayZ_ = 0;
    glm::vec3 origin_{0.0f};  // the bay's low corner on its floor surface
    std::array<bool, 4 * kCellsPerQuadrant> usedCells_{};
};

}  // namespace

PlantLayout plantLayout(const PlantOptions& options) {
    if (options.objects == 0 || options.objects > kMaxPlantObjects)
        throw UsageError("plant: objects must be in 1.." + std::to_string(kMaxPlantObjects) + ", got " +
                         std::to_string(options.objects));
    const uint64_t bay_floors = std::max<uint64_t>(1, (options.objects + kObjectsPerBayFloor / 2) / kObjectsPerBayFloor);
    // Floors grow as the cube root of the size (rounded), so a plant is wider than tall.
    PlantLayout layout;
    auto cube = [](double x) { return x * x * x; };
    while (layout.floors < kMaxFloors && cube(1.5 * (layout.floors + 0.5)) <= double(bay_floors)) ++layout.floors;
    const uint64_t per_floor = (bay_floors + layout.floors - 1) / layout.floors;
    while (uint64_t(layout.baysX) * layout.baysX < per_floor) ++layout.baysX;
    layout.baysZ = uint32_t((per_floor + layout.baysX - 1) / layout.baysX);
    return layout;
}

Scene generatePlant(const PlantOptions& options) {
    Scene scene;
    scene.meshes.reserve(options.objects);
    scene.objects.reserve(options.objects);
    generatePlant(options, [&scene](Mesh&& mesh, const glm::mat4& world) {
        scene.objects.push_back(Object{uint32_t(scene.meshes.size()), world, mesh.color});
        scene.meshes.push_back(std::move(mesh));
    });
    return scene;
}

void generatePlant(const PlantOptions& options, const PlantSink& sink) {
    const PlantLayout layout = plantLayout(options);
    PlantGenerator generator(options.seed, layout, sink);
    const uint64_t bay_floors = uint64_t(layout.floors) * layout.baysX * layout.baysZ;
    const uint64_t objects = options.objects;
    // Spread the objects evenly; the bay-floor count was chosen for about 40 each.
    for (uint64_t b = 0; b < bay_floors; ++b)
        generator.generateBayFloor(b, uint32_t(objects * (b + 1) / bay_floors - objects * b / bay_floors));
}

void writePlant(const std::string& path, const PlantOptions& options, PlantProgress* progress) {
    GltfStreamWriter writer(path);
    std::vector<uint32_t> roots;
    roots.reserve(options.objects);
    generatePlant(options, [&](Mesh&& mesh, const glm::mat4& world) {
        GltfNode node;
        node.mesh = int32_t(writer.addMesh(mesh));
        node.matrix = world;
        roots.push_back(writer.addNode(node));
        if (progress) {
            progress->triangles += mesh.triangleCount();
            ++progress->objects;
        }
    });
    writer.finish(roots);
}

}  // namespace occ
