/*
 * test_field.c — metric fields (lib/surface/field.c): curvature, shock and Hessian
 * tensors against hand computations, SPD and finite everywhere for every kind, the
 * anisotropy clamp, umbilic and singular points, custom callbacks, SPEC parsing errors,
 * allocation failures; and the rule that a metric that is not positive definite on S is
 * an error naming the point, never a substitute (a zero Hessian without eps, callbacks
 * and .sol tensors that are not finite and SPD, eigenvalues that overflow), through the
 * internal API and through the public one up to a mesher run.
 */
#include "test_util.h"

#include "geom/linalg.h"
#include "surface/field.h"
#include "surface/surface.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const double PI = 3.14159265358979323846;

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
/* M = sum_k e_k^2 u_k u_k^T, written out independently of the library. */
static void outer_sum(double u[3][3], const double e[3], double m[6]) {
    double full[3][3] = {{0}};
    for (int k = 0; k < 3; k++)
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) full[i][j] += e[k] * e[k] * u[k][i] * u[k][j];
    m[0] = full[0][0];
    m[1] = full[0][1];
    m[2] = full[0][2];
    m[3] = full[1][1];
    m[4] = full[1][2];
    m[5] = full[2][2];
}
/* max_i |a_i - b_i| / max_i |b_i| */
static double tensor_err(const double a[6], const double b[6]) {
    double num = 0, den = 0;
    for (int i = 0; i < 6; i++) {
        num = fmax(num, fabs(a[i] - b[i]));
        den = fmax(den, fabs(b[i]));
    }
    return num / den;
}

/* The point named by an error message: the last "at (X, Y, Z)" in msg. Fails the test when
 * there is none. */
static void msg_point(const char *msg, double p[3]) {
    const char *at = NULL;
    for (const char *c = strstr(msg, "at ("); c; c = strstr(c + 1, "at (")) at = c;
    if (!at || sscanf(at, "at (%lf, %lf, %lf)", &p[0], &p[1], &p[2]) != 3)
        fail_msg("no point in '%s'", msg);
}

static as_surface *builtin(anistar_context *ctx, const char *spec) {
    as_surface *s = NULL;
    if (as_implicit_builtin(ctx, spec, &s)) fail_msg("%s: %s", spec, anistar_last_error(ctx));
    return s;
}
static as_surface *expression(anistar_context *ctx, const char *src, double r) {
    const double c[3] = {0, 0, 0};
    as_surface *s = NULL;
    if (as_implicit_from_expression(ctx, src, c, r, &s))
        fail_msg("%s: %s", src, anistar_last_error(ctx));
    return s;
}
static as_field *field(anistar_context *ctx, const as_surface *s, const char *spec) {
    as_field *f = NULL;
    if (as_field_from_spec(ctx, s, spec, &f)) fail_msg("%s: %s", spec, anistar_last_error(ctx));
    return f;
}

/* ---- curvature ---------------------------------------------------------------------------- */

static void test_curvature_torus(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "torus"); /* R 10, r 1, bound 11.25 */
    /* defaults: eps = 1/11.25, power 1, e_n = max e_1 over the sample = 1/r = 1 */
    as_field *f = field(ctx, s, "curvature");
    assert_true(fabs(f->en - 1) < 1e-9);
    assert_true(f->eps == 1 / 11.25 && f->power == 1);
    as_field *g = field(ctx, s, "curvature,eps=0.2,en=3,power=0.5");
    tu_rng rng = {1};
    for (int t = 0; t < 400; t++) {
        double th = tu_rng_range(&rng, 0, 2 * PI), ph = tu_rng_range(&rng, 0, 2 * PI);
        double p[3] = {(10 + cos(ph)) * cos(th), (10 + cos(ph)) * sin(th), sin(ph)};
        double u[3][3] = {{-sin(ph) * cos(th), -sin(ph) * sin(th), cos(ph)}, /* meridian */
                          {-sin(th), cos(th), 0},                            /* parallel */
                          {cos(ph) * cos(th), cos(ph) * sin(th), sin(ph)}};  /* normal */
        double kpar = fabs(cos(ph) / (10 + cos(ph)));
        double e[3] = {1, fmax(1 / 11.25, kpar), f->en}, want[6], m[6];
        outer_sum(u, e, want);
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
        assert_true(tensor_err(m, want) < 1e-10);
        double e2[3] = {1, sqrt(fmax(0.2, kpar)), 3};
        outer_sum(u, e2, want);
        assert_int_equal(as_field_eval(ctx, g, p, m), ANISTAR_OK);
        assert_true(tensor_err(m, want) < 1e-10);
    }
    as_field_free(f);
    as_field_free(g);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* Umbilic points: on a sphere every tangent frame is principal; the tensor is
 * e^2 (I - n n^T) + e_n^2 n n^T whatever frame the library picks. */
static void test_curvature_umbilic(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere,r=0.5");
    as_field *f = field(ctx, s, "curvature,en=5");
    tu_rng rng = {2};
    for (int t = 0; t < 200; t++) {
        double n[3], p[3], m[6];
        rand_unit(&rng, n);
        for (int i = 0; i < 3; i++) p[i] = 0.5 * n[i];
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
        double want[6];
        int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
        for (int k = 0; k < 6; k++) {
            int i = ij[k][0], j = ij[k][1];
            want[k] = 4 * ((i == j) - n[i] * n[j]) + 25 * n[i] * n[j];
        }
        assert_true(tensor_err(m, want) < 1e-12);
    }
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- shock: E = tanh((2x - sin 5y)/lambda) + x^3 + x y^2 on the unit sphere ----------- */

static void shock_by_hand(double lambda, double phi, double en, const double p[3],
                          double m[6]) {
    double x = p[0], y = p[1];
    double u = (2 * x - sin(5 * y)) / lambda, sech2 = 1 / (cosh(u) * cosh(u));
    double gE[3] = {2 / lambda * sech2 + 3 * x * x + y * y, -5 * cos(5 * y) / lambda * sech2 + 2 * x * y,
                    0};
    double n[3] = {p[0], p[1], p[2]}; /* unit sphere */
    double gn = dot3(gE, n), gt[3];
    for (int i = 0; i < 3; i++) gt[i] = gE[i] - gn * n[i];
    double l = norm3(gt), U[3][3];
    for (int i = 0; i < 3; i++) {
        U[0][i] = gt[i] / l;
        U[2][i] = n[i];
    }
    cross3(U[2], U[0], U[1]);
    double e[3] = {1 + phi * l, 1, en};
    outer_sum(U, e, m);
}

static void test_shock(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    as_field *f1 = field(ctx, s, "shock,en=4");
    as_field *f2 = field(ctx, s, "shock,lambda=0.3,phi=2.5,en=7");
    as_field *f3 = field(ctx, s, "shock"); /* default e_n from the sample */
    assert_true(f3->en > 1 && f3->phi == 1);
    const double pts[][3] = {{1, 0, 0}, {0, 1, 0}, {0.6, 0.8, 0}, {0.48, 0.6, 0.64},
                             {-0.36, 0.48, 0.8}, {0, 0.6, -0.8}};
    for (size_t t = 0; t < sizeof pts / sizeof pts[0]; t++) {
        double m[6], want[6];
        assert_int_equal(as_field_eval(ctx, f1, pts[t], m), ANISTAR_OK);
        shock_by_hand(0.6, 1, 4, pts[t], want);
        assert_true(tensor_err(m, want) < 1e-12);
        assert_int_equal(as_field_eval(ctx, f2, pts[t], m), ANISTAR_OK);
        shock_by_hand(0.3, 2.5, 7, pts[t], want);
        assert_true(tensor_err(m, want) < 1e-12);
        assert_int_equal(as_field_eval(ctx, f3, pts[t], m), ANISTAR_OK);
        shock_by_hand(0.6, 1, f3->en, pts[t], want);
        assert_true(tensor_err(m, want) < 1e-12);
    }
    /* gradient:EXPR with the same E is the same field */
    as_field *g = field(ctx, s, "gradient:tanh((2*x-sin(5*y))/0.6)+x^3+x*y^2,en=4");
    for (size_t t = 0; t < sizeof pts / sizeof pts[0]; t++) {
        double a[6], b[6];
        assert_int_equal(as_field_eval(ctx, f1, pts[t], a), ANISTAR_OK);
        assert_int_equal(as_field_eval(ctx, g, pts[t], b), ANISTAR_OK);
        assert_true(tensor_err(a, b) < 1e-14);
    }
    /* where grad E is normal to S (E = z at the pole): isotropic tangential 1 */
    as_field *gz = field(ctx, s, "gradient:z,phi=3,en=2");
    double pole[3] = {0, 0, 1}, m[6];
    assert_int_equal(as_field_eval(ctx, gz, pole, m), ANISTAR_OK);
    double want[6] = {1, 0, 0, 1, 0, 4};
    assert_true(tensor_err(m, want) < 1e-15);
    as_field_free(gz);
    as_field_free(g);
    as_field_free(f1);
    as_field_free(f2);
    as_field_free(f3);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- hessian ---------------------------------------------------------------------------- */

static void test_hessian(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    double pole[3] = {0, 0, 1}, m[6];
    /* |H| = diag(2, 8, 18); tangent plane at the pole = xy: M = diag(2, 8, en^2) with
     * power 0.5 (F = |H|^(1/2)) */
    as_field *f = field(ctx, s, "hessian:x^2+4*y^2+9*z^2,eps=0.001,en=3");
    assert_int_equal(as_field_eval(ctx, f, pole, m), ANISTAR_OK);
    double want[6] = {2, 0, 0, 8, 0, 9};
    assert_true(tensor_err(m, want) < 1e-14);
    as_field_free(f);
    /* absolute eigenvalues: x^2 - 4 y^2 gives the same tangential part */
    f = field(ctx, s, "hessian:x^2-4*y^2,eps=0.001,en=3");
    assert_int_equal(as_field_eval(ctx, f, pole, m), ANISTAR_OK);
    assert_true(tensor_err(m, want) < 1e-14);
    as_field_free(f);
    /* eps clamp and power 1: E = x^2 (|H| = diag(2, 0, 0)): e = (2, eps) */
    f = field(ctx, s, "hessian:x^2,eps=0.5,en=3,power=1");
    assert_int_equal(as_field_eval(ctx, f, pole, m), ANISTAR_OK);
    double want2[6] = {4, 0, 0, 0.25, 0, 9};
    assert_true(tensor_err(m, want2) < 1e-14);
    as_field_free(f);
    /* options after a parenthesised expression with commas; rotated Hessian:
     * max(x,y)^2 near (0.6, -0.8, 0) is x^2: |H| = 2 e_x e_x^T, tangent plane spanned by
     * (0.8, 0.6, 0) and z */
    f = field(ctx, s, "hessian:max(x,y)^2,eps=0.5,en=2,power=1");
    assert_true(f->eps == 0.5);
    double p[3] = {0.6, -0.8, 0};
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    double t1 = 2 * 0.8 * 0.8; /* (0.8,0.6,0)^T |H| (0.8,0.6,0) */
    double U[3][3] = {{0.8, 0.6, 0}, {0, 0, 1}, {0.6, -0.8, 0}};
    double e[3] = {t1, 0.5, 2};
    outer_sum(U, e, want);
    assert_true(tensor_err(m, want) < 1e-13);
    as_field_free(f);
    /* default eps: 1e-3 of the largest tangential |H| eigenvalue over the sample */
    f = field(ctx, s, "hessian:x^2+4*y^2+9*z^2");
    assert_true(f->eps > 1e-3 * 8 && f->eps <= 1e-3 * 18 * 1.000001);
    assert_true(f->power == 0.5 && f->en > sqrt(8) && f->en <= sqrt(18) * 1.000001);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- every kind: SPD, finite, bounded anisotropy ---------------------------------------- */

static int custom_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)user;
    /* stretched along the normal and along x, depending on p */
    double a = 1 + p[0] * p[0], b = 2 + sin(p[1]);
    m[0] = a + b * n[0] * n[0];
    m[1] = b * n[0] * n[1];
    m[2] = b * n[0] * n[2];
    m[3] = 1 + b * n[1] * n[1];
    m[4] = b * n[1] * n[2];
    m[5] = 1 + b * n[2] * n[2];
    return 0;
}

static void check_spd(const double m[6]) {
    for (int i = 0; i < 6; i++) assert_true(isfinite(m[i]));
    double w[3], v[9];
    assert_int_equal(as_sym3_eigen(m, w, v), 0);
    assert_true(w[0] > 0);
    assert_true(w[2] / w[0] <= AS_FIELD_MAX_ANISOTROPY * AS_FIELD_MAX_ANISOTROPY * (1 + 1e-6));
}

static void test_all_kinds_spd(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const char *surfaces[] = {"torus", "chair", "tanglecube", "double_torus", "ellipsoid"};
    const char *specs[] = {"euclidean",         "uniform,h=0.1",  "curvature",
                           "curvature,power=0.5,eps=1e-9", "shock",      "shock,phi=100,lambda=0.05",
                           "gradient:x*y*z,phi=3", "hessian:x^2*y+z^3", "hessian:sin(3*x)*y,power=1"};
    for (size_t a = 0; a < sizeof surfaces / sizeof surfaces[0]; a++) {
        as_surface *s = builtin(ctx, surfaces[a]);
        as_point_sample smp;
        assert_int_equal(as_surface_sample(ctx, s, 120, &smp), ANISTAR_OK);
        for (size_t b = 0; b <= sizeof specs / sizeof specs[0]; b++) {
            as_field *f;
            if (b < sizeof specs / sizeof specs[0]) f = field(ctx, s, specs[b]);
            else assert_int_equal(as_field_custom(ctx, s, custom_fn, NULL, &f), ANISTAR_OK);
            for (size_t i = 0; i < smp.n; i++) {
                double m[6];
                assert_int_equal(as_field_eval(ctx, f, smp.points + 3 * i, m), ANISTAR_OK);
                check_spd(m);
            }
            as_field_free(f);
        }
        as_surface_sample_free(ctx, &smp);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* ---- anisotropy clamp ------------------------------------------------------------------- */

static int thin_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)p;
    (void)n;
    (void)user;
    m[0] = 1;
    m[1] = m[2] = m[4] = 0;
    m[3] = 1e-20;
    m[5] = 4;
    return 0;
}

static void test_anisotropy_clamp(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "torus");
    /* top circle (phi = pi/2): k_parallel = 0, eps = 1e-12: e = (1, 1e-12, 1) is raised
     * to (1, 1e-6, 1) */
    as_field *f = field(ctx, s, "curvature,eps=1e-12,en=1");
    double p[3] = {10, 0, 1}, m[6], w[3], v[9];
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_int_equal(as_sym3_eigen(m, w, v), 0);
    assert_true(fabs(w[0] - 1e-12) < 1e-18 && fabs(w[2] - 1) < 1e-12);
    assert_true(fabs(v[1]) > 1 - 1e-9); /* the clamped direction is the parallel (y) */
    as_field_free(f);
    /* a custom tensor with eigenvalue ratio 4e20 is clamped to 1e12 */
    assert_int_equal(as_field_custom(ctx, s, thin_fn, NULL, &f), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_int_equal(as_sym3_eigen(m, w, v), 0);
    assert_true(fabs(w[2] / w[0] - 1e12) < 1e12 * 1e-9 && fabs(w[2] - 4) < 1e-12);
    as_field_free(f);
    /* a uniform tensor too */
    double thin[6] = {1, 0, 0, 1e-20, 0, 1};
    assert_int_equal(as_field_uniform(ctx, NULL, thin, &f), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_true(fabs(m[3] - 1e-12) < 1e-20);
    as_field_free(f);
    /* the clamp never makes a tensor the mesher refuses acceptable: a condition number
     * of 1e30 (> 1e24, as_metric_frame_init's bound) is an error, not clamped */
    double thinner[6] = {1, 0, 0, 1e-30, 0, 1};
    f = (as_field *)1;
    assert_int_equal(as_field_uniform(ctx, NULL, thinner, &f), ANISTAR_EINVAL);
    assert_null(f);
    assert_non_null(strstr(anistar_last_error(ctx), "(1 0 0 1.0000000000000001e-30 0 1)"));
    /* untouched within the bound: bit for bit */
    double ok[6] = {2, 0.5, 0.25, 3, 0.125, 4}, c[6];
    memcpy(c, ok, sizeof c);
    assert_int_equal(as_field_check_tensor(c), 0);
    assert_memory_equal(c, ok, sizeof c);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- singular points ---------------------------------------------------------------------- */

static void test_singular_points(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    /* the double cone has a singular point at the origin (no normal) */
    as_surface *s = expression(ctx, "x^2+y^2-z^2", 1);
    double o[3] = {0, 0, 0}, m[6];
    as_field *f = field(ctx, s, "curvature,en=3");
    assert_int_equal(as_field_eval(ctx, f, o, m), ANISTAR_OK);
    double want[6] = {9, 0, 0, 9, 0, 9};
    assert_true(tensor_err(m, want) < 1e-15);
    as_field_free(f);
    /* gradient: isotropic with the larger of e_n and 1 + phi |grad E| */
    f = field(ctx, s, "gradient:3*x+4*y,phi=2,en=3");
    assert_int_equal(as_field_eval(ctx, f, o, m), ANISTAR_OK);
    double want2[6] = {121, 0, 0, 121, 0, 121};
    assert_true(tensor_err(m, want2) < 1e-15);
    as_field_free(f);
    /* near (not at) the singular point the curvature is huge but the tensor stays SPD */
    f = field(ctx, s, "curvature,en=3");
    double q[3] = {1e-150, 0, 1e-150};
    assert_int_equal(as_field_eval(ctx, f, q, m), ANISTAR_OK);
    check_spd(m);
    as_field_free(f);
    /* custom fields get a zero normal there */
    assert_int_equal(as_field_custom(ctx, s, custom_fn, NULL, &f), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, f, o, m), ANISTAR_OK);
    double want3[6] = {1, 0, 0, 1, 0, 1};
    assert_true(tensor_err(m, want3) < 1e-15);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- custom callback errors ---------------------------------------------------------------- */

static int bad_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)p;
    (void)n;
    int mode = *(const int *)user;
    double t[6] = {1, 0, 0, 1, 0, 1};
    if (mode == 0) t[3] = -1;           /* indefinite */
    if (mode == 1) t[1] = NAN;          /* not finite */
    if (mode == 3) t[1] = 2;            /* indefinite through the off-diagonal */
    if (mode == 4) t[5] = -1;           /* diag(1, 1, -1) */
    if (mode == 5) t[5] = INFINITY;     /* not finite */
    if (mode == 6) {                    /* diag(1, 2, 3) written as the first six entries of
                                           a row-major 3x3 matrix: 1 0 0 0 2 0 — looks like a
                                           tensor, is singular (m22 = m33 = 0) */
        double r[6] = {1, 0, 0, 0, 2, 0};
        memcpy(t, r, sizeof r);
    }
    if (mode == 7) t[3] = 1e-30; /* positive definite, condition number 1e30 > 1e24 */
    if (mode == 8) memset(t, 0, sizeof t); /* left unfilled */
    memcpy(m, t, sizeof t);
    return mode == 2; /* failure */
}

/* A custom callback's tensor is checked with the mesher's own test (as_metric_frame_init)
 * before any clamp; an invalid one is EINVAL naming the point and the six values. */
static void test_custom_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    double p[3] = {0.6, 0, 0.8}, m[6];
    const struct {
        const char *msg, *values;
    } want[] = {
        {"not positive definite", "(1 0 0 -1 0 1)"},
        {"non-finite", "(1 nan 0 1 0 1)"},
        {"callback failed", NULL},
        {"not positive definite", "(1 2 0 1 0 1)"},
        {"not positive definite", "(1 0 0 1 0 -1)"},
        {"non-finite", "(1 0 0 1 0 inf)"},
        {"not positive definite", "(1 0 0 0 2 0)"},
        {"not positive definite", "(1 0 0 1.0000000000000001e-30 0 1)"},
        {"not positive definite", "(0 0 0 0 0 0)"},
    };
    for (int mode = 0; mode < (int)(sizeof want / sizeof want[0]); mode++) {
        as_field *f;
        assert_int_equal(as_field_custom(ctx, s, bad_fn, &mode, &f), ANISTAR_OK);
        for (int i = 0; i < 6; i++) m[i] = 42;
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_EINVAL);
        const char *e = anistar_last_error(ctx);
        if (!strstr(e, want[mode].msg) ||
            !strstr(e, "at (0.59999999999999998, 0, 0.80000000000000004)") ||
            (want[mode].values && !strstr(e, want[mode].values)))
            fail_msg("mode %d: '%s'", mode, e);
        for (int i = 0; i < 6; i++) assert_true(m[i] == 42); /* nothing handed out */
        as_field_free(f);
    }
    /* through the public API: the same status and message */
    int mode = 4;
    anistar_metric *pm;
    assert_int_equal(anistar_metric_from_callback(ctx, s, bad_fn, &mode,
                                                  &pm),
                     ANISTAR_OK);
    assert_int_equal(anistar_metric_eval(pm, p, m), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "not positive definite (1 0 0 1 0 -1)"));
    anistar_metric_free(pm);
    /* NaN in a scalar field or in f: an error naming the point */
    as_field *f = field(ctx, s, "gradient:sqrt(x),en=1");
    double q[3] = {-0.6, 0, 0.8};
    assert_int_equal(as_field_eval(ctx, f, q, m), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "(-0.59999999999999998, 0, "));
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- no silent substitutes for built-in fields --------------------------------------------- */

/* hessian of a linear E: no size to derive without eps (EINVAL naming a point of S); with
 * eps the documented clamp makes it the uniform metric eps^(2 power) I. */
static void test_hessian_zero(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    const char *bad[] = {"hessian:x+2*y", "hessian:x+2*y,en=2", "hessian:x+2*y,power=1",
                         "hessian:3"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        as_field *f = (as_field *)1;
        assert_int_equal(as_field_from_spec(ctx, s, bad[i], &f), ANISTAR_EINVAL);
        assert_null(f);
        const char *e = anistar_last_error(ctx);
        char name[64];
        snprintf(name, sizeof name, "metric '%s': ", bad[i]);
        if (!strstr(e, name) || !strstr(e, "the Hessian of E is 0 on S") ||
            !strstr(e, "give eps=E") || strchr(e, '\n'))
            fail_msg("'%s': '%s'", bad[i], e);
        double q[3];
        msg_point(e, q);
        assert_true(fabs(norm3(q) - 1) < 1e-12); /* a point of S, printed in full */
    }
    as_field *f;
    /* with eps: a uniform metric; e = eps^power tangentially and e_n = the largest
     * e over the sample = eps^power */
    const struct {
        const char *spec;
        double v; /* M = v I */
    } good[] = {{"hessian:x+2*y,eps=0.5", 0.5},
                {"hessian:x+2*y,eps=0.5,power=1", 0.25},
                {"hessian:x+2*y,eps=0.5,en=3", -9}}; /* v < 0: tangential 0.5, normal 9 */
    tu_rng rng = {12};
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        f = field(ctx, s, good[i].spec);
        assert_true(f->eps == 0.5);
        for (int t = 0; t < 50; t++) {
            double n[3], m[6], want[6];
            rand_unit(&rng, n);
            assert_int_equal(as_field_eval(ctx, f, n, m), ANISTAR_OK);
            double tv = good[i].v > 0 ? good[i].v : 0.5, nv = good[i].v > 0 ? tv : -good[i].v;
            int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
            for (int k = 0; k < 6; k++) {
                int a = ij[k][0], b = ij[k][1];
                want[k] = tv * ((a == b) - n[a] * n[b]) + nv * n[a] * n[b];
            }
            if (tensor_err(m, want) > 1e-14)
                fail_msg("%s: (%g %g %g %g %g %g)", good[i].spec, m[0], m[1], m[2], m[3], m[4],
                         m[5]);
        }
        as_field_free(f);
    }
    /* the public API refuses it the same way */
    anistar_metric *pm = (anistar_metric *)1;
    assert_int_equal(anistar_metric_from_spec(ctx, s, "hessian:x+2*y",
                                              &pm),
                     ANISTAR_EINVAL);
    assert_null(pm);
    assert_non_null(strstr(anistar_last_error(ctx), "Hessian"));
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* Eigenvalues of gradient and hessian fields that overflow the limit are E's, not S's:
 * EINVAL naming the point (they used to become e_n^2 I). Tiny eps and e_n whose squares
 * underflow give a tensor the mesher would refuse: EINVAL too (it used to be handed
 * out as the zero tensor). */
static void test_builtin_overflow(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    /* E = exp(800 x): at (0.6, 0.8, 0) |H| ~ 2.6e214 and |grad E| ~ 3.2e211, both with a
     * tangential part; at (-1, 0, 0) both vanish */
    double hot[3] = {0.6, 0.8, 0}, cold[3] = {-1, 0, 0}, m[6];
    const char *specs[] = {"hessian:exp(800*x),eps=1,en=1,power=1", "gradient:exp(800*x),en=1"};
    for (size_t i = 0; i < 2; i++) {
        as_field *f = field(ctx, s, specs[i]);
        assert_int_equal(as_field_eval(ctx, f, cold, m), ANISTAR_OK);
        check_spd(m);
        assert_int_equal(as_field_eval(ctx, f, hot, m), ANISTAR_EINVAL);
        const char *e = anistar_last_error(ctx);
        if (!strstr(e, "exceeds") || !strstr(e, "at (0.59999999999999998, 0.80000000000000004, 0)"))
            fail_msg("%s: '%s'", specs[i], e);
        as_field_free(f);
    }
    /* at a singular point too (the double cone's apex): not replaced by e_n */
    as_surface *cone = expression(ctx, "x^2+y^2-z^2", 1);
    as_field *f = field(ctx, cone, "gradient:1e200*x,en=1");
    double o[3] = {0, 0, 0};
    assert_int_equal(as_field_eval(ctx, f, o, m), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "at (0, 0, 0)"));
    as_field_free(f);
    as_surface_free(cone);
    /* underflow: every eigenvalue ~1e-300, squares 0 */
    f = field(ctx, s, "hessian:1e-300*x^2,eps=1e-300,en=1e-300,power=1");
    double pole[3] = {0, 0, 1};
    assert_int_equal(as_field_eval(ctx, f, pole, m), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "not finite and positive definite"));
    assert_non_null(strstr(anistar_last_error(ctx), "at (0, 0, 1)"));
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* .sol tensors on a triangle-mesh surface: non-finite ones are refused by the reader,
 * non-SPD ones (and condition numbers the mesher refuses) by the field, naming the vertex
 * and its position; a valid anisotropic one is clamped as documented. */
static void write_sol6(const char *path, const double t[6], size_t n, size_t bad,
                       const char *badline) { /* every vertex t, except vertex bad: badline */
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n%zu\n1 3\n", n);
    for (size_t i = 0; i < n; i++) { /* Medit order m11 m12 m22 m13 m23 m33 */
        if (i == bad) fprintf(fp, "%s\n", badline);
        else fprintf(fp, "%.17g %.17g %.17g %.17g %.17g %.17g\n", t[0], t[1], t[3], t[2], t[4], t[5]);
    }
    fprintf(fp, "End\n");
    fclose(fp);
}

static void test_sol_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = NULL;
    assert_int_equal(as_mesh_surface_read(ctx, AS_TEST_DATA_DIR "/sphere_r0.5.off", &s),
                     ANISTAR_OK);
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    char dir[] = "/tmp/anistar_field_XXXXXX", path[96], spec[128];
    assert_non_null(mkdtemp(dir));
    snprintf(path, sizeof path, "%s/m.sol", dir);
    snprintf(spec, sizeof spec, "sol:%s", path);
    const double c[6] = {4, 0, 0, 4, 0, 4};
    /* Medit order: m11 m12 m22 m13 m23 m33 */
    const struct {
        const char *line;
        anistar_status st;
        const char *msg;
    } bad[] = {
        {"4 nan 4 0 0 4", 0, NULL}, /* the reader's error (any status but OK) */
        {"4 0 4 0 0 -4", ANISTAR_EFORMAT, "(4 0 0 4 0 -4) is not finite and positive definite"},
        {"1 2 1 0 0 1", ANISTAR_EFORMAT, "(1 2 0 1 0 1) is not finite and positive definite"},
        {"1 0 1e-30 0 0 1", ANISTAR_EFORMAT, "not finite and positive definite"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        write_sol6(path, c, mi.nv_in, 6, bad[i].line);
        as_field *f = (as_field *)1;
        anistar_status st = as_field_from_spec(ctx, s, spec, &f);
        assert_null(f);
        const char *e = anistar_last_error(ctx);
        if (st == ANISTAR_OK || (bad[i].st && st != bad[i].st) ||
            (bad[i].msg && (!strstr(e, bad[i].msg) || !strstr(e, "vertex 7 at ("))))
            fail_msg("'%s': status %d, '%s'", bad[i].line, st, e);
        if (bad[i].msg) {
            double q[3];
            msg_point(e, q);
            int32_t v = mi.vmap ? mi.vmap[6] : 6;
            assert_true(v >= 0);
            assert_memory_equal(q, mi.xyz + 3 * (size_t)v, sizeof q); /* %.17g: exact */
        }
    }
    /* condition number 1e20 (<= 1e24): valid, clamped to F's 1e6 (M's 1e12) */
    const double thin[6] = {1, 0, 0, 1e-20, 0, 1}, clamped[6] = {1, 0, 0, 1e-12, 0, 1};
    write_sol6(path, thin, mi.nv_in, (size_t)-1, "");
    as_field *f = field(ctx, s, spec);
    double m[6], p[3] = {0.5, 0, 0};
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_true(tensor_err(m, clamped) < 1e-12 && fabs(m[3] - 1e-12) < 1e-24);
    as_field_free(f);
    remove(path);
    rmdir(dir);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* Through the public API, up to the mesher: a zero-Hessian SPEC gives no metric (so no
 * mesher); a callback that turns non-SPD on part of S makes the run EINVAL with the point
 * and no mesh. */
static int half_bad_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)n;
    int mode = *(const int *)user;
    double t[6] = {4, 0, 0, 4, 0, 4};
    if (p[2] > 0.5) {
        if (mode == 0) t[5] = -4;  /* indefinite */
        if (mode == 1) t[1] = 8;   /* indefinite through the off-diagonal */
        if (mode == 2) t[3] = 0;   /* singular */
    }
    memcpy(m, t, sizeof t);
    return 0;
}

static void test_mesher_refuses(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    anistar_metric *m = (anistar_metric *)1;
    assert_int_equal(anistar_metric_from_spec(ctx, s, "hessian:x+2*y", &m), ANISTAR_EINVAL);
    assert_null(m);
    assert_non_null(strstr(anistar_last_error(ctx), "the Hessian of E is 0 on S"));
    anistar_mesher *me = (anistar_mesher *)1;
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_EINVAL);
    assert_null(me);
    /* with eps it meshes: a uniform metric */
    assert_int_equal(anistar_metric_from_spec(ctx, s, "hessian:x+2*y,eps=4", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.5), ANISTAR_OK);
    anistar_mesh *mesh = NULL;
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_OK);
    assert_non_null(mesh);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    for (int mode = 0; mode < 3; mode++) {
        assert_int_equal(anistar_metric_from_callback(ctx, s, half_bad_fn, &mode, &m), ANISTAR_OK);
        assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
        assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.5), ANISTAR_OK);
        mesh = (anistar_mesh *)1;
        assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_EINVAL);
        assert_null(mesh);
        const char *e = anistar_last_error(ctx);
        if (!strstr(e, "not") || !strstr(e, "positive definite")) fail_msg("mode %d: '%s'", mode, e);
        double q[3];
        msg_point(e, q);
        assert_true(q[2] > 0.5); /* where the callback turned bad */
        anistar_mesher_free(me);
        anistar_metric_free(m);
    }
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- SPEC parsing --------------------------------------------------------------------------- */

/* The smallest eigenvalue of P^-1/2 M P^-1/2: M >= t P iff it is >= t. */
static double min_rel_eig(const double P[6], const double M[6]) {
    double w[3], v[9], s6[6];
    assert_int_equal(as_sym3_eigen(P, w, v), 0);
    for (int k = 0; k < 3; k++) w[k] = 1 / sqrt(w[k]);
    as_sym3_from_eigen(w, v, s6);
    const double S[9] = {s6[0], s6[1], s6[2], s6[1], s6[3], s6[4], s6[2], s6[4], s6[5]};
    const double A[9] = {M[0], M[1], M[2], M[1], M[3], M[4], M[2], M[4], M[5]};
    double T[9], C[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            T[3 * i + j] = 0;
            for (int k = 0; k < 3; k++) T[3 * i + j] += A[3 * i + k] * S[3 * k + j];
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            C[3 * i + j] = 0;
            for (int k = 0; k < 3; k++) C[3 * i + j] += S[3 * i + k] * T[3 * k + j];
        }
    double c6[6] = {C[0], 0.5 * (C[1] + C[3]), 0.5 * (C[2] + C[6]), C[4], 0.5 * (C[5] + C[7]),
                    C[8]};
    assert_int_equal(as_sym3_eigen(c6, w, v), 0);
    return fmin(w[0], fmin(w[1], w[2]));
}

/* nv random anisotropic tensors (eigenvalues 1 to 10^6, random frames) from seed. */
static void random_tensors(double *t, size_t nv, uint64_t seed) {
    tu_rng r = {seed};
    for (size_t v = 0; v < nv; v++) {
        double q[9], e[3];
        tu_random_rotation(&r, q);
        for (int k = 0; k < 3; k++) e[k] = pow(10, tu_rng_range(&r, 0, 3));
        as_field_tensor(q, e, t + 6 * v);
    }
}

/* The gradation (grad=G) on a real mesh (the fandisk's vertices and triangles) with random
 * anisotropic vertex tensors (eigenvalues 1 to 10^6, random frames: jumps everywhere):
 * afterwards every directed edge i -> j satisfies M_j >= eta^2 M_i, eta = 1 / (1 + l ln G)
 * with l the M_i length of the edge (to the documented relative 1e-3), every tensor is at
 * least its input, something changed, and a second pass changes nothing. */
static void test_gradation(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    assert_int_equal(as_mesh_surface_read(ctx, AS_TEST_DATA_DIR "/fandisk.off", &s), ANISTAR_OK);
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    double *t0 = malloc(mi.nv * 6 * sizeof(double)), *t = malloc(mi.nv * 6 * sizeof(double));
    assert_non_null(t0);
    assert_non_null(t);
    random_tensors(t0, mi.nv, 7);
    memcpy(t, t0, mi.nv * 6 * sizeof(double));
    const double G = 1.3;
    /* the triangles' edges, each as often as it appears, in their order */
    int32_t *edges = malloc(mi.nt * 6 * sizeof(int32_t));
    assert_non_null(edges);
    for (size_t f = 0; f < mi.nt; f++)
        for (int k = 0; k < 3; k++) {
            edges[6 * f + 2 * k] = mi.tri[3 * f + k];
            edges[6 * f + 2 * k + 1] = mi.tri[3 * f + (k + 1) % 3];
        }
    assert_int_equal(as_field_gradation_edges(ctx, t, mi.xyz, 3 * mi.nt, edges, G, 0, NULL),
                     ANISTAR_OK);
    size_t changed = 0;
    double worst = INFINITY, least = INFINITY;
    for (size_t v = 0; v < mi.nv; v++) {
        double g = min_rel_eig(t0 + 6 * v, t + 6 * v);
        if (g < least) least = g;
        if (memcmp(t0 + 6 * v, t + 6 * v, 6 * sizeof(double))) changed++;
    }
    for (size_t f = 0; f < mi.nt; f++)
        for (int k = 0; k < 3; k++)
            for (int dir = 0; dir < 2; dir++) {
                int32_t i = mi.tri[3 * f + k], j = mi.tri[3 * f + (k + 1) % 3];
                if (dir) {
                    int32_t x = i;
                    i = j;
                    j = x;
                }
                const double *M = t + 6 * (size_t)i, *a = mi.xyz + 3 * (size_t)i,
                             *b = mi.xyz + 3 * (size_t)j;
                double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
                double l2 = M[0] * d[0] * d[0] + M[3] * d[1] * d[1] + M[5] * d[2] * d[2] +
                            2 * (M[1] * d[0] * d[1] + M[2] * d[0] * d[2] + M[4] * d[1] * d[2]);
                double eta = 1 / (1 + sqrt(l2) * log(G)), P[6];
                for (int q = 0; q < 6; q++) P[q] = eta * eta * M[q];
                double g = min_rel_eig(P, t + 6 * (size_t)j);
                if (g < worst) worst = g;
            }
    print_message("gradation 1.3 on fandisk: %zu of %zu tensors changed, edge bound %.6f, "
                  "growth %.6f\n", changed, mi.nv, worst, least);
    assert_true(changed > mi.nv / 2);
    assert_true(worst >= 1 - 2e-3);
    assert_true(least >= 1 - 1e-9);
    double *t2 = malloc(mi.nv * 6 * sizeof(double));
    assert_non_null(t2);
    /* keep_frame: from the same random tensors, each M_j keeps its eigenvectors; along
     * each of them u^T M_j u >= eta^2 u^T M_i u for every edge (to 1e-3), every tensor is
     * at least its input, and no eigenvalue exceeds the input's largest (the intersection
     * above inflates: its largest eigenvalue is printed) */
    double lmax_in = 0, lmax_kf = 0, lmax_int = 0, worst_kf = INFINITY, least_kf = INFINITY;
    random_tensors(t2, mi.nv, 7);
    for (size_t v = 0; v < mi.nv; v++) {
        double w[3], V[9];
        assert_int_equal(as_sym3_eigen(t2 + 6 * v, w, V), 0);
        lmax_in = fmax(lmax_in, w[2]);
    }
    double *t3 = malloc(mi.nv * 6 * sizeof(double));
    assert_non_null(t3);
    memcpy(t3, t2, mi.nv * 6 * sizeof(double));
    assert_int_equal(as_field_gradation_edges(ctx, t2, mi.xyz, 3 * mi.nt, edges, G, 1, NULL), ANISTAR_OK);
    for (size_t v = 0; v < mi.nv; v++) {
        double w[3], V[9];
        assert_int_equal(as_sym3_eigen(t2 + 6 * v, w, V), 0);
        lmax_kf = fmax(lmax_kf, w[2]);
        assert_int_equal(as_sym3_eigen(t + 6 * v, w, V), 0);
        lmax_int = fmax(lmax_int, w[2]);
        least_kf = fmin(least_kf, min_rel_eig(t3 + 6 * v, t2 + 6 * v));
    }
    for (size_t e = 0; e < 3 * mi.nt; e++)
        for (int dir = 0; dir < 2; dir++) {
            int32_t i = edges[2 * e + dir], j = edges[2 * e + 1 - dir];
            const double *M = t2 + 6 * (size_t)i, *a = mi.xyz + 3 * (size_t)i,
                         *b = mi.xyz + 3 * (size_t)j;
            double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            double l2 = M[0] * d[0] * d[0] + M[3] * d[1] * d[1] + M[5] * d[2] * d[2] +
                        2 * (M[1] * d[0] * d[1] + M[2] * d[0] * d[2] + M[4] * d[1] * d[2]);
            double eta = 1 / (1 + sqrt(l2) * log(G)), w[3], V[9];
            assert_int_equal(as_sym3_eigen(t2 + 6 * (size_t)j, w, V), 0);
            for (int k = 0; k < 3; k++) {
                const double *u = V + 3 * k;
                double qi = M[0] * u[0] * u[0] + M[3] * u[1] * u[1] + M[5] * u[2] * u[2] +
                            2 * (M[1] * u[0] * u[1] + M[2] * u[0] * u[2] + M[4] * u[1] * u[2]);
                worst_kf = fmin(worst_kf, w[k] / (eta * eta * qi));
            }
        }
    print_message("gradation 1.3 keeping frames: edge bound %.6f along the axes, growth %.6f, "
                  "largest eigenvalue %.4g (input %.4g; intersections: %.4g)\n",
                  worst_kf, least_kf, lmax_kf, lmax_in, lmax_int);
    assert_true(worst_kf >= 1 - 2e-3);
    assert_true(least_kf >= 1 - 1e-9);
    assert_true(lmax_kf <= lmax_in * (1 + 1e-9));
    free(t3);
    free(t2);
    memcpy(t0, t, mi.nv * 6 * sizeof(double));
    assert_int_equal(as_field_gradation_edges(ctx, t, mi.xyz, 3 * mi.nt, edges, G, 0, NULL),
                     ANISTAR_OK);
    assert_memory_equal(t0, t, mi.nv * 6 * sizeof(double));
    free(edges);
    free(t0);
    free(t);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The distortion between metrics a and b (gamma: the largest stretch of F_a F_b^-1 either
 * way). */
static double gamma_of(const double a[6], const double b[6]) {
    return 1 / sqrt(fmin(min_rel_eig(a, b), min_rel_eig(b, a)));
}

/* grad=G on a field given at every point: a capsule (a cylinder of radius 1/2 between two
 * half-spheres, f = max(|x| - 1, 0)^2 + y^2 + z^2 - 1/4, continuous tangents but not
 * curvatures) has a curvature metric that jumps across the seams x = +-1, along the axis
 * from max(eps, 0)^2 (eps = 1/R_bound = 1/2) to 4. Graded: (1) the jump is gone — seen
 * from either side of the seam the metrics differ by a distortion below 1.1 (ungraded: 4
 * = the ratio of the sizes); (2) the graded field is nowhere below the ungraded one (at
 * 400 points of S, and off S); (3) sizes grow from the seam along the cylinder as the
 * gradation allows: the axial eigenvalue stays within the bound grown from the cap's 4 by
 * 1 + l ln G over the M-length l along the axis (with the sample's spacing as slack), and
 * it is below 4 (the field is graded, not flattened) halfway. */
static void test_gradation_analytic(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = expression(ctx, "max(abs(x)-1,0)^2+y^2+z^2-0.25", 2);
    as_field *g = field(ctx, s, "curvature,grad=1.3"), *u = field(ctx, s, "curvature,grad=0");
    /* the default grades it (the expression has kinks: abs, max), a sphere's not */
    as_field *d = field(ctx, s, "curvature");
    assert_true(d->grad > 1);
    as_field_free(d);
    as_surface *sph = expression(ctx, "x^2+y^2+z^2-1", 2);
    d = field(ctx, sph, "curvature");
    assert_true(d->grad == 0);
    as_field_free(d);
    as_surface_free(sph);
    assert_non_null(g->g.blend);
    const double x0 = 1 - 1e-7, x1 = 1 + 1e-7;
    double a[6], b[6], ua[6], ub[6];
    const double pa[3] = {x0, 0.5, 0}, pb[3] = {x1, 0.5, 0};
    assert_int_equal(as_field_eval(ctx, g, pa, a), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, g, pb, b), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, u, pa, ua), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, u, pb, ub), ANISTAR_OK);
    double gg = gamma_of(a, b), gu = gamma_of(ua, ub);
    print_message("capsule seam: gamma %.4f graded, %.4f ungraded\n", gg, gu);
    assert_true(gu > 3.9);
    assert_true(gg < 1.1);
    /* (2) never below the ungraded field: on S (the sampler's points) and off S */
    as_point_sample smp;
    assert_int_equal(as_surface_sample(ctx, s, 400, &smp), ANISTAR_OK);
    double least = INFINITY;
    for (size_t i = 0; i < smp.n; i++)
        for (int off = 0; off < 2; off++) {
            double q[3] = {smp.points[3 * i], smp.points[3 * i + 1] + 0.05 * off,
                           smp.points[3 * i + 2]};
            double mg[6], mu[6];
            assert_int_equal(as_field_eval(ctx, g, q, mg), ANISTAR_OK);
            assert_int_equal(as_field_eval(ctx, u, q, mu), ANISTAR_OK);
            double e = min_rel_eig(mu, mg);
            if (e < least) least = e;
        }
    as_surface_sample_free(ctx, &smp);
    assert_true(least >= 1 - 1e-9);
    /* (3) growth along the cylinder from the seam x = 1 (the axial size h = 1/sqrt(m11)
     * starts at 1/2 and grows at most by ln G per unit of M-length) */
    double h = 0.5, worst = 0;
    const double lg = log(1.3), dx = 1e-3;
    for (double x = 1; x > 0; x -= dx) {
        double q[3] = {x - dx, 0.5, 0}, m[6];
        assert_int_equal(as_field_eval(ctx, g, q, m), ANISTAR_OK);
        h += dx * lg; /* dh / dx = ln G: the size-space form of 1 + l ln G */
        double hx = 1 / sqrt(m[0]);
        if (hx / h > worst) worst = hx / h;
    }
    double mid[6];
    const double pm[3] = {0, 0.5, 0};
    assert_int_equal(as_field_eval(ctx, g, pm, mid), ANISTAR_OK);
    print_message("capsule cylinder: axial size / graded bound at most %.3f; at x = 0: "
                  "m11 = %.3f (ungraded 0.25, the cap 4)\n", worst, mid[0]);
    assert_true(worst < 1.15);
    assert_true(mid[0] < 3.5 && mid[0] > 0.25);
    as_field_free(g);
    as_field_free(u);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* A field from a solver that jumps: on the unit sphere, isotropic with unit length 1/2 in
 * the upper half (z > 0) and 2 in the lower one (a size ratio of 4 across the equator).
 * With fail set it fails where x > 0.9. Counts its calls. */
typedef struct jump_user {
    int fail;
    long calls;
} jump_user;
static int jump_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)n;
    jump_user *u = user;
    u->calls++;
    if (u->fail && p[0] > 0.9) return 1;
    double e = p[2] > 0 ? 4 : 0.25;
    m[0] = m[3] = m[5] = e;
    m[1] = m[2] = m[4] = 0;
    return 0;
}

/* The tensors of m at the n points pts (3 n) into t (6 n). */
static void eval_all(const anistar_metric *m, const double *pts, size_t n, double *t) {
    for (size_t i = 0; i < n; i++)
        if (anistar_metric_eval(m, pts + 3 * i, t + 6 * i))
            fail_msg("eval at point %zu: %s", i, anistar_last_error(m->ctx));
}

/* anistar_metric_set_gradation on a metric from a callback (the public API end to end):
 * (1) bad G is EINVAL and leaves the field as it was; (2) graded with G = 1.3 the jump at
 * the equator is gone (distortion across it below 1.1; ungraded 4), the field is nowhere
 * below the callback's, and along a meridian of the coarse half the unit length grows
 * from the fine half's 1/2 within the gradation's bound 1/2 + s ln G (arc length s, the
 * sample's spacing as slack) yet above 1/2 at the pole (graded, not flattened); (3) a
 * second call replaces the first (G = 2 after 1.3 gives, bit for bit, what G = 2 gives on
 * a new metric); G = 0 gives back the callback's tensors bit for bit; (4) a callback that
 * fails at sample points makes the call fail naming the point, and the field is unchanged;
 * (5) a uniform metric accepts it unchanged; (6) ungraded, the run is refused by its
 * estimate with a message naming the setter; graded, the field meshes: certified, closed,
 * Euler characteristic 2, no distortion insertion. */
static void test_set_gradation(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    jump_user ju = {0, 0};
    anistar_metric *m = NULL;
    assert_int_equal(anistar_metric_from_callback(ctx, s, jump_fn, &ju, &m), ANISTAR_OK);
    as_point_sample smp;
    assert_int_equal(as_surface_sample(ctx, s, 300, &smp), ANISTAR_OK);
    const size_t n = smp.n;
    double *raw = malloc(n * 6 * sizeof *raw), *t = malloc(n * 6 * sizeof *t),
           *g13 = malloc(n * 6 * sizeof *g13);
    assert_true(raw && t && g13);
    eval_all(m, smp.points, n, raw);
    /* (1) */
    const double bad[] = {1, 0.5, -2, NAN, INFINITY};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(anistar_metric_set_gradation(m, bad[i]), ANISTAR_EINVAL);
        assert_non_null(strstr(anistar_last_error(ctx), "gradation G must be > 1"));
    }
    assert_int_equal(anistar_metric_set_gradation(NULL, 1.3), ANISTAR_EINVAL);
    eval_all(m, smp.points, n, t);
    assert_memory_equal(t, raw, n * 6 * sizeof *t);
    /* (2) */
    long before = ju.calls;
    assert_int_equal(anistar_metric_set_gradation(m, 1.3), ANISTAR_OK);
    print_message("set_gradation(1.3): %ld callback calls\n", ju.calls - before);
    assert_true(ju.calls - before >= AS_FIELD_GRAD_MIN_POINTS / 2); /* the sample and the pre-sample */
    const double pa[3] = {1, 0, 1e-7}, pb[3] = {1, 0, -1e-7};
    double a[6], b[6];
    assert_int_equal(anistar_metric_eval(m, pa, a), ANISTAR_OK);
    assert_int_equal(anistar_metric_eval(m, pb, b), ANISTAR_OK);
    double gg = gamma_of(a, b);
    print_message("equator: gamma %.4f graded (ungraded 4)\n", gg);
    assert_true(gg < 1.1);
    eval_all(m, smp.points, n, g13);
    double least = INFINITY;
    for (size_t i = 0; i < n; i++) least = fmin(least, min_rel_eig(raw + 6 * i, g13 + 6 * i));
    assert_true(least >= 1 - 1e-9);
    const double lg = log(1.3), ds = 1e-3;
    double worst = 0, L = 0;
    for (double th = 0; th < PI / 2; th += ds) { /* from the equator down to the pole */
        double q[3] = {cos(th + ds), 0, -sin(th + ds)}, mq[6];
        assert_int_equal(anistar_metric_eval(m, q, mq), ANISTAR_OK);
        double u[3] = {-sin(th + ds), 0, -cos(th + ds)}; /* along the meridian */
        double uMu = u[0] * (mq[0] * u[0] + mq[1] * u[1] + mq[2] * u[2]) +
                     u[1] * (mq[1] * u[0] + mq[3] * u[1] + mq[4] * u[2]) +
                     u[2] * (mq[2] * u[0] + mq[4] * u[1] + mq[5] * u[2]);
        L = 1 / sqrt(uMu);
        worst = fmax(worst, L / (0.5 + (th + ds) * lg));
    }
    print_message("meridian: unit length / graded bound at most %.3f; at the pole %.3f "
                  "(callback 2, equator 0.5)\n", worst, L);
    assert_true(worst < 1.15);
    assert_true(L > 0.6 && L < 1.0);
    /* (3) */
    assert_int_equal(anistar_metric_set_gradation(m, 2), ANISTAR_OK);
    eval_all(m, smp.points, n, t);
    anistar_metric *m2 = NULL;
    assert_int_equal(anistar_metric_from_callback(ctx, s, jump_fn, &ju, &m2), ANISTAR_OK);
    assert_int_equal(anistar_metric_set_gradation(m2, 2), ANISTAR_OK);
    double *t2 = malloc(n * 6 * sizeof *t2);
    assert_non_null(t2);
    eval_all(m2, smp.points, n, t2);
    assert_memory_equal(t, t2, n * 6 * sizeof *t);
    assert_memory_not_equal(t, g13, n * 6 * sizeof *t);
    anistar_metric_free(m2);
    assert_int_equal(anistar_metric_set_gradation(m, 0), ANISTAR_OK);
    eval_all(m, smp.points, n, t);
    assert_memory_equal(t, raw, n * 6 * sizeof *t);
    /* (4) */
    assert_int_equal(anistar_metric_set_gradation(m, 1.3), ANISTAR_OK);
    ju.fail = 1;
    assert_int_equal(anistar_metric_set_gradation(m, 2), ANISTAR_EINVAL);
    const char *e = anistar_last_error(ctx);
    assert_non_null(strstr(e, "the metric callback failed"));
    double q[3];
    msg_point(e, q);
    assert_true(q[0] > 0.9);
    ju.fail = 0;
    eval_all(m, smp.points, n, t);
    assert_memory_equal(t, g13, n * 6 * sizeof *t);
    /* (5) */
    anistar_metric *mu = NULL;
    const double uni[6] = {4, 0, 0, 1, 0, 0.25};
    assert_int_equal(anistar_metric_uniform(ctx, s, uni, &mu), ANISTAR_OK);
    assert_int_equal(anistar_metric_set_gradation(mu, 1.3), ANISTAR_OK);
    assert_int_equal(anistar_metric_eval(mu, pa, a), ANISTAR_OK);
    assert_memory_equal(a, uni, sizeof a);
    anistar_metric_free(mu);
    /* (6) ungraded, the run is refused up front, the message naming this call (and the
     * estimate ends: its bisection met gamma >= gamma0 at every distance > 0 from the
     * sample points with z = 0 exactly, down to the least subnormal, and looped there) */
    anistar_mesher *me = NULL;
    assert_int_equal(anistar_metric_from_callback(ctx, s, jump_fn, &ju, &m2), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m2, &me), ANISTAR_OK);
    anistar_mesh *none = (anistar_mesh *)1;
    assert_int_equal(anistar_mesher_run(me, &none), ANISTAR_EINVAL);
    assert_null(none);
    print_message("ungraded: %s\n", anistar_last_error(ctx));
    assert_non_null(strstr(anistar_last_error(ctx), "grade it: anistar_metric_set_gradation"));
    anistar_mesher_free(me);
    anistar_metric_free(m2);
    /* graded */
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_THREADS, 2), ANISTAR_OK);
    anistar_mesh *mesh = NULL;
    if (anistar_mesher_run(me, &mesh)) fail_msg("graded callback: %s", anistar_last_error(ctx));
    anistar_mesh_stats st;
    anistar_mesh_get_stats(mesh, &st);
    const anistar_mesh_stats *S = &st;
    print_message("sphere, jumping callback graded 1.3: %zu V, %llu distortion insertions\n",
                  S->vertices, (unsigned long long)S->insertions_distortion);
    assert_true(S->complete && S->closed_manifold);
    assert_int_equal(S->inconsistent_facets, 0);
    assert_int_equal(S->facets_below_hmin, 0);
    assert_int_equal(S->euler_characteristic, 2);
    assert_true(S->insertions_distortion == 0);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    free(raw);
    free(t);
    free(t2);
    free(g13);
    as_surface_sample_free(ctx, &smp);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* The setter gives the field the SPEC gives: "curvature,grad=1.3" and "curvature" graded
 * with 1.3 afterwards agree bit for bit on a triangle mesh (per-vertex tensors graded
 * along the edges), an image (lattice tensors along their nearest neighbours) and an
 * implicit surface (a graded sample); and 0 gives back the ungraded field ("grad=0": the
 * data fields are graded by default) on each. */
static void test_set_gradation_spec(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *surf[3] = {NULL, NULL, NULL};
    assert_int_equal(as_mesh_surface_read(ctx, AS_TEST_DATA_DIR "/fandisk.off", &surf[0]),
                     ANISTAR_OK);
    assert_int_equal(as_image_surface_read(ctx, AS_TEST_DATA_DIR "/skull_2.9.inr", 2.9, 1,
                                           &surf[1]),
                     ANISTAR_OK);
    surf[2] = expression(ctx, "max(abs(x)-1,0)^2+y^2+z^2-0.25", 2);
    for (int k = 0; k < 3; k++) {
        as_point_sample smp;
        assert_int_equal(as_surface_sample(ctx, surf[k], 200, &smp), ANISTAR_OK);
        as_field *a = field(ctx, surf[k], "curvature,grad=1.3"),
                 *b = field(ctx, surf[k], "curvature"), *c = field(ctx, surf[k], "curvature");
        assert_int_equal(as_field_set_gradation(ctx, b, 1.3), ANISTAR_OK);
        assert_int_equal(as_field_set_gradation(ctx, c, 1.6), ANISTAR_OK);
        assert_int_equal(as_field_set_gradation(ctx, c, 0), ANISTAR_OK);
        as_field *u = field(ctx, surf[k], "curvature,grad=0");
        size_t differ = 0;
        for (size_t i = 0; i < smp.n; i++) {
            double ta[6], tb[6], tc[6], tu[6];
            const double *p = smp.points + 3 * i;
            assert_int_equal(as_field_eval(ctx, a, p, ta), ANISTAR_OK);
            assert_int_equal(as_field_eval(ctx, b, p, tb), ANISTAR_OK);
            assert_int_equal(as_field_eval(ctx, c, p, tc), ANISTAR_OK);
            assert_int_equal(as_field_eval(ctx, u, p, tu), ANISTAR_OK);
            assert_memory_equal(ta, tb, sizeof ta);
            assert_memory_equal(tc, tu, sizeof tc);
            differ += memcmp(ta, tu, sizeof ta) != 0;
        }
        print_message("surface %d: graded differs from ungraded at %zu of %zu points\n", k,
                      differ, smp.n);
        assert_true(differ > 0); /* the gradation did something on each */
        as_field_free(a);
        as_field_free(b);
        as_field_free(c);
        as_field_free(u);
        as_surface_sample_free(ctx, &smp);
        as_surface_free(surf[k]);
    }
    anistar_context_free(ctx);
}

static void test_spec_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    struct {
        const char *spec;
        anistar_status st;
        const char *msg;
    } bad[] = {
        {"", ANISTAR_EINVAL, "empty name"},
        {"foo", ANISTAR_EINVAL, "unknown metric 'foo'"},
        {"curvatures", ANISTAR_EINVAL, "unknown metric"},
        {"curvature,eps=0", ANISTAR_EINVAL, "eps must be > 0"},
        {"curvature,eps=-1", ANISTAR_EINVAL, "eps must be > 0"},
        {"curvature,eps=abc", ANISTAR_EINVAL, "not a finite number"},
        {"curvature,eps=", ANISTAR_EINVAL, "not a finite number"},
        {"curvature,eps=nan", ANISTAR_EINVAL, "not a finite number"},
        {"curvature,foo=1", ANISTAR_EINVAL, "unknown option 'foo'"},
        {"curvature,phi=1", ANISTAR_EINVAL, "unknown option 'phi' (options: eps, en, power, grad)"},
        {"curvature,eps=1,eps=2", ANISTAR_EINVAL, "given twice"},
        {"curvature,eps", ANISTAR_EINVAL, "OPTION=VALUE"},
        {"curvature:x", ANISTAR_EINVAL, "takes no ':'"},
        {"euclidean,h=1", ANISTAR_EINVAL, "unknown option"},
        {"uniform,h=0", ANISTAR_EINVAL, "h must be > 0"},
        {"shock,lambda=-1", ANISTAR_EINVAL, "lambda must be > 0"},
        {"shock,phi=-1", ANISTAR_EINVAL, "phi must be >= 0"},
        {"curvature,grad=1", ANISTAR_EINVAL, "grad must be > 1"},
        {"sol:f.sol,grad=0.5", ANISTAR_EINVAL, "grad must be > 1 (or 0: none), got 0.5"},
        {"euclidean,grad=1.3", ANISTAR_EINVAL, "unknown option 'grad'"},
        {"shock,grad=0.9", ANISTAR_EINVAL, "grad must be > 1"},
        {"gradient", ANISTAR_EINVAL, "needs an argument"},
        {"gradient:", ANISTAR_EINVAL, "needs an argument"},
        {"hessian: ,eps=1", ANISTAR_EINVAL, "needs an argument"},
        {"sol:", ANISTAR_EINVAL, "needs an argument"},
        {"hessian:max(x,y", ANISTAR_EFORMAT, "unbalanced parentheses"},
        {"hessian:x)+(y", ANISTAR_EFORMAT, "unbalanced parentheses"},
        {"hessian:x+*y", ANISTAR_EFORMAT, "metric 'hessian': expression"},
        {"gradient:foo(x)", ANISTAR_EFORMAT, "metric 'gradient': expression"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        as_field_spec sp;
        anistar_status st = as_field_spec_parse(ctx, bad[i].spec, &sp);
        if (st != bad[i].st || !strstr(anistar_last_error(ctx), bad[i].msg))
            fail_msg("'%s': status %d, message '%s' (want %d, '%s')", bad[i].spec, st,
                     anistar_last_error(ctx), bad[i].st, bad[i].msg);
        assert_null(sp.expr);
    }
    /* good specs */
    as_field_spec sp;
    assert_int_equal(as_field_spec_parse(ctx, " hessian : max(x, y)^2 , eps = 0.5 ", &sp),
                     ANISTAR_OK);
    assert_int_equal(sp.kind, AS_FIELD_HESSIAN);
    assert_true(sp.has_eps && sp.eps == 0.5 && !sp.has_en);
    double p[3] = {2, 3, 0};
    assert_true(as_expr_value(sp.expr, p) == 9);
    as_field_spec_clear(ctx, &sp);
    assert_int_equal(as_field_spec_parse(ctx, "sol:some,file.sol", &sp), ANISTAR_EINVAL);
    assert_int_equal(as_field_spec_parse(ctx, "sol:file.sol", &sp), ANISTAR_OK);
    assert_string_equal(sp.path, "file.sol");
    as_field_spec_clear(ctx, &sp);
    /* sol on an implicit surface: not supported yet */
    as_surface *s = builtin(ctx, "sphere");
    as_field *f = (as_field *)1;
    assert_int_equal(as_field_from_spec(ctx, s, "sol:file.sol", &f), ANISTAR_EINVAL);
    assert_null(f);
    assert_non_null(strstr(anistar_last_error(ctx), "not supported yet for implicit surfaces"));
    /* the sphere's curvature field is constant: the gradation raises nothing and the
     * field stays exactly the ungraded one (no blend kept) */
    {
        as_field *g = field(ctx, s, "curvature,grad=1.3"), *u = field(ctx, s, "curvature");
        assert_null(g->g.blend);
        double mg[6], mu[6];
        assert_int_equal(as_field_eval(ctx, g, p, mg), ANISTAR_OK);
        assert_int_equal(as_field_eval(ctx, u, p, mu), ANISTAR_OK);
        assert_memory_equal(mg, mu, sizeof mg);
        as_field_free(g);
        as_field_free(u);
    }
    /* uniform */
    f = field(ctx, s, "uniform,h=0.5");
    double m[6];
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_true(m[0] == 4 && m[3] == 4 && m[5] == 4 && m[1] == 0);
    as_field_free(f);
    /* curvature on a surface without zero: the sampler's error */
    as_surface *e = expression(ctx, "x^2+y^2+z^2+1", 2);
    assert_int_equal(as_field_from_spec(ctx, e, "curvature", &f), ANISTAR_ENOSURFACE);
    assert_non_null(strstr(anistar_last_error(ctx), "no surface"));
    as_surface_free(e);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- public API ------------------------------------------------------------------------------ */

static int pub_fn(const double p[3], const double n[3], double m[6], void *user) {
    (void)p;
    (void)n;
    *(int *)user += 1;
    m[0] = m[3] = m[5] = 2;
    m[1] = m[2] = m[4] = 0;
    return 0;
}

static void test_public_api(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    assert_int_equal(anistar_surface_builtin(ctx, "torus", &s), ANISTAR_OK);
    anistar_metric *m = NULL;
    assert_int_equal(anistar_metric_from_spec(ctx, s, "curvature", &m), ANISTAR_OK);
    double p[3] = {11, 0, 0}, t[6];
    assert_int_equal(anistar_metric_eval(m, p, t), ANISTAR_OK);
    assert_true(fabs(t[0] - 1) < 1e-9 && fabs(t[3] - 1.0 / 121) < 1e-12 && fabs(t[5] - 1) < 1e-12);
    double bad[3] = {INFINITY, 0, 0};
    assert_int_equal(anistar_metric_eval(m, bad, t), ANISTAR_EINVAL);
    assert_int_equal(anistar_metric_eval(m, NULL, t), ANISTAR_EINVAL);
    assert_int_equal(anistar_metric_eval(NULL, p, t), ANISTAR_EINVAL);
    anistar_metric_free(m);
    assert_int_equal(anistar_metric_spec_check(ctx, "hessian:max(x,y)^2,eps=0.5"), ANISTAR_OK);
    assert_int_equal(anistar_metric_spec_check(ctx, "hessian:max(x,y)^2,eps=-0.5"),
                     ANISTAR_EINVAL);
    assert_int_equal(anistar_metric_spec_check(ctx, NULL), ANISTAR_EINVAL);
    assert_int_equal(anistar_metric_from_spec(ctx, NULL, "curvature", &m), ANISTAR_EINVAL);
    int calls = 0;
    assert_int_equal(anistar_metric_from_callback(ctx, s, pub_fn, &calls, &m), ANISTAR_OK);
    assert_int_equal(anistar_metric_eval(m, p, t), ANISTAR_OK);
    assert_true(calls == 1 && t[0] == 2);
    anistar_metric_free(m);
    double u[6] = {1, 0, 0, 1, 0, 1}, nu[6] = {1, 2, 0, 1, 0, 1};
    assert_int_equal(anistar_metric_uniform(ctx, NULL, u, &m), ANISTAR_OK);
    anistar_metric_free(m);
    assert_int_equal(anistar_metric_uniform(ctx, s, nu, &m), ANISTAR_EINVAL);
    assert_null(m);
    anistar_metric_free(NULL);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- allocation failures ----------------------------------------------------------------------- */

static void test_alloc_failures(void **state) {
    (void)state;
    const char *specs[] = {"curvature", "hessian:x^2*y,en=2", "shock", "uniform,h=2"};
    for (size_t sp = 0; sp < sizeof specs / sizeof specs[0]; sp++) {
        int succeeded = 0;
        for (long k = 0; k < 400 && !succeeded; k++) {
            tu_alloc ta;
            tu_alloc_init(&ta, k);
            anistar_allocator al = tu_allocator(&ta);
            anistar_context *ctx = anistar_context_new(&al);
            if (!ctx) continue;
            as_surface *s = NULL;
            anistar_status st = as_implicit_builtin(ctx, "sphere", &s);
            if (!st) {
                as_field *f = NULL;
                st = as_field_from_spec(ctx, s, specs[sp], &f);
                if (!st) {
                    double p[3] = {0, 0.6, 0.8}, m[6];
                    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
                    check_spd(m);
                    succeeded = 1;
                    as_field_free(f);
                } else {
                    assert_null(f);
                    assert_int_equal(st, ANISTAR_ENOMEM);
                }
                as_surface_free(s);
            }
            anistar_context_free(ctx);
            assert_int_equal(ta.live_blocks, 0);
            assert_int_equal(ta.live_bytes, 0);
        }
        assert_true(succeeded);
    }
}

/* The graded field (grad=G on a field given at every point) under allocation failures: the
 * capsule, whose gradation raises tensors, so the sample, the graph, the gradation and the
 * blend all allocate. Every allocation after the surface's is made to fail in turn (every
 * one of the last 64, which are the gradation's, and every 7th before them: the sampler's
 * allocations are tested by test_alloc_failures above): ENOMEM, nothing left allocated;
 * with none failing the field is made and graded. */
static void test_alloc_failures_graded(void **state) {
    (void)state;
    const char *src = "max(abs(x)-1,0)^2+y^2+z^2-0.25";
    const double c[3] = {0, 0, 0};
    long total = -1, base = -1;
    for (int pass = 0; pass < 2; pass++) { /* counts: after the surface, and in all */
        tu_alloc ta;
        tu_alloc_init(&ta, -1);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        assert_non_null(ctx);
        as_surface *s = NULL;
        assert_int_equal(as_implicit_from_expression(ctx, src, c, 2, &s), ANISTAR_OK);
        if (pass == 0) base = ta.count;
        as_field *f = NULL;
        if (pass == 1) {
            assert_int_equal(as_field_from_spec(ctx, s, "curvature,grad=1.3", &f), ANISTAR_OK);
            assert_non_null(f->g.blend);
            total = ta.count;
            as_field_free(f);
        }
        as_surface_free(s);
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
    }
    assert_true(total > base);
    long tested = 0;
    for (long k = base; k < total; k++) {
        if (k < total - 64 && (k - base) % 7 != 0) continue;
        tu_alloc ta;
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        assert_non_null(ctx);
        as_surface *s = NULL;
        assert_int_equal(as_implicit_from_expression(ctx, src, c, 2, &s), ANISTAR_OK);
        as_field *f = (as_field *)1;
        anistar_status st = as_field_from_spec(ctx, s, "curvature,grad=1.3", &f);
        if (st != ANISTAR_ENOMEM) fail_msg("allocation %ld failing: status %d", k, (int)st);
        assert_null(f);
        as_surface_free(s);
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
        assert_int_equal(ta.live_bytes, 0);
        tested++;
    }
    print_message("graded field: %ld allocations after the surface's, %ld failures tested\n",
                  total - base, tested);
}

/* The setter under allocation failures, on a metric from a callback (a graded sample)
 * and on a triangle mesh's curvature (graded vertex tensors): every allocation the call
 * makes fails in turn (every one of the last 24 and every 6th before them): ENOMEM, the
 * field as it was (the callback's tensors, no graded blend; the mesh's blend unchanged),
 * nothing left allocated when all is freed. */
static void test_alloc_failures_setter(void **state) {
    (void)state;
    const double p[3] = {0.6, 0, -0.8};
    for (int kind = 0; kind < 2; kind++) {
        long before = -1, after = -1;
        double want[6] = {0};
        for (long k = -1; k < 0 || k < after; k = k < 0 ? before : k + 1) { /* -1: count */
            if (k >= 0 && k < after - 24 && (k - before) % 6 != 0) continue;
            tu_alloc ta;
            tu_alloc_init(&ta, -1);
            anistar_allocator al = tu_allocator(&ta);
            anistar_context *ctx = anistar_context_new(&al);
            assert_non_null(ctx);
            as_surface *s = NULL;
            as_field *f = NULL;
            jump_user ju = {0, 0};
            if (kind == 0) {
                assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
                assert_int_equal(as_field_custom(ctx, s, jump_fn, &ju, &f), ANISTAR_OK);
            } else {
                assert_int_equal(as_mesh_surface_read(ctx, AS_TEST_DATA_DIR "/sphere_r0.5.off", &s),
                                 ANISTAR_OK);
                /* ungraded: the first gradation also keeps the tensors as fitted */
                assert_int_equal(as_field_from_spec(ctx, s, "curvature,grad=0", &f), ANISTAR_OK);
            }
            double m0[6], m1[6];
            const double *q = p;
            double qm[3] = {0.3, 0, -0.4}; /* on the mesh sphere of radius 1/2 */
            if (kind == 1) q = qm;
            assert_int_equal(as_field_eval(ctx, f, q, m0), ANISTAR_OK);
            if (k < 0) {
                before = ta.count;
                assert_int_equal(as_field_set_gradation(ctx, f, 1.3), ANISTAR_OK);
                after = ta.count;
                assert_int_equal(as_field_eval(ctx, f, q, want), ANISTAR_OK);
            } else {
                ta.fail_after = k;
                anistar_status st = as_field_set_gradation(ctx, f, 1.3);
                if (st != ANISTAR_ENOMEM) fail_msg("allocation %ld failing: status %d", k, (int)st);
                ta.fail_after = -1;
                assert_null(f->g.blend);
                assert_int_equal(as_field_eval(ctx, f, q, m1), ANISTAR_OK);
                assert_memory_equal(m0, m1, sizeof m0);
                if (k % 16 == 0) { /* and it succeeds afterwards (a few: each samples S) */
                    assert_int_equal(as_field_set_gradation(ctx, f, 1.3), ANISTAR_OK);
                    assert_int_equal(as_field_eval(ctx, f, q, m1), ANISTAR_OK);
                    assert_memory_equal(want, m1, sizeof m1);
                }
            }
            as_field_free(f);
            as_surface_free(s);
            anistar_context_free(ctx);
            assert_int_equal(ta.live_blocks, 0);
            assert_int_equal(ta.live_bytes, 0);
        }
        print_message("setter, %s: %ld allocations\n", kind ? "mesh curvature" : "callback",
                      after - before);
        assert_true(after > before);
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_curvature_torus),  cmocka_unit_test(test_curvature_umbilic),
        cmocka_unit_test(test_shock),            cmocka_unit_test(test_hessian),
        cmocka_unit_test(test_all_kinds_spd),    cmocka_unit_test(test_anisotropy_clamp),
        cmocka_unit_test(test_singular_points),  cmocka_unit_test(test_custom_errors),
        cmocka_unit_test(test_gradation),        cmocka_unit_test(test_gradation_analytic),
        cmocka_unit_test(test_set_gradation),    cmocka_unit_test(test_set_gradation_spec),
        cmocka_unit_test(test_alloc_failures_setter),
        cmocka_unit_test(test_spec_errors),      cmocka_unit_test(test_public_api),
        cmocka_unit_test(test_alloc_failures),   cmocka_unit_test(test_alloc_failures_graded),
        cmocka_unit_test(test_hessian_zero),
        cmocka_unit_test(test_builtin_overflow), cmocka_unit_test(test_sol_errors),
        cmocka_unit_test(test_mesher_refuses),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
