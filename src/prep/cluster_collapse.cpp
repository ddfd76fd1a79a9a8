// SPDX-License-Identifier: MIT
#include "prep/cluster_collapse.h"

#include "prep/least_squares_point.h"
#include "scene/colour.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace occ {

namespace {

// The planes of a vertex's triangles as one quadric: sum of area x (n.p + d)^2, kept as
// A = sum area n n^T, b = sum area d n (the constant is not needed to find the minimum).
struct PlaneSum {
    glm::dmat3 a{0.0};
    glm::dvec3 b{0.0};
    double area = 0.0;
    void add(const PlaneSum& o) {
        a += o.a;
        b += o.b;
        area += o.area;
    }
};

// An sRGB RGBA8 colour (oss::kWhite's layout) mixed from weighted ones, in linear light.
class ColourMix {
public:
    void add(uint32_t c, double w) {
        for (int k = 0; k < 3; ++k) mix_[k] += w * srgbToLinear(float((c >> (8 * k)) & 0xFFu) / 255.0f);
        alpha_ += w * double(c >> 24);
        weight_ += w;
    }
    uint32_t result() const {
        if (!(weight_ > 0.0)) return 0xFFFFFFFFu;
        uint32_t out = uint32_t(std::lround(alpha_ / weight_)) << 24;
        for (int k = 0; k < 3; ++k)
            out |= uint32_t(std::lround(255.0f * linearToSrgb(float(mix_[k] / weight_)))) << (8 * k);
        return out;
    }

private:
    glm::dvec3 mix_{0.0};
    double alpha_ = 0.0, weight_ = 0.0;
};

}  // namespace

CollapseSequence clusterAfterCollapses(std::vector<glm::vec3>& positions, std::vector<uint32_t>* colours,
                                       const std::vector<uint32_t>& triangles, CollapseSequence sequence,
                                       const ClusterOptions& options) {
    if (!(options.first_cell > 0.0f && options.first_cell <= options.last_cell))
        throw std::invalid_argument("clusterAfterCollapses: need 0 < first_cell <= last_cell");
    if (colours && colours->size() != positions.size())
        throw std::invalid_argument("clusterAfterCollapses: one colour per position expected");
    const uint32_t n = uint32_t(positions.size());
    const uint32_t tc = uint32_t(triangles.size() / 3);
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    for (const glm::vec3& p : positions) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    const float extent = std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
    // Nothing to cluster: the edge collapses as they are.
    const bool cluster = n > 0 && tc > 0 && extent > 0.0f && std::isfinite(extent);
    const float first_cell = extent * options.first_cell;

    // The edge collapses up to the first one that moves more than the first grid would.
    size_t keep = 0;
    const float limit = first_cell * std::sqrt(3.0f);
    while (keep < sequence.size() && (!cluster || sequence.error[keep] <= limit)) ++keep;
    sequence.removed.resize(keep);
    sequence.kept.resize(keep);
    sequence.error.resize(keep);
    sequence.triangle_offsets.resize(keep + 1);
    sequence.triangles.resize(sequence.triangle_offsets[keep]);

    // The vertices the kept collapses placed (created in order, each first as the kept vertex
    // of its pair's first entry), with their colours mixed from the pair's.
    uint32_t placed = 0;
    for (size_t i = 0; i < keep; ++i)
        if (sequence.kept[i] >= n) placed = std::max(placed, sequence.kept[i] - n + 1);
    if (placed > sequence.placed.size())
        throw std::invalid_argument("clusterAfterCollapses: a collapse keeps a vertex that was never placed");
    positions.insert(positions.end(), sequence.placed.begin(), sequence.placed.begin() + placed);
    if (colours) {
        colours->resize(n + placed, 0xFFFFFFFFu);
        std::vector<uint8_t> made(placed, 0);
        for (size_t i = 0; i < keep; ++i) {
            const uint32_t w = sequence.kept[i];
            if (w < n || made[w - n]) continue;
            made[w - n] = 1;  // its first entry: the pair that made it, i and i + 1
            const double share = sequence.placed_share[w - n];
            ColourMix mix;
            mix.add((*colours)[sequence.removed[i]], share + 1e-9);
            if (i + 1 < sequence.size() && sequence.kept[i + 1] == w)
                mix.add((*colours)[sequence.removed[i + 1]], 1.0 - share + 1e-9);
            (*colours)[w] = mix.result();
        }
    }
    sequence.placed.clear();
    sequence.placed_share.clear();
    const uint32_t total = n + placed;
    if (!cluster) return sequence;

    // Each input vertex's planes (its triangles', area-weighted), summed onto the survivors of
    // the edge collapses as they merge.
    std::vector<PlaneSum> planes(options.place ? total : 0);
    if (options.place)
        for (uint32_t t = 0; t < tc; ++t) {
            const glm::dvec3 p0 = positions[triangles[3 * t]], p1 = positions[triangles[3 * t + 1]],
                             p2 = positions[triangles[3 * t + 2]];
            const glm::dvec3 cross = glm::cross(p1 - p0, p2 - p0);
            const double len = glm::length(cross);
            if (!(len > 0.0)) continue;
            const glm::dvec3 normal = cross / len;
            const double area = 0.5 * len, d = -glm::dot(normal, p0);
            PlaneSum s;
            s.a = area * glm::outerProduct(normal, normal);
            s.b = area * d * normal;
            s.area = area;
            for (int c = 0; c < 3; ++c) planes[triangles[3 * t + c]].add(s);
        }

    // The state the collapses leave: each vertex's survivor, the triangles alive and their corners.
    std::vector<uint32_t> survivor(total);
    std::iota(survivor.begin(), survivor.end(), 0u);
    std::vector<uint8_t> alive(total, 1), dead(tc, 0);
    for (size_t i = 0; i < keep; ++i) {
        survivor[sequence.removed[i]] = sequence.kept[i];
        alive[sequence.removed[i]] = 0;
        if (options.place) planes[sequence.kept[i]].add(planes[sequence.removed[i]]);
    }
    for (uint32_t t : sequence.triangles) dead[t] = 1;
    const auto find = [&](uint32_t v) {
        uint32_t r = v;
        while (survivor[r] != r) r = survivor[r];
        while (survivor[v] != r) {
            const uint32_t next = survivor[v];
            survivor[v] = r;
            v = next;
        }
        return r;
    };
    std::vector<uint32_t> corners(triangles.size());
    std::vector<std::vector<uint32_t>> incident(total);
    for (uint32_t t = 0; t < tc; ++t) {
        if (dead[t]) continue;
        for (int c = 0; c < 3; ++c) {
            corners[3 * t + c] = find(triangles[3 * t + c]);
            incident[corners[3 * t + c]].push_back(t);
        }
    }

    // A placed vertex starts with the distance its pair's collapse recorded: an edge collapse
    // moves its vertices by about its error.
    std::vector<float> radius(total, 0.0f);
    for (size_t i = 0; i < keep; ++i)
        if (sequence.kept[i] >= n) radius[sequence.kept[i]] = std::max(radius[sequence.kept[i]], sequence.error[i]);
    std::vector<uint32_t> member_mark(total, 0);
    uint32_t cluster_id = 0;
    std::vector<uint32_t> members, order, died;
    struct Keyed {
        uint64_t cell;
        uint32_t colour, vertex;
        bool operator<(const Keyed& o) const {
            return cell != o.cell ? cell < o.cell : colour != o.colour ? colour < o.colour : vertex < o.vertex;
        }
        bool sameCluster(const Keyed& o) const { return cell == o.cell && colour == o.colour; }
    };
    std::vector<Keyed> keyed;
    const bool by_colour = options.colour_borders && colours;
    // Would moving the members onto p turn a triangle that survives over (or flat from not)?
    const auto turnsOver = [&](const glm::vec3& p, uint32_t mark) {
        for (uint32_t v : members)
            for (uint32_t t : incident[v]) {
                if (dead[t]) continue;
                const uint32_t* c = &corners[3 * t];
                const int inside = (member_mark[c[0]] == mark) + (member_mark[c[1]] == mark) + (member_mark[c[2]] == mark);
                if (inside >= 2) continue;  // degenerate once clustered
                glm::vec3 moved[3];
                for (int k = 0; k < 3; ++k) moved[k] = member_mark[c[k]] == mark ? p : positions[c[k]];
                const glm::vec3 before = glm::cross(positions[c[1]] - positions[c[0]], positions[c[2]] - positions[c[0]]);
                const glm::vec3 after = glm::cross(moved[1] - moved[0], moved[2] - moved[0]);
                if (glm::dot(before, after) < 0.0f) return true;
            }
        return false;
    };
    const float last_cell = extent * options.last_cell * 1.0001f;
    for (float cell = first_cell; cell <= last_cell; cell *= 2.0f) {
        keyed.clear();
        for (uint32_t v = 0; v < uint32_t(alive.size()); ++v) {
            if (!alive[v]) continue;
            const glm::vec3 g = glm::floor((positions[v] - lo) / cell);
            const uint64_t key = (uint64_t(uint32_t(g.x)) << 42) | (uint64_t(uint32_t(g.y)) << 21) | uint64_t(uint32_t(g.z));
            keyed.push_back({key, by_colour ? (*colours)[v] : 0u, v});
        }
        if (keyed.size() <= 1) break;
        std::sort(keyed.begin(), keyed.end());
        for (size_t b = 0; b < keyed.size();) {
            size_t e = b + 1;
            while (e < keyed.size() && keyed[e].sameCluster(keyed[b])) ++e;
            if (e - b > 1) {
                members.clear();
                const uint32_t mark = ++cluster_id;
                glm::dvec3 centre(0.0);
                glm::vec3 box_lo(INFINITY), box_hi(-INFINITY);
                for (size_t j = b; j < e; ++j) {
                    const uint32_t v = keyed[j].vertex;
                    members.push_back(v);
                    member_mark[v] = mark;
                    centre += glm::dvec3(positions[v]);
                    box_lo = glm::min(box_lo, positions[v]), box_hi = glm::max(box_hi, positions[v]);
                }
                centre /= double(members.size());
                // The member nearest the cell's centroid (lowest id on ties): the point when
                // nothing is placed.
                uint32_t nearest = members[0];
                double best = INFINITY;
                for (uint32_t v : members) {
                    const glm::dvec3 d = glm::dvec3(positions[v]) - centre;
                    const double d2 = glm::dot(d, d);
                    if (d2 < best) best = d2, nearest = v;
                }
                uint32_t kept = nearest;
                if (options.place) {
                    PlaneSum sum;
                    for (uint32_t v : members) sum.add(planes[v]);
                    const glm::vec3 p = glm::clamp(glm::vec3(leastSquaresPoint(sum.a, sum.b, centre)), box_lo, box_hi);
                    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && !turnsOver(p, mark)) {
                        kept = uint32_t(positions.size());
                        positions.push_back(p);
                        planes.push_back(sum);
                        alive.push_back(1);
                        radius.push_back(0.0f);
                        member_mark.push_back(0);
                        incident.emplace_back();
                        if (colours) {
                            // The members' colours mixed by the surface each stands for.
                            ColourMix mix;
                            for (uint32_t v : members) mix.add((*colours)[v], planes[v].area + 1e-30);
                            colours->push_back(mix.result());
                        }
                    }
                }
                order.clear();
                for (uint32_t v : members)
                    if (v != kept) order.push_back(v);
                const glm::vec3 at = positions[kept];
                const auto dist = [&](uint32_t v) { return glm::length(positions[v] - at); };
                std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t c) { return dist(a) < dist(c); });
                for (uint32_t v : order) {
                    const float r = std::max(radius[kept], radius[v] + dist(v));
                    radius[kept] = r;
                    died.clear();
                    for (uint32_t t : incident[v]) {
                        if (dead[t]) continue;
                        uint32_t* c = &corners[3 * t];
                        if (c[0] == kept || c[1] == kept || c[2] == kept) {
                            dead[t] = 1;
                            died.push_back(t);
                            continue;
                        }
                        for (int k = 0; k < 3; ++k)
                            if (c[k] == v) c[k] = kept;
                        incident[kept].push_back(t);
                    }
                    std::sort(died.begin(), died.end());
                    died.erase(std::unique(died.begin(), died.end()), died.end());
                    sequence.push(v, kept, r, died.data(), died.size());
                    alive[v] = 0;
                    std::vector<uint32_t>().swap(incident[v]);
                }
            }
            b = e;
        }
    }
    return sequence;
}

}  // namespace occ
