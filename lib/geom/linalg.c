/*
 * linalg.c — small dense linear algebra: the symmetric 3x3 eigen-decomposition (Jacobi),
 * products of 3x3 matrices, and dense least squares by Householder QR with column
 * pivoting (DESIGN.md 4.2; jet fitting of 4.7 uses the least squares).
 *
 * Everything here is deterministic, allocation-free, and never reads or writes anything
 * but its arguments.
 */
#include "geom/linalg.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

/* ---- symmetric 3x3 eigen-decomposition --------------------------------------------- */

/*
 * Tolerances of the Jacobi iteration (the matrix is first scaled by a power of two so that
 * its largest entry lies in [0.5, 1)):
 *  - AS_JACOBI_REL: an off-diagonal entry a_pq is negligible when
 *    |a_pq| <= AS_JACOBI_REL * sqrt(|a_pp|) * sqrt(|a_qq|). This is the relative criterion
 *    of Demmel and Veselic ("Jacobi's method is more accurate than QR", 1992): dropping such
 *    an entry changes every eigenvalue by a tiny fraction of its own size for scaled
 *    diagonally dominant matrices (graded metrics such as diag(1e-12, 1, 1e12) keep their
 *    small eigenvalues to full relative accuracy), and by at most ~eps |A| in any case.
 *  - AS_JACOBI_FLOOR: entries below 2^-500 (of the scaled matrix, whose norm is ~1) are
 *    negligible whatever the diagonal: they are far below any rounding error of |A| (they
 *    matter only to eigenvalues below ~1e-150 |A|), and their squares stay normal numbers.
 *  - AS_JACOBI_MAX_ROT: a bound on the number of rotations that the iteration provably
 *    never reaches (see as_sym3_eigen's contract); it only guards the loop.
 */
#define AS_JACOBI_REL 0x1.0p-53
#define AS_JACOBI_FLOOR 0x1.0p-500
#define AS_JACOBI_MAX_ROT 2048

/* The three off-diagonal pairs (p, q), p < q, and the remaining index r. */
static const int as_jac_p[3] = {0, 0, 1};
static const int as_jac_q[3] = {1, 2, 2};
static const int as_jac_r[3] = {2, 1, 0};

static inline int as_sym3_finite(const double a[6]) {
    for (int i = 0; i < 6; i++)
        if (!isfinite(a[i])) return 0;
    return 1;
}

/* Negate v (3 doubles) when its entry of largest magnitude (the first one on ties) is
 * negative: a canonical sign, so equal inputs give equal outputs whatever path the
 * iteration took. */
static void as_vec3_canonical_sign(double *v) {
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(v[i]) > fabs(v[k])) k = i;
    if (v[k] < 0) {
        v[0] = -v[0];
        v[1] = -v[1];
        v[2] = -v[2];
    }
}

/* 2^k for -1022 <= k <= 1023, exactly (its bits: ldexp(1.0, k) without the call). */
static inline double pow2i(int k) {
    uint64_t b = (uint64_t)(k + 1023) << 52;
    double x;
    memcpy(&x, &b, sizeof x);
    return x;
}

/* frexp's exponent of a positive finite x (x = m 2^e, 0.5 <= m < 1): from its bits when x
 * is normal. */
static inline int exponent_of(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    int e = (int)((b >> 52) & 0x7ff);
    if (e == 0) {
        (void)frexp(x, &e);
        return e;
    }
    return e - 1022;
}

/*
 * as_sym3_eigen — A = V diag(w) V^T for a symmetric 3x3 A (6 doubles).
 *
 * Returns 0; -1 if an entry of A is not finite (w and vec are then NaN).
 * Notes: w ascending; vec + 3k is the unit eigenvector of w[k]; (vec0, vec1, vec2) is a
 *   right-handed orthonormal basis; vec0 and vec1 have a non-negative entry of largest
 *   magnitude. The zero matrix gives w = 0 and the identity. Eigenvalues of a matrix whose
 *   entries are near DBL_MAX may overflow to +-inf (|w| can exceed max |a_ij| by 3x).
 * Accuracy: each rotation is backward stable, so the residual |A v - w v| and the loss of
 *   orthogonality are a small multiple of eps |A| (the tests check 1e-13 relative on random,
 *   repeated-eigenvalue and condition-1e12 matrices).
 * design:
 *   1. s = 2^e with max |a_ij| / s in [0.5, 1): scale A by 1/s, exactly (powers of two), so
 *      no intermediate overflows or underflows, whatever the magnitude of A.
 *   2. Classical Jacobi on the three off-diagonal entries: while some entry is not
 *      negligible (AS_JACOBI_REL / AS_JACOBI_FLOOR above), annihilate the largest one
 *      a_pq by the rotation of angle phi, |phi| <= pi/4, tan(phi) = t the smaller root of
 *      t^2 + 2 theta t - 1 = 0, theta = (a_qq - a_pp) / (2 a_pq) (Rutishauser's update
 *      formulas with tau = s / (1 + c), accumulating V). Classical (largest entry first)
 *      rather than cyclic order: for n = 3 finding the largest costs 3 compares, and it
 *      gives the simple bound of step 3.
 *   3. Convergence, with a bound: let S = a12^2 + a13^2 + a23^2. A rotation in (p, q)
 *      sets a_pq to 0 and rotates (a_pr, a_qr), keeping a_pr^2 + a_qr^2; so S drops by
 *      a_pq^2 >= S / 3 (a_pq is the largest): S_k <= (2/3)^k S_0, up to a factor
 *      (1 + 4 eps) per rotation from rounding. S_0 <= 3 after scaling, and once
 *      S <= 2^-1000 every entry is below AS_JACOBI_FLOOR, so the loop ends after at most
 *      (ln 3 + 1000 ln 2) / ln 1.5 < 1713 rotations < AS_JACOBI_MAX_ROT. That is the worst
 *      case of the linear rate; Jacobi's ultimately quadratic convergence (Schoenhage 1961,
 *      also with repeated eigenvalues) makes it 5 to 10 rotations in practice (9 on
 *      average for random matrices: three "sweeps"). Reaching the cap is impossible, and
 *      even then the result would carry an off-diagonal norm below 2^-1000 |A|.
 *   4. Sort ascending (stable), scale w back by s, canonical signs, right-handed basis
 *      (negate vec2 when det V < 0).
 */
int as_sym3_eigen(const double a[6], double w[3], double vec[9]) {
    if (!as_sym3_finite(a)) {
        for (int i = 0; i < 3; i++) w[i] = NAN;
        for (int i = 0; i < 9; i++) vec[i] = NAN;
        return -1;
    }
    double amax = 0;
    for (int i = 0; i < 6; i++)
        if (fabs(a[i]) > amax) amax = fabs(a[i]);
    /* v[3*i + k] = V_ik: the eigenvector of w[k] is the column k of V. */
    double v[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    if (amax == 0) {
        w[0] = w[1] = w[2] = 0;
        memcpy(vec, v, sizeof v);
        return 0;
    }
    int ex = exponent_of(amax);
    /* Scale by 2^-ex as two multiplications by representable powers of two (|ex| <= 1074):
     * exact except for entries that become subnormal, i.e. below 2^-1022 |A|. */
    double dn1 = pow2i(-ex / 2), dn2 = pow2i(-ex - (-ex / 2));
    /* d: the diagonal; o[k]: the off-diagonal entry of pair k (a12, a13, a23). */
    double d[3] = {a[0] * dn1 * dn2, a[3] * dn1 * dn2, a[5] * dn1 * dn2};
    double o[3] = {a[1] * dn1 * dn2, a[2] * dn1 * dn2, a[4] * dn1 * dn2};

    for (int rot = 0; rot < AS_JACOBI_MAX_ROT; rot++) {
        int k = -1;
        int live = 0;
        for (int j = 0; j < 3; j++) {
            /* Squared tests: o^2 >= 2^-1000 is normal whenever it matters (o above the
             * floor); an underflowing d_p d_q only makes the entry live (one more
             * harmless rotation). */
            double x2 = o[j] * o[j];
            if (x2 > AS_JACOBI_FLOOR * AS_JACOBI_FLOOR &&
                x2 > AS_JACOBI_REL * AS_JACOBI_REL * fabs(d[as_jac_p[j]] * d[as_jac_q[j]]))
                live = 1;
            if (k < 0 || x2 > o[k] * o[k]) k = j;
        }
        if (!live) break;
        int p = as_jac_p[k], q = as_jac_q[k], r = as_jac_r[k];
        double apq = o[k];
        /* With delta = a_qq - a_pp, b = sign(delta) 2 a_pq (sign(0) = +1),
         * h = sqrt(delta^2 + 4 a_pq^2), u = h + |delta| and wv = sqrt(2 h u):
         *   t = sign(theta) / (|theta| + sqrt(theta^2 + 1)) = b / u,
         *   c = 1 / sqrt(1 + t^2) = u / wv, s = t c = b / wv, tau = s / (1 + c) = b / (wv + u),
         * since (|delta| + h)^2 + 4 a_pq^2 = 2 h u (c itself is not needed by the updates).
         * Only sums of positive terms, no cancellation, and a short dependency chain (two
         * square roots, then independent divisions). No overflow or underflow: |delta| < 6
         * after scaling and |a_pq| > 2^-500 (it is the largest entry and one is live). */
        double delta = d[q] - d[p];
        double b = delta < 0 ? -2 * apq : 2 * apq;
        double h = sqrt(delta * delta + 4 * apq * apq);
        double u = h + fabs(delta);
        double wv = sqrt(2 * h * u);
        double t = b / u;
        double s = b / wv;
        double tau = b / (wv + u);
        d[p] -= t * apq;
        d[q] += t * apq;
        o[k] = 0;
        /* The entries (r, p) and (r, q) rotate; the pair {i, j} has index i + j - 1:
         * {0,1} -> 0, {0,2} -> 1, {1,2} -> 2. */
        int kp = p + r - 1, kq = q + r - 1;
        double arp = o[kp], arq = o[kq];
        o[kp] = arp - s * (arq + tau * arp);
        o[kq] = arq + s * (arp - tau * arq);
        for (int i = 0; i < 3; i++) {
            double vip = v[3 * i + p], viq = v[3 * i + q];
            v[3 * i + p] = vip - s * (viq + tau * vip);
            v[3 * i + q] = viq + s * (vip - tau * viq);
        }
    }

    /* Sort ascending (insertion sort, stable), carrying the columns of V. */
    double up1 = pow2i(ex / 2), up2 = pow2i(ex - ex / 2);
    int idx[3] = {0, 1, 2};
    for (int i = 1; i < 3; i++) {
        int j = i;
        while (j > 0 && d[idx[j - 1]] > d[idx[j]]) {
            int tmp = idx[j];
            idx[j] = idx[j - 1];
            idx[j - 1] = tmp;
            j--;
        }
    }
    for (int k = 0; k < 3; k++) {
        w[k] = d[idx[k]] * up1 * up2;
        for (int i = 0; i < 3; i++) vec[3 * k + i] = v[3 * i + idx[k]];
    }
    as_vec3_canonical_sign(vec);
    as_vec3_canonical_sign(vec + 3);
    double det = vec[6] * (vec[1] * vec[5] - vec[2] * vec[4]) +
                 vec[7] * (vec[2] * vec[3] - vec[0] * vec[5]) +
                 vec[8] * (vec[0] * vec[4] - vec[1] * vec[3]);
    if (det < 0) {
        vec[6] = -vec[6];
        vec[7] = -vec[7];
        vec[8] = -vec[8];
    }
    return 0;
}

void as_sym3_from_eigen(const double w[3], const double vec[9], double a[6]) {
    /* a_ij = sum_k (w_k v_k[i]) v_k[j], upper triangle only, in a fixed order. */
    static const int ii[6] = {0, 0, 0, 1, 1, 2};
    static const int jj[6] = {0, 1, 2, 1, 2, 2};
    for (int e = 0; e < 6; e++) {
        int i = ii[e], j = jj[e];
        a[e] = (w[0] * vec[i]) * vec[j] + (w[1] * vec[3 + i]) * vec[3 + j] +
               (w[2] * vec[6 + i]) * vec[6 + j];
    }
}

void as_sym3_to_mat3(const double s[6], double m[9]) {
    m[0] = s[0];
    m[1] = s[1];
    m[2] = s[2];
    m[3] = s[1];
    m[4] = s[3];
    m[5] = s[4];
    m[6] = s[2];
    m[7] = s[4];
    m[8] = s[5];
}

void as_mat3_mul(const double a[9], const double b[9], double c[9]) {
    double r[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            r[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
    memcpy(c, r, sizeof r);
}

void as_mat3_vec(const double a[9], const double x[3], double y[3]) {
    double r[3];
    for (int i = 0; i < 3; i++) r[i] = a[3 * i] * x[0] + a[3 * i + 1] * x[1] + a[3 * i + 2] * x[2];
    y[0] = r[0];
    y[1] = r[1];
    y[2] = r[2];
}

void as_mat3_gram(const double g[9], double a[6]) {
    /* (G^T G)_ij = sum_k g_ki g_kj. */
    static const int ii[6] = {0, 0, 0, 1, 1, 2};
    static const int jj[6] = {0, 1, 2, 1, 2, 2};
    for (int e = 0; e < 6; e++) {
        int i = ii[e], j = jj[e];
        a[e] = g[i] * g[j] + g[3 + i] * g[3 + j] + g[6 + i] * g[6 + j];
    }
}

/* ---- least squares ------------------------------------------------------------------ */

#define AS_LSQ_MAX_N 15

size_t as_lsq_work_size(size_t m, size_t n) {
    /* The scaled copy of A (m x n, row-major) and of b. */
    if (n >= SIZE_MAX || (m != 0 && n + 1 > SIZE_MAX / m)) return 0;
    return m * (n + 1);
}

/* Euclidean norm of a strided vector without spurious overflow or underflow: the plain
 * sum of squares when it lies safely in range (then any underflowed square is below
 * 2^-1022 / 2^-900 of the sum), else rescaled by a power of two. */
static double as_norm_strided(const double *x, size_t cnt, size_t stride) {
    double s = 0;
    for (size_t i = 0; i < cnt; i++) s += x[i * stride] * x[i * stride];
    if (s >= 0x1.0p-900 && s <= DBL_MAX) return sqrt(s);
    double mx = 0;
    for (size_t i = 0; i < cnt; i++) mx = fmax(mx, fabs(x[i * stride]));
    if (mx == 0) return 0;
    int ex;
    (void)frexp(mx, &ex);
    s = 0;
    for (size_t i = 0; i < cnt; i++) {
        double t = ldexp(x[i * stride], -ex);
        s += t * t;
    }
    return ldexp(sqrt(s), ex);
}

/* y[i * stride] = x[i * stride] * 2^-ex, exactly (but for underflow to subnormals). */
static void as_scale_strided(const double *x, double *y, size_t cnt, size_t stride, int ex) {
    if (ex > -1000 && ex < 1000) {
        double f = ldexp(1.0, -ex);
        for (size_t i = 0; i < cnt; i++) y[i * stride] = x[i * stride] * f;
    } else {
        for (size_t i = 0; i < cnt; i++) y[i * stride] = ldexp(x[i * stride], -ex);
    }
}

/* Sum of squares of rows k.. of column j of the equilibrated matrix (entries <= ~1, so a
 * plain sum: an underflowed square is negligible next to any pivot that counts). */
static double as_colnorm2(const double *r, size_t m, size_t n, size_t k, size_t j) {
    double s = 0;
    for (size_t i = k; i < m; i++) s += r[i * n + j] * r[i * n + j];
    return s;
}

int as_lsq_solve(const double *a, const double *b, size_t m, size_t n, double *x, double *work) {
    return as_lsq_solve_rcond(a, b, m, n, AS_LSQ_RCOND, x, work);
}

/*
 * as_lsq_solve_rcond — least squares min |A x - b| with an explicit rank tolerance.
 *
 * Returns the numerical rank r: the number of pivots |R_kk| > rcond * |R_00| of the
 * column-pivoted QR of the column-equilibrated A; -1 on invalid input (n == 0, n > 15,
 * m < n, rcond not in [0, 1), a non-finite entry). With r < n, x is the basic solution:
 * the n - r columns chosen last get x_j = 0.
 * Notes: x never holds NaN for finite input. work: as_lsq_work_size(m, n) doubles.
 * design (Golub & Van Loan 5.4.1, Businger-Golub pivoting):
 *   1. Equilibrate: scale every column of A, and b, by a power of two (exact) so their
 *      norms lie in [0.5, 1); the solution of the scaled problem maps back exactly, and
 *      rank decisions no longer depend on the units of the unknowns (jets mix 1 and h^4).
 *   2. For k = 0..n-1: bring the column of largest remaining norm (rows k..m-1, recomputed
 *      each step: O(mn) per step, as cheap as the update at these sizes, and free of the
 *      cancellation of norm downdating) to position k; stop when its norm is
 *      <= rcond * |R_00|; else reflect rows k..m-1 of the remaining columns and of b with
 *      the Householder reflector mapping that column to -sign(x_k) |x| e_k.
 *   3. Back-substitute R_11 z = (Q^T b)_1 over the r leading pivots, un-permute, unscale.
 */
int as_lsq_solve_rcond(const double *a, const double *b, size_t m, size_t n, double rcond,
                       double *x, double *work) {
    if (n == 0 || n > AS_LSQ_MAX_N || m < n || !(rcond >= 0 && rcond < 1)) return -1;
    for (size_t i = 0; i < m * n; i++)
        if (!isfinite(a[i])) return -1;
    for (size_t i = 0; i < m; i++)
        if (!isfinite(b[i])) return -1;

    double *r = work;        /* m x n, row-major, becomes R (upper part) */
    double *qb = work + m * n; /* m, becomes Q^T b */
    int cscale[AS_LSQ_MAX_N];  /* column j was multiplied by 2^-cscale[j] */
    size_t perm[AS_LSQ_MAX_N]; /* column k of r is column perm[k] of a */
    int bscale = 0;

    for (size_t j = 0; j < n; j++) {
        int ex = 0;
        double nr = as_norm_strided(a + j, m, n);
        if (nr > 0) (void)frexp(nr, &ex);
        cscale[j] = ex;
        perm[j] = j;
        as_scale_strided(a + j, r + j, m, n, ex);
    }
    {
        double nb = as_norm_strided(b, m, 1);
        if (nb > 0) (void)frexp(nb, &bscale);
        as_scale_strided(b, qb, m, 1, bscale);
    }

    size_t rank = 0;
    double r00 = 0;
    for (size_t k = 0; k < n; k++) {
        /* Pivot: the remaining column of largest norm over rows k..m-1. */
        size_t best = k;
        double bestn = -1;
        for (size_t j = k; j < n; j++) {
            double nj = as_colnorm2(r, m, n, k, j);
            if (nj > bestn) {
                bestn = nj;
                best = j;
            }
        }
        bestn = sqrt(bestn);
        if (k == 0) r00 = bestn;
        if (bestn == 0 || bestn <= rcond * r00) break;
        if (best != k) {
            for (size_t i = 0; i < m; i++) {
                double t = r[i * n + k];
                r[i * n + k] = r[i * n + best];
                r[i * n + best] = t;
            }
            size_t tp = perm[k];
            perm[k] = perm[best];
            perm[best] = tp;
        }
        /* Householder: v = x - alpha e_1, alpha = -sign(x_0) |x|; H = I - v v^T / (-alpha v_0)
         * (v^T v = -2 alpha v_0 since |x| = |alpha|). */
        double x0 = r[k * n + k];
        double alpha = x0 >= 0 ? -bestn : bestn;
        double v0 = x0 - alpha; /* no cancellation: x0 and -alpha share a sign */
        double beta = -alpha * v0; /* = v^T v / 2 > 0 */
        r[k * n + k] = v0;
        for (size_t j = k + 1; j < n; j++) {
            double dot = 0;
            for (size_t i = k; i < m; i++) dot += r[i * n + k] * r[i * n + j];
            double f = dot / beta;
            for (size_t i = k; i < m; i++) r[i * n + j] -= f * r[i * n + k];
        }
        {
            double dot = 0;
            for (size_t i = k; i < m; i++) dot += r[i * n + k] * qb[i];
            double f = dot / beta;
            for (size_t i = k; i < m; i++) qb[i] -= f * r[i * n + k];
        }
        r[k * n + k] = alpha;
        rank++;
    }

    /* Back substitution over the leading rank x rank block; free unknowns are 0. */
    double z[AS_LSQ_MAX_N];
    for (size_t k = rank; k < n; k++) z[k] = 0;
    for (size_t kk = rank; kk-- > 0;) {
        double s = qb[kk];
        for (size_t j = kk + 1; j < rank; j++) s -= r[kk * n + j] * z[j];
        z[kk] = s / r[kk * n + kk];
    }
    for (size_t k = 0; k < n; k++) {
        size_t j = perm[k];
        x[j] = ldexp(z[k], bscale - cscale[j]);
    }
    return (int)rank;
}
