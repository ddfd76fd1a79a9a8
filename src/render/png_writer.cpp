// SPDX-License-Identifier: MIT
#include "render/png_writer.h"

#include "scene/atomic_file.h"
#include "scene/errors.h"

#include <stb/stb_image_write.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>

namespace occ::render {

void writePng(const std::string& path, uint32_t width, uint32_t height, int channels, const uint8_t* pixels) {
    AtomicFile file(path);
    // Bottom row first in memory, top row first in the file.
    stbi_flip_vertically_on_write(1);
    const auto sink = [](void* context, void* data, int size) {
        static_cast<AtomicFile*>(context)->write(data, size_t(size));
    };
    if (!stbi_write_png_to_func(sink, &file, int(width), int(height), channels, pixels, int(width) * channels))
        throw InputError(path, "cannot encode the PNG");
    file.commit();
}

std::vector<uint8_t> depthToGrey(const float* depth, uint64_t count) {
    float lo = 1.0f, hi = 0.0f;
    for (uint64_t i = 0; i < count; ++i)
        if (depth[i] < 1.0f) lo = std::min(lo, depth[i]), hi = std::max(hi, depth[i]);
    std::vector<uint8_t> grey(count, 0);
    const float range = hi > lo ? hi - lo : 1.0f;
    for (uint64_t i = 0; i < count; ++i)
        if (depth[i] < 1.0f) grey[i] = uint8_t(255.0f - 215.0f * std::clamp((depth[i] - lo) / range, 0.0f, 1.0f));
    return grey;
}

}  // namespace occ::render
