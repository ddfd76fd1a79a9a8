// SPDX-License-Identifier: MIT
#pragma once

#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

// Per-frame weight of each candidate occluder (Eq. 3 of Peng & Cao 2013, "Integrating occlusion
// culling with parallel LOD for rendering complex 3D environments on GPU", I3D; our Eq. 3): for
// candidate j, with c = cos[j] an index into objects,
//     weight[j] = V * |N . E| / D
// where V is the volume of objects[c].aabb, N its occluder_normal, E = camera.forward and D the
// distance from camera.eye to the nearest point of the box, but at least 1e-3 of the box's
// diagonal (so an occluder the eye is inside or touching wins, with a finite weight).
// weight[j] = 0 if in_frustum[c] == 0 or the box has no volume (a box with min > max on an axis
// counts as flat on it).
//
// objects holds every object (indexed by the ids in cos), cos has cos_count ids (may be 0),
// in_frustum one byte per object (as frustumCull writes it), weight room for cos_count floats;
// all in kernel memory. Candidates in parallel.
void occluderWeight(const ObjectInfo* objects, const uint32_t* cos, uint32_t cos_count, const uint8_t* in_frustum,
                    const Camera& camera, float* weight);

// The active occluder set (AOS of Peng 2014): writes to aos the object ids of the (up to) k
// candidates with the largest weights, in decreasing weight, equal weights by increasing object
// id, and returns how many it wrote: min(k, number of candidates whose weight is > 0). Candidates
// with weight 0 (or negative, or NaN) are never chosen.
//
// cos and weight have cos_count entries (as occluderWeight takes and writes them; cos_count may
// be 0), aos has room for k ids; all in kernel memory. Allocates 8 bytes of kernel memory per
// candidate for the call. The work is a filter and one sort of 64-bit keys (weight, id) over the
// candidates with positive weight: about 1 ms for 10^5 candidates on 2 CPU cores.
uint32_t selectTopK(const uint32_t* cos, const float* weight, uint32_t cos_count, uint32_t k, uint32_t* aos);

}  // namespace occ::k
