// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

namespace occ::k {

// Orders the occluder ids[0, count) (device memory, count may be 0) front to back: by the
// distance from camera.eye to each object's box (0 for an eye inside it), nearest first, equal
// distances in their given order. The masked raster (masked_raster.h) merges a subtile's layers
// in triangle order, and near occluders first let it fill subtiles with near depths and pass
// over what lies behind them (Hasselgren et al. 2016 render front to back for that reason).
// keys: scratch, grown to count floats.
void sortFrontToBack(DevicePtr<const ObjectInfo> objects, DevicePtr<uint32_t> ids, uint32_t count,
                     const Camera& camera, DeviceArray<float>& keys);

}  // namespace occ::k
