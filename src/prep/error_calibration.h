// SPDX-License-Identifier: MIT
#pragma once

#include "prep/collapse_sequence.h"

#include <cstdint>

namespace occ {

struct ErrorCalibration {
    uint32_t levels_measured = 0;  // levels whose distance to the full detail was measured
    float largest_factor = 1.0f;   // the largest factor a segment's errors were multiplied by
};

// Makes a progressive mesh's recorded errors distances that tau can trust. The collapser
// records an area-weighted RMS distance to each collapse's planes, which understates how far a
// level strays (a closed hole, a thin wall folded flat: most planes are met, one is far), by a
// factor that differs from mesh to mesh and from level to level. Here the levels that quarter
// the triangle count, from the full detail down to q, are measured against the full detail
// (sampled symmetric Hausdorff distance: `samples` area samples per surface, and up to 128 of
// the full detail's vertices the level dropped; its own are at distance 0; a point of the full
// detail counts at most the extent of its connected component, which is how much of the picture
// a component that vanishes whole can change, e.g. an HLOD's small objects); each measured
// level has a ratio measured / recorded (never below 1), and a collapse error between two
// measured levels is multiplied by a factor going geometrically from one's ratio to the
// other's; a measured level's error is then raised to its measured distance where that is
// still larger. So at every measured level the level's error (the suffix maximum of pm.error)
// is at least the distance measured there, and between them it follows the collapses' own
// ranking. Only pm.error changes.
ErrorCalibration calibrateRecordedErrors(ProgressiveMesh& pm, uint32_t samples = 32);

}  // namespace occ
