/*
 * bench_predicates — calls per second of orient3d and insphere, plain floating point
 * (_fast), adaptive exact, and _exact, on random and on near-degenerate inputs; the
 * ratio adaptive / fast; the per-stage counters of the adaptive predicates and of
 * insphere_sos (bench builds are compiled with -DANISTAR_BENCH).
 *
 * Inputs live in arrays small enough for L1/L2 (so memory is not what is measured), every
 * result feeds a checksum printed at the end (so no call can be optimised away), and each
 * timing is the best of several repetitions (the machine may be shared).
 */
#include "bench_util.h"
#include "geom/predicates.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#define NCASE 1024

static double rng_range(bench_rng *r, double lo, double hi) {
    return lo + (hi - lo) * bench_unit(r);
}

/* Five points per case. */
static double pts[NCASE][5][3];

static void gen_random(bench_rng *r) {
    for (int i = 0; i < NCASE; i++)
        for (int j = 0; j < 5; j++)
            for (int k = 0; k < 3; k++) pts[i][j][k] = rng_range(r, -1, 1);
}

/* Near-degenerate: points on a sphere (so also nearly cospherical for insphere) whose
 * fourth point is (nearly) on the plane of the first three for orient3d, rounded to
 * doubles and moved by up to 2 ulps. */
static void gen_near_degenerate(bench_rng *r) {
    for (int i = 0; i < NCASE; i++) {
        double c[3] = {rng_range(r, -1, 1), rng_range(r, -1, 1), rng_range(r, -1, 1)};
        for (int j = 0; j < 5; j++) {
            double v[3], l;
            do {
                for (int k = 0; k < 3; k++) v[k] = rng_range(r, -1, 1);
                l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            } while (l < 0.1 || l > 1);
            for (int k = 0; k < 3; k++) pts[i][j][k] = c[k] + v[k] / l;
        }
        if (i % 2 == 0) { /* orient3d-degenerate: point 3 on the plane of 0, 1, 2 */
            double u = rng_range(r, 0, 1), w = rng_range(r, 0, 1);
            for (int k = 0; k < 3; k++)
                pts[i][3][k] = pts[i][0][k] + u * (pts[i][1][k] - pts[i][0][k]) +
                               w * (pts[i][2][k] - pts[i][0][k]);
        }
        int j = (int)(bench_u64(r) % 5), k = (int)(bench_u64(r) % 3),
            n = (int)(bench_u64(r) % 5) - 2;
        for (; n > 0; n--) pts[i][j][k] = nextafter(pts[i][j][k], 2.0);
        for (; n < 0; n++) pts[i][j][k] = nextafter(pts[i][j][k], -2.0);
    }
}

typedef double (*o3d_fn)(const double *, const double *, const double *, const double *);
typedef double (*isp_fn)(const double *, const double *, const double *, const double *,
                         const double *);

static double checksum;

/* Best ns per call over reps repetitions of rounds passes over the cases. */
static double time_o3d_reps(o3d_fn f, int rounds, int reps) {
    double best = 1e30;
    for (int rep = 0; rep < reps; rep++) {
        double acc = 0;
        double t0 = bench_cpu_seconds();
        for (int r = 0; r < rounds; r++)
            for (int i = 0; i < NCASE; i++) {
                double v = f(pts[i][0], pts[i][1], pts[i][2], pts[i][3]);
                acc += (v > 0) - (v < 0);
            }
        double t = bench_cpu_seconds() - t0;
        checksum += acc;
        if (t < best) best = t;
    }
    return best * 1e9 / ((double)rounds * NCASE);
}

static double time_isp_reps(isp_fn f, int rounds, int reps) {
    double best = 1e30;
    for (int rep = 0; rep < reps; rep++) {
        double acc = 0;
        double t0 = bench_cpu_seconds();
        for (int r = 0; r < rounds; r++)
            for (int i = 0; i < NCASE; i++) {
                double v = f(pts[i][0], pts[i][1], pts[i][2], pts[i][3], pts[i][4]);
                acc += (v > 0) - (v < 0);
            }
        double t = bench_cpu_seconds() - t0;
        checksum += acc;
        if (t < best) best = t;
    }
    return best * 1e9 / ((double)rounds * NCASE);
}

static double time_o3d(o3d_fn f, int rounds) { return time_o3d_reps(f, rounds, 5); }
static double time_isp(isp_fn f, int rounds) { return time_isp_reps(f, rounds, 5); }

/* fast and adaptive timed in alternation (best of many short runs each), so that load
 * from other processes affects both alike; returns the two times through t. */
static void pair_o3d(o3d_fn fast, o3d_fn adaptive, int rounds, double t[2]) {
    t[0] = t[1] = 1e30;
    for (int k = 0; k < 15; k++) {
        double a = time_o3d_reps(fast, rounds, 1), b = time_o3d_reps(adaptive, rounds, 1);
        if (a < t[0]) t[0] = a;
        if (b < t[1]) t[1] = b;
    }
}

static void pair_isp(isp_fn fast, isp_fn adaptive, int rounds, double t[2]) {
    t[0] = t[1] = 1e30;
    for (int k = 0; k < 15; k++) {
        double a = time_isp_reps(fast, rounds, 1), b = time_isp_reps(adaptive, rounds, 1);
        if (a < t[0]) t[0] = a;
        if (b < t[1]) t[1] = b;
    }
}

static double time_sos(int rounds) {
    double best = 1e30;
    for (int rep = 0; rep < 5; rep++) {
        double acc = 0;
        double t0 = bench_cpu_seconds();
        for (int r = 0; r < rounds; r++)
            for (int i = 0; i < NCASE; i++)
                acc +=
                    as_insphere_sos(pts[i][0], pts[i][1], pts[i][2], pts[i][3], pts[i][4],
                                    5 * i, 5 * i + 1, 5 * i + 2, 5 * i + 3, 5 * i + 4);
        double t = bench_cpu_seconds() - t0;
        checksum += acc;
        if (t < best) best = t;
    }
    return best * 1e9 / ((double)rounds * NCASE);
}

static void row(const char *pred, const char *input, const char *variant, double ns) {
    printf("%-10s %-16s %-9s %12.2f %10.1f\n", pred, input, variant, 1e3 / ns, ns);
}

static void stage_line(const char *pred, const char *input, uint64_t calls,
                       const uint64_t st[4]) {
    double c = calls ? (double)calls : 1.0;
    printf("%-10s %-16s %12llu %9.4f%% %9.4f%% %9.4f%% %9.4f%%\n", pred, input,
           (unsigned long long)calls, 100.0 * (double)st[0] / c, 100.0 * (double)st[1] / c,
           100.0 * (double)st[2] / c, 100.0 * (double)st[3] / c);
}

#ifndef ANISTAR_BENCH
/* Built without the counters (e.g. to time the library exactly as shipped): no-ops. */
typedef struct as_pred_counters {
    uint64_t orient3d_calls, orient3d_stage[4];
    uint64_t insphere_calls, insphere_stage[4];
    uint64_t insphere_sos_calls, insphere_sos_perturbed;
} as_pred_counters;
static as_pred_counters no_counters;
static as_pred_counters *as_pred_counters_get(void) { return &no_counters; }
static void as_pred_counters_reset(void) {}
#endif

int main(void) {
    bench_rng r = {12345};
    const char *inputs[2] = {"random", "near-degenerate"};
    double ratio_o[2], ratio_i[2];
    as_pred_counters cnt[2];

    printf("%-10s %-16s %-9s %12s %10s\n", "predicate", "input", "variant", "Mcalls/s",
           "ns/call");
    for (int in = 0; in < 2; in++) {
        if (in == 0)
            gen_random(&r);
        else
            gen_near_degenerate(&r);
        int fast_rounds = 400, exact_rounds = 20;
        double t[2], of, oa, isf, isa;
        as_pred_counters_reset();
        if (in == 0) {
            pair_o3d(as_orient3d_fast, as_orient3d, fast_rounds, t);
            of = t[0];
            oa = t[1];
        } else {
            of = time_o3d(as_orient3d_fast, fast_rounds);
            oa = time_o3d(as_orient3d, exact_rounds * 5);
        }
        cnt[in] = *as_pred_counters_get();
        double oe = time_o3d(as_orient3d_exact, exact_rounds * 5);
        as_pred_counters_reset();
        if (in == 0) {
            pair_isp(as_insphere_fast, as_insphere, fast_rounds / 2, t);
            isf = t[0];
            isa = t[1];
        } else {
            isf = time_isp(as_insphere_fast, fast_rounds / 2);
            isa = time_isp(as_insphere, exact_rounds);
        }
        as_pred_counters cnt_i = *as_pred_counters_get();
        cnt[in].insphere_calls = cnt_i.insphere_calls;
        memcpy(cnt[in].insphere_stage, cnt_i.insphere_stage, sizeof cnt_i.insphere_stage);
        double ise = time_isp(as_insphere_exact, exact_rounds);
        as_pred_counters_reset();
        double sos = time_sos(in == 0 ? fast_rounds / 4 : exact_rounds);
        cnt_i = *as_pred_counters_get();
        cnt[in].insphere_sos_calls = cnt_i.insphere_sos_calls;
        cnt[in].insphere_sos_perturbed = cnt_i.insphere_sos_perturbed;
        row("orient3d", inputs[in], "fast", of);
        row("orient3d", inputs[in], "adaptive", oa);
        row("orient3d", inputs[in], "exact", oe);
        row("insphere", inputs[in], "fast", isf);
        row("insphere", inputs[in], "adaptive", isa);
        row("insphere", inputs[in], "exact", ise);
        row("insph_sos", inputs[in], "adaptive", sos);
        ratio_o[in] = oa / of;
        ratio_i[in] = isa / isf;
    }
    printf("\nratio adaptive / fast (time per call; target <= 1.5 on random):\n");
    for (int in = 0; in < 2; in++)
        printf("  %-16s orient3d %6.2f   insphere %6.2f\n", inputs[in], ratio_o[in],
               ratio_i[in]);

    printf(
        "\nstage counters of the adaptive runs (share of calls settled by each stage):\n");
    printf("%-10s %-16s %12s %10s %10s %10s %10s\n", "predicate", "input", "calls",
           "filter", "B", "C", "exact");
    for (int in = 0; in < 2; in++) {
        stage_line("orient3d", inputs[in], cnt[in].orient3d_calls, cnt[in].orient3d_stage);
        stage_line("insphere", inputs[in], cnt[in].insphere_calls, cnt[in].insphere_stage);
    }
    printf("\ninsphere_sos: calls and calls that needed the perturbation:\n");
    for (int in = 0; in < 2; in++)
        printf("  %-16s %12llu %12llu\n", inputs[in],
               (unsigned long long)cnt[in].insphere_sos_calls,
               (unsigned long long)cnt[in].insphere_sos_perturbed);
    printf("\n(checksum %.0f)\n", checksum);
    return 0;
}
