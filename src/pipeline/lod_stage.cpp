// SPDX-License-Identifier: MIT
#include "pipeline/lod_stage.h"

#include "hzm_test.h"
#include "lod_select.h"
#include "pipeline/pipeline.h"

#include <algorithm>
#include <cmath>

namespace occ {

namespace {

// The first `count` entries of a host list to its device copy, which grows as needed.
template <class T, class Host>
void upload(k::DeviceArray<T>& device, const Host& host, size_t count) {
    device.growTo(std::max<size_t>(1, count));
    k::copyToDevice(device.ptr(), host.data(), count);
}

}  // namespace

void VisibleItems::reserve(uint32_t items) {
    vertices.resize(items);
    triangles.resize(items);
    const size_t room = std::max<uint32_t>(1, items);
    device_ids.resize(room);
    device_vertices.resize(room);
    device_triangles.resize(room);
}

LodStage::LodStage(const OssFile& file, const DeviceScene& scene, const PipelineOptions& options)
    : scene_(scene), options_(options) {
    // The error tables serve the error rule, and with a hierarchy the budget rule's floor: an
    // item is never drawn coarser than tau allows (issue 49).
    if (options.lod == LodRule::Error || (scene.nodes && options.mode != CullMode::Full)) {
        // The error of the level with k vertices is the largest error of the collapses it has
        // undone, those of vertices k .. n - 1: a suffix maximum, 0 at full detail.
        std::vector<float> lod_error(std::max<size_t>(1, file.allMaps().size()), 0.0f);
        for (uint32_t m = 0; m < scene.mesh_count; ++m) {
            const OssFile::MeshView mesh = file.mesh(m);
            float* e = lod_error.data() + scene.host_map_first[m];
            const uint32_t nv = mesh.vertexCount();
            e[nv] = 0.0f;
            for (uint32_t k = nv; k-- > 0;) e[k] = std::max(e[k + 1], mesh.error[k]);
        }
        std::vector<float> scale(std::max<uint32_t>(1, scene.item_count), 1.0f);
        for (uint32_t i = 0; i < scene.item_count; ++i) {
            const glm::mat4& w = scene.host_world[i];
            scale[i] = std::max({glm::length(glm::vec3(w[0])), glm::length(glm::vec3(w[1])), glm::length(glm::vec3(w[2]))});
        }
        lod_error_.resize(lod_error.size());
        k::copyToDevice(lod_error_.ptr(), lod_error.data(), lod_error.size());
        object_scale_.resize(scale.size());
        k::copyToDevice(object_scale_.ptr(), scale.data(), scale.size());
        level_hint_.resize(scale.size());
        k::deviceMemset(level_hint_.ptr(), 0, scale.size() * sizeof(uint32_t));
        if (scene.nodes) {
            // An HLOD's level gets what its node's own error leaves of tau.
            std::vector<float> item_error(std::max<uint32_t>(1, scene.item_count), 0.0f);
            for (uint32_t i = 0; i < scene.item_count; ++i) item_error[i] = scene.host_nodes[i].error;
            item_error_.resize(item_error.size());
            k::copyToDevice(item_error_.ptr(), item_error.data(), item_error.size());
        }
    }
    double scene_vertices = 0;
    for (uint32_t i = 0; i < scene.item_count; ++i) scene_vertices += scene.host_objects[i].vertex_count;
    budget_ = options.budget > 0        ? options.budget
              : options.budget_share > 0 ? options.budget_share * scene_vertices
                                         : std::min(scene_vertices, PipelineOptions::kVerticesPerPixel *
                                                                        double(options.width) * double(options.height));
}

void LodStage::select(const k::Camera& camera, VisibleItems& visible,
                      std::span<const std::pair<uint32_t, uint32_t>> previous, const k::HzmLevels* hzm, float tau) {
    const uint32_t count = visible.size();
    const k::DevicePtr<const uint32_t> ids = visible.device_ids.ptr();
    const auto shares = [&]() -> k::DevicePtr<const float> {
        if (!hzm) return nullptr;
        visible_share_.growTo(std::max<uint32_t>(1, count));
        k::hzmVisibleShare(scene_.objects.ptr(), ids, count, camera, *hzm, visible_share_.ptr());
        return visible_share_.ptr();
    };
    if (options_.mode == CullMode::Full) {
        // The baseline draws every object whole: its counts go up.
        for (uint32_t j = 0; j < count; ++j) {
            visible.vertices[j] = scene_.host_objects[visible.ids[j]].vertex_count;
            visible.triangles[j] = scene_.host_objects[visible.ids[j]].triangle_count;
        }
        k::copyToDevice(visible.device_vertices.ptr(), visible.vertices.data(), count);
        k::copyToDevice(visible.device_triangles.ptr(), visible.triangles.data(), count);
    } else if (options_.lod == LodRule::Error) {
        // No hysteresis: keeping a coarser level than the bound allows would break it.
        k::lodSelectByError(scene_.objects.ptr(), ids, count, camera, tau, options_.pet, shares(),
                            scene_.map_first.ptr(), lod_error_.ptr(), object_scale_.ptr(),
                            scene_.nodes ? item_error_.ptr() : nullptr, scene_.maps, visible.device_vertices.ptr(),
                            visible.device_triangles.ptr(), level_hint_.ptr());
        k::copyToHost(visible.vertices.data(), visible.device_vertices.ptr(), count);
    } else {
        const k::DevicePtr<const float> share = shares();
        const k::LodParams params{float(budget_), options_.alpha, options_.pet, share};
        k::lodSelect(scene_.objects.ptr(), ids, count, camera, params, scene_.map_first.ptr(), scene_.maps,
                     visible.device_vertices.ptr(), visible.device_triangles.ptr(), lod_shares_);
        if (options_.lod_hysteresis > 0 && !previous.empty()) {
            // The last frame's visible set goes up (the switch's comes from the other rank).
            previous_lod_.resize(previous.size());
            for (size_t j = 0; j < previous.size(); ++j) previous_lod_[j] = {previous[j].first, previous[j].second};
            upload(previous_lod_device_, previous_lod_, previous.size());
            k::keepSimilarLods(ids, count, previous_lod_device_.ptr(), uint32_t(previous.size()), options_.lod_hysteresis,
                               budget_, scene_.objects.ptr(), scene_.map_first.ptr(), scene_.maps,
                               visible.device_vertices.ptr(), visible.device_triangles.ptr(), hysteresis_scratch_);
        }
        // With a hierarchy the cut stopped where a node's own error is within tau; its level may
        // then be finer than the budget gives, never coarser (the bound covers input + level).
        // Raised levels step by the hysteresis' fraction (k::levelOnRaiseGrid), so that they
        // change, and are reformed and streamed, only where the bound crosses a step.
        if (scene_.nodes)
            k::lodRaiseToErrorBound(scene_.objects.ptr(), ids, count, camera, tau, options_.pet, share,
                                    scene_.map_first.ptr(), lod_error_.ptr(), object_scale_.ptr(), item_error_.ptr(),
                                    scene_.maps, visible.device_vertices.ptr(), visible.device_triangles.ptr(),
                                    level_hint_.ptr(), float(options_.lod_hysteresis));
        k::copyToHost(visible.vertices.data(), visible.device_vertices.ptr(), count);
    }
}

}  // namespace occ
