// SPDX-License-Identifier: MIT
#include "prep/hierarchy.h"
#include "prep/vertex_normals.h"

#include "prep/prepare.h"
#include "scene/colour.h"

#include <glm/gtc/type_ptr.hpp>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <tuple>
#include <unordered_map>

namespace occ {

ObjectHierarchy buildObjectHierarchy(std::span<const k::Aabb> boxes, std::span<const uint64_t> triangles,
                                     uint32_t fanout) {
    if (fanout < 2) throw std::invalid_argument("buildObjectHierarchy: fanout must be at least 2");
    if (boxes.empty()) throw std::invalid_argument("buildObjectHierarchy: no objects");
    if (boxes.size() != triangles.size())
        throw std::invalid_argument("buildObjectHierarchy: boxes and triangle counts differ in size");
    std::vector<uint32_t> order(boxes.size());
    std::iota(order.begin(), order.end(), 0u);
    const auto centre = [&](uint32_t i) { return 0.5f * (boxes[i].min + boxes[i].max); };

    // Cuts order[b, e) into `parts` groups (sizes within a third of equal); appends the groups' bounds.
    std::vector<std::pair<size_t, size_t>> groups;
    const auto cut = [&](auto&& self, size_t b, size_t e, uint32_t parts) -> void {
        if (parts <= 1 || e - b <= 1) {
            groups.emplace_back(b, e);
            return;
        }
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (size_t j = b; j < e; ++j) lo = glm::min(lo, centre(order[j])), hi = glm::max(hi, centre(order[j]));
        const glm::vec3 extent = hi - lo;
        // The widest axis; extents within 1e-4 of each other count as equal (x, then y, then z),
        // so that rounding does not turn copies of one arrangement differently.
        const float widest_extent = std::max({extent.x, extent.y, extent.z}) * (1.0f - 1e-4f);
        const int axis = extent.x >= widest_extent ? 0 : extent.y >= widest_extent ? 1 : 2;
        const uint32_t left = parts / 2;
        const auto less = [&](uint32_t x, uint32_t y) {
            const float cx = centre(x)[axis], cy = centre(y)[axis];
            return cx < cy || (cx == cy && x < y);
        };
        // The split goes into the widest gap between consecutive centres among the middle third
        // of the objects around the balanced position: it falls between clusters (a tiled
        // model's copies, a plant's rooms) rather than through them, and never between equal
        // coordinates, so that a subtree's shape depends on its geometry, not on object ids,
        // and repeated geometry gets repeated subtrees (findRepeatedSubtrees). Gaps within 1e-4
        // of the widest count as equal: the one nearest the balanced position wins.
        const size_t n = e - b, balanced = b + n * left / parts;
        const size_t reach = std::min(balanced - b, e - balanced) / 3;
        size_t mid = balanced;
        bool in_gap = false;
        const auto at = [&](size_t j) { return centre(order[j])[axis]; };
        if (reach > 0) {
            const size_t from = balanced - reach, to = balanced + reach;  // splits in [from, to]
            std::nth_element(order.begin() + std::ptrdiff_t(b), order.begin() + std::ptrdiff_t(from - 1),
                             order.begin() + std::ptrdiff_t(e), less);
            std::nth_element(order.begin() + std::ptrdiff_t(from), order.begin() + std::ptrdiff_t(to),
                             order.begin() + std::ptrdiff_t(e), less);
            std::sort(order.begin() + std::ptrdiff_t(from), order.begin() + std::ptrdiff_t(to), less);
            float widest = 0.0f;
            for (size_t j = from; j <= to; ++j) widest = std::max(widest, at(j) - at(j - 1));
            const auto off = [&](size_t j) { return j > balanced ? j - balanced : balanced - j; };
            for (size_t j = from; widest > 0.0f && j <= to; ++j)
                if (at(j) - at(j - 1) >= widest * (1.0f - 1e-4f) && (!in_gap || off(j) < off(mid))) mid = j, in_gap = true;
        }
        if (!in_gap)  // no gap to split in: the balanced position
            std::nth_element(order.begin() + std::ptrdiff_t(b), order.begin() + std::ptrdiff_t(mid),
                             order.begin() + std::ptrdiff_t(e), less);
        self(self, b, mid, left);
        self(self, mid, e, parts - left);
    };

    ObjectHierarchy h;
    // Breadth-first: a queue of (node, object range) in node order.
    struct Pending {
        size_t b, e;
    };
    std::vector<Pending> ranges{{0, order.size()}};
    h.nodes.emplace_back();
    for (size_t n = 0; n < h.nodes.size(); ++n) {
        const Pending r = ranges[n];
        SceneNode& node = h.nodes[n];
        node.box.min = glm::vec3(INFINITY);
        node.box.max = glm::vec3(-INFINITY);
        for (size_t j = r.b; j < r.e; ++j) {
            node.box.min = glm::min(node.box.min, boxes[order[j]].min);
            node.box.max = glm::max(node.box.max, boxes[order[j]].max);
            node.triangles += triangles[order[j]];
        }
        h.levels = std::max(h.levels, node.depth + 1);
        if (r.e - r.b == 1 && n > 0) {
            node.object = order[r.b];
            continue;
        }
        groups.clear();
        if (r.e - r.b <= fanout) {
            // Leaves in an order of their own (triangles, then centre), not the order the splits
            // left them in, so that copies of one arrangement get their leaves in the same order.
            std::sort(order.begin() + std::ptrdiff_t(r.b), order.begin() + std::ptrdiff_t(r.e), [&](uint32_t x, uint32_t y) {
                const glm::vec3 cx = centre(x), cy = centre(y);
                return std::tie(triangles[x], cx.x, cx.y, cx.z, x) < std::tie(triangles[y], cy.x, cy.y, cy.z, y);
            });
            for (size_t j = r.b; j < r.e; ++j) groups.emplace_back(j, j + 1);
        } else {
            cut(cut, r.b, r.e, fanout);
        }
        const uint32_t depth = node.depth;
        h.nodes[n].first_child = uint32_t(h.nodes.size());
        h.nodes[n].child_count = uint32_t(groups.size());
        for (const auto& [b, e] : groups) {
            SceneNode child;
            child.depth = depth + 1;
            h.nodes.push_back(child);
            ranges.push_back({b, e});
        }
    }
    return h;
}

void appendLevel(std::span<const glm::vec3> positions, std::span<const int32_t> ecol,
                 std::span<const uint32_t> triangles, std::span<const uint32_t> map, uint32_t k,
                 const glm::mat4& world, std::vector<glm::vec3>& out_positions, std::vector<uint32_t>& out_triangles) {
    const uint32_t base = uint32_t(out_positions.size());
    for (uint32_t v = 0; v < k; ++v) out_positions.push_back(glm::vec3(world * glm::vec4(positions[v], 1.0f)));
    const auto walk = [&](uint32_t c) {
        while (c >= k) c = uint32_t(ecol[c]);
        return c;
    };
    for (uint32_t t = 0; t < map[k]; ++t) {
        const uint32_t a = walk(triangles[3 * t]), b = walk(triangles[3 * t + 1]), c = walk(triangles[3 * t + 2]);
        if (a == b || b == c || a == c) continue;
        out_triangles.insert(out_triangles.end(), {base + a, base + b, base + c});
    }
}

SubtreeRepeats findRepeatedSubtrees(std::span<const SceneNode> nodes, std::span<const uint32_t> object_class,
                                    std::span<const glm::mat4> object_world, std::span<const uint32_t> order) {
    const uint32_t count = uint32_t(nodes.size());
    std::vector<uint32_t> descending;  // the default order: inner nodes from the last
    if (order.empty()) {
        for (uint32_t n = count; n-- > 0;)
            if (nodes[n].child_count > 0) descending.push_back(n);
        order = descending;
    }
    SubtreeRepeats r;
    r.index.assign(count, UINT32_MAX);
    // Per node: its first leaf's object and a class; leaves' classes are their objects', inner
    // nodes' come after. (16 bytes a node and a bucket entry per inner node: prep's memory bound.)
    std::vector<uint32_t> first(count);
    std::vector<uint64_t> cls(count);
    uint64_t classes = UINT32_MAX + uint64_t(1);
    std::unordered_map<uint64_t, std::vector<uint32_t>> buckets;  // children's classes -> nodes
    // Relative placements are compared in double at 1e-5.
    const auto world = [&](uint32_t n) { return glm::dmat4(object_world[first[n]]); };
    double matched_slack = 0.0;  // same()'s translation slack, for the repeat's error
    const auto same = [&](uint32_t n, uint32_t m) {
        const SceneNode& a = nodes[n];
        const SceneNode& b = nodes[m];
        if (a.child_count != b.child_count) return false;
        for (uint32_t i = 0; i < a.child_count; ++i)
            if (cls[a.first_child + i] != cls[b.first_child + i]) return false;
        // Positions are floats: two placements cannot be told apart below a few units in the last
        // place of the coordinates they come from (about 1e-6 of the largest), nor, here, below
        // 1e-5 of the subtree's diagonal.
        const glm::dvec3 extent = glm::dvec3(b.box.max) - glm::dvec3(b.box.min);
        const auto magnitude = [](const SceneNode& x) {
            return std::max({std::abs(x.box.min.x), std::abs(x.box.min.y), std::abs(x.box.min.z), std::abs(x.box.max.x),
                             std::abs(x.box.max.y), std::abs(x.box.max.z)});
        };
        const double slack = 1e-5 * glm::length(extent) + 1e-6 * double(std::max(magnitude(a), magnitude(b)));
        matched_slack = slack;
        const glm::dmat4 from_a = world(n), to_a = glm::inverse(from_a), to_b = glm::inverse(world(m));
        for (uint32_t i = 0; i < a.child_count; ++i) {  // child i relative to the node's first leaf
            const glm::dmat4 pa = to_a * world(a.first_child + i), pb = to_b * world(b.first_child + i);
            for (int c = 0; c < 3; ++c)
                for (int e = 0; e < 3; ++e)
                    if (!(std::abs(pa[c][e] - pb[c][e]) <= 1e-5)) return false;  // NaN (a singular world) too
            // The translations differ in the first leaf's frame; how far that is in the world:
            const glm::dvec3 apart = glm::dmat3(from_a) * (glm::dvec3(pa[3]) - glm::dvec3(pb[3]));
            if (!(glm::length(apart) <= slack)) return false;
        }
        return true;
    };
    for (uint32_t n = 0; n < count; ++n)
        if (nodes[n].child_count == 0) first[n] = nodes[n].object, cls[n] = object_class[nodes[n].object];
    for (const uint32_t n : order) {
        const SceneNode& node = nodes[n];
        first[n] = first[node.first_child];
        uint64_t key = 0x9e3779b97f4a7c15ull ^ node.child_count;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
            key = (key ^ cls[c]) * 0x100000001b3ull + (key >> 29);
        std::vector<uint32_t>& bucket = buckets[key];
        uint32_t found = UINT32_MAX;
        // A few candidates per bucket: the same children placed differently are other classes.
        for (size_t j = 0; j < bucket.size() && j < 16 && found == UINT32_MAX; ++j)
            if (same(n, bucket[j])) found = bucket[j];
        if (found == UINT32_MAX) {
            cls[n] = classes++;
            bucket.push_back(n);
            continue;
        }
        const glm::dmat4 motion = world(n) * glm::inverse(world(found));
        // Only similarities move an HLOD's error by one factor: equal, orthogonal columns; and no
        // mirror, which would turn the HLOD's triangles inside out.
        const glm::dvec3 c0(motion[0]), c1(motion[1]), c2(motion[2]);
        const double scale = glm::length(c0);
        const double tolerance = 1e-5 * scale;
        const auto within = [](double x, double limit) { return std::abs(x) <= limit; };  // false for NaN
        if (!(scale > 0.0) || !(glm::determinant(glm::dmat3(motion)) > 0.0) || !within(glm::length(c1) - scale, tolerance) ||
            !within(glm::length(c2) - scale, tolerance) || !within(glm::dot(c0, c1), tolerance * scale) ||
            !within(glm::dot(c0, c2), tolerance * scale) || !within(glm::dot(c1, c2), tolerance * scale) ||
            !std::isfinite(motion[3][0] + motion[3][1] + motion[3][2])) {
            cls[n] = classes++;
            bucket.push_back(n);
            continue;
        }
        cls[n] = cls[found];
        r.index[n] = uint32_t(r.list.size());
        r.list.push_back({found, float(scale), float(matched_slack), glm::mat4(motion)});
    }
    return r;
}

uint32_t levelWithTriangles(std::span<const uint32_t> map, uint32_t q, uint64_t want) {
    const uint32_t n = uint32_t(map.size() - 1);
    if (map[n] <= want) return n;
    uint32_t lo = std::min(q, n), hi = n;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo) / 2;
        if (map[mid] >= want) hi = mid;
        else lo = mid + 1;
    }
    return lo;
}

namespace {

// What a built node hands its parent: its HLOD's progressive mesh in world space up to the
// finest level the parent may take (`top`), with each level's error against the subtree at full
// detail (the node's own error included). The parent chooses the level (chooseChildLevels).
struct KeptMesh {
    std::vector<glm::vec3> positions;  // the first `top`, world space
    std::vector<uint32_t> colours;     // the first `top` (oss::kWhite layout)
    std::vector<int32_t> ecol;         // the first `top`
    std::vector<uint32_t> triangles;   // the first map[top], corners walked below `top`
    std::vector<uint32_t> map;         // top + 1 entries
    std::vector<float> error;          // top + 1 entries: error[k] of the level with k vertices
    uint32_t q = 0;
};

// A vertex colour (oss::kWhite layout, sRGB) times a linear tint, as the display multiplies them.
uint32_t tintedColour(const glm::vec4& tint, uint32_t colour) {
    uint32_t out = colour & 0xFF000000u;
    for (int c = 0; c < 3; ++c) {
        const float linear = srgbToLinear(float((colour >> (8 * c)) & 0xFFu) / 255.0f) * glm::clamp(tint[c], 0.0f, 1.0f);
        out |= uint32_t(std::lround(255.0f * linearToSrgb(linear))) << (8 * c);
    }
    return out;
}

// The largest k in [q, n] whose level has at most `most` triangles (q where even it has more).
uint32_t levelWithAtMost(std::span<const uint32_t> map, uint32_t q, uint64_t most) {
    const uint32_t n = uint32_t(map.size() - 1);
    uint32_t lo = std::min(q, n), hi = n;
    while (lo < hi) {
        const uint32_t mid = lo + (hi - lo + 1) / 2;
        if (map[mid] <= most) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

// Keeps p's levels up to k vertices (k in [q, n]), so that its finest level is its level k
// (the first k positions, the first map[k] triangles walked below k). Returns that level's
// error, which the caller adds to the node's; the collapse errors left are lowered by it
// (never below 0), so that node error + a level's error is still that level's error against
// the input: max(t, e) = t + max(0, e - t).
float truncateLevels(ProgressiveMesh& p, uint32_t k) {
    const uint32_t n = p.vertexCount();
    if (k >= n) return 0.0f;
    float t = 0.0f;
    for (uint32_t v = k; v < n; ++v) t = std::max(t, p.error[v]);
    p.triangles.resize(3 * size_t(p.map[k]));
    for (uint32_t& c : p.triangles)
        while (c >= k) c = uint32_t(p.ecol[c]);
    p.positions.resize(k);
    p.ecol.resize(k);
    p.error.resize(k);
    for (float& e : p.error) e = std::max(0.0f, e - t);
    if (!p.colours.empty()) p.colours.resize(k);
    if (!p.normals.empty()) p.normals.resize(k);
    p.map.resize(size_t(k) + 1);
    p.q = std::min(p.q, k);
    return t;
}

// errors[k] for k <= top: offset plus scale times the largest collapse error the level with k
// vertices has undone (those of vertices k .. n - 1; 0 at full detail).
std::vector<float> levelErrors(std::span<const float> error, uint32_t top, float offset, float scale) {
    std::vector<float> out(size_t(top) + 1);
    float e = 0.0f;
    for (size_t v = error.size(); v-- > top;) e = std::max(e, error[v]);
    out[top] = offset + scale * e;
    for (uint32_t k = top; k-- > 0;) {
        e = std::max(e, error[k]);
        out[k] = offset + scale * e;
    }
    return out;
}

}  // namespace

ChildLevelChoice chooseChildLevels(std::span<const std::span<const float>> errors,
                                   std::span<const std::span<const uint32_t>> maps, std::span<const uint32_t> q,
                                   uint64_t budget) {
    const size_t count = errors.size();
    const auto within = [&](size_t c, float e) {
        const uint32_t top = uint32_t(errors[c].size() - 1);
        uint32_t lo = std::min(q[c], top), hi = top;
        while (lo < hi) {
            const uint32_t mid = lo + (hi - lo) / 2;
            if (errors[c][mid] <= e) hi = mid;
            else lo = mid + 1;
        }
        return lo;
    };
    const auto total = [&](float e) {
        uint64_t t = 0;
        for (size_t c = 0; c < count; ++c) t += maps[c][within(c, e)];
        return t;
    };
    // Every error a child's level has is a candidate for E; the least whose levels fit wins,
    // the largest (every child at its coarsest) where none fits.
    std::vector<float> candidates;
    float least = 0.0f;  // below it some child cannot go
    for (size_t c = 0; c < count; ++c) {
        const uint32_t top = uint32_t(errors[c].size() - 1);
        least = std::max(least, errors[c][top]);
        for (uint32_t k = std::min(q[c], top); k <= top; ++k) candidates.push_back(errors[c][k]);
    }
    std::sort(candidates.begin(), candidates.end());
    candidates.erase(std::unique(candidates.begin(), candidates.end()), candidates.end());
    candidates.erase(candidates.begin(), std::lower_bound(candidates.begin(), candidates.end(), least));
    size_t lo = 0, hi = candidates.empty() ? 0 : candidates.size() - 1;
    while (lo < hi) {
        const size_t mid = lo + (hi - lo) / 2;
        if (total(candidates[mid]) <= budget) hi = mid;
        else lo = mid + 1;
    }
    const float e = candidates.empty() ? least : candidates[lo];
    ChildLevelChoice choice;
    for (size_t c = 0; c < count; ++c) choice.levels.push_back(within(c, e));
    for (size_t c = 0; c < count; ++c) {
        choice.error = std::max(choice.error, errors[c][choice.levels[c]]);
        choice.triangles += maps[c][choice.levels[c]];
    }
    return choice;
}

void buildHlods(const OssFile& file, ObjectHierarchy& h, const HlodOptions& options,
                const std::function<uint32_t(ProgressiveMesh&&)>& add_mesh, HlodProgress* progress) {
    const auto objects = file.objects();
    const size_t count = h.nodes.size();
    std::vector<uint32_t> parent(count, UINT32_MAX);
    std::vector<uint32_t> level_first(h.levels + 1, uint32_t(count));
    for (uint32_t n = uint32_t(count); n-- > 0;) {
        const SceneNode& node = h.nodes[n];
        level_first[node.depth] = n;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) parent[c] = n;
    }
    // What child c of node n contributes to n's merged input: its share of twice
    // node_triangles, and (reduced input) at most 1 / reduction of its subtree, so that HLODs
    // stay a fraction of the scene however small its objects. With fine input the share is
    // not cut by the reduction: the HLOD is simplified from the finer levels and only its
    // levels up to 1 / reduction of its subtree are kept (truncateLevels).
    const auto wanted = [&](uint32_t n, uint32_t c) {
        const uint64_t share = 2ull * options.node_triangles / std::max(1u, h.nodes[n].child_count);
        const uint64_t cap = options.fine_input ? h.nodes[c].triangles : h.nodes[c].triangles / std::max(1u, options.reduction);
        return std::max<uint64_t>(1, std::min<uint64_t>(share, cap));
    };
    if (progress) {
        progress->total = 0;
        for (const SceneNode& node : h.nodes) progress->total += node.child_count > 0;
    }
    // The order HLODs are built in: subtree by subtree (issue 34, item 3), so that what a
    // finished subtree hands its parent is all that is kept of it. The nodes of the deepest
    // level whose levels above have at most kChunks nodes root the subtrees; each is built bottom-up, a level of
    // it at a time (a pass: built in parallel), then the levels above them. A level-by-level
    // build over the whole tree kept every node's level for its parent at once: 1.6 GB at the
    // Boeing's size.
    constexpr uint32_t kChunks = 4096;
    uint32_t chunk_depth = 0;  // the deepest level with no level above it (or itself) over kChunks nodes
    while (chunk_depth + 1 < h.levels && level_first[chunk_depth + 2] - level_first[chunk_depth + 1] <= kChunks) ++chunk_depth;
    std::vector<uint32_t> order;               // inner nodes in build order
    std::vector<size_t> pass_first{0};         // passes: order[pass_first[i], pass_first[i + 1])
    // Consecutive subtree roots are built together until they hold kGroupInner inner nodes, so
    // that a pass (a level of the group) has enough nodes to keep every thread busy: the 10^5
    // plant's 4 096 subtrees hold 7 inner nodes each, and a pass of one subtree's level was one
    // or two nodes, built on one core.
    constexpr uint64_t kGroupInner = 512;
    std::vector<uint32_t> subtree_inner(count, 0);
    for (uint32_t n = uint32_t(count); n-- > 0;)
        if (h.nodes[n].child_count > 0) {
            subtree_inner[n] = 1;
            for (uint32_t c = h.nodes[n].first_child; c < h.nodes[n].first_child + h.nodes[n].child_count; ++c)
                subtree_inner[n] += subtree_inner[c];
        }
    for (uint32_t r = level_first[chunk_depth], r_end = r; r < level_first[chunk_depth + 1]; r = r_end) {
        uint64_t group_inner = 0;
        while (r_end < level_first[chunk_depth + 1] && (r_end == r || group_inner < kGroupInner))
            group_inner += subtree_inner[r_end++];
        // The group's nodes at each depth are a contiguous range of ids (breadth-first).
        std::vector<std::pair<uint32_t, uint32_t>> ranges{{r, r_end}};
        while (true) {
            const auto [b, e] = ranges.back();
            uint32_t cb = UINT32_MAX, ce = 0;
            for (uint32_t n = b; n < e; ++n)
                if (h.nodes[n].child_count > 0)
                    cb = std::min(cb, h.nodes[n].first_child), ce = std::max(ce, h.nodes[n].first_child + h.nodes[n].child_count);
            if (cb == UINT32_MAX) break;
            ranges.push_back({cb, ce});
        }
        for (size_t d = ranges.size(); d-- > 0;) {
            for (uint32_t n = ranges[d].first; n < ranges[d].second; ++n)
                if (h.nodes[n].child_count > 0) order.push_back(n);
            if (order.size() > pass_first.back()) pass_first.push_back(order.size());
        }
    }
    for (uint32_t d = chunk_depth; d-- > 0;) {
        for (uint32_t n = level_first[d]; n < level_first[d + 1]; ++n)
            if (h.nodes[n].child_count > 0) order.push_back(n);
        if (order.size() > pass_first.back()) pass_first.push_back(order.size());
    }

    // Subtrees that repeat take their representative's HLOD (matched in build order, so that a
    // representative is built before its repeats); the representatives whose progressive mesh a
    // repeat's parent merges from keep it until the last such parent is built.
    SubtreeRepeats repeats;
    if (options.share_repeats) {
        // A leaf's class is its mesh in its colour: an HLOD carries its objects' colours, so
        // copies in other colours are not repeats.
        std::vector<uint32_t> object_class(objects.size());
        std::vector<glm::mat4> object_world(objects.size());
        std::map<std::tuple<uint32_t, float, float, float, float>, uint32_t> classes;
        for (size_t o = 0; o < objects.size(); ++o) {
            const float* c = objects[o].color;
            object_class[o] = classes.try_emplace({objects[o].mesh, c[0], c[1], c[2], c[3]}, uint32_t(classes.size())).first->second;
            std::memcpy(&object_world[o], objects[o].world, sizeof(glm::mat4));
        }
        repeats = findRepeatedSubtrees(h.nodes, object_class, object_world, order);
    } else {
        repeats.index.assign(count, UINT32_MAX);
    }
    const auto repeat = [&](uint32_t n) { return repeats.index[n] != UINT32_MAX; };
    std::vector<uint32_t> pm_uses(count, 0);
    for (uint32_t n = 0; n < count; ++n)
        if (repeat(n) && h.nodes[n].child_count > 0 && parent[n] != UINT32_MAX && !repeat(parent[n]))
            ++pm_uses[repeats.of(n)];
    std::unordered_map<uint32_t, ProgressiveMesh> retained;

    // What a built node hands its parent, until the parent is built. Entries are made before a
    // pass's parallel builds (which then write distinct entries) and erased after its parents'.
    std::unordered_map<uint32_t, KeptMesh> kept;
    // The finest level child c may give node n: child_cap times its share.
    const auto topLevel = [&](std::span<const uint32_t> map, uint32_t q, uint32_t n, uint32_t c) {
        return levelWithTriangles(map, q, std::max<uint64_t>(1, options.child_cap) * wanted(n, c));
    };
    // Node n hands its parent its progressive mesh p (placed by world) up to the finest level the
    // parent may take, each level's error n's own plus what the level gives up (scaled with the
    // placement).
    const auto handUp = [&](uint32_t n, const ProgressiveMesh& p, const glm::mat4& world, float error, float scale) {
        KeptMesh& k = kept.find(n)->second;
        const uint32_t top = topLevel(p.map, p.q, parent[n], n);
        k.positions.resize(top);
        for (uint32_t v = 0; v < top; ++v) k.positions[v] = glm::vec3(world * glm::vec4(p.positions[v], 1.0f));
        if (p.colours.empty()) k.colours.assign(top, oss::kWhite);
        else k.colours.assign(p.colours.begin(), p.colours.begin() + top);
        k.ecol.assign(p.ecol.begin(), p.ecol.begin() + top);
        k.triangles.resize(3 * size_t(p.map[top]));
        for (size_t i = 0; i < k.triangles.size(); ++i) {
            uint32_t c = p.triangles[i];
            while (c >= top) c = uint32_t(p.ecol[c]);
            k.triangles[i] = c;
        }
        k.map.assign(p.map.begin(), p.map.begin() + top + 1);
        k.error = levelErrors(p.error, top, error, scale);
        k.q = std::min(p.q, top);
    };
    const unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    tbb::task_arena arena{int(threads)};
    const size_t batch = 64 * size_t(threads);
    std::vector<uint32_t> inner, repeated;
    std::vector<ProgressiveMesh> built;
    size_t batches = 0;
    for (size_t pass = 0; pass + 1 < pass_first.size(); ++pass) {
        inner.clear();
        repeated.clear();
        for (size_t i = pass_first[pass]; i < pass_first[pass + 1]; ++i)
            (repeat(order[i]) ? repeated : inner).push_back(order[i]);
        for (const uint32_t n : inner)
            if (parent[n] != UINT32_MAX) kept[n];
        for (size_t b = 0; b < inner.size(); b += batch) {
            const size_t e = std::min(inner.size(), b + batch);
            built.assign(e - b, ProgressiveMesh{});
            arena.execute([&] {
                tbb::parallel_for(size_t(b), e, [&](size_t j) {
                    const uint32_t n = inner[j];
                    const SceneNode& node = h.nodes[n];
                    // Each child's candidate levels: an object's own progressive mesh, an inner
                    // child's what it handed up.
                    const uint32_t children = node.child_count;
                    std::vector<std::vector<float>> leaf_errors(children);
                    std::vector<std::span<const float>> errors(children);
                    std::vector<std::span<const uint32_t>> maps(children);
                    std::vector<uint32_t> floors(children);
                    // Where each child's levels come from, for the merge once they are chosen.
                    struct Source {
                        std::span<const glm::vec3> positions;
                        std::span<const uint32_t> colours;  // per vertex, times the tint
                        glm::vec4 tint{1.0f};               // a leaf's object colour (linear)
                        std::span<const int32_t> ecol;
                        std::span<const uint32_t> triangles;
                        glm::mat4 world{1.0f};
                        KeptMesh* kept = nullptr;  // an inner child's, dropped once merged
                    };
                    std::vector<Source> sources(children);
                    uint64_t budget = 0;
                    for (uint32_t i = 0; i < children; ++i) {
                        const uint32_t c = node.first_child + i;
                        const SceneNode& child = h.nodes[c];
                        budget += wanted(n, c);
                        if (child.child_count == 0) {
                            const oss::ObjectDisk& o = objects[child.object];
                            const OssFile::MeshView m = file.mesh(o.mesh);
                            glm::mat4 world;
                            std::memcpy(&world, o.world, sizeof world);
                            const float scale = std::max({glm::length(glm::vec3(world[0])), glm::length(glm::vec3(world[1])),
                                                          glm::length(glm::vec3(world[2]))});
                            leaf_errors[i] = levelErrors(m.error, topLevel(m.map, m.q, n, c), 0.0f, scale);
                            errors[i] = leaf_errors[i];
                            maps[i] = m.map;
                            floors[i] = m.q;
                            sources[i] = {m.positions, m.colours, glm::make_vec4(o.color), m.ecol, m.triangles, world, nullptr};
                        } else {
                            KeptMesh& k = kept.find(c)->second;  // made by the child's pass
                            errors[i] = k.error;
                            maps[i] = k.map;
                            floors[i] = k.q;
                            sources[i] = {k.positions, k.colours, glm::vec4(1.0f), k.ecol, k.triangles, glm::mat4(1.0f), &k};
                        }
                    }
                    const ChildLevelChoice choice = chooseChildLevels(errors, maps, floors, budget);
                    Mesh merged;
                    std::vector<uint32_t> merged_colours;  // per merged vertex: what it shows
                    for (uint32_t i = 0; i < children; ++i) {
                        const Source& from = sources[i];
                        appendLevel(from.positions, from.ecol, from.triangles, maps[i], choice.levels[i], from.world,
                                    merged.positions, merged.indices);
                        // The level's vertices are the first choice.levels[i] of the child's.
                        for (uint32_t v = 0; v < choice.levels[i]; ++v)
                            merged_colours.push_back(tintedColour(from.tint, from.colours[v]));
                        if (from.kept) *from.kept = KeptMesh{};
                    }
                    float error = choice.error;
                    ProgressiveMesh& p = built[j - b];
                    if (options.cluster) {
                        ClusterOptions cluster;
                        cluster.place = options.place;
                        cluster.place_edges = options.place_edges;
                        cluster.colour_borders = options.colour_borders;
                        p = buildClusteredProgressiveMesh(merged, merged_colours, cluster);
                    } else {
                        p = buildProgressiveMesh(merged, Collapser::Fast, merged_colours);
                    }
                    // The levels kept: with fine input up to 1 / reduction of the subtree.
                    const uint32_t keep = options.fine_input
                        ? levelWithAtMost(p.map, p.q, std::max<uint64_t>(1, node.triangles / std::max(1u, options.reduction)))
                        : p.vertexCount();
                    if (options.normals) p.normals = hlodVertexNormals(p, 0.8f, keep);
                    if (options.fine_input) error += truncateLevels(p, keep);
                    h.nodes[n].error = error;
                    if (parent[n] != UINT32_MAX) handUp(n, p, glm::mat4(1.0f), error, 1.0f);
                    if (progress) ++progress->done;
                });
            });
            for (size_t j = b; j < e; ++j) {
                if (pm_uses[inner[j]] > 0) retained.emplace(inner[j], built[j - b]);
                h.nodes[inner[j]].mesh = add_mesh(std::move(built[j - b]));
            }
            // What the batches read of the objects' meshes is not kept mapped (OssFile::releasePages).
            if (++batches % 256 == 0) file.releasePages();
        }
        // The repeats of this pass: their representatives are built (earlier in the order).
        for (const uint32_t n : repeated) {
            const SubtreeRepeats::Repeat& rep = *repeats.find(n);
            const uint32_t r = rep.of;
            SceneNode& node = h.nodes[n];
            const float scale = rep.scale;
            node.mesh = h.nodes[r].mesh;
            node.world = rep.motion;
            // The placements matched within a slack: counted as error.
            node.error = scale * h.nodes[r].error + rep.slack;
            if (parent[n] != UINT32_MAX && !repeat(parent[n])) {
                kept.try_emplace(n);
                handUp(n, retained.at(r), node.world, node.error, scale);
                if (--pm_uses[r] == 0) retained.erase(r);
            }
            if (progress) ++progress->done;
        }
        // The children's levels are merged: dropped.
        for (const uint32_t n : inner)
            for (uint32_t c = h.nodes[n].first_child; c < h.nodes[n].first_child + h.nodes[n].child_count; ++c)
                kept.erase(c);
    }
    file.releasePages();
}

ObjectHierarchy buildObjectHierarchy(const OssFile& file, uint32_t fanout) {
    std::vector<k::Aabb> boxes;
    std::vector<uint64_t> triangles;
    boxes.reserve(file.objectCount());
    triangles.reserve(file.objectCount());
    for (const oss::ObjectDisk& o : file.objects()) {
        boxes.push_back({glm::make_vec3(o.aabb_min), glm::make_vec3(o.aabb_max)});
        triangles.push_back(file.meshRecords()[o.mesh].triangle_count);
    }
    return buildObjectHierarchy(boxes, triangles, fanout);
}

ObjectHierarchy writeWithHierarchy(const OssFile& file, const std::string& path, uint32_t fanout,
                                   const HlodOptions& options, HlodProgress* progress, OssFile::HlodCounts* counts) {
    ObjectHierarchy h = buildObjectHierarchy(file, fanout);
    OssStreamWriter writer(path);
    // The flat scene's meshes come first, as they are: the kernel copies their bytes from the
    // flat file when the writer finishes (they are hashed here, a chunk of pages at a time).
    writer.addMeshesOf(file);
    OssFile::HlodCounts c;  // every HLOD built is some inner node's mesh
    buildHlods(
        file, h, options,
        [&writer, &c](ProgressiveMesh&& p) {
            ++c.meshes;
            c.triangles += p.triangleCount();
            return writer.addMesh(p);
        },
        progress);
    for (const SceneNode& n : h.nodes) c.inner += n.child_count > 0;
    if (counts) *counts = c;
    std::vector<ObjectRecord> objects;
    objects.reserve(file.objectCount());
    for (const oss::ObjectDisk& d : file.objects()) objects.push_back(oss::fromDisk(d));
    writer.finish(objects, file.cos(), file.ct(), h.nodes);
    return h;
}

}  // namespace occ
