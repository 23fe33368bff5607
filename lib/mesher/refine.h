/*
 * refine.h — internal: Delaunay refinement of the star set by rules 1-3 (DESIGN.md 4.5,
 * paper 4.1, 4.2, 5.1). The entry point is as_mesher_run (mesher.h); this header exposes
 * the pieces tests use.
 */
#ifndef ANISTAR_REFINE_H
#define ANISTAR_REFINE_H

#include "mesher/mesher.h"

/* One entry of a rule queue: a facet (packed triple) of a star, its violation. */
typedef struct as_qentry {
    double pri;
    as_fkey key;
    as_gid star;
} as_qentry;

/* A binary max-heap (largest violation first; ties by key then star: deterministic). */
typedef struct as_queue {
    as_qentry *a;
    size_t n, cap;
} as_queue;

anistar_status as_queue_push(anistar_context *ctx, as_queue *q, as_qentry e);
/* Pop the top into *e; returns 0 if empty. */
int as_queue_pop(as_queue *q, as_qentry *e);
/* Halve the capacity of a queue a quarter full (from 2048 entries up): the queues peak
 * early in a run and the stars later (memory). Never fails (a failed shrink keeps it). */
void as_queue_trim(anistar_context *ctx, as_queue *q);
void as_queue_free(anistar_context *ctx, as_queue *q);

/*
 * Rule-1 violation of facet f of star v: the largest of r/r0, gamma/gamma0 (largest
 * pairwise distortion of the vertices' metrics, when all three are sites), with
 * approx > 0 dist/approx (distance from the facet's centroid to S), and
 * r/(ss->alpha lfs_v) (v's local feature size in M_v, as_starset_lfs), and with
 * ss->hmax > 0 L/hmax (L the longest Euclidean edge), among those >= 1; 0 when the facet
 * satisfies rule 1. A facet below ss->hmin (as_facet_below_hmin) is held to the feature
 * size and hmax only. *cause (optional) receives the
 * AS_CAUSE_* of the largest ratio; *err surface errors (then 0 is returned).
 */
double as_rule1_violation(as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f, int *cause, anistar_status *err);
/* The longest Euclidean edge of the facet with global ids g (ss->hmax refines above it). */
double as_facet_longest_edge(const as_starset *ss, const as_gid g[3]);
/* 1 if ss->hmin > 0 and f's surface center lies within hmin (Euclidean) of one of f's
 * vertices: refining f would make an edge shorter than hmin, so no size, distortion,
 * approximation or shape rule applies to it. */
int as_facet_below_hmin(const as_starset *ss, const as_rfacet *f);
/* A refinement point closer than AS_NEAR_SITE times its facet's radius (in the star's
 * metric) to an existing site is a bug trap (as_refine_check_point). */
#define AS_NEAR_SITE 1e-9

/* Passes of the final checks whose fidelity failures are refined locally (the points of
 * S the offending edges miss) before alpha is halved. */
#define AS_FIX_PASSES 32

/*
 * The bug trap in front of every refinement insertion: p, the refinement point of facet
 * g (NULL: of the topology rule) of star v with radius r in M_v, must not lie within
 * AS_NEAR_SITE r (in M_v) of an existing site or pole. A surface ball is empty of the
 * sites of v's star, so a site that close is one v's star never received (a missed
 * site): inserting p would kill nothing and the facet would come back forever.
 * Returns OK, or EINTERNAL naming the point, the facet, the star and the site; ENOMEM.
 */
anistar_status as_refine_check_point(as_starset *ss, const double p[3], int32_t v,
                                     const as_gid g[3], double r);

/*
 * The up-front estimate (DESIGN.md 4.5) of the run's output vertex count and peak memory
 * from the metric field and the sizing field alone (estimate.c), and the share of those
 * vertices whose size the distortion radius (gamma0) sets. OK, or the surface's or the
 * field's errors, ENOMEM.
 */
anistar_status as_mesher_estimate(as_starset *ss, const as_mesher_params *prm, double *vertices,
                                  double *bytes, double *bygamma);

/* Rule-2 violation: rho/rho0 if the radius-edge ratio in M_v exceeds rho0, else 0 (0 for a
 * facet below ss->hmin, as_facet_below_hmin). */
double as_rule2_violation(const as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f);

#endif /* ANISTAR_REFINE_H */
