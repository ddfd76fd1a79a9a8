// SPDX-License-Identifier: MIT
#include "pipeline/frame_stats.h"

#include <sstream>

namespace occ {

const char* stageName(Stage s) {
    static const char* names[] = {"frustum_cull", "occluder_select", "depth_raster", "hzm_build", "hzm_test",
                                  "lod_select",   "scan",            "stream_collect", "defragment", "reform"};
    static_assert(sizeof(names) / sizeof(names[0]) == size_t(Stage::Count));
    return names[uint32_t(s)];
}

void BusWindow::take(FrameStats& s) {
    const k::BusCounters now = k::busCounters();
    s.bus_h2d_bytes = now.h2d_bytes - last_.h2d_bytes;
    s.bus_d2h_bytes = now.d2h_bytes - last_.d2h_bytes;
    last_ = now;
}

Churn setChurn(const std::vector<uint32_t>& before, const std::vector<uint32_t>& now) {
    Churn c;
    size_t i = 0, j = 0;
    while (i < before.size() || j < now.size()) {
        if (j == now.size() || (i < before.size() && before[i] < now[j])) {
            ++c.removed;
            ++i;
        } else if (i == before.size() || now[j] < before[i]) {
            ++c.added;
            ++j;
        } else {
            ++i;
            ++j;
        }
    }
    return c;
}

std::string frameStatsHeader() {
    std::string h =
        "frame,objects_in_frustum,objects_occluded,objects_visible,objects_drawn,aos_size,occluder_triangles,"
        "active_triangles,active_vertices,resident_triangles,resident_vertices,budget_vertices,streamed_triangles,streamed_vertices,streamed_bytes,"
        "moved_bytes,reformed_triangles,bus_h2d_bytes,bus_d2h_bytes,pvs_hash,pvs_added,pvs_removed";
    for (uint32_t s = 0; s < uint32_t(Stage::Count); ++s) h += std::string(",ms_") + stageName(Stage(s));
    return h + ",ms_total";
}

std::string frameStatsRow(const FrameStats& s) {
    std::ostringstream o;
    o << s.frame << ',' << s.objects_in_frustum << ',' << s.objects_occluded << ',' << s.objects_visible << ','
      << s.objects_drawn << ',' << s.aos_size << ',' << s.occluder_triangles << ',' << s.active_triangles << ','
      << s.active_vertices << ',' << s.resident_triangles << ',' << s.resident_vertices << ',' << s.budget_vertices << ',' << s.streamed_triangles << ',' << s.streamed_vertices
      << ',' << s.streamed_bytes << ',' << s.moved_bytes << ',' << s.reformed_triangles << ',' << s.bus_h2d_bytes << ',' << s.bus_d2h_bytes << ',';
    char hash[17];
    std::snprintf(hash, sizeof hash, "%016llx", static_cast<unsigned long long>(s.pvs_hash));
    o << hash << ',' << s.pvs_added << ',' << s.pvs_removed;
    o.setf(std::ios::fixed);
    o.precision(3);
    for (double ms : s.ms) o << ',' << ms;
    o << ',' << s.ms_total;
    return o.str();
}

}  // namespace occ
