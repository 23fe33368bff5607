/*
 * bench_meshio.c — load times of triangle-mesh files: bunny00.off (ASCII, 2.6 MB), the
 * binary PLY and binary STL written from it, the other writers, and the topology check.
 * Best of 5 runs each; prints a plain table (MB/s over the file size, triangles/s).
 *
 * Run from the project root: build/bench/bench/bench_meshio [path/to/mesh.off]
 */
#include "core.h"
#include "io/meshio.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double file_mb(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (double)st.st_size / 1e6 : 0;
}

/* Best of 5 reads of path; exits on failure (a bench, not a test). */
static double best_read(anistar_context *ctx, const char *path, size_t *nt) {
    double best = 1e30;
    for (int i = 0; i < 5; i++) {
        as_trimesh m;
        as_trimesh_init(&m);
        double t0 = now();
        anistar_status st = as_mesh_read(ctx, path, &m);
        double t = now() - t0;
        if (st) {
            fprintf(stderr, "%s\n", anistar_last_error(ctx));
            exit(1);
        }
        *nt = m.nt;
        as_trimesh_free(ctx, &m);
        if (t < best) best = t;
    }
    return best;
}

static double best_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                         const as_cell_field *cf, size_t ncf) {
    double best = 1e30;
    for (int i = 0; i < 5; i++) {
        double t0 = now();
        if (as_mesh_write(ctx, path, m, cf, ncf)) {
            fprintf(stderr, "%s\n", anistar_last_error(ctx));
            exit(1);
        }
        double t = now() - t0;
        if (t < best) best = t;
    }
    return best;
}

int main(int argc, char **argv) {
    const char *src = argc > 1 ? argv[1] : "test/data/bunny00.off";
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    char dir[] = "/tmp/anistar_bench_meshio_XXXXXX";
    if (!mkdtemp(dir)) {
        perror("mkdtemp");
        return 1;
    }
    as_trimesh m;
    as_trimesh_init(&m);
    if (as_mesh_read(ctx, src, &m)) {
        fprintf(stderr, "%s\n", anistar_last_error(ctx));
        return 1;
    }
    as_trimesh_alloc_tensors(ctx, &m);
    for (size_t i = 0; i < m.nv; i++) {
        double *t = m.tensor + 6 * i;
        t[0] = t[3] = t[5] = 1.0 + (double)(i % 7);
        t[1] = 0.25;
    }
    double *q = malloc(m.nt * sizeof(double));
    for (size_t i = 0; i < m.nt; i++) q[i] = (double)(i % 100) / 100.0;
    as_cell_field cf = {"quality", q};

    printf("source: %s (%zu vertices, %zu triangles)\n\n", src, m.nv, m.nt);
    printf("%-28s %10s %12s %10s %14s\n", "operation", "MB", "best s (5)", "MB/s", "triangles/s");
    size_t nt;
    double t = best_read(ctx, src, &nt);
    printf("%-28s %10.2f %12.4f %10.1f %14.3e\n", "read off (ascii)", file_mb(src), t,
           file_mb(src) / t, (double)nt / t);

    static const char *exts[] = {"ply", "stl", "obj", "off", "mesh", "sol", "vtk", "vtu"};
    char path[256];
    for (size_t e = 0; e < sizeof exts / sizeof exts[0]; e++) {
        snprintf(path, sizeof path, "%s/bunny.%s", dir, exts[e]);
        int vtk = e >= 6;
        t = best_write(ctx, path, &m, vtk ? &cf : NULL, vtk ? 1 : 0);
        char label[64];
        snprintf(label, sizeof label, "write %s%s", exts[e],
                 e == 0 ? " (binary LE)" : e == 1 ? " (binary)" : "");
        printf("%-28s %10.2f %12.4f %10.1f %14.3e\n", label, file_mb(path), t,
               file_mb(path) / t, (double)m.nt / t);
        if (e <= 4) {
            t = best_read(ctx, path, &nt);
            snprintf(label, sizeof label, "read %s%s", exts[e],
                     e == 0 ? " (binary LE)" : e == 1 ? " (binary, weld)" : "");
            printf("%-28s %10.2f %12.4f %10.1f %14.3e\n", label, file_mb(path), t,
                   file_mb(path) / t, (double)nt / t);
        }
        remove(path);
    }
    double best = 1e30;
    as_topology r;
    for (int i = 0; i < 5; i++) {
        double t0 = now();
        if (as_topology_check(ctx, m.nv, m.xyz, m.nt, m.tri, &r)) return 1;
        double dt = now() - t0;
        if (dt < best) best = dt;
    }
    printf("%-28s %10s %12.4f %10s %14.3e\n", "topology check", "-", best, "-",
           (double)m.nt / best);
    rmdir(dir);
    free(q);
    as_trimesh_free(ctx, &m);
    anistar_context_free(ctx);
    return 0;
}
