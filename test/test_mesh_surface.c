/*
 * test_mesh_surface.c — triangle-mesh surfaces (lib/surface/mesh.c) and their metric
 * fields (curvature by jets + blending, sol:FILE; lib/surface/field.c):
 *  - every mesh of test/data loads; outside on and beyond the bounding sphere, even
 *    crossing counts along random lines, outward normals, sampling on every component
 *    (with the exact area of each component);
 *  - sphere_r0.5.off against the exact sphere (the data README's distances), projection
 *    against brute force, side against |p| < 0.5, crossings against brute force;
 *  - curvatures: sphere_r0.5 within a few %, generated sphere and ellipsoid meshes
 *    (vertices exactly on the surface) against analytic values, ellipsoid.off against the
 *    ellipsoid fitted to its vertices, Gauss-Bonnet;
 *  - the blended curvature metric: SPD, continuous, e_n; sol files: constant round trip,
 *    count mismatch, non-SPD tensors, unused vertices;
 *  - bad meshes (open, non-manifold, zero area, bad indices, NaN), reorientation of
 *    flipped and inside-out meshes, nested components (a cavity), errors of the public
 *    API, allocation failures.
 */
#include "test_util.h"

#include "geom/bvh.h"
#include "geom/linalg.h"
#include "io/meshio.h"
#include "surface/field.h"
#include "surface/jet.h"
#include "surface/surface.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

static double dot3(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static double norm3(const double a[3]) { return sqrt(dot3(a, a)); }
static double dist3(const double a[3], const double b[3]) {
    double d[3] = {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
    return norm3(d);
}
static void cross3(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static void rand_unit(tu_rng *r, double u[3]) {
    double n;
    do {
        for (int i = 0; i < 3; i++) u[i] = tu_rng_range(r, -1, 1);
        n = norm3(u);
    } while (n > 1 || n < 0.1);
    for (int i = 0; i < 3; i++) u[i] /= n;
}

static const char *const mesh_files[] = {"bunny00.off", "elephant.off",   "fandisk.off",
                                         "knot1.off",   "sphere_r0.5.off", "ellipsoid.off",
                                         "hinge.stl",   "lever.stl"};
#define NFILES (sizeof mesh_files / sizeof mesh_files[0])

static void data_path(char *buf, size_t n, const char *name) {
    snprintf(buf, n, "%s/%s", AS_TEST_DATA_DIR, name);
}

static as_surface *load(anistar_context *ctx, const char *name) {
    char path[512];
    data_path(path, sizeof path, name);
    as_surface *s = NULL;
    anistar_status st = as_mesh_surface_read(ctx, path, &s);
    if (st) fail_msg("%s: %s", name, anistar_last_error(ctx));
    return s;
}

/* ---- generated meshes ------------------------------------------------------------------ */

typedef struct tmesh {
    double *xyz;
    int32_t *tri;
    size_t nv, nt;
} tmesh;

static void tmesh_free(tmesh *m) {
    test_free(m->xyz);
    test_free(m->tri);
    memset(m, 0, sizeof *m);
}

/* Midpoint of edge (a, b), created once (a small open-addressing table). */
typedef struct edge_map {
    int64_t *key;
    int32_t *val;
    size_t cap;
} edge_map;

static int32_t midpoint(edge_map *em, tmesh *m, int32_t a, int32_t b) {
    int32_t lo = a < b ? a : b, hi = a < b ? b : a;
    int64_t key = (int64_t)lo * 1000000 + hi;
    size_t i = (size_t)((uint64_t)key * 0x9E3779B97F4A7C15ULL >> 20) & (em->cap - 1);
    while (em->key[i] != -1) {
        if (em->key[i] == key) return em->val[i];
        i = (i + 1) & (em->cap - 1);
    }
    int32_t v = (int32_t)m->nv++;
    double *p = m->xyz + 3 * v;
    for (int k = 0; k < 3; k++) p[k] = 0.5 * (m->xyz[3 * a + k] + m->xyz[3 * b + k]);
    double l = norm3(p);
    for (int k = 0; k < 3; k++) p[k] /= l;
    em->key[i] = key;
    em->val[i] = v;
    return v;
}

/* An icosphere: the icosahedron subdivided `level` times, vertices on the unit sphere,
 * triangles counterclockwise seen from outside. 10 4^level + 2 vertices. */
static tmesh icosphere(int level) {
    tmesh m;
    size_t nvmax = 10 * ((size_t)1 << (2 * level)) + 2, ntmax = 20 * ((size_t)1 << (2 * level));
    m.xyz = test_malloc(3 * nvmax * sizeof(double));
    m.tri = test_malloc(3 * ntmax * sizeof(int32_t));
    const double t = (1 + sqrt(5.0)) / 2;
    const double v0[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                              {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                              {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    const int32_t f0[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                               {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                               {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                               {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int i = 0; i < 12; i++) {
        double l = norm3(v0[i]);
        for (int k = 0; k < 3; k++) m.xyz[3 * i + k] = v0[i][k] / l;
    }
    memcpy(m.tri, f0, sizeof f0);
    m.nv = 12;
    m.nt = 20;
    for (int l = 0; l < level; l++) {
        edge_map em;
        em.cap = 1;
        while (em.cap < 4 * 3 * m.nt) em.cap *= 2;
        em.key = test_malloc(em.cap * sizeof(int64_t));
        em.val = test_malloc(em.cap * sizeof(int32_t));
        for (size_t i = 0; i < em.cap; i++) em.key[i] = -1;
        size_t nt = m.nt;
        int32_t *old = test_malloc(3 * nt * sizeof(int32_t));
        memcpy(old, m.tri, 3 * nt * sizeof(int32_t));
        m.nt = 0;
        for (size_t f = 0; f < nt; f++) {
            int32_t a = old[3 * f], b = old[3 * f + 1], c = old[3 * f + 2];
            int32_t ab = midpoint(&em, &m, a, b), bc = midpoint(&em, &m, b, c),
                    ca = midpoint(&em, &m, c, a);
            int32_t nf[4][3] = {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}};
            memcpy(m.tri + 3 * m.nt, nf, sizeof nf);
            m.nt += 4;
        }
        test_free(old);
        test_free(em.key);
        test_free(em.val);
    }
    return m;
}

/* The sum of the areas of triangles tri[0..nt) (3 indices each) of xyz. */
static double mesh_area(const double *xyz, const int32_t *tri, size_t nt) {
    double a = 0;
    for (size_t t = 0; t < nt; t++) {
        const double *p = xyz + 3 * (size_t)tri[3 * t], *q = xyz + 3 * (size_t)tri[3 * t + 1],
                     *r = xyz + 3 * (size_t)tri[3 * t + 2];
        double u[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]},
               v[3] = {r[0] - p[0], r[1] - p[1], r[2] - p[2]}, w[3];
        cross3(u, v, w);
        a += 0.5 * norm3(w);
    }
    return a;
}

/* Brute-force closest point of the mesh. */
static double brute_closest(const as_mesh_info *mi, const double p[3], double q[3]) {
    double best = INFINITY;
    for (size_t t = 0; t < mi->nt; t++) {
        const int32_t *c = mi->tri + 3 * t;
        double x[3];
        double d = as_closest_on_triangle(p, mi->xyz + 3 * (size_t)c[0], mi->xyz + 3 * (size_t)c[1],
                                          mi->xyz + 3 * (size_t)c[2], x);
        if (d < best) {
            best = d;
            memcpy(q, x, sizeof x);
        }
    }
    return sqrt(best);
}

/* ---- every data file --------------------------------------------------------------------- */

static void test_load_all(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {1};
    for (size_t f = 0; f < NFILES; f++) {
        as_surface *s = load(ctx, mesh_files[f]);
        assert_true(as_surface_is_mesh(s));
        assert_string_equal(s->ops->kind, "mesh");
        as_mesh_info mi;
        as_mesh_surface_info(s, &mi);
        assert_int_equal(mi.ncomponents, 1);
        assert_true(mi.nv >= 4 && mi.nt % 2 == 0); /* closed: F = 2V - 2 chi (counts: test_meshio) */
        /* every vertex strictly inside the bounding sphere */
        for (size_t v = 0; v < mi.nv; v++)
            assert_true(dist3(mi.xyz + 3 * v, s->center) < s->radius);
        /* outside on and beyond the bounding sphere */
        for (int i = 0; i < 50; i++) {
            double u[3], p[3];
            int side;
            rand_unit(&r, u);
            double sc = i < 25 ? 1.0 : tu_rng_range(&r, 1, 3);
            for (int k = 0; k < 3; k++) p[k] = s->center[k] + sc * s->radius * u[k];
            assert_int_equal(as_surface_side(ctx, s, p, &side), ANISTAR_OK);
            assert_int_equal(side, 1);
        }
        /* closed: even crossing counts along random chords of the bounding sphere, and
         * the side of the chord's points between crossings alternates */
        int lines = 0;
        for (int i = 0; i < 200; i++) {
            double u[3], w[3], a[3], b[3];
            rand_unit(&r, u);
            rand_unit(&r, w);
            for (int k = 0; k < 3; k++) {
                a[k] = s->center[k] + s->radius * u[k];
                b[k] = s->center[k] + s->radius * w[k];
            }
            size_t proper;
            size_t n = as_bvh_segment_count(mi.bvh, a, b, &proper);
            if (proper != n) continue; /* through an edge or vertex: not generic */
            lines++;
            if (n % 2) fail_msg("%s: %zu crossings on a chord", mesh_files[f], n);
        }
        assert_true(lines > 150);
        /* outward normals: a small step along the normal never goes inside, a step
         * against it never outside (at a crease vertex one of the steps may slide along
         * a face: on S), and for nearly every vertex they go strictly out and in */
        size_t strict = 0, tried = 0;
        for (size_t v = 0; v < mi.nv; v += 1 + mi.nv / 3000) {
            as_surface_frame fr;
            assert_int_equal(as_surface_frame_at(ctx, s, mi.xyz + 3 * v, &fr), ANISTAR_OK);
            assert_false(fr.singular);
            double po[3], pi[3], eps = 1e-3 * mi.spacing;
            int so, si;
            for (int k = 0; k < 3; k++) {
                po[k] = mi.xyz[3 * v + k] + eps * fr.n[k];
                pi[k] = mi.xyz[3 * v + k] - eps * fr.n[k];
            }
            assert_int_equal(as_surface_side(ctx, s, po, &so), ANISTAR_OK);
            assert_int_equal(as_surface_side(ctx, s, pi, &si), ANISTAR_OK);
            if (so == -1 || si == 1 || (so == 0 && si == 0))
                fail_msg("%s: vertex %zu: the normal is not outward (sides %d %d)",
                         mesh_files[f], v, so, si);
            tried++;
            strict += so == 1 && si == -1;
        }
        assert_true(strict * 100 >= 95 * tried);
        /* sample: vertices of the mesh, one component */
        as_point_sample smp;
        assert_int_equal(as_surface_sample(ctx, s, 64, &smp), ANISTAR_OK);
        assert_int_equal(smp.ncomponents, 1);
        assert_true(smp.n >= 32 && smp.n <= 65);
        assert_true(smp.spacing > 0);
        /* the area: the exact sum of the triangles (the same sum in another order) */
        double area = mesh_area(mi.xyz, mi.tri, mi.nt);
        assert_true(fabs(smp.area[0] - area) <= 1e-12 * area);
        for (size_t i = 0; i < smp.n; i++) {
            double q[3];
            assert_true(brute_closest(&mi, smp.points + 3 * i, q) == 0);
            assert_int_equal(smp.component[i], 0);
        }
        as_surface_sample_free(ctx, &smp);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* ---- sphere_r0.5.off against the exact sphere ------------------------------------------------ */

static void test_sphere_distances(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s = load(ctx, "sphere_r0.5.off");
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    as_surface *ex;
    double c0[3] = {0, 0, 0};
    assert_int_equal(as_implicit_from_expression(ctx, "x^2+y^2+z^2-0.25", c0, 1, &ex), ANISTAR_OK);
    /* the README's sampling: barycentric lattice of step 1/10 on every face */
    double dmax = 0, dsum = 0;
    size_t cnt = 0;
    for (size_t t = 0; t < mi.nt; t++) {
        const int32_t *c = mi.tri + 3 * t;
        for (int i = 0; i <= 10; i++)
            for (int j = 0; i + j <= 10; j++) {
                double l1 = i / 10.0, l2 = j / 10.0, l0 = 1 - l1 - l2, p[3];
                for (int k = 0; k < 3; k++)
                    p[k] = l0 * mi.xyz[3 * c[0] + k] + l1 * mi.xyz[3 * c[1] + k] +
                           l2 * mi.xyz[3 * c[2] + k];
                double exact = fabs(norm3(p) - 0.5);
                /* the implicit sphere's projection gives the exact distance */
                double q[3];
                assert_int_equal(as_surface_project(ctx, ex, p, q), ANISTAR_OK);
                assert_true(fabs(dist3(p, q) - exact) < 1e-12);
                dmax = fmax(dmax, exact);
                dsum += exact;
                cnt++;
                /* the mesh's distance from the radial point of the exact sphere: at most
                 * the distance to p (a point of the mesh), equal to brute force */
                if ((i + j) % 3 == 0) {
                    double e[3], m[3], b[3];
                    for (int k = 0; k < 3; k++) e[k] = 0.5 * p[k] / norm3(p);
                    assert_int_equal(as_surface_project(ctx, s, e, m), ANISTAR_OK);
                    double dm = dist3(e, m), db = brute_closest(&mi, e, b);
                    assert_true(dm <= dist3(e, p) * (1 + 1e-12) + 1e-15);
                    assert_true(fabs(dm - db) <= 1e-15);
                    double f, g[3];
                    int side;
                    assert_int_equal(as_mesh_surface_signed_distance(ctx, s, e, &f, g), ANISTAR_OK);
                    assert_int_equal(as_surface_side(ctx, s, e, &side), ANISTAR_OK);
                    assert_true(fabs(fabs(f) - dm) <= 1e-15 && (f < 0) == (side < 0));
                }
            }
    }
    /* test/data/README.md: max 0.00846, mean 0.00509 */
    assert_true(fabs(dmax - 0.00846) < 5e-6);
    assert_true(fabs(dsum / (double)cnt - 0.00509) < 5e-6);
    as_surface_free(ex);
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_projection_side_crossing(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {7};
    const char *files[] = {"sphere_r0.5.off", "knot1.off", "bunny00.off"};
    for (int f = 0; f < 3; f++) {
        as_surface *s = load(ctx, files[f]);
        as_mesh_info mi;
        as_mesh_surface_info(s, &mi);
        int nq = f == 2 ? 40 : 200;
        for (int i = 0; i < nq; i++) {
            double p[3], q[3], b[3];
            for (int k = 0; k < 3; k++) p[k] = s->center[k] + tu_rng_range(&r, -1, 1) * s->radius;
            assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
            double d = dist3(p, q), db = brute_closest(&mi, p, b);
            if (!(fabs(d - db) <= 1e-15 * (1 + d))) fail_msg("%s: %g vs %g", files[f], d, db);
            /* signed distance: the sign is the side */
            double sd, g[3];
            int side;
            assert_int_equal(as_mesh_surface_signed_distance(ctx, s, p, &sd, g), ANISTAR_OK);
            assert_int_equal(as_surface_side(ctx, s, p, &side), ANISTAR_OK);
            assert_true(fabs(fabs(sd) - d) <= 1e-15);
            assert_true((sd < 0) == (side < 0));
            assert_true(fabs(norm3(g) - 1) < 1e-12);
        }
        /* crossings: the contact nearest ref, against brute force over the triangles */
        for (int i = 0; i < nq; i++) {
            double a[3], bb[3], ref[3], x[3];
            for (int k = 0; k < 3; k++) {
                a[k] = s->center[k] + tu_rng_range(&r, -1, 1) * s->radius;
                bb[k] = s->center[k] + tu_rng_range(&r, -1, 1) * s->radius;
                ref[k] = s->center[k] + tu_rng_range(&r, -1, 1) * s->radius;
            }
            int found;
            assert_int_equal(as_surface_crossing(ctx, s, a, bb, ref, &found, x), ANISTAR_OK);
            double best = INFINITY, xb[3] = {0, 0, 0};
            for (size_t t = 0; t < mi.nt; t++) {
                const int32_t *c = mi.tri + 3 * t;
                double tt;
                if (as_segment_triangle(a, bb, mi.xyz + 3 * (size_t)c[0],
                                        mi.xyz + 3 * (size_t)c[1], mi.xyz + 3 * (size_t)c[2],
                                        &tt) == AS_HIT_NONE)
                    continue;
                double y[3];
                for (int k = 0; k < 3; k++) y[k] = a[k] + tt * (bb[k] - a[k]);
                if (dist3(y, ref) < best) {
                    best = dist3(y, ref);
                    memcpy(xb, y, sizeof y);
                }
            }
            assert_int_equal(found, best < INFINITY);
            if (found) {
                assert_true(dist3(x, xb) < 1e-12 * s->radius);
                double q[3];
                assert_int_equal(as_surface_project(ctx, s, x, q), ANISTAR_OK);
                assert_true(dist3(x, q) < 1e-12 * s->radius);
                /* the endpoints' sides differ iff the number of generic crossings is odd */
            }
        }
        as_surface_free(s);
    }
    /* side of the sphere mesh against |p| < 0.5 away from the surface (the mesh deviates
     * from the sphere by at most 0.00846) */
    as_surface *s = load(ctx, "sphere_r0.5.off");
    int checked = 0;
    for (int i = 0; i < 2000; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(&r, -0.6, 0.6);
        double rr = norm3(p);
        if (fabs(rr - 0.5) < 0.009) continue;
        int side, pub;
        assert_int_equal(as_surface_side(ctx, s, p, &side), ANISTAR_OK);
        assert_int_equal(anistar_surface_side(s, p, &pub), ANISTAR_OK);
        assert_int_equal(side, rr < 0.5 ? -1 : 1);
        assert_int_equal(pub, side);
        checked++;
    }
    assert_true(checked > 1500);
    /* a vertex is on S */
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    int side;
    assert_int_equal(as_surface_side(ctx, s, mi.xyz, &side), ANISTAR_OK);
    assert_int_equal(side, 0);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* ---- curvature ----------------------------------------------------------------------------- */

/* Largest relative error of the frame's curvatures against k_exact over random points. */
static void check_sphere_frames(anistar_context *ctx, as_surface *s, double radius, tu_rng *r,
                                double tol_k, double tol_n) {
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    for (int i = 0; i < 300; i++) {
        double u[3], p[3];
        rand_unit(r, u);
        for (int k = 0; k < 3; k++) p[k] = radius * u[k];
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, s, p, &fr), ANISTAR_OK);
        for (int j = 0; j < 2; j++)
            if (!(fabs(fr.k[j] * radius - 1) < tol_k))
                fail_msg("curvature %g, want %g (tol %g)", fr.k[j], 1 / radius, tol_k);
        assert_true(acos(fmin(1, dot3(fr.n, u))) < tol_n);
        double c[3];
        cross3(fr.d, fr.d + 3, c);
        assert_true(dot3(c, fr.n) > 1 - 1e-12);
    }
}

static void test_curvature_spheres(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {13};
    /* the data file: 162 vertices, neighbourhoods of 35 degrees: within 5% (degree 2) */
    as_surface *s = load(ctx, "sphere_r0.5.off");
    check_sphere_frames(ctx, s, 0.5, &r, 0.05, 0.01);
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    double *j4 = test_malloc(mi.nv * AS_MESH_VJET * sizeof(double));
    assert_int_equal(as_mesh_surface_jets(ctx, s, 4, AS_JET_K4, j4), ANISTAR_OK);
    for (size_t v = 0; v < mi.nv; v++) /* degree 4: within 3% */
        assert_true(fabs(j4[AS_MESH_VJET * v + 3] / 2 - 1) < 0.03 &&
                    fabs(j4[AS_MESH_VJET * v + 4] / 2 - 1) < 0.03);
    assert_int_equal(as_mesh_surface_jets(ctx, s, 4, 10, j4), ANISTAR_EINVAL);
    assert_int_equal(as_mesh_surface_jets(ctx, s, 5, 30, j4), ANISTAR_EINVAL);
    assert_int_equal(as_mesh_surface_jets(ctx, s, 2, AS_JET_MAX_POINTS + 1, j4), ANISTAR_EINVAL);
    test_free(j4);
    as_surface_free(s);
    /* generated icospheres of radius 2: the error shrinks with refinement */
    double prev = INFINITY;
    for (int level = 2; level <= 4; level++) {
        tmesh m = icosphere(level);
        for (size_t i = 0; i < 3 * m.nv; i++) m.xyz[i] *= 2;
        assert_int_equal(as_mesh_surface_create(ctx, "ico", m.xyz, m.nv, m.tri, m.nt, &s),
                         ANISTAR_OK);
        as_mesh_surface_info(s, &mi);
        double worst = 0;
        for (size_t v = 0; v < mi.nv; v++)
            for (int j = 0; j < 2; j++)
                worst = fmax(worst, fabs(mi.vjet[AS_MESH_VJET * v + 3 + j] * 2 - 1));
        if (!(worst < prev / 2.5)) fail_msg("level %d: error %g after %g", level, worst, prev);
        prev = worst;
        if (level == 4) check_sphere_frames(ctx, s, 2, &r, 0.005, 0.002);
        as_surface_free(s);
        tmesh_free(&m);
    }
    anistar_context_free(ctx);
}

/* Ellipsoids: a generated one (vertices exactly on it) and the data file (its vertices
 * are within about 2% of the ellipsoid fitted to them). */
static void test_curvature_ellipsoids(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const double ax[3] = {0.2, 0.3, 0.5};
    tmesh m = icosphere(4);
    for (size_t v = 0; v < m.nv; v++)
        for (int k = 0; k < 3; k++) m.xyz[3 * v + k] *= ax[k];
    as_surface *s, *ex;
    assert_int_equal(as_mesh_surface_create(ctx, "ellipsoid", m.xyz, m.nv, m.tri, m.nt, &s),
                     ANISTAR_OK);
    double c0[3] = {0, 0, 0};
    assert_int_equal(as_implicit_from_expression(ctx, "(x/0.2)^2+(y/0.3)^2+(z/0.5)^2-1", c0, 1,
                                                 &ex),
                     ANISTAR_OK);
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    double worst = 0;
    for (size_t v = 0; v < mi.nv; v++) {
        as_surface_frame fr;
        assert_int_equal(as_surface_frame_at(ctx, ex, mi.xyz + 3 * v, &fr), ANISTAR_OK);
        const double *J = mi.vjet + AS_MESH_VJET * v;
        for (int j = 0; j < 2; j++) worst = fmax(worst, fabs(J[3 + j] / fr.k[j] - 1));
        assert_true(dot3(J, fr.n) > cos(0.01));
    }
    if (!(worst < 0.05)) fail_msg("generated ellipsoid: worst relative curvature error %g", worst);
    as_surface_free(s);
    as_surface_free(ex);
    tmesh_free(&m);

    /* ellipsoid.off: fit x^2/a^2 + y^2/b^2 + z^2/c^2 = 1 to the vertices */
    s = load(ctx, "ellipsoid.off");
    as_mesh_surface_info(s, &mi);
    double *A = test_malloc(mi.nv * 3 * sizeof(double)), *b = test_malloc(mi.nv * sizeof(double));
    double *w = test_malloc(as_lsq_work_size(mi.nv, 3) * sizeof(double)), x[3];
    for (size_t v = 0; v < mi.nv; v++) {
        for (int k = 0; k < 3; k++) A[3 * v + k] = mi.xyz[3 * v + k] * mi.xyz[3 * v + k];
        b[v] = 1;
    }
    assert_int_equal(as_lsq_solve(A, b, mi.nv, 3, x, w), 3);
    char expr[256];
    snprintf(expr, sizeof expr, "%.17g*x^2+%.17g*y^2+%.17g*z^2-1", x[0], x[1], x[2]);
    /* the bounding box says axes of about 0.2, 0.3, 0.5 */
    assert_true(fabs(1 / sqrt(x[0]) - 0.2) < 0.01 && fabs(1 / sqrt(x[1]) - 0.3) < 0.01 &&
                fabs(1 / sqrt(x[2]) - 0.5) < 0.01);
    assert_int_equal(as_implicit_from_expression(ctx, expr, c0, 1, &ex), ANISTAR_OK);
    double *errH = test_malloc(mi.nv * sizeof(double));
    for (size_t v = 0; v < mi.nv; v++) {
        double q[3];
        as_surface_frame fr;
        assert_int_equal(as_surface_project(ctx, ex, mi.xyz + 3 * v, q), ANISTAR_OK);
        assert_int_equal(as_surface_frame_at(ctx, ex, q, &fr), ANISTAR_OK);
        const double *J = mi.vjet + AS_MESH_VJET * v;
        double H = 0.5 * (J[3] + J[4]), He = 0.5 * (fr.k[0] + fr.k[1]);
        errH[v] = fabs(H / He - 1);
    }
    /* median relative error of the mean curvature (sorted by insertion) */
    for (size_t i = 1; i < mi.nv; i++)
        for (size_t j = i; j > 0 && errH[j] < errH[j - 1]; j--) {
            double t = errH[j];
            errH[j] = errH[j - 1];
            errH[j - 1] = t;
        }
    if (!(errH[mi.nv / 2] < 0.25)) fail_msg("ellipsoid.off: median error of H %g", errH[mi.nv / 2]);
    test_free(errH);
    test_free(A);
    test_free(b);
    test_free(w);
    as_surface_free(ex);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* Gauss-Bonnet on the smooth meshes: sum over vertices of K * (area / 3) ~ 2 pi chi. */
static void test_gauss_bonnet(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const char *files[] = {"sphere_r0.5.off", "knot1.off", "ellipsoid.off"};
    const double chi[] = {2, 0, 2};
    for (int f = 0; f < 3; f++) {
        as_surface *s = load(ctx, files[f]);
        as_mesh_info mi;
        as_mesh_surface_info(s, &mi);
        double *area = test_calloc(mi.nv, sizeof(double)), KA = 0, HA = 0;
        for (size_t t = 0; t < mi.nt; t++) {
            const int32_t *c = mi.tri + 3 * t;
            double u[3], v[3], n[3];
            for (int k = 0; k < 3; k++) {
                u[k] = mi.xyz[3 * c[1] + k] - mi.xyz[3 * c[0] + k];
                v[k] = mi.xyz[3 * c[2] + k] - mi.xyz[3 * c[0] + k];
            }
            cross3(u, v, n);
            for (int k = 0; k < 3; k++) area[c[k]] += norm3(n) / 6;
        }
        for (size_t v = 0; v < mi.nv; v++) {
            const double *J = mi.vjet + AS_MESH_VJET * v;
            KA += J[3] * J[4] * area[v];
            HA += 0.5 * (J[3] + J[4]) * area[v];
        }
        double want = 2 * 3.14159265358979 * chi[f];
        if (!(fabs(KA - want) < 0.25 * 4 * 3.14159265358979))
            fail_msg("%s: sum K dA = %g, want %g", files[f], KA, want);
        assert_true(HA > 0); /* outward convention: closed smooth surfaces bulge out */
        test_free(area);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* ---- metric fields --------------------------------------------------------------------------- */

static as_field *field(anistar_context *ctx, const as_surface *s, const char *spec) {
    as_field *f = NULL;
    anistar_status st = as_field_from_spec(ctx, s, spec, &f);
    if (st) fail_msg("'%s': %s", spec, anistar_last_error(ctx));
    return f;
}

static double tensor_diff(const double a[6], const double b[6]) {
    double e = 0;
    for (int i = 0; i < 6; i++) e = fmax(e, fabs(a[i] - b[i]));
    return e;
}

static void test_curvature_metric(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tu_rng r = {29};
    /* sphere: every eigenvalue of F ~ 2 (tangential ~ |k|, normal e_n = max e1) */
    as_surface *s = load(ctx, "sphere_r0.5.off");
    const char *specs[] = {"curvature", "curvature,degree=4", "curvature,degree=3,k=20,rb=0.2"};
    for (int sp = 0; sp < 3; sp++) {
        as_field *f = field(ctx, s, specs[sp]);
        assert_non_null(f->blend);
        /* degree 3 is no better than 2 (the sphere's rho^4 term is even) */
        double tol = sp == 0 ? 0.06 : (sp == 1 ? 0.03 : 0.08);
        for (int i = 0; i < 200; i++) {
            double u[3], p[3], m[6], w[3], v[9];
            rand_unit(&r, u);
            for (int k = 0; k < 3; k++) p[k] = 0.5 * u[k];
            assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
            assert_int_equal(as_sym3_eigen(m, w, v), 0);
            for (int k = 0; k < 3; k++)
                if (!(fabs(sqrt(w[k]) / 2 - 1) < tol))
                    fail_msg("'%s': eigenvalue of F %g, want 2", specs[sp], sqrt(w[k]));
        }
        as_field_free(f);
    }
    /* options that do not fit */
    as_field *f = (as_field *)1;
    assert_int_equal(as_field_from_spec(ctx, s, "curvature,degree=4,k=10", &f), ANISTAR_EINVAL);
    assert_null(f);
    assert_non_null(strstr(anistar_last_error(ctx), "too small"));
    assert_int_equal(as_field_from_spec(ctx, s, "curvature,degree=5", &f), ANISTAR_EINVAL);
    assert_int_equal(as_field_from_spec(ctx, s, "curvature,k=2.5", &f), ANISTAR_EINVAL);
    assert_int_equal(as_field_from_spec(ctx, s, "curvature,rb=-1", &f), ANISTAR_EINVAL);
    as_surface_free(s);
    /* degree, k, rb are for meshes only */
    as_surface *im;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &im), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, im, "curvature,degree=4", &f), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "triangle-mesh surfaces only"));
    as_surface_free(im);

    /* knot1: SPD everywhere (on, near and off the surface), continuous, e_n */
    s = load(ctx, "knot1.off");
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    f = field(ctx, s, "curvature");
    double en = 0, eps = 1 / s->radius;
    for (size_t v = 0; v < mi.nv; v++) {
        const double *J = mi.vjet + AS_MESH_VJET * v;
        en = fmax(en, fmax(fmax(eps, fabs(J[3])), fmax(eps, fabs(J[4]))));
    }
    assert_true(f->en == en);
    double rb = as_blend_radius(f->blend), mmax = 0;
    assert_true(rb > 0.5 * mi.spacing && rb < 4 * mi.spacing);
    for (int i = 0; i < 300; i++) {
        double p[3], q[3], m[6], m2[6], w[3], v[9];
        for (int k = 0; k < 3; k++) p[k] = s->center[k] + tu_rng_range(&r, -1, 1) * s->radius;
        if (i % 2) { /* on the surface */
            assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
            memcpy(p, q, sizeof q);
        }
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
        assert_int_equal(as_sym3_eigen(m, w, v), 0);
        assert_true(w[0] > 0 && w[2] <= en * en * (1 + 1e-12));
        for (int k = 0; k < 6; k++) mmax = fmax(mmax, fabs(m[k]));
        /* continuity: a step of 1e-6 r_B changes the tensor by at most ~ 1e-6 * 14 * max */
        double d[3];
        rand_unit(&r, d);
        for (int k = 0; k < 3; k++) q[k] = p[k] + 1e-6 * rb * d[k];
        assert_int_equal(as_field_eval(ctx, f, q, m2), ANISTAR_OK);
        assert_true(tensor_diff(m, m2) <= 1e-6 * 30 * en * en);
    }
    assert_true(mmax > 0);
    as_field_free(f);
    /* other fields work on meshes through the frame and the sample */
    const char *others[] = {"euclidean", "shock", "hessian:x^2-y^2", "gradient:x*y*z"};
    for (int i = 0; i < 4; i++) {
        f = field(ctx, s, others[i]);
        double m[6], w[3], v[9];
        assert_int_equal(as_field_eval(ctx, f, mi.xyz + 30, m), ANISTAR_OK);
        assert_int_equal(as_sym3_eigen(m, w, v), 0);
        assert_true(w[0] > 0);
        as_field_free(f);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* A temporary directory under /tmp. */
typedef struct tmpdir {
    char path[64];
} tmpdir;

static void tmp_make(tmpdir *d) {
    snprintf(d->path, sizeof d->path, "/tmp/anistar_mesh_surface_XXXXXX");
    assert_non_null(mkdtemp(d->path));
}

static void write_sol(const char *path, const double *t, size_t n) {
    FILE *fp = fopen(path, "w");
    assert_non_null(fp);
    fprintf(fp, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n%zu\n1 3\n", n);
    for (size_t i = 0; i < n; i++) { /* Medit order m11 m12 m22 m13 m23 m33 */
        const double *m = t + 6 * i;
        fprintf(fp, "%.17g %.17g %.17g %.17g %.17g %.17g\n", m[0], m[1], m[3], m[2], m[4], m[5]);
    }
    fprintf(fp, "End\n");
    fclose(fp);
}

static void test_sol(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tmpdir d;
    tmp_make(&d);
    char path[128], spec[160];
    snprintf(path, sizeof path, "%s/m.sol", d.path);
    tu_rng r = {31};
    as_surface *s = load(ctx, "sphere_r0.5.off");
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    double c[6] = {4, 1, -0.5, 3, 0.25, 2};
    double *t = test_malloc(6 * (mi.nv + 1) * sizeof(double));
    for (size_t v = 0; v <= mi.nv; v++) memcpy(t + 6 * v, c, sizeof c);
    /* a constant tensor everywhere */
    write_sol(path, t, mi.nv);
    snprintf(spec, sizeof spec, "sol:%s", path);
    as_field *f = field(ctx, s, spec);
    for (int i = 0; i < 100; i++) {
        double p[3], m[6];
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(&r, -1, 1);
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
        assert_true(tensor_diff(m, c) < 1e-13);
    }
    as_field_free(f);
    /* round trip through the library's .sol writer (Medit order on disk) */
    as_trimesh out;
    as_trimesh_init(&out);
    assert_int_equal(as_trimesh_set(ctx, &out, mi.nv, mi.xyz, mi.nt, mi.tri, t), ANISTAR_OK);
    char path2[128];
    snprintf(path2, sizeof path2, "%s/w.sol", d.path);
    assert_int_equal(as_mesh_write(ctx, path2, &out, NULL, 0), ANISTAR_OK);
    as_trimesh_free(ctx, &out);
    snprintf(spec, sizeof spec, "sol:%s", path2);
    f = field(ctx, s, spec);
    for (int i = 0; i < 20; i++) {
        double p[3], m[6];
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(&r, -1, 1);
        assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
        assert_true(tensor_diff(m, c) < 1e-13);
    }
    as_field_free(f);
    remove(path2);
    /* rb option; varying tensors stay within the convex hull of the vertex tensors */
    for (size_t v = 0; v < mi.nv; v++) {
        double s2 = 1 + (double)(v % 7);
        for (int k = 0; k < 6; k++) t[6 * v + k] = c[k] * s2;
    }
    write_sol(path, t, mi.nv);
    snprintf(spec, sizeof spec, "sol:%s,rb=0.1", path);
    f = field(ctx, s, spec);
    assert_true(as_blend_radius(f->blend) == 0.1);
    for (size_t v = 0; v < mi.nv; v++) {
        double m[6];
        assert_int_equal(as_field_eval(ctx, f, mi.xyz + 3 * v, m), ANISTAR_OK);
        double ratio = m[0] / c[0];
        assert_true(ratio >= 1 - 1e-12 && ratio <= 7 + 1e-12);
        for (int k = 0; k < 6; k++) assert_true(fabs(m[k] - ratio * c[k]) < 1e-12 * fabs(m[0]));
    }
    as_field_free(f);
    /* count mismatch */
    write_sol(path, t, mi.nv - 1);
    snprintf(spec, sizeof spec, "sol:%s", path);
    f = (as_field *)1;
    assert_int_equal(as_field_from_spec(ctx, s, spec, &f), ANISTAR_EFORMAT);
    assert_null(f);
    assert_non_null(strstr(anistar_last_error(ctx), "161 tensors for a mesh of 162 vertices"));
    /* a tensor that is not positive definite */
    t[6 * 5] = -1;
    write_sol(path, t, mi.nv);
    assert_int_equal(as_field_from_spec(ctx, s, spec, &f), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(ctx), "vertex 6"));
    /* a missing file */
    assert_int_equal(as_field_from_spec(ctx, s, "sol:/nonexistent/x.sol", &f), ANISTAR_EIO);
    as_surface_free(s);
    /* an input vertex of no triangle is dropped from the surface but counts in the .sol */
    char off[128];
    snprintf(off, sizeof off, "%s/extra.off", d.path);
    as_trimesh tm;
    as_trimesh_init(&tm);
    char src[512];
    data_path(src, sizeof src, "sphere_r0.5.off");
    assert_int_equal(as_mesh_read(ctx, src, &tm), ANISTAR_OK);
    size_t nv0 = tm.nv;
    assert_int_equal(as_trimesh_add_vertex(ctx, &tm, 5, 5, 5), ANISTAR_OK);
    assert_int_equal(as_mesh_write(ctx, off, &tm, NULL, 0), ANISTAR_OK);
    as_trimesh_free(ctx, &tm);
    assert_int_equal(as_mesh_surface_read(ctx, off, &s), ANISTAR_OK);
    as_mesh_surface_info(s, &mi);
    assert_int_equal(mi.nv, nv0);
    assert_int_equal(mi.nv_in, nv0 + 1);
    assert_true(s->radius < 1); /* the stray vertex does not count */
    for (size_t v = 0; v <= nv0; v++) memcpy(t + 6 * v, c, sizeof c);
    write_sol(path, t, nv0 + 1);
    f = field(ctx, s, spec);
    double m[6], p[3] = {0.5, 0, 0};
    assert_int_equal(as_field_eval(ctx, f, p, m), ANISTAR_OK);
    assert_true(tensor_diff(m, c) < 1e-13);
    as_field_free(f);
    write_sol(path, t, nv0);
    assert_int_equal(as_field_from_spec(ctx, s, spec, &f), ANISTAR_EFORMAT);
    as_surface_free(s);
    remove(path);
    remove(off);
    rmdir(d.path);
    test_free(t);
    anistar_context_free(ctx);
}

/* ---- bad input, orientation, nesting ---------------------------------------------------------- */

static void read_arrays(anistar_context *ctx, const char *name, as_trimesh *tm) {
    char path[512];
    data_path(path, sizeof path, name);
    as_trimesh_init(tm);
    assert_int_equal(as_mesh_read(ctx, path, tm), ANISTAR_OK);
}

static void expect_error(anistar_context *ctx, const as_trimesh *tm, anistar_status want,
                         const char *msg) {
    as_surface *s = (as_surface *)1;
    anistar_status st = as_mesh_surface_create(ctx, "bad.off", tm->xyz, tm->nv, tm->tri, tm->nt, &s);
    if (st != want || !strstr(anistar_last_error(ctx), msg))
        fail_msg("status %d '%s', want %d '%s'", st, anistar_last_error(ctx), want, msg);
    assert_null(s);
}

static void test_bad_meshes(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh tm;
    read_arrays(ctx, "sphere_r0.5.off", &tm);
    /* open: one face removed */
    tm.nt--;
    expect_error(ctx, &tm, ANISTAR_EFORMAT, "bad.off: not a closed 2-manifold: 3 border edges");
    tm.nt++;
    /* non-manifold: a fin on an existing edge (3 triangles there, 2 new border edges) */
    int32_t a = tm.tri[0], b = tm.tri[1];
    assert_int_equal(as_trimesh_add_vertex(ctx, &tm, 2, 2, 2), ANISTAR_OK);
    assert_int_equal(as_trimesh_add_triangle(ctx, &tm, a, b, (int32_t)tm.nv - 1), ANISTAR_OK);
    expect_error(ctx, &tm, ANISTAR_EFORMAT, "2 border edges, 1 non-manifold edge");
    tm.nt--;
    tm.nv--;
    /* a zero-area triangle: a degenerate copy of a vertex position */
    double *p0 = tm.xyz + 3 * (size_t)tm.tri[0];
    double *p1 = tm.xyz + 3 * (size_t)tm.tri[1];
    double *p2 = tm.xyz + 3 * (size_t)tm.tri[2];
    double keep[3];
    memcpy(keep, p2, sizeof keep);
    for (int k = 0; k < 3; k++) p2[k] = 0.5 * (p0[k] + p1[k]);
    if (as_io_collinear3(p0, p1, p2)) expect_error(ctx, &tm, ANISTAR_EFORMAT, "zero-area triangle");
    memcpy(p2, keep, sizeof keep);
    /* bad index, bad coordinates */
    int32_t save = tm.tri[4];
    tm.tri[4] = (int32_t)tm.nv;
    expect_error(ctx, &tm, ANISTAR_EINVAL, "out of range");
    tm.tri[4] = -1;
    expect_error(ctx, &tm, ANISTAR_EINVAL, "out of range");
    tm.tri[4] = save;
    double x = tm.xyz[7];
    tm.xyz[7] = NAN;
    expect_error(ctx, &tm, ANISTAR_EINVAL, "vertex 2");
    tm.xyz[7] = 1e-200;
    expect_error(ctx, &tm, ANISTAR_EINVAL, "vertex 2");
    tm.xyz[7] = x;
    as_surface *s = (as_surface *)1;
    assert_int_equal(as_mesh_surface_create(ctx, "x", tm.xyz, 2, tm.tri, 0, &s), ANISTAR_EINVAL);
    assert_null(s);
    /* flipped faces are reoriented; so is an inside-out mesh */
    for (int mode = 0; mode < 2; mode++) {
        for (size_t t = 0; t < tm.nt; t++)
            if (mode == 1 || t % 3 == 0) {
                int32_t y = tm.tri[3 * t + 1];
                tm.tri[3 * t + 1] = tm.tri[3 * t + 2];
                tm.tri[3 * t + 2] = y;
            }
        assert_int_equal(as_mesh_surface_create(ctx, "flipped", tm.xyz, tm.nv, tm.tri, tm.nt, &s),
                         ANISTAR_OK);
        as_mesh_info mi;
        as_mesh_surface_info(s, &mi);
        for (size_t t = 0; t < mi.nt; t++) {
            const int32_t *c = mi.tri + 3 * t;
            double u[3], v[3], n[3];
            for (int k = 0; k < 3; k++) {
                u[k] = mi.xyz[3 * c[1] + k] - mi.xyz[3 * c[0] + k];
                v[k] = mi.xyz[3 * c[2] + k] - mi.xyz[3 * c[0] + k];
            }
            cross3(u, v, n);
            assert_true(dot3(n, mi.xyz + 3 * (size_t)c[0]) > 0);
        }
        for (size_t v = 0; v < mi.nv; v++)
            assert_true(mi.vjet[AS_MESH_VJET * v + 3] > 0 && dot3(mi.vjet + AS_MESH_VJET * v, mi.xyz + 3 * v) > 0);
        as_surface_free(s);
    }
    as_trimesh_free(ctx, &tm);
    /* files */
    assert_int_equal(as_mesh_surface_read(ctx, "/nonexistent/x.off", &s), ANISTAR_EIO);
    assert_null(s);
    assert_int_equal(as_mesh_surface_read(ctx, "x.xyz", &s), ANISTAR_EFORMAT);
    anistar_context_free(ctx);
}

/* Two concentric spheres: the region between them is inside; the inner one is the wall
 * of a cavity and faces inward. */
static void test_nested(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    tmesh m = icosphere(2);
    size_t n = m.nv, t = m.nt;
    double *xyz = test_malloc(6 * n * sizeof(double));
    int32_t *tri = test_malloc(6 * t * sizeof(int32_t));
    for (size_t i = 0; i < 3 * n; i++) {
        xyz[i] = m.xyz[i];
        xyz[3 * n + i] = 0.5 * m.xyz[i];
    }
    for (size_t i = 0; i < 3 * t; i++) {
        tri[i] = m.tri[i];
        tri[3 * t + i] = m.tri[i] + (int32_t)n; /* as given: outward like the outer one */
    }
    as_surface *s;
    assert_int_equal(as_mesh_surface_create(ctx, "shell", xyz, 2 * n, tri, 2 * t, &s), ANISTAR_OK);
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    assert_int_equal(mi.ncomponents, 2);
    int side;
    double pin[3] = {0.75, 0, 0}, pcav[3] = {0.1, 0.1, 0}, pout[3] = {1.2, 0, 0};
    assert_int_equal(as_surface_side(ctx, s, pin, &side), ANISTAR_OK);
    assert_int_equal(side, -1);
    assert_int_equal(as_surface_side(ctx, s, pcav, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    assert_int_equal(as_surface_side(ctx, s, pout, &side), ANISTAR_OK);
    assert_int_equal(side, 1);
    for (size_t v = 0; v < mi.nv; v++) {
        const double *J = mi.vjet + AS_MESH_VJET * v, *p = mi.xyz + 3 * v;
        int inner = norm3(p) < 0.75;
        /* outward of the solid: away from the center outside, toward it on the cavity */
        assert_true(inner ? dot3(J, p) < 0 : dot3(J, p) > 0);
        assert_true(inner ? J[3] < 0 : J[4] > 0);
    }
    as_point_sample smp;
    assert_int_equal(as_surface_sample(ctx, s, 40, &smp), ANISTAR_OK);
    assert_int_equal(smp.ncomponents, 2);
    int seen[2] = {0, 0};
    for (size_t i = 0; i < smp.n; i++) {
        int inner = norm3(smp.points + 3 * i) < 0.75;
        assert_int_equal(smp.component[i], inner ? 1 : 0);
        seen[inner]++;
    }
    assert_true(seen[0] >= 10 && seen[1] >= 10); /* shares proportional to the sizes */
    /* areas per component: the outer sphere's triangles, the inner one's (1/4 of it) */
    double outer = mesh_area(m.xyz, m.tri, m.nt);
    assert_true(fabs(smp.area[0] - outer) <= 1e-12 * outer);
    assert_true(fabs(smp.area[1] - 0.25 * outer) <= 1e-12 * outer);
    as_surface_sample_free(ctx, &smp);
    as_surface_free(s);
    test_free(xyz);
    test_free(tri);
    tmesh_free(&m);
    anistar_context_free(ctx);
}

/* ---- public API ------------------------------------------------------------------------------ */

static void test_public_api(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    for (size_t f = 0; f < NFILES; f++) {
        char path[512];
        data_path(path, sizeof path, mesh_files[f]);
        anistar_surface *s = NULL;
        assert_int_equal(anistar_surface_read(ctx, path, &s), ANISTAR_OK);
        double c[3], r;
        assert_int_equal(anistar_surface_bound(s, c, &r), ANISTAR_OK);
        assert_true(r > 0);
        anistar_surface_free(s);
    }
    anistar_surface *s = (anistar_surface *)1;
    assert_int_equal(anistar_surface_read(ctx, "/nonexistent/x.stl", &s), ANISTAR_EIO);
    assert_null(s);
    assert_int_equal(anistar_surface_read(ctx, "head.MHD", &s), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "use anistar_surface_from_image_file"));
    assert_int_equal(anistar_surface_read(ctx, NULL, &s), ANISTAR_EINVAL);
    /* from arrays; eval is the signed distance */
    tmesh m = icosphere(3);
    assert_int_equal(anistar_surface_from_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &s),
                     ANISTAR_OK);
    tu_rng r = {41};
    for (int i = 0; i < 100; i++) {
        double p[3], f, g[3], h[6];
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(&r, -1.5, 1.5);
        assert_int_equal(anistar_surface_eval(s, p, &f, g, NULL), ANISTAR_OK);
        assert_true(fabs(f - (norm3(p) - 1)) < 0.02); /* level 3: within 1.3% of the sphere */
        assert_true(fabs(norm3(g) - 1) < 1e-12 && dot3(g, p) > 0);
        assert_int_equal(anistar_surface_eval(s, p, &f, g, h), ANISTAR_EINVAL);
        double k[2], d1[3], d2[3], n[3];
        assert_int_equal(anistar_surface_curvature(s, p, k, d1, d2), ANISTAR_OK);
        assert_true(fabs(k[0] - 1) < 0.05 && fabs(k[1] - 1) < 0.05);
        assert_int_equal(anistar_surface_normal(s, p, n), ANISTAR_OK);
        assert_true(dot3(n, p) / norm3(p) > 0.99);
    }
    anistar_metric *mt = NULL;
    assert_int_equal(anistar_metric_from_spec(ctx, s, "curvature,degree=4", &mt), ANISTAR_OK);
    double t6[6], p[3] = {0, 0, 1};
    assert_int_equal(anistar_metric_eval(mt, p, t6), ANISTAR_OK);
    assert_true(fabs(t6[0] - 1) < 0.05 && fabs(t6[5] - 1) < 0.05);
    anistar_metric_free(mt);
    anistar_surface_free(s);
    int32_t bad[3] = {0, 1, 99999};
    assert_int_equal(anistar_surface_from_triangles(ctx, m.xyz, m.nv, bad, 1, &s), ANISTAR_EINVAL);
    assert_int_equal(anistar_surface_from_triangles(ctx, NULL, m.nv, m.tri, m.nt, &s),
                     ANISTAR_EINVAL);
    tmesh_free(&m);
    anistar_context_free(ctx);
}

/* ---- allocation failures ---------------------------------------------------------------------- */

static void test_alloc_failures(void **state) {
    (void)state;
    tmesh m = icosphere(1);
    /* shift a vertex off the list: an unused vertex exercises the compaction path */
    double *xyz = test_malloc(3 * (m.nv + 1) * sizeof(double));
    memcpy(xyz, m.xyz, 3 * m.nv * sizeof(double));
    xyz[3 * m.nv] = xyz[3 * m.nv + 1] = xyz[3 * m.nv + 2] = 0.25;
    tu_alloc ta;
    int done = 0;
    long k;
    for (k = 0; !done; k++) {
        tu_alloc_init(&ta, k);
        anistar_allocator al = tu_allocator(&ta);
        anistar_context *ctx = anistar_context_new(&al);
        if (!ctx) continue;
        as_surface *s = NULL;
        anistar_status st = as_mesh_surface_create(ctx, "ico", xyz, m.nv + 1, m.tri, m.nt, &s);
        as_field *f = NULL;
        if (!st) {
            st = as_field_from_spec(ctx, s, "curvature,degree=4,k=20", &f);
            if (st) assert_null(f);
        }
        as_point_sample smp;
        if (!st) st = as_surface_sample(ctx, s, 10, &smp);
        if (!st) {
            as_surface_sample_free(ctx, &smp);
            double a[3] = {0, 0, 0}, b[3] = {2, 0.1, 0.2}, x[3];
            int found;
            st = as_surface_crossing(ctx, s, a, b, a, &found, x);
            if (!st) assert_true(found);
        }
        if (st) {
            assert_int_equal(st, ANISTAR_ENOMEM);
        } else {
            done = 1;
        }
        as_field_free(f);
        as_surface_free(s);
        anistar_context_free(ctx);
        assert_int_equal(ta.live_blocks, 0);
        assert_int_equal(ta.live_bytes, 0);
    }
    assert_true(k > 10);
    test_free(xyz);
    tmesh_free(&m);
}


/* ---- the command line: anistar probe on files --------------------------------------------------- */

/* Run "anistar ARGS" (stderr discarded); the exit status, stdout into out. */
static int run_tool(const char *args, char *out, size_t cap) {
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s/anistar %s 2>/dev/null", AS_TEST_BUILD_DIR, args);
    FILE *p = popen(cmd, "r");
    assert_non_null(p);
    size_t n = fread(out, 1, cap - 1, p);
    out[n] = '\0';
    int st = pclose(p);
    assert_true(WIFEXITED(st));
    return WEXITSTATUS(st);
}

/* The first number after "key": in a JSON text. */
static double json_number(const char *json, const char *key) {
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\": ", key);
    const char *p = strstr(json, pat);
    assert_non_null(p);
    p += strlen(pat);
    if (*p == '[') p++;
    return strtod(p, NULL);
}

static void test_probe_files(void **state) {
    (void)state;
    char *out = test_malloc(8192);
    char args[512];
    /* a mesh: f is the signed distance; the projection is at distance 0.1 */
    snprintf(args, sizeof args, "probe %s/sphere_r0.5.off --at 0.6,0,0", AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    assert_true(fabs(json_number(out, "f") - 0.1) < 1e-12);
    assert_true(fabs(json_number(out, "distance") - 0.1) < 1e-12);
    assert_true(fabs(json_number(out, "curvatures") - 2) < 0.1);
    assert_true(fabs(json_number(out, "tensor") - 4) < 0.5);
    snprintf(args, sizeof args, "probe %s/knot1.off --metric curvature,degree=4,k=30 --at 0,0,0",
             AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    snprintf(args, sizeof args, "probe %s/hinge.stl --metric curvature,rb=3 --at 0,0,0",
             AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    /* images: f and its gradient at the point; inside flips the sign */
    snprintf(args, sizeof args, "probe %s/skull_2.9.inr --iso 2.9 --at 120,120,110",
             AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    double f1 = json_number(out, "f");
    snprintf(args, sizeof args,
             "probe %s/skull_2.9.inr --iso 2.9 --inside less --metric euclidean --at 120,120,110",
             AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    assert_true(fabs(json_number(out, "f") + f1) < 1e-9 * fabs(f1)); /* other background */
    snprintf(args, sizeof args, "probe %s/brain_t1.nhdr --iso 40 --at 127,127,91",
             AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    /* an image without --iso: Otsu's threshold (anistar_image_file_otsu), the same f as
     * with that isovalue given */
    double otsu;
    {
        anistar_context *cx = anistar_context_new(NULL);
        char ip[512];
        snprintf(ip, sizeof ip, "%s/brain_t1.mhd", AS_TEST_DATA_DIR);
        assert_int_equal(anistar_image_file_otsu(cx, ip, &otsu), ANISTAR_OK);
        anistar_context_free(cx);
    }
    snprintf(args, sizeof args, "probe %s/brain_t1.mhd --at 127,127,91", AS_TEST_DATA_DIR);
    assert_int_equal(run_tool(args, out, 8192), 0);
    double f_auto = json_number(out, "f");
    snprintf(args, sizeof args, "probe %s/brain_t1.mhd --iso %.17g --at 127,127,91",
             AS_TEST_DATA_DIR, otsu);
    assert_int_equal(run_tool(args, out, 8192), 0);
    assert_true(json_number(out, "f") == f_auto);
    /* usage errors (status 2): --iso or --inside with a mesh, an unknown extension, a bad
     * --inside */
    const char *usage[] = {"probe %s/knot1.off --iso 3 --at 1,1,1",
                           "probe %s/knot1.off --inside less --at 1,1,1",
                           "probe %s/README.md --at 1,1,1",
                           "probe %s/skull_2.9.inr --iso 2.9 --inside more --at 1,1,1",
                           "probe %s/skull_2.9.inr --iso 2.9 --inside less --inside less --at 1,1,1"};
    for (size_t i = 0; i < sizeof usage / sizeof usage[0]; i++) {
        snprintf(args, sizeof args, usage[i], AS_TEST_DATA_DIR);
        if (run_tool(args, out, 8192) != 2) fail_msg("'%s': not a usage error", args);
        assert_string_equal(out, "");
    }
    /* errors (status 1): missing files, no surface at iso, sol on a mesh with the wrong count */
    const char *errs[] = {"probe /nonexistent/x.off --at 1,1,1",
                          "probe /nonexistent/x.nrrd --iso 1 --at 1,1,1",
                          "probe %s/skull_2.9.inr --iso 9 --at 1,1,1",
                          "probe %s/sphere_r0.5.off --metric sol:/nonexistent.sol --at 1,1,1"};
    for (size_t i = 0; i < sizeof errs / sizeof errs[0]; i++) {
        snprintf(args, sizeof args, errs[i], AS_TEST_DATA_DIR);
        if (run_tool(args, out, 8192) != 1) fail_msg("'%s': not an error", args);
        assert_string_equal(out, "");
    }
    test_free(out);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_load_all),          cmocka_unit_test(test_sphere_distances),
        cmocka_unit_test(test_projection_side_crossing),
        cmocka_unit_test(test_curvature_spheres), cmocka_unit_test(test_curvature_ellipsoids),
        cmocka_unit_test(test_gauss_bonnet),      cmocka_unit_test(test_curvature_metric),
        cmocka_unit_test(test_sol),               cmocka_unit_test(test_bad_meshes),
        cmocka_unit_test(test_nested),            cmocka_unit_test(test_public_api),
        cmocka_unit_test(test_alloc_failures),    cmocka_unit_test(test_probe_files),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
