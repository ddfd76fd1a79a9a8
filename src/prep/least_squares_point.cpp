// SPDX-License-Identifier: MIT
#include "prep/least_squares_point.h"

#include <algorithm>
#include <cmath>

namespace occ {

namespace {

// Eigenvalues and eigenvectors (columns of `vectors`) of a symmetric 3x3 matrix, cyclic Jacobi.
void symmetricEigen(glm::dmat3 m, glm::dvec3& values, glm::dmat3& vectors) {
    vectors = glm::dmat3(1.0);
    for (int sweep = 0; sweep < 16; ++sweep) {
        const double off = m[0][1] * m[0][1] + m[0][2] * m[0][2] + m[1][2] * m[1][2];
        const double scale = m[0][0] * m[0][0] + m[1][1] * m[1][1] + m[2][2] * m[2][2];
        if (off <= 1e-24 * scale) break;
        for (int p = 0; p < 2; ++p)
            for (int q = p + 1; q < 3; ++q) {
                if (m[p][q] == 0.0) continue;
                const double theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
                const double t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1.0));
                const double c = 1.0 / std::sqrt(t * t + 1.0), s = t * c;
                glm::dmat3 r(1.0);
                r[p][p] = c, r[q][q] = c, r[q][p] = s, r[p][q] = -s;  // glm: r[column][row]
                m = glm::transpose(r) * m * r;
                vectors = vectors * r;
            }
    }
    values = {m[0][0], m[1][1], m[2][2]};
}

}  // namespace

glm::dvec3 leastSquaresPoint(const glm::dmat3& a, const glm::dvec3& b, const glm::dvec3& centre) {
    glm::dvec3 values;
    glm::dmat3 vectors;
    symmetricEigen(a, values, vectors);
    const double largest = std::max({values.x, values.y, values.z});
    if (!(largest > 0.0)) return centre;
    const glm::dvec3 residual = -(a * centre + b);
    glm::dvec3 x = centre;
    for (int i = 0; i < 3; ++i)
        if (values[i] > 1e-3 * largest) x += vectors[i] * (glm::dot(vectors[i], residual) / values[i]);
    return x;
}

}  // namespace occ
