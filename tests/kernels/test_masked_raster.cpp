// SPDX-License-Identifier: MIT
#include "depth_raster.h"
#include "hzm.h"
#include "hzm_build.h"
#include "masked_raster.h"
#include "masked_tile.h"
#include "simd_level.h"

#include "device_test_support.h"
#include "raster_fixtures.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <string>
#include <vector>

namespace occ::k {
namespace {

using test::atWindow;
using test::identityCamera;
using test::Mesh;
using test::perspectiveCamera;
using test::randomScene;
using test::toDevice;
using test::toHost;

using MaskedRaster = test::DeviceTest;

// A tessellated wall of nx x ny quads (shared edges), tilted, at about `distance`.
Mesh wall(uint32_t nx, uint32_t ny, float distance, float tilt) {
    Mesh m;
    for (uint32_t j = 0; j <= ny; ++j)
        for (uint32_t i = 0; i <= nx; ++i) {
            const float x = -6.0f + 12.0f * float(i) / float(nx), y = -4.0f + 8.0f * float(j) / float(ny);
            m.positions.emplace_back(x, y, -distance + tilt * x);
        }
    for (uint32_t j = 0; j < ny; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            const uint32_t a = j * (nx + 1) + i, b = a + 1, c = a + nx + 1, d = c + 1;
            m.triangles.insert(m.triangles.end(), {a, b, d, a, d, c});
        }
    return m;
}

// Corners on the half-pixel grid under the identity camera, some a margin off it, so that many
// pixel centres lie exactly on edges and at exactly the margin; tessellated pieces share edges.
Mesh gridScene(std::mt19937& rng, const Camera& c, uint32_t piece_count) {
    std::uniform_int_distribution<int> half_pixel(-8, 2 * int(c.width) + 8), cells(1, 6), step(1, 12), percent(0, 99);
    Mesh scene;
    for (uint32_t p = 0; p < piece_count; ++p) {
        const uint32_t nx = uint32_t(cells(rng)), ny = uint32_t(cells(rng)), first = uint32_t(scene.positions.size());
        const int x0 = half_pixel(rng), y0 = half_pixel(rng), dx = step(rng), dy = step(rng), shear = step(rng) - 6;
        for (uint32_t j = 0; j <= ny; ++j)
            for (uint32_t i = 0; i <= nx; ++i) {
                const float x = 0.5f * float(x0 + int(i) * dx + int(j) * shear) + (percent(rng) < 20 ? 1.0f / 64 : 0.0f);
                const float y = 0.5f * float(y0 + int(j) * dy);
                scene.positions.push_back(atWindow(c, x, y, float(percent(rng) + 100) / 256.0f));
            }
        for (uint32_t j = 0; j < ny; ++j)
            for (uint32_t i = 0; i < nx; ++i) {
                const uint32_t a = first + j * (nx + 1) + i, b = a + 1, cc = a + nx + 1, d = cc + 1;
                scene.triangles.insert(scene.triangles.end(), {a, b, d, a, d, cc});
            }
    }
    return scene;
}

enum class Which { Masked, MaskedScalar, Exact, ExactScalar };

std::vector<float> raster(Which which, const Mesh& mesh, const Camera& c, DepthRasterScratch& scratch,
                          bool with_flags = false) {
    std::vector<uint8_t> flags(mesh.triangleCount());
    std::vector<uint32_t> neighbours(3 * size_t(mesh.triangleCount()));
    if (with_flags) sharedEdgeFlags(mesh.triangles.data(), mesh.triangleCount(), flags.data(), neighbours.data());
    const auto positions = toDevice(mesh.positions);
    const auto triangles = toDevice(mesh.triangles);
    const auto flag_memory = toDevice(flags);
    const auto neighbour_memory = toDevice(neighbours);
    DeviceArray<float> depth(std::max<size_t>(1, size_t(c.width) * c.height));
    const DevicePtr<const uint8_t> f = with_flags ? DevicePtr<const uint8_t>(flag_memory.ptr()) : DevicePtr<const uint8_t>();
    const DevicePtr<const uint32_t> n =
        with_flags ? DevicePtr<const uint32_t>(neighbour_memory.ptr()) : DevicePtr<const uint32_t>();
    switch (which) {
        case Which::Masked:
            maskedDepthRaster(positions.ptr(), triangles.ptr(), mesh.triangleCount(), f, n, c, depth.ptr(), scratch, true);
            break;
        case Which::MaskedScalar:
            maskedDepthRasterScalar(positions.ptr(), triangles.ptr(), mesh.triangleCount(), f, n, c, depth.ptr(),
                                    scratch, true);
            break;
        case Which::Exact:
            depthRaster(positions.ptr(), triangles.ptr(), mesh.triangleCount(), f, n, c, depth.ptr(), scratch, true);
            break;
        case Which::ExactScalar:
            depthRasterScalar(positions.ptr(), triangles.ptr(), mesh.triangleCount(), f, n, c, depth.ptr(), scratch,
                              true);
            break;
    }
    return toHost(depth, size_t(c.width) * c.height);
}

// The whole max pyramid (HZM) of a depth buffer.
std::vector<float> pyramid(const std::vector<float>& depth, uint32_t w, uint32_t h) {
    DeviceArray<float> levels(hzmTotalTexels(w, h));
    copyToDevice(levels.ptr(), depth.data(), depth.size());
    hzmBuild(levels.ptr(), w, h);
    return toHost(levels, hzmTotalTexels(w, h));
}

// Every texel of the masked raster's pyramid is at or beyond the exact one's; returns how many
// level-0 pixels the masked raster left at far where the exact one has an occluder.
uint64_t expectNeverNearer(const std::vector<float>& masked, const std::vector<float>& exact, uint32_t w, uint32_t h,
                           const char* what) {
    const std::vector<float> a = pyramid(masked, w, h), b = pyramid(exact, w, h);
    for (size_t i = 0; i < a.size(); ++i)
        if (!(a[i] >= b[i])) {
            ADD_FAILURE() << what << ": texel " << i << " of the pyramid is nearer: " << a[i] << " < " << b[i];
            break;
        }
    uint64_t lost = 0;
    for (size_t i = 0; i < exact.size(); ++i) lost += exact[i] < 1.0f && masked[i] >= 1.0f;
    return lost;
}

TEST(MaskedSubtile, TwoHalvesAtDifferentDepthsBecomeAReferenceLayerAtTheFarther) {
    MaskedSubtile t{1.0f, 0.0f, 0u};
    updateSubtile(t, 0x0000ffffu, 0.4f, 0u);
    EXPECT_EQ(t.mask, 0x0000ffffu);
    EXPECT_EQ(t.z1, 0.4f);
    EXPECT_EQ(subtileDepth(t, 0), 0.4f);
    EXPECT_EQ(subtileDepth(t, 31), 1.0f);
    updateSubtile(t, 0xffff0000u, 0.5f, 0u);
    EXPECT_EQ(t.mask, 0u);
    EXPECT_EQ(t.z0, 0.5f);
    EXPECT_EQ(subtileDepth(t, 0), 0.5f);
}

TEST(MaskedSubtile, ATriangleBehindTheReferenceLayerChangesNothing) {
    MaskedSubtile t{0.3f, 0.2f, 0x0fu};
    updateSubtile(t, kSubtileFull, 0.3f, 0u);
    updateSubtile(t, 0xf0u, 0.9f, 0u);
    EXPECT_EQ(t.z0, 0.3f);
    EXPECT_EQ(t.z1, 0.2f);
    EXPECT_EQ(t.mask, 0x0fu);
}

TEST(MaskedSubtile, AWholeSubtileKeepsANearerWorkingLayer) {
    MaskedSubtile t{1.0f, 0.2f, 0x0fu};
    updateSubtile(t, kSubtileFull, 0.6f, 0u);
    EXPECT_EQ(t.z0, 0.6f);
    EXPECT_EQ(t.mask, 0x0fu);
    EXPECT_EQ(subtileDepth(t, 0), 0.2f);
    EXPECT_EQ(subtileDepth(t, 4), 0.6f);
    updateSubtile(t, kSubtileFull, 0.1f, 0u);  // nearer than the working layer: it goes
    EXPECT_EQ(t.mask, 0u);
    EXPECT_EQ(t.z0, 0.1f);
}

TEST(MaskedSubtile, AFarWorkingLayerIsDroppedForANearTriangle) {
    // working layer at 0.8 under a reference at 0.9; a triangle at 0.1 is nearer to nothing:
    // |0.1 - 0.8| > 0.9 - 0.1 is false, so it merges; at 0.85 it merges too; a triangle
    // at 0.2 beside a working layer at 0.85 under a reference at 1 is 0.65 from it and 0.8
    // from the reference: merged. Only a working layer farther from the triangle than the
    // reference is dropped.
    MaskedSubtile t{0.5f, 0.45f, 0x1u};
    updateSubtile(t, 0x2u, 0.05f, 0u);  // |0.05 - 0.45| = 0.4 < 0.45: merged
    EXPECT_EQ(t.mask, 0x3u);
    EXPECT_EQ(t.z1, 0.45f);
    MaskedSubtile u{1.0f, 0.9f, 0x1u};
    updateSubtile(u, 0x2u, 0.1f, 0u);  // |0.1 - 0.9| = 0.8 < 0.9: merged
    EXPECT_EQ(u.mask, 0x3u);
    MaskedSubtile v{1.0f, 0.95f, 0x1u};
    updateSubtile(v, 0x2u, 0.02f, 0u);  // 0.93 > 0.98? no: merged
    EXPECT_EQ(v.mask, 0x3u);
    MaskedSubtile w{1.0f, 0.05f, 0x1u};
    updateSubtile(w, 0x2u, 0.7f, 0u);  // 0.65 > 0.3: the working layer goes, the triangle starts one
    EXPECT_EQ(w.mask, 0x2u);
    EXPECT_EQ(w.z1, 0.7f);
}

TEST(MaskedSubtile, PixelsOutsideTheViewportCountAsCovered) {
    EXPECT_EQ(subtileInside(0, 0, 100, 100), kSubtileFull);
    EXPECT_EQ(subtileInside(8, 4, 13, 6), 0x1f1fu);
    MaskedSubtile t{1.0f, 0.0f, 0u};
    updateSubtile(t, 0x1f1fu, 0.3f, ~0x1f1fu);
    EXPECT_EQ(t.mask, 0u);
    EXPECT_EQ(t.z0, 0.3f);
}

TEST_F(MaskedRaster, SimdBandsMatchTheScalarSubtileLoopBitForBit) {
    std::mt19937 rng(23);
    DepthRasterScratch scratch;
    const uint32_t sizes[][3] = {{77, 45, 3000}, {256, 256, 20000}, {31, 97, 4097}, {512, 384, 5000}, {1, 1, 100},
                                 {1030, 70, 3000}};
    for (const auto& size : sizes) {
        const Camera c = perspectiveCamera(size[0], size[1]);
        for (float max_size : {0.3f, 40.0f}) {
            const Mesh mesh = randomScene(rng, size[2], max_size);
            EXPECT_EQ(raster(Which::Masked, mesh, c, scratch), raster(Which::MaskedScalar, mesh, c, scratch))
                << size[0] << "x" << size[1] << " up to " << max_size;
        }
    }
    const Camera c = perspectiveCamera(200, 150);
    const Mesh w = wall(37, 23, 12.0f, 0.3f);
    EXPECT_EQ(raster(Which::Masked, w, c, scratch, true), raster(Which::MaskedScalar, w, c, scratch, true));
    for (uint32_t side : {8u, 33u, 64u, 130u}) {
        const Camera g = identityCamera(side, side);
        const Mesh grid = gridScene(rng, g, 60);
        for (bool flags : {false, true})
            EXPECT_EQ(raster(Which::Masked, grid, g, scratch, flags), raster(Which::MaskedScalar, grid, g, scratch, flags))
                << side << (flags ? " with shared edges" : "");
    }
}

TEST_F(MaskedRaster, NeverNearerThanTheExactRasterAtAnyHzmLevel) {
    std::mt19937 rng(5);
    DepthRasterScratch scratch;
    const uint32_t sizes[][3] = {{77, 45, 3000}, {256, 256, 20000}, {31, 97, 4097}, {512, 512, 5000}};
    for (const auto& size : sizes) {
        const Camera c = perspectiveCamera(size[0], size[1]);
        for (float max_size : {0.3f, 40.0f}) {
            const Mesh mesh = randomScene(rng, size[2], max_size);
            expectNeverNearer(raster(Which::Masked, mesh, c, scratch), raster(Which::Exact, mesh, c, scratch), size[0],
                              size[1], "random scene");
        }
    }
    for (uint32_t side : {8u, 33u, 130u}) {
        const Camera g = identityCamera(side, side);
        const Mesh grid = gridScene(rng, g, 60);
        for (bool flags : {false, true})
            expectNeverNearer(raster(Which::Masked, grid, g, scratch, flags), raster(Which::Exact, grid, g, scratch, flags),
                              side, side, "grid scene");
    }
}

// A flat grid whose corners and edges run through pixel centres: the tie rule gives each centre
// on a shared edge to exactly one triangle, so the masked raster, like the exact one, leaves no
// hole, and at one depth it is exact.
TEST_F(MaskedRaster, AGridThroughPixelCentresAtOneDepthIsExact) {
    DepthRasterScratch scratch;
    const Camera c = identityCamera(67, 41);
    Mesh grid;
    const uint32_t nx = 15, ny = 10;
    for (uint32_t j = 0; j <= ny; ++j)
        for (uint32_t i = 0; i <= nx; ++i)
            grid.positions.push_back(atWindow(c, -3.5f + 5.0f * float(i), -2.5f + 5.0f * float(j), 0.375f));
    for (uint32_t j = 0; j < ny; ++j)
        for (uint32_t i = 0; i < nx; ++i) {
            const uint32_t a = j * (nx + 1) + i, b = a + 1, cc = a + nx + 1, d = cc + 1;
            grid.triangles.insert(grid.triangles.end(), {a, b, d, a, d, cc});
        }
    const std::vector<float> exact = raster(Which::Exact, grid, c, scratch, true);
    EXPECT_EQ(std::count(exact.begin(), exact.end(), 1.0f), 0) << "the grid covers the viewport";
    EXPECT_EQ(raster(Which::Masked, grid, c, scratch, true), exact);
}

TEST_F(MaskedRaster, ATessellatedWallCoversWhatTheExactRasterCovers) {
    DepthRasterScratch scratch;
    const Camera c = perspectiveCamera(320, 240);
    for (float tilt : {0.0f, 0.4f, -1.5f}) {
        const Mesh w = wall(61, 29, 9.0f, tilt);
        const std::vector<float> masked = raster(Which::Masked, w, c, scratch, true);
        const std::vector<float> exact = raster(Which::Exact, w, c, scratch, true);
        EXPECT_EQ(expectNeverNearer(masked, exact, c.width, c.height, "wall"), 0u) << "tilt " << tilt;
        // Inside the wall's image each subtile fills and takes its farthest triangle's bound:
        // above the exact depth by at most the wall's depth across a subtile.
        uint64_t near = 0, covered = 0;
        for (size_t i = 0; i < exact.size(); ++i) {
            if (exact[i] >= 1.0f) continue;
            ++covered;
            near += masked[i] - exact[i] < 0.01f;
        }
        EXPECT_GT(covered, 20000u);
        EXPECT_GT(near, covered * 99 / 100) << "tilt " << tilt;
    }
}

TEST_F(MaskedRaster, AScreenFillingQuadAtOneDepthIsExact) {
    DepthRasterScratch scratch;
    const Camera c = identityCamera(70, 37);
    Mesh quad;
    quad.positions = {atWindow(c, -10, -10, 0.25f), atWindow(c, 90, -10, 0.25f), atWindow(c, 90, 50, 0.25f),
                      atWindow(c, -10, 50, 0.25f)};
    quad.triangles = {0, 1, 2, 0, 2, 3};
    EXPECT_EQ(raster(Which::Masked, quad, c, scratch, true), raster(Which::Exact, quad, c, scratch, true));
}

TEST_F(MaskedRaster, NoTrianglesClearsToFar) {
    DepthRasterScratch scratch;
    const Camera c = perspectiveCamera(19, 11);
    EXPECT_EQ(raster(Which::Masked, Mesh{}, c, scratch), std::vector<float>(19 * 11, 1.0f));
}

TEST_F(MaskedRaster, ViewportBeyondLimitIsRejected) {
    DepthRasterScratch scratch;
    DeviceArray<float> depth(1);
    DeviceArray<glm::vec3> positions(1);
    DeviceArray<uint32_t> triangles(1);
    Camera c = perspectiveCamera(32769, 4);
    EXPECT_THROW(maskedDepthRaster(positions.ptr(), triangles.ptr(), 0, {}, {}, c, depth.ptr(), scratch),
                 std::invalid_argument);
}

// Both rasters' tile loops at every SIMD level this machine runs (AVX-512, AVX2, SSE4 and the
// portable copy on this project's machines), each against the scalar loop, bit for bit, on
// small and large triangles, viewports cut mid-tile and grids through pixel centres.
TEST_F(MaskedRaster, EveryInstructionSetMatchesTheScalarLoopsBitForBit) {
    struct Restore {
        ~Restore() { setSimdCeiling(SimdLevel::Avx512); }
    } restore;
    const std::set<std::string> cpu_names = {"AVX-512", "AVX2", "SSE4", "portable"};
    std::set<std::string> ran;
    for (int level = 0; level < kSimdLevels; ++level) {
        setSimdCeiling(SimdLevel(level));
        const std::string exact_target = depthRasterTarget(), masked_target = maskedRasterTarget();
        EXPECT_EQ(exact_target, masked_target);
        if (exact_target == "CUDA") return;  // the CUDA build has no CPU tile loops
        EXPECT_TRUE(cpu_names.count(exact_target)) << exact_target;
        if (!ran.insert(exact_target).second) continue;  // this CPU has no such level
        std::mt19937 rng(31 + level);
        DepthRasterScratch scratch;
        const uint32_t sizes[][3] = {{77, 45, 2000}, {256, 256, 6000}, {31, 97, 1500}, {1030, 70, 2000}};
        for (const auto& size : sizes) {
            const Camera c = perspectiveCamera(size[0], size[1]);
            for (float max_size : {0.3f, 40.0f}) {
                const Mesh mesh = randomScene(rng, size[2], max_size);
                const std::string what = exact_target + " " + std::to_string(size[0]) + "x" + std::to_string(size[1]);
                EXPECT_EQ(raster(Which::Exact, mesh, c, scratch), raster(Which::ExactScalar, mesh, c, scratch)) << what;
                EXPECT_EQ(raster(Which::Masked, mesh, c, scratch), raster(Which::MaskedScalar, mesh, c, scratch)) << what;
            }
        }
        for (uint32_t side : {8u, 33u, 130u}) {
            const Camera g = identityCamera(side, side);
            const Mesh grid = gridScene(rng, g, 60);
            for (bool flags : {false, true}) {
                EXPECT_EQ(raster(Which::Exact, grid, g, scratch, flags), raster(Which::ExactScalar, grid, g, scratch, flags))
                    << exact_target << " grid " << side;
                EXPECT_EQ(raster(Which::Masked, grid, g, scratch, flags),
                          raster(Which::MaskedScalar, grid, g, scratch, flags))
                    << exact_target << " grid " << side;
            }
        }
    }
    // The portable copy runs everywhere.
    EXPECT_TRUE(ran.count("portable"));
}

}  // namespace
}  // namespace occ::k
