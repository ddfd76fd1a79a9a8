// SPDX-License-Identifier: MIT
#pragma once

// For kernel sources only: running functors over the elements of blocks on the device.
#include "block_runs.h"
#include "device_access.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/transform.h>

namespace occ::k {

// Calls f(tile) for every tile of kRunTile elements of [0, total) (nothing when total is 0).
template <class F>
void forEachTile(uint64_t total, const F& f) {
    if (total == 0) return;
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint64_t>(0), (total + kRunTile - 1) / kRunTile, f);
}

// The elements of `count` blocks, block j having size(j) of them (a functor that runs on the
// device): the sizes go to `lengths` and their exclusive scan to `offsets` (scratch, grown as
// needed), then make(offsets, total) gives the functor forEachTile runs over them. Returns the
// total.
template <class Size, class MakeTile>
uint64_t forEachBlockTile(uint32_t count, const Size& size, DeviceArray<uint32_t>& lengths,
                          DeviceArray<uint64_t>& offsets, const MakeTile& make) {
    if (count == 0) return 0;
    lengths.growTo(count);
    offsets.growTo(count);
    const thrust::counting_iterator<uint32_t> first(0);
    thrust::transform(onDevice(), first, first + count, raw(lengths.ptr()), size);
    const uint64_t total = exclusiveScan(lengths.ptr(), count, offsets.ptr());
    forEachTile(total, make(static_cast<const uint64_t*>(raw(offsets.ptr())), total));
    return total;
}

}  // namespace occ::k
