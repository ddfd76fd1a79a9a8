// SPDX-License-Identifier: MIT
#include "import/import.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>

namespace occ {
namespace {

using test::writeFixture;

TEST(ImportObj, OneObjectPerGroupWithPolygonsTriangulated) {
    const std::string path = writeFixture("groups.obj",
                                          "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                                          "g first\nf 1 2 3 4\n"
                                          "g second\nf 2 5 3\n");
    const Scene s = importModel(path);
    ASSERT_EQ(s.objects.size(), 2u);
    EXPECT_EQ(s.meshes[s.objects[0].mesh].name, "first");
    EXPECT_EQ(s.meshes[s.objects[0].mesh].triangleCount(), 2u);  // quad -> 2 triangles
    EXPECT_EQ(s.meshes[s.objects[0].mesh].positions.size(), 4u);
    EXPECT_EQ(s.meshes[s.objects[1].mesh].name, "second");
    EXPECT_EQ(s.meshes[s.objects[1].mesh].triangleCount(), 1u);
    EXPECT_EQ(s.meshes[s.objects[1].mesh].positions.size(), 3u);  // only the vertices it uses
    EXPECT_EQ(s.triangleCount(), 3u);
}

TEST(ImportObj, FileWithoutGroupsIsOneObjectAndPentagonGivesThreeTriangles) {
    const std::string path = writeFixture("penta.obj", "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\nf 1 2 3 4 5\n");
    const Scene s = importModel(path);
    ASSERT_EQ(s.objects.size(), 1u);
    const Mesh& m = s.meshes[0];
    EXPECT_EQ(m.triangleCount(), 3u);  // ear clipping: tests/unit/test_import_polygons.cpp
}

TEST(ImportOff, CubeOfQuadsBecomesTwelveTriangles) {
    const std::string path = writeFixture("cube.off",
                                          "OFF\n8 6 0\n"
                                          "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
                                          "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n");
    const Scene s = importModel(path);
    ASSERT_EQ(s.objects.size(), 1u);
    EXPECT_EQ(s.triangleCount(), 12u);
    EXPECT_EQ(s.vertexCount(), 8u);
    const Bounds b = s.worldBounds();
    EXPECT_EQ(b.min, glm::vec3(0.0f));
    EXPECT_EQ(b.max, glm::vec3(1.0f));
}

TEST(ImportPly, AsciiTriangleAndQuad) {
    const std::string path = writeFixture("tq.ply",
                                          "ply\nformat ascii 1.0\nelement vertex 5\n"
                                          "property float x\nproperty float y\nproperty float z\n"
                                          "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
                                          "0 0 0\n1 0 0\n1 1 0\n0 1 0\n2 0 0\n3 0 1 2\n4 1 4 2 3\n");
    const Scene s = importModel(path);
    EXPECT_EQ(s.objects.size(), 1u);
    EXPECT_EQ(s.triangleCount(), 3u);
}

// Binary PLY of both byte orders, with properties and elements the importer reads past.
std::string binaryPly(bool big) {
    std::string h = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                    " 1.0\ncomment made by a test\nelement vertex 4\nproperty double x\nproperty float nx\n"
                    "property double y\nproperty double z\nproperty uchar red\n"
                    "element face 2\nproperty list uchar uint vertex_indices\nproperty short flags\n"
                    "element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n";
    const auto put = [&](const void* p, size_t n) {
        std::string b(static_cast<const char*>(p), n);
        if (big) std::reverse(b.begin(), b.end());
        h += b;
    };
    const double xy[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 2}};
    for (const auto& v : xy) {
        const float n = 1;
        const uint8_t red = 7;
        put(&v[0], 8), put(&n, 4), put(&v[1], 8), put(&v[2], 8), put(&red, 1);
    }
    const uint32_t faces[2][4] = {{3, 0, 1, 2}, {3, 0, 2, 3}};
    for (const auto& f : faces) {
        const uint8_t count = 3;
        const int16_t flags = -1;
        put(&count, 1);
        for (int k = 1; k < 4; ++k) put(&f[k], 4);
        put(&flags, 2);
    }
    const int32_t e[2] = {0, 1};
    put(&e[0], 4), put(&e[1], 4);
    return h;
}

TEST(ImportPly, BinaryOfBothByteOrdersWithPropertiesReadPast) {
    for (bool big : {false, true}) {
        SCOPED_TRACE(big ? "big endian" : "little endian");
        const Scene s = importModel(writeFixture(big ? "be.ply" : "le.ply", binaryPly(big)));
        EXPECT_EQ(s.triangleCount(), 2u);
        EXPECT_EQ(s.worldBounds().max, glm::vec3(1, 1, 2));
        // Cut anywhere in the body: truncated, never a crash.
        const std::string whole = binaryPly(big);
        const size_t body = whole.find("end_header\n") + 11;
        for (size_t n = body; n < whole.size(); n += 7)
            EXPECT_THROW(importModel(writeFixture("cut.ply", whole.substr(0, n))), InputError) << n;
    }
}

TEST(ImportPly, CountsThatPromiseMoreThanTheFileAreRefusedBeforeAllocating) {
    const std::string path = writeFixture("huge.ply",
                                          "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n"
                                          "property float x\nproperty float y\nproperty float z\nend_header\n");
    try {
        importModel(path);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("do not fit"), std::string::npos) << e.what();
    }
}

TEST(ImportStl, BinaryTrianglesShareMergedVertices) {
    std::string b(80, ' ');
    const uint32_t count = 2;
    b.append(reinterpret_cast<const char*>(&count), 4);
    const float tris[2][12] = {{0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 1, 0}, {0, 0, 1, 0, 0, 0, 1, 1, 0, 0, 1, 0}};
    for (const auto& t : tris) {
        b.append(reinterpret_cast<const char*>(t), 48);
        b.append(2, '\0');
    }
    b.replace(0, 5, "solid");  // binary files may begin with "solid" too
    const Scene s = importModel(writeFixture("bin.stl", b));
    EXPECT_EQ(s.triangleCount(), 2u);
    EXPECT_EQ(s.vertexCount(), 4u);
}

TEST(ImportStl, MalformedAsciiLinesSayWhichLine) {
    const auto rejected = [](const std::string& text, const std::string& what) {
        const std::string path = writeFixture("m.stl", text);
        try {
            importModel(path);
            ADD_FAILURE() << "accepted: " << text;
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        }
    };
    const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n";
    rejected("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 blah\n", "line 4: 'blah' is not a number");
    rejected("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nvertex 2 2 0\nendloop\nendfacet\nendsolid\n",
             "line 2: the facet has more than 3 vertices");
    rejected("solid t\n" + facet, "no endsolid");
    rejected("solid t\n" + facet + "endsolid t\ngarbage\n", "line 10: unknown keyword 'garbage'");
}

TEST(ImportStl, AsciiFacetsShareMergedVertices) {
    const std::string path = writeFixture("two.stl",
                                          "solid t\n"
                                          "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 1 1 0\nendloop\nendfacet\n"
                                          "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n"
                                          "endsolid t\n");
    const Scene s = importModel(path);
    EXPECT_EQ(s.triangleCount(), 2u);
    EXPECT_EQ(s.vertexCount(), 4u);
}

// A one-triangle glTF whose buffer is embedded as a data URI; `nodes` and `primitives` are JSON.
std::string gltfWithTriangle(const std::string& nodes, const std::string& scene_nodes, const std::string& primitives) {
    std::vector<unsigned char> bin(36 + 6 + 2);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(bin.data(), pos, 36);
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data() + 36, idx, 6);
    return R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":)" + scene_nodes + R"(}],"nodes":)" + nodes +
           R"(,"meshes":[{"primitives":)" + primitives +
           R"(}],"materials":[{"pbrMetallicRoughness":{"baseColorFactor":[0.25,0.5,0.75,1]}}],)"
           R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]},)"
           R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],)"
           R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],)"
           R"("buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,)" +
           test::base64(bin) + R"("}]})";
}

const char* kTrianglePrimitive = R"([{"attributes":{"POSITION":0},"indices":1,"material":0}])";

TEST(ImportGltf, NodeTransformsAreFlattenedParentTimesChild) {
    // parent: translate (10,0,0); child: uniform scale 2 then rotation of 90 degrees about z.
    const std::string nodes =
        R"([{"translation":[10,0,0],"children":[1]},{"mesh":0,"scale":[2,2,2],"rotation":[0,0,0.7071067811865476,0.7071067811865476]}])";
    const Scene s = importModel(writeFixture("tr.gltf", gltfWithTriangle(nodes, "[0]", kTrianglePrimitive)));
    ASSERT_EQ(s.objects.size(), 1u);
    const glm::vec3 p = s.objects[0].world * glm::vec4(1, 0, 0, 1);  // (1,0,0) -> scale (2,0,0) -> rot (0,2,0) -> (10,2,0)
    EXPECT_NEAR(p.x, 10.0f, 1e-5f);
    EXPECT_NEAR(p.y, 2.0f, 1e-5f);
    EXPECT_NEAR(p.z, 0.0f, 1e-5f);
    EXPECT_EQ(s.objects[0].color, glm::vec4(0.25f, 0.5f, 0.75f, 1.0f));
}

TEST(ImportGltf, MatrixNodeIsUsedColumnMajor) {
    const std::string nodes = R"([{"mesh":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1]}])";
    const Scene s = importModel(writeFixture("mat.gltf", gltfWithTriangle(nodes, "[0]", kTrianglePrimitive)));
    const Bounds b = s.worldBounds();
    EXPECT_EQ(b.min, glm::vec3(5, 6, 7));
    EXPECT_EQ(b.max, glm::vec3(6, 7, 7));
}

TEST(ImportGltf, InstancesShareOneMesh) {
    const std::string nodes = R"([{"mesh":0},{"mesh":0,"translation":[0,0,3]},{"mesh":0,"translation":[0,0,6]}])";
    const Scene s = importModel(writeFixture("inst.gltf", gltfWithTriangle(nodes, "[0,1,2]", kTrianglePrimitive)));
    EXPECT_EQ(s.objects.size(), 3u);
    EXPECT_EQ(s.meshes.size(), 1u);
    EXPECT_EQ(s.triangleCount(), 3u);
    EXPECT_EQ(s.worldBounds().max.z, 6.0f);
}

TEST(ImportGltf, PointsAndLinesAreSkippedAndCounted) {
    const std::string prims = R"([{"attributes":{"POSITION":0},"indices":1},{"attributes":{"POSITION":0},"mode":0},)"
                              R"({"attributes":{"POSITION":0},"mode":1,"indices":1},{"attributes":{"POSITION":0},"mode":3}])";
    const Scene s = importModel(writeFixture("mixed.gltf", gltfWithTriangle(R"([{"mesh":0}])", "[0]", prims)));
    EXPECT_EQ(s.objects.size(), 1u);
    EXPECT_EQ(s.skipped.points, 1u);
    EXPECT_EQ(s.skipped.lines, 2u);
}

TEST(ImportGltf, StripAndFanAreTriangulatedWithConsistentWinding) {
    // Four non-indexed vertices: a strip gives (0,1,2),(2,1,3); a fan gives (0,1,2),(0,2,3).
    std::vector<unsigned char> bin(48);
    const float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
    std::memcpy(bin.data(), pos, 48);
    const std::string doc =
        R"({"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
        R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"mode":5},{"attributes":{"POSITION":0},"mode":6}]}],)"
        R"("accessors":[{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}],)"
        R"("bufferViews":[{"buffer":0,"byteLength":48}],"buffers":[{"byteLength":48,"uri":"data:application/octet-stream;base64,)" +
        test::base64(bin) + R"("}]})";
    const Scene s = importModel(writeFixture("stripfan.gltf", doc));
    ASSERT_EQ(s.meshes.size(), 2u);
    EXPECT_EQ(s.meshes[0].indices, (std::vector<uint32_t>{0, 1, 2, 2, 1, 3}));
    EXPECT_EQ(s.meshes[1].indices, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
}

// Positions as KHR_mesh_quantization allows them (normalized 16-bit integers with a byte
// stride) and through sparse accessors (on a buffer view, and on zeros without one).
TEST(ImportGltf, QuantizedAndSparsePositions) {
    std::vector<unsigned char> bin(96, 0);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(bin.data(), pos, 36);
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data() + 36, idx, 6);
    const uint16_t sparse_idx[2] = {1, 2};
    std::memcpy(bin.data() + 44, sparse_idx, 4);
    const float sparse_val[6] = {5, 0, 0, 0, 5, 0};
    std::memcpy(bin.data() + 48, sparse_val, 24);
    const int16_t q[12] = {0, 0, 0, 0, 32767, 0, 0, 0, 0, -32767, 0, 0};  // stride 8: x y z pad
    std::memcpy(bin.data() + 72, q, 24);
    const std::string json =
        R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_mesh_quantization"],"extensionsRequired":["KHR_mesh_quantization"],)"
        R"("scene":0,"scenes":[{"nodes":[0,1,2]}],"nodes":[{"mesh":0},{"mesh":1},{"mesh":2}],)"
        R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]},)"
        R"({"primitives":[{"attributes":{"POSITION":2},"indices":1}]},{"primitives":[{"attributes":{"POSITION":3},"indices":1}]}],)"
        R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",)"
        R"("sparse":{"count":2,"indices":{"bufferView":2,"componentType":5123},"values":{"bufferView":3}}},)"
        R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},)"
        R"({"bufferView":4,"componentType":5122,"normalized":true,"count":3,"type":"VEC3"},)"
        R"({"componentType":5126,"count":3,"type":"VEC3",)"
        R"("sparse":{"count":2,"indices":{"bufferView":2,"componentType":5123},"values":{"bufferView":3}}}],)"
        R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6},)"
        R"({"buffer":0,"byteOffset":44,"byteLength":4},{"buffer":0,"byteOffset":48,"byteLength":24},)"
        R"({"buffer":0,"byteOffset":72,"byteLength":24,"byteStride":8}],)"
        R"("buffers":[{"byteLength":96,"uri":"data:application/octet-stream;base64,)" + test::base64(bin) + R"("}]})";
    const Scene s = importModel(writeFixture("qs.gltf", json));
    ASSERT_EQ(s.meshes.size(), 3u);
    EXPECT_EQ(s.meshes[0].positions, (std::vector<glm::vec3>{{0, 0, 0}, {5, 0, 0}, {0, 5, 0}}));
    EXPECT_EQ(s.meshes[1].positions, (std::vector<glm::vec3>{{0, 0, 0}, {1, 0, 0}, {0, -1, 0}}));
    EXPECT_EQ(s.meshes[2].positions, (std::vector<glm::vec3>{{0, 0, 0}, {5, 0, 0}, {0, 5, 0}}));
}

// EXT_mesh_gpu_instancing: one object per instance, the node's transform times the instance's.
TEST(ImportGltf, GpuInstancesBecomeObjectsSharingTheMesh) {
    std::vector<unsigned char> bin(44 + 24 + 32, 0);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(bin.data(), pos, 36);
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data() + 36, idx, 6);
    const float t[6] = {10, 0, 0, 0, 20, 0};
    std::memcpy(bin.data() + 44, t, 24);
    const float r[8] = {0, 0, 0.7071067811865476f, 0.7071067811865476f, 0, 0, 0, 1};
    std::memcpy(bin.data() + 68, r, 32);
    const std::string json =
        R"({"asset":{"version":"2.0"},"extensionsUsed":["EXT_mesh_gpu_instancing"],"extensionsRequired":["EXT_mesh_gpu_instancing"],)"
        R"("scene":0,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0,"translation":[0,0,1],)"
        R"("extensions":{"EXT_mesh_gpu_instancing":{"attributes":{"TRANSLATION":2,"ROTATION":3}}}}],)"
        R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],)"
        R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},)"
        R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"},)"
        R"({"bufferView":2,"componentType":5126,"count":2,"type":"VEC3"},{"bufferView":3,"componentType":5126,"count":2,"type":"VEC4"}],)"
        R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6},)"
        R"({"buffer":0,"byteOffset":44,"byteLength":24},{"buffer":0,"byteOffset":68,"byteLength":32}],)"
        R"("buffers":[{"byteLength":100,"uri":"data:application/octet-stream;base64,)" + test::base64(bin) + R"("}]})";
    const Scene s = importModel(writeFixture("inst.gltf", json));
    ASSERT_EQ(s.objects.size(), 2u);
    ASSERT_EQ(s.meshes.size(), 1u);
    const glm::vec3 a = s.objects[0].world * glm::vec4(1, 0, 0, 1);  // rotate 90 about z, + (10,0,0), + (0,0,1)
    EXPECT_NEAR(a.x, 10, 1e-5);
    EXPECT_NEAR(a.y, 1, 1e-5);
    EXPECT_NEAR(a.z, 1, 1e-5);
    const glm::vec3 b = s.objects[1].world * glm::vec4(1, 0, 0, 1);
    EXPECT_NEAR(b.x, 1, 1e-5);
    EXPECT_NEAR(b.y, 20, 1e-5);
    EXPECT_NEAR(b.z, 1, 1e-5);
}

TEST(ImportGltf, DefaultEngineHas115ObjectsAnd121496Triangles) {
    ASSERT_TRUE(std::filesystem::exists(test::kEngine)) << "install Debian's assimp-testmodels (launch/setup does)";
    const Scene s = importModel(test::kEngine);
    EXPECT_EQ(s.objects.size(), 115u);
    EXPECT_EQ(s.triangleCount(), 121496u);
    EXPECT_LT(s.meshes.size(), s.objects.size());  // the engine instances parts (bolts, rods)
}

TEST(ImportErrors, MessageNamesTheFile) {
    const std::string path = writeFixture("bad.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 7\n");
    try {
        importModel(path);
        FAIL() << "accepted a face with an out-of-range vertex";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
        EXPECT_EQ(e.file(), path);
    }
}

TEST(ImportErrors, EveryTruncationOfAGlbIsRejectedCleanly) {
    // Style: each decoder is fed every truncation of a valid input (under ASan in the sanitize build).
    const std::string whole = writeFixture("whole.gltf", gltfWithTriangle(R"([{"mesh":0}])", "[0]", kTrianglePrimitive));
    ASSERT_NO_THROW(importModel(whole));
    const std::vector<char> engine = test::readBytes(test::kEngine);
    ASSERT_GT(engine.size(), 1000u);
    // Every length of the header and the JSON's first 4 KiB, then about 150 cuts strided through
    // the rest of the JSON and the binary chunk (each cut is a file written and read back: a
    // stride of 1 KiB wrote 1.6 GB and took 80 s under ASan).
    std::vector<size_t> lengths;
    for (size_t n = 0; n < 4096 && n < engine.size(); ++n) lengths.push_back(n);
    for (size_t n = 4096; n < engine.size(); n += 12007) lengths.push_back(n);
    for (size_t n : lengths) {
        const std::string cut = writeFixture("cut.glb", std::string(engine.begin(), engine.begin() + long(n)));
        EXPECT_THROW(importModel(cut), InputError) << "length " << n;
    }
}

}  // namespace
}  // namespace occ
