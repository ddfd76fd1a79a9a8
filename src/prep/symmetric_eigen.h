// SPDX-License-Identifier: MIT
#pragma once

namespace occ {

// Eigenvalues and eigenvectors of a symmetric 3x3 matrix by cyclic Jacobi rotations (Numerical
// Recipes §11.1), accurate for nearly equal eigenvalues. a is overwritten (its diagonal ends as
// the eigenvalues, in values); vectors[k][i] is component k of eigenvector i (columns).
void symmetricEigen(double a[3][3], double values[3], double vectors[3][3]);

}  // namespace occ
