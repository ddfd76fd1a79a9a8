// SPDX-License-Identifier: MIT
#pragma once

#include "device_memory.h"
#include "kernel_types.h"

#include <vector>

namespace occ::k {

// The rules of the occluder depth rasteriser, shared with the tests and with whoever reasons
// about conservativeness (hzm_test).
//
// Window coordinates are snapped to 1/256 pixel, the sub-pixel grid GPUs rasterise on (8 bits,
// D3D11 and Vulkan's usual subPixelPrecisionBits), so coverage is decided exactly in integers
// and the same on every back end. A pixel centre is covered when it lies inside the snapped
// triangle at least kDepthRasterMarginUnits/256 pixel (1/64) from every edge not shared within
// its mesh, so a pixel centre on an occluder's boundary, or within 1/64 pixel of it, is never
// covered: whatever fill rule a GPU uses, the occluder never covers a centre it does not really
// cover.
// Edges shared within a mesh (sharedEdgeFlags) lie inside the occluder, where the margin would
// leave a crack that no triangle covers and that the max-pyramid spreads over its coarse levels.
// They take no margin but the top-left tie rule on the snapped edge functions instead (D3D's):
// a centre exactly on the edge is covered by the triangle for which, taken counter-clockwise
// with y up, the edge runs down or runs left horizontally, so by exactly one of the two, and a
// tessellated surface covers every centre inside its boundary margin, corners where shared
// edges meet included.
// Where a mesh folds over on screen (its two triangles on the same side of the shared edge, as
// at every silhouette of a closed mesh), or the triangle across the edge is skipped, the edge is
// a boundary of the image: given the triangle across each edge (edge_neighbours), the raster
// sees that and keeps the margin there, since a GPU's different rounding of a corner (below
// 1/256 pixel) could otherwise leave uncovered a centre this raster covers. (Measured before
// this rule: on plant20k's walk, 10 % of the shared edges drawn were such folds, and 4 of 1200
// frames had an object culled that the GPU showed in about 10 pixels along one such edge.)
inline constexpr int32_t kDepthRasterSubpixelUnits = 256;
inline constexpr int32_t kDepthRasterMarginUnits = 4;
// A covered pixel gets the triangle's window depth at its centre pushed away, the MIN over every
// triangle covering it. The push is this epsilon (for a GPU's rounding and ours) plus 2^-20
// times the largest |depth| the triangle's plane takes over its pixel box (a bound on the
// rounding of the float plane evaluation): about 2 * kDepthRasterEpsilon for a triangle that is
// not seen nearly edge-on, never less than kDepthRasterEpsilon.
inline constexpr float kDepthRasterEpsilon = 1.0f / (1 << 20);
// Triangles with a corner farther than this from the viewport's origin in window x or y are
// skipped (so that snapped coordinates fit 32-bit and edge functions 64-bit integers). Only
// triangles with a corner just in front of the near plane and far off to the side get there.
inline constexpr float kDepthRasterGuardBand = float(1 << 20);
// Triangles with a corner of larger window depth are skipped: no perspective projection with
// far >= 2 * near puts anything there, and it keeps every depth small and finite.
inline constexpr float kDepthRasterMaxDepth = 2.0f;
// Screen tiles of this many pixels square are the unit of parallel work.
inline constexpr uint32_t kDepthRasterTileSize = 32;

struct DepthRasterVertex;    // per-vertex projection, defined in depth_raster.cu
struct DepthRasterTriangle;  // per-triangle setup, defined in depth_raster.cu

// Scratch memory of depthRaster, kept by the caller between frames: a call allocates only when
// it needs more than any call before it. Its contents are meaningless between calls. One
// scratch per concurrent call.
struct DepthRasterScratch {
    DeviceArray<DepthRasterVertex> vertices;  // largest index + 1
    DeviceArray<DepthRasterTriangle> setup;   // tri_count (entries of undrawn triangles stale)
    DeviceArray<uint8_t> drawn;               // tri_count: 1 where setup holds a drawn triangle
    DeviceArray<uint32_t> drawn_ids;          // tri_count: the drawn triangles, ascending
    uint32_t drawn_count = 0;                 // entries of drawn_ids in use
    DeviceArray<DepthRasterTriangle> drawn_setup;  // drawn_count: setup of drawn_ids[i], seams applied
    DeviceArray<uint64_t> cells;              // (tiles x binning chunks) + 1 counts, then offsets
    DeviceArray<uint32_t> pair_triangle;      // one per (tile, triangle) pair, grouped by tile: drawn position
    // Seams between occluders (see depthRaster): the boundary edges of drawn triangles, their
    // keys, and per triangle the edges found shared across.
    DeviceArray<uint32_t> edge_first;         // tri_count + 1: exclusive scan of boundary edges
    DeviceArray<uint32_t> edge_ids;           // 3 * triangle + stored edge, one per boundary edge
    DeviceArray<uint64_t> edge_keys;          // hash of the edge's world endpoints, unordered
    DeviceArray<uint32_t> key_groups;         // CPU build: a hash table of edge_keys and its chains
    std::vector<uint64_t> grouped_keys;       // CPU build: the keys shared by several edges, grouped
    std::vector<uint32_t> grouped_ids;        // and their edges
    DeviceArray<uint8_t> seam_edges;          // 3 per drawn triangle: 1 where a stored edge is shared across
    DeviceArray<uint8_t> seam_bits;           // per drawn triangle: the same as bits
    DeviceArray<uint32_t> seam_triangles;     // the drawn positions of triangles with such bits
    // rasterOccluders' CPU front end: the first occluder of each chunk, then the count; per
    // chunk, the triangles it drew and those across the near plane with how many corners in
    // front; the drawn ones among the clipped parts appended.
    std::vector<uint32_t> occluder_chunks;
    struct ChunkLists {
        std::vector<uint32_t> drawn, crossing;
        std::vector<uint8_t> crossing_front;
    };
    std::vector<ChunkLists> occluder_chunk_lists;
    std::vector<uint32_t> occluder_appended_drawn;
};

// Marks the edges that a triangle list shares within itself, once per mesh: flags[t] gets bit e
// (e = 0, 1, 2) set when edge e of triangle t, from corner e to corner (e + 1) % 3, is used by
// exactly one other triangle of the list and in the opposite direction, as in a consistently
// wound surface; the other bits are cleared. Edges that three or more triangles use, that two
// use in the same direction, or whose two corners are one index are not shared (they keep the
// margin, which only loses occlusion).
// triangles: 3 * tri_count corner indices, any values (may be empty). flags: tri_count bytes.
// Host code, one thread. Cost: a hash table of the edges, O(tri_count) expected time and 24
// bytes per slot, 4.5 to 9 slots per triangle, of temporary memory (108 to 216 bytes per
// triangle); the 3.7 M triangles of the 20 000 meshes of plant20k.oss take 0.17 s on one core.
// neighbours: null, or 3 * tri_count entries: for a shared edge e of triangle t,
// neighbours[3t+e] is the other triangle using it; UINT32_MAX for edges not shared.
void sharedEdgeFlags(const uint32_t* triangles, uint32_t tri_count, uint8_t* flags, uint32_t* neighbours = nullptr);

// Bits of the per-triangle flag byte beyond sharedEdgeFlags' three shared-edge bits.
// kEdgeFlagClosedMesh: the triangle's mesh is closed (every edge of every triangle shared, as
// sharedEdgeFlags has it: each edge used by exactly two triangles, in opposite directions) and
// wound counter-clockwise seen from outside (positive signed volume). markClosedMeshes sets it;
// depthRaster ignores it.
// kEdgeFlagSkipBackFace: depthRaster (and maskedDepthRaster) skip the triangle when it faces
// away, i.e. is clockwise on screen with y up. gatherOccluders sets it on the triangles of
// closed meshes whose object is not mirrored and whose world box does not hold the eye: from
// outside a closed surface, every ray that meets it where it faces away met it nearer where it
// faces the eye, so the front faces alone write the same nearest depths. Skipping occluder
// triangles only ever loses occlusion, never culls more, so the rule is safe even where its
// premises fail (a mesh that intersects itself, a camera inside a concave mesh's hollow).
inline constexpr uint8_t kEdgeFlagSkipBackFace = 8;
inline constexpr uint8_t kEdgeFlagClosedMesh = 16;

// Sets kEdgeFlagClosedMesh on all tri_count flags when the mesh they describe (sharedEdgeFlags
// already ran on them) is closed and outward, as above; leaves them as they are otherwise.
// triangles: 3 * tri_count corners into positions (the mesh's own numbering). Host code.
// Returns whether it set them.
bool markClosedMesh(const uint32_t* triangles, uint32_t tri_count, const glm::vec3* positions, uint8_t* flags);

// Conservative software depth rasterisation of occluder triangles into a W x H depth buffer,
// W = camera.width, H = camera.height (each in [0, 32768], else std::invalid_argument; 0 draws
// nothing).
// All arrays are device memory. positions: world-space vertices (already transformed by the
// caller). Every vertex up to the
// largest index in `triangles` is projected, so pass a compact array (the occluders' vertices,
// not the whole scene's). triangles: 3 * tri_count corner indices (may be empty). edge_flags:
// tri_count bytes as sharedEdgeFlags makes them (for the triangles of each mesh, so that only
// edges shared within one mesh are flagged: two meshes that touch are still two boundaries), or
// null, which gives every edge the margin. edge_neighbours: null (then every flagged edge takes
// the tie rule), or 3 * tri_count triangle indices into this list as sharedEdgeFlags gives
// them per mesh (offset by the mesh's first triangle here), so that folds and edges whose
// neighbour is skipped keep the margin (see above). Projection and depth follow kernels.md:
// window x = (ndc.x*0.5+0.5)*W, y up, depth = ndc.z*0.5+0.5.
// depth: W*H floats, row-major (index y*W+x); this function CLEARS it to 1.0 (far) and then,
// for every pixel whose centre a triangle covers (see the rules above), writes the minimum over
// those triangles of their pushed depth at the centre (values above 1 leave 1).
// Seams (seams = true, as the pipeline calls it): an edge of a drawn triangle that would keep the margin (not shared within its mesh,
// or a fold) takes the tie rule instead when another drawn triangle of the list, of any mesh,
// has an edge with bit-identical world-space endpoints running the other way round on screen,
// so that the two lie on either side of it: the union of two occluders that abut exactly (two
// wall panels, a wall on a slab) is then rastered without the 1/32-pixel crack the two margins
// left, which a pixel centre sometimes fell into and through which whole halls stayed visible.
// Identical endpoints project and snap identically on any rasteriser, so the GPU's image of the
// two has no crack there either; matching is exact (no tolerance), so occluders that merely
// nearly touch keep their margins.
// Skipped, which only loses occlusion: triangles with a corner behind the near plane
// (clip.w <= 0 or clip.z < -clip.w), a corner outside the guard band or deeper than
// kDepthRasterMaxDepth, a NaN, zero snapped area, or facing away (clockwise on screen) with
// kEdgeFlagSkipBackFace in its flags. Both windings are drawn otherwise. Without flags
// the margin holds on every edge, shared ones too: a centre within 1/64 pixel of the edge
// between two triangles of one mesh then belongs to neither and stays far. Deterministic: the
// result depends neither on the thread count nor on the back end.
// Memory: scratch grows to 16 bytes per vertex, 77 per triangle, 4 per (32x32 tile, triangle)
// pair of overlapping screen boxes, 8 per (tile, 4096 triangles), at most 32 MB, and 12 per
// boundary edge of a drawn triangle.
void depthRaster(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles, uint32_t tri_count,
                 DevicePtr<const uint8_t> edge_flags, DevicePtr<const uint32_t> edge_neighbours, const Camera& camera,
                 DevicePtr<float> depth, DepthRasterScratch& scratch, bool seams = false);

// depthRaster with the one-thread-per-tile loop the CUDA build runs, whatever the build: on
// the CPU, the reference that depthRaster's SIMD tile loop must match bit for bit.
void depthRasterScalar(DevicePtr<const glm::vec3> positions, DevicePtr<const uint32_t> triangles, uint32_t tri_count,
                       DevicePtr<const uint8_t> edge_flags, DevicePtr<const uint32_t> edge_neighbours,
                       const Camera& camera, DevicePtr<float> depth, DepthRasterScratch& scratch, bool seams = false);

// The instruction set depthRaster's tile loop runs with here: "CUDA", or on the CPU the SIMD
// level (kernels/simd_level.h: "AVX-512", "AVX2", "SSE4" or "portable").
const char* depthRasterTarget();

}  // namespace occ::k
