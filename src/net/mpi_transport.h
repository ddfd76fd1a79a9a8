// SPDX-License-Identifier: MIT
#pragma once

// The transport between MPI ranks (built with OCC_MPI). Sends are MPI_Isend, receives are
// MPI_Improbe + MPI_Imrecv polled with MPI_Test against a deadline, on a duplicate of
// MPI_COMM_WORLD whose error handler is MPI_ERRORS_RETURN: a failed MPI call or a silent peer
// becomes a RankError naming the peer, never an abort or a hang. docs/protocol.md, section
// "Faults", says how mpirun must be started for the fault guarantees to hold.

#include "net/transport.h"

#include <chrono>
#include <memory>

namespace occ {

struct MpiTransportOptions {
    // How long a rank that suspects a fault (a receive timed out, or mpirun sent SIGTERM) waits
    // for the other ranks to answer its roll call; a rank that does not answer is named as the
    // culprit. Ranks answer from inside any transport call, so this bounds how long a healthy
    // rank may compute between two calls without being taken for dead during a fault (twice
    // this when several ranks are silent at first: see rollCall).
    std::chrono::milliseconds roll_call{500};
    // How long a failing rank waits for its fault notices to leave before it gives up on them.
    std::chrono::milliseconds notice_grace{500};
};

class MpiTransport final : public Transport {
public:
    // Initializes MPI unless it already is (and then finalizes it in the destructor), duplicates
    // MPI_COMM_WORLD with MPI_ERRORS_RETURN and installs a SIGTERM handler, so that a rank
    // mpirun is tearing down reports which rank failed instead of dying silently. One per
    // process (std::logic_error for a second); throws RankError if an MPI call fails.
    MpiTransport(int* argc, char*** argv, MpiTransportOptions options = {});

    // After finish(): MPI_Finalize (when the constructor initialized MPI). Otherwise the run
    // failed: reports a fault naming this rank unless one is known already, and leaves MPI
    // unfinalized, since MPI_Finalize would wait for ranks that may be dead; the process is
    // expected to exit with a non-zero status right after (mpirun then ends the job).
    ~MpiTransport() override;

    int rank() const override;
    int size() const override;
    void send(int dest, MessageKind kind, std::vector<uint8_t> bytes) override;
    std::vector<uint8_t> receive(int source, MessageKind kind, std::chrono::milliseconds timeout) override;
    bool poll(int source, MessageKind kind) override;
    void composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels,
                   std::chrono::milliseconds timeout, const std::function<void()>& idle) override;
    void finish(std::chrono::milliseconds timeout) override;
    void fail(int culprit, const std::string& detail) noexcept override;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace occ
