// SPDX-License-Identifier: MIT
#include "prep/fast_collapser.h"

#include "prep/least_squares_point.h"

#include <algorithm>
#include <cmath>

namespace occ {

namespace {

// Symmetric 4x4 error quadric of Garland & Heckbert 1997, "Surface simplification using
// quadric error metrics": a weighted sum of squared distances to a set of planes.
struct Quadric {
    double a00 = 0, a01 = 0, a02 = 0, a11 = 0, a12 = 0, a22 = 0, b0 = 0, b1 = 0, b2 = 0, c = 0;
    double weight = 0;  // total plane weight, to turn the sum of squares into a mean

    void addPlane(const glm::dvec3& n, double d, double w) {
        weight += w;
        a00 += w * n.x * n.x, a01 += w * n.x * n.y, a02 += w * n.x * n.z;
        a11 += w * n.y * n.y, a12 += w * n.y * n.z, a22 += w * n.z * n.z;
        b0 += w * n.x * d, b1 += w * n.y * d, b2 += w * n.z * d;
        c += w * d * d;
    }
    void add(const Quadric& q) {
        a00 += q.a00, a01 += q.a01, a02 += q.a02, a11 += q.a11, a12 += q.a12, a22 += q.a22;
        b0 += q.b0, b1 += q.b1, b2 += q.b2, c += q.c;
        weight += q.weight;
    }
    glm::dmat3 matrix() const { return glm::dmat3(a00, a01, a02, a01, a11, a12, a02, a12, a22); }
    glm::dvec3 vector() const { return {b0, b1, b2}; }
    double eval(const glm::vec3& pf) const {
        const double x = pf.x, y = pf.y, z = pf.z;
        return x * (a00 * x + 2 * (a01 * y + a02 * z + b0)) + y * (a11 * y + 2 * (a12 * z + b1)) +
               z * (a22 * z + 2 * b2) + c;
    }
};

constexpr uint32_t kNone = UINT32_MAX;

// Each vertex's best collapse, cheapest first: a binary heap of vertices with their positions,
// so a vertex is queued at most once and a new best replaces the old in place (no stale entries
// to pop past). Ties (flat regions all cost 0) go to the lower vertex id, so the sequence is a
// function of the mesh alone.
class CandidateHeap {
public:
    void reset(const std::vector<float>* cost, uint32_t vertex_count) {
        cost_ = cost;
        heap_.clear();
        heap_.reserve(vertex_count);
        slot_.assign(vertex_count, kNone);
    }
    bool empty() const { return heap_.empty(); }
    uint32_t top() const { return heap_.front(); }
    // Queues v, or moves it after its cost changed.
    void update(uint32_t v) {
        if (slot_[v] == kNone) {
            slot_[v] = uint32_t(heap_.size());
            heap_.push_back(v);
            up(slot_[v]);
        } else {
            down(up(slot_[v]));
        }
    }
    void remove(uint32_t v) {
        const uint32_t i = slot_[v];
        if (i == kNone) return;
        slot_[v] = kNone;
        const uint32_t last = heap_.back();
        heap_.pop_back();
        if (last == v) return;
        heap_[i] = last;
        slot_[last] = i;
        down(up(i));
    }

private:
    bool before(uint32_t a, uint32_t b) const {
        const float ca = (*cost_)[a], cb = (*cost_)[b];
        return ca < cb || (ca == cb && a < b);
    }
    uint32_t up(uint32_t i) {
        const uint32_t v = heap_[i];
        while (i > 0) {
            const uint32_t parent = (i - 1) / 2;
            if (!before(v, heap_[parent])) break;
            heap_[i] = heap_[parent];
            slot_[heap_[i]] = i;
            i = parent;
        }
        heap_[i] = v;
        slot_[v] = i;
        return i;
    }
    void down(uint32_t i) {
        const uint32_t v = heap_[i], n = uint32_t(heap_.size());
        for (;;) {
            uint32_t child = 2 * i + 1;
            if (child >= n) break;
            if (child + 1 < n && before(heap_[child + 1], heap_[child])) ++child;
            if (!before(heap_[child], v)) break;
            heap_[i] = heap_[child];
            slot_[heap_[i]] = i;
            i = child;
        }
        heap_[i] = v;
        slot_[v] = i;
    }

    const std::vector<float>* cost_ = nullptr;
    std::vector<uint32_t> heap_, slot_;
};

// One per thread, reused from mesh to mesh: its arrays keep their capacity, so a scene of many
// small meshes (the plant's thousands) does not allocate twenty arrays per mesh (malloc and free
// were 7 % of the collapse stage on the plant).
class FastCollapser {
public:
    CollapseSequence run(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                         CollapseCost cost, bool place, std::span<const uint32_t> colours) {
        colour_.assign(colours.begin(), colours.end());
        place_ = place && cost == CollapseCost::Quadric;
        pos_ = positions.data();
        if (place_) {  // placed vertices move their slot: a copy to move
            positions_.assign(positions.begin(), positions.end());
            pos_ = positions_.data();
            box_lo_ = glm::vec3(INFINITY), box_hi_ = glm::vec3(-INFINITY);
            for (const glm::vec3& p : positions) box_lo_ = glm::min(box_lo_, p), box_hi_ = glm::max(box_hi_, p);
        }
        external_.resize(positions.size());
        for (uint32_t v = 0; v < uint32_t(positions.size()); ++v) external_[v] = v;
        corner_.assign(triangles.begin(), triangles.end());
        cost_kind_ = cost;
        n_ = uint32_t(positions.size());
        t_ = uint32_t(triangles.size() / 3);
        border_edges_.clear();
        mark_.assign(n_, 0);
        second_mark_.assign(n_, 0);
        mark_id_ = second_mark_id_ = 0;
        closes_hole_ = kNone;
        sequence_ = CollapseSequence{};
        buildIncidence();
        classifyVertices();
        if (cost_kind_ == CollapseCost::Quadric) buildQuadrics();
        for (uint32_t u = 0; u < n_; ++u)
            if (!locked_[u]) pushBest(u);
        while (!heap_.empty()) {
            const uint32_t u = heap_.top(), v = best_target_[u];
            glm::vec3 at;
            bool reverse = false;
            if (removed_[v] || !legalTarget(u, v, at, &reverse)) {
                // Another neighbour may still be legal; the next change around u retries anyway.
                retryWithLegalTarget(u);
                continue;
            }
            if (reverse) {
                const float c = best_cost_[u];
                heap_.remove(v);
                collapse(v, u, c, at);
                continue;
            }
            heap_.remove(u);
            collapse(u, v, best_cost_[u], at);
        }
        return std::move(sequence_);
    }

private:
    // Vertex -> triangle incidence as linked lists in one pool, so that moving all triangles of a
    // removed vertex to the kept one is O(1) (splice); dead triangles are dropped lazily.
    void buildIncidence() {
        head_.assign(n_, kNone);
        tail_.assign(n_, kNone);
        node_tri_.resize(size_t(t_) * 3);
        node_next_.assign(size_t(t_) * 3, kNone);
        for (uint32_t t = 0; t < t_; ++t)
            for (int c = 0; c < 3; ++c) {
                const uint32_t node = 3 * t + uint32_t(c), v = corner_[node];
                node_tri_[node] = t;
                if (head_[v] == kNone)
                    head_[v] = node;
                else
                    node_next_[tail_[v]] = node;
                tail_[v] = node;
            }
        alive_.assign(t_, 1);
        removed_.assign(n_, 0);
        locked_.assign(n_, 0);
        best_cost_.assign(n_, INFINITY);
        best_target_.assign(n_, kNone);
        heap_.reset(&best_cost_, n_);
        count_.assign(n_, 0);
    }

    // Each vertex's kind, from how many of its triangles use the edge to each neighbour (counted
    // through its incidence list, no global sort of edge keys): an edge used by three or more
    // triangles is a non-manifold seam and locks both ends (non-manifold input stays intact);
    // one used by one triangle is a border. A vertex on exactly two border edges whose fan is one
    // open chain (triangles = neighbours - 1) is a border vertex, which may move along its border
    // (Quadric cost; EdgeLength keeps the outline, as the hand-checked fixtures expect); any
    // other vertex on a border (a corner where chains meet) is locked until a hole closes
    // through it (reclassify).
    void classifyVertices() {
        border_.assign(n_, 0);
        const bool borders_move = cost_kind_ == CollapseCost::Quadric;
        uses_.assign(n_, 0);
        last_triangle_.resize(n_);
        std::vector<uint32_t>& uses = uses_;
        std::vector<uint32_t>& last_triangle = last_triangle_;
        std::vector<uint32_t>& touched = touched_;
        for (uint32_t v = 0; v < n_; ++v) {
            if (head_[v] == kNone) {
                locked_[v] = 1;  // a vertex used by no triangle has nothing to collapse along
                continue;
            }
            touched.clear();
            uint32_t triangles = 0;
            for (uint32_t node = head_[v]; node != kNone; node = node_next_[node]) {
                const uint32_t t = node_tri_[node];
                ++triangles;
                for (int c = 0; c < 3; ++c) {
                    const uint32_t w = corner_[3 * t + c];
                    if (w == v) continue;
                    if (uses[w]++ == 0) touched.push_back(w);
                    last_triangle[w] = t;
                }
            }
            uint32_t border_edges = 0;
            for (uint32_t w : touched) {
                if (uses[w] > 2) locked_[v] = locked_[w] = 1;
                if (uses[w] == 1) {
                    ++border_edges;
                    if (v < w) border_edges_.push_back({v, w, last_triangle[w]});
                    if (!borders_move) locked_[v] = locked_[w] = 1;
                }
                uses[w] = 0;
            }
            if (border_edges == 0) continue;
            if (borders_move && border_edges == 2 && triangles + 1 == touched.size()) border_[v] = 1;
            else locked_[v] = 1;
        }
    }

    void buildQuadrics() {
        quadric_.assign(n_, Quadric{});
        error_quadric_.assign(n_, Quadric{});
        for (uint32_t t = 0; t < t_; ++t) {
            const glm::dvec3 p0 = pos_[corner_[3 * t]], p1 = pos_[corner_[3 * t + 1]], p2 = pos_[corner_[3 * t + 2]];
            const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
            const double len = glm::length(n);
            if (len <= 0.0) continue;
            // Weighted by the square root of twice the area, linear in length as meshoptimizer
            // weighs its planes (simplifier.cpp, 0.18): with area weights a fillet's or a pipe
            // cap's small triangles were too cheap to move far, which a Hausdorff error punishes.
            const glm::dvec3 unit = n / len;
            Quadric q, area;
            q.addPlane(unit, -glm::dot(unit, p0), std::sqrt(len));
            area.addPlane(unit, -glm::dot(unit, p0), 0.5 * len);
            for (int c = 0; c < 3; ++c) {
                quadric_[corner_[3 * t + c]].add(q);
                error_quadric_[corner_[3 * t + c]].add(area);
            }
        }
        // A border edge also adds, to both ends, the plane through it at right angles to its
        // face (Garland & Heckbert's boundary constraint), weighted kBorderWeight x the edge's
        // length (linear, as the face planes): moving a border vertex off its outline costs.
        for (const BorderEdge& b : border_edges_) {
            const uint32_t t = b.triangle;
            const glm::dvec3 p0 = pos_[corner_[3 * t]], p1 = pos_[corner_[3 * t + 1]], p2 = pos_[corner_[3 * t + 2]];
            const glm::dvec3 n = glm::cross(p1 - p0, p2 - p0);
            const double len = glm::length(n);
            const glm::dvec3 pa = pos_[b.a], along = glm::dvec3(pos_[b.b]) - pa;
            const double edge = glm::length(along);
            if (len <= 0.0 || edge <= 0.0) continue;
            const glm::dvec3 across = glm::cross(along / edge, n / len);
            Quadric e, area;
            e.addPlane(across, -glm::dot(across, pa), kBorderWeight * edge);
            area.addPlane(across, -glm::dot(across, pa), edge * edge);
            area.weight = 0;  // a constraint, not surface: the recorded distance stays a surface mean
            quadric_[b.a].add(e);
            quadric_[b.b].add(e);
            error_quadric_[b.a].add(area);
            error_quadric_[b.b].add(area);
        }
    }

    // The removed vertex's quadric at the kept position, as meshoptimizer ranks collapses: v's
    // own planes pass through p_v, and counting v's earlier collapses again made vertices that had
    // absorbed much look dear to move onto. Depends on u's quadric and v's position only.
    float cost(uint32_t u, uint32_t v) const {
        if (cost_kind_ == CollapseCost::EdgeLength) return glm::length(pos_[u] - pos_[v]);
        if (place_) {
            Quadric q = quadric_[u];
            q.add(quadric_[v]);
            return float(std::max(0.0, q.eval(placement(u, v))));
        }
        return float(std::max(0.0, quadric_[u].eval(pos_[v])));
    }

    // Placing (issue 49, item 3): both ends of an edge of two interior vertices may move to a
    // new point; a border vertex moves along its border onto a neighbour as before (placed
    // border collapses cut the corners of flat sheets), and nothing moves a locked vertex.
    bool placeable(uint32_t u, uint32_t v) const {
        return place_ && !locked_[v] && !border_[u] && !border_[v] && (colour_.empty() || colour_[u] == colour_[v]);
    }

    // Where the vertex the collapse u-v leaves goes: v's position (a half-edge collapse), or,
    // where placeable, the point of least squared distance to both ends' planes (their summed
    // quadric, Garland & Heckbert's optimal placement; flat directions resolved towards the
    // edge's midpoint), unless it is no cheaper than v's position or lies farther from the
    // midpoint than the edge is long (near-parallel planes).
    glm::vec3 placement(uint32_t u, uint32_t v) const {
        if (!placeable(u, v)) return pos_[v];
        Quadric q = quadric_[u];
        q.add(quadric_[v]);
        const glm::dvec3 pu = pos_[u], pv = pos_[v], mid = 0.5 * (pu + pv);
        const glm::dvec3 x = leastSquaresPoint(q.matrix(), q.vector(), mid);
        // Within the input's box: an HLOD stays inside the box its node is culled by.
        const glm::vec3 p = glm::clamp(glm::vec3(x), box_lo_, box_hi_);
        if (!(glm::length(x - mid) <= glm::length(pu - pv)) || !std::isfinite(p.x + p.y + p.z)) return pos_[v];
        const double at_p = q.eval(p), at_v = q.eval(pos_[v]);
        return at_p < at_v * (1.0 - 1e-6) ? p : pos_[v];
    }

    // A locked vertex whose border changed (a hole closed through it) may now be a plain border
    // vertex: on exactly two border edges, one open fan, no edge of three or more triangles.
    void reclassify(uint32_t x) {
        const uint32_t m = ++mark_id_;
        candidates_.clear();
        uint32_t triangles = 0;
        forTriangles(x, [&](uint32_t t) {
            ++triangles;
            for (int c = 0; c < 3; ++c) {
                const uint32_t w = corner_[3 * t + c];
                if (w == x) continue;
                if (mark_[w] != m) mark_[w] = m, count_[w] = 0, candidates_.push_back(w);
                ++count_[w];
            }
        });
        uint32_t border_edges = 0;
        for (uint32_t w : candidates_) {
            if (count_[w] > 2) return;
            border_edges += count_[w] == 1;
        }
        if (border_edges == 2 && triangles + 1 == candidates_.size()) locked_[x] = 0, border_[x] = 1;
    }

    // Triangles on the edge a-b.
    uint32_t trianglesOn(uint32_t a, uint32_t b) {
        uint32_t n = 0;
        forTriangles(a, [&](uint32_t t) { n += contains(t, b); });
        return n;
    }

    bool contains(uint32_t t, uint32_t v) const {
        return corner_[3 * t] == v || corner_[3 * t + 1] == v || corner_[3 * t + 2] == v;
    }

    // Calls f(t) for every live triangle around v and unlinks dead ones on the way.
    template <class F>
    void forTriangles(uint32_t v, F&& f) {
        uint32_t prev = kNone;
        for (uint32_t node = head_[v]; node != kNone;) {
            const uint32_t next = node_next_[node];
            if (!alive_[node_tri_[node]]) {
                if (prev == kNone)
                    head_[v] = next;
                else
                    node_next_[prev] = next;
                if (tail_[v] == node) tail_[v] = prev;
            } else {
                f(node_tri_[node]);
                prev = node;
            }
            node = next;
        }
    }

    // Marks the neighbours of v with a fresh mark and returns it.
    uint32_t markNeighbours(uint32_t v, std::vector<uint32_t>* out) {
        const uint32_t m = ++mark_id_;
        forTriangles(v, [&](uint32_t t) {
            for (int c = 0; c < 3; ++c) {
                const uint32_t w = corner_[3 * t + c];
                if (w != v && mark_[w] != m) {
                    mark_[w] = m;
                    if (out) out->push_back(w);
                }
            }
        });
        return m;
    }

    // The neighbours a border vertex may move to: the far ends of its border edges (the
    // neighbours that share one triangle with it).
    void borderNeighbours(uint32_t u, std::vector<uint32_t>& out) {
        out.clear();
        const uint32_t m = ++mark_id_;
        candidates_.clear();
        forTriangles(u, [&](uint32_t t) {
            for (int c = 0; c < 3; ++c) {
                const uint32_t w = corner_[3 * t + c];
                if (w == u) continue;
                if (mark_[w] != m) mark_[w] = m, count_[w] = 0, candidates_.push_back(w);
                ++count_[w];
            }
        });
        for (uint32_t w : candidates_)
            if (count_[w] == 1) out.push_back(w);
    }

    void pushBest(uint32_t u) {
        float best = INFINITY;
        uint32_t target = kNone;
        if (border_[u]) {
            borderNeighbours(u, border_neighbours_);
            for (uint32_t w : border_neighbours_) {
                const float e = cost(u, w);
                if (e < best || (e == best && w < target)) best = e, target = w;
            }
        } else {
            // u is interior, so its fan is a closed disk: the corner after u in each triangle
            // visits every neighbour exactly once.
            forTriangles(u, [&](uint32_t t) {
                const uint32_t* c = &corner_[3 * t];
                const uint32_t w = c[0] == u ? c[1] : (c[1] == u ? c[2] : c[0]);
                const float e = cost(u, w);
                if (e < best || (e == best && w < target)) best = e, target = w;
            });
        }
        setBest(u, best, target);
    }

    // u's queued collapse becomes u -> target at cost (target kNone: u leaves the queue).
    void setBest(uint32_t u, float cost, uint32_t target) {
        best_cost_[u] = cost;
        best_target_[u] = target;
        if (target != kNone) heap_.update(u);
        else heap_.remove(u);
    }

    void retryWithLegalTarget(uint32_t u) {
        neighbours_.clear();
        if (border_[u]) borderNeighbours(u, neighbours_);
        else markNeighbours(u, &neighbours_);
        float best = INFINITY;
        uint32_t target = kNone;
        for (uint32_t w : neighbours_) {
            const float e = cost(u, w);
            glm::vec3 at;
            if ((e < best || (e == best && w < target)) && legalTarget(u, w, at)) best = e, target = w;
        }
        setBest(u, best, target);
    }

    // Legal half-edge collapse u -> v (v keeps its place): the link condition (common
    // neighbours of u and v are exactly the apexes of the triangles on edge uv), no surviving
    // triangle becomes a copy of one v already has (the tetrahedron case the link condition
    // misses), and no surviving triangle of u turns over when u moves onto v (a triangle that
    // becomes or was flat is allowed, as meshoptimizer allows it: CAD slivers otherwise pin
    // their vertices). One exception to the link condition closes holes: a border loop of
    // three (u, v, x) may shut, u onto v, when both border edges to x are x's, and x turns
    // interior (or, where loops met at x, becomes a plain border vertex again). Without it every
    // bolt hole of a CAD sheet stopped as a triangle and held its sheet far above its target.
    // Sets closes_hole_ to x for collapse(), kNone otherwise.
    // The collapse u-v with the kept vertex at its placement, or else at v: false when neither
    // is legal; at: where it goes.
    // A placement at u's own position is the half-edge collapse v -> u (no vertex added):
    // reverse is then set, and the caller removes v instead.
    bool legalTarget(uint32_t u, uint32_t v, glm::vec3& at, bool* reverse = nullptr) {
        at = placement(u, v);
        if (reverse) *reverse = false;
        if (at == pos_[u] && at != pos_[v]) {
            if (reverse && !locked_[u] && isLegal(v, u, at)) return *reverse = true;
        } else if (isLegal(u, v, at)) {
            return true;
        }
        if (at == pos_[v]) return false;
        at = pos_[v];
        return isLegal(u, v, at);
    }

    // A placed vertex must also keep the triangles around v from turning over, and every
    // triangle around either end within kPlacedTurn of its normal (a triangle that becomes flat
    // is allowed): the placement's normal check.
    static constexpr float kPlacedTurn = 0.5f;  // cos 60 degrees
    bool keepsFacing(uint32_t moved, uint32_t other, const glm::vec3& at, bool placed, uint32_t mv) {
        bool ok = true;
        const glm::vec3 from = pos_[moved];
        forTriangles(moved, [&](uint32_t t) {
            if (!ok || contains(t, other)) return;
            const uint32_t* c = &corner_[3 * t];
            const int k = c[0] == moved ? 0 : (c[1] == moved ? 1 : 2);
            const uint32_t a = c[(k + 1) % 3], b = c[(k + 2) % 3];
            const glm::vec3 n_old = glm::cross(pos_[a] - from, pos_[b] - from);
            const glm::vec3 n_new = glm::cross(pos_[a] - at, pos_[b] - at);
            const float d = glm::dot(n_old, n_new);
            if (d < 0.0f) {
                ok = false;
                return;
            }
            if (placed) {
                const float lo = glm::length(n_old), ln = glm::length(n_new);
                if (ln > 1e-3f * lo && d < kPlacedTurn * lo * ln) {
                    ok = false;
                    return;
                }
            }
            if (mv != 0 && mark_[a] == mv && mark_[b] == mv)
                forTriangles(other, [&](uint32_t s) { ok = ok && !(contains(s, a) && contains(s, b)); });
        });
        return ok;
    }

    bool isLegal(uint32_t u, uint32_t v, const glm::vec3& at) {
        closes_hole_ = kNone;
        const uint32_t mv = markNeighbours(v, nullptr);
        if (mark_[u] != mv) return false;  // no longer an edge
        uint32_t shared = 0, common = 0, apex = kNone, first_common[2] = {kNone, kNone};
        const uint32_t mu = ++second_mark_id_;
        forTriangles(u, [&](uint32_t t) {
            const bool on_edge = contains(t, v);
            shared += on_edge;
            for (int c = 0; c < 3; ++c) {
                const uint32_t w = corner_[3 * t + c];
                if (on_edge && w != u && w != v) apex = w;
                if (w != u && second_mark_[w] != mu) {
                    second_mark_[w] = mu;
                    if (mark_[w] == mv && common++ < 2) first_common[common - 1] = w;
                }
            }
        });
        // The common neighbour besides the apex, when there are exactly two.
        const uint32_t extra = first_common[0] == apex ? first_common[1] : first_common[0];
        if (border_[u] && border_[v] && shared == 1 && common == 2 && apex != kNone && extra != apex &&
            trianglesOn(u, extra) == 1 && trianglesOn(v, extra) == 1) {
            closes_hole_ = extra;
            common = 1;
        }
        if (common != shared) return false;
        // An interior vertex moves along an interior edge (two triangles), a border vertex
        // along its border (one): the border stays a border.
        if (shared != (border_[u] ? 1u : 2u)) return false;

        const bool placed = at != pos_[v];
        if (!keepsFacing(u, v, at, placed, mv)) return false;
        return !placed || keepsFacing(v, u, at, placed, 0);
    }

    void collapse(uint32_t u, uint32_t v, float cost_value, const glm::vec3& at) {
        removed_tris_.clear();
        forTriangles(u, [&](uint32_t t) {
            if (contains(t, v)) {
                alive_[t] = 0;
                removed_tris_.push_back(t);
            } else {
                for (int c = 0; c < 3; ++c)
                    if (corner_[3 * t + c] == u) corner_[3 * t + c] = v;
            }
        });
        std::sort(removed_tris_.begin(), removed_tris_.end());
        // Splice u's incidence list onto v's: those triangles now use v.
        if (head_[u] != kNone) {
            if (head_[v] == kNone)
                head_[v] = head_[u];
            else
                node_next_[tail_[v]] = head_[u];
            tail_[v] = tail_[u];
        }
        head_[u] = tail_[u] = kNone;
        removed_[u] = 1;
        // A placed vertex: v's slot goes on as a new vertex at `at`, which both ends move onto.
        const bool placed = at != pos_[v];
        uint32_t kept = external_[v];
        if (placed) {
            kept = n_ + uint32_t(sequence_.placed.size());
            const double wu = error_quadric_[u].weight, wv = error_quadric_[v].weight;
            sequence_.placed.push_back(at);
            sequence_.placed_share.push_back(wu + wv > 0.0 ? float(wu / (wu + wv)) : 0.5f);
            positions_[v] = at;
        }
        float recorded = cost_value;
        if (cost_kind_ == CollapseCost::Quadric) {
            // Recorded as a distance: the root mean square distance of the kept position to the
            // surface planes both vertices stand for, area weighted: the scale the LOD and HLOD
            // cuts' tau was tuned to (recorded with the ranking's sqrt-area weights, the 10^5
            // plant's orbit cut drew 1.45x the triangles at tau 1).
            quadric_[v].add(quadric_[u]);
            error_quadric_[v].add(error_quadric_[u]);
            const Quadric& e = error_quadric_[v];
            recorded = e.weight > 0 ? float(std::sqrt(std::max(0.0, e.eval(pos_[v])) / e.weight)) : 0.0f;
        }
        if (placed) {
            sequence_.push(external_[u], kept, recorded, nullptr, 0);
            sequence_.push(external_[v], kept, recorded, removed_tris_.data(), removed_tris_.size());
            external_[v] = kept;
        } else {
            sequence_.push(external_[u], kept, recorded, removed_tris_.data(), removed_tris_.size());
        }

        // A closed hole leaves v interior and x interior or a plain border vertex.
        const uint32_t closed = closes_hole_;
        if (closed != kNone) {
            border_[v] = 0;
            if (border_[closed]) border_[closed] = 0;
            else reclassify(closed);
        }

        // v has a new quadric and new neighbours: all its candidates change. A neighbour w's
        // quadric and v's position are as they were, so its cost to v stands; what changes is
        // that u's former neighbours now reach v, and that a w whose best target was u lost it
        // (a full look, as for a border vertex, whose border neighbours may have changed).
        if (!locked_[v]) pushBest(v);
        if (closed != kNone && !locked_[closed]) pushBest(closed);
        neighbours_.clear();
        markNeighbours(v, &neighbours_);
        for (uint32_t w : neighbours_) {
            if (place_ && !locked_[w]) {
                pushBest(w);  // v's quadric (and maybe place) changed: every cost to v did
                continue;
            }
            if (locked_[w] || best_target_[w] == v) continue;
            if (border_[w] || best_target_[w] == u || best_target_[w] == kNone) {
                pushBest(w);
                continue;
            }
            const float e = cost(w, v);
            if (e < best_cost_[w] || (e == best_cost_[w] && v < best_target_[w])) {
                setBest(w, e, v);
            }
        }
    }

    std::vector<glm::vec3> positions_;  // placing: the welded positions, a slot's moved where a collapse put it
    const glm::vec3* pos_ = nullptr;    // the input's positions, or positions_.data() when placing
    std::vector<uint32_t> external_;    // per slot: the vertex it is in the sequence (a placed one: n_ + i)
    bool place_ = false;
    std::vector<uint32_t> colour_;  // per slot, when colours were given: only ends of one colour are placed
    glm::vec3 box_lo_{0.0f}, box_hi_{0.0f};  // the input's box: placements stay in it
    std::vector<uint32_t> corner_;
    CollapseCost cost_kind_ = CollapseCost::Quadric;
    uint32_t n_ = 0, t_ = 0;

    std::vector<uint32_t> head_, tail_, node_tri_, node_next_;
    std::vector<uint8_t> alive_, removed_, locked_, border_;
    struct BorderEdge {
        uint32_t a, b, triangle;
    };
    std::vector<BorderEdge> border_edges_;  // the input's border edges and their triangle, for the quadrics
    std::vector<uint32_t> count_, candidates_, border_neighbours_;
    std::vector<uint32_t> uses_, last_triangle_, touched_;  // classifyVertices' scratch
    // meshoptimizer's kEdgeWeightBorder; on the engine (bench prep, docs/results_prep.md) 1 and 3
    // left the 1 % error above meshopt's, 10 below it at every target.
    static constexpr double kBorderWeight = 10.0;
    std::vector<uint32_t> mark_, second_mark_;
    std::vector<float> best_cost_;       // cost of the candidate currently queued for each vertex
    std::vector<uint32_t> best_target_;  // its kept vertex, kNone if none
    uint32_t mark_id_ = 0, second_mark_id_ = 0;
    std::vector<Quadric> quadric_;        // ranks collapses (meshoptimizer's weights)
    std::vector<Quadric> error_quadric_;  // area-weighted planes: the recorded error
    CandidateHeap heap_;
    std::vector<uint32_t> neighbours_, removed_tris_;
    CollapseSequence sequence_;
    uint32_t closes_hole_ = kNone;  // set by isLegal: the third vertex of a border loop u-v closes
};

}  // namespace

CollapseSequence fastCollapseSequence(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                      CollapseCost cost, bool place, std::span<const uint32_t> colours) {
    thread_local FastCollapser collapser;
    return collapser.run(positions, triangles, cost, place, colours);
}

}  // namespace occ
