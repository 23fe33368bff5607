/*
 * test_kdtree — the kd-tree forest (lib/geom/kdtree.c): k-nearest, radius and box queries
 * equal brute force on many point distributions (uniform, clustered, duplicates, all
 * identical, collinear, integer grids with many distance ties, 0 and 1 point), for static
 * builds and for incremental insertion interleaved with queries; selection; the
 * farthest-point order against the quadratic scan; invalid input;
 * allocation-failure injection (ENOMEM, tree unchanged, no leak).
 */
#include "test_util.h"

#include "core.h"
#include "geom/kdtree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- point sets ------------------------------------------------------------------------ */

enum { DIST_UNIFORM, DIST_CLUSTER, DIST_DUP, DIST_SAME, DIST_LINE, DIST_GRID, DIST_COUNT };

static void gen_points(tu_rng *r, int dist, size_t n, double *xyz) {
    double centers[5][3];
    for (int c = 0; c < 5; c++)
        for (int a = 0; a < 3; a++) centers[c][a] = tu_rng_range(r, -10, 10);
    double dir[3] = {tu_rng_range(r, -1, 1), tu_rng_range(r, -1, 1), tu_rng_range(r, -1, 1)};
    for (size_t i = 0; i < n; i++) {
        double *p = xyz + 3 * i;
        switch (dist) {
        case DIST_UNIFORM:
            for (int a = 0; a < 3; a++) p[a] = tu_rng_range(r, -1, 1);
            break;
        case DIST_CLUSTER: {
            int c = (int)(tu_rng_u64(r) % 5);
            double s = (c == 0) ? 1e-6 : 0.05 * (c + 1);
            for (int a = 0; a < 3; a++)
                p[a] = centers[c][a] + s * (tu_rng_unit(r) + tu_rng_unit(r) - 1);
            break;
        }
        case DIST_DUP:
            if (i > 0 && tu_rng_unit(r) < 0.7) {
                size_t j = (size_t)(tu_rng_u64(r) % i);
                memcpy(p, xyz + 3 * j, 3 * sizeof *p);
            } else {
                for (int a = 0; a < 3; a++) p[a] = tu_rng_range(r, -1, 1);
            }
            break;
        case DIST_SAME:
            p[0] = 0.25;
            p[1] = -3;
            p[2] = 7;
            break;
        case DIST_LINE: {
            double t = tu_rng_range(r, -5, 5);
            for (int a = 0; a < 3; a++) p[a] = 1 + t * dir[a];
            break;
        }
        default: /* DIST_GRID: small integer grid, many equal distances */
            for (int a = 0; a < 3; a++) p[a] = (double)(tu_rng_u64(r) % 5);
            break;
        }
    }
}

static void gen_query(tu_rng *r, const double *xyz, size_t n, double q[3]) {
    double u = tu_rng_unit(r);
    if (n > 0 && u < 0.3) { /* a data point itself */
        memcpy(q, xyz + 3 * (tu_rng_u64(r) % n), 3 * sizeof *q);
    } else if (u < 0.45) { /* integer point (ties on the grid set) */
        for (int a = 0; a < 3; a++) q[a] = (double)(tu_rng_u64(r) % 7) - 1;
    } else if (u < 0.5) { /* far away */
        for (int a = 0; a < 3; a++) q[a] = tu_rng_range(r, -1e3, 1e3);
    } else {
        for (int a = 0; a < 3; a++) q[a] = tu_rng_range(r, -2, 2);
    }
}

/* ---- brute force ------------------------------------------------------------------------ */

static double d2_of(const double *x, const double *q) {
    double dx = x[0] - q[0], dy = x[1] - q[1], dz = x[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

typedef struct cand {
    double d2;
    int32_t id;
} cand;

static int cand_cmp(const void *a, const void *b) {
    const cand *x = a, *y = b;
    if (x->d2 < y->d2) return -1;
    if (x->d2 > y->d2) return 1;
    return (x->id > y->id) - (x->id < y->id);
}

static size_t brute_knn(const double *xyz, const int32_t *ids, size_t n, const double q[3],
                        size_t k, cand *work, int32_t *oid, double *od2) {
    for (size_t i = 0; i < n; i++) {
        work[i].d2 = d2_of(xyz + 3 * i, q);
        work[i].id = ids[i];
    }
    qsort(work, n, sizeof *work, cand_cmp);
    size_t m = k < n ? k : n;
    for (size_t i = 0; i < m; i++) {
        oid[i] = work[i].id;
        od2[i] = work[i].d2;
    }
    return m;
}

static int id_cmp(const void *a, const void *b) {
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* mode 0: ball (q, r); mode 1: box (lo, hi). */
static size_t brute_range(const double *xyz, const int32_t *ids, size_t n, int mode,
                          const double q[3], double r, const double lo[3],
                          const double hi[3], int32_t *out) {
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        const double *x = xyz + 3 * i;
        int in;
        if (mode == 0) {
            in = d2_of(x, q) <= r * r;
        } else {
            in = 1;
            for (int a = 0; a < 3; a++)
                if (x[a] < lo[a] || x[a] > hi[a]) in = 0;
        }
        if (in) out[m++] = ids[i];
    }
    qsort(out, m, sizeof *out, id_cmp);
    return m;
}

/* ---- comparison of one tree with brute force -------------------------------------------- */

typedef struct scratch {
    cand *work;
    int32_t *bid, *kid, *rid;
    double *bd2, *kd2;
    size_t cap;
} scratch;

static void scratch_init(scratch *s, size_t cap) {
    s->cap = cap + 80;
    s->work = malloc(s->cap * sizeof *s->work);
    s->bid = malloc(s->cap * sizeof *s->bid);
    s->kid = malloc(s->cap * sizeof *s->kid);
    s->rid = malloc(s->cap * sizeof *s->rid);
    s->bd2 = malloc(s->cap * sizeof *s->bd2);
    s->kd2 = malloc(s->cap * sizeof *s->kd2);
    assert_non_null(s->work);
    assert_non_null(s->bid);
    assert_non_null(s->kid);
    assert_non_null(s->rid);
    assert_non_null(s->bd2);
    assert_non_null(s->kd2);
}

static void scratch_free(scratch *s) {
    free(s->work);
    free(s->bid);
    free(s->kid);
    free(s->rid);
    free(s->bd2);
    free(s->kd2);
}

/* nq random queries of each kind on kd against the brute force over (xyz, ids, n). */
static void compare_queries(anistar_context *ctx, const as_kdtree *kd, const double *xyz,
                            const int32_t *ids, size_t n, tu_rng *r, int nq, scratch *s) {
    static const size_t ks[] = {1, 2, 5, 16, 20, 64};
    as_idlist out = {0};
    assert_int_equal(as_kdtree_size(kd), n);
    for (int iq = 0; iq < nq; iq++) {
        double q[3];
        gen_query(r, xyz, n, q);
        /* k nearest: several k, including k > n */
        size_t k = ks[tu_rng_u64(r) % 6];
        if (tu_rng_unit(r) < 0.1) k = n + 3;
        if (k > s->cap) k = s->cap;
        size_t mb = brute_knn(xyz, ids, n, q, k, s->work, s->bid, s->bd2);
        size_t mk = as_kdtree_knn(kd, q, k, s->kid, s->kd2);
        assert_int_equal(mk, mb);
        for (size_t i = 0; i < mk; i++) {
            assert_int_equal(s->kid[i], s->bid[i]);
            assert_true(s->kd2[i] == s->bd2[i]);
        }
        /* radius: around a typical neighbour distance, sometimes 0 or huge */
        double rad = tu_rng_range(r, 0, 0.6);
        double u = tu_rng_unit(r);
        if (u < 0.1) rad = 0;
        else if (u < 0.15) rad = 1e4;
        else if (u < 0.3 && mb > 0) rad = sqrt(s->bd2[mb / 2]); /* exactly on a point */
        size_t m = brute_range(xyz, ids, n, 0, q, rad, NULL, NULL, s->bid);
        assert_int_equal(as_kdtree_radius(ctx, kd, q, rad, &out), ANISTAR_OK);
        assert_int_equal(out.n, m);
        for (size_t i = 0; i < m; i++) assert_int_equal(out.ids[i], s->bid[i]);
        /* box: random, sometimes degenerate or with faces through data points */
        double lo[3], hi[3];
        for (int a = 0; a < 3; a++) {
            double c = q[a], h = tu_rng_range(r, 0, 0.8);
            if (tu_rng_unit(r) < 0.1) h = 0;
            lo[a] = c - h;
            hi[a] = c + h * tu_rng_unit(r);
        }
        if (n > 0 && tu_rng_unit(r) < 0.3) {
            const double *x = xyz + 3 * (tu_rng_u64(r) % n);
            lo[0] = x[0];
            hi[1] = x[1];
            if (lo[0] > hi[0]) hi[0] = lo[0];
            if (hi[1] < lo[1]) lo[1] = hi[1];
        }
        m = brute_range(xyz, ids, n, 1, NULL, 0, lo, hi, s->bid);
        assert_int_equal(as_kdtree_box(ctx, kd, lo, hi, &out), ANISTAR_OK);
        assert_int_equal(out.n, m);
        for (size_t i = 0; i < m; i++) assert_int_equal(out.ids[i], s->bid[i]);
    }
    /* negative or NaN radius: empty */
    double q0[3] = {0, 0, 0};
    assert_int_equal(as_kdtree_radius(ctx, kd, q0, -1, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    assert_int_equal(as_kdtree_radius(ctx, kd, q0, NAN, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    /* non-finite query point, empty and NaN boxes: nothing */
    double qn[3] = {0, NAN, 0};
    assert_int_equal(as_kdtree_radius(ctx, kd, qn, 1e9, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    int32_t kid[4];
    double kd2[4];
    assert_int_equal(as_kdtree_knn(kd, qn, 4, kid, kd2), 0);
    double blo[3] = {-1e9, -1e9, -1e9}, bhi[3] = {1e9, 1e9, 1e9};
    bhi[2] = -2e9;
    assert_int_equal(as_kdtree_box(ctx, kd, blo, bhi, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    bhi[2] = NAN;
    assert_int_equal(as_kdtree_box(ctx, kd, blo, bhi, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    as_idlist_free(ctx, &out);
}

/* ---- tests -------------------------------------------------------------------------------- */

static void test_select(void **state) {
    (void)state;
    tu_rng r = {11};
    for (int it = 0; it < 300; it++) {
        size_t n = 1 + (size_t)(tu_rng_u64(&r) % 400);
        as_kdpoint *a = malloc(n * sizeof *a);
        assert_non_null(a);
        int levels = 1 + (int)(tu_rng_u64(&r) % 6); /* few distinct values: many ties */
        int sorted = (int)(tu_rng_u64(&r) % 3);      /* 0 random, 1 ascending, 2 descending */
        for (size_t i = 0; i < n; i++) {
            for (int d = 0; d < 3; d++) a[i].x[d] = (double)(tu_rng_u64(&r) % (uint64_t)(levels * 10));
            if (sorted == 1) a[i].x[1] = (double)i;
            if (sorted == 2) a[i].x[1] = -(double)i;
            a[i].id = (int32_t)i;
        }
        int axis = (int)(tu_rng_u64(&r) % 3);
        size_t k = (size_t)(tu_rng_u64(&r) % n);
        double sum_before = 0, sum_after = 0;
        for (size_t i = 0; i < n; i++) sum_before += a[i].x[axis] * (double)(a[i].id + 1);
        as_kdpoint_select(a, n, k, axis);
        for (size_t i = 0; i < k; i++) assert_true(a[i].x[axis] <= a[k].x[axis]);
        for (size_t i = k + 1; i < n; i++) assert_true(a[i].x[axis] >= a[k].x[axis]);
        /* a permutation of the records (records move whole) */
        char *seen = calloc(n, 1);
        assert_non_null(seen);
        for (size_t i = 0; i < n; i++) {
            assert_false(seen[a[i].id]);
            seen[a[i].id] = 1;
            sum_after += a[i].x[axis] * (double)(a[i].id + 1);
        }
        assert_true(sum_before == sum_after);
        free(seen);
        free(a);
    }
}

static void test_ids_sort(void **state) {
    (void)state;
    tu_rng r = {5};
    for (int it = 0; it < 100; it++) {
        size_t n = (size_t)(tu_rng_u64(&r) % 300);
        int32_t *a = malloc((n + 1) * sizeof *a), *b = malloc((n + 1) * sizeof *b);
        assert_non_null(a);
        assert_non_null(b);
        for (size_t i = 0; i < n; i++) a[i] = b[i] = (int32_t)(tu_rng_u64(&r) % 50);
        as_ids_sort(a, n);
        qsort(b, n, sizeof *b, id_cmp);
        for (size_t i = 0; i < n; i++) assert_int_equal(a[i], b[i]);
        free(a);
        free(b);
    }
}

static void test_static_queries(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    static const size_t sizes[] = {0, 1, 2, 15, 16, 17, 100, 1000, 4000};
    tu_rng r = {1234};
    scratch s;
    scratch_init(&s, 4000);
    double *xyz = malloc(3 * 4000 * sizeof *xyz);
    int32_t *ids = malloc(4000 * sizeof *ids);
    assert_non_null(xyz);
    assert_non_null(ids);
    for (int dist = 0; dist < DIST_COUNT; dist++) {
        for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++) {
            size_t n = sizes[si];
            gen_points(&r, dist, n, xyz);
            /* ids: identity, or a shuffled sparse set (ties broken by the caller's ids) */
            int custom = (int)(si % 2);
            for (size_t i = 0; i < n; i++) ids[i] = (int32_t)(custom ? 3 * (n - i) + 1 : i);
            as_kdtree *kd = NULL;
            assert_int_equal(as_kdtree_build(ctx, xyz, custom ? ids : NULL, n, &kd), ANISTAR_OK);
            if (!custom)
                for (size_t i = 0; i < n; i++) ids[i] = (int32_t)i;
            assert_int_equal(as_kdtree_check(kd), 0);
            assert_true(as_kdtree_tree_count(kd) == (n > 0 ? 1u : 0u));
            compare_queries(ctx, kd, xyz, ids, n, &r, n > 1000 ? 60 : 150, &s);
            as_kdtree_free(ctx, kd);
        }
    }
    free(xyz);
    free(ids);
    scratch_free(&s);
    anistar_context_free(ctx);
}

/* Insertion one point at a time, from empty or after a static build, with queries and
 * validation interleaved; the forest keeps its logarithmic shape. */
static void test_incremental(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    tu_rng r = {99};
    const size_t n = 3000;
    scratch s;
    scratch_init(&s, n);
    double *xyz = malloc(3 * n * sizeof *xyz);
    int32_t *ids = malloc(n * sizeof *ids);
    assert_non_null(xyz);
    assert_non_null(ids);
    for (int dist = 0; dist < DIST_COUNT; dist++) {
        for (int start = 0; start < 2; start++) {
            gen_points(&r, dist, n, xyz);
            for (size_t i = 0; i < n; i++) ids[i] = (int32_t)((i * 7919) % n); /* distinct */
            size_t n0 = start ? 37 + (size_t)dist * 100 : 0;
            as_kdtree *kd = NULL;
            if (start)
                assert_int_equal(as_kdtree_build(ctx, xyz, ids, n0, &kd), ANISTAR_OK);
            else
                assert_int_equal(as_kdtree_new(ctx, &kd), ANISTAR_OK);
            size_t next_check = n0 + 1;
            for (size_t i = n0; i < n; i++) {
                assert_int_equal(as_kdtree_insert(ctx, kd, xyz + 3 * i, ids[i]), ANISTAR_OK);
                if (i + 1 == next_check || i + 1 == n) {
                    assert_int_equal(as_kdtree_check(kd), 0);
                    compare_queries(ctx, kd, xyz, ids, i + 1, &r, 6, &s);
                    /* at most log2(size / leaf) + 2 trees */
                    size_t bound = 2;
                    for (size_t m = (i + 1) / AS_KD_LEAF; m > 1; m >>= 1) bound++;
                    assert_true(as_kdtree_tree_count(kd) <= bound);
                    next_check += 1 + next_check / 8;
                }
            }
            as_kdtree_free(ctx, kd);
        }
    }
    free(xyz);
    free(ids);
    scratch_free(&s);
    anistar_context_free(ctx);
}

/* The same point set inserted in two orders, and built statically, answers identically
 * (results depend on the set only). */
static void test_order_independence(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    tu_rng r = {7};
    const size_t n = 1500;
    double *xyz = malloc(3 * n * sizeof *xyz);
    assert_non_null(xyz);
    gen_points(&r, DIST_GRID, n, xyz);
    as_kdtree *a = NULL, *b = NULL, *c = NULL;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, n, &a), ANISTAR_OK);
    assert_int_equal(as_kdtree_new(ctx, &b), ANISTAR_OK);
    assert_int_equal(as_kdtree_new(ctx, &c), ANISTAR_OK);
    assert_int_equal(as_kdtree_reserve(ctx, c, n), ANISTAR_OK);
    for (size_t i = 0; i < n; i++) {
        assert_int_equal(as_kdtree_insert(ctx, b, xyz + 3 * i, (int32_t)i), ANISTAR_OK);
        size_t j = n - 1 - i;
        assert_int_equal(as_kdtree_insert(ctx, c, xyz + 3 * j, (int32_t)j), ANISTAR_OK);
    }
    int32_t ia[64], ib[64], ic[64];
    double da[64], db[64], dc[64];
    for (int it = 0; it < 300; it++) {
        double q[3];
        gen_query(&r, xyz, n, q);
        size_t k = 1 + (size_t)(tu_rng_u64(&r) % 64);
        size_t ma = as_kdtree_knn(a, q, k, ia, da);
        size_t mb = as_kdtree_knn(b, q, k, ib, db);
        size_t mc = as_kdtree_knn(c, q, k, ic, dc);
        assert_int_equal(ma, k);
        assert_int_equal(mb, k);
        assert_int_equal(mc, k);
        assert_memory_equal(ia, ib, k * sizeof *ia);
        assert_memory_equal(ia, ic, k * sizeof *ia);
        assert_memory_equal(da, dc, k * sizeof *da);
    }
    as_kdtree_free(ctx, a);
    as_kdtree_free(ctx, b);
    as_kdtree_free(ctx, c);
    free(xyz);
    anistar_context_free(ctx);
}

static void test_invalid(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    double xyz[6] = {0, 0, 0, 1, NAN, 0};
    as_kdtree *kd = (as_kdtree *)1;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, 2, &kd), ANISTAR_EINVAL);
    assert_null(kd);
    assert_true(strlen(anistar_last_error(ctx)) > 0);
    xyz[4] = INFINITY;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, 2, &kd), ANISTAR_EINVAL);
    xyz[4] = 0;
    int32_t bad[2] = {0, -4};
    assert_int_equal(as_kdtree_build(ctx, xyz, bad, 2, &kd), ANISTAR_EINVAL);
    assert_int_equal(as_kdtree_build(ctx, NULL, NULL, 2, &kd), ANISTAR_EINVAL);
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, 2, &kd), ANISTAR_OK);
    double p[3] = {NAN, 0, 0};
    assert_int_equal(as_kdtree_insert(ctx, kd, p, 5), ANISTAR_EINVAL);
    p[0] = 0;
    assert_int_equal(as_kdtree_insert(ctx, kd, p, -1), ANISTAR_EINVAL);
    assert_int_equal(as_kdtree_size(kd), 2);
    int32_t id[2];
    double d2[2];
    assert_int_equal(as_kdtree_knn(kd, p, 0, id, d2), 0);
    as_kdtree_free(ctx, kd);
    as_kdtree_free(ctx, NULL);
    anistar_context_free(ctx);
}

/* as_farthest_order against the quadratic scan it replaces (every distance updated after
 * each pick, the first maximum taken), on every distribution (ties, duplicates, all points
 * equal), for several q; then allocation failures (ENOMEM, no leak). */
static void test_farthest_order(void **state) {
    (void)state;
    tu_alloc ta;
    tu_alloc_init(&ta, -1);
    anistar_allocator al = tu_allocator(&ta);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    tu_rng r = {17};
    const size_t sizes[] = {0, 1, 2, 7, 100, 1500};
    for (int dist = 0; dist < DIST_COUNT; dist++)
        for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++) {
            size_t n = sizes[si];
            double *xyz = malloc((3 * n + 3) * sizeof *xyz);
            double *d = malloc((n + 1) * sizeof *d);
            int32_t *want = malloc((n + 1) * sizeof *want), *got = malloc((n + 1) * sizeof *got);
            assert_true(xyz && d && want && got);
            gen_points(&r, dist, n, xyz);
            const size_t qs[] = {1, 3, n / 2, n, n + 5};
            for (size_t qi = 0; qi < sizeof qs / sizeof *qs; qi++) {
                size_t q = qs[qi], nw = 0;
                for (size_t i = 0; i < n; i++) d[i] = INFINITY;
                size_t cur = 0;
                while (n > 0 && nw < q) {
                    want[nw++] = (int32_t)cur;
                    d[cur] = -1;
                    const double *x = xyz + 3 * cur;
                    double far = -1;
                    size_t next = 0;
                    for (size_t i = 0; i < n; i++) {
                        if (d[i] < 0) continue;
                        double e0 = xyz[3 * i] - x[0], e1 = xyz[3 * i + 1] - x[1],
                               e2 = xyz[3 * i + 2] - x[2];
                        double dd = e0 * e0 + e1 * e1 + e2 * e2;
                        if (dd < d[i]) d[i] = dd;
                        if (d[i] > far) {
                            far = d[i];
                            next = i;
                        }
                    }
                    if (far < 0) break;
                    cur = next;
                }
                size_t ng = 99;
                assert_int_equal(as_farthest_order(ctx, xyz, n, q, got, &ng), ANISTAR_OK);
                assert_int_equal(ng, nw);
                for (size_t i = 0; i < nw; i++) assert_int_equal(got[i], want[i]);
            }
            if (n == 1500 && dist == DIST_UNIFORM) { /* failures at every allocation */
                long base = ta.live_blocks;
                for (long f = 0;; f++) {
                    size_t ng = 0;
                    ta.fail_after = ta.count + f;
                    anistar_status st = as_farthest_order(ctx, xyz, n, n / 3, got, &ng);
                    ta.fail_after = -1;
                    assert_int_equal(ta.live_blocks, base);
                    if (st == ANISTAR_OK) break;
                    assert_int_equal(st, ANISTAR_ENOMEM);
                }
            }
            free(xyz);
            free(d);
            free(want);
            free(got);
        }
    double bad[6] = {0, 0, 0, NAN, 1, 2};
    int32_t o[2];
    size_t no = 9;
    assert_int_equal(as_farthest_order(ctx, bad, 2, 2, o, &no), ANISTAR_EINVAL);
    assert_int_equal(as_farthest_order(ctx, bad, 2, 1, o, &no), ANISTAR_EINVAL);
    assert_int_equal(no, 0);
    anistar_context_free(ctx);
    assert_int_equal(ta.live_blocks, 0);
}

/* Allocation failures: every allocation of a build, of a run of insertions and of the
 * queries' result growth fails in turn; the call reports ENOMEM, the tree stays valid and
 * unchanged, and freeing leaves no block behind. */
static void test_alloc_failure(void **state) {
    (void)state;
    tu_alloc ta;
    tu_alloc_init(&ta, -1);
    anistar_allocator al = tu_allocator(&ta);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    long base_blocks = ta.live_blocks;
    size_t base_bytes = ta.live_bytes;
    tu_rng r = {3};
    const size_t n = 700;
    double *xyz = malloc(3 * n * sizeof *xyz);
    int32_t *ids = malloc(n * sizeof *ids);
    assert_non_null(xyz);
    assert_non_null(ids);
    gen_points(&r, DIST_UNIFORM, n, xyz);
    for (size_t i = 0; i < n; i++) ids[i] = (int32_t)i;
    scratch s;
    scratch_init(&s, n);

    /* static build */
    int built = 0;
    for (long f = 0; !built; f++) {
        ta.fail_after = ta.count + f;
        as_kdtree *kd = NULL;
        anistar_status st = as_kdtree_build(ctx, xyz, NULL, n, &kd);
        ta.fail_after = -1;
        if (st == ANISTAR_OK) {
            built = 1;
            compare_queries(ctx, kd, xyz, ids, n, &r, 5, &s);
            as_kdtree_free(ctx, kd);
        } else {
            assert_int_equal(st, ANISTAR_ENOMEM);
            assert_null(kd);
        }
        assert_int_equal(ta.live_blocks, base_blocks);
        assert_int_equal(ta.live_bytes, base_bytes);
    }

    /* insertions: the k-th allocation after creation fails */
    int finished = 0;
    for (long f = 0; !finished; f++) {
        as_kdtree *kd = NULL;
        ta.fail_after = ta.count + f;
        anistar_status st = as_kdtree_new(ctx, &kd);
        size_t inserted = 0;
        while (st == ANISTAR_OK && inserted < n) {
            st = as_kdtree_insert(ctx, kd, xyz + 3 * inserted, ids[inserted]);
            if (st == ANISTAR_OK) inserted++;
        }
        ta.fail_after = -1;
        if (st == ANISTAR_OK) {
            finished = 1;
        } else {
            assert_int_equal(st, ANISTAR_ENOMEM);
        }
        if (kd) {
            assert_int_equal(as_kdtree_check(kd), 0);
            compare_queries(ctx, kd, xyz, ids, inserted, &r, 3, &s);
            /* after a failure the tree keeps working */
            if (inserted < n) {
                assert_int_equal(as_kdtree_insert(ctx, kd, xyz + 3 * inserted, ids[inserted]),
                                 ANISTAR_OK);
                compare_queries(ctx, kd, xyz, ids, inserted + 1, &r, 2, &s);
            }
            as_kdtree_free(ctx, kd);
        }
        assert_int_equal(ta.live_blocks, base_blocks);
        assert_int_equal(ta.live_bytes, base_bytes);
    }

    /* after as_kdtree_reserve, insertions allocate nothing (every allocation would fail) */
    {
        as_kdtree *kr = NULL;
        assert_int_equal(as_kdtree_build(ctx, xyz, NULL, 100, &kr), ANISTAR_OK);
        assert_int_equal(as_kdtree_reserve(ctx, kr, n - 100), ANISTAR_OK);
        long failures_before = ta.failures;
        ta.fail_after = ta.count;
        for (size_t i = 100; i < n; i++)
            assert_int_equal(as_kdtree_insert(ctx, kr, xyz + 3 * i, ids[i]), ANISTAR_OK);
        ta.fail_after = -1;
        assert_int_equal(ta.failures, failures_before);
        assert_int_equal(as_kdtree_check(kr), 0);
        compare_queries(ctx, kr, xyz, ids, n, &r, 3, &s);
        as_kdtree_free(ctx, kr);
    }

    /* query output growth */
    as_kdtree *kd = NULL;
    assert_int_equal(as_kdtree_build(ctx, xyz, NULL, n, &kd), ANISTAR_OK);
    double q[3] = {0, 0, 0};
    as_idlist out = {0};
    ta.fail_after = ta.count;
    assert_int_equal(as_kdtree_radius(ctx, kd, q, 10, &out), ANISTAR_ENOMEM);
    double lo[3] = {-5, -5, -5}, hi[3] = {5, 5, 5};
    assert_int_equal(as_kdtree_box(ctx, kd, lo, hi, &out), ANISTAR_ENOMEM);
    ta.fail_after = -1;
    assert_int_equal(as_kdtree_box(ctx, kd, lo, hi, &out), ANISTAR_OK);
    assert_int_equal(out.n, n);
    as_idlist_free(ctx, &out);
    as_kdtree_free(ctx, kd);
    assert_int_equal(ta.live_blocks, base_blocks);

    scratch_free(&s);
    free(xyz);
    free(ids);
    anistar_context_free(ctx);
    assert_int_equal(ta.live_blocks, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_select),
        cmocka_unit_test(test_ids_sort),
        cmocka_unit_test(test_static_queries),
        cmocka_unit_test(test_incremental),
        cmocka_unit_test(test_order_independence),
        cmocka_unit_test(test_invalid),
        cmocka_unit_test(test_farthest_order),
        cmocka_unit_test(test_alloc_failure),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
