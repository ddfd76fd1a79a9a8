// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_types.h"
#include "view/camera.h"

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

namespace occ {

class OssFile;

// ---- The path file ----------------------------------------------------------------------------
//
// Text, so that people can write and edit paths by hand. The first line is kCameraPathHeader;
// then one camera per line: 12 numbers separated by spaces or tabs,
//     eye.x eye.y eye.z target.x target.y target.z up.x up.y up.z fovy_degrees near far
// in world units (fovy in degrees). Blank lines and lines whose first non-blank character is '#'
// are ignored anywhere, so the header is optional when reading. A line may end in "\r\n".

inline constexpr const char* kCameraPathHeader =
    "# occswitch camera path v1: eye.x eye.y eye.z target.x target.y target.z up.x up.y up.z fovy_degrees near far";

// More cameras than this are refused by the generators (and by `occswitch path --frames`).
inline constexpr uint32_t kMaxPathFrames = 10'000'000;

// Writes the header and one line per camera, each number as printf's "%.9g" (nine significant
// digits, enough for every float to read back bit-identical), atomically: the text goes to a new
// temporary "<path>.tmp.<pid>.<n>" next to `path`, is fsync'ed and renamed over `path`; on any
// failure the temporary is removed and an existing file at `path` is left as it was.
// Throws std::invalid_argument if `cameras` is empty or a camera has a poseDefect() (the file
// would not read back), InputError(path, ...) on I/O failure.
void writeCameraPath(const std::string& path, std::span<const CameraPose> cameras);

// Reads a path file. Every camera line must hold exactly 12 numbers, each finite and within
// float range, and describe a pose without poseDefect(); otherwise throws
// InputError(path, "line L: what"), L counted from 1. Also throws InputError(path, ...) if the
// file cannot be read or holds no camera line. Returns at least one camera.
std::vector<CameraPose> readCameraPath(const std::string& path);

// Length of the polyline through the eyes, in scene units (0 for fewer than two cameras).
double eyePathLength(std::span<const CameraPose> cameras);

// ---- Generated paths --------------------------------------------------------------------------

// What a path is planned around: the objects' world AABBs, optionally their triangles, and the
// name errors report.
struct PathScene {
    std::string name;
    std::vector<k::Aabb> objects;
    // Replaces `corners` by object i's triangles in world space, three corners each. May be
    // empty; walkPath needs it only for Avoid::triangles.
    std::function<void(uint32_t object, std::vector<glm::vec3>& corners)> triangles;
};

// The AABBs of every object of a .oss scene, named after its file, and its triangles at full
// detail (the returned scene refers to `file`, which must outlive it and not be moved).
PathScene pathSceneOf(const OssFile& file);

// `frames` cameras circling the union of the objects' AABBs: centre C, bounding-sphere radius R;
// eye at distance d = 1.05 R / sin(30 degrees) = 2.1 R from C, so that the whole sphere fits the
// 60 degree fovy (the narrower field at aspect >= 1) with a margin, 25 degrees above the
// horizontal plane through C, at azimuth 2 pi i / frames for camera i (one full turn,
// counter-clockwise seen from +y, so the path loops seamlessly), looking at C with up = +y.
// near = R / 100 (every object is at least 1.1 R away, so nothing is clipped, and the depth
// buffer keeps its precision), far = d + 2 R. Throws std::invalid_argument if frames is 0 or above kMaxPathFrames,
// InputError(scene.name, ...) if there are no objects, an AABB is not finite or inverted, the
// bounds are a single point, or the scene is too far from the origin for float cameras.
std::vector<CameraPose> orbitPath(const PathScene& scene, uint32_t frames);

// A person's pace at 60 frames per second: on the plant's 0.25 m cells, 0.1 cells per frame is
// 1.5 m/s, and the view turns at most 60 degrees per second. Faster paths measure how fast the
// camera moves more than how well frame-to-frame coherence works.
inline constexpr double kWalkCellsPerFrame = 0.1;
inline constexpr double kWalkMaxTurnDegreesPerFrame = 1.0;

// What the eyes of a walk keep clear of.
enum class Avoid {
    boxes,      // every object's AABB: a conservative and cheap rule, but the AABB of a bent pipe
                // or an L-shaped tray covers the corridors under it, which it then closes
    triangles,  // the geometry itself (full-detail triangles), so a walk can pass under such AABBs
};

// A walk (flight) through the scene's interior at eye height, and what it was planned on.
struct WalkPath {
    std::vector<CameraPose> cameras;
    float eye_height = 0.0f;   // world y of every eye
    bool on_floor = false;     // eye_height = floor_top + 1.7 (the scene has floors, units are metres)
    float floor_top = 0.0f;    // the floor's walking surface when on_floor
    float cell_size = 0.0f;    // of the occupancy grid, scene units
    uint32_t grid_x = 0, grid_z = 0;  // occupancy grid size in cells
    uint64_t free_cells = 0;   // of the connected free region the walk stays in
};

// `frames` cameras flying through the interior of the scene at one eye height, turning smoothly.
//
// Height: large flat AABBs (thin in y, wide in x and z) whose tops agree and together cover a
// quarter of the scene's x/z footprint are floors; the walk uses the lowest floor with room above
// it, at eye height floor + 1.7 (the scene's units are taken to be metres) on a 0.25 m grid
// (a window of at most 2048 x 2048 cells around the centre on huge scenes). A scene without
// floors is cut at 16 heights spread over its y range, on a grid of 192 cells along the longer of
// x and z. Free cells from which at least 4 of the 8 rays along the axes and diagonals meet an
// object are enclosed (inside the scene, not in the margin around it: the streets of a lattice
// and their crossings qualify); the cut whose largest connected enclosed walkable region is most
// surrounded (summed over its cells, the rays meeting an object within 16 cells) wins. Without
// any, the cut with the largest walkable region.
//
// Occupancy: a cell is occupied when, among the objects whose AABB overlaps the horizontal slab
// eye height +- one cell, an AABB touches it (Avoid::boxes) or the x/z bounding rectangle of a
// triangle's part inside the slab does (Avoid::triangles). Cells at least 3 cells (max norm)
// from every occupied cell and from the grid's edge, and over the floor's slabs or enclosed, are
// walkable; the walk starts at a seeded random cell of their largest 4-connected region.
//
// Path: a seeded random walk from cell to cell goes straight while it can, turns at most 45
// degrees per cell towards the most open and least visited way when an obstacle comes within 8
// cells, and now and then takes a side way that opens up. It is low-pass filtered (Gaussian,
// sigma 3 steps, each point's displacement limited by the free space around it) and resampled at
// 0.4 cells per frame. The camera looks level towards the point 6 cells further along the path,
// turning at most 4 degrees per frame; up = +y, fovy 60, near = cell / 5, far = the scene's
// diagonal.
//
// Guarantees: every eye is inside the scene's bounds and at least one cell away (horizontally
// or vertically) from every AABB (Avoid::boxes) or every triangle (Avoid::triangles) of the
// scene; consecutive eyes are at most 0.4 cells apart; the view direction turns at most 4
// degrees between frames; the result depends only on the objects (and triangles), frames, seed
// and `avoid`. Throws std::invalid_argument if frames is 0 or above kMaxPathFrames, or if
// Avoid::triangles is asked of a scene without triangles; InputError(scene.name, ...) if the
// objects are unusable (as orbitPath) or no height tried has a walkable region of 64 cells.
WalkPath walkPath(const PathScene& scene, uint32_t frames, uint64_t seed, Avoid avoid = Avoid::boxes);

}  // namespace occ
