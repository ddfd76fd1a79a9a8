// SPDX-License-Identifier: MIT
#pragma once

#include "host_device.h"
#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

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
void boxImagesCpu(const ObjectInfo* objects, const uint32_t* ids, uint32_t count, const float* view_proj,
                  float near_plane, float w0, float h0, BoxImage* images, uint8_t* valid);
#endif

}  // namespace occ::k
