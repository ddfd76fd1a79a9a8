// SPDX-License-Identifier: MIT
#pragma once

#include "prep/collapse_sequence.h"

namespace occ {

// The reference collapse sequence: OpenMesh's Decimater with ModQuadric, run to the end, and a
// module of ours (CollapseRecorder) that records every half-edge collapse in
// postprocess_collapse. Boundary vertices are locked. Faces OpenMesh refuses to add (complex
// edges of non-manifold CAD input) are kept as they are, never collapsed (their vertices are
// locked) and counted in CollapseSequence::refused_faces.
// Same input contract as fastCollapseSequence; about 55 K triangles/s on one core here.
CollapseSequence openMeshCollapseSequence(const std::vector<glm::vec3>& positions,
                                          const std::vector<uint32_t>& triangles);

}  // namespace occ
