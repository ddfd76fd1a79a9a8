// SPDX-License-Identifier: MIT
// The object hierarchy and its HLODs (issue 16), in memory and in the .oss.
#include "frustum_cull.h"
#include "import/grid.h"
#include "import/import.h"
#include "import/plant.h"
#include "pipeline/cut_stage.h"
#include "pipeline/device_scene.h"
#include "pipeline/pipeline.h"
#include "prep/cluster_collapse.h"
#include "prep/fast_collapser.h"
#include "prep/rearrange.h"
#include "prep/hierarchy.h"
#include "scene/lod_prefix.h"
#include "scene/oss_file.h"
#include "prep/prepare.h"
#include "test_support.h"
#include "view/camera.h"

#include <glm/gtc/matrix_transform.hpp>
#include "scene/colour.h"

#include <glm/gtc/type_ptr.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <set>

namespace occ {
namespace {

struct HierarchyFixture {
    std::unique_ptr<OssFile> file;
    std::vector<k::Aabb> boxes;
    std::vector<uint64_t> triangles;
    HierarchyFixture() {
        const std::string path = (test::scratchDir() / "hierarchy_plant.oss").string();
        writeOss(path, prepareScene(generatePlant({400, 11}), PrepOptions{}));
        file = std::make_unique<OssFile>(OssFile::open(path));
        for (const oss::ObjectDisk& o : file->objects()) {
            boxes.push_back({{o.aabb_min[0], o.aabb_min[1], o.aabb_min[2]}, {o.aabb_max[0], o.aabb_max[1], o.aabb_max[2]}});
            triangles.push_back(file->meshRecords()[o.mesh].triangle_count);
        }
    }
};

const HierarchyFixture& fixture() {
    static const HierarchyFixture f;
    return f;
}

template <typename A, typename B>
bool contains(const A& outer, const B& inner) {
    return glm::all(glm::lessThanEqual(outer.min, inner.min)) && glm::all(glm::greaterThanEqual(outer.max, inner.max));
}

TEST(Hierarchy, EveryObjectIsOneLeafAndNodesBoundTheirChildrenBreadthFirst) {
    const HierarchyFixture& f = fixture();
    for (uint32_t fanout : {2u, 4u, 8u}) {
        const ObjectHierarchy h = buildObjectHierarchy(f.boxes, f.triangles, fanout);
        std::set<uint32_t> leaves;
        uint64_t root_triangles = 0;
        for (uint64_t t : f.triangles) root_triangles += t;
        EXPECT_EQ(h.nodes[0].triangles, root_triangles);
        for (size_t n = 0; n < h.nodes.size(); ++n) {
            const SceneNode& node = h.nodes[n];
            if (node.child_count == 0) {
                ASSERT_LT(node.object, f.boxes.size());
                EXPECT_TRUE(leaves.insert(node.object).second) << "object " << node.object << " twice";
                EXPECT_TRUE(contains(node.box, f.boxes[node.object]));
                continue;
            }
            EXPECT_GE(node.child_count, 2u);
            EXPECT_LE(node.child_count, fanout);
            EXPECT_GT(node.first_child, n);  // children come after their parent
            uint64_t sum = 0;
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) {
                EXPECT_EQ(h.nodes[c].depth, node.depth + 1);
                EXPECT_TRUE(contains(node.box, h.nodes[c].box));
                sum += h.nodes[c].triangles;
            }
            EXPECT_EQ(sum, node.triangles);
            if (n > 0) {
                EXPECT_GE(node.depth, h.nodes[n - 1].depth);  // level by level
            }
        }
        EXPECT_EQ(leaves.size(), f.boxes.size());
        // Splits within a third of balanced: a child holds at most (4/3)^splits / fanout of its
        // parent's objects, which bounds the levels below the root.
        const double splits = std::ceil(std::log2(double(fanout)));
        const double shrink = double(fanout) / std::pow(4.0 / 3.0, splits);
        const double bound = std::ceil(std::log(double(f.boxes.size())) / std::log(shrink));
        EXPECT_LE(double(h.levels - 1), bound + 1) << "fanout " << fanout;
        const double ideal = std::ceil(std::log(double(f.boxes.size())) / std::log(double(fanout)));
        EXPECT_GE(double(h.levels - 1), ideal) << "fanout " << fanout;
    }
    EXPECT_THROW(buildObjectHierarchy(f.boxes, f.triangles, 1), std::invalid_argument);
}

// Every inner node's HLOD is a valid progressive mesh in world space, inside its node's box,
// covering most of it, from a merged input of about twice node_triangles.
// The fixture plant's hierarchy (fanout 8) with its HLODs of about 600 triangles, kept in memory:
// node n's HLOD is made[h.nodes[n].mesh].
struct BuiltHlods {
    ObjectHierarchy h;
    HlodOptions options;
    std::vector<ProgressiveMesh> made;
    HlodProgress progress;
    explicit BuiltHlods(bool colour_borders = true) {
        const HierarchyFixture& f = fixture();
        h = buildObjectHierarchy(f.boxes, f.triangles, 8);
        options.node_triangles = 600;
        options.colour_borders = colour_borders;
        buildHlods(*f.file, h, options, [&](ProgressiveMesh&& p) {
            made.push_back(std::move(p));
            return uint32_t(made.size() - 1);
        }, &progress);
    }
};

TEST(Hierarchy, HlodsAreProgressiveMeshesOfTheirSubtrees) {
    const BuiltHlods built;
    const ObjectHierarchy& h = built.h;
    const HlodOptions& options = built.options;
    const std::vector<ProgressiveMesh>& made = built.made;
    const HlodProgress& progress = built.progress;
    EXPECT_EQ(progress.done, progress.total);
    std::vector<ProgressiveMesh> hlods(h.nodes.size());
    for (size_t n = 0; n < h.nodes.size(); ++n)
        if (h.nodes[n].child_count > 0) {
            ASSERT_LT(h.nodes[n].mesh, made.size());
            hlods[n] = made[h.nodes[n].mesh];
        } else {
            EXPECT_EQ(h.nodes[n].mesh, UINT32_MAX);
        }
    EXPECT_EQ(made.size(), progress.total);
    LodPrefixScratch scratch;
    uint32_t inner = 0;
    for (size_t n = 0; n < h.nodes.size(); ++n) {
        const SceneNode& node = h.nodes[n];
        const ProgressiveMesh& p = hlods[n];
        if (node.child_count == 0) {
            EXPECT_EQ(p.vertexCount(), 0u);
            continue;
        }
        ++inner;
        ASSERT_GT(p.triangleCount(), 0u) << "node " << n;
        EXPECT_FALSE(checkLodPrefix(p.vertexCount(), p.ecol, p.triangles, p.map, p.q, scratch).has_value()) << n;
        // A little over 2 x node_triangles at most (children round up to a level), and never
        // more than the subtree has.
        EXPECT_LE(p.triangleCount(), std::min<uint64_t>(node.triangles, 3 * options.node_triangles)) << "node " << n;
        // Its finest level is at most 1 / reduction of the subtree (fine input: the levels past
        // it are not kept), or its coarsest where even that has more.
        EXPECT_LE(p.triangleCount(), std::max<uint64_t>(p.map[p.q], node.triangles / options.reduction)) << "node " << n;
        Bounds b;
        for (const glm::vec3& v : p.positions) b.min = glm::min(b.min, v), b.max = glm::max(b.max, v);
        const glm::vec3 slack = 1e-4f * (node.box.max - node.box.min) + glm::vec3(1e-5f);
        EXPECT_TRUE(contains(k::Aabb{node.box.min - slack, node.box.max + slack}, b)) << "node " << n;
        EXPECT_GE(glm::length(b.max - b.min), 0.5f * glm::length(node.box.max - node.box.min)) << "node " << n;
    }
    EXPECT_GT(inner, 8u);
}

// Issue 49: an HLOD's vertices carry the colours of the objects they stand for. A vertex of an
// HLOD is a vertex of an object of its subtree, with that object's colour (the plant's meshes
// are white), sRGB-encoded, and the object's box holds it; or a placed vertex of a cluster.
// With colour borders kept, a cluster is of one colour, one of the subtree's object colours.
// Without them (prep's default) a placed vertex mixes its cluster's colours: each channel then
// lies between the subtree's least and greatest.
void checkHlodColours(bool colour_borders) {
    const HierarchyFixture& f = fixture();
    const BuiltHlods built(colour_borders);
    const ObjectHierarchy& h = built.h;
    const std::vector<ProgressiveMesh>& made = built.made;
    const auto encoded = [](const float* linear) {
        uint32_t c = 0xFF000000u;
        for (int k = 0; k < 3; ++k) c |= uint32_t(std::lround(255.0f * linearToSrgb(linear[k]))) << (8 * k);
        return c;
    };
    const std::span<const oss::ObjectDisk> objects = f.file->objects();
    size_t checked = 0, multicoloured = 0, mixed = 0;
    for (size_t n = 0; n < h.nodes.size(); ++n) {
        if (h.nodes[n].child_count == 0) continue;
        // The subtree's objects.
        std::vector<uint32_t> subtree, stack{uint32_t(n)};
        while (!stack.empty()) {
            const SceneNode& s = h.nodes[stack.back()];
            stack.pop_back();
            if (s.child_count == 0) subtree.push_back(s.object);
            for (uint32_t c = s.first_child; c < s.first_child + s.child_count; ++c) stack.push_back(c);
        }
        glm::ivec3 least(255), greatest(0);
        for (uint32_t o : subtree)
            for (int k = 0; k < 3; ++k) {
                const int channel = int((encoded(objects[o].color) >> (8 * k)) & 0xFFu);
                least[k] = std::min(least[k], channel), greatest[k] = std::max(greatest[k], channel);
            }
        const ProgressiveMesh& p = made[h.nodes[n].mesh];
        ASSERT_EQ(p.colours.size(), p.positions.size()) << "node " << n;
        std::set<uint32_t> seen;
        for (size_t v = 0; v < p.positions.size(); ++v) {
            bool found = false;
            for (uint32_t o : subtree) {
                const oss::ObjectDisk& d = objects[o];
                const glm::vec3 lo = glm::make_vec3(d.aabb_min), hi = glm::make_vec3(d.aabb_max);
                const glm::vec3 slack = 1e-4f * (hi - lo) + glm::vec3(1e-4f);
                if (encoded(d.color) == p.colours[v] && glm::all(glm::lessThanEqual(lo - slack, p.positions[v])) &&
                    glm::all(glm::lessThanEqual(p.positions[v], hi + slack)))
                    found = true;
            }
            if (colour_borders && !found)
                for (uint32_t o : subtree) found = found || encoded(objects[o].color) == p.colours[v];
            if (!colour_borders && !found) {
                found = true;
                for (int k = 0; k < 3; ++k) {
                    const int channel = int((p.colours[v] >> (8 * k)) & 0xFFu);
                    found = found && channel >= least[k] - 1 && channel <= greatest[k] + 1;
                }
                mixed += found;
            }
            EXPECT_TRUE(found) << "node " << n << " vertex " << v << " colour " << std::hex << p.colours[v];
            seen.insert(p.colours[v]);
            ++checked;
        }
        multicoloured += seen.size() > 1;
    }
    EXPECT_GT(checked, 1000u);
    EXPECT_GT(multicoloured, 4u);
    if (!colour_borders) {
        EXPECT_GT(mixed, 0u) << "clusters were expected to mix colours somewhere";
    }
}

// Issue 49, item 2: every HLOD carries a normal per vertex, most of them one (the plant's pipes,
// walls and floors have a direction almost everywhere), and each a unit direction; and --hlod-
// normals off leaves them out.
TEST(Hierarchy, HlodVerticesCarryNormals) {
    const BuiltHlods built;
    uint64_t vertices = 0, with = 0;
    for (const SceneNode& node : built.h.nodes) {
        if (node.child_count == 0) continue;
        const ProgressiveMesh& p = built.made[node.mesh];
        ASSERT_EQ(p.normals.size(), p.vertexCount());
        for (uint32_t n : p.normals) {
            ++vertices;
            if (n == oss::kNoNormal) continue;
            ++with;
            EXPECT_NEAR(glm::length(oss::decodeNormal(n)), 1.0f, 1e-5f);
        }
    }
    EXPECT_GT(with, vertices / 2) << with << " of " << vertices << " HLOD vertices have a normal";
    const HierarchyFixture& f = fixture();
    ObjectHierarchy h = buildObjectHierarchy(f.boxes, f.triangles, 8);
    HlodOptions options;
    options.node_triangles = 600;
    options.normals = false;
    std::vector<ProgressiveMesh> made;
    buildHlods(*f.file, h, options, [&](ProgressiveMesh&& p) {
        made.push_back(std::move(p));
        return uint32_t(made.size() - 1);
    });
    for (const ProgressiveMesh& p : made) EXPECT_TRUE(p.normals.empty());
}

TEST(Hierarchy, HlodVerticesCarryTheColoursOfTheObjectsTheyStandFor) { checkHlodColours(true); }
TEST(Hierarchy, PlacedHlodVerticesMixTheColoursOfTheirClusters) { checkHlodColours(false); }

// A cloud of 512 small closed tetrahedra: edge collapses cannot go below the 4 triangles each
// (2 048 in all); clustering after them can, and what it makes is still a progressive mesh whose
// every level moves no input vertex farther than that level's error.
TEST(Hierarchy, ClusteringRemovesTheFloorsEdgeCollapsesKeep) {
    std::vector<glm::vec3> positions;
    std::vector<uint32_t> triangles;
    for (int x = 0; x < 8; ++x)
        for (int y = 0; y < 8; ++y)
            for (int z = 0; z < 8; ++z) {
                const uint32_t b = uint32_t(positions.size());
                const glm::vec3 o{float(x), float(y), float(z)};
                positions.insert(positions.end(), {o, o + glm::vec3(0.3f, 0, 0), o + glm::vec3(0, 0.3f, 0), o + glm::vec3(0, 0, 0.3f)});
                triangles.insert(triangles.end(), {b, b + 2, b + 1, b, b + 1, b + 3, b, b + 3, b + 2, b + 1, b + 2, b + 3});
            }
    const CollapseSequence edges = fastCollapseSequence(positions, triangles);
    EXPECT_EQ(edges.triangles.size(), 0u) << "a tetrahedron has no legal edge collapse";
    EXPECT_THROW(clusterAfterCollapses(positions, nullptr, triangles, edges, {0.5f, 0.25f}), std::invalid_argument);
    const CollapseSequence clustered = clusterAfterCollapses(positions, nullptr, triangles, edges);
    const CollapseArrays arrays = recordCollapseArrays(uint32_t(positions.size()), uint32_t(triangles.size() / 3), clustered);
    const ProgressiveMesh p = rearrange(positions, triangles, clustered, arrays);
    LodPrefixScratch scratch;
    const auto bad = checkLodPrefix(p.vertexCount(), p.ecol, p.triangles, p.map, p.q, scratch);
    EXPECT_FALSE(bad.has_value()) << bad->what;
    // The coarsest level: cells a quarter of the cloud's extent, 5 x 5 x 5 clusters at most.
    EXPECT_LE(p.q, 125u);
    EXPECT_LT(p.map[p.q], 2048u / 8);
    // Every level: each input vertex, walked down to it, moved at most the level's error.
    const float extent = 7.3f;
    for (uint32_t k = p.vertexCount(); k >= p.q && k > 0; k -= std::max(1u, (p.vertexCount() - p.q) / 16)) {
        float error = 0.0f;
        for (uint32_t v = k; v < p.vertexCount(); ++v) error = std::max(error, p.error[v]);
        for (uint32_t v = 0; v < p.vertexCount(); ++v) {
            uint32_t w = v;
            while (w >= k) w = uint32_t(p.ecol[w]);
            EXPECT_LE(glm::length(p.positions[v] - p.positions[w]), error * 1.0001f + 1e-6f) << "level " << k;
        }
        EXPECT_LE(error, 0.25f * extent * std::sqrt(3.0f) * 1.01f) << "level " << k;
        if (k - p.q < std::max(1u, (p.vertexCount() - p.q) / 16)) break;
    }
    // Clustering's first moves join each tetrahedron's corners (the first cells are smaller than
    // the gaps between them), so the levels in between have triangles in between.
    EXPECT_GT(p.map[(p.vertexCount() + p.q) / 2], p.map[p.q]);
}

// prep's file: the flat scene's meshes, objects and COS unchanged, then one HLOD mesh per inner
// node, and the nodes, which verify accepts; the result does not depend on the thread count.
TEST(Hierarchy, TheFileCarriesTheHierarchyAndItsHlods) {
    const HierarchyFixture& f = fixture();
    HlodOptions options;
    options.node_triangles = 300;
    const std::string one = (test::scratchDir() / "hierarchy_1.oss").string(), two = (test::scratchDir() / "hierarchy_2.oss").string();
    options.threads = 1;
    OssFile::HlodCounts counts;
    const ObjectHierarchy h = writeWithHierarchy(*f.file, one, 4, options, nullptr, &counts);
    options.threads = 2;
    writeWithHierarchy(*f.file, two, 4, options);
    EXPECT_EQ(test::readBytes(one), test::readBytes(two));
    const OssFile file = OssFile::open(one);
    // What the writer counted is what the file holds (prep prints it without reading the file).
    const OssFile::HlodCounts read = file.hlodCounts();
    EXPECT_EQ(counts.inner, read.inner);
    EXPECT_EQ(counts.meshes, read.meshes);
    EXPECT_EQ(counts.triangles, read.triangles);
    EXPECT_GT(counts.triangles, 0u);
    file.verifyLodPrefix();
    ASSERT_EQ(file.nodeCount(), h.nodes.size());
    EXPECT_EQ(file.objectCount(), f.file->objectCount());
    const uint32_t flat_meshes = f.file->meshCount();
    uint32_t inner = 0;
    std::set<uint32_t> hlods;
    for (size_t n = 0; n < h.nodes.size(); ++n) {
        const oss::Node& d = file.nodes()[n];
        EXPECT_EQ(d.child_count, h.nodes[n].child_count);
        EXPECT_EQ(d.triangles, h.nodes[n].triangles);
        EXPECT_EQ(d.error, h.nodes[n].error);
        if (d.child_count > 0) {
            ++inner;
            EXPECT_GE(d.mesh, flat_meshes) << "HLODs come after the objects' meshes";
            EXPECT_TRUE(hlods.insert(d.mesh).second);
            // Errors add up the tree: a parent merges a child's level, no finer than the child.
            for (uint32_t c = d.first_child; c < d.first_child + d.child_count; ++c)
                EXPECT_GE(d.error, file.nodes()[c].error) << "node " << n << ", child " << c;
        }
    }
    EXPECT_GT(file.nodes()[0].error, 0.0f);
    EXPECT_EQ(file.meshCount(), flat_meshes + inner);
    for (uint32_t m = 0; m < flat_meshes; ++m) EXPECT_EQ(file.mesh(m).triangleCount(), f.file->mesh(m).triangleCount());
    for (uint32_t i = 0; i < file.objectCount(); ++i)
        EXPECT_EQ(std::memcmp(&file.objects()[i], &f.file->objects()[i], sizeof(oss::ObjectDisk)), 0);
    EXPECT_TRUE(std::equal(file.cos().begin(), file.cos().end(), f.file->cos().begin(), f.file->cos().end()));
    const PreparedScene scene = file.toPreparedScene();
    ASSERT_EQ(scene.nodes.size(), h.nodes.size());
    EXPECT_EQ(scene.nodes.back().object, h.nodes.back().object);
}

// Two leaves under one inner node, per group, under a root: group g's objects at worlds[g] and
// worlds[g] x step (meshes 0 and 1).
ObjectHierarchy twoLeafGroups(uint32_t groups) {
    ObjectHierarchy h;
    h.levels = 3;
    h.nodes.resize(1 + groups + 2 * groups);
    h.nodes[0].first_child = 1;
    h.nodes[0].child_count = groups;
    for (uint32_t g = 0; g < groups; ++g) {
        SceneNode& inner = h.nodes[1 + g];
        inner.depth = 1;
        inner.first_child = 1 + groups + 2 * g;
        inner.child_count = 2;
        inner.box = {glm::vec3(-100.0f), glm::vec3(100.0f)};
        for (uint32_t l = 0; l < 2; ++l) {
            SceneNode& leaf = h.nodes[inner.first_child + l];
            leaf.depth = 2;
            leaf.object = 2 * g + l;
            leaf.box = inner.box;
        }
    }
    h.nodes[0].box = {glm::vec3(-100.0f), glm::vec3(100.0f)};
    return h;
}

TEST(Hierarchy, RepeatedSubtreesAreFoundUpToASimilarityButNotAMirror) {
    const glm::mat4 step = glm::translate(glm::mat4(1.0f), glm::vec3(2, 0, 0));
    const glm::mat4 base = glm::translate(glm::mat4(1.0f), glm::vec3(1, 2, 3));
    const glm::mat4 turned = glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(-5, 0, 7)), 1.0f,
                                                    glm::vec3(0, 1, 0)),
                                        glm::vec3(2.0f));
    const glm::mat4 mirrored = glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1));
    const glm::mat4 moved_apart = glm::translate(glm::mat4(1.0f), glm::vec3(9, 9, 9));
    // Groups: the representative (last, matched first), a rotated and scaled copy, a mirror, the
    // same meshes placed differently, and a copy with the meshes swapped.
    const std::vector<glm::mat4> worlds{turned * base, turned * base * step, mirrored * base, mirrored * base * step,
                                        base, base * glm::translate(glm::mat4(1.0f), glm::vec3(0, 3, 0)),
                                        moved_apart * base, moved_apart * base * step, base, base * step};
    const std::vector<uint32_t> meshes{0, 1, 0, 1, 0, 1, 1, 0, 0, 1};
    const ObjectHierarchy h = twoLeafGroups(5);
    const SubtreeRepeats r = findRepeatedSubtrees(h.nodes, meshes, worlds);
    ASSERT_EQ(r.list.size(), 1u);
    EXPECT_EQ(r.of(1), 5u) << "the rotated, scaled copy repeats the last group";
    EXPECT_EQ(r.of(2), 2u) << "a mirror image would turn the HLOD inside out";
    EXPECT_EQ(r.of(3), 3u) << "the second object placed elsewhere";
    EXPECT_EQ(r.of(4), 4u) << "the meshes swapped";
    EXPECT_EQ(r.of(5), 5u);
    EXPECT_NEAR(r.find(1)->scale, 2.0f, 1e-5f);
    // The motion takes the representative's objects onto the repeat's.
    for (uint32_t l = 0; l < 2; ++l) {
        const glm::mat4 moved = r.find(1)->motion * worlds[8 + l];
        for (int c = 0; c < 4; ++c)
            for (int e = 0; e < 4; ++e) EXPECT_NEAR(moved[c][e], worlds[l][c][e], 1e-4f) << l << " " << c << " " << e;
    }
    EXPECT_GT(r.find(1)->slack, 0.0f);
    EXPECT_EQ(r.find(5), nullptr);

    // A flattened copy (a singular world, whose inverse is not finite) repeats nothing.
    const glm::mat4 flat = glm::scale(glm::mat4(1.0f), glm::vec3(0.0f));
    const std::vector<glm::mat4> singular{flat * base, flat * base * step, base, base * step};
    const SubtreeRepeats none = findRepeatedSubtrees(twoLeafGroups(2).nodes, std::vector<uint32_t>{0, 1, 0, 1}, singular);
    EXPECT_TRUE(none.list.empty());
    EXPECT_EQ(none.of(1), 1u);
}

TEST(Hierarchy, ATiledModelBuildsEachDistinctSubtreeOnceAndPlacesItsHlodOnTheCopies) {
    const std::string glb = (test::scratchDir() / "hierarchy_grid.glb").string();
    GridOptions g;
    g.nx = 3;
    g.ny = 2;
    g.nz = 2;
    writeGrid(glb, importModel(test::kEngine), g);
    const std::string flat = (test::scratchDir() / "hierarchy_grid_flat.oss").string();
    writeOss(flat, prepareScene(importModel(glb), PrepOptions{}));
    const OssFile file = OssFile::open(flat);
    HlodOptions options;
    options.node_triangles = 512;
    const std::string shared_path = (test::scratchDir() / "hierarchy_grid_shared.oss").string();
    const std::string own_path = (test::scratchDir() / "hierarchy_grid_own.oss").string();
    OssFile::HlodCounts counted;
    const ObjectHierarchy shared = writeWithHierarchy(file, shared_path, 8, options, nullptr, &counted);
    options.share_repeats = false;
    const ObjectHierarchy own = writeWithHierarchy(file, own_path, 8, options);
    ASSERT_EQ(shared.nodes.size(), own.nodes.size());

    const OssFile with = OssFile::open(shared_path), without = OssFile::open(own_path);
    const OssFile::HlodCounts read = with.hlodCounts();
    EXPECT_EQ(counted.inner, read.inner);
    EXPECT_EQ(counted.meshes, read.meshes);
    EXPECT_EQ(counted.triangles, read.triangles);
    EXPECT_LT(counted.meshes, counted.inner) << "repeats draw their representative's HLOD";
    with.verifyLodPrefix();
    uint32_t inner = 0, repeats = 0;
    uint64_t shared_triangles = 0, own_triangles = 0;  // of the nodes' HLODs as drawn
    double relative_difference = 0.0;                  // of the errors, summed over inner nodes
    std::set<uint32_t> hlods;
    for (size_t n = 0; n < shared.nodes.size(); ++n) {
        const SceneNode& a = shared.nodes[n];
        const SceneNode& b = own.nodes[n];
        EXPECT_EQ(a.child_count, b.child_count);
        EXPECT_EQ(std::memcmp(&with.nodes()[n].world, glm::value_ptr(a.world), sizeof(glm::mat4)), 0);
        if (a.child_count == 0) continue;
        ++inner;
        hlods.insert(a.mesh);
        EXPECT_EQ(b.world, glm::mat4(1.0f)) << "without sharing every HLOD is in world space";
        // Shared or not, a node's HLOD covers its box alike and has about the same error (a
        // copy's HLOD built for itself differs from its representative's only by rounding in the
        // world positions, which can turn a collapse or two). Its triangles may differ more: the
        // children's levels are chosen for the least error that fits the node's budget, and copies
        // whose errors are equal (shared) move to a finer level together where copies whose
        // errors differ by rounding (their own) move one by one: alike over the tree.
        // The error also holds what keeping the HLOD's levels up to 1 / reduction gave up
        // (HlodOptions::fine_input), the largest error of the collapses past that level, which
        // jumps where rounding reorders them: each within 2.5x, and 15 % apart on average (each
        // within 10 % before fine input).
        const float diagonal = glm::length(a.box.max - a.box.min);
        const float slack_error = 1e-3f * diagonal;
        EXPECT_LE(a.error, 2.5f * b.error + slack_error) << "node " << n;
        EXPECT_LE(b.error, 2.5f * a.error + slack_error) << "node " << n;
        relative_difference += std::abs(a.error - b.error) / std::max(b.error, slack_error);
        const OssFile::MeshView m = with.mesh(a.mesh);
        Bounds placed;
        for (const glm::vec3& p : m.positions) placed.extend(glm::vec3(a.world * glm::vec4(p, 1.0f)));
        Bounds built;
        for (const glm::vec3& p : without.mesh(b.mesh).positions) built.extend(p);
        const float slack = std::max(a.error, b.error) + 1e-3f * diagonal;
        EXPECT_LE(glm::length(placed.min - built.min), slack) << "node " << n;
        EXPECT_LE(glm::length(placed.max - built.max), slack) << "node " << n;
        shared_triangles += m.triangleCount();
        own_triangles += without.mesh(b.mesh).triangleCount();
        if (a.world != glm::mat4(1.0f)) ++repeats;
    }
    EXPECT_NEAR(double(shared_triangles), double(own_triangles), 0.2 * double(own_triangles));
    EXPECT_LE(relative_difference / inner, 0.15) << "mean relative difference of the errors, shared against own";
    EXPECT_GT(repeats, inner / 2) << "twelve engines: most subtrees are copies";
    EXPECT_EQ(with.meshCount(), file.meshCount() + inner - repeats) << "one HLOD per distinct subtree";
    EXPECT_EQ(hlods.size(), inner - repeats);
    EXPECT_LT(with.fileSize(), without.fileSize());
}

TEST(Hierarchy, LevelWithTrianglesFindsTheSmallestLevelThatHasThem) {
    const std::vector<uint32_t> map{2, 2, 2, 3, 5, 5, 8};  // q = 2, n = 6
    EXPECT_EQ(levelWithTriangles(map, 2, 1), 2u);
    EXPECT_EQ(levelWithTriangles(map, 2, 4), 4u);
    EXPECT_EQ(levelWithTriangles(map, 2, 5), 4u);
    EXPECT_EQ(levelWithTriangles(map, 2, 6), 6u);
    EXPECT_EQ(levelWithTriangles(map, 2, 100), 6u);
}

// Brute force over every combination of the children's levels: the least largest error whose
// levels fit the budget, which chooseChildLevels must find, within the budget.
TEST(Hierarchy, ChildLevelsTakeTheLeastErrorThatFitsTheBudget) {
    std::mt19937 rng(7);
    int feasible = 0, better_than_equal_shares = 0;
    for (int trial = 0; trial < 400; ++trial) {
        const size_t children = 1 + rng() % 4;
        std::vector<std::vector<float>> errors(children);
        std::vector<std::vector<uint32_t>> maps(children);
        std::vector<uint32_t> q(children);
        for (size_t c = 0; c < children; ++c) {
            const uint32_t n = 1 + rng() % 6;
            q[c] = rng() % (n + 1);
            errors[c].resize(n + 1);
            maps[c].resize(n + 1);
            float e = float(rng() % 5);  // error at full detail: the child's own
            uint32_t t = rng() % 3;
            for (uint32_t k = n + 1; k-- > 0;) {
                errors[c][k] = e;
                e += float(rng() % 4) * (c + 1);  // children differ in how fast they lose shape
            }
            for (uint32_t k = 0; k <= n; ++k) maps[c][k] = t += rng() % 4;
        }
        const uint64_t budget = rng() % 30;
        const std::vector<std::span<const float>> es(errors.begin(), errors.end());
        const std::vector<std::span<const uint32_t>> ms(maps.begin(), maps.end());
        const ChildLevelChoice choice = chooseChildLevels(es, ms, q, budget);
        ASSERT_EQ(choice.levels.size(), children);
        float least = INFINITY, equal_shares = 0.0f;
        uint64_t coarsest = 0;
        std::vector<uint32_t> k(q);
        for (size_t c = 0; c < children; ++c) {
            k[c] = std::min<uint32_t>(q[c], uint32_t(errors[c].size() - 1));
            coarsest += maps[c][k[c]];
            const uint32_t shared = levelWithTriangles(maps[c], k[c], budget / children);
            equal_shares = std::max(equal_shares, errors[c][std::min<uint32_t>(shared, uint32_t(errors[c].size() - 1))]);
        }
        while (true) {  // every combination, odometer style
            uint64_t t = 0;
            float e = 0.0f;
            for (size_t c = 0; c < children; ++c) t += maps[c][k[c]], e = std::max(e, errors[c][k[c]]);
            if (t <= budget) least = std::min(least, e);
            size_t c = 0;
            while (c < children && ++k[c] == errors[c].size()) k[c] = std::min<uint32_t>(q[c], uint32_t(errors[c].size() - 1)), ++c;
            if (c == children) break;
        }
        uint64_t triangles = 0;
        float error = 0.0f;
        for (size_t c = 0; c < children; ++c) {
            const uint32_t level = choice.levels[c];
            ASSERT_GE(level, std::min<uint32_t>(q[c], uint32_t(errors[c].size() - 1))) << "trial " << trial;
            ASSERT_LT(level, errors[c].size()) << "trial " << trial;
            triangles += maps[c][level];
            error = std::max(error, errors[c][level]);
        }
        EXPECT_EQ(choice.triangles, triangles) << "trial " << trial;
        EXPECT_EQ(choice.error, error) << "trial " << trial;
        if (least < INFINITY) {
            ++feasible;
            EXPECT_LE(triangles, budget) << "trial " << trial;
            EXPECT_EQ(error, least) << "trial " << trial;
            better_than_equal_shares += least < equal_shares;
        } else {
            EXPECT_EQ(triangles, coarsest) << "trial " << trial << ": nothing fits, every child at its coarsest";
        }
    }
    EXPECT_GT(feasible, 100);
    EXPECT_GT(better_than_equal_shares, 10) << "equal shares leave the error to the hardest child";
}

}  // namespace
}  // namespace occ

namespace occ {
namespace {

// The reference cut: every item against the frustum in one pass (the flat pipeline's), then a
// host recursion from the root that stops at leaves or, with the budget rule, where a node's own
// error projects to at most tau pixels.
std::vector<uint32_t> hostCut(const Pipeline& p, const CameraPose& pose, bool to_leaves, uint64_t& reached) {
    const DeviceScene& scene = p.scene();
    const k::Camera camera = toKernelCamera(pose, p.options().width, p.options().height);
    k::DeviceArray<uint8_t> flags;
    flags.resize(scene.item_count);
    k::frustumCull(scene.objects.ptr(), scene.item_count, k::frustumFromViewProj(camera.view_proj), flags.ptr());
    std::vector<uint8_t> in(scene.item_count);
    k::copyToHost(in.data(), flags.ptr(), in.size());
    const float pixels_at_1 = float(p.options().height) / (2.0f * std::tan(0.5f * camera.fovy));
    std::vector<uint32_t> cut;
    reached = 0;
    std::vector<uint32_t> stack{0};
    while (!stack.empty()) {
        const uint32_t id = stack.back();
        stack.pop_back();
        if (!in[id]) continue;
        ++reached;
        const DeviceScene::NodeLinks& node = scene.host_nodes[id];
        const k::Aabb& box = scene.host_objects[id].aabb;
        const float distance =
            std::max(glm::length(glm::clamp(camera.eye, box.min, box.max) - camera.eye), camera.near_plane);
        if (node.child_count == 0 || (!to_leaves && node.error * pixels_at_1 / distance <= p.options().tau)) {
            cut.push_back(id);
            continue;
        }
        for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c) stack.push_back(c);
    }
    std::sort(cut.begin(), cut.end());
    return cut;
}

// Whether no node of the ascending list lies under another of it, every one in the frustum.
bool isCutOfFrustumNodes(const Pipeline& p, const std::vector<uint32_t>& cut) {
    const DeviceScene& scene = p.scene();
    std::vector<uint32_t> parent(scene.item_count, UINT32_MAX);
    for (uint32_t i = 0; i < scene.item_count; ++i)
        for (uint32_t c = scene.host_nodes[i].first_child; c < scene.host_nodes[i].first_child + scene.host_nodes[i].child_count; ++c)
            parent[c] = i;
    std::vector<uint8_t> on(scene.item_count, 0);
    for (const uint32_t id : cut) on[id] = 1;
    for (const uint32_t id : cut)
        for (uint32_t a = parent[id]; a != UINT32_MAX; a = parent[a])
            if (on[a]) return false;
    return std::is_sorted(cut.begin(), cut.end()) && std::adjacent_find(cut.begin(), cut.end()) == cut.end();
}

// Issue 34: the cut is refined on the device, level by level, testing only the nodes it
// reaches: no frame tests every item against the frustum. Its cut equals a host refinement's
// over a whole-scene frustum pass, and a view of one corner reaches a small share of the nodes.
// Occluder candidates with the hierarchy: the listed nodes and the leaves among their
// children, ascending, each once (the list may hold a leaf and its parent: two frames' cuts).
TEST(Hierarchy, OccluderCandidatesTakeTheLeafChildrenOfHlods) {
    const HierarchyFixture& f = fixture();
    const std::string path = (test::scratchDir() / "hierarchy_leaf_children.oss").string();
    writeWithHierarchy(*f.file, path, 4, HlodOptions{});
    const OssFile file = OssFile::open(path);
    const DeviceScene scene = DeviceScene::upload(file, true);
    PipelineOptions o;
    o.hierarchy = true;
    CutStage stage(scene, o, nullptr, nullptr);
    std::mt19937 rng(3);
    uint32_t added = 0;
    for (int trial = 0; trial < 20; ++trial) {
        std::vector<uint32_t> ids;
        for (uint32_t n = 0; n < scene.item_count; ++n)
            if (rng() % 4 == 0) ids.push_back(n);
        std::set<uint32_t> expected(ids.begin(), ids.end());
        for (const uint32_t n : ids) {
            const DeviceScene::NodeLinks& node = scene.host_nodes[n];
            for (uint32_t c = node.first_child; c < node.first_child + node.child_count; ++c)
                if (scene.host_nodes[c].child_count == 0) expected.insert(c);
        }
        k::DeviceArray<uint32_t> device_ids(std::max<size_t>(1, ids.size())), out;
        k::copyToDevice(device_ids.ptr(), ids.data(), ids.size());
        const uint32_t count = stage.withLeafChildren(device_ids.ptr(), uint32_t(ids.size()), out);
        std::vector<uint32_t> got(count);
        k::copyToHost(got.data(), out.ptr(), count);
        EXPECT_EQ(got, std::vector<uint32_t>(expected.begin(), expected.end())) << "trial " << trial;
        added += uint32_t(expected.size() - ids.size());
    }
    EXPECT_GT(added, 0u);
}

TEST(Hierarchy, TheDeviceCutEqualsAHostRefinementAndReachesOnlyWhatItRefines) {
    const HierarchyFixture& f = fixture();
    HlodOptions hlod;
    hlod.node_triangles = 300;
    const std::string path = (test::scratchDir() / "hierarchy_cut.oss").string();
    writeWithHierarchy(*f.file, path, 4, hlod);
    const OssFile file = OssFile::open(path);
    k::Aabb bounds{glm::vec3(INFINITY), glm::vec3(-INFINITY)};
    for (const k::Aabb& b : f.boxes) bounds.min = glm::min(bounds.min, b.min), bounds.max = glm::max(bounds.max, b.max);
    const glm::vec3 centre = 0.5f * (bounds.min + bounds.max), size = bounds.max - bounds.min;
    CameraPose overview, corner;
    overview.eye = centre + glm::vec3(1.2f * size.x, 1.5f * size.y + 0.5f * size.x, 0.9f * size.z);
    overview.target = centre;
    overview.far_plane = 10.0f * glm::length(size);
    // Straight down onto a corner of the plant, a few units across.
    corner.eye = bounds.min + glm::vec3(2.0f, size.y + 4.0f, 2.0f);
    corner.target = bounds.min + glm::vec3(2.0f, 0.0f, 2.0f);
    corner.up = glm::vec3(0.0f, 0.0f, 1.0f);
    corner.fovy_degrees = 30.0f;
    corner.far_plane = overview.far_plane;
    for (const CullMode mode : {CullMode::Full, CullMode::Lod}) {
        for (const float tau : {0.5f, 4.0f}) {
            PipelineOptions o;
            o.width = 256, o.height = 192;
            o.mode = mode;
            o.hierarchy = true;
            o.tau = tau;
            o.finer_cut_items = 0;  // the cut at tau itself; the finer one below
            Pipeline p(file, o);
            for (const bool at_corner : {false, true}) {
                const CameraPose& pose = at_corner ? corner : overview;
                FrameStats stats;
                p.frustumPass(pose, stats);
                uint64_t reached = 0;
                const std::vector<uint32_t> expected = hostCut(p, pose, mode == CullMode::Full, reached);
                const std::vector<uint32_t> cut = p.downloadFrustumObjects();
                EXPECT_EQ(cut, expected) << "mode " << int(mode) << ", tau " << tau;
                EXPECT_EQ(p.nodesTested(), reached);
                EXPECT_FALSE(cut.empty());
                if (at_corner) {
                    EXPECT_LT(p.nodesTested(), p.itemCount() / 4) << "a corner reaches a small share";
                }
            }
        }
    }
    // Issue 49, item 4: the budget rule refines a cut of few items again at half the tau, down to
    // tau / 8: the cut at tau 4 of this small plant is the one at tau 0.5; bounded to fewer items
    // than that finer cut draws, it stays the cut at tau 4.
    {
        PipelineOptions o;
        o.width = 256, o.height = 192;
        o.mode = CullMode::Lod;
        o.hierarchy = true;
        o.tau = 4.0f;
        Pipeline finer(file, o);
        o.tau = 0.5f;
        o.finer_cut_items = 0;
        Pipeline fine(file, o);
        o.tau = 4.0f;
        Pipeline coarse(file, o);
        FrameStats stats;
        finer.frustumPass(overview, stats);
        fine.frustumPass(overview, stats);
        coarse.frustumPass(overview, stats);
        EXPECT_EQ(finer.cutTau(), 0.5f);
        EXPECT_EQ(finer.downloadFrustumObjects(), fine.downloadFrustumObjects());
        const size_t coarse_items = coarse.downloadFrustumObjects().size(), fine_items = fine.downloadFrustumObjects().size();
        ASSERT_LT(coarse_items, fine_items) << "the fixture's cut was expected to grow at a finer tau";
        o.finer_cut_items = uint32_t(coarse_items);  // room for the cut at 4, not for the one at 2
        Pipeline bounded(file, o);
        bounded.frustumPass(overview, stats);
        EXPECT_EQ(bounded.downloadFrustumObjects(), coarse.downloadFrustumObjects());
        EXPECT_EQ(bounded.cutTau(), 4.0f);
    }
    // The error rule with occlusion: frames through the pipeline give cuts of nodes in the
    // frustum, none under another; the fine cut's leaves supply the next frames' occluders.
    PipelineOptions o;
    o.width = 256, o.height = 192;
    o.hierarchy = true;
    o.lod = LodRule::Error;
    o.tau = 2.0f;
    Pipeline p(file, o);
    for (uint64_t frame = 0; frame < 4; ++frame) {
        CameraPose pose = overview;
        pose.eye += glm::vec3(0.1f * float(frame) * size.x, 0.0f, 0.0f);
        const FrameStats stats = p.runFrame(pose, frame);
        EXPECT_TRUE(isCutOfFrustumNodes(p, p.visibleObjects())) << "frame " << frame;
        EXPECT_GT(p.visibleObjects().size(), 0u);
        EXPECT_LT(p.visibleObjects().size(), p.itemCount());
        if (frame > 0) {
            EXPECT_GT(stats.occluder_triangles, 0u) << "frame " << frame;
        }
    }
}

}  // namespace
}  // namespace occ
