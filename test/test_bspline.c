/*
 * test_bspline.c — the cubic B-spline reconstruction (lib/surface/bspline.c):
 * interpolation at voxel centers (inside and, with the background, outside the image),
 * exact reproduction of cubic polynomials (value, gradient, Hessian in world coordinates
 * with anisotropic spacing and a rotated grid), derivatives against finite differences,
 * C2 continuity across knots and the border, background far away, closed isosurfaces
 * at the border, error handling and allocation-failure injection.
 */
#include "test_util.h"

#include "io/image_io.h"
#include "surface/bspline.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define POLE_ABS 0.26794919243112270647

/* |a - b| <= tol, in double (cmocka's float helpers round to float). */
static void check_near(double a, double b, double tol, const char *expr, int line) {
    if (!(fabs(a - b) <= tol)) {
        print_error("line %d: %s: %.17g vs %.17g (diff %.3g, tol %.3g)\n", line, expr, a, b,
                    fabs(a - b), tol);
        fail();
    }
}
#define assert_near(a, b, tol) check_near((a), (b), (tol), #a, __LINE__)

typedef struct fixture {
    tu_alloc alloc;
    anistar_allocator al;
    anistar_context *ctx;
} fixture;

static fixture *fx_new(void) {
    fixture *f = calloc(1, sizeof *f);
    assert_non_null(f);
    tu_alloc_init(&f->alloc, -1);
    f->al = tu_allocator(&f->alloc);
    f->ctx = anistar_context_new(&f->al);
    assert_non_null(f->ctx);
    return f;
}

static void fx_free(fixture *f) {
    anistar_context_free(f->ctx);
    assert_int_equal(f->alloc.live_blocks, 0);
    assert_int_equal(f->alloc.live_bytes, 0);
    free(f);
}

static void rotation(double ax0, double ax1, double ax2, double th, double r[9]) {
    double n = sqrt(ax0 * ax0 + ax1 * ax1 + ax2 * ax2), ax[3] = {ax0 / n, ax1 / n, ax2 / n};
    double c = cos(th), s = sin(th);
    double k[9] = {0, -ax[2], ax[1], ax[2], 0, -ax[0], -ax[1], ax[0], 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double kk = 0;
            for (int m = 0; m < 3; m++) kk += k[3 * i + m] * k[3 * m + j];
            r[3 * i + j] = (i == j) + s * k[3 * i + j] + (1 - c) * kk;
        }
}

/* A float64 image of random values in [lo, hi) with the given geometry. */
static as_image *random_image(fixture *f, size_t nx, size_t ny, size_t nz, double lo, double hi,
                              const double sp[3], const double org[3], const double dir[9],
                              tu_rng *rng) {
    as_image *img;
    assert_int_equal(as_image_new(f->ctx, nx, ny, nz, AS_VOXEL_F64, &img), ANISTAR_OK);
    assert_int_equal(as_image_set_geometry(f->ctx, img, sp, org, dir), ANISTAR_OK);
    double *d = img->data;
    for (size_t i = 0; i < img->count; i++) d[i] = tu_rng_range(rng, lo, hi);
    return img;
}

static void voxel_world(const as_bspline *bs, double i, double j, double k, double p[3]) {
    double v[3] = {i, j, k};
    as_grid_voxel_to_world(as_bspline_grid(bs), v, p);
}

/* ---- interpolation ------------------------------------------------------------------ */

/* The extension's fade at d voxels outside the image (bspline.h): 1 - the quintic
 * smoothstep of |d| / (FADE + 1), 0 beyond FADE. */
static double fade_at(ptrdiff_t d) {
    if (d < 0) d = -d;
    if (d > AS_BSPLINE_FADE) return 0;
    double t = (double)d / (AS_BSPLINE_FADE + 1);
    return 1 - (10 * t * t * t - 15 * t * t * t * t + 6 * t * t * t * t * t);
}
static ptrdiff_t clampi(ptrdiff_t i, ptrdiff_t n) { return i < 0 ? 0 : i > n - 1 ? n - 1 : i; }

static void test_interpolates_voxels(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {42};
    double rot[9];
    rotation(1, -2, 0.5, 0.9, rot);
    const double sp[3] = {0.7, 1.3, 2.1}, org[3] = {5, -1, 2};
    /* Sizes including 1 and 2 along an axis (edge cases of the recursions). */
    static const size_t dims[][3] = {{13, 11, 9}, {1, 5, 3}, {2, 1, 1}, {1, 1, 1}, {4, 2, 7}};
    for (size_t t = 0; t < sizeof dims / sizeof dims[0]; t++) {
        as_image *img =
            random_image(f, dims[t][0], dims[t][1], dims[t][2], -1, 2, sp, org, rot, &rng);
        const double bg = -0.37;
        as_bspline *bs;
        assert_int_equal(as_bspline_create(f->ctx, img, bg, &bs), ANISTAR_OK);
        double vmax = 2;
        const ptrdiff_t n[3] = {(ptrdiff_t)dims[t][0], (ptrdiff_t)dims[t][1],
                                (ptrdiff_t)dims[t][2]};
        /* Every integer position of [-7, n+6]^3: the voxel inside; outside, the nearest
         * border voxel faded to the background (bspline.h), the background from FADE + 1
         * voxels out. */
        long checked = 0;
        const ptrdiff_t e = AS_BSPLINE_PAD + 3;
        for (ptrdiff_t k = -e; k < n[2] + e; k++)
            for (ptrdiff_t j = -e; j < n[1] + e; j++)
                for (ptrdiff_t i = -e; i < n[0] + e; i++) {
                    ptrdiff_t ci = clampi(i, n[0]), cj = clampi(j, n[1]), ck = clampi(k, n[2]);
                    double fade = fade_at(i - ci) * fade_at(j - cj) * fade_at(k - ck);
                    double expect =
                        bg + (as_image_value(img, (size_t)(ci + n[0] * (cj + n[1] * ck))) - bg) *
                                 fade;
                    double p[3], v[3] = {(double)i, (double)j, (double)k};
                    voxel_world(bs, (double)i, (double)j, (double)k, p);
                    assert_near(as_bspline_value(bs, p), expect, 1e-12 * vmax);
                    assert_near(as_bspline_value_voxel(bs, v), expect, 1e-13 * vmax);
                    double g[3], h[6];
                    assert_near(as_bspline_value_grad_hess(bs, p, g, h), expect, 1e-12 * vmax);
                    checked++;
                }
        assert_true(checked > 0);
        as_bspline_free(f->ctx, bs);
        as_image_free(f->ctx, img);
    }
    fx_free(f);
}

/* The same voxels as uint8 and as float64 give the same spline; a real image
 * interpolates at its voxel centers and keeps its inside count. */
static void test_types_and_skull(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *a, *b;
    assert_int_equal(as_image_new(f->ctx, 9, 8, 7, AS_VOXEL_U8, &a), ANISTAR_OK);
    assert_int_equal(as_image_new(f->ctx, 9, 8, 7, AS_VOXEL_F64, &b), ANISTAR_OK);
    tu_rng rng = {9};
    for (size_t i = 0; i < a->count; i++) {
        uint8_t x = (uint8_t)tu_rng_u64(&rng);
        ((uint8_t *)a->data)[i] = x;
        ((double *)b->data)[i] = x;
    }
    as_bspline *sa, *sb;
    assert_int_equal(as_bspline_create(f->ctx, a, 10, &sa), ANISTAR_OK);
    assert_int_equal(as_bspline_create(f->ctx, b, 10, &sb), ANISTAR_OK);
    for (int it = 0; it < 200; it++) {
        double p[3] = {tu_rng_range(&rng, -3, 11), tu_rng_range(&rng, -3, 10),
                       tu_rng_range(&rng, -3, 9)};
        assert_true(as_bspline_value(sa, p) == as_bspline_value(sb, p));
    }
    as_bspline_free(f->ctx, sa);
    as_bspline_free(f->ctx, sb);
    as_image_free(f->ctx, a);
    as_image_free(f->ctx, b);

    as_image *img;
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/skull_2.9.inr", &img), ANISTAR_OK);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_OK);
    long inside = 0;
    for (size_t k = 0; k < img->nz; k++)
        for (size_t j = 0; j < img->ny; j++)
            for (size_t i = 0; i < img->nx; i++) {
                double p[3];
                voxel_world(bs, (double)i, (double)j, (double)k, p);
                double fv = as_bspline_value(bs, p);
                double v = as_image_value(img, i + img->nx * (j + img->ny * k));
                assert_near(fv, v, 1e-12 * 5.43);
                inside += fv > 2.9;
            }
    assert_int_equal(inside, 22490);
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- polynomial reproduction -------------------------------------------------------- */

typedef struct poly {
    double k[20];
    int e[20][3];
    double c[3], L; /* P(p) = sum k_m q^e_m, q = (p - c) / L */
} poly;

static void poly_init(poly *P, tu_rng *rng, const double c[3], double L) {
    int m = 0;
    for (int a = 0; a <= 3; a++)
        for (int b = 0; a + b <= 3; b++)
            for (int d = 0; a + b + d <= 3; d++) {
                P->e[m][0] = a;
                P->e[m][1] = b;
                P->e[m][2] = d;
                P->k[m] = tu_rng_range(rng, -1, 1);
                m++;
            }
    assert_int_equal(m, 20);
    memcpy(P->c, c, sizeof P->c);
    P->L = L;
}

static double ipow(double x, int n) {
    double r = 1;
    for (int i = 0; i < n; i++) r *= x;
    return r;
}

/* d^n/dx^n of x^e. */
static double dpow(double x, int e, int n) {
    if (n > e) return 0;
    double f = 1;
    for (int i = 0; i < n; i++) f *= e - i;
    return f * ipow(x, e - n);
}

static double poly_eval(const poly *P, const double p[3], double g[3], double h[6]) {
    double q[3];
    for (int i = 0; i < 3; i++) q[i] = (p[i] - P->c[i]) / P->L;
    double v = 0;
    for (int i = 0; i < 3; i++) g[i] = 0;
    for (int i = 0; i < 6; i++) h[i] = 0;
    static const int hi[6] = {0, 0, 0, 1, 1, 2}, hj[6] = {0, 1, 2, 1, 2, 2};
    for (int m = 0; m < 20; m++) {
        const int *e = P->e[m];
        v += P->k[m] * ipow(q[0], e[0]) * ipow(q[1], e[1]) * ipow(q[2], e[2]);
        for (int a = 0; a < 3; a++) {
            int n[3] = {0, 0, 0};
            n[a] = 1;
            g[a] += P->k[m] * dpow(q[0], e[0], n[0]) * dpow(q[1], e[1], n[1]) *
                    dpow(q[2], e[2], n[2]) / P->L;
        }
        for (int s = 0; s < 6; s++) {
            int n[3] = {0, 0, 0};
            n[hi[s]]++;
            n[hj[s]]++;
            h[s] += P->k[m] * dpow(q[0], e[0], n[0]) * dpow(q[1], e[1], n[1]) *
                    dpow(q[2], e[2], n[2]) / (P->L * P->L);
        }
    }
    return v;
}

static void test_polynomial_reproduction(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {2024};
    double rot[9];
    rotation(0.3, 1, -0.7, 1.1, rot);
    const double sp[3] = {0.7, 1.1, 1.6}, org[3] = {-10, 4, 30};
    const size_t n = 60;
    as_image *img;
    assert_int_equal(as_image_new(f->ctx, n, n, n, AS_VOXEL_F64, &img), ANISTAR_OK);
    assert_int_equal(as_image_set_geometry(f->ctx, img, sp, org, rot), ANISTAR_OK);
    double center[3], radius;
    as_grid_bounding_sphere(&img->grid, 0, center, &radius);
    for (int rep = 0; rep < 3; rep++) {
        poly P;
        poly_init(&P, &rng, center, 0.5 * radius);
        double *d = img->data, g[3], h[6];
        for (size_t k = 0; k < n; k++)
            for (size_t j = 0; j < n; j++)
                for (size_t i = 0; i < n; i++) {
                    double v[3] = {(double)i, (double)j, (double)k}, p[3];
                    as_grid_voxel_to_world(&img->grid, v, p);
                    d[i + n * (j + n * k)] = poly_eval(&P, p, g, h);
                }
        as_bspline *bs;
        assert_int_equal(as_bspline_create(f->ctx, img, tu_rng_range(&rng, -2, 2), &bs),
                         ANISTAR_OK);
        /* Random points at least 25 voxels from the border; scales = largest magnitude of
         * each quantity over the points. */
        enum { NP = 300 };
        double pts[NP][3], ev[NP], eg[NP][3], eh[NP][6];
        double sv = 0, sg = 0, sh = 0;
        for (int t = 0; t < NP; t++) {
            double v[3] = {tu_rng_range(&rng, 25, 34), tu_rng_range(&rng, 25, 34),
                           tu_rng_range(&rng, 25, 34)};
            as_grid_voxel_to_world(&img->grid, v, pts[t]);
            ev[t] = poly_eval(&P, pts[t], eg[t], eh[t]);
            sv = fmax(sv, fabs(ev[t]));
            for (int a = 0; a < 3; a++) sg = fmax(sg, fabs(eg[t][a]));
            for (int a = 0; a < 6; a++) sh = fmax(sh, fabs(eh[t][a]));
        }
        for (int t = 0; t < NP; t++) {
            double fg[3], fh[6];
            double fv = as_bspline_value_grad_hess(bs, pts[t], fg, fh);
            assert_near(fv, ev[t], 1e-9 * sv);
            for (int a = 0; a < 3; a++) assert_near(fg[a], eg[t][a], 1e-9 * sg);
            for (int a = 0; a < 6; a++) assert_near(fh[a], eh[t][a], 1e-9 * sh);
            assert_near(as_bspline_value(bs, pts[t]), ev[t], 1e-9 * sv);
            double g1[3];
            assert_near(as_bspline_value_grad(bs, pts[t], g1), ev[t], 1e-9 * sv);
            for (int a = 0; a < 3; a++) assert_near(g1[a], eg[t][a], 1e-9 * sg);
        }
        as_bspline_free(f->ctx, bs);
    }
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- derivatives and continuity ----------------------------------------------------- */

/* An anisotropic, sheared grid of random values. */
static as_image *sheared_image(fixture *f, tu_rng *rng) {
    const double sp[3] = {0.6, 1.0, 1.7}, org[3] = {1, 2, 3};
    const double shear[9] = {1, 0.3, -0.2, 0.1, 1, 0.25, 0, -0.15, 1};
    return random_image(f, 12, 10, 8, 0, 1, sp, org, shear, rng);
}

static void test_derivatives_vs_finite_differences(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {31337};
    as_image *img = sheared_image(f, &rng);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0.2, &bs), ANISTAR_OK);
    const double eps = 1e-5; /* world step (voxels are ~1 wide) */
    for (int it = 0; it < 400; it++) {
        double v[3] = {tu_rng_range(&rng, -4, 15), tu_rng_range(&rng, -4, 13),
                       tu_rng_range(&rng, -4, 11)};
        double p[3], g[3], h[6], g1[3];
        as_grid_voxel_to_world(as_bspline_grid(bs), v, p);
        double fv = as_bspline_value_grad_hess(bs, p, g, h);
        assert_near(as_bspline_value(bs, p), fv, 1e-14);
        assert_near(as_bspline_value_grad(bs, p, g1), fv, 1e-14);
        for (int a = 0; a < 3; a++) assert_near(g1[a], g[a], 1e-14);
        static const int hi[6] = {0, 0, 0, 1, 1, 2}, hj[6] = {0, 1, 2, 1, 2, 2};
        double hfd[3][3];
        for (int a = 0; a < 3; a++) {
            double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]}, gp[3], gm[3];
            pp[a] += eps;
            pm[a] -= eps;
            double fp = as_bspline_value_grad(bs, pp, gp);
            double fm = as_bspline_value_grad(bs, pm, gm);
            assert_near(g[a], (fp - fm) / (2 * eps), 1e-6);
            for (int b = 0; b < 3; b++) hfd[b][a] = (gp[b] - gm[b]) / (2 * eps);
        }
        for (int s = 0; s < 6; s++) {
            assert_near(h[s], hfd[hi[s]][hj[s]], 1e-5);
            assert_near(h[s], hfd[hj[s]][hi[s]], 1e-5);
        }
        /* Voxel-coordinate derivatives map to the world ones: g_w = A^-T g_v. */
        double gv[3], hv[6];
        as_bspline_value_grad_hess_voxel(bs, v, gv, hv);
        const double *ai = as_bspline_grid(bs)->ainv;
        for (int a = 0; a < 3; a++)
            assert_near(g[a], gv[0] * ai[a] + gv[1] * ai[3 + a] + gv[2] * ai[6 + a], 1e-12);
    }
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

static void test_c2_continuity_across_knots(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {5};
    as_image *img = sheared_image(f, &rng);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0.5, &bs), ANISTAR_OK);
    const double de = 1e-8;
    const ptrdiff_t n[3] = {12, 10, 8};
    double worst_h = 0, seen_d3 = 0;
    for (int it = 0; it < 600; it++) {
        double v[3] = {tu_rng_range(&rng, -4, 15), tu_rng_range(&rng, -4, 13),
                       tu_rng_range(&rng, -4, 11)};
        int a = it % 3;
        /* A knot plane; every 4th one on the border or beyond it. */
        ptrdiff_t knot = (it % 4 == 0) ? ((it / 4) % 2 ? n[a] - 1 + (it / 8) % 4 : -((it / 8) % 4))
                                       : (ptrdiff_t)floor(v[a]);
        double lo[3] = {v[0], v[1], v[2]}, hi[3] = {v[0], v[1], v[2]};
        lo[a] = (double)knot - de;
        hi[a] = (double)knot + de;
        double gl[3], hl[6], gh[3], hh[6];
        double fl = as_bspline_value_grad_hess_voxel(bs, lo, gl, hl);
        double fh = as_bspline_value_grad_hess_voxel(bs, hi, gh, hh);
        /* Steps of 2e-8 voxel: value, gradient and Hessian change by O(2e-8) (C2). */
        assert_near(fl, fh, 1e-6);
        for (int c = 0; c < 3; c++) assert_near(gl[c], gh[c], 1e-6);
        for (int c = 0; c < 6; c++) {
            assert_near(hl[c], hh[c], 1e-6);
            worst_h = fmax(worst_h, fabs(hl[c] - hh[c]));
        }
        /* The third derivative does jump at knots (piecewise cubic): the Hessian's
         * one-sided slopes differ, so the test above is not vacuous. */
        double l2[3] = {lo[0], lo[1], lo[2]}, h2[3] = {hi[0], hi[1], hi[2]};
        l2[a] -= 1e-3;
        h2[a] += 1e-3;
        double g2[3], hl2[6], hh2[6];
        as_bspline_value_grad_hess_voxel(bs, l2, g2, hl2);
        as_bspline_value_grad_hess_voxel(bs, h2, g2, hh2);
        int ii = a == 0 ? 0 : a == 1 ? 3 : 5; /* d2/da2 */
        double d3l = (hl[ii] - hl2[ii]) / 1e-3, d3h = (hh2[ii] - hh[ii]) / 1e-3;
        seen_d3 = fmax(seen_d3, fabs(d3l - d3h));
    }
    assert_true(worst_h < 1e-6);
    assert_true(seen_d3 > 1e-2);
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- outside the image -------------------------------------------------------------- */

static void test_background_outside(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {77};
    as_image *img = sheared_image(f, &rng);
    const double bg = -3.0;
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, bg, &bs), ANISTAR_OK);
    const double cmax = as_bspline_coef_max(bs);
    assert_true(cmax > 1);
    assert_true(as_bspline_background(bs) == bg);
    const ptrdiff_t n[3] = {12, 10, 8};
    for (int it = 0; it < 2000; it++) {
        /* A point d voxels outside the padded grid along axis a (PAD + d outside the
         * image), anywhere along the others. */
        int a = it % 3;
        double d = tu_rng_range(&rng, 0.5, AS_BSPLINE_REACH + 10);
        double v[3];
        for (int c = 0; c < 3; c++) v[c] = tu_rng_range(&rng, -40, (double)n[c] + 40);
        v[a] = (it / 3) % 2 ? (double)(n[a] - 1) + AS_BSPLINE_PAD + d : -AS_BSPLINE_PAD - d;
        double g[3], h[6];
        double fv = as_bspline_value_grad_hess_voxel(bs, v, g, h);
        assert_true(as_bspline_value_voxel(bs, v) == fv);
        /* |f - b| < |z|^(d-2) max|c| */
        assert_true(fabs(fv - bg) <= pow(POLE_ABS, d - 2) * cmax);
        int beyond = 0;
        for (int c = 0; c < 3; c++)
            beyond |= v[c] < -(AS_BSPLINE_PAD + AS_BSPLINE_REACH) ||
                      v[c] > (double)(n[c] - 1) + AS_BSPLINE_PAD + AS_BSPLINE_REACH;
        if (beyond) {
            assert_true(fv == bg);
            for (int c = 0; c < 3; c++) assert_true(g[c] == 0);
            for (int c = 0; c < 6; c++) assert_true(h[c] == 0);
        }
    }
    /* The value tends to the background: |f - b| shrinks along a ray leaving the image. */
    double prev = INFINITY;
    for (int d = 2; d < AS_BSPLINE_REACH; d += 3) {
        double v[3] = {5.5, 4.25, (double)(n[2] - 1) + AS_BSPLINE_PAD + d + 0.5};
        double dev = fabs(as_bspline_value_voxel(bs, v) - bg);
        assert_true(dev < prev || dev == 0);
        prev = dev;
    }
    assert_true(prev < 1e-14 * cmax);
    /* The margin: beyond it, f stays on the background's side of the level. */
    static const double levels[] = {-2.9, -2.0, -1.0, 0.3, 0.9, -3.1, -4.5};
    for (size_t l = 0; l < sizeof levels / sizeof levels[0]; l++) {
        double m = as_bspline_margin(bs, levels[l]);
        assert_true(m >= 1 && m <= AS_BSPLINE_PAD + AS_BSPLINE_REACH && m == floor(m));
        for (int it = 0; it < 300; it++) {
            int a = it % 3;
            double v[3];
            for (int c = 0; c < 3; c++) v[c] = tu_rng_range(&rng, -m - 5, (double)n[c] + m + 5);
            double out = tu_rng_range(&rng, 1e-9, 6);
            v[a] = it % 2 ? (double)(n[a] - 1) + m + out : -m - out;
            double fv = as_bspline_value_voxel(bs, v);
            assert_true(fabs(fv - bg) < fabs(levels[l] - bg));
        }
    }
    assert_true(as_bspline_margin(bs, bg) == AS_BSPLINE_PAD + AS_BSPLINE_REACH);
    /* Non-finite points give NaN. */
    double pn[3] = {NAN, 0, 0}, pi[3] = {0, INFINITY, 0}, g[3], h[6];
    assert_true(isnan(as_bspline_value(bs, pn)));
    assert_true(isnan(as_bspline_value(bs, pi)));
    assert_true(isnan(as_bspline_value_grad_hess(bs, pn, g, h)) && isnan(g[0]) && isnan(h[5]));
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* Sample n points on the sphere (c, r) and return max of f there. */
static double max_on_sphere(const as_bspline *bs, const double c[3], double r, int n, tu_rng *rng) {
    double mx = -INFINITY;
    for (int i = 0; i < n; i++) {
        double u = tu_rng_range(rng, -1, 1), phi = tu_rng_range(rng, 0, 6.283185307179586);
        double s = sqrt(1 - u * u);
        double p[3] = {c[0] + r * s * cos(phi), c[1] + r * s * sin(phi), c[2] + r * u};
        mx = fmax(mx, as_bspline_value(bs, p));
    }
    return mx;
}

static void test_border_surface_closes(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {99};
    /* An image filled with 1: the isosurface 0.5 of the reconstruction is closed. */
    as_image *img;
    assert_int_equal(as_image_new(f->ctx, 10, 8, 6, AS_VOXEL_U8, &img), ANISTAR_OK);
    memset(img->data, 1, img->data_bytes);
    double rot[9];
    rotation(1, 1, 1, 0.4, rot);
    const double sp[3] = {1.0, 0.5, 2.0};
    assert_int_equal(as_image_set_geometry(f->ctx, img, sp, NULL, rot), ANISTAR_OK);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_OK);
    double c[3], r;
    as_grid_bounding_sphere(as_bspline_grid(bs), 0, c, &r);
    assert_true(as_bspline_value(bs, c) > 0.5);
    /* Every voxel center is inside (interpolation), the whole image too. */
    for (size_t k = 0; k < 6; k++)
        for (size_t j = 0; j < 8; j++)
            for (size_t i = 0; i < 10; i++) {
                double p[3];
                voxel_world(bs, (double)i, (double)j, (double)k, p);
                assert_true(as_bspline_value(bs, p) - 0.5 > 0);
            }
    double m = as_bspline_margin(bs, 0.5);
    print_message("margin of the ones at 0.5: %g voxels\n", m);
    assert_true(m >= 1 && m <= AS_BSPLINE_PAD + 4);
    double cm[3], rm;
    as_grid_bounding_sphere(as_bspline_grid(bs), m, cm, &rm);
    assert_true(max_on_sphere(bs, cm, rm, 4000, &rng) - 0.5 < 0);
    /* Tighter: already one voxel beyond the fade the sign is negative. */
    as_grid_bounding_sphere(as_bspline_grid(bs), AS_BSPLINE_PAD + 1, cm, &rm);
    assert_true(max_on_sphere(bs, cm, rm, 4000, &rng) - 0.5 < 0);
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);

    /* The brain: the head crosses the first and last z slices; with background 0 the
     * skin isosurface (40) closes within the margin. */
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/brain_t1.nhdr", &img), ANISTAR_OK);
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_OK);
    double top_inside = 0;
    for (size_t i = 0; i < 128 * 128; i++)
        top_inside = fmax(top_inside, as_image_value(img, 61 * 128 * 128 + i));
    assert_true(top_inside > 40);
    m = as_bspline_margin(bs, 40);
    print_message("margin of the brain at 40: %g voxels\n", m);
    assert_true(m >= 1 && m < AS_BSPLINE_PAD + AS_BSPLINE_REACH);
    as_grid_bounding_sphere(as_bspline_grid(bs), m, cm, &rm);
    assert_true(max_on_sphere(bs, cm, rm, 4000, &rng) < 40);
    /* Along the z axis through a voxel above 40 on the last slice, f goes below 40
     * within m voxels and stays there. */
    for (size_t i = 0; i < 128 * 128; i++)
        if (as_image_value(img, 61 * 128 * 128 + i) > 40) {
            double v[3] = {(double)(i % 128), (double)(i / 128), 61};
            assert_true(as_bspline_value_voxel(bs, v) > 40);
            for (double t = 61 + m; t < 61 + AS_BSPLINE_PAD + AS_BSPLINE_REACH + 2; t += 0.37) {
                v[2] = t;
                assert_true(as_bspline_value_voxel(bs, v) < 40);
            }
            break;
        }
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- the smoothing fit ---------------------------------------------------------------- */

/* The centred cubic B-spline. */
static double bspline3(double t) {
    t = fabs(t);
    if (t < 1) return 2.0 / 3.0 - t * t + 0.5 * t * t * t;
    if (t < 2) return (2 - t) * (2 - t) * (2 - t) / 6;
    return 0;
}

/* The extended data at integer voxel k (bspline.h): the image inside, the border faded
 * to bg outside. */
static double extended(const as_image *img, const ptrdiff_t n[3], double bg, ptrdiff_t i,
                       ptrdiff_t j, ptrdiff_t k) {
    ptrdiff_t ci = clampi(i, n[0]), cj = clampi(j, n[1]), ck = clampi(k, n[2]);
    double fade = fade_at(i - ci) * fade_at(j - cj) * fade_at(k - ck);
    return bg + (as_image_value(img, (size_t)(ci + n[0] * (cj + n[1] * ck))) - bg) * fade;
}

/* AS_BSPLINE_SMOOTH: f = b + sum_k (s(k) - b) beta3(v - k) over the extended data, so at a
 * voxel centre the (1/6, 2/3, 1/6)^3 average of its 27 neighbours, anywhere between the
 * smallest and largest data of the 4^3 around it (no overshoot), b beyond the pad; its
 * derivatives agree with differences. Checked on random images, against a direct sum. */
static void test_smoothing_fit(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {7};
    const double sp[3] = {0.9, 1.1, 1.7}, org[3] = {-2, 3, 1};
    static const size_t dims[][3] = {{9, 8, 7}, {1, 4, 3}, {2, 2, 1}};
    for (size_t t = 0; t < sizeof dims / sizeof dims[0]; t++) {
        as_image *img = random_image(f, dims[t][0], dims[t][1], dims[t][2], 0, 10, sp, org,
                                     NULL, &rng);
        const double bg = -1;
        const ptrdiff_t n[3] = {(ptrdiff_t)dims[t][0], (ptrdiff_t)dims[t][1],
                                (ptrdiff_t)dims[t][2]};
        as_bspline *bs;
        assert_int_equal(as_bspline_create_fit(f->ctx, img, bg, AS_BSPLINE_SMOOTH, &bs),
                         ANISTAR_OK);
        assert_int_equal(as_bspline_fit(bs), AS_BSPLINE_SMOOTH);
        for (int it = 0; it < 3000; it++) {
            double v[3];
            for (int a = 0; a < 3; a++)
                v[a] = tu_rng_range(&rng, -AS_BSPLINE_PAD - 3, (double)n[a] + AS_BSPLINE_PAD + 2);
            if (it % 3 == 0)
                for (int a = 0; a < 3; a++) v[a] = floor(v[a]); /* voxel centres too */
            /* the direct sum over the 4^3 (5^3 at integers) extended data around v */
            double want = bg, lo = INFINITY, hi = -INFINITY;
            ptrdiff_t b0[3];
            for (int a = 0; a < 3; a++) b0[a] = (ptrdiff_t)floor(v[a]) - 2;
            for (ptrdiff_t k = b0[2]; k <= b0[2] + 4; k++)
                for (ptrdiff_t j = b0[1]; j <= b0[1] + 4; j++)
                    for (ptrdiff_t i = b0[0]; i <= b0[0] + 4; i++) {
                        double w = bspline3(v[0] - (double)i) * bspline3(v[1] - (double)j) *
                                   bspline3(v[2] - (double)k);
                        if (w == 0) continue;
                        double e = extended(img, n, bg, i, j, k);
                        want += w * (e - bg);
                        lo = fmin(lo, e);
                        hi = fmax(hi, e);
                    }
            double fv = as_bspline_value_voxel(bs, v);
            assert_near(fv, want, 1e-12 * 10);
            assert_true(fv >= lo - 1e-12 * 10 && fv <= hi + 1e-12 * 10);
            /* derivatives against central differences */
            double g[3], h[6];
            assert_near(as_bspline_value_grad_hess_voxel(bs, v, g, h), fv, 1e-12 * 10);
            for (int a = 0; a < 3; a++) {
                const double e = 1e-5;
                double vp[3] = {v[0], v[1], v[2]}, vm[3] = {v[0], v[1], v[2]};
                vp[a] += e;
                vm[a] -= e;
                double fd = (as_bspline_value_voxel(bs, vp) - as_bspline_value_voxel(bs, vm)) /
                            (2 * e);
                assert_near(g[a], fd, 1e-5 * 10);
            }
        }
        /* b beyond the pad (the last layer's data is b: no continuation) */
        double far[3] = {-(double)AS_BSPLINE_PAD - 2.5, 1, 1};
        assert_true(as_bspline_value_voxel(bs, far) == bg);
        as_bspline_free(f->ctx, bs);
        as_image_free(f->ctx, img);
    }
    as_image *img = random_image(f, 3, 3, 3, 0, 1, sp, org, NULL, &rng);
    as_bspline *bs = NULL;
    assert_int_equal(as_bspline_create_fit(f->ctx, img, 0, 7, &bs), ANISTAR_EINVAL);
    assert_null(bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- errors and allocation failures ------------------------------------------------- */

static void test_errors(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *img;
    assert_int_equal(as_image_new(f->ctx, 3, 3, 3, AS_VOXEL_F32, &img), ANISTAR_OK);
    as_bspline *bs = (as_bspline *)(uintptr_t)1;
    assert_int_equal(as_bspline_create(f->ctx, img, NAN, &bs), ANISTAR_EINVAL);
    assert_null(bs);
    assert_non_null(strstr(anistar_last_error(f->ctx), "background"));
    ((float *)img->data)[13] = NAN;
    ((float *)img->data)[20] = INFINITY;
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_EINVAL);
    assert_null(bs);
    assert_non_null(strstr(anistar_last_error(f->ctx), "2 non-finite voxels"));
    as_image_free(f->ctx, img);
    assert_int_equal(as_bspline_create(f->ctx, NULL, 0, &bs), ANISTAR_EINVAL);
    /* Values whose coefficients overflow. */
    assert_int_equal(as_image_new(f->ctx, 3, 3, 3, AS_VOXEL_F64, &img), ANISTAR_OK);
    for (size_t i = 0; i < img->count; i++) ((double *)img->data)[i] = (i % 2 ? 1 : -1) * 1e308;
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_EINVAL);
    assert_null(bs);
    assert_non_null(strstr(anistar_last_error(f->ctx), "overflow"));
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- the lattice layers and the inner kernel --------------------------------------- */

static int same_bits(double a, double b) { return memcmp(&a, &b, sizeof a) == 0; }

/* as_bspline_layers gives, to the bit, as_bspline_value at each node's world point, on
 * axis-aligned grids (flipped axes, spacings and origins that do not round-trip exactly,
 * sizes 1 to 3 along an axis); a rotated grid gets no layers. */
static void test_layers_match_values(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {7};
    static const size_t dims[][3] = {{13, 11, 9}, {1, 5, 3}, {2, 1, 1}, {1, 1, 1}, {4, 3, 7}};
    const double sp[3] = {0.3, 1.23438, 2.66666}, org[3] = {32.0938, -0.1, 0};
    const double flip[9] = {-1, 0, 0, 0, 1, 0, 0, 0, -1};
    for (size_t t = 0; t < sizeof dims / sizeof dims[0]; t++)
        for (int fl = 0; fl < 2; fl++) {
            as_image *img = random_image(f, dims[t][0], dims[t][1], dims[t][2], -1, 2, sp, org,
                                         fl ? flip : NULL, &rng);
            as_bspline *bs;
            assert_int_equal(as_bspline_create(f->ctx, img, -0.37, &bs), ANISTAR_OK);
            as_bspline_layers *L = NULL;
            assert_int_equal(as_bspline_layers_new(f->ctx, bs, &L), ANISTAR_OK);
            assert_non_null(L);
            /* the nodes: the padded grid's voxel centers and one more on every side */
            const as_grid *pg = as_bspline_padded_grid(bs);
            assert_true(pg->n[0] == dims[t][0] + 2 * AS_BSPLINE_PAD);
            const size_t lx = pg->n[0] + 2, ly = pg->n[1] + 2, lz = pg->n[2] + 2;
            double *out = malloc(lx * ly * sizeof *out);
            assert_non_null(out);
            for (size_t k = 0; k < lz; k++) {
                as_bspline_layers_get(L, k, out);
                for (size_t j = 0; j < ly; j++)
                    for (size_t i = 0; i < lx; i++) {
                        double p[3], v[3] = {(double)i - 1, (double)j - 1, (double)k - 1};
                        as_grid_voxel_to_world(pg, v, p);
                        assert_true(same_bits(out[j * lx + i], as_bspline_value(bs, p)));
                    }
            }
            free(out);
            as_bspline_layers_free(f->ctx, L);
            as_bspline_free(f->ctx, bs);
            as_image_free(f->ctx, img);
        }
    double rot[9];
    rotation(1, -2, 0.5, 0.9, rot);
    as_image *img = random_image(f, 5, 4, 3, -1, 2, sp, org, rot, &rng);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0, &bs), ANISTAR_OK);
    as_bspline_layers *L = (as_bspline_layers *)&rng; /* must be set to NULL */
    assert_int_equal(as_bspline_layers_new(f->ctx, bs, &L), ANISTAR_OK);
    assert_null(L);
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* Value, gradient and Hessian entry points return the same value to the bit, and the
 * world ones the same gradient, at points where all 64 coefficients are stored (the
 * inner kernel), at the border and beyond it (the general path). */
static void test_inner_kernel_bits(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {11};
    const double sp[3] = {1, 1, 1}, org[3] = {0, 0, 0};
    as_image *img = random_image(f, 9, 8, 7, -1, 2, sp, org, NULL, &rng);
    as_bspline *bs;
    assert_int_equal(as_bspline_create(f->ctx, img, 0.5, &bs), ANISTAR_OK);
    for (int it = 0; it < 20000; it++) {
        double v[3];
        for (int a = 0; a < 3; a++) {
            double n = (double)img->nx * (a == 0) + (double)img->ny * (a == 1) +
                       (double)img->nz * (a == 2);
            /* about the stored grid's ends (the image's grown by the pad): inner kernel
             * on one side, the general path on the other */
            double e = tu_rng_range(&rng, 0, 1) < 0.5
                           ? floor(tu_rng_range(&rng, 0, 4)) - 1 - AS_BSPLINE_PAD
                           : n - 3 + AS_BSPLINE_PAD + floor(tu_rng_range(&rng, 0, 4));
            v[a] = it % 3 == 0 ? e : e + tu_rng_range(&rng, -0.5, 0.5);
        }
        double g[3], h[6], p[3], g1[3], g2[3], h2[6];
        double f0 = as_bspline_value_voxel(bs, v), f2 = as_bspline_value_grad_hess_voxel(bs, v, g, h);
        assert_true(same_bits(f0, f2));
        as_grid_voxel_to_world(as_bspline_grid(bs), v, p);
        double w0 = as_bspline_value(bs, p), w1 = as_bspline_value_grad(bs, p, g1),
               w2 = as_bspline_value_grad_hess(bs, p, g2, h2);
        assert_true(same_bits(w0, w1) && same_bits(w0, w2));
        for (int i = 0; i < 3; i++) assert_true(same_bits(g1[i], g2[i]));
    }
    as_bspline_free(f->ctx, bs);
    as_image_free(f->ctx, img);
    fx_free(f);
}

static void test_alloc_failures(void **state) {
    (void)state;
    long fail_at;
    for (fail_at = 1;; fail_at++) { /* allocation 0 is the context */
        tu_alloc a;
        tu_alloc_init(&a, fail_at);
        anistar_allocator al = tu_allocator(&a);
        anistar_context *ctx = anistar_context_new(&al);
        assert_non_null(ctx);
        as_image *img = NULL;
        as_bspline *bs = NULL;
        anistar_status st = as_image_read(ctx, AS_TEST_DATA_DIR "/brain_t1.mhd", &img);
        if (st == ANISTAR_OK) {
            st = as_bspline_create(ctx, img, 0, &bs);
            if (st == ANISTAR_OK) {
                double p[3] = {100, 120, 80};
                assert_true(isfinite(as_bspline_value(bs, p)));
                as_bspline_layers *L = NULL;
                st = as_bspline_layers_new(ctx, bs, &L);
                if (st == ANISTAR_OK) {
                    assert_non_null(L);
                    const as_grid *pg = as_bspline_padded_grid(bs);
                    double *row = malloc((pg->n[0] + 2) * (pg->n[1] + 2) * sizeof *row);
                    assert_non_null(row);
                    as_bspline_layers_get(L, 3, row);
                    assert_true(isfinite(row[0]));
                    free(row);
                } else {
                    assert_null(L);
                }
                as_bspline_layers_free(ctx, L);
                as_bspline_free(ctx, bs);
            } else {
                assert_null(bs);
            }
            as_image_free(ctx, img);
        }
        if (st != ANISTAR_OK) {
            assert_int_equal(st, ANISTAR_ENOMEM);
            assert_true(a.failures > 0);
        }
        anistar_context_free(ctx);
        assert_int_equal(a.live_blocks, 0);
        assert_int_equal(a.live_bytes, 0);
        if (st == ANISTAR_OK) break;
        assert_true(fail_at < 100);
    }
    assert_true(fail_at >= 5); /* reader (>= 3) + spline (2) */
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_interpolates_voxels),
        cmocka_unit_test(test_types_and_skull),
        cmocka_unit_test(test_polynomial_reproduction),
        cmocka_unit_test(test_derivatives_vs_finite_differences),
        cmocka_unit_test(test_c2_continuity_across_knots),
        cmocka_unit_test(test_background_outside),
        cmocka_unit_test(test_border_surface_closes),
        cmocka_unit_test(test_smoothing_fit),
        cmocka_unit_test(test_errors),
        cmocka_unit_test(test_layers_match_values),
        cmocka_unit_test(test_inner_kernel_bits),
        cmocka_unit_test(test_alloc_failures),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
