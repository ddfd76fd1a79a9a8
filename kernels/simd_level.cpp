// SPDX-License-Identifier: MIT
#include "simd_level.h"

#include <atomic>

namespace occ::k {

namespace {

// The feature sets follow Highway's definitions of its x86 targets (AVX3, AVX2, SSE4); GCC's
// __builtin_cpu_supports also checks that the OS saves the AVX and AVX-512 registers.
SimdLevel hardwareLevel() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_cpu_init();
    const bool sse4 = __builtin_cpu_supports("ssse3") && __builtin_cpu_supports("sse4.1") &&
                      __builtin_cpu_supports("sse4.2") && __builtin_cpu_supports("pclmul") &&
                      __builtin_cpu_supports("aes");
    const bool avx2 = sse4 && __builtin_cpu_supports("avx") && __builtin_cpu_supports("avx2") &&
                      __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") &&
                      __builtin_cpu_supports("fma") && __builtin_cpu_supports("f16c");
    const bool avx512 = avx2 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                        __builtin_cpu_supports("avx512dq") && __builtin_cpu_supports("avx512bw");
    return avx512 ? SimdLevel::Avx512 : avx2 ? SimdLevel::Avx2 : sse4 ? SimdLevel::Sse4 : SimdLevel::Portable;
#else
    return SimdLevel::Portable;
#endif
}

std::atomic<uint8_t> ceiling{uint8_t(SimdLevel::Avx512)};

}  // namespace

SimdLevel simdLevel() {
    static const SimdLevel hardware = hardwareLevel();
    const uint8_t c = ceiling.load(std::memory_order_relaxed);
    return SimdLevel(uint8_t(hardware) > c ? uint8_t(hardware) : c);
}

const char* simdLevelName(SimdLevel level) {
    switch (level) {
        case SimdLevel::Avx512: return "AVX-512";
        case SimdLevel::Avx2: return "AVX2";
        case SimdLevel::Sse4: return "SSE4";
        default: return "portable";
    }
}

void setSimdCeiling(SimdLevel c) { ceiling.store(uint8_t(c), std::memory_order_relaxed); }

}  // namespace occ::k
