/*
 * test_surface.c — the surface oracle (lib/surface/surface.c, implicit.c): curvatures
 * against closed forms, crossings, projections, sampling of every component (thin and small
 * ones included: plates, tubes, long tori, tiny spheres, a thin shell, a hidden cavity),
 * the sample's areas and area weights, errors (NaN, no surface, leaks, bad specs),
 * finite-difference callbacks, allocation failures, concurrent queries.
 */
#include "test_util.h"

#include "pool.h"
#include "surface/surface.h"

#include <float.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

static const double PI = 3.14159265358979323846;

static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }
static double dist3(const double a[3], const double b[3]) {
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return norm3(d);
}
static void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static double relerr(double got, double want) {
    return fabs(got - want) / fmax(fabs(want), 1e-300);
}
/* A random unit vector. */
static void rand_unit(tu_rng *r, double u[3]) {
    double n;
    do {
        for (int i = 0; i < 3; i++) u[i] = tu_rng_range(r, -1, 1);
        n = norm3(u);
    } while (n > 1 || n < 0.1);
    for (int i = 0; i < 3; i++) u[i] /= n;
}

static as_surface *builtin(anistar_context *ctx, const char *spec) {
    as_surface *s = NULL;
    anistar_status st = as_implicit_builtin(ctx, spec, &s);
    if (st) fail_msg("builtin '%s': %s", spec, anistar_last_error(ctx));
    return s;
}
static as_surface *expression(anistar_context *ctx, const char *src, double r) {
    const double c[3] = {0, 0, 0};
    as_surface *s = NULL;
    anistar_status st = as_implicit_from_expression(ctx, src, c, r, &s);
    if (st) fail_msg("expression '%s': %s", src, anistar_last_error(ctx));
    return s;
}

/* The frame is orthonormal and right-handed: (d1, d2, n). */
static void check_frame(const as_surface_frame *fr) {
    const double *d1 = fr->d, *d2 = fr->d + 3;
    assert_true(fabs(norm3(d1) - 1) < 1e-14);
    assert_true(fabs(norm3(d2) - 1) < 1e-14);
    assert_true(fabs(norm3(fr->n) - 1) < 1e-14);
    assert_true(fabs(dot3(d1, d2)) < 1e-14);
    assert_true(fabs(dot3(d1, fr->n)) < 1e-14);
    double c[3];
    cross3(d1, d2, c);
    assert_true(dist3(c, fr->n) < 1e-14);
    assert_true(fr->k[0] >= fr->k[1]);
}

/* ---- curvature against closed forms -------------------------------------------------- */

static void test_sphere_curvature(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere,r=2");
    tu_rng rng = {1};
    for (int t = 0; t < 500; t++) {
        double u[3], p[3];
        rand_unit(&rng, u);
        for (int i = 0; i < 3; i++) p[i] = 2 * u[i];
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, s, p, &fr), ANISTAR_OK);
        assert_false(fr.singular);
        check_frame(&fr);
        assert_true(relerr(fr.k[0], 0.5) < 1e-10);
        assert_true(relerr(fr.k[1], 0.5) < 1e-10);
        assert_true(dist3(fr.n, u) < 1e-14); /* outward */
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* Torus (R, r): point at angles (theta around z, phi around the tube). */
static void torus_point(double R, double r, double th, double ph, double p[3]) {
    p[0] = (R + r * cos(ph)) * cos(th);
    p[1] = (R + r * cos(ph)) * sin(th);
    p[2] = r * sin(ph);
}

static void check_torus(anistar_context *ctx, const char *spec, double R, double r) {
    as_surface *s = builtin(ctx, spec);
    tu_rng rng = {2};
    for (int t = 0; t < 600; t++) {
        double th = tu_rng_range(&rng, 0, 2 * PI), ph = tu_rng_range(&rng, 0, 2 * PI);
        if (t == 0) ph = 0;       /* outer equator */
        if (t == 1) ph = PI;      /* inner equator */
        if (t == 2) ph = PI / 2;  /* top circle: parabolic */
        double p[3];
        torus_point(R, r, th, ph, p);
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, s, p, &fr), ANISTAR_OK);
        check_frame(&fr);
        double kmer = 1 / r, kpar = cos(ph) / (R + r * cos(ph));
        assert_true(relerr(fr.k[0], kmer) < 1e-10);
        if (fabs(kpar) > 1e-12) assert_true(relerr(fr.k[1], kpar) < 1e-10);
        else assert_true(fabs(fr.k[1]) < 1e-12);
        double meridian[3] = {-sin(ph) * cos(th), -sin(ph) * sin(th), cos(ph)};
        double parallel[3] = {-sin(th), cos(th), 0};
        double normal[3] = {cos(ph) * cos(th), cos(ph) * sin(th), sin(ph)};
        assert_true(fabs(fabs(dot3(fr.d, meridian)) - 1) < 1e-10);
        assert_true(fabs(fabs(dot3(fr.d + 3, parallel)) - 1) < 1e-10);
        assert_true(dist3(fr.n, normal) < 1e-12);
    }
    /* the brief's named points: outer equator (R+r,0,0) and inner equator (R-r,0,0) */
    double po[3] = {R + r, 0, 0}, pi[3] = {R - r, 0, 0};
    as_surface_frame fr;
    assert_int_equal(as_surface_frame_at(ctx, s, po, &fr), ANISTAR_OK);
    assert_true(relerr(fr.k[0], 1 / r) < 1e-10 && relerr(fr.k[1], 1 / (R + r)) < 1e-10);
    assert_int_equal(as_surface_frame_at(ctx, s, pi, &fr), ANISTAR_OK);
    assert_true(relerr(fr.k[0], 1 / r) < 1e-10 && relerr(fr.k[1], -1 / (R - r)) < 1e-10);
    as_surface_free(s);
}

static void test_torus_curvature(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    check_torus(ctx, "torus", 10, 1);
    check_torus(ctx, "torus,R=5,r=2", 5, 2);
    anistar_context_free(ctx);
}

/*
 * Ellipsoid x^2/a^2 + y^2/b^2 + z^2/c^2 = 1 parametrised X(u, v) = (a cos u cos v,
 * b sin u cos v, c sin v): principal curvatures from the first and second fundamental
 * forms (outward normal; our sign convention: positive for convex, so k = -k_II).
 */
static void ellipsoid_closed_form(double a, double b, double c, double u, double v,
                                  double p[3], double k[2], double Xu[3], double Xv[3],
                                  double I[3], double II[3]) {
    p[0] = a * cos(u) * cos(v);
    p[1] = b * sin(u) * cos(v);
    p[2] = c * sin(v);
    double xu[3] = {-a * sin(u) * cos(v), b * cos(u) * cos(v), 0};
    double xv[3] = {-a * cos(u) * sin(v), -b * sin(u) * sin(v), c * cos(v)};
    double xuu[3] = {-a * cos(u) * cos(v), -b * sin(u) * cos(v), 0};
    double xuv[3] = {a * sin(u) * sin(v), -b * cos(u) * sin(v), 0};
    double xvv[3] = {-a * cos(u) * cos(v), -b * sin(u) * cos(v), -c * sin(v)};
    double n[3];
    cross3(xu, xv, n);
    double nn = norm3(n);
    for (int i = 0; i < 3; i++) n[i] /= nn;
    if (dot3(n, p) < 0)
        for (int i = 0; i < 3; i++) n[i] = -n[i];
    double E = dot3(xu, xu), F = dot3(xu, xv), G = dot3(xv, xv);
    double L = -dot3(xuu, n), M = -dot3(xuv, n), N = -dot3(xvv, n); /* sign: convex > 0 */
    double K = (L * N - M * M) / (E * G - F * F);
    double H = (E * N + G * L - 2 * F * M) / (2 * (E * G - F * F));
    double d = sqrt(fmax(0, H * H - K));
    k[0] = H + d;
    k[1] = K / k[0]; /* product form: accurate for the smaller one */
    memcpy(Xu, xu, sizeof xu);
    memcpy(Xv, xv, sizeof xv);
    I[0] = E;
    I[1] = F;
    I[2] = G;
    II[0] = L;
    II[1] = M;
    II[2] = N;
}

static void test_ellipsoid_curvature(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double a = 3, b = 2, c = 1;
    as_surface *s = builtin(ctx, "ellipsoid,a=3,b=2,c=1");
    /* axis points */
    struct {
        double p[3], k0, k1;
    } axes[] = {{{a, 0, 0}, a / (c * c), a / (b * b)}, {{0, -b, 0}, b / (c * c), b / (a * a)},
                {{0, 0, c}, c / (b * b), c / (a * a)}};
    for (int t = 0; t < 3; t++) {
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, s, axes[t].p, &fr), ANISTAR_OK);
        check_frame(&fr);
        assert_true(relerr(fr.k[0], axes[t].k0) < 1e-10);
        assert_true(relerr(fr.k[1], axes[t].k1) < 1e-10);
    }
    /* generic points */
    tu_rng rng = {3};
    for (int t = 0; t < 500; t++) {
        double u = tu_rng_range(&rng, 0, 2 * PI), v = tu_rng_range(&rng, -1.4, 1.4);
        double p[3], k[2], Xu[3], Xv[3], I[3], II[3];
        ellipsoid_closed_form(a, b, c, u, v, p, k, Xu, Xv, I, II);
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, s, p, &fr), ANISTAR_OK);
        check_frame(&fr);
        assert_true(relerr(fr.k[0], k[0]) < 1e-10);
        assert_true(relerr(fr.k[1], k[1]) < 1e-10);
        if (k[0] - k[1] < 1e-3 * k[0]) continue; /* near an umbilic: directions arbitrary */
        /* d1 = alpha Xu + beta Xv satisfies (II - k I)(alpha, beta) = 0 */
        for (int j = 0; j < 2; j++) {
            const double *d = fr.d + 3 * j;
            double du = dot3(d, Xu), dv = dot3(d, Xv);
            double det = I[0] * I[2] - I[1] * I[1];
            double al = (I[2] * du - I[1] * dv) / det, be = (I[0] * dv - I[1] * du) / det;
            double r1 = (II[0] - k[j] * I[0]) * al + (II[1] - k[j] * I[1]) * be;
            double r2 = (II[1] - k[j] * I[1]) * al + (II[2] - k[j] * I[2]) * be;
            double scale = fabs(k[0]) * (fabs(I[0]) + fabs(I[2])) * (fabs(al) + fabs(be));
            assert_true(fabs(r1) < 1e-9 * scale && fabs(r2) < 1e-9 * scale);
        }
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- projection ---------------------------------------------------------------------- */

static void test_projection(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng rng = {4};
    /* sphere of radius 2: q = 2 p/|p| */
    as_surface *s = builtin(ctx, "sphere,r=2");
    for (int t = 0; t < 300; t++) {
        double u[3], p[3], q[3], w[3];
        rand_unit(&rng, u);
        double rad = tu_rng_range(&rng, 0.2, 4.0);
        for (int i = 0; i < 3; i++) {
            p[i] = rad * u[i];
            w[i] = 2 * u[i];
        }
        assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
        assert_true(dist3(q, w) <= 1e-12 * s->radius);
    }
    as_surface_free(s);
    /* torus (10, 1): q on the circle of the tube around the nearest core point */
    s = builtin(ctx, "torus");
    for (int t = 0; t < 300; t++) {
        double th = tu_rng_range(&rng, 0, 2 * PI), ph = tu_rng_range(&rng, 0, 2 * PI);
        double d = tu_rng_range(&rng, 0.05, 2.5); /* distance of p from the core circle */
        double core[3] = {10 * cos(th), 10 * sin(th), 0};
        double dir[3] = {cos(ph) * cos(th), cos(ph) * sin(th), sin(ph)};
        double p[3], w[3], q[3];
        for (int i = 0; i < 3; i++) {
            p[i] = core[i] + d * dir[i];
            w[i] = core[i] + dir[i];
        }
        assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
        assert_true(dist3(q, w) <= 1e-12 * s->radius);
    }
    as_surface_free(s);
    /* ellipsoid: the closest-point condition (p - q parallel to the normal at q) for
     * points outside (where the closest point is unique: a convex body); inside points
     * near the medial disk z = 0 have two closest points (documented limitation) */
    s = builtin(ctx, "ellipsoid,a=3,b=2,c=1");
    for (int t = 0; t < 200; t++) {
        double u[3], p[3], q[3], g[3], f;
        rand_unit(&rng, u);
        double rad = tu_rng_range(&rng, 1.0, 1.4);
        p[0] = 3 * rad * u[0];
        p[1] = 2 * rad * u[1];
        p[2] = 1 * rad * u[2];
        assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
        assert_int_equal(as_surface_eval(ctx, s, q, 1, &f, g, NULL), ANISTAR_OK);
        double gn = norm3(g);
        assert_true(fabs(f) / gn <= 1e-12 * s->radius);
        double v[3] = {p[0] - q[0], p[1] - q[1], p[2] - q[2]}, vn = dot3(v, g) / gn;
        double vt[3] = {v[0] - vn * g[0] / gn, v[1] - vn * g[1] / gn, v[2] - vn * g[2] / gn};
        assert_true(norm3(vt) <= 1e-10 * s->radius);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- crossings ----------------------------------------------------------------------- */

static void test_crossing_once(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere,r=2"); /* bound 2.5 */
    tu_rng rng = {5};
    for (int t = 0; t < 300; t++) {
        /* a inside, b outside (possibly beyond the bounding sphere) */
        double u[3], w[3], a[3], b[3], x[3];
        rand_unit(&rng, u);
        rand_unit(&rng, w);
        double ra = tu_rng_range(&rng, 0, 1.9), rb = tu_rng_range(&rng, 2.1, 6);
        for (int i = 0; i < 3; i++) {
            a[i] = ra * u[i];
            b[i] = rb * w[i];
        }
        int found;
        assert_int_equal(as_surface_crossing(ctx, s, a, b, a, &found, x), ANISTAR_OK);
        assert_true(found);
        /* exact: |a + t (b - a)| = 2, t in (0, 1) */
        double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double A = dot3(d, d), B = dot3(a, d), C = dot3(a, a) - 4;
        double tt = (-B + sqrt(B * B - A * C)) / A;
        double e[3] = {a[0] + tt * d[0], a[1] + tt * d[1], a[2] + tt * d[2]};
        assert_true(dist3(x, e) <= 2e-12 * s->radius);
        /* side agrees with the ends */
        int sa, sb;
        assert_int_equal(as_surface_side(ctx, s, a, &sa), ANISTAR_OK);
        assert_int_equal(as_surface_side(ctx, s, b, &sb), ANISTAR_OK);
        assert_int_equal(sa, -1);
        assert_int_equal(sb, 1);
    }
    /* a segment entirely outside (misses the sphere) */
    double a[3] = {-3, 2.2, 0}, b[3] = {3, 2.2, 0}, x[3];
    int found = 1;
    assert_int_equal(as_surface_crossing(ctx, s, a, b, a, &found, x), ANISTAR_OK);
    assert_false(found);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_crossing_three(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    /* torus (10, 1) along the x axis from -10.5 (inside the tube) to 11.5 (outside):
     * crossings at x = -9, 9, 11 */
    as_surface *s = builtin(ctx, "torus");
    double a[3] = {-10.5, 0, 0}, b[3] = {11.5, 0, 0};
    struct {
        double ref[3], want;
    } cases[] = {{{-9.4, 0.3, 0}, -9},  {{-20, 0, 0}, -9}, {{0, 0, 0}, -9}, {{0.1, 0, 0}, 9},
                 {{8.2, -0.5, 1}, 9}, {{10.2, 0, 0}, 11}, {{30, 0, 0}, 11}};
    for (size_t t = 0; t < sizeof cases / sizeof cases[0]; t++) {
        double x[3];
        int found;
        assert_int_equal(as_surface_crossing(ctx, s, a, b, cases[t].ref, &found, x),
                         ANISTAR_OK);
        assert_true(found);
        double w[3] = {cases[t].want, 0, 0};
        if (cases[t].ref[0] == 0) { /* equidistant from -9 and 9: either is nearest */
            assert_true(dist3(x, w) <= 2e-12 * s->radius ||
                        fabs(x[0] - 9) <= 2e-12 * s->radius);
            continue;
        }
        assert_true(dist3(x, w) <= 2e-12 * s->radius);
    }
    as_surface_free(s);
    /* two crossings closer together than the base sampling (one piece): a sphere of
     * radius 0.05 in a bounding sphere of radius 5 (spacing 5/32) */
    s = expression(ctx, "x^2+y^2+z^2-0.0025", 5);
    double c[3] = {-1, 0.01, 0}, d[3] = {1, 0.01, 0}, x[3];
    double xr = sqrt(0.0025 - 0.0001);
    int found;
    double ref1[3] = {0.3, 0, 0}, ref2[3] = {-0.2, 0.1, 0};
    assert_int_equal(as_surface_crossing(ctx, s, c, d, ref1, &found, x), ANISTAR_OK);
    assert_true(found && fabs(x[0] - xr) <= 2e-12 * 5);
    assert_int_equal(as_surface_crossing(ctx, s, c, d, ref2, &found, x), ANISTAR_OK);
    assert_true(found && fabs(x[0] + xr) <= 2e-12 * 5);
    as_surface_free(s);
    /* a thin shell 0.04 < |p| < 0.1 (inside) in a bounding sphere of radius 5: the segment
     * from x = -0.07 to 0.2 crosses at -0.04, 0.04, 0.1, the first two within one base
     * piece where f has the same sign at both ends */
    s = expression(ctx, "(x^2+y^2+z^2-0.01)*(x^2+y^2+z^2-0.0016)", 5);
    double e0[3] = {-0.07, 0, 0}, e1[3] = {0.2, 0, 0};
    struct {
        double ref[3], want;
    } sh[] = {{{-0.045, 0.01, 0}, -0.04}, {{0.03, -0.01, 0}, 0.04}, {{0.15, 0, 0}, 0.1},
              {{-1, 0, 0}, -0.04}};
    for (size_t t = 0; t < sizeof sh / sizeof sh[0]; t++) {
        assert_int_equal(as_surface_crossing(ctx, s, e0, e1, sh[t].ref, &found, x), ANISTAR_OK);
        assert_true(found && fabs(x[0] - sh[t].want) <= 2e-12 * 5 && x[1] == 0 && x[2] == 0);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The crossing found does not depend on how far the segment reaches along its line (the
 * base pieces lie on a lattice of the line): a corrugated sheet z = 0.003 sin(150 x)
 * crossed by the line z = 0.00295 near its crests, where pairs of crossings lie 0.0024
 * apart and a wavelength (0.042) is shorter than a base piece (2/32), seen from 300
 * segments of that line with random ends 1 to 1.5 away from the middle (and both
 * orientations): the crossing nearest the reference is the same one every time (to the
 * root finder's tolerance; a crossing of the sheet, not always the nearest: see
 * as_surface_crossing's limits). A mesher's dual segment and an
 * independent check's copy of it differ so in extent. (With pieces cut from the
 * segment's ends, 197 of the 300 found another crossing for the first reference.) */
static void test_crossing_extent(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = expression(ctx, "z-0.003*sin(150*x)", 2);
    tu_rng r = {5};
    const double zl = 0.00295, yl = 0.1;
    for (int t = 0; t < 5; t++) {
        double ref[3] = {tu_rng_range(&r, -0.5, 0.5), yl, zl}, first[3] = {0, 0, 0};
        int first_found = -1, differ = 0;
        for (int k = 0; k < 300; k++) {
            double x0 = -tu_rng_range(&r, 1, 1.5), x1 = tu_rng_range(&r, 1, 1.5);
            double a[3] = {x0, yl, zl}, b[3] = {x1, yl, zl}, x[3];
            if (k & 1) { /* the other orientation */
                a[0] = x1;
                b[0] = x0;
            }
            int found;
            assert_int_equal(as_surface_crossing(ctx, s, a, b, ref, &found, x), ANISTAR_OK);
            if (first_found < 0) {
                first_found = found;
                memcpy(first, x, sizeof first);
            } else if (found != first_found || (found && dist3(x, first) > 1e-10)) {
                differ++;
            }
        }
        /* the true nearest: 150 x = asin(zl / 0.003) or pi - asin(zl / 0.003), mod 2 pi */
        double as = asin(zl / 0.003), best = INFINITY, want = 0;
        for (int k = -40; k <= 40; k++)
            for (int h = 0; h < 2; h++) {
                double xr = ((h ? PI - as : as) + 2 * PI * k) / 150;
                if (fabs(xr - ref[0]) < best) best = fabs(xr - ref[0]), want = xr;
            }
        print_message("reference x = %.3f: crossing at x = %.6f (nearest %.6f), %d of 300 "
                      "segments differ\n", ref[0], first[0], want, differ);
        assert_int_equal(first_found, 1);
        assert_int_equal(differ, 0);
        /* a true crossing (not always the nearest: a pair within one piece whose valley
         * the Hermite test does not see is missed, by every segment alike) */
        double nearest_root = INFINITY;
        for (int k = -40; k <= 40; k++)
            for (int h = 0; h < 2; h++)
                nearest_root = fmin(nearest_root, fabs(first[0] - ((h ? PI - as : as) + 2 * PI * k) / 150));
        assert_true(nearest_root < 1e-9);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_crossing_tangent(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere"); /* r 1, bound 1.25 */
    double x[3];
    int found;
    /* touching at (0, 0, 1): reported at the touching point (double root: position to
     * about sqrt(tol)) */
    double a[3] = {-1, 0, 1}, b[3] = {1, 0, 1}, ref[3] = {0.3, 0, 1.5}, top[3] = {0, 0, 1};
    assert_int_equal(as_surface_crossing(ctx, s, a, b, ref, &found, x), ANISTAR_OK);
    assert_true(found);
    assert_true(dist3(x, top) < 1e-6);
    /* passing 1e-3 above: no crossing */
    double a2[3] = {-1, 0, 1.001}, b2[3] = {1, 0, 1.001};
    assert_int_equal(as_surface_crossing(ctx, s, a2, b2, ref, &found, x), ANISTAR_OK);
    assert_false(found);
    /* passing 1e-4 below: two crossings at x = +-sqrt(1 - 0.9999^2); nearest to ref */
    double a3[3] = {-1, 0, 0.9999}, b3[3] = {1, 0, 0.9999};
    double xr = sqrt(1 - 0.9999 * 0.9999);
    assert_int_equal(as_surface_crossing(ctx, s, a3, b3, ref, &found, x), ANISTAR_OK);
    assert_true(found && fabs(x[0] - xr) < 1e-11);
    double refm[3] = {-0.5, 0, 0};
    assert_int_equal(as_surface_crossing(ctx, s, a3, b3, refm, &found, x), ANISTAR_OK);
    assert_true(found && fabs(x[0] + xr) < 1e-11);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_side(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "sphere"); /* bound 1.25 */
    int side;
    double in[3] = {0.2, 0.1, 0}, out[3] = {1.1, 0, 0}, on[3] = {0, 1, 0}, far[3] = {5, 0, 0};
    assert_int_equal(as_surface_side(ctx, s, in, &side), ANISTAR_OK);
    assert_int_equal(side, -1);
    assert_int_equal(as_surface_side(ctx, s, out, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    assert_int_equal(as_surface_side(ctx, s, on, &side), ANISTAR_OK);
    assert_int_equal(side, 0);
    assert_int_equal(as_surface_side(ctx, s, far, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    as_surface_free(s);
    /* beyond the bounding sphere counts as outside even where f < 0 */
    s = expression(ctx, "x^2+y^2+z^2-100", 2);
    double p[3] = {2.5, 0, 0};
    assert_int_equal(as_surface_side(ctx, s, p, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- errors ---------------------------------------------------------------------------- */

static void test_nan_is_error(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = expression(ctx, "sqrt(x) + y^2 + z^2 - 1", 3);
    double p[3] = {-0.5, 0.25, 0}, q[3], x[3];
    int side = 7, found;
    assert_int_equal(as_surface_side(ctx, s, p, &side), ANISTAR_EINVAL);
    assert_int_equal(side, 7);
    assert_non_null(strstr(anistar_last_error(ctx), "(-0.5, 0.25, 0)"));
    double a[3] = {-1, 0, 0}, b[3] = {1, 0, 0};
    assert_int_equal(as_surface_crossing(ctx, s, a, b, a, &found, x), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "not finite"));
    assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_EINVAL);
    as_point_sample smp;
    assert_int_equal(as_surface_sample(ctx, s, 16, &smp), ANISTAR_EINVAL);
    assert_null(smp.points);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_no_surface(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_point_sample smp;
    /* no zero inside the bounding sphere */
    as_surface *s = expression(ctx, "x^2+y^2+z^2+1", 2);
    assert_int_equal(as_surface_sample(ctx, s, 16, &smp), ANISTAR_ENOSURFACE);
    assert_non_null(strstr(anistar_last_error(ctx), "no surface"));
    double p[3] = {0.5, 0, 0}, q[3];
    assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_ENOSURFACE);
    as_surface_free(s);
    /* S not inside its bounding sphere */
    s = expression(ctx, "x^2+y^2+z^2-9", 2);
    assert_int_equal(as_surface_sample(ctx, s, 16, &smp), ANISTAR_ENOSURFACE);
    assert_non_null(strstr(anistar_last_error(ctx), "surface: f < 0 at"));
    assert_non_null(strstr(anistar_last_error(ctx), "bounding sphere"));
    as_surface_free(s);
    /* bad bounding spheres and expressions */
    const double c[3] = {0, 0, 0}, cn[3] = {0, NAN, 0};
    assert_int_equal(as_implicit_from_expression(ctx, "x", c, 0, &s), ANISTAR_EINVAL);
    assert_null(s);
    assert_int_equal(as_implicit_from_expression(ctx, "x", c, INFINITY, &s), ANISTAR_EINVAL);
    assert_int_equal(as_implicit_from_expression(ctx, "x", cn, 1, &s), ANISTAR_EINVAL);
    assert_int_equal(as_implicit_from_expression(ctx, "x^2+*y", c, 1, &s), ANISTAR_EFORMAT);
    assert_null(s);
    anistar_context_free(ctx);
}

static void test_builtin_specs(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    struct {
        const char *spec, *msg;
    } bad[] = {{"torux", "unknown builtin"},        {"torus,q=1", "no parameter 'q'"},
               {"torus,R=abc", "not a finite"},     {"torus,R=1e999", "not a finite"},
               {"torus,R", "NAME=VALUE"},           {"torus,R=5,R=6", "twice"},
               {"torus,R=1,r=2", "R > r"},          {"sphere,r=-1", "r must be > 0"},
               {"sphere,bound=0", "bound must be"}, {"double_torus,r=0.3", "genus 2"},
               {"", "unknown builtin"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        as_surface *s = (as_surface *)1;
        assert_int_equal(as_implicit_builtin(ctx, bad[i].spec, &s), ANISTAR_EINVAL);
        assert_null(s);
        if (!strstr(anistar_last_error(ctx), bad[i].msg))
            fail_msg("'%s': message '%s' lacks '%s'", bad[i].spec, anistar_last_error(ctx),
                     bad[i].msg);
    }
    /* parameters and bound are applied */
    as_surface *s = builtin(ctx, "torus,R=5,r=2,bound=9");
    assert_true(s->radius == 9);
    double p[3] = {7, 0, 0}, f;
    assert_int_equal(as_surface_eval(ctx, s, p, 0, &f, NULL, NULL), ANISTAR_OK);
    assert_true(fabs(f) < 1e-14);
    as_surface_free(s);
    /* the list */
    const char *name, *desc;
    size_t n = 0;
    while (as_implicit_builtin_info(n, &name, &desc) == 0) {
        assert_true(strlen(name) > 0 && strlen(desc) > 10);
        n++;
    }
    assert_int_equal(n, 6);
    anistar_context_free(ctx);
}

/* ---- sampling: every component, genus ---------------------------------------------- */

/* Euler characteristic of the cubical complex of the inside grid vertices (n^3 cubes over
 * the bounding cube): 1 - genus for a solid handlebody. */
static long inside_euler(const as_surface *s, int n) {
    int nv = n + 1;
    double h = 2 * s->radius / n;
    unsigned char *in = test_calloc((size_t)nv * nv * nv, 1);
    for (int k = 0; k < nv; k++)
        for (int j = 0; j < nv; j++)
            for (int i = 0; i < nv; i++) {
                double p[3] = {s->center[0] - s->radius + h * i, s->center[1] - s->radius + h * j,
                               s->center[2] - s->radius + h * k};
                double d[3] = {p[0] - s->center[0], p[1] - s->center[1], p[2] - s->center[2]};
                in[i + nv * (j + nv * k)] =
                    dot3(d, d) <= s->radius * s->radius && s->ops->eval(s, p, 0, NULL, NULL) < 0;
            }
#define IN(i, j, k) ((i) < nv && (j) < nv && (k) < nv && in[(i) + nv * ((j) + nv * (k))])
    long V = 0, E = 0, F = 0, C = 0;
    for (int k = 0; k < nv; k++)
        for (int j = 0; j < nv; j++)
            for (int i = 0; i < nv; i++) {
                if (!IN(i, j, k)) continue;
                V++;
                E += IN(i + 1, j, k) + IN(i, j + 1, k) + IN(i, j, k + 1);
                F += (IN(i + 1, j, k) && IN(i, j + 1, k) && IN(i + 1, j + 1, k)) +
                     (IN(i + 1, j, k) && IN(i, j, k + 1) && IN(i + 1, j, k + 1)) +
                     (IN(i, j + 1, k) && IN(i, j, k + 1) && IN(i, j + 1, k + 1));
                C += IN(i + 1, j, k) && IN(i, j + 1, k) && IN(i, j, k + 1) &&
                     IN(i + 1, j + 1, k) && IN(i + 1, j, k + 1) && IN(i, j + 1, k + 1) &&
                     IN(i + 1, j + 1, k + 1);
            }
#undef IN
    test_free(in);
    return V - E + F - C;
}

/* Every sample point lies on S within tol; component ids are in range and all used. */
static void check_sample(anistar_context *ctx, const as_surface *s, const as_point_sample *smp) {
    assert_true(smp->n >= smp->ncomponents && smp->ncomponents > 0);
    int used[64] = {0};
    for (size_t i = 0; i < smp->n; i++) {
        double f, g[3];
        assert_int_equal(as_surface_eval(ctx, s, smp->points + 3 * i, 1, &f, g, NULL), ANISTAR_OK);
        assert_true(fabs(f) <= 1e-12 * s->radius * norm3(g) * 1.0000001);
        assert_true(smp->component[i] >= 0 && (size_t)smp->component[i] < smp->ncomponents);
        if (smp->component[i] < 64) used[smp->component[i]] = 1;
    }
    for (size_t c = 0; c < smp->ncomponents && c < 64; c++) assert_true(used[c]);
}

static void test_builtins_sample(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    struct {
        const char *spec;
        int genus;
    } cases[] = {{"sphere", 0},     {"ellipsoid", 0},  {"torus", 1},
                 {"chair", 3},      {"tanglecube", 5}, {"double_torus", 2}};
    for (size_t t = 0; t < sizeof cases / sizeof cases[0]; t++) {
        as_surface *s = builtin(ctx, cases[t].spec);
        as_point_sample smp;
        assert_int_equal(as_surface_sample(ctx, s, 100, &smp), ANISTAR_OK);
        check_sample(ctx, s, &smp);
        assert_int_equal(smp.ncomponents, 1);
        assert_true(smp.n >= 50 && smp.n <= 101);
        /* the sample is spread: its points are not all in one small region */
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < smp.n; i++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], smp.points[3 * i + k]);
                hi[k] = fmax(hi[k], smp.points[3 * i + k]);
            }
        assert_true(hi[0] - lo[0] > 0.5 * s->radius);
        as_surface_sample_free(ctx, &smp);
        assert_null(smp.points);
        /* genus from the Euler characteristic of the inside region */
        assert_int_equal(inside_euler(s, 64), 1 - cases[t].genus);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* Component id of the sample point nearest c. */
static int32_t nearest_component(const as_point_sample *smp, const double c[3], double *d) {
    size_t best = 0;
    for (size_t i = 1; i < smp->n; i++)
        if (dist3(smp->points + 3 * i, c) < dist3(smp->points + 3 * best, c)) best = i;
    *d = dist3(smp->points + 3 * best, c);
    return smp->component[best];
}

static void test_small_components(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_point_sample smp;
    /* two spheres of radius 0.1 in a bounding sphere of radius 5 */
    as_surface *s = expression(
        ctx, "min((x-3)^2+y^2+z^2-0.01, (x+3)^2+y^2+z^2-0.01)", 5);
    assert_int_equal(as_surface_sample(ctx, s, 40, &smp), ANISTAR_OK);
    check_sample(ctx, s, &smp);
    assert_int_equal(smp.ncomponents, 2);
    double c1[3] = {3, 0, 0}, c2[3] = {-3, 0, 0}, d1, d2;
    int32_t k1 = nearest_component(&smp, c1, &d1), k2 = nearest_component(&smp, c2, &d2);
    assert_true(k1 != k2 && fabs(d1 - 0.1) < 1e-9 && fabs(d2 - 0.1) < 1e-9);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
    /* spheres of radius 0.05 centred in cells of the finest grid (spacing 10/128): no grid
     * vertex inside them at any level; found by descent from the local minima */
    double h = 10.0 / 128, cx = -5 + 88.5 * h, cy = -5 + 64.5 * h, cz = -5 + 60.5 * h;
    double ex = -5 + 30.5 * h;
    char src[256];
    snprintf(src, sizeof src,
             "min((x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-0.0025, "
             "(x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-0.0025)",
             cx, cy, cz, ex, cy, cz);
    s = expression(ctx, src, 5);
    assert_int_equal(as_surface_sample(ctx, s, 40, &smp), ANISTAR_OK);
    check_sample(ctx, s, &smp);
    assert_int_equal(smp.ncomponents, 2);
    double e1[3] = {cx, cy, cz}, e2[3] = {ex, cy, cz};
    k1 = nearest_component(&smp, e1, &d1);
    k2 = nearest_component(&smp, e2, &d2);
    assert_true(k1 != k2 && fabs(d1 - 0.05) < 1e-9 && fabs(d2 - 0.05) < 1e-9);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
    /* a shell between radii 1 and 2: one inside region, two components */
    s = expression(ctx, "(x^2+y^2+z^2-1)*(x^2+y^2+z^2-4)", 3);
    assert_int_equal(as_surface_sample(ctx, s, 40, &smp), ANISTAR_OK);
    check_sample(ctx, s, &smp);
    assert_int_equal(smp.ncomponents, 2);
    int seen_r1 = 0, seen_r2 = 0;
    for (size_t i = 0; i < smp.n; i++) {
        double r = norm3(smp.points + 3 * i);
        assert_true(fabs(r - 1) < 1e-9 || fabs(r - 2) < 1e-9);
        seen_r1 |= fabs(r - 1) < 1e-9;
        seen_r2 |= fabs(r - 2) < 1e-9;
        /* a component lies on one sphere */
        for (size_t j = 0; j < smp.n; j++)
            if (smp.component[i] == smp.component[j])
                assert_true(fabs(norm3(smp.points + 3 * j) - r) < 1e-9);
    }
    assert_true(seen_r1 && seen_r2);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- sampling: thin and small components -------------------------------------------------- */

/*
 * Shapes thinner or smaller than the sampler's grid cells (64^3 cells over the bounding
 * cube, h = R/32): plates, tubes, long tori, small separate pieces, a thin shell, a thin
 * cavity cut by max() (f does not show it at most grid vertices), two spheres closer than a
 * cell. Most are tilted by a fixed rotation Q and shifted by t (local coordinates
 * u = Q (p - t)) so that no grid plane or line is aligned with them. Each case names its
 * true components (comp: the component of a point of S) and, for long or wide ones,
 * sectors that must all hold a sample point (the points spread over it).
 * The summed areas (Crofton's formula on the lattice lines for the parts thinner than the
 * cells, marching tetrahedra elsewhere, a local grid for pieces smaller than a cell) were
 * measured at these relative errors: flat ellipsoids 2.2e-2 (axis-aligned, 0.01 thick),
 * 1.9e-3, 1.5e-3, 1.4e-3 (tilted, 0.01, 0.002, 0.0004 thick); thin torus 1.0e-2; long tori
 * 6.5e-2 (r = 1, 0.3 cells) and 0.32 (r = 0.2: about 40 lattice lines meet the tube);
 * spheres r=1 and r=0.01 1.2e-3; five tiny spheres 5e-3; capsule 0.16; thin shell 8e-4;
 * spheres 0.03 apart 6e-4; ball with a thin cavity 7.5e-2. The tolerances (area_tol) are
 * about two to three times these.
 */
typedef struct thin_case {
    const char *name;
    char expr[1024];
    double center[3], radius;
    int ncomp, nsect;
    int (*comp)(const struct thin_case *c, const double p[3]);
    int (*sect)(const struct thin_case *c, const double p[3]);
    double Q[9], t[3];
    double cen[6][3]; /* sphere centers (comp_nearest), or cen[0][0] a radius (comp_radial) */
    double area;      /* true area of S */
    double area_tol;  /* asserted relative area error */
} thin_case;

static void thin_local(const thin_case *c, const double p[3], double u[3]) {
    double d[3] = {p[0] - c->t[0], p[1] - c->t[1], p[2] - c->t[2]};
    for (int i = 0; i < 3; i++) u[i] = dot3(c->Q + 3 * i, d);
}
static int comp_one(const thin_case *c, const double p[3]) {
    (void)c;
    (void)p;
    return 0;
}
static int comp_nearest(const thin_case *c, const double p[3]) {
    int best = 0;
    for (int j = 1; j < c->ncomp; j++)
        if (dist3(p, c->cen[j]) < dist3(p, c->cen[best])) best = j;
    return best;
}
static int comp_radial(const thin_case *c, const double p[3]) {
    double u[3];
    thin_local(c, p, u);
    return norm3(u) < c->cen[0][0] ? 0 : 1;
}
/* 8 sectors of the angle around the local w axis (tori), 4 of the local w coordinate
 * (tubes along w), 4 quadrants of the local (u, v) plane (plates) */
static int sect_angle8(const thin_case *c, const double p[3]) {
    double u[3];
    thin_local(c, p, u);
    int k = (int)floor((atan2(u[1], u[0]) + PI) / (2 * PI) * 8);
    return k < 0 ? 0 : (k > 7 ? 7 : k);
}
static int sect_axis4(const thin_case *c, const double p[3]) {
    double u[3];
    thin_local(c, p, u);
    int k = (int)floor((u[2] + 1.02) / 2.04 * 4);
    return k < 0 ? 0 : (k > 3 ? 3 : k);
}
static int sect_quadrant(const thin_case *c, const double p[3]) {
    double u[3];
    thin_local(c, p, u);
    return (u[0] > 0) + 2 * (u[1] > 0);
}

/* "(a*x+b*y+c*z+d)": the local coordinate i of the case. */
static void thin_coord(const thin_case *c, int i, char *buf, size_t n) {
    const double *q = c->Q + 3 * i;
    snprintf(buf, n, "(%.17g*x+(%.17g)*y+(%.17g)*z+(%.17g))", q[0], q[1], q[2], -dot3(q, c->t));
}

/* The area of the ellipsoid with semi-axes a, b, c: the parametrisation over
 * (s = cos theta, phi): |x_s x x_phi| = sqrt(b^2c^2 (1-s^2) cos^2 phi + a^2c^2 (1-s^2)
 * sin^2 phi + a^2b^2 s^2), midpoint rule in both (periodic in phi: 256 nodes are exact to
 * rounding; 20000 in s resolve the bend at s = 0 of flat ellipsoids, width about c/b). */
static double ellipsoid_area(double a, double b, double c) {
    const int ns = 20000, np = 256;
    double sum = 0;
    for (int i = 0; i < ns; i++) {
        double s = -1 + (i + 0.5) * 2.0 / ns, q = 1 - s * s;
        for (int j = 0; j < np; j++) {
            double ph = (j + 0.5) * 2 * PI / np, cp = cos(ph), sp = sin(ph);
            sum += sqrt(b * b * c * c * q * cp * cp + a * a * c * c * q * sp * sp +
                        a * a * b * b * s * s);
        }
    }
    return sum * (2.0 / ns) * (2 * PI / np);
}

/* A fixed rotation (from the unit quaternion along (0.86, 0.31, -0.27, 0.29)). */
static void thin_rotation(double Q[9]) {
    double w = 0.86, x = 0.31, y = -0.27, z = 0.29, n = sqrt(w * w + x * x + y * y + z * z);
    w /= n, x /= n, y /= n, z /= n;
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y - w * z),     2 * (x * z + w * y),
                   2 * (x * y + w * z),     1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
                   2 * (x * z - w * y),     2 * (y * z + w * x),     1 - 2 * (x * x + y * y)};
    memcpy(Q, R, sizeof R);
}

/* A new case with frame (Q, t) and the local coordinates as expression text in u, v, w. */
static thin_case *thin_add(thin_case *cs, int *n, const char *name, const double Q[9],
                           double radius, int ncomp,
                           int (*comp)(const thin_case *, const double *), int nsect,
                           int (*sect)(const thin_case *, const double *), char u[160],
                           char v[160], char w[160]) {
    static const double t[3] = {0.0123, -0.0071, 0.0131};
    thin_case *c = &cs[(*n)++];
    memset(c, 0, sizeof *c);
    c->name = name;
    memcpy(c->Q, Q, sizeof c->Q);
    memcpy(c->t, t, sizeof c->t);
    c->radius = radius;
    c->ncomp = ncomp;
    c->comp = comp;
    c->nsect = nsect;
    c->sect = sect;
    thin_coord(c, 0, u, 160);
    thin_coord(c, 1, v, 160);
    thin_coord(c, 2, w, 160);
    return c;
}

/* Fill the cases; returns their number. */
static int thin_cases(thin_case *cs) {
    int n = 0;
    double Q[9], I[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    thin_rotation(Q);
    char u[160], v[160], w[160];
    thin_case *c;
    /* flat ellipsoids: thickness 0.01 (axis-aligned off the grid planes, and tilted), 0.002
     * and 0.0004 (tilted) */
    static const double flat[4] = {0.005, 0.005, 0.001, 0.0002};
    static const char *flat_names[4] = {"flat ellipsoid c=0.005", "flat ellipsoid c=0.005 tilted",
                                        "flat ellipsoid c=0.001 tilted",
                                        "flat ellipsoid c=0.0002 tilted"};
    for (int k = 0; k < 4; k++) {
        c = thin_add(cs, &n, flat_names[k], k == 0 ? I : Q, 1.25, 1, comp_one, 4, sect_quadrant,
                     u, v, w);
        snprintf(c->expr, sizeof c->expr, "%s^2+(%s/0.3)^2+(%s/%g)^2-1", u, v, w, flat[k]);
        c->area = ellipsoid_area(1, 0.3, flat[k]);
        c->area_tol = k == 0 ? 0.05 : 0.01;
    }
    /* a thin torus R = 1, r = 0.01 (tilted) */
    c = thin_add(cs, &n, "thin torus R=1 r=0.01", Q, 1.25, 1, comp_one, 8, sect_angle8, u, v, w);
    snprintf(c->expr, sizeof c->expr, "(sqrt(%s^2+%s^2)-1)^2+%s^2-0.0001", u, v, w);
    c->area = 4 * PI * PI * 0.01;
    c->area_tol = 0.03;
    /* long tori R = 100: r = 1 (axis-aligned, off the grid planes), r = 0.2 (tilted) */
    c = thin_add(cs, &n, "long torus R=100 r=1", I, 101.5, 1, comp_one, 8, sect_angle8, u, v, w);
    snprintf(c->expr, sizeof c->expr, "(sqrt(%s^2+%s^2)-100)^2+%s^2-1", u, v, w);
    c->area = 4 * PI * PI * 100;
    c->area_tol = 0.15;
    c = thin_add(cs, &n, "long torus R=100 r=0.2", Q, 101.5, 1, comp_one, 8, sect_angle8, u, v,
                 w);
    snprintf(c->expr, sizeof c->expr, "(sqrt(%s^2+%s^2)-100)^2+%s^2-0.04", u, v, w);
    c->area = 4 * PI * PI * 100 * 0.2;
    c->area_tol = 0.5;
    /* two spheres, radii 1 and 0.01, far apart */
    c = thin_add(cs, &n, "spheres r=1 and r=0.01", I, 3.5, 2, comp_nearest, 0, NULL, u, v, w);
    {
        double c1[3] = {3, 0.0177, -0.0101};
        memcpy(c->cen[1], c1, sizeof c1);
        snprintf(c->expr, sizeof c->expr,
                 "min(x^2+y^2+z^2-1, (x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-0.0001)", c1[0], c1[1],
                 c1[2]);
        c->area = 4 * PI * (1 + 1e-4);
        c->area_tol = 0.01;
    }
    /* five tiny spheres: four of radius 0.01, one of radius 0.002 */
    c = thin_add(cs, &n, "five tiny spheres", I, 2, 5, comp_nearest, 0, NULL, u, v, w);
    {
        static const double cc[5][4] = {{1.0123, 0.0071, 0.0133, 0.01},
                                        {-1.013, 0.5, 0.0, 0.01},
                                        {0.0, 1.017, 0.3, 0.01},
                                        {0.3, -0.9, -0.71, 0.01},
                                        {0.011, 0.023, 0.031, 0.002}};
        size_t len = 0;
        for (int j = 0; j < 5; j++) {
            memcpy(c->cen[j], cc[j], 3 * sizeof(double));
            len += (size_t)snprintf(c->expr + len, sizeof c->expr - len,
                                    "%s(x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-%.17g",
                                    j ? ", " : "min(", cc[j][0], cc[j][1], cc[j][2],
                                    cc[j][3] * cc[j][3]);
            c->area += 4 * PI * cc[j][3] * cc[j][3];
        }
        snprintf(c->expr + len, sizeof c->expr - len, ")");
        c->area_tol = 0.03;
    }
    /* a thin plate: a flattened superellipsoid, thickness 0.02 (tilted) */
    c = thin_add(cs, &n, "thin plate (superellipsoid)", Q, 1.6, 1, comp_one, 4, sect_quadrant, u,
                 v, w);
    snprintf(c->expr, sizeof c->expr, "%s^8+%s^8+(%s/0.01)^8-1", u, v, w);
    /* a capsule of radius 0.01 around a segment of length 2 (tilted) */
    c = thin_add(cs, &n, "capsule r=0.01 length 2", Q, 1.25, 1, comp_one, 4, sect_axis4, u, v, w);
    snprintf(c->expr, sizeof c->expr, "sqrt(%s^2+%s^2+(%s-min(max(%s,-1),1))^2)-0.01", u, v, w,
             w);
    c->area = 2 * PI * 0.01 * 2 + 4 * PI * 0.01 * 0.01;
    c->area_tol = 0.35;
    /* a thin shell between radii 0.995 and 1.005: two components, inner and outer */
    c = thin_add(cs, &n, "thin shell", I, 1.25, 2, comp_radial, 0, NULL, u, v, w);
    snprintf(c->expr, sizeof c->expr, "abs(sqrt(%s^2+%s^2+%s^2)-1)-0.005", u, v, w);
    c->cen[0][0] = 1;
    c->area = 4 * PI * (0.995 * 0.995 + 1.005 * 1.005);
    c->area_tol = 0.01;
    /* two unit spheres 0.03 apart (the cells are 0.078 wide) */
    c = thin_add(cs, &n, "spheres 0.03 apart", I, 2.5, 2, comp_nearest, 0, NULL, u, v, w);
    {
        double c0[3] = {-1.015, 0.0071, 0.0133}, c1[3] = {1.015, 0.0071, 0.0133};
        memcpy(c->cen[0], c0, sizeof c0);
        memcpy(c->cen[1], c1, sizeof c1);
        snprintf(c->expr, sizeof c->expr,
                 "min((x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-1, "
                 "(x-%.17g)^2+(y-%.17g)^2+(z-%.17g)^2-1)",
                 c0[0], c0[1], c0[2], c1[0], c1[1], c1[2]);
        c->area = 8 * PI;
        c->area_tol = 0.01;
    }
    /* a ball with a thin flat cavity (thickness 0.008, tilted): two components */
    c = thin_add(cs, &n, "ball with a thin cavity", Q, 1.25, 2, comp_radial, 0, NULL, u, v, w);
    snprintf(c->expr, sizeof c->expr,
             "max(x^2+y^2+z^2-1, -((%s/0.6)^2+(%s/0.5)^2+(%s/0.004)^2-1))", u, v, w);
    c->cen[0][0] = 0.8;
    c->area = 4 * PI + ellipsoid_area(0.6, 0.5, 0.004);
    c->area_tol = 0.15;
    return n;
}

static void test_thin_components(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    thin_case cs[24];
    int ncases = thin_cases(cs);
    for (int ci = 0; ci < ncases; ci++) {
        const thin_case *c = &cs[ci];
        as_surface *s = NULL;
        if (as_implicit_from_expression(ctx, c->expr, c->center, c->radius, &s))
            fail_msg("%s: %s", c->name, anistar_last_error(ctx));
        as_point_sample smp;
        if (as_surface_sample(ctx, s, 256, &smp))
            fail_msg("%s: sampling: %s", c->name, anistar_last_error(ctx));
        check_sample(ctx, s, &smp);
        if ((int)smp.ncomponents != c->ncomp)
            fail_msg("%s: %zu components found, %d expected", c->name, smp.ncomponents,
                     c->ncomp);
        /* sample components and true components correspond one to one */
        int truth[16], seen[16] = {0}, sect[16] = {0};
        for (int k = 0; k < c->ncomp; k++) truth[k] = -1;
        for (size_t i = 0; i < smp.n; i++) {
            const double *p = smp.points + 3 * i;
            int k = smp.component[i], tc = c->comp(c, p);
            if (truth[k] < 0) {
                if (seen[tc]) fail_msg("%s: true component %d split", c->name, tc);
                truth[k] = tc;
                seen[tc] = 1;
            } else if (truth[k] != tc) {
                fail_msg("%s: sample component %d mixes true components %d and %d", c->name, k,
                         truth[k], tc);
            }
            if (c->nsect) sect[c->sect(c, p)] = 1;
        }
        for (int k = 0; k < c->nsect; k++)
            if (!sect[k]) fail_msg("%s: no sample point in sector %d", c->name, k);
        /* area: the sum over the components */
        double area = 0;
        for (size_t k = 0; k < smp.ncomponents; k++) {
            assert_true(smp.area[k] >= 0);
            area += smp.area[k];
        }
        if (c->area_tol > 0 && !(relerr(area, c->area) <= c->area_tol))
            fail_msg("%s: area %.6g, true %.6g (relative error %.3g > %.3g)", c->name, area,
                     c->area, relerr(area, c->area), c->area_tol);
        /* deterministic: the same points again */
        as_point_sample again;
        assert_int_equal(as_surface_sample(ctx, s, 256, &again), ANISTAR_OK);
        assert_int_equal(again.n, smp.n);
        assert_memory_equal(again.points, smp.points, smp.n * 3 * sizeof(double));
        assert_memory_equal(again.component, smp.component, smp.n * sizeof(int32_t));
        assert_memory_equal(again.area, smp.area, smp.ncomponents * sizeof(double));
        as_surface_sample_free(ctx, &again);
        as_surface_sample_free(ctx, &smp);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* ---- sampling: area weights ------------------------------------------------------------- */

/* sum over the points of component k of (area[k] / count) g(p), over area[k]: the mean of g */
static double weighted_mean(const as_point_sample *smp, size_t k, double (*g)(const double *)) {
    size_t cnt = 0;
    double sum = 0;
    for (size_t i = 0; i < smp->n; i++)
        if ((size_t)smp->component[i] == k) cnt++;
    for (size_t i = 0; i < smp->n; i++)
        if ((size_t)smp->component[i] == k) sum += smp->area[k] / (double)cnt * g(smp->points + 3 * i);
    return sum / smp->area[k];
}
static double g_x(const double *p) { return p[0]; }
static double g_xx(const double *p) { return p[0] * p[0]; }
static double g_zz(const double *p) { return p[2] * p[2]; }

/*
 * Areas of smooth surfaces against closed forms and a numerical reference, from the
 * sampler's 64^3 grid (marching tetrahedra, vertices placed by cubic interpolation along
 * the grid lines). Measured relative errors: sphere r=1 (bound 1.25) 1.4e-4, torus R=10 r=1
 * (bound 11.25, 2.8 cells across the tube) 2.3e-4, ellipsoid 1.5 x 1 x 0.5 (bound 1.875)
 * 4.1e-4, the shell's spheres r=2 and r=1 (bound 3) 1.9e-4 and 8.9e-4. Asserted: 0.1%
 * (sphere), 0.3% (the others). (Crofton's lattice formula with a normal per crossing,
 * which the sampler uses only for parts thinner than the cells, gives 0.1% on the sphere
 * but 3% to 7% on this torus, depending on the grid's offset.)
 * Weighted means, sum of (area / n) g(p) over the n points, against the true means (the
 * points come from farthest-point sampling of the crossings: about uniform in area once
 * their spacing is small against the curvature radii): on the unit sphere, 256 points:
 * z^2 -> 1/3 (measured error 1.9e-3), x^2 -> 1/3 (7e-4), x -> 0 (6e-4); asserted 0.01.
 * On the torus (true means z^2 = r^2/2 = 0.5, x^2 = (R^2 + 1.5 r^2)/2 = 50.75), 256 points,
 * spacing 1.2 about the tube radius: z^2 0.465 (error 0.035), x^2 51.14 (0.8%); asserted
 * 0.07 and 3%; 1024 points: z^2 0.4984 (error 1.6e-3), asserted 0.01.
 */
static void test_sample_area(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_point_sample smp;
    as_surface *s = builtin(ctx, "sphere");
    assert_int_equal(as_surface_sample(ctx, s, 256, &smp), ANISTAR_OK);
    assert_int_equal(smp.ncomponents, 1);
    if (!(relerr(smp.area[0], 4 * PI) < 1e-3))
        fail_msg("sphere: area %.9g, true %.9g", smp.area[0], 4 * PI);
    if (!(fabs(weighted_mean(&smp, 0, g_zz) - 1.0 / 3) < 0.01))
        fail_msg("sphere: mean of z^2 %.6g, true 1/3", weighted_mean(&smp, 0, g_zz));
    assert_true(fabs(weighted_mean(&smp, 0, g_x)) < 0.01);
    assert_true(fabs(weighted_mean(&smp, 0, g_xx) - 1.0 / 3) < 0.01);
    as_surface_sample_free(ctx, &smp);
    assert_null(smp.area);
    as_surface_free(s);

    s = builtin(ctx, "torus");
    assert_int_equal(as_surface_sample(ctx, s, 256, &smp), ANISTAR_OK);
    if (!(relerr(smp.area[0], 4 * PI * PI * 10) < 3e-3))
        fail_msg("torus: area %.9g, true %.9g", smp.area[0], 4 * PI * PI * 10);
    if (!(fabs(weighted_mean(&smp, 0, g_zz) - 0.5) < 0.07))
        fail_msg("torus: mean of z^2 %.6g, true 1/2", weighted_mean(&smp, 0, g_zz));
    assert_true(relerr(weighted_mean(&smp, 0, g_xx), 50.75) < 0.03);
    as_surface_sample_free(ctx, &smp);
    assert_int_equal(as_surface_sample(ctx, s, 1024, &smp), ANISTAR_OK);
    if (!(fabs(weighted_mean(&smp, 0, g_zz) - 0.5) < 0.01))
        fail_msg("torus, 1024 points: mean of z^2 %.6g, true 1/2", weighted_mean(&smp, 0, g_zz));
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);

    s = builtin(ctx, "ellipsoid");
    assert_int_equal(as_surface_sample(ctx, s, 256, &smp), ANISTAR_OK);
    double ea = ellipsoid_area(1.5, 1, 0.5);
    if (!(relerr(smp.area[0], ea) < 3e-3))
        fail_msg("ellipsoid: area %.9g, reference %.9g", smp.area[0], ea);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);

    /* per component: the shell's two spheres */
    s = expression(ctx, "(x^2+y^2+z^2-1)*(x^2+y^2+z^2-4)", 3);
    assert_int_equal(as_surface_sample(ctx, s, 256, &smp), ANISTAR_OK);
    assert_int_equal(smp.ncomponents, 2);
    for (size_t k = 0; k < 2; k++) {
        size_t i = 0;
        while ((size_t)smp.component[i] != k) i++;
        double r = norm3(smp.points + 3 * i), want = 4 * PI * r * r;
        if (!(relerr(smp.area[k], want) < 3e-3))
            fail_msg("shell: component %zu (r = %g): area %.9g, true %.9g", k, r, smp.area[k],
                     want);
    }
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- callbacks: finite differences ---------------------------------------------------- */

/* torus R = 3, r = 1 */
static double cb_value(const double p[3], void *user) {
    int *calls = user;
    if (calls) (*calls)++;
    double q = sqrt(p[0] * p[0] + p[1] * p[1]) - 3;
    return q * q + p[2] * p[2] - 1;
}
static void cb_gradient(const double p[3], double g[3], void *user) {
    (void)user;
    double rho = sqrt(p[0] * p[0] + p[1] * p[1]), q = rho - 3;
    g[0] = 2 * q * p[0] / rho;
    g[1] = 2 * q * p[1] / rho;
    g[2] = 2 * p[2];
}

static void test_callbacks(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double c[3] = {0, 0, 0};
    int calls = 0;
    as_implicit_fn values_only = {cb_value, NULL, NULL, &calls};
    as_implicit_fn with_grad = {cb_value, cb_gradient, NULL, NULL};
    as_surface *sv, *sg, *se;
    assert_int_equal(as_implicit_create(ctx, &values_only, c, 4.5, &sv), ANISTAR_OK);
    assert_int_equal(as_implicit_create(ctx, &with_grad, c, 4.5, &sg), ANISTAR_OK);
    se = expression(ctx, "(sqrt(x^2+y^2)-3)^2+z^2-1", 4.5);
    tu_rng rng = {6};
    for (int t = 0; t < 200; t++) {
        double th = tu_rng_range(&rng, 0, 2 * PI), ph = tu_rng_range(&rng, 0, 2 * PI), p[3];
        torus_point(3, 1, th, ph, p);
        as_surface_frame fe, fv, fg;
        assert_int_equal(as_surface_frame_at(ctx, se, p, &fe), ANISTAR_OK);
        assert_int_equal(as_surface_frame_at(ctx, sv, p, &fv), ANISTAR_OK);
        assert_int_equal(as_surface_frame_at(ctx, sg, p, &fg), ANISTAR_OK);
        /* documented accuracy: gradient ~1e-10, Hessian from gradient ~1e-10, from values
         * ~1e-8 (relative to the curvature scale 1/r = 1) */
        assert_true(dist3(fv.n, fe.n) < 1e-9);
        for (int k = 0; k < 2; k++) {
            assert_true(fabs(fg.k[k] - fe.k[k]) < 1e-8);
            assert_true(fabs(fv.k[k] - fe.k[k]) < 1e-6);
        }
    }
    assert_true(calls > 0); /* user is passed back */
    /* value callback required */
    as_implicit_fn none = {NULL, NULL, NULL, NULL};
    as_surface *s = (as_surface *)1;
    assert_int_equal(as_implicit_create(ctx, &none, c, 1, &s), ANISTAR_EINVAL);
    assert_null(s);
    as_surface_free(sv);
    as_surface_free(sg);
    as_surface_free(se);
    anistar_context_free(ctx);
}

/* ---- the analysis kept by the surface ---------------------------------------------------- */

/* The first sample of a surface given by a function analyses S on the sampler's grid (a
 * value per node); the later ones, of any size, reuse it and only refine their crossings:
 * the same points as a fresh surface's first sample of that size, for a small fraction
 * of the evaluations. */
static void test_sample_kept(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double c[3] = {0, 0, 0};
    int calls_a = 0, calls_b = 0;
    as_implicit_fn fa = {cb_value, cb_gradient, NULL, &calls_a};
    as_implicit_fn fb = {cb_value, cb_gradient, NULL, &calls_b};
    as_surface *sa, *sb;
    assert_int_equal(as_implicit_create(ctx, &fa, c, 4.5, &sa), ANISTAR_OK);
    assert_int_equal(as_implicit_create(ctx, &fb, c, 4.5, &sb), ANISTAR_OK);
    as_point_sample s256, s1024, fresh;
    assert_int_equal(as_surface_sample(ctx, sa, 256, &s256), ANISTAR_OK);
    const int first = calls_a;
    /* the values at the grid's nodes inside the bounding sphere: about pi/6 of the 65^3 */
    assert_true(first > 100000);
    assert_int_equal(as_surface_sample(ctx, sa, 1024, &s1024), ANISTAR_OK);
    const int second = calls_a - first;
    assert_true(second > 0);           /* its crossings are refined */
    assert_true(second < first / 8);   /* but S is not analysed again */
    /* the same points as a first sample of 1,024 */
    assert_int_equal(as_surface_sample(ctx, sb, 1024, &fresh), ANISTAR_OK);
    assert_true(calls_b > 100000);
    assert_int_equal(fresh.n, s1024.n);
    assert_int_equal(fresh.ncomponents, s1024.ncomponents);
    assert_memory_equal(fresh.points, s1024.points, 3 * fresh.n * sizeof(double));
    assert_memory_equal(fresh.component, s1024.component, fresh.n * sizeof(int32_t));
    assert_memory_equal(fresh.area, s1024.area, fresh.ncomponents * sizeof(double));
    check_sample(ctx, sa, &s256);
    check_sample(ctx, sa, &s1024);
    /* a sampler with threads gives them too, from the kept analysis */
    as_pool *pool = NULL;
    as_sampler *sp = NULL;
    assert_int_equal(as_pool_new(ctx, 2, &pool), ANISTAR_OK);
    assert_int_equal(as_sampler_new(ctx, sa, pool, &sp), ANISTAR_OK);
    as_point_sample pooled;
    const int before = calls_a;
    assert_int_equal(as_sampler_sample(ctx, sp, 1024, &pooled), ANISTAR_OK);
    assert_true(calls_a - before < first / 8);
    assert_int_equal(pooled.n, s1024.n);
    assert_memory_equal(pooled.points, s1024.points, 3 * pooled.n * sizeof(double));
    as_surface_sample_free(ctx, &pooled);
    as_sampler_free(ctx, sp);
    as_pool_free(pool);
    as_surface_sample_free(ctx, &s256);
    as_surface_sample_free(ctx, &s1024);
    as_surface_sample_free(ctx, &fresh);
    as_surface_free(sa); /* frees the kept analysis: no leak under ASan */
    as_surface_free(sb);
    anistar_context_free(ctx);
}

/* ---- singular points --------------------------------------------------------------------- */

static void test_singular(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = expression(ctx, "x^2+y^2-z^2", 1);
    double o[3] = {0, 0, 0}, n[3];
    as_surface_frame fr;
    assert_int_equal(as_surface_frame_at(ctx, s, o, &fr), ANISTAR_OK);
    assert_true(fr.singular);
    assert_int_equal(as_surface_normal(ctx, s, o, n), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "grad f vanishes"));
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- allocation failures ---------------------------------------------------------------- */

static void test_alloc_failures(void **state) {
    (void)state;
    int succeeded = 0;
    for (long k = 0; k < 400 && !succeeded; k++) {
        tu_alloc ta;
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        if (!ctx) continue;
        as_surface *s = NULL;
        anistar_status st = as_implicit_builtin(ctx, "torus,R=4,r=1", &s);
        if (st == ANISTAR_OK) {
            as_point_sample smp;
            st = as_surface_sample(ctx, s, 20, &smp);
            if (st == ANISTAR_OK) {
                check_sample(ctx, s, &smp);
                as_surface_sample_free(ctx, &smp);
                succeeded = 1;
            } else {
                assert_null(smp.points);
            }
            as_surface_free(s);
        } else {
            assert_null(s);
        }
        if (st) assert_true(st == ANISTAR_ENOMEM || st == ANISTAR_EFORMAT);
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
        assert_int_equal(ta.live_bytes, 0);
    }
    assert_true(succeeded);
}

/* ---- concurrent queries ------------------------------------------------------------------ */

typedef struct th_job {
    const as_surface *s;
    uint64_t seed;
    int n;
    double *out; /* 6 per query: crossing point, projection */
    int errors;
} th_job;

static void th_queries(th_job *job, anistar_context *ctx) {
    tu_rng rng = {job->seed};
    for (int i = 0; i < job->n; i++) {
        double a[3], b[3], x[3] = {0, 0, 0}, q[3] = {0, 0, 0};
        for (int k = 0; k < 3; k++) {
            a[k] = tu_rng_range(&rng, -3, 3);
            b[k] = tu_rng_range(&rng, -3, 3);
        }
        a[0] += 10;
        b[0] += 10;
        int found;
        if (as_surface_crossing(ctx, job->s, a, b, a, &found, x)) job->errors++;
        if (as_surface_project(ctx, job->s, a, q)) job->errors++;
        memcpy(job->out + 6 * i, x, sizeof x);
        memcpy(job->out + 6 * i + 3, q, sizeof q);
    }
}

static void *th_main(void *arg) {
    th_job *job = arg;
    anistar_context *ctx = anistar_context_new(NULL); /* each thread its own context */
    th_queries(job, ctx);
    anistar_context_free(ctx);
    return NULL;
}

static void test_threads(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = builtin(ctx, "torus");
    enum { NT = 4, NQ = 150 };
    double *ref = test_malloc(sizeof(double) * 6 * NQ * NT);
    double *got = test_malloc(sizeof(double) * 6 * NQ * NT);
    th_job jobs[NT];
    for (int t = 0; t < NT; t++) {
        th_job j = {s, 100 + (uint64_t)t, NQ, ref + 6 * NQ * t, 0};
        th_queries(&j, ctx);
        assert_int_equal(j.errors, 0);
        th_job j2 = {s, 100 + (uint64_t)t, NQ, got + 6 * NQ * t, 0};
        jobs[t] = j2;
    }
    pthread_t th[NT];
    for (int t = 0; t < NT; t++) assert_int_equal(pthread_create(&th[t], NULL, th_main, &jobs[t]), 0);
    for (int t = 0; t < NT; t++) pthread_join(th[t], NULL);
    for (int t = 0; t < NT; t++) assert_int_equal(jobs[t].errors, 0);
    assert_memory_equal(ref, got, sizeof(double) * 6 * NQ * NT);
    test_free(ref);
    test_free(got);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- the public API wrappers ---------------------------------------------------------------- */

static void test_public_api(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s = NULL;
    assert_int_equal(anistar_surface_builtin(ctx, "torus", &s), ANISTAR_OK);
    double c[3], r, p[3] = {11, 0, 0}, f, g[3], h[6], q[3], n[3], k[2], d1[3], d2[3];
    assert_int_equal(anistar_surface_bound(s, c, &r), ANISTAR_OK);
    assert_true(r == 11.25 && c[0] == 0);
    assert_int_equal(anistar_surface_eval(s, p, &f, g, h), ANISTAR_OK);
    assert_true(f == 0 && g[0] == 2 && h[5] == 2);
    double p2[3] = {12, 0, 0};
    assert_int_equal(anistar_surface_project(s, p2, q), ANISTAR_OK);
    assert_true(dist3(q, p) < 1e-11);
    assert_int_equal(anistar_surface_normal(s, q, n), ANISTAR_OK);
    assert_true(fabs(n[0] - 1) < 1e-14);
    assert_int_equal(anistar_surface_curvature(s, q, k, d1, d2), ANISTAR_OK);
    assert_true(relerr(k[0], 1) < 1e-10 && relerr(k[1], 1.0 / 11) < 1e-10);
    int side, found;
    assert_int_equal(anistar_surface_side(s, p2, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    double a[3] = {10.5, 0, 0}, x[3];
    assert_int_equal(anistar_surface_crossing(s, a, p2, a, &found, x), ANISTAR_OK);
    assert_true(found && dist3(x, p) < 1e-11);
    /* argument checks */
    double bad[3] = {NAN, 0, 0};
    assert_int_equal(anistar_surface_eval(s, bad, &f, NULL, NULL), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_eval(s, p, NULL, NULL, NULL), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_eval(NULL, p, &f, NULL, NULL), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_project(s, NULL, q), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_crossing(s, a, NULL, a, &found, x), ANISTAR_EINVAL);
    anistar_surface *s2 = NULL;
    assert_int_equal(anistar_surface_builtin(ctx, NULL, &s2), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_from_expression(ctx, NULL, c, 1, &s2), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_from_expression(NULL, "x", c, 1, &s2), ANISTAR_EINVAL);
    anistar_implicit_fn fn = {cb_value, NULL, NULL, NULL};
    assert_int_equal(anistar_surface_from_implicit(ctx, &fn, c, 4.5, &s2), ANISTAR_OK);
    assert_int_equal(anistar_surface_side(s2, p, &side), ANISTAR_OK);
    anistar_surface_free(s2);
    const char *name, *desc;
    assert_int_equal(anistar_surface_builtin_info(0, &name, &desc), ANISTAR_OK);
    assert_int_equal(anistar_surface_builtin_info(1000, &name, &desc), ANISTAR_EINVAL);
    anistar_surface_free(s);
    anistar_surface_free(NULL);
    anistar_context_free(ctx);
}

/* Every built-in surface is evaluated natively (kind "builtin"); its value, gradient and
 * Hessian agree with its formula run by the expression interpreter at random points of
 * its bounding box, to rounding (1e-12 of the largest magnitude of each quantity over the
 * points), with default and other parameters; on the torus's axis both fail. */
static void test_builtin_native(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    static const char *specs[] = {"sphere",     "sphere,r=0.3",         "ellipsoid",
                                  "ellipsoid,a=2,b=0.5,c=3", "torus",   "torus,R=3,r=2",
                                  "chair",      "chair,a=0.5,b=0.7,k=2", "tanglecube",
                                  "tanglecube,c=10", "double_torus", "double_torus,r=0.2"};
    enum { NP = 400 };
    tu_rng rng = {77};
    for (size_t i = 0; i < sizeof specs / sizeof specs[0]; i++) {
        as_surface *nat = NULL, *ex = NULL;
        assert_int_equal(as_implicit_builtin(ctx, specs[i], &nat), ANISTAR_OK);
        assert_int_equal(as_implicit_builtin_expr(ctx, specs[i], &ex), ANISTAR_OK);
        assert_string_equal(nat->ops->kind, "builtin");
        assert_string_equal(ex->ops->kind, "expression");
        static double a[NP][10], b[NP][10];
        double scale[3] = {0, 0, 0}; /* f, g, h */
        for (int k = 0; k < NP; k++) {
            double p[3];
            for (int j = 0; j < 3; j++)
                p[j] = nat->center[j] + tu_rng_range(&rng, -nat->radius, nat->radius);
            assert_int_equal(as_surface_eval(ctx, nat, p, 2, &a[k][0], a[k] + 1, a[k] + 4),
                             ANISTAR_OK);
            assert_int_equal(as_surface_eval(ctx, ex, p, 2, &b[k][0], b[k] + 1, b[k] + 4),
                             ANISTAR_OK);
            for (int j = 0; j < 10; j++) {
                int q = j == 0 ? 0 : j < 4 ? 1 : 2;
                if (fabs(b[k][j]) > scale[q]) scale[q] = fabs(b[k][j]);
            }
        }
        for (int k = 0; k < NP; k++)
            for (int j = 0; j < 10; j++) {
                int q = j == 0 ? 0 : j < 4 ? 1 : 2;
                if (!(fabs(a[k][j] - b[k][j]) <= 1e-12 * scale[q]))
                    fail_msg("%s: point %d, component %d: native %.17g, formula %.17g",
                             specs[i], k, j, a[k][j], b[k][j]);
            }
        as_surface_free(nat);
        as_surface_free(ex);
    }
    /* the torus's axis: the gradient is 0/0 in both */
    as_surface *t = builtin(ctx, "torus");
    const double axis[3] = {0, 0, 0.5};
    double f, g[3], h[6];
    assert_int_equal(as_surface_eval(ctx, t, axis, 1, &f, g, h), ANISTAR_EINVAL);
    assert_int_equal(as_surface_eval(ctx, t, axis, 0, &f, NULL, NULL), ANISTAR_OK);
    assert_true(f == 100 + 0.25 - 1);
    as_surface_free(t);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere_curvature),  cmocka_unit_test(test_torus_curvature),
        cmocka_unit_test(test_ellipsoid_curvature), cmocka_unit_test(test_projection),
        cmocka_unit_test(test_crossing_once),     cmocka_unit_test(test_crossing_three),
        cmocka_unit_test(test_crossing_tangent),  cmocka_unit_test(test_crossing_extent),
        cmocka_unit_test(test_side),
        cmocka_unit_test(test_nan_is_error),      cmocka_unit_test(test_no_surface),
        cmocka_unit_test(test_builtin_specs),     cmocka_unit_test(test_builtins_sample),
        cmocka_unit_test(test_small_components),  cmocka_unit_test(test_thin_components),
        cmocka_unit_test(test_sample_area),       cmocka_unit_test(test_callbacks), cmocka_unit_test(test_sample_kept),
        cmocka_unit_test(test_singular),          cmocka_unit_test(test_alloc_failures),
        cmocka_unit_test(test_threads),           cmocka_unit_test(test_public_api),
        cmocka_unit_test(test_builtin_native),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
