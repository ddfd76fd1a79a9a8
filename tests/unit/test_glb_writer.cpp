// SPDX-License-Identifier: MIT
#include "import/glb_writer.h"
#include "import/grid.h"
#include "import/import.h"
#include "test_support.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

namespace occ {
namespace {

Scene twoBoxes() {
    Scene s;
    Mesh box;
    box.name = "box";
    box.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    box.indices = {0, 2, 1, 0, 3, 2, 4, 5, 6, 4, 6, 7, 0, 1, 5, 0, 5, 4, 1, 2, 6, 1, 6, 5, 2, 3, 7, 2, 7, 6, 3, 0, 4, 3, 4, 7};
    box.color = {1.0f, 0.0f, 0.0f, 1.0f};
    s.meshes.push_back(box);
    Object a, b;
    a.color = b.color = box.color;
    b.world = glm::translate(glm::mat4(1.0f), glm::vec3(3, 0, 0));
    s.objects = {a, b};
    return s;
}

TEST(GlbWriter, RoundTripKeepsGeometryTransformsColoursAndSharing) {
    const Scene in = twoBoxes();
    const std::string path = (test::scratchDir() / "boxes.glb").string();
    writeSceneGlb(path, in);
    const Scene out = importModel(path);
    ASSERT_EQ(out.objects.size(), 2u);
    EXPECT_EQ(out.meshes.size(), 1u);
    EXPECT_EQ(out.meshes[0].positions, in.meshes[0].positions);
    EXPECT_EQ(out.meshes[0].indices, in.meshes[0].indices);
    EXPECT_EQ(out.objects[1].world, in.objects[1].world);
    EXPECT_EQ(out.objects[0].color, in.meshes[0].color);
    EXPECT_EQ(out.worldBounds().max, glm::vec3(4, 1, 1));
}

TEST(GlbWriter, SameSceneSameBytes) {
    const std::string a = (test::scratchDir() / "a.glb").string(), b = (test::scratchDir() / "b.glb").string();
    writeSceneGlb(a, twoBoxes());
    writeSceneGlb(b, twoBoxes());
    EXPECT_EQ(test::readBytes(a), test::readBytes(b));
}

TEST(GlbWriter, LargeMeshUses32BitIndices) {
    Scene s;
    Mesh m;
    for (uint32_t i = 0; i < 70000; ++i) m.positions.push_back({float(i), float(i % 2), 0.0f});
    for (uint32_t i = 0; i + 2 < 70000; i += 3) m.indices.insert(m.indices.end(), {i, i + 1, i + 2});
    s.meshes.push_back(m);
    s.objects.push_back(Object{});
    const std::string path = (test::scratchDir() / "big.glb").string();
    writeSceneGlb(path, s);
    EXPECT_EQ(importModel(path).meshes[0].indices, m.indices);
}

TEST(Grid, TilesByInstancingWithTranslatedCopies) {
    const std::string path = (test::scratchDir() / "grid.glb").string();
    GridOptions g;
    g.nx = 3;
    g.ny = 2;
    g.nz = 1;
    g.spacing = 10.0f;
    writeGrid(path, twoBoxes(), g);
    const Scene out = importModel(path);
    EXPECT_EQ(out.objects.size(), 12u);
    EXPECT_EQ(out.meshes.size(), 1u);
    const Bounds b = out.worldBounds();
    EXPECT_EQ(b.min, glm::vec3(0, 0, 0));
    EXPECT_EQ(b.max, glm::vec3(24, 11, 1));  // last tile origin (20,10,0) + second box at x 3..4
}

}  // namespace
}  // namespace occ
