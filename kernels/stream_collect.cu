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

// Copies the staged elements of one tile: element kept + i of list entry j comes from the
// entry's object's mesh. T is one element of width W (a vertex, or a triangle's 3 corners).
template <class T, int W>
struct GatherTile {
    const StreamBlock* blocks;
    uint32_t count;
    bool vertices;                  // the vertex column, else the triangle one
    const uint64_t* staged_offset;  // exclusive scan of the staged lengths
    uint64_t staged_total;
    const T* source;                // mesh after mesh, W per element
    const uint64_t* mesh_first;     // per mesh, in elements
    const ObjectInfo* objects;
    T* staging;

    void operator()(uint64_t tile) const {
        const uint64_t begin = tile * kHostRunTile;
        const uint64_t end = begin + kHostRunTile < staged_total ? begin + kHostRunTile : staged_total;
        forEachRun(staged_offset, count, staged_total, begin, end, [&](uint32_t j, uint64_t first, uint64_t length) {
            const StreamBlock& b = blocks[j];
            const uint64_t kept = vertices ? b.vertex_kept : b.triangle_kept;
            const uint64_t from = mesh_first[objects[b.object].mesh] + kept + first;
            const T* src = source + W * from;
            T* dst = staging + W * (staged_offset[j] + first);
            for (uint64_t i = 0; i < W * length; ++i) dst[i] = src[i];
        });
    }
};

struct StagedLength {
    bool vertices;
    uint64_t operator()(const StreamBlock& b) const { return vertices ? b.vertex_staged : b.triangle_staged; }
};

// Host-side bookkeeping: at least n elements, growing by half again.
template <class T>
void reserve(std::vector<T>& v, uint64_t n) {
    if (n > v.size()) v.resize(n + n / 2);
}

// Stages one column (the vertex or the triangle parts); returns the element count.
template <class T, int W>
uint64_t collect(const StreamBlock* blocks, uint32_t count, bool vertices, const T* source, const uint64_t* mesh_first,
                 const ObjectInfo* objects, PinnedArray<T>& staging, StagingBuffers& bookkeeping) {
    if (count == 0) return 0;
    reserve(bookkeeping.offsets, count);
    uint64_t* offsets = bookkeeping.offsets.data();
    const auto lengths = thrust::make_transform_iterator(blocks, StagedLength{vertices});
    thrust::exclusive_scan(kHostSide, lengths, lengths + count, offsets, uint64_t(0));
    const uint64_t total = offsets[count - 1] + lengths[count - 1];
    if (total == 0) return 0;

    staging.growTo(W * total);
    const uint64_t tiles = (total + kHostRunTile - 1) / kHostRunTile;
    thrust::for_each_n(kHostSide, thrust::counting_iterator<uint64_t>(0), tiles,
                       GatherTile<T, W>{blocks, count, vertices, offsets, total, source, mesh_first, objects,
                                        staging.data()});
    return total;
}

// What block j of `current` needs beyond what `previous` held.
struct ChangeOf {
    HostLayout previous, current;
    StreamBlock operator()(uint32_t j) const {
        const KeptPrefix v = keptPrefix(vertexBlocks(previous), vertexBlocks(current), j);
        const KeptPrefix t = keptPrefix(triangleBlocks(previous), triangleBlocks(current), j);
        return {current.vertex_offset[j],           current.triangle_offset[j], current.objects[j], v.length,
                current.vertex_count[j] - v.length, t.length,                   current.triangle_count[j] - t.length,
                0};
    }
};

}  // namespace

StreamCounts streamBlocks(const StreamBlock* blocks, uint32_t count, const HostGeometry& host,
                          StagingBuffers& staging) {
    StreamCounts counts;
    counts.vertices = collect<glm::vec3, 1>(blocks, count, true, host.positions, host.vertex_first, host.objects,
                                            staging.vertices, staging);
    counts.triangles = collect<uint32_t, 3>(blocks, count, false, host.triangles, host.triangle_first, host.objects,
                                            staging.triangles, staging);
    staging.vertex_count = counts.vertices;
    staging.triangle_count = counts.triangles;
    // The transfer: what was gathered, and nothing else, crosses the bus.
    staging.device_vertices.growTo(counts.vertices);
    staging.device_triangles.growTo(3 * counts.triangles);
    copyToDevice(staging.device_vertices.ptr(), staging.vertices.data(), counts.vertices);
    copyToDevice(staging.device_triangles.ptr(), staging.triangles.data(), 3 * counts.triangles);
    return counts;
}

std::vector<StreamBlock> streamList(const HostLayout& previous, const HostLayout& current) {
    // Blocks are matched across frames by binary search on the ids.
    if (!thrust::is_sorted(kHostSide, current.objects, current.objects + current.count,
                           thrust::less_equal<uint32_t>()))
        throw std::invalid_argument("streamList: the current layout's object ids are not strictly ascending");
    std::vector<StreamBlock> list(current.count);
    thrust::transform(kHostSide, thrust::counting_iterator<uint32_t>(0),
                      thrust::counting_iterator<uint32_t>(current.count), list.data(), ChangeOf{previous, current});
    return list;
}

StreamCounts streamCollect(const HostLayout& previous, const HostLayout& current, const HostGeometry& host,
                           StagingBuffers& staging) {
    const std::vector<StreamBlock> list = streamList(previous, current);
    return streamBlocks(list.data(), uint32_t(list.size()), host, staging);
}

}  // namespace occ::k
