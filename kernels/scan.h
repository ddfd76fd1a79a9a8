// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "host_device.h"

namespace occ::k {

// Exclusive prefix sums, the avn / atn arrays of Peng & Cao 2012: out[i] = in[0] + ... + in[i-1],
// out[0] = 0. Returns the total in[0] + ... + in[count-1]. out has count entries and must not
// overlap in. count may be 0 (nothing is written, returns 0). Sums are 64-bit, so no total of
// 32-bit counts overflows.
uint64_t exclusiveScan(DevicePtr<const uint32_t> in, uint32_t count, DevicePtr<uint64_t> out);

// Stream compaction. compactIndices: out gets every i < count with flags[i] == value,
// ascending. compactSelected: out gets ids[j] for every j < count with flags[j] == value, in
// order. out has room for count entries and must not overlap the inputs. Both return how many
// they wrote (a 4-byte readback).
uint32_t compactIndices(DevicePtr<const uint8_t> flags, uint32_t count, uint8_t value, DevicePtr<uint32_t> out);
uint32_t compactSelected(DevicePtr<const uint32_t> ids, DevicePtr<const uint8_t> flags, uint32_t count, uint8_t value,
                         DevicePtr<uint32_t> out);

// The union of two strictly ascending id lists a[0, a_count) and b[0, b_count), ascending and
// each id once, into out (room for a_count + b_count, overlapping neither). Returns its length
// (a 4-byte readback). Linear: a merge, not a sort.
uint32_t unionAscending(DevicePtr<const uint32_t> a, uint32_t a_count, DevicePtr<const uint32_t> b, uint32_t b_count,
                        DevicePtr<uint32_t> out);

// Where every resident object's block of one frame sits in the active arrays, as the host keeps
// it (the device gets only the blocks that changed). All pointers are host memory with `count`
// entries (none read when count is 0, so HostLayout{} is the empty layout: "nothing resident",
// the previous layout of the first frame).
//   objects          object ids, strictly ascending (streaming matches frames by binary search)
//   vertex_count     vc_i, the vertices the block holds; 0 = none (the entry is then ignored)
//   triangle_count   tc_i = map_i[vc_i]; 0 when vc_i is 0
//   vertex_offset    where the block's vertices start (blocks may have gaps between them)
//   triangle_offset  where its triangles start, in triangles (3 indices each)
// vertex_total and triangle_total are the sums of the counts.
struct HostLayout {
    const uint32_t* objects = nullptr;
    const uint32_t* vertex_count = nullptr;
    const uint32_t* triangle_count = nullptr;
    const uint64_t* vertex_offset = nullptr;
    const uint64_t* triangle_offset = nullptr;
    uint32_t count = 0;
    uint64_t vertex_total = 0;
    uint64_t triangle_total = 0;
};

}  // namespace occ::k
