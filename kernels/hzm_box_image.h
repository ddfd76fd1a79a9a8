// SPDX-License-Identifier: MIT
#pragma once

#include "host_device.h"
#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

// What a texel's depth gets added before it is compared with a box's nearest depth (hzmTest).
inline constexpr float kHzmTestEpsilon = 1e-6f;

// A box's image as the HZM tests read it (kernels/hzm_test.cu): the level-0 pixel rectangle
// [x0, x1] x [y0, y1] its corners' window rectangle touches, clipped to the viewport, and its
// nearest window depth.
struct BoxImage {
    uint32_t x0, x1, y0, y1;
    float z_min;
};

#if !defined(__CUDACC__)
// The CPU's box images (kernels/hzm_test_cpu.cpp), a SIMD vector of boxes at a time, in the
// float operations of hzm_test.cu's boxImage, so the same bits: for j < count, valid[j] = 1 and
// images[j] set where boxImage(objects[ids[j]].aabb, ...) would return true, else valid[j] = 0
// (images[j] then unspecified). view_proj: column-major, as glm keeps it (16 floats).
// And the HZM test's first look, at the level it starts at (the finest where the image spans at
// most 2x2 texels): settled[j] = 1 where the image is valid and every texel there proves the box
// hidden (its nearest depth beyond the texel's + kHzmTestEpsilon), which is then the answer; 0
// where the test must look further. The pyramid: `texels` (all levels), level_count >= 1 levels
// of level_width[l] texels a row starting at level_offset[l] (all below 2^31).
void boxImagesCpu(const ObjectInfo* objects, const uint32_t* ids, uint32_t count, const float* view_proj,
                  float near_plane, float w0, float h0, BoxImage* images, uint8_t* valid, const float* texels,
                  uint32_t level_count, const int32_t* level_width, const int32_t* level_offset, uint8_t* settled);
#endif

}  // namespace occ::k
