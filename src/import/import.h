// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <string>

namespace occ {

// Imports a model by its file name extension:
//   .gltf / .glb          glTF 2.0 (tinygltf): the default scene (or options.scene), node
//                         transforms flattened, one object per (node, triangle primitive) and per
//                         EXT_mesh_gpu_instancing instance, instanced meshes shared; positions
//                         may be quantized (KHR_mesh_quantization), views meshopt-compressed
//                         (EXT_meshopt_compression), primitives Draco-compressed
//                         (KHR_draco_mesh_compression), accessors sparse;
//   .obj                  our reader, one object per group ("g"/"o"), or one per file;
//   .ply                  our reader (ASCII and binary of either byte order), one object per file;
//   .stl                  our reader (binary and ASCII, shared corners merged), one object per file;
//   .off                  our reader (OFF, COFF, NOFF, STOFF, 4OFF, nOFF, comments anywhere),
//                         one object per file.
// Polygons are triangulated by ear clipping (concave and holed ones too); points and lines are
// skipped and counted in Scene::skipped.
// Throws InputError("FILE: what") for anything unreadable or invalid (bad magic, truncation,
// indices out of range, non-finite positions, node cycles, no triangles at all, ...).
struct ImportOptions {
    // glTF: the scene to import (-1: the file's default scene, or its first). Other formats
    // hold one scene: only -1 and 0 are accepted.
    int scene = -1;
};
Scene importModel(const std::string& path, const ImportOptions& options = {});

// The file name's extension in lower case, with its dot (".glb"), or "" if it has none.
std::string lowerExtension(const std::string& path);

// Per-format entry points used by importModel; same contract.
Scene importGltf(const std::string& path, const ImportOptions& options = {});
Scene importPly(const std::string& path);
Scene importStl(const std::string& path);
Scene importOff(const std::string& path);
Scene importObj(const std::string& path);

}  // namespace occ
