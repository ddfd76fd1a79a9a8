// SPDX-License-Identifier: MIT
#pragma once

#include "scene/scene.h"

#include <string>

namespace occ {

// Imports a model by its file name extension:
//   .gltf / .glb          glTF 2.0 (tinygltf): the default scene, node transforms flattened,
//                         one object per (node, triangle primitive), instanced meshes shared;
//   .obj                  OpenMesh's reader, one object per group ("g"/"o"), or one per file;
//   .ply / .off / .stl    OpenMesh's readers, one object per file.
// Polygons are fan-triangulated; points and lines are skipped and counted in Scene::skipped.
// Throws InputError("FILE: what") for anything unreadable or invalid (bad magic, truncation,
// indices out of range, non-finite positions, node cycles, no triangles at all, ...).
Scene importModel(const std::string& path);

// The file name's extension in lower case, with its dot (".glb"), or "" if it has none.
std::string lowerExtension(const std::string& path);

// Per-format entry points used by importModel; same contract.
Scene importGltf(const std::string& path);
Scene importWithOpenMesh(const std::string& path);

}  // namespace occ
