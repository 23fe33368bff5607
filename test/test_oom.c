/*
 * test_oom.c — every allocation failure of a whole run is handled: a run of the public API
 * (surface, metric, mesher, output, write) is repeated with an allocator that fails from
 * its k-th allocation on, for k spread over every allocation the run makes, with 1 and 2
 * threads (the batches, the pool's tasks and their per-thread arenas included). Each run
 * must end with ANISTAR_ENOMEM and a message (or OK when k is past the allocations the
 * failing path reaches), and once everything is freed no block may be left.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

/* A counting allocator that fails from allocation fail_after on, safe to call from several
 * threads (the run's pool calls the context's allocator from its workers). */
typedef struct oom_alloc {
    pthread_mutex_t mu;
    long fail_after; /* < 0: never */
    long count, live_blocks, failures;
} oom_alloc;

static void *oom_fn(void *user, void *ptr, size_t old_size, size_t new_size) {
    oom_alloc *a = user;
    pthread_mutex_lock(&a->mu);
    void *q = NULL;
    if (new_size == 0) {
        if (ptr) {
            a->live_blocks--;
            free(ptr);
        }
    } else if ((!ptr || new_size > old_size) && a->fail_after >= 0 &&
               a->count++ >= a->fail_after) {
        a->failures++;
    } else {
        if (!ptr || new_size > old_size) {
            if (a->fail_after < 0) a->count++;
        }
        q = realloc(ptr, new_size);
        if (q && !ptr) a->live_blocks++;
    }
    pthread_mutex_unlock(&a->mu);
    return q;
}

/* One run on its own context; the status of the first failing call (OK if none). */
static anistar_status one_run(oom_alloc *a, int threads, const char *out) {
    anistar_allocator al = {oom_fn, a};
    anistar_context *ctx = anistar_context_new(&al);
    if (!ctx) return ANISTAR_ENOMEM;
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *me = NULL;
    anistar_mesh *mesh = NULL;
    anistar_status st = anistar_surface_builtin(ctx, "sphere", &s);
    if (st == ANISTAR_OK) st = anistar_metric_from_spec(ctx, s, "shock,phi=0.3", &m);
    if (st == ANISTAR_OK) st = anistar_mesher_new(ctx, s, m, &me);
    if (st == ANISTAR_OK) st = anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.8);
    if (st == ANISTAR_OK) st = anistar_mesher_set(me, ANISTAR_PARAM_GAMMA0, 3);
    if (st == ANISTAR_OK) st = anistar_mesher_set(me, ANISTAR_PARAM_THREADS, threads);
    if (st == ANISTAR_OK) st = anistar_mesher_run(me, &mesh);
    if (st == ANISTAR_OK) st = anistar_mesh_write(ctx, mesh, out);
    if (st != ANISTAR_OK) {
        /* a failure names itself */
        const char *msg = anistar_last_error(ctx);
        assert_non_null(msg);
        assert_true(msg[0] != '\0');
    }
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return st;
}

static void sweep(int threads) {
    char out[256];
    snprintf(out, sizeof out, "%s/test_oom_%d.off", AS_TEST_BUILD_DIR, threads);
    oom_alloc a;
    memset(&a, 0, sizeof a);
    pthread_mutex_init(&a.mu, NULL);
    a.fail_after = -1;
    assert_int_equal(one_run(&a, threads, out), ANISTAR_OK);
    assert_int_equal(a.live_blocks, 0);
    const long total = a.count;

    /* every allocation of the first 4 (the context, the surface, the field), then 16
     * spread evenly over the rest of the run (the sampler, the pool, the batches, the
     * output, the writer; a run costs about 0.2 s, mostly its start, and CI runs this
     * three times within its 20 minutes), offset by the thread count so that the two
     * sweeps fail at different places */
    long stride = total > 4 ? (total - 4) / 16 + 1 : 1;
    long runs = 0, nomem = 0;
    for (long k = 0; k < total; k += k < 4 ? 1 : stride) {
        if (k >= 4 && k + threads < total) k += threads;
        a.fail_after = k;
        a.count = a.failures = 0;
        anistar_status st = one_run(&a, threads, out);
        runs++;
        if (st != ANISTAR_OK) {
            if (st != ANISTAR_ENOMEM)
                fail_msg("%d threads, allocation %ld of %ld failed: status %d, not ENOMEM",
                         threads, k, total, (int)st);
            nomem++;
        }
        if (a.live_blocks != 0)
            fail_msg("%d threads, allocation %ld of %ld failed: %ld blocks left", threads, k,
                     total, a.live_blocks);
    }
    print_message("%d threads: %ld allocations in a run; %ld runs failing from one of them, "
                  "%ld ended ENOMEM\n",
                  threads, total, runs, nomem);
    /* a failure at any allocation before the run's end is reported */
    assert_true(nomem * 10 >= runs * 9);
    pthread_mutex_destroy(&a.mu);
    remove(out);
}

static void test_oom_one_thread(void **state) {
    (void)state;
    sweep(1);
}

static void test_oom_two_threads(void **state) {
    (void)state;
    sweep(2);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_oom_one_thread),
        cmocka_unit_test(test_oom_two_threads),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
