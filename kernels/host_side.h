// SPDX-License-Identifier: MIT
#pragma once

// For kernel files only (it includes Thrust). Work that reads the scene where it lives, in host
// memory (streaming's gather, the object-by-object baseline), runs on the host side: Thrust's
// host system under nvcc; in the CPU build the device system (TBB) works on host memory too,
// and in parallel.
#include <thrust/execution_policy.h>

namespace occ::k {

#if defined(__CUDACC__)
inline const auto& kHostSide = thrust::host;
#else
inline const auto& kHostSide = thrust::device;
#endif

}  // namespace occ::k
