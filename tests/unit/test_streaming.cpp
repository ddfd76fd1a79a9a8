// SPDX-License-Identifier: MIT
// Streaming preparation: the glTF writer that holds one mesh at a time, the glTF reader that
// reads one mesh at a time, and the .oss writer that spools sections; each against the
// whole-scene path it replaces for large scenes.
#include "import/glb_writer.h"
#include "import/import.h"
#include "import/plant.h"
#include "import/scene_source.h"
#include "prep/prepare.h"
#include "scene/errors.h"
#include "scene/oss_file.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace occ {
namespace {

std::string scratch(const std::string& name) { return (test::scratchDir() / name).string(); }

void expectSameScene(const SceneSource& source, const Scene& whole) {
    ASSERT_EQ(source.objects().size(), whole.objects.size());
    ASSERT_EQ(source.meshCount(), whole.meshes.size());
    for (size_t i = 0; i < whole.objects.size(); ++i) {
        EXPECT_EQ(source.objects()[i].mesh, whole.objects[i].mesh) << "object " << i;
        EXPECT_EQ(source.objects()[i].world, whole.objects[i].world) << "object " << i;
        EXPECT_EQ(source.objects()[i].color, whole.objects[i].color) << "object " << i;
    }
    for (uint32_t m = 0; m < whole.meshes.size(); ++m) {
        const Mesh mesh = source.mesh(m);
        EXPECT_EQ(mesh.positions, whole.meshes[m].positions) << "mesh " << m;
        EXPECT_EQ(mesh.indices, whole.meshes[m].indices) << "mesh " << m;
        EXPECT_EQ(mesh.color, whole.meshes[m].color) << "mesh " << m;
        EXPECT_EQ(source.meshTriangles(m), whole.meshes[m].triangleCount()) << "mesh " << m;
    }
}

TEST(StreamingGltf, WritePlantGivesTheSameSceneAsGeneratePlantAsGlbAndAsGltf) {
    const PlantOptions options{400, 3};
    const Scene plant = generatePlant(options);
    for (const char* name : {"plant.glb", "plant.gltf"}) {
        PlantProgress progress;
        writePlant(scratch(name), options, &progress);
        EXPECT_EQ(progress.objects, 400u);
        EXPECT_EQ(progress.triangles, plant.triangleCount());
        const Scene back = importModel(scratch(name));
        ASSERT_EQ(back.objects.size(), plant.objects.size()) << name;
        for (size_t i = 0; i < plant.objects.size(); ++i) {
            EXPECT_EQ(back.objects[i].world, plant.objects[i].world);
            EXPECT_EQ(back.meshes[back.objects[i].mesh].positions, plant.meshes[plant.objects[i].mesh].positions);
            EXPECT_EQ(back.meshes[back.objects[i].mesh].indices, plant.meshes[plant.objects[i].mesh].indices);
        }
    }
    EXPECT_TRUE(std::filesystem::exists(scratch("plant.bin")));  // the .gltf's buffer, beside it
    for (const auto& e : std::filesystem::directory_iterator(test::scratchDir()))
        EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(StreamingGltf, ReadsWhatTheWholeFileImporterReads) {
    writePlant(scratch("p.glb"), {300, 9});
    writePlant(scratch("p.gltf"), {300, 9});
    for (const std::string& path : {scratch("p.glb"), scratch("p.gltf"), std::string(test::kEngine)}) {
        SCOPED_TRACE(path);
        std::string why;
        const auto source = streamGltf(path, {}, &why);
        ASSERT_TRUE(source) << why;
        expectSameScene(*source, importModel(path));
    }
}

TEST(StreamingGltf, TheSecondSceneOfAFileAndNodeHierarchies) {
    // Two scenes; the second has a parent node whose TRS moves its child's box.
    const std::string box = R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
                   {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
      "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],)";
    std::vector<unsigned char> bin(44, 0);
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data(), p, 36);
    std::memcpy(bin.data() + 36, idx, 6);
    const std::string json = R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]},{"nodes":[1]}],
      "nodes":[{"mesh":0},{"translation":[5,0,0],"scale":[2,2,2],"children":[2]},{"mesh":0,"rotation":[0,0,0.7071068,0.7071068]}],)" +
                             box + R"("buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,)" +
                             test::base64(bin) + R"("}]})";
    const std::string path = test::writeFixture("two.gltf", json);
    std::string why;
    EXPECT_FALSE(streamGltf(path, {}, &why));  // data: URIs are for the whole-file importer
    EXPECT_EQ(why, "data: URIs");
    // The same with the buffer in a file.
    std::ofstream(scratch("two.bin"), std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), 44);
    const std::string external = test::writeFixture(
        "two_ext.gltf", R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]},{"nodes":[1]}],
      "nodes":[{"mesh":0},{"translation":[5,0,0],"scale":[2,2,2],"children":[2]},{"mesh":0,"rotation":[0,0,0.7071068,0.7071068]}],)" +
                            box + R"("buffers":[{"byteLength":44,"uri":"two.bin"}]})");
    for (int scene : {-1, 0, 1}) {
        ImportOptions o;
        o.scene = scene;
        const auto source = streamGltf(external, o, &why);
        ASSERT_TRUE(source) << why;
        expectSameScene(*source, importModel(external, o));
    }
    ImportOptions missing;
    missing.scene = 2;
    EXPECT_THROW(streamGltf(external, missing, &why), InputError);
}

// Both readers pick the scene's roots and walk the node forest with the same code
// (gltf::sceneRoots, gltf::walkNodeForest): each broken forest fails in both with the same place
// and words, and a file without scenes draws the same nodes.
TEST(StreamingGltf, NodeForestsAreCheckedAsTheWholeFileImporterChecksThem) {
    std::vector<unsigned char> bin(44, 0);
    const float p[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data(), p, 36);
    std::memcpy(bin.data() + 36, idx, 6);
    std::ofstream(scratch("forest.bin"), std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), 44);
    const auto file = [](const std::string& name, const std::string& forest) {
        return test::writeFixture(name, R"({"asset":{"version":"2.0"},)" + forest + R"(,
      "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
                   {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
      "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
      "buffers":[{"byteLength":44,"uri":"forest.bin"}]})");
    };
    const auto message = [](const auto& read) -> std::string {
        try {
            read();
        } catch (const InputError& e) {
            return e.what();
        }
        return "no error";
    };
    const struct {
        const char* name;
        const char* forest;
        const char* error;
    } cases[] = {
        {"cycle.gltf", R"("scenes":[{"nodes":[0]}],"nodes":[{"children":[1]},{"children":[0],"mesh":0}])",
         "/nodes/1/children/0: node graph has a cycle through node 0"},
        {"parents.gltf", R"("scenes":[{"nodes":[0,1]}],"nodes":[{"children":[2]},{"children":[2]},{"mesh":0}])",
         "/nodes/1/children/0: node 2 has more than one parent"},
        {"child.gltf", R"("scenes":[{"nodes":[0]}],"nodes":[{"children":[5],"mesh":0}])",
         "/nodes/0/children/0: node index 5 out of range (1 nodes)"},
        {"root.gltf", R"("scenes":[{"nodes":[3]}],"nodes":[{"mesh":0}])",
         "/scenes/nodes/0: node index 3 out of range (1 nodes)"},
        {"twice.gltf", R"("scenes":[{"nodes":[0,0]}],"nodes":[{"mesh":0}])", "/nodes/0: node has more than one parent"},
        {"empty.gltf", R"("scenes":[{"nodes":[]}],"nodes":[{"mesh":0}])", "empty scene"},
        {"default.gltf", R"("scene":3,"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}])",
         "/scene: index 3 out of range (1 scenes)"},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        const std::string path = file(c.name, c.forest);
        std::string why;
        const std::string whole = message([&] { importModel(path); });
        const std::string streamed = message([&] { streamGltf(path, {}, &why); });
        EXPECT_NE(whole.find(path), std::string::npos) << whole;
        EXPECT_NE(whole.find(c.error), std::string::npos) << whole;
        EXPECT_EQ(streamed, whole);
    }
    // Without scenes every node that is nobody's child is a root: node 0 and its child 1, and 2.
    const std::string path =
        file("noscene.gltf", R"("nodes":[{"children":[1]},{"mesh":0,"translation":[1,0,0]},{"mesh":0}])");
    std::string why;
    const auto source = streamGltf(path, {}, &why);
    ASSERT_TRUE(source) << why;
    const Scene whole = importModel(path);
    EXPECT_EQ(whole.objects.size(), 2u);
    expectSameScene(*source, whole);
}

TEST(StreamingGltf, LeavesCompressedAndInstancedFilesToTheWholeFileImporter) {
    if (std::system("command -v gltfpack > /dev/null 2>&1") != 0) GTEST_SKIP() << "gltfpack not installed";
    const std::string in = scratch("src.glb"), packed = scratch("packed.glb");
    writePlant(in, {60, 2});
    ASSERT_EQ(std::system(("gltfpack -i " + in + " -o " + packed + " -cc > /dev/null 2>&1").c_str()), 0);
    std::string why;
    EXPECT_FALSE(streamGltf(packed, {}, &why));
    EXPECT_EQ(why, "meshopt compression");
    // openSceneSource falls back and still reads it, whatever the mode.
    const auto source = openSceneSource(packed, {}, ReadMode::Stream);
    EXPECT_STREQ(source->how(), "imported whole");
    EXPECT_EQ(source->objects().size(), importModel(packed).objects.size());
}

TEST(StreamingGltf, MalformedFilesFailWithTheFileAndPlace) {
    writePlant(scratch("ok.glb"), {50, 4});
    const std::vector<char> good = test::readBytes(scratch("ok.glb"));
    const auto expectError = [](const std::string& path, const std::string& part) {
        std::string why;
        try {
            auto s = streamGltf(path, {}, &why);
            for (uint32_t m = 0; s && m < s->meshCount(); ++m) s->mesh(m);
            ADD_FAILURE() << path << ": no error, expected one with '" << part << "'";
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
        }
    };
    // Truncated anywhere: the header's length no longer matches.
    for (size_t cut : {size_t(10), size_t(100), good.size() / 2, good.size() - 4}) {
        const std::string path = test::writeFixture("cut" + std::to_string(cut) + ".glb", std::string(good.data(), cut));
        expectError(path, cut < 20 ? "truncated" : "header says");
    }
    // Broken JSON.
    std::string text(good.begin(), good.end());
    const size_t brace = text.find("\"nodes\"");
    std::string broken = text;
    broken[brace] = '!';
    expectError(test::writeFixture("badjson.glb", broken), "invalid glTF json");
    // An index past the vertices, in a .gltf whose buffer is a file.
    const std::string json = R"({"asset":{"version":"2.0"},"nodes":[{"mesh":0}],
      "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
      "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
                   {"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],
      "bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],
      "buffers":[{"byteLength":44,"uri":"idx.bin"}]})";
    std::vector<unsigned char> bin(44, 0);
    const uint16_t idx[3] = {0, 1, 7};
    std::memcpy(bin.data() + 36, idx, 6);
    std::ofstream(scratch("idx.bin"), std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), 44);
    expectError(test::writeFixture("idx.gltf", json), "index value 7 at element 2 out of range (3 vertices)");
    // A buffer shorter than it says.
    std::ofstream(scratch("idx.bin"), std::ios::binary).write(reinterpret_cast<const char*>(bin.data()), 20);
    expectError(test::writeFixture("short.gltf", json), "only 20 bytes are there");
    std::filesystem::remove(scratch("idx.bin"));
    expectError(test::writeFixture("nobin.gltf", json), "missing buffer file");
    expectError(test::writeFixture("v1.gltf", R"({"asset":{"version":"1.0"}})"), "unsupported glTF version '1.0'");
}

TEST(StreamingPrep, TheStreamedOssIsTheInMemoryOneByteForByteOnAnyThreadCount) {
    writePlant(scratch("s.glb"), {500, 6});
    PrepOptions one, two;
    one.threads = 1;
    two.threads = 2;
    writeOss(scratch("whole.oss"), prepareScene(importModel(scratch("s.glb")), two));
    std::string why;
    const auto source = streamGltf(scratch("s.glb"), {}, &why);
    ASSERT_TRUE(source) << why;
    prepareToFile(*source, scratch("one.oss"), one);
    const PrepSummary s = prepareToFile(*source, scratch("two.oss"), two);
    EXPECT_EQ(test::readBytes(scratch("whole.oss")), test::readBytes(scratch("one.oss")));
    EXPECT_EQ(test::readBytes(scratch("whole.oss")), test::readBytes(scratch("two.oss")));
    EXPECT_EQ(s.objects, 500u);
    EXPECT_EQ(s.meshes, 500u);
    const OssFile f = OssFile::open(scratch("two.oss"));
    f.verifyLodPrefix();
    EXPECT_EQ(f.triangleCount(), s.unique_triangles);
}

TEST(StreamingPrep, AFailingMeshStopsThePrepAndLeavesNoFile) {
    // The plant's bytes with one mesh's index bytes broken: a worker fails mid-way.
    writePlant(scratch("f.gltf"), {200, 1});
    std::vector<char> bin = test::readBytes(scratch("f.bin"));
    // The last mesh's indices end the buffer; make its last index huge.
    bin[bin.size() - 4] = char(0xff);
    bin[bin.size() - 3] = char(0xff);
    std::ofstream(scratch("f.bin"), std::ios::binary).write(bin.data(), std::streamsize(bin.size()));
    std::string why;
    const auto source = streamGltf(scratch("f.gltf"), {}, &why);
    ASSERT_TRUE(source) << why;
    const std::string out = scratch("f.oss");
    writeOss(out, prepareScene(generatePlant({5, 1}), PrepOptions{}));  // an earlier good file
    const std::vector<char> before = test::readBytes(out);
    EXPECT_THROW(prepareToFile(*source, out, PrepOptions{}), InputError);
    EXPECT_EQ(test::readBytes(out), before);
    for (const auto& e : std::filesystem::directory_iterator(test::scratchDir()))
        EXPECT_EQ(e.path().string().find(".tmp."), std::string::npos) << e.path();
}

TEST(StreamingPrep, ObjectsOfMeshesWithoutTrianglesAreDropped) {
    Scene s;
    Mesh tri, none;
    tri.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    tri.indices = {0, 1, 2};
    s.meshes = {none, tri};
    s.objects = {Object{1, glm::mat4(1.0f), {}}, Object{0, glm::mat4(1.0f), {}}, Object{1, glm::mat4(2.0f), {}}};
    const PreparedScene p = prepareScene(s, PrepOptions{});
    ASSERT_EQ(p.objects.size(), 2u);
    ASSERT_EQ(p.meshes.size(), 1u);
    EXPECT_EQ(p.objects[0].mesh, 0u);
    EXPECT_EQ(p.objects[1].world, glm::mat4(2.0f));
}

}  // namespace
}  // namespace occ

namespace occ {
namespace {

// Every malformed glTF of tests/bad is refused by the streaming reader too: an InputError when
// opened or when a mesh is read, no triangles at all, or (data: URIs) left to the whole-file
// importer, which refuses it as test cli/prep_verify_info checks.
TEST(StreamingGltf, RefusesEveryMalformedFileOfTheBadCorpus) {
    int checked = 0;
    for (const auto& e : std::filesystem::directory_iterator(std::string(OCC_TEST_DATA) + "/bad")) {
        const std::string ext = e.path().extension().string();
        if (ext != ".glb" && ext != ".gltf") continue;
        ++checked;
        const std::string path = e.path().string();
        std::string why;
        try {
            const auto source = streamGltf(path, {}, &why);
            if (!source) {
                EXPECT_FALSE(why.empty()) << path;
                continue;
            }
            uint64_t triangles = 0;
            for (uint32_t m = 0; m < source->meshCount(); ++m) triangles += source->mesh(m).triangleCount();
            EXPECT_TRUE(source->objects().empty() || triangles == 0) << path << ": accepted";
        } catch (const InputError& error) {
            EXPECT_NE(std::string(error.what()).find(path), std::string::npos) << error.what();
        }
    }
    EXPECT_GT(checked, 10);
}

}  // namespace
}  // namespace occ
