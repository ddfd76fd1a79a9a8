// SPDX-License-Identifier: MIT
#include "occluder_weight.h"

#include "kernel_memory.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
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

// Sorting these ascending sorts by weight descending, then by object id ascending: for positive
// floats the IEEE bit pattern grows with the value, so its complement shrinks.
struct TopKKey {
    const uint32_t* candidates;
    const float* weight;

    OCC_HD uint64_t operator()(uint32_t j) const {
        const float w = weight[j];
        uint32_t bits;
        memcpy(&bits, &w, sizeof bits);
        return (uint64_t(~bits) << 32) | candidates[j];
    }
};

struct IsPositive {
    OCC_HD bool operator()(float w) const { return w > 0.0f; }
};

struct KeyToId {
    OCC_HD uint32_t operator()(uint64_t key) const { return uint32_t(key); }
};

}  // namespace

void occluderWeight(const ObjectInfo* objects, const uint32_t* cos, uint32_t cos_count, const uint8_t* in_frustum,
                    const Camera& camera, float* weight) {
    if (cos_count == 0) return;
    thrust::transform(thrust::device, thrust::counting_iterator<uint32_t>(0),
                      thrust::counting_iterator<uint32_t>(cos_count), weight,
                      Eq3Weight{objects, cos, in_frustum, camera.eye, camera.forward});
}

uint32_t selectTopK(const uint32_t* cos, const float* weight, uint32_t cos_count, uint32_t k, uint32_t* aos) {
    if (cos_count == 0 || k == 0) return 0;
    KernelArray<uint64_t> keys(cos_count);
    const auto first_key = thrust::make_transform_iterator(thrust::counting_iterator<uint32_t>(0), TopKKey{cos, weight});
    uint64_t* const keys_end =
        thrust::copy_if(thrust::device, first_key, first_key + cos_count, weight, keys.data(), IsPositive{});
    const auto positive = uint32_t(keys_end - keys.data());
    thrust::sort(thrust::device, keys.data(), keys_end);
    const uint32_t chosen = positive < k ? positive : k;
    thrust::transform(thrust::device, keys.data(), keys.data() + chosen, aos, KeyToId{});
    return chosen;
}

}  // namespace occ::k
