// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "hzm.h"
#include "kernel_types.h"
#include "lod_hysteresis.h"
#include "pipeline/device_scene.h"

#include <span>
#include <utility>
#include <vector>

namespace occ {

struct PipelineOptions;

// The frame's visible set: ascending item ids with their LOD (vertex and triangle counts), on
// the host (for the network, the history and the churn) and on the device (for the layout).
// Every stage after culling reads it; culling (ids) and LOD selection (counts) write it, or a
// display sets it whole from what a culling rank chose.
struct VisibleItems {
    std::vector<uint32_t> ids, vertices, triangles;  // host; triangles only where the host needs them
    k::DeviceArray<uint32_t> device_ids, device_vertices, device_triangles;

    // Room for every one of `items` items.
    void reserve(uint32_t items);
    uint32_t size() const { return uint32_t(ids.size()); }
    k::VisibleLods device() const {
        return {device_ids.ptr(), device_vertices.ptr(), device_triangles.ptr(), uint32_t(ids.size())};
    }
};

// LOD selection: each visible item's level under the vertex budget N (Eq. 1, Peng & Cao, with
// the LOD hysteresis against the last frame's set; with a hierarchy never coarser than the error
// rule's level, so that an item's whole error, its node's and its level's, stays within tau) or
// within tau pixels of error (the error rule); mode full takes every item whole.
class LodStage {
public:
    // options must outlive the stage. The budget N follows the options (PipelineOptions::budget).
    LodStage(const OssFile& file, const DeviceScene& scene, const PipelineOptions& options);

    // Chooses the LOD of visible.ids (on the device and the host) into its counts. previous: the
    // last frame's set as (id, vertex count) pairs, ascending, for the hysteresis (empty: none);
    // hzm: the occluders' HZM for the visibility-weighted choice (oc+lod), or null.
    // tau: the pixels of error the hierarchy's cut was refined to (CutStage::tau), which a
    // level must keep within; without a hierarchy PipelineOptions::tau.
    void select(const k::Camera& camera, VisibleItems& visible,
                std::span<const std::pair<uint32_t, uint32_t>> previous, const k::HzmLevels* hzm, float tau);

    double budget() const { return budget_; }
    // The error rule, and the budget rule with a hierarchy: per mesh the largest collapse error
    // of each level (laid out as the maps), per item its world scale, on the device (the cut's
    // costs read them too); null otherwise.
    k::DevicePtr<const float> lodErrors() const { return lod_error_.ptr(); }
    k::DevicePtr<const float> itemScales() const { return object_scale_.ptr(); }

private:
    const DeviceScene& scene_;
    const PipelineOptions& options_;
    double budget_ = 0;
    k::DeviceArray<float> lod_shares_;
    // LodRule::Error: per mesh, vertex_count + 1 entries laid out as the maps (map_first): the
    // largest collapse error of the level with k vertices; per object, its world scale. With
    // nodes: per item, the world error its input already has (an HLOD's node error, 0 for leaves).
    k::DeviceArray<float> lod_error_, object_scale_, item_error_;
    // Per item, the level its last error-bounded search found: where the next one starts
    // (k::levelWithinErrorNear; speed only, the levels chosen do not depend on it).
    k::DeviceArray<uint32_t> level_hint_;
    k::DeviceArray<float> visible_share_;  // visibility_weighted: per visible entry
    k::PinnedArray<k::LodEntry> previous_lod_;  // the hysteresis' last visible set, on its way up
    k::DeviceArray<k::LodEntry> previous_lod_device_;
    k::LodHysteresisScratch hysteresis_scratch_;
};

}  // namespace occ
