/*
 * custom_metric — mesh an ellipsoid given by an expression with a metric field of our own
 * (a callback): edges three times shorter along z than across, finer towards x > 0.
 * Public API only; writes the mesh and prints its size and the time taken.
 *
 *   custom_metric [OUT.off|.obj|...]              (default /tmp/anistar_custom_metric.off)
 */
#include "anistar.h"

#include <math.h>
#include <stdio.h>

/* The tensor at p (m11 m12 m13 m22 m23 m33): M = diag(a, a, 9 a) with a = 4 (1 + e^x)^2,
 * i.e. a prescribed edge length 1 / (2 (1 + e^x)) across z and a third of it along z. */
static int my_metric(const double p[3], const double normal[3], double m[6], void *user) {
    (void)normal;
    (void)user;
    double h = 0.5 / (1.0 + exp(p[0])), a = 1.0 / (h * h);
    m[0] = a, m[1] = 0, m[2] = 0, m[3] = a, m[4] = 0, m[5] = 9 * a;
    return 0;
}

int main(int argc, char **argv) {
    const char *out = argc > 1 ? argv[1] : "/tmp/anistar_custom_metric.off";
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *mr = NULL;
    anistar_mesh *mesh = NULL;
    const double center[3] = {0, 0, 0};
    anistar_status st =
        anistar_surface_from_expression(ctx, "a=2; b=1.5; x^2/a^2 + y^2/b^2 + z^2 - 1",
                                        center, 2.5, &s);
    if (!st) st = anistar_metric_from_callback(ctx, s, my_metric, NULL, &m);
    if (!st) st = anistar_mesher_new(ctx, s, m, &mr);
    /* the metric already holds the sizes: r0 = 1 bounds circumradii by about 1 in it */
    if (!st) st = anistar_mesher_set(mr, ANISTAR_PARAM_R0, 1.0);
    if (!st) st = anistar_mesher_set(mr, ANISTAR_PARAM_GAMMA0, 2.0);
    if (!st) st = anistar_mesher_run(mr, &mesh);
    if (mesh && (st == ANISTAR_OK || st == ANISTAR_INCOMPLETE)) {
        anistar_status wst = anistar_mesh_write(ctx, mesh, out);
        anistar_mesh_stats stats;
        anistar_mesh_get_stats(mesh, &stats);
        printf("custom_metric: %zu vertices, %zu facets, %.2f seconds%s -> %s\n", stats.vertices,
               stats.facets, stats.seconds_total, st ? " (incomplete)" : "", out);
        if (wst) st = wst;
    }
    if (st && st != ANISTAR_INCOMPLETE)
        fprintf(stderr, "custom_metric: %s\n", anistar_last_error(ctx));
    anistar_mesh_free(mesh);
    anistar_mesher_free(mr);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return st == ANISTAR_OK ? 0 : st == ANISTAR_INCOMPLETE ? 3 : 1;
}
