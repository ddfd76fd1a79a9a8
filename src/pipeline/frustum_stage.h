// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"
#include "pipeline/device_scene.h"
#include "view/camera.h"

#include <vector>

namespace occ {

// Frustum culling: every item's box against the view frustum, on the device. Keeps the items in
// the frustum (ascending ids) and a flag per item until the next run. With the hierarchy no
// frame tests every item: run only sets the frustum, and the list is what the cut (CutStage)
// or the occluder choice tested and found in it (cullIds, replace); their flags are valid.
class FrustumStage {
public:
    explicit FrustumStage(const DeviceScene& scene);

    // Culls every item for `camera`, the view of `pose` (with the hierarchy: none; the list is
    // then empty until cullIds or replace).
    void run(const CameraPose& pose, const k::Camera& camera);
    // The listed items against the last run's frustum: their flags, and the list becomes those
    // in it (in list order).
    void cullIds(k::DevicePtr<const uint32_t> ids, uint32_t count);
    // Whether ids() are the last run's for exactly this pose (each role culls a frame's
    // frustum once, whichever step needs it first).
    bool isFor(const CameraPose& pose) const;
    // The list becomes `ids` (device memory, ascending, in the frustum); the flags stay.
    void replace(k::DevicePtr<const uint32_t> ids, uint32_t count);

    k::DevicePtr<const uint32_t> ids() const { return ids_.ptr(); }
    uint32_t count() const { return count_; }
    k::DevicePtr<const uint8_t> inFrustum() const { return in_frustum_.ptr(); }  // per item, 1 = in
    k::DevicePtr<uint8_t> flags() { return in_frustum_.ptr(); }                  // for the cut's tests
    const k::Frustum& frustum() const { return frustum_; }  // the last run's
    std::vector<uint32_t> download() const;

private:
    const DeviceScene& scene_;
    k::DeviceArray<uint8_t> in_frustum_;
    k::DeviceArray<uint32_t> ids_;
    uint32_t count_ = 0;
    k::Frustum frustum_{};
    CameraPose pose_{};
    bool has_pose_ = false;
};

}  // namespace occ
