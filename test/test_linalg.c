/*
 * test_linalg — lib/geom/linalg.c: the symmetric 3x3 eigen-decomposition (random,
 * repeated, nearly repeated, rank-deficient, zero, graded and ill-conditioned matrices;
 * scaling; bad input), the 3x3 helpers, and least squares by pivoted QR (exact recovery
 * of bivariate jets, residual orthogonality, rank deficiency, scaling invariance, bad input).
 *
 * Residuals and products are checked in long double (64-bit mantissa on x86) so the check
 * is more accurate than what it checks.
 */
#include "test_util.h"

#include "geom/linalg.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

typedef long double ld;

static void check_le(double x, double tol, const char *what, long iter) {
    if (!(x <= tol)) fail_msg("%s (case %ld): %.3e > %.3e", what, iter, x, tol);
}

/* A = Q diag(l) Q^T (rounded to doubles), Q's columns are the eigenvectors. */
static void build_sym(const double q[9], const double l[3], double a[6]) {
    static const int ii[6] = {0, 0, 0, 1, 1, 2}, jj[6] = {0, 1, 2, 1, 2, 2};
    for (int e = 0; e < 6; e++) {
        ld s = 0;
        for (int k = 0; k < 3; k++) s += (ld)q[3 * ii[e] + k] * l[k] * q[3 * jj[e] + k];
        a[e] = (double)s;
    }
}

static double sym_norm(const double a[6]) { /* Frobenius */
    ld s = (ld)a[0] * a[0] + (ld)a[3] * a[3] + (ld)a[5] * a[5] +
           2 * ((ld)a[1] * a[1] + (ld)a[2] * a[2] + (ld)a[4] * a[4]);
    return (double)sqrtl(s);
}

/*
 * Check an eigen-decomposition of a: returns max(residual, orthogonality) relative to |A|
 * (orthogonality absolute), and asserts ascending order, right-handedness and unit
 * determinant.
 */
static double eigen_error(const double a[6], const double w[3], const double v[9], long iter) {
    double m[9];
    as_sym3_to_mat3(a, m);
    double nrm = sym_norm(a);
    double worst = 0;
    for (int k = 0; k < 3; k++) {
        for (int i = 0; i < 3; i++) {
            ld r = -(ld)w[k] * v[3 * k + i];
            for (int j = 0; j < 3; j++) r += (ld)m[3 * i + j] * v[3 * k + j];
            double rel = nrm > 0 ? (double)fabsl(r) / nrm : (double)fabsl(r);
            if (rel > worst) worst = rel;
        }
        for (int l = 0; l < 3; l++) {
            ld d = 0;
            for (int i = 0; i < 3; i++) d += (ld)v[3 * k + i] * v[3 * l + i];
            double o = (double)fabsl(d - (k == l ? 1 : 0));
            if (o > worst) worst = o;
        }
    }
    if (!(w[0] <= w[1] && w[1] <= w[2])) fail_msg("case %ld: eigenvalues not ascending", iter);
    ld det = (ld)v[6] * ((ld)v[1] * v[5] - (ld)v[2] * v[4]) +
             (ld)v[7] * ((ld)v[2] * v[3] - (ld)v[0] * v[5]) +
             (ld)v[8] * ((ld)v[0] * v[4] - (ld)v[1] * v[3]);
    if (!(fabsl(det - 1) < 1e-13L)) fail_msg("case %ld: det V = %.17Lg", iter, det);
    return worst;
}

static void sort3(double l[3]) {
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && l[j - 1] > l[j]; j--) {
            double t = l[j];
            l[j] = l[j - 1];
            l[j - 1] = t;
        }
}

/* Decompose A = Q diag(l) Q^T and check residual, orthogonality, and w ~ sorted l within
 * tol relative to |A|. */
static void check_constructed(const double q[9], const double l[3], double tol, long iter) {
    double a[6], w[3], v[9], ls[3] = {l[0], l[1], l[2]};
    build_sym(q, l, a);
    assert_int_equal(as_sym3_eigen(a, w, v), 0);
    check_le(eigen_error(a, w, v, iter), tol, "eigen residual/orthogonality", iter);
    sort3(ls);
    double nrm = sym_norm(a);
    for (int k = 0; k < 3; k++)
        check_le(fabs(w[k] - ls[k]) / (nrm > 0 ? nrm : 1), tol, "eigenvalue vs constructed",
                 iter);
}

/* ---- eigen tests -------------------------------------------------------------------- */

/* 10^5 random Q diag(l) Q^T with l uniform in [-1, 1], then 10^5 with random entries. */
static void test_eigen_random(void **state) {
    (void)state;
    tu_rng r = {1};
    for (long it = 0; it < 100000; it++) {
        double q[9], l[3];
        tu_random_rotation(&r, q);
        for (int k = 0; k < 3; k++) l[k] = tu_rng_range(&r, -1, 1);
        check_constructed(q, l, 1e-13, it);
    }
    for (long it = 0; it < 100000; it++) {
        double a[6], w[3], v[9];
        for (int k = 0; k < 6; k++) a[k] = tu_rng_range(&r, -1, 1);
        assert_int_equal(as_sym3_eigen(a, w, v), 0);
        check_le(eigen_error(a, w, v, it), 1e-13, "random entries", it);
        /* Trace and Frobenius norm are invariants. */
        double tr = a[0] + a[3] + a[5];
        check_le(fabs(w[0] + w[1] + w[2] - tr), 1e-13 * sym_norm(a), "trace", it);
    }
}

/* Condition numbers 1e3 .. 1e12 (PD and indefinite), eigenvalues spread over the range. */
static void test_eigen_ill_conditioned(void **state) {
    (void)state;
    tu_rng r = {2};
    for (long it = 0; it < 50000; it++) {
        double q[9], l[3];
        tu_random_rotation(&r, q);
        double cond = pow(10, 3 + 9 * tu_rng_unit(&r));
        l[0] = 1;
        l[1] = pow(cond, tu_rng_unit(&r));
        l[2] = cond;
        if (it % 2) l[(size_t)(it / 2) % 3] = -l[(size_t)(it / 2) % 3];
        double s = pow(10, tu_rng_range(&r, -5, 5));
        for (int k = 0; k < 3; k++) l[k] *= s;
        check_constructed(q, l, 1e-13, it);
    }
}

/* Exactly and nearly repeated eigenvalues, rank deficiency, multiples of I, zero. */
static void test_eigen_repeated(void **state) {
    (void)state;
    tu_rng r = {3};
    static const double cases[][3] = {
        {1, 1, 2},  {1, 2, 2},   {1, 1 + 1e-12, 2}, {1, 1 + 1e-15, 2}, {1, 1 + 1e-8, 1 - 1e-8},
        {0, 1, 2},  {0, 0, 1},   {0, 0, -3},        {3, 3, 3},         {-2, -2, -2},
        {1e-300, 1, 1}, {1, 1, 1 + 0x1p-52}, {-1, 1, 1}, {5, 0, 5},   {1e-12, 1e-12, 1},
    };
    long it = 0;
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        for (int t = 0; t < 2000; t++, it++) {
            double q[9];
            tu_random_rotation(&r, q);
            check_constructed(q, cases[c], 1e-13, it);
        }
    }
    /* Exactly diagonal / scalar matrices: no rotation, exact answer. */
    double a[6] = {4, 0, 0, 4, 0, 4}, w[3], v[9];
    assert_int_equal(as_sym3_eigen(a, w, v), 0);
    for (int k = 0; k < 3; k++) assert_true(w[k] == 4);
    for (int k = 0; k < 9; k++) assert_true(v[k] == (k % 4 == 0 ? 1 : 0));
    double z[6] = {0, 0, 0, 0, 0, 0};
    assert_int_equal(as_sym3_eigen(z, w, v), 0);
    for (int k = 0; k < 3; k++) assert_true(w[k] == 0);
    for (int k = 0; k < 9; k++) assert_true(v[k] == (k % 4 == 0 ? 1 : 0));
    double d[6] = {3, 0, 0, -1, 0, 2};
    assert_int_equal(as_sym3_eigen(d, w, v), 0);
    assert_true(w[0] == -1 && w[1] == 2 && w[2] == 3);
    /* (e2, e3, e1) is right-handed. */
    assert_true(v[1] == 1 && v[5] == 1 && v[6] == 1);
    /* Nearly repeated by construction without a rotation error: a 2x2 block. */
    for (int t = 0; t < 1000; t++, it++) {
        double eps = pow(10, -tu_rng_range(&r, 8, 17));
        double b[6] = {1, eps, 0, 1, 0, 2};
        assert_int_equal(as_sym3_eigen(b, w, v), 0);
        check_le(eigen_error(b, w, v, it), 1e-15, "2x2 block", it);
        check_le(fabs(w[0] - (1 - eps)), 4e-16, "2x2 block: 1 - eps", it);
        check_le(fabs(w[1] - (1 + eps)), 4e-16, "2x2 block: 1 + eps", it);
    }
}

/*
 * Graded matrices A = D C D (C well-conditioned SPD, D = diag(1, 1e-6, 1e-12)): Jacobi with
 * the relative stopping test keeps the tiny eigenvalues to high relative accuracy. The
 * product of the eigenvalues must match det(A) = det(C) prod d_i^2 (computed in long double
 * from C, where it is well-conditioned) to 1e-12 relative.
 */
static void test_eigen_graded(void **state) {
    (void)state;
    tu_rng r = {4};
    const double dd[3] = {1, 1e-6, 1e-12};
    for (long it = 0; it < 20000; it++) {
        double q[9], l[3], c[6], a[6], w[3], v[9];
        tu_random_rotation(&r, q);
        for (int k = 0; k < 3; k++) l[k] = tu_rng_range(&r, 0.5, 2);
        build_sym(q, l, c);
        static const int ii[6] = {0, 0, 0, 1, 1, 2}, jj[6] = {0, 1, 2, 1, 2, 2};
        for (int e = 0; e < 6; e++) a[e] = c[e] * dd[ii[e]] * dd[jj[e]];
        ld detc = (ld)c[0] * ((ld)c[3] * c[5] - (ld)c[4] * c[4]) -
                  (ld)c[1] * ((ld)c[1] * c[5] - (ld)c[4] * c[2]) +
                  (ld)c[2] * ((ld)c[1] * c[4] - (ld)c[3] * c[2]);
        ld deta = detc * (ld)dd[1] * dd[1] * (ld)dd[2] * dd[2];
        assert_int_equal(as_sym3_eigen(a, w, v), 0);
        check_le(eigen_error(a, w, v, it), 1e-13, "graded residual", it);
        assert_true(w[0] > 0);
        ld prod = (ld)w[0] * w[1] * w[2];
        check_le((double)fabsl(prod / deta - 1), 1e-12, "graded: relative accuracy", it);
    }
}

/* Scaling by 2^k gives exactly scaled eigenvalues and identical eigenvectors (the input is
 * scaled by a power of two inside), over the whole exponent range. */
static void test_eigen_scaling(void **state) {
    (void)state;
    tu_rng r = {5};
    static const int ks[] = {-1000, -600, -300, -40, 40, 300, 600, 1000};
    for (long it = 0; it < 2000; it++) {
        double a[6], w[3], v[9];
        for (int k = 0; k < 6; k++) a[k] = tu_rng_range(&r, -1, 1);
        assert_int_equal(as_sym3_eigen(a, w, v), 0);
        for (size_t j = 0; j < sizeof ks / sizeof ks[0]; j++) {
            double b[6], ws[3], vs[9];
            for (int k = 0; k < 6; k++) b[k] = ldexp(a[k], ks[j]);
            assert_int_equal(as_sym3_eigen(b, ws, vs), 0);
            for (int k = 0; k < 3; k++) assert_true(ws[k] == ldexp(w[k], ks[j]));
            assert_memory_equal(vs, v, sizeof v);
        }
    }
    /* Huge and tiny entries side by side, and subnormals. */
    double h[6] = {1e308, 1e-308, 0, -1e308, 4.9e-324, 1e300};
    double w[3], v[9];
    assert_int_equal(as_sym3_eigen(h, w, v), 0);
    check_le(eigen_error(h, w, v, 0), 1e-13, "huge entries", 0);
    double t[6] = {4.9e-324, 1e-320, 0, 3e-322, 0, 1e-315};
    assert_int_equal(as_sym3_eigen(t, w, v), 0);
    for (int k = 0; k < 3; k++) assert_true(isfinite(w[k]));
    check_le(eigen_error(t, w, v, 0), 1e-6, "subnormal entries", 0);
}

static void test_eigen_bad_input(void **state) {
    (void)state;
    const double bad[] = {NAN, INFINITY, -INFINITY};
    for (int b = 0; b < 3; b++)
        for (int i = 0; i < 6; i++) {
            double a[6] = {1, 0, 0, 1, 0, 1}, w[3], v[9];
            a[i] = bad[b];
            assert_int_equal(as_sym3_eigen(a, w, v), -1);
            for (int k = 0; k < 3; k++) assert_true(isnan(w[k]));
            for (int k = 0; k < 9; k++) assert_true(isnan(v[k]));
        }
}

/* Deterministic and canonical: same input, same bits; vec0 and vec1 have a positive
 * largest entry. from_eigen rebuilds A. */
static void test_eigen_canonical_and_rebuild(void **state) {
    (void)state;
    tu_rng r = {6};
    for (long it = 0; it < 20000; it++) {
        double q[9], l[3], a[6], w[3], v[9], w2[3], v2[9], b[6];
        tu_random_rotation(&r, q);
        for (int k = 0; k < 3; k++) l[k] = tu_rng_range(&r, -10, 10);
        build_sym(q, l, a);
        assert_int_equal(as_sym3_eigen(a, w, v), 0);
        assert_int_equal(as_sym3_eigen(a, w2, v2), 0);
        assert_memory_equal(w, w2, sizeof w);
        assert_memory_equal(v, v2, sizeof v);
        for (int k = 0; k < 2; k++) {
            int m = 0;
            for (int i = 1; i < 3; i++)
                if (fabs(v[3 * k + i]) > fabs(v[3 * k + m])) m = i;
            assert_true(v[3 * k + m] > 0);
        }
        as_sym3_from_eigen(w, v, b);
        double nrm = sym_norm(a);
        for (int e = 0; e < 6; e++) check_le(fabs(b[e] - a[e]) / nrm, 1e-14 * 10, "rebuild", it);
    }
}

/* The general 3x3 helpers against long double. */
static void test_mat3_helpers(void **state) {
    (void)state;
    tu_rng r = {7};
    for (long it = 0; it < 10000; it++) {
        double a[9], b[9], c[9], x[3], y[3], s[6], m[9], g[6];
        for (int k = 0; k < 9; k++) a[k] = tu_rng_range(&r, -1, 1);
        for (int k = 0; k < 9; k++) b[k] = tu_rng_range(&r, -1, 1);
        for (int k = 0; k < 3; k++) x[k] = tu_rng_range(&r, -1, 1);
        for (int k = 0; k < 6; k++) s[k] = tu_rng_range(&r, -1, 1);
        as_mat3_mul(a, b, c);
        as_mat3_vec(a, x, y);
        as_sym3_to_mat3(s, m);
        as_mat3_gram(a, g);
        for (int i = 0; i < 3; i++) {
            ld yi = 0;
            for (int j = 0; j < 3; j++) {
                ld cij = 0, gij = 0;
                for (int k = 0; k < 3; k++) {
                    cij += (ld)a[3 * i + k] * b[3 * k + j];
                    gij += (ld)a[3 * k + i] * a[3 * k + j];
                }
                check_le((double)fabsl(c[3 * i + j] - cij), 1e-15, "mat3_mul", it);
                if (j >= i) {
                    int e = i == 0 ? j : (i == 1 ? 2 + j : 5);
                    check_le((double)fabsl(g[e] - gij), 1e-15, "mat3_gram", it);
                }
                assert_true(m[3 * i + j] == m[3 * j + i]);
                yi += (ld)a[3 * i + j] * x[j];
            }
            check_le((double)fabsl(y[i] - yi), 1e-15, "mat3_vec", it);
        }
        assert_true(m[0] == s[0] && m[1] == s[1] && m[2] == s[2] && m[4] == s[3] &&
                    m[5] == s[4] && m[8] == s[5]);
        /* Aliasing: c = a b with c == a. */
        double a2[9];
        memcpy(a2, a, sizeof a);
        as_mat3_mul(a2, b, a2);
        assert_memory_equal(a2, c, sizeof c);
    }
}

/* ---- least squares ------------------------------------------------------------------ */

#define LSQ_MAXM 300

/* The 15 monomials x^i y^j, i + j <= 4, of a degree-4 bivariate jet. */
static void jet_row(double x, double y, double row[15]) {
    int c = 0;
    for (int d = 0; d <= 4; d++)
        for (int i = d; i >= 0; i--) {
            int j = d - i;
            row[c++] = pow(x, i) * pow(y, j);
        }
}

/* Exact (noiseless) data of a random degree-4 jet at m random points in [-h, h]^2: the
 * coefficients come back to 1e-10 (relative to their scale h^-deg for h != 1). */
static void test_lsq_jets(void **state) {
    (void)state;
    tu_rng r = {8};
    static double a[LSQ_MAXM * 15], b[LSQ_MAXM], work[LSQ_MAXM * 15 + LSQ_MAXM];
    static const size_t ms[] = {15, 20, 40, 100, 300};
    assert_true(as_lsq_work_size(LSQ_MAXM, 15) <= sizeof work / sizeof work[0]);
    long it = 0;
    for (size_t mi = 0; mi < sizeof ms / sizeof ms[0]; mi++) {
        for (int t = 0; t < 200; t++, it++) {
            size_t m = ms[mi];
            double h = t % 2 ? 1.0 : 0.01;
            double coef[15], x[15];
            for (int k = 0; k < 15; k++) coef[k] = tu_rng_range(&r, -1, 1);
            for (size_t i = 0; i < m; i++) {
                jet_row(tu_rng_range(&r, -h, h), tu_rng_range(&r, -h, h), a + i * 15);
                ld s = 0;
                for (int k = 0; k < 15; k++) s += (ld)a[i * 15 + k] * coef[k];
                b[i] = (double)s;
            }
            int rank = as_lsq_solve(a, b, m, 15, x, work);
            assert_int_equal(rank, 15);
            /* The coefficient of a degree-d monomial is determined to ~eps / h^d. */
            int c = 0;
            for (int d = 0; d <= 4; d++)
                for (int i = 0; i <= d; i++, c++)
                    check_le(fabs(x[c] - coef[c]) * pow(h, d), 1e-10, "jet coefficient", it);
        }
    }
}

/* Random overdetermined systems: A^T (A x - b) ~ 0 (normal equations of the least squares
 * solution), and x matches the normal-equation solution refined in long double. */
static void test_lsq_orthogonality(void **state) {
    (void)state;
    tu_rng r = {9};
    static double a[LSQ_MAXM * 15], b[LSQ_MAXM], work[LSQ_MAXM * 15 + LSQ_MAXM];
    for (long it = 0; it < 3000; it++) {
        size_t n = 1 + (size_t)(tu_rng_u64(&r) % 15);
        size_t m = n + (size_t)(tu_rng_u64(&r) % (LSQ_MAXM - n + 1));
        double x[15];
        for (size_t i = 0; i < m * n; i++) a[i] = tu_rng_range(&r, -1, 1);
        /* Columns of wildly different scales: equilibration must make this harmless. */
        for (size_t j = 0; j < n; j++) {
            double s = pow(10, tu_rng_range(&r, -8, 8));
            for (size_t i = 0; i < m; i++) a[i * n + j] *= s;
        }
        for (size_t i = 0; i < m; i++) b[i] = tu_rng_range(&r, -1, 1);
        int rank = as_lsq_solve(a, b, m, n, x, work);
        assert_int_equal(rank, (int)n);
        ld res[LSQ_MAXM];
        ld bn = 0;
        for (size_t i = 0; i < m; i++) {
            ld s = -(ld)b[i];
            for (size_t j = 0; j < n; j++) s += (ld)a[i * n + j] * x[j];
            res[i] = s;
            bn += (ld)b[i] * b[i];
        }
        for (size_t j = 0; j < n; j++) {
            ld dot = 0, cn = 0;
            for (size_t i = 0; i < m; i++) {
                dot += (ld)a[i * n + j] * res[i];
                cn += (ld)a[i * n + j] * a[i * n + j];
            }
            /* cos of the angle between column j and the residual. */
            double cosang = (double)(fabsl(dot) / (sqrtl(cn) * sqrtl(bn)));
            check_le(cosang, 1e-12, "A^T r ~ 0", it);
        }
    }
}

/* Rank-deficient input: dependent columns, zero columns, all zero; rank < n, no NaN, and
 * the basic solution is still a least-squares solution (A^T r ~ 0). */
static void test_lsq_rank_deficient(void **state) {
    (void)state;
    tu_rng r = {10};
    static double a[LSQ_MAXM * 15], b[LSQ_MAXM], work[LSQ_MAXM * 15 + LSQ_MAXM];
    for (long it = 0; it < 2000; it++) {
        size_t n = 2 + (size_t)(tu_rng_u64(&r) % 14);
        size_t m = n + (size_t)(tu_rng_u64(&r) % 100);
        size_t def = 1 + (size_t)(tu_rng_u64(&r) % (n - 1)); /* number of dependent columns */
        size_t base = n - def;
        double x[15];
        for (size_t i = 0; i < m; i++)
            for (size_t j = 0; j < base; j++) a[i * n + j] = tu_rng_range(&r, -1, 1);
        for (size_t j = base; j < n; j++) {
            int kind = (int)(tu_rng_u64(&r) % 3);
            double c1 = tu_rng_range(&r, -2, 2), c2 = tu_rng_range(&r, -2, 2);
            size_t j1 = (size_t)(tu_rng_u64(&r) % base), j2 = (size_t)(tu_rng_u64(&r) % base);
            for (size_t i = 0; i < m; i++) {
                if (kind == 0) a[i * n + j] = 0;
                else if (kind == 1) a[i * n + j] = a[i * n + j1] * 3;
                else a[i * n + j] = c1 * a[i * n + j1] + c2 * a[i * n + j2];
            }
        }
        /* Shuffle the columns so dependent ones are not always last. */
        for (size_t j = n - 1; j > 0; j--) {
            size_t k = (size_t)(tu_rng_u64(&r) % (j + 1));
            for (size_t i = 0; i < m; i++) {
                double t = a[i * n + j];
                a[i * n + j] = a[i * n + k];
                a[i * n + k] = t;
            }
        }
        for (size_t i = 0; i < m; i++) b[i] = tu_rng_range(&r, -1, 1);
        int rank = as_lsq_solve(a, b, m, n, x, work);
        assert_true(rank >= 0 && rank <= (int)base);
        if (rank < (int)base) fail_msg("case %ld: rank %d < %zu", it, rank, base);
        for (size_t j = 0; j < n; j++) assert_true(isfinite(x[j]));
        size_t zeros = 0;
        for (size_t j = 0; j < n; j++) zeros += x[j] == 0;
        assert_true(zeros >= n - (size_t)rank);
        ld bn = 0, res[LSQ_MAXM];
        for (size_t i = 0; i < m; i++) {
            ld s = -(ld)b[i];
            for (size_t j = 0; j < n; j++) s += (ld)a[i * n + j] * x[j];
            res[i] = s;
            bn += (ld)b[i] * b[i];
        }
        for (size_t j = 0; j < n; j++) {
            ld dot = 0, cn = 0;
            for (size_t i = 0; i < m; i++) {
                dot += (ld)a[i * n + j] * res[i];
                cn += (ld)a[i * n + j] * a[i * n + j];
            }
            if (cn > 0) check_le((double)(fabsl(dot) / sqrtl(cn * bn)), 1e-11, "A^T r", it);
        }
    }
    /* The zero matrix: rank 0, x = 0. */
    double z[12] = {0}, bz[4] = {1, 2, 3, 4}, x[3], wk[16];
    assert_int_equal(as_lsq_solve(z, bz, 4, 3, x, wk), 0);
    for (int j = 0; j < 3; j++) assert_true(x[j] == 0);
}

/* Scaling a column by 2^k scales its unknown by 2^-k exactly; scaling b by 2^k scales x. */
static void test_lsq_scaling(void **state) {
    (void)state;
    tu_rng r = {11};
    static double a[100 * 6], a2[100 * 6], b[100], b2[100], work[100 * 6 + 100];
    for (long it = 0; it < 500; it++) {
        size_t m = 6 + (size_t)(tu_rng_u64(&r) % 94), n = 6;
        for (size_t i = 0; i < m * n; i++) a[i] = tu_rng_range(&r, -1, 1);
        for (size_t i = 0; i < m; i++) b[i] = tu_rng_range(&r, -1, 1);
        double x[6], x2[6];
        assert_int_equal(as_lsq_solve(a, b, m, n, x, work), 6);
        int k[6];
        for (size_t j = 0; j < n; j++) k[j] = (int)(tu_rng_u64(&r) % 200) - 100;
        int kb = (int)(tu_rng_u64(&r) % 200) - 100;
        for (size_t i = 0; i < m; i++) {
            for (size_t j = 0; j < n; j++) a2[i * n + j] = ldexp(a[i * n + j], k[j]);
            b2[i] = ldexp(b[i], kb);
        }
        assert_int_equal(as_lsq_solve(a2, b2, m, n, x2, work), 6);
        for (size_t j = 0; j < n; j++) assert_true(x2[j] == ldexp(x[j], kb - k[j]));
    }
}

static void test_lsq_square_and_bad_input(void **state) {
    (void)state;
    /* A square, well-conditioned system is solved exactly (to rounding). */
    double a[9] = {2, 1, 0, 1, 3, 1, 0, 1, 4}, xt[3] = {1, -2, 3}, b[3], x[3], wk[12];
    for (int i = 0; i < 3; i++) b[i] = a[3 * i] * xt[0] + a[3 * i + 1] * xt[1] + a[3 * i + 2] * xt[2];
    assert_int_equal(as_lsq_solve(a, b, 3, 3, x, wk), 3);
    for (int j = 0; j < 3; j++) check_le(fabs(x[j] - xt[j]), 1e-14, "square", j);
    /* Invalid shapes and values. */
    double big[16 * 16] = {0}, bb[16] = {0}, xb[16], wb[16 * 16 + 16];
    assert_int_equal(as_lsq_solve(big, bb, 16, 16, xb, wb), -1); /* n > 15 */
    assert_int_equal(as_lsq_solve(a, b, 3, 0, x, wk), -1);       /* n == 0 */
    assert_int_equal(as_lsq_solve(a, b, 2, 3, x, wk), -1);       /* m < n */
    assert_int_equal(as_lsq_solve_rcond(a, b, 3, 3, -1, x, wk), -1);
    assert_int_equal(as_lsq_solve_rcond(a, b, 3, 3, 1, x, wk), -1);
    assert_int_equal(as_lsq_solve_rcond(a, b, 3, 3, NAN, x, wk), -1);
    a[4] = NAN;
    assert_int_equal(as_lsq_solve(a, b, 3, 3, x, wk), -1);
    a[4] = 3;
    b[1] = INFINITY;
    assert_int_equal(as_lsq_solve(a, b, 3, 3, x, wk), -1);
    assert_true(as_lsq_work_size(300, 15) == 300 * 16);
    assert_true(as_lsq_work_size(SIZE_MAX / 2, 15) == 0); /* overflow */
    /* rcond = 0 keeps every nonzero pivot; rcond close to 1 keeps only the first. */
    b[1] = 1;
    assert_int_equal(as_lsq_solve_rcond(a, b, 3, 3, 0, x, wk), 3);
    assert_int_equal(as_lsq_solve_rcond(a, b, 3, 3, 0.999, x, wk), 1);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_eigen_random),
        cmocka_unit_test(test_eigen_ill_conditioned),
        cmocka_unit_test(test_eigen_repeated),
        cmocka_unit_test(test_eigen_graded),
        cmocka_unit_test(test_eigen_scaling),
        cmocka_unit_test(test_eigen_bad_input),
        cmocka_unit_test(test_eigen_canonical_and_rebuild),
        cmocka_unit_test(test_mat3_helpers),
        cmocka_unit_test(test_lsq_jets),
        cmocka_unit_test(test_lsq_orthogonality),
        cmocka_unit_test(test_lsq_rank_deficient),
        cmocka_unit_test(test_lsq_scaling),
        cmocka_unit_test(test_lsq_square_and_bad_input),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
