// SPDX-License-Identifier: MIT
#pragma once

#include <glm/glm.hpp>

namespace occ {

// The point x that minimises x^T A x + 2 b^T x (a sum of squared distances to planes, A = sum
// w n n^T, b = sum w d n, A symmetric positive semi-definite) nearest `centre` along the
// directions the planes leave free: A's eigenvalues under 1e-3 of the largest count as zero
// (Lindstrom 2000's truncated inverse), so that a flat set of planes keeps the point on its
// plane and two planes keep it on their edge. `centre` when A is zero.
glm::dvec3 leastSquaresPoint(const glm::dmat3& a, const glm::dvec3& b, const glm::dvec3& centre);

}  // namespace occ
