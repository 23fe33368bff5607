/*
 * mesh_curvature — mesh the surface of a closed triangle mesh read from a file with the
 * curvature metric of the paper (5.2.3: per-vertex jets, degree 2 on the 16 nearest
 * vertices, blended with Gaussian weights between vertices), through the public API.
 * Writes the new mesh (PLY: the per-vertex tensors come along) and prints its size,
 * Euler characteristic and the time taken.
 *
 *   mesh_curvature [IN.off|.obj|.ply|.stl|.mesh [OUT.ply|.off|... [R0 [GAMMA0]]]]
 *            (defaults test/data/knot1.off, /tmp/anistar_mesh_curvature.ply, 0.5, 2)
 *
 * The defaults make a coarse mesh of knot1.off in seconds: the metric's anisotropy is
 * softened (power 0.5) and the distortion bound is loose. The input must be a closed
 * 2-manifold (otherwise the error names the border and non-manifold edges).
 *
 * Exit status: 0 done, 1 error (one line on stderr), 2 bad arguments, 3 stopped at the
 * time guard (the consistent part of the mesh is written).
 */
#include "anistar.h"

#include <stdio.h>
#include <stdlib.h>

/* A number from the command line, or -1 when it is not one. */
static double arg_number(const char *s) {
    char *end;
    double v = strtod(s, &end);
    return end != s && *end == '\0' ? v : -1;
}

int main(int argc, char **argv) {
    const char *in = argc > 1 ? argv[1] : "test/data/knot1.off";
    const char *out = argc > 2 ? argv[2] : "/tmp/anistar_mesh_curvature.ply";
    double r0 = argc > 3 ? arg_number(argv[3]) : 0.5;
    double gamma0 = argc > 4 ? arg_number(argv[4]) : 2.0;
    if (argc > 5) {
        fprintf(stderr, "usage: mesh_curvature [IN [OUT [R0 [GAMMA0]]]]\n");
        return 2;
    }
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        fprintf(stderr, "mesh_curvature: out of memory\n");
        return 1;
    }
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *mr = NULL;
    anistar_mesh *mesh = NULL;
    /* the reader checks the mesh is closed and 2-manifold and orients it outward */
    anistar_status st = anistar_surface_read(ctx, in, &s);
    if (!st) st = anistar_metric_from_spec(ctx, s, "curvature,power=0.5", &m);
    if (!st) st = anistar_mesher_new(ctx, s, m, &mr);
    int usage = 0;
    if (!st && (st = anistar_mesher_set(mr, ANISTAR_PARAM_R0, r0)) != 0) usage = 1;
    if (!st && (st = anistar_mesher_set(mr, ANISTAR_PARAM_GAMMA0, gamma0)) != 0) usage = 1;
    /* a guard only: a run stopped there returns INCOMPLETE with the consistent facets */
    if (!st) st = anistar_mesher_set(mr, ANISTAR_PARAM_MAX_SECONDS, 300);
    if (!st) st = anistar_mesher_run(mr, &mesh);
    if (mesh) {
        anistar_status wst = anistar_mesh_write(ctx, mesh, out);
        if (wst) {
            st = wst;
        } else {
            anistar_mesh_stats stats;
            anistar_mesh_get_stats(mesh, &stats);
            printf("mesh_curvature: %s: %zu vertices, %zu facets, Euler characteristic "
                   "%lld, %.2f seconds%s -> %s\n",
                   in, stats.vertices, stats.facets, stats.euler_characteristic,
                   stats.seconds_total, st ? " (incomplete)" : "", out);
        }
    }
    if (st && st != ANISTAR_INCOMPLETE)
        fprintf(stderr, "mesh_curvature: %s\n", anistar_last_error(ctx));
    anistar_mesh_free(mesh);
    anistar_mesher_free(mr);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    if (usage) return 2;
    return st == ANISTAR_OK ? 0 : st == ANISTAR_INCOMPLETE ? 3 : 1;
}
