// SPDX-License-Identifier: MIT
#include "pipeline/frustum_stage.h"

#include "frustum_cull.h"

#include <algorithm>
#include <cstring>

namespace occ {

FrustumStage::FrustumStage(const DeviceScene& scene) : scene_(scene) {
    const size_t room = std::max<uint32_t>(1, scene.item_count);
    in_frustum_.resize(room);
    ids_.resize(room);
}

void FrustumStage::run(const CameraPose& pose, const k::Camera& camera) {
    frustum_ = k::frustumFromViewProj(camera.view_proj);
    count_ = scene_.nodes ? 0 : k::frustumCull(scene_.objects.ptr(), scene_.item_count, frustum_, in_frustum_.ptr(), ids_.ptr());
    pose_ = pose;
    has_pose_ = true;
}

bool FrustumStage::isFor(const CameraPose& pose) const {
    return has_pose_ && std::memcmp(&pose_, &pose, sizeof pose) == 0;
}

void FrustumStage::cullIds(k::DevicePtr<const uint32_t> ids, uint32_t count) {
    count_ = k::frustumCullIds(scene_.objects.ptr(), ids, count, frustum_, in_frustum_.ptr(), ids_.ptr());
}

void FrustumStage::replace(k::DevicePtr<const uint32_t> ids, uint32_t count) {
    count_ = count;
    k::copyOnDevice(ids_.ptr(), ids, count);
}

std::vector<uint32_t> FrustumStage::download() const {
    std::vector<uint32_t> ids(count_);
    k::copyToHost(ids.data(), ids_.ptr(), ids.size());
    return ids;
}

}  // namespace occ
