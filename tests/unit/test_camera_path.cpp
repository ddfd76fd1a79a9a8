// SPDX-License-Identifier: MIT
#include "view/camera_path.h"

#include "import/plant.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>
#include <glm/gtc/matrix_transform.hpp>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

namespace occ {
namespace {

using test::scratchDir;
using test::writeFixture;

CameraPose pose(glm::vec3 eye, glm::vec3 target) {
    CameraPose p;
    p.eye = eye;
    p.target = target;
    p.up = {0, 1, 0};
    p.fovy_degrees = 60;
    p.near_plane = 0.5f;
    p.far_plane = 200;
    return p;
}

bool sameBits(const CameraPose& a, const CameraPose& b) {
    const float fa[12] = {a.eye.x, a.eye.y, a.eye.z, a.target.x, a.target.y, a.target.z,
                          a.up.x,  a.up.y,  a.up.z,  a.fovy_degrees, a.near_plane, a.far_plane};
    const float fb[12] = {b.eye.x, b.eye.y, b.eye.z, b.target.x, b.target.y, b.target.z,
                          b.up.x,  b.up.y,  b.up.z,  b.fovy_degrees, b.near_plane, b.far_plane};
    return std::memcmp(fa, fb, sizeof(fa)) == 0;
}

bool samePath(const std::vector<CameraPose>& a, const std::vector<CameraPose>& b) {
    if (a.size() != b.size()) return false;
    for (size_t i = 0; i < a.size(); ++i)
        if (!sameBits(a[i], b[i])) return false;
    return true;
}

std::string errorOf(const std::string& path) {
    try {
        readCameraPath(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "no error";
}

glm::vec3 viewDirection(const CameraPose& c) { return glm::normalize(c.target - c.eye); }

double degreesBetween(glm::vec3 a, glm::vec3 b) {
    return glm::degrees(std::acos(std::clamp(double(glm::dot(glm::normalize(a), glm::normalize(b))), -1.0, 1.0)));
}

bool inside(const glm::vec3& p, const k::Aabb& box) {
    return glm::all(glm::greaterThanEqual(p, box.min)) && glm::all(glm::lessThanEqual(p, box.max));
}

// Horizontal (x/z) distance from p to the box's footprint; 0 inside it.
float footprintDistance(const glm::vec3& p, const k::Aabb& box) {
    const float dx = std::max({box.min.x - p.x, 0.0f, p.x - box.max.x});
    const float dz = std::max({box.min.z - p.z, 0.0f, p.z - box.max.z});
    return std::max(dx, dz);
}

// The 12 triangles of a box, three corners each.
void appendBox(std::vector<glm::vec3>& out, const k::Aabb& b) {
    const auto corner = [&](int i) { return glm::vec3(i & 1 ? b.max.x : b.min.x, i & 2 ? b.max.y : b.min.y, i & 4 ? b.max.z : b.min.z); };
    static const int faces[6][4] = {{0, 2, 6, 4}, {1, 5, 7, 3}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 6, 7, 5}};
    for (const auto& f : faces)
        for (int t : {0, 2}) {
            out.push_back(corner(f[0]));
            out.push_back(corner(f[1 + t / 2]));
            out.push_back(corner(f[2 + t / 2]));
        }
}

// A scene of boxes, each object one box, with its triangles.
PathScene boxScene(const std::vector<k::Aabb>& boxes) {
    PathScene scene{"boxes", boxes, {}};
    scene.triangles = [boxes](uint32_t i, std::vector<glm::vec3>& corners) {
        corners.clear();
        appendBox(corners, boxes[i]);
    };
    return scene;
}

k::Aabb box(glm::vec3 lo, glm::vec3 hi) { return {lo, hi}; }

// A 40 x 40 m floor slab with some boxes standing on it and one column reaching 5 m.
PathScene floorWithBoxes() {
    return boxScene({box({0, -0.3f, 0}, {40, 0, 40}), box({5, 0, 5}, {8, 3, 9}), box({15, 0, 20}, {17, 2.5f, 30}),
                     box({25, 0, 10}, {35, 3, 12}), box({10, 0, 30}, {12, 3, 38}), box({30, 0, 30}, {33, 1, 33}),
                     box({20, 0, 5}, {21, 5, 6})});
}

// 5 x 3 x 5 cubes of side 2 at a pitch of 3: no floors, gaps between everything.
PathScene latticeOfCubes() {
    std::vector<k::Aabb> cubes;
    for (int y = 0; y < 3; ++y)
        for (int z = 0; z < 5; ++z)
            for (int x = 0; x < 5; ++x) cubes.push_back(box(glm::vec3(x, y, z) * 3.0f, glm::vec3(x, y, z) * 3.0f + 2.0f));
    return boxScene(cubes);
}

k::Aabb boundsOf(const PathScene& scene) {
    k::Aabb b = scene.objects[0];
    for (const k::Aabb& a : scene.objects) b.min = glm::min(b.min, a.min), b.max = glm::max(b.max, a.max);
    return b;
}

// What every generated walk promises, checked on the cameras.
void expectSmoothLevelWalk(const WalkPath& walk, const PathScene& scene) {
    const k::Aabb bounds = boundsOf(scene);
    // float positions of size ~100 carry ~1e-5 of rounding per step
    const float step = float(kWalkCellsPerFrame) * walk.cell_size * 1.001f;
    for (size_t f = 0; f < walk.cameras.size(); ++f) {
        const CameraPose& c = walk.cameras[f];
        ASSERT_TRUE(poseDefect(c).empty()) << "camera " << f << ": " << poseDefect(c);
        ASSERT_TRUE(inside(c.eye, bounds)) << "camera " << f;
        EXPECT_EQ(c.eye.y, walk.eye_height);
        EXPECT_EQ(c.target.y, c.eye.y) << "camera " << f << " does not look level";
        EXPECT_EQ(c.up, glm::vec3(0, 1, 0));
        EXPECT_EQ(c.fovy_degrees, 60.0f);
        if (f == 0) continue;
        const CameraPose& p = walk.cameras[f - 1];
        ASSERT_LE(glm::length(c.eye - p.eye), step) << "camera " << f << " jumps";
        ASSERT_LE(degreesBetween(viewDirection(c), viewDirection(p)), kWalkMaxTurnDegreesPerFrame + 0.01) << "camera " << f << " turns abruptly";
    }
}

// ---- CameraPose ----

TEST(Camera, ViewMatrixPutsTheEyeAtTheOriginLookingDownMinusZ) {
    const CameraPose c = pose({1, 2, 3}, {1, 2, -7});
    const glm::mat4 view = viewMatrix(c);
    EXPECT_NEAR(glm::length(glm::vec3(view * glm::vec4(c.eye, 1))), 0.0f, 1e-6f);
    const glm::vec3 t(view * glm::vec4(c.target, 1));
    EXPECT_NEAR(t.x, 0, 1e-5f);
    EXPECT_NEAR(t.y, 0, 1e-5f);
    EXPECT_NEAR(t.z, -10, 1e-5f);
}

TEST(Camera, ProjectionMapsNearAndFarToWindowDepthZeroAndOne) {
    const CameraPose c = pose({0, 0, 0}, {0, 0, -1});
    const glm::mat4 vp = projectionMatrix(c, 200, 100) * viewMatrix(c);
    const auto window_depth = [&](float distance) {
        const glm::vec4 clip = vp * glm::vec4(0, 0, -distance, 1);
        return clip.z / clip.w * 0.5f + 0.5f;
    };
    EXPECT_NEAR(window_depth(c.near_plane), 0.0f, 1e-6f);
    EXPECT_NEAR(window_depth(c.far_plane), 1.0f, 1e-5f);
    EXPECT_LT(window_depth(10), window_depth(20));
    // aspect = width / height: a point at the right edge of a 2:1 viewport
    const float half_height = std::tan(glm::radians(30.0f)) * 10;
    const glm::vec4 edge = vp * glm::vec4(2 * half_height, half_height, -10, 1);
    EXPECT_NEAR(edge.x / edge.w, 1.0f, 1e-5f);
    EXPECT_NEAR(edge.y / edge.w, 1.0f, 1e-5f);
}

TEST(Camera, KernelCameraFillsEveryField) {
    CameraPose c = pose({1, 2, 3}, {4, 6, 3});
    c.fovy_degrees = 45;
    const k::Camera k = toKernelCamera(c, 640, 480);
    EXPECT_EQ(k.eye, c.eye);
    EXPECT_NEAR(glm::length(k.forward - glm::vec3(0.6f, 0.8f, 0)), 0.0f, 1e-6f);
    EXPECT_EQ(k.near_plane, c.near_plane);
    EXPECT_EQ(k.far_plane, c.far_plane);
    EXPECT_EQ(k.width, 640u);
    EXPECT_EQ(k.height, 480u);
    EXPECT_FLOAT_EQ(k.fovy, float(std::numbers::pi / 4));
    EXPECT_EQ(k.pad, 0.0f);
    const glm::mat4 expected = projectionMatrix(c, 640, 480) * viewMatrix(c);
    EXPECT_EQ(std::memcmp(&k.view_proj, &expected, sizeof(expected)), 0);
    EXPECT_THROW(toKernelCamera(c, 0, 480), std::invalid_argument);
    EXPECT_THROW(projectionMatrix(c, 640, 0), std::invalid_argument);
}

// ---- The path file ----

TEST(CameraPathFile, RoundTripIsBitIdentical) {
    std::vector<CameraPose> cameras;
    const float awkward[] = {0.1f, 1.0f / 3, -0.0f, 1e-30f, 1e-40f /* subnormal */, 3.4028235e38f,
                             std::nextafter(1.0f, 2.0f), float(std::numbers::pi), -123456.789f, 16777217.0f};
    for (float a : awkward) {
        CameraPose c = pose({a, -a, a / 2}, {a + 1, 7, -a});
        c.up = {1e-3f, 1, a};
        c.fovy_degrees = 179.99998f;
        c.near_plane = 1e-7f;
        c.far_plane = 3.0e38f;
        cameras.push_back(c);
    }
    const std::string path = (scratchDir() / "round.cam").string();
    writeCameraPath(path, cameras);
    EXPECT_TRUE(samePath(readCameraPath(path), cameras));

    std::ifstream in(path);
    std::string first;
    std::getline(in, first);
    EXPECT_EQ(first, kCameraPathHeader);
    size_t lines = 1;
    for (std::string line; std::getline(in, line);) ++lines;
    EXPECT_EQ(lines, cameras.size() + 1);
}

TEST(CameraPathFile, ReadSkipsBlankLinesCommentsAndCarriageReturns) {
    const std::string path = writeFixture("loose.cam",
                                          "# a comment first\n"
                                          "\n"
                                          "   \t \r\n"
                                          "  # an indented comment\n"
                                          "0 1.5 10\t0 1.5 0  0 1 0 60 0.1 100\r\n"
                                          "+1 2 3 4 5 6 0 1 0 +45 1e-2 1E3\n"
                                          "# the end, no newline after the last camera\n"
                                          "1 2 3 1 2 4 0 1 0 90 1 2");
    const std::vector<CameraPose> cameras = readCameraPath(path);
    ASSERT_EQ(cameras.size(), 3u);
    EXPECT_EQ(cameras[0].eye, glm::vec3(0, 1.5f, 10));
    EXPECT_EQ(cameras[0].near_plane, 0.1f);
    EXPECT_EQ(cameras[1].eye, glm::vec3(1, 2, 3));
    EXPECT_EQ(cameras[1].fovy_degrees, 45.0f);
    EXPECT_EQ(cameras[1].far_plane, 1000.0f);
    EXPECT_EQ(cameras[2].target, glm::vec3(1, 2, 4));
}

TEST(CameraPathFile, EveryMalformedLineIsRejectedWithItsLineNumber) {
    const std::string good = "0 0 5 0 0 0 0 1 0 60 0.1 100";
    const struct {
        const char* line;
        const char* error;
    } cases[] = {
        {"0 0 5 0 0 0 0 1 0 60 0.1", "line 3: expected 12 numbers (eye.xyz target.xyz up.xyz fovy_degrees near far), found 11"},
        {"0 0 5 0 0 0 0 1 0 60 0.1 100 7", "line 3: expected 12 numbers"},
        {"0 0 5 0 0 0 0 1 0 60 0.1 100 # note", "found 14"},
        {"0 0 5 abc 0 0 0 1 0 60 0.1 100", "line 3: field 4 (target.x) = 'abc' is not a number"},
        {"0 0 5 0 0 0 0 1 0 60 0.1 1.5x", "line 3: field 12 (far) = '1.5x' is not a number"},
        {"0 0 5 0 0 0 0 1 0 60 0,1 100", "field 11 (near) = '0,1' is not a number"},
        {"0 0 5 0 0 0 0 1 0 60 0.1 ++100", "field 12 (far) = '++100' is not a number"},
        {"0 0 5 0 0 0 0 1 0 60 0.1 0x10", "field 12 (far) = '0x10' is not a number"},
        {"inf 0 5 0 0 0 0 1 0 60 0.1 100", "line 3: field 1 (eye.x) = 'inf' is not finite"},
        {"0 nan 5 0 0 0 0 1 0 60 0.1 100", "line 3: field 2 (eye.y) = 'nan' is not finite"},
        {"0 0 1e39 0 0 0 0 1 0 60 0.1 100", "line 3: field 3 (eye.z) = '1e39' is outside the float range"},
        {"0 0 5 0 0 0 0 1 0 0 0.1 100", "line 3: fovy_degrees = 0 is outside (0, 180)"},
        {"0 0 5 0 0 0 0 1 0 180 0.1 100", "line 3: fovy_degrees = 180 is outside (0, 180)"},
        {"0 0 5 0 0 0 0 1 0 -30 0.1 100", "line 3: fovy_degrees = -30 is outside (0, 180)"},
        {"0 0 5 0 0 0 0 1 0 60 0 100", "line 3: near = 0 is not positive"},
        {"0 0 5 0 0 0 0 1 0 60 -1 100", "line 3: near = -1 is not positive"},
        {"0 0 5 0 0 0 0 1 0 60 100 10", "line 3: near = 100 is not below far = 10"},
        {"0 0 5 0 0 0 0 1 0 60 10 10", "line 3: near = 10 is not below far = 10"},
        {"1 2 3 1 2 3 0 1 0 60 0.1 100", "line 3: eye equals target"},
        {"0 0 5 0 0 0 0 0 -2 60 0.1 100", "line 3: up is parallel to the view direction"},
        {"0 5 0 0 0 0 0 1 0 60 0.1 100", "line 3: up is parallel to the view direction"},
        {"0 0 5 0 0 0 0 0 0 60 0.1 100", "line 3: up is the zero vector"},
    };
    for (const auto& c : cases) {
        const std::string path = writeFixture("bad.cam", std::string(kCameraPathHeader) + "\n" + good + "\n" + c.line + "\n" + good + "\n");
        const std::string error = errorOf(path);
        EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << c.line << " -> " << error;
        EXPECT_NE(error.find(c.error), std::string::npos) << c.line << " -> " << error;
    }
}

TEST(CameraPathFile, EveryTruncationReadsOrFailsCleanly) {
    const std::vector<CameraPose> cameras{pose({0.1f, 1.7f, -3}, {1, 1.7f, -3}), pose({-1e-7f, 2, 3e5f}, {0, 0, 0}),
                                          pose({4, 5, 6}, {4, 5, 7})};
    const std::string path = (scratchDir() / "whole.cam").string();
    writeCameraPath(path, cameras);
    const std::vector<char> bytes = test::readBytes(path);
    for (size_t length = 0; length <= bytes.size(); ++length) {
        const std::string cut = writeFixture("cut.cam", std::string(bytes.data(), length));
        try {
            const std::vector<CameraPose> read = readCameraPath(cut);
            ASSERT_LE(read.size(), cameras.size());
            for (size_t i = 0; i + 1 < read.size(); ++i) EXPECT_TRUE(sameBits(read[i], cameras[i])) << length;
        } catch (const InputError& e) {
            EXPECT_EQ(std::string(e.what()).rfind(cut + ": ", 0), 0u) << e.what();
        }
    }
}

TEST(CameraPathFile, LineNumbersCountBlankAndCommentLines) {
    const std::string path = writeFixture("late.cam", "# one\n\n# three\n\n1 2\n");
    EXPECT_NE(errorOf(path).find(": line 5: expected 12 numbers"), std::string::npos) << errorOf(path);
}

TEST(CameraPathFile, APathWithoutCamerasIsAnError) {
    for (const char* text : {"", "\n\n", "# occswitch camera path v1\n# nothing else\n"}) {
        const std::string path = writeFixture("empty.cam", text);
        EXPECT_NE(errorOf(path).find(": no cameras"), std::string::npos) << errorOf(path);
    }
    EXPECT_NE(errorOf((scratchDir() / "missing.cam").string()).find("cannot open"), std::string::npos);
    EXPECT_NE(errorOf(scratchDir().string()).find("is a folder"), std::string::npos);
}

TEST(CameraPathFile, WriteRefusesWhatCouldNotBeReadBack) {
    const std::string path = (scratchDir() / "refused.cam").string();
    EXPECT_THROW(writeCameraPath(path, {}), std::invalid_argument);
    CameraPose bad = pose({0, 0, 0}, {0, 0, 0});
    EXPECT_THROW(writeCameraPath(path, std::vector<CameraPose>{pose({0, 0, 1}, {0, 0, 0}), bad}), std::invalid_argument);
    bad = pose({0, 0, 1}, {0, 0, 0});
    bad.near_plane = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(writeCameraPath(path, std::vector<CameraPose>{bad}), std::invalid_argument);
    EXPECT_FALSE(std::filesystem::exists(path));
}

TEST(CameraPathFile, WriteReplacesTheFileAndLeavesNoTemporary) {
    const std::filesystem::path dir = scratchDir() / "camera_path_atomic";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / "p.cam").string();
    writeCameraPath(path, std::vector<CameraPose>(3, pose({0, 0, 1}, {0, 0, 0})));
    const std::vector<CameraPose> second{pose({0, 0, 2}, {0, 0, 0})};
    writeCameraPath(path, second);
    EXPECT_TRUE(samePath(readCameraPath(path), second));
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir), std::filesystem::directory_iterator()), 1);
    EXPECT_THROW(writeCameraPath((dir / "no" / "such" / "folder.cam").string(), second), InputError);
}

// ---- Orbit ----

TEST(Orbit, CirclesTheCentreOnceAtConstantDistanceAndElevation) {
    const PathScene scene = boxScene({box({-1, -2, -3}, {1, 4, 0}), box({0, 0, 0}, {5, 1, 3})});
    const glm::vec3 centre(2, 1, 0);
    const float radius = glm::length(glm::vec3(6, 6, 6)) / 2;
    const uint32_t frames = 360;
    const std::vector<CameraPose> cameras = orbitPath(scene, frames);
    ASSERT_EQ(cameras.size(), frames);
    double turned = 0;
    for (uint32_t i = 0; i < frames; ++i) {
        const CameraPose& c = cameras[i];
        EXPECT_EQ(c.target, centre);
        EXPECT_EQ(c.up, glm::vec3(0, 1, 0));
        const glm::vec3 offset = c.eye - centre;
        EXPECT_NEAR(glm::length(offset), 2.1f * radius, 1e-4f);
        // The whole bounding sphere is in view: its angular radius fits half the vertical fov.
        EXPECT_LT(std::asin(radius / glm::length(offset)), glm::radians(c.fovy_degrees) / 2);
        EXPECT_NEAR(glm::degrees(std::asin(offset.y / glm::length(offset))), 25.0f, 1e-3f);
        EXPECT_LT(c.near_plane, 1.1f * radius);  // nothing of the scene is nearer than 1.1 R
        EXPECT_GT(c.near_plane, 1e-3f * radius);
        EXPECT_GE(c.far_plane, 3.1f * radius);  // the far side of the bounding sphere
        const glm::vec3 next = cameras[(i + 1) % frames].eye - centre;
        // azimuth of next minus this, counter-clockwise seen from +y (x right, z down the screen)
        const double step = std::atan2(-(double(next.z) * offset.x - double(next.x) * offset.z),
                                       double(next.x) * offset.x + double(next.z) * offset.z);
        EXPECT_NEAR(glm::degrees(step), 1.0, 1e-3);
        turned += step;
    }
    EXPECT_NEAR(turned, 2 * std::numbers::pi, 1e-4);
}

TEST(Orbit, RejectsNoFramesAndScenesWithoutExtent) {
    const PathScene scene = boxScene({box({0, 0, 0}, {1, 1, 1})});
    EXPECT_THROW(orbitPath(scene, 0), std::invalid_argument);
    EXPECT_THROW(orbitPath(scene, kMaxPathFrames + 1), std::invalid_argument);
    EXPECT_EQ(orbitPath(scene, 1).size(), 1u);
    EXPECT_THROW(orbitPath(boxScene({box({1, 2, 3}, {1, 2, 3})}), 10), InputError);
    EXPECT_THROW(orbitPath(PathScene{"none", {}, {}}, 10), InputError);
    EXPECT_THROW(orbitPath(boxScene({box({0, 0, 0}, {-1, 1, 1})}), 10), InputError);
    EXPECT_THROW(orbitPath(boxScene({box({1e7f, 0, 0}, {1e7f, 1e-6f, 0})}), 10), InputError);  // eye rounds onto target
}

// ---- Walk ----

TEST(Walk, OnAFloorKeepsEyeHeightAndStaysOutOfEveryBox) {
    const PathScene scene = floorWithBoxes();
    const WalkPath walk = walkPath(scene, 3000, 3);
    ASSERT_EQ(walk.cameras.size(), 3000u);
    EXPECT_TRUE(walk.on_floor);
    EXPECT_EQ(walk.floor_top, 0.0f);
    EXPECT_EQ(walk.eye_height, 1.7f);
    EXPECT_EQ(walk.cell_size, 0.25f);
    EXPECT_NEAR(walk.cameras[0].near_plane, 0.05f, 1e-6f);
    expectSmoothLevelWalk(walk, scene);
    for (const CameraPose& c : walk.cameras)
        for (size_t b = 1; b < scene.objects.size(); ++b) {
            ASSERT_FALSE(inside(c.eye, scene.objects[b])) << "box " << b;
            if (scene.objects[b].max.y > c.eye.y - walk.cell_size) {  // reaches the eye's slab
                ASSERT_GE(footprintDistance(c.eye, scene.objects[b]), walk.cell_size * 0.999f) << "box " << b;
            }
        }
    EXPECT_GT(eyePathLength(walk.cameras), 0.99 * 2999 * kWalkCellsPerFrame * walk.cell_size);
}

TEST(Walk, SmoothingDoesNotCutCornersOfANarrowCorridor) {
    // An L-shaped corridor 1.75 m wide (7 cells, 2 walkable at its middle) with dead ends: the
    // smoothed walk must keep its distance at the corner and where it turns round.
    const PathScene scene = boxScene({box({0, -0.3f, 0}, {20, 0, 20}), box({0, 0, 0}, {20, 3, 2}),
                                      box({0, 0, 3.75f}, {16.25f, 3, 20}), box({18, 0, 2}, {20, 3, 20}),
                                      box({0, 0, 2}, {2, 3, 3.75f}), box({16.25f, 0, 18}, {18, 3, 20})});
    for (uint64_t seed : {1, 2, 3}) {
        const WalkPath walk = walkPath(scene, 4000, seed);
        expectSmoothLevelWalk(walk, scene);
        for (const CameraPose& c : walk.cameras)
            for (size_t b = 1; b < scene.objects.size(); ++b)
                ASSERT_GE(footprintDistance(c.eye, scene.objects[b]), walk.cell_size * 0.999f) << "box " << b;
    }
}

TEST(Walk, TakesTheLowestFloorWithRoomAboveIt) {
    // Two storeys; the ground floor is filled by one big crate, the upper one is free.
    const PathScene scene = boxScene({box({0, -0.3f, 0}, {30, 0, 30}), box({0, 0, 0}, {30, 3.5f, 30}),
                                      box({0, 3.7f, 0}, {30, 4, 30}), box({0, 4, 0}, {1, 8, 1})});
    const WalkPath walk = walkPath(scene, 500, 1);
    EXPECT_TRUE(walk.on_floor);
    EXPECT_EQ(walk.floor_top, 4.0f);
    EXPECT_EQ(walk.eye_height, 5.7f);
    expectSmoothLevelWalk(walk, scene);
}

TEST(Walk, ThroughALatticeOfCubesPicksAHeightAmongThem) {
    const PathScene scene = latticeOfCubes();
    const WalkPath walk = walkPath(scene, 2000, 5);
    EXPECT_FALSE(walk.on_floor);
    // The cut goes through a layer of cubes (y in [0,2], [3,5] or [6,8]), not between layers.
    const float y = walk.eye_height, layer = std::fmod(y, 3.0f);
    EXPECT_TRUE(layer > 0 && layer < 2) << y;
    expectSmoothLevelWalk(walk, scene);
    for (const CameraPose& c : walk.cameras)
        for (const k::Aabb& cube : scene.objects) {
            ASSERT_FALSE(inside(c.eye, cube));
            if (cube.min.y < y + walk.cell_size && cube.max.y > y - walk.cell_size) {
                ASSERT_GE(footprintDistance(c.eye, cube), walk.cell_size * 0.999f);
            }
        }
}

TEST(Walk, ThroughTheGeneratedPlantStaysOutOfEveryAabb) {
    const Scene plant = generatePlant({2000, 1});
    PathScene scene{"plant", {}, {}};
    for (uint32_t i = 0; i < plant.objects.size(); ++i) {
        const Bounds b = plant.objectBounds(i);
        scene.objects.push_back({b.min, b.max});
    }
    const WalkPath walk = walkPath(scene, 1000, 1);
    EXPECT_TRUE(walk.on_floor);
    EXPECT_EQ(walk.floor_top, 0.0f);
    EXPECT_EQ(walk.eye_height, 1.7f);
    expectSmoothLevelWalk(walk, scene);
    for (const CameraPose& c : walk.cameras)
        for (size_t i = 0; i < scene.objects.size(); ++i) ASSERT_FALSE(inside(c.eye, scene.objects[i])) << "object " << i;
}

TEST(Walk, AvoidingTrianglesPassesUnderTheAabbOfABentPipe) {
    // An L of two thin legs whose AABB covers most of the floor; the floor inside the L is free.
    const k::Aabb leg_a = box({2, 0.5f, 2}, {38, 3, 2.4f}), leg_b = box({37.6f, 0.5f, 2}, {38, 3, 38});
    PathScene scene{"bent", {box({0, -0.3f, 0}, {40, 0, 40}), box({2, 0.5f, 2}, {38, 3, 38}), box({5, 0, 20}, {8, 3, 23})}, {}};
    scene.triangles = [&](uint32_t i, std::vector<glm::vec3>& corners) {
        corners.clear();
        if (i == 1) {
            appendBox(corners, leg_a);
            appendBox(corners, leg_b);
        } else {
            appendBox(corners, scene.objects[i]);
        }
    };
    const WalkPath boxes = walkPath(scene, 1000, 2, Avoid::boxes);
    for (const CameraPose& c : boxes.cameras) ASSERT_FALSE(inside(c.eye, scene.objects[1]));

    const WalkPath triangles = walkPath(scene, 1000, 2, Avoid::triangles);
    expectSmoothLevelWalk(triangles, scene);
    size_t under = 0;
    for (const CameraPose& c : triangles.cameras) {
        under += inside(c.eye, scene.objects[1]);
        for (const k::Aabb& solid : {leg_a, leg_b, scene.objects[2]})
            ASSERT_GE(footprintDistance(c.eye, solid), triangles.cell_size * 0.999f);
    }
    EXPECT_GT(under, triangles.cameras.size() / 2);
    EXPECT_GT(triangles.free_cells, 4 * boxes.free_cells);

    PathScene without = scene;
    without.triangles = nullptr;
    EXPECT_THROW(walkPath(without, 10, 1, Avoid::triangles), std::invalid_argument);
}

TEST(Walk, SameSeedSamePathOtherSeedOtherPath) {
    const PathScene scene = floorWithBoxes();
    const WalkPath a = walkPath(scene, 800, 11), b = walkPath(scene, 800, 11), c = walkPath(scene, 800, 12);
    EXPECT_TRUE(samePath(a.cameras, b.cameras));
    EXPECT_FALSE(samePath(a.cameras, c.cameras));
    const PathScene lattice = latticeOfCubes();
    EXPECT_TRUE(samePath(walkPath(lattice, 300, 4, Avoid::triangles).cameras, walkPath(lattice, 300, 4, Avoid::triangles).cameras));
    // and a file written from it reads back as it was
    const std::string path = (scratchDir() / "walk.cam").string();
    writeCameraPath(path, a.cameras);
    EXPECT_TRUE(samePath(readCameraPath(path), a.cameras));
}

TEST(Walk, ShortAndSingleFramePaths) {
    const PathScene scene = floorWithBoxes();
    EXPECT_EQ(walkPath(scene, 1, 1).cameras.size(), 1u);
    const WalkPath two = walkPath(scene, 2, 1);
    EXPECT_NEAR(glm::length(two.cameras[1].eye - two.cameras[0].eye), float(kWalkCellsPerFrame) * two.cell_size, 1e-4f);
    EXPECT_THROW(walkPath(scene, 0, 1), std::invalid_argument);
    EXPECT_THROW(walkPath(scene, kMaxPathFrames + 1, 1), std::invalid_argument);
}

TEST(Walk, ASceneWithoutRoomIsAnInputError) {
    EXPECT_THROW(walkPath(boxScene({box({0, 0, 0}, {10, 10, 10})}), 10, 1), InputError);
    EXPECT_THROW(walkPath(boxScene({box({0, -0.3f, 0}, {40, 0, 40})}), 10, 1), InputError);  // a floor, nothing above
    EXPECT_THROW(walkPath(PathScene{"none", {}, {}}, 10, 1), InputError);
}

}  // namespace
}  // namespace occ
