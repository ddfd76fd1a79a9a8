// SPDX-License-Identifier: MIT
#include "import/gltf_common.h"

#include "scene/errors.h"

#include <algorithm>
#include <cstring>

namespace occ::gltf {

bool isSupportedExtension(const std::string& name) {
    return name.rfind("KHR_materials_", 0) == 0 || name == "KHR_texture_transform" ||
           name == "KHR_lights_punctual" || name == "KHR_texture_basisu" || name == "EXT_texture_webp" ||
           name == "KHR_mesh_quantization" || name == "EXT_mesh_gpu_instancing" || name == "EXT_meshopt_compression" ||
           name == "KHR_meshopt_compression" || name == "KHR_draco_mesh_compression";
}

size_t componentSize(int type) {
    switch (type) {
    case kByte:
    case kUnsignedByte: return 1;
    case kShort:
    case kUnsignedShort: return 2;
    case kUnsignedInt:
    case kFloat: return 4;
    default: return 0;
    }
}

uint32_t indexValue(const unsigned char* p, int type) {
    if (type == kUnsignedByte) return *p;
    if (type == kUnsignedShort) {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    uint32_t v;
    std::memcpy(&v, p, 4);
    return v;
}

float componentValue(const unsigned char* p, int type, bool normalized) {
    switch (type) {
    case kByte: {
        const int8_t v = int8_t(*p);
        return normalized ? std::max(float(v) / 127.0f, -1.0f) : float(v);
    }
    case kUnsignedByte: return normalized ? float(*p) / 255.0f : float(*p);
    case kShort: {
        int16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? std::max(float(v) / 32767.0f, -1.0f) : float(v);
    }
    case kUnsignedShort: {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return normalized ? float(v) / 65535.0f : float(v);
    }
    case kUnsignedInt: {
        uint32_t v;
        std::memcpy(&v, p, 4);
        return normalized ? float(double(v) / 4294967295.0) : float(v);
    }
    default: {
        float v;
        std::memcpy(&v, p, 4);
        return v;
    }
    }
}

void triangulatePrimitive(const std::string& path, int mode, const std::vector<uint32_t>& raw,
                          std::vector<uint32_t>& out) {
    if (mode == kTriangles) {
        if (raw.size() % 3 != 0)
            throw InputError(path, "triangle list has " + std::to_string(raw.size()) + " indices, not a multiple of 3");
        out = raw;
    } else if (mode == kTriangleStrip) {
        for (size_t i = 2; i < raw.size(); ++i) {
            // Every other triangle of a strip is flipped back to keep one winding.
            const bool odd = (i % 2) == 1;
            out.insert(out.end(), {raw[i - 2 + odd], raw[i - 1 - odd], raw[i]});
        }
    } else if (mode == kTriangleFan) {
        for (size_t i = 2; i < raw.size(); ++i) out.insert(out.end(), {raw[0], raw[i - 1], raw[i]});
    } else {
        throw InputError(path, "unsupported primitive mode " + std::to_string(mode));
    }
}

}  // namespace occ::gltf
