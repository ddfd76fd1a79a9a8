// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"
#include "pipeline/device_scene.h"
#include "view/camera.h"

#include <vector>

namespace occ {

// Frustum culling: every item's box against the view frustum, on the device. Keeps the items in
// the frustum (ascending ids) and a flag per item until the next run; with the hierarchy the
// list may be replaced by the cut's share of it (CutStage).
class FrustumStage {
public:
    explicit FrustumStage(const DeviceScene& scene);

    // Culls every item for `camera`, the view of `pose`.
    void run(const CameraPose& pose, const k::Camera& camera);
    // Whether ids() are the last run's for exactly this pose (each role culls a frame's
    // frustum once, whichever step needs it first).
    bool isFor(const CameraPose& pose) const;
    // The list becomes `ids` (ascending, in the frustum); the flags stay the run's.
    void replace(const std::vector<uint32_t>& ids);

    k::DevicePtr<const uint32_t> ids() const { return ids_.ptr(); }
    uint32_t count() const { return count_; }
    k::DevicePtr<const uint8_t> inFrustum() const { return in_frustum_.ptr(); }  // per item, 1 = in
    std::vector<uint32_t> download() const;

private:
    const DeviceScene& scene_;
    k::DeviceArray<uint8_t> in_frustum_;
    k::DeviceArray<uint32_t> ids_;
    uint32_t count_ = 0;
    CameraPose pose_{};
    bool has_pose_ = false;
};

}  // namespace occ
