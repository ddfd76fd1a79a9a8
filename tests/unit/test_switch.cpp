// SPDX-License-Identifier: MIT
// The occlusion-switch roles over in-process ranks (threads): a live run, whose cameras come one
// by one from the display as a window's do, culls exactly what the recorded run of the same
// cameras culls, on 2 and 3 ranks, and ends every rank when the display stops.
#include "import/plant.h"
#include "prep/prepare.h"
#include "roles/occlusion_switch.h"
#include "scene/csv.h"
#include "scene/errors.h"
#include "test_support.h"
#include "view/camera_path.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace occ {
namespace {

struct SwitchFixture {
    std::unique_ptr<OssFile> file;
    std::vector<CameraPose> cameras;
    SwitchFixture() {
        const std::string path = (test::scratchDir() / "switch_plant.oss").string();
        writeOss(path, prepareScene(generatePlant({300, 9}), PrepOptions{}));
        file = std::make_unique<OssFile>(OssFile::open(path));
        cameras = walkPath(pathSceneOf(*file), 14, 3, Avoid::triangles).cameras;
    }
};

const SwitchFixture& fixture() {
    static const SwitchFixture f;
    return f;
}

PipelineOptions options() {
    PipelineOptions o;
    o.width = 128;
    o.height = 96;
    o.budget_share = 0.2;
    o.pvs_occluder_lag = 0;  // what the layout has
    return o;
}

// Runs every rank of `size` on a thread of its own; rank 0's rows (its records as the stats CSV
// writes them) and summary come back.
std::string runAll(int size, const roles::RunOptions& run, roles::RunSummary& summary) {
    InProcessHub hub(size);
    std::vector<std::unique_ptr<Transport>> ends;
    for (int r = 0; r < size; ++r) ends.push_back(hub.connect(r));
    std::vector<std::vector<FrameRecord>> records(size);
    std::vector<std::string> errors(size);
    std::vector<roles::RunSummary> sums(size);
    std::vector<std::thread> threads;
    for (int r = 0; r < size; ++r)
        threads.emplace_back([&, r] {
            try {
                records[r] = roles::runRanks(*ends[r], *fixture().file, options(), run, sums[r]);
            } catch (const std::exception& e) {
                errors[r] = e.what();
            }
        });
    for (std::thread& t : threads) t.join();
    for (int r = 0; r < size; ++r) EXPECT_EQ(errors[r], "") << "rank " << r;
    summary = sums[0];
    return roles::rankStatsRows(records[0], roles::RankLayout(size), run);
}

// rank -> frame -> visible_hash of the merged rows.
std::vector<std::string> hashes(const std::string& rows, const std::string& header) {
    const std::vector<std::string> names = csvFields(header, "header");
    size_t hash = 0, rank = 0;
    for (size_t i = 0; i < names.size(); ++i) {
        if (names[i] == "visible_hash") hash = i;
        if (names[i] == "rank") rank = i;
    }
    std::vector<std::string> out;
    std::istringstream lines(rows);
    for (std::string line; std::getline(lines, line);) {
        const std::vector<std::string> f = csvFields(line, "row");
        out.push_back(f.at(rank) + ":" + f.at(2) + ":" + f.at(hash));
    }
    return out;
}

class LiveSwitch : public ::testing::TestWithParam<int> {};

TEST_P(LiveSwitch, CullsWhatTheRecordedRunCullsAndStopsEveryRank) {
    const int size = GetParam();
    const std::vector<CameraPose>& cameras = fixture().cameras;
    ASSERT_GE(cameras.size(), 10u);

    roles::RunOptions recorded;
    recorded.cameras = cameras;
    roles::RunSummary recorded_sum;
    const std::string recorded_rows = runAll(size, recorded, recorded_sum);

    roles::RunOptions live;
    live.live = true;
    std::vector<uint64_t> asked;
    uint64_t idles = 0;
    live.next_camera = [&](uint64_t f, CameraPose& pose) {
        asked.push_back(f);
        if (f >= cameras.size()) return false;
        pose = cameras[f];
        return true;
    };
    live.idle = [&] { ++idles; };
    roles::RunSummary live_sum;
    const std::string live_rows = runAll(size, live, live_sum);

    EXPECT_EQ(live_sum.frames, cameras.size());
    // Frame f's camera is asked once, in order, and the one past the end stops the run.
    ASSERT_EQ(asked.size(), cameras.size() + 1);
    for (size_t f = 0; f < asked.size(); ++f) EXPECT_EQ(asked[f], f);
    EXPECT_EQ(live_sum.latency_frames, 1u);  // the camera of f + 1 leaves before f is drawn
    const std::string header = roles::rankStatsHeader(recorded);
    const std::vector<std::string> a = hashes(recorded_rows, header), b = hashes(live_rows, header);
    EXPECT_EQ(a.size(), cameras.size() * 2);  // each frame: the display's row and its culling rank's
    EXPECT_EQ(a, b);
    // A live switch rank also sends its last delta to the other, which cannot know it is the last.
    EXPECT_GE(live_sum.bytes_delta, recorded_sum.bytes_delta);
    (void)idles;  // how often the display waited depends on the threads' timing
}

INSTANTIATE_TEST_SUITE_P(Ranks, LiveSwitch, ::testing::Values(2, 3));

TEST(LiveSwitchStop, AStopBeforeTheFirstFrameEndsEveryRankWithNoFrames) {
    roles::RunOptions live;
    live.live = true;
    live.next_camera = [](uint64_t, CameraPose&) { return false; };
    roles::RunSummary sum;
    const std::string rows = runAll(3, live, sum);
    EXPECT_EQ(sum.frames, 0u);
    EXPECT_EQ(rows, "");
}

// 2 + P ranks in-process: the switch culls what 3 ranks cull, each display rank gets exactly its
// partition's part of every frame's visible set.
TEST(SortLast, DisplayRanksTogetherShowTheSwitchsVisibleSets) {
    const std::vector<CameraPose>& cameras = fixture().cameras;
    roles::RunOptions run;
    run.cameras = cameras;
    roles::RunSummary three, five;
    const std::string rows3 = runAll(3, run, three);
    const std::string rows5 = runAll(5, run, five);
    const std::string header = roles::rankStatsHeader(run);
    const std::vector<std::string> names = csvFields(header, "header");
    const auto col = [&](const char* name) {
        return size_t(std::find(names.begin(), names.end(), name) - names.begin());
    };
    std::map<std::string, std::vector<std::vector<std::string>>> by_frame3, by_frame5;
    const auto split = [&](const std::string& rows, auto& out) {
        std::istringstream lines(rows);
        for (std::string line; std::getline(lines, line);) {
            std::vector<std::string> f = csvFields(line, "row");
            out[f.at(2)].push_back(std::move(f));
        }
    };
    split(rows3, by_frame3);
    split(rows5, by_frame5);
    ASSERT_EQ(by_frame5.size(), cameras.size());
    for (const auto& [frame, rows] : by_frame5) {
        ASSERT_EQ(rows.size(), 4u) << "frame " << frame;  // its culler and three display ranks
        const auto& rows_3 = by_frame3.at(frame);
        uint64_t visible = 0, visible_3 = 0;
        for (const auto& r : rows) {
            if (r[col("role")] == "or+hc") {
                for (const auto& q : rows_3) {
                    if (q[col("role")] == "or+hc") {
                        EXPECT_EQ(r[col("visible_hash")], q[col("visible_hash")]);
                    }
                }
            } else {
                EXPECT_EQ(r[col("partition")], std::to_string(roles::RankLayout(5).partitionOf(std::stoi(r[0]))));
                visible += std::stoull(r[col("objects_visible")]);
            }
        }
        for (const auto& q : rows_3)
            if (q[col("role")] == "rvg") visible_3 = std::stoull(q[col("objects_visible")]);
        EXPECT_EQ(visible, visible_3) << "frame " << frame;
    }
    EXPECT_EQ(five.displays, 3);
    EXPECT_EQ(five.objects_visible, three.objects_visible);
    EXPECT_EQ(five.active_triangles, three.active_triangles);
    ASSERT_EQ(five.partition_triangles.size(), 3u);
}

TEST(SortLast, PartitionsAreDeterministicSpatialAndBalancedByTriangles) {
    const OssFile& file = *fixture().file;
    for (const auto& [parts, cells] : std::vector<std::pair<int, int>>{{1, 1}, {2, 1}, {3, 1}, {5, 1}, {3, 8}, {4, 16}}) {
        const std::vector<uint16_t> a = roles::partitionObjects(file, parts, cells),
                                    b = roles::partitionObjects(file, parts, cells);
        EXPECT_EQ(a, b);
        ASSERT_EQ(a.size(), file.objectCount());
        std::vector<double> triangles(size_t(parts), 0.0);
        double total = 0;
        for (uint32_t i = 0; i < a.size(); ++i) {
            ASSERT_LT(a[i], parts);
            const double t = std::max(1.0, double(file.meshRecords()[file.objects()[i].mesh].triangle_count));
            triangles[a[i]] += t;
            total += t;
        }
        // Balanced up to the largest object: no part far from 1 / parts of the triangles.
        for (double t : triangles) EXPECT_NEAR(t / total, 1.0 / parts, 0.5 / parts) << parts << " parts, " << cells;
    }
    // One cell per part: a part is one region, so two parts' box centres do not interleave along
    // the first cut (the widest axis of the scene).
    const std::vector<uint16_t> two = roles::partitionObjects(file, 2);
    int axis = 0;
    glm::vec3 lo(INFINITY), hi(-INFINITY);
    const auto centre = [&](uint32_t i) {
        const auto& o = file.objects()[i];
        return 0.5f * (glm::vec3(o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]) +
                       glm::vec3(o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]));
    };
    for (uint32_t i = 0; i < two.size(); ++i) lo = glm::min(lo, centre(i)), hi = glm::max(hi, centre(i));
    const glm::vec3 e = hi - lo;
    axis = e.x >= e.y && e.x >= e.z ? 0 : e.y >= e.z ? 1 : 2;
    float max0 = -INFINITY, min1 = INFINITY;
    for (uint32_t i = 0; i < two.size(); ++i)
        if (two[i] == 0) max0 = std::max(max0, centre(i)[axis]);
        else min1 = std::min(min1, centre(i)[axis]);
    EXPECT_LE(max0, min1);
    EXPECT_THROW(roles::partitionObjects(file, 0), std::invalid_argument);
    EXPECT_THROW(roles::partitionObjects(file, 2, 0), std::invalid_argument);
}

TEST(SortLast, LayoutsOfTwoPlusPRanks) {
    const roles::RankLayout five(5);
    EXPECT_EQ(five.displays(), 3);
    EXPECT_EQ(five.displayRanks(), (std::vector<int>{0, 3, 4}));
    EXPECT_EQ(five.cullingRanks(), (std::vector<int>{1, 2}));
    EXPECT_EQ(five.partitionOf(4), 2);
    EXPECT_EQ(five.partitionOf(2), -1);
    EXPECT_STREQ(five.roleOf(3), "rvg");
    EXPECT_EQ(roles::RankLayout(3).displays(), 1);
    EXPECT_THROW(roles::RankLayout(roles::RankLayout::kMaxRanks + 1), UsageError);
    EXPECT_THROW(roles::RankLayout(0), UsageError);
}

// In-process compositing: the first rank gets the nearest fragment per pixel; equal depths go
// to the lower object.
TEST(SortLast, InProcessCompositeKeepsTheNearestAndTheLowerObjectOnTies) {
    InProcessHub hub(4);
    std::vector<std::unique_ptr<Transport>> ends;
    for (int r = 0; r < 4; ++r) ends.push_back(hub.connect(r));
    const std::vector<int> group{0, 2, 3};
    std::vector<std::vector<DepthPixel>> images = {
        {{0.5f, 7, 1}, {1.0f, 0, 9}, {0.3f, 9, 1}},
        {{0.4f, 3, 2}, {1.0f, 0, 9}, {0.3f, 4, 2}},
        {{0.6f, 5, 3}, {0.9f, 6, 3}, {0.7f, 1, 3}},
    };
    std::vector<std::thread> threads;
    for (size_t m = 1; m < group.size(); ++m)
        threads.emplace_back([&, m] { ends[size_t(group[m])]->composite(group, images[m], std::chrono::seconds(5), {}); });
    ends[0]->composite(group, images[0], std::chrono::seconds(5), {});
    for (std::thread& t : threads) t.join();
    EXPECT_EQ(images[0][0].item, 3u);
    EXPECT_EQ(images[0][1].item, 6u);
    EXPECT_EQ(images[0][2].item, 4u);  // a tie at 0.3: the lower object
    EXPECT_GT(ends[2]->counters().composite_bytes_sent, 0u);
    threads.clear();
    for (auto& e : ends) threads.emplace_back([&e] { e->finish(std::chrono::seconds(5)); });
    for (std::thread& t : threads) t.join();
}

// A member that comes late: the first rank's wait calls `idle` meanwhile (a window keeps
// answering) and still gets the composite.
TEST(SortLast, TheWaitForALateMemberCallsIdle) {
    InProcessHub hub(2);
    std::vector<std::unique_ptr<Transport>> ends;
    for (int r = 0; r < 2; ++r) ends.push_back(hub.connect(r));
    const std::vector<int> group{0, 1};
    std::vector<DepthPixel> first = {{0.5f, 7, 1}, {0.2f, 2, 1}}, second = {{0.4f, 3, 2}, {0.9f, 4, 2}};
    std::thread late([&] {
        std::this_thread::sleep_for(std::chrono::milliseconds(100));
        ends[1]->composite(group, second, std::chrono::seconds(5), {});
    });
    int idles = 0;
    ends[0]->composite(group, first, std::chrono::seconds(5), [&] { ++idles; });
    late.join();
    EXPECT_GE(idles, 10);
    EXPECT_EQ(first[0].item, 3u);
    EXPECT_EQ(first[1].item, 2u);
    std::vector<std::thread> threads;
    for (auto& e : ends) threads.emplace_back([&e] { e->finish(std::chrono::seconds(5)); });
    for (std::thread& t : threads) t.join();
}

}  // namespace
}  // namespace occ
