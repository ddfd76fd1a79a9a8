// SPDX-License-Identifier: MIT
#include "net/messages.h"

#include <xxhash.h>

#include <bit>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <new>
#include <stdexcept>
#include <string>

namespace occ {

namespace {

constexpr uint8_t kFlagDeltaFull = 1;
constexpr uint8_t kFlagEndOfFrameLast = 1;
constexpr uint8_t kFlagCameraStop = 1;
constexpr size_t kChecksumOffset = 24;

// Little-endian writer into a buffer sized up front: every field is written byte by byte, so
// the wire format does not depend on struct layout or host byte order.
class ByteWriter {
public:
    explicit ByteWriter(size_t size) : bytes_(size) {}

    void u8(uint8_t v) { bytes_[at_++] = v; }
    void u16(uint16_t v) { put(v, 2); }
    void u32(uint32_t v) { put(v, 4); }
    void u64(uint64_t v) { put(v, 8); }
    void i64(int64_t v) { put(uint64_t(v), 8); }
    void f32(float v) { u32(std::bit_cast<uint32_t>(v)); }
    void vec3(const glm::vec3& v) {
        f32(v.x);
        f32(v.y);
        f32(v.z);
    }
    void f64(double v) { u64(std::bit_cast<uint64_t>(v)); }
    size_t position() const { return at_; }
    std::vector<uint8_t> take() { return std::move(bytes_); }
    std::vector<uint8_t>& bytes() { return bytes_; }

private:
    void put(uint64_t v, int n) {
        for (int i = 0; i < n; ++i) bytes_[at_++] = uint8_t(v >> (8 * i));
    }
    std::vector<uint8_t> bytes_;
    size_t at_ = 0;
};

// Reads little-endian fields at fixed offsets; callers check sizes before reading, and get()
// checks again so that a mistake there is an exception, not a read past the buffer.
class ByteReader {
public:
    explicit ByteReader(std::span<const uint8_t> bytes) : bytes_(bytes) {}

    uint8_t u8(size_t at) const { return uint8_t(get(at, 1)); }
    uint16_t u16(size_t at) const { return uint16_t(get(at, 2)); }
    uint32_t u32(size_t at) const { return uint32_t(get(at, 4)); }
    uint64_t u64(size_t at) const { return get(at, 8); }
    int64_t i64(size_t at) const { return int64_t(get(at, 8)); }
    float f32(size_t at) const { return std::bit_cast<float>(u32(at)); }
    glm::vec3 vec3(size_t at) const { return {f32(at), f32(at + 4), f32(at + 8)}; }
    double f64(size_t at) const { return std::bit_cast<double>(u64(at)); }

private:
    uint64_t get(size_t at, int n) const {
        if (at > bytes_.size() || bytes_.size() - at < size_t(n))
            throw std::logic_error("ByteReader: read past the end of a message (a missing size check)");
        uint64_t v = 0;
        for (int i = 0; i < n; ++i) v |= uint64_t(bytes_[at + i]) << (8 * i);
        return v;
    }
    std::span<const uint8_t> bytes_;
};

// A streaming XXH3-64 state, seed 0. Allocated by the library: the state's layout is only
// public under XXH_STATIC_LINKING_ONLY, which would tie us to one xxHash version's ABI.
class Xxh3State {
public:
    Xxh3State() : state_(XXH3_createState()) {
        if (!state_ || XXH3_64bits_reset(state_) != XXH_OK) throw std::bad_alloc();
    }
    ~Xxh3State() { XXH3_freeState(state_); }
    Xxh3State(const Xxh3State&) = delete;
    Xxh3State& operator=(const Xxh3State&) = delete;
    XXH3_state_t* get() const { return state_; }

private:
    XXH3_state_t* state_;
};

// XXH3-64 of the whole message except the checksum field itself.
uint64_t messageChecksum(std::span<const uint8_t> message) {
    const Xxh3State state;
    XXH3_64bits_update(state.get(), message.data(), kChecksumOffset);
    XXH3_64bits_update(state.get(), message.data() + kMessageHeaderSize, message.size() - kMessageHeaderSize);
    return XXH3_64bits_digest(state.get());
}

ByteWriter startMessage(MessageKind kind, uint8_t flags, int sender, uint64_t frame, size_t payload_size) {
    if (sender < 0) throw std::invalid_argument("encode: negative sender rank");
    if (payload_size > UINT32_MAX) throw std::invalid_argument("encode: payload larger than 4 GiB");
    ByteWriter w(kMessageHeaderSize + payload_size);
    w.u32(kMessageMagic);
    w.u16(kProtocolVersion);
    w.u8(uint8_t(kind));
    w.u8(flags);
    w.u32(uint32_t(sender));
    w.u32(uint32_t(payload_size));
    w.u64(frame);
    w.u64(0);  // checksum, filled by finishMessage once the payload is written
    return w;
}

std::vector<uint8_t> finishMessage(ByteWriter& w) {
    if (w.position() != w.bytes().size()) throw std::logic_error("encode: payload size mismatch");
    const uint64_t sum = messageChecksum(w.bytes());
    for (int i = 0; i < 8; ++i) w.bytes()[kChecksumOffset + i] = uint8_t(sum >> (8 * i));
    return w.take();
}

std::string frameWhat(MessageKind kind, uint64_t frame) {
    return std::string(messageKindName(kind)) + " of frame " + std::to_string(frame);
}

[[noreturn]] void fail(const DecodeContext& ctx, const std::string& detail) { throw RankError(ctx.sender, detail); }

// Checks the header against the buffer and the context; returns (flags, payload span). Every
// check before the checksum names the message by kind only, since its frame is not yet trusted.
std::pair<uint8_t, std::span<const uint8_t>> checkHeader(std::span<const uint8_t> bytes, MessageKind kind,
                                                         const DecodeContext& ctx) {
    const std::string what = std::string(messageKindName(kind)) + " message";
    if (bytes.size() < kMessageHeaderSize)
        fail(ctx, what + " of " + std::to_string(bytes.size()) + " bytes: shorter than the " +
                      std::to_string(kMessageHeaderSize) + "-byte header");
    const ByteReader r(bytes);
    const uint32_t magic = r.u32(0);
    if (magic != kMessageMagic) {
        char hex[16];
        std::snprintf(hex, sizeof hex, "0x%08" PRIx32, magic);
        fail(ctx, what + ": bad magic " + hex + " (not an occswitch message)");
    }
    const uint16_t version = r.u16(4);
    if (version != kProtocolVersion)
        fail(ctx, what + ": protocol version " + std::to_string(version) + ", this build speaks version " +
                      std::to_string(kProtocolVersion) + " (mixed builds?)");
    const uint8_t got_kind = r.u8(6);
    if (got_kind != uint8_t(kind))
        fail(ctx, what + ": header says kind " + std::to_string(got_kind) + " (" +
                      messageKindName(MessageKind(got_kind)) + ")");
    const uint32_t sender = r.u32(8);
    if (ctx.sender < 0 || sender != uint32_t(ctx.sender))
        fail(ctx, what + ": header says it comes from rank " + std::to_string(sender));
    const uint32_t payload_size = r.u32(12);
    if (payload_size != bytes.size() - kMessageHeaderSize)
        fail(ctx, what + ": header says " + std::to_string(payload_size) + " payload bytes, " +
                      std::to_string(bytes.size() - kMessageHeaderSize) + " arrived");
    if (r.u64(kChecksumOffset) != messageChecksum(bytes))
        fail(ctx, what + " of " + std::to_string(bytes.size()) + " bytes: checksum mismatch (corrupted)");
    const uint64_t frame = r.u64(16);
    // A stop packet carries the run's frame count, which is the receiver's next frame or the
    // one before it (the other switch rank culls that one).
    const bool stop_frame = kind == MessageKind::Camera && (r.u8(7) & kFlagCameraStop) && ctx.expected_frame > 0 &&
                            frame + 1 == ctx.expected_frame;
    if (frame != ctx.expected_frame && !stop_frame)
        fail(ctx, frameWhat(kind, frame) + ": expected frame " + std::to_string(ctx.expected_frame) +
                      " (out of order)");
    return {r.u8(7), bytes.subspan(kMessageHeaderSize)};
}

void checkFlags(const DecodeContext& ctx, MessageKind kind, uint64_t frame, uint8_t flags, uint8_t allowed) {
    if (flags & ~allowed) fail(ctx, frameWhat(kind, frame) + ": unknown flags " + std::to_string(flags));
}

// Checks that ids are ascending, unique and < object_count; `name` is the list's name.
template <typename IdAt>
void checkIdList(const DecodeContext& ctx, const std::string& what, const char* name, size_t count, IdAt id_at) {
    for (size_t i = 0; i < count; ++i) {
        const uint32_t id = id_at(i);
        if (id >= ctx.object_count)
            fail(ctx, what + ": " + name + " id " + std::to_string(id) + " >= object count " +
                          std::to_string(ctx.object_count));
        if (i > 0 && id <= id_at(i - 1))
            fail(ctx, what + ": " + name + " ids not ascending (" + std::to_string(id_at(i - 1)) + " then " +
                          std::to_string(id) + ")");
    }
}

// Throws unless `list` is sorted by id with no id twice; `what` names the list for apply().
template <typename List, typename IdOf>
void checkAscending(int sender, const std::string& what, const char* name, const List& list, IdOf id_of) {
    for (size_t i = 1; i < list.size(); ++i)
        if (id_of(list[i]) <= id_of(list[i - 1]))
            throw RankError(sender, what + ": " + name + " ids not ascending (" + std::to_string(id_of(list[i - 1])) +
                                        " then " + std::to_string(id_of(list[i])) + ")");
}

}  // namespace

const char* messageKindName(MessageKind kind) {
    switch (kind) {
    case MessageKind::Camera: return "camera";
    case MessageKind::Delta: return "delta";
    case MessageKind::EndOfFrame: return "eof";
    case MessageKind::Report: return "report";
    }
    return "unknown";
}

VisibleSet::VisibleSet(std::vector<Entry> entries) : entries_(std::move(entries)) {
    for (size_t i = 1; i < entries_.size(); ++i)
        if (entries_[i].first <= entries_[i - 1].first)
            throw std::invalid_argument("VisibleSet: ids must be ascending and unique");
}

uint64_t VisibleSet::hash() const {
    // Entries are hashed through a small buffer of explicit little-endian bytes, so the hash is
    // defined by the wire order of (id, count), not by std::pair's layout.
    const Xxh3State state;
    uint8_t buffer[4096];
    size_t used = 0;
    for (const Entry& e : entries_) {
        for (int i = 0; i < 4; ++i) buffer[used + i] = uint8_t(e.first >> (8 * i));
        for (int i = 0; i < 4; ++i) buffer[used + 4 + i] = uint8_t(e.second >> (8 * i));
        used += 8;
        if (used == sizeof buffer) {
            XXH3_64bits_update(state.get(), buffer, used);
            used = 0;
        }
    }
    XXH3_64bits_update(state.get(), buffer, used);
    return XXH3_64bits_digest(state.get());
}

void VisibleSet::apply(const VisibleSetDelta& delta, int sender) {
    const std::string what = frameWhat(MessageKind::Delta, delta.frame);
    const auto id_of_pair = [](const Entry& e) { return e.first; };
    const auto id_of_id = [](uint32_t id) { return id; };
    checkAscending(sender, what, "added", delta.added, id_of_pair);
    checkAscending(sender, what, "removed", delta.removed, id_of_id);
    checkAscending(sender, what, "changed", delta.changed, id_of_pair);

    std::vector<Entry> next;
    if (delta.full) {
        if (!delta.removed.empty() || !delta.changed.empty())
            throw RankError(sender, what + ": a full set with removed or changed ids");
        next = delta.added;
    } else {
        // One merge over the old set and the three sorted lists: removed and changed ids must
        // meet an old entry, added ids must fall between old ones.
        next.reserve(entries_.size() + delta.added.size());
        size_t a = 0, r = 0, c = 0;
        for (const Entry& old : entries_) {
            while (a < delta.added.size() && delta.added[a].first < old.first) next.push_back(delta.added[a++]);
            if (a < delta.added.size() && delta.added[a].first == old.first)
                throw RankError(sender, what + ": added id " + std::to_string(old.first) + " is already visible");
            if (r < delta.removed.size() && delta.removed[r] < old.first)
                throw RankError(sender, what + ": removed id " + std::to_string(delta.removed[r]) + " is not visible");
            if (c < delta.changed.size() && delta.changed[c].first < old.first)
                throw RankError(sender, what + ": changed id " + std::to_string(delta.changed[c].first) +
                                            " is not visible");
            const bool removed = r < delta.removed.size() && delta.removed[r] == old.first;
            const bool changed = c < delta.changed.size() && delta.changed[c].first == old.first;
            if (removed && changed)
                throw RankError(sender, what + ": id " + std::to_string(old.first) + " both removed and changed");
            if (removed) {
                ++r;
            } else if (changed) {
                next.push_back(delta.changed[c++]);
            } else {
                next.push_back(old);
            }
        }
        if (r < delta.removed.size())
            throw RankError(sender, what + ": removed id " + std::to_string(delta.removed[r]) + " is not visible");
        if (c < delta.changed.size())
            throw RankError(sender, what + ": changed id " + std::to_string(delta.changed[c].first) + " is not visible");
        next.insert(next.end(), delta.added.begin() + ptrdiff_t(a), delta.added.end());
    }

    VisibleSet candidate;
    candidate.entries_ = std::move(next);
    const uint64_t got = candidate.hash();
    if (got != delta.hash) {
        char buf[96];
        std::snprintf(buf, sizeof buf, ": hash of the rebuilt set %016" PRIx64 " != sent %016" PRIx64, got, delta.hash);
        throw RankError(sender, what + buf + " (the ranks' visible sets diverged)");
    }
    entries_ = std::move(candidate.entries_);
}

VisibleSetDelta makeDelta(const VisibleSet& previous, const VisibleSet& current, uint64_t frame) {
    VisibleSetDelta d;
    d.frame = frame;
    const auto& p = previous.entries();
    const auto& q = current.entries();
    size_t i = 0, j = 0;
    while (i < p.size() || j < q.size()) {
        if (j == q.size() || (i < p.size() && p[i].first < q[j].first)) {
            d.removed.push_back(p[i++].first);
        } else if (i == p.size() || q[j].first < p[i].first) {
            d.added.push_back(q[j++]);
        } else {
            if (p[i].second != q[j].second) d.changed.push_back(q[j]);
            ++i;
            ++j;
        }
    }
    d.hash = current.hash();
    return d;
}

VisibleSetDelta makeFullDelta(const VisibleSet& current, uint64_t frame) {
    VisibleSetDelta d;
    d.frame = frame;
    d.full = true;
    d.added = current.entries();
    d.hash = current.hash();
    return d;
}

size_t encodedSize(const VisibleSetDelta& delta) {
    return kMessageHeaderSize + kDeltaPayloadHeaderSize + 8 * delta.added.size() + 4 * delta.removed.size() +
           8 * delta.changed.size();
}

size_t fullVisibleSetEncodedSize(size_t visible_count) {
    return kMessageHeaderSize + kDeltaPayloadHeaderSize + 8 * visible_count;
}

std::vector<uint8_t> encodeCameraPacket(const CameraPacket& packet, int sender) {
    ByteWriter w =
        startMessage(MessageKind::Camera, packet.stop ? kFlagCameraStop : 0, sender, packet.frame, kCameraPayloadSize);
    w.vec3(packet.pose.eye);
    w.vec3(packet.pose.target);
    w.vec3(packet.pose.up);
    w.f32(packet.pose.fovy_degrees);
    w.f32(packet.pose.near_plane);
    w.f32(packet.pose.far_plane);
    w.i64(packet.sent_ns);
    return finishMessage(w);
}

std::vector<uint8_t> encodeVisibleSetDelta(const VisibleSetDelta& delta, uint32_t object_count, int sender) {
    const auto count32 = [](size_t n) {
        if (n > UINT32_MAX) throw std::invalid_argument("encode: a delta list longer than 2^32 - 1");
        return uint32_t(n);
    };
    ByteWriter w = startMessage(MessageKind::Delta, delta.full ? kFlagDeltaFull : 0, sender, delta.frame,
                                encodedSize(delta) - kMessageHeaderSize);
    w.u32(object_count);
    w.u32(count32(delta.added.size()));
    w.u32(count32(delta.removed.size()));
    w.u32(count32(delta.changed.size()));
    w.u64(delta.hash);
    for (const auto& [id, count] : delta.added) {
        w.u32(id);
        w.u32(count);
    }
    for (uint32_t id : delta.removed) w.u32(id);
    for (const auto& [id, count] : delta.changed) {
        w.u32(id);
        w.u32(count);
    }
    return finishMessage(w);
}

std::vector<uint8_t> encodeEndOfFrame(const EndOfFrame& eof, int sender) {
    ByteWriter w = startMessage(MessageKind::EndOfFrame, eof.last ? kFlagEndOfFrameLast : 0, sender, eof.frame,
                                kEndOfFramePayloadSize);
    w.i64(eof.compute_ns);
    w.u32(eof.visible_count);
    w.u32(0);
    return finishMessage(w);
}

namespace {

// A record's fields onto the wire (visitRecordFields' order), and back.
struct RecordWriter {
    ByteWriter& w;
    void operator()(int32_t v) { w.u32(uint32_t(v)); }
    void operator()(bool v) { w.u8(v ? 1 : 0); }
    void operator()(uint64_t v) { w.u64(v); }
    void operator()(int64_t v) { w.i64(v); }
    void operator()(double v) { w.f64(v); }
};

struct RecordSize {
    size_t bytes = 0;
    void operator()(int32_t) { bytes += 4; }
    void operator()(bool) { bytes += 1; }
    void operator()(uint64_t) { bytes += 8; }
    void operator()(int64_t) { bytes += 8; }
    void operator()(double) { bytes += 8; }
};

// Reads one record at `at`; `bad` names the first field that cannot be a figure (a flag other
// than 0 or 1, a double that is not finite), or stays empty.
struct RecordReader {
    const ByteReader& r;
    size_t at;
    std::string bad;
    void operator()(int32_t& v) { v = int32_t(r.u32(at)), at += 4; }
    void operator()(bool& v) {
        const uint8_t b = r.u8(at++);
        if (b > 1 && bad.empty()) bad = "a flag byte " + std::to_string(b);
        v = b == 1;
    }
    void operator()(uint64_t& v) { v = r.u64(at), at += 8; }
    void operator()(int64_t& v) { v = int64_t(r.u64(at)), at += 8; }
    void operator()(double& v) {
        v = r.f64(at), at += 8;
        if (!std::isfinite(v) && bad.empty()) bad = "a figure that is not finite";
    }
};

}  // namespace

size_t frameRecordWireSize() {
    static const size_t size = [] {
        RecordSize counter;
        FrameRecord r;
        visitRecordFields(r, counter);
        return counter.bytes;
    }();
    return size;
}

std::vector<uint8_t> encodeReport(std::span<const FrameRecord> records, int sender) {
    const size_t size = frameRecordWireSize() * records.size();
    if (size > kMaxReportBytes) throw std::invalid_argument("encodeReport: records over kMaxReportBytes");
    ByteWriter w = startMessage(MessageKind::Report, 0, sender, records.size(), size);
    RecordWriter writer{w};
    for (const FrameRecord& r : records) {
        if (r.rank != sender) throw std::invalid_argument("encodeReport: a record of another rank");
        visitRecordFields(r, writer);
    }
    return finishMessage(w);
}

std::vector<FrameRecord> decodeReport(std::span<const uint8_t> bytes, const DecodeContext& ctx) {
    const auto [flags, payload] = checkHeader(bytes, MessageKind::Report, ctx);
    const std::string what = frameWhat(MessageKind::Report, ctx.expected_frame);
    checkFlags(ctx, MessageKind::Report, ctx.expected_frame, flags, 0);
    const size_t record_size = frameRecordWireSize();
    if (ctx.expected_frame > kMaxReportBytes / record_size || payload.size() != ctx.expected_frame * record_size)
        fail(ctx, what + ": " + std::to_string(payload.size()) + " payload bytes, not " +
                      std::to_string(ctx.expected_frame) + " records of " + std::to_string(record_size));
    const ByteReader r(payload);
    std::vector<FrameRecord> records(ctx.expected_frame);
    for (size_t i = 0; i < records.size(); ++i) {
        FrameRecord& record = records[i];
        RecordReader reader{r, i * record_size, {}};
        visitRecordFields(record, reader);
        const std::string which = what + ": record " + std::to_string(i);
        if (!reader.bad.empty()) fail(ctx, which + ": " + reader.bad);
        if (record.rank != ctx.sender) fail(ctx, which + " is rank " + std::to_string(record.rank) + "'s");
        if (record.net.partition < -1 || record.net.partition >= 65535)
            fail(ctx, which + ": partition " + std::to_string(record.net.partition));
        if (record.net.latency_frames < -1) fail(ctx, which + ": latency of a negative number of frames");
        if (record.displayed && record.net.partition < 0) fail(ctx, which + ": displayed without a partition");
        bool negative = record.ms_frame < 0 || record.stats.ms_total < 0 || record.net.ms_wait < 0 ||
                        record.net.ms_composite < 0 || record.display.ms_draw < 0 || record.display.ms_exact < 0;
        for (double ms : record.stats.ms) negative = negative || ms < 0;
        if (negative) fail(ctx, which + ": a negative time");
        if (i > 0 && record.stats.frame <= records[i - 1].stats.frame)
            fail(ctx, which + ": frame " + std::to_string(record.stats.frame) + " after frame " +
                          std::to_string(records[i - 1].stats.frame));
    }
    return records;
}

CameraPacket decodeCameraPacket(std::span<const uint8_t> bytes, const DecodeContext& ctx) {
    const auto [flags, payload] = checkHeader(bytes, MessageKind::Camera, ctx);
    const std::string what = frameWhat(MessageKind::Camera, ctx.expected_frame);
    checkFlags(ctx, MessageKind::Camera, ctx.expected_frame, flags, kFlagCameraStop);
    if (payload.size() != kCameraPayloadSize)
        fail(ctx, what + ": " + std::to_string(payload.size()) + " payload bytes, a camera packet has " +
                      std::to_string(kCameraPayloadSize));
    const ByteReader r(payload);
    CameraPacket p;
    p.stop = (flags & kFlagCameraStop) != 0;
    p.frame = ByteReader(bytes).u64(16);
    p.pose.eye = r.vec3(0);
    p.pose.target = r.vec3(12);
    p.pose.up = r.vec3(24);
    p.pose.fovy_degrees = r.f32(36);
    p.pose.near_plane = r.f32(40);
    p.pose.far_plane = r.f32(44);
    p.sent_ns = r.i64(48);
    if (const std::string defect = poseDefect(p.pose); !defect.empty()) fail(ctx, what + ": camera " + defect);
    return p;
}

VisibleSetDelta decodeVisibleSetDelta(std::span<const uint8_t> bytes, const DecodeContext& ctx) {
    const auto [flags, payload] = checkHeader(bytes, MessageKind::Delta, ctx);
    const std::string what = frameWhat(MessageKind::Delta, ctx.expected_frame);
    checkFlags(ctx, MessageKind::Delta, ctx.expected_frame, flags, kFlagDeltaFull);
    if (payload.size() < kDeltaPayloadHeaderSize)
        fail(ctx, what + ": " + std::to_string(payload.size()) + " payload bytes, shorter than the counts");
    const ByteReader r(payload);
    const uint32_t object_count = r.u32(0);
    if (object_count != ctx.object_count)
        fail(ctx, what + ": sender's scene has " + std::to_string(object_count) + " objects, ours " +
                      std::to_string(ctx.object_count) + " (not the same .oss file?)");
    const uint64_t added_count = r.u32(4), removed_count = r.u32(8), changed_count = r.u32(12);
    // In 64 bits: 8 * (2^32 - 1) * 2 + 4 * (2^32 - 1) cannot overflow.
    const uint64_t expected = kDeltaPayloadHeaderSize + 8 * added_count + 4 * removed_count + 8 * changed_count;
    if (expected != payload.size())
        fail(ctx, what + ": " + std::to_string(added_count) + " added, " + std::to_string(removed_count) +
                      " removed, " + std::to_string(changed_count) + " changed need " + std::to_string(expected) +
                      " payload bytes, " + std::to_string(payload.size()) + " arrived");
    VisibleSetDelta d;
    d.frame = ctx.expected_frame;
    d.full = (flags & kFlagDeltaFull) != 0;
    d.hash = r.u64(16);
    if (d.full && (removed_count != 0 || changed_count != 0))
        fail(ctx, what + ": a full set with removed or changed ids");
    const size_t added_at = kDeltaPayloadHeaderSize;
    const size_t removed_at = added_at + 8 * added_count;
    const size_t changed_at = removed_at + 4 * removed_count;
    checkIdList(ctx, what, "added", added_count, [&](size_t i) { return r.u32(added_at + 8 * i); });
    checkIdList(ctx, what, "removed", removed_count, [&](size_t i) { return r.u32(removed_at + 4 * i); });
    checkIdList(ctx, what, "changed", changed_count, [&](size_t i) { return r.u32(changed_at + 8 * i); });
    d.added.resize(added_count);
    for (size_t i = 0; i < added_count; ++i) d.added[i] = {r.u32(added_at + 8 * i), r.u32(added_at + 8 * i + 4)};
    d.removed.resize(removed_count);
    for (size_t i = 0; i < removed_count; ++i) d.removed[i] = r.u32(removed_at + 4 * i);
    d.changed.resize(changed_count);
    for (size_t i = 0; i < changed_count; ++i)
        d.changed[i] = {r.u32(changed_at + 8 * i), r.u32(changed_at + 8 * i + 4)};
    return d;
}

EndOfFrame decodeEndOfFrame(std::span<const uint8_t> bytes, const DecodeContext& ctx) {
    const auto [flags, payload] = checkHeader(bytes, MessageKind::EndOfFrame, ctx);
    const std::string what = frameWhat(MessageKind::EndOfFrame, ctx.expected_frame);
    checkFlags(ctx, MessageKind::EndOfFrame, ctx.expected_frame, flags, kFlagEndOfFrameLast);
    if (payload.size() != kEndOfFramePayloadSize)
        fail(ctx, what + ": " + std::to_string(payload.size()) + " payload bytes, an end-of-frame has " +
                      std::to_string(kEndOfFramePayloadSize));
    const ByteReader r(payload);
    EndOfFrame e;
    e.frame = ctx.expected_frame;
    e.last = (flags & kFlagEndOfFrameLast) != 0;
    e.compute_ns = r.i64(0);
    e.visible_count = r.u32(8);
    if (e.compute_ns < 0) fail(ctx, what + ": negative frame time " + std::to_string(e.compute_ns) + " ns");
    if (e.visible_count > ctx.object_count)
        fail(ctx, what + ": visible count " + std::to_string(e.visible_count) + " > object count " +
                      std::to_string(ctx.object_count));
    if (r.u32(12) != 0) fail(ctx, what + ": reserved field is not 0");
    return e;
}

}  // namespace occ
