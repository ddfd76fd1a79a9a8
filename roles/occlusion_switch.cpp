// SPDX-License-Identifier: MIT
#include "roles/occlusion_switch.h"

#include "net/messages.h"
#include "net/rank_error.h"
#include "render/picture_metrics.h"
#include "scene/errors.h"
#include "util/config.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <memory>

namespace occ::roles {

namespace {

using Clock = std::chrono::steady_clock;

int64_t nowNs() {
    return std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now().time_since_epoch()).count();
}

// Waits of the first two frames may cover a rank's start (mapping the scene, building its
// pipeline, a first frame that streams everything), which a large scene stretches to seconds.
constexpr std::chrono::milliseconds kStartupAllowance{60000};

constexpr MessageKind kFrameKinds[] = {MessageKind::Camera, MessageKind::Delta, MessageKind::EndOfFrame};

// Per-row differences of the transport's cumulative counters.
class CounterWindow {
public:
    explicit CounterWindow(const Transport& t) : transport_(t), last_(t.counters()) {}
    NetFigures take() {
        const TransportCounters now = transport_.counters();
        const TransportCounters d = now - last_;
        last_ = now;
        NetFigures c;
        for (int i = 0; i < 3; ++i) {
            c.bytes[i] = d[kFrameKinds[i]].bytes_sent;
            c.messages[i] = d[kFrameKinds[i]].messages_sent;
        }
        for (const KindCounters& k : d.kinds) c.ms_wait += double(k.receive_wait_ns) / 1e6;
        c.composite_bytes = d.composite_bytes_sent;
        c.ms_composite = double(d.composite_ns) / 1e6;
        return c;
    }

private:
    const Transport& transport_;
    TransportCounters last_;
};

// A row's message columns: what the transport counted since the last row, with what the
// frame's culling or display recorded about it (hash, delta entries, latency, partition).
NetFigures rowColumns(const NetFigures& counted, NetFigures frame) {
    std::copy(std::begin(counted.bytes), std::end(counted.bytes), frame.bytes);
    std::copy(std::begin(counted.messages), std::end(counted.messages), frame.messages);
    frame.ms_wait = counted.ms_wait;
    frame.composite_bytes = counted.composite_bytes;
    frame.ms_composite = counted.ms_composite;
    return frame;
}

// OR + HC on one rank: rasters a frame's occluders when its camera arrives, then culls it and
// sends the visible-set delta to the display (and to the other switch rank).
class Culler {
public:
    // `partition`: each object's display partition (2 + P ranks), empty with one display.
    Culler(Transport& t, Pipeline& pipeline, const RankLayout& layout, const RunOptions& run,
           const std::vector<uint16_t>& partition)
        : t_(t), pipeline_(pipeline), objects_(pipeline.itemCount()), layout_(layout), run_(run), partition_(partition) {}

    // OR of frame f: its camera from the display, then the occluders (Eq. 3's AOS plus the
    // largest objects of the last PVS this rank computed) rastered into this rank's HZM.
    // Returns false, rastering nothing, when the display stopped a live run before frame f.
    bool occluders(uint64_t f) {
        const CameraPacket packet =
            decodeCameraPacket(t_.receive(0, MessageKind::Camera, waitLimit()), {0, f, objects_});
        if (packet.stop) {
            if (!run_.live) throw RankError(0, "camera of frame " + std::to_string(f) + ": a stop in a recorded run");
            stop_frames_ = packet.frame;
            // The other switch rank sent its last frame's delta to this one too.
            const int other = layout_.size() >= 3 ? 3 - t_.rank() : -1;
            if (other > 0 && packet.frame == f && f > 0) receiveOthers(f - 1, other);
            return false;
        }
        pose_ = packet.pose;
        pose_frame_ = f;
        or_stats_ = FrameStats{};
        pipeline_.frustumPass(pose_, or_stats_);
        pipeline_.occluderPass(pose_, f, or_stats_);
        return true;
    }

    // HC of frame f (after occluders(f)): returns the frame's OR + HC stats; the delta is sent.
    FrameStats cull(uint64_t f, NetFigures& net) {
        if (pose_frame_ != f) throw std::logic_error("Culler::cull before occluders of the frame");
        // The display may lag at most two frames behind the culling.
        while (f >= 2 && eof_seen_ + 2 < f + 1) receiveEndOfFrame();
        // V_{f-1}: this rank's own, or in the switch the other rank's, from its delta, in the
        // pipeline's history. The LOD hysteresis starts from it, and the delta of f is taken
        // against it.
        const int other = layout_.size() >= 3 ? 3 - t_.rank() : -1;
        if (other > 0 && f > 0) receiveOthers(f - 1, other);
        FrameStats stats = or_stats_;
        stats.frame = f;
        pipeline_.cullPass(pose_, f, stats);
        const VisibleSet& current = *pipeline_.culledSet(f);
        remember(f, current);
        const VisibleSet* previous = f > 0 ? pipeline_.culledSet(f - 1) : nullptr;
        if (run_.deltas && f > 0 && !previous)
            throw std::logic_error("Culler::cull: frame " + std::to_string(f - 1) + " left the history");
        const VisibleSetDelta delta =
            run_.deltas && f > 0 ? makeDelta(*previous, current, f) : makeFullDelta(current, f);
        const std::vector<uint8_t> bytes = encodeVisibleSetDelta(delta, objects_, t_.rank());
        if (layout_.displays() == 1) {
            t_.send(0, MessageKind::Delta, bytes);
            net.full_pvs_bytes += fullVisibleSetEncodedSize(current.size());
        } else {
            // Each display rank gets its partition's part of the delta (and of the budget's
            // vertex counts): one Eq. 1 solve for the whole scene, split by partition.
            std::vector<VisibleSetDelta> parts(size_t(layout_.displays()));
            std::vector<std::vector<VisibleSet::Entry>> sets(parts.size());
            for (size_t p = 0; p < parts.size(); ++p) parts[p].frame = delta.frame, parts[p].full = delta.full;
            for (const auto& e : delta.added) parts[partition_[e.first]].added.push_back(e);
            for (uint32_t id : delta.removed) parts[partition_[id]].removed.push_back(id);
            for (const auto& e : delta.changed) parts[partition_[e.first]].changed.push_back(e);
            for (const auto& e : current.entries()) sets[partition_[e.first]].push_back(e);
            for (size_t p = 0; p < parts.size(); ++p) {
                const VisibleSet part(std::move(sets[p]));
                parts[p].hash = part.hash();
                t_.send(layout_.displayRank(int(p)), MessageKind::Delta,
                        encodeVisibleSetDelta(parts[p], objects_, t_.rank()));
                net.full_pvs_bytes += fullVisibleSetEncodedSize(part.size());
            }
        }
        if (other > 0 && (run_.live || f + 1 < run_.cameras.size())) {
            t_.send(other, MessageKind::Delta, bytes);
            net.full_pvs_bytes += fullVisibleSetEncodedSize(current.size());
        }
        net.visible_hash = current.hash();
        net.added = delta.added.size();
        net.removed = delta.removed.size();
        net.changed = delta.changed.size();
        return stats;
    }

    std::chrono::milliseconds finishLimit() const { return waitLimit(); }

    // One rank's live run: the display, on this rank, ended it after `frames` frames. It asks
    // for the next camera after drawing (so that waiting for it is no part of the frame), so its
    // end-of-frames cannot say which was the last.
    void endLive(uint64_t frames) {
        stop_frames_ = frames;
        last_unknown_ = true;
    }

    // The display's end-of-frame messages still due, at the end of the run.
    void drainEndOfFrames() {
        while (eof_seen_ < frames()) receiveEndOfFrame();
    }

private:
    // The other switch rank's V_g from its delta (against V_{g-1}, this rank's own), into the
    // pipeline's history.
    void receiveOthers(uint64_t g, int other) {
        const VisibleSetDelta d =
            decodeVisibleSetDelta(t_.receive(other, MessageKind::Delta, waitLimit()), {other, g, objects_});
        const VisibleSet* base = g > 0 ? pipeline_.culledSet(g - 1) : nullptr;
        VisibleSet v = base ? *base : VisibleSet();
        v.apply(d, other);
        remember(g, v);
        pipeline_.recordCulledElsewhere(g, std::move(v));
    }

    // The end-of-frame of frame eof_seen_ from every display rank.
    void receiveEndOfFrame() {
        for (int r : layout_.displayRanks()) {
            const EndOfFrame e =
                decodeEndOfFrame(t_.receive(r, MessageKind::EndOfFrame, waitLimit()), {r, eof_seen_, objects_});
            slowest_display_ns_ = std::max(slowest_display_ns_, e.compute_ns);
            // The display's set must be the switch's (its partition of it).
            if (const auto known = sizes_.find(eof_seen_); known != sizes_.end()) {
                const uint32_t expected = known->second[size_t(std::max(0, layout_.partitionOf(r)))];
                if (e.visible_count != expected)
                    throw RankError(r, "end-of-frame of frame " + std::to_string(eof_seen_) + ": " +
                                           std::to_string(e.visible_count) + " visible objects, the switch sent " +
                                           std::to_string(expected));
            }
            // A live run's last frame is known once the stop came; the display ranks other than
            // rank 0 learn it only from the stop, after their last frame.
            const bool known = (!run_.live || (frames() != UINT64_MAX && !last_unknown_)) && r == 0;
            if (known && e.last != (eof_seen_ + 1 == frames()))
                throw RankError(r, "end-of-frame of frame " + std::to_string(eof_seen_) + ": wrong 'last' flag");
        }
        sizes_.erase(sizes_.begin(), sizes_.upper_bound(eof_seen_));
        ++eof_seen_;
    }

    // The sizes of frame f's visible set per display partition, for the end-of-frame check.
    void remember(uint64_t f, const VisibleSet& v) {
        std::vector<uint32_t> sizes(size_t(layout_.displays()), 0);
        if (layout_.displays() == 1) sizes[0] = uint32_t(v.size());
        else
            for (const auto& e : v.entries()) ++sizes[partition_[e.first]];
        if (f >= eof_seen_) sizes_[f] = std::move(sizes);
    }

    // The run's frames: the path's, or in a live run UINT64_MAX until the display stopped it.
    uint64_t frames() const { return run_.live ? stop_frames_ : run_.cameras.size(); }

    // How long to wait for the display (or the other switch rank, which waits for it): the
    // start-up allowance until the display has finished two frames, then --rank-timeout or 3x
    // the display's slowest frame so far, whichever is longer (a display drawing 10^7
    // triangles on a CPU takes seconds per frame and is not dead).
    std::chrono::milliseconds waitLimit() const {
        if (eof_seen_ < 2) return std::max(run_.timeout, kStartupAllowance);
        return std::max(run_.timeout, std::chrono::milliseconds(3 * slowest_display_ns_ / 1000000));
    }

    Transport& t_;
    Pipeline& pipeline_;
    uint32_t objects_;
    const RankLayout& layout_;
    const RunOptions& run_;
    const std::vector<uint16_t>& partition_;
    int64_t slowest_display_ns_ = 0;
    CameraPose pose_;
    uint64_t pose_frame_ = UINT64_MAX;
    FrameStats or_stats_;
    uint64_t eof_seen_ = 0;  // end-of-frames received: frames 0 .. eof_seen_ - 1
    std::map<uint64_t, std::vector<uint32_t>> sizes_;  // remember()
    uint64_t stop_frames_ = UINT64_MAX;  // a live run: the frame count of the display's stop
    bool last_unknown_ = false;
};

// RVG on rank 0: sends cameras, receives each frame's delta, rebuilds V_f, streams, reforms
// and draws it, and tells the culling ranks the frame is done.
class Display {
public:
    Display(Transport& t, Pipeline& pipeline, const PipelineOptions& options,
            const RankLayout& layout, const RunOptions& run)
        : t_(t), pipeline_(pipeline), objects_(pipeline.itemCount()), options_(options), layout_(layout), run_(run) {}

    // Sends frame f's camera (f = every earlier frame's + 1).
    void sendCamera(uint64_t f, uint64_t step, const CameraPose& pose) {
        const CameraPacket p = packet(f, pose, false);
        poses_.push_back(pose);
        sent_ns_.push_back(p.sent_ns);
        sent_step_.push_back(step);
        const std::vector<uint8_t> bytes = encodeCameraPacket(p, t_.rank());
        t_.send(layout_.culler(f), MessageKind::Camera, bytes);
        // The other display ranks draw the same camera.
        for (int q = 1; q < layout_.displays(); ++q) t_.send(layout_.displayRank(q), MessageKind::Camera, bytes);
    }

    // A display rank other than rank 0: frame f's camera from rank 0. False when rank 0 stopped
    // a live run before frame f.
    bool receiveCamera(uint64_t f) {
        const std::chrono::milliseconds limit = f < 2 ? std::max(run_.timeout, kStartupAllowance) : run_.timeout;
        const CameraPacket p = decodeCameraPacket(t_.receive(0, MessageKind::Camera, limit), {0, f, objects_});
        if (p.stop) {
            if (!run_.live) throw RankError(0, "camera of frame " + std::to_string(f) + ": a stop in a recorded run");
            return false;
        }
        poses_.push_back(p.pose);
        sent_ns_.push_back(p.sent_ns);
        sent_step_.push_back(f == 0 ? 0 : f - 1);  // rank 0 sends frame f's camera at step f - 1
        return true;
    }

    // Ends a live run of `frames` frames: every culling rank is told, at the frame it waits for.
    void sendStop(uint64_t frames) {
        const CameraPacket p = packet(frames, poses_.empty() ? CameraPose{} : poses_.back(), true);
        for (int r = 1; r < layout_.size(); ++r) t_.send(r, MessageKind::Camera, encodeCameraPacket(p, t_.rank()));
    }

    // Displays frame f at display step `step` into `record`, adding to its stats (which hold the
    // culling's stages on one rank) what streaming costs, its messages and what the drawing
    // measured. `last`: no frame follows (the culling ranks are told with the end-of-frame).
    void display(uint64_t f, uint64_t step, FrameRecord& record, bool last) {
        FrameStats& stats = record.stats;
        NetFigures& net = record.net;
        const int64_t start_ns = nowNs();
        const int from = layout_.culler(f);
        const std::chrono::milliseconds limit = f < 2 ? std::max(run_.timeout, kStartupAllowance) : run_.timeout;
        if (run_.idle) {
            // A live display keeps its window answering while the culling rank works.
            const auto deadline = Clock::now() + limit;
            while (!t_.poll(from, MessageKind::Delta)) {
                if (Clock::now() >= deadline)
                    throw RankError(from, "no delta message for " + formatDuration(limit) +
                                              ": the rank died or stopped answering");
                run_.idle();
            }
        }
        const VisibleSetDelta d = decodeVisibleSetDelta(t_.receive(from, MessageKind::Delta, limit), {from, f, objects_});
        // One rank: this pipeline culled frame f (its frustum is this frame's).
        const bool culled_here = pipeline_.culledSet(f) != nullptr;
        // V_f from V_{f-1} in the pipeline's history: the sets this display received (its
        // partition's with 2 + P ranks), or on one rank the ones its own culling chose.
        const VisibleSet* base = f > 0 ? pipeline_.culledSet(f - 1) : nullptr;
        if (f > 0 && !base && !d.full)
            throw std::logic_error("Display::display: frame " + std::to_string(f - 1) + " left the history");
        VisibleSet next = base ? *base : VisibleSet();
        next.apply(d, from);  // checks that V_f hashes to d.hash
        net.added = d.added.size();
        net.removed = d.removed.size();
        net.changed = d.changed.size();
        if (!culled_here) pipeline_.recordCulledElsewhere(f, std::move(next));
        const VisibleSet& shown = culled_here ? next : *pipeline_.culledSet(f);
        const CameraPose pose = poses_.at(f);
        // A rank that culled frame f itself (one rank) holds its visible set and frustum on the
        // device already (the delta applied to f - 1's hashed to it); another's set is uploaded.
        if (!culled_here) {
            try {
                pipeline_.setVisible(shown);
            } catch (const std::invalid_argument& e) {
                throw RankError(from, "delta of frame " + std::to_string(f) + ": " + e.what());
            }
            pipeline_.frustumPass(pose, stats, Pipeline::FrustumUse::Measure);
        }
        stats.objects_in_frustum = pipeline_.frustumCount();
        stats.objects_occluded = stats.objects_in_frustum - std::min<uint64_t>(stats.objects_in_frustum, shown.size());
        pipeline_.streamPass(f, stats);
        if (run_.draw) {
            record.display = run_.draw(pipeline_, pose, f, stats);
            record.displayed = true;
        }
        net.latency_ms = double(nowNs() - sent_ns_[f]) / 1e6;
        net.latency_frames = int64_t(step - sent_step_[f]);
        net.visible_hash = d.hash;
        EndOfFrame e;
        e.frame = f;
        e.visible_count = uint32_t(shown.size());
        e.last = last;
        e.compute_ns = nowNs() - start_ns;
        const std::vector<uint8_t> bytes = encodeEndOfFrame(e, t_.rank());
        for (int r : layout_.cullingRanks()) t_.send(r, MessageKind::EndOfFrame, bytes);
        net.partition = layout_.partitionOf(t_.rank());
    }

private:
    CameraPacket packet(uint64_t f, const CameraPose& pose, bool stop) const {
        CameraPacket p;
        p.frame = f;
        p.stop = stop;
        p.pose = pose;
        p.sent_ns = nowNs();
        return p;
    }

    Transport& t_;
    Pipeline& pipeline_;
    uint32_t objects_;
    const PipelineOptions& options_;
    const RankLayout& layout_;
    const RunOptions& run_;
    std::vector<CameraPose> poses_;  // the camera sent for each frame
    std::vector<int64_t> sent_ns_;
    std::vector<uint64_t> sent_step_;
};

}  // namespace

RankLayout::RankLayout(int size) : size_(size) {
    if (size < 1 || size > kMaxRanks)
        throw UsageError(std::to_string(size) + " ranks: occswitch runs 1 (all roles), 2 (display + "
                         "culling), 3 (display + occlusion switch) or 2 + P up to " + std::to_string(kMaxRanks) +
                         " (the switch and P sort-last display ranks)");
}

std::vector<int> RankLayout::displayRanks() const {
    std::vector<int> r;
    for (int p = 0; p < displays(); ++p) r.push_back(displayRank(p));
    return r;
}

std::vector<int> RankLayout::cullingRanks() const {
    if (size_ == 1) return {0};
    if (size_ == 2) return {1};
    return {1, 2};
}

const char* RankLayout::roleOf(int rank) const {
    if (size_ == 1) return "or+hc+rvg";
    return partitionOf(rank) >= 0 ? "rvg" : "or+hc";
}

uint32_t RankLayout::resolveOccluderLag(uint32_t requested) const {
    if (requested == 0) return occluderLag();
    if (requested < occluderLag())
        throw OptionError("pvs_occluder_lag", std::to_string(requested) + " with " + std::to_string(size_) +
                                                  " ranks: the switch's occluder rank has the PVS of " +
                                                  std::to_string(occluderLag()) + " frames back at the newest");
    return requested;
}

std::vector<uint16_t> partitionObjects(const OssFile& file, int parts, int cells) {
    if (parts < 1 || parts > 65535) throw std::invalid_argument("partitionObjects: parts outside [1, 65535]");
    if (cells < 1 || cells > kMaxSortLastCells)
        throw std::invalid_argument("partitionObjects: cells outside [1, " + std::to_string(kMaxSortLastCells) + "]");
    const auto objects = file.objects();
    const auto meshes = file.meshRecords();
    std::vector<uint16_t> partition(objects.size(), 0);
    if (parts == 1) return partition;
    struct Item {
        glm::vec3 centre;
        double triangles;
        uint32_t id;
    };
    std::vector<Item> items(objects.size());
    for (uint32_t i = 0; i < objects.size(); ++i) {
        const auto& o = objects[i];
        const glm::vec3 lo(o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]), hi(o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]);
        // Every object weighs at least one triangle, so that empty ones spread too.
        items[i] = {0.5f * (lo + hi), std::max(1.0, double(meshes[o.mesh].triangle_count)), i};
    }
    // Splits items [begin, end) into leaves [first, first + k).
    std::vector<uint32_t> leaf(objects.size(), 0);
    const auto split = [&](auto&& self, size_t begin, size_t end, int first, int k) -> void {
        if (k == 1 || end - begin <= 1) {
            for (size_t j = begin; j < end; ++j) leaf[items[j].id] = uint32_t(first);
            return;
        }
        glm::vec3 lo(INFINITY), hi(-INFINITY);
        for (size_t j = begin; j < end; ++j) lo = glm::min(lo, items[j].centre), hi = glm::max(hi, items[j].centre);
        const glm::vec3 extent = hi - lo;
        const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0 : extent.y >= extent.z ? 1 : 2;
        // Sorted along the axis, ties by id: the same order on every rank.
        std::sort(items.begin() + std::ptrdiff_t(begin), items.begin() + std::ptrdiff_t(end),
                  [axis](const Item& a, const Item& b) {
                      return a.centre[axis] < b.centre[axis] || (a.centre[axis] == b.centre[axis] && a.id < b.id);
                  });
        double total = 0;
        for (size_t j = begin; j < end; ++j) total += items[j].triangles;
        const int left = k / 2;
        const double target = total * double(left) / double(k);
        size_t cut = begin;
        double before = 0;
        while (cut < end && before + 0.5 * items[cut].triangles < target) before += items[cut++].triangles;
        // Both sides keep at least one object while they can.
        cut = std::clamp(cut, begin + 1, end - 1);
        self(self, begin, cut, first, left);
        self(self, cut, end, first + left, k - left);
    };
    const int leaves = parts * cells;
    split(split, 0, items.size(), 0, leaves);
    // One cell per part: leaf L is partition L. More: the heaviest leaf first to the lightest
    // partition (ties to the lower number), so that objects heavier than a leaf's share still
    // even out; neighbouring leaves mostly land on different partitions.
    std::vector<int> owner(static_cast<size_t>(leaves));
    if (cells == 1) {
        for (int l = 0; l < leaves; ++l) owner[size_t(l)] = l;
    } else {
        std::vector<double> weight(static_cast<size_t>(leaves), 0.0), load(static_cast<size_t>(parts), 0.0);
        for (const Item& it : items) weight[leaf[it.id]] += it.triangles;
        std::vector<int> order(static_cast<size_t>(leaves));
        for (int l = 0; l < leaves; ++l) order[size_t(l)] = l;
        std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return weight[size_t(a)] > weight[size_t(b)]; });
        for (int l : order) {
            const int p = int(std::min_element(load.begin(), load.end()) - load.begin());
            owner[size_t(l)] = p;
            load[size_t(p)] += weight[size_t(l)];
        }
    }
    for (uint32_t i = 0; i < objects.size(); ++i) partition[i] = uint16_t(owner[leaf[i]]);
    return partition;
}

std::string rankStatsHeader(const RunOptions& run) {
    return "rank,role," + frameStatsHeader() + netFiguresHeader() +
           (run.display_columns ? displayStatsHeader(*run.display_columns) : std::string());
}

std::string rankStatsRows(const std::vector<FrameRecord>& records, const RankLayout& layout, const RunOptions& run) {
    // The display's columns stay empty in the rows of a rank that did not draw the frame.
    std::string no_display;
    if (run.display_columns) {
        const std::string header = displayStatsHeader(*run.display_columns);
        no_display.assign(size_t(std::count(header.begin(), header.end(), ',')), ',');
    }
    std::string text;
    for (const FrameRecord& r : records) {
        text += std::to_string(r.rank) + "," + layout.roleOf(r.rank) + "," + frameStatsRow(r.stats) +
                netFiguresRow(r.net);
        if (run.display_columns) text += r.displayed ? displayStatsRow(r.display, *run.display_columns) : no_display;
        text += '\n';
    }
    return text;
}

double RunSummary::pooledPsnrDb() const {
    // Frames are the same size, so the run's squared error per byte is the mean of theirs.
    return frames ? render::psnrFromSquaredError(mse, frames) : 100.0;
}

RunSummary summarize(const std::vector<FrameRecord>& records, const RankLayout& layout) {
    RunSummary sum;
    sum.displays = layout.displays();
    sum.partition_triangles.assign(size_t(sum.displays), 0.0);
    sum.min_psnr_db = 1e9;
    // Per display rank: frames drawn and the sums over them (sort-last: the frame's figures are
    // the sums over the display ranks; rank 0's pipeline holds its partition only).
    std::vector<double> frames(size_t(sum.displays), 0.0), visible(frames), active(frames), streamed(frames);
    for (const FrameRecord& r : records) {
        const FrameStats& s = r.stats;
        const NetFigures& net = r.net;
        sum.bytes_camera += net.bytes[0];
        sum.bytes_delta += net.bytes[1];
        sum.bytes_eof += net.bytes[2];
        sum.full_pvs_bytes += net.full_pvs_bytes;
        sum.bytes_composite += net.composite_bytes;
        if (net.partition >= 0 && net.partition < sum.displays) {
            const size_t p = size_t(net.partition);
            frames[p] += 1;
            visible[p] += double(s.objects_visible);
            active[p] += double(s.active_triangles);
            streamed[p] += double(s.streamed_triangles);
        }
        if (r.rank != 0) continue;
        sum.frames += 1;
        sum.ms_frame += r.ms_frame;
        sum.objects_in_frustum += double(s.objects_in_frustum);
        sum.objects_visible += double(s.objects_visible);
        sum.active_triangles += double(s.active_triangles);
        sum.streamed_triangles += double(s.streamed_triangles);
        sum.ms_wait += net.ms_wait;
        sum.ms_composite += net.ms_composite;
        if (s.frame > 0) {
            sum.bus_h2d_bytes += s.bus_h2d_bytes;
            sum.bus_d2h_bytes += s.bus_d2h_bytes;
            sum.streamed_bytes += s.streamed_bytes;
            sum.pvs_churn += double(s.pvs_added + s.pvs_removed);
            sum.latency_ms += net.latency_ms;
            sum.latency_frames = uint32_t(net.latency_frames);
        }
        if (!r.displayed) continue;
        const DisplayStats& d = r.display;
        sum.ms_draw += d.ms_draw;
        sum.false_culls += double(d.false_culls);
        sum.exact_occluded += double(d.exact_occluded);
        sum.culling_accuracy += d.culling_accuracy;
        if (s.frame > 0) sum.exact_churn += double(d.exact_added + d.exact_removed);
        sum.psnr_db += d.psnr_db;
        sum.min_psnr_db = std::min(sum.min_psnr_db, d.psnr_db);
        sum.changed_pixel_share += d.changed_pixel_share;
        sum.mse += d.mse;
        sum.perceptible_share += d.perceptible_share;
        sum.ssim += d.ssim;
        sum.max_bound_p99_px = std::max(sum.max_bound_p99_px, d.bound_p99_px);
        sum.bound_pixels += d.bound_pixels;
        sum.bound_beyond_tau += d.bound_beyond_tau;
    }
    for (size_t p = 0; p < frames.size(); ++p)
        if (frames[p] > 0) sum.partition_triangles[p] = active[p] / frames[p];
    if (sum.displays > 1) {
        sum.objects_visible = sum.active_triangles = sum.streamed_triangles = 0;
        for (size_t p = 0; p < frames.size(); ++p) {
            sum.objects_visible += visible[p];
            sum.active_triangles += active[p];
            sum.streamed_triangles += streamed[p];
        }
    }
    return sum;
}

namespace {

// The frames a rank culls or displays in a run of `frames` frames.
uint64_t framesOfRank(const RankLayout& layout, int rank, uint64_t frames) {
    if (layout.size() >= 3 && layout.partitionOf(rank) < 0) return (frames + (rank == 1 ? 1 : 0)) / 2;
    return frames;
}

// Rank 0: every other rank's records, checked against the layout, merged with rank 0's by
// frame, then rank.
std::vector<FrameRecord> gatherRecords(Transport& transport, const RankLayout& layout, std::vector<FrameRecord> own,
                                       uint64_t frames, uint32_t items, std::chrono::milliseconds timeout) {
    for (int r = 1; r < layout.size(); ++r) {
        const std::vector<FrameRecord> theirs = decodeReport(transport.receive(r, MessageKind::Report, timeout),
                                                             {r, framesOfRank(layout, r, frames), items});
        for (const FrameRecord& record : theirs) {
            if (record.net.partition != layout.partitionOf(r))
                throw RankError(r, "report: partition " + std::to_string(record.net.partition) + ", expected " +
                                       std::to_string(layout.partitionOf(r)));
            const uint64_t f = record.stats.frame;
            if (f >= frames || (layout.partitionOf(r) < 0 && layout.culler(f) != r))
                throw RankError(r, "report: a record of frame " + std::to_string(f) + ", which this rank did not run");
        }
        own.insert(own.end(), theirs.begin(), theirs.end());
    }
    std::stable_sort(own.begin(), own.end(),
                     [](const FrameRecord& a, const FrameRecord& b) { return a.stats.frame < b.stats.frame; });
    return own;
}

}  // namespace

namespace {

// One rank's part of a run: the objects of its roles over its pipeline, and the frame loop.
class RankRun {
public:
    RankRun(Transport& transport, const RankLayout& layout, const RunOptions& run, Pipeline& pipeline,
            const PipelineOptions& options, const std::vector<uint16_t>& partition)
        : layout_(layout), run_(run), rank_(transport.rank()),
          frames_(run.live ? UINT64_MAX : run.cameras.size()), window_(transport) {
        if (culls()) culler_ = std::make_unique<Culler>(transport, pipeline, layout, run, partition);
        if (displays()) display_ = std::make_unique<Display>(transport, pipeline, options, layout, run);
    }

    // The frame loop, the same on every rank of every layout: each step is done by the ranks
    // whose roles it belongs to (one rank: all of them, in this order). Returns the frames run.
    uint64_t loop() {
        // With more than one rank the display sends frame f + 1's camera before it draws frame
        // f: the culling ranks work on f + 1 meanwhile.
        const uint32_t lead = layout_.cameraLead();
        if (source())
            for (uint64_t g = 0; g < lead && g < frames_; ++g)
                if (!sendCamera(g, g)) frames_ = g;
        for (uint64_t f = 0; f < frames_; ++f) {
            auto start = Clock::now();
            // 1. Camera: the source takes frame f + lead's and sends it.
            if (source() && !sendCamera(f + lead, f)) frames_ = f + lead;
            if (f >= frames_) break;
            if (lead == 0) start = Clock::now();  // one rank: the frame starts once its camera is taken
            FrameRecord r;
            bool recorded = false;
            // 2. Occluders (OR) and 3. cull (HC), sending the visible-set delta: the culling rank
            // of frame f. A live run's stop ends the run here.
            if (culls() && layout_.culler(f) == rank_) {
                if (!culler_->occluders(f)) {
                    frames_ = f;
                    break;
                }
                r.stats = culler_->cull(f, r.net);
                recorded = true;
            }
            // 4. The delta applied, stream, draw and present: every display rank (the other
            // sort-last display ranks take rank 0's camera first).
            if (displays()) {
                if (!source() && !display_->receiveCamera(f)) {
                    frames_ = f;
                    break;
                }
                display_->display(f, f, r, frames_ != UINT64_MAX && f + 1 == frames_);
                recorded = true;
            }
            // 5. Record.
            if (!recorded) continue;
            if (source()) r.ms_frame = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
            record(r);
            if (source() && run_.on_frame) run_.on_frame(f + 1);
        }
        if (frames_ == UINT64_MAX) frames_ = 0;
        return frames_;
    }

    // After the loop: the end-of-frames still due, a live run's stop. Returns how long this rank
    // may wait for the others to finish.
    std::chrono::milliseconds finishRoles() {
        std::chrono::milliseconds limit = run_.timeout;
        if (culls()) {
            if (displays() && run_.live) culler_->endLive(frames_);
            culler_->drainEndOfFrames();
            // The display may still be drawing its last frame when this rank is done.
            if (!displays()) limit = culler_->finishLimit();
        }
        if (source() && layout_.size() > 1 && run_.live) display_->sendStop(frames_);
        return limit;
    }

    std::vector<FrameRecord>& records() { return records_; }

private:
    bool culls() const { return layout_.size() == 1 || layout_.partitionOf(rank_) < 0; }
    bool displays() const { return layout_.partitionOf(rank_) >= 0; }
    bool source() const { return rank_ == 0; }  // the display that takes the cameras

    // The camera of frame g from the source (the path, or a live run's newest pose), sent to the
    // ranks that need it; false ends the run before frame g.
    bool sendCamera(uint64_t g, uint64_t step) {
        CameraPose pose;
        if (run_.live ? !run_.next_camera(g, pose) : g >= frames_) return false;
        if (!run_.live) pose = run_.cameras[g];
        display_->sendCamera(g, step, pose);
        return true;
    }

    // A frame's record is done: its bus bytes and the messages the transport counted for it.
    void record(FrameRecord& r) {
        if (!run_.keep_records) return;
        r.rank = rank_;
        r.net = rowColumns(window_.take(), r.net);
        bus_.take(r.stats);
        records_.push_back(r);
    }

    const RankLayout& layout_;
    const RunOptions& run_;
    const int rank_;
    uint64_t frames_;  // a live run: UINT64_MAX until it ends
    std::unique_ptr<Culler> culler_;
    std::unique_ptr<Display> display_;
    CounterWindow window_;
    BusWindow bus_;  // after the pipeline's start-up copies
    std::vector<FrameRecord> records_;
};

}  // namespace

std::vector<FrameRecord> runRanks(Transport& transport, const OssFile& file, const PipelineOptions& options,
                                  const RunOptions& run, RunSummary& summary) {
    try {
        const RankLayout layout(transport.size());
        const int rank = transport.rank();
        if (!run.live && run.cameras.empty()) throw UsageError("the camera path has no frames");
        if (run.live && rank == 0 && !run.next_camera) throw std::logic_error("runRanks: a live run without cameras");
        PipelineOptions o = options;
        o.pvs_occluder_lag = layout.resolveOccluderLag(o.pvs_occluder_lag);
        if (o.hierarchy && layout.displays() > 1)
            throw OptionError("hierarchy", "on with " + std::to_string(layout.size()) +
                                               " ranks: sort-last partitions are of objects; the hierarchy runs on 1 to 3 ranks");
        const std::vector<uint16_t> partition =
            layout.displays() > 1 ? partitionObjects(file, layout.displays(), run.sort_last_cells)
                                  : std::vector<uint16_t>();
        Pipeline pipeline(file, o);
        summary = RunSummary{};
        RankRun me(transport, layout, run, pipeline, o, partition);
        const uint64_t frames = me.loop();
        const std::chrono::milliseconds finish_limit = me.finishRoles();
        std::vector<FrameRecord> records = std::move(me.records());
        // Every rank's records to rank 0, which writes the CSV and the summary from them.
        if (!run.keep_records) {
            summary.frames = frames;
        } else if (rank != 0) {
            transport.send(0, MessageKind::Report, encodeReport(records, rank));
        } else {
            records = gatherRecords(transport, layout, std::move(records), frames, pipeline.itemCount(), run.timeout);
            summary = summarize(records, layout);
        }
        transport.finish(finish_limit);
        return records;
    } catch (const RankError& e) {
        transport.fail(e.rank(), e.detail());
        throw;
    } catch (const std::exception& e) {
        transport.fail(transport.rank(), e.what());
        throw;
    }
}

}  // namespace occ::roles
