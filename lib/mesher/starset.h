/*
 * starset.h — internal: all the stars of the mesher, the facet table (consistency), the
 * spatial indexes, Insert(p), poles (DESIGN.md 4.4, paper 4.1 and 5.3).
 *
 * Global ids: 0-7 the corners of the enlarged bounding box (in every star), then the
 * poles (8 .. first_site-1: they localise stars, have no star, are never refined nor
 * output), then the surface sites in insertion order. Every point is stored once in xyz
 * by global id; every site's metric is evaluated once when it is inserted and kept as a
 * frame.
 *
 * Facet table: sorted triple of global ids -> 3-bit mask of which of its vertices' stars
 * hold it restricted (bit k for the k-th smallest id). A facet is consistent iff its mask
 * is full and its three vertices are surface sites (corners and poles have no star). The
 * set of inconsistent facets is kept exactly, updated from the difference of a star's
 * restricted facets before and after each change (never by rescanning).
 *
 * Limits: global ids (as_gid, core.h) below ss->max_ids, AS_STARSET_MAX_IDS unless a test
 * lowers it: counts, loops and the spatial indexes are int32, so 2^31 - 1 whatever the
 * width of the stored ids; the refiner stops 1024 sites short of it (docs/algorithm.md).
 */
#ifndef ANISTAR_STARSET_H
#define ANISTAR_STARSET_H

#include <stdint.h>

#include "core.h"
#include "geom/boxindex.h"
#include "geom/kdtree.h"
#include "mesher/feature.h"
#include "mesher/star.h"
#include "pool.h"
#include "surface/field.h"

#define AS_STARSET_MAX_IDS INT32_MAX

/* A facet's key: its three global ids, ascending (no packing: any id width). Keys compare
 * lexicographically (as_fkey_cmp), the order of the refiner's ties. */
typedef struct as_fkey {
    as_gid g[3];
} as_fkey;

typedef struct as_ftab_entry {
    as_fkey key;    /* valid while mask != 0 */
    int32_t incpos; /* position in the inconsistent set, or -1 */
    uint8_t mask;   /* 0: an empty slot */
    uint8_t queued; /* an entry of rule 3's queue refers to it */
} as_ftab_entry;

/* Threads (as_starset_set_threads): what one task of a parallel insertion left for the
 * serial part after it: the star's facets before the insertion (in its thread's arena),
 * whether it was closed. */
typedef struct as_ptask {
    size_t off;     /* in the arena of thread `thread` */
    int32_t nold;
    int thread;
    int was_closed;
    int grew;       /* the star's zone grew (zone_grew), in box zb (lo, hi) */
    double zb[6];
} as_ptask;
typedef struct as_parena {
    as_rfacet *f;
    size_t n, cap;
} as_parena;

/*
 * The search state of the star set's queries, star growth and simulations: ss->ws is the
 * caller's; with threads each slot has its own (ss->tws), so that Pick_valid's candidates
 * are simulated at once (docs/algorithm.md, "Threads").
 */
/* A point of a batch of insertions (as_starset_insert_batch). */
typedef struct as_bpoint {
    double p[3];
    as_metric_frame mf;      /* its frame (as_starset_metric_in) */
    int32_t *list, *hints;   /* the stars it conflicts with, a conflicting tet of each */
    size_t nl, cap_list, cap_hints;
    double lfs;              /* its local feature size (as_starset_lfs_point; NaN: none) */
    int32_t gid;             /* out: its id */
} as_bpoint;
/* One star update of a batch: site gid into star v (hint: a tet of v in conflict). */
typedef struct as_btask {
    int32_t v, gid, hint;
} as_btask;

typedef struct as_simws {
    uint32_t *stamp;         /* per id: membership marks (ss->ws: in the per-id block) */
    size_t cap_stamp;        /* a thread's own stamp array's capacity (0 for ss->ws) */
    uint32_t epoch;
    as_idlist cand, ids;
    int32_t *list, *batch;   /* changed stars; insertion batch */
    int32_t *hints;          /* per changed star: a tet in conflict with p */
    size_t cap_hints;
    size_t cap_list, cap_batch;
    double *bdist;           /* M_v distances of grow_star's candidates (batch), -1: not yet */
    size_t cap_bdist;
    int32_t *seeds;          /* a rebuilt star's seed sites (as_starset_rebuild_on) */
    size_t cap_seeds;
    as_star *spare;          /* a star for simulations (Pick_valid) */
    as_star_ovr ovr;         /* the simulated point (the spare's) */
    uint64_t conflict_tests, star_builds;
} as_simws;

/* A facet of a star that is new or whose surface ball moved (the refiner's queue feed). */
typedef struct as_fevent {
    as_gid star;
    as_gid g[3];
} as_fevent;

typedef struct as_starset {
    anistar_context *ctx;
    const as_surface *surf;
    const as_field *field;
    as_star_env env;

    int32_t n, cap;          /* points (global ids) */
    int32_t max_ids;         /* the id limit: AS_STARSET_MAX_IDS (tests lower it) */
    void *pblk;              /* the one block of the per-id arrays (xyz, mf, stars, stamp,
                                lfs, scomp, ascale: cap each) */
    double *xyz;             /* 3 per id */
    as_metric_frame *mf;     /* per id (identity for corners and poles) */
    as_star **stars;         /* per id (NULL for corners and poles) */
    int32_t first_site;      /* 8 + number of poles */
    double box_lo[3], box_hi[3]; /* the box; corners 0-7 lie just outside it */

    /* facet table (open addressing, linear probing, backward-shift deletion) */
    as_ftab_entry *tab;
    size_t tab_cap, tab_n;
    as_fkey *inc;            /* inconsistent facets (keys) */
    size_t ninc, cap_inc;

    as_sampler *sampler;     /* the samples of the run's start (NULL after) */
    as_kdtree *kd;           /* poles and sites */
    as_feature feat;         /* medial points: the local feature size */
    double *lfs;             /* per id: lfs in its own metric (NaN: not computed yet) */
    int32_t *scomp;          /* per id: the sample component of an initial site, or -1 */
    int32_t nscomp;          /* components of the surface sample */
    double hmin, hmax;       /* the run's Euclidean size bounds in force (0: none; see
                                as_mesher_params) */
    double ecap_hi, ecap_lo; /* the eigenvalues of every site's F are clamped to
                                [ecap_lo, ecap_hi] (0: no bound): r0/hmax and r0/hmin */
    double rot_r0, rot_g;    /* the rotation cap (as_starset_metric): r0 and gamma0 - 1;
                                rot_g 0: off */
    double alpha;            /* the feature-size fraction (AS_FEATURE_ALPHA), times each
                                site's ascale */
    double *fix;             /* points of S the final checks found the mesh missing (4 per
                                point: x, y, z, the radius of the edge that missed it) */
    size_t nfix, cap_fix;
    double *trouble;         /* balls where the final checks failed (x, y, z, radius) */
    size_t ntrouble, cap_trouble;
    double *ascale;          /* per id: the site's own factor on alpha (1, halved in trouble) */
    as_boxindex *bi;         /* conflict-zone box of each star, keyed by global id */

    /* events since the refiner last drained them */
    as_fevent *ev;
    size_t nev, cap_ev;
    as_fkey *newinc;         /* keys that became inconsistent */
    size_t nnewinc, cap_newinc;
    int32_t *open;           /* stars found not a closed fan (topology rule's feed) */
    size_t nopen, cap_open;

    /* scratch */
    as_star_scratch sc;
    as_idlist fids;          /* the feature-size queries' own */
    as_simws ws;             /* the caller's search state */
    as_simws *tws;           /* per thread slot: its own (Pick_valid's simulations) */
    int32_t *rebuild;        /* stars to compact after the current insertion */
    size_t nrebuild, cap_rebuild;
    int32_t *regrow;         /* stars whose zone grew in the current insertion ... */
    size_t nregrow, cap_regrow;
    double *regrow_box;      /* ... and the box where it grew (lo, hi: 6 per star) */
    size_t cap_regrow_box;
    as_rfacet *keep;         /* a star's facets before its compaction */
    size_t cap_keep;

    /* threads (docs/algorithm.md, "Threads"): the pool (NULL: one thread), per thread
     * slot an environment (the slot's context) and a scratch, the tasks of the current
     * parallel insertion and the arenas of their old facets */
    as_pool *pool;
    int nthreads;
    as_star_env *tenv;
    as_star_scratch *tsc;
    as_parena *parena;
    as_ptask *ptask;
    size_t cap_ptask;
    as_btask *btask;         /* a batch's star updates (as_starset_insert_batch) */
    size_t cap_btask;
    as_bpoint *bpts;         /* the batch's points while their stars are built */
    int restar_compact;      /* the parallel regrowths (0) or compactions (1) running */

    /* statistics */
    uint64_t star_updates, star_rebuilds, zone_regrowths; /* builds, conflict tests: ws */
} as_starset;

/* Sort three global ids ascending, in place (a facet key's order). */
static inline void as_sort_gid3(as_gid g[3]) {
    for (int a = 0; a < 2; a++)
        for (int b = a + 1; b < 3; b++)
            if (g[b] < g[a]) {
                as_gid t = g[a];
                g[a] = g[b];
                g[b] = t;
            }
}
/* The key of a sorted triple. */
static inline as_fkey as_facet_key(const as_gid g[3]) {
    as_fkey k = {{g[0], g[1], g[2]}};
    return k;
}
static inline int as_fkey_eq(const as_fkey *a, const as_fkey *b) {
    return a->g[0] == b->g[0] && a->g[1] == b->g[1] && a->g[2] == b->g[2];
}
/* Lexicographic order: -1, 0, 1. */
static inline int as_fkey_cmp(const as_fkey *a, const as_fkey *b) {
    for (int k = 0; k < 3; k++)
        if (a->g[k] != b->g[k]) return a->g[k] < b->g[k] ? -1 : 1;
    return 0;
}

/*
 * Initialise: the corner box (half-width 2 R around the bounding sphere's center), the
 * poles from a surface sample (see as_starset_add_poles), empty tables. Returns OK,
 * ENOMEM, or the sampler's errors.
 */
anistar_status as_starset_init(as_starset *ss, anistar_context *ctx, const as_surface *surf,
                               const as_field *field);
/* The same with threads for its parallel sections (>= 1; 1: serial, as_starset_init).
 * The results are the same for every count (docs/algorithm.md, "Threads"). Also EINVAL
 * (a count out of [1, AS_POOL_MAX_THREADS]) or EINTERNAL (a thread could not start). */
anistar_status as_starset_init_threads(as_starset *ss, anistar_context *ctx,
                                       const as_surface *surf, const as_field *field,
                                       int threads);
void as_starset_destroy(as_starset *ss);

/*
 * Poles (paper 5.3, Amenta-Bern): from the ordinary Delaunay triangulation (identity
 * frame) of the sample points smp[3n], for each sample point the farthest incident
 * circumcenter p+ and the farthest one on the other side of p+ (for hull points p+ is at
 * infinity along the outward normal: only the inner pole); candidates outside the
 * corner box (with a margin of R/4) are dropped; farthest-point sampling keeps at most
 * max_poles, spread out. Must be called before any site is inserted.
 */
anistar_status as_starset_add_poles(as_starset *ss, const double *smp, int32_t n,
                                    int32_t max_poles);

/*
 * Insert(p) (paper 4.1 and 5.3): p becomes the site *gid (its metric evaluated now).
 * design:
 *  1. the stars whose conflict-zone box contains p (box index), tested exactly
 *     (as_star_conflicts); p is inserted in those;
 *  2. p's star: corners, p, the sites whose stars changed; then rounds: the sites of the
 *     kd-tree inside the box of p's current conflict zone that conflict are inserted,
 *     until a round inserts none (each site is tested once: zones only shrink);
 *  3. the facet table, the inconsistent set and the events follow each star's diff; the
 *     boxes of changed stars are updated.
 * Returns OK, ENOMEM, EINVAL (metric not SPD or not finite at p, surface errors),
 * EINTERNAL.
 */
anistar_status as_starset_insert(as_starset *ss, const double p[3], int32_t *gid);

/*
 * Batches of insertions (issue 15; docs/algorithm.md, "Threads"). as_starset_conflicts_on
 * puts into b->list and b->hints (grown with ctx) the stars that p conflicts with now and a
 * conflicting tet of each, searched on thread slot t's workspace (-1: the caller's; slot
 * workspaces need as_starset_simulate_prepare first); it changes nothing of ss. Then
 * as_starset_insert_batch inserts the np points b[0..np) at once, as sites ss->n,
 * ss->n + 1, ... (b[j].gid), given that no star is in two of their lists and the lists and
 * frames were computed on the star set as it is: each point enters its stars (one task per
 * star), then each point's star is built (one task per point) with every point of the
 * batch in the kd-tree, then the table, the events, zone regrowths and compactions in a
 * fixed order. The result does not depend on the thread count. Same returns as
 * as_starset_insert. as_bpoint_free frees a point's lists.
 */
anistar_status as_starset_conflicts_on(as_starset *ss, int t, anistar_context *ctx,
                                       const double p[3], as_bpoint *b);
anistar_status as_starset_insert_batch(as_starset *ss, as_bpoint *b, int32_t np);
/* b->lfs: the local feature size at b->p in b->mf, as as_starset_lfs would cache it for
 * the site (the batch's insertion caches it), on slot t's workspace (-1: the caller's). */
anistar_status as_starset_lfs_point(as_starset *ss, int t, anistar_context *ctx, as_bpoint *b);
void as_bpoint_free(anistar_context *ctx, as_bpoint *b);

/*
 * Check every star on the ball zone (AS_STAR_BALL_ZONE) for which need(arg, v) is nonzero
 * (every one when need is NULL) against the sites that conflict with it within a reach
 * of 4 r_max, deepened until each difference is decided; a star whose restricted facets
 * differ keeps its whole Delaunay region as its zone from then on (zfull), is regrown, and
 * its changes go to the facet table and the events. *opened: how many. halt (NULL: none)
 * is tested before each star: once it is due the remaining stars are not checked and no
 * star is opened (*opened 0; the caller reads halt->halted). OK, ENOMEM, EINTERNAL. See
 * the design note in starset.c.
 */
anistar_status as_starset_verify_zones(as_starset *ss, int (*need)(void *, int32_t), void *arg,
                                       as_halt *halt, size_t *opened);

/*
 * Simulate p's star without changing anything: fills ss->spare with the star p would
 * get (p given the provisional id ss->n, its frame *mf). Used by Pick_valid.
 */
/* Threads: as_starset_simulate_prepare once before simulations on the threads (it sizes
 * their workspaces), then as_starset_simulate_thread(ss, t, ...) on thread slot t gives
 * what as_starset_simulate gives (the star is slot t's spare); as_starset_collect_counts
 * after, for the statistics. */
anistar_status as_starset_simulate_prepare(as_starset *ss);
anistar_status as_starset_simulate_thread(as_starset *ss, int t, const double p[3],
                                          const as_metric_frame *mf, as_star **out);
void as_starset_collect_counts(as_starset *ss);
anistar_status as_starset_simulate(as_starset *ss, const double p[3], const as_metric_frame *mf,
                                   as_star **out);

/*
 * v's local feature size in M_v (paper 2.3: the lfs part of the sizing field): the M_v
 * distance from v to the nearest medial point of the surface (ss->feat); +inf when there
 * is none. Only needed to decide "r >= alpha lfs": when a cheap lower bound
 * already exceeds need, *lfs receives that bound; otherwise the exact value, cached.
 */
anistar_status as_starset_lfs(as_starset *ss, int32_t v, double need, double *lfs);

/* Facets of a star stay below alpha times its center's local feature size (ss->alpha):
 * AS_FEATURE_ALPHA at the start, halved each time the final checks of a run find the
 * topology wrong, down to AS_FEATURE_ALPHA_MIN (docs/algorithm.md: measured on thin
 * tori, plates, close spheres and the mesh inputs). */
#define AS_FEATURE_ALPHA 1.0
#define AS_FEATURE_ALPHA_MIN 0.125

/* Evaluate the metric at p into a frame. EINVAL when the field fails or M is not SPD. */
anistar_status as_starset_metric(as_starset *ss, const double p[3], as_metric_frame *mf);
/* The same with errors in ctx, writing nothing of ss (a thread's). */
anistar_status as_starset_metric_in(const as_starset *ss, anistar_context *ctx, const double p[3],
                                    as_metric_frame *mf);

/* The table entry of key, or NULL. */
as_ftab_entry *as_starset_lookup(const as_starset *ss, as_fkey key);
/* 1 if the entry is consistent (full mask, three surface sites). */
int as_starset_consistent(const as_starset *ss, as_fkey key, uint8_t mask);

/* Validator: rebuild the table from every star's restricted facets and compare with the
 * table and the inconsistent set. ANISTAR_OK or EINTERNAL with a message; ENOMEM. */
anistar_status as_starset_check_table(as_starset *ss);

#endif /* ANISTAR_STARSET_H */
