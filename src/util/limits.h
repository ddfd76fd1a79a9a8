// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>

// Limits that more than one layer checks (the command line, the pipeline, the roles): each is
// written here once, and every check and message reads it from here.
namespace occ {

// Largest viewport side, in pixels, for the view and the occlusion depth buffer (`--size WxH`).
inline constexpr uint32_t kMaxViewportSide = 16384;

// Most cells the sort-last display may cut the screen into (`--sort-last-cells`).
inline constexpr int kMaxSortLastCells = 1024;

}  // namespace occ
