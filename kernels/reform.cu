// SPDX-License-Identifier: MIT
#include "reform.h"

#include "layout_access.h"


namespace occ::k {

namespace {

struct TrianglesOf {
    const ReformBlock* blocks;
    OCC_HD uint32_t operator()(uint32_t j) const { return blocks[j].triangle_count; }
};

struct ReformTile {
    const ReformBlock* blocks;
    const uint64_t* work_offset;
    uint32_t count;
    uint64_t total;
    const ObjectInfo* objects;
    const uint64_t* vertex_first;
    const int32_t* ecol;
    const uint32_t* triangles;
    uint32_t* indices;

    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(work_offset, count, total, tile * kRunTile, tileEnd(tile, total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
            const ReformBlock& block = blocks[j];
            const uint32_t vc = block.walk_vertex_count;
            if (vc == 0) return;  // resident but not drawn this frame
            const ObjectInfo& object = objects[block.object];
            const uint64_t corner = 3 * (block.triangle_offset + first);
            const uint32_t* in = triangles + corner;
            uint32_t* out = indices + corner;
            if (vc >= object.vertex_count) {  // full detail: every corner is < vc already
                for (uint64_t k = 0; k < 3 * length; ++k) out[k] = in[k];
                return;
            }
            const int32_t* object_ecol = ecol + vertex_first[object.mesh];
            for (uint64_t t = 0; t < length; ++t) {
                // A branch per corner on "must it walk?" is a coin toss the CPU mispredicts, and
                // that, not the loads, dominates. So the three corners take their first two steps
                // together with selects instead (every load is in bounds, c < P); walks are 1.3
                // to 1.6 steps long on average, so the loop after them rarely runs.
                uint32_t a = in[3 * t], b = in[3 * t + 1], c = in[3 * t + 2];
                for (int step = 0; step < 2; ++step) {
                    const uint32_t na = uint32_t(object_ecol[a]);
                    const uint32_t nb = uint32_t(object_ecol[b]);
                    const uint32_t nc = uint32_t(object_ecol[c]);
                    a = a < vc ? a : na;
                    b = b < vc ? b : nb;
                    c = c < vc ? c : nc;
                }
                while (a >= vc || b >= vc || c >= vc) {
                    a = a < vc ? a : uint32_t(object_ecol[a]);
                    b = b < vc ? b : uint32_t(object_ecol[b]);
                    c = c < vc ? c : uint32_t(object_ecol[c]);
                }
                out[3 * t] = a;
                out[3 * t + 1] = b;
                out[3 * t + 2] = c;
            }
        });
    }
};

}  // namespace

uint64_t reformBlocks(DevicePtr<const ReformBlock> blocks, uint32_t count, DevicePtr<const ObjectInfo> objects,
                      DevicePtr<const uint64_t> vertex_first, DevicePtr<const int32_t> ecol,
                      DevicePtr<const uint32_t> active_triangles, DevicePtr<uint32_t> indices, ReformScratch& scratch) {
    return forEachBlockTile(count, TrianglesOf{raw(blocks)}, scratch.lengths, scratch.offsets,
                            [&](const uint64_t* work_offset, uint64_t total) {
                                return ReformTile{raw(blocks), work_offset, count, total, raw(objects),
                                                  raw(vertex_first), raw(ecol), raw(active_triangles), raw(indices)};
                            });
}

}  // namespace occ::k
