// SPDX-License-Identifier: MIT
#include "cut_refine.h"

#include "box_projection.h"
#include "device_access.h"
#include "for_each_index.h"
#include "scan.h"

#include <thrust/transform.h>

#include <cmath>

namespace occ::k {

namespace {

// CutRule as a kernel reads it.
struct CutRuleRaw {
    uint32_t kind;
    float tau, pet, draw_cost, fine_share, pixels_at_1;
    const float* lod_error;
    const float* scale;
    const uint64_t* map_first;
    const uint32_t* maps;
};

struct DecideCutNode {
    const ObjectInfo* objects;
    const CutNode* nodes;
    const uint32_t* ids;
    Camera camera;
    CutRuleRaw rule;
    const uint8_t* occluded;
    const float* share;
    uint8_t* state;
    double* cost;
    uint8_t* level_state;

    // The error rule: triangles of the item's coarsest level that gives up at most `allowed`
    // world units (the level k::lodSelectByError chooses).
    OCC_HD uint32_t triangles(uint32_t id, const ObjectInfo& o, float allowed) const {
        if (o.vertex_count == 0) return 0;
        const uint64_t first = rule.map_first[o.mesh];
        const float scale = rule.scale[id] > 1e-30f ? rule.scale[id] : 1e-30f;
        return rule.maps[first + levelWithinError(rule.lod_error + first, o.q, o.vertex_count, allowed / scale)];
    }

    OCC_HD void operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        uint8_t result;
        if (occluded && occluded[j]) {
            result = kCutHidden;
            if (cost) cost[id] = 0.0;
        } else {
            const CutNode node = nodes[id];
            const ObjectInfo o = objects[id];
            const float s = share ? share[j] : 1.0f;
            if (rule.kind == CutRule::kLeaves) {
                result = node.child_count == 0 ? kCutStop : kCutRefined;
            } else if (rule.kind == CutRule::kOwnError) {
                const glm::vec3 nearest = glm::clamp(camera.eye, o.aabb.min, o.aabb.max);
                const float distance = fmaxf(glm::length(nearest - camera.eye), camera.near_plane);
                result = node.child_count == 0 || node.error * s * rule.pixels_at_1 / distance <= rule.tau ? kCutStop
                                                                                                          : kCutRefined;
            } else {
                const Projection pr = projectBox(o, camera);
                if (pr.area < rule.pet) {
                    cost[id] = 0.0;  // under the pixel threshold: not drawn
                    result = kCutStop;
                } else {
                    const float allowed = rule.tau * pr.depth / (rule.pixels_at_1 * fmaxf(s, 1e-30f));
                    cost[id] = node.error < allowed ? double(triangles(id, o, allowed - node.error)) + rule.draw_cost
                                                    : double(INFINITY);
                    result = node.child_count == 0 || node.error <= rule.fine_share * allowed ? kCutStop : kCutRefined;
                }
            }
        }
        state[id] = result;
        level_state[j] = result;
    }
};

// The children of listed node j that Take accepts: take.node(j) for the node as a whole, then
// take.child(c) for each child c. Counted first, then written after the scan's offset, in order.
template <class Take>
struct CountChildren {
    const CutNode* nodes;
    const uint32_t* ids;
    Take take;
    OCC_HD uint32_t operator()(uint32_t j) const {
        if (!take.node(j)) return 0u;
        const CutNode node = nodes[ids[j]];
        uint32_t n = 0;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) n += take.child(c) ? 1u : 0u;
        return n;
    }
};

template <class Take>
struct WriteChildren {
    const CutNode* nodes;
    const uint32_t* ids;
    Take take;
    const uint64_t* offsets;
    uint32_t* out;
    OCC_HD void operator()(uint32_t j) const {
        if (!take.node(j)) return;
        const CutNode node = nodes[ids[j]];
        uint32_t* to = out + offsets[j];
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
            if (take.child(c)) *to++ = c;
    }
};

// Every child of a node refined this level.
struct RefinedNodes {
    const uint8_t* level_state;
    OCC_HD bool node(uint32_t j) const { return level_state[j] == kCutRefined; }
    OCC_HD bool child(uint32_t) const { return true; }
};

// The leaves among any listed node's children (an inner node's; a leaf has none).
struct LeafChildren {
    const CutNode* nodes;
    OCC_HD bool node(uint32_t) const { return true; }
    OCC_HD bool child(uint32_t c) const { return nodes[c].child_count == 0; }
};

// The children Take accepts: counted into counts and scanned into offsets (returns the total),
// then written after their node's offset.
template <class Take>
uint64_t countChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count, const Take& take,
                       DevicePtr<uint32_t> counts, DevicePtr<uint64_t> offsets) {
    const thrust::counting_iterator<uint32_t> first(0);
    withPolicy(count, [&](auto policy) {
        thrust::transform(policy, first, first + count, raw(counts), CountChildren<Take>{raw(nodes), raw(ids), take});
    });
    return exclusiveScan(counts, count, offsets);
}

template <class Take>
void writeChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count, const Take& take,
                   DevicePtr<const uint64_t> offsets, DevicePtr<uint32_t> out) {
    forEachIndex(count, WriteChildren<Take>{raw(nodes), raw(ids), take, raw(offsets), raw(out)});
}

struct CoarsenNode {
    const CutNode* nodes;
    const uint32_t* ids;
    const uint8_t* in_frustum;
    uint8_t* state;
    double* cost;
    OCC_HD void operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        if (state[id] != kCutRefined) return;
        const CutNode node = nodes[id];
        double children = 0.0;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
            if (in_frustum[c]) children += cost[c];
        if (cost[id] <= children) state[id] = kCutMerged;
        else cost[id] = children;
    }
};

struct GatherNode {
    const CutNode* nodes;
    const uint32_t* ids;
    const uint8_t* state;
    uint8_t* covered;
    uint8_t* flags;
    OCC_HD void operator()(uint32_t j) const {
        const uint32_t id = ids[j];
        const uint8_t s = state[id];
        const bool cov = covered[id] != 0;
        flags[j] = !cov && (s == kCutStop || s == kCutMerged) ? 1 : 0;
        if (s != kCutRefined && s != kCutMerged) return;
        const CutNode node = nodes[id];
        const uint8_t below = cov || s == kCutMerged ? 1 : 0;
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) covered[c] = below;
    }
};

}  // namespace

void cutDecide(DevicePtr<const ObjectInfo> objects, DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids,
               uint32_t count, const Camera& camera, const CutRule& rule, DevicePtr<const uint8_t> occluded,
               DevicePtr<const float> share, DevicePtr<uint8_t> state, DevicePtr<double> cost,
               DevicePtr<uint8_t> level_state) {
    if (count == 0) return;
    const CutRuleRaw r{rule.kind,           rule.tau,        rule.pet,            rule.draw_cost, rule.fine_share,
                       rule.pixels_at_1,    raw(rule.lod_error), raw(rule.scale), raw(rule.map_first), raw(rule.maps)};
    forEachIndex(count, DecideCutNode{raw(objects), raw(nodes), raw(ids), camera, r, raw(occluded), raw(share),
                                      raw(state), raw(cost), raw(level_state)});
}

uint32_t cutChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> level_state,
                     uint32_t count, DevicePtr<uint32_t> counts, DevicePtr<uint64_t> offsets, DevicePtr<uint32_t> out) {
    if (count == 0) return 0;
    const RefinedNodes take{raw(level_state)};
    const uint64_t total = countChildren(nodes, ids, count, take, counts, offsets);
    writeChildren(nodes, ids, count, take, offsets, out);
    return uint32_t(total);
}

uint32_t cutLeafChildren(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
                         DevicePtr<uint32_t> counts, DevicePtr<uint64_t> offsets, DeviceArray<uint32_t>& out) {
    if (count == 0) return 0;
    const LeafChildren take{raw(nodes)};
    const uint64_t total = countChildren(nodes, ids, count, take, counts, offsets);
    out.growTo(std::max<uint64_t>(1, total));
    writeChildren(nodes, ids, count, take, offsets, out.ptr());
    return uint32_t(total);
}

void cutCoarsen(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
                DevicePtr<const uint8_t> in_frustum, DevicePtr<uint8_t> state, DevicePtr<double> cost) {
    if (count == 0) return;
    forEachIndex(count, CoarsenNode{raw(nodes), raw(ids), raw(in_frustum), raw(state), raw(cost)});
}

void cutGather(DevicePtr<const CutNode> nodes, DevicePtr<const uint32_t> ids, uint32_t count,
               DevicePtr<const uint8_t> state, DevicePtr<uint8_t> covered, DevicePtr<uint8_t> flags) {
    if (count == 0) return;
    forEachIndex(count, GatherNode{raw(nodes), raw(ids), raw(state), raw(covered), raw(flags)});
}

}  // namespace occ::k
