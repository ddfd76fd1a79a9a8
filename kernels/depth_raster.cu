// SPDX-License-Identifier: MIT
#include "depth_raster.h"
#include "raster_setup.h"

#include "device_access.h"
#include "for_each_index.h"

#include "hzm.h"
#include "occluder_gather.h"
#include "device_policy.h"

#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/for_each.h>
#include <thrust/functional.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/copy.h>
#include <thrust/reduce.h>
#include <thrust/sort.h>
#include <thrust/scan.h>

#if !defined(__CUDACC__)
#include <tbb/parallel_for.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

namespace occ::k {

namespace {

using namespace raster;

// Triangles per binning chunk (a thread each), and a cap on the tile x chunk count matrix (32
// MB). A GPU wants tens of thousands of threads: 32 triangles a chunk there, against 4 096 for
// the CPU's few cores (the bins come out the same, each tile's triangles in index order).
#if defined(__CUDACC__)
constexpr uint64_t kChunkTriangles = 32;
#else
constexpr uint64_t kChunkTriangles = 4096;
#endif
constexpr uint64_t kMaxCountCells = uint64_t(1) << 22;

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
        // Comparisons that fail on NaN, so that NaNs skip too.
        if (clip[3] > 0.0f && clip[2] >= -clip[3]) {
            const float inv_w = divRn(1.0f, clip[3]);
            const float wx = mulRn(addRn(mulRn(mulRn(clip[0], inv_w), 0.5f), 0.5f), width);
            const float wy = mulRn(addRn(mulRn(mulRn(clip[1], inv_w), 0.5f), 0.5f), height);
            out.z = addRn(mulRn(mulRn(clip[2], inv_w), 0.5f), 0.5f);
            if (fabsf(wx) <= kDepthRasterGuardBand && fabsf(wy) <= kDepthRasterGuardBand &&
                out.z <= kDepthRasterMaxDepth) {
                // Inside the guard band, so exact in float after scaling by 256 and within int32.
                out.x = int32_t(floorf(addRn(mulRn(wx, float(kUnits)), 0.5f)));
                out.y = int32_t(floorf(addRn(mulRn(wy, float(kUnits)), 0.5f)));
                out.drawn = 1;
            }
        }
        vertices[v] = out;
    }
};

// One thread per triangle: its box of candidate pixels, orientation and depth plane.
struct SetupTriangles {
    const DepthRasterVertex* vertices;
    const uint32_t* triangles;
    const uint8_t* edge_flags;  // may be null
    const uint32_t* neighbours;  // may be null: 3 per triangle, the triangle across each edge
    uint32_t tri_count;
    DepthRasterTriangle* setup;
    // Per triangle, 1 when setup[t] was written (the triangle is drawn and its box holds a pixel
    // centre), else 0 and setup[t] left as it was: most occluder triangles are skipped or cover
    // no centre, and the passes after this one read their byte, not their 64-byte line.
    uint8_t* drawn;
    int64_t last_x, last_y;  // viewport size - 1
    // A second pass over some drawn triangles (seams): null, or the positions in the drawn
    // list (DepthRasterScratch::drawn_ids, drawn_setup) of the triangles to set up again, with
    // per position the stored edges found shared across a seam, which then take the tie rule
    // and no box margin. The pass writes drawn_setup[position] instead of setup[t].
    const uint32_t* only = nullptr;
    const uint32_t* drawn_ids = nullptr;
    const uint8_t* seam_edges = nullptr;
    DepthRasterTriangle* drawn_setup = nullptr;

    // The pixels whose centres lie in the snapped box [x_min, x_max] x [y_min, y_max] shrunk by
    // `margin`, within the viewport (empty when lo > hi).
    OCC_HD void pixelBox(int64_t x_min, int64_t x_max, int64_t y_min, int64_t y_max, int64_t margin, int64_t& x_lo,
                         int64_t& x_hi, int64_t& y_lo, int64_t& y_hi) const {
        x_lo = max64(0, -floorDiv(-(x_min + margin - kHalfPixel), kUnits));
        x_hi = min64(last_x, floorDiv(x_max - margin - kHalfPixel, kUnits));
        y_lo = max64(0, -floorDiv(-(y_min + margin - kHalfPixel), kUnits));
        y_hi = min64(last_y, floorDiv(y_max - margin - kHalfPixel, kUnits));
    }

    OCC_HD void operator()(uint32_t i) const {
        const uint32_t position = only ? only[i] : 0u;
        const uint32_t t = only ? drawn_ids[position] : i;
        // Most triangles of a detailed occluder cover no pixel centre: leave as early as possible.
        drawn[t] = 0;
        const DepthRasterVertex c0 = vertices[triangles[3 * t]], v1 = vertices[triangles[3 * t + 1]],
                                v2 = vertices[triangles[3 * t + 2]];
        if (!(c0.drawn & v1.drawn & v2.drawn)) return;
        int64_t area2 = int64_t(v1.x - c0.x) * (v2.y - c0.y) - int64_t(v1.y - c0.y) * (v2.x - c0.x);
        if (area2 == 0) return;
        // A back face of a closed mesh seen from outside: its front faces are nearer wherever it is.
        if (area2 < 0 && edge_flags && (edge_flags[t] & kEdgeFlagSkipBackFace)) return;
        // Most triangles hold no pixel centre even without a margin: leave before the
        // neighbours' corners are fetched.
        const int64_t x_min = min64(c0.x, min64(v1.x, v2.x)), x_max = max64(c0.x, max64(v1.x, v2.x));
        const int64_t y_min = min64(c0.y, min64(v1.y, v2.y)), y_max = max64(c0.y, max64(v1.y, v2.y));
        int64_t x_lo, x_hi, y_lo, y_hi;
        pixelBox(x_min, x_max, y_min, y_max, 0, x_lo, x_hi, y_lo, y_hi);
        if (x_lo > x_hi || y_lo > y_hi) return;
        uint32_t flags = edge_flags ? edge_flags[t] & 7u : 0u;
        // A shared edge is inside the occluder's image only when the neighbour across it is
        // drawn too and faces the same way on screen: then the two lie on either side of it.
        // Where the surface folds over (a silhouette: one faces the viewer, one away, both on
        // the same side) or the neighbour is skipped, the edge is a boundary and keeps the margin.
        if (flags && neighbours) {
            for (uint32_t e = 0; e < 3; ++e) {
                if (!(flags >> e & 1u)) continue;
                const uint32_t n = neighbours[3 * t + e];
                bool inside = n < tri_count;
                if (inside) {
                    const DepthRasterVertex n0 = vertices[triangles[3 * n]], n1 = vertices[triangles[3 * n + 1]],
                                            n2 = vertices[triangles[3 * n + 2]];
                    const int64_t n_area2 =
                        int64_t(n1.x - n0.x) * (n2.y - n0.y) - int64_t(n1.y - n0.y) * (n2.x - n0.x);
                    inside = (n0.drawn & n1.drawn & n2.drawn) && (n_area2 > 0) == (area2 > 0) && n_area2 != 0;
                }
                if (!inside) flags &= ~(1u << e);
            }
        }

        // A covered centre is at least the margin inside every edge, so inside the snapped
        // box shrunk by the margin: 256*x + 128 in [min + margin, max - margin]. (The box side
        // at a corner is that far in when both edges at the corner keep the margin; shrinking
        // only triangles without a shared edge keeps it simple and loses next to nothing.)
        const uint32_t seams = only ? seam_edges[position] : 0u;
        if (!flags && !seams) {
            pixelBox(x_min, x_max, y_min, y_max, kMargin, x_lo, x_hi, y_lo, y_hi);
            if (x_lo > x_hi || y_lo > y_hi) return;
        }

        // Both windings are drawn: store it counter-clockwise.
        const bool reversed = area2 < 0;
        const DepthRasterVertex& c1 = reversed ? v2 : v1;
        const DepthRasterVertex& c2 = reversed ? v1 : v2;
        area2 = abs64(area2);
        DepthRasterTriangle s;
        s.x[0] = c0.x, s.x[1] = c1.x, s.x[2] = c2.x;
        s.y[0] = c0.y, s.y[1] = c1.y, s.y[2] = c2.y;
        s.x_lo = uint16_t(x_lo), s.x_hi = uint16_t(x_hi);
        s.y_lo = uint16_t(y_lo), s.y_hi = uint16_t(y_hi);
        // Edge k of the stored triangle runs between its corners k+1 and k+2: edge 0 is the
        // input's edge 1 either way, edges 1 and 2 are the input's 2 and 0, or 0 and 2 when the
        // winding was reversed.
        const uint32_t e0 = flags & 1u, e1 = flags >> 1 & 1u, e2 = flags >> 2 & 1u;
        s.shared_edges = (reversed ? e1 | e0 << 1 | e2 << 2 : e1 | e2 << 1 | e0 << 2) | seams | (reversed ? kReversedBit : 0u);

        // The depth plane through the snapped corners, in double (the integers are exact there),
        // per 1/256 pixel: z = z0 + gx * (X - X0) + gy * (Y - Y0) by Cramer's rule.
        const double d1x = double(c1.x - c0.x), d1y = double(c1.y - c0.y);
        const double d2x = double(c2.x - c0.x), d2y = double(c2.y - c0.y);
        const double dz1 = addRn(double(c1.z), -double(c0.z)), dz2 = addRn(double(c2.z), -double(c0.z));
        const double area = double(area2);
        const double gx = divRn(addRn(mulRn(dz1, d2y), -mulRn(dz2, d1y)), area);
        const double gy = divRn(addRn(mulRn(d1x, dz2), -mulRn(d2x, dz1)), area);
        const double ref = addRn(addRn(double(c0.z), mulRn(gx, double(x_lo * kUnits + kHalfPixel - c0.x))),
                                 mulRn(gy, double(y_lo * kUnits + kHalfPixel - c0.y)));
        s.gx = float(mulRn(gx, double(kUnits)));
        s.gy = float(mulRn(gy, double(kUnits)));
        // Every value in the float evaluation of the plane is at most `magnitude`, so its
        // rounding stays below 8 * 2^-24 * magnitude; push by twice that on top of the epsilon.
        const float magnitude = addRn(addRn(maxf(fabsf(c0.z), maxf(fabsf(c1.z), fabsf(c2.z))),
                                            mulRn(fabsf(s.gx), float(x_hi - x_lo + 1))),
                                      mulRn(fabsf(s.gy), float(y_hi - y_lo + 1)));
        const float push = addRn(kDepthRasterEpsilon, mulRn(magnitude, 1.0f / (1 << 20)));
        s.z_ref = float(addRn(ref, double(push)));
        s.lower_bound = minf(c0.z, minf(c1.z, c2.z));
        (only ? drawn_setup[position] : setup[t]) = s;
        drawn[t] = 1;
    }
};

// Seams between occluders. A boundary edge is one of a drawn triangle (one whose box holds a
// pixel centre) that keeps the margin there; each is keyed by its two world-space endpoints
// taken in either order, so that the two sides of a seam get the same key.
OCC_HD inline uint32_t boundaryEdges(const DepthRasterTriangle& s) { return 7u & ~s.shared_edges; }

// The vertex indices of stored edge k of triangle t: from stored corner k+1 to k+2.
OCC_HD inline void storedEdge(const uint32_t* triangles, const DepthRasterTriangle& s, uint32_t t, uint32_t k,
                              uint32_t& a, uint32_t& b) {
    const bool reversed = (s.shared_edges & kReversedBit) != 0;
    uint32_t c[3] = {triangles[3 * t], triangles[3 * t + 1], triangles[3 * t + 2]};
    if (reversed) {
        const uint32_t x = c[1];
        c[1] = c[2];
        c[2] = x;
    }
    a = c[(k + 1) % 3];
    b = c[(k + 2) % 3];
}

OCC_HD inline uint32_t floatBits(float f) {
    uint32_t u;
    memcpy(&u, &f, 4);
    return u;
}

// Whether point p comes before q in a fixed order of bit patterns (any total order will do).
OCC_HD inline bool pointBefore(const glm::vec3& p, const glm::vec3& q) {
    const uint32_t a[3] = {floatBits(p.x), floatBits(p.y), floatBits(p.z)};
    const uint32_t b[3] = {floatBits(q.x), floatBits(q.y), floatBits(q.z)};
    for (int i = 0; i < 3; ++i)
        if (a[i] != b[i]) return a[i] < b[i];
    return false;
}

OCC_HD inline bool samePoint(const glm::vec3& p, const glm::vec3& q) {
    return floatBits(p.x) == floatBits(q.x) && floatBits(p.y) == floatBits(q.y) && floatBits(p.z) == floatBits(q.z);
}

OCC_HD inline uint64_t mixBits(uint64_t h, uint32_t v) {
    h ^= v;
    h *= 0x100000001b3ull;  // FNV-1a's prime, then a splitmix64 finaliser below
    return h;
}

OCC_HD inline uint64_t edgeKey(const glm::vec3& p, const glm::vec3& q) {
    const glm::vec3& lo = pointBefore(p, q) ? p : q;
    const glm::vec3& hi = pointBefore(p, q) ? q : p;
    uint64_t h = 0xcbf29ce484222325ull;
    h = mixBits(h, floatBits(lo.x)), h = mixBits(h, floatBits(lo.y)), h = mixBits(h, floatBits(lo.z));
    h = mixBits(h, floatBits(hi.x)), h = mixBits(h, floatBits(hi.y)), h = mixBits(h, floatBits(hi.z));
    h ^= h >> 30, h *= 0xbf58476d1ce4e5b9ull, h ^= h >> 27, h *= 0x94d049bb133111ebull, h ^= h >> 31;
    return h;
}

// The passes from here on take the drawn triangles' list (DepthRasterScratch::drawn_ids and
// drawn_setup): a triangle is its position i there, triangle drawn_ids[i] of the input.
struct GatherDrawn {
    const DepthRasterTriangle* setup;
    const uint32_t* drawn_ids;
    DepthRasterTriangle* drawn_setup;
    OCC_HD void operator()(uint32_t i) const { drawn_setup[i] = setup[drawn_ids[i]]; }
};

struct CountBoundaryEdges {
    const DepthRasterTriangle* setup;  // drawn_setup
    uint32_t* counts;
    OCC_HD void operator()(uint32_t i) const {
        const uint32_t bits = boundaryEdges(setup[i]);
        counts[i] = (bits & 1u) + (bits >> 1 & 1u) + (bits >> 2 & 1u);
    }
};

struct EmitBoundaryEdges {
    const DepthRasterTriangle* setup;  // drawn_setup
    const uint32_t* drawn_ids;
    const uint32_t* triangles;
    const glm::vec3* positions;
    const uint32_t* first;
    uint32_t* ids;  // 3 * position + stored edge
    uint64_t* keys;
    OCC_HD void operator()(uint32_t i) const {
        const uint32_t t = drawn_ids[i];
        const uint32_t bits = boundaryEdges(setup[i]);
        uint32_t at = first[i];
        for (uint32_t k = 0; k < 3; ++k) {
            if (!(bits >> k & 1u)) continue;
            uint32_t a, b;
            storedEdge(triangles, setup[i], t, k, a, b);
            ids[at] = 3 * i + k;
            keys[at] = edgeKey(positions[a], positions[b]);
            ++at;
        }
    }
};

// One thread per boundary edge, in key order: marks its edge when another edge of the same key
// has the same two endpoints the other way round (the triangle across). Neighbours of equal
// key are next to it; a run of equal keys is a handful of edges.
struct MatchSeams {
    const DepthRasterTriangle* setup;  // drawn_setup
    const uint32_t* drawn_ids;
    const uint32_t* triangles;
    const glm::vec3* positions;
    const uint32_t* ids;
    const uint64_t* keys;
    uint32_t count;
    uint8_t* seam_edges;  // 3 per position, each written by the thread of its only boundary entry
    OCC_HD bool across(uint32_t i, const glm::vec3& a, const glm::vec3& b) const {
        const uint32_t p = ids[i] / 3, k = ids[i] % 3;
        uint32_t c, d;
        storedEdge(triangles, setup[p], drawn_ids[p], k, c, d);
        return samePoint(positions[c], b) && samePoint(positions[d], a);
    }
    OCC_HD void operator()(uint32_t i) const {
        // Most keys are unique: nothing to fetch then.
        if (!(i > 0 && keys[i - 1] == keys[i]) && !(i + 1 < count && keys[i + 1] == keys[i])) return;
        const uint32_t p = ids[i] / 3, k = ids[i] % 3;
        uint32_t ia, ib;
        storedEdge(triangles, setup[p], drawn_ids[p], k, ia, ib);
        const glm::vec3 a = positions[ia], b = positions[ib];
        if (samePoint(a, b)) return;
        bool found = false;
        for (uint32_t j = i; j-- > 0 && keys[j] == keys[i] && !found;) found = across(j, a, b);
        for (uint32_t j = i + 1; j < count && keys[j] == keys[i] && !found; ++j) found = across(j, a, b);
        // One byte per (triangle, edge), each written by this edge's thread alone; a second
        // pass packs them per triangle.
        if (found) seam_edges[3 * p + k] = 1;
    }
};

// Per triangle, its three per-edge marks into the bits SetupTriangles takes.
struct GatherSeamBits {
    const uint8_t* marks;  // 3 per position
    uint8_t* bits;
    OCC_HD void operator()(uint32_t i) const {
        bits[i] = uint8_t(marks[3 * i] | marks[3 * i + 1] << 1 | marks[3 * i + 2] << 2);
    }
};

// Whether a triangle's byte is set (drawn, or has seam bits).
struct ByteSet {
    const uint8_t* bits;
    OCC_HD bool operator()(uint32_t t) const { return bits[t] != 0; }
};

// Binning is a counting sort by tile, without atomics: the triangles are cut into chunks, each
// chunk counts its triangles per tile (one thread per chunk, so the chunk's column of the
// tile-major count matrix is its own), a scan of the matrix turns counts into offsets, and
// each chunk writes its triangles there. Every tile's triangles end up contiguous and in index
// order, whatever the thread count. (Emitting (tile, triangle) pairs and sort_by_key did the
// same slower: Thrust's TBB sort allocates and copies its temporaries on every call, which
// with the sort itself was a quarter of a call on 1.7 M triangles.)
struct ChunkGrid {
    uint32_t tri_count, chunk_size, chunk_count, tiles_x;  // tri_count: entries of the drawn list
    uint32_t tile_w_log2, tile_h_log2;

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
    const DepthRasterTriangle* setup;  // drawn_setup
    uint64_t* counts;
    ChunkGrid grid;

    OCC_HD void operator()(uint32_t chunk) const {
        for (uint32_t i = grid.chunkBegin(chunk); i < grid.chunkEnd(chunk); ++i) {
            const DepthRasterTriangle& s = setup[i];
            for (uint32_t ty = s.y_lo >> grid.tile_h_log2; ty <= uint32_t(s.y_hi) >> grid.tile_h_log2; ++ty)
                for (uint32_t tx = s.x_lo >> grid.tile_w_log2; tx <= uint32_t(s.x_hi) >> grid.tile_w_log2; ++tx)
                    ++counts[grid.cell(tx, ty, chunk)];
        }
    }
};

// After the scan, cursor[cell] is where the chunk's next triangle for that tile goes. Once every
// chunk is done, cursor[cell] is the end of the cell, so a tile's triangles are
// [end of the previous tile's last cell, end of its own last cell).
struct FillPerChunk {
    const DepthRasterTriangle* setup;  // drawn_setup
    uint64_t* cursor;
    uint32_t* pair_triangle;  // positions in the drawn list
    ChunkGrid grid;

    OCC_HD void operator()(uint32_t chunk) const {
        for (uint32_t i = grid.chunkBegin(chunk); i < grid.chunkEnd(chunk); ++i) {
            const DepthRasterTriangle& s = setup[i];
            for (uint32_t ty = s.y_lo >> grid.tile_h_log2; ty <= uint32_t(s.y_hi) >> grid.tile_h_log2; ++ty)
                for (uint32_t tx = s.x_lo >> grid.tile_w_log2; tx <= uint32_t(s.x_hi) >> grid.tile_w_log2; ++tx)
                    pair_triangle[cursor[grid.cell(tx, ty, chunk)]++] = i;
        }
    }
};

// Rows of a triangle's box at most this wide are drawn testing every pixel; wider ones first
// find the covered span with one division per edge.
constexpr uint32_t kNarrowRow = 8;

// Narrows [first, last] to the i with e + i * step >= threshold, exactly (last < first if none).
OCC_HD inline void edgeSpan(int64_t e, int64_t step, int64_t threshold, int64_t& first, int64_t& last) {
    if (step > 0) {
        if (e < threshold) first = max64(first, -floorDiv(-(threshold - e), step));
    } else if (step < 0) {
        last = e < threshold ? -1 : min64(last, floorDiv(e - threshold, -step));
    } else if (e < threshold) {
        last = -1;
    }
}

// Draws row y (in [s.y_lo, s.y_hi]) of set-up triangle s over columns [x_lo, x_hi] into out,
// which holds the row's pixels from column x_lo on: each covered centre keeps the nearer of its
// depth and the triangle's plane there. Edge functions in exact integers (so computing a row
// on its own gives the same values as stepping to it), depth from the triangle's plane.
OCC_HD inline void drawTriangleRow(const DepthRasterTriangle& s, uint32_t y, uint32_t x_lo, uint32_t x_hi,
                                   float* out) {
    // Edge k is the one opposite corner k, from corner k+1 to corner k+2:
    // e_k(p) = (b - a) x (p - a), positive inside a counter-clockwise triangle.
    // A centre is covered when e_k >= threshold_k for every k.
    int64_t row[3], step_x[3], threshold[3];
    const int64_t cx = int64_t(x_lo) * kUnits + kHalfPixel, cy = int64_t(y) * kUnits + kHalfPixel;
    for (int k = 0; k < 3; ++k) {
        const int a = (k + 1) % 3, b = (k + 2) % 3;
        const int64_t ex = int64_t(s.x[b]) - s.x[a], ey = int64_t(s.y[b]) - s.y[a];
        row[k] = ex * (cy - s.y[a]) - ey * (cx - s.x[a]);
        step_x[k] = -ey * kUnits;
        if (s.shared_edges >> k & 1u) {
            // The top-left rule (D3D's), for counter-clockwise triangles with y up: a
            // centre on the edge belongs to this triangle when the edge is a left edge
            // (going down) or a top edge (horizontal, going left). The neighbour across
            // it runs it the other way, its edge function exactly negated, so exactly
            // one of the two covers each centre on it.
            threshold[k] = ey < 0 || (ey == 0 && ex < 0) ? 0 : 1;
        } else {
            // distance = e / |edge|_2 >= margin, made integer by |edge|_1 >= |edge|_2
            threshold[k] = kMargin * (abs64(ex) + abs64(ey));
        }
    }
    const int64_t columns = int64_t(x_hi - x_lo) + 1;
    const float row_depth = addRn(s.z_ref, mulRn(s.gy, float(int32_t(y - s.y_lo))));
    const float gx = s.gx;
    // out[x] and the plane's column term both start at x_lo.
    const int32_t column0 = int32_t(x_lo - s.x_lo);
    if (columns <= int64_t(kNarrowRow)) {
        int64_t e0 = row[0], e1 = row[1], e2 = row[2];
        for (int64_t x = 0; x < columns; ++x) {
            // Without branches, since whether a centre is covered is close to
            // random for the small triangles drawn here: all three
            // e_k - threshold_k are non-negative when their OR is, and an
            // uncovered centre's candidate is pushed beyond every depth.
            const int64_t outside = (e0 - threshold[0]) | (e1 - threshold[1]) | (e2 - threshold[2]);
            const float d = addRn(row_depth, mulRn(gx, float(column0 + int32_t(x))));
            const float candidate = addRn(d, mulRn(float(uint64_t(outside) >> 63), kFar));
            out[x] = candidate < out[x] ? candidate : out[x];
            e0 += step_x[0], e1 += step_x[1], e2 += step_x[2];
        }
    } else {
        int64_t first = 0, last = columns - 1;
        for (int k = 0; k < 3; ++k) edgeSpan(row[k], step_x[k], threshold[k], first, last);
        for (int64_t x = first; x <= last; ++x) {
            const float d = addRn(row_depth, mulRn(gx, float(column0 + int32_t(x))));
            out[x] = d < out[x] ? d : out[x];
        }
    }
}

// One thread per tile: draws its triangles into a tile-sized buffer, row by row
// (drawTriangleRow), then writes the tile out. The minimum makes the order of triangles
// irrelevant. On the CPU, the reference the SIMD loop is tested against; the CUDA build gives
// a tile to a warp instead (rasterTilesWarp), drawing the same rows.
struct RasterTiles {
    const DepthRasterTriangle* setup;
    TileBins bins;
    float* depth;
    uint32_t width, height;

    // Whether every pixel of the box (tile coordinates, inclusive) is already at or nearer
    // than `bound`; gives up after the first row that is not. Counting rather than breaking
    // out lets the compiler vectorise the row, and hidden triangles scan their whole box.
    OCC_HD static bool hidden(const float* nearest, float bound, uint32_t x_lo, uint32_t x_hi, uint32_t y_lo,
                              uint32_t y_hi) {
        for (uint32_t y = y_lo; y <= y_hi; ++y) {
            uint32_t farther = 0;
            for (uint32_t x = x_lo; x <= x_hi; ++x) farther += nearest[y * kTile + x] > bound ? 1u : 0u;
            if (farther) return false;
        }
        return true;
    }

    OCC_HD void operator()(uint32_t tile) const {
        const uint32_t px0 = tile % bins.tiles_x * kTile, py0 = tile / bins.tiles_x * kTile;
        const uint32_t px1 = px0 + kTile < width ? px0 + kTile : width;
        const uint32_t py1 = py0 + kTile < height ? py0 + kTile : height;
        float nearest[kTile * kTile];
        for (uint32_t i = 0; i < kTile * kTile; ++i) nearest[i] = kFar;

        const uint64_t begin = bins.tileBegin(tile), end = bins.tileEnd(tile);
        for (uint64_t i = begin; i < end; ++i) {
            if (i + kPrefetchDistance < end) prefetch(&setup[bins.pair_triangle[i + kPrefetchDistance]]);
            const DepthRasterTriangle& s = setup[bins.pair_triangle[i]];
            const uint32_t x_lo = s.x_lo > px0 ? s.x_lo : px0, x_hi = s.x_hi < px1 - 1 ? s.x_hi : px1 - 1;
            const uint32_t y_lo = s.y_lo > py0 ? s.y_lo : py0, y_hi = s.y_hi < py1 - 1 ? s.y_hi : py1 - 1;
            if (x_lo > x_hi || y_lo > y_hi) continue;
            if (!EdgeFunctions(s).mayCover(x_lo, x_hi, y_lo, y_hi)) continue;
            if (hidden(nearest, s.lower_bound, x_lo - px0, x_hi - px0, y_lo - py0, y_hi - py0)) continue;
            for (uint32_t y = y_lo; y <= y_hi; ++y)
                drawTriangleRow(s, y, x_lo, x_hi, nearest + (y - py0) * kTile + (x_lo - px0));
        }

        for (uint32_t y = py0; y < py1; ++y)
            for (uint32_t x = px0; x < px1; ++x) {
                const float d = nearest[(y - py0) * kTile + (x - px0)];
                depth[uint64_t(y) * width + x] = d < 1.0f ? d : 1.0f;
            }
    }
};

#if defined(__CUDACC__)
// The CUDA build's tile loop (issue 32): a warp per tile and a lane per tile row, the tile in
// shared memory (one padded row per lane, so that the lanes' columns fall in distinct banks),
// instead of a thread per tile with the whole tile in local memory (4 KiB of stack per thread:
// about 1 GB reserved per process on a large GPU) and 32 times fewer threads. The warp walks its
// tile's triangles together; a triangle every row of whose box already holds a nearer depth is
// skipped by a warp vote (RasterTiles::hidden's rule, which never changes the result); each lane
// draws its own row with drawTriangleRow, so the image is RasterTiles' bit for bit. The tile
// goes out row by row, the lanes writing consecutive pixels.
constexpr uint32_t kWarpsPerBlock = 4;

__global__ void rasterTilesWarp(const DepthRasterTriangle* setup, TileBins bins, float* depth, uint32_t width,
                                uint32_t height) {
    __shared__ float tiles[kWarpsPerBlock][kTile][kTile + 1];
    const uint32_t warp = threadIdx.x / 32, lane = threadIdx.x % 32;
    const uint32_t tile = blockIdx.x * kWarpsPerBlock + warp;
    if (tile >= bins.tiles_x * bins.tiles_y) return;  // the whole warp: tile depends on the warp alone
    float(*const nearest)[kTile + 1] = tiles[warp];
    for (uint32_t x = 0; x < kTile; ++x) nearest[lane][x] = kFar;
    const uint32_t px0 = tile % bins.tiles_x * kTile, py0 = tile / bins.tiles_x * kTile;
    const uint32_t px1 = px0 + kTile < width ? px0 + kTile : width;
    const uint32_t py1 = py0 + kTile < height ? py0 + kTile : height;
    const uint32_t y = py0 + lane;

    const uint64_t begin = bins.tileBegin(tile), end = bins.tileEnd(tile);
    for (uint64_t i = begin; i < end; ++i) {
        const DepthRasterTriangle& s = setup[bins.pair_triangle[i]];
        const uint32_t x_lo = s.x_lo > px0 ? s.x_lo : px0, x_hi = s.x_hi < px1 - 1 ? s.x_hi : px1 - 1;
        const uint32_t y_lo = s.y_lo > py0 ? s.y_lo : py0, y_hi = s.y_hi < py1 - 1 ? s.y_hi : py1 - 1;
        // Both the same for every lane.
        if (x_lo > x_hi || y_lo > y_hi || !EdgeFunctions(s).mayCover(x_lo, x_hi, y_lo, y_hi)) continue;
        const bool mine = y >= y_lo && y <= y_hi;
        uint32_t farther = 0;
        if (mine)
            for (uint32_t x = x_lo; x <= x_hi; ++x) farther += nearest[lane][x - px0] > s.lower_bound ? 1u : 0u;
        if (__all_sync(0xffffffffu, farther == 0)) continue;
        if (mine) drawTriangleRow(s, y, x_lo, x_hi, &nearest[lane][x_lo - px0]);
    }
    __syncwarp();
    for (uint32_t r = 0; r < kTile; ++r) {
        const uint32_t x = px0 + lane;
        if (py0 + r < py1 && x < px1) {
            const float d = nearest[r][lane];
            depth[uint64_t(py0 + r) * width + x] = d < 1.0f ? d : 1.0f;
        }
    }
}
#endif

}  // namespace

bool markClosedMesh(const uint32_t* triangles, uint32_t tri_count, const glm::vec3* positions, uint8_t* flags) {
    if (tri_count < 4) return false;
    for (uint32_t t = 0; t < tri_count; ++t)
        if ((flags[t] & 7u) != 7u) return false;
    // Six times the signed volume, about the first corner (smaller terms, less cancellation).
    const glm::dvec3 o(positions[triangles[0]]);
    double volume6 = 0.0;
    for (uint32_t t = 0; t < tri_count; ++t) {
        const glm::dvec3 a = glm::dvec3(positions[triangles[3 * t]]) - o;
        const glm::dvec3 b = glm::dvec3(positions[triangles[3 * t + 1]]) - o;
        const glm::dvec3 c = glm::dvec3(positions[triangles[3 * t + 2]]) - o;
        volume6 += glm::dot(a, glm::cross(b, c));
    }
    if (!(volume6 > 0.0)) return false;
    for (uint32_t t = 0; t < tri_count; ++t) flags[t] |= kEdgeFlagClosedMesh;
    return true;
}

void sharedEdgeFlags(const uint32_t* triangles, uint32_t tri_count, uint8_t* flags, uint32_t* neighbours) {
    // One slot per undirected edge (smaller index, larger index) in an open-addressing hash
    // table, whatever the indices, holding its first two uses and how many there are (up to 3).
    // More than 1.5 slots per use keeps it under 2/3 full even when no edge is shared.
    struct Slot {
        uint64_t key;
        uint32_t triangle[2];
        uint8_t edge[2], forward[2];  // forward: runs from the smaller index to the larger
        uint8_t count;                // 0: empty
    };
    const size_t uses = 3 * size_t(tri_count);
    uint32_t bits = 4;
    while ((size_t(1) << bits) <= uses + uses / 2) ++bits;
    const size_t mask = (size_t(1) << bits) - 1;
    std::vector<Slot> slots(mask + 1);
    for (uint32_t t = 0; t < tri_count; ++t) {
        flags[t] = 0;
        if (neighbours) neighbours[3 * size_t(t)] = neighbours[3 * size_t(t) + 1] = neighbours[3 * size_t(t) + 2] = UINT32_MAX;
        for (uint8_t e = 0; e < 3; ++e) {
            const uint32_t a = triangles[3 * size_t(t) + e], b = triangles[3 * size_t(t) + (e + 1) % 3];
            if (a == b) continue;  // a degenerate edge borders nothing
            const uint64_t key = a < b ? uint64_t(a) << 32 | b : uint64_t(b) << 32 | a;
            // Fibonacci hashing: the top bits of key * 2^64 / golden ratio.
            size_t i = size_t((key * 0x9E3779B97F4A7C15ull) >> (64 - bits));
            while (slots[i].count && slots[i].key != key) i = (i + 1) & mask;
            Slot& slot = slots[i];
            slot.key = key;
            if (slot.count < 2) {
                slot.triangle[slot.count] = t;
                slot.edge[slot.count] = e;
                slot.forward[slot.count] = a < b;
            }
            if (slot.count < 3) ++slot.count;
        }
    }
    // Shared: exactly two uses, by two triangles, in opposite directions.
    for (const Slot& slot : slots)
        if (slot.count == 2 && slot.forward[0] != slot.forward[1] && slot.triangle[0] != slot.triangle[1]) {
            flags[slot.triangle[0]] |= uint8_t(1u << slot.edge[0]);
            flags[slot.triangle[1]] |= uint8_t(1u << slot.edge[1]);
            if (neighbours) {
                neighbours[3 * size_t(slot.triangle[0]) + slot.edge[0]] = slot.triangle[1];
                neighbours[3 * size_t(slot.triangle[1]) + slot.edge[1]] = slot.triangle[0];
            }
        }
}

namespace {

// Brings the boundary edges of equal keys next to each other, as MatchSeams wants them, and
// returns how many entries that leaves at the front of keys and ids. The CUDA build sorts them
// all. On the CPU a hash table finds the keys that more than one edge has (on the plant walks a
// third of the edges) and puts only those edges first, grouped by key:
// Thrust's TBB sort took half the seams' time, most of it allocating and copying its
// temporaries.
uint32_t groupEqualKeys(uint64_t* keys, uint32_t* ids, uint32_t count, DepthRasterScratch& scratch) {
#if defined(__CUDACC__)
    (void)scratch;
    thrust::sort_by_key(onDevice(), keys, keys + count, ids);
    return count;
#else
    uint32_t bits = 4;
    while ((uint64_t(1) << bits) < 2 * uint64_t(count)) ++bits;
    const uint64_t slots = uint64_t(1) << bits;
    // Per slot the first edge of its key; per edge the next one of its key, and per first edge
    // the last one so far and how many there are.
    scratch.key_groups.resize(slots + 3 * uint64_t(count));
    uint32_t* const table = raw(scratch.key_groups.ptr());
    uint32_t* const next = table + slots;
    uint32_t* const last = next + count;
    uint32_t* const size = last + count;
    std::fill(table, table + slots, UINT32_MAX);
    uint32_t shared = 0;
    for (uint32_t i = 0; i < count; ++i) {
        next[i] = UINT32_MAX;
        uint64_t h = (keys[i] * 0x9E3779B97F4A7C15ull) >> (64 - bits);
        while (table[h] != UINT32_MAX && keys[table[h]] != keys[i]) h = (h + 1) & (slots - 1);
        const uint32_t f = table[h];
        if (f == UINT32_MAX) {
            table[h] = i, last[i] = i, size[i] = 1;
        } else {
            next[last[f]] = i, last[f] = i;
            shared += size[f] == 1 ? 2u : 1u;
            ++size[f];
        }
    }
    if (shared == 0) return 0;
    // The keys' groups in the order of their slots (a function of the keys alone).
    std::vector<uint64_t>& out_keys = scratch.grouped_keys;
    std::vector<uint32_t>& out_ids = scratch.grouped_ids;
    out_keys.resize(shared);
    out_ids.resize(shared);
    uint32_t at = 0;
    for (uint64_t h = 0; h < slots; ++h) {
        const uint32_t f = table[h];
        if (f == UINT32_MAX || size[f] < 2) continue;
        for (uint32_t e = f; e != UINT32_MAX; e = next[e]) out_keys[at] = keys[e], out_ids[at] = ids[e], ++at;
    }
    std::copy(out_keys.begin(), out_keys.begin() + shared, keys);
    std::copy(out_ids.begin(), out_ids.begin() + shared, ids);
    return shared;
#endif
}

// Finds the seams (see depthRaster) among the set-up triangles and sets them up again with the
// tie rule on those edges.
void seams(const glm::vec3* positions, const uint32_t* triangles, SetupTriangles setup, DepthRasterScratch& scratch) {
    const thrust::counting_iterator<uint32_t> first(0);
    DepthRasterTriangle* const drawn_setup = raw(scratch.drawn_setup.ptr());
    const uint32_t drawn_count = scratch.drawn_count;
    const uint32_t* const drawn_ids = raw(scratch.drawn_ids.ptr());
    scratch.edge_first.resize(uint64_t(drawn_count) + 1);
    uint32_t* const edge_first = raw(scratch.edge_first.ptr());
    forEachIndex(drawn_count, CountBoundaryEdges{drawn_setup, edge_first});
    withPolicy(drawn_count, [&](auto policy) {
        thrust::fill(policy, edge_first + drawn_count, edge_first + drawn_count + 1, 0u);
        thrust::exclusive_scan(policy, edge_first, edge_first + drawn_count + 1, edge_first);
    });
    const uint32_t count = readBack(DevicePtr<const uint32_t>(scratch.edge_first.ptr() + drawn_count));
    if (count < 2) return;
    scratch.edge_ids.resize(count);
    scratch.edge_keys.resize(count);
    uint32_t* const ids = raw(scratch.edge_ids.ptr());
    uint64_t* const keys = raw(scratch.edge_keys.ptr());
    forEachIndex(drawn_count,
                       EmitBoundaryEdges{drawn_setup, drawn_ids, triangles, positions, edge_first, ids, keys});
    const uint32_t grouped = groupEqualKeys(keys, ids, count, scratch);
    scratch.seam_edges.resize(3 * uint64_t(drawn_count));
    uint8_t* const marks = raw(scratch.seam_edges.ptr());
    withPolicy(3 * uint64_t(drawn_count),
               [&](auto policy) { thrust::fill(policy, marks, marks + 3 * uint64_t(drawn_count), uint8_t(0)); });
    forEachIndex(grouped,
                       MatchSeams{drawn_setup, drawn_ids, triangles, positions, ids, keys, grouped, marks});
    scratch.seam_triangles.resize(std::max<uint32_t>(1, drawn_count));
    uint32_t* const affected = raw(scratch.seam_triangles.ptr());
    scratch.seam_bits.resize(std::max<uint32_t>(1, drawn_count));
    uint8_t* const bits = raw(scratch.seam_bits.ptr());
    forEachIndex(drawn_count, GatherSeamBits{marks, bits});
    const uint32_t n = uint32_t(withPolicy(drawn_count, [&](auto policy) {
                                    return thrust::copy_if(policy, first, first + drawn_count, affected, ByteSet{bits});
                                }) -
                                affected);
    countReadback(sizeof n);
    if (n == 0) return;
    setup.only = affected;
    setup.drawn_ids = drawn_ids;
    setup.seam_edges = bits;
    setup.drawn_setup = drawn_setup;
    forEachIndex(n, setup);
}

#if !defined(__CUDACC__)
// On the CPU, blocks of triangles, each looked at a vector at a time first (setupCandidatesCpu):
// most occluder triangles hold no pixel centre, and leave there.
constexpr uint32_t kSetupBlock = 2048;

// Sets up triangles [begin, end), at most kSetupBlock of them; appends those drawn to `listed`
// when it is not null.
void setupBlockCpu(const SetupTriangles& setup, uint32_t begin, uint32_t end, std::vector<uint32_t>* listed = nullptr) {
    std::fill(setup.drawn + begin, setup.drawn + end, uint8_t(0));
    uint32_t candidates[kSetupBlock];
    const uint32_t n = setupCandidatesCpu(setup.vertices, setup.triangles, setup.edge_flags, begin, end,
                                          int32_t(setup.last_x), int32_t(setup.last_y), candidates);
    for (uint32_t i = 0; i < n; ++i) {
        setup(candidates[i]);
        if (listed && setup.drawn[candidates[i]]) listed->push_back(candidates[i]);
    }
}

// Blocks of triangles [begin, end) in parallel.
void setupTrianglesCpu(const SetupTriangles& setup, uint32_t begin, uint32_t end) {
    tbb::parallel_for(0u, (end - begin + kSetupBlock - 1) / kSetupBlock, [&](uint32_t block) {
        const uint32_t from = begin + block * kSetupBlock;
        setupBlockCpu(setup, from, std::min(end, from + kSetupBlock));
    });
}
#endif

// The setup of the drawn triangles listed in scratch.drawn_ids copied densely, then the seams
// found among them. Seams only move margins of drawn triangles, so the list stays what it is.
void copyDrawnSetup(const glm::vec3* positions, const uint32_t* triangles, const SetupTriangles& setup,
                    DepthRasterScratch& scratch, bool with_seams) {
    scratch.drawn_setup.resize(std::max<uint32_t>(1, scratch.drawn_count));
    forEachIndex(scratch.drawn_count, GatherDrawn{raw(scratch.setup.ptr()), raw(scratch.drawn_ids.ptr()),
                                                  raw(scratch.drawn_setup.ptr())});
    if (with_seams) seams(positions, triangles, setup, scratch);
}

// The list of drawn triangles, which every later pass walks instead of all of them (on the
// plant walks 3 occluder triangles in 4 hold no pixel centre), then copyDrawnSetup.
void listDrawnTriangles(const glm::vec3* positions, const uint32_t* triangles, uint32_t tri_count,
                        const SetupTriangles& setup, DepthRasterScratch& scratch, bool with_seams) {
    const thrust::counting_iterator<uint32_t> first(0);
    scratch.drawn_ids.resize(tri_count);
    uint32_t* const drawn_ids = raw(scratch.drawn_ids.ptr());
    scratch.drawn_count = uint32_t(
        thrust::copy_if(onDevice(), first, first + tri_count, drawn_ids, ByteSet{raw(scratch.drawn.ptr())}) - drawn_ids);
    countReadback(sizeof scratch.drawn_count);
    copyDrawnSetup(positions, triangles, setup, scratch, with_seams);
}

}  // namespace

void depthRasterSetup(const glm::vec3* positions, const uint32_t* triangles, uint32_t tri_count,
                      const uint8_t* edge_flags, const uint32_t* edge_neighbours, const Camera& camera,
                      DepthRasterScratch& scratch, bool with_seams) {
    const thrust::counting_iterator<uint32_t> first(0);
    const uint32_t vertex_count = thrust::reduce(onDevice(), triangles, triangles + uint64_t(tri_count) * 3, 0u,
                                                 thrust::maximum<uint32_t>()) + 1;
    countReadback(sizeof vertex_count);
    scratch.vertices.resize(vertex_count);
    scratch.setup.resize(tri_count);
    scratch.drawn.resize(tri_count);
    ProjectVertices project{positions, raw(scratch.vertices.ptr()), {}, float(camera.width), float(camera.height)};
    for (int i = 0; i < 16; ++i) project.m[i] = camera.view_proj[i / 4][i % 4];
    thrust::for_each_n(onDevice(), first, vertex_count, project);
    const SetupTriangles setup{raw(scratch.vertices.ptr()), triangles, edge_flags, edge_neighbours, tri_count,
                               raw(scratch.setup.ptr()), raw(scratch.drawn.ptr()), int64_t(camera.width) - 1,
                               int64_t(camera.height) - 1};
#if defined(__CUDACC__)
    thrust::for_each_n(onDevice(), first, tri_count, setup);
#else
    setupTrianglesCpu(setup, 0, tri_count);
#endif
    listDrawnTriangles(positions, triangles, tri_count, setup, scratch, with_seams);
}

TileBins binTriangles(uint32_t tri_count, uint32_t width, uint32_t height, uint32_t tile_w_log2,
                      uint32_t tile_h_log2, DepthRasterScratch& scratch) {
    const uint32_t tile_w = 1u << tile_w_log2, tile_h = 1u << tile_h_log2;
    const uint32_t tiles_x = (width + tile_w - 1) / tile_w, tiles_y = (height + tile_h - 1) / tile_h;
    const uint32_t tile_count = tiles_x * tiles_y;
    // Enough chunks to keep every core busy, few enough that the count matrix stays small.
    // The drawn triangles are what is binned (tri_count 0: nothing was set up).
    const uint32_t drawn = tri_count > 0 ? scratch.drawn_count : 0u;
    const uint64_t wanted_chunks = (drawn + kChunkTriangles - 1) / kChunkTriangles;
    const uint32_t chunk_count = uint32_t(std::max<uint64_t>(1, std::min(wanted_chunks, kMaxCountCells / tile_count)));
    const ChunkGrid grid{drawn, (drawn + chunk_count - 1) / chunk_count, chunk_count, tiles_x, tile_w_log2,
                         tile_h_log2};
#if !defined(__CUDACC__)
    // On the CPU each chunk counts and fills a row of its own (chunk-major), so that no two
    // cores write the same cache line (the tile-major matrix below had neighbouring chunks'
    // cells side by side), and one serial scan in tile order leaves each tile's end in the first
    // tile_count cells: TileBins with one chunk.
    if (drawn > 0) {
        const uint64_t row = tile_count;
        scratch.cells.resize(row * (chunk_count + 1));
        uint64_t* const ends = raw(scratch.cells.ptr());
        uint64_t* const rows = ends + row;  // chunk c's counts, then cursors, at rows + c * row
        const DepthRasterTriangle* const drawn_setup = raw(scratch.drawn_setup.ptr());
        const auto forEachTileOf = [&](const DepthRasterTriangle& t, auto&& f) {
            for (uint32_t ty = t.y_lo >> tile_h_log2; ty <= uint32_t(t.y_hi) >> tile_h_log2; ++ty)
                for (uint32_t tx = t.x_lo >> tile_w_log2; tx <= uint32_t(t.x_hi) >> tile_w_log2; ++tx)
                    f(uint64_t(ty) * tiles_x + tx);
        };
        const auto eachChunk = [&](auto&& work) {
            if (chunk_count == 1)
                work(0u);
            else
                tbb::parallel_for(0u, chunk_count, [&](uint32_t c) { work(c); });
        };
        eachChunk([&](uint32_t c) {
            uint64_t* const counts = rows + c * row;
            std::fill(counts, counts + row, uint64_t(0));
            for (uint32_t i = grid.chunkBegin(c); i < grid.chunkEnd(c); ++i)
                forEachTileOf(drawn_setup[i], [&](uint64_t tile) { ++counts[tile]; });
        });
        uint64_t total = 0;
        for (uint64_t tile = 0; tile < row; ++tile) {
            for (uint32_t c = 0; c < chunk_count; ++c) {
                const uint64_t n = rows[c * row + tile];
                rows[c * row + tile] = total;
                total += n;
            }
            ends[tile] = total;
        }
        scratch.pair_triangle.resize(std::max<uint64_t>(1, total));
        uint32_t* const pairs = raw(scratch.pair_triangle.ptr());
        eachChunk([&](uint32_t c) {
            uint64_t* const cursor = rows + c * row;
            for (uint32_t i = grid.chunkBegin(c); i < grid.chunkEnd(c); ++i)
                forEachTileOf(drawn_setup[i], [&](uint64_t tile) { pairs[cursor[tile]++] = i; });
        });
        return TileBins{tile_w_log2, tile_h_log2, tiles_x, tiles_y, 1, ends, pairs};
    }
#endif
    const uint64_t cell_count = uint64_t(tile_count) * chunk_count;
    scratch.cells.resize(cell_count + 1);
    uint64_t* cells = raw(scratch.cells.ptr());
    withPolicy(cell_count + 1, [&](auto policy) { thrust::fill(policy, cells, cells + cell_count + 1, uint64_t(0)); });
    if (drawn > 0) {
        const thrust::counting_iterator<uint32_t> first(0);
        thrust::for_each_n(onDevice(), first, chunk_count,
                           CountPerChunk{raw(scratch.drawn_setup.ptr()), cells, grid});
        // One more cell than there are, counting 0, so that the scan leaves the total there.
        withPolicy(cell_count + 1,
                   [&](auto policy) { thrust::exclusive_scan(policy, cells, cells + cell_count + 1, cells); });
        scratch.pair_triangle.resize(readBack(DevicePtr<const uint64_t>(scratch.cells.ptr() + cell_count)));
        thrust::for_each_n(onDevice(), first, chunk_count,
                           FillPerChunk{raw(scratch.drawn_setup.ptr()), cells,
                                        raw(scratch.pair_triangle.ptr()), grid});
    }
    return TileBins{tile_w_log2, tile_h_log2, tiles_x, tiles_y, chunk_count, cells, raw(scratch.pair_triangle.ptr())};
}

void checkRasterViewport(const Camera& camera, const char* who) {
    // The HZM's limit, which also keeps pixel boxes within 16 bits.
    if (camera.width > kHzmMaxSide || camera.height > kHzmMaxSide)
        throw std::invalid_argument(std::string(who) + ": viewport " + std::to_string(camera.width) + "x" +
                                    std::to_string(camera.height) + " is larger than 32768x32768");
}

namespace {

// The drawn triangles binned to the exact raster's tiles, as its tile loops take them.
DepthTiles binnedTiles(uint32_t tri_count, const Camera& camera, DevicePtr<float> depth, DepthRasterScratch& scratch) {
    static_assert(kTile == 1u << 5);
    const TileBins bins = binTriangles(tri_count, camera.width, camera.height, 5, 5, scratch);
    return DepthTiles{raw(scratch.drawn_setup.ptr()), bins, raw(depth), camera.width, camera.height};
}

DepthTiles depthRasterFrontEnd(DevicePtr<const glm::vec3> position_memory, DevicePtr<const uint32_t> triangle_memory,
                               uint32_t tri_count, DevicePtr<const uint8_t> flag_memory,
                               DevicePtr<const uint32_t> neighbour_memory, const Camera& camera,
                               DevicePtr<float> depth_memory, DepthRasterScratch& scratch, bool with_seams) {
    if (tri_count > 0)
        depthRasterSetup(raw(position_memory), raw(triangle_memory), tri_count, raw(flag_memory), raw(neighbour_memory),
                         camera, scratch, with_seams);
    return binnedTiles(tri_count, camera, depth_memory, scratch);
}

void rasterTilesScalar(const DepthTiles& t) {
    thrust::for_each_n(onDevice(), thrust::counting_iterator<uint32_t>(0), t.bins.tiles_x * t.bins.tiles_y,
                       RasterTiles{t.setup, t.bins, t.depth, t.width, t.height});
}

#if defined(__CUDACC__)
void rasterTilesWarps(const DepthTiles& t) {
    const uint32_t tiles = t.bins.tiles_x * t.bins.tiles_y;
    if (tiles == 0) return;
    rasterTilesWarp<<<(tiles + kWarpsPerBlock - 1) / kWarpsPerBlock, kWarpsPerBlock * 32>>>(t.setup, t.bins, t.depth,
                                                                                          t.width, t.height);
    const cudaError_t status = cudaGetLastError();
    if (status != cudaSuccess)
        throw std::runtime_error(std::string("CUDA: depthRaster's tile kernel: ") + cudaGetErrorString(status));
}
#endif

}  // namespace

void depthRaster(DevicePtr<const glm::vec3> position_memory, DevicePtr<const uint32_t> triangle_memory,
                 uint32_t tri_count, DevicePtr<const uint8_t> flag_memory, DevicePtr<const uint32_t> neighbour_memory,
                 const Camera& camera, DevicePtr<float> depth_memory, DepthRasterScratch& scratch, bool with_seams) {
    checkRasterViewport(camera, "depthRaster");
    if (camera.width == 0 || camera.height == 0) return;
    const DepthTiles tiles = depthRasterFrontEnd(position_memory, triangle_memory, tri_count, flag_memory,
                                                 neighbour_memory, camera, depth_memory, scratch, with_seams);
#if defined(__CUDACC__)
    rasterTilesWarps(tiles);
#else
    depthRasterTilesCpu(tiles);
#endif
}

void depthRasterScalar(DevicePtr<const glm::vec3> position_memory, DevicePtr<const uint32_t> triangle_memory,
                       uint32_t tri_count, DevicePtr<const uint8_t> flag_memory,
                       DevicePtr<const uint32_t> neighbour_memory, const Camera& camera, DevicePtr<float> depth_memory,
                       DepthRasterScratch& scratch, bool with_seams) {
    checkRasterViewport(camera, "depthRasterScalar");
    if (camera.width == 0 || camera.height == 0) return;
    rasterTilesScalar(depthRasterFrontEnd(position_memory, triangle_memory, tri_count, flag_memory, neighbour_memory,
                                          camera, depth_memory, scratch, with_seams));
}

#if !defined(__CUDACC__)
namespace {

// Occluder triangles per chunk of rasterOccluders' CPU front end (whole occluders; a larger one
// is a chunk of its own): small enough that a chunk's vertices, triangles and setup flags stay
// in the core's caches between its steps, large enough to amortise a task.
constexpr uint64_t kOccluderChunkTriangles = 4096;

// Sets up triangles [first, first + count) on this thread, a block at a time, appending those
// drawn to `listed`.
void setupRangeCpu(const SetupTriangles& setup, uint32_t first, uint32_t count, std::vector<uint32_t>& listed) {
    for (uint32_t b = first; b < first + count; b += kSetupBlock)
        setupBlockCpu(setup, b, std::min(first + count, b + kSetupBlock), &listed);
}

// Asks for the first `lines` cache lines of [p, p + bytes).
inline void prefetchLines(const void* p, uint64_t bytes, uint64_t lines) {
    const char* const c = static_cast<const char*>(p);
    for (uint64_t b = 0; b < std::min(bytes, 64 * lines); b += 64) prefetch(c + b);
}

// Asks for the start of the arrays of the mesh of occluder o.
void prefetchMesh(const ObjectInfo& o, const MeshGeometry& meshes) {
    const uint64_t first_triangle = raw(meshes.triangle_first)[o.mesh];
    prefetchLines(raw(meshes.positions) + raw(meshes.vertex_first)[o.mesh], 12 * uint64_t(o.vertex_count), 8);
    prefetchLines(raw(meshes.triangles) + 3 * first_triangle, 12 * uint64_t(o.triangle_count), 8);
    prefetchLines(raw(meshes.edge_neighbours) + 3 * first_triangle, 12 * uint64_t(o.triangle_count), 8);
    prefetch(raw(meshes.edge_flags) + first_triangle);
}

// Lists the triangles [first, first + count) with one or two corners in front of the near plane
// (appendNearClipped's CountNearClipped), with that number.
void listNearCrossings(const uint8_t* front, const uint32_t* corners, uint32_t first, uint32_t count,
                       DepthRasterScratch::ChunkLists& lists) {
    for (uint32_t t = first; t < first + count; ++t) {
        const uint32_t ahead = front[corners[3 * t]] + front[corners[3 * t + 1]] + front[corners[3 * t + 2]];
        if (ahead == 1 || ahead == 2) lists.crossing.push_back(t), lists.crossing_front.push_back(uint8_t(ahead));
    }
}

// Grows a to at least n entries, keeping its contents.
template <class T>
void growKeepingAll(DeviceArray<T>& a, uint64_t n) {
    if (a.size() < n) a.resizeKeep(n + n / 2);
}

}  // namespace
#endif

uint64_t rasterOccluders(DevicePtr<const ObjectInfo> object_memory, DevicePtr<const glm::mat4> world_memory,
                         const MeshGeometry& meshes, DevicePtr<const uint32_t> id_memory, uint32_t count,
                         const Camera& camera, OccluderGeometry& g, DevicePtr<float> depth, DepthRasterScratch& scratch) {
    checkRasterViewport(camera, "rasterOccluders");
    const auto threeCalls = [&] {
        gatherOccluders(object_memory, world_memory, meshes, id_memory, count, g, &camera.eye);
        appendNearClipped(g, camera);
        depthRaster(g.positions.ptr(), g.triangles.ptr(), uint32_t(g.triangle_total), g.edge_flags.ptr(),
                    g.edge_neighbours.ptr(), camera, depth, scratch, /*seams=*/true);
        return g.triangle_total;
    };
#if defined(__CUDACC__)
    return threeCalls();
#else
    if (count == 0 || camera.width == 0 || camera.height == 0) return threeCalls();
    const ObjectInfo* const objects = raw(object_memory);
    const glm::mat4* const world = raw(world_memory);
    const uint32_t* const ids = raw(id_memory);
    // Sizes, offsets and chunks on the host (a few thousand occluders).
    g.offsets.growTo(2 * uint64_t(count));
    uint64_t* const vertex_offsets = raw(g.offsets.ptr());
    uint64_t* const triangle_offsets = vertex_offsets + count;
    std::vector<uint32_t>& chunks = scratch.occluder_chunks;  // first occluder of each, then count
    chunks.clear();
    uint64_t vertex_total = 0, triangle_total = 0, in_chunk = 0;
    for (uint32_t j = 0; j < count; ++j) {
        const ObjectInfo& o = objects[ids[j]];
        if (j == 0 || in_chunk >= kOccluderChunkTriangles) chunks.push_back(j), in_chunk = 0;
        vertex_offsets[j] = vertex_total, triangle_offsets[j] = triangle_total;
        vertex_total += o.vertex_count, triangle_total += o.triangle_count;
        in_chunk += o.triangle_count;
    }
    chunks.push_back(count);
    // depthRaster takes 32-bit counts (and appendNearClipped up to 2^32 triangles): beyond a
    // quarter of that, the three calls answer as they do.
    if (vertex_total > UINT32_MAX / 4 || triangle_total > UINT32_MAX / 4) return threeCalls();
    g.vertex_total = vertex_total, g.triangle_total = triangle_total;
    g.positions.growTo(vertex_total);
    g.triangles.growTo(3 * triangle_total);
    g.edge_flags.growTo(triangle_total);
    g.edge_neighbours.growTo(3 * triangle_total);
    g.front.growTo(vertex_total);
    scratch.vertices.growTo(vertex_total);
    scratch.setup.growTo(triangle_total);
    scratch.drawn.growTo(triangle_total);
    const auto last_x = int64_t(camera.width) - 1, last_y = int64_t(camera.height) - 1;
    ProjectVertices project{raw(g.positions.ptr()), raw(scratch.vertices.ptr()), {}, float(camera.width),
                            float(camera.height)};
    for (int i = 0; i < 16; ++i) project.m[i] = camera.view_proj[i / 4][i % 4];
    const SetupTriangles setup{raw(scratch.vertices.ptr()), raw(g.triangles.ptr()), raw(g.edge_flags.ptr()),
                               raw(g.edge_neighbours.ptr()), uint32_t(triangle_total), raw(scratch.setup.ptr()),
                               raw(scratch.drawn.ptr()), last_x, last_y};
    const glm::vec4 near_row = nearPlaneRow(camera.view_proj);
    glm::vec3* const positions = raw(g.positions.ptr());
    uint8_t* const front = raw(g.front.ptr());
    const glm::vec3* const mesh_positions = raw(meshes.positions);
    const uint64_t* const vertex_first = raw(meshes.vertex_first);
    const uint64_t* const triangle_first = raw(meshes.triangle_first);
    const size_t chunk_count = chunks.size() - 1;
    // Per chunk, the triangles it drew and those across the near plane (with how many corners
    // in front), ascending; kept with their capacity from call to call.
    if (scratch.occluder_chunk_lists.size() < chunk_count) scratch.occluder_chunk_lists.resize(chunk_count);
    // Per chunk, occluder by occluder: its vertices to world space, their side of the near plane
    // and their projection, its triangles copied, then set up, each step reading what the last
    // one wrote while it is in cache.
    OccluderVertexJob job_template{};
    for (int i = 0; i < 16; ++i) job_template.view_proj[i] = project.m[i];
    job_template.width = float(camera.width), job_template.height = float(camera.height);
    for (int i = 0; i < 4; ++i) job_template.near_row[i] = near_row[i];
    tbb::parallel_for(size_t(0), chunk_count, [&](size_t c) {
        OccluderVertexJob vertex_job = job_template;
        DepthRasterScratch::ChunkLists& lists = scratch.occluder_chunk_lists[c];
        lists.drawn.clear(), lists.crossing.clear(), lists.crossing_front.clear();
        for (uint32_t j = chunks[c]; j < chunks[c + 1]; ++j) {
            // Each occluder's mesh starts where the hardware's prefetcher has no stream yet: ask
            // for the start of the one after next (a fifth off this pass on the 10^5 orbit), and
            // for the records of the one after that.
            if (j + 4 < count) prefetch(objects + ids[j + 4]), prefetch(world + ids[j + 4]);
            if (j + 2 < count) prefetchMesh(objects[ids[j + 2]], meshes);
            const uint32_t id = ids[j];
            const ObjectInfo& o = objects[id];
            const glm::mat4 m = world[id];
            const glm::vec3* const src = mesh_positions + vertex_first[o.mesh];
            const uint64_t base = vertex_offsets[j];
            uint32_t in_front = 0;
            for (int e = 0; e < 16; ++e) vertex_job.world[e] = m[e / 4][e % 4];
            const uint32_t simd = transformProjectCpu(vertex_job, src, o.vertex_count, positions + base,
                                                      raw(scratch.vertices.ptr()) + base, front + base, in_front);
            for (uint32_t v = simd; v < o.vertex_count; ++v) {
                const glm::vec3 p = occluderVertex(m, src[v]);
                positions[base + v] = p;
                const bool ahead = inFrontOfNearPlane(near_row, p);
                front[base + v] = ahead ? 1u : 0u;
                in_front += ahead ? 1u : 0u;
                project(uint32_t(base + v));
            }
            const auto first = uint32_t(triangle_offsets[j]);
            copyOccluderTriangles(raw(meshes.triangles), raw(meshes.edge_flags), raw(meshes.edge_neighbours),
                                  triangle_first[o.mesh], first, o.triangle_count, uint32_t(base), first,
                                  occluderSkipsBackFaces(o.aabb, m, camera.eye, true), raw(g.triangles.ptr()),
                                  raw(g.edge_flags.ptr()), raw(g.edge_neighbours.ptr()));
            setupRangeCpu(setup, first, o.triangle_count, lists.drawn);
            // Across the near plane: only where the occluder's vertices lie on both sides.
            if (in_front != 0 && in_front != o.vertex_count)
                listNearCrossings(front, raw(g.triangles.ptr()), first, o.triangle_count, lists);
        }
    });
    // The parts of triangles across the near plane, appended chunk after chunk (so in ascending
    // order, as appendNearClipped appends them), then projected and set up on their own (their
    // edges are all boundaries, so they need no neighbour).
    uint64_t drawn_total = 0, added = 0;
    for (size_t c = 0; c < chunk_count; ++c) {
        const DepthRasterScratch::ChunkLists& lists = scratch.occluder_chunk_lists[c];
        drawn_total += lists.drawn.size();
        added += appendNearClippedList(g, camera, lists.crossing.data(), lists.crossing_front.data(),
                                       lists.crossing.size());
    }
    const auto tri_count = uint32_t(g.triangle_total);
    SetupTriangles final_setup = setup;
    std::vector<uint32_t>& appended_drawn = scratch.occluder_appended_drawn;
    appended_drawn.clear();
    if (added > 0) {
        growKeepingAll(scratch.vertices, g.vertex_total);
        growKeepingAll(scratch.setup, g.triangle_total);
        growKeepingAll(scratch.drawn, g.triangle_total);
        ProjectVertices more = project;
        more.positions = raw(g.positions.ptr());
        more.vertices = raw(scratch.vertices.ptr());
        for (uint64_t v = vertex_total; v < g.vertex_total; ++v) more(uint32_t(v));
        final_setup = SetupTriangles{raw(scratch.vertices.ptr()), raw(g.triangles.ptr()), raw(g.edge_flags.ptr()),
                                     raw(g.edge_neighbours.ptr()), tri_count, raw(scratch.setup.ptr()),
                                     raw(scratch.drawn.ptr()), last_x, last_y};
        setupRangeCpu(final_setup, uint32_t(triangle_total), uint32_t(added), appended_drawn);
    }
    // The drawn list: chunk after chunk (ascending), then the appended triangles.
    scratch.drawn_count = uint32_t(drawn_total + appended_drawn.size());
    scratch.drawn_ids.resize(std::max<uint32_t>(1, scratch.drawn_count));
    uint32_t* at = raw(scratch.drawn_ids.ptr());
    for (size_t c = 0; c < chunk_count; ++c) {
        const std::vector<uint32_t>& d = scratch.occluder_chunk_lists[c].drawn;
        at = std::copy(d.begin(), d.end(), at);
    }
    std::copy(appended_drawn.begin(), appended_drawn.end(), at);
    copyDrawnSetup(raw(g.positions.ptr()), raw(g.triangles.ptr()), final_setup, scratch, /*seams=*/true);
    depthRasterTilesCpu(binnedTiles(tri_count, camera, depth, scratch));
    return g.triangle_total;
#endif
}

const char* depthRasterTarget() {
#if defined(__CUDACC__)
    return "CUDA";
#else
    return depthRasterCpuTarget();
#endif
}

}  // namespace occ::k
