// SPDX-License-Identifier: MIT
#include "net/emulated_link.h"

#include "scene/errors.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace occ {

namespace {

constexpr size_t kStampBytes = sizeof(int64_t);

int64_t nowNs() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
        .count();
}

void sleepUntilNs(int64_t t) {
    const int64_t now = nowNs();
    if (t > now) std::this_thread::sleep_for(std::chrono::nanoseconds(t - now));
}

std::string number(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
}

}  // namespace

std::string LinkSpec::describe() const {
    if (!active()) return "none";
    std::string s = number(latency_ms) + " ms";
    s += mbps > 0 ? ", " + (mbps >= 1000 ? number(mbps / 1000) + " Gb/s" : number(mbps) + " Mb/s") : ", unlimited";
    if (jitter_ms > 0) s += ", jitter " + number(jitter_ms) + " ms";
    return s;
}

LinkSpec parseLinkSpec(const std::string& text) {
    const char* names[] = {"latency (ms)", "bandwidth (Mb/s)", "jitter (ms)"};
    double values[3] = {0, 0, 0};
    size_t start = 0, part = 0;
    for (;;) {
        if (part == 3) throw std::invalid_argument("'" + text + "': at most LATENCY_MS:MBPS:JITTER_MS");
        const size_t colon = text.find(':', start);
        const std::string piece = text.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
        size_t used = 0;
        double v = NAN;
        try {
            v = std::stod(piece, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (piece.empty() || used != piece.size() || !std::isfinite(v) || v < 0 || (part == 1 && v <= 0))
            throw std::invalid_argument("'" + text + "': the " + names[part] + " '" + piece + "' is not a number " +
                                        (part == 1 ? "> 0" : ">= 0"));
        values[part++] = v;
        if (colon == std::string::npos) break;
        start = colon + 1;
    }
    LinkSpec s;
    s.latency_ms = values[0];
    s.mbps = values[1];
    s.jitter_ms = values[2];
    return s;
}

EmulatedLink::EmulatedLink(std::unique_ptr<Transport> inner, const LinkSpec& link)
    : EmulatedLink(std::move(inner), std::vector<LinkSpec>(1, link)) {
    to_rank_.assign(to_rank_.size(), link);
}

EmulatedLink::EmulatedLink(std::unique_ptr<Transport> inner, std::vector<LinkSpec> to_rank)
    : inner_(std::move(inner)),
      to_rank_(std::move(to_rank)),
      jitter_rng_((to_rank_.empty() ? 1 : to_rank_[0].seed) * 0x9E3779B97F4A7C15ull + uint64_t(inner_->rank())),
      link_free_ns_(size_t(inner_->size()), 0),
      last_arrival_ns_(size_t(inner_->size()), 0) {
    to_rank_.resize(size_t(inner_->size()));
}

std::vector<std::vector<LinkSpec>> readLinkTable(const std::string& path, int size, const LinkSpec& fallback) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "cannot read the link file");
    std::vector<std::vector<LinkSpec>> table(size_t(size), std::vector<LinkSpec>(size_t(size), fallback));
    std::set<std::pair<int, int>> seen;
    std::string line;
    for (int number = 1; std::getline(in, line); ++number) {
        const size_t hash = line.find('#');
        if (hash != std::string::npos) line.resize(hash);
        std::istringstream words(line);
        std::string a_text, b_text, spec, extra;
        if (!(words >> a_text)) continue;
        const std::string where = "line " + std::to_string(number) + ": ";
        if (!(words >> b_text >> spec) || (words >> extra))
            throw InputError(path, where + "expected RANK RANK LATENCY_MS[:MBPS[:JITTER_MS]], got '" + line + "'");
        int ab[2];
        const std::string texts[2] = {a_text, b_text};
        for (int i = 0; i < 2; ++i) {
            size_t used = 0;
            try {
                ab[i] = std::stoi(texts[i], &used);
            } catch (const std::exception&) {
                used = 0;
            }
            if (used == 0 || used != texts[i].size() || ab[i] < 0 || ab[i] >= size)
                throw InputError(path, where + "rank '" + texts[i] + "' is not in [0, " + std::to_string(size) + ")");
        }
        if (ab[0] == ab[1]) throw InputError(path, where + "rank " + a_text + " paired with itself");
        if (!seen.insert({std::min(ab[0], ab[1]), std::max(ab[0], ab[1])}).second)
            throw InputError(path, where + "the pair " + a_text + " " + b_text + " is listed twice");
        LinkSpec s;
        try {
            s = parseLinkSpec(spec);
        } catch (const std::invalid_argument& e) {
            throw InputError(path, where + e.what());
        }
        s.seed = fallback.seed;
        table[size_t(ab[0])][size_t(ab[1])] = table[size_t(ab[1])][size_t(ab[0])] = s;
    }
    return table;
}

std::vector<LinkSpec> readLinkFile(const std::string& path, int rank, int size, const LinkSpec& fallback) {
    return readLinkTable(path, size, fallback)[size_t(rank)];
}

void EmulatedLink::send(int dest, MessageKind kind, std::vector<uint8_t> bytes) {
    if (dest < 0 || dest >= size()) {
        inner_->send(dest, kind, std::move(bytes));  // the inner transport names the bad rank
        return;
    }
    const int64_t now = nowNs();
    int64_t arrival = now;
    if (dest != rank() && kind == MessageKind::Report) {
        arrival = std::max(now, last_arrival_ns_[size_t(dest)]);
        last_arrival_ns_[size_t(dest)] = arrival;
    } else if (dest != rank()) {
        const LinkSpec& link_ = to_rank_[size_t(dest)];
        int64_t& free = link_free_ns_[size_t(dest)];
        const double wire_ns = link_.mbps > 0 ? double(bytes.size()) * 8.0 / (link_.mbps * 1e6) * 1e9 : 0.0;
        const int64_t departed = std::max(now, free) + int64_t(wire_ns);
        free = departed;
        double delay_ns = link_.latency_ms * 1e6;
        if (link_.jitter_ms > 0)
            delay_ns += std::uniform_real_distribution<double>(0.0, link_.jitter_ms * 1e6)(jitter_rng_);
        arrival = std::max(departed + int64_t(delay_ns), last_arrival_ns_[size_t(dest)]);
        last_arrival_ns_[size_t(dest)] = arrival;
    }
    std::vector<uint8_t> stamped(kStampBytes + bytes.size());
    std::memcpy(stamped.data(), &arrival, kStampBytes);
    if (!bytes.empty()) std::memcpy(stamped.data() + kStampBytes, bytes.data(), bytes.size());
    inner_->send(dest, kind, std::move(stamped));
    adjust_[kind].bytes_sent += kStampBytes;
}

void EmulatedLink::take(int source, MessageKind kind, std::chrono::milliseconds timeout) {
    std::vector<uint8_t> bytes = inner_->receive(source, kind, timeout);
    if (bytes.size() < kStampBytes)
        throw RankError(source, "a " + std::string(messageKindName(kind)) + " message of " + std::to_string(bytes.size()) +
                                    " bytes lacks the emulated link's arrival stamp (is every rank run with the same --link?)");
    Held h;
    std::memcpy(&h.arrival_ns, bytes.data(), kStampBytes);
    h.bytes.assign(bytes.begin() + kStampBytes, bytes.end());
    adjust_[kind].bytes_received += kStampBytes;
    held_[{source, kind}].push_back(std::move(h));
}

std::vector<uint8_t> EmulatedLink::receive(int source, MessageKind kind, std::chrono::milliseconds timeout) {
    auto& queue = held_[{source, kind}];
    if (queue.empty()) take(source, kind, timeout);
    Held h = std::move(queue.front());
    queue.pop_front();
    const int64_t before = nowNs();
    sleepUntilNs(h.arrival_ns);
    adjust_[kind].receive_wait_ns += std::max<int64_t>(0, nowNs() - before);
    return std::move(h.bytes);
}

bool EmulatedLink::poll(int source, MessageKind kind) {
    auto& queue = held_[{source, kind}];
    while (inner_->poll(source, kind)) take(source, kind, std::chrono::milliseconds(0));
    return !queue.empty() && queue.front().arrival_ns <= nowNs();
}

void EmulatedLink::finish(std::chrono::milliseconds timeout) { inner_->finish(timeout); }

void EmulatedLink::fail(int culprit, const std::string& detail) noexcept { inner_->fail(culprit, detail); }

void EmulatedLink::composite(const std::vector<int>& group, std::vector<DepthPixel>& pixels,
                             std::chrono::milliseconds timeout, const std::function<void()>& idle) {
    const size_t bytes = pixels.size() * sizeof(DepthPixel);
    inner_->composite(group, pixels, timeout, idle);
    // One hop over the slowest of this rank's links to the group.
    const auto hop_ms = [bytes](const LinkSpec& l) {
        return l.latency_ms + (l.mbps > 0 ? double(bytes) * 8.0 / (l.mbps * 1e3) : 0.0);
    };
    double slowest_ms = 0.0;
    for (int g : group)
        if (g != rank() && g >= 0 && g < size()) slowest_ms = std::max(slowest_ms, hop_ms(to_rank_[size_t(g)]));
    const int64_t before = nowNs();
    const int64_t until = before + int64_t(slowest_ms * 1e6);
    while (nowNs() < until) {
        if (idle) idle();
        std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    adjust_.composite_ns += nowNs() - before;
}

TransportCounters EmulatedLink::counters() const {
    TransportCounters c = inner_->counters();
    for (size_t i = 0; i < c.kinds.size(); ++i) {
        c.kinds[i].bytes_sent -= adjust_.kinds[i].bytes_sent;
        c.kinds[i].bytes_received -= adjust_.kinds[i].bytes_received;
        c.kinds[i].receive_wait_ns += adjust_.kinds[i].receive_wait_ns;
    }
    c.composite_ns += adjust_.composite_ns;  // the pixels' time on the link
    return c;
}

}  // namespace occ
