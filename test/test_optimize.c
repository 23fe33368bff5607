/*
 * test_optimize.c — the vertex optimisation post-pass (lib/mesher/optimize.c and
 * starmove.c; paper 6.2, DESIGN.md 4.9).
 *
 * Each case meshes a surface without optimisation (as_mesher_run_keep), then optimises the
 * kept star set (as_mesher_optimize) and checks, on the output alone where possible: the
 * mesh is still complete, a closed oriented manifold with the right Euler characteristic
 * and the same vertex count; every facet satisfies rules 1-2 in its three vertex metrics;
 * every vertex lies on S; the mean squared radius-edge ratio went down (computed here from
 * both meshes, and equal to the statistics); the facet table matches the stars; and the
 * star of sampled output vertices is exactly their restricted Delaunay star, rebuilt from
 * scratch (the moved stars are exact). Then determinism, the public parameter, and
 * allocation-failure injection during the optimisation.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "mesh_check.h"
#include "test_util.h"

#include "geom/del3.h"
#include "geom/metric.h"
#include "io/meshio.h"
#include "mesher/mesher.h"
#include "mesher/optimize.h"
#include "mesher/star.h"
#include "mesher/starmove.h"
#include "surface/field.h"
#include "surface/surface.h"

/* Mean squared radius-edge ratio over every triangle and its three vertex metrics,
 * computed from the output alone; also checks rules 1-2 and the distortion bound. */
static double check_rules(const anistar_mesh *mesh, const as_mesher_params *p) {
    double sum = 0;
    size_t nt = mesh->tm.nt;
    for (size_t t = 0; t < nt; t++) {
        const int32_t *tri = mesh->tm.tri + 3 * t;
        as_metric_frame mf[3];
        for (int k = 0; k < 3; k++)
            assert_int_equal(as_metric_frame_init(&mf[k], mesh->tm.tensor + 6 * (size_t)tri[k]), 0);
        for (int k = 0; k < 3; k++) {
            double R;
            double rho = as_radius_edge(&mf[k], mesh->tm.xyz + 3 * (size_t)tri[0],
                                        mesh->tm.xyz + 3 * (size_t)tri[1],
                                        mesh->tm.xyz + 3 * (size_t)tri[2], &R);
            assert_true(rho <= p->rho0 * (1 + 1e-12)); /* rule 2 */
            assert_true(R < p->r0);                   /* rule 1: size */
            sum += rho * rho;
        }
        for (int a = 0; a < 3; a++)
            for (int b = a + 1; b < 3; b++)
                assert_true(as_metric_distortion(&mf[a], &mf[b]) < p->gamma0); /* rule 1 */
    }
    return sum / (3.0 * (double)nt);
}

typedef struct ocase {
    const char *surface, *metric;
    double r0, gamma0;
    long long chi;
} ocase;

/* Mesh, optimise, check everything; returns the optimised mesh's vertices and triangles
 * (to free) when xyz_out is not NULL. */
static void run_case(const ocase *c, double **xyz_out, int32_t **tri_out, size_t *nv_out,
                     size_t *nt_out) {
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, c->surface, &s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, s, c->metric, &f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = c->r0;
    p.gamma0 = c->gamma0;
    anistar_mesh *mesh;
    as_starset *ss;
    assert_int_equal(as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss), ANISTAR_OK);
    assert_int_equal(mesh->stats.complete, 1);
    assert_int_equal(mesh->stats.optimized, 0);
    anistar_mesh_stats before = mesh->stats;
    double mean0 = check_rules(mesh, &p);
    size_t nv0 = mesh->tm.nv;
    double *xyz0 = malloc(3 * nv0 * sizeof *xyz0);
    memcpy(xyz0, mesh->tm.xyz, 3 * nv0 * sizeof *xyz0);
    assert_true(fabs(mean0 - before.rho2_mean) <= 1e-9 * mean0);

    p.optimize = 1;
    int stopped = 1;
    assert_int_equal(as_mesher_optimize(ss, &p, NULL, &mesh, &stopped), ANISTAR_OK);
    assert_false(stopped);
    const anistar_mesh_stats *S = &mesh->stats;
    size_t nv = mesh->tm.nv, nt = mesh->tm.nt;
    /* still complete and exact */
    assert_int_equal(ss->ninc, 0);
    assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
    assert_int_equal(S->inconsistent_facets, 0);
    assert_int_equal(S->complete, 1);
    assert_int_equal(nv, nv0);
    as_topology top;
    assert_int_equal(as_topology_check(ctx, nv, mesh->tm.xyz, nt, mesh->tm.tri, &top), ANISTAR_OK);
    assert_true(top.closed_manifold);
    assert_true(top.oriented);
    assert_int_equal(top.euler, c->chi);
    assert_int_equal((long long)nt, 2 * (long long)nv - 2 * c->chi);
    /* rules and quality */
    double mean1 = check_rules(mesh, &p);
    assert_true(mean1 < mean0);
    assert_true(fabs(mean1 - S->rho2_mean) <= 1e-9 * mean1);
    assert_true(fabs(mean0 - S->rho2_mean_before) <= 1e-9 * mean0);
    assert_memory_equal(S->histogram_before, before.histogram, sizeof before.histogram);
    uint64_t h = 0, hb = 0;
    for (int b = 0; b < ANISTAR_HISTOGRAM_BINS; b++) {
        h += S->histogram[b];
        hb += S->histogram_before[b];
    }
    assert_int_equal(h, 3 * (uint64_t)nt);
    assert_int_equal(hb, 3 * (uint64_t)before.facets);
    /* counters: moves happened, and the vertices that differ were moved */
    assert_int_equal(S->optimized, 1);
    assert_true(S->optimize_moved > 0);
    assert_true(S->optimize_tries >= S->optimize_moved);
    assert_true(S->optimize_passes >= 1 && S->optimize_passes <= AS_OPTIMIZE_MAX_PASSES);
    size_t differ = 0;
    for (size_t i = 0; i < nv; i++)
        differ += memcmp(xyz0 + 3 * i, mesh->tm.xyz + 3 * i, 3 * sizeof(double)) != 0;
    assert_true(differ > 0 && differ <= S->optimize_moved);
    /* the refinement's counters are kept */
    assert_int_equal(S->insertions_initial, before.insertions_initial);
    assert_int_equal(S->insertions_rule[0], before.insertions_rule[0]);
    /* every vertex on S, every metric the mesher's at the vertex (the field's, clamped by
     * hmin and raised by the anisotropy cap: as_starset_metric) */
    for (size_t i = 0; i < nv; i++) {
        double fv, g[3];
        const double *x = mesh->tm.xyz + 3 * i;
        assert_int_equal(as_surface_eval(ctx, s, x, 1, &fv, g, NULL), ANISTAR_OK);
        double gn = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
        assert_true(fabs(fv) / gn <= 1e-9 * s->radius);
        as_metric_frame mfx;
        assert_int_equal(as_starset_metric(ss, x, &mfx), ANISTAR_OK);
        assert_memory_equal(mfx.m, mesh->tm.tensor + 6 * i, sizeof mfx.m);
    }
    /* the shared output checks (test/common/mesh_check.c), the star of every vertex
     * against an independent rebuild included */
    mc_limits lim = {p.r0, p.rho0, p.gamma0, c->chi, 1e-9 * s->radius, 0};
    mc_report rep;
    mc_report_init(&rep);
    mc_check_all(ctx, s, ss->xyz, ss->first_site, &mesh->tm, &lim, &rep);
    mc_assert_ok(&rep, c->surface);
    assert_true(rep.stars_checked == nv);
    fprintf(stderr, "# %s / %s: V %zu, mean rho^2 %.4f -> %.4f, moved %llu, tries %llu, "
                    "passes %llu, refine %.3f s, optimize %.3f s\n",
            c->surface, c->metric, nv, mean0, mean1, (unsigned long long)S->optimize_moved,
            (unsigned long long)S->optimize_tries, (unsigned long long)S->optimize_passes,
            S->seconds_refine, S->seconds_optimize);
    if (xyz_out) {
        *nv_out = nv;
        *nt_out = nt;
        *xyz_out = malloc(3 * nv * sizeof **xyz_out);
        *tri_out = malloc(3 * nt * sizeof **tri_out);
        memcpy(*xyz_out, mesh->tm.xyz, 3 * nv * sizeof **xyz_out);
        memcpy(*tri_out, mesh->tm.tri, 3 * nt * sizeof **tri_out);
    }
    free(xyz0);
    as_starset_destroy(ss);
    free(ss);
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static const ocase sphere_shock = {"sphere", "shock,phi=0.3", 1.0, 2.0, 2};
static const ocase ellipsoid_small = {"ellipsoid", "curvature", 0.8, 2.5, 2};

static void test_sphere_shock(void **state) {
    (void)state;
    run_case(&sphere_shock, NULL, NULL, NULL, NULL);
}

/* The ellipsoid with the curvature metric, twice: both runs pass every check and give
 * byte-identical optimised meshes (determinism). */
static void test_ellipsoid_curvature_determinism(void **state) {
    (void)state;
    double *x[2];
    int32_t *t[2];
    size_t nv[2], nt[2];
    for (int r = 0; r < 2; r++) run_case(&ellipsoid_small, &x[r], &t[r], &nv[r], &nt[r]);
    assert_int_equal(nv[0], nv[1]);
    assert_int_equal(nt[0], nt[1]);
    assert_memory_equal(x[0], x[1], 3 * nv[0] * sizeof(double));
    assert_memory_equal(t[0], t[1], 3 * nt[0] * sizeof(int32_t));
    for (int r = 0; r < 2; r++) {
        free(x[r]);
        free(t[r]);
    }
}

/* The ellipsoid with the curvature metric (r0 0.8, gamma0 2.5) meshed, its star set
 * kept: the moves' tests start from it. */
typedef struct ell_run {
    anistar_context *ctx;
    as_surface *s;
    as_field *f;
    anistar_mesh *mesh;
    as_starset *ss;
} ell_run;

static void ell_open(ell_run *r) {
    r->ctx = anistar_context_new(NULL);
    assert_int_equal(as_implicit_builtin(r->ctx, "ellipsoid", &r->s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(r->ctx, r->s, "curvature", &r->f), ANISTAR_OK);
    as_mesher_params p;
    as_mesher_params_default(&p);
    p.r0 = 0.8;
    p.gamma0 = 2.5;
    assert_int_equal(as_mesher_run_keep(r->ctx, r->s, r->f, &p, NULL, &r->mesh, &r->ss),
                     ANISTAR_OK);
}

static void ell_close(ell_run *r) {
    as_starset_destroy(r->ss);
    free(r->ss);
    as_mesh_free(r->mesh);
    as_field_free(r->f);
    as_surface_free(r->s);
    anistar_context_free(r->ctx);
}

/* A move and its undo leave the stars and the facet table as they were. */
static void test_move_undo(void **state) {
    (void)state;
    ell_run R;
    ell_open(&R);
    anistar_context *ctx = R.ctx;
    as_surface *s = R.s;
    as_starset *ss = R.ss;
    as_starmove mv;
    memset(&mv, 0, sizeof mv);
    tu_rng rng = {7};
    int undone = 0;
    for (int trial = 0; trial < 20; trial++) {
        int32_t v = ss->first_site + (int32_t)(tu_rng_u64(&rng) % (uint64_t)(ss->n - ss->first_site));
        const as_star *st = ss->stars[v];
        assert_non_null(st);
        assert_true(st->nrf >= 3);
        /* the snapshot: v's facets with their centers, the table size */
        int32_t nrf = st->nrf;
        as_rfacet *rf = malloc((size_t)nrf * sizeof *rf);
        memcpy(rf, st->rf, (size_t)nrf * sizeof *rf);
        size_t tab_n = ss->tab_n;
        double x[3];
        memcpy(x, ss->xyz + 3 * (size_t)v, sizeof x);
        /* a large move: toward a facet's surface center, past it, projected on S */
        double q[3], p3[3];
        for (int k = 0; k < 3; k++) q[k] = x[k] + 1.5 * (st->rf[0].c[k] - x[k]);
        assert_int_equal(as_surface_project(ctx, s, q, p3), ANISTAR_OK);
        assert_int_equal(as_starmove_apply(ss, &mv, v, p3), ANISTAR_OK);
        assert_true(mv.n >= 1);
        assert_int_equal(mv.ids[0], v);
        assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
        assert_memory_equal(ss->xyz + 3 * (size_t)v, p3, sizeof p3);
        assert_int_equal(as_starmove_undo(ss, &mv), ANISTAR_OK);
        undone++;
        assert_int_equal(ss->ninc, 0);
        assert_int_equal(ss->tab_n, tab_n);
        assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
        assert_memory_equal(ss->xyz + 3 * (size_t)v, x, sizeof x);
        assert_ptr_equal(ss->stars[v], st);
        assert_int_equal(ss->stars[v]->nrf, nrf);
        assert_memory_equal(ss->stars[v]->rf, rf, (size_t)nrf * sizeof *rf);
        free(rf);
    }
    assert_int_equal(undone, 20);
    /* stale kd-tree entries are dropped by a flush, and queries still find every site */
    assert_true(mv.stale > 0);
    assert_int_equal(as_starmove_flush(ss, &mv), ANISTAR_OK);
    assert_int_equal(mv.stale, 0);
    for (int32_t v = ss->first_site; v < ss->n; v += 7) {
        int32_t id;
        double d2;
        assert_int_equal(as_kdtree_knn(ss->kd, ss->xyz + 3 * (size_t)v, 1, &id, &d2), 1);
        assert_int_equal(id, v);
        assert_true(d2 == 0);
    }
    as_starmove_free(ctx, &mv);
    ell_close(&R);
}

/* A move with mv.early: stopped early (doomed) only when the full move ends inconsistent
 * or with an open star; otherwise the same stars, facet for facet, as the full move. */
static void test_move_early(void **state) {
    (void)state;
    ell_run R;
    ell_open(&R);
    anistar_context *ctx = R.ctx;
    as_surface *s = R.s;
    as_starset *ss = R.ss;
    as_starmove mv;
    memset(&mv, 0, sizeof mv);
    tu_rng rng = {11};
    int doomed = 0, kept = 0;
    for (int trial = 0; trial < 40; trial++) {
        int32_t v = ss->first_site + (int32_t)(tu_rng_u64(&rng) % (uint64_t)(ss->n - ss->first_site));
        const as_star *st = ss->stars[v];
        const double *x = ss->xyz + 3 * (size_t)v;
        /* large moves (past a facet's surface center) and small ones, projected on S */
        double step = trial % 2 ? 1.5 : 0.15, q[3], p3[3];
        for (int k = 0; k < 3; k++) q[k] = x[k] + step * (st->rf[0].c[k] - x[k]);
        assert_int_equal(as_surface_project(ctx, s, q, p3), ANISTAR_OK);
        /* the early move: its touched stars' facets, then undone. Each move inserts p in
         * the kd-tree (undo leaves it, starmove.h): a flush before each of the two moves
         * gives them the same tree */
        assert_int_equal(as_starmove_flush(ss, &mv), ANISTAR_OK);
        mv.early = 1;
        assert_int_equal(as_starmove_apply(ss, &mv, v, p3), ANISTAR_OK);
        int was_doomed = mv.doomed;
        size_t n_early = mv.n, total = 0;
        int32_t ids[256];
        assert_true(n_early <= 256);
        for (size_t k = 0; k < n_early; k++) {
            ids[k] = mv.ids[k];
            total += (size_t)ss->stars[ids[k]]->nrf;
        }
        as_rfacet *rf = malloc((total + 1) * sizeof *rf);
        int32_t nrf[256];
        size_t at = 0;
        for (size_t k = 0; k < n_early; k++) {
            nrf[k] = ss->stars[ids[k]]->nrf;
            memcpy(rf + at, ss->stars[ids[k]]->rf, (size_t)nrf[k] * sizeof *rf);
            at += (size_t)nrf[k];
        }
        assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
        assert_int_equal(as_starmove_undo(ss, &mv), ANISTAR_OK);
        assert_int_equal(ss->ninc, 0);
        assert_int_equal(as_starset_check_table(ss), ANISTAR_OK);
        /* the full move */
        assert_int_equal(as_starmove_flush(ss, &mv), ANISTAR_OK);
        mv.early = 0;
        assert_int_equal(as_starmove_apply(ss, &mv, v, p3), ANISTAR_OK);
        assert_int_equal(mv.doomed, 0);
        int bad = ss->ninc != 0;
        for (size_t k = 0; k < mv.n; k++) bad |= !ss->stars[mv.ids[k]]->closed;
        if (was_doomed) {
            doomed++;
            assert_true(bad);
            assert_true(n_early < mv.n);
        } else {
            kept++;
            assert_int_equal(n_early, mv.n);
        }
        /* every star the early move rebuilt is the full move's, facet for facet */
        at = 0;
        for (size_t k = 0; k < n_early; k++) {
            const as_star *sk = ss->stars[ids[k]];
            assert_int_equal(sk->nrf, nrf[k]);
            for (int32_t i = 0; i < nrf[k]; i++) {
                assert_memory_equal(sk->rf[i].g, rf[at + (size_t)i].g, sizeof sk->rf[i].g);
                assert_memory_equal(sk->rf[i].c, rf[at + (size_t)i].c, sizeof sk->rf[i].c);
                assert_true(sk->rf[i].r == rf[at + (size_t)i].r);
            }
            at += (size_t)nrf[k];
        }
        free(rf);
        assert_int_equal(as_starmove_undo(ss, &mv), ANISTAR_OK);
        assert_int_equal(ss->ninc, 0);
    }
    assert_true(doomed > 0);
    assert_true(kept > 0);
    as_starmove_free(ctx, &mv);
    ell_close(&R);
}

/* The public parameter: range, default, get. */
static void test_param(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "euclidean", &m), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, m, &me), ANISTAR_OK);
    double v = -1;
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_OPTIMIZE, &v), ANISTAR_OK);
    assert_true(v == 0);
    const double bad[] = {-1, 0.5, 2, NAN, INFINITY};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_OPTIMIZE, bad[i]), ANISTAR_EINVAL);
        assert_non_null(strstr(anistar_last_error(ctx), "optimize"));
    }
    assert_int_equal(anistar_mesher_set(me, ANISTAR_PARAM_OPTIMIZE, 1), ANISTAR_OK);
    assert_int_equal(anistar_mesher_get(me, ANISTAR_PARAM_OPTIMIZE, &v), ANISTAR_OK);
    assert_true(v == 1);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

/* Allocation failures during the optimisation: ENOMEM, the mesh gone, no leak. */
static void enomem_threads(int threads) {
    /* count the allocations of the refinement and of the whole job */
    long before = 0, total = 0;
    int failed = 0; /* passes whose injected failure happened */
    for (int pass = 0; pass < 8; pass++) {
        tu_alloc a;
        tu_alloc_init(&a, -1);
        anistar_allocator al = tu_allocator(&a);
        anistar_context *ctx = anistar_context_new(&al);
        assert_non_null(ctx);
        as_surface *s;
        as_field *f;
        assert_int_equal(as_implicit_builtin(ctx, "ellipsoid", &s), ANISTAR_OK);
        assert_int_equal(as_field_from_spec(ctx, s, "curvature", &f), ANISTAR_OK);
        as_mesher_params p;
        as_mesher_params_default(&p);
        p.r0 = 0.8;
        p.gamma0 = 2.5;
        p.threads = threads;
        anistar_mesh *mesh;
        as_starset *ss;
        assert_int_equal(as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss), ANISTAR_OK);
        /* failures from a point of the optimisation on (counted from its start: with
         * threads the refinement's count varies with the timing of its scratch growth) */
        long start = a.count;
        if (pass == 0) before = start;
        if (pass >= 2) a.fail_after = start + (total - before) * (pass - 2) / 6;
        int stopped;
        anistar_status st = as_mesher_optimize(ss, &p, NULL, &mesh, &stopped);
        if (pass <= 1 || (threads > 1 && a.failures == 0)) {
            assert_int_equal(st, ANISTAR_OK);
            assert_non_null(mesh);
            assert_true(mesh->stats.optimize_moved > 0);
            if (pass == 0) total = a.count;
            else if (threads == 1) assert_int_equal(a.count - start, total - before);
            assert_int_equal(a.failures, 0);
        } else {
            assert_int_equal(st, ANISTAR_ENOMEM);
            assert_null(mesh);
            assert_true(a.failures > 0);
            failed++;
        }
        as_mesh_free(mesh);
        as_starset_destroy(ss);
        as_free(ctx, ss, sizeof *ss);
        as_field_free(f);
        as_surface_free(s);
        anistar_context_free(ctx);
        assert_int_equal(a.live_blocks, 0);
        assert_int_equal(a.live_bytes, 0);
    }
    assert_true(total > before);
    assert_true(failed >= (threads == 1 ? 6 : 4));
}

/* Allocation failures during the optimisation, one thread and two (a move's stars built on
 * the threads: a failed round frees what it built). */
static void test_enomem(void **state) {
    (void)state;
    enomem_threads(1);
    enomem_threads(2);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_param),
        cmocka_unit_test(test_move_undo),
        cmocka_unit_test(test_move_early),
        cmocka_unit_test(test_sphere_shock),
        cmocka_unit_test(test_ellipsoid_curvature_determinism),
        cmocka_unit_test(test_enomem),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
