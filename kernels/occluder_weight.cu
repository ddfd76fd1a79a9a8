// SPDX-License-Identifier: MIT
#include "occluder_weight.h"

#include "device_access.h"
#include "for_each_index.h"
#include "device_policy.h"

#include <algorithm>

#include <thrust/copy.h>
#include <thrust/count.h>
#include <thrust/execution_policy.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/for_each.h>
#include <thrust/sort.h>
#include <thrust/transform.h>

#include <cstring>

namespace occ::k {

namespace {

struct Eq3Weight {
    const ObjectInfo* objects;
    const uint32_t* candidates;
    const uint8_t* in_frustum;
    glm::vec3 eye;
    glm::vec3 forward;

    OCC_HD float operator()(uint32_t j) const {
        const uint32_t c = candidates[j];
        if (!in_frustum[c]) return 0.0f;
        const ObjectInfo& o = objects[c];
        const glm::vec3 extent = glm::max(o.aabb.max - o.aabb.min, glm::vec3(0.0f));
        const float volume = extent.x * extent.y * extent.z;
        if (!(volume > 0.0f)) return 0.0f;
        // Per axis, how far the eye is outside the slab of the box (0 inside it).
        const glm::vec3 outside = glm::max(glm::max(o.aabb.min - eye, eye - o.aabb.max), glm::vec3(0.0f));
        const float distance = fmaxf(glm::length(outside), 1e-3f * glm::length(extent));
        return volume * fabsf(glm::dot(o.occluder_normal, forward)) / distance;
    }
};

// Sorting these keys ascending sorts by score descending, then by object id ascending: for
// non-negative floats the IEEE bit pattern grows with the value, so its complement shrinks.
OCC_HD inline uint64_t descendingKey(float score, uint32_t id) {
    uint32_t bits;
    memcpy(&bits, &score, sizeof bits);
    return (uint64_t(~bits) << 32) | id;
}

struct TopKKey {
    const uint32_t* candidates;
    const float* weight;

    OCC_HD uint64_t operator()(uint32_t j) const { return descendingKey(weight[j], candidates[j]); }
};

struct IsPositive {
    OCC_HD bool operator()(float w) const { return w > 0.0f; }
};

struct KeyToId {
    OCC_HD uint32_t operator()(uint64_t key) const { return uint32_t(key); }
};

}  // namespace

void occluderWeight(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> cos, uint32_t cos_count,
                    DevicePtr<const uint8_t> in_frustum, const Camera& camera, DevicePtr<float> weight) {
    if (cos_count == 0) return;
    thrust::transform(onDevice(), thrust::counting_iterator<uint32_t>(0),
                      thrust::counting_iterator<uint32_t>(cos_count), raw(weight),
                      Eq3Weight{raw(objects), raw(cos), raw(in_frustum), camera.eye, camera.forward});
}

uint32_t selectTopK(DevicePtr<const uint32_t> cos, DevicePtr<const float> weight, uint32_t cos_count, uint32_t k,
                    DevicePtr<uint32_t> aos, DeviceArray<uint64_t>& keys) {
    if (cos_count == 0 || k == 0) return 0;
    keys.growTo(cos_count);
    uint64_t* const key_data = raw(keys.ptr());
    const auto first_key =
        thrust::make_transform_iterator(thrust::counting_iterator<uint32_t>(0), TopKKey{raw(cos), raw(weight)});
    uint64_t* const keys_end =
        thrust::copy_if(onDevice(), first_key, first_key + cos_count, raw(weight), key_data, IsPositive{});
    countReadback(sizeof(uint32_t));  // copy_if's count
    const auto positive = uint32_t(keys_end - key_data);
    const uint32_t chosen = positive < k ? positive : k;
#if defined(__CUDACC__)
    thrust::sort(onDevice(), key_data, keys_end);
#else
    // Only the k smallest keys are read, in order: on the CPU a partial sort finds them (the keys
    // are distinct, ids in their low bits, so these are the full sort's first k). Sorting all
    // the frustum's candidates to take 16 was a third of the occluder choice on the 10^5 orbit.
    std::partial_sort(key_data, key_data + chosen, keys_end);
#endif
    thrust::transform(onDevice(), key_data, key_data + chosen, raw(aos), KeyToId{});
    return chosen;
}

namespace {

// Ascending keys sort by score descending, then id ascending (descendingKey; out-of-frustum
// candidates get the largest key and are dropped after the sort).
struct PvsOccluderKey {
    const ObjectInfo* objects;
    const uint32_t* candidates;
    const uint8_t* in_frustum;
    glm::vec3 eye;
    float near_plane;

    OCC_HD uint64_t operator()(uint32_t j) const {
        const uint32_t id = candidates[j];
        const ObjectInfo& o = objects[id];
        // Dropped after the sort: out of the frustum, or no occluder at all (an HLOD).
        if (!in_frustum[id] || o.compactness < 0.0f) return ~uint64_t(0);
        const glm::vec3 nearest = glm::clamp(eye, o.aabb.min, o.aabb.max);
        const float length = glm::length(nearest - eye);
        const float distance = length > near_plane ? length : near_plane;
        // Screen per rastered triangle. An earlier version also weighed it by (near / D)^2, so that of two
        // occluders as large on screen the nearer one came first (it raised a 10^5 plant orbit's
        // culling then). Measured again with issue 32's late pass and kept objects, that factor
        // paid nowhere and cost the 10^8-triangle grid walk a fifth of its culling: 8 547
        // objects culled a frame with it, 10 616 without; the 10^5 plant orbit 88 882 and 91 365
        // (docs/results.md, "Where issue 32 ends").
        const float size = glm::length(o.aabb.max - o.aabb.min) / distance;
        const float triangles = float(o.triangle_count > 1 ? o.triangle_count : 1u);
        const float score = size * size * o.compactness / triangles;
        return descendingKey(score >= 0.0f ? score : 0.0f, id);  // a NaN or negative score ranks last
    }
};

struct MarkTaken {
    uint8_t* taken;
    uint8_t value;
    OCC_HD void operator()(uint32_t id) const { taken[id] = value; }
};

// The greedy pass: one thread, in rank order.
struct TakeWithinBudget {
    const ObjectInfo* objects;
    const uint64_t* keys;
    uint32_t count;
    uint8_t* taken;
    uint64_t budget;
    uint32_t* out;
    uint32_t* chosen;

    OCC_HD void operator()(uint32_t) const {
        uint64_t triangles = 0;
        uint32_t n = 0;
        for (uint32_t j = 0; j < count; ++j) {
            if (keys[j] == ~uint64_t(0)) break;
            const uint32_t id = uint32_t(keys[j]);
            if (taken[id]) continue;
            const uint64_t t = objects[id].triangle_count;
            if (triangles + t > budget) continue;
            triangles += t;
            taken[id] = 1;  // a candidate listed twice is taken once
            out[n++] = id;
        }
        for (uint32_t j = 0; j < n; ++j) taken[out[j]] = 0;
        *chosen = n;
    }
};

}  // namespace

uint32_t selectPvsOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> candidates, uint32_t count,
                            DevicePtr<const uint8_t> in_frustum, const Camera& camera,
                            DevicePtr<const uint32_t> exclude, uint32_t exclude_count, uint64_t triangle_budget,
                            PvsOccluderScratch& scratch, DevicePtr<uint32_t> out) {
    if (count == 0 || triangle_budget == 0) return 0;
    scratch.keys.growTo(count);
    if (scratch.chosen.size() < 1) scratch.chosen.resize(1);
    uint64_t* const keys = raw(scratch.keys.ptr());
    uint8_t* const taken = raw(scratch.taken.ptr());
    const thrust::counting_iterator<uint32_t> first(0);
    // A PVS is a few thousand ids: on the CPU the ranking then runs on the calling thread, and
    // the sort without the TBB sort's temporaries.
    withPolicy(count, [&](auto policy) {
        thrust::transform(policy, first, first + count, keys,
                          PvsOccluderKey{raw(objects), raw(candidates), raw(in_frustum), camera.eye, camera.near_plane});
        thrust::sort(policy, keys, keys + count);
    });
    if (exclude_count > 0)
        withPolicy(exclude_count,
                   [&](auto policy) { thrust::for_each_n(policy, raw(exclude), exclude_count, MarkTaken{taken, 1}); });
    thrust::for_each_n(onDevice(), first, 1,
                       TakeWithinBudget{raw(objects), keys, count, taken, triangle_budget, raw(out),
                                        raw(scratch.chosen.ptr())});
    if (exclude_count > 0)
        withPolicy(exclude_count,
                   [&](auto policy) { thrust::for_each_n(policy, raw(exclude), exclude_count, MarkTaken{taken, 0}); });
    return readBack(DevicePtr<const uint32_t>(scratch.chosen.ptr()));
}

namespace {

struct InFrustum {
    const uint8_t* in_frustum;
    OCC_HD bool operator()(uint32_t id) const { return in_frustum[id] != 0; }
};

}  // namespace

uint32_t countInFrustum(DevicePtr<const uint32_t> ids, uint32_t count, DevicePtr<const uint8_t> in_frustum) {
    if (count == 0) return 0;
    countReadback(sizeof(uint32_t));
    return uint32_t(withPolicy(
        count, [&](auto policy) { return thrust::count_if(policy, raw(ids), raw(ids) + count, InFrustum{raw(in_frustum)}); }));
}

}  // namespace occ::k
