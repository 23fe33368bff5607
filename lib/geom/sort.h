/*
 * sort.h — internal: spatial sorts of point sets for incremental insertion
 * (DESIGN.md 4.3; BRIO: Amenta, Choi, Rote 2003; Hilbert curve order).
 *
 * A good insertion order makes the walk of every insertion short (consecutive points are
 * close) while keeping the randomised-incremental bounds (BRIO rounds of doubling size).
 * Everything is deterministic: the same input and seed give the same order.
 */
#ifndef ANISTAR_SORT_H
#define ANISTAR_SORT_H

#include <stdint.h>

#include "core.h"

/*
 * The Hilbert index of cell (x, y, z) of a 2^bits grid (bits in 1..21), in
 * [0, 2^(3 bits)): consecutive indices are face-adjacent cells.
 * design: the curve of Skilling's transpose form (J. Skilling, "Programming the Hilbert
 *   curve", 2004), computed by a 24-state table machine on the interleaved bits: one
 *   table load per level (sort.c; test_del3 checks it against the transpose form).
 */
uint64_t as_hilbert3_index(uint32_t x, uint32_t y, uint32_t z, int bits);

/*
 * Write into order[0..n-1] a permutation of 0..n-1 sorting the points pts[3i..3i+2] along
 * a Hilbert curve on a 2^21 grid over their bounding cube (ties keep the input order).
 * A median-split curve was tried: on surface samples it cuts thin slabs and made the
 * walks of del3 40% longer.
 * Returns ANISTAR_OK, ANISTAR_EINVAL (n < 0 or a non-finite coordinate) or ANISTAR_ENOMEM.
 */
anistar_status as_sort_hilbert(anistar_context *ctx, const double *pts, int32_t n,
                               int32_t *order);

/*
 * The same with BRIO rounds: each point i falls in round r(i) (a geometric law of ratio
 * 1/8 from a hash of i and seed: 7/8 of the points in the last round, 7/64 in the one
 * before, ...; the first round holds about 64 points or more); points are sorted by round,
 * then along the Hilbert curve inside a round. Returns as as_sort_hilbert.
 */
anistar_status as_sort_brio(anistar_context *ctx, const double *pts, int32_t n, uint64_t seed,
                            int32_t *order);

#endif /* ANISTAR_SORT_H */
