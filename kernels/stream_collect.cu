// SPDX-License-Identifier: MIT
#include "stream_collect.h"
#include "layout_access.h"
#include "host_side.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/scan.h>
#include <thrust/sort.h>
#include <thrust/transform.h>

#include <stdexcept>

namespace occ::k {

namespace {

struct StagedLength {
    BlockColumn previous, current;
    OCC_HD uint32_t operator()(uint32_t j) const {
        return current.size[j] - keptPrefix(previous, current, j).length;
    }
};

// Copies the staged elements of one tile: element kept + i of block j comes from the block's
// object's mesh. T is one element of width W (a vertex, or a triangle's 3 corners).
template <class T, int W>
struct GatherTile {
    BlockColumn current;
    const uint32_t* staged_length;  // per block: size - kept
    const uint64_t* staged_offset;  // exclusive scan of the staged lengths
    uint64_t staged_total;
    const T* source;                // mesh after mesh, W per element
    const uint64_t* mesh_first;     // per mesh, in elements
    const ObjectInfo* objects;
    T* staging;

    void operator()(uint64_t tile) const {
        const uint64_t begin = tile * kHostRunTile;
        const uint64_t end = begin + kHostRunTile < staged_total ? begin + kHostRunTile : staged_total;
        forEachRun(staged_offset, current.count, staged_total, begin, end,
                   [&](uint32_t j, uint64_t first, uint64_t length) {
                       const uint64_t kept = current.size[j] - staged_length[j];
                       const uint64_t from = mesh_first[objects[current.objects[j]].mesh] + kept + first;
                       const T* src = source + W * from;
                       T* dst = staging + W * (staged_offset[j] + first);
                       for (uint64_t i = 0; i < W * length; ++i) dst[i] = src[i];
                   });
    }
};

// Staging and the host-side bookkeeping: at least n elements, growing by half again.
template <class T>
void reserve(std::vector<T>& v, uint64_t n) {
    if (n > v.size()) v.resize(n + n / 2);
}

// Stages one column (the vertex or the triangle blocks); returns the element count.
template <class T, int W>
uint64_t collect(const BlockColumn& previous, const BlockColumn& current, const T* source,
                 const uint64_t* mesh_first, const ObjectInfo* objects, PinnedArray<T>& staging,
                 StagingBuffers& bookkeeping) {
    if (current.count == 0) return 0;
    reserve(bookkeeping.lengths, current.count);
    reserve(bookkeeping.offsets, current.count);
    uint32_t* lengths = bookkeeping.lengths.data();
    uint64_t* offsets = bookkeeping.offsets.data();
    const thrust::counting_iterator<uint32_t> entries(0);
    thrust::transform(kHostSide, entries, entries + current.count, lengths, StagedLength{previous, current});
    const auto wide = thrust::make_transform_iterator(lengths, Widen());
    thrust::exclusive_scan(kHostSide, wide, wide + current.count, offsets, uint64_t(0));
    const uint64_t total = offsets[current.count - 1] + lengths[current.count - 1];
    if (total == 0) return 0;

    staging.growTo(W * total);
    const uint64_t tiles = (total + kHostRunTile - 1) / kHostRunTile;
    thrust::for_each_n(kHostSide, thrust::counting_iterator<uint64_t>(0), tiles,
                       GatherTile<T, W>{current, lengths, offsets, total, source, mesh_first, objects, staging.data()});
    return total;
}

}  // namespace

StreamCounts streamCollect(const HostLayout& previous, const HostLayout& current, const HostGeometry& host,
                           StagingBuffers& staging) {
    // Blocks are matched across frames by binary search on the ids.
    if (!thrust::is_sorted(kHostSide, current.objects, current.objects + current.count,
                           thrust::less_equal<uint32_t>()))
        throw std::invalid_argument("streamCollect: the current layout's object ids are not strictly ascending");
    StreamCounts counts;
    counts.vertices = collect<glm::vec3, 1>(vertexBlocks(previous), vertexBlocks(current), host.positions,
                                            host.vertex_first, host.objects, staging.vertices, staging);
    counts.triangles = collect<uint32_t, 3>(triangleBlocks(previous), triangleBlocks(current), host.triangles,
                                            host.triangle_first, host.objects, staging.triangles, staging);
    staging.vertex_count = counts.vertices;
    staging.triangle_count = counts.triangles;
    // The transfer: what was gathered, and nothing else, crosses the bus.
    staging.device_vertices.growTo(counts.vertices);
    staging.device_triangles.growTo(3 * counts.triangles);
    copyToDevice(staging.device_vertices.ptr(), staging.vertices.data(), counts.vertices);
    copyToDevice(staging.device_triangles.ptr(), staging.triangles.data(), 3 * counts.triangles);
    return counts;
}

}  // namespace occ::k
