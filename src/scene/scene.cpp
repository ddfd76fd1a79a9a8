// SPDX-License-Identifier: MIT
#include "scene/scene.h"

#include <algorithm>
#include <execution>
#include <numeric>

namespace occ {

uint64_t Scene::triangleCount() const {
    uint64_t n = 0;
    for (const Object& o : objects) n += meshes[o.mesh].triangleCount();
    return n;
}

uint64_t Scene::vertexCount() const {
    uint64_t n = 0;
    for (const Object& o : objects) n += meshes[o.mesh].positions.size();
    return n;
}

Bounds Scene::meshBounds(uint32_t mesh) const {
    Bounds b;
    for (const glm::vec3& p : meshes[mesh].positions) b.extend(p);
    return b;
}

Bounds Scene::objectBounds(uint32_t object) const {
    const Object& o = objects[object];
    Bounds b;
    for (const glm::vec3& p : meshes[o.mesh].positions) b.extend(glm::vec3(o.world * glm::vec4(p, 1.0f)));
    return b;
}

Bounds Scene::worldBounds() const {
    std::vector<uint32_t> ids(objects.size());
    std::iota(ids.begin(), ids.end(), 0u);
    // Exact bounds need every instance's vertices transformed (10^8 for the engine grid), so the
    // objects are spread over the cores.
    return std::transform_reduce(
        std::execution::par, ids.begin(), ids.end(), Bounds{},
        [](Bounds a, const Bounds& b) {
            a.extend(b);
            return a;
        },
        [this](uint32_t id) { return objectBounds(id); });
}

}  // namespace occ
