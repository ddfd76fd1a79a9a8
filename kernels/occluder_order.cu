// SPDX-License-Identifier: MIT
#include "occluder_order.h"

#include "device_access.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/sort.h>
#include <thrust/transform.h>

namespace occ::k {

namespace {

struct EyeToBox {
    const ObjectInfo* objects;
    glm::vec3 eye;
    OCC_HD float operator()(uint32_t id) const {
        const Aabb& b = objects[id].aabb;
        const glm::vec3 d = glm::max(glm::max(b.min - eye, eye - b.max), glm::vec3(0.0f));
        return d.x * d.x + d.y * d.y + d.z * d.z;
    }
};

}  // namespace

void sortFrontToBack(DevicePtr<const ObjectInfo> objects, DevicePtr<uint32_t> id_memory, uint32_t count,
                     const Camera& camera, DeviceArray<float>& key_memory) {
    if (count < 2) return;
    key_memory.growTo(count);
    uint32_t* const ids = raw(id_memory);
    float* const keys = raw(key_memory.ptr());
    thrust::transform(onDevice(), ids, ids + count, keys, EyeToBox{raw(objects), camera.eye});
    thrust::stable_sort_by_key(onDevice(), keys, keys + count, ids);
}

}  // namespace occ::k
