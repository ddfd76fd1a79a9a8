// SPDX-License-Identifier: MIT
#pragma once

// For kernel sources only (it includes Thrust): the execution policy every device algorithm
// runs with.
#include "device_memory.h"

#include <thrust/execution_policy.h>

#include <cstddef>

namespace occ::k {

// Thrust's allocator for an algorithm's temporary storage: the process's cache
// (temporaryAlloc), so that sorts, scans and compactions inside a frame make no cudaMalloc or
// cudaFree once the sizes they need have been seen.
struct TemporaryAllocator {
    using value_type = char;
    char* allocate(std::ptrdiff_t bytes) { return static_cast<char*>(temporaryAlloc(size_t(bytes))); }
    void deallocate(char* p, size_t) { temporaryFree(p); }
};

// The device policy: temporaries from the cache and, under CUDA, no synchronisation after each
// algorithm (thrust::cuda::par_nosync; one that hands a value back to the host still waits for
// it). Kernels and copies all run on the default stream in order; a stage waits once, at its end
// (StageClock::lap in src/pipeline/frame_stats.h).
inline auto onDevice() {
    static TemporaryAllocator allocator;
#if defined(__CUDACC__)
    return thrust::cuda::par_nosync(allocator);
#else
    return thrust::device(allocator);
#endif
}

}  // namespace occ::k
