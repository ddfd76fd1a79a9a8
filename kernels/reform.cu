// SPDX-License-Identifier: MIT
#include "reform.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

struct ReformTile {
    ActiveLayout layout;
    const ObjectInfo* objects;
    const uint64_t* vertex_first;
    const int32_t* ecol;
    const uint32_t* triangles;
    uint32_t* indices;

    OCC_HD void operator()(uint64_t tile) const {
        const uint64_t total = layout.triangle_total;
        const uint64_t begin = tile * kRunTile, end = begin + kRunTile < total ? begin + kRunTile : total;
        forEachRun(layout.triangle_offset, layout.count, total, begin, end,
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint32_t vc = layout.vertex_count[j];
                       const uint32_t offset = uint32_t(layout.vertex_offset[j]);
                       const int32_t* object_ecol = ecol + vertex_first[objects[layout.objects[j]].mesh];
                       const uint64_t corner = 3 * (layout.triangle_offset[j] + first);
                       const uint32_t* in = triangles + corner;
                       uint32_t* out = indices + corner;
                       for (uint64_t k = 0; k < 3 * length; ++k) {
                           // The first step is taken without a branch: the load is always in
                           // bounds (c < P) and a select replaces a branch the CPU would
                           // mispredict on every walked corner. Most walks end after it.
                           uint32_t c = in[k];
                           const uint32_t next = uint32_t(object_ecol[c]);
                           c = c < vc ? c : next;
                           while (c >= vc) c = uint32_t(object_ecol[c]);
                           out[k] = offset + c;
                       }
                   });
    }
};

}  // namespace

void reform(const ActiveLayout& layout, const ObjectInfo* objects, const uint64_t* vertex_first, const int32_t* ecol,
            const uint32_t* active_triangles, uint32_t* indices) {
    if (layout.triangle_total == 0) return;
    thrust::for_each_n(thrust::device, thrust::counting_iterator<uint64_t>(0),
                       (layout.triangle_total + kRunTile - 1) / kRunTile,
                       ReformTile{layout, objects, vertex_first, ecol, active_triangles, indices});
}

}  // namespace occ::k
