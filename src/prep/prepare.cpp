// SPDX-License-Identifier: MIT
#include "prep/prepare.h"

#include "prep/cluster_collapse.h"

#include "prep/collapse_recorder.h"
#include "prep/error_calibration.h"
#include "prep/fast_collapser.h"
#include "prep/occluder.h"
#include "prep/rearrange.h"
#include "prep/weld.h"
#include "scene/errors.h"
#include "scene/oss_file.h"

#include <algorithm>
#include <stdexcept>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <numeric>
#include <thread>

namespace occ {

namespace {

// Weld, the collapse sequence `collapse` makes of the welded mesh (which it may extend with
// placed vertices and their colours), the §4.2 arrays, Algorithm 1. colours: one per mesh
// position, carried to ProgressiveMesh::colours; empty: none.
template <typename Collapse>
ProgressiveMesh buildFromSequence(const Mesh& mesh, std::span<const uint32_t> colours, const Collapse& collapse) {
    WeldedMesh welded = weldPositions(mesh.positions, mesh.indices);
    std::vector<uint32_t> welded_colours;
    if (!colours.empty()) {
        if (colours.size() != mesh.positions.size())
            throw std::invalid_argument("buildProgressiveMesh: one colour per position expected");
        welded_colours.reserve(welded.positions.size());
        for (uint32_t v : welded.source) welded_colours.push_back(colours[v]);
    }
    const CollapseSequence sequence = collapse(welded, colours.empty() ? nullptr : &welded_colours);
    const CollapseArrays arrays = recordCollapseArrays(uint32_t(welded.positions.size()),
                                                       uint32_t(welded.triangles.size() / 3), sequence);
    ProgressiveMesh pm = rearrange(welded.positions, welded.triangles, sequence, arrays);
    if (!colours.empty()) {
        pm.colours.resize(pm.positions.size());
        for (size_t v = 0; v < welded_colours.size(); ++v) pm.colours[arrays.permuteV[v]] = welded_colours[v];
    }
    calibrateRecordedErrors(pm);  // the recorded errors become distances tau can trust
    pm.source_vertices = uint32_t(mesh.positions.size());
    pm.dropped_triangles = welded.dropped_triangles;
    return pm;
}

}  // namespace

ProgressiveMesh buildProgressiveMesh(const Mesh& mesh, Collapser collapser, std::span<const uint32_t> colours) {
    return buildFromSequence(mesh, colours, [collapser](const WeldedMesh& w, std::vector<uint32_t>*) {
        return collapser == Collapser::Fast ? fastCollapseSequence(w.positions, w.triangles)
                                            : openMeshCollapseSequence(w.positions, w.triangles);
    });
}

ProgressiveMesh buildClusteredProgressiveMesh(const Mesh& mesh, std::span<const uint32_t> colours,
                                             const ClusterOptions& options) {
    return buildFromSequence(mesh, colours, [&options](WeldedMesh& w, std::vector<uint32_t>* welded_colours) {
        const std::span<const uint32_t> borders =
            options.colour_borders && welded_colours ? std::span<const uint32_t>(*welded_colours) : std::span<const uint32_t>();
        CollapseSequence edges = fastCollapseSequence(w.positions, w.triangles, CollapseCost::Quadric, options.place_edges, borders);
        return clusterAfterCollapses(w.positions, welded_colours, w.triangles, std::move(edges), options);
    });
}

namespace {

// Completed meshes wait here until every earlier one is written, so that the output does not
// depend on which worker finished first; workers stay at most kWindowPerThread meshes per
// thread ahead of the writer, which bounds the memory held to a few meshes per thread.
constexpr size_t kWindowPerThread = 4;

struct Finished {
    bool ready = false;
    bool empty = false;  // the source mesh has no triangles: its objects are dropped
    ProgressiveMesh mesh;
};

}  // namespace

PrepSummary prepareFromSource(const SceneSource& source, const PrepOptions& options, PrepProgress* progress,
                              const std::function<uint32_t(ProgressiveMesh&&)>& add_mesh,
                              std::vector<ObjectRecord>& objects_out, std::vector<uint32_t>& cos_out) {
    if (!(options.ct >= 0.0f && options.ct <= 1.0f))
        throw OptionError("ct", OptionError::value(options.ct) + ": must be in [0, 1]");
    const unsigned threads = options.threads ? options.threads : std::max(1u, std::thread::hardware_concurrency());
    const std::vector<Object>& objects = source.objects();
    const uint32_t mesh_count = source.meshCount();

    // Only meshes some object uses are prepared, in the source's order; per mesh its objects.
    std::vector<uint32_t> first(size_t(mesh_count) + 1, 0), members(objects.size());
    for (const Object& o : objects) ++first[o.mesh + 1];
    for (uint32_t m = 0; m < mesh_count; ++m) first[m + 1] += first[m];
    {
        std::vector<uint32_t> fill(first.begin(), first.end() - 1);
        for (uint32_t i = 0; i < objects.size(); ++i) members[fill[objects[i].mesh]++] = i;
    }
    std::vector<uint32_t> order;
    for (uint32_t m = 0; m < mesh_count; ++m)
        if (first[m + 1] > first[m]) order.push_back(m);
    if (progress) {
        progress->meshes_total = order.size();
        progress->triangles_total = 0;
        for (uint32_t m : order) progress->triangles_total += source.meshTriangles(m);
    }

    std::vector<ObjectRecord> records(objects.size());
    std::vector<uint8_t> dropped(objects.size(), 0);
    PrepSummary summary;
    const size_t window = kWindowPerThread * threads + 4;
    std::vector<Finished> slots(window);
    std::mutex mutex;
    std::condition_variable advanced;
    size_t written = 0;  // meshes of `order` handed to add_mesh (or dropped)
    std::atomic<size_t> next{0};
    std::exception_ptr failure;
    bool failed = false;

    // Called with the lock held: writes every finished mesh that is next in order.
    const auto writeReady = [&] {
        while (written < order.size() && slots[written % window].ready) {
            Finished& f = slots[written % window];
            const uint32_t m = order[written];
            if (f.empty) {
                for (uint32_t k = first[m]; k < first[m + 1]; ++k) dropped[members[k]] = 1;
            } else {
                summary.unique_triangles += f.mesh.triangleCount();
                summary.instanced_triangles += uint64_t(f.mesh.triangleCount()) * (first[m + 1] - first[m]);
                summary.dropped_triangles += f.mesh.dropped_triangles;
                const uint32_t index = add_mesh(std::move(f.mesh));
                for (uint32_t k = first[m]; k < first[m + 1]; ++k) records[members[k]].mesh = index;
                ++summary.meshes;
            }
            f = Finished{};
            ++written;
        }
        advanced.notify_all();
    };

    const auto worker = [&] {
        for (size_t k; (k = next.fetch_add(1)) < order.size();) {
            {
                std::unique_lock lock(mutex);
                advanced.wait(lock, [&] { return failed || k < written + window; });
                if (failed) return;
            }
            try {
                const uint32_t m = order[k];
                Finished f;
                const Mesh mesh = source.mesh(m);
                f.empty = mesh.indices.empty();
                if (!f.empty) {
                    f.mesh = buildProgressiveMesh(mesh, options.collapser);
                    const OccluderData occ =
                        computeOccluderData(f.mesh.positions, f.mesh.triangles, options.compactness_resolution);
                    for (uint32_t j = first[m]; j < first[m + 1]; ++j) {
                        const Object& o = objects[members[j]];
                        ObjectRecord& r = records[members[j]];
                        r.color = o.color;
                        r.world = o.world;
                        for (const glm::vec3& p : f.mesh.positions) r.aabb.extend(glm::vec3(o.world * glm::vec4(p, 1.0f)));
                        r.oobb = transformBox(occ.oobb, o.world);
                        int t = 0;
                        for (int a = 1; a < 3; ++a)
                            if (r.oobb.half_extent[a] < r.oobb.half_extent[t]) t = a;
                        r.occluder_normal = r.oobb.axis[t];
                        r.compactness = std::clamp(occ.compactness, 0.0f, 1.0f);  // the file format requires [0, 1]
                    }
                }
                if (progress) {
                    progress->triangles_done += source.meshTriangles(m);
                    ++progress->meshes_done;
                }
                std::lock_guard lock(mutex);
                f.ready = true;
                slots[k % window] = std::move(f);
                writeReady();
            } catch (...) {
                std::lock_guard lock(mutex);
                if (!failed) failure = std::current_exception();
                failed = true;
                advanced.notify_all();
                return;
            }
        }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (std::thread& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);

    // Objects of meshes without triangles go; the others keep their order.
    objects_out.clear();
    objects_out.reserve(objects.size());
    for (size_t i = 0; i < records.size(); ++i)
        if (!dropped[i]) objects_out.push_back(records[i]);
    records = {};
    cos_out.clear();
    for (uint32_t i = 0; i < objects_out.size(); ++i)
        if (objects_out[i].compactness >= options.ct) cos_out.push_back(i);
    std::stable_sort(cos_out.begin(), cos_out.end(), [&](uint32_t a, uint32_t b) {
        return objects_out[a].compactness > objects_out[b].compactness;
    });
    summary.objects = objects_out.size();
    summary.cos = cos_out.size();
    summary.skipped = source.skipped();
    return summary;
}

PreparedScene prepareScene(const Scene& scene, const PrepOptions& options, PrepProgress* progress) {
    const std::unique_ptr<SceneSource> view = sceneView(scene);  // the scene is not copied
    PreparedScene out;
    out.ct = options.ct;
    prepareFromSource(
        *view, options, progress,
        [&out](ProgressiveMesh&& m) {
            out.meshes.push_back(std::move(m));
            return uint32_t(out.meshes.size() - 1);
        },
        out.objects, out.cos);
    return out;
}

PrepSummary prepareToFile(const SceneSource& source, const std::string& path, const PrepOptions& options,
                          PrepProgress* progress, bool durable) {
    OssStreamWriter writer(path);
    writer.setDurable(durable);
    std::vector<ObjectRecord> objects;
    std::vector<uint32_t> cos;
    PrepSummary summary = prepareFromSource(
        source, options, progress, [&writer](ProgressiveMesh&& m) { return writer.addMesh(m); }, objects, cos);
    if (objects.empty()) throw InputError(path, "the model has no triangles: nothing to prepare");
    writer.finish(objects, cos, options.ct);
    return summary;
}

}  // namespace occ
