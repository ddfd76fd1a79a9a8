// SPDX-License-Identifier: MIT
#pragma once

// Cameras and triangle soups that the raster tests (test_depth_raster.cpp,
// test_masked_raster.cpp) build their fixtures from.
#include "kernel_types.h"

#include <glm/gtc/matrix_transform.hpp>

#include <cmath>
#include <cstdint>
#include <random>
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

// Random triangles of every size (up to max_size across), some behind the eye, across the near
// plane or off screen.
inline Mesh randomScene(std::mt19937& rng, uint32_t triangle_count, float max_size = 40.0f) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_real_distribution<float> log_size(std::log(0.01f), std::log(max_size));
    std::uniform_real_distribution<float> distance(-2.0f, 60.0f);
    Mesh mesh;
    for (uint32_t t = 0; t < triangle_count; ++t) {
        const float z = -distance(rng);
        const glm::vec3 centre(unit(rng) * (0.7f * std::abs(z) + 1.0f), unit(rng) * (0.6f * std::abs(z) + 1.0f), z);
        const float size = std::exp(log_size(rng));
        auto corner = [&] { return centre + size * glm::vec3(unit(rng), unit(rng), unit(rng)); };
        mesh.add(corner(), corner(), corner());
    }
    return mesh;
}

}  // namespace occ::k::test
