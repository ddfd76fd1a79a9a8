// SPDX-License-Identifier: MIT
#include "net/emulated_link.h"
#include "net/transport.h"
#include "scene/errors.h"

#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace occ {
namespace {

using namespace std::chrono_literals;

TEST(InProcessTransport, OneRankTalksToItselfAndCountsPerKind) {
    InProcessHub hub(1);
    std::unique_ptr<Transport> t = hub.connect(0);
    EXPECT_EQ(t->rank(), 0);
    EXPECT_EQ(t->size(), 1);
    t->send(0, MessageKind::Delta, {1, 2, 3});
    t->send(0, MessageKind::Delta, {4});
    t->send(0, MessageKind::Camera, std::vector<uint8_t>(10, 7));
    EXPECT_EQ(t->receive(0, MessageKind::Camera, 1s), std::vector<uint8_t>(10, 7));
    EXPECT_EQ(t->receive(0, MessageKind::Delta, 1s), (std::vector<uint8_t>{1, 2, 3}));  // in order per kind
    EXPECT_EQ(t->receive(0, MessageKind::Delta, 1s), (std::vector<uint8_t>{4}));
    const TransportCounters c = t->counters();
    EXPECT_EQ(c[MessageKind::Delta].bytes_sent, 4u);
    EXPECT_EQ(c[MessageKind::Delta].messages_sent, 2u);
    EXPECT_EQ(c[MessageKind::Camera].bytes_sent, 10u);
    EXPECT_EQ(c[MessageKind::Camera].messages_received, 1u);
    EXPECT_EQ(c[MessageKind::EndOfFrame].messages_sent, 0u);
    t->finish(1s);
}

TEST(InProcessTransport, CounterDifferencesGiveOneFramesShare) {
    InProcessHub hub(1);
    auto t = hub.connect(0);
    t->send(0, MessageKind::EndOfFrame, std::vector<uint8_t>(48));
    const TransportCounters before = t->counters();
    t->send(0, MessageKind::EndOfFrame, std::vector<uint8_t>(48));
    t->send(0, MessageKind::Delta, std::vector<uint8_t>(100));
    const TransportCounters frame = t->counters() - before;
    EXPECT_EQ(frame[MessageKind::EndOfFrame].bytes_sent, 48u);
    EXPECT_EQ(frame[MessageKind::EndOfFrame].messages_sent, 1u);
    EXPECT_EQ(frame[MessageKind::Delta].bytes_sent, 100u);
    t->receive(0, MessageKind::EndOfFrame, 1s);
    t->receive(0, MessageKind::EndOfFrame, 1s);
    t->receive(0, MessageKind::Delta, 1s);
    t->finish(1s);
}

// Three threads pass visible-set deltas around a ring; each rebuilds its neighbour's set from
// the deltas and checks it against the hash, as the switch ranks do.
TEST(InProcessTransport, ThreeRanksRebuildEachOthersSetsFromDeltas) {
    constexpr int ranks = 3;
    constexpr uint32_t objects = 500;
    InProcessHub hub(ranks);
    std::vector<std::string> errors(ranks);
    std::vector<std::thread> threads;
    for (int r = 0; r < ranks; ++r) {
        threads.emplace_back([&, r, t = hub.connect(r)] {
            try {
                VisibleSet mine, theirs;
                const int next = (r + 1) % ranks, prev = (r + ranks - 1) % ranks;
                for (uint64_t frame = 0; frame < 50; ++frame) {
                    std::vector<VisibleSet::Entry> e;
                    for (uint32_t id = uint32_t(r); id < objects; id += uint32_t(3 + (frame + id) % 7))
                        e.push_back({id, uint32_t(1 + (frame * 13 + id) % 90)});
                    const VisibleSet current(e);
                    const VisibleSetDelta d = frame == 0 ? makeFullDelta(current, frame) : makeDelta(mine, current, frame);
                    t->send(next, MessageKind::Delta, encodeVisibleSetDelta(d, objects, r));
                    mine = current;
                    theirs.apply(decodeVisibleSetDelta(t->receive(prev, MessageKind::Delta, 5s), {prev, frame, objects}),
                                 prev);
                }
                t->finish(5s);
            } catch (const std::exception& ex) {
                errors[size_t(r)] = ex.what();
            }
        });
    }
    for (auto& th : threads) th.join();
    for (int r = 0; r < ranks; ++r) EXPECT_EQ(errors[size_t(r)], "") << "rank " << r;
}

TEST(InProcessTransport, SilenceBecomesAnErrorNamingTheSilentRankOnEveryRank) {
    InProcessHub hub(3);
    auto t0 = hub.connect(0);
    auto t1 = hub.connect(1);
    auto t2 = hub.connect(2);
    const auto start = std::chrono::steady_clock::now();
    try {
        t2->receive(1, MessageKind::Delta, 100ms);
        FAIL() << "receive returned without a message";
    } catch (const RankError& e) {
        EXPECT_EQ(e.rank(), 1);
        EXPECT_STREQ(e.what(), "rank 1: no delta message for 100 ms: the rank died or stopped answering");
    }
    EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
    try {
        t0->receive(2, MessageKind::Camera, 10s);  // rank 0 learns at once, not after 10 s
        FAIL() << "receive returned without a message";
    } catch (const RankError& e) {
        EXPECT_EQ(e.rank(), 1);
        EXPECT_STREQ(e.what(),
                     "rank 1: no delta message for 100 ms: the rank died or stopped answering (reported by rank 2)");
    }
    EXPECT_LT(std::chrono::steady_clock::now() - start, 2s);
    EXPECT_THROW(t0->send(1, MessageKind::Camera, {1}), RankError);  // the run has failed for good
}

TEST(InProcessTransport, AFailingRankStopsTheOthers) {
    InProcessHub hub(2);
    auto t0 = hub.connect(0);
    std::thread failing([t1 = hub.connect(1)] {
        std::this_thread::sleep_for(20ms);
        t1->fail(1, "cannot open scene.oss");
    });
    try {
        t0->receive(1, MessageKind::Delta, 10s);
        ADD_FAILURE() << "receive returned without a message";
    } catch (const RankError& e) {
        EXPECT_STREQ(e.what(), "rank 1: cannot open scene.oss");
    }
    failing.join();
}

TEST(InProcessTransport, AnEndpointDroppedWithoutFinishingIsAFault) {
    InProcessHub hub(2);
    auto t0 = hub.connect(0);
    hub.connect(1).reset();
    try {
        t0->finish(10s);
        FAIL() << "finish returned although rank 1 is gone";
    } catch (const RankError& e) {
        EXPECT_STREQ(e.what(), "rank 1: stopped without finishing the run");
    }
}

TEST(InProcessTransport, FinishWaitsForEveryRankAndNamesALateOne) {
    InProcessHub hub(2);
    auto t0 = hub.connect(0);
    auto t1 = hub.connect(1);
    try {
        t0->finish(50ms);
        FAIL() << "finish returned although rank 1 did not finish";
    } catch (const RankError& e) {
        EXPECT_STREQ(e.what(), "rank 1: did not finish the run within 50 ms");
    }
}

TEST(InProcessTransport, BadPeersAndDoubleConnectsAreUsageErrors) {
    InProcessHub hub(2);
    auto t0 = hub.connect(0);
    EXPECT_THROW(hub.connect(0), std::invalid_argument);
    EXPECT_THROW(hub.connect(2), std::invalid_argument);
    EXPECT_THROW(t0->send(2, MessageKind::Delta, {}), std::invalid_argument);
    EXPECT_THROW(t0->receive(-1, MessageKind::Delta, 1ms), std::invalid_argument);
    EXPECT_THROW(InProcessHub(0), std::invalid_argument);
    t0->fail(0, "test over");
}

// The emulated link (issue 17): a message is not handed over before latency + bytes / bandwidth
// after it was sent (lower bounds only: a loaded machine may add, never take away), in order per
// pair, and the counters hold the message bytes, not the link's stamps.
TEST(EmulatedLinkTransport, DelaysEachMessageByLatencyAndBytesAtTheBandwidthInOrder) {
    InProcessHub hub(2);
    const LinkSpec spec = parseLinkSpec("30:8");  // 30 ms, 8 Mb/s: a byte takes 1 us
    EmulatedLink a(hub.connect(0), spec), b(hub.connect(1), spec);
    EXPECT_EQ(a.rank(), 0);
    EXPECT_EQ(b.size(), 2);
    const auto start = std::chrono::steady_clock::now();
    a.send(1, MessageKind::Delta, std::vector<uint8_t>(10000, 5));  // 10 ms on the wire
    a.send(1, MessageKind::Delta, {1, 2, 3});
    a.send(1, MessageKind::Camera, {9});
    EXPECT_FALSE(b.poll(0, MessageKind::Delta)) << "a message arrived before the link's latency";
    EXPECT_EQ(b.receive(0, MessageKind::Delta, 2s), std::vector<uint8_t>(10000, 5));
    EXPECT_GE(std::chrono::steady_clock::now() - start, 39ms);
    EXPECT_EQ(b.receive(0, MessageKind::Delta, 2s), (std::vector<uint8_t>{1, 2, 3}));
    EXPECT_EQ(b.receive(0, MessageKind::Camera, 2s), (std::vector<uint8_t>{9}));
    // A rank to itself is no link.
    const auto self = std::chrono::steady_clock::now();
    b.send(1, MessageKind::EndOfFrame, {7});
    EXPECT_TRUE(b.poll(1, MessageKind::EndOfFrame));
    EXPECT_EQ(b.receive(1, MessageKind::EndOfFrame, 2s), (std::vector<uint8_t>{7}));
    EXPECT_LT(std::chrono::steady_clock::now() - self, 25ms);
    const TransportCounters sent = a.counters(), got = b.counters();
    EXPECT_EQ(sent[MessageKind::Delta].bytes_sent, 10003u);
    EXPECT_EQ(sent[MessageKind::Delta].messages_sent, 2u);
    EXPECT_EQ(got[MessageKind::Delta].bytes_received, 10003u);
    EXPECT_EQ(got[MessageKind::Camera].bytes_received, 1u);
    EXPECT_GE(got[MessageKind::Delta].receive_wait_ns, 30'000'000) << "the wait for the link counts as waiting";
    std::thread other([&] { a.finish(2s); });
    b.finish(2s);
    other.join();
}

// The end-of-run report is the run's bookkeeping: it crosses an emulated link without its
// latency and bandwidth (after what the pair sent before it), and leaves the link free for what
// follows. At 40 kb/s its 50 000 bytes would take 10 s; the end-of-run limit is 5 s by default.
TEST(EmulatedLinkTransport, TheEndOfRunReportCrossesWithoutTheLinksDelay) {
    InProcessHub hub(2);
    const LinkSpec spec = parseLinkSpec("100:0.04");  // 100 ms, 40 kb/s: 5 000 bytes a second
    EmulatedLink a(hub.connect(0), spec), b(hub.connect(1), spec);
    const auto start = std::chrono::steady_clock::now();
    a.send(1, MessageKind::Delta, {1, 2, 3});
    a.send(1, MessageKind::Report, std::vector<uint8_t>(50000, 4));
    EXPECT_EQ(b.receive(0, MessageKind::Delta, 5s), (std::vector<uint8_t>{1, 2, 3}));
    EXPECT_GE(std::chrono::steady_clock::now() - start, 99ms) << "the delta did not wait for the link";
    EXPECT_EQ(b.receive(0, MessageKind::Report, 5s), std::vector<uint8_t>(50000, 4));
    EXPECT_LT(std::chrono::steady_clock::now() - start, 3s) << "the report paid the link's bandwidth";
    // The link is as free as the delta left it: a camera sent now waits only its own bytes.
    const auto camera = std::chrono::steady_clock::now();
    a.send(1, MessageKind::Camera, {9});
    EXPECT_EQ(b.receive(0, MessageKind::Camera, 5s), (std::vector<uint8_t>{9}));
    EXPECT_GE(std::chrono::steady_clock::now() - camera, 99ms);
    EXPECT_LT(std::chrono::steady_clock::now() - camera, 3s) << "the report took up the link";
    std::thread other([&] { a.finish(2s); });
    b.finish(2s);
    other.join();
}

TEST(EmulatedLinkTransport, LinkSpecsParseOrSayWhichPartIsWrong) {
    const LinkSpec s = parseLinkSpec("20:100:2");
    EXPECT_DOUBLE_EQ(s.latency_ms, 20.0);
    EXPECT_DOUBLE_EQ(s.mbps, 100.0);
    EXPECT_DOUBLE_EQ(s.jitter_ms, 2.0);
    EXPECT_EQ(s.describe(), "20 ms, 100 Mb/s, jitter 2 ms");
    EXPECT_EQ(parseLinkSpec("0.2:10000").describe(), "0.2 ms, 10 Gb/s");
    EXPECT_EQ(parseLinkSpec("1").describe(), "1 ms, unlimited");
    EXPECT_FALSE(parseLinkSpec("0").active());
    for (const char* bad : {"", "x", "-1", "1:0", "1:-5", "1:100:-1", "1:100:2:3", "1::2", "nan", "inf", "1:1e400"})
        EXPECT_THROW(parseLinkSpec(bad), std::invalid_argument) << bad;
    try {
        parseLinkSpec("5:fast");
        FAIL();
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("bandwidth (Mb/s) 'fast'"), std::string::npos) << e.what();
    }
}

// Jitter is seeded: the same seed delays the same messages alike, and never reorders a pair.
TEST(EmulatedLinkTransport, JitterKeepsTheOrderOfAPair) {
    InProcessHub hub(2);
    LinkSpec spec = parseLinkSpec("1:1000:5");
    EmulatedLink a(hub.connect(0), spec), b(hub.connect(1), spec);
    for (uint8_t i = 0; i < 20; ++i) a.send(1, MessageKind::Delta, {i});
    for (uint8_t i = 0; i < 20; ++i) EXPECT_EQ(b.receive(0, MessageKind::Delta, 2s), (std::vector<uint8_t>{i}));
    std::thread other([&] { a.finish(2s); });
    b.finish(2s);
    other.join();
}

// Links per pair from a file: each rank gets its own row, both directions of a pair alike, the
// fallback elsewhere; malformed files name the file and the line.
TEST(EmulatedLinkTransport, LinkFilesGiveEachPairItsLink) {
    const std::string path = testing::TempDir() + "occ_links.txt";
    const auto write = [&](const std::string& text) {
        std::ofstream(path, std::ios::trunc) << text;
    };
    write("# display <-> switch slow\n0 1 10:100\n0 2 10:100  # both cullers\n\n1 2 0.05:10000\n");
    const LinkSpec fallback = parseLinkSpec("1");
    const std::vector<LinkSpec> from0 = readLinkFile(path, 0, 4, fallback), from2 = readLinkFile(path, 2, 4, fallback);
    ASSERT_EQ(from0.size(), 4u);
    EXPECT_EQ(from0[1].describe(), "10 ms, 100 Mb/s");
    EXPECT_EQ(from0[2].describe(), "10 ms, 100 Mb/s");
    EXPECT_EQ(from0[3].describe(), "1 ms, unlimited");  // not listed: the fallback
    EXPECT_EQ(from2[0].describe(), "10 ms, 100 Mb/s");
    EXPECT_EQ(from2[1].describe(), "0.05 ms, 10 Gb/s");
    for (const char* bad : {"0 1\n", "0 1 5 extra\n", "0 7 1\n", "x 1 1\n", "1 1 1\n", "0 1 1\n1 0 2\n", "0 1 fast\n"}) {
        write(bad);
        try {
            readLinkFile(path, 0, 3, fallback);
            ADD_FAILURE() << "accepted: " << bad;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("line "), std::string::npos) << e.what();
        }
    }
    EXPECT_THROW(readLinkFile(path + ".missing", 0, 3, fallback), InputError);
    // Per destination: rank 0's message to rank 1 waits for its 40 ms link, to rank 2 not.
    write("0 1 40\n");
    InProcessHub hub(3);
    EmulatedLink a(hub.connect(0), readLinkFile(path, 0, 3, LinkSpec{})), b(hub.connect(1), readLinkFile(path, 1, 3, LinkSpec{})),
        c(hub.connect(2), readLinkFile(path, 2, 3, LinkSpec{}));
    const auto start = std::chrono::steady_clock::now();
    a.send(1, MessageKind::Delta, {1});
    a.send(2, MessageKind::Delta, {2});
    EXPECT_EQ(c.receive(0, MessageKind::Delta, 2s), (std::vector<uint8_t>{2}));
    EXPECT_FALSE(b.poll(0, MessageKind::Delta));
    EXPECT_EQ(b.receive(0, MessageKind::Delta, 2s), (std::vector<uint8_t>{1}));
    EXPECT_GE(std::chrono::steady_clock::now() - start, 40ms);
    std::thread t1([&] { b.finish(2s); }), t2([&] { c.finish(2s); });
    a.finish(2s);
    t1.join();
    t2.join();
}

}  // namespace
}  // namespace occ
