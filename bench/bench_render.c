/*
 * bench_render.c — the renderer and the PNG encoder: rasterizing knot1.off (6,400
 * triangles) and bunny00.off (75,408) at 1024x768 with 1, 2 and 3 samples per pixel
 * side, then encoding the picture stored and deflated (MB/s over the raw scanlines,
 * compression ratio). Best of 3 runs each; prints a plain table.
 *
 * Run from the project root: build/bench/bench/bench_render
 */
#include "core.h"
#include "io/meshio.h"
#include "io/png.h"
#include "io/render.h"

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void die(anistar_context *ctx) {
    fprintf(stderr, "%s\n", anistar_last_error(ctx));
    exit(1);
}

int main(void) {
    const char *files[] = {"test/data/knot1.off", "test/data/bunny00.off"};
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    const uint32_t W = 1024, H = 768;
    unsigned char *rgb = malloc((size_t)W * H * 3);
    if (!rgb) return 1;
    double raw_mb = (double)H * (1 + 3.0 * W) / 1e6;
    printf("%-12s %9s %3s %10s %12s %10s %10s %8s\n", "mesh", "triangles", "ss", "render ms",
           "Msamples/s", "stored MB/s", "deflate MB/s", "ratio");
    for (size_t f = 0; f < sizeof files / sizeof files[0]; f++) {
        as_trimesh m;
        as_trimesh_init(&m);
        if (as_mesh_read(ctx, files[f], &m)) die(ctx);
        double *val = malloc(m.nt * sizeof(double));
        if (!val) return 1;
        for (size_t t = 0; t < m.nt; t++)
            val[t] = as_tri_radius_edge(m.xyz + 3 * (size_t)m.tri[3 * t],
                                        m.xyz + 3 * (size_t)m.tri[3 * t + 1],
                                        m.xyz + 3 * (size_t)m.tri[3 * t + 2]);
        for (int ss = 1; ss <= 3; ss++) {
            as_render_params p;
            as_render_params_init(&p);
            p.supersample = ss;
            p.label = "radius-edge ratio";
            double best = 1e30;
            for (int i = 0; i < 3; i++) {
                double t0 = now();
                if (as_render(ctx, &p, m.nv, m.xyz, m.nt, m.tri, val, rgb)) die(ctx);
                double t = now() - t0;
                if (t < best) best = t;
            }
            double bs = 1e30, bd = 1e30;
            size_t ns = 0, nd = 0;
            for (int i = 0; i < 3; i++) {
                unsigned char *out;
                double t0 = now();
                if (as_png_encode_mem(ctx, rgb, W, H, 3, AS_PNG_STORED, &out, &ns)) die(ctx);
                double t = now() - t0;
                as_free(ctx, out, ns);
                if (t < bs) bs = t;
                t0 = now();
                if (as_png_encode_mem(ctx, rgb, W, H, 3, AS_PNG_DEFLATE, &out, &nd)) die(ctx);
                t = now() - t0;
                as_free(ctx, out, nd);
                if (t < bd) bd = t;
            }
            const char *name = f == 0 ? "knot1" : "bunny00";
            printf("%-12s %9zu %3d %10.1f %12.1f %10.0f %10.0f %8.2f\n", name, m.nt, ss,
                   1e3 * best, (double)W * H * ss * ss / best / 1e6, raw_mb / bs, raw_mb / bd,
                   (double)ns / (double)nd);
        }
        free(val);
        as_trimesh_free(ctx, &m);
    }
    free(rgb);
    anistar_context_free(ctx);
    return 0;
}
