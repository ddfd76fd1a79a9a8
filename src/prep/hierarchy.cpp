// SPDX-License-Identifier: MIT
#include "prep/hierarchy.h"

#include "prep/prepare.h"

#include <algorithm>
#include <cstring>
#include <numeric>
#include <stdexcept>

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

    // Cuts order[b, e) into `parts` groups of about equal size; appends the groups' bounds.
    std::vector<std::pair<size_t, size_t>> groups;
    const auto cut = [&](auto&& self, size_t b, size_t e, uint32_t parts) -> void {
        if (parts <= 1 || e - b <= 1) {
            groups.emplace_back(b, e);
            return;
        }
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (size_t j = b; j < e; ++j) lo = glm::min(lo, centre(order[j])), hi = glm::max(hi, centre(order[j]));
        const glm::vec3 extent = hi - lo;
        const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : extent.y >= extent.z ? 1 : 2;
        const uint32_t left = parts / 2;
        const size_t mid = b + (e - b) * left / parts;
        std::nth_element(order.begin() + std::ptrdiff_t(b), order.begin() + std::ptrdiff_t(mid),
                         order.begin() + std::ptrdiff_t(e), [&](uint32_t x, uint32_t y) {
                             const float cx = centre(x)[axis], cy = centre(y)[axis];
                             return cx < cy || (cx == cy && x < y);
                         });
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
        HierarchyNode& node = h.nodes[n];
        node.box = {glm::vec3(INFINITY), glm::vec3(-INFINITY)};
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
            for (size_t j = r.b; j < r.e; ++j) groups.emplace_back(j, j + 1);
        } else {
            cut(cut, r.b, r.e, fanout);
        }
        const uint32_t depth = node.depth;
        h.nodes[n].first_child = uint32_t(h.nodes.size());
        h.nodes[n].child_count = uint32_t(groups.size());
        for (const auto& [b, e] : groups) {
            HierarchyNode child;
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

std::vector<ProgressiveMesh> buildHlods(const OssFile& file, const ObjectHierarchy& h, const HlodOptions& options) {
    std::vector<ProgressiveMesh> hlod(h.nodes.size());
    const auto objects = file.objects();
    // Children before parents: breadth-first order backwards.
    for (size_t n = h.nodes.size(); n-- > 0;) {
        const HierarchyNode& node = h.nodes[n];
        if (node.child_count == 0) continue;
        const uint64_t want = std::max<uint64_t>(1, 2ull * options.node_triangles / node.child_count);
        Mesh merged;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
            const HierarchyNode& child = h.nodes[c];
            if (child.child_count == 0) {
                const oss::ObjectDisk& o = objects[child.object];
                const OssFile::MeshView m = file.mesh(o.mesh);
                glm::mat4 world;
                std::memcpy(&world, o.world, sizeof world);
                appendLevel(m.positions, m.ecol, m.triangles, m.map, levelWithTriangles(m.map, m.q, want), world,
                            merged.positions, merged.indices);
            } else {
                const ProgressiveMesh& p = hlod[c];
                appendLevel(p.positions, p.ecol, p.triangles, p.map, levelWithTriangles(p.map, p.q, want),
                            glm::mat4(1.0f), merged.positions, merged.indices);
            }
        }
        hlod[n] = buildProgressiveMesh(merged, Collapser::Fast);
    }
    return hlod;
}

}  // namespace occ
