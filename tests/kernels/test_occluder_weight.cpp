// SPDX-License-Identifier: MIT
#include "occluder_weight.h"

#include "device_test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace occ::k {
namespace {

using test::filledDevice;
using test::toDevice;
using test::toHost;

using OccluderWeight = test::DeviceTest;
using SelectTopK = test::DeviceTest;
using SelectPvsOccluders = test::DeviceTest;

ObjectInfo occluder(const glm::vec3& lo, const glm::vec3& hi, const glm::vec3& normal) {
    ObjectInfo o{};
    o.aabb = {lo, hi};
    o.occluder_normal = normal;
    return o;
}

// Eye at the origin looking down -z; the rest of the camera is not read by occluderWeight.
Camera eyeAtOrigin() {
    Camera c{};
    c.view_proj = glm::mat4(1);
    c.eye = {0, 0, 0};
    c.forward = {0, 0, -1};
    return c;
}

std::vector<float> weights(const std::vector<ObjectInfo>& objects, const std::vector<uint32_t>& cos,
                           const std::vector<uint8_t>& in_frustum, const Camera& camera) {
    const DeviceArray<ObjectInfo> o = toDevice(objects);
    const DeviceArray<uint32_t> c = toDevice(cos);
    const DeviceArray<uint8_t> f = toDevice(in_frustum);
    DeviceArray<float> w(cos.size());
    occluderWeight(o.ptr(), c.ptr(), uint32_t(cos.size()), f.ptr(), camera, w.ptr());
    return toHost(w);
}

TEST_F(OccluderWeight, HandComputedEq3) {
    const std::vector<ObjectInfo> objects = {
        // 2x2x2 box 10 ahead, facing the eye: 8 * 1 / 10.
        occluder({-1, -1, -12}, {1, 1, -10}, {0, 0, 1}),
        // Seen edge-on (N across E): 0.
        occluder({2, 0, -5}, {4, 1, -4}, {1, 0, 0}),
        // Unit cube whose nearest point (3, 4, 0) is 5 away, N . E = -0.8: 1 * 0.8 / 5.
        occluder({3, 4, -1}, {4, 5, 0}, {0, 0.6f, 0.8f}),
        // The eye is inside: D = 1e-3 of the diagonal sqrt(4 + 16 + 16) = 6, so 32 / 0.006.
        occluder({-1, -2, -2}, {1, 2, 2}, {0, 0, 1}),
        // Like object 0 but outside the frustum: 0.
        occluder({-1, -1, -12}, {1, 1, -10}, {0, 0, 1}),
        // Flat (no thickness in z): no volume, 0.
        occluder({-1, -1, -10}, {1, 1, -10}, {0, 0, 1}),
        // Inverted in x (min > max): flat, 0.
        occluder({1, -1, -12}, {-1, 1, -10}, {0, 0, 1}),
    };
    const std::vector<uint8_t> in_frustum = {1, 1, 1, 1, 0, 1, 1};
    // Candidates in a different order than the objects: weight[j] belongs to cos[j].
    const std::vector<uint32_t> cos = {3, 0, 6, 2, 5, 1, 4};
    const std::vector<float> w = weights(objects, cos, in_frustum, eyeAtOrigin());
    const std::vector<float> expected = {32 / 0.006f, 0.8f, 0, 0.16f, 0, 0, 0};
    ASSERT_EQ(w.size(), expected.size());
    for (size_t j = 0; j < w.size(); ++j) EXPECT_NEAR(w[j], expected[j], 1e-5f * expected[j]) << "candidate " << j;
}

TEST_F(OccluderWeight, CloserAndLargerWins) {
    const std::vector<ObjectInfo> objects = {
        occluder({-1, -1, -12}, {1, 1, -10}, {0, 0, 1}),
        occluder({-1, -1, -22}, {1, 1, -20}, {0, 0, 1}),
        occluder({-2, -2, -22}, {2, 2, -20}, {0, 0, 1}),
        // Just touching the eye: D is the epsilon, not 0.
        occluder({-1, -1, -2}, {1, 1, 0}, {0, 0, 1}),
    };
    const std::vector<float> w = weights(objects, {0, 1, 2, 3}, {1, 1, 1, 1}, eyeAtOrigin());
    EXPECT_GT(w[0], w[1]);
    EXPECT_GT(w[2], w[0]);
    EXPECT_TRUE(std::isfinite(w[3]));
    EXPECT_GT(w[3], w[2]);
}

TEST_F(OccluderWeight, EmptyInput) { occluderWeight(nullptr, nullptr, 0, nullptr, eyeAtOrigin(), nullptr); }

std::vector<uint32_t> topK(const std::vector<uint32_t>& cos, const std::vector<float>& weight, uint32_t k) {
    const DeviceArray<uint32_t> c = toDevice(cos);
    const DeviceArray<float> w = toDevice(weight);
    DeviceArray<uint32_t> aos(k);
    DeviceArray<uint64_t> keys;
    const uint32_t n = selectTopK(c.ptr(), w.ptr(), uint32_t(cos.size()), k, aos.ptr(), keys);
    EXPECT_LE(n, k);
    return toHost(aos, n);
}

TEST_F(SelectTopK, DecreasingWeightTiesByLowerId) {
    const std::vector<uint32_t> cos = {7, 3, 5, 1, 9, 2};
    const std::vector<float> weight = {2, 5, 2, 0, 5, 4};
    EXPECT_EQ(topK(cos, weight, 3), (std::vector<uint32_t>{3, 9, 2}));
    EXPECT_EQ(topK(cos, weight, 5), (std::vector<uint32_t>{3, 9, 2, 5, 7}));
}

TEST_F(SelectTopK, ZeroWeightsAreNeverChosen) {
    const std::vector<uint32_t> cos = {4, 8, 6, 2};
    EXPECT_EQ(topK(cos, {0, 1.5f, 0, 0}, 3), (std::vector<uint32_t>{8}));
    EXPECT_EQ(topK(cos, {0, 0, 0, 0}, 3), (std::vector<uint32_t>{}));
    EXPECT_EQ(topK(cos, {-1, NAN, 3, 0}, 4), (std::vector<uint32_t>{6}));
}

TEST_F(SelectTopK, HugeAndTinyWeightsKeepTheirOrder) {
    const std::vector<uint32_t> cos = {0, 1, 2, 3};
    EXPECT_EQ(topK(cos, {1e-30f, INFINITY, 3e30f, 1e-45f}, 4), (std::vector<uint32_t>{1, 2, 0, 3}));
}

TEST_F(SelectTopK, EmptyInputOrZeroK) {
    DeviceArray<uint64_t> keys;
    EXPECT_EQ(selectTopK(nullptr, nullptr, 0, 8, nullptr, keys), 0u);
    EXPECT_EQ(topK({1, 2}, {1, 2}, 0), (std::vector<uint32_t>{}));
}

TEST_F(SelectTopK, RandomCandidatesMatchStdSort) {
    std::mt19937 rng(7);
    for (const uint32_t count : {1u, 5u, 300u, 100000u}) {
        std::vector<uint32_t> cos(count);
        std::vector<float> weight(count);
        // Distinct ids in scrambled order; a third zero, and few distinct values so ties are common.
        for (uint32_t j = 0; j < count; ++j) cos[j] = j * 7919u % 1000003u;
        std::shuffle(cos.begin(), cos.end(), rng);
        for (float& w : weight) w = rng() % 3 == 0 ? 0.0f : float(rng() % 1000) * 0.25f + 0.25f;
        std::vector<std::pair<float, uint32_t>> ranked;
        for (uint32_t j = 0; j < count; ++j)
            if (weight[j] > 0) ranked.push_back({weight[j], cos[j]});
        std::sort(ranked.begin(), ranked.end(), [](const auto& a, const auto& b) {
            return a.first != b.first ? a.first > b.first : a.second < b.second;
        });
        for (const uint32_t k : {1u, 16u, 256u}) {
            std::vector<uint32_t> expected;
            for (size_t i = 0; i < ranked.size() && i < k; ++i) expected.push_back(ranked[i].second);
            EXPECT_EQ(topK(cos, weight, k), expected) << count << " candidates, k = " << k;
        }
    }
}

TEST_F(SelectTopK, KeysScratchIsReusedAcrossCalls) {
    // One scratch for a large call and then a small one: the small call must not read the
    // large call's leftover keys.
    DeviceArray<uint64_t> keys;
    std::vector<uint32_t> cos(1000);
    std::vector<float> weight(1000);
    for (uint32_t j = 0; j < 1000; ++j) cos[j] = j, weight[j] = float(j + 1);
    const DeviceArray<uint32_t> c = toDevice(cos);
    const DeviceArray<float> w = toDevice(weight);
    DeviceArray<uint32_t> aos(4);
    EXPECT_EQ(selectTopK(c.ptr(), w.ptr(), 1000, 4, aos.ptr(), keys), 4u);
    EXPECT_EQ(toHost(aos), (std::vector<uint32_t>{999, 998, 997, 996}));
    EXPECT_EQ(selectTopK(c.ptr(), w.ptr(), 3, 4, aos.ptr(), keys), 3u);
    EXPECT_EQ(toHost(aos, 3), (std::vector<uint32_t>{2, 1, 0}));
}

// selectPvsOccluders on seven hand-checked objects. With the eye at the origin and near plane 1,
// a box [-1,1] x [-1,1] x [z-2, z] (z < 0) has diagonal sqrt(12) and is |z| away, so its
// (diagonal / D)^2 is 3 at z = -2 and 0.75 at z = -4; score = that x compactness / triangles.
//   id  z   compactness  triangles  score    note
//   0   -2  1            100        0.03     ties with 3: the lower id ranks first
//   1   -2  1            50         0.06
//   2   -4  1            10         0.075    twice as far, but few triangles: second
//   3   -2  0.5          50         0.03
//   4   -2  1            20         0.15     the AOS: excluded
//   5   -2  1            5          0.6      out of the frustum
//   6   -2  1            25         0.12
// So the rank order of those that may be taken is 6, 2, 1, 0, 3.
ObjectInfo pvsCandidate(float z, float compactness, uint32_t triangles) {
    ObjectInfo o{};
    o.aabb = {{-1, -1, z - 2}, {1, 1, z}};
    o.compactness = compactness;
    o.triangle_count = triangles;
    return o;
}

struct PvsFixture {
    std::vector<ObjectInfo> objects = {pvsCandidate(-2, 1, 100), pvsCandidate(-2, 1, 50), pvsCandidate(-4, 1, 10),
                                       pvsCandidate(-2, 0.5f, 50), pvsCandidate(-2, 1, 20), pvsCandidate(-2, 1, 5),
                                       pvsCandidate(-2, 1, 25)};
    std::vector<uint8_t> in_frustum = {1, 1, 1, 1, 1, 0, 1};
    std::vector<uint32_t> candidates = {3, 5, 0, 6, 4, 1, 2};  // any order
    DeviceArray<ObjectInfo> objects_d = toDevice(objects);
    DeviceArray<uint8_t> in_frustum_d = toDevice(in_frustum);
    DeviceArray<uint32_t> candidates_d = toDevice(candidates);
    PvsOccluderScratch scratch;

    PvsFixture() { scratch.taken = filledDevice<uint8_t>(objects.size(), 0); }

    std::vector<uint32_t> select(const std::vector<uint32_t>& exclude, uint64_t budget) {
        Camera camera{};
        camera.near_plane = 1;
        camera.forward = {0, 0, -1};
        const DeviceArray<uint32_t> exclude_d = toDevice(exclude);
        DeviceArray<uint32_t> out = filledDevice<uint32_t>(candidates.size(), UINT32_MAX);
        const uint32_t n = selectPvsOccluders(objects_d.ptr(), candidates_d.ptr(), uint32_t(candidates.size()),
                                              in_frustum_d.ptr(), camera, exclude_d.ptr(), uint32_t(exclude.size()),
                                              budget, scratch, out.ptr());
        EXPECT_LE(n, candidates.size());
        return toHost(out, n);
    }
};

TEST_F(SelectPvsOccluders, RanksByScreenPerTriangleTiesByIdSkippingTheAosAndTheUnseen) {
    PvsFixture f;
    EXPECT_EQ(f.select({4}, 1000), (std::vector<uint32_t>{6, 2, 1, 0, 3}));
}

TEST_F(SelectPvsOccluders, GreedyBudgetSkipsACandidateTooLargeAndTakesALaterSmallerOne) {
    // 6, 2 and 1 take 25 + 10 + 50 = 85 triangles; 0 (100) would make 185 > 150 and is skipped;
    // 3 (50) makes 135 and is taken. The excluded 4 spends none of the budget (it would have left
    // no room for 3).
    PvsFixture f;
    EXPECT_EQ(f.select({4}, 150), (std::vector<uint32_t>{6, 2, 1, 3}));
    // A budget too small for every candidate takes none; a zero budget too.
    EXPECT_EQ(f.select({4}, 9), (std::vector<uint32_t>{}));
    EXPECT_EQ(f.select({4}, 0), (std::vector<uint32_t>{}));
    // Exactly the first candidate's triangles is enough for it.
    EXPECT_EQ(f.select({4}, 25), (std::vector<uint32_t>{6}));
}

TEST_F(SelectPvsOccluders, ExcludedIdsAreFreeAgainInTheNextCall) {
    // The scratch's `taken` bytes must come back zeroed, so a call without exclusions takes 4.
    PvsFixture f;
    EXPECT_EQ(f.select({4, 6}, 1000), (std::vector<uint32_t>{2, 1, 0, 3}));
    EXPECT_EQ(f.select({}, 1000), (std::vector<uint32_t>{4, 6, 2, 1, 0, 3}));
    EXPECT_EQ(test::toHost(f.scratch.taken), std::vector<uint8_t>(f.objects.size(), 0));
}

TEST_F(SelectPvsOccluders, NoCandidatesTakesNothing) {
    PvsFixture f;
    f.candidates.clear();
    f.candidates_d = toDevice(f.candidates);
    EXPECT_EQ(f.select({4}, 1000), (std::vector<uint32_t>{}));
}

}  // namespace
}  // namespace occ::k
