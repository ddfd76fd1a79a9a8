// SPDX-License-Identifier: MIT
#include "import/gltf_common.h"

#include "scene/errors.h"

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>

#include <algorithm>
#include <cmath>
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

glm::mat4 nodeMatrix(const std::string& path, size_t node, const double* matrix, const double* translation,
                     const double* rotation, const double* scale) {
    glm::mat4 m(1.0f);
    if (matrix) {
        m = glm::mat4(glm::make_mat4(matrix));
    } else {
        const glm::dvec3 t = translation ? glm::make_vec3(translation) : glm::dvec3(0.0);
        const glm::dvec3 s = scale ? glm::make_vec3(scale) : glm::dvec3(1.0);
        const glm::dquat r = rotation ? glm::dquat(rotation[3], rotation[0], rotation[1], rotation[2])
                                      : glm::dquat(1.0, 0.0, 0.0, 0.0);
        m = glm::mat4(glm::translate(glm::dmat4(1.0), t) * glm::mat4_cast(r) * glm::scale(glm::dmat4(1.0), s));
    }
    for (int c = 0; c < 4; ++c)
        for (int k = 0; k < 4; ++k)
            if (!std::isfinite(m[c][k]))
                throw InputError(path, "/nodes/" + std::to_string(node) + ": non-finite (nan or inf) transform");
    return m;
}

}  // namespace occ::gltf
