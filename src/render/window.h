// SPDX-License-Identifier: MIT
#pragma once

#include "net/transport.h"
#include "pipeline/pipeline.h"
#include "roles/occlusion_switch.h"
#include "scene/errors.h"
#include "render/scene_renderer.h"
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
    int device = -1;                     // --device as given (-1: none): the GL context's GPU must be it
    ColourMode colours = ColourMode::Model;  // --colours
};

// Opens a GLFW window (OpenGL 4.5 core) on rank 0 and flies through `file` with the frame loop
// (roles::runRanks, live) until Escape or the window is closed: the window is the loop's camera
// source (the user's newest pose when a frame starts; poses made while the switch is busy are
// skipped, never queued: the paper's camera buffer of one) and its frame sink (the frame drawn,
// presented and the title set). Every other rank runs runRanks with `live` set. Keys: mouse drag
// with the left button = look around; W/A/S/D = move, Q/E = down/up, scroll = speed; 1/2/3 = mode
// full / lod / oc+lod (one rank only); F = freeze culling (the frozen frame from where the user
// flies: occlusion-culled objects as red boxes, with one rank its occluders purple; one rank runs
// no frames while frozen, with more the switch goes on culling the frozen camera; refused with
// 2 + P ranks); R = start / stop recording the camera (stop writes OUT/recorded_N.cam); P =
// screenshot OUT/screenshot_N.png. While a culling rank works the window keeps answering and
// shows the newest complete frame. With 2 + P ranks it shows the sort-last composite of every
// display rank's partition (the other display ranks run runRanks with a drawing that
// composites, see SortLastCompositor). The title shows fps, visible objects and, with one rank,
// triangles and the mode, with more the ranks and the latency. Each action is also printed on
// stdout, one line each. Esc ends every rank. Returns runRanks's records and fills `summary`;
// throws WindowUnavailable before any message is sent when no window can be opened (no X
// display, no GLX; the caller tells the other ranks).
std::vector<FrameRecord> runWindow(Transport& transport, const OssFile& file, const PipelineOptions& options,
                                   const WindowOptions& window, roles::RunOptions run, roles::RunSummary& summary);

}  // namespace occ::render
