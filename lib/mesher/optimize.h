/*
 * optimize.h — internal: the vertex optimisation post-pass (paper 6.2, DESIGN.md 4.9),
 * run after a complete refinement when the parameter optimize is 1.
 */
#ifndef ANISTAR_OPTIMIZE_H
#define ANISTAR_OPTIMIZE_H

#include <stdint.h>

#include "mesher/mesher.h"

/* Passes over the vertices at most (each pass visits the vertices whose neighbourhood
 * changed in the previous one). */
#define AS_OPTIMIZE_MAX_PASSES 4

/* The step threshold h of paper 6.2, relative: candidate positions are halved toward v
 * until d_v(v, v') <= h, with h = AS_OPTIMIZE_H times the mean surface radius r_v(tau)
 * of v's facets. */
#define AS_OPTIMIZE_H 0.05

typedef struct as_optimize_counters {
    uint64_t moved;  /* accepted moves */
    uint64_t tries;  /* candidate positions tested (moves performed, accepted or undone) */
    uint64_t passes; /* passes run */
    int stopped;     /* the stop flag ended it early (the star set stays valid) */
    double seconds;
} as_optimize_counters;

/*
 * Optimise the positions of the sites of a complete star set (0 inconsistent facets) in
 * place. Returns OK (also when there is nothing to do: ss not complete), ENOMEM, EINVAL
 * (metric or surface errors), EINTERNAL. On an error ss is only fit for destruction.
 * design (paper 6.2, DESIGN.md 4.9):
 *  1. for a site v: b_v = the M_v-area-weighted mean of the surface centers c_v(tau) of
 *     the facets tau of S_v (an M_v-barycenter: F_v is linear, so the weighted mean of
 *     the points is the M_v one), projected on S;
 *  2. a pass sorts the candidate sites by decreasing d_v(v, b_v) (ties by id) and visits
 *     them in turn, recomputing b_v at the visit (neighbours may have moved since);
 *  3. v' = b_v is tried by moving v (starmove.c) and checking: no inconsistent facet,
 *     every touched star a closed fan, no facet of a touched star violating rule 1 or 2
 *     in that star's metric, and the sum of the squared radius-edge ratios over the
 *     facets of the touched stars (each in its star's metric: exactly the terms of the
 *     histogram that can change) strictly decreases; otherwise the move is undone and
 *     v' = proj((v + v') / 2), while d_v(v, v') > h;
 *  4. the next pass visits the sites of the stars touched by accepted moves; stop when
 *     a pass moves nothing or after AS_OPTIMIZE_MAX_PASSES.
 *  The quality condition of 3 is our addition to the paper (which accepts any valid v'):
 *  it makes the mean squared radius-edge ratio decrease monotonically, the point of the
 *  pass, instead of on average.
 */
anistar_status as_optimize_starset(as_starset *ss, const as_mesher_params *prm,
                                   const atomic_int *stop, as_optimize_counters *cnt);

/*
 * The post-pass on a finished run: if (*out)->stats.complete, optimise ss, then replace
 * *out by the output of the optimised star set, whose statistics keep the refinement's
 * counters and times and add histogram_before / rho2_mean_before (the statistics of the
 * mesh before) and the optimize_* counters. Nothing happens for an incomplete mesh. On an
 * error *out is freed and set to NULL.
 */
anistar_status as_mesher_optimize(as_starset *ss, const as_mesher_params *prm,
                                  const atomic_int *stop, anistar_mesh **out, int *stopped);

#endif /* ANISTAR_OPTIMIZE_H */
