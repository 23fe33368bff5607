/*
 * bench_util.h — shared by the benchmarks: CPU-time clock (robust on a shared machine), a
 * deterministic generator, and a fatal-error exit for failed library calls.
 */
#ifndef ANISTAR_BENCH_UTIL_H
#define ANISTAR_BENCH_UTIL_H

#include "anistar.h"

#include <stdint.h>

/* CPU seconds of this process. */
double bench_cpu_seconds(void);
/* Monotonic wall-clock seconds. */
double bench_wall_seconds(void);

typedef struct bench_rng {
    uint64_t s;
} bench_rng;
/* 64 random bits (SplitMix64 of the state). */
uint64_t bench_u64(bench_rng *r);
/* Uniform in [0, 1) with 53 random bits (the top bits of bench_u64). */
double bench_unit(bench_rng *r);

/* Print "PROGRAM: WHAT failed: STATUS (message)" on stderr and exit 1. */
void bench_die(const char *program, anistar_context *ctx, anistar_status st, const char *what);

#endif
