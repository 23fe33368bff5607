/*
 * test_selfx.c — the exact self-intersection test (lib/geom/selfx.c) and the voxel
 * labelling of `anistar info` (lib/io/info.c): constructed cases for every kind of
 * adjacency (none, a shared vertex, a shared edge, a duplicated triangle), closed meshes
 * that cross, touch at a vertex or are clean, the tree-accelerated search against all
 * pairs, the cap, and allocation failures.
 */
#include "test_util.h"

#include "core.h"
#include "geom/selfx.h"
#include "io/info.h"

#include <stdlib.h>
#include <string.h>

typedef struct mesh {
    double xyz[3 * 64];
    int32_t tri[3 * 128];
    size_t nv, nt;
} mesh;

static int32_t V(mesh *m, double x, double y, double z) {
    assert_true(m->nv < 64);
    m->xyz[3 * m->nv] = x;
    m->xyz[3 * m->nv + 1] = y;
    m->xyz[3 * m->nv + 2] = z;
    return (int32_t)m->nv++;
}

static void T(mesh *m, int32_t a, int32_t b, int32_t c) {
    assert_true(m->nt < 128);
    m->tri[3 * m->nt] = a;
    m->tri[3 * m->nt + 1] = b;
    m->tri[3 * m->nt + 2] = c;
    m->nt++;
}

/* A closed tetrahedron with corner o and edge s (its apex is v0 unless apex >= 0, then
 * that existing vertex replaces the corner o). */
static void tet(mesh *m, double ox, double oy, double oz, double s, int32_t apex) {
    int32_t a = apex >= 0 ? apex : V(m, ox, oy, oz);
    int32_t b = V(m, ox + s, oy, oz), c = V(m, ox, oy + s, oz), d = V(m, ox, oy, oz + s);
    T(m, a, c, b);
    T(m, a, b, d);
    T(m, a, d, c);
    T(m, b, c, d);
}

static size_t count(const mesh *m, int32_t *pairs, size_t np) {
    anistar_context *ctx = anistar_context_new(NULL);
    size_t n = 0;
    int capped = 1;
    assert_int_equal(as_self_intersections(ctx, m->xyz, m->nv, m->tri, m->nt, 1000, pairs, np,
                                           &n, &capped),
                     ANISTAR_OK);
    assert_int_equal(capped, 0);
    anistar_context_free(ctx);
    return n;
}

/* All pairs by brute force with the pair test. */
static size_t brute(const mesh *m) {
    size_t n = 0;
    for (size_t i = 0; i < m->nt; i++)
        for (size_t j = i + 1; j < m->nt; j++)
            n += (size_t)as_tri_pair_intersect(m->xyz, m->tri + 3 * i, m->tri + 3 * j);
    return n;
}

static void test_clean(void **state) {
    (void)state;
    mesh m = {0};
    tet(&m, 0, 0, 0, 1, -1);
    tet(&m, 3, 0, 0, 1, -1); /* a second, disjoint */
    assert_int_equal(count(&m, NULL, 0), 0);
    assert_int_equal(brute(&m), 0);
}

static void test_crossing_tetrahedra(void **state) {
    (void)state;
    mesh m = {0};
    tet(&m, 0, 0, 0, 1, -1);
    tet(&m, 0.2, 0.2, 0.2, 1, -1); /* shifted into the first */
    int32_t pairs[16];
    size_t n = count(&m, pairs, 8);
    assert_true(n > 0);
    assert_int_equal(n, brute(&m));
    for (size_t k = 0; k < n && k < 8; k++) {
        /* every pair joins the two tetrahedra (triangles 0-3 and 4-7), in order */
        assert_true(pairs[2 * k] < 4 && pairs[2 * k + 1] >= 4);
        if (k) assert_true(pairs[2 * k - 2] < pairs[2 * k] ||
                           (pairs[2 * k - 2] == pairs[2 * k] && pairs[2 * k - 1] < pairs[2 * k + 1]));
    }
}

static void test_touch_at_vertex(void **state) {
    (void)state;
    /* two tetrahedra sharing the vertex index of a corner, on opposite sides: not an
     * intersection (the shared vertex is a non-manifold vertex, a topology matter) */
    mesh m = {0};
    tet(&m, 0, 0, 0, 1, -1);
    int32_t p = 0;
    int32_t b = V(&m, -1, 0, 0), c = V(&m, 0, -1, 0), d = V(&m, 0, 0, -1);
    T(&m, p, b, c);
    T(&m, p, d, b);
    T(&m, p, c, d);
    T(&m, b, d, c);
    assert_int_equal(count(&m, NULL, 0), 0);
    /* the same with the second tetrahedron's corner a distinct vertex at the same point:
     * the surfaces touch there, three triangles against three */
    mesh q = {0};
    tet(&q, 0, 0, 0, 1, -1);
    tet(&q, 0, 0, 0, -1, -1);
    assert_int_equal(count(&q, NULL, 0), 9);
    assert_int_equal(brute(&q), 9);
}

static void test_shared_edge(void **state) {
    (void)state;
    mesh m = {0};
    int32_t u = V(&m, 0, 0, 0), v = V(&m, 1, 0, 0), a = V(&m, 0, 1, 0), b = V(&m, 0.5, 2, 0),
            c = V(&m, 0.5, -1, 0), d = V(&m, 0.5, 1, 1);
    int32_t t1[3] = {u, v, a}, fold[3] = {v, u, b}, flat[3] = {v, u, c}, bent[3] = {u, v, d};
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, fold), 1); /* coplanar, same side */
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, flat), 0); /* coplanar, other side */
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, bent), 0); /* a dihedral angle */
    int32_t dup[3] = {a, u, v};
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, dup), 1); /* the same triangle */
}

static void test_shared_vertex(void **state) {
    (void)state;
    mesh m = {0};
    int32_t p = V(&m, 0, 0, 0), a = V(&m, 2, 0, 0), b = V(&m, 0, 2, 0);
    int32_t c = V(&m, 1, 1, 0), d = V(&m, -1, 2, 0);  /* coplanar wedge overlapping */
    int32_t e = V(&m, -1, 0, 0), f = V(&m, 0, -1, 0); /* coplanar, opposite wedge */
    int32_t g = V(&m, 1, 0.5, -1), h = V(&m, 1, 0.5, 1); /* pierces t1 through its edge */
    int32_t k = V(&m, 0, 0, 1), l = V(&m, -1, -1, 1);   /* above, apart */
    int32_t r = V(&m, 1, 0, 0), s = V(&m, 0, 0, 1);     /* along t1's edge pa */
    int32_t t1[3] = {p, a, b};
    int32_t over[3] = {p, c, d}, opp[3] = {p, e, f}, pierce[3] = {p, g, h}, apart[3] = {p, k, l},
            along[3] = {p, r, s};
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, over), 1);
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, opp), 0);
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, pierce), 1);
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, apart), 0);
    assert_int_equal(as_tri_pair_intersect(m.xyz, t1, along), 1); /* edges overlap */
    assert_int_equal(as_tri_pair_intersect(m.xyz, over, t1), 1);  /* symmetric */
    assert_int_equal(as_tri_pair_intersect(m.xyz, along, t1), 1);
}

static void test_degenerate_skipped(void **state) {
    (void)state;
    mesh m = {0};
    int32_t a = V(&m, 0, 0, 0), b = V(&m, 1, 0, 0), c = V(&m, 2, 0, 0), d = V(&m, 1, -1, 0),
            e = V(&m, 1, 1, 0);
    int32_t line[3] = {a, b, c}, rep[3] = {a, a, d}, t[3] = {d, e, c};
    assert_int_equal(as_tri_degenerate(m.xyz, line), 1);
    assert_int_equal(as_tri_degenerate(m.xyz, rep), 1);
    assert_int_equal(as_tri_degenerate(m.xyz, t), 0);
    assert_int_equal(as_tri_pair_intersect(m.xyz, line, t), 0);
}

/* Random small triangles in a box: the tree search finds exactly the pairs of the
 * all-pairs loop, in the same order. */
static void test_random_against_all_pairs(void **state) {
    (void)state;
    tu_rng r = {42};
    for (int round = 0; round < 20; round++) {
        mesh m = {0};
        for (int i = 0; i < 40; i++) {
            double o[3] = {tu_rng_range(&r, 0, 4), tu_rng_range(&r, 0, 4), tu_rng_range(&r, 0, 4)};
            int32_t a = V(&m, o[0], o[1], o[2]);
            int32_t b = V(&m, o[0] + tu_rng_range(&r, -1, 1), o[1] + tu_rng_range(&r, -1, 1), o[2]);
            int32_t c = i % 3 == 0 && i > 0 ? (int32_t)(m.nv - 5) /* share a vertex sometimes */
                                            : V(&m, o[0], o[1] + tu_rng_range(&r, -1, 1),
                                                o[2] + tu_rng_range(&r, -1, 1));
            if (m.nv > 60) break;
            T(&m, a, b, c);
        }
        int32_t pairs[2 * 100];
        size_t n = count(&m, pairs, 100);
        assert_int_equal(n, brute(&m));
        size_t k = 0;
        for (size_t i = 0; i < m.nt; i++)
            for (size_t j = i + 1; j < m.nt; j++)
                if (as_tri_pair_intersect(m.xyz, m.tri + 3 * i, m.tri + 3 * j) && k < 100) {
                    assert_int_equal(pairs[2 * k], (int32_t)i);
                    assert_int_equal(pairs[2 * k + 1], (int32_t)j);
                    k++;
                }
    }
}

static void test_cap_and_alloc_failures(void **state) {
    (void)state;
    mesh m = {0};
    tet(&m, 0, 0, 0, 1, -1);
    tet(&m, 0.2, 0.2, 0.2, 1, -1);
    size_t total = brute(&m);
    assert_true(total > 2);
    anistar_context *ctx = anistar_context_new(NULL);
    size_t n;
    int capped;
    assert_int_equal(as_self_intersections(ctx, m.xyz, m.nv, m.tri, m.nt, 2, NULL, 0, &n, &capped),
                     ANISTAR_OK);
    assert_int_equal(n, 2);
    assert_int_equal(capped, 1);
    anistar_context_free(ctx);
    int ok = 0;
    for (long k = 0; k < 100 && !ok; k++) {
        tu_alloc a;
        tu_alloc_init(&a, k);
        anistar_allocator al = tu_allocator(&a);
        anistar_context *c = anistar_context_new(&al);
        if (!c) continue;
        anistar_status st =
            as_self_intersections(c, m.xyz, m.nv, m.tri, m.nt, 1000, NULL, 0, &n, &capped);
        if (st == ANISTAR_OK) {
            assert_int_equal(n, total);
            ok = 1;
        } else {
            assert_int_equal(st, ANISTAR_ENOMEM);
        }
        anistar_context_free(c);
        assert_int_equal(a.live_blocks, 0);
    }
    assert_true(ok);
}

static void test_voxel_components(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    unsigned char v[4 * 3 * 2];
    memset(v, 0, sizeof v);
    size_t n = 99;
    assert_int_equal(as_voxel_components(ctx, v, 4, 3, 2, &n), ANISTAR_OK);
    assert_int_equal(n, 0);
    v[0] = 1;                   /* (0,0,0) */
    v[1 + 4 * 1 + 12 * 1] = 1;  /* (1,1,1): only a corner shared with (0,0,0) */
    v[3 + 4 * 2] = 1;           /* (3,2,0) */
    v[3 + 4 * 2 + 12] = 1;      /* (3,2,1): a face shared with (3,2,0) */
    assert_int_equal(as_voxel_components(ctx, v, 4, 3, 2, &n), ANISTAR_OK);
    assert_int_equal(n, 3); /* 6-connectivity: the corner does not join */
    memset(v, 1, sizeof v);
    assert_int_equal(as_voxel_components(ctx, v, 4, 3, 2, &n), ANISTAR_OK);
    assert_int_equal(n, 1);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_clean),
        cmocka_unit_test(test_crossing_tetrahedra),
        cmocka_unit_test(test_touch_at_vertex),
        cmocka_unit_test(test_shared_edge),
        cmocka_unit_test(test_shared_vertex),
        cmocka_unit_test(test_degenerate_skipped),
        cmocka_unit_test(test_random_against_all_pairs),
        cmocka_unit_test(test_cap_and_alloc_failures),
        cmocka_unit_test(test_voxel_components),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
