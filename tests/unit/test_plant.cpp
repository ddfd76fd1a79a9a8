// SPDX-License-Identifier: MIT
#include "import/plant.h"

#include "scene/errors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

namespace occ {
namespace {

// One mid-sized plant shared by the read-only tests: 5000 objects, two floors' worth of hero
// bays, generated once.
const Scene& plant5000() {
    static const Scene scene = generatePlant({5000, 1});
    return scene;
}

template <class T>
bool sameBytes(const std::vector<T>& a, const std::vector<T>& b) {
    return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

bool sameScene(const Scene& a, const Scene& b) {
    if (a.meshes.size() != b.meshes.size() || a.objects.size() != b.objects.size()) return false;
    for (size_t i = 0; i < a.meshes.size(); ++i) {
        const Mesh &ma = a.meshes[i], &mb = b.meshes[i];
        if (ma.name != mb.name || !sameBytes(ma.positions, mb.positions) || !sameBytes(ma.indices, mb.indices) ||
            std::memcmp(&ma.color, &mb.color, sizeof(ma.color)) != 0)
            return false;
    }
    for (size_t i = 0; i < a.objects.size(); ++i) {
        const Object &oa = a.objects[i], &ob = b.objects[i];
        if (oa.mesh != ob.mesh || std::memcmp(&oa.world, &ob.world, sizeof(oa.world)) != 0 ||
            std::memcmp(&oa.color, &ob.color, sizeof(oa.color)) != 0)
            return false;
    }
    return true;
}

glm::vec3 toWorld(const Object& object, const glm::vec3& p) { return glm::vec3(object.world * glm::vec4(p, 1.0f)); }

TEST(Plant, HasExactlyTheRequestedObjectCount) {
    for (uint32_t n : {1u, 2u, 7u, 39u, 40u, 41u, 333u, 2000u, 2001u}) {
        const Scene scene = generatePlant({n, 3});
        EXPECT_EQ(scene.objects.size(), n);
        EXPECT_EQ(scene.meshes.size(), n);
    }
}

TEST(Plant, RejectsZeroAndTooManyObjects) {
    EXPECT_THROW(generatePlant({0, 1}), UsageError);
    EXPECT_THROW(generatePlant({kMaxPlantObjects + 1, 1}), UsageError);
    EXPECT_THROW(plantLayout({0, 1}), UsageError);
}

TEST(Plant, SameOptionsGiveBitIdenticalScenes) {
    EXPECT_TRUE(sameScene(generatePlant({3000, 42}), generatePlant({3000, 42})));
}

TEST(Plant, DifferentSeedsGiveDifferentScenes) {
    EXPECT_FALSE(sameScene(generatePlant({3000, 42}), generatePlant({3000, 43})));
}

TEST(Plant, ObjectsOwnTheirMeshAndShareItsColour) {
    const Scene& scene = plant5000();
    for (uint32_t i = 0; i < scene.objects.size(); ++i) {
        ASSERT_EQ(scene.objects[i].mesh, i);
        EXPECT_EQ(scene.objects[i].color, scene.meshes[i].color);
        // two finds instead of a concatenated needle: GCC 12 warns (-Wrestrict) on "_" + string
        const size_t at = scene.meshes[i].name.rfind(std::to_string(i));
        ASSERT_NE(at, std::string::npos);
        EXPECT_EQ(scene.meshes[i].name[at - 1], '_');
    }
}

TEST(Plant, IndicesAreInRangeAndTrianglesNonDegenerate) {
    for (const Mesh& mesh : plant5000().meshes) {
        ASSERT_EQ(mesh.indices.size() % 3, 0u) << mesh.name;
        for (size_t t = 0; t < mesh.indices.size(); t += 3) {
            const uint32_t a = mesh.indices[t], b = mesh.indices[t + 1], c = mesh.indices[t + 2];
            ASSERT_LT(std::max({a, b, c}), mesh.positions.size()) << mesh.name;
            ASSERT_TRUE(a != b && b != c && a != c) << mesh.name << " triangle " << t / 3;
            const glm::dvec3 pa(mesh.positions[a]), pb(mesh.positions[b]), pc(mesh.positions[c]);
            ASSERT_GT(glm::length(glm::cross(pb - pa, pc - pa)), 0.0) << mesh.name << " triangle " << t / 3;
        }
    }
}

TEST(Plant, PositionsAndMatricesAreFinite) {
    const Scene& scene = plant5000();
    for (const Mesh& mesh : scene.meshes)
        for (const glm::vec3& p : mesh.positions)
            ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) << mesh.name;
    for (const Object& object : scene.objects)
        for (int c = 0; c < 4; ++c)
            for (int r = 0; r < 4; ++r) ASSERT_TRUE(std::isfinite(object.world[c][r]));
}

TEST(Plant, TriangleCountsSpanBoxToFineTank) {
    size_t lo = SIZE_MAX, hi = 0;
    for (const Mesh& mesh : plant5000().meshes) {
        lo = std::min(lo, mesh.triangleCount());
        hi = std::max(hi, mesh.triangleCount());
    }
    EXPECT_EQ(lo, 12u);
    EXPECT_LE(hi, 20000u);
    EXPECT_GE(hi, 15000u);
}

TEST(Plant, SmallestPlantWithAHeroStillHasOne) {
    size_t hi = 0;
    for (const Mesh& mesh : generatePlant({2000, 9}).meshes) hi = std::max(hi, mesh.triangleCount());
    EXPECT_GE(hi, 15000u);
    EXPECT_LE(hi, 20000u);
}

TEST(Plant, MeshesShareVertices) {
    size_t vertices = 0, triangles = 0;
    for (const Mesh& mesh : plant5000().meshes) {
        vertices += mesh.positions.size();
        triangles += mesh.triangleCount();
    }
    // Closed meshes have about half as many vertices as triangles; unshared ones would have 3x.
    EXPECT_LT(vertices, triangles);
}

// Each directed edge once and its reverse once: closed, two-manifold and consistently wound;
// then a positive enclosed volume says the winding faces outward.
TEST(Plant, MeshesAreClosedAndWoundOutward) {
    for (const Mesh& mesh : plant5000().meshes) {
        std::vector<uint64_t> edges;
        edges.reserve(mesh.indices.size());
        double volume = 0.0;
        for (size_t t = 0; t < mesh.indices.size(); t += 3) {
            for (int k = 0; k < 3; ++k)
                edges.push_back(uint64_t(mesh.indices[t + k]) << 32 | mesh.indices[t + (k + 1) % 3]);
            const glm::dvec3 a(mesh.positions[mesh.indices[t]]), b(mesh.positions[mesh.indices[t + 1]]),
                c(mesh.positions[mesh.indices[t + 2]]);
            volume += glm::dot(a, glm::cross(b, c)) / 6.0;
        }
        std::sort(edges.begin(), edges.end());
        ASSERT_EQ(std::adjacent_find(edges.begin(), edges.end()), edges.end()) << mesh.name << " repeats an edge";
        for (uint64_t e : edges)
            ASSERT_TRUE(std::binary_search(edges.begin(), edges.end(), e << 32 | e >> 32)) << mesh.name << " has a hole";
        EXPECT_GT(volume, 0.0) << mesh.name;
    }
}

TEST(Plant, EveryKindIsPresent) {
    const Scene& scene = plant5000();
    for (const char* kind : {"slab_", "wall_", "column_", "girder_", "equipment_", "motor_", "tank_", "vessel_",
                             "sphere_", "pipe_", "tray_"}) {
        const bool found = std::any_of(scene.meshes.begin(), scene.meshes.end(),
                                       [&](const Mesh& m) { return m.name.rfind(kind, 0) == 0; });
        EXPECT_TRUE(found) << kind;
    }
}

TEST(Plant, LayoutGrowsWithTheObjectCount) {
    const PlantLayout small = plantLayout({100, 1});
    const PlantLayout large = plantLayout({100'000, 1});
    EXPECT_EQ(small.floors, 1u);
    EXPECT_EQ(large.floors, 6u);
    EXPECT_GE(uint64_t(large.floors) * large.baysX * large.baysZ * 40, 100'000u - 20);
    EXPECT_LE(large.baysZ, large.baysX);
}

TEST(Plant, EverythingStaysInsideTheBuilding) {
    const Scene& scene = plant5000();
    const PlantLayout layout = plantLayout({5000, 1});
    const float slack = 0.26f;  // outer walls and corner columns straddle the outline
    const glm::vec3 lo(-slack, -layout.slabThickness - slack, -slack);
    const glm::vec3 hi(layout.baysX * layout.bayPitch + slack, layout.floors * layout.storeyHeight + slack,
                       layout.baysZ * layout.bayPitch + slack);
    for (const Object& object : scene.objects)
        for (const glm::vec3& p : scene.meshes[object.mesh].positions) {
            const glm::vec3 w = toWorld(object, p);
            ASSERT_TRUE(glm::all(glm::greaterThanEqual(w, lo)) && glm::all(glm::lessThanEqual(w, hi)))
                << scene.meshes[object.mesh].name;
        }
}

// A walk path at eye height along the corridors must meet nothing: no triangle's world box may
// reach into a corridor between a floor and the clearance above it.
TEST(Plant, CorridorsAreClearToHeadHeight) {
    const Scene& scene = plant5000();
    const PlantLayout l = plantLayout({5000, 1});
    const float width = l.baysX * l.bayPitch, depth = l.baysZ * l.bayPitch, eps = 1e-3f;
    auto overlaps = [](float lo, float hi, float band_lo, float band_hi) { return lo < band_hi && hi > band_lo; };
    // Does [lo, hi] reach into any bay's corridor band on this axis?
    auto inBand = [&](float lo, float hi) {
        for (int b = int(std::floor(lo / l.bayPitch)); b <= int(std::floor(hi / l.bayPitch)); ++b)
            if (overlaps(lo, hi, b * l.bayPitch + l.corridorMin + eps, b * l.bayPitch + l.corridorMax - eps))
                return true;
        return false;
    };
    auto inHeadroom = [&](float lo, float hi) {
        for (int f = int(std::floor(lo / l.storeyHeight)); f <= int(std::floor(hi / l.storeyHeight)); ++f)
            if (overlaps(lo, hi, f * l.storeyHeight + eps, f * l.storeyHeight + l.corridorClearance)) return true;
        return false;
    };
    for (const Object& object : scene.objects) {
        const Mesh& mesh = scene.meshes[object.mesh];
        for (size_t t = 0; t < mesh.indices.size(); t += 3) {
            glm::vec3 lo(INFINITY), hi(-INFINITY);
            for (int k = 0; k < 3; ++k) {
                const glm::vec3 w = toWorld(object, mesh.positions[mesh.indices[t + k]]);
                lo = glm::min(lo, w);
                hi = glm::max(hi, w);
            }
            if (!inHeadroom(lo.y, hi.y)) continue;
            const bool in_x_corridor = inBand(lo.z, hi.z) && overlaps(lo.x, hi.x, 0.5f, width - 0.5f);
            const bool in_z_corridor = inBand(lo.x, hi.x) && overlaps(lo.z, hi.z, 0.5f, depth - 0.5f);
            ASSERT_FALSE(in_x_corridor || in_z_corridor) << mesh.name << " triangle " << t / 3;
        }
    }
}

}  // namespace
}  // namespace occ
