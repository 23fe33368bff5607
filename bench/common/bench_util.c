#include "bench_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

double bench_cpu_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double bench_wall_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

uint64_t bench_u64(bench_rng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

double bench_unit(bench_rng *r) { return (double)(bench_u64(r) >> 11) * 0x1.0p-53; }

void bench_die(const char *program, anistar_context *ctx, anistar_status st, const char *what) {
    fprintf(stderr, "%s: %s failed: %s (%s)\n", program, what, anistar_status_name(st),
            anistar_last_error(ctx));
    exit(1);
}
