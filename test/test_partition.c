/*
 * test_partition.c — the star set split over k parts in one process (issue 15 item 4,
 * lib/mesher/partition.h, docs/scaling.md).
 *
 * - One part is the serial run: the same sites, every star the union's, no repair.
 * - k parts on two surfaces (a sphere with the shock metric, a torus with the curvature
 *   metric): the check run from the union of the owned sites ends certified; the owned
 *   stars of the parts agree with the star set of the union (checked against every star
 *   of it, not sampled) and the stitched facets are consistent but for the seams', whose
 *   share is bounded; every part owns sites and gets some from its neighbours.
 * - The same input twice gives the same mesh byte for byte (the parts run as threads:
 *   their timing must not matter), and k out of range is refused.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#include "mesher/mesher.h"
#include "mesher/partition.h"
#include "surface/field.h"
#include "surface/surface.h"

typedef struct pcase {
    const char *surface, *metric;
    double r0, gamma0;
} pcase;

static void setup(anistar_context **ctx, as_surface **s, as_field **f, as_mesher_params *p,
                  const pcase *c) {
    *ctx = anistar_context_new(NULL);
    assert_non_null(*ctx);
    assert_int_equal(as_implicit_builtin(*ctx, c->surface, s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(*ctx, *s, c->metric, f), ANISTAR_OK);
    as_mesher_params_default(p);
    p->r0 = c->r0;
    p->gamma0 = c->gamma0;
}

static void teardown(anistar_context *ctx, as_surface *s, as_field *f) {
    anistar_metric_free(f);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

static void test_one_part_is_the_serial_run(void **state) {
    (void)state;
    const pcase c = {"sphere", "shock", 0.2, 1.5};
    anistar_context *ctx;
    as_surface *s;
    as_field *f;
    as_mesher_params p;
    setup(&ctx, &s, &f, &p, &c);
    /* a part takes its jobs one at a time (the hook judges each): so does the run it is
     * compared with */
    p.batch = 1;
    anistar_mesh *serial = NULL, *out = NULL;
    assert_int_equal(as_mesher_run(ctx, s, f, &p, NULL, &serial), ANISTAR_OK);
    as_partition_result res;
    assert_int_equal(as_partition_run(ctx, s, f, &p, 1, &res, &out), ANISTAR_OK);
    assert_int_equal(res.certified, 1);
    assert_int_equal(res.union_sites, (int64_t)serial->tm.nv);
    assert_int_equal(res.stars_same, res.union_sites);
    assert_int_equal(res.union_consistent, res.union_facets);
    assert_int_equal(res.union_inconsistent, 0);
    assert_int_equal(res.repairs, 0);
    assert_int_equal(res.part[0].requests_sent, 0);
    assert_int_equal(out->tm.nv, serial->tm.nv);
    assert_int_equal(out->tm.nt, serial->tm.nt);
    /* the same points (the check run inserts the serial run's sites in its order) */
    assert_memory_equal(out->tm.xyz, serial->tm.xyz, 3 * serial->tm.nv * sizeof(double));
    as_mesh_free(serial);
    as_mesh_free(out);
    teardown(ctx, s, f);
}

static void check_k(const pcase *c, int k) {
    anistar_context *ctx;
    as_surface *s;
    as_field *f;
    as_mesher_params p;
    setup(&ctx, &s, &f, &p, c);
    as_partition_result res, res2;
    anistar_mesh *out = NULL, *out2 = NULL;
    anistar_status st = as_partition_run(ctx, s, f, &p, k, &res, &out);
    if (st != ANISTAR_OK) fprintf(stderr, "%s k %d: %s\n", c->surface, k, anistar_last_error(ctx));
    assert_int_equal(st, ANISTAR_OK);
    assert_int_equal(res.k, k);
    assert_int_equal(res.certified, 1);
    assert_true(out->stats.complete);
    assert_true(out->stats.closed_manifold);
    assert_true(res.rounds >= 2); /* at least one exchange, then a round with nothing new */
    int64_t owned = 0;
    for (int i = 0; i < k; i++) {
        assert_true(res.part[i].owned > 0);
        assert_true(res.part[i].halo_in > 0);
        assert_true(res.part[i].sites > res.part[i].owned);
        owned += res.part[i].owned;
    }
    assert_int_equal(owned, res.union_sites);
    /* the seams: at most 2% of the owned stars differ from the union's, at most 2% of
     * the stitched facets are not held by all three owned stars, and the check run adds
     * at most 1% of points (measured: 99.5-99.9%, 0-5 points on the torus, bench) */
    fprintf(stderr, "%s k %d: %lld sites, %lld same stars, %lld / %lld consistent, %lld repairs\n",
            c->surface, k, (long long)res.union_sites, (long long)res.stars_same,
            (long long)res.union_consistent, (long long)res.union_facets,
            (long long)res.repairs);
    assert_true((double)res.stars_same >= 0.98 * (double)res.union_sites);
    assert_true((double)res.union_consistent >= 0.98 * (double)res.union_facets);
    assert_true((double)res.repairs <= 0.01 * (double)res.union_sites);
    assert_int_equal(res.final_sites, (int64_t)out->tm.nv);
    /* deterministic whatever the threads' timing */
    assert_int_equal(as_partition_run(ctx, s, f, &p, k, &res2, &out2), ANISTAR_OK);
    assert_int_equal(res2.union_sites, res.union_sites);
    assert_int_equal(res2.rounds, res.rounds);
    assert_int_equal(out2->tm.nv, out->tm.nv);
    assert_int_equal(out2->tm.nt, out->tm.nt);
    assert_memory_equal(out2->tm.xyz, out->tm.xyz, 3 * out->tm.nv * sizeof(double));
    assert_memory_equal(out2->tm.tri, out->tm.tri, 3 * out->tm.nt * sizeof(out->tm.tri[0]));
    as_mesh_free(out);
    as_mesh_free(out2);
    teardown(ctx, s, f);
}

static void test_sphere_shock_three_parts(void **state) {
    (void)state;
    const pcase c = {"sphere", "shock", 0.2, 1.5};
    check_k(&c, 3);
}

static void test_torus_curvature_four_parts(void **state) {
    (void)state;
    const pcase c = {"torus,R=4,r=1", "curvature", 0.2, 1.5};
    check_k(&c, 4);
}

static void test_k_out_of_range(void **state) {
    (void)state;
    const pcase c = {"sphere", "euclidean", 0.3, 1.5};
    anistar_context *ctx;
    as_surface *s;
    as_field *f;
    as_mesher_params p;
    setup(&ctx, &s, &f, &p, &c);
    as_partition_result res;
    anistar_mesh *out = NULL;
    assert_int_equal(as_partition_run(ctx, s, f, &p, 0, &res, &out), ANISTAR_EINVAL);
    assert_null(out);
    assert_int_equal(as_partition_run(ctx, s, f, &p, AS_PARTITION_MAX + 1, &res, &out),
                     ANISTAR_EINVAL);
    assert_null(out);
    teardown(ctx, s, f);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_one_part_is_the_serial_run),
        cmocka_unit_test(test_sphere_shock_three_parts),
        cmocka_unit_test(test_torus_curvature_four_parts),
        cmocka_unit_test(test_k_out_of_range),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
