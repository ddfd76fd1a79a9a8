// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

// The six planes of the view volume of view_proj (OpenGL clip space, z in [-w, w]), extracted
// from its rows as in Gribb & Hartmann, "Fast extraction of viewing frustum planes from the
// world-view-projection matrix", 2001: left = row3 + row0, right = row3 - row0, bottom, top,
// near = row3 + row2, far = row3 - row2. Each plane is scaled so |n| = 1 (a plane whose n is
// zero, which only a degenerate matrix gives, is left as it is); n points inside. Order as in
// Frustum: left, right, bottom, top, near, far.
Frustum frustumFromViewProj(const glm::mat4& view_proj);

// Writes in_frustum[i] = 1 if objects[i].aabb may intersect the frustum, else 0, for i < count,
// writes the ids i with a 1, ascending, to ids (count entries of room; null: not wanted) and
// returns how many there are (4 bytes back to the host).
//
// The test is the conservative p-vertex test: a box is rejected only when, for one plane, its
// corner farthest along the inward normal is outside (by more than 1e-6 of the magnitude of the
// terms, so rounding never rejects a box that touches the frustum). So it never says 0 for a box
// that intersects the frustum; it may say 1 for a box that is just outside near an edge or a
// corner of the frustum. A box that contains the whole frustum, and a box with a NaN
// coordinate, get 1; a box around the eye that ends before the near plane gets 0.
//
// objects has `count` entries and in_frustum `count` bytes, both in device memory; count may be
// 0. Objects are tested in parallel.
uint32_t frustumCull(DevicePtr<const ObjectInfo> objects, uint32_t count, const Frustum& frustum,
                     DevicePtr<uint8_t> in_frustum, DevicePtr<uint32_t> ids = nullptr);

// The same test for the listed items only (with the hierarchy no frame tests every item): for
// j < count, in_frustum[ids[j]] = whether objects[ids[j]] may intersect the frustum (the flags of
// unlisted items are left as they were); the listed ids in the frustum, in list order, go to out
// (room for count, not overlapping ids), and their number is returned (4 bytes back to the host).
uint32_t frustumCullIds(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                        const Frustum& frustum, DevicePtr<uint8_t> in_frustum, DevicePtr<uint32_t> out);

}  // namespace occ::k
