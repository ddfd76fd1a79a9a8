// SPDX-License-Identifier: MIT
#pragma once

// A frame's record: what one rank measured of one frame (the pipeline's stages, the messages it
// sent, what its display drew). Ranks send their records to rank 0 in binary (the report,
// net/messages.h); rank 0 writes the stats CSV and the run's summary from them, once.

#include "pipeline/frame_stats.h"

#include <cstdint>
#include <string>

namespace occ {

// What the network did for a row: the transport's counters since the rank's last row, with what
// the frame's culling or display recorded about its messages.
struct NetFigures {
    uint64_t bytes[3] = {}, messages[3] = {};  // camera, delta, end-of-frame messages sent
    uint64_t full_pvs_bytes = 0;               // what full visible sets would have weighed
    double latency_ms = -1;                    // the display's rows only: camera sent -> frame drawn
    int64_t latency_frames = -1;
    double ms_wait = 0;                        // waiting for messages
    uint64_t visible_hash = 0;
    uint64_t added = 0, removed = 0, changed = 0;  // entries of the frame's visible-set message
    int32_t partition = -1;                        // display rows: the partition drawn
    uint64_t composite_bytes = 0;                  // sort-last pixels sent
    double ms_composite = 0;
};

// One frame of a display: drawing, and with DisplayColumns' passes its measurements against the
// full-detail frame.
struct DisplayStats {
    double ms_draw = 0;       // drawing the pipeline's frame, uploads included, until GL finished
    double ms_exact = 0;      // the full-detail pass and the comparisons (not part of a frame's cost)
    uint64_t uploaded_bytes = 0;
    uint64_t draw_calls = 0;  // multi-draw calls (each draws many objects)
    // With DisplayColumns::exact:
    uint64_t exact_visible = 0;   // objects with at least one pixel in the full-detail item buffer
    uint64_t false_culls = 0;     // of those, objects the pipeline left out of the PVS (must be 0)
    uint64_t exact_occluded = 0;  // frustum objects whose box is behind the full-detail depth everywhere
    double culling_accuracy = 0;  // percent: objects we culled by occlusion / exact_occluded (100 if 0 / 0)
    // The exact visible set's churn against the previous frame displayed (compare pvs_added and
    // pvs_removed: the least any PVS must change).
    uint64_t exact_added = 0;
    uint64_t exact_removed = 0;
    // With DisplayColumns::reference (src/render/picture_metrics.h says what each measures):
    double psnr_db = 0;               // RGB, against the full-detail picture; 100 for identical pictures
    double changed_pixel_share = 0;   // percent of pixels that differ in any channel
    double mse = 0;                   // mean squared error per byte: runs pool PSNR from its mean
    double perceptible_share = 0;     // percent of pixels changed by a CIEDE2000 above 2
    double ssim = 1;                  // scikit-image's structural_similarity of the RGB pictures
    double bound_p99_px = 0;          // 99th percentile of the changed pixels' distance to their item
    uint64_t bound_pixels = 0;        // changed pixels measured by the bound check
    uint64_t bound_beyond_tau = 0;    // of those, farther than tau from their item in the reference
};

// Which display columns a run's CSV has (a run that draws): the drawing's always, the exact
// pass's and the reference's when measured.
struct DisplayColumns {
    bool exact = false;
    bool reference = false;
};

struct FrameRecord {
    int32_t rank = 0;
    bool displayed = false;  // `display` holds this rank's drawing of the frame
    double ms_frame = 0;     // rank 0: wall time of the frame (the run's frame time; no column)
    FrameStats stats;
    NetFigures net;
    DisplayStats display;
};

// Every field of a record in wire order (docs/protocol.md, the report), for the encoder and the
// decoder: visit(field) with int32_t&, bool&, uint64_t&, int64_t& or double&. A new figure is
// added here and in its CSV column, nowhere else.
template <class Record, class Visit>
void visitRecordFields(Record& r, Visit&& visit) {
    visit(r.rank);
    visit(r.displayed);
    visit(r.ms_frame);
    auto& s = r.stats;
    for (auto* v : {&s.frame, &s.objects_in_frustum, &s.objects_occluded, &s.objects_visible, &s.objects_drawn,
                    &s.aos_size, &s.occluder_triangles, &s.active_triangles, &s.active_vertices,
                    &s.resident_triangles, &s.resident_vertices, &s.budget_vertices, &s.streamed_triangles,
                    &s.streamed_vertices, &s.streamed_bytes, &s.moved_bytes, &s.reformed_triangles, &s.bus_h2d_bytes,
                    &s.bus_d2h_bytes, &s.pvs_hash, &s.pvs_added, &s.pvs_removed})
        visit(*v);
    for (auto& ms : s.ms) visit(ms);
    visit(s.ms_total);
    auto& n = r.net;
    for (auto& b : n.bytes) visit(b);
    for (auto& m : n.messages) visit(m);
    visit(n.full_pvs_bytes);
    visit(n.latency_ms);
    visit(n.latency_frames);
    visit(n.ms_wait);
    visit(n.visible_hash);
    visit(n.added);
    visit(n.removed);
    visit(n.changed);
    visit(n.partition);
    visit(n.composite_bytes);
    visit(n.ms_composite);
    auto& d = r.display;
    visit(d.ms_draw);
    visit(d.ms_exact);
    for (auto* v : {&d.uploaded_bytes, &d.draw_calls, &d.exact_visible, &d.false_culls, &d.exact_occluded})
        visit(*v);
    visit(d.culling_accuracy);
    visit(d.exact_added);
    visit(d.exact_removed);
    visit(d.psnr_db);
    visit(d.changed_pixel_share);
    visit(d.mse);
    visit(d.perceptible_share);
    visit(d.ssim);
    visit(d.bound_p99_px);
    visit(d.bound_pixels);
    visit(d.bound_beyond_tau);
}

// The CSV columns, each with a leading comma: the messages' (after frameStatsHeader()) and the
// display's for these columns.
std::string netFiguresHeader();
std::string netFiguresRow(const NetFigures& n);
std::string displayStatsHeader(const DisplayColumns& columns);
std::string displayStatsRow(const DisplayStats& d, const DisplayColumns& columns);

}  // namespace occ
