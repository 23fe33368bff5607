/*
 * mesh_check.c — independent checks of a mesher output (see mesh_check.h).
 */
#include "mesh_check.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#include "geom/del3.h"
#include "geom/kdtree.h"
#include "geom/metric.h"

void mc_report_init(mc_report *r) {
    memset(r, 0, sizeof *r);
}

/* Count a violation; keep the first description. */
static void mc_fail(mc_report *r, const char *fmt, ...) {
    if (getenv("MC_VERBOSE")) {
        va_list aq;
        va_start(aq, fmt);
        vfprintf(stderr, fmt, aq);
        fputc(10, stderr);
        va_end(aq);
    }
    if (r->failures++ == 0) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(r->first, sizeof r->first, fmt, ap);
        va_end(ap);
    }
}

static void *xmalloc(size_t n) {
    void *p = malloc(n ? n : 1);
    assert_non_null(p);
    return p;
}

void mc_assert_ok(const mc_report *r, const char *what) {
    if (r->failures) fail_msg("%s: %zu violation(s); first: %s", what, r->failures, r->first);
}

/* ---- topology ------------------------------------------------------------------------ */

void mc_check_topology(anistar_context *ctx, const as_trimesh *m, const mc_limits *lim,
                       mc_report *r) {
    as_topology top;
    anistar_status st = as_topology_check(ctx, m->nv, m->xyz, m->nt, m->tri, &top);
    if (st != ANISTAR_OK) {
        mc_fail(r, "topology check failed: %s", anistar_last_error(ctx));
        return;
    }
    if (!top.closed_manifold)
        mc_fail(r, "not a closed 2-manifold: %zu border, %zu non-manifold edges, %zu "
                   "non-manifold vertices", top.border_edges, top.nonmanifold_edges,
                top.nonmanifold_vertices);
    /* consistency here; outward (relative to the solid, so an inner cavity's shell faces
     * into the cavity) is checked against the surface's side oracle in
     * mc_check_on_surface */
    if (top.misoriented_edges || top.nonorientable)
        mc_fail(r, "not consistently oriented: %zu misoriented edges", top.misoriented_edges);
    if (top.used_vertices != m->nv)
        mc_fail(r, "%zu of %zu vertices in no triangle", m->nv - top.used_vertices, m->nv);
    if (top.euler != lim->chi)
        mc_fail(r, "Euler characteristic %lld, S has %lld", top.euler, lim->chi);
    if ((long long)m->nt != 2 * (long long)m->nv - 2 * lim->chi)
        mc_fail(r, "F = %zu but 2V - 2chi = %lld", m->nt, 2 * (long long)m->nv - 2 * lim->chi);
}

/* ---- shape and distortion ----------------------------------------------------------- */

static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static void sub3(const double a[3], const double b[3], double c[3]) {
    for (int k = 0; k < 3; k++) c[k] = a[k] - b[k];
}
static void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

/* Circumcenter of the triangle A, B, C (in its plane); -1 when degenerate. */
static int tri_center(const double A[3], const double B[3], const double C[3], double o[3]) {
    double u[3], v[3], w[3], t[3];
    sub3(B, A, u);
    sub3(C, A, v);
    cross3(u, v, w);
    double w2 = dot3(w, w);
    if (!(w2 > 0)) return -1;
    /* o - A = (|u|^2 v - |v|^2 u) x w / (2 |w|^2) */
    double uu = dot3(u, u), vv = dot3(v, v);
    double s[3] = {uu * v[0] - vv * u[0], uu * v[1] - vv * u[1], uu * v[2] - vv * u[2]};
    cross3(s, w, t);
    for (int k = 0; k < 3; k++) o[k] = A[k] + t[k] / (2 * w2);
    return 0;
}

/* Radius-edge ratio of a, b, c stretched by mf: circumradius / shortest edge. */
static double radius_edge(const as_metric_frame *mf, const double *a, const double *b,
                          const double *c) {
    double A[3], B[3], C[3], o[3], e[3];
    as_metric_apply(mf, a, A);
    as_metric_apply(mf, b, B);
    as_metric_apply(mf, c, C);
    double l = INFINITY;
    const double *P[3] = {A, B, C};
    for (int k = 0; k < 3; k++) {
        sub3(P[(k + 1) % 3], P[k], e);
        double le = sqrt(dot3(e, e));
        if (le < l) l = le;
    }
    if (tri_center(A, B, C, o) != 0 || !(l > 0)) return INFINITY;
    sub3(o, A, e);
    return sqrt(dot3(e, e)) / l;
}

void mc_check_shape(const as_trimesh *m, const mc_limits *lim, mc_report *r) {
    if (!m->tensor) {
        mc_fail(r, "the mesh has no per-vertex tensors");
        return;
    }
    for (size_t t = 0; t < m->nt; t++) {
        const int32_t *tri = m->tri + 3 * t;
        as_metric_frame mf[3];
        int bad = 0;
        for (int k = 0; k < 3; k++)
            if (as_metric_frame_init(&mf[k], m->tensor + 6 * (size_t)tri[k]) != 0) bad = 1;
        if (bad) {
            mc_fail(r, "facet %zu: a vertex tensor is not positive definite", t);
            continue;
        }
        if (lim->hmin > 0) {
            double a = 1, l2 = 0;
            for (int k = 0; k < 3; k++) {
                if (mf[k].e[2] / mf[k].e[0] > a) a = mf[k].e[2] / mf[k].e[0];
                double e[3];
                sub3(m->xyz + 3 * (size_t)tri[k], m->xyz + 3 * (size_t)tri[(k + 1) % 3], e);
                if (dot3(e, e) > l2) l2 = dot3(e, e);
            }
            if (sqrt(l2) < 2 * a * lim->hmin * (1 + 1e-9)) continue;
        }
        for (int k = 0; k < 3; k++) {
            double rho = radius_edge(&mf[k], m->xyz + 3 * (size_t)tri[0],
                                     m->xyz + 3 * (size_t)tri[1], m->xyz + 3 * (size_t)tri[2]);
            if (rho > r->rho_max) r->rho_max = rho;
            /* slack: the ratio is recomputed here in another order of operations */
            if (!(rho <= lim->rho0 * (1 + 1e-12)))
                mc_fail(r, "facet %zu (%d %d %d): radius-edge ratio %.17g > rho0 %g in the "
                           "metric of vertex %d", t, tri[0], tri[1], tri[2], rho, lim->rho0,
                        tri[k]);
        }
        for (int a = 0; a < 3; a++)
            for (int b = a + 1; b < 3; b++) {
                double g = as_metric_distortion(&mf[a], &mf[b]);
                if (g > r->gamma_max) r->gamma_max = g;
                if (!(g < lim->gamma0))
                    mc_fail(r, "facet %zu: distortion %.17g >= gamma0 %g between vertices %d "
                               "and %d", t, g, lim->gamma0, tri[a], tri[b]);
            }
    }
}

/* ---- on the surface ------------------------------------------------------------------ */

void mc_check_on_surface(anistar_context *ctx, const as_surface *s, const as_trimesh *m,
                         const mc_limits *lim, mc_report *r) {
    int has_f = s->ops->eval != NULL;
    for (size_t i = 0; i < m->nv; i++) {
        const double *p = m->xyz + 3 * i;
        if (has_f) {
            double f, g[3];
            if (as_surface_eval(ctx, s, p, 1, &f, g, NULL) != ANISTAR_OK) {
                mc_fail(r, "vertex %zu: %s", i, anistar_last_error(ctx));
                continue;
            }
            double d = fabs(f) / sqrt(dot3(g, g));
            if (d > r->dist_max) r->dist_max = d;
            if (!(d <= lim->on_tol))
                mc_fail(r, "vertex %zu: |f|/|grad f| = %g > %g", i, d, lim->on_tol);
        }
        double q[3], e[3];
        if (as_surface_project(ctx, s, p, q) != ANISTAR_OK) {
            mc_fail(r, "vertex %zu: projection failed: %s", i, anistar_last_error(ctx));
            continue;
        }
        sub3(q, p, e);
        double d = sqrt(dot3(e, e));
        if (d > r->dist_max) r->dist_max = d;
        if (!(d <= lim->on_tol))
            mc_fail(r, "vertex %zu: distance %g to its projection on S > %g", i, d, lim->on_tol);
    }
    /* outward, as fidelity: each triangle's normal against S's outward normal at the
     * projection of its centroid, on the triangles over which S is resolved (S's normals
     * at its three vertices pairwise within 90 degrees; below the surface's resolution -
     * the noise of a head scan at its voxel size - they are not, and nothing is asked
     * there); at least 99% must agree (a coarse triangle across a fold of S may project
     * where S faces elsewhere), and a consistently oriented component facing inward would
     * fail them all. The exact orientation test, every triangle against its dual segment,
     * is in the star check. */
    size_t agree = 0, tested = 0;
    for (size_t t = 0; t < m->nt; t++) {
        const double *a = m->xyz + 3 * (size_t)m->tri[3 * t],
                     *b = m->xyz + 3 * (size_t)m->tri[3 * t + 1],
                     *c = m->xyz + 3 * (size_t)m->tri[3 * t + 2];
        double u[3], v[3], n[3], g[3], q[3], ns[3];
        sub3(b, a, u);
        sub3(c, a, v);
        cross3(u, v, n);
        for (int k = 0; k < 3; k++) g[k] = (a[k] + b[k] + c[k]) / 3;
        int sing = 0;
        if (as_surface_project(ctx, s, g, q) != ANISTAR_OK ||
            as_surface_normal_at(ctx, s, q, ns, &sing) != ANISTAR_OK) {
            mc_fail(r, "triangle %zu: surface normal failed: %s", t, anistar_last_error(ctx));
            return;
        }
        if (sing || !(dot3(n, n) > 0)) continue;
        const double *P[3] = {a, b, c};
        double nv[3][3];
        int resolved = 1;
        for (int k = 0; k < 3 && resolved; k++) {
            int sg = 0;
            if (as_surface_normal_at(ctx, s, P[k], nv[k], &sg) != ANISTAR_OK) {
                mc_fail(r, "triangle %zu: surface normal failed: %s", t, anistar_last_error(ctx));
                return;
            }
            if (sg) resolved = 0;
        }
        if (!resolved || !(dot3(nv[0], nv[1]) > 0 && dot3(nv[1], nv[2]) > 0 &&
                           dot3(nv[2], nv[0]) > 0)) {
            r->orient_unresolved++;
            continue;
        }
        tested++;
        agree += dot3(n, ns) > 0;
    }
    if (!(agree >= tested - tested / 100))
        mc_fail(r, "only %zu of %zu triangles face outward", agree, tested);
}

/* ---- stars ---------------------------------------------------------------------------- */

static int cmp_tri(const void *a, const void *b) {
    const int32_t *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}
static void sort3(int32_t g[3]) {
    for (int a = 0; a < 3; a++)
        for (int b = a + 1; b < 3; b++)
            if (g[b] < g[a]) {
                int32_t t = g[a];
                g[a] = g[b];
                g[b] = t;
            }
}

/* Reorder idx[lo..hi] so that the k smallest keys come first (iterative quickselect). */
static void select_k(int32_t *idx, const double *key, size_t n, size_t k) {
    size_t lo = 0, hi = n;
    while (hi - lo > 1 && k > lo && k < hi) {
        double piv = key[idx[lo + (hi - lo - 1) / 2]]; /* never the last: j < hi - 1 */
        size_t i = lo, j = hi - 1;
        for (;;) {
            while (key[idx[i]] < piv) i++;
            while (key[idx[j]] > piv) j--;
            if (i >= j) break;
            int32_t t = idx[i];
            idx[i] = idx[j];
            idx[j] = t;
            i++;
            j--;
        }
        /* [lo, j] <= piv <= [j+1, hi) */
        if (k <= j) hi = j + 1;
        else lo = j + 1;
    }
}

/* Scratch of the star check. */
typedef struct star_work {
    int32_t npts;         /* extra + output vertices */
    double *pts;          /* 3 npts: every point, in global-id order */
    double *dist2;        /* per output vertex: squared M_i distance to vertex i */
    int32_t *order;       /* output vertices, K nearest first */
    double *sel;          /* 3 npts: the points triangulated */
    int64_t *gid;         /* their global ids */
    int32_t *vx;          /* their del3 vertices */
    int32_t *found;       /* 4 per restricted facet: sorted global ids, index into fdir */
    double *fdir;         /* 3 per restricted facet: its dual segment, inside end to outside */
    size_t cap_found;
    double *balls;        /* 5 per tet around the vertex (in_some_ball): 2 u (u = its
                             circumcenter - F x_i), 1e-9 |u|^2, 4 |u|^2 (1 + 1e-6); sorted
                             by radius, largest first */
    size_t cap_balls;
    as_kdtree *kd;        /* the output vertices, by global id (candidates by box) */
    as_idlist ids;        /* a box query's result */
    int64_t *mark;        /* per point: the vertex whose selection holds it */
} star_work;

/* The points in the box of the M-ball of radius r around x (a superset of the ball),
 * into w->ids. */
static void ball_candidates(anistar_context *ctx, star_work *w, const as_metric_frame *mf,
                            const double x[3], double r) {
    double h[3], lo[3], hi[3];
    as_metric_ellipsoid_box(mf, r * (1 + 1e-9), h);
    for (int k = 0; k < 3; k++) {
        lo[k] = x[k] - h[k];
        hi[k] = x[k] + h[k];
    }
    assert_int_equal(as_kdtree_box_any(ctx, w->kd, lo, hi, 0, &w->ids), ANISTAR_OK);
}

/* z = F x_j - yi for point j (global id: extra sites, then output vertices) and
 * yi = F x_i; returns |z|^2, the squared M distance. */
static double mdiff(const as_metric_frame *mf, const star_work *w, size_t j, const double yi[3],
                    double z[3]) {
    double y[3];
    as_metric_apply(mf, w->pts + 3 * j, y);
    sub3(y, yi, z);
    return dot3(z, z);
}

/* Squared M distance from point j to yi = F x_i. */
static double mdist2(const as_metric_frame *mf, const star_work *w, size_t j,
                     const double yi[3]) {
    double z[3];
    return mdiff(mf, w, j, yi, z);
}

/* Rebuild i's triangulation from the k selected points w->order[0..k) (global ids: the
 * extra sites, then the output vertices). Returns i's del3 vertex, or -1 on failure
 * (reported). */
static int32_t rebuild(anistar_context *ctx, star_work *w, int32_t nextra, size_t k, size_t i,
                       const as_metric_frame *mf, as_del3 *d, mc_report *r) {
    int32_t n = 0, me = -1;
    for (size_t q = 0; q < k; q++, n++) {
        int32_t j = w->order[q];
        if (j == nextra + (int32_t)i) me = n;
        memcpy(w->sel + 3 * (size_t)n, w->pts + 3 * (size_t)j, 3 * sizeof(double));
        w->gid[n] = j;
    }
    as_del3_reset(d);
    anistar_status st = as_del3_insert_points(d, w->sel, w->gid, n, mf, w->vx, NULL);
    if (st != ANISTAR_OK || me < 0) {
        mc_fail(r, "vertex %zu: rebuilding its triangulation failed: %s", i,
                st ? anistar_last_error(ctx) : "the vertex was not selected");
        return -1;
    }
    if ((size_t)n > r->star_points_max) r->star_points_max = (size_t)n;
    return w->vx[me];
}

/*
 * Whether x (on S) lies on an unsampled speck: a closed piece of S that fits in the box of
 * half-side 2.125 hmin around x and holds no output vertex. The contract leaves such
 * pieces out (below the surface's resolution, hmin; docs/algorithm.md, "At the surface's
 * resolution"), and a restricted facet whose dual segment crosses one has no vertex on
 * it. design: the signs of S's function on a grid of spacing hmin/4, x at a cell's
 * centre; from the corners of that cell of each sign, a flood over the nodes of that sign;
 * a side whose flood never reaches the box's boundary is enclosed by S within the box; a
 * speck when no output vertex lies in the box of the flood (grown by a cell). Pieces
 * thinner than the grid are below the resolution as well.
 */
#define SPECK_N 18
static int unsampled_speck(anistar_context *ctx, const as_surface *s, star_work *w,
                           const double x[3], double hmin, int *bsign, double blo[3],
                           double bhi[3]) {
    if (!(hmin > 0)) return 0;
    enum { N = SPECK_N };
    const double h = hmin / 4;
    double lo[3];
    for (int k = 0; k < 3; k++) lo[k] = x[k] - (N / 2 - 0.5) * h;
    signed char sg[N * N * N];
    for (int a = 0; a < N; a++)
        for (int b = 0; b < N; b++)
            for (int c = 0; c < N; c++) {
                double p[3] = {lo[0] + a * h, lo[1] + b * h, lo[2] + c * h};
                int side;
                if (as_surface_side(ctx, s, p, &side) != ANISTAR_OK) return 0;
                sg[(a * N + b) * N + c] = (signed char)(side < 0 ? -1 : 1);
            }
    int queue[N * N * N];
    unsigned char seen[N * N * N];
    for (int sign = -1; sign <= 1; sign += 2) {
        memset(seen, 0, sizeof seen);
        int nq = 0, open = 0;
        int bl[3] = {N, N, N}, bh[3] = {-1, -1, -1};
        for (int cn = 0; cn < 8; cn++) {
            int id = ((N / 2 - 1 + (cn & 1)) * N + (N / 2 - 1 + ((cn >> 1) & 1))) * N +
                     (N / 2 - 1 + ((cn >> 2) & 1));
            if (sg[id] == sign && !seen[id]) {
                seen[id] = 1;
                queue[nq++] = id;
            }
        }
        if (nq == 0) continue;
        for (int q = 0; q < nq && !open; q++) {
            int id = queue[q], ix[3] = {id / (N * N), (id / N) % N, id % N};
            for (int k = 0; k < 3; k++) {
                if (ix[k] == 0 || ix[k] == N - 1) open = 1;
                if (ix[k] < bl[k]) bl[k] = ix[k];
                if (ix[k] > bh[k]) bh[k] = ix[k];
            }
            for (int k = 0; k < 3 && !open; k++)
                for (int dlt = -1; dlt <= 1; dlt += 2) {
                    int jx[3] = {ix[0], ix[1], ix[2]};
                    jx[k] += dlt;
                    int j = (jx[0] * N + jx[1]) * N + jx[2];
                    if (sg[j] == sign && !seen[j]) {
                        seen[j] = 1;
                        queue[nq++] = j;
                    }
                }
        }
        if (open) continue;
        *bsign = sign;
        for (int k = 0; k < 3; k++) {
            blo[k] = lo[k] + (bl[k] - 1) * h;
            bhi[k] = lo[k] + (bh[k] + 1) * h;
        }
        if (as_kdtree_box_any(ctx, w->kd, blo, bhi, 0, &w->ids) != ANISTAR_OK) return 0;
        if (w->ids.n == 0) return 1;
    }
    return 0;
}

/* Balls by their stop bound (their radius), largest first. */
static int cmp_ball(const void *a, const void *b) {
    double x = ((const double *)a)[4], y = ((const double *)b)[4];
    return (x < y) - (x > y);
}

/* Whether z (= F x_j - F x_i, |z|^2 = zz) is in (or on, within the slack) one of the nb
 * sorted balls: z . a_b + s_b >= zz, i.e. |z - u_b|^2 <= (1 + 1e-9) |u_b|^2. A ball of
 * radius below |z| / 2 cannot hold it (nor any after it). */
static int in_some_ball(const star_work *w, size_t nb, const double z[3], double zz) {
    const double *b = w->balls;
    for (size_t q = 0; q < nb && !(zz > b[5 * q + 4]); q++) {
        const double *a = b + 5 * q;
        if ((z[0] * a[0] + z[1] * a[1]) + (z[2] * a[2] + a[3]) >= zz) return 1;
    }
    return 0;
}

/* Check the star of output vertex i (see mesh_check.h). */
static void check_one(anistar_context *ctx, const as_surface *s, star_work *w, int32_t nextra,
                      const as_trimesh *m, const int32_t *vt_start, const int32_t *vt_tris,
                      const int32_t *sorted_tris, const mc_limits *lim, size_t i, as_del3 *d,
                      as_del3_buf *buf, mc_report *r) {
    as_metric_frame mf;
    if (as_metric_frame_init(&mf, m->tensor + 6 * i) != 0) {
        mc_fail(r, "vertex %zu: tensor not positive definite", i);
        return;
    }
    const size_t nv = (size_t)w->npts; /* every point: the extra sites and the vertices */
    double yi[3];
    as_metric_apply(&mf, m->xyz + 3 * i, yi);
    const double *xi = m->xyz + 3 * i;
    /* the eight box corners (extra sites 0-7: they enclose every point, so every tet
     * around i is finite) and the 16 M-nearest poles (they bound the balls on both sides
     * of S: without poles the balls toward the far side reach across the whole mesh),
     * then the 48 M-nearest vertices: the 48 Euclidean-nearest are within M distance ub,
     * so the box of the M-ball of radius ub holds the 48 M-nearest. The other poles join
     * like the vertices, when one lies in a ball (a scan of them each round): starting
     * with all 256 made every rebuild a triangulation of some 300 points, most of the
     * checks' time */
    const int32_t ncorner = nextra < 8 ? nextra : 8;
    const size_t npole = (size_t)(nextra - ncorner), kp = npole < 16 ? npole : 16;
    const size_t nvert = m->nv, kv = nvert < 48 ? nvert : 48;
    size_t k = (size_t)ncorner + kp + kv;
    {
        for (int32_t e = 0; e < ncorner; e++) {
            w->order[e] = e;
            w->mark[e] = (int64_t)i;
        }
        int32_t *pc = w->order + ncorner;
        for (size_t q = 0; q < npole; q++) {
            int32_t j = ncorner + (int32_t)q;
            w->dist2[j] = mdist2(&mf, w, (size_t)j, yi);
            pc[q] = j;
        }
        select_k(pc, w->dist2, npole, kp);
        for (size_t q = 0; q < kp; q++) w->mark[pc[q]] = (int64_t)i;
        int32_t kid[48];
        double kd2[48], ub = 0;
        size_t got = as_kdtree_knn(w->kd, xi, kv, kid, kd2);
        assert_int_equal(got, kv);
        for (size_t q = 0; q < got; q++) {
            double d2 = mdist2(&mf, w, (size_t)kid[q], yi);
            if (d2 > ub) ub = d2;
        }
        ball_candidates(ctx, w, &mf, xi, sqrt(ub));
        size_t nc = 0;
        int32_t *cand = w->order + ncorner + kp;
        for (size_t q = 0; q < w->ids.n; q++) {
            int32_t j = w->ids.ids[q];
            w->dist2[j] = mdist2(&mf, w, (size_t)j, yi);
            cand[nc++] = j;
        }
        assert_true(nc >= kv);
        select_k(cand, w->dist2, nc, kv);
        for (size_t q = 0; q < kv; q++) w->mark[cand[q]] = (int64_t)i;
    }
    int32_t v = rebuild(ctx, w, nextra, k, i, &mf, d, r);
    if (v < 0) return;
    for (;;) {
        if (k == nv) {
            r->stars_full++;
            break;
        }
        /* certificate: no vertex left out lies in (or on) the circumball of a tet around
         * v; a vertex beyond 2 rho_max of v cannot, the others (found by box) are tested
         * one by one */
        if (as_del3_vertex_tets(d, v, buf) != ANISTAR_OK) {
            mc_fail(r, "vertex %zu: %s", i, anistar_last_error(ctx));
            return;
        }
        size_t nb = buf->n;
        if (nb > w->cap_balls) {
            w->cap_balls = 2 * nb;
            w->balls = realloc(w->balls, 5 * w->cap_balls * sizeof *w->balls);
            assert_non_null(w->balls);
        }
        double reach = 0;
        int bounded = 1;
        for (size_t q = 0; q < nb && bounded; q++) {
            double c[3];
            if (as_del3_circumcenter(d, buf->a[q], c) != 0) {
                bounded = 0; /* an infinite tet: v is on the hull of the subset */
                break;
            }
            double *b = w->balls + 5 * q, u[3];
            sub3(c, yi, u); /* yi: v's point in d, bit for bit (as_metric_apply both) */
            double r2 = dot3(u, u);
            for (int h = 0; h < 3; h++) b[h] = 2 * u[h];
            b[3] = 1e-9 * r2;
            b[4] = 4 * r2 * (1 + 1e-6);
            if (4 * r2 > reach) reach = 4 * r2;
        }
        if (!bounded) {
            /* twice as many vertices: the nearest of those left out, by a scan (rare: a
             * vertex on the hull of its subset) */
            size_t nk = 2 * k < nv ? 2 * k : nv, nl = 0;
            for (size_t j = 0; j < nv; j++)
                if (w->mark[j] != (int64_t)i) {
                    w->dist2[j] = mdist2(&mf, w, j, yi);
                    w->order[k + nl++] = (int32_t)j;
                }
            select_k(w->order + k, w->dist2, nl, nk - k);
            for (size_t q = k; q < nk; q++) w->mark[w->order[q]] = (int64_t)i;
            k = nk;
            v = rebuild(ctx, w, nextra, k, i, &mf, d, r);
            if (v < 0) return;
            continue;
        }
        /* largest first (in_some_ball); the slack of 1e-9 on the squared radius is for
         * the rounding of the circumcenters and distances */
        qsort(w->balls, nb, 5 * sizeof *w->balls, cmp_ball);
        /* the vertices left out that lie in (or on) a ball join the selection and are
         * inserted: the triangulation is the same as a rebuild with them (Delaunay with
         * symbolic perturbation is unique), then the certificate is checked again */
        size_t nviol = 0;
        ball_candidates(ctx, w, &mf, xi, sqrt(reach));
        /* the candidates: the vertices in the box of the reach, then the poles left out */
        for (size_t q = 0; q < w->ids.n + (size_t)(nextra - ncorner); q++) {
            int32_t j = q < w->ids.n ? w->ids.ids[q] : ncorner + (int32_t)(q - w->ids.n);
            if (w->mark[j] == (int64_t)i) continue;
            double z[3], zz = mdiff(&mf, w, (size_t)j, yi, z);
            if (zz > reach * (1 + 1e-6)) continue;
            if (in_some_ball(w, nb, z, zz)) {
                w->order[k + nviol++] = j;
                w->mark[j] = (int64_t)i;
            }
        }
        if (nviol == 0) break;
        /* in one bulk insertion (Hilbert order: short walks) */
        for (size_t q = 0; q < nviol; q++) {
            int32_t j = w->order[k + q];
            memcpy(w->sel + 3 * q, w->pts + 3 * (size_t)j, 3 * sizeof(double));
            w->gid[q] = j;
        }
        int32_t ndup = 0;
        anistar_status rc = as_del3_insert_points(d, w->sel, w->gid, (int32_t)nviol, &mf, NULL,
                                                  &ndup);
        if (rc != ANISTAR_OK || ndup != 0) {
            mc_fail(r, "vertex %zu: inserting %zu vertices failed: %s", i, nviol,
                    rc != ANISTAR_OK ? anistar_last_error(ctx) : "a duplicate point");
            return;
        }
        k += nviol;
        if (k > r->star_points_max) r->star_points_max = k;
    }
    r->stars_checked++;
    /* restricted facets of v: dual segment with one end inside S and the other outside */
    if (as_del3_vertex_facets(d, v, buf) != ANISTAR_OK) {
        mc_fail(r, "vertex %zu: %s", i, anistar_last_error(ctx));
        return;
    }
    size_t nf = 0;
    for (size_t q = 0; q < buf->n; q++) {
        int32_t f = buf->a[q], t[2] = {f >> 2, as_del3_mirror(d, f) >> 2};
        double c[2][3];
        int in[2];
        int ok = 1;
        for (int h = 0; h < 2; h++) {
            double cc[3];
            int side;
            if (as_del3_circumcenter(d, t[h], cc) != 0) {
                ok = 0;
                break;
            }
            as_metric_unapply(&mf, cc, c[h]);
            if (as_surface_side(ctx, s, c[h], &side) != ANISTAR_OK) {
                mc_fail(r, "vertex %zu: %s", i, anistar_last_error(ctx));
                return;
            }
            in[h] = side < 0;
        }
        if (!ok) {
            mc_fail(r, "vertex %zu: an infinite tet around it (not enclosed by the corners)", i);
            return;
        }
        if (in[0] == in[1]) continue;
        if (nf == w->cap_found) {
            w->cap_found *= 2;
            w->found = realloc(w->found, 4 * w->cap_found * sizeof *w->found);
            w->fdir = realloc(w->fdir, 3 * w->cap_found * sizeof *w->fdir);
            assert_non_null(w->found);
            assert_non_null(w->fdir);
        }
        int32_t *g = w->found + 4 * nf, lv[3];
        g[3] = (int32_t)nf;
        for (int h = 0; h < 3; h++) w->fdir[3 * nf + (size_t)h] = c[in[0] ? 1 : 0][h] - c[in[0] ? 0 : 1][h];
        nf++;
        int n = 0;
        for (int j = 0; j < 4; j++)
            if (j != (f & 3)) {
                lv[n] = as_del3_tet_vertex(d, t[0], j);
                g[n] = (int32_t)d->gid[lv[n]];
                n++;
            }
        sort3(g);
        /* surface circumradius: crossing nearest the facet's circumcenter */
        double fcs[3], fc[3], x[3];
        int hit = 0;
        if (tri_center(as_del3_point(d, lv[0]), as_del3_point(d, lv[1]),
                       as_del3_point(d, lv[2]), fcs) == 0)
            as_metric_unapply(&mf, fcs, fc);
        else
            for (int h = 0; h < 3; h++) fc[h] = 0.5 * (c[0][h] + c[1][h]);
        if (as_surface_crossing(ctx, s, c[0], c[1], fc, &hit, x) != ANISTAR_OK || !hit) {
            mc_fail(r, "vertex %zu: no crossing of a dual segment with S", i);
            continue;
        }
        double rad = as_metric_dist(&mf, x, m->xyz + 3 * i);
        int held = 0;
        for (int h = 0; h < 3 && lim->hmin > 0; h++) {
            if (g[h] < (int32_t)nextra) continue;
            double e[3];
            sub3(x, m->xyz + 3 * (size_t)(g[h] - (int32_t)nextra), e);
            if (dot3(e, e) < lim->hmin * lim->hmin * (1 + 1e-9)) held = 1;
        }
        /* a facet with a corner or a pole, or too large, whose crossing is on a speck of S
         * that no vertex samples (below the resolution): when an end of its dual segment
         * is inside the speck, the speck alone makes it restricted and it is left out;
         * otherwise the segment passes through the speck (two crossings) and crosses S
         * elsewhere too, so the facet stays but this crossing does not size it */
        int bsign;
        double blo[3], bhi[3];
        if ((g[0] < (int32_t)nextra || (!held && !(rad < lim->r0 * (1 + 1e-9)))) &&
            unsampled_speck(ctx, s, w, x, lim->hmin, &bsign, blo, bhi)) {
            int end_in = 0;
            for (int h = 0; h < 2; h++) {
                int inbox = 1;
                for (int k = 0; k < 3; k++)
                    if (!(c[h][k] >= blo[k] && c[h][k] <= bhi[k])) inbox = 0;
                if (inbox && (in[h] ? -1 : 1) == bsign) end_in = 1;
            }
            r->specks_unsampled++;
            if (end_in) {
                nf--;
                continue;
            }
            held = 1;
        }
        if (rad > r->r_max) r->r_max = rad;
        if (!held && !(rad < lim->r0 * (1 + 1e-9)))
            mc_fail(r, "vertex %zu: facet (%d %d %d) has surface circumradius %.17g >= r0 %g at (%.9g, %.9g, %.9g)",
                    i, g[0], g[1], g[2], rad, lim->r0, x[0], x[1], x[2]);
    }
    qsort(w->found, nf, 4 * sizeof *w->found, cmp_tri);
    /* the output triangles incident to i, as sorted global ids */
    size_t no = (size_t)(vt_start[i + 1] - vt_start[i]);
    int same = no == nf;
    for (size_t q = 0; same && q < no; q++)
        if (memcmp(sorted_tris + 4 * (size_t)vt_tris[vt_start[i] + (int32_t)q], w->found + 4 * q,
                   3 * sizeof(int32_t)) != 0)
            same = 0;
    /* orientation: each output triangle's normal points along its dual segment from the
     * end inside S to the end outside (a linear map with positive determinant, the
     * metric's square root, keeps the sign of that product) */
    for (size_t q = 0; same && q < no; q++) {
        const int32_t *st = sorted_tris + 4 * (size_t)vt_tris[vt_start[i] + (int32_t)q];
        int32_t o[3] = {st[0], st[3] ? st[2] : st[1], st[3] ? st[1] : st[2]};
        double u[3], v[3], n[3];
        sub3(w->pts + 3 * (size_t)o[1], w->pts + 3 * (size_t)o[0], u);
        sub3(w->pts + 3 * (size_t)o[2], w->pts + 3 * (size_t)o[0], v);
        cross3(u, v, n);
        const double *dir = w->fdir + 3 * (size_t)w->found[4 * q + 3];
        r->orient_tested++;
        if (!(dot3(n, dir) > 0))
            mc_fail(r, "vertex %zu: triangle (%d %d %d) faces against its dual segment (from "
                       "inside S to outside)", i, o[0], o[1], o[2]);
    }
    if (!same)
        mc_fail(r, "vertex %zu: its restricted Delaunay star has %zu facets, the output %zu "
                   "triangles, and they differ", i, nf, no);
}

void mc_check_stars(anistar_context *ctx, const as_surface *s, const double *extra,
                    int32_t nextra, const as_trimesh *m, const mc_limits *lim, size_t stride,
                    mc_report *r) {
    if (!m->tensor || m->nv == 0) {
        mc_fail(r, "the star check needs vertices with tensors");
        return;
    }
    size_t nv = m->nv, nt = m->nt;
    star_work w;
    w.npts = nextra + (int32_t)nv;
    w.pts = xmalloc(3 * (size_t)w.npts * sizeof *w.pts);
    memcpy(w.pts, extra, 3 * (size_t)nextra * sizeof *w.pts);
    memcpy(w.pts + 3 * (size_t)nextra, m->xyz, 3 * nv * sizeof *w.pts);
    w.dist2 = xmalloc((size_t)w.npts * sizeof *w.dist2);
    w.order = xmalloc((size_t)w.npts * sizeof *w.order);
    w.sel = xmalloc(3 * (size_t)w.npts * sizeof *w.sel);
    w.gid = xmalloc((size_t)w.npts * sizeof *w.gid);
    w.vx = xmalloc((size_t)w.npts * sizeof *w.vx);
    w.cap_found = 64;
    w.found = xmalloc(4 * w.cap_found * sizeof *w.found);
    w.fdir = xmalloc(3 * w.cap_found * sizeof *w.fdir);
    w.cap_balls = 64;
    w.balls = xmalloc(5 * w.cap_balls * sizeof *w.balls);
    w.kd = NULL;
    int32_t *vid = xmalloc(nv * sizeof *vid);
    for (size_t j = 0; j < nv; j++) vid[j] = nextra + (int32_t)j;
    assert_int_equal(as_kdtree_build(ctx, m->xyz, vid, nv, &w.kd), ANISTAR_OK);
    free(vid);
    memset(&w.ids, 0, sizeof w.ids);
    w.mark = xmalloc((size_t)w.npts * sizeof *w.mark);
    for (int32_t j = 0; j < w.npts; j++) w.mark[j] = -1;
    /* output triangles as sorted global-id triples, sorted; vertex -> triangles (CSR) in
     * that order, so each vertex's list comes out sorted */
    int32_t *tris = xmalloc(4 * nt * sizeof *tris);
    for (size_t t = 0; t < nt; t++) {
        /* sorted ids and the parity of the sort (1: the output order is odd) */
        int32_t *x = tris + 4 * t;
        for (int k = 0; k < 3; k++) x[k] = m->tri[3 * t + k] + nextra;
        int swaps = 0;
        for (int a = 0; a < 3; a++)
            for (int b = a + 1; b < 3; b++)
                if (x[b] < x[a]) {
                    int32_t y = x[a];
                    x[a] = x[b];
                    x[b] = y;
                    swaps++;
                }
        x[3] = swaps & 1;
    }
    qsort(tris, nt, 4 * sizeof *tris, cmp_tri);
    int32_t *start = calloc(nv + 1, sizeof *start);
    int32_t *fill = calloc(nv + 1, sizeof *fill);
    int32_t *vt = xmalloc(3 * nt * sizeof *vt);
    assert_non_null(start);
    assert_non_null(fill);
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) start[tris[4 * t + (size_t)k] - nextra + 1]++;
    for (size_t i = 0; i < nv; i++) start[i + 1] += start[i];
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) {
            int32_t i = tris[4 * t + (size_t)k] - nextra;
            vt[start[i] + fill[i]++] = (int32_t)t;
        }
    as_del3 d;
    as_del3_init(&d, ctx);
    as_del3_buf buf = {0};
    if (stride < 1) stride = 1;
    for (size_t i = 0; i < nv; i += stride)
        check_one(ctx, s, &w, nextra, m, start, vt, tris, lim, i, &d, &buf, r);
    as_del3_buf_free(ctx, &buf);
    as_del3_destroy(&d);
    free(vt);
    free(fill);
    free(start);
    free(tris);
    as_kdtree_free(ctx, w.kd);
    as_idlist_free(ctx, &w.ids);
    free(w.mark);
    free(w.balls);
    free(w.found);
    free(w.fdir);
    free(w.vx);
    free(w.gid);
    free(w.sel);
    free(w.order);
    free(w.dist2);
    free(w.pts);
}

void mc_check_all(anistar_context *ctx, const as_surface *s, const double *extra,
                  int32_t nextra, const as_trimesh *m, const mc_limits *lim, mc_report *r) {
    mc_check_topology(ctx, m, lim, r);
    mc_check_shape(m, lim, r);
    mc_check_on_surface(ctx, s, m, lim, r);
    mc_check_stars(ctx, s, extra, nextra, m, lim, 1, r);
}
