// SPDX-License-Identifier: MIT
#include "pipeline/frame_record.h"

#include "util/number_format.h"

#include <cstdio>

namespace occ {

std::string netFiguresHeader() {
    return ",bytes_camera,bytes_delta,bytes_eof,msgs_camera,msgs_delta,msgs_eof,full_pvs_bytes,delta_added,"
           "delta_removed,delta_changed,latency_ms,latency_frames,ms_wait,visible_hash,partition,bytes_composite,"
           "ms_composite";
}

std::string netFiguresRow(const NetFigures& c) {
    char b[640];
    std::snprintf(b, sizeof b, ",%llu,%llu,%llu,%llu,%llu,%llu,%llu,%llu,%llu,%llu,%s,%s,%.3f,%016llx,%s,%llu,%.3f",
                  static_cast<unsigned long long>(c.bytes[0]), static_cast<unsigned long long>(c.bytes[1]),
                  static_cast<unsigned long long>(c.bytes[2]), static_cast<unsigned long long>(c.messages[0]),
                  static_cast<unsigned long long>(c.messages[1]), static_cast<unsigned long long>(c.messages[2]),
                  static_cast<unsigned long long>(c.full_pvs_bytes), static_cast<unsigned long long>(c.added),
                  static_cast<unsigned long long>(c.removed), static_cast<unsigned long long>(c.changed),
                  c.latency_ms < 0 ? "" : fixed(c.latency_ms, 3).c_str(),
                  c.latency_frames < 0 ? "" : std::to_string(c.latency_frames).c_str(), c.ms_wait,
                  static_cast<unsigned long long>(c.visible_hash),
                  c.partition < 0 ? "" : std::to_string(c.partition).c_str(),
                  static_cast<unsigned long long>(c.composite_bytes), c.ms_composite);
    return b;
}

std::string displayStatsHeader(const DisplayColumns& columns) {
    std::string h = ",ms_draw,uploaded_bytes,draw_calls";
    if (columns.exact || columns.reference) h += ",ms_exact";
    if (columns.exact) h += ",exact_visible,false_culls,exact_occluded,culling_accuracy,exact_added,exact_removed";
    if (columns.reference)
        h += ",psnr_db,changed_pixel_share,mse,perceptible_share,ssim,bound_p99_px,bound_pixels,bound_beyond_tau";
    return h;
}

std::string displayStatsRow(const DisplayStats& s, const DisplayColumns& columns) {
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict, its bug 105329) on "," + string.
    std::string r;
    const auto add = [&r](const std::string& v) {
        r += ',';
        r += v;
    };
    add(fixed(s.ms_draw, 3));
    add(std::to_string(s.uploaded_bytes));
    add(std::to_string(s.draw_calls));
    if (columns.exact || columns.reference) add(fixed(s.ms_exact, 3));
    if (columns.exact) {
        add(std::to_string(s.exact_visible));
        add(std::to_string(s.false_culls));
        add(std::to_string(s.exact_occluded));
        add(fixed(s.culling_accuracy, 2));
        add(std::to_string(s.exact_added));
        add(std::to_string(s.exact_removed));
    }
    if (columns.reference) {
        add(fixed(s.psnr_db, 2));
        add(fixed(s.changed_pixel_share, 3));
        add(fixed(s.mse, 6));
        add(fixed(s.perceptible_share, 3));
        add(fixed(s.ssim, 6));
        add(fixed(s.bound_p99_px, 2));
        add(std::to_string(s.bound_pixels));
        add(std::to_string(s.bound_beyond_tau));
    }
    return r;
}

}  // namespace occ
