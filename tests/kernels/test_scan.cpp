// SPDX-License-Identifier: MIT
#include "kernel_memory.h"
#include "scan.h"

#include <gtest/gtest.h>

#include <random>
#include <utility>
#include <vector>

using namespace occ::k;

namespace {

std::pair<std::vector<uint64_t>, uint64_t> scan(const std::vector<uint32_t>& in) {
    KernelArray<uint32_t> in_k(in.size());
    KernelArray<uint64_t> out(in.size());
    std::copy(in.begin(), in.end(), in_k.begin());
    const uint64_t total = exclusiveScan(in_k.data(), uint32_t(in.size()), out.data());
    return {std::vector<uint64_t>(out.begin(), out.end()), total};
}

// The runs forEachRun reports, as (segment, first, length).
std::vector<std::vector<uint64_t>> runs(const std::vector<uint64_t>& offsets, uint64_t total, uint64_t begin,
                                        uint64_t end) {
    std::vector<std::vector<uint64_t>> r;
    forEachRun(offsets.data(), uint32_t(offsets.size()), total, begin, end,
               [&](uint32_t s, uint64_t first, uint64_t length) { r.push_back({s, first, length}); });
    return r;
}

}  // namespace

TEST(Scan, SmallInputGivesTheSumsBeforeEachElement) {
    const auto [out, total] = scan({3, 0, 4, 1});
    EXPECT_EQ(out, (std::vector<uint64_t>{0, 3, 3, 7}));
    EXPECT_EQ(total, 8u);
}

TEST(Scan, OneElement) {
    const auto [out, total] = scan({5});
    EXPECT_EQ(out, (std::vector<uint64_t>{0}));
    EXPECT_EQ(total, 5u);
}

TEST(Scan, EmptyInputWritesNothingAndSumsToZero) {
    EXPECT_EQ(exclusiveScan(nullptr, 0, nullptr), 0u);
}

TEST(Scan, SumsPast32BitsDoNotWrap) {
    const auto [out, total] = scan({0xFFFFFFFFu, 0xFFFFFFFFu, 2});
    EXPECT_EQ(out[2], 2 * uint64_t(0xFFFFFFFFu));
    EXPECT_EQ(total, 2 * uint64_t(0xFFFFFFFFu) + 2);
}

TEST(Scan, LargeRandomInputMatchesASerialScan) {
    std::mt19937 rng(3);
    std::vector<uint32_t> in(3'000'017);
    for (uint32_t& x : in) x = rng() % 100'000;
    const auto [out, total] = scan(in);
    uint64_t sum = 0;
    for (size_t i = 0; i < in.size(); ++i) {
        ASSERT_EQ(out[i], sum) << i;
        sum += in[i];
    }
    EXPECT_EQ(total, sum);
}

TEST(Scan, ForEachRunSplitsARangeAtSegmentBoundariesAndSkipsEmptySegments) {
    // Segment sizes 2, 0, 3, 0, 0, 4: offsets 0 2 2 5 5 5, total 9.
    const std::vector<uint64_t> offsets{0, 2, 2, 5, 5, 5};
    using R = std::vector<std::vector<uint64_t>>;
    EXPECT_EQ(runs(offsets, 9, 0, 9), (R{{0, 0, 2}, {2, 0, 3}, {5, 0, 4}}));
    EXPECT_EQ(runs(offsets, 9, 1, 6), (R{{0, 1, 1}, {2, 0, 3}, {5, 0, 1}}));
    EXPECT_EQ(runs(offsets, 9, 2, 3), (R{{2, 0, 1}}));
    EXPECT_EQ(runs(offsets, 9, 8, 9), (R{{5, 3, 1}}));
}

TEST(Scan, ForEachRunSkipsLeadingEmptySegments) {
    const std::vector<uint64_t> offsets{0, 0, 0, 1};
    using R = std::vector<std::vector<uint64_t>>;
    EXPECT_EQ(runs(offsets, 3, 0, 3), (R{{2, 0, 1}, {3, 0, 2}}));
}

TEST(Scan, KeptPrefixIsTheSharedPartOfTheSameObjectsBlocks) {
    const uint32_t prev_ids[] = {2, 5, 9}, prev_size[] = {4, 6, 1};
    const uint64_t prev_offset[] = {0, 4, 10};
    const uint32_t cur_ids[] = {1, 5, 9}, cur_size[] = {3, 8, 0};
    const uint64_t cur_offset[] = {0, 3, 11};
    const BlockColumn previous{prev_ids, prev_size, prev_offset, 3, 11};
    const BlockColumn current{cur_ids, cur_size, cur_offset, 3, 11};
    EXPECT_EQ(keptPrefix(previous, current, 0).length, 0u);  // object 1 is new
    EXPECT_EQ(keptPrefix(previous, current, 1).length, 6u);  // object 5 grew from 6 to 8
    EXPECT_EQ(keptPrefix(previous, current, 1).previous_offset, 4u);
    EXPECT_EQ(keptPrefix(previous, current, 2).length, 0u);  // object 9 is no longer drawn
    const BlockColumn nothing{nullptr, nullptr, nullptr, 0, 0};
    EXPECT_EQ(keptPrefix(nothing, current, 1).length, 0u);
}
