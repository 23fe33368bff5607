#include "test_util.h"

#include <stdlib.h>

static void *tu_alloc_fn(void *user, void *ptr, size_t old_size, size_t new_size) {
    tu_alloc *a = user;
    if (new_size == 0) {
        if (ptr) {
            a->live_blocks--;
            a->live_bytes -= old_size;
            free(ptr);
        }
        return NULL;
    }
    if (!ptr || new_size > old_size) {
        long n = a->count++;
        if (a->fail_after >= 0 && n >= a->fail_after) {
            a->failures++;
            return NULL;
        }
    }
    void *q = realloc(ptr, new_size);
    if (!q) return NULL;
    if (!ptr) a->live_blocks++;
    a->live_bytes += new_size - (ptr ? old_size : 0);
    if (a->live_bytes > a->peak_bytes) a->peak_bytes = a->live_bytes;
    return q;
}

void tu_alloc_init(tu_alloc *a, long fail_after) {
    a->fail_after = fail_after;
    a->count = 0;
    a->live_blocks = 0;
    a->live_bytes = 0;
    a->peak_bytes = 0;
    a->failures = 0;
}

anistar_allocator tu_allocator(tu_alloc *a) {
    anistar_allocator al = {tu_alloc_fn, a};
    return al;
}

uint64_t tu_rng_u64(tu_rng *r) {
    uint64_t z = (r->s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

double tu_rng_unit(tu_rng *r) { return (double)(tu_rng_u64(r) >> 11) * 0x1.0p-53; }

double tu_rng_range(tu_rng *r, double lo, double hi) { return lo + (hi - lo) * tu_rng_unit(r); }
