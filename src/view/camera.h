// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_types.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <string>

namespace occ {

// One camera as a path file stores it (docs: src/view/camera_path.h). World space, OpenGL
// conventions: right-handed, the view looks from eye towards target with up roughly up.
struct CameraPose {
    glm::vec3 eye{0.0f};
    glm::vec3 target{0.0f, 0.0f, -1.0f};
    glm::vec3 up{0.0f, 1.0f, 0.0f};
    float fovy_degrees = 60.0f;  // vertical field of view, in (0, 180)
    float near_plane = 0.1f;     // 0 < near_plane < far_plane
    float far_plane = 1000.0f;
};

// Why `pose` cannot be rendered, or "" when it can: every number finite, fovy in (0, 180),
// 0 < near < far, eye != target, up neither zero nor parallel to target - eye (computed in
// double, so that huge finite coordinates do not overflow into a false verdict).
std::string poseDefect(const CameraPose& pose);

// World to view space (glm::lookAt, right-handed: the view looks down -z).
glm::mat4 viewMatrix(const CameraPose& pose);

// View to clip space (glm::perspective, right-handed, clip z in [-w, w] so window depth is in
// [0, 1] after the usual viewport transform), aspect = width / height. Throws
// std::invalid_argument if width or height is 0.
glm::mat4 projectionMatrix(const CameraPose& pose, uint32_t width, uint32_t height);

// Everything the kernels read about a frame's camera: view_proj = projection * view, eye,
// forward = normalize(target - eye), near/far, viewport, fovy in radians, pad = 0. Throws
// std::invalid_argument if width or height is 0.
k::Camera toKernelCamera(const CameraPose& pose, uint32_t width, uint32_t height);

}  // namespace occ
