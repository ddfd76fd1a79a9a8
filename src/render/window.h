// SPDX-License-Identifier: MIT
#pragma once

#include "net/transport.h"
#include "pipeline/pipeline.h"
#include "roles/occlusion_switch.h"
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

// The same window as rank 0 of 2 or more ranks: rank 0 is the display (RVG) of a live
// roles::runRanks, which every other rank runs with `live` set. Each frame's camera is the
// user's newest pose (a camera buffer of one: poses made while the switch is busy are skipped);
// while a culling rank works the window keeps answering and shows the newest complete frame.
// F freezes: the switch goes on culling the frozen camera and the window draws the frozen
// visible set from where the user flies (culled objects in the frustum as red boxes; the
// occluders live on the culling ranks and are not drawn). The mode keys only work with one
// rank. With 2 + P ranks the window shows the sort-last composite of every display rank's
// partition (the other display ranks run runRanks with a drawing that composites, see
// SortLastCompositor), and F is refused. The title shows fps, ranks, the latency in frames and ms, and visible objects. Esc
// ends every rank. Returns runRanks's records and fills `summary`; throws WindowUnavailable
// before any message is sent when no window can be opened (the caller tells the other ranks).
std::vector<FrameRecord> runWindowRanks(Transport& transport, const OssFile& file, const PipelineOptions& options,
                                        const WindowOptions& window, roles::RunOptions run, roles::RunSummary& summary);

}  // namespace occ::render
