/*
 * bench_surfaces — triangle-mesh and image surfaces (lib/surface/mesh.c, image.c, jet.c):
 * the load of bunny00.off as a surface by phase (read, validate and orient, AABB tree,
 * kd-tree, per-vertex jets), the oracle's queries on it (segment crossings, side,
 * projection, frame), the blended curvature metric (creation and queries at surface
 * points), and the skull image surface (creation, crossings, curvature metric). Prints a
 * plain table (CPU time); never asserts on time.
 */
#include "geom/bvh.h"
#include "geom/kdtree.h"
#include "io/meshio.h"
#include "surface/field.h"
#include "surface/jet.h"
#include "surface/surface.h"

#include <math.h>
#include <stdint.h>
#include "bench_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifndef AS_BENCH_DATA_DIR
#define AS_BENCH_DATA_DIR "test/data"
#endif

static double now(void) { return bench_cpu_seconds(); } /* CPU time: robust when shared */

typedef bench_rng rng;
static double unit(rng *r) { return bench_unit(r); }

static void print_head(const char *title) {
    printf("\n%-52s %14s %12s  %s\n", title, "per second", "us / call", "notes");
}

static void print_row(const char *what, double calls, double secs, const char *note) {
    printf("%-52s %14.0f %12.2f  %s\n", what, calls / secs, 1e6 * secs / calls, note);
}

static void print_time(const char *what, double secs, const char *note) {
    printf("%-52s %14s %12.3f  %s\n", what, "(seconds)", secs, note);
}

static void die(anistar_context *ctx, anistar_status st, const char *what) {
    bench_die("bench_surfaces", ctx, st, what);
}

/* A random point of the bounding box of the sphere (center, radius). */
static void rand_in_ball_box(rng *r, const as_surface *s, double p[3]) {
    for (int k = 0; k < 3; k++) p[k] = s->center[k] + (2 * unit(r) - 1) * s->radius / 1.1;
}

static void bench_mesh(anistar_context *ctx) {
    const char *path = AS_BENCH_DATA_DIR "/bunny00.off";
    print_head("bunny00.off (37,706 vertices, 75,408 triangles)");
    /* phases, as the constructor runs them */
    as_trimesh m;
    as_trimesh_init(&m);
    double t0 = now();
    anistar_status st = as_mesh_read(ctx, path, &m);
    double t1 = now();
    if (st) die(ctx, st, "as_mesh_read");
    print_time("  read (OFF parser)", t1 - t0, "");
    as_topology rep;
    t0 = now();
    st = as_topology_orient(ctx, m.nv, m.xyz, m.nt, m.tri, &rep);
    t1 = now();
    if (st) die(ctx, st, "as_topology_orient");
    print_time("  validate + orient (topology)", t1 - t0, "closed 2-manifold, no zero area");
    as_bvh *bvh;
    t0 = now();
    st = as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &bvh);
    t1 = now();
    if (st) die(ctx, st, "as_bvh_build_triangles");
    print_time("  AABB tree", t1 - t0, "");
    as_kdtree *kd;
    t0 = now();
    st = as_kdtree_build(ctx, m.xyz, NULL, m.nv, &kd);
    t1 = now();
    if (st) die(ctx, st, "as_kdtree_build");
    print_time("  kd-tree", t1 - t0, "");
    as_bvh_free(ctx, bvh);
    as_kdtree_free(ctx, kd);
    as_trimesh_free(ctx, &m);

    as_surface *s;
    t0 = now();
    st = as_mesh_surface_read(ctx, path, &s);
    t1 = now();
    if (st) die(ctx, st, "as_mesh_surface_read");
    print_time("as_mesh_surface_read (all of the above + jets)", t1 - t0,
               "jets: degree 2, 16 neighbours, every vertex");
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    double *jets = malloc(mi.nv * AS_MESH_VJET * sizeof(double));
    if (!jets) exit(1);
    t0 = now();
    st = as_mesh_surface_jets(ctx, s, 2, AS_JET_K2, jets);
    t1 = now();
    if (st) die(ctx, st, "jets");
    print_row("  per-vertex jet, degree 2, k = 16", (double)mi.nv, t1 - t0, "kNN + weighted LSQ");
    t0 = now();
    st = as_mesh_surface_jets(ctx, s, 4, AS_JET_K4, jets);
    t1 = now();
    if (st) die(ctx, st, "jets");
    print_row("  per-vertex jet, degree 4, k = 28", (double)mi.nv, t1 - t0, "");
    free(jets);

    /* oracle queries */
    const size_t nq = 100000;
    rng r = {42};
    double *a = malloc(9 * nq * sizeof(double));
    if (!a) exit(1);
    for (size_t i = 0; i < 3 * nq; i++) rand_in_ball_box(&r, s, a + 3 * i);
    double *b = a + 3 * nq, *ref = a + 6 * nq;
    /* points on S (projections of random points), for crossings, frames and metrics */
    double *on = malloc(3 * nq * sizeof(double));
    if (!on) exit(1);
    for (size_t i = 0; i < nq; i++) as_surface_project(ctx, s, a + 3 * i, on + 3 * i);
    for (size_t i = 0; i < nq; i++) {
        /* segments of length ~ 4 mean edges through a point near S: like dual edges */
        for (int k = 0; k < 3; k++) {
            double d = (2 * unit(&r) - 1) * 2 * mi.spacing;
            double c = on[3 * i + k] + (2 * unit(&r) - 1) * 0.5 * mi.spacing;
            b[3 * i + k] = c + d;
            ref[3 * i + k] = c;
        }
    }
    double *sa = malloc(3 * nq * sizeof(double));
    if (!sa) exit(1);
    for (size_t i = 0; i < 3 * nq; i++) sa[i] = 2 * ref[i] - b[i];
    size_t found = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        int f;
        double x[3];
        as_surface_crossing(ctx, s, sa + 3 * i, b + 3 * i, ref + 3 * i, &f, x);
        found += (size_t)f;
    }
    t1 = now();
    char note[128];
    snprintf(note, sizeof note, "4-edge segments near S, %.0f%% meet S",
             100.0 * (double)found / (double)nq);
    print_row("segment crossing (short, near S)", (double)nq, t1 - t0, note);
    /* long segments: through the whole model */
    found = 0;
    t0 = now();
    for (size_t i = 0; i < nq / 10; i++) {
        int f;
        double x[3];
        as_surface_crossing(ctx, s, a + 3 * i, a + 3 * (nq - 1 - i), ref + 3 * i, &f, x);
        found += (size_t)f;
    }
    t1 = now();
    snprintf(note, sizeof note, "random chords of the box, %.0f%% meet S",
             100.0 * (double)found / (double)(nq / 10));
    print_row("segment crossing (long)", (double)(nq / 10), t1 - t0, note);
    int sum = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        int side;
        as_surface_side(ctx, s, a + 3 * i, &side);
        sum += side;
    }
    t1 = now();
    print_row("side (exact ray parity)", (double)nq, t1 - t0, "random points of the box");
    double acc = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double q[3];
        as_surface_project(ctx, s, a + 3 * i, q);
        acc += q[0];
    }
    t1 = now();
    print_row("projection (closest point)", (double)nq, t1 - t0, "random points of the box");
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double q[3];
        as_surface_project(ctx, s, ref + 3 * i, q);
        acc += q[0];
    }
    t1 = now();
    print_row("projection (closest point), points near S", (double)nq, t1 - t0,
              "within half an edge of S");
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        as_surface_frame fr;
        as_surface_frame_at(ctx, s, on + 3 * i, &fr);
        acc += fr.k[0];
    }
    t1 = now();
    print_row("frame (normal, curvatures; interpolated jets)", (double)nq, t1 - t0,
              "includes the closest-point query");

    const char *specs[] = {"curvature", "curvature,degree=4"};
    for (int k = 0; k < 2; k++) {
        as_field *f;
        t0 = now();
        st = as_field_from_spec(ctx, s, specs[k], &f);
        t1 = now();
        if (st) die(ctx, st, specs[k]);
        snprintf(note, sizeof note, "jets (if not the default) + tensors + r_B + hash grid");
        char what[96];
        snprintf(what, sizeof what, "metric '%s': creation", specs[k]);
        print_time(what, t1 - t0, note);
        t0 = now();
        for (size_t i = 0; i < nq; i++) {
            double mt[6];
            as_field_eval(ctx, f, on + 3 * i, mt);
            acc += mt[0];
        }
        t1 = now();
        snprintf(what, sizeof what, "metric '%s': query at surface points", specs[k]);
        snprintf(note, sizeof note, "Gaussian blending, r_B = %.4g (%.2f mean edges)",
                 as_blend_radius(f->blend), as_blend_radius(f->blend) / mi.spacing);
        print_row(what, (double)nq, t1 - t0, note);
        as_field_free(f);
    }
    if (sum == 12345 && acc == 0.5) printf("(unlikely)\n");
    free(sa);
    free(on);
    free(a);
    as_surface_free(s);
}

static void bench_image(anistar_context *ctx) {
    const char *path = AS_BENCH_DATA_DIR "/skull_2.9.inr";
    print_head("skull_2.9.inr (64^3 float32) at 2.9");
    as_surface *s;
    double t0 = now();
    anistar_status st = as_image_surface_read(ctx, path, 2.9, 1, &s);
    double t1 = now();
    if (st) die(ctx, st, "as_image_surface_read");
    print_time("as_image_surface_read", t1 - t0, "read + B-spline prefilter");
    as_point_sample smp;
    t0 = now();
    st = as_surface_sample(ctx, s, 256, &smp);
    t1 = now();
    if (st) die(ctx, st, "sample");
    char note[128];
    snprintf(note, sizeof note, "%zu points, %zu components", smp.n, smp.ncomponents);
    print_time("initial sample (256 points)", t1 - t0, note);
    const size_t nq = 20000;
    rng r = {7};
    size_t found = 0;
    double acc = 0;
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        const double *p = smp.points + 3 * (i % smp.n);
        double a[3], b[3], x[3];
        for (int k = 0; k < 3; k++) {
            double d = (2 * unit(&r) - 1) * 8;
            a[k] = p[k] + d;
            b[k] = p[k] - d;
        }
        int f;
        as_surface_crossing(ctx, s, a, b, p, &f, x);
        found += (size_t)f;
    }
    t1 = now();
    snprintf(note, sizeof note, "segments of ~2 voxels through S, %.0f%% found",
             100.0 * (double)found / (double)nq);
    print_row("segment crossing", (double)nq, t1 - t0, note);
    as_field *f;
    t0 = now();
    st = as_field_from_spec(ctx, s, "curvature", &f);
    t1 = now();
    if (st) die(ctx, st, "curvature");
    print_time("metric 'curvature': creation", t1 - t0, "samples S for e_n");
    t0 = now();
    for (size_t i = 0; i < nq; i++) {
        double m[6];
        as_field_eval(ctx, f, smp.points + 3 * (i % smp.n), m);
        acc += m[0];
    }
    t1 = now();
    print_row("metric 'curvature': query", (double)nq, t1 - t0, "spline Hessian");
    if (acc == 0.5) printf("(unlikely)\n");
    as_field_free(f);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
}

int main(void) {
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    printf("bench_surfaces: CPU time per call\n");
    bench_mesh(ctx);
    bench_image(ctx);
    anistar_context_free(ctx);
    return 0;
}
