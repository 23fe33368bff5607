/*
 * test_del3_debug — lib/geom/del3.c built with -DAS_DEL3_DEBUG (del3.h "Debug:").
 *
 * The Makefile links this program against a copy of del3.c compiled with -DAS_DEL3_DEBUG
 * (build/.../obj/test/del3_debug.o) instead of the library's del3.o, so every successful
 * as_del3_insert runs both validators (as_del3_check_combinatorics,
 * as_del3_check_delaunay) and returns ANISTAR_EINTERNAL when the triangulation it leaves is
 * invalid. Why: test_del3 validates final triangulations (mostly bulk builds), so an
 * insertion that breaks the triangulation and a later one that happens to repair it, or a
 * debug mode that no longer compiles or no longer reports, would go unnoticed; here every
 * intermediate triangulation is validated: each point is inserted ONE BY ONE and every
 * insertion must return ANISTAR_OK (AS_DEL3_DUPLICATE where a point repeats). The
 * validators cost O(n) per insertion (O(n^2) a build, exact insphere tests for nearly
 * cospherical points), hence the modest sizes. Families: uniform points in a cube
 * (with and without the sphere cache, whose entries the validator compares with fresh
 * ones), points on a sphere and a torus, an integer grid (cospherical and coplanar: the
 * perturbation, the pending phase of collinear/coplanar points, and coplanar hull faces),
 * sphere and torus points stretched by frames of anisotropy 1e3 (as_del3_insert_frame),
 * duplicates (in the pending phase too), and star-like sets (8 box corners then a small
 * curved patch, rebuilt after as_del3_reset). At the end of each build, counted
 * independently of the validators: Euler's relation of the finite tets (a triangulated
 * ball: V - E + F - T = 1), every vertex used by a finite tet, the hull a triangulated
 * 2-sphere (infinite tets = 2 h - 4 for h hull vertices), h where it is known (convex
 * position: all points; the grid: its boundary points; stars: the 8 corners), the grid's
 * tets tiling its cube (exact volume), and the same triangulation whatever the insertion
 * order (the perturbed triangulation is unique).
 * One negative test proves the hook is linked and runs: a valid triangulation is broken
 * by moving a vertex (still positively oriented, no longer Delaunay), and the next
 * insertion, far from it, must return ANISTAR_EINTERNAL, which the library's own del3.o
 * never does for a valid insertion.
 */
#include "test_util.h"
#include "del3_check.h"

#include "anistar.h"
#include "core.h"
#include "geom/del3.h"
#include "geom/metric.h"
#include "geom/predicates.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ------------------------------------------------------------------------- */

typedef struct fixture {
    tu_alloc al;
    anistar_context *ctx;
} fixture;

static void fx_open(fixture *f) {
    tu_alloc_init(&f->al, -1);
    anistar_allocator a = tu_allocator(&f->al);
    f->ctx = anistar_context_new(&a);
    assert_non_null(f->ctx);
}

static void fx_close(fixture *f) {
    anistar_context_free(f->ctx);
    assert_int_equal(f->al.live_blocks, 0);
    assert_int_equal(f->al.live_bytes, 0);
}

/* Insert one point (through mf, NULL: as given) and require ANISTAR_OK: the debug build
 * validated the triangulation it left. The new vertex is nv-1; once the set is 3D, every
 * tet the insertion created holds it (unless it built the first tets). */
static int32_t insert_ok(as_del3 *d, const as_metric_frame *mf, const double q[3], int64_t gid) {
    int32_t v = -7, nv0 = d->nv;
    int r = as_del3_insert_frame(d, mf, q, gid, &v);
    if (r != ANISTAR_OK)
        fail_msg("insertion of gid %lld (vertex %d) returned %d: %s", (long long)gid, (int)nv0,
                 r, anistar_last_error(d->ctx));
    assert_int_equal(v, nv0);
    assert_int_equal(d->nv, nv0 + 1);
    if (d->dim3 && !d->rebuilt) {
        assert_true(d->created.n > 0);
        for (size_t k = 0; k < d->created.n; k++) {
            const int32_t *tv = as_del3_tet_vertices(d, d->created.a[k]);
            assert_true(tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v);
        }
    }
    return v;
}

/* Insert pts[0..n-1] one by one with gids gid0 + i. */
static void insert_each(as_del3 *d, const as_metric_frame *mf, const double *pts, int n,
                        int64_t gid0) {
    for (int i = 0; i < n; i++) insert_ok(d, mf, pts + 3 * i, gid0 + i);
}

/*
 * The end-of-build sanity checks, counted from the tet records without the validators:
 * the set is 3D with nv vertices; finite + infinite tets = live tets; every vertex is in a
 * finite tet; Euler's relation of the finite part (V - E + F - T = 1, E and F by
 * deduplicating the simplices of the finite tets); the hull (finite faces of the infinite
 * tets) has 2 h - 4 triangles for h hull vertices. Returns h.
 */
static int32_t check_counts(const as_del3 *d, int32_t nv) {
    assert_true(d->dim3);
    assert_int_equal(d->nv, nv);
    int32_t nf, ni;
    as_del3_count(d, &nf, &ni);
    assert_int_equal(nf + ni, d->nlive);
    assert_true(nf > 0 && ni >= 4);
    unsigned char *used = calloc((size_t)nv, 1), *hull = calloc((size_t)nv, 1);
    assert_true(used && hull);
    int32_t nlive = 0, ninf = 0;
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t)) continue;
        nlive++;
        const int32_t *tv = as_del3_tet_vertices(d, t);
        int inf = as_del3_is_infinite(d, t);
        ninf += inf;
        for (int i = 0; i < 4; i++) {
            if (tv[i] < 0) continue;
            assert_true(tv[i] < nv);
            if (inf)
                hull[tv[i]] = 1;
            else
                used[tv[i]] = 1;
        }
    }
    assert_int_equal(nlive, d->nlive);
    assert_int_equal(ninf, ni);
    int32_t h = 0;
    for (int32_t v = 0; v < nv; v++) {
        if (!used[v]) fail_msg("vertex %d is in no finite tet", (int)v);
        h += hull[v];
    }
    tu_del3_assert_euler(d);
    assert_int_equal(ni, 2 * h - 4);
    free(used);
    free(hull);
    return h;
}

/* ---- families of points, inserted one by one -------------------------------------------- */

/* Uniform points in a cube: 2000 without the sphere cache, 600 with it (the validator
 * compares every cached sphere with a fresh one after each insertion). */
static void test_random_cube(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {101};
    int sizes[2] = {2000, 600};
    for (int k = 0; k < 2; k++) {
        int n = sizes[k];
        double *p = tu_pts_cube(&r, n);
        as_del3 d;
        as_del3_init(&d, f.ctx);
        d.sphere_cache = k;
        insert_each(&d, NULL, p, n, 0);
        assert_true((d.sph != NULL) == (k == 1));
        int32_t h = check_counts(&d, n);
        assert_true(h >= 8 && h < n / 4); /* few random points lie on the hull */
        as_del3_destroy(&d);
        free(p);
    }
    fx_close(&f);
}

/* Points on a sphere: nearly cospherical everywhere (the validators' insphere tests mostly
 * reach the exact stage, hence the small size); convex position: every point is a hull
 * vertex. */
static void test_sphere(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {102};
    int n = 400;
    double *p = tu_pts_sphere(&r, n);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    insert_each(&d, NULL, p, n, 0);
    assert_int_equal(check_counts(&d, n), n);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* Points on a torus: a non-convex surface sample (flat tets between the sheets), with the
 * sphere cache. */
static void test_torus(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {108};
    int n = 900;
    double *p = tu_pts_torus(&r, n, 1.0, 0.35);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    d.sphere_cache = 1;
    insert_each(&d, NULL, p, n, 0);
    assert_non_null(d.sph);
    int32_t h = check_counts(&d, n);
    assert_true(h > 0 && h < n);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* A 7x7x7 integer grid, massively cospherical and coplanar. In index order the first 7
 * points are collinear and the first 49 coplanar (pending phase), then the 50th builds the
 * first tets. The finite tets tile the cube [0,6]^3 (exact volumes: orient3d is exact on
 * small integers); the hull vertices are exactly the 218 boundary points; a random
 * insertion order gives the same triangulation. */
static void test_grid(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    enum { G = 7, N = G * G * G };
    double *p = tu_pts_alloc(N);
    for (int i = 0; i < N; i++) {
        p[3 * i] = i % G;
        p[3 * i + 1] = (i / G) % G;
        p[3 * i + 2] = i / (G * G);
    }
    as_del3 d;
    as_del3_init(&d, f.ctx);
    for (int i = 0; i < N; i++) {
        insert_ok(&d, NULL, p + 3 * i, i);
        assert_int_equal(d.dim3, i >= G * G);
        if (i == G * G) assert_true(d.rebuilt);
    }
    assert_int_equal(check_counts(&d, N), N - (G - 2) * (G - 2) * (G - 2));
    double vol6 = 0;
    for (int32_t t = 0; t < d.nt; t++) {
        if (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t)) continue;
        const int32_t *v = as_del3_tet_vertices(&d, t);
        double o = as_orient3d(as_del3_point(&d, v[0]), as_del3_point(&d, v[1]),
                               as_del3_point(&d, v[2]), as_del3_point(&d, v[3]));
        assert_true(o > 0);
        vol6 += o;
    }
    assert_true(vol6 == 6.0 * (G - 1) * (G - 1) * (G - 1));
    /* shuffled order, same gids */
    int32_t perm[N];
    for (int i = 0; i < N; i++) perm[i] = i;
    tu_rng r = {103};
    for (int i = N - 1; i > 0; i--) {
        int j = (int)(tu_rng_u64(&r) % (uint64_t)(i + 1));
        int32_t t = perm[i];
        perm[i] = perm[j];
        perm[j] = t;
    }
    as_del3 e;
    as_del3_init(&e, f.ctx);
    for (int i = 0; i < N; i++) insert_ok(&e, NULL, p + 3 * perm[i], perm[i]);
    check_counts(&e, N);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* Sphere and torus points stretched by F with anisotropy 1e3 (random eigenframes), through
 * as_del3_insert_frame: the stored coordinates are F q bit for bit; the stretched sphere
 * (an ellipsoid) is still in convex position. */
static void test_stretched(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {104};
    for (int k = 0; k < 2; k++) {
        double u[9], e[3] = {1, sqrt(1e3), 1e3};
        tu_random_rotation(&r, u);
        as_metric_frame mf;
        assert_int_equal(as_metric_frame_from_eigen(&mf, u, e), 0);
        assert_true(mf.e[2] / mf.e[0] > 0.999e3 && mf.e[2] / mf.e[0] < 1.001e3);
        int n = 700;
        double *p = k == 0 ? tu_pts_sphere(&r, n) : tu_pts_torus(&r, n, 1.0, 0.4);
        as_del3 d;
        as_del3_init(&d, f.ctx);
        insert_each(&d, &mf, p, n, 0);
        int32_t h = check_counts(&d, n);
        if (k == 0) assert_int_equal(h, n);
        for (int32_t v = 0; v < d.nv; v++) {
            double y[3];
            as_metric_apply(&mf, p + 3 * d.gid[v], y);
            assert_memory_equal(y, as_del3_point(&d, v), sizeof y);
        }
        as_del3_destroy(&d);
        free(p);
    }
    fx_close(&f);
}

/* Repeated points, one by one: each repeat returns AS_DEL3_DUPLICATE with the vertex of its
 * first occurrence and changes nothing (-0 equals +0; repeats also in the pending phase);
 * the result equals the triangulation of the distinct points alone. */
static void test_duplicates(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {105};
    int n = 600, m = 900; /* 600 distinct points, 300 repeats interleaved */
    double *u = tu_pts_cube(&r, n);
    u[0] = 0.0;
    double *p = tu_pts_alloc(m);
    int32_t *src = malloc((size_t)m * sizeof *src);
    assert_non_null(src);
    /* the sequence: points 0, 1, 0 (pending-phase repeat), then distinct points in order,
     * each followed with probability 1/2 by a repeat of a random earlier one */
    int k = 0, next = 0;
    src[k++] = next++;
    src[k++] = next++;
    src[k++] = 0;
    while (k < m) {
        if (next < n && ((tu_rng_u64(&r) & 1) || k + (n - next) >= m)) {
            src[k++] = next++;
        } else {
            src[k++] = (int32_t)(tu_rng_u64(&r) % (uint64_t)next);
        }
    }
    assert_int_equal(next, n);
    for (int i = 0; i < m; i++) memcpy(p + 3 * i, u + 3 * src[i], 3 * sizeof *p);
    p[3 * 2] = -0.0; /* the pending-phase repeat of point 0 as -0: equal coordinates */
    as_del3 d;
    as_del3_init(&d, f.ctx);
    int32_t *vof = malloc((size_t)n * sizeof *vof); /* vertex of each distinct point */
    assert_non_null(vof);
    int ndup = 0;
    for (int i = 0; i < m; i++) {
        int first = 1;
        for (int j = 0; j < i && first; j++) first = src[j] != src[i];
        if (first) {
            vof[src[i]] = insert_ok(&d, NULL, p + 3 * i, src[i]);
        } else {
            int32_t v = -7, nv0 = d.nv, nlive0 = d.nlive;
            assert_int_equal(as_del3_insert(&d, p + 3 * i, 100000 + i, &v), AS_DEL3_DUPLICATE);
            assert_int_equal(v, vof[src[i]]);
            assert_int_equal(d.nv, nv0);
            assert_int_equal(d.nlive, nlive0);
            ndup++;
        }
    }
    assert_int_equal(ndup, m - n);
    assert_int_equal(d.stats.duplicates, (uint64_t)ndup);
    check_counts(&d, n);
    as_del3 e;
    as_del3_init(&e, f.ctx);
    for (int i = 0; i < n; i++) insert_ok(&e, NULL, u + 3 * i, i);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    as_del3_destroy(&d);
    free(vof);
    free(src);
    free(p);
    free(u);
    fx_close(&f);
}

/* Star-like sets, as the mesher builds them (bench_del3's star_points): 8 box corners
 * (exact cube corners: cospherical, coplanar hull faces; or slightly irregular ones), then
 * 40 points on a small curved patch, rebuilt many times in one structure after
 * as_del3_reset, with and without the sphere cache. The hull is the 8 corners; a rebuild
 * of the first set gives the same triangulation. */
static void star_points(tu_rng *r, int generic, double *p, int npatch) {
    for (int c = 0; c < 8; c++)
        for (int k = 0; k < 3; k++) {
            double s = (c >> k) & 1 ? 3.0 : -3.0;
            p[3 * c + k] = generic ? s * (1.0 + tu_rng_range(r, 0, 0.1)) : s;
        }
    for (int i = 8; i < 8 + npatch; i++) {
        double x = tu_rng_range(r, -0.1, 0.1), y = tu_rng_range(r, -0.1, 0.1);
        p[3 * i] = x;
        p[3 * i + 1] = y;
        p[3 * i + 2] = 0.5 * (x * x - 2 * y * y);
    }
}

static void test_star_like(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {106};
    enum { NP = 40, N = 8 + NP, REPS = 60 };
    double p[3 * N], first[3 * N];
    as_del3 d[2];
    as_del3_init(&d[0], f.ctx);
    as_del3_init(&d[1], f.ctx);
    d[1].sphere_cache = 1;
    size_t nq0 = 0;
    int64_t *q0 = NULL;
    for (int rep = 0; rep < REPS; rep++) {
        as_del3 *dd = &d[rep & 1];
        as_del3_reset(dd);
        star_points(&r, rep % 4 >= 2, p, NP);
        if (rep == 0) memcpy(first, p, sizeof p);
        for (int i = 0; i < N; i++) {
            insert_ok(dd, NULL, p + 3 * i, i);
            if (i < 3) assert_false(dd->dim3);
            if (i >= 4) assert_true(dd->dim3); /* cube corners 0-3 are coplanar */
        }
        assert_true((dd->sph != NULL) == (rep & 1));
        assert_int_equal(check_counts(dd, N), 8);
        if (rep == 0) q0 = tu_del3_canon(dd, &nq0);
    }
    /* the first set again, in the structure that built it */
    as_del3_reset(&d[0]);
    insert_each(&d[0], NULL, first, N, 0);
    size_t nq;
    int64_t *q = tu_del3_canon(&d[0], &nq);
    assert_int_equal(nq, nq0);
    assert_memory_equal(q, q0, 4 * nq * sizeof *q);
    free(q);
    free(q0);
    as_del3_destroy(&d[0]);
    as_del3_destroy(&d[1]);
    fx_close(&f);
}

/* ---- the hook runs ------------------------------------------------------------------------ */

/* 1 if tet t has vertex v. */
static int has_vertex(const as_del3 *d, int32_t t, int32_t v) {
    const int32_t *tv = as_del3_tet_vertices(d, t);
    return tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v;
}

/* 1 if t holds v or is a neighbour of a tet that does: the tets whose local Delaunay test
 * can change when v moves. */
static int near_vertex(const as_del3 *d, int32_t t, int32_t v) {
    if (has_vertex(d, t, v)) return 1;
    for (int i = 0; i < 4; i++)
        if (has_vertex(d, as_del3_neighbor(d, t, i), v)) return 1;
    return 0;
}

/*
 * Break a valid triangulation: move an interior vertex so that every tet stays positively
 * oriented (as_del3_check_combinatorics passes) but the local Delaunay test fails. Then
 * insert a point whose conflict zone is disjoint from the moved vertex's tets and their
 * neighbours: the insertion itself is an ordinary one and leaves the broken pair in place,
 * so only the debug hook can notice, and the insertion must return ANISTAR_EINTERNAL
 * with the validator's message. (The library's own del3.o would return ANISTAR_OK.)
 */
static void test_hook_detects_corruption(void **state) {
    (void)state;
    fixture f;
    fx_open(&f);
    tu_rng r = {107};
    int n = 200;
    double *p = tu_pts_cube(&r, n);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    insert_each(&d, NULL, p, n, 0);
    check_counts(&d, n);
    /* a move of an interior vertex (|x|_inf < 0.6) that keeps the orientations */
    int32_t v = -1;
    for (int trial = 0; trial < 2000 && v < 0; trial++) {
        int32_t w = (int32_t)(tu_rng_u64(&r) % (uint64_t)n);
        double *x = d.vert[w].x, save[3] = {x[0], x[1], x[2]};
        if (fabs(x[0]) > 0.6 || fabs(x[1]) > 0.6 || fabs(x[2]) > 0.6) continue;
        for (int k = 0; k < 3; k++) x[k] += tu_rng_range(&r, -0.08, 0.08);
        as_del3_forget_spheres(&d);
        if (as_del3_check_combinatorics(&d) == ANISTAR_OK &&
            as_del3_check_delaunay(&d) == ANISTAR_EINTERNAL) {
            v = w;
        } else {
            memcpy(x, save, sizeof save);
            as_del3_forget_spheres(&d);
        }
    }
    assert_true(v >= 0);
    /* a new point far from v whose conflict zone avoids v's neighbourhood */
    as_del3_buf zone = {0};
    double q[3];
    int found = 0;
    for (int trial = 0; trial < 1000 && !found; trial++) {
        for (int k = 0; k < 3; k++) q[k] = tu_rng_range(&r, -1, 1);
        double dx = q[0] - d.vert[v].x[0], dy = q[1] - d.vert[v].x[1],
               dz = q[2] - d.vert[v].x[2];
        if (dx * dx + dy * dy + dz * dz < 0.64) continue;
        int32_t dupv;
        assert_int_equal(as_del3_conflict_zone(&d, q, n, -1, &zone, &dupv), ANISTAR_OK);
        assert_true(zone.n > 0);
        found = 1;
        for (size_t k = 0; k < zone.n && found; k++) found = !near_vertex(&d, zone.a[k], v);
    }
    assert_true(found);
    int32_t nv0 = d.nv, vnew = -7;
    assert_int_equal(as_del3_insert(&d, q, n, &vnew), ANISTAR_EINTERNAL);
    assert_non_null(strstr(anistar_last_error(f.ctx), "del3 check"));
    /* the point went in (the hook runs after the insertion); the break is still there */
    assert_int_equal(d.nv, nv0 + 1);
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_OK);
    assert_int_equal(as_del3_check_delaunay(&d), ANISTAR_EINTERNAL);
    as_del3_buf_free(f.ctx, &zone);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hook_detects_corruption),
        cmocka_unit_test(test_random_cube),
        cmocka_unit_test(test_sphere),
        cmocka_unit_test(test_torus),
        cmocka_unit_test(test_grid),
        cmocka_unit_test(test_stretched),
        cmocka_unit_test(test_duplicates),
        cmocka_unit_test(test_star_like),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
