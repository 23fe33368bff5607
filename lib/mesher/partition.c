/*
 * partition.c — the star set split over k parts, simulated in one process (partition.h,
 * docs/scaling.md; issue 15 item 4).
 */
#include "mesher/partition.h"

#include <math.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "geom/boxindex.h"
#include "geom/kdtree.h"
#include "mesher/refine.h"
#include "mesher/starset.h"

/* Rounds at most: a seam that keeps asking for points is reported, not followed forever. */
#define PT_MAX_ROUNDS 200

static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- the split ------------------------------------------------------------------------ */

/* A node of the bisection: leaf part >= 0, or a cut (axis, value) with children. */
typedef struct pt_node {
    int part, axis, left, right;
    double cut;
} pt_node;

typedef struct pt_split {
    pt_node node[2 * AS_PARTITION_MAX];
    int nnode;
} pt_split;

static int pt_owner(const pt_split *sp, const double p[3]) {
    int n = 0;
    while (sp->node[n].part < 0) n = p[sp->node[n].axis] < sp->node[n].cut ? sp->node[n].left
                                                                           : sp->node[n].right;
    return sp->node[n].part;
}

/* 1 if p lies within eps of a cut on its way down the bisection. */
static int pt_near_cut(const pt_split *sp, const double p[3], double eps) {
    int n = 0;
    while (sp->node[n].part < 0) {
        const pt_node *nd = &sp->node[n];
        if (fabs(p[nd->axis] - nd->cut) <= eps) return 1;
        n = p[nd->axis] < nd->cut ? nd->left : nd->right;
    }
    return 0;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Bisect the points idx[0..n) into parts [p0, p0 + k) within the box lo-hi; scratch
 * holds n doubles. Returns the node's index. */
static int pt_bisect(pt_split *sp, const double *pts, int32_t *idx, size_t n, int p0, int k,
                     const double lo[3], const double hi[3], double *scratch,
                     as_partition_result *res) {
    int me = sp->nnode++;
    pt_node *nd = &sp->node[me];
    if (k == 1) {
        nd->part = p0;
        memcpy(res->part[p0].lo, lo, 3 * sizeof(double));
        memcpy(res->part[p0].hi, hi, 3 * sizeof(double));
        return me;
    }
    double blo[3] = {INFINITY, INFINITY, INFINITY}, bhi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) {
            blo[a] = fmin(blo[a], pts[3 * (size_t)idx[i] + a]);
            bhi[a] = fmax(bhi[a], pts[3 * (size_t)idx[i] + a]);
        }
    int axis = 0;
    for (int a = 1; a < 3; a++)
        if (bhi[a] - blo[a] > bhi[axis] - blo[axis]) axis = a;
    int k1 = k / 2;
    double cut;
    if (n == 0) {
        cut = 0.5 * (lo[axis] + hi[axis]);
    } else {
        for (size_t i = 0; i < n; i++) scratch[i] = pts[3 * (size_t)idx[i] + axis];
        qsort(scratch, n, sizeof *scratch, cmp_double);
        size_t q = n * (size_t)k1 / (size_t)k;
        cut = q == 0 ? scratch[0] : 0.5 * (scratch[q - 1] + scratch[q]);
    }
    /* partition idx by the cut (stable enough: the order within a side does not matter) */
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (pts[3 * (size_t)idx[i] + axis] < cut) {
            int32_t t = idx[m];
            idx[m++] = idx[i];
            idx[i] = t;
        }
    nd->part = -1;
    nd->axis = axis;
    nd->cut = cut;
    double mid_hi[3], mid_lo[3];
    memcpy(mid_hi, hi, sizeof mid_hi);
    memcpy(mid_lo, lo, sizeof mid_lo);
    mid_hi[axis] = cut;
    mid_lo[axis] = cut;
    int l = pt_bisect(sp, pts, idx, m, p0, k1, lo, mid_hi, scratch, res);
    int r = pt_bisect(sp, pts, idx + m, n - m, p0 + k1, k - k1, mid_lo, hi, scratch, res);
    sp->node[me].left = l;
    sp->node[me].right = r;
    return me;
}

/* ---- the parts ------------------------------------------------------------------------ */

/* A barrier the parts can leave (a part whose run ended on an error or a limit). */
typedef struct pt_barrier {
    pthread_mutex_t m;
    pthread_cond_t c;
    int active, waiting;
    unsigned gen;
} pt_barrier;

static void bar_wait(pt_barrier *b) {
    pthread_mutex_lock(&b->m);
    if (++b->waiting >= b->active) {
        b->waiting = 0;
        b->gen++;
        pthread_cond_broadcast(&b->c);
    } else {
        unsigned g = b->gen;
        while (g == b->gen) pthread_cond_wait(&b->c, &b->m);
    }
    pthread_mutex_unlock(&b->m);
}

static void bar_leave(pt_barrier *b) {
    pthread_mutex_lock(&b->m);
    b->active--;
    if (b->waiting > 0 && b->waiting >= b->active) {
        b->waiting = 0;
        b->gen++;
        pthread_cond_broadcast(&b->c);
    }
    pthread_mutex_unlock(&b->m);
}

typedef struct pt_buf {
    double *p; /* 3 per point */
    size_t n, cap;
} pt_buf;

/* A request: a job's point p for the part owning it, with the job's empty ball (center c,
 * radius r in the metric of the job's star, mf). */
typedef struct pt_req {
    double p[3], c[3], r;
    as_metric_frame mf;
    int dest;
} pt_req;

typedef struct pt_reqs {
    pt_req *q;
    size_t n, cap;
} pt_reqs;

struct pt_sim;

typedef struct pt_part {
    struct pt_sim *S;
    int i;
    anistar_context ctx;
    as_mesher_params prm;
    as_part_hook hook;
    pt_buf out, in;      /* sites created this round; the points to insert */
    pt_reqs req;         /* its requests of this round */
    int32_t *again, *again_ret; /* stars with jobs set aside (this round; returned) */
    size_t nagain, cap_again, nagain_ret, cap_again_ret;
    as_idlist ids;       /* the staleness test's query */
    int32_t pub_n;       /* ids below are published (-1: not yet known) */
    int take_all;        /* one of its stars has no zone box: its halo is everything */
    double cpu_mark;
    double *round_cpu;   /* per round */
    size_t cap_round;
    int rounds;
    int failed;          /* its buffers could not grow, or its run failed */
    int left;            /* its run ended (under the barrier's mutex) */
    anistar_status st;
    anistar_mesh *mesh;
    as_starset *ss;
    as_partition_part *rp;
} pt_part;

typedef struct pt_sim {
    int k;
    pt_split sp;
    pt_barrier bar;
    const as_surface *surf;
    const as_field *field;
    pt_part *parts;
} pt_sim;

static int buf_push(anistar_context *ctx, pt_buf *b, const double p[3]) {
    if (as_grow(ctx, (void **)&b->p, &b->cap, 3 * (b->n + 1), sizeof *b->p))
        return -1;
    memcpy(b->p + 3 * b->n, p, 3 * sizeof(double));
    b->n++;
    return 0;
}

static void buf_free(anistar_context *ctx, pt_buf *b) {
    as_free(ctx, b->p, b->cap * sizeof *b->p);
    memset(b, 0, sizeof *b);
}

static int part_accept(void *user, const as_starset *ss, int rule, int32_t v, const as_rfacet *f,
                       const double p[3], int final) {
    pt_part *P = user;
    const pt_split *sp = &P->S->sp;
    if (P->pub_n < 0) { /* the first job: the run's start is done */
        P->pub_n = ss->n; /* the initial sites are every part's */
        P->rp->init_seconds = cpu_now() - P->cpu_mark;
    }
    /* design: a facet's job belongs to the part owning the facet's surface center (the
     * center of its empty ball, where rule 1 inserts): that part holds the facet's
     * star, as a halo copy if the site is across the cut, so the job is done where its
     * point goes and only Pick_valid's moves across a cut become requests. (Owning jobs
     * by their star's site, or by the facet's vertex with the smallest coordinates,
     * made every part send about 1,000 requests on the paper's torus, nearly all found
     * stale: the neighbour was refining the same spot with its own points; owning them
     * by the facet's centroid, 6,945 stale requests of 6,977 on the shock sphere with
     * 8 parts.) A center computed in two parts may differ in its last bits (their ids,
     * hence their sums' orders, differ): within 1e-9 R of a cut the job goes by the
     * centroid of the facet's points summed in a fixed order, the same bits everywhere.
     * (Without that, on the shock sphere, whose sample is symmetric, a cut fell exactly
     * where centers lay, two parts both owned one and inserted it 1e-16 apart, and a
     * part then refined that spot forever.) The topology rule's job: the star's part. */
    double at[3];
    memcpy(at, f ? f->c : ss->xyz + 3 * (size_t)v, sizeof at);
    if (f && pt_near_cut(sp, at, 1e-9 * P->S->surf->radius)) {
        const double *q[3];
        for (int c = 0; c < 3; c++) q[c] = ss->xyz + 3 * (size_t)f->g[c];
        for (int a = 0; a < 2; a++) /* lexicographic order of the points */
            for (int b = a + 1; b < 3; b++)
                if (q[b][0] < q[a][0] ||
                    (q[b][0] == q[a][0] &&
                     (q[b][1] < q[a][1] || (q[b][1] == q[a][1] && q[b][2] < q[a][2])))) {
                    const double *t = q[a];
                    q[a] = q[b];
                    q[b] = t;
                }
        for (int c = 0; c < 3; c++) at[c] = (q[0][c] + q[1][c] + q[2][c]) / 3;
    }
    if (pt_owner(sp, at) != P->i) return 0;
    (void)rule;
    if (P->rounds == 0 && f) {
        /* design: before the first exchange a part knows nothing beyond its box but the
         * initial sites: a facet whose empty ball leaves the box may be wrong there (its
         * neighbour's sites are missing), and its point would be a request the owner
         * finds stale. Set it aside until the halo has come (measured on the paper's
         * torus: about 1,200 stale requests per part without this, whatever k) */
        double h[3];
        as_metric_ellipsoid_box(&ss->mf[v], f->r, h);
        int inside = 1;
        for (int a = 0; a < 3; a++)
            inside &= f->c[a] - h[a] >= P->rp->lo[a] && f->c[a] + h[a] <= P->rp->hi[a];
        if (!inside) {
            if (as_grow(&P->ctx, (void **)&P->again, &P->cap_again, P->nagain + 1,
                        sizeof *P->again))
                P->failed = 1;
            else
                P->again[P->nagain++] = v;
            P->rp->deferred++;
            return 0;
        }
    }
    if (!final) return 1;
    int o = pt_owner(sp, p);
    if (o == P->i) {
        P->rp->inserted++;
        return 1;
    }
    if (as_grow(&P->ctx, (void **)&P->req.q, &P->req.cap, P->req.n + 1, sizeof *P->req.q)) {
        P->failed = 1;
        return 0;
    }
    pt_req *q = &P->req.q[P->req.n++];
    memcpy(q->p, p, sizeof q->p);
    /* the job's empty ball: the facet's surface ball; for the topology rule, the ball
     * around p through v (p lies in v's Voronoi cell in M_v: no site is nearer) */
    memcpy(q->c, f ? f->c : p, sizeof q->c);
    q->r = f ? f->r : as_metric_dist(&ss->mf[v], p, ss->xyz + 3 * (size_t)v);
    q->mf = ss->mf[v];
    q->dest = o;
    P->rp->requests_sent++;
    return 0;
}

/* Whether request q is stale in star set ss: a site lies inside the job's empty ball, so
 * the facet it was made for is gone here (the owner refined there since, or another part
 * asked for the same spot). design: the serial loop never inserts twice for one ball:
 * after the first point the facet is no longer there. The margin 1e-9 keeps the facet's
 * own vertices (on the ball's boundary up to rounding) out of the test; the test only
 * spares points, whatever it decides the check run certifies the result. */
static anistar_status req_stale(pt_part *P, const as_starset *ss, const pt_req *q, int *stale) {
    *stale = 0;
    if (!(q->r > 0)) return ANISTAR_OK; /* no ball: only an exact duplicate is stale */
    const double lim = q->r * (1 - 1e-9);
    double h[3], lo[3], hi[3];
    as_metric_ellipsoid_box(&q->mf, lim, h);
    for (int a = 0; a < 3; a++) {
        lo[a] = q->c[a] - h[a];
        hi[a] = q->c[a] + h[a];
    }
    anistar_status s = as_kdtree_box_any(&P->ctx, ss->kd, lo, hi, 0, &P->ids);
    if (s != ANISTAR_OK) return s;
    for (size_t k = 0; k < P->ids.n; k++) {
        int32_t u = P->ids.ids[k];
        if (u < ss->first_site) continue;
        if (as_metric_dist(&q->mf, q->c, ss->xyz + 3 * (size_t)u) < lim) {
            *stale = 1;
            break;
        }
    }
    return ANISTAR_OK;
}

static int cmp_i32(const void *a, const void *b) {
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return x < y ? -1 : x > y;
}

static anistar_status part_round_end(void *user, as_starset *ss, const double **pts,
                                     size_t *npts, const int32_t **again, size_t *nagain,
                                     int *more) {
    pt_part *P = user;
    pt_sim *S = P->S;
    const int me = P->i;
    /* this round's CPU time (the exchange below is a rank's communication) */
    double now = cpu_now();
    if (P->pub_n < 0) { /* no job before the first exchange */
        P->pub_n = ss->n;
        P->rp->init_seconds = now - P->cpu_mark;
    }
    if ((size_t)P->rounds == P->cap_round &&
        as_grow(&P->ctx, (void **)&P->round_cpu, &P->cap_round, (size_t)P->rounds + 1,
                sizeof *P->round_cpu))
        P->failed = 1;
    if ((size_t)P->rounds < P->cap_round) P->round_cpu[P->rounds] = now - P->cpu_mark;
    if (P->rounds < 8)
        P->rp->round_seconds[P->rounds] =
            now - P->cpu_mark - (P->rounds == 0 ? P->rp->init_seconds : 0);
    P->rounds++;
    /* 1. what it publishes: the sites it created since the last exchange, its reach */

    P->out.n = 0;
    for (int32_t u = P->pub_n; u < ss->n; u++)
        if (pt_owner(&S->sp, ss->xyz + 3 * (size_t)u) == me &&
            buf_push(&P->ctx, &P->out, ss->xyz + 3 * (size_t)u))
            P->failed = 1;
    P->pub_n = ss->n;
    /* the stars whose jobs were set aside, once each, in id order */
    P->nagain_ret = 0;
    if (P->nagain) {
        qsort(P->again, P->nagain, sizeof *P->again, cmp_i32);
        if (as_grow(&P->ctx, (void **)&P->again_ret, &P->cap_again_ret, P->nagain,
                    sizeof *P->again_ret))
            P->failed = 1;
        else
            for (size_t q = 0; q < P->nagain; q++)
                if (q == 0 || P->again[q] != P->again[q - 1])
                    P->again_ret[P->nagain_ret++] = P->again[q];
        P->nagain = 0;
    }
    /* its halo: the sites that conflict with one of its stars, i.e. would change it if
     * inserted (the boxes of the stars' conflict zones, then the exact test of an
     * insertion); a star without a zone box takes every site */
    P->take_all = 0;
    for (int32_t u = ss->first_site; u < ss->n && !P->take_all; u++) {
        double zlo[3], zhi[3];
        if (ss->stars[u] && pt_owner(&S->sp, ss->xyz + 3 * (size_t)u) == me &&
            !as_boxindex_get(ss->bi, u, zlo, zhi))
            P->take_all = 1;
    }
    bar_wait(&S->bar);
    /* 2. what it receives; whether any part created a site or asked for one */
    int any = 0, stop = 0;
    pthread_mutex_lock(&S->bar.m);
    for (int j = 0; j < S->k; j++) {
        any |= S->parts[j].out.n > 0 || S->parts[j].req.n > 0;
        /* a part that failed or ended on a limit ends the simulation */
        stop |= S->parts[j].failed || S->parts[j].left;
    }
    pthread_mutex_unlock(&S->bar.m);
    P->in.n = 0;
    anistar_status st = ANISTAR_OK;
    for (int j = 0; j < S->k && st == ANISTAR_OK; j++) {
        if (j == me) continue;
        const pt_buf *o = &S->parts[j].out;
        for (size_t q = 0; q < o->n; q++) {
            int take = P->take_all;
            if (!take &&
                (st = as_boxindex_query_point(&P->ctx, ss->bi, o->p + 3 * q, &P->ids)) !=
                    ANISTAR_OK)
                break;
            for (size_t w = 0; !take && w < P->ids.n; w++) {
                int32_t u = P->ids.ids[w];
                /* design: the stars whose jobs were set aside count too, although at
                 * the initial sites' scale across the cut their zones reach far into the
                 * neighbour's box (on the shock sphere with 4 parts each part then takes
                 * about twice its own sites): without their halo a part whose stars were
                 * all set aside refined its box in the next round against a coarse
                 * outside, and rule 3 at that seam inserted points 1e-11 apart without
                 * end (shock sphere, 8 parts) */
                if (pt_owner(&S->sp, ss->xyz + 3 * (size_t)u) != me) continue;
                int32_t hint = -1;
                take = as_star_conflicts(ss->stars[u], &ss->mf[u], ss->xyz, o->p + 3 * q,
                                         ss->n, &hint);
            }
            if (!take) continue;
            if (buf_push(&P->ctx, &P->in, o->p + 3 * q)) P->failed = 1;
            P->rp->halo_in++;
        }
    }
    const int64_t req0 = P->rp->requests_in;
    for (int j = 0; j < S->k && st == ANISTAR_OK; j++) {
        const pt_reqs *o = &S->parts[j].req;
        for (size_t q = 0; q < o->n && st == ANISTAR_OK; q++) {
            if (o->q[q].dest != me) continue;
            int stale = 0;
            if ((st = req_stale(P, ss, &o->q[q], &stale)) != ANISTAR_OK) break;
            /* and the requests taken before it in this exchange */
            size_t first_req = P->in.n - (size_t)(P->rp->requests_in - req0);
            for (size_t w = first_req; w < P->in.n && !stale; w++)
                stale = o->q[q].r > 0 &&
                        as_metric_dist(&o->q[q].mf, o->q[q].c, P->in.p + 3 * w) <
                            o->q[q].r * (1 - 1e-9);
            if (stale) {
                P->rp->requests_stale++;
                continue;
            }
            if (buf_push(&P->ctx, &P->in, o->q[q].p)) P->failed = 1;
            P->rp->requests_in++;
        }
    }
    if (st != ANISTAR_OK) P->failed = 1;
    bar_wait(&S->bar); /* every part has read the others' buffers */
    P->req.n = 0;
    *pts = P->in.p;
    *npts = P->in.n;
    *again = P->again_ret;
    *nagain = P->nagain_ret;
    *more = any && !stop && P->rounds < PT_MAX_ROUNDS;
    P->cpu_mark = cpu_now();
    if (P->failed) return as_fail(&P->ctx, ANISTAR_ENOMEM, "partition: out of memory (exchange)");
    return ANISTAR_OK;
}

static void *part_main(void *arg) {
    pt_part *P = arg;
    pt_sim *S = P->S;
    P->cpu_mark = cpu_now();
    double c0 = P->cpu_mark;
    P->st = as_mesher_run_keep(&P->ctx, S->surf, S->field, &P->prm, NULL, &P->mesh, &P->ss);
    /* a part ends INCOMPLETE by design (its round found nothing more to do) */
    if (P->st == ANISTAR_INCOMPLETE) P->st = ANISTAR_OK;
    P->rp->cpu_seconds = cpu_now() - c0;
    pthread_mutex_lock(&S->bar.m);
    P->left = 1;
    if (P->st != ANISTAR_OK) P->failed = 1;
    pthread_mutex_unlock(&S->bar.m);
    bar_leave(&S->bar);
    return NULL;
}

/* ---- the stitch ----------------------------------------------------------------------- */

/* The id in ss of the site at p (-1: none). */
static int32_t id_at(const as_starset *ss, const double p[3]) {
    int32_t id;
    double d2;
    if (as_kdtree_knn(ss->kd, p, 1, &id, &d2) == 0 || d2 != 0) return -1;
    return id;
}

typedef struct pt_tri {
    as_gid g[3];
} pt_tri;

static int cmp_tri(const void *a, const void *b) {
    const pt_tri *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x->g[k] != y->g[k]) return x->g[k] < y->g[k] ? -1 : 1;
    return 0;
}

/* Hook of the union's star set: build the stars of the seeds, refine nothing. */
static int none_accept(void *user, const as_starset *ss, int rule, int32_t v, const as_rfacet *f,
                       const double p[3], int final) {
    (void)user, (void)ss, (void)rule, (void)v, (void)f, (void)p, (void)final;
    return 0;
}
static anistar_status none_round(void *user, as_starset *ss, const double **pts, size_t *n,
                                 const int32_t **again, size_t *nagain, int *more) {
    (void)user, (void)ss;
    *pts = NULL;
    *n = 0;
    *again = NULL;
    *nagain = 0;
    *more = 0;
    return ANISTAR_OK;
}

/*
 * Compare the parts' owned stars with the union's star set U; count the union's facets.
 *   design: per part, map each of its ids to U's id at the same point (-1: none), one kd
 *   query per point; then translate every owned star's facets through the map, sort them,
 *   and compare them with the star of U at the same point.
 */
static anistar_status compare_stars(anistar_context *ctx, pt_sim *S, const as_starset *U,
                                    as_partition_result *res) {
    size_t cap = 0, n = 0, cap_a = 0, cap_b = 0, cap_map = 0;
    pt_tri *all = NULL, *a = NULL, *b = NULL;
    int32_t *map = NULL; /* a part's id -> U's id, or -1 */
    anistar_status s = ANISTAR_OK;
    for (int i = 0; i < S->k && s == ANISTAR_OK; i++) {
        const as_starset *ss = S->parts[i].ss;
        if (as_grow(ctx, (void **)&map, &cap_map, (size_t)ss->n + 1, sizeof *map)) {
            s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory (stitch)");
            break;
        }
        for (int32_t g = 0; g < ss->n; g++) map[g] = id_at(U, ss->xyz + 3 * (size_t)g);
        for (int32_t v = ss->first_site; v < ss->n && s == ANISTAR_OK; v++) {
            const as_star *st = ss->stars[v];
            if (!st || pt_owner(&S->sp, ss->xyz + 3 * (size_t)v) != i) continue;
            int32_t gv = map[v];
            size_t na = 0;
            if (as_grow(ctx, (void **)&a, &cap_a, (size_t)st->nrf + 1, sizeof *a) ||
                as_grow(ctx, (void **)&all, &cap, n + (size_t)st->nrf + 1, sizeof *all)) {
                s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory (stitch)");
                break;
            }
            int missing = gv < 0;
            for (int32_t f = 0; f < st->nrf; f++) {
                pt_tri t;
                for (int c = 0; c < 3; c++) {
                    t.g[c] = map[st->rf[f].g[c]];
                    if (t.g[c] < 0) missing = 1;
                }
                as_sort_gid3(t.g);
                a[na++] = t;
                all[n++] = t;
            }
            if (missing) continue;
            const as_star *su = U->stars[gv];
            if (!su || (size_t)su->nrf != na) continue;
            if (as_grow(ctx, (void **)&b, &cap_b, na + 1, sizeof *b)) {
                s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory (stitch)");
                break;
            }
            for (size_t f = 0; f < na; f++) {
                for (int c = 0; c < 3; c++) b[f].g[c] = su->rf[f].g[c];
                as_sort_gid3(b[f].g);
            }
            qsort(a, na, sizeof *a, cmp_tri);
            qsort(b, na, sizeof *b, cmp_tri);
            if (na == 0 || memcmp(a, b, na * sizeof *a) == 0) res->stars_same++;
        }
    }
    if (s == ANISTAR_OK) {
        qsort(all, n, sizeof *all, cmp_tri);
        for (size_t i = 0; i < n;) {
            size_t j = i;
            while (j < n && cmp_tri(&all[i], &all[j]) == 0) j++;
            res->union_facets++;
            int ok = j - i == 3;
            for (int c = 0; c < 3; c++) ok &= all[i].g[c] >= U->first_site;
            if (ok) res->union_consistent++;
            i = j;
        }
    }
    as_free(ctx, all, cap * sizeof *all);
    as_free(ctx, a, cap_a * sizeof *a);
    as_free(ctx, b, cap_b * sizeof *b);
    as_free(ctx, map, cap_map * sizeof *map);
    return s;
}

/* ---- the run -------------------------------------------------------------------------- */

anistar_status as_partition_run(anistar_context *ctx, const as_surface *surf,
                                const as_field *field, const as_mesher_params *prm, int k,
                                as_partition_result *res, anistar_mesh **out) {
    memset(res, 0, sizeof *res);
    if (out) *out = NULL;
    if (k < 1 || k > AS_PARTITION_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "partition: k must be in [1, %d], got %d",
                       AS_PARTITION_MAX, k);
    res->k = k;
    pt_sim *S = as_alloc(ctx, sizeof *S);
    if (!S) return as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory");
    memset(S, 0, sizeof *S);
    S->k = k;
    S->surf = surf;
    S->field = field;
    anistar_status s = ANISTAR_OK;
    double *seeds = NULL;
    size_t nseeds = 0, cap_seeds = 0;
    as_starset *U = NULL;
    anistar_mesh *mu = NULL;

    /* the split, from a surface sample */
    as_point_sample smp;
    memset(&smp, 0, sizeof smp);
    if ((s = as_surface_sample(ctx, surf, 4096, &smp)) != ANISTAR_OK) goto done;
    {
        int32_t *idx = as_alloc_array(ctx, smp.n + 1, sizeof *idx);
        double *scratch = as_alloc_array(ctx, smp.n + 1, sizeof *scratch);
        if (!idx || !scratch) {
            as_free(ctx, idx, (smp.n + 1) * sizeof *idx);
            as_free(ctx, scratch, (smp.n + 1) * sizeof *scratch);
            as_surface_sample_free(ctx, &smp);
            s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory");
            goto done;
        }
        for (size_t i = 0; i < smp.n; i++) idx[i] = (int32_t)i;
        const double lo[3] = {-INFINITY, -INFINITY, -INFINITY},
                     hi[3] = {INFINITY, INFINITY, INFINITY};
        pt_bisect(&S->sp, smp.points, idx, smp.n, 0, k, lo, hi, scratch, res);
        as_free(ctx, idx, (smp.n + 1) * sizeof *idx);
        as_free(ctx, scratch, (smp.n + 1) * sizeof *scratch);
        as_surface_sample_free(ctx, &smp);
    }

    /* the parts, one thread each */
    S->parts = as_alloc_array(ctx, (size_t)k, sizeof *S->parts);
    if (!S->parts) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory");
        goto done;
    }
    memset(S->parts, 0, (size_t)k * sizeof *S->parts);
    pthread_mutex_init(&S->bar.m, NULL);
    pthread_cond_init(&S->bar.c, NULL);
    S->bar.active = k;
    pthread_t th[AS_PARTITION_MAX];
    int started = 0;
    for (int i = 0; i < k; i++) {
        pt_part *P = &S->parts[i];
        P->S = S;
        P->i = i;
        P->ctx.alloc = ctx->alloc;
        P->ctx.last_status = ANISTAR_OK;
        P->prm = *prm;
        P->prm.threads = 1;
        P->prm.batch = 1; /* the hook judges one job at a time (refine.c) */
        P->prm.optimize = 0;
        P->prm.seeds = NULL;
        P->prm.nseeds = 0;
        P->hook.user = P;
        P->hook.accept = part_accept;
        P->hook.round_end = part_round_end;
        P->prm.part = &P->hook;
        P->pub_n = -1;
        P->rp = &res->part[i];
    }
    double w0 = as_now_seconds();
    for (; started < k; started++)
        if (pthread_create(&th[started], NULL, part_main, &S->parts[started]) != 0) break;
    if (started < k) {
        /* the parts that did start must not wait for the others */
        pthread_mutex_lock(&S->bar.m);
        S->parts[0].failed = 1;
        pthread_mutex_unlock(&S->bar.m);
        for (int i = started; i < k; i++) bar_leave(&S->bar);
    }
    for (int i = 0; i < started; i++) pthread_join(th[i], NULL);
    res->wall_seconds = as_now_seconds() - w0;
    pthread_mutex_destroy(&S->bar.m);
    pthread_cond_destroy(&S->bar.c);
    if (started < k) {
        s = as_fail(ctx, ANISTAR_EINTERNAL, "partition: cannot start the thread of part %d",
                    started);
        goto done;
    }
    for (int i = 0; i < k; i++)
        if (S->parts[i].st != ANISTAR_OK) {
            s = as_fail(ctx, S->parts[i].st, "partition: part %d: %s", i,
                        S->parts[i].ctx.last_error);
            goto done;
        }
    for (int i = 0; i < k; i++) {
        pt_part *P = &S->parts[i];
        if (P->rounds > res->rounds) res->rounds = P->rounds;
        res->total_seconds += P->rp->cpu_seconds;
        P->rp->sites = P->ss->n - P->ss->first_site;
        P->rp->peak_bytes = P->ctx.peak;
    }
    for (int r = 0; r < res->rounds; r++) {
        double m = 0;
        for (int i = 0; i < k; i++)
            if (r < S->parts[i].rounds && (size_t)r < S->parts[i].cap_round)
                m = fmax(m, S->parts[i].round_cpu[r]);
        res->parallel_seconds += m;
    }
    /* the last stretch of each part (after its last exchange) */
    {
        double m = 0;
        for (int i = 0; i < k; i++) {
            double sum = 0;
            for (int r = 0; r < S->parts[i].rounds && (size_t)r < S->parts[i].cap_round; r++)
                sum += S->parts[i].round_cpu[r];
            m = fmax(m, S->parts[i].rp->cpu_seconds - sum);
        }
        res->parallel_seconds += m;
    }

    /* the stitch: the owned sites, part by part in their order */
    for (int i = 0; i < k; i++) {
        const as_starset *ss = S->parts[i].ss;
        for (int32_t v = ss->first_site; v < ss->n; v++) {
            if (pt_owner(&S->sp, ss->xyz + 3 * (size_t)v) != i) continue;
            if (as_grow(ctx, (void **)&seeds, &cap_seeds, 3 * (nseeds + 1), sizeof *seeds)) {
                s = as_fail(ctx, ANISTAR_ENOMEM, "partition: out of memory (stitch)");
                goto done;
            }
            memcpy(seeds + 3 * nseeds, ss->xyz + 3 * (size_t)v, 3 * sizeof *seeds);
            nseeds++;
            res->part[i].owned++;
        }
    }
    res->union_sites = (int64_t)nseeds;
    as_mesher_params pu = *prm;
    pu.optimize = 0;
    pu.seeds = seeds;
    pu.nseeds = nseeds;
    as_part_hook none = {NULL, none_accept, none_round};
    pu.part = &none;
    s = as_mesher_run_keep(ctx, surf, field, &pu, NULL, &mu, &U);
    if (s == ANISTAR_INCOMPLETE) s = ANISTAR_OK;
    if (s != ANISTAR_OK) goto done;
    res->union_inconsistent = (int64_t)U->ninc;
    if ((s = compare_stars(ctx, S, U, res)) != ANISTAR_OK) goto done;
    as_mesh_free(mu);
    mu = NULL;
    as_starset_destroy(U);
    as_free(ctx, U, sizeof *U);
    U = NULL;

    /* the check: a run from the union, refined and certified like any other */
    pu.part = NULL;
    double c0 = as_now_seconds();
    s = as_mesher_run(ctx, surf, field, &pu, NULL, &mu);
    res->check_seconds = as_now_seconds() - c0;
    if (mu) {
        res->certified = s == ANISTAR_OK && mu->stats.complete;
        res->final_sites = (int64_t)mu->tm.nv;
        res->repairs = (int64_t)mu->stats.vertices - (int64_t)nseeds;
    }
    if (out && mu) {
        *out = mu;
        mu = NULL;
    }
done:
    if (mu) as_mesh_free(mu);
    if (U) {
        as_starset_destroy(U);
        as_free(ctx, U, sizeof *U);
    }
    as_free(ctx, seeds, cap_seeds * sizeof *seeds);
    if (S->parts) {
        for (int i = 0; i < k; i++) {
            pt_part *P = &S->parts[i];
            if (P->mesh) as_mesh_free(P->mesh);
            if (P->ss) {
                as_starset_destroy(P->ss);
                as_free(&P->ctx, P->ss, sizeof *P->ss);
            }
            buf_free(&P->ctx, &P->out);
            as_free(&P->ctx, P->req.q, P->req.cap * sizeof *P->req.q);
            as_idlist_free(&P->ctx, &P->ids);
            as_free(&P->ctx, P->again, P->cap_again * sizeof *P->again);
            as_free(&P->ctx, P->again_ret, P->cap_again_ret * sizeof *P->again_ret);
            buf_free(&P->ctx, &P->in);
            as_free(&P->ctx, P->round_cpu, P->cap_round * sizeof *P->round_cpu);
        }
        as_free(ctx, S->parts, (size_t)k * sizeof *S->parts);
    }
    as_free(ctx, S, sizeof *S);
    return s;
}
