/*
 * linalg.h — internal: small dense linear algebra (DESIGN.md 4.2).
 *
 * Symmetric 3x3 matrices are 6 doubles m11 m12 m13 m22 m23 m33 (the public order).
 * General 3x3 matrices are 9 doubles, row-major: a[3*i + j] = A_ij.
 */
#ifndef ANISTAR_LINALG_H
#define ANISTAR_LINALG_H

#include <stddef.h>

/*
 * Eigen-decomposition of a symmetric 3x3 matrix: A = V diag(w) V^T.
 * w: eigenvalues in ascending order. vec: eigenvectors, vec + 3*k is the unit
 * eigenvector of w[k]; the three form a right-handed orthonormal basis.
 * Accurate (residual and orthogonality ~1e-15 relative to |A|) for ill-conditioned
 * matrices and repeated eigenvalues. Returns 0, or -1 if A has a non-finite entry
 * (then w and vec are filled with NaN).
 */
int as_sym3_eigen(const double a[6], double w[3], double vec[9]);

/* Build the symmetric matrix V diag(w) V^T from eigenvectors vec (as above, need only be
 * orthonormal) and values w. */
void as_sym3_from_eigen(const double w[3], const double vec[9], double a[6]);

/* Helpers on symmetric 3x3 / general 3x3 matrices. */
void as_sym3_to_mat3(const double s[6], double m[9]);
void as_mat3_mul(const double a[9], const double b[9], double c[9]);
void as_mat3_vec(const double a[9], const double x[3], double y[3]);

/*
 * Dense least squares: minimise |A x - b| for A of m rows and n columns (m >= n,
 * n <= 15, row-major a[i*n + j]) by Householder QR with column pivoting.
 * work must hold as_lsq_work_size(m, n) doubles. Returns the numerical rank
 * (< n when A is rank-deficient; the minimum-norm-ish basic solution is returned
 * then, with the free components set to 0), or -1 on invalid input (non-finite
 * entries, n > 15, m < n). x has n entries.
 */
size_t as_lsq_work_size(size_t m, size_t n);
int as_lsq_solve(const double *a, const double *b, size_t m, size_t n, double *x, double *work);

#endif /* ANISTAR_LINALG_H */
