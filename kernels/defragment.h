// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "scan.h"
#include "stream_collect.h"

// Streaming with frame-to-frame coherence (SC, Algorithm 3 of Peng & Cao 2012), part 2 of 2:
// the new active arrays from the old ones plus the staging buffer. The per-frame sequence and
// which buffers live across frames are in stream_collect.h.

namespace occ::k {

// One active array, double-buffered: buffers[current] holds `count` elements (times 3 uint32
// for triangles) of the layout defragment last built; the other buffer is its workspace.
// Read it through data(); only defragment and streamObjectByObject change it. A buffer's size()
// is its capacity: they grow by half again when short and never shrink.
// The two buffers live in device memory of their own, or in a display's GL buffers
// (ProvidedBuffer::lendFrom), which OpenGL then draws from.
template <class T>
struct ActiveBuffer {
    ProvidedBuffer<T> buffers[2];
    uint32_t current = 0;
    uint64_t count = 0;

    DevicePtr<const T> data() const { return buffers[current].ptr(); }
};

// Peng & Cao's active vertex array (glm::vec3, object space, each drawn object's first vc
// vertices at its vertex offset) and active triangle array (3 uint32 corners per triangle in the
// object's own numbering, before reformation: its first tc triangles at its triangle offset).
// Owned by the caller and kept from frame to frame: the first frame starts from a default one.
struct ActiveArrays {
    ActiveBuffer<glm::vec3> vertices;
    ActiveBuffer<uint32_t> triangles;
    DeviceArray<uint32_t> lengths;  // per-block bookkeeping of defragment; no meaning outside it
    DeviceArray<uint64_t> offsets;
};

// What one defragment wrote, per array. Elements are vertices or triangles.
struct DefragmentCounts {
    uint64_t vertices_copied = 0;   // from staging: the streamed parts
    uint64_t triangles_copied = 0;
    uint64_t vertices_moved = 0;    // kept prefixes written to the new layout's place
    uint64_t triangles_moved = 0;
    uint64_t vertices_bounced = 0;  // moved elements that went through the workspace first
    uint64_t triangles_bounced = 0;
};

// Turns `active` from holding `previous` into holding `current`, block by block: the prefix both
// frames share stays or moves, the rest comes from `staging`, which must be what
// streamCollect(previous, current, ...) left there. Per array it takes the cheaper of
//   - in place (the extension of Algorithm 3): blocks whose offset did not change are not
//     touched beyond appending their streamed part; blocks that move are first copied to the
//     workspace, then to their new place (2 writes per moved element), because a block's new
//     place may overlap another's old one;
//   - double buffering (Peng & Cao): every block is written into the other buffer, which then
//     becomes current (1 write per kept element);
// in place whenever 2 x moved <= kept and the current buffer is large enough, so a frame whose
// drawn set and LODs did not change writes nothing at all.
// previous must be the layout `active` holds (or ActiveLayout{}: nothing is kept, the SNC
// baseline). Throws std::invalid_argument, leaving `active` as it was, if its totals differ from
// what `active` holds, if current's ids are not strictly ascending, or if staging's counts are
// not what the two layouts need. Layouts are read only and may share arrays.
DefragmentCounts defragment(const ActiveLayout& previous, const ActiveLayout& current, const StagingBuffers& staging,
                            ActiveArrays& active);

// The NS baseline of Peng & Cao's Table 1, no streaming batch: every drawn block of `current` is
// copied whole from `host` straight into `active`, one bus copy per object and array (2 x drawn
// objects copies), with no staging and no reuse of the previous frame. `current` is the host's
// copy of the layout. Leaves `active` holding `current`, so it may be mixed with defragment from
// frame to frame. Returns the counts copied.
StreamCounts streamObjectByObject(const HostLayout& current, const HostGeometry& host, ActiveArrays& active);

}  // namespace occ::k
