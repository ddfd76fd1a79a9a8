// SPDX-License-Identifier: MIT
#include "pipeline/block_allocator.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

namespace occ {
namespace {

constexpr uint64_t kNone = RangeAllocator::kNone;

RangeAllocator withCapacity(uint64_t capacity) {
    RangeAllocator a;
    a.reset(capacity);
    return a;
}

TEST(RangeAllocator, AllocatesBackToBackFromTheStart) {
    RangeAllocator a = withCapacity(100);
    EXPECT_EQ(a.capacity(), 100u);
    EXPECT_EQ(a.used(), 0u);
    EXPECT_EQ(a.extent(), 0u);
    EXPECT_EQ(a.allocate(10), 0u);
    EXPECT_EQ(a.allocate(20), 10u);
    EXPECT_EQ(a.allocate(5), 30u);
    EXPECT_EQ(a.used(), 35u);
    EXPECT_EQ(a.extent(), 35u);
}

TEST(RangeAllocator, FirstFitTakesTheLowestRangeThatIsLargeEnough) {
    RangeAllocator a = withCapacity(100);
    a.allocate(10);  // [0, 10)
    a.allocate(20);  // [10, 30)
    a.allocate(5);   // [30, 35)
    a.allocate(10);  // [35, 45)
    a.release(0, 10);
    a.release(30, 5);
    // Free: [0, 10), [30, 35), [45, 100).
    EXPECT_EQ(a.allocate(8), 0u);    // the lowest that fits, not the best fit [30, 35)
    EXPECT_EQ(a.allocate(5), 30u);   // [8, 10) is too small
    EXPECT_EQ(a.allocate(2), 8u);    // the rest of the first hole
    EXPECT_EQ(a.allocate(40), 45u);  // only the tail is large enough
    EXPECT_EQ(a.used(), 10u + 20 + 5 + 10 + 40);
}

TEST(RangeAllocator, ReleasedNeighboursCoalesce) {
    RangeAllocator a = withCapacity(60);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(a.allocate(10), uint64_t(10 * i));
    EXPECT_EQ(a.allocate(1), kNone);
    // Release 1 and 3, then 2 between them: one free range [10, 40).
    a.release(10, 10);
    a.release(30, 10);
    EXPECT_EQ(a.allocate(11), kNone) << "no single hole of 11 yet";
    a.release(20, 10);
    EXPECT_EQ(a.allocate(30), 10u);
    EXPECT_EQ(a.allocate(1), kNone);
    // Now [0, 10) [10, 40) [40, 50) [50, 60). Merging with the free range before only:
    a.release(0, 10);
    a.release(10, 30);
    EXPECT_EQ(a.allocate(40), 0u);
    // Then with the free range after only:
    a.release(50, 10);
    a.release(40, 10);
    EXPECT_EQ(a.allocate(20), 40u);
    EXPECT_EQ(a.allocate(1), kNone);
    EXPECT_EQ(a.used(), 60u);
}

TEST(RangeAllocator, ReturnsNoneWhenNoFreeRangeIsLargeEnough) {
    RangeAllocator a = withCapacity(10);
    EXPECT_EQ(a.allocate(11), kNone);
    EXPECT_EQ(a.used(), 0u) << "a failed allocation takes nothing";
    EXPECT_EQ(a.allocate(10), 0u);
    EXPECT_EQ(a.allocate(1), kNone);
    RangeAllocator empty = withCapacity(0);
    EXPECT_EQ(empty.allocate(1), kNone);
    EXPECT_EQ(empty.extent(), 0u);
    // Enough free in total, but split.
    RangeAllocator split = withCapacity(30);
    split.allocate(10), split.allocate(10), split.allocate(10);
    split.release(0, 10), split.release(20, 10);
    EXPECT_EQ(split.allocate(15), kNone);
    EXPECT_EQ(split.allocate(10), 0u);
}

TEST(RangeAllocator, ZeroElementsAreRejectedOrIgnored) {
    RangeAllocator a = withCapacity(10);
    EXPECT_THROW(a.allocate(0), std::invalid_argument);
    a.release(3, 0);  // nothing
    EXPECT_EQ(a.used(), 0u);
    EXPECT_EQ(a.allocate(10), 0u);
}

TEST(RangeAllocator, ReleasingWhatIsNotAllocatedThrowsAndChangesNothing) {
    RangeAllocator a = withCapacity(100);
    EXPECT_THROW(a.release(0, 10), std::invalid_argument) << "nothing is allocated";
    a.allocate(10);  // [0, 10)
    a.allocate(10);  // [10, 20)
    a.allocate(10);  // [20, 30)
    EXPECT_THROW(a.release(50, 10), std::invalid_argument) << "in the free tail";
    EXPECT_THROW(a.release(25, 10), std::invalid_argument) << "straddles into the free tail";
    EXPECT_THROW(a.release(95, 10), std::invalid_argument) << "past the capacity";
    a.release(10, 10);
    EXPECT_THROW(a.release(10, 10), std::invalid_argument) << "released twice";
    EXPECT_THROW(a.release(5, 10), std::invalid_argument) << "overlaps the free hole from below";
    EXPECT_THROW(a.release(15, 10), std::invalid_argument) << "overlaps the free hole from above";
    EXPECT_THROW(a.release(12, 3), std::invalid_argument) << "inside the free hole";
    EXPECT_THROW(a.release(0, 30), std::invalid_argument) << "covers the free hole";
    // Nothing changed: [0, 10) and [20, 30) allocated, [10, 20) and [30, 100) free.
    EXPECT_EQ(a.used(), 20u);
    EXPECT_EQ(a.extent(), 30u);
    EXPECT_EQ(a.allocate(10), 10u);
    EXPECT_EQ(a.allocate(70), 30u);
    EXPECT_EQ(a.allocate(1), kNone);
}

TEST(RangeAllocator, ExtentFollowsTheLastAllocatedElement) {
    RangeAllocator a = withCapacity(100);
    a.allocate(10);  // [0, 10)
    a.allocate(20);  // [10, 30)
    a.allocate(5);   // [30, 35)
    a.release(10, 20);
    EXPECT_EQ(a.extent(), 35u) << "a hole in the middle does not shorten it";
    a.release(30, 5);
    EXPECT_EQ(a.extent(), 10u) << "the hole and the tail merge";
    a.release(0, 10);
    EXPECT_EQ(a.extent(), 0u);
    EXPECT_EQ(a.used(), 0u);
    // Full to the end, then the last range released.
    RangeAllocator full = withCapacity(20);
    full.allocate(15), full.allocate(5);
    EXPECT_EQ(full.extent(), 20u);
    full.release(0, 15);
    EXPECT_EQ(full.extent(), 20u);
    full.release(15, 5);
    EXPECT_EQ(full.extent(), 0u);
}

TEST(RangeAllocator, ResetFreesEverything) {
    RangeAllocator a = withCapacity(10);
    a.allocate(4), a.allocate(6);
    a.reset(50);
    EXPECT_EQ(a.capacity(), 50u);
    EXPECT_EQ(a.used(), 0u);
    EXPECT_EQ(a.extent(), 0u);
    EXPECT_EQ(a.allocate(50), 0u);
}

TEST(RangeAllocator, MatchesABitmapModelOnRandomOperations) {
    std::mt19937 rng(17);
    for (int round = 0; round < 20; ++round) {
        SCOPED_TRACE(testing::Message() << "round " << round);
        const uint64_t capacity = std::uniform_int_distribution<uint64_t>(1, 600)(rng);
        RangeAllocator a = withCapacity(capacity);
        std::vector<bool> taken(capacity, false);
        std::vector<std::pair<uint64_t, uint64_t>> live;  // what allocate returned, not released
        const auto modelFirstFit = [&](uint64_t n) {
            uint64_t run = 0;
            for (uint64_t i = 0; i < capacity; ++i) {
                run = taken[i] ? 0 : run + 1;
                if (run == n) return i + 1 - n;
            }
            return kNone;
        };
        for (int op = 0; op < 2000; ++op) {
            const int what = std::uniform_int_distribution<int>(0, 9)(rng);
            if (what < 5 || live.empty()) {
                const uint64_t n = std::uniform_int_distribution<uint64_t>(1, std::max<uint64_t>(1, capacity / 8))(rng);
                const uint64_t expected = modelFirstFit(n);
                ASSERT_EQ(a.allocate(n), expected) << "op " << op << ": allocate " << n;
                if (expected != kNone) {
                    for (uint64_t i = expected; i < expected + n; ++i) taken[i] = true;
                    live.emplace_back(expected, n);
                }
            } else if (what < 9) {
                const size_t k = std::uniform_int_distribution<size_t>(0, live.size() - 1)(rng);
                const auto [offset, n] = live[k];
                a.release(offset, n);
                for (uint64_t i = offset; i < offset + n; ++i) taken[i] = false;
                live[k] = live.back();
                live.pop_back();
            } else {
                // A range with at least one free element: the release must throw.
                const uint64_t offset = std::uniform_int_distribution<uint64_t>(0, capacity - 1)(rng);
                const uint64_t n = std::uniform_int_distribution<uint64_t>(1, capacity - offset)(rng);
                bool any_free = false;
                for (uint64_t i = offset; i < offset + n; ++i) any_free = any_free || !taken[i];
                if (any_free) {
                    EXPECT_THROW(a.release(offset, n), std::invalid_argument) << "op " << op;
                }
            }
            uint64_t used = 0, extent = 0;
            for (uint64_t i = 0; i < capacity; ++i)
                if (taken[i]) ++used, extent = i + 1;
            ASSERT_EQ(a.used(), used) << "op " << op;
            ASSERT_EQ(a.extent(), extent) << "op " << op;
        }
    }
}

}  // namespace
}  // namespace occ
