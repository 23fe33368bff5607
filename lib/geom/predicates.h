/*
 * predicates.h — internal: exact geometric predicates (DESIGN.md 4.1).
 *
 * Every predicate comes as a family:
 *   _fast   plain floating-point determinant (for benches and tests only);
 *   (plain) adaptive exact: static filter -> adaptive stages -> exact expansion;
 *   _exact  the exact expansion directly (for tests).
 * The sign of the adaptive and exact versions is always the sign of the exact
 * determinant for inputs in the valid range documented in anistar.h.
 *
 * Conventions are Shewchuk's (see anistar.h).
 */
#ifndef ANISTAR_PREDICATES_H
#define ANISTAR_PREDICATES_H

#include <stdint.h>

double as_orient3d(const double *a, const double *b, const double *c, const double *d);
double as_orient3d_fast(const double *a, const double *b, const double *c, const double *d);
double as_orient3d_exact(const double *a, const double *b, const double *c, const double *d);

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
 * a caller bug. See predicates.c for the scheme and why it is consistent with
 * as_orient3d.
 */
int as_insphere_sos(const double *a, const double *b, const double *c, const double *d,
                    const double *e, int64_t ia, int64_t ib, int64_t ic, int64_t id,
                    int64_t ie);

#ifdef ANISTAR_BENCH
/* Per-stage counters, compiled into bench builds only (thread-local, so reentrancy is
 * kept). stage[0] = settled by the static/first filter, [1..] = later adaptive stages,
 * last = exact expansion, sos = symbolic perturbation needed. */
typedef struct as_pred_counters {
    uint64_t orient3d_calls, orient3d_stage[4];
    uint64_t insphere_calls, insphere_stage[4];
    uint64_t insphere_sos_calls, insphere_sos_perturbed;
} as_pred_counters;
as_pred_counters *as_pred_counters_get(void);
void as_pred_counters_reset(void);
#endif

#endif /* ANISTAR_PREDICATES_H */
