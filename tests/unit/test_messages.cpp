// SPDX-License-Identifier: MIT
#include "net/messages.h"

#include "scene/splitmix.h"

#include <gtest/gtest.h>
#include <xxhash.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace occ {
namespace {

constexpr uint32_t kObjects = 115000;

CameraPacket samplePacket() {
    CameraPacket p;
    p.frame = 42;
    p.pose.eye = {1.5f, -2.0f, 30.25f};
    p.pose.target = {0.0f, 0.5f, -1.0f};
    p.pose.up = {0.0f, 0.0f, 1.0f};
    p.pose.fovy_degrees = 47.5f;
    p.pose.near_plane = 0.05f;
    p.pose.far_plane = 5000.0f;
    p.sent_ns = -123456789012345;  // any value: only the sender interprets it
    return p;
}

// prev {1:10, 3:20, 5:30} -> cur {1:10, 3:25, 7:5}: 7 appears, 5 goes, 3 changes its count.
VisibleSet previousSet() { return VisibleSet({{1, 10}, {3, 20}, {5, 30}}); }
VisibleSet currentSet() { return VisibleSet({{1, 10}, {3, 25}, {7, 5}}); }

// Recomputes a message's checksum after a test edited it on purpose, so that the decoder's
// checks behind the checksum can be reached.
void reseal(std::vector<uint8_t>& bytes) {
    XXH3_state_t* state = XXH3_createState();
    XXH3_64bits_reset(state);
    XXH3_64bits_update(state, bytes.data(), 24);
    XXH3_64bits_update(state, bytes.data() + kMessageHeaderSize, bytes.size() - kMessageHeaderSize);
    const uint64_t sum = XXH3_64bits_digest(state);
    XXH3_freeState(state);
    for (int i = 0; i < 8; ++i) bytes[24 + size_t(i)] = uint8_t(sum >> (8 * i));
}

void putU32(std::vector<uint8_t>& bytes, size_t at, uint32_t v) {
    for (int i = 0; i < 4; ++i) bytes[at + size_t(i)] = uint8_t(v >> (8 * i));
}

std::string decodeError(const std::vector<uint8_t>& bytes, const DecodeContext& ctx) {
    try {
        decodeVisibleSetDelta(bytes, ctx);
    } catch (const RankError& e) {
        EXPECT_EQ(e.rank(), ctx.sender);
        return e.what();
    }
    return "";
}

TEST(Messages, CameraPacketRoundTripsBitExactly) {
    const CameraPacket p = samplePacket();
    const std::vector<uint8_t> bytes = encodeCameraPacket(p, 0);
    ASSERT_EQ(bytes.size(), kMessageHeaderSize + kCameraPayloadSize);
    const CameraPacket q = decodeCameraPacket(bytes, {0, 42, kObjects});
    EXPECT_EQ(q.frame, 42u);
    EXPECT_EQ(q.pose.eye, p.pose.eye);
    EXPECT_EQ(q.pose.target, p.pose.target);
    EXPECT_EQ(q.pose.up, p.pose.up);
    EXPECT_EQ(q.pose.fovy_degrees, p.pose.fovy_degrees);
    EXPECT_EQ(q.pose.near_plane, p.pose.near_plane);
    EXPECT_EQ(q.pose.far_plane, p.pose.far_plane);
    EXPECT_EQ(q.sent_ns, p.sent_ns);
}

TEST(Messages, HeaderIsLittleEndianAsDocumented) {
    const std::vector<uint8_t> bytes = encodeEndOfFrame({0x0102030405060708ull, 7, 3, true}, 2);
    const std::vector<uint8_t> header(bytes.begin(), bytes.begin() + 24);
    const std::vector<uint8_t> expected = {'O', 'C', 'S', 'M', 3, 0, 3, 1, 2, 0, 0, 0, 16, 0, 0, 0,
                                           8,   7,   6,   5,   4, 3, 2, 1};
    EXPECT_EQ(header, expected);
    // payload: compute_ns 7 (i64), visible_count 3 (u32), reserved 0 (u32)
    const std::vector<uint8_t> payload(bytes.begin() + 32, bytes.end());
    EXPECT_EQ(payload, (std::vector<uint8_t>{7, 0, 0, 0, 0, 0, 0, 0, 3, 0, 0, 0, 0, 0, 0, 0}));
}

TEST(Messages, EndOfFrameRoundTrips) {
    for (bool last : {false, true}) {
        const EndOfFrame e{9, 16'600'000, 1234, last};
        const EndOfFrame f = decodeEndOfFrame(encodeEndOfFrame(e, 1), {1, 9, kObjects});
        EXPECT_EQ(f.frame, 9u);
        EXPECT_EQ(f.compute_ns, 16'600'000);
        EXPECT_EQ(f.visible_count, 1234u);
        EXPECT_EQ(f.last, last);
    }
}

TEST(Messages, MakeDeltaFindsAddedRemovedAndChanged) {
    const VisibleSetDelta d = makeDelta(previousSet(), currentSet(), 5);
    EXPECT_FALSE(d.full);
    EXPECT_EQ(d.frame, 5u);
    EXPECT_EQ(d.added, (std::vector<std::pair<uint32_t, uint32_t>>{{7, 5}}));
    EXPECT_EQ(d.removed, (std::vector<uint32_t>{5}));
    EXPECT_EQ(d.changed, (std::vector<std::pair<uint32_t, uint32_t>>{{3, 25}}));
    EXPECT_EQ(d.hash, currentSet().hash());
    VisibleSet v = previousSet();
    v.apply(d, 1);
    EXPECT_EQ(v, currentSet());
}

TEST(Messages, DeltaRoundTripsAndEncodedSizeIsExact) {
    const VisibleSetDelta d = makeDelta(previousSet(), currentSet(), 5);
    const std::vector<uint8_t> bytes = encodeVisibleSetDelta(d, kObjects, 1);
    EXPECT_EQ(bytes.size(), encodedSize(d));
    EXPECT_EQ(bytes.size(), 32u + 24u + 8u + 4u + 8u);
    const VisibleSetDelta e = decodeVisibleSetDelta(bytes, {1, 5, kObjects});
    EXPECT_EQ(e.frame, d.frame);
    EXPECT_EQ(e.full, d.full);
    EXPECT_EQ(e.added, d.added);
    EXPECT_EQ(e.removed, d.removed);
    EXPECT_EQ(e.changed, d.changed);
    EXPECT_EQ(e.hash, d.hash);
}

TEST(Messages, FullDeltaReplacesTheSetAndWeighsWhatFullPvsBytesSays) {
    const VisibleSetDelta full = makeFullDelta(currentSet(), 0);
    EXPECT_TRUE(full.full);
    EXPECT_EQ(encodedSize(full), fullVisibleSetEncodedSize(currentSet().size()));
    const VisibleSetDelta e = decodeVisibleSetDelta(encodeVisibleSetDelta(full, kObjects, 2), {2, 0, kObjects});
    EXPECT_TRUE(e.full);
    VisibleSet v = previousSet();  // whatever the receiver had is replaced
    v.apply(e, 2);
    EXPECT_EQ(v, currentSet());
}

TEST(Messages, EmptySetsAndEmptyDeltasWork) {
    const VisibleSet empty;
    const VisibleSetDelta none = makeDelta(currentSet(), currentSet(), 3);
    EXPECT_TRUE(none.added.empty() && none.removed.empty() && none.changed.empty());
    EXPECT_EQ(encodedSize(none), 56u);
    VisibleSet v = currentSet();
    v.apply(decodeVisibleSetDelta(encodeVisibleSetDelta(none, kObjects, 0), {0, 3, kObjects}), 0);
    EXPECT_EQ(v, currentSet());
    v.apply(makeDelta(currentSet(), empty, 4), 0);
    EXPECT_TRUE(v.empty());
    EXPECT_NE(empty.hash(), VisibleSet({{0, 0}}).hash());
}

// V_i rebuilt from V_{i-1} and the decoded delta equals the set the sender had, frame after
// frame, over random sets with churn like a walk through a model (most objects stay).
TEST(Messages, DeltasReconstructEveryFrameOfARandomSequence) {
    SplitMix64 rng(2024);
    constexpr uint32_t objects = 3000;
    VisibleSet sender_prev, receiver;
    std::vector<uint32_t> lod(objects, 0);  // 0 = not visible
    for (uint64_t frame = 0; frame < 200; ++frame) {
        for (uint32_t id = 0; id < objects; ++id) {
            const uint64_t r = rng.next() % 100;
            if (lod[id] == 0 && r < 3)
                lod[id] = 1 + uint32_t(rng.next() % 5000);
            else if (lod[id] != 0 && r < 4)
                lod[id] = 0;
            else if (lod[id] != 0 && r < 10)
                lod[id] = 1 + uint32_t(rng.next() % 5000);
        }
        std::vector<VisibleSet::Entry> entries;
        for (uint32_t id = 0; id < objects; ++id)
            if (lod[id] != 0) entries.push_back({id, lod[id]});
        const VisibleSet current(entries);
        const bool full = frame == 0 || frame % 50 == 0;
        const VisibleSetDelta d = full ? makeFullDelta(current, frame) : makeDelta(sender_prev, current, frame);
        const std::vector<uint8_t> bytes = encodeVisibleSetDelta(d, objects, 1);
        EXPECT_EQ(bytes.size(), encodedSize(d));
        if (!full) {
            EXPECT_LT(bytes.size(), fullVisibleSetEncodedSize(current.size()));
        }
        receiver.apply(decodeVisibleSetDelta(bytes, {1, frame, objects}), 1);
        ASSERT_EQ(receiver, current) << "frame " << frame;
        sender_prev = current;
    }
}

TEST(Messages, ApplyRejectsAWrongHashNamingTheRankAndKeepsTheSet) {
    VisibleSetDelta d = makeDelta(previousSet(), currentSet(), 8);
    d.hash ^= 1;
    VisibleSet v = previousSet();
    try {
        v.apply(d, 2);
        FAIL() << "a wrong hash was accepted";
    } catch (const RankError& e) {
        EXPECT_EQ(e.rank(), 2);
        EXPECT_EQ(std::string(e.what()).rfind("rank 2: delta of frame 8: hash of the rebuilt set", 0), 0u) << e.what();
    }
    EXPECT_EQ(v, previousSet());
}

TEST(Messages, ApplyRejectsIdsThatDoNotFitTheSet) {
    const auto rejects = [](VisibleSetDelta d, const std::string& words) {
        d.hash = 0;  // the set checks come before the hash check
        VisibleSet v = previousSet();
        try {
            v.apply(d, 1);
            ADD_FAILURE() << "accepted a delta that should fail with: " << words;
        } catch (const RankError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
            EXPECT_EQ(std::string(e.what()).rfind("rank 1: delta of frame 0: ", 0), 0u) << e.what();
        }
        EXPECT_EQ(v, previousSet());
    };
    VisibleSetDelta d;
    d.added = {{3, 1}};
    rejects(d, "added id 3 is already visible");
    d = {};
    d.removed = {4};
    rejects(d, "removed id 4 is not visible");
    d = {};
    d.removed = {9};
    rejects(d, "removed id 9 is not visible");
    d = {};
    d.changed = {{2, 7}};
    rejects(d, "changed id 2 is not visible");
    d = {};
    d.removed = {3};
    d.changed = {{3, 7}};
    rejects(d, "both removed and changed");
    d = {};
    d.removed = {5, 1};
    rejects(d, "removed ids not ascending (5 then 1)");
    d = {};
    d.added = {{8, 1}, {8, 2}};
    rejects(d, "added ids not ascending (8 then 8)");
    d = {};
    d.full = true;
    d.removed = {1};
    rejects(d, "a full set with removed or changed ids");
}

TEST(Messages, DecodeRejectsAnIdBeyondTheObjectCountNamingTheRank) {
    VisibleSetDelta d;
    d.frame = 5;
    d.added = {{17, 4}, {123456, 9}};
    const std::vector<uint8_t> bytes = encodeVisibleSetDelta(d, kObjects, 2);
    EXPECT_EQ(decodeError(bytes, {2, 5, kObjects}), "rank 2: delta of frame 5: added id 123456 >= object count 115000");
}

TEST(Messages, DecodeRejectsFramesOutOfOrder) {
    const std::vector<uint8_t> bytes = encodeVisibleSetDelta(makeDelta(previousSet(), currentSet(), 7), kObjects, 1);
    EXPECT_EQ(decodeError(bytes, {1, 6, kObjects}), "rank 1: delta of frame 7: expected frame 6 (out of order)");
    EXPECT_THROW(decodeCameraPacket(encodeCameraPacket(samplePacket(), 0), {0, 41, kObjects}), RankError);
    EXPECT_THROW(decodeEndOfFrame(encodeEndOfFrame({3, 0, 0, false}, 0), {0, 4, kObjects}), RankError);
}

TEST(Messages, DecodeRejectsHeaderMismatches) {
    const std::vector<uint8_t> delta = encodeVisibleSetDelta(makeDelta(previousSet(), currentSet(), 7), kObjects, 1);
    EXPECT_EQ(decodeError(delta, {2, 7, kObjects}), "rank 2: delta message: header says it comes from rank 1");
    EXPECT_EQ(decodeError(delta, {1, 7, 1000}),
              "rank 1: delta of frame 7: sender's scene has 115000 objects, ours 1000 (not the same .oss file?)");
    const std::vector<uint8_t> camera = encodeCameraPacket(samplePacket(), 1);
    EXPECT_EQ(decodeError(camera, {1, 42, kObjects}), "rank 1: delta message: header says kind 1 (camera)");

    std::vector<uint8_t> newer = delta;
    newer[4] = 4;
    reseal(newer);
    EXPECT_EQ(decodeError(newer, {1, 7, kObjects}),
              "rank 1: delta message: protocol version 4, this build speaks version 3 (mixed builds?)");
    std::vector<uint8_t> flagged = delta;
    flagged[7] = 0x80;
    reseal(flagged);
    EXPECT_EQ(decodeError(flagged, {1, 7, kObjects}), "rank 1: delta of frame 7: unknown flags 128");
}

TEST(Messages, DecodeRejectsCountsThatDoNotMatchTheBytes) {
    std::vector<uint8_t> bytes = encodeVisibleSetDelta(makeDelta(previousSet(), currentSet(), 7), kObjects, 1);
    putU32(bytes, 32 + 4, 0xFFFFFFFFu);  // added_count: 2^32 - 1 entries would need 32 GiB
    reseal(bytes);
    EXPECT_EQ(decodeError(bytes, {1, 7, kObjects}),
              "rank 1: delta of frame 7: 4294967295 added, 1 removed, 1 changed need 34359738396 payload bytes, "
              "44 arrived");
}

TEST(Messages, DecodeRejectsIdsNotAscending) {
    VisibleSetDelta d;
    d.frame = 1;
    d.removed = {10, 4};
    EXPECT_EQ(decodeError(encodeVisibleSetDelta(d, kObjects, 0), {0, 1, kObjects}),
              "rank 0: delta of frame 1: removed ids not ascending (10 then 4)");
}

TEST(Messages, DecodeRejectsUnrenderableCameras) {
    CameraPacket p = samplePacket();
    p.pose.eye.x = std::numeric_limits<float>::quiet_NaN();
    EXPECT_THROW(decodeCameraPacket(encodeCameraPacket(p, 0), {0, 42, kObjects}), RankError);
    p = samplePacket();
    p.pose.far_plane = p.pose.near_plane;
    EXPECT_THROW(decodeCameraPacket(encodeCameraPacket(p, 0), {0, 42, kObjects}), RankError);
}

TEST(Messages, ReportRoundTripsItsRecords) {
    std::vector<FrameRecord> records(3);
    for (size_t i = 0; i < records.size(); ++i) {
        FrameRecord& r = records[i];
        r.rank = 3;
        r.stats.frame = 2 * i + 1;
        r.stats.objects_visible = 40 + i;
        r.stats.pvs_hash = 0x0123456789abcdefull;
        r.stats.ms[2] = 1.25;
        r.net.bytes[1] = 700 + i;
        r.net.latency_ms = -1;
        r.net.partition = 2;
        r.displayed = i == 1;
        r.display.psnr_db = 100;
        r.display.false_culls = 0;
    }
    const std::vector<FrameRecord> q = decodeReport(encodeReport(records, 3), {3, 3, kObjects});
    ASSERT_EQ(q.size(), 3u);
    for (size_t i = 0; i < q.size(); ++i) {
        EXPECT_EQ(q[i].rank, 3);
        EXPECT_EQ(q[i].stats.frame, records[i].stats.frame);
        EXPECT_EQ(q[i].stats.objects_visible, records[i].stats.objects_visible);
        EXPECT_EQ(q[i].stats.pvs_hash, records[i].stats.pvs_hash);
        EXPECT_EQ(q[i].stats.ms[2], 1.25);
        EXPECT_EQ(q[i].net.bytes[1], records[i].net.bytes[1]);
        EXPECT_EQ(q[i].net.latency_ms, -1);
        EXPECT_EQ(q[i].net.partition, 2);
        EXPECT_EQ(q[i].displayed, i == 1);
        EXPECT_EQ(q[i].display.psnr_db, 100);
    }
    // The count must be the one expected, every record the sender's, frames ascending and figures finite.
    EXPECT_THROW(decodeReport(encodeReport(records, 3), {3, 4, kObjects}), RankError);
    EXPECT_THROW(decodeReport(encodeReport(records, 3), {2, 3, kObjects}), RankError);
    std::vector<FrameRecord> bad = records;
    bad[2].stats.frame = 1;
    EXPECT_THROW(decodeReport(encodeReport(bad, 3), {3, 3, kObjects}), RankError);
    bad = records;
    bad[0].stats.ms_total = std::numeric_limits<double>::infinity();
    EXPECT_THROW(decodeReport(encodeReport(bad, 3), {3, 3, kObjects}), RankError);
    bad = records;
    bad[1].net.partition = -2;
    EXPECT_THROW(decodeReport(encodeReport(bad, 3), {3, 3, kObjects}), RankError);
    // A culling rank's record (no partition) drew nothing; times are never negative.
    bad = records;
    bad[1].net.partition = -1;
    EXPECT_THROW(decodeReport(encodeReport(bad, 3), {3, 3, kObjects}), RankError);
    bad = records;
    bad[2].stats.ms[0] = -0.5;
    EXPECT_THROW(decodeReport(encodeReport(bad, 3), {3, 3, kObjects}), RankError);
    // A record of another rank is not encoded.
    bad = records;
    bad[0].rank = 1;
    EXPECT_THROW(encodeReport(bad, 3), std::invalid_argument);
    // A flag byte other than 0 or 1 (the `displayed` byte follows the rank's 4 bytes).
    std::vector<uint8_t> bytes = encodeReport(records, 3);
    bytes[kMessageHeaderSize + 4] = 7;
    reseal(bytes);
    EXPECT_THROW(decodeReport(bytes, {3, 3, kObjects}), RankError);
}

TEST(Messages, DecodeRejectsEndOfFrameBeyondTheScene) {
    EXPECT_THROW(decodeEndOfFrame(encodeEndOfFrame({3, 0, kObjects + 1, false}, 0), {0, 3, kObjects}), RankError);
    EXPECT_THROW(decodeEndOfFrame(encodeEndOfFrame({3, -5, 0, false}, 0), {0, 3, kObjects}), RankError);
}

// Every prefix and every single-byte change of a valid message is rejected with RankError:
// never accepted, never another exception, never a read outside the buffer (ASan build).
template <typename Decode>
void expectEveryTruncationAndFlipRejected(const std::vector<uint8_t>& bytes, Decode decode) {
    for (size_t n = 0; n < bytes.size(); ++n) {
        const std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + ptrdiff_t(n));
        EXPECT_THROW(decode(prefix), RankError) << "prefix of " << n << " bytes";
    }
    for (size_t i = 0; i < bytes.size(); ++i) {
        for (uint8_t flip : {uint8_t(0x01), uint8_t(0x80), uint8_t(0xFF)}) {
            std::vector<uint8_t> changed = bytes;
            changed[i] ^= flip;
            EXPECT_THROW(decode(changed), RankError) << "byte " << i << " ^ " << int(flip);
        }
    }
    std::vector<uint8_t> longer = bytes;
    longer.push_back(0);
    EXPECT_THROW(decode(longer), RankError);
}

TEST(Messages, EveryTruncationAndByteFlipOfADeltaIsRejected) {
    const std::vector<uint8_t> bytes = encodeVisibleSetDelta(makeDelta(previousSet(), currentSet(), 7), kObjects, 1);
    expectEveryTruncationAndFlipRejected(bytes, [](const std::vector<uint8_t>& b) {
        return decodeVisibleSetDelta(b, {1, 7, kObjects});
    });
}

TEST(Messages, EveryTruncationAndByteFlipOfACameraPacketIsRejected) {
    expectEveryTruncationAndFlipRejected(encodeCameraPacket(samplePacket(), 0), [](const std::vector<uint8_t>& b) {
        return decodeCameraPacket(b, {0, 42, kObjects});
    });
}

TEST(Messages, EveryTruncationAndByteFlipOfAnEndOfFrameIsRejected) {
    expectEveryTruncationAndFlipRejected(encodeEndOfFrame({11, 5000, 12, true}, 2), [](const std::vector<uint8_t>& b) {
        return decodeEndOfFrame(b, {2, 11, kObjects});
    });
}

// Past the checksum: every value of every payload byte of a resealed delta either decodes (and
// then re-encodes to the same bytes) or is rejected with RankError.
TEST(Messages, EveryResealedPayloadByteValueDecodesOrIsRejected) {
    const std::vector<uint8_t> bytes = encodeVisibleSetDelta(makeDelta(previousSet(), currentSet(), 7), kObjects, 1);
    int accepted = 0, rejected = 0;
    for (size_t i = kMessageHeaderSize; i < bytes.size(); ++i) {
        for (int v = 0; v < 256; ++v) {
            std::vector<uint8_t> changed = bytes;
            changed[i] = uint8_t(v);
            reseal(changed);
            try {
                const VisibleSetDelta d = decodeVisibleSetDelta(changed, {1, 7, kObjects});
                EXPECT_EQ(encodeVisibleSetDelta(d, kObjects, 1), changed);
                ++accepted;
            } catch (const RankError&) {
                ++rejected;
            }
        }
    }
    EXPECT_GT(accepted, 0);
    EXPECT_GT(rejected, 0);
}

}  // namespace
}  // namespace occ
