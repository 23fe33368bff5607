/*
 * bench_spatial — throughput of the spatial indexes (lib/geom/kdtree.c, bvh.c,
 * boxindex.c): kd-tree build, k-nearest and radius queries, incremental insertion; AABB
 * tree build, segment crossings, inside/outside by ray parity and closest points on a
 * 75,000-triangle torus; dynamic box index inserts, updates and point/box queries with
 * 10^5 boxes. Prints a plain table (CPU time); never asserts on time.
 */
#include "geom/boxindex.h"
#include "geom/bvh.h"
#include "geom/kdtree.h"
#include "geom/predicates.h"

#include <math.h>
#include <stdint.h>
#include "bench_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static double now(void) { return bench_cpu_seconds(); } /* CPU time: robust when shared */

typedef bench_rng rng;
static double unit(rng *r) { return bench_unit(r); }

static void print_head(const char *title) {
    printf("\n%-52s %14s %12s  %s\n", title, "per second", "ns / call", "notes");
}

static void print_row(const char *what, double calls, double secs, const char *note) {
    printf("%-52s %14.0f %12.1f  %s\n", what, calls / secs, 1e9 * secs / calls, note);
}

static void print_time(const char *what, double secs, const char *note) {
    printf("%-52s %14s %12.3f  %s\n", what, "(seconds)", secs, note);
}

static void die(anistar_context *ctx, anistar_status st, const char *what) {
    bench_die("bench_spatial", ctx, st, what);
}

/* ---- kd-tree --------------------------------------------------------------------------------- */

static void bench_kdtree(anistar_context *ctx) {
    const size_t n = 1000000, nq = 200000;
    rng r = {1};
    double *xyz = malloc(3 * n * sizeof *xyz);
    double *q = malloc(3 * nq * sizeof *q);
    if (!xyz || !q) exit(1);
    for (size_t i = 0; i < 3 * n; i++) xyz[i] = unit(&r);
    for (size_t i = 0; i < 3 * nq; i++) q[i] = unit(&r);
    print_head("kd-tree, 10^6 uniform points in the unit cube");

    as_kdtree *kd = NULL;
    double t0 = now();
    anistar_status st = as_kdtree_build(ctx, xyz, NULL, n, &kd);
    double t1 = now();
    if (st) die(ctx, st, "as_kdtree_build");
    print_time("build (static, 10^6 points)", t1 - t0, "median splits, leaves 8-16");

    int32_t ids[64];
    double d2[64];
    size_t sum = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) sum += as_kdtree_knn(kd, q + 3 * i, 20, ids, d2);
    t1 = now();
    print_row("k-nearest, k = 20 (static tree)", (double)nq, t1 - t0, "");
    t0 = now();
    for (size_t i = 0; i < nq; i++) sum += as_kdtree_knn(kd, q + 3 * i, 1, ids, d2);
    t1 = now();
    print_row("k-nearest, k = 1 (static tree)", (double)nq, t1 - t0, "");
    {   /* coherent queries: a 59^3 grid walked in lexicographic order (as a mesher's
         * queries, which follow its insertions) */
        const int g = 59;
        size_t m = 0;
        t0 = now();
        for (int a = 0; a < g; a++)
            for (int b2 = 0; b2 < g; b2++)
                for (int c = 0; c < g; c++) {
                    double p[3] = {(a + 0.5) / g, (b2 + 0.5) / g, (c + 0.5) / g};
                    sum += as_kdtree_knn(kd, p, 20, ids, d2);
                    m++;
                }
        t1 = now();
        print_row("k-nearest, k = 20 (static tree, coherent queries)", (double)m, t1 - t0,
                  "grid points in scan order");
    }

    as_idlist out = {0};
    size_t found = 0;
    const double rad = 0.02; /* about 33 points per ball */
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        st = as_kdtree_radius(ctx, kd, q + 3 * i, rad, &out);
        if (st) die(ctx, st, "as_kdtree_radius");
        found += out.n;
    }
    t1 = now();
    char note[96];
    snprintf(note, sizeof note, "r = %.2f, %.1f points each", rad, (double)found / (double)nq);
    print_row("radius query", (double)nq, t1 - t0, note);
    as_kdtree_free(ctx, kd);

    /* incremental insertion, one point at a time */
    st = as_kdtree_new(ctx, &kd);
    if (st) die(ctx, st, "as_kdtree_new");
    t0 = now();
    for (size_t i = 0; i < n; i++) {
        st = as_kdtree_insert(ctx, kd, xyz + 3 * i, (int32_t)i);
        if (st) die(ctx, st, "as_kdtree_insert");
    }
    t1 = now();
    snprintf(note, sizeof note, "forest of %zu trees at the end", as_kdtree_tree_count(kd));
    print_row("incremental insertion (10^6 points)", (double)n, t1 - t0, note);
    t0 = now();
    for (size_t i = 0; i < nq; i++) sum += as_kdtree_knn(kd, q + 3 * i, 20, ids, d2);
    t1 = now();
    print_row("k-nearest, k = 20 (forest after insertions)", (double)nq, t1 - t0, "");
    as_kdtree_free(ctx, kd);
    as_idlist_free(ctx, &out);
    if (sum == 0) printf("(no result)\n");
    free(xyz);
    free(q);
}

/* ---- AABB tree --------------------------------------------------------------------------------- */

static void bench_bvh(anistar_context *ctx) {
    const int nu = 250, nv = 150; /* 75,000 triangles */
    const double R = 1, rr = 0.4, pi = 3.14159265358979323846;
    size_t nvert = (size_t)nu * nv, nt = 2 * nvert;
    double *xyz = malloc(3 * nvert * sizeof *xyz);
    int32_t *tri = malloc(3 * nt * sizeof *tri);
    if (!xyz || !tri) exit(1);
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
            double *p = xyz + 3 * ((size_t)i * nv + j);
            p[0] = (R + rr * cos(v)) * cos(u);
            p[1] = (R + rr * cos(v)) * sin(u);
            p[2] = rr * sin(v);
        }
    size_t t = 0;
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            int32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j;
            int32_t c = ((i + 1) % nu) * nv + (j + 1) % nv, d = i * nv + (j + 1) % nv;
            int32_t q[6] = {a, b, c, a, c, d};
            memcpy(tri + 3 * t, q, sizeof q);
            t += 2;
        }
    print_head("AABB tree, torus R = 1, r = 0.4, 75,000 triangles");
    as_bvh *b = NULL;
    double t0 = now();
    anistar_status st = as_bvh_build_triangles(ctx, xyz, nvert, tri, nt, &b);
    double t1 = now();
    if (st) die(ctx, st, "as_bvh_build_triangles");
    print_time("build", t1 - t0, "median splits, leaves of 2-4 triangles");

    rng r = {2};
    const size_t nq = 100000;
    double *pa = malloc(3 * nq * sizeof *pa), *pb = malloc(3 * nq * sizeof *pb);
    double *ps = malloc(3 * nq * sizeof *ps), *pe = malloc(3 * nq * sizeof *pe);
    if (!pa || !pb || !ps || !pe) exit(1);
    for (size_t i = 0; i < nq; i++) {
        for (int k = 0; k < 3; k++) {
            double h = k < 2 ? 1.5 : 0.5;
            pa[3 * i + k] = h * (2 * unit(&r) - 1);
            pb[3 * i + k] = h * (2 * unit(&r) - 1);
        }
        /* short segments across the surface: a surface point +- 0.05 along a random
         * direction (the mesher's dual segments are of this kind) */
        double u = 2 * pi * unit(&r), v = 2 * pi * unit(&r), dir[3], l = 0;
        for (int k = 0; k < 3; k++) {
            dir[k] = 2 * unit(&r) - 1;
            l += dir[k] * dir[k];
        }
        l = sqrt(l);
        double c[3] = {(R + rr * cos(v)) * cos(u), (R + rr * cos(v)) * sin(u), rr * sin(v)};
        for (int k = 0; k < 3; k++) {
            ps[3 * i + k] = c[k] - 0.05 * dir[k] / l;
            pe[3 * i + k] = c[k] + 0.05 * dir[k] / l;
        }
    }
    as_bvh_hits hits = {0};
    size_t nh = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        st = as_bvh_segment(ctx, b, pa + 3 * i, pb + 3 * i, &hits);
        if (st) die(ctx, st, "as_bvh_segment");
        nh += hits.n;
    }
    t1 = now();
    char note[128];
    snprintf(note, sizeof note, "random points in the box, %.2f hits each", (double)nh / (double)nq);
    print_row("segment crossings (long segments)", (double)nq, t1 - t0, note);
    /* short segments through a surface point */
    nh = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        st = as_bvh_segment(ctx, b, ps + 3 * i, pe + 3 * i, &hits);
        if (st) die(ctx, st, "as_bvh_segment");
        nh += hits.n;
    }
    t1 = now();
    snprintf(note, sizeof note, "length 0.1 through a surface point, %.2f hits each",
             (double)nh / (double)nq);
    print_row("segment crossings (short segments)", (double)nq, t1 - t0, note);

#ifdef ANISTAR_BENCH
    as_pred_counters_reset();
#endif
    size_t inside = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) inside += as_bvh_side(b, pa + 3 * i) > 0;
    t1 = now();
    snprintf(note, sizeof note, "exact ray parity, %.1f%% inside", 100.0 * (double)inside / (double)nq);
    print_row("inside/outside (as_bvh_side)", (double)nq, t1 - t0, note);
#ifdef ANISTAR_BENCH
    {
        const as_pred_counters *pc = as_pred_counters_get();
        printf("%-52s orient3d calls %llu, settled by the filter %.4f%%\n", "  predicates",
               (unsigned long long)pc->orient3d_calls,
               pc->orient3d_calls ? 100.0 * (double)pc->orient3d_stage[0] / (double)pc->orient3d_calls : 0.0);
    }
#endif
    double sumd = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) sumd += as_bvh_closest(b, pa + 3 * i, NULL, NULL);
    t1 = now();
    print_row("closest point (random points in the box)", (double)nq, t1 - t0, "");
    t0 = now();
    for (size_t i = 0; i < nq; i++) sumd += as_bvh_closest(b, ps + 3 * i, NULL, NULL);
    t1 = now();
    print_row("closest point (points within 0.05 of the surface)", (double)nq, t1 - t0, "");
    as_idlist ids = {0};
    nh = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            lo[k] = ps[3 * i + k] - 0.02;
            hi[k] = ps[3 * i + k] + 0.02;
        }
        st = as_bvh_query_box(ctx, b, lo, hi, &ids);
        if (st) die(ctx, st, "as_bvh_query_box");
        nh += ids.n;
    }
    t1 = now();
    snprintf(note, sizeof note, "0.04-wide boxes near the surface, %.1f triangles each",
             (double)nh / (double)nq);
    print_row("box query", (double)nq, t1 - t0, note);
    if (sumd < 0) printf("(impossible)\n");
    as_idlist_free(ctx, &ids);
    as_bvh_hits_free(ctx, &hits);
    as_bvh_free(ctx, b);
    free(pa);
    free(pb);
    free(ps);
    free(pe);
    free(xyz);
    free(tri);
}

/* ---- box index ---------------------------------------------------------------------------------- */

static void bench_boxindex(anistar_context *ctx) {
    const int n = 100000, rounds = 10;
    const size_t nq = 200000;
    rng r = {3};
    print_head("box index, 10^5 boxes (each point in ~30), 10 updates each");
    double *ctr = malloc(3 * (size_t)n * sizeof *ctr), *half = malloc(3 * (size_t)n * sizeof *half);
    if (!ctr || !half) exit(1);
    const double s = 0.5 * cbrt(30.0 / n); /* half-size for ~30 boxes over each point */
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            ctr[3 * i + k] = unit(&r);
            half[3 * i + k] = s * (0.5 + unit(&r)); /* aspect up to 3 */
        }
    as_boxindex *bi = NULL;
    anistar_status st = as_boxindex_new(ctx, &bi);
    if (st) die(ctx, st, "as_boxindex_new");
    double t0 = now();
    for (int i = 0; i < n; i++) {
        double lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            lo[k] = ctr[3 * i + k] - half[3 * i + k];
            hi[k] = ctr[3 * i + k] + half[3 * i + k];
        }
        st = as_boxindex_set(ctx, bi, i, lo, hi);
        if (st) die(ctx, st, "as_boxindex_set");
    }
    double t1 = now();
    print_row("insert", (double)n, t1 - t0, "");
    /* updates: conflict zones shrink and drift a little at every change */
    t0 = now();
    for (int round = 0; round < rounds; round++)
        for (int i = 0; i < n; i++) {
            double lo[3], hi[3];
            for (int k = 0; k < 3; k++) {
                half[3 * i + k] *= 0.8 + 0.25 * unit(&r);
                ctr[3 * i + k] += 0.2 * half[3 * i + k] * (2 * unit(&r) - 1);
                lo[k] = ctr[3 * i + k] - half[3 * i + k];
                hi[k] = ctr[3 * i + k] + half[3 * i + k];
            }
            st = as_boxindex_set(ctx, bi, i, lo, hi);
            if (st) die(ctx, st, "as_boxindex_set");
        }
    t1 = now();
    print_row("update (shrink and drift)", (double)n * rounds, t1 - t0, "");
    /* back to the original sizes for the queries */
    for (int i = 0; i < n; i++) {
        double lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            half[3 * i + k] = s * (0.5 + unit(&r));
            lo[k] = ctr[3 * i + k] - half[3 * i + k];
            hi[k] = ctr[3 * i + k] + half[3 * i + k];
        }
        st = as_boxindex_set(ctx, bi, i, lo, hi);
        if (st) die(ctx, st, "as_boxindex_set");
    }
    as_idlist out = {0};
    size_t found = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double p[3] = {unit(&r), unit(&r), unit(&r)};
        st = as_boxindex_query_point(ctx, bi, p, &out);
        if (st) die(ctx, st, "as_boxindex_query_point");
        found += out.n;
    }
    t1 = now();
    char note[96];
    snprintf(note, sizeof note, "%.1f boxes contain each point", (double)found / (double)nq);
    print_row("point query", (double)nq, t1 - t0, note);
    found = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double lo[3] = {unit(&r), unit(&r), unit(&r)}, hi[3];
        for (int k = 0; k < 3; k++) hi[k] = lo[k] + s;
        st = as_boxindex_query_box(ctx, bi, lo, hi, &out);
        if (st) die(ctx, st, "as_boxindex_query_box");
        found += out.n;
    }
    t1 = now();
    snprintf(note, sizeof note, "boxes of the typical size, %.1f hits each", (double)found / (double)nq);
    print_row("box query", (double)nq, t1 - t0, note);
    t0 = now();
    for (int i = 0; i < n; i++) as_boxindex_remove(bi, i);
    t1 = now();
    print_row("remove", (double)n, t1 - t0, "");
    as_idlist_free(ctx, &out);
    as_boxindex_free(ctx, bi);
    free(ctr);
    free(half);
}

int main(void) {
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    printf("bench_spatial (CPU time)\n");
    bench_kdtree(ctx);
    bench_bvh(ctx);
    bench_boxindex(ctx);
    anistar_context_free(ctx);
    return 0;
}
