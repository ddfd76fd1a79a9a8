// SPDX-License-Identifier: MIT
#include "kernel_memory.h"

#include <cstdlib>
#include <new>
#include <string>

#if defined(__CUDACC__)
#include <cuda_runtime.h>
#endif

namespace occ::k {

#if defined(__CUDACC__)

void* kernelAlloc(size_t bytes) {
    void* p = nullptr;
    const cudaError_t e = cudaMallocManaged(&p, bytes ? bytes : 1);
    if (e != cudaSuccess) throw std::bad_alloc();
    return p;
}
void kernelFree(void* p) {
    if (p) cudaFree(p);
}
void kernelSynchronize() { cudaDeviceSynchronize(); }
const char* kernelBackend() { return "cuda"; }

#else

void* kernelAlloc(size_t bytes) {
    // 64-byte alignment: cache lines, and what the GPU's allocator gives too.
    void* p = std::aligned_alloc(64, ((bytes ? bytes : 1) + 63) / 64 * 64);
    if (!p) throw std::bad_alloc();
    return p;
}
void kernelFree(void* p) { std::free(p); }
void kernelSynchronize() {}
const char* kernelBackend() { return "cpu-tbb"; }

#endif

}  // namespace occ::k
