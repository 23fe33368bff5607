/*
 * star.c — one vertex star: stretched triangulation, restricted facets, surface balls,
 * conflict-zone box (DESIGN.md 4.3-4.4, paper 3.1 and 5.3). See star.h.
 */
#include "mesher/star.h"

#include "geom/predicates.h"
#include "mesher/starset.h" /* as_sort_gid3 */

#include <math.h>
#include <string.h>

enum { TF_UNKNOWN = 0, TF_OUT = 1, TF_IN = 2, TF_STATE = 3, TF_FRESH = 4 };


void as_star_scratch_free(anistar_context *ctx, as_star_scratch *s) {
    if (s->work_init) as_del3_destroy(&s->work);
    as_del3_buf_free(ctx, &s->tets);
    as_del3_buf_free(ctx, &s->faces);
    as_free(ctx, s->old, (size_t)s->cap_old * sizeof *s->old);
    as_free(ctx, s->rf, (size_t)s->cap_rf * sizeof *s->rf);
    as_free(ctx, s->itet, (size_t)s->cap_itet * sizeof *s->itet);
    as_free(ctx, s->isph, (size_t)s->cap_isph * sizeof *s->isph);
    as_free(ctx, s->pball, (size_t)s->cap_pball * sizeof *s->pball);
    as_free(ctx, s->tflag, s->cap_tflag);
    as_free(ctx, s->fsph, s->cap_fsph * sizeof *s->fsph);
    as_free(ctx, s->sprev, (size_t)s->cap_sprev * sizeof *s->sprev);
    as_free(ctx, s->slot, (size_t)s->cap_slot * sizeof *s->slot);
    as_free(ctx, s->mside, ((size_t)1 << AS_STAR_MEMO_BITS) * sizeof *s->mside);
    as_free(ctx, s->mcross, ((size_t)1 << AS_STAR_MEMO_BITS) * sizeof *s->mcross);
    memset(s, 0, sizeof *s);
}

void as_star_init(as_star *st, anistar_context *ctx) {
    (void)ctx;
    memset(st, 0, sizeof *st);
    st->gid = -1;
    st->vloc = -1;
    st->free_head = -1;
    st->hint = -1;
}

void as_star_destroy(anistar_context *ctx, as_star *st) {
    /* everything a star owns is in its block (while open, its arrays are the scratch's) */
    as_free(ctx, st->blk, st->blk_bytes);
    memset(st, 0, sizeof *st);
}

static inline void sub3(const double a[3], const double b[3], double r[3]) {
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
static inline double dot3(const double a[3], const double b[3]) {
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2];
}
static inline void cross3(const double a[3], const double b[3], double r[3]) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}

/* Circumcenter of the triangle a, b, c in its plane; returns -1 when degenerate. */
static int tri_circumcenter(const double a[3], const double b[3], const double c[3],
                            double o[3]) {
    double u[3], v[3], w[3], t1[3];
    sub3(b, a, u);
    sub3(c, a, v);
    cross3(u, v, w);
    double w2 = dot3(w, w);
    if (!(w2 > 0) || !isfinite(w2)) return -1;
    double uu = dot3(u, u), vv = dot3(v, v);
    double s[3] = {uu * v[0] - vv * u[0], uu * v[1] - vv * u[1], uu * v[2] - vv * u[2]};
    cross3(s, w, t1);
    for (int k = 0; k < 3; k++) o[k] = a[k] + t1[k] / (2.0 * w2);
    return 0;
}

double as_radius_edge(const as_metric_frame *mf, const double a[3], const double b[3],
                      const double c[3], double *r) {
    double A[3], B[3], C[3], u[3], v[3], e[3], w[3];
    as_metric_apply(mf, a, A);
    as_metric_apply(mf, b, B);
    as_metric_apply(mf, c, C);
    sub3(B, A, u);
    sub3(C, A, v);
    sub3(C, B, e);
    double lu = sqrt(dot3(u, u)), lv = sqrt(dot3(v, v)), le = sqrt(dot3(e, e));
    cross3(u, v, w);
    double area2 = sqrt(dot3(w, w));
    double R = area2 > 0 ? lu * lv * le / (2.0 * area2) : INFINITY;
    if (r) *r = R;
    double m = lu < lv ? lu : lv;
    if (le < m) m = le;
    return m > 0 ? R / m : INFINITY;
}

static anistar_status grow_tflag(anistar_context *ctx, as_star *st) {
    size_t need = (size_t)st->d->nt;
    if (need <= st->cap_tflag) return ANISTAR_OK;
    size_t cap = st->cap_tflag ? st->cap_tflag : 32;
    while (cap < need) cap *= 2;
    uint8_t *p = as_realloc(ctx, st->tflag, st->cap_tflag, cap);
    if (!p) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star flags)");
    memset(p + st->cap_tflag, TF_FRESH, cap - st->cap_tflag);
    st->tflag = p;
    st->cap_tflag = cap;
    return ANISTAR_OK;
}

/* isph[4i+3] of an incident tet whose sphere star_update left for later (unchanged: its
 * packed ball is kept; computed here only if needed) */
#define SPH_LATER (-3.0)

static void tet_sphere(const double *const *q, const double V[3], double S[4]);

/* tet_sphere of live tet t of the open triangulation d, V its center's stored point. */
static void del3_tet_sphere(const as_del3 *d, int32_t t, const double V[3], double S[4]) {
    const int32_t *tv = as_del3_tet_vertices(d, t);
    const double *q[4];
    int inf = as_del3_is_infinite(d, t);
    for (int k = 0; k < 4 && !inf; k++) q[k] = as_del3_point(d, tv[k]);
    tet_sphere(inf ? NULL : q, V, S);
}

/* The sphere of the i-th incident tet of open star st (computed if left for later). */
static const double *inc_sphere(as_star *st, int32_t i) {
    double *S = st->isph + 4 * (size_t)i;
    if (S[3] == SPH_LATER) del3_tet_sphere(st->d, st->itet[i], as_del3_point(st->d, st->vloc), S);
    return S;
}

/* The circumcenter of tet t (stretched frame): from the spheres of the tets incident to v
 * when t is one of them (star_update computes those first: no circumcenter twice), else
 * computed. 0, or -1 for an infinite tet.
 * design: star_update's facet loop keeps sc->slot[t] = t's place in st->itet (else -1),
 * which finds the sphere without searching the list (the list holds each tet once). */
static int tet_center(const as_star_scratch *sc, as_star *st, int32_t t, double cc[3]) {
    int32_t i = t < sc->cap_slot ? sc->slot[t] : -1;
    if (i >= 0) {
        const double *S = inc_sphere(st, i);
        if (S[3] == -1) return -1;
        memcpy(cc, S, 3 * sizeof(double));
        return 0;
    }
    return as_del3_circumcenter(st->d, t, cc);
}

/* The memo's slot for the n doubles of x (a hash of their bits). */
static size_t memo_slot(const double *x, int n) {
    uint64_t h = 0x9e3779b97f4a7c15u;
    for (int i = 0; i < n; i++) {
        uint64_t b;
        memcpy(&b, x + i, sizeof b);
        h = (h ^ b) * 0xff51afd7ed558ccdu;
        h ^= h >> 32;
    }
    return (size_t)(h >> (64 - AS_STAR_MEMO_BITS));
}

/* The memo's tables of sc (allocated at the first use): 0, or -1 out of memory (then
 * the caller asks the surface: the memo is only a shortcut). */
static int memo_ready(const as_star_env *env, as_star_scratch *sc) {
    if (!env->memo) return -1;
    if (sc->mside) return 0;
    size_t n = (size_t)1 << AS_STAR_MEMO_BITS;
    sc->mside = as_alloc_array(env->ctx, n, sizeof *sc->mside);
    sc->mcross = as_alloc_array(env->ctx, n, sizeof *sc->mcross);
    if (!sc->mside || !sc->mcross) {
        as_free(env->ctx, sc->mside, n * sizeof *sc->mside);
        as_free(env->ctx, sc->mcross, n * sizeof *sc->mcross);
        sc->mside = NULL;
        sc->mcross = NULL;
        return -1;
    }
    memset(sc->mside, 0, n * sizeof *sc->mside);
    memset(sc->mcross, 0, n * sizeof *sc->mcross);
    return 0;
}

/* as_surface_side through the memo of sc (see as_star_memo). */
static anistar_status side_memo(const as_star_env *env, as_star_scratch *sc, const double x[3],
                                int *side) {
    if (memo_ready(env, sc) != 0) return as_surface_side(env->ctx, env->surf, x, side);
    as_star_memo_side *e = &sc->mside[memo_slot(x, 3)];
    if (e->side != 0 && memcmp(e->x, x, sizeof e->x) == 0) {
        *side = e->side;
        return ANISTAR_OK;
    }
    anistar_status s = as_surface_side(env->ctx, env->surf, x, side);
    if (s == ANISTAR_OK && *side != 0) {
        memcpy(e->x, x, sizeof e->x);
        e->side = *side;
    }
    return s;
}

/* The inside state of live finite tet t (cached). */
static anistar_status tet_inside(const as_star_env *env, as_star_scratch *sc, as_star *st,
                                 const as_metric_frame *mf, int32_t t, int *in) {
    uint8_t f = st->tflag[t];
    if ((f & TF_STATE) != TF_UNKNOWN) {
        *in = (f & TF_STATE) == TF_IN;
        return ANISTAR_OK;
    }
    double cc[3], x[3];
    if (tet_center(sc, st, t, cc) != 0)
        return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: infinite tet beside a star center");
    as_metric_unapply(mf, cc, x);
    int side = 1;
    if (isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2])) {
        anistar_status s = side_memo(env, sc, x, &side);
        if (s != ANISTAR_OK) return s;
    }
    *in = side < 0;
    st->tflag[t] = (uint8_t)((f & ~TF_STATE) | (*in ? TF_IN : TF_OUT));
    return ANISTAR_OK;
}

/* The crossing of [a, b] (a inside, b outside or the reverse) nearest ref; bisection on
 * the side oracle when the crossing finder misses it (it should not: the end signs
 * differ). */
static anistar_status dual_crossing_surface(const as_star_env *env, const double a[3],
                                            const double b[3], const double ref[3], double c[3]);

/* dual_crossing_surface through the memo of sc (see as_star_memo). */
static anistar_status dual_crossing(const as_star_env *env, as_star_scratch *sc, const double a[3],
                                    const double b[3], const double ref[3], double c[3]) {
    if (memo_ready(env, sc) != 0) return dual_crossing_surface(env, a, b, ref, c);
    double in[9];
    memcpy(in, a, 3 * sizeof *in);
    memcpy(in + 3, b, 3 * sizeof *in);
    memcpy(in + 6, ref, 3 * sizeof *in);
    as_star_memo_cross *e = &sc->mcross[memo_slot(in, 9)];
    if (e->used && memcmp(e->in, in, sizeof in) == 0) {
        memcpy(c, e->c, sizeof e->c);
        return ANISTAR_OK;
    }
    anistar_status s = dual_crossing_surface(env, a, b, ref, c);
    if (s == ANISTAR_OK) {
        memcpy(e->in, in, sizeof in);
        memcpy(e->c, c, sizeof e->c);
        e->used = 1;
    }
    return s;
}

static anistar_status dual_crossing_surface(const as_star_env *env, const double a[3],
                                            const double b[3], const double ref[3], double c[3]) {
    int found = 0;
    anistar_status s = as_surface_crossing(env->ctx, env->surf, a, b, ref, &found, c);
    if (s != ANISTAR_OK) return s;
    if (found) return ANISTAR_OK;
    /* design: fallback bisection keeps the invariant side(lo) != side(hi). */
    double lo[3] = {a[0], a[1], a[2]}, hi[3] = {b[0], b[1], b[2]};
    int slo = 1;
    s = as_surface_side(env->ctx, env->surf, lo, &slo);
    if (s != ANISTAR_OK) return s;
    for (int it = 0; it < 200; it++) {
        double m[3] = {0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), 0.5 * (lo[2] + hi[2])};
        if ((m[0] == lo[0] || m[0] == hi[0]) && (m[1] == lo[1] || m[1] == hi[1]) &&
            (m[2] == lo[2] || m[2] == hi[2]))
            break;
        int sm = 1;
        s = as_surface_side(env->ctx, env->surf, m, &sm);
        if (s != ANISTAR_OK) return s;
        if ((sm < 0) == (slo < 0)) memcpy(lo, m, sizeof m);
        else memcpy(hi, m, sizeof m);
    }
    for (int k = 0; k < 3; k++) c[k] = 0.5 * (lo[k] + hi[k]);
    return ANISTAR_OK;
}

static int cmp_g(const as_gid a[3], const as_gid b[3]) {
    for (int k = 0; k < 3; k++)
        if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
    return 0;
}

int32_t as_star_find(const as_star *st, const as_gid g[3]) {
    int32_t lo = 0, hi = st->nrf;
    while (lo < hi) {
        int32_t mid = (lo + hi) / 2;
        int c = cmp_g(st->rf[mid].g, g);
        if (c == 0) return mid;
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

static int32_t find_in(const as_rfacet *rf, int32_t n, const as_gid g[3]) {
    int32_t lo = 0, hi = n;
    while (lo < hi) {
        int32_t mid = (lo + hi) / 2;
        int c = cmp_g(rf[mid].g, g);
        if (c == 0) return mid;
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

/* The link vertex occurrences of as_star_fan_closed's fast path: a vertex and a facet. */
typedef struct fan_occ {
    as_gid x;
    int32_t i;
} fan_occ;

/* Stars with at most this many facets take the sorted path of as_star_fan_closed. */
#define FAN_FAST 48

int as_star_fan_closed(const as_rfacet *rf, int32_t n, int32_t v) {
    if (n < 3) return 0;
    /* design: the link of v is a graph on the other vertices with one edge per facet; it
     * is one cycle iff every vertex has degree 2 and a walk from facet 0 visits all n.
     * Up to FAN_FAST facets (nearly every star): the 2n link-vertex occurrences sorted
     * (insertion sort), degrees read off the runs, each facet's two neighbours from the
     * pairs, then the walk: O(n^2) compares at worst in the sort instead of 18 n^2 and a
     * quadratic walk (the star update's 1.4% of the torus). Beyond, the scans below. */
    if (n <= FAN_FAST) {
        fan_occ occ[2 * FAN_FAST];
        int32_t nb[2 * FAN_FAST]; /* per facet i: its neighbours through its two link vertices */
        as_gid lk[2 * FAN_FAST];  /* per facet i: its two link vertices */
        for (int32_t i = 0; i < n; i++) {
            int m = 0;
            for (int k = 0; k < 3; k++) {
                if (rf[i].g[k] == v) continue;
                if (m == 2) return 0; /* v not in the facet */
                lk[2 * i + m++] = rf[i].g[k];
            }
            if (m != 2) return 0;
        }
        for (int32_t e = 0; e < 2 * n; e++) {
            fan_occ o = {lk[e], e / 2};
            int32_t j = e;
            while (j > 0 && (occ[j - 1].x > o.x || (occ[j - 1].x == o.x && occ[j - 1].i > o.i))) {
                occ[j] = occ[j - 1];
                j--;
            }
            occ[j] = o;
        }
        for (int32_t e = 0; e < 2 * n; e += 2) {
            if (occ[e + 1].x != occ[e].x) return 0;                   /* degree 1 */
            if (e + 2 < 2 * n && occ[e + 2].x == occ[e].x) return 0;  /* degree 3 or more */
            const int32_t a = occ[e].i, b = occ[e + 1].i;
            nb[2 * a + (lk[2 * a] == occ[e].x ? 0 : 1)] = b;
            nb[2 * b + (lk[2 * b] == occ[e].x ? 0 : 1)] = a;
        }
        /* the walk: from facet 0 out through its second link vertex */
        int32_t cur = 0, steps = 0;
        as_gid at = lk[1];
        for (;;) {
            steps++;
            const int32_t next = nb[2 * cur + (lk[2 * cur] == at ? 0 : 1)];
            if (next == 0) break;
            at = lk[2 * next] == at ? lk[2 * next + 1] : lk[2 * next];
            cur = next;
            if (steps > n) return 0;
        }
        return steps == n;
    }
    int32_t cur = 0, prev_vertex = -1, steps = 0;
    int32_t a0 = -1, b0 = -1;
    for (int k = 0; k < 3; k++) {
        if (rf[0].g[k] == v) continue;
        if (a0 < 0) a0 = rf[0].g[k];
        else b0 = rf[0].g[k];
    }
    if (a0 < 0 || b0 < 0) return 0;
    for (int32_t i = 0; i < n; i++) {
        int has_v = 0;
        for (int k = 0; k < 3; k++) has_v |= rf[i].g[k] == v;
        if (!has_v) return 0;
    }
    /* degree check */
    for (int32_t i = 0; i < n; i++) {
        for (int k = 0; k < 3; k++) {
            int32_t x = rf[i].g[k];
            if (x == v) continue;
            int deg = 0;
            for (int32_t j = 0; j < n; j++)
                for (int l = 0; l < 3; l++) deg += rf[j].g[l] == x;
            if (deg != 2) return 0;
        }
    }
    prev_vertex = a0;
    int32_t at = b0; /* walk: from facet cur leave through vertex `at` */
    for (;;) {
        steps++;
        int32_t next = -1;
        for (int32_t j = 0; j < n && next < 0; j++) {
            if (j == cur) continue;
            for (int l = 0; l < 3; l++)
                if (rf[j].g[l] == at) next = j;
        }
        if (next < 0) return 0;
        if (next == 0) break;
        int32_t other = -1;
        for (int l = 0; l < 3; l++)
            if (rf[next].g[l] != v && rf[next].g[l] != at) other = rf[next].g[l];
        cur = next;
        prev_vertex = at;
        at = other;
        if (steps > n) return 0;
    }
    (void)prev_vertex;
    return steps == n;
}

static anistar_status grow_rf(anistar_context *ctx, as_rfacet **p, int32_t *cap, int32_t need) {
    if (need <= *cap) return ANISTAR_OK;
    size_t c = (size_t)*cap;
    if (as_grow(ctx, (void **)p, &c, (size_t)need, sizeof **p))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (restricted facets)");
    *cap = (int32_t)c;
    return ANISTAR_OK;
}

static anistar_status grow_i32(anistar_context *ctx, int32_t **p, int32_t *cap, int32_t need) {
    if (need <= *cap) return ANISTAR_OK;
    size_t c = (size_t)*cap;
    if (as_grow(ctx, (void **)p, &c, (size_t)need, sizeof **p))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    *cap = (int32_t)c;
    return ANISTAR_OK;
}

static anistar_status grow_dbl(anistar_context *ctx, double **a, int32_t *cap, int32_t need) {
    if (need <= *cap) return ANISTAR_OK;
    size_t c = (size_t)*cap;
    if (as_grow(ctx, (void **)a, &c, (size_t)need, sizeof **a))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    *cap = (int32_t)c;
    return ANISTAR_OK;
}

static void box_add(double lo[3], double hi[3], const double c[3], const double h[3]) {
    for (int k = 0; k < 3; k++) {
        double a = c[k] - h[k], b = c[k] + h[k];
        if (a < lo[k]) lo[k] = a;
        if (b > hi[k]) hi[k] = b;
    }
}

/* The cached sphere of a tet incident to v whose stored points are q (q NULL: an infinite
 * tet), V v's stored point: star_update and as_star_sphere, the same arithmetic. */
static void tet_sphere(const double *const *q, const double V[3], double S[4]) {
    if (!q) {
        S[0] = S[1] = S[2] = 0;
        S[3] = -1;
        return;
    }
    as_del3_circumcenter_points(q[0], q[1], q[2], q[3], S);
    double dd[3];
    sub3(S, V, dd);
    double R = sqrt(dot3(dd, dd)) * (1 + 1e-9);
    S[3] = isfinite(R) ? R * R : -2; /* -2: a center, no usable bound */
}

/* The box of the conflict zone (see as_star_rezone in star.h). */
void as_star_rezone(as_star *st, const double *xyz, const as_metric_frame *mf) {
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    const double *V = st->d ? as_del3_point(st->d, st->vloc) : st->fv;
    if (AS_STAR_BALL_ZONE(st)) {
        /* design: the surface balls in the stretched frame, and one ball around F_v v
         * holding them all, so that most candidates are rejected by one distance */
        double zr = 0;
        for (int32_t i = 0; i < st->nrf; i++) {
            double z[4], dd[3];
            as_star_zone_ball(mf, &st->rf[i], z);
            sub3(z, V, dd);
            double e = sqrt(dot3(dd, dd)) + z[3];
            if (e > zr) zr = e;
        }
        zr *= 1 + 4 * AS_STAR_SLACK;
        st->zr2 = zr * zr;
        double n[3]; /* design: the frame's unit extents once (as_metric_box_axes) */
        as_metric_box_axes(mf, n);
        for (int32_t i = 0; i < st->nrf; i++) {
            const double r = st->rf[i].r * AS_STAR_ZONE_INFLATE * (1 + AS_STAR_SLACK);
            const double h[3] = {r * n[0], r * n[1], r * n[2]};
            box_add(lo, hi, st->rf[i].c, h);
        }
    } else {
        double n[3];
        as_metric_box_axes(mf, n);
        for (int32_t k = 0; k < st->nitet; k++) {
            double S[4], x[3], dd[3];
            /* open: the update's spheres; packed: recomputed (the same numbers) */
            if (st->d)
                memcpy(S, inc_sphere(st, k), sizeof S);
            else
                as_star_sphere(st, xyz, mf, k, S);
            if (S[3] == -1) continue; /* infinite */
            sub3(S, V, dd);
            double R = sqrt(dot3(dd, dd));
            as_metric_unapply(mf, S, x);
            const double r = R * (1 + AS_STAR_SLACK), h[3] = {r * n[0], r * n[1], r * n[2]};
            box_add(lo, hi, x, h);
        }
    }
    for (int k = 0; k < 3; k++) {
        double pad = AS_STAR_SLACK * (fabs(lo[k]) + fabs(hi[k]) + (hi[k] - lo[k]));
        st->lo[k] = lo[k] - pad;
        st->hi[k] = hi[k] + pad;
    }
}

/* star_update's restricted facets: of the facets around v (sc->faces), those whose two
 * tets differ in inside state, each kept from sc->old when its tets are not fresh, else
 * computed (dual segment crossing, radius). sc->slot maps st->itet (see tet_center). */
static anistar_status update_facets(const as_star_env *env, as_star *st,
                                    const as_metric_frame *mf, as_star_scratch *sc) {
    anistar_context *ctx = env->ctx;
    anistar_status s;
    const as_del3 *d = st->d;
    const double *vx = as_star_xyz(st, env->xyz, st->gid);
    for (size_t k = 0; k < sc->faces.n; k++) {
        int32_t face = sc->faces.a[k];
        int32_t t1 = face >> 2, t2 = as_del3_mirror(d, face) >> 2;
        /* design: the cached states read here (most are known: a call per side cost more
         * than the lookup) */
        const unsigned f1 = st->tflag[t1] & TF_STATE, f2 = st->tflag[t2] & TF_STATE;
        int in1 = f1 == TF_IN, in2 = f2 == TF_IN;
        if (f1 == TF_UNKNOWN && (s = tet_inside(env, sc, st, mf, t1, &in1)) != ANISTAR_OK)
            return s;
        if (f2 == TF_UNKNOWN && (s = tet_inside(env, sc, st, mf, t2, &in2)) != ANISTAR_OK)
            return s;
        if (in1 == in2) continue;
        as_gid g[3];
        int32_t lv[3], n = 0;
        for (int j = 0; j < 4; j++) {
            if (j == (face & 3)) continue;
            lv[n] = as_del3_tet_vertex(d, t1, j);
            g[n] = (as_gid)d->gid[lv[n]];
            n++;
        }
        as_sort_gid3(g);
        if ((s = grow_rf(ctx, &st->rf, &st->cap_rf, st->nrf + 1)) != ANISTAR_OK) return s;
        as_rfacet *f = &st->rf[st->nrf++];
        int fresh = ((st->tflag[t1] | st->tflag[t2]) & TF_FRESH) != 0;
        int32_t o = fresh ? -1 : find_in(sc->old, sc->nold, g);
        if (o >= 0) {
            *f = sc->old[o];
            f->fresh = 0;
            continue;
        }
        memset(f, 0, sizeof *f);
        memcpy(f->g, g, sizeof g);
        f->fresh = 1;
        if (sc->probe) { /* the triple is all a probe asks: no crossing, no radius */
            memcpy(f->c, vx, sizeof f->c);
            continue;
        }
        /* design: dual segment between the two mapped circumcenters; the crossing nearest
         * the facet's own circumcenter (DESIGN.md 4.4). */
        double cc1[3], cc2[3], a[3], b[3], fcs[3], fc[3];
        if (tet_center(sc, st, t1, cc1) || tet_center(sc, st, t2, cc2))
            return as_fail(ctx, ANISTAR_EINTERNAL, "mesher: infinite tet beside a star center");
        as_metric_unapply(mf, cc1, a);
        as_metric_unapply(mf, cc2, b);
        if (tri_circumcenter(as_del3_point(d, lv[0]), as_del3_point(d, lv[1]),
                             as_del3_point(d, lv[2]), fcs) == 0)
            as_metric_unapply(mf, fcs, fc);
        else
            for (int q = 0; q < 3; q++) fc[q] = 0.5 * (a[q] + b[q]);
        if ((s = dual_crossing(env, sc, a, b, fc, f->c)) != ANISTAR_OK) return s;
        f->r = as_metric_dist(mf, f->c, vx);
    }
    return ANISTAR_OK;
}

/* Recompute restricted facets, closed flag and box after the del3 changed. */
static anistar_status star_update(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                  as_star_scratch *sc) {
    anistar_context *ctx = env->ctx;
    anistar_status s;
    st->version++;
    /* keep the old facets for center reuse and for the caller's diff */
    if ((s = grow_rf(ctx, &sc->old, &sc->cap_old, st->nrf)) != ANISTAR_OK) return s;
    if (st->nrf) memcpy(sc->old, st->rf, (size_t)st->nrf * sizeof *st->rf);
    sc->nold = st->nrf;
    st->nrf = 0;

    /* the tets incident to v, and the facets around v (one walk) */
    if ((s = as_del3_vertex_tets_facets(st->d, st->vloc, &sc->tets, &sc->faces)) !=
        ANISTAR_OK)
        return s;
    const int32_t nprev = st->nitet, nnew = (int32_t)sc->tets.n;
    if ((s = grow_dbl(ctx, &st->isph, &st->cap_isph, 4 * nnew)) != ANISTAR_OK) return s;
    if ((s = grow_i32(ctx, &st->itet, &st->cap_itet, nnew)) != ANISTAR_OK) return s;
    if ((s = grow_i32(ctx, &sc->sprev, &sc->cap_sprev, nnew)) != ANISTAR_OK) return s;
    if (st->d->nt > sc->cap_slot) {
        int32_t c0 = sc->cap_slot;
        if ((s = grow_i32(ctx, &sc->slot, &sc->cap_slot, st->d->nt)) != ANISTAR_OK) return s;
        for (int32_t t = c0; t < sc->cap_slot; t++) sc->slot[t] = -1;
    }
    /* design: cached circumspheres. as_del3_circumcenter is within 2^-40 R of the true
     * center c* (R the true radius); with R' = |c - v| the computed radius,
     * |y - c*| >= |y - c| - 2^-40 R and R <= R' + 2^-40 R, so |y - c| > R'(1 + 1e-9) (with
     * the rounding of these few operations far below the 1e-9 margin) proves y strictly
     * outside the true sphere: not in conflict, whatever the perturbation. A packed star
     * keeps only float balls around them (star_close): a tet that is not fresh is
     * unchanged since the last update, its ball is kept (sc->sprev: its place in the
     * previous list) and its sphere computed only if needed (inc_sphere). */
    const int defer = !sc->sph_fresh; /* the previous balls are those of sc->fsph */
    if (defer)
        for (int32_t i = 0; i < nprev; i++)
            if (st->itet[i] < sc->cap_slot) sc->slot[st->itet[i]] = i;
    {
        const as_del3 *d = st->d;
        const double *V = as_del3_point(d, st->vloc);
        for (int32_t i = 0; i < nnew; i++) {
            int32_t t = sc->tets.a[i];
            int32_t j = defer ? sc->slot[t] : -1;
            sc->sprev[i] = j;
            if (j >= 0 && !(st->tflag[t] & TF_FRESH)) {
                st->isph[4 * (size_t)i + 3] = SPH_LATER;
                continue;
            }
            sc->sprev[i] = -1;
            del3_tet_sphere(d, t, V, st->isph + 4 * (size_t)i);
        }
    }
    if (defer)
        for (int32_t i = 0; i < nprev; i++)
            if (st->itet[i] < sc->cap_slot) sc->slot[st->itet[i]] = -1;
    sc->sph_fresh = 1;
    memcpy(st->itet, sc->tets.a, (size_t)nnew * sizeof *st->itet);
    st->nitet = nnew;
    for (int32_t i = 0; i < nnew; i++) sc->slot[st->itet[i]] = i; /* for tet_center */
    s = update_facets(env, st, mf, sc);
    for (int32_t i = 0; i < nnew; i++) sc->slot[st->itet[i]] = -1;
    if (s != ANISTAR_OK) return s;
    const as_del3 *d = st->d;
    /* sort by triple (insertion sort: tens of facets) */
    for (int32_t i = 1; i < st->nrf; i++) {
        as_rfacet x = st->rf[i];
        int32_t j = i - 1;
        while (j >= 0 && cmp_g(st->rf[j].g, x.g) > 0) {
            st->rf[j + 1] = st->rf[j];
            j--;
        }
        st->rf[j + 1] = x;
    }
    /* a probe asks only for the triples: its copy of the star is dropped */
    if (!sc->probe) {
        st->closed = as_star_fan_closed(st->rf, st->nrf, st->gid);
        as_star_rezone(st, env->xyz, mf);
    }
    /* the fresh marks served this update (design: eight flags per step) */
    size_t nt = (size_t)d->nt, t = 0;
    for (; t + 8 <= nt; t += 8) {
        uint64_t w;
        memcpy(&w, st->tflag + t, sizeof w);
        w &= ~(UINT64_C(0x0101010101010101) * TF_FRESH);
        memcpy(st->tflag + t, &w, sizeof w);
    }
    for (; t < nt; t++) st->tflag[t] &= (uint8_t)~TF_FRESH;
    return ANISTAR_OK;
}


/* ---- packing (see star.h) ---------------------------------------------------------- */

/* Grow a scratch array to n elements (its contents need not survive). 0 or -1. */
static int scratch_fit(anistar_context *ctx, void **p, size_t *cap, size_t n, size_t elem) {
    return n > *cap ? as_grow(ctx, p, cap, n, elem) : 0;
}
static int scratch_fit32(anistar_context *ctx, void **p, int32_t *cap, size_t n, size_t elem) {
    size_t c = (size_t)*cap;
    if (scratch_fit(ctx, p, &c, n, elem)) return -1;
    *cap = (int32_t)c;
    return 0;
}

/* tiny_handle[h]: the del3 handle 8t'+j of the tiny record's 10-bit field h = 4t'+j
 * (design: one load per handle when unpacking, instead of masking and adding) */
#define TH1(h) ((int32_t)((h) + ((h) & ~3)))
#define TH4(h) TH1(h), TH1((h) + 1), TH1((h) + 2), TH1((h) + 3)
#define TH16(h) TH4(h), TH4((h) + 4), TH4((h) + 8), TH4((h) + 12)
#define TH64(h) TH16(h), TH16((h) + 16), TH16((h) + 32), TH16((h) + 48)
#define TH256(h) TH64(h), TH64((h) + 64), TH64((h) + 128), TH64((h) + 192)
static const int32_t tiny_handle[1024] = {TH256(0), TH256(256), TH256(512), TH256(768)};
#undef TH256
#undef TH64
#undef TH16
#undef TH4
#undef TH1

/* The packed record formats of a star's tets (see star.h): their sizes in bytes. */
enum { FMT_WIDE = 0, FMT_NARROW = 1, FMT_TINY = 2 };
static const size_t fmt_tet_bytes[3] = {8 * sizeof(int32_t), 12, 8};
static const size_t fmt_vtet_bytes[3] = {sizeof(int32_t), sizeof(uint16_t), sizeof(uint8_t)};

/* The format for nv vertices and nt tet slots: the smallest whose fields hold every value
 * (vertices -2 .. nv-1, handles 8t+j < 8 nt, free links and incident tets -1 .. nt-1). */
static int star_fmt(int32_t nv, int32_t nt) {
    if (nv <= AS_STAR_TINY_NV && nt <= AS_STAR_TINY_NT) return FMT_TINY;
    if (nv <= AS_STAR_NARROW_NV && nt <= AS_STAR_NARROW_NT) return FMT_NARROW;
    return FMT_WIDE;
}

/* Tet slot t of packed star st as del3's record r[8] (a free slot: r[0] DEAD, r[1] its
 * link, the rest 0). */
static inline void tet_get(const as_star *st, int32_t t, int32_t r[8]) {
    if (st->fmt == FMT_TINY) {
        uint64_t w = ((const uint64_t *)st->trec)[t];
        if ((w & 63) == 0) {
            r[0] = AS_DEL3_DEAD;
            r[1] = (int32_t)((w >> 24) & 1023) - 1;
            r[2] = r[3] = r[4] = r[5] = r[6] = r[7] = 0;
            return;
        }
        for (int i = 0; i < 4; i++) {
            r[i] = (int32_t)((w >> (6 * i)) & 63) - 2;
            uint32_t h = (uint32_t)(w >> (24 + 10 * i)) & 1023;
            r[4 + i] = (int32_t)(((h >> 2) << 3) | (h & 3));
        }
    } else if (st->fmt == FMT_NARROW) {
        const uint16_t *ht = (const uint16_t *)st->trec + 4 * (size_t)t;
        const uint8_t *vt = (const uint8_t *)((const uint16_t *)st->trec + 4 * (size_t)st->nt) +
                            4 * (size_t)t;
        if (vt[0] == 0) {
            r[0] = AS_DEL3_DEAD;
            r[1] = (int32_t)ht[0] - 1;
            r[2] = r[3] = r[4] = r[5] = r[6] = r[7] = 0;
            return;
        }
        for (int i = 0; i < 4; i++) {
            r[i] = (int32_t)vt[i] - 2;
            r[4 + i] = ht[i];
        }
    } else {
        memcpy(r, (const int32_t *)st->trec + 8 * (size_t)t, 8 * sizeof *r);
    }
}

/* Store del3's record r[8] as slot t of the packed arrays trec (format fmt, nt slots). */
static inline void tet_put(void *trec, int fmt, int32_t nt, int32_t t, const int32_t r[8]) {
    int dead = r[0] == AS_DEL3_DEAD;
    if (fmt == FMT_TINY) {
        uint64_t w = 0;
        if (dead) {
            w = (uint64_t)(uint32_t)(r[1] + 1) << 24;
        } else {
            for (int i = 0; i < 4; i++) {
                uint32_t h = ((uint32_t)r[4 + i] >> 3 << 2) | ((uint32_t)r[4 + i] & 3);
                w |= (uint64_t)(uint32_t)(r[i] + 2) << (6 * i);
                w |= (uint64_t)h << (24 + 10 * i);
            }
        }
        ((uint64_t *)trec)[t] = w;
    } else if (fmt == FMT_NARROW) {
        uint16_t *ht = (uint16_t *)trec + 4 * (size_t)t;
        uint8_t *vt = (uint8_t *)((uint16_t *)trec + 4 * (size_t)nt) + 4 * (size_t)t;
        if (dead) {
            vt[0] = vt[1] = vt[2] = vt[3] = 0;
            ht[0] = (uint16_t)(r[1] + 1);
            ht[1] = ht[2] = ht[3] = 0;
            return;
        }
        for (int i = 0; i < 4; i++) {
            vt[i] = (uint8_t)(r[i] + 2);
            ht[i] = (uint16_t)r[4 + i];
        }
    } else {
        memcpy((int32_t *)trec + 8 * (size_t)t, r, 8 * sizeof *r);
    }
}

/* The incident tet of vertex k of packed star st. */
static inline int32_t vtet_get(const as_star *st, int32_t k) {
    switch (st->fmt) {
    case FMT_TINY: return (int32_t)((const uint8_t *)st->vtet)[k] - 1;
    case FMT_NARROW: return (int32_t)((const uint16_t *)st->vtet)[k] - 1;
    default: return ((const int32_t *)st->vtet)[k];
    }
}

/*
 * Unpack star st into the owner's working triangulation sc->work and lend it the working
 * arrays of sc (its facets, incident tets, spheres and flags copied in): st->d is set.
 * unpack 0: the triangulation is left empty (the caller builds it anew).
 * design: the work is reset, then given st's vertex and tet records exactly as del3 left
 * them (slot numbers, free list, hints, random state: a packed star continues as if it had
 * never been packed); the visit marks are 0 between operations. ANISTAR_OK or ENOMEM (st
 * unchanged, still packed).
 */
static anistar_status star_open(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                as_star_scratch *sc, int unpack) {
    anistar_context *ctx = env->ctx;
    if (!sc->work_init) {
        as_del3_init(&sc->work, ctx);
        sc->work.no_sphere_cache = 1; /* design: isph filters the conflict tests (memory) */
        sc->work_init = 1;
    }
    as_del3 *d = &sc->work;
    const int32_t nv = unpack ? st->nv : 0, nt = unpack ? st->nt : 0;
    /* the work still holds st as this scratch packed it (as_star_scratch, work_star) */
    const int kept = unpack && nv && sc->work_star == st && st->pack_sc == (const void *)sc &&
                     st->pack_serial == sc->serial && d->nv == nv && d->nt == nt &&
                     env->xyz == sc->work_xyz && st->ovr == sc->work_ovr &&
                     (!st->ovr || (st->ovr->gid == sc->work_ovr_copy.gid &&
                                   memcmp(st->ovr->p, sc->work_ovr_copy.p,
                                          sizeof st->ovr->p) == 0)) &&
                     memcmp(mf->f, sc->work_f, sizeof sc->work_f) == 0;
    sc->work_star = NULL; /* the work changes from here on; the points it will hold: */
    memcpy(sc->work_f, mf->f, sizeof sc->work_f);
    sc->work_xyz = env->xyz;
    sc->work_ovr = st->ovr;
    if (st->ovr) {
        sc->work_ovr_copy.gid = st->ovr->gid;
        memcpy(sc->work_ovr_copy.p, st->ovr->p, sizeof sc->work_ovr_copy.p);
    }
    if (scratch_fit32(ctx, (void **)&sc->rf, &sc->cap_rf, (size_t)st->nrf, sizeof *sc->rf) ||
        scratch_fit32(ctx, (void **)&sc->itet, &sc->cap_itet, (size_t)st->nitet,
                      sizeof *sc->itet) ||
        scratch_fit(ctx, (void **)&sc->fsph, &sc->cap_fsph, 4 * (size_t)st->nitet,
                    sizeof *sc->fsph) ||
        scratch_fit(ctx, (void **)&sc->tflag, &sc->cap_tflag, (size_t)nt, 1) ||
        (nv && !kept && as_del3_reserve(d, nv, nt) != ANISTAR_OK))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    if (kept) {
        /* what unpacking would write and an operation may have changed since */
        d->boot[0] = d->boot[1] = d->boot[2] = -1;
        d->removed.n = d->created.n = 0;
        d->rebuilt = 0;
        memset(&d->stats, 0, sizeof d->stats);
        d->hint = st->hint;
        d->rng = st->rng;
    } else {
        as_del3_reset(d);
    }
    if (st->nrf) memcpy(sc->rf, st->rf, (size_t)st->nrf * sizeof *sc->rf);
    if (st->nitet) {
        memcpy(sc->itet, st->itet, (size_t)st->nitet * sizeof *sc->itet);
        memcpy(sc->fsph, st->fsph, 4 * (size_t)st->nitet * sizeof *sc->fsph);
    }
    if (nt) memcpy(sc->tflag, st->tflag, (size_t)nt);
    if (nv && !kept) {
        /* the vertices: as_star_point and vtet_get, their branches taken once */
        as_del3_vertex *vert = d->vert;
        const as_gid *vg = st->vgid;
        if (st->vx)
            for (int32_t k = 0; k < nv; k++)
                memcpy(vert[k].x, st->vx + 3 * (size_t)k, sizeof vert[k].x);
        else
            for (int32_t k = 0; k < nv; k++)
                as_metric_apply(mf, as_star_xyz(st, env->xyz, vg[k]), vert[k].x);
        if (st->fmt == FMT_TINY)
            for (int32_t k = 0; k < nv; k++)
                vert[k].tet = (int32_t)((const uint8_t *)st->vtet)[k] - 1;
        else
            for (int32_t k = 0; k < nv; k++) vert[k].tet = vtet_get(st, k);
        for (int32_t k = 0; k < nv; k++) {
            vert[k].loc = -1;
            d->gid[k] = vg[k];
        }
        if (st->fmt == FMT_TINY) { /* the common case, unrolled */
            const uint64_t *w = st->trec;
            for (int32_t t = 0; t < nt; t++) {
                int32_t *r = d->tet + 8 * (size_t)t;
                uint64_t x = w[t];
                if ((x & 63) == 0) {
                    tet_get(st, t, r);
                    continue;
                }
                r[0] = (int32_t)(x & 63) - 2;
                r[1] = (int32_t)((x >> 6) & 63) - 2;
                r[2] = (int32_t)((x >> 12) & 63) - 2;
                r[3] = (int32_t)((x >> 18) & 63) - 2;
                /* handle 4t'+j (10 bits) -> 8t'+j (tiny_handle) */
                r[4] = tiny_handle[(x >> 24) & 1023];
                r[5] = tiny_handle[(x >> 34) & 1023];
                r[6] = tiny_handle[(x >> 44) & 1023];
                r[7] = tiny_handle[x >> 54];
            }
        } else if (st->fmt == FMT_NARROW) {
            const uint16_t *h = st->trec;
            const uint8_t *vb = (const uint8_t *)(h + 4 * (size_t)nt);
            for (int32_t t = 0; t < nt; t++) {
                int32_t *r = d->tet + 8 * (size_t)t;
                const uint16_t *ht = h + 4 * (size_t)t;
                const uint8_t *vt = vb + 4 * (size_t)t;
                if (vt[0] == 0) {
                    tet_get(st, t, r);
                    continue;
                }
                r[0] = (int32_t)vt[0] - 2;
                r[1] = (int32_t)vt[1] - 2;
                r[2] = (int32_t)vt[2] - 2;
                r[3] = (int32_t)vt[3] - 2;
                r[4] = ht[0];
                r[5] = ht[1];
                r[6] = ht[2];
                r[7] = ht[3];
            }
        } else {
            memcpy(d->tet, st->trec, 8 * (size_t)nt * sizeof *d->tet);
        }
        memset(d->mark, 0, (size_t)nt);
        d->nv = nv;
        d->nt = nt;
        d->nlive = st->nlive;
        d->free_head = st->free_head;
        d->dim3 = nt > 0;
        d->hint = st->hint;
        d->rng = st->rng;
    }
    st->rf = sc->rf;
    st->cap_rf = sc->cap_rf;
    st->itet = sc->itet;
    st->cap_itet = sc->cap_itet;
    st->isph = sc->isph;
    st->cap_isph = sc->cap_isph;
    sc->sph_fresh = 0;
    st->tflag = sc->tflag;
    st->cap_tflag = sc->cap_tflag;
    st->d = d;
    return ANISTAR_OK;
}

static size_t up8(size_t n) { return (n + 7) & ~(size_t)7; }

/*
 * The float ball f of a packed star around the sphere S of an update (star.h, fsph), its
 * center relative to V = F_v v (a vertex of the tet: |S - V| is the radius, so the float
 * rounding is relative to the radius, not to the coordinates).
 * design: D = S - V in double (error below 2^-53 |D|), c_f = (float) D per coordinate,
 * e = |D - c_f| bounded by its L1 norm plus 2^-52 |D|_1, radius sqrt(S[3]) + e, times
 * 1 + 2e-6 before the rounding to a float (which loses at most 2^-24 relative): r_f
 * exceeds |S - V - c_f| + sqrt(S[3]) by a relative 1e-6 at least, far above the roundings
 * of the test (y - V, then - c_f: below 1e-15 of the radius where it matters). Then
 * |(y - V) - c_f| > r_f proves |y - S| > sqrt(S[3]): outside, as the double filter proved.
 * No ball (-1) where S has no bound or does not fit a float.
 */
static void sphere_ball(const double S[4], const double V[3], float f[4]) {
    f[0] = f[1] = f[2] = 0;
    f[3] = -1;
    if (!(S[3] >= 0)) return;
    double e1 = 0;
    float c[3];
    for (int k = 0; k < 3; k++) {
        double D = S[k] - V[k];
        c[k] = (float)D;
        if (!isfinite(c[k])) return;
        e1 += fabs(D - (double)c[k]) + fabs(D) * 0x1p-52;
    }
    float fb = (float)((sqrt(S[3]) + e1) * (1 + 2e-6));
    if (!isfinite(fb)) return;
    f[0] = c[0];
    f[1] = c[1];
    f[2] = c[2];
    f[3] = fb;
}

/*
 * Pack star st (open: st->d) into a new block of the exact size, give the working arrays
 * back to sc, free the old block. ANISTAR_OK; ENOMEM leaves the star empty (no vertices,
 * no facets: the run ends with the error). st->d is NULL after either.
 */
static anistar_status star_close(const as_star_env *env, as_star *st, as_star_scratch *sc) {
    anistar_context *ctx = env->ctx;
    as_del3 *d = st->d;
    /* the working arrays go back to the scratch (they may have grown) */
    sc->rf = st->rf;
    sc->cap_rf = st->cap_rf;
    sc->itet = st->itet;
    sc->cap_itet = st->cap_itet;
    sc->isph = st->isph;
    sc->cap_isph = st->cap_isph;
    sc->tflag = st->tflag;
    sc->cap_tflag = st->cap_tflag;
    st->d = NULL;
    const int32_t nv = d->nv, nt = d->nt;
    const size_t nrf = (size_t)st->nrf, nit = (size_t)st->nitet;
    const int fmt = star_fmt(nv, nt);
    const int keep = env->keep_points;
    /* design: one block, the 8-byte arrays first */
    size_t o_vx = nrf * sizeof(as_rfacet);
    size_t o_isph = o_vx + (keep ? 3 * (size_t)nv * sizeof(double) : 0);
    size_t o_fsph = up8(o_isph);
    size_t o_gid = up8(o_fsph + 4 * nit * sizeof(float));
    size_t o_itet = up8(o_gid + (size_t)nv * sizeof(as_gid));
    size_t o_vtet = o_itet + nit * sizeof(int32_t);
    size_t o_trec = up8(o_vtet + (size_t)nv * fmt_vtet_bytes[fmt]);
    size_t o_tflag = o_trec + (size_t)nt * fmt_tet_bytes[fmt];
    size_t bytes = o_tflag + (size_t)nt;
    char *blk = bytes ? as_alloc(ctx, bytes) : NULL;
    if (bytes && !blk) {
        as_free(ctx, st->blk, st->blk_bytes);
        st->blk = NULL;
        st->blk_bytes = 0;
        st->nv = st->nt = st->nlive = st->nrf = st->nitet = 0;
        st->cap_rf = st->cap_itet = st->cap_isph = 0;
        st->fsph = NULL;
        st->cap_tflag = 0;
        st->rf = NULL;
        st->itet = NULL;
        st->isph = st->vx = NULL;
        st->vgid = NULL;
        st->vtet = st->trec = NULL;
        st->tflag = NULL;
        st->closed = 0;
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    }
    as_rfacet *rf = (as_rfacet *)(void *)blk;
    double *vx = (double *)(void *)(blk + o_vx);
    float *fsph = (float *)(void *)(blk + o_fsph);
    as_gid *vgid = (as_gid *)(void *)(blk + o_gid);
    int32_t *itet = (int32_t *)(void *)(blk + o_itet);
    void *vtet = blk + o_vtet, *trec = blk + o_trec;
    uint8_t *tflag = (uint8_t *)(blk + o_tflag);
    if (nrf) memcpy(rf, st->rf, nrf * sizeof *rf);
    if (nit) {
        memcpy(itet, st->itet, nit * sizeof *itet);
        if (sc->sph_fresh) {
            for (size_t i = 0; i < nit; i++) {
                if (st->isph[4 * i + 3] == SPH_LATER)
                    memcpy(fsph + 4 * i, sc->fsph + 4 * (size_t)sc->sprev[i], 4 * sizeof *fsph);
                else
                    sphere_ball(st->isph + 4 * i, d->vert[st->vloc].x, fsph + 4 * i);
            }
        } else {
            memcpy(fsph, sc->fsph, 4 * nit * sizeof *fsph);
        }
    }
    if (nt) memcpy(tflag, st->tflag, (size_t)nt);
    for (int32_t k = 0; k < nv; k++) {
        if (keep) memcpy(vx + 3 * (size_t)k, d->vert[k].x, 3 * sizeof *vx);
        vgid[k] = (as_gid)d->gid[k];
        int32_t vt = d->vert[k].tet;
        if (fmt == FMT_TINY) ((uint8_t *)vtet)[k] = (uint8_t)(vt + 1);
        else if (fmt == FMT_NARROW) ((uint16_t *)vtet)[k] = (uint16_t)(vt + 1);
        else ((int32_t *)vtet)[k] = vt;
    }
    if (fmt == FMT_TINY) { /* the common case, unrolled */
        uint64_t *w = trec;
        for (int32_t t = 0; t < nt; t++) {
            const int32_t *r = d->tet + 8 * (size_t)t;
            if (r[0] == AS_DEL3_DEAD) {
                tet_put(trec, fmt, nt, t, r);
                continue;
            }
            /* design: the fields are disjoint, so they are summed: the vertex codes as
             * r[i] << 6i plus the constant of the + 2s (modulo 2^64: the vertices are
             * -2 .. 61, the total is the code), and the handle 8t'+j as 4t'+j =
             * (8t'+j + j) / 2, its field h << 10i + 24 as (h + j) << 10i + 23 (h + j is
             * even): fewer operations than masking each field */
            uint64_t x = (uint64_t)(int64_t)r[0] + ((uint64_t)(int64_t)r[1] << 6) +
                         ((uint64_t)(int64_t)r[2] << 12) + ((uint64_t)(int64_t)r[3] << 18) +
                         (uint64_t)(2 + (2 << 6) + (2 << 12) + (2 << 18));
            uint64_t h0 = (uint32_t)r[4], h1 = (uint32_t)r[5], h2 = (uint32_t)r[6];
            uint64_t h3 = (uint32_t)r[7];
            x += ((h0 + (h0 & 3)) << 23) + ((h1 + (h1 & 3)) << 33) + ((h2 + (h2 & 3)) << 43) +
                 ((h3 + (h3 & 3)) << 53);
            w[t] = x;
        }
    } else if (fmt == FMT_NARROW) {
        uint16_t *h = trec;
        uint8_t *vb = (uint8_t *)(h + 4 * (size_t)nt);
        for (int32_t t = 0; t < nt; t++) {
            const int32_t *r = d->tet + 8 * (size_t)t;
            if (r[0] == AS_DEL3_DEAD) {
                tet_put(trec, fmt, nt, t, r);
                continue;
            }
            uint16_t *ht = h + 4 * (size_t)t;
            uint8_t *vt = vb + 4 * (size_t)t;
            vt[0] = (uint8_t)(r[0] + 2);
            vt[1] = (uint8_t)(r[1] + 2);
            vt[2] = (uint8_t)(r[2] + 2);
            vt[3] = (uint8_t)(r[3] + 2);
            ht[0] = (uint16_t)r[4];
            ht[1] = (uint16_t)r[5];
            ht[2] = (uint16_t)r[6];
            ht[3] = (uint16_t)r[7];
        }
    } else if (nt) {
        memcpy(trec, d->tet, 8 * (size_t)nt * sizeof *d->tet);
    }
    as_free(ctx, st->blk, st->blk_bytes);
    st->blk = blk;
    st->blk_bytes = bytes;
    st->rf = rf;
    st->cap_rf = (int32_t)nrf;
    st->itet = itet;
    st->cap_itet = (int32_t)nit;
    st->isph = NULL;
    st->cap_isph = 0;
    st->fsph = fsph;
    st->tflag = tflag;
    st->cap_tflag = (size_t)nt;
    st->vx = keep ? vx : NULL;
    st->vgid = vgid;
    st->vtet = vtet;
    st->trec = trec;
    st->fmt = fmt;
    st->nv = nv;
    st->nt = nt;
    st->nlive = d->nlive;
    st->free_head = d->free_head;
    st->hint = d->hint;
    st->rng = d->rng;
    if (nv) memcpy(st->fv, d->vert[st->vloc].x, sizeof st->fv);
    /* the work keeps st's records: star_open may reuse them (as_star_scratch) */
    sc->serial++;
    st->pack_sc = sc;
    st->pack_serial = sc->serial;
    sc->work_star = nv ? st : NULL;
    return ANISTAR_OK;
}

/* Close st after an operation that returned s: the operation's error wins. */
static anistar_status star_done(const as_star_env *env, as_star *st, as_star_scratch *sc,
                                anistar_status s) {
    anistar_status c = star_close(env, st, sc);
    return s != ANISTAR_OK ? s : c;
}

/* Insert one site into the del3 of the star; marks the created tets. */
static anistar_status star_add(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                               int32_t gid, int *inserted) {
    int32_t vtx = -1;
    int r = as_del3_insert_frame(st->d, mf, as_star_xyz(st, env->xyz, gid), gid, &vtx);
    *inserted = 0;
    if (r == AS_DEL3_DUPLICATE) return ANISTAR_OK;
    if (r != ANISTAR_OK) {
        if (r == ANISTAR_ENOMEM) return as_fail(env->ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
        return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: star insertion failed (%d)", r);
    }
    *inserted = 1;
    anistar_status s = grow_tflag(env->ctx, st);
    if (s != ANISTAR_OK) return s;
    const as_del3_buf *cr = &st->d->created;
    for (size_t k = 0; k < cr->n; k++) st->tflag[cr->a[k]] = TF_FRESH;
    return ANISTAR_OK;
}

static anistar_status star_build(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                 int32_t gid) {
    as_del3_reset(st->d);
    st->gid = gid;
    st->nrf = 0;
    st->closed = 0;
    anistar_status s;
    int ins;
    for (int32_t k = 0; k < 8; k++)
        if ((s = star_add(env, st, mf, k, &ins)) != ANISTAR_OK) return s;
    if ((s = star_add(env, st, mf, gid, &ins)) != ANISTAR_OK) return s;
    if (!ins) return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: site equals a box corner");
    st->vloc = st->d->nv - 1;
    /* every slot is fresh after a rebuild */
    for (int32_t t = 0; t < st->d->nt; t++) st->tflag[t] = TF_FRESH;
    return ANISTAR_OK;
}

static anistar_status star_insert(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                  const int32_t *gids, int32_t n, as_star_scratch *sc,
                                  int32_t *changed) {
    anistar_status s;
    int32_t cnt = 0;
    for (int32_t i = 0; i < n; i++) {
        int ins;
        if ((s = star_add(env, st, mf, gids[i], &ins)) != ANISTAR_OK) return s;
        cnt += ins;
    }
    if (changed) *changed = cnt;
    if (cnt == 0) {
        /* nothing changed: the old facets are the current ones */
        if ((s = grow_rf(env->ctx, &sc->old, &sc->cap_old, st->nrf)) != ANISTAR_OK) return s;
        if (st->nrf) memcpy(sc->old, st->rf, (size_t)st->nrf * sizeof *st->rf);
        sc->nold = st->nrf;
        for (int32_t i = 0; i < st->nrf; i++) st->rf[i].fresh = 0;
        return ANISTAR_OK;
    }
    return star_update(env, st, mf, sc);
}

anistar_status as_star_build(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                             int32_t gid, as_star_scratch *sc) {
    return as_star_build_seeded(env, st, mf, gid, NULL, 0, sc);
}

anistar_status as_star_build_seeded(const as_star_env *env, as_star *st,
                                    const as_metric_frame *mf, int32_t gid,
                                    const int32_t *seeds, int32_t n, as_star_scratch *sc) {
    anistar_status s = star_open(env, st, mf, sc, 0);
    if (s != ANISTAR_OK) return s;
    s = star_build(env, st, mf, gid);
    int32_t nv_base = st->d->nv;
    for (int32_t i = 0; s == ANISTAR_OK && i < n; i++) {
        int ins;
        s = star_add(env, st, mf, seeds[i], &ins);
    }
    if (s == ANISTAR_OK) {
        sc->nold = 0;
        s = star_update(env, st, mf, sc);
    }
    s = star_done(env, st, sc, s);
    st->nv_base = nv_base;
    return s;
}

anistar_status as_star_insert(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                              const int32_t *gids, int32_t n, as_star_scratch *sc,
                              int32_t *changed) {
    anistar_status s = star_open(env, st, mf, sc, 1);
    if (s != ANISTAR_OK) return s;
    s = star_insert(env, st, mf, gids, n, sc, changed);
    return star_done(env, st, sc, s);
}

anistar_status as_star_probe(const as_star_env *env, const as_star *st, const as_metric_frame *mf,
                             const int32_t *gids, int32_t n, as_star_scratch *sc,
                             const as_rfacet **rf, int32_t *nrf) {
    *rf = NULL;
    *nrf = 0;
    as_star t = *st; /* reads st's packed block; the working arrays are sc's */
    anistar_status s = star_open(env, &t, mf, sc, 1);
    if (s != ANISTAR_OK) return s;
    sc->probe = 1;
    /* design: a site is inserted only if it still conflicts with a tet around v. The
     * region where a point conflicts with v's tets (the union of their circumballs, which
     * all pass through v) only shrinks as sites are inserted, since v's Voronoi cell
     * does, so a site outside it now stays outside: v's tets, the only ones the facets
     * read, are those of inserting them all. With the sites nearest first (the caller's
     * order) the near ones cut the cell and most far ones are skipped (the liver's zone
     * check: 20-35 conflicting sites per star, most of them far). */
    int32_t cnt = 0;
    int stale = 1;
    for (int32_t i = 0; s == ANISTAR_OK && i < n; i++) {
        double y[3];
        as_metric_apply(mf, as_star_xyz(&t, env->xyz, gids[i]), y);
        if (stale) { /* v's tets and their filter balls (as star_update's) */
            if ((s = as_del3_vertex_tets(t.d, t.vloc, &sc->tets)) != ANISTAR_OK ||
                (s = grow_dbl(env->ctx, &sc->pball, &sc->cap_pball,
                              4 * (int32_t)sc->tets.n)) != ANISTAR_OK)
                break;
            const double *V = as_del3_point(t.d, t.vloc);
            for (size_t k = 0; k < sc->tets.n; k++)
                del3_tet_sphere(t.d, sc->tets.a[k], V, sc->pball + 4 * k);
            stale = 0;
        }
        int hit = 0;
        for (size_t k = 0; k < sc->tets.n && !hit; k++) {
            const double *S = sc->pball + 4 * k;
            if (S[3] >= 0) {
                double dd[3];
                sub3(y, S, dd);
                if (dot3(dd, dd) > S[3]) continue; /* proven outside (see star_update) */
            }
            hit = as_del3_in_sphere(t.d, sc->tets.a[k], y, gids[i]);
        }
        if (!hit) continue;
        int ins;
        if ((s = star_add(env, &t, mf, gids[i], &ins)) != ANISTAR_OK) break;
        cnt += ins;
        stale = ins;
    }
    if (s == ANISTAR_OK) {
        if (cnt == 0) {
            for (int32_t i = 0; i < t.nrf; i++) t.rf[i].fresh = 0;
        } else {
            s = star_update(env, &t, mf, sc);
        }
    }
    sc->probe = 0;
    /* the working arrays go back to the scratch (they may have grown); nothing is packed */
    sc->rf = t.rf;
    sc->cap_rf = t.cap_rf;
    sc->itet = t.itet;
    sc->cap_itet = t.cap_itet;
    sc->isph = t.isph;
    sc->cap_isph = t.cap_isph;
    sc->tflag = t.tflag;
    sc->cap_tflag = t.cap_tflag;
    if (s == ANISTAR_OK) {
        *rf = sc->rf;
        *nrf = t.nrf;
    }
    return s;
}

anistar_status as_star_keep_points(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                   as_star_scratch *sc) {
    if (st->vx || st->nv == 0) return ANISTAR_OK;
    anistar_status s = star_open(env, st, mf, sc, 1);
    if (s != ANISTAR_OK) return s;
    return star_close(env, st, sc);
}

anistar_status as_star_rebuild(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                               const int32_t *seeds, int32_t n, as_star_scratch *sc) {
    anistar_context *ctx = env->ctx;
    anistar_status s;
    /* keep the old facets for the caller's diff */
    size_t c = (size_t)sc->cap_old;
    if ((size_t)st->nrf > c) {
        if (as_grow(ctx, (void **)&sc->old, &c, (size_t)st->nrf, sizeof *sc->old))
            return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (restricted facets)");
        sc->cap_old = (int32_t)c;
    }
    if (st->nrf) memcpy(sc->old, st->rf, (size_t)st->nrf * sizeof *st->rf);
    int32_t nold = st->nrf;
    int32_t gid = st->gid;
    /* design: from scratch (star_build resets the working triangulation: slots, free list
     * and random state as for a new star); the packed block shrinks to the new size */
    if ((s = star_open(env, st, mf, sc, 0)) != ANISTAR_OK) return s;
    s = star_build(env, st, mf, gid);
    for (int32_t i = 0; s == ANISTAR_OK && i < n; i++) {
        int ins;
        s = star_add(env, st, mf, seeds[i], &ins);
    }
    if (s == ANISTAR_OK) {
        sc->nold = 0;
        s = star_update(env, st, mf, sc);
    }
    s = star_done(env, st, sc, s);
    st->nv_base = st->nv;
    /* star_update left sc->old's entries in place (it copied the empty list): they are
     * the facets from before the rebuild */
    sc->nold = nold;
    return s;
}

/* as_del3_in_sphere on tet t of a packed star (the stored points and ids of its vertices:
 * the same predicate on the same numbers). */
static int packed_in_sphere(const as_star *st, const double *xyz, const as_metric_frame *mf,
                            int32_t t, const double y[3], int64_t gid) {
    int32_t r[8];
    tet_get(st, t, r);
    if (r[0] == AS_DEL3_DEAD) return 0;
    double pts[4][3];
    const double *q[4];
    int64_t g[4];
    int k = -1;
    for (int i = 0; i < 4; i++) {
        if (r[i] < 0) {
            k = i;
            q[i] = y;
            g[i] = -1;
            continue;
        }
        as_star_point(st, xyz, mf, r[i], pts[i]);
        q[i] = pts[i];
        g[i] = as_star_vertex_gid(st, r[i]);
        if (q[i][0] == y[0] && q[i][1] == y[1] && q[i][2] == y[2]) return 0;
    }
    if (k < 0) return as_del3_in_sphere_points(q, g, y, gid);
    /* an infinite tet (del3.c's rule): y beyond its finite face, or on that face's plane
     * and inside the sphere of the finite tet across it */
    double o = as_orient3d(q[0], q[1], q[2], q[3]);
    if (o != 0) return o > 0;
    int32_t w[8];
    tet_get(st, r[4 + k] >> 3, w);
    for (int i = 0; i < 4; i++) {
        as_star_point(st, xyz, mf, w[i], pts[i]);
        q[i] = pts[i];
        g[i] = as_star_vertex_gid(st, w[i]);
    }
    double det = as_insphere_filter(q[0], q[1], q[2], q[3], y);
    int sg = (det > 0) - (det < 0);
    if (!sg) sg = as_insphere_sos(q[0], q[1], q[2], q[3], y, g[0], g[1], g[2], g[3], gid);
    return sg > 0;
}

void as_star_tet(const as_star *st, int32_t t, int32_t r[8]) { tet_get(st, t, r); }
int32_t as_star_vertex_tet(const as_star *st, int32_t k) { return vtet_get(st, k); }

void as_star_sphere(const as_star *st, const double *xyz, const as_metric_frame *mf, int32_t i,
                    double S[4]) {
    int32_t r[8];
    tet_get(st, st->itet[i], r);
    double pts[4][3], V[3];
    const double *q[4];
    int inf = 0;
    for (int k = 0; k < 4; k++) {
        if (r[k] < 0) {
            inf = 1;
            break;
        }
        as_star_point(st, xyz, mf, r[k], pts[k]);
        q[k] = pts[k];
    }
    as_star_point(st, xyz, mf, st->vloc, V);
    tet_sphere(inf ? NULL : q, V, S);
}

/* The exact Delaunay conflict of y = F_v p (global id gid) with a tet around v (open or
 * packed star). */
static int conflicts_at(const as_star *st, const double *xyz, const as_metric_frame *mf,
                        const double y[3], int64_t gid, int32_t *hint) {
    const as_del3 *d = st->d; /* NULL: packed (the usual case) */
    double w[3]; /* y - F_v v: the float balls' frame */
    sub3(y, st->fv, w);
    for (int32_t i = 0; i < st->nitet; i++) {
        if (d) {
            const double *S = st->isph + 4 * (size_t)i;
            if (S[3] >= 0) {
                double dd[3];
                sub3(y, S, dd);
                if (dot3(dd, dd) > S[3]) continue; /* proven outside (see star_update) */
            }
        } else {
            const float *F = st->fsph + 4 * (size_t)i;
            if (F[3] >= 0) {
                double dd[3] = {w[0] - (double)F[0], w[1] - (double)F[1], w[2] - (double)F[2]};
                double b = F[3];
                if (dot3(dd, dd) > b * b) continue; /* proven outside (see sphere_ball) */
            }
        }
        if (d ? as_del3_in_sphere(d, st->itet[i], y, gid)
              : packed_in_sphere(st, xyz, mf, st->itet[i], y, gid)) {
            if (hint) *hint = st->itet[i];
            return 1;
        }
    }
    return 0;
}

int as_star_conflicts(const as_star *st, const as_metric_frame *mf, const double *xyz,
                      const double p[3], int64_t gid, int32_t *hint) {
    double y[3];
    as_metric_apply(mf, p, y);
    if (AS_STAR_BALL_ZONE(st)) {
        /* design: a site outside every inflated surface ball leaves the surface star
         * unchanged (paper 5.3): a filter in the stretched frame, then the exact test */
        const double *V = st->d ? as_del3_point(st->d, st->vloc) : st->fv;
        double dd[3];
        sub3(y, V, dd);
        if (!(dot3(dd, dd) < st->zr2)) return 0;
        int near = 0;
        for (int32_t i = 0; i < st->nrf && !near; i++) {
            double z[4];
            as_star_zone_ball(mf, &st->rf[i], z);
            sub3(y, z, dd);
            near = dot3(dd, dd) < z[3] * z[3];
        }
        if (!near) return 0;
    }
    return conflicts_at(st, xyz, mf, y, gid, hint);
}

int as_star_conflicts_delaunay(const as_star *st, const as_metric_frame *mf, const double *xyz,
                               const double p[3], int64_t gid, int32_t *hint) {
    double y[3];
    as_metric_apply(mf, p, y);
    return conflicts_at(st, xyz, mf, y, gid, hint);
}

/* design: unpacked for the walk around v (a few stars per final check), packed again */
anistar_status as_star_facet_extent(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                    as_star_scratch *sc, const as_gid g[3], int *in_dt,
                                    double *ext) {
    *in_dt = 0;
    *ext = INFINITY;
    anistar_status s = star_open(env, st, mf, sc, 1);
    if (s != ANISTAR_OK) return s;
    as_del3 *d = st->d;
    s = as_del3_vertex_facets(d, st->vloc, &sc->faces);
    const double *V = as_del3_point(d, st->vloc);
    for (size_t k = 0; s == ANISTAR_OK && k < sc->faces.n; k++) {
        int32_t face = sc->faces.a[k], t1 = face >> 2, n = 0;
        as_gid h[3];
        for (int j = 0; j < 4; j++)
            if (j != (face & 3)) h[n++] = (as_gid)d->gid[as_del3_tet_vertex(d, t1, j)];
        as_sort_gid3(h);
        if (h[0] != g[0] || h[1] != g[1] || h[2] != g[2]) continue;
        *in_dt = 1;
        int32_t t[2] = {t1, as_del3_mirror(d, face) >> 2};
        double e = 0;
        int inf = 0;
        for (int q = 0; q < 2 && !inf; q++) {
            double cc[3], dd[3];
            if (as_del3_circumcenter(d, t[q], cc) != 0) {
                inf = 1; /* infinite: +inf */
                break;
            }
            sub3(cc, V, dd);
            double R = sqrt(dot3(dd, dd));
            if (R > e) e = R;
        }
        if (!inf) *ext = 2 * e * (1 + 1e-9);
        break;
    }
    return star_done(env, st, sc, s);
}
