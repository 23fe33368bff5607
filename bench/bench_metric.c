/*
 * bench_metric — throughput of the metric kernel (lib/geom/linalg.c, lib/geom/metric.c):
 * eigen-decompositions, frames, the stretched transform, distortions with and without the
 * filter of as_metric_distortion_le (and the fraction of pairs the filter settles), and
 * small least squares. Prints a plain table; never asserts on time.
 *
 * The distortion mix ("realistic"): metrics with random frames, F-eigenvalues of random
 * scale and anisotropy up to 10; half the pairs are neighbours (the second metric is the
 * first with its frame turned a little and its axes rescaled by 1.5^t, t in [-1.2, 1.2],
 * so gamma clusters around 1.5, the default gamma0), half are independent random pairs.
 */
#include "bench_util.h"
#include "geom/linalg.h"
#include "geom/metric.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>


typedef bench_rng rng;
static double unit(rng *r) { return bench_unit(r); }

static double gauss(rng *r) {
    double u = unit(r), v = unit(r);
    return sqrt(-2 * log(1 - u)) * cos(6.283185307179586 * v);
}

static void random_frame(rng *r, double q[9]) {
    double a = gauss(r), b = gauss(r), c = gauss(r), d = gauss(r);
    double n = sqrt(a * a + b * b + c * c + d * d);
    a /= n, b /= n, c /= n, d /= n;
    double m[9] = {a * a + b * b - c * c - d * d, 2 * (b * c - a * d), 2 * (b * d + a * c),
                   2 * (b * c + a * d), a * a - b * b + c * c - d * d, 2 * (c * d - a * b),
                   2 * (b * d - a * c), 2 * (c * d + a * b), a * a - b * b - c * c + d * d};
    memcpy(q, m, sizeof m);
}

static void orthonormalise(double u[9]) {
    for (int k = 0; k < 3; k++) {
        for (int j = 0; j < k; j++) {
            double d = u[3 * k] * u[3 * j] + u[3 * k + 1] * u[3 * j + 1] + u[3 * k + 2] * u[3 * j + 2];
            for (int i = 0; i < 3; i++) u[3 * k + i] -= d * u[3 * j + i];
        }
        double n = sqrt(u[3 * k] * u[3 * k] + u[3 * k + 1] * u[3 * k + 1] + u[3 * k + 2] * u[3 * k + 2]);
        for (int i = 0; i < 3; i++) u[3 * k + i] /= n;
    }
}

static void random_metric(rng *r, double amax, double u[9], double e[3]) {
    random_frame(r, u);
    double an = pow(amax, unit(r)), s = pow(10, 4 * unit(r) - 2);
    e[0] = s;
    e[1] = s * pow(an, unit(r));
    e[2] = s * an;
}

#define NPAIR 4096

static void print_row(const char *what, double calls, double secs, const char *note) {
    printf("%-44s %12.0f %10.1f  %s\n", what, calls / secs, 1e9 * secs / calls, note);
}

int main(void) {
    rng r = {12345};
    static double sym[NPAIR][6];
    static as_metric_frame fa[NPAIR], fb[NPAIR];
    double sink = 0;
    const int reps = 60;

    printf("%-44s %12s %10s  %s\n", "operation", "calls/s", "ns/call", "notes");

    /* Eigen-decompositions: random entries, and SPD metrics of anisotropy up to 10. */
    for (int i = 0; i < NPAIR; i++)
        for (int k = 0; k < 6; k++) sym[i][k] = 2 * unit(&r) - 1;
    double t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps; rep++)
        for (int i = 0; i < NPAIR; i++) {
            double w[3], v[9];
            as_sym3_eigen(sym[i], w, v);
            sink += w[0] + v[4];
        }
    double t1 = bench_cpu_seconds();
    print_row("as_sym3_eigen (random entries)", (double)reps * NPAIR, t1 - t0, "Jacobi");

    for (int i = 0; i < NPAIR; i++) {
        double u[9], e[3], w[3];
        random_metric(&r, 10, u, e);
        for (int k = 0; k < 3; k++) w[k] = e[k] * e[k];
        as_sym3_from_eigen(w, u, sym[i]);
    }
    t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps; rep++)
        for (int i = 0; i < NPAIR; i++) {
            double w[3], v[9];
            as_sym3_eigen(sym[i], w, v);
            sink += w[0] + v[4];
        }
    t1 = bench_cpu_seconds();
    print_row("as_sym3_eigen (SPD, anisotropy <= 10)", (double)reps * NPAIR, t1 - t0, "");

    t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps; rep++)
        for (int i = 0; i < NPAIR; i++) {
            as_metric_frame_init(&fa[i], sym[i]);
            sink += fa[i].f[0];
        }
    t1 = bench_cpu_seconds();
    print_row("as_metric_frame_init", (double)reps * NPAIR, t1 - t0, "eigen + F + F^-1");

    t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps * 10; rep++)
        for (int i = 0; i < NPAIR; i++) {
            double y[3];
            as_metric_apply(&fa[i], sym[(i + rep) % NPAIR], y);
            sink += y[0];
        }
    t1 = bench_cpu_seconds();
    print_row("as_metric_apply", (double)reps * 10 * NPAIR, t1 - t0, "y = F x");

    /* The realistic distortion mix. */
    for (int i = 0; i < NPAIR; i++) {
        double um[9], em[3], un[9], en[3];
        random_metric(&r, 10, um, em);
        if (i % 2 == 0) {
            double q[9], t = 0.3 * unit(&r);
            random_frame(&r, q);
            for (int k = 0; k < 9; k++) un[k] = um[k] + t * q[k];
            orthonormalise(un);
            for (int k = 0; k < 3; k++) en[k] = em[k] * pow(1.5, 2.4 * unit(&r) - 1.2);
        } else {
            random_metric(&r, 10, un, en);
        }
        as_metric_frame_from_eigen(&fa[i], um, em);
        as_metric_frame_from_eigen(&fb[i], un, en);
    }
    const double g0 = 1.5;
    long below = 0;
    t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps; rep++)
        for (int i = 0; i < NPAIR; i++) {
            double g = as_metric_distortion(&fa[i], &fb[i]);
            below += g <= g0;
            sink += g;
        }
    t1 = bench_cpu_seconds();
    print_row("as_metric_distortion", (double)reps * NPAIR, t1 - t0, "two eigen-solves");
    double t_exact = t1 - t0;

    long below2 = 0;
    t0 = bench_cpu_seconds();
    for (int rep = 0; rep < reps; rep++)
        for (int i = 0; i < NPAIR; i++) below2 += as_metric_distortion_le(&fa[i], &fb[i], g0);
    t1 = bench_cpu_seconds();
    print_row("as_metric_distortion_le (g = 1.5)", (double)reps * NPAIR, t1 - t0, "filter");
    double t_filter = t1 - t0;

    for (int gi = 0; gi < 3; gi++) {
        const double gs[3] = {1.2, 1.5, 2.0};
        long acc = 0, rej = 0, le_nb = 0, nb = 0;
        for (int i = 0; i < NPAIR; i++) {
            int f = as_metric_distortion_filter(&fa[i], &fb[i], gs[gi]);
            acc += f == 1;
            rej += f == 0;
            if (i % 2 == 0) {
                nb++;
                le_nb += f >= 0;
            }
        }
        printf("filter at g = %.1f: settles %.1f%% (accepts %.1f%%, rejects %.1f%%); "
               "neighbour pairs %.1f%%\n",
               gs[gi], 100.0 * (double)(acc + rej) / NPAIR, 100.0 * (double)acc / NPAIR,
               100.0 * (double)rej / NPAIR, 100.0 * (double)le_nb / (double)nb);
    }
    printf("pairs with gamma <= 1.5: %.1f%% (exact) %.1f%% (filtered); speed-up %.1fx\n",
           100.0 * (double)below / (reps * (double)NPAIR),
           100.0 * (double)below2 / (reps * (double)NPAIR), t_exact / t_filter);
    {
        /* gamma distribution of the neighbour pairs. */
        static double gl[NPAIR / 2];
        for (int i = 0; i < NPAIR / 2; i++) gl[i] = as_metric_distortion(&fa[2 * i], &fb[2 * i]);
        for (int i = 1; i < NPAIR / 2; i++)
            for (int j = i; j > 0 && gl[j - 1] > gl[j]; j--) {
                double t = gl[j];
                gl[j] = gl[j - 1];
                gl[j - 1] = t;
            }
        printf("neighbour pairs: gamma quartiles %.3f %.3f %.3f\n", gl[NPAIR / 8], gl[NPAIR / 4],
               gl[3 * NPAIR / 8]);
    }

    /* Small least squares: degree-4 bivariate jets. */
    static double a[300 * 15], b[300], work[300 * 15 + 300];
    const int ms[2] = {40, 300};
    for (int mi = 0; mi < 2; mi++) {
        int m = ms[mi];
        for (int i = 0; i < m; i++) {
            double x = 2 * unit(&r) - 1, y = 2 * unit(&r) - 1;
            int c = 0;
            for (int d = 0; d <= 4; d++)
                for (int p = d; p >= 0; p--) a[i * 15 + c++] = pow(x, p) * pow(y, d - p);
            b[i] = unit(&r);
        }
        int n = mi == 0 ? 20000 : 3000;
        t0 = bench_cpu_seconds();
        for (int k = 0; k < n; k++) {
            double x[15];
            as_lsq_solve(a, b, (size_t)m, 15, x, work);
            sink += x[k % 15];
        }
        t1 = bench_cpu_seconds();
        char what[64];
        snprintf(what, sizeof what, "as_lsq_solve (%d x 15)", m);
        print_row(what, n, t1 - t0, "pivoted Householder QR");
    }
    printf("(checksum %g)\n", sink);
    return 0;
}
