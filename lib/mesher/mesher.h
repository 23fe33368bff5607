/*
 * mesher.h — internal: the parameters, counters and output object shared by refine.c,
 * output.c and api.c (DESIGN.md 4.5 and 4.8).
 */
#ifndef ANISTAR_MESHER_H
#define ANISTAR_MESHER_H

#include <stdatomic.h>
#include <stdint.h>

#include "core.h"
#include "mesh/trimesh.h"
#include "mesher/starset.h"
#include "surface/field.h"
#include "surface/surface.h"

/* The refinement points of one batch (as_mesher_params.batch; docs/algorithm.md §11). */
#define AS_MESHER_BATCH 16

/* Parameters (DESIGN.md 4.5; public setters check the ranges). */
typedef struct as_mesher_params {
    double r0, gamma0, rho0, beta, delta, approx, max_seconds;
    int64_t max_vertices; /* surface sites; 0: the hard limit (AS_MESHER_MAX_SITES) */
    int64_t max_stall;    /* stall budget in insertions; 0: automatic (AS_STALL_MIN, 2 V) */
    uint64_t seed;
    int32_t pick_tries;
    int32_t initial_points; /* initial sites wanted (0: automatic) */
    int32_t optimize;       /* 1: vertex optimisation after a complete run (optimize.c) */
    double alpha0;          /* tests: the first feature-size fraction (0: AS_FEATURE_ALPHA) */
    double hmin;            /* Euclidean size floor: facets whose longest edge is shorter get
                               no size, distortion, approximation or shape refinement;
                               0: automatic, the surface's resolution (as_feature floor_e) */
    double hmax;            /* Euclidean size ceiling: facets whose longest edge is longer are
                               refined (rule 1); 0: none */
    int32_t aniso_cap;      /* 1: the rotation floor of the metric (starset.c) */
    int32_t threads;        /* threads of the star set's parallel sections (>= 1) */
    int32_t batch;          /* refinement points taken together (refine.c, batch_step):
                               AS_MESHER_BATCH by default; 1: one at a time (the order of
                               the runs before issue 15's batches). Never depends on
                               threads: the output does not either */
    int32_t max_ids;        /* tests: the star set's id limit (0: AS_STARSET_MAX_IDS); the
                               hard limit on sites is 1024 below it */
    const double *seeds;    /* sites inserted after the initial ones (3 per site; NULL:
                               none), in their order, exact duplicates skipped */
    size_t nseeds;
    const struct as_part_hook *part; /* the partition simulation's hook (NULL: none) */
} as_mesher_params;

/*
 * The partition simulation (partition.c, docs/scaling.md): a run that is one part of a
 * surface split into k. With a hook, a run inserts only the refinement points the hook
 * accepts, and when no job is left it calls round_end instead of the final checks: the
 * hook exchanges sites with the other parts and returns the points to insert (the other
 * parts' sites near this part, the points they asked it to insert); the run goes on while
 * *more is set and otherwise ends INCOMPLETE (not checked), its star set kept.
 *  round_end also names stars whose jobs accept set aside (again): after the points,
 *          their facets that violate rules 1 or 2 are queued again, and every
 *          inconsistent facet.
 *  accept: whether to insert p, the point of a job of star v (rule: 0-2 the rules 1-3,
 *          3 the topology rule; f the facet, NULL for the topology rule); when `final`
 *          is 0, p is only the facet's surface center, asked before Pick_valid (0 there:
 *          the job is dropped without picking)
 */
typedef struct as_part_hook {
    void *user;
    int (*accept)(void *user, const as_starset *ss, int rule, int32_t v, const as_rfacet *f,
                  const double p[3], int final);
    anistar_status (*round_end)(void *user, as_starset *ss, const double **pts, size_t *npts,
                                const int32_t **again, size_t *nagain, int *more);
} as_part_hook;

void as_mesher_params_default(as_mesher_params *p);

/* The default of max_vertices, and the automatic stall budget: the larger of
 * AS_STALL_MIN and AS_STALL_PER_VERTEX times the vertices so far. */
#define AS_MAX_VERTICES_DEFAULT 1000000
/* The hard limit on sites: the id limit less 1024 ids for the 8 corners, at most 256 poles
 * and Pick_valid's provisional id (2,147,482,623). */
#define AS_MESHER_ID_RESERVE 1024
#define AS_MESHER_MAX_SITES ((int64_t)AS_STARSET_MAX_IDS - AS_MESHER_ID_RESERVE)
#define AS_STALL_MIN 50000
#define AS_STALL_PER_VERTEX 2

/* Progress: return nonzero to cancel. */
typedef int (*as_progress_fn)(size_t vertices, size_t inconsistent, double seconds, void *user);

/*
 * The caller's side of a run (NULL: none): the progress callback, the stop request
 * (set by anistar_mesher_stop from any thread or a signal handler; the run clears it when
 * it ends), and the state the refiner publishes for anistar_mesher_get_progress.
 */
typedef struct as_run_ctl {
    as_progress_fn progress;
    void *user;
    atomic_int stop;
    anistar_progress state;
} as_run_ctl;

/* Counters of one run. rule[0] is the sum of the rule-1 causes cause[AS_CAUSE_*]. */
enum {
    AS_CAUSE_SIZE = 0,
    AS_CAUSE_DISTORTION,
    AS_CAUSE_APPROX,
    AS_CAUSE_FEATURE,
    AS_CAUSE_HMAX,
    AS_NCAUSES
};
typedef struct as_mesher_counters {
    uint64_t initial, rule[3], topology, cause[AS_NCAUSES];
    uint64_t pick_tries, pick_failures;
    uint64_t stall_max;
    uint64_t halvings; /* times alpha was halved after failed final checks */
    uint64_t specks;   /* image components below the resolution, not meshed */
    uint64_t topo_below_hmin; /* topology points refused: nearer than hmin to a site */
    uint64_t zones_opened;    /* stars set to their Delaunay zone (as_starset_verify_zones) */
    uint64_t swept;           /* facets violating rules 1-2 that no queue held when the
                                 queues ran dry (sweep_rules: 0 unless a flag was lost) */
    uint64_t batches, batch_jobs, batch_lost, batch_set_aside; /* refine.c, batch_run */
    double t_init, t_refine, t_output, t_total;
    double estimate_vertices, estimate_bytes;
    int stop_reason; /* anistar_stop_reason */
} as_mesher_counters;

/* The output mesh (the public anistar_mesh). */
struct anistar_mesh {
    anistar_context *ctx;
    as_trimesh tm;              /* vertices, triangles (outward), per-vertex tensors */
    anistar_mesh_stats stats;
    as_gid *gid;                /* per vertex: its global id in the star set (internal) */
    size_t ngid;
    double *rho;                /* per triangle: the largest radius-edge ratio in its three
                                   vertex metrics (as_radius_edge), the statistics' rho */
    size_t nrho;
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
                             const as_mesher_params *prm, as_run_ctl *ctl, anistar_mesh **out);

/* For tests: the same run keeping the star set alive (*ss_out, destroy with
 * as_starset_destroy and as_free) so that tests can inspect it; *out as as_mesher_run. */
anistar_status as_mesher_run_keep(anistar_context *ctx, const as_surface *surf,
                                  const as_field *field, const as_mesher_params *prm,
                                  as_run_ctl *ctl, anistar_mesh **out, as_starset **ss_out);

/*
 * Build the output mesh from the star set (output.c): consistent restricted facets of
 * surface stars, deduplicated, without corners and poles, vertices renumbered by global
 * id, triangles oriented by the outward normal at their surface center; statistics.
 * complete: 1 when refinement finished. errors: 0 leaves the approximation error out of
 * the statistics (0; the final checks' output: as_mesher_output_errors adds it to the one
 * kept).
 */
anistar_status as_mesher_output(as_starset *ss, const as_mesher_params *prm,
                                const as_mesher_counters *cnt, int complete, int errors,
                                anistar_mesh **out);

/* The approximation error statistics of output m of ss (as as_mesher_output computes them
 * with errors = 1, bit for bit: the same samples, summed in the same order). OK or
 * ENOMEM or an oracle error. */
anistar_status as_mesher_output_errors(as_starset *ss, anistar_mesh *m);

/*
 * The final checks of a complete run (anistar_mesher_run's contract for ANISTAR_OK), on
 * the output m of the star set ss (output.c): every site's star one closed fan; the mesh
 * non-empty, a closed 2-manifold, consistently oriented (m's triangles are reoriented
 * per component when needed, outward by the normals of S); no edge bridging a gap or
 * cutting through a thin part (step 4 of the design in output.c); every sample component
 * meshed; for a triangle-mesh surface its components exactly (none split, joined or
 * extra) with their Euler characteristics. *ok = 1 when all hold; otherwise *ok = 0, ctx's
 * message names the first failure and a point on it, *sig identifies it (AS_CERT_* and
 * the components involved), and *refinable = 1 when finer sampling can cure it
 * (everything but a lost component or a star left open). A failed fidelity check (step
 * 4) also leaves in ss->fix the points of S that every offending edge misses (the
 * projections of their midpoints): the refiner inserts them. Fills m's stats.components
 * and components_found/split/joined. OK or ENOMEM.
 */
#define AS_CERT_SPLIT (1ull << 56)
#define AS_CERT_JOIN (2ull << 56)
#define AS_CERT_PIECE (3ull << 56)
#define AS_CERT_EULER (4ull << 56)
#define AS_CERT_ORIENT (5ull << 56)
#define AS_CERT_FIDELITY (6ull << 56)
#define AS_CERT_SAGITTA 0.5
#define AS_CERT_OPPOSITE (-0.8660254037844386) /* cos 150 degrees */
anistar_status as_mesher_certify(as_starset *ss, anistar_mesh *m, int *ok, int *refinable,
                                 uint64_t *sig);

void as_mesh_free(anistar_mesh *m);

#endif /* ANISTAR_MESHER_H */
