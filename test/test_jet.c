/*
 * test_jet.c — jet fitting and Gaussian blending (lib/surface/jet.c):
 *  - exactness: points on a polynomial height function of degree <= d over a given frame
 *    (rotated, translated, origin off the surface) give the exact normal, curvatures and
 *    directions (the reference is the generic implicit-surface frame of surface.c, an
 *    independent computation from the function's exact derivatives);
 *  - convergence on analytic surfaces (sphere, ellipsoid, torus, a cubic saddle) with the
 *    PCA frame: degree 2 and 4 errors shrink with the neighbourhood, degree 4 faster;
 *  - orientation, degenerate inputs, degree fallback;
 *  - blending: constant fields, agreement with the untruncated formula of the paper,
 *    continuity exactly at the cutoff and where the nearest vertex changes, SPD
 *    everywhere, far points, the default radius, allocation failures.
 */
#include "test_util.h"

#include "geom/kdtree.h"
#include "geom/linalg.h"
#include "surface/jet.h"
#include "surface/surface.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }
static void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static void rand_unit(tu_rng *r, double u[3]) {
    double n;
    do {
        for (int i = 0; i < 3; i++) u[i] = tu_rng_range(r, -1, 1);
        n = norm3(u);
    } while (n > 1 || n < 0.1);
    for (int i = 0; i < 3; i++) u[i] /= n;
}
/* A random right-handed orthonormal frame u1, u2, w. */
static void rand_frame(tu_rng *r, double fr[9]) {
    double a[3], b[3];
    rand_unit(r, fr + 6);
    do {
        rand_unit(r, a);
        cross3(fr + 6, a, b);
    } while (norm3(b) < 0.3);
    for (int i = 0; i < 3; i++) fr[i] = b[i] / norm3(b); /* u1 */
    cross3(fr + 6, fr, fr + 3);                         /* u2 = w x u1 */
}

/* ---- a polynomial height function over a frame, as an implicit surface ------------- */

typedef struct poly_surf {
    double fr[9], t[3]; /* frame and translation */
    double c[15];       /* z = sum c[t(t+1)/2 + j] x^(t-j) y^j */
    int degree;
} poly_surf;

/* P and its derivatives up to order 2 at (x, y). */
static void poly_eval(const poly_surf *ps, double x, double y, double *P, double *Px, double *Py,
                      double *Pxx, double *Pxy, double *Pyy) {
    *P = *Px = *Py = *Pxx = *Pxy = *Pyy = 0;
    int idx = 0;
    for (int t = 0; t <= ps->degree; t++)
        for (int j = 0; j <= t; j++, idx++) {
            int i = t - j;
            double c = ps->c[idx];
            *P += c * pow(x, i) * pow(y, j);
            if (i >= 1) *Px += c * i * pow(x, i - 1) * pow(y, j);
            if (j >= 1) *Py += c * j * pow(x, i) * pow(y, j - 1);
            if (i >= 2) *Pxx += c * i * (i - 1) * pow(x, i - 2) * pow(y, j);
            if (i >= 1 && j >= 1) *Pxy += c * i * j * pow(x, i - 1) * pow(y, j - 1);
            if (j >= 2) *Pyy += c * j * (j - 1) * pow(x, i) * pow(y, j - 2);
        }
}

static void poly_local(const poly_surf *ps, const double p[3], double l[3]) {
    double d[3] = {p[0] - ps->t[0], p[1] - ps->t[1], p[2] - ps->t[2]};
    for (int k = 0; k < 3; k++) l[k] = dot3(d, ps->fr + 3 * k);
}

static double ps_value(const double p[3], void *user) {
    const poly_surf *ps = user;
    double l[3], P, a, b, c, d, e;
    poly_local(ps, p, l);
    poly_eval(ps, l[0], l[1], &P, &a, &b, &c, &d, &e);
    return l[2] - P;
}
static void ps_grad(const double p[3], double g[3], void *user) {
    const poly_surf *ps = user;
    double l[3], P, Px, Py, c, d, e;
    poly_local(ps, p, l);
    poly_eval(ps, l[0], l[1], &P, &Px, &Py, &c, &d, &e);
    for (int i = 0; i < 3; i++) g[i] = ps->fr[6 + i] - Px * ps->fr[i] - Py * ps->fr[3 + i];
}
static void ps_hess(const double p[3], double h[6], void *user) {
    const poly_surf *ps = user;
    double l[3], P, Px, Py, Pxx, Pxy, Pyy;
    poly_local(ps, p, l);
    poly_eval(ps, l[0], l[1], &P, &Px, &Py, &Pxx, &Pxy, &Pyy);
    const double *u = ps->fr, *v = ps->fr + 3;
    static const int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int e = 0; e < 6; e++) {
        int a = ij[e][0], b = ij[e][1];
        h[e] = -(Pxx * u[a] * u[b] + Pxy * (u[a] * v[b] + v[a] * u[b]) + Pyy * v[a] * v[b]);
    }
}

/* The world point of local (x, y, P(x, y)). */
static void ps_point(const poly_surf *ps, double x, double y, double p[3]) {
    double P, a, b, c, d, e;
    poly_eval(ps, x, y, &P, &a, &b, &c, &d, &e);
    for (int i = 0; i < 3; i++)
        p[i] = ps->t[i] + x * ps->fr[i] + y * ps->fr[3 + i] + P * ps->fr[6 + i];
}

/* Compare a jet with a reference frame: normal, curvatures (relative to max(1, |k|)),
 * directions (up to sign) when the curvatures are distinct. Returns the largest error. */
static double jet_error(const as_jet *j, const as_surface_frame *fr) {
    double e = 0, sc = fmax(1, fmax(fabs(fr->k[0]), fabs(fr->k[1])));
    double dn[3] = {j->n[0] - fr->n[0], j->n[1] - fr->n[1], j->n[2] - fr->n[2]};
    e = fmax(e, norm3(dn));
    e = fmax(e, fabs(j->k[0] - fr->k[0]) / sc);
    e = fmax(e, fabs(j->k[1] - fr->k[1]) / sc);
    if (fr->k[0] - fr->k[1] > 1e-3 * sc) {
        e = fmax(e, 1 - fabs(dot3(j->d, fr->d)));
        e = fmax(e, 1 - fabs(dot3(j->d + 3, fr->d + 3)));
    }
    return e;
}

static void check_jet_frame(const as_jet *j) {
    /* (d0, d1, n) right-handed orthonormal, k0 >= k1 */
    double c[3];
    assert_true(j->k[0] >= j->k[1]);
    assert_true(fabs(norm3(j->n) - 1) < 1e-12);
    assert_true(fabs(norm3(j->d) - 1) < 1e-12 && fabs(norm3(j->d + 3) - 1) < 1e-12);
    assert_true(fabs(dot3(j->d, j->n)) < 1e-12 && fabs(dot3(j->d + 3, j->n)) < 1e-12);
    cross3(j->d, j->d + 3, c);
    assert_true(dot3(c, j->n) > 1 - 1e-12);
}

/* Exactness on polynomial height functions over the given frame. */
static void test_exact_polynomials(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {11};
    for (int trial = 0; trial < 60; trial++) {
        poly_surf ps;
        memset(&ps, 0, sizeof ps);
        rand_frame(&r, ps.fr);
        for (int i = 0; i < 3; i++) ps.t[i] = tu_rng_range(&r, -3, 3);
        ps.degree = 1 + trial % 4; /* 1..4 */
        int ncoef = as_jet_coef_count(ps.degree);
        for (int i = 0; i < ncoef; i++) ps.c[i] = tu_rng_range(&r, -2, 2);
        double h = tu_rng_range(&r, 0.05, 2); /* any scale */
        size_t n = (size_t)(19 + trial % 30);
        double pts[3 * AS_JET_MAX_POINTS];
        for (size_t i = 0; i < n; i++)
            ps_point(&ps, tu_rng_range(&r, -h, h), tu_rng_range(&r, -h, h), pts + 3 * i);
        /* origin: off the surface along w (the jet's Monge point is P(0,0) above it) */
        double origin[3], monge[3], off = tu_rng_range(&r, -0.5, 0.5) * h;
        ps_point(&ps, 0, 0, monge);
        for (int i = 0; i < 3; i++) origin[i] = ps.t[i] + off * ps.fr[6 + i];
        as_implicit_fn fn = {ps_value, ps_grad, ps_hess, &ps};
        as_surface *s;
        double c0[3] = {0, 0, 0};
        assert_int_equal(as_implicit_create(ctx, &fn, c0, 100, &s), ANISTAR_OK);
        as_surface_frame ref;
        assert_int_equal(as_surface_frame_at(ctx, s, monge, &ref), ANISTAR_OK);
        for (int d = ps.degree; d <= 4; d++) {
            if (d < 2 && ps.degree < 2) continue; /* degree 1 checked below */
            as_jet j;
            assert_int_equal(as_jet_fit(pts, n, origin, d, ps.fr, ps.fr + 6, &j), 0);
            assert_int_equal(j.degree, d);
            check_jet_frame(&j);
            double e = jet_error(&j, &ref);
            if (e > 1e-8)
                fail_msg("trial %d: poly degree %d fitted with degree %d: error %g", trial,
                         ps.degree, d, e);
            double dm[3] = {j.point[0] - monge[0], j.point[1] - monge[1], j.point[2] - monge[2]};
            assert_true(norm3(dm) < 1e-9 * (1 + h));
        }
        if (ps.degree == 1) { /* a plane: zero curvature at degree 1 and 2 */
            as_jet j;
            assert_int_equal(as_jet_fit(pts, n, origin, 2, ps.fr, ps.fr + 6, &j), 0);
            assert_true(fabs(j.k[0]) < 1e-9 && fabs(j.k[1]) < 1e-9);
            assert_true(jet_error(&j, &ref) < 1e-9);
        }
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* The PCA frame on a polynomial that is symmetric enough for PCA to find w: a quadric
 * z = a x^2 + b y^2 on a symmetric grid of points has the frame's axes as principal axes,
 * so even without a given frame degree 2 is exact. */
static void test_pca_symmetric(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {5};
    for (int trial = 0; trial < 20; trial++) {
        poly_surf ps;
        memset(&ps, 0, sizeof ps);
        rand_frame(&r, ps.fr);
        ps.degree = 2;
        ps.c[3] = tu_rng_range(&r, -1, 1); /* x^2 */
        ps.c[5] = tu_rng_range(&r, -1, 1); /* y^2 */
        double h = 0.1, pts[3 * 25];
        size_t n = 0;
        for (int a = -2; a <= 2; a++)
            for (int b = -2; b <= 2; b++) ps_point(&ps, a * h, b * h, pts + 3 * n++);
        as_implicit_fn fn = {ps_value, ps_grad, ps_hess, &ps};
        as_surface *s;
        double c0[3] = {0, 0, 0};
        assert_int_equal(as_implicit_create(ctx, &fn, c0, 100, &s), ANISTAR_OK);
        as_surface_frame ref;
        assert_int_equal(as_surface_frame_at(ctx, s, ps.t, &ref), ANISTAR_OK);
        as_jet j;
        assert_int_equal(as_jet_fit(pts, n, ps.t, 2, NULL, ps.fr + 6, &j), 0);
        double e = jet_error(&j, &ref);
        if (e > 1e-9) fail_msg("trial %d: error %g", trial, e);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* n points near p0 on S (p0 included): tangent offsets of radius <= h projected on S. */
static void sample_near(anistar_context *ctx, const as_surface *s, const double p0[3],
                        const as_surface_frame *fr, double h, size_t n, tu_rng *r,
                        double *pts) {
    memcpy(pts, p0, 3 * sizeof(double));
    for (size_t i = 1; i < n; i++) {
        double rad = h * sqrt(tu_rng_range(r, 0.05, 1)), th = tu_rng_range(r, 0, 6.283185307179586);
        double q[3];
        for (int k = 0; k < 3; k++)
            q[k] = p0[k] + rad * (cos(th) * fr->d[k] + sin(th) * fr->d[3 + k]);
        assert_int_equal(as_surface_project(ctx, s, q, pts + 3 * i), ANISTAR_OK);
    }
}

/* Convergence on analytic surfaces, PCA frame: mean errors over random points. */
static void test_analytic_convergence(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    static const struct {
        const char *expr;
        double radius;
    } surfs[] = {
        {"x^2+y^2+z^2-4", 3},
        {"(x/1.5)^2+y^2+(z/0.5)^2-1", 2},
        {"(sqrt(x^2+y^2)-3)^2+z^2-1", 5},
        {"z-(0.7*x^2-0.4*y^2+0.5*x*y+0.3*x^3-0.2*x*y^2+0.1*y^3)", 4},
    };
    const double hs[3] = {0.4, 0.2, 0.1};
    tu_rng r = {3};
    for (size_t si = 0; si < sizeof surfs / sizeof surfs[0]; si++) {
        as_surface *s;
        double c0[3] = {0, 0, 0};
        assert_int_equal(as_implicit_from_expression(ctx, surfs[si].expr, c0, surfs[si].radius, &s),
                         ANISTAR_OK);
        double err[2][3] = {{0, 0, 0}, {0, 0, 0}};
        const int npts = 12;
        for (int pi = 0; pi < npts; pi++) {
            /* a random point of S: project a random point of a box */
            double q[3], p0[3];
            for (int k = 0; k < 3; k++) q[k] = tu_rng_range(&r, -1, 1);
            if (si == 2) q[0] += 3; /* near the torus tube */
            assert_int_equal(as_surface_project(ctx, s, q, p0), ANISTAR_OK);
            as_surface_frame fr;
            assert_int_equal(as_surface_frame_at(ctx, s, p0, &fr), ANISTAR_OK);
            for (int hi = 0; hi < 3; hi++) {
                double pts[3 * AS_JET_MAX_POINTS];
                for (int di = 0; di < 2; di++) {
                    int degree = di ? 4 : 2;
                    size_t n = di ? AS_JET_K4 : AS_JET_K2;
                    sample_near(ctx, s, p0, &fr, hs[hi], n, &r, pts);
                    as_jet j;
                    assert_int_equal(as_jet_fit(pts, n, p0, degree, NULL, fr.n, &j), 0);
                    assert_int_equal(j.degree, degree);
                    check_jet_frame(&j);
                    double sc = fmax(1, fmax(fabs(fr.k[0]), fabs(fr.k[1])));
                    double e = fmax(fabs(j.k[0] - fr.k[0]), fabs(j.k[1] - fr.k[1])) / sc;
                    err[di][hi] += e / npts;
                }
            }
        }
        /* degree 2: O(h) at least; degree 4: O(h^3) expected, at least much faster; and
         * degree 4 beats degree 2 at the smallest neighbourhood */
        if (!(err[0][2] < err[0][0] / 2.5) || !(err[1][2] < err[1][0] / 10) ||
            !(err[1][2] < err[0][2] / 5) || !(err[0][2] < 0.03) || !(err[1][2] < 2e-3))
            fail_msg("%s: degree 2 errors %g %g %g, degree 4 errors %g %g %g", surfs[si].expr,
                     err[0][0], err[0][1], err[0][2], err[1][0], err[1][1], err[1][2]);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* The orientation hint flips the normal; curvatures negate and swap. */
static void test_orientation(void **state) {
    (void)state;
    tu_rng r = {8};
    poly_surf ps;
    memset(&ps, 0, sizeof ps);
    rand_frame(&r, ps.fr);
    ps.degree = 2;
    ps.c[3] = -0.8;
    ps.c[4] = 0.2;
    ps.c[5] = 0.3;
    double pts[3 * 16];
    for (int i = 0; i < 16; i++)
        ps_point(&ps, tu_rng_range(&r, -0.2, 0.2), tu_rng_range(&r, -0.2, 0.2), pts + 3 * i);
    as_jet a, b;
    double mw[3] = {-ps.fr[6], -ps.fr[7], -ps.fr[8]};
    assert_int_equal(as_jet_fit(pts, 16, ps.t, 2, ps.fr, ps.fr + 6, &a), 0);
    assert_int_equal(as_jet_fit(pts, 16, ps.t, 2, ps.fr, mw, &b), 0);
    check_jet_frame(&a);
    check_jet_frame(&b);
    for (int i = 0; i < 3; i++) assert_true(fabs(a.n[i] + b.n[i]) < 1e-12);
    assert_true(fabs(a.k[0] + b.k[1]) < 1e-12 && fabs(a.k[1] + b.k[0]) < 1e-12);
    assert_true(fabs(fabs(dot3(a.d, b.d + 3)) - 1) < 1e-9);
    /* the outward normal on the convex side: z = -0.8 x^2 + ... is a saddle; k signs
     * opposite */
    assert_true(a.k[0] > 0 && a.k[1] < 0);
}

static void test_degenerate(void **state) {
    (void)state;
    as_jet j;
    double o[3] = {0, 0, 0};
    double line[3 * 10], few[3 * 5], many[3 * (AS_JET_MAX_POINTS + 1)];
    for (int i = 0; i < 10; i++) {
        line[3 * i] = i;
        line[3 * i + 1] = 2 * i;
        line[3 * i + 2] = -i;
    }
    assert_int_equal(as_jet_fit(line, 10, o, 2, NULL, NULL, &j), -1);
    tu_rng r = {2};
    for (int i = 0; i < 5; i++) {
        few[3 * i] = tu_rng_range(&r, -1, 1);
        few[3 * i + 1] = tu_rng_range(&r, -1, 1);
        few[3 * i + 2] = 0.3 * few[3 * i] - 0.1 * few[3 * i + 1];
    }
    /* 5 points cannot make a degree-2 jet: degree 1, the plane, curvature 0 */
    assert_int_equal(as_jet_fit(few, 5, o, 2, NULL, NULL, &j), 0);
    assert_int_equal(j.degree, 1);
    assert_true(j.k[0] == 0 && j.k[1] == 0);
    double n[3] = {-0.3, 0.1, 1};
    assert_true(fabs(fabs(dot3(j.n, n)) / norm3(n) - 1) < 1e-12);
    assert_int_equal(as_jet_fit(few, 2, o, 2, NULL, NULL, &j), -1);
    for (int i = 0; i < 3 * (AS_JET_MAX_POINTS + 1); i++) many[i] = tu_rng_range(&r, -1, 1);
    assert_int_equal(as_jet_fit(many, AS_JET_MAX_POINTS + 1, o, 2, NULL, NULL, &j), -1);
    assert_int_equal(as_jet_fit(many, AS_JET_MAX_POINTS, o, 2, NULL, NULL, &j), 0);
    many[4] = NAN;
    assert_int_equal(as_jet_fit(many, 10, o, 2, NULL, NULL, &j), -1);
    double same[3 * 8] = {0};
    assert_int_equal(as_jet_fit(same, 8, o, 2, NULL, NULL, &j), -1);
    /* points symmetric enough that degree 4 is rank-deficient: two lines crossing (an X)
     * determine no quadratic term in xy... a 3x3 grid: 9 points, 15 > 9 coefficients */
    double grid[3 * 9];
    int k = 0;
    for (int a = -1; a <= 1; a++)
        for (int b = -1; b <= 1; b++, k++) {
            grid[3 * k] = a;
            grid[3 * k + 1] = b;
            grid[3 * k + 2] = 0.1 * (a * a + b * b);
        }
    assert_int_equal(as_jet_fit(grid, 9, o, 4, NULL, NULL, &j), 0);
    assert_true(j.degree == 2 || j.degree == 3);
    assert_true(fabs(fabs(j.k[0]) - 0.2) < 1e-12 && fabs(fabs(j.k[1]) - 0.2) < 1e-12);
}

/* ---- blending ------------------------------------------------------------------------ */

/* Points on a sphere of radius 1 (Fibonacci), n of them. */
static double *fib_sphere(size_t n) {
    double *x = test_malloc(3 * n * sizeof(double));
    for (size_t i = 0; i < n; i++) {
        double z = 1 - (2.0 * (double)i + 1) / (double)n, rr = sqrt(1 - z * z);
        double th = 2.399963229728653 * (double)i;
        x[3 * i] = rr * cos(th);
        x[3 * i + 1] = rr * sin(th);
        x[3 * i + 2] = z;
    }
    return x;
}

static void rand_spd(tu_rng *r, double m[6]) {
    double u[9], w[3], a[6];
    for (int i = 0; i < 6; i++) a[i] = tu_rng_range(r, -1, 1);
    as_sym3_eigen(a, w, u);
    for (int k = 0; k < 3; k++) w[k] = tu_rng_range(r, 0.5, 20);
    as_sym3_from_eigen(w, u, m);
}

static double tensor_diff(const double a[6], const double b[6]) {
    double e = 0;
    for (int i = 0; i < 6; i++) e = fmax(e, fabs(a[i] - b[i]));
    return e;
}

/* The paper's formula over every vertex, no truncation. */
static void blend_brute(const double *xyz, const double *t, size_t n, double rb, const double p[3],
                        double m[6]) {
    double d0 = INFINITY;
    for (size_t v = 0; v < n; v++) {
        double d[3] = {xyz[3 * v] - p[0], xyz[3 * v + 1] - p[1], xyz[3 * v + 2] - p[2]};
        d0 = fmin(d0, dot3(d, d));
    }
    double acc[6] = {0}, ws = 0;
    for (size_t v = 0; v < n; v++) {
        double d[3] = {xyz[3 * v] - p[0], xyz[3 * v + 1] - p[1], xyz[3 * v + 2] - p[2]};
        double w = exp(-(dot3(d, d) - d0) / (rb * rb)); /* times exp(d0/rb^2): cancels */
        for (int i = 0; i < 6; i++) acc[i] += w * t[6 * v + i];
        ws += w;
    }
    for (int i = 0; i < 6; i++) m[i] = acc[i] / ws;
}

static void test_blend_formula(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const size_t n = 3000;
    double *xyz = fib_sphere(n);
    double *t = test_malloc(6 * n * sizeof(double));
    tu_rng r = {17};
    double tmax = 0;
    for (size_t v = 0; v < n; v++) {
        rand_spd(&r, t + 6 * v);
        for (int i = 0; i < 6; i++) tmax = fmax(tmax, fabs(t[6 * v + i]));
    }
    as_kdtree *kd;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, n, &kd), ANISTAR_OK);
    double rb;
    assert_int_equal(as_blend_default_radius(ctx, kd, xyz, n, 16, &rb), ANISTAR_OK);
    /* spacing of n points on the unit sphere ~ sqrt(4 pi / n) ~ 0.065; mean distance to
     * the 16 nearest ~ 1.5 spacing */
    assert_true(rb > 0.05 && rb < 0.2);
    as_blend *b;
    assert_int_equal(as_blend_create(ctx, kd, xyz, n, t, rb, &b), ANISTAR_OK);
    assert_true(as_blend_radius(b) == rb);
    double worst = 0;
    for (int q = 0; q < 400; q++) {
        double p[3], m[6], e[6], w[3], u[9];
        rand_unit(&r, p);
        double s = q < 300 ? 1 + tu_rng_range(&r, -0.05, 0.05) : tu_rng_range(&r, 0, 3);
        for (int i = 0; i < 3; i++) p[i] *= s; /* on, near and far from the sphere */
        assert_int_equal(as_blend_eval(ctx, b, p, m), ANISTAR_OK);
        blend_brute(xyz, t, n, rb, p, e);
        worst = fmax(worst, tensor_diff(m, e) / tmax);
        assert_int_equal(as_sym3_eigen(m, w, u), 0);
        assert_true(w[0] > 0.4); /* a convex combination of tensors with eigenvalues >= 0.5 */
    }
    /* documented bound: (1 + c^2) exp(-c^2) ~ 6e-5 of the spread */
    if (!(worst < 2e-4)) fail_msg("blend vs the paper's formula: %g", worst);
    as_blend_free(ctx, b);
    /* a constant field is reproduced everywhere */
    double c[6] = {3, 0.5, -0.2, 2, 0.1, 1};
    for (size_t v = 0; v < n; v++) memcpy(t + 6 * v, c, sizeof c);
    assert_int_equal(as_blend_create(ctx, kd, xyz, n, t, rb, &b), ANISTAR_OK);
    for (int q = 0; q < 100; q++) {
        double p[3], m[6];
        for (int i = 0; i < 3; i++) p[i] = tu_rng_range(&r, -4, 4);
        assert_int_equal(as_blend_eval(ctx, b, p, m), ANISTAR_OK);
        assert_true(tensor_diff(m, c) < 1e-13);
    }
    double bad[3] = {NAN, 0, 0}, m[6];
    assert_int_equal(as_blend_eval(ctx, b, bad, m), ANISTAR_EINVAL);
    as_blend_free(ctx, b);
    /* a small r_B: far points gather their vertices by a kd-tree radius query */
    for (size_t v = 0; v < n; v++) rand_spd(&r, t + 6 * v);
    assert_int_equal(as_blend_create(ctx, kd, xyz, n, t, 0.03, &b), ANISTAR_OK);
    worst = 0;
    for (int q = 0; q < 60; q++) {
        double p[3], e[6];
        rand_unit(&r, p);
        double s = q < 30 ? 1 : tu_rng_range(&r, 1.5, 3);
        for (int i = 0; i < 3; i++) p[i] *= s;
        assert_int_equal(as_blend_eval(ctx, b, p, m), ANISTAR_OK);
        blend_brute(xyz, t, n, 0.03, p, e);
        worst = fmax(worst, tensor_diff(m, e) / tmax);
    }
    if (!(worst < 2e-4)) fail_msg("blend (r_B 0.03) vs the paper's formula: %g", worst);
    as_blend_free(ctx, b);
    as_kdtree_free(ctx, kd);
    test_free(t);
    test_free(xyz);
    anistar_context_free(ctx);
}

/* Continuity where the cutoff drops a vertex and where the nearest vertex changes. */
static void test_blend_continuity(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double rb = 1, c = AS_BLEND_CUTOFF;
    double t[12] = {1, 0, 0, 1, 0, 1, 9, 2, 0, 4, 0, 1};
    for (int cas = 0; cas < 2; cas++) {
        double D = cas == 0 ? 5.0 : 2.0; /* beyond / within the cutoff of each other */
        double xyz[6] = {0, 0, 0, D, 0, 0};
        as_kdtree *kd;
        assert_int_equal(as_kdtree_build(ctx, xyz, NULL, 2, &kd), ANISTAR_OK);
        as_blend *b;
        assert_int_equal(as_blend_create(ctx, kd, xyz, 2, t, rb, &b), ANISTAR_OK);
        /* case 0: on the segment, vertex 1's weight vanishes where
         * d1^2 - d0^2 = c^2 rb^2, i.e. x = (D^2 - c^2 rb^2) / (2D); case 1: the nearest
         * vertex changes at x = D/2 */
        double xs = cas == 0 ? (D * D - c * c * rb * rb) / (2 * D) : D / 2;
        double lo[3] = {xs - 1e-9, 0, 0}, hi[3] = {xs + 1e-9, 0, 0}, ml[6], mh[6];
        assert_int_equal(as_blend_eval(ctx, b, lo, ml), ANISTAR_OK);
        assert_int_equal(as_blend_eval(ctx, b, hi, mh), ANISTAR_OK);
        if (!(tensor_diff(ml, mh) < 1e-7)) fail_msg("case %d: jump %g", cas, tensor_diff(ml, mh));
        if (cas == 0) { /* beyond the cutoff only vertex 0 counts */
            double far[3] = {xs - 0.5, 0, 0}, m[6];
            assert_int_equal(as_blend_eval(ctx, b, far, m), ANISTAR_OK);
            assert_true(tensor_diff(m, t) < 1e-15);
        } else { /* symmetric: equal weights at the midpoint */
            double mid[3] = {D / 2, 0, 0}, m[6];
            assert_int_equal(as_blend_eval(ctx, b, mid, m), ANISTAR_OK);
            for (int i = 0; i < 6; i++) assert_true(fabs(m[i] - 0.5 * (t[i] + t[6 + i])) < 1e-12);
        }
        as_blend_free(ctx, b);
        as_kdtree_free(ctx, kd);
    }
    anistar_context_free(ctx);
}

/* Lipschitz along lines through a dense sphere sample (crossing grid cells). */
static void test_blend_lipschitz(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const size_t n = 2000;
    double *xyz = fib_sphere(n);
    double *t = test_malloc(6 * n * sizeof(double));
    tu_rng r = {23};
    double spread = 0;
    for (size_t v = 0; v < n; v++) {
        rand_spd(&r, t + 6 * v);
        for (int i = 0; i < 6; i++) spread = fmax(spread, fabs(t[6 * v + i]));
    }
    as_kdtree *kd;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, n, &kd), ANISTAR_OK);
    double rb;
    assert_int_equal(as_blend_default_radius(ctx, kd, xyz, n, 16, &rb), ANISTAR_OK);
    as_blend *b;
    assert_int_equal(as_blend_create(ctx, kd, xyz, n, t, rb, &b), ANISTAR_OK);
    /* |grad M| <= 2 sup |grad w| / sum w * spread <= 2 (2 c / rb) spread; be generous */
    const double step = 1e-3 * rb, L = 4 * 2 * AS_BLEND_CUTOFF / rb * 2 * spread;
    for (int line = 0; line < 5; line++) {
        double a[3], d[3], prev[6], m[6];
        rand_unit(&r, a);
        rand_unit(&r, d);
        for (int k = 0; k <= 3000; k++) {
            double p[3];
            for (int i = 0; i < 3; i++) p[i] = a[i] + (k - 1500) * step * d[i];
            assert_int_equal(as_blend_eval(ctx, b, p, m), ANISTAR_OK);
            if (k > 0 && tensor_diff(m, prev) > L * step)
                fail_msg("line %d step %d: jump %g > %g", line, k, tensor_diff(m, prev), L * step);
            memcpy(prev, m, sizeof m);
        }
    }
    as_blend_free(ctx, b);
    as_kdtree_free(ctx, kd);
    test_free(t);
    test_free(xyz);
    anistar_context_free(ctx);
}

static void test_blend_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    /* default radius on a square grid: the 4 nearest are at distance h */
    double g[3 * 100];
    for (int i = 0; i < 100; i++) {
        g[3 * i] = 0.5 * (i % 10);
        g[3 * i + 1] = 0.5 * (i / 10);
        g[3 * i + 2] = 0;
    }
    as_kdtree *kd;
    assert_int_equal(as_kdtree_build(ctx, g, NULL, 100, &kd), ANISTAR_OK);
    double rb;
    assert_int_equal(as_blend_default_radius(ctx, kd, g, 100, 1, &rb), ANISTAR_OK);
    assert_true(fabs(rb - 0.5) < 1e-15);
    assert_int_equal(as_blend_default_radius(ctx, kd, g, 1, 1, &rb), ANISTAR_EINVAL);
    /* the kept lists are the keep_k-nearest queries' answers, ties (the grid is full of
     * them) broken by id the same way; on 100 points and on the first 5 (fewer than
     * keep_k); the radius is the same */
    static const size_t sizes[2] = {100, 5};
    for (int c = 0; c < 2; c++) {
        const size_t n = sizes[c];
        as_kdtree *kn;
        assert_int_equal(as_kdtree_build(ctx, g, NULL, n, &kn), ANISTAR_OK);
        int32_t keep[100 * 9], ids[9];
        uint8_t kept[100];
        double d2[9], r0, r1;
        assert_int_equal(as_blend_default_radius(ctx, kn, g, n, 16, &r0), ANISTAR_OK);
        assert_int_equal(as_blend_default_radius_keep(ctx, kn, g, n, 16, &r1, keep, 9, kept),
                         ANISTAR_OK);
        assert_true(r0 == r1);
        for (size_t v = 0; v < n; v++) {
            size_t got = as_kdtree_knn(kn, g + 3 * v, 9, ids, d2);
            assert_int_equal(kept[v], got);
            for (size_t i = 0; i < got; i++) assert_int_equal(keep[9 * v + i], ids[i]);
        }
        assert_int_equal(as_blend_default_radius_keep(ctx, kn, g, n, 7, &r1, keep, 9, kept),
                         ANISTAR_EINVAL);
        as_kdtree_free(ctx, kn);
    }
    double t[6 * 100];
    for (int i = 0; i < 100; i++) {
        double m[6] = {1, 0, 0, 1, 0, 1};
        memcpy(t + 6 * i, m, sizeof m);
    }
    as_blend *b = NULL;
    assert_int_equal(as_blend_create(ctx, kd, g, 100, t, 0, &b), ANISTAR_EINVAL);
    assert_int_equal(as_blend_create(ctx, kd, g, 100, t, NAN, &b), ANISTAR_EINVAL);
    assert_int_equal(as_blend_create(ctx, kd, g, 99, t, 1, &b), ANISTAR_EINVAL);
    assert_null(b);
    as_kdtree_free(ctx, kd);
    /* allocation failures: every failure point gives ENOMEM and leaks nothing; a small
     * r_B and a far point make the query take the allocating radius-query path */
    const size_t n = 500;
    double *xyz = fib_sphere(n), *ts = test_malloc(6 * n * sizeof(double));
    for (size_t i = 0; i < n; i++) memcpy(ts + 6 * i, t, 6 * sizeof(double));
    tu_alloc ta;
    int done = 0;
    for (long k = 0; !done; k++) {
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *c2 = anistar_context_new(&al);
        if (!c2) continue;
        as_kdtree *kd2 = NULL;
        anistar_status st = as_kdtree_build(c2, xyz, NULL, n, &kd2);
        if (!st) st = as_blend_create(c2, kd2, xyz, n, ts, 0.01, &b);
        if (!st) {
            double p[3] = {3, 2, 1}, m[6];
            st = as_blend_eval(c2, b, p, m);
            done = st == ANISTAR_OK;
            if (done) assert_true(tensor_diff(m, t) < 1e-14);
            as_blend_free(c2, b);
        }
        if (!done) assert_int_equal(st, ANISTAR_ENOMEM);
        as_kdtree_free(c2, kd2);
        anistar_context_free(c2);
        assert_int_equal(ta.live_blocks, 0);
        assert_true(k < 200);
    }
    test_free(ts);
    test_free(xyz);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_exact_polynomials),  cmocka_unit_test(test_pca_symmetric),
        cmocka_unit_test(test_analytic_convergence), cmocka_unit_test(test_orientation),
        cmocka_unit_test(test_degenerate),         cmocka_unit_test(test_blend_formula),
        cmocka_unit_test(test_blend_continuity),   cmocka_unit_test(test_blend_lipschitz),
        cmocka_unit_test(test_blend_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
