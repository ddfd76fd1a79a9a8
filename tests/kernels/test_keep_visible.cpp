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

// One frame of keepRecentlyVisible over ids with the HZM's verdicts; the records stay on the device.
struct Records {
    DeviceArray<uint32_t> seen, returned;
    explicit Records(size_t n) : seen(toDevice(std::vector<uint32_t>(n, 0))), returned(toDevice(std::vector<uint32_t>(n, 0))) {}
};

std::vector<uint8_t> keepFrame(const std::vector<uint32_t>& ids, const std::vector<uint8_t>& occluded, uint64_t frame,
                               uint32_t keep, Records& r, uint32_t step = 1) {
    const auto d_ids = toDevice(ids);
    const auto d_occluded = toDevice(occluded);
    auto drop = toDevice(std::vector<uint8_t>(ids.size(), 7));
    keepRecentlyVisible(d_ids.ptr(), d_occluded.ptr(), uint32_t(ids.size()), frame, keep, step, r.seen.ptr(),
                        r.returned.ptr(), drop.ptr());
    return toHost(drop);
}

TEST_F(KeepVisible, AnObjectThatGoesOutOfSightIsDroppedAtOnce) {
    Records r(3);
    EXPECT_EQ(keepFrame({0, 1, 2}, {0, 0, 1}, 10, 2, r), (std::vector<uint8_t>{0, 0, 1}));
    EXPECT_EQ(toHost(r.seen), (std::vector<uint32_t>{11, 11, 0}));
    EXPECT_EQ(keepFrame({0, 1, 2}, {1, 0, 1}, 11, 2, r), (std::vector<uint8_t>{1, 0, 1}));
}

TEST_F(KeepVisible, AFlickeringObjectIsKeptThroughShortGaps) {
    Records r(1);
    // Seen at 10, hidden at 11 (dropped: no flicker yet), seen again at 12 after a one-frame gap.
    EXPECT_EQ(keepFrame({0}, {0}, 10, 2, r), (std::vector<uint8_t>{0}));
    EXPECT_EQ(keepFrame({0}, {1}, 11, 2, r), (std::vector<uint8_t>{1}));
    EXPECT_EQ(keepFrame({0}, {0}, 12, 2, r), (std::vector<uint8_t>{0}));
    EXPECT_EQ(toHost(r.returned), (std::vector<uint32_t>{13}));
    // From now on a gap of up to 2 frames is bridged; a third hidden frame drops it.
    EXPECT_EQ(keepFrame({0}, {1}, 13, 2, r), (std::vector<uint8_t>{0}));
    EXPECT_EQ(keepFrame({0}, {1}, 14, 2, r), (std::vector<uint8_t>{0}));
    EXPECT_EQ(keepFrame({0}, {1}, 15, 2, r), (std::vector<uint8_t>{1}));
    // Being kept is not being seen: the record still says frame 12.
    EXPECT_EQ(toHost(r.seen), (std::vector<uint32_t>{13}));
    // Back at 17 after a gap of 4 > 1 + 2 frames: not a flicker, so its memory is not refreshed,
    // but the one from frame 12 still holds until 12 + kFlickerMemory.
    EXPECT_EQ(keepFrame({0}, {0}, 17, 2, r), (std::vector<uint8_t>{0}));
    EXPECT_EQ(toHost(r.returned), (std::vector<uint32_t>{13}));
    EXPECT_EQ(keepFrame({0}, {1}, 18, 2, r), (std::vector<uint8_t>{0}));
    // Long after its last return it is dropped at once again.
    keepFrame({0}, {0}, 12 + kFlickerMemory, 2, r);
    EXPECT_EQ(keepFrame({0}, {1}, 13 + kFlickerMemory, 2, r), (std::vector<uint8_t>{1}));
}

TEST_F(KeepVisible, AParityRecordCountsGapsInItsOwnSteps) {
    Records r(1);
    // Culled every other frame (step 2): seen at 10 and 14 with 12 hidden is a flicker.
    keepFrame({0}, {0}, 10, 2, r, 2);
    EXPECT_EQ(keepFrame({0}, {1}, 12, 2, r, 2), (std::vector<uint8_t>{1}));
    keepFrame({0}, {0}, 14, 2, r, 2);
    EXPECT_EQ(keepFrame({0}, {1}, 16, 2, r, 2), (std::vector<uint8_t>{0}));
    // Seen at 16 would not be a gap at all with step 2 (frames 14 and 16 are consecutive culls).
    Records q(1);
    keepFrame({0}, {0}, 14, 2, q, 2);
    keepFrame({0}, {0}, 16, 2, q, 2);
    EXPECT_EQ(toHost(q.returned), (std::vector<uint32_t>{0}));
}

TEST_F(KeepVisible, ZeroKeepsNothingButStillRecords) {
    Records r(3);
    EXPECT_EQ(keepFrame({0, 1, 2}, {0, 1, 0}, 5, 0, r), (std::vector<uint8_t>{0, 1, 0}));
    EXPECT_EQ(toHost(r.seen), (std::vector<uint32_t>{6, 0, 6}));
    keepFrame({0, 1, 2}, {1, 1, 1}, 6, 0, r);
    EXPECT_EQ(keepFrame({0, 1, 2}, {0, 1, 1}, 7, 0, r), (std::vector<uint8_t>{0, 1, 1}));
    EXPECT_EQ(keepFrame({0, 1, 2}, {1, 1, 1}, 8, 0, r), (std::vector<uint8_t>{1, 1, 1}));
}

TEST_F(KeepVisible, AFrameEarlierThanTheRecordKeepsNothing) {
    Records r(1);
    keepFrame({0}, {0}, 30, 8, r);
    keepFrame({0}, {1}, 31, 8, r);
    keepFrame({0}, {0}, 32, 8, r);  // a flicker
    EXPECT_EQ(keepFrame({0}, {1}, 29, 8, r), (std::vector<uint8_t>{1}));
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
