/*
 * test_cli.c — the command-line tool (examples/anistar.c), run as a separate process:
 * the probe command's JSON checked against closed forms, --help/--version, usage errors
 * (exit 2, one line on stderr) and runtime errors (exit 1, one line on stderr).
 */
#include "test_util.h"

#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"

typedef tu_run_result run_result;

/* Run the tool with args (NULL-terminated, without argv[0]). */
static void run(const char *const *args, run_result *res) { tu_run(TOOL, args, res); }

static void assert_one_line(const run_result *r) { tu_assert_one_line(r); }

/* The numbers of the JSON array after "key": [ ... ] (nested brackets flattened). */
static int json_numbers(const char *json, const char *key, double *v, int max) {
    char pat[64];
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(json, pat);
    if (!p) return -1;
    p += strlen(pat);
    while (*p == ' ') p++;
    if (*p != '[') {
        char *end;
        v[0] = strtod(p, &end);
        return end == p ? -1 : 1;
    }
    int depth = 0, n = 0;
    for (; *p; p++) {
        if (*p == '[') depth++;
        else if (*p == ']') {
            if (--depth == 0) break;
        } else if (*p == '-' || (*p >= '0' && *p <= '9')) {
            char *end;
            double x = strtod(p, &end);
            if (n < max) v[n] = x;
            n++;
            p = end - 1;
        }
    }
    return n;
}

static void test_probe_torus(void **state) {
    (void)state;
    const char *args[] = {"probe", "--builtin", "torus", "--metric", "curvature", "--at",
                          "11,0,0", NULL};
    run_result *r = test_malloc(sizeof *r);
    run(args, r);
    if (r->status != 0) fail_msg("exit %d: %s", r->status, r->err);
    assert_string_equal(r->err, "");
    double v[8];
    /* at (11, 0, 0) on the torus R 10, r 1: on S, curvatures 1/r and 1/(R + r) */
    assert_int_equal(json_numbers(r->out, "f", v, 8), 1);
    assert_true(fabs(v[0]) < 1e-12);
    assert_int_equal(json_numbers(r->out, "gradient", v, 8), 3);
    assert_true(fabs(v[0] - 2) < 1e-12 && fabs(v[1]) < 1e-12 && fabs(v[2]) < 1e-12);
    assert_int_equal(json_numbers(r->out, "projection", v, 8), 3);
    assert_true(fabs(v[0] - 11) < 1e-10 && fabs(v[1]) < 1e-10 && fabs(v[2]) < 1e-10);
    assert_int_equal(json_numbers(r->out, "normal", v, 8), 3);
    assert_true(fabs(v[0] - 1) < 1e-12);
    assert_int_equal(json_numbers(r->out, "curvatures", v, 8), 2);
    assert_true(fabs(v[0] - 1) < 1e-10 && fabs(v[1] - 1.0 / 11) < 1e-10);
    assert_int_equal(json_numbers(r->out, "directions", v, 8), 6);
    assert_true(fabs(fabs(v[2]) - 1) < 1e-10); /* meridian: z */
    assert_true(fabs(fabs(v[4]) - 1) < 1e-10); /* parallel: y */
    /* tensor: e = 1 along z (meridian), 1/11 along y (parallel), e_n = 1 along x */
    assert_int_equal(json_numbers(r->out, "tensor", v, 8), 6);
    assert_true(fabs(v[0] - 1) < 1e-9 && fabs(v[3] - 1.0 / 121) < 1e-12 &&
                fabs(v[5] - 1) < 1e-9);
    assert_true(fabs(v[1]) < 1e-12 && fabs(v[2]) < 1e-9 && fabs(v[4]) < 1e-12);
    assert_non_null(strstr(r->out, "\"metric\": \"curvature\""));
    test_free(r);
}

static void test_probe_projection(void **state) {
    (void)state;
    /* a point off S: the sphere of radius 2 given as an expression */
    const char *args[] = {"probe", "--implicit", "x^2+y^2+z^2-4", "--bound", "0,0,0,3",
                          "--at", "0,3,4", "--metric", "shock,en=2", NULL};
    run_result *r = test_malloc(sizeof *r);
    run(args, r);
    if (r->status != 0) fail_msg("exit %d: %s", r->status, r->err);
    double v[8];
    assert_int_equal(json_numbers(r->out, "f", v, 8), 1);
    assert_true(fabs(v[0] - 21) < 1e-12);
    assert_int_equal(json_numbers(r->out, "projection", v, 8), 3);
    assert_true(fabs(v[0]) < 1e-11 && fabs(v[1] - 1.2) < 1e-11 && fabs(v[2] - 1.6) < 1e-11);
    assert_int_equal(json_numbers(r->out, "distance", v, 8), 1);
    assert_true(fabs(v[0] - 3) < 1e-11);
    assert_int_equal(json_numbers(r->out, "curvatures", v, 8), 2);
    assert_true(fabs(v[0] - 0.5) < 1e-10 && fabs(v[1] - 0.5) < 1e-10);
    assert_int_equal(json_numbers(r->out, "tensor", v, 8), 6);
    test_free(r);
}

static void test_help_version(void **state) {
    (void)state;
    run_result *r = test_malloc(sizeof *r);
    const char *h[] = {"--help", NULL};
    run(h, r);
    assert_int_equal(r->status, 0);
    assert_non_null(strstr(r->out, "probe SURFACE"));
    assert_non_null(strstr(r->out, "mesh"));
    assert_non_null(strstr(r->out, "render"));
    const char *name, *desc;
    for (size_t i = 0; anistar_surface_builtin_info(i, &name, &desc) == ANISTAR_OK; i++)
        assert_non_null(strstr(r->out, name));
    const char *v[] = {"--version", NULL};
    run(v, r);
    assert_int_equal(r->status, 0);
    assert_non_null(strstr(r->out, anistar_version()));
    test_free(r);
}

static void test_usage_errors(void **state) {
    (void)state;
    const char *cases[][12] = {
        {NULL},
        {"frobnicate", NULL},
        {"probe", "--builtin", "torus", "--at", "11,0,0", "--frob", NULL},
        {"probe", "--builtin", "torus", NULL},
        {"probe", "--builtin", "torus", "--at", "11,0", NULL},
        {"probe", "--builtin", "torus", "--at", "11,0,x", NULL},
        {"probe", "--builtin", "torus", "--at", "11,,0", NULL},
        {"probe", "--builtin", "torus", "--at", "11,0,0,1", NULL},
        {"probe", "--builtin", "torus", "--at", NULL},
        {"probe", "--builtin", "torux", "--at", "11,0,0", NULL},
        {"probe", "--builtin", "torus,q=1", "--at", "11,0,0", NULL},
        {"probe", "--builtin", "torus", "--metric", "curvature,foo=1", "--at", "11,0,0", NULL},
        {"probe", "--builtin", "torus", "--metric", "frob", "--at", "11,0,0", NULL},
        {"probe", "--builtin", "torus", "--metric", "hessian:max(x,y", "--at", "1,0,0", NULL},
        {"probe", "--at", "11,0,0", NULL},
        {"probe", "--implicit", "x^2+y^2+z^2-1", "--at", "1,0,0", NULL},
        {"probe", "--implicit", "x^2+y^2+z^2-1", "--bound", "0,0,0", "--at", "1,0,0", NULL},
        {"probe", "--implicit", "x^2+y^2+z^2-1", "--bound", "0,0,0,-1", "--at", "1,0,0", NULL},
        {"probe", "--implicit", "x^2+*y", "--bound", "0,0,0,2", "--at", "1,0,0", NULL},
        {"probe", "--builtin", "torus", "--implicit", "x", "--bound", "0,0,0,1", "--at",
         "1,0,0", NULL},
        {"probe", "--builtin", "torus", "--builtin", "sphere", "--at", "1,0,0", NULL},
    };
    run_result *r = test_malloc(sizeof *r);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run(cases[i], r);
        if (r->status != 2)
            fail_msg("case %zu (%s %s ...): exit %d, stderr '%s'", i,
                     cases[i][0] ? cases[i][0] : "", cases[i][0] && cases[i][1] ? cases[i][1] : "",
                     r->status, r->err);
        assert_one_line(r);
        assert_string_equal(r->out, "");
    }
    test_free(r);
}

static void test_runtime_errors(void **state) {
    (void)state;
    const char *cases[][12] = {
        /* no zero inside the bounding sphere */
        {"probe", "--implicit", "x^2+y^2+z^2+1", "--bound", "0,0,0,2", "--at", "0.5,0,0",
         NULL},
        /* f is NaN at the point */
        {"probe", "--implicit", "sqrt(x)+y^2+z^2-1", "--bound", "0,0,0,2", "--at", "-1,0,0",
         NULL},
        /* the surface leaks out of its bounding sphere (found computing the default e_n) */
        {"probe", "--implicit", "x^2+y^2+z^2-9", "--bound", "0,0,0,2", "--at", "1,0,0", NULL},
        /* a mesh file that does not exist */
        {"probe", "model.off", "--at", "0,0,0", NULL},
        /* sol metrics need a mesh surface */
        {"probe", "--builtin", "sphere", "--metric", "sol:m.sol", "--at", "1,0,0", NULL},
        /* mesh: no zero inside the bounding sphere */
        {"mesh", "--implicit", "x^2+y^2+z^2+1", "--bound", "0,0,0,2", "-o",
         AS_TEST_BUILD_DIR "/anistar_cli_nosurface.off", NULL},
    };
    const char *msgs[] = {"no", "not finite", "bounding sphere", "cannot open 'model.off'",
                          "not supported yet", "no"};
    run_result *r = test_malloc(sizeof *r);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run(cases[i], r);
        if (r->status != 1)
            fail_msg("case %zu: exit %d, stderr '%s'", i, r->status, r->err);
        assert_one_line(r);
        if (!strstr(r->err, msgs[i])) fail_msg("case %zu: '%s' lacks '%s'", i, r->err, msgs[i]);
        assert_string_equal(r->out, "");
    }
    test_free(r);
}

/* A bounding sphere too small for S, or no surface inside it, is the surface's error
 * (status ENOSURFACE, "surface: ..."), whatever layer first samples S: the default e_n of
 * a curvature metric, or the mesher with a euclidean one; never a metric error. */
static void test_surface_errors_are_surface_errors(void **state) {
    (void)state;
    const char *cases[][12] = {
        {"mesh", "--implicit", "x^2+y^2+z^2-4", "--bound", "0,0,0,1", "-o", AS_TEST_BUILD_DIR "/anistar_cli_se.off", NULL},
        {"mesh", "--implicit", "x^2+y^2+z^2-4", "--bound", "0,0,0,1", "--metric", "euclidean", "-o",
         AS_TEST_BUILD_DIR "/anistar_cli_se.off", NULL},
        {"mesh", "--implicit", "x^2+y^2+z^2+1", "--bound", "0,0,0,1", "-o", AS_TEST_BUILD_DIR "/anistar_cli_se.off", NULL},
        {"mesh", "--implicit", "x^2+y^2+z^2+1", "--bound", "0,0,0,1", "--metric", "hessian:x^2", "-o",
         AS_TEST_BUILD_DIR "/anistar_cli_se.off", NULL},
    };
    const char *want[] = {"must lie strictly inside the bounding sphere",
                          "must lie strictly inside the bounding sphere",
                          "no surface found inside the bounding sphere",
                          "no surface found inside the bounding sphere"};
    run_result *r = test_malloc(sizeof *r);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run(cases[i], r);
        if (r->status != 1) fail_msg("case %zu: exit %d: %s", i, r->status, r->err);
        assert_one_line(r);
        if (strncmp(r->err, "anistar: surface: ", 18) || !strstr(r->err, want[i]) ||
            strstr(r->err, "metric"))
            fail_msg("case %zu: '%s'", i, r->err);
    }
    test_free(r);
    /* the API: anistar_metric_from_spec passes the surface's status through */
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    const double c[3] = {0, 0, 0};
    assert_int_equal(anistar_surface_from_expression(ctx, "x^2+y^2+z^2-4", c, 1, &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "curvature", &m), ANISTAR_ENOSURFACE);
    assert_null(m);
    assert_int_equal(strncmp(anistar_last_error(ctx), "surface: ", 9), 0);
    anistar_surface_free(s);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_probe_torus),   cmocka_unit_test(test_probe_projection),
        cmocka_unit_test(test_help_version),  cmocka_unit_test(test_usage_errors),
        cmocka_unit_test(test_runtime_errors),
        cmocka_unit_test(test_surface_errors_are_surface_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
