// SPDX-License-Identifier: MIT
#include "render/frame_display.h"

#include "hzm_build.h"
#include "hzm_test.h"
#include "render/gl_check.h"
#include "render/png_writer.h"
#include "util/number_format.h"

#include <chrono>
#include <cmath>
#include <cstring>

namespace occ::render {

namespace {

using Clock = std::chrono::steady_clock;

double msSince(Clock::time_point t) { return std::chrono::duration<double, std::milli>(Clock::now() - t).count(); }

// True unless all 8 corners of the box lie outside one clip plane: a box that passes may still
// be off screen, one that fails has no pixel. Written apart from the kernels' frustum test, as
// the reference it is checked against.
bool boxMayHavePixels(const k::Aabb& box, const glm::mat4& view_proj) {
    int outside[6] = {0, 0, 0, 0, 0, 0};
    for (int c = 0; c < 8; ++c) {
        const glm::vec4 p = view_proj * glm::vec4(c & 1 ? box.max.x : box.min.x, c & 2 ? box.max.y : box.min.y,
                                                  c & 4 ? box.max.z : box.min.z, 1.0f);
        outside[0] += p.x < -p.w;
        outside[1] += p.x > p.w;
        outside[2] += p.y < -p.w;
        outside[3] += p.y > p.w;
        outside[4] += p.z < -p.w;
        outside[5] += p.z > p.w;
    }
    for (int o : outside)
        if (o == 8) return false;
    return true;
}

}  // namespace

uint64_t markSeenObjects(const uint32_t* items, uint64_t pixels, uint32_t object_count, std::vector<uint8_t>& seen) {
    seen.assign(object_count, 0);
    uint64_t count = 0;
    for (uint64_t p = 0; p < pixels; ++p) {
        const uint32_t item = items[p];
        if (item == 0 || item > object_count || seen[item - 1]) continue;
        seen[item - 1] = 1;
        ++count;
    }
    return count;
}

double psnrDb(const uint8_t* a, const uint8_t* b, uint64_t bytes) {
    return psnrFromSquaredError(squaredError(a, b, bytes), bytes);
}

double changedPixelPercent(const uint8_t* a, const uint8_t* b, uint64_t pixels, int channels) {
    if (pixels == 0) return 0;
    uint64_t changed = 0;
    for (uint64_t p = 0; p < pixels; ++p)
        changed += std::memcmp(a + p * channels, b + p * channels, size_t(channels)) != 0;
    return 100.0 * double(changed) / double(pixels);
}

FrameDisplay::FrameDisplay(Pipeline& pipeline, uint32_t width, uint32_t height, const DisplayOptions& options)
    : options_(options), width_(width), height_(height), renderer_(pipeline.scene(), options.colours), frame_(width, height) {
    renderer_.attach(pipeline);
    if (options.exact || options.reference) full_ = std::make_unique<FrameTarget>(width, height);
}

const std::vector<uint8_t>& FrameDisplay::picture() {
    if (!picture_read_) frame_.readColour(picture_);
    picture_read_ = true;
    return picture_;
}

DisplayStats FrameDisplay::display(const Pipeline& pipeline, const CameraPose& pose) {
    DisplayStats s;
    const k::Camera camera = toKernelCamera(pose, width_, height_);
    Clock::time_point start = Clock::now();
    // The reference's bound check reads which item drew each pixel.
    frame_.begin(options_.items || options_.reference);
    const DrawCounts counts = renderer_.drawFrame(pipeline, camera);
    glFinish();
    s.ms_draw = msSince(start);
    s.uploaded_bytes = counts.uploaded_bytes;
    s.draw_calls = counts.multi_draws;
    picture_read_ = false;
    if (!full_) return s;

    // What follows measures the frame; it is not part of it.
    const k::BusMeasurementScope measuring;
    start = Clock::now();
    const DeviceScene& scene = pipeline.scene();
    const uint32_t n = scene.item_count;
    candidates_.clear();
    // The full-detail picture draws the objects (with a hierarchy: the leaves, never an HLOD).
    for (uint32_t i = 0; i < n; ++i)
        if ((!scene.nodes || scene.host_nodes[i].child_count == 0) &&
            boxMayHavePixels(scene.host_objects[i].aabb, camera.view_proj))
            candidates_.push_back(i);
    full_->begin(true);
    renderer_.drawFullDetail(candidates_.data(), candidates_.size(), camera);
    const uint64_t pixels = uint64_t(width_) * height_;

    if (options_.exact) {
        full_->readItems(items_);
        s.exact_visible = markSeenObjects(items_.data(), pixels, n, seen_);
        in_pvs_.assign(n, 0);
        for (uint32_t id : pipeline.visibleObjects()) in_pvs_[id] = 1;
        // A leaf is drawn when it or a node above it is in the visible set: parents come first.
        if (scene.nodes)
            for (uint32_t i = 0; i < n; ++i)
                for (uint32_t c = scene.host_nodes[i].first_child; in_pvs_[i] && c < scene.host_nodes[i].first_child + scene.host_nodes[i].child_count; ++c)
                    in_pvs_[c] = 1;
        for (uint32_t i = 0; i < n; ++i) s.false_culls += seen_[i] && !in_pvs_[i];
        exact_now_.clear();
        for (uint32_t i = 0; i < n; ++i)
            if (seen_[i]) exact_now_.push_back(i);
        const Churn churn = setChurn(exact_before_, exact_now_);
        s.exact_added = churn.added;
        s.exact_removed = churn.removed;
        std::swap(exact_before_, exact_now_);

        // Peng 2014's exact culling: each frustum object's box against the full-detail depth
        // buffer at every pixel it covers (hzmTest against the full buffer's pyramid is that test).
        const uint32_t frustum = pipeline.frustumCount();
        full_hzm_.resize(size_t(k::hzmTotalTexels(width_, height_)));
        std::vector<float> depth;
        full_->readDepth(depth);
        k::copyToDevice(full_hzm_.ptr(), depth.data(), pixels);
        k::hzmBuild(full_hzm_.ptr(), width_, height_);
        k::HzmLevels levels;
        k::hzmLayout(width_, height_, levels);
        levels.data = full_hzm_.ptr();
        occluded_.resize(std::max<size_t>(1, frustum));
        k::hzmTest(pipeline.scene().objects.ptr(), pipeline.frustumIds(), frustum, camera, levels, occluded_.ptr());
        std::vector<uint8_t> occluded(frustum);
        k::copyToHost(occluded.data(), occluded_.ptr(), frustum);
        for (uint8_t o : occluded) s.exact_occluded += o;
        const uint64_t ours = frustum - pipeline.visibleObjects().size();
        s.culling_accuracy = s.exact_occluded == 0 ? (ours == 0 ? 100.0 : 0.0) : 100.0 * double(ours) / double(s.exact_occluded);
    }
    if (options_.reference) {
        full_->readColour(full_picture_);
        const std::vector<uint8_t>& ours = picture();
        s.changed_pixel_share = changedPixelPercent(ours.data(), full_picture_.data(), pixels, 3);
        // The bound check in one id space: a reference pixel (a leaf) counts as the item drawn
        // for it, the leaf or the node above it in this frame's cut; not drawn: matches nothing.
        drawn_cached_ = false;
        frame_.readItems(our_items_);
        full_->readItems(items_);
        mapToDrawnItems(pipeline, items_);
        const float bound = boundCheckPixels(options_.tau);
        PictureDifference d = comparePictures(ours.data(), full_picture_.data(), our_items_.data(), items_.data(),
                                              width_, height_, bound);
        // Where surfaces of several objects lie within the bound of each other in depth (IFC
        // walls, slabs and their layers overlap), the reference shows the nearest, and a frame
        // within the bound may show another. So an item with changed pixels beyond the bound is
        // looked for again among the surfaces within tau pixels' span behind the reference's
        // (a pixel spans 2 tan(fovy / 2) / height of its distance): two tie passes draw its
        // leaves alone at full detail, pulled that far towards the eye, depth test GL_LEQUAL,
        // in ascending and descending order, and each pixel they reach counts as one of its.
        if (d.bound_beyond_tau > 0) {
            bound_distances_.clear();
            changedPixelItemDistances(ours.data(), full_picture_.data(), our_items_.data(), items_.data(), width_,
                                      height_, kBoundSearchRadiusPx, bound_distances_);
            suspect_.assign(size_t(pipeline.scene().item_count) + 1, 0);
            size_t next = 0;
            for (uint64_t p = 0; p < pixels; ++p)
                if (std::memcmp(ours.data() + 3 * p, full_picture_.data() + 3 * p, 3) != 0 &&
                    bound_distances_[next++] > bound && our_items_[p] < suspect_.size())
                    suspect_[our_items_[p]] = 1;
            tie_leaves_.clear();
            for (uint32_t leaf : candidates_) {
                const uint32_t drawn = drawnItem(pipeline, leaf + 1);
                if (drawn != 0 && drawn < suspect_.size() && suspect_[drawn]) tie_leaves_.push_back(leaf);
            }
            const float pull = bound * 2.0f * std::tan(0.5f * camera.fovy) / float(height_);
            for (int pass = 0; pass < 2; ++pass) {
                if (pass == 1) std::reverse(tie_leaves_.begin(), tie_leaves_.end());
                full_->beginTiePass();
                renderer_.drawFullDetail(tie_leaves_.data(), tie_leaves_.size(), camera, pull);
                full_->endTiePass();
                full_->readItems(tied_items_[pass]);
                mapToDrawnItems(pipeline, tied_items_[pass]);
            }
            const uint32_t* const tied[2] = {tied_items_[0].data(), tied_items_[1].data()};
            d = comparePictures(ours.data(), full_picture_.data(), our_items_.data(), items_.data(), width_, height_,
                                bound, tied);
        }
        s.psnr_db = d.psnr_db;
        s.mse = d.mse;
        s.perceptible_share = d.perceptible_percent;
        // Below 7 x 7 pixels no SSIM window fits: identical pictures then score 1, others 0
        // (records carry finite numbers only).
        s.ssim = std::isfinite(d.ssim) ? d.ssim : d.psnr_db >= 100.0 ? 1.0 : 0.0;
        s.bound_p99_px = d.bound_p99_px;
        s.bound_pixels = d.bound_pixels;
        s.bound_beyond_tau = d.bound_beyond_tau;
    }
    s.ms_exact = msSince(start);
    return s;
}

void FrameDisplay::mapToDrawnItems(const Pipeline& pipeline, std::vector<uint32_t>& items) {
    for (uint32_t& item : items) item = drawnItem(pipeline, item);
}

uint32_t FrameDisplay::drawnItem(const Pipeline& pipeline, uint32_t item) {
    const DeviceScene& scene = pipeline.scene();
    const uint32_t n = scene.item_count;
    if (!drawn_cached_) {
        // The frame's visible set, once per frame (the bound check clears drawn_cached_).
        drawn_cached_ = true;
        drawn_of_.assign(size_t(n) + 1, UINT32_MAX);  // by item + 1, as the buffer holds them
        drawn_of_[0] = 0;                             // the background is the background
        in_pvs_.assign(n, 0);
        for (uint32_t id : pipeline.visibleObjects()) in_pvs_[id] = 1;
        if (scene.nodes && parent_.size() != n) {
            parent_.assign(n, UINT32_MAX);
            for (uint32_t i = 0; i < n; ++i)
                for (uint32_t c = scene.host_nodes[i].first_child; c < scene.host_nodes[i].first_child + scene.host_nodes[i].child_count; ++c)
                    parent_[c] = i;
        }
    }
    if (item == 0 || item > n) return item;
    uint32_t& drawn = drawn_of_[item];
    if (drawn == UINT32_MAX) {
        uint32_t i = item - 1;
        while (!in_pvs_[i] && scene.nodes && parent_[i] != UINT32_MAX) i = parent_[i];
        drawn = in_pvs_[i] ? i + 1 : UINT32_MAX - 1;  // culled: no pixel of ours can match it
    }
    return drawn;
}

void FrameDisplay::drawCullingView(const Pipeline& pipeline, const k::Camera& camera) {
    const k::BusMeasurementScope measuring;
    frame_.begin(false);
    renderer_.drawFrame(pipeline, camera);
    std::vector<SceneRenderer::Box> boxes;
    in_pvs_.assign(pipeline.scene().item_count, 0);
    for (uint32_t id : pipeline.visibleObjects()) in_pvs_[id] = 1;
    const auto box = [&](uint32_t id, glm::vec3 colour) {
        const k::Aabb& b = pipeline.scene().host_objects[id].aabb;
        boxes.push_back({glm::vec4(b.min, 0), glm::vec4(b.max, 0), glm::vec4(colour, 1)});
    };
    for (uint32_t id : pipeline.downloadFrustumObjects())
        if (!in_pvs_[id]) box(id, {0.95f, 0.15f, 0.1f});
    for (uint32_t id : pipeline.downloadOccluders()) box(id, {0.7f, 0.2f, 0.95f});
    renderer_.drawBoxes(boxes, camera, false);
    picture_read_ = false;
}

void FrameDisplay::writeDebugViews(const Pipeline& pipeline, const CameraPose& pose, const std::string& dir,
                                   const std::string& name) {
    const k::BusMeasurementScope measuring;
    const std::string base = dir + "/" + name;
    const k::HzmLevels levels = pipeline.hzmLevels();
    const uint64_t pixels = uint64_t(width_) * height_;
    std::vector<float> hzm(size_t(k::hzmTotalTexels(width_, height_)));
    k::copyToHost(hzm.data(), levels.data, hzm.size());
    writePng(base + "_aos_depth.png", width_, height_, 1, depthToGrey(hzm.data(), pixels).data());
    // Levels scaled back to W x H (texel of pixel p at level l is p >> l), so that they overlay.
    std::vector<float> scaled(pixels);
    for (uint32_t l = 1; l < levels.level_count; ++l) {
        const float* texels = hzm.data() + levels.offset[l];
        for (uint32_t y = 0; y < height_; ++y)
            for (uint32_t x = 0; x < width_; ++x)
                scaled[uint64_t(y) * width_ + x] = texels[uint64_t(y >> l) * levels.width[l] + (x >> l)];
        writePng(base + "_hzm_" + std::to_string(l) + ".png", width_, height_, 1,
                 depthToGrey(scaled.data(), pixels).data());
    }
    drawCullingView(pipeline, toKernelCamera(pose, width_, height_));
    std::vector<uint8_t> rgb;
    frame_.readColour(rgb);
    writePng(base + "_culling.png", width_, height_, 3, rgb.data());
    picture_read_ = false;
}

}  // namespace occ::render
