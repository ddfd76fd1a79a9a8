// SPDX-License-Identifier: MIT
// Exercises the MPI transport across real ranks, the way the occlusion switch will: every frame
// rank 0 sends a camera packet to every rank, each rank sends its visible-set delta to the next
// rank of a ring (and rebuilds its predecessor's set from the deltas it gets, checking the
// hash), then an end-of-frame to rank 0. One rank can be made to fail at a chosen frame:
//   kill     raise(SIGKILL): the rank dies
//   hang     sleep forever: the rank stops answering
//   garbage  send a delta with one byte changed: the receiver must reject it, naming the rank
// Every healthy rank prints "ok rank R" and exits 0; after a fault every surviving rank prints
// "error: rank C: ..." naming the culprit C and exits 1.
//
//   mpirun -np 3 mpi_fault_probe [--frames N] [--frame-ms M] [--timeout-ms T]
//                                [--fault kill|hang|garbage --fault-rank R --fault-frame K] [--no-deltas]

#include "net/messages.h"
#include "net/mpi_transport.h"
#include "scene/splitmix.h"

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <unistd.h>

namespace {

using namespace occ;
using namespace std::chrono_literals;

struct Options {
    int frames = 60;
    int frame_ms = 10;
    int timeout_ms = 5000;
    std::string fault = "none";
    int fault_rank = 1;
    int fault_frame = 20;
    bool no_deltas = false;
};

Options parse(int argc, char** argv) {
    Options o;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        const auto value = [&]() -> std::string {
            if (i + 1 >= argc) throw UsageError(a + " needs a value");
            return argv[++i];
        };
        if (a == "--frames") o.frames = std::stoi(value());
        else if (a == "--frame-ms") o.frame_ms = std::stoi(value());
        else if (a == "--timeout-ms") o.timeout_ms = std::stoi(value());
        else if (a == "--fault") o.fault = value();
        else if (a == "--fault-rank") o.fault_rank = std::stoi(value());
        else if (a == "--fault-frame") o.fault_frame = std::stoi(value());
        else if (a == "--no-deltas") o.no_deltas = true;
        else throw UsageError("unknown option " + a);
    }
    if (o.fault != "none" && o.fault != "kill" && o.fault != "hang" && o.fault != "garbage")
        throw UsageError("--fault must be none, kill, hang or garbage");
    return o;
}

constexpr uint32_t kObjects = 20000;

// A rank's visible set at a frame: a band of ids that drifts with the frame, so consecutive
// sets share most ids, as along a camera path.
VisibleSet visibleSetOf(int rank, uint64_t frame) {
    SplitMix64 rng(uint64_t(rank) * 1000003u + frame);
    std::vector<VisibleSet::Entry> entries;
    const uint32_t first = uint32_t((frame * 8 + uint64_t(rank) * 5000) % (kObjects - 4000));
    for (uint32_t id = first; id < first + 4000; id += 2)
        entries.push_back({id, 100 + id % 50 + ((id + frame) % 64 == 0 ? uint32_t(frame) : 0u)});
    entries.push_back({kObjects - 1 - uint32_t(rng.next() % 10), 7});
    return VisibleSet(std::move(entries));
}

CameraPacket cameraOf(uint64_t frame) {
    CameraPacket p;
    p.frame = frame;
    const float t = float(frame) * 0.05f;
    p.pose.eye = {10.0f * std::cos(t), 2.0f, 10.0f * std::sin(t)};
    p.pose.target = {0.0f, 0.0f, 0.0f};
    p.sent_ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                    std::chrono::steady_clock::now().time_since_epoch())
                    .count();
    return p;
}

int run(MpiTransport& t, const Options& o) {
    const int rank = t.rank(), size = t.size();
    const int next = (rank + 1) % size, prev = (rank + size - 1) % size;
    const auto timeout = std::chrono::milliseconds(o.timeout_ms);
    VisibleSet mine, theirs;
    uint64_t delta_bytes = 0, full_pvs_bytes = 0;
    for (int f = 0; f < o.frames; ++f) {
        const uint64_t frame = uint64_t(f);
        const auto frame_start = std::chrono::steady_clock::now();
        if (rank == o.fault_rank && f == o.fault_frame) {
            if (o.fault == "kill") std::raise(SIGKILL);
            if (o.fault == "hang")
                for (;;) ::pause();
        }
        if (rank == 0)
            for (int p = 0; p < size; ++p) t.send(p, MessageKind::Camera, encodeCameraPacket(cameraOf(frame), 0));
        const CameraPacket camera = decodeCameraPacket(t.receive(0, MessageKind::Camera, timeout), {0, frame, kObjects});
        if (camera.pose.eye != cameraOf(frame).pose.eye) throw RankError(0, "camera packet changed in transit");

        const VisibleSet current = visibleSetOf(rank, frame);
        const VisibleSetDelta delta =
            (f == 0 || o.no_deltas) ? makeFullDelta(current, frame) : makeDelta(mine, current, frame);
        std::vector<uint8_t> bytes = encodeVisibleSetDelta(delta, kObjects, rank);
        if (o.fault == "garbage" && rank == o.fault_rank && f == o.fault_frame) bytes[bytes.size() / 2] ^= 0x10;
        delta_bytes += bytes.size();
        full_pvs_bytes += fullVisibleSetEncodedSize(current.size());
        t.send(next, MessageKind::Delta, std::move(bytes));
        mine = current;
        // The work of a frame, while the delta travels.
        std::this_thread::sleep_for(std::chrono::milliseconds(o.frame_ms));
        theirs.apply(decodeVisibleSetDelta(t.receive(prev, MessageKind::Delta, timeout), {prev, frame, kObjects}), prev);

        const int64_t compute_ns =
            std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - frame_start).count();
        t.send(0, MessageKind::EndOfFrame, encodeEndOfFrame({frame, compute_ns, uint32_t(mine.size()), f + 1 == o.frames}, rank));
        if (rank == 0)
            for (int p = 0; p < size; ++p) {
                const EndOfFrame eof =
                    decodeEndOfFrame(t.receive(p, MessageKind::EndOfFrame, timeout), {p, frame, kObjects});
                if (eof.last != (f + 1 == o.frames)) throw RankError(p, "end-of-frame 'last' flag is wrong");
            }
    }
    t.finish(timeout);
    const TransportCounters c = t.counters();
    std::printf("ok rank %d: %d frames, sent camera %llu B, delta %llu B in %llu msgs (full PVS would be %llu B), "
                "eof %llu B, control %llu B\n",
                rank, o.frames, (unsigned long long)c[MessageKind::Camera].bytes_sent,
                (unsigned long long)c[MessageKind::Delta].bytes_sent,
                (unsigned long long)c[MessageKind::Delta].messages_sent, (unsigned long long)full_pvs_bytes,
                (unsigned long long)c[MessageKind::EndOfFrame].bytes_sent, (unsigned long long)c.control_bytes_sent);
    if (delta_bytes != c[MessageKind::Delta].bytes_sent) throw std::logic_error("delta byte counter is off");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    Options options;
    try {
        options = parse(argc, argv);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    }
    occ::MpiTransport transport(&argc, &argv);
    try {
        return run(transport, options);
    } catch (const occ::RankError& e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        transport.fail(e.rank(), e.detail());
    } catch (const std::exception& e) {
        std::fprintf(stderr, "error: rank %d: %s\n", transport.rank(), e.what());
        transport.fail(transport.rank(), e.what());
    }
    std::fflush(stderr);
    return 1;
}
