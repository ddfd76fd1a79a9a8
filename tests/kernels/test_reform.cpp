// SPDX-License-Identifier: MIT
#include "reform.h"

#include "device_test_support.h"
#include "scan.h"

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

// A frame on the device: per block its object, vc and tc, and the scans (the layout), the active
// triangle array built from each object's mesh, and room for the indices.
struct Frame {
    LayoutPair blocks;
    ActiveLayout layout;
    DeviceArray<uint32_t> triangles, indices;

    Frame(const std::vector<uint32_t>& objects, const std::vector<uint32_t>& vertex_counts,
          const std::vector<uint32_t>& triangle_counts, const std::vector<std::vector<uint32_t>>& object_triangles)
        : blocks(objects, vertex_counts, triangle_counts), layout(blocks.device()) {
        std::vector<uint32_t> active;
        for (size_t j = 0; j < objects.size(); ++j)
            active.insert(active.end(), object_triangles[j].begin(), object_triangles[j].begin() + 3 * triangle_counts[j]);
        triangles = toDevice(active);
        // A sentinel no corner can be, so that an index the kernel does not write shows.
        indices = filledDevice<uint32_t>(active.size(), UINT32_MAX);
    }
    std::vector<uint32_t> indexVector() const { return toHost(indices); }
};

std::vector<uint32_t> shifted(std::vector<uint32_t> v, uint32_t offset) {
    for (uint32_t& x : v) x += offset;
    return v;
}

}  // namespace

TEST_F(Reform, TheFigureMeshAtEveryLevelMatchesTheHandWalk) {
    const DeviceArray<int32_t> ecol = toDevice(kFigureEcol);
    const DeviceArray<uint64_t> vertex_first = toDevice(std::vector<uint64_t>{0});
    std::vector<ObjectInfo> object(1, ObjectInfo{});
    object[0].vertex_count = 7;
    const DeviceArray<ObjectInfo> objects = toDevice(object);
    for (uint32_t k = 4; k <= 7; ++k) {
        SCOPED_TRACE(testing::Message() << "k = " << k);
        Frame f({0}, {k}, {kFigureMap[k]}, {kFigureTriangles});
        reform(f.layout, objects.ptr(), vertex_first.ptr(), ecol.ptr(), f.triangles.ptr(), f.indices.ptr());
        EXPECT_EQ(f.indexVector(), kFigureLods[k - 4]);
    }
}

TEST_F(Reform, InstancesAtDifferentLevelsGetTheirOwnOffsetsAndMeshes) {
    // Mesh 0 is a 3-vertex triangle that never collapses; mesh 1 is the figure mesh, after it
    // in ecol. Objects 0 and 2 instance the figure at k = 4 and k = 6, object 1 is mesh 0 and
    // object 3 is listed but not drawn.
    std::vector<int32_t> ecol{-1, -1, -1};
    ecol.insert(ecol.end(), kFigureEcol.begin(), kFigureEcol.end());
    const DeviceArray<int32_t> ecol_d = toDevice(ecol);
    const DeviceArray<uint64_t> vertex_first = toDevice(std::vector<uint64_t>{0, 3});
    std::vector<ObjectInfo> object(4, ObjectInfo{});
    for (uint32_t i = 0; i < 4; ++i) {
        object[i].mesh = i == 1 ? 0 : 1;
        object[i].vertex_count = i == 1 ? 3 : 7;
    }
    const DeviceArray<ObjectInfo> objects = toDevice(object);
    const std::vector<uint32_t> triangle{2, 0, 1};
    Frame f({0, 1, 2, 3}, {4, 3, 6, 0}, {2, 1, 6, 0}, {kFigureTriangles, triangle, kFigureTriangles, {}});
    reform(f.layout, objects.ptr(), vertex_first.ptr(), ecol_d.ptr(), f.triangles.ptr(), f.indices.ptr());
    std::vector<uint32_t> expected = kFigureLods[0];                       // vertices 0..3
    const std::vector<uint32_t> second = shifted(triangle, 4);             // vertices 4..6
    const std::vector<uint32_t> third = shifted(kFigureLods[2], 4 + 3);    // vertices 7..12
    expected.insert(expected.end(), second.begin(), second.end());
    expected.insert(expected.end(), third.begin(), third.end());
    EXPECT_EQ(f.indexVector(), expected);
}

TEST_F(Reform, AnEmptyFrameWritesNothing) {
    Frame f({}, {}, {}, {});
    reform(f.layout, nullptr, nullptr, nullptr, f.triangles.ptr(), f.indices.ptr());
    EXPECT_TRUE(f.indexVector().empty());
}

TEST_F(Reform, MatchesTheScalarWalkOnRandomMeshesAndLayouts) {
    std::mt19937 rng(5);
    for (int round = 0; round < 4; ++round) {
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
        const uint32_t object_count = 200;
        std::vector<ObjectInfo> objects(object_count);
        std::vector<uint32_t> ids, vc, tc;
        std::vector<std::vector<uint32_t>> tris;
        for (uint32_t o = 0; o < object_count; ++o) {
            const uint32_t m = std::uniform_int_distribution<uint32_t>(0, mesh_count - 1)(rng);
            objects[o] = ObjectInfo{};
            objects[o].mesh = m;
            objects[o].vertex_count = mesh_vertices[m];
            if (rng() % 4 == 0) continue;  // not in this frame
            const bool drawn = rng() % 8 != 0;
            ids.push_back(o);
            vc.push_back(drawn ? std::uniform_int_distribution<uint32_t>(mesh_q[m], mesh_vertices[m])(rng) : 0);
            const uint32_t all = uint32_t(mesh_triangles[m].size() / 3);
            tc.push_back(drawn ? std::uniform_int_distribution<uint32_t>(0, all)(rng) : 0);
            tris.push_back(mesh_triangles[m]);
        }
        const DeviceArray<ObjectInfo> objects_d = toDevice(objects);
        const DeviceArray<int32_t> ecol_d = toDevice(ecol);
        const DeviceArray<uint64_t> first_d = toDevice(first);
        Frame f(ids, vc, tc, tris);
        reform(f.layout, objects_d.ptr(), first_d.ptr(), ecol_d.ptr(), f.triangles.ptr(), f.indices.ptr());

        std::vector<uint32_t> expected;
        uint64_t vertex_offset = 0;
        for (size_t j = 0; j < ids.size(); ++j) {
            const uint32_t m = objects[ids[j]].mesh;
            for (uint32_t i = 0; i < 3 * tc[j]; ++i) {
                uint32_t c = tris[j][i];
                while (c >= vc[j]) c = uint32_t(ecol[first[m] + c]);
                expected.push_back(uint32_t(vertex_offset + c));
            }
            vertex_offset += vc[j];
        }
        ASSERT_EQ(f.indexVector(), expected) << "round " << round;
    }
}
