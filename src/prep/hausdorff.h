// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace occ {

// The point of triangle abc closest to p (Ericson 2005, Real-Time Collision Detection,
// §5.1.5: Voronoi regions of the three vertices, then of the three edges, then the face).
// Degenerate triangles (collinear or coincident corners) are handled: the result is then the
// closest point of the segments, never NaN.
glm::vec3 closestPointOnTriangle(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c);

struct HausdorffOptions {
    uint32_t samples = 20000;  // area-uniform samples per surface, on top of its vertices
    uint64_t seed = 1;         // same seed, same meshes: same samples, same result
    bool vertices = true;      // sample the vertices too (false: a SampledSurface whose vertices
                               // are known to lie on the other surface, such as a level of
                               // detail whose positions are a subset of its full detail's)
};

// Distances between two surfaces A and B, measured at sample points. A one-sided distance is
// the largest distance from a sample of one surface to the closest point of the other; each
// is a lower bound of the exact one-sided Hausdorff distance and converges to it as samples
// grow (exact wherever the farthest point is a vertex or the two surfaces are parallel).
struct HausdorffDistance {
    double max = 0.0;         // symmetric Hausdorff distance: max(a_to_b, b_to_a)
    double mean = 0.0;        // mean distance over the samples of both directions
    double a_to_b = 0.0;      // largest distance from a sample of A to B
    double b_to_a = 0.0;      // largest distance from a sample of B to A
    uint64_t samples = 0;     // sample points measured, both directions
};

// Points on a surface: every vertex some triangle uses, once each, in order of first use
// (unless `vertices` is false), then `count` area-uniform points (stratified along the
// cumulative area, jittered with a seeded generator, so large triangles get samples in
// proportion and results repeat exactly). Triangles of zero area get no area samples; with no
// area at all only vertices are returned.
// triangles: 3 indices per triangle, each < positions.size(); may be empty (no points).
std::vector<glm::vec3> sampleSurface(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles,
                                     uint32_t count, uint64_t seed, bool vertices = true);

// Sampled symmetric Hausdorff distance between triangle meshes A and B: the samples of each
// (sampleSurface with options.samples and options.seed) are measured against the other's
// triangles exactly (closestPointOnTriangle), through a bounding volume hierarchy, so 20 000
// samples against 20 000 triangles take milliseconds. Single-threaded; callers parallelise
// over mesh pairs.
// Empty meshes (no triangles): both empty gives all zeros. One empty gives +infinity for
// max, mean and the direction from the non-empty surface (every point is infinitely far from
// nothing), and 0 for the direction from the empty one (a maximum over no samples).
// Callers that want a finite score for a vanished LOD cap it themselves (the bench counts it
// as one bounding-box diagonal, the farthest any non-empty subset of the box can be).
// Triangles: 3 indices per triangle, each < its positions.size(); unused positions are ignored.
HausdorffDistance sampledHausdorff(std::span<const glm::vec3> a_positions, std::span<const uint32_t> a_triangles,
                                   std::span<const glm::vec3> b_positions, std::span<const uint32_t> b_triangles,
                                   const HausdorffOptions& options = {});

// A surface made ready to be measured against others: its samples (sampleSurface) and its
// triangle hierarchy, made once. One surface measured against many (the levels of one
// progressive mesh against its full detail) saves rebuilding them for each pair.
class SampledSurface {
public:
    // triangle_cap (empty, or one value per triangle): the most a sample of that triangle counts
    // in this surface's direction of distanceTo, e.g. the extent of the triangle's connected
    // component (a component that vanishes whole changes a picture only within its own extent).
    // A vertex sample takes the cap of the first triangle that uses it. With caps, a direction
    // from this surface to an empty one is its largest cap instead of +infinity.
    SampledSurface(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles,
                   const HausdorffOptions& options = {}, std::span<const float> triangle_cap = {});
    ~SampledSurface();
    SampledSurface(SampledSurface&&) noexcept;
    SampledSurface& operator=(SampledSurface&&) noexcept;

    // sampledHausdorff(this surface as A, other as B), with each surface's own options.
    HausdorffDistance distanceTo(const SampledSurface& other) const;
    // distanceTo(other).max, the same value found with less work (no mean).
    double maxDistanceTo(const SampledSurface& other) const;
    // The largest distance from one of `points` to this surface (+infinity when it is empty and
    // there are points, 0 when there are none); with `caps` (one per point), point i's distance
    // counts at most caps[i].
    double farthestFrom(std::span<const glm::vec3> points, std::span<const float> caps = {}) const;

private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace occ
