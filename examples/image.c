/*
 * image — mesh an isosurface of a 3D image (.inr .nrrd .nhdr .mha .mhd) through the
 * public API: the image is reconstructed by a cubic B-spline and the surface is where it
 * equals ISO, the inside where the value is greater (gray-level images). The metric is
 * uniform (Euclidean: r0 is then a length in the image's world units, millimetres for
 * the skull); pass a SPEC as the 6th argument for another, e.g. "curvature,power=0.5".
 * Writes the mesh (PLY: the per-vertex tensors come along) and prints its size, Euler
 * characteristic and the time taken.
 *
 *   image [IMAGE [ISO [OUT.ply|.off|... [R0 [GAMMA0 [METRIC]]]]]]
 *         (defaults test/data/skull_2.9.inr, 2.9, /tmp/anistar_image.ply, 4, 1.5,
 *          euclidean)
 *
 * The defaults make a coarse mesh of the skull (surface circumradii below 10 mm).
 *
 * Exit status: 0 done, 1 error (one line on stderr), 2 bad arguments, 3 stopped at the
 * time guard (the consistent part of the mesh is written).
 */
#include "anistar.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

/* A number from the command line, or NaN when it is not one. */
static double arg_number(const char *s) {
    char *end;
    double v = strtod(s, &end);
    return end != s && *end == '\0' ? v : NAN;
}

int main(int argc, char **argv) {
    const char *in = argc > 1 ? argv[1] : "test/data/skull_2.9.inr";
    double iso = argc > 2 ? arg_number(argv[2]) : 2.9;
    const char *out = argc > 3 ? argv[3] : "/tmp/anistar_image.ply";
    double r0 = argc > 4 ? arg_number(argv[4]) : 4.0;
    double gamma0 = argc > 5 ? arg_number(argv[5]) : 1.5;
    const char *metric = argc > 6 ? argv[6] : "euclidean";
    if (argc > 7 || !isfinite(iso)) {
        fprintf(stderr, "usage: image [IMAGE [ISO [OUT [R0 [GAMMA0 [METRIC]]]]]]\n");
        return 2;
    }
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        fprintf(stderr, "image: out of memory\n");
        return 1;
    }
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *mr = NULL;
    anistar_mesh *mesh = NULL;
    /* ENOSURFACE when iso is not strictly between the smallest and largest voxel */
    anistar_status st = anistar_surface_from_image_file(ctx, in, iso, ANISTAR_INSIDE_GREATER, &s);
    if (!st) st = anistar_metric_from_spec(ctx, s, metric, &m);
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
            printf("image: %s at %g: %zu vertices, %zu facets, Euler characteristic %lld, "
                   "%.2f seconds%s -> %s\n",
                   in, iso, stats.vertices, stats.facets, stats.euler_characteristic,
                   stats.seconds_total, st ? " (incomplete)" : "", out);
        }
    }
    if (st && st != ANISTAR_INCOMPLETE)
        fprintf(stderr, "image: %s\n", anistar_last_error(ctx));
    anistar_mesh_free(mesh);
    anistar_mesher_free(mr);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    if (usage) return 2;
    return st == ANISTAR_OK ? 0 : st == ANISTAR_INCOMPLETE ? 3 : 1;
}
