// SPDX-License-Identifier: MIT
#include "net/mpi_transport.h"

#include <mpi.h>

#include <algorithm>
#include <atomic>
#include <climits>
#include <csignal>
#include <list>
#include <map>
#include <optional>
#include <stdexcept>
#include <thread>

#include <unistd.h>

#include <cstring>
#include <fstream>
#include <sstream>

namespace occ {

namespace {

using Clock = std::chrono::steady_clock;

// Tags of the transport's own control messages; frame messages use their MessageKind value.
constexpr int kTagNotice = 16;  // u32 culprit rank, then the fault's text
constexpr int kTagPing = 17;    // u32 roll-call number
constexpr int kTagPong = 18;    // u32 roll-call number being answered
constexpr int kTagBye = 19;     // empty: the sender reached finish()
constexpr int kTagGroup = 21;   // u32 ranks of a composite group: the sender is ready to make its communicator
// Notices stay far below every BTL's eager limit (vader 4 KiB), so a matched notice is complete
// and MPI_Mrecv on it cannot block.
constexpr size_t kMaxNoticeText = 1000;

volatile std::sig_atomic_t g_sigterm = 0;
std::atomic<bool> g_transport_exists{false};

extern "C" void onSigterm(int) { g_sigterm = 1; }

// The compositing MPI_Op: per pixel the nearer of two DepthPixels (DepthPixel's order, which is
// commutative and associative, so MPI may combine the images in any order).
extern "C" void compositeDepthPixels(void* in, void* inout, int* length, MPI_Datatype*) {
    const auto* a = static_cast<const occ::DepthPixel*>(in);
    auto* b = static_cast<occ::DepthPixel*>(inout);
    for (int i = 0; i < *length; ++i)
        if (occ::nearer(a[i], b[i])) b[i] = a[i];
}

std::string mpiErrorString(int code) {
    char text[MPI_MAX_ERROR_STRING];
    int length = 0;
    if (MPI_Error_string(code, text, &length) != MPI_SUCCESS) return "MPI error " + std::to_string(code);
    return std::string(text, size_t(length));
}

std::vector<uint8_t> u32Bytes(uint32_t v) { return {uint8_t(v), uint8_t(v >> 8), uint8_t(v >> 16), uint8_t(v >> 24)}; }

uint32_t readU32(const std::vector<uint8_t>& b) {
    return uint32_t(b[0]) | uint32_t(b[1]) << 8 | uint32_t(b[2]) << 16 | uint32_t(b[3]) << 24;
}

// Polling without burning a core that another rank on the same machine needs: spin briefly
// (low latency for messages already on their way), then sleep in growing steps.
class Backoff {
public:
    void pause() {
        const auto waited = Clock::now() - start_;
        if (waited < std::chrono::milliseconds(1))
            std::this_thread::yield();
        else if (waited < std::chrono::milliseconds(50))
            std::this_thread::sleep_for(std::chrono::microseconds(50));
        else
            std::this_thread::sleep_for(std::chrono::microseconds(500));
    }

private:
    Clock::time_point start_ = Clock::now();
};

// Where a rank runs: its host and process, to tell a dead or stopped peer on the same machine
// from a slow one (see rollCall). start is the process's start time in clock ticks since boot,
// so a pid reused by another process is not taken for the rank.
struct ProcessId {
    char host[MPI_MAX_PROCESSOR_NAME] = {};
    int64_t pid = 0;
    uint64_t start = 0;
};

enum class PeerState { Unknown, Running, Gone, Stopped };

// The start time (field 22) and state (field 3) of /proc/PID/stat; false when there is none.
bool readProcStat(int64_t pid, char& state, uint64_t& start) {
    std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
    std::string line;
    if (!in || !std::getline(in, line)) return false;
    const size_t close = line.rfind(')');  // the command name may hold spaces and parentheses
    if (close == std::string::npos) return false;
    std::istringstream fields(line.substr(close + 1));
    std::string field;
    for (int i = 3; i <= 22 && fields >> field; ++i) {
        if (i == 3) state = field.empty() ? '?' : field[0];
        if (i == 22) {
            start = std::strtoull(field.c_str(), nullptr, 10);
            return true;
        }
    }
    return false;
}

ProcessId thisProcess() {
    ProcessId id;
    int length = 0;
    if (MPI_Get_processor_name(id.host, &length) != MPI_SUCCESS) id.host[0] = 0;
    id.pid = int64_t(getpid());
    char state = 0;
    readProcStat(id.pid, state, id.start);  // start stays 0 (unknown) when it cannot be read
    return id;
}

// What the operating system says of a peer: only for one on this host whose start time was read.
PeerState peerState(const ProcessId& self, const ProcessId& peer) {
    if (!self.host[0] || std::strncmp(self.host, peer.host, sizeof self.host) != 0 || peer.start == 0)
        return PeerState::Unknown;
    char state = 0;
    uint64_t start = 0;
    if (!readProcStat(peer.pid, state, start) || start != peer.start) return PeerState::Gone;
    if (state == 'Z' || state == 'X') return PeerState::Gone;
    if (state == 'T' || state == 't') return PeerState::Stopped;
    return PeerState::Running;
}

}  // namespace

// Every MPI call goes through this: the call's text, file and line and MPI's own message become
// a fault naming `peer` (the rank the call talks to, or this rank for local calls).
#define OCC_MPI_CHECK(impl, call, peer) (impl).checkMpi((call), #call, __FILE_NAME__, __LINE__, (peer))

struct MpiTransport::Impl {
    struct PendingSend {
        MPI_Request request = MPI_REQUEST_NULL;
        std::vector<uint8_t> bytes;
        int dest = 0;
        int tag = 0;
        Clock::time_point since;
    };

    MpiTransport& self;
    MpiTransportOptions options;
    bool owns_mpi = false;
    MPI_Comm comm = MPI_COMM_NULL;
    int rank = 0;
    int size = 1;
    std::list<PendingSend> sends;  // data and control; a list, so buffers stay put while MPI reads them
    // Receives given up while MPI may still write into them (a fault mid-transfer): the buffers
    // must outlive the requests, and a failed run never finalizes MPI, so they are kept.
    std::list<std::vector<uint8_t>> orphaned_buffers;
    std::optional<RankError> fault;
    bool notice_done = false;  // a fault notice was sent or received
    bool finished = false;
    uint32_t roll_call_number = 0;
    struct sigaction previous_sigterm {};
    std::vector<ProcessId> processes;  // per rank, gathered once at the start
    // composite(): a communicator per group (made on its first use), the pixel type and the op.
    std::map<std::vector<int>, MPI_Comm> group_comms;
    MPI_Datatype pixel_type = MPI_DATATYPE_NULL;
    MPI_Op composite_op = MPI_OP_NULL;
    // Images handed to a nonblocking collective that a fault interrupted: MPI may still use them.
    std::list<std::vector<DepthPixel>> orphaned_images;

    Impl(MpiTransport& owner, MpiTransportOptions opts) : self(owner), options(opts) {}

    void checkMpi(int rc, const char* call, const char* file, int line, int peer) {
        if (rc != MPI_SUCCESS)
            raise(peer, std::string(call) + " failed (" + file + ":" + std::to_string(line) + "): " + mpiErrorString(rc));
    }

    void checkUsable(const char* what) {
        if (fault) throw *fault;
        if (finished) throw std::logic_error(std::string(what) + " after finish()");
    }

    void checkPeer(int peer, const char* what) const {
        if (peer < 0 || peer >= size)
            throw std::invalid_argument(std::string(what) + ": rank " + std::to_string(peer) + " outside [0, " +
                                        std::to_string(size) + ")");
    }

    // Records the fault (the first one wins), tells the other ranks unless they were told, throws.
    [[noreturn]] void raise(int culprit, const std::string& detail) {
        if (!fault) {
            fault = RankError(culprit, detail);
            if (!notice_done) broadcastNotice(culprit, detail);
        }
        throw *fault;
    }

    void postSend(int dest, int tag, std::vector<uint8_t> bytes) {
        PendingSend& s = sends.emplace_back();
        s.bytes = std::move(bytes);
        s.dest = dest;
        s.tag = tag;
        s.since = Clock::now();
        OCC_MPI_CHECK(*this, MPI_Isend(s.bytes.data(), int(s.bytes.size()), MPI_BYTE, dest, tag, comm, &s.request), dest);
    }

    void sendControl(int dest, int tag, std::vector<uint8_t> bytes) {
        self.countControlSent(bytes.size());
        postSend(dest, tag, std::move(bytes));
    }

    // Frees the buffers of completed sends.
    void progressSends() {
        for (auto it = sends.begin(); it != sends.end();) {
            int done = 0;
            OCC_MPI_CHECK(*this, MPI_Test(&it->request, &done, MPI_STATUS_IGNORE), it->dest);
            it = done ? sends.erase(it) : std::next(it);
        }
    }

    // Receives one matched control message, or returns nullopt if none of `tag` from `source`.
    std::optional<std::pair<int, std::vector<uint8_t>>> takeControl(int source, int tag, size_t max_bytes) {
        int flag = 0;
        MPI_Message message;
        MPI_Status status;
        OCC_MPI_CHECK(*this, MPI_Improbe(source, tag, comm, &flag, &message, &status), source == MPI_ANY_SOURCE ? rank : source);
        if (!flag) return std::nullopt;
        int count = 0;
        OCC_MPI_CHECK(*this, MPI_Get_count(&status, MPI_BYTE, &count), status.MPI_SOURCE);
        std::vector<uint8_t> bytes(size_t(std::max(count, 0)));
        OCC_MPI_CHECK(*this, MPI_Mrecv(bytes.data(), count, MPI_BYTE, &message, MPI_STATUS_IGNORE), status.MPI_SOURCE);
        if (bytes.size() > max_bytes)
            raise(status.MPI_SOURCE, "sent a control message (tag " + std::to_string(tag) + ") of " +
                                         std::to_string(bytes.size()) + " bytes");
        return std::make_pair(status.MPI_SOURCE, std::move(bytes));
    }

    // A fault another rank diagnosed: adopt it.
    void takeNotices() {
        auto notice = takeControl(MPI_ANY_SOURCE, kTagNotice, 4 + kMaxNoticeText);
        if (!notice) return;
        const auto& [reporter, bytes] = *notice;
        notice_done = true;
        if (bytes.size() < 4 || readU32(bytes) >= uint32_t(size))
            raise(reporter, "sent a malformed fault notice");
        const int culprit = int(readU32(bytes));
        const std::string text(bytes.begin() + 4, bytes.end());
        raise(culprit, culprit == reporter ? text : text + " (reported by rank " + std::to_string(reporter) + ")");
    }

    void answerPings() {
        while (auto ping = takeControl(MPI_ANY_SOURCE, kTagPing, 4)) {
            if (ping->second.size() != 4) raise(ping->first, "sent a malformed roll call");
            sendControl(ping->first, kTagPong, ping->second);
        }
    }

    // Everything a rank does whenever it is inside the transport: adopt faults others found,
    // answer roll calls, and turn mpirun's SIGTERM into a diagnosis.
    void serviceControl() {
        takeNotices();
        answerPings();
        if (g_sigterm) {
            const std::vector<int> silent = rollCall();
            if (silent.empty())
                raise(rank, "terminated by SIGTERM (mpirun or the user ended the job)");
            std::string detail = "died or stopped answering: mpirun is ending the job and the rank did not answer a "
                                 "roll call within " + formatDuration(options.roll_call);
            for (size_t i = 1; i < silent.size(); ++i)
                detail += (i == 1 ? "; nor did rank " : ", ") + std::to_string(silent[i]);
            raise(silent[0], detail);
        }
        progressSends();
    }

    // Asks every other rank to answer within options.roll_call; returns those that did not,
    // ascending. Ranks answer from inside any transport call (serviceControl), so a silent rank
    // is dead, hung, or computing for longer than the roll-call window. When more than one rank
    // is silent at the window's end, the call listens one window more, until one rank is left:
    // a fault seldom takes two ranks, and a rank that is only slow (a long frame on an
    // oversubscribed or sanitized run; seen: a 5-rank job under ASan named its healthy display
    // rank with the killed one) answers once it is back in the transport, while a dead one never
    // does. Two windows stay within mpirun's default SIGKILL grace of 1 s. Then, for silent ranks
    // on this host, the operating system has the last word: a process gone, a zombie or a
    // stopped one is named first, and silent ranks it shows running are left out (a 5-rank job
    // under ASan in CI had two healthy ranks silent for both windows).
    std::vector<int> rollCall() {
        const uint32_t number = ++roll_call_number;
        std::vector<bool> answered(size_t(size), false);
        answered[size_t(rank)] = true;
        for (int p = 0; p < size; ++p)
            if (p != rank) sendControl(p, kTagPing, u32Bytes(number));
        auto deadline = Clock::now() + options.roll_call;
        bool extended = false;
        Backoff backoff;
        while (std::find(answered.begin(), answered.end(), false) != answered.end()) {
            const auto silent = std::count(answered.begin(), answered.end(), false);
            if (extended && silent < 2) break;
            if (Clock::now() >= deadline) {
                if (extended || silent < 2) break;
                extended = true;
                deadline += options.roll_call;
            }
            takeNotices();
            answerPings();
            while (auto pong = takeControl(MPI_ANY_SOURCE, kTagPong, 4))
                if (pong->second.size() == 4 && readU32(pong->second) == number) answered[size_t(pong->first)] = true;
            progressSends();
            backoff.pause();
        }
        std::vector<int> silent, confirmed, unknown;
        for (int p = 0; p < size; ++p) {
            if (answered[size_t(p)]) continue;
            silent.push_back(p);
            const PeerState state = peerState(processes[size_t(rank)], processes[size_t(p)]);
            if (state == PeerState::Gone || state == PeerState::Stopped)
                confirmed.push_back(p);
            else if (state == PeerState::Unknown)
                unknown.push_back(p);
        }
        // A silent rank that the operating system shows dead or stopped is the culprit; silent
        // ranks it shows running on this host are only slow (or waiting on the culprit).
        if (confirmed.empty()) return silent;
        confirmed.insert(confirmed.end(), unknown.begin(), unknown.end());
        return confirmed;
    }

    // Tells every other rank about the fault and waits up to notice_grace for the notices to
    // leave, answering roll calls meanwhile so that this rank is not taken for the culprit.
    // Never throws: it runs on the way out of an error already.
    void broadcastNotice(int culprit, const std::string& detail) noexcept {
        notice_done = true;
        try {
            std::vector<uint8_t> payload = u32Bytes(uint32_t(culprit));
            payload.insert(payload.end(), detail.begin(), detail.begin() + ptrdiff_t(std::min(detail.size(), kMaxNoticeText)));
            std::vector<MPI_Request*> notices;
            for (int p = 0; p < size; ++p) {
                if (p == rank) continue;
                self.countControlSent(payload.size());
                PendingSend& s = sends.emplace_back();
                s.bytes = payload;
                s.dest = p;
                s.tag = kTagNotice;
                s.since = Clock::now();
                if (MPI_Isend(s.bytes.data(), int(s.bytes.size()), MPI_BYTE, p, kTagNotice, comm, &s.request) != MPI_SUCCESS)
                    continue;
                if (p != culprit) notices.push_back(&s.request);  // a dead culprit never takes it
            }
            const auto deadline = Clock::now() + options.notice_grace;
            Backoff backoff;
            while (Clock::now() < deadline) {
                bool all_done = true;
                for (MPI_Request* r : notices) {
                    int done = 0;
                    if (*r != MPI_REQUEST_NULL && MPI_Test(r, &done, MPI_STATUS_IGNORE) == MPI_SUCCESS && !done)
                        all_done = false;
                }
                if (all_done) break;
                while (true) {  // answer roll calls by hand: answerPings() may throw
                    int flag = 0;
                    MPI_Message message;
                    MPI_Status status;
                    uint8_t number[4];
                    if (MPI_Improbe(MPI_ANY_SOURCE, kTagPing, comm, &flag, &message, &status) != MPI_SUCCESS || !flag)
                        break;
                    int count = 0;
                    MPI_Get_count(&status, MPI_BYTE, &count);
                    if (count != 4 || MPI_Mrecv(number, 4, MPI_BYTE, &message, MPI_STATUS_IGNORE) != MPI_SUCCESS) break;
                    PendingSend& s = sends.emplace_back();
                    s.bytes.assign(number, number + 4);
                    s.dest = status.MPI_SOURCE;
                    s.tag = kTagPong;
                    MPI_Isend(s.bytes.data(), 4, MPI_BYTE, s.dest, kTagPong, comm, &s.request);
                }
                backoff.pause();
            }
        } catch (...) {
            // Out of memory while failing: the other ranks will find out by their own timeouts.
        }
    }

    [[noreturn]] void timeoutFault(int source, MessageKind kind, std::chrono::milliseconds timeout) {
        const std::vector<int> silent = rollCall();
        const std::string waited = std::string("no ") + messageKindName(kind) + " message for " + formatDuration(timeout);
        if (std::find(silent.begin(), silent.end(), source) != silent.end())
            raise(source, waited + ": the rank died or stopped answering");
        if (!silent.empty())
            raise(silent[0], "did not answer a roll call within " + formatDuration(options.roll_call) + " while rank " +
                                 std::to_string(rank) + " had " + waited + " from rank " + std::to_string(source) +
                                 ": the rank died or stopped answering");
        raise(source, "alive but sent " + waited + " (are the ranks waiting for each other?)");
    }
};

MpiTransport::MpiTransport(int* argc, char*** argv, MpiTransportOptions options)
    : impl_(std::make_unique<Impl>(*this, options)) {
    if (g_transport_exists.exchange(true)) throw std::logic_error("MpiTransport: only one per process");
    Impl& m = *impl_;
    int initialized = 0;
    MPI_Initialized(&initialized);
    if (!initialized) {
        if (MPI_Init(argc, argv) != MPI_SUCCESS) throw RankError(0, "MPI_Init failed");
        m.owns_mpi = true;
    }
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &m.rank);
    MPI_Comm_size(MPI_COMM_WORLD, &m.size);
    if (const int rc = MPI_Comm_dup(MPI_COMM_WORLD, &m.comm); rc != MPI_SUCCESS)
        throw RankError(m.rank, "MPI_Comm_dup(MPI_COMM_WORLD) failed: " + mpiErrorString(rc));
    OCC_MPI_CHECK(m, MPI_Comm_set_errhandler(m.comm, MPI_ERRORS_RETURN), m.rank);
    const ProcessId me = thisProcess();
    m.processes.resize(size_t(m.size));
    OCC_MPI_CHECK(m, MPI_Allgather(&me, int(sizeof me), MPI_BYTE, m.processes.data(), int(sizeof me), MPI_BYTE, m.comm), m.rank);
    struct sigaction action {};
    action.sa_handler = onSigterm;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &action, &m.previous_sigterm);
}

MpiTransport::~MpiTransport() {
    Impl& m = *impl_;
    if (m.finished) {
        for (auto& [group, comm] : m.group_comms) MPI_Comm_free(&comm);
        if (m.composite_op != MPI_OP_NULL) MPI_Op_free(&m.composite_op);
        if (m.pixel_type != MPI_DATATYPE_NULL) MPI_Type_free(&m.pixel_type);
        MPI_Comm_free(&m.comm);
        sigaction(SIGTERM, &m.previous_sigterm, nullptr);
        if (m.owns_mpi) MPI_Finalize();
    } else {
        // No MPI_Finalize: it synchronizes with every rank, and one of them may be dead. Keep
        // the SIGTERM handler: mpirun's teardown must not kill this rank before it has exited
        // with its own status. Pending sends keep their buffers (the Impl is leaked on purpose
        // below), since MPI may still read them until the process ends.
        fail(m.rank, "stopped without finishing the run");
        (void)impl_.release();
    }
    g_transport_exists = false;
}

int MpiTransport::rank() const { return impl_->rank; }
int MpiTransport::size() const { return impl_->size; }

void MpiTransport::send(int dest, MessageKind kind, std::vector<uint8_t> bytes) {
    Impl& m = *impl_;
    m.checkUsable("send");
    m.checkPeer(dest, "send");
    if (bytes.size() > size_t(INT_MAX)) throw std::invalid_argument("send: a message larger than 2 GiB");
    m.serviceControl();
    const size_t n = bytes.size();
    m.postSend(dest, int(kind), std::move(bytes));
    countSent(kind, n);
}

std::vector<uint8_t> MpiTransport::receive(int source, MessageKind kind, std::chrono::milliseconds timeout) {
    Impl& m = *impl_;
    m.checkUsable("receive");
    m.checkPeer(source, "receive");
    const auto start = Clock::now();
    const auto deadline = start + timeout;
    std::vector<uint8_t> bytes;
    MPI_Request request = MPI_REQUEST_NULL;
    Backoff backoff;
    try {
        for (;;) {
            m.serviceControl();
            if (request == MPI_REQUEST_NULL) {
                // Matched probe, then receive into a buffer of the matched size: frame messages
                // vary in size, and nothing else can take the matched message meanwhile.
                int flag = 0;
                MPI_Message message;
                MPI_Status status;
                OCC_MPI_CHECK(m, MPI_Improbe(source, int(kind), m.comm, &flag, &message, &status), source);
                if (flag) {
                    int count = 0;
                    OCC_MPI_CHECK(m, MPI_Get_count(&status, MPI_BYTE, &count), source);
                    bytes.resize(size_t(std::max(count, 0)));
                    OCC_MPI_CHECK(m, MPI_Imrecv(bytes.data(), count, MPI_BYTE, &message, &request), source);
                }
            }
            if (request != MPI_REQUEST_NULL) {
                int done = 0;
                OCC_MPI_CHECK(m, MPI_Test(&request, &done, MPI_STATUS_IGNORE), source);
                if (done) {
                    countReceived(kind, bytes.size(),
                                  std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count());
                    return bytes;
                }
            }
            if (Clock::now() >= deadline) m.timeoutFault(source, kind, timeout);
            backoff.pause();
        }
    } catch (...) {
        if (request != MPI_REQUEST_NULL) m.orphaned_buffers.push_back(std::move(bytes));
        throw;
    }
}

bool MpiTransport::poll(int source, MessageKind kind) {
    Impl& m = *impl_;
    m.checkUsable("poll");
    m.checkPeer(source, "poll");
    m.serviceControl();
    int flag = 0;
    OCC_MPI_CHECK(m, MPI_Iprobe(source, int(kind), m.comm, &flag, MPI_STATUS_IGNORE), source);
    return flag != 0;
}

void MpiTransport::composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels,
                             std::chrono::milliseconds timeout, const std::function<void()>& idle) {
    Impl& m = *impl_;
    m.checkUsable("composite");
    const auto start = Clock::now();
    if (group.empty() || !std::is_sorted(group.begin(), group.end()) ||
        std::adjacent_find(group.begin(), group.end()) != group.end() ||
        !std::binary_search(group.begin(), group.end(), m.rank))
        throw std::invalid_argument("composite: the group must be ascending ranks without repeats, this rank among them");
    for (int r : group) m.checkPeer(r, "composite");
    const int members = int(group.size());
    const int me = int(std::lower_bound(group.begin(), group.end(), m.rank) - group.begin());
    m.serviceControl();
    if (members == 1) return;  // the image is the composite
    if (m.pixel_type == MPI_DATATYPE_NULL) {
        OCC_MPI_CHECK(m, MPI_Type_contiguous(int(sizeof(DepthPixel)), MPI_BYTE, &m.pixel_type), m.rank);
        OCC_MPI_CHECK(m, MPI_Type_commit(&m.pixel_type), m.rank);
        OCC_MPI_CHECK(m, MPI_Op_create(compositeDepthPixels, 1, &m.composite_op), m.rank);
    }
    // Between two polls: the caller's idle work, else the usual backoff.
    const auto pause = [&](Backoff& backoff) {
        if (idle) {
            idle();
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
        } else {
            backoff.pause();
        }
    };
    // A member that never comes (dead, or stopped before its first composite) is a timeout
    // naming it, with a roll call; while waiting, faults reported meanwhile are seen.
    const auto overdue = [&](const char* what, const std::vector<bool>* came) {
        const std::vector<int> silent = m.rollCall();
        int late = me == 0 ? group[1] : group.front();
        if (came)
            for (size_t j = 0; j < group.size(); ++j)
                if (!(*came)[j]) {
                    late = group[j];
                    break;
                }
        for (int p : silent)
            if (std::binary_search(group.begin(), group.end(), p)) {
                late = p;
                break;
            }
        m.raise(late, std::string("composite (") + what + ") not done within " + formatDuration(timeout) +
                          (silent.empty() ? ": a rank of the group did not come" : ": the rank died or stopped answering"));
    };
    auto found = m.group_comms.find(group);
    if (found == m.group_comms.end()) {
        // MPI_Comm_create_group blocks until every member calls it, with no timeout: first each
        // member tells the others it is here (point to point) and waits for all of them.
        std::vector<uint8_t> ready;
        for (int r : group) {
            const std::vector<uint8_t> b = u32Bytes(uint32_t(r));
            ready.insert(ready.end(), b.begin(), b.end());
        }
        for (int r : group)
            if (r != m.rank) m.sendControl(r, kTagGroup, ready);
        std::vector<bool> came(group.size(), false);
        came[size_t(me)] = true;
        Backoff backoff;
        while (std::find(came.begin(), came.end(), false) != came.end()) {
            for (size_t j = 0; j < group.size(); ++j) {
                if (came[j]) continue;
                if (auto message = m.takeControl(group[j], kTagGroup, ready.size())) {
                    if (message->second != ready)
                        m.raise(group[j], "is making another composite group than rank " + std::to_string(m.rank));
                    came[j] = true;
                }
            }
            m.serviceControl();
            if (Clock::now() - start >= timeout) overdue("MPI_Comm_create_group", &came);
            pause(backoff);
        }
        MPI_Comm made = MPI_COMM_NULL;
        // Collective over the group's members only (MPI-3): the other ranks take no part.
        MPI_Group world = MPI_GROUP_NULL, members_group = MPI_GROUP_NULL;
        OCC_MPI_CHECK(m, MPI_Comm_group(m.comm, &world), m.rank);
        OCC_MPI_CHECK(m, MPI_Group_incl(world, members, group.data(), &members_group), m.rank);
        OCC_MPI_CHECK(m, MPI_Comm_create_group(m.comm, members_group, 20, &made), group.front());
        MPI_Group_free(&members_group);
        MPI_Group_free(&world);
        OCC_MPI_CHECK(m, MPI_Comm_set_errhandler(made, MPI_ERRORS_RETURN), m.rank);
        found = m.group_comms.emplace(group, made).first;
    }
    MPI_Comm comm = found->second;
    // Each member ends up with one block of the composite (reduce-scatter), then the first
    // gathers the blocks. Nonblocking, so that a member that never comes is a timeout naming
    // it (a roll call) rather than a hang, and faults reported meanwhile are seen.
    const size_t block = (pixels.size() + size_t(members) - 1) / size_t(members);
    if (block > size_t(INT_MAX)) throw std::invalid_argument("composite: an image too large for one MPI call");
    std::vector<DepthPixel> whole(block * size_t(members));
    std::copy(pixels.begin(), pixels.end(), whole.begin());
    std::vector<DepthPixel> mine(block);
    const auto wait = [&](MPI_Request& request, const char* what) {
        Backoff backoff;
        for (;;) {
            int done = 0;
            OCC_MPI_CHECK(m, MPI_Test(&request, &done, MPI_STATUS_IGNORE), group.front());
            if (done) return;
            m.serviceControl();
            if (Clock::now() - start >= timeout) overdue(what, nullptr);
            pause(backoff);
        }
    };
    try {
        MPI_Request request = MPI_REQUEST_NULL;
        OCC_MPI_CHECK(m, MPI_Ireduce_scatter_block(whole.data(), mine.data(), int(block), m.pixel_type, m.composite_op,
                                                   comm, &request),
                      group.front());
        wait(request, "MPI_Ireduce_scatter_block");
        OCC_MPI_CHECK(m, MPI_Igather(mine.data(), int(block), m.pixel_type, me == 0 ? whole.data() : nullptr, int(block),
                                     m.pixel_type, 0, comm, &request),
                      group.front());
        wait(request, "MPI_Igather");
    } catch (...) {
        m.orphaned_images.push_back(std::move(whole));
        m.orphaned_images.push_back(std::move(mine));
        throw;
    }
    if (me == 0) std::copy(whole.begin(), whole.begin() + std::ptrdiff_t(pixels.size()), pixels.begin());
    // What this rank hands on: the other members' blocks of its image, and its block of the
    // composite unless it is the first.
    const uint64_t sent = (uint64_t(members) - 1) * block * sizeof(DepthPixel) + (me == 0 ? 0 : block * sizeof(DepthPixel));
    countComposite(size_t(sent), std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - start).count());
}

void MpiTransport::finish(std::chrono::milliseconds timeout) {
    Impl& m = *impl_;
    m.checkUsable("finish");
    const auto deadline = Clock::now() + timeout;
    Backoff backoff;
    // This rank's frame messages first: a peer that never takes one is the culprit.
    while (!m.sends.empty()) {
        m.serviceControl();
        if (!m.sends.empty() && Clock::now() >= deadline) {
            const Impl::PendingSend& oldest = m.sends.front();
            const std::vector<int> silent = m.rollCall();
            m.raise(oldest.dest, "did not take a message (tag " + std::to_string(oldest.tag) + ") within " +
                                     formatDuration(timeout) + " at the end of the run" +
                                     (std::find(silent.begin(), silent.end(), oldest.dest) != silent.end()
                                          ? ": the rank died or stopped answering"
                                          : ""));
        }
        backoff.pause();
    }
    // Then every rank says it got here, so MPI_Finalize, which waits for all, cannot hang.
    std::vector<bool> arrived(size_t(m.size), false);
    arrived[size_t(m.rank)] = true;
    for (int p = 0; p < m.size; ++p)
        if (p != m.rank) m.sendControl(p, kTagBye, {});
    while (std::find(arrived.begin(), arrived.end(), false) != arrived.end()) {
        m.serviceControl();
        for (int p = 0; p < m.size; ++p)
            if (!arrived[size_t(p)] && m.takeControl(p, kTagBye, 0)) arrived[size_t(p)] = true;
        if (Clock::now() >= deadline && std::find(arrived.begin(), arrived.end(), false) != arrived.end()) {
            const std::vector<int> silent = m.rollCall();
            int late = int(std::find(arrived.begin(), arrived.end(), false) - arrived.begin());
            for (int p : silent)
                if (!arrived[size_t(p)]) {
                    late = p;
                    break;
                }
            m.raise(late, "did not finish the run within " + formatDuration(timeout));
        }
        backoff.pause();
    }
    // The goodbyes and any roll-call answers must leave before MPI_Finalize.
    while (!m.sends.empty() && Clock::now() < deadline + m.options.notice_grace) {
        m.progressSends();
        backoff.pause();
    }
    m.finished = true;
}

void MpiTransport::fail(int culprit, const std::string& detail) noexcept {
    Impl& m = *impl_;
    if (m.fault || m.notice_done) return;
    try {
        m.fault = RankError(culprit, detail);
    } catch (...) {
        return;
    }
    m.broadcastNotice(culprit, detail);
}

}  // namespace occ
