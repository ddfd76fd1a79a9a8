// SPDX-License-Identifier: MIT
#pragma once

// The instruction sets the CPU's SIMD kernels (the occluder rasters' tile loops) are compiled
// for, and which one runs: the widest this CPU and its OS support, chosen once at run time,
// unless a test lowers the ceiling to run the narrower copies on a machine that has more.
// Highway (libhwy-dev) generates the copies from one source; only its headers are used.

#include <cstdint>

namespace occ::k {

enum class SimdLevel : uint8_t { Avx512 = 0, Avx2 = 1, Sse4 = 2, Portable = 3 };
inline constexpr int kSimdLevels = 4;

// The widest level this CPU runs, no wider than the ceiling.
SimdLevel simdLevel();
// "AVX-512", "AVX2", "SSE4", "portable".
const char* simdLevelName(SimdLevel level);
// The widest level simdLevel may return from now on (Avx512: no limit). For tests.
void setSimdCeiling(SimdLevel ceiling);

// The entry of a per-level table (Highway's HWY_CHOOSE_* in that order, null where a level was
// not compiled) that runs here: the first non-null one from simdLevel() down. The last entry
// (the portable copy) is never null.
template <class F>
F pickSimd(F const (&table)[kSimdLevels], SimdLevel* picked = nullptr) {
    int i = int(simdLevel());
    while (i + 1 < kSimdLevels && table[i] == nullptr) ++i;
    if (picked) *picked = SimdLevel(i);
    return table[i];
}

}  // namespace occ::k
