/*
 * test_meshio.c — triangle-mesh readers and writers (lib/io): the test data, every
 * writer/reader round trip, format variants, hostile files, allocation failures, and the
 * number parser.
 */
#include "test_util.h"

#include "core.h"
#include "io/meshio.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ==================================================================================== */
/* Helpers                                                                               */
/* ==================================================================================== */

#define DATA(f) AS_TEST_DATA_DIR "/" f

/* A context on the counting allocator; done() checks that nothing leaked. */
typedef struct tctx {
    tu_alloc a;
    anistar_allocator al;
    anistar_context *ctx;
} tctx;

static void tctx_init(tctx *t) {
    tu_alloc_init(&t->a, -1);
    t->al = tu_allocator(&t->a);
    t->ctx = anistar_context_new(&t->al);
    assert_non_null(t->ctx);
}

static void tctx_done(tctx *t) {
    anistar_context_free(t->ctx);
    assert_int_equal(t->a.live_blocks, 0);
    assert_int_equal(t->a.live_bytes, 0);
}

/* A temporary directory under /tmp, removed with the files made in it. */
typedef struct tdir {
    char path[128];
    char names[64][48];
    int n;
} tdir;

static void tdir_make(tdir *d) {
    snprintf(d->path, sizeof d->path, "/tmp/anistar_meshio_XXXXXX");
    assert_non_null(mkdtemp(d->path));
    d->n = 0;
}

/* The path of `name` in d (recorded for removal); buf has 256 bytes. */
static const char *tdir_file(tdir *d, const char *name, char *buf) {
    snprintf(buf, 256, "%s/%s", d->path, name);
    for (int i = 0; i < d->n; i++)
        if (strcmp(d->names[i], name) == 0) return buf;
    assert_true(d->n < 64 && strlen(name) < sizeof d->names[0]);
    snprintf(d->names[d->n++], sizeof d->names[0], "%s", name);
    return buf;
}

static void tdir_clean(tdir *d) {
    char buf[256];
    for (int i = 0; i < d->n; i++) {
        snprintf(buf, sizeof buf, "%s/%s", d->path, d->names[i]);
        remove(buf);
    }
    assert_int_equal(rmdir(d->path), 0);
}

static void write_bytes(const char *path, const void *data, size_t n) {
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static char *slurp(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t cap = 1 << 16, len = 0;
    char *buf = malloc(cap + 1);
    assert_non_null(buf);
    size_t got;
    while ((got = fread(buf + len, 1, cap - len, f)) > 0) {
        len += got;
        if (len == cap) {
            cap *= 2;
            buf = realloc(buf, cap + 1);
            assert_non_null(buf);
        }
    }
    fclose(f);
    buf[len] = '\0';
    *n = len;
    return buf;
}

/* A growable byte buffer for building test files. */
typedef struct sbuf {
    char *p;
    size_t n, cap;
} sbuf;

static void sb_put(sbuf *b, const void *d, size_t n) {
    if (b->n + n + 1 > b->cap) {
        b->cap = 2 * (b->n + n + 1) + 256;
        b->p = realloc(b->p, b->cap);
        assert_non_null(b->p);
    }
    memcpy(b->p + b->n, d, n);
    b->n += n;
    b->p[b->n] = '\0';
}

static void sb_printf(sbuf *b, const char *fmt, ...) AS_PRINTF(2, 3);
static void sb_printf(sbuf *b, const char *fmt, ...) {
    char tmp[4096];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(tmp, sizeof tmp, fmt, ap);
    va_end(ap);
    assert_true(n >= 0 && (size_t)n < sizeof tmp);
    sb_put(b, tmp, (size_t)n);
}

static void sb_free(sbuf *b) {
    free(b->p);
    b->p = NULL;
    b->n = b->cap = 0;
}

/* Parse len bytes from an exact-size heap copy (so that ASan sees any over-read). */
static anistar_status parse_mem(anistar_context *ctx, as_mesh_format fmt, const char *name,
                                const void *data, size_t len, as_trimesh *m) {
    char *buf = malloc(len + 1);
    assert_non_null(buf);
    memcpy(buf, data, len);
    buf[len] = '\0';
    anistar_status st;
    if (fmt == AS_FMT_SOL) {
        size_t n;
        double *t;
        st = as_sol_parse(ctx, name, buf, len, &n, &t);
        if (!st) {
            assert_non_null(t);
            assert_true(n > 0);
            as_free(ctx, t, n * 6 * sizeof(double));
        } else {
            assert_null(t);
        }
    } else {
        st = as_mesh_parse(ctx, fmt, name, buf, len, m);
    }
    free(buf);
    return st;
}

/* The mesh must be a valid reader output (counts, indices, finite coordinates). */
static void assert_valid_mesh(const as_trimesh *m) {
    assert_true(m->nv > 0 && m->nt > 0);
    for (size_t i = 0; i < 3 * m->nt; i++) assert_true(m->tri[i] >= 0 && (size_t)m->tri[i] < m->nv);
    for (size_t i = 0; i < 3 * m->nv; i++) assert_true(isfinite(m->xyz[i]));
}

static void assert_mesh_is(const as_trimesh *m, size_t nv, const double *xyz, size_t nt,
                           const int32_t *tri) {
    assert_int_equal(m->nv, nv);
    assert_int_equal(m->nt, nt);
    for (size_t i = 0; i < 3 * nv; i++) assert_true(m->xyz[i] == xyz[i]);
    for (size_t i = 0; i < 3 * nt; i++) assert_int_equal(m->tri[i], tri[i]);
}

static void assert_same_mesh(const as_trimesh *a, const as_trimesh *b) {
    assert_int_equal(a->nv, b->nv);
    assert_int_equal(a->nt, b->nt);
    assert_memory_equal(a->xyz, b->xyz, a->nv * 3 * sizeof(double));
    assert_memory_equal(a->tri, b->tri, a->nt * 3 * sizeof(int32_t));
}

/* Parse text expecting EFORMAT whose message names the file and contains `what`. */
static void expect_bad(as_mesh_format fmt, const char *text, size_t len, const char *what) {
    tctx t;
    tctx_init(&t);
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status st = parse_mem(t.ctx, fmt, "bad.file", text, len, &m);
    if (st != ANISTAR_EFORMAT || strncmp(anistar_last_error(t.ctx), "bad.file", 8) != 0 ||
        (what && !strstr(anistar_last_error(t.ctx), what)))
        fail_msg("status %d, message '%s' (wanted EFORMAT with '%s') for:\n%.300s", st,
                 anistar_last_error(t.ctx), what ? what : "", text);
    assert_int_equal(m.nv, 0);
    assert_null(m.xyz);
    tctx_done(&t);
}
#define BAD(fmt, text, what) expect_bad(fmt, text, sizeof(text) - 1, what)

static as_trimesh read_ok(tctx *t, const char *path) {
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status st = as_mesh_read(t->ctx, path, &m);
    if (st) fail_msg("%s: %s", path, anistar_last_error(t->ctx));
    assert_valid_mesh(&m);
    return m;
}

static as_trimesh parse_ok(tctx *t, as_mesh_format fmt, const void *text, size_t len) {
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status st = parse_mem(t->ctx, fmt, "mem", text, len, &m);
    if (st) fail_msg("%s\n--- for:\n%.400s", anistar_last_error(t->ctx), (const char *)text);
    assert_valid_mesh(&m);
    return m;
}

/* ==================================================================================== */
/* The test data                                                                         */
/* ==================================================================================== */

typedef struct data_file {
    const char *path;
    size_t nv, nt;
    long long chi, genus;
    double lo[3], hi[3]; /* bounding box as printed in the data README (3 digits) */
} data_file;

static const data_file data_files[] = {
    {DATA("bunny00.off"), 37706, 75408, 2, 0, {-0.499, -0.493, -0.387}, {0.499, 0.494, 0.386}},
    {DATA("elephant.off"), 2775, 5558, -4, 3, {-0.360, -0.5, -0.302}, {0.360, 0.5, 0.302}},
    {DATA("fandisk.off"), 6475, 12946, 2, 0, {-0.460, -0.256, -0.5}, {0.460, 0.256, 0.5}},
    {DATA("knot1.off"), 3200, 6400, 0, 1, {-0.480, -0.5, -0.232}, {0.480, 0.5, 0.232}},
    {DATA("sphere_r0.5.off"), 162, 320, 2, 0, {-0.5, -0.5, -0.5}, {0.5, 0.5, 0.5}},
    {DATA("ellipsoid.off"), 132, 260, 2, 0, {NAN, NAN, NAN}, {NAN, NAN, NAN}},
    {DATA("hinge.stl"), 598, 1212, -8, 5, {-0.18, -4.94, 0}, {49.8, 25.1, 10}},
    {DATA("lever.stl"), 377, 774, -10, 6, {-163, -76.2, 0}, {24.9, 24.9, 42.3}},
};

static void test_data_files(void **state) {
    (void)state;
    for (size_t f = 0; f < sizeof data_files / sizeof data_files[0]; f++) {
        const data_file *d = &data_files[f];
        tctx t;
        tctx_init(&t);
        as_trimesh m = read_ok(&t, d->path);
        if (m.nv != d->nv || m.nt != d->nt)
            fail_msg("%s: %zu V %zu T, expected %zu %zu", d->path, m.nv, m.nt, d->nv, d->nt);
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < m.nv; i++)
            for (int k = 0; k < 3; k++) {
                lo[k] = fmin(lo[k], m.xyz[3 * i + k]);
                hi[k] = fmax(hi[k], m.xyz[3 * i + k]);
            }
        for (int k = 0; k < 3; k++) {
            if (isnan(d->lo[k])) continue;
            double tol = 0.006 * (d->hi[k] - d->lo[k]); /* the README rounds to 3 digits */
            assert_true(fabs(lo[k] - d->lo[k]) <= tol);
            assert_true(fabs(hi[k] - d->hi[k]) <= tol);
        }
        as_topology r;
        assert_int_equal(as_topology_check(t.ctx, m.nv, m.xyz, m.nt, m.tri, &r), ANISTAR_OK);
        assert_true(r.closed_manifold && r.oriented && r.volume > 0);
        assert_int_equal(r.euler, d->chi);
        assert_int_equal(r.genus, d->genus);
        assert_int_equal(as_topology_require(t.ctx, d->path, &r), ANISTAR_OK);
        as_trimesh_free(t.ctx, &m);
        tctx_done(&t);
    }
}

/* lever.stl begins with "solid" but is binary: the size rule must win. */
static void test_stl_solid_trap(void **state) {
    (void)state;
    size_t n;
    char *d = slurp(DATA("lever.stl"), &n);
    assert_int_equal(strncmp(d, "solid", 5), 0);
    assert_int_equal(n, 84 + 50 * 774);
    tctx t;
    tctx_init(&t);
    as_trimesh m = parse_ok(&t, AS_FMT_STL, d, n);
    assert_int_equal(m.nv, 377);
    /* Every corner equals the float of the file (welding lost nothing). */
    for (size_t i = 0; i < 774; i++)
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) {
                float f;
                memcpy(&f, d + 84 + 50 * i + 12 + 12 * j + 4 * k, 4);
                assert_true(m.xyz[3 * m.tri[3 * i + j] + k] == (double)f);
            }
    as_trimesh_free(t.ctx, &m);
    tctx_done(&t);
    free(d);
}

/* ==================================================================================== */
/* Round trips                                                                           */
/* ==================================================================================== */

/* A mesh whose coordinates need all 17 digits: random bit patterns of every magnitude,
 * -0, subnormals, extremes; random tensors. */
static void hard_mesh(tctx *t, as_trimesh *m, size_t nv, size_t nt, uint64_t seed) {
    tu_rng r = {seed};
    as_trimesh_init(m);
    assert_int_equal(as_trimesh_reserve(t->ctx, m, nv, nt), ANISTAR_OK);
    static const double special[] = {0.0, -0.0, 4.9406564584124654e-324, -2.2250738585072014e-308,
                                     1.7976931348623157e308, -1e-300, 0.1, 1.0 / 3, 123456789.0};
    for (size_t i = 0; i < nv; i++) {
        double p[3];
        for (int k = 0; k < 3; k++) {
            uint64_t u = tu_rng_u64(&r);
            double x;
            if (u % 5 == 0)
                x = special[(u >> 8) % (sizeof special / sizeof special[0])];
            else {
                memcpy(&x, &u, sizeof x);
                if (!isfinite(x)) x = tu_rng_range(&r, -1, 1);
            }
            p[k] = x;
        }
        assert_int_equal(as_trimesh_add_vertex(t->ctx, m, p[0], p[1], p[2]), ANISTAR_OK);
    }
    for (size_t i = 0; i < nt; i++) {
        int32_t v[3];
        for (int k = 0; k < 3; k++) v[k] = (int32_t)(tu_rng_u64(&r) % nv);
        assert_int_equal(as_trimesh_add_triangle(t->ctx, m, v[0], v[1], v[2]), ANISTAR_OK);
    }
    assert_int_equal(as_trimesh_alloc_tensors(t->ctx, m), ANISTAR_OK);
    for (size_t i = 0; i < 6 * nv; i++) m->tensor[i] = tu_rng_range(&r, -1e3, 1e3) * pow(10, (double)(tu_rng_u64(&r) % 40) - 20);
}

static void roundtrip_one(tctx *t, tdir *d, const as_trimesh *m, const char *name,
                          int with_tensor) {
    char buf[256];
    const char *path = tdir_file(d, name, buf);
    anistar_status st = as_mesh_write(t->ctx, path, m, NULL, 0);
    if (st) fail_msg("%s", anistar_last_error(t->ctx));
    as_trimesh b;
    as_trimesh_init(&b);
    st = as_mesh_read(t->ctx, path, &b);
    if (st) fail_msg("%s", anistar_last_error(t->ctx));
    assert_same_mesh(m, &b);
    if (with_tensor) {
        assert_non_null(b.tensor);
        assert_memory_equal(m->tensor, b.tensor, m->nv * 6 * sizeof(double));
    } else {
        assert_null(b.tensor);
    }
    as_trimesh_free(t->ctx, &b);
}

static void test_roundtrip_exact(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    as_trimesh ms[3];
    ms[0] = read_ok(&t, DATA("sphere_r0.5.off"));
    ms[1] = read_ok(&t, DATA("elephant.off"));
    hard_mesh(&t, &ms[2], 500, 900, 42);
    for (int i = 0; i < 3; i++) {
        roundtrip_one(&t, &d, &ms[i], "a.off", 0);
        roundtrip_one(&t, &d, &ms[i], "a.OBJ", 0);
        roundtrip_one(&t, &d, &ms[i], "a.mesh", 0);
        roundtrip_one(&t, &d, &ms[i], "a.ply", ms[i].tensor != NULL);
        if (ms[i].tensor) {
            /* .sol: tensors exactly, through Medit's order. */
            char buf[256];
            const char *path = tdir_file(&d, "a.sol", buf);
            assert_int_equal(as_mesh_write(t.ctx, path, &ms[i], NULL, 0), ANISTAR_OK);
            size_t n;
            double *tt;
            assert_int_equal(as_sol_read(t.ctx, path, &n, &tt), ANISTAR_OK);
            assert_int_equal(n, ms[i].nv);
            assert_memory_equal(tt, ms[i].tensor, n * 6 * sizeof(double));
            as_free(t.ctx, tt, n * 6 * sizeof(double));
            as_trimesh c;
            as_trimesh_init(&c);
            assert_int_equal(as_trimesh_set(t.ctx, &c, ms[i].nv, ms[i].xyz, ms[i].nt, ms[i].tri,
                                            NULL),
                             ANISTAR_OK);
            assert_int_equal(as_trimesh_read_sol(t.ctx, path, &c), ANISTAR_OK);
            assert_memory_equal(c.tensor, ms[i].tensor, n * 6 * sizeof(double));
            as_trimesh_free(t.ctx, &c);
        }
    }
    for (int i = 0; i < 3; i++) as_trimesh_free(t.ctx, &ms[i]);
    tdir_clean(&d);
    tctx_done(&t);
}

/* The .sol file holds m11 m12 m22 m13 m23 m33; a scalar field h becomes h^-2 I. */
static void test_sol_order(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char buf[256];
    double xyz[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    int32_t tri[3] = {0, 1, 2};
    double ten[18] = {1, 2, 3, 4, 5, 6, 11, 12, 13, 14, 15, 16, 0.5, 0, 0, 0.5, 0, 0.5};
    as_trimesh m;
    as_trimesh_init(&m);
    assert_int_equal(as_trimesh_set(t.ctx, &m, 3, xyz, 1, tri, ten), ANISTAR_OK);
    const char *path = tdir_file(&d, "o.sol", buf);
    assert_int_equal(as_mesh_write(t.ctx, path, &m, NULL, 0), ANISTAR_OK);
    size_t n;
    char *text = slurp(path, &n);
    assert_non_null(strstr(text, "SolAtVertices\n3\n1 3\n1 2 4 3 5 6\n11 12 14 13 15 16\n"));
    free(text);
    /* Writing .sol without tensors is an error. */
    as_trimesh plain;
    as_trimesh_init(&plain);
    assert_int_equal(as_trimesh_set(t.ctx, &plain, 3, xyz, 1, tri, NULL), ANISTAR_OK);
    assert_int_equal(as_mesh_write(t.ctx, path, &plain, NULL, 0), ANISTAR_EINVAL);
    as_trimesh_free(t.ctx, &plain);
    /* An empty mesh (a run stopped before its first consistent facet) writes an empty
     * solution (a SIGINT early in a run once failed here with exit 1). */
    as_trimesh empty;
    as_trimesh_init(&empty);
    assert_int_equal(as_mesh_write(t.ctx, path, &empty, NULL, 0), ANISTAR_OK);
    text = slurp(path, &n);
    assert_non_null(strstr(text, "SolAtVertices\n0\n1 3\n"));
    free(text);
    /* A scalar size field, and a file with scalar + vector + tensor fields. */
    static const char scal[] = "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n2\n1 1\n"
                               "0.5\n4\nEnd\n";
    double *tt;
    assert_int_equal(as_sol_parse(t.ctx, "s.sol", scal, sizeof scal - 1, &n, &tt), ANISTAR_OK);
    assert_int_equal(n, 2);
    double want0[6] = {4, 0, 0, 4, 0, 4}, want1[6] = {1.0 / 16, 0, 0, 1.0 / 16, 0, 1.0 / 16};
    assert_memory_equal(tt, want0, sizeof want0);
    assert_memory_equal(tt + 6, want1, sizeof want1);
    as_free(t.ctx, tt, 12 * sizeof(double));
    static const char multi[] = "MeshVersionFormatted 1 Dimension 3 # comment\nSolAtVertices 1\n"
                                "3 1 2 3\n9 7 7 7 1 2 3 4 5 6\nEnd";
    assert_int_equal(as_sol_parse(t.ctx, "m.sol", multi, sizeof multi - 1, &n, &tt), ANISTAR_OK);
    double want2[6] = {1, 2, 4, 3, 5, 6};
    assert_memory_equal(tt, want2, sizeof want2);
    as_free(t.ctx, tt, 6 * sizeof(double));
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n1\n1 2\n1 2 3\nEnd\n",
        "no scalar or tensor");
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n1\n1 1\n0\nEnd\n",
        "not positive");
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n2\n1 3\n"
                    "1  2  3  4  5  6\n7  8  9\n", "bad.file:8: expected a solution value, found the end of the file");
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n1\n1 5\n1\n", "unknown");
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nEnd\n", "no SolAtVertices");
    BAD(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices 1 1 1 nan\n", "finite");
    /* A .sol whose count differs from the mesh's. */
    const char *p2 = tdir_file(&d, "two.sol", buf);
    write_bytes(p2, scal, sizeof scal - 1);
    assert_int_equal(as_trimesh_read_sol(t.ctx, p2, &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(t.ctx), "2 tensors for a mesh of 3 vertices"));
    assert_memory_equal(m.tensor, ten, sizeof ten);
    as_trimesh_free(t.ctx, &m);
    tdir_clean(&d);
    tctx_done(&t);
}

/* Binary STL: float32 coordinates, welding; exact for float data. */
static void test_roundtrip_stl(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char buf[256];
    const char *path = tdir_file(&d, "a.stl", buf);
    /* Decimal data: every corner comes back as the float of the original. */
    as_trimesh m = read_ok(&t, DATA("elephant.off"));
    assert_int_equal(as_mesh_write(t.ctx, path, &m, NULL, 0), ANISTAR_OK);
    size_t n;
    char *raw = slurp(path, &n);
    assert_int_equal(n, 84 + 50 * m.nt);
    assert_true(strncmp(raw, "solid", 5) != 0);
    free(raw);
    as_trimesh b;
    as_trimesh_init(&b);
    assert_int_equal(as_mesh_read(t.ctx, path, &b), ANISTAR_OK);
    assert_int_equal(b.nt, m.nt);
    assert_int_equal(b.nv, m.nv); /* distinct vertices stay distinct as floats here */
    for (size_t c = 0; c < 3 * m.nt; c++)
        for (int k = 0; k < 3; k++)
            assert_true(b.xyz[3 * b.tri[c] + k] == (double)(float)m.xyz[3 * m.tri[c] + k]);
    as_trimesh_free(t.ctx, &b);
    as_trimesh_free(t.ctx, &m);
    /* Float data (lever.stl): identical arrays after a second trip. */
    m = read_ok(&t, DATA("lever.stl"));
    assert_int_equal(as_mesh_write(t.ctx, path, &m, NULL, 0), ANISTAR_OK);
    as_trimesh_init(&b);
    assert_int_equal(as_mesh_read(t.ctx, path, &b), ANISTAR_OK);
    assert_same_mesh(&m, &b);
    as_trimesh_free(t.ctx, &b);
    /* A coordinate beyond float range cannot be written. */
    m.xyz[0] = 1e39;
    assert_int_equal(as_mesh_write(t.ctx, path, &m, NULL, 0), ANISTAR_EINVAL);
    as_trimesh_free(t.ctx, &m);
    tdir_clean(&d);
    tctx_done(&t);
}

/* ---- VTK / VTU: parsed back here ---------------------------------------------------- */

static double next_num(char **p) {
    char *end;
    double x = strtod(*p, &end);
    assert_true(end != *p);
    *p = end;
    return x;
}

static void expect_word(char **p, const char *w) {
    while (**p == ' ' || **p == '\n') (*p)++;
    size_t n = strlen(w);
    if (strncmp(*p, w, n) != 0) fail_msg("expected '%s' at '%.40s'", w, *p);
    *p += n;
}

static void check_vtk(const char *path, const as_trimesh *m, const as_cell_field *cf, size_t nc) {
    size_t n;
    char *text = slurp(path, &n), *p = text;
    expect_word(&p, "# vtk DataFile Version 3.0\n");
    p = strstr(p, "ASCII\nDATASET UNSTRUCTURED_GRID\n");
    assert_non_null(p);
    char head[64];
    snprintf(head, sizeof head, "POINTS %zu double", m->nv);
    p = strstr(p, head) + strlen(head);
    for (size_t i = 0; i < 3 * m->nv; i++) assert_true(next_num(&p) == m->xyz[i]);
    snprintf(head, sizeof head, "CELLS %zu %zu", m->nt, 4 * m->nt);
    expect_word(&p, head);
    for (size_t i = 0; i < m->nt; i++) {
        assert_true(next_num(&p) == 3);
        for (int k = 0; k < 3; k++) assert_true(next_num(&p) == m->tri[3 * i + k]);
    }
    snprintf(head, sizeof head, "CELL_TYPES %zu", m->nt);
    expect_word(&p, head);
    for (size_t i = 0; i < m->nt; i++) assert_true(next_num(&p) == 5);
    if (m->tensor) {
        snprintf(head, sizeof head, "POINT_DATA %zu", m->nv);
        expect_word(&p, head);
        expect_word(&p, "TENSORS metric double");
        static const int full[9] = {0, 1, 2, 1, 3, 4, 2, 4, 5};
        for (size_t i = 0; i < m->nv; i++)
            for (int k = 0; k < 9; k++) assert_true(next_num(&p) == m->tensor[6 * i + full[k]]);
    }
    if (nc) {
        snprintf(head, sizeof head, "CELL_DATA %zu", m->nt);
        expect_word(&p, head);
        for (size_t c = 0; c < nc; c++) {
            snprintf(head, sizeof head, "SCALARS %s double 1", cf[c].name);
            expect_word(&p, head);
            expect_word(&p, "LOOKUP_TABLE default");
            for (size_t i = 0; i < m->nt; i++) assert_true(next_num(&p) == cf[c].values[i]);
        }
    }
    while (*p == '\n') p++;
    assert_int_equal(*p, '\0');
    free(text);
}

static int b64_val(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

/* Decode the base64 body of the DataArray whose attributes contain `key` (e.g.
 * Name="metric"); returns the payload after checking the UInt64 byte-count header. */
static unsigned char *vtu_array(const char *text, const char *key, size_t *nbytes) {
    const char *a = strstr(text, key);
    if (!a) fail_msg("no DataArray with %s", key);
    const char *s = strchr(a, '>') + 1, *e = strstr(s, "</DataArray>");
    assert_non_null(e);
    unsigned char *out = malloc((size_t)(e - s));
    size_t n = 0;
    unsigned v = 0;
    int bits = 0;
    for (const char *p = s; p < e; p++) {
        if (*p == ' ' || *p == '\n') continue;
        if (*p == '=') break;
        int x = b64_val(*p);
        assert_true(x >= 0);
        v = v << 6 | (unsigned)x;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[n++] = (unsigned char)(v >> bits);
            v &= (1u << bits) - 1;
        }
    }
    assert_true(n >= 8);
    uint64_t hdr = as_ld_uint(out, 8, 0);
    assert_int_equal(hdr, n - 8);
    *nbytes = n - 8;
    memmove(out, out + 8, n - 8);
    return out;
}

static void check_vtu(const char *path, const as_trimesh *m, const as_cell_field *cf, size_t nc) {
    size_t n;
    char *text = slurp(path, &n);
    assert_non_null(strstr(text, "<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" "
                                 "byte_order=\"LittleEndian\" header_type=\"UInt64\">"));
    char head[128];
    snprintf(head, sizeof head, "<Piece NumberOfPoints=\"%zu\" NumberOfCells=\"%zu\">", m->nv, m->nt);
    assert_non_null(strstr(text, head));
    assert_non_null(strstr(text, "</Piece>\n  </UnstructuredGrid>\n</VTKFile>\n"));
    size_t nb;
    unsigned char *b = vtu_array(text, "NumberOfComponents=\"3\"", &nb);
    assert_int_equal(nb, 24 * m->nv);
    for (size_t i = 0; i < 3 * m->nv; i++) {
        uint64_t u = as_ld_uint(b + 8 * i, 8, 0);
        double x;
        memcpy(&x, &u, 8);
        assert_memory_equal(&x, &m->xyz[i], 8);
    }
    free(b);
    b = vtu_array(text, "Name=\"connectivity\"", &nb);
    assert_int_equal(nb, 24 * m->nt);
    for (size_t i = 0; i < 3 * m->nt; i++) assert_true(as_ld_uint(b + 8 * i, 8, 0) == (uint64_t)m->tri[i]);
    free(b);
    b = vtu_array(text, "Name=\"offsets\"", &nb);
    assert_int_equal(nb, 8 * m->nt);
    for (size_t i = 0; i < m->nt; i++) assert_true(as_ld_uint(b + 8 * i, 8, 0) == 3 * (i + 1));
    free(b);
    b = vtu_array(text, "Name=\"types\"", &nb);
    assert_int_equal(nb, m->nt);
    for (size_t i = 0; i < m->nt; i++) assert_int_equal(b[i], 5);
    free(b);
    if (m->tensor) {
        assert_non_null(strstr(text, "<PointData Tensors=\"metric\">"));
        b = vtu_array(text, "Name=\"metric\" NumberOfComponents=\"9\"", &nb);
        assert_int_equal(nb, 72 * m->nv);
        static const int full[9] = {0, 1, 2, 1, 3, 4, 2, 4, 5};
        for (size_t i = 0; i < m->nv; i++)
            for (int k = 0; k < 9; k++) {
                uint64_t u = as_ld_uint(b + 72 * i + 8 * k, 8, 0);
                double x;
                memcpy(&x, &u, 8);
                assert_true(x == m->tensor[6 * i + full[k]]);
            }
        free(b);
    }
    for (size_t c = 0; c < nc; c++) {
        snprintf(head, sizeof head, "Name=\"%s\"", cf[c].name);
        b = vtu_array(text, head, &nb);
        assert_int_equal(nb, 8 * m->nt);
        for (size_t i = 0; i < m->nt; i++) {
            uint64_t u = as_ld_uint(b + 8 * i, 8, 0);
            double x;
            memcpy(&x, &u, 8);
            assert_true(x == cf[c].values[i]);
        }
        free(b);
    }
    free(text);
}

static void test_vtk_vtu(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char b1[256], b2[256];
    as_trimesh m;
    hard_mesh(&t, &m, 60, 100, 7);
    double *q = malloc(m.nt * sizeof(double)), *an = malloc(m.nt * sizeof(double));
    for (size_t i = 0; i < m.nt; i++) {
        q[i] = 1.0 / (double)(i + 3);
        an[i] = -(double)i * 1e-17;
    }
    as_cell_field cf[2] = {{"quality", q}, {"anisotropy", an}};
    const char *pk = tdir_file(&d, "m.vtk", b1), *pu = tdir_file(&d, "m.vtu", b2);
    for (int variant = 0; variant < 3; variant++) {
        size_t nc = variant == 0 ? 2 : variant == 1 ? 1 : 0;
        if (variant == 2) {
            as_free(t.ctx, m.tensor, m.cap_m * 6 * sizeof(double));
            m.tensor = NULL;
            m.cap_m = 0;
        }
        assert_int_equal(as_mesh_write(t.ctx, pk, &m, cf, nc), ANISTAR_OK);
        check_vtk(pk, &m, cf, nc);
        assert_int_equal(as_mesh_write(t.ctx, pu, &m, cf, nc), ANISTAR_OK);
        check_vtu(pu, &m, cf, nc);
    }
    /* Invalid field names and values. */
    as_cell_field badname = {"two words", q};
    assert_int_equal(as_mesh_write(t.ctx, pk, &m, &badname, 1), ANISTAR_EINVAL);
    q[3] = NAN;
    assert_int_equal(as_mesh_write(t.ctx, pu, &m, cf, 1), ANISTAR_EINVAL);
    assert_non_null(strstr(anistar_last_error(t.ctx), "quality"));
    free(q);
    free(an);
    as_trimesh_free(t.ctx, &m);
    tdir_clean(&d);
    tctx_done(&t);
}

/* Write errors: no such directory, a full device, an invalid mesh, an unknown extension. */
static void test_write_errors(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    as_trimesh m = read_ok(&t, DATA("sphere_r0.5.off"));
    assert_int_equal(as_mesh_write(t.ctx, "/nonexistent-dir/x.off", &m, NULL, 0), ANISTAR_EIO);
    assert_non_null(strstr(anistar_last_error(t.ctx), "/nonexistent-dir/x.off"));
    assert_non_null(strstr(anistar_last_error(t.ctx), strerror(ENOENT)));
    static const char *exts[] = {"full.off", "full.obj", "full.ply", "full.stl", "full.mesh",
                                 "full.vtk", "full.vtu"};
    char buf[256];
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++) {
        const char *p = tdir_file(&d, exts[i], buf);
        assert_int_equal(symlink("/dev/full", p), 0);
        assert_int_equal(as_mesh_write(t.ctx, p, &m, NULL, 0), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(t.ctx), strerror(ENOSPC)));
        /* A failed write never removes what existed before it: the link stays and the
         * device it names is still a device (as root, removing it would be a disaster). */
        struct stat sb;
        assert_int_equal(lstat(p, &sb), 0);
        assert_true(S_ISLNK(sb.st_mode));
        assert_int_equal(stat("/dev/full", &sb), 0);
        assert_true(S_ISCHR(sb.st_mode));
    }
    assert_int_equal(as_mesh_write(t.ctx, tdir_file(&d, "x.xyz", buf), &m, NULL, 0),
                     ANISTAR_EFORMAT);
    /* Readers accept regular files only (a device would never end). */
    {
        char zb[256];
        const char *z = tdir_file(&d, "zero.off", zb);
        assert_int_equal(symlink("/dev/zero", z), 0);
        as_trimesh zm;
        as_trimesh_init(&zm);
        assert_int_equal(as_mesh_read(t.ctx, z, &zm), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(t.ctx), "not a regular file"));
        assert_int_equal(zm.nv, 0);
    }
    const char *p = tdir_file(&d, "x.off", buf);
    m.tri[7] = (int32_t)m.nv;
    assert_int_equal(as_mesh_write(t.ctx, p, &m, NULL, 0), ANISTAR_EINVAL);
    m.tri[7] = -1;
    assert_int_equal(as_mesh_write(t.ctx, p, &m, NULL, 0), ANISTAR_EINVAL);
    m.tri[7] = 0;
    m.xyz[4] = NAN;
    assert_int_equal(as_mesh_write(t.ctx, p, &m, NULL, 0), ANISTAR_EINVAL);
    assert_int_equal(access(p, F_OK), -1); /* nothing was created */
    as_trimesh_free(t.ctx, &m);
    tdir_clean(&d);
    tctx_done(&t);
}

static long enomem_sweep(const char *path, int sol);

/* ==================================================================================== */
/* Format variants                                                                       */
/* ==================================================================================== */

/* A square pyramid: base quad 0 3 2 1 (fanned), four sides. */
static const double pyr_xyz[15] = {0.5, -1.25, 0, 2.75, -1.25, 0, 2.75, 3.5, 0, 0.5, 3.5, 0,
                                   1.625, 1.125, 7};
static const int32_t pyr_tri[18] = {0, 3, 2, 0, 2, 1, 0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4};

static void check_pyramid(const char *fmt_text, as_mesh_format fmt, size_t len) {
    tctx t;
    tctx_init(&t);
    as_trimesh m = parse_ok(&t, fmt, fmt_text, len);
    assert_mesh_is(&m, 5, pyr_xyz, 6, pyr_tri);
    as_trimesh_free(t.ctx, &m);
    tctx_done(&t);
}
#define PYR(fmt, text) check_pyramid(text, fmt, sizeof(text) - 1)

static void test_off_variants(void **state) {
    (void)state;
    /* COFF with rgba integers, comments before the header and between lines, blank lines,
     * trailing comments, face colours (floats or integers) after the indices; a quad and a
     * pentagon become fans (v0 vi vi+1). */
    {
        static const char txt[] =
            "# made by hand\n#\n\nCOFF\n# counts follow\n5 2 0\n"
            "0.5 -1.25 0 255 0 0 255\n2.75 -1.25 0 0 255 0 255 # a comment\n\n"
            "2.75 3.5 0 0 0 255 255\n# between\n0.5 3.5 0 9 9 9 9\n1.625 1.125 7 1 1 1 1\n"
            "4 0 3 2 1 0.5 0.5 0.5 1\n5 4 0 1 2 3 255 0 0\n";
        static const int32_t fan[15] = {0, 3, 2, 0, 2, 1, 4, 0, 1, 4, 1, 2, 4, 2, 3};
        tctx t;
        tctx_init(&t);
        as_trimesh m = parse_ok(&t, AS_FMT_OFF, txt, sizeof txt - 1);
        assert_mesh_is(&m, 5, pyr_xyz, 5, fan);
        as_trimesh_free(t.ctx, &m);
        tctx_done(&t);
    }
    PYR(AS_FMT_OFF, "OFF 5 5 12\n0.5 -1.25 0\n2.75 -1.25 0\n2.75 3.5 0\n0.5 3.5 0\n1.625 1.125 7\n"
                    "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4");
    /* CRLF, NOFF with normals, no edge count, no newline at the end, a 1 MB comment line,
     * faces of 0, 1 and 2 vertices (ignored). */
    {
        sbuf b = {0};
        sb_printf(&b, "NOFF\r\n5 8\r\n#");
        for (int i = 0; i < 1 << 20; i++) sb_put(&b, "x", 1);
        sb_printf(&b, "\r\n0.5 -1.25 0 0 0 1\r\n2.75 -1.25 0 0 0 1\r\n2.75 3.5 0 0 0 1\r\n"
                      "0.5 3.5 0 0 0 1\r\n1.625 1.125 7 0 0 1\r\n0\r\n1 3\r\n2 0 4\r\n"
                      "4 0 3 2 1\r\n3 0 1 4\r\n3 1 2 4\r\n3 2 3 4\r\n3 3 0 4");
        check_pyramid(b.p, AS_FMT_OFF, b.n);
        sb_free(&b);
    }
    /* STOFF, CNOFF headers; scientific notation; signs; UTF-8 BOM. */
    PYR(AS_FMT_OFF, "\xEF\xBB\xBFSTOFF\n5 5 0\n5e-1 -1.25e0 0 0 0\n+2.75 -125E-2 -0 1 1\n"
                    "2.75 3.5 0.0 1 1\n.5 35e-1 0 1 1\n1.625 1.125 7. 1 1\n"
                    "4 0 3 2 1\n3 0 1 4\n3 1 2 4\n3 2 3 4\n3 3 0 4\n");
    /* Headers that are not supported or not OFF. */
    BAD(AS_FMT_OFF, "4OFF\n1 1 0\n0 0 0 0\n", "4OFF");
    BAD(AS_FMT_OFF, "OFF BINARY\n", "binary OFF");
    BAD(AS_FMT_OFF, "PLY\n", "not an OFF file");
    BAD(AS_FMT_OFF, "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "no triangles");
    BAD(AS_FMT_OFF, "OFF\n3 1\n0 0 0\n1 0 0\n0 1\n3 0 1 2\n", "bad.file:5: expected a vertex coordinate");
    BAD(AS_FMT_OFF, "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", "face 0: expected 4 vertex indices");
    BAD(AS_FMT_OFF, "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2.5\n", "expected a vertex index");
    BAD(AS_FMT_OFF, "OFF\n3 1\n0 0 0\n1 0 0\n0 1 0\n2 0 3\n3 0 1 2\n", "out of range");
    BAD(AS_FMT_OFF, "OFF\n-3 1\n", "negative");
}

static void test_obj_variants(void **state) {
    (void)state;
    static const char obj[] =
        "# a pyramid\nmtllib pyr.mtl\no pyramid\n"
        "v 0.5 -1.25 0\nv 2.75 -1.25 0 1.0\nv 2.75 3.5 0 0.5 0.5 0.5\nv 0.5 3.5 0 1 0.2 0.3 0.4\n"
        "vt 0 0\nvt 1 0 0\nvn 0 0 1\nvp 0.5\ng base\nusemtl red\ns off\n"
        "f 1/1/1 4/2/1 3/1/1 2/1/1\n"
        "v 1.625 1.125 \\\n 7\n"
        "f -5 -4 -1\n"
        "f 2//1 3//1 5//1\n"
        "f -3/1 -2/2 -1/1\n"
        "fo 4 \\\n 1 5\n"
        "l 1 2\np 1\ncstype bezier\nf 1 2\n";
    PYR(AS_FMT_OBJ, obj);
    /* The same with CRLF line ends (the continuation too) and no final newline. */
    {
        sbuf b = {0};
        for (const char *p = obj; *p; p++) {
            if (*p == '\n') sb_put(&b, "\r", 1);
            sb_put(&b, p, 1);
        }
        b.n -= 2; /* drop the last CRLF */
        check_pyramid(b.p, AS_FMT_OBJ, b.n);
        sb_free(&b);
    }
    /* Forward references are fine, as long as the vertex comes eventually. */
    PYR(AS_FMT_OBJ, "f 1 4 3 2\nf 1 2 5\nf 2 3 5\nf 3 4 5\nf 4 1 5\n"
                    "v 0.5 -1.25 0\nv 2.75 -1.25 0\nv 2.75 3.5 0\nv 0.5 3.5 0\nv 1.625 1.125 7\n");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "indices start at 1");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "bad.file:4: vertex index 4 out of range");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n", "out of range");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/2/3/4 2 3\n", "malformed");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n", "malformed");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\n", "no triangles");
    BAD(AS_FMT_OBJ, "v 0 0 0\n\x01\x02 garbage\n", "expected an OBJ statement");
    BAD(AS_FMT_OBJ, "v 0 0\nf 1 1 1\n", "bad.file:1: expected a vertex coordinate, found the end of the line");
}

/* ---- PLY: the same mesh as ascii, binary little and big endian ------------------------ */

static int ply_tsize(const char *ty) {
    static const struct {
        const char *n;
        int s;
    } t[] = {{"char", 1},  {"uchar", 1},  {"int8", 1},   {"uint8", 1},   {"short", 2},
             {"ushort", 2}, {"int16", 2}, {"uint16", 2}, {"int", 4},     {"uint", 4},
             {"int32", 4}, {"uint32", 4}, {"float", 4},  {"float32", 4}, {"double", 8},
             {"float64", 8}};
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
        if (strcmp(t[i].n, ty) == 0) return t[i].s;
    fail_msg("type %s", ty);
    return 0;
}

/* Append value v of PLY type ty in format fmt (0 ascii, 1 LE, 2 BE). */
static void ply_put(sbuf *b, int fmt, const char *ty, double v) {
    int isf = strncmp(ty, "float", 5) == 0 || strcmp(ty, "double") == 0;
    if (fmt == 0) {
        if (isf)
            sb_printf(b, "%.17g ", v);
        else
            sb_printf(b, "%lld ", (long long)v);
        return;
    }
    int sz = ply_tsize(ty);
    uint64_t u;
    if (isf && sz == 4) {
        float f = (float)v;
        uint32_t w;
        memcpy(&w, &f, 4);
        u = w;
    } else if (isf) {
        memcpy(&u, &v, 8);
    } else {
        u = (uint64_t)(int64_t)v;
    }
    unsigned char by[8];
    for (int i = 0; i < sz; i++) by[fmt == 1 ? i : sz - 1 - i] = (unsigned char)(u >> (8 * i));
    sb_put(b, by, (size_t)sz);
}

static void ply_pyramid(sbuf *b, int fmt, int faces_first) {
    static const char *fmts[] = {"ascii", "binary_little_endian", "binary_big_endian"};
    sb_printf(b, "ply\nformat %s 1.0\ncomment a pyramid\nobj_info made by a test\n", fmts[fmt]);
    const char *vhead = "element vertex 5\nproperty float x\nproperty uchar red\n"
                        "property float64 y\nproperty list uchar float texcoord\n"
                        "property int16 z\nproperty float32 nx\n";
    const char *fhead = "element face 5\nproperty uchar flags\n"
                        "property list uchar uint vertex_indices\n"
                        "property list ushort int16 extra\n";
    const char *ehead = "element edge 2\nproperty int vertex1\nproperty int32 vertex2\n"
                        "property list uint8 uint8 colour\n";
    if (faces_first)
        sb_printf(b, "%s%s%s", fhead, ehead, vhead);
    else
        sb_printf(b, "%s%s%s", vhead, ehead, fhead);
    sb_printf(b, "element material 1\nproperty double ambient\nend_header\n");
    static const int faces[5][5] = {{4, 0, 3, 2, 1}, {3, 0, 1, 4}, {3, 1, 2, 4}, {3, 2, 3, 4},
                                    {3, 3, 0, 4}};
    for (int part = 0; part < 3; part++) {
        int which = faces_first ? (part == 0 ? 2 : part == 1 ? 1 : 0) : part;
        if (which == 0)
            for (int i = 0; i < 5; i++) {
                ply_put(b, fmt, "float", pyr_xyz[3 * i]);
                ply_put(b, fmt, "uchar", 200 + i);
                ply_put(b, fmt, "float64", pyr_xyz[3 * i + 1]);
                ply_put(b, fmt, "uchar", 2);
                ply_put(b, fmt, "float", 0.25);
                ply_put(b, fmt, "float", -0.5);
                ply_put(b, fmt, "int16", pyr_xyz[3 * i + 2]);
                ply_put(b, fmt, "float32", 1e-3);
                if (fmt == 0) sb_printf(b, "\n");
            }
        if (which == 1)
            for (int i = 0; i < 2; i++) {
                ply_put(b, fmt, "int", i);
                ply_put(b, fmt, "int32", i + 1);
                ply_put(b, fmt, "uint8", 3);
                for (int k = 0; k < 3; k++) ply_put(b, fmt, "uint8", 10 * k);
                if (fmt == 0) sb_printf(b, "\n");
            }
        if (which == 2)
            for (int i = 0; i < 5; i++) {
                ply_put(b, fmt, "uchar", 7);
                ply_put(b, fmt, "uchar", faces[i][0]);
                for (int k = 1; k <= faces[i][0]; k++) ply_put(b, fmt, "uint", faces[i][k]);
                ply_put(b, fmt, "ushort", i % 2);
                if (i % 2) ply_put(b, fmt, "int16", -300);
                if (fmt == 0) sb_printf(b, "\n");
            }
    }
    ply_put(b, fmt, "double", 0.125);
}

static void test_ply_variants(void **state) {
    (void)state;
    for (int ff = 0; ff < 2; ff++)
        for (int fmt = 0; fmt < 3; fmt++) {
            sbuf b = {0};
            ply_pyramid(&b, fmt, ff);
            check_pyramid(b.p, AS_FMT_PLY, b.n);
            sb_free(&b);
        }
    /* vertex_index, a signed list count, CRLF header in ascii. */
    PYR(AS_FMT_PLY, "ply\r\nformat ascii 1.0\r\nelement vertex 5\r\nproperty double x\r\n"
                    "property double y\r\nproperty double z\r\nelement face 5\r\n"
                    "property list char int vertex_index\r\nend_header\r\n"
                    "0.5 -1.25 0\r\n2.75 -1.25 0\r\n2.75 3.5 0\r\n0.5 3.5 0\r\n1.625 1.125 7\r\n"
                    "4 0 3 2 1\r\n3 0 1 4\r\n3 1 2 4\r\n3 2 3 4\r\n3 3 0 4");
    /* Tensors m11..m33 are read when all six are there. */
    {
        tctx t;
        tctx_init(&t);
        static const char txt[] = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                                  "property float y\nproperty float z\nproperty float m11\n"
                                  "property float m12\nproperty float m13\nproperty float m22\n"
                                  "property float m23\nproperty float m33\nelement face 1\n"
                                  "property list uchar int vertex_indices\nend_header\n"
                                  "0 0 0 1 2 3 4 5 6\n1 0 0 1 0 0 1 0 1\n0 1 0 2 0 0 2 0 2\n"
                                  "3 0 1 2\n";
        as_trimesh m = parse_ok(&t, AS_FMT_PLY, txt, sizeof txt - 1);
        assert_non_null(m.tensor);
        double want[18] = {1, 2, 3, 4, 5, 6, 1, 0, 0, 1, 0, 1, 2, 0, 0, 2, 0, 2};
        assert_memory_equal(m.tensor, want, sizeof want);
        as_trimesh_free(t.ctx, &m);
        tctx_done(&t);
    }
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list float int vertex_indices\n"
                    "end_header\n", "list count type 'float' is not an integer type");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar double vertex_indices\n"
                    "end_header\n", "integer type");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty list uchar float x\n",
        "must be a scalar");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty foo x\n",
        "bad.file:4: unknown property type 'foo'");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty int vertex_indices\nend_header\n",
        "must be a list");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0\n1 0\n0 1\n3 0 1 2\n", "lacks property x, y or z");
    BAD(AS_FMT_PLY, "ply\nformat binary_middle_endian 1.0\n", "unknown PLY format");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n", "no end_header");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "out of range");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "out of range");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "end_header\n0 0 0\n1 0 0\n0 1 0\n-3 0 1 2\n", "negative list length");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nproperty float w\nelement face 1\n"
                    "property list uchar int vertex_indices\nend_header\n"
                    "0 0 0 q\n1 0 0 1\n0 1 0 1\n3 0 1 2\n", "expected a number, found 'q'");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                    "element empty 5\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n",
        "has no properties");
    BAD(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n", "no 'face' element");
    BAD(AS_FMT_PLY, "solid\n", "not a PLY file");
}

/* ---- STL ------------------------------------------------------------------------------ */

static const double tet_xyz[12] = {0, 0, 0, 1.5, 0, 0, 0, 2.25, 0, 0, 0, -0.75};
static const int32_t tet_tri[12] = {0, 1, 2, 0, 3, 1, 1, 3, 2, 2, 3, 0};

/* Binary STL of the tetrahedron, with a header that starts with "solid". */
static void stl_binary_tet(sbuf *b) {
    char head[80];
    memset(head, ' ', sizeof head);
    memcpy(head, "solid binary STL from a CAD system", 34);
    sb_put(b, head, 80);
    unsigned char n[4] = {4, 0, 0, 0};
    sb_put(b, n, 4);
    for (int t = 0; t < 4; t++) {
        float rec[12] = {0, 0, 0};
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) rec[3 + 3 * j + k] = (float)tet_xyz[3 * tet_tri[3 * t + j] + k];
        for (int i = 0; i < 12; i++) ply_put(b, 1, "float", rec[i]);
        sb_put(b, "\0\0", 2);
    }
}

static void stl_ascii_tet(sbuf *b, int crlf, int quad) {
    const char *nl = crlf ? "\r\n" : "\n";
    sb_printf(b, "solid tet%s", nl);
    for (int t = 0; t < 4; t++) {
        if (t == 2) sb_printf(b, "endsolid tet%sSOLID second%s", nl, nl);
        sb_printf(b, "  %s 0 0 %s%s    outer loop%s", t % 2 ? "FACET NORMAL" : "facet normal",
                  t == 3 ? "nan" : "1", nl, nl);
        for (int j = 0; j < 3; j++)
            sb_printf(b, "      vertex %.9g %.9g %.9g%s", tet_xyz[3 * tet_tri[3 * t + j]],
                      tet_xyz[3 * tet_tri[3 * t + j] + 1], tet_xyz[3 * tet_tri[3 * t + j] + 2], nl);
        if (quad && t == 3) /* a repeated corner: the fan adds a degenerate triangle */
            sb_printf(b, "      vertex 0 0 -0.75%s", nl);
        sb_printf(b, "    endloop%s  endfacet%s", nl, nl);
    }
    sb_printf(b, "endsolid");
}

static void test_stl_variants(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    sbuf b = {0};
    stl_binary_tet(&b);
    as_trimesh m = parse_ok(&t, AS_FMT_STL, b.p, b.n);
    assert_mesh_is(&m, 4, tet_xyz, 4, tet_tri);
    as_trimesh_free(t.ctx, &m);
    /* Trailing bytes after the records (not "solid") are ignored. */
    sb_put(&b, "\x01\x02\x03", 3);
    memcpy(b.p, "CAD ", 4);
    m = parse_ok(&t, AS_FMT_STL, b.p, b.n);
    assert_mesh_is(&m, 4, tet_xyz, 4, tet_tri);
    as_trimesh_free(t.ctx, &m);
    sb_free(&b);
    for (int crlf = 0; crlf < 2; crlf++) {
        stl_ascii_tet(&b, crlf, 0);
        m = parse_ok(&t, AS_FMT_STL, b.p, b.n);
        assert_mesh_is(&m, 4, tet_xyz, 4, tet_tri);
        as_trimesh_free(t.ctx, &m);
        sb_free(&b);
    }
    stl_ascii_tet(&b, 0, 1);
    m = parse_ok(&t, AS_FMT_STL, b.p, b.n);
    assert_int_equal(m.nt, 5);
    assert_int_equal(m.nv, 4);
    int32_t last[3] = {2, 0, 3}; /* (v0, v2, v3) of the facet 2 3 0 3 */
    assert_memory_equal(m.tri + 12, last, sizeof last);
    as_trimesh_free(t.ctx, &m);
    sb_free(&b);
    tctx_done(&t);
    BAD(AS_FMT_STL, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                    "vertex 0 1 0\nendloop\nendfacet\n", "endsolid");
    BAD(AS_FMT_STL, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
                    "endloop\nendfacet\nendsolid\n", "facet with 2 vertices");
    BAD(AS_FMT_STL, "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 abc\n",
        "bad.file:5: expected a vertex coordinate, found 'abc'");
    BAD(AS_FMT_STL, "solid x\nendsolid x\n", "no triangles");
    BAD(AS_FMT_STL, "hello", "not an STL file");
}

/* A soup of disjoint triangles (V = 3T, six times the weld table's first guess): the
 * table grows and is rebuilt; the round trip is exact (float data) and numbers vertices
 * in first-occurrence order; and every allocation failure on the way is clean. */
static void test_stl_soup_rehash(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char buf[256];
    tu_rng r = {77};
    as_trimesh m;
    as_trimesh_init(&m);
    for (int i = 0; i < 3000; i++)
        assert_int_equal(as_trimesh_add_vertex(t.ctx, &m, (float)tu_rng_range(&r, -5, 5),
                                               (float)tu_rng_range(&r, -5, 5), (float)i),
                         ANISTAR_OK);
    for (int i = 0; i < 1000; i++)
        assert_int_equal(as_trimesh_add_triangle(t.ctx, &m, 3 * i, 3 * i + 1, 3 * i + 2), ANISTAR_OK);
    const char *p = tdir_file(&d, "soup.stl", buf);
    assert_int_equal(as_mesh_write(t.ctx, p, &m, NULL, 0), ANISTAR_OK);
    as_trimesh b;
    as_trimesh_init(&b);
    assert_int_equal(as_mesh_read(t.ctx, p, &b), ANISTAR_OK);
    assert_same_mesh(&m, &b);
    as_trimesh_free(t.ctx, &b);
    as_trimesh_free(t.ctx, &m);
    tctx_done(&t);
    assert_true(enomem_sweep(p, 0) >= 5);
    tdir_clean(&d);
}

/* ---- Medit ---------------------------------------------------------------------------- */

static void test_medit_variants(void **state) {
    (void)state;
    PYR(AS_FMT_MESH, "MeshVersionFormatted 2\n# comment\nDimension\n3\n\nVertices\n5\n"
                     "0.5 -1.25 0 1\n2.75 -1.25 0 1\n2.75 3.5 0 1\n0.5 3.5 0 2\n1.625 1.125 7 3\n"
                     "Edges\n2\n1 2 0\n2 3 0\nCorners 1 1\nRidges\n1\n1\nRequiredVertices 2 1 2\n"
                     "Quadrilaterals\n1\n1 4 3 2 7\n"
                     "Tetrahedra 1 1 2 3 5 0\nNormals 1 0 0 1\nNormalAtVertices 1 1 1\n"
                     "SomethingNew 2 1.5 2.5 3 4\n"
                     "Triangles\n4\n1 2 5 0\n2 3 5 0\n3 4 5 0\n4 1 5 0\nEnd\nignored after End");
    PYR(AS_FMT_MESH, "MeshVersionFormatted 1\r\nDimension 3\r\nVertices\r\n5\r\n"
                     "0.5 -1.25 0 1\r\n2.75 -1.25 0 1\r\n2.75 3.5 0 1\r\n0.5 3.5 0 2\r\n"
                     "1.625 1.125 7 3\r\nTriangles\r\n6\r\n1 4 3 0\r\n1 3 2 0\r\n1 2 5 0\r\n"
                     "2 3 5 0\r\n3 4 5 0\r\n4 1 5 0");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 2\n", "Dimension 2 is not supported");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n"
                     "0 1 0 0\nTriangles 1\n0 1 2 0\nEnd\n", "out of range");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n"
                     "0 1 0 0\nTriangles 1\n1 2 4 0\nEnd\n", "out of range");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n"
                     "0 1 0 0\nEnd\n", "no triangles");
    BAD(AS_FMT_MESH, "Dimension 3\nVertices 3\n", "expected MeshVersionFormatted");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n"
                     "0 1 zz 0\n", "bad.file:6: expected a vertex coordinate, found 'zz'");
    BAD(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n0 0 0 0\n1 0 0 0\n"
                     "0 1 0 0\nEdges 1\n1 2\n", "unexpected end of file in Edges");
}

/* ==================================================================================== */
/* Hostile files                                                                         */
/* ==================================================================================== */

/* Every prefix (or, for long files, prefixes at a stride) of a valid file: the reader
 * returns EFORMAT naming the file, or OK with a valid mesh; `complete` says that OK is
 * only allowed when nothing was lost (nt == full_nt). */
static size_t truncations(as_mesh_format fmt, const char *data, size_t len, size_t full_nt,
                          int complete) {
    tctx t;
    tctx_init(&t);
    size_t stride = len <= 20000 ? 1 : len / 20000 + 1, fails = 0;
    for (size_t n = 0; n < len; n += (n < 2000 ? 1 : stride)) {
        as_trimesh m;
        as_trimesh_init(&m);
        anistar_status st = parse_mem(t.ctx, fmt, "trunc", data, n, &m);
        if (st == ANISTAR_OK) {
            if (fmt != AS_FMT_SOL) {
                assert_valid_mesh(&m);
                assert_true(m.nt <= full_nt);
                if (complete && m.nt != full_nt) fail_msg("prefix %zu of %zu accepted", n, len);
            }
            as_trimesh_free(t.ctx, &m);
            continue;
        }
        fails++;
        if (st != ANISTAR_EFORMAT || strncmp(anistar_last_error(t.ctx), "trunc", 5) != 0)
            fail_msg("prefix %zu: status %d '%s'", n, st, anistar_last_error(t.ctx));
        assert_null(m.xyz);
        assert_int_equal(t.a.live_blocks, 1); /* only the context */
    }
    tctx_done(&t);
    return fails;
}

static char *written(tctx *t, tdir *d, const as_trimesh *m, const char *name, size_t *n) {
    char buf[256];
    const char *p = tdir_file(d, name, buf);
    assert_int_equal(as_mesh_write(t->ctx, p, m, NULL, 0), ANISTAR_OK);
    return slurp(p, n);
}

static void ascii_ply_of(sbuf *b, const as_trimesh *m) {
    sb_printf(b, "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\n"
                 "property double y\nproperty double z\nelement face %zu\n"
                 "property list uchar int vertex_indices\nend_header\n", m->nv, m->nt);
    for (size_t i = 0; i < m->nv; i++)
        sb_printf(b, "%.17g %.17g %.17g\n", m->xyz[3 * i], m->xyz[3 * i + 1], m->xyz[3 * i + 2]);
    for (size_t i = 0; i < m->nt; i++)
        sb_printf(b, "3 %d %d %d\n", m->tri[3 * i], m->tri[3 * i + 1], m->tri[3 * i + 2]);
}

static void test_truncated(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    as_trimesh s = read_ok(&t, DATA("sphere_r0.5.off"));
    as_trimesh_alloc_tensors(t.ctx, &s);
    for (size_t i = 0; i < s.nv; i++) s.tensor[6 * i] = s.tensor[6 * i + 3] = s.tensor[6 * i + 5] = 1.0 + (double)i / 7;
    size_t n, f;
    char *txt = slurp(DATA("sphere_r0.5.off"), &n);
    f = truncations(AS_FMT_OFF, txt, n, s.nt, 1);
    assert_true(f >= n - 8);
    free(txt);
    txt = written(&t, &d, &s, "s.obj", &n);
    truncations(AS_FMT_OBJ, txt, n, s.nt, 0);
    free(txt);
    txt = written(&t, &d, &s, "s.ply", &n);
    assert_int_equal(truncations(AS_FMT_PLY, txt, n, s.nt, 1), n); /* binary: all fail */
    free(txt);
    sbuf b = {0};
    ascii_ply_of(&b, &s);
    truncations(AS_FMT_PLY, b.p, b.n, s.nt, 1);
    sb_free(&b);
    txt = written(&t, &d, &s, "s.stl", &n);
    assert_int_equal(truncations(AS_FMT_STL, txt, n, s.nt, 1), n);
    free(txt);
    stl_ascii_tet(&b, 0, 0); /* two solids: the first alone is a valid file */
    assert_true(truncations(AS_FMT_STL, b.p, b.n, 4, 0) >= b.n - 40);
    sb_free(&b);
    txt = written(&t, &d, &s, "s.mesh", &n);
    truncations(AS_FMT_MESH, txt, n, s.nt, 1);
    free(txt);
    txt = written(&t, &d, &s, "s.sol", &n);
    truncations(AS_FMT_SOL, txt, n, 0, 1);
    free(txt);
    /* Through files too: 50 prefixes of the sphere. */
    txt = slurp(DATA("sphere_r0.5.off"), &n);
    char buf[256];
    const char *p = tdir_file(&d, "cut.off", buf);
    for (int k = 0; k < 50; k++) {
        size_t len = (size_t)k * (n - 1) / 49;
        write_bytes(p, txt, len);
        as_trimesh m;
        as_trimesh_init(&m);
        anistar_status st = as_mesh_read(t.ctx, p, &m);
        if (len < n - 8) {
            assert_int_equal(st, ANISTAR_EFORMAT);
            assert_non_null(strstr(anistar_last_error(t.ctx), p));
        }
        as_trimesh_free(t.ctx, &m);
    }
    free(txt);
    as_trimesh_free(t.ctx, &s);
    tdir_clean(&d);
    tctx_done(&t);
}

/* Counts far beyond the file: EFORMAT without allocating from the count. */
static void huge(as_mesh_format fmt, const void *text, size_t len, const char *what) {
    tctx t;
    tctx_init(&t);
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status st = parse_mem(t.ctx, fmt, "huge", text, len, &m);
    if (st != ANISTAR_EFORMAT || !strstr(anistar_last_error(t.ctx), what))
        fail_msg("status %d '%s', wanted '%s'", st, anistar_last_error(t.ctx), what);
    assert_true(t.a.peak_bytes < 65536);
    tctx_done(&t);
}
#define HUGE_COUNT(fmt, text, what) huge(fmt, text, sizeof(text) - 1, what)

static void test_huge_counts(void **state) {
    (void)state;
    HUGE_COUNT(AS_FMT_OFF, "OFF\n4000000000 1 0\n", "too many vertices");
    HUGE_COUNT(AS_FMT_OFF, "OFF\n2000000000 1 0\n0 0 0\n", "only 6 bytes follow");
    HUGE_COUNT(AS_FMT_OFF, "OFF\n3 4000000000 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "4000000000 faces");
    HUGE_COUNT(AS_FMT_OFF, "OFF\n3 99999999999999999999 0\n", "out of range");
    HUGE_COUNT(AS_FMT_PLY, "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\n"
                     "property float y\nproperty float z\nelement face 1\n"
                     "property list uchar int vertex_indices\nend_header\n0 0 0\n3 0 0 0\n",
         "count 4000000000 exceeds");
    HUGE_COUNT(AS_FMT_PLY, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                     "property float y\nproperty float z\nelement face 1000000\n"
                     "property list uchar int vertex_indices\nend_header\n"
                     "012345678901234567890123456789012345",
         "count 1000000 exceeds");
    HUGE_COUNT(AS_FMT_PLY, "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
                     "property float y\nproperty float z\nelement face 1\n"
                     "property list uchar int vertex_indices\nelement junk 4000000000\n"
                     "end_header\n", "has no properties");
    {
        unsigned char stl[84 + 50];
        memset(stl, 0, sizeof stl);
        stl[80] = stl[81] = stl[82] = stl[83] = 0xff;
        huge(AS_FMT_STL, stl, sizeof stl, "truncated");
    }
    HUGE_COUNT(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices\n4000000000\n0 0 0 0\n",
         "exceeds");
    HUGE_COUNT(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nVertices\n3\n0 0 0 0\n1 0 0 0\n"
                      "0 1 0 0\nTriangles 300000000\n1 2 3 0\n", "exceeds");
    HUGE_COUNT(AS_FMT_MESH, "MeshVersionFormatted 2\nDimension 3\nTetrahedra 300000000\n", "exceeds");
    HUGE_COUNT(AS_FMT_SOL, "MeshVersionFormatted 2\nDimension 3\nSolAtVertices\n100000000\n1 3\n1 2 3\n",
         "exceeds");
    HUGE_COUNT(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4000000000\n", "out of range");
}

static void test_bad_values(void **state) {
    (void)state;
    static const char *const nonfinite[] = {"nan", "-inf", "Infinity", "1e999", "-1e400",
                                            "1.#QNAN", "-1.#IND", "NaN"};
    for (size_t i = 0; i < sizeof nonfinite / sizeof nonfinite[0]; i++) {
        char txt[512];
        int n = snprintf(txt, sizeof txt, "OFF\n3 1 0\n0 0 0\n1 %s 0\n0 1 0\n3 0 1 2\n", nonfinite[i]);
        expect_bad(AS_FMT_OFF, txt, (size_t)n, "bad.file:4: a vertex coordinate is not a finite number");
        n = snprintf(txt, sizeof txt, "v 0 0 0\nv 1 0 %s\nv 0 1 0\nf 1 2 3\n", nonfinite[i]);
        expect_bad(AS_FMT_OBJ, txt, (size_t)n, "bad.file:2: a vertex coordinate is not a finite");
        n = snprintf(txt, sizeof txt, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
                     "property float y\nproperty float z\nelement face 1\n"
                     "property list uchar int vertex_indices\nend_header\n0 0 0\n%s 0 0\n0 1 0\n"
                     "3 0 1 2\n", nonfinite[i]);
        expect_bad(AS_FMT_PLY, txt, (size_t)n, "not a finite number");
        n = snprintf(txt, sizeof txt, "solid\nfacet normal 0 0 0\nouter loop\nvertex 0 0 0\n"
                     "vertex 1 0 0\nvertex %s 1 0\nendloop\nendfacet\nendsolid\n", nonfinite[i]);
        expect_bad(AS_FMT_STL, txt, (size_t)n, "bad.file:6: a vertex coordinate is not a finite");
        n = snprintf(txt, sizeof txt, "MeshVersionFormatted 2\nDimension 3\nVertices 3\n"
                     "0 0 0 0\n1 0 0 0\n0 1 %s 0\nTriangles 1\n1 2 3 0\n", nonfinite[i]);
        expect_bad(AS_FMT_MESH, txt, (size_t)n, "not a finite number");
    }
    /* Binary NaN: PLY (both endians) and STL. */
    for (int fmt = 1; fmt <= 2; fmt++) {
        sbuf b = {0};
        sb_printf(&b, "ply\nformat %s 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                      "property double z\nelement face 1\nproperty list uchar int vertex_indices\n"
                      "end_header\n", fmt == 1 ? "binary_little_endian" : "binary_big_endian");
        double v[9] = {0, 0, 0, 1, 0, 0, 0, 1, NAN};
        for (int i = 0; i < 3; i++) {
            ply_put(&b, fmt, "float", v[3 * i]);
            ply_put(&b, fmt, "float", v[3 * i + 1]);
            ply_put(&b, fmt, "double", v[3 * i + 2]);
        }
        ply_put(&b, fmt, "uchar", 3);
        for (int k = 0; k < 3; k++) ply_put(&b, fmt, "int", k);
        expect_bad(AS_FMT_PLY, b.p, b.n, "vertex 2: value is not a finite number");
        /* And an index out of range in binary: 0xffffffff as uint. */
        b.n -= 4;
        ply_put(&b, fmt, "int", -1);
        memcpy(b.p + b.n - 13 - 8, "\0\0\0\0\0\0\0\0", 8); /* z of vertex 2 back to 0 */
        expect_bad(AS_FMT_PLY, b.p, b.n, "face 0: vertex index -1 out of range");
        sb_free(&b);
    }
    sbuf b = {0};
    stl_binary_tet(&b);
    memcpy(b.p + 84 + 50 * 2 + 12 + 4, "\x00\x00\xc0\x7f", 4); /* a float NaN */
    expect_bad(AS_FMT_STL, b.p, b.n, "triangle 2: coordinate is not a finite number");
    sb_free(&b);
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "bad.file:6: face 0: vertex index 3 out of range [0, 3)");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", "vertex index -1 out of range");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n", "bad.file:4: expected a vertex coordinate, found 'abc'");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 0x1 0\n0 1 0\n3 0 1 2\n", "found '0x1'");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 1..2 0\n0 1 0\n3 0 1 2\n", "found '1..2'");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 1e 0\n0 1 0\n3 0 1 2\n", "found '1e'");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 - 0\n0 1 0\n3 0 1 2\n", "found '-'");
    BAD(AS_FMT_OFF, "OFF\n3 1 0\n0 0 0\n1 \x01\x02\x03 0\n0 1 0\n3 0 1 2\n", "found '?\?\?'");
    BAD(AS_FMT_OFF, "OFF\nthree 1 0\n", "expected the vertex count, found 'three'");
    BAD(AS_FMT_OBJ, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 two 3\n", "bad.file:4: face 0: expected a vertex index, found 'two'");
}

/* Random bytes, random text, and random mutations of valid files: EFORMAT or a valid
 * mesh, never a crash, a hang or a leak. */
static void test_garbage(void **state) {
    (void)state;
    static const as_mesh_format fmts[] = {AS_FMT_OFF, AS_FMT_OBJ, AS_FMT_PLY, AS_FMT_STL,
                                          AS_FMT_MESH, AS_FMT_SOL};
    tu_rng r = {12345};
    tctx t;
    tctx_init(&t);
    static const char alphabet[] = "0123456789 .-+eE\n\n\n#/\\vfOFFplyformatasciielementvertex"
                                   "facepropertylistucharintend_headersolidfacetnormalouter"
                                   "loopendloopendfacetendsolidMeshVersionFormattedDimension"
                                   "VerticesTrianglesSolAtVerticesEnd\r\t";
    size_t accepted = 0;
    for (int iter = 0; iter < 600; iter++) {
        size_t len = tu_rng_u64(&r) % 3000;
        char *buf = malloc(len + 1);
        for (size_t i = 0; i < len; i++)
            buf[i] = iter % 2 ? (char)(tu_rng_u64(&r) & 0xff)
                              : alphabet[tu_rng_u64(&r) % (sizeof alphabet - 1)];
        for (size_t f = 0; f < sizeof fmts / sizeof fmts[0]; f++) {
            as_trimesh m;
            as_trimesh_init(&m);
            anistar_status st = parse_mem(t.ctx, fmts[f], "garbage", buf, len, &m);
            assert_true(st == ANISTAR_OK || st == ANISTAR_EFORMAT);
            if (st == ANISTAR_OK) {
                accepted++;
                if (fmts[f] != AS_FMT_SOL) assert_valid_mesh(&m);
                as_trimesh_free(t.ctx, &m);
            } else {
                assert_int_equal(strncmp(anistar_last_error(t.ctx), "garbage", 7), 0);
            }
            assert_int_equal(t.a.live_blocks, 1);
        }
        free(buf);
    }
    assert_true(accepted < 20);
    /* Mutations of valid small files of each format. */
    tdir d;
    tdir_make(&d);
    as_trimesh s = read_ok(&t, DATA("ellipsoid.off"));
    as_trimesh_alloc_tensors(t.ctx, &s);
    for (size_t i = 0; i < s.nv; i++) s.tensor[6 * i] = s.tensor[6 * i + 3] = s.tensor[6 * i + 5] = 2;
    static const char *names[] = {"e.off", "e.obj", "e.ply", "e.stl", "e.mesh", "e.sol"};
    for (size_t f = 0; f < sizeof names / sizeof names[0]; f++) {
        size_t n;
        char *orig = written(&t, &d, &s, names[f], &n);
        char *buf = malloc(n + 1);
        for (int iter = 0; iter < 300; iter++) {
            memcpy(buf, orig, n);
            int k = 1 + (int)(tu_rng_u64(&r) % 3);
            for (int j = 0; j < k; j++) {
                size_t pos = tu_rng_u64(&r) % n;
                uint64_t u = tu_rng_u64(&r);
                buf[pos] = (u & 0x100) ? (char)(u & 0xff) : "0123456789-.e \n#/"[u % 17];
            }
            as_trimesh m;
            as_trimesh_init(&m);
            anistar_status st = parse_mem(t.ctx, fmts[f], "mutant", buf, n, &m);
            assert_true(st == ANISTAR_OK || st == ANISTAR_EFORMAT);
            if (st == ANISTAR_OK && fmts[f] != AS_FMT_SOL) assert_valid_mesh(&m);
            as_trimesh_free(t.ctx, &m);
            assert_int_equal(t.a.live_blocks, 1 + 3 * (s.tensor != NULL));
        }
        free(buf);
        free(orig);
    }
    as_trimesh_free(t.ctx, &s);
    tdir_clean(&d);
    tctx_done(&t);
}

static void test_files_missing_empty_dir(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char buf[256];
    static const char *exts[] = {"off", "obj", "ply", "stl", "mesh", "OFF", "Ply"};
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++) {
        as_trimesh m;
        as_trimesh_init(&m);
        char name[32];
        snprintf(name, sizeof name, "empty.%s", exts[i]);
        const char *p = tdir_file(&d, name, buf);
        write_bytes(p, "", 0);
        assert_int_equal(as_mesh_read(t.ctx, p, &m), ANISTAR_EFORMAT);
        assert_non_null(strstr(anistar_last_error(t.ctx), p));
        snprintf(name, sizeof name, "dir.%s", exts[i]);
        p = tdir_file(&d, name, buf);
        assert_int_equal(mkdir(p, 0700), 0);
        assert_int_equal(as_mesh_read(t.ctx, p, &m), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(t.ctx), p));
        assert_non_null(strstr(anistar_last_error(t.ctx), strerror(EISDIR)));
        snprintf(name, sizeof name, "missing.%s", exts[i]);
        p = tdir_file(&d, name, buf);
        assert_int_equal(as_mesh_read(t.ctx, p, &m), ANISTAR_EIO);
        assert_non_null(strstr(anistar_last_error(t.ctx), strerror(ENOENT)));
        assert_null(m.xyz);
    }
    size_t n;
    double *tt;
    assert_int_equal(as_sol_read(t.ctx, tdir_file(&d, "missing.sol", buf), &n, &tt), ANISTAR_EIO);
    assert_null(tt);
    as_trimesh m;
    as_trimesh_init(&m);
    assert_int_equal(as_mesh_read(t.ctx, DATA("README.md"), &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(t.ctx), "'.md'"));
    assert_int_equal(as_mesh_read(t.ctx, "test/data/noext", &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(t.ctx), "without extension"));
    assert_int_equal(as_mesh_format_of("a.b/c"), AS_FMT_UNKNOWN);
    assert_int_equal(as_mesh_format_of("x.VTU"), AS_FMT_VTU);
    assert_int_equal(as_mesh_format_of("x.mesh"), AS_FMT_MESH);
    assert_int_equal(as_mesh_format_of("x.meshb"), AS_FMT_MESHB);
    assert_int_equal(as_mesh_format_of("x.SOLB"), AS_FMT_SOLB);
    assert_int_equal(as_mesh_format_of("x.meshbb"), AS_FMT_UNKNOWN);
    tdir_clean(&d);
    tctx_done(&t);
}

/* ==================================================================================== */
/* Allocation failures                                                                   */
/* ==================================================================================== */

/* Read path with allocation k failing, for k = 0, 1, ... until the read succeeds: every
 * failure is ENOMEM and frees everything. Returns the number of allocations. */
static long enomem_sweep(const char *path, int sol) {
    for (long k = 0;; k++) {
        tctx t;
        tctx_init(&t);
        t.a.fail_after = t.a.count + k;
        as_trimesh m;
        as_trimesh_init(&m);
        anistar_status st;
        size_t n = 0;
        double *tt = NULL;
        if (sol)
            st = as_sol_read(t.ctx, path, &n, &tt);
        else
            st = as_mesh_read(t.ctx, path, &m);
        if (st == ANISTAR_OK) {
            assert_int_equal(t.a.failures, 0);
            as_trimesh_free(t.ctx, &m);
            as_free(t.ctx, tt, n * 6 * sizeof(double));
            tctx_done(&t);
            return k;
        }
        if (st != ANISTAR_ENOMEM) fail_msg("%s, allocation %ld: %d %s", path, k, st, anistar_last_error(t.ctx));
        assert_int_equal(t.a.live_blocks, 1);
        assert_null(m.xyz);
        tctx_done(&t);
        assert_true(k < 10000);
    }
}

static void test_enomem(void **state) {
    (void)state;
    tctx t;
    tctx_init(&t);
    tdir d;
    tdir_make(&d);
    char buf[256];
    as_trimesh s = read_ok(&t, DATA("ellipsoid.off"));
    static const char *names[] = {"e.off", "e.obj", "e.ply", "e.stl", "e.mesh"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        const char *p = tdir_file(&d, names[i], buf);
        assert_int_equal(as_mesh_write(t.ctx, p, &s, NULL, 0), ANISTAR_OK);
        assert_true(enomem_sweep(p, 0) >= 2);
    }
    /* Growth paths: OBJ and ascii STL grow their arrays; ascii PLY of the same mesh. */
    sbuf b = {0};
    ascii_ply_of(&b, &s);
    const char *p = tdir_file(&d, "a.ply", buf);
    write_bytes(p, b.p, b.n);
    sb_free(&b);
    assert_true(enomem_sweep(p, 0) >= 3);
    stl_ascii_tet(&b, 0, 1);
    p = tdir_file(&d, "a.stl", buf);
    write_bytes(p, b.p, b.n);
    sb_free(&b);
    assert_true(enomem_sweep(p, 0) >= 3);
    assert_true(enomem_sweep(DATA("lever.stl"), 0) >= 3);
    as_trimesh_alloc_tensors(t.ctx, &s);
    for (size_t i = 0; i < s.nv; i++) s.tensor[6 * i] = s.tensor[6 * i + 3] = s.tensor[6 * i + 5] = 2;
    p = tdir_file(&d, "e.sol", buf);
    assert_int_equal(as_mesh_write(t.ctx, p, &s, NULL, 0), ANISTAR_OK);
    assert_true(enomem_sweep(p, 1) >= 2);
    p = tdir_file(&d, "t.ply", buf);
    assert_int_equal(as_mesh_write(t.ctx, p, &s, NULL, 0), ANISTAR_OK);
    assert_true(enomem_sweep(p, 0) >= 3);
    as_trimesh_free(t.ctx, &s);
    tdir_clean(&d);
    tctx_done(&t);
}

/* ==================================================================================== */
/* Numbers                                                                               */
/* ==================================================================================== */

static void test_parse_numbers(void **state) {
    (void)state;
    tu_rng r = {99};
    char buf[1200];
    double x, y;
    /* %.17g of random bit patterns parses back to the same bits. */
    for (int i = 0; i < 20000; i++) {
        uint64_t u = tu_rng_u64(&r);
        memcpy(&x, &u, 8);
        if (!isfinite(x)) continue;
        snprintf(buf, sizeof buf, "%.17g", x);
        size_t n = as_parse_double(buf, &y);
        assert_int_equal(n, strlen(buf));
        assert_memory_equal(&x, &y, 8);
    }
    /* Random decimal strings agree with the C library's correctly rounded strtod. */
    for (int i = 0; i < 20000; i++) {
        int nd = 1 + (int)(tu_rng_u64(&r) % (i % 10 == 0 ? 900 : 25)), k = 0;
        int dot = (int)(tu_rng_u64(&r) % (unsigned)(nd + 1));
        if (tu_rng_u64(&r) & 1) buf[k++] = '-';
        for (int j = 0; j < nd; j++) {
            if (j == dot) buf[k++] = '.';
            buf[k++] = (char)('0' + tu_rng_u64(&r) % 10);
        }
        if (tu_rng_u64(&r) & 1) k += snprintf(buf + k, 40, "e%d", (int)(tu_rng_u64(&r) % 700) - 350);
        buf[k] = '\0';
        size_t n = as_parse_double(buf, &x);
        assert_int_equal(n, (size_t)k);
        y = strtod(buf, NULL);
        if (memcmp(&x, &y, 8) != 0) fail_msg("%s: %.17g vs strtod %.17g", buf, x, y);
    }
    /* Halfway cases beyond the kept digits: 2^53 + 1 followed by many zeros then a 1. */
    {
        int k = snprintf(buf, sizeof buf, "9007199254740993");
        for (int j = 0; j < 1000; j++) buf[k++] = '0';
        buf[k++] = '1';
        snprintf(buf + k, 20, "e-1001");
        as_parse_double(buf, &x);
        assert_true(x == strtod(buf, NULL));
        assert_true(x == 9007199254740994.0);
    }
    static const struct {
        const char *s;
        size_t n;
        int finite;
    } cases[] = {{"1", 1, 1},     {"-0", 2, 1},     {".5", 2, 1},     {"5.", 2, 1},
                 {"1e5", 3, 1},   {"1e", 1, 1},     {"1e+", 1, 1},    {".", 0, 0},
                 {"-", 0, 0},     {"e5", 0, 0},     {"0x10", 1, 1},   {"nan", 3, 0},
                 {"-INF", 4, 0},  {"infinity", 8, 0}, {"1.#INF", 6, 0}, {"1e99999", 7, 0},
                 {"1e-99999", 8, 1}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        size_t n = as_parse_double(cases[i].s, &x);
        assert_int_equal(n, cases[i].n);
        if (n) assert_int_equal(isfinite(x) != 0, cases[i].finite);
    }
    assert_int_equal(as_parse_double("-0", &x), 2);
    assert_true(signbit(x));
    int64_t v;
    int ovf;
    assert_int_equal(as_parse_int("-9223372036854775808", &v, &ovf), 20);
    assert_true(v == INT64_MIN && !ovf);
    assert_int_equal(as_parse_int("9223372036854775808", &v, &ovf), 19);
    assert_true(ovf);
    assert_int_equal(as_parse_int("+12x", &v, &ovf), 3);
    assert_true(v == 12 && !ovf);
    assert_int_equal(as_parse_int("x", &v, &ovf), 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_data_files),
        cmocka_unit_test(test_stl_solid_trap),
        cmocka_unit_test(test_roundtrip_exact),
        cmocka_unit_test(test_sol_order),
        cmocka_unit_test(test_roundtrip_stl),
        cmocka_unit_test(test_vtk_vtu),
        cmocka_unit_test(test_write_errors),
        cmocka_unit_test(test_off_variants),
        cmocka_unit_test(test_obj_variants),
        cmocka_unit_test(test_ply_variants),
        cmocka_unit_test(test_stl_variants),
        cmocka_unit_test(test_stl_soup_rehash),
        cmocka_unit_test(test_medit_variants),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_huge_counts),
        cmocka_unit_test(test_bad_values),
        cmocka_unit_test(test_garbage),
        cmocka_unit_test(test_files_missing_empty_dir),
        cmocka_unit_test(test_enomem),
        cmocka_unit_test(test_parse_numbers),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
