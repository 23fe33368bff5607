/*
 * test_topology.c — topology validation on arrays (lib/io/topology.c): the test data,
 * borders, non-manifold edges and vertices, orientation repair, non-orientable surfaces,
 * components and genus, exact degeneracy tests against a GMP oracle, allocation failures.
 */
#include "test_util.h"

#include "core.h"
#include "io/meshio.h"

#include <gmp.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define DATA(f) AS_TEST_DATA_DIR "/" f

typedef struct tctx {
    tu_alloc a;
    anistar_allocator al;
    anistar_context *ctx;
} tctx;

static void tctx_init(tctx *t) {
    tu_alloc_init(&t->a, -1);
    t->al = tu_allocator(&t->a);
    t->ctx = anistar_context_new(&t->al);
    assert_non_null(t->ctx);
}

static void tctx_done(tctx *t) {
    anistar_context_free(t->ctx);
    assert_int_equal(t->a.live_blocks, 0);
}

/* A mesh in plain malloc'd arrays (grown as needed). */
typedef struct mesh {
    double *xyz;
    int32_t *tri;
    size_t nv, nt;
} mesh;

static int32_t add_v(mesh *m, double x, double y, double z) {
    m->xyz = realloc(m->xyz, (m->nv + 1) * 3 * sizeof(double));
    assert_non_null(m->xyz);
    m->xyz[3 * m->nv] = x;
    m->xyz[3 * m->nv + 1] = y;
    m->xyz[3 * m->nv + 2] = z;
    return (int32_t)m->nv++;
}

static void add_t(mesh *m, int32_t a, int32_t b, int32_t c) {
    m->tri = realloc(m->tri, (m->nt + 1) * 3 * sizeof(int32_t));
    assert_non_null(m->tri);
    m->tri[3 * m->nt] = a;
    m->tri[3 * m->nt + 1] = b;
    m->tri[3 * m->nt + 2] = c;
    m->nt++;
}

static void mesh_free(mesh *m) {
    free(m->xyz);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

static as_topology check(const mesh *m) {
    tctx t;
    tctx_init(&t);
    as_topology r;
    anistar_status st = as_topology_check(t.ctx, m->nv, m->xyz, m->nt, m->tri, &r);
    if (st) fail_msg("%s", anistar_last_error(t.ctx));
    tctx_done(&t);
    return r;
}

static as_topology orient(mesh *m) {
    tctx t;
    tctx_init(&t);
    as_topology r;
    anistar_status st = as_topology_orient(t.ctx, m->nv, m->xyz, m->nt, m->tri, &r);
    if (st) fail_msg("%s", anistar_last_error(t.ctx));
    tctx_done(&t);
    return r;
}

/* The message as_topology_require gives for r. */
static void require_msg(const as_topology *r, char *out, size_t n) {
    tctx t;
    tctx_init(&t);
    anistar_status st = as_topology_require(t.ctx, "x.off", r);
    snprintf(out, n, "%s", st ? anistar_last_error(t.ctx) : "");
    if (st) assert_int_equal(st, ANISTAR_EFORMAT);
    tctx_done(&t);
}

static mesh load(const char *path) {
    tctx t;
    tctx_init(&t);
    as_trimesh tm;
    as_trimesh_init(&tm);
    if (as_mesh_read(t.ctx, path, &tm)) fail_msg("%s", anistar_last_error(t.ctx));
    mesh m = {0};
    m.nv = tm.nv;
    m.nt = tm.nt;
    m.xyz = malloc(m.nv * 3 * sizeof(double));
    m.tri = malloc(m.nt * 3 * sizeof(int32_t));
    memcpy(m.xyz, tm.xyz, m.nv * 3 * sizeof(double));
    memcpy(m.tri, tm.tri, m.nt * 3 * sizeof(int32_t));
    as_trimesh_free(t.ctx, &tm);
    tctx_done(&t);
    return m;
}

/* The unit cube [0,1]^3 shifted by o, 12 outward triangles; vertex i of the cube is
 * (i & 1, i >> 1 & 1, i >> 2 & 1) and becomes map[i] if map[i] >= 0. */
static void add_cube(mesh *m, const double o[3], const int32_t *map) {
    int32_t v[8];
    for (int i = 0; i < 8; i++)
        v[i] = (map && map[i] >= 0) ? map[i]
                                    : add_v(m, o[0] + (i & 1), o[1] + (i >> 1 & 1), o[2] + (i >> 2 & 1));
    static const int f[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                 {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
    for (int i = 0; i < 12; i++) add_t(m, v[f[i][0]], v[f[i][1]], v[f[i][2]]);
}

/* ==================================================================================== */

static const struct {
    const char *path;
    size_t nv, nt;
    long long chi, genus;
} data[] = {{DATA("bunny00.off"), 37706, 75408, 2, 0}, {DATA("elephant.off"), 2775, 5558, -4, 3},
            {DATA("fandisk.off"), 6475, 12946, 2, 0},  {DATA("knot1.off"), 3200, 6400, 0, 1},
            {DATA("sphere_r0.5.off"), 162, 320, 2, 0}, {DATA("ellipsoid.off"), 132, 260, 2, 0},
            {DATA("hinge.stl"), 598, 1212, -8, 5},     {DATA("lever.stl"), 377, 774, -10, 6}};

static void test_data_files(void **state) {
    (void)state;
    for (size_t i = 0; i < sizeof data / sizeof data[0]; i++) {
        mesh m = load(data[i].path);
        assert_int_equal(m.nv, data[i].nv);
        assert_int_equal(m.nt, data[i].nt);
        int32_t *orig = malloc(m.nt * 3 * sizeof(int32_t));
        memcpy(orig, m.tri, m.nt * 3 * sizeof(int32_t));
        as_topology r = orient(&m);
        assert_int_equal(r.used_vertices, m.nv);
        assert_int_equal(r.edges, 3 * m.nt / 2);
        assert_int_equal(r.border_edges, 0);
        assert_int_equal(r.nonmanifold_edges, 0);
        assert_int_equal(r.nonmanifold_vertices, 0);
        assert_int_equal(r.repeated_index, 0);
        assert_int_equal(r.zero_area, 0);
        assert_int_equal(r.components, 1);
        assert_int_equal(r.patches, 1);
        assert_int_equal(r.nonorientable, 0);
        assert_int_equal(r.misoriented_edges, 0);
        assert_int_equal(r.inward_patches, 0);
        assert_int_equal(r.flipped, 0);
        assert_int_equal(r.euler, data[i].chi);
        assert_int_equal(r.genus, data[i].genus);
        assert_true(r.closed_manifold && r.oriented && r.volume > 0);
        assert_true(as_topology_ok(&r));
        assert_memory_equal(orig, m.tri, m.nt * 3 * sizeof(int32_t)); /* untouched */
        free(orig);
        mesh_free(&m);
    }
}

static void test_cube_and_open_cube(void **state) {
    (void)state;
    mesh m = {0};
    double o[3] = {0, 0, 0};
    add_cube(&m, o, NULL);
    as_topology r = check(&m);
    assert_true(r.closed_manifold && r.oriented);
    assert_int_equal(r.euler, 2);
    assert_int_equal(r.genus, 0);
    assert_true(fabs(r.volume - 1.0) < 1e-15);
    /* Remove the face x = 1 (its two triangles): a disk with a 4-edge border. */
    m.nt -= 2;
    r = check(&m);
    assert_int_equal(r.border_edges, 4);
    assert_int_equal(r.edges, 17);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.nonmanifold_vertices, 0);
    assert_int_equal(r.euler, 1);
    assert_int_equal(r.genus, -1);
    assert_int_equal(r.components, 1);
    assert_false(r.closed_manifold);
    assert_false(as_topology_ok(&r));
    char msg[512];
    require_msg(&r, msg, sizeof msg);
    assert_string_equal(msg, "x.off: not a closed 2-manifold: 4 border edges");
    mesh_free(&m);
}

static void test_nonmanifold(void **state) {
    (void)state;
    /* Two cubes sharing the edge (1,1,0)-(1,1,1): cube vertices 3 and 7 of the first are
     * vertices 0 and 4 of the second. */
    mesh m = {0};
    double o[3] = {0, 0, 0}, o2[3] = {1, 1, 0}, o3[3] = {1, 1, 1};
    add_cube(&m, o, NULL);
    int32_t map[8] = {3, -1, -1, -1, 7, -1, -1, -1};
    add_cube(&m, o2, map);
    assert_int_equal(m.nv, 14);
    as_topology r = check(&m);
    assert_int_equal(r.nonmanifold_edges, 1);
    assert_int_equal(r.nonmanifold_vertices, 2);
    assert_int_equal(r.border_edges, 0);
    assert_int_equal(r.components, 1);
    assert_int_equal(r.patches, 2);
    assert_false(r.closed_manifold);
    assert_int_equal(r.genus, -1);
    char msg[512];
    require_msg(&r, msg, sizeof msg);
    assert_string_equal(msg, "x.off: not a closed 2-manifold: 1 non-manifold edge, 2 "
                             "non-manifold vertices");
    mesh_free(&m);
    /* Two cubes sharing one vertex (1,1,1): a pinch. */
    add_cube(&m, o, NULL);
    int32_t map2[8] = {7, -1, -1, -1, -1, -1, -1, -1};
    add_cube(&m, o3, map2);
    r = check(&m);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.nonmanifold_vertices, 1);
    assert_int_equal(r.border_edges, 0);
    assert_int_equal(r.components, 1);
    assert_int_equal(r.patches, 2);
    assert_false(r.closed_manifold);
    mesh_free(&m);
    /* A triangle with a repeated vertex inside an otherwise closed cube. */
    add_cube(&m, o, NULL);
    add_t(&m, 0, 0, 5);
    r = check(&m);
    assert_int_equal(r.repeated_index, 1);
    assert_int_equal(r.euler, 2); /* ignored by E and F */
    assert_int_equal(r.border_edges, 0);
    assert_false(r.closed_manifold);
    require_msg(&r, msg, sizeof msg);
    assert_non_null(strstr(msg, "1 triangle with a repeated vertex"));
    mesh_free(&m);
}

/* Flip a random subset (or all) of the sphere's triangles: check reports it, orient
 * restores the original arrays exactly. */
static void test_reorient(void **state) {
    (void)state;
    tu_rng rng = {7};
    mesh m = load(DATA("sphere_r0.5.off"));
    int32_t *orig = malloc(m.nt * 3 * sizeof(int32_t));
    memcpy(orig, m.tri, m.nt * 3 * sizeof(int32_t));
    as_topology r0 = check(&m);
    for (int trial = 0; trial < 4; trial++) {
        size_t flips = 0;
        for (size_t t = 0; t < m.nt; t++) {
            int f = trial == 3 ? 1 : (tu_rng_u64(&rng) % 3 == 0);
            if (!f) continue;
            int32_t x = m.tri[3 * t + 1];
            m.tri[3 * t + 1] = m.tri[3 * t + 2];
            m.tri[3 * t + 2] = x;
            flips++;
        }
        as_topology r = check(&m);
        assert_true(r.closed_manifold);
        assert_false(r.oriented);
        assert_int_equal(r.flipped, flips);
        if (trial == 3) {
            assert_int_equal(r.misoriented_edges, 0);
            assert_int_equal(r.inward_patches, 1);
            assert_true(r.volume < 0);
        } else {
            assert_true(r.misoriented_edges > 0);
        }
        r = orient(&m);
        assert_int_equal(r.flipped, flips);
        assert_true(fabs(r.volume - r0.volume) <= 1e-14 * r0.volume);
        assert_memory_equal(orig, m.tri, m.nt * 3 * sizeof(int32_t));
        r = check(&m);
        assert_true(r.oriented && r.flipped == 0);
    }
    free(orig);
    mesh_free(&m);
}

/* Renumber vertices, shuffle triangles, rotate corners, flip some: the topology and the
 * (oriented) volume do not change. */
static void test_shuffled(void **state) {
    (void)state;
    tu_rng rng = {2024};
    static const char *files[] = {DATA("elephant.off"), DATA("knot1.off"), DATA("hinge.stl")};
    for (size_t f = 0; f < 3; f++) {
        mesh m = load(files[f]);
        as_topology r0 = check(&m);
        int32_t *perm = malloc(m.nv * sizeof(int32_t));
        for (size_t i = 0; i < m.nv; i++) perm[i] = (int32_t)i;
        for (size_t i = m.nv - 1; i > 0; i--) {
            size_t j = tu_rng_u64(&rng) % (i + 1);
            int32_t x = perm[i];
            perm[i] = perm[j];
            perm[j] = x;
        }
        double *xyz = malloc(m.nv * 3 * sizeof(double));
        for (size_t i = 0; i < m.nv; i++) memcpy(xyz + 3 * perm[i], m.xyz + 3 * i, 3 * sizeof(double));
        free(m.xyz);
        m.xyz = xyz;
        size_t flips = 0;
        for (size_t t = m.nt - 1; t > 0; t--) {
            size_t j = tu_rng_u64(&rng) % (t + 1);
            int32_t a[3], b[3];
            memcpy(a, m.tri + 3 * t, sizeof a);
            memcpy(b, m.tri + 3 * j, sizeof b);
            memcpy(m.tri + 3 * t, b, sizeof b);
            memcpy(m.tri + 3 * j, a, sizeof a);
        }
        for (size_t t = 0; t < m.nt; t++) {
            int32_t *c = m.tri + 3 * t, rot = (int32_t)(tu_rng_u64(&rng) % 3), v[3];
            for (int k = 0; k < 3; k++) v[k] = perm[c[(k + rot) % 3]];
            if (tu_rng_u64(&rng) % 4 == 0) {
                int32_t x = v[1];
                v[1] = v[2];
                v[2] = x;
                flips++;
            }
            memcpy(c, v, sizeof v);
        }
        as_topology r = orient(&m);
        assert_int_equal(r.flipped, flips);
        assert_int_equal(r.euler, r0.euler);
        assert_int_equal(r.genus, r0.genus);
        assert_true(fabs(r.volume - r0.volume) <= 1e-12 * r0.volume);
        r = check(&m);
        assert_true(r.oriented && r.closed_manifold);
        free(perm);
        mesh_free(&m);
    }
}

/* A grid of n x m quads (two triangles each) whose vertex (i, j) is id(i, j), with the
 * identifications done by id. */
typedef int32_t (*grid_id)(int i, int j, int n, int m);

static void grid(mesh *g, int n, int m, grid_id id) {
    for (int i = 0; i < n; i++)
        for (int j = 0; j < m; j++) {
            int32_t a = id(i, j, n, m), b = id(i + 1, j, n, m), c = id(i + 1, j + 1, n, m),
                    d = id(i, j + 1, n, m);
            add_t(g, a, b, c);
            add_t(g, a, c, d);
        }
}

static int32_t torus_id(int i, int j, int n, int m) { return (int32_t)((i % n) * m + j % m); }
static int32_t strip_id(int i, int j, int n, int m) { /* m == 1: rows j = 0, 1 */
    (void)m;
    if (i == n) return (int32_t)(2 * 0 + (1 - j)); /* the twist */
    return (int32_t)(2 * i + j);
}
static int32_t klein_id(int i, int j, int n, int m) {
    j %= m;
    if (i == n) return (int32_t)((m - j) % m); /* (n, j) ~ (0, -j) */
    return (int32_t)(i * m + j);
}

static void test_torus_moebius_klein(void **state) {
    (void)state;
    const double pi = 3.14159265358979323846;
    /* Torus R = 2, r = 0.7: genus 1, volume close to 2 pi^2 R r^2. */
    mesh m = {0};
    int n = 48, k = 24;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < k; j++) {
            double u = 2 * pi * i / n, v = 2 * pi * j / k;
            add_v(&m, (2 + 0.7 * cos(v)) * cos(u), (2 + 0.7 * cos(v)) * sin(u), 0.7 * sin(v));
        }
    grid(&m, n, k, torus_id);
    as_topology r = orient(&m);
    assert_true(r.closed_manifold);
    assert_int_equal(r.euler, 0);
    assert_int_equal(r.genus, 1);
    assert_int_equal(r.components, 1);
    double vol = 2 * pi * pi * 2 * 0.7 * 0.7;
    assert_true(r.volume > 0.97 * vol && r.volume < vol);
    r = check(&m);
    assert_true(r.oriented);
    mesh_free(&m);

    /* Moebius strip: one border loop of 2n edges, non-orientable, chi 0. */
    n = 12;
    for (int i = 0; i < n; i++)
        for (int s = 0; s < 2; s++) {
            double u = 2 * pi * i / n, w = s ? 0.3 : -0.3;
            add_v(&m, (1 + w * cos(u / 2)) * cos(u), (1 + w * cos(u / 2)) * sin(u), w * sin(u / 2));
        }
    grid(&m, n, 1, strip_id);
    r = check(&m);
    assert_int_equal(r.border_edges, 2 * n);
    assert_int_equal(r.nonorientable, 1);
    assert_int_equal(r.euler, 0);
    assert_int_equal(r.genus, -1);
    assert_false(r.oriented);
    char msg[512];
    require_msg(&r, msg, sizeof msg);
    assert_string_equal(msg, "x.off: not a closed 2-manifold: 24 border edges, 1 non-orientable "
                             "component");
    int32_t *before = malloc(m.nt * 3 * sizeof(int32_t));
    memcpy(before, m.tri, m.nt * 3 * sizeof(int32_t));
    r = orient(&m); /* leaves a non-orientable patch as it is */
    assert_memory_equal(before, m.tri, m.nt * 3 * sizeof(int32_t));
    free(before);
    mesh_free(&m);

    /* Klein bottle (combinatorial; coordinates of a flat grid, which do not matter here
     * except for the zero-area test, so they are made generic): closed, non-orientable. */
    n = 6;
    k = 6;
    tu_rng rng = {5};
    for (int i = 0; i < n * k; i++)
        add_v(&m, tu_rng_unit(&rng), tu_rng_unit(&rng), tu_rng_unit(&rng));
    grid(&m, n, k, klein_id);
    r = check(&m);
    assert_int_equal(r.border_edges, 0);
    assert_int_equal(r.nonmanifold_edges, 0);
    assert_int_equal(r.nonmanifold_vertices, 0);
    assert_true(r.closed_manifold);
    assert_int_equal(r.nonorientable, 1);
    assert_int_equal(r.euler, 0);
    assert_int_equal(r.genus, -1);
    assert_false(as_topology_ok(&r));
    require_msg(&r, msg, sizeof msg);
    assert_string_equal(msg, "x.off: not a valid closed surface: 1 non-orientable component");
    mesh_free(&m);
}

static void test_components(void **state) {
    (void)state;
    mesh s = load(DATA("sphere_r0.5.off"));
    as_topology r1 = check(&s);
    /* Two disjoint spheres, the second inverted and shifted: orient flips it. */
    mesh m = {0};
    for (int copy = 0; copy < 2; copy++) {
        int32_t base = (int32_t)m.nv;
        for (size_t i = 0; i < s.nv; i++)
            add_v(&m, s.xyz[3 * i] + 3 * copy, s.xyz[3 * i + 1], s.xyz[3 * i + 2]);
        for (size_t t = 0; t < s.nt; t++) {
            int32_t a = s.tri[3 * t] + base, b = s.tri[3 * t + 1] + base, c = s.tri[3 * t + 2] + base;
            if (copy)
                add_t(&m, a, c, b);
            else
                add_t(&m, a, b, c);
        }
    }
    as_topology r = check(&m);
    assert_int_equal(r.components, 2);
    assert_int_equal(r.patches, 2);
    assert_int_equal(r.euler, 4);
    assert_int_equal(r.genus, 0);
    assert_int_equal(r.inward_patches, 1);
    assert_int_equal(r.flipped, s.nt);
    assert_false(r.oriented);
    r = orient(&m);
    assert_true(fabs(r.volume - 2 * r1.volume) <= 1e-13 * r1.volume);
    r = check(&m);
    assert_true(r.oriented);
    assert_true(as_topology_ok(&r));
    mesh_free(&m);
    mesh_free(&s);
}

/* ---- exact degeneracy ---------------------------------------------------------------- */

static int gmp_orient2d(const double *a, const double *b, const double *c) {
    mpq_t x[6], l, r;
    const double v[6] = {a[0] - 0, a[1], b[0], b[1], c[0], c[1]};
    for (int i = 0; i < 6; i++) {
        mpq_init(x[i]);
        mpq_set_d(x[i], v[i]);
    }
    mpq_inits(l, r, NULL);
    mpq_sub(x[0], x[0], x[4]); /* ax - cx */
    mpq_sub(x[1], x[1], x[5]); /* ay - cy */
    mpq_sub(x[2], x[2], x[4]); /* bx - cx */
    mpq_sub(x[3], x[3], x[5]); /* by - cy */
    mpq_mul(l, x[0], x[3]);
    mpq_mul(r, x[1], x[2]);
    int s = mpq_cmp(l, r);
    for (int i = 0; i < 6; i++) mpq_clear(x[i]);
    mpq_clears(l, r, NULL);
    return (s > 0) - (s < 0);
}

static void test_exact_orient2d(void **state) {
    (void)state;
    tu_rng rng = {31};
    int zeros = 0, nonzero_hard = 0;
    for (int i = 0; i < 30000; i++) {
        double a[2], b[2], c[2];
        double scale = pow(2, (double)(tu_rng_u64(&rng) % 120) - 60);
        for (int k = 0; k < 2; k++) {
            a[k] = tu_rng_range(&rng, -1, 1) * scale;
            b[k] = tu_rng_range(&rng, -1, 1) * scale;
        }
        int kind = i % 4;
        double t = tu_rng_range(&rng, -2, 3);
        for (int k = 0; k < 2; k++) c[k] = a[k] + t * (b[k] - a[k]); /* nearly collinear */
        if (kind == 1) c[0] = nextafter(c[0], INFINITY);
        if (kind == 2) { /* exactly collinear: small integers on a line */
            long p = (long)(tu_rng_u64(&rng) % 1000) - 500, q = (long)(tu_rng_u64(&rng) % 1000) - 500;
            long s1 = (long)(tu_rng_u64(&rng) % 100) - 50, s2 = (long)(tu_rng_u64(&rng) % 100) - 50;
            a[0] = (double)p, a[1] = (double)q;
            b[0] = (double)(p + 3 * s1), b[1] = (double)(q + 5 * s1);
            c[0] = (double)(p + 3 * s2), c[1] = (double)(q + 5 * s2);
            for (int k = 0; k < 2; k++) a[k] *= scale, b[k] *= scale, c[k] *= scale;
        }
        if (kind == 3) { /* the classic: (1+u)^2 vs 1+2u */
            double u = ldexp(1, -52 - (int)(tu_rng_u64(&rng) % 3));
            a[0] = 0, a[1] = 0, b[0] = 1 + u, b[1] = 1, c[0] = 1 + 2 * u, c[1] = 1 + u;
        }
        int want = gmp_orient2d(a, b, c), got = as_io_orient2d_sign(a, b, c);
        if (want != got) fail_msg("case %d: (%a %a) (%a %a) (%a %a): %d, exact %d", i, a[0], a[1],
                                  b[0], b[1], c[0], c[1], got, want);
        zeros += want == 0;
        if (kind == 3 && want != 0) {
            /* the naive determinant says 0 here */
            nonzero_hard += ((a[0] - c[0]) * (b[1] - c[1]) - (a[1] - c[1]) * (b[0] - c[0])) == 0 ||
                            (b[0] * c[1] - b[1] * c[0]) == 0;
        }
    }
    assert_true(zeros >= 7500);       /* the exactly collinear quarter at least */
    assert_true(nonzero_hard > 1000); /* cases a floating-point test gets wrong */
    /* 3D: collinear iff the cross product is exactly zero. */
    double p[3] = {0.1, 0.2, 0.3}, q[3] = {0.2, 0.4, 0.6}, r[3] = {0.4, 0.8, 1.2};
    assert_true(as_io_collinear3(p, q, r)); /* exact doubles: q = 2p, r = 4p */
    double u = ldexp(1, -52), e[3] = {1 + u, 1, 7}, f[3] = {1 + 2 * u, 1 + u, 7}, o[3] = {0, 0, 7};
    assert_false(as_io_collinear3(o, e, f));
    double g[3] = {1, 1, 1};
    assert_true(as_io_collinear3(g, g, p)); /* two coincide */
}

/* A tetrahedron whose fourth vertex sits on an edge: closed, but one triangle is flat. */
static void test_zero_area(void **state) {
    (void)state;
    mesh m = {0};
    add_v(&m, 0, 0, 0);
    add_v(&m, 1, 0, 0);
    add_v(&m, 0, 1, 0);
    add_v(&m, 0.5, 0, 0); /* on edge 0-1 */
    add_t(&m, 0, 2, 1);
    add_t(&m, 0, 1, 3);
    add_t(&m, 1, 2, 3);
    add_t(&m, 2, 0, 3);
    as_topology r = check(&m);
    assert_true(r.closed_manifold);
    assert_int_equal(r.zero_area, 1);
    assert_int_equal(r.genus, 0);
    assert_false(as_topology_ok(&r));
    char msg[512];
    require_msg(&r, msg, sizeof msg);
    assert_string_equal(msg, "x.off: not a valid closed surface: 1 zero-area triangle");
    mesh_free(&m);
}

static void test_invalid_and_enomem(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    mesh m = load(DATA("sphere_r0.5.off"));
    as_topology r;
    m.tri[5] = (int32_t)m.nv;
    assert_int_equal(as_topology_check(t.ctx, m.nv, m.xyz, m.nt, m.tri, &r), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(t.ctx), "triangle 1"));
    m.tri[5] = -3;
    assert_int_equal(as_topology_orient(t.ctx, m.nv, m.xyz, m.nt, m.tri, &r), ANISTAR_EINVAL);
    m.tri[5] = 0;
    assert_int_equal(as_topology_check(t.ctx, 0, NULL, 0, NULL, &r), ANISTAR_OK);
    assert_false(as_topology_ok(&r));
    assert_int_equal(as_topology_require(t.ctx, "e.off", &r), ANISTAR_EFORMAT);
    assert_string_equal(anistar_last_error(t.ctx), "e.off: no triangles");
    tctx_done(&t);
    mesh_free(&m);
    m = load(DATA("sphere_r0.5.off"));
    int32_t *orig = malloc(m.nt * 3 * sizeof(int32_t));
    memcpy(orig, m.tri, m.nt * 3 * sizeof(int32_t));
    m.tri[4] = orig[5], m.tri[5] = orig[4]; /* one flipped triangle to repair */
    long k = 0;
    for (;; k++) {
        tctx_init(&t);
        t.a.fail_after = t.a.count + k;
        anistar_status st = as_topology_orient(t.ctx, m.nv, m.xyz, m.nt, m.tri, &r);
        if (st == ANISTAR_OK) {
            tctx_done(&t);
            break;
        }
        assert_int_equal(st, ANISTAR_ENOMEM);
        assert_int_equal(t.a.live_blocks, 1);
        if (m.tri[4] != orig[5]) fail_msg("the array changed on failure");
        tctx_done(&t);
    }
    assert_true(k >= 1);
    assert_memory_equal(orig, m.tri, m.nt * 3 * sizeof(int32_t));
    free(orig);
    mesh_free(&m);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_data_files),
        cmocka_unit_test(test_cube_and_open_cube),
        cmocka_unit_test(test_nonmanifold),
        cmocka_unit_test(test_reorient),
        cmocka_unit_test(test_shuffled),
        cmocka_unit_test(test_torus_moebius_klein),
        cmocka_unit_test(test_components),
        cmocka_unit_test(test_exact_orient2d),
        cmocka_unit_test(test_zero_area),
        cmocka_unit_test(test_invalid_and_enomem),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
