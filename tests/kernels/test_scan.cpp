// SPDX-License-Identifier: MIT
#include "scan.h"

// forEachRun and keptPrefix are kernel helpers; they are tested here on host arrays only.
#include "block_runs.h"
#include "device_test_support.h"

#include <gtest/gtest.h>

#include <random>
#include <utility>
#include <vector>

using namespace occ::k;
using namespace occ::k::test;

using Scan = DeviceTest;
using Compact = DeviceTest;

namespace {

std::pair<std::vector<uint64_t>, uint64_t> scan(const std::vector<uint32_t>& in) {
    const DeviceArray<uint32_t> in_d = toDevice(in);
    DeviceArray<uint64_t> out(in.size());
    const uint64_t total = exclusiveScan(in_d.ptr(), uint32_t(in.size()), out.ptr());
    return {toHost(out), total};
}

// compactIndices or compactSelected (ids given), downloaded: what it wrote, and the count it
// returned checked against it. The room past the count is filled with a sentinel that must stay.
constexpr uint32_t kUntouched = 0xDEADBEEF;
std::vector<uint32_t> compact(const std::vector<uint8_t>& flags, uint8_t value, const std::vector<uint32_t>& ids = {}) {
    const DeviceArray<uint8_t> flags_d = toDevice(flags);
    const DeviceArray<uint32_t> ids_d = toDevice(ids);
    DeviceArray<uint32_t> out = filledDevice(flags.size() + 1, kUntouched);
    const uint32_t n = ids.empty() ? compactIndices(flags_d.ptr(), uint32_t(flags.size()), value, out.ptr())
                                   : compactSelected(ids_d.ptr(), flags_d.ptr(), uint32_t(flags.size()), value, out.ptr());
    std::vector<uint32_t> written = toHost(out);
    EXPECT_LE(n, flags.size());
    for (size_t i = n; i < written.size(); ++i) EXPECT_EQ(written[i], kUntouched) << "written past the count at " << i;
    written.resize(n);
    return written;
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

TEST_F(Scan, SmallInputGivesTheSumsBeforeEachElement) {
    const auto [out, total] = scan({3, 0, 4, 1});
    EXPECT_EQ(out, (std::vector<uint64_t>{0, 3, 3, 7}));
    EXPECT_EQ(total, 8u);
}

TEST_F(Scan, OneElement) {
    const auto [out, total] = scan({5});
    EXPECT_EQ(out, (std::vector<uint64_t>{0}));
    EXPECT_EQ(total, 5u);
}

TEST_F(Scan, EmptyInputWritesNothingAndSumsToZero) {
    EXPECT_EQ(exclusiveScan(nullptr, 0, nullptr), 0u);
    const auto [out, total] = scan({});
    EXPECT_TRUE(out.empty());
    EXPECT_EQ(total, 0u);
}

TEST_F(Scan, SumsPast32BitsDoNotWrap) {
    const auto [out, total] = scan({0xFFFFFFFFu, 0xFFFFFFFFu, 2});
    EXPECT_EQ(out[2], 2 * uint64_t(0xFFFFFFFFu));
    EXPECT_EQ(total, 2 * uint64_t(0xFFFFFFFFu) + 2);
}

TEST_F(Scan, LargeRandomInputMatchesASerialScan) {
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

TEST_F(Scan, ForEachRunSplitsARangeAtSegmentBoundariesAndSkipsEmptySegments) {
    // Segment sizes 2, 0, 3, 0, 0, 4: offsets 0 2 2 5 5 5, total 9.
    const std::vector<uint64_t> offsets{0, 2, 2, 5, 5, 5};
    using R = std::vector<std::vector<uint64_t>>;
    EXPECT_EQ(runs(offsets, 9, 0, 9), (R{{0, 0, 2}, {2, 0, 3}, {5, 0, 4}}));
    EXPECT_EQ(runs(offsets, 9, 1, 6), (R{{0, 1, 1}, {2, 0, 3}, {5, 0, 1}}));
    EXPECT_EQ(runs(offsets, 9, 2, 3), (R{{2, 0, 1}}));
    EXPECT_EQ(runs(offsets, 9, 8, 9), (R{{5, 3, 1}}));
}

TEST_F(Scan, ForEachRunSkipsLeadingEmptySegments) {
    const std::vector<uint64_t> offsets{0, 0, 0, 1};
    using R = std::vector<std::vector<uint64_t>>;
    EXPECT_EQ(runs(offsets, 3, 0, 3), (R{{2, 0, 1}, {3, 0, 2}}));
}

TEST_F(Scan, KeptPrefixIsTheSharedPartOfTheSameObjectsBlocks) {
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

TEST_F(Compact, IndicesAreThoseWithTheValueAscending) {
    const std::vector<uint8_t> flags{1, 0, 2, 1, 1, 0};
    EXPECT_EQ(compact(flags, 1), (std::vector<uint32_t>{0, 3, 4}));
    EXPECT_EQ(compact(flags, 0), (std::vector<uint32_t>{1, 5}));
    EXPECT_EQ(compact(flags, 2), (std::vector<uint32_t>{2}));
    EXPECT_EQ(compact(flags, 3), (std::vector<uint32_t>{}));
}

TEST_F(Compact, SelectedIdsKeepTheirOrder) {
    // The ids are not the positions, and not ascending: the output follows the input order.
    const std::vector<uint32_t> ids{90, 80, 7, 60, 5, 41};
    const std::vector<uint8_t> flags{1, 0, 2, 1, 1, 0};
    EXPECT_EQ(compact(flags, 1, ids), (std::vector<uint32_t>{90, 60, 5}));
    EXPECT_EQ(compact(flags, 0, ids), (std::vector<uint32_t>{80, 41}));
    EXPECT_EQ(compact(flags, 2, ids), (std::vector<uint32_t>{7}));
}

TEST_F(Compact, EmptyInputWritesNothing) {
    EXPECT_EQ(compactIndices(nullptr, 0, 1, nullptr), 0u);
    EXPECT_EQ(compactSelected(nullptr, nullptr, 0, 1, nullptr), 0u);
    EXPECT_EQ(compact({}, 1), (std::vector<uint32_t>{}));
}

TEST_F(Compact, LargeRandomInputMatchesASerialFilter) {
    std::mt19937 rng(9);
    std::vector<uint8_t> flags(1'000'003);
    std::vector<uint32_t> ids(flags.size());
    for (uint8_t& f : flags) f = uint8_t(rng() % 3);
    for (uint32_t& id : ids) id = rng();
    std::vector<uint32_t> indices, selected;
    for (uint32_t i = 0; i < flags.size(); ++i)
        if (flags[i] == 2) indices.push_back(i), selected.push_back(ids[i]);
    EXPECT_EQ(compact(flags, 2), indices);
    EXPECT_EQ(compact(flags, 2, ids), selected);
}

TEST_F(Compact, TheUnionOfTwoAscendingListsHasEachIdOnceInOrder) {
    const auto run = [](const std::vector<uint32_t>& a, const std::vector<uint32_t>& b) {
        const auto da = toDevice(a), db = toDevice(b);
        auto out = toDevice(std::vector<uint32_t>(a.size() + b.size() + 1, 7u));
        const uint32_t n = unionAscending(da.ptr(), uint32_t(a.size()), db.ptr(), uint32_t(b.size()), out.ptr());
        return toHost(out, n);
    };
    EXPECT_EQ(run({1, 4, 9, 12}, {2, 4, 12, 30}), (std::vector<uint32_t>{1, 2, 4, 9, 12, 30}));
    EXPECT_EQ(run({}, {3, 5}), (std::vector<uint32_t>{3, 5}));
    EXPECT_EQ(run({3, 5}, {}), (std::vector<uint32_t>{3, 5}));
    EXPECT_TRUE(run({}, {}).empty());
    EXPECT_EQ(run({0, 1, 2}, {0, 1, 2}), (std::vector<uint32_t>{0, 1, 2}));
}
