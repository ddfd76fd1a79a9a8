// SPDX-License-Identifier: MIT
#include "defragment.h"

#include "layout_access.h"

namespace occ::k {

namespace {

struct WorkOf {
    const BlockMove* moves;
    OCC_HD uint32_t operator()(uint32_t j) const { return moves[j].moved + moves[j].staged; }
};

// Element i of block j's work: the moved prefix first, then the staged part after the kept one.
template <class T, int W>
struct PlaceMoved {
    const BlockMove* moves;
    const uint64_t* work_offset;
    uint32_t count;
    uint64_t total;
    const T* src;
    const T* staging;
    T* dst;
    OCC_HD void operator()(uint64_t tile) const {
        forEachRun(work_offset, count, total, tile * kRunTile, tileEnd(tile, total),
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const BlockMove m = moves[j];
                       for (uint64_t i = first; i < first + length; ++i) {
                           const T* from = i < m.moved ? src + W * (m.from + i)
                                                       : staging + W * (m.staged_offset + i - m.moved);
                           T* to = dst + W * (m.to + (i < m.moved ? i : m.kept + i - m.moved));
                           for (int w = 0; w < W; ++w) to[w] = from[w];
                       }
                   });
    }
};

template <class T, int W>
uint64_t apply(DevicePtr<const BlockMove> moves, uint32_t count, DevicePtr<const T> src, DevicePtr<T> dst,
               DevicePtr<const T> staging, ActiveArrays& scratch) {
    return forEachBlockTile(count, WorkOf{raw(moves)}, scratch.lengths, scratch.offsets,
                            [&](const uint64_t* work_offset, uint64_t total) {
                                return PlaceMoved<T, W>{raw(moves), work_offset, count, total, raw(src), raw(staging),
                                                   raw(dst)};
                            });
}

}  // namespace

uint64_t defragmentVertices(DevicePtr<const BlockMove> moves, uint32_t count, DevicePtr<const glm::vec3> src,
                            DevicePtr<glm::vec3> dst, DevicePtr<const glm::vec3> staging, ActiveArrays& scratch) {
    return apply<glm::vec3, 1>(moves, count, src, dst, staging, scratch);
}

uint64_t defragmentTriangles(DevicePtr<const BlockMove> moves, uint32_t count, DevicePtr<const uint32_t> src,
                             DevicePtr<uint32_t> dst, DevicePtr<const uint32_t> staging, ActiveArrays& scratch) {
    return apply<uint32_t, 3>(moves, count, src, dst, staging, scratch);
}

StreamCounts streamObjectByObject(const StreamBlock* blocks, uint32_t count, const HostGeometry& host,
                                  DevicePtr<glm::vec3> vertices, DevicePtr<uint32_t> triangles) {
    StreamCounts counts;
    for (uint32_t j = 0; j < count; ++j) {
        const StreamBlock& b = blocks[j];
        const uint32_t mesh = host.objects[b.object].mesh;
        copyToDevice(vertices + (b.vertex_offset + b.vertex_kept), host.positions + host.vertex_first[mesh] + b.vertex_kept,
                     b.vertex_staged);
        copyToDevice(triangles + 3 * (b.triangle_offset + b.triangle_kept),
                     host.triangles + 3 * (host.triangle_first[mesh] + b.triangle_kept), 3 * uint64_t(b.triangle_staged));
        counts.vertices += b.vertex_staged;
        counts.triangles += b.triangle_staged;
    }
    return counts;
}

}  // namespace occ::k
