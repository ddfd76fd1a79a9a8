// SPDX-License-Identifier: MIT
#pragma once

#include "hzm.h"

namespace occ::k {

// Builds levels 1.. of the max-depth pyramid (HZM, Peng 2014) in place, laid out as hzmLayout
// says: `levels` holds hzmTotalTexels(width, height) floats in device memory whose first
// width*height are the depth buffer (level 0, read only); every later level is overwritten, each
// texel the MAX of the (up to) 2x2 texels below it. One parallel pass per level, over its texels.
// width and height in [1, 32768]; a 1x1 buffer is its own pyramid and nothing is written.
void hzmBuild(DevicePtr<float> levels, uint32_t width, uint32_t height);

}  // namespace occ::k
