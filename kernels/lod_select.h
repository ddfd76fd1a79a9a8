// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

namespace occ::k {

struct LodParams {
    float budget;  // N: vertices to spend over the listed objects, >= 0
    float alpha;   // exponent of Eq. 1, >= 1 (Peng & Cao use 3; 1 shares the budget equally)
    float pet;     // pixel error threshold: objects covering fewer pixels are not drawn
    // Visibility weighting: per listed object (count entries, device memory) the share of its
    // image left visible (hzmVisibleShare); A_i becomes A_i x share[j] in Eq. 1's weight, and
    // the error-bounded rule allows an error tau / share[j] (Charalambos 2006's eps q / alpha).
    // Null: A_i as projected.
    DevicePtr<const float> visible_share = nullptr;
};

// LOD selection, Eq. 1 of Peng & Cao 2013 as reconstructed for occswitch. For each listed object
// i = ids[j] (j < count; ids index `objects`):
//   A_i  pixels of the bounding rectangle of its projected AABB, clamped to the viewport; an AABB
//        with a corner nearer than the near plane gets the whole viewport and D_i = near_plane,
//   D_i  nearest view depth (along camera.forward) over the AABB corners, at least near_plane,
//   P_i  = objects[i].vertex_count, q_i = min(objects[i].q, P_i),
//   w_i  = (A_i P_i / D_i)^(alpha - 1), share s_i = w_i^(1/alpha),
//   vc_i = clamp(lambda s_i, q_i, P_i) rounded to nearest, and 0 when A_i < pet or P_i = 0.
// lambda solves sum_i clamp(lambda s_i, q_i, P_i) = budget, then is lowered just enough for the
// rounded levels to fit: N s_i / sum s_j when nothing clamps, and the water-filling of Peng & Cao
// when some objects clamp (what an object capped at P_i or raised to q_i leaves over or takes is
// shared by the others in proportion to s). If the floors alone exceed the budget every drawn
// object gets q_i. Rounding typically leaves a few vertices per hundred objects unspent.
//
// vertex_count and triangle_count (device memory, count entries each) receive vc_i and
// tc_i = map_i[vc_i] (0 when vc_i = 0), map_i being maps + map_first[objects[i].mesh] (device
// memory; each mesh's map has its vertex count + 1 entries). ids may be in any order and may be
// empty (count = 0). shares is scratch kept by the caller (grows to count floats). Returns
// sum vc_i: at most budget unless the floors force more. The solve reads back one small sum per
// pass (typically 5 to 10 passes of 24 bytes).
uint64_t lodSelect(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                   const Camera& camera, const LodParams& params, DevicePtr<const uint64_t> map_first,
                   DevicePtr<const uint32_t> maps, DevicePtr<uint32_t> vertex_count,
                   DevicePtr<uint32_t> triangle_count, DeviceArray<float>& shares);

// Error-bounded LOD (SWITCH's and CHLOD's rule, `--lod error`): for each listed object the
// coarsest level whose simplification error projects to at most tau pixels: the smallest
// vc_i in [q_i, P_i] with (lod_error_i[vc_i] * scale[i] + offset_i) * H / (2 tan(fovy / 2) D_i)
// <= tau (offset_i = error_offset[i], world units, what an HLOD's input already gave up; 0 when
// error_offset is null), D_i, A_i and pet as lodSelect's (0 when A_i < pet or P_i = 0). lod_error + map_first[mesh]
// holds, per mesh, vertex_count + 1 non-increasing entries: the largest collapse error of the
// level with k vertices, in object space (0 at full detail); scale[i] is how much object i's
// world matrix enlarges lengths at most. Writes vertex_count and triangle_count as lodSelect
// does and returns sum vc_i. No budget: the error bounds the picture, the count follows.
// hint (null, or one entry per item, by id): where each search starts, then the level found
// (levelWithinErrorNear): a level moves little from frame to frame, so the next frame's search
// costs a probe or two; the levels chosen do not depend on it.
uint64_t lodSelectByError(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                          const Camera& camera, float tau, float pet, DevicePtr<const float> visible_share,
                          DevicePtr<const uint64_t> map_first,
                          DevicePtr<const float> lod_error, DevicePtr<const float> scale,
                          DevicePtr<const float> error_offset, DevicePtr<const uint32_t> maps,
                          DevicePtr<uint32_t> vertex_count, DevicePtr<uint32_t> triangle_count,
                          DevicePtr<uint32_t> hint = nullptr);

// The error bound as a floor under a level already chosen (the budget rule with a hierarchy,
// issue 49: the budget may draw finer than tau allows, never coarser): for each listed object
// the level lodSelectByError would choose, where it is finer than vertex_count[j] (which then
// takes it, and triangle_count[j] its triangles); levels at least as fine stay. A level of 0
// (not drawn: A_i < pet) is raised only where the bound draws the object. Same arguments as
// lodSelectByError; returns the new sum of vc_i. A level already within the bound is kept after
// one probe of its error; the hint is used and written only where the level is raised. A raised
// level goes on up to levelOnRaiseGrid(level, P_i, raise_step) (0: stays at the bound's level),
// so that a bound that moves with the camera changes it only now and then.
uint64_t lodRaiseToErrorBound(DevicePtr<const ObjectInfo> objects, DevicePtr<const uint32_t> ids, uint32_t count,
                              const Camera& camera, float tau, float pet, DevicePtr<const float> visible_share,
                              DevicePtr<const uint64_t> map_first, DevicePtr<const float> lod_error,
                              DevicePtr<const float> scale, DevicePtr<const float> error_offset,
                              DevicePtr<const uint32_t> maps, DevicePtr<uint32_t> vertex_count,
                              DevicePtr<uint32_t> triangle_count, DevicePtr<uint32_t> hint = nullptr,
                              float raise_step = 0.0f);

}  // namespace occ::k
