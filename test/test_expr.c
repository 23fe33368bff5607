/*
 * test_expr.c — the expression language (lib/surface/expr.c): values against the same
 * formulas written in C, exact derivatives against hand-derived formulas and finite
 * differences, fused opcodes against their unfused forms, IEEE semantics at singular
 * points, syntax errors with their columns, huge inputs, allocation failures and
 * concurrent evaluation.
 */
#include "test_util.h"

#include "surface/expr.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ------------------------------------------------------------------------- */

static anistar_context *new_ctx(void) {
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    return ctx;
}

static as_expr *compile_ok(anistar_context *ctx, const char *src) {
    as_expr *e = NULL;
    anistar_status st = as_expr_compile(ctx, src, &e);
    if (st != ANISTAR_OK)
        fail_msg("compile \"%.80s\": %s: %s", src, anistar_status_name(st), anistar_last_error(ctx));
    assert_non_null(e);
    return e;
}

/* Bitwise-equal doubles, NaN equal to NaN. */
static int same(double a, double b) {
    if (isnan(a) && isnan(b)) return 1;
    return memcmp(&a, &b, sizeof a) == 0;
}

static void assert_same(double a, double b, const char *what) {
    if (!same(a, b)) fail_msg("%s: %.17g != %.17g", what, a, b);
}

/* |a - b| <= tol * (|b| + scale). */
static void assert_close(double a, double b, double tol, double scale, const char *what) {
    if (!(fabs(a - b) <= tol * (fabs(b) + scale)))
        fail_msg("%s: got %.17g, expected %.17g (diff %.3g, tol %.3g)", what, a, b, fabs(a - b),
                 tol * (fabs(b) + scale));
}

static void random_point(tu_rng *r, double lo, double hi, double p[3]) {
    for (int i = 0; i < 3; i++) p[i] = tu_rng_range(r, lo, hi);
}

/* A value with gradient and Hessian (m11 m12 m13 m22 m23 m33), written out by hand in
 * the tests below; the j_* rules are the textbook sum / product / quotient / chain
 * rules, used to assemble references from hand-derived pieces. */
typedef struct J {
    double f, g[3], h[6];
} J;

static const int IH[6] = {0, 0, 0, 1, 1, 2};
static const int JH[6] = {0, 1, 2, 1, 2, 2};

static J j_zero(double f) {
    J r;
    memset(&r, 0, sizeof r);
    r.f = f;
    return r;
}

/* phi(u) with phi' = d1, phi'' = d2. */
static J j_chain(J u, double f, double d1, double d2) {
    J r = j_zero(f);
    for (int i = 0; i < 3; i++) r.g[i] = d1 * u.g[i];
    for (int k = 0; k < 6; k++) r.h[k] = d1 * u.h[k] + d2 * u.g[IH[k]] * u.g[JH[k]];
    return r;
}

/* F(a, b) with its partial derivatives. */
static J j_bin(J a, J b, double f, double fa, double fb, double faa, double fab, double fbb) {
    J r = j_zero(f);
    for (int i = 0; i < 3; i++) r.g[i] = fa * a.g[i] + fb * b.g[i];
    for (int k = 0; k < 6; k++) {
        int i = IH[k], j = JH[k];
        r.h[k] = fa * a.h[k] + fb * b.h[k] + faa * a.g[i] * a.g[j] +
                 fab * (a.g[i] * b.g[j] + b.g[i] * a.g[j]) + fbb * b.g[i] * b.g[j];
    }
    return r;
}

static J j_add(J a, J b) { return j_bin(a, b, a.f + b.f, 1, 1, 0, 0, 0); }
static J j_sub(J a, J b) { return j_bin(a, b, a.f - b.f, 1, -1, 0, 0, 0); }
static J j_mul(J a, J b) { return j_bin(a, b, a.f * b.f, b.f, a.f, 0, 1, 0); }
static J j_div(J a, J b) {
    return j_bin(a, b, a.f / b.f, 1 / b.f, -a.f / (b.f * b.f), 0, -1 / (b.f * b.f),
                 2 * a.f / (b.f * b.f * b.f));
}

/* Compare all three entry points of e at p with the reference r: values relative tol,
 * derivatives relative to the size of the whole reference gradient / Hessian. */
static void check_against(const as_expr *e, const double p[3], const J *r, double tol,
                          const char *what) {
    double g[3], h[6], g2[3];
    double v0 = as_expr_value(e, p);
    double v1 = as_expr_value_grad(e, p, g2);
    double v2 = as_expr_value_grad_hess(e, p, g, h);
    char buf[200];
    /* the three entry points agree bitwise on value and gradient */
    snprintf(buf, sizeof buf, "%s value (grad vs value) at %g %g %g", what, p[0], p[1], p[2]);
    assert_same(v1, v0, buf);
    snprintf(buf, sizeof buf, "%s value (hess vs value) at %g %g %g", what, p[0], p[1], p[2]);
    assert_same(v2, v0, buf);
    for (int i = 0; i < 3; i++) {
        snprintf(buf, sizeof buf, "%s gradient %d (hess vs grad)", what, i);
        assert_same(g[i], g2[i], buf);
    }
    double gs = 1.0, hs = 1.0;
    for (int i = 0; i < 3; i++) gs = fmax(gs, fabs(r->g[i]));
    for (int k = 0; k < 6; k++) hs = fmax(hs, fabs(r->h[k]));
    snprintf(buf, sizeof buf, "%s value at %g %g %g", what, p[0], p[1], p[2]);
    assert_close(v0, r->f, tol, 1e-300, buf);
    for (int i = 0; i < 3; i++) {
        snprintf(buf, sizeof buf, "%s g[%d] at %g %g %g", what, i, p[0], p[1], p[2]);
        assert_close(g[i], r->g[i], tol, gs, buf);
    }
    for (int k = 0; k < 6; k++) {
        snprintf(buf, sizeof buf, "%s h[%d] at %g %g %g", what, k, p[0], p[1], p[2]);
        assert_close(h[k], r->h[k], tol, hs, buf);
    }
}

/* Central differences: of the value against the gradient, of the gradient against the
 * Hessian. Step 1e-5 (relative to |p|): truncation ~1e-10, rounding ~1e-11 relative. */
static void check_fd(const as_expr *e, const double p[3], const char *what) {
    double g[3], h[6];
    as_expr_value_grad_hess(e, p, g, h);
    double gs = 1.0, hs = 1.0;
    for (int i = 0; i < 3; i++) gs = fmax(gs, fabs(g[i]));
    for (int k = 0; k < 6; k++) hs = fmax(hs, fabs(h[k]));
    double H[3][3] = {{h[0], h[1], h[2]}, {h[1], h[3], h[4]}, {h[2], h[4], h[5]}};
    for (int j = 0; j < 3; j++) {
        double step = 1e-5 * (1.0 + fabs(p[j]));
        double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
        a[j] += step;
        b[j] -= step;
        double ga[3], gb[3];
        double fa = as_expr_value_grad(e, a, ga), fb = as_expr_value_grad(e, b, gb);
        double fd = (fa - fb) / (a[j] - b[j]);
        char buf[200];
        snprintf(buf, sizeof buf, "%s: FD gradient %d at %g %g %g", what, j, p[0], p[1], p[2]);
        assert_close(g[j], fd, 1e-6, gs, buf);
        for (int i = 0; i < 3; i++) {
            double fdh = (ga[i] - gb[i]) / (a[j] - b[j]);
            snprintf(buf, sizeof buf, "%s: FD Hessian %d%d at %g %g %g", what, i, j, p[0], p[1],
                     p[2]);
            assert_close(H[i][j], fdh, 1e-6, hs, buf);
        }
    }
}

/* ---- the headline surfaces ----------------------------------------------------------- */

#define TORUS "R=10; r=1; (sqrt(x^2+y^2)-R)^2 + z^2 - r^2"
#define CHAIR "a=0.8; b=0.4; k=1; (x^2+y^2+z^2-a*k^2)^2 - b*((z-k)^2-2*x^2)*((z+k)^2-2*y^2)"
#define SPHERE "x^2 + y^2 + z^2 - 1"

static double torus_c(const double p[3]) {
    double x = p[0], y = p[1], z = p[2], R = 10, r = 1;
    double a = sqrt(x * x + y * y) - R;
    return a * a + z * z - r * r;
}

static J torus_ref(const double p[3]) {
    double x = p[0], y = p[1], z = p[2], R = 10, r = 1;
    double rho = sqrt(x * x + y * y), q = rho - R, r3 = rho * rho * rho;
    J j = j_zero(q * q + z * z - r * r);
    j.g[0] = 2 * q * x / rho;
    j.g[1] = 2 * q * y / rho;
    j.g[2] = 2 * z;
    j.h[0] = 2 * x * x / (rho * rho) + 2 * q * y * y / r3;
    j.h[1] = 2 * R * x * y / r3;
    j.h[3] = 2 * y * y / (rho * rho) + 2 * q * x * x / r3;
    j.h[5] = 2;
    return j;
}

static double chair_c(const double p[3]) {
    double x = p[0], y = p[1], z = p[2], a = 0.8, b = 0.4, k = 1;
    double s = x * x + y * y + z * z - a * (k * k);
    double A = (z - k) * (z - k) - 2 * (x * x), B = (z + k) * (z + k) - 2 * (y * y);
    return s * s - b * A * B;
}

/* f = S^2 - b A B: grad = 2 S grad S - b (B grad A + A grad B),
 * H = 2 gS gS^T + 2 S HS - b (B HA + A HB + gA gB^T + gB gA^T). */
static J chair_ref(const double p[3]) {
    double x = p[0], y = p[1], z = p[2], a = 0.8, b = 0.4, k = 1;
    double S = x * x + y * y + z * z - a * k * k;
    double A = (z - k) * (z - k) - 2 * x * x, B = (z + k) * (z + k) - 2 * y * y;
    double gS[3] = {2 * x, 2 * y, 2 * z}, gA[3] = {-4 * x, 0, 2 * (z - k)},
           gB[3] = {0, -4 * y, 2 * (z + k)};
    double HS[6] = {2, 0, 0, 2, 0, 2}, HA[6] = {-4, 0, 0, 0, 0, 2}, HB[6] = {0, 0, 0, -4, 0, 2};
    J j = j_zero(S * S - b * A * B);
    for (int i = 0; i < 3; i++) j.g[i] = 2 * S * gS[i] - b * (B * gA[i] + A * gB[i]);
    for (int q = 0; q < 6; q++) {
        int i = IH[q], l = JH[q];
        j.h[q] = 2 * gS[i] * gS[l] + 2 * S * HS[q] -
                 b * (B * HA[q] + A * HB[q] + gA[i] * gB[l] + gB[i] * gA[l]);
    }
    return j;
}

static J sphere_ref(const double p[3]) {
    J j = j_zero(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - 1);
    for (int i = 0; i < 3; i++) j.g[i] = 2 * p[i];
    j.h[0] = j.h[3] = j.h[5] = 2;
    return j;
}

/* A mix of every function, and its C transcription with the same operation order. */
#define MIX                                                                                 \
    "sqrt(x^2+1) + exp(y/4) - log(z^2+2) + sin(x*y)*cos(z) + tan(x/3) - tanh(y) + abs(x-y)" \
    " + min(x,y)*max(y,z) + pow(z^2+1, 0.7) + atan2(y, x) + x^3 - y^-2 + (x^2+1)^0.5"      \
    " - 2/(1+z^2) + (3 - x)*(y + 0.5)^2"

static double mix_c(const double p[3]) {
    double x = p[0], y = p[1], z = p[2];
    return sqrt(x * x + 1) + exp(y / 4) - log(z * z + 2) + sin(x * y) * cos(z) + tan(x / 3) -
           tanh(y) + fabs(x - y) + fmin(x, y) * fmax(y, z) + pow(z * z + 1, 0.7) + atan2(y, x) +
           x * x * x - 1 / (y * y) + pow(x * x + 1, 0.5) - 2 / (1 + z * z) +
           (3 - x) * ((y + 0.5) * (y + 0.5));
}

static void test_values_match_c(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *t = compile_ok(ctx, TORUS), *c = compile_ok(ctx, CHAIR), *m = compile_ok(ctx, MIX);
    as_expr *s = compile_ok(ctx, SPHERE);
    tu_rng r = {1};
    for (int n = 0; n < 5000; n++) {
        double p[3];
        random_point(&r, -12, 12, p);
        assert_same(as_expr_value(t, p), torus_c(p), "torus");
        random_point(&r, -1.5, 1.5, p);
        assert_same(as_expr_value(c, p), chair_c(p), "chair");
        assert_same(as_expr_value(s, p), p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - 1, "sphere");
        random_point(&r, -3, 3, p);
        if (p[1] == 0) continue;
        assert_same(as_expr_value(m, p), mix_c(p), "mix");
    }
    as_expr_free(ctx, t);
    as_expr_free(ctx, c);
    as_expr_free(ctx, m);
    as_expr_free(ctx, s);
    anistar_context_free(ctx);
}

/* Integer powers by repeated squaring against pow(): a different operation order, so
 * within a few ulps (1e-15 relative up to x^5; each squaring doubles the error). */
static void test_integer_powers_vs_pow(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    static const int ns[] = {3, 4, 5, -1, -2, -3, -5, 7, 10, 16, 31};
    tu_rng r = {2};
    for (size_t i = 0; i < sizeof ns / sizeof ns[0]; i++) {
        char src[32];
        snprintf(src, sizeof src, "x^%d", ns[i]);
        as_expr *e = compile_ok(ctx, src);
        double tol = abs(ns[i]) <= 5 ? 1e-15 : 8e-15;
        for (int k = 0; k < 500; k++) {
            double p[3];
            random_point(&r, -3, 3, p);
            if (p[0] == 0) continue;
            assert_close(as_expr_value(e, p), pow(p[0], ns[i]), tol, 0, src);
        }
        as_expr_free(ctx, e);
    }
    anistar_context_free(ctx);
}

static void test_surfaces_hand_derivatives(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *t = compile_ok(ctx, TORUS), *c = compile_ok(ctx, CHAIR), *s = compile_ok(ctx, SPHERE);
    tu_rng r = {3};
    for (int n = 0; n < 2000; n++) {
        double p[3];
        random_point(&r, -12, 12, p);
        J jt = torus_ref(p);
        check_against(t, p, &jt, 1e-12, "torus");
        random_point(&r, -1.5, 1.5, p);
        J jc = chair_ref(p);
        check_against(c, p, &jc, 1e-12, "chair");
        J js = sphere_ref(p);
        check_against(s, p, &js, 0, "sphere"); /* exact */
        if (n % 10 == 0) {
            check_fd(t, p, "torus");
            check_fd(c, p, "chair");
        }
    }
    as_expr_free(ctx, t);
    as_expr_free(ctx, c);
    as_expr_free(ctx, s);
    anistar_context_free(ctx);
}

/* ---- every function and operator, through a composition ------------------------------ */

/* Inner functions with hand-derived derivatives:
 *   U = 0.5 x^2 + y z - 0.3 y + 0.2 x + 1.7   grad (x + 0.2, z - 0.3, y), H: m11 1, m23 1
 *   V = x y - z^2 + 0.5                       grad (y, x, -2z),           H: m12 1, m33 -2 */
#define U_SRC "(0.5*x^2 + y*z - 0.3*y + 0.2*x + 1.7)"
#define V_SRC "(x*y - z^2 + 0.5)"

static J u_ref(const double p[3]) {
    double x = p[0], y = p[1], z = p[2];
    J j = j_zero(0.5 * (x * x) + y * z - 0.3 * y + 0.2 * x + 1.7);
    j.g[0] = x + 0.2;
    j.g[1] = z - 0.3;
    j.g[2] = y;
    j.h[0] = 1;
    j.h[4] = 1;
    return j;
}

static J v_ref(const double p[3]) {
    double x = p[0], y = p[1], z = p[2];
    J j = j_zero(x * y - z * z + 0.5);
    j.g[0] = y;
    j.g[1] = x;
    j.g[2] = -2 * z;
    j.h[1] = 1;
    j.h[5] = -2;
    return j;
}

/* phi, phi', phi'' written independently of the library's forms. */
typedef void (*unary_ref)(double u, double *f, double *d1, double *d2);
static void r_sqrt(double u, double *f, double *d1, double *d2) {
    *f = sqrt(u), *d1 = 0.5 / sqrt(u), *d2 = -0.25 / (u * sqrt(u));
}
static void r_exp(double u, double *f, double *d1, double *d2) { *f = *d1 = *d2 = exp(u); }
static void r_log(double u, double *f, double *d1, double *d2) {
    *f = log(u), *d1 = 1 / u, *d2 = -1 / (u * u);
}
static void r_sin(double u, double *f, double *d1, double *d2) {
    *f = sin(u), *d1 = cos(u), *d2 = -sin(u);
}
static void r_cos(double u, double *f, double *d1, double *d2) {
    *f = cos(u), *d1 = -sin(u), *d2 = -cos(u);
}
static void r_tan(double u, double *f, double *d1, double *d2) {
    double c = cos(u);
    *f = tan(u), *d1 = 1 / (c * c), *d2 = 2 * sin(u) / (c * c * c);
}
static void r_tanh(double u, double *f, double *d1, double *d2) {
    double c = cosh(u);
    *f = tanh(u), *d1 = 1 / (c * c), *d2 = -2 * sinh(u) / (c * c * c);
}
static void r_abs(double u, double *f, double *d1, double *d2) {
    *f = fabs(u), *d1 = u < 0 ? -1 : 1, *d2 = 0;
}
static void r_neg(double u, double *f, double *d1, double *d2) { *f = -u, *d1 = -1, *d2 = 0; }
static void r_sq(double u, double *f, double *d1, double *d2) { *f = u * u, *d1 = 2 * u, *d2 = 2; }
static void r_sqm(double u, double *f, double *d1, double *d2) { /* (u - 1.25)^2 */
    *f = (u - 1.25) * (u - 1.25), *d1 = 2 * (u - 1.25), *d2 = 2;
}

static void test_unary_functions(void **state) {
    (void)state;
    static const struct {
        const char *fmt;
        unary_ref ref;
    } cases[] = {
        {"sqrt(%s)", r_sqrt}, {"exp(%s)", r_exp},   {"log(%s)", r_log},  {"sin(%s)", r_sin},
        {"cos(%s)", r_cos},   {"tan(%s)", r_tan},   {"tanh(%s)", r_tanh}, {"abs(%s)", r_abs},
        {"-%s", r_neg},       {"%s^2", r_sq},       {"(%s-1.25)^2", r_sqm},
        {"(1.25-%s)^2", r_sqm}, {"pow(%s, 2)", r_sq},
    };
    anistar_context *ctx = new_ctx();
    tu_rng r = {4};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        char src[200];
        snprintf(src, sizeof src, cases[c].fmt, U_SRC);
        as_expr *e = compile_ok(ctx, src);
        int checked = 0;
        for (int n = 0; n < 400; n++) {
            double p[3], f, d1, d2;
            random_point(&r, -1.5, 1.5, p);
            J u = u_ref(p);
            cases[c].ref(u.f, &f, &d1, &d2);
            if (!isfinite(f) || !isfinite(d2) || fabs(u.f) < 1e-3) continue;
            J ref = j_chain(u, f, d1, d2);
            check_against(e, p, &ref, 1e-12, src);
            /* finite differences away from poles and kinks */
            if (n % 8 == 0 && fabs(u.f) > 0.1 && fabs(d1) < 100 && fabs(d2) < 100)
                check_fd(e, p, src);
            checked++;
        }
        if (checked < 100) fail_msg("%s: only %d points checked", src, checked);
        as_expr_free(ctx, e);
    }
    anistar_context_free(ctx);
}

/* Constant exponents: integers by repeated squaring (also for negative bases), other
 * reals through pow (NaN for negative bases). */
static void test_constant_powers(void **state) {
    (void)state;
    static const double ns[] = {3, 4, 5, -1, -2, -3, 10, 0.5, 1.5, -0.5, 2.5, 1.0 / 3.0};
    anistar_context *ctx = new_ctx();
    tu_rng r = {5};
    for (size_t c = 0; c < sizeof ns / sizeof ns[0]; c++) {
        char src[200];
        snprintf(src, sizeof src, "%s^%.17g", V_SRC, ns[c]);
        as_expr *e = compile_ok(ctx, src);
        double n = ns[c];
        int integer = n == floor(n), checked = 0;
        for (int k = 0; k < 400; k++) {
            double p[3];
            random_point(&r, -1.5, 1.5, p);
            J v = v_ref(p);
            if (fabs(v.f) < 1e-2) continue;
            double f = pow(v.f, n), d1 = n * pow(v.f, n - 1), d2 = n * (n - 1) * pow(v.f, n - 2);
            if (v.f < 0 && !integer) { /* negative base, real exponent: NaN, no trap */
                double g[3], h[6];
                assert_true(isnan(as_expr_value(e, p)));
                assert_true(isnan(as_expr_value_grad_hess(e, p, g, h)));
                continue;
            }
            J ref = j_chain(v, f, d1, d2);
            check_against(e, p, &ref, 1e-12, src);
            if (k % 8 == 0 && fabs(v.f) > 0.1) check_fd(e, p, src);
            checked++;
        }
        if (checked < 100) fail_msg("%s: only %d points checked", src, checked);
        as_expr_free(ctx, e);
    }
    /* exact small cases on negative bases */
    static const struct {
        const char *src;
        double x, f, g, h;
    } ex[] = {
        {"x^3", -2, -8, 12, -12},       {"x^4", -1.5, 5.0625, -13.5, 27},
        {"x^-1", -2, -0.5, -0.25, -0.25}, {"x^-2", -2, 0.25, 0.25, 0.375},
        {"x^-3", -0.5, -8, -48, -384},  {"x^0.5", 4, 2, 0.25, -1.0 / 32},
        {"x^1", -3, -3, 1, 0},          {"x^0", -3, 1, 0, 0},
        {"(-x)^3", 2, -8, -12, -12},
    };
    for (size_t c = 0; c < sizeof ex / sizeof ex[0]; c++) {
        as_expr *e = compile_ok(ctx, ex[c].src);
        double p[3] = {ex[c].x, 0.5, 0.25}, g[3], h[6];
        double f = as_expr_value_grad_hess(e, p, g, h);
        assert_close(f, ex[c].f, 1e-15, 0, ex[c].src);
        assert_close(g[0], ex[c].g, 1e-15, 0, ex[c].src);
        assert_close(h[0], ex[c].h, 1e-15, 0, ex[c].src);
        assert_true(g[1] == 0 && g[2] == 0 && h[1] == 0 && h[3] == 0 && h[5] == 0);
        as_expr_free(ctx, e);
    }
    anistar_context_free(ctx);
}

typedef J (*binary_ref)(J a, J b);
static J rb_add(J a, J b) { return j_add(a, b); }
static J rb_sub(J a, J b) { return j_sub(a, b); }
static J rb_mul(J a, J b) { return j_mul(a, b); }
static J rb_div(J a, J b) { return j_div(a, b); }
/* d/da a^b = b a^(b-1), d/db = a^b ln a, d2/da2 = b(b-1) a^(b-2), d2/dadb = a^(b-1)(1 + b ln a),
 * d2/db2 = a^b ln^2 a */
static J rb_pow(J a, J b) {
    double A = a.f, B = b.f, L = log(A);
    return j_bin(a, b, pow(A, B), B * pow(A, B - 1), pow(A, B) * L, B * (B - 1) * pow(A, B - 2),
                 pow(A, B - 1) * (1 + B * L), pow(A, B) * L * L);
}
/* atan2(a, b): d/da = b/r2, d/db = -a/r2, d2/da2 = -2ab/r2^2, d2/db2 = 2ab/r2^2,
 * d2/dadb = (a^2 - b^2)/r2^2 */
static J rb_atan2(J a, J b) {
    double A = a.f, B = b.f, r2 = A * A + B * B;
    return j_bin(a, b, atan2(A, B), B / r2, -A / r2, -2 * A * B / (r2 * r2), (A * A - B * B) / (r2 * r2),
                 2 * A * B / (r2 * r2));
}
static J rb_min(J a, J b) { return a.f <= b.f ? a : b; }
static J rb_max(J a, J b) { return a.f >= b.f ? a : b; }

static void test_binary_operators(void **state) {
    (void)state;
    static const struct {
        const char *fmt;
        binary_ref ref;
        int positive_a; /* needs a > 0 */
    } cases[] = {
        {"%s + %s", rb_add, 0},       {"%s - %s", rb_sub, 0},       {"%s * %s", rb_mul, 0},
        {"%s / %s", rb_div, 0},       {"%s ^ %s", rb_pow, 1},       {"pow(%s, %s)", rb_pow, 1},
        {"atan2(%s, %s)", rb_atan2, 0}, {"min(%s, %s)", rb_min, 0}, {"max(%s, %s)", rb_max, 0},
    };
    anistar_context *ctx = new_ctx();
    tu_rng r = {6};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        /* both orders: U op V and V op U */
        for (int order = 0; order < 2; order++) {
            char src[300];
            snprintf(src, sizeof src, cases[c].fmt, order ? V_SRC : U_SRC, order ? U_SRC : V_SRC);
            as_expr *e = compile_ok(ctx, src);
            int checked = 0;
            for (int n = 0; n < 400; n++) {
                double p[3];
                random_point(&r, -1.5, 1.5, p);
                J u = u_ref(p), v = v_ref(p);
                J a = order ? v : u, b = order ? u : v;
                if (cases[c].positive_a && a.f <= 0.05) continue;
                if (fabs(b.f) < 0.05 || fabs(a.f - b.f) < 1e-3) continue; /* poles, ties */
                J ref = cases[c].ref(a, b);
                check_against(e, p, &ref, 1e-12, src);
                if (n % 8 == 0 && fabs(b.f) > 0.2 && a.f * a.f + b.f * b.f > 0.1 &&
                    fabs(a.f - b.f) > 0.05)
                    check_fd(e, p, src);
                checked++;
            }
            if (checked < 50) fail_msg("%s: only %d points checked", src, checked);
            as_expr_free(ctx, e);
        }
    }
    anistar_context_free(ctx);
}

/* A product / quotient / composition mix using every function, against the reference
 * assembled from the hand-derived pieces. */
static void test_mix_every_function(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *e = compile_ok(
        ctx, "sqrt(" U_SRC ")*exp(" V_SRC ")/(2 + cos(" V_SRC ")) - log(" U_SRC ")*tanh(" V_SRC
             ") + sin(" U_SRC ")^3/tan(" V_SRC ") + abs(" V_SRC ")*min(" U_SRC ", " V_SRC
             ") - max(" U_SRC ", " V_SRC ")^2 + atan2(" V_SRC ", " U_SRC ") + pow(" U_SRC
             ", " V_SRC ")");
    tu_rng r = {7};
    int checked = 0;
    for (int n = 0; n < 2000 && checked < 500; n++) {
        double p[3];
        random_point(&r, -1.5, 1.5, p);
        J u = u_ref(p), v = v_ref(p);
        if (u.f <= 0.05 || fabs(v.f) < 0.05 || fabs(u.f - v.f) < 1e-3 || fabs(sin(v.f)) < 0.05)
            continue;
        double f, d1, d2, f2, e1, e2;
        r_sqrt(u.f, &f, &d1, &d2);
        J a = j_chain(u, f, d1, d2);
        r_exp(v.f, &f, &d1, &d2);
        J b = j_chain(v, f, d1, d2);
        r_cos(v.f, &f, &d1, &d2);
        J c = j_chain(v, 2 + f, d1, d2);
        J term1 = j_div(j_mul(a, b), c);
        r_log(u.f, &f, &d1, &d2);
        r_tanh(v.f, &f2, &e1, &e2);
        J term2 = j_mul(j_chain(u, f, d1, d2), j_chain(v, f2, e1, e2));
        r_sin(u.f, &f, &d1, &d2);
        J s = j_chain(u, f, d1, d2);
        J s3 = j_chain(s, s.f * s.f * s.f, 3 * s.f * s.f, 6 * s.f);
        r_tan(v.f, &f, &d1, &d2);
        J term3 = j_div(s3, j_chain(v, f, d1, d2));
        r_abs(v.f, &f, &d1, &d2);
        J term4 = j_mul(j_chain(v, f, d1, d2), rb_min(u, v));
        J mx = rb_max(u, v);
        J term5 = j_chain(mx, mx.f * mx.f, 2 * mx.f, 2);
        J ref = j_add(j_add(j_add(j_sub(j_add(j_sub(term1, term2), term3), j_zero(0)), term4),
                            j_sub(rb_atan2(v, u), term5)),
                      rb_pow(u, v));
        check_against(e, p, &ref, 1e-12, "mix");
        if (n % 4 == 0) check_fd(e, p, "mix");
        checked++;
    }
    assert_true(checked >= 200);
    as_expr_free(ctx, e);
    anistar_context_free(ctx);
}

/* ---- fused opcodes against their unfused forms --------------------------------------- */

/* Replace each variable v by max(v, v) (same value, same derivatives, but an opaque
 * operand that no fusion recognises). */
static void unfuse(const char *src, char *out, size_t size) {
    size_t o = 0;
    for (const char *s = src; *s && o + 16 < size; s++) {
        int prev_name = s > src && (s[-1] == '_' || (s[-1] >= 'a' && s[-1] <= 'z') ||
                                    (s[-1] >= 'A' && s[-1] <= 'Z') || (s[-1] >= '0' && s[-1] <= '9'));
        int next_name = s[1] == '_' || (s[1] >= 'a' && s[1] <= 'z') || (s[1] >= '0' && s[1] <= '9');
        if ((*s == 'x' || *s == 'y' || *s == 'z') && !prev_name && !next_name)
            o += (size_t)snprintf(out + o, size - o, "max(%c,%c)", *s, *s);
        else
            out[o++] = *s;
    }
    out[o] = '\0';
}

static void test_fused_shapes(void **state) {
    (void)state;
    static const char *shapes[] = {
        "x*y",           "x^2*y",         "y*x^2",         "y - x^2",       "x^2 - y*z",
        "x - y*z",       "y*z + x",       "y*z - x",       "y*z + x^2",     "y*z - x^2",
        "(y*z)*x^2",     "x^2*(y*z)",     "2/x",           "x/2",           "x/3",
        "3 - x*y",       "3 + x*y",       "x*y*3",         "-(x*y*3)",      "-(x*y) * 2",
        "(x - 1)*y*z",   "y*z*(x + 2)",   "y*z - (x + 2)", "(x + 2) - y*z", "y*z + (2 + x)",
        "y*z*(x - 1)^2", "(z - 1)^2 - y*x", "y*x - (1 - z)^2", "y*x + 3*(z + 1)^2",
        "y*x - 3*z^2",   "y*x + -z",      "-z + y*x",      "y*x * -z",      "-2*x + y*z",
        "y*z - 0.4*x",   "(y*z)*(0.4*x)", "(0.4*x)*(y*z)", "(sin(x)*y + 1)^2",
        "(2 - sin(x)*y)^2", "(sin(x)*y - 0.5)^2", "exp(z) - sin(x)*cos(y)",
        "exp(z) / (sin(x)*cos(y))", "exp(z) + sin(x)*cos(y)", "exp(z) * (sin(x)*cos(y))",
        "x^2 + y^2 + z^2 - 1", "(x + 1)^2 + (y - 2)^2 + (3 - z)^2 - 1", "-(x - 1)^2 * y",
        "2*(x - 1) - y", "y - 2*(x - 1)", "x*(y*(z*(x + y)))", "1/(x*y)", "(x*y)/(y*z + 5)",
    };
    anistar_context *ctx = new_ctx();
    tu_rng r = {8};
    for (size_t c = 0; c < sizeof shapes / sizeof shapes[0]; c++) {
        char plain[512];
        unfuse(shapes[c], plain, sizeof plain);
        as_expr *e = compile_ok(ctx, shapes[c]), *q = compile_ok(ctx, plain);
        assert_true(as_expr_code_size(e) < as_expr_code_size(q));
        for (int n = 0; n < 200; n++) {
            double p[3], g[3], h[6], gq[3], hq[6];
            for (int i = 0; i < 3; i++) /* |p_i| in [0.2, 2]: away from the poles of 1/x */
                p[i] = tu_rng_range(&r, 0.2, 2) * (tu_rng_unit(&r) < 0.5 ? -1 : 1);
            double f = as_expr_value_grad_hess(e, p, g, h);
            double fq = as_expr_value_grad_hess(q, p, gq, hq);
            /* the fused forms are exact rewritings: the values are bitwise equal */
            assert_same(as_expr_value(e, p), as_expr_value(q, p), shapes[c]);
            assert_same(f, fq, shapes[c]);
            double gs = 1, hs = 1;
            for (int i = 0; i < 3; i++) gs = fmax(gs, fabs(gq[i]));
            for (int k = 0; k < 6; k++) hs = fmax(hs, fabs(hq[k]));
            for (int i = 0; i < 3; i++) assert_close(g[i], gq[i], 1e-13, gs, shapes[c]);
            for (int k = 0; k < 6; k++) assert_close(h[k], hq[k], 1e-13, hs, shapes[c]);
            if (n % 20 == 0) check_fd(e, p, shapes[c]);
        }
        as_expr_free(ctx, e);
        as_expr_free(ctx, q);
    }
    /* the headline surfaces compile to short code (a regression guard for speed) */
    as_expr *t = compile_ok(ctx, TORUS), *c = compile_ok(ctx, CHAIR), *s = compile_ok(ctx, SPHERE);
    assert_true(as_expr_code_size(t) <= 6);
    assert_true(as_expr_code_size(c) <= 11);
    assert_true(as_expr_code_size(s) <= 4);
    assert_true(as_expr_stack_depth(c) <= 2);
    as_expr_free(ctx, t);
    as_expr_free(ctx, c);
    as_expr_free(ctx, s);
    anistar_context_free(ctx);
}

/* ---- special points ------------------------------------------------------------------- */

static void eval3(const as_expr *e, double x, double y, double z, double *f, double g[3],
                  double h[6]) {
    double p[3] = {x, y, z};
    *f = as_expr_value_grad_hess(e, p, g, h);
    double g2[3];
    assert_same(as_expr_value(e, p), *f, "value vs hess");
    assert_same(as_expr_value_grad(e, p, g2), *f, "grad vs hess");
}

static void test_atan2_quadrants(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *e = compile_ok(ctx, "atan2(y, x)");
    static const double pts[][2] = {{1, 2}, {-1, 2}, {-1, -2}, {1, -2}, {3, 0.5}, {-3, 0.5},
                                    {-3, -0.5}, {0.5, -3}, {0, 1}, {-1, 0}};
    for (size_t i = 0; i < sizeof pts / sizeof pts[0]; i++) {
        double x = pts[i][0], y = pts[i][1], f, g[3], h[6], r2 = x * x + y * y;
        eval3(e, x, y, 0.3, &f, g, h);
        assert_close(f, atan2(y, x), 1e-15, 0, "atan2 value");
        /* d/dx = -y/r2, d/dy = x/r2; d2/dx2 = 2xy/r2^2, d2/dxdy = (y^2-x^2)/r2^2, d2/dy2 = -2xy/r2^2 */
        J ref = j_zero(atan2(y, x));
        ref.g[0] = -y / r2;
        ref.g[1] = x / r2;
        ref.h[0] = 2 * x * y / (r2 * r2);
        ref.h[1] = (y * y - x * x) / (r2 * r2);
        ref.h[3] = -2 * x * y / (r2 * r2);
        double p[3] = {x, y, 0.3};
        check_against(e, p, &ref, 1e-14, "atan2");
        /* the quadrant is right: the angle's sign follows y, |angle| > pi/2 iff x < 0 */
        if (y != 0) assert_true((f > 0) == (y > 0));
        if (x != 0) assert_true((fabs(f) > 1.5707963267948966) == (x < 0));
    }
    /* at the origin: value atan2(0, 0) = 0, derivatives NaN, no trap */
    double f, g[3], h[6];
    eval3(e, 0, 0, 0, &f, g, h);
    assert_true(f == 0 && isnan(g[0]) && isnan(h[0]));
    as_expr_free(ctx, e);
    anistar_context_free(ctx);
}

static void test_ties_and_kinks(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    double f, g[3], h[6];
    /* as_expr_has_kinks: abs, min or max of something that varies; constants fold away */
    static const struct {
        const char *src;
        int kinks;
    } kk[] = {{"x^2+y^2+z^2-1", 0},       {"abs(x)+y", 1},          {"max(x,y)-z", 1},
              {"min(x^2, y)", 1},         {"min(1, 2)*x + abs(-3)", 0}, {"sqrt(x^2+1)-y", 0},
              {"a=abs(-2); a*x^2 - y", 0}};
    for (size_t i = 0; i < sizeof kk / sizeof kk[0]; i++) {
        as_expr *k = compile_ok(ctx, kk[i].src);
        if (as_expr_has_kinks(k) != kk[i].kinks)
            fail_msg("'%s': has_kinks %d", kk[i].src, as_expr_has_kinks(k));
        as_expr_free(ctx, k);
    }
    assert_int_equal(as_expr_has_kinks(NULL), 0);
    /* abs at 0: the branch +u */
    as_expr *e = compile_ok(ctx, "abs(x*y - 1)");
    eval3(e, 1, 1, 0, &f, g, h);
    assert_true(f == 0 && !signbit(f) && g[0] == 1 && g[1] == 1 && h[1] == 1);
    eval3(e, -2, 1, 0, &f, g, h);
    assert_true(f == 3 && g[0] == -1 && g[1] == 2 && h[1] == -1);
    as_expr_free(ctx, e);
    /* min / max at a tie: the first argument */
    e = compile_ok(ctx, "min(x^2, y)");
    eval3(e, 2, 4, 0, &f, g, h);
    assert_true(f == 4 && g[0] == 4 && g[1] == 0 && h[0] == 2);
    eval3(e, 2, 3, 0, &f, g, h);
    assert_true(f == 3 && g[0] == 0 && g[1] == 1 && h[0] == 0);
    as_expr_free(ctx, e);
    e = compile_ok(ctx, "max(y, x^2)");
    eval3(e, 2, 4, 0, &f, g, h);
    assert_true(f == 4 && g[0] == 0 && g[1] == 1 && h[0] == 0);
    as_expr_free(ctx, e);
    e = compile_ok(ctx, "max(x, y, z)"); /* variadic, left to right: max(max(x, y), z) */
    eval3(e, 1, 1, 1, &f, g, h);
    assert_true(f == 1 && g[0] == 1 && g[1] == 0 && g[2] == 0);
    eval3(e, 1, 3, 2, &f, g, h);
    assert_true(f == 3 && g[1] == 1);
    as_expr_free(ctx, e);
    /* NaN is never swallowed by min / max (fmin would drop it) */
    e = compile_ok(ctx, "min(log(x), 1) + max(2, sqrt(x))");
    eval3(e, -1, 0, 0, &f, g, h);
    assert_true(isnan(f));
    as_expr_free(ctx, e);
    anistar_context_free(ctx);
}

static void test_nan_semantics(void **state) {
    (void)state;
    static const struct {
        const char *src;
        double x;
        int nan;      /* 1: NaN expected */
        double value; /* otherwise */
    } cases[] = {
        {"1/x", 0, 1, 0},          {"x/0", 3, 1, 0},          {"1/0", 0, 1, 0},
        {"0/0", 0, 1, 0},          {"x/(y - y)", 1, 1, 0},     {"2/(x - 1)", 1, 1, 0},
        {"(x*y)/(x - 1)", 1, 1, 0}, {"log(x)", -1, 1, 0},      {"log(-1)", 0, 1, 0},
        {"sqrt(x)", -1, 1, 0},      {"sqrt(-1)", 0, 1, 0},     {"x^-1", 0, 1, 0},
        {"x^-2", 0, 1, 0},          {"0^-1", 0, 1, 0},         {"x^-0.5", 0, 1, 0},
        {"pow(x, -1.5)", 0, 1, 0},  {"x^0.5", -1, 1, 0},       {"(-8)^(1/3)", 0, 1, 0},
        {"pow(x, y)", -2, 1, 0},    {"log(x)", 0, 0, -INFINITY}, {"x^0.5", 0, 0, 0},
        {"x^2.5", 0, 0, 0},         {"pow(x, 1.5)", 0, 0, 0},  {"x^0", 0, 0, 1},
        {"sqrt(x)", 0, 0, 0},       {"exp(x)", 1000, 0, INFINITY},
    };
    anistar_context *ctx = new_ctx();
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        as_expr *e = compile_ok(ctx, cases[c].src);
        double f, g[3], h[6];
        eval3(e, cases[c].x, 0.5, 0.25, &f, g, h);
        if (cases[c].nan) {
            if (!isnan(f)) fail_msg("%s at x=%g: %g, expected NaN", cases[c].src, cases[c].x, f);
        } else {
            assert_same(f, cases[c].value, cases[c].src);
        }
        as_expr_free(ctx, e);
    }
    /* derivative of sqrt at 0: infinite or NaN, never a trap; the value stays 0 */
    as_expr *e = compile_ok(ctx, "sqrt(x) + sqrt(y^2)");
    double f, g[3], h[6];
    eval3(e, 0, 0, 0, &f, g, h);
    assert_true(f == 0 && !isfinite(g[0]) && !isfinite(g[1]) && !isfinite(h[0]));
    as_expr_free(ctx, e);
    /* pow with a variable exponent on a negative base with an integer exponent: the
     * value exists, d/dexponent is NaN, and forward mode carries it into the whole
     * gradient (documented) */
    e = compile_ok(ctx, "pow(x, y)");
    eval3(e, -2, 3, 0, &f, g, h);
    assert_true(f == -8 && isnan(g[1]));
    eval3(e, 2, 3, 0, &f, g, h);
    assert_true(f == 8 && g[0] == 12 && fabs(g[1] - 8 * log(2)) < 1e-14);
    /* and at a zero base with a positive exponent: no dependence on the exponent */
    eval3(e, 0, 3, 0, &f, g, h);
    assert_true(f == 0 && g[0] == 0 && g[1] == 0 && h[3] == 0);
    as_expr_free(ctx, e);
    anistar_context_free(ctx);
}

/* ---- syntax ----------------------------------------------------------------------------- */

static void test_grammar(void **state) {
    (void)state;
    static const struct {
        const char *src;
        double x, y, z, value;
    } cases[] = {
        {"-x^2", 3, 0, 0, -9},           {"-2^2", 0, 0, 0, -4},
        {"2^3^2", 0, 0, 0, 512},         {"(2^3)^2", 0, 0, 0, 64},
        {"x^-2", 2, 0, 0, 0.25},         {"2^-x^2", 1, 0, 0, 0.5},
        {"2*-3", 0, 0, 0, -6},           {"--x", 5, 0, 0, 5},
        {"+x", 5, 0, 0, 5},              {"x - -y", 1, 2, 0, 3},
        {"x*-y^2", 2, 3, 0, -18},        {"-x*y", 2, 3, 0, -6},
        {"1 - 2 - 3", 0, 0, 0, -4},      {"2/4/2", 0, 0, 0, 0.25},
        {"1 + 2*3^2", 0, 0, 0, 19},      {"1e3 + .5 + 5. + 1E-2", 0, 0, 0, 1005.51},
        {"2.5e+1 - 2.5E-1", 0, 0, 0, 24.75}, {"\t x \n +\r\n y ", 1, 2, 0, 3},
        {"pi", 0, 0, 0, 3.141592653589793}, {"x;", 7, 0, 0, 7},
        {"a = 2; b = a^2 * 3; x*b", 3, 0, 0, 36},
        {"a=2;b=a^a;c=b*b;c+x", 1, 0, 0, 17}, {"x_1 = 3; x_1*x", 2, 0, 0, 6},
        {"min(x, y, z, -1)", 0, 0, 0, -1},
        {"max(1,2,3,4,5,6,7,8)", 0, 0, 0, 8}, {"pow(2, 10)", 0, 0, 0, 1024},
        {"atan2(1, 1)*4", 0, 0, 0, 3.141592653589793}, {"abs(-3) + abs(x)", -2, 0, 0, 5},
        {"exp(log(x))", 2, 0, 0, 2},     {"((((x))))", 4, 0, 0, 4},
        {"sin ( x ) ^ 2 + cos(x)^2", 0.7, 0, 0, 1},
        {"e = 2; x*e", 3, 0, 0, 6},      {"1e-400 + x", 2, 0, 0, 2},
        {"x^1e300", -2, 0, 0, INFINITY}, {"x^1e300", -0.5, 0, 0, 0},
        {"x^(1/2)", 2.25, 0, 0, 1.5},    {"x^2.0", -3, 0, 0, 9},
        {"2^x", -1, 0, 0, 0.5},          {"x^y^z", 2, 3, 2, 512},
    };
    anistar_context *ctx = new_ctx();
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        as_expr *e = NULL;
        anistar_status st = as_expr_compile(ctx, cases[c].src, &e);
        if (st) fail_msg("%s: %s", cases[c].src, anistar_last_error(ctx));
        double p[3] = {cases[c].x, cases[c].y, cases[c].z};
        double v = as_expr_value(e, p);
        if (isinf(cases[c].value))
            assert_same(v, cases[c].value, cases[c].src);
        else
            assert_close(v, cases[c].value, 1e-15, 0, cases[c].src);
        as_expr_free(ctx, e);
    }
    anistar_context_free(ctx);
}

static void test_params_and_queries(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *e = compile_ok(ctx, TORUS);
    double v = 0;
    assert_int_equal(as_expr_param(e, "R", &v), 0);
    assert_true(v == 10);
    assert_int_equal(as_expr_param(e, "r", &v), 0);
    assert_true(v == 1);
    assert_int_equal(as_expr_param(e, "x", &v), -1);
    assert_int_equal(as_expr_param(e, "R ", &v), -1);
    assert_int_equal(as_expr_param(e, "", &v), -1);
    assert_int_equal((int)as_expr_param_count(e), 2);
    const char *name = NULL;
    assert_int_equal(as_expr_param_at(e, 1, &name, &v), 0);
    assert_string_equal(name, "r");
    assert_int_equal(as_expr_param_at(e, 2, &name, &v), -1);
    assert_int_equal(as_expr_uses_xyz(e), 7);
    as_expr_free(ctx, e);
    e = compile_ok(ctx, "k = 3; c = k*k + pi; x*y + c");
    assert_int_equal(as_expr_param(e, "c", &v), 0);
    assert_true(v == 9 + 3.141592653589793);
    assert_int_equal(as_expr_uses_xyz(e), 3);
    as_expr_free(ctx, e);
    e = compile_ok(ctx, "2*pi + 1");
    assert_int_equal(as_expr_uses_xyz(e), 0);
    assert_int_equal((int)as_expr_param_count(e), 0);
    as_expr_free(ctx, e);
    e = compile_ok(ctx, "0*z");
    assert_int_equal(as_expr_uses_xyz(e), 4);
    as_expr_free(ctx, e);
    /* NULL arguments */
    as_expr *out = (as_expr *)&v;
    assert_int_equal(as_expr_compile(ctx, NULL, &out), ANISTAR_EINVAL);
    assert_null(out);
    assert_int_equal(as_expr_compile(ctx, "x", NULL), ANISTAR_EINVAL);
    as_expr_free(ctx, NULL);
    anistar_context_free(ctx);
}

typedef struct bad_case {
    const char *src;
    int column; /* the 1-based column the message must name */
    const char *text; /* and a fragment it must contain */
} bad_case;

static void expect_error(anistar_context *ctx, const char *src, int column, const char *text) {
    as_expr *e = (as_expr *)ctx; /* must be reset to NULL */
    anistar_status st = as_expr_compile(ctx, src, &e);
    if (st != ANISTAR_EFORMAT)
        fail_msg("\"%.60s\": status %s, expected EFORMAT (%s)", src, anistar_status_name(st),
                 anistar_last_error(ctx));
    assert_null(e);
    assert_int_equal(anistar_last_status(ctx), ANISTAR_EFORMAT);
    const char *msg = anistar_last_error(ctx);
    char col[48];
    snprintf(col, sizeof col, "column %d:", column);
    if (column > 0 && !strstr(msg, col))
        fail_msg("\"%.60s\": message \"%s\" does not name %s", src, msg, col);
    if (!strstr(msg, text)) fail_msg("\"%.60s\": message \"%s\" lacks \"%s\"", src, msg, text);
    if (strncmp(msg, "expression", 10) != 0) fail_msg("\"%.60s\": message \"%s\"", src, msg);
}

static void test_syntax_errors(void **state) {
    (void)state;
    static const bad_case cases[] = {
        {"(x", 3, "expected ')' to close '(' at column 1"},
        {"((x)", 5, "to close '(' at column 1"},
        {"sin(x", 6, "to close '(' at column 4"},
        {"x)", 2, "unmatched ')'"},
        {"(x))", 4, "unmatched ')'"},
        {")", 1, "expected an operand"},
        {"(", 2, "expected an operand after '('"},
        {"foo", 1, "unknown name 'foo'"},
        {"x + foo*2", 5, "unknown name 'foo'"},
        {"X + 1", 1, "unknown name 'X'"},
        {"sinh(x)", 1, "unknown function 'sinh' (known: sqrt exp log sin cos tan tanh abs"},
        {"Sin(x)", 1, "unknown function 'Sin'"},
        {"atan2(y)", 1, "function 'atan2' takes 2 arguments, got 1"},
        {"1 + sin(x, y)", 5, "function 'sin' takes 1 argument, got 2"},
        {"pow(x,y,z)", 1, "function 'pow' takes 2 arguments, got 3"},
        {"min(x)", 1, "function 'min' takes 2 or more arguments, got 1"},
        {"sin()", 1, "function 'sin' takes 1 argument, got 0"},
        {"max()", 1, "got 0"},
        {"x+", 2, "trailing operator '+'"},
        {"x*(y-", 5, "trailing operator '-'"},
        {"x ^ ", 3, "trailing operator '^'"},
        {"-", 1, "trailing operator '-'"},
        {"*x", 1, "operator '*' has no left operand"},
        {"/x", 1, "operator '/' has no left operand"},
        {"^x", 1, "operator '^' has no left operand"},
        {"(*x)", 2, "operator '*' has no left operand"},
        {"x+*y", 3, "expected an operand after '+', got '*'"},
        {"", 1, "empty expression"},
        {"   \t\n ", 1, "empty expression"},
        {";", 1, "empty expression"},
        {"x y", 3, "missing operator between 'x' and 'y'"},
        {"1 2", 3, "missing operator"},
        {"(x)(y)", 4, "missing operator"},
        {"x sin(y)", 3, "missing operator"},
        {"1e", 1, "malformed number '1e'"},
        {"1e+", 1, "malformed number '1e+'"},
        {"1.2.3", 1, "malformed number '1.2.3'"},
        {"x + 3..5", 5, "malformed number '3..5'"},
        {"2x", 1, "malformed number '2x'"},
        {"0x10", 1, "malformed number '0x10'"},
        {"x + .e5", 5, "unexpected character '.'"},
        {"1e999", 1, "number '1e999' is out of range"},
        {"r=x; r", 3, "parameter 'r' cannot use the variable 'x'"},
        {"a=1; r=a*z; r", 10, "cannot use the variable 'z'"},
        {"R=1; R=2; x", 6, "parameter 'R' is already defined at column 1"},
        {"r+1; r=2", 1, "parameter 'r' is used before its definition at column 6"},
        {"a=b+1; b=2; x", 3, "parameter 'b' is used before its definition at column 8"},
        {"x = 1", 1, "'x' is reserved"},
        {"pi = 3; x", 1, "'pi' is reserved"},
        {"sin = 1; x", 1, "'sin' is reserved"},
        {"sin x", 1, "function 'sin' needs its arguments in parentheses"},
        {"sin", 1, "needs its arguments in parentheses"},
        {"()", 2, "empty parentheses"},
        {"x;y", 3, "unexpected text after the formula"},
        {"x; R=1", 4, "unexpected text after the formula"},
        {"x,y", 2, "',' outside of a function's arguments"},
        {"(x,y)", 3, "',' outside"},
        {"R=1", 4, "expected ';' after the definition of parameter 'R'"},
        {"R=1;", 5, "expected the formula after the parameter definitions"},
        {"R=1; ", 6, "expected the formula"},
        {"R=;x", 3, "expected an operand after '='"},
        {"x @ y", 3, "unexpected character '@'"},
        {"x \xc2\xb7 y", 3, "unexpected character (byte 0xc2)"},
        {"a=log(-1); x", 1, "parameter 'a' is not a finite number"},
        {"a=1/0; x", 1, "parameter 'a' is not a finite number"},
        {"R=1; R(x)", 6, "'R' is not a function"},
        {"x(2)", 1, "'x' is not a function"},
        {"x + y = 2", 7, "unexpected '='"},
        {"min(x,)", 7, "expected an operand after ','"},
        {"min(,x)", 5, "expected an operand after '(', got ','"},
        {"R=10; r=1; ;", 12, "expected an operand after ';', got ';'"},
    };
    anistar_context *ctx = new_ctx();
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++)
        expect_error(ctx, cases[c].src, cases[c].column, cases[c].text);
    /* a literal longer than 400 characters */
    char big[600];
    memset(big, '1', 500);
    big[500] = '\0';
    expect_error(ctx, big, 1, "number longer than 400 characters");
    anistar_context_free(ctx);
}

/* ---- huge inputs ---------------------------------------------------------------------- */

#define BIG 1000000

static char *repeat(const char *prefix, const char *unit, size_t n, const char *middle,
                    const char *unit2, size_t n2, const char *suffix) {
    size_t l = strlen(prefix) + strlen(unit) * n + strlen(middle) + strlen(unit2) * n2 +
               strlen(suffix) + 1;
    char *s = malloc(l), *o = s;
    assert_non_null(s);
    o += sprintf(o, "%s", prefix);
    for (size_t i = 0; i < n; i++) o += sprintf(o, "%s", unit);
    o += sprintf(o, "%s", middle);
    for (size_t i = 0; i < n2; i++) o += sprintf(o, "%s", unit2);
    sprintf(o, "%s", suffix);
    return s;
}

static void test_huge_inputs(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    double p[3] = {0.5, 0.25, -0.75}, g[3], h[6];
    /* 10^6 nested parentheses: no recursion, so they compile (to one instruction) */
    char *s = repeat("", "(", BIG, "x", ")", BIG, "");
    as_expr *e = compile_ok(ctx, s);
    assert_int_equal(as_expr_stack_depth(e), 1);
    assert_true(as_expr_value(e, p) == 0.5);
    as_expr_free(ctx, e);
    free(s);
    /* unbalanced both ways */
    s = repeat("", "(", BIG, "x", ")", BIG - 1, "");
    char want[80];
    snprintf(want, sizeof want, "to close '(' at column 1");
    expect_error(ctx, s, 2 * BIG + 1, want);
    free(s);
    s = repeat("", "(", BIG - 1, "x", ")", BIG, "");
    expect_error(ctx, s, 2 * BIG, "unmatched ')'");
    free(s);
    /* 10^6 open parentheses and nothing else */
    s = repeat("", "(", BIG, "", "", 0, "");
    expect_error(ctx, s, BIG + 1, "expected an operand after '('");
    free(s);
    /* 10^6-term flat sum: two stack slots at most */
    s = repeat("x", "+x", BIG - 1, "", "", 0, "");
    e = compile_ok(ctx, s);
    assert_true(as_expr_stack_depth(e) <= 2);
    assert_true(as_expr_value_grad_hess(e, p, g, h) == 0.5 * BIG);
    assert_true(g[0] == BIG && g[1] == 0 && h[0] == 0);
    as_expr_free(ctx, e);
    free(s);
    /* a long sum with a trailing operator */
    s = repeat("x", "+x", BIG - 1, "+", "", 0, "");
    expect_error(ctx, s, 2 * BIG, "trailing operator '+'");
    free(s);
    /* right-nested: x+(x+(x+...)): fused, one slot */
    s = repeat("", "x+(", BIG, "x", ")", BIG, "");
    e = compile_ok(ctx, s);
    assert_true(as_expr_stack_depth(e) <= 2);
    assert_true(as_expr_value(e, p) == 0.5 * (BIG + 1));
    as_expr_free(ctx, e);
    free(s);
    /* right-nested opaque operands: reordered (Sethi-Ullman), two slots, linear time */
    s = repeat("", "sin(y)-(", BIG / 10, "y", ")", BIG / 10, "");
    e = compile_ok(ctx, s);
    assert_true(as_expr_stack_depth(e) <= 2);
    /* sin(y) - (sin(y) - (... - y)): the sin(y) terms cancel in pairs; 10^5 is even */
    assert_close(as_expr_value(e, p), 0.25, 1e-9, 0, "alternating sum");
    as_expr_free(ctx, e);
    free(s);
    /* 10^6 unary minus signs */
    s = repeat("", "-", BIG, "x", "", 0, "");
    e = compile_ok(ctx, s);
    assert_true(as_expr_value(e, p) == 0.5);
    as_expr_free(ctx, e);
    free(s);
    /* min(x, min(x, ...)) cannot be reordered: each level needs one more slot; 127
     * levels need 128 (the limit) and evaluate; 128 levels are refused */
    s = repeat("", "min(z,", AS_EXPR_MAX_STACK - 1, "x", ")", AS_EXPR_MAX_STACK - 1, "");
    e = compile_ok(ctx, s);
    assert_int_equal(as_expr_stack_depth(e), AS_EXPR_MAX_STACK);
    assert_true(as_expr_value_grad_hess(e, p, g, h) == -0.75 && g[2] == 1);
    as_expr_free(ctx, e);
    free(s);
    s = repeat("", "min(z,", AS_EXPR_MAX_STACK, "x", ")", AS_EXPR_MAX_STACK, "");
    expect_error(ctx, s, 0, "nested too deeply");
    free(s);
    s = repeat("", "pow(x,", BIG, "x", ")", BIG, "");
    expect_error(ctx, s, 0, "nested too deeply");
    free(s);
    anistar_context_free(ctx);
}

/* ---- allocation failures ---------------------------------------------------------------- */

static void test_alloc_failures(void **state) {
    (void)state;
    static const char *srcs[] = {TORUS, CHAIR, MIX, "x+", "a=1; b=2; c=3; d=a+b+c; sin(d*x)"};
    for (size_t i = 0; i < sizeof srcs / sizeof srcs[0]; i++) {
        int succeeded = 0;
        for (long k = 0; k < 10000 && !succeeded; k++) {
            tu_alloc a;
            tu_alloc_init(&a, -1);
            anistar_allocator al = tu_allocator(&a);
            anistar_context *ctx = anistar_context_new(&al);
            assert_non_null(ctx);
            long base_blocks = a.live_blocks;
            a.fail_after = a.count + k;
            as_expr *e = (as_expr *)&a;
            anistar_status st = as_expr_compile(ctx, srcs[i], &e);
            if (st == ANISTAR_OK) {
                succeeded = 1;
                assert_true(a.failures == 0);
                double p[3] = {1, 2, 3};
                (void)as_expr_value(e, p);
                as_expr_free(ctx, e);
            } else {
                assert_null(e);
                if (a.failures > 0)
                    assert_int_equal(st, ANISTAR_ENOMEM);
                else
                    assert_int_equal(st, ANISTAR_EFORMAT); /* "x+" fails on its own */
                if (st == ANISTAR_EFORMAT && a.failures == 0) succeeded = 1;
            }
            assert_int_equal(a.live_blocks, base_blocks);
            anistar_context_free(ctx);
            assert_int_equal(a.live_blocks, 0);
            assert_int_equal(a.live_bytes, 0);
        }
        assert_true(succeeded);
    }
}

/* ---- concurrency ---------------------------------------------------------------------- */

#define NTHREAD_PTS 20000

typedef struct job {
    const as_expr *e;
    const double *pts;
    double *out; /* 10 per point: f, g, h */
} job;

static void *worker(void *arg) {
    job *j = arg;
    for (int i = 0; i < NTHREAD_PTS; i++) {
        double *o = j->out + 10 * i;
        o[0] = as_expr_value_grad_hess(j->e, j->pts + 3 * i, o + 1, o + 4);
        double g[3];
        if (!same(as_expr_value(j->e, j->pts + 3 * i), o[0]) ||
            !same(as_expr_value_grad(j->e, j->pts + 3 * i, g), o[0]))
            o[0] = -12345.0; /* flagged: the main thread compares */
    }
    return NULL;
}

static void test_threads(void **state) {
    (void)state;
    anistar_context *ctx = new_ctx();
    as_expr *e = compile_ok(ctx, CHAIR " + atan2(y, x)*min(x, z)");
    double *pts = malloc(sizeof(double) * 3 * NTHREAD_PTS);
    double *seq = malloc(sizeof(double) * 10 * NTHREAD_PTS);
    double *par[2] = {malloc(sizeof(double) * 10 * NTHREAD_PTS),
                      malloc(sizeof(double) * 10 * NTHREAD_PTS)};
    assert_true(pts && seq && par[0] && par[1]);
    tu_rng r = {9};
    for (int i = 0; i < 3 * NTHREAD_PTS; i++) pts[i] = tu_rng_range(&r, -1.5, 1.5);
    job sj = {e, pts, seq};
    worker(&sj);
    pthread_t th[2];
    job jobs[2] = {{e, pts, par[0]}, {e, pts, par[1]}};
    for (int t = 0; t < 2; t++) assert_int_equal(pthread_create(&th[t], NULL, worker, &jobs[t]), 0);
    for (int t = 0; t < 2; t++) assert_int_equal(pthread_join(th[t], NULL), 0);
    for (int t = 0; t < 2; t++)
        for (int i = 0; i < 10 * NTHREAD_PTS; i++) assert_same(par[t][i], seq[i], "thread result");
    for (int i = 0; i < NTHREAD_PTS; i++) assert_true(seq[10 * i] != -12345.0);
    free(pts);
    free(seq);
    free(par[0]);
    free(par[1]);
    as_expr_free(ctx, e);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_values_match_c),
        cmocka_unit_test(test_integer_powers_vs_pow),
        cmocka_unit_test(test_surfaces_hand_derivatives),
        cmocka_unit_test(test_unary_functions),
        cmocka_unit_test(test_constant_powers),
        cmocka_unit_test(test_binary_operators),
        cmocka_unit_test(test_mix_every_function),
        cmocka_unit_test(test_fused_shapes),
        cmocka_unit_test(test_atan2_quadrants),
        cmocka_unit_test(test_ties_and_kinks),
        cmocka_unit_test(test_nan_semantics),
        cmocka_unit_test(test_grammar),
        cmocka_unit_test(test_params_and_queries),
        cmocka_unit_test(test_syntax_errors),
        cmocka_unit_test(test_huge_inputs),
        cmocka_unit_test(test_alloc_failures),
        cmocka_unit_test(test_threads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
