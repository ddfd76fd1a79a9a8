// SPDX-License-Identifier: MIT
#include "device_test_support.h"
#include "lod_hysteresis.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

namespace occ::k {
namespace {

using test::toDevice;
using test::toHost;
using LodHysteresis = test::DeviceTest;

// Objects 0..n-1, one mesh each of 100 vertices whose map is maps[v] = 2 v (easy to check).
struct Fixture {
    std::vector<ObjectInfo> objects;
    std::vector<uint64_t> map_first;
    std::vector<uint32_t> maps;
    explicit Fixture(uint32_t n) {
        for (uint32_t i = 0; i < n; ++i) {
            ObjectInfo o{};
            o.mesh = i;
            o.vertex_count = 100;
            o.q = 1;
            objects.push_back(o);
            map_first.push_back(maps.size());
            for (uint32_t v = 0; v <= 100; ++v) maps.push_back(2 * v);
        }
    }
};

struct Result {
    std::vector<uint32_t> vertices, triangles;
};

Result run(const Fixture& f, const std::vector<uint32_t>& ids, const std::vector<uint32_t>& eq1,
           const std::vector<LodEntry>& previous, float hysteresis, double budget) {
    std::vector<uint32_t> tc(eq1.size());
    for (size_t j = 0; j < eq1.size(); ++j) tc[j] = 2 * eq1[j];
    DeviceArray<ObjectInfo> objects = toDevice(f.objects);
    DeviceArray<uint64_t> map_first = toDevice(f.map_first);
    DeviceArray<uint32_t> maps = toDevice(f.maps);
    DeviceArray<uint32_t> d_ids = toDevice(ids), vc = toDevice(eq1), d_tc = toDevice(tc);
    DeviceArray<LodEntry> d_previous = toDevice(previous);
    LodHysteresisScratch scratch;
    keepSimilarLods(d_ids.ptr(), uint32_t(ids.size()), d_previous.ptr(), uint32_t(previous.size()), hysteresis, budget,
                    objects.ptr(), map_first.ptr(), maps.ptr(), vc.ptr(), d_tc.ptr(), scratch);
    return {toHost(vc, ids.size()), toHost(d_tc, ids.size())};
}

// The host reference: the rule as Pipeline applied it before it moved to the device.
std::vector<uint32_t> reference(const std::vector<uint32_t>& ids, const std::vector<uint32_t>& eq1,
                                const std::vector<LodEntry>& previous, float hysteresis, double budget) {
    std::vector<uint32_t> vc = eq1;
    double total = 0, chosen = 0;
    std::vector<std::pair<uint32_t, uint32_t>> raised;
    size_t i = 0;
    for (uint32_t j = 0; j < ids.size(); ++j) {
        const uint32_t v = vc[j];
        chosen += v;
        while (i < previous.size() && previous[i].object < ids[j]) ++i;
        if (v > 0 && i < previous.size() && previous[i].object == ids[j]) {
            const uint32_t p = previous[i].vertices;
            if (p > 0 && p != v && std::abs(double(v) - double(p)) <= hysteresis * double(p)) {
                vc[j] = p;
                if (p > v) raised.emplace_back(p - v, j);
            }
        }
        total += vc[j];
    }
    const double limit = std::max(budget, chosen);
    if (total > limit) {
        std::sort(raised.begin(), raised.end(), std::greater<>());
        for (const auto& [extra, j] : raised) {
            if (total <= limit) break;
            vc[j] = eq1[j];
            total -= extra;
        }
    }
    return vc;
}

TEST_F(LodHysteresis, KeepsLastFramesCountWithinTheHysteresisOnly) {
    const Fixture f(5);
    // Object 0: 50 -> 54 (within 10 %, kept 50); 1: 50 -> 60 (not within, 60); 2: new; 3: 0 (not
    // drawn stays 0); 4: was not drawn (p = 0), takes Eq. 1's.
    const std::vector<uint32_t> ids{0, 1, 2, 3, 4};
    const std::vector<uint32_t> eq1{54, 60, 30, 0, 20};
    const std::vector<LodEntry> previous{{0, 50}, {1, 50}, {3, 40}, {4, 0}};
    const Result r = run(f, ids, eq1, previous, 0.1f, 1000);
    EXPECT_EQ(r.vertices, (std::vector<uint32_t>{50, 60, 30, 0, 20}));
    EXPECT_EQ(r.triangles, (std::vector<uint32_t>{100, 120, 60, 0, 40}));  // maps[v] = 2 v where changed
}

TEST_F(LodHysteresis, RaisesOverTheBudgetAreGivenBackLargestFirst) {
    const Fixture f(4);
    // Eq. 1 spends exactly the budget 160; keeping the old counts would raise 0 by 4, 1 by 2 and
    // 2 by 4 (total 170). Raises go back largest first, equal ones larger index first, while the
    // total is above the budget: 170 - 4 (object 2) = 166, - 4 (object 0) = 162, - 2 (object 1)
    // = 160: all three.
    const std::vector<uint32_t> ids{0, 1, 2, 3};
    const std::vector<uint32_t> eq1{40, 40, 40, 40};
    const std::vector<LodEntry> previous{{0, 44}, {1, 42}, {2, 44}, {3, 40}};
    Result r = run(f, ids, eq1, previous, 0.1f, 160);
    EXPECT_EQ(r.vertices, (std::vector<uint32_t>{40, 40, 40, 40}));
    // With a budget of 164, giving back object 2 (166) and then object 0 (162) fits.
    r = run(f, ids, eq1, previous, 0.1f, 164);
    EXPECT_EQ(r.vertices, (std::vector<uint32_t>{40, 42, 40, 40}));
    EXPECT_EQ(r.triangles, (std::vector<uint32_t>{80, 84, 80, 80}));
}

TEST_F(LodHysteresis, MatchesTheHostRuleOnRandomFrames) {
    std::mt19937 rng(12);
    const Fixture f(300);
    for (int round = 0; round < 50; ++round) {
        std::vector<uint32_t> ids, eq1;
        std::vector<LodEntry> previous;
        for (uint32_t i = 0; i < 300; ++i) {
            if (rng() % 3 == 0) ids.push_back(i), eq1.push_back(rng() % 5 == 0 ? 0 : 1 + rng() % 100);
            if (rng() % 3 == 0) previous.push_back({i, rng() % 6 == 0 ? 0u : uint32_t(1 + rng() % 100)});
        }
        const double sum = std::accumulate(eq1.begin(), eq1.end(), 0.0);
        const double budget = sum * (0.9 + 0.2 * double(rng() % 100) / 100.0);
        const float hysteresis = 0.05f + 0.3f * float(rng() % 100) / 100.0f;
        EXPECT_EQ(run(f, ids, eq1, previous, hysteresis, budget).vertices,
                  reference(ids, eq1, previous, hysteresis, budget))
            << "round " << round;
    }
}

TEST_F(LodHysteresis, NoObjectsIsNothingToDo) {
    const Fixture f(1);
    EXPECT_TRUE(run(f, {}, {}, {{0, 10}}, 0.1f, 100).vertices.empty());
}

}  // namespace
}  // namespace occ::k
