/*
 * jet.h — internal: local polynomial fitting ("jets", Cazals and Pouget 2005) for the
 * normal and principal curvatures of a sampled surface, and the Gaussian blending of
 * per-vertex metric tensors (paper 5.2.3; DESIGN.md 4.7).
 *
 * Conventions are those of surface.h: the normal is the OUTWARD unit normal when an
 * orientation hint is given (otherwise it is the PCA normal with an arbitrary sign), and
 * the principal curvatures are positive where the surface is convex seen from outside (a
 * sphere of radius r: +1/r), k[0] >= k[1], with unit principal directions d (of k[0]) and
 * d + 3 (of k[1]) such that (d, d + 3, n) is a right-handed orthonormal frame.
 *
 * Nothing here allocates except as_blend_create and the far-point path of as_blend_eval
 * (see there); everything takes its inputs const, so several threads may
 * fit and blend at once.
 */
#ifndef ANISTAR_JET_H
#define ANISTAR_JET_H

#include "core.h"
#include "geom/kdtree.h"

#include <stddef.h>

/* Most points one fit takes (the fit keeps its least-squares system on the stack:
 * AS_JET_MAX_POINTS x 15 doubles, twice). */
#define AS_JET_MAX_POINTS 64
/* Default numbers of neighbours (the fitting vertex included) for degrees 2 and 4: about
 * 2.7 and 1.9 times the number of coefficients (6 and 15), so the least-squares problem
 * is well over-determined on irregular meshes (CGAL's examples use 15-30). Degree 3 takes
 * the degree-4 default. */
#define AS_JET_K2 16
#define AS_JET_K4 28
/*
 * The least-squares rows are weighted: row i is multiplied by exp(-AS_JET_WEIGHT
 * (rho_i / rho_max)^2), rho_i the distance of point i from the height axis and rho_max the
 * largest, so the residual of the farthest points counts exp(-8) ~ 3e-4 as much as the
 * nearest ones. Why: the bias of a jet of degree d on a smooth surface grows like
 * rho^(d-1) (the terms of degree d+1 and d+2 of the true height function that the
 * polynomial cannot represent), so near points should dominate, while the far ones keep
 * the system well-determined on irregular samplings. On test/data/sphere_r0.5.off (162
 * vertices, neighbourhoods spanning 35 degrees of arc) the degree-2 curvature error drops
 * from 11% (unweighted) to 4%, degree 4's from 7% to 2%. Exactness on polynomial height
 * functions is unchanged (any positive weights reproduce them).
 */
#define AS_JET_WEIGHT 4.0

/* Number of coefficients of a bivariate polynomial of total degree d: (d+1)(d+2)/2. */
static inline int as_jet_coef_count(int degree) { return (degree + 1) * (degree + 2) / 2; }

/* A fitted jet and the differential quantities at its Monge point. */
typedef struct as_jet {
    double point[3]; /* the Monge point: the fitted surface's point over the fitting origin */
    double n[3];     /* unit normal there */
    double k[2];     /* principal curvatures, k[0] >= k[1] */
    double d[6];     /* unit principal directions: d (of k[0]), d + 3 (of k[1]) */
    double frame[9]; /* the fitting frame u1, u2, w (w: the height axis), right-handed */
    double h;        /* the scale: local coordinates were divided by h */
    double coef[15]; /* height z/h = sum coef[t(t+1)/2 + j] (x/h)^(t-j) (y/h)^j, t <= degree */
    int degree;      /* the degree used (lowered from the one asked when rank-deficient) */
} as_jet;

/*
 * as_jet_fit — fit the height function of n points pts[3i..3i+2] over a local frame at
 * origin, by least squares with a bivariate polynomial of total degree `degree` (1 to 4),
 * and compute the normal, principal curvatures and directions of the fitted surface at the
 * point over origin.
 *   frame   NULL: the frame comes from principal component analysis of the points (the
 *           height axis w is the eigenvector of the smallest eigenvalue of their
 *           covariance); or 9 doubles u1, u2, w (orthonormal, right-handed) to fit over a
 *           given frame (tests; a known tangent plane).
 *   orient  NULL, or a vector whose side the normal must point to: the height axis w (and
 *           so the normal, which is within 90 degrees of w) is flipped when w . orient < 0,
 *           so curvature signs follow the outward convention.
 * Returns 0, or -1 when n < 3, n > AS_JET_MAX_POINTS, a coordinate is not finite, or the
 * points do not spread in two directions of the tangent plane (the smaller eigenvalue of
 * the covariance of their (x, y) at most 1e-12 times the trace: e.g. all on a line), or
 * are too degenerate even for degree 1. When the points
 * cannot determine the asked degree (n below the coefficient count, or numerical rank
 * below it), the degree is lowered until they do; out->degree says which was used
 * (degree 1 gives the plane: curvatures 0 and an arbitrary tangent frame).
 * Exactness: with the points on a polynomial height function of degree <= `degree` over
 * the given frame, the jet is that polynomial up to rounding (relative ~1e-12 for
 * well-spread points).
 * design (Cazals and Pouget, "Estimating differential quantities using polynomial fitting
 * of osculating jets", 2005; paper 5.2.3):
 *   1. frame: PCA of the points about their centroid (or the given frame), oriented;
 *   2. local coordinates (x, y, z) of p - origin in that frame, divided by h = the largest
 *      |(x, y)| (conditioning; as_lsq_solve also equilibrates its columns);
 *   3. weighted least squares (rows scaled by exp(-AS_JET_WEIGHT (x^2 + y^2)); Householder
 *      QR, as_lsq_solve) for the coefficients of z = sum a_ij x^i y^j, lowering the
 *      degree while the rank is deficient;
 *   4. Monge point (0, 0, J(0, 0)); J_x = a10, J_y = a01, J_xx = 2 a20 / h,
 *      J_xy = a11 / h, J_yy = 2 a02 / h; normal (-J_x, -J_y, 1) / rho;
 *   5. second fundamental form on an orthonormal tangent basis (t1, t2):
 *      B_ij = -(J_xx a_i a_j + J_xy (a_i b_j + a_j b_i) + J_yy b_i b_j) / rho with
 *      (a_i, b_i) the (x, y) components of t_i (the minus sign: outward convention, the
 *      inside being below the graph); eigen-decomposition of B.
 */
int as_jet_fit(const double *pts, size_t n, const double origin[3], int degree,
               const double frame[9], const double orient[3], as_jet *out);

/* ==================================================================================== */
/* Gaussian blending of per-vertex tensors (paper 5.2.3, step 2)                         */
/* ==================================================================================== */

/* The cutoff of the blending weights, in units of r_B (see as_blend_eval). */
#define AS_BLEND_CUTOFF 3.5

typedef struct as_blend as_blend;

/*
 * as_blend_create — a blended tensor field over n vertices: vertex i at xyz[3i..3i+2]
 * carries the SPD tensor tensors[6i..6i+5] (m11 m12 m13 m22 m23 m33). kd is a kd-tree of
 * exactly these vertices with ids 0..n-1. xyz and kd are borrowed (they must outlive the
 * blend: the mesh surface owns them); the tensors are copied. rb > 0 is the blending
 * radius r_B. Builds a hash grid of cell size c r_B over the vertices (O(n log n), 4 bytes
 * per vertex plus 16 bytes per 2 occupied cells). Returns OK, EINVAL (n == 0, kd size !=
 * n, rb not finite and > 0), ENOMEM.
 */
anistar_status as_blend_create(anistar_context *ctx, const as_kdtree *kd, const double *xyz,
                               size_t n, const double *tensors, double rb, as_blend **out);
void as_blend_free(anistar_context *ctx, as_blend *b);
double as_blend_radius(const as_blend *b);
/* The blend's tensors (6 per vertex, *n vertices), to read or replace in place (the points,
 * radius and grid do not depend on them). */
double *as_blend_tensors(as_blend *b, size_t *n);

/*
 * as_blend_eval — the blended tensor at p:
 *     M_p = sum_v w_v M(v) / sum_v w_v,
 *     w_v = max(0, exp(-(|p - v|^2 - d0^2) / r_B^2) - exp(-c^2)),   c = AS_BLEND_CUTOFF,
 * d0 the distance from p to its nearest vertex. Up to the common factor exp(d0^2/r_B^2),
 * which cancels in the normalisation, this is the paper's weight mu_p(v) =
 * exp(-|p - v|^2 / r_B^2) lowered by its value at the cutoff: w_v = 0 exactly for
 * vertices with |p - v|^2 > d0^2 + c^2 r_B^2, so only O(c^2 r_B^2 density) vertices are
 * summed: d0 from the kd-tree (logarithmic time), the vertices within the cutoff from the
 * hash grid (expected constant time per cell, 27 cells near the surface).
 * Properties:
 *  - M_p is a positive combination of SPD tensors: SPD (the nearest vertex always has
 *    weight 1 - exp(-c^2) > 0, so there is no empty case, even far from the surface);
 *  - continuous in p (the weights are continuous functions of p: d0 and |p - v| are);
 *  - truncation error: each weight differs from the paper's (normalised to the nearest
 *    vertex) by at most exp(-c^2) = 4.8e-6; on a uniformly sampled flat region the
 *    relative change of sum_v w_v M(v) / sum_v w_v is about (1 + c^2) exp(-c^2) = 6e-5
 *    times the spread of the M(v) involved.
 * ctx: allocates only for points so far from the vertices that the cutoff ball meets more
 * than 512 grid cells (then a kd-tree radius query gathers the vertices; NULL means the
 * blend's creating context); receives error messages. Returns OK, EINVAL (p not finite),
 * ENOMEM.
 */
anistar_status as_blend_eval(anistar_context *ctx, const as_blend *b, const double p[3],
                             double m[6]);

/*
 * as_blend_default_radius — the paper's default r_B: the mean, over the n vertices, of
 * their mean distance to their k nearest other vertices (1 <= k, clamped to
 * AS_JET_MAX_POINTS; fewer when n <= k).
 * Returns OK or EINVAL (n < 2).
 */
anistar_status as_blend_default_radius(anistar_context *ctx, const as_kdtree *kd,
                                       const double *xyz, size_t n, size_t k, double *rb);
/* The same, keeping for each vertex v the first keep_k (<= k + 1, k clamped as above) ids
 * of its nearest-neighbour query, itself included (as_kdtree_knn's order: by squared
 * distance, then id), in keep[keep_k * v ..] (unused slots -1) and their number in
 * kept[v]: what as_kdtree_knn(kd, xyz + 3v, keep_k, ...) returns, since the keep_k
 * nearest by (distance, id) are the first of the k + 1 nearest. EINVAL if keep_k > k + 1. */
anistar_status as_blend_default_radius_keep(anistar_context *ctx, const as_kdtree *kd,
                                            const double *xyz, size_t n, size_t k, double *rb,
                                            int32_t *keep, size_t keep_k, uint8_t *kept);

#endif /* ANISTAR_JET_H */
