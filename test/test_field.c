/*
 * test_field.c — metric fields (lib/surface/field.c): curvature, shock and Hessian
 * tensors against hand computations, SPD and finite everywhere for every kind, the
 * anisotropy clamp, umbilic and singular points, custom callbacks, SPEC parsing errors,
 * allocation failures.
 */
#include "test_util.h"

#include "geom/linalg.h"
#include "surface/field.h"
#include "surface/surface.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

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
    double thin[6] = {1, 0, 0, 1e-30, 0, 1};
    assert_int_equal(as_field_uniform(ctx, NULL, thin, &f), ANISTAR_OK);
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_true(fabs(m[3] - 1e-12) < 1e-20);
    as_field_free(f);
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
    memcpy(m, t, sizeof t);
    return mode == 2; /* failure */
}

static void test_custom_errors(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere");
    double p[3] = {0.6, 0, 0.8}, m[6];
    const char *msgs[] = {"not positive definite", "non-finite", "callback failed",
                          "not positive definite"};
    for (int mode = 0; mode < 4; mode++) {
        as_field *f;
        assert_int_equal(as_field_custom(ctx, s, bad_fn, &mode, &f), ANISTAR_OK);
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_EINVAL);
        assert_non_null(strstr(anistar_last_error(ctx), msgs[mode]));
        assert_non_null(strstr(anistar_last_error(ctx), "(0.59999999999999998, 0, "));
        as_field_free(f);
    }
    /* NaN in a scalar field or in f: an error naming the point */
    as_field *f = field(ctx, s, "gradient:sqrt(x),en=1");
    double q[3] = {-0.6, 0, 0.8};
    assert_int_equal(as_field_eval(ctx, f, q, m), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "(-0.59999999999999998, 0, "));
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- SPEC parsing --------------------------------------------------------------------------- */

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
        {"curvature,phi=1", ANISTAR_EINVAL, "unknown option 'phi' (options: eps, en, power)"},
        {"curvature,eps=1,eps=2", ANISTAR_EINVAL, "given twice"},
        {"curvature,eps", ANISTAR_EINVAL, "OPTION=VALUE"},
        {"curvature:x", ANISTAR_EINVAL, "takes no ':'"},
        {"euclidean,h=1", ANISTAR_EINVAL, "unknown option"},
        {"uniform,h=0", ANISTAR_EINVAL, "h must be > 0"},
        {"shock,lambda=-1", ANISTAR_EINVAL, "lambda must be > 0"},
        {"shock,phi=-1", ANISTAR_EINVAL, "phi must be >= 0"},
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

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_curvature_torus),  cmocka_unit_test(test_curvature_umbilic),
        cmocka_unit_test(test_shock),            cmocka_unit_test(test_hessian),
        cmocka_unit_test(test_all_kinds_spd),    cmocka_unit_test(test_anisotropy_clamp),
        cmocka_unit_test(test_singular_points),  cmocka_unit_test(test_custom_errors),
        cmocka_unit_test(test_spec_errors),      cmocka_unit_test(test_public_api),
        cmocka_unit_test(test_alloc_failures),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
