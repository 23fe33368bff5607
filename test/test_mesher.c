/*
 * test_mesher.c — end-to-end tests of the anisotropic surface mesher (lib/mesher, public
 * API): guarantees of the output checked independently of the mesher's state.
 *
 * The output checks (topology, shape in every vertex metric, vertices on S, and the
 * independent star check that rebuilds each output vertex's stretched Delaunay
 * triangulation from the output vertices, the poles and the 8 box corners) live in
 * test/common/mesh_check.c, shared with test_e2e.
 */
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_check.h"
#include "test_util.h"

#include "geom/del3.h"
#include "geom/metric.h"
#include "io/meshio.h"
#include "mesher/mesher.h"
#include "mesher/star.h"
#include "mesher/starset.h"
#include "surface/field.h"
#include "surface/surface.h"

typedef struct mcase {
    const char *surface, *metric;
    double r0, gamma0;
    long long chi;
} mcase;

/* Run one case with batches of `batch` points (seed) and check every guarantee; its
 * statistics in *out (may be NULL). */
static void run_case_batch(const mcase *c, int32_t batch, uint64_t seed, anistar_mesh_stats *out) {
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, c->surface, &s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, s, c->metric, &f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = c->r0;
    p.gamma0 = c->gamma0;
    p.batch = batch;
    p.seed = seed;
    anistar_mesh *mesh;
    as_starset *ss;
    anistar_status st = as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss);
    if (st != ANISTAR_OK) fprintf(stderr, "%s / %s: %s\n", c->surface, c->metric, anistar_last_error(ctx));
    assert_int_equal(st, ANISTAR_OK);
    const anistar_mesh_stats *S = &mesh->stats;
    size_t nv = mesh->tm.nv, nt = mesh->tm.nt;
    assert_true(nv > 20);
    assert_int_equal(S->inconsistent_facets, 0);
    assert_int_equal(S->complete, 1);
    assert_int_equal(S->euler_characteristic, c->chi);
    assert_true(S->closed_manifold);
    /* topology, shape and size in every vertex metric, vertices on S (implicit:
     * |f|/|grad f| <= 1e-9 R), stars: independently of the mesher's state */
    mc_limits lim = {p.r0, p.rho0, p.gamma0, c->chi, 1e-9 * s->radius, 0};
    mc_report rep;
    mc_report_init(&rep);
    mc_check_all(ctx, s, ss->xyz, ss->first_site, &mesh->tm, &lim, &rep);
    mc_assert_ok(&rep, c->surface);
    assert_true(rep.stars_checked == nv);
    assert_true(fabs(rep.rho_max - S->rho_max) <= 1e-12 * rep.rho_max);
    assert_true(S->r_max < p.r0);
    /* histogram counts 3 values per facet */
    uint64_t h = 0;
    for (int b = 0; b < ANISTAR_HISTOGRAM_BINS; b++) h += S->histogram[b];
    assert_int_equal(h, 3 * (uint64_t)nt);
    if (out) *out = *S;
    as_starset_destroy(ss);
    free(ss); /* allocated with the default (malloc) allocator of ctx */
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void run_case(const mcase *c) { run_case_batch(c, AS_MESHER_BATCH, 0, NULL); }

static void test_sphere_uniform(void **state) {
    (void)state;
    mcase c = {"sphere", "euclidean", 0.25, 1.5, 2};
    run_case(&c);
}
static void test_sphere_shock(void **state) {
    (void)state;
    mcase c = {"sphere", "shock,phi=0.3", 1.0, 2.0, 2};
    run_case(&c);
}
static void test_ellipsoid_curvature(void **state) {
    (void)state;
    mcase c = {"ellipsoid", "curvature", 0.5, 2.0, 2};
    run_case(&c);
}
static void test_torus_curvature(void **state) {
    (void)state;
    /* R = 3 rather than the paper's 10 (whose distortion bound needs ~14k vertices at
     * gamma0 1.5: the bench runs that one) */
    mcase c = {"torus,R=3,r=1", "curvature,eps=0.3", 0.5, 2.0, 0};
    run_case(&c);
}
static void test_chair_curvature(void **state) {
    (void)state;
    /* genus 3; power 0.5 and gamma0 3 keep it near 900 vertices (test time) */
    mcase c = {"chair", "curvature,power=0.5", 0.5, 3.0, -4};
    run_case(&c);
}

/* The anisotropy that pays (ANISTAR_PARAM_ANISO_CAP, starset.c): on the paper's torus
 * (R 10, r 1) with the default curvature metric, the field's frame turns with the big
 * circle, and without the cap the distortion rule sizes almost every facet (r0 then has
 * no effect: 18,730 vertices at r0 0.1, 18,834 at 0.2). With it the metric asks only for
 * the elongation gamma0 keeps: r0 sizes the mesh again, with fewer vertices for the same
 * accuracy. Measured (r0 0.2, gamma0 1.5): off 18,834 V, 13,790 of 13,794 rule-1
 * insertions by distortion, mean error 1.52e-3 (V x error 28.7); on 1,986 V, 106 of
 * 1,554, 7.1e-3 (14.1). The test takes the torus R 5, r 1 at r0 0.3 (the same effect at
 * a third of the vertices): off 5,787 V, 4,123 of 4,129 by distortion, V x error 17.2;
 * on 733 V, 30 of 538, 9.9. */
static void test_aniso_cap(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "torus,R=5,r=1", &s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, s, "curvature", &f), ANISTAR_OK);
    double vx[2] = {0, 0};
    size_t nv[2] = {0, 0};
    for (int cap = 0; cap < 2; cap++) {
        as_mesher_params p;
        as_mesher_params_default(&p);
        assert_int_equal(p.aniso_cap, 1); /* the default */
        p.r0 = 0.3;
        p.gamma0 = 1.5;
        p.aniso_cap = cap;
        anistar_mesh *mesh;
        as_starset *ss;
        assert_int_equal(as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss), ANISTAR_OK);
        const anistar_mesh_stats *S = &mesh->stats;
        assert_int_equal(S->complete, 1);
        assert_int_equal(S->euler_characteristic, 0);
        mc_limits lim = {p.r0, p.rho0, p.gamma0, 0, 1e-9 * s->radius, 0};
        mc_report rep;
        mc_report_init(&rep);
        mc_check_all(ctx, s, ss->xyz, ss->first_site, &mesh->tm, &lim, &rep);
        mc_assert_ok(&rep, cap ? "torus, aniso_cap 1" : "torus, aniso_cap 0");
        double share = (double)S->insertions_distortion / (double)S->insertions_rule[0];
        print_message("aniso_cap %d: %zu V, distortion %.3f of rule 1, mean error %.3g\n", cap,
                      mesh->tm.nv, share, S->approx_error_mean);
        if (cap) assert_true(share < 0.1);
        else assert_true(share > 0.9);
        nv[cap] = mesh->tm.nv;
        vx[cap] = (double)mesh->tm.nv * S->approx_error_mean;
        as_starset_destroy(ss);
        free(ss);
        as_mesh_free(mesh);
    }
    assert_true(nv[1] < nv[0] / 4);
    assert_true(vx[1] < 0.75 * vx[0]); /* accuracy per vertex */
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- public API: determinism, threads, bad input, limits --------------------------- */

typedef struct job {
    const char *surface, *metric;
    double r0, gamma0;
    uint64_t seed;
    size_t nv, nt;
    double *xyz;
    int32_t *tri;
    anistar_status st;
} job;

static void *run_job(void *arg) {
    job *j = arg;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh = NULL;
    j->st = anistar_surface_builtin(ctx, j->surface, &s);
    if (j->st) return NULL;
    j->st = anistar_metric_from_spec(ctx, s, j->metric, &m);
    if (j->st) return NULL;
    anistar_mesher_new(ctx, s, m, &me);
    anistar_mesher_set(me, ANISTAR_PARAM_R0, j->r0);
    anistar_mesher_set(me, ANISTAR_PARAM_GAMMA0, j->gamma0);
    anistar_mesher_set(me, ANISTAR_PARAM_SEED, (double)j->seed);
    j->st = anistar_mesher_run(me, &mesh);
    if (mesh) {
        j->nv = anistar_mesh_vertex_count(mesh);
        j->nt = anistar_mesh_triangle_count(mesh);
        j->xyz = malloc(3 * j->nv * sizeof *j->xyz);
        j->tri = malloc(3 * j->nt * sizeof *j->tri);
        anistar_mesh_get_vertices(mesh, j->xyz);
        anistar_mesh_get_triangles(mesh, j->tri);
        anistar_mesh_free(mesh);
    }
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return NULL;
}

static void job_free(job *j) {
    free(j->xyz);
    free(j->tri);
}

static void assert_same(const job *a, const job *b) {
    assert_int_equal(a->st, ANISTAR_OK);
    assert_int_equal(b->st, ANISTAR_OK);
    assert_int_equal(a->nv, b->nv);
    assert_int_equal(a->nt, b->nt);
    assert_memory_equal(a->xyz, b->xyz, 3 * a->nv * sizeof *a->xyz);
    assert_memory_equal(a->tri, b->tri, 3 * a->nt * sizeof *a->tri);
}

/* The approximation error statistic on the unit sphere, where the distance from p to S is
 * 1 - |p| exactly: the area-weighted mean over the 4 barycentric samples recomputed here,
 * and the bound 1 - sqrt(1 - R^2) for a triangle with circumradius R inscribed in S. */
static void test_approx_error_sphere(void **state) {
    (void)state;
    job j = {"sphere", "euclidean", 0.3, 1.5, 3, 0, 0, NULL, NULL, 0};
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh = NULL;
    assert_int_equal(anistar_surface_builtin(ctx, j.surface, &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, j.metric, &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    anistar_mesher_set(me, ANISTAR_PARAM_R0, j.r0);
    anistar_mesher_set(me, ANISTAR_PARAM_GAMMA0, j.gamma0);
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_OK);
    size_t nv = anistar_mesh_vertex_count(mesh), nt = anistar_mesh_triangle_count(mesh);
    double *xyz = malloc(3 * nv * sizeof *xyz);
    int32_t *tri = malloc(3 * nt * sizeof *tri);
    anistar_mesh_get_vertices(mesh, xyz);
    anistar_mesh_get_triangles(mesh, tri);
    anistar_mesh_stats S;
    anistar_mesh_get_stats(mesh, &S);
    static const double bw[4][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3},
                                    {2.0 / 3, 1.0 / 6, 1.0 / 6},
                                    {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                    {1.0 / 6, 1.0 / 6, 2.0 / 3}};
    double esum = 0, asum = 0, emax = 0, bound = 0;
    for (size_t t = 0; t < nt; t++) {
        const double *a = xyz + 3 * tri[3 * t], *b = xyz + 3 * tri[3 * t + 1],
                     *c = xyz + 3 * tri[3 * t + 2];
        double u[3], v[3], w[3], n[3];
        for (int k = 0; k < 3; k++) {
            u[k] = b[k] - a[k];
            v[k] = c[k] - a[k];
            w[k] = c[k] - b[k];
        }
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        double area2 = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        double R = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]) *
                   sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) *
                   sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]) / (2 * area2);
        double bt = 1 - sqrt(1 - R * R);
        if (bt > bound) bound = bt;
        double e4 = 0;
        for (int q = 0; q < 4; q++) {
            double p[3];
            for (int k = 0; k < 3; k++) p[k] = bw[q][0] * a[k] + bw[q][1] * b[k] + bw[q][2] * c[k];
            double e = 1 - sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            assert_true(e >= 0 && e <= bt * (1 + 1e-9) + 1e-15);
            if (e > emax) emax = e;
            e4 += e;
        }
        esum += 0.5 * area2 * e4 / 4;
        asum += 0.5 * area2;
    }
    double mean = esum / asum;
    assert_true(S.approx_error_mean > 0);
    assert_true(S.approx_error_mean <= S.approx_error_max);
    assert_true(fabs(S.approx_error_mean - mean) <= 1e-9 * mean);
    assert_true(fabs(S.approx_error_max - emax) <= 1e-9 * emax);
    assert_true(S.approx_error_max <= bound * (1 + 1e-9));
    free(xyz);
    free(tri);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* The statistics of surface s meshed with the euclidean metric at r0 0.15; frees s and
 * its context ctx. */
static void euclidean_stats(anistar_context *ctx, anistar_surface *s, anistar_mesh_stats *S) {
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh = NULL;
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.15), ANISTAR_OK);
    if (anistar_mesher_run(me, &mesh) != ANISTAR_OK) fail_msg("%s", anistar_last_error(ctx));
    anistar_mesh_get_stats(mesh, S);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* One sphere, bound=1.25 and bound=1e4: the automatic hmin follows the surface's size,
 * not a loose bounding radius (with 1e-4 of the bound it was 1, and the sphere was
 * "certified" with 9 vertices and a mean error of a quarter of its radius). The loose run
 * must be certified and close to the tight one. */
static void run_sphere_bound(const char *spec, anistar_mesh_stats *S) {
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    assert_int_equal(anistar_surface_builtin(ctx, spec, &s), ANISTAR_OK);
    euclidean_stats(ctx, s, S);
}

static void test_loose_bound(void **state) {
    (void)state;
    anistar_mesh_stats tight, loose;
    run_sphere_bound("sphere,bound=1.25", &tight);
    run_sphere_bound("sphere,bound=1e4", &loose);
    assert_true(tight.complete && loose.complete);
    assert_true(loose.closed_manifold && loose.euler_characteristic == 2);
    assert_true(loose.hmin <= 1e-3);
    double rv = (double)loose.vertices / (double)tight.vertices;
    double re = loose.approx_error_mean / tight.approx_error_mean;
    if (!(rv > 0.9 && rv < 1.1 && re > 0.8 && re < 1.25))
        fail_msg("loose bound: %zu V, error %g; tight: %zu V, error %g", loose.vertices,
                 loose.approx_error_mean, tight.vertices, tight.approx_error_mean);
}

/* The same unit sphere centred at the origin, at x = 1e7 and at x = 1e10: the same mesh up
 * to a few percent. Far from the origin the coordinates' spacing (1.9e-9 at 1e7) exceeded
 * the surface's tolerance (1e-12 R) and the medial balls' ray offset (1e-9 R): the balls
 * met their own point, the feature size was 1e-9, and the sphere at 1e7 took 2,997
 * vertices (2,319 feature insertions) against an estimate of 2.1e6; at 1e8 it was
 * refused. */
static void run_sphere_at(double x0, anistar_mesh_stats *S) {
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    char expr[128];
    snprintf(expr, sizeof expr, "(x-%.17g)^2+y^2+z^2-1", x0);
    const double c[3] = {x0, 0, 0};
    assert_int_equal(anistar_surface_from_expression(ctx, expr, c, 1.25, &s), ANISTAR_OK);
    euclidean_stats(ctx, s, S);
}

static void test_far_from_origin(void **state) {
    (void)state;
    anistar_mesh_stats o, f[2];
    run_sphere_at(0, &o);
    run_sphere_at(1e7, &f[0]);
    run_sphere_at(1e10, &f[1]);
    for (int i = 0; i < 2; i++) {
        double rv = (double)f[i].vertices / (double)o.vertices;
        double re = f[i].estimate_vertices / o.estimate_vertices;
        print_message("sphere at x = %g: %zu V (origin %zu), estimate %.0f (origin %.0f), "
                      "%zu feature insertions\n",
                      i ? 1e10 : 1e7, f[i].vertices, o.vertices, f[i].estimate_vertices,
                      o.estimate_vertices, (size_t)f[i].insertions_feature);
        assert_true(f[i].complete && f[i].closed_manifold && f[i].euler_characteristic == 2);
        assert_true(rv > 0.95 && rv < 1.05);
        assert_true(re > 0.95 && re < 1.05);
        assert_true(f[i].insertions_feature == 0);
    }
}

static void test_determinism_and_threads(void **state) {
    (void)state;
    job a1 = {"sphere", "shock,phi=0.3", 1.0, 2.0, 7, 0, 0, NULL, NULL, 0};
    job a2 = a1, a3 = a1;
    job b1 = {"ellipsoid", "curvature", 1.0, 3.0, 7, 0, 0, NULL, NULL, 0};
    job b2 = b1;
    run_job(&a1);
    run_job(&a2);
    assert_same(&a1, &a2); /* same input and seed: identical output */
    run_job(&b1);
    pthread_t t1, t2;
    assert_int_equal(pthread_create(&t1, NULL, run_job, &a3), 0);
    assert_int_equal(pthread_create(&t2, NULL, run_job, &b2), 0);
    pthread_join(t1, NULL);
    pthread_join(t2, NULL);
    assert_same(&a1, &a3);
    assert_same(&b1, &b2);
    job_free(&a1);
    job_free(&a2);
    job_free(&a3);
    job_free(&b1);
    job_free(&b2);
}

/* Batches of refinement points (issue 15, docs/algorithm.md §11) against one point at a
 * time, each with seeds 1 to 4 (the order of the points alone moves these small meshes by
 * about 10%: Pick_valid's random points differ): every run certified and independently
 * checked (run_case_batch); the batched runs' accuracy per vertex (mean vertex count
 * times mean approximation error) within 6% of the one-at-a-time runs', their vertex
 * counts within 10%; the reservations were exercised (jobs lost or set aside) and every
 * rule insertion was a job that kept its stars. Over 16 seeds (session 19) batches give
 * 3-4% more vertices with a 3-5% lower error (torus 273.6 -> 284.6 V, V x error +1.0%;
 * sphere 253.6 -> 261.9 V, -1.5%): the counts alone, over 4 seeds, came out 6.1% apart. */
static void test_batches_against_one_at_a_time(void **state) {
    (void)state;
    static const mcase cases[] = {{"torus,R=3,r=1", "curvature,eps=0.3", 0.5, 2.0, 0},
                                  {"sphere", "shock,phi=0.3", 0.5, 2.0, 2}};
    enum { NSEED = 4 };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        double v[2] = {0, 0}, e[2] = {0, 0};
        uint64_t lost = 0, aside = 0;
        for (int b = 0; b < 2; b++)
            for (uint64_t seed = 1; seed <= NSEED; seed++) {
                anistar_mesh_stats S;
                run_case_batch(&cases[i], b ? AS_MESHER_BATCH : 1, seed, &S);
                v[b] += (double)S.vertices / NSEED;
                e[b] += S.approx_error_mean / NSEED;
                uint64_t ins = S.insertions_rule[0] + S.insertions_rule[1] + S.insertions_rule[2];
                if (!b) {
                    assert_int_equal(S.batches, 0);
                    continue;
                }
                assert_true(S.batches > 0 && ins <= S.batch_jobs - S.batch_jobs_lost);
                lost += S.batch_jobs_lost;
                aside += S.batch_jobs_set_aside;
            }
        print_message("%s / %s, means over %d seeds: one at a time %.1f V (error %.4g), "
                      "batches %.1f V (error %.4g; %llu jobs lost, %llu set aside)\n",
                      cases[i].surface, cases[i].metric, NSEED, v[0], e[0], v[1], e[1],
                      (unsigned long long)lost, (unsigned long long)aside);
        assert_true(fabs(v[1] * e[1] - v[0] * e[0]) <= 0.06 * v[0] * e[0]);
        assert_true(fabs(v[1] - v[0]) <= 0.10 * v[0]);
        assert_true(lost > 0 && aside > 0);
    }
}

static void test_bad_parameters(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    struct {
        anistar_param k;
        double v;
        const char *word;
    } bad[] = {{ANISTAR_PARAM_R0, 0, "r0"},           {ANISTAR_PARAM_R0, -1, "r0"},
               {ANISTAR_PARAM_R0, NAN, "r0"},         {ANISTAR_PARAM_GAMMA0, 1, "gamma0"},
               {ANISTAR_PARAM_RHO0, 1, "rho0"},       {ANISTAR_PARAM_DELTA, 0, "delta"},
               {ANISTAR_PARAM_DELTA, 1, "delta"},     {ANISTAR_PARAM_BETA, 0.5, "beta"},
               {ANISTAR_PARAM_APPROX, -1, "approx"},  {ANISTAR_PARAM_MAX_VERTICES, 1.5, "max_vertices"},
               {ANISTAR_PARAM_PICK_TRIES, 0, "pick_tries"}, {ANISTAR_PARAM_SEED, -1, "seed"},
               {ANISTAR_PARAM_MAX_SECONDS, -2, "max_seconds"}, {ANISTAR_PARAM_HMIN, -1, "hmin"},
               {ANISTAR_PARAM_HMIN, NAN, "hmin"},     {ANISTAR_PARAM_HMAX, INFINITY, "hmax"},
               {ANISTAR_PARAM_ANISO_CAP, 0.5, "aniso_cap"}, {ANISTAR_PARAM_ANISO_CAP, 2, "aniso_cap"},
               {(anistar_param)99, 1, "unknown"}};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        double before = 0, after = 0;
        anistar_mesher_get(me, bad[i].k, &before);
        assert_int_equal(anistar_mesher_set(me, bad[i].k, bad[i].v), ANISTAR_EINVAL);
        assert_non_null(strstr(anistar_last_error(ctx), bad[i].word));
        anistar_mesher_get(me, bad[i].k, &after);
        assert_true(before == after);
    }
    double v;
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_RHO0, &v), ANISTAR_OK);
    assert_true(v == 3.0);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_PICK_TRIES, &v), ANISTAR_OK);
    assert_true(v == 20);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_DELTA, 0.5), ANISTAR_OK);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_DELTA, &v), ANISTAR_OK);
    assert_true(v == 0.5);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_HMIN, &v), ANISTAR_OK);
    assert_true(v == 0); /* automatic */
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_HMAX, 0.25), ANISTAR_OK);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_HMAX, &v), ANISTAR_OK);
    assert_true(v == 0.25);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_ANISO_CAP, &v), ANISTAR_OK);
    assert_true(v == 1); /* the default */
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_ANISO_CAP, 0), ANISTAR_OK);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_ANISO_CAP, &v), ANISTAR_OK);
    assert_true(v == 0);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

static int nan_metric(const double p[3], const double n[3], double m[6], void *user) {
    (void)n;
    int *mode = user;
    for (int k = 0; k < 6; k++) m[k] = 0;
    m[0] = m[3] = m[5] = 4;
    if (*mode == 0 && p[2] > 0.5) m[0] = NAN;     /* NaN somewhere on S */
    if (*mode == 1 && p[2] > 0.5) m[0] = -1;      /* not positive definite */
    return 0;
}

static void test_bad_metric(void **state) {
    (void)state;
    for (int mode = 0; mode < 2; mode++) {
        anistar_context *ctx = anistar_context_new(NULL);
        anistar_surface *s;
        anistar_metric *m;
        anistar_mesher *me;
        anistar_mesh *mesh = (anistar_mesh *)1;
        assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
        assert_int_equal(anistar_metric_from_callback(ctx, s, nan_metric, &mode, &m), ANISTAR_OK);
        assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
        assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.5), ANISTAR_OK);
        assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_EINVAL);
        assert_null(mesh);
        assert_true(strlen(anistar_last_error(ctx)) > 0);
        anistar_mesher_free(me);
        anistar_metric_free(m);
        anistar_surface_free(s);
        anistar_context_free(ctx);
    }
}

static void test_max_vertices_incomplete(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    /* the sphere with the shock metric: the up-front estimate (10,400 vertices here; rule
     * 1's distortion bound makes the mesh denser than it predicts) stays below the limit,
     * so the run starts, and stops at it. Without the anisotropy cap: with it the metric
     * asks for no elongation that the distortion rule undoes, and the estimate holds */
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, s, "shock", &f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = 0.3;
    p.aniso_cap = 0;
    p.max_vertices = 12000;
    anistar_mesh *mesh;
    as_starset *ss;
    assert_int_equal(as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss), ANISTAR_INCOMPLETE);
    const anistar_mesh_stats *S = &mesh->stats;
    assert_int_equal(S->complete, 0);
    assert_true(S->inconsistent_facets > 0);
    assert_int_equal(S->inconsistent_facets, ss->ninc);
    assert_true(mesh->tm.nt > 0);
    assert_true(ss->n - ss->first_site == 12000);
    assert_true(S->estimate_vertices < 12000);
    assert_int_equal(S->stop_reason, ANISTAR_STOP_MAX_VERTICES);
    /* every output triangle is consistent: all three stars hold it */
    for (size_t t = 0; t < mesh->tm.nt; t++) {
        /* map output indices back to global ids: output order is increasing global id */
        as_gid g[3];
        for (int k = 0; k < 3; k++) {
            const double *x = mesh->tm.xyz + 3 * (size_t)mesh->tm.tri[3 * t + k];
            g[k] = -1;
            for (int32_t q = ss->first_site; q < ss->n; q++)
                if (memcmp(ss->xyz + 3 * (size_t)q, x, 3 * sizeof *x) == 0) g[k] = q;
            assert_true(g[k] >= 0);
        }
        as_sort_gid3(g);
        as_ftab_entry *e = as_starset_lookup(ss, as_facet_key(g));
        assert_non_null(e);
        assert_int_equal(e->mask, 7);
    }
    assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
    as_starset_destroy(ss);
    free(ss);
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The id limit (issue 15): global ids are 32-bit, the star set refuses an id at or past
 * ss->max_ids and the refiner stops 1024 sites short of it, INCOMPLETE with a message that
 * names the limit. Checked with the limit lowered (max_ids, a test parameter) instead of
 * allocating 2^31 points. */
static void test_id_limit(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    /* the run of test_max_vertices_incomplete: its estimate (10,400) stays below the limit
     * (else the run is refused up front), the mesh needs more */
    assert_int_equal(as_field_from_spec(ctx, s, "shock", &f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = 0.3;
    p.aniso_cap = 0;
    p.max_vertices = 0; /* the hard limit */
    p.max_ids = AS_MESHER_ID_RESERVE + 11000;
    anistar_mesh *mesh;
    as_starset *ss;
    assert_int_equal(as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss), ANISTAR_INCOMPLETE);
    assert_int_equal(mesh->stats.stop_reason, ANISTAR_STOP_MAX_VERTICES);
    assert_int_equal(ss->n - ss->first_site, 11000);
    assert_non_null(strstr(anistar_last_error(ctx), "hard limit of 11000 vertices"));
    assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
    /* the star set itself: one id past the limit is refused, nothing changes */
    ss->max_ids = ss->n;
    int32_t n0 = ss->n, gid = -1;
    const double q[3] = {0, 0, 1};
    assert_int_equal(as_starset_insert(ss, q, &gid), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "the limit of global ids"));
    assert_int_equal(ss->n, n0);
    assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
    /* the public range of max_vertices reaches the hard limit, and no further */
    anistar_mesher *me = NULL;
    anistar_surface *ps = NULL;
    anistar_metric *pm = NULL;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &ps), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, ps, "euclidean", &pm), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, ps, pm, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_MAX_VERTICES, 2147482623.0), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_MAX_VERTICES, 2147482624.0),
                     ANISTAR_EINVAL);
    anistar_mesher_free(me);
    anistar_metric_free(pm);
    anistar_surface_free(ps);
    as_starset_destroy(ss);
    free(ss);
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static int cancel_now(size_t v, size_t inc, double sec, void *user) {
    (void)v;
    (void)inc;
    (void)sec;
    (*(int *)user)++;
    return 1;
}

static void test_cancel_and_write(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.3), ANISTAR_OK);
    int calls = 0;
    anistar_mesher_set_progress(me, cancel_now, &calls);
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_ECANCELED);
    assert_null(mesh);
    assert_int_equal(calls, 1);
    anistar_mesher_set_progress(me, NULL, NULL);
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_OK);
    size_t nv = anistar_mesh_vertex_count(mesh), nt = anistar_mesh_triangle_count(mesh);
    assert_int_equal(nt, 2 * nv - 4);
    char path[256];
    snprintf(path, sizeof path, "%s/test_mesher_out.off", AS_TEST_BUILD_DIR);
    assert_int_equal(anistar_mesh_write(NULL, mesh, path), ANISTAR_OK);
    as_trimesh back;
    as_trimesh_init(&back);
    assert_int_equal(as_mesh_read(ctx, path, &back), ANISTAR_OK);
    assert_int_equal(back.nv, nv);
    assert_int_equal(back.nt, nt);
    double *xyz = malloc(3 * nv * sizeof *xyz);
    anistar_mesh_get_vertices(mesh, xyz);
    assert_memory_equal(xyz, back.xyz, 3 * nv * sizeof *xyz);
    free(xyz);
    as_trimesh_free(ctx, &back);
    remove(path);
    snprintf(path, sizeof path, "%s/test_mesher_out.xyz", AS_TEST_BUILD_DIR);
    assert_int_not_equal(anistar_mesh_write(ctx, mesh, path), ANISTAR_OK);
    double *mt = malloc(6 * nv * sizeof *mt);
    anistar_mesh_get_metrics(mesh, mt);
    for (size_t i = 0; i < nv; i++) assert_true(mt[6 * i] == 1.0 && mt[6 * i + 3] == 1.0);
    free(mt);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* The run's limits hold in the final checks too (issue 12's contract): a run whose
 * refinement has nothing to do (a sphere, r0 above its size: the initial points are the
 * mesh) goes straight to the final checks; with max_seconds already past when they
 * start it ends INCOMPLETE at max_seconds with its consistent facets, and without the
 * limit it is certified. The zone check itself tests the halt before each star: due, it
 * checks no star and opens none. */
static void test_limits_in_final_checks(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_R0, 10), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_THREADS, 1), ANISTAR_OK);
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_OK);
    anistar_mesh_stats S;
    anistar_mesh_get_stats(mesh, &S);
    assert_int_equal(S.stop_reason, ANISTAR_STOP_DONE);
    size_t nt = anistar_mesh_triangle_count(mesh);
    assert_true(nt > 0);
    anistar_mesh_free(mesh);
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_MAX_SECONDS, 1e-9), ANISTAR_OK);
    assert_int_equal(anistar_mesher_run(me, &mesh), ANISTAR_INCOMPLETE);
    assert_non_null(strstr(anistar_last_error(ctx), "during the final checks"));
    anistar_mesh_get_stats(mesh, &S);
    assert_int_equal(S.stop_reason, ANISTAR_STOP_MAX_SECONDS);
    assert_int_equal(S.complete, 0);
    assert_int_equal(S.inconsistent_facets, 0);
    assert_int_equal(anistar_mesh_triangle_count(mesh), nt);
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);

    /* the zone check on a finished star set: halted, it leaves every star unverified */
    as_surface *is;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &is), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, is, "euclidean", &f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = 0.3;
    as_starset *ss;
    assert_int_equal(as_mesher_run_keep(ctx, is, f, &p, NULL, &mesh, &ss), ANISTAR_OK);
    for (int why = AS_HALT_TIME; why <= AS_HALT_STOP; why++) {
        atomic_int stop;
        atomic_init(&stop, why == AS_HALT_STOP);
        as_halt h = {why == AS_HALT_TIME ? as_now_seconds() - 1 : 0, &stop, AS_HALT_NONE};
        size_t opened = 1;
        assert_int_equal(as_starset_verify_zones(ss, NULL, NULL, &h, &opened), ANISTAR_OK);
        assert_int_equal(opened, 0);
        assert_int_equal(atomic_load(&h.halted), why);
        for (int32_t v = ss->first_site; v < ss->n; v++)
            assert_true(!ss->stars[v] || ss->stars[v]->vz_reach == 0);
    }
    /* not halted, the same call checks the stars on the ball zone */
    atomic_int stop;
    atomic_init(&stop, 0);
    as_halt h = {as_now_seconds() + 3600, &stop, AS_HALT_NONE};
    size_t opened = 0, checked = 0;
    assert_int_equal(as_starset_verify_zones(ss, NULL, NULL, &h, &opened), ANISTAR_OK);
    assert_int_equal(atomic_load(&h.halted), AS_HALT_NONE);
    for (int32_t v = ss->first_site; v < ss->n; v++)
        checked += ss->stars[v] && ss->stars[v]->vz_reach > 0;
    assert_true(checked > 0);
    as_starset_destroy(ss);
    free(ss);
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(is);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_bad_parameters),
        cmocka_unit_test(test_bad_metric),
        cmocka_unit_test(test_cancel_and_write),
        cmocka_unit_test(test_limits_in_final_checks),
        cmocka_unit_test(test_sphere_uniform),
        cmocka_unit_test(test_sphere_shock),
        cmocka_unit_test(test_ellipsoid_curvature),
        cmocka_unit_test(test_torus_curvature),
        cmocka_unit_test(test_chair_curvature),
        cmocka_unit_test(test_aniso_cap),
        cmocka_unit_test(test_max_vertices_incomplete),
        cmocka_unit_test(test_id_limit),
        cmocka_unit_test(test_approx_error_sphere),
        cmocka_unit_test(test_loose_bound),
        cmocka_unit_test(test_far_from_origin),
        cmocka_unit_test(test_determinism_and_threads),
        cmocka_unit_test(test_batches_against_one_at_a_time),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
