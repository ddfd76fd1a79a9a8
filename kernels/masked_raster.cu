// SPDX-License-Identifier: MIT
#include "masked_raster.h"

#include "device_access.h"
#include "masked_tile.h"
#include "raster_setup.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/for_each.h>
#include <thrust/iterator/counting_iterator.h>

namespace occ::k {

namespace {

// One thread per subtile: its layers in registers, the triangles of its band in index order,
// then its pixels written out. The warp's 32 subtiles side by side read the same triangles.
// The CUDA build's raster, and on the CPU the scalar reference the SIMD band loop must match.
struct RasterSubtiles {
    const DepthRasterTriangle* setup;
    TileBins bins;
    float* depth;
    uint32_t width, height, subtiles_x;

    OCC_HD void operator()(uint32_t i) const {
        const uint32_t px0 = i % subtiles_x * kSubtileWidth, py0 = i / subtiles_x * kSubtileHeight;
        const uint32_t outside = ~subtileInside(px0, py0, width, height);
        MaskedSubtile tile{1.0f, 0.0f, 0u};
        const uint32_t band = py0 >> kMaskedBandRowsLog2;
        for (uint64_t p = bins.tileBegin(band); p < bins.tileEnd(band); ++p) {
            const DepthRasterTriangle& s = setup[bins.pair_triangle[p]];
            const SubtileBox box(s, px0, py0);
            if (box.empty) continue;
            const float z = box.farDepth(s);
            if (!(z < tile.z0)) continue;
            updateSubtile(tile, subtileCoverage(raster::EdgeFunctions(s), box, px0, py0), z, outside);
        }
        for (uint32_t y = 0; y < kSubtileHeight && py0 + y < height; ++y)
            for (uint32_t x = 0; x < kSubtileWidth && px0 + x < width; ++x)
                depth[uint64_t(py0 + y) * width + px0 + x] = subtileDepth(tile, 8 * y + x);
    }
};

MaskedBands maskedFrontEnd(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles, uint32_t tri_count,
                           DevicePtr<const uint8_t> edge_flags, DevicePtr<const uint32_t> edge_neighbours,
                           const Camera& camera, DevicePtr<float> depth, DepthRasterScratch& scratch, bool seams) {
    if (tri_count > 0)
        depthRasterSetup(raw(positions), raw(triangles), tri_count, raw(edge_flags), raw(edge_neighbours), camera,
                         scratch, seams);
    // A band spans the viewport: 2^15 columns is the widest there is.
    const TileBins bins = binTriangles(tri_count, camera.width, camera.height, 15, kMaskedBandRowsLog2, scratch);
    return MaskedBands{raw(scratch.drawn_setup.ptr()), bins, raw(depth), camera.width, camera.height};
}

void rasterSubtiles(const MaskedBands& bands) {
    const uint32_t subtiles_x = (bands.width + kSubtileWidth - 1) / kSubtileWidth;
    const uint32_t subtiles_y = (bands.height + kSubtileHeight - 1) / kSubtileHeight;
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), subtiles_x * subtiles_y,
                       RasterSubtiles{bands.setup, bands.bins, bands.depth, bands.width, bands.height, subtiles_x});
}

}  // namespace

void maskedDepthRaster(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles, uint32_t tri_count,
                       DevicePtr<const uint8_t> edge_flags, DevicePtr<const uint32_t> edge_neighbours,
                       const Camera& camera, DevicePtr<float> depth, DepthRasterScratch& scratch, bool seams) {
    checkRasterViewport(camera, "maskedDepthRaster");
    if (camera.width == 0 || camera.height == 0) return;
    const MaskedBands bands =
        maskedFrontEnd(positions, triangles, tri_count, edge_flags, edge_neighbours, camera, depth, scratch, seams);
#if defined(__CUDACC__)
    rasterSubtiles(bands);
#else
    maskedRasterBandsCpu(bands);
#endif
}

void maskedDepthRasterScalar(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles,
                             uint32_t tri_count, DevicePtr<const uint8_t> edge_flags,
                             DevicePtr<const uint32_t> edge_neighbours, const Camera& camera, DevicePtr<float> depth,
                             DepthRasterScratch& scratch, bool seams) {
    checkRasterViewport(camera, "maskedDepthRasterScalar");
    if (camera.width == 0 || camera.height == 0) return;
    rasterSubtiles(
        maskedFrontEnd(positions, triangles, tri_count, edge_flags, edge_neighbours, camera, depth, scratch, seams));
}

const char* maskedRasterTarget() {
#if defined(__CUDACC__)
    return "CUDA";
#else
    return maskedRasterCpuTarget();
#endif
}

}  // namespace occ::k
