/*
 * test_util.h — shared by the test programs: a counting allocator with failure
 * injection (Lua's test build does the same), paths, and a deterministic RNG.
 */
#ifndef ANISTAR_TEST_UTIL_H
#define ANISTAR_TEST_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "anistar.h"

#ifndef AS_TEST_BUILD_DIR
#define AS_TEST_BUILD_DIR "build"
#endif
#ifndef AS_TEST_DATA_DIR
#define AS_TEST_DATA_DIR "test/data"
#endif

/* A counting allocator: fail_after < 0 never fails; otherwise the allocation number
 * fail_after (0-based, counting allocations and growing reallocations) and every later
 * one fail. live_bytes and live_blocks must be 0 after everything is freed. */
typedef struct tu_alloc {
    long fail_after;
    long count;
    long live_blocks;
    size_t live_bytes;
    size_t peak_bytes;
    long failures;
} tu_alloc;

void tu_alloc_init(tu_alloc *a, long fail_after);
anistar_allocator tu_allocator(tu_alloc *a);

/* SplitMix64 / xoshiro-style deterministic generator for tests. */
typedef struct tu_rng {
    uint64_t s;
} tu_rng;
uint64_t tu_rng_u64(tu_rng *r);
double tu_rng_unit(tu_rng *r); /* uniform in [0, 1) with 53 random bits */
double tu_rng_range(tu_rng *r, double lo, double hi);

#endif
