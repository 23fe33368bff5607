/*
 * bench_del3 — throughput of lib/geom/del3.c: bulk insertion with the spatial sort
 * (uniform points, torus surface points), star-sized triangulations from scratch (8 box
 * corners + 32 points of a small surface patch = 40 points, reused through
 * as_del3_reset), without the sphere cache (the default, and the mesher's stars) and
 * with it, single insertions into a 40-point triangulation, conflict-zone queries; with
 * the work counters of del3 (walk steps, cavity sizes, conflict tests and their exact
 * fallbacks) and, in bench builds, the predicates' stage counters.
 * Prints tables with CPU time (this process) and wall time; never asserts on time.
 *
 * usage: bench_del3 [N (default 1000000)] [what: 0 all, 1 bulk only, 2 stars only]
 */
#include "anistar.h"
#include "bench_util.h"
#include "core.h"
#include "geom/del3.h"
#include "geom/predicates.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static double wall(void) { return bench_wall_seconds(); }
static double cpu(void) { return bench_cpu_seconds(); }
static double unit(bench_rng *r) { return bench_unit(r); }

static void pred_line(void) {
#ifdef ANISTAR_BENCH
    as_pred_counters *c = as_pred_counters_get();
    printf("    predicates.c: orient3d %llu calls (%.2f%% settled by its filter), insphere %llu "
           "(%.2f%%), insphere_sos %llu, perturbed %llu\n",
           (unsigned long long)c->orient3d_calls,
           c->orient3d_calls ? 100.0 * (double)c->orient3d_stage[0] / (double)c->orient3d_calls : 0,
           (unsigned long long)c->insphere_calls,
           c->insphere_calls ? 100.0 * (double)c->insphere_stage[0] / (double)c->insphere_calls : 0,
           (unsigned long long)c->insphere_sos_calls,
           (unsigned long long)c->insphere_sos_perturbed);
    as_pred_counters_reset();
#endif
}

static void pred_reset(void) {
#ifdef ANISTAR_BENCH
    as_pred_counters_reset();
#endif
}

static int bulk(anistar_context *ctx, const char *name, const double *p, int n) {
    as_del3 d;
    as_del3_init(&d, ctx);
    pred_reset();
    double w0 = wall(), c0 = cpu();
    anistar_status st = as_del3_insert_points(&d, p, NULL, n, NULL, NULL, NULL);
    double w1 = wall(), c1 = cpu();
    if (st != ANISTAR_OK) {
        fprintf(stderr, "bulk %s: %s\n", name, anistar_last_error(ctx));
        as_del3_destroy(&d);
        return 1;
    }
    int32_t nf, ni;
    as_del3_count(&d, &nf, &ni);
    printf("| %-22s | %8d | %7.2f | %10.0f | %7.2f | %10.0f | %6.2f | %6.2f | %6.2f |\n", name,
           n, c1 - c0, n / (c1 - c0), w1 - w0, n / (w1 - w0), (double)nf / n,
           (double)d.stats.walk_steps / n, (double)d.stats.conflict_tets / n);
    printf("    per point: %.1f conflict tests (%.2f%% left to the exact predicate), %.1f tets"
           " created\n",
           (double)d.stats.sphere_tests / n,
           d.stats.sphere_tests
               ? 100.0 * (double)d.stats.sphere_exact / (double)d.stats.sphere_tests
               : 0.0,
           (double)d.stats.created_tets / n);
    pred_line();
    as_del3_destroy(&d);
    return 0;
}

enum { NPATCH_SETS = 1000, NCORNER = 8 };

/* A star's points: 8 corners of the box [-3,3]^3 (exact, or each coordinate pushed out
 * by a different few percent: "generic", no 4 coplanar, no 5 cospherical), then npatch
 * points on z = (x^2 - 2 y^2)/2 over [-0.1, 0.1]^2. */
static void star_points(double *p, int npatch, int generic, bench_rng *rs) {
    for (int c = 0; c < NCORNER; c++) {
        for (int k = 0; k < 3; k++) {
            double s = (c >> k) & 1 ? 3.0 : -3.0;
            p[3 * c + k] = generic ? s * (1.0 + 0.02 * ((c * 7 + k * 3) % 5) + 0.001 * c) : s;
        }
    }
    for (int i = NCORNER; i < NCORNER + npatch; i++) {
        double x = 0.2 * unit(rs) - 0.1, y = 0.2 * unit(rs) - 0.1;
        p[3 * i] = x;
        p[3 * i + 1] = y;
        p[3 * i + 2] = 0.5 * (x * x - 2 * y * y);
    }
}

static int build(as_del3 *d, const double *q, int n) {
    as_del3_reset(d);
    for (int i = 0; i < n; i++)
        if (as_del3_insert(d, q + 3 * i, i, NULL) != ANISTAR_OK) return 1;
    return 0;
}

static int stars(anistar_context *ctx, int count, int npatch, int generic, int cache,
                 bench_rng *rs) {
    int n = NCORNER + npatch;
    double *sp = malloc((size_t)NPATCH_SETS * (size_t)n * 3 * sizeof *sp);
    if (!sp) return 1;
    for (int s = 0; s < NPATCH_SETS; s++)
        star_points(sp + (size_t)s * (size_t)n * 3, npatch, generic, rs);
    as_del3 d;
    as_del3_init(&d, ctx);
    d.sphere_cache = cache;
    pred_reset();
    uint64_t ins = 0, removed = 0, created = 0, walk = 0, stests = 0, sexact = 0;
    double w0 = wall(), c0 = cpu();
    for (int s = 0; s < count; s++) {
        if (build(&d, sp + (size_t)(s % NPATCH_SETS) * (size_t)n * 3, n)) {
            fprintf(stderr, "star insertion failed: %s\n", anistar_last_error(ctx));
            return 1;
        }
        ins += d.stats.inserted;
        removed += d.stats.conflict_tets;
        created += d.stats.created_tets;
        walk += d.stats.walk_steps;
        stests += d.stats.sphere_tests;
        sexact += d.stats.sphere_exact;
    }
    double w1 = wall(), c1 = cpu();
    char what[80];
    snprintf(what, sizeof what, "from scratch: %s corners + %d%s", generic ? "generic" : "cube",
             npatch, cache ? ", cache" : "");
    printf("| %-42s | %7d | %8.2f | %8.2f |\n", what, count, 1e6 * (c1 - c0) / count,
           1e6 * (w1 - w0) / count);
    printf("    per insertion: %.1f tets removed, %.1f created, %.2f walk steps, %.1f conflict"
           " tests (%.2f%% left to the exact predicate); %d live tets\n",
           (double)removed / (double)ins, (double)created / (double)ins,
           (double)walk / (double)ins, (double)stests / (double)ins,
           stests ? 100.0 * (double)sexact / (double)stests : 0.0, (int)d.nlive);
    pred_line();
    if (generic && npatch == 32) {
        /* One more insertion into a 40-point star, timed one by one with the monotonic
         * clock (a vDSO call, ~20 ns) around each insertion, minus the cost of an empty
         * timer pair measured the same way. (A difference of two loop timings, builds +
         * insertions minus builds, drowned in the noise of a loaded machine.) */
        double xs[3 * 64];
        for (int k = 0; k < 64; k++) {
            double x = 0.2 * unit(rs) - 0.1, y = 0.2 * unit(rs) - 0.1;
            xs[3 * k] = x;
            xs[3 * k + 1] = y;
            xs[3 * k + 2] = 0.5 * (x * x - 2 * y * y);
        }
        double tin = 0, tempty = 0;
        for (int s = 0; s < count; s++) {
            build(&d, sp + (size_t)(s % NPATCH_SETS) * (size_t)n * 3, n);
            double a = wall();
            double b = wall();
            as_del3_insert(&d, xs + 3 * (s % 64), n, NULL);
            double c = wall();
            tempty += b - a;
            tin += c - b;
        }
        printf("| %-42s | %7d | %8s | %8.2f |\n",
               cache ? "one insertion into a 40-point star, cache"
                     : "one insertion into a 40-point star",
               count, "-", 1e6 * (tin - tempty) / count);
        /* conflict-zone queries: 64 different points against each of 1000 stars */
        as_del3_buf zone = {0};
        double tq = 0, wq = 0;
        int nq = 0;
        for (int s = 0; s < NPATCH_SETS; s++) {
            build(&d, sp + (size_t)s * (size_t)n * 3, n);
            double a = wall(), b = cpu();
            for (int k = 0; k < 64; k++) as_del3_conflict_zone(&d, xs + 3 * k, n, -1, &zone, NULL);
            tq += cpu() - b;
            wq += wall() - a;
            nq += 64;
        }
        printf("| %-42s | %7d | %8.2f | %8.2f |\n",
               cache ? "conflict-zone query, 40-point star, cache"
                     : "conflict-zone query, 40-point star",
               nq, 1e6 * tq / nq, 1e6 * wq / nq);
        as_del3_buf_free(ctx, &zone);
    }
    as_del3_destroy(&d);
    free(sp);
    return 0;
}

int main(int argc, char **argv) {
    bench_rng rstate = {0x1234567}, *rs = &rstate;
    int big = 1000000, only = 0;
    if (argc > 1) big = atoi(argv[1]);
    if (argc > 2) only = atoi(argv[2]);
    if (big < 1000) big = 1000;
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    int rc = 0;
    if (only != 2) {
        double *p = malloc(3 * (size_t)big * sizeof *p);
        if (!p) return 1;
        printf("| %-22s | %8s | %7s | %10s | %7s | %10s | %6s | %6s | %6s |\n",
               "bulk (BRIO + Hilbert)", "points", "cpu s", "points/s", "wall s", "points/s",
               "tets/p", "walk/p", "rem/p");
        printf("|------------------------|----------|---------|------------|---------|"
               "------------|--------|--------|--------|\n");
        int n1 = big < 100000 ? big : 100000;
        for (int i = 0; i < 3 * n1; i++) p[i] = unit(rs);
        rc |= bulk(ctx, "uniform cube", p, n1);
        for (int i = 0; i < 3 * big; i++) p[i] = unit(rs);
        rc |= bulk(ctx, "uniform cube", p, big);
        for (int i = 0; i < big; i++) {
            double a = 6.283185307179586 * unit(rs), b = 6.283185307179586 * unit(rs);
            p[3 * i] = (1 + 0.3 * cos(b)) * cos(a);
            p[3 * i + 1] = (1 + 0.3 * cos(b)) * sin(a);
            p[3 * i + 2] = 0.3 * sin(b);
        }
        rc |= bulk(ctx, "torus surface (R/r=3.3)", p, big);
        free(p);
        printf("\n");
    }
    if (only != 1) {
        printf("| %-42s | %7s | %8s | %8s |\n", "star-sized triangulations", "count", "cpu us",
               "wall us");
        printf("|--------------------------------------------|---------|----------|----------|\n");
        rc |= stars(ctx, 100000, 32, 1, 0, rs);
        rc |= stars(ctx, 100000, 32, 1, 1, rs);
        rc |= stars(ctx, 20000, 32, 0, 0, rs);
        rc |= stars(ctx, 20000, 40, 1, 0, rs);
    }
    anistar_context_free(ctx);
    return rc;
}
