// SPDX-License-Identifier: MIT
#include "lod_hysteresis.h"

#include "block_runs.h"
#include "device_access.h"
#include "device_policy.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/find.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/reduce.h>
#include <thrust/scan.h>
#include <thrust/sort.h>

namespace occ::k {

namespace {

// Keeps last frame's count where Eq. 1's is within the hysteresis of it; notes the raises.
struct KeepSimilar {
    const uint32_t* ids;
    const LodEntry* previous;
    uint32_t previous_count;
    double hysteresis;
    uint32_t* vertex_count;
    uint64_t* raised;  // per j: (extra << 32 | j), 0 when not raised

    OCC_HD void operator()(uint32_t j) const {
        raised[j] = 0;
        const uint32_t v = vertex_count[j];
        if (v == 0) return;
        uint32_t lo = 0, hi = previous_count;  // first previous entry with object >= ids[j]
        while (lo < hi) {
            const uint32_t mid = lo + (hi - lo) / 2;
            if (previous[mid].object < ids[j])
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo == previous_count || previous[lo].object != ids[j]) return;
        const uint32_t p = previous[lo].vertices;
        const double difference = double(v) > double(p) ? double(v) - double(p) : double(p) - double(v);
        if (p == 0 || p == v || !(difference <= hysteresis * double(p))) return;
        vertex_count[j] = p;
        if (p > v) raised[j] = (uint64_t(p - v) << 32) | j;
    }
};

struct IsRaised {
    OCC_HD bool operator()(uint64_t key) const { return key != 0; }
};

struct Extra {
    OCC_HD uint64_t operator()(uint64_t key) const { return key >> 32; }
};

// The first running sum that brings the total within the limit.
struct Fits {
    uint64_t total, limit_floor;  // total - sum <= limit  <=>  sum >= total - floor(limit)
    OCC_HD bool operator()(uint64_t sum) const { return sum >= total - limit_floor; }
};

struct GiveBack {
    const uint64_t* raised;
    const uint32_t* eq1;
    uint32_t* vertex_count;
    OCC_HD void operator()(uint32_t i) const {
        const uint32_t j = uint32_t(raised[i]);
        vertex_count[j] = eq1[j];
    }
};

struct Retriangulate {
    const uint32_t* ids;
    const uint32_t* eq1;
    const uint32_t* vertex_count;
    const ObjectInfo* objects;
    const uint64_t* map_first;
    const uint32_t* maps;
    uint32_t* triangle_count;
    OCC_HD void operator()(uint32_t j) const {
        if (vertex_count[j] == eq1[j]) return;
        triangle_count[j] = maps[map_first[objects[ids[j]].mesh] + vertex_count[j]];
    }
};

}  // namespace

void keepSimilarLods(DevicePtr<const uint32_t> ids, uint32_t count, DevicePtr<const LodEntry> previous,
                     uint32_t previous_count, float hysteresis, double budget, DevicePtr<const ObjectInfo> objects,
                     DevicePtr<const uint64_t> map_first, DevicePtr<const uint32_t> maps,
                     DevicePtr<uint32_t> vertex_count, DevicePtr<uint32_t> triangle_count,
                     LodHysteresisScratch& scratch) {
    if (count == 0) return;
    scratch.eq1.growTo(count);
    scratch.raised.growTo(count);
    scratch.sums.growTo(count);
    uint32_t* const vc = raw(vertex_count);
    uint32_t* const eq1 = raw(scratch.eq1.ptr());
    uint64_t* const raised = raw(scratch.raised.ptr());
    uint64_t* const sums = raw(scratch.sums.ptr());
    copyOnDevice(scratch.eq1.ptr(), DevicePtr<const uint32_t>(vertex_count), count);
    const auto wide_eq1 = thrust::make_transform_iterator(eq1, Widen());
    const uint64_t chosen = thrust::reduce(onDevice(), wide_eq1, wide_eq1 + count, uint64_t(0));
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), count,
                       KeepSimilar{raw(ids), raw(previous), previous_count, double(hysteresis), vc, raised});
    const auto wide_vc = thrust::make_transform_iterator(vc, Widen());
    const uint64_t total = thrust::reduce(onDevice(), wide_vc, wide_vc + count, uint64_t(0));
    countReadback(2 * sizeof(uint64_t));
    // Sums of integer counts are exact in 64 bits; the limit is compared as the host would.
    const double limit = budget > double(chosen) ? budget : double(chosen);
    if (double(total) > limit) {
        uint64_t* const end = thrust::copy_if(onDevice(), raised, raised + count, sums, IsRaised{});
        const uint32_t n = uint32_t(end - sums);
        thrust::copy(onDevice(), sums, sums + n, raised);
        thrust::sort(onDevice(), raised, raised + n, thrust::greater<uint64_t>());
        const auto extras = thrust::make_transform_iterator(raised, Extra());
        thrust::inclusive_scan(onDevice(), extras, extras + n, sums);
        // Give back raises, largest first, while the total is above the limit: the m-th sum is
        // the first with total - sum <= limit (limit >= chosen >= 0, so floor(limit) fits).
        const uint64_t limit_floor = uint64_t(limit);
        const uint64_t* const first = thrust::find_if(onDevice(), sums, sums + n, Fits{total, limit_floor});
        countReadback(2 * sizeof(uint32_t));  // copy_if's and find_if's positions
        const uint32_t m = first == sums + n ? n : uint32_t(first - sums) + 1;
        thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), m, GiveBack{raised, eq1, vc});
    }
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), count,
                       Retriangulate{raw(ids), eq1, vc, raw(objects), raw(map_first), raw(maps),
                                     raw(triangle_count)});
}

}  // namespace occ::k
