// SPDX-License-Identifier: MIT
#include "reform.h"

#include "device_test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

using namespace occ::k;
using namespace occ::k::test;

using Reform = DeviceTest;

namespace {

// The example progressive mesh of the spec (Peng & Cao's figure), already re-arranged:
// 7 vertices, q = 4; vertex 6 and 5 collapse to 4, vertex 4 to 1.
const std::vector<int32_t> kFigureEcol{-1, -1, -1, -1, 1, 4, 4};
const std::vector<uint32_t> kFigureMap{2, 2, 2, 2, 2, 4, 6, 8};
const std::vector<uint32_t> kFigureTriangles{0, 5, 3, 6, 2, 3, 1, 2, 4, 0, 1, 6, 5, 6, 3, 0, 6, 5, 4, 2, 6, 1, 4, 6};

// The first map[k] triangles at k = 4..7 with every corner >= k walked through ecol by hand.
const std::vector<std::vector<uint32_t>> kFigureLods{
    {0, 1, 3, 1, 2, 3},                                                   // k = 4: 5->4->1, 6->4->1
    {0, 4, 3, 4, 2, 3, 1, 2, 4, 0, 1, 4},                                 // k = 5: 5->4, 6->4
    {0, 5, 3, 4, 2, 3, 1, 2, 4, 0, 1, 4, 5, 4, 3, 0, 4, 5},               // k = 6: 6->4
    {0, 5, 3, 6, 2, 3, 1, 2, 4, 0, 1, 6, 5, 6, 3, 0, 6, 5, 4, 2, 6, 1, 4, 6},  // k = 7: as stored
};

// A sentinel no corner can be, so that an index the kernel does not write shows.
constexpr uint32_t kSentinel = UINT32_MAX;

// The active triangle array and the index buffer of one frame, on the device: `triangles`
// corners in total (each block's object triangles at its offset, junk in the gaps), the index
// buffer as large and all sentinel.
struct Frame {
    std::vector<uint32_t> active;
    DeviceArray<uint32_t> triangles, indices;
    DeviceArray<ReformBlock> blocks;
    uint32_t count = 0;

    explicit Frame(uint64_t triangle_capacity) : active(3 * triangle_capacity, 0x5eed) {}
    // Puts `corners` (whole triangles) at triangle `offset` of the active array.
    void place(uint64_t offset, const std::vector<uint32_t>& corners) {
        std::copy(corners.begin(), corners.end(), active.begin() + int64_t(3 * offset));
    }
    uint64_t reform(const std::vector<ReformBlock>& list, DevicePtr<const ObjectInfo> objects,
                    DevicePtr<const uint64_t> vertex_first, DevicePtr<const int32_t> ecol) {
        triangles = toDevice(active);
        indices = filledDevice<uint32_t>(active.size(), kSentinel);
        blocks = toDevice(list);
        ReformScratch scratch;
        return reformBlocks(blocks.ptr(), uint32_t(list.size()), objects, vertex_first, ecol, triangles.ptr(),
                            indices.ptr(), scratch);
    }
    std::vector<uint32_t> indexVector() const { return toHost(indices); }
};

// An index buffer of `triangles` triangles, all sentinel but `corners` at triangle `offset`.
std::vector<uint32_t> onlyAt(uint64_t triangles, uint64_t offset, const std::vector<uint32_t>& corners) {
    std::vector<uint32_t> v(3 * triangles, kSentinel);
    std::copy(corners.begin(), corners.end(), v.begin() + int64_t(3 * offset));
    return v;
}

std::vector<uint32_t> prefix(const std::vector<uint32_t>& corners, uint32_t triangles) {
    return {corners.begin(), corners.begin() + 3 * int64_t(triangles)};
}

// The figure mesh as the only mesh, object 0 instancing it.
struct FigureScene {
    DeviceArray<int32_t> ecol = toDevice(kFigureEcol);
    DeviceArray<uint64_t> vertex_first = toDevice(std::vector<uint64_t>{0});
    DeviceArray<ObjectInfo> objects;
    explicit FigureScene(uint32_t vertex_count = 7) {
        std::vector<ObjectInfo> object(1, ObjectInfo{});
        object[0].vertex_count = vertex_count;
        object[0].q = 4;
        object[0].triangle_count = 8;
        objects = toDevice(object);
    }
};

}  // namespace

TEST_F(Reform, TheFigureMeshAtEveryLevelMatchesTheHandWalk) {
    const FigureScene scene;
    for (const uint64_t offset : {uint64_t(0), uint64_t(5)}) {
        for (uint32_t k = 4; k <= 7; ++k) {
            SCOPED_TRACE(testing::Message() << "k = " << k << ", block at triangle " << offset);
            Frame f(offset + 8 + 3);
            f.place(offset, kFigureTriangles);
            EXPECT_EQ(f.reform({{offset, 0, k, kFigureMap[k], 0}}, scene.objects.ptr(), scene.vertex_first.ptr(),
                               scene.ecol.ptr()),
                      kFigureMap[k]);
            // Block-local indices, and nothing written outside the block's map[k] triangles.
            EXPECT_EQ(f.indexVector(), onlyAt(offset + 8 + 3, offset, kFigureLods[k - 4]));
        }
    }
}

TEST_F(Reform, TrianglesPastTheWalkedLevelComeOutDegenerate) {
    // The block holds all 8 triangles (kept resident for later frames) but is drawn at k: the
    // first map[k] are the LOD, every later one has two equal corners.
    const FigureScene scene;
    for (uint32_t k = 4; k <= 6; ++k) {
        SCOPED_TRACE(testing::Message() << "k = " << k);
        Frame f(8);
        f.place(0, kFigureTriangles);
        EXPECT_EQ(f.reform({{0, 0, k, 8, 0}}, scene.objects.ptr(), scene.vertex_first.ptr(), scene.ecol.ptr()), 8u);
        const std::vector<uint32_t> got = f.indexVector();
        EXPECT_EQ(prefix(got, kFigureMap[k]), kFigureLods[k - 4]);
        for (uint32_t t = kFigureMap[k]; t < 8; ++t) {
            const uint32_t a = got[3 * t], b = got[3 * t + 1], c = got[3 * t + 2];
            EXPECT_LT(std::max({a, b, c}), k) << "triangle " << t;
            EXPECT_TRUE(a == b || b == c || a == c) << "triangle " << t << ": " << a << " " << b << " " << c;
        }
    }
}

TEST_F(Reform, FullDetailBlocksAreCopied) {
    const FigureScene scene;
    for (const uint32_t walk : {7u, 8u, 1000u}) {
        SCOPED_TRACE(testing::Message() << "walk below " << walk);
        Frame f(10);
        f.place(2, kFigureTriangles);
        EXPECT_EQ(f.reform({{2, 0, walk, 8, 0}}, scene.objects.ptr(), scene.vertex_first.ptr(), scene.ecol.ptr()), 8u);
        EXPECT_EQ(f.indexVector(), onlyAt(10, 2, kFigureTriangles));
    }
    // Copied, not walked: with the object's full detail said to be 6 vertices, a walk below 6
    // would take corner 6 to 4; at full detail it is copied as it is.
    const FigureScene six(6);
    Frame f(8);
    f.place(0, kFigureTriangles);
    f.reform({{0, 0, 6, 8, 0}}, six.objects.ptr(), six.vertex_first.ptr(), six.ecol.ptr());
    EXPECT_EQ(f.indexVector(), kFigureTriangles);
}

TEST_F(Reform, BlocksWalkedBelowZeroVerticesAreSkipped) {
    const FigureScene scene;
    Frame f(20);
    f.place(0, kFigureTriangles);
    f.place(10, kFigureTriangles);
    // The first block is resident but not drawn (walk 0); the second is drawn at k = 5.
    f.reform({{0, 0, 0, 8, 0}, {10, 0, 5, kFigureMap[5], 0}}, scene.objects.ptr(), scene.vertex_first.ptr(),
             scene.ecol.ptr());
    EXPECT_EQ(f.indexVector(), onlyAt(20, 10, kFigureLods[1]));
}

TEST_F(Reform, InstancesAtDifferentLevelsGetTheirOwnMeshesAndLocalIndices) {
    // Mesh 0 is a 3-vertex triangle that never collapses; mesh 1 is the figure mesh, after it
    // in ecol. Objects 0, 2 and 4 instance the figure, object 1 is mesh 0. Blocks sit out of
    // object order with gaps between them; object 4's block is in the active array but not
    // listed (it did not change), so its indices are not written.
    std::vector<int32_t> ecol{-1, -1, -1};
    ecol.insert(ecol.end(), kFigureEcol.begin(), kFigureEcol.end());
    const DeviceArray<int32_t> ecol_d = toDevice(ecol);
    const DeviceArray<uint64_t> vertex_first = toDevice(std::vector<uint64_t>{0, 3});
    std::vector<ObjectInfo> object(5, ObjectInfo{});
    for (uint32_t i = 0; i < 5; ++i) {
        object[i].mesh = i == 1 ? 0 : 1;
        object[i].vertex_count = i == 1 ? 3 : 7;
    }
    const DeviceArray<ObjectInfo> objects = toDevice(object);
    const std::vector<uint32_t> triangle{2, 0, 1};
    Frame f(40);
    f.place(20, kFigureTriangles);  // object 0
    f.place(12, triangle);          // object 1
    f.place(2, kFigureTriangles);   // object 2
    f.place(30, kFigureTriangles);  // object 4
    const uint64_t reformed = f.reform({{20, 0, 4, 2, 0}, {12, 1, 3, 1, 0}, {2, 2, 6, 6, 0}}, objects.ptr(),
                                       vertex_first.ptr(), ecol_d.ptr());
    EXPECT_EQ(reformed, 2u + 1 + 6);
    std::vector<uint32_t> expected(3 * 40, kSentinel);
    std::copy(kFigureLods[0].begin(), kFigureLods[0].end(), expected.begin() + 3 * 20);
    std::copy(triangle.begin(), triangle.end(), expected.begin() + 3 * 12);
    std::copy(kFigureLods[2].begin(), kFigureLods[2].end(), expected.begin() + 3 * 2);
    EXPECT_EQ(f.indexVector(), expected);
}

TEST_F(Reform, NoBlocksWriteNothing) {
    Frame f(4);
    EXPECT_EQ(f.reform({}, nullptr, nullptr, nullptr), 0u);
    EXPECT_EQ(f.indexVector(), std::vector<uint32_t>(12, kSentinel));
}

TEST_F(Reform, MatchesTheScalarWalkOnRandomMeshesAndBlocks) {
    std::mt19937 rng(5);
    for (int round = 0; round < 4; ++round) {
        SCOPED_TRACE(testing::Message() << "round " << round);
        // Random progressive meshes: ecol[v] is any earlier vertex for v >= q (a chain like
        // v -> v - 1 -> ... makes long walks), triangles have random corners.
        const uint32_t mesh_count = 9;
        std::vector<int32_t> ecol;
        std::vector<uint64_t> first;
        std::vector<uint32_t> mesh_vertices, mesh_q;
        std::vector<std::vector<uint32_t>> mesh_triangles;
        for (uint32_t m = 0; m < mesh_count; ++m) {
            const uint32_t n = std::uniform_int_distribution<uint32_t>(1, 2000)(rng);
            const uint32_t q = std::uniform_int_distribution<uint32_t>(1, n)(rng);
            first.push_back(ecol.size());
            for (uint32_t v = 0; v < n; ++v)
                ecol.push_back(v < q ? -1 : m % 3 == 0 ? int32_t(v - 1)
                                                       : int32_t(std::uniform_int_distribution<uint32_t>(0, v - 1)(rng)));
            std::vector<uint32_t> t(3 * std::uniform_int_distribution<uint32_t>(1, 2 * n)(rng));
            for (uint32_t& c : t) c = std::uniform_int_distribution<uint32_t>(0, n - 1)(rng);
            mesh_vertices.push_back(n), mesh_q.push_back(q), mesh_triangles.push_back(std::move(t));
        }
        // Every object resident as a block, at increasing offsets with random gaps; about half
        // of them listed (changed this frame), a few of those not drawn (walk 0).
        const uint32_t object_count = 200;
        std::vector<ObjectInfo> objects(object_count);
        struct Resident {
            uint32_t object;
            uint64_t offset;
            uint32_t triangles;
        };
        std::vector<Resident> resident;
        uint64_t capacity = 0;
        for (uint32_t o = 0; o < object_count; ++o) {
            const uint32_t m = std::uniform_int_distribution<uint32_t>(0, mesh_count - 1)(rng);
            objects[o] = ObjectInfo{};
            objects[o].mesh = m;
            objects[o].vertex_count = mesh_vertices[m];
            objects[o].q = mesh_q[m];
            if (rng() % 4 == 0) continue;  // not resident
            const uint32_t all = uint32_t(mesh_triangles[m].size() / 3);
            capacity += std::uniform_int_distribution<uint32_t>(0, 50)(rng);
            resident.push_back({o, capacity, std::uniform_int_distribution<uint32_t>(0, all)(rng)});
            capacity += resident.back().triangles;
        }
        std::shuffle(resident.begin(), resident.end(), rng);  // the list need not be in offset order
        Frame f(capacity + 1);
        std::vector<ReformBlock> list;
        std::vector<uint32_t> expected(3 * (capacity + 1), kSentinel);
        for (const Resident& r : resident) {
            const uint32_t m = objects[r.object].mesh;
            f.place(r.offset, prefix(mesh_triangles[m], r.triangles));
            if (rng() % 2 == 0) continue;  // unchanged: not listed
            const bool drawn = rng() % 8 != 0;
            const uint32_t walk = drawn ? std::uniform_int_distribution<uint32_t>(mesh_q[m], mesh_vertices[m])(rng) : 0;
            list.push_back({r.offset, r.object, walk, r.triangles, 0});
            if (!drawn) continue;
            for (uint32_t i = 0; i < 3 * r.triangles; ++i) {
                uint32_t c = mesh_triangles[m][i];
                while (c >= walk) c = uint32_t(ecol[first[m] + c]);
                expected[3 * r.offset + i] = c;
            }
        }
        const DeviceArray<ObjectInfo> objects_d = toDevice(objects);
        const DeviceArray<int32_t> ecol_d = toDevice(ecol);
        const DeviceArray<uint64_t> first_d = toDevice(first);
        f.reform(list, objects_d.ptr(), first_d.ptr(), ecol_d.ptr());
        ASSERT_EQ(f.indexVector(), expected);
    }
}
