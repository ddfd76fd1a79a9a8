// SPDX-License-Identifier: MIT
#include "net/transport.h"

#include <algorithm>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <tuple>

namespace occ {

TransportCounters TransportCounters::operator-(const TransportCounters& earlier) const {
    TransportCounters d;
    for (size_t i = 0; i < kinds.size(); ++i) {
        d.kinds[i].bytes_sent = kinds[i].bytes_sent - earlier.kinds[i].bytes_sent;
        d.kinds[i].messages_sent = kinds[i].messages_sent - earlier.kinds[i].messages_sent;
        d.kinds[i].bytes_received = kinds[i].bytes_received - earlier.kinds[i].bytes_received;
        d.kinds[i].messages_received = kinds[i].messages_received - earlier.kinds[i].messages_received;
        d.kinds[i].receive_wait_ns = kinds[i].receive_wait_ns - earlier.kinds[i].receive_wait_ns;
    }
    d.control_bytes_sent = control_bytes_sent - earlier.control_bytes_sent;
    d.control_messages_sent = control_messages_sent - earlier.control_messages_sent;
    d.composite_bytes_sent = composite_bytes_sent - earlier.composite_bytes_sent;
    d.composite_ns = composite_ns - earlier.composite_ns;
    return d;
}

void Transport::countSent(MessageKind kind, size_t bytes) {
    counters_[kind].bytes_sent += bytes;
    counters_[kind].messages_sent += 1;
}

void Transport::countReceived(MessageKind kind, size_t bytes, int64_t wait_ns) {
    counters_[kind].bytes_received += bytes;
    counters_[kind].messages_received += 1;
    counters_[kind].receive_wait_ns += wait_ns;
}

void Transport::countComposite(size_t bytes, int64_t ns) {
    counters_.composite_bytes_sent += bytes;
    counters_.composite_ns += ns;
}

void Transport::countControlSent(size_t bytes) {
    counters_.control_bytes_sent += bytes;
    counters_.control_messages_sent += 1;
}

std::string formatDuration(std::chrono::milliseconds d) {
    char buf[32];
    if (d.count() >= 1000)
        std::snprintf(buf, sizeof buf, "%.1f s", double(d.count()) / 1000.0);
    else
        std::snprintf(buf, sizeof buf, "%lld ms", static_cast<long long>(d.count()));
    return buf;
}

// All endpoints share one lock: the in-process transport serves tests and the one-rank run,
// where contention is not the bottleneck.
struct InProcessHub::State {
    struct Fault {
        int culprit;
        std::string detail;
        int reporter;
    };

    explicit State(int n) : size(n), connected(size_t(n), false), finished(size_t(n), false) {}

    const int size;
    std::mutex mutex;
    std::condition_variable changed;
    std::map<std::tuple<int, int, MessageKind>, std::deque<std::vector<uint8_t>>> queues;  // (dest, source, kind)
    // composite(): images handed to a group's first rank, (dest, source) -> images in call order.
    std::map<std::pair<int, int>, std::deque<std::vector<DepthPixel>>> images;
    std::vector<bool> connected;
    std::vector<bool> finished;
    std::optional<Fault> fault;  // the first fault reported wins

    // Throws the recorded fault as `self` sees it.
    [[noreturn]] void throwFault(int self) const {
        const std::string suffix = fault->reporter == self || fault->reporter == fault->culprit
                                       ? ""
                                       : " (reported by rank " + std::to_string(fault->reporter) + ")";
        throw RankError(fault->culprit, fault->detail + suffix);
    }

    // Records a fault unless one is already known; then throws the recorded one.
    [[noreturn]] void raise(int self, int culprit, const std::string& detail) {
        if (!fault) fault = Fault{culprit, detail, self};
        changed.notify_all();
        throwFault(self);
    }
};

namespace {

class InProcessTransport final : public Transport {
public:
    InProcessTransport(std::shared_ptr<InProcessHub::State> state, int rank) : state_(std::move(state)), rank_(rank) {}

    ~InProcessTransport() override {
        bool done;
        {
            std::lock_guard lock(state_->mutex);
            done = state_->finished[size_t(rank_)];
        }
        if (!done) fail(rank_, "stopped without finishing the run");
    }

    int rank() const override { return rank_; }
    int size() const override { return state_->size; }

    void send(int dest, MessageKind kind, std::vector<uint8_t> bytes) override {
        checkPeer(dest, "send");
        const size_t n = bytes.size();
        {
            std::lock_guard lock(state_->mutex);
            if (state_->fault) state_->throwFault(rank_);
            state_->queues[{dest, rank_, kind}].push_back(std::move(bytes));
        }
        state_->changed.notify_all();
        countSent(kind, n);
    }

    std::vector<uint8_t> receive(int source, MessageKind kind, std::chrono::milliseconds timeout) override {
        checkPeer(source, "receive");
        const auto start = std::chrono::steady_clock::now();
        std::unique_lock lock(state_->mutex);
        auto& queue = state_->queues[{rank_, source, kind}];
        const bool arrived = state_->changed.wait_until(lock, start + timeout,
                                                        [&] { return state_->fault || !queue.empty(); });
        if (state_->fault) state_->throwFault(rank_);
        if (!arrived)
            state_->raise(rank_, source,
                          std::string("no ") + messageKindName(kind) + " message for " + formatDuration(timeout) +
                              ": the rank died or stopped answering");
        std::vector<uint8_t> bytes = std::move(queue.front());
        queue.pop_front();
        lock.unlock();
        countReceived(kind, bytes.size(),
                      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start)
                          .count());
        return bytes;
    }

    bool poll(int source, MessageKind kind) override {
        checkPeer(source, "poll");
        std::lock_guard lock(state_->mutex);
        if (state_->fault) state_->throwFault(rank_);
        const auto it = state_->queues.find({rank_, source, kind});
        return it != state_->queues.end() && !it->second.empty();
    }

    // The group's first rank gathers every member's image and composes them; the others hand
    // theirs over (threads of one process: no bytes need to move twice).
    void composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels,
                   std::chrono::milliseconds timeout, const std::function<void()>& idle) override {
        const auto start = std::chrono::steady_clock::now();
        checkGroup(group);
        const int root = group.front();
        if (rank_ != root) {
            const size_t n = pixels.size() * sizeof(DepthPixel);
            {
                std::lock_guard lock(state_->mutex);
                if (state_->fault) state_->throwFault(rank_);
                state_->images[{root, rank_}].push_back(pixels);
            }
            state_->changed.notify_all();
            countComposite(n, std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start).count());
            return;
        }
        for (size_t m = 1; m < group.size(); ++m) {
            std::unique_lock lock(state_->mutex);
            auto& queue = state_->images[{rank_, group[m]}];
            const auto ready = [&] { return state_->fault || !queue.empty(); };
            const auto deadline = start + timeout;
            bool arrived = false;
            if (!idle) {
                arrived = state_->changed.wait_until(lock, deadline, ready);
            } else {
                // In slices of a millisecond, calling `idle` unlocked in between.
                for (;;) {
                    const auto slice = std::min(deadline, std::chrono::steady_clock::now() + std::chrono::milliseconds(1));
                    arrived = state_->changed.wait_until(lock, slice, ready);
                    if (arrived || std::chrono::steady_clock::now() >= deadline) break;
                    lock.unlock();
                    idle();
                    lock.lock();
                }
            }
            if (state_->fault) state_->throwFault(rank_);
            if (!arrived)
                state_->raise(rank_, group[m], "no image to composite for " + formatDuration(timeout) +
                                                   ": the rank died or stopped answering");
            std::vector<DepthPixel> image = std::move(queue.front());
            queue.pop_front();
            lock.unlock();
            if (image.size() != pixels.size())
                state_->raise(rank_, group[m], "image of " + std::to_string(image.size()) + " pixels to composite, not " +
                                                   std::to_string(pixels.size()));
            for (size_t i = 0; i < pixels.size(); ++i)
                if (nearer(image[i], pixels[i])) pixels[i] = image[i];
        }
        countComposite(0, std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start).count());
    }

    void finish(std::chrono::milliseconds timeout) override {
        const auto deadline = std::chrono::steady_clock::now() + timeout;
        std::unique_lock lock(state_->mutex);
        if (state_->fault) state_->throwFault(rank_);
        state_->finished[size_t(rank_)] = true;
        state_->changed.notify_all();
        const auto all_finished = [&] {
            for (bool f : state_->finished)
                if (!f) return false;
            return true;
        };
        const bool done = state_->changed.wait_until(lock, deadline, [&] { return state_->fault || all_finished(); });
        if (state_->fault) state_->throwFault(rank_);
        if (!done) {
            int late = 0;
            while (state_->finished[size_t(late)]) ++late;
            state_->raise(rank_, late, "did not finish the run within " + formatDuration(timeout));
        }
    }

    void fail(int culprit, const std::string& detail) noexcept override {
        {
            std::lock_guard lock(state_->mutex);
            if (!state_->fault) state_->fault = InProcessHub::State::Fault{culprit, detail, rank_};
        }
        state_->changed.notify_all();
    }

private:
    void checkGroup(const std::vector<int>& group) const {
        if (group.empty() || !std::is_sorted(group.begin(), group.end()) ||
            std::adjacent_find(group.begin(), group.end()) != group.end() ||
            !std::binary_search(group.begin(), group.end(), rank_))
            throw std::invalid_argument("composite: the group must be ascending ranks without repeats, this rank among them");
        for (int r : group) checkPeer(r, "composite");
    }

    void checkPeer(int peer, const char* what) const {
        if (peer < 0 || peer >= state_->size)
            throw std::invalid_argument(std::string(what) + ": rank " + std::to_string(peer) + " outside [0, " +
                                        std::to_string(state_->size) + ")");
    }

    std::shared_ptr<InProcessHub::State> state_;
    int rank_;
};

}  // namespace

InProcessHub::InProcessHub(int size) {
    if (size < 1) throw std::invalid_argument("InProcessHub: size must be >= 1");
    state_ = std::make_shared<State>(size);
}

InProcessHub::~InProcessHub() = default;

int InProcessHub::size() const { return state_->size; }

std::unique_ptr<Transport> InProcessHub::connect(int rank) {
    std::lock_guard lock(state_->mutex);
    if (rank < 0 || rank >= state_->size)
        throw std::invalid_argument("InProcessHub::connect: rank " + std::to_string(rank) + " outside [0, " +
                                    std::to_string(state_->size) + ")");
    if (state_->connected[size_t(rank)])
        throw std::invalid_argument("InProcessHub::connect: rank " + std::to_string(rank) + " is already connected");
    state_->connected[size_t(rank)] = true;
    return std::make_unique<InProcessTransport>(state_, rank);
}

}  // namespace occ
