/*
 * test_util.h — shared by the test programs: a counting allocator with failure
 * injection (Lua's test build does the same), paths, and a deterministic RNG.
 */
#ifndef ANISTAR_TEST_UTIL_H
#define ANISTAR_TEST_UTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "anistar.h"

#ifndef AS_TEST_BUILD_DIR
#define AS_TEST_BUILD_DIR "build"
#endif
#ifndef AS_TEST_DATA_DIR
#define AS_TEST_DATA_DIR "test/data"
#endif

/* A counting allocator: fail_after < 0 never fails; otherwise the allocation number
 * fail_after (0-based, counting allocations and growing reallocations) and every later
 * one fail. live_bytes and live_blocks must be 0 after everything is freed. */
typedef struct tu_alloc {
    long fail_after;
    long count;
    long live_blocks;
    size_t live_bytes;
    size_t peak_bytes;
    long failures;
} tu_alloc;

void tu_alloc_init(tu_alloc *a, long fail_after);
anistar_allocator tu_allocator(tu_alloc *a);

/* SplitMix64 / xoshiro-style deterministic generator for tests. */
typedef struct tu_rng {
    uint64_t s;
} tu_rng;
uint64_t tu_rng_u64(tu_rng *r);
double tu_rng_unit(tu_rng *r); /* uniform in [0, 1) with 53 random bits */
double tu_rng_range(tu_rng *r, double lo, double hi);
double tu_rng_gauss(tu_rng *r); /* standard normal (Box-Muller, two draws) */

/* A uniformly random rotation (from a random unit quaternion: four gaussian draws),
 * row-major; its rows form an orthonormal frame. */
void tu_random_rotation(tu_rng *r, double q[9]);

/* n random points (3n doubles, malloc'd: free them; the test fails when out of memory):
 * uniform in the cube [-1, 1]^3; uniform on the unit sphere; on the torus of radii R, rr
 * around the z axis (uniform in its two angles). */
double *tu_pts_alloc(int n); /* room for n points, uninitialised */
double *tu_pts_cube(tu_rng *r, int n);
double *tu_pts_sphere(tu_rng *r, int n);
double *tu_pts_torus(tu_rng *r, int n, double R, double rr);

/* Running the command-line tool as a separate process (tests of examples/anistar.c). */
typedef struct tu_run_result {
    int status; /* exit code, or -1 if the program did not exit normally */
    char out[16384];
    char err[4096];
} tu_run_result;

/* Run program with args (NULL-terminated, without argv[0]; at most 62), capturing stdout
 * and stderr (truncated to the buffers). */
void tu_run(const char *program, const char *const *args, tu_run_result *res);

/* Fail unless stderr holds exactly one line starting with "anistar: ". */
void tu_assert_one_line(const tu_run_result *r);

/* The whole file (NUL-terminated, to free), or NULL if it cannot be read. */
char *tu_read_file(const char *path);

/* Reading the tool's --stats JSON: the value text after "key": (its first occurrence in
 * json), or NULL; a number or a boolean there (the test fails when the key is missing or
 * the value is not one). */
const char *tu_json_value(const char *json, const char *key);
double tu_json_number(const char *json, const char *key);
int tu_json_bool(const char *json, const char *key);

#endif
