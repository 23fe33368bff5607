/*
 * metric.c — metric tensors: the frame (M, F = M^(1/2), F^-1, eigen-decomposition), the
 * stretched transform, M-distances, the distortion gamma(M, N) with its filter, and the
 * box of an M-ellipsoid (DESIGN.md 4.2, paper 2.1-2.2).
 */
#include "geom/metric.h"

#include "geom/linalg.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* The largest condition number of F accepted in a frame (M's is its square, 1e24). */
#define AS_METRIC_MAX_COND_F 1e12
/* How far from orthonormal the frame given to as_metric_frame_from_eigen may be:
 * |u_i . u_j - delta_ij| <= this (it catches wrong frames, not rounding). */
#define AS_METRIC_ORTHO_TOL 1e-9

/* F = U diag(e) U^T and F^-1 = U diag(1/e) U^T, computed on the upper triangle and
 * mirrored so both are exactly symmetric. */
static void as_metric_fill(as_metric_frame *mf) {
    double w[3], s[6];
    for (int k = 0; k < 3; k++) w[k] = mf->e[k];
    as_sym3_from_eigen(w, mf->u, s);
    as_sym3_to_mat3(s, mf->f);
    for (int k = 0; k < 3; k++) w[k] = 1 / mf->e[k];
    as_sym3_from_eigen(w, mf->u, s);
    as_sym3_to_mat3(s, mf->finv);
}

/* e (ascending) finite and positive, e[2] / e[0] <= AS_METRIC_MAX_COND_F, and 1/e, e^2
 * finite (so F, F^-1 and M are). */
static int as_metric_e_valid(const double e[3]) {
    for (int k = 0; k < 3; k++)
        if (!(e[k] > 0) || !isfinite(e[k]) || !isfinite(1 / e[k]) || !isfinite(e[k] * e[k]))
            return 0;
    return e[2] <= AS_METRIC_MAX_COND_F * e[0];
}

/*
 * as_metric_frame_init — the frame of the metric M (6 doubles).
 *
 * Returns 0; -1 (mf zeroed) if M has a non-finite entry, is not positive definite, or
 * sqrt(lambda_max) / sqrt(lambda_min) > 1e12 (M's condition number > ~1e24), as computed
 * by as_sym3_eigen.
 * design:
 *   1. M = U diag(lambda) U^T by as_sym3_eigen (ascending, right-handed U).
 *   2. e = sqrt(lambda); validate (as_metric_e_valid).
 *   3. F = U diag(e) U^T, F^-1 = U diag(1/e) U^T; mf->m keeps the caller's M bit for bit.
 */
int as_metric_frame_eigen(const double m[6], double e[3], double u[9]) {
    double w[3];
    if (as_sym3_eigen(m, w, u) || !(w[0] > 0)) return -1;
    for (int k = 0; k < 3; k++) e[k] = sqrt(w[k]);
    return as_metric_e_valid(e) ? 0 : -1;
}

int as_metric_frame_init(as_metric_frame *mf, const double m[6]) {
    double e[3], u[9];
    if (as_metric_frame_eigen(m, e, u)) {
        memset(mf, 0, sizeof *mf);
        return -1;
    }
    memcpy(mf->m, m, sizeof mf->m);
    memcpy(mf->e, e, sizeof mf->e);
    memcpy(mf->u, u, sizeof mf->u);
    as_metric_fill(mf);
    return 0;
}

/*
 * as_metric_frame_from_eigen — the frame of M = U diag(e^2) U^T.
 *
 * Returns 0; -1 (mf zeroed) if some e[k] is not finite and positive, max e / min e > 1e12,
 * or u is not finite and orthonormal to within AS_METRIC_ORTHO_TOL.
 * Notes: e need not be sorted: the pairs (e[k], u + 3k) are sorted ascending (stably) into
 *   mf->e, mf->u. u is kept as given (not re-orthonormalised): F, F^-1 and M are the
 *   caller's U diag(e) U^T, U diag(1/e) U^T, U diag(e^2) U^T evaluated in a fixed order
 *   (as_sym3_from_eigen), so equal inputs give bit-identical frames.
 */
int as_metric_frame_from_eigen(as_metric_frame *mf, const double u[9], const double e[3]) {
    int idx[3] = {0, 1, 2};
    for (int i = 1; i < 3; i++)
        for (int j = i; j > 0 && e[idx[j - 1]] > e[idx[j]]; j--) {
            int t = idx[j];
            idx[j] = idx[j - 1];
            idx[j - 1] = t;
        }
    double es[3], us[9];
    for (int k = 0; k < 3; k++) {
        es[k] = e[idx[k]];
        for (int i = 0; i < 3; i++) us[3 * k + i] = u[3 * idx[k] + i];
    }
    int ok = as_metric_e_valid(es);
    for (int i = 0; i < 9 && ok; i++) ok = isfinite(us[i]);
    for (int i = 0; i < 3 && ok; i++)
        for (int j = i; j < 3 && ok; j++) {
            double d = us[3 * i] * us[3 * j] + us[3 * i + 1] * us[3 * j + 1] +
                       us[3 * i + 2] * us[3 * j + 2];
            ok = fabs(d - (i == j ? 1.0 : 0.0)) <= AS_METRIC_ORTHO_TOL;
        }
    if (!ok) {
        memset(mf, 0, sizeof *mf);
        return -1;
    }
    memcpy(mf->e, es, sizeof es);
    memcpy(mf->u, us, sizeof us);
    double w[3] = {es[0] * es[0], es[1] * es[1], es[2] * es[2]};
    as_sym3_from_eigen(w, us, mf->m);
    as_metric_fill(mf);
    return 0;
}

/* |v| for a 3-vector whose squared norm s under- or overflowed (as_metric_dist's slow
 * path): scaled by a power of two. */
double as_norm3_scaled(const double v[3], double s) {
    if (s >= DBL_MIN && s <= DBL_MAX) return sqrt(s);
    double mx = fmax(fabs(v[0]), fmax(fabs(v[1]), fabs(v[2])));
    if (mx == 0 || !isfinite(mx)) return mx;
    int ex;
    (void)frexp(mx, &ex);
    double a = ldexp(v[0], -ex), b = ldexp(v[1], -ex), c = ldexp(v[2], -ex);
    return ldexp(sqrt(a * a + b * b + c * c), ex);
}


/* ---- distortion --------------------------------------------------------------------- */

/*
 * The two Gram matrices of a pair: A = G^T G with G = F_a F_b^-1 and B = H^T H with
 * H = F_b F_a^-1. |G|^2 = lambda_max(A) and |H|^2 = lambda_max(B), so
 * gamma(a, b)^2 = max(lambda_max(A), lambda_max(B)).
 *
 * Why this equals DESIGN.md 4.2's formula: A = F_b^-1 F_a^T F_a F_b^-1 = F_b^-1 M_a F_b^-1
 * (F symmetric); and H = G^-1, so |H| = 1 / sigma_min(G) and
 * |H|^2 = 1 / lambda_min(G^T G) = 1 / lambda_min(A). We compute |H|^2 as the largest
 * eigenvalue of its own Gram matrix instead of the reciprocal of A's smallest: the largest
 * eigenvalue of a symmetric matrix is known to ~eps relative accuracy, the smallest only to
 * ~eps lambda_max(A), i.e. to eps gamma^4 relative.
 *
 * Range: when an entry of G (or H) lies outside [2^-200, 2^200] (metrics of wildly
 * different scales), G is first scaled by 2^-k (k its largest entry's exponent; exact) so
 * that its Gram matrix neither overflows nor underflows, and the eigenvalues are scaled
 * back by 4^k. Otherwise k = 0 and nothing is scaled.
 */
typedef struct as_metric_pair {
    double ga[6], gb[6]; /* Gram matrices of 2^-ka G and 2^-kb H */
    int ka, kb;
} as_metric_pair;

static int as_mat3_range_exp(double g[9]) {
    double mx = 0;
    for (int i = 0; i < 9; i++) mx = fmax(mx, fabs(g[i]));
    if (mx <= 0x1.0p200 && mx >= 0x1.0p-200) return 0;
    int k;
    (void)frexp(mx, &k);
    for (int i = 0; i < 9; i++) g[i] = ldexp(g[i], -k);
    return k;
}

static void as_metric_grams(const as_metric_frame *a, const as_metric_frame *b,
                            as_metric_pair *pr) {
    double g[9];
    as_mat3_mul(a->f, b->finv, g);
    pr->ka = as_mat3_range_exp(g);
    as_mat3_gram(g, pr->ga);
    as_mat3_mul(b->f, a->finv, g);
    pr->kb = as_mat3_range_exp(g);
    as_mat3_gram(g, pr->gb);
}

/* gamma from the two Gram matrices (both paths of the distortion end here, so they agree
 * bit for bit). */
static double as_metric_distortion_pair(const as_metric_pair *pr) {
    double wa[3], wb[3], v[9];
    if (as_sym3_eigen(pr->ga, wa, v) || as_sym3_eigen(pr->gb, wb, v)) return INFINITY;
    double sa = sqrt(wa[2]), sb = sqrt(wb[2]);
    if (pr->ka | pr->kb) {
        sa = ldexp(sa, pr->ka);
        sb = ldexp(sb, pr->kb);
    }
    double g = sa > sb ? sa : sb;
    /* gamma >= 1 exactly (|G| |G^-1| >= 1): clamp the rounding of pairs with gamma ~ 1. */
    return g < 1 ? 1.0 : g;
}

/* Frames with the same F (bit for bit) are the same metric: gamma = 1 exactly. */
static int as_metric_same(const as_metric_frame *a, const as_metric_frame *b) {
    return a == b || memcmp(a->f, b->f, sizeof a->f) == 0;
}

/*
 * as_metric_distortion — gamma(M_a, M_b) = max(|F_a F_b^-1|, |F_b F_a^-1|) >= 1.
 *
 * Returns gamma; exactly 1 when a and b hold the same F; gamma(a, b) == gamma(b, a) bit for
 * bit (the max of the same two numbers); +inf only if gamma exceeds DBL_MAX.
 * Accuracy: ~1e-15 relative to |F_a| |F_b^-1| + |F_b| |F_a^-1| (the rounding of the two
 *   products); for metrics of moderate anisotropy that is ~1e-15 relative to gamma (the
 *   tests see < 3e-15 for anisotropy <= 10, < 1e-13 for anisotropy 1000).
 * design: paper 2.2; as_metric_grams, then the largest eigenvalue of each Gram matrix by
 *   as_sym3_eigen (Jacobi).
 */
double as_metric_distortion(const as_metric_frame *a, const as_metric_frame *b) {
    if (as_metric_same(a, b)) return 1.0;
    as_metric_pair pr;
    as_metric_grams(a, b, &pr);
    return as_metric_distortion_pair(&pr);
}

/*
 * Bounds on lambda_max of a symmetric positive semi-definite S without solving for it.
 * With mu = tr S / 3 and r^2 = |S - mu I|_F^2 = sum_i (lambda_i - mu)^2 (the deviations
 * d_i = lambda_i - mu sum to 0), a zero-sum 3-vector has
 *   max_i d_i <= sqrt(2/3) r   (d_1 = -(d_2 + d_3), so d_1^2 <= 2 (d_2^2 + d_3^2))   and
 *   max_i d_i >= r / sqrt(6)   (equality for (a, a, -2a)),
 * and lambda_max <= tr S (S is PSD) and lambda_max >= max_i S_ii. So
 *   lo = max(max_i S_ii, mu + r / sqrt 6) <= lambda_max <= hi = min(tr S, mu + sqrt(2/3) r).
 * The deviation is formed entry by entry (S_ii - mu), not as |S|_F^2 - tr^2 / 3, which
 * would cancel catastrophically when S ~ c I (the common case: nearby metrics).
 */
static void as_lambda_max_bounds(const double s[6], double *lo, double *hi) {
    double tr = s[0] + s[3] + s[5];
    double mu = tr / 3;
    double d0 = s[0] - mu, d1 = s[3] - mu, d2 = s[5] - mu;
    double r = sqrt(d0 * d0 + d1 * d1 + d2 * d2 + 2 * (s[1] * s[1] + s[2] * s[2] + s[4] * s[4]));
    double dmax = fmax(s[0], fmax(s[3], s[5]));
    *lo = fmax(dmax, mu + r * 0.40824829046386301637); /* 1 / sqrt(6) */
    *hi = fmin(tr, mu + r * 0.81649658092772603273);   /* sqrt(2 / 3) */
}

/*
 * The filter's safety margin, relative to g^2: its decisions are taken only when the
 * bound clears g^2 by this much, which exceeds the rounding of the Gram matrix entries,
 * of the bounds (~10 eps relative to lambda_max) and of the Jacobi eigenvalue (a few
 * rotations, each ~eps relative to |S| = lambda_max). 2^-44 ~ 5.7e-14 = 256 eps.
 */
#define AS_METRIC_FILTER_MARGIN 0x1.0p-44

/*
 * The sign of lambda_max(S) - x without an eigen-solve, by the Budan-Fourier rule.
 *
 * Returns 1 if lambda_max(S) < x is certain, 0 if lambda_max(S) > x is certain, -1 when
 * rounding leaves it open (|lambda_max - x| ~ 1e-14 |S|, or numbers beyond 2^+-300).
 * design:
 *   1. Shift: mu = tr S / 3 (any double), D = S - mu I entry by entry (diagonal rounding
 *      E, |E| <= u max |D_ii|, u = 2^-53), y = x - mu rounded (error <= u |y|). Comparing
 *      lambda_max(D) with y -+ eta, eta = 8 u (max |D_ii| + |y|), settles lambda_max(S)
 *      vs x despite those roundings (Weyl: E moves eigenvalues by <= |E|).
 *   2. p(t) = det(t I - D) = t^3 - c2 t^2 + c1 t - c0 has only real roots (D symmetric),
 *      so the Budan-Fourier count is exact: the number of eigenvalues above t is the number
 *      of sign changes in (p(t), p'(t), p''(t), 6) (no pair is lost: at a root z of q' for
 *      a real-rooted q, q q'' < 0 because q q'' < q'^2, Newton's inequality). Hence all
 *      eigenvalues < t iff p, p', p'' > 0 at t, and some eigenvalue > t iff one of them
 *      is < 0.
 *      With tr D = 0, p'(t) = 3 t^2 - r^2 / 2 and p''(t) = 6 t (r as in
 *      as_lambda_max_bounds), so the p' and p'' conditions are exactly stage 1's bounds
 *      mu + r / sqrt 6 and mu; what stage 1 cannot settle hinges on the sign of p.
 *   3. Each of p, p', p'' is evaluated with a running bound on its rounding error: the
 *      same expression on absolute values, times 2^-48 (> 16 u: no term goes through
 *      more than ~12 roundings), plus DBL_MIN for underflowed products; a sign counts only
 *      beyond that bound.
 */
static int as_lambda_max_vs(const double s[6], double x) {
    double mu = (s[0] + s[3] + s[5]) / 3;
    double d0 = s[0] - mu, d1 = s[3] - mu, d2 = s[5] - mu;
    double o12 = s[1], o13 = s[2], o23 = s[4];
    double y = x - mu;
    double dmax = fmax(fabs(d0), fmax(fabs(d1), fabs(d2)));
    double scale = fmax(fmax(dmax, fabs(y)), fmax(fabs(o12), fmax(fabs(o13), fabs(o23))));
    if (!(scale <= 0x1.0p300 && scale >= 0x1.0p-300)) return -1;
    double eta = 8 * 0x1.0p-53 * (dmax + fabs(y));
    /* Coefficients and their absolute-value counterparts. */
    double c2 = d0 + d1 + d2;
    double c1 = (d0 * d1 + d0 * d2 + d1 * d2) - (o12 * o12 + o13 * o13 + o23 * o23);
    double c0 = d0 * (d1 * d2 - o23 * o23) - o12 * (o12 * d2 - o23 * o13) +
                o13 * (o12 * o23 - d1 * o13);
    double a2 = fabs(d0) + fabs(d1) + fabs(d2);
    double a1 = (fabs(d0 * d1) + fabs(d0 * d2) + fabs(d1 * d2)) + (o12 * o12 + o13 * o13 + o23 * o23);
    double a0 = fabs(d0) * (fabs(d1 * d2) + o23 * o23) + fabs(o12) * (fabs(o12 * d2) + fabs(o23 * o13)) +
                fabs(o13) * (fabs(o12 * o23) + fabs(d1 * o13));
    const double k = 0x1.0p-48;
    for (int side = 0; side < 2; side++) {
        /* side 0: t = y - eta, accept if all of p, p', p'' are surely positive;
         * side 1: t = y + eta, reject if one of them is surely negative. */
        double t = side == 0 ? y - eta : y + eta, at = fabs(t);
        double p = ((t - c2) * t + c1) * t - c0;
        double p1 = (3 * t - 2 * c2) * t + c1;
        double p2 = 6 * t - 2 * c2;
        double ep = k * (((at + a2) * at + a1) * at + a0) + DBL_MIN;
        double ep1 = k * ((3 * at + 2 * a2) * at + a1) + DBL_MIN;
        double ep2 = k * (6 * at + 2 * a2) + DBL_MIN;
        if (side == 0 && p > ep && p1 > ep1 && p2 > ep2) return 1;
        if (side == 1 && (p < -ep || p1 < -ep1 || p2 < -ep2)) return 0;
    }
    return -1;
}

/* One side of the filter: 1 if lambda_max(S) 4^k is surely <= g2, 0 if surely > g2, -1 if
 * unsure. Stage 1: the bounds of as_lambda_max_bounds (no eigen-solve, one sqrt); stage 2:
 * the exact sign test of as_lambda_max_vs. */
static int as_metric_filter_side(const double s[6], int k, double g2) {
    double lo, hi;
    as_lambda_max_bounds(s, &lo, &hi);
    if (!isfinite(lo) || !isfinite(hi)) return -1;
    if (k) g2 = ldexp(g2, -2 * k);
    if (lo > g2 * (1 + AS_METRIC_FILTER_MARGIN)) return 0;
    if (hi <= g2 * (1 - AS_METRIC_FILTER_MARGIN)) return 1;
    return as_lambda_max_vs(s, g2);
}

/* Steps 1-3 of as_metric_distortion_le: 1 accepted, 0 rejected, -1 undecided (then pr
 * holds the two Gram matrices). */
static int as_metric_filter_pair(const as_metric_frame *a, const as_metric_frame *b, double g,
                                 as_metric_pair *pr) {
    if (!(g >= 1)) return 0;
    if (as_metric_same(a, b)) return 1;
    as_metric_grams(a, b, pr);
    double g2 = g * g;
    if (!(g2 <= DBL_MAX)) return -1;
    int da = as_metric_filter_side(pr->ga, pr->ka, g2);
    if (da == 0) return 0;
    int db = as_metric_filter_side(pr->gb, pr->kb, g2);
    if (db == 0) return 0;
    return da == 1 && db == 1 ? 1 : -1;
}

/*
 * as_metric_distortion_le — whether gamma(M_a, M_b) <= g.
 *
 * Returns 1 or 0. It equals (as_metric_distortion(a, b) <= g) for every pair, except
 * possibly when gamma lies within ~1e-13 relative of g. Why: both work on the same two
 * computed Gram matrices; the filter decides only when it is certain of the sign of
 * lambda_max - g^2 for them (the bounds with a margin of 2^-44 g^2, the sign test with
 * rigorous rounding bounds), and otherwise runs the very computation of
 * as_metric_distortion (bit-identical); while the Jacobi eigenvalue behind
 * as_metric_distortion is within a few ulps of that lambda_max. So they can differ only
 * when lambda_max is within those few ulps of g^2 (the tests allow 1e-13).
 * g < 1 or NaN gives 0 (gamma >= 1). Symmetric in (a, b) up to that same boundary case.
 * design: DESIGN.md 4.2's trace filter, sharpened. With A = F_b^-1 M_a F_b^-1 = G^T G and
 *   B = H^T H (as_metric_grams), gamma <= g iff lambda_max(A) <= g^2 and
 *   lambda_max(B) <= g^2 (lambda_max(B) = 1 / lambda_min(A) = lambda_max(A^-1)).
 *   DESIGN's test "tr A <= g^2 and tr A^-1 <= g^2" accepts; it can never accept g < sqrt 3
 *   (tr A >= 3 when A ~ I), so the upper bound min(tr S, mu + sqrt(2/3) r) of
 *   as_lambda_max_bounds is used instead (it includes the trace). Its lower bound rejects.
 *   1. same F: gamma = 1 <= g.
 *   2. Gram matrices A, B (~90 flops).
 *   3. per side S = A, B: reject if lo_S > g^2 (1 + margin); accept if hi_S <= g^2
 *      (1 - margin); else the exact sign test of as_lambda_max_vs (Budan-Fourier on the
 *      characteristic polynomial, ~60 flops), which is undecided only within ~1e-14 of
 *      the boundary.
 *   4. else the exact decision: as_metric_distortion's value <= g.
 *   On the benchmark's mix (anisotropy <= 10, pairs around gamma = 1.5) the bounds alone
 *   settle ~85% of the pairs at g = 1.5 (~98% at g = 1.2 or 2), with the sign test 100%.
 */
int as_metric_distortion_le(const as_metric_frame *a, const as_metric_frame *b, double g) {
    as_metric_pair pr;
    int d = as_metric_filter_pair(a, b, g, &pr);
    if (d >= 0) return d;
    return as_metric_distortion_pair(&pr) <= g;
}

double as_metric_distortion_over(const as_metric_frame *a, const as_metric_frame *b, double g) {
    if (!(g >= 1)) return as_metric_distortion(a, b);
    if (as_metric_same(a, b)) return 0;
    as_metric_pair pr;
    int d = as_metric_filter_pair(a, b, g, &pr); /* a, b differ: pr holds the Gram matrices */
    if (d == 1) return 0;
    return as_metric_distortion_pair(&pr);
}

int as_metric_distortion_filter(const as_metric_frame *a, const as_metric_frame *b, double g) {
    as_metric_pair pr;
    return as_metric_filter_pair(a, b, g, &pr);
}

/*
 * as_metric_ellipsoid_box — half-extents of the axis-aligned box of {x : |F (x - c)| <= r}.
 *
 * x - c = F^-1 y with |y| <= r, so the extent on axis i is max over |y| <= r of
 * row_i(F^-1) . y = r |row_i(F^-1)| (DESIGN.md 4.4).
 */
void as_metric_box_axes(const as_metric_frame *mf, double n[3]) {
    for (int i = 0; i < 3; i++) {
        const double *w = mf->finv + 3 * i;
        n[i] = as_norm3_scaled(w, w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    }
}

void as_metric_ellipsoid_box(const as_metric_frame *mf, double r, double h[3]) {
    double n[3];
    as_metric_box_axes(mf, n);
    for (int i = 0; i < 3; i++) h[i] = r * n[i];
}
