/*
 * predicates.h — internal: exact geometric predicates (DESIGN.md 4.1).
 *
 * Every predicate comes as a family:
 *   _fast   plain floating-point determinant (for benches and tests only);
 *   (plain) adaptive exact: static filter -> adaptive stages -> exact expansion;
 *   _exact  the exact expansion directly (for tests).
 * The sign of the adaptive and exact versions is always the sign of the exact
 * determinant for inputs in the valid range documented in anistar.h (finite, each
 * coordinate 0 or of magnitude in [1e-40, 1e40]); the value approximates the
 * determinant (the _exact value is the exact determinant rounded, to a few ulps).
 * Non-finite input gives NaN (adaptive and _exact; _fast returns whatever the
 * arithmetic gives). All are reentrant (no state; the exact insphere uses ~110 KB of
 * stack in the worst case).
 *
 * Conventions are Shewchuk's (see anistar.h): orient3d(a,b,c,d) = det[a-d; b-d; c-d] > 0
 * when d is below the plane of a, b, c (a, b, c counterclockwise seen from above);
 * insphere(a,b,c,d,e) > 0 when e is inside the sphere through a, b, c, d and
 * orient3d(a,b,c,d) > 0.
 */
#ifndef ANISTAR_PREDICATES_H
#define ANISTAR_PREDICATES_H

#include <float.h>
#include <math.h>
#include <stdint.h>

/* ---- stage 0 (the semi-static filters), inline for the hot loops of callers ------------
 * as_orient3d_filter / as_insphere_filter return the plain floating-point determinant when
 * its sign is certified (|det| > c * sx * sy * sz [* lmax]: the bound and its derivation
 * are in predicates.c, "Stage-0 constants"), else 0 (also for non-finite input): the
 * caller then calls as_orient3d / as_insphere, which are always exact. The adaptive
 * predicates start with exactly these filters. */
#if defined(__GNUC__) || defined(__clang__)
#define AS_PRED_INLINE static inline __attribute__((always_inline))
#else
#define AS_PRED_INLINE static inline
#endif
#define AS_O3D_STATIC ((7.0 + 256.0 * (DBL_EPSILON * 0.5)) * (DBL_EPSILON * 0.5))
#define AS_ISP_STATIC ((16.0 + 1024.0 * (DBL_EPSILON * 0.5)) * (DBL_EPSILON * 0.5))

AS_PRED_INLINE double as_orient3d_filter(const double *a, const double *b, const double *c,
                                        const double *d) {
    double adx = a[0] - d[0], bdx = b[0] - d[0], cdx = c[0] - d[0];
    double ady = a[1] - d[1], bdy = b[1] - d[1], cdy = c[1] - d[1];
    double adz = a[2] - d[2], bdz = b[2] - d[2], cdz = c[2] - d[2];
    double bc = bdx * cdy - cdx * bdy;
    double ca = cdx * ady - adx * cdy;
    double ab = adx * bdy - bdx * ady;
    double det = adz * bc + bdz * ca + cdz * ab;
    double sx = fabs(adx) + fabs(bdx) + fabs(cdx);
    double sy = fabs(ady) + fabs(bdy) + fabs(cdy);
    double sz = fabs(adz) + fabs(bdz) + fabs(cdz);
    double bound = AS_O3D_STATIC * (sx * sy * sz);
    return fabs(det) > bound ? det : 0.0; /* false for NaN */
}

/* as_insphere_filter tries a cheaper bound before its own B = c ((sx sy sz) lmax):
 *   Bc = K lmax^2 sqrt(lmax),  K = 64 c (1 + 64 u)   (c = AS_ISP_STATIC, u = 2^-53).
 * Bc >= B, so |det| > Bc certifies the sign as |det| > B does (predicates.c proves B), and
 * the filter decides exactly what it decided without Bc. Proof of Bc >= B: every rounded
 * difference x of the filter has x^2 <= L / (1 - u)^3 for the computed lift L of its point
 * (three roundings, all terms positive), so |x| <= sqrt(lmax) (1 - u)^-1.5; the computed sx
 * (two roundings) is at most 4 sqrt(lmax) (1 + u)^2 (1 - u)^-1.5, the same for sy and sz,
 * and the computed B at most 64 c lmax^2.5 (1 + u)^10 (1 - u)^-4.5; the computed Bc
 * (lmax^2, K times it, sqrt, the last product: four roundings) is at least
 * K lmax^2.5 (1 - u)^4 >= 64 c lmax^2.5 (1 + 61 u) (1 - u)^4, which exceeds it. Bc costs a
 * square root and three products instead of 12 absolute values, 9 sums and 4 products,
 * and decides nearly every test (at most ~8x looser than B on typical tetrahedra). */
#define AS_ISP_CHEAP (64.0 * AS_ISP_STATIC * (1.0 + 64.0 * (DBL_EPSILON * 0.5)))

AS_PRED_INLINE double as_insphere_filter(const double *a, const double *b, const double *c,
                                        const double *d, const double *e) {
    double aex = a[0] - e[0], bex = b[0] - e[0], cex = c[0] - e[0], dex = d[0] - e[0];
    double aey = a[1] - e[1], bey = b[1] - e[1], cey = c[1] - e[1], dey = d[1] - e[1];
    double aez = a[2] - e[2], bez = b[2] - e[2], cez = c[2] - e[2], dez = d[2] - e[2];
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
    double det = (dlift * abc - clift * dab) + (blift * cda - alift * bcd);
    double m1 = alift > blift ? alift : blift, m2 = clift > dlift ? clift : dlift;
    double lmax = m1 > m2 ? m1 : m2;
    if (fabs(det) > AS_ISP_CHEAP * (lmax * lmax) * sqrt(lmax)) return det;
    double sx = (fabs(aex) + fabs(bex)) + (fabs(cex) + fabs(dex));
    double sy = (fabs(aey) + fabs(bey)) + (fabs(cey) + fabs(dey));
    double sz = (fabs(aez) + fabs(bez)) + (fabs(cez) + fabs(dez));
    double bound = AS_ISP_STATIC * ((sx * sy * sz) * lmax);
    return fabs(det) > bound ? det : 0.0; /* false for NaN */
}

double as_orient3d(const double *a, const double *b, const double *c, const double *d);
double as_orient3d_fast(const double *a, const double *b, const double *c, const double *d);
double as_orient3d_exact(const double *a, const double *b, const double *c,
                         const double *d);

double as_insphere(const double *a, const double *b, const double *c, const double *d,
                   const double *e);
double as_insphere_fast(const double *a, const double *b, const double *c, const double *d,
                        const double *e);
double as_insphere_exact(const double *a, const double *b, const double *c, const double *d,
                         const double *e);

/*
 * Insphere with symbolic perturbation keyed on integer ids (global site ids, never
 * addresses). Returns +1 when e is inside the perturbed sphere through a, b, c, d and
 * -1 when outside, with the same orientation convention as as_insphere (the result is
 * for orient3d(a,b,c,d) > 0; it flips with the orientation). Never returns 0 when the
 * five ids are distinct. The ids must be distinct; equal ids with different points is
 * a caller bug. Coincident points with distinct ids are allowed (the point with the
 * smaller id is lifted higher): if e coincides with a vertex p of a positively oriented
 * a, b, c, d, the result is -1 when id(e) < id(p), else +1; a triangulator should still
 * merge duplicates first. Inputs must be finite. See
 * predicates.c for the scheme and why it is consistent with as_orient3d.
 */
int as_insphere_sos(const double *a, const double *b, const double *c, const double *d,
                    const double *e, int64_t ia, int64_t ib, int64_t ic, int64_t id,
                    int64_t ie);

#ifdef ANISTAR_BENCH
/* Per-stage counters, compiled into bench builds only (thread-local, so reentrancy is
 * kept). stage[0] = settled by the filters (semi-static, then Shewchuk's stage A),
 * [1] = stage B (exact determinant of the rounded differences, also when those were
 * exact), [2] = stage C (first-order tail correction), [3] = exact expansion (stage D);
 * insphere_sos_perturbed = calls whose exact insphere was 0. The fast paths only count
 * calls: stage[0] is derived (calls minus the later stages) by as_pred_counters_get,
 * which returns this thread's counters. _exact and _fast variants are not counted. */
typedef struct as_pred_counters {
    uint64_t orient3d_calls, orient3d_stage[4];
    uint64_t insphere_calls, insphere_stage[4];
    uint64_t insphere_sos_calls, insphere_sos_perturbed;
} as_pred_counters;
as_pred_counters *as_pred_counters_get(void);
void as_pred_counters_reset(void);
#endif

#endif /* ANISTAR_PREDICATES_H */
