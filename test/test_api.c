/*
 * test_api — the public surface of the library: version, status table, contexts and
 * allocators, exported symbols of the shared library, soname, install/uninstall.
 */
#include "test_util.h"

#include "anistar.h"
#include "core.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__SANITIZE_ADDRESS__)
#define AS_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define AS_TEST_ASAN 1
#endif
#endif
#ifndef AS_TEST_ASAN
#define AS_TEST_ASAN 0
#endif

static void test_version(void **state) {
    (void)state;
    char want[64];
    snprintf(want, sizeof want, "%d.%d.%d", ANISTAR_VERSION_MAJOR, ANISTAR_VERSION_MINOR,
             ANISTAR_VERSION_PATCH);
    assert_string_equal(anistar_version(), want);
    assert_int_equal(anistar_version_number(), ANISTAR_VERSION_NUMBER);
    assert_int_equal(ANISTAR_VERSION_NUMBER, ANISTAR_VERSION_MAJOR * 10000 +
                                                 ANISTAR_VERSION_MINOR * 100 +
                                                 ANISTAR_VERSION_PATCH);
}

static void test_status_table(void **state) {
    (void)state;
    assert_int_equal(ANISTAR_OK, 0);
    /* Every status has its own non-empty message and name, taken from the one table. */
    for (int i = 0; i < ANISTAR_STATUS_COUNT_; i++) {
        const char *msg = anistar_status_string((anistar_status)i);
        const char *name = anistar_status_name((anistar_status)i);
        assert_non_null(msg);
        assert_true(strlen(msg) > 0);
        assert_string_not_equal(msg, "unknown status");
        assert_string_not_equal(name, "UNKNOWN");
        for (int j = 0; j < i; j++) {
            assert_string_not_equal(msg, anistar_status_string((anistar_status)j));
            assert_string_not_equal(name, anistar_status_name((anistar_status)j));
        }
    }
    assert_string_equal(anistar_status_name(ANISTAR_ENOMEM), "ENOMEM");
    assert_string_equal(anistar_status_name(ANISTAR_INCOMPLETE), "INCOMPLETE");
    assert_string_equal(anistar_status_string((anistar_status)ANISTAR_STATUS_COUNT_),
                        "unknown status");
    assert_string_equal(anistar_status_string((anistar_status)-1), "unknown status");
    assert_string_equal(anistar_status_name((anistar_status)1000), "UNKNOWN");
}

static void test_context_default(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    assert_string_equal(anistar_last_error(ctx), "");
    assert_int_equal(anistar_last_status(ctx), ANISTAR_OK);
    anistar_context_free(ctx);
    anistar_context_free(NULL);
    assert_true(strlen(anistar_last_error(NULL)) > 0);
}

static void test_context_allocator(void **state) {
    (void)state;
    tu_alloc a;
    tu_alloc_init(&a, -1);
    anistar_allocator al = tu_allocator(&a);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    assert_int_equal(a.live_blocks, 1); /* the context itself comes from the allocator */
    /* Library allocations go through it and are accounted for. */
    void *p = as_alloc(ctx, 100);
    assert_non_null(p);
    assert_int_equal(a.live_bytes, sizeof(struct anistar_context) + 100);
    void *q = NULL;
    size_t cap = 0;
    assert_int_equal(as_grow(ctx, &q, &cap, 1000, sizeof(double)), 0);
    assert_true(cap >= 1000);
    as_free(ctx, q, cap * sizeof(double));
    as_free(ctx, p, 100);
    anistar_context_free(ctx);
    assert_int_equal(a.live_blocks, 0);
    assert_int_equal(a.live_bytes, 0);

    /* An allocator that fails at once: no context, no crash. */
    tu_alloc_init(&a, 0);
    al = tu_allocator(&a);
    assert_null(anistar_context_new(&al));
    assert_int_equal(a.live_blocks, 0);
    /* An allocator without a function is refused. */
    anistar_allocator bad = {NULL, NULL};
    assert_null(anistar_context_new(&bad));
}

static void test_grow_overflow(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    void *q = NULL;
    size_t cap = 0;
    /* A size that overflows size_t is refused, not wrapped around. */
    assert_int_equal(as_grow(ctx, &q, &cap, SIZE_MAX / 2, 16), -1);
    assert_null(q);
    assert_int_equal(cap, 0);
    assert_null(as_alloc_array(ctx, SIZE_MAX / 4, 8));
    anistar_context_free(ctx);
}

static void test_error_messages(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    double g;
    double m[6] = {1, 0, 0, 1, 0, 1};
    assert_int_equal(anistar_tensor_distortion(ctx, m, NULL, &g), ANISTAR_EINVAL);
    assert_int_equal(anistar_last_status(ctx), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(ctx), "NULL"));
    /* Messages are one line even when the caller's text has newlines. */
    as_fail(ctx, ANISTAR_EIO, "cannot open 'a\nb': %s", "No such file");
    assert_null(strchr(anistar_last_error(ctx), '\n'));
    assert_int_equal(anistar_last_status(ctx), ANISTAR_EIO);
    /* Long messages are truncated, not overflowed. */
    char big[4 * AS_ERRMSG_SIZE];
    memset(big, 'x', sizeof big - 1);
    big[sizeof big - 1] = '\0';
    as_fail(ctx, ANISTAR_EFORMAT, "%s", big);
    assert_int_equal(strlen(anistar_last_error(ctx)), AS_ERRMSG_SIZE - 1);
    as_clear_error(ctx);
    assert_string_equal(anistar_last_error(ctx), "");
    anistar_context_free(ctx);
}

static void test_predicates_bad_input(void **state) {
    (void)state;
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0, 0, 1};
    double n[3] = {NAN, 0, 0};
    assert_true(isnan(anistar_orient3d(NULL, b, c, d)));
    assert_true(isnan(anistar_insphere(a, b, c, d, NULL)));
    assert_true(isnan(anistar_orient3d(a, b, c, n)));
    assert_true(isnan(anistar_insphere(a, b, c, d, n)));
    /* The conventions of the header: d below the plane of counterclockwise a, b, c. */
    double below[3] = {0, 0, -1};
    assert_true(anistar_orient3d(a, b, c, below) > 0);
    assert_true(anistar_orient3d(a, b, c, d) < 0);
}

/* Run a shell command, return its exit status, and keep its output for messages. */
static int run(const char *cmd, char *out, size_t outsz) {
    FILE *f = popen(cmd, "r");
    if (!f) return -1;
    size_t n = fread(out, 1, outsz - 1, f);
    out[n] = '\0';
    int st = pclose(f);
    return st;
}

static void test_exported_symbols(void **state) {
    (void)state;
    static char out[1 << 16];
    const char *so = AS_TEST_BUILD_DIR "/libanistar.so";
    char cmd[512];
    snprintf(cmd, sizeof cmd, "nm -D --defined-only %s", so);
    assert_int_equal(run(cmd, out, sizeof out), 0);
    int exported = 0, foreign = 0;
    int has_orient = 0, has_ctx = 0;
    for (char *line = strtok(out, "\n"); line; line = strtok(NULL, "\n")) {
        char *name = strrchr(line, ' ');
        name = name ? name + 1 : line;
        if (!strcmp(name, "_init") || !strcmp(name, "_fini") || !strcmp(name, "_edata") ||
            !strcmp(name, "_end") || !strcmp(name, "__bss_start"))
            continue;
        exported++;
        if (strncmp(name, "anistar_", 8) != 0) {
            print_error("exported symbol without the anistar_ prefix: %s\n", name);
            foreign++;
        }
        if (!strcmp(name, "anistar_orient3d")) has_orient = 1;
        if (!strcmp(name, "anistar_context_new")) has_ctx = 1;
    }
    assert_int_equal(foreign, 0);
    assert_true(exported >= 10);
    assert_true(has_orient && has_ctx);
    /* Internal symbols are hidden. */
    snprintf(cmd, sizeof cmd, "nm -D --defined-only %s | grep -c ' as_' || true", so);
    run(cmd, out, sizeof out);
    assert_int_equal(atoi(out), 0);
}

static void test_soname(void **state) {
    (void)state;
    char out[4096];
    char cmd[512];
    snprintf(cmd, sizeof cmd, "objdump -p %s/libanistar.so | grep SONAME", AS_TEST_BUILD_DIR);
    assert_int_equal(run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "libanistar.so.0"));
}

static void test_install(void **state) {
    (void)state;
    static char out[1 << 14];
    char cmd[512];
    snprintf(cmd, sizeof cmd, "PROG_CFLAGS='%s' sh test/install_check.sh %s 2>&1",
             AS_TEST_ASAN ? "-fsanitize=address,undefined" : "", AS_TEST_BUILD_DIR);
    int st = run(cmd, out, sizeof out);
    if (st != 0) print_error("%s\n", out);
    assert_int_equal(st, 0);
}

/* The layers call only downward: core, geom, mesh, io, surface, mesher, api
 * (test/layers_check.sh over the objects of this build). */
static void test_layers(void **state) {
    (void)state;
    static char out[1 << 14];
    char cmd[512];
    snprintf(cmd, sizeof cmd, "sh test/layers_check.sh %s 2>&1", AS_TEST_BUILD_DIR);
    int st = run(cmd, out, sizeof out);
    if (st != 0) print_error("%s\n", out);
    assert_int_equal(st, 0);
    assert_non_null(strstr(out, "every call downward"));
}

/* The check finds an upward call: a core object calling a function of an api object (as
 * lib/core.c called anistar_status_string of lib/api.c), built in a scratch tree. */
static void test_layers_catches_upward_call(void **state) {
    (void)state;
    static char out[1 << 14];
    char cmd[2048];
    snprintf(cmd, sizeof cmd,
             "d=$(mktemp -d \"${TMPDIR:-/tmp}/anistar-layers-t.XXXXXX\") && "
             "mkdir -p \"$d/obj/lib/geom\" && "
             "printf 'int top_fn(void);\\nint core_fn(void) { return top_fn(); }\\n' "
             ">\"$d/core.c\" && "
             "printf 'int geom_fn(void);\\nint top_fn(void) { return geom_fn(); }\\n' "
             ">\"$d/api.c\" && "
             "printf 'int geom_fn(void) { return 1; }\\n' >\"$d/g.c\" && "
             "cc -c \"$d/core.c\" -o \"$d/obj/lib/core.o\" && "
             "cc -c \"$d/api.c\" -o \"$d/obj/lib/api.o\" && "
             "cc -c \"$d/g.c\" -o \"$d/obj/lib/geom/g.o\" && "
             "sh test/layers_check.sh \"$d\" 2>&1; echo \"rc=$?\"; rm -rf \"$d\"");
    assert_int_equal(run(cmd, out, sizeof out), 0);
    if (!strstr(out, "rc=1")) print_error("%s\n", out);
    assert_non_null(strstr(out, "rc=1"));
    assert_non_null(strstr(out, "uses top_fn from"));
    /* the downward calls (api -> geom) are not reported */
    assert_null(strstr(out, "geom_fn"));
}

/* The API example of README.md compiles, runs and writes its mesh. */
static void test_readme_api(void **state) {
    (void)state;
    static char out[1 << 14];
    char cmd[512];
    snprintf(cmd, sizeof cmd, "PROG_CFLAGS='%s' sh test/readme_check.sh %s 2>&1",
             AS_TEST_ASAN ? "-fsanitize=address,undefined" : "", AS_TEST_BUILD_DIR);
    int st = run(cmd, out, sizeof out);
    if (st != 0) print_error("%s\n", out);
    assert_int_equal(st, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_version),
        cmocka_unit_test(test_status_table),
        cmocka_unit_test(test_context_default),
        cmocka_unit_test(test_context_allocator),
        cmocka_unit_test(test_grow_overflow),
        cmocka_unit_test(test_error_messages),
        cmocka_unit_test(test_predicates_bad_input),
        cmocka_unit_test(test_exported_symbols),
        cmocka_unit_test(test_soname),
        cmocka_unit_test(test_install),
        cmocka_unit_test(test_readme_api),
        cmocka_unit_test(test_layers),
        cmocka_unit_test(test_layers_catches_upward_call),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
