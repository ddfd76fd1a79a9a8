// SPDX-License-Identifier: MIT
#pragma once
// Emulated links between ranks (issue 17): a Transport that delays every message another one
// carries as a network link would, so that latency and bandwidth experiments run on one machine
// (shared memory or loopback TCP) as over 100 Mb/s Ethernet, a cluster link or a WAN hop. This
// kernel has no netem qdisc; the shaping is the transport's own.
//
// Per destination the sender keeps the link's queue: a message of s bytes departs when the link
// is free (after the messages before it) and takes s x 8 / bandwidth to go out, then `latency`
// (+ a seeded jitter in [0, jitter]) to arrive. The sender stamps the arrival time (system
// clock, ns) in front of the bytes; the receiver does not hand the message over before it:
// receive() waits, poll() says no. Arrivals to one destination never go backwards, so the
// order per pair is kept. The end-of-run report (MessageKind::Report) is the run's bookkeeping,
// not frame traffic: it crosses without the link's latency and bandwidth (only after what the
// pair sent before it), so that a narrow link's run still ends within the ranks' end-of-run
// limit instead of spending minutes shipping its stats rows. Ranks on one host share the clock; across hosts the emulation is as
// good as their clocks' agreement (NTP: about a millisecond).
//
// Counters are the inner transport's with the stamps taken out, and the time waited for the
// link added to the receiving kind's wait. composite() (sort-last pixels) waits, after the
// inner collective, the latency plus this rank's pixel bytes at the bandwidth: one hop.

#include "net/transport.h"

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <random>
#include <string>

namespace occ {

struct LinkSpec {
    double latency_ms = 0.0;
    double mbps = 0.0;  // megabits per second; 0: no bandwidth limit
    double jitter_ms = 0.0;
    uint64_t seed = 1;

    bool active() const { return latency_ms > 0.0 || mbps > 0.0 || jitter_ms > 0.0; }
    // "1 ms, 100 Mb/s, jitter 0.2 ms" or "none".
    std::string describe() const;
};

// Parses LATENCY_MS[:MBPS[:JITTER_MS]], e.g. "1", "0.2:1000", "20:100:2"; throws
// std::invalid_argument naming the part that is not a finite number >= 0 (bandwidth > 0).
LinkSpec parseLinkSpec(const std::string& text);

// Links per pair of ranks, from a small text file: one pair per line, "RANK RANK SPEC" (SPEC as
// parseLinkSpec takes it), both directions; '#' starts a comment. Pairs not listed get
// `fallback`. Returns the link from `rank` to each of `size` ranks. Throws InputError(path,
// "line N: ...") for an unreadable file, a malformed line, a rank outside [0, size), a rank paired
// with itself or a pair listed twice.
std::vector<LinkSpec> readLinkFile(const std::string& path, int rank, int size, const LinkSpec& fallback);
// The same for every rank at once: table[a][b] is the link from a to b (the file read once).
std::vector<std::vector<LinkSpec>> readLinkTable(const std::string& path, int size, const LinkSpec& fallback);

class EmulatedLink final : public Transport {
public:
    EmulatedLink(std::unique_ptr<Transport> inner, const LinkSpec& link);
    // One link per destination (to_rank[d], this rank's own entry unused).
    EmulatedLink(std::unique_ptr<Transport> inner, std::vector<LinkSpec> to_rank);

    int rank() const override { return inner_->rank(); }
    int size() const override { return inner_->size(); }
    void send(int dest, MessageKind kind, std::vector<uint8_t> bytes) override;
    std::vector<uint8_t> receive(int source, MessageKind kind, std::chrono::milliseconds timeout) override;
    bool poll(int source, MessageKind kind) override;
    void finish(std::chrono::milliseconds timeout) override;
    void fail(int culprit, const std::string& detail) noexcept override;
    void composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels, std::chrono::milliseconds timeout,
                   const std::function<void()>& idle) override;
    TransportCounters counters() const override;

    const LinkSpec& link(int dest) const { return to_rank_[size_t(dest)]; }

private:
    struct Held {
        int64_t arrival_ns = 0;
        std::vector<uint8_t> bytes;
    };
    // Takes one message of (source, kind) from the inner transport, stamp removed, into held_.
    void take(int source, MessageKind kind, std::chrono::milliseconds timeout);

    std::unique_ptr<Transport> inner_;
    std::vector<LinkSpec> to_rank_;
    std::mt19937_64 jitter_rng_;
    std::vector<int64_t> link_free_ns_;      // per destination: when its link is idle again
    std::vector<int64_t> last_arrival_ns_;   // per destination: the latest arrival stamped
    std::map<std::pair<int, MessageKind>, std::deque<Held>> held_;
    TransportCounters adjust_;               // stamps out, link waits in
};

}  // namespace occ
