/*
 * bench_partition.c — the star set split over k parts, simulated in one process
 * (lib/mesher/partition.h; docs/scaling.md; issue 15 item 4).
 *
 * Usage: bench_partition [SURFACE METRIC R0 GAMMA0 K,K,...]; SURFACE is a built-in spec
 * or a file (triangle mesh or image, images at Otsu's threshold). Default: the paper's
 * torus (torus,R=10,r=1, curvature, r0 0.1, gamma0 1.5) with k = 1, 2, 4, 8. The ratios
 * are against the first k listed when it is 1 (give 1 first). BENCH_PARTITION_ROUNDS set:
 * each part's times, rounds and counts on stderr.
 *
 * First the serial run (one star set: the reference), then per k the parts' rounds, the
 * stitch and the check (a run from the union of the owned sites, certified like any
 * other). One markdown row per k. Times are CPU seconds of the threads concerned: the
 * parts run as threads of this process (on fewer cores than parts they take turns), and
 * "parallel" sums over the rounds the slowest part's time, what k ranks would take
 * without the exchanges' communication.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "bench_util.h"

#include "mesher/mesher.h"
#include "mesher/partition.h"
#include "surface/field.h"
#include "surface/surface.h"

int main(int argc, char **argv) {
    const char *surf = argc > 1 ? argv[1] : "torus,R=10,r=1";
    const char *met = argc > 2 ? argv[2] : "curvature";
    double r0 = argc > 3 ? atof(argv[3]) : 0.1;
    double g0 = argc > 4 ? atof(argv[4]) : 1.5;
    const char *ks = argc > 5 ? argv[5] : "1,2,4,8";
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    as_surface *s;
    as_field *f;
    anistar_status st = strchr(surf, '.') && !strchr(surf, '=') ? anistar_surface_read(ctx, surf, &s)
                                                                 : anistar_surface_builtin(ctx, surf, &s);
    if (st) bench_die("bench_partition", ctx, st, "surface");
    if ((st = anistar_metric_from_spec(ctx, s, met, &f)))
        bench_die("bench_partition", ctx, st, "metric");
    as_mesher_params prm;
    as_mesher_params_default(&prm);
    prm.r0 = r0;
    prm.gamma0 = g0;

    double c0 = bench_cpu_seconds();
    anistar_mesh *m = NULL;
    st = as_mesher_run(ctx, s, f, &prm, NULL, &m);
    double serial = bench_cpu_seconds() - c0;
    if (st != ANISTAR_OK) bench_die("bench_partition", ctx, st, "serial run");
    size_t nv = m->tm.nv;
    as_mesh_free(m);
    printf("%s / %s, r0 %g, gamma0 %g: serial run %zu V certified in %.2f CPU-s\n\n", surf, met,
           r0, g0, nv, serial);
    printf("| k | rounds | union V | part V (min-max, halo incl.) | halo in | requests (stale) | "
           "stars as in the union | union facets consistent | repairs | check | V | "
           "parts CPU-s | parallel CPU-s (start) | k = 1 / parallel | without the start |\n");
    printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    /* the baseline of the ratios: one part (the serial run with the hook, its start
     * measured the same way as the parts') */
    double base = 0, base_init = 0;
    for (const char *p = ks; *p;) {
        int k = atoi(p);
        as_partition_result res;
        anistar_mesh *out = NULL;
        st = as_partition_run(ctx, s, f, &prm, k, &res, &out);
        if (st != ANISTAR_OK && st != ANISTAR_INCOMPLETE)
            bench_die("bench_partition", ctx, st, "partition run");
        int64_t pmin = INT64_MAX, pmax = 0, halo = 0, req = 0, stale = 0;
        double init = 0;
        for (int i = 0; i < k; i++) {
            if (res.part[i].sites < pmin) pmin = res.part[i].sites;
            if (res.part[i].sites > pmax) pmax = res.part[i].sites;
            halo += res.part[i].halo_in;
            req += res.part[i].requests_in + res.part[i].requests_stale;
            stale += res.part[i].requests_stale;
            if (res.part[i].init_seconds > init) init = res.part[i].init_seconds;
        }
        /* without the start: each part samples the whole surface here (a rank would
         * sample its box); the serial run's start is taken out likewise */
        double par_ns = res.parallel_seconds - init;
        if (k == 1) {
            base = res.parallel_seconds;
            base_init = init;
        }
        printf("| %d | %d | %lld | %lld-%lld | %lld | %lld (%lld) | %lld / %lld (%.2f%%) | %lld / "
               "%lld (%.2f%%) | %lld | %s | %lld | %.2f | %.2f (%.2f) | %.2f | %.2f |\n",
               k, res.rounds, (long long)res.union_sites, (long long)pmin, (long long)pmax,
               (long long)halo, (long long)req, (long long)stale, (long long)res.stars_same,
               (long long)res.union_sites,
               res.union_sites ? 100.0 * (double)res.stars_same / (double)res.union_sites : 0,
               (long long)res.union_consistent, (long long)res.union_facets,
               res.union_facets ? 100.0 * (double)res.union_consistent / (double)res.union_facets
                                : 0,
               (long long)res.repairs, res.certified ? "certified" : "NOT certified",
               (long long)res.final_sites, res.total_seconds, res.parallel_seconds, init,
               res.parallel_seconds > 0 ? base / res.parallel_seconds : 0,
               par_ns > 0 ? (base - base_init) / par_ns : 0);
        if (getenv("BENCH_PARTITION_ROUNDS"))
            for (int i = 0; i < k; i++) {
                fprintf(stderr, "k %d part %d: init %.3f s, rounds", k, i, res.part[i].init_seconds);
                for (int r = 0; r < res.rounds && r < 8; r++)
                    fprintf(stderr, " %.3f", res.part[i].round_seconds[r]);
                fprintf(stderr, "; total %.3f s; owned %lld, inserted %lld, halo in %lld, "
                        "requests in %lld (stale %lld), deferred %lld, sites %lld\n",
                        res.part[i].cpu_seconds, (long long)res.part[i].owned,
                        (long long)res.part[i].inserted, (long long)res.part[i].halo_in,
                        (long long)res.part[i].requests_in, (long long)res.part[i].requests_stale, (long long)res.part[i].deferred,
                        (long long)res.part[i].sites);
            }
        fflush(stdout);
        if (out) as_mesh_free(out);
        p = strchr(p, ',');
        if (!p) break;
        p++;
    }
    anistar_metric_free(f);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return 0;
}
