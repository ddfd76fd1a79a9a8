// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>

// Limits and defaults that more than one layer uses (the command line, the benchmarks, the
// pipeline, the roles): each is written here once, and every check and message reads it from here.
namespace occ {

// Largest viewport side, in pixels, for the view and the occlusion depth buffer (`--size WxH`).
inline constexpr uint32_t kMaxViewportSide = 16384;

// Most cells the sort-last display may cut the screen into (`--sort-last-cells`).
inline constexpr int kMaxSortLastCells = 1024;

// The model `gen` tiles and the benchmarks measure when none is given: the engine of
// assimp-testmodels (Debian's package), the default demo input.
inline constexpr const char* kDefaultModel =
    "/usr/share/assimp/models/glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";

}  // namespace occ
