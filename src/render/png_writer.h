// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace occ::render {

// Writes a W x H 8-bit PNG with `channels` (1 = grey, 3 = RGB) per pixel, rows given bottom
// first (OpenGL's order; the file has the top row first). The file appears whole or not at all
// (written to PATH.tmp, then renamed). Throws InputError(path, ...) when it cannot be written.
void writePng(const std::string& path, uint32_t width, uint32_t height, int channels, const uint8_t* pixels);

// A depth buffer as a grey picture: near = white, far (1.0, nothing drawn) = black, the depths
// present stretched over the grey range so that a person can see the shapes.
std::vector<uint8_t> depthToGrey(const float* depth, uint64_t count);

}  // namespace occ::render
