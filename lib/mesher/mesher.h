/*
 * mesher.h — internal: the parameters, counters and output object shared by refine.c,
 * output.c and api.c (DESIGN.md 4.5 and 4.8).
 */
#ifndef ANISTAR_MESHER_H
#define ANISTAR_MESHER_H

#include <stdint.h>

#include "core.h"
#include "io/meshio.h"
#include "mesher/starset.h"
#include "surface/field.h"
#include "surface/surface.h"

/* Parameters (DESIGN.md 4.5; public setters check the ranges). */
typedef struct as_mesher_params {
    double r0, gamma0, rho0, beta, delta, approx, max_seconds;
    int64_t max_vertices; /* surface sites; 0: no limit (AS_STARSET_MAX_IDS applies) */
    uint64_t seed;
    int32_t pick_tries;
    int32_t initial_points; /* initial sites wanted (0: automatic) */
    int32_t optimize;       /* 1: vertex optimisation after a complete run (optimize.c) */
} as_mesher_params;

void as_mesher_params_default(as_mesher_params *p);

/* Progress: return nonzero to cancel. */
typedef int (*as_progress_fn)(size_t vertices, size_t inconsistent, double seconds, void *user);

/* Counters of one run. */
typedef struct as_mesher_counters {
    uint64_t initial, rule[3];
    uint64_t pick_tries, pick_failures;
    double t_init, t_refine, t_output, t_total;
} as_mesher_counters;

/* The output mesh (the public anistar_mesh). */
struct anistar_mesh {
    anistar_context *ctx;
    as_trimesh tm;              /* vertices, triangles (outward), per-vertex tensors */
    anistar_mesh_stats stats;
};

/*
 * Run the whole algorithm: initial points, poles, refinement by rules 1-3 (refine.c),
 * then the output (output.c). Returns OK (no rule applies: consistent), INCOMPLETE (a
 * limit stopped it; *out holds the consistent facets), ECANCELED (progress returned
 * nonzero; *out NULL), or an error (*out NULL).
 * design: DESIGN.md 4.5; paper 4.1 (rules with priorities), 4.2 (Pick_valid), 5.1
 *   (practical rule 1), 5.3 (poles, conflict zones).
 */
anistar_status as_mesher_run(anistar_context *ctx, const as_surface *surf, const as_field *field,
                             const as_mesher_params *prm, as_progress_fn progress, void *user,
                             anistar_mesh **out);

/* For tests: the same run keeping the star set alive (*ss_out, destroy with
 * as_starset_destroy and as_free) so that tests can inspect it; *out as as_mesher_run. */
anistar_status as_mesher_run_keep(anistar_context *ctx, const as_surface *surf,
                                  const as_field *field, const as_mesher_params *prm,
                                  as_progress_fn progress, void *user, anistar_mesh **out,
                                  as_starset **ss_out);

/*
 * Build the output mesh from the star set (output.c): consistent restricted facets of
 * surface stars, deduplicated, without corners and poles, vertices renumbered by global
 * id, triangles oriented by the outward normal at their surface center; statistics.
 * complete: 1 when refinement finished.
 */
anistar_status as_mesher_output(as_starset *ss, const as_mesher_params *prm,
                                const as_mesher_counters *cnt, int complete, anistar_mesh **out);

void as_mesh_free(anistar_mesh *m);

#endif /* ANISTAR_MESHER_H */
