// SPDX-License-Identifier: MIT
#pragma once

#include "pipeline/pipeline.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <string>

namespace occ::render {

// No window could be opened (a SystemError, exit status 1).
class WindowUnavailable : public SystemError {
public:
    using SystemError::SystemError;
};

struct WindowOptions {
    uint32_t width = 512, height = 512;  // the pipeline's viewport; the window may be resized
    std::string path;                    // camera path played first (empty: start outside the scene)
    std::string out = ".";               // folder for screenshots (P) and recorded paths (R)
};

// Opens a GLFW window (OpenGL 4.5 core) and renders `file` interactively until Escape or the
// window is closed. Keys: mouse drag with the left button = look around; W/A/S/D = move, Q/E =
// down/up, scroll = speed; 1/2/3 = mode full / lod / oc+lod; F = freeze culling (fly around the
// frozen frame: occlusion-culled objects as red boxes, its occluders purple); R = start / stop
// recording the camera (stop writes OUT/recorded_N.cam); P = screenshot OUT/screenshot_N.png.
// The title bar shows fps, visible objects and triangles. Each action is also printed on
// stdout, one line each. Throws WindowUnavailable when no window can be opened (no X display,
// no GLX). Returns the exit status.
int runWindow(const OssFile& file, const PipelineOptions& options, const WindowOptions& window);

}  // namespace occ::render
