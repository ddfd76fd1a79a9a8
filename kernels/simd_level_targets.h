// SPDX-License-Identifier: MIT
// Included first by every Highway source (before hwy/foreach_target.h): compiles only the
// copies kernels/simd_level.h can pick (AVX3 = AVX-512, AVX2, SSE4 and the portable one).
#pragma once

#include "simd_level.h"

#ifndef HWY_DISABLED_TARGETS
#define HWY_DISABLED_TARGETS (HWY_AVX3_DL | HWY_SSSE3)
#endif
