/*
 * refine.c — rules 1-3 with priorities, lazy queues, Pick_valid, initial points, limits,
 * progress (DESIGN.md 4.5, paper 4.1, 4.2, 5.1, 5.3). See refine.h and mesher.h.
 */
#include "mesher/refine.h"
#include "mesher/optimize.h"
#include "mesher/starmove.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <stdio.h>

void as_mesher_params_default(as_mesher_params *p) {
    memset(p, 0, sizeof *p);
    p->r0 = 0.1;
    p->gamma0 = 1.5;
    p->rho0 = 3.0;
    p->beta = 2.5;
    p->delta = 0.3;
    p->approx = 0;
    p->max_seconds = 0;
    p->max_vertices = AS_MAX_VERTICES_DEFAULT;
    p->max_stall = 0;
    p->seed = 0;
    p->pick_tries = 20; /* design: measured, see docs/algorithm.md §9 (Pick_valid) */
    p->optimize = 0;
    p->aniso_cap = 1;
    p->threads = 1;
    p->batch = AS_MESHER_BATCH;
}

/* ---- queues ------------------------------------------------------------------------- */

static int q_before(const as_qentry *a, const as_qentry *b) {
    if (a->pri != b->pri) return a->pri > b->pri;
    int c = as_fkey_cmp(&a->key, &b->key);
    if (c != 0) return c < 0;
    return a->star < b->star;
}

anistar_status as_queue_push(anistar_context *ctx, as_queue *q, as_qentry e) {
    if (q->n == q->cap && as_grow(ctx, (void **)&q->a, &q->cap, q->n + 1, sizeof *q->a))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (queue)");
    size_t i = q->n++;
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (!q_before(&e, &q->a[p])) break;
        q->a[i] = q->a[p];
        i = p;
    }
    q->a[i] = e;
    return ANISTAR_OK;
}

int as_queue_pop(as_queue *q, as_qentry *e) {
    if (q->n == 0) return 0;
    *e = q->a[0];
    as_qentry x = q->a[--q->n];
    size_t i = 0, n = q->n;
    for (;;) {
        size_t l = 2 * i + 1, r = l + 1, m = i;
        const as_qentry *best = &x;
        if (l < n && q_before(&q->a[l], best)) {
            m = l;
            best = &q->a[l];
        }
        if (r < n && q_before(&q->a[r], best)) m = r;
        if (m == i) break;
        q->a[i] = q->a[m];
        i = m;
    }
    if (n) q->a[i] = x;
    return 1;
}

void as_queue_trim(anistar_context *ctx, as_queue *q) {
    if (q->cap < 2048 || q->n >= q->cap / 4) return;
    size_t cap = q->cap / 2;
    as_qentry *a = as_realloc(ctx, q->a, q->cap * sizeof *q->a, cap * sizeof *q->a);
    if (!a) return; /* keeping the larger array is fine */
    q->a = a;
    q->cap = cap;
}

void as_queue_free(anistar_context *ctx, as_queue *q) {
    as_free(ctx, q->a, q->cap * sizeof *q->a);
    memset(q, 0, sizeof *q);
}

/* ---- rule tests --------------------------------------------------------------------- */

double as_facet_longest_edge(const as_starset *ss, const as_gid g[3]) {
    const double *a = ss->xyz + 3 * (size_t)g[0], *b = ss->xyz + 3 * (size_t)g[1],
                 *c = ss->xyz + 3 * (size_t)g[2];
    double l = 0;
    const double *e[3][2] = {{a, b}, {b, c}, {c, a}};
    for (int i = 0; i < 3; i++) {
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (e[i][1][k] - e[i][0][k]) * (e[i][1][k] - e[i][0][k]);
        if (d2 > l) l = d2;
    }
    return sqrt(l);
}

int as_facet_below_hmin(const as_starset *ss, const as_rfacet *f) {
    if (!(ss->hmin > 0)) return 0;
    const double h2 = ss->hmin * ss->hmin;
    for (int i = 0; i < 3; i++) {
        const double *q = ss->xyz + 3 * (size_t)f->g[i];
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (f->c[k] - q[k]) * (f->c[k] - q[k]);
        if (d2 < h2) return 1;
    }
    return 0;
}

/* ---- rule 1's distortions, cached by pair ----------------------------------------------- */

/* A pair of sites (a < b) and as_metric_distortion_over(M_a, M_b, gamma0): 0 where the
 * filter proves gamma <= gamma0, else gamma. a == b == 0 marks an empty slot (site ids
 * are at least 8). */
typedef struct as_gpair {
    as_gid a, b;
    double g;
} as_gpair;

/*
 * design: rule 1's distortion part is the largest of the three pairwise distortions of a
 * facet's vertex metrics, and the same pairs come back again and again: a facet is judged
 * in each of its three stars, and facets are made and unmade as the stars grow (the
 * paper's torus judged 405,930 pairs for 5,768 vertices, 8% of the run). A site's metric
 * is fixed while the refinement runs, so a pair's value is a function of its two ids: it
 * is kept in a direct-mapped table (a pair overwrites the one in its slot) of four to
 * eight slots per site, 16 bytes a slot with 32-bit ids: the pairs come back while their
 * facets are being refined, so a table of every pair (2.1 MB on the torus, 12% of the
 * run's peak) saved only 0.8% more of the run's instructions (measured: 2, 4, 8 slots
 * per site and every pair, 7.535, 7.509, 7.493 and 7.446 10^9 instructions, 0.26, 0.52,
 * 1.05 and 2.1 MB). It is read by the threads and written only between
 * parallel parts, in the events' order, so what hits, and the output, is the same for
 * every thread count. The optimiser, which moves sites, does not use it.
 */
typedef struct as_gcache {
    as_gpair *t;
    size_t cap; /* a power of two, or 0 */
} as_gcache;

static inline size_t gpair_hash(as_gid a, as_gid b, size_t cap) {
    uint64_t h = (uint64_t)a * 0x9E3779B97F4A7C15ULL ^ (uint64_t)b * 0xC2B2AE3D27D4EB4FULL;
    h ^= h >> 31;
    return (size_t)h & (cap - 1);
}

/* The cached value of pair (a, b), a < b: 1 and *g when its slot holds it, else 0. */
static int gcache_get(const as_gcache *gc, as_gid a, as_gid b, double *g) {
    if (!gc || gc->cap == 0) return 0;
    const as_gpair *e = &gc->t[gpair_hash(a, b, gc->cap)];
    if (e->a != a || e->b != b) return 0;
    *g = e->g;
    return 1;
}

/* Keep pair (a, b) with value g in its slot; the table follows the site count (nsites),
 * starting empty again when it doubles. A table that cannot grow keeps its size (a
 * cache: the values do not depend on it). */
static void gcache_put(anistar_context *ctx, as_gcache *gc, size_t nsites, as_gid a, as_gid b,
                       double g) {
    if (gc->cap < 4 * nsites || gc->cap == 0) {
        size_t cap = gc->cap ? gc->cap : 1024;
        while (cap < 4 * nsites) cap *= 2;
        as_gpair *t = as_alloc_array(ctx, cap, sizeof *t);
        if (t) {
            memset(t, 0, cap * sizeof *t);
            as_free(ctx, gc->t, gc->cap * sizeof *gc->t);
            gc->t = t;
            gc->cap = cap;
        }
        if (gc->cap == 0) return;
    }
    gc->t[gpair_hash(a, b, gc->cap)] = (as_gpair){a, b, g};
}

static void gcache_free(anistar_context *ctx, as_gcache *gc) {
    as_free(ctx, gc->t, gc->cap * sizeof *gc->t);
    memset(gc, 0, sizeof *gc);
}

/* The pairs a rule-1 test solved that the cache did not hold (for the caller to keep). */
typedef struct as_gnew {
    as_gpair p[3];
    int n;
} as_gnew;

/* as_metric_distortion_over for sites a < b, from gc when it holds the pair (gc NULL: no
 * cache); a pair solved here is added to fresh (NULL: not kept). */
static double pair_over(const as_starset *ss, const as_gcache *gc, as_gid a, as_gid b,
                        double gamma0, as_gnew *fresh) {
    double g;
    if (gcache_get(gc, a, b, &g)) return g;
    g = as_metric_distortion_over(&ss->mf[a], &ss->mf[b], gamma0);
    if (fresh) fresh->p[fresh->n++] = (as_gpair){a, b, g};
    return g;
}

/* Rule 1 without its feature-size part (which reads and fills the star set's lfs cache):
 * nothing but f, the points and frames, and the surface (ctx takes a projection's error).
 * The threads of drain run it. */
static double rule1_local(const as_starset *ss, anistar_context *ctx,
                          const as_mesher_params *prm, const as_rfacet *f, int *cause,
                          anistar_status *err, const as_gcache *gc, as_gnew *fresh) {
    double viol = 0;
    if (fresh) fresh->n = 0;
    int why = AS_CAUSE_SIZE;
    *err = ANISTAR_OK;
    /* design: the Euclidean bounds (MMG's hmin/hmax, edge lengths): a facet whose longest
     * edge exceeds hmax is refined; a facet whose refinement point (its surface center)
     * lies within hmin of one of its vertices would make an edge shorter than hmin: it
     * gets no size, distortion, approximation or shape refinement (the feature size, the
     * topology rule and consistency still apply) */
    if (ss->hmax > 0) {
        double len = as_facet_longest_edge(ss, f->g);
        if (len > ss->hmax) {
            viol = len / ss->hmax;
            why = AS_CAUSE_HMAX;
        }
    }
    const int small = as_facet_below_hmin(ss, f);
    if (!small && f->r >= prm->r0 && f->r / prm->r0 > viol) {
        viol = f->r / prm->r0;
        why = AS_CAUSE_SIZE;
    }
    if (!small && f->g[0] >= ss->first_site) {
        /* design: gamma(tau) approximated by the largest pairwise distortion of the
         * vertices' metrics (paper 5.1); the trace filter settles most pairs, and only a
         * pair it does not prove below gamma0 is solved for (a pair it proves below cannot
         * be the largest distortion at or above gamma0); the pairs' values are cached
         * (as_gcache) */
        double g = pair_over(ss, gc, f->g[0], f->g[1], prm->gamma0, fresh);
        double g2 = pair_over(ss, gc, f->g[0], f->g[2], prm->gamma0, fresh);
        double g3 = pair_over(ss, gc, f->g[1], f->g[2], prm->gamma0, fresh);
        if (g2 > g) g = g2;
        if (g3 > g) g = g3;
        if (g >= prm->gamma0 && g / prm->gamma0 > viol) {
            viol = g / prm->gamma0;
            why = AS_CAUSE_DISTORTION;
        }
    }
    if (!small && prm->approx > 0) {
        const double *a = ss->xyz + 3 * (size_t)f->g[0], *b = ss->xyz + 3 * (size_t)f->g[1],
                     *c = ss->xyz + 3 * (size_t)f->g[2];
        double m[3], q[3];
        for (int k = 0; k < 3; k++) m[k] = (a[k] + b[k] + c[k]) / 3.0;
        anistar_status s = as_surface_project(ctx, ss->surf, m, q);
        if (s == ANISTAR_OK) {
            double d = sqrt((m[0] - q[0]) * (m[0] - q[0]) + (m[1] - q[1]) * (m[1] - q[1]) +
                            (m[2] - q[2]) * (m[2] - q[2]));
            if (d > prm->approx && d / prm->approx > viol) {
                viol = d / prm->approx;
                why = AS_CAUSE_APPROX;
            }
        } else if (s != ANISTAR_ENOSURFACE) {
            *err = s;
            return 0;
        }
    }
    *cause = why;
    return viol;
}

/* The feature-size part of rule 1 on top of viol (cause *why) from rule1_local. */
static double rule1_feature(as_starset *ss, int32_t v, const as_rfacet *f, double viol,
                            int *why, anistar_status *err) {
    /* design: the lfs part of the sizing field (paper 2.3, sf = min(lfs, dr)): facets of
     * v's star stay below alpha times v's local feature size in M_v */
    if (v >= ss->first_site) {
        double lfs;
        const double alpha = ss->alpha * ss->ascale[v];
        anistar_status s = as_starset_lfs(ss, v, f->r / alpha, &lfs);
        if (s != ANISTAR_OK) {
            *err = s;
            return 0;
        }
        double x = f->r / (alpha * lfs);
        if (x >= 1 && x > viol) {
            viol = x;
            *why = AS_CAUSE_FEATURE;
        }
    }
    return viol;
}

double as_rule1_violation(as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f, int *cause, anistar_status *err) {
    int why;
    double viol = rule1_local(ss, ss->ctx, prm, f, &why, err, NULL, NULL);
    if (*err != ANISTAR_OK) return 0;
    viol = rule1_feature(ss, v, f, viol, &why, err);
    if (*err != ANISTAR_OK) return 0;
    if (cause) *cause = why;
    return viol;
}

double as_rule2_violation(const as_starset *ss, const as_mesher_params *prm, int32_t v,
                          const as_rfacet *f) {
    if (as_facet_below_hmin(ss, f)) return 0;
    double rho = as_radius_edge(&ss->mf[v], ss->xyz + 3 * (size_t)f->g[0],
                                ss->xyz + 3 * (size_t)f->g[1], ss->xyz + 3 * (size_t)f->g[2], NULL);
    return rho > prm->rho0 ? rho / prm->rho0 : 0;
}

/* ---- the refiner ---------------------------------------------------------------------- */

typedef struct refiner {
    anistar_context *ctx;
    const as_mesher_params *prm;
    as_starset *ss;
    as_queue q[3];
    uint64_t rng;
    as_mesher_counters cnt;
    as_run_ctl *ctl;         /* the caller's side (may be NULL) */
    double t0;               /* start of the run */
    /* stall detection (see stall_update): the lowest inconsistent-facet count seen by
     * rule 3 since the count was last 0, when it was seen (in rule-3 insertions), and
     * the vertices then */
    size_t inc_low;
    uint64_t n3, low_at;
    int64_t low_vertices;
    int hard_limit; /* the vertex limit in force is the star set's hard limit */
    int in_final;   /* the limit or stop request came during the final checks */
    as_halt halt;   /* max_seconds and the stop flag, for the steps and the final checks */
    as_gcache gc;           /* rule 1's pair distortions (as_gcache) */
    struct as_evpre *evpre; /* drain's parallel part, per event */
    size_t cap_evpre;
    struct as_pcand *pcand; /* Pick_valid's candidates of a round (threads) */
    size_t cap_pcand;
    struct as_bjob *jobs;   /* a batch's jobs (batch_step), their points' lists kept */
    size_t cap_jobs;
    as_bpoint *win;         /* a batch's points to insert (copies of their jobs' points) */
    size_t cap_win;
    uint32_t *resv;         /* per id: the batch that reserved the star (batch_step) */
    struct as_bjob *defer;  /* jobs set aside by batch_take */
    size_t cap_defer;
    size_t cap_resv;
    uint32_t bepoch;
    int32_t njobs;
    /* as_starset_verify_zones' selection (on_held_piece): per site, its piece (union-find
     * over the restricted facets of the stars) and per piece root whether one of its
     * facets is not below hmin */
    uint32_t *piece;
    uint8_t *piece_refined;
    size_t cap_piece, cap_piece_refined;
} refiner;

/* as_rule1_violation with the refiner's pair cache (serial parts only: the pairs solved
 * are kept). */
static double rule1_cached(refiner *R, int32_t v, const as_rfacet *f, int *cause,
                           anistar_status *err) {
    int why;
    as_gnew fresh;
    double viol = rule1_local(R->ss, R->ss->ctx, R->prm, f, &why, err, &R->gc, &fresh);
    if (*err != ANISTAR_OK) return 0;
    for (int k = 0; k < fresh.n; k++)
        gcache_put(R->ctx, &R->gc, (size_t)R->ss->n, fresh.p[k].a, fresh.p[k].b, fresh.p[k].g);
    viol = rule1_feature(R->ss, v, f, viol, &why, err);
    if (*err != ANISTAR_OK) return 0;
    if (cause) *cause = why;
    return viol;
}

/*
 * Whether star v needs as_starset_verify_zones: every facet of its piece (the sites
 * joined by restricted facets) is below hmin. design: the ball zone of paper 5.3 is sound
 * where the sites are an epsilon-sample of S; a speck of S meshed with a few sites at
 * hmin (the noise of an image at its voxels) is not one: its Voronoi cells reach far
 * beyond its surface balls and meet the other sheets of S there (the brain at Otsu's
 * threshold: all 43 stars found wrong were on such pieces). Checking also every star with
 * a facet held by hmin beyond r0, rho0 or gamma0 found no wrong star on any input and cost
 * 26% on the bunny and about 10% on the fandisk and the liver; on the smooth inputs
 * neither selection holds a star. pieces_update computes the pieces first.
 */
static anistar_status pieces_update(refiner *R) {
    as_starset *ss = R->ss;
    size_t n = (size_t)ss->n;
    if (!(ss->hmin > 0)) return ANISTAR_OK;
    if (as_grow(R->ctx, (void **)&R->piece, &R->cap_piece, n, sizeof *R->piece) ||
        as_grow(R->ctx, (void **)&R->piece_refined, &R->cap_piece_refined, n, 1))
        return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory");
    for (size_t i = 0; i < n; i++) {
        R->piece[i] = (uint32_t)i;
        R->piece_refined[i] = 0;
    }
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        for (int32_t k = 0; st && k < st->nrf; k++) {
            const int32_t *g = st->rf[k].g;
            if (g[0] < ss->first_site) continue;
            as_uf_union(R->piece, (uint32_t)g[0], (uint32_t)g[1]);
            as_uf_union(R->piece, (uint32_t)g[0], (uint32_t)g[2]);
        }
    }
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        for (int32_t k = 0; st && k < st->nrf; k++)
            if (st->rf[k].g[0] >= ss->first_site && !as_facet_below_hmin(ss, &st->rf[k]))
                R->piece_refined[as_uf_find(R->piece, (uint32_t)v)] = 1;
    }
    return ANISTAR_OK;
}

static int on_held_piece(void *arg, int32_t v) {
    refiner *R = arg;
    if (!(R->ss->hmin > 0)) return 0;
    return !R->piece_refined[as_uf_find(R->piece, (uint32_t)v)];
}

static uint64_t rng_next_at(uint64_t *state) {
    /* xorshift64* */
    uint64_t x = *state;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *state = x;
    return x * 0x2545F4914F6CDD1DULL;
}
static double rng_unit_at(uint64_t *state) {
    return (double)(rng_next_at(state) >> 11) * 0x1.0p-53;
}
static double rng_unit(refiner *R) { return rng_unit_at(&R->rng); }

/* A fresh xorshift state from x (splitmix64: never zero). */
static uint64_t rng_seed(uint64_t x) {
    uint64_t z = x + 0x9E3779B97F4A7C15ULL;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return (z ^ (z >> 31)) | 1;
}

/* Turn the star set's events into queue entries. */
/* What drain's threads find for event k (ev_task): the facet's index in its star (-1:
 * gone), rule 1 without its feature-size part (cause, status) and rule 2. */
typedef struct as_evpre {
    int32_t i;
    int why;
    anistar_status err;
    double v1, v2;
    as_ftab_entry *te; /* the facet's table entry (the table does not move while draining) */
    as_gnew gn;        /* the pairs rule 1 solved (kept by the serial part) */
} as_evpre;

static anistar_status ev_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)t;
    refiner *R = arg;
    const as_starset *ss = R->ss;
    const as_fevent *e = &ss->ev[k];
    as_evpre *d = &R->evpre[k];
    const as_star *st = ss->stars[e->star];
    d->i = as_star_find(st, e->g);
    if (d->i < 0) return ANISTAR_OK;
    const as_rfacet *f = &st->rf[d->i];
    d->gn.n = 0;
    d->v1 = (f->queued & 1) ? 0
                            : rule1_local(ss, tctx, R->prm, f, &d->why, &d->err, &R->gc, &d->gn);
    d->v2 = (f->queued & 2) ? 0 : as_rule2_violation(ss, R->prm, e->star, f);
    d->te = as_starset_lookup(ss, as_facet_key(f->g));
    return ANISTAR_OK;
}

static anistar_status drain(refiner *R) {
    as_starset *ss = R->ss;
    anistar_status s;
    /* design: with threads, the rules' local tests of every event first, in parallel
     * (they read the stars and the points only), then the queues in the events' order
     * with the feature-size part (a cache); a facet queued by an earlier event is skipped
     * as before, so the queues are the serial loop's */
    const int pre = ss->pool && ss->nev >= 4;
    if (pre) {
        if (ss->nev > R->cap_evpre &&
            as_grow(R->ctx, (void **)&R->evpre, &R->cap_evpre, ss->nev, sizeof *R->evpre))
            return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (events)");
        memset(R->evpre, 0, ss->nev * sizeof *R->evpre);
        if ((s = as_pool_run(ss->pool, (int32_t)ss->nev, ev_task, R)) != ANISTAR_OK) return s;
    }
    for (size_t k = 0; k < ss->nev; k++) {
        const as_fevent *e = &ss->ev[k];
        as_star *st = ss->stars[e->star];
        int32_t i = pre ? R->evpre[k].i : as_star_find(st, e->g);
        if (i < 0) continue;
        as_rfacet *f = &st->rf[i];
        as_fkey key = as_facet_key(f->g);
        if (!(f->queued & 1)) {
            double v1;
            if (pre && R->evpre[k].err == ANISTAR_OK) {
                int why = R->evpre[k].why;
                const as_gnew *gn = &R->evpre[k].gn;
                for (int j = 0; j < gn->n; j++)
                    gcache_put(R->ctx, &R->gc, (size_t)ss->n, gn->p[j].a, gn->p[j].b,
                               gn->p[j].g);
                s = ANISTAR_OK;
                v1 = rule1_feature(ss, e->star, f, R->evpre[k].v1, &why, &s);
            } else {
                v1 = rule1_cached(R, e->star, f, NULL, &s);
            }
            if (s != ANISTAR_OK) return s;
            if (v1 > 0) {
                as_qentry q = {v1, key, e->star};
                if ((s = as_queue_push(R->ctx, &R->q[0], q)) != ANISTAR_OK) return s;
                f->queued |= 1;
            }
        }
        if (!(f->queued & 2)) {
            double v2 = pre ? R->evpre[k].v2 : as_rule2_violation(ss, R->prm, e->star, f);
            if (v2 > 0) {
                as_qentry q = {v2, key, e->star};
                if ((s = as_queue_push(R->ctx, &R->q[1], q)) != ANISTAR_OK) return s;
                f->queued |= 2;
            }
        }
        as_ftab_entry *te = pre ? R->evpre[k].te : as_starset_lookup(ss, key);
        if (te && te->incpos >= 0 && !te->queued) {
            as_qentry q = {f->r, key, e->star};
            if ((s = as_queue_push(R->ctx, &R->q[2], q)) != ANISTAR_OK) return s;
            te->queued = 1;
        }
    }
    ss->nev = 0;
    for (size_t k = 0; k < ss->nnewinc; k++) {
        as_ftab_entry *te = as_starset_lookup(ss, ss->newinc[k]);
        if (!te || te->incpos < 0 || te->queued) continue;
        const as_gid *g = te->key.g;
        /* the priority: r of the lowest star holding it */
        for (int b = 0; b < 3; b++) {
            if (!(te->mask & (1u << b))) continue;
            as_star *st = ss->stars[g[b]];
            int32_t i = st ? as_star_find(st, g) : -1;
            if (i < 0) continue;
            as_qentry q = {st->rf[i].r, te->key, g[b]};
            if ((s = as_queue_push(R->ctx, &R->q[2], q)) != ANISTAR_OK) return s;
            te->queued = 1;
            break;
        }
    }
    ss->nnewinc = 0;
    for (int k = 0; k < 3; k++) as_queue_trim(R->ctx, &R->q[k]);
    return ANISTAR_OK;
}

/*
 * The stall bookkeeping. design: rule 3 runs only when no other rule applies, so the
 * inconsistent-facet count it sees is the residue of an otherwise finished mesh; in a run
 * that converges that residue falls to 0 (paper 4.3), in one that does not, rule-3
 * insertions create as many inconsistencies as they remove. The counter is the number of
 * rule-3 insertions since the residue last reached a new low; a count of 0 at any time
 * starts over. Rule-1 growth, whatever its length, never counts.
 */
static void stall_update(refiner *R, int rule3) {
    const as_starset *ss = R->ss;
    if (ss->ninc == 0) {
        R->inc_low = SIZE_MAX;
        R->low_at = R->n3;
        return;
    }
    if (!rule3) return;
    if (ss->ninc < R->inc_low) {
        R->inc_low = ss->ninc;
        R->low_at = R->n3;
        R->low_vertices = ss->n - ss->first_site;
    }
    R->n3++;
    uint64_t stalled = R->n3 - R->low_at;
    if (stalled > R->cnt.stall_max) R->cnt.stall_max = stalled;
}

/* The stall budget in force (ANISTAR_PARAM_MAX_STALL, automatic when 0). */
static uint64_t stall_budget(const refiner *R) {
    if (R->prm->max_stall > 0) return (uint64_t)R->prm->max_stall;
    uint64_t b = (uint64_t)AS_STALL_PER_VERTEX * (uint64_t)R->low_vertices;
    return b > AS_STALL_MIN ? b : AS_STALL_MIN;
}

static anistar_status insert_point(refiner *R, const double p[3]) {
    anistar_status s = as_starset_insert(R->ss, p, NULL);
    if (s != ANISTAR_OK) return s;
    stall_update(R, 0);
    return drain(R);
}

/* The first site or pole q (in *q, -1 if none) within M_v distance lim of p (its
 * distance in *d). OK or ENOMEM. */
static anistar_status site_within(as_starset *ss, const double p[3], int32_t v, double lim,
                                  int32_t *q, double *d) {
    const as_metric_frame *mf = &ss->mf[v];
    double h[3], lo[3], hi[3];
    *q = -1;
    *d = INFINITY;
    as_metric_ellipsoid_box(mf, lim, h);
    for (int k = 0; k < 3; k++) {
        lo[k] = p[k] - h[k] * (1 + 1e-9) - 1e-300;
        hi[k] = p[k] + h[k] * (1 + 1e-9) + 1e-300;
    }
    anistar_status s = as_kdtree_box_any(ss->ctx, ss->kd, lo, hi, 0, &ss->ws.ids);
    if (s != ANISTAR_OK) return s;
    for (size_t k = 0; k < ss->ws.ids.n; k++) {
        int32_t u = ss->ws.ids.ids[k];
        double e = as_metric_dist(mf, p, ss->xyz + 3 * (size_t)u);
        if (!(e < lim)) continue;
        *q = u;
        *d = e;
        break;
    }
    return ANISTAR_OK;
}

anistar_status as_refine_check_point(as_starset *ss, const double p[3], int32_t v,
                                     const as_gid g[3], double r) {
    anistar_context *ctx = ss->ctx;
    double lim = AS_NEAR_SITE * r, d;
    int32_t q;
    anistar_status s = site_within(ss, p, v, lim, &q, &d);
    if (s != ANISTAR_OK) return s;
    if (q >= 0) {
        if (g)
            return as_fail(ctx, ANISTAR_EINTERNAL,
                           "mesher: the refinement point (%.17g, %.17g, %.17g) of facet (%d %d %d) "
                           "in the star of site %d (radius %.3g) lies %.3g from site %d, within "
                           "a relative %g: a site missing from that star (a bug; please report "
                           "it with the command)",
                           p[0], p[1], p[2], (int)g[0], (int)g[1], (int)g[2], (int)v, r, d,
                           (int)q, AS_NEAR_SITE);
        return as_fail(ctx, ANISTAR_EINTERNAL,
                       "mesher: the topology refinement point (%.17g, %.17g, %.17g) of the star "
                       "of site %d (distance %.3g) lies %.3g from site %d, within a relative %g "
                       "(a bug; please report it with the command)",
                       p[0], p[1], p[2], (int)v, r, d, (int)q, AS_NEAR_SITE);
    }
    return ANISTAR_OK;
}

/* The Euclidean distance from p to the nearest site or pole (its id in *id). */
static double nearest_site(const as_starset *ss, const double p[3], int32_t *id) {
    double d2;
    if (as_kdtree_knn(ss->kd, p, 1, id, &d2) == 0) return INFINITY;
    return sqrt(d2);
}

/* 1 if p coincides with an existing point (kd-tree nearest at distance 0). */
static int is_duplicate(const as_starset *ss, const double p[3]) {
    int32_t id;
    double d2;
    if (as_kdtree_knn(ss->kd, p, 1, &id, &d2) == 0) return 0;
    return d2 == 0;
}

/*
 * Predict whether the facet f of the simulated star of p (id pid) would be restricted in
 * the star of its vertex w (a site): the surface M_w-circumball of the triangle (the
 * smallest M_w-circumball centred on S, paper 3.1) is empty of the points of w's star.
 */
static anistar_status predict_restricted(refiner *R, anistar_context *ctx, const as_rfacet *f,
                                         int32_t pid, const double p[3], int32_t w,
                                         int *restricted) {
    as_starset *ss = R->ss;
    const as_metric_frame *mf = &ss->mf[w];
    const double *x[3];
    for (int k = 0; k < 3; k++) x[k] = f->g[k] == pid ? p : ss->xyz + 3 * (size_t)f->g[k];
    double Y[3][3];
    for (int k = 0; k < 3; k++) as_metric_apply(mf, x[k], Y[k]);
    double u[3], v[3], n[3];
    for (int k = 0; k < 3; k++) {
        u[k] = Y[1][k] - Y[0][k];
        v[k] = Y[2][k] - Y[0][k];
    }
    n[0] = u[1] * v[2] - u[2] * v[1];
    n[1] = u[2] * v[0] - u[0] * v[2];
    n[2] = u[0] * v[1] - u[1] * v[0];
    double nn = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    *restricted = 0;
    if (!(nn > 0)) return ANISTAR_OK;
    double uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2], vv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    double sv[3] = {uu * v[0] - vv * u[0], uu * v[1] - vv * u[1], uu * v[2] - vv * u[2]};
    double O[3] = {Y[0][0] + (sv[1] * n[2] - sv[2] * n[1]) / (2 * nn * nn),
                   Y[0][1] + (sv[2] * n[0] - sv[0] * n[2]) / (2 * nn * nn),
                   Y[0][2] + (sv[0] * n[1] - sv[1] * n[0]) / (2 * nn * nn)};
    double rho = sqrt((O[0] - Y[0][0]) * (O[0] - Y[0][0]) + (O[1] - Y[0][1]) * (O[1] - Y[0][1]) +
                      (O[2] - Y[0][2]) * (O[2] - Y[0][2]));
    /* design: the M_w-axis O + s n, s in [-2 rho, 2 rho], mapped back; its crossing with S
     * nearest the circumcenter is the center of the surface ball. */
    double A[3], B[3], o[3];
    for (int k = 0; k < 3; k++) {
        A[k] = O[k] - 2 * rho * n[k] / nn;
        B[k] = O[k] + 2 * rho * n[k] / nn;
    }
    double a[3], b[3], c[3];
    as_metric_unapply(mf, A, a);
    as_metric_unapply(mf, B, b);
    as_metric_unapply(mf, O, o);
    int found = 0;
    anistar_status s = as_surface_crossing(ctx, ss->surf, a, b, o, &found, c);
    if (s != ANISTAR_OK) return s;
    if (!found) return ANISTAR_OK;
    double C[3];
    as_metric_apply(mf, c, C);
    double r2 = (C[0] - Y[0][0]) * (C[0] - Y[0][0]) + (C[1] - Y[0][1]) * (C[1] - Y[0][1]) +
                (C[2] - Y[0][2]) * (C[2] - Y[0][2]);
    const as_star *st = ss->stars[w];
    for (int32_t q = 0; q < as_star_nv(st); q++) {
        as_gid gq = as_star_vertex_gid(st, q);
        if (gq == f->g[0] || gq == f->g[1] || gq == f->g[2]) continue;
        double Q[3];
        as_star_point(st, ss->xyz, mf, q, Q);
        double d2 = (C[0] - Q[0]) * (C[0] - Q[0]) + (C[1] - Q[1]) * (C[1] - Q[1]) +
                    (C[2] - Q[2]) * (C[2] - Q[2]);
        if (d2 < r2) return ANISTAR_OK;
    }
    *restricted = 1;
    return ANISTAR_OK;
}

/*
 * Is p a valid refinement point for a facet of radius rv (paper 4.2)? We simulate p's
 * star and reject p when one of its restricted facets smaller than beta * rv (radius in
 * M_p) is predicted inconsistent: a vertex is a corner or pole (*pole = 1: such facets
 * are looked for first), or the facet would not be restricted in the star of another
 * vertex.
 * design (replaces the hitting-set test, DESIGN.md 4.5): only the facets of p's own
 * predicted surface star are examined; facets with p that other stars would gain but p's
 * star would lack are not simulated (they are caught by rule 3 later).
 */
/* t: the thread slot whose workspace simulates (-1: the caller's); ctx: its context */
static anistar_status valid_point_on(refiner *R, int t, anistar_context *ctx, const double p[3],
                                     double rv, int *valid, int *pole) {
    as_starset *ss = R->ss;
    as_metric_frame mf;
    anistar_status s = as_starset_metric_in(ss, ctx, p, &mf);
    if (s != ANISTAR_OK) return s;
    as_star *sp;
    s = t < 0 ? as_starset_simulate(ss, p, &mf, &sp) : as_starset_simulate_thread(ss, t, p, &mf, &sp);
    if (s != ANISTAR_OK) return s;
    int32_t pid = ss->n;
    *valid = 1;
    *pole = 0;
    for (int32_t i = 0; i < sp->nrf; i++) {
        const as_rfacet *f = &sp->rf[i];
        if (f->r >= R->prm->beta * rv) continue;
        for (int k = 0; k < 3; k++)
            if (f->g[k] != pid && f->g[k] < ss->first_site) {
                *valid = 0;
                *pole = 1;
                return ANISTAR_OK;
            }
    }
    for (int32_t i = 0; i < sp->nrf && *valid; i++) {
        const as_rfacet *f = &sp->rf[i];
        if (f->r >= R->prm->beta * rv) continue;
        for (int k = 0; k < 3 && *valid; k++) {
            int32_t w = f->g[k];
            if (w == pid) continue;
            int res;
            if ((s = predict_restricted(R, ctx, f, pid, p, w, &res)) != ANISTAR_OK) return s;
            if (!res) *valid = 0;
        }
    }
    return ANISTAR_OK;
}

/* Pick_valid on threads: one candidate of a round (pick_task). */
typedef struct as_pcand {
    int is_center;
    double u[3];        /* a try's draw (in the unit ball, times rad) */
    uint64_t rng_after; /* the refiner's random state after the draw */
    int skip;           /* the try gives no candidate (no projection, outside, a site) */
    double q[3];
    int valid;
    int pole;           /* invalid for a small facet with a pole or corner (valid_point_on) */
    anistar_status st;  /* the candidate's error (its message in msg) */
    char msg[AS_ERRMSG_SIZE];
} as_pcand;

typedef struct as_pround {
    refiner *R;
    const as_rfacet *f;
    const as_metric_frame *mf;
    const double *n;
    int sing;
    double rad;
    as_pcand *c;
} as_pround;

static int is_duplicate(const as_starset *ss, const double p[3]);

static anistar_status pick_one(as_pround *P, as_pcand *c, int t, anistar_context *tctx) {
    refiner *R = P->R;
    as_starset *ss = R->ss;
    const as_rfacet *f = P->f;
    if (c->is_center) {
        memcpy(c->q, f->c, sizeof c->q);
    } else {
        double w[3], y[3];
        as_metric_unapply(P->mf, c->u, w);
        const double *n = P->n;
        double dn = P->sing ? 0 : w[0] * n[0] + w[1] * n[1] + w[2] * n[2];
        for (int k2 = 0; k2 < 3; k2++) y[k2] = f->c[k2] + w[k2] - dn * n[k2];
        anistar_status s = as_surface_project(tctx, ss->surf, y, c->q);
        if (s == ANISTAR_ENOSURFACE || (s == ANISTAR_OK && !(as_metric_dist(P->mf, c->q, f->c) <= P->rad))) {
            c->skip = 1;
            return ANISTAR_OK;
        }
        if (s != ANISTAR_OK) return s;
        if (is_duplicate(ss, c->q)) {
            c->skip = 1;
            return ANISTAR_OK;
        }
    }
    return valid_point_on(R, t, tctx, c->q, f->r, &c->valid, &c->pole);
}

/* A candidate's errors stay with it: the serial loop would report one only if no earlier
 * candidate was valid. */
static anistar_status pick_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    as_pround *P = arg;
    as_pcand *c = &P->c[k];
    c->skip = 0;
    c->valid = 0;
    c->pole = 0;
    c->st = pick_one(P, c, t, tctx);
    if (c->st != ANISTAR_OK) memcpy(c->msg, tctx->last_error, sizeof c->msg);
    return ANISTAR_OK;
}

/* Pick_valid on the pool: candidates (the center, then the tries) in rounds of one per
 * thread. design: a round's draws are made in order before it, each try's random state
 * after its draw kept; the first valid candidate of a round (in order) wins and the state
 * is set back to after its draw, and errors count only up to it, so the point, the random
 * state and the counts are those of the serial loop whatever the thread count (the
 * candidates after the winner were simulated for nothing: they cost the other threads'
 * time, not the caller's). */
static anistar_status pick_valid_pool(refiner *R, const as_rfacet *f, const as_metric_frame *mf,
                                      double out[3]) {
    as_starset *ss = R->ss;
    anistar_status s;
    const int T = as_pool_threads(ss->pool);
    double n[3] = {0, 0, 0};
    int sing = 0;
    anistar_status ns = as_surface_normal_at(R->ctx, ss->surf, f->c, n, &sing);
    const double rad = R->prm->delta * f->r;
    if ((s = as_starset_simulate_prepare(ss)) != ANISTAR_OK) return s;
    if ((size_t)T > R->cap_pcand &&
        as_grow(R->ctx, (void **)&R->pcand, &R->cap_pcand, (size_t)T, sizeof *R->pcand))
        return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (Pick_valid)");
    as_pround P = {R, f, mf, n, sing, rad, R->pcand};
    int center = !is_duplicate(ss, f->c);
    int32_t tries = 0; /* tries drawn so far */
    const int32_t ntries = R->prm->pick_tries;
    memcpy(out, f->c, 3 * sizeof(double));
    while (center || tries < ntries) {
        int m = 0;
        const uint64_t rng0 = R->rng;
        if (center) {
            R->pcand[m].is_center = 1;
            R->pcand[m].rng_after = rng0;
            m++;
        }
        if (center && ns != ANISTAR_OK) {
            /* the normal failed: the serial loop would not have needed it if the center
             * is valid; test the center alone */
        } else {
            if (ns != ANISTAR_OK) return ns;
            for (; m < T && tries < ntries; m++, tries++) {
                as_pcand *c = &R->pcand[m];
                c->is_center = 0;
                double u[3];
                do {
                    for (int k = 0; k < 3; k++) u[k] = 2 * rng_unit(R) - 1;
                } while (u[0] * u[0] + u[1] * u[1] + u[2] * u[2] > 1);
                for (int k = 0; k < 3; k++) c->u[k] = u[k] * rad;
                c->rng_after = R->rng;
            }
        }
        s = as_pool_run(ss->pool, m, pick_task, &P);
        as_starset_collect_counts(ss);
        if (s != ANISTAR_OK) return s;
        /* the first valid candidate in order; an error before it ends the run */
        int win = -1;
        for (int k = 0; k < m && win < 0; k++) {
            if (R->pcand[k].st != ANISTAR_OK)
                return as_fail(R->ctx, R->pcand[k].st, "%s", R->pcand[k].msg);
            if (R->pcand[k].valid) win = k;
            else if (R->pcand[k].is_center && R->pcand[k].pole) {
                /* the center fails for a pole: no try (pick_valid_on) */
                R->rng = rng0;
                R->cnt.pick_failures++;
                memcpy(out, f->c, 3 * sizeof(double));
                return ANISTAR_OK;
            }
        }
        /* the counts and the random state as the serial loop leaves them */
        int last = win >= 0 ? win : m - 1;
        for (int k = 0; k <= last; k++)
            if (!R->pcand[k].is_center) R->cnt.pick_tries++;
        if (win >= 0) {
            R->rng = R->pcand[win].rng_after;
            memcpy(out, R->pcand[win].q, 3 * sizeof(double));
            return ANISTAR_OK;
        }
        if (center && ns != ANISTAR_OK) return ns;
        center = 0;
    }
    R->cnt.pick_failures++;
    memcpy(out, f->c, 3 * sizeof(double));
    return ANISTAR_OK;
}

/* Pick_valid(tau, M_v) (paper 4.2, DESIGN.md 4.5): the center first, then random points of
 * the picking region; after pick_tries failures the center. One candidate after the other
 * on thread slot t (-1: the caller's workspace; ctx: the slot's context), with the random
 * state *rng; the tries made and failures (0 or 1) added to *tries and *failures. */
static anistar_status pick_valid_on(refiner *R, int t, anistar_context *ctx,
                                    const as_rfacet *f, const as_metric_frame *mf, uint64_t *rng,
                                    double out[3], uint64_t *tries, uint64_t *failures) {
    as_starset *ss = R->ss;
    anistar_status s;
    int valid = 0, pole = 0;
    memcpy(out, f->c, 3 * sizeof(double));
    if (!is_duplicate(ss, f->c)) {
        if ((s = valid_point_on(R, t, ctx, f->c, f->r, &valid, &pole)) != ANISTAR_OK) return s;
        if (valid) return ANISTAR_OK;
        if (pole) {
            /* design: a center refused for a small facet with a pole (or corner) is
             * inserted at once, without the random tries: a pole in the star means the
             * sample does not yet separate S from the medial axis there (at a CAD
             * crease the medial axis reaches S), a matter of density that moving the
             * point by delta r does not change. The tries are for near-cospherical
             * configurations, which this is not; on the hinge all 11,996 tries of
             * such picks failed (docs/algorithm.md) */
            (*failures)++;
            return ANISTAR_OK;
        }
    }
    double n[3];
    int sing = 0;
    if ((s = as_surface_normal_at(ctx, ss->surf, f->c, n, &sing)) != ANISTAR_OK) return s;
    double rad = R->prm->delta * f->r;
    for (int32_t k2 = 0; k2 < R->prm->pick_tries; k2++) {
        (*tries)++;
        double u[3];
        do {
            for (int k = 0; k < 3; k++) u[k] = 2 * rng_unit_at(rng) - 1;
        } while (u[0] * u[0] + u[1] * u[1] + u[2] * u[2] > 1);
        double w[3], y[3], q[3];
        for (int k = 0; k < 3; k++) u[k] *= rad;
        as_metric_unapply(mf, u, w);
        /* design: a point of the M_v-ball around c, moved to the tangent plane at c, then
         * projected onto S; kept if still within the picking region. */
        double dn = sing ? 0 : w[0] * n[0] + w[1] * n[1] + w[2] * n[2];
        for (int k = 0; k < 3; k++) y[k] = f->c[k] + w[k] - dn * n[k];
        s = as_surface_project(ctx, ss->surf, y, q);
        if (s == ANISTAR_ENOSURFACE) continue;
        if (s != ANISTAR_OK) return s;
        if (!(as_metric_dist(mf, q, f->c) <= rad)) continue;
        if (is_duplicate(ss, q)) continue;
        if ((s = valid_point_on(R, t, ctx, q, f->r, &valid, &pole)) != ANISTAR_OK) return s;
        if (valid) {
            memcpy(out, q, sizeof q);
            return ANISTAR_OK;
        }
    }
    (*failures)++;
    memcpy(out, f->c, 3 * sizeof(double));
    return ANISTAR_OK;
}

static anistar_status pick_valid(refiner *R, int32_t v, const as_rfacet *f, double out[3]) {
    as_starset *ss = R->ss;
    /* a copy: simulations may move ss->mf */
    const as_metric_frame mfv = ss->mf[v], *mf = &mfv;
    if (ss->pool) return pick_valid_pool(R, f, mf, out);
    return pick_valid_on(R, -1, R->ctx, f, mf, &R->rng, out, &R->cnt.pick_tries,
                         &R->cnt.pick_failures);
}

/* ---- topology rule ---------------------------------------------------------------------- */

/*
 * The refinement point of star v whose surface star is empty or not one closed fan
 * (the topology rule, before rule 1; paper 2.3's sf = min(lfs, dr): such a star means
 * the sample is too coarse for S around v). *found = 0 when no candidate exists.
 * design: candidates are points of S in v's M_v-Voronoi cell, as far from v as they
 * come (the insertion radius of a point of that cell is its M_v distance to v):
 *  1. the surface centers of v's restricted facets (M_v distance r_v(tau));
 *  2. for each tet t incident to v, the crossing of S with the segment from v to t's
 *     circumcenter (mapped back by F_v^-1) nearest that circumcenter: the segment lies
 *     in v's cell (convex), and every point of it but v is strictly inside t's
 *     circumsphere, so the point conflicts with v's star and changes it.
 * The farthest candidate in M_v wins; crossings within a relative 1e-6 of the segment
 * from v are v itself and are skipped.
 *  3. when neither gives a point (every segment meets S at v only: v at a corner), S is
 *     probed around v: projections of points of v's tangent plane, the farthest that
 *     conflicts with the star and is not an existing site within AS_NEAR_SITE (a
 *     projection can snap to a site: no theory keeps it away, unlike 1 and 2).
 */
static anistar_status topology_point(refiner *R, int32_t v, double out[3], double *dist,
                                     int *found) {
    as_starset *ss = R->ss;
    const as_star *st = ss->stars[v];
    const as_metric_frame mfv = ss->mf[v], *mf = &mfv;
    const double *x = ss->xyz + 3 * (size_t)v;
    anistar_status s;
    *found = 0;
    *dist = 0;
    for (int32_t i = 0; i < st->nrf; i++) {
        if (st->rf[i].r > *dist) {
            *dist = st->rf[i].r;
            memcpy(out, st->rf[i].c, 3 * sizeof(double));
            *found = 1;
        }
    }
    for (int32_t i = 0; i < st->nitet; i++) {
        double S[4];
        as_star_sphere(st, ss->xyz, mf, i, S);
        if (S[3] == -1) continue;
        double b[3], c[3];
        as_metric_unapply(mf, S, b);
        int hit = 0;
        if ((s = as_surface_crossing(R->ctx, ss->surf, x, b, b, &hit, c)) != ANISTAR_OK) return s;
        if (!hit) continue;
        double d = as_metric_dist(mf, c, x), full = as_metric_dist(mf, b, x);
        if (!(d > 1e-6 * full) || d <= *dist) continue;
        *dist = d;
        memcpy(out, c, sizeof c);
        *found = 1;
    }
    if (*found) return ANISTAR_OK;
    /* design: nothing crosses (v on a part of S smaller than its cell, e.g. a speck): probe
     * S around v, projecting points of v's tangent plane at distances falling by 4 from
     * the nearest circumradius; the farthest that conflicts with v's star is the point */
    double n[3];
    int sing = 0;
    if ((s = as_surface_normal_at(R->ctx, ss->surf, x, n, &sing)) != ANISTAR_OK) return s;
    if (sing) return ANISTAR_OK;
    double t1[3], t2[3], a[3] = {0, 0, 0};
    a[fabs(n[0]) < 0.6 ? 0 : fabs(n[1]) < 0.6 ? 1 : 2] = 1;
    double dn = a[0] * n[0] + a[1] * n[1] + a[2] * n[2], l = 0;
    for (int k = 0; k < 3; k++) {
        t1[k] = a[k] - dn * n[k];
        l += t1[k] * t1[k];
    }
    for (int k = 0; k < 3; k++) t1[k] /= sqrt(l);
    t2[0] = n[1] * t1[2] - n[2] * t1[1];
    t2[1] = n[2] * t1[0] - n[0] * t1[2];
    t2[2] = n[0] * t1[1] - n[1] * t1[0];
    double rad = INFINITY;
    for (int32_t i = 0; i < st->nitet; i++) {
        double S[4];
        as_star_sphere(st, ss->xyz, mf, i, S);
        if (S[3] > 0 && S[3] < rad * rad) rad = sqrt(S[3]);
    }
    if (!isfinite(rad)) return ANISTAR_OK;
    for (int k = 0; k < 12 && !*found; k++, rad *= 0.25) {
        for (int j = 0; j < 6; j++) {
            double ang = 1.0471975511965976 * j, y[3], w[3], q[3];
            for (int i = 0; i < 3; i++) y[i] = rad * (cos(ang) * t1[i] + sin(ang) * t2[i]);
            as_metric_unapply(mf, y, w); /* M_v length rad in a tangent direction */
            for (int i = 0; i < 3; i++) q[i] = x[i] + w[i];
            s = as_surface_project(R->ctx, ss->surf, q, q);
            if (s == ANISTAR_ENOSURFACE) continue;
            if (s != ANISTAR_OK) return s;
            double d = as_metric_dist(mf, q, x);
            if (!(d > 1e-6 * rad) || d <= *dist) continue;
            if (!as_star_conflicts(st, mf, ss->xyz, q, ss->n, NULL)) continue;
            /* a projection can land on an existing site (on a triangle mesh it snaps to
             * the corner or crease nearest the probe, where earlier points landed too):
             * a point within rounding of a site is no new point (its conflict is that of
             * a perturbed copy of a star vertex) */
            int32_t near;
            double dn2;
            if ((s = site_within(ss, q, v, AS_NEAR_SITE * d, &near, &dn2)) != ANISTAR_OK)
                return s;
            if (near >= 0) continue;
            *dist = d;
            memcpy(out, q, sizeof q);
            *found = 1;
        }
    }
    return ANISTAR_OK;
}

/* ---- initial points ------------------------------------------------------------------- */

/* design: the surface sample (256 points, every component) gives the poles; the initial
 * sites are a farthest-point subset of each component's points: max(4, n_c / 8) of its
 * n_c points (at most n_c). */
static anistar_status initial_points(refiner *R) {
    as_starset *ss = R->ss;
    anistar_context *ctx = R->ctx;
    as_point_sample smp;
    memset(&smp, 0, sizeof smp);
    anistar_status s = (ss->sampler ? as_sampler_sample(ctx, ss->sampler, 256, &smp)
                                    : as_surface_sample(ctx, ss->surf, 256, &smp));
    if (s != ANISTAR_OK) return s;
    double *dist = as_alloc_array(ctx, smp.n ? smp.n : 1, sizeof *dist);
    if (!dist) {
        as_surface_sample_free(ctx, &smp);
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (initial points)");
    }
    if ((s = as_starset_add_poles(ss, smp.points, (int32_t)smp.n, 256)) != ANISTAR_OK) goto done;
    ss->nscomp = 0;
    /* design: an image's isosurface has specks from noise far below its voxels (a value a
     * hair above iso at one point): a component whose area is below the square of the
     * feature-size floor (about half a voxel) is below the image's resolution and is not
     * meshed (counted); every other kind meshes every component found */
    const double tiny = as_surface_is_image(ss->surf) ? ss->feat.floor_e * ss->feat.floor_e : 0;
    for (size_t c = 0; c < smp.ncomponents; c++) {
        if (smp.area && smp.area[c] < tiny) {
            R->cnt.specks++;
            continue;
        }
        const int32_t label = ss->nscomp++;
        size_t nc = 0, first = SIZE_MAX;
        for (size_t i = 0; i < smp.n; i++)
            if ((size_t)smp.component[i] == c) {
                nc++;
                if (first == SIZE_MAX) first = i;
                dist[i] = INFINITY;
            }
        if (!nc) continue;
        size_t want = R->prm->initial_points > 0 ? (size_t)R->prm->initial_points : nc / 8;
        if (want < 4) want = 4;
        if (want > nc) want = nc;
        size_t pick = first;
        for (size_t k = 0; k < want; k++) {
            const double *p = smp.points + 3 * pick;
            if (!is_duplicate(ss, p)) {
                int32_t gid = ss->n;
                if ((s = insert_point(R, p)) != ANISTAR_OK) goto done;
                ss->scomp[gid] = label;
                R->cnt.initial++;
            }
            dist[pick] = -1;
            double best = -1;
            size_t nx = pick;
            for (size_t i = 0; i < smp.n; i++) {
                if ((size_t)smp.component[i] != c || dist[i] < 0) continue;
                const double *x = smp.points + 3 * i;
                double d2 = (x[0] - p[0]) * (x[0] - p[0]) + (x[1] - p[1]) * (x[1] - p[1]) +
                            (x[2] - p[2]) * (x[2] - p[2]);
                if (d2 < dist[i]) dist[i] = d2;
                if (dist[i] > best) {
                    best = dist[i];
                    nx = i;
                }
            }
            if (best < 0) break;
            pick = nx;
        }
    }
done:
    as_free(ctx, dist, (smp.n ? smp.n : 1) * sizeof *dist);
    as_surface_sample_free(ctx, &smp);
    return s;
}

/* ---- main loop ------------------------------------------------------------------------- */

/* The rules as next_job reports them. */
enum { JOB_NONE = -1, JOB_RULE1 = 0, JOB_RULE2 = 1, JOB_RULE3 = 2, JOB_TOPOLOGY = 3 };

/* Pop the next valid job: the topology rule first (a star that is not one closed fan),
 * then the entry of the highest-priority rule; *rule = JOB_NONE when none. */
/* Drop the stars on top of the open-star stack that closed since they were queued. */
static void drop_closed_open(as_starset *ss) {
    while (ss->nopen > 0 && ss->stars[ss->open[ss->nopen - 1]]->closed)
        ss->stars[ss->open[--ss->nopen]]->topo_queued = 0;
}

/* Whether entry e of queue k (0, 1: rules 1, 2 on a star's facet; 2: rule 3 on an
 * inconsistent facet) is still a job; then its queue flag is cleared and the star and the
 * facet (for rule 3, in the lowest vertex's star that holds it) are in *v, *f. */
static int take_entry(refiner *R, int k, const as_qentry *e, int32_t *v, as_rfacet *f) {
    as_starset *ss = R->ss;
    const as_gid *g = e->key.g;
    if (k < 2) {
        as_star *st = ss->stars[e->star];
        int32_t i = as_star_find(st, g);
        if (i < 0 || !(st->rf[i].queued & (1u << k))) return 0;
        st->rf[i].queued &= (uint8_t) ~(1u << k);
        *v = e->star;
        *f = st->rf[i];
        return 1;
    }
    as_ftab_entry *te = as_starset_lookup(ss, e->key);
    if (!te) return 0;
    te->queued = 0;
    if (te->incpos < 0) return 0;
    for (int b = 0; b < 3; b++) {
        if (!(te->mask & (1u << b))) continue;
        as_star *st = ss->stars[g[b]];
        int32_t i = as_star_find(st, g);
        if (i < 0) continue;
        *v = g[b];
        *f = st->rf[i];
        return 1;
    }
    return 0;
}

static anistar_status next_job(refiner *R, int *rule, int32_t *star, as_rfacet *fout,
                               int *cause) {
    as_starset *ss = R->ss;
    anistar_status s;
    drop_closed_open(ss);
    if (ss->nopen > 0) {
        int32_t v = ss->open[--ss->nopen];
        ss->stars[v]->topo_queued = 0;
        *rule = JOB_TOPOLOGY;
        *star = v;
        memset(fout, 0, sizeof *fout);
        return ANISTAR_OK;
    }
    for (int k = 0; k < 3; k++) {
        as_qentry e;
        while (as_queue_pop(&R->q[k], &e)) {
            if (!take_entry(R, k, &e, star, fout)) continue;
            if (k < 2) {
                double viol = k == 0 ? rule1_cached(R, *star, fout, cause, &s)
                                     : as_rule2_violation(ss, R->prm, *star, fout);
                if (k == 0 && s != ANISTAR_OK) return s;
                if (viol <= 0) continue;
            }
            *rule = k;
            return ANISTAR_OK;
        }
    }
    *rule = JOB_NONE;
    return ANISTAR_OK;
}

/* ---- batches (issue 15) ---------------------------------------------------------------- */

/* A job of a batch: a queue entry taken, its facet, and what the threads computed. */
typedef struct as_bjob {
    as_qentry e;    /* the entry (put back when the job loses its stars) */
    int rule;       /* JOB_RULE1, JOB_RULE2, JOB_RULE3 */
    int why;        /* rule 1's cause */
    int32_t v;      /* the star */
    as_rfacet f;    /* the facet (a copy) */
    double viol;    /* rules 1-2: the local part of the violation */
    uint64_t rng;   /* its own random state (Pick_valid) */
    uint64_t tries, failures;
    int live;       /* still a job after the violation test */
    as_bpoint b;    /* its point, frame and conflicting stars */
} as_bjob;

/* Put job J's entry back in its queue (its star was taken by an earlier job of the batch,
 * or the vertex limit was reached). */
static anistar_status batch_putback(refiner *R, const as_bjob *J) {
    as_starset *ss = R->ss;
    if (J->rule < 2) {
        as_star *st = ss->stars[J->e.star];
        int32_t i = as_star_find(st, J->e.key.g);
        if (i < 0 || (st->rf[i].queued & (1u << J->rule))) return ANISTAR_OK;
        st->rf[i].queued |= (uint8_t)(1u << J->rule);
    } else {
        as_ftab_entry *te = as_starset_lookup(ss, J->e.key);
        if (!te || te->queued || te->incpos < 0) return ANISTAR_OK;
        te->queued = 1;
    }
    return as_queue_push(R->ctx, &R->q[J->rule], J->e);
}

/* A new epoch of the per-site marks R->resv (sized to the sites). */
static anistar_status resv_epoch(refiner *R, uint32_t *ep) {
    const as_starset *ss = R->ss;
    if ((size_t)ss->n > R->cap_resv) {
        size_t old = R->cap_resv;
        if (as_grow(R->ctx, (void **)&R->resv, &R->cap_resv, (size_t)ss->n, sizeof *R->resv))
            return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
        memset(R->resv + old, 0, (R->cap_resv - old) * sizeof *R->resv);
    }
    if (++R->bepoch == 0) {
        memset(R->resv, 0, R->cap_resv * sizeof *R->resv);
        R->bepoch = 1;
    }
    *ep = R->bepoch;
    return ANISTAR_OK;
}

/* Take up to prm->batch valid entries of queue k (take_entry, as next_job). */
static anistar_status batch_take(refiner *R, int k) {
    const int32_t B = R->prm->batch;
    if ((size_t)B > R->cap_jobs) {
        size_t old = R->cap_jobs;
        if (as_grow(R->ctx, (void **)&R->jobs, &R->cap_jobs, (size_t)B, sizeof *R->jobs))
            return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
        memset(R->jobs + old, 0, (R->cap_jobs - old) * sizeof *R->jobs);
    }
    R->njobs = 0;
    uint32_t ep;
    anistar_status s;
    if ((s = resv_epoch(R, &ep)) != ANISTAR_OK) return s;
    size_t ndef = 0;
    as_qentry e;
    while (R->njobs < B && as_queue_pop(&R->q[k], &e)) {
        as_bjob *J = &R->jobs[R->njobs];
        if (!take_entry(R, k, &e, &J->v, &J->f)) continue;
        J->e = e;
        J->rule = k;
        /* design: a facet that shares its star or a vertex with a facet taken before in
         * this batch would lose its reservation (its point falls in the stars of its
         * vertices, and so does the other's): it is set aside before its point is
         * computed, and comes out first next time. On the paper's torus 88% of the
         * losers were such jobs. At most 4 B are set aside per batch. */
        int near = R->resv[J->v] == ep;
        for (int q = 0; q < 3 && !near; q++) near = R->resv[J->f.g[q]] == ep;
        if (near && ndef < 4 * (size_t)B) {
            if (ndef == R->cap_defer &&
                as_grow(R->ctx, (void **)&R->defer, &R->cap_defer, ndef + 1, sizeof *R->defer))
                return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
            R->defer[ndef++] = *J;
            R->cnt.batch_set_aside++;
            continue;
        }
        R->resv[J->v] = ep;
        for (int q = 0; q < 3; q++) R->resv[J->f.g[q]] = ep;
        J->why = AS_CAUSE_SIZE;
        J->live = 1;
        J->tries = J->failures = 0;
        R->njobs++;
    }
    for (size_t i = 0; i < ndef; i++)
        if ((s = batch_putback(R, &R->defer[i])) != ANISTAR_OK) return s;
    return ANISTAR_OK;
}

/* Rules 1-2 without the feature-size part, for job k (threads: reads only). */
static anistar_status bviol_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)t;
    refiner *R = arg;
    as_bjob *J = &R->jobs[k];
    anistar_status err = ANISTAR_OK;
    if (J->rule == JOB_RULE1)
        J->viol = rule1_local(R->ss, tctx, R->prm, &J->f, &J->why, &err, &R->gc, NULL);
    else
        J->viol = as_rule2_violation(R->ss, R->prm, J->v, &J->f);
    return err;
}

/* Job k's point (its surface center, or Pick_valid's), its frame and its conflicting
 * stars, on thread slot t (-1: the caller's); reads only. */
static anistar_status bpoint_on(refiner *R, int32_t k, int t, anistar_context *tctx) {
    as_starset *ss = R->ss;
    as_bjob *J = &R->jobs[k];
    if (!J->live) return ANISTAR_OK;
    anistar_status s;
    if (J->rule == JOB_RULE1) {
        memcpy(J->b.p, J->f.c, sizeof J->b.p);
    } else {
        const as_metric_frame mfv = ss->mf[J->v];
        if ((s = pick_valid_on(R, t, tctx, &J->f, &mfv, &J->rng, J->b.p, &J->tries,
                               &J->failures)) != ANISTAR_OK)
            return s;
    }
    if ((s = as_starset_metric_in(ss, tctx, J->b.p, &J->b.mf)) != ANISTAR_OK) return s;
    if ((s = as_starset_conflicts_on(ss, t, tctx, J->b.p, &J->b)) != ANISTAR_OK) return s;
    /* the feature size the drain after the batch will ask for (a per-site cache) */
    return as_starset_lfs_point(ss, t, tctx, &J->b);
}

static anistar_status bpoint_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    return bpoint_on(arg, k, t, tctx);
}

/*
 * One batch of refinement points (issue 15, docs/algorithm.md §11): the jobs batch_take
 * took from queue k (the first of rules 1, 2, 3 that has one). design: deterministic
 * reservations (Blelloch, Fineman, Gibbons, Shun, PPoPP 2012), with the jobs' queue order
 * as their priority:
 *  1. in parallel, each job's violation (rules 1-2, without the feature-size part, which
 *     fills a cache: then in order), its point (the facet's surface center for rule 1,
 *     Pick_valid with the job's own random state for rules 2-3), the point's frame and the
 *     stars it conflicts with, all on the star set as it is;
 *  2. in order, each job reserves its star and its conflicting stars; a job that finds
 *     one reserved by an earlier job goes back to its queue (it comes out first next time);
 *  3. the winners' points are inserted at once (as_starset_insert_batch: their stars are
 *     disjoint, so each star update and each new star is a task of its own), then the
 *     events are drained.
 * Nothing here depends on the thread count: the batch, the jobs' random states (from the
 * run's state and the job's place) and the order of every serial step are fixed, and each
 * task reads the star set as it was before the batch. The points differ from those of one
 * job at a time only in what the batch's earlier winners would have changed.
 */
static anistar_status batch_run(refiner *R, int k, int64_t maxv) {
    as_starset *ss = R->ss;
    anistar_status s;
    const int32_t nj = R->njobs;
    R->cnt.batches++;
    R->cnt.batch_jobs += (uint64_t)nj;
    if (ss->pool && (s = as_starset_simulate_prepare(ss)) != ANISTAR_OK) return s;
    /* 1. violations (rules 1-2) */
    if (k < 2) {
        if (ss->pool && nj >= 2) {
            if ((s = as_pool_run(ss->pool, nj, bviol_task, R)) != ANISTAR_OK) return s;
        } else {
            for (int32_t j = 0; j < nj; j++)
                if ((s = bviol_task(R, j, 0, R->ctx)) != ANISTAR_OK) return s;
        }
        for (int32_t j = 0; j < nj; j++) {
            as_bjob *J = &R->jobs[j];
            if (k == 0) {
                s = ANISTAR_OK;
                J->viol = rule1_feature(ss, J->v, &J->f, J->viol, &J->why, &s);
                if (s != ANISTAR_OK) return s;
            }
            J->live = J->viol > 0;
        }
    }
    /* points, frames, conflicting stars */
    uint64_t base = rng_next_at(&R->rng);
    for (int32_t j = 0; j < nj; j++) R->jobs[j].rng = rng_seed(base + (uint64_t)j);
    if (ss->pool && nj >= 2) {
        s = as_pool_run(ss->pool, nj, bpoint_task, R);
        as_starset_collect_counts(ss);
        if (s != ANISTAR_OK) return s;
    } else {
        for (int32_t j = 0; j < nj; j++)
            if ((s = bpoint_on(R, j, -1, R->ctx)) != ANISTAR_OK) return s;
    }
    /* 2. reservations, in the jobs' order */
    uint32_t ep;
    if ((s = resv_epoch(R, &ep)) != ANISTAR_OK) return s;
    if ((size_t)nj > R->cap_win &&
        as_grow(R->ctx, (void **)&R->win, &R->cap_win, (size_t)nj, sizeof *R->win))
        return as_fail(R->ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
    int32_t nw = 0;
    int64_t room = maxv - (int64_t)(ss->n - ss->first_site);
    for (int32_t j = 0; j < nj; j++) {
        as_bjob *J = &R->jobs[j];
        if (!J->live) continue;
        R->cnt.pick_tries += J->tries;
        R->cnt.pick_failures += J->failures;
        int free_ = R->resv[J->v] != ep && nw < room;
        for (size_t i = 0; i < J->b.nl && free_; i++) free_ = R->resv[J->b.list[i]] != ep;
        if (!free_) {
            R->cnt.batch_lost++;
            if ((s = batch_putback(R, J)) != ANISTAR_OK) return s;
            J->live = 0;
            continue;
        }
        R->resv[J->v] = ep;
        for (size_t i = 0; i < J->b.nl; i++) R->resv[J->b.list[i]] = ep;
        if ((s = as_refine_check_point(ss, J->b.p, J->v, J->f.g, J->f.r)) != ANISTAR_OK)
            return s;
        if (J->rule == JOB_RULE3) stall_update(R, 1); /* the residue this insertion faces */
        R->win[nw++] = J->b;
    }
    /* 3. the winners at once */
    if ((s = as_starset_insert_batch(ss, R->win, nw)) != ANISTAR_OK) return s;
    for (int32_t j = 0; j < nj; j++) {
        const as_bjob *J = &R->jobs[j];
        if (!J->live) continue;
        R->cnt.rule[J->rule]++;
        if (J->rule == JOB_RULE1) R->cnt.cause[J->why]++;
    }
    stall_update(R, 0);
    return drain(R);
}

/* Queue for rule 1 every restricted facet of star v that violates it now and is not
 * queued (after its alpha changed); *pushed (if not NULL) counts them. */
static anistar_status requeue_rule1(refiner *R, int32_t v, size_t *pushed) {
    as_star *st = R->ss->stars[v];
    anistar_status s = ANISTAR_OK;
    for (int32_t i = 0; st && i < st->nrf; i++) {
        as_rfacet *f = &st->rf[i];
        if (f->queued & 1) continue;
        double v1 = rule1_cached(R, v, f, NULL, &s);
        if (s != ANISTAR_OK) return s;
        if (v1 <= 0) continue;
        as_qentry q = {v1, as_facet_key(f->g), v};
        if ((s = as_queue_push(R->ctx, &R->q[0], q)) != ANISTAR_OK) return s;
        f->queued |= 1;
        if (pushed) (*pushed)++;
    }
    return ANISTAR_OK;
}

/* Queue for rules 1 and 2 every restricted facet of star v that violates them now and is
 * not queued (the partition simulation: jobs it set aside before its halo came; the sweep
 * below); *pushed (if not NULL) counts them. */
static anistar_status requeue_star(refiner *R, int32_t v, size_t *pushed) {
    as_starset *ss = R->ss;
    anistar_status s = requeue_rule1(R, v, pushed);
    as_star *st = ss->stars[v];
    for (int32_t i = 0; s == ANISTAR_OK && st && i < st->nrf; i++) {
        as_rfacet *f = &st->rf[i];
        if (f->queued & 2) continue;
        double v2 = as_rule2_violation(ss, R->prm, v, f);
        if (v2 <= 0) continue;
        as_qentry q = {v2, as_facet_key(f->g), v};
        if ((s = as_queue_push(R->ctx, &R->q[1], q)) != ANISTAR_OK) return s;
        f->queued |= 2;
        if (pushed) (*pushed)++;
    }
    return s;
}

/*
 * Before the final checks: every restricted facet of every star is judged by rules 1 and
 * 2 once more, and a violation that no queue holds is queued (*pushed counts them).
 * design: the queues are fed by the star set's events, and a facet that changes without
 * an event, or loses its queue flag, would otherwise reach the output unrefined while the
 * run reports it certified (a facet 1.2% above r0 on knot1, before the flags of restar's
 * survivors were kept); the final checks do not re-judge the rules, so this pass is what
 * makes "no rule applies" true of the stars themselves. Serial, in site order: one pass
 * over the facets per time the queues run dry (rule 1's pairs are in the cache).
 */
static anistar_status sweep_rules(refiner *R, size_t *pushed) {
    anistar_status s = ANISTAR_OK;
    *pushed = 0;
    for (int32_t v = R->ss->first_site; v < R->ss->n && s == ANISTAR_OK; v++)
        s = requeue_star(R, v, pushed);
    return s;
}

/*
 * Halve the alpha of the sites inside the balls where the final checks failed
 * (ss->trouble), down to AS_FEATURE_ALPHA_MIN, and queue their stars' facets that now
 * violate rule 1; *halved = the sites changed (0: nothing left to refine there).
 */
static anistar_status halve_alpha(refiner *R, size_t *halved) {
    as_starset *ss = R->ss;
    anistar_status s;
    *halved = 0;
    uint32_t ep = as_starset_next_epoch(ss);
    for (size_t k = 0; k < ss->ntrouble; k++) {
        const double *T = ss->trouble + 4 * k;
        double lo[3], hi[3];
        for (int j = 0; j < 3; j++) {
            lo[j] = T[j] - T[3];
            hi[j] = T[j] + T[3];
        }
        if ((s = as_kdtree_box_any(R->ctx, ss->kd, lo, hi, 0, &ss->ws.ids)) != ANISTAR_OK) return s;
        for (size_t i = 0; i < ss->ws.ids.n; i++) {
            int32_t v = ss->ws.ids.ids[i];
            if (v < ss->first_site || ss->ws.stamp[v] == ep) continue;
            const double *x = ss->xyz + 3 * (size_t)v;
            double d2 = 0;
            for (int j = 0; j < 3; j++) d2 += (x[j] - T[j]) * (x[j] - T[j]);
            if (!(d2 <= T[3] * T[3])) continue;
            ss->ws.stamp[v] = ep;
            if (0.5 * ss->alpha * ss->ascale[v] < AS_FEATURE_ALPHA_MIN) continue;
            ss->ascale[v] *= 0.5;
            (*halved)++;
        }
    }
    /* the stars whose alpha changed, in id order (deterministic) */
    for (int32_t v = ss->first_site; v < ss->n && *halved; v++)
        if (ss->ws.stamp[v] == ep && (s = requeue_rule1(R, v, NULL)) != ANISTAR_OK) return s;
    return ANISTAR_OK;
}

/* Re-queue every inconsistent facet (the exact set) whose entry was dropped. */
static anistar_status requeue_inconsistent(refiner *R, int *pushed) {
    as_starset *ss = R->ss;
    *pushed = 0;
    for (size_t k = 0; k < ss->ninc; k++) {
        as_ftab_entry *te = as_starset_lookup(ss, ss->inc[k]);
        if (te->queued) continue;
        as_qentry q = {0, te->key, 0};
        anistar_status s = as_queue_push(R->ctx, &R->q[2], q);
        if (s != ANISTAR_OK) return s;
        te->queued = 1;
        (*pushed)++;
    }
    return ANISTAR_OK;
}

/* Publish the state of the run (anistar_mesher_get_progress). */
static void publish(refiner *R, double now) {
    as_run_ctl *ctl = R->ctl;
    const as_starset *ss = R->ss;
    anistar_progress *p = &ctl->state;
    p->vertices = (size_t)(ss->n - ss->first_site);
    p->inconsistent = ss->ninc;
    p->seconds = now - R->t0;
    p->estimate_vertices = R->cnt.estimate_vertices;
    p->estimate_bytes = R->cnt.estimate_bytes;
    p->stalled = R->n3 - R->low_at;
    p->max_stall = stall_budget(R);
    /* design: the rate of the refinement so far, over the vertices still expected */
    double refine_s = now - R->t0 - R->cnt.t_init, left = p->estimate_vertices - (double)p->vertices;
    p->eta_seconds = -1;
    if (p->vertices > R->cnt.initial && refine_s > 0 && left > 0)
        p->eta_seconds = left * refine_s / (double)(p->vertices - R->cnt.initial);
    else if (left <= 0 && p->estimate_vertices > 0)
        p->eta_seconds = 0;
}

/* Publish the state and call the progress callback; 1 when it asks to cancel. */
static int report(refiner *R, double now) {
    as_run_ctl *ctl = R->ctl;
    if (!ctl) return 0;
    publish(R, now);
    if (!ctl->progress) return 0;
    const anistar_progress *p = &ctl->state;
    return ctl->progress(p->vertices, p->inconsistent, p->seconds, ctl->user) != 0;
}

/* Why the loop stopped before the end, as an INCOMPLETE message in ctx. */
static void stop_message(refiner *R) {
    as_starset *ss = R->ss;
    long long v = (long long)(ss->n - ss->first_site);
    const char *final = R->in_final ? "; during the final checks, before they ended" : "";
    switch (R->cnt.stop_reason) {
    case ANISTAR_STOP_MAX_VERTICES:
        if (R->hard_limit) {
            as_fail(R->ctx, ANISTAR_INCOMPLETE,
                    "mesher: stopped at the hard limit of %lld vertices (global ids: "
                    "docs/algorithm.md, memory; %zu inconsistent facets left; the up-front "
                    "estimate was %.0f)",
                    v, ss->ninc, R->cnt.estimate_vertices);
            break;
        }
        as_fail(R->ctx, ANISTAR_INCOMPLETE,
                "mesher: stopped at max_vertices (%lld vertices; %zu inconsistent facets left; "
                "the up-front estimate was %.0f)",
                v, ss->ninc, R->cnt.estimate_vertices);
        break;
    case ANISTAR_STOP_MAX_SECONDS:
        as_fail(R->ctx, ANISTAR_INCOMPLETE,
                "mesher: stopped at max_seconds %g (%lld vertices; %zu inconsistent facets left%s)",
                R->prm->max_seconds, v, ss->ninc, final);
        break;
    case ANISTAR_STOP_STALL:
        if (R->inc_low == SIZE_MAX)
            as_fail(R->ctx, ANISTAR_INCOMPLETE,
                    "mesher: stalled: %zu inconsistent facets keep coming back to the "
                    "consistency rule without being killed (%lld vertices)",
                    ss->ninc, v);
        else
            as_fail(R->ctx, ANISTAR_INCOMPLETE,
                    "mesher: stalled: %llu consistency insertions (rule 3) since the count of "
                    "inconsistent facets they faced was last at a new low (%zu; now %zu, %lld "
                    "vertices): the metric field or the parameters leave inconsistencies that "
                    "refinement does not resolve (try a larger r0, a smaller gamma0, or a "
                    "smoother metric)",
                    (unsigned long long)(R->n3 - R->low_at), R->inc_low, ss->ninc, v);
        break;
    case ANISTAR_STOP_REQUESTED:
        as_fail(R->ctx, ANISTAR_INCOMPLETE,
                "mesher: stopped on request (%lld vertices; %zu inconsistent facets left%s)", v,
                ss->ninc, final);
        break;
    default:
        break;
    }
}

/* 1 when R->halt is due (max_seconds past or the stop flag set): the reason into R->cnt,
 * in_final: whether the final checks were running. */
static int halted(refiner *R, int in_final) {
    if (!as_halt_due(&R->halt)) return 0;
    R->cnt.stop_reason = atomic_load(&R->halt.halted) == AS_HALT_TIME ? ANISTAR_STOP_MAX_SECONDS
                                                                      : ANISTAR_STOP_REQUESTED;
    R->in_final = in_final;
    return 1;
}

/* The limits checked before each job (or batch): 1 when the run stops (the reason in
 * R->cnt, *s set on cancellation). */
static int run_limits(refiner *R, int64_t maxv, uint64_t *steps, double *last_report,
                      anistar_status *s) {
    const as_starset *ss = R->ss;
    if ((int64_t)(ss->n - ss->first_site) >= maxv) {
        R->cnt.stop_reason = ANISTAR_STOP_MAX_VERTICES;
        return 1;
    }
    if (halted(R, 0)) return 1;
    double now = as_now_seconds();
    if (R->n3 - R->low_at >= stall_budget(R)) {
        R->cnt.stop_reason = ANISTAR_STOP_STALL;
        return 1;
    }
    if ((*steps & 255) == 0 || now - *last_report >= 0.25) {
        *last_report = now;
        if (report(R, now)) {
            *s = as_fail(R->ctx, ANISTAR_ECANCELED, "mesher: canceled by the progress callback");
            return 1;
        }
    }
    (*steps)++;
    return 0;
}

/* The refusal's advice when the distortion radius asks for a share bygamma of the
 * estimated vertices: above half, the metric varies faster than its own sizes, and where
 * it jumps (surfaces joined with continuous tangents only, a solver's field) no r0 helps,
 * a gradation does: named as the user sets it (a SPEC option, the API call for a
 * callback), or gamma0 and a smaller G when the field is graded already. */
static const char *refusal_hint(const as_field *fl, double bygamma) {
    if (bygamma <= 0.5) return "";
    if (fl->grad > 0)
        return "; most of them for gamma0: the graded metric still varies faster than its own "
               "sizes (raise gamma0, or lower grad)";
    if (fl->kind == AS_FIELD_CUSTOM)
        return "; most of them for gamma0: the metric varies faster than its own sizes (where "
               "it jumps, grade it: anistar_metric_set_gradation, e.g. G = 1.3, or raise "
               "gamma0)";
    return "; most of them for gamma0: the metric varies faster than its own sizes (where it "
           "jumps, grade it: grad=G in the metric spec, e.g. curvature,grad=1.3, or raise "
           "gamma0)";
}

anistar_status as_mesher_run_keep(anistar_context *ctx, const as_surface *surf,
                                  const as_field *field, const as_mesher_params *prm,
                                  as_run_ctl *ctl, anistar_mesh **out, as_starset **ss_out) {
    *out = NULL;
    if (ss_out) *ss_out = NULL;
    double t0 = as_now_seconds();
    size_t bytes0 = ctx->bytes;
    ctx->peak = ctx->bytes;
    refiner R;
    memset(&R, 0, sizeof R);
    R.ctx = ctx;
    R.prm = prm;
    R.ctl = ctl;
    R.t0 = t0;
    R.inc_low = SIZE_MAX;
    R.cnt.stop_reason = ANISTAR_STOP_DONE;
    if (ctl) {
        memset(&ctl->state, 0, sizeof ctl->state);
        ctl->state.eta_seconds = -1;
    }
    R.rng = rng_seed(prm->seed);
    as_starset *ss = as_alloc(ctx, sizeof *ss);
    if (!ss) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
    R.ss = ss;
    anistar_status s =
        as_starset_init_threads(ss, ctx, surf, field, prm->threads > 0 ? prm->threads : 1);
    if (prm->max_ids > 0) ss->max_ids = prm->max_ids;
    /* the hard limit: global ids are as_gid, counts and indexes int32 (starset.h) */
    const int64_t hardv = (int64_t)ss->max_ids - AS_MESHER_ID_RESERVE;
    int64_t maxv = prm->max_vertices > 0 && prm->max_vertices < hardv ? prm->max_vertices : hardv;
    R.hard_limit = maxv == hardv;
    if (prm->alpha0 > 0) ss->alpha = prm->alpha0;
    /* design: the automatic hmin is the surface's own resolution, the floor of the local
     * feature size: what keeps distortion refinement finite where a metric from data
     * jumps (the curvature of a triangle mesh across a crease) */
    if (s == ANISTAR_OK) {
        /* design: the automatic hmin is the resolution of what the metric is made from.
         * A field fitted to a triangle mesh's vertices (curvature from jets over 16
         * neighbours, about two edges around; a .sol) sees nothing below about half the
         * mean edge but the creases and the noise: hmin is half the mean edge there.
         * With an eighth, the curvature metric asked for up to 64 times the input's
         * density: the elephant's estimate was 101,912 vertices and the fandisk's 72,301,
         * neither converging in 60 s; with half, both are certified (7,162 and 15,104 V).
         * Any other field (euclidean, shock, an expression's gradient or Hessian) is the
         * user's own sizes: hmin is the floor of the feature size (an eighth of a mesh's
         * mean edge, about a voxel, 1e-4 R), which also stays the floor of the feature
         * rule and of the final checks: thin parts are still resolved */
        ss->hmin = prm->hmin > 0          ? prm->hmin
                   : ss->field->hdata > 0 ? ss->field->hdata
                   : ss->field->blend     ? 4 * ss->feat.floor_e
                                          : ss->feat.floor_e;
        ss->hmax = prm->hmax > 0 ? prm->hmax : 0;
        /* design: and they bound the metric itself (as_starset_metric), as MMG's hmin and
         * hmax do: a field from data asks for sizes below the surface's resolution (the
         * jets of a CAD mesh at its creases, of a scan at its noise) and there its
         * neighbouring tensors differ by far more than gamma0, which no refinement
         * above hmin reconciles. Clamped, the lever and the hinge are certified with
         * the defaults (they were not: stars at the creases stayed open) */
        ss->ecap_hi = ss->hmin > 0 ? prm->r0 / ss->hmin : 0;
        ss->ecap_lo = ss->hmax > 0 ? prm->r0 / ss->hmax : 0;
        /* design: the anisotropy that pays (as_starset_metric): the floor of the small
         * eigenvalues where the metric's frame turns, from r0 and gamma0. Not on triangle
         * meshes: their normals are piecewise (a jet interpolation with the angle-weighted
         * normal at creases), so the turn rates taken by differences jump, and so did the
         * floor: on the elephant (curvature,power=0.25, r0 2, gamma0 2) neighbours an hmin
         * apart had eigenvalues 1.45 and 4.04 along the same direction, 157 facets held by
         * hmin, and a gamma of 2.9 between vertices of the certified mesh. Not on images
         * either: their normals are a B-spline's through sampled values, smooth but
         * turning with the noise at the voxel scale, so the rates (by differences) are
         * the noise's and the floors differ from site to site: on the skull CT
         * (curvature, r0 3) neighbours 2-4 units apart with raw tangent eigenvalues within
         * 6% were floored to (0.17, 0.21) and (0.09, 0.22), gamma 2-3 between them below
         * hmin where the distortion rule does not reach, and rule 3 inserted without end
         * (a stall after 53,000 V, estimate 6,060), with the rates taken at hmin's scale
         * too; without the floor the skull is certified in 2,991 V, and at r0 0.1 and 1
         * the three images of test/data give the same vertex counts with it or without */
        if (prm->aniso_cap && !as_surface_is_mesh(surf) && !as_surface_is_image(surf)) {
            ss->rot_r0 = prm->r0;
            ss->rot_g = prm->gamma0 - 1 / prm->gamma0;
        }
    }
    int complete = 0;
    anistar_mesh *done = NULL; /* the output built when no rule applied */
    int fixes = 0;             /* passes that inserted the points the final checks found */
    double t_check = 0;        /* the last pass of the final checks */
    /* design: the up-front estimate refuses at once a run that cannot fit (DESIGN.md 4.5) */
    double bygamma = 0;
    if (s == ANISTAR_OK)
        s = as_mesher_estimate(ss, prm, &R.cnt.estimate_vertices, &R.cnt.estimate_bytes,
                               &bygamma);
    if (s == ANISTAR_OK && R.cnt.estimate_vertices > (double)maxv)
        s = as_fail(ctx, ANISTAR_EINVAL,
                    "mesher: refused: the metric and r0 ask for about %.3g vertices (%.3g GB), "
                    "more than max_vertices %lld; raise r0 or max_vertices%s",
                    R.cnt.estimate_vertices, R.cnt.estimate_bytes * 1e-9, (long long)maxv,
                    refusal_hint(ss->field, bygamma));
    if (s == ANISTAR_OK) s = initial_points(&R);
    for (size_t k = 0; s == ANISTAR_OK && k < prm->nseeds; k++) {
        const double *p = prm->seeds + 3 * k;
        if (is_duplicate(ss, p)) continue;
        if ((int64_t)(ss->n - ss->first_site) >= maxv) break; /* the loop says why */
        s = insert_point(&R, p);
    }
    as_sampler_free(ctx, ss->sampler); /* the analysis stays with the surface */
    ss->sampler = NULL;
    double t1 = as_now_seconds();
    R.cnt.t_init = t1 - t0;
    /* design: the final checks test the run's limits between stars too (the zone check of
     * a 100,000-vertex run takes tens of seconds): max_seconds and stop requests hold to
     * the end, not only between refinement steps */
    R.halt.deadline = prm->max_seconds > 0 ? t1 + prm->max_seconds : 0;
    R.halt.stop = ctl ? &ctl->stop : NULL;
    atomic_init(&R.halt.halted, AS_HALT_NONE);
    double last_report = t1;
    uint64_t steps = 0;
    int requeues = 0;
    while (s == ANISTAR_OK) {
        if (ctl && atomic_load(&ctl->stop)) {
            R.cnt.stop_reason = ANISTAR_STOP_REQUESTED;
            break;
        }
        /* the open stars that closed since they were queued are dropped (as next_job
         * does), so that a topology job is left only when one is due */
        drop_closed_open(ss);
        if (prm->batch > 1 && !prm->part && ss->nopen == 0) {
            /* batches (batch_step) for the rules' jobs; topology jobs and the rest one at
             * a time below */
            int ran = 0, stop = 0;
            for (int k = 0; k < 3 && !ran && !stop && s == ANISTAR_OK; k++) {
                if (R.q[k].n == 0 || (s = batch_take(&R, k)) != ANISTAR_OK || R.njobs == 0)
                    continue; /* only stale entries: the next queue */
                if (run_limits(&R, maxv, &steps, &last_report, &s)) stop = 1;
                else if ((s = batch_run(&R, k, maxv)) == ANISTAR_OK) ran = 1;
            }
            if (s != ANISTAR_OK || stop) break;
            if (ran) continue;
        }
        int rule = JOB_NONE, cause = AS_CAUSE_SIZE;
        int32_t v = -1;
        as_rfacet f;
        if ((s = next_job(&R, &rule, &v, &f, &cause)) != ANISTAR_OK) break;
        if (rule == JOB_NONE && prm->part) {
            /* a part of the partition simulation: its round ends here, not the run */
            const double *pts = NULL;
            const int32_t *again = NULL;
            size_t npts = 0, nagain = 0;
            int more = 0;
            if ((s = prm->part->round_end(prm->part->user, ss, &pts, &npts, &again, &nagain,
                                          &more)) != ANISTAR_OK)
                break;
            for (size_t k = 0; k < npts && s == ANISTAR_OK; k++)
                if (!is_duplicate(ss, pts + 3 * k)) s = insert_point(&R, pts + 3 * k);
            for (size_t k = 0; k < nagain && s == ANISTAR_OK; k++)
                s = requeue_star(&R, again[k], NULL);
            int pushed;
            if (s == ANISTAR_OK && nagain) s = requeue_inconsistent(&R, &pushed);
            if (s != ANISTAR_OK || !more) break;
            continue;
        }
        if (rule == JOB_NONE) {
            int pushed = 0;
            if (ss->ninc == 0) {
                /* design: no rule applies. First the stars of pieces meshed wholly below
                 * hmin are checked against every site that could change them
                 * (as_starset_verify_zones, on_held_piece); a star found wrong takes its
                 * whole Delaunay region as its zone and the refinement goes on. */
                size_t opened = 0, swept = 0;
                if (halted(&R, 1)) break;
                if ((s = sweep_rules(&R, &swept)) != ANISTAR_OK) break;
                if (swept) {
                    R.cnt.swept += swept;
                    continue;
                }
                if ((s = pieces_update(&R)) != ANISTAR_OK ||
                    (s = as_starset_verify_zones(ss, on_held_piece, &R, &R.halt, &opened)) !=
                        ANISTAR_OK ||
                    halted(&R, 1))
                    break;
                if (opened) {
                    R.cnt.zones_opened += opened;
                    continue;
                }
                /* design: no rule applies: the final checks decide. A wrong topology
                 * (components, Euler characteristic, orientation) means the feature
                 * size was overestimated: halve alpha and refine on (paper 2.3: any
                 * sizing field below sf works); below AS_FEATURE_ALPHA_MIN, stop. */
                int ok = 0, refinable = 0;
                uint64_t sig = 0;
                double tc = as_now_seconds();
                /* design: the approximation error (4 projections per facet, a tenth of
                 * the brain's run) only for the output kept (as_mesher_output_errors) */
                s = as_mesher_output(ss, prm, &R.cnt, 1, 0, &done);
                if (s == ANISTAR_OK) s = as_mesher_certify(ss, done, &ok, &refinable, &sig);
                t_check = as_now_seconds() - tc;
                if (s != ANISTAR_OK) break;
                if (ok) {
                    complete = 1;
                    break;
                }
                if (refinable && sig == AS_CERT_FIDELITY && fixes < AS_FIX_PASSES) {
                    /* design: an edge that bridges or cuts through S is refined where it
                     * misses S (Boissonnat-Oudot: insert where the restricted Delaunay
                     * triangulation is wrong), not by a smaller size everywhere */
                    as_mesh_free(done);
                    done = NULL;
                    fixes++;
                    size_t added = 0;
                    for (size_t k = 0; k < ss->nfix && s == ANISTAR_OK; k++) {
                        const double *F = ss->fix + 4 * k;
                        if (is_duplicate(ss, F)) continue;
                        int32_t near = -1;
                        double d = nearest_site(ss, F, &near);
                        if (!(d > AS_NEAR_SITE * F[3])) continue; /* found twice in a pass */
                        if ((s = insert_point(&R, F)) != ANISTAR_OK) break;
                        R.cnt.topology++;
                        added++;
                    }
                    if (s != ANISTAR_OK) break;
                    if (added) continue;
                }
                if (refinable) {
                    /* design: halve alpha where the checks failed (the balls they left
                     * in ss->trouble), not everywhere: the cost of a thin part stays at
                     * the thin part */
                    size_t halved = 0;
                    if ((s = halve_alpha(&R, &halved)) != ANISTAR_OK) break;
                    if (halved) {
                        as_mesh_free(done);
                        done = NULL;
                        R.cnt.halvings++;
                        continue;
                    }
                }
                R.cnt.stop_reason = ANISTAR_STOP_UNCERTIFIED;
                break;
            }
            /* design: inconsistent facets whose queue entry was consumed without killing
             * them (their stars did not re-emit them) are queued again from the exact set;
             * a bounded number of rounds without progress ends the run as a stall. */
            if ((s = requeue_inconsistent(&R, &pushed)) != ANISTAR_OK) break;
            if (pushed == 0 || ++requeues > 64) {
                R.cnt.stop_reason = ANISTAR_STOP_STALL;
                break;
            }
            continue;
        }
        if (run_limits(&R, maxv, &steps, &last_report, &s)) break;
        double p[3];
        if (rule == JOB_TOPOLOGY) {
            double d;
            int found;
            if ((s = topology_point(&R, v, p, &d, &found)) != ANISTAR_OK) break;
            if (!found) continue; /* certification names the star if it stays open */
            if (prm->part && !prm->part->accept(prm->part->user, ss, rule, v, NULL, p, 1))
                continue;
            /* design: on a triangle mesh and on an implicit function the topology rule
             * stops at the surface's resolution too (hmin, as the other rules): a point
             * nearer than hmin to a site is not inserted, and certification judges the
             * star. A polyhedron is not smooth (lfs is 0 at every edge with a dihedral
             * angle: the creases and corners of a CAD mesh, the facets of a scan refined
             * below its own edges), and there the restricted Delaunay triangulation need
             * not become a disk at any sampling: the farthest crossing of a star's cell
             * lies nearer and nearer the crease, and the rule spiralled into it (the
             * lever, the hinge and the elephant with the default curvature reached 1e-15
             * and the 1e-9 trap). An implicit function need not be smooth either: the
             * max, min or abs of smooth ones (a gyroid clipped by a ball, the usual CAD
             * construction) has creases where lfs is 0, and the rule spiralled into the
             * gyroid's crease with the sphere the same way (nine sites within 1e-15 of one
             * point, then the trap: `--metric curvature,grad=1.3`, session 21). An image is
             * a cubic B-spline, C2: the rule terminates there (its points are a fraction
             * of lfs > 0 from the sites), and the brain at r0 6 needs it below its hmin
             * (two voxels) to be certified */
            if (!as_surface_is_image(ss->surf)) {
                int32_t near;
                double dn = nearest_site(ss, p, &near);
                if (ss->hmin > 0 && dn < ss->hmin) {
                    R.cnt.topo_below_hmin++;
                    continue;
                }
            }
            if ((s = as_refine_check_point(ss, p, v, NULL, d)) != ANISTAR_OK) break;
            if ((s = insert_point(&R, p)) != ANISTAR_OK) break;
            R.cnt.topology++;
            continue;
        }
        if (prm->part && rule != JOB_RULE1 &&
            !prm->part->accept(prm->part->user, ss, rule, v, &f, f.c, 0))
            continue;
        if (rule == JOB_RULE1) {
            memcpy(p, f.c, sizeof p);
        } else {
            if ((s = pick_valid(&R, v, &f, p)) != ANISTAR_OK) break;
        }
        if (prm->part && !prm->part->accept(prm->part->user, ss, rule, v, &f, p, 1)) continue;
        if ((s = as_refine_check_point(ss, p, v, f.g, f.r)) != ANISTAR_OK) break;
        if (rule == JOB_RULE3) stall_update(&R, 1); /* the residue this insertion faces */
        if ((s = insert_point(&R, p)) != ANISTAR_OK) break;
        R.cnt.rule[rule]++;
        if (rule == JOB_RULE1) R.cnt.cause[cause]++;
    }
    double t2 = as_now_seconds();
    R.cnt.t_refine = t2 - t1;
    for (int k = 0; k < 3; k++) as_queue_free(ctx, &R.q[k]);
    gcache_free(ctx, &R.gc);
    as_free(ctx, R.evpre, R.cap_evpre * sizeof *R.evpre);
    as_free(ctx, R.pcand, R.cap_pcand * sizeof *R.pcand);
    for (size_t j = 0; j < R.cap_jobs; j++) as_bpoint_free(ctx, &R.jobs[j].b);
    as_free(ctx, R.jobs, R.cap_jobs * sizeof *R.jobs);
    as_free(ctx, R.win, R.cap_win * sizeof *R.win);
    as_free(ctx, R.resv, R.cap_resv * sizeof *R.resv);
    as_free(ctx, R.defer, R.cap_defer * sizeof *R.defer);
    as_free(ctx, R.piece, R.cap_piece * sizeof *R.piece);
    as_free(ctx, R.piece_refined, R.cap_piece_refined);
    if (s != ANISTAR_OK && done) {
        as_mesh_free(done);
        done = NULL;
    }
    if (s == ANISTAR_OK) {
        R.cnt.t_total = t2 - t0;
        if (!done) stop_message(&R);
        char msg[AS_ERRMSG_SIZE];
        snprintf(msg, sizeof msg, "%s", ctx->last_error);
        if (done) {
            *out = done; /* the checked output (certified, or not: the message says why) */
            done = NULL;
            (*out)->stats.complete = complete;
            s = as_mesher_output_errors(ss, *out);
        } else {
            s = as_mesher_output(ss, prm, &R.cnt, 0, 1, out);
        }
        if (s == ANISTAR_OK && complete && prm->optimize) {
            /* the optimised mesh is a new output: checked again */
            int stopped = 0;
            s = as_mesher_optimize(ss, prm, ctl ? &ctl->stop : NULL, out, &stopped);
            if (s == ANISTAR_OK && stopped) {
                /* the mesh stays certified; the run was asked to stop all the same */
                complete = 0;
                R.cnt.stop_reason = ANISTAR_STOP_REQUESTED;
                (*out)->stats.complete = 0;
                as_fail(ctx, ANISTAR_INCOMPLETE,
                        "mesher: stopped on request during the vertex optimisation (the mesh "
                        "of the refinement is complete; %llu vertices moved so far)",
                        (unsigned long long)(*out)->stats.optimize_moved);
                snprintf(msg, sizeof msg, "%s", ctx->last_error);
            }
            int ok = 0, refinable = 0;
            uint64_t sig = 0;
            if (s == ANISTAR_OK) s = as_mesher_certify(ss, *out, &ok, &refinable, &sig);
            if (s == ANISTAR_OK && !ok) {
                complete = 0;
                R.cnt.stop_reason = ANISTAR_STOP_UNCERTIFIED;
                (*out)->stats.complete = 0;
                snprintf(msg, sizeof msg, "%s", ctx->last_error);
            }
        }
        if (s == ANISTAR_OK) {
            double t3 = as_now_seconds();
            anistar_mesh_stats *S = &(*out)->stats;
            /* the final checks' last pass (output and certification) counts as output,
             * the earlier ones (which led to more refinement) as refinement */
            S->seconds_refine = R.cnt.t_refine - t_check;
            S->seconds_output = t3 - t2 + t_check;
            S->seconds_total = t3 - t0;
            S->stop_reason = R.cnt.stop_reason;
            S->feature_alpha = ss->alpha;
            for (int32_t v = ss->first_site; v < ss->n; v++)
                if (ss->alpha * ss->ascale[v] < S->feature_alpha)
                    S->feature_alpha = ss->alpha * ss->ascale[v];
            S->feature_halvings = R.cnt.halvings;
            S->peak_bytes = ctx->peak - bytes0;
            if (!complete) s = as_fail(ctx, ANISTAR_INCOMPLETE, "%s", msg);
        } else if (*out) {
            as_mesh_free(*out);
            *out = NULL;
        }
    }
    if (ctl) publish(&R, as_now_seconds());
    if (ss_out && (s == ANISTAR_OK || s == ANISTAR_INCOMPLETE)) {
        *ss_out = ss;
    } else {
        as_starset_destroy(ss);
        as_free(ctx, ss, sizeof *ss);
    }
    return s;
}

anistar_status as_mesher_run(anistar_context *ctx, const as_surface *surf, const as_field *field,
                             const as_mesher_params *prm, as_run_ctl *ctl, anistar_mesh **out) {
    return as_mesher_run_keep(ctx, surf, field, prm, ctl, out, NULL);
}
