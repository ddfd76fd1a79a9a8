// SPDX-License-Identifier: MIT
#include "view/camera.h"

#include <glm/gtc/matrix_transform.hpp>

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace occ {

namespace {

bool finite(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

// Shortest text that reads back as x, for messages ("180", not "180.000000").
std::string str(float x) {
    char text[32];
    return std::string(text, std::to_chars(text, text + sizeof(text), x).ptr);
}

}  // namespace

std::string poseDefect(const CameraPose& p) {
    if (!finite(p.eye)) return "eye is not finite";
    if (!finite(p.target)) return "target is not finite";
    if (!finite(p.up)) return "up is not finite";
    if (!std::isfinite(p.fovy_degrees) || !std::isfinite(p.near_plane) || !std::isfinite(p.far_plane))
        return "fovy, near or far is not finite";
    if (!(p.fovy_degrees > 0.0f && p.fovy_degrees < 180.0f))
        return "fovy_degrees = " + str(p.fovy_degrees) + " is outside (0, 180)";
    if (!(p.near_plane > 0.0f)) return "near = " + str(p.near_plane) + " is not positive";
    if (!(p.near_plane < p.far_plane))
        return "near = " + str(p.near_plane) + " is not below far = " + str(p.far_plane);
    const glm::dvec3 view = glm::dvec3(p.target) - glm::dvec3(p.eye), up(p.up);
    if (view == glm::dvec3(0.0)) return "eye equals target";
    if (up == glm::dvec3(0.0)) return "up is the zero vector";
    // Relative to the lengths, so that the verdict does not depend on the scene's units. Below
    // this glm::lookAt's basis loses most of its bits.
    const double sine = glm::length(glm::cross(view, up)) / (glm::length(view) * glm::length(up));
    if (!(sine > 1e-6)) return "up is parallel to the view direction";
    return {};
}

glm::mat4 viewMatrix(const CameraPose& pose) { return glm::lookAtRH(pose.eye, pose.target, pose.up); }

glm::mat4 projectionMatrix(const CameraPose& pose, uint32_t width, uint32_t height) {
    if (width == 0 || height == 0) throw std::invalid_argument("projectionMatrix: the viewport has no pixels");
    // The _NO variant whatever GLM_FORCE_DEPTH_ZERO_TO_ONE says: the kernels assume clip z in [-w, w].
    return glm::perspectiveRH_NO(glm::radians(pose.fovy_degrees), float(width) / float(height), pose.near_plane,
                                 pose.far_plane);
}

k::Camera toKernelCamera(const CameraPose& pose, uint32_t width, uint32_t height) {
    k::Camera camera{};
    camera.view_proj = projectionMatrix(pose, width, height) * viewMatrix(pose);
    camera.eye = pose.eye;
    camera.near_plane = pose.near_plane;
    camera.forward = glm::normalize(pose.target - pose.eye);
    camera.far_plane = pose.far_plane;
    camera.width = width;
    camera.height = height;
    camera.fovy = glm::radians(pose.fovy_degrees);
    camera.pad = 0.0f;
    return camera;
}

}  // namespace occ
