// SPDX-License-Identifier: MIT
// glTF as the ecosystem optimizes it (issue 13): files written here by Debian's gltfpack
// (meshoptimizer) and draco_transcoder (Draco) from the engine, imported with the engine's
// triangle count.
#include "import/import.h"
#include "prep/weld.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cstdlib>
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
}

}  // namespace
}  // namespace occ
