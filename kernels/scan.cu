// SPDX-License-Identifier: MIT
#include "scan.h"

#include <thrust/execution_policy.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/scan.h>

namespace occ::k {

namespace {

// Widening before the scan makes Thrust accumulate in 64 bits: it sums in the input's value type.
struct Widen {
    OCC_HD uint64_t operator()(uint32_t x) const { return x; }
};

}  // namespace

uint64_t exclusiveScan(const uint32_t* in, uint32_t count, uint64_t* out) {
    if (count == 0) return 0;
    const auto wide = thrust::make_transform_iterator(in, Widen());
    thrust::exclusive_scan(thrust::device, wide, wide + count, out, uint64_t(0));
    // Thrust's device algorithms return after the device has finished, so kernel memory is
    // readable here on either back end.
    return out[count - 1] + in[count - 1];
}

}  // namespace occ::k
