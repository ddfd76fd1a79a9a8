// SPDX-License-Identifier: MIT
#pragma once

// For kernel files only (it includes Thrust). Work that reads the scene where it lives, in host
// memory (streaming's gather from the mapped file into pinned staging), runs on the host, in
// parallel on every core: Thrust's TBB system, which is the device system of the CPU build and
// an explicit policy under nvcc (whose device is the GPU).
#include <thrust/execution_policy.h>
#if defined(__CUDACC__)
#include <thrust/system/tbb/execution_policy.h>
#endif

namespace occ::k {

#if defined(__CUDACC__)
inline const auto& kHostSide = thrust::tbb::par;
#else
inline const auto& kHostSide = thrust::device;
#endif

}  // namespace occ::k
