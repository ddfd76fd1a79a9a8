// SPDX-License-Identifier: MIT
#include "device_test_support.h"
#include "keep_visible.h"

#include <gtest/gtest.h>

#include <vector>

namespace occ::k {
namespace {

using test::toDevice;
using test::toHost;
using KeepVisible = test::DeviceTest;

// One frame of keepRecentlyVisible over ids with the HZM's verdicts; the record stays on the device.
std::vector<uint8_t> keepFrame(const std::vector<uint32_t>& ids, const std::vector<uint8_t>& occluded, uint64_t frame,
                               uint32_t keep, DeviceArray<uint32_t>& record) {
    const auto d_ids = toDevice(ids);
    const auto d_occluded = toDevice(occluded);
    auto drop = toDevice(std::vector<uint8_t>(ids.size(), 7));
    keepRecentlyVisible(d_ids.ptr(), d_occluded.ptr(), uint32_t(ids.size()), frame, keep, record.ptr(), drop.ptr());
    return toHost(drop);
}

TEST_F(KeepVisible, AnObjectSeenStaysForKeepFramesThenDrops) {
    auto record = toDevice(std::vector<uint32_t>(4, 0));
    const std::vector<uint32_t> ids = {0, 2, 3};
    // Frame 10: object 2 visible, 0 and 3 hidden and never seen.
    EXPECT_EQ(keepFrame(ids, {1, 0, 1}, 10, 3, record), (std::vector<uint8_t>{1, 0, 1}));
    EXPECT_EQ(toHost(record), (std::vector<uint32_t>{0, 0, 11, 0}));
    // Frames 11 to 13: 2 hidden, kept (seen 1, 2, 3 frames before); 14: dropped.
    for (uint64_t frame = 11; frame <= 13; ++frame)
        EXPECT_EQ(keepFrame(ids, {1, 1, 1}, frame, 3, record), (std::vector<uint8_t>{1, 0, 1})) << frame;
    EXPECT_EQ(keepFrame(ids, {1, 1, 1}, 14, 3, record), (std::vector<uint8_t>{1, 1, 1}));
    // Being kept is not being seen: the record still says frame 10.
    EXPECT_EQ(toHost(record)[2], 11u);
    // Seen again at 20, hidden at 21: kept from the new sighting.
    keepFrame(ids, {1, 0, 1}, 20, 3, record);
    EXPECT_EQ(keepFrame(ids, {1, 1, 1}, 21, 3, record), (std::vector<uint8_t>{1, 0, 1}));
}

TEST_F(KeepVisible, ZeroKeepsNothingButStillRecords) {
    auto record = toDevice(std::vector<uint32_t>(3, 0));
    EXPECT_EQ(keepFrame({0, 1, 2}, {0, 1, 0}, 5, 0, record), (std::vector<uint8_t>{0, 1, 0}));
    EXPECT_EQ(toHost(record), (std::vector<uint32_t>{6, 0, 6}));
    EXPECT_EQ(keepFrame({0, 1, 2}, {1, 1, 1}, 6, 0, record), (std::vector<uint8_t>{1, 1, 1}));
}

TEST_F(KeepVisible, AFrameEarlierThanTheRecordKeepsNothing) {
    auto record = toDevice(std::vector<uint32_t>{31});  // seen at frame 30
    EXPECT_EQ(keepFrame({0}, {1}, 29, 8, record), (std::vector<uint8_t>{1}));
    // The same frame again (a re-run): it was seen in it, so it stays.
    EXPECT_EQ(keepFrame({0}, {1}, 30, 8, record), (std::vector<uint8_t>{0}));
}

TEST_F(KeepVisible, NewlyVisibleMeansVisibleAndUnseenWithinTheWindow) {
    // Objects 0..4 last seen at frames never, 7, 8, 9, 3; all visible at frame 10 but object 1.
    const auto record = toDevice(std::vector<uint32_t>{0, 8, 9, 10, 4});
    const auto ids = toDevice(std::vector<uint32_t>{0, 1, 2, 3, 4});
    const auto occluded = toDevice(std::vector<uint8_t>{0, 1, 0, 0, 0});
    auto flags = toDevice(std::vector<uint8_t>(5, 7));
    markNewlyVisible(ids.ptr(), occluded.ptr(), 5, 10, 2, record.ptr(), flags.ptr());
    // Window 2: seen at 8 or 9 is not new; never seen, or at 3, is; hidden is never new.
    EXPECT_EQ(toHost(flags), (std::vector<uint8_t>{1, 0, 0, 0, 1}));
    markNewlyVisible(ids.ptr(), occluded.ptr(), 5, 10, 4, record.ptr(), flags.ptr());
    EXPECT_EQ(toHost(flags), (std::vector<uint8_t>{1, 0, 0, 0, 1}));
    markNewlyVisible(ids.ptr(), occluded.ptr(), 5, 10, 1, record.ptr(), flags.ptr());
    EXPECT_EQ(toHost(flags), (std::vector<uint8_t>{1, 0, 1, 0, 1}));
}

TEST_F(KeepVisible, MergeNearestKeepsTheSmallerDepthAndScatterPlacesFlags) {
    auto depth = toDevice(std::vector<float>{1.0f, 0.5f, 0.25f, 0.75f});
    const auto other = toDevice(std::vector<float>{0.3f, 1.0f, 0.25f, 0.7f});
    mergeNearest(depth.ptr(), other.ptr(), 4);
    EXPECT_EQ(toHost(depth), (std::vector<float>{0.3f, 0.5f, 0.25f, 0.7f}));

    auto occluded = toDevice(std::vector<uint8_t>{0, 0, 0, 0, 0});
    const auto at = toDevice(std::vector<uint32_t>{4, 1});
    const auto values = toDevice(std::vector<uint8_t>{1, 1});
    scatterFlags(at.ptr(), values.ptr(), 2, occluded.ptr());
    EXPECT_EQ(toHost(occluded), (std::vector<uint8_t>{0, 1, 0, 0, 1}));
}

}  // namespace
}  // namespace occ::k
