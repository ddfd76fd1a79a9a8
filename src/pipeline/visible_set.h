// SPDX-License-Identifier: MIT
#pragma once

#include <cstdint>
#include <utility>
#include <vector>

namespace occ {

struct VisibleSetDelta;  // net/messages.h

// The one visible-set type: what a frame's culling chose, what the pipeline's history keeps,
// what the deltas between ranks change and what a display draws (net/messages.h makes and
// applies the deltas; the hash and apply live in net/messages.cpp). A visible set V_i: item ids with their LOD vertex counts, sorted by id, ids unique.
class VisibleSet {
public:
    using Entry = std::pair<uint32_t, uint32_t>;  // (object id, LOD vertex count)

    VisibleSet() = default;
    // Throws std::invalid_argument unless entries are sorted by id with no id twice.
    explicit VisibleSet(std::vector<Entry> entries);

    const std::vector<Entry>& entries() const { return entries_; }
    size_t size() const { return entries_.size(); }
    bool empty() const { return entries_.empty(); }
    bool operator==(const VisibleSet&) const = default;

    // XXH3-64 (seed 0) of the entries as consecutive little-endian (u32 id, u32 count) pairs;
    // the empty set hashes the empty input. Same value on every rank for the same set.
    uint64_t hash() const;

    // V_i = (V_{i-1} - removed) ∪ added with the changed counts, or V_i = added when
    // delta.full. Checks that each list is ascending without duplicates, that removed and
    // changed ids are in the set (changed ones not removed), added ids are not (unless full),
    // and that the result hashes to delta.hash. On any failure throws RankError(sender,
    // "delta of frame F: ...") and leaves the set unchanged. Linear in size() + the delta.
    void apply(const VisibleSetDelta& delta, int sender);

private:
    std::vector<Entry> entries_;
};

}  // namespace occ
