/*
 * defaults_case.h — one input of test/data meshed with the defaults of `anistar mesh FILE
 * -o OUT` and checked (test_defaults.c: the triangle meshes; test_defaults_image.c: the
 * images). See defaults_case.c.
 */
#ifndef ANISTAR_TEST_DEFAULTS_CASE_H
#define ANISTAR_TEST_DEFAULTS_CASE_H

#include <stddef.h>

typedef struct dcase {
    const char *file;
    int image;
    long long chi; /* meshes: the input's Euler characteristic (test/data/README.md);
                      images: checked with comps when comps > 0 */
    size_t comps;  /* meshes: the input's components; images: 0 = not checked */
    int must; /* must end certified; otherwise bounded by DC_MAX_SECONDS */
} dcase;

#define DC_MAX_SECONDS 8.0

/* Mesh c->file with the defaults and check the result (fails the test on a violation);
 * *certified is incremented when the run ended certified. */
void dc_run_case(const dcase *c, int *certified);
/* Run the n cases; 1 iff at least as many ended certified as must (prints the count). */
int dc_run_all(const dcase *cases, size_t n);

#endif
