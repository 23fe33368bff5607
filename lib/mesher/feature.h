/*
 * feature.h — internal: the local feature size of S (paper 2.3: the sizing field
 * sf = min(lfs, dr); DESIGN.md 4.5 "Topology rule").
 *
 * The medial axis of S is approximated by medial points (Amenta-Bern's poles play this
 * role in the paper's references): for each point q of a dense surface sample and each
 * side of S (inside, outside), the largest ball tangent to S at q on that side is
 * shrunk until it is empty of the sample (the shrinking-ball construction of Ma, Bae
 * and Kim) and until it does not reach past the first crossing of S along the normal
 * (the oracle: exact for plates and tubes thinner than the sample spacing). Its center
 * is a medial point when the ball touches S at two points that subtend at least
 * AS_FEATURE_ANGLE at the center: thin plates, tubes, gaps between components and
 * necks (about 180 degrees) are kept; the medial sheets that end at creases of
 * triangle meshes (90 degrees for a right-angled crease) and osculating balls of
 * curvature (near 0) are dropped. Those features threaten the geometry, not the
 * topology, and refining them to their zero feature size would never end; the topology
 * rule checks the local manifold property directly.
 *
 * The local feature size of a site v in its own metric M_v is the M_v distance from v
 * to the nearest medial point (paper 2.3: "the M_p-distance from p to the M_p-medial
 * axis", with the Euclidean medial axis standing in for the M_p one).
 */
#ifndef ANISTAR_FEATURE_H
#define ANISTAR_FEATURE_H

#include <stdint.h>

#include "core.h"
#include "geom/kdtree.h"
#include "geom/metric.h"
#include "pool.h"
#include "surface/surface.h"

/* Surface sample size, and the separation angle (radians, 120 degrees) of the kept
 * medial balls. */
#define AS_FEATURE_SAMPLE 4096
#define AS_FEATURE_ANGLE 2.0943951023931957

typedef struct as_feature {
    as_kdtree *kd;  /* the medial points, ids 0..n-1 (NULL when there are none) */
    double *pts;    /* 3 n */
    double *rad;    /* n: the radius of each medial ball */
    int32_t n, cap;
    double floor_e; /* Euclidean floor of the feature size, the surface's own resolution:
                       an eighth of the mean edge of a triangle mesh (sharp creases have
                       lfs 0), half the sampler's grid spacing for an image (about a voxel:
                       noise), 1e-4 of an implicit function's size (its bounding radius
                       R, or the diameter of its sample's box when that is smaller); it
                       keeps refinement finite where lfs tends to 0 */
} as_feature;

/*
 * Build the medial points of surf from a sample of AS_FEATURE_SAMPLE points (the
 * surface's own sampler). OK, ENOMEM, or the surface's errors.
 * design:
 *  1. the sample and a kd-tree over it; per point its outward normal n (skipped where
 *     the surface is singular);
 *  2. for each side d = -n, +n: rho = half the distance to the first crossing of S along
 *     the ray q + t d (t > 1e-9 R), or the bounding radius R when there is none; then
 *     shrinking ball: center c = q + rho d, s = the sample point nearest c other than q;
 *     while |c - s| < rho: rho = |q - s|^2 / (2 d.(s - q)) (the ball tangent at q through
 *     s), at most 64 rounds;
 *  3. keep c when rho < R and the angle between q - c and the touching point - c is at
 *     least AS_FEATURE_ANGLE (the ray's crossing counts as a touching point at 180
 *     degrees).
 */
anistar_status as_feature_build(anistar_context *ctx, const as_surface *surf, as_sampler *sp,
                                as_pool *pool, as_feature *fe);

void as_feature_free(anistar_context *ctx, as_feature *fe);

/*
 * The local feature size at p in the metric mf: the smallest M distance from p to a
 * medial point, at least e_max(F) * floor_e; +inf when there are no medial points.
 * When need > 0 and the cheap lower bound e_min(F) * (Euclidean distance to the nearest
 * medial point) already exceeds need, that bound is returned instead (*exact = 0).
 * OK or ENOMEM (scratch holds the box query).
 */
anistar_status as_feature_lfs(anistar_context *ctx, const as_feature *fe,
                              const as_metric_frame *mf, const double p[3], double need,
                              as_idlist *scratch, double *lfs, int *exact);

#endif /* ANISTAR_FEATURE_H */
