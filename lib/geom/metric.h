/*
 * metric.h — internal: metric tensors (DESIGN.md 4.2, paper 2.1-2.2).
 *
 * A metric M is SPD; F = U diag(e) U^T is its symmetric square root (F^T F = M),
 * d_M(a, b) = |F (a - b)|. A site stores F and F^-1 once (as_metric_frame).
 */
#ifndef ANISTAR_METRIC_H
#define ANISTAR_METRIC_H

typedef struct as_metric_frame {
    double m[6];    /* M, symmetric (m11 m12 m13 m22 m23 m33) */
    double f[9];    /* F = M^(1/2), row-major */
    double finv[9]; /* F^-1, row-major */
    double e[3];    /* eigenvalues of F, ascending (sqrt of M's) */
    double u[9];    /* eigenvectors: u + 3*k belongs to e[k] */
} as_metric_frame;

/* Fill mf from M. Returns 0, or -1 if M has a non-finite entry, is not symmetric
 * positive definite, or its condition number exceeds 1e24 (F's 1e12). */
int as_metric_frame_init(as_metric_frame *mf, const double m[6]);

/* Fill mf from an orthonormal frame u (u + 3*k unit vectors) and F's eigenvalues e > 0
 * (M = U diag(e^2) U^T). Returns 0, or -1 if e is not finite and positive. */
int as_metric_frame_from_eigen(as_metric_frame *mf, const double u[9], const double e[3]);

/* y = F x, always computed the same way (so stretched coordinates are reproducible
 * bit for bit). */
void as_metric_apply(const as_metric_frame *mf, const double x[3], double y[3]);
/* y = F^-1 x. */
void as_metric_unapply(const as_metric_frame *mf, const double x[3], double y[3]);
/* d_M(a, b) = |F (a - b)|. */
double as_metric_dist(const as_metric_frame *mf, const double a[3], const double b[3]);

/* Distortion gamma(M, N) = max(|F_M F_N^-1|, |F_N F_M^-1|) >= 1 (paper 2.2). */
double as_metric_distortion(const as_metric_frame *a, const as_metric_frame *b);
/* 1 if gamma(M, N) <= g, 0 otherwise; the trace filter of DESIGN.md 4.2 settles most
 * pairs without an eigen-solve. */
int as_metric_distortion_le(const as_metric_frame *a, const as_metric_frame *b, double g);

/* Half-extents of the axis-aligned box of the M-ellipsoid {x : |F(x - c)| <= r}:
 * h[i] = r * |row_i(F^-1)|. */
void as_metric_ellipsoid_box(const as_metric_frame *mf, double r, double h[3]);

#endif /* ANISTAR_METRIC_H */
