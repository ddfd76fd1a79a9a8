// SPDX-License-Identifier: MIT
#include "prep/prepare.h"

#include "prep/collapse_recorder.h"
#include "prep/fast_collapser.h"
#include "prep/occluder.h"
#include "prep/rearrange.h"
#include "prep/weld.h"
#include "scene/errors.h"

#include <algorithm>
#include <numeric>
#include <thread>

namespace occ {

ProgressiveMesh buildProgressiveMesh(const Mesh& mesh, Collapser collapser) {
    const WeldedMesh welded = weldPositions(mesh.positions, mesh.indices);
    const CollapseSequence sequence = collapser == Collapser::Fast
                                          ? fastCollapseSequence(welded.positions, welded.triangles)
                                          : openMeshCollapseSequence(welded.positions, welded.triangles);
    const CollapseArrays arrays = recordCollapseArrays(uint32_t(welded.positions.size()),
                                                       uint32_t(welded.triangles.size() / 3), sequence);
    ProgressiveMesh pm = rearrange(welded.positions, welded.triangles, sequence, arrays);
    pm.source_vertices = uint32_t(mesh.positions.size());
    pm.dropped_triangles = welded.dropped_triangles;
    return pm;
}

namespace {

// Runs body(i) for i in [0, count) on `threads` workers, in the given order of indices.
template <class F>
void parallelFor(const std::vector<uint32_t>& order, unsigned threads, F&& body) {
    std::atomic<size_t> next{0};
    const auto worker = [&] {
        for (size_t i; (i = next.fetch_add(1)) < order.size();) body(order[i]);
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
}

}  // namespace

PreparedScene prepareScene(const Scene& scene, const PrepOptions& options, PrepProgress* progress) {
    if (!(options.ct >= 0.0f && options.ct <= 1.0f))
        throw OptionError("ct", OptionError::value(options.ct) + ": must be in [0, 1]");
    const unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());

    // Only meshes some object uses are prepared.
    std::vector<uint8_t> used(scene.meshes.size(), 0);
    for (const Object& o : scene.objects) used[o.mesh] = 1;
    std::vector<uint32_t> order;
    for (uint32_t m = 0; m < scene.meshes.size(); ++m)
        if (used[m]) order.push_back(m);
    // Largest first, so that one big mesh does not start last and keep one core busy alone.
    std::stable_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
        return scene.meshes[a].indices.size() > scene.meshes[b].indices.size();
    });
    if (progress) {
        progress->meshes_total = order.size();
        progress->triangles_total = 0;
        for (uint32_t m : order) progress->triangles_total += scene.meshes[m].triangleCount();
    }

    PreparedScene out;
    out.ct = options.ct;
    out.meshes.resize(scene.meshes.size());
    std::vector<OccluderData> occluders(scene.meshes.size());
    parallelFor(order, threads, [&](uint32_t m) {
        out.meshes[m] = buildProgressiveMesh(scene.meshes[m], options.collapser);
        occluders[m] = computeOccluderData(out.meshes[m].positions, out.meshes[m].triangles,
                                           options.compactness_resolution);
        if (progress) {
            progress->triangles_done += scene.meshes[m].triangleCount();
            ++progress->meshes_done;
        }
    });

    // Unused meshes are not stored: renumber the used ones densely.
    std::vector<uint32_t> new_index(scene.meshes.size(), UINT32_MAX);
    std::vector<ProgressiveMesh> kept;
    for (uint32_t m = 0; m < scene.meshes.size(); ++m)
        if (used[m]) {
            new_index[m] = uint32_t(kept.size());
            kept.push_back(std::move(out.meshes[m]));
        }

    out.objects.resize(scene.objects.size());
    std::vector<uint32_t> ids(scene.objects.size());
    std::iota(ids.begin(), ids.end(), 0u);
    parallelFor(ids, threads, [&](uint32_t i) {
        const Object& o = scene.objects[i];
        const ProgressiveMesh& pm = kept[new_index[o.mesh]];
        ObjectRecord& r = out.objects[i];
        r.mesh = new_index[o.mesh];
        r.color = o.color;
        r.world = o.world;
        for (const glm::vec3& p : pm.positions) r.aabb.extend(glm::vec3(o.world * glm::vec4(p, 1.0f)));
        const OccluderData& occ = occluders[o.mesh];
        r.oobb = transformBox(occ.oobb, o.world);
        int thin = 0;
        for (int a = 1; a < 3; ++a)
            if (r.oobb.half_extent[a] < r.oobb.half_extent[thin]) thin = a;
        r.occluder_normal = r.oobb.axis[thin];
        r.compactness = std::clamp(occ.compactness, 0.0f, 1.0f);  // the file format requires [0, 1]
    });
    out.meshes = std::move(kept);

    for (uint32_t i = 0; i < out.objects.size(); ++i)
        if (out.objects[i].compactness >= options.ct) out.cos.push_back(i);
    std::stable_sort(out.cos.begin(), out.cos.end(), [&](uint32_t a, uint32_t b) {
        return out.objects[a].compactness > out.objects[b].compactness;
    });
    return out;
}

}  // namespace occ
