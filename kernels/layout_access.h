// SPDX-License-Identifier: MIT
#pragma once

// For kernel sources only: a device layout's raw pointers, for functors that run on the device.
#include "block_runs.h"
#include "device_access.h"

namespace occ::k {

// A device layout with raw pointers, for functors that run on the device.
inline HostLayout rawLayout(const ActiveLayout& layout) {
    return {raw(layout.objects), raw(layout.vertex_count), raw(layout.triangle_count), raw(layout.vertex_offset),
            raw(layout.triangle_offset), layout.count, layout.vertex_total, layout.triangle_total};
}
inline BlockColumn vertexBlocks(const ActiveLayout& layout) { return vertexBlocks(rawLayout(layout)); }
inline BlockColumn triangleBlocks(const ActiveLayout& layout) { return triangleBlocks(rawLayout(layout)); }

}  // namespace occ::k
