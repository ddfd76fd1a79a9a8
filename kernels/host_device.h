// SPDX-License-Identifier: MIT
#pragma once

// One source for CPU and GPU: every kernel file in kernels/ is compiled twice, as C++ with
// Thrust's TBB device system (the CPU build, what tests run) and by nvcc with the CUDA
// toolkit's CCCL (the GPU build). Functors that run on the device are marked OCC_HD.
#if defined(__CUDACC__)
#define OCC_HD __host__ __device__
#else
#define OCC_HD
#endif

#include <glm/glm.hpp>

#include <cstdint>

namespace occ::k {

// Plain comparisons rather than fminf/fmaxf, which g++ calls out of line without -ffast-math
// (depths and areas are never NaN here).
OCC_HD inline float minf(float a, float b) { return a < b ? a : b; }
OCC_HD inline float maxf(float a, float b) { return a > b ? a : b; }

}  // namespace occ::k
