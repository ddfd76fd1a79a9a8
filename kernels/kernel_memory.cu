// SPDX-License-Identifier: MIT
#include "kernel_memory.h"

#include <cstdlib>
#include <new>
#include <string>

#if defined(__CUDACC__)
#include <cuda_runtime.h>

#include <stdexcept>

// Every CUDA runtime call goes through this: a failure becomes one exception naming the call,
// where it was made and CUDA's own words (e.g. "no CUDA-capable device is detected").
#define OCC_CUDA_CHECK(call)                                                                           \
    do {                                                                                               \
        const cudaError_t occ_cuda_status = (call);                                                    \
        if (occ_cuda_status != cudaSuccess)                                                            \
            throw std::runtime_error(std::string("CUDA: ") + #call + " failed at " + __FILE__ + ":" +  \
                                     std::to_string(__LINE__) + ": " + cudaGetErrorString(occ_cuda_status)); \
    } while (0)
#endif

namespace occ::k {

#if defined(__CUDACC__)

void* kernelAlloc(size_t bytes) {
    void* p = nullptr;
    OCC_CUDA_CHECK(cudaMallocManaged(&p, bytes ? bytes : 1));
    return p;
}
void kernelFree(void* p) {
    if (p) cudaFree(p);  // in destructors: a failure here has nowhere to go
}
void kernelSynchronize() { OCC_CUDA_CHECK(cudaDeviceSynchronize()); }
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
