/*
 * test_cli_info.c — `anistar info` (examples/anistar.c, lib/io/info.c) run as a separate
 * process: on every mesh and image of test/data, its --json output is valid JSON and
 * byte-identical to the golden file test/golden/info/NAME.json (regenerate them all with
 *   ANISTAR_REGEN_GOLDEN=1 build/test/test_cli_info
 * and review the diff); its numbers are consistent (chi = V - E + F, the genus of every
 * closed orientable component, the components' sums); constructed meshes that cross,
 * touch at a vertex or are clean; a hostile file and usage errors.
 */
#include "test_util.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define TOOL AS_TEST_BUILD_DIR "/anistar"
#define GOLDEN "test/golden/info"

/* ---- a minimal JSON syntax check (RFC 8259 grammar, no semantics) ------------------ */

static const char *ws(const char *p) {
    while (*p == ' ' || *p == '\n' || *p == '\t' || *p == '\r') p++;
    return p;
}

static const char *value(const char *p, int depth);

static const char *string(const char *p) {
    if (*p++ != '"') return NULL;
    while (*p && *p != '"') {
        if ((unsigned char)*p < 0x20) return NULL;
        if (*p == '\\') {
            p++;
            if (!strchr("\"\\/bfnrtu", *p) || !*p) return NULL;
        }
        p++;
    }
    return *p == '"' ? p + 1 : NULL;
}

static const char *number(const char *p) {
    const char *s = p;
    if (*p == '-') p++;
    if (*p == '0') p++;
    else if (*p >= '1' && *p <= '9')
        while (*p >= '0' && *p <= '9') p++;
    else return NULL;
    if (*p == '.') {
        p++;
        if (!(*p >= '0' && *p <= '9')) return NULL;
        while (*p >= '0' && *p <= '9') p++;
    }
    if (*p == 'e' || *p == 'E') {
        p++;
        if (*p == '+' || *p == '-') p++;
        if (!(*p >= '0' && *p <= '9')) return NULL;
        while (*p >= '0' && *p <= '9') p++;
    }
    return p > s ? p : NULL;
}

static const char *value(const char *p, int depth) {
    if (depth > 32) return NULL;
    p = ws(p);
    if (*p == '{' || *p == '[') {
        char close = *p == '{' ? '}' : ']';
        p = ws(p + 1);
        if (*p == close) return p + 1;
        for (;;) {
            if (close == '}') {
                p = string(ws(p));
                if (!p) return NULL;
                p = ws(p);
                if (*p++ != ':') return NULL;
            }
            p = value(p, depth + 1);
            if (!p) return NULL;
            p = ws(p);
            if (*p == ',') {
                p++;
                continue;
            }
            return *p == close ? p + 1 : NULL;
        }
    }
    if (*p == '"') return string(p);
    if (!strncmp(p, "true", 4)) return p + 4;
    if (!strncmp(p, "false", 5)) return p + 5;
    if (!strncmp(p, "null", 4)) return p + 4;
    return number(p);
}

static int json_valid(const char *s) {
    const char *p = value(s, 0);
    return p && *ws(p) == '\0';
}

/* ---- helpers ------------------------------------------------------------------------ */

static long long num(const char *json, const char *key) {
    return (long long)tu_json_number(json, key);
}

static int is_image(const char *name) {
    static const char *const ext[] = {".inr", ".nrrd", ".nhdr", ".mha", ".mhd"};
    size_t n = strlen(name);
    for (size_t i = 0; i < 5; i++) {
        size_t k = strlen(ext[i]);
        if (n > k && !strcmp(name + n - k, ext[i])) return 1;
    }
    return 0;
}

static int is_mesh(const char *name) {
    static const char *const ext[] = {".off", ".obj", ".ply", ".stl", ".mesh", ".vtk", ".vtu"};
    size_t n = strlen(name);
    for (size_t i = 0; i < 7; i++) {
        size_t k = strlen(ext[i]);
        if (n > k && !strcmp(name + n - k, ext[i])) return 1;
    }
    return 0;
}

/* Mesh properties that must hold whatever the file. */
static void check_mesh_json(const char *j) {
    long long v = num(j, "used_vertices"), e = num(j, "edges"), f = num(j, "triangles");
    long long degenerate = num(j, "degenerate_triangles");
    assert_true(v <= num(j, "vertices"));
    if (degenerate == 0) assert_int_equal(num(j, "euler_characteristic"), v - e + f);
    /* the components listed: each chi = V - E + F, genus = (2 - chi) / 2 when closed and
     * orientable; with every component listed, their counts add up to the mesh's */
    const char *p = strstr(j, "\"per_component\"");
    assert_non_null(p);
    long long sv = 0, se = 0, sf = 0, listed = 0;
    while ((p = strstr(p, "{\"vertices\"")) != NULL) {
        long long cv = num(p, "vertices"), ce = num(p, "edges"), cf = num(p, "triangles");
        long long chi = num(p, "euler_characteristic");
        assert_int_equal(chi, cv - ce + cf);
        if (tu_json_bool(p, "closed") && tu_json_bool(p, "orientable"))
            assert_int_equal(2 * num(p, "genus"), 2 - chi);
        sv += cv;
        se += ce;
        sf += cf;
        listed++;
        p++;
    }
    if (listed == num(j, "components") && degenerate == 0) {
        assert_int_equal(sv, v);
        assert_int_equal(se, e);
        assert_int_equal(sf, f);
    }
    if (tu_json_bool(j, "closed_manifold"))
        assert_true(num(j, "border_edges") == 0 && num(j, "nonmanifold_edges") == 0);
}

static void test_data_golden(void **state) {
    (void)state;
    int regen = getenv("ANISTAR_REGEN_GOLDEN") != NULL;
    DIR *d = opendir(AS_TEST_DATA_DIR);
    assert_non_null(d);
    struct dirent *de;
    int files = 0, meshes = 0, images = 0;
    tu_run_result *r = test_malloc(sizeof *r);
    while ((de = readdir(d)) != NULL) {
        int img = is_image(de->d_name), msh = is_mesh(de->d_name);
        if (!img && !msh) continue;
        char path[512], golden[512];
        snprintf(path, sizeof path, "%s/%s", AS_TEST_DATA_DIR, de->d_name);
        snprintf(golden, sizeof golden, "%s/%s.json", GOLDEN, de->d_name);
        const char *args[] = {"info", path, "--json", NULL};
        tu_run(TOOL, args, r);
        if (r->status != 0) fail_msg("%s: exit %d: %s", path, r->status, r->err);
        assert_string_equal(r->err, "");
        if (!json_valid(r->out)) fail_msg("%s: invalid JSON:\n%s", path, r->out);
        if (msh) {
            check_mesh_json(r->out);
            meshes++;
        } else {
            assert_true(num(r->out, "voxels_inside") > 0 && num(r->out, "components") >= 1);
            images++;
        }
        if (regen) {
            FILE *f = fopen(golden, "w");
            assert_non_null(f);
            fputs(r->out, f);
            assert_int_equal(fclose(f), 0);
        }
        char *want = tu_read_file(golden);
        if (!want)
            fail_msg("%s: no golden file %s (run ANISTAR_REGEN_GOLDEN=1 %s)", path, golden,
                     AS_TEST_BUILD_DIR "/test/test_cli_info");
        if (strcmp(want, r->out))
            fail_msg("%s: the output differs from %s:\n%s", path, golden, r->out);
        free(want);
        files++;
        /* the plain text form names the file and exits 0 too */
        const char *targs[] = {"info", path, NULL};
        tu_run(TOOL, targs, r);
        assert_int_equal(r->status, 0);
        assert_non_null(strstr(r->out, path));
    }
    closedir(d);
    test_free(r);
    assert_true(meshes >= 6 && images >= 3);
    (void)files;
}

/* Write an OFF file of nv vertices and nt triangles into dir/name; return its path. */
static void write_off(const char *path, const double *xyz, int nv, const int *tri, int nt) {
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "OFF\n%d %d 0\n", nv, nt);
    for (int i = 0; i < nv; i++) fprintf(f, "%.17g %.17g %.17g\n", xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    for (int i = 0; i < nt; i++) fprintf(f, "3 %d %d %d\n", tri[3 * i], tri[3 * i + 1], tri[3 * i + 2]);
    assert_int_equal(fclose(f), 0);
}

/* Two unit tetrahedra with corners o1, o2; share: the second's corner is vertex 0. */
static void two_tets(const char *path, const double o1[3], const double o2[3], int share) {
    double xyz[24];
    int tri[24], nv = 0;
    const double *o[2] = {o1, o2};
    for (int k = 0; k < 2; k++) {
        double s = k && share ? -1 : 1;
        int a = k && share ? 0 : nv;
        if (!(k && share)) {
            memcpy(xyz + 3 * nv, o[k], 3 * sizeof(double));
            nv++;
        }
        int b = nv, c = nv + 1, d = nv + 2;
        for (int i = 0; i < 3; i++) {
            memcpy(xyz + 3 * (nv + i), o[k], 3 * sizeof(double));
            xyz[3 * (nv + i) + i] += s;
        }
        nv += 3;
        int t[12] = {a, c, b, a, b, d, a, d, c, b, c, d};
        memcpy(tri + 12 * k, t, sizeof t);
    }
    write_off(path, xyz, nv, tri, 8);
}

static void test_constructed(void **state) {
    (void)state;
    char dir[] = "/tmp/anistar-info-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char cross[600], touch[600], clean[600];
    snprintf(cross, sizeof cross, "%s/cross.off", dir);
    snprintf(touch, sizeof touch, "%s/touch.off", dir);
    snprintf(clean, sizeof clean, "%s/clean.off", dir);
    const double o[3] = {0, 0, 0}, in[3] = {0.2, 0.2, 0.2}, far[3] = {5, 0, 0};
    two_tets(cross, o, in, 0);
    two_tets(touch, o, o, 1);
    two_tets(clean, o, far, 0);
    tu_run_result *r = test_malloc(sizeof *r);
    const char *a1[] = {"info", cross, "--json", NULL};
    tu_run(TOOL, a1, r);
    assert_int_equal(r->status, 0);
    assert_true(json_valid(r->out));
    const char *si = strstr(r->out, "\"self_intersections\"");
    assert_non_null(si);
    assert_true(tu_json_number(si, "count") > 0);
    /* only the first one's slanted face (triangle 3) reaches the second's three faces
     * at the corner inside it */
    assert_int_equal((long long)tu_json_number(si, "count"), 3);
    assert_non_null(strstr(si, "\"pairs\": [[3, 4], [3, 5], [3, 6]]"));
    assert_int_equal(num(r->out, "components"), 2);
    assert_true(tu_json_bool(r->out, "closed_manifold"));
    check_mesh_json(r->out);
    /* shared corner vertex: a non-manifold vertex, no intersection */
    const char *a2[] = {"info", touch, "--json", NULL};
    tu_run(TOOL, a2, r);
    assert_int_equal(r->status, 0);
    si = strstr(r->out, "\"self_intersections\"");
    assert_int_equal((long long)tu_json_number(si, "count"), 0);
    assert_int_equal(num(r->out, "nonmanifold_vertices"), 1);
    assert_int_equal(num(r->out, "components"), 1);
    assert_false(tu_json_bool(r->out, "closed_manifold"));
    check_mesh_json(r->out);
    const char *a3[] = {"info", clean, "--json", NULL};
    tu_run(TOOL, a3, r);
    assert_int_equal(r->status, 0);
    si = strstr(r->out, "\"self_intersections\"");
    assert_int_equal((long long)tu_json_number(si, "count"), 0);
    assert_int_equal(num(r->out, "components"), 2);
    assert_non_null(strstr(r->out, "\"genus\": 0}"));
    check_mesh_json(r->out);
    /* the text form lists the first pairs */
    const char *a4[] = {"info", cross, NULL};
    tu_run(TOOL, a4, r);
    assert_int_equal(r->status, 0);
    assert_non_null(strstr(r->out, "self-intersections"));
    assert_non_null(strstr(r->out, "3: triangles 3-4, 3-5, 3-6"));
    remove(cross);
    remove(touch);
    remove(clean);
    rmdir(dir);
    test_free(r);
}

static void test_errors(void **state) {
    (void)state;
    char dir[] = "/tmp/anistar-info-XXXXXX";
    assert_non_null(mkdtemp(dir));
    char bad[600], big[600];
    snprintf(bad, sizeof bad, "%s/hostile.off", dir);
    snprintf(big, sizeof big, "%s/huge.off", dir);
    FILE *f = fopen(bad, "w");
    assert_non_null(f);
    fputs("OFF\n2000000000 1 0\n0 0 0\n", f); /* a count the file cannot hold */
    assert_int_equal(fclose(f), 0);
    f = fopen(big, "w");
    assert_non_null(f);
    fputs("OFF\n3 1 0\n0 0 0\n1e300 0 0\n0 1 0\n3 0 1 2\n", f); /* beyond the exact range */
    assert_int_equal(fclose(f), 0);
    tu_run_result *r = test_malloc(sizeof *r);
    const char *a1[] = {"info", bad, "--json", NULL};
    tu_run(TOOL, a1, r);
    assert_int_equal(r->status, 1);
    tu_assert_one_line(r);
    assert_non_null(strstr(r->err, "hostile.off"));
    assert_string_equal(r->out, "");
    const char *a2[] = {"info", big, NULL};
    tu_run(TOOL, a2, r);
    assert_int_equal(r->status, 1);
    tu_assert_one_line(r);
    assert_non_null(strstr(r->err, "huge.off"));
    const char *a3[] = {"info", "/nonexistent/x.off", NULL};
    tu_run(TOOL, a3, r);
    assert_int_equal(r->status, 1);
    tu_assert_one_line(r);
    const char *a4[] = {"info", NULL};
    tu_run(TOOL, a4, r);
    assert_int_equal(r->status, 2);
    tu_assert_one_line(r);
    const char *a5[] = {"info", AS_TEST_DATA_DIR "/knot1.off", "--iso", "2", NULL};
    tu_run(TOOL, a5, r);
    assert_int_equal(r->status, 2);
    tu_assert_one_line(r);
    const char *a6[] = {"info", AS_TEST_DATA_DIR "/knot1.off", "--bogus", NULL};
    tu_run(TOOL, a6, r);
    assert_int_equal(r->status, 2);
    tu_assert_one_line(r);
    /* --iso on an image: the given isovalue is used */
    const char *a7[] = {"info", AS_TEST_DATA_DIR "/skull_2.9.inr", "--iso", "2.9", "--json", NULL};
    tu_run(TOOL, a7, r);
    assert_int_equal(r->status, 0);
    assert_true(tu_json_number(r->out, "iso") == 2.9);
    assert_non_null(strstr(r->out, "\"iso_source\": \"given\""));
    remove(bad);
    remove(big);
    rmdir(dir);
    test_free(r);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_data_golden),
        cmocka_unit_test(test_constructed),
        cmocka_unit_test(test_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
