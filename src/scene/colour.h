// SPDX-License-Identifier: MIT
#pragma once

#include <cmath>

// Colours in occswitch are linear RGB in [0, 1], as glTF's baseColorFactor and COLOR_0 are;
// formats that store display colours (OBJ's Kd, PLY's 8-bit red / green / blue) are converted
// from sRGB when read, and the display encodes sRGB again after lighting.
namespace occ {

// sRGB (IEC 61966-2-1) to linear light and back, one channel in [0, 1].
inline float srgbToLinear(float c) { return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f); }
inline float linearToSrgb(float c) { return c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f; }

}  // namespace occ
