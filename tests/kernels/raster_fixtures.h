// SPDX-License-Identifier: MIT
#pragma once

// Cameras and triangle soups that the raster tests (test_depth_raster.cpp,
// test_masked_raster.cpp) build their fixtures from.
#include "kernel_types.h"

#include <glm/gtc/matrix_transform.hpp>

#include <cstdint>
#include <vector>

namespace occ::k::test {

// view_proj = identity: world coordinates are NDC, so tests can place corners in window space.
inline Camera identityCamera(uint32_t width, uint32_t height) {
    Camera c{};
    c.view_proj = glm::mat4(1.0f);
    c.near_plane = 1.0f;
    c.far_plane = 2.0f;
    c.forward = glm::vec3(0, 0, -1);
    c.width = width;
    c.height = height;
    return c;
}

// Eye at the origin looking down -z.
inline Camera perspectiveCamera(uint32_t width, uint32_t height, float near_plane = 0.5f, float far_plane = 100.0f) {
    Camera c{};
    c.fovy = glm::radians(60.0f);
    c.view_proj = glm::perspective(c.fovy, float(width) / float(height), near_plane, far_plane);
    c.near_plane = near_plane;
    c.far_plane = far_plane;
    c.forward = glm::vec3(0, 0, -1);
    c.width = width;
    c.height = height;
    return c;
}

// World point that the identity camera puts at window (x, y) with window depth d.
inline glm::vec3 atWindow(const Camera& c, float x, float y, float d) {
    return glm::vec3(x / float(c.width) * 2.0f - 1.0f, y / float(c.height) * 2.0f - 1.0f, d * 2.0f - 1.0f);
}

struct Mesh {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;

    // A triangle of its own three corners: it shares no edge.
    void add(glm::vec3 a, glm::vec3 b, glm::vec3 c) {
        const uint32_t first = uint32_t(positions.size());
        positions.insert(positions.end(), {a, b, c});
        triangles.insert(triangles.end(), {first, first + 1, first + 2});
    }
    uint32_t triangleCount() const { return uint32_t(triangles.size() / 3); }
};

}  // namespace occ::k::test
