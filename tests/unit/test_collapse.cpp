// SPDX-License-Identifier: MIT
#include "import/import.h"
#include "import/plant.h"
#include "prep/collapse_recorder.h"
#include "prep/error_calibration.h"
#include "prep/fast_collapser.h"
#include "prep/hausdorff.h"
#include "scene/lod_prefix.h"
#include "prep/prepare.h"
#include "prep/rearrange.h"
#include "prep/vertex_normals.h"
#include "prep/weld.h"
#include "scene/oss_file.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

namespace occ {
namespace {

// "" when the prefix property holds, otherwise the violation.
std::string prefixViolation(const ProgressiveMesh& pm) {
    LodPrefixScratch scratch;
    const auto v = checkLodPrefix(pm.vertexCount(), pm.ecol, pm.triangles, pm.map, pm.q, scratch);
    return v ? v->what : "";
}

// The size of Peng & Cao 2012's Figure 3/4 example: 7 vertices and 8 triangles, edge-length
// cost. A 6x4 rectangle (corners 0-3, locked as boundary) around three interior vertices:
//
//   3 ----------------- 2
//   |  \     t4     /  / |
//   | t2 4 --- 5 --- 6 t6|        4 = (2, 2), 5 = (3.2, 2.5), 6 = (4, 2)
//   |  /  t1  \ t0 /  \  |
//   0 ----------------- 1
struct FigureMesh {
    std::vector<glm::vec3> positions{{0, 0, 0}, {6, 0, 0}, {6, 4, 0}, {0, 4, 0}, {2, 2, 0}, {3.2f, 2.5f, 0}, {4, 2, 0}};
    std::vector<uint32_t> triangles{0, 1, 5, 0, 5, 4, 0, 4, 3, 4, 5, 3, 5, 2, 3, 1, 6, 5, 1, 2, 6, 6, 2, 5};
};

TEST(CollapseSequence, FigureExampleCollapsesShortestLegalEdgesFirst) {
    const FigureMesh f;
    const CollapseSequence s = fastCollapseSequence(f.positions, f.triangles, CollapseCost::EdgeLength);
    // |5-6| = 0.943 (5 -> 6, tie with 6 -> 5 broken by lower id); then |4-6| = 2 (4 -> 6, tie
    // with 6 -> 4); then |6-1| = |6-2| = 2.828 (6 -> 1, lower kept id). Corners are boundary.
    ASSERT_EQ(s.size(), 3u);
    EXPECT_EQ(s.removed, (std::vector<uint32_t>{5, 4, 6}));
    EXPECT_EQ(s.kept, (std::vector<uint32_t>{6, 6, 1}));
    EXPECT_NEAR(s.error[0], 0.9434f, 1e-3f);
    EXPECT_NEAR(s.error[1], 2.0f, 1e-5f);
    EXPECT_NEAR(s.error[2], 2.8284f, 1e-3f);
    EXPECT_EQ(s.triangle_offsets, (std::vector<uint32_t>{0, 2, 4, 6}));
    EXPECT_EQ(s.triangles, (std::vector<uint32_t>{5, 7, 1, 3, 0, 6}));
}

TEST(CollapseSequence, FigureExampleArraysOfSection42) {
    const FigureMesh f;
    const CollapseSequence s = fastCollapseSequence(f.positions, f.triangles, CollapseCost::EdgeLength);
    const CollapseArrays a = recordCollapseArrays(7, 8, s);
    // Collapse 1 (m = 7, t = 8): 5 -> position 6, triangles 5, 7 -> 7, 6; map[6] = 6.
    // Collapse 2 (m = 6, t = 6): 4 -> position 5, triangles 1, 3 -> 5, 4; map[5] = 4.
    // Collapse 3 (m = 5, t = 4): 6 -> position 4, triangles 0, 6 -> 3, 2; map[4] = 2.
    // Survivors 0..3 and triangles 2, 4 keep the front in order.
    EXPECT_EQ(a.q, 4u);
    EXPECT_EQ(a.ecol, (std::vector<int32_t>{-1, -1, -1, -1, 6, 6, 1}));
    EXPECT_EQ(a.permuteV, (std::vector<uint32_t>{0, 1, 2, 3, 5, 6, 4}));
    EXPECT_EQ(a.permuteT, (std::vector<uint32_t>{3, 5, 0, 4, 1, 7, 2, 6}));
    EXPECT_EQ(a.map, (std::vector<uint32_t>{2, 2, 2, 2, 2, 4, 6, 8}));
}

TEST(CollapseSequence, FigureExampleAfterAlgorithm1) {
    const FigureMesh f;
    const CollapseSequence s = fastCollapseSequence(f.positions, f.triangles, CollapseCost::EdgeLength);
    const ProgressiveMesh pm = rearrange(f.positions, f.triangles, s, recordCollapseArrays(7, 8, s));
    EXPECT_EQ(pm.ecol, (std::vector<int32_t>{-1, -1, -1, -1, 1, 4, 4}));
    EXPECT_EQ(pm.positions[4], f.positions[6]);
    EXPECT_EQ(pm.positions[5], f.positions[4]);
    EXPECT_EQ(pm.positions[6], f.positions[5]);
    EXPECT_EQ(pm.triangles, (std::vector<uint32_t>{0, 5, 3, 6, 2, 3, 1, 2, 4, 0, 1, 6, 5, 6, 3, 0, 6, 5, 4, 2, 6, 1, 4, 6}));
    // The LOD with 4 vertices: the first map[4] = 2 triangles, corners walked below 4.
    const auto walk = [&](uint32_t v, uint32_t k) {
        while (v >= k) v = uint32_t(pm.ecol[v]);
        return v;
    };
    std::vector<uint32_t> lod4;
    for (uint32_t i = 0; i < 3 * pm.map[4]; ++i) lod4.push_back(walk(pm.triangles[i], 4));
    EXPECT_EQ(lod4, (std::vector<uint32_t>{0, 1, 3, 1, 2, 3}));
    EXPECT_EQ(prefixViolation(pm), "");
}

TEST(LodPrefix, DetectsAMapOffByOne) {
    const FigureMesh f;
    const CollapseSequence s = fastCollapseSequence(f.positions, f.triangles, CollapseCost::EdgeLength);
    ProgressiveMesh pm = rearrange(f.positions, f.triangles, s, recordCollapseArrays(7, 8, s));
    pm.map[5] = 5;
    EXPECT_NE(prefixViolation(pm), "");
}

TEST(Weld, MergesSplitVerticesAndDropsTrianglesThatCollapse) {
    // Two triangles of a quad with the diagonal split (as exporters do for hard edges), plus a
    // sliver whose two corners sit at the same place.
    const std::vector<glm::vec3> p{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 0, -0.0f}, {1, 1, 0}, {0, 1, 0}, {1, 0, 0}, {1, 0, 0}};
    const std::vector<uint32_t> t{0, 1, 2, 3, 4, 5, 6, 7, 2};
    const WeldedMesh w = weldPositions(p, t);
    EXPECT_EQ(w.positions.size(), 4u);
    EXPECT_EQ(w.triangles, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
    EXPECT_EQ(w.dropped_triangles, 1u);
}

// Every invariant of a progressive mesh that does not depend on which collapser made it.
void expectValidProgressiveMesh(const ProgressiveMesh& pm) {
    ASSERT_EQ(pm.map.size(), size_t(pm.vertexCount()) + 1);
    for (uint32_t v = 0; v < pm.vertexCount(); ++v) {
        if (v < pm.q)
            ASSERT_EQ(pm.ecol[v], -1) << v;
        else
            ASSERT_LT(pm.ecol[v], int32_t(v)) << v;
    }
    for (uint32_t k = 1; k <= pm.vertexCount(); ++k) ASSERT_LE(pm.map[k - 1], pm.map[k]);
    EXPECT_EQ(prefixViolation(pm), "");
}

// The LOD of a progressive mesh with k vertices: its first map[k] triangles, walked below k.
std::vector<uint32_t> lodTriangles(const ProgressiveMesh& pm, uint32_t k) {
    std::vector<uint32_t> out(pm.triangles.begin(), pm.triangles.begin() + 3 * pm.map[k]);
    for (uint32_t& v : out)
        while (v >= k) v = uint32_t(pm.ecol[v]);
    return out;
}

TEST(Collapsers, FastAndOpenMeshGiveValidSequencesOfComparableErrorOnEngineParts) {
    const Scene engine = importModel(test::kEngine);
    uint64_t fast_collapses = 0, om_collapses = 0;
    double fast_error = 0.0, om_error = 0.0;
    for (const Mesh& mesh : engine.meshes) {
        const ProgressiveMesh fast = buildProgressiveMesh(mesh, Collapser::Fast);
        const ProgressiveMesh om = buildProgressiveMesh(mesh, Collapser::OpenMesh);
        expectValidProgressiveMesh(fast);
        expectValidProgressiveMesh(om);
        ASSERT_EQ(fast.vertexCount(), om.vertexCount());  // same welded input
        fast_collapses += fast.vertexCount() - fast.q;
        om_collapses += om.vertexCount() - om.q;
        // Geometric error (sampled Hausdorff against the full mesh) with 25 % of the collapsible
        // vertices left, the same vertex count for both.
        const uint32_t floor = std::max(fast.q, om.q);
        const uint32_t k = floor + (fast.vertexCount() - floor) / 4;
        const HausdorffOptions samples{2000, 7};
        fast_error += sampledHausdorff(fast.positions, fast.triangles, fast.positions, lodTriangles(fast, k), samples).max;
        om_error += sampledHausdorff(om.positions, om.triangles, om.positions, lodTriangles(om, k), samples).max;
    }
    // Both simplify the same amount (within 5 %) ...
    EXPECT_GT(fast_collapses, om_collapses * 95 / 100);
    // ... and ours is not worse in Hausdorff error summed over the parts (10 % slack).
    EXPECT_LE(fast_error, om_error * 1.1) << "fast " << fast_error << " openmesh " << om_error;
    RecordProperty("hausdorff_fast", std::to_string(fast_error));
    RecordProperty("hausdorff_openmesh", std::to_string(om_error));
}

TEST(Collapsers, ClosedPlantMeshesSimplifyToTheMinimum) {
    const Scene plant = generatePlant({200, 3});
    for (const Mesh& mesh : plant.meshes) {
        const ProgressiveMesh pm = buildProgressiveMesh(mesh, Collapser::Fast);
        expectValidProgressiveMesh(pm);
        EXPECT_LE(pm.q, 8u) << mesh.name;  // closed meshes have no boundary to lock
    }
}

// An open sheet (a 10 x 10 grid of squares, every border vertex on two border edges): with the
// Quadric cost border vertices collapse too, always along the border (a vertex of a side moves
// onto a vertex of the same side), so the sheet simplifies far below its outline's 40 vertices
// and keeps its square outline while it does.
TEST(Collapsers, OpenSheetBordersCollapseAlongTheBorder) {
    std::vector<glm::vec3> p;
    std::vector<uint32_t> t;
    for (int y = 0; y <= 10; ++y)
        for (int x = 0; x <= 10; ++x) p.push_back({float(x), float(y), 0.0f});
    for (uint32_t y = 0; y < 10; ++y)
        for (uint32_t x = 0; x < 10; ++x) {
            const uint32_t a = y * 11 + x, b = a + 1, c = a + 11, d = c + 1;
            t.insert(t.end(), {a, b, d, a, d, c});
        }
    const CollapseSequence s = fastCollapseSequence(p, t);
    const auto side = [&](uint32_t v, int axis, float at) { return p[v][axis] == at; };
    uint32_t border_moves = 0;
    for (size_t i = 0; i < s.size(); ++i) {
        const uint32_t u = s.removed[i], v = s.kept[i];
        for (int axis = 0; axis < 2; ++axis)
            for (float at : {0.0f, 10.0f})
                if (side(u, axis, at) && !side(u, 1 - axis, 0.0f) && !side(u, 1 - axis, 10.0f)) {
                    ++border_moves;
                    EXPECT_TRUE(side(v, axis, at)) << "side vertex " << u << " left its side for " << v;
                }
    }
    EXPECT_EQ(border_moves, 36u);  // every side vertex but the corners went, along its side
    EXPECT_GE(s.size(), p.size() - 4);
    // EdgeLength keeps the outline whole (the hand-checked fixtures rely on it).
    const CollapseSequence locked = fastCollapseSequence(p, t, CollapseCost::EdgeLength);
    EXPECT_EQ(locked.size(), 81u);  // the interior vertices only
}

// A 10 x 10 sheet of squares (two triangles each) without the squares listed in `holes`.
struct Sheet {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    explicit Sheet(std::initializer_list<std::pair<uint32_t, uint32_t>> holes) {
        for (int y = 0; y <= 10; ++y)
            for (int x = 0; x <= 10; ++x) positions.push_back({float(x), float(y), 0.0f});
        for (uint32_t y = 0; y < 10; ++y)
            for (uint32_t x = 0; x < 10; ++x) {
                if (std::find(holes.begin(), holes.end(), std::pair{x, y}) != holes.end()) continue;
                const uint32_t a = y * 11 + x, b = a + 1, c = a + 11, d = c + 1;
                triangles.insert(triangles.end(), {a, b, d, a, d, c});
            }
    }
};

// Euler characteristic V - E + F of the triangles after the first `count` collapses of s (1 for
// a disk, 0 for a disk with one hole, -1 with two), and how many triangles are left.
std::pair<int, int> eulerAfter(const Sheet& sheet, const CollapseSequence& s, size_t count) {
    std::vector<uint32_t> to(sheet.positions.size());
    for (uint32_t v = 0; v < to.size(); ++v) to[v] = v;
    for (size_t i = 0; i < count; ++i) to[s.removed[i]] = s.kept[i];
    const auto root = [&](uint32_t v) {
        while (to[v] != v) v = to[v];
        return v;
    };
    std::set<uint32_t> vertices;
    std::set<std::pair<uint32_t, uint32_t>> edges;
    int faces = 0;
    for (size_t t = 0; t < sheet.triangles.size(); t += 3) {
        const uint32_t c[3] = {root(sheet.triangles[t]), root(sheet.triangles[t + 1]), root(sheet.triangles[t + 2])};
        if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
        ++faces;
        for (int k = 0; k < 3; ++k) {
            vertices.insert(c[k]);
            edges.insert(std::minmax(c[k], c[(k + 1) % 3]));
        }
    }
    return {int(vertices.size()) - int(edges.size()) + faces, faces};
}

// The Euler characteristic of the coarsest level that still has triangles.
int eulerOfCoarsestLevel(const Sheet& sheet, const CollapseSequence& s) {
    for (size_t count = s.size();; --count) {
        const auto [euler, faces] = eulerAfter(sheet, s, count);
        if (faces > 0 || count == 0) return euler;
    }
}

// A sheet with a one-square hole: the hole's border loop shrinks to three vertices and then
// closes (the one exception to the link condition), so the sheet simplifies as far as one
// without a hole and ends a disk; the sequence is still a valid progressive mesh.
TEST(Collapsers, SmallHolesCloseWhenTheirLoopIsDownToThree) {
    const Sheet sheet({{4, 4}});
    const CollapseSequence s = fastCollapseSequence(sheet.positions, sheet.triangles);
    EXPECT_GE(s.size(), sheet.positions.size() - 4);
    EXPECT_EQ(eulerAfter(sheet, s, 0).first, 0);
    EXPECT_EQ(eulerOfCoarsestLevel(sheet, s), 1);
    const CollapseArrays a = recordCollapseArrays(uint32_t(sheet.positions.size()),
                                                  uint32_t(sheet.triangles.size() / 3), s);
    expectValidProgressiveMesh(rearrange(sheet.positions, sheet.triangles, s, a));
}

// Two holes that touch at one vertex (4 border edges there: locked, as meshoptimizer locks it):
// once one hole closes through it, the vertex is a plain border vertex and may go too.
TEST(Collapsers, AVertexWhereHolesMeetIsFreedWhenOneCloses) {
    const Sheet sheet({{4, 4}, {5, 5}});
    const uint32_t pinch = 5 * 11 + 5;
    const CollapseSequence s = fastCollapseSequence(sheet.positions, sheet.triangles);
    EXPECT_NE(std::find(s.removed.begin(), s.removed.end(), pinch), s.removed.end());
    EXPECT_GE(s.size(), sheet.positions.size() - 4);
    EXPECT_EQ(eulerAfter(sheet, s, 0).first, -1);  // two holes
    EXPECT_EQ(eulerOfCoarsestLevel(sheet, s), 1);
    const CollapseArrays a = recordCollapseArrays(uint32_t(sheet.positions.size()),
                                                  uint32_t(sheet.triangles.size() / 3), s);
    expectValidProgressiveMesh(rearrange(sheet.positions, sheet.triangles, s, a));
}

TEST(Collapsers, NonManifoldEdgeIsKeptAndNeverCollapsed) {
    // Three triangles share edge 0-1 (a "book" of three pages), plus a fan that can simplify.
    std::vector<glm::vec3> p{{0, 0, 0}, {0, 0, 1}, {1, 0, 0.5f}, {-1, 0, 0.5f}, {0, 1, 0.5f}};
    std::vector<uint32_t> t{0, 1, 2, 1, 0, 3, 0, 1, 4};
    const CollapseSequence fast = fastCollapseSequence(p, t);
    for (uint32_t u : fast.removed) EXPECT_TRUE(u != 0 && u != 1) << "collapsed a vertex of the non-manifold edge";
    const CollapseSequence om = openMeshCollapseSequence(p, t);
    EXPECT_EQ(om.refused_faces, 1u);  // OpenMesh cannot add the third page
    for (uint32_t u : om.removed) EXPECT_TRUE(u != 0 && u != 1);
}

// The error of the level with k vertices: the largest error of the collapses it has undone.
float levelError(const ProgressiveMesh& pm, uint32_t k) {
    float e = 0.0f;
    for (uint32_t v = k; v < pm.vertexCount(); ++v) e = std::max(e, pm.error[v]);
    return e;
}

// A progressive mesh as prep makes it, before its errors are calibrated.
ProgressiveMesh uncalibrated(const Mesh& mesh) {
    const WeldedMesh w = weldPositions(mesh.positions, mesh.indices);
    const CollapseSequence s = fastCollapseSequence(w.positions, w.triangles);
    const CollapseArrays a = recordCollapseArrays(uint32_t(w.positions.size()), uint32_t(w.triangles.size() / 3), s);
    return rearrange(w.positions, w.triangles, s, a);
}

// Calibration only raises errors, keeps everything else, and leaves the levels' errors within
// 2x of a dense measurement (other seed, 2 000 samples, levels between its measured ones),
// where the collapser's own RMS errors understate many levels by more.
// Issue 49, item 3: a thin slab (4 x 4 x 0.2, a box) simplified to 4 triangles. Half-edge
// collapses leave a tetrahedron of its corners: each vertex is a corner, on the top or bottom
// face, and the facets tilt by the slab's thickness over its width. Placing collapses meet the
// top and bottom faces half way: three of the four vertices lie in the mid-plane (the link
// condition stops the fourth, whose collapse would leave no volume) and the facets tilt less.
TEST(Collapsers, PlacingCollapsesFoldAThinSlabTowardsItsMidPlane) {
    Mesh box;
    for (int i = 0; i < 8; ++i) box.positions.push_back({i & 1 ? 4.0f : 0.0f, i & 2 ? 4.0f : 0.0f, i & 4 ? 0.2f : 0.0f});
    for (const uint32_t c : {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5})
        box.indices.push_back(c);
    // The level's largest tilt (degrees from the z axis) and how many of its vertices lie in the mid-plane.
    const auto flatness = [](const ProgressiveMesh& pm, uint32_t k) {
        const std::vector<uint32_t> tris = lodTriangles(pm, k);
        float tilt = 0.0f;
        std::set<uint32_t> mid;
        for (size_t t = 0; t + 2 < tris.size(); t += 3) {
            const glm::vec3 a = pm.positions[tris[t]], b = pm.positions[tris[t + 1]], c = pm.positions[tris[t + 2]];
            const glm::vec3 n = glm::normalize(glm::cross(b - a, c - a));
            tilt = std::max(tilt, glm::degrees(std::acos(std::min(1.0f, std::abs(n.z)))));
            for (int i = 0; i < 3; ++i)
                if (std::abs(pm.positions[tris[t + i]].z - 0.1f) < 1e-5f) mid.insert(tris[t + i]);
        }
        return std::pair{tilt, mid.size()};
    };
    ClusterOptions half, placing;
    half.first_cell = half.last_cell = placing.first_cell = placing.last_cell = 1.0f;  // edge collapses only
    placing.place_edges = true;
    const ProgressiveMesh h = buildClusteredProgressiveMesh(box, {}, half), p = buildClusteredProgressiveMesh(box, {}, placing);
    LodPrefixScratch scratch;
    for (const ProgressiveMesh* pm : {&h, &p}) {
        const auto bad = checkLodPrefix(pm->vertexCount(), pm->ecol, pm->triangles, pm->map, pm->q, scratch);
        EXPECT_FALSE(bad.has_value()) << bad->what;
        ASSERT_EQ(pm->map[pm->q], 4u) << "a closed box ends at 4 triangles";
    }
    EXPECT_GT(p.vertexCount(), 8u) << "placing collapses add the vertices they place";
    const auto [half_tilt, half_mid] = flatness(h, h.q);
    const auto [placed_tilt, placed_mid] = flatness(p, p.q);
    EXPECT_EQ(half_mid, 0u);
    EXPECT_EQ(placed_mid, 3u);
    EXPECT_LT(placed_tilt, 0.75f * half_tilt);
}

TEST(ErrorCalibration, LevelErrorsFollowTheMeasuredDistanceOnEngineParts) {
    const Scene engine = importModel(test::kEngine);
    uint32_t pairs = 0, raw_under = 0, calibrated_under = 0;
    for (const Mesh& mesh : engine.meshes) {
        const ProgressiveMesh raw = uncalibrated(mesh);
        ProgressiveMesh pm = raw;
        const ErrorCalibration c = calibrateRecordedErrors(pm);
        ASSERT_EQ(pm.ecol, raw.ecol);
        ASSERT_EQ(pm.map, raw.map);
        ASSERT_EQ(pm.triangles, raw.triangles);
        for (uint32_t v = 0; v < pm.vertexCount(); ++v) ASSERT_GE(pm.error[v], raw.error[v]) << v;
        if (pm.vertexCount() > pm.q) {
            EXPECT_GE(c.levels_measured, 1u);
        }
        const ProgressiveMesh built = buildProgressiveMesh(mesh, Collapser::Fast);  // what prep stores
        ASSERT_EQ(built.error, pm.error);
        for (const uint32_t share : {3u, 10u}) {
            const uint32_t k = pm.q + (pm.vertexCount() - pm.q) / share;
            if (k >= pm.vertexCount()) continue;
            const double d =
                sampledHausdorff(pm.positions, pm.triangles, pm.positions, lodTriangles(pm, k), {2000, 11}).max;
            if (!(d > 1e-6)) continue;
            ++pairs;
            raw_under += levelError(raw, k) < 0.5 * d;
            calibrated_under += levelError(pm, k) < 0.5 * d;
        }
    }
    ASSERT_GT(pairs, 20u);
    RecordProperty("levels", std::to_string(pairs));
    RecordProperty("under_half_raw", std::to_string(raw_under));
    RecordProperty("under_half_calibrated", std::to_string(calibrated_under));
    EXPECT_GE(raw_under, pairs / 4) << "the raw errors were expected to understate; " << raw_under << " of " << pairs;
    EXPECT_LE(calibrated_under, pairs / 10) << calibrated_under << " of " << pairs << " levels understated over 2x";
}

// Issue 49, item 3: the calibrated errors come from sampled distances (calibrateRecordedErrors'
// `samples` area samples per surface, 32 in prep), a lower bound of the true distance that
// grows towards it with the samples. Against 8 192 samples, the level errors of the engine's
// parts (eight levels of each) at 32 to 2 048 samples: the share of levels more than 10 % off
// and the geometric mean ratio. Measured (docs/results.md, "HLODs from finer input"): 36 % and
// 0.87 at 32 samples, 15 % and 0.96 at 2 048: prep's errors are not converged; this checks
// that more samples come nearer.
TEST(ErrorCalibration, SampledLevelErrorsConvergeWithTheSampleCount) {
    const Scene engine = importModel(test::kEngine);
    const std::vector<uint32_t> counts{32, 128, 512, 2048, 8192};
    std::vector<std::vector<float>> errors(counts.size());  // per sample count, every level's error
    for (const Mesh& mesh : engine.meshes) {
        const ProgressiveMesh raw = uncalibrated(mesh);
        if (raw.vertexCount() <= raw.q + 8) continue;
        for (size_t i = 0; i < counts.size(); ++i) {
            ProgressiveMesh pm = raw;
            calibrateRecordedErrors(pm, counts[i]);
            for (uint32_t j = 0; j < 8; ++j) errors[i].push_back(levelError(pm, pm.q + (pm.vertexCount() - pm.q) * j / 8));
        }
    }
    const std::vector<float>& best = errors.back();
    ASSERT_GT(best.size(), 100u);
    std::vector<double> off(counts.size() - 1);         // share of levels more than 10 % from 8 192 samples' error
    std::vector<double> mean_ratio(counts.size() - 1);  // geometric mean of the errors' ratio to 8 192 samples
    for (size_t i = 0; i + 1 < counts.size(); ++i) {
        uint32_t far = 0, levels = 0;
        double ratio = 0.0;
        for (size_t l = 0; l < best.size(); ++l) {
            if (!(best[l] > 0.0f)) continue;
            ++levels;
            far += std::abs(errors[i][l] - best[l]) > 0.1f * best[l];
            ratio += std::log(std::max(errors[i][l], 1e-12f) / best[l]);
        }
        off[i] = double(far) / std::max(1u, levels);
        mean_ratio[i] = std::exp(ratio / std::max(1u, levels));
        std::printf("calibration with %u samples: %.1f %% of %u levels more than 10 %% from 8192 samples' error, geometric mean ratio %.3f\n",
                    counts[i], 100.0 * off[i], levels, mean_ratio[i]);
        RecordProperty("off_at_" + std::to_string(counts[i]), std::to_string(off[i]));
    }
    EXPECT_LT(off[3], off[0]) << "2 048 samples were expected nearer 8 192's errors than 32";
    EXPECT_LT(mean_ratio[0], mean_ratio[3]) << "sampled distances are lower bounds: more samples, larger errors";
    EXPECT_GT(mean_ratio[3], 0.9);
}

// A 10 x 10 plate of unit squares in z = 0 and a closed cube of half-width `half` at `centre`.
Mesh plateAndCube(const glm::vec3& centre, float half) {
    Mesh mesh;
    for (int y = 0; y <= 10; ++y)
        for (int x = 0; x <= 10; ++x) mesh.positions.push_back({float(x), float(y), 0.0f});
    for (uint32_t y = 0; y < 10; ++y)
        for (uint32_t x = 0; x < 10; ++x) {
            const uint32_t v = y * 11 + x;
            mesh.indices.insert(mesh.indices.end(), {v, v + 1, v + 12, v, v + 12, v + 11});
        }
    const uint32_t b = uint32_t(mesh.positions.size());
    for (int i = 0; i < 8; ++i)
        mesh.positions.push_back(centre + half * glm::vec3(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1));
    for (const uint32_t c : {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5})
        mesh.indices.push_back(b + c);
    return mesh;
}

// An HLOD's small objects vanish under clustering; the picture then changes only within each
// one's extent, however far the nearest surface left. A 10 x 10 plate and a cube 0.02 wide 5
// above it (the plate simplifies without error): the levels without the cube are over 5 away
// from the full detail, uncapped; their calibrated errors are the cube's extent, 0.035.
TEST(ErrorCalibration, AVanishedComponentCostsItsExtentNotItsDistance) {
    const Mesh mesh = plateAndCube(glm::vec3(5.2f, 5.2f, 5.2f), 0.01f);
    const ProgressiveMesh pm = buildClusteredProgressiveMesh(mesh);
    uint32_t vanished = 0;
    for (uint32_t k = pm.vertexCount(); k >= pm.q && k > 0; --k) {
        const double d = sampledHausdorff(pm.positions, pm.triangles, pm.positions, lodTriangles(pm, k), {2000, 11}).max;
        if (d < 4.9) continue;
        ++vanished;
        EXPECT_LE(levelError(pm, k), 0.1f) << "level " << k << " of " << pm.vertexCount() << ", uncapped distance " << d;
    }
    EXPECT_GT(vanished, 0u) << "the cube was expected to vanish at some level";
}

}  // namespace
}  // namespace occ

namespace occ {
namespace {

// Issue 49, item 2: an HLOD vertex's normal is the full detail's it stands for. A 10 x 10 plate
// and a small cube above it: every plate vertex (and every cluster of plate vertices) has the
// plate's normal up to sign; the cube's corners, where three faces meet, have none. An open
// 16-sided tube: every vertex has its radial direction.
TEST(HlodVertexNormals, APlateHasItsNormalACornerNoneATubeItsRadii) {
    const Mesh mesh = plateAndCube(glm::vec3(5.2f, 5.2f, 3.0f), 0.5f);
    const ProgressiveMesh pm = buildClusteredProgressiveMesh(mesh);
    const std::vector<uint32_t> normals = hlodVertexNormals(pm);
    ASSERT_EQ(normals.size(), pm.vertexCount());
    uint32_t plate = 0, corners = 0;
    for (uint32_t v = 0; v < pm.vertexCount(); ++v) {
        const glm::vec3& p = pm.positions[v];
        if (std::abs(p.z) < 1e-4f) {
            // A plate vertex, or a cluster of plate vertices placed on the plate.
            if (normals[v] == oss::kNoNormal) continue;  // a cluster that took a cube corner too
            ++plate;
            EXPECT_GT(std::abs(oss::decodeNormal(normals[v]).z), 0.9999f) << "vertex " << v;
        } else if (std::abs(std::abs(p.x - 5.2f) - 0.5f) < 1e-4f && std::abs(std::abs(p.y - 5.2f) - 0.5f) < 1e-4f &&
                   std::abs(std::abs(p.z - 3.0f) - 0.5f) < 1e-4f) {
            ++corners;
            EXPECT_EQ(normals[v], oss::kNoNormal) << "cube corner " << v;
        }
    }
    EXPECT_GE(plate, 121u);
    EXPECT_EQ(corners, 8u);

    Mesh tube;
    constexpr int kSides = 16;
    for (int ring = 0; ring <= 4; ++ring)
        for (int s = 0; s < kSides; ++s) {
            const float a = 2.0f * 3.14159265f * float(s) / kSides;
            tube.positions.push_back({std::cos(a), std::sin(a), float(ring)});
        }
    for (uint32_t ring = 0; ring < 4; ++ring)
        for (uint32_t s = 0; s < kSides; ++s) {
            const uint32_t a = ring * kSides + s, b2 = ring * kSides + (s + 1) % kSides;
            tube.indices.insert(tube.indices.end(), {a, b2, b2 + kSides, a, b2 + kSides, a + kSides});
        }
    const ProgressiveMesh tube_pm = buildProgressiveMesh(tube, Collapser::Fast);
    const std::vector<uint32_t> tube_normals = hlodVertexNormals(tube_pm);
    for (uint32_t v = 0; v < tube_pm.vertexCount(); ++v) {
        ASSERT_NE(tube_normals[v], oss::kNoNormal) << "tube vertex " << v;
        const glm::vec3 radial = glm::normalize(glm::vec3(tube_pm.positions[v].x, tube_pm.positions[v].y, 0.0f));
        EXPECT_GT(std::abs(glm::dot(oss::decodeNormal(tube_normals[v]), radial)), 0.99f) << "tube vertex " << v;
    }
}

}  // namespace
}  // namespace occ
