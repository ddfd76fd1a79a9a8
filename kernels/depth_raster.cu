// SPDX-License-Identifier: MIT
#include "depth_raster.h"

#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/reduce.h>
#include <thrust/scan.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace occ::k {

// One vertex after projection and snapping (every triangle corner reads it).
struct DepthRasterVertex {
    int32_t x, y;    // window position in 1/256 pixel
    float z;         // window depth
    uint32_t drawn;  // 0 when the rules skip every triangle using it
};
static_assert(sizeof(DepthRasterVertex) == 16);

// One triangle after projection and snapping, as the tiles read it.
struct DepthRasterTriangle {
    int32_t x[3], y[3];  // window position in 1/256 pixel, counter-clockwise (y up)
    // depth at a point = sum over corners i of edgeFunction(edge opposite i) * weight[i]: the
    // edge functions over twice the area are the barycentric coordinates, so weight[i] is
    // corner i's window depth over twice the snapped area.
    float weight[3];
    // At most every depth (before the epsilon) the triangle writes, or below every depth: a
    // triangle whose box is already nearer everywhere changes nothing and can be passed over.
    float lower_bound;
    // Pixels whose centres may be covered, inclusive, clamped to the viewport; the triangle is
    // empty (skipped, or covers no centre) when x_lo > x_hi.
    uint16_t x_lo, y_lo, x_hi, y_hi;
};
static_assert(sizeof(DepthRasterTriangle) == 48);

namespace {

// Arithmetic without fused multiply-adds: nvcc contracts a*b+c in device code by default while
// g++ for our x86-64 target does not, and the raster must be the same bits on both back ends.
OCC_HD inline float mulRn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fmul_rn(a, b);
#else
    return a * b;
#endif
}
OCC_HD inline float addRn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fadd_rn(a, b);
#else
    return a + b;
#endif
}
OCC_HD inline float divRn(float a, float b) {
#if defined(__CUDA_ARCH__)
    return __fdiv_rn(a, b);
#else
    return a / b;
#endif
}

// A tile's triangles are scattered over the setup array, which outgrows the caches: on the CPU,
// ask for the triangle a few pairs ahead while drawing this one (about 15 % of the whole call on
// 400 K triangles whose objects come in random order).
constexpr uint64_t kPrefetchDistance = 8;
OCC_HD inline void prefetch(const void* p) {
#if defined(__GNUC__) && !defined(__CUDA_ARCH__)
    __builtin_prefetch(p);
#else
    (void)p;
#endif
}

OCC_HD inline int64_t floorDiv(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
OCC_HD inline float minf(float a, float b) { return a < b ? a : b; }
OCC_HD inline int64_t abs64(int64_t a) { return a < 0 ? -a : a; }
OCC_HD inline int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }
OCC_HD inline int64_t max64(int64_t a, int64_t b) { return a > b ? a : b; }

constexpr int64_t kUnits = kDepthRasterSubpixelUnits;
constexpr int64_t kHalfPixel = kUnits / 2;
constexpr int64_t kMargin = kDepthRasterMarginUnits;
constexpr uint32_t kTile = kDepthRasterTileSize;
// Pixel boxes are kept in 16 bits.
constexpr uint32_t kMaxSide = 32768;
// Triangles per binning chunk, and a cap on the tile x chunk count matrix (32 MB).
constexpr uint64_t kChunkTriangles = 4096;
constexpr uint64_t kMaxCountCells = uint64_t(1) << 22;
// Above every depth a triangle can produce (those are finite): no triangle yet.
constexpr float kFar = 3.0e38f;

// One thread per vertex: projection, the skip rules that concern one vertex, snapping.
struct ProjectVertices {
    const glm::vec3* positions;
    DepthRasterVertex* vertices;
    float m[16];  // view_proj, column-major as glm keeps it: m[4*col + row]
    float width, height;

    OCC_HD void operator()(uint32_t v) const {
        const glm::vec3 p = positions[v];
        float clip[4];
        for (int r = 0; r < 4; ++r)
            clip[r] = addRn(addRn(addRn(mulRn(m[r], p.x), mulRn(m[4 + r], p.y)), mulRn(m[8 + r], p.z)), m[12 + r]);
        DepthRasterVertex out{0, 0, 0.0f, 0};
        // Negated comparisons so that NaNs skip too.
        if (clip[3] > 0.0f && clip[2] >= -clip[3]) {
            const float inv_w = divRn(1.0f, clip[3]);
            const float wx = mulRn(addRn(mulRn(mulRn(clip[0], inv_w), 0.5f), 0.5f), width);
            const float wy = mulRn(addRn(mulRn(mulRn(clip[1], inv_w), 0.5f), 0.5f), height);
            out.z = addRn(mulRn(mulRn(clip[2], inv_w), 0.5f), 0.5f);
            if (fabsf(wx) <= kDepthRasterGuardBand && fabsf(wy) <= kDepthRasterGuardBand && out.z <= 3.0e38f) {
                // Inside the guard band, so exact in float after scaling by 256 and within int32.
                out.x = int32_t(floorf(addRn(mulRn(wx, float(kUnits)), 0.5f)));
                out.y = int32_t(floorf(addRn(mulRn(wy, float(kUnits)), 0.5f)));
                out.drawn = 1;
            }
        }
        vertices[v] = out;
    }
};

// One thread per triangle: its box of candidate pixels, orientation and depth weights.
struct SetupTriangles {
    const DepthRasterVertex* vertices;
    const uint32_t* triangles;
    DepthRasterTriangle* setup;
    int64_t last_x, last_y;  // viewport size - 1

    OCC_HD void operator()(uint32_t t) const {
        // Most triangles of a detailed occluder cover no pixel centre: leave as early as possible.
        setup[t].x_lo = 1, setup[t].x_hi = 0;
        const DepthRasterVertex c0 = vertices[triangles[3 * t]], c1 = vertices[triangles[3 * t + 1]],
                                c2 = vertices[triangles[3 * t + 2]];
        if (!(c0.drawn & c1.drawn & c2.drawn)) return;

        // A covered centre is at least the margin inside every edge, so inside the snapped
        // box shrunk by the margin: 256*x + 128 in [min + margin, max - margin].
        const int64_t x_min = min64(c0.x, min64(c1.x, c2.x)), x_max = max64(c0.x, max64(c1.x, c2.x));
        const int64_t y_min = min64(c0.y, min64(c1.y, c2.y)), y_max = max64(c0.y, max64(c1.y, c2.y));
        const int64_t x_lo = max64(0, -floorDiv(-(x_min + kMargin - kHalfPixel), kUnits));
        const int64_t x_hi = min64(last_x, floorDiv(x_max - kMargin - kHalfPixel, kUnits));
        const int64_t y_lo = max64(0, -floorDiv(-(y_min + kMargin - kHalfPixel), kUnits));
        const int64_t y_hi = min64(last_y, floorDiv(y_max - kMargin - kHalfPixel, kUnits));
        if (x_lo > x_hi || y_lo > y_hi) return;

        int64_t area2 = int64_t(c1.x - c0.x) * (c2.y - c0.y) - int64_t(c1.y - c0.y) * (c2.x - c0.x);
        if (area2 == 0) return;
        // Both windings are drawn: store it counter-clockwise.
        const DepthRasterVertex& second = area2 > 0 ? c1 : c2;
        const DepthRasterVertex& third = area2 > 0 ? c2 : c1;
        const float inv_area = divRn(1.0f, float(abs64(area2)));
        DepthRasterTriangle s;
        s.x[0] = c0.x, s.x[1] = second.x, s.x[2] = third.x;
        s.y[0] = c0.y, s.y[1] = second.y, s.y[2] = third.y;
        s.weight[0] = mulRn(c0.z, inv_area);
        s.weight[1] = mulRn(second.z, inv_area);
        s.weight[2] = mulRn(third.z, inv_area);
        // Depth is a convex combination of the corner depths computed with 7 roundings on each
        // path, so for positive corners it is at least z_min * (1 - 7 * 2^-24) > z_min * (1 - 2^-21).
        // (Tiny and negative depths get no bound.)
        const float z_min = minf(c0.z, minf(c1.z, c2.z));
        s.lower_bound = z_min > 1.0e-30f ? mulRn(z_min, 1.0f - 1.0f / (1 << 20)) : -kFar;
        s.x_lo = uint16_t(x_lo), s.x_hi = uint16_t(x_hi);
        s.y_lo = uint16_t(y_lo), s.y_hi = uint16_t(y_hi);
        setup[t] = s;
    }
};

// Binning is a counting sort by tile, without atomics: the triangles are cut into chunks, each
// chunk counts its triangles per tile (one thread per chunk, so the chunk's column of the
// tile-major count matrix is its own), a scan of the matrix turns counts into offsets, and
// each chunk writes its triangles there. Every tile's triangles end up contiguous and in index
// order, whatever the thread count. (Emitting (tile, triangle) pairs and sort_by_key did the
// same slower: Thrust's TBB sort allocates and copies its temporaries on every call, which
// with the sort itself was a quarter of a call on 1.7 M triangles.)
struct ChunkGrid {
    uint32_t tri_count, chunk_size, chunk_count, tiles_x;

    OCC_HD uint32_t chunkBegin(uint32_t chunk) const {
        const uint64_t begin = uint64_t(chunk) * chunk_size;
        return begin < tri_count ? uint32_t(begin) : tri_count;
    }
    OCC_HD uint32_t chunkEnd(uint32_t chunk) const { return chunkBegin(chunk + 1); }
    OCC_HD uint64_t cell(uint32_t tx, uint32_t ty, uint32_t chunk) const {
        return (uint64_t(ty) * tiles_x + tx) * chunk_count + chunk;
    }
};

struct CountPerChunk {
    const DepthRasterTriangle* setup;
    uint64_t* counts;
    ChunkGrid grid;

    OCC_HD void operator()(uint32_t chunk) const {
        for (uint32_t t = grid.chunkBegin(chunk); t < grid.chunkEnd(chunk); ++t) {
            const DepthRasterTriangle& s = setup[t];
            if (s.x_lo > s.x_hi) continue;
            for (uint32_t ty = s.y_lo / kTile; ty <= s.y_hi / kTile; ++ty)
                for (uint32_t tx = s.x_lo / kTile; tx <= s.x_hi / kTile; ++tx) ++counts[grid.cell(tx, ty, chunk)];
        }
    }
};

// After the scan, cursor[cell] is where the chunk's next triangle for that tile goes. Once every
// chunk is done, cursor[cell] is the end of the cell, so a tile's triangles are
// [end of the previous tile's last cell, end of its own last cell).
struct FillPerChunk {
    const DepthRasterTriangle* setup;
    uint64_t* cursor;
    uint32_t* pair_triangle;
    ChunkGrid grid;

    OCC_HD void operator()(uint32_t chunk) const {
        for (uint32_t t = grid.chunkBegin(chunk); t < grid.chunkEnd(chunk); ++t) {
            const DepthRasterTriangle& s = setup[t];
            if (s.x_lo > s.x_hi) continue;
            for (uint32_t ty = s.y_lo / kTile; ty <= s.y_hi / kTile; ++ty)
                for (uint32_t tx = s.x_lo / kTile; tx <= s.x_hi / kTile; ++tx)
                    pair_triangle[cursor[grid.cell(tx, ty, chunk)]++] = t;
        }
    }
};

// One thread per tile: draws its triangles into a tile-sized buffer with edge functions
// stepped in exact integers, then writes the tile out. The minimum makes the order of
// triangles irrelevant.
struct RasterTiles {
    const DepthRasterTriangle* setup;
    const uint32_t* pair_triangle;
    const uint64_t* cell_end;  // the cursors once FillPerChunk is done
    float* depth;
    uint32_t width, height, tiles_x, chunk_count;

    // Whether every pixel of the box (tile coordinates, inclusive) is already at or nearer
    // than `bound`; gives up at the first that is not.
    OCC_HD static bool hidden(const float* nearest, float bound, uint32_t x_lo, uint32_t x_hi, uint32_t y_lo,
                              uint32_t y_hi) {
        for (uint32_t y = y_lo; y <= y_hi; ++y)
            for (uint32_t x = x_lo; x <= x_hi; ++x)
                if (nearest[y * kTile + x] > bound) return false;
        return true;
    }

    OCC_HD void operator()(uint32_t tile) const {
        const uint32_t px0 = tile % tiles_x * kTile, py0 = tile / tiles_x * kTile;
        const uint32_t px1 = px0 + kTile < width ? px0 + kTile : width;
        const uint32_t py1 = py0 + kTile < height ? py0 + kTile : height;
        // Nearest depth so far before the epsilon, which is added once at the end: rounding is
        // monotonic, so min(a + eps, b + eps) = min(a, b) + eps.
        float nearest[kTile * kTile];
        for (uint32_t i = 0; i < kTile * kTile; ++i) nearest[i] = kFar;

        const uint64_t begin = tile == 0 ? 0 : cell_end[uint64_t(tile) * chunk_count - 1];
        const uint64_t end = cell_end[uint64_t(tile + 1) * chunk_count - 1];
        for (uint64_t i = begin; i < end; ++i) {
            if (i + kPrefetchDistance < end) prefetch(&setup[pair_triangle[i + kPrefetchDistance]]);
            const DepthRasterTriangle& s = setup[pair_triangle[i]];
            const uint32_t x_lo = s.x_lo > px0 ? s.x_lo : px0, x_hi = s.x_hi < px1 - 1 ? s.x_hi : px1 - 1;
            const uint32_t y_lo = s.y_lo > py0 ? s.y_lo : py0, y_hi = s.y_hi < py1 - 1 ? s.y_hi : py1 - 1;
            if (x_lo > x_hi || y_lo > y_hi) continue;
            if (hidden(nearest, s.lower_bound, x_lo - px0, x_hi - px0, y_lo - py0, y_hi - py0)) continue;

            // Edge k is the one opposite corner k, from corner k+1 to corner k+2:
            // e_k(p) = (b - a) x (p - a), positive inside a counter-clockwise triangle.
            int64_t row[3], step_x[3], step_y[3], threshold[3];
            const int64_t cx = int64_t(x_lo) * kUnits + kHalfPixel, cy = int64_t(y_lo) * kUnits + kHalfPixel;
            for (int k = 0; k < 3; ++k) {
                const int a = (k + 1) % 3, b = (k + 2) % 3;
                const int64_t ex = int64_t(s.x[b]) - s.x[a], ey = int64_t(s.y[b]) - s.y[a];
                row[k] = ex * (cy - s.y[a]) - ey * (cx - s.x[a]);
                step_x[k] = -ey * kUnits;
                step_y[k] = ex * kUnits;
                // distance = e / |edge|_2 >= margin, made integer by |edge|_1 >= |edge|_2
                threshold[k] = kMargin * (abs64(ex) + abs64(ey));
            }
            for (uint32_t y = y_lo; y <= y_hi; ++y) {
                int64_t e0 = row[0], e1 = row[1], e2 = row[2];
                float* out = nearest + (y - py0) * kTile - px0;
                for (uint32_t x = x_lo; x <= x_hi; ++x) {
                    // Without branches, since whether a centre is covered is close to random
                    // for the small triangles that dominate: all three e_k - threshold_k are
                    // non-negative when their OR is, and an uncovered centre's candidate is
                    // pushed beyond every depth.
                    const int64_t outside = (e0 - threshold[0]) | (e1 - threshold[1]) | (e2 - threshold[2]);
                    const float d = addRn(addRn(mulRn(float(e0), s.weight[0]), mulRn(float(e1), s.weight[1])),
                                          mulRn(float(e2), s.weight[2]));
                    const float candidate = addRn(d, mulRn(float(uint64_t(outside) >> 63), kFar));
                    out[x] = candidate < out[x] ? candidate : out[x];
                    e0 += step_x[0], e1 += step_x[1], e2 += step_x[2];
                }
                row[0] += step_y[0], row[1] += step_y[1], row[2] += step_y[2];
            }
        }

        for (uint32_t y = py0; y < py1; ++y)
            for (uint32_t x = px0; x < px1; ++x) {
                const float d = addRn(nearest[(y - py0) * kTile + (x - px0)], kDepthRasterEpsilon);
                depth[uint64_t(y) * width + x] = d < 1.0f ? d : 1.0f;
            }
    }
};

}  // namespace

void depthRaster(const glm::vec3* positions, const uint32_t* triangles, uint32_t tri_count,
                 const Camera& camera, float* depth, DepthRasterScratch& scratch) {
    const uint32_t width = camera.width, height = camera.height;
    if (width > kMaxSide || height > kMaxSide)
        throw std::invalid_argument("depthRaster: viewport " + std::to_string(width) + "x" + std::to_string(height) +
                                    " is larger than 32768x32768");
    if (width == 0 || height == 0) return;
    const uint32_t tiles_x = (width + kTile - 1) / kTile, tiles_y = (height + kTile - 1) / kTile;
    const uint32_t tile_count = tiles_x * tiles_y;
    const thrust::counting_iterator<uint32_t> first(0);

    // Enough chunks to keep every core busy, few enough that the count matrix stays small.
    const uint64_t wanted_chunks = (tri_count + kChunkTriangles - 1) / kChunkTriangles;
    const uint32_t chunk_count = uint32_t(std::max<uint64_t>(1, std::min(wanted_chunks, kMaxCountCells / tile_count)));
    const ChunkGrid grid{tri_count, (tri_count + chunk_count - 1) / chunk_count, chunk_count, tiles_x};
    const uint64_t cell_count = uint64_t(tile_count) * chunk_count;
    scratch.cells.resize(cell_count + 1);
    uint64_t* cells = scratch.cells.data();
    thrust::fill(thrust::device, cells, cells + cell_count + 1, uint64_t(0));

    if (tri_count > 0) {
        const uint32_t vertex_count = thrust::reduce(thrust::device, triangles, triangles + uint64_t(tri_count) * 3,
                                                     0u, thrust::maximum<uint32_t>()) + 1;
        scratch.vertices.resize(vertex_count);
        scratch.setup.resize(tri_count);
        ProjectVertices project{positions, scratch.vertices.data(), {}, float(width), float(height)};
        for (int i = 0; i < 16; ++i) project.m[i] = camera.view_proj[i / 4][i % 4];
        thrust::for_each_n(thrust::device, first, vertex_count, project);
        thrust::for_each_n(thrust::device, first, tri_count,
                           SetupTriangles{scratch.vertices.data(), triangles, scratch.setup.data(), int64_t(width) - 1,
                                          int64_t(height) - 1});
        thrust::for_each_n(thrust::device, first, chunk_count, CountPerChunk{scratch.setup.data(), cells, grid});
        // One more cell than there are, counting 0, so that the scan leaves the total there.
        thrust::exclusive_scan(thrust::device, cells, cells + cell_count + 1, cells);
        kernelSynchronize();
        scratch.pair_triangle.resize(cells[cell_count]);
        thrust::for_each_n(thrust::device, first, chunk_count,
                           FillPerChunk{scratch.setup.data(), cells, scratch.pair_triangle.data(), grid});
    }
    thrust::for_each_n(thrust::device, first, tile_count,
                       RasterTiles{scratch.setup.data(), scratch.pair_triangle.data(), cells, depth, width, height,
                                   tiles_x, chunk_count});
    kernelSynchronize();
}

}  // namespace occ::k
