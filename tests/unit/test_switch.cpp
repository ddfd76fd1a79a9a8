// SPDX-License-Identifier: MIT
// The occlusion-switch roles over in-process ranks (threads): a live run, whose cameras come one
// by one from the display as a window's do, culls exactly what the recorded run of the same
// cameras culls, on 2 and 3 ranks, and ends every rank when the display stops.
#include "import/plant.h"
#include "prep/prepare.h"
#include "roles/occlusion_switch.h"
#include "scene/csv.h"
#include "test_support.h"
#include "view/camera_path.h"

#include <gtest/gtest.h>

#include <memory>
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

// Runs every rank of `size` on a thread of its own; rank 0's rows and summary come back.
std::string runAll(int size, const roles::RunOptions& run, roles::RunSummary& summary) {
    InProcessHub hub(size);
    std::vector<std::unique_ptr<Transport>> ends;
    for (int r = 0; r < size; ++r) ends.push_back(hub.connect(r));
    std::vector<std::string> rows(size), errors(size);
    std::vector<roles::RunSummary> sums(size);
    std::vector<std::thread> threads;
    for (int r = 0; r < size; ++r)
        threads.emplace_back([&, r] {
            try {
                rows[r] = roles::runRanks(*ends[r], *fixture().file, options(), run, sums[r]);
            } catch (const std::exception& e) {
                errors[r] = e.what();
            }
        });
    for (std::thread& t : threads) t.join();
    for (int r = 0; r < size; ++r) EXPECT_EQ(errors[r], "") << "rank " << r;
    summary = sums[0];
    return rows[0];
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

}  // namespace
}  // namespace occ
