/*
 * bench_expr.c — evaluations per second of compiled expressions (lib/surface/expr.c):
 * value, value + gradient, value + gradient + Hessian, for the torus and chair implicit
 * surfaces of DESIGN.md, plus compile time. Points come from an array, every result is
 * accumulated (and printed) so that nothing is optimised away. One core, process CPU
 * time; never asserts on time. Usage: bench_expr [seconds per row, default 0.4]
 */
#include "bench_util.h"
#include "surface/expr.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define NPTS 4096


/* A fixed pseudo-random point cloud in [-lo, lo]^3 (SplitMix64). */
static void make_points(double *pts, double lo) {
    bench_rng r = {12345};
    for (int i = 0; i < 3 * NPTS; i++) pts[i] = lo * (2.0 * bench_unit(&r) - 1.0);
}

typedef struct row {
    double rate;
    double sink;
} row;

/* Run mode (0 value, 1 +gradient, 2 +Hessian) for about `secs` seconds. */
static row run(const as_expr *e, const double *pts, int mode, double secs) {
    row r = {0.0, 0.0};
    long n = 0;
    double acc = 0.0, g[3], h[6];
    double t0 = bench_cpu_seconds(), t1 = t0;
    while (t1 - t0 < secs) {
        for (int rep = 0; rep < 16; rep++) {
            for (int i = 0; i < NPTS; i++) {
                const double *p = pts + 3 * i;
                if (mode == 0) {
                    acc += as_expr_value(e, p);
                } else if (mode == 1) {
                    acc += as_expr_value_grad(e, p, g);
                    acc += g[0] + g[1] + g[2];
                } else {
                    acc += as_expr_value_grad_hess(e, p, g, h);
                    acc += g[0] + g[1] + g[2] + h[0] + h[3] + h[5] + h[1] + h[2] + h[4];
                }
            }
            n += NPTS;
        }
        t1 = bench_cpu_seconds();
    }
    r.rate = (double)n / (t1 - t0);
    r.sink = acc;
    return r;
}

int main(int argc, char **argv) {
    double secs = argc > 1 ? atof(argv[1]) : 0.4;
    if (!(secs > 0.0)) secs = 0.4;
    static const struct {
        const char *name, *src;
        double lo;
    } cases[] = {
        {"torus", "R=10; r=1; (sqrt(x^2+y^2)-R)^2 + z^2 - r^2", 12.0},
        {"chair", "a=0.8; b=0.4; k=1; (x^2+y^2+z^2-a*k^2)^2 - b*((z-k)^2-2*x^2)*((z+k)^2-2*y^2)",
         1.5},
        {"sphere", "x^2 + y^2 + z^2 - 1", 1.5},
        {"mix", "sin(x)*exp(y/3)/(2+cos(z)) + atan2(y, x) - log(1 + x^2) + tanh(z)^3", 2.0},
    };
    static const char *mode_name[3] = {"value", "value+grad", "value+grad+hess"};
    static const double target[3] = {20e6, 0.0, 3e6};
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    double *pts = malloc(sizeof(double) * 3 * NPTS);
    if (!pts) return 1;
    double sink = 0.0;
    printf("%-8s %-16s %14s %14s %8s %6s\n", "expr", "mode", "evals/s", "target", "ns/eval",
           "insns");
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        as_expr *e = NULL;
        if (as_expr_compile(ctx, cases[c].src, &e)) {
            fprintf(stderr, "compile %s: %s\n", cases[c].name, anistar_last_error(ctx));
            return 1;
        }
        make_points(pts, cases[c].lo);
        for (int m = 0; m < 3; m++) {
            row r = run(e, pts, m, secs);
            sink += r.sink;
            char tg[32] = "-";
            if (target[m] > 0.0 && c < 2) snprintf(tg, sizeof tg, ">= %.0fM", target[m] / 1e6);
            printf("%-8s %-16s %14.0f %14s %8.1f %6zu\n", cases[c].name, mode_name[m], r.rate, tg,
                   1e9 / r.rate, as_expr_code_size(e));
        }
        as_expr_free(ctx, e);
    }
    /* Compile speed: the torus source, repeatedly. */
    {
        long n = 0;
        double t0 = bench_cpu_seconds(), t1 = t0;
        while (t1 - t0 < secs) {
            for (int i = 0; i < 256; i++) {
                as_expr *e = NULL;
                if (as_expr_compile(ctx, cases[0].src, &e)) return 1;
                sink += as_expr_code_size(e);
                as_expr_free(ctx, e);
            }
            n += 256;
            t1 = bench_cpu_seconds();
        }
        printf("%-8s %-16s %14.0f %14s %8.1f\n", "torus", "compile", (double)n / (t1 - t0), "-",
               1e9 * (t1 - t0) / (double)n);
    }
    printf("(checksum %g)\n", sink);
    free(pts);
    anistar_context_free(ctx);
    return 0;
}
