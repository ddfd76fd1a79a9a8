// SPDX-License-Identifier: MIT
#pragma once

// What the two occluder rasters share (kernels/depth_raster.cu, the exact per-pixel reference,
// and kernels/masked_raster.cu, the coverage-mask raster the pipeline uses): the projected and
// set-up triangles, the rounding-exact arithmetic they are built with, the front end that makes
// them (projection, snapping, triangle setup, seams) and the binning of triangles to screen
// tiles. Kernel code only: src/ and roles/ call the rasters through depth_raster.h and
// masked_raster.h.

#include "depth_raster.h"
#include "host_device.h"

#include <cstdint>
#include <cstring>

namespace occ::k {

// One vertex after projection and snapping (every triangle corner reads it).
struct DepthRasterVertex {
    int32_t x, y;    // window position in 1/256 pixel
    float z;         // window depth
    uint32_t drawn;  // 0 when the rules skip every triangle using it
};
static_assert(sizeof(DepthRasterVertex) == 16);

// One triangle after projection and snapping, as the tiles read it: 52 bytes, padded to a cache
// line (alignas) since tiles read triangles in scattered order and one line per triangle is
// the least they can touch.
struct alignas(64) DepthRasterTriangle {
    int32_t x[3], y[3];  // window position in 1/256 pixel, counter-clockwise (y up)
    // The depth written at pixel (px, py) is the plane
    //   (z_ref + gy * (py - y_lo)) + gx * (px - x_lo)
    // in float arithmetic, in that order: z_ref, the plane at the centre of pixel (x_lo, y_lo),
    // already carries the push away (kDepthRasterEpsilon plus a bound on that arithmetic's
    // rounding), so what is written is never nearer than the triangle.
    float z_ref, gx, gy;
    // The nearest corner depth: below every depth the triangle writes, so a triangle whose box
    // is already at least that near everywhere changes nothing and can be passed over.
    float lower_bound;
    // Pixels whose centres may be covered, inclusive, clamped to the viewport (x_lo <= x_hi and
    // y_lo <= y_hi: the setup writes only triangles that have one, DepthRasterScratch::drawn).
    uint16_t x_lo, y_lo, x_hi, y_hi;
    // Bit k set: edge k (opposite corner k) is shared within its mesh or across a seam, so it
    // takes the tie rule instead of the margin. Bit raster::kReversedBit: the stored corners 1
    // and 2 are the input's 2 and 1 (the input was clockwise on screen).
    uint32_t shared_edges;
};
static_assert(sizeof(DepthRasterTriangle) == 64);

namespace raster {

// Arithmetic without fused multiply-adds: nvcc contracts a*b+c in device code by default while
// g++ for our x86-64 target does not, and the raster must be the same bits on both back ends
// (and its rounding bounds must hold).
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

OCC_HD inline double mulRn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __dmul_rn(a, b);
#else
    return a * b;
#endif
}
OCC_HD inline double addRn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __dadd_rn(a, b);
#else
    return a + b;
#endif
}
OCC_HD inline double divRn(double a, double b) {
#if defined(__CUDA_ARCH__)
    return __ddiv_rn(a, b);
#else
    return a / b;
#endif
}

OCC_HD inline int64_t floorDiv(int64_t a, int64_t b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
OCC_HD inline int64_t abs64(int64_t a) { return a < 0 ? -a : a; }
OCC_HD inline int64_t min64(int64_t a, int64_t b) { return a < b ? a : b; }
OCC_HD inline int64_t max64(int64_t a, int64_t b) { return a > b ? a : b; }

constexpr int64_t kUnits = kDepthRasterSubpixelUnits;
constexpr int64_t kHalfPixel = kUnits / 2;
constexpr int64_t kMargin = kDepthRasterMarginUnits;
constexpr uint32_t kReversedBit = 8;

// The exact raster's tiles (kDepthRasterTileSize pixels square, the unit of parallel work).
constexpr uint32_t kTile = kDepthRasterTileSize;
// Far above every depth a covered pixel can get (corners are at most kDepthRasterMaxDepth) and
// every value the plane takes over a box: no triangle yet.
constexpr float kFar = 3.0e38f;

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

// The three edge functions of a set-up triangle, exactly as both rasters test a pixel centre.
// Edge k is the one opposite corner k, from corner k+1 to corner k+2:
// e_k(p) = (b - a) x (p - a), positive inside a counter-clockwise triangle, and a centre is
// covered when e_k >= threshold_k for every k.
struct EdgeFunctions {
    int64_t ex[3], ey[3], ax[3], ay[3], threshold[3];

    OCC_HD explicit EdgeFunctions(const DepthRasterTriangle& s) {
        for (int k = 0; k < 3; ++k) {
            const int a = (k + 1) % 3, b = (k + 2) % 3;
            ex[k] = int64_t(s.x[b]) - s.x[a], ey[k] = int64_t(s.y[b]) - s.y[a];
            ax[k] = s.x[a], ay[k] = s.y[a];
            if (s.shared_edges >> k & 1u) {
                // The top-left rule (D3D's), for counter-clockwise triangles with y up: a
                // centre on the edge belongs to this triangle when the edge is a left edge
                // (going down) or a top edge (horizontal, going left). The neighbour across
                // it runs it the other way, its edge function exactly negated, so exactly
                // one of the two covers each centre on it.
                threshold[k] = ey[k] < 0 || (ey[k] == 0 && ex[k] < 0) ? 0 : 1;
            } else {
                // distance = e / |edge|_2 >= margin, made integer by |edge|_1 >= |edge|_2
                threshold[k] = kMargin * (abs64(ex[k]) + abs64(ey[k]));
            }
        }
    }
    // e_k - threshold_k at the centre of pixel (px, py): non-negative inside edge k.
    OCC_HD int64_t inside(int k, int64_t px, int64_t py) const {
        const int64_t cx = px * kUnits + kHalfPixel, cy = py * kUnits + kHalfPixel;
        return ex[k] * (cy - ay[k]) - ey[k] * (cx - ax[k]) - threshold[k];
    }
    OCC_HD bool covers(int64_t px, int64_t py) const {
        return (inside(0, px, py) | inside(1, px, py) | inside(2, px, py)) >= 0;
    }
    // Whether a centre of the pixel box [x_lo, x_hi] x [y_lo, y_hi] may be covered: false when,
    // for some edge, even the box's corner farthest inside it is outside (inside() grows with x
    // where ey < 0 and with y where ex > 0). Long thin triangles cross most tiles of their
    // pixel box nowhere: on the 10^4 plant walk, 6 (tile, triangle) pairs in 10.
    OCC_HD bool mayCover(int64_t x_lo, int64_t x_hi, int64_t y_lo, int64_t y_hi) const {
        for (int k = 0; k < 3; ++k)
            if (inside(k, ey[k] < 0 ? x_hi : x_lo, ex[k] > 0 ? y_hi : y_lo) < 0) return false;
        return true;
    }
};

// The plane's value at pixel (px, py) of the triangle's box, in the float arithmetic and order
// that depthRaster writes it.
OCC_HD inline float planeDepth(const DepthRasterTriangle& s, uint32_t px, uint32_t py) {
    const float row_depth = addRn(s.z_ref, mulRn(s.gy, float(int32_t(py - s.y_lo))));
    return addRn(row_depth, mulRn(s.gx, float(int32_t(px - s.x_lo))));
}

}  // namespace raster

// The front end both rasters share: projects, snaps and sets up the triangles as depthRaster's
// contract says (skip rules, margins, shared edges, seams when `seams`) into scratch.vertices
// and scratch.setup, with scratch.drawn[t] = 1 where setup[t] holds a triangle whose box has
// a pixel centre and 0 where the triangle is skipped (setup[t] then stale), and those drawn
// triangles listed in ascending order in scratch.drawn_ids (scratch.drawn_count), their setup
// copied to scratch.drawn_setup in that order (seams applied there): the later passes read
// that dense copy, not the sparse lines of scratch.setup. tri_count > 0.
void depthRasterSetup(const glm::vec3* positions, const uint32_t* triangles, uint32_t tri_count,
                      const uint8_t* edge_flags, const uint32_t* edge_neighbours, const Camera& camera,
                      DepthRasterScratch& scratch, bool seams);

// Throws std::invalid_argument naming `who` when the viewport is beyond the HZM's 32768 limit
// (which also keeps pixel boxes within 16 bits).
void checkRasterViewport(const Camera& camera, const char* who);

// Screen tiles of (1 << tile_w_log2) x (1 << tile_h_log2) pixels and the triangles overlapping
// each, as binTriangles leaves them in the scratch: tile t = ty * tiles_x + tx lists the
// positions in the drawn list (scratch.drawn_setup) pair_triangle[tileBegin(t), tileEnd(t)),
// in increasing order.
struct TileBins {
    uint32_t tile_w_log2, tile_h_log2, tiles_x, tiles_y, chunk_count;
    const uint64_t* cell_end;  // scratch.cells once binning is done
    const uint32_t* pair_triangle;

    OCC_HD uint64_t tileBegin(uint32_t tile) const { return tile == 0 ? 0 : cell_end[uint64_t(tile) * chunk_count - 1]; }
    OCC_HD uint64_t tileEnd(uint32_t tile) const { return cell_end[uint64_t(tile + 1) * chunk_count - 1]; }
};

// Bins the drawn triangles of scratch.setup (those scratch.drawn_ids lists, as the setup left
// it; none when tri_count is 0) to the tiles of a width x height viewport, by the pixel box of
// each (x_lo..x_hi, y_lo..y_hi). Deterministic.
TileBins binTriangles(uint32_t tri_count, uint32_t width, uint32_t height, uint32_t tile_w_log2,
                      uint32_t tile_h_log2, DepthRasterScratch& scratch);

// The exact raster's tiles of kTile x kTile pixels, as the tile loops take them: the set-up
// triangles binned to them, and the depth buffer to fill.
struct DepthTiles {
    const DepthRasterTriangle* setup;
    TileBins bins;
    float* depth;
    uint32_t width, height;
};

#if !defined(__CUDACC__)
// The CPU's first look at triangles [begin, end) (kernels/depth_raster_cpu.cpp), a vector of
// them at a time: writes to out, in increasing order, those whose three corners are drawn, whose
// snapped area is not 0, that are not back faces they may skip (edge_flags, which may be null),
// and whose snapped box holds the centre of a pixel in [0, last_x] x [0, last_y] (the box shrunk
// by the margin when their flags share no edge), and returns how many. Every triangle the setup
// draws is among them: these are its own tests, before the neighbours across shared edges may
// take the sharing away.
uint32_t setupCandidatesCpu(const DepthRasterVertex* vertices, const uint32_t* triangles, const uint8_t* edge_flags,
                            uint32_t begin, uint32_t end, int32_t last_x, int32_t last_y, uint32_t* out);
// One occluder's vertices as rasterOccluders' CPU front end transforms and projects them: its
// world matrix and the camera's view_proj (column-major, m[4 * column + row]), the viewport,
// and nearPlaneRow.
struct OccluderVertexJob {
    float world[16];
    float view_proj[16];
    float width, height;
    float near_row[4];
};
// The first count - count % lanes of src[0, count) (object space), a vector at a time
// (kernels/depth_raster_cpu.cpp): world[i] = occluderVertex, front[i] = inFrontOfNearPlane,
// out[i] = ProjectVertices' vertex of world[i], in the same float operations, so the same bits.
// Returns how many it did (the caller does the rest one by one) and their count in front.
uint32_t transformProjectCpu(const OccluderVertexJob& job, const glm::vec3* src, uint32_t count, glm::vec3* world,
                             DepthRasterVertex* out, uint8_t* front, uint32_t& in_front);
// The CPU's tile loop (kernels/depth_raster_cpu.cpp): every tile in parallel, in SIMD, the same
// bits as the one-thread-per-tile loop of depth_raster.cu.
void depthRasterTilesCpu(const DepthTiles& tiles);
// The instruction set that loop runs with on this machine (simdLevelName).
const char* depthRasterCpuTarget();
#endif

}  // namespace occ::k
