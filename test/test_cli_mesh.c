/*
 * test_cli_mesh.c — the `anistar mesh` command (examples/anistar.c, DESIGN.md 3), run as a
 * separate process: a small mesh written in several formats with its .sol and --stats,
 * the counts of the OFF checked against the JSON and against Euler's formula for a sphere;
 * a run stopped at --max-vertices (exit 3, output still written); usage errors (exit 2)
 * and runtime errors (exit 1), each with one line on stderr.
 */
#include "test_util.h"

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


/* The counts of an OFF file; checks every face is a triangle with indices in range and
 * that no two faces share the same sorted triple. Returns 0 or -1. */
static int off_counts(const char *path, long *nv, long *nf) {
    FILE *f = fopen(path, "r");
    if (!f) return -1;
    char head[8];
    long ne;
    if (fscanf(f, "%7s %ld %ld %ld", head, nv, nf, &ne) != 4 || strcmp(head, "OFF")) {
        fclose(f);
        return -1;
    }
    for (long i = 0; i < *nv; i++) {
        double x, y, z;
        if (fscanf(f, "%lf %lf %lf", &x, &y, &z) != 3 || !isfinite(x + y + z)) {
            fclose(f);
            return -1;
        }
    }
    for (long i = 0; i < *nf; i++) {
        long k, a, b, c;
        if (fscanf(f, "%ld %ld %ld %ld", &k, &a, &b, &c) != 4 || k != 3 || a < 0 || b < 0 ||
            c < 0 || a >= *nv || b >= *nv || c >= *nv || a == b || b == c || a == c) {
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    return 0;
}

static void test_mesh_sphere(void **state) {
    (void)state;
    const char *off = AS_TEST_BUILD_DIR "/anistar_clim_s.off", *vtu = AS_TEST_BUILD_DIR "/anistar_clim_s.vtu",
               *sol = AS_TEST_BUILD_DIR "/anistar_clim_s.sol", *json = AS_TEST_BUILD_DIR "/anistar_clim_s.json";
    unlink(off), unlink(vtu), unlink(sol), unlink(json);
    const char *args[] = {"mesh", "--builtin", "sphere", "--metric", "euclidean", "--r0", "0.3",
                          "--seed", "7", "-o", off, "-o", vtu, "--sol", sol, "--stats", json,
                          NULL};
    run_result *r = test_malloc(sizeof *r);
    run(args, r);
    if (r->status != 0) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    long nv, nf;
    assert_int_equal(off_counts(off, &nv, &nf), 0);
    assert_true(nv >= 4);
    assert_int_equal(nf, 2 * nv - 4); /* a closed genus-0 triangle mesh */

    char *js = tu_read_file(json);
    assert_non_null(js);
    assert_true(tu_json_number(js, "vertices") == (double)nv);
    assert_true(tu_json_number(js, "facets") == (double)nf);
    assert_true(tu_json_number(js, "inconsistent_facets") == 0);
    assert_true(tu_json_number(js, "euler_characteristic") == 2);
    assert_int_equal(tu_json_bool(js, "closed_manifold"), 1);
    assert_int_equal(tu_json_bool(js, "complete"), 1);
    const char *sec = tu_json_value(js, "seconds"), *ins_o = tu_json_value(js, "insertions");
    assert_non_null(sec);
    assert_non_null(ins_o);
    double total = tu_json_number(sec, "total"), init = tu_json_number(sec, "init"),
           refine = tu_json_number(sec, "refine"), output = tu_json_number(sec, "output");
    assert_true(total >= 0 && init >= 0 && refine >= 0 && output >= 0);
    assert_true(init + refine + output <= total * 1.01 + 1e-3);
    double ins = tu_json_number(ins_o, "initial") + tu_json_number(ins_o, "rule1") +
                 tu_json_number(ins_o, "rule2") + tu_json_number(ins_o, "rule3");
    assert_true(ins >= (double)nv); /* every output vertex was inserted */
    const char *pv = tu_json_value(js, "pick_valid");
    assert_non_null(pv);
    assert_true(tu_json_number(pv, "tries") >= tu_json_number(pv, "failures"));
    /* the rules' points came in batches: every insertion by rules 1-3 is a job of a batch
     * that kept its stars */
    const char *ba = tu_json_value(js, "batches");
    assert_non_null(ba);
    double bjobs = tu_json_number(ba, "jobs"), blost = tu_json_number(ba, "lost");
    assert_true(tu_json_number(ba, "count") >= 1 && bjobs >= tu_json_number(ba, "count"));
    assert_true(blost >= 0 && tu_json_number(ba, "set_aside") >= 0);
    assert_true(tu_json_number(ins_o, "rule1") + tu_json_number(ins_o, "rule2") +
                    tu_json_number(ins_o, "rule3") <=
                bjobs - blost);
    /* the bounds hold on a finished mesh (euclidean: one metric, no distortion) */
    double rho = tu_json_number(js, "rho_max"), rmax = tu_json_number(js, "r_max");
    assert_true(rho > 0.5 && rho <= 3.0 + 1e-9); /* rho0 defaults to 3 */
    assert_true(rmax > 0 && rmax <= 0.3 + 1e-9);
    assert_true(fabs(tu_json_number(js, "gamma_max") - 1) < 1e-9);
    /* facets inscribed in the unit sphere with circumradius <= r_max <= 0.3 are within
     * 1 - sqrt(1 - 0.3^2) of it */
    const char *ae = tu_json_value(js, "approx_error");
    assert_non_null(ae);
    double emean = tu_json_number(ae, "mean"), emax = tu_json_number(ae, "max");
    assert_true(emean > 0 && emean <= emax && emax <= 1 - sqrt(1 - 0.09) + 1e-12);
    const char *par = tu_json_value(js, "parameters");
    assert_non_null(par);
    assert_true(tu_json_number(par, "r0") == 0.3);
    assert_true(tu_json_number(par, "seed") == 7);
    assert_true(tu_json_number(js, "seed") == 7);
    assert_true(tu_json_number(par, "aniso_cap") == 1); /* the default */
    assert_true(tu_json_number(par, "pick_tries") == 20); /* the default */
    assert_non_null(strstr(js, "\"euclidean\""));
    free(js);

    /* the .vtu and .sol describe the same mesh */
    char *vt = tu_read_file(vtu);
    assert_non_null(vt);
    char want[64];
    snprintf(want, sizeof want, "NumberOfPoints=\"%ld\"", nv);
    assert_non_null(strstr(vt, want));
    snprintf(want, sizeof want, "NumberOfCells=\"%ld\"", nf);
    assert_non_null(strstr(vt, want));
    free(vt);
    char *so = tu_read_file(sol);
    assert_non_null(so);
    const char *p = strstr(so, "SolAtVertices");
    assert_non_null(p);
    assert_true(strtol(p + strlen("SolAtVertices"), NULL, 10) == nv);
    free(so);
    assert_string_equal(r->out, "");
    /* render reads our .vtu (its metric) and --sol alone implies --color anisotropy: the
     * three images are the same bytes */
    const char *png[3] = {AS_TEST_BUILD_DIR "/anistar_clim_1.png", AS_TEST_BUILD_DIR "/anistar_clim_2.png",
                          AS_TEST_BUILD_DIR "/anistar_clim_3.png"};
    const char *r1[] = {"render", vtu, "-o", png[0], "--color", "anisotropy", "--size", "96x64",
                        NULL};
    const char *r2[] = {"render", off, "-o", png[1], "--sol", sol, "--size", "96x64", NULL};
    const char *r3[] = {"render", off, "-o", png[2], "--sol", sol, "--color", "anisotropy",
                        "--size", "96x64", NULL};
    const char *const *rr[3] = {r1, r2, r3};
    size_t len[3];
    char *img[3];
    for (int k = 0; k < 3; k++) {
        run(rr[k], r);
        if (r->status != 0) fail_msg("render %d: exit %d, stderr '%s'", k, r->status, r->err);
        FILE *f = fopen(png[k], "rb");
        assert_non_null(f);
        img[k] = malloc(1 << 20);
        len[k] = fread(img[k], 1, 1 << 20, f);
        fclose(f);
        unlink(png[k]);
    }
    assert_true(len[0] > 100 && len[0] == len[1] && len[1] == len[2]);
    assert_memory_equal(img[0], img[1], len[0]);
    assert_memory_equal(img[1], img[2], len[0]);
    for (int k = 0; k < 3; k++) free(img[k]);
    unlink(off), unlink(vtu), unlink(sol), unlink(json);
    test_free(r);
}

static void test_mesh_limit(void **state) {
    (void)state;
    const char *off = AS_TEST_BUILD_DIR "/anistar_clim_l.off", *json = AS_TEST_BUILD_DIR "/anistar_clim_l.json";
    unlink(off), unlink(json);
    /* the paper's torus at r0 0.5, gamma0 2 without the anisotropy cap: estimated at about
     * 1,500 vertices (rule 1's distortion bound makes it 7,300), so a limit of 2,000 lets
     * it start and stops it */
    const char *args[] = {"mesh", "--builtin", "torus", "--metric", "curvature,eps=0.1", "--r0",
                          "0.5", "--gamma0", "2", "--max-vertices", "2000", "--aniso-cap", "0",
                          "--quiet", "-o", off, "--stats", json, NULL};
    run_result *r = test_malloc(sizeof *r);
    run(args, r);
    if (r->status != 3) fail_msg("exit %d, stderr '%s'", r->status, r->err);
    /* --quiet silences the progress, not the result: one line saying why it stopped */
    tu_assert_one_line(r);
    assert_non_null(strstr(r->err, "incomplete (max_vertices)"));
    long nv, nf;
    assert_int_equal(off_counts(off, &nv, &nf), 0);
    char *js = tu_read_file(json);
    assert_non_null(js);
    assert_true(tu_json_number(js, "vertices") == (double)nv);
    assert_true(tu_json_number(js, "facets") == (double)nf);
    assert_int_equal(tu_json_bool(js, "complete"), 0);
    /* stopped before the size rule was satisfied: some facet is still too large (or some
     * facets were left out as inconsistent) */
    assert_true(nv <= 2000);
    assert_true(tu_json_number(js, "r_max") > 0.5 || tu_json_number(js, "inconsistent_facets") > 0);
    const char *par = tu_json_value(js, "parameters");
    assert_non_null(par);
    assert_true(tu_json_number(par, "max_vertices") == 2000);
    assert_true(tu_json_number(par, "aniso_cap") == 0);
    free(js);
    unlink(off), unlink(json);
    test_free(r);
}

static void test_usage_errors(void **state) {
    (void)state;
#define S "mesh", "--builtin", "sphere"
    const char *cases[][12] = {
        {S, "--frobnicate", "-o", "/tmp/x.off", NULL},
        {S, NULL},                                      /* missing -o */
        {S, "--r0", "abc", "-o", "/tmp/x.off", NULL},   /* bad number */
        {S, "--r0", "0", "-o", "/tmp/x.off", NULL},     /* r0 <= 0 */
        {S, "--gamma0", "1", "-o", "/tmp/x.off", NULL}, /* gamma0 <= 1 */
        {S, "--rho0", "0.5", "-o", "/tmp/x.off", NULL}, /* rho0 <= 1 */
        {S, "--delta", "1", "-o", "/tmp/x.off", NULL},  /* delta outside (0, 1) */
        {S, "--delta", "0", "-o", "/tmp/x.off", NULL},
        {S, "--beta", "0.9", "-o", "/tmp/x.off", NULL}, /* beta < 1 */
        {S, "-o", "/tmp/x.xyz", NULL}, /* unknown output extension */
        {S, "--max-vertices", "1.5", "-o", "/tmp/x.off", NULL},
        {S, "--metric", "bogus", "-o", "/tmp/x.off", NULL},
        {S, "--r0", NULL},
        {S, "--aniso-cap", "2", "-o", "/tmp/x.off", NULL},
        {S, "--fit", "smooth", "-o", "/tmp/x.off", NULL}, /* --fit without an image */
        {"mesh", AS_TEST_DATA_DIR "/skull_2.9.inr", "--fit", "spline", "-o", "/tmp/x.off", NULL},
    };
#undef S
    const char *msgs[] = {"unknown option", "-o",       "--r0",     "--r0",     "--gamma0",
                          "--rho0",         "--delta",  "--delta",  "--beta",
                          "extension",      "--max-vertices",       "--metric", "needs a value",
                          "--aniso-cap",    "--fit goes with an image", "--fit expects"};
    run_result *r = test_malloc(sizeof *r);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        run(cases[i], r);
        if (r->status != 2) fail_msg("case %zu: exit %d, stderr '%s'", i, r->status, r->err);
        assert_one_line(r);
        if (!strstr(r->err, msgs[i])) fail_msg("case %zu: '%s' lacks '%s'", i, r->err, msgs[i]);
        assert_string_equal(r->out, "");
    }
    test_free(r);
}

static void test_runtime_errors(void **state) {
    (void)state;
    /* a mask of one voxel in 3^3: its smoothing B-spline (automatic for a mask) peaks at
     * (2/3)^3 of the voxel, below the isovalue 0.5: no surface, and the message says how
     * to keep it */
    FILE *fp = fopen(AS_TEST_BUILD_DIR "/anistar_clim_one.raw", "wb");
    assert_non_null(fp);
    for (int i = 0; i < 27; i++) fputc(i == 13 ? 1 : 0, fp);
    fclose(fp);
    fp = fopen(AS_TEST_BUILD_DIR "/anistar_clim_one.mhd", "w");
    assert_non_null(fp);
    fprintf(fp, "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = "
                "False\nDimSize = 3 3 3\nElementType = MET_UCHAR\nElementDataFile = "
                "anistar_clim_one.raw\n");
    fclose(fp);
    const char *cases[][12] = {
        /* a mesh file that does not exist */
        {"mesh", AS_TEST_BUILD_DIR "/anistar_clim_missing.off", "-o", AS_TEST_BUILD_DIR "/anistar_clim_e.off", NULL},
        /* no zero of f inside the bounding sphere (ENOSURFACE) */
        {"mesh", "--implicit", "x^2+y^2+z^2+1", "--bound", "0,0,0,2", "-o",
         AS_TEST_BUILD_DIR "/anistar_clim_e.off", NULL},
        {"mesh", AS_TEST_BUILD_DIR "/anistar_clim_one.mhd", "--iso", "0.5", "--quiet", "-o",
         AS_TEST_BUILD_DIR "/anistar_clim_e.off", NULL},
    };
    const char *msgs[] = {"anistar_clim_missing.off", "no", "--fit interpolate keeps them"};
    run_result *r = test_malloc(sizeof *r);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        unlink(AS_TEST_BUILD_DIR "/anistar_clim_e.off");
        run(cases[i], r);
        if (r->status != 1) fail_msg("case %zu: exit %d, stderr '%s'", i, r->status, r->err);
        assert_one_line(r);
        if (!strstr(r->err, msgs[i])) fail_msg("case %zu: '%s' lacks '%s'", i, r->err, msgs[i]);
        assert_string_equal(r->out, "");
        assert_true(access(AS_TEST_BUILD_DIR "/anistar_clim_e.off", F_OK) != 0); /* nothing written */
    }
    /* with the interpolating fit the voxel is a blob: certified */
    const char *keep[] = {"mesh", AS_TEST_BUILD_DIR "/anistar_clim_one.mhd", "--iso", "0.5",
                          "--fit", "interpolate", "--quiet", "-o",
                          AS_TEST_BUILD_DIR "/anistar_clim_e.off", NULL};
    run(keep, r);
    if (r->status != 0) fail_msg("one voxel, interpolated: exit %d, stderr '%s'", r->status, r->err);
    unlink(AS_TEST_BUILD_DIR "/anistar_clim_e.off");
    unlink(AS_TEST_BUILD_DIR "/anistar_clim_one.mhd");
    unlink(AS_TEST_BUILD_DIR "/anistar_clim_one.raw");
    test_free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mesh_sphere),
        cmocka_unit_test(test_mesh_limit),
        cmocka_unit_test(test_usage_errors),
        cmocka_unit_test(test_runtime_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
