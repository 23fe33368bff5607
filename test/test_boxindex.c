/*
 * test_boxindex — the dynamic box index (lib/geom/boxindex.c): random inserts, updates
 * (small moves inside a cell and large ones across cells and levels) and removals
 * interleaved with point and box queries, all against brute force, on boxes of very
 * different sizes (points, flat boxes, huge boxes), extreme coordinates (near 1e300,
 * subnormal, negative, zero), query points on box faces and corners (closed boxes);
 * the invariant checker after every step of a run; invalid input; allocation-failure
 * injection (ENOMEM leaves the index unchanged, no leak).
 */
#include "test_util.h"

#include "core.h"
#include "geom/boxindex.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct model {
    int n;
    unsigned char *has;
    double *box; /* 6 per id */
} model;

static void model_init(model *m, int n) {
    m->n = n;
    m->has = calloc((size_t)n, 1);
    m->box = calloc((size_t)n * 6, sizeof *m->box);
    assert_non_null(m->has);
    assert_non_null(m->box);
}

static void model_free(model *m) {
    free(m->has);
    free(m->box);
}

/* A random box; `style` picks the size regime. */
static void random_box(tu_rng *r, int style, double lo[3], double hi[3]) {
    double c[3], h[3];
    double scale;
    switch (style % 6) {
    case 0: scale = 1e-3; break;
    case 1: scale = 1e-1; break;
    case 2: scale = 0; break; /* points */
    case 3: scale = 3; break;
    case 4: scale = 1e-2; break;
    default: scale = pow(10.0, tu_rng_range(r, -6, 1)); break;
    }
    for (int k = 0; k < 3; k++) {
        c[k] = tu_rng_range(r, -1, 1);
        h[k] = scale * tu_rng_unit(r);
    }
    if (style % 7 == 3) h[1] = 0;            /* flat */
    if (style % 11 == 5) h[0] *= 50;         /* elongated */
    if (style % 13 == 7) c[2] = 0;           /* on a plane through the origin */
    if (style % 17 == 1) c[0] = (double)(tu_rng_u64(r) % 5) * 0.25; /* dyadic, shared */
    for (int k = 0; k < 3; k++) {
        lo[k] = c[k] - h[k];
        hi[k] = c[k] + h[k];
    }
}

static void brute_query(const model *m, const double lo[3], const double hi[3], int32_t *out,
                        size_t *n) {
    *n = 0;
    for (int id = 0; id < m->n; id++) {
        if (!m->has[id]) continue;
        const double *b = m->box + 6 * id;
        int meet = 1;
        for (int k = 0; k < 3; k++)
            if (b[3 + k] < lo[k] || b[k] > hi[k]) meet = 0;
        if (meet) out[(*n)++] = id;
    }
}

static void check_query(anistar_context *ctx, const as_boxindex *bi, const model *m,
                        const double lo[3], const double hi[3], int point, as_idlist *out,
                        int32_t *ref) {
    size_t n;
    brute_query(m, lo, hi, ref, &n);
    if (point)
        assert_int_equal(as_boxindex_query_point(ctx, bi, lo, out), ANISTAR_OK);
    else
        assert_int_equal(as_boxindex_query_box(ctx, bi, lo, hi, out), ANISTAR_OK);
    assert_int_equal(out->n, n);
    for (size_t i = 0; i < n; i++) assert_int_equal(out->ids[i], ref[i]);
}

/* A query point or box: random, or a corner/face point of a stored box, or huge. */
static void random_query(tu_rng *r, const model *m, double lo[3], double hi[3]) {
    double u = tu_rng_unit(r);
    int id = (int)(tu_rng_u64(r) % (uint64_t)m->n);
    if (u < 0.35 && m->has[id]) {
        const double *b = m->box + 6 * id;
        for (int k = 0; k < 3; k++) lo[k] = (tu_rng_u64(r) & 1) ? b[k] : b[3 + k];
        if (tu_rng_unit(r) < 0.5) lo[1] = 0.5 * (b[1] + b[4]); /* on a face */
        memcpy(hi, lo, 3 * sizeof *hi);
        if (tu_rng_unit(r) < 0.3)
            for (int k = 0; k < 3; k++) hi[k] = lo[k] + tu_rng_range(r, 0, 0.05);
    } else if (u < 0.4) {
        for (int k = 0; k < 3; k++) {
            lo[k] = -2;
            hi[k] = 2; /* everything: the scanning path */
        }
    } else {
        for (int k = 0; k < 3; k++) lo[k] = hi[k] = tu_rng_range(r, -1.2, 1.2);
        if (tu_rng_unit(r) < 0.5)
            for (int k = 0; k < 3; k++) hi[k] = lo[k] + pow(10.0, tu_rng_range(r, -4, 0));
    }
}

static void random_run(int nid, int steps, int check_every, uint64_t seed) {
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    as_boxindex *bi = NULL;
    assert_int_equal(as_boxindex_new(ctx, &bi), ANISTAR_OK);
    model m;
    model_init(&m, nid);
    tu_rng r = {seed};
    as_idlist out = {0};
    int32_t *ref = malloc((size_t)nid * sizeof *ref);
    assert_non_null(ref);
    size_t count = 0;
    for (int step = 0; step < steps; step++) {
        int id = (int)(tu_rng_u64(&r) % (uint64_t)nid);
        double u = tu_rng_unit(&r);
        if (u < 0.5) { /* insert or update */
            double lo[3], hi[3];
            if (m.has[id] && tu_rng_unit(&r) < 0.5) { /* small change: mostly same cell */
                const double *b = m.box + 6 * id;
                for (int k = 0; k < 3; k++) {
                    lo[k] = b[k] + 1e-9 * tu_rng_unit(&r);
                    hi[k] = b[3 + k] >= lo[k] ? b[3 + k] : lo[k];
                }
            } else {
                random_box(&r, (int)(tu_rng_u64(&r) % 1000), lo, hi);
            }
            assert_int_equal(as_boxindex_set(ctx, bi, id, lo, hi), ANISTAR_OK);
            if (!m.has[id]) count++;
            m.has[id] = 1;
            memcpy(m.box + 6 * id, lo, sizeof lo);
            memcpy(m.box + 6 * id + 3, hi, sizeof hi);
        } else if (u < 0.65) {
            assert_int_equal(as_boxindex_remove(bi, id), m.has[id]);
            if (m.has[id]) count--;
            m.has[id] = 0;
        } else {
            double lo[3], hi[3];
            random_query(&r, &m, lo, hi);
            int point = lo[0] == hi[0] && lo[1] == hi[1] && lo[2] == hi[2];
            check_query(ctx, bi, &m, lo, hi, point, &out, ref);
        }
        assert_int_equal(as_boxindex_size(bi), count);
        if (check_every && step % check_every == 0) assert_int_equal(as_boxindex_check(ctx, bi), 0);
    }
    assert_int_equal(as_boxindex_check(ctx, bi), 0);
    for (int id = 0; id < nid; id++) {
        double lo[3], hi[3];
        assert_int_equal(as_boxindex_get(bi, id, lo, hi), m.has[id]);
        if (m.has[id]) {
            assert_memory_equal(lo, m.box + 6 * id, sizeof lo);
            assert_memory_equal(hi, m.box + 6 * id + 3, sizeof hi);
        }
    }
    /* remove everything: empty again */
    for (int id = 0; id < nid; id++) as_boxindex_remove(bi, id);
    assert_int_equal(as_boxindex_size(bi), 0);
    assert_int_equal(as_boxindex_check(ctx, bi), 0);
    double p[3] = {0, 0, 0};
    assert_int_equal(as_boxindex_query_point(ctx, bi, p, &out), ANISTAR_OK);
    assert_int_equal(out.n, 0);
    free(ref);
    as_idlist_free(ctx, &out);
    model_free(&m);
    as_boxindex_free(ctx, bi);
    anistar_context_free(ctx);
}

static void test_random_small_checked(void **state) {
    (void)state;
    random_run(60, 6000, 1, 1); /* validator after every operation */
}

static void test_random_medium(void **state) {
    (void)state;
    random_run(3000, 40000, 997, 2);
}

/* Extreme coordinates and sizes: huge, tiny, subnormal, zero-size at the origin. */
static void test_extremes(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    as_boxindex *bi = NULL;
    assert_int_equal(as_boxindex_new(ctx, &bi), ANISTAR_OK);
    enum { N = 12 };
    double boxes[N][6] = {
        {0, 0, 0, 0, 0, 0},
        {-1e300, -1e300, -1e300, 1e300, 1e300, 1e300},
        {1e299, 0, 0, 1e300, 1, 1},
        {-4.9e-324, 0, 0, 4.9e-324, 0, 0},
        {1e-310, 1e-310, 1e-310, 2e-310, 2e-310, 2e-310},
        {-1e-300, -1e-300, -1e-300, -5e-301, 0, 0},
        {-3, -3, -3, -3, -3, -3},
        {1e200, 1e200, 1e200, 1e200, 1e200, 1e200},
        {-1, -1e-20, 5, 1, 1e-20, 5},
        {0.5, 0.5, 0.5, 0.5 + 0x1p-52, 0.5, 0.5},
        {-1e100, 0, 0, 1e-100, 0, 0},
        {1e-5, 1e-5, 1e-5, 1e5, 1e5, 1e5},
    };
    model m;
    model_init(&m, N);
    for (int i = 0; i < N; i++) {
        assert_int_equal(as_boxindex_set(ctx, bi, i, boxes[i], boxes[i] + 3), ANISTAR_OK);
        m.has[i] = 1;
        memcpy(m.box + 6 * i, boxes[i], sizeof boxes[i]);
    }
    assert_int_equal(as_boxindex_check(ctx, bi), 0);
    as_idlist out = {0};
    int32_t ref[N];
    /* every box corner, the centre and the two diagonal corners of each box */
    for (int i = 0; i < N; i++)
        for (int c = 0; c < 8; c++) {
            double p[3];
            for (int k = 0; k < 3; k++) p[k] = (c >> k) & 1 ? boxes[i][3 + k] : boxes[i][k];
            check_query(ctx, bi, &m, p, p, 1, &out, ref);
            double q[3] = {p[0] + 1, p[1], p[2]};
            double lo[3], hi[3];
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(p[k], q[k]);
                hi[k] = fmax(p[k], q[k]);
            }
            check_query(ctx, bi, &m, lo, hi, 0, &out, ref);
            double neg[3] = {-p[0], -p[1], -p[2]};
            check_query(ctx, bi, &m, neg, neg, 1, &out, ref);
        }
    double far[3] = {1e308, -1e308, 1e308};
    check_query(ctx, bi, &m, far, far, 1, &out, ref);
    double all_lo[3] = {-1e308, -1e308, -1e308}, all_hi[3] = {1e308, 1e308, 1e308};
    check_query(ctx, bi, &m, all_lo, all_hi, 0, &out, ref);
    assert_int_equal(out.n, N);
    /* move every box to another one's place (level and cell change) */
    for (int i = 0; i < N; i++) {
        int j = (i * 5 + 3) % N;
        assert_int_equal(as_boxindex_set(ctx, bi, i, boxes[j], boxes[j] + 3), ANISTAR_OK);
        memcpy(m.box + 6 * i, boxes[j], sizeof boxes[j]);
        assert_int_equal(as_boxindex_check(ctx, bi), 0);
        for (int t = 0; t < N; t++) check_query(ctx, bi, &m, boxes[t], boxes[t], 1, &out, ref);
    }
    as_idlist_free(ctx, &out);
    model_free(&m);
    as_boxindex_free(ctx, bi);
    anistar_context_free(ctx);
}

static void test_invalid(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    as_boxindex *bi = NULL;
    assert_int_equal(as_boxindex_new(ctx, &bi), ANISTAR_OK);
    double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    assert_int_equal(as_boxindex_set(ctx, bi, -1, lo, hi), ANISTAR_EINVAL);
    assert_int_equal(as_boxindex_set(ctx, bi, INT32_MAX, lo, hi), ANISTAR_EINVAL);
    hi[1] = -1;
    assert_int_equal(as_boxindex_set(ctx, bi, 0, lo, hi), ANISTAR_EINVAL);
    hi[1] = NAN;
    assert_int_equal(as_boxindex_set(ctx, bi, 0, lo, hi), ANISTAR_EINVAL);
    hi[1] = 1e301;
    assert_int_equal(as_boxindex_set(ctx, bi, 0, lo, hi), ANISTAR_EINVAL);
    assert_true(strlen(anistar_last_error(ctx)) > 0);
    hi[1] = 1;
    assert_int_equal(as_boxindex_set(ctx, bi, 7, lo, hi), ANISTAR_OK);
    assert_int_equal(as_boxindex_size(bi), 1);
    as_idlist out = {0};
    double p[3] = {NAN, 0, 0};
    assert_int_equal(as_boxindex_query_point(ctx, bi, p, &out), ANISTAR_EINVAL);
    double qlo[3] = {1, 0, 0}, qhi[3] = {0, 1, 1};
    assert_int_equal(as_boxindex_query_box(ctx, bi, qlo, qhi, &out), ANISTAR_EINVAL);
    assert_int_equal(as_boxindex_remove(bi, -3), 0);
    assert_int_equal(as_boxindex_remove(bi, 1000), 0);
    assert_int_equal(as_boxindex_remove(bi, 6), 0);
    assert_int_equal(as_boxindex_remove(bi, 7), 1);
    assert_int_equal(as_boxindex_remove(bi, 7), 0);
    assert_int_equal(as_boxindex_get(bi, 7, lo, hi), 0);
    as_idlist_free(ctx, &out);
    as_boxindex_free(ctx, bi);
    as_boxindex_free(ctx, NULL);
    anistar_context_free(ctx);
}

/* Allocation failures: a run of set operations where the f-th allocation fails; each
 * failed set reports ENOMEM and changes nothing; the index keeps answering like the
 * model; no leak. */
static void test_alloc_failure(void **state) {
    (void)state;
    tu_alloc ta;
    tu_alloc_init(&ta, -1);
    anistar_allocator al = tu_allocator(&ta);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    const int nid = 400;
    int32_t *ref = malloc((size_t)nid * sizeof *ref);
    assert_non_null(ref);
    int done = 0;
    for (long f = 0; !done; f++) {
        tu_rng r = {77};
        model m;
        model_init(&m, nid);
        as_boxindex *bi = NULL;
        ta.fail_after = ta.count + f;
        anistar_status st = as_boxindex_new(ctx, &bi);
        int failures = 0;
        for (int step = 0; st == ANISTAR_OK && step < 1500; step++) {
            int id = (int)(tu_rng_u64(&r) % (uint64_t)nid);
            double lo[3], hi[3];
            random_box(&r, step, lo, hi);
            anistar_status s2 = as_boxindex_set(ctx, bi, id, lo, hi);
            if (s2 == ANISTAR_ENOMEM) {
                failures++;
                continue;
            }
            assert_int_equal(s2, ANISTAR_OK);
            m.has[id] = 1;
            memcpy(m.box + 6 * id, lo, sizeof lo);
            memcpy(m.box + 6 * id + 3, hi, sizeof hi);
            if (step % 5 == 0) {
                int rid = (int)(tu_rng_u64(&r) % (uint64_t)nid);
                assert_int_equal(as_boxindex_remove(bi, rid), m.has[rid]);
                m.has[rid] = 0;
            }
        }
        ta.fail_after = -1;
        if (st != ANISTAR_OK) {
            assert_int_equal(st, ANISTAR_ENOMEM);
            assert_null(bi);
        } else {
            /* failed sets changed nothing: the index holds the model's boxes */
            for (int id = 0; id < nid; id++) {
                double lo[3], hi[3];
                assert_int_equal(as_boxindex_get(bi, id, lo, hi), m.has[id]);
                if (m.has[id]) {
                    assert_memory_equal(lo, m.box + 6 * id, sizeof lo);
                    assert_memory_equal(hi, m.box + 6 * id + 3, sizeof hi);
                }
            }
            assert_int_equal(as_boxindex_check(ctx, bi), 0);
            as_idlist out = {0};
            for (int q = 0; q < 200; q++) {
                double lo[3], hi[3];
                random_query(&r, &m, lo, hi);
                check_query(ctx, bi, &m, lo, hi, 0, &out, ref);
            }
            /* query output growth failure */
            double all_lo[3] = {-9, -9, -9}, all_hi[3] = {9, 9, 9};
            as_idlist fresh = {0};
            ta.fail_after = ta.count;
            anistar_status qs = as_boxindex_query_box(ctx, bi, all_lo, all_hi, &fresh);
            ta.fail_after = -1;
            assert_int_equal(qs, as_boxindex_size(bi) ? ANISTAR_ENOMEM : ANISTAR_OK);
            as_idlist_free(ctx, &fresh);
            as_idlist_free(ctx, &out);
            as_boxindex_free(ctx, bi);
            if (failures == 0) done = 1;
        }
        model_free(&m);
        assert_int_equal(ta.live_blocks, 1); /* the context */
    }
    free(ref);
    anistar_context_free(ctx);
    assert_int_equal(ta.live_blocks, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_small_checked),
        cmocka_unit_test(test_random_medium),
        cmocka_unit_test(test_extremes),
        cmocka_unit_test(test_invalid),
        cmocka_unit_test(test_alloc_failure),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
