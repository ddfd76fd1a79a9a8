// SPDX-License-Identifier: MIT
#pragma once

// What both glTF readers share: the whole-file importer (tinygltf, gltf_import.cpp) and the
// streaming one prep uses for large files (gltf_stream.cpp). Constants are the spec's.

#include <glm/glm.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace occ::gltf {

inline constexpr int kByte = 5120, kUnsignedByte = 5121, kShort = 5122, kUnsignedShort = 5123,
                     kUnsignedInt = 5125, kFloat = 5126;
inline constexpr int kPoints = 0, kLines = 1, kLineLoop = 2, kLineStrip = 3, kTriangles = 4, kTriangleStrip = 5,
                     kTriangleFan = 6;
// The binary container (GLB): its magic and its two chunk types.
inline constexpr uint32_t kGlbMagic = 0x46546C67;      // "glTF"
inline constexpr uint32_t kGlbChunkJson = 0x4E4F534A;  // "JSON"
inline constexpr uint32_t kGlbChunkBin = 0x004E4942;   // "BIN\0"

// The extensions the importers read (the geometry ones) or may ignore (they change how a
// model looks, not its triangles). Any other required extension is refused by name.
bool isSupportedExtension(const std::string& name);

// Bytes per component of a glTF component type (0 for an unknown one).
size_t componentSize(int type);

// One unsigned integer component (an index).
uint32_t indexValue(const unsigned char* p, int type);

// One component as a float: normalized integers as the spec maps them to [-1, 1] or [0, 1],
// others by value (KHR_mesh_quantization puts the dequantization into the node transform).
float componentValue(const unsigned char* p, int type, bool normalized);

// A primitive's indices of `mode` (triangles, strip, fan) as a triangle list, one winding;
// InputError naming `path` for a list that is not a multiple of 3 or another mode.
void triangulatePrimitive(const std::string& path, int mode, const std::vector<uint32_t>& raw,
                          std::vector<uint32_t>& out);

// A node's local transform as glTF defines it: its matrix (16 column-major values) when it has
// one, else translation * rotation (x, y, z, w) * scale, composed in double; null arguments
// take their defaults. InputError naming `path` and /nodes/`node` for a non-finite result.
glm::mat4 nodeMatrix(const std::string& path, size_t node, const double* matrix, const double* translation,
                     const double* rotation, const double* scale);

}  // namespace occ::gltf
