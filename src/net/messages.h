// SPDX-License-Identifier: MIT
#pragma once

// The messages occlusion-switch ranks exchange every frame (Govindaraju et al. 2003,
// "Interactive visibility culling in complex environments using occlusion-switches"): the
// camera packet, the visible-set delta V_i = (V_{i-1} - removed) ∪ added and the end-of-frame
// marker. The wire format is docs/protocol.md; this file is that format, byte by byte.

#include "net/rank_error.h"
#include "pipeline/frame_record.h"
#include "pipeline/visible_set.h"
#include "view/camera.h"

#include <glm/glm.hpp>

#include <bit>
#include <cstddef>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

namespace occ {

static_assert(std::endian::native == std::endian::little,
              "the visible-set hash reads ids and counts in host order; a big-endian port needs byte swapping");

// The three kinds of frame message, and the end-of-run report (each rank's frame records, sent
// to rank 0, which writes the stats CSV and the summary from them). The value is the `kind` byte of the header and the MPI tag.
enum class MessageKind : uint8_t { Camera = 1, Delta = 2, EndOfFrame = 3, Report = 4 };
inline constexpr int kMessageKindCount = 4;

// "camera", "delta", "eof", "report" (the counters' suffixes); "unknown" for any other value.
const char* messageKindName(MessageKind kind);

// Wire constants (docs/protocol.md). A receiver accepts exactly kProtocolVersion.
inline constexpr uint32_t kMessageMagic = 0x4D53434Fu;  // "OCSM" read as little-endian u32
inline constexpr uint16_t kProtocolVersion = 3;
inline constexpr size_t kMessageHeaderSize = 32;
inline constexpr size_t kCameraPayloadSize = 56;
inline constexpr size_t kDeltaPayloadHeaderSize = 24;
inline constexpr size_t kEndOfFramePayloadSize = 16;
inline constexpr size_t kMaxReportBytes = size_t(256) << 20;  // a report's records

// What the display rank (RVG) sends every frame. sent_ns is the sender's steady clock at send
// time; only the sender compares it (round-trip latency), other ranks carry it back unchanged.
// A stop packet (a live run the user ended) says no frame `frame` or later will come: `frame`
// is the number of frames of the run, the receiver's next frame or the one before it; its pose
// is the last one sent. Only what the receivers use: each rank derives the matrices from the
// pose and its own viewport (every rank runs with the same options).
struct CameraPacket {
    uint64_t frame = 0;
    bool stop = false;
    CameraPose pose;
    int64_t sent_ns = 0;
};

// The change of the visible set (PVS with each object's LOD vertex count) from frame - 1 to
// frame. All three lists are sorted by id, ascending, without duplicates; `changed` holds ids
// kept from the previous set whose LOD vertex count is different now. When `full` is set the
// message carries the whole set in `added` (removed and changed are empty) and the receiver
// replaces its set: the first frame, and every frame under --no-deltas. hash = VisibleSet::hash()
// of the set after the change.
struct VisibleSetDelta {
    uint64_t frame = 0;
    bool full = false;
    std::vector<std::pair<uint32_t, uint32_t>> added;  // (object id, LOD vertex count)
    std::vector<uint32_t> removed;
    std::vector<std::pair<uint32_t, uint32_t>> changed;  // (object id, new LOD vertex count)
    uint64_t hash = 0;
};

// Sent by a rank when its part of `frame` is done. compute_ns is the sender's time spent on the
// frame (steady clock); visible_count is the size of its visible set after the frame (0 for a
// rank that keeps none), for the receiver to cross-check; last says the sender sends nothing
// after this frame.
struct EndOfFrame {
    uint64_t frame = 0;
    int64_t compute_ns = 0;
    uint32_t visible_count = 0;
    bool last = false;
};

// The delta that turns `previous` into `current` (full = false), hash = current.hash().
VisibleSetDelta makeDelta(const VisibleSet& previous, const VisibleSet& current, uint64_t frame);

// The message that carries all of `current` (full = true): the first frame and --no-deltas.
VisibleSetDelta makeFullDelta(const VisibleSet& current, uint64_t frame);

// Encoders: header + payload, little-endian, exactly encodedSize() bytes. `sender` is the rank
// that will send the bytes (the header records it, the receiver checks it). object_count is
// the number of objects of the scene both ranks mapped (the receiver checks it matches).
std::vector<uint8_t> encodeCameraPacket(const CameraPacket& packet, int sender);
std::vector<uint8_t> encodeVisibleSetDelta(const VisibleSetDelta& delta, uint32_t object_count, int sender);
std::vector<uint8_t> encodeEndOfFrame(const EndOfFrame& eof, int sender);
// The report: the sender's frame records (FrameRecord, visitRecordFields' fields in order, each
// record frameRecordWireSize() bytes, at most kMaxReportBytes in all); its frame field is the
// number of records. Every record's rank must be the sender.
std::vector<uint8_t> encodeReport(std::span<const FrameRecord> records, int sender);
size_t frameRecordWireSize();

// Bytes encodeVisibleSetDelta() produces, without encoding.
size_t encodedSize(const VisibleSetDelta& delta);
// Bytes a full delta of a set of visible_count objects weighs: the counters' full_pvs_bytes.
size_t fullVisibleSetEncodedSize(size_t visible_count);

// What a receiver knows before decoding: who sent the bytes, the frame the message must carry
// (messages of one kind from one rank come in frame order, so the receiver always knows it) and
// the scene's object count (ids must be below it).
struct DecodeContext {
    int sender = 0;
    uint64_t expected_frame = 0;
    uint32_t object_count = 0;
};

// Decoders: validate everything (header magic, version, kind, sender, payload size against the
// buffer, checksum, frame == expected_frame, every count against the bytes present, ids <
// object_count, lists ascending, camera finite and renderable) and throw RankError(ctx.sender,
// "<kind> of frame F: ...") on the first violation; never read outside `bytes`.
CameraPacket decodeCameraPacket(std::span<const uint8_t> bytes, const DecodeContext& ctx);
VisibleSetDelta decodeVisibleSetDelta(std::span<const uint8_t> bytes, const DecodeContext& ctx);
EndOfFrame decodeEndOfFrame(std::span<const uint8_t> bytes, const DecodeContext& ctx);
// ctx.expected_frame is the number of records the report must hold; each must be ctx.sender's,
// with finite figures, times >= 0, a partition in [-1, 65535) (>= 0 where it displayed), frames
// ascending. Which frames a rank ran is the layout's: the receiver checks those.
std::vector<FrameRecord> decodeReport(std::span<const uint8_t> bytes, const DecodeContext& ctx);

}  // namespace occ
