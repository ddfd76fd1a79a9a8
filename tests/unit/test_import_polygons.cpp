// SPDX-License-Identifier: MIT
// Polygons (ear clipping) and OFF as tools write it (issue 13).
#include "import/import.h"
#include "import/triangulate.h"
#include "scene/errors.h"
#include "test_support.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

namespace occ {
namespace {

using test::writeFixture;

// Twice the area of a mesh's triangles, each measured along `normal`: a triangle turned against
// the polygon's winding counts negative.
double signedArea2(const Mesh& m, const glm::dvec3& normal) {
    double sum = 0;
    for (size_t t = 0; t < m.indices.size(); t += 3) {
        const glm::dvec3 a(m.positions[m.indices[t]]), b(m.positions[m.indices[t + 1]]), c(m.positions[m.indices[t + 2]]);
        sum += glm::dot(glm::cross(b - a, c - a), normal);
    }
    return sum;
}
double absoluteArea2(const Mesh& m) {
    double sum = 0;
    for (size_t t = 0; t < m.indices.size(); t += 3) {
        const glm::dvec3 a(m.positions[m.indices[t]]), b(m.positions[m.indices[t + 1]]), c(m.positions[m.indices[t + 2]]);
        sum += glm::length(glm::cross(b - a, c - a));
    }
    return sum;
}

TEST(Triangulate, AConvexPentagonGivesThreeTrianglesOfItsWinding) {
    const std::vector<glm::vec3> p{{0, 0, 0}, {2, 0, 0}, {3, 1, 0}, {1, 2, 0}, {-1, 1, 0}};
    std::vector<uint32_t> t;
    ASSERT_TRUE(triangulatePolygon(p, {0, 1, 2, 3, 4}, t));
    ASSERT_EQ(t.size(), 9u);
    Mesh m;
    m.positions = p;
    m.indices = t;
    EXPECT_NEAR(signedArea2(m, {0, 0, 1}), absoluteArea2(m), 1e-9);  // none turned over
    EXPECT_NEAR(absoluteArea2(m), 2 * 5.0, 1e-9);                   // the pentagon's area is 5
}

TEST(Triangulate, AConcaveOutlineIsNotFilled) {
    // A "C": fanning from corner 0 would cover the notch.
    const std::vector<glm::vec3> p{{0, 0, 0}, {3, 0, 0}, {3, 1, 0}, {1, 1, 0}, {1, 2, 0}, {3, 2, 0}, {3, 3, 0}, {0, 3, 0}};
    std::vector<uint32_t> t;
    ASSERT_TRUE(triangulatePolygon(p, {3, 4, 5, 6, 7, 0, 1, 2}, t));  // starting at the reflex corner
    ASSERT_EQ(t.size(), 3u * 6);
    Mesh m;
    m.positions = p;
    m.indices = t;
    EXPECT_NEAR(signedArea2(m, {0, 0, 1}), 2 * 7.0, 1e-9);
    EXPECT_NEAR(absoluteArea2(m), 2 * 7.0, 1e-9);
}

TEST(Triangulate, AHoleJoinedByABridgeEdgeStaysOpen) {
    // A 4 x 4 square with a 2 x 2 hole, the hole's outline (clockwise) joined to the outer one
    // (counter-clockwise) by a bridge traversed both ways: 10 corners, 8 triangles, area 12.
    const std::vector<glm::vec3> p{{0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 4, 0},
                                   {1, 1, 0}, {1, 3, 0}, {3, 3, 0}, {3, 1, 0}};
    std::vector<uint32_t> t;
    ASSERT_TRUE(triangulatePolygon(p, {0, 1, 2, 3, 0, 4, 5, 6, 7, 4}, t));
    ASSERT_EQ(t.size(), 3u * 8);
    Mesh m;
    m.positions = p;
    m.indices = t;
    EXPECT_NEAR(signedArea2(m, {0, 0, 1}), 2 * 12.0, 1e-9);
    EXPECT_NEAR(absoluteArea2(m), 2 * 12.0, 1e-9);
    for (size_t k = 0; k < t.size(); k += 3) {
        const glm::vec3 centre = (p[t[k]] + p[t[k + 1]] + p[t[k + 2]]) / 3.0f;
        EXPECT_FALSE(centre.x > 1 && centre.x < 3 && centre.y > 1 && centre.y < 3) << "a triangle in the hole";
    }
}

TEST(Triangulate, FewerThanThreeDistinctCornersIsDegenerate) {
    const std::vector<glm::vec3> p{{0, 0, 0}, {1, 0, 0}, {1, 1, 0}};
    std::vector<uint32_t> t;
    EXPECT_FALSE(triangulatePolygon(p, {0, 1, 1, 0}, t));
    EXPECT_FALSE(triangulatePolygon(p, {2, 2, 2}, t));
    EXPECT_TRUE(t.empty());
    EXPECT_TRUE(triangulatePolygon(p, {0, 0, 1, 2, 0}, t));  // repeats dropped: one triangle
    EXPECT_EQ(t, (std::vector<uint32_t>{0, 1, 2}));
}

TEST(Triangulate, ATiltedPolygonIsClippedInItsOwnPlane) {
    // The "C" of above, rotated out of every axis plane.
    const glm::mat3 r = glm::mat3(glm::vec3(0.36f, 0.48f, -0.8f), glm::vec3(-0.8f, 0.6f, 0.0f), glm::vec3(0.48f, 0.64f, 0.6f));
    std::vector<glm::vec3> p{{0, 0, 0}, {3, 0, 0}, {3, 1, 0}, {1, 1, 0}, {1, 2, 0}, {3, 2, 0}, {3, 3, 0}, {0, 3, 0}};
    for (glm::vec3& v : p) v = r * v;
    std::vector<uint32_t> t;
    ASSERT_TRUE(triangulatePolygon(p, {0, 1, 2, 3, 4, 5, 6, 7}, t));
    Mesh m;
    m.positions = p;
    m.indices = t;
    EXPECT_NEAR(absoluteArea2(m), 2 * 7.0, 1e-4);
    EXPECT_NEAR(signedArea2(m, glm::dvec3(r * glm::vec3(0, 0, 1))), 2 * 7.0, 1e-4);
}

TEST(ImportObj, AssimpsConcavePolygonWithAHoleGivesNMinusTwoTrianglesAndNoFill) {
    const std::string path = "/usr/share/assimp/models/OBJ/concave_polygon.obj";
    ASSERT_TRUE(std::filesystem::exists(path)) << "install Debian's assimp-testmodels (launch/setup does)";
    const Scene s = importModel(path);
    ASSERT_EQ(s.triangleCount(), 64u);  // 66 corners
    const Mesh& m = s.meshes[s.objects[0].mesh];
    // Every triangle turned the polygon's way: the areas add up to the polygon's, no overlaps.
    glm::dvec3 normal(0.0);
    for (size_t t = 0; t < m.indices.size(); t += 3) {
        const glm::dvec3 a(m.positions[m.indices[t]]), b(m.positions[m.indices[t + 1]]), c(m.positions[m.indices[t + 2]]);
        normal += glm::cross(b - a, c - a);
    }
    normal = glm::normalize(normal);
    EXPECT_NEAR(signedArea2(m, normal), absoluteArea2(m), 1e-6 * absoluteArea2(m));
}

// ---- OFF --------------------------------------------------------------------------------

const char* kCubeBody =
    "0 0 0\n1 0 0\n1 1 0\n0 1 0\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
    "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n";

TEST(ImportOff, CommentsAndBlankLinesMayComeAnywhere) {
    const std::string path = writeFixture("commented.off",
                                          "# written by a CGAL example\n\n"
                                          "OFF  # the header\n"
                                          "\n8 6 0\n"
                                          "# vertices\n"
                                          "0 0 0\n1 0 0\n1 1 0\n0 1 0\n\n0 0 1\n1 0 1\n1 1 1\n0 1 1\n"
                                          "# facets\n"
                                          "4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n# half way\n4 1 2 6 5\n4 2 3 7 6\n4 3 0 4 7\n"
                                          "# end\n\n");
    const Scene s = importModel(path);
    EXPECT_EQ(s.triangleCount(), 12u);
    EXPECT_EQ(s.vertexCount(), 8u);
}

TEST(ImportOff, ColoursNormalsAndTextureCoordinatesAreReadPast) {
    // COFF (a colour per vertex), NOFF (normals), STOFF, and colours per face (RGB or RGBA).
    const std::string coff = writeFixture("c.off",
                                          "COFF\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n"
                                          "0 1 0 9 9 9 255\n3 0 1 2 0.5 0.5 0.5\n3 0 2 3 1 0 0 1\n");
    EXPECT_EQ(importModel(coff).triangleCount(), 2u);
    const std::string noff = writeFixture("n.off", "NOFF\n3 1 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n");
    EXPECT_EQ(importModel(noff).triangleCount(), 1u);
    const std::string stoff = writeFixture("st.off", "STOFF 3 1 0\n0 0 0 0 0\n1 0 0 1 0\n0 1 0 0 1\n3 0 1 2\n");
    EXPECT_EQ(importModel(stoff).triangleCount(), 1u);
    // Twenty triangles with a colour each, as quint_tris.off has them: every one kept.
    std::string q = "OFF\n22 20 0\n";
    for (int i = 0; i < 22; ++i) q += std::to_string(i % 11) + " " + std::to_string(i / 11) + " 0\n";
    for (int i = 0; i < 10; ++i) {
        q += "3 " + std::to_string(i) + " " + std::to_string(i + 1) + " " + std::to_string(i + 12) + " 1 0 0\n";
        q += "3 " + std::to_string(i) + " " + std::to_string(i + 12) + " " + std::to_string(i + 11) + " 0 1 0 1\n";
    }
    const Scene s = importModel(writeFixture("quint.off", q));
    EXPECT_EQ(s.triangleCount(), 20u);
}

TEST(ImportOff, HeaderVariants) {
    // The counts on the header line; no header word at all; 4OFF's homogeneous coordinates.
    EXPECT_EQ(importModel(writeFixture("a.off", std::string("OFF 8 6 0\n") + kCubeBody)).triangleCount(), 12u);
    EXPECT_EQ(importModel(writeFixture("b.off", std::string("8 6 0\n") + kCubeBody)).triangleCount(), 12u);
    EXPECT_EQ(importModel(writeFixture("c.off", "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")).triangleCount(), 1u);
    const Scene h = importModel(writeFixture("h.off", "4OFF\n3 1 0\n0 0 0 2\n2 0 0 2\n0 4 0 2\n3 0 1 2\n"));
    EXPECT_EQ(h.worldBounds().max, glm::vec3(1, 2, 0));
}

TEST(ImportOff, PointsLinesAndDegenerateFacesAreCounted) {
    const Scene s = importModel(writeFixture(
        "mixed.off", "OFF\n4 5 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n1 0\n2 0 1\n3 0 0 1\n0\n"));
    EXPECT_EQ(s.triangleCount(), 2u);
    EXPECT_EQ(s.skipped.points, 1u);
    EXPECT_EQ(s.skipped.lines, 1u);
    EXPECT_EQ(s.skipped.degenerate, 2u);
}

void expectRejected(const std::string& name, const std::string& text, const std::string& what) {
    const std::string path = writeFixture(name, text);
    try {
        importModel(path);
        ADD_FAILURE() << name << " was accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
    }
}

TEST(ImportOff, BrokenFilesSayWhatAndWhere) {
    expectRejected("t.off", "OFF\n8 6 0\n0 0 0\n1 0 0\n4 0 1 2 3\n", "truncated");
    expectRejected("idx.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 1679833972\n", "line 6: face 0: vertex index");
    expectRejected("few.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", "lists 3 of its 4 corners");
    expectRejected("nan.off", "OFF\n3 1 0\n0 0 0\n1 blah 0\n0 1 0\n3 0 1 2\n", "line 4: vertex 1: 'blah' is not a number");
    expectRejected("inf.off", "OFF\n3 1 0\n0 0 0\n1 inf 0\n0 1 0\n3 0 1 2\n", "not finite");
    expectRejected("more.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 2\n", "data after the last");
    expectRejected("magic.off", "OFFICE\n3 1 0\n", "bad magic 'OFFICE'");
    expectRejected("word.off", "XOFF\n3 1 0\n", "unknown header word 'XOFF'");
    expectRejected("bin.off", "OFF BINARY\n", "binary OFF");
    expectRejected("empty.off", "# nothing\n\n", "empty file");
    // assimp's own bad files: a face that lists fewer corners than it says, and a header that
    // promises 3.5 trillion vertices (nothing is allocated for them).
    if (std::filesystem::exists("/usr/share/assimp/models/OFF/invalid.off")) {
        EXPECT_THROW(importModel("/usr/share/assimp/models/OFF/invalid.off"), InputError);
        EXPECT_THROW(importModel("/usr/share/assimp/models/invalid/OutOfMemory.off"), InputError);
        EXPECT_THROW(importModel("/usr/share/assimp/models/invalid/empty.off"), InputError);
    }
}

TEST(ImportOff, AssimpsModelsImportWhole) {
    if (!std::filesystem::exists("/usr/share/assimp/models/OFF/Wuson.off")) GTEST_SKIP() << "no assimp-testmodels";
    EXPECT_EQ(importModel("/usr/share/assimp/models/OFF/Cube.off").triangleCount(), 12u);
    const Scene w = importModel("/usr/share/assimp/models/OFF/Wuson.off");
    EXPECT_EQ(w.triangleCount(), 3732u);  // all triangles in the file
    EXPECT_EQ(w.skipped.degenerate, 0u);
}

// ---- text encodings, point clouds, old headers ---------------------------------------------

// `text` (ASCII or UTF-8 of two-byte characters) as UTF-16 with its byte-order mark.
std::string utf16(const std::string& text, bool big) {
    std::string out = big ? std::string("\xFE\xFF", 2) : std::string("\xFF\xFE", 2);
    for (size_t i = 0; i < text.size(); ++i) {
        unsigned c = static_cast<unsigned char>(text[i]);
        if (c >= 0xC0 && i + 1 < text.size()) c = (c & 0x1F) << 6 | (static_cast<unsigned char>(text[++i]) & 0x3F);
        const char hi = char(c >> 8), lo = char(c & 0xFF);
        out += big ? std::string{hi, lo} : std::string{lo, hi};
    }
    return out;
}

TEST(ImportText, ByteOrderMarksAndUtf16AreRead) {
    const std::string body = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    // With a UTF-8 mark the first vertex must not be lost to it (the face would then be out of range).
    EXPECT_EQ(importModel(writeFixture("bom8.obj", "\xEF\xBB\xBF" + body)).triangleCount(), 1u);
    for (const bool big : {false, true}) {
        const std::string path = writeFixture(big ? "be.obj" : "le.obj", utf16("# \xC3\xA9t\xC3\xA9\n" + body, big));
        EXPECT_EQ(importModel(path).triangleCount(), 1u) << path;
    }
    EXPECT_EQ(importModel(writeFixture("le.off", utf16("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", false))).triangleCount(),
              1u);
    expectRejected("odd.obj", std::string("\xFF\xFEv\0 ", 5), "UTF-16 text with an odd number of bytes");
}

TEST(ImportText, APointCloudSaysSo) {
    expectRejected("cloud.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n", "3 vertices and no faces");
    expectRejected("cloud.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
                                "property float z\nend_header\n0 0 0\n1 0 0\n", "2 vertices and no faces");
    expectRejected("lines.obj", "v 0 0 0\nv 1 0 0\nl 1 2\nl 2 1\n", "only 2 line primitives");
}

TEST(ImportPly, AHeaderLineWithoutCommentIsACommentAndAMisspeltOneFails) {
    const std::string head = "ply\nformat ascii 1.0\nCreated by Blender3D 247\nelement vertex 3\n"
                             "property float x\nproperty float y\nproperty float z\n";
    const std::string tail = "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                             "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
    EXPECT_EQ(importModel(writeFixture("blender.ply", head + tail)).triangleCount(), 1u);
    // "proprety" is read past like a comment; the extra column then leaves data over.
    expectRejected("misspelt.ply",
                   head + "proprety float nx\n" + tail.substr(0, tail.find("0 0 0")) + "0 0 0 1\n1 0 0 1\n0 1 0 1\n3 0 1 2\n",
                   "data after the last element");
}

}  // namespace
}  // namespace occ
