/*
 * test_del3 — lib/geom/del3.c and lib/geom/sort.c: incremental Delaunay in a stretched
 * frame.
 *
 * Every family of points (uniform in a cube, on a sphere, on a torus, a 10x10x10 integer
 * grid, integer points exactly on a sphere, points stretched by frames of anisotropy 1e3
 * and 1e5, a box plus a small surface patch like a star) is triangulated and must pass
 * both validators (combinatorics with exact orientation; local Delaunay with the
 * perturbation) and Euler's relation counted independently on the finite simplices
 * (V - E + F - T = 1 for a triangulated ball). Small sets are checked against brute force
 * (empty perturbed spheres, and the number of tets equals the number of empty perturbed
 * spheres over all 4-subsets). The perturbed triangulation is unique, so the result must
 * not depend on the insertion order; the conflict zone query must equal the set of tets an
 * insertion removes and the brute-force set of tets in conflict; the grid's finite tets
 * must tile its hull (exact volume); circumcenters are compared with an exact rational
 * (GMP) computation, flat tets included; reset gives identical arrays without
 * allocating; allocation failures at every allocation leave a valid, unchanged
 * triangulation and no leak.
 */
#include "test_util.h"
#include "del3_check.h"

#include "anistar.h"
#include "core.h"
#include "geom/del3.h"
#include "geom/metric.h"
#include "geom/predicates.h"
#include "geom/sort.h"

#include <gmp.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- helpers ------------------------------------------------------------------------- */

typedef struct fixture {
    tu_alloc al;
    anistar_context *ctx;
    long base; /* allocations made by the context itself */
} fixture;

/* A context on the counting allocator; fail_after >= 0: the allocation number fail_after
 * after the context's own fails, and every later one. */
static void fx_open(fixture *f, long fail_after) {
    tu_alloc_init(&f->al, -1);
    anistar_allocator a = tu_allocator(&f->al);
    f->ctx = anistar_context_new(&a);
    assert_non_null(f->ctx);
    f->base = f->al.count;
    f->al.fail_after = fail_after < 0 ? -1 : f->base + fail_after;
}

static int same_xyz(const double *a, const double *b) {
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

static void fx_close(fixture *f) {
    anistar_context_free(f->ctx);
    assert_int_equal(f->al.live_blocks, 0);
    assert_int_equal(f->al.live_bytes, 0);
}

static void check_all(as_del3 *d) {
    anistar_status st = as_del3_check_combinatorics(d);
    if (st != ANISTAR_OK) fail_msg("combinatorics: %s", anistar_last_error(d->ctx));
    st = as_del3_check_delaunay(d);
    if (st != ANISTAR_OK) fail_msg("delaunay: %s", anistar_last_error(d->ctx));
    if (d->dim3) tu_del3_assert_euler(d);
}

/* Build from pts (n points, gid i) by bulk insertion and check; sphere_cache: ask for the
 * cached spheres. */
static void build_check_cache(fixture *f, as_del3 *d, const double *pts, int n,
                              const as_metric_frame *mf, int sphere_cache) {
    as_del3_init(d, f->ctx);
    d->sphere_cache = sphere_cache;
    int32_t *vx = malloc((size_t)n * sizeof *vx), ndup = -1;
    assert_non_null(vx);
    assert_int_equal(as_del3_insert_points(d, pts, NULL, n, mf, vx, &ndup), ANISTAR_OK);
    assert_int_equal(ndup, 0);
    assert_int_equal(d->nv, n);
    for (int i = 0; i < n; i++) {
        assert_true(vx[i] >= 0 && vx[i] < n);
        assert_int_equal(d->gid[vx[i]], i);
    }
    free(vx);
    check_all(d);
}

static void build_check(fixture *f, as_del3 *d, const double *pts, int n,
                        const as_metric_frame *mf) {
    build_check_cache(f, d, pts, n, mf, 0);
}

/* ---- Hilbert and BRIO ---------------------------------------------------------------- */

/* The curve on a 2^B grid: a bijection onto [0, 8^B) whose consecutive indices are
 * face-adjacent cells. */
static void check_curve(int B) {
    size_t n = (size_t)1 << (3 * B);
    int32_t *cell = malloc(3 * n * sizeof *cell);
    unsigned char *seen = calloc(n, 1);
    assert_true(cell && seen);
    for (uint32_t x = 0; x < (1u << B); x++)
        for (uint32_t y = 0; y < (1u << B); y++)
            for (uint32_t z = 0; z < (1u << B); z++) {
                uint64_t h = as_hilbert3_index(x, y, z, B);
                assert_true(h < n);
                assert_int_equal(seen[h], 0);
                seen[h] = 1;
                cell[3 * h] = (int32_t)x;
                cell[3 * h + 1] = (int32_t)y;
                cell[3 * h + 2] = (int32_t)z;
            }
    for (size_t h = 1; h < n; h++) {
        int dist = abs(cell[3 * h] - cell[3 * h - 3]) + abs(cell[3 * h + 1] - cell[3 * h - 2]) +
                   abs(cell[3 * h + 2] - cell[3 * h - 1]);
        assert_int_equal(dist, 1);
    }
    free(cell);
    free(seen);
}

/* Reference: Skilling's transpose form of the Hilbert index (J. Skilling, "Programming the
 * Hilbert curve", 2004), written with plain loops: undo the excess rotations level by level
 * from the coarsest, Gray-encode across the axes, interleave (axis 0 first). sort.c runs a
 * table-driven state machine; both must give the same index. */
static uint64_t hilbert_reference(uint32_t x, uint32_t y, uint32_t z, int bits) {
    uint32_t c[3] = {x, y, z};
    for (uint32_t q = (uint32_t)1 << (bits - 1); q > 1; q >>= 1) {
        uint32_t low = q - 1;
        for (int i = 0; i < 3; i++) {
            if (c[i] & q) {
                c[0] ^= low; /* invert the lower bits of axis 0 */
            } else {
                uint32_t t = (c[0] ^ c[i]) & low; /* exchange them with axis i */
                c[0] ^= t;
                c[i] ^= t;
            }
        }
    }
    c[1] ^= c[0];
    c[2] ^= c[1];
    uint32_t g = 0;
    for (uint32_t q = (uint32_t)1 << (bits - 1); q > 1; q >>= 1)
        if (c[2] & q) g ^= q - 1;
    for (int i = 0; i < 3; i++) c[i] ^= g;
    uint64_t h = 0;
    for (int l = bits - 1; l >= 0; l--)
        for (int i = 0; i < 3; i++) h = h << 1 | ((c[i] >> l) & 1u);
    return h;
}

static void test_hilbert(void **state) {
    (void)state;
    for (int B = 1; B <= 6; B++) check_curve(B);
    /* the state machine of sort.c against the reference, every width */
    tu_rng rr = {6};
    for (int k = 0; k < 200000; k++) {
        int bits = 1 + (int)(tu_rng_u64(&rr) % 21);
        uint32_t m = ((uint32_t)1 << bits) - 1;
        uint32_t x = (uint32_t)tu_rng_u64(&rr) & m, y = (uint32_t)tu_rng_u64(&rr) & m;
        uint32_t z = (uint32_t)tu_rng_u64(&rr) & m;
        uint64_t h = as_hilbert3_index(x, y, z, bits);
        if (h != hilbert_reference(x, y, z, bits))
            fail_msg("hilbert index of (%u, %u, %u) on %d bits", x, y, z, bits);
    }
    /* The 21-bit curve used by the sort: face-adjacent cells stay close along the curve on
     * average (locality), and every index is in range. */
    tu_rng r = {5};
    for (int k = 0; k < 1000; k++) {
        uint32_t c[3];
        for (int i = 0; i < 3; i++) c[i] = (uint32_t)(tu_rng_u64(&r) % ((1u << 21) - 1));
        uint64_t h0 = as_hilbert3_index(c[0], c[1], c[2], 21);
        assert_true(h0 < ((uint64_t)1 << 63));
        c[0] ^= 1u << 20; /* the other half along x: a different top-level octant */
        assert_true(as_hilbert3_index(c[0], c[1], c[2], 21) != h0);
    }
}

static void test_sort(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {11};
    int n = 5000;
    double *p = tu_pts_cube(&r, n);
    int32_t *o1 = malloc((size_t)n * sizeof *o1), *o2 = malloc((size_t)n * sizeof *o2);
    assert_int_equal(as_sort_brio(f.ctx, p, n, 7, o1), ANISTAR_OK);
    assert_int_equal(as_sort_brio(f.ctx, p, n, 7, o2), ANISTAR_OK);
    assert_memory_equal(o1, o2, (size_t)n * sizeof *o1); /* deterministic */
    char *seen = calloc((size_t)n, 1);
    for (int i = 0; i < n; i++) {
        assert_true(o1[i] >= 0 && o1[i] < n);
        assert_int_equal(seen[o1[i]], 0);
        seen[o1[i]] = 1;
    }
    /* Hilbert order: consecutive points are close on average (a random order gives a mean
     * distance about 1 in this cube; a space-filling order about n^(-1/3)). */
    assert_int_equal(as_sort_hilbert(f.ctx, p, n, o2), ANISTAR_OK);
    double sum = 0;
    for (int i = 1; i < n; i++) {
        const double *a = p + 3 * o2[i - 1], *b = p + 3 * o2[i];
        sum += sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                    (a[2] - b[2]) * (a[2] - b[2]));
    }
    assert_true(sum / (n - 1) < 0.2);
    /* A shuffled 16^3 grid: consecutive points are mostly grid neighbours (a Hilbert curve
     * on a finer grid that does not align with this one: a few longer jumps). */
    enum { G = 16, NG = G * G * G };
    double *g = tu_pts_alloc(NG);
    int32_t *og = malloc(NG * sizeof *og);
    for (int i = 0; i < NG; i++) {
        int j = (int)((uint64_t)i * 2654435761u % NG); /* a permutation: odd multiplier */
        g[3 * j] = i % G;
        g[3 * j + 1] = (i / G) % G;
        g[3 * j + 2] = i / (G * G);
    }
    assert_int_equal(as_sort_hilbert(f.ctx, g, NG, og), ANISTAR_OK);
    int adjacent = 0;
    for (int i = 1; i < NG; i++) {
        const double *a = g + 3 * og[i - 1], *b = g + 3 * og[i];
        adjacent += fabs(a[0] - b[0]) + fabs(a[1] - b[1]) + fabs(a[2] - b[2]) == 1.0;
    }
    assert_true(adjacent > NG * 3 / 4);
    free(g);
    free(og);
    double bad[6] = {0, 0, 0, NAN, 0, 0};
    assert_int_equal(as_sort_hilbert(f.ctx, bad, 2, o2), ANISTAR_EINVAL);
    free(seen);
    free(o1);
    free(o2);
    free(p);
    fx_close(&f);
}

/* ---- families -------------------------------------------------------------------------- */

static void test_random_cube(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {1};
    int sizes[2] = {1000, 100000};
    for (int s = 0; s < 2; s++) {
        double *p = tu_pts_cube(&r, sizes[s]);
        as_del3 d;
        build_check(&f, &d, p, sizes[s], NULL);
        int32_t nf, ni;
        as_del3_count(&d, &nf, &ni);
        /* uniform random points: about 6.5 tets per point */
        assert_true(nf > 5 * sizes[s] && nf < 8 * sizes[s]);
        as_del3_destroy(&d);
        free(p);
    }
    fx_close(&f);
}

/* as_del3_shrink: capacity down to the counts, and the structure goes on exactly as one
 * never shrunk (same arrays after more insertions), with and without the sphere cache. */
static void test_shrink(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {21};
    double *p = tu_pts_sphere(&r, 600);
    for (int nosph = 0; nosph < 2; nosph++) {
        as_del3 a, b;
        as_del3_init(&a, f.ctx);
        as_del3_init(&b, f.ctx);
        a.sphere_cache = b.sphere_cache = !nosph;
        for (int i = 0; i < 600; i++) {
            int32_t va, vb;
            assert_int_equal(as_del3_insert(&a, p + 3 * i, i, &va), ANISTAR_OK);
            assert_int_equal(as_del3_insert(&b, p + 3 * i, i, &vb), ANISTAR_OK);
            if (i == 299) {
                assert_true(a.cap_t > (size_t)a.nt || a.cap_v > (size_t)a.nv);
                assert_int_equal(as_del3_shrink(&a), 0);
                assert_int_equal(a.cap_t, (size_t)a.nt);
                assert_int_equal(a.cap_v, (size_t)a.nv);
                check_all(&a);
            }
        }
        check_all(&a);
        assert_int_equal(a.nt, b.nt);
        assert_int_equal(a.nv, b.nv);
        assert_memory_equal(a.tet, b.tet, 8 * (size_t)a.nt * sizeof *a.tet);
        assert_int_equal(a.sph == NULL, nosph);
        as_del3_destroy(&a);
        as_del3_destroy(&b);
    }
    free(p);
    fx_close(&f);
}

static void test_sphere_torus(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {2};
    double *p = tu_pts_sphere(&r, 5000);
    as_del3 d;
    build_check(&f, &d, p, 5000, NULL);
    /* points in convex position: every vertex is on the hull */
    int32_t nf, ni;
    as_del3_count(&d, &nf, &ni);
    assert_int_equal(ni, 2 * 5000 - 4);
    as_del3_destroy(&d);
    free(p);
    p = tu_pts_torus(&r, 8000, 1.0, 0.3);
    build_check(&f, &d, p, 8000, NULL);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* A 10x10x10 integer grid: massively cospherical. The finite tets tile the hull cube:
 * their exact volumes (orient3d is exact on small integers) add up to 9^3. */
static void test_grid(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    int n = 1000;
    double *p = tu_pts_alloc(n);
    for (int i = 0; i < n; i++) {
        p[3 * i] = i % 10;
        p[3 * i + 1] = (i / 10) % 10;
        p[3 * i + 2] = i / 100;
    }
    as_del3 d;
    build_check(&f, &d, p, n, NULL);
    double vol6 = 0;
    for (int32_t t = 0; t < d.nt; t++) {
        if (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t)) continue;
        const int32_t *v = as_del3_tet_vertices(&d, t);
        vol6 += as_orient3d(as_del3_point(&d, v[0]), as_del3_point(&d, v[1]),
                            as_del3_point(&d, v[2]), as_del3_point(&d, v[3]));
    }
    assert_true(vol6 == 6.0 * 729.0);
    /* the same set inserted one by one in index order gives the same triangulation */
    as_del3 e;
    as_del3_init(&e, f.ctx);
    for (int i = 0; i < n; i++)
        assert_int_equal(as_del3_insert(&e, p + 3 * i, i, NULL), ANISTAR_OK);
    check_all(&e);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* Integer points exactly on the sphere x^2 + y^2 + z^2 = r^2 (Pythagorean quadruples),
 * scaled by a power of two (dyadic), plus the center: every tet of the surface points is
 * cospherical with all others. */
static int sphere_lattice(int rad, double scale, double *p, int cap) {
    int n = 0;
    for (int x = -rad; x <= rad; x++)
        for (int y = -rad; y <= rad; y++)
            for (int z = -rad; z <= rad; z++)
                if (x * x + y * y + z * z == rad * rad) {
                    if (n < cap) {
                        p[3 * n] = x * scale;
                        p[3 * n + 1] = y * scale;
                        p[3 * n + 2] = z * scale;
                    }
                    n++;
                }
    return n;
}

static void test_cospherical(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    double *p = tu_pts_alloc(4000);
    int n = sphere_lattice(45, 1.0 / 64, p, 3999);
    assert_true(n > 300 && n < 3999);
    p[3 * n] = p[3 * n + 1] = p[3 * n + 2] = 0; /* the center */
    n++;
    as_del3 d, e;
    build_check(&f, &d, p, n, NULL);
    /* reversed one-by-one insertion (the center first): same triangulation */
    as_del3_init(&e, f.ctx);
    for (int i = n - 1; i >= 0; i--)
        assert_int_equal(as_del3_insert(&e, p + 3 * i, i, NULL), ANISTAR_OK);
    check_all(&e);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    /* in index order the center comes last: every finite tet has its circumsphere centred
     * at the center, so all of them are in conflict: a cavity far beyond the direct table
     * (the hash fallback) */
    as_del3_init(&e, f.ctx);
    for (int i = 0; i < n; i++)
        assert_int_equal(as_del3_insert(&e, p + 3 * i, i, NULL), ANISTAR_OK);
    assert_true(e.stats.big_cavities > 0);
    assert_true(e.created.n > 2 * AS_DEL3_LMAX);
    check_all(&e);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* ---- the cached-sphere filter versus the exact predicate ------------------------------ */

static int sgn(double x) { return (x > 0) - (x < 0); }

/* For every live finite tet of d: the filter on nq query points (its vertices' neighbours,
 * points rounded onto its circumsphere, random points around it) must agree with the sign
 * of the exact insphere whenever it decides. Counts decided / undecided / exact zeros. */
static void filter_vs_exact(as_del3 *d, tu_rng *r, long cnt[3]) {
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t) || as_del3_is_infinite(d, t)) continue;
        const int32_t *tv = as_del3_tet_vertices(d, t);
        const double *a = as_del3_point(d, tv[0]), *b = as_del3_point(d, tv[1]);
        const double *c = as_del3_point(d, tv[2]), *e = as_del3_point(d, tv[3]);
        double ctr[3];
        assert_int_equal(as_del3_circumcenter(d, t, ctr), 0);
        double rad = sqrt((a[0] - ctr[0]) * (a[0] - ctr[0]) + (a[1] - ctr[1]) * (a[1] - ctr[1]) +
                          (a[2] - ctr[2]) * (a[2] - ctr[2]));
        for (int k = 0; k < 24; k++) {
            double q[3];
            if (k < 8) { /* a vertex of the triangulation (often one of t: exact zero) */
                const double *w = as_del3_point(d, (int32_t)(tu_rng_u64(r) % (uint64_t)d->nv));
                memcpy(q, w, sizeof q);
                if (k < 4) memcpy(q, as_del3_point(d, tv[k]), sizeof q);
            } else { /* on the circumsphere up to rounding, or a little off it */
                double g[3] = {tu_rng_gauss(r), tu_rng_gauss(r), tu_rng_gauss(r)};
                double gn = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
                double f = k < 16 ? 1.0 : 1.0 + tu_rng_range(r, -1e-9, 1e-9);
                for (int i = 0; i < 3; i++) q[i] = ctr[i] + rad * f * g[i] / gn;
            }
            int fl = as_del3_sphere_filter(d, t, q);
            int ex = sgn(as_insphere_exact(a, b, c, e, q));
            if (fl != 0 && fl != ex)
                fail_msg("sphere filter %d, exact %d (tet %d)", fl, ex, (int)t);
            cnt[fl == 0]++;
            cnt[2] += ex == 0;
        }
    }
}

static void test_sphere_filter(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {77};
    long cnt[3] = {0, 0, 0};
    double *p = tu_pts_alloc(2000);
    for (int fam = 0; fam < 5; fam++) {
        int n = 0;
        if (fam == 0) { /* uniform */
            for (n = 0; n < 300; n++)
                for (int k = 0; k < 3; k++) p[3 * n + k] = tu_rng_range(&r, -1, 1);
        } else if (fam == 1) { /* a grid: cospherical quadruples everywhere */
            for (int x = 0; x < 6; x++)
                for (int y = 0; y < 6; y++)
                    for (int z = 0; z < 6; z++, n++) {
                        p[3 * n] = x;
                        p[3 * n + 1] = y;
                        p[3 * n + 2] = z;
                    }
        } else if (fam == 2) { /* exactly cospherical points plus the center */
            n = sphere_lattice(13, 1.0 / 16, p, 1999);
            p[3 * n] = p[3 * n + 1] = p[3 * n + 2] = 0;
            n++;
        } else { /* tiny / huge scales, flattened (slivers): anisotropy 1e6 */
            double sc = fam == 3 ? 1e-30 : 1e30;
            for (n = 0; n < 300; n++) {
                p[3 * n] = sc * tu_rng_range(&r, -1, 1);
                p[3 * n + 1] = sc * tu_rng_range(&r, -1, 1);
                p[3 * n + 2] = sc * 1e-6 * tu_rng_range(&r, -1, 1);
            }
        }
        as_del3 d;
        build_check_cache(&f, &d, p, n, NULL, 1);
        assert_non_null(d.sph);
        filter_vs_exact(&d, &r, cnt);
        /* the insertions' own statistics: the cache served them, with exact fallbacks */
        assert_true(d.stats.sphere_tests > 0);
        assert_true(d.stats.sphere_exact <= d.stats.sphere_tests);
        if (fam == 1 || fam == 2) assert_true(d.stats.sphere_exact > 0);
        /* a corrupted cache is caught by the validator */
        for (int32_t t = 0; t < d.nt; t++) {
            double *cs = d.sph + AS_DEL3_SPH * (size_t)t;
            if (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t) || cs[4] < 0) continue;
            double keep = cs[0];
            cs[0] = keep != 0 ? 3 * keep : 1.0; /* differs from keep */
            assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
            cs[0] = keep;
            break;
        }
        check_all(&d);
        /* a cached sphere equals a fresh one: drop the caches, same answers */
        as_del3_forget_spheres(&d);
        long cnt2[3] = {0, 0, 0};
        filter_vs_exact(&d, &r, cnt2);
        as_del3_destroy(&d);
    }
    /* both outcomes occur, and exact ties are never decided */
    assert_true(cnt[0] > 1000 && cnt[1] > 100 && cnt[2] > 100);
    /* a big triangulation drops the cache (and stays valid through the plain filter) */
    {
        double *q = tu_pts_cube(&r, 4000);
        as_del3 d;
        build_check_cache(&f, &d, q, 4000, NULL, 1);
        assert_true(d.cap_t > ((size_t)1 << 14));
        assert_null(d.sph);
        /* its tests went through the inline filter, which decided nearly all of them */
        assert_true(d.stats.sphere_tests > 4000);
        assert_true(d.stats.sphere_exact * 100 < d.stats.sphere_tests);
        as_del3_destroy(&d);
        free(q);
    }
    free(p);
    fx_close(&f);
}

/* The inline insphere filter of triangulations without the sphere cache (a cheap bound,
 * then the bound of predicates.h's filter): on random, near-cospherical, exactly
 * cospherical, tiny, huge and flat configurations it never contradicts the exact sign,
 * never decides an exact zero, decides whatever predicates.h's stage-0 filter decides (its
 * second stage is that filter's bound), and decides nearly all random tests. */
static void test_insphere_filter(void **state) {
    (void)state;
    tu_rng r = {91};
    long decided = 0, total = 0, zeros = 0, near = 0, near_undecided = 0;
    for (int k = 0; k < 200000; k++) {
        int kind = k % 5;
        double sc = kind == 3 ? 1e-30 : kind == 4 ? 1e30 : 1.0;
        double flat = kind == 4 ? 1e-6 : 1.0;
        double q[5][3];
        for (int i = 0; i < 5; i++)
            for (int j = 0; j < 3; j++)
                q[i][j] = sc * tu_rng_range(&r, -1, 1) * (j == 2 ? flat : 1);
        if (kind == 1 || kind == 2) {
            /* the query on the sphere through four points of a sphere centered at c (up
             * to rounding: kind 1), or all five exactly on the integer sphere of radius
             * 15 (kind 2: the determinant is exactly 0) */
            static const int32_t on15[][3] = {{15, 0, 0}, {0, 15, 0}, {0, 0, 15}, {-15, 0, 0},
                                              {0, -15, 0}, {0, 0, -15}, {9, 12, 0}, {12, 0, 9},
                                              {0, 9, 12}, {-9, 12, 0}, {12, 0, -9}, {0, -9, 12},
                                              {5, 10, 10}, {10, 5, 10}, {10, 10, 5}, {-5, 10, 10},
                                              {2, 5, 14}, {14, 2, 5}, {5, 14, 2}, {-2, -5, 14}};
            double c[3] = {tu_rng_range(&r, -3, 3), tu_rng_range(&r, -3, 3),
                           tu_rng_range(&r, -3, 3)};
            if (kind == 2) c[0] = c[1] = c[2] = (double)(tu_rng_u64(&r) % 7);
            for (int i = 0; i < 5; i++) {
                if (kind == 2) {
                    const int32_t *w = on15[tu_rng_u64(&r) % 20];
                    for (int j = 0; j < 3; j++) q[i][j] = c[j] + w[j];
                } else {
                    double g[3] = {tu_rng_gauss(&r), tu_rng_gauss(&r), tu_rng_gauss(&r)};
                    double n = sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
                    for (int j = 0; j < 3; j++) q[i][j] = c[j] + 2.0 * g[j] / n;
                }
            }
        }
        int f = as_del3_insphere_filter(q[0], q[1], q[2], q[3], q[4]);
        double ex = as_insphere_exact(q[0], q[1], q[2], q[3], q[4]);
        int es = (ex > 0) - (ex < 0);
        if (f != 0 && f != es) fail_msg("insphere filter %d, exact %d (kind %d)", f, es, kind);
        if (es == 0) {
            zeros++;
            assert_int_equal(f, 0);
        }
        double s0 = as_insphere_filter(q[0], q[1], q[2], q[3], q[4]);
        if (s0 != 0) assert_int_equal(f, (s0 > 0) - (s0 < 0));
        if (kind == 1) {
            near++;
            near_undecided += f == 0;
        } else if (kind != 2) {
            total++;
            decided += f != 0;
        }
    }
    assert_true(zeros > 1000);                 /* the exact zeros were exercised */
    assert_true(near_undecided > 0);           /* ... and the undecided band */
    assert_true(decided * 1000 > total * 999); /* random tests: nearly all decided */
}

/* Points stretched by F with anisotropy 1e3 and 1e5 (random eigenframes): the stored
 * coordinates are F q bit for bit, and the triangulation is valid. */
static void test_stretched(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {3};
    double ratios[2] = {1e3, 1e5};
    for (int k = 0; k < 2; k++) {
        double u[9], e[3] = {1, sqrt(ratios[k]), ratios[k]};
        tu_random_rotation(&r, u);
        as_metric_frame mf;
        assert_int_equal(as_metric_frame_from_eigen(&mf, u, e), 0);
        int n = 3000;
        double *p = k == 0 ? tu_pts_sphere(&r, n) : tu_pts_torus(&r, n, 1.0, 0.4);
        as_del3 d;
        build_check(&f, &d, p, n, &mf);
        for (int32_t v = 0; v < d.nv; v++) {
            double y[3];
            as_metric_apply(&mf, p + 3 * d.gid[v], y);
            assert_memory_equal(y, as_del3_point(&d, v), sizeof y);
        }
        /* single insertion through the frame agrees with the bulk result */
        as_del3 s;
        as_del3_init(&s, f.ctx);
        for (int i = 0; i < n; i++)
            assert_int_equal(as_del3_insert_frame(&s, &mf, p + 3 * i, i, NULL), ANISTAR_OK);
        tu_del3_assert_same(&d, &s);
        as_del3_destroy(&s);
        as_del3_destroy(&d);
        free(p);
    }
    fx_close(&f);
}

/* 8 box corners (ids 0-7) and 40 points on a small curved patch: a star's configuration. */
static void test_star_like(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {4};
    as_del3 d[2];
    as_del3_init(&d[0], f.ctx);
    as_del3_init(&d[1], f.ctx);
    d[1].sphere_cache = 1;
    for (int rep = 0; rep < 100; rep++) {
        as_del3 *dd = &d[rep & 1]; /* without and with the sphere cache */
        as_del3_reset(dd);
        for (int c = 0; c < 8; c++) {
            double q[3] = {c & 1 ? 3.0 : -3.0, c & 2 ? 3.0 : -3.0, c & 4 ? 3.0 : -3.0};
            assert_int_equal(as_del3_insert(dd, q, c, NULL), ANISTAR_OK);
        }
        assert_true(dd->dim3);
        for (int i = 0; i < 40; i++) {
            double x = tu_rng_range(&r, -0.1, 0.1), y = tu_rng_range(&r, -0.1, 0.1);
            double q[3] = {x, y, 0.5 * (x * x - 2 * y * y)};
            int32_t v;
            assert_int_equal(as_del3_insert(dd, q, 8 + i, &v), ANISTAR_OK);
            assert_int_equal(v, 8 + i);
            /* every created tet holds the new vertex */
            for (size_t k = 0; k < dd->created.n; k++) {
                const int32_t *tv = as_del3_tet_vertices(dd, dd->created.a[k]);
                assert_true(tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v);
            }
        }
        assert_true((dd->sph != NULL) == (rep & 1));
        check_all(dd);
    }
    as_del3_destroy(&d[0]);
    as_del3_destroy(&d[1]);
    fx_close(&f);
}

/* tight_growth: the same triangulation (same records, slot for slot) as doubling growth,
 * with every capacity within 1/8 (+4) of its use after each insertion. */
static void test_tight_growth(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {11};
    as_del3 d[2];
    as_del3_init(&d[0], f.ctx);
    as_del3_init(&d[1], f.ctx);
    d[1].tight_growth = 1;
    double q[3 * 200];
    for (int i = 0; i < 200; i++)
        for (int k = 0; k < 3; k++) q[3 * i + k] = tu_rng_range(&r, -1, 1);
    for (int i = 0; i < 200; i++) {
        for (int j = 0; j < 2; j++)
            assert_int_equal(as_del3_insert(&d[j], q + 3 * i, i, NULL), ANISTAR_OK);
        assert_int_equal(d[0].nt, d[1].nt);
        assert_int_equal(d[0].nv, d[1].nv);
        size_t nt = (size_t)d[1].nt, nv = (size_t)d[1].nv;
        assert_true(d[1].cap_t >= nt && d[1].cap_t <= nt + nt / 8 + 4 + 64);
        assert_true(d[1].cap_v >= nv && d[1].cap_v <= nv + nv / 8 + 4 + 16);
    }
    /* doubling left more slack than the tight growth at the end */
    assert_true(d[1].cap_t < d[0].cap_t);
    for (int32_t t = 0; t < d[0].nt; t++)
        assert_memory_equal(as_del3_tet_vertices(&d[0], t), as_del3_tet_vertices(&d[1], t),
                            4 * sizeof(int32_t));
    check_all(&d[1]);
    as_del3_destroy(&d[0]);
    as_del3_destroy(&d[1]);
    fx_close(&f);
}

/* ---- duplicates and the pending phase ------------------------------------------------- */

static void test_duplicates(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {5};
    int n = 500;
    double *p = tu_pts_alloc(2 * n);
    for (int i = 0; i < 3 * n; i++) p[i] = tu_rng_range(&r, -1, 1);
    p[0] = 0.0;
    for (int i = 0; i < n; i++) { /* the second half repeats random points of the first */
        int j = (int)(tu_rng_u64(&r) % (uint64_t)n);
        memcpy(p + 3 * (n + i), p + 3 * j, 3 * sizeof *p);
    }
    memcpy(p + 3 * (n + 7), p, 3 * sizeof *p);
    p[3 * (n + 7)] = -0.0; /* -0 vs +0: equal coordinates */
    as_del3 d;
    as_del3_init(&d, f.ctx);
    int32_t *vx = malloc(2 * (size_t)n * sizeof *vx), ndup;
    assert_int_equal(as_del3_insert_points(&d, p, NULL, 2 * n, NULL, vx, &ndup), ANISTAR_OK);
    assert_int_equal(ndup, n);
    assert_int_equal(d.nv, n);
    for (int i = 0; i < 2 * n; i++) {
        const double *q = as_del3_point(&d, vx[i]);
        assert_true(q[0] == p[3 * i] && q[1] == p[3 * i + 1] && q[2] == p[3 * i + 2]);
    }
    check_all(&d);
    /* single insertion of a duplicate: reported with the vertex, nothing changes */
    size_t nt0;
    int64_t *before = tu_del3_canon(&d, &nt0);
    for (int i = 0; i < 20; i++) {
        int32_t v = -5;
        assert_int_equal(as_del3_insert(&d, p + 3 * i, 10000 + i, &v), AS_DEL3_DUPLICATE);
        assert_int_equal(v, vx[i]);
    }
    size_t nt1;
    int64_t *after = tu_del3_canon(&d, &nt1);
    assert_int_equal(nt0, nt1);
    assert_memory_equal(before, after, 4 * nt0 * sizeof *before);
    free(before);
    free(after);
    /* duplicates in the pending phase */
    as_del3_reset(&d);
    double a[3] = {1, 2, 3}, b[3] = {1, 2, 4};
    int32_t v;
    assert_int_equal(as_del3_insert(&d, a, 0, &v), ANISTAR_OK);
    assert_int_equal(as_del3_insert(&d, b, 1, &v), ANISTAR_OK);
    assert_int_equal(as_del3_insert(&d, a, 2, &v), AS_DEL3_DUPLICATE);
    assert_int_equal(v, 0);
    double bad[3] = {0, INFINITY, 0};
    assert_int_equal(as_del3_insert(&d, bad, 3, &v), ANISTAR_EINVAL);
    assert_int_equal(d.nv, 2);
    as_del3_destroy(&d);
    free(vx);
    free(p);
    fx_close(&f);
}

/* Collinear, then coplanar points stay pending; the first point off the plane builds the
 * triangulation of all of them (created = every tet, rebuilt = 1). */
static void test_pending(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    int id = 0;
    for (int i = 0; i < 10; i++) {
        double q[3] = {i, 2.0 * i, -1.0 * i};
        assert_int_equal(as_del3_insert(&d, q, id++, NULL), ANISTAR_OK);
        assert_false(d.dim3);
    }
    for (int i = 0; i < 30; i++) { /* the plane z = -x */
        double q[3] = {i % 6, (double)(i / 6) + 0.5, -(double)(i % 6)};
        assert_int_equal(as_del3_insert(&d, q, id++, NULL), ANISTAR_OK);
        assert_false(d.dim3);
    }
    assert_int_equal(d.nlive, 0);
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_OK);
    double off[3] = {1, 1, 1};
    assert_int_equal(as_del3_insert(&d, off, id++, NULL), ANISTAR_OK);
    assert_true(d.dim3);
    assert_int_equal(d.nv, 41);
    assert_int_equal(d.rebuilt, 1);
    assert_int_equal((int32_t)d.created.n, d.nlive);
    assert_int_equal(d.removed.n, 0);
    check_all(&d);
    /* the same points in another order: same triangulation */
    as_del3 e;
    as_del3_init(&e, f.ctx);
    assert_int_equal(as_del3_insert(&e, off, 40, NULL), ANISTAR_OK);
    for (int i = 29; i >= 0; i--) {
        double q[3] = {i % 6, (double)(i / 6) + 0.5, -(double)(i % 6)};
        assert_int_equal(as_del3_insert(&e, q, 10 + i, NULL), ANISTAR_OK);
    }
    for (int i = 0; i < 10; i++) {
        double q[3] = {i, 2.0 * i, -1.0 * i};
        assert_int_equal(as_del3_insert(&e, q, i, NULL), ANISTAR_OK);
    }
    check_all(&e);
    tu_del3_assert_same(&d, &e);
    as_del3_destroy(&e);
    as_del3_destroy(&d);
    fx_close(&f);
}

/* ---- brute force on small sets ------------------------------------------------------------ */

/* Every finite tet's perturbed sphere is empty of all other vertices, and the number of
 * finite tets equals the number of 4-subsets (not coplanar) with an empty perturbed
 * sphere. */
static void brute_force(as_del3 *d) {
    int n = d->nv;
    int32_t nf, ni;
    as_del3_count(d, &nf, &ni);
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t) || as_del3_is_infinite(d, t)) continue;
        const int32_t *v = as_del3_tet_vertices(d, t);
        for (int32_t w = 0; w < n; w++) {
            if (w == v[0] || w == v[1] || w == v[2] || w == v[3]) continue;
            int s = as_insphere_sos(as_del3_point(d, v[0]), as_del3_point(d, v[1]),
                                    as_del3_point(d, v[2]), as_del3_point(d, v[3]),
                                    as_del3_point(d, w), d->gid[v[0]], d->gid[v[1]],
                                    d->gid[v[2]], d->gid[v[3]], d->gid[w]);
            assert_int_equal(s, -1);
        }
    }
    int empty = 0;
    for (int a = 0; a < n; a++)
        for (int b = a + 1; b < n; b++)
            for (int c = b + 1; c < n; c++)
                for (int e = c + 1; e < n; e++) {
                    int q[4] = {a, b, c, e};
                    double o = as_orient3d(as_del3_point(d, a), as_del3_point(d, b),
                                           as_del3_point(d, c), as_del3_point(d, e));
                    if (o == 0) continue;
                    if (o < 0) {
                        q[0] = b;
                        q[1] = a;
                    }
                    int ok = 1;
                    for (int w = 0; w < n && ok; w++) {
                        if (w == a || w == b || w == c || w == e) continue;
                        ok = as_insphere_sos(as_del3_point(d, q[0]), as_del3_point(d, q[1]),
                                             as_del3_point(d, q[2]), as_del3_point(d, q[3]),
                                             as_del3_point(d, w), d->gid[q[0]], d->gid[q[1]],
                                             d->gid[q[2]], d->gid[q[3]], d->gid[w]) < 0;
                    }
                    empty += ok;
                }
    assert_int_equal(empty, nf);
}

static void test_brute_force(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {6};
    as_del3 d;
    /* random points */
    for (int rep = 0; rep < 3; rep++) {
        double *p = tu_pts_cube(&r, 30);
        build_check(&f, &d, p, 30, NULL);
        brute_force(&d);
        as_del3_destroy(&d);
        free(p);
    }
    /* the 3x3x3 grid */
    double g[81];
    for (int i = 0; i < 27; i++) {
        g[3 * i] = i % 3;
        g[3 * i + 1] = (i / 3) % 3;
        g[3 * i + 2] = i / 9;
    }
    build_check(&f, &d, g, 27, NULL);
    brute_force(&d);
    as_del3_destroy(&d);
    /* cospherical integer points (r = 9) with random ids, and a 2x3x4 grid */
    double s[3 * 200];
    int n = sphere_lattice(9, 1.0, s, 200);
    assert_true(n > 20 && n <= 200);
    if (n > 34) n = 34;
    int64_t gids[200];
    for (int i = 0; i < n; i++) gids[i] = (int64_t)(tu_rng_u64(&r) >> 2);
    as_del3_init(&d, f.ctx);
    assert_int_equal(as_del3_insert_points(&d, s, gids, n, NULL, NULL, NULL), ANISTAR_OK);
    check_all(&d);
    brute_force(&d);
    as_del3_destroy(&d);
    double h[72];
    for (int i = 0; i < 24; i++) {
        h[3 * i] = i % 2;
        h[3 * i + 1] = (i / 2) % 3;
        h[3 * i + 2] = i / 6;
    }
    build_check(&f, &d, h, 24, NULL);
    brute_force(&d);
    as_del3_destroy(&d);
    fx_close(&f);
}

/* ---- order independence, queries ---------------------------------------------------------- */

static void test_order_independence(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {7};
    int n = 800;
    double *p = tu_pts_sphere(&r, n);
    for (int i = 0; i < n / 2; i++) /* half on a sphere, half inside */
        for (int k = 0; k < 3; k++) p[3 * i + k] *= 0.5 + 0.5 * tu_rng_unit(&r);
    as_del3 a, b, c;
    build_check(&f, &a, p, n, NULL);
    as_del3_init(&b, f.ctx);
    as_del3_init(&c, f.ctx);
    as_del3_set_seed(&c, 99);
    for (int i = 0; i < n; i++) {
        assert_int_equal(as_del3_insert(&b, p + 3 * i, i, NULL), ANISTAR_OK);
        int j = n - 1 - i;
        assert_int_equal(as_del3_insert(&c, p + 3 * j, j, NULL), ANISTAR_OK);
    }
    check_all(&b);
    check_all(&c);
    tu_del3_assert_same(&a, &b);
    tu_del3_assert_same(&a, &c);
    as_del3_destroy(&a);
    as_del3_destroy(&b);
    as_del3_destroy(&c);
    free(p);
    fx_close(&f);
}

static int cmp_i32(const void *a, const void *b) {
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* The conflict zone query equals the brute-force set of tets in conflict (as_del3_in_sphere
 * over every live tet) and the set an insertion then removes; the created tets are exactly
 * the tets of the new vertex. Points inside, outside the hull, on hull planes and on
 * cospherical positions (a grid) are used. */
static void test_conflict_queries(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {8};
    as_del3 d;
    as_del3_init(&d, f.ctx);
    for (int i = 0; i < 64; i++) { /* 4x4x4 grid */
        double q[3] = {i % 4, (i / 4) % 4, i / 16};
        assert_int_equal(as_del3_insert(&d, q, i, NULL), ANISTAR_OK);
    }
    as_del3_buf zone = {0}, brute = {0}, tets = {0};
    for (int k = 0; k < 300; k++) {
        double q[3];
        int kind = k % 4;
        for (int i = 0; i < 3; i++) {
            if (kind == 0) q[i] = tu_rng_range(&r, -1, 4); /* anywhere */
            else q[i] = (double)(tu_rng_u64(&r) % 11) * 0.5 - 1; /* half-integers: on planes */
        }
        if (kind == 3) q[2] = 3 + (double)(tu_rng_u64(&r) % 3); /* hull plane z = 3 and above */
        int64_t g = 1000 + k;
        int32_t dupv;
        int rc = as_del3_conflict_zone(&d, q, g, -1, &zone, &dupv);
        if (rc == AS_DEL3_DUPLICATE) {
            assert_true(same_xyz(as_del3_point(&d, dupv), q));
            continue;
        }
        assert_int_equal(rc, ANISTAR_OK);
        brute.n = 0;
        for (int32_t t = 0; t < d.nt; t++)
            if (as_del3_is_live(&d, t) && as_del3_in_sphere(&d, t, q, g)) {
                if (brute.n == brute.cap) {
                    brute.cap = brute.cap ? 2 * brute.cap : 64;
                    brute.a = realloc(brute.a, brute.cap * sizeof *brute.a);
                }
                brute.a[brute.n++] = t;
            }
        qsort(zone.a, zone.n, sizeof *zone.a, cmp_i32);
        assert_int_equal(zone.n, brute.n);
        assert_memory_equal(zone.a, brute.a, zone.n * sizeof *zone.a);
        int32_t v;
        assert_int_equal(as_del3_insert(&d, q, g, &v), ANISTAR_OK);
        qsort(d.removed.a, d.removed.n, sizeof *d.removed.a, cmp_i32);
        assert_int_equal(d.removed.n, zone.n);
        assert_memory_equal(d.removed.a, zone.a, zone.n * sizeof *zone.a);
        assert_int_equal(as_del3_vertex_tets(&d, v, &tets), ANISTAR_OK);
        qsort(tets.a, tets.n, sizeof *tets.a, cmp_i32);
        qsort(d.created.a, d.created.n, sizeof *d.created.a, cmp_i32);
        assert_int_equal(tets.n, d.created.n);
        assert_memory_equal(tets.a, d.created.a, tets.n * sizeof *tets.a);
        if (k % 50 == 0) check_all(&d);
    }
    check_all(&d);
    as_del3_buf_free(f.ctx, &zone);
    as_del3_buf_free(f.ctx, &tets);
    free(brute.a);
    as_del3_destroy(&d);
    fx_close(&f);
}

/* Incident tets and facets of every vertex against a scan of all tets. */
static void test_vertex_queries(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {9};
    double *p = tu_pts_cube(&r, 400);
    as_del3 d;
    build_check(&f, &d, p, 400, NULL);
    as_del3_buf tets = {0}, facets = {0};
    int64_t *keys = malloc(4 * (size_t)d.nt * sizeof *keys);
    for (int32_t v = 0; v < d.nv; v++) {
        assert_int_equal(as_del3_vertex_tets(&d, v, &tets), ANISTAR_OK);
        size_t cnt = 0;
        for (int32_t t = 0; t < d.nt; t++) {
            if (!as_del3_is_live(&d, t)) continue;
            const int32_t *tv = as_del3_tet_vertices(&d, t);
            cnt += tv[0] == v || tv[1] == v || tv[2] == v || tv[3] == v;
        }
        assert_int_equal(tets.n, cnt);
        assert_int_equal(as_del3_vertex_facets(&d, v, &facets), ANISTAR_OK);
        /* each facet: holds v, finite, unique (as a vertex triple), and its mirror agrees */
        size_t nk = 0;
        for (size_t k = 0; k < facets.n; k++) {
            int32_t fc = facets.a[k], t = fc >> 2, i = fc & 3;
            int64_t tri[4];
            int m = 0, hasv = 0;
            for (int j = 0; j < 4; j++) {
                if (j == i) continue;
                int32_t w = as_del3_tet_vertex(&d, t, j);
                assert_true(w >= 0);
                hasv |= w == v;
                tri[m++] = w;
            }
            assert_true(hasv);
            int32_t mir = as_del3_mirror(&d, fc);
            assert_int_equal(as_del3_mirror(&d, mir), fc);
            tri[3] = -1;
            tu_sort4(tri);
            keys[nk++] = (tri[1] * d.nv + tri[2]) * d.nv + tri[3];
        }
        size_t before = nk;
        assert_int_equal(tu_count_unique(keys, nk), (int64_t)before);
        /* brute force: distinct finite faces holding v */
        nk = 0;
        for (int32_t t = 0; t < d.nt; t++) {
            if (!as_del3_is_live(&d, t)) continue;
            const int32_t *tv = as_del3_tet_vertices(&d, t);
            for (int i = 0; i < 4; i++) {
                int64_t tri[4];
                int m = 0, ok = 0, fin = 1;
                for (int j = 0; j < 4; j++) {
                    if (j == i) continue;
                    fin &= tv[j] >= 0;
                    ok |= tv[j] == v;
                    tri[m++] = tv[j];
                }
                if (!ok || !fin) continue;
                tri[3] = -1;
                tu_sort4(tri);
                keys[nk++] = (tri[1] * d.nv + tri[2]) * d.nv + tri[3];
            }
        }
        assert_int_equal(tu_count_unique(keys, nk), (int64_t)facets.n);
    }
    free(keys);
    as_del3_buf_free(f.ctx, &tets);
    as_del3_buf_free(f.ctx, &facets);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* ---- circumcenters against GMP ----------------------------------------------------------- */

/* Exact circumcenter of a, b, c, e by Cramer's rule on rationals: rel error of the
 * computed center c, relative to the circumradius. */
static double circum_error(const double *a, const double *b, const double *c, const double *e,
                           const double *got) {
    mpq_t m[3][3], rhs[3], det, tmp, tmp2, x[3];
    const double *pts[3] = {b, c, e};
    for (int i = 0; i < 3; i++) {
        mpq_init(rhs[i]);
        mpq_init(x[i]);
        for (int j = 0; j < 3; j++) mpq_init(m[i][j]);
    }
    mpq_inits(det, tmp, tmp2, NULL);
    for (int i = 0; i < 3; i++) { /* 2 (p - a) . x = |p|^2 - |a|^2 */
        for (int j = 0; j < 3; j++) {
            mpq_set_d(tmp, pts[i][j]);
            mpq_set_d(tmp2, a[j]);
            mpq_sub(m[i][j], tmp, tmp2);
            mpq_add(m[i][j], m[i][j], m[i][j]);
            mpq_set_d(tmp, pts[i][j]);
            mpq_mul(tmp, tmp, tmp);
            mpq_add(rhs[i], rhs[i], tmp);
            mpq_set_d(tmp2, a[j]);
            mpq_mul(tmp2, tmp2, tmp2);
            mpq_sub(rhs[i], rhs[i], tmp2);
        }
    }
    /* det3 by cofactors; x_k = det(m with column k = rhs) / det */
    mpq_t cols[3][3];
    for (int k = -1; k < 3; k++) {
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                mpq_init(cols[i][j]);
                mpq_set(cols[i][j], j == k ? rhs[i] : m[i][j]);
            }
        mpq_t acc;
        mpq_init(acc);
        for (int j = 0; j < 3; j++) {
            int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
            mpq_mul(tmp, cols[1][j1], cols[2][j2]);
            mpq_mul(tmp2, cols[1][j2], cols[2][j1]);
            mpq_sub(tmp, tmp, tmp2);
            mpq_mul(tmp, tmp, cols[0][j]);
            mpq_add(acc, acc, tmp);
        }
        if (k < 0) mpq_set(det, acc);
        else mpq_div(x[k], acc, det);
        mpq_clear(acc);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) mpq_clear(cols[i][j]);
    }
    double err = 0, rad = 0;
    for (int k = 0; k < 3; k++) {
        mpq_set_d(tmp, got[k]);
        mpq_sub(tmp, tmp, x[k]);
        double dk = fabs(mpq_get_d(tmp));
        err += dk * dk;
        mpq_set_d(tmp, a[k]);
        mpq_sub(tmp, tmp, x[k]);
        double rk = mpq_get_d(tmp);
        rad += rk * rk;
    }
    for (int i = 0; i < 3; i++) {
        mpq_clear(rhs[i]);
        mpq_clear(x[i]);
        for (int j = 0; j < 3; j++) mpq_clear(m[i][j]);
    }
    mpq_clears(det, tmp, tmp2, NULL);
    return sqrt(err) / sqrt(rad);
}

static void test_circumcenter(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {10};
    as_del3 d;
    as_del3_init(&d, f.ctx);
    double worst = 0;
    int flat_cases = 0;
    for (int rep = 0; rep < 400; rep++) {
        as_del3_reset(&d);
        double q[4][3];
        for (int i = 0; i < 3; i++)
            for (int k = 0; k < 3; k++) q[i][k] = 100 + tu_rng_range(&r, -1, 1);
        /* the fourth point: random, or at relative height 10^-(rep % 20) above the
         * plane of the first three (nearly flat tets) */
        double h = pow(10.0, -(double)(rep % 20));
        double w1 = tu_rng_unit(&r), w2 = tu_rng_unit(&r);
        double e1[3], e2[3], nrm[3];
        for (int k = 0; k < 3; k++) {
            e1[k] = q[1][k] - q[0][k];
            e2[k] = q[2][k] - q[0][k];
        }
        nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
        nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
        nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double nn = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
        for (int k = 0; k < 3; k++)
            q[3][k] = q[0][k] + w1 * (q[1][k] - q[0][k]) + w2 * (q[2][k] - q[0][k]) +
                      h * nrm[k] / nn;
        int ok = 1;
        for (int i = 0; i < 4 && ok; i++) ok = as_del3_insert(&d, q[i], i, NULL) == ANISTAR_OK;
        if (!ok || !d.dim3) continue; /* rounded onto the plane */
        for (int32_t t = 0; t < d.nt; t++) {
            if (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t)) continue;
            double c[3];
            assert_int_equal(as_del3_circumcenter(&d, t, c), 0);
            const int32_t *tv = as_del3_tet_vertices(&d, t);
            double err = circum_error(as_del3_point(&d, tv[0]), as_del3_point(&d, tv[1]),
                                      as_del3_point(&d, tv[2]), as_del3_point(&d, tv[3]), c);
            if (err > worst) worst = err;
            flat_cases += h < 1e-12;
            if (!(err < 0x1p-40 || (h < 1e-16 && err < 0x1p-30)))
                fail_msg("circumcenter error %.3e at height %.1e", err, h);
        }
        int32_t inf = -1;
        for (int32_t t = 0; t < d.nt && inf < 0; t++)
            if (as_del3_is_live(&d, t) && as_del3_is_infinite(&d, t)) inf = t;
        double c[3];
        assert_int_equal(as_del3_circumcenter(&d, inf, c), -1);
    }
    assert_true(flat_cases > 50);
    assert_true(worst < 0x1p-30);
    /* The hardest tets: four nearly cocircular points (integer points of the circle
     * x^2 + y^2 = 65^2 scaled by 2^45, the fourth lifted by 2^-20; exact coordinates):
     * kappa ~ 2^72 and the center near the plane, so the numerators cancel far beyond
     * double-double; the exact tier must still give a few ulps. */
    static const int circ[12][2] = {{16, 63}, {25, 60}, {33, 56}, {39, 52}, {52, 39}, {56, 33},
                                    {60, 25}, {63, 16}, {-16, 63}, {-33, -56}, {-60, 25}, {0, -65}};
    for (int rep = 0; rep < 60; rep++) {
        as_del3_reset(&d);
        int pick[4], np = 0;
        while (np < 4) {
            int k = (int)(tu_rng_u64(&r) % 12), dup = 0;
            for (int j = 0; j < np; j++) dup |= pick[j] == k;
            if (!dup) pick[np++] = k;
        }
        double shift[3] = {ldexp((double)(tu_rng_u64(&r) % 1000), 40),
                           ldexp((double)(tu_rng_u64(&r) % 1000), 40), 0};
        for (int i = 0; i < 4; i++) {
            double q[3] = {ldexp(circ[pick[i]][0], 45) + shift[0],
                           ldexp(circ[pick[i]][1], 45) + shift[1], i == 3 ? 0x1p-20 : 0.0};
            assert_int_equal(as_del3_insert(&d, q, i, NULL), ANISTAR_OK);
        }
        assert_true(d.dim3);
        for (int32_t t = 0; t < d.nt; t++) {
            if (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t)) continue;
            double c[3];
            assert_int_equal(as_del3_circumcenter(&d, t, c), 0);
            const int32_t *tv = as_del3_tet_vertices(&d, t);
            double err = circum_error(as_del3_point(&d, tv[0]), as_del3_point(&d, tv[1]),
                                      as_del3_point(&d, tv[2]), as_del3_point(&d, tv[3]), c);
            if (!(err < 0x1p-50)) fail_msg("cocircular tets: circumcenter error %.3e", err);
        }
    }
    as_del3_destroy(&d);
    fx_close(&f);
}

/* ---- the validators themselves ------------------------------------------------------------ */

/* Global emptiness (the definition, not the local test): no vertex in conflict with any tet
 * by the rule of del3.c, checked with the library predicates directly. */
static int globally_delaunay(const as_del3 *d) {
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t)) continue;
        const int32_t *v = as_del3_tet_vertices(d, t);
        for (int32_t w = 0; w < d->nv; w++) {
            if (w == v[0] || w == v[1] || w == v[2] || w == v[3]) continue;
            if (as_del3_in_sphere(d, t, as_del3_point(d, w), d->gid[w])) return 0;
        }
    }
    return 1;
}

static void test_validators(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {14};
    double *p = tu_pts_cube(&r, 50);
    as_del3 d;
    build_check(&f, &d, p, 50, NULL);
    assert_true(globally_delaunay(&d));
    /* combinatorial corruptions are caught */
    int32_t t = 0;
    while (!as_del3_is_live(&d, t) || as_del3_is_infinite(&d, t)) t++;
    int32_t *tv = d.tet + 8 * t, s0 = tv[0];
    tv[0] = tv[1];
    tv[1] = s0; /* reversed orientation */
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
    tv[1] = tv[0];
    tv[0] = s0;
    int32_t a0 = tv[4];
    tv[4] = tv[5]; /* a wrong neighbour */
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
    tv[4] = a0;
    int32_t vt = d.vert[3].tet;
    d.vert[3].tet = as_del3_neighbor(&d, vt, 0); /* a tet that may not hold vertex 3 */
    const int32_t *w = as_del3_tet_vertices(&d, d.vert[3].tet);
    if (w[0] != 3 && w[1] != 3 && w[2] != 3 && w[3] != 3)
        assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
    d.vert[3].tet = vt;
    d.mark[t] = 1; /* a mark left behind */
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
    d.mark[t] = 0;
    d.vert[5].loc = 2; /* a cavity-local number left behind */
    assert_int_equal(as_del3_check_combinatorics(&d), ANISTAR_EINTERNAL);
    d.vert[5].loc = -1;
    check_all(&d);
    /* Moving a vertex: whenever the tets stay positive, the local test must agree with the
     * global definition; both outcomes must occur. */
    int valid = 0, invalid = 0;
    for (int trial = 0; trial < 300; trial++) {
        int32_t v = (int32_t)(tu_rng_u64(&r) % 50);
        double *x = d.vert[v].x, save[3] = {x[0], x[1], x[2]};
        for (int k = 0; k < 3; k++) x[k] += tu_rng_range(&r, -0.08, 0.08);
        as_del3_forget_spheres(&d); /* the cached spheres of v's tets are stale */
        if (as_del3_check_combinatorics(&d) == ANISTAR_OK) {
            int local = as_del3_check_delaunay(&d) == ANISTAR_OK;
            assert_int_equal(local, globally_delaunay(&d));
            valid += local;
            invalid += !local;
        }
        memcpy(x, save, sizeof save);
        as_del3_forget_spheres(&d);
    }
    assert_true(valid > 0 && invalid > 0);
    check_all(&d);
    as_del3_destroy(&d);
    free(p);
    fx_close(&f);
}

/* ---- reset, determinism, allocation failures --------------------------------------------- */

static void test_reset_determinism(void **state) {
    (void)state;
    fixture f;
    fx_open(&f, -1);
    tu_rng r = {12};
    int n = 3000;
    double *p = tu_pts_torus(&r, n, 1, 0.25);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    assert_int_equal(as_del3_insert_points(&d, p, NULL, n, NULL, NULL, NULL), ANISTAR_OK);
    for (int i = 0; i < 50; i++) { /* plus single insertions */
        double q[3] = {tu_rng_range(&r, -1, 1), tu_rng_range(&r, -1, 1), 0};
        assert_int_equal(as_del3_insert(&d, q, n + i, NULL), ANISTAR_OK);
    }
    size_t nt = (size_t)d.nt, nv = (size_t)d.nv;
    int32_t *tv = malloc(8 * nt * sizeof *tv);
    as_del3_vertex *vx = malloc(nv * sizeof *vx);
    assert_true(tv && vx);
    memcpy(tv, d.tet, 8 * nt * sizeof *tv);
    memcpy(vx, d.vert, nv * sizeof *vx);
    long allocs = f.al.count;
    size_t bytes = f.al.live_bytes;
    tu_rng r2 = {12};
    double *p2 = tu_pts_torus(&r2, n, 1, 0.25);
    assert_memory_equal(p, p2, 3 * (size_t)n * sizeof *p);
    as_del3_reset(&d);
    assert_int_equal(d.nv, 0);
    assert_int_equal(d.nlive, 0);
    assert_int_equal(as_del3_insert_points(&d, p2, NULL, n, NULL, NULL, NULL), ANISTAR_OK);
    for (int i = 0; i < 50; i++) {
        double q[3] = {tu_rng_range(&r2, -1, 1), tu_rng_range(&r2, -1, 1), 0};
        assert_int_equal(as_del3_insert(&d, q, n + i, NULL), ANISTAR_OK);
    }
    assert_int_equal((size_t)d.nt, nt);
    assert_memory_equal(tv, d.tet, 8 * nt * sizeof *tv);
    assert_memory_equal(vx, d.vert, nv * sizeof *vx);
    /* only the bulk insertion's temporary arrays were allocated again */
    assert_true(f.al.count - allocs <= 4);
    assert_int_equal(f.al.live_bytes, bytes);
    check_all(&d);
    free(tv);
    free(vx);
    free(p);
    free(p2);
    as_del3_destroy(&d);
    fx_close(&f);
}

/* With the k-th allocation (and every later one) failing, for every k up to the total of a
 * successful run: each call returns ANISTAR_OK or ANISTAR_ENOMEM, an ENOMEM insertion
 * leaves the triangulation unchanged and valid, nothing leaks. */
static void run_alloc_case(long k, const double *p, int n, long *total) {
    fixture f;
    fx_open(&f, k);
    as_del3 d;
    as_del3_init(&d, f.ctx);
    int failures = 0, zone_fail = 0;
    as_del3_buf zone = {0};
    for (int i = 0; i < n; i++) {
        int32_t nv0 = d.nv, nl0 = d.nlive;
        int rc = as_del3_insert(&d, p + 3 * i, i, NULL);
        if (rc == ANISTAR_ENOMEM) {
            failures++;
            assert_int_equal(d.nv, nv0);
            assert_int_equal(d.nlive, nl0);
        } else {
            assert_int_equal(rc, ANISTAR_OK);
        }
        if (d.dim3 && i % 16 == 0) {
            double q[3] = {p[3 * i] * 0.5, p[3 * i + 1] * 0.5, 0.25};
            rc = as_del3_conflict_zone(&d, q, 100000 + i, -1, &zone, NULL);
            assert_true(rc == ANISTAR_OK || rc == ANISTAR_ENOMEM || rc == AS_DEL3_DUPLICATE);
            zone_fail |= rc == ANISTAR_ENOMEM;
        }
    }
    int32_t *vx = malloc((size_t)n * sizeof *vx);
    as_del3 b;
    as_del3_init(&b, f.ctx);
    anistar_status st = as_del3_insert_points(&b, p, NULL, n, NULL, vx, NULL);
    assert_true(st == ANISTAR_OK || st == ANISTAR_ENOMEM);
    long fail_after = f.al.fail_after;
    f.al.fail_after = -1; /* the validators allocate too */
    check_all(&d);
    check_all(&b);
    if (st == ANISTAR_OK) {
        assert_int_equal(b.nv, n);
    } else {
        int inserted = 0;
        for (int i = 0; i < n; i++) inserted += vx[i] >= 0;
        assert_int_equal(inserted, b.nv);
    }
    free(vx);
    /* an allocation that failed was reported by the call that made it */
    if (f.al.failures > 0) assert_true(failures > 0 || st == ANISTAR_ENOMEM || zone_fail);
    if (fail_after < 0) *total = f.al.count - f.base;
    as_del3_buf_free(f.ctx, &zone);
    as_del3_destroy(&d);
    as_del3_destroy(&b);
    fx_close(&f);
}

static void test_alloc_failures(void **state) {
    (void)state;
    tu_rng r = {13};
    int n = 300;
    double *p = tu_pts_cube(&r, n);
    for (int i = 0; i < 6; i++) p[3 * i + 2] = 0; /* a coplanar start: the pending phase */
    long total = 0;
    run_alloc_case(-1, p, n, &total);
    assert_true(total > 10);
    for (long k = 0; k <= total; k++) {
        long dummy = 0;
        run_alloc_case(k, p, n, &dummy);
    }
    free(p);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_hilbert),
        cmocka_unit_test(test_sort),
        cmocka_unit_test(test_random_cube),
        cmocka_unit_test(test_shrink),
        cmocka_unit_test(test_sphere_torus),
        cmocka_unit_test(test_grid),
        cmocka_unit_test(test_cospherical),
        cmocka_unit_test(test_stretched),
        cmocka_unit_test(test_star_like),
        cmocka_unit_test(test_tight_growth),
        cmocka_unit_test(test_duplicates),
        cmocka_unit_test(test_pending),
        cmocka_unit_test(test_brute_force),
        cmocka_unit_test(test_order_independence),
        cmocka_unit_test(test_conflict_queries),
        cmocka_unit_test(test_vertex_queries),
        cmocka_unit_test(test_circumcenter),
        cmocka_unit_test(test_validators),
        cmocka_unit_test(test_sphere_filter),
        cmocka_unit_test(test_insphere_filter),
        cmocka_unit_test(test_reset_determinism),
        cmocka_unit_test(test_alloc_failures),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
