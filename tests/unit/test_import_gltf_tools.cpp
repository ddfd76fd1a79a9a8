// SPDX-License-Identifier: MIT
// glTF as the ecosystem optimizes it (issue 13): files written here by Debian's gltfpack
// (meshoptimizer) and draco_transcoder (Draco) from the engine, imported with the engine's
// triangle count.
#include "import/glb_writer.h"
#include "import/grid.h"
#include "import/import.h"
#include "import/plant.h"
#include "prep/weld.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>

namespace occ {
namespace {

constexpr uint64_t kEngineTriangles = 121496;
// What prep keeps of them: 11 160 (with instances) have two corners at the same place.
constexpr uint64_t kEngineKept = 110336;

// Triangles prep keeps (none with two corners at one place), counting instances.
uint64_t keptTriangles(const Scene& s) {
    std::vector<uint64_t> kept(s.meshes.size());
    for (size_t m = 0; m < s.meshes.size(); ++m)
        kept[m] = weldPositions(s.meshes[m].positions, s.meshes[m].indices).triangles.size() / 3;
    uint64_t total = 0;
    for (const Object& o : s.objects) total += kept[o.mesh];
    return total;
}

// An optimizer's output holds the engine's triangles: the optimizers drop the triangles whose
// corners repeat an index (so at least what prep keeps remains), and quantizing positions to
// 14 bits puts a few more corners on one place (at most 0.05 % of the triangles).
void expectEngineTriangles(const Scene& s) {
    EXPECT_GE(s.triangleCount(), kEngineKept);
    EXPECT_LE(s.triangleCount(), kEngineTriangles);
    EXPECT_NEAR(double(keptTriangles(s)), double(kEngineKept), 0.0005 * kEngineKept);
}

// Runs a tool (quietly); fails the test when it is missing or fails.
std::string written(const std::string& name, const std::string& command_before_output) {
    const std::string out = (test::scratchDir() / name).string();
    const std::string command = command_before_output + " " + out + " > /dev/null 2>&1";
    EXPECT_EQ(std::system(command.c_str()), 0) << command << " (launch/setup installs gltfpack and draco)";
    return out;
}

class OptimizedGltf : public testing::Test {
protected:
    void SetUp() override {
        ASSERT_TRUE(std::filesystem::exists(test::kEngine)) << "install Debian's assimp-testmodels (launch/setup does)";
    }
};

// The world-space box of a scene, for comparing a re-encoded file with its original: quantized
// positions move by at most a part in 2^14 of the extent.
void expectSameBounds(const Scene& a, const Scene& b, float tolerance) {
    const Bounds ba = a.worldBounds(), bb = b.worldBounds();
    const float extent = glm::length(ba.max - ba.min);
    for (int k = 0; k < 3; ++k) {
        EXPECT_NEAR(ba.min[k], bb.min[k], tolerance * extent) << "axis " << k;
        EXPECT_NEAR(ba.max[k], bb.max[k], tolerance * extent) << "axis " << k;
    }
}

TEST_F(OptimizedGltf, GltfpacksQuantizedOutputImportsWhole) {
    // gltfpack's default: KHR_mesh_quantization (16-bit integer positions, dequantized by the
    // node transforms).
    const Scene original = importModel(test::kEngine);
    ASSERT_EQ(original.triangleCount(), kEngineTriangles);
    ASSERT_EQ(keptTriangles(original), kEngineKept);
    const Scene s = importModel(written("q.glb", "gltfpack -i " + std::string(test::kEngine) + " -o"));
    expectEngineTriangles(s);
    expectSameBounds(original, s, 1e-3f);
}

TEST_F(OptimizedGltf, GltfpacksInstancedOutputGivesEveryInstanceAnObject) {
    // -mi: EXT_mesh_gpu_instancing for meshes used more than once.
    const std::string path = written("mi.glb", "gltfpack -mi -i " + std::string(test::kEngine) + " -o");
    const Scene s = importModel(path);
    expectEngineTriangles(s);
    EXPECT_LT(s.meshes.size(), s.objects.size());
    expectSameBounds(importModel(test::kEngine), s, 1e-3f);
}

TEST_F(OptimizedGltf, GltfpacksMeshoptCompressedOutputImportsWhole) {
    // -cc: EXT_meshopt_compression with its fallback buffer, in a GLB and in a .gltf + .bin.
    for (const char* name : {"cc.glb", "cc.gltf"}) {
        SCOPED_TRACE(name);
        const Scene s = importModel(written(name, "gltfpack -cc -i " + std::string(test::kEngine) + " -o"));
        expectEngineTriangles(s);
        expectSameBounds(importModel(test::kEngine), s, 1e-3f);
    }
    // With instancing and without quantization too.
    const Scene unquantized = importModel(written("ccmi.glb", "gltfpack -cc -mi -noq -i " + std::string(test::kEngine) + " -o"));
    expectEngineTriangles(unquantized);
}

TEST_F(OptimizedGltf, DracoCompressedPrimitivesImportWhole) {
    // draco_transcoder writes KHR_draco_mesh_compression; assimp-testmodels ships one too.
    const Scene s = importModel(written("draco.glb", "draco_transcoder -i " + std::string(test::kEngine) + " -o"));
    EXPECT_EQ(s.triangleCount(), kEngineKept);  // Draco drops the index-degenerate ones
    expectEngineTriangles(s);
    expectSameBounds(importModel(test::kEngine), s, 1e-3f);
    const std::string shipped = "/usr/share/assimp/models/glTF2/draco/2CylinderEngine.gltf";
    if (std::filesystem::exists(shipped)) {
        expectEngineTriangles(importModel(shipped));
    }
}

TEST_F(OptimizedGltf, ACorruptCompressedViewIsAnErrorThatNamesIt) {
    const std::string path = written("broken.glb", "gltfpack -cc -i " + std::string(test::kEngine) + " -o");
    std::vector<char> bytes = test::readBytes(path);
    // Flip bytes in the middle of the binary chunk (the compressed streams).
    for (size_t i = bytes.size() / 2; i < bytes.size() / 2 + 64; ++i) bytes[i] = char(~bytes[i]);
    const std::string broken = test::writeFixture("broken2.glb", std::string(bytes.begin(), bytes.end()));
    try {
        const Scene s = importModel(broken);
        // A flip the decoder cannot notice still yields whole meshes of valid indices.
        EXPECT_GT(s.triangleCount(), 0u);
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(broken), std::string::npos) << e.what();
    }
}

TEST_F(OptimizedGltf, AnUnsupportedRequiredExtensionIsNamed) {
    const std::string path = test::writeFixture(
        "ext.gltf", R"({"asset":{"version":"2.0"},"extensionsUsed":["EXT_made_up"],"extensionsRequired":["EXT_made_up"],
                        "scenes":[{"nodes":[]}],"nodes":[]})");
    try {
        importModel(path);
        FAIL() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("EXT_made_up"), std::string::npos) << e.what();
    }
}

TEST_F(OptimizedGltf, SceneNumberChoosesTheScene) {
    EXPECT_EQ(importModel(test::kEngine, {0}).triangleCount(), kEngineTriangles);
    EXPECT_THROW(importModel(test::kEngine, {1}), InputError);
    // Two scenes over the same triangle: the file's default (1) has it twice, scene 0 once.
    std::vector<unsigned char> bin(44, 0);
    const float pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    std::memcpy(bin.data(), pos, 36);
    const uint16_t idx[3] = {0, 1, 2};
    std::memcpy(bin.data() + 36, idx, 6);
    const std::string two = test::writeFixture(
        "two_scenes.gltf",
        R"({"asset":{"version":"2.0"},"scene":1,"scenes":[{"nodes":[0]},{"nodes":[0,1]}],)"
        R"("nodes":[{"mesh":0},{"mesh":0,"translation":[5,0,0]}],)"
        R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],)"
        R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},)"
        R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],)"
        R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":6}],)"
        R"("buffers":[{"byteLength":44,"uri":"data:application/octet-stream;base64,)" + test::base64(bin) + R"("}]})");
    EXPECT_EQ(importModel(two).objects.size(), 2u);
    EXPECT_EQ(importModel(two, {0}).objects.size(), 1u);
    EXPECT_EQ(importModel(two, {1}).objects.size(), 2u);
    EXPECT_THROW(importModel(two, {2}), InputError);
}

// Every integer position type KHR_mesh_quantization allows (signed and unsigned bytes and
// shorts, normalized or not), each at the 4-byte aligned stride the extension requires.
TEST_F(OptimizedGltf, EveryQuantizedPositionTypeDequantizes) {
    struct Case {
        int type;
        size_t size;
        double max;  // the normalized divisor
        bool is_signed;
    };
    for (const Case c : {Case{5120, 1, 127, true}, Case{5121, 1, 255, false}, Case{5122, 2, 32767, true},
                         Case{5123, 2, 65535, false}})
        for (const bool normalized : {false, true}) {
            SCOPED_TRACE(std::to_string(c.type) + (normalized ? " normalized" : ""));
            const size_t stride = c.size == 1 ? 4 : 8;
            std::vector<unsigned char> bin(3 * stride + 8, 0);
            const int64_t big = c.size == 1 ? 100 : 20000, neg = c.is_signed ? -big : big / 2;
            const int64_t raw[3][3] = {{0, 0, 0}, {big, 0, 0}, {0, neg, 0}};
            for (int v = 0; v < 3; ++v)
                for (int k = 0; k < 3; ++k) {
                    const int64_t x = raw[v][k];
                    std::memcpy(bin.data() + size_t(v) * stride + size_t(k) * c.size, &x, c.size);  // little-endian
                }
            const uint16_t idx[3] = {0, 1, 2};
            std::memcpy(bin.data() + 3 * stride, idx, 6);
            const std::string json =
                R"({"asset":{"version":"2.0"},"extensionsUsed":["KHR_mesh_quantization"],)"
                R"("extensionsRequired":["KHR_mesh_quantization"],"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],)"
                R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],)"
                R"("accessors":[{"bufferView":0,"componentType":)" + std::to_string(c.type) +
                (normalized ? R"(,"normalized":true)" : "") + R"(,"count":3,"type":"VEC3"},)" +
                R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}],)" +
                R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" + std::to_string(3 * stride) +
                R"(,"byteStride":)" + std::to_string(stride) + R"(},{"buffer":0,"byteOffset":)" +
                std::to_string(3 * stride) + R"(,"byteLength":6}],)" + R"("buffers":[{"byteLength":)" +
                std::to_string(bin.size()) + R"(,"uri":"data:application/octet-stream;base64,)" + test::base64(bin) +
                R"("}]})";
            const Scene s = importModel(test::writeFixture("q" + std::to_string(c.type) + (normalized ? "n" : "") + ".gltf", json));
            ASSERT_EQ(s.meshes.size(), 1u);
            const double scale = normalized ? c.max : 1.0;
            const std::vector<glm::vec3>& p = s.meshes[0].positions;
            ASSERT_EQ(p.size(), 3u);
            EXPECT_FLOAT_EQ(p[1].x, float(double(big) / scale));
            EXPECT_FLOAT_EQ(p[2].y, float(double(neg) / scale));
        }
}

// Scenes occswitch generates, through the same optimizers: the plant (every mesh its own;
// gltfpack merges them by material) and an engine grid (instanced by nodes, and by
// EXT_mesh_gpu_instancing with -mi) keep every triangle; Draco's quantization makes a few
// degenerate (at most 0.05 %), which prep then drops.
TEST_F(OptimizedGltf, GeneratedScenesKeepTheirTrianglesThroughTheOptimizers) {
    const std::string plant = (test::scratchDir() / "plant300.glb").string();
    writeSceneGlb(plant, generatePlant(PlantOptions{300, 1}));
    const std::string grid = (test::scratchDir() / "grid2x2.glb").string();
    writeGrid(grid, importModel(test::kEngine), GridOptions{2, 1, 2, 0.0f});
    for (const std::string& source : {plant, grid}) {
        const Scene original = importModel(source);
        const uint64_t kept = keptTriangles(original);
        for (const std::string tool : {"gltfpack -i", "gltfpack -cc -i", "gltfpack -cc -mi -i", "draco_transcoder -i"}) {
            SCOPED_TRACE(source + " through " + tool);
            const Scene s = importModel(written("opt.glb", tool + " " + source + " -o"));
            EXPECT_GE(s.triangleCount(), kept);
            EXPECT_LE(s.triangleCount(), original.triangleCount());
            EXPECT_NEAR(double(keptTriangles(s)), double(kept), 0.0005 * double(kept));
            expectSameBounds(original, s, 1e-3f);
        }
    }
}

}  // namespace
}  // namespace occ
