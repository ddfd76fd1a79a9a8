// SPDX-License-Identifier: MIT
#pragma once

#include "hzm.h"
#include "device_memory.h"
#include "kernel_types.h"

#include <cstdint>

namespace occ::k {

// Conservative occlusion test of object boxes against the max-depth pyramid (HZM test of Peng &
// Cao 2013, Eq. 5; our Eq. 4). For j < count, with i = ids[j] an index into objects, writes
// occluded[j] = 1 if every pixel objects[i].aabb could cover already holds a nearer depth, else 0:
//
// - The 8 box corners are projected with camera.view_proj. If any has clip.w <= near_plane or
//   clip.z < -clip.w (on or behind the near plane), the box crosses the near plane: 0.
// - Otherwise the corners' window rectangle, x = (ndc.x*0.5+0.5)*W and y = (ndc.y*0.5+0.5)*H
//   (y up) with W x H = hzm.width[0] x hzm.height[0] (camera.width and height are not read), and
//   their nearest window depth z_min = min(ndc.z*0.5+0.5) bound the box's image. A rectangle
//   entirely outside the viewport gives 0: culling what is off screen is frustumCull's job, and
//   no texel can prove such a box occluded.
// - The level-0 pixels the rectangle touches, [floor(xmin), floor(xmax)] x [floor(ymin),
//   floor(ymax)] clipped to the viewport, are first looked up at the finest level l at which
//   they span at most 2x2 texels (pixel p lies under texel p >> l). That is ceil(log2(pixels
//   across)) or one below it; if the pyramid stops before, its top level is read whole.
// - occluded[j] = 1 iff z_min > depth + 1e-6 at every level-0 pixel of the rectangle. A texel
//   that proves it (z_min > texel + 1e-6: the box's nearest point is strictly farther than the
//   farthest depth drawn under the texel) settles its pixels; one that does not is opened into
//   its children in the rectangle, down to level 0 if need be.
//
// So it says exactly what the test against every level-0 pixel of the rectangle says, reading
// at most 4 texels for a box the coarse level proves hidden. Depth is window depth in [0, 1], 0 = near plane,
// larger is farther (see Camera); level 0 of the pyramid is the occluders' depth buffer (cleared
// to 1 = far) rendered with the same view_proj at W x H. view_proj must be a perspective
// projection (clip.w = distance in front of the eye), as the near-plane rule relies on it.
//
// objects holds every object, ids has count indices into it (count may be 0), occluded room for
// count bytes, hzm.data all levels; all in device memory. If hzm.level_count is 0 every box is
// visible. Boxes in parallel; a box reads at most 4 texels when the coarse level settles it,
// and at most about 4/3 of its rectangle's pixels otherwise.
void hzmTest(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count, const Camera& camera,
             const HzmLevels& hzm, DevicePtr<uint8_t> occluded);

// hzmTest with one thread a box as the CUDA build runs it, whatever the build: on the CPU, the
// reference that hzmTest's SIMD box images (kernels/hzm_test_cpu.cpp) must match bit for bit.
void hzmTestScalar(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                   const Camera& camera, const HzmLevels& hzm, DevicePtr<uint8_t> occluded);

// Visibility weighting (Charalambos 2006's q / alpha, estimated): for j < count, share[j] = the
// share of objects[ids[j]]'s image an occlusion query of the box would find visible, sampled at
// the finest level where the box's rectangle (as hzmTest projects it) spans at most 8 x 8
// texels: one ray per texel (through the middle of its part of the rectangle) is cut with the
// box, and its entry depth compared with the texel's; the pixels of the texels whose ray enters
// the box in front of the texel, over those of the texels whose ray enters it at all. A box no
// ray meets counts the pixels under texels that do not hide its nearest point, over its
// rectangle's. In [0, 1]; 1 for a box crossing the near plane, off screen, or with no pyramid.
// Reads at most 64 texels per box.
void hzmVisibleShare(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                     const Camera& camera, const HzmLevels& hzm, DevicePtr<float> share);

}  // namespace occ::k
