// SPDX-License-Identifier: MIT
#include "pipeline/block_allocator.h"

#include <iterator>
#include <stdexcept>

namespace occ {

void RangeAllocator::reset(uint64_t capacity) {
    free_.clear();
    if (capacity > 0) free_[0] = capacity;
    capacity_ = capacity;
    used_ = 0;
}

uint64_t RangeAllocator::allocate(uint64_t n) {
    if (n == 0) throw std::invalid_argument("RangeAllocator::allocate: 0 elements");
    for (auto it = free_.begin(); it != free_.end(); ++it) {
        if (it->second < n) continue;
        const uint64_t offset = it->first, rest = it->second - n;
        free_.erase(it);
        if (rest > 0) free_[offset + n] = rest;
        used_ += n;
        return offset;
    }
    return kNone;
}

void RangeAllocator::release(uint64_t offset, uint64_t n) {
    if (n == 0) return;
    if (offset + n > capacity_ || n > used_) throw std::invalid_argument("RangeAllocator::release: not allocated");
    auto next = free_.lower_bound(offset);
    if (next != free_.end() && next->first < offset + n)
        throw std::invalid_argument("RangeAllocator::release: range overlaps a free one");
    uint64_t first = offset, length = n;
    if (next != free_.begin()) {
        const auto before = std::prev(next);
        if (before->first + before->second > offset)
            throw std::invalid_argument("RangeAllocator::release: range overlaps a free one");
        if (before->first + before->second == offset) {
            first = before->first;
            length += before->second;
            free_.erase(before);
        }
    }
    if (next != free_.end() && next->first == offset + n) {
        length += next->second;
        free_.erase(next);
    }
    free_[first] = length;
    used_ -= n;
}

uint64_t RangeAllocator::extent() const {
    if (used_ == 0) return 0;
    if (free_.empty()) return capacity_;
    const auto last = std::prev(free_.end());
    return last->first + last->second == capacity_ ? last->first : capacity_;
}

}  // namespace occ
