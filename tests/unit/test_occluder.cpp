// SPDX-License-Identifier: MIT
#include "prep/occluder.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

namespace occ {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

struct TestMesh {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
};

void addQuad(TestMesh& m, uint32_t a, uint32_t b, uint32_t c, uint32_t d) {
    m.triangles.insert(m.triangles.end(), {a, b, c, a, c, d});
}

// Closed box: 8 corners (corner i takes hi's coordinate where bit 0/1/2 of i is set), 12 triangles.
void addBox(TestMesh& m, const glm::vec3& lo, const glm::vec3& hi) {
    const auto base = uint32_t(m.positions.size());
    for (uint32_t i = 0; i < 8; ++i)
        m.positions.push_back({i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z});
    const uint32_t faces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (const auto& f : faces) addQuad(m, base + f[0], base + f[1], base + f[2], base + f[3]);
}

TestMesh box(const glm::vec3& lo, const glm::vec3& hi) {
    TestMesh m;
    addBox(m, lo, hi);
    return m;
}

TestMesh transformed(TestMesh m, const glm::mat4& world) {
    for (glm::vec3& p : m.positions) p = glm::vec3(world * glm::vec4(p, 1.0f));
    return m;
}

// Radius-r sphere with `segments` meridians and `rings` latitude bands, poles on z.
TestMesh uvSphere(uint32_t segments, uint32_t rings, float r) {
    TestMesh m;
    m.positions.push_back({0, 0, r});
    for (uint32_t k = 1; k < rings; ++k) {
        const float phi = kPi * float(k) / float(rings);
        for (uint32_t s = 0; s < segments; ++s) {
            const float theta = 2.0f * kPi * float(s) / float(segments);
            m.positions.push_back(
                {r * std::sin(phi) * std::cos(theta), r * std::sin(phi) * std::sin(theta), r * std::cos(phi)});
        }
    }
    m.positions.push_back({0, 0, -r});
    const auto south = uint32_t(m.positions.size() - 1);
    auto ring = [segments](uint32_t k, uint32_t s) { return 1 + (k - 1) * segments + s % segments; };
    for (uint32_t s = 0; s < segments; ++s) {
        m.triangles.insert(m.triangles.end(), {0, ring(1, s), ring(1, s + 1)});
        for (uint32_t k = 1; k + 1 < rings; ++k)
            addQuad(m, ring(k, s), ring(k + 1, s), ring(k + 1, s + 1), ring(k, s + 1));
        m.triangles.insert(m.triangles.end(), {south, ring(rings - 1, s + 1), ring(rings - 1, s)});
    }
    return m;
}

// Closed cylinder along z from -length/2 to length/2, caps fanned from their first vertex.
TestMesh cylinder(uint32_t segments, float radius, float length) {
    TestMesh m;
    for (float z : {-0.5f * length, 0.5f * length})
        for (uint32_t s = 0; s < segments; ++s) {
            const float theta = 2.0f * kPi * float(s) / float(segments);
            m.positions.push_back({radius * std::cos(theta), radius * std::sin(theta), z});
        }
    for (uint32_t s = 0; s < segments; ++s)
        addQuad(m, s, (s + 1) % segments, segments + (s + 1) % segments, segments + s);
    for (uint32_t s = 1; s + 1 < segments; ++s) {
        m.triangles.insert(m.triangles.end(), {0, s + 1, s});
        m.triangles.insert(m.triangles.end(), {segments, segments + s, segments + s + 1});
    }
    return m;
}

OccluderData compute(const TestMesh& m, int resolution = 64) {
    return computeOccluderData(m.positions, m.triangles, resolution);
}

// Every point within the box, with a tolerance relative to the box's largest half extent.
bool containsAll(const OrientedBox& b, const std::vector<glm::vec3>& points, float relative = 1e-4f) {
    const float tolerance = relative * std::max({b.half_extent.x, b.half_extent.y, b.half_extent.z, 1e-6f});
    for (const glm::vec3& p : points)
        for (int k = 0; k < 3; ++k)
            if (std::abs(glm::dot(p - b.center, b.axis[k])) > b.half_extent[k] + tolerance) return false;
    return true;
}

void expectOrthonormalRightHanded(const OrientedBox& b) {
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(glm::length(b.axis[k]), 1.0f, 1e-5f);
        EXPECT_NEAR(glm::dot(b.axis[k], b.axis[(k + 1) % 3]), 0.0f, 1e-5f);
    }
    EXPECT_GT(glm::dot(glm::cross(b.axis[0], b.axis[1]), b.axis[2]), 0.9999f);
    EXPECT_GE(b.half_extent[0], b.half_extent[1]);
    EXPECT_GE(b.half_extent[1], b.half_extent[2]);
}

void expectFinite(const OccluderData& d) {
    for (int k = 0; k < 3; ++k) {
        EXPECT_TRUE(std::isfinite(d.oobb.center[k]));
        EXPECT_TRUE(std::isfinite(d.oobb.half_extent[k]));
        EXPECT_GE(d.oobb.half_extent[k], 0.0f);
        EXPECT_TRUE(std::isfinite(d.largest_face_normal[k]));
        for (int j = 0; j < 3; ++j) EXPECT_TRUE(std::isfinite(d.oobb.axis[k][j]));
    }
    EXPECT_TRUE(std::isfinite(d.compactness));
    EXPECT_GE(d.compactness, 0.0f);
    EXPECT_LE(d.compactness, 1.0f);
}

// Deterministic across platforms, unlike the standard distributions.
struct SplitMix {
    uint64_t state;
    uint64_t next() {
        uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    float uniform(float lo, float hi) { return lo + (hi - lo) * float(next() >> 40) / float(1u << 24); }
};

glm::mat4 randomRotation(SplitMix& rng) {
    const glm::vec3 axis = glm::normalize(glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(0.1f, 1)));
    return glm::rotate(glm::mat4(1.0f), rng.uniform(0, 2 * kPi), axis);
}

TEST(Occluder, UnitCubeIsItsOwnBoxAndFullyCompact) {
    const TestMesh cube = box(glm::vec3(0), glm::vec3(1));
    const OccluderData d = compute(cube);
    EXPECT_NEAR(d.compactness, 1.0f, 0.01f);
    EXPECT_NEAR(boxVolume(d.oobb), 1.0f, 1e-4f);
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(d.oobb.center[k], 0.5f, 1e-5f);
        EXPECT_NEAR(d.oobb.half_extent[k], 0.5f, 1e-5f);
        const glm::vec3 a = glm::abs(d.oobb.axis[k]);
        EXPECT_NEAR(std::max({a.x, a.y, a.z}), 1.0f, 1e-6f);  // the local axes, in some order
    }
    expectOrthonormalRightHanded(d.oobb);
    EXPECT_TRUE(containsAll(d.oobb, cube.positions));
}

TEST(Occluder, RotatedSlabGetsItsTrueVolumeAndThinAxis) {
    const glm::mat4 rotation = glm::rotate(glm::mat4(1.0f), glm::radians(30.0f), glm::vec3(0, 0, 1)) *
                               glm::rotate(glm::mat4(1.0f), glm::radians(20.0f), glm::vec3(1, 0, 0));
    const TestMesh slab = transformed(box(glm::vec3(-5, -0.5f, -0.05f), glm::vec3(5, 0.5f, 0.05f)), rotation);
    const OccluderData d = compute(slab);
    EXPECT_NEAR(boxVolume(d.oobb), 1.0f, 0.01f);
    const glm::vec3 thin_axis = glm::vec3(rotation * glm::vec4(0, 0, 1, 0));
    EXPECT_GT(std::abs(glm::dot(d.largest_face_normal, thin_axis)), 0.999f);
    EXPECT_EQ(d.largest_face_normal, d.oobb.axis[2]);
    EXPECT_NEAR(d.compactness, 1.0f, 0.01f);
    EXPECT_NEAR(d.oobb.half_extent[0], 5.0f, 0.01f);
    EXPECT_NEAR(d.oobb.half_extent[1], 0.5f, 0.005f);
    EXPECT_NEAR(d.oobb.half_extent[2], 0.05f, 0.0005f);
    expectOrthonormalRightHanded(d.oobb);
    EXPECT_TRUE(containsAll(d.oobb, slab.positions));
}

// A cube's surface covariance is isotropic, so its principal axes are arbitrary: the face
// normals and the rotating calipers must recover the cube.
TEST(Occluder, RotatedCubeKeepsItsVolume) {
    const glm::mat4 world = glm::translate(glm::mat4(1.0f), glm::vec3(3, -2, 7)) *
                            glm::rotate(glm::mat4(1.0f), glm::radians(37.0f), glm::normalize(glm::vec3(1, 2, 3)));
    const TestMesh cube = transformed(box(glm::vec3(-1), glm::vec3(1)), world);
    const OccluderData d = compute(cube);
    EXPECT_NEAR(boxVolume(d.oobb), 8.0f, 0.08f);
    EXPECT_NEAR(d.compactness, 1.0f, 0.01f);
    EXPECT_TRUE(containsAll(d.oobb, cube.positions));
}

TEST(Occluder, SphereCompactnessIsItsPolygonOverItsSquare) {
    const TestMesh sphere = uvSphere(32, 16, 1.0f);
    const OccluderData d = compute(sphere);
    // Seen along a pole the sphere is a regular 32-gon of circumradius 1, area 16 sin(pi/16);
    // its tightest square has the 32-gon's edge-to-edge width 2 cos(pi/32) as side.
    const double polygon = 16.0 * std::sin(std::numbers::pi / 16.0);
    const double square = std::pow(2.0 * std::cos(std::numbers::pi / 32.0), 2.0);
    EXPECT_NEAR(d.compactness, polygon / square, 0.02);  // 0.788, a little above pi/4
    EXPECT_LE(boxVolume(d.oobb), 8.0f * 1.0001f);
    EXPECT_TRUE(containsAll(d.oobb, sphere.positions));
}

TEST(Occluder, DiagonalCylinderAlignsItsLongAxis) {
    const glm::vec3 direction = glm::normalize(glm::vec3(1, 2, 3));
    const glm::vec3 z(0, 0, 1);
    const glm::mat4 world =
        glm::rotate(glm::mat4(1.0f), std::acos(glm::dot(z, direction)), glm::normalize(glm::cross(z, direction)));
    const TestMesh rod = transformed(cylinder(24, 0.1f, 10.0f), world);
    const OccluderData d = compute(rod);
    EXPECT_GT(std::abs(glm::dot(d.oobb.axis[0], direction)), 0.99f);
    // 24 is a multiple of 4, so the tightest square around the 24-gon is edge-aligned.
    const float side = 2.0f * 0.1f * std::cos(kPi / 24.0f);
    EXPECT_NEAR(boxVolume(d.oobb), 10.0f * side * side, 0.01f * 10.0f * side * side);
    EXPECT_TRUE(containsAll(d.oobb, rod.positions));
}

// Three unit cubes forming an L in the 2 x 2 x 1 box [0,2]x[0,2]x[0,1]. Along z the L covers 3
// of the 4 unit squares; along x and y it covers the whole 2 x 1 face. Eq. 2:
// (A_z * 3/4 + A_x + A_y) / (A_x + A_y + A_z) = (4 * 0.75 + 2 + 2) / 8 = 0.875.
TEST(Occluder, ThreeCubeLMatchesTheHandComputedValue) {
    TestMesh l;
    addBox(l, glm::vec3(0, 0, 0), glm::vec3(2, 1, 1));
    addBox(l, glm::vec3(0, 1, 0), glm::vec3(1, 2, 1));
    const OccluderData d = compute(l);
    EXPECT_NEAR(boxVolume(d.oobb), 4.0f, 1e-4f);
    EXPECT_GT(std::abs(d.largest_face_normal.z), 0.9999f);
    EXPECT_NEAR(d.compactness, 0.875f, 0.02f);
}

// An angle bracket: two 0.2-thick plates, 2 long and 1 high, meeting at a right angle, in the
// box [0,2]x[0,2]x[0,1]. Along z the L-shaped footprint covers (0.4 + 0.4 - 0.04) / 4 = 0.19;
// along x and y the plates cover the whole face: (4 * 0.19 + 2 + 2) / 8 = 0.595.
TEST(Occluder, AngleBracketIsHalfCompact) {
    TestMesh bracket;
    addBox(bracket, glm::vec3(0, 0, 0), glm::vec3(2, 0.2f, 1));
    addBox(bracket, glm::vec3(0, 0, 0), glm::vec3(0.2f, 2, 1));
    const OccluderData d = compute(bracket);
    EXPECT_NEAR(boxVolume(d.oobb), 4.0f, 1e-4f);
    EXPECT_NEAR(d.compactness, 0.595f, 0.02f);
    EXPECT_GT(d.compactness, 0.5f);
    EXPECT_LT(d.compactness, 0.8f);
}

// Two thin rods crossing along the diagonals of a 10 x 10 square: the box is the square, and
// the rods cover little of it.
TEST(Occluder, DiagonalCrossOfRodsIsNotCompact) {
    TestMesh cross;
    for (float angle : {45.0f, -45.0f}) {
        const TestMesh rod = transformed(box(glm::vec3(-7.07f, -0.05f, -0.05f), glm::vec3(7.07f, 0.05f, 0.05f)),
                                         glm::rotate(glm::mat4(1.0f), glm::radians(angle), glm::vec3(0, 0, 1)));
        const auto base = uint32_t(cross.positions.size());
        cross.positions.insert(cross.positions.end(), rod.positions.begin(), rod.positions.end());
        for (uint32_t i : rod.triangles) cross.triangles.push_back(base + i);
    }
    const OccluderData d = compute(cross);
    EXPECT_LT(d.compactness, 0.15f);
    EXPECT_GT(std::abs(d.largest_face_normal.z), 0.999f);
}

TEST(Occluder, FlatQuadCountsOnlyItsOwnFace) {
    const glm::mat4 rotation = glm::rotate(glm::mat4(1.0f), glm::radians(25.0f), glm::normalize(glm::vec3(1, 1, 0)));
    TestMesh quad;
    quad.positions = {{0, 0, 0}, {3, 0, 0}, {3, 2, 0}, {0, 2, 0}};
    addQuad(quad, 0, 1, 2, 3);
    quad = transformed(quad, rotation);
    const OccluderData d = compute(quad);
    EXPECT_NEAR(d.compactness, 1.0f, 0.01f);
    EXPECT_GT(std::abs(glm::dot(d.largest_face_normal, glm::vec3(rotation * glm::vec4(0, 0, 1, 0)))), 0.9999f);
    EXPECT_NEAR(d.oobb.half_extent[0], 1.5f, 1e-4f);
    EXPECT_NEAR(d.oobb.half_extent[1], 1.0f, 1e-4f);
    EXPECT_LT(d.oobb.half_extent[2], 1e-5f);
    EXPECT_TRUE(containsAll(d.oobb, quad.positions));
}

TEST(Occluder, SingleTriangleHalfFillsItsRectangle) {
    TestMesh triangle;
    triangle.positions = {{0, 0, 0}, {4, 0, 1}, {1, 3, 2}};
    triangle.triangles = {0, 1, 2};
    const OccluderData d = compute(triangle);
    expectFinite(d);
    // The minimum-area rectangle around a triangle has one side on a triangle side: twice its area.
    EXPECT_NEAR(d.compactness, 0.5f, 0.03f);
    EXPECT_TRUE(containsAll(d.oobb, triangle.positions));
}

TEST(Occluder, DegenerateInputsGiveFiniteBoxesAndZeroCompactness) {
    const OccluderData empty = computeOccluderData({}, {});
    expectFinite(empty);
    EXPECT_EQ(empty.compactness, 0.0f);
    EXPECT_EQ(boxVolume(empty.oobb), 0.0f);

    TestMesh collinear;
    for (int i = 0; i < 7; ++i)
        collinear.positions.push_back(glm::vec3(1, 2, 3) + float(i) * glm::vec3(0.3f, -0.2f, 0.5f));
    collinear.triangles = {0, 1, 2, 2, 3, 6, 4, 5, 0};
    const OccluderData line = compute(collinear);
    expectFinite(line);
    EXPECT_EQ(line.compactness, 0.0f);
    EXPECT_GT(std::abs(glm::dot(line.oobb.axis[0], glm::normalize(glm::vec3(0.3f, -0.2f, 0.5f)))), 0.9999f);
    EXPECT_TRUE(containsAll(line.oobb, collinear.positions));

    TestMesh point;
    point.positions = {{1, 1, 1}, {1, 1, 1}, {1, 1, 1}};
    point.triangles = {0, 1, 2};
    const OccluderData dot = compute(point);
    expectFinite(dot);
    EXPECT_EQ(dot.compactness, 0.0f);
    EXPECT_TRUE(containsAll(dot.oobb, point.positions));

    TestMesh cloud = box(glm::vec3(0), glm::vec3(1));
    cloud.triangles.clear();  // vertices without triangles: a box, but nothing to project
    const OccluderData no_triangles = compute(cloud);
    expectFinite(no_triangles);
    EXPECT_EQ(no_triangles.compactness, 0.0f);
    EXPECT_NEAR(boxVolume(no_triangles.oobb), 1.0f, 1e-4f);
}

TEST(Occluder, IgnoresOutOfRangeAndTrailingIndices) {
    TestMesh cube = box(glm::vec3(0), glm::vec3(1));
    const OccluderData clean = compute(cube);
    cube.triangles.insert(cube.triangles.end(), {0, 1, 99, 0, 1});
    const OccluderData messy = compute(cube);
    EXPECT_EQ(messy.compactness, clean.compactness);
    EXPECT_EQ(boxVolume(messy.oobb), boxVolume(clean.oobb));
}

TEST(Occluder, ResolutionBelowOneMeansOnePixel) {
    const TestMesh sphere = uvSphere(16, 8, 1.0f);
    EXPECT_EQ(compute(sphere, 1).compactness, 1.0f);  // the single pixel centre is the disk's centre
    EXPECT_EQ(compute(sphere, 0).compactness, 1.0f);
    EXPECT_EQ(compute(sphere, -3).compactness, 1.0f);
}

// Pixel centres on shared edges and on a shared vertex must be covered by some triangle: a fan
// over the unit square whose apex and edges run through pixel centres covers the whole raster.
TEST(Occluder, SharedEdgesLeaveNoCracks) {
    constexpr int kResolution = 61;  // odd, so the apex (0.5, 0.5) is a pixel centre
    TestMesh fan;
    fan.positions = {{0.5f, 0.5f, 0}, {0, 0, 0}};
    // Bottom side points at pixel-centre x, so the edges to them cross pixel centres (the one at
    // x = 0.5 is vertical through a whole column); the diagonals to the corners cross them all.
    for (int k = 0; k < kResolution; ++k) fan.positions.push_back({(float(k) + 0.5f) / kResolution, 0, 0});
    fan.positions.insert(fan.positions.end(), {{1, 0, 0}, {1, 1, 0}, {0, 1, 0}});
    const auto ring = uint32_t(fan.positions.size() - 1);
    for (uint32_t i = 1; i < ring; ++i) fan.triangles.insert(fan.triangles.end(), {0, i, i + 1});
    fan.triangles.insert(fan.triangles.end(), {0, ring, 1});
    // Unreferenced corners on top make the box the unit cube without adding anything to project.
    fan.positions.insert(fan.positions.end(), {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}});
    const OccluderData d = compute(fan, kResolution);
    EXPECT_NEAR(boxVolume(d.oobb), 1.0f, 1e-4f);
    // Along z the fan covers its whole face; along x and y it is a segment and covers nothing.
    // With all three faces of area 1, Eq. 2 gives exactly 1/3; one missed pixel would cost 1/11163.
    EXPECT_NEAR(d.compactness, 1.0f / 3.0f, 1e-6f);
}

TEST(Occluder, RandomMeshesStayInsideTheirBoxes) {
    SplitMix rng{2024};
    for (int trial = 0; trial < 40; ++trial) {
        TestMesh m;
        // Large trials exercise the thinned hull.
        const int n = trial % 8 == 7 ? 6000 : 3 + int(rng.next() % 200);
        const glm::vec3 stretch(rng.uniform(0.01f, 10), rng.uniform(0.01f, 10), rng.uniform(0.0f, 10));
        const glm::mat4 world =
            glm::translate(glm::mat4(1.0f),
                           glm::vec3(rng.uniform(-100, 100), rng.uniform(-100, 100), rng.uniform(-100, 100))) *
            randomRotation(rng);
        for (int i = 0; i < n; ++i) {
            const glm::vec3 p = stretch * glm::vec3(rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1));
            m.positions.push_back(glm::vec3(world * glm::vec4(p, 1.0f)));
        }
        for (int t = 0; t < n; ++t)
            for (int c = 0; c < 3; ++c) m.triangles.push_back(uint32_t(rng.next() % uint64_t(n)));
        const OccluderData d = compute(m);
        expectFinite(d);
        expectOrthonormalRightHanded(d.oobb);
        EXPECT_TRUE(containsAll(d.oobb, m.positions)) << "trial " << trial;
        EXPECT_TRUE(containsAll(d.oobb, m.positions, 0.0f)) << "trial " << trial;  // even without tolerance
        // Never worse than the local axis-aligned box.
        Bounds aabb;
        for (const glm::vec3& p : m.positions) aabb.extend(p);
        const glm::vec3 size = aabb.max - aabb.min;
        EXPECT_LE(boxVolume(d.oobb), size.x * size.y * size.z * 1.001f + 1e-3f) << "trial " << trial;
    }
}

// Far from the origin a float centre is off by up to half an ulp of its coordinates; the
// padding must absorb that.
TEST(Occluder, BoxFarFromTheOriginStillContainsItsVertices) {
    const glm::mat4 world = glm::translate(glm::mat4(1.0f), glm::vec3(5000.3f, -3000.7f, 2000.1f)) *
                            glm::rotate(glm::mat4(1.0f), glm::radians(33.0f), glm::normalize(glm::vec3(3, 1, 2)));
    const TestMesh part = transformed(box(glm::vec3(-0.5f, -0.25f, -0.1f), glm::vec3(0.5f, 0.25f, 0.1f)), world);
    const OccluderData d = compute(part);
    EXPECT_TRUE(containsAll(d.oobb, part.positions, 0.0f));
    EXPECT_NEAR(boxVolume(d.oobb), 0.1f, 0.01f * 0.1f);
    EXPECT_NEAR(d.compactness, 1.0f, 0.01f);
}

TEST(Occluder, FinelyTessellatedSphereUsesTheThinnedHull) {
    const TestMesh sphere = uvSphere(128, 64, 2.0f);  // 8 000 vertices, above the exact-hull limit
    const OccluderData d = compute(sphere);
    EXPECT_TRUE(containsAll(d.oobb, sphere.positions));
    EXPECT_NEAR(boxVolume(d.oobb), 64.0f, 0.01f * 64.0f);
    EXPECT_NEAR(d.compactness, kPi / 4.0f, 0.02f);
}

TEST(TransformBox, RotationTranslationAndScaleAlongTheAxesAreExact) {
    const TestMesh slab = box(glm::vec3(-2, -1, -0.25f), glm::vec3(2, 1, 0.25f));
    const OccluderData d = compute(slab);
    const glm::mat4 world = glm::translate(glm::mat4(1.0f), glm::vec3(10, -4, 2)) *
                            glm::rotate(glm::mat4(1.0f), glm::radians(50.0f), glm::normalize(glm::vec3(2, -1, 1))) *
                            glm::scale(glm::mat4(1.0f), glm::vec3(0.5f, 3.0f, 2.0f));
    const OrientedBox w = transformBox(d.oobb, world);
    const TestMesh moved = transformed(slab, world);
    EXPECT_TRUE(containsAll(w, moved.positions));
    EXPECT_NEAR(boxVolume(w), boxVolume(d.oobb) * 3.0f, 1e-3f);  // det = 0.5 * 3 * 2
    // The image is again a box, whose corners all lie on the transformed box's surface.
    for (int k = 0; k < 3; ++k) {
        float reach = 0.0f;
        for (const glm::vec3& p : moved.positions) reach = std::max(reach, std::abs(glm::dot(p - w.center, w.axis[k])));
        EXPECT_NEAR(reach, w.half_extent[k], 1e-4f);
    }
    expectOrthonormalRightHanded(w);
    // The scale made local y (3 * 1) the longest extent, then x (0.5 * 2), then z (2 * 0.25).
    EXPECT_NEAR(w.half_extent[0], 3.0f, 1e-4f);
    EXPECT_GT(std::abs(glm::dot(w.axis[0], glm::vec3(world * glm::vec4(0, 1, 0, 0))) / 3.0f), 0.9999f);
}

TEST(TransformBox, ShearIsConservative) {
    SplitMix rng{99};
    for (int trial = 0; trial < 20; ++trial) {
        const TestMesh cube = transformed(box(glm::vec3(-1, -2, -0.5f), glm::vec3(1, 2, 0.5f)), randomRotation(rng));
        const OccluderData d = compute(cube);
        glm::mat4 world(1.0f);
        for (int c = 0; c < 3; ++c)
            for (int r = 0; r < 3; ++r) world[c][r] = rng.uniform(-2, 2);
        world[3] = glm::vec4(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(-5, 5), 1.0f);
        const OrientedBox w = transformBox(d.oobb, world);
        EXPECT_TRUE(containsAll(w, transformed(cube, world).positions)) << "trial " << trial;
        const float image_volume = boxVolume(d.oobb) * std::abs(glm::determinant(glm::mat3(world)));
        EXPECT_GE(boxVolume(w), image_volume * 0.999f);
        expectOrthonormalRightHanded(w);
    }
}

TEST(TransformBox, SingularTransformFlattensTheBox) {
    const OccluderData d = compute(box(glm::vec3(0), glm::vec3(1, 2, 3)));
    const glm::mat4 flatten = glm::scale(glm::mat4(1.0f), glm::vec3(1, 1, 0));
    const OrientedBox w = transformBox(d.oobb, flatten);
    EXPECT_LT(w.half_extent[2], 1e-5f);
    EXPECT_NEAR(w.half_extent[0], 1.0f, 1e-5f);
    EXPECT_NEAR(w.half_extent[1], 0.5f, 1e-5f);
    expectOrthonormalRightHanded(w);
}

TEST(Occluder, BoxVolumeIsEightTimesTheHalfExtents) {
    OrientedBox b;
    b.half_extent = {1.0f, 2.0f, 0.5f};
    EXPECT_EQ(boxVolume(b), 8.0f);
}

}  // namespace
}  // namespace occ
