// SPDX-License-Identifier: MIT
#include "../kernels/device_test_support.h"
#include "depth_raster.h"
#include "frustum_cull.h"
#include "hzm_build.h"
#include "masked_raster.h"
#include "import/plant.h"
#include "pipeline/pipeline.h"
#include "prep/prepare.h"
#include "prep/hierarchy.h"
#include "scene/errors.h"
#include "test_support.h"
#include "view/camera_path.h"

#include <glm/gtc/matrix_transform.hpp>
#include <gtest/gtest.h>

#include <algorithm>
#include <iterator>
#include <cmath>
#include <map>
#include <memory>

namespace occ {
namespace {

// A small procedural plant, preprocessed once for all pipeline tests, and the cameras of a walk
// through it (occlusion matters) followed by an orbit (everything at a distance).
struct PipelineFixture {
    std::string path;
    std::unique_ptr<OssFile> file;
    std::vector<CameraPose> cameras;

    PipelineFixture() {
        path = (test::scratchDir() / "pipeline_plant.oss").string();
        writeOss(path, prepareScene(generatePlant({600, 5}), PrepOptions{}));
        file = std::make_unique<OssFile>(OssFile::open(path));
        const PathScene scene = pathSceneOf(*file);
        cameras = walkPath(scene, 24, 3, Avoid::triangles).cameras;
        const std::vector<CameraPose> orbit = orbitPath(scene, 8);
        cameras.insert(cameras.end(), orbit.begin(), orbit.end());
    }
};

const PipelineFixture& fixture() {
    static const PipelineFixture f;
    return f;
}

// Every test runs frames on the build's device: skipped where it cannot run kernels (the CUDA
// test binary on a machine without a GPU).
using PipelineFrames = k::test::DeviceTest;

PipelineOptions smallOptions(StreamMode stream) {
    PipelineOptions o;
    o.width = 160;
    o.height = 120;
    o.stream = stream;
    o.pvs_occluder_triangles = 20000;
    o.budget_share = 0.1;  // smaller than the scene, so that LOD selection has work to do
    return o;
}

// The active arrays and the index buffer, read back from the device.
std::vector<glm::vec3> activeVertices(const Pipeline& p) {
    std::vector<glm::vec3> v(p.vertexExtent());
    k::copyToHost(v.data(), p.activeVertices(), v.size());
    return v;
}
std::vector<uint32_t> indices(const Pipeline& p) {
    std::vector<uint32_t> i(3 * p.triangleExtent());
    k::copyToHost(i.data(), p.indices(), i.size());
    return i;
}

// Invariant: every drawn block of the index buffer is the object's LOD prefix computed straight
// from the .oss (first tc triangles, corners walked through ecol below vc, local to the block),
// and the active vertices are the mesh's first vc positions.
TEST_F(PipelineFrames, ReformedTrianglesEqualTheLodPrefixOfTheOss) {
    const PipelineFixture& f = fixture();
    Pipeline pipeline(*f.file, smallOptions(StreamMode::Coherent));
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats s = pipeline.runFrame(f.cameras[frame], frame);
        const std::vector<k::LayoutBlock> layout = pipeline.downloadLayout();
        const std::vector<glm::vec3> active = activeVertices(pipeline);
        const std::vector<uint32_t> index = indices(pipeline);
        uint64_t checked = 0;
        for (size_t j = 0; j < layout.size(); ++j) {
            const k::LayoutBlock& b = layout[j];
            if (j > 0) {
                ASSERT_LT(layout[j - 1].object, b.object);
            }
            const uint32_t vc = b.draw_vertex_count, tc = b.draw_triangle_count;
            const OssFile::MeshView mesh = f.file->mesh(f.file->objects()[b.object].mesh);
            ASSERT_EQ(tc, vc ? mesh.map[vc] : 0u);
            ASSERT_LE(vc, b.vertex_count);  // what is drawn is a prefix of what is resident
            ASSERT_EQ(b.triangle_count, mesh.map[b.vertex_count]);
            ASSERT_LE(b.vertex_offset + b.vertex_count, pipeline.vertexExtent());
            ASSERT_LE(b.triangle_offset + b.triangle_count, pipeline.triangleExtent());
            for (uint32_t v = 0; v < b.vertex_count; ++v)
                ASSERT_EQ(active[b.vertex_offset + v], mesh.positions[v]);
            for (uint32_t c = 0; c < 3 * tc; ++c) {
                uint32_t v = mesh.triangles[c];
                while (v >= vc) v = uint32_t(mesh.ecol[v]);
                ASSERT_EQ(index[3 * b.triangle_offset + c], v) << "frame " << frame << " object " << b.object;
            }
            checked += tc;
        }
        ASSERT_EQ(checked, s.active_triangles);
    }
}

// What a frame draws, per object, in a form that does not depend on where blocks sit: the
// drawn vertices and the reformed (block-local) triangles.
std::map<uint32_t, std::pair<std::vector<glm::vec3>, std::vector<uint32_t>>> drawnGeometry(const Pipeline& p) {
    std::map<uint32_t, std::pair<std::vector<glm::vec3>, std::vector<uint32_t>>> out;
    const std::vector<glm::vec3> active = activeVertices(p);
    const std::vector<uint32_t> index = indices(p);
    for (const k::LayoutBlock& b : p.downloadLayout()) {
        const uint32_t vc = b.draw_vertex_count, tc = b.draw_triangle_count;
        if (vc == 0) continue;
        auto& [vertices, triangles] = out[b.object];
        vertices.assign(active.begin() + b.vertex_offset, active.begin() + b.vertex_offset + vc);
        for (uint64_t c = 0; c < 3ull * tc; ++c) triangles.push_back(index[3 * b.triangle_offset + c]);
    }
    return out;
}

// Invariant: with coherent streaming (and residency) what each frame draws is what a
// from-scratch build (no coherence) and object-by-object copies draw for the same frame.
TEST_F(PipelineFrames, CoherentStreamingMatchesAFreshBuildEveryFrame) {
    const PipelineFixture& f = fixture();
    Pipeline coherent(*f.file, smallOptions(StreamMode::Coherent));
    Pipeline scratch(*f.file, smallOptions(StreamMode::NonCoherent));
    Pipeline by_object(*f.file, smallOptions(StreamMode::None));
    uint64_t streamed_coherent = 0, streamed_scratch = 0;
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats a = coherent.runFrame(f.cameras[frame], frame);
        const FrameStats b = scratch.runFrame(f.cameras[frame], frame);
        by_object.runFrame(f.cameras[frame], frame);
        streamed_coherent += a.streamed_bytes;
        streamed_scratch += b.streamed_bytes;
        ASSERT_EQ(a.active_triangles, b.active_triangles);
        const auto drawn = drawnGeometry(coherent);
        ASSERT_EQ(drawn, drawnGeometry(scratch)) << "frame " << frame;
        ASSERT_EQ(drawn, drawnGeometry(by_object)) << "frame " << frame;
    }
    EXPECT_LT(streamed_coherent * 5, streamed_scratch);  // coherence is the point
}

// Invariant: the PVS never lacks an object that is in the frustum and not behind the occluders'
// depth. Reference: a plain scalar test of each culled object's projected AABB against every
// pixel of the full-resolution depth buffer it touches (the HZM may only be less aggressive).
TEST_F(PipelineFrames, OcclusionCullsOnlyWhatTheFullResolutionDepthHides) {
    const PipelineFixture& f = fixture();
    const PipelineOptions options = smallOptions(StreamMode::Coherent);
    Pipeline pipeline(*f.file, options);
    uint64_t culled = 0;
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats s = pipeline.runFrame(f.cameras[frame], frame);
        const k::Camera camera = toKernelCamera(f.cameras[frame], options.width, options.height);
        const k::Frustum frustum = k::frustumFromViewProj(camera.view_proj);
        std::vector<uint8_t> visible(f.file->objectCount(), 0);
        for (uint32_t id : pipeline.visibleObjects()) visible[id] = 1;
        std::vector<float> depth(size_t(options.width) * options.height);
        k::copyToHost(depth.data(), pipeline.occluderDepth(), depth.size());
        // The frustum test on its own arrays, not the pipeline's.
        const uint32_t n = f.file->objectCount();
        k::DeviceArray<uint8_t> flags(n);
        k::frustumCull(pipeline.scene().objects.ptr(), n, frustum, flags.ptr());
        std::vector<uint8_t> in_frustum(n);
        k::copyToHost(in_frustum.data(), flags.ptr(), n);
        for (uint32_t id = 0; id < n; ++id) {
            if (visible[id] || !in_frustum[id]) continue;
            const k::ObjectInfo& o = pipeline.scene().host_objects[id];
            ++culled;
            float xmin = INFINITY, ymin = INFINITY, xmax = -INFINITY, ymax = -INFINITY, zmin = INFINITY;
            for (int c = 0; c < 8; ++c) {
                const glm::vec3 p((c & 1) ? o.aabb.max.x : o.aabb.min.x, (c & 2) ? o.aabb.max.y : o.aabb.min.y,
                                  (c & 4) ? o.aabb.max.z : o.aabb.min.z);
                const glm::vec4 clip = camera.view_proj * glm::vec4(p, 1.0f);
                ASSERT_GT(clip.w, camera.near_plane) << "culled object " << id << " crosses the near plane";
                const glm::vec3 ndc = glm::vec3(clip) / clip.w;
                xmin = std::min(xmin, (ndc.x * 0.5f + 0.5f) * options.width);
                xmax = std::max(xmax, (ndc.x * 0.5f + 0.5f) * options.width);
                ymin = std::min(ymin, (ndc.y * 0.5f + 0.5f) * options.height);
                ymax = std::max(ymax, (ndc.y * 0.5f + 0.5f) * options.height);
                zmin = std::min(zmin, ndc.z * 0.5f + 0.5f);
            }
            const int x0 = std::max(0, int(std::floor(xmin))), x1 = std::min(int(options.width) - 1, int(std::floor(xmax)));
            const int y0 = std::max(0, int(std::floor(ymin))), y1 = std::min(int(options.height) - 1, int(std::floor(ymax)));
            for (int y = y0; y <= y1; ++y)
                for (int x = x0; x <= x1; ++x)
                    ASSERT_GT(zmin, depth[size_t(y) * options.width + size_t(x)])
                        << "frame " << frame << ": object " << id << " culled but visible at pixel " << x << "," << y;
        }
        EXPECT_EQ(s.objects_occluded + s.objects_visible, s.objects_in_frustum);
    }
    EXPECT_GT(culled, 0u) << "the walk should see some occlusion";
}

// The masked raster against the exact one on the occluder sets the pipeline records over the walk
// and the orbit (each frame's gathered occluders, in the masked raster's front-to-back order):
// never nearer at any level of the HZM, so it never culls what the exact raster would not.
TEST_F(PipelineFrames, TheMaskedRasterIsNeverNearerThanTheExactOneOnRecordedOccluders) {
    const PipelineFixture& f = fixture();
    PipelineOptions options = smallOptions(StreamMode::Coherent);
    options.raster = OccluderRaster::Masked;
    options.late_pass = false;  // level 0 is then the raster of occluderGeometry() alone
    Pipeline pipeline(*f.file, options);
    k::DepthRasterScratch scratch;
    const uint64_t texels = k::hzmTotalTexels(options.width, options.height);
    k::DeviceArray<float> masked(texels), exact(texels);
    uint64_t occluder_triangles = 0, nearer_by_exact = 0;
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        pipeline.runFrame(f.cameras[frame], frame);
        const k::OccluderGeometry& g = pipeline.occluderGeometry();
        const k::Camera camera = toKernelCamera(f.cameras[frame], options.width, options.height);
        occluder_triangles += g.triangle_total;
        k::maskedDepthRaster(g.positions.ptr(), g.triangles.ptr(), uint32_t(g.triangle_total), g.edge_flags.ptr(),
                             g.edge_neighbours.ptr(), camera, masked.ptr(), scratch, true);
        k::depthRaster(g.positions.ptr(), g.triangles.ptr(), uint32_t(g.triangle_total), g.edge_flags.ptr(),
                       g.edge_neighbours.ptr(), camera, exact.ptr(), scratch, true);
        k::hzmBuild(masked.ptr(), options.width, options.height);
        k::hzmBuild(exact.ptr(), options.width, options.height);
        std::vector<float> a(texels), b(texels);
        k::copyToHost(a.data(), masked.ptr(), texels);
        k::copyToHost(b.data(), exact.ptr(), texels);
        std::vector<float> level0(options.width * options.height);
        k::copyToHost(level0.data(), pipeline.occluderDepth(), level0.size());
        ASSERT_TRUE(std::equal(level0.begin(), level0.end(), a.begin())) << "frame " << frame << ": the pipeline's own raster";
        for (uint64_t i = 0; i < texels; ++i) {
            ASSERT_GE(a[i], b[i]) << "frame " << frame << ": HZM texel " << i << " of the masked raster is nearer";
            nearer_by_exact += b[i] < a[i];
        }
    }
    EXPECT_GT(occluder_triangles, 10000u);
    EXPECT_GT(nearer_by_exact, 0u) << "the masked raster's subtiles are coarser than pixels somewhere";
}

// Invariant: the frame's vertices stay within the budget N except where the floors q force more.
TEST_F(PipelineFrames, VertexBudgetIsRespectedUpToTheFloors) {
    const PipelineFixture& f = fixture();
    PipelineOptions options = smallOptions(StreamMode::Coherent);
    options.budget = 20000;
    Pipeline pipeline(*f.file, options);
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats s = pipeline.runFrame(f.cameras[frame], frame);
        uint64_t floors = 0;
        for (const k::LayoutBlock& b : pipeline.downloadLayout())
            if (b.draw_vertex_count > 0) {
                floors += pipeline.scene().host_objects[b.object].q;
                ASSERT_GE(b.draw_vertex_count, pipeline.scene().host_objects[b.object].q);
            }
        EXPECT_LE(s.active_vertices, std::max<uint64_t>(uint64_t(options.budget), floors)) << "frame " << frame;
    }
}

// --lod error: each visible object at the coarsest level whose recorded error projects within
// tau pixels. A larger tau never draws an object finer; a huge tau draws every drawn object at
// its floor q; the vertex budget plays no part.
TEST_F(PipelineFrames, ErrorBoundedLodsFollowTauNotTheBudget) {
    const PipelineFixture& f = fixture();
    const auto levels = [&](float tau, double share) {
        PipelineOptions options = smallOptions(StreamMode::Coherent);
        options.lod = LodRule::Error;
        options.tau = tau;
        options.budget_share = share;
        Pipeline pipeline(*f.file, options);
        std::vector<std::map<uint32_t, uint32_t>> frames;
        for (size_t frame = 0; frame < 8; ++frame) {
            pipeline.runFrame(f.cameras[frame * 3], frame);
            std::map<uint32_t, uint32_t> lod;
            const auto ids = pipeline.visibleObjects();
            const auto vc = pipeline.visibleLodVertices();
            for (size_t j = 0; j < ids.size(); ++j) lod[ids[j]] = vc[j];
            frames.push_back(std::move(lod));
        }
        return frames;
    };
    const auto fine = levels(0.25f, 0.1), coarse = levels(4.0f, 0.1), same_tau = levels(0.25f, 0.5),
               floor = levels(1e9f, 0.1);
    uint64_t fine_sum = 0, coarse_sum = 0;
    for (size_t frame = 0; frame < fine.size(); ++frame) {
        EXPECT_EQ(fine[frame], same_tau[frame]) << "the budget changed an error-bounded frame";
        ASSERT_EQ(fine[frame].size(), coarse[frame].size());  // LODs do not change what is visible
        for (const auto& [id, vc] : fine[frame]) {
            EXPECT_LE(coarse[frame].at(id), vc) << "object " << id << ", frame " << frame;
            const k::ObjectInfo& o = [&]() -> const k::ObjectInfo& {
                static std::unique_ptr<Pipeline> p;
                if (!p) p = std::make_unique<Pipeline>(*f.file, smallOptions(StreamMode::Coherent));
                return p->scene().host_objects[id];
            }();
            // Objects under the pixel error threshold are not drawn at any tau.
            EXPECT_EQ(floor[frame].at(id), vc == 0 ? 0u : std::min(o.q, o.vertex_count));
            fine_sum += vc, coarse_sum += coarse[frame].at(id);
        }
    }
    EXPECT_LT(coarse_sum, fine_sum);  // tau matters on this walk
}

// Beyond the paper: a frame whose view (so complexities and drawn set) did not change streams,
// moves and reforms nothing, and still draws the right thing.
TEST_F(PipelineFrames, AnUnchangedFrameStreamsMovesAndReformsNothing) {
    const PipelineFixture& f = fixture();
    // Occluders from Eq. 3 only, so that what a frame culls depends on its camera alone.
    PipelineOptions options = smallOptions(StreamMode::Coherent);
    options.pvs_occluder_triangles = 0;
    // And Eq. 1's counts alone: with the hysteresis they would depend on the frames before.
    options.lod_hysteresis = 0;
    Pipeline pipeline(*f.file, options);
    for (size_t frame = 0; frame < 6; ++frame) pipeline.runFrame(f.cameras[frame], frame);
    const CameraPose still = f.cameras[5];
    const FrameStats repeat = pipeline.runFrame(still, 6);
    EXPECT_EQ(repeat.streamed_bytes, 0u);
    EXPECT_EQ(repeat.moved_bytes, 0u);
    EXPECT_EQ(repeat.reformed_triangles, 0u);
    options.stream = StreamMode::NonCoherent;
    Pipeline fresh(*f.file, options);
    fresh.runFrame(still, 0);
    EXPECT_EQ(drawnGeometry(pipeline), drawnGeometry(fresh));
}

// Issue 35: once a frame's sizes have been seen, a frame allocates and frees no device memory (a
// cudaMalloc or cudaFree waits for the whole device): arrays keep their capacity and grow by half
// again when short, and the device algorithms' temporaries come back from the cache. So frames
// with one camera stop allocating within a few frames, and so does a path flown again (its
// later passes see sizes its first pass has seen; the layout's free list and the hysteresis
// settle over a pass or two). Counted by deviceAlloc and deviceFree, in both builds.
TEST_F(PipelineFrames, AFrameMakesNoDeviceAllocationOnceItsSizesHaveBeenSeen) {
    const PipelineFixture& f = fixture();
    for (const CullMode mode : {CullMode::OcLod, CullMode::Lod}) {
        PipelineOptions options = smallOptions(StreamMode::Coherent);
        options.mode = mode;
        Pipeline pipeline(*f.file, options);
        uint64_t frame = 0;
        k::DeviceAllocationCounters before, after;
        for (int i = 0; i < 5; ++i) {
            before = k::deviceAllocationCounters();
            pipeline.runFrame(f.cameras[5], frame++);
            after = k::deviceAllocationCounters();
        }
        EXPECT_EQ(after.allocations, before.allocations) << "the fifth frame from one camera";
        EXPECT_EQ(after.frees, before.frees) << "the fifth frame from one camera";
        const uint64_t temporaries = after.temporary_requests;
        for (int pass = 0; pass < 4; ++pass) {
            before = k::deviceAllocationCounters();
            for (const CameraPose& camera : f.cameras) pipeline.runFrame(camera, frame++);
            after = k::deviceAllocationCounters();
        }
        EXPECT_EQ(after.allocations, before.allocations) << "the path's fourth pass";
        EXPECT_EQ(after.frees, before.frees) << "the path's fourth pass";
        EXPECT_GT(after.temporary_requests, temporaries) << "the frames' sorts and compactions bypass the cache";
    }
}

TEST_F(PipelineFrames, FullModeDrawsEveryFrustumObjectAtFullDetail) {
    const PipelineFixture& f = fixture();
    PipelineOptions options = smallOptions(StreamMode::Coherent);
    options.mode = CullMode::Full;
    Pipeline pipeline(*f.file, options);
    const FrameStats s = pipeline.runFrame(f.cameras.back(), 0);
    EXPECT_EQ(s.objects_occluded, 0u);
    const std::vector<k::LayoutBlock> layout = pipeline.downloadLayout();
    EXPECT_EQ(layout.size(), s.objects_visible);
    for (const k::LayoutBlock& b : layout)
        EXPECT_EQ(b.draw_vertex_count, pipeline.scene().host_objects[b.object].vertex_count);
}

// The stable layout (issue 12): a block that keeps its place keeps its bytes, most blocks keep
// their place from frame to frame, and compaction is the exception.
TEST_F(PipelineFrames, BlocksKeepTheirPlaceAndTheirBytes) {
    const PipelineFixture& f = fixture();
    Pipeline pipeline(*f.file, smallOptions(StreamMode::Coherent));
    std::map<uint32_t, std::pair<uint64_t, std::vector<glm::vec3>>> before;  // id -> (offset, vertices)
    uint64_t shared = 0, stayed = 0, compactions = 0;
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats s = pipeline.runFrame(f.cameras[frame], frame);
        const std::vector<k::LayoutBlock> layout = pipeline.downloadLayout();
        const std::vector<glm::vec3> active = activeVertices(pipeline);
        std::map<uint32_t, std::pair<uint64_t, std::vector<glm::vec3>>> now;
        uint64_t moved_here = 0;
        for (const k::LayoutBlock& b : layout) {
            auto& [offset, vertices] = now[b.object];
            offset = b.vertex_offset;
            vertices.assign(active.begin() + offset, active.begin() + offset + b.vertex_count);
            const auto was = before.find(b.object);
            if (was == before.end()) continue;
            ++shared;
            if (was->second.first != offset) {
                ++moved_here;
                continue;
            }
            ++stayed;
            const size_t common = std::min(was->second.second.size(), vertices.size());
            for (size_t v = 0; v < common; ++v)
                ASSERT_EQ(vertices[v], was->second.second[v]) << "frame " << frame << " object " << b.object;
        }
        compactions += frame > 0 && moved_here > 0 && s.moved_bytes > 0 && moved_here * 2 > layout.size();
        before = std::move(now);
    }
    EXPECT_GT(stayed, shared * 9 / 10) << stayed << " of " << shared << " blocks kept their place";
    EXPECT_LT(compactions, f.cameras.size() / 4);
}

// Issue 12's target without a display: after the first frame, what crosses between host and
// device is the streamed geometry plus at most 64 bytes per visible object plus 64 KiB, and at
// least the streamed geometry (the transfer cannot be skipped).
TEST_F(PipelineFrames, TheBusCarriesTheStreamedGeometryAndLittleMore) {
    const PipelineFixture& f = fixture();
    Pipeline pipeline(*f.file, smallOptions(StreamMode::Coherent));
    for (size_t frame = 0; frame < f.cameras.size(); ++frame) {
        const FrameStats s = pipeline.runFrame(f.cameras[frame], frame);
        EXPECT_GE(s.bus_h2d_bytes, s.streamed_bytes) << "frame " << frame;
        if (frame == 0) continue;
        EXPECT_LE(s.bus_h2d_bytes + s.bus_d2h_bytes, s.streamed_bytes + 64 * s.objects_visible + 65536)
            << "frame " << frame << ": " << s.bus_h2d_bytes << " + " << s.bus_d2h_bytes << " bytes for "
            << s.streamed_bytes << " streamed and " << s.objects_visible << " visible objects";
    }
}

// A frame without a usable earlier PVS (the first, or one after the camera jumped) takes its
// occluder candidates from a first pass of its own: it culls as much as a frame with history
// from the same camera, and more than the AOS alone does.
TEST_F(PipelineFrames, TheFirstFrameAndAJumpCullAsASteadyFrameDoes) {
    const PipelineFixture& f = fixture();
    const CameraPose& inside = f.cameras[5];
    const CameraPose& elsewhere = f.cameras[f.cameras.size() - 1];  // on the orbit, outside
    PipelineOptions aos_only = smallOptions(StreamMode::Coherent);
    aos_only.pvs_occluder_triangles = 0;
    Pipeline plain(*f.file, aos_only);
    const uint64_t aos_visible = plain.runFrame(inside, 0).objects_visible;

    // Culling alone: objects seen before the jump are not kept in the visible set after it.
    PipelineOptions options = smallOptions(StreamMode::Coherent);
    options.keep_visible = 0;
    Pipeline pipeline(*f.file, options);
    const uint64_t first = pipeline.runFrame(inside, 0).objects_visible;
    const uint64_t steady = pipeline.runFrame(inside, 1).objects_visible;
    EXPECT_LT(first, aos_visible);
    EXPECT_LE(double(first), 1.1 * double(steady));
    // Away and back: the frame after each jump is as good as the steady one.
    pipeline.runFrame(elsewhere, 2);
    pipeline.runFrame(elsewhere, 3);
    EXPECT_LE(double(pipeline.runFrame(inside, 4).objects_visible), 1.1 * double(steady));
}

// niagara's late pass: on a turn's first frame, objects the last frames' occluders cannot hide
// are rastered too and tested again. It only ever removes newly visible objects that its own
// raster hides (the full-resolution check of every frame is OcclusionCullsOnlyWhat...), and on
// this walk's turns it removes some.
TEST_F(PipelineFrames, ALatePassCullsOnlyNewlyVisibleObjectsOnATurn) {
    const PipelineFixture& f = fixture();
    PipelineOptions late = smallOptions(StreamMode::Coherent), early = late;
    late.keep_visible = early.keep_visible = 0;
    early.late_pass = false;
    size_t turns = 0, culled_more = 0;
    for (size_t start = 0; start + 4 < 24; start += 4) {
        const CameraPose& a = f.cameras[start];
        for (const float degrees : {40.0f, -40.0f, 70.0f}) {
            CameraPose b = a;
            const glm::vec3 view = glm::rotate(glm::mat4(1.0f), glm::radians(degrees), a.up) * glm::vec4(a.target - a.eye, 0.0f);
            b.target = a.eye + view;
            Pipeline with(*f.file, late), without(*f.file, early);
            for (uint64_t frame = 0; frame < 3; ++frame) {
                with.runFrame(a, frame);
                without.runFrame(a, frame);
                ASSERT_EQ(with.visibleObjects(), without.visibleObjects()) << "a steady frame " << frame;
            }
            const std::vector<uint32_t> before = with.visibleObjects();
            with.runFrame(b, 3);
            without.runFrame(b, 3);
            const std::vector<uint32_t>& v = with.visibleObjects();
            const std::vector<uint32_t>& w = without.visibleObjects();
            ASSERT_TRUE(std::includes(w.begin(), w.end(), v.begin(), v.end())) << start << " " << degrees;
            // What it removed was new: visible in neither of the two frames before.
            std::vector<uint32_t> removed;
            std::set_difference(w.begin(), w.end(), v.begin(), v.end(), std::back_inserter(removed));
            for (const uint32_t id : removed)
                ASSERT_FALSE(std::binary_search(before.begin(), before.end(), id)) << "object " << id;
            ++turns;
            culled_more += !removed.empty();
        }
    }
    EXPECT_GT(culled_more, 0u) << "of " << turns << " turns";
}

// With occluder_ms the occluder budget follows the raster's measured speed: a time no raster
// meets brings it down to the floor (so frames raster fewer PVS occluders than the fixed
// budget), a time every raster meets lets it grow past the fixed budget.
TEST_F(PipelineFrames, TheAdaptiveOccluderBudgetFollowsTheRasterTime) {
    const PipelineFixture& f = fixture();
    PipelineOptions fixed = smallOptions(StreamMode::Coherent);
    fixed.pvs_occluder_triangles = 40000;
    PipelineOptions tight = fixed, loose = fixed;
    tight.occluder_ms = 1e-6;
    loose.occluder_ms = 1e6;
    Pipeline a(*f.file, fixed), b(*f.file, tight), c(*f.file, loose);
    uint64_t sum_fixed = 0, sum_tight = 0, sum_loose = 0;
    for (size_t frame = 0; frame < 12; ++frame) {
        const uint64_t fa = a.runFrame(f.cameras[frame], frame).occluder_triangles;
        const uint64_t fb = b.runFrame(f.cameras[frame], frame).occluder_triangles;
        const uint64_t fc = c.runFrame(f.cameras[frame], frame).occluder_triangles;
        if (frame < 3) continue;  // the first frames still raster what the fixed budget gives
        sum_fixed += fa, sum_tight += fb, sum_loose += fc;
    }
    EXPECT_LT(sum_tight, sum_fixed);
    EXPECT_GE(sum_loose, sum_fixed);
    PipelineOptions bad = fixed;
    bad.occluder_ms = -1;
    EXPECT_THROW(Pipeline(*f.file, bad), UsageError);
}

TEST_F(PipelineFrames, ImpossibleOptionsAreRefused) {
    const PipelineFixture& f = fixture();
    PipelineOptions o = smallOptions(StreamMode::Coherent);
    o.width = 0;
    EXPECT_THROW(Pipeline(*f.file, o), UsageError);
    o = smallOptions(StreamMode::Coherent);
    o.alpha = 1.0f;
    EXPECT_THROW(Pipeline(*f.file, o), UsageError);
    EXPECT_THROW(parseCullMode("everything"), UsageError);
    EXPECT_THROW(parseStreamMode("fast"), UsageError);
}

// Issue 35: the device memory a pipeline's frames need, counted before the first frame, is a
// lower bound of what they use (a configuration that fits is never refused) that counts a third
// or more of it where the active arrays dominate: measured by deviceAlloc over the orbit (the whole plant in view, so a frame fills
// its budget) in every mode, flat and with the hierarchy, at two budgets and two viewports.
TEST_F(PipelineFrames, TheFramesMemoryNeedIsALowerBoundOfWhatTheyUse) {
    const PipelineFixture& f = fixture();
    const std::string path = (test::scratchDir() / "pipeline_plant_hierarchy.oss").string();
    writeWithHierarchy(*f.file, path, 8, HlodOptions{});
    const OssFile with_nodes = OssFile::open(path);
    const std::vector<CameraPose> orbit = orbitPath(pathSceneOf(*f.file), 8);
    for (const OssFile* file : {static_cast<const OssFile*>(f.file.get()), &with_nodes})
        for (const CullMode mode : {CullMode::OcLod, CullMode::Lod, CullMode::Full})
            for (const uint32_t width : {160u, 512u})
                for (const double share : {0.1, 1.0}) {
                    PipelineOptions o;
                    o.width = width;
                    o.height = width * 3 / 4;
                    o.mode = mode;
                    o.budget_share = share;
                    o.hierarchy = file->nodeCount() > 0;
                    const std::string config = std::string(o.hierarchy ? "hierarchy" : "flat") + ", mode " +
                                               std::to_string(int(mode)) + ", " + std::to_string(width) + " wide, " +
                                               std::to_string(share) + " of the vertices";
                    k::releaseTemporaries();
                    Pipeline pipeline(*file, o);
                    const FrameMemoryNeed need = frameMemoryNeed(*file, pipeline.options(), pipeline.budget());
                    const uint64_t made = k::deviceAllocationCounters().live_bytes;
                    k::resetDevicePeak();
                    uint64_t frame = 0, drawn_vertices = 0;
                    for (const CameraPose& camera : orbit)
                        drawn_vertices = std::max(drawn_vertices, pipeline.runFrame(camera, frame++).active_vertices);
                    // What deviceAlloc lent; the kernels' local memory CUDA reserves itself.
                    const uint64_t used = k::deviceAllocationCounters().peak_bytes - made + need.local_bytes;
                    // need counts a frame that fills its budget. With the hierarchy and a budget
                    // of every object's vertices the orbit's cut of HLODs draws far fewer: it
                    // cannot fill it (that is what the hierarchy is for).
                    if (o.hierarchy && share == 1.0 && mode != CullMode::Full) {
                        EXPECT_LT(drawn_vertices, need.vertices) << config;
                        continue;
                    }
                    EXPECT_LE(need.total(), used) << config;
                    // Where the active arrays dominate (the whole scene's vertices), most of it.
                    if (share == 1.0 || mode == CullMode::Full) {
                        EXPECT_GE(need.total() * 3, used) << config << ": counts less than a third of " << used;
                    }
                }
}

}  // namespace
}  // namespace occ
