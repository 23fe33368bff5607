/*
 * test_metric — lib/geom/metric.c and the public anistar_tensor_* functions: frames
 * (F^T F = M, F F^-1 = I, validation), the fixed-order transform, distances, the
 * distortion against an independent computation, its symmetry and bounds, the filter of
 * as_metric_distortion_le and _over against the exact decision, the ellipsoid box, and bad input.
 *
 * The independent distortion (ref_distortion): F_M, F_N^-1, F_N, F_M^-1 are built in long
 * double from the constructed eigenframes (not from the library's eigen-solver),
 * G = F_M F_N^-1 and H = F_N F_M^-1 in long double, and lambda_max of G^T G and H^T H by
 * the power method with repeated squaring in long double (no Jacobi anywhere); then
 * gamma = sqrt(max(lambda_max(G^T G), lambda_max(H^T H))). It is cross-checked against
 * DESIGN.md's form sqrt(max(lambda_max(A), 1 / lambda_min(A))), A = G^T G, and against the
 * closed-form trigonometric solution of the characteristic cubic (Smith 1961).
 */
#include "test_util.h"

#include "anistar.h"
#include "geom/linalg.h"
#include "geom/metric.h"

#include <float.h>
#include <math.h>
#include <string.h>

typedef long double ld;

static void check_le(double x, double tol, const char *what, long iter) {
    if (!(x <= tol)) fail_msg("%s (case %ld): %.3e > %.3e", what, iter, x, tol);
}

/* A random metric: frame u (rows), F-eigenvalues e = s * (1, a^t1, a^t2), anisotropy a
 * up to amax, scale s in [1e-2, 1e2]. */
static void random_metric(tu_rng *r, double amax, double u[9], double e[3]) {
    tu_random_rotation(r, u);
    double an = pow(amax, tu_rng_unit(r));
    double s = pow(10, tu_rng_range(r, -2, 2));
    e[0] = s;
    e[1] = s * pow(an, tu_rng_unit(r));
    e[2] = s * an;
}

/* In long double: X = U diag(p) U^T with u's rows the eigenvectors, after making the rows
 * orthonormal in long double (twice Gram-Schmidt), so that the X built for p and for 1/p
 * are inverses to long double accuracy. */
static void ld_from_frame(const double u[9], const ld p[3], ld x[9]) {
    ld q[9];
    for (int k = 0; k < 9; k++) q[k] = u[k];
    for (int pass = 0; pass < 2; pass++)
        for (int k = 0; k < 3; k++) {
            for (int j = 0; j < k; j++) {
                ld d = q[3 * k] * q[3 * j] + q[3 * k + 1] * q[3 * j + 1] + q[3 * k + 2] * q[3 * j + 2];
                for (int i = 0; i < 3; i++) q[3 * k + i] -= d * q[3 * j + i];
            }
            ld n = sqrtl(q[3 * k] * q[3 * k] + q[3 * k + 1] * q[3 * k + 1] +
                         q[3 * k + 2] * q[3 * k + 2]);
            for (int i = 0; i < 3; i++) q[3 * k + i] /= n;
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            ld s = 0;
            for (int k = 0; k < 3; k++) s += q[3 * k + i] * p[k] * q[3 * k + j];
            x[3 * i + j] = s;
        }
}

static void ld_mul(const ld a[9], const ld b[9], ld c[9]) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            ld s = 0;
            for (int k = 0; k < 3; k++) s += a[3 * i + k] * b[3 * k + j];
            c[3 * i + j] = s;
        }
}

static void ld_gram(const ld g[9], ld a[9]) {
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            ld s = 0;
            for (int k = 0; k < 3; k++) s += g[3 * k + i] * g[3 * k + j];
            a[3 * i + j] = s;
        }
}

/* Eigenvalues (ascending) of a symmetric 3x3 by the trigonometric solution of the cubic. */
static void ld_sym_eig_trig(const ld a[9], ld l[3]) {
    ld p1 = a[1] * a[1] + a[2] * a[2] + a[5] * a[5];
    ld q = (a[0] + a[4] + a[8]) / 3;
    if (p1 == 0) {
        l[0] = a[0];
        l[1] = a[4];
        l[2] = a[8];
    } else {
        ld d0 = a[0] - q, d1 = a[4] - q, d2 = a[8] - q;
        ld p = sqrtl((d0 * d0 + d1 * d1 + d2 * d2 + 2 * p1) / 6);
        ld b[9];
        for (int i = 0; i < 9; i++) b[i] = (a[i] - (i % 4 == 0 ? q : 0)) / p;
        ld r = (b[0] * (b[4] * b[8] - b[5] * b[7]) - b[1] * (b[3] * b[8] - b[5] * b[6]) +
                b[2] * (b[3] * b[7] - b[4] * b[6])) /
               2;
        if (r < -1) r = -1;
        if (r > 1) r = 1;
        ld phi = acosl(r) / 3;
        l[2] = q + 2 * p * cosl(phi);
        l[0] = q + 2 * p * cosl(phi + 2.0943951023931954923L);
        l[1] = 3 * q - l[0] - l[2];
    }
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && l[j - 1] > l[j]; j--) {
            ld t = l[j];
            l[j] = l[j - 1];
            l[j - 1] = t;
        }
}

/*
 * lambda_max of a symmetric positive semi-definite 3x3 in long double by the power method
 * with repeated squaring: P = S^(2^64) (normalised after every squaring) maps everything to
 * the dominant eigenspace; the Rayleigh quotient of P's largest column with S is then
 * lambda_max to ~lambda_max / 2^64 (gap-free: the error of the quotient is at most
 * max over lambda of (lambda_1 - lambda) (lambda / lambda_1)^(2^65)).
 */
static ld ld_lambda_max_power(const ld s[9]) {
    ld p[9], t[9];
    memcpy(p, s, sizeof p);
    for (int it = 0; it < 64; it++) {
        ld_mul(p, p, t);
        ld mx = 0;
        for (int k = 0; k < 9; k++) mx = fmaxl(mx, fabsl(t[k]));
        if (mx == 0) return 0;
        for (int k = 0; k < 9; k++) p[k] = t[k] / mx;
    }
    int c = 0;
    ld best = -1;
    for (int j = 0; j < 3; j++) {
        ld n = p[j] * p[j] + p[3 + j] * p[3 + j] + p[6 + j] * p[6 + j];
        if (n > best) {
            best = n;
            c = j;
        }
    }
    ld x[3] = {p[c], p[3 + c], p[6 + c]}, num = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) num += x[i] * s[3 * i + j] * x[j];
    return num / best;
}

/* Inverse of a 3x3 in long double by cofactors. */
static void ld_inverse(const ld a[9], ld b[9]) {
    b[0] = a[4] * a[8] - a[5] * a[7];
    b[1] = a[2] * a[7] - a[1] * a[8];
    b[2] = a[1] * a[5] - a[2] * a[4];
    b[3] = a[5] * a[6] - a[3] * a[8];
    b[4] = a[0] * a[8] - a[2] * a[6];
    b[5] = a[2] * a[3] - a[0] * a[5];
    b[6] = a[3] * a[7] - a[4] * a[6];
    b[7] = a[1] * a[6] - a[0] * a[7];
    b[8] = a[0] * a[4] - a[1] * a[3];
    ld det = a[0] * b[0] + a[1] * b[3] + a[2] * b[6];
    for (int k = 0; k < 9; k++) b[k] /= det;
}

/*
 * The independent gamma of two metrics given by their frames, in long double:
 * sqrt(max(lambda_max(G^T G), lambda_max(H^T H))) by the power method.
 * *alt: DESIGN's form sqrt(max(lambda_max(A), 1 / lambda_min(A))), A = G^T G, with
 * 1 / lambda_min(A) = lambda_max(A^-1) (cofactor inverse; accurate to ~eps_ld cond(A)).
 * *trig: the first form with the eigenvalues from the trigonometric cubic solution
 * (accurate to ~sqrt(eps_ld) when eigenvalues nearly coincide).
 */
static double ref_distortion(const double um[9], const double em[3], const double un[9],
                             const double en[3], double *alt, double *trig) {
    ld pm[3], pmi[3], pn[3], pni[3];
    for (int k = 0; k < 3; k++) {
        pm[k] = em[k];
        pmi[k] = 1 / (ld)em[k];
        pn[k] = en[k];
        pni[k] = 1 / (ld)en[k];
    }
    ld fm[9], fmi[9], fn[9], fni[9], g[9], h[9], ga[9], gb[9], gai[9], la[3], lb[3];
    ld_from_frame(um, pm, fm);
    ld_from_frame(um, pmi, fmi);
    ld_from_frame(un, pn, fn);
    ld_from_frame(un, pni, fni);
    ld_mul(fm, fni, g);
    ld_mul(fn, fmi, h);
    ld_gram(g, ga);
    ld_gram(h, gb);
    ld_inverse(ga, gai);
    ld ma = ld_lambda_max_power(ga), mb = ld_lambda_max_power(gb);
    if (alt) *alt = (double)sqrtl(fmaxl(ma, ld_lambda_max_power(gai)));
    if (trig) {
        ld_sym_eig_trig(ga, la);
        ld_sym_eig_trig(gb, lb);
        *trig = (double)sqrtl(fmaxl(la[2], lb[2]));
    }
    return (double)sqrtl(fmaxl(ma, mb));
}

static void init_from(as_metric_frame *mf, const double u[9], const double e[3]) {
    /* M = U diag(e^2) U^T, rounded to doubles, then the frame from M. */
    double w[3] = {e[0] * e[0], e[1] * e[1], e[2] * e[2]}, m[6];
    as_sym3_from_eigen(w, u, m);
    assert_int_equal(as_metric_frame_init(mf, m), 0);
}

/* ---- frames ------------------------------------------------------------------------- */

/* F^T F = M within 1e-13 relative, F symmetric, F F^-1 = I, e^2 = eigenvalues of M. */
static void test_frame_init(void **state) {
    (void)state;
    tu_rng r = {21};
    for (long it = 0; it < 50000; it++) {
        double u[9], e[3], m[6];
        double amax = it % 2 ? 100 : 1e6;
        random_metric(&r, amax, u, e);
        double w[3] = {e[0] * e[0], e[1] * e[1], e[2] * e[2]};
        as_sym3_from_eigen(w, u, m);
        as_metric_frame mf;
        assert_int_equal(as_metric_frame_init(&mf, m), 0);
        assert_memory_equal(mf.m, m, sizeof m);
        double mn = 0;
        for (int k = 0; k < 6; k++) mn = fmax(mn, fabs(m[k]));
        ld cond = (ld)mf.e[2] / mf.e[0];
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                assert_true(mf.f[3 * i + j] == mf.f[3 * j + i]);
                assert_true(mf.finv[3 * i + j] == mf.finv[3 * j + i]);
                ld ff = 0, fi = 0;
                for (int k = 0; k < 3; k++) {
                    ff += (ld)mf.f[3 * k + i] * mf.f[3 * k + j];
                    fi += (ld)mf.f[3 * i + k] * mf.finv[3 * k + j];
                }
                int e6 = i <= j ? (i == 0 ? j : (i == 1 ? 2 + j : 5))
                                : (j == 0 ? i : (j == 1 ? 2 + i : 5));
                check_le((double)fabsl(ff - m[e6]) / mn, 1e-13, "F^T F = M", it);
                /* F F^-1 = I up to eps * cond(F). */
                check_le((double)fabsl(fi - (i == j)), 1e-13 + 1e-15 * (double)cond,
                         "F F^-1 = I", it);
            }
        assert_true(mf.e[0] > 0 && mf.e[0] <= mf.e[1] && mf.e[1] <= mf.e[2]);
        for (int k = 0; k < 3; k++)
            check_le(fabs(mf.e[k] * mf.e[k] - w[k]) / w[2], 1e-13, "e^2 = lambda", it);
    }
}

/* F F^-1 = I within 1e-13 on moderately anisotropic metrics (anisotropy <= 100). */
static void test_frame_inverse(void **state) {
    (void)state;
    tu_rng r = {22};
    for (long it = 0; it < 50000; it++) {
        double u[9], e[3];
        random_metric(&r, 100, u, e);
        as_metric_frame mf;
        init_from(&mf, u, e);
        double p[9];
        as_mat3_mul(mf.f, mf.finv, p);
        for (int k = 0; k < 9; k++)
            check_le(fabs(p[k] - (k % 4 == 0 ? 1 : 0)), 1e-13, "F F^-1 = I (double)", it);
        double x[3] = {tu_rng_gauss(&r), tu_rng_gauss(&r), tu_rng_gauss(&r)}, y[3], z[3];
        as_metric_apply(&mf, x, y);
        as_metric_unapply(&mf, y, z);
        for (int k = 0; k < 3; k++) check_le(fabs(z[k] - x[k]), 1e-12, "unapply(apply)", it);
    }
}

static void test_frame_from_eigen(void **state) {
    (void)state;
    tu_rng r = {23};
    for (long it = 0; it < 20000; it++) {
        double u[9], e[3];
        random_metric(&r, 1000, u, e);
        /* Shuffle the pairs: from_eigen sorts them. */
        int p = (int)(tu_rng_u64(&r) % 3);
        double us[9], es[3];
        for (int k = 0; k < 3; k++) {
            int kk = (k + p) % 3;
            es[k] = e[kk];
            memcpy(us + 3 * k, u + 3 * kk, 3 * sizeof(double));
        }
        as_metric_frame a, b;
        assert_int_equal(as_metric_frame_from_eigen(&a, us, es), 0);
        assert_memory_equal(a.e, e, sizeof e);
        assert_memory_equal(a.u, u, sizeof u);
        init_from(&b, u, e);
        /* Two frames of the same metric: nearly equal F, gamma ~ 1. */
        double fn = e[2];
        for (int k = 0; k < 9; k++) check_le(fabs(a.f[k] - b.f[k]) / fn, 1e-13, "F", it);
        double gm = as_metric_distortion(&a, &b);
        assert_true(gm >= 1);
        check_le(gm - 1, 1e-15 * (e[2] / e[0]) * (e[2] / e[0]) + 1e-14, "gamma(M, M')", it);
        /* F^T F = M for the frame built from the eigen-decomposition too. */
        double f2[6];
        as_mat3_gram(a.f, f2);
        for (int k = 0; k < 6; k++)
            check_le(fabs(f2[k] - a.m[k]) / (e[2] * e[2]), 1e-13, "from_eigen F^T F", it);
    }
    /* Validation. */
    double id[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    as_metric_frame mf;
    double bad_e[][3] = {{0, 1, 1}, {-1, 1, 1}, {NAN, 1, 1}, {1, INFINITY, 1}, {1, 1, 1.01e12},
                         {1e-320, 1, 1}, {1e200, 1e200, 1e200}};
    for (size_t k = 0; k < sizeof bad_e / sizeof bad_e[0]; k++) {
        assert_int_equal(as_metric_frame_from_eigen(&mf, id, bad_e[k]), -1);
        for (int i = 0; i < 3; i++) assert_true(mf.e[i] == 0);
    }
    double ok_e[3] = {1, 1, 0.99e12};
    assert_int_equal(as_metric_frame_from_eigen(&mf, id, ok_e), 0);
    double skew[9] = {1, 0, 0, 0, 1, 1e-6, 0, 0, 1}, nanu[9] = {1, 0, 0, 0, 1, 0, 0, 0, NAN};
    double one[3] = {1, 2, 3};
    assert_int_equal(as_metric_frame_from_eigen(&mf, skew, one), -1);
    assert_int_equal(as_metric_frame_from_eigen(&mf, nanu, one), -1);
}

static void test_frame_validation(void **state) {
    (void)state;
    as_metric_frame mf;
    const double bad[][6] = {
        {NAN, 0, 0, 1, 0, 1},  {1, 0, 0, INFINITY, 0, 1}, {1, 0, 0, 1, 0, -1}, /* negative */
        {0, 0, 0, 0, 0, 0},    {1, 0, 0, 1, 0, 0},        {0, 1, 0, 0, 0, 1},  /* indefinite */
        {1, 2, 0, 1, 0, 1},    {1, 0, 0, 1, 0, 1e-25},    {1e300, 0, 0, 1e300, 0, 1e-300},
        {-1, 0, 0, -1, 0, -1}, {1, 1, 1, 1, 1, 1}, /* rank 1 */
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++)
        assert_int_equal(as_metric_frame_init(&mf, bad[k]), -1);
    const double good[][6] = {
        {1, 0, 0, 1, 0, 1e-23}, {1e300, 0, 0, 1e300, 0, 1e300}, {1e-300, 0, 0, 1e-300, 0, 1e-300},
        {2, 1, 0, 2, 0, 1}, {1, 0.5, 0.5, 1, 0.5, 1},
    };
    for (size_t k = 0; k < sizeof good / sizeof good[0]; k++)
        assert_int_equal(as_metric_frame_init(&mf, good[k]), 0);
    /* Diagonal input: exact square root. */
    double d[6] = {4, 0, 0, 9, 0, 0.25};
    assert_int_equal(as_metric_frame_init(&mf, d), 0);
    assert_true(mf.e[0] == 0.5 && mf.e[1] == 2 && mf.e[2] == 3);
    assert_true(mf.f[0] == 2 && mf.f[4] == 3 && mf.f[8] == 0.5 && mf.f[1] == 0);
    assert_true(mf.finv[0] == 0.5 && mf.finv[8] == 2);
}

/* apply uses one fixed expression order; dist(a, b) = dist(b, a) bit for bit and matches
 * sqrt((a-b)^T M (a-b)); no spurious overflow. */
static void test_apply_and_dist(void **state) {
    (void)state;
    tu_rng r = {24};
    for (long it = 0; it < 50000; it++) {
        double u[9], e[3];
        random_metric(&r, 1000, u, e);
        as_metric_frame mf;
        init_from(&mf, u, e);
        double x[3], y[3], a[3], b[3];
        for (int k = 0; k < 3; k++) {
            x[k] = tu_rng_range(&r, -10, 10);
            a[k] = tu_rng_range(&r, -10, 10);
            b[k] = tu_rng_range(&r, -10, 10);
        }
        as_metric_apply(&mf, x, y);
        const double *f = mf.f;
        for (int i = 0; i < 3; i++) {
            double want = f[3 * i] * x[0] + f[3 * i + 1] * x[1];
            want = want + f[3 * i + 2] * x[2];
            assert_true(y[i] == want);
        }
        /* In place. */
        double xx[3] = {x[0], x[1], x[2]};
        as_metric_apply(&mf, xx, xx);
        assert_memory_equal(xx, y, sizeof y);
        double d1 = as_metric_dist(&mf, a, b), d2 = as_metric_dist(&mf, b, a);
        assert_true(d1 == d2);
        ld dv[3] = {(ld)a[0] - b[0], (ld)a[1] - b[1], (ld)a[2] - b[2]}, q = 0;
        double m9[9];
        as_sym3_to_mat3(mf.m, m9);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) q += dv[i] * m9[3 * i + j] * dv[j];
        /* Relative accuracy of d ~ eps cond(F) (the smallest direction of M). */
        check_le(fabs(d1 - (double)sqrtl(q)) / d1, 1e-14 * (e[2] / e[0]) + 1e-13, "dist", it);
    }
    /* Huge and tiny stretched vectors do not overflow or underflow. */
    as_metric_frame big, tiny;
    double mb[6] = {1e200, 0, 0, 1e200, 0, 1e200}, mt[6] = {1e-200, 0, 0, 1e-200, 0, 1e-200};
    assert_int_equal(as_metric_frame_init(&big, mb), 0);
    assert_int_equal(as_metric_frame_init(&tiny, mt), 0);
    double o[3] = {0, 0, 0}, p[3] = {1e60, 1e60, 1e60}, t[3] = {1e-60, 1e-60, 1e-60};
    check_le(fabs(as_metric_dist(&big, o, p) / (1e160 * sqrt(3)) - 1), 1e-14, "big", 0);
    check_le(fabs(as_metric_dist(&tiny, o, t) / (1e-160 * sqrt(3)) - 1), 1e-14, "tiny", 0);
    assert_true(as_metric_dist(&big, p, p) == 0);
}

/* ---- distortion --------------------------------------------------------------------- */

/* Against the independent long double computation; symmetric; >= 1; gamma(M, M) = 1. */
static void test_distortion_reference(void **state) {
    (void)state;
    tu_rng r = {25};
    for (long it = 0; it < 30000; it++) {
        double um[9], em[3], un[9], en[3];
        double amax = it % 3 == 0 ? 10 : (it % 3 == 1 ? 100 : 1000);
        random_metric(&r, amax, um, em);
        if (it % 4 == 0) {
            /* A nearby metric: small rotation and rescaling of the same frame. */
            memcpy(un, um, sizeof un);
            for (int k = 0; k < 3; k++) en[k] = em[k] * tu_rng_range(&r, 0.7, 1.4);
        } else {
            random_metric(&r, amax, un, en);
        }
        as_metric_frame a, b;
        assert_int_equal(as_metric_frame_from_eigen(&a, um, em), 0);
        assert_int_equal(as_metric_frame_from_eigen(&b, un, en), 0);
        double alt, trig, ref = ref_distortion(um, em, un, en, &alt, &trig);
        double g = as_metric_distortion(&a, &b), gr = as_metric_distortion(&b, &a);
        assert_true(g == gr);
        assert_true(g >= 1);
        /* Both built from the same frames, so the only error is rounding in F (~eps
         * cond(F_a) cond(F_b) relative to gamma at worst). */
        double ca = a.e[2] / a.e[0], cb = b.e[2] / b.e[0];
        double tol = 1e-14 + 4e-16 * fmax(ca, cb) * fmin(fmax(ca, cb), 10);
        check_le(fabs(g - ref) / ref, tol, "gamma vs trig reference", it);
        /* The form with 1 / lambda_min(A) loses ~eps_ld cond(A) <= eps_ld gamma^4 (and
         * more through the cofactor inverse): compare where that is small. */
        if (ref <= 30)
            check_le(fabs(alt - ref) / ref, 4.5e-16 + 1e-15 * pow(ref, 4),
                     "reference: the two forms agree", it);
        check_le(fabs(trig - ref) / ref, 1e-8, "reference: power method vs trig", it);
        assert_true(as_metric_distortion(&a, &a) == 1);
        assert_true(as_metric_distortion(&b, &b) == 1);
    }
}

/* Exactly known distortions: diagonal and rotated-axis cases. */
static void test_distortion_known(void **state) {
    (void)state;
    as_metric_frame a, b;
    double id[6] = {1, 0, 0, 1, 0, 1};
    assert_int_equal(as_metric_frame_init(&b, id), 0);
    /* gamma(diag(s^2), I) = max(s, 1/s) for every axis and scale. */
    const double s[] = {1.5, 0.25, 3, 1e3, 1e-3, 2};
    for (size_t k = 0; k < sizeof s / sizeof s[0]; k++)
        for (int ax = 0; ax < 3; ax++) {
            double m[6] = {1, 0, 0, 1, 0, 1};
            m[ax == 0 ? 0 : (ax == 1 ? 3 : 5)] = s[k] * s[k];
            assert_int_equal(as_metric_frame_init(&a, m), 0);
            double want = s[k] > 1 ? s[k] : 1 / s[k];
            assert_true(fabs(as_metric_distortion(&a, &b) - want) <= 1e-15 * want);
        }
    /* Two ellipsoids with swapped axes: M = diag(4, 1, 1), N = diag(1, 4, 1): gamma = 2. */
    double m1[6] = {4, 0, 0, 1, 0, 1}, m2[6] = {1, 0, 0, 4, 0, 1};
    assert_int_equal(as_metric_frame_init(&a, m1), 0);
    assert_int_equal(as_metric_frame_init(&b, m2), 0);
    assert_true(as_metric_distortion(&a, &b) == 2);
    /* Uniform scaling: gamma(cM, M) = sqrt(c). */
    tu_rng r = {26};
    for (long it = 0; it < 5000; it++) {
        double u[9], e[3], e2[3];
        random_metric(&r, 100, u, e);
        double c = tu_rng_range(&r, 1, 4);
        for (int k = 0; k < 3; k++) e2[k] = e[k] * c;
        assert_int_equal(as_metric_frame_from_eigen(&a, u, e), 0);
        assert_int_equal(as_metric_frame_from_eigen(&b, u, e2), 0);
        check_le(fabs(as_metric_distortion(&a, &b) / c - 1), 1e-13, "gamma(cM, M)", it);
    }
}

/* 1/gamma d_M <= d_N <= gamma d_M on random vectors (the defining property, paper 2.2),
 * and the bound is nearly attained along the top singular direction. */
static void test_distortion_distance_bounds(void **state) {
    (void)state;
    tu_rng r = {27};
    for (long it = 0; it < 20000; it++) {
        double um[9], em[3], un[9], en[3];
        random_metric(&r, 10, um, em);
        random_metric(&r, 10, un, en);
        as_metric_frame a, b;
        init_from(&a, um, em);
        init_from(&b, un, en);
        double g = as_metric_distortion(&a, &b);
        double worst = 0;
        for (int t = 0; t < 20; t++) {
            double p[3], q[3] = {0, 0, 0};
            for (int k = 0; k < 3; k++) p[k] = tu_rng_gauss(&r);
            double dm = as_metric_dist(&a, p, q), dn = as_metric_dist(&b, p, q);
            check_le(dn, g * dm * (1 + 1e-13), "d_N <= gamma d_M", it);
            check_le(dm, g * dn * (1 + 1e-13), "d_M <= gamma d_N", it);
            worst = fmax(worst, fmax(dn / dm, dm / dn));
        }
        assert_true(worst <= g * (1 + 1e-13));
    }
}

/* The filter never contradicts the exact value, and as_metric_distortion_le equals
 * (as_metric_distortion <= g) except within 1e-13 of the boundary. A realistic mix:
 * anisotropy up to 10, pairs near gamma 1.5 (nearby metrics) and random pairs. */
static void test_distortion_filter(void **state) {
    (void)state;
    tu_rng r = {28};
    const double gs[] = {1.0, 1.1, 1.5, 2, 3, 10, 1e3};
    long settled = 0, total = 0;
    for (long it = 0; it < 100000; it++) {
        double um[9], em[3], un[9], en[3];
        random_metric(&r, 10, um, em);
        if (it % 2) {
            random_metric(&r, 10, un, en);
        } else {
            /* Perturb: rotate the frame slightly and rescale the axes. */
            double q[9];
            tu_random_rotation(&r, q);
            double t = tu_rng_range(&r, 0, 0.3);
            for (int k = 0; k < 9; k++) un[k] = um[k] + t * q[k];
            /* Re-orthonormalise (Gram-Schmidt) to a valid frame. */
            for (int k = 0; k < 3; k++) {
                for (int j = 0; j < k; j++) {
                    double d = un[3 * k] * un[3 * j] + un[3 * k + 1] * un[3 * j + 1] +
                               un[3 * k + 2] * un[3 * j + 2];
                    for (int i = 0; i < 3; i++) un[3 * k + i] -= d * un[3 * j + i];
                }
                double n = sqrt(un[3 * k] * un[3 * k] + un[3 * k + 1] * un[3 * k + 1] +
                                un[3 * k + 2] * un[3 * k + 2]);
                for (int i = 0; i < 3; i++) un[3 * k + i] /= n;
            }
            for (int k = 0; k < 3; k++) en[k] = em[k] * pow(1.5, tu_rng_range(&r, -1.2, 1.2));
        }
        as_metric_frame a, b;
        assert_int_equal(as_metric_frame_from_eigen(&a, um, em), 0);
        assert_int_equal(as_metric_frame_from_eigen(&b, un, en), 0);
        double gam = as_metric_distortion(&a, &b);
        for (size_t k = 0; k < sizeof gs / sizeof gs[0]; k++) {
            double g = gs[k];
            int f = as_metric_distortion_filter(&a, &b, g);
            int le = as_metric_distortion_le(&a, &b, g);
            int le2 = as_metric_distortion_le(&b, &a, g);
            int exact = gam <= g;
            assert_true(f == -1 || f == 0 || f == 1);
            if (f >= 0) {
                total++, settled++;
                assert_int_equal(f, le);
            } else {
                /* Undecided: le runs as_metric_distortion's own computation. */
                total++;
                assert_int_equal(le, exact);
            }
            if (le != exact || le2 != exact) {
                if (!(fabs(gam / g - 1) < 1e-13))
                    fail_msg("case %ld g %g: gamma %.17g, le %d %d, filter %d", it, g, gam, le,
                             le2, f);
            }
            /* as_metric_distortion_over: 0 where the filter proves gamma <= g, else
             * gamma itself, the bits of as_metric_distortion (g >= 1 here) */
            double over = as_metric_distortion_over(&a, &b, g);
            if (f == 1) assert_true(over == 0);
            else assert_true(over == gam);
            if (f == 1) check_le(gam, g * (1 + 1e-13), "filter accepted gamma > g", it);
            if (f == 0) check_le(g, gam * (1 + 1e-13), "filter rejected gamma <= g", it);
        }
    }
    /* The filter must settle most pairs (it is the point of it). */
    assert_true(settled > total / 2);
}

/* Thresholds just above and just below gamma: the filter (its exact Budan-Fourier stage)
 * must decide them right down to 1e-12 relative, and as_metric_distortion_le always. */
static void test_distortion_le_near(void **state) {
    (void)state;
    tu_rng r = {32};
    const double rel[] = {1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12};
    long undecided = 0, asked = 0;
    for (long it = 0; it < 20000; it++) {
        double um[9], em[3], un[9], en[3];
        random_metric(&r, it % 2 ? 10 : 100, um, em);
        random_metric(&r, it % 2 ? 10 : 100, un, en);
        if (it % 3 == 0) memcpy(un, um, sizeof un); /* coaxial: repeated structure */
        as_metric_frame a, b;
        assert_int_equal(as_metric_frame_from_eigen(&a, um, em), 0);
        assert_int_equal(as_metric_frame_from_eigen(&b, un, en), 0);
        double gam = as_metric_distortion(&a, &b);
        for (size_t k = 0; k < sizeof rel / sizeof rel[0]; k++) {
            double hi = gam * (1 + rel[k]), lo = gam * (1 - rel[k]);
            int fh = as_metric_distortion_filter(&a, &b, hi);
            int fl = lo >= 1 ? as_metric_distortion_filter(&a, &b, lo) : 0;
            asked += 2;
            undecided += (fh < 0) + (fl < 0);
            if (fh == 0) fail_msg("case %ld: filter rejects g = gamma (1 + %g)", it, rel[k]);
            if (fl == 1) fail_msg("case %ld: filter accepts g = gamma (1 - %g)", it, rel[k]);
            assert_int_equal(as_metric_distortion_le(&a, &b, hi), 1);
            assert_int_equal(as_metric_distortion_le(&b, &a, hi), 1);
            if (lo >= 1) {
                assert_int_equal(as_metric_distortion_le(&a, &b, lo), 0);
                assert_int_equal(as_metric_distortion_le(&b, &a, lo), 0);
            }
            /* Down to 1e-10 the filter settles (nearly) everything by itself. */
            if (rel[k] >= 1e-10 && it % 3 != 0) {
                if (fh < 0) fail_msg("case %ld: undecided at g = gamma (1 + %g)", it, rel[k]);
                if (fl < 0 && lo >= 1)
                    fail_msg("case %ld: undecided at g = gamma (1 - %g)", it, rel[k]);
            }
        }
    }
    /* Most queries, even at 1e-12 from the boundary, need no eigen-solve. */
    assert_true(undecided < asked / 10);
}

/* Pairs exactly at the boundary: gamma(diag(g^2, 1, 1), I) = g exactly. */
static void test_distortion_le_boundary(void **state) {
    (void)state;
    as_metric_frame a, b, c;
    double id[6] = {1, 0, 0, 1, 0, 1}, m[6] = {2.25, 0, 0, 1, 0, 1};
    assert_int_equal(as_metric_frame_init(&a, m), 0);
    assert_int_equal(as_metric_frame_init(&b, id), 0);
    assert_true(as_metric_distortion(&a, &b) == 1.5);
    assert_int_equal(as_metric_distortion_le(&a, &b, 1.5), 1);
    assert_int_equal(as_metric_distortion_le(&b, &a, 1.5), 1);
    assert_int_equal(as_metric_distortion_le(&a, &b, nextafter(1.5, 0)), 0);
    assert_int_equal(as_metric_distortion_le(&a, &b, nextafter(1.5, 2)), 1);
    /* The same frame: gamma = 1 <= g for any g >= 1; g < 1 or NaN: 0. */
    assert_int_equal(as_metric_distortion_le(&a, &a, 1), 1);
    assert_int_equal(as_metric_distortion_le(&a, &b, 0.5), 0);
    assert_int_equal(as_metric_distortion_le(&a, &b, NAN), 0);
    assert_int_equal(as_metric_distortion_le(&a, &b, INFINITY), 1);
    assert_int_equal(as_metric_distortion_le(&a, &b, 1e300), 1);
    /* Equal metrics held in two frames: gamma exactly 1. */
    assert_int_equal(as_metric_frame_init(&c, m), 0);
    assert_true(as_metric_distortion(&a, &c) == 1);
    assert_int_equal(as_metric_distortion_le(&a, &c, 1), 1);
}

/* Metrics of wildly different scales: the Gram matrices are rescaled, no overflow. */
static void test_distortion_range(void **state) {
    (void)state;
    tu_rng r = {31};
    for (long it = 0; it < 3000; it++) {
        double um[9], em[3], un[9], en[3];
        random_metric(&r, 10, um, em);
        random_metric(&r, 10, un, en);
        double sa = pow(10, tu_rng_range(&r, -140, 140)), sb = pow(10, tu_rng_range(&r, -140, 140));
        double ema[3], enb[3];
        for (int k = 0; k < 3; k++) {
            ema[k] = em[k] * sa;
            enb[k] = en[k] * sb;
        }
        as_metric_frame a, b;
        assert_int_equal(as_metric_frame_from_eigen(&a, um, ema), 0);
        assert_int_equal(as_metric_frame_from_eigen(&b, un, enb), 0);
        double ref = ref_distortion(um, ema, un, enb, NULL, NULL);
        double g = as_metric_distortion(&a, &b);
        assert_true(isfinite(g));
        check_le(fabs(g - ref) / ref, 1e-13, "gamma at extreme scales", it);
        assert_true(g == as_metric_distortion(&b, &a));
        const double f[4] = {0.5, 0.999, 1.001, 2};
        for (int k = 0; k < 4; k++) {
            double gg = g * f[k];
            if (gg < 1) continue;
            int le = as_metric_distortion_le(&a, &b, gg);
            assert_int_equal(le, f[k] > 1);
            int fl = as_metric_distortion_filter(&a, &b, gg);
            assert_true(fl == -1 || fl == le);
        }
    }
    /* Exactly: gamma(1e200 I, 1e-200 I) = 1e200. */
    as_metric_frame a, b;
    double ma[6] = {1e200, 0, 0, 1e200, 0, 1e200}, mb[6] = {1e-200, 0, 0, 1e-200, 0, 1e-200};
    assert_int_equal(as_metric_frame_init(&a, ma), 0);
    assert_int_equal(as_metric_frame_init(&b, mb), 0);
    check_le(fabs(as_metric_distortion(&a, &b) / 1e200 - 1), 1e-15, "1e200", 0);
    assert_int_equal(as_metric_distortion_le(&a, &b, 1e199), 0);
    assert_int_equal(as_metric_distortion_le(&a, &b, 1e201), 1);
}

/* ---- ellipsoid box ------------------------------------------------------------------ */

/* h_i = r |row_i(F^-1)| = r sqrt((M^-1)_ii); every boundary point x = c + F^-1 y, |y| = r,
 * lies in the box, and the extreme point along each axis reaches it. */
static void test_ellipsoid_box(void **state) {
    (void)state;
    tu_rng r = {29};
    for (long it = 0; it < 20000; it++) {
        double u[9], e[3], h[3];
        random_metric(&r, 1000, u, e);
        as_metric_frame mf;
        assert_int_equal(as_metric_frame_from_eigen(&mf, u, e), 0);
        double rad = tu_rng_range(&r, 0.1, 10);
        as_metric_ellipsoid_box(&mf, rad, h);
        ld pinv[3] = {1 / ((ld)e[0] * e[0]), 1 / ((ld)e[1] * e[1]), 1 / ((ld)e[2] * e[2])};
        ld minv[9];
        ld_from_frame(u, pinv, minv);
        for (int i = 0; i < 3; i++) {
            double want = (double)(rad * sqrtl(minv[4 * i]));
            check_le(fabs(h[i] - want) / want, 1e-14, "box vs M^-1", it);
            /* The extreme point: y = r row_i(F^-1) / |row_i(F^-1)|, x - c = F^-1 y. */
            const double *row = mf.finv + 3 * i;
            double n = sqrt(row[0] * row[0] + row[1] * row[1] + row[2] * row[2]);
            double y[3] = {rad * row[0] / n, rad * row[1] / n, rad * row[2] / n}, x[3];
            as_metric_unapply(&mf, y, x);
            check_le(fabs(x[i] - h[i]) / h[i], 1e-13, "box attained", it);
        }
        for (int t = 0; t < 10; t++) {
            double y[3] = {tu_rng_gauss(&r), tu_rng_gauss(&r), tu_rng_gauss(&r)}, x[3];
            double n = sqrt(y[0] * y[0] + y[1] * y[1] + y[2] * y[2]);
            for (int k = 0; k < 3; k++) y[k] *= rad / n;
            as_metric_unapply(&mf, y, x);
            for (int k = 0; k < 3; k++) check_le(fabs(x[k]), h[k] * (1 + 1e-13), "inside", it);
        }
    }
}

/* ---- public API --------------------------------------------------------------------- */

static void test_api_tensor_valid(void **state) {
    (void)state;
    tu_alloc al;
    tu_alloc_init(&al, -1);
    anistar_allocator aa = tu_allocator(&al);
    anistar_context *ctx = anistar_context_new(&aa);
    assert_non_null(ctx);
    tu_rng r = {30};
    for (long it = 0; it < 2000; it++) {
        double um[9], em[3], un[9], en[3], m[6], n[6];
        random_metric(&r, 100, um, em);
        random_metric(&r, 100, un, en);
        double wm[3] = {em[0] * em[0], em[1] * em[1], em[2] * em[2]};
        double wn[3] = {en[0] * en[0], en[1] * en[1], en[2] * en[2]};
        as_sym3_from_eigen(wm, um, m);
        as_sym3_from_eigen(wn, un, n);
        double g, g2, f[6], d, d2;
        assert_int_equal(anistar_tensor_distortion(ctx, m, n, &g), ANISTAR_OK);
        assert_int_equal(anistar_tensor_distortion(ctx, n, m, &g2), ANISTAR_OK);
        assert_true(g == g2 && g >= 1);
        double ref = ref_distortion(um, em, un, en, NULL, NULL);
        /* M and N were rounded to doubles: the sensitivity is ~eps cond(M)... */
        check_le(fabs(g - ref) / ref, 1e-10, "api distortion", it);
        assert_int_equal(anistar_tensor_sqrt(ctx, m, f), ANISTAR_OK);
        /* F^2 = M from the 6 public entries. */
        double f9[9], f2[9], mm[9];
        as_sym3_to_mat3(f, f9);
        as_mat3_mul(f9, f9, f2);
        as_sym3_to_mat3(m, mm);
        for (int k = 0; k < 9; k++)
            check_le(fabs(f2[k] - mm[k]) / wm[2], 1e-13, "api sqrt: F^2 = M", it);
        double a[3] = {tu_rng_gauss(&r), tu_rng_gauss(&r), tu_rng_gauss(&r)}, b[3] = {tu_rng_gauss(&r), tu_rng_gauss(&r), tu_rng_gauss(&r)};
        assert_int_equal(anistar_tensor_distance(ctx, m, a, b, &d), ANISTAR_OK);
        assert_int_equal(anistar_tensor_distance(ctx, m, b, a, &d2), ANISTAR_OK);
        assert_true(d == d2 && d > 0);
        ld q = 0, dv[3] = {(ld)a[0] - b[0], (ld)a[1] - b[1], (ld)a[2] - b[2]};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) q += dv[i] * mm[3 * i + j] * dv[j];
        check_le(fabs(d - (double)sqrtl(q)) / d, 1e-11, "api distance", it);
    }
    anistar_context_free(ctx);
    assert_int_equal(al.live_blocks, 0);
}

static void expect_einval(anistar_context *ctx, anistar_status st, const char *what) {
    if (st != ANISTAR_EINVAL) fail_msg("%s: status %d, want EINVAL", what, (int)st);
    assert_int_equal(anistar_last_status(ctx), ANISTAR_EINVAL);
    const char *msg = anistar_last_error(ctx);
    assert_non_null(msg);
    if (msg[0] == '\0') fail_msg("%s: empty error message", what);
}

static void test_api_tensor_bad_input(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    double id[6] = {1, 0, 0, 1, 0, 1}, p[3] = {0, 0, 0}, q[3] = {1, 1, 1};
    double g = -7, d = -7, f[6] = {-7, -7, -7, -7, -7, -7};
    /* NULL context: EINVAL, no crash. */
    assert_int_equal(anistar_tensor_distortion(NULL, id, id, &g), ANISTAR_EINVAL);
    assert_int_equal(anistar_tensor_distance(NULL, id, p, q, &d), ANISTAR_EINVAL);
    assert_int_equal(anistar_tensor_sqrt(NULL, id, f), ANISTAR_EINVAL);
    /* NULL arguments. */
    expect_einval(ctx, anistar_tensor_distortion(ctx, NULL, id, &g), "distortion m NULL");
    expect_einval(ctx, anistar_tensor_distortion(ctx, id, NULL, &g), "distortion n NULL");
    expect_einval(ctx, anistar_tensor_distortion(ctx, id, id, NULL), "distortion out NULL");
    expect_einval(ctx, anistar_tensor_distance(ctx, NULL, p, q, &d), "distance m NULL");
    expect_einval(ctx, anistar_tensor_distance(ctx, id, NULL, q, &d), "distance a NULL");
    expect_einval(ctx, anistar_tensor_distance(ctx, id, p, NULL, &d), "distance b NULL");
    expect_einval(ctx, anistar_tensor_distance(ctx, id, p, q, NULL), "distance out NULL");
    expect_einval(ctx, anistar_tensor_sqrt(ctx, NULL, f), "sqrt m NULL");
    expect_einval(ctx, anistar_tensor_sqrt(ctx, id, NULL), "sqrt out NULL");
    /* Tensors that are not metrics. */
    const double bad[][6] = {
        {NAN, 0, 0, 1, 0, 1},      {1, 0, 0, 1, NAN, 1},     {1, 0, 0, 1, 0, INFINITY},
        {1, -INFINITY, 0, 1, 0, 1}, {1, 0, 0, 1, 0, -1},     {-1, 0, 0, -1, 0, -1},
        {0, 0, 0, 0, 0, 0},        {1, 0, 0, 1, 0, 0},       {0, 1, 0, 0, 0, 1},
        {1, 2, 0, 1, 0, 1},        {1, 0, 0, 1, 0, 1e-30},   {1, 1, 1, 1, 1, 1},
        {1e-300, 0, 0, 1, 0, 1e300},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        expect_einval(ctx, anistar_tensor_distortion(ctx, bad[k], id, &g), "distortion m");
        expect_einval(ctx, anistar_tensor_distortion(ctx, id, bad[k], &g), "distortion n");
        expect_einval(ctx, anistar_tensor_distance(ctx, bad[k], p, q, &d), "distance m");
        expect_einval(ctx, anistar_tensor_sqrt(ctx, bad[k], f), "sqrt m");
    }
    /* Non-finite points. */
    double pn[3] = {0, NAN, 0}, pi[3] = {INFINITY, 0, 0};
    expect_einval(ctx, anistar_tensor_distance(ctx, id, pn, q, &d), "distance NaN point");
    expect_einval(ctx, anistar_tensor_distance(ctx, id, p, pi, &d), "distance inf point");
    /* Outputs untouched on failure. */
    assert_true(g == -7 && d == -7 && f[0] == -7);
    /* And a good call still works afterwards. */
    assert_int_equal(anistar_tensor_distortion(ctx, id, id, &g), ANISTAR_OK);
    assert_true(g == 1);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frame_init),
        cmocka_unit_test(test_frame_inverse),
        cmocka_unit_test(test_frame_from_eigen),
        cmocka_unit_test(test_frame_validation),
        cmocka_unit_test(test_apply_and_dist),
        cmocka_unit_test(test_distortion_reference),
        cmocka_unit_test(test_distortion_known),
        cmocka_unit_test(test_distortion_distance_bounds),
        cmocka_unit_test(test_distortion_filter),
        cmocka_unit_test(test_distortion_le_near),
        cmocka_unit_test(test_distortion_le_boundary),
        cmocka_unit_test(test_distortion_range),
        cmocka_unit_test(test_ellipsoid_box),
        cmocka_unit_test(test_api_tensor_valid),
        cmocka_unit_test(test_api_tensor_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
