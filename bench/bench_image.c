/*
 * bench_image.c — 3D image readers and the cubic B-spline reconstruction:
 * load time of the test images, prefilter time, and evaluations per second (value only,
 * value + gradient, value + gradient + Hessian) at random points inside the image.
 * Run from the project root (the images are read from test/data). Prints plain tables;
 * asserts nothing about time.
 */
#include "anistar.h"
#include "io/image_io.h"
#include "surface/bspline.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#define DATA "test/data/"

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static uint64_t rng_next(uint64_t *s) {
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static double rng_unit(uint64_t *s) { return (double)(rng_next(s) >> 11) * 0x1.0p-53; }

static void die(anistar_context *ctx, const char *what) {
    fprintf(stderr, "bench_image: %s: %s\n", what, anistar_last_error(ctx));
    exit(1);
}

/* Repeat loading path for at least 0.3 s; print ms per load and MB/s of voxels. */
static void bench_load(anistar_context *ctx, const char *path) {
    int reps = 0;
    double t0 = now(), t = 0;
    size_t bytes = 0, nx = 0, ny = 0, nz = 0;
    const char *type = "";
    while (t < 0.3 || reps < 3) {
        as_image *img;
        if (as_image_read(ctx, path, &img)) die(ctx, path);
        bytes = img->data_bytes;
        nx = img->nx;
        ny = img->ny;
        nz = img->nz;
        type = as_voxel_type_name(img->type);
        as_image_free(ctx, img);
        reps++;
        t = now() - t0;
    }
    double per = t / reps;
    printf("%-34s %4zux%4zux%4zu %-8s %9.3f %10.1f\n", path, nx, ny, nz, type, 1e3 * per,
           (double)bytes / per / 1e6);
}

/* Prefilter timing (best of a few runs). */
static void bench_prefilter(anistar_context *ctx, const char *name, const as_image *img) {
    double best = 1e30;
    for (int r = 0; r < 3; r++) {
        as_bspline *bs;
        double t0 = now();
        if (as_bspline_create(ctx, img, 0, &bs)) die(ctx, name);
        double t = now() - t0;
        best = t < best ? t : best;
        as_bspline_free(ctx, bs);
    }
    printf("%-34s %12zu %10.2f %12.1f %10.1f\n", name, img->count, 1e3 * best,
           (double)img->count / best / 1e6, (double)img->count * 8 / 1048576.0);
}

enum { NPTS = 1 << 16 };

/* Evaluations per second at random world points inside the voxel-center box. */
static void bench_eval(const char *name, const as_bspline *bs, uint64_t *seed) {
    const as_grid *g = as_bspline_grid(bs);
    double(*pts)[3] = malloc(sizeof(double[3]) * NPTS);
    if (!pts) exit(1);
    for (int i = 0; i < NPTS; i++) {
        double v[3];
        for (int a = 0; a < 3; a++) v[a] = rng_unit(seed) * (double)(g->n[a] - 1);
        as_grid_voxel_to_world(g, v, pts[i]);
    }
    const long n = 2000000;
    double sink = 0, gr[3], h[6];
    double t0 = now();
    for (long i = 0; i < n; i++) sink += as_bspline_value(bs, pts[i & (NPTS - 1)]);
    double t1 = now();
    for (long i = 0; i < n; i++) {
        sink += as_bspline_value_grad(bs, pts[i & (NPTS - 1)], gr);
        sink += gr[0];
    }
    double t2 = now();
    for (long i = 0; i < n; i++) {
        sink += as_bspline_value_grad_hess(bs, pts[i & (NPTS - 1)], gr, h);
        sink += gr[1] + h[4];
    }
    double t3 = now();
    printf("%-34s %14.2f %14.2f %14.2f   (%g)\n", name, (double)n / (t1 - t0) / 1e6,
           (double)n / (t2 - t1) / 1e6, (double)n / (t3 - t2) / 1e6, sink > 0 ? 1.0 : 0.0);
    free(pts);
}

int main(void) {
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    uint64_t seed = 12345;

    printf("%-34s %-14s %-8s %9s %10s\n", "load", "dims", "type", "ms/load", "MB/s");
    bench_load(ctx, DATA "skull_2.9.inr");
    bench_load(ctx, DATA "liver_labels_half.inr");
    bench_load(ctx, DATA "brain_t1.mhd");
    bench_load(ctx, DATA "brain_t1.nhdr");

    as_image *skull, *brain, *liver, *big;
    if (as_image_read(ctx, DATA "skull_2.9.inr", &skull)) die(ctx, "skull");
    if (as_image_read(ctx, DATA "brain_t1.nhdr", &brain)) die(ctx, "brain");
    if (as_image_read(ctx, DATA "liver_labels_half.inr", &liver)) die(ctx, "liver");
    if (as_image_new(ctx, 192, 192, 192, AS_VOXEL_F32, &big)) die(ctx, "big");
    float *bd = big->data;
    for (size_t i = 0; i < big->count; i++) bd[i] = (float)rng_unit(&seed);

    printf("\n%-34s %12s %10s %12s %10s\n", "prefilter (best of 3)", "voxels", "ms", "Mvoxel/s",
           "coef MiB");
    bench_prefilter(ctx, "skull 64^3 float32", skull);
    bench_prefilter(ctx, "brain 128x128x62 uint8", brain);
    bench_prefilter(ctx, "liver 169x142x70 uint8", liver);
    bench_prefilter(ctx, "random 192^3 float32", big);

    printf("\n%-34s %14s %14s %14s\n", "evaluation (random inside points)", "value M/s",
           "val+grad M/s", "val+g+H M/s");
    as_image *imgs[4] = {skull, brain, liver, big};
    const char *names[4] = {"skull", "brain", "liver", "random 192^3 (56 MiB of coefs)"};
    for (int i = 0; i < 4; i++) {
        as_bspline *bs;
        if (as_bspline_create(ctx, imgs[i], 0, &bs)) die(ctx, names[i]);
        bench_eval(names[i], bs, &seed);
        as_bspline_free(ctx, bs);
        as_image_free(ctx, imgs[i]);
    }
    anistar_context_free(ctx);
    return 0;
}
