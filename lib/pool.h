/*
 * pool.h — internal: a fixed set of worker threads (pthreads) that run indexed tasks for
 * one caller (issue 15; docs/algorithm.md, "Threads").
 *
 * as_pool_run(pool, n, fn, arg) runs fn for the tasks 0..n-1, on the caller's thread and
 * the workers, and returns when all have run. Which thread runs a task is not fixed
 * (tasks are claimed in index order by whichever thread is free): a task must compute
 * the same result on any thread, writing only what belongs to its index, and use the
 * per-thread slot it is given (0..threads-1) for scratch. That is what keeps every
 * output the same for every thread count.
 *
 * Each thread runs its tasks under its own context: the allocator and the byte counters
 * are the owner's (counted atomically), the error message is the thread's. When tasks
 * fail, every task still runs, and the failure of the lowest task index is returned with
 * its message copied into the owner's context, so errors too do not depend on timing.
 *
 * The workers wait for work by spinning for a bounded time (when the pool has no more
 * threads than online cores) and then sleeping on a condition variable: the parallel
 * sections of the mesher last tens of microseconds, a sleep-and-wake costs about as much.
 */
#ifndef ANISTAR_POOL_H
#define ANISTAR_POOL_H

#include <stdint.h>

#include "core.h"

typedef struct as_pool as_pool;

/* A task: index task, on per-thread slot thread (0 = the caller), allocating and failing
 * through tctx. */
typedef anistar_status (*as_pool_fn)(void *arg, int32_t task, int thread, anistar_context *tctx);

/* A pool of nthreads threads in all (the caller and nthreads - 1 workers; nthreads >= 1,
 * at most AS_POOL_MAX_THREADS). ANISTAR_OK, ENOMEM, or EINTERNAL when a thread cannot be
 * created (the message says why). */
#define AS_POOL_MAX_THREADS 1024
anistar_status as_pool_new(anistar_context *ctx, int nthreads, as_pool **out);

/* Stop and join the workers, free the pool (NULL: nothing). */
void as_pool_free(as_pool *p);

/* The number of threads (per-thread slots) of p; 1 for NULL. */
int as_pool_threads(const as_pool *p);

/* The context of per-thread slot t (t = 0: the caller's, for serial work in the same
 * accounting). */
anistar_context *as_pool_context(as_pool *p, int t);

/* Run fn(arg, i, thread, ctx_thread) for i in [0, n) (see above); p not NULL (a caller
 * without a pool runs its tasks itself, on its own context). One thread or n < 2: on the
 * caller's thread, in order. ANISTAR_OK, or the status of the lowest failing task. */
anistar_status as_pool_run(as_pool *p, int32_t n, as_pool_fn fn, void *arg);

#endif
