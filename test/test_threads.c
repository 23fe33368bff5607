/*
 * test_threads.c — ANISTAR_PARAM_THREADS (issue 15): the output does not depend on the
 * thread count. Three surfaces of the three kinds (an implicit surface with the paper's
 * Table 2 parameters, a triangle mesh, an image) are meshed with 1, 2, 3 and 8 threads
 * through the public API; vertices, triangles, vertex metrics and the run's counts must
 * be equal byte for byte, and every run must end certified; the mesh is also optimised
 * (the vertex optimiser rebuilds a move's stars on the threads). Also: the parameter's range,
 * and two runs with threads at once in two contexts (nothing shared between contexts).
 * Under ThreadSanitizer (make tsan) this is the suite of the threaded paths.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#define DATA AS_TEST_DATA_DIR "/"

typedef struct tcase {
    const char *name;
    int kind;           /* 0 builtin, 1 mesh file, 2 image file (Otsu-free: iso given) */
    const char *input;
    const char *metric;
    double r0, gamma0, iso;
    int optimize; /* the vertex optimiser after the refinement (its rebuilds on threads) */
} tcase;

static const tcase cases[] = {
    {"torus (Table 2)", 0, "torus,R=10,r=1", "curvature", 0.1, 1.5, 0, 0},
    {"hinge.stl, optimised", 1, DATA "hinge.stl", "curvature", 0, 0, 0, 1},
    {"skull_2.9.inr", 2, DATA "skull_2.9.inr", "curvature", 0, 0, 1.5904694795610057, 0},
};

typedef struct result {
    anistar_status st;
    size_t nv, nt;
    double *xyz, *met;
    int32_t *tri;
    anistar_mesh_stats stats;
    char err[512];
} result;

static void run(const tcase *c, int threads, result *r) {
    memset(r, 0, sizeof *r);
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *me = NULL;
    anistar_mesh *mesh = NULL;
    r->st = c->kind == 0   ? anistar_surface_builtin(ctx, c->input, &s)
            : c->kind == 1 ? anistar_surface_read(ctx, c->input, &s)
                           : anistar_surface_from_image_file(ctx, c->input, c->iso,
                                                             ANISTAR_INSIDE_GREATER, &s);
    if (r->st == ANISTAR_OK) r->st = anistar_metric_from_spec(ctx, s, c->metric, &m);
    if (r->st == ANISTAR_OK) r->st = anistar_mesher_new(ctx, s, m, &me);
    if (r->st == ANISTAR_OK && c->r0 > 0) r->st = anistar_mesher_set(me, ANISTAR_PARAM_R0, c->r0);
    if (r->st == ANISTAR_OK && c->gamma0 > 0)
        r->st = anistar_mesher_set(me, ANISTAR_PARAM_GAMMA0, c->gamma0);
    if (r->st == ANISTAR_OK) r->st = anistar_mesher_set(me, ANISTAR_PARAM_THREADS, threads);
    if (r->st == ANISTAR_OK && c->optimize)
        r->st = anistar_mesher_set(me, ANISTAR_PARAM_OPTIMIZE, 1);
    if (r->st == ANISTAR_OK) r->st = anistar_mesher_run(me, &mesh);
    snprintf(r->err, sizeof r->err, "%s", anistar_last_error(ctx));
    if (mesh) {
        r->nv = anistar_mesh_vertex_count(mesh);
        r->nt = anistar_mesh_triangle_count(mesh);
        r->xyz = malloc(3 * r->nv * sizeof *r->xyz);
        r->met = malloc(6 * r->nv * sizeof *r->met);
        r->tri = malloc(3 * r->nt * sizeof *r->tri);
        if (!r->xyz || !r->met || !r->tri) fail_msg("out of memory");
        anistar_mesh_get_vertices(mesh, r->xyz);
        anistar_mesh_get_metrics(mesh, r->met);
        anistar_mesh_get_triangles(mesh, r->tri);
        anistar_mesh_get_stats(mesh, &r->stats);
        anistar_mesh_free(mesh);
    }
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

static void result_free(result *r) {
    free(r->xyz);
    free(r->met);
    free(r->tri);
}

/* The counts of two runs that must agree (not the times or the memory peak, which
 * depend on the machine and on the threads' timing). */
static void same_counts(const char *name, int t, const anistar_mesh_stats *a,
                        const anistar_mesh_stats *b) {
    if (memcmp(a->insertions_rule, b->insertions_rule, sizeof a->insertions_rule) ||
        a->insertions_initial != b->insertions_initial || a->complete != b->complete ||
        a->poles != b->poles || a->pick_valid_tries != b->pick_valid_tries ||
        a->pick_valid_failures != b->pick_valid_failures ||
        memcmp(a->histogram, b->histogram, sizeof a->histogram) || a->rho_max != b->rho_max ||
        a->batches != b->batches || a->batch_jobs != b->batch_jobs ||
        a->batch_jobs_lost != b->batch_jobs_lost ||
        a->batch_jobs_set_aside != b->batch_jobs_set_aside ||
        a->optimize_moved != b->optimize_moved || a->optimize_tries != b->optimize_tries ||
        a->optimize_passes != b->optimize_passes)
        fail_msg("%s, %d threads: the run's counts differ from 1 thread's (rule-1 insertions "
                 "%llu / %llu)",
                 name, t, (unsigned long long)b->insertions_rule[0],
                 (unsigned long long)a->insertions_rule[0]);
}

static void test_same_output_for_every_thread_count(void **state) {
    (void)state;
    const int counts[] = {1, 2, 3, 8};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const tcase *c = &cases[i];
        result base;
        run(c, 1, &base);
        if (base.st != ANISTAR_OK) fail_msg("%s, 1 thread: %s", c->name, base.err);
        if (!base.stats.complete || base.nv < 1000)
            fail_msg("%s: not a certified mesh of some size (%zu vertices)", c->name, base.nv);
        if (c->optimize && !(base.stats.optimized && base.stats.optimize_moved > 100))
            fail_msg("%s: the optimiser moved %llu vertices", c->name,
                     (unsigned long long)base.stats.optimize_moved);
        for (size_t k = 1; k < sizeof counts / sizeof counts[0]; k++) {
            result r;
            run(c, counts[k], &r);
            if (r.st != ANISTAR_OK) fail_msg("%s, %d threads: %s", c->name, counts[k], r.err);
            if (r.nv != base.nv || r.nt != base.nt)
                fail_msg("%s, %d threads: %zu vertices %zu triangles, 1 thread %zu %zu", c->name,
                         counts[k], r.nv, r.nt, base.nv, base.nt);
            if (memcmp(r.xyz, base.xyz, 3 * r.nv * sizeof *r.xyz) ||
                memcmp(r.met, base.met, 6 * r.nv * sizeof *r.met) ||
                memcmp(r.tri, base.tri, 3 * r.nt * sizeof *r.tri))
                fail_msg("%s, %d threads: the mesh differs from 1 thread's", c->name, counts[k]);
            same_counts(c->name, counts[k], &base.stats, &r.stats);
            result_free(&r);
        }
        result_free(&base);
    }
}

static void test_threads_range(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    double v = 0;
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_THREADS, &v), ANISTAR_OK);
    assert_true(v == 1); /* the API's default */
    const double bad[] = {0, -1, 1.5, 1025, 1e300};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_THREADS, bad[i]), ANISTAR_EINVAL);
        assert_non_null(strstr(anistar_last_error(ctx), "threads"));
    }
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_THREADS, 1024), ANISTAR_OK);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_THREADS, &v), ANISTAR_OK);
    assert_true(v == 1024);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

typedef struct job {
    const tcase *c;
    result r;
} job;

static void *job_run(void *a) {
    job *j = a;
    run(j->c, 2, &j->r);
    return NULL;
}

/* Two threaded runs at once, each in its own context, give the one-thread output. */
static void test_two_contexts_at_once(void **state) {
    (void)state;
    const tcase *c = &cases[1];
    result base;
    run(c, 1, &base);
    assert_int_equal(base.st, ANISTAR_OK);
    job j[2] = {{c, {0}}, {c, {0}}};
    pthread_t th[2];
    for (int k = 0; k < 2; k++) assert_int_equal(pthread_create(&th[k], NULL, job_run, &j[k]), 0);
    for (int k = 0; k < 2; k++) pthread_join(th[k], NULL);
    for (int k = 0; k < 2; k++) {
        if (j[k].r.st != ANISTAR_OK) fail_msg("run %d: %s", k, j[k].r.err);
        assert_true(j[k].r.nv == base.nv && j[k].r.nt == base.nt);
        assert_true(memcmp(j[k].r.xyz, base.xyz, 3 * base.nv * sizeof *base.xyz) == 0);
        assert_true(memcmp(j[k].r.tri, base.tri, 3 * base.nt * sizeof *base.tri) == 0);
        result_free(&j[k].r);
    }
    result_free(&base);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_threads_range),
        cmocka_unit_test(test_same_output_for_every_thread_count),
        cmocka_unit_test(test_two_contexts_at_once),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
