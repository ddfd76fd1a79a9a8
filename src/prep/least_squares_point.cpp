// SPDX-License-Identifier: MIT
#include "prep/least_squares_point.h"

#include "prep/symmetric_eigen.h"

#include <algorithm>
#include <cmath>

namespace occ {

glm::dvec3 leastSquaresPoint(const glm::dmat3& a, const glm::dvec3& b, const glm::dvec3& centre) {
    double m[3][3], values[3], vectors[3][3];
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) m[i][j] = a[j][i];  // glm: a[column][row]
    symmetricEigen(m, values, vectors);
    const double largest = std::max({values[0], values[1], values[2]});
    if (!(largest > 0.0)) return centre;
    const glm::dvec3 residual = -(a * centre + b);
    glm::dvec3 x = centre;
    for (int i = 0; i < 3; ++i) {
        const glm::dvec3 e(vectors[0][i], vectors[1][i], vectors[2][i]);
        if (values[i] > 1e-3 * largest) x += e * (glm::dot(e, residual) / values[i]);
    }
    return x;
}

}  // namespace occ
