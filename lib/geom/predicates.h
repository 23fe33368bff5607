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

#include <stdint.h>

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
