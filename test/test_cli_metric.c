/*
 * test_cli_metric.c — `anistar mesh` and `anistar probe` with metrics that are not
 * positive definite on S (issue 12: status 1 with the point, never a silent substitute),
 * run as separate processes: a zero Hessian without eps, an overflowing Hessian; and the
 * same zero Hessian with eps, which is the documented uniform metric.
 */
#include "test_util.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"

/* The point named by the message: the last "at (X, Y, Z)". */
static void msg_point(const char *msg, double p[3]) {
    const char *at = NULL;
    for (const char *c = strstr(msg, "at ("); c; c = strstr(c + 1, "at (")) at = c;
    if (!at || sscanf(at, "at (%lf, %lf, %lf)", &p[0], &p[1], &p[2]) != 3)
        fail_msg("no point in '%s'", msg);
}

static void test_mesh_zero_hessian(void **state) {
    (void)state;
    char off[96];
    snprintf(off, sizeof off, "/tmp/anistar_climetric_%ld.off", (long)getpid());
    unlink(off);
    const char *args[] = {"mesh", "--builtin", "sphere", "--metric", "hessian:x+2*y",
                          "-o",   off,         NULL};
    tu_run_result *r = test_malloc(sizeof *r);
    tu_run(TOOL, args, r);
    if (r->status != 1) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    tu_assert_one_line(r);
    if (!strstr(r->err, "metric 'hessian:x+2*y': the Hessian of E is 0 on S") ||
        !strstr(r->err, "give eps=E"))
        fail_msg("stderr '%s'", r->err);
    double p[3];
    msg_point(r->err, p);
    assert_true(fabs(sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - 1) < 1e-12);
    assert_int_equal(access(off, F_OK), -1); /* nothing written */
    /* probe refuses it the same way */
    const char *probe[] = {"probe", "--builtin", "sphere", "--metric", "hessian:x+2*y",
                           "--at",  "1,0,0",     NULL};
    tu_run(TOOL, probe, r);
    if (r->status != 1 || !strstr(r->err, "Hessian")) fail_msg("exit %d, '%s'", r->status, r->err);
    tu_assert_one_line(r);
    test_free(r);
}

/* With eps the zero Hessian is the uniform metric eps^(2 power) I: power 0.5, M = 0.5 I. */
static void test_probe_zero_hessian_eps(void **state) {
    (void)state;
    const char *args[] = {"probe", "--builtin", "sphere", "--metric", "hessian:x+2*y,eps=0.5",
                          "--at",  "0,0.6,0.8", NULL};
    tu_run_result *r = test_malloc(sizeof *r);
    tu_run(TOOL, args, r);
    if (r->status != 0) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    const char *t = strstr(r->out, "\"tensor\": [");
    assert_non_null(t);
    double m[6];
    assert_int_equal(sscanf(t, "\"tensor\": [%lf, %lf, %lf, %lf, %lf, %lf]", &m[0], &m[1], &m[2],
                            &m[3], &m[4], &m[5]),
                     6);
    const double want[6] = {0.5, 0, 0, 0.5, 0, 0.5};
    for (int i = 0; i < 6; i++) assert_true(fabs(m[i] - want[i]) < 1e-14);
    test_free(r);
}

/* A Hessian whose eigenvalue overflows the limit at the probed point: status 1 naming it. */
static void test_probe_hessian_overflow(void **state) {
    (void)state;
    const char *args[] = {"probe", "--builtin", "sphere", "--metric",
                          "hessian:exp(800*x),eps=1,en=1,power=1", "--at", "0.6,0.8,0", NULL};
    tu_run_result *r = test_malloc(sizeof *r);
    tu_run(TOOL, args, r);
    if (r->status != 1 || !strstr(r->err, "exceeds")) fail_msg("exit %d, '%s'", r->status, r->err);
    tu_assert_one_line(r);
    double p[3];
    msg_point(r->err, p);
    assert_true(fabs(p[0] - 0.6) < 1e-12 && fabs(p[1] - 0.8) < 1e-12 && fabs(p[2]) < 1e-12);
    test_free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mesh_zero_hessian),
        cmocka_unit_test(test_probe_zero_hessian_eps),
        cmocka_unit_test(test_probe_hessian_overflow),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
