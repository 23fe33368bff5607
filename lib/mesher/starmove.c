/*
 * starmove.c — move one site of the star set, with an exact undo (DESIGN.md 4.9, paper
 * 6.2). See starmove.h for the model and the design choices.
 */
#include "mesher/starmove.h"

#include <stddef.h>
#include <string.h>

#include "pool.h"

void as_starmove_free(anistar_context *ctx, as_starmove *mv) {
    for (size_t k = 0; k < mv->n; k++)
        if (mv->old[k]) {
            as_star_destroy(ctx, mv->old[k]);
            as_free(ctx, mv->old[k], sizeof *mv->old[k]);
        }
    as_free(ctx, mv->ids, mv->cap * sizeof *mv->ids);
    as_free(ctx, mv->old, mv->cap * sizeof *mv->old);
    as_free(ctx, mv->bid, mv->cap * sizeof *mv->bid);
    as_free(ctx, mv->bst, mv->cap * sizeof *mv->bst);
    as_free(ctx, mv->seeds, mv->cap_seeds * sizeof *mv->seeds);
    memset(mv, 0, sizeof *mv);
}

static void star_free(anistar_context *ctx, as_star *st) {
    if (!st) return;
    as_star_destroy(ctx, st);
    as_free(ctx, st, sizeof *st);
}

/* 1 if site q is a vertex of star st's triangulation. */
static int holds(const as_star *st, int32_t q) {
    for (int32_t i = 0; i < as_star_nv(st); i++)
        if (as_star_vertex_gid(st, i) == q) return 1;
    return 0;
}

/* Make room for n touched stars (ids and old pointers grow together); the first keep
 * entries of both are preserved. */
static anistar_status reserve_touched(anistar_context *ctx, as_starmove *mv, size_t n,
                                      size_t keep) {
    if (n <= mv->cap) return ANISTAR_OK;
    size_t cap = mv->cap ? mv->cap : 16;
    while (cap < n) cap *= 2;
    int32_t *ids = as_alloc_array(ctx, cap, sizeof *ids);
    as_star **old = as_alloc_array(ctx, cap, sizeof *old);
    int32_t *bid = as_alloc_array(ctx, cap, sizeof *bid);
    as_star **bst = as_alloc_array(ctx, cap, sizeof *bst);
    if (!ids || !old || !bid || !bst) {
        as_free(ctx, ids, cap * sizeof *ids);
        as_free(ctx, old, cap * sizeof *old);
        as_free(ctx, bid, cap * sizeof *bid);
        as_free(ctx, bst, cap * sizeof *bst);
        return as_fail(ctx, ANISTAR_ENOMEM, "optimize: out of memory (touched stars)");
    }
    as_free(ctx, mv->bid, mv->cap * sizeof *mv->bid); /* empty between moves */
    as_free(ctx, mv->bst, mv->cap * sizeof *mv->bst);
    mv->bid = bid;
    mv->bst = bst;
    if (keep) {
        memcpy(ids, mv->ids, keep * sizeof *ids);
        memcpy(old, mv->old, keep * sizeof *old);
    }
    as_free(ctx, mv->ids, mv->cap * sizeof *mv->ids);
    as_free(ctx, mv->old, mv->cap * sizeof *mv->old);
    mv->ids = ids;
    mv->old = old;
    mv->cap = cap;
    return ANISTAR_OK;
}

/*
 * The touched stars of moving v from x to p into mv->ids (v first, then ascending, no
 * duplicates); mv->n stays 0 (no old star is held yet).
 * design: the holders of v among the stars whose box contains x, and the stars whose box
 *   contains p that hold v or whose zone p conflicts with (as_star_conflicts, exact).
 */
static anistar_status touched_stars(as_starset *ss, as_starmove *mv, int32_t v,
                                    const double x[3], const double p[3], size_t *count) {
    anistar_context *ctx = ss->ctx;
    anistar_status s;
    size_t m = 0;
    if ((s = reserve_touched(ctx, mv, 1, 0)) != ANISTAR_OK) return s;
    mv->ids[m++] = v;
    for (int pass = 0; pass < 2; pass++) {
        const double *q = pass == 0 ? x : p;
        if ((s = as_boxindex_query_point(ctx, ss->bi, q, &ss->ws.cand)) != ANISTAR_OK) return s;
        for (size_t k = 0; k < ss->ws.cand.n; k++) {
            int32_t w = ss->ws.cand.ids[k];
            const as_star *st = ss->stars[w];
            if (w == v || !st) continue;
            int touch = holds(st, v);
            if (!touch && pass == 1) {
                ss->ws.conflict_tests++;
                touch = as_star_conflicts(st, &ss->mf[w], ss->xyz, p, v, NULL);
            }
            if (!touch) continue;
            if ((s = reserve_touched(ctx, mv, m + 1, m)) != ANISTAR_OK) return s;
            mv->ids[m++] = w;
        }
    }
    /* sort the others and drop duplicates (a star can be found from x and from p) */
    as_ids_sort(mv->ids + 1, m - 1);
    size_t u = 1;
    for (size_t k = 1; k < m; k++)
        if (u == 1 || mv->ids[k] != mv->ids[u - 1]) mv->ids[u++] = mv->ids[k];
    *count = u;
    return ANISTAR_OK;
}

/* A new star of site w (current position and metric) into *out, on thread slot t (-1:
 * the caller's): as_starset_rebuild_on into a star allocated here with the star set's
 * context (freed by it like any star). */
static anistar_status new_star(as_starset *ss, int t, int32_t w, const as_star *old,
                               int32_t skip, as_star **out) {
    *out = NULL;
    as_star *st = as_alloc(ss->ctx, sizeof *st);
    if (!st) return as_fail(ss->ctx, ANISTAR_ENOMEM, "optimize: out of memory (star)");
    as_star_init(st, ss->ctx);
    anistar_status s = as_starset_rebuild_on(ss, t, w, old, skip, st);
    if (s != ANISTAR_OK) {
        star_free(ss->ctx, st);
        return s;
    }
    *out = st;
    return ANISTAR_OK;
}

/* The most rebuilds of one move that run at once (a move touches about seven stars; a
 * round cut short by an early stop wastes the rest). */
#define AS_STARMOVE_ROUND 8

/* The rebuilds of one round of a move on the pool: task j builds the new star of site
 * id[j] into nw[j]. */
typedef struct mv_round {
    as_starset *ss;
    int32_t v; /* the site moved */
    size_t m;
    int32_t id[AS_STARMOVE_ROUND];
    as_star *nw[AS_STARMOVE_ROUND];
} mv_round;

static anistar_status round_task(void *arg, int32_t j, int t, anistar_context *tctx) {
    (void)tctx;
    mv_round *R = arg;
    int32_t id = R->id[j];
    return new_star(R->ss, t, id, R->ss->stars[id], id == R->v ? -1 : R->v, &R->nw[j]);
}

/* The place of site id among the stars built ahead (mv->bid[0..nbuilt)), or -1. */
static ptrdiff_t built_ahead(const as_starmove *mv, int32_t id) {
    for (size_t j = 0; j < mv->nbuilt; j++)
        if (mv->bid[j] == id) return (ptrdiff_t)j;
    return -1;
}

/* 1 if some inconsistent facet of ss is final: none of its vertices' stars is among the
 * touched stars still to rebuild (mv->ids[mv->n..count)). A star's rebuild only changes
 * the facets that hold its center, so such a facet stays inconsistent to the end of the
 * move. */
static int final_inconsistency(const as_starset *ss, const as_starmove *mv, size_t count) {
    for (size_t i = 0; i < ss->ninc; i++) {
        const as_gid *g = ss->inc[i].g;
        int pending = 0;
        for (size_t k = mv->n; k < count && !pending; k++)
            pending = mv->ids[k] == g[0] || mv->ids[k] == g[1] || mv->ids[k] == g[2];
        if (!pending) return 1;
    }
    return 0;
}

/*
 * Reorder the touched stars after v's (mv->ids[1..count), v's new star rebuilt) so that
 * facets of v become final soon: v's neighbours in the order of a walk around v's new
 * facets (after v, a and b are rebuilt, facet (v, a, b) is final), then the others as
 * they were (ascending).
 */
static void order_by_fan(const as_starset *ss, as_starmove *mv, size_t count) {
    const as_star *st = ss->stars[mv->v];
    size_t placed = 1;
    int32_t prev = -1, cur = -1;
    int32_t start = -1;
    for (int32_t step = 0; step <= st->nrf && placed < count; step++) {
        /* the next vertex of the walk: a facet holding cur other than the one from prev */
        int32_t next = -1;
        for (int32_t i = 0; i < st->nrf && next < 0; i++) {
            const as_gid *g = st->rf[i].g;
            int32_t a = -1, b = -1;
            for (int j = 0; j < 3; j++)
                if (g[j] != mv->v) {
                    if (a < 0) a = g[j];
                    else b = g[j];
                }
            if (cur < 0) {
                next = a;
                start = a;
            } else if (a == cur && b != prev) {
                next = b;
            } else if (b == cur && a != prev) {
                next = a;
            }
        }
        if (next < 0 || (step > 0 && next == start)) break;
        for (size_t k = placed; k < count; k++)
            if (mv->ids[k] == next) {
                /* move it to position placed, keeping the others in order */
                memmove(mv->ids + placed + 1, mv->ids + placed, (k - placed) * sizeof *mv->ids);
                mv->ids[placed++] = next;
                break;
            }
        prev = cur;
        cur = next;
    }
}

/* Put the old stars 0..mv->n back (reverse diffs), free the new ones, restore v. */
static anistar_status revert(as_starset *ss, as_starmove *mv) {
    anistar_context *ctx = ss->ctx;
    anistar_status st = ANISTAR_OK;
    for (size_t k = mv->n; k-- > 0;) {
        int32_t id = mv->ids[k];
        as_star *nw = ss->stars[id];
        ss->stars[id] = mv->old[k];
        mv->old[k] = NULL;
        if (st == ANISTAR_OK) st = as_starset_apply_diff(ss, id, nw->rf, nw->nrf);
        star_free(ctx, nw);
    }
    mv->n = 0;
    memcpy(ss->xyz + 3 * (size_t)mv->v, mv->old_x, sizeof mv->old_x);
    ss->mf[mv->v] = mv->old_mf;
    mv->v = -1;
    mv->stale++; /* the kd-tree entry at the new position */
    ss->nev = 0;
    ss->nnewinc = 0;
    return st;
}

anistar_status as_starmove_apply(as_starset *ss, as_starmove *mv, int32_t v, const double p[3]) {
    anistar_context *ctx = ss->ctx;
    anistar_status s;
    mv->n = 0;
    mv->v = -1;
    mv->doomed = 0;
    if (v < ss->first_site || v >= ss->n || !ss->stars[v])
        return as_fail(ctx, ANISTAR_EINVAL, "optimize: %d is not a surface site", (int)v);
    if (!ss->env.keep_points) {
        /* design: from the first move on, stars keep their stretched points (star.h: a star
         * not rebuilt keeps a moved site where it was) */
        ss->env.keep_points = 1;
        /* design: the rebuilds of the moves ask the surface the same questions again
         * (star.h, as_star_memo) */
        ss->env.memo = 1;
        for (int32_t w = 0; w < ss->n; w++)
            if (ss->stars[w] &&
                (s = as_star_keep_points(&ss->env, ss->stars[w], &ss->mf[w], &ss->sc)) !=
                    ANISTAR_OK)
                return s;
    }
    /* the threads' workspaces (sized to the sites, the environment copied: it changed
     * above on the first move); before x is taken, since it may grow the point arrays */
    const int T = ss->pool ? ss->nthreads : 1;
    if (T > 1 && (s = as_starset_threads_prepare(ss)) != ANISTAR_OK) return s;
    const double *x = ss->xyz + 3 * (size_t)v;
    as_metric_frame mfp;
    if ((s = as_starset_metric(ss, p, &mfp)) != ANISTAR_OK) return s;
    size_t count;
    if ((s = touched_stars(ss, mv, v, x, p, &count)) != ANISTAR_OK) return s;
    if ((s = as_kdtree_insert(ctx, ss->kd, p, v)) != ANISTAR_OK) return s;
    /* from here on the star set changes; revert() undoes what was done */
    mv->v = v;
    memcpy(mv->old_x, x, sizeof mv->old_x);
    mv->old_mf = ss->mf[v];
    memcpy(ss->xyz + 3 * (size_t)v, p, 3 * sizeof(double));
    ss->mf[v] = mfp;
    /* design: the rebuilds read only the old stars, the positions, the metrics and the
     * kd-tree (as_starset_rebuild_on), so with threads they are built ahead, up to
     * AS_STARMOVE_ROUND at once (the first round: v's star and the next ones), kept by id,
     * and applied one at a time in the serial loop's order (v's fan reorders the others)
     * with the same early stop: the stars applied, the table and the verdict are those of
     * the serial loop whatever the thread count; stars built past an early stop are freed
     * unused. */
    mv->nbuilt = 0;
    for (size_t k = 0; k < count && s == ANISTAR_OK; k++) {
        int32_t id = mv->ids[k];
        as_star *nw = NULL;
        ptrdiff_t ja = built_ahead(mv, id);
        if (ja >= 0) { /* taken out of the built-ahead list */
            nw = mv->bst[ja];
            mv->bid[ja] = mv->bid[--mv->nbuilt];
            mv->bst[ja] = mv->bst[mv->nbuilt];
        }
        if (!nw && T == 1) {
            s = new_star(ss, -1, id, ss->stars[id], id == v ? -1 : v, &nw);
        } else if (!nw) {
            /* a round: this star and the next ones not built yet, in the current order */
            mv_round R;
            R.ss = ss;
            R.v = v;
            R.m = 0;
            for (size_t q = k; q < count && R.m < AS_STARMOVE_ROUND; q++)
                if (built_ahead(mv, mv->ids[q]) < 0) {
                    R.id[R.m] = mv->ids[q];
                    R.nw[R.m++] = NULL;
                }
            s = as_pool_run(ss->pool, (int32_t)R.m, round_task, &R);
            as_starset_collect_counts(ss);
            for (size_t j = 0; j < R.m; j++) {
                if (s != ANISTAR_OK || j == 0) continue;
                mv->bid[mv->nbuilt] = R.id[j]; /* room: count entries (reserve_touched) */
                mv->bst[mv->nbuilt++] = R.nw[j];
                R.nw[j] = NULL;
            }
            nw = R.nw[0];
            if (s != ANISTAR_OK)
                for (size_t j = 0; j < R.m; j++) star_free(ss->ctx, R.nw[j]);
        }
        if (s != ANISTAR_OK) break;
        as_star *old = ss->stars[id];
        ss->star_rebuilds++;
        ss->stars[id] = nw;
        mv->old[k] = old;
        mv->n = k + 1;
        if ((s = as_starset_apply_diff(ss, id, old->rf, old->nrf)) != ANISTAR_OK) break;
        if (!mv->early || k + 1 == count) continue;
        /* a touched star that is not a closed fan, or a final inconsistent facet: the
         * optimiser would undo the move (optimize.c) */
        if (!nw->closed || (ss->ninc && final_inconsistency(ss, mv, count))) {
            mv->doomed = 1;
            break;
        }
        if (k == 0) order_by_fan(ss, mv, count);
    }
    for (size_t j = 0; j < mv->nbuilt; j++) star_free(ss->ctx, mv->bst[j]);
    mv->nbuilt = 0;
    if (s != ANISTAR_OK) {
        (void)revert(ss, mv);
        return s;
    }
    ss->nev = 0; /* design: the refiner is done; the optimiser reads the stars directly */
    ss->nnewinc = 0;
    return ANISTAR_OK;
}

void as_starmove_commit(as_starset *ss, as_starmove *mv) {
    for (size_t k = 0; k < mv->n; k++) {
        star_free(ss->ctx, mv->old[k]);
        mv->old[k] = NULL;
    }
    mv->n = 0;
    if (mv->v >= 0) mv->stale++; /* the kd-tree entry at the old position */
    mv->v = -1;
}

anistar_status as_starmove_undo(as_starset *ss, as_starmove *mv) {
    if (mv->v < 0) return ANISTAR_OK;
    anistar_status s = revert(ss, mv);
    if (s != ANISTAR_OK && s != ANISTAR_ENOMEM)
        return as_fail(ss->ctx, ANISTAR_EINTERNAL, "optimize: undo of a move failed");
    return s;
}

anistar_status as_starmove_flush(as_starset *ss, as_starmove *mv) {
    anistar_context *ctx = ss->ctx;
    size_t n = (size_t)(ss->n - 8);
    if (ss->n <= 8) return ANISTAR_OK;
    if (n > mv->cap_seeds &&
        as_grow(ctx, (void **)&mv->seeds, &mv->cap_seeds, n, sizeof *mv->seeds))
        return as_fail(ctx, ANISTAR_ENOMEM, "optimize: out of memory (kd-tree)");
    for (size_t i = 0; i < n; i++) mv->seeds[i] = (int32_t)(8 + i);
    as_kdtree *kd = NULL;
    anistar_status s = as_kdtree_build(ctx, ss->xyz + 24, mv->seeds, n, &kd);
    if (s != ANISTAR_OK) return s;
    as_kdtree_free(ctx, ss->kd);
    ss->kd = kd;
    mv->stale = 0;
    return ANISTAR_OK;
}
