/*
 * predicates.c — exact orient3d and insphere on doubles, and insphere with symbolic
 * perturbation keyed on global ids (DESIGN.md 4.1; STYLE.md point 7).
 *
 * design:
 *  - Ladder per predicate (Shewchuk 1997, "Adaptive precision floating-point arithmetic
 *    and fast robust geometric predicates"; our code):
 *      0. semi-static filter: the plain determinant of the differences against one
 *         bound c * sx * sy * sz (* max lift for insphere), sx = sum over the rows of
 *         |dx| etc.; the permanent is a sub-sum of the expanded product sx sy sz
 *         (times lmax), so c times that dominates Shewchuk's stage-A bound and the
 *         common case costs one determinant, a few abs/add/mul and one comparison;
 *      A. Shewchuk's stage A: the same determinant against errA * permanent;
 *      B. the exact determinant of the rounded differences (expansions), against
 *         errB * permanent; if the differences were exact it is the answer (insphere:
 *         first in double-double, B', which bounds B's value within 128u^2 * permanent
 *         and settles B's answers; B's expansions then run only when the differences
 *         were exact and B' is within its error of 0: see as_isp_adapt);
 *      C. B's estimate plus the first-order terms of the differences' rounding errors
 *         (evaluated in floating point), against errC * permanent + resulterr * |det|
 *         (insphere: B' as the estimate, the bound widened by B''s 128u^2 * permanent);
 *      D. the exact determinant of the raw coordinates (the _exact variant).
 *    The constants are expressions of DBL_EPSILON, folded at compile time (no init call,
 *    no globals). Stage C's correction is our own formula; its bound follows the usual
 *    argument: |second-order remainder| <= ((1+u)^k - 1 - k u) * perm for degree k, and
 *    the floating-point evaluation of the first-order part, of depth n, errs by at most
 *    gamma_n * k u * perm; orient3d: k = 3, n = 7 -> 24 u^2 <= 26 u^2; insphere: k = 5,
 *    n = 11 -> 65 u^2 <= 71 u^2 (the constants of Shewchuk's bounds, which we reuse).
 *  - Stage-0 constants: orient3d's permanent (computed in floating point) is at most
 *    sx sy sz (1+u)^5 and insphere's at most lmax sx sy sz (1+u)^11 (each row triple
 *    (j, k, l) of distinct rows appears once in the sum of the four 3x3 permanents);
 *    the bound's own sums and products round down by at most (1-u)^9, resp. (1-u)^16;
 *    so c_o3d = errA_o3d (1 + 16u) <= (7 + 256u) u and
 *    c_isp = errA_isp (1 + 32u) <= (16 + 1024u) u suffice.
 *  - The fast path is one determinant, 9 or 12 fabs, 6 or 9 adds, 3 or 4 products
 *    (+ 3 max for insphere) and one comparison |det| > bound (false for NaN), then a
 *    tail call to the noinline slow path; measured at <= 1.5x the plain determinant
 *    (bench/bench_predicates.c).
 *  - Non-finite input makes the filter comparison false (NaN/inf determinant or bound);
 *    the slow path then sees a non-finite permanent and returns NaN. Finite input whose
 *    permanent overflows also returns NaN (outside the valid range).
 *  - Valid input range (what the exactness proof needs and the tests check): finite
 *    coordinates, each 0 or of magnitude in [1e-40, 1e+40] (anistar.h). Such a
 *    coordinate is a multiple of 2^-185 (the ulp of 1e-40), so every intermediate value
 *    of every stage (degree <= 5) is a multiple of 2^-925 and underflow is exact; every
 *    product stays below 2^700 (no overflow); the stage-0, A and B bounds stay normal
 *    numbers, and stage C's (>= 71 u^2 2^-925, possibly subnormal) loses at most 2^-1075
 *    to rounding, far less than the slack 6 u^2 perm between 65 u^2 and 71 u^2. Beyond the
 *    range the argument fails (measured: exact to about [1e-90, 1e+100] for orient3d
 *    and [1e-48, 1e+60] for insphere; not promised).
 *  - Stack: the exact insphere expansion may reach 5760 components in the worst case,
 *    so as_insphere_exact (and stage D) uses about 110 KB of stack.
 *
 * insphere_sos — symbolic perturbation (Edelsbrunner & Muecke's SoS applied to the
 * lifted points; the "first nonzero orient3d minor" rule of Devillers & Teillaud and of
 * geogram's side4 SOS is its first phase). Our scheme:
 *  - insphere(a,b,c,d,e) is the 5x5 determinant D of the rows (x, y, z, h, 1) of the
 *    points in the given order, h = x^2 + y^2 + z^2, i.e. orient4d of the lifted points.
 *  - Perturb every entry of the first four columns of the row of the point with global
 *    id I by its own infinitesimal: h by eps^(2^k), x/y/z by eps^(2^k') where, over ALL
 *    points, the h entries come first ordered by increasing id, then the coordinate
 *    entries ordered by (id, axis). Within one call this is: rank r of the five ids
 *    (0 = smallest), h of rank r -> bit r, coordinate k of rank r -> bit 5 + 3 r + k.
 *  - det(A + E) is a polynomial in eps; the monomial of a partial matching S of
 *    (row, column) pairs has exponent sum(2^bit) = the bitmask of S, so bigger terms
 *    have smaller masks, all exponents are distinct, and the sign is the sign of the
 *    first nonzero coefficient in increasing mask order. By the generalised Laplace
 *    expansion that coefficient is (-1)^(sum rows + sum cols) sgn(matching) times the
 *    minor of A without the rows and columns of S.
 *  - Mask 0 is D itself. Masks 1, 2, 4, 8, 16 (one h entry, the point of rank r) have
 *    the coefficient (-1)^(i+3) orient3d(the other four points in order), i the row of
 *    rank r: the lifted-coordinate perturbation |p|^2 + eps^(2^rank(id)). When a, b, c, d
 *    are not coplanar this phase always decides (e's minor is -orient3d(a,b,c,d) != 0).
 *  - If all five points are coplanar every such minor vanishes; we continue with the
 *    masks >= 32 (coordinate entries). A full matching (|S| = 4) leaves the 1x1 minor
 *    [1], so the sign is never 0; the first one has mask < 2^12, so the scan is short.
 *  - Consistency: the result is exactly sign(det(A + E)), the orient4d of a fixed
 *    (id-keyed, call-independent) perturbation of the lifted points, so any set of calls
 *    is realised by one perturbed point set: swapping two rows flips the sign, permuting
 *    points together with their ids permutes the determinant's rows, and whenever D != 0
 *    the sign is D's. orient3d is not perturbed; for a, b, c, d with orient3d != 0 (a
 *    triangulator only asks insphere_sos for positively oriented tetrahedra) the
 *    coordinate perturbation is never reached and orient3d of the perturbed points has
 *    the unperturbed sign, so the perturbed lifted points, whose lower hull is a regular
 *    triangulation with infinitesimal weights -eps^(2^rank), are consistent with the
 *    orient3d signs the triangulator sees: it builds that regular triangulation, which is
 *    a Delaunay triangulation of the unperturbed points.
 *  - Coincident points (equal coordinates, distinct ids) are handled too: the one with
 *    the smaller id is lifted more, so it is "outside" every sphere through the other;
 *    in a triangulation it becomes hidden (a triangulator should merge duplicates first).
 */
#include "geom/predicates.h"

#include "geom/dd.h"
#include "geom/expansion.h"

#include <float.h>
#include <math.h>
#include <string.h>

/* ---- error bound constants (Shewchuk's, as expressions of u = DBL_EPSILON / 2) ------ */

#define AS_RESULT_ERR ((3.0 + 8.0 * AS_EPS) * AS_EPS)
#define AS_O3D_ERRA ((7.0 + 56.0 * AS_EPS) * AS_EPS)
#define AS_O3D_ERRB ((3.0 + 28.0 * AS_EPS) * AS_EPS)
#define AS_O3D_ERRC ((26.0 + 288.0 * AS_EPS) * AS_EPS * AS_EPS)
#define AS_ISP_ERRA ((16.0 + 224.0 * AS_EPS) * AS_EPS)
#define AS_ISP_ERRB ((5.0 + 72.0 * AS_EPS) * AS_EPS)
#define AS_ISP_ERRC ((71.0 + 1408.0 * AS_EPS) * AS_EPS * AS_EPS)
/* AS_O3D_STATIC = (7 + 256u)u and AS_ISP_STATIC = (16 + 1024u)u: predicates.h (stage 0,
 * exported inline as as_orient3d_filter / as_insphere_filter). */

/* ---- bench-only counters ------------------------------------------------------------- */

#if defined(__GNUC__)
#define AS_NOINLINE __attribute__((noinline))
#else
#define AS_NOINLINE
#endif

#ifdef ANISTAR_BENCH
/* initial-exec: one %fs-relative add per count, no __tls_get_addr call in -fPIC code
 * (which would also make the fast path save registers around it). The fast paths only
 * count calls; stage[0] (settled by the filters) is derived when the counters are read. */
#if defined(__GNUC__)
#define AS_TLS_MODEL __attribute__((tls_model("initial-exec")))
#else
#define AS_TLS_MODEL
#endif
static _Thread_local as_pred_counters as_pc AS_TLS_MODEL;
as_pred_counters *as_pred_counters_get(void) {
    as_pc.orient3d_stage[0] = as_pc.orient3d_calls - as_pc.orient3d_stage[1] -
                              as_pc.orient3d_stage[2] - as_pc.orient3d_stage[3];
    as_pc.insphere_stage[0] = as_pc.insphere_calls - as_pc.insphere_stage[1] -
                              as_pc.insphere_stage[2] - as_pc.insphere_stage[3];
    return &as_pc;
}
void as_pred_counters_reset(void) { memset(&as_pc, 0, sizeof as_pc); }
#define AS_COUNT(field) (as_pc.field++)
#else
#define AS_COUNT(field) ((void)0)
#endif

static inline double as_max4(double a, double b, double c, double d) {
    double m = a > b ? a : b;
    double n = c > d ? c : d;
    return m > n ? m : n;
}

/* ====================================================================================== */
/* orient3d                                                                               */
/* ====================================================================================== */

/* The floating-point determinant of the rows (ad, bd, cd), expanded along z. */
static inline double as_o3d_det(double adx, double ady, double adz, double bdx, double bdy,
                                double bdz, double cdx, double cdy, double cdz) {
    double bc = bdx * cdy - cdx * bdy;
    double ca = cdx * ady - adx * cdy;
    double ab = adx * bdy - bdx * ady;
    return adz * bc + bdz * ca + cdz * ab;
}

/* out = pz [qr] - qz [pr] + rz [pq] (the 3x3 determinant of the raw rows p, q, r), given
 * the exact 2x2 xy-minors [qr], [pr], [pq] (lengths nqr, npr, npq <= 4), compressed.
 * out: 24 doubles. */
static int as_det3_raw(const double *p, const double *q, const double *r, int nqr,
                       const double *qr, int npr, const double *pr, int npq,
                       const double *pq, double *out) {
    double t1[8], t2[8], t3[8], s[16];
    int l1 = as_exp_scale(nqr, qr, p[2], t1);
    int l2 = as_exp_scale(npr, pr, -q[2], t2);
    int l3 = as_exp_scale(npq, pq, r[2], t3);
    int ls = as_exp_sum(l1, t1, l2, t2, s);
    return as_exp_compress(as_exp_sum(ls, s, l3, t3, out), out);
}

/* [pq] = px qy - qx py exactly, compressed (at most 4 components). Returns the length. */
static int as_minor2_raw(const double *p, const double *q, double out[4]) {
    double p1, p0, q1, q0;
    as_two_product(p[0], q[1], &p1, &p0);
    as_two_product(q[0], p[1], &q1, &q0);
    as_two_two_diff(p1, p0, q1, q0, out);
    return as_exp_compress(4, out);
}

/* out = orient3d(a, b, c, d) exactly, as
 * det3(a,b,c) - det3(a,b,d) + det3(a,c,d) - det3(b,c,d) on the raw coordinates (the 4x4
 * determinant of the rows (p, 1) expanded along the ones). out: 96 doubles. */
static int as_o3d_exact_exp(const double *a, const double *b, const double *c,
                            const double *d, double *out) {
    double ab[4], ac[4], ad[4], bc[4], bd[4], cd[4];
    double abc[24], abd[24], acd[24], bcd[24], s1[48], s2[48];
    int nab = as_minor2_raw(a, b, ab), nac = as_minor2_raw(a, c, ac);
    int nad = as_minor2_raw(a, d, ad), nbc = as_minor2_raw(b, c, bc);
    int nbd = as_minor2_raw(b, d, bd), ncd = as_minor2_raw(c, d, cd);
    int l1 = as_det3_raw(a, b, c, nbc, bc, nac, ac, nab, ab, abc);
    int l2 = as_det3_raw(a, b, d, nbd, bd, nad, ad, nab, ab, abd);
    int l3 = as_det3_raw(a, c, d, ncd, cd, nad, ad, nac, ac, acd);
    int l4 = as_det3_raw(b, c, d, ncd, cd, nbd, bd, nbc, bc, bcd);
    as_exp_negate(l2, abd);
    as_exp_negate(l4, bcd);
    int m1 = as_exp_sum(l1, abc, l2, abd, s1);
    int m2 = as_exp_sum(l3, acd, l4, bcd, s2);
    return as_exp_sum(m1, s1, m2, s2, out);
}

static double as_o3d_exact_value(const double *a, const double *b, const double *c,
                                 const double *d) {
    double e[96];
    int n = as_o3d_exact_exp(a, b, c, d, e);
    return as_exp_value(n, e);
}

double as_orient3d_fast(const double *a, const double *b, const double *c,
                        const double *d) {
    return as_o3d_det(a[0] - d[0], a[1] - d[1], a[2] - d[2], b[0] - d[0], b[1] - d[1],
                      b[2] - d[2], c[0] - d[0], c[1] - d[1], c[2] - d[2]);
}

double as_orient3d_exact(const double *a, const double *b, const double *c,
                         const double *d) {
    for (int k = 0; k < 3; k++)
        if (!isfinite(a[k]) || !isfinite(b[k]) || !isfinite(c[k]) || !isfinite(d[k]))
            return NAN;
    double v = as_o3d_exact_value(a, b, c, d);
    return isfinite(v) ? v : NAN; /* overflow (outside the valid range) */
}

/* Stages A-D of orient3d (the semi-static filter failed). Returns the determinant's
 * sign exactly with an approximate magnitude, NaN for non-finite input or overflow. */
static AS_NOINLINE double as_o3d_adapt(const double *a, const double *b, const double *c,
                                       const double *d) {
    double adx = a[0] - d[0], bdx = b[0] - d[0], cdx = c[0] - d[0];
    double ady = a[1] - d[1], bdy = b[1] - d[1], cdy = c[1] - d[1];
    double adz = a[2] - d[2], bdz = b[2] - d[2], cdz = c[2] - d[2];

    /* Stage A. */
    double bdxcdy = bdx * cdy, cdxbdy = cdx * bdy;
    double cdxady = cdx * ady, adxcdy = adx * cdy;
    double adxbdy = adx * bdy, bdxady = bdx * ady;
    double det =
        adz * (bdxcdy - cdxbdy) + bdz * (cdxady - adxcdy) + cdz * (adxbdy - bdxady);
    double perm = (fabs(bdxcdy) + fabs(cdxbdy)) * fabs(adz) +
                  (fabs(cdxady) + fabs(adxcdy)) * fabs(bdz) +
                  (fabs(adxbdy) + fabs(bdxady)) * fabs(cdz);
    if (!(perm <= DBL_MAX)) return NAN;
    double err = AS_O3D_ERRA * perm;
    if (fabs(det) > err) return det;

    /* Stage B: exact determinant of the rounded differences. */
    double p1, p0, q1, q0;
    double bc[4], ca[4], ab[4], t8a[8], t8b[8], t8c[8], t16[16], fin[24];
    as_two_product(bdx, cdy, &p1, &p0);
    as_two_product(cdx, bdy, &q1, &q0);
    as_two_two_diff(p1, p0, q1, q0, bc);
    as_two_product(cdx, ady, &p1, &p0);
    as_two_product(adx, cdy, &q1, &q0);
    as_two_two_diff(p1, p0, q1, q0, ca);
    as_two_product(adx, bdy, &p1, &p0);
    as_two_product(bdx, ady, &q1, &q0);
    as_two_two_diff(p1, p0, q1, q0, ab);
    int la = as_exp_scale(4, bc, adz, t8a);
    int lb = as_exp_scale(4, ca, bdz, t8b);
    int lc = as_exp_scale(4, ab, cdz, t8c);
    int l16 = as_exp_sum(la, t8a, lb, t8b, t16);
    int lf = as_exp_sum(l16, t16, lc, t8c, fin);
    det = as_exp_value(lf, fin);
    err = AS_O3D_ERRB * perm;
    if (det >= err || -det >= err) {
        AS_COUNT(orient3d_stage[1]);
        return det;
    }

    /* Stage C: first-order terms of the differences' rounding errors. */
    double adxt = as_two_diff_tail(a[0], d[0], adx);
    double bdxt = as_two_diff_tail(b[0], d[0], bdx);
    double cdxt = as_two_diff_tail(c[0], d[0], cdx);
    double adyt = as_two_diff_tail(a[1], d[1], ady);
    double bdyt = as_two_diff_tail(b[1], d[1], bdy);
    double cdyt = as_two_diff_tail(c[1], d[1], cdy);
    double adzt = as_two_diff_tail(a[2], d[2], adz);
    double bdzt = as_two_diff_tail(b[2], d[2], bdz);
    double cdzt = as_two_diff_tail(c[2], d[2], cdz);
    if (adxt == 0.0 && bdxt == 0.0 && cdxt == 0.0 && adyt == 0.0 && bdyt == 0.0 &&
        cdyt == 0.0 && adzt == 0.0 && bdzt == 0.0 && cdzt == 0.0) {
        AS_COUNT(orient3d_stage[1]); /* the differences were exact: B is the answer */
        return det;
    }
    err = AS_O3D_ERRC * perm + AS_RESULT_ERR * fabs(det);
    det += (adz * ((bdx * cdyt + cdy * bdxt) - (bdy * cdxt + cdx * bdyt)) +
            adzt * (bdx * cdy - bdy * cdx)) +
           (bdz * ((cdx * adyt + ady * cdxt) - (cdy * adxt + adx * cdyt)) +
            bdzt * (cdx * ady - cdy * adx)) +
           (cdz * ((adx * bdyt + bdy * adxt) - (ady * bdxt + bdx * adyt)) +
            cdzt * (adx * bdy - ady * bdx));
    if (det >= err || -det >= err) {
        AS_COUNT(orient3d_stage[2]);
        return det;
    }

    /* Stage D: exact. */
    AS_COUNT(orient3d_stage[3]);
    return as_o3d_exact_value(a, b, c, d);
}

/* orient3d(a, b, c, d), adaptive exact (contract in predicates.h).
 * design:
 *  - differences from d, the plain determinant, the column sums sx, sy, sz of |diff|;
 *  - |det| > c_o3d sx sy sz: return det (the common case);
 *  - else as_o3d_adapt: stage A, B, C, D (file header). */
double as_orient3d(const double *a, const double *b, const double *c, const double *d) {
    AS_COUNT(orient3d_calls);
    double det = as_orient3d_filter(a, b, c, d);
    if (det != 0.0) return det; /* 0 for NaN: non-finite input goes on */
    return as_o3d_adapt(a, b, c, d);
}

/* ====================================================================================== */
/* insphere                                                                               */
/* ====================================================================================== */

/* The floating-point determinant of the rows (pe, |pe|^2), p = a, b, c, d, expanded
 * along the lift column: dlift abc - clift dab + blift cda - alift bcd. */
static inline double as_isp_det(double aex, double aey, double aez, double bex, double bey,
                                double bez, double cex, double cey, double cez, double dex,
                                double dey, double dez, double *lmax) {
    double ab = aex * bey - bex * aey;
    double bc = bex * cey - cex * bey;
    double cd = cex * dey - dex * cey;
    double da = dex * aey - aex * dey;
    double ac = aex * cey - cex * aey;
    double bd = bex * dey - dex * bey;
    double abc = aez * bc - bez * ac + cez * ab;
    double bcd = bez * cd - cez * bd + dez * bc;
    double cda = cez * da + dez * ac + aez * cd;
    double dab = dez * ab + aez * bd + bez * da;
    double alift = aex * aex + aey * aey + aez * aez;
    double blift = bex * bex + bey * bey + bez * bez;
    double clift = cex * cex + cey * cey + cez * cez;
    double dlift = dex * dex + dey * dey + dez * dez;
    *lmax = as_max4(alift, blift, clift, dlift);
    return (dlift * abc - clift * dab) + (blift * cda - alift * bcd);
}

/* h = x^2 + y^2 + z^2 exactly, compressed. h: 6 doubles. Returns the length. */
static int as_lift_exact(const double *p, double h[6]) {
    double sx[2], sy[2], sz[2], t[4];
    as_two_square(p[0], &sx[1], &sx[0]);
    as_two_square(p[1], &sy[1], &sy[0]);
    as_two_square(p[2], &sz[1], &sz[0]);
    int lt = as_exp_sum(2, sx, 2, sy, t);
    return as_exp_compress(as_exp_sum(lt, t, 2, sz, h), h);
}

/* out = s o h exactly, compressed (o: olen <= 96 components, h: hlen <= 6, s = +-1).
 * out: 12 olen doubles. Returns the length. */
static int as_mul_lift(int olen, const double *o, int hlen, const double *h, double s,
                       double *out) {
    double t[192], acc[2][1152];
    int cur = 0;
    int alen = as_exp_scale(olen, o, s * h[0], acc[0]);
    for (int j = 1; j < hlen; j++) {
        int tl = as_exp_scale(olen, o, s * h[j], t);
        alen = as_exp_sum(alen, acc[cur], tl, t, acc[1 - cur]);
        cur = 1 - cur;
    }
    memcpy(out, acc[cur], (size_t)alen * sizeof(double));
    return as_exp_compress(alen, out);
}

/* insphere(a, b, c, d, e) exactly, as the 5x5 determinant of the raw rows
 * (x, y, z, h, 1) expanded along h: the sum over m of (-1)^(m+1) h_m orient3d(the other
 * four), m 0-based; orient3d(p, q, r, s) = [pqr] - [pqs] + [prs] - [qrs] with the raw
 * 3x3 determinants. Returns a double with the exact sign. Uses about 110 KB of stack
 * (the expansion can reach 5760 components). */
static double as_isp_exact_value(const double *a, const double *b, const double *c,
                                 const double *d, const double *e) {
    const double *p[5] = {a, b, c, d, e};
    double m2[10][4];
    double m3[10][24];
    int l2[10], l3[10];
    int idx2[5][5], idx3[5][5][5];
    int k = 0;
    for (int i = 0; i < 5; i++)
        for (int j = i + 1; j < 5; j++) {
            l2[k] = as_minor2_raw(p[i], p[j], m2[k]);
            idx2[i][j] = k++;
        }
    k = 0;
    for (int i = 0; i < 5; i++)
        for (int j = i + 1; j < 5; j++)
            for (int l = j + 1; l < 5; l++) {
                int jl = idx2[j][l], il = idx2[i][l], ij = idx2[i][j];
                l3[k] = as_det3_raw(p[i], p[j], p[l], l2[jl], m2[jl], l2[il], m2[il],
                                    l2[ij], m2[ij], m3[k]);
                idx3[i][j][l] = k++;
            }
    /* Running sums alternate between big (lengths 1152, 3456, 5760) and small (2304,
     * 4608). */
    double big[5760], small[4608], term[1152];
    int blen = 0, slen = 0;
    for (int m = 0; m < 5; m++) {
        int r[4], n = 0;
        for (int i = 0; i < 5; i++)
            if (i != m) r[n++] = i;
        double neg1[24], neg3[24], s1[48], s2[48], o[96];
        int k0 = idx3[r[0]][r[1]][r[2]], k1 = idx3[r[0]][r[1]][r[3]];
        int k2 = idx3[r[0]][r[2]][r[3]], k3 = idx3[r[1]][r[2]][r[3]];
        memcpy(neg1, m3[k1], (size_t)l3[k1] * sizeof(double));
        memcpy(neg3, m3[k3], (size_t)l3[k3] * sizeof(double));
        as_exp_negate(l3[k1], neg1);
        as_exp_negate(l3[k3], neg3);
        int ls1 = as_exp_sum(l3[k0], m3[k0], l3[k1], neg1, s1);
        int ls2 = as_exp_sum(l3[k2], m3[k2], l3[k3], neg3, s2);
        int lo = as_exp_compress(as_exp_sum(ls1, s1, ls2, s2, o), o);
        double s = (m % 2 == 0) ? -1.0 : 1.0, h[6];
        int lh = as_lift_exact(p[m], h);
        if (m == 0) {
            blen = as_mul_lift(lo, o, lh, h, s, big);
        } else {
            int lt = as_mul_lift(lo, o, lh, h, s, term);
            if (m % 2 == 1)
                slen = as_exp_compress(as_exp_sum(blen, big, lt, term, small), small);
            else
                blen = as_exp_compress(as_exp_sum(slen, small, lt, term, big), big);
        }
    }
    return as_exp_value(blen, big);
}

double as_insphere_fast(const double *a, const double *b, const double *c, const double *d,
                        const double *e) {
    double unused;
    return as_isp_det(a[0] - e[0], a[1] - e[1], a[2] - e[2], b[0] - e[0], b[1] - e[1],
                      b[2] - e[2], c[0] - e[0], c[1] - e[1], c[2] - e[2], d[0] - e[0],
                      d[1] - e[1], d[2] - e[2], &unused);
}

double as_insphere_exact(const double *a, const double *b, const double *c, const double *d,
                         const double *e) {
    for (int k = 0; k < 3; k++)
        if (!isfinite(a[k]) || !isfinite(b[k]) || !isfinite(c[k]) || !isfinite(d[k]) ||
            !isfinite(e[k]))
            return NAN;
    double v = as_isp_exact_value(a, b, c, d, e);
    return isfinite(v) ? v : NAN; /* overflow (outside the valid range) */
}

/* out[4] = p1 q2 - q1 p2 exactly from the rounded differences. */
static void as_minor2(double p1, double p2, double q1, double q2, double out[4]) {
    double x1, x0, y1, y0;
    as_two_product(p1, q2, &x1, &x0);
    as_two_product(q1, p2, &y1, &y0);
    as_two_two_diff(x1, x0, y1, y0, out);
}

/* out = pz [qr] - qz [pr] + rz [pq] with the z entries and minors given; out: 24. */
static int as_det3_of(double pz, double qz, double rz, const double *qr, const double *pr,
                      const double *pq, double *out) {
    double t1[8], t2[8], t3[8], s[16];
    int l1 = as_exp_scale(4, qr, pz, t1);
    int l2 = as_exp_scale(4, pr, -qz, t2);
    int l3 = as_exp_scale(4, pq, rz, t3);
    int ls = as_exp_sum(l1, t1, l2, t2, s);
    return as_exp_compress(as_exp_sum(ls, s, l3, t3, out), out);
}

/* Stages A-D of insphere (the semi-static filter failed). */
/* Stage B' (double-double) of as_isp_adapt.
 * design: stage B evaluates the determinant of the rounded differences exactly, in
 * expansions of up to 1,152 components; on points (nearly) on one sphere — an isotropic
 * metric on a sphere: every Delaunay tet inside it has the sphere itself as circumsphere —
 * stage A fails for most tests and B took 40% of a sphere's run (1.05 million stage-B
 * answers in 1.6 million calls, `--metric euclidean --r0 0.02`) and 80% of a run of two
 * spheres 1e-4 apart. The same determinant in double-double costs a fraction of it, and
 * bounds B's value: each double-double operation errs by at most 7u^2 relative to its
 * exact result on its computed operands (dd.h: 3u^2/(1-4u) add, 3u^2/2 + 4u^3 times a
 * double, 7u^2 product), the 2x2 minors' products are exact, and the longest chain has 7
 * rounding operations (minor, times a double, two sums, times a lift, two sums), so
 * |v - B| <= ((1 + 7u^2)^7 - 1) P <= 50u^2 P for the permanent P of the same expression,
 * and P <= perm (1 + 12u) for stage A's floating-point permanent perm. AS_ISP_ERRDD =
 * 128u^2 covers it with room. When |v| - AS_ISP_ERRDD perm clears B's own bound
 * (ERRB perm) with a relative 8u to spare (for the roundings of |v| and of B's value),
 * B would have returned a value of v's sign; when the differences were exact and
 * |v| > AS_ISP_ERRDD perm, B's value has v's sign and is the answer. Stage C starts from
 * v instead of B's value, its bound widened by AS_ISP_ERRDD perm (71u^2 + 128u^2 instead
 * of 71u^2, plus the rounding term as before): on two spheres 1e-4 apart 2.27 million of
 * 5.95 million calls went to C, each paying B's expansions first. B's expansions now run
 * only for exact differences whose v is within its error of 0 (exactly cospherical
 * points on a grid, say), where B's value is the answer. Only signs are promised (the
 * magnitude is an approximation, anistar.h), and they are the exact ones: the mesher's
 * outputs do not change. No underflow in the valid input range: every value is a
 * multiple of 2^-925 and each error term stays above 2^-1074 relative to perm's scale. */
#define AS_ISP_ERRDD (128.0 * AS_EPS * AS_EPS)

static inline as_dd isp_minor_dd(double p, double q, double r, double s) {
    return as_dd_sub(as_dd_two_prod(p, q), as_dd_two_prod(r, s));
}

static inline as_dd isp_lift_dd(double x, double y, double z) {
    return as_dd_add(as_dd_add(as_dd_two_prod(x, x), as_dd_two_prod(y, y)),
                     as_dd_two_prod(z, z));
}

static AS_NOINLINE double as_isp_adapt(const double *a, const double *b, const double *c,
                                       const double *d, const double *e) {
    double aex = a[0] - e[0], bex = b[0] - e[0], cex = c[0] - e[0], dex = d[0] - e[0];
    double aey = a[1] - e[1], bey = b[1] - e[1], cey = c[1] - e[1], dey = d[1] - e[1];
    double aez = a[2] - e[2], bez = b[2] - e[2], cez = c[2] - e[2], dez = d[2] - e[2];

    /* Stage A (the same floating-point determinant as as_isp_det), with the permanent. */
    double aexbey = aex * bey, bexaey = bex * aey, bexcey = bex * cey, cexbey = cex * bey;
    double cexdey = cex * dey, dexcey = dex * cey, dexaey = dex * aey, aexdey = aex * dey;
    double aexcey = aex * cey, cexaey = cex * aey, bexdey = bex * dey, dexbey = dex * bey;
    double ab = aexbey - bexaey, bc = bexcey - cexbey, cd = cexdey - dexcey;
    double da = dexaey - aexdey, ac = aexcey - cexaey, bd = bexdey - dexbey;
    double abc = aez * bc - bez * ac + cez * ab;
    double bcd = bez * cd - cez * bd + dez * bc;
    double cda = cez * da + dez * ac + aez * cd;
    double dab = dez * ab + aez * bd + bez * da;
    double alift = aex * aex + aey * aey + aez * aez;
    double blift = bex * bex + bey * bey + bez * bez;
    double clift = cex * cex + cey * cey + cez * cez;
    double dlift = dex * dex + dey * dey + dez * dez;
    double det = (dlift * abc - clift * dab) + (blift * cda - alift * bcd);
    double pab = fabs(aexbey) + fabs(bexaey), pbc = fabs(bexcey) + fabs(cexbey);
    double pcd = fabs(cexdey) + fabs(dexcey), pda = fabs(dexaey) + fabs(aexdey);
    double pac = fabs(aexcey) + fabs(cexaey), pbd = fabs(bexdey) + fabs(dexbey);
    double faz = fabs(aez), fbz = fabs(bez), fcz = fabs(cez), fdz = fabs(dez);
    double pabc = faz * pbc + fbz * pac + fcz * pab;
    double pbcd = fbz * pcd + fcz * pbd + fdz * pbc;
    double pcda = fcz * pda + fdz * pac + faz * pcd;
    double pdab = fdz * pab + faz * pbd + fbz * pda;
    double perm = (dlift * pabc + clift * pdab) + (blift * pcda + alift * pbcd);
    if (!(perm <= DBL_MAX)) return NAN;
    double err = AS_ISP_ERRA * perm;
    if (fabs(det) > err) return det;

    /* Stage B': B's determinant in double-double; returned when it settles what B would. */
    const double errdd = AS_ISP_ERRDD * perm;
    as_dd v;
    double mag;
    {
        as_dd xab = isp_minor_dd(aex, bey, bex, aey), xbc = isp_minor_dd(bex, cey, cex, bey);
        as_dd xcd = isp_minor_dd(cex, dey, dex, cey), xda = isp_minor_dd(dex, aey, aex, dey);
        as_dd xac = isp_minor_dd(aex, cey, cex, aey), xbd = isp_minor_dd(bex, dey, dex, bey);
        as_dd yabc = as_dd_add(as_dd_sub(as_dd_mul_d(xbc, aez), as_dd_mul_d(xac, bez)),
                               as_dd_mul_d(xab, cez));
        as_dd ybcd = as_dd_add(as_dd_sub(as_dd_mul_d(xcd, bez), as_dd_mul_d(xbd, cez)),
                               as_dd_mul_d(xbc, dez));
        as_dd ycda = as_dd_add(as_dd_add(as_dd_mul_d(xda, cez), as_dd_mul_d(xac, dez)),
                               as_dd_mul_d(xcd, aez));
        as_dd ydab = as_dd_add(as_dd_add(as_dd_mul_d(xab, dez), as_dd_mul_d(xbd, aez)),
                               as_dd_mul_d(xda, bez));
        as_dd la = isp_lift_dd(aex, aey, aez), lb = isp_lift_dd(bex, bey, bez);
        as_dd lc = isp_lift_dd(cex, cey, cez), ld = isp_lift_dd(dex, dey, dez);
        v = as_dd_add(as_dd_sub(as_dd_mul(ld, yabc), as_dd_mul(lc, ydab)),
                      as_dd_sub(as_dd_mul(lb, ycda), as_dd_mul(la, ybcd)));
        mag = fabs(v.hi) - fabs(v.lo); /* <= |v| (1 + u) */
        if (mag > (AS_ISP_ERRB * perm + errdd) * (1.0 + 8.0 * AS_EPS)) {
            AS_COUNT(insphere_stage[1]);
            return v.hi;
        }
    }

    /* The differences' rounding errors (stage C's tails). */
    double aext = as_two_diff_tail(a[0], e[0], aex);
    double bext = as_two_diff_tail(b[0], e[0], bex);
    double cext = as_two_diff_tail(c[0], e[0], cex);
    double dext = as_two_diff_tail(d[0], e[0], dex);
    double aeyt = as_two_diff_tail(a[1], e[1], aey);
    double beyt = as_two_diff_tail(b[1], e[1], bey);
    double ceyt = as_two_diff_tail(c[1], e[1], cey);
    double deyt = as_two_diff_tail(d[1], e[1], dey);
    double aezt = as_two_diff_tail(a[2], e[2], aez);
    double bezt = as_two_diff_tail(b[2], e[2], bez);
    double cezt = as_two_diff_tail(c[2], e[2], cez);
    double dezt = as_two_diff_tail(d[2], e[2], dez);
    if (aext == 0.0 && bext == 0.0 && cext == 0.0 && dext == 0.0 && aeyt == 0.0 &&
        beyt == 0.0 && ceyt == 0.0 && deyt == 0.0 && aezt == 0.0 && bezt == 0.0 &&
        cezt == 0.0 && dezt == 0.0) {
        /* the differences were exact: B's determinant is the answer, its sign v's when v
         * is farther from 0 than its error, else B's value itself (which may be 0) */
        AS_COUNT(insphere_stage[1]);
        if (mag > errdd * (1.0 + 8.0 * AS_EPS)) return v.hi;
        /* Stage B: exact determinant of the rounded differences. */
        {
            double xab[4], xbc[4], xcd[4], xda[4], xac[4], xbd[4];
            double xabc[24], xbcd[24], xcda[24], xdab[24];
            double ta[288], tb[288], tc[288], td[288], s1[576], s2[576], fin[1152];
            as_minor2(aex, aey, bex, bey, xab);
            as_minor2(bex, bey, cex, cey, xbc);
            as_minor2(cex, cey, dex, dey, xcd);
            as_minor2(dex, dey, aex, aey, xda);
            as_minor2(aex, aey, cex, cey, xac);
            as_minor2(bex, bey, dex, dey, xbd);
            /* abc = aez bc - bez ac + cez ab; bcd = bez cd - cez bd + dez bc;
             * cda = cez da + dez ac + aez cd = cez da - dez (-ac) + aez cd;
             * dab = dez ab + aez bd + bez da. as_det3_of(p, q, r, .) = p X - q Y + r Z. */
            int nabc = as_det3_of(aez, bez, cez, xbc, xac, xab, xabc);
            int nbcd = as_det3_of(bez, cez, dez, xcd, xbd, xbc, xbcd);
            int ncda = as_det3_of(cez, -dez, aez, xda, xac, xcd, xcda);
            int ndab = as_det3_of(dez, -aez, bez, xab, xbd, xda, xdab);
            const double ua[3] = {aex, aey, aez}, ub[3] = {bex, bey, bez};
            const double uc[3] = {cex, cey, cez}, ud[3] = {dex, dey, dez};
            double h[6];
            int lh = as_lift_exact(ua, h);
            int la = as_mul_lift(nbcd, xbcd, lh, h, -1.0, ta);
            lh = as_lift_exact(ub, h);
            int lb = as_mul_lift(ncda, xcda, lh, h, 1.0, tb);
            lh = as_lift_exact(uc, h);
            int lc = as_mul_lift(ndab, xdab, lh, h, -1.0, tc);
            lh = as_lift_exact(ud, h);
            int ld = as_mul_lift(nabc, xabc, lh, h, 1.0, td);
            int l1 = as_exp_sum(ld, td, lc, tc, s1);
            int l2 = as_exp_sum(lb, tb, la, ta, s2);
            int lf = as_exp_sum(l1, s1, l2, s2, fin);
            det = as_exp_value(lf, fin);
        }
        return det;
    }

    /* Stage C: B's value (from B', within errdd of it) plus the first-order terms of the
     * differences' rounding errors. */
    det = v.hi;
    err = AS_ISP_ERRC * perm + errdd + AS_RESULT_ERR * fabs(det);
    /* Differentials of the 2x2 minors: d(pq) = (pxt qy + px qyt) - (qxt py + qx pyt). */
    double dab_ = (aext * bey + aex * beyt) - (bext * aey + bex * aeyt);
    double dbc_ = (bext * cey + bex * ceyt) - (cext * bey + cex * beyt);
    double dcd_ = (cext * dey + cex * deyt) - (dext * cey + dex * ceyt);
    double dda_ = (dext * aey + dex * aeyt) - (aext * dey + aex * deyt);
    double dac_ = (aext * cey + aex * ceyt) - (cext * aey + cex * aeyt);
    double dbd_ = (bext * dey + bex * deyt) - (dext * bey + dex * beyt);
    /* Differentials of the 3x3 minors (same shapes as abc, bcd, cda, dab). */
    double dabc =
        ((aezt * bc + aez * dbc_) - (bezt * ac + bez * dac_)) + (cezt * ab + cez * dab_);
    double dbcd =
        ((bezt * cd + bez * dcd_) - (cezt * bd + cez * dbd_)) + (dezt * bc + dez * dbc_);
    double dcda =
        ((cezt * da + cez * dda_) + (dezt * ac + dez * dac_)) + (aezt * cd + aez * dcd_);
    double ddab =
        ((dezt * ab + dez * dab_) + (aezt * bd + aez * dbd_)) + (bezt * da + bez * dda_);
    /* Differentials of the lifts (times 1/2). */
    double dal = aex * aext + aey * aeyt + aez * aezt;
    double dbl = bex * bext + bey * beyt + bez * bezt;
    double dcl = cex * cext + cey * ceyt + cez * cezt;
    double ddl = dex * dext + dey * deyt + dez * dezt;
    det += ((2.0 * ddl * abc + dlift * dabc) - (2.0 * dcl * dab + clift * ddab)) +
           ((2.0 * dbl * cda + blift * dcda) - (2.0 * dal * bcd + alift * dbcd));
    if (det >= err || -det >= err) {
        AS_COUNT(insphere_stage[2]);
        return det;
    }

    /* Stage D: exact. */
    AS_COUNT(insphere_stage[3]);
    return as_isp_exact_value(a, b, c, d, e);
}

/* insphere(a, b, c, d, e), adaptive exact (contract in predicates.h).
 * design:
 *  - differences from e, the plain 4x4 determinant with lifts, the column sums of
 *    |diff| and the largest lift;
 *  - |det| > c_isp sx sy sz lmax: return det (the common case);
 *  - else as_isp_adapt: stage A, B, C, D (file header). */
double as_insphere(const double *a, const double *b, const double *c, const double *d,
                   const double *e) {
    AS_COUNT(insphere_calls);
    double det = as_insphere_filter(a, b, c, d, e);
    if (det != 0.0) return det; /* 0 for NaN: non-finite input goes on */
    return as_isp_adapt(a, b, c, d, e);
}

/* ====================================================================================== */
/* insphere with symbolic perturbation                                                    */
/* ====================================================================================== */

/* The five rows of the 5x5 matrix and their exact lifts. */
typedef struct as_sos_rows {
    const double *p[5];
    double h[5][6];
    int hlen[5];
} as_sos_rows;

/* out = A[r][col] - A[last][col] exactly (col 0..2: a coordinate, 3: the lift).
 * Returns the length (<= 12). */
static int as_sos_entry(const as_sos_rows *s, int r, int last, int col, double *out) {
    if (col < 3) {
        double x, y;
        as_two_diff(s->p[r][col], s->p[last][col], &x, &y);
        out[0] = y;
        out[1] = x;
        return 2;
    }
    double neg[6];
    for (int i = 0; i < s->hlen[last]; i++) neg[i] = -s->h[last][i];
    return as_exp_sum(s->hlen[r], s->h[r], s->hlen[last], neg, out);
}

/* h = e * f exactly; requires 2 elen flen <= 384 and flen <= 12. h must not alias e or
 * f. Returns h's length. */
static int as_exp_mul(int elen, const double *e, int flen, const double *f, double *h) {
    if (flen > elen) {
        const double *t = e;
        int tl = elen;
        e = f;
        elen = flen;
        f = t;
        flen = tl;
    }
    double sc[384], acc[2][384];
    int cur = 0;
    int alen = as_exp_scale(elen, e, f[0], acc[0]);
    for (int j = 1; j < flen; j++) {
        int sl = as_exp_scale(elen, e, f[j], sc);
        alen = as_exp_sum(alen, acc[cur], sl, sc, acc[1 - cur]);
        cur = 1 - cur;
    }
    memcpy(h, acc[cur], (size_t)alen * sizeof(double));
    return alen;
}

/* out = e00 e11 - e01 e10 exactly (entries of length <= 12, one column at most of length
 * > 2). out: <= 96 doubles. */
static int as_det2_exp(int l00, const double *e00, int l01, const double *e01, int l10,
                       const double *e10, int l11, const double *e11, double *out) {
    double x[48], y[48];
    int lx = as_exp_mul(l00, e00, l11, e11, x);
    int ly = as_exp_mul(l01, e01, l10, e10, y);
    as_exp_negate(ly, y);
    return as_exp_sum(lx, x, ly, y, out);
}

/* The sign of the minor of the 5x5 matrix on the rows rows[0..m-1] (increasing) and the
 * columns cols[0..m-2] (increasing, perturbed columns 0..3) plus the ones column.
 * Subtracting the last row and expanding along the ones column leaves the (m-1)x(m-1)
 * determinant of the row differences. */
static int as_sos_minor_sign(const as_sos_rows *s, const int *rows, int m,
                             const int *cols) {
    if (m == 1) return 1;
    int last = rows[m - 1], n = m - 1;
    double ent[3][3][12];
    int len[3][3];
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            len[i][j] = as_sos_entry(s, rows[i], last, cols[j], ent[i][j]);
    if (n == 1) return as_exp_sign(len[0][0], ent[0][0]);
    if (n == 2) {
        double d[96];
        int l = as_det2_exp(len[0][0], ent[0][0], len[0][1], ent[0][1], len[1][0],
                            ent[1][0], len[1][1], ent[1][1], d);
        return as_exp_sign(l, d);
    }
    /* n == 3: Laplace along row 0. */
    double term[3][384], s01[768], tot[1152];
    int lt[3];
    for (int j = 0; j < 3; j++) {
        int c0 = j == 0 ? 1 : 0, c1 = j == 2 ? 1 : 2;
        double mnr[96];
        int lm = as_det2_exp(len[1][c0], ent[1][c0], len[1][c1], ent[1][c1], len[2][c0],
                             ent[2][c0], len[2][c1], ent[2][c1], mnr);
        lt[j] = as_exp_mul(len[0][j], ent[0][j], lm, mnr, term[j]);
        if (j == 1) as_exp_negate(lt[j], term[j]);
    }
    int l01 = as_exp_sum(lt[0], term[0], lt[1], term[1], s01);
    int l = as_exp_sum(l01, s01, lt[2], term[2], tot);
    return as_exp_sign(l, tot);
}

/* The coordinate phase (all five points coplanar): scan the partial matchings in
 * increasing mask order from 32 on (see the header). */
static int as_sos_coord_phase(const as_sos_rows *s, const int order[5]) {
    for (unsigned mask = 32; mask < (1u << 20); mask++) {
        int er[4], ec[4], n = 0, ok = 1;
        unsigned rows_used = 0, cols_used = 0;
        for (int bit = 0; bit < 20 && ok; bit++) {
            if (!(mask & (1u << bit))) continue;
            if (n == 4) {
                ok = 0;
                break;
            }
            int r, col;
            if (bit < 5) {
                r = order[bit];
                col = 3;
            } else {
                r = order[(bit - 5) / 3];
                col = (bit - 5) % 3;
            }
            if ((rows_used >> r) & 1u || (cols_used >> col) & 1u) ok = 0;
            rows_used |= 1u << r;
            cols_used |= 1u << col;
            er[n] = r;
            ec[n] = col;
            n++;
        }
        if (!ok) continue;
        /* Sign of the matching as a bijection from sorted rows to sorted columns: the
         * parity of the inversions of the columns listed by increasing row. */
        int parity = 0;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                if (er[i] < er[j] && ec[i] > ec[j]) parity ^= 1;
        for (int i = 0; i < n; i++) parity ^= (er[i] + ec[i]) & 1;
        int rows[5], cols[4], m = 0, k = 0;
        for (int r = 0; r < 5; r++)
            if (!((rows_used >> r) & 1u)) rows[m++] = r;
        for (int col = 0; col < 4; col++)
            if (!((cols_used >> col) & 1u)) cols[k++] = col;
        int sg = as_sos_minor_sign(s, rows, m, cols);
        if (sg != 0) return parity ? -sg : sg;
    }
    return 1; /* unreachable: a full matching (mask < 2^12) has the minor [1] */
}

/* insphere with symbolic perturbation (contract in predicates.h; scheme in the file
 * header).
 * design:
 *  - the adaptive insphere; its sign if nonzero;
 *  - rank the rows by id; lift phase: for rank 0..4, the first nonzero
 *    (-1)^(row+3) orient3d(the other four) decides;
 *  - coordinate phase (all five coplanar): as_sos_coord_phase. */
int as_insphere_sos(const double *a, const double *b, const double *c, const double *d,
                    const double *e, int64_t ia, int64_t ib, int64_t ic, int64_t id,
                    int64_t ie) {
    AS_COUNT(insphere_sos_calls);
    double v = as_insphere(a, b, c, d, e);
    if (v > 0) return 1;
    if (v < 0) return -1;
    AS_COUNT(insphere_sos_perturbed);

    as_sos_rows s;
    s.p[0] = a;
    s.p[1] = b;
    s.p[2] = c;
    s.p[3] = d;
    s.p[4] = e;
    int64_t ids[5] = {ia, ib, ic, id, ie};
    int order[5] = {0, 1, 2, 3, 4};
    for (int i = 1; i < 5; i++) /* insertion sort of the rows by id */
        for (int j = i; j > 0 && ids[order[j]] < ids[order[j - 1]]; j--) {
            int t = order[j];
            order[j] = order[j - 1];
            order[j - 1] = t;
        }

    /* Lift phase: masks 1, 2, 4, 8, 16. */
    for (int r = 0; r < 5; r++) {
        int i = order[r];
        const double *q[4];
        int n = 0;
        for (int j = 0; j < 5; j++)
            if (j != i) q[n++] = s.p[j];
        double o = as_orient3d(q[0], q[1], q[2], q[3]);
        if (o != 0.0) {
            int sg = o > 0 ? 1 : -1;
            return ((i + 3) & 1) ? -sg : sg;
        }
    }

    /* Coordinate phase: exact lifts first. */
    for (int i = 0; i < 5; i++) s.hlen[i] = as_lift_exact(s.p[i], s.h[i]);
    return as_sos_coord_phase(&s, order);
}
