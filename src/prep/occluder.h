// SPDX-License-Identifier: MIT
#pragma once

#include "scene/prepared_scene.h"

#include <glm/glm.hpp>

#include <cstdint>
#include <vector>

namespace occ {

// What occluder qualification (Peng 2014, §5.1) needs to know about one mesh, in its local space.
struct OccluderData {
    OrientedBox oobb;                        // tight oriented bounding box (OOBB)
    glm::vec3 largest_face_normal{0, 0, 1};  // oobb.axis[2]: normal of the OOBB's largest face (Eq. 3's N)
    float compactness = 0.0f;                // Eq. 2, in [0, 1]
};

// Computes the OOBB, its largest face's normal and the compactness of one triangle mesh.
//
// positions are the mesh's vertices and triangles its triangle list, both in local space;
// positions must be finite. Every position counts for the box, referenced by a triangle or not;
// a triangle with an index >= positions.size() is ignored, and so are trailing indices when
// triangles.size() is not a multiple of 3. Either vector may be empty.
//
// The OOBB's axes are orthonormal and right-handed (axis[0] x axis[1] = axis[2]) and sorted by
// decreasing half extent, so axis[2] is the normal of the largest face. It is the smallest-volume
// box among: the local axis-aligned box, the principal axes of the surface (area-weighted triangle
// covariance, so uneven tessellation does not tilt it), and, for each of several fixed axes (local
// x/y/z, the principal axes, the normals of the largest triangles, then the best box's own axes),
// the minimum-area rectangle of the projection onto the plane across that axis (rotating calipers
// over its 2D convex hull). Boxes and prisms (cylinders) come out with their true volume, up to
// float rounding, whatever their orientation; in general it is a heuristic, not the optimum. The
// box holds every position as stored, in floats: its half extents are measured from the float
// centre along the float axes and rounded up, plus 4 float ulps of the box's size so that
// evaluating dot(p - center, axis) in floats cannot put a vertex outside either. Flat and line-like
// meshes get (up to that margin) zero half extents across them; an empty mesh gets a zero box at
// the origin with the identity axes.
//
// compactness follows Eq. 2 of Peng & Cao 2013 ("Integrating occlusion culling with parallel
// LOD for rendering complex 3D environments on GPU", I3D): for each OOBB axis a, A_a is the
// area of the OOBB face across a, R_a the pixels of a raster spanning that face and P_a the
// pixels the mesh's triangles cover when projected orthographically along a:
//     compactness = (sum_a A_a * P_a / R_a) / (sum_a A_a)
// A solid box or a slab gives 1, a sphere about pi/4, an L-shaped bracket 0.5 to 0.9, an X of
// two thin rods nearly 0.
// resolution is the raster's pixel count along the longer side of each face (the shorter side
// gets the proportional count, at least 1); it is clamped to [1, 4096]. Pixels are sampled at
// their centres with exact fixed-point edge functions (1/256 pixel) and a top-left rule, so
// triangles sharing an edge leave no cracks. Faces of zero area (A_a = 0, e.g. across a flat
// mesh's thin axis) drop out of both sums; a mesh whose faces all have zero area (all points on
// a line), or that has no triangles, gets 0. Extents below 1e-5 of the longest one, or within
// 16 float ulps of the coordinates' magnitude, count as zero here, since float positions of a
// flat or straight mesh scatter by about that much.
//
// Runs in O(positions + triangles) time (plus the raster of resolution^2 pixels per axis) on
// the calling thread; callers parallelise over meshes.
OccluderData computeOccluderData(const std::vector<glm::vec3>& positions, const std::vector<uint32_t>& triangles,
                                 int resolution = 64);

// The box that contains `local` mapped through the affine transform `world` (its bottom row is
// taken to be 0, 0, 0, 1). Exact when world maps the box's axes to mutually orthogonal directions:
// rotations, reflections, translations, uniform scale, and non-uniform scale along the box's axes.
// Otherwise (shear, or non-uniform scale across the box's axes) the image is a parallelepiped, and
// the result is the smallest of the boxes aligned with a Gram-Schmidt frame of its edges (all six
// orders tried) that contain it: conservative, not minimal. A singular world gives (up to the float
// margin below) zero half extents along the collapsed directions. The result's axes follow
// computeOccluderData's convention (orthonormal, right-handed, decreasing half extent), and half
// extents hold the image's corners with the same float margin as computeOccluderData's.
OrientedBox transformBox(const OrientedBox& local, const glm::mat4& world);

// 8 * hx * hy * hz.
float boxVolume(const OrientedBox& box);

}  // namespace occ
