/*
 * star.c — one vertex star: stretched triangulation, restricted facets, surface balls,
 * conflict-zone box (DESIGN.md 4.3-4.4, paper 3.1 and 5.3). See star.h.
 */
#include "mesher/star.h"

#include <math.h>
#include <string.h>

enum { TF_UNKNOWN = 0, TF_OUT = 1, TF_IN = 2, TF_STATE = 3, TF_FRESH = 4 };

/* Relative slack of the floating-point filters in front of exact tests (boxes, surface
 * ball distances): a filter may only let more candidates through, never fewer. */
#define AS_STAR_SLACK 1e-9

void as_star_scratch_free(anistar_context *ctx, as_star_scratch *s) {
    if (s->donor_init) as_del3_destroy(&s->donor);
    as_del3_buf_free(ctx, &s->tets);
    as_del3_buf_free(ctx, &s->faces);
    as_free(ctx, s->old, (size_t)s->cap_old * sizeof *s->old);
    as_free(ctx, s->osph, (size_t)s->cap_osph * sizeof *s->osph);
    as_free(ctx, s->slot, (size_t)s->cap_slot * sizeof *s->slot);
    memset(s, 0, sizeof *s);
}

void as_star_init(as_star *st, anistar_context *ctx) {
    memset(st, 0, sizeof *st);
    as_del3_init(&st->del, ctx);
    st->del.no_sphere_cache = 1; /* design: isph filters its conflict tests (memory) */
    st->del.tight_growth = 1;    /* design: many small triangulations (memory) */
    st->gid = -1;
    st->vloc = -1;
}

void as_star_destroy(anistar_context *ctx, as_star *st) {
    as_del3_destroy(&st->del);
    as_free(ctx, st->tflag, st->cap_tflag);
    as_free(ctx, st->rf, (size_t)st->cap_rf * sizeof *st->rf);
    as_free(ctx, st->itet, (size_t)st->cap_itet * sizeof *st->itet);
    as_free(ctx, st->zone, (size_t)st->cap_zone * sizeof *st->zone);
    as_free(ctx, st->isph, (size_t)st->cap_isph * sizeof *st->isph);
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

/* Shrink array *p of capacity *cap (elements of size elem) to n >= 1 elements. 0 or -1. */
static int trim_array(anistar_context *ctx, void **p, int32_t *cap, int32_t n, size_t elem) {
    if (n < 1) n = 1;
    if (n >= *cap) return 0;
    void *q = as_realloc(ctx, *p, (size_t)*cap * elem, (size_t)n * elem);
    if (!q) return -1;
    *p = q;
    *cap = n;
    return 0;
}

anistar_status as_star_trim(anistar_context *ctx, as_star *st) {
    if (as_del3_shrink(&st->del) != 0)
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    size_t need = st->del.nt > 0 ? (size_t)st->del.nt : 1;
    if (need < st->cap_tflag) {
        uint8_t *p = as_realloc(ctx, st->tflag, st->cap_tflag, need);
        if (!p) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star flags)");
        st->tflag = p;
        st->cap_tflag = need;
    }
    if (trim_array(ctx, (void **)&st->rf, &st->cap_rf, st->nrf, sizeof *st->rf) ||
        trim_array(ctx, (void **)&st->itet, &st->cap_itet, st->nitet, sizeof *st->itet) ||
        trim_array(ctx, (void **)&st->isph, &st->cap_isph, 4 * st->nitet, sizeof *st->isph) ||
        trim_array(ctx, (void **)&st->zone, &st->cap_zone, AS_STAR_BALL_ZONE(st) ? 4 * st->nrf : 0,
                   sizeof *st->zone))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    return ANISTAR_OK;
}

static anistar_status grow_tflag(anistar_context *ctx, as_star *st) {
    size_t need = (size_t)st->del.nt;
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

/* The circumcenter of tet t (stretched frame): from the spheres of the tets incident to v
 * when t is one of them (star_update computes those first: no circumcenter twice), else
 * computed. 0, or -1 for an infinite tet. */
static int tet_center(const as_star *st, int32_t t, double cc[3]) {
    for (int32_t i = 0; i < st->nitet; i++)
        if (st->itet[i] == t) {
            const double *S = st->isph + 4 * (size_t)i;
            if (S[3] == -1) return -1;
            memcpy(cc, S, 3 * sizeof(double));
            return 0;
        }
    return as_del3_circumcenter(&st->del, t, cc);
}

/* The inside state of live finite tet t (cached). */
static anistar_status tet_inside(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                 int32_t t, int *in) {
    uint8_t f = st->tflag[t];
    if ((f & TF_STATE) != TF_UNKNOWN) {
        *in = (f & TF_STATE) == TF_IN;
        return ANISTAR_OK;
    }
    double cc[3], x[3];
    if (tet_center(st, t, cc) != 0)
        return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: infinite tet beside a star center");
    as_metric_unapply(mf, cc, x);
    int side = 1;
    if (isfinite(x[0]) && isfinite(x[1]) && isfinite(x[2])) {
        anistar_status s = as_surface_side(env->ctx, env->surf, x, &side);
        if (s != ANISTAR_OK) return s;
    }
    *in = side < 0;
    st->tflag[t] = (uint8_t)((f & ~TF_STATE) | (*in ? TF_IN : TF_OUT));
    return ANISTAR_OK;
}

/* The crossing of [a, b] (a inside, b outside or the reverse) nearest ref; bisection on
 * the side oracle when the crossing finder misses it (it should not: the end signs
 * differ). */
static anistar_status dual_crossing(const as_star_env *env, const double a[3], const double b[3],
                                    const double ref[3], double c[3]) {
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

static int cmp_g(const int32_t a[3], const int32_t b[3]) {
    for (int k = 0; k < 3; k++)
        if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
    return 0;
}

static void sort3(int32_t g[3]) {
    int32_t t;
    if (g[0] > g[1]) { t = g[0]; g[0] = g[1]; g[1] = t; }
    if (g[1] > g[2]) { t = g[1]; g[1] = g[2]; g[2] = t; }
    if (g[0] > g[1]) { t = g[0]; g[0] = g[1]; g[1] = t; }
}

int32_t as_star_find(const as_star *st, const int32_t g[3]) {
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

static int32_t find_in(const as_rfacet *rf, int32_t n, const int32_t g[3]) {
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

int as_star_fan_closed(const as_rfacet *rf, int32_t n, int32_t v) {
    if (n < 3) return 0;
    /* design: the link of v is a graph on the other vertices with one edge per facet; it
     * is one cycle iff every vertex has degree 2 and a walk from facet 0 visits all n. */
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

/* The box of the conflict zone (see as_star_rezone in star.h). */
anistar_status as_star_rezone(anistar_context *ctx, as_star *st, const as_metric_frame *mf) {
    anistar_status s;
    const as_del3 *d = &st->del;
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    if (AS_STAR_BALL_ZONE(st)) {
        /* design: the surface balls in the stretched frame, and one ball around F_v v
         * holding them all, so that most candidates are rejected by one distance */
        if ((s = grow_dbl(ctx, &st->zone, &st->cap_zone, 4 * st->nrf)) != ANISTAR_OK) return s;
        const double *V = as_del3_point(d, st->vloc);
        double zr = 0;
        for (int32_t i = 0; i < st->nrf; i++) {
            double *z = st->zone + 4 * (size_t)i, dd[3];
            as_metric_apply(mf, st->rf[i].c, z);
            z[3] = st->rf[i].r * AS_STAR_ZONE_INFLATE * (1 + AS_STAR_SLACK);
            sub3(z, V, dd);
            double e = sqrt(dot3(dd, dd)) + z[3];
            if (e > zr) zr = e;
        }
        zr *= 1 + 4 * AS_STAR_SLACK;
        st->zr2 = zr * zr;
        for (int32_t i = 0; i < st->nrf; i++) {
            double h[3];
            as_metric_ellipsoid_box(mf, st->rf[i].r * AS_STAR_ZONE_INFLATE * (1 + AS_STAR_SLACK), h);
            box_add(lo, hi, st->rf[i].c, h);
        }
    } else {
        const double *V = as_del3_point(d, st->vloc);
        for (int32_t k = 0; k < st->nitet; k++) {
            const double *cc = st->isph + 4 * (size_t)k;
            double x[3], h[3], dd[3];
            if (cc[3] == -1) continue; /* infinite */
            sub3(cc, V, dd);
            double R = sqrt(dot3(dd, dd));
            as_metric_unapply(mf, cc, x);
            as_metric_ellipsoid_box(mf, R * (1 + AS_STAR_SLACK), h);
            box_add(lo, hi, x, h);
        }
    }
    for (int k = 0; k < 3; k++) {
        double pad = AS_STAR_SLACK * (fabs(lo[k]) + fabs(hi[k]) + (hi[k] - lo[k]));
        st->lo[k] = lo[k] - pad;
        st->hi[k] = hi[k] + pad;
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

    /* the tets incident to v */
    if ((s = as_del3_vertex_tets(&st->del, st->vloc, &sc->tets)) != ANISTAR_OK) return s;
    const int32_t nprev = st->nitet, nnew = (int32_t)sc->tets.n;
    if ((s = grow_dbl(ctx, &sc->osph, &sc->cap_osph, 4 * nprev)) != ANISTAR_OK) return s;
    if (st->del.nt > sc->cap_slot) {
        int32_t c0 = sc->cap_slot;
        if ((s = grow_i32(ctx, &sc->slot, &sc->cap_slot, st->del.nt)) != ANISTAR_OK) return s;
        for (int32_t t = c0; t < sc->cap_slot; t++) sc->slot[t] = -1;
    }
    if ((s = grow_dbl(ctx, &st->isph, &st->cap_isph, 4 * nnew)) != ANISTAR_OK) return s;
    if ((s = grow_i32(ctx, &st->itet, &st->cap_itet, nnew)) != ANISTAR_OK) return s;
    /* design: cached circumspheres. as_del3_circumcenter is within 2^-40 R of the true
     * center c* (R the true radius); with R' = |c - v| the computed radius,
     * |y - c*| >= |y - c| - 2^-40 R and R <= R' + 2^-40 R, so |y - c| > R'(1 + 1e-9) (with
     * the rounding of these few operations far below the 1e-9 margin) proves y strictly
     * outside the true sphere: not in conflict, whatever the perturbation. A tet that is
     * not fresh is unchanged since the last update: its sphere is kept (sc->slot maps its
     * slot to its place in the previous list, sc->osph). */
    if (nprev) memcpy(sc->osph, st->isph, 4 * (size_t)nprev * sizeof *sc->osph);
    for (int32_t i = 0; i < nprev; i++)
        if (st->itet[i] < sc->cap_slot) sc->slot[st->itet[i]] = i;
    {
        const as_del3 *d = &st->del;
        const double *V = as_del3_point(d, st->vloc);
        for (int32_t i = 0; i < nnew; i++) {
            int32_t t = sc->tets.a[i];
            double *S = st->isph + 4 * (size_t)i, dd[3];
            int32_t j = sc->slot[t];
            if (j >= 0 && !(st->tflag[t] & TF_FRESH)) {
                memcpy(S, sc->osph + 4 * (size_t)j, 4 * sizeof *S);
                continue;
            }
            if (as_del3_circumcenter(d, t, S) != 0) {
                S[0] = S[1] = S[2] = 0;
                S[3] = -1;
                continue;
            }
            sub3(S, V, dd);
            double R = sqrt(dot3(dd, dd)) * (1 + 1e-9);
            S[3] = isfinite(R) ? R * R : -2; /* -2: a center, no usable bound */
        }
    }
    for (int32_t i = 0; i < nprev; i++)
        if (st->itet[i] < sc->cap_slot) sc->slot[st->itet[i]] = -1;
    memcpy(st->itet, sc->tets.a, (size_t)nnew * sizeof *st->itet);
    st->nitet = nnew;
    if ((s = as_del3_vertex_facets(&st->del, st->vloc, &sc->faces)) != ANISTAR_OK) return s;
    const as_del3 *d = &st->del;
    const double *vx = env->xyz + 3 * (size_t)st->gid;
    for (size_t k = 0; k < sc->faces.n; k++) {
        int32_t face = sc->faces.a[k];
        int32_t t1 = face >> 2, t2 = as_del3_mirror(d, face) >> 2;
        int in1, in2;
        if ((s = tet_inside(env, st, mf, t1, &in1)) != ANISTAR_OK) return s;
        if ((s = tet_inside(env, st, mf, t2, &in2)) != ANISTAR_OK) return s;
        if (in1 == in2) continue;
        int32_t g[3], lv[3], n = 0;
        for (int j = 0; j < 4; j++) {
            if (j == (face & 3)) continue;
            lv[n] = as_del3_tet_vertex(d, t1, j);
            g[n] = (int32_t)d->gid[lv[n]];
            n++;
        }
        sort3(g);
        if ((s = grow_rf(ctx, &st->rf, &st->cap_rf, st->nrf + 1)) != ANISTAR_OK) return s;
        as_rfacet *f = &st->rf[st->nrf++];
        int fresh = ((st->tflag[t1] | st->tflag[t2]) & TF_FRESH) != 0;
        int32_t o = fresh ? -1 : find_in(sc->old, sc->nold, g);
        if (o >= 0) {
            *f = sc->old[o];
            f->fresh = 0;
            f->face = face;
            continue;
        }
        memset(f, 0, sizeof *f);
        memcpy(f->g, g, sizeof g);
        f->face = face;
        f->fresh = 1;
        /* design: dual segment between the two mapped circumcenters; the crossing nearest
         * the facet's own circumcenter (DESIGN.md 4.4). */
        double cc1[3], cc2[3], a[3], b[3], fcs[3], fc[3];
        if (tet_center(st, t1, cc1) || tet_center(st, t2, cc2))
            return as_fail(ctx, ANISTAR_EINTERNAL, "mesher: infinite tet beside a star center");
        as_metric_unapply(mf, cc1, a);
        as_metric_unapply(mf, cc2, b);
        if (tri_circumcenter(as_del3_point(d, lv[0]), as_del3_point(d, lv[1]),
                             as_del3_point(d, lv[2]), fcs) == 0)
            as_metric_unapply(mf, fcs, fc);
        else
            for (int q = 0; q < 3; q++) fc[q] = 0.5 * (a[q] + b[q]);
        if ((s = dual_crossing(env, a, b, fc, f->c)) != ANISTAR_OK) return s;
        f->r = as_metric_dist(mf, f->c, vx);
    }
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
    st->closed = as_star_fan_closed(st->rf, st->nrf, st->gid);
    if ((s = as_star_rezone(ctx, st, mf)) != ANISTAR_OK) return s;
    /* the fresh marks served this update */
    for (int32_t t = 0; t < d->nt; t++) st->tflag[t] &= (uint8_t)~TF_FRESH;
    return ANISTAR_OK;
}


static void lend(anistar_context *ctx, as_star *st, as_star_scratch *sc) {
    if (!sc->donor_init) {
        as_del3_init(&sc->donor, ctx);
        sc->donor_init = 1;
    }
    as_del3_swap_scratch(&st->del, &sc->donor);
}
static void unlend(as_star *st, as_star_scratch *sc) { as_del3_swap_scratch(&st->del, &sc->donor); }

/* Insert one site into the del3 of the star; marks the created tets. */
static anistar_status star_add(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                               int32_t gid, int *inserted) {
    int32_t vtx = -1;
    int r = as_del3_insert_frame(&st->del, mf, env->xyz + 3 * (size_t)gid, gid, &vtx);
    *inserted = 0;
    if (r == AS_DEL3_DUPLICATE) return ANISTAR_OK;
    if (r != ANISTAR_OK) {
        if (r == ANISTAR_ENOMEM) return as_fail(env->ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
        return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: star insertion failed (%d)", r);
    }
    *inserted = 1;
    anistar_status s = grow_tflag(env->ctx, st);
    if (s != ANISTAR_OK) return s;
    const as_del3_buf *cr = &st->del.created;
    for (size_t k = 0; k < cr->n; k++) st->tflag[cr->a[k]] = TF_FRESH;
    return ANISTAR_OK;
}

static anistar_status star_build(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                 int32_t gid) {
    as_del3_reset(&st->del);
    st->gid = gid;
    st->nrf = 0;
    st->closed = 0;
    anistar_status s;
    int ins;
    for (int32_t k = 0; k < 8; k++)
        if ((s = star_add(env, st, mf, k, &ins)) != ANISTAR_OK) return s;
    if ((s = star_add(env, st, mf, gid, &ins)) != ANISTAR_OK) return s;
    if (!ins) return as_fail(env->ctx, ANISTAR_EINTERNAL, "mesher: site equals a box corner");
    st->vloc = st->del.nv - 1;
    /* every slot is fresh after a rebuild */
    for (int32_t t = 0; t < st->del.nt; t++) st->tflag[t] = TF_FRESH;
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
    lend(env->ctx, st, sc);
    anistar_status s = star_build(env, st, mf, gid);
    int32_t nv_base = st->del.nv;
    for (int32_t i = 0; s == ANISTAR_OK && i < n; i++) {
        int ins;
        s = star_add(env, st, mf, seeds[i], &ins);
    }
    if (s == ANISTAR_OK) {
        sc->nold = 0;
        s = star_update(env, st, mf, sc);
    }
    unlend(st, sc);
    st->nv_base = nv_base;
    return s;
}

anistar_status as_star_insert(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                              const int32_t *gids, int32_t n, as_star_scratch *sc,
                              int32_t *changed) {
    lend(env->ctx, st, sc);
    anistar_status s = star_insert(env, st, mf, gids, n, sc, changed);
    unlend(st, sc);
    return s;
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
    /* design: free the arrays (capacity shrinks to the new size), reserve tightly */
    as_del3_destroy(&st->del);
    as_del3_init(&st->del, ctx);
    st->del.no_sphere_cache = 1;
    st->del.tight_growth = 1;
    as_free(ctx, st->tflag, st->cap_tflag);
    st->tflag = NULL;
    st->cap_tflag = 0;
    int32_t nvw = 9 + n + 8;
    if (as_del3_reserve(&st->del, nvw, 7 * nvw) != ANISTAR_OK)
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
    lend(ctx, st, sc);
    s = star_build(env, st, mf, gid);
    for (int32_t i = 0; s == ANISTAR_OK && i < n; i++) {
        int ins;
        s = star_add(env, st, mf, seeds[i], &ins);
    }
    if (s == ANISTAR_OK) {
        sc->nold = 0;
        s = star_update(env, st, mf, sc);
    }
    unlend(st, sc);
    st->nv_base = st->del.nv;
    /* star_update left sc->old's entries in place (it copied the empty list): they are
     * the facets from before the rebuild */
    sc->nold = nold;
    return s;
}

/* The exact Delaunay conflict of y = F_v p (global id gid) with a tet around v. */
static int conflicts_at(const as_star *st, const double y[3], int64_t gid, int32_t *hint) {
    const as_del3 *d = &st->del;
    for (int32_t i = 0; i < st->nitet; i++) {
        const double *S = st->isph + 4 * (size_t)i;
        if (S[3] >= 0) {
            double dd[3];
            sub3(y, S, dd);
            if (dot3(dd, dd) > S[3]) continue; /* proven outside (see star_update) */
        }
        if (as_del3_in_sphere(d, st->itet[i], y, gid)) {
            if (hint) *hint = st->itet[i];
            return 1;
        }
    }
    return 0;
}

int as_star_conflicts(const as_star *st, const as_metric_frame *mf, const double p[3],
                      int64_t gid, int32_t *hint) {
    double y[3];
    as_metric_apply(mf, p, y);
    const as_del3 *d = &st->del;
    if (AS_STAR_BALL_ZONE(st)) {
        /* design: a site outside every inflated surface ball leaves the surface star
         * unchanged (paper 5.3): a filter in the stretched frame, then the exact test */
        const double *V = as_del3_point(d, st->vloc);
        double dd[3];
        sub3(y, V, dd);
        if (!(dot3(dd, dd) < st->zr2)) return 0;
        int near = 0;
        for (int32_t i = 0; i < st->nrf && !near; i++) {
            const double *z = st->zone + 4 * (size_t)i;
            sub3(y, z, dd);
            near = dot3(dd, dd) < z[3] * z[3];
        }
        if (!near) return 0;
    }
    return conflicts_at(st, y, gid, hint);
}

int as_star_conflicts_delaunay(const as_star *st, const as_metric_frame *mf, const double p[3],
                               int64_t gid, int32_t *hint) {
    double y[3];
    as_metric_apply(mf, p, y);
    return conflicts_at(st, y, gid, hint);
}

anistar_status as_star_facet_extent(as_star *st, as_star_scratch *sc, const int32_t g[3],
                                    int *in_dt, double *ext) {
    *in_dt = 0;
    *ext = INFINITY;
    const as_del3 *d = &st->del;
    anistar_status s = as_del3_vertex_facets(&st->del, st->vloc, &sc->faces);
    if (s != ANISTAR_OK) return s;
    const double *V = as_del3_point(d, st->vloc);
    for (size_t k = 0; k < sc->faces.n; k++) {
        int32_t face = sc->faces.a[k], t1 = face >> 2, h[3], n = 0;
        for (int j = 0; j < 4; j++)
            if (j != (face & 3)) h[n++] = (int32_t)d->gid[as_del3_tet_vertex(d, t1, j)];
        sort3(h);
        if (h[0] != g[0] || h[1] != g[1] || h[2] != g[2]) continue;
        *in_dt = 1;
        int32_t t[2] = {t1, as_del3_mirror(d, face) >> 2};
        double e = 0;
        for (int q = 0; q < 2; q++) {
            double cc[3], dd[3];
            if (tet_center(st, t[q], cc) != 0) return ANISTAR_OK; /* infinite: +inf */
            sub3(cc, V, dd);
            double R = sqrt(dot3(dd, dd));
            if (R > e) e = R;
        }
        *ext = 2 * e * (1 + 1e-9);
        return ANISTAR_OK;
    }
    return ANISTAR_OK;
}
