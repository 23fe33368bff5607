/*
 * core.h — internal: the context structure, allocation through the context allocator,
 * and error reporting. Every layer may include it (it depends on nothing but the
 * public header).
 *
 * Rules for library code:
 *  - allocate only through as_alloc/as_realloc/as_free (they use the context allocator,
 *    so tests can inject failures and users can pool);
 *  - every fallible function returns anistar_status and, on failure, sets the message
 *    with as_fail(ctx, status, "what went wrong: %s", ...);
 *  - internal symbols use the prefix as_ and are hidden from the shared library by
 *    -fvisibility=hidden (only ANISTAR_API symbols are exported).
 */
#ifndef ANISTAR_CORE_H
#define ANISTAR_CORE_H

#include "anistar.h"

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#define AS_ERRMSG_SIZE 512

struct anistar_context {
    anistar_allocator alloc;
    anistar_status last_status;
    char last_error[AS_ERRMSG_SIZE];
    /* bytes held through as_alloc/as_realloc/as_free, and the most held at once since
     * peak was last reset (the mesher's memory statistics); atomic: the threads of a
     * pool (pool.h) count into their owner's */
    _Atomic size_t bytes, peak;
    /* a thread's context of a pool: its allocations are counted in owner (NULL: in this
     * context) */
    anistar_context *owner;
};

#if defined(__GNUC__) || defined(__clang__)
#define AS_PRINTF(f, a) __attribute__((format(printf, f, a)))
#define AS_UNLIKELY(x) __builtin_expect(!!(x), 0)
#define AS_LIKELY(x) __builtin_expect(!!(x), 1)
#else
#define AS_PRINTF(f, a)
#define AS_UNLIKELY(x) (x)
#define AS_LIKELY(x) (x)
#endif

/* Record status st and a formatted one-line message in ctx; returns st so that callers
 * can write `return as_fail(ctx, ANISTAR_EINVAL, "r0 must be > 0, got %g", r0);`.
 * ctx may be NULL (then nothing is recorded). */
anistar_status as_fail(anistar_context *ctx, anistar_status st, const char *fmt, ...)
    AS_PRINTF(3, 4);

/* Clear the last error of ctx (successful public calls need not call it). */
void as_clear_error(anistar_context *ctx);

/* Allocation. Sizes are in bytes. as_alloc(ctx, 0) returns NULL. The context counts the
 * bytes held (callers pass the sizes they allocated with, as the allocator contract
 * requires). */
static inline void as_count_bytes(anistar_context *ctx, size_t freed, size_t got) {
    anistar_context *c = ctx->owner ? ctx->owner : ctx;
    if (got >= freed) {
        size_t d = got - freed;
        size_t b = atomic_fetch_add_explicit(&c->bytes, d, memory_order_relaxed) + d;
        size_t p = atomic_load_explicit(&c->peak, memory_order_relaxed);
        while (b > p && !atomic_compare_exchange_weak_explicit(&c->peak, &p, b, memory_order_relaxed,
                                                               memory_order_relaxed)) {
        }
    } else {
        atomic_fetch_sub_explicit(&c->bytes, freed - got, memory_order_relaxed);
    }
}
static inline void *as_alloc(anistar_context *ctx, size_t n) {
    if (n == 0) return NULL;
    void *q = ctx->alloc.fn(ctx->alloc.user, NULL, 0, n);
    if (q) as_count_bytes(ctx, 0, n);
    return q;
}
static inline void *as_realloc(anistar_context *ctx, void *p, size_t old_n, size_t new_n) {
    if (!p) old_n = 0;
    if (new_n == 0) {
        if (p) {
            ctx->alloc.fn(ctx->alloc.user, p, old_n, 0);
            as_count_bytes(ctx, old_n, 0);
        }
        return NULL;
    }
    void *q = ctx->alloc.fn(ctx->alloc.user, p, old_n, new_n);
    if (q) as_count_bytes(ctx, old_n, new_n);
    return q;
}
static inline void as_free(anistar_context *ctx, void *p, size_t n) {
    if (p) {
        ctx->alloc.fn(ctx->alloc.user, p, n, 0);
        as_count_bytes(ctx, n, 0);
    }
}

/* Overflow-checked size arithmetic: returns 0 and sets *out on success, -1 on overflow. */
static inline int as_mul_size(size_t a, size_t b, size_t *out) {
    if (b != 0 && a > SIZE_MAX / b) return -1;
    *out = a * b;
    return 0;
}

/* Allocate an array of count elements of size bytes, overflow-checked; NULL on failure
 * or when count == 0. */
static inline void *as_alloc_array(anistar_context *ctx, size_t count, size_t size) {
    size_t n;
    if (as_mul_size(count, size, &n)) return NULL;
    return as_alloc(ctx, n);
}

/* Global ids of the mesher's points (corners, poles, sites; lib/mesher/starset.h): the
 * width of every id the star set stores (star vertices, restricted facets, facet keys,
 * queues, events) is this one switch. 32 bits by default, measured: 64-bit ids cost 8.6%
 * more memory per output vertex on the paper torus (docs/algorithm.md, "Global ids"), and
 * 2^31 sites would be 5.9 TB at our bytes per vertex. -DAS_GID64: 64-bit storage (the id
 * limit stays 2^31 - 1: counts, loops and the spatial indexes are int32). */
#ifdef AS_GID64
typedef int64_t as_gid;
#else
typedef int32_t as_gid;
#endif

/* Grow *p (an array of *cap elements of elem bytes) to hold at least need elements,
 * geometric growth. Returns 0 on success, -1 on failure (then *p and *cap unchanged). */
int as_grow(anistar_context *ctx, void **p, size_t *cap, size_t need, size_t elem);

/* Seconds on the monotonic clock (CLOCK_MONOTONIC): for time limits and timings. */
double as_now_seconds(void);

/*
 * A halt condition that long passes test between their items (the zone check of the
 * final checks takes tens of seconds on a large run): the run's deadline and the
 * caller's stop flag. as_halt_due may be called from any thread; the first call that
 * finds the condition due records why (AS_HALT_TIME or AS_HALT_STOP) in halted, and every
 * call after it returns 1.
 */
enum { AS_HALT_NONE = 0, AS_HALT_TIME, AS_HALT_STOP };
typedef struct as_halt {
    double deadline;  /* as_now_seconds() after which the pass stops; 0: none */
    atomic_int *stop; /* nonzero: stop; NULL: no flag */
    atomic_int halted;
} as_halt;

/* 1 when h (not NULL) is due: halted already, the stop flag set, or the deadline past. */
int as_halt_due(as_halt *h);

#endif /* ANISTAR_CORE_H */
