// SPDX-License-Identifier: MIT
#include "prep/hausdorff.h"

#include "scene/splitmix.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <stdexcept>
#include <utility>

namespace occ {

namespace {

constexpr uint32_t kNoTriangle = UINT32_MAX;

// Numerator / denominator of an edge parameter, clamped to the edge: the denominator is the
// squared edge length, zero when two corners coincide, and rounding may push the ratio a hair
// outside [0, 1].
float edgeParameter(float numerator, float denominator) {
    return denominator > 0.0f ? std::clamp(numerator / denominator, 0.0f, 1.0f) : 0.0f;
}

glm::vec3 closestPointOnSegment(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b) {
    const glm::vec3 ab = b - a;
    return a + ab * edgeParameter(glm::dot(p - a, ab), glm::dot(ab, ab));
}

float distance2(const glm::vec3& a, const glm::vec3& b) {
    const glm::vec3 d = a - b;
    return glm::dot(d, d);
}

// Ericson's routine (see closestPointOnTriangle in the header), inline because the hierarchy
// calls it for every triangle of every leaf it opens, about ten per query.
inline glm::vec3 closestPoint(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    const glm::vec3 ab = b - a, ac = c - a, ap = p - a;
    const float d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
    if (d1 <= 0.0f && d2 <= 0.0f) return a;  // vertex region A

    const glm::vec3 bp = p - b;
    const float d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
    if (d3 >= 0.0f && d4 <= d3) return b;  // vertex region B

    // d1 - d3 = |ab|^2, and likewise below. Ericson's tests pass trivially for an edge of
    // length zero (all terms 0) and would return its end; requiring a positive length leaves
    // such a point to the other edges, which are then the triangle.
    const float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0f && d1 >= 0.0f && d3 <= 0.0f && d1 > d3) return a + ab * edgeParameter(d1, d1 - d3);  // edge AB

    const glm::vec3 cp = p - c;
    const float d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
    if (d6 >= 0.0f && d5 <= d6) return c;  // vertex region C

    const float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0f && d2 >= 0.0f && d6 <= 0.0f && d2 > d6) return a + ac * edgeParameter(d2, d2 - d6);  // edge AC

    const float va = d3 * d6 - d5 * d4;
    if (va <= 0.0f && d4 - d3 >= 0.0f && d5 - d6 >= 0.0f && (d4 - d3) + (d5 - d6) > 0.0f)
        return b + (c - b) * edgeParameter(d4 - d3, (d4 - d3) + (d5 - d6));  // edge BC

    // Face region: va, vb, vc are the barycentric weights scaled by the squared double area.
    // Only rounding on a (near-)degenerate triangle gets here with a weight <= 0; then the
    // closest point is on the boundary and the segments give it without dividing by ~0.
    const float sum = va + vb + vc;
    if (!(va > 0.0f && vb > 0.0f && vc > 0.0f && sum > 0.0f)) {
        const glm::vec3 candidates[3] = {closestPointOnSegment(p, a, b), closestPointOnSegment(p, a, c),
                                         closestPointOnSegment(p, b, c)};
        int best = 0;
        for (int i = 1; i < 3; ++i)
            if (distance2(p, candidates[i]) < distance2(p, candidates[best])) best = i;
        return candidates[best];
    }
    return a + ab * (vb / sum) + ac * (vc / sum);
}

// Uniform in [0, 1) from our seeded generator (scene/splitmix.h): the same samples on every
// platform, unlike std::uniform_real_distribution whose output the standard leaves open.
double uniform(SplitMix64& rng) { return double(rng.next() >> 11) * 0x1.0p-53; }

// Bounding volume hierarchy over the triangles of one mesh, for closest-point queries: binary,
// median split of the centroids along the longest axis, up to kLeafSize triangles per leaf.
// The corners are copied in leaf order so a leaf reads one contiguous run of memory.
class TriangleBvh {
public:
    TriangleBvh(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles) {
        const uint32_t tc = uint32_t(triangles.size() / 3);
        if (tc == 0) return;
        std::vector<glm::vec3> centroid(tc);
        for (uint32_t t = 0; t < tc; ++t)
            centroid[t] = (positions[triangles[3 * t]] + positions[triangles[3 * t + 1]] +
                           positions[triangles[3 * t + 2]]) / 3.0f;
        std::vector<uint32_t> order(tc);
        std::iota(order.begin(), order.end(), 0u);
        nodes_.reserve(2 * (tc / kLeafSize + 1));
        nodes_.push_back({});
        // Ranges of `order` still to split, from an explicit stack; a node's two children are
        // appended together, after it, which the bottom-up bounds pass below relies on.
        struct Range {
            uint32_t node, first, end;
        };
        std::vector<Range> todo{{0, 0, tc}};
        while (!todo.empty()) {
            const Range r = todo.back();
            todo.pop_back();
            if (r.end - r.first <= kLeafSize) {
                nodes_[r.node].first = r.first;
                nodes_[r.node].count = r.end - r.first;
                continue;
            }
            glm::vec3 cmin(std::numeric_limits<float>::max()), cmax(std::numeric_limits<float>::lowest());
            for (uint32_t i = r.first; i < r.end; ++i) {
                cmin = glm::min(cmin, centroid[order[i]]);
                cmax = glm::max(cmax, centroid[order[i]]);
            }
            const glm::vec3 extent = cmax - cmin;
            const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
            const uint32_t mid = r.first + (r.end - r.first) / 2;
            std::nth_element(order.begin() + r.first, order.begin() + mid, order.begin() + r.end,
                             [&](uint32_t x, uint32_t y) { return centroid[x][axis] < centroid[y][axis]; });
            const uint32_t left = uint32_t(nodes_.size());
            nodes_[r.node].first = left;
            nodes_.push_back({});
            nodes_.push_back({});
            todo.push_back({left, r.first, mid});
            todo.push_back({left + 1, mid, r.end});
        }
        corners_.resize(size_t(tc) * 3);
        for (uint32_t i = 0; i < tc; ++i)
            for (int c = 0; c < 3; ++c) corners_[3 * i + c] = positions[triangles[3 * order[i] + c]];
        // Bounds bottom-up: children always come after their parent, so a reverse sweep sees
        // both children of a node before the node, and each corner is read once.
        for (uint32_t n = uint32_t(nodes_.size()); n-- > 0;) {
            Node& node = nodes_[n];
            if (node.count > 0) {
                for (uint32_t i = 3 * node.first; i < 3 * (node.first + node.count); ++i) {
                    node.min = glm::min(node.min, corners_[i]);
                    node.max = glm::max(node.max, corners_[i]);
                }
            } else {
                node.min = glm::min(nodes_[node.first].min, nodes_[node.first + 1].min);
                node.max = glm::max(nodes_[node.first].max, nodes_[node.first + 1].max);
            }
        }
    }

    // Squared distance from p to the closest triangle, and that triangle (leaf order) so the
    // next, nearby query can start from it: its distance bounds the search from the start.
    // Only triangles nearer than `bound` (a squared distance) are looked for: none nearer
    // gives kNoTriangle. The search stops as soon as one is within `enough` (squared): then the
    // distance returned is that one's, not necessarily the smallest.
    std::pair<float, uint32_t> closest(const glm::vec3& p, uint32_t hint,
                                       float bound = std::numeric_limits<float>::infinity(), float enough = -1.0f) const {
        float best = bound;
        uint32_t best_triangle = kNoTriangle;
        if (hint != kNoTriangle) {
            const float d = distance2(p, triangleClosest(p, hint));
            if (d < best) best = d, best_triangle = hint;
            if (best <= enough) return {best, best_triangle};
        }
        // Pending nodes with their box distance, so a node pushed before best shrank is dropped
        // on pop without measuring its box again. Depth <= log2(triangles) + 1 (median splits).
        struct Pending {
            uint32_t node;
            float distance2;
        };
        Pending stack[64];
        int top = 0;
        const float root = boxDistance2(p, nodes_[0]);
        if (root < best) stack[top++] = {0, root};
        while (top > 0) {
            const Pending pending = stack[--top];
            if (pending.distance2 >= best) continue;
            const Node& node = nodes_[pending.node];
            if (node.count > 0) {
                for (uint32_t t = node.first; t < node.first + node.count; ++t) {
                    const float d = distance2(p, triangleClosest(p, t));
                    if (d < best) best = d, best_triangle = t;
                }
                if (best <= enough) return {best, best_triangle};
                continue;
            }
            const float dl = boxDistance2(p, nodes_[node.first]), dr = boxDistance2(p, nodes_[node.first + 1]);
            // Near child last so it is popped first and shrinks best before the far one is tried.
            const Pending near = dl <= dr ? Pending{node.first, dl} : Pending{node.first + 1, dr};
            const Pending far = dl <= dr ? Pending{node.first + 1, dr} : Pending{node.first, dl};
            if (far.distance2 < best) stack[top++] = far;
            if (near.distance2 < best) stack[top++] = near;
        }
        return {best, best_triangle};
    }

private:
    static constexpr uint32_t kLeafSize = 4;

    struct Node {
        glm::vec3 min{std::numeric_limits<float>::max()};
        glm::vec3 max{std::numeric_limits<float>::lowest()};
        uint32_t first = 0;  // leaf: first triangle (leaf order); inner: left child, right is first + 1
        uint32_t count = 0;  // triangles in a leaf, 0 for an inner node
    };

    static float boxDistance2(const glm::vec3& p, const Node& n) {
        const glm::vec3 d = glm::max(glm::max(n.min - p, p - n.max), glm::vec3(0.0f));
        return glm::dot(d, d);
    }

    glm::vec3 triangleClosest(const glm::vec3& p, uint32_t t) const {
        return closestPoint(p, corners_[3 * t], corners_[3 * t + 1], corners_[3 * t + 2]);
    }

    std::vector<Node> nodes_;
    std::vector<glm::vec3> corners_;
};

struct OneSided {
    double max = 0.0, sum = 0.0;
};

// The smallest float whose square root (in double) is at least x: a squared distance below it
// is a distance below x, one at or above it a distance of at least x.
float squaredAtLeast(double x) {
    float b = float(x * x);
    while (std::sqrt(double(b)) < x && b < std::numeric_limits<float>::max())
        b = std::nextafter(b, std::numeric_limits<float>::infinity());
    return b;
}
// The largest float whose square root (in double) is at most x (x >= 0).
float squaredAtMost(double x) {
    float b = float(x * x);
    while (b > 0.0f && std::sqrt(double(b)) > x) b = std::nextafter(b, 0.0f);
    return b;
}

// caps: empty, or one per sample (the most its distance counts). max_only: the largest distance
// alone (sum left 0), found with less work and the same value: a sample's search stops once a
// triangle is nearer than the largest distance so far (it cannot raise it), and looks no
// farther than its cap (beyond it the distance counts as the cap).
OneSided measure(std::span<const glm::vec3> samples, const TriangleBvh& to, std::span<const float> caps = {},
                 bool max_only = false) {
    constexpr float kNoBound = std::numeric_limits<float>::infinity();
    OneSided r;
    uint32_t hint = kNoTriangle;
    for (size_t i = 0; i < samples.size(); ++i) {
        const float bound = max_only && !caps.empty() ? squaredAtLeast(double(caps[i])) : kNoBound;
        const auto [d2, t] = to.closest(samples[i], hint, bound, max_only ? squaredAtMost(r.max) : -1.0f);
        double d = caps.empty() ? double(kNoBound) : double(caps[i]);  // nothing nearer than the cap
        if (t != kNoTriangle) {
            hint = t;
            d = std::min(d, std::sqrt(double(d2)));
        }
        r.max = std::max(r.max, d);
        if (!max_only) r.sum += d;
    }
    return r;
}

}  // namespace

glm::vec3 closestPointOnTriangle(const glm::vec3& p, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c) {
    return closestPoint(p, a, b, c);
}

namespace {

// sampleSurface, and for each point the triangle it came from (a vertex: the first triangle
// that uses it) when `from` is given.
std::vector<glm::vec3> samplePoints(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles,
                                    uint32_t count, uint64_t seed, bool vertices, std::vector<uint32_t>* from) {
    std::vector<glm::vec3> out;
    if (vertices) {
        std::vector<uint8_t> seen(positions.size(), 0);
        for (size_t i = 0; i < triangles.size(); ++i) {
            const uint32_t v = triangles[i];
            if (!seen[v]) {
                seen[v] = 1;
                out.push_back(positions[v]);
                if (from) from->push_back(uint32_t(i / 3));
            }
        }
    }

    const size_t tc = triangles.size() / 3;
    std::vector<double> cumulative(tc);
    double total = 0.0;
    for (size_t t = 0; t < tc; ++t) {
        const glm::dvec3 a = positions[triangles[3 * t]], b = positions[triangles[3 * t + 1]],
                         c = positions[triangles[3 * t + 2]];
        total += 0.5 * glm::length(glm::cross(b - a, c - a));
        cumulative[t] = total;
    }
    if (!(total > 0.0) || count == 0) return out;

    out.reserve(out.size() + count);
    SplitMix64 rng(seed);
    size_t t = 0;
    for (uint32_t i = 0; i < count; ++i) {
        // Stratified: sample i lands in the i-th of `count` equal slices of the total area, so
        // the positions along the cumulative area rise and t only ever moves forward.
        const double u = (double(i) + uniform(rng)) / double(count) * total;
        while (t + 1 < tc && cumulative[t] <= u) ++t;
        // Uniform in the triangle (Osada et al. 2002, "Shape distributions", Eq. 1).
        const double s = std::sqrt(uniform(rng)), r = uniform(rng);
        const glm::dvec3 a = positions[triangles[3 * t]], b = positions[triangles[3 * t + 1]],
                         c = positions[triangles[3 * t + 2]];
        out.push_back(glm::vec3((1.0 - s) * a + s * (1.0 - r) * b + s * r * c));
        if (from) from->push_back(uint32_t(t));
    }
    return out;
}

}  // namespace

std::vector<glm::vec3> sampleSurface(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles,
                                     uint32_t count, uint64_t seed, bool vertices) {
    return samplePoints(positions, triangles, count, seed, vertices, nullptr);
}

struct SampledSurface::Impl {
    std::vector<glm::vec3> samples;
    std::vector<float> caps;         // empty, or one per sample
    std::optional<TriangleBvh> bvh;  // none: the surface has no triangles
};

SampledSurface::SampledSurface(std::span<const glm::vec3> positions, std::span<const uint32_t> triangles,
                               const HausdorffOptions& options, std::span<const float> triangle_cap)
    : impl_(std::make_unique<Impl>()) {
    if (triangles.size() < 3) return;
    if (!triangle_cap.empty() && triangle_cap.size() != triangles.size() / 3)
        throw std::invalid_argument("SampledSurface: triangle_cap needs one value per triangle");
    // Same seed for every surface, so that swapping A and B swaps the two directions exactly.
    std::vector<uint32_t> from;
    impl_->samples = samplePoints(positions, triangles, options.samples, options.seed, options.vertices,
                                  triangle_cap.empty() ? nullptr : &from);
    if (!triangle_cap.empty()) {
        impl_->caps.reserve(from.size());
        for (uint32_t t : from) impl_->caps.push_back(triangle_cap[t]);
    }
    impl_->bvh.emplace(positions, triangles);
}

SampledSurface::~SampledSurface() = default;
SampledSurface::SampledSurface(SampledSurface&&) noexcept = default;
SampledSurface& SampledSurface::operator=(SampledSurface&&) noexcept = default;

HausdorffDistance SampledSurface::distanceTo(const SampledSurface& other) const {
    HausdorffDistance r;
    const Impl &a = *impl_, &b = *other.impl_;
    if (!a.bvh && !b.bvh) return r;
    if (!a.bvh || !b.bvh) {
        // Every sample of the other surface is infinitely far from nothing, or its cap.
        const std::vector<float>& caps = a.bvh ? a.caps : b.caps;
        const double far = caps.empty() ? std::numeric_limits<double>::infinity()
                                        : double(*std::max_element(caps.begin(), caps.end()));
        r.max = r.mean = far;
        (a.bvh ? r.a_to_b : r.b_to_a) = far;
        return r;
    }
    const OneSided ab = measure(a.samples, *b.bvh, a.caps);
    const OneSided ba = measure(b.samples, *a.bvh, b.caps);
    r.a_to_b = ab.max;
    r.b_to_a = ba.max;
    r.max = std::max(ab.max, ba.max);
    r.samples = a.samples.size() + b.samples.size();
    r.mean = (ab.sum + ba.sum) / double(r.samples);
    return r;
}

double SampledSurface::farthestFrom(std::span<const glm::vec3> points, std::span<const float> caps) const {
    if (points.empty()) return 0.0;
    if (!caps.empty() && caps.size() != points.size())
        throw std::invalid_argument("SampledSurface::farthestFrom: caps needs one value per point");
    if (!impl_->bvh) {
        if (caps.empty()) return std::numeric_limits<double>::infinity();
        return double(*std::max_element(caps.begin(), caps.end()));
    }
    return measure(points, *impl_->bvh, caps, true).max;
}

double SampledSurface::maxDistanceTo(const SampledSurface& other) const {
    const Impl &a = *impl_, &b = *other.impl_;
    if (!a.bvh || !b.bvh) return distanceTo(other).max;
    return std::max(measure(a.samples, *b.bvh, a.caps, true).max, measure(b.samples, *a.bvh, b.caps, true).max);
}

HausdorffDistance sampledHausdorff(std::span<const glm::vec3> a_positions, std::span<const uint32_t> a_triangles,
                                   std::span<const glm::vec3> b_positions, std::span<const uint32_t> b_triangles,
                                   const HausdorffOptions& options) {
    return SampledSurface(a_positions, a_triangles, options).distanceTo(SampledSurface(b_positions, b_triangles, options));
}

}  // namespace occ
