// SPDX-License-Identifier: MIT
#include "prep/hausdorff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

namespace occ {
namespace {

struct TriangleMesh {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
};

// The unit square [0, 1]^2 at height z, two triangles, normal +z.
TriangleMesh square(float z) {
    return {{{0, 0, z}, {1, 0, z}, {1, 1, z}, {0, 1, z}}, {0, 1, 2, 0, 2, 3}};
}

// Closed axis-aligned cube [-h, h]^3, 12 triangles, outward normals.
TriangleMesh cube(float h) {
    TriangleMesh m;
    for (int i = 0; i < 8; ++i) m.positions.push_back({i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h});
    m.triangles = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                   2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
    return m;
}

// An n x n height field over [0, 1]^2 with bumps, so that the closest triangle of a point is
// rarely the one straight below it.
TriangleMesh bumpyGrid(int n) {
    TriangleMesh m;
    for (int y = 0; y <= n; ++y)
        for (int x = 0; x <= n; ++x) {
            const float fx = float(x) / float(n), fy = float(y) / float(n);
            m.positions.push_back({fx, fy, 0.1f * std::sin(17.0f * fx) * std::cos(11.0f * fy)});
        }
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const uint32_t v = uint32_t(y * (n + 1) + x);
            m.triangles.insert(m.triangles.end(), {v, v + 1, v + uint32_t(n) + 2, v, v + uint32_t(n) + 2, v + uint32_t(n) + 1});
        }
    return m;
}

HausdorffDistance hausdorff(const TriangleMesh& a, const TriangleMesh& b, uint32_t samples = 2000) {
    return sampledHausdorff(a.positions, a.triangles, b.positions, b.triangles, {samples, 7});
}

TEST(ClosestPointOnTriangle, EachVoronoiRegion) {
    const glm::vec3 a{0, 0, 0}, b{2, 0, 0}, c{0, 2, 0};
    EXPECT_EQ(closestPointOnTriangle({-1, -1, 3}, a, b, c), a);
    EXPECT_EQ(closestPointOnTriangle({3, -1, 0}, a, b, c), b);
    EXPECT_EQ(closestPointOnTriangle({-1, 3, 0}, a, b, c), c);
    EXPECT_EQ(closestPointOnTriangle({1, -5, 1}, a, b, c), glm::vec3(1, 0, 0));    // edge AB
    EXPECT_EQ(closestPointOnTriangle({-4, 1, -1}, a, b, c), glm::vec3(0, 1, 0));   // edge AC
    EXPECT_EQ(closestPointOnTriangle({2, 2, 0}, a, b, c), glm::vec3(1, 1, 0));     // edge BC
    EXPECT_EQ(closestPointOnTriangle({0.5f, 0.5f, -4}, a, b, c), glm::vec3(0.5f, 0.5f, 0));  // face
}

TEST(ClosestPointOnTriangle, DegenerateTrianglesGiveTheClosestPointOfTheirSegments) {
    // Collinear corners: a segment from (0,0,0) to (4,0,0) with a middle corner.
    const glm::vec3 on_segment = closestPointOnTriangle({1, 3, 0}, {0, 0, 0}, {4, 0, 0}, {2, 0, 0});
    EXPECT_EQ(on_segment, glm::vec3(1, 0, 0));
    // Two coincident corners: still a segment, no 0/0.
    const glm::vec3 coincident = closestPointOnTriangle({1, 1, 0}, {0, 0, 0}, {0, 0, 0}, {2, 0, 0});
    EXPECT_EQ(coincident, glm::vec3(1, 0, 0));
    // All three at one point.
    EXPECT_EQ(closestPointOnTriangle({1, 1, 1}, {3, 3, 3}, {3, 3, 3}, {3, 3, 3}), glm::vec3(3, 3, 3));
}

TEST(ClosestPointOnTriangle, NoPointOfTheTriangleIsCloser) {
    // Random triangles (some squashed flat or to a point) and points, against a dense grid of
    // barycentric points of each triangle.
    uint32_t state = 12345;
    const auto next = [&state] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24) * 2.0f - 1.0f;
    };
    for (int trial = 0; trial < 300; ++trial) {
        glm::vec3 v[3], p{next(), next(), next()};
        for (glm::vec3& c : v) c = {next(), next(), next()};
        if (trial % 10 == 1) v[2] = v[0] + 0.3f * (v[1] - v[0]);  // collinear
        if (trial % 10 == 2) v[1] = v[0];                          // two corners coincide
        if (trial % 10 == 3) v[1] = v[2] = v[0];                   // a point
        const glm::vec3 q = closestPointOnTriangle(p, v[0], v[1], v[2]);
        const float d = glm::length(p - q);
        constexpr int kSteps = 60;
        for (int i = 0; i <= kSteps; ++i)
            for (int j = 0; i + j <= kSteps; ++j) {
                const float s = float(i) / kSteps, t = float(j) / kSteps;
                const glm::vec3 g = v[0] + s * (v[1] - v[0]) + t * (v[2] - v[0]);
                ASSERT_LE(d, glm::length(p - g) + 1e-5f) << "trial " << trial;
            }
    }
}

TEST(SampleSurface, VerticesFirstThenAreaSamplesOnTheSurfaceAndRepeatable) {
    const TriangleMesh m = square(0.0f);
    const std::vector<glm::vec3> s = sampleSurface(m.positions, m.triangles, 1000, 3);
    ASSERT_EQ(s.size(), 4u + 1000u);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(s[i], m.positions[i]);
    float lower_left = 0;  // samples in the quarter [0, 0.5)^2
    for (const glm::vec3& p : s) {
        EXPECT_GE(p.x, 0.0f);
        EXPECT_LE(p.x, 1.0f);
        EXPECT_GE(p.y, 0.0f);
        EXPECT_LE(p.y, 1.0f);
        EXPECT_EQ(p.z, 0.0f);
        lower_left += p.x < 0.5f && p.y < 0.5f;
    }
    // Area-uniform: a quarter of the square gets about a quarter of the samples.
    EXPECT_NEAR(lower_left / 1000.0f, 0.25f, 0.05f);
    EXPECT_EQ(s, sampleSurface(m.positions, m.triangles, 1000, 3));
    EXPECT_NE(s, sampleSurface(m.positions, m.triangles, 1000, 4));
}

TEST(SampleSurface, UnusedVerticesAndZeroAreaTrianglesGetNoSamples) {
    const std::vector<glm::vec3> p{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {9, 9, 9}};
    const std::vector<uint32_t> t{0, 1, 2};  // collinear: no area; vertex 3 unused
    EXPECT_EQ(sampleSurface(p, t, 100, 1), (std::vector<glm::vec3>{{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}));
}

TEST(SampledHausdorff, IdenticalMeshesAreZeroApart) {
    const TriangleMesh m = bumpyGrid(20);
    const HausdorffDistance d = hausdorff(m, m);
    EXPECT_NEAR(d.max, 0.0, 1e-6);
    EXPECT_NEAR(d.mean, 0.0, 1e-7);
    EXPECT_EQ(d.samples, 2u * (21u * 21u + 2000u));
}

TEST(SampledHausdorff, SquareLiftedAlongItsNormalIsHalfAway) {
    const HausdorffDistance d = hausdorff(square(0.0f), square(0.5f));
    EXPECT_NEAR(d.max, 0.5, 1e-6);
    EXPECT_NEAR(d.mean, 0.5, 1e-6);  // every point of one is straight above/below the other
    EXPECT_NEAR(d.a_to_b, 0.5, 1e-6);
    EXPECT_NEAR(d.b_to_a, 0.5, 1e-6);
}

TEST(SampledHausdorff, CubeAndConcentricHalfSizeCube) {
    // Outer cube [-1, 1]^3, inner [-0.5, 0.5]^3. A point of the inner surface has one
    // coordinate at +-0.5 and the others within [-0.5, 0.5], so its nearest outer face is
    // 1 - 0.5 = 0.5 away, and never nearer: inner -> outer is 0.5 everywhere. The outer
    // corner (1, 1, 1) is farthest from the inner cube, at the inner corner (0.5, 0.5, 0.5):
    // sqrt(3) * 0.5. Corners are vertices, so samples hit it exactly.
    const HausdorffDistance d = hausdorff(cube(1.0f), cube(0.5f));
    EXPECT_NEAR(d.a_to_b, std::sqrt(3.0) * 0.5, 1e-6);
    EXPECT_NEAR(d.b_to_a, 0.5, 1e-6);
    EXPECT_NEAR(d.max, std::sqrt(3.0) * 0.5, 1e-6);
    // The outer face centre is 0.5 from the inner one, so every outer point is at least 0.5.
    EXPECT_GT(d.mean, 0.5);
    EXPECT_LT(d.mean, std::sqrt(3.0) * 0.5);
}

TEST(SampledHausdorff, SymmetricInItsArguments) {
    const TriangleMesh a = bumpyGrid(12), b = cube(0.6f);
    const HausdorffDistance ab = hausdorff(a, b), ba = hausdorff(b, a);
    EXPECT_EQ(ab.max, ba.max);
    EXPECT_EQ(ab.mean, ba.mean);
    EXPECT_EQ(ab.a_to_b, ba.b_to_a);
    EXPECT_EQ(ab.b_to_a, ba.a_to_b);
}

TEST(SampledHausdorff, HierarchyFindsTheSameClosestTrianglesAsBruteForce) {
    // Bumps make the closest triangle far from the one below; the search must not prune it.
    TriangleMesh a = bumpyGrid(25);
    const TriangleMesh b = bumpyGrid(7);
    for (glm::vec3& p : a.positions) p.z *= -1.5f;
    const HausdorffDistance d = hausdorff(a, b, 500);
    const auto brute = [](const TriangleMesh& from, const TriangleMesh& to) {
        double worst = 0.0;
        for (const glm::vec3& p : sampleSurface(from.positions, from.triangles, 500, 7)) {
            float best = std::numeric_limits<float>::infinity();
            for (size_t t = 0; t < to.triangles.size(); t += 3) {
                const glm::vec3 q = closestPointOnTriangle(p, to.positions[to.triangles[t]],
                                                           to.positions[to.triangles[t + 1]],
                                                           to.positions[to.triangles[t + 2]]);
                best = std::min(best, glm::dot(p - q, p - q));
            }
            worst = std::max(worst, std::sqrt(double(best)));
        }
        return worst;
    };
    EXPECT_DOUBLE_EQ(d.a_to_b, brute(a, b));
    EXPECT_DOUBLE_EQ(d.b_to_a, brute(b, a));
}

TEST(SampledHausdorff, EmptyMeshIsInfinitelyFarAndTwoEmptyOnesCoincide) {
    const TriangleMesh m = square(0.0f), none;
    const double inf = std::numeric_limits<double>::infinity();
    const HausdorffDistance d = hausdorff(m, none);
    EXPECT_EQ(d.max, inf);
    EXPECT_EQ(d.mean, inf);
    EXPECT_EQ(d.a_to_b, inf);
    EXPECT_EQ(d.b_to_a, 0.0);
    EXPECT_EQ(hausdorff(none, m).b_to_a, inf);
    const HausdorffDistance both = hausdorff(none, none);
    EXPECT_EQ(both.max, 0.0);
    EXPECT_EQ(both.samples, 0u);
}

// Per-triangle caps bound what a sample counts: a tiny triangle 10 above a square, missing from
// the other surface, counts its own extent instead of its distance; the other direction and
// the uncapped measure are unchanged, and a surface measured against nothing gives its largest cap.
TEST(SampledHausdorff, CapsBoundWhatAVanishedComponentCounts) {
    TriangleMesh both = square(0.0f);
    both.positions.insert(both.positions.end(), {{0.5f, 0.5f, 10.0f}, {0.51f, 0.5f, 10.0f}, {0.5f, 0.51f, 10.0f}});
    both.triangles.insert(both.triangles.end(), {4, 5, 6});
    const TriangleMesh plain = square(0.0f), none;
    const float tiny = std::sqrt(2.0f) * 0.01f;
    const std::vector<float> caps{100.0f, 100.0f, tiny};
    const HausdorffOptions options{2000, 7};
    const SampledSurface capped(both.positions, both.triangles, options, caps);
    const SampledSurface uncapped(both.positions, both.triangles, options);
    const SampledSurface other(plain.positions, plain.triangles, options);
    EXPECT_GT(uncapped.distanceTo(other).a_to_b, 9.99);
    const HausdorffDistance d = capped.distanceTo(other);
    EXPECT_NEAR(d.a_to_b, tiny, 1e-6);
    EXPECT_EQ(d.b_to_a, uncapped.distanceTo(other).b_to_a);
    EXPECT_NEAR(other.distanceTo(capped).b_to_a, tiny, 1e-6);
    const std::vector<glm::vec3> points{{0.5f, 0.5f, 10.0f}, {0.2f, 0.2f, 0.5f}};
    EXPECT_NEAR(other.farthestFrom(points), 10.0, 1e-5);
    EXPECT_NEAR(other.farthestFrom(points, std::vector<float>{0.25f, 1.0f}), 0.5, 1e-6);
    const SampledSurface empty(none.positions, none.triangles, options);
    EXPECT_EQ(capped.distanceTo(empty).a_to_b, 100.0);
    EXPECT_EQ(empty.farthestFrom(points, std::vector<float>{0.25f, 1.0f}), 1.0);
    EXPECT_THROW(SampledSurface(both.positions, both.triangles, options, std::vector<float>{1.0f}), std::invalid_argument);
    EXPECT_THROW(other.farthestFrom(points, std::vector<float>{1.0f}), std::invalid_argument);
}

}  // namespace
// The max-only measure (calibration's) stops a sample's search once a triangle is nearer than
// the largest distance so far and looks no farther than its cap: the same largest distance, to
// the bit, as the full measure, with and without caps, either way round.
TEST(SampledHausdorff, TheMaxAloneIsTheFullMeasuresMax) {
    TriangleMesh a = bumpyGrid(25);
    for (glm::vec3& p : a.positions) p.z *= -1.5f;
    const TriangleMesh b = bumpyGrid(7), c = cube(0.6f);
    std::vector<float> caps(a.triangles.size() / 3);
    for (size_t t = 0; t < caps.size(); ++t) caps[t] = 0.05f + 0.5f * float(t % 7) / 7.0f;
    const HausdorffOptions options{3000, 11};
    const SampledSurface sa(a.positions, a.triangles, options), sb(b.positions, b.triangles, options),
        sc(c.positions, c.triangles, options), capped(a.positions, a.triangles, options, caps);
    for (const auto& [x, y] : {std::pair{&sa, &sb}, {&sb, &sa}, {&sa, &sc}, {&sc, &sb}, {&capped, &sb}, {&sb, &capped},
                               {&capped, &sc}})
        EXPECT_EQ(x->maxDistanceTo(*y), x->distanceTo(*y).max);
    std::vector<glm::vec3> points = sampleSurface(a.positions, a.triangles, 500, 3);
    std::vector<float> point_caps(points.size());
    for (size_t i = 0; i < points.size(); ++i) point_caps[i] = 0.02f * float(i % 13);
    double worst = 0.0, worst_capped = 0.0;
    for (size_t i = 0; i < points.size(); ++i) {
        float best = std::numeric_limits<float>::infinity();
        for (size_t t = 0; t < b.triangles.size(); t += 3) {
            const glm::vec3 q = closestPointOnTriangle(points[i], b.positions[b.triangles[t]], b.positions[b.triangles[t + 1]],
                                                       b.positions[b.triangles[t + 2]]);
            best = std::min(best, glm::dot(points[i] - q, points[i] - q));
        }
        worst = std::max(worst, std::sqrt(double(best)));
        worst_capped = std::max(worst_capped, std::min(std::sqrt(double(best)), double(point_caps[i])));
    }
    EXPECT_EQ(sb.farthestFrom(points), worst);
    EXPECT_EQ(sb.farthestFrom(points, point_caps), worst_capped);
}

}  // namespace occ
