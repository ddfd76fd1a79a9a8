// SPDX-License-Identifier: MIT
#include "kernel_memory.h"
#include "occluder_weight.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace occ::k {
namespace {

template <class T>
KernelArray<T> toKernel(const std::vector<T>& v) {
    KernelArray<T> a(v.size());
    std::copy(v.begin(), v.end(), a.begin());
    return a;
}

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
    const KernelArray<ObjectInfo> o = toKernel(objects);
    const KernelArray<uint32_t> c = toKernel(cos);
    const KernelArray<uint8_t> f = toKernel(in_frustum);
    KernelArray<float> w(cos.size());
    occluderWeight(o.data(), c.data(), uint32_t(cos.size()), f.data(), camera, w.data());
    return {w.begin(), w.end()};
}

TEST(OccluderWeight, HandComputedEq3) {
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

TEST(OccluderWeight, CloserAndLargerWins) {
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

TEST(OccluderWeight, EmptyInput) { occluderWeight(nullptr, nullptr, 0, nullptr, eyeAtOrigin(), nullptr); }

std::vector<uint32_t> topK(const std::vector<uint32_t>& cos, const std::vector<float>& weight, uint32_t k) {
    const KernelArray<uint32_t> c = toKernel(cos);
    const KernelArray<float> w = toKernel(weight);
    KernelArray<uint32_t> aos(k);
    const uint32_t n = selectTopK(c.data(), w.data(), uint32_t(cos.size()), k, aos.data());
    EXPECT_LE(n, k);
    return {aos.begin(), aos.begin() + n};
}

TEST(SelectTopK, DecreasingWeightTiesByLowerId) {
    const std::vector<uint32_t> cos = {7, 3, 5, 1, 9, 2};
    const std::vector<float> weight = {2, 5, 2, 0, 5, 4};
    EXPECT_EQ(topK(cos, weight, 3), (std::vector<uint32_t>{3, 9, 2}));
    EXPECT_EQ(topK(cos, weight, 5), (std::vector<uint32_t>{3, 9, 2, 5, 7}));
}

TEST(SelectTopK, ZeroWeightsAreNeverChosen) {
    const std::vector<uint32_t> cos = {4, 8, 6, 2};
    EXPECT_EQ(topK(cos, {0, 1.5f, 0, 0}, 3), (std::vector<uint32_t>{8}));
    EXPECT_EQ(topK(cos, {0, 0, 0, 0}, 3), (std::vector<uint32_t>{}));
    EXPECT_EQ(topK(cos, {-1, NAN, 3, 0}, 4), (std::vector<uint32_t>{6}));
}

TEST(SelectTopK, HugeAndTinyWeightsKeepTheirOrder) {
    const std::vector<uint32_t> cos = {0, 1, 2, 3};
    EXPECT_EQ(topK(cos, {1e-30f, INFINITY, 3e30f, 1e-45f}, 4), (std::vector<uint32_t>{1, 2, 0, 3}));
}

TEST(SelectTopK, EmptyInputOrZeroK) {
    EXPECT_EQ(selectTopK(nullptr, nullptr, 0, 8, nullptr), 0u);
    EXPECT_EQ(topK({1, 2}, {1, 2}, 0), (std::vector<uint32_t>{}));
}

TEST(SelectTopK, RandomCandidatesMatchStdSort) {
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

}  // namespace
}  // namespace occ::k
