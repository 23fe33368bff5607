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
 * eigenvector of w[k]; the three form a right-handed orthonormal basis (vec0 and vec1
 * have a positive entry of largest magnitude: a canonical sign).
 * Accurate (residual and orthogonality ~1e-15 relative to |A|, tested to 1e-13) for
 * ill-conditioned matrices and repeated eigenvalues; small eigenvalues of graded matrices
 * (e.g. D C D, D diagonal) keep high relative accuracy. Deterministic (classical Jacobi,
 * provably bounded number of rotations, ~9 in practice). Returns 0, or -1 if A has a
 * non-finite entry (then w and vec are filled with NaN). The zero matrix gives w = 0 and
 * the identity.
 */
int as_sym3_eigen(const double a[6], double w[3], double vec[9]);

/* Build the symmetric matrix V diag(w) V^T from eigenvectors vec (as above, need only be
 * orthonormal) and values w. */
void as_sym3_from_eigen(const double w[3], const double vec[9], double a[6]);

/* Helpers on symmetric 3x3 / general 3x3 matrices. as_mat3_mul: c = a b (c may alias a
 * or b); as_mat3_vec: y = a x (y may alias x); sums are evaluated left to right. */
void as_sym3_to_mat3(const double s[6], double m[9]);
void as_mat3_mul(const double a[9], const double b[9], double c[9]);
void as_mat3_vec(const double a[9], const double x[3], double y[3]);
/* a = G^T G (symmetric, 6 doubles) for a general G (9 doubles). */
void as_mat3_gram(const double g[9], double a[6]);

/*
 * Dense least squares: minimise |A x - b| for A of m rows and n columns (m >= n,
 * 1 <= n <= 15, row-major a[i*n + j]) by Householder QR with column pivoting, after
 * scaling every column to unit norm (exactly, by powers of two: the units of the unknowns
 * do not matter). work must hold as_lsq_work_size(m, n) doubles (it may not alias a, b, x).
 * Returns the numerical rank (see AS_LSQ_RCOND), or -1 on invalid input (n == 0, n > 15,
 * m < n, a non-finite entry). When the rank r < n, x is the basic solution: the n - r
 * columns that pivoting left last get x_j = 0 and the rest solve the least-squares problem
 * on the others (still a least-squares solution; not the minimum-norm one). x has n
 * entries and holds no NaN for valid input.
 */
/* m * n + m; 0 if that overflows size_t. */
size_t as_lsq_work_size(size_t m, size_t n);
int as_lsq_solve(const double *a, const double *b, size_t m, size_t n, double *x, double *work);

/*
 * The rank tolerance of as_lsq_solve: after every column of A is scaled to unit norm
 * (exactly, by a power of two), the pivot k counts in the rank iff
 * |R_kk| > AS_LSQ_RCOND * |R_00|. 1e-12 is ~1000x above the rounding level of an exactly
 * rank-deficient A of a few hundred rows (|R_kk| ~ sqrt(m) n eps ~ 1e-14) and far below
 * the conditioning of any fit worth solving; use as_lsq_solve_rcond for another value.
 */
#define AS_LSQ_RCOND 1e-12
/* as_lsq_solve with the rank tolerance rcond in [0, 1) instead of AS_LSQ_RCOND. */
int as_lsq_solve_rcond(const double *a, const double *b, size_t m, size_t n, double rcond,
                       double *x, double *work);

#endif /* ANISTAR_LINALG_H */
