/*
 * test_fuzz_corpus.c — replays the fuzzing corpus (issue 5, part 7): every file under
 * test/fuzz/corpus/<reader>/ goes through that reader with the checks of the libFuzzer
 * harnesses (test/fuzz/fuzz_targets.c, included here because the Makefile links only
 * test/common into the tests): the reader returns OK (with an output that satisfies its
 * contract) or an error with a non-empty message, and every allocated byte is freed.
 * The corpus holds small valid files, interesting variants and every input a fuzzer
 * found a bug with, so `make check` keeps those bugs fixed.
 */
#include "test_util.h"

#include "fuzz/fuzz_targets.c"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FC_CORPUS_DIR "test/fuzz/corpus"

/* Read the whole file path into a malloc'ed buffer. */
static uint8_t *fc_slurp(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t cap = 4096, n = 0;
    uint8_t *buf = malloc(cap);
    assert_non_null(buf);
    for (;;) {
        if (n == cap) {
            cap *= 2;
            buf = realloc(buf, cap);
            assert_non_null(buf);
        }
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) break;
    }
    assert_int_equal(ferror(f), 0);
    fclose(f);
    *size = n;
    return buf;
}

/* Replay every regular file of the corpus directory of reader r; returns how many. */
static size_t fc_replay(ft_reader r) {
    char dir[256];
    snprintf(dir, sizeof dir, "%s/%s", FC_CORPUS_DIR, ft_reader_name(r));
    DIR *d = opendir(dir);
    if (!d) fail_msg("cannot open the corpus directory %s (run from the project root)", dir);
    size_t files = 0, ok = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        if (e->d_name[0] == '.') continue;
        char path[512];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        size_t size;
        uint8_t *data = fc_slurp(path, &size);
        ft_result res;
        ft_run(r, data, size, &res);
        free(data);
        if (!res.ok) fail_msg("%s: %s (status %d)", path, res.what, res.status);
        files++;
        ok += res.status == ANISTAR_OK;
    }
    closedir(d);
    /* Each corpus has at least one valid seed and one that the reader rejects. */
    if (files < 2 || ok == 0 || ok == files)
        fail_msg("%s: %zu files, %zu accepted: the corpus needs both valid and invalid seeds",
                 dir, files, ok);
    return files;
}

static void test_corpus_off(void **state) { (void)state; fc_replay(FT_OFF); }
static void test_corpus_obj(void **state) { (void)state; fc_replay(FT_OBJ); }
static void test_corpus_ply(void **state) { (void)state; fc_replay(FT_PLY); }
static void test_corpus_stl(void **state) { (void)state; fc_replay(FT_STL); }
static void test_corpus_medit(void **state) { (void)state; fc_replay(FT_MEDIT); }
static void test_corpus_sol(void **state) { (void)state; fc_replay(FT_SOL); }
static void test_corpus_inr(void **state) { (void)state; fc_replay(FT_INR); }
static void test_corpus_nrrd(void **state) { (void)state; fc_replay(FT_NRRD); }
static void test_corpus_metaimage(void **state) { (void)state; fc_replay(FT_METAIMAGE); }
static void test_corpus_expr(void **state) { (void)state; fc_replay(FT_EXPR); }
static void test_corpus_vtk(void **state) { (void)state; fc_replay(FT_VTK); }
static void test_corpus_vtu(void **state) { (void)state; fc_replay(FT_VTU); }
static void test_corpus_meshb(void **state) { (void)state; fc_replay(FT_MESHB); }
static void test_corpus_solb(void **state) { (void)state; fc_replay(FT_SOLB); }

/* The harness itself: the name table round-trips (the directory names select the
 * readers), an invalid reader is reported, the counting allocator sees a block that is
 * not freed, and every reader rejects an empty input with a message and no leak. */
static void test_harness_self_check(void **state) {
    (void)state;
    ft_alloc a = {0, 0, 0};
    void *p = ft_alloc_fn(&a, NULL, 0, 24);
    assert_non_null(p);
    assert_int_equal(a.live_blocks, 1);
    assert_int_equal(a.live_bytes, 24);
    p = ft_alloc_fn(&a, p, 24, 40);
    assert_non_null(p);
    assert_int_equal(a.live_bytes, 40);
    assert_null(ft_alloc_fn(&a, NULL, 0, FT_ALLOC_CAP + 1));
    ft_alloc_fn(&a, p, 40, 0);
    assert_int_equal(a.live_blocks, 0);
    assert_int_equal(a.live_bytes, 0);
    for (int i = 0; i < FT_READER_COUNT; i++)
        assert_int_equal(ft_reader_by_name(ft_reader_name((ft_reader)i)), i);
    assert_int_equal(ft_reader_by_name("nope"), FT_READER_COUNT);
    ft_result res;
    ft_run(FT_READER_COUNT, (const uint8_t *)"", 0, &res);
    assert_int_equal(res.ok, 0);
    /* An empty input is rejected with a message by every reader, without leaks. */
    for (int i = 0; i < FT_READER_COUNT; i++) {
        ft_run((ft_reader)i, (const uint8_t *)"", 0, &res);
        if (!res.ok) fail_msg("%s on empty input: %s", ft_reader_name((ft_reader)i), res.what);
        assert_int_not_equal(res.status, ANISTAR_OK);
    }
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_harness_self_check), cmocka_unit_test(test_corpus_off),
        cmocka_unit_test(test_corpus_obj),         cmocka_unit_test(test_corpus_ply),
        cmocka_unit_test(test_corpus_stl),         cmocka_unit_test(test_corpus_medit),
        cmocka_unit_test(test_corpus_sol),         cmocka_unit_test(test_corpus_inr),
        cmocka_unit_test(test_corpus_nrrd),        cmocka_unit_test(test_corpus_metaimage),
        cmocka_unit_test(test_corpus_expr),        cmocka_unit_test(test_corpus_vtk),
        cmocka_unit_test(test_corpus_vtu),         cmocka_unit_test(test_corpus_meshb),
        cmocka_unit_test(test_corpus_solb),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
