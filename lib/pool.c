/*
 * pool.c — worker threads for indexed tasks (see pool.h).
 */
#include "pool.h"

#include <pthread.h>
#include <string.h>
#include <unistd.h>

/* design: how long an idle worker spins before it sleeps, in polls of the generation
 * counter (a poll with a pause is some tens of nanoseconds: about 0.2-1 ms in all). The
 * serial stretches between the mesher's parallel sections are of that order; a worker
 * that sleeps costs a wake-up (a futex call and a reschedule) at the next section. */
#define POOL_SPIN 20000
/* two cache lines */
#define POOL_LINE 128

typedef struct pool_slot {
    anistar_context ctx;      /* the thread's context (owner: the pool's) */
    int32_t fail_task;        /* the lowest task index that failed on this thread, or -1 */
    anistar_status fail_status;
    char fail_msg[AS_ERRMSG_SIZE];
    pthread_t th;
    int started;
    as_pool *pool;
    int index;
} pool_slot;

struct as_pool {
    anistar_context *ctx;
    int n;                    /* threads in all (slot 0: the caller) */
    int spin;                 /* spin before sleeping (no more threads than cores) */
    pool_slot *slot;
    pthread_mutex_t mu;
    pthread_cond_t start, done;
    int32_t ntask;
    as_pool_fn fn;
    void *arg;
    /* design: the counters the threads write, each on its own pair of cache lines (the
     * adjacent-line prefetcher pairs them), away from what the idle workers poll: with
     * gen, next and busy on one line, a worker's spin made the caller's every task claim
     * a coherence miss (the paper torus, the caller alone claiming: 8% more time in the
     * tasks) */
    char pad0[POOL_LINE];
    _Atomic uint64_t gen;     /* incremented by each run */
    _Atomic int quit;
    char pad1[POOL_LINE];
    _Atomic int32_t next;     /* the next task to claim */
    char pad2[POOL_LINE];
    _Atomic int busy;         /* workers still in the current run */
    char pad3[POOL_LINE];
};

static inline void cpu_pause(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

/* Claim and run tasks until none is left.
 * design: guided claims — a claim takes 1/(2T) of the tasks left (at least one), so a run
 * of n tasks costs O(T log n) claims instead of n: the mesher's sections are ~90 tasks of
 * ~3 us on average, and with every task claimed alone the claims' atomic counter moved
 * between the cores at each one (the paper torus, 2 threads: 243,618 claims, 2-3% of the
 * time in the tasks). The last claims are single tasks, so the threads still end
 * together; which thread runs a task never matters (pool.h). */
static void work(as_pool *p, pool_slot *s) {
    const int32_t n = p->ntask, div = 2 * p->n;
    for (;;) {
        int32_t left = n - atomic_load_explicit(&p->next, memory_order_relaxed);
        if (left <= 0) return;
        int32_t c = left / div > 1 ? left / div : 1;
        int32_t i = atomic_fetch_add_explicit(&p->next, c, memory_order_relaxed);
        int32_t end = i < n - c ? i + c : n;
        for (; i < end; i++) {
            anistar_status st = p->fn(p->arg, i, s->index, &s->ctx);
            if (st != ANISTAR_OK && (s->fail_task < 0 || i < s->fail_task)) {
                s->fail_task = i;
                s->fail_status = st;
                memcpy(s->fail_msg, s->ctx.last_error, sizeof s->fail_msg);
            }
        }
    }
}

static void *worker(void *a) {
    pool_slot *s = a;
    as_pool *p = s->pool;
    uint64_t seen = 0;
    for (;;) {
        uint64_t g = atomic_load_explicit(&p->gen, memory_order_acquire);
        for (int k = 0; p->spin && g == seen && k < POOL_SPIN; k++) {
            cpu_pause();
            g = atomic_load_explicit(&p->gen, memory_order_acquire);
        }
        if (g == seen) {
            pthread_mutex_lock(&p->mu);
            while ((g = atomic_load_explicit(&p->gen, memory_order_acquire)) == seen &&
                   !atomic_load(&p->quit))
                pthread_cond_wait(&p->start, &p->mu);
            pthread_mutex_unlock(&p->mu);
        }
        if (atomic_load(&p->quit)) return NULL;
        seen = g;
        work(p, s);
        if (atomic_fetch_sub_explicit(&p->busy, 1, memory_order_acq_rel) == 1) {
            pthread_mutex_lock(&p->mu);
            pthread_cond_signal(&p->done);
            pthread_mutex_unlock(&p->mu);
        }
    }
}

static void slot_init(as_pool *p, int t) {
    pool_slot *s = &p->slot[t];
    memset(&s->ctx, 0, sizeof s->ctx);
    s->ctx.alloc = p->ctx->alloc;
    s->ctx.last_status = ANISTAR_OK;
    s->ctx.owner = p->ctx->owner ? p->ctx->owner : p->ctx;
    s->fail_task = -1;
    s->pool = p;
    s->index = t;
}

anistar_status as_pool_new(anistar_context *ctx, int nthreads, as_pool **out) {
    *out = NULL;
    if (nthreads < 1 || nthreads > AS_POOL_MAX_THREADS)
        return as_fail(ctx, ANISTAR_EINVAL, "threads must be in [1, %d], got %d",
                       AS_POOL_MAX_THREADS, nthreads);
    as_pool *p = as_alloc(ctx, sizeof *p);
    if (!p) return as_fail(ctx, ANISTAR_ENOMEM, "out of memory (thread pool)");
    memset(p, 0, sizeof *p);
    p->ctx = ctx;
    p->n = nthreads;
    p->slot = as_alloc_array(ctx, (size_t)nthreads, sizeof *p->slot);
    if (!p->slot) {
        as_free(ctx, p, sizeof *p);
        return as_fail(ctx, ANISTAR_ENOMEM, "out of memory (thread pool)");
    }
    for (int t = 0; t < nthreads; t++) {
        memset(&p->slot[t], 0, sizeof p->slot[t]);
        slot_init(p, t);
    }
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    p->spin = cores < 1 || nthreads <= cores;
    atomic_init(&p->gen, 0);
    atomic_init(&p->next, 0);
    atomic_init(&p->busy, 0);
    atomic_init(&p->quit, 0);
    if (nthreads == 1) {
        *out = p;
        return ANISTAR_OK;
    }
    int e;
    if ((e = pthread_mutex_init(&p->mu, NULL)) != 0) goto fail0;
    if ((e = pthread_cond_init(&p->start, NULL)) != 0) goto fail1;
    if ((e = pthread_cond_init(&p->done, NULL)) != 0) goto fail2;
    for (int t = 1; t < nthreads; t++) {
        if ((e = pthread_create(&p->slot[t].th, NULL, worker, &p->slot[t])) != 0) {
            as_pool_free(p);
            return as_fail(ctx, ANISTAR_EINTERNAL, "cannot start thread %d of %d: %s", t + 1,
                           nthreads, strerror(e));
        }
        p->slot[t].started = 1;
    }
    *out = p;
    return ANISTAR_OK;
fail2:
    pthread_cond_destroy(&p->start);
fail1:
    pthread_mutex_destroy(&p->mu);
fail0:
    as_free(ctx, p->slot, (size_t)nthreads * sizeof *p->slot);
    as_free(ctx, p, sizeof *p);
    return as_fail(ctx, ANISTAR_EINTERNAL, "cannot set up threads: %s", strerror(e));
}

void as_pool_free(as_pool *p) {
    if (!p) return;
    anistar_context *ctx = p->ctx;
    if (p->n > 1) {
        pthread_mutex_lock(&p->mu);
        atomic_store(&p->quit, 1);
        pthread_cond_broadcast(&p->start);
        pthread_mutex_unlock(&p->mu);
        for (int t = 1; t < p->n; t++)
            if (p->slot[t].started) pthread_join(p->slot[t].th, NULL);
        pthread_cond_destroy(&p->done);
        pthread_cond_destroy(&p->start);
        pthread_mutex_destroy(&p->mu);
    }
    as_free(ctx, p->slot, (size_t)p->n * sizeof *p->slot);
    as_free(ctx, p, sizeof *p);
}

int as_pool_threads(const as_pool *p) { return p ? p->n : 1; }

anistar_context *as_pool_context(as_pool *p, int t) { return &p->slot[t].ctx; }

anistar_status as_pool_run(as_pool *p, int32_t n, as_pool_fn fn, void *arg) {
    if (n <= 0) return ANISTAR_OK;
    pool_slot *s0 = &p->slot[0];
    if (p->n == 1 || n == 1) {
        /* serial, in order: the first failure is the lowest index */
        for (int32_t i = 0; i < n; i++) {
            anistar_status st = fn(arg, i, 0, &s0->ctx);
            if (st != ANISTAR_OK)
                return as_fail(p->ctx, st, "%s", s0->ctx.last_error);
        }
        return ANISTAR_OK;
    }
    p->fn = fn;
    p->arg = arg;
    p->ntask = n;
    for (int t = 0; t < p->n; t++) p->slot[t].fail_task = -1;
    atomic_store_explicit(&p->next, 0, memory_order_relaxed);
    atomic_store_explicit(&p->busy, p->n - 1, memory_order_relaxed);
    pthread_mutex_lock(&p->mu);
    atomic_fetch_add_explicit(&p->gen, 1, memory_order_release);
    pthread_cond_broadcast(&p->start);
    pthread_mutex_unlock(&p->mu);
    work(p, s0);
    /* wait for the workers: spin, then sleep */
    for (int k = 0, m = p->spin ? POOL_SPIN : 0;
         atomic_load_explicit(&p->busy, memory_order_acquire) > 0 && k < m; k++)
        cpu_pause();
    if (atomic_load_explicit(&p->busy, memory_order_acquire) > 0) {
        pthread_mutex_lock(&p->mu);
        while (atomic_load_explicit(&p->busy, memory_order_acquire) > 0)
            pthread_cond_wait(&p->done, &p->mu);
        pthread_mutex_unlock(&p->mu);
    }
    int best = -1;
    for (int t = 0; t < p->n; t++)
        if (p->slot[t].fail_task >= 0 &&
            (best < 0 || p->slot[t].fail_task < p->slot[best].fail_task))
            best = t;
    if (best < 0) return ANISTAR_OK;
    return as_fail(p->ctx, p->slot[best].fail_status, "%s", p->slot[best].fail_msg);
}
