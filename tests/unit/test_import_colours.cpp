// SPDX-License-Identifier: MIT
// Each object in its model's colour (issue 49): glTF baseColorFactor times COLOR_0, OBJ's usemtl
// with the .mtl's Kd, PLY vertex colours; colours are linear (scene/colour.h).
#include "import/import.h"
#include "import/scene_source.h"
#include "scene/colour.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cstring>

namespace occ {
namespace {

using test::writeFixture;

void expectColour(const glm::vec4& c, const glm::vec3& want, float tolerance = 1e-5f) {
    EXPECT_NEAR(c.r, want.r, tolerance);
    EXPECT_NEAR(c.g, want.g, tolerance);
    EXPECT_NEAR(c.b, want.b, tolerance);
}

glm::vec3 linear(float r, float g, float b) { return {srgbToLinear(r), srgbToLinear(g), srgbToLinear(b)}; }

TEST(Colour, SrgbRoundTripsThroughLinearAndKeepsItsEnds) {
    EXPECT_EQ(srgbToLinear(0.0f), 0.0f);
    EXPECT_NEAR(srgbToLinear(1.0f), 1.0f, 1e-6f);
    EXPECT_NEAR(srgbToLinear(0.5f), 0.21404f, 1e-5f);  // IEC 61966-2-1
    for (float c = 0; c <= 1.0f; c += 0.05f) EXPECT_NEAR(linearToSrgb(srgbToLinear(c)), c, 1e-5f);
}

TEST(ImportObj, UsemtlTakesTheDiffuseColourOfItsLibraryAndSplitsAGroupByMaterial) {
    writeFixture("colours.mtl",
                 "# two materials\nnewmtl roof\nKa 0 0 0\nKd 0.6 0.3 0.1\n\nnewmtl wall paint\nKd 0.5\n");
    const Scene s = importObj(writeFixture("colours.obj",
                                           "mtllib colours.mtl\n"
                                           "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                           "g house\nusemtl roof\nf 1 2 3\n"
                                           "usemtl wall paint\nf 2 4 3\n"
                                           "usemtl roof\nf 1 3 4\n"));
    ASSERT_EQ(s.objects.size(), 2u);  // (house, roof) with two faces, (house, wall paint) with one
    EXPECT_EQ(s.meshes[s.objects[0].mesh].name, "house (roof)");
    EXPECT_EQ(s.meshes[s.objects[0].mesh].triangleCount(), 2u);
    expectColour(s.objects[0].color, linear(0.6f, 0.3f, 0.1f));
    EXPECT_EQ(s.meshes[s.objects[1].mesh].name, "house (wall paint)");
    expectColour(s.objects[1].color, linear(0.5f, 0.5f, 0.5f));  // "Kd r" is r r r
    EXPECT_EQ(s.skipped.unknown_materials, 0u);
}

TEST(ImportObj, OneMaterialColoursTheWholeFile) {
    writeFixture("one.mtl", "newmtl steel\nKd 0.2 0.4 0.8\n");
    const Scene s = importObj(writeFixture("one.obj", "mtllib one.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl steel\nf 1 2 3\n"));
    ASSERT_EQ(s.objects.size(), 1u);
    expectColour(s.objects[0].color, linear(0.2f, 0.4f, 0.8f));
}

TEST(ImportObj, AMaterialNoLibraryDefinesIsCountedAndDrawnGrey) {
    const Scene s = importObj(writeFixture("nolib.obj", "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
                                                        "usemtl a\nf 1 2 3\nusemtl b\nf 2 4 3\nusemtl a\nf 1 3 4\n"));
    ASSERT_EQ(s.objects.size(), 2u);
    EXPECT_EQ(s.skipped.unknown_materials, 2u);  // a and b, each counted once
    expectColour(s.objects[0].color, glm::vec3(Mesh{}.color));
}

TEST(ImportObj, AMalformedKdNamesTheLibraryAndLine) {
    writeFixture("bad.mtl", "newmtl x\nKd 0.1 zero 0.3\n");
    try {
        importObj(writeFixture("badmtl.obj", "mtllib bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl x\nf 1 2 3\n"));
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("bad.mtl"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
    }
}

TEST(ImportObj, VertexColoursGiveTheObjectTheirMean) {
    const Scene s = importObj(writeFixture("vc.obj", "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n"));
    ASSERT_EQ(s.objects.size(), 1u);
    const float third = srgbToLinear(1.0f) / 3;
    expectColour(s.objects[0].color, {third, third, third});
}

TEST(ImportPly, VertexColoursInBytesAreSrgbAndGiveTheirMean) {
    const Scene s = importPly(writeFixture("vc.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                                     "property float x\nproperty float y\nproperty float z\n"
                                                     "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                                                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                                     "0 0 0 255 0 0\n1 0 0 255 0 0\n0 1 0 0 0 255\n3 0 1 2\n"));
    ASSERT_EQ(s.objects.size(), 1u);
    expectColour(s.objects[0].color, {2.0f / 3, 0.0f, 1.0f / 3});
}

TEST(ImportPly, WithoutColoursTheObjectIsGrey) {
    const Scene s = importPly(writeFixture("nc.ply", "ply\nformat ascii 1.0\nelement vertex 3\n"
                                                     "property float x\nproperty float y\nproperty float z\n"
                                                     "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                                     "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"));
    ASSERT_EQ(s.objects.size(), 1u);
    expectColour(s.objects[0].color, glm::vec3(Mesh{}.color));
}

// One triangle with baseColorFactor (0.5, 1, 1) and COLOR_0 as normalized bytes: red, green and
// (0, 0, 0.6): the object's colour is the factor times the colours' mean, (1/6, 1/3, 0.2).
// The buffer is a file beside the .gltf so that the streaming reader takes it too.
std::string gltfWithVertexColours(const std::string& name) {
    std::vector<unsigned char> bin(36 + 8 + 12);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(bin.data(), pos, 36);
    const uint16_t idx[4] = {0, 1, 2, 0};
    std::memcpy(bin.data() + 36, idx, 8);
    const unsigned char rgba[12] = {255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 153, 255};
    std::memcpy(bin.data() + 44, rgba, 12);
    writeFixture(name + ".bin", std::string(bin.begin(), bin.end()));
    return writeFixture(
        name + ".gltf",
        R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
        R"("meshes":[{"primitives":[{"attributes":{"POSITION":0,"COLOR_0":2},"indices":1,"material":0}]}],)"
        R"("materials":[{"pbrMetallicRoughness":{"baseColorFactor":[0.5,1,1,1]}}],)"
        R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},)"
        R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},)"
        R"({"bufferView":2,"componentType":5121,"normalized":true,"count":3,"type":"VEC4"}],)"
        R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6},)"
        R"({"buffer":0,"byteOffset":44,"byteLength":12}],)"
        R"("buffers":[{"byteLength":56,"uri":")" + name + R"(.bin"}]})");
}

TEST(ImportGltf, VertexColoursMultiplyTheBaseColourByTheirMean) {
    const Scene s = importModel(gltfWithVertexColours("vcol"));
    ASSERT_EQ(s.objects.size(), 1u);
    expectColour(s.objects[0].color, {1.0f / 6, 1.0f / 3, 0.2f});
}

TEST(ImportGltf, TheStreamingReaderGivesTheSameVertexColour) {
    const std::unique_ptr<SceneSource> source = openSceneSource(gltfWithVertexColours("vcol_stream"), {}, ReadMode::Stream);
    EXPECT_STREQ(source->how(), "streamed");
    ASSERT_EQ(source->objects().size(), 1u);
    expectColour(source->objects()[0].color, {1.0f / 6, 1.0f / 3, 0.2f});
    expectColour(source->mesh(0).color, {1.0f / 6, 1.0f / 3, 0.2f});
}

}  // namespace
}  // namespace occ
