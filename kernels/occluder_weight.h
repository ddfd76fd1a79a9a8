// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
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
// all in device memory. Candidates in parallel. Any id list and byte mask will do: the pipeline
// passes the frustum's ids with a mask of COS membership where the COS is much larger.
void occluderWeight(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> cos, uint32_t cos_count,
                    DevicePtr<const uint8_t> in_frustum, const Camera& camera, DevicePtr<float> weight);

// The active occluder set (AOS of Peng 2014): writes to aos the object ids of the (up to) k
// candidates with the largest weights, in decreasing weight, equal weights by increasing object
// id, and returns how many it wrote: min(k, number of candidates whose weight is > 0). Candidates
// with weight 0 (or negative, or NaN) are never chosen.
//
// cos and weight have cos_count entries (as occluderWeight takes and writes them; cos_count may
// be 0), aos has room for k ids; all in device memory. keys is scratch kept by the caller (it
// grows to 8 bytes per candidate). The work is a filter and one sort of 64-bit keys (weight, id)
// over the candidates with positive weight: about 1 ms for 10^5 candidates on 2 CPU cores.
uint32_t selectTopK(DevicePtr<const uint32_t> cos, DevicePtr<const float> weight, uint32_t cos_count, uint32_t k,
                    DevicePtr<uint32_t> aos, DeviceArray<uint64_t>& keys);

// Scratch of selectPvsOccluders, kept by the caller between frames; contents are meaningless
// between calls. `taken` must be all zero when first used (the call leaves it so).
struct PvsOccluderScratch {
    DeviceArray<uint64_t> keys;
    DeviceArray<uint8_t> taken;   // one byte per object
    DeviceArray<uint32_t> chosen;  // the count, read back
};

// Beyond the papers, the two-pass idea of occlusion-switches and GPU-driven renderers: what was
// visible in an earlier frame is likely to occlude now. Of candidates[0, count) (object ids; one
// listed twice is taken once), those in the frustum (in_frustum as frustumCull writes it) and
// with compactness >= 0 (an HLOD has -1: not the real surface, never an occluder) are ranked by most
// screen per rastered triangle first: (|aabb diagonal| / D)^2 x compactness / max(1, triangles),
// D the distance from the eye to the box, at least camera.near_plane; equal scores by increasing
// id. Then, in that order and skipping ids of exclude[0, exclude_count) (the AOS),
// each is taken while the triangles taken so far plus its own stay within triangle_budget.
// Writes the taken ids to out in rank order (room for count) and returns how many. All arrays
// in device memory; `scratch.taken` is sized by the caller to the object count and zeroed once.
// The ranking is parallel; the greedy pass is one device thread (candidates are one PVS, a few
// thousand ids).
uint32_t selectPvsOccluders(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> candidates, uint32_t count,
                            DevicePtr<const uint8_t> in_frustum, const Camera& camera,
                            DevicePtr<const uint32_t> exclude, uint32_t exclude_count, uint64_t triangle_budget,
                            PvsOccluderScratch& scratch, DevicePtr<uint32_t> out);

// How many of ids[0, count) (device memory) are in the frustum (in_frustum as frustumCull
// writes it): the occluder pass's test for a camera that jumped. Reads back 4 bytes.
uint32_t countInFrustum(DevicePtr<const uint32_t> ids, uint32_t count, DevicePtr<const uint8_t> in_frustum);

}  // namespace occ::k
