// SPDX-License-Identifier: MIT
#pragma once

#include "depth_raster.h"

namespace occ::k {

// The occluder raster the pipeline uses: a raster of the Masked Occlusion Culling class
// (Hasselgren, Andersson, Akenine-Möller, "Masked Software Occlusion Culling", HPG 2016). The
// screen is cut into subtiles of 8 x 4 pixels; each keeps a coverage mask of 32 bits and two
// conservative depths instead of a depth per pixel (kernels/masked_tile.h), so a triangle costs
// a mask and a compare per subtile it touches, not a depth per pixel.
//
// Same inputs, skip rules, coverage and seams as depthRaster (kernels/depth_raster.h), whose
// front end it shares: a pixel centre is covered by a triangle exactly when depthRaster covers
// it. What differs is depth: a covered pixel gets a bound at least as far as depthRaster's
// (the triangle's plane at the farthest corner of the subtile's part of its box, in the same
// float arithmetic, so never nearer, rounding included), and the two layers of a subtile merge
// conservatively. Hence, per pixel, depth >= depthRaster's depth: the HZM built from it never
// culls what depthRaster's would not (tests/kernels/test_masked_raster.cpp compares the two).
//
// depth: W*H floats, row-major, W = camera.width, H = camera.height in [0, 32768] (else
// std::invalid_argument); cleared to 1.0 (far) and then, per pixel, the bound of its subtile.
// Deterministic: the result depends neither on the thread count nor on the back end. Triangles
// are taken in index order within each band of 32 rows (the unit of parallel work on the CPU;
// on CUDA a thread per subtile), so the order of the list matters a little (the layers merge in
// that order) but never conservativeness.
// CPU: the coverage masks are made with SIMD (Highway, the widest instruction set the machine
// has, chosen at run time: AVX-512, AVX2, SSE4, or a portable path).
// Memory: depthRaster's scratch (its front end and binning) plus nothing per frame.
void maskedDepthRaster(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles, uint32_t tri_count,
                       DevicePtr<const uint8_t> edge_flags, DevicePtr<const uint32_t> edge_neighbours,
                       const Camera& camera, DevicePtr<float> depth, DepthRasterScratch& scratch, bool seams = false);

// The same result by the one-thread-per-subtile loop, 64-bit integer coverage pixel by pixel, on
// either back end: the CUDA build's maskedDepthRaster itself, and on the CPU the reference its
// SIMD band loop is tested against (bit for bit).
void maskedDepthRasterScalar(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles,
                             uint32_t tri_count, DevicePtr<const uint8_t> edge_flags,
                             DevicePtr<const uint32_t> edge_neighbours, const Camera& camera, DevicePtr<float> depth,
                             DepthRasterScratch& scratch, bool seams = false);

// The instruction set the CPU's masked raster runs with on this machine (kernels/simd_level.h:
// "AVX-512", "AVX2", "SSE4" or "portable"); "CUDA" in the CUDA build.
const char* maskedRasterTarget();

}  // namespace occ::k
