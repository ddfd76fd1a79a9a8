// SPDX-License-Identifier: MIT
#include "depth_raster.h"
#include "hzm.h"
#include "hzm_build.h"
#include "occluder_gather.h"
#include "simd_level.h"

#include "device_test_support.h"
#include "raster_fixtures.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace occ::k {
namespace {

using test::atWindow;
using test::filledDevice;
using test::identityCamera;
using test::Mesh;
using test::perspectiveCamera;
using test::randomScene;
using test::toDevice;
using test::toHost;

using DepthRaster = test::DeviceTest;

constexpr float kEps = kDepthRasterEpsilon;


std::vector<uint8_t> sharedFlags(const std::vector<uint32_t>& triangles) {
    std::vector<uint8_t> flags(triangles.size() / 3, 0xff);  // every bit must be written
    sharedEdgeFlags(triangles.data(), uint32_t(flags.size()), flags.data());
    return flags;
}
std::vector<uint8_t> sharedFlags(const Mesh& mesh) { return sharedFlags(mesh.triangles); }

// flags: one per triangle, or empty for none (null); neighbours: 3 per triangle, or empty.
std::vector<float> rasterize(const Mesh& mesh, const Camera& camera, DepthRasterScratch& scratch,
                             const std::vector<uint8_t>& flags = {}, const std::vector<uint32_t>& neighbours = {},
                             bool seams = false) {
    const DeviceArray<glm::vec3> positions = toDevice(mesh.positions);
    const DeviceArray<uint32_t> triangles = toDevice(mesh.triangles);
    const DeviceArray<uint8_t> edge_flags = toDevice(flags);
    const DeviceArray<uint32_t> across = toDevice(neighbours);
    const uint64_t pixels = uint64_t(camera.width) * camera.height;
    DeviceArray<float> depth = filledDevice(pixels, -3.0f);  // the raster must clear it
    depthRaster(positions.ptr(), triangles.ptr(), mesh.triangleCount(),
                flags.empty() ? DevicePtr<const uint8_t>() : edge_flags.ptr(),
                neighbours.empty() ? DevicePtr<const uint32_t>() : across.ptr(), camera, depth.ptr(), scratch, seams);
    return toHost(depth, pixels);
}

std::vector<float> rasterize(const Mesh& mesh, const Camera& camera, const std::vector<uint8_t>& flags = {}) {
    DepthRasterScratch scratch;
    return rasterize(mesh, camera, scratch, flags);
}

// The rules of depth_raster.h, one triangle and one pixel at a time: plain projection, snapping
// to 1/256 pixel, the pixel box, exact integer edge functions evaluated (not stepped) at every
// pixel centre of the box, and the same float and double sums for the depth plane and its push
// so that results match bit for bit. flags: per triangle as sharedEdgeFlags gives them (with
// kEdgeFlagSkipBackFace where a back face may be skipped), or empty for none.
std::vector<float> referenceRaster(const Mesh& mesh, const Camera& camera, const std::vector<uint8_t>& flags = {}) {
    const uint32_t width = camera.width, height = camera.height;
    std::vector<float> depth(uint64_t(width) * height, 1.0f);
    const glm::mat4& m = camera.view_proj;
    for (size_t t = 0; t + 2 < mesh.triangles.size(); t += 3) {
        int64_t sx[3], sy[3];
        float sz[3];
        bool drawn = true;
        for (int i = 0; i < 3 && drawn; ++i) {
            const glm::vec3 p = mesh.positions[mesh.triangles[t + i]];
            float clip[4];
            for (int r = 0; r < 4; ++r) clip[r] = m[0][r] * p.x + m[1][r] * p.y + m[2][r] * p.z + m[3][r];
            if (!(clip[3] > 0.0f) || !(clip[2] >= -clip[3])) {
                drawn = false;
                break;
            }
            const float inv_w = 1.0f / clip[3];
            const float wx = (clip[0] * inv_w * 0.5f + 0.5f) * float(width);
            const float wy = (clip[1] * inv_w * 0.5f + 0.5f) * float(height);
            sz[i] = clip[2] * inv_w * 0.5f + 0.5f;
            drawn = std::abs(wx) <= kDepthRasterGuardBand && std::abs(wy) <= kDepthRasterGuardBand &&
                    sz[i] <= kDepthRasterMaxDepth;
            sx[i] = int64_t(std::floor(wx * 256.0f + 0.5f));
            sy[i] = int64_t(std::floor(wy * 256.0f + 0.5f));
        }
        if (!drawn) continue;
        const uint8_t shared = flags.empty() ? 0 : flags[t / 3] & 7;
        // Centres 256 p + 128 at least the margin (4) inside the snapped bounding box, for a
        // triangle without shared edges; inside the box for one with.
        const int64_t box_margin = shared ? 0 : 4;
        const auto [sx_min, sx_max] = std::minmax({sx[0], sx[1], sx[2]});
        const auto [sy_min, sy_max] = std::minmax({sy[0], sy[1], sy[2]});
        const int64_t x0 = std::max<int64_t>(0, int64_t(std::ceil((sx_min + box_margin - 128) / 256.0)));
        const int64_t x1 = std::min<int64_t>(width - 1, int64_t(std::floor((sx_max - box_margin - 128) / 256.0)));
        const int64_t y0 = std::max<int64_t>(0, int64_t(std::ceil((sy_min + box_margin - 128) / 256.0)));
        const int64_t y1 = std::min<int64_t>(height - 1, int64_t(std::floor((sy_max - box_margin - 128) / 256.0)));
        if (x0 > x1 || y0 > y1) continue;
        int64_t area2 = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sy[1] - sy[0]) * (sx[2] - sx[0]);
        if (area2 == 0) continue;
        // A back face (clockwise on screen) that may be skipped is.
        if (area2 < 0 && !flags.empty() && (flags[t / 3] & kEdgeFlagSkipBackFace)) continue;
        int corner[3] = {0, 1, 2};  // which input corner each counter-clockwise corner is
        if (area2 < 0) {
            std::swap(sx[1], sx[2]);
            std::swap(sy[1], sy[2]);
            std::swap(sz[1], sz[2]);
            std::swap(corner[1], corner[2]);
            area2 = -area2;
        }
        const double dz1 = double(sz[1]) - double(sz[0]), dz2 = double(sz[2]) - double(sz[0]);
        const double d1x = double(sx[1] - sx[0]), d1y = double(sy[1] - sy[0]);
        const double d2x = double(sx[2] - sx[0]), d2y = double(sy[2] - sy[0]);
        const double gx = (dz1 * d2y - dz2 * d1y) / double(area2), gy = (d1x * dz2 - d2x * dz1) / double(area2);
        const double ref = sz[0] + gx * double(x0 * 256 + 128 - sx[0]) + gy * double(y0 * 256 + 128 - sy[0]);
        const float gx_px = float(gx * 256.0), gy_px = float(gy * 256.0);
        const float magnitude = std::max({std::abs(sz[0]), std::abs(sz[1]), std::abs(sz[2])}) +
                                std::abs(gx_px) * float(x1 - x0 + 1) + std::abs(gy_px) * float(y1 - y0 + 1);
        const float z_ref = float(ref + double(kEps + magnitude / float(1 << 20)));
        for (int64_t py = y0; py <= y1; ++py)
            for (int64_t px = x0; px <= x1; ++px) {
                const int64_t cx = px * 256 + 128, cy = py * 256 + 128;
                bool inside = true;
                for (int k = 0; k < 3; ++k) {
                    const int a = (k + 1) % 3, b = (k + 2) % 3;
                    const int64_t ex = sx[b] - sx[a], ey = sy[b] - sy[a];
                    const int64_t e = ex * (cy - sy[a]) - ey * (cx - sx[a]);
                    // the input edge between input corners i and j: from i to i+1 or from j to j+1
                    const int i = corner[a], j = corner[b];
                    const int input_edge = (i + 1) % 3 == j ? i : j;
                    if (shared >> input_edge & 1) {
                        const bool top_left = ey < 0 || (ey == 0 && ex < 0);
                        inside = inside && (e > 0 || (e == 0 && top_left));
                    } else {
                        inside = inside && e >= 4 * (std::abs(ex) + std::abs(ey));
                    }
                }
                if (!inside) continue;
                const float d = z_ref + gy_px * float(py - y0) + gx_px * float(px - x0);
                float& out = depth[uint64_t(py) * width + px];
                out = std::min(out, d);
            }
    }
    return depth;
}

// A plane depth as written: pushed by kEps plus 2^-20 times `magnitude`, the largest corner
// |depth| plus the plane's slopes across the triangle's pixel box (depth_raster.h).
float pushed(float plane, float magnitude) { return plane + kEps * (1.0f + magnitude); }

int coveredCount(const std::vector<float>& depth) {
    return int(std::count_if(depth.begin(), depth.end(), [](float d) { return d < 1.0f; }));
}

// Window corners (0,0), (8,0), (0,8) at depths 0.25, 0.75, 0.5: the depth plane is
// 0.25 + x/16 + y/32 and the centres with px + py <= 6 are inside (28 of them); those with
// px + py = 7 lie exactly on the hypotenuse. Its pixel box is all 8 x 8, so the magnitude of
// its push is 0.75 + 8/16 + 8/32.
constexpr float kKnownMagnitude = 1.5f;
Mesh knownTriangle(const Camera& c) {
    Mesh mesh;
    mesh.add(atWindow(c, 0, 0, 0.25f), atWindow(c, 8, 0, 0.75f), atWindow(c, 0, 8, 0.5f));
    return mesh;
}

TEST_F(DepthRaster, KnownTriangleCoversCentresWithInterpolatedDepth) {
    const Camera c = identityCamera(8, 8);
    const std::vector<float> depth = rasterize(knownTriangle(c), c);
    // hand-computed plane values at a few centres
    EXPECT_NEAR(depth[0 * 8 + 0], pushed(0.296875f, kKnownMagnitude), 0.3f * kEps);  // (0.5, 0.5)
    EXPECT_NEAR(depth[3 * 8 + 2], pushed(0.515625f, kKnownMagnitude), 0.3f * kEps);  // (2.5, 3.5)
    EXPECT_NEAR(depth[0 * 8 + 6], pushed(0.671875f, kKnownMagnitude), 0.3f * kEps);  // (6.5, 0.5)
    EXPECT_NEAR(depth[6 * 8 + 0], pushed(0.484375f, kKnownMagnitude), 0.3f * kEps);  // (0.5, 6.5)
    for (uint32_t py = 0; py < 8; ++py)
        for (uint32_t px = 0; px < 8; ++px) {
            const float d = depth[py * 8 + px];
            if (px + py <= 6) {
                const float plane = 0.25f + (px + 0.5f) / 16 + (py + 0.5f) / 32;
                EXPECT_NEAR(d, pushed(plane, kKnownMagnitude), 0.3f * kEps) << px << "," << py;
                EXPECT_GE(d, plane + kEps) << "pushed away, " << px << "," << py;
            } else {
                EXPECT_EQ(d, 1.0f) << px << "," << py;
            }
        }
    EXPECT_EQ(coveredCount(depth), 28);
}

TEST_F(DepthRaster, PixelCentreOnEdgeIsNotCovered) {
    const Camera c = identityCamera(8, 8);
    // the hypotenuse of the known triangle passes through the centres with px + py = 7
    const std::vector<float> depth = rasterize(knownTriangle(c), c);
    for (uint32_t px = 0; px < 8; ++px) EXPECT_EQ(depth[(7 - px) * 8 + px], 1.0f) << px;

    // A vertical left edge at x = 2.5 - inset: column 2's centres are `inset` pixels inside.
    // Everything else of the triangle lies far outside the viewport, columns 3.. are covered.
    auto columnTwoCovered = [&](float inset) {
        Mesh mesh;
        const float x = 2.5f - inset;
        mesh.add(atWindow(c, x, -16, 0.5f), atWindow(c, 40, 4, 0.5f), atWindow(c, x, 24, 0.5f));
        const std::vector<float> d = rasterize(mesh, c);
        int column_two = 0;
        for (uint32_t py = 0; py < 8; ++py) {
            column_two += d[py * 8 + 2] < 1.0f;
            EXPECT_EQ(d[py * 8 + 1], 1.0f);
            EXPECT_LT(d[py * 8 + 3], 1.0f);
        }
        EXPECT_TRUE(column_two == 0 || column_two == 8) << inset;
        return column_two == 8;
    };
    EXPECT_FALSE(columnTwoCovered(0.0f));         // on the edge
    EXPECT_FALSE(columnTwoCovered(1.0f / 128));   // inside, but closer than the margin
    EXPECT_TRUE(columnTwoCovered(1.0f / 64));     // exactly the margin
    EXPECT_TRUE(columnTwoCovered(1.0f / 32));
}

TEST_F(DepthRaster, OverlappingTrianglesKeepTheNearerDepth) {
    const Camera c = identityCamera(8, 8);
    Mesh flat, tilted;
    flat.add(atWindow(c, -8, -8, 0.5f), atWindow(c, 24, -8, 0.5f), atWindow(c, -8, 24, 0.5f));
    // depth 0.125 + x/16 over the whole viewport: nearer than 0.5 for columns 0..5 (the push
    // magnitudes are 0.5 for the flat one, 1.5625 + 8/16 for this one)
    tilted.add(atWindow(c, -1, -8, 0.0625f), atWindow(c, 23, -8, 1.5625f), atWindow(c, -1, 40, 0.0625f));
    Mesh both = flat;
    both.add(tilted.positions[0], tilted.positions[1], tilted.positions[2]);
    Mesh reversed = tilted;
    reversed.add(flat.positions[0], flat.positions[1], flat.positions[2]);

    const std::vector<float> depth = rasterize(both, c);
    for (uint32_t py = 0; py < 8; ++py)
        for (uint32_t px = 0; px < 8; ++px) {
            const float expected = px <= 5 ? pushed(0.125f + (px + 0.5f) / 16, 2.0625f) : pushed(0.5f, 0.5f);
            EXPECT_NEAR(depth[py * 8 + px], expected, 0.3f * kEps) << px << "," << py;
        }
    EXPECT_EQ(rasterize(reversed, c), depth);
}

TEST_F(DepthRaster, TriangleCrossingNearPlaneIsSkipped) {
    const Camera c = perspectiveCamera(16, 16, 0.5f, 100.0f);
    const glm::vec3 a(-1, -1, -5), b(1, -1, -5);
    Mesh in_front, inside_near, behind_eye;
    in_front.add(a, b, glm::vec3(0, 1, -5));
    inside_near.add(a, b, glm::vec3(0, 0.01f, -0.2f));  // in front of the eye, nearer than near
    behind_eye.add(a, b, glm::vec3(0, 1, 1));
    EXPECT_GT(coveredCount(rasterize(in_front, c)), 10);
    EXPECT_EQ(coveredCount(rasterize(inside_near, c)), 0);
    EXPECT_EQ(coveredCount(rasterize(behind_eye, c)), 0);
}

// appendNearClipped (occluder_gather.h): the part of a crossing triangle in front of the near
// plane, as one or two triangles inside the original, rasters; every depth written is at or
// behind the floor's true depth through that pixel centre, so culling stays conservative.
TEST_F(DepthRaster, NearClippedPartsOfACrossingFloorRasterConservatively) {
    const Camera c = perspectiveCamera(32, 32, 0.5f, 100.0f);
    // A floor at y = -1 from 10 in front of the eye to 2 behind it (two corners in front), and a
    // strip with one corner in front.
    Mesh floor;
    floor.add(glm::vec3(-3, -1, -10), glm::vec3(3, -1, -10), glm::vec3(0, -1, 2));
    Mesh strip;
    strip.add(glm::vec3(0, -1, -6), glm::vec3(3, -1, 3), glm::vec3(-3, -1, 3));
    ASSERT_EQ(coveredCount(rasterize(floor, c)), 0);  // skipped whole without clipping
    ASSERT_EQ(coveredCount(rasterize(strip, c)), 0);
    const glm::dmat4 view_proj(c.view_proj), inverse = glm::inverse(view_proj);
    Mesh front;  // the same floor ending just beyond the near plane: nothing to clip, the same bound
    front.add(glm::vec3(-3, -1, -10), glm::vec3(3, -1, -10), glm::vec3(0, -1, -0.6f));
    for (const auto& [mesh, expected_new] : {std::pair{front, 0u}, std::pair{floor, 2u}, std::pair{strip, 1u}}) {
        OccluderGeometry g;
        g.positions = toDevice(mesh.positions);
        g.triangles = toDevice(mesh.triangles);
        g.edge_flags = toDevice(std::vector<uint8_t>(1, 0));
        g.edge_neighbours = toDevice(std::vector<uint32_t>(3, UINT32_MAX));
        g.vertex_total = 3;
        g.triangle_total = 1;
        ASSERT_EQ(appendNearClipped(g, c), expected_new);
        ASSERT_EQ(g.triangle_total, 1 + expected_new);
        Mesh clipped;
        clipped.positions = toHost(g.positions, g.vertex_total);
        clipped.triangles = toHost(g.triangles, 3 * g.triangle_total);
        const std::vector<uint8_t> flags = toHost(g.edge_flags, g.triangle_total);
        EXPECT_EQ(std::count(flags.begin() + 1, flags.end(), uint8_t(0)), std::ptrdiff_t(expected_new));
        for (size_t v = 3; v < clipped.positions.size(); ++v) {
            const glm::vec4 clip = c.view_proj * glm::vec4(clipped.positions[v], 1.0f);
            EXPECT_GT(clip.z + clip.w, 0.0f) << "new corner " << v << " is not in front of the near plane";
            EXPECT_NEAR(clipped.positions[v].y, -1.0f, 1e-5f);  // on the floor
        }
        const std::vector<float> depth = rasterize(clipped, c);
        EXPECT_GT(coveredCount(depth), 20);
        for (uint32_t py = 0; py < c.height; ++py)
            for (uint32_t px = 0; px < c.width; ++px) {
                const float d = depth[py * c.width + px];
                if (d >= 1.0f) continue;
                // The floor's depth through this pixel centre (the ray's intersection with
                // y = -1), allowing for the raster's snapping of corners to 1/256 pixel as for
                // any triangle: the least of it over centres moved by 1/256 pixel.
                double truth = 2;
                for (const double oy : {-1.0 / 256, 0.0, 1.0 / 256})
                    for (const double ox : {-1.0 / 256, 0.0, 1.0 / 256}) {
                        const double x = (px + 0.5 + ox) / c.width * 2 - 1, y = (py + 0.5 + oy) / c.height * 2 - 1;
                        const glm::dvec4 n4 = inverse * glm::dvec4(x, y, -1, 1), f4 = inverse * glm::dvec4(x, y, 1, 1);
                        const glm::dvec3 n = glm::dvec3(n4) / n4.w, f = glm::dvec3(f4) / f4.w;
                        ASSERT_LT(f.y, n.y) << "a covered pixel whose ray does not go down to the floor";
                        const double t = (-1.0 - n.y) / (f.y - n.y);
                        const glm::dvec4 hit = view_proj * glm::dvec4(n + t * (f - n), 1.0);
                        truth = std::min(truth, hit.z / hit.w * 0.5 + 0.5);
                    }
                EXPECT_GE(double(d), truth - 1e-6) << "pixel " << px << "," << py << " written nearer than the floor";
            }
    }
}

TEST_F(DepthRaster, BothWindingsDrawTheSame) {
    const Camera c = identityCamera(8, 8);
    const Mesh forward = knownTriangle(c);
    Mesh backward;
    backward.add(forward.positions[0], forward.positions[2], forward.positions[1]);
    const std::vector<float> depth = rasterize(forward, c);
    EXPECT_EQ(coveredCount(depth), 28);
    EXPECT_EQ(rasterize(backward, c), depth);
}

TEST_F(DepthRaster, TriangleLargerThanScreenCoversEveryPixel) {
    const Camera c = perspectiveCamera(70, 50);
    Mesh wall;  // facing the camera at distance 10, its edges thousands of pixels off screen
    wall.add(glm::vec3(-1000, -1000, -10), glm::vec3(3000, -1000, -10), glm::vec3(-1000, 3000, -10));
    const std::vector<float> depth = rasterize(wall, c);
    const glm::vec4 clip = c.view_proj * glm::vec4(0, 0, -10, 1);
    const float wall_depth = clip.z / clip.w * 0.5f + 0.5f;
    for (float d : depth) ASSERT_NEAR(d, pushed(wall_depth, wall_depth), 0.5f * kEps);
    EXPECT_EQ(depth, referenceRaster(wall, c));
}

// Vertex indices of an (nx + 1) x (ny + 1) grid of nx x ny quads, each split into two
// counter-clockwise triangles (when the grid's x and y run right and up), along alternating
// diagonals when `alternate` so that both directions of shared diagonal are drawn.
std::vector<uint32_t> gridTriangles(uint32_t nx, uint32_t ny, bool alternate) {
    std::vector<uint32_t> triangles;
    for (uint32_t j = 0; j < ny; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            const uint32_t a = j * (nx + 1) + i, b = a + 1, d = a + nx + 1, e = d + 1;  // d e above a b
            if (alternate && (i + j) % 2) {
                triangles.insert(triangles.end(), {a, b, d, b, e, d});
            } else {
                triangles.insert(triangles.end(), {a, b, e, a, e, d});
            }
        }
    return triangles;
}

// A square wall of n x n quads (side `side`, centred on the origin in the xy plane) placed by
// `place`.
Mesh wall(uint32_t n, float side, const glm::mat4& place, bool alternate) {
    Mesh mesh;
    for (uint32_t j = 0; j <= n; ++j)
        for (uint32_t i = 0; i <= n; ++i) {
            const glm::vec4 p(side * (float(i) / n - 0.5f), side * (float(j) / n - 0.5f), 0, 1);
            mesh.positions.push_back(glm::vec3(place * p));
        }
    mesh.triangles = gridTriangles(n, n, alternate);
    return mesh;
}

// How many pixels each triangle of the mesh covers on its own, with its own flags: tells
// exactly which triangle covers which centre, even where they have the same depth.
std::vector<int> coverageCounts(const Mesh& mesh, const Camera& c, const std::vector<uint8_t>& flags) {
    std::vector<int> counts(uint64_t(c.width) * c.height, 0);
    DepthRasterScratch scratch;
    for (uint32_t t = 0; t < mesh.triangleCount(); ++t) {
        Mesh one{mesh.positions, {mesh.triangles.begin() + 3 * t, mesh.triangles.begin() + 3 * t + 3}};
        const std::vector<float> depth = rasterize(one, c, scratch, {flags[t]});
        for (size_t i = 0; i < depth.size(); ++i) counts[i] += depth[i] < 1.0f;
    }
    return counts;
}

TEST(SharedEdgeFlags, QuadDiagonalIsSharedOuterEdgesAreNot) {
    // 0 -> 1 -> 2 and 0 -> 2 -> 3: the diagonal is edge 2 (2 -> 0) of the first triangle and
    // edge 0 (0 -> 2) of the second
    EXPECT_EQ(sharedFlags({0, 1, 2, 0, 2, 3}), (std::vector<uint8_t>{4, 1}));
    // the same quad with its triangles rotated and given in the other order
    EXPECT_EQ(sharedFlags({2, 3, 0, 1, 2, 0}), (std::vector<uint8_t>{4, 2}));
}

TEST(SharedEdgeFlags, ClosedTetrahedronSharesEveryEdge) {
    EXPECT_EQ(sharedFlags({0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}), (std::vector<uint8_t>{7, 7, 7, 7}));
}

TEST(SharedEdgeFlags, EdgeOfThreeTrianglesIsNotShared) {
    // 0-1 is used by all three (0 -> 1, 1 -> 0, 1 -> 0); 1-2 only by the first
    EXPECT_EQ(sharedFlags({0, 1, 2, 1, 0, 3, 1, 0, 4}), (std::vector<uint8_t>{0, 0, 0}));
    // and by four, two in each direction
    EXPECT_EQ(sharedFlags({0, 1, 2, 1, 0, 3, 0, 1, 4, 1, 0, 5}), (std::vector<uint8_t>{0, 0, 0, 0}));
}

TEST(SharedEdgeFlags, SameDirectionDuplicateIsNotShared) {
    EXPECT_EQ(sharedFlags({0, 1, 2, 0, 1, 3}), (std::vector<uint8_t>{0, 0}));
    // a triangle given twice: every edge twice in the same direction
    EXPECT_EQ(sharedFlags({4, 5, 6, 5, 6, 4}), (std::vector<uint8_t>{0, 0}));
}

TEST(SharedEdgeFlags, DegenerateEdgesAreNotShared) {
    // 0 -> 1 -> 0 uses 0-1 both ways, but it is one triangle; 0 -> 0 is no edge
    EXPECT_EQ(sharedFlags({0, 1, 0}), (std::vector<uint8_t>{0}));
    EXPECT_EQ(sharedFlags({3, 3, 3, 3, 3, 3}), (std::vector<uint8_t>{0, 0}));
    EXPECT_TRUE(sharedFlags(std::vector<uint32_t>{}).empty());
}

TEST(SharedEdgeFlags, GridSharesExactlyItsInteriorEdges) {
    for (bool alternate : {false, true}) {
        const uint32_t nx = 7, ny = 4;
        const std::vector<uint8_t> flags = sharedFlags(gridTriangles(nx, ny, alternate));
        int bits = 0;
        for (uint8_t f : flags) bits += std::popcount(f);
        // diagonals, then the edges between rows, then those between columns, each twice
        EXPECT_EQ(bits, 2 * int(nx * ny + nx * (ny - 1) + (nx - 1) * ny)) << alternate;
        // the first quad's two triangles: two outer edges, the diagonal, and two inner edges
        EXPECT_EQ(std::popcount(flags[0]) + std::popcount(flags[1]), 4) << alternate;
    }
}

// Without flags the margin applies to every edge, shared or not: centres on the diagonal that
// splits a quad into two triangles belong to neither and stay far. With them the diagonal is
// exact: each of its centres belongs to exactly one of the two triangles.
TEST_F(DepthRaster, CentresOnSharedEdgeStayFarOnlyWithoutFlags) {
    const Camera c = perspectiveCamera(70, 50);
    Mesh quad;  // its diagonal projects to y - 25 = x - 35, through the centres with py = px - 10
    quad.positions = {glm::vec3(-1000, -1000, -10), glm::vec3(1000, -1000, -10), glm::vec3(1000, 1000, -10),
                      glm::vec3(-1000, 1000, -10)};
    quad.triangles = {0, 1, 2, 0, 2, 3};
    const std::vector<float> depth = rasterize(quad, c);
    for (uint32_t py = 0; py < 50; ++py)
        for (uint32_t px = 0; px < 70; ++px) {
            if (px == py + 10) {
                EXPECT_EQ(depth[py * 70 + px], 1.0f) << px << "," << py;
            } else {
                EXPECT_LT(depth[py * 70 + px], 1.0f) << px << "," << py;
            }
        }

    const std::vector<uint8_t> flags = sharedFlags(quad);
    ASSERT_EQ(flags, (std::vector<uint8_t>{4, 1}));
    EXPECT_EQ(coveredCount(rasterize(quad, c, flags)), 70 * 50);
    const std::vector<int> counts = coverageCounts(quad, c, flags);
    EXPECT_TRUE(std::all_of(counts.begin(), counts.end(), [](int n) { return n == 1; }));
}

// The triangles across each edge let the raster tell a shared edge inside the image from a fold
// (both triangles on the same side of it on screen, as at a silhouette), which keeps the margin.
std::vector<float> rasterizeWithNeighbours(const Mesh& mesh, const Camera& camera) {
    std::vector<uint8_t> flags(mesh.triangleCount());
    std::vector<uint32_t> across(3 * flags.size());
    sharedEdgeFlags(mesh.triangles.data(), mesh.triangleCount(), flags.data(), across.data());
    DepthRasterScratch scratch;
    return rasterize(mesh, camera, scratch, flags, across);
}

TEST_F(DepthRaster, FoldedSharedEdgeKeepsTheMarginInteriorOneDoesNot) {
    const Camera c = identityCamera(16, 12);
    // Edge A-B lies exactly on the centres of row 4 (y = 4.5). Both triangles below it: a fold,
    // whose top-left tie would cover those centres; one below and one above: an interior edge.
    const glm::vec3 a = atWindow(c, 2, 4.5f, 0.5f), b = atWindow(c, 14, 4.5f, 0.5f);
    for (const bool folded : {true, false}) {
        Mesh mesh;
        mesh.positions = {a, b, atWindow(c, 8, 0.2f, 0.5f), atWindow(c, 8, folded ? 1.2f : 9.5f, 0.5f)};
        mesh.triangles = {0, 1, 2, 1, 0, 3};  // the edge used in opposite directions: shared
        ASSERT_EQ(sharedFlags(mesh), (std::vector<uint8_t>{1, 1}));
        const std::vector<float> tie = rasterize(mesh, c, sharedFlags(mesh));
        const std::vector<float> told = rasterizeWithNeighbours(mesh, c);
        for (uint32_t px = 3; px <= 13; ++px) {
            EXPECT_LT(tie[4 * 16 + px], 1.0f) << "flags alone: the tie rule covers " << px << ",4";
            if (folded) {
                EXPECT_EQ(told[4 * 16 + px], 1.0f) << "fold: centre " << px << ",4 on the silhouette covered";
            } else {
                EXPECT_EQ(told[4 * 16 + px], tie[4 * 16 + px]) << "interior edge: " << px << ",4";
            }
        }
    }
}

TEST(SharedEdgeFlags, NeighboursNameTheTriangleAcrossEachSharedEdge) {
    const std::vector<uint32_t> quad = {0, 1, 2, 0, 2, 3};
    std::vector<uint8_t> flags(2);
    std::vector<uint32_t> across(6, 7);
    sharedEdgeFlags(quad.data(), 2, flags.data(), across.data());
    EXPECT_EQ(across, (std::vector<uint32_t>{UINT32_MAX, UINT32_MAX, 1, 0, UINT32_MAX, UINT32_MAX}));
}

// Which of the two triangles gets the centres exactly on their shared edge: the one for which
// it is a left or top edge, counter-clockwise, whatever the winding of the input.
TEST_F(DepthRaster, CentresOnSharedEdgeGoToTheTriangleWhoseLeftOrTopEdgeItIs) {
    const Camera c = identityCamera(8, 8);
    // diagonal from (-8, -8) to (16, 16), exactly through the centres with px = py
    const glm::vec3 bl = atWindow(c, -8, -8, 0.5f), br = atWindow(c, 16, -8, 0.5f), tr = atWindow(c, 16, 16, 0.5f),
                    tl = atWindow(c, -8, 16, 0.5f);
    for (bool clockwise : {false, true}) {
        Mesh quad;
        quad.positions = {bl, br, tr, tl};
        // In the lower-right triangle, counter-clockwise, the diagonal runs down-left (its left
        // edge); in the upper-left one up-right (a right edge).
        quad.triangles = clockwise ? std::vector<uint32_t>{0, 2, 1, 0, 3, 2} : std::vector<uint32_t>{0, 1, 2, 0, 2, 3};
        const std::vector<uint8_t> flags = sharedFlags(quad);
        const Mesh lower{quad.positions, {quad.triangles.begin(), quad.triangles.begin() + 3}};
        const Mesh upper{quad.positions, {quad.triangles.begin() + 3, quad.triangles.end()}};
        const std::vector<float> lower_depth = rasterize(lower, c, {flags[0]});
        const std::vector<float> upper_depth = rasterize(upper, c, {flags[1]});
        for (uint32_t p = 0; p < 8; ++p) {
            EXPECT_LT(lower_depth[p * 8 + p], 1.0f) << p << " " << clockwise;
            EXPECT_EQ(upper_depth[p * 8 + p], 1.0f) << p << " " << clockwise;
        }
        // and without flags neither
        EXPECT_EQ(rasterize(lower, c)[9], 1.0f);
    }
    // A horizontal shared edge at y = 3.5 belongs to the triangle below it, for which it runs
    // left (a top edge).
    Mesh strip;
    strip.positions = {atWindow(c, -8, -8, 0.5f), atWindow(c, 16, -8, 0.5f), atWindow(c, 16, 3.5f, 0.5f),
                       atWindow(c, -8, 3.5f, 0.5f), atWindow(c, 4, 16, 0.5f)};
    strip.triangles = {0, 1, 2, 0, 2, 3, 3, 2, 4};
    const std::vector<uint8_t> flags = sharedFlags(strip);
    ASSERT_EQ(flags, (std::vector<uint8_t>{4, 3, 1}));
    const std::vector<int> below = coverageCounts(Mesh{strip.positions, {0, 1, 2, 0, 2, 3}}, c, {4, 3});
    const std::vector<float> above = rasterize(Mesh{strip.positions, {3, 2, 4}}, c, {1});
    for (uint32_t px = 0; px < 8; ++px) {
        EXPECT_EQ(below[3 * 8 + px], 1) << px;
        EXPECT_EQ(above[3 * 8 + px], 1.0f) << px;
        EXPECT_LT(above[4 * 8 + px], 1.0f) << px;
    }
}

// Corners on the half-pixel grid, so that many centres lie exactly on shared edges and exactly
// on shared corners: the top-left rule gives each of them to exactly one triangle, whichever
// way the diagonals run and whichever winding the triangles have.
TEST_F(DepthRaster, SharedEdgesAndCornersCoverEachCentreExactlyOnce) {
    const Camera c = identityCamera(48, 40);
    std::mt19937 rng(5);
    std::uniform_int_distribution<int> jitter(-2, 2);
    for (bool alternate : {false, true})
        for (bool mirrored : {false, true}) {
            Mesh mesh;
            const uint32_t n = 8;
            for (uint32_t j = 0; j <= n; ++j)
                for (uint32_t i = 0; i <= n; ++i) {
                    // a 64 x 56 pixel grid around the viewport, corners moved by up to one pixel
                    float x = -8.0f + 8.0f * i + 0.5f * jitter(rng), y = -8.0f + 7.0f * j + 0.5f * jitter(rng);
                    if (mirrored) x = 48.0f - x;
                    mesh.positions.push_back(atWindow(c, x, y, 0.5f + 0.01f * float(i + j)));
                }
            mesh.triangles = gridTriangles(n, n, alternate);
            const std::vector<uint8_t> flags = sharedFlags(mesh);
            const std::vector<int> counts = coverageCounts(mesh, c, flags);
            for (uint32_t py = 0; py < c.height; ++py)
                for (uint32_t px = 0; px < c.width; ++px)
                    ASSERT_EQ(counts[py * c.width + px], 1) << px << "," << py << " " << alternate << mirrored;
            EXPECT_EQ(rasterize(mesh, c, flags), referenceRaster(mesh, c, flags));
        }
}

// The max-pyramid spreads every far pixel upwards: with the margin on shared edges, the cracks of
// a tessellated wall that fills the screen turn its coarse levels far; with flags, no level has
// a far texel.
TEST_F(DepthRaster, TessellatedWallHasNoCracksAtAnyHzmLevel) {
    const Camera c = perspectiveCamera(160, 128);
    // 20 x 20 quads of about 12 pixels, turned a little about every axis so that its edges run
    // at odd slopes through the pixel grid
    const glm::mat4 place = glm::rotate(glm::rotate(glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, -10)),
                                                                0.13f, glm::vec3(0, 0, 1)),
                                                    0.2f, glm::vec3(0, 1, 0)),
                                        0.1f, glm::vec3(1, 0, 0));
    HzmLevels layout;
    hzmLayout(c.width, c.height, layout);
    const uint32_t levels = layout.level_count;
    auto farShares = [&](const Mesh& mesh, const std::vector<uint8_t>& flags) {
        std::vector<float> pyramid = rasterize(mesh, c, flags);
        pyramid.resize(size_t(hzmTotalTexels(c.width, c.height)));
        DeviceArray<float> pyramid_d = toDevice(pyramid);
        hzmBuild(pyramid_d.ptr(), c.width, c.height);
        pyramid = toHost(pyramid_d);
        std::vector<double> shares;
        for (uint32_t l = 0; l < levels; ++l) {
            const float* level = pyramid.data() + layout.offset[l];
            const uint64_t texels = uint64_t(layout.width[l]) * layout.height[l];
            shares.push_back(double(std::count(level, level + texels, 1.0f)) / double(texels));
        }
        return shares;
    };
    for (bool alternate : {false, true}) {
        const Mesh mesh = wall(20, 22.0f, place, alternate);
        const std::vector<double> with_flags = farShares(mesh, sharedFlags(mesh));
        for (uint32_t l = 0; l < levels; ++l) EXPECT_EQ(with_flags[l], 0.0) << "level " << l << " " << alternate;
        // null flags: the margin on every edge, as before
        const std::vector<double> without = farShares(mesh, {});
        EXPECT_GT(without[0], 0.005) << alternate;
        EXPECT_GT(without[3], 0.3) << alternate;
        EXPECT_GT(without[4], 0.9) << alternate;
        EXPECT_EQ(without[levels - 1], 1.0) << alternate;
    }
}

// A wall that does not fill the screen: every texel of every level whose pixels all lie in the
// wall, its boundary margin included, stays near.
TEST_F(DepthRaster, TessellatedWallIsNearEverywhereInsideItsSilhouette) {
    const Camera c = identityCamera(128, 96);
    // a 20 x 20 quad wall turned by 0.1 radian about its centre (64, 48), 80 pixels on a side
    const glm::mat4 place = glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(64, 48, 0)), 0.1f, glm::vec3(0, 0, 1));
    Mesh mesh = wall(20, 80.0f, place, true);
    for (glm::vec3& p : mesh.positions) p = atWindow(c, p.x, p.y, 0.4f + p.x / 1024.0f);
    const std::vector<uint8_t> flags = sharedFlags(mesh);
    const std::vector<float> depth = rasterize(mesh, c, flags);
    EXPECT_EQ(depth, referenceRaster(mesh, c, flags));
    std::vector<float> pyramid = depth;
    pyramid.resize(size_t(hzmTotalTexels(c.width, c.height)));
    DeviceArray<float> pyramid_d = toDevice(pyramid);
    hzmBuild(pyramid_d.ptr(), c.width, c.height);
    pyramid = toHost(pyramid_d);
    HzmLevels layout;
    hzmLayout(c.width, c.height, layout);
    // inside the wall: the centre rotated back into the wall's frame lies 1/16 pixel inside
    const float half = 40.0f - 1.0f / 16, cos_a = std::cos(0.1f), sin_a = std::sin(0.1f);
    auto inside = [&](float x, float y) {
        const float dx = x - 64, dy = y - 48;
        return std::abs(cos_a * dx + sin_a * dy) < half && std::abs(-sin_a * dx + cos_a * dy) < half;
    };
    int near_texels[3] = {0, 0, 0};
    for (uint32_t l = 0; l < layout.level_count; ++l) {
        const uint32_t size = 1u << l;  // pixels per texel side (the last odd ones fold in: skipped)
        for (uint32_t ty = 0; ty < layout.height[l]; ++ty)
            for (uint32_t tx = 0; tx < layout.width[l]; ++tx) {
                const uint32_t x0 = tx * size, y0 = ty * size;
                if (x0 + size > c.width || y0 + size > c.height) continue;
                // the texel's corner centres inside a convex wall: all of its centres are
                if (!inside(x0 + 0.5f, y0 + 0.5f) || !inside(x0 + size - 0.5f, y0 + 0.5f) ||
                    !inside(x0 + 0.5f, y0 + size - 0.5f) || !inside(x0 + size - 0.5f, y0 + size - 0.5f))
                    continue;
                EXPECT_LT(pyramid[layout.offset[l] + ty * layout.width[l] + tx], 1.0f)
                    << "level " << l << " texel " << tx << "," << ty;
                if (l < 3) ++near_texels[l];
            }
    }
    EXPECT_GT(near_texels[0], 5000);
    EXPECT_GT(near_texels[2], 300);
}

// Flags leave the boundary alone: the margin still holds on an outer edge of a quad whose
// diagonal is shared (the test above for one triangle, now for a flagged pair).
TEST_F(DepthRaster, BoundaryEdgesKeepTheMarginWithSharedEdges) {
    const Camera c = identityCamera(8, 8);
    auto columnTwoCovered = [&](float inset) {
        // left edge at x = 2.5 - inset from y = -16 to 24, the rest far off screen
        const float x = 2.5f - inset;
        Mesh quad;
        quad.positions = {atWindow(c, x, -16, 0.5f), atWindow(c, 40, -16, 0.5f), atWindow(c, 40, 24, 0.5f),
                          atWindow(c, x, 24, 0.5f)};
        quad.triangles = {0, 1, 2, 0, 2, 3};
        const std::vector<uint8_t> flags = sharedFlags(quad);
        EXPECT_EQ(flags, (std::vector<uint8_t>{4, 1}));
        const std::vector<float> d = rasterize(quad, c, flags);
        EXPECT_EQ(d, referenceRaster(quad, c, flags));
        int column_two = 0;
        for (uint32_t py = 0; py < 8; ++py) {
            column_two += d[py * 8 + 2] < 1.0f;
            EXPECT_EQ(d[py * 8 + 1], 1.0f);
            for (uint32_t px = 3; px < 8; ++px) EXPECT_LT(d[py * 8 + px], 1.0f) << px << "," << py;
        }
        EXPECT_TRUE(column_two == 0 || column_two == 8) << inset;
        return column_two == 8;
    };
    EXPECT_FALSE(columnTwoCovered(0.0f));        // on the edge
    EXPECT_FALSE(columnTwoCovered(1.0f / 128));  // inside, but closer than the margin
    EXPECT_TRUE(columnTwoCovered(1.0f / 64));    // exactly the margin
}

TEST_F(DepthRaster, CornerOutsideGuardBandOrTooDeepSkipsTriangle) {
    const Camera c = identityCamera(8, 8);
    Mesh wide, deep, control;
    wide.add(atWindow(c, -8, -8, 0.5f), atWindow(c, 2 * kDepthRasterGuardBand, -8, 0.5f), atWindow(c, -8, 24, 0.5f));
    deep.add(atWindow(c, -8, -8, 0.5f), atWindow(c, 24, -8, 2.5f), atWindow(c, -8, 24, 0.5f));
    control.add(atWindow(c, -8, -8, 0.5f), atWindow(c, 24, -8, 1.5f), atWindow(c, -8, 24, 0.5f));
    EXPECT_EQ(coveredCount(rasterize(wide, c)), 0);
    EXPECT_EQ(coveredCount(rasterize(deep, c)), 0);
    EXPECT_EQ(coveredCount(rasterize(control, c)), 64);
}

TEST_F(DepthRaster, NoTrianglesClearsToFar) {
    const Camera c = identityCamera(40, 33);
    const std::vector<float> depth = rasterize(Mesh{}, c);
    EXPECT_TRUE(std::all_of(depth.begin(), depth.end(), [](float d) { return d == 1.0f; }));
}

// One small triangle around each pixel centre of a 128 x 128 viewport, each at its own depth:
// 16384 triangles, so several binning chunks, and losing any one triangle leaves a pixel far.
TEST_F(DepthRaster, EveryTriangleOfALargeSceneLands) {
    const Camera c = identityCamera(128, 128);
    Mesh mesh;
    std::vector<float> expected;
    for (uint32_t py = 0; py < 128; ++py)
        for (uint32_t px = 0; px < 128; ++px) {
            const float x = px + 0.5f, y = py + 0.5f, d = float(py * 128 + px) / 32768.0f + 0.25f;
            mesh.add(atWindow(c, x - 0.25f, y - 0.25f, d), atWindow(c, x + 0.5f, y - 0.25f, d),
                     atWindow(c, x - 0.25f, y + 0.5f, d));
            expected.push_back(d);
        }
    const std::vector<float> depth = rasterize(mesh, c);
    for (uint32_t i = 0; i < expected.size(); ++i)
        ASSERT_NEAR(depth[i], pushed(expected[i], expected[i]), 0.3f * kEps) << i;
}

TEST_F(DepthRaster, ViewportBeyondLimitIsRejected) {
    DepthRasterScratch scratch;
    EXPECT_THROW(depthRaster(nullptr, nullptr, 0, nullptr, nullptr, identityCamera(32769, 1), nullptr, scratch),
                 std::invalid_argument);
}

// The push must outweigh the rounding of the float plane evaluation for every triangle, the
// steep ones especially: one random triangle at a time (corners on the 1/256 grid, so snapping
// changes nothing), every covered centre at least kEps behind the exact plane through them.
TEST_F(DepthRaster, PushedDepthIsNeverNearerThanTheTriangle) {
    const Camera c = identityCamera(64, 64);
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> units(-64 * 256, 128 * 256);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f);
    DepthRasterScratch scratch;
    int covered = 0;
    for (int t = 0; t < 1500; ++t) {
        long double x[3], y[3], z[3];
        Mesh mesh;
        glm::vec3 corners[3];
        const float spread = t % 3 == 0 ? 1.0f : t % 3 == 1 ? 1e-3f : 1e-6f;  // steep to flat
        const float base = unit(rng);
        for (int i = 0; i < 3; ++i) {
            x[i] = units(rng) / 256.0L, y[i] = units(rng) / 256.0L;
            corners[i] = atWindow(c, float(x[i]), float(y[i]), base + spread * unit(rng));
            z[i] = corners[i].z * 0.5f + 0.5f;  // the depth the raster sees (the round trip rounds)
        }
        mesh.add(corners[0], corners[1], corners[2]);
        const std::vector<float> depth = rasterize(mesh, c, scratch);
        const long double area = (x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]);
        for (uint32_t py = 0; py < 64; ++py)
            for (uint32_t px = 0; px < 64; ++px) {
                if (depth[py * 64 + px] >= 1.0f) continue;
                ++covered;
                const long double cx = px + 0.5L, cy = py + 0.5L;
                const long double b0 = ((x[1] - cx) * (y[2] - cy) - (y[1] - cy) * (x[2] - cx)) / area;
                const long double b1 = ((x[2] - cx) * (y[0] - cy) - (y[2] - cy) * (x[0] - cx)) / area;
                const long double plane = b0 * z[0] + b1 * z[1] + (1 - b0 - b1) * z[2];
                ASSERT_GE(depth[py * 64 + px], plane + 0.999L * kEps)
                    << "triangle " << t << " pixel " << px << "," << py;
            }
    }
    EXPECT_GT(covered, 10000);
}

// Corners on the half-pixel grid under the identity camera, so that many pixel centres lie
// exactly on edges and at exactly the margin.
Mesh gridScene(std::mt19937& rng, const Camera& c, uint32_t triangle_count) {
    std::uniform_int_distribution<int> half_pixel(-8, 2 * int(c.width) + 8);
    std::uniform_int_distribution<int> step(0, 255);
    Mesh mesh;
    for (uint32_t t = 0; t < triangle_count; ++t) {
        auto corner = [&] {
            const float x = half_pixel(rng) * 0.5f + (step(rng) < 64 ? 1.0f / 64 : 0.0f);
            return atWindow(c, x, half_pixel(rng) * 0.5f, step(rng) / 256.0f);
        };
        mesh.add(corner(), corner(), corner());
    }
    return mesh;
}

// Flat triangles all at (nearly) one depth: a tile may pass over a triangle only when none of
// its pixels could get nearer, which rounding at equal depths puts to the test.
Mesh coplanarScene(std::mt19937& rng, const Camera& c, uint32_t triangle_count) {
    std::uniform_real_distribution<float> window(-4.0f, float(c.width) + 4.0f);
    std::uniform_int_distribution<int> ulps(-2, 2);
    Mesh mesh;
    for (uint32_t t = 0; t < triangle_count; ++t) {
        const float depth = std::nextafter(0.7f, ulps(rng) < 0 ? 0.0f : 1.0f);
        auto corner = [&] { return atWindow(c, window(rng), window(rng), ulps(rng) == 0 ? 0.7f : depth); };
        mesh.add(corner(), corner(), corner());
    }
    return mesh;
}

void append(Mesh& into, const Mesh& piece) {
    const uint32_t base = uint32_t(into.positions.size());
    into.positions.insert(into.positions.end(), piece.positions.begin(), piece.positions.end());
    for (uint32_t i : piece.triangles) into.triangles.push_back(base + i);
}

// Random indexed meshes in front of (and around, and behind) the perspective camera: grids of
// every size, bumpy enough that some fold over on screen, and fans, some closed. A few
// triangles are turned round or given twice, so that edges used in the same direction or by
// three triangles are there too.
Mesh randomSharedScene(std::mt19937& rng, uint32_t piece_count) {
    std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
    std::uniform_real_distribution<float> angle(0.0f, 6.2831853f);
    std::uniform_real_distribution<float> log_size(std::log(0.02f), std::log(40.0f));
    std::uniform_real_distribution<float> distance(-2.0f, 60.0f);
    std::uniform_int_distribution<int> cells(1, 16), rim(3, 12), percent(0, 99);
    Mesh scene;
    for (uint32_t p = 0; p < piece_count; ++p) {
        const float z = -distance(rng);
        const glm::vec3 centre(unit(rng) * (0.7f * std::abs(z) + 1.0f), unit(rng) * (0.6f * std::abs(z) + 1.0f), z);
        const float size = std::exp(log_size(rng));
        const glm::mat4 place = glm::rotate(glm::translate(glm::mat4(1.0f), centre), angle(rng),
                                            glm::normalize(glm::vec3(unit(rng), unit(rng), unit(rng)) + 0.01f));
        Mesh piece;
        if (p % 3 != 2) {
            const uint32_t nx = uint32_t(cells(rng)), ny = uint32_t(cells(rng));
            const float bump = percent(rng) < 50 ? 0.0f : 0.5f * size / float(std::max(nx, ny));
            for (uint32_t j = 0; j <= ny; ++j)
                for (uint32_t i = 0; i <= nx; ++i) {
                    const glm::vec4 local(size * (float(i) / nx - 0.5f), size * (float(j) / ny - 0.5f), bump * unit(rng), 1);
                    piece.positions.push_back(glm::vec3(place * local));
                }
            piece.triangles = gridTriangles(nx, ny, percent(rng) < 50);
        } else {
            const uint32_t n = uint32_t(rim(rng));
            const bool closed = percent(rng) < 70;
            piece.positions.push_back(glm::vec3(place * glm::vec4(0, 0, 0.2f * size * unit(rng), 1)));
            for (uint32_t i = 0; i < n; ++i) {
                const float a = 6.2831853f * (float(i) + 0.3f * unit(rng)) / float(n);
                const float r = size * (0.5f + 0.4f * unit(rng));
                piece.positions.push_back(glm::vec3(place * glm::vec4(r * std::cos(a), r * std::sin(a), 0.2f * size * unit(rng), 1)));
            }
            for (uint32_t i = 0; i < (closed ? n : n - 1); ++i)
                piece.triangles.insert(piece.triangles.end(), {0, 1 + i, 1 + (i + 1) % n});
        }
        const size_t corners = piece.triangles.size();
        for (size_t t = 0; t < corners; t += 3) {
            const int roll = percent(rng);
            if (roll < 3) std::swap(piece.triangles[t + 1], piece.triangles[t + 2]);
            if (roll >= 97) {
                const uint32_t again[3] = {piece.triangles[t], piece.triangles[t + 1], piece.triangles[t + 2]};
                piece.triangles.insert(piece.triangles.end(), again, again + 3);
            }
        }
        append(scene, piece);
    }
    return scene;
}

// Grids whose corners sit on the half-pixel grid under the identity camera, so that centres lie
// exactly on shared edges and corners, and exactly at the margin of boundary ones.
Mesh gridOnHalfPixels(std::mt19937& rng, const Camera& c, uint32_t piece_count) {
    std::uniform_int_distribution<int> half_pixel(-8, 2 * int(c.width) + 8), cells(1, 6), step(1, 12), percent(0, 99);
    Mesh scene;
    for (uint32_t p = 0; p < piece_count; ++p) {
        const uint32_t nx = uint32_t(cells(rng)), ny = uint32_t(cells(rng));
        const int x0 = half_pixel(rng), y0 = half_pixel(rng), dx = step(rng), dy = step(rng), shear = step(rng) - 6;
        Mesh piece;
        for (uint32_t j = 0; j <= ny; ++j)
            for (uint32_t i = 0; i <= nx; ++i) {
                const float x = 0.5f * float(x0 + int(i) * dx + int(j) * shear) + (percent(rng) < 20 ? 1.0f / 64 : 0.0f);
                const float y = 0.5f * float(y0 + int(j) * dy);
                piece.positions.push_back(atWindow(c, x, y, float(percent(rng) + 100) / 256.0f));
            }
        piece.triangles = gridTriangles(nx, ny, percent(rng) < 50);
        append(scene, piece);
    }
    return scene;
}

TEST_F(DepthRaster, RandomMeshesWithSharedEdgesMatchScalarReferenceBitForBit) {
    std::mt19937 rng(17);
    DepthRasterScratch scratch;
    const uint32_t sizes[][3] = {{77, 45, 60}, {256, 256, 400}, {31, 97, 90}, {512, 384, 150}};
    uint64_t shared_bits = 0, covered = 0;
    for (const auto& size : sizes) {
        const Camera c = perspectiveCamera(size[0], size[1]);
        const Mesh mesh = randomSharedScene(rng, size[2]);
        const std::vector<uint8_t> flags = sharedFlags(mesh);
        for (uint8_t f : flags) shared_bits += std::popcount(f);
        const std::vector<float> depth = rasterize(mesh, c, scratch, flags);
        EXPECT_EQ(depth, referenceRaster(mesh, c, flags)) << size[0] << "x" << size[1];
        covered += coveredCount(depth);
        // null flags still draw the old rules
        EXPECT_EQ(rasterize(mesh, c, scratch), referenceRaster(mesh, c)) << size[0] << "x" << size[1];
    }
    EXPECT_GT(shared_bits, 20000u);
    EXPECT_GT(covered, 50000u);
    for (uint32_t w : {8u, 33u, 64u}) {
        const Camera c = identityCamera(w, w);
        const Mesh grid = gridOnHalfPixels(rng, c, 40);
        const std::vector<uint8_t> flags = sharedFlags(grid);
        EXPECT_EQ(rasterize(grid, c, scratch, flags), referenceRaster(grid, c, flags)) << w;
    }
}

TEST_F(DepthRaster, RandomScenesMatchScalarReferenceBitForBit) {
    std::mt19937 rng(7);
    DepthRasterScratch scratch;  // one scratch across sizes: reuse and growth
    const uint32_t sizes[][3] = {{77, 45, 3000}, {256, 256, 20000}, {31, 97, 4097}, {512, 512, 5000}, {1, 1, 100}};
    for (const auto& size : sizes) {
        const Camera c = perspectiveCamera(size[0], size[1]);
        const Mesh mesh = randomScene(rng, size[2]);
        const std::vector<float> depth = rasterize(mesh, c, scratch);
        EXPECT_EQ(depth, referenceRaster(mesh, c)) << size[0] << "x" << size[1];
        if (size[2] > 1000) {
            EXPECT_GT(coveredCount(depth), 0);
        }
    }
    for (uint32_t w : {8u, 33u}) {
        const Camera c = identityCamera(w, w);
        const Mesh grid = gridScene(rng, c, 400);
        EXPECT_EQ(rasterize(grid, c, scratch), referenceRaster(grid, c)) << w;
        const Mesh coplanar = coplanarScene(rng, c, 300);
        EXPECT_EQ(rasterize(coplanar, c, scratch), referenceRaster(coplanar, c)) << w;
    }
}

// Seams between occluders: every triangle of a tessellated wall on vertices of its own (as the
// wall's quads would be if each were another object), rastered with seams, is the welded wall
// rastered with its shared edges, bit for bit; without seams the copies leave cracks.
TEST_F(DepthRaster, SeamsBetweenAbuttingOccludersRasterAsOneMesh) {
    const Camera c = perspectiveCamera(160, 128);
    const glm::mat4 place = glm::rotate(glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(0, 0, -10)), 0.13f,
                                                    glm::vec3(0, 0, 1)),
                                        0.2f, glm::vec3(0, 1, 0));
    for (bool alternate : {false, true}) {
        const Mesh welded = wall(20, 22.0f, place, alternate);
        std::vector<uint8_t> flags(welded.triangleCount());
        std::vector<uint32_t> across(3 * flags.size());
        sharedEdgeFlags(welded.triangles.data(), welded.triangleCount(), flags.data(), across.data());
        DepthRasterScratch scratch;
        const std::vector<float> one = rasterize(welded, c, scratch, flags, across);
        Mesh apart;  // every triangle its own three corners, the same positions bit for bit
        for (uint32_t corner : welded.triangles) {
            apart.triangles.push_back(uint32_t(apart.positions.size()));
            apart.positions.push_back(welded.positions[corner]);
        }
        const std::vector<float> seams = rasterize(apart, c, scratch, {}, {}, true);
        EXPECT_EQ(seams, one) << alternate;
        const std::vector<float> cracked = rasterize(apart, c, scratch);
        EXPECT_GT(std::count(cracked.begin(), cracked.end(), 1.0f), std::count(one.begin(), one.end(), 1.0f)) << alternate;
    }
}

// Two quads of different objects abutting along a column of pixel centres: with seams those
// centres are covered, each by one of the two; an endpoint one float step off, or the two on
// the same side (a fold), keeps the margins and leaves them far.
TEST_F(DepthRaster, ASeamNeedsIdenticalEndpointsOnEitherSide) {
    const Camera c = identityCamera(16, 12);
    const auto quads = [&](float nudge, bool folded, bool seams = true) {
        Mesh m;
        const glm::vec3 top = atWindow(c, 7.5f, 10.0f, 0.5f), bottom = atWindow(c, 7.5f, 1.0f, 0.5f);
        glm::vec3 top_b = top;
        top_b.x = nudge == 0 ? top.x : std::nextafter(top.x, top.x + nudge);
        const float far_x = folded ? 3.0f : 13.0f;
        m.positions = {atWindow(c, 2, 1.0f, 0.5f), bottom, top, atWindow(c, 2, 10.0f, 0.5f),  // A, left
                       bottom, atWindow(c, far_x, 1.0f, 0.5f), atWindow(c, far_x, 10.0f, 0.5f), top_b};  // B
        m.triangles = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7};
        DepthRasterScratch scratch;
        return rasterize(m, c, scratch, {}, {}, seams);
    };
    const auto coveredOnSeam = [&](const std::vector<float>& d) {
        int n = 0;
        for (uint32_t y = 2; y < 9; ++y) n += d[y * 16 + 7] < 1.0f;
        return n;
    };
    EXPECT_EQ(coveredOnSeam(quads(0, false)), 7);
    EXPECT_EQ(coveredOnSeam(quads(1, false)), 0);
    EXPECT_EQ(coveredOnSeam(quads(0, true)), 0);
    EXPECT_EQ(coveredOnSeam(quads(0, false, false)), 0);  // without seams the exact abutment is cracked too
}

// A closed box, its 12 triangles wound counter-clockwise seen from outside, placed by `place`.
Mesh closedBox(const glm::mat4& place) {
    Mesh mesh;
    for (int i = 0; i < 8; ++i)
        mesh.positions.push_back(glm::vec3(place * glm::vec4(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1, 1)));
    // Faces as corner quads (counter-clockwise from outside), two triangles each.
    const uint32_t faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (const auto& f : faces) mesh.triangles.insert(mesh.triangles.end(), {f[0], f[1], f[2], f[0], f[2], f[3]});
    return mesh;
}

TEST(MarkClosedMesh, ABoxIsClosedAnOpenOneAndAnInsideOutOneAreNot) {
    Mesh box = closedBox(glm::mat4(1.0f));
    std::vector<uint8_t> flags = sharedFlags(box);
    EXPECT_TRUE(markClosedMesh(box.triangles.data(), box.triangleCount(), box.positions.data(), flags.data()));
    for (uint8_t f : flags) EXPECT_EQ(f, 7u | kEdgeFlagClosedMesh);
    // Turned inside out: closed, but wound clockwise from outside.
    Mesh inside_out = box;
    for (size_t t = 0; t < inside_out.triangles.size(); t += 3) std::swap(inside_out.triangles[t + 1], inside_out.triangles[t + 2]);
    flags = sharedFlags(inside_out);
    EXPECT_FALSE(markClosedMesh(inside_out.triangles.data(), inside_out.triangleCount(), inside_out.positions.data(),
                                flags.data()));
    for (uint8_t f : flags) EXPECT_EQ(f, 7u);
    // Without its last face: open.
    Mesh open = box;
    open.triangles.resize(open.triangles.size() - 6);
    flags = sharedFlags(open);
    EXPECT_FALSE(markClosedMesh(open.triangles.data(), open.triangleCount(), open.positions.data(), flags.data()));
    for (uint8_t f : flags) EXPECT_EQ(f & kEdgeFlagClosedMesh, 0u);
}

TEST_F(DepthRaster, ATriangleThatMaySkipItsBackFaceDrawsOnlyItsFront) {
    const Camera c = identityCamera(16, 16);
    Mesh front;  // counter-clockwise on screen
    front.add(atWindow(c, 1, 1, 0.5f), atWindow(c, 15, 1, 0.5f), atWindow(c, 1, 15, 0.5f));
    Mesh back;  // the same, clockwise
    back.add(atWindow(c, 1, 1, 0.5f), atWindow(c, 1, 15, 0.5f), atWindow(c, 15, 1, 0.5f));
    const std::vector<uint8_t> skip = {kEdgeFlagSkipBackFace}, none = {0};
    const std::vector<float> drawn = rasterize(front, c, none);
    EXPECT_GT(std::count_if(drawn.begin(), drawn.end(), [](float d) { return d < 1.0f; }), 50);
    EXPECT_EQ(rasterize(front, c, skip), drawn);
    EXPECT_EQ(rasterize(back, c, none), drawn);
    EXPECT_EQ(rasterize(back, c, skip), std::vector<float>(drawn.size(), 1.0f));
}

// From outside, a closed box's front faces alone write the depths the whole box writes, at
// every pixel: skipping its back faces changes no bit, in any orientation.
TEST_F(DepthRaster, SkippingTheBackFacesOfAClosedBoxSeenFromOutsideChangesNothing) {
    std::mt19937 rng(41);
    std::uniform_real_distribution<float> angle(0.0f, 6.2831853f), offset(-2.0f, 2.0f), size(0.3f, 3.0f);
    DepthRasterScratch scratch;
    const Camera c = perspectiveCamera(160, 120);
    uint64_t covered = 0;
    for (int i = 0; i < 40; ++i) {
        glm::mat4 place = glm::translate(glm::mat4(1.0f), glm::vec3(offset(rng), offset(rng), -6.0f + offset(rng)));
        place = glm::rotate(place, angle(rng), glm::normalize(glm::vec3(offset(rng), offset(rng), offset(rng)) + 0.01f));
        place = glm::scale(place, glm::vec3(size(rng), size(rng), size(rng)));
        const Mesh box = closedBox(place);
        std::vector<uint8_t> flags = sharedFlags(box);
        std::vector<uint32_t> neighbours(3 * size_t(box.triangleCount()));
        sharedEdgeFlags(box.triangles.data(), box.triangleCount(), flags.data(), neighbours.data());
        ASSERT_TRUE(markClosedMesh(box.triangles.data(), box.triangleCount(), box.positions.data(), flags.data()));
        std::vector<uint8_t> skipping = flags;
        for (uint8_t& f : skipping) f |= kEdgeFlagSkipBackFace;
        const std::vector<float> all = rasterize(box, c, scratch, flags, neighbours, true);
        EXPECT_EQ(rasterize(box, c, scratch, skipping, neighbours, true), all) << "box " << i;
        covered += std::count_if(all.begin(), all.end(), [](float d) { return d < 1.0f; });
    }
    EXPECT_GT(covered, 40u * 200u);
}

// The CPU build's SIMD code (the setup's first look at each triangle, the tile loop) at every
// instruction set this machine runs, against the per-pixel reference, with and without shared
// edges: the copies Highway makes for narrower machines must draw what AVX-512 draws.
TEST_F(DepthRaster, EverySimdLevelMatchesTheReferenceBitForBit) {
    struct Restore {
        ~Restore() { setSimdCeiling(SimdLevel::Avx512); }
    } restore;
    std::set<std::string> ran;
    for (int level = 0; level < kSimdLevels; ++level) {
        setSimdCeiling(SimdLevel(level));
        const std::string target = depthRasterTarget();
        if (target == "CUDA") return;
        if (!ran.insert(target).second) continue;  // this CPU has no such level
        std::mt19937 rng(101 + level);
        DepthRasterScratch scratch;
        const uint32_t sizes[][3] = {{77, 45, 3000}, {256, 256, 9000}, {31, 97, 4099}};
        for (const auto& size : sizes) {
            const Camera c = perspectiveCamera(size[0], size[1]);
            const Mesh mesh = randomScene(rng, size[2]);
            const std::vector<float> depth = rasterize(mesh, c, scratch);
            EXPECT_EQ(depth, referenceRaster(mesh, c)) << target << " " << size[0] << "x" << size[1];
            EXPECT_GT(coveredCount(depth), 0) << target;
            const Mesh shared = randomSharedScene(rng, size[2] / 20);
            const std::vector<uint8_t> flags = sharedFlags(shared);
            EXPECT_EQ(rasterize(shared, c, scratch, flags), referenceRaster(shared, c, flags))
                << target << " shared " << size[0] << "x" << size[1];
        }
        // Corners on pixel centres and half pixels: every rounding of the box tests shows.
        for (uint32_t w : {8u, 33u}) {
            const Camera c = identityCamera(w, w);
            const Mesh grid = gridScene(rng, c, 400);
            EXPECT_EQ(rasterize(grid, c, scratch), referenceRaster(grid, c)) << target << " grid " << w;
            const Mesh halves = gridOnHalfPixels(rng, c, 40);
            const std::vector<uint8_t> flags = sharedFlags(halves);
            EXPECT_EQ(rasterize(halves, c, scratch, flags), referenceRaster(halves, c, flags))
                << target << " half pixels " << w;
        }
        // Boxes and random triangles, every other one allowed to skip its back face: the first
        // look's area signs at this level drop exactly the back faces that may go.
        uint64_t covered = 0, skipped = 0;
        for (int i = 0; i < 10; ++i) {
            std::uniform_real_distribution<float> angle(0.0f, 6.2831853f), offset(-2.0f, 2.0f), scale(0.3f, 1.5f);
            glm::mat4 place = glm::translate(glm::mat4(1.0f), glm::vec3(offset(rng), offset(rng), -7.0f + offset(rng)));
            place = glm::rotate(place, angle(rng), glm::normalize(glm::vec3(offset(rng), offset(rng), offset(rng)) + 0.01f));
            place = glm::scale(place, glm::vec3(scale(rng), scale(rng), scale(rng)));
            Mesh scene = closedBox(place);
            append(scene, randomScene(rng, 300));
            std::vector<uint8_t> flags = sharedFlags(scene);
            for (size_t t = 0; t < flags.size(); t += 2) flags[t] |= kEdgeFlagSkipBackFace;
            const Camera c = perspectiveCamera(160, 120);
            const std::vector<float> depth = rasterize(scene, c, scratch, flags);
            EXPECT_EQ(depth, referenceRaster(scene, c, flags)) << target << " back faces " << i;
            covered += coveredCount(depth);
            std::vector<uint8_t> drawing_all = flags;
            for (uint8_t& f : drawing_all) f &= uint8_t(~kEdgeFlagSkipBackFace);
            skipped += depth != rasterize(scene, c, scratch, drawing_all) ? 1u : 0u;
        }
        EXPECT_GT(skipped, 0u) << target << ": no scene had a back face that mattered";
        EXPECT_GT(covered, 10u * 200u) << target;
    }
    EXPECT_GE(ran.size(), 2u);  // at least one SIMD copy and the portable one
}

}  // namespace
}  // namespace occ::k
