// SPDX-License-Identifier: MIT
#include "scan.h"

#include "block_runs.h"
#include "device_access.h"
#include "for_each_index.h"
#include "device_policy.h"

#include <thrust/copy.h>
#include <thrust/execution_policy.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/scan.h>
#include <thrust/set_operations.h>

namespace occ::k {

namespace {

struct Equals {
    uint8_t value;
    OCC_HD bool operator()(uint8_t x) const { return x == value; }
};

}  // namespace

uint64_t exclusiveScan(DevicePtr<const uint32_t> in, uint32_t count, DevicePtr<uint64_t> out) {
    if (count == 0) return 0;
    const auto wide = thrust::make_transform_iterator(raw(in), Widen());
    thrust::exclusive_scan(onDevice(), wide, wide + count, raw(out), uint64_t(0));
    // The total is the last offset plus the last count: 12 bytes back to the host.
    return readBack(DevicePtr<const uint64_t>(out + (count - 1))) + readBack(in + (count - 1));
}

uint32_t compactIndices(DevicePtr<const uint8_t> flags, uint32_t count, uint8_t value, DevicePtr<uint32_t> out) {
    if (count == 0) return 0;
    const thrust::counting_iterator<uint32_t> first(0);
    uint32_t* const end = withPolicy(
        count, [&](auto policy) { return thrust::copy_if(policy, first, first + count, raw(flags), raw(out), Equals{value}); });
    countReadback(sizeof(uint32_t));  // copy_if's count
    return uint32_t(end - raw(out));
}

uint32_t compactSelected(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> flags, uint32_t count, uint8_t value,
                         DevicePtr<uint32_t> out) {
    if (count == 0) return 0;
    uint32_t* const end = withPolicy(count, [&](auto policy) {
        return thrust::copy_if(policy, raw(ids), raw(ids) + count, raw(flags), raw(out), Equals{value});
    });
    countReadback(sizeof(uint32_t));
    return uint32_t(end - raw(out));
}

uint32_t unionAscending(DevicePtr<const uint32_t> a, uint32_t a_count, DevicePtr<const uint32_t> b, uint32_t b_count,
                        DevicePtr<uint32_t> out) {
    uint32_t* const end = withPolicy(uint64_t(a_count) + b_count, [&](auto policy) {
        return thrust::set_union(policy, raw(a), raw(a) + a_count, raw(b), raw(b) + b_count, raw(out));
    });
    countReadback(sizeof(uint32_t));
    return uint32_t(end - raw(out));
}

}  // namespace occ::k
