/*
 * test_cli_optimize.c — `anistar mesh ... --optimize --stats` (examples/anistar.c, vertex
 * optimisation of paper 6.2) run as a separate process: the same run with and without
 * --optimize; the optimised one reports moves, a lower mean squared radius-edge ratio,
 * and a "before" histogram equal to the histogram of the run without it; both outputs
 * are closed meshes of a sphere with the same vertex count.
 */
#include "test_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"

/* The array of ANISTAR_HISTOGRAM_BINS integers after "key": into h. */
static void json_hist(const char *from, const char *key, unsigned long long *h) {
    const char *p = tu_json_value(from, key);
    assert_non_null(p);
    assert_true(*p == '[');
    p++;
    for (int i = 0; i < ANISTAR_HISTOGRAM_BINS; i++) {
        char *end;
        h[i] = strtoull(p, &end, 10);
        assert_true(end != p);
        p = end;
        while (*p == ',' || *p == ' ') p++;
    }
    assert_true(*p == ']');
}

/* Vertex and face counts of an OFF file. */
static void off_counts(const char *path, long *nv, long *nf) {
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char magic[8];
    long ne;
    assert_int_equal(fscanf(f, "%7s %ld %ld %ld", magic, nv, nf, &ne), 4);
    assert_string_equal(magic, "OFF");
    fclose(f);
}

static void test_mesh_optimize(void **state) {
    (void)state;
    const char *off[2] = {AS_TEST_BUILD_DIR "/anistar_cliopt_0.off", AS_TEST_BUILD_DIR "/anistar_cliopt_1.off"};
    const char *json[2] = {AS_TEST_BUILD_DIR "/anistar_cliopt_0.json", AS_TEST_BUILD_DIR "/anistar_cliopt_1.json"};
    char *js[2];
    long nv[2], nf[2];
    for (int r = 0; r < 2; r++) {
        remove(off[r]);
        remove(json[r]);
        const char *args[] = {"mesh", "--builtin", "sphere", "--metric", "shock,phi=0.3",
                              "--r0", "1", "--gamma0", "2", "--quiet", "--stats", json[r],
                              "-o", off[r], r ? "--optimize" : NULL, NULL};
        tu_run_result res;
        tu_run(TOOL, args, &res);
        if (res.status != 0) fprintf(stderr, "%s", res.err);
        assert_int_equal(res.status, 0);
        assert_int_equal(res.err[0], '\0'); /* --quiet */
        js[r] = tu_read_file(json[r]);
        assert_non_null(js[r]);
        off_counts(off[r], &nv[r], &nf[r]);
        assert_int_equal(nf[r], 2 * nv[r] - 4); /* a sphere */
        assert_true(tu_json_number(js[r], "vertices") == (double)nv[r]);
        assert_true(tu_json_number(js[r], "facets") == (double)nf[r]);
        assert_true(tu_json_bool(js[r], "closed_manifold"));
        assert_true(tu_json_number(js[r], "inconsistent_facets") == 0);
        const char *par = tu_json_value(js[r], "parameters");
        assert_non_null(par);
        assert_int_equal(tu_json_bool(par, "optimize"), r);
        const char *opt = tu_json_value(js[r], "optimize");
        assert_non_null(opt);
        assert_int_equal(tu_json_bool(opt, "done"), r);
    }
    /* without: nothing moved; with: moves, fewer bad triangles on average */
    const char *o0 = tu_json_value(js[0], "optimize"), *o1 = tu_json_value(js[1], "optimize");
    assert_non_null(o0);
    assert_non_null(o1);
    assert_true(tu_json_number(o0, "moved") == 0);
    double moved = tu_json_number(o1, "moved"), tries = tu_json_number(o1, "tries");
    assert_true(moved > 0 && tries >= moved);
    assert_true(tu_json_number(o1, "passes") >= 1);
    assert_int_equal(nv[0], nv[1]);
    double m0 = tu_json_number(js[0], "rho2_mean"), m1 = tu_json_number(js[1], "rho2_mean");
    assert_true(m1 < m0);
    /* the "before" of the optimised run is the run without (same seed: same refinement) */
    assert_true(tu_json_number(o1, "rho2_mean_before") == m0);
    unsigned long long h0[ANISTAR_HISTOGRAM_BINS], hb[ANISTAR_HISTOGRAM_BINS],
        h1[ANISTAR_HISTOGRAM_BINS];
    json_hist(js[0], "histogram", h0);
    json_hist(o1, "histogram_before", hb);
    json_hist(js[1], "histogram", h1);
    assert_memory_equal(h0, hb, sizeof h0);
    unsigned long long s1 = 0;
    for (int i = 0; i < ANISTAR_HISTOGRAM_BINS; i++) s1 += h1[i];
    assert_true(s1 == 3 * (unsigned long long)nf[1]);
    for (int r = 0; r < 2; r++) {
        free(js[r]);
        remove(off[r]);
        remove(json[r]);
    }
}

/* --optimize is a flag: a value after it is an unknown argument (usage error). */
static void test_optimize_flag(void **state) {
    (void)state;
    const char *args[] = {"mesh", "--builtin", "sphere", "--optimize", "yes", "-o",
                          AS_TEST_BUILD_DIR "/anistar_cliopt_x.off", NULL};
    tu_run_result res;
    tu_run(TOOL, args, &res);
    assert_int_equal(res.status, 2);
    tu_assert_one_line(&res);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mesh_optimize),
        cmocka_unit_test(test_optimize_flag),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
