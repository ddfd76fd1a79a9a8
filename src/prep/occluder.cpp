// SPDX-License-Identifier: MIT
#include "prep/occluder.h"

#include "prep/symmetric_eigen.h"

#include <algorithm>
#include <array>
#include <cfloat>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace occ {
namespace {

constexpr int kMaxResolution = 4096;
constexpr int kSubpixelBits = 8;  // fixed-point raster coordinates in 1/256 pixel
constexpr int64_t kSubpixel = int64_t(1) << kSubpixelBits;
constexpr int64_t kPixelCentre = kSubpixel / 2;
// Projections with more points than this are thinned to the lowest and highest point of each of
// kHullBuckets vertical strips before the 2D hull is taken, so the OOBB search stays O(n). The
// thinned hull lies within one strip width of the true one; box extents are always measured on
// every point, so this only costs tightness, never containment.
constexpr size_t kExactHullPoints = 4096;
constexpr int kHullBuckets = 2048;
constexpr int kLargestTriangleNormals = 3;
constexpr int kRefinementRounds = 4;
// Candidate boxes are ranked by prod(extent + kScoreSlack * diagonal) rather than the bare
// volume, so that among boxes of (near) zero volume, as for flat and line-like meshes, the one
// with the smallest footprint still wins.
constexpr double kScoreSlack = 1e-4;
// A candidate must beat the best so far by this relative margin, so that float noise does not
// trade an axis-aligned box for an equally tight rotated one.
constexpr double kScoreMargin = 1e-6;
constexpr double kSameAxis = 1e-8;  // 1 - |cos| below which two axes count as one
// Box extents below this fraction of the longest count as zero for Eq. 2.
constexpr double kNegligibleExtent = 1e-5;

using Frame = std::array<glm::dvec3, 3>;  // orthonormal axes

glm::dvec3 anyPerpendicular(const glm::dvec3& a) {
    const glm::dvec3 m = glm::abs(a);
    const glm::dvec3 helper = m.x <= m.y && m.x <= m.z ? glm::dvec3(1, 0, 0)
                              : m.y <= m.z             ? glm::dvec3(0, 1, 0)
                                                       : glm::dvec3(0, 0, 1);
    return glm::normalize(glm::cross(a, helper));
}

// Orthonormal, right-handed frame from the directions of in[0], in[1], in[2] taken in that order;
// vectors shorter than a tiny fraction of the longest (or parallel to earlier ones) are skipped
// and the frame is completed with perpendiculars.
Frame gramSchmidt(const std::array<glm::dvec3, 3>& in) {
    double longest = 0.0;
    for (const glm::dvec3& v : in) longest = std::max(longest, glm::length(v));
    Frame e{};
    int n = 0;
    for (glm::dvec3 v : in) {
        for (int j = 0; j < n; ++j) v -= glm::dot(v, e[j]) * e[j];
        const double len = glm::length(v);
        if (len > 1e-9 * longest && n < 3) e[n++] = v / len;
    }
    if (n == 0) e[0] = glm::dvec3(1, 0, 0);
    if (n <= 1) e[1] = anyPerpendicular(e[0]);
    e[2] = glm::cross(e[0], e[1]);
    return e;
}

// Eigenvectors of a symmetric 3x3 matrix (symmetricEigen), made orthonormal: for the nearly
// equal eigenvalues of cubes and spheres any frame will do.
Frame symmetricEigenvectors(double a[3][3]) {
    double values[3], v[3][3];
    symmetricEigen(a, values, v);
    return gramSchmidt({glm::dvec3(v[0][0], v[1][0], v[2][0]), glm::dvec3(v[0][1], v[1][1], v[2][1]),
                        glm::dvec3(v[0][2], v[1][2], v[2][2])});
}

// Principal axes of the surface: the covariance of a point spread uniformly over the triangles,
// so that a finely tessellated face does not pull the axes towards itself as vertex PCA would.
// The second moment of a triangle (p, q, r) about the origin is
// area/12 * (pp^T + qq^T + rr^T + ss^T) with s = p + q + r (Eberly, "Dynamic Collision Detection
// using Oriented Bounding Boxes", 2002). Without any surface area it falls back to the vertices.
Frame principalAxes(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                    const glm::dvec3& origin) {
    double m[3][3] = {};
    glm::dvec3 sum(0.0);
    double weight = 0.0;
    auto addOuter = [&m](const glm::dvec3& x, double w) {
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) m[i][j] += w * x[i] * x[j];
    };
    for (size_t t = 0; t + 3 <= triangles.size(); t += 3) {
        const glm::dvec3 p = glm::dvec3(positions[triangles[t]]) - origin;
        const glm::dvec3 q = glm::dvec3(positions[triangles[t + 1]]) - origin;
        const glm::dvec3 r = glm::dvec3(positions[triangles[t + 2]]) - origin;
        const double area = 0.5 * glm::length(glm::cross(q - p, r - p));
        if (area == 0.0) continue;
        const double w = area / 12.0;
        addOuter(p, w);
        addOuter(q, w);
        addOuter(r, w);
        addOuter(p + q + r, w);
        sum += area * (p + q + r) / 3.0;
        weight += area;
    }
    if (weight == 0.0)
        for (const glm::vec3& x : positions) {
            const glm::dvec3 p = glm::dvec3(x) - origin;
            addOuter(p, 1.0);
            sum += p;
            weight += 1.0;
        }
    const glm::dvec3 mean = sum / weight;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m[i][j] = m[i][j] / weight - mean[i] * mean[j];
    return symmetricEigenvectors(m);
}

// Normals of the largest triangles, at most one per direction (|cos| < 0.999 between them):
// CAD parts are mostly planar faces, and a big face's normal is usually an axis of the best box.
std::vector<glm::dvec3> largestTriangleNormals(const std::vector<glm::vec3>& positions,
                                               const std::vector<uint32_t>& triangles) {
    std::array<std::pair<float, glm::vec3>, kLargestTriangleNormals> best{};
    for (size_t t = 0; t + 3 <= triangles.size(); t += 3) {
        const glm::vec3& p = positions[triangles[t]];
        const glm::vec3 c = glm::cross(positions[triangles[t + 1]] - p, positions[triangles[t + 2]] - p);
        const float area2 = glm::length(c);
        size_t smallest = 0;
        for (size_t k = 1; k < best.size(); ++k)
            if (best[k].first < best[smallest].first) smallest = k;
        if (!(area2 > best[smallest].first)) continue;
        const glm::vec3 n = c / area2;
        size_t slot = smallest;
        for (size_t k = 0; k < best.size(); ++k)
            if (best[k].first > 0.0f && std::abs(glm::dot(best[k].second, n)) > 0.999f) {
                slot = k;
                break;
            }
        if (area2 > best[slot].first) best[slot] = {area2, n};
    }
    std::vector<glm::dvec3> normals;
    for (const auto& [area2, n] : best)
        if (area2 > 0.0f) normals.push_back(glm::dvec3(n));
    return normals;
}

struct BoxCandidate {
    Frame axes;
    glm::dvec3 lo{0.0}, hi{0.0};  // extents along axes, relative to the search origin
    double score = std::numeric_limits<double>::infinity();
};

struct Search {
    const std::vector<glm::vec3>& positions;
    glm::dvec3 origin;
    double slack;  // kScoreSlack * diagonal of the local axis-aligned box
    BoxCandidate best;
    std::vector<glm::vec2> projected, thinned, hull;  // scratch of caliperFrame

    BoxCandidate fit(const Frame& axes) const {
        BoxCandidate c;
        c.axes = axes;
        c.lo = glm::dvec3(std::numeric_limits<double>::max());
        c.hi = glm::dvec3(std::numeric_limits<double>::lowest());
        for (const glm::vec3& x : positions) {
            const glm::dvec3 p = glm::dvec3(x) - origin;
            const glm::dvec3 t(glm::dot(p, axes[0]), glm::dot(p, axes[1]), glm::dot(p, axes[2]));
            c.lo = glm::min(c.lo, t);
            c.hi = glm::max(c.hi, t);
        }
        const glm::dvec3 e = c.hi - c.lo + slack;
        c.score = e.x * e.y * e.z;
        return c;
    }

    // Returns true if the frame's box beat the best so far.
    bool consider(const Frame& axes) {
        BoxCandidate c = fit(axes);
        if (!(c.score < best.score * (1.0 - kScoreMargin))) return false;
        best = c;
        return true;
    }

    // The frame {u, v, axis} whose u and v bound the projection of the positions onto the plane
    // across `axis` with the smallest rectangle: one side of the minimum-area rectangle lies on
    // an edge of the convex hull (Freeman & Shapira 1975), found by rotating calipers
    // (Toussaint 1983, "Solving geometric problems with the rotating calipers").
    Frame caliperFrame(const glm::dvec3& axis) {
        const glm::dvec3 b1 = anyPerpendicular(axis), b2 = glm::cross(axis, b1);
        const glm::vec3 fb1(b1), fb2(b2), fo(origin);
        projected.resize(positions.size());
        for (size_t i = 0; i < positions.size(); ++i) {
            const glm::vec3 p = positions[i] - fo;
            projected[i] = {glm::dot(p, fb1), glm::dot(p, fb2)};
        }
        convexHull(projected.size() > kExactHullPoints ? thin() : projected);
        const glm::vec2 d = minAreaRectangleDirection();
        const glm::dvec3 u = glm::normalize(double(d.x) * b1 + double(d.y) * b2);
        return {u, glm::cross(axis, u), axis};
    }

    std::vector<glm::vec2>& thin() {
        float xmin = projected[0].x, xmax = projected[0].x;
        size_t imin = 0, imax = 0;
        for (size_t i = 1; i < projected.size(); ++i) {
            if (projected[i].x < xmin) xmin = projected[i].x, imin = i;
            if (projected[i].x > xmax) xmax = projected[i].x, imax = i;
        }
        std::array<int64_t, kHullBuckets> low, high;
        low.fill(-1);
        high.fill(-1);
        const float scale = xmax > xmin ? float(kHullBuckets) / (xmax - xmin) : 0.0f;
        for (size_t i = 0; i < projected.size(); ++i) {
            const int b = std::min(int((projected[i].x - xmin) * scale), kHullBuckets - 1);
            if (low[b] < 0 || projected[i].y < projected[size_t(low[b])].y) low[b] = int64_t(i);
            if (high[b] < 0 || projected[i].y > projected[size_t(high[b])].y) high[b] = int64_t(i);
        }
        thinned.clear();
        thinned.push_back(projected[imin]);
        thinned.push_back(projected[imax]);
        for (int b = 0; b < kHullBuckets; ++b)
            if (low[b] >= 0) {
                thinned.push_back(projected[size_t(low[b])]);
                thinned.push_back(projected[size_t(high[b])]);
            }
        return thinned;
    }

    static float cross(const glm::vec2& o, const glm::vec2& a, const glm::vec2& b) {
        return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    }

    // Counter-clockwise hull without collinear points (Andrew's monotone chain) into `hull`;
    // sorts `sorted` in place and removes its duplicates.
    void convexHull(std::vector<glm::vec2>& sorted) {
        std::sort(sorted.begin(), sorted.end(),
                  [](const glm::vec2& a, const glm::vec2& b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
        sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
        hull.assign(2 * sorted.size(), glm::vec2(0.0f));
        if (sorted.size() < 3) {
            hull.assign(sorted.begin(), sorted.end());
            return;
        }
        size_t k = 0;
        for (const glm::vec2& p : sorted) {
            while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0.0f) --k;
            hull[k++] = p;
        }
        for (size_t i = sorted.size() - 1, lower = k + 1; i-- > 0;) {
            while (k >= lower && cross(hull[k - 2], hull[k - 1], sorted[i]) <= 0.0f) --k;
            hull[k++] = sorted[i];
        }
        hull.resize(k - 1);
    }

    // Unit direction of one side of the minimum-area rectangle around `hull`.
    glm::vec2 minAreaRectangleDirection() const {
        const size_t n = hull.size();
        if (n < 2) return {1.0f, 0.0f};
        if (n == 2) return glm::normalize(hull[1] - hull[0]);
        auto next = [n](size_t i) { return i + 1 == n ? 0 : i + 1; };
        // Along each edge's direction u the hull is unimodal, and as the edge turns
        // counter-clockwise the extreme points only move forward: r (max along u), then t
        // (farthest from the edge), then l (min along u).
        auto advance = [&](size_t& i, const glm::vec2& dir, float sign) {
            for (size_t steps = 0; steps < n && sign * glm::dot(hull[next(i)] - hull[i], dir) >= 0.0f; ++steps)
                i = next(i);
        };
        size_t r = 0, t = 0, l = 0;
        float best_area = std::numeric_limits<float>::infinity();
        glm::vec2 best_dir(1.0f, 0.0f);
        for (size_t i = 0; i < n; ++i) {
            const glm::vec2 u = glm::normalize(hull[next(i)] - hull[i]);
            const glm::vec2 normal(-u.y, u.x);
            advance(r, u, 1.0f);
            if (i == 0) t = r;
            advance(t, normal, 1.0f);
            if (i == 0) l = t;
            advance(l, u, -1.0f);
            const float area = glm::dot(hull[r] - hull[l], u) * glm::dot(hull[t] - hull[i], normal);
            if (area < best_area) best_area = area, best_dir = u;
        }
        return best_dir;
    }
};

// The box across the frame, stored in floats, with its axes ordered by decreasing half extent
// and made right-handed. The half extents are measured again, in double, from the float centre
// along the float axes over every point the box must hold, and rounded up: float rounding of
// the centre (half an ulp of its coordinates, 2.4e-4 at 5 km) cannot leave a point outside, and
// a further 4 ulps of the box's size cover the rounding of dot(p - center, axis) in floats.
template <class Points>
OrientedBox storedBox(const Frame& axes, const glm::dvec3& half, const glm::dvec3& center, const Points& points) {
    std::array<int, 3> order{0, 1, 2};
    std::stable_sort(order.begin(), order.end(), [&half](int a, int b) { return half[a] > half[b]; });
    OrientedBox box;
    box.center = glm::vec3(center);
    box.axis[0] = glm::vec3(axes[order[0]]);
    box.axis[1] = glm::vec3(axes[order[1]]);
    // Flipping the third axis keeps the same box, the extents being symmetric.
    box.axis[2] = glm::vec3(glm::cross(axes[order[0]], axes[order[1]]));
    const glm::dvec3 c(box.center);
    const Frame stored{glm::dvec3(box.axis[0]), glm::dvec3(box.axis[1]), glm::dvec3(box.axis[2])};
    glm::dvec3 reach(0.0);
    for (const auto& point : points) {
        const glm::dvec3 d = glm::dvec3(point) - c;
        reach = glm::max(reach,
                         glm::abs(glm::dvec3(glm::dot(d, stored[0]), glm::dot(d, stored[1]), glm::dot(d, stored[2]))));
    }
    reach += 4.0 * FLT_EPSILON * (reach.x + reach.y + reach.z);
    for (int k = 0; k < 3; ++k) {
        box.half_extent[k] = float(reach[k]);
        if (double(box.half_extent[k]) < reach[k])
            box.half_extent[k] = std::nextafter(box.half_extent[k], std::numeric_limits<float>::infinity());
    }
    return box;
}

// Pixels of a width x height raster, spanning [0, width] x [0, height] in fixed point, whose
// centres the triangles cover. Exact integer edge functions with a top-left rule give every
// pixel centre on a shared edge or vertex to exactly one triangle of a closed fan, so there are
// no cracks; orientation does not matter and zero-area triangles cover nothing.
uint32_t coveredPixels(const std::vector<glm::i64vec2>& fixed, const std::vector<uint32_t>& triangles, int width,
                       int height, std::vector<uint8_t>& mask) {
    const uint32_t total = uint32_t(width) * uint32_t(height);
    mask.assign(total, 0);
    uint32_t covered = 0;
    for (size_t t = 0; t + 3 <= triangles.size() && covered < total; t += 3) {
        glm::i64vec2 v[3] = {fixed[triangles[t]], fixed[triangles[t + 1]], fixed[triangles[t + 2]]};
        const int64_t area = (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[1].y - v[0].y) * (v[2].x - v[0].x);
        if (area == 0) continue;
        if (area < 0) std::swap(v[1], v[2]);
        const int64_t min_x = std::min({v[0].x, v[1].x, v[2].x}), max_x = std::max({v[0].x, v[1].x, v[2].x});
        const int64_t min_y = std::min({v[0].y, v[1].y, v[2].y}), max_y = std::max({v[0].y, v[1].y, v[2].y});
        // First and last pixel whose centre lies in the bounding box (>> floors, C++20).
        const int x0 = int(std::max<int64_t>(0, (min_x - kPixelCentre + kSubpixel - 1) >> kSubpixelBits));
        const int x1 = int(std::min<int64_t>(width - 1, (max_x - kPixelCentre) >> kSubpixelBits));
        const int y0 = int(std::max<int64_t>(0, (min_y - kPixelCentre + kSubpixel - 1) >> kSubpixelBits));
        const int y1 = int(std::min<int64_t>(height - 1, (max_y - kPixelCentre) >> kSubpixelBits));
        if (x0 > x1 || y0 > y1) continue;
        int64_t row[3], step_x[3], step_y[3];
        const int64_t cx = int64_t(x0) * kSubpixel + kPixelCentre, cy = int64_t(y0) * kSubpixel + kPixelCentre;
        for (int e = 0; e < 3; ++e) {
            const glm::i64vec2& a = v[e];
            const glm::i64vec2& b = v[(e + 1) % 3];
            // E(p) = cross(b - a, p - a) > 0 inside a counter-clockwise triangle. An edge owns
            // the centres on it when it points down, or left if horizontal; the same edge in the
            // neighbouring triangle runs the other way and does not.
            const int64_t ex = a.y - b.y, ey = b.x - a.x;
            const bool owns = ex > 0 || (ex == 0 && ey < 0);
            row[e] = ex * (cx - a.x) + ey * (cy - a.y) - (owns ? 0 : 1);
            step_x[e] = ex * kSubpixel;
            step_y[e] = ey * kSubpixel;
        }
        // Row by row, each edge bounds the run of covered centres on one side: E + step_x * k >= 0
        // for k pixels right of x0. The quotients are exact (|E| < 2^53, and a double division
        // of integers rounds an integral quotient to itself), so the run is exactly the set of
        // centres the edge functions accept; scanning the bounding box instead costs ~75
        // pixel tests per triangle on long thin pipe triangles.
        for (int y = y0; y <= y1; ++y) {
            int64_t first = 0, until = x1 - x0;
            for (int e = 0; e < 3 && first <= until; ++e) {
                if (step_x[e] > 0) {
                    if (row[e] < 0) {
                        const double q = double(-row[e]) / double(step_x[e]);
                        const auto k = int64_t(q);  // q > 0: truncation floors, then round up
                        first = std::max(first, double(k) < q ? k + 1 : k);
                    }
                } else if (row[e] < 0) {
                    until = -1;  // E does not grow to the right: failing at x0, it fails on the whole row
                } else if (step_x[e] < 0) {
                    until = std::min(until, int64_t(double(row[e]) / double(-step_x[e])));
                }
            }
            uint8_t* line = mask.data() + size_t(y) * size_t(width) + size_t(x0);
            for (int64_t k = first; k <= until; ++k) {
                covered += 1u - line[k];
                line[k] = 1;
            }
            for (int e = 0; e < 3; ++e) row[e] += step_y[e];
        }
    }
    return covered;
}

// Eq. 2 of Peng & Cao 2013 (Integrating occlusion culling with parallel LOD for rendering
// complex 3D environments on GPU, I3D):
//     compactness = (sum_a A_a * P_a / R_a) / (sum_a A_a)
// over the three OOBB axes a; `local` holds every vertex's coordinates in the box, in
// [0, extent[k]] along axis k.
float compactness(const std::vector<glm::dvec3>& local, const std::vector<uint32_t>& triangles,
                  const glm::dvec3& extent, int resolution) {
    std::vector<glm::i64vec2> fixed(local.size());
    std::vector<uint8_t> mask;
    double weighted = 0.0, area_sum = 0.0;
    for (int a = 0; a < 3; ++a) {
        const int i = (a + 1) % 3, j = (a + 2) % 3;
        const double area = extent[i] * extent[j];
        if (!(area > 0.0)) continue;
        const bool i_longer = extent[i] >= extent[j];
        const double shorter = i_longer ? extent[j] : extent[i], longer = i_longer ? extent[i] : extent[j];
        const int short_pixels = std::max(1, int(std::lround(resolution * (shorter / longer))));
        const int width = i_longer ? resolution : short_pixels, height = i_longer ? short_pixels : resolution;
        const double sx = double(width * kSubpixel) / extent[i], sy = double(height * kSubpixel) / extent[j];
        for (size_t v = 0; v < local.size(); ++v)
            fixed[v] = {std::clamp<int64_t>(std::llround(local[v][i] * sx), 0, width * kSubpixel),
                        std::clamp<int64_t>(std::llround(local[v][j] * sy), 0, height * kSubpixel)};
        const uint32_t covered = coveredPixels(fixed, triangles, width, height, mask);
        weighted += area * double(covered) / (double(width) * double(height));
        area_sum += area;
    }
    return area_sum > 0.0 ? float(std::clamp(weighted / area_sum, 0.0, 1.0)) : 0.0f;
}

}  // namespace

OccluderData computeOccluderData(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                 int resolution) {
    OccluderData out;
    if (positions.empty()) return out;

    // Keep only whole triangles with valid indices, copying only when something must go.
    const size_t whole = triangles.size() / 3 * 3;
    const bool keep_all = whole == triangles.size() && std::all_of(triangles.begin(), triangles.end(),
                                                                   [&](uint32_t i) { return i < positions.size(); });
    std::vector<uint32_t> valid_copy;
    if (!keep_all)
        for (size_t t = 0; t < whole; t += 3)
            if (std::max({triangles[t], triangles[t + 1], triangles[t + 2]}) < positions.size())
                valid_copy.insert(valid_copy.end(), triangles.begin() + std::ptrdiff_t(t),
                                  triangles.begin() + std::ptrdiff_t(t + 3));
    const std::vector<uint32_t>& tris = keep_all ? triangles : valid_copy;

    Bounds aabb;
    for (const glm::vec3& p : positions) aabb.extend(p);
    const glm::dvec3 origin = 0.5 * (glm::dvec3(aabb.min) + glm::dvec3(aabb.max));
    const double diagonal = glm::length(glm::dvec3(aabb.max) - glm::dvec3(aabb.min));
    Search search{positions, origin, kScoreSlack * diagonal, {}, {}, {}, {}};

    const Frame identity{glm::dvec3(1, 0, 0), glm::dvec3(0, 1, 0), glm::dvec3(0, 0, 1)};
    search.consider(identity);
    const Frame principal = principalAxes(positions, tris, origin);
    search.consider(principal);
    // Fixed axes for the calipers; parallel ones (a principal axis or big face normal along a
    // local axis, the axis that produced the best box) give the same rectangle and are skipped.
    std::vector<glm::dvec3> tried;
    auto tryAxis = [&](const glm::dvec3& axis) {
        for (const glm::dvec3& t : tried)
            if (std::abs(glm::dot(t, axis)) > 1.0 - kSameAxis) return false;
        tried.push_back(axis);
        return search.consider(search.caliperFrame(axis));
    };
    for (const glm::dvec3& axis : identity) tryAxis(axis);
    for (const glm::dvec3& axis : principal) tryAxis(axis);
    for (const glm::dvec3& axis : largestTriangleNormals(positions, tris)) tryAxis(axis);
    // Each of the best box's own axes, held fixed, may allow a tighter rectangle across it.
    for (int round = 0; round < kRefinementRounds; ++round) {
        const Frame current = search.best.axes;
        bool improved = false;
        for (const glm::dvec3& axis : current) improved |= tryAxis(axis);
        if (!improved) break;
    }

    const BoxCandidate& best = search.best;
    const glm::dvec3 half = 0.5 * (best.hi - best.lo);
    const glm::dvec3 mid = 0.5 * (best.hi + best.lo);
    const glm::dvec3 center = origin + mid.x * best.axes[0] + mid.y * best.axes[1] + mid.z * best.axes[2];
    out.oobb = storedBox(best.axes, half, center, positions);
    out.largest_face_normal = out.oobb.axis[2];

    std::vector<glm::dvec3> local(positions.size());
    for (size_t v = 0; v < positions.size(); ++v) {
        const glm::dvec3 p = glm::dvec3(positions[v]) - origin;
        local[v] =
            glm::dvec3(glm::dot(p, best.axes[0]), glm::dot(p, best.axes[1]), glm::dot(p, best.axes[2])) - best.lo;
    }
    // Float positions of a flat or straight mesh scatter by an ulp or so off its plane or line;
    // projected into a box that thin, its triangles would look like anything. Extents within that
    // noise, or below kNegligibleExtent of the longest, count as zero.
    glm::dvec3 extent = best.hi - best.lo;
    const glm::dvec3 reach = glm::max(glm::abs(glm::dvec3(aabb.min)), glm::abs(glm::dvec3(aabb.max)));
    const double negligible = std::max(kNegligibleExtent * std::max({extent.x, extent.y, extent.z}),
                                       16.0 * FLT_EPSILON * std::max({reach.x, reach.y, reach.z}));
    for (int k = 0; k < 3; ++k)
        if (extent[k] <= negligible) extent[k] = 0.0;
    out.compactness = compactness(local, tris, extent, std::clamp(resolution, 1, kMaxResolution));
    return out;
}

OrientedBox transformBox(const OrientedBox& local, const glm::mat4& world) {
    const glm::dmat3 linear(world);
    const glm::dvec3 center = linear * glm::dvec3(local.center) + glm::dvec3(world[3]);
    // The box's image is the parallelepiped center + sum_k s_k * edge[k], |s_k| <= 1.
    std::array<glm::dvec3, 3> edge;
    for (int k = 0; k < 3; ++k) edge[k] = linear * glm::dvec3(local.axis[k]) * double(local.half_extent[k]);
    const double slack = kScoreSlack * (glm::length(edge[0]) + glm::length(edge[1]) + glm::length(edge[2]));

    Frame best_axes{};
    glm::dvec3 best_half(0.0);
    double best_score = std::numeric_limits<double>::infinity();
    std::array<int, 3> order{0, 1, 2};
    do {
        const Frame axes = gramSchmidt({edge[order[0]], edge[order[1]], edge[order[2]]});
        glm::dvec3 half(0.0);
        for (int k = 0; k < 3; ++k)
            for (const glm::dvec3& e : edge) half[k] += std::abs(glm::dot(e, axes[k]));
        const glm::dvec3 s = 2.0 * half + slack;
        const double score = s.x * s.y * s.z;
        if (score < best_score * (1.0 - kScoreMargin)) {
            best_score = score;
            best_axes = axes;
            best_half = half;
        }
    } while (std::next_permutation(order.begin(), order.end()));
    std::array<glm::dvec3, 8> corners;
    for (int i = 0; i < 8; ++i)
        corners[i] =
            center + (i & 1 ? 1.0 : -1.0) * edge[0] + (i & 2 ? 1.0 : -1.0) * edge[1] + (i & 4 ? 1.0 : -1.0) * edge[2];
    return storedBox(best_axes, best_half, center, corners);
}

float boxVolume(const OrientedBox& box) { return 8.0f * box.half_extent.x * box.half_extent.y * box.half_extent.z; }

}  // namespace occ
