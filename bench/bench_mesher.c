/*
 * bench_mesher.c — the anisotropic surface mesher end to end (DESIGN.md 5 yardsticks).
 *
 * Default case: the torus R=10 r=1 with the curvature metric (eps 0.1), r0 0.1,
 * gamma0 1.5, beta 2.5, delta 0.3 (paper Table 2). Prints vertices, facets, seconds,
 * vertices/s, peak memory through a counting allocator (bytes and bytes per output
 * vertex), Pick_valid tries/failures, insertions per rule and seconds per phase.
 * Usage: bench_mesher [SURFACE METRIC R0 GAMMA0 [MAX_VERTICES]]; SURFACE is a built-in
 * spec or a triangle-mesh file (.off .stl .obj .ply .mesh).
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "anistar.h"

typedef struct counting {
    size_t live, peak;
} counting;

static void *count_alloc(void *user, void *ptr, size_t old, size_t n) {
    counting *c = user;
    if (n == 0) {
        if (ptr) c->live -= old;
        free(ptr);
        return NULL;
    }
    void *p = realloc(ptr, n);
    if (!p) return NULL;
    c->live += n - (ptr ? old : 0);
    if (c->live > c->peak) c->peak = c->live;
    return p;
}

int main(int argc, char **argv) {
    const char *surf = argc > 1 ? argv[1] : "torus,R=10,r=1";
    const char *met = argc > 2 ? argv[2] : "curvature,eps=0.1";
    double r0 = argc > 3 ? atof(argv[3]) : 0.1;
    double g0 = argc > 4 ? atof(argv[4]) : 1.5;
    double maxv = argc > 5 ? atof(argv[5]) : 0;
    counting cnt = {0, 0};
    anistar_allocator a = {count_alloc, &cnt};
    anistar_context *ctx = anistar_context_new(&a);
    anistar_surface *s;
    anistar_metric *m;
    anistar_mesher *me;
    anistar_mesh *mesh = NULL;
    /* a SURFACE with a mesh extension is read as a file (mesh inputs: issue 13's speed) */
    const char *dot = strrchr(surf, '.');
    int file = dot && (!strcmp(dot, ".off") || !strcmp(dot, ".stl") || !strcmp(dot, ".obj") ||
                       !strcmp(dot, ".ply") || !strcmp(dot, ".mesh"));
    if ((file ? anistar_surface_read(ctx, surf, &s) : anistar_surface_builtin(ctx, surf, &s)) ||
        anistar_metric_from_spec(ctx, s, met, &m) ||
        anistar_mesher_new(ctx, s, m, &me)) {
        fprintf(stderr, "bench_mesher: %s\n", anistar_last_error(ctx));
        return 1;
    }
    size_t base = cnt.live;
    cnt.peak = cnt.live;
    anistar_mesher_set(me, ANISTAR_PARAM_R0, r0);
    anistar_mesher_set(me, ANISTAR_PARAM_GAMMA0, g0);
    anistar_mesher_set(me, ANISTAR_PARAM_BETA, 2.5);
    anistar_mesher_set(me, ANISTAR_PARAM_DELTA, 0.3);
    anistar_mesher_set(me, ANISTAR_PARAM_MAX_VERTICES, maxv);
    anistar_status st = anistar_mesher_run(me, &mesh);
    if (!mesh) {
        fprintf(stderr, "bench_mesher: %s\n", anistar_last_error(ctx));
        return 1;
    }
    anistar_mesh_stats S;
    anistar_mesh_get_stats(mesh, &S);
    size_t peak = cnt.peak - base;
    printf("case                 %s / %s, r0 %g, gamma0 %g, beta 2.5, delta 0.3\n", surf, met, r0,
           g0);
    printf("status               %s\n", anistar_status_name(st));
    printf("vertices             %zu\n", S.vertices);
    printf("facets               %zu\n", S.facets);
    printf("inconsistent         %zu\n", S.inconsistent_facets);
    printf("euler / manifold     %lld / %d\n", S.euler_characteristic, S.closed_manifold);
    printf("poles                %zu\n", S.poles);
    printf("seconds              %.3f (init %.3f, refine %.3f, output %.3f)\n", S.seconds_total,
           S.seconds_init, S.seconds_refine, S.seconds_output);
    printf("vertices/s           %.0f\n", S.seconds_total > 0 ? (double)S.vertices / S.seconds_total : 0);
    printf("peak memory          %zu bytes (%.0f per output vertex)\n", peak,
           S.vertices ? (double)peak / (double)S.vertices : 0);
    printf("insertions           initial %llu, rule1 %llu, rule2 %llu, rule3 %llu\n",
           (unsigned long long)S.insertions_initial, (unsigned long long)S.insertions_rule[0],
           (unsigned long long)S.insertions_rule[1], (unsigned long long)S.insertions_rule[2]);
    printf("rule 1 causes        size %llu, distortion %llu, approx %llu, feature %llu; "
           "topology %llu\n",
           (unsigned long long)S.insertions_size, (unsigned long long)S.insertions_distortion,
           (unsigned long long)S.insertions_approx, (unsigned long long)S.insertions_feature,
           (unsigned long long)S.insertions_topology);
    printf("estimate             %.0f vertices, %.0f bytes (measured %zu bytes)\n",
           S.estimate_vertices, S.estimate_bytes, S.peak_bytes);
    printf("stop / stall_max     %s / %llu; feature_alpha %g (%llu halvings)\n",
           anistar_stop_reason_name(S.stop_reason), (unsigned long long)S.stall_max,
           S.feature_alpha, (unsigned long long)S.feature_halvings);
    printf("pick_valid           tries %llu, failures %llu\n",
           (unsigned long long)S.pick_valid_tries, (unsigned long long)S.pick_valid_failures);
    printf("rho_max r_max gamma  %.3f %.4f %.3f\n", S.rho_max, S.r_max, S.gamma_max);
    printf("rho^2 histogram      (bin %.2f)", S.histogram_width);
    for (int b = 0; b < 20; b++) printf(" %llu", (unsigned long long)S.histogram[b]);
    printf(" ...\n");
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return 0;
}
