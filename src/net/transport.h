// SPDX-License-Identifier: MIT
#pragma once

// How ranks move message bytes (src/net/messages.h) between each other: an abstract Transport,
// the in-process one here (ranks are threads of one process, or one rank talking to itself)
// and the MPI one in net/mpi_transport.h. docs/protocol.md describes the rules both follow.

#include "net/messages.h"
#include "net/rank_error.h"

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace occ {

// What one rank sent and received of one message kind, cumulative since the transport began.
struct KindCounters {
    uint64_t bytes_sent = 0;
    uint64_t messages_sent = 0;
    uint64_t bytes_received = 0;
    uint64_t messages_received = 0;
    int64_t receive_wait_ns = 0;  // time spent blocked in receive() for this kind
};

// One pixel of a sort-last (depth) composite: the depth buffer's value (0 near .. 1 far), the
// object drawn there (id + 1, 0 = background) and its colour (R | G << 8 | B << 16).
// Compositing keeps per pixel the nearer fragment, and of equal depths the lower object's: what
// one display drawing every object in ascending id order with GL_LESS keeps. An order, so the
// result is the same whatever order the images meet in.
struct DepthPixel {
    float depth = 1.0f;
    uint32_t item = 0;
    uint32_t rgb = 0;
};
static_assert(sizeof(DepthPixel) == 12);
inline bool nearer(const DepthPixel& a, const DepthPixel& b) {
    if (a.depth != b.depth) return a.depth < b.depth;
    return a.item != b.item ? a.item < b.item : a.rgb < b.rgb;
}

// Counters of one rank: per message kind, plus the transport's own control traffic (fault
// notices, roll calls, the end-of-run handshake), which no frame message pays for. A per-frame
// figure is the difference of two snapshots.
struct TransportCounters {
    std::array<KindCounters, kMessageKindCount> kinds{};
    uint64_t control_bytes_sent = 0;
    uint64_t control_messages_sent = 0;
    uint64_t composite_bytes_sent = 0;  // pixels this rank sent for composite()
    int64_t composite_ns = 0;           // time spent in composite()

    KindCounters& operator[](MessageKind kind) { return kinds[size_t(kind) - 1]; }
    const KindCounters& operator[](MessageKind kind) const { return kinds[size_t(kind) - 1]; }
    // Field-by-field this - earlier, for a frame's share of cumulative counters.
    TransportCounters operator-(const TransportCounters& earlier) const;
};

// One rank's end of the message channels between `size()` ranks. Messages of one kind from one
// rank to another arrive complete and in the order they were sent. Not thread-safe: one thread
// per Transport object.
//
// Faults: once a receive() or finish() has thrown RankError, the transport is failed and every
// later call throws the same error again. The other ranks learn of the fault (the failing rank
// notifies them) and throw the same RankError from their next call, so a whole run stops with
// every rank naming the same culprit.
class Transport {
public:
    virtual ~Transport() = default;
    Transport() = default;
    Transport(const Transport&) = delete;
    Transport& operator=(const Transport&) = delete;

    virtual int rank() const = 0;
    virtual int size() const = 0;

    // Queues `bytes` for rank `dest` (0 <= dest < size(), this rank included) and returns at
    // once; the transport owns the bytes until the peer has them. Counted under `kind`.
    // Throws std::invalid_argument for a bad dest, RankError if the run has failed.
    virtual void send(int dest, MessageKind kind, std::vector<uint8_t> bytes) = 0;

    // The next message of `kind` from rank `source`, waiting at most `timeout`. Throws
    // RankError naming the culprit when nothing arrived in time ("rank R: no delta message for
    // 5.0 s: the rank died or stopped answering"), when another rank reported a fault, or when
    // the job is being torn down; std::invalid_argument for a bad source.
    virtual std::vector<uint8_t> receive(int source, MessageKind kind, std::chrono::milliseconds timeout) = 0;

    // Whether receive(source, kind) would return at once, without waiting or taking the message.
    // Throws RankError when another rank reported a fault, as receive() does.
    virtual bool poll(int source, MessageKind kind) = 0;

    // The orderly end of a run, called by every rank after its last send and receive: waits
    // until this rank's sends are delivered and every other rank has called finish(), at most
    // `timeout` in all; throws RankError naming a rank that did not get there. After it returns
    // no call but counters() is allowed; the MPI transport may then finalize MPI.
    virtual void finish(std::chrono::milliseconds timeout) = 0;

    // Tells every other rank that the run failed because of rank `culprit` (this rank's own
    // number for its own errors, e.RankError::rank() for one it caught), so that they stop and
    // report "rank culprit: detail" too. Waits briefly for the notices to leave; never throws.
    // Does nothing if this transport already sent or received a fault notice.
    virtual void fail(int culprit, const std::string& detail) noexcept = 0;

    // Sort-last compositing among the ranks of `group` (ascending, this rank among them; every
    // member calls it with the same group and the same number of pixels, in the same order as
    // its other composite() calls): afterwards group[0]'s `pixels` hold the composite of every
    // member's (DepthPixel's order); the others' are unspecified. A member that does not come
    // within `timeout` is a RankError where the transport can tell (in-process); MPI's
    // collectives cannot time out, and a dead member ends the job through mpirun instead.
    // MPI: MPI_Reduce_scatter_block with a user-defined compositing MPI_Op, then MPI_Gather to
    // group[0], both on a communicator of the group, through host memory. While it waits for
    // the others it calls `idle` (when given) every millisecond or so, e.g. so that a window
    // keeps answering; `idle` must not call this transport.
    virtual void composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels,
                           std::chrono::milliseconds timeout, const std::function<void()>& idle) = 0;

    virtual TransportCounters counters() const { return counters_; }

protected:
    void countSent(MessageKind kind, size_t bytes);
    void countReceived(MessageKind kind, size_t bytes, int64_t wait_ns);
    void countControlSent(size_t bytes);
    void countComposite(size_t bytes, int64_t ns);

private:
    TransportCounters counters_;
};

// Human-readable duration for error messages: "5.0 s", "250 ms".
std::string formatDuration(std::chrono::milliseconds d);

// Ranks as threads of one process (or one rank alone). The hub owns the queues; each rank's
// thread takes its own endpoint with connect(). No MPI involved.
class InProcessHub {
public:
    // Throws std::invalid_argument unless size >= 1.
    explicit InProcessHub(int size);
    ~InProcessHub();
    InProcessHub(const InProcessHub&) = delete;
    InProcessHub& operator=(const InProcessHub&) = delete;

    int size() const;

    // The endpoint of `rank`; each rank can be connected once (std::invalid_argument for a rank
    // outside [0, size) or connected before). Endpoints may outlive the hub. Destroying an
    // endpoint that neither finished nor failed reports a fault naming its rank.
    std::unique_ptr<Transport> connect(int rank);

    struct State;

private:
    std::shared_ptr<State> state_;
};

}  // namespace occ
