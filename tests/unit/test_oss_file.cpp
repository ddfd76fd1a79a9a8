// SPDX-License-Identifier: MIT
#include "scene/oss_file.h"

#include "scene/errors.h"
#include "test_support.h"

#include <glm/gtc/type_ptr.hpp>
#include <gtest/gtest.h>
#include <xxhash.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <random>
#include <vector>

#include <sys/resource.h>

namespace occ {
namespace {

namespace fs = std::filesystem;
using test::readBytes;
using test::scratchDir;

// A closed tetrahedron whose vertex 3 collapses onto vertex 0 (q = 3). Collapsing 3 -> 0 turns
// (0,1,3) and (2,0,3) into slivers and (1,2,3) into (1,2,0), so the two survivors come first:
//   t0 (0,2,1)  t1 (1,2,3)  |  t2 (0,1,3)  t3 (2,0,3)       map = 2 2 2 2 4
ProgressiveMesh tetrahedron() {
    ProgressiveMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    m.ecol = {-1, -1, -1, 0};
    m.error = {0, 0, 0, 0.25f};
    m.triangles = {0, 2, 1, 1, 2, 3, 0, 1, 3, 2, 0, 3};
    m.map = {2, 2, 2, 2, 4};
    m.q = 3;
    m.source_vertices = 12;
    return m;
}

// A 2x1 rectangle with corners 0..3 (boundary, q = 4) and two interior vertices 4 and 5:
//   A (0,1,4)  B (4,1,5)  C (1,2,5)  D (2,3,5)  E (4,5,3)  F (0,4,3)
// 5 -> 4 kills B and E and turns C, D into (1,2,4), (2,3,4); 4 -> 0 then kills A and F.
// Re-arranged: t0 C, t1 D | t2 A, t3 F | t4 B, t5 E            map = 2 2 2 2 2 4 6
ProgressiveMesh rectangle() {
    ProgressiveMesh m;
    m.positions = {{0, 0, 0}, {2, 0, 0}, {2, 1, 0}, {0, 1, 0}, {0.7f, 0.5f, 0}, {1.3f, 0.5f, 0}};
    m.ecol = {-1, -1, -1, -1, 0, 4};
    m.error = {0, 0, 0, 0, 0.5f, 0.125f};
    m.triangles = {1, 2, 5, 2, 3, 5, 0, 1, 4, 0, 4, 3, 4, 1, 5, 4, 5, 3};
    m.map = {2, 2, 2, 2, 2, 4, 6};
    m.q = 4;
    m.refused_faces = 1;
    m.source_vertices = 9;
    m.dropped_triangles = 2;
    return m;
}

ObjectRecord object(uint32_t mesh, float compactness, float shift) {
    ObjectRecord o;
    o.mesh = mesh;
    o.color = {0.1f * shift, 0.5f, 0.25f, 1.0f};
    o.world = glm::mat4(1.0f);
    o.world[3] = {shift, 2.0f * shift, -shift, 1.0f};
    o.aabb.min = {shift, 2.0f * shift, -shift - 1.0f};
    o.aabb.max = {shift + 2.0f, 2.0f * shift + 1.0f, -shift};
    o.oobb.center = {shift + 1.0f, 2.0f * shift + 0.5f, -shift - 0.5f};
    o.oobb.axis[0] = {0.0f, 1.0f, 0.0f};
    o.oobb.axis[1] = {-1.0f, 0.0f, 0.0f};
    o.oobb.half_extent = {1.0f, 0.5f, 0.5f};
    o.occluder_normal = {0.0f, 0.0f, -1.0f};
    o.compactness = compactness;
    return o;
}

SceneNode node(const Bounds& box, uint32_t depth, uint64_t triangles) {
    SceneNode n;
    n.box = box;
    n.depth = depth;
    n.triangles = triangles;
    return n;
}

// With a hierarchy: root (0) -> inner 1 (objects 0 and 1, nodes 3 and 4) and leaf 2 (object 2);
// mesh 1 stands in for the HLODs.
PreparedScene smallScene() {
    PreparedScene s;
    s.meshes = {tetrahedron(), rectangle()};
    s.objects = {object(0, 0.9f, 1.0f), object(1, 0.3f, 2.0f), object(1, 0.7f, 3.0f)};
    s.cos = {0, 2};
    s.ct = 0.55f;
    Bounds all, first_two;
    for (int i = 0; i < 3; ++i) {
        all.extend(s.objects[size_t(i)].aabb.min), all.extend(s.objects[size_t(i)].aabb.max);
        if (i < 2) first_two.extend(s.objects[size_t(i)].aabb.min), first_two.extend(s.objects[size_t(i)].aabb.max);
    }
    s.nodes = {node(all, 0, 16), node(first_two, 1, 10), node(s.objects[2].aabb, 1, 6), node(s.objects[0].aabb, 2, 4),
               node(s.objects[1].aabb, 2, 6)};
    s.nodes[0].first_child = 1, s.nodes[0].child_count = 2, s.nodes[0].mesh = 1;
    s.nodes[1].first_child = 3, s.nodes[1].child_count = 2, s.nodes[1].mesh = 1;
    s.nodes[2].object = 2, s.nodes[3].object = 0, s.nodes[4].object = 1;
    s.nodes[0].error = 0.5f, s.nodes[1].error = 0.25f;
    return s;
}

// A valid progressive mesh of n >= 3 vertices grown by vertex splits, the inverse of half-edge
// collapses: vertex v goes inside a live triangle (a,b,c), which becomes (b,c,v) and gains
// (a,b,v) and (c,a,v) at the end; collapsing v -> a undoes exactly that.
ProgressiveMesh grownMesh(uint32_t n, uint32_t& seed) {
    auto next = [&seed] { return seed = seed * 1664525u + 1013904223u, seed >> 8; };
    ProgressiveMesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    m.ecol = {-1, -1, -1};
    m.error = {0, 0, 0};
    m.triangles = {0, 1, 2};
    m.map = {1, 1, 1, 1};
    m.q = 3;
    for (uint32_t v = 3; v < n; ++v) {
        const uint32_t t = next() % m.triangleCount(), r = next() % 3;
        const uint32_t a = m.triangles[t * 3 + r], b = m.triangles[t * 3 + (r + 1) % 3], c = m.triangles[t * 3 + (r + 2) % 3];
        m.positions.push_back((m.positions[a] + m.positions[b] + m.positions[c]) / 3.0f);
        m.ecol.push_back(int32_t(a));
        m.error.push_back(float(v));
        m.triangles[t * 3 + 0] = b;
        m.triangles[t * 3 + 1] = c;
        m.triangles[t * 3 + 2] = v;
        m.triangles.insert(m.triangles.end(), {a, b, v, c, a, v});
        m.map.push_back(m.triangleCount());
    }
    m.source_vertices = n;
    return m;
}

PreparedScene grownScene(uint32_t meshes, uint32_t max_vertices, uint32_t objects, uint32_t seed) {
    PreparedScene s;
    for (uint32_t i = 0; i < meshes; ++i) s.meshes.push_back(grownMesh(5 + seed % max_vertices, seed));
    for (uint32_t i = 0; i < objects; ++i)
        s.objects.push_back(object(i % meshes, float(i % 100) / 100.0f, float(i)));
    for (uint32_t i = 0; i < objects; ++i)
        if (s.objects[i].compactness >= s.ct) s.cos.push_back(i);
    std::stable_sort(s.cos.begin(), s.cos.end(), [&](uint32_t a, uint32_t b) {
        return s.objects[a].compactness > s.objects[b].compactness;
    });
    // A root over one leaf per object.
    SceneNode root;
    root.first_child = 1, root.child_count = objects, root.mesh = 0, root.error = 1.0f;
    for (uint32_t i = 0; i < objects; ++i) {
        SceneNode leaf;
        leaf.box = s.objects[i].aabb, leaf.object = i, leaf.depth = 1;
        leaf.triangles = s.meshes[s.objects[i].mesh].triangleCount();
        root.box.extend(leaf.box.min), root.box.extend(leaf.box.max), root.triangles += leaf.triangles;
        s.nodes.push_back(leaf);
    }
    s.nodes.insert(s.nodes.begin(), root);
    return s;
}

std::string scratch(const std::string& name) { return (scratchDir() / name).string(); }

// Removes the old file first: ext4 flushes a file that is truncated and rewritten when it is
// closed (auto_da_alloc), which would make thousands of rewrites take seconds.
void writeBytes(const std::string& path, const std::vector<char>& bytes, size_t count) {
    fs::remove(path);
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(count));
}

// The message of the InputError that opening `path` raises, or "" if it opens.
std::string openError(const std::string& path) {
    try {
        OssFile::open(path);
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

uint64_t sectionOffset(const OssFile& f, const std::string& name) {
    for (const OssFile::SectionInfo& s : f.sections())
        if (s.name == name) return s.offset;
    ADD_FAILURE() << "no section " << name;
    return 0;
}

// Offset of section `name` in a valid file written from `scene` (bad scenes share the layout).
uint64_t sectionOffsetOf(const PreparedScene& scene, const std::string& name) {
    const std::string path = scratch("layout.oss");
    writeOss(path, scene);
    return sectionOffset(OssFile::open(path), name);
}

void expectSameMesh(const ProgressiveMesh& a, const ProgressiveMesh& b) {
    EXPECT_EQ(a.positions, b.positions);
    EXPECT_EQ(a.ecol, b.ecol);
    EXPECT_EQ(a.error, b.error);
    EXPECT_EQ(a.triangles, b.triangles);
    EXPECT_EQ(a.map, b.map);
    EXPECT_EQ(a.q, b.q);
    EXPECT_EQ(a.refused_faces, b.refused_faces);
    EXPECT_EQ(a.source_vertices, b.source_vertices);
    EXPECT_EQ(a.dropped_triangles, b.dropped_triangles);
}

void expectSameObject(const ObjectRecord& a, const ObjectRecord& b) {
    EXPECT_EQ(a.mesh, b.mesh);
    EXPECT_EQ(a.color, b.color);
    EXPECT_EQ(a.world, b.world);
    EXPECT_EQ(a.aabb.min, b.aabb.min);
    EXPECT_EQ(a.aabb.max, b.aabb.max);
    EXPECT_EQ(a.oobb.center, b.oobb.center);
    for (int i = 0; i < 3; ++i) EXPECT_EQ(a.oobb.axis[i], b.oobb.axis[i]);
    EXPECT_EQ(a.oobb.half_extent, b.oobb.half_extent);
    EXPECT_EQ(a.occluder_normal, b.occluder_normal);
    EXPECT_EQ(a.compactness, b.compactness);
}

void expectSameScene(const PreparedScene& a, const PreparedScene& b) {
    ASSERT_EQ(a.meshes.size(), b.meshes.size());
    for (size_t i = 0; i < a.meshes.size(); ++i) expectSameMesh(a.meshes[i], b.meshes[i]);
    ASSERT_EQ(a.objects.size(), b.objects.size());
    for (size_t i = 0; i < a.objects.size(); ++i) expectSameObject(a.objects[i], b.objects[i]);
    EXPECT_EQ(a.cos, b.cos);
    EXPECT_EQ(a.ct, b.ct);
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    for (size_t i = 0; i < a.nodes.size(); ++i) {
        EXPECT_EQ(a.nodes[i].box.min, b.nodes[i].box.min);
        EXPECT_EQ(a.nodes[i].box.max, b.nodes[i].box.max);
        EXPECT_EQ(a.nodes[i].first_child, b.nodes[i].first_child);
        EXPECT_EQ(a.nodes[i].child_count, b.nodes[i].child_count);
        EXPECT_EQ(a.nodes[i].object, b.nodes[i].object);
        EXPECT_EQ(a.nodes[i].mesh, b.nodes[i].mesh);
        EXPECT_EQ(a.nodes[i].depth, b.nodes[i].depth);
        EXPECT_EQ(a.nodes[i].triangles, b.nodes[i].triangles);
        EXPECT_EQ(a.nodes[i].error, b.nodes[i].error);
    }
}

TEST(OssFile, RoundTripKeepsEveryField) {
    const PreparedScene scene = smallScene();
    const std::string path = scratch("round_trip.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);
    EXPECT_EQ(f.meshCount(), 2u);
    EXPECT_EQ(f.objectCount(), 3u);
    EXPECT_EQ(f.vertexCount(), 10u);
    EXPECT_EQ(f.triangleCount(), 10u);
    EXPECT_EQ(f.ct(), 0.55f);
    expectSameScene(f.toPreparedScene(), scene);
    expectSameObject(f.object(2), scene.objects[2]);
    EXPECT_EQ(f.nodeCount(), 5u);
    f.verifyLodPrefix();
    // Without a hierarchy: an empty NODES section.
    PreparedScene flat = scene;
    flat.nodes.clear();
    writeOss(path, flat);
    const OssFile g = OssFile::open(path);
    EXPECT_EQ(g.nodeCount(), 0u);
    expectSameScene(g.toPreparedScene(), flat);
}

// A leaf is stored as its object alone (format 4): what a SceneNode leaf would repeat (box,
// triangles, placement, error, depth) is not written, and comes back from the object, its mesh
// and the tree.
TEST(OssFile, ALeafIsItsObject) {
    PreparedScene scene = smallScene();
    SceneNode& leaf = scene.nodes[3];  // object 0, depth 2
    leaf.box.max += glm::vec3(1.0f);
    leaf.triangles = 99;
    leaf.error = 3.0f;
    leaf.depth = 7;
    leaf.world[3][0] = 5.0f;
    leaf.mesh = 1;
    const std::string path = scratch("leaf.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);
    const oss::Node& n = f.nodes()[3];
    EXPECT_EQ(glm::make_vec3(n.box_min), scene.objects[0].aabb.min);
    EXPECT_EQ(glm::make_vec3(n.box_max), scene.objects[0].aabb.max);
    EXPECT_EQ(n.triangles, 4u);  // the tetrahedron
    EXPECT_EQ(n.error, 0.0f);
    EXPECT_EQ(n.depth, 2u);
    EXPECT_EQ(n.object, 0u);
    EXPECT_EQ(n.mesh, UINT32_MAX);
    EXPECT_EQ(glm::make_mat4(n.world), glm::mat4(1.0f));
    EXPECT_EQ(f.nodes()[1].depth, 1u);
}

TEST(OssFile, MeshViewsPointIntoTheMapping) {
    const std::string path = scratch("views.oss");
    writeOss(path, smallScene());
    OssFile f = OssFile::open(path);
    const OssFile::MeshView m = f.mesh(1);
    EXPECT_EQ(m.vertexCount(), 6u);
    EXPECT_EQ(m.triangleCount(), 6u);
    EXPECT_EQ(m.map.size(), 7u);
    EXPECT_EQ(m.q, 4u);
    EXPECT_EQ(m.ecol[5], 4);
    EXPECT_EQ(m.positions[4], glm::vec3(0.7f, 0.5f, 0));
    // Views survive a move of the file object: the mapping moves, it is not copied.
    const OssFile moved = std::move(f);
    EXPECT_EQ(moved.mesh(1).positions.data(), m.positions.data());
    EXPECT_EQ(moved.cos().size(), 2u);
    EXPECT_EQ(moved.cos()[1], 2u);
    EXPECT_THROW(moved.mesh(2), std::out_of_range);
    EXPECT_THROW(moved.object(3), std::out_of_range);
}

TEST(OssFile, SectionsAreAlignedInOrderAndCoverTheFile) {
    const std::string path = scratch("sections.oss");
    writeOss(path, smallScene());
    const OssFile f = OssFile::open(path);
    const std::vector<OssFile::SectionInfo> s = f.sections();
    const std::vector<std::string> names = {"HEADER",    "MESHES", "POSITIONS", "ECOL",  "ERROR", "TRIANGLES",
                                            "MAP",       "OBJECTS", "COS",      "NODES", "INNER", "COLOURS",
                                            "NORMALS"};
    ASSERT_EQ(s.size(), names.size());
    for (size_t i = 0; i < s.size(); ++i) {
        EXPECT_EQ(s[i].name, names[i]);
        EXPECT_EQ(s[i].offset % 64, 0u) << s[i].name;
        if (i > 0) {
            EXPECT_GE(s[i].offset, s[i - 1].offset + s[i - 1].size);
        }
    }
    EXPECT_EQ(s[2].count, 10u);  // positions
    EXPECT_EQ(s[6].count, 12u);  // map: 5 + 7
    EXPECT_EQ(s[7].size, 3 * sizeof(oss::ObjectDisk));
    EXPECT_EQ(s[9].size, 5 * sizeof(oss::NodeLink));
    EXPECT_EQ(s[10].size, 2 * sizeof(oss::InnerDisk));  // the root and node 1
    EXPECT_EQ(f.fileSize() % 64, 0u);
    EXPECT_EQ(f.fileSize(), fs::file_size(path));
}

TEST(OssFile, EveryTruncationIsRejected) {
    const std::string good = scratch("truncate_source.oss"), path = scratch("truncated.oss");
    writeOss(good, smallScene());
    const std::vector<char> bytes = readBytes(good);
    for (size_t size = 0; size < bytes.size(); ++size) {
        writeBytes(path, bytes, size);
        EXPECT_NE(openError(path), "") << "truncated to " << size << " bytes";
    }
}

TEST(OssFile, EveryByteFlipIsRejected) {
    const std::string good = scratch("flip_source.oss"), path = scratch("flipped.oss");
    writeOss(good, smallScene());
    const std::vector<char> bytes = readBytes(good);
    for (size_t i = 0; i < bytes.size(); ++i) {
        for (const unsigned char mask : {0xffu, 1u << (i % 8)}) {
            std::vector<char> bad = bytes;
            bad[i] = char(bad[i] ^ mask);
            writeBytes(path, bad, bad.size());
            EXPECT_NE(openError(path), "") << "byte " << i << " xor " << unsigned(mask);
        }
    }
}

TEST(OssFile, SampledByteFlipsInALargerFileAreRejected) {
    const PreparedScene scene = grownScene(40, 200, 300, 7);
    const std::string good = scratch("flip_large_source.oss"), path = scratch("flip_large.oss");
    writeOss(good, scene);
    const std::vector<char> bytes = readBytes(good);
    ASSERT_GT(bytes.size(), 8192u);
    std::vector<OssFile::SectionInfo> sections = OssFile::open(good).sections();
    // Every section's first and last byte and the padding after it, then pseudo-random positions.
    std::vector<size_t> positions;
    for (size_t i = 0; i < sections.size(); ++i) {
        const uint64_t end = sections[i].offset + sections[i].size;
        if (sections[i].size > 0) positions.insert(positions.end(), {sections[i].offset, end - 1});
        if (end % 64 != 0) positions.push_back(end);
    }
    uint64_t state = 12345;
    while (positions.size() < 2500) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        positions.push_back(size_t((state >> 33) % bytes.size()));
    }
    std::set<std::string> sections_hit;
    for (const size_t i : positions) {
        std::vector<char> bad = bytes;
        bad[i] = char(bad[i] ^ (1u << (i % 8)));
        writeBytes(path, bad, bad.size());
        const std::string error = openError(path);
        EXPECT_NE(error, "") << "byte " << i;
        for (const OssFile::SectionInfo& s : sections)
            if (i >= s.offset && i < s.offset + s.size) sections_hit.insert(s.name);
    }
    EXPECT_EQ(sections_hit.size(), sections.size());
}

TEST(OssFile, AppendedBytesAreRejected) {
    const std::string path = scratch("appended.oss");
    writeOss(path, smallScene());
    std::ofstream(path, std::ios::binary | std::ios::app) << '\0';
    EXPECT_NE(openError(path).find("section HEADER at offset 16: the header says the file is"), std::string::npos)
        << openError(path);
}

TEST(OssFile, ErrorsNameFileSectionAndOffset) {
    const std::string good = scratch("named_source.oss"), path = scratch("named.oss");
    writeOss(good, smallScene());
    std::vector<char> bytes = readBytes(good);
    const uint64_t ecol = sectionOffset(OssFile::open(good), "ECOL");
    bytes[ecol + 3] ^= 0x40;
    writeBytes(path, bytes, bytes.size());
    EXPECT_EQ(openError(path), path + ": section ECOL at offset " + std::to_string(ecol) +
                                   ": checksum mismatch (corrupt data)");
    writeBytes(path, bytes, 100);
    EXPECT_EQ(openError(path), path + ": section HEADER at offset 0: file is 100 bytes, shorter than the "
                                      "512-byte header (truncated, or not an .oss file)");
    EXPECT_NE(openError(scratch("missing.oss")).find("cannot open"), std::string::npos);
}

TEST(OssFile, FutureVersionIsNamed) {
    const std::string good = scratch("version_source.oss"), path = scratch("version.oss");
    writeOss(good, smallScene());
    std::vector<char> bytes = readBytes(good);
    bytes[8] = 7;
    writeBytes(path, bytes, bytes.size());
    EXPECT_EQ(openError(path), path + ": section HEADER at offset 8: format version 7, this build reads version 6");
    bytes[8] = 5;  // a file of an older build (no NORMALS): prepared again
    writeBytes(path, bytes, bytes.size());
    EXPECT_EQ(openError(path), path + ": section HEADER at offset 8: format version 5, this build reads version 6 "
                                      "(prepare the model again: occswitch prep)");
    bytes[0] = 'X';
    writeBytes(path, bytes, bytes.size());
    EXPECT_EQ(openError(path), path + ": section HEADER at offset 0: bad magic, not an .oss file");
}

// Semantic violations are written with valid checksums: writeOss does not validate content.
std::string errorOfWritten(const PreparedScene& scene) {
    const std::string path = scratch("bad.oss");
    writeOss(path, scene);
    const std::string error = openError(path);
    const std::string prefix = path + ": ";
    return error.rfind(prefix, 0) == 0 ? error.substr(prefix.size()) : "no error or wrong prefix: " + error;
}

TEST(OssFile, EcolNotBelowItsVertexIsRejected) {
    PreparedScene scene = smallScene();
    const uint64_t ecol = sectionOffsetOf(scene, "ECOL");
    scene.meshes[1].ecol[5] = 5;
    // mesh 1 starts at vertex 4, so its vertex 5 is entry 9 of the section
    EXPECT_EQ(errorOfWritten(scene),
              "section ECOL at offset " + std::to_string(ecol + 9 * 4) + ": mesh 1: ecol[5] = 5 is not < 5");
    scene.meshes[1].ecol[5] = -1;
    EXPECT_EQ(errorOfWritten(scene),
              "section ECOL at offset " + std::to_string(ecol + 9 * 4) + ": mesh 1: ecol[5] = -1 is negative but 5 >= q = 4");
}

TEST(OssFile, LockedVertexWithEcolIsRejected) {
    PreparedScene scene = smallScene();
    scene.meshes[0].ecol[2] = 1;
    EXPECT_NE(errorOfWritten(scene).find("mesh 0: ecol[2] = 1 but 2 < q = 3"), std::string::npos);
}

TEST(OssFile, QOutOfRangeIsRejected) {
    PreparedScene scene = smallScene();
    scene.meshes[0].q = 5;
    EXPECT_NE(errorOfWritten(scene).find("section MESHES at offset"), std::string::npos);
    EXPECT_NE(errorOfWritten(scene).find("mesh 0: q = 5 exceeds the vertex count 4"), std::string::npos);
    scene.meshes[0].q = 0;
    EXPECT_NE(errorOfWritten(scene).find("mesh 0: q = 0"), std::string::npos);
}

TEST(OssFile, DecreasingMapIsRejected) {
    PreparedScene scene = smallScene();
    const uint64_t map = sectionOffsetOf(scene, "MAP");
    scene.meshes[1].map[5] = 1;
    // mesh 1's map starts at entry 5 (after the tetrahedron's 5 entries)
    EXPECT_EQ(errorOfWritten(scene), "section MAP at offset " + std::to_string(map + 10 * 4) +
                                         ": mesh 1: map[5] = 1 < map[4] = 2 (map must be non-decreasing)");
}

TEST(OssFile, MapMustEndAtTheTriangleCount) {
    PreparedScene scene = smallScene();
    scene.meshes[0].map[4] = 3;
    EXPECT_NE(errorOfWritten(scene).find("mesh 0: map[4] = 3, expected the triangle count 4"), std::string::npos);
}

TEST(OssFile, MapBelowQMustRepeatMapQ) {
    PreparedScene scene = smallScene();
    scene.meshes[1].map[0] = 0;
    EXPECT_NE(errorOfWritten(scene).find("mesh 1: map[0] = 0 differs from map[q = 4] = 2"), std::string::npos);
}

TEST(OssFile, TriangleCornerOutOfRangeIsRejected) {
    PreparedScene scene = smallScene();
    const uint64_t triangles = sectionOffsetOf(scene, "TRIANGLES");
    scene.meshes[0].triangles[7] = 4;
    EXPECT_EQ(errorOfWritten(scene), "section TRIANGLES at offset " + std::to_string(triangles + 7 * 4) +
                                         ": mesh 0: triangle 2 corner 1 = 4 is not < vertex count 4");
}

TEST(OssFile, NonFiniteValuesAreRejected) {
    PreparedScene scene = smallScene();
    scene.meshes[1].positions[3].y = std::numeric_limits<float>::quiet_NaN();
    EXPECT_NE(errorOfWritten(scene).find("section POSITIONS at offset"), std::string::npos);
    EXPECT_NE(errorOfWritten(scene).find("mesh 1: position 3 is not finite"), std::string::npos);
    scene = smallScene();
    scene.meshes[0].error[3] = std::numeric_limits<float>::infinity();
    EXPECT_NE(errorOfWritten(scene).find("mesh 0: error[3] = inf is not finite"), std::string::npos);
    scene = smallScene();
    scene.objects[1].world[2][1] = std::numeric_limits<float>::quiet_NaN();
    EXPECT_NE(errorOfWritten(scene).find("object 1: world[9] = nan is not finite"), std::string::npos);
}

TEST(OssFile, ObjectMeshOutOfRangeIsRejected) {
    PreparedScene scene = smallScene();
    const uint64_t objects = sectionOffsetOf(scene, "OBJECTS");
    scene.objects[2].mesh = 2;
    EXPECT_EQ(errorOfWritten(scene), "section OBJECTS at offset " + std::to_string(objects + 2 * 184) +
                                         ": object 2: mesh 2 is not < mesh count 2");
}

TEST(OssFile, CompactnessOutsideUnitIntervalIsRejected) {
    PreparedScene scene = smallScene();
    scene.objects[1].compactness = 1.5f;
    EXPECT_NE(errorOfWritten(scene).find("object 1: compactness 1.5 is not in [0, 1]"), std::string::npos);
}

TEST(OssFile, UnsortedCosIsRejected) {
    PreparedScene scene = smallScene();
    const uint64_t cos = sectionOffsetOf(scene, "COS");
    scene.cos = {2, 0};
    EXPECT_EQ(errorOfWritten(scene), "section COS at offset " + std::to_string(cos + 4) +
                                         ": cos[1] = 0 has compactness 0.899999976 > 0.699999988 of cos[0] "
                                         "(must be sorted highest first)");
}

TEST(OssFile, CosEntriesMustBeQualifiedDistinctObjects) {
    PreparedScene scene = smallScene();
    scene.cos = {0, 3};
    EXPECT_NE(errorOfWritten(scene).find("cos[1] = 3 is not < object count 3"), std::string::npos);
    scene.cos = {0, 1};
    EXPECT_NE(errorOfWritten(scene).find("cos[1] = 1 has compactness 0.300000012 < ct = 0.550000012"),
              std::string::npos);
    scene.cos = {0, 0};
    EXPECT_NE(errorOfWritten(scene).find("cos[1] = 0 appears twice"), std::string::npos);
    scene.cos = {0, 2, 0, 2};
    EXPECT_NE(errorOfWritten(scene).find("COS has 4 entries but there are only 3 objects"), std::string::npos);
}

// The hierarchy, written with valid checksums: one tree in breadth-first order, every object
// one leaf, boxes and triangle counts that hold their children's, HLOD meshes that exist.
TEST(OssFile, ABrokenHierarchyIsRejected) {
    const uint64_t nodes = sectionOffsetOf(smallScene(), "NODES"), inner = sectionOffsetOf(smallScene(), "INNER");
    const auto at = [&](uint32_t n, size_t field) {
        return "section NODES at offset " + std::to_string(nodes + n * sizeof(oss::NodeLink) + field) + ": node " +
               std::to_string(n) + ": ";
    };
    // Nodes 0 and 1 are the inner nodes: INNER records 0 and 1.
    const auto in = [&](uint32_t n, size_t field) {
        return "section INNER at offset " + std::to_string(inner + n * sizeof(oss::InnerDisk) + field) + ": node " +
               std::to_string(n) + " (inner record " + std::to_string(n) + "): ";
    };
    const auto broken = [](const std::function<void(PreparedScene&)>& change) {
        PreparedScene scene = smallScene();
        change(scene);
        return errorOfWritten(scene);
    };
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].first_child = 2; }),
              at(1, 0) + "first_child 2, expected 3 (children follow in breadth-first order)");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].child_count = 3; }),
              at(1, 4) + "3 children from node 3 pass the 5 nodes");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[4].object = 0; }), at(4, 0) + "object 0 is a second leaf");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[4].object = 3; }), at(4, 0) + "leaf object 3 is not < object count 3");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].mesh = 2; }), in(1, 24) + "HLOD mesh 2 is not < mesh count 2");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[0].triangles = 17; }), in(0, 32) + "17 triangles, its children have 16");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].box.max = s.nodes[1].box.min; }),
              in(1, 0) + "box does not hold child 4's box");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].box.min.z = std::numeric_limits<float>::infinity(); }),
              in(1, 0) + "box is not finite");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].world[3][1] = std::numeric_limits<float>::infinity(); }),
              in(1, 40 + 4 * 13) + "world[13] is not finite");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[1].error = std::numeric_limits<float>::quiet_NaN(); }),
              in(1, 28) + "error nan is not a finite number >= 0");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes[0].child_count = 0, s.nodes[0].first_child = 0; }),
              at(0, 4) + "the root has no children");
    EXPECT_EQ(broken([](PreparedScene& s) { s.nodes.pop_back(); }),
              at(1, 4) + "2 children from node 3 pass the 4 nodes");
    EXPECT_EQ(broken([](PreparedScene& s) {
                  s.nodes[1].child_count = 1, s.nodes[1].triangles = 4, s.nodes[0].triangles = 10;
              }),
              at(4, 0) + "no node has it as a child (the tree reaches only 4 nodes)");
    EXPECT_EQ(broken([](PreparedScene& s) {
                  s.nodes = {s.nodes[0], s.nodes[3], s.nodes[4]};  // object 2 has no leaf
                  s.nodes[1].depth = s.nodes[2].depth = 1, s.nodes[0].triangles = 10;
              }),
              "section NODES at offset " + std::to_string(nodes) + ": node 0: 2 leaves for 3 objects (one leaf per object)");
}

// The header's count of inner nodes (version 4) agrees with the nodes and with INNER's size:
// changed with a valid header checksum, it is named.
TEST(OssFile, AnInnerCountThatDisagreesIsRejected) {
    const std::string good = scratch("inner_source.oss"), path = scratch("inner.oss");
    writeOss(good, smallScene());
    const std::vector<char> bytes = readBytes(good);
    const auto withInnerCount = [&](uint32_t inner) {
        std::vector<char> b = bytes;
        std::memcpy(b.data() + offsetof(oss::Header, inner_count), &inner, sizeof inner);
        const uint64_t checksum = XXH3_64bits(b.data(), offsetof(oss::Header, header_checksum));
        std::memcpy(b.data() + offsetof(oss::Header, header_checksum), &checksum, sizeof checksum);
        writeBytes(path, b, b.size());
        return openError(path);
    };
    EXPECT_EQ(withInnerCount(2), "");  // the file as written: the root and node 1
    EXPECT_EQ(withInnerCount(0), path + ": section HEADER at offset 448: 0 inner nodes for 5 nodes (none without a "
                                        "hierarchy; else at least the root, and fewer than the nodes)");
    EXPECT_EQ(withInnerCount(5), path + ": section HEADER at offset 448: 5 inner nodes for 5 nodes (none without a "
                                        "hierarchy; else at least the root, and fewer than the nodes)");
    EXPECT_NE(withInnerCount(1).find("section INNER at offset "), std::string::npos) << withInnerCount(1);
    EXPECT_NE(withInnerCount(1).find("size 208 bytes, expected 1 elements * 104 bytes = 104"), std::string::npos);
}

TEST(OssFile, EmptySceneIsRejected) {
    PreparedScene scene = smallScene();
    scene.objects.clear();
    scene.cos.clear();
    EXPECT_EQ(errorOfWritten(scene), "section HEADER at offset 32: no objects");
    scene.meshes.clear();
    EXPECT_EQ(errorOfWritten(scene), "section HEADER at offset 28: no meshes");
}

TEST(OssFile, BadCtIsRejected) {
    PreparedScene scene = smallScene();
    scene.ct = std::numeric_limits<float>::quiet_NaN();
    EXPECT_EQ(errorOfWritten(scene), "section HEADER at offset 56: compactness threshold ct = nan is not in [0, 1]");
}

TEST(OssFile, VerifyAcceptsValidProgressiveMeshes) {
    const PreparedScene scene = grownScene(30, 500, 60, 99);
    const std::string path = scratch("grown.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);
    f.verifyLodPrefix();
    expectSameScene(f.toPreparedScene(), scene);
}

std::string verifyError(const PreparedScene& scene) {
    const std::string path = scratch("verify.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);  // structurally valid: only the prefix property is broken
    try {
        f.verifyLodPrefix();
    } catch (const InputError& e) {
        return std::string(e.what()).substr(path.size() + 2);
    }
    return "";
}

TEST(OssFile, VerifyRejectsMapOffByOne) {
    PreparedScene scene = smallScene();
    const uint64_t map = sectionOffsetOf(scene, "MAP");
    scene.meshes[1].map[5] = 5;
    EXPECT_EQ(verifyError(scene), "section MAP at offset " + std::to_string(map + 10 * 4) +
                                      ": mesh 1: LOD prefix broken at k = 5: triangle 4 degenerates when vertex 5 "
                                      "collapses into 4, but it is below map[5] = 5");
    scene.meshes[1].map[5] = 3;
    EXPECT_EQ(verifyError(scene), "section MAP at offset " + std::to_string(map + 10 * 4) +
                                      ": mesh 1: LOD prefix broken at k = 5: collapsing vertex 5 into 4 removes 2 "
                                      "triangles, but map[6] - map[5] = 3; triangle 3 stays non-degenerate");
}

TEST(OssFile, VerifyRejectsTrianglesOutOfCollapseOrder) {
    PreparedScene scene = smallScene();
    // swap t1 (survives both collapses) with t2 (dies when 4 collapses)
    std::swap_ranges(scene.meshes[1].triangles.begin() + 3, scene.meshes[1].triangles.begin() + 6,
                     scene.meshes[1].triangles.begin() + 6);
    EXPECT_NE(verifyError(scene).find("mesh 1: LOD prefix broken at k = 4: triangle 1 degenerates when vertex 4 "
                                      "collapses into 0, but it is below map[4] = 2"),
              std::string::npos);
}

TEST(OssFile, VerifyRejectsDegenerateFullDetailTriangle) {
    PreparedScene scene = smallScene();
    scene.meshes[0].triangles[5] = 2;  // t1 = (1, 2, 2)
    EXPECT_NE(verifyError(scene).find("mesh 0: LOD prefix broken at k = 4: triangle 1 (1, 2, 2) is degenerate at "
                                      "full detail"),
              std::string::npos);
}

TEST(OssFile, VerifyReportsTheLowestBrokenMesh) {
    PreparedScene scene = grownScene(200, 300, 200, 5);
    for (const uint32_t i : {150u, 60u, 170u}) scene.meshes[i].map[scene.meshes[i].map.size() - 2] -= 1;
    EXPECT_NE(verifyError(scene).find(": mesh 60: LOD prefix broken"), std::string::npos);
}

TEST(OssFile, WriteIntoMissingDirectoryThrowsAndLeavesNothing) {
    const fs::path dir = scratchDir() / "no_such_dir";
    try {
        writeOss((dir / "scene.oss").string(), smallScene());
        ADD_FAILURE() << "no exception";
    } catch (const InputError& e) {
        EXPECT_EQ(e.file(), (dir / "scene.oss").string());
        EXPECT_NE(std::string(e.what()).find("cannot create temporary file"), std::string::npos);
    }
    EXPECT_FALSE(fs::exists(dir));
}

std::vector<std::string> filesIn(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) names.push_back(entry.path().filename().string());
    std::sort(names.begin(), names.end());
    return names;
}

TEST(OssFile, FailedWriteLeavesTheExistingFileUntouched) {
    const fs::path dir = scratchDir() / "failed_write";
    fs::create_directories(dir);
    const std::string path = (dir / "scene.oss").string();
    writeOss(path, smallScene());
    const std::vector<char> before = readBytes(path);

    // A file size limit makes write() fail with EFBIG part way through the new file.
    rlimit old_limit{};
    ASSERT_EQ(getrlimit(RLIMIT_FSIZE, &old_limit), 0);
    const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
    rlimit limit = old_limit;
    limit.rlim_cur = 1000;
    ASSERT_EQ(setrlimit(RLIMIT_FSIZE, &limit), 0);
    bool threw = false;
    try {
        writeOss(path, grownScene(5, 100, 10, 3));
    } catch (const InputError& e) {
        threw = true;
        EXPECT_NE(std::string(e.what()).find("cannot write temporary file"), std::string::npos) << e.what();
    }
    setrlimit(RLIMIT_FSIZE, &old_limit);
    std::signal(SIGXFSZ, old_handler);

    EXPECT_TRUE(threw);
    EXPECT_EQ(readBytes(path), before);
    EXPECT_EQ(filesIn(dir), std::vector<std::string>{"scene.oss"});
}

// prep's hierarchy pass starts its writer from the flat file (addMeshesOf): the meshes' bytes
// are copied from it by the kernel instead of being added one by one, and the file is the same.
TEST(OssFile, AWriterStartedFromAFileWritesWhatAddingItsMeshesWould) {
    const PreparedScene base = grownScene(5, 40, 6, 3), more = grownScene(3, 30, 2, 9);
    const std::string flat_path = scratch("writer_base.oss");
    writeOss(flat_path, base);
    const OssFile flat = OssFile::open(flat_path, OssFile::Pages::Release);
    const auto write = [&](const std::string& path, bool from_file) {
        OssStreamWriter w(path);
        w.setDurable(from_file);  // syncing or not writes the same bytes
        if (from_file) {
            w.addMeshesOf(flat);
            EXPECT_EQ(w.meshCount(), flat.meshCount());
            EXPECT_EQ(w.vertexCount(), flat.vertexCount());
            EXPECT_EQ(w.triangleCount(), flat.triangleCount());
        } else {
            for (uint32_t m = 0; m < flat.meshCount(); ++m) w.addMesh(flat.progressiveMesh(m));
        }
        for (const ProgressiveMesh& m : more.meshes) w.addMesh(m);
        w.finish(base.objects, base.cos, base.ct);
    };
    const std::string copied = scratch("writer_copied.oss"), added = scratch("writer_added.oss");
    write(copied, true);
    write(added, false);
    EXPECT_EQ(readBytes(copied), readBytes(added));
    const OssFile f = OssFile::open(copied);
    ASSERT_EQ(f.meshCount(), base.meshes.size() + more.meshes.size());
    f.verifyLodPrefix();
    const ProgressiveMesh last = f.progressiveMesh(f.meshCount() - 1);
    EXPECT_EQ(last.positions, more.meshes.back().positions);
    EXPECT_EQ(last.triangles, more.meshes.back().triangles);
    // Only first.
    OssStreamWriter late(scratch("writer_late.oss"));
    late.addMesh(more.meshes[0]);
    EXPECT_THROW(late.addMeshesOf(flat), std::logic_error);
}

TEST(OssFile, WriteReplacesAnExistingFile) {
    const fs::path dir = scratchDir() / "replace";
    fs::create_directories(dir);
    const std::string path = (dir / "scene.oss").string();
    writeOss(path, smallScene());
    const PreparedScene other = grownScene(3, 50, 4, 11);
    writeOss(path, other);
    expectSameScene(OssFile::open(path).toPreparedScene(), other);
    EXPECT_EQ(filesIn(dir), std::vector<std::string>{"scene.oss"});
}

TEST(OssFile, WriteRejectsArraysThatDoNotFitTheLayout) {
    const fs::path dir = scratchDir() / "inconsistent";
    fs::create_directories(dir);
    PreparedScene scene = smallScene();
    scene.meshes[1].map.pop_back();
    EXPECT_THROW(writeOss((dir / "scene.oss").string(), scene), std::invalid_argument);
    scene = smallScene();
    scene.meshes[0].triangles.pop_back();
    EXPECT_THROW(writeOss((dir / "scene.oss").string(), scene), std::invalid_argument);
    EXPECT_TRUE(filesIn(dir).empty());
}

}  // namespace
}  // namespace occ

namespace occ {
namespace {

// Version 5's COLOURS: a mesh's vertex colours come back as written; a mesh written without
// them is white in the file (the object's colour alone) and reads back without them.
TEST(OssFile, VertexColoursRoundTripAndAMeshWithoutThemIsWhite) {
    PreparedScene scene = smallScene();
    ASSERT_GE(scene.meshes.size(), 2u);
    ProgressiveMesh& coloured = scene.meshes[0];
    coloured.colours.resize(coloured.positions.size());
    for (size_t v = 0; v < coloured.colours.size(); ++v) coloured.colours[v] = 0xFF000000u | uint32_t(v * 7919);
    scene.meshes[1].colours.clear();
    const std::string path = scratch("colours.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);
    EXPECT_EQ(f.progressiveMesh(0).colours, coloured.colours);
    EXPECT_TRUE(f.progressiveMesh(1).colours.empty());
    const OssFile::MeshView second = f.mesh(1);
    ASSERT_EQ(second.colours.size(), second.positions.size());
    for (uint32_t c : second.colours) EXPECT_EQ(c, oss::kWhite);
    EXPECT_EQ(f.allColours().size(), f.vertexCount());
    scene.meshes[0].colours.pop_back();
    EXPECT_THROW(writeOss(scratch("colours_short.oss"), scene), std::invalid_argument);
}

// Version 6's NORMALS: a mesh's vertex normals come back as written; a mesh written without them
// has kNoNormal in the file and reads back without them.
TEST(OssFile, VertexNormalsRoundTripAndAMeshWithoutThemHasNone) {
    PreparedScene scene = smallScene();
    ASSERT_GE(scene.meshes.size(), 2u);
    ProgressiveMesh& lit = scene.meshes[1];
    lit.normals.resize(lit.positions.size());
    for (size_t v = 0; v < lit.normals.size(); ++v)
        lit.normals[v] = v == 1 ? oss::kNoNormal : oss::encodeNormal(glm::normalize(glm::vec3(float(v), 1.0f, -2.0f)));
    scene.meshes[0].normals.clear();
    const std::string path = scratch("normals.oss");
    writeOss(path, scene);
    const OssFile f = OssFile::open(path);
    EXPECT_EQ(f.progressiveMesh(1).normals, lit.normals);
    EXPECT_TRUE(f.progressiveMesh(0).normals.empty());
    for (uint32_t n : f.mesh(0).normals) EXPECT_EQ(n, oss::kNoNormal);
    EXPECT_EQ(f.allNormals().size(), f.vertexCount());
    scene.meshes[1].normals.push_back(1u);
    EXPECT_THROW(writeOss(scratch("normals_long.oss"), scene), std::invalid_argument);
}

// The octahedral encoding: within 1e-4 of every direction (snorm16 steps are 3e-5 of the
// octahedron's span), never kNoNormal, the poles and axes exact.
TEST(OssFile, NormalsEncodeWithinATenThousandth) {
    std::mt19937 random(6);
    std::normal_distribution<float> gauss;
    std::vector<glm::vec3> directions = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}};
    for (int i = 0; i < 2000; ++i) directions.push_back(glm::normalize(glm::vec3(gauss(random), gauss(random), gauss(random))));
    for (const glm::vec3& d : directions) {
        const uint32_t packed = oss::encodeNormal(d);
        ASSERT_NE(packed, oss::kNoNormal);
        const glm::vec3 back = oss::decodeNormal(packed);
        EXPECT_NEAR(glm::length(back), 1.0f, 1e-5f);
        EXPECT_GT(glm::dot(back, d), 1.0f - 1e-4f) << d.x << " " << d.y << " " << d.z;
    }
}

}  // namespace
}  // namespace occ
