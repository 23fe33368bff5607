/*
 * optimize.c — vertex optimisation after refinement (paper 6.2, DESIGN.md 4.9): move each
 * vertex toward the M_v-area-weighted barycenter of the surface centers of its facets
 * while every guarantee holds. See optimize.h.
 */
#include "mesher/optimize.h"

#include <math.h>
#include <string.h>
#include <time.h>

#include "mesher/refine.h"
#include "mesher/starmove.h"

/* One candidate site of a pass. */
typedef struct opt_item {
    double key; /* d_v(v, b_v) */
    int32_t v;
} opt_item;

static int item_before(const opt_item *a, const opt_item *b) {
    if (a->key != b->key) return a->key > b->key;
    return a->v < b->v;
}

/* Sort items by decreasing key, ties by id (heapsort: no recursion, no allocation). */
static void sort_items(opt_item *a, size_t n) {
    /* a max-heap of "after" = min-heap of item_before, popped to the end */
    for (size_t start = n / 2; start-- > 0;) {
        size_t i = start;
        for (;;) {
            size_t l = 2 * i + 1, r = l + 1, m = i;
            if (l < n && item_before(&a[m], &a[l])) m = l;
            if (r < n && item_before(&a[m], &a[r])) m = r;
            if (m == i) break;
            opt_item t = a[i];
            a[i] = a[m];
            a[m] = t;
            i = m;
        }
    }
    for (size_t end = n; end-- > 1;) {
        opt_item t = a[0];
        a[0] = a[end];
        a[end] = t;
        size_t i = 0;
        for (;;) {
            size_t l = 2 * i + 1, r = l + 1, m = i;
            if (l < end && item_before(&a[m], &a[l])) m = l;
            if (r < end && item_before(&a[m], &a[r])) m = r;
            if (m == i) break;
            t = a[i];
            a[i] = a[m];
            a[m] = t;
            i = m;
        }
    }
}

/*
 * The target of site v: b_v projected on S into t, and h. Returns OK with *ok = 0 when v
 * has no usable star (not a closed fan, zero area) or the projection finds no surface.
 */
static anistar_status target(as_starset *ss, int32_t v, double t[3], double *h, int *ok) {
    const as_star *st = ss->stars[v];
    const as_metric_frame *mf = &ss->mf[v];
    *ok = 0;
    if (!st || !st->closed || st->nrf < 3) return ANISTAR_OK;
    double acc[3] = {0, 0, 0}, W = 0, rs = 0;
    for (int32_t i = 0; i < st->nrf; i++) {
        const as_rfacet *f = &st->rf[i];
        double A[3], B[3], C[3], u[3], w[3];
        as_metric_apply(mf, ss->xyz + 3 * (size_t)f->g[0], A);
        as_metric_apply(mf, ss->xyz + 3 * (size_t)f->g[1], B);
        as_metric_apply(mf, ss->xyz + 3 * (size_t)f->g[2], C);
        for (int k = 0; k < 3; k++) {
            u[k] = B[k] - A[k];
            w[k] = C[k] - A[k];
        }
        double x = u[1] * w[2] - u[2] * w[1], y = u[2] * w[0] - u[0] * w[2],
               z = u[0] * w[1] - u[1] * w[0];
        double area = 0.5 * sqrt((x * x + y * y) + z * z); /* the M_v-area */
        for (int k = 0; k < 3; k++) acc[k] += area * f->c[k];
        W += area;
        rs += f->r;
    }
    if (!(W > 0) || !isfinite(W)) return ANISTAR_OK;
    double b[3] = {acc[0] / W, acc[1] / W, acc[2] / W};
    anistar_status s = as_surface_project(ss->ctx, ss->surf, b, t);
    if (s == ANISTAR_ENOSURFACE) return ANISTAR_OK;
    if (s != ANISTAR_OK) return s;
    *h = AS_OPTIMIZE_H * rs / st->nrf;
    *ok = 1;
    return ANISTAR_OK;
}

/* Sum of the squared radius-edge ratios of the facets of star st of site w (metric mf),
 * with site v at position xv. */
static double star_rho2(const as_starset *ss, const as_star *st, const as_metric_frame *mf,
                        int32_t v, const double xv[3]) {
    double sum = 0;
    for (int32_t i = 0; i < st->nrf; i++) {
        const as_gid *g = st->rf[i].g;
        const double *x[3];
        for (int k = 0; k < 3; k++) x[k] = g[k] == v ? xv : ss->xyz + 3 * (size_t)g[k];
        double rho = as_radius_edge(mf, x[0], x[1], x[2], NULL);
        sum += rho * rho;
    }
    return sum;
}

/* Is the pending move mv acceptable (see optimize.h, design 3)? */
static anistar_status acceptable(as_starset *ss, const as_mesher_params *prm,
                                 const as_starmove *mv, int *ok) {
    *ok = 0;
    if (ss->ninc != 0) return ANISTAR_OK;
    double before = 0, after = 0;
    for (size_t k = 0; k < mv->n; k++) {
        int32_t id = mv->ids[k];
        const as_star *st = ss->stars[id];
        if (!st->closed) return ANISTAR_OK;
        for (int32_t i = 0; i < st->nrf; i++) {
            anistar_status s;
            if (as_rule1_violation(ss, prm, id, &st->rf[i], NULL, &s) > 0) return s;
            if (s != ANISTAR_OK) return s;
            if (as_rule2_violation(ss, prm, id, &st->rf[i]) > 0) return ANISTAR_OK;
        }
        const double *xv = ss->xyz + 3 * (size_t)mv->v;
        after += star_rho2(ss, st, &ss->mf[id], mv->v, xv);
        const as_metric_frame *mold = id == mv->v ? &mv->old_mf : &ss->mf[id];
        before += star_rho2(ss, mv->old[k], mold, mv->v, mv->old_x);
    }
    *ok = after < before;
    return ANISTAR_OK;
}

/*
 * The filter in front of a move: with the current facets of v's star (consistent, so also
 * in its neighbours' stars), v at p with metric mfp: 1 if every facet keeps its
 * radius-edge ratio within rho0 in its three vertex metrics and the sum of their squares
 * decreases. A move it refuses is not performed (the move may change the facets, but
 * the test is cheap and refuses most of the moves the full check would refuse).
 */
static int promising(const as_starset *ss, const as_mesher_params *prm, int32_t v,
                     const double p[3], const as_metric_frame *mfp) {
    const as_star *st = ss->stars[v];
    double before = 0, after = 0;
    for (int32_t i = 0; i < st->nrf; i++) {
        const as_gid *g = st->rf[i].g;
        const double *a[3], *b[3];
        for (int k = 0; k < 3; k++) {
            a[k] = ss->xyz + 3 * (size_t)g[k];
            b[k] = g[k] == v ? p : a[k];
        }
        for (int k = 0; k < 3; k++) {
            const as_metric_frame *m0 = &ss->mf[g[k]], *m1 = g[k] == v ? mfp : m0;
            double r0 = as_radius_edge(m0, a[0], a[1], a[2], NULL);
            double r1 = as_radius_edge(m1, b[0], b[1], b[2], NULL);
            if (!(r1 <= prm->rho0)) return 0;
            before += r0 * r0;
            after += r1 * r1;
        }
    }
    return after < before;
}

/* 1 if some site other than v is at p exactly. */
static int occupied(const as_starset *ss, int32_t v, const double p[3]) {
    int32_t id[4];
    double d2[4];
    size_t n = as_kdtree_knn(ss->kd, p, 4, id, d2);
    for (size_t i = 0; i < n && d2[i] == 0; i++) {
        const double *x = ss->xyz + 3 * (size_t)id[i];
        if (id[i] != v && x[0] == p[0] && x[1] == p[1] && x[2] == p[2]) return 1;
    }
    return 0;
}

/* Try to move v toward its target (paper 6.2: b_v, then halving). *moved = 1 if done. */
static anistar_status optimize_site(as_starset *ss, const as_mesher_params *prm,
                                    as_starmove *mv, int32_t v, as_optimize_counters *cnt,
                                    int *moved) {
    anistar_status s;
    double t[3], h;
    int ok;
    *moved = 0;
    if ((s = target(ss, v, t, &h, &ok)) != ANISTAR_OK || !ok) return s;
    double x[3];
    memcpy(x, ss->xyz + 3 * (size_t)v, sizeof x);
    const as_metric_frame mfv = ss->mf[v];
    while (as_metric_dist(&mfv, x, t) > h) {
        as_metric_frame mft;
        if ((s = as_starset_metric(ss, t, &mft)) != ANISTAR_OK) return s;
        if (!occupied(ss, v, t) && promising(ss, prm, v, t, &mft)) {
            cnt->tries++;
            if ((s = as_starmove_apply(ss, mv, v, t)) != ANISTAR_OK) return s;
            ok = 0;
            if (!mv->doomed && (s = acceptable(ss, prm, mv, &ok)) != ANISTAR_OK) return s;
            if (ok) {
                as_starmove_commit(ss, mv);
                *moved = 1;
                return ANISTAR_OK;
            }
            if ((s = as_starmove_undo(ss, mv)) != ANISTAR_OK) return s;
        }
        double m[3] = {0.5 * (x[0] + t[0]), 0.5 * (x[1] + t[1]), 0.5 * (x[2] + t[2])};
        s = as_surface_project(ss->ctx, ss->surf, m, t);
        if (s == ANISTAR_ENOSURFACE) return ANISTAR_OK;
        if (s != ANISTAR_OK) return s;
    }
    return ANISTAR_OK;
}

anistar_status as_optimize_starset(as_starset *ss, const as_mesher_params *prm,
                                   const atomic_int *stop, as_optimize_counters *cnt) {
    anistar_context *ctx = ss->ctx;
    double t0 = as_now_seconds();
    memset(cnt, 0, sizeof *cnt);
    if (ss->ninc != 0 || ss->n <= ss->first_site) return ANISTAR_OK;
    size_t n = (size_t)ss->n;
    anistar_status s = ANISTAR_OK;
    as_starmove mv;
    memset(&mv, 0, sizeof mv);
    mv.v = -1;
    mv.early = 1; /* design: a move that must end inconsistent stops early (starmove.h) */
    uint8_t *dirty = as_alloc_array(ctx, n, sizeof *dirty);
    opt_item *items = as_alloc_array(ctx, n, sizeof *items);
    if (!dirty || !items) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "optimize: out of memory");
        goto done;
    }
    for (size_t i = 0; i < n; i++) dirty[i] = i >= (size_t)ss->first_site && ss->stars[i];
    for (int pass = 0; pass < AS_OPTIMIZE_MAX_PASSES; pass++) {
        /* the queue: dirty sites by decreasing d_v(v, b_v) */
        size_t ni = 0;
        for (int32_t v = ss->first_site; v < ss->n; v++) {
            if (!dirty[v]) continue;
            dirty[v] = 0;
            double t[3], h;
            int ok;
            if ((s = target(ss, v, t, &h, &ok)) != ANISTAR_OK) goto done;
            if (!ok) continue;
            double d = as_metric_dist(&ss->mf[v], ss->xyz + 3 * (size_t)v, t);
            if (!(d > h)) continue;
            items[ni].key = d;
            items[ni].v = v;
            ni++;
        }
        if (ni == 0) break;
        cnt->passes++;
        sort_items(items, ni);
        uint64_t moved_pass = 0;
        for (size_t i = 0; i < ni && !cnt->stopped; i++) {
            /* design: a stop request ends the pass between two moves (each move leaves
             * the star set valid) */
            if (stop && atomic_load(stop)) {
                cnt->stopped = 1;
                break;
            }
            int32_t v = items[i].v;
            int moved;
            if ((s = optimize_site(ss, prm, &mv, v, cnt, &moved)) != ANISTAR_OK) goto done;
            if (!moved) continue;
            moved_pass++;
            cnt->moved++;
            /* design: the sites whose barycenter may have changed: the neighbours of v */
            const as_star *st = ss->stars[v];
            dirty[v] = 1;
            for (int32_t k = 0; k < st->nrf; k++)
                for (int j = 0; j < 3; j++) dirty[st->rf[k].g[j]] = 1;
            if (mv.stale > 1024 && mv.stale > n / 2 &&
                (s = as_starmove_flush(ss, &mv)) != ANISTAR_OK)
                goto done;
        }
        if (moved_pass == 0 || cnt->stopped) break;
    }
    if (mv.stale) s = as_starmove_flush(ss, &mv);
done:
    as_starmove_free(ctx, &mv);
    as_free(ctx, dirty, n * sizeof *dirty);
    as_free(ctx, items, n * sizeof *items);
    cnt->seconds = as_now_seconds() - t0;
    return s;
}

anistar_status as_mesher_optimize(as_starset *ss, const as_mesher_params *prm,
                                  const atomic_int *stop, anistar_mesh **out, int *stopped) {
    anistar_mesh *m = *out;
    *stopped = 0;
    if (!m || !m->stats.complete || ss->ninc != 0) return ANISTAR_OK;
    const anistar_mesh_stats *S = &m->stats;
    as_optimize_counters oc;
    anistar_status s = as_optimize_starset(ss, prm, stop, &oc);
    *stopped = oc.stopped;
    anistar_mesh *m2 = NULL;
    if (s == ANISTAR_OK) {
        as_mesher_counters c;
        memset(&c, 0, sizeof c);
        c.initial = S->insertions_initial;
        for (int k = 0; k < 3; k++) c.rule[k] = S->insertions_rule[k];
        c.pick_tries = S->pick_valid_tries;
        c.pick_failures = S->pick_valid_failures;
        c.t_init = S->seconds_init;
        c.t_refine = S->seconds_refine;
        c.t_total = S->seconds_total + oc.seconds;
        s = as_mesher_output(ss, prm, &c, 1, 1, &m2);
    }
    if (s != ANISTAR_OK) {
        as_mesh_free(m);
        *out = NULL;
        return s;
    }
    anistar_mesh_stats *T = &m2->stats;
    /* the refinement's counters carry over */
    T->insertions_topology = S->insertions_topology;
    T->insertions_size = S->insertions_size;
    T->insertions_distortion = S->insertions_distortion;
    T->insertions_approx = S->insertions_approx;
    T->insertions_feature = S->insertions_feature;
    T->insertions_hmax = S->insertions_hmax;
    T->topology_below_hmin = S->topology_below_hmin;
    T->sites_unused = S->sites_unused;
    T->stars_delaunay_zone = S->stars_delaunay_zone;
    T->facets_swept = S->facets_swept;
    T->batches = S->batches;
    T->batch_jobs = S->batch_jobs;
    T->batch_jobs_lost = S->batch_jobs_lost;
    T->batch_jobs_set_aside = S->batch_jobs_set_aside;
    T->stall_max = S->stall_max;
    T->components_below_resolution = S->components_below_resolution;
    T->estimate_vertices = S->estimate_vertices;
    T->estimate_bytes = S->estimate_bytes;
    T->stop_reason = S->stop_reason;
    T->seconds_output = S->seconds_output + oc.seconds;
    T->optimized = 1;
    T->optimize_moved = oc.moved;
    T->optimize_tries = oc.tries;
    T->optimize_passes = oc.passes;
    T->seconds_optimize = oc.seconds;
    T->rho2_mean_before = S->rho2_mean;
    memcpy(T->histogram_before, S->histogram, sizeof T->histogram_before);
    as_mesh_free(m);
    *out = m2;
    return ANISTAR_OK;
}
