// SPDX-License-Identifier: MIT
#pragma once

// For kernel sources only: passes over an index range that may be short.
#include "device_access.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

#include <cstdint>

namespace occ::k {

// On the CPU, a pass over at most this many elements runs on the calling thread. Waking TBB's
// workers for a pass costs 5 to 15 us on the 2-core machine (a micro-benchmark of an empty
// parallel_for), more than a few thousand cheap elements take on one core, and one occluder
// raster makes two dozen passes, many over a walk's few thousand drawn triangles or boundary
// edges or over the pyramid's small levels. Under CUDA every pass is a kernel.
inline constexpr uint64_t kSerialPassMost = 4096;

// body(policy) with the Thrust execution policy for a pass over n elements: thrust::seq on the
// CPU when n <= kSerialPassMost, onDevice() otherwise. body must compile with both.
template <class Body>
decltype(auto) withPolicy(uint64_t n, Body&& body) {
#if !defined(__CUDACC__)
    if (n <= kSerialPassMost) return body(thrust::seq);
#else
    (void)n;
#endif
    return body(onDevice());
}

// f(i) for every i in [0, n), as thrust::for_each_n over a counting iterator, serial when short.
template <class Index, class F>
void forEachIndex(Index n, const F& f) {
    withPolicy(uint64_t(n), [&](auto policy) { thrust::for_each_n(policy, thrust::counting_iterator<Index>(0), n, f); });
}

}  // namespace occ::k
