/*
 * metric.h — internal: metric tensors (DESIGN.md 4.2, paper 2.1-2.2).
 *
 * A metric M is SPD; F = U diag(e) U^T is its symmetric square root (F^T F = M),
 * d_M(a, b) = |F (a - b)|. A site stores F and F^-1 once (as_metric_frame).
 */
#ifndef ANISTAR_METRIC_H
#define ANISTAR_METRIC_H

#include <math.h>

typedef struct as_metric_frame {
    double m[6];    /* M, symmetric (m11 m12 m13 m22 m23 m33) */
    double f[9];    /* F = M^(1/2), row-major, exactly symmetric (f[3i+j] == f[3j+i]) */
    double finv[9]; /* F^-1, row-major, exactly symmetric */
    double e[3];    /* eigenvalues of F, ascending (sqrt of M's) */
    double u[9];    /* eigenvectors: u + 3*k belongs to e[k] */
} as_metric_frame;

/* Fill mf from M. Returns 0, or -1 (mf zeroed) if M has a non-finite entry, is not
 * positive definite, or its condition number exceeds 1e24 (F's 1e12), as computed by
 * as_sym3_eigen. mf->m is M bit for bit; F^T F = M to ~1e-15 |M|. Every valid frame
 * (from either constructor) has max e / min e <= 1e12. */
int as_metric_frame_init(as_metric_frame *mf, const double m[6]);
/* The test of as_metric_frame_init alone: 0 with F's eigenvalues e (ascending) and the
 * eigenvectors u (u + 3*k for e[k]) that a frame of M would hold, or -1 where
 * as_metric_frame_init fails (without F and F^-1: a validity check costs one
 * eigendecomposition and no more). */
int as_metric_frame_eigen(const double m[6], double e[3], double u[9]);

/* Fill mf from an orthonormal frame u (u + 3*k unit vectors) and F's eigenvalues e > 0
 * (M = U diag(e^2) U^T); the pairs (e[k], u + 3k) are sorted ascending into mf. Returns 0,
 * or -1 if e is not finite and positive, max e / min e > 1e12, or u is not finite and
 * orthonormal to within 1e-9 (|u_i . u_j - delta_ij|). */
int as_metric_frame_from_eigen(as_metric_frame *mf, const double u[9], const double e[3]);

/* y = F x, always computed the same way: y_i = (f_i0 x_0 + f_i1 x_1) + f_i2 x_2, so
 * stretched coordinates are reproducible bit for bit (y may alias x). */
static inline void as_metric_mul3(const double a[9], const double x[3], double y[3]) {
    double x0 = x[0], x1 = x[1], x2 = x[2];
    double y0 = (a[0] * x0 + a[1] * x1) + a[2] * x2;
    double y1 = (a[3] * x0 + a[4] * x1) + a[5] * x2;
    double y2 = (a[6] * x0 + a[7] * x1) + a[8] * x2;
    y[0] = y0;
    y[1] = y1;
    y[2] = y2;
}
static inline void as_metric_apply(const as_metric_frame *mf, const double x[3], double y[3]) {
    as_metric_mul3(mf->f, x, y);
}
/* y = F^-1 x. */
static inline void as_metric_unapply(const as_metric_frame *mf, const double x[3], double y[3]) {
    as_metric_mul3(mf->finv, x, y);
}
double as_norm3_scaled(const double v[3], double s);
/* d_M(a, b) = |F (a - b)|, without spurious overflow or underflow; d(a, b) == d(b, a).
 * Inline: the mesher calls it in its innermost loops. */
static inline double as_metric_dist(const as_metric_frame *mf, const double a[3],
                                    const double b[3]) {
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]}, y[3];
    as_metric_mul3(mf->f, d, y);
    double s = y[0] * y[0] + y[1] * y[1] + y[2] * y[2];
    if (s >= 0x1p-1022 && s <= 0x1.fffffffffffffp+1023) return sqrt(s);
    return as_norm3_scaled(y, s);
}

/* Distortion gamma(M, N) = max(|F_M F_N^-1|, |F_N F_M^-1|) >= 1 (paper 2.2), computed as
 * sqrt(max(lambda_max(G^T G), lambda_max(H^T H))), G = F_M F_N^-1, H = F_N F_M^-1 (equal to
 * DESIGN.md 4.2's sqrt(max(lambda_max(A), 1 / lambda_min(A))), A = F_N^-1 M F_N^-1, but
 * more accurate). Exactly 1 for frames with the same F; symmetric bit for bit; relative
 * error ~1e-15 for moderate anisotropy (see metric.c). ~1 us (two Jacobi solves). */
double as_metric_distortion(const as_metric_frame *a, const as_metric_frame *b);
/* 1 if gamma(M, N) <= g, 0 otherwise (0 for g < 1 or NaN). A filter (DESIGN.md 4.2's
 * trace filter, sharpened: bounds on lambda_max from the trace and the deviatoric norm of
 * the Gram matrices, then an exact sign test on their characteristic polynomials) settles
 * nearly every pair without an eigen-solve (~0.15 us); the answer equals
 * (as_metric_distortion(a, b) <= g) except possibly when gamma is within ~1e-13 relative
 * of g. */
int as_metric_distortion_le(const as_metric_frame *a, const as_metric_frame *b, double g);
/* The filter of as_metric_distortion_le alone: 1 when it proves gamma <= g, 0 when it proves
 * gamma > g, -1 when it cannot tell (then as_metric_distortion_le solves for gamma). For
 * tests and benchmarks. */
int as_metric_distortion_filter(const as_metric_frame *a, const as_metric_frame *b, double g);
/* as_metric_distortion(a, b) where as_metric_distortion_le(a, b, g) is 0, and 0 where the
 * filter proves gamma <= g (then gamma < g up to its margin): the decision and the value
 * from one pair of Gram matrices, bit for bit those of the two calls (g >= 1). */
double as_metric_distortion_over(const as_metric_frame *a, const as_metric_frame *b, double g);

/* Half-extents of the axis-aligned box of the M-ellipsoid {x : |F(x - c)| <= r}:
 * h[i] = r * |row_i(F^-1)|. */
void as_metric_ellipsoid_box(const as_metric_frame *mf, double r, double h[3]);
/* The unit half-extents n[i] = |row_i(F^-1)|: as_metric_ellipsoid_box(mf, r, h) is
 * h[i] = r * n[i], bit for bit (for callers that take many boxes of one frame). */
void as_metric_box_axes(const as_metric_frame *mf, double n[3]);

#endif /* ANISTAR_METRIC_H */
