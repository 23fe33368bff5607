/*
 * bench_del3 — throughput of lib/geom/del3.c: bulk insertion with the spatial sort
 * (uniform points, torus surface points), star-sized triangulations from scratch (8 box
 * corners + 40 points of a small surface patch, reused through as_del3_reset), single
 * insertions into a 40-point triangulation; with the predicates' stage counters.
 * Prints a table; never asserts on time.
 */
#include "anistar.h"
#include "core.h"
#include "geom/del3.h"
#include "geom/predicates.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double unit(uint64_t *state) {
    uint64_t z = (*state += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

static void print_pred(const char *what) {
#ifdef ANISTAR_BENCH
    as_pred_counters *c = as_pred_counters_get();
    printf("  %-34s orient3d %llu (filter %.4f%%), insphere_sos %llu (filter %.4f%%, "
           "perturbed %llu)\n",
           what, (unsigned long long)c->orient3d_calls,
           c->orient3d_calls ? 100.0 * (double)c->orient3d_stage[0] / (double)c->orient3d_calls : 0,
           (unsigned long long)c->insphere_sos_calls,
           c->insphere_calls ? 100.0 * (double)c->insphere_stage[0] / (double)c->insphere_calls : 0,
           (unsigned long long)c->insphere_sos_perturbed);
    as_pred_counters_reset();
#else
    (void)what;
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
    double t0 = now();
    anistar_status st = as_del3_insert_points(&d, p, NULL, n, NULL, NULL, NULL);
    double t1 = now();
    if (st != ANISTAR_OK) {
        fprintf(stderr, "bulk %s: %s\n", name, anistar_last_error(ctx));
        as_del3_destroy(&d);
        return 1;
    }
    int32_t nf, ni;
    as_del3_count(&d, &nf, &ni);
    printf("| %-30s | %9d | %8.3f | %12.0f | %6.2f | %6.2f |\n", name, n, t1 - t0,
           n / (t1 - t0), (double)nf / n, (double)d.stats.walk_steps / n);
    print_pred(name);
    as_del3_destroy(&d);
    return 0;
}

/* A star: 8 corners of the box [-3,3]^3 then 40 points on z = (x^2 - 2 y^2)/2 near 0. */
static void star_points(double *p, uint64_t *rs) {
    for (int c = 0; c < 8; c++) {
        p[3 * c] = c & 1 ? 3.0 : -3.0;
        p[3 * c + 1] = c & 2 ? 3.0 : -3.0;
        p[3 * c + 2] = c & 4 ? 3.0 : -3.0;
    }
    for (int i = 8; i < 48; i++) {
        double x = 0.2 * unit(rs) - 0.1, y = 0.2 * unit(rs) - 0.1;
        p[3 * i] = x;
        p[3 * i + 1] = y;
        p[3 * i + 2] = 0.5 * (x * x - 2 * y * y);
    }
}

int main(int argc, char **argv) {
    uint64_t rstate = 0x1234567, *rs = &rstate;
    int big = 1000000;
    int only = 0; /* 1: bulk only, 2: stars only */
    if (argc > 1) big = atoi(argv[1]);
    if (argc > 2) only = atoi(argv[2]);
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    double *p = malloc(3 * (size_t)big * sizeof *p);
    if (!p) return 1;
    printf("| %-30s | %9s | %8s | %12s | %6s | %6s |\n", "bulk insertion (BRIO+Hilbert)",
           "points", "seconds", "points/s", "tets/p", "walk/p");
    printf("|--------------------------------|-----------|----------|--------------|--------|--------|\n");
    int rc = 0;
    int n1 = big < 100000 ? big : 100000;
    if (only == 2) goto stars;
    for (int i = 0; i < 3 * n1; i++) p[i] = unit(rs);
    rc |= bulk(ctx, "uniform cube 1e5", p, n1);
    for (int i = 0; i < 3 * big; i++) p[i] = unit(rs);
    rc |= bulk(ctx, "uniform cube 1e6", p, big);
    for (int i = 0; i < big; i++) {
        double a = 6.283185307179586 * unit(rs), b = 6.283185307179586 * unit(rs);
        p[3 * i] = (1 + 0.3 * cos(b)) * cos(a);
        p[3 * i + 1] = (1 + 0.3 * cos(b)) * sin(a);
        p[3 * i + 2] = 0.3 * sin(b);
    }
    rc |= bulk(ctx, "torus surface 1e6", p, big);

    if (only == 1) goto end;
stars:;
    /* stars from scratch */
    enum { NSTAR = 100000, NPTS = 48 };
    double *sp = malloc((size_t)NSTAR / 100 * NPTS * 3 * sizeof *sp);
    for (int s = 0; s < NSTAR / 100; s++) star_points(sp + (size_t)s * NPTS * 3, rs);
    as_del3 d;
    as_del3_init(&d, ctx);
    pred_reset();
    double t0 = now();
    long tets = 0;
    for (int s = 0; s < NSTAR; s++) {
        const double *q = sp + (size_t)(s % (NSTAR / 100)) * NPTS * 3;
        as_del3_reset(&d);
        for (int i = 0; i < NPTS; i++) {
            if (as_del3_insert(&d, q + 3 * i, i, NULL) != ANISTAR_OK) {
                fprintf(stderr, "star insertion failed: %s\n", anistar_last_error(ctx));
                return 1;
            }
        }
        tets += d.nlive;
    }
    double t1 = now();
    printf("(stars: %.1f live tets, %.1f removed and %.1f created per insertion, %.2f walk steps)\n",
           (double)tets / NSTAR, (double)d.stats.conflict_tets / (NPTS - 5),
           (double)d.stats.created_tets / (NPTS - 5), (double)d.stats.walk_steps / NPTS);
    printf("\n| %-44s | %10s | %10s |\n", "star triangulations (8 corners + 40 points)",
           "count", "us each");
    printf("|----------------------------------------------|------------|------------|\n");
    printf("| %-44s | %10d | %10.3f |\n", "from scratch (reset, 48 insertions)", NSTAR,
           1e6 * (t1 - t0) / NSTAR);
    print_pred("stars");
    (void)tets;

    /* single insertion into a 40-point star: build (untimed) then time one insertion */
    double tins = 0;
    int nins = 0;
    for (int s = 0; s < NSTAR; s++) {
        const double *q = sp + (size_t)(s % (NSTAR / 100)) * NPTS * 3;
        as_del3_reset(&d);
        for (int i = 0; i < NPTS - 1; i++) as_del3_insert(&d, q + 3 * i, i, NULL);
        double a = now();
        as_del3_insert(&d, q + 3 * (NPTS - 1), NPTS - 1, NULL);
        tins += now() - a;
        nins++;
    }
    printf("| %-44s | %10d | %10.3f |\n", "one insertion into a 47-point star", nins,
           1e6 * tins / nins);
    /* conflict-zone query of one point against a 48-point star */
    as_del3_buf zone = {0};
    double tq = 0;
    for (int s = 0; s < NSTAR / 10; s++) {
        const double *q = sp + (size_t)(s % (NSTAR / 100)) * NPTS * 3;
        as_del3_reset(&d);
        for (int i = 0; i < NPTS; i++) as_del3_insert(&d, q + 3 * i, i, NULL);
        double x[3] = {0.2 * unit(rs) - 0.1, 0.2 * unit(rs) - 0.1, 0};
        double a = now();
        as_del3_conflict_zone(&d, x, 1000, -1, &zone, NULL);
        tq += now() - a;
    }
    printf("| %-44s | %10d | %10.3f |\n", "conflict-zone query, 48-point star", NSTAR / 10,
           1e6 * tq / (NSTAR / 10));
    as_del3_buf_free(ctx, &zone);
    as_del3_destroy(&d);
    free(sp);
end:
    free(p);
    anistar_context_free(ctx);
    return rc;
}
