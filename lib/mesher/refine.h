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
    uint64_t key;
    int32_t star;
} as_qentry;

/* A binary max-heap (largest violation first; ties by key then star: deterministic). */
typedef struct as_queue {
    as_qentry *a;
    size_t n, cap;
} as_queue;

anistar_status as_queue_push(anistar_context *ctx, as_queue *q, as_qentry e);
/* Pop the top into *e; returns 0 if empty. */
int as_queue_pop(as_queue *q, as_qentry *e);
void as_queue_free(anistar_context *ctx, as_queue *q);

/*
 * Rule-1 violation of facet f of star v: the largest of r/r0, gamma/gamma0 (largest
 * pairwise distortion of the vertices' metrics, when all three are sites) and, with
 * approx > 0, dist/approx (distance from the facet's centroid to S) among those >= 1;
 * 0 when the facet satisfies rule 1. *err receives surface errors.
 */
double as_rule1_violation(as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f, anistar_status *err);
/* Rule-2 violation: rho/rho0 if the radius-edge ratio in M_v exceeds rho0, else 0. */
double as_rule2_violation(const as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f);

#endif /* ANISTAR_REFINE_H */
