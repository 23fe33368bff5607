/*
 * del3_check.h — shared by the del3 test programs (test_del3, test_del3_debug): checks
 * of a triangulation counted from its tet records, independent of del3's own validators.
 */
#ifndef ANISTAR_TEST_DEL3_CHECK_H
#define ANISTAR_TEST_DEL3_CHECK_H

#include "geom/del3.h"

/* All live tets of d as quadruples of global ids (the infinite vertex as -1), each sorted,
 * the list sorted: 4 *count values, malloc'd (free it). */
int64_t *tu_del3_canon(const as_del3 *d, size_t *count);

/* Sort 4 values in place; sort keys[0..n) and return how many distinct values it has. */
void tu_sort4(int64_t q[4]);
int64_t tu_count_unique(int64_t *keys, size_t n);

/* Fail unless a and b have the same live tets as sets of global-id quadruples (the
 * infinite vertex as -1), whatever their slot numbering and vertex order. */
void tu_del3_assert_same(const as_del3 *a, const as_del3 *b);

/* Fail unless the finite tets satisfy Euler's relation of a triangulated ball,
 * V - E + F - T = 1 (V = d->nv, E and F counted by deduplicating the simplices of the
 * finite tets). */
void tu_del3_assert_euler(const as_del3 *d);

#endif
