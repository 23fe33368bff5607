/*
 * test_image_io.c — the 3D image readers (lib/io/image_io.c): the real images of
 * test/data, synthetic files of every voxel type x byte order x format written here,
 * hostile headers, truncation and mutation fuzzing, allocation-failure injection.
 */
#include "test_util.h"

#include "io/image_io.h"

#include <dirent.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- helpers ------------------------------------------------------------------------ */

/* |a - b| <= tol, in double (cmocka's float helpers round to float). */
static void check_near(double a, double b, double tol, const char *expr, int line) {
    if (!(fabs(a - b) <= tol)) {
        print_error("line %d: %s: %.17g vs %.17g (tol %g)\n", line, expr, a, b, tol);
        fail();
    }
}
#define assert_double_equal(a, b, tol) check_near((a), (b), (tol), #a, __LINE__)

typedef struct fixture {
    tu_alloc alloc;
    anistar_allocator al;
    anistar_context *ctx;
    char dir[64]; /* a fresh temporary folder */
} fixture;

static fixture *fx_new(void) {
    fixture *f = calloc(1, sizeof *f);
    assert_non_null(f);
    tu_alloc_init(&f->alloc, -1);
    f->al = tu_allocator(&f->alloc);
    f->ctx = anistar_context_new(&f->al);
    assert_non_null(f->ctx);
    strcpy(f->dir, "/tmp/anistar_image_io_XXXXXX");
    assert_non_null(mkdtemp(f->dir));
    return f;
}

static void fx_free(fixture *f) {
    DIR *d = opendir(f->dir);
    assert_non_null(d);
    struct dirent *e;
    char p[512];
    while ((e = readdir(d)) != NULL) {
        if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0) continue;
        snprintf(p, sizeof p, "%s/%s", f->dir, e->d_name);
        unlink(p);
    }
    closedir(d);
    rmdir(f->dir);
    anistar_context_free(f->ctx);
    assert_int_equal(f->alloc.live_blocks, 0);
    assert_int_equal(f->alloc.live_bytes, 0);
    free(f);
}

static const char *fx_path(const fixture *f, const char *name, char buf[512]) {
    snprintf(buf, 512, "%s/%s", f->dir, name);
    return buf;
}

static void write_file(const char *path, const void *a, size_t na, const void *b, size_t nb) {
    FILE *fp = fopen(path, "wb");
    assert_non_null(fp);
    if (na) assert_int_equal(fwrite(a, 1, na, fp), na);
    if (nb) assert_int_equal(fwrite(b, 1, nb, fp), nb);
    assert_int_equal(fclose(fp), 0);
}

static int host_big_endian(void) {
    uint16_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 0;
}

/* A copy of host-order voxels in the requested byte order (caller frees). */
static unsigned char *to_order(const void *host, size_t count, size_t size, int big) {
    unsigned char *out = malloc(count * size + 1);
    assert_non_null(out);
    memcpy(out, host, count * size);
    if (size > 1 && big != host_big_endian())
        for (size_t i = 0; i < count; i++)
            for (size_t a = 0, b = size - 1; a < b; a++, b--) {
                unsigned char t = out[i * size + a];
                out[i * size + a] = out[i * size + b];
                out[i * size + b] = t;
            }
    return out;
}

/* Read with as_image_read and expect failure status st with a message containing
 * `needle` and the file's base name. */
static void expect_fail(fixture *f, const char *path, anistar_status st, const char *needle) {
    as_image *img = (as_image *)(uintptr_t)1;
    anistar_status got = as_image_read(f->ctx, path, &img);
    const char *msg = anistar_last_error(f->ctx);
    if (got != st || !strstr(msg, needle)) {
        print_error("file %s: expected %s with '%s', got %s: %s\n", path, anistar_status_name(st),
                    needle, anistar_status_name(got), msg);
        fail();
    }
    assert_null(img);
    const char *base = strrchr(path, '/');
    assert_non_null(strstr(msg, base ? base + 1 : path));
}

static int64_t count_above(const as_image *img, double t) {
    int64_t n = 0;
    for (size_t i = 0; i < img->count; i++) n += as_image_value(img, i) > t;
    return n;
}

/* ---- real images ------------------------------------------------------------------- */

static void test_skull(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *img;
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/skull_2.9.inr", &img), ANISTAR_OK);
    assert_int_equal(img->nx, 64);
    assert_int_equal(img->ny, 64);
    assert_int_equal(img->nz, 64);
    assert_int_equal(img->type, AS_VOXEL_F32);
    assert_int_equal(img->data_bytes, 64 * 64 * 64 * 4);
    assert_double_equal(img->grid.spacing[0], 3.94305, 1e-12);
    assert_double_equal(img->grid.spacing[1], 3.94305, 1e-12);
    assert_double_equal(img->grid.spacing[2], 3.65079, 1e-12);
    for (int i = 0; i < 3; i++) assert_true(img->grid.origin[i] == 0);
    double lo = INFINITY, hi = -INFINITY, lo2, hi2;
    for (size_t i = 0; i < img->count; i++) {
        double v = as_image_value(img, i);
        lo = v < lo ? v : lo;
        hi = v > hi ? v : hi;
    }
    as_image_range(img, &lo2, &hi2);
    assert_true(lo2 == lo && hi2 == hi);
    assert_true(lo >= 2.15e-13 && lo <= 2.25e-13);
    assert_true(hi >= 5.425 && hi <= 5.435);
    assert_int_equal(count_above(img, 2.9), 22490);
    /* None of the inside voxels touches the border. */
    for (size_t k = 0; k < 64; k++)
        for (size_t j = 0; j < 64; j++)
            for (size_t i = 0; i < 64; i++)
                if (i == 0 || j == 0 || k == 0 || i == 63 || j == 63 || k == 63)
                    assert_true(as_image_value(img, i + 64 * (j + 64 * k)) <= 2.9);
    as_image_free(f->ctx, img);
    fx_free(f);
}

static void test_liver(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *img;
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/liver_labels_half.inr", &img),
                     ANISTAR_OK);
    assert_int_equal(img->nx, 169);
    assert_int_equal(img->ny, 142);
    assert_int_equal(img->nz, 70);
    assert_int_equal(img->type, AS_VOXEL_U8);
    long counts[256] = {0};
    const uint8_t *d = img->data;
    for (size_t i = 0; i < img->count; i++) counts[d[i]]++;
    assert_int_equal(counts[0], 1243120);
    assert_int_equal(counts[255], 395274);
    assert_int_equal(counts[127], 39227);
    assert_int_equal(counts[85], 2238);
    assert_int_equal(counts[84], 1);
    double lo, hi;
    as_image_range(img, &lo, &hi);
    assert_true(lo == 0 && hi == 255);
    assert_int_equal(counts[0] + counts[255] + counts[127] + counts[85] + counts[84],
                     (long)img->count);
    assert_double_equal(img->grid.spacing[0], 1.23438, 1e-12);
    assert_double_equal(img->grid.spacing[1], 1.23438, 1e-12);
    assert_double_equal(img->grid.spacing[2], 2.66666, 1e-12);
    assert_double_equal(img->grid.origin[0], 32.0938, 1e-12);
    assert_double_equal(img->grid.origin[1], 22.2188, 1e-12);
    assert_double_equal(img->grid.origin[2], 12, 1e-12);
    /* The origin is voxel (0,0,0)'s world position. */
    double v[3] = {0, 0, 0}, p[3];
    as_grid_voxel_to_world(&img->grid, v, p);
    for (int i = 0; i < 3; i++) assert_true(p[i] == img->grid.origin[i]);
    as_image_free(f->ctx, img);
    fx_free(f);
}

static void test_brain_mhd_nhdr(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *a, *b;
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/brain_t1.mhd", &a), ANISTAR_OK);
    assert_int_equal(as_image_read(f->ctx, AS_TEST_DATA_DIR "/brain_t1.nhdr", &b), ANISTAR_OK);
    as_image *im[2] = {a, b};
    for (int t = 0; t < 2; t++) {
        assert_int_equal(im[t]->nx, 128);
        assert_int_equal(im[t]->ny, 128);
        assert_int_equal(im[t]->nz, 62);
        assert_int_equal(im[t]->type, AS_VOXEL_U8);
        assert_double_equal(im[t]->grid.spacing[0], 2, 1e-15);
        assert_double_equal(im[t]->grid.spacing[1], 2, 1e-15);
        assert_double_equal(im[t]->grid.spacing[2], 3, 1e-15);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++)
                assert_true(im[t]->grid.dir[3 * r + c] == (r == c ? 1.0 : 0.0));
        double sum = 0;
        for (size_t i = 0; i < im[t]->count; i++) sum += as_image_value(im[t], i);
        assert_double_equal(sum / (double)im[t]->count, 19.2, 0.05);
    }
    assert_int_equal(a->data_bytes, b->data_bytes);
    assert_memory_equal(a->data, b->data, a->data_bytes);
    /* The head crosses the first and the last z slices. */
    int64_t first = 0, last = 0;
    for (size_t i = 0; i < 128 * 128; i++) {
        first += as_image_value(a, i) > 40;
        last += as_image_value(a, 61 * 128 * 128 + i) > 40;
    }
    assert_true(first > 0 && last > 0);
    as_image_free(f->ctx, a);
    as_image_free(f->ctx, b);
    fx_free(f);
}

/* ---- synthetic round trips ---------------------------------------------------------- */

enum { SX = 5, SY = 4, SZ = 3, SN = SX * SY * SZ };

/* SN voxels of type t in host order: extremes, small values and random bits. */
static void make_voxels(as_voxel_type t, tu_rng *rng, unsigned char *out) {
    size_t vs = as_voxel_size(t);
    for (size_t i = 0; i < SN; i++) {
        uint64_t r = tu_rng_u64(rng);
        unsigned char *p = out + i * vs;
        switch (t) {
        case AS_VOXEL_U8: {
            uint8_t x = i == 0 ? 0 : i == 1 ? UINT8_MAX : (uint8_t)r;
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_I8: {
            int8_t x = i == 0 ? INT8_MIN : i == 1 ? INT8_MAX : i == 2 ? -1 : (int8_t)(r & 0xff);
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_U16: {
            uint16_t x = i == 0 ? 0 : i == 1 ? UINT16_MAX : (uint16_t)r;
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_I16: {
            int16_t x = i == 0   ? INT16_MIN
                        : i == 1 ? INT16_MAX
                        : i == 2 ? -1
                                 : (int16_t)(r & 0xffff);
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_U32: {
            uint32_t x = i == 0 ? 0 : i == 1 ? UINT32_MAX : (uint32_t)r;
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_I32: {
            int32_t x = i == 0   ? INT32_MIN
                        : i == 1 ? INT32_MAX
                        : i == 2 ? -1
                                 : (int32_t)(r & 0xffffffffu);
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_U64: {
            uint64_t x = i == 0 ? 0 : i == 1 ? UINT64_MAX : r;
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_I64: {
            int64_t x = i == 0 ? INT64_MIN : i == 1 ? INT64_MAX : i == 2 ? -1 : (int64_t)r;
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_F32: {
            float x = i == 0   ? -0.0f
                      : i == 1 ? 3.0e38f
                      : i == 2
                          ? 1.0e-45f /* subnormal */
                          : (float)((tu_rng_unit(rng) - 0.5) * ldexp(1.0, (int)(r % 200) - 100));
            memcpy(p, &x, vs);
            break;
        }
        case AS_VOXEL_F64: {
            double x = i == 0   ? -0.0
                       : i == 1 ? 1.5e308
                       : i == 2 ? 4.9e-324
                                : (tu_rng_unit(rng) - 0.5) * ldexp(1.0, (int)(r % 1600) - 800);
            memcpy(p, &x, vs);
            break;
        }
        default:
            fail();
        }
    }
}

/* Voxel number i as ASCII text (exact round trip). */
static void voxel_text(as_voxel_type t, const unsigned char *p, char *buf, size_t n) {
    switch (t) {
    case AS_VOXEL_U8: {
        uint8_t x;
        memcpy(&x, p, 1);
        snprintf(buf, n, "%u", (unsigned)x);
        break;
    }
    case AS_VOXEL_I8: {
        int8_t x;
        memcpy(&x, p, 1);
        snprintf(buf, n, "%d", (int)x);
        break;
    }
    case AS_VOXEL_U16: {
        uint16_t x;
        memcpy(&x, p, 2);
        snprintf(buf, n, "%u", (unsigned)x);
        break;
    }
    case AS_VOXEL_I16: {
        int16_t x;
        memcpy(&x, p, 2);
        snprintf(buf, n, "%d", (int)x);
        break;
    }
    case AS_VOXEL_U32: {
        uint32_t x;
        memcpy(&x, p, 4);
        snprintf(buf, n, "%" PRIu32, x);
        break;
    }
    case AS_VOXEL_I32: {
        int32_t x;
        memcpy(&x, p, 4);
        snprintf(buf, n, "%" PRId32, x);
        break;
    }
    case AS_VOXEL_U64: {
        uint64_t x;
        memcpy(&x, p, 8);
        snprintf(buf, n, "%" PRIu64, x);
        break;
    }
    case AS_VOXEL_I64: {
        int64_t x;
        memcpy(&x, p, 8);
        snprintf(buf, n, "%" PRId64, x);
        break;
    }
    case AS_VOXEL_F32: {
        float x;
        memcpy(&x, p, 4);
        snprintf(buf, n, "%.9g", (double)x);
        break;
    }
    case AS_VOXEL_F64: {
        double x;
        memcpy(&x, p, 8);
        snprintf(buf, n, "%.17g", x);
        break;
    }
    default:
        fail();
    }
}

static const char *inr_type(as_voxel_type t) {
    return t == AS_VOXEL_F32 || t == AS_VOXEL_F64 ? "float"
           : (t == AS_VOXEL_I8 || t == AS_VOXEL_I16 || t == AS_VOXEL_I32 || t == AS_VOXEL_I64)
               ? "signed fixed"
               : "unsigned fixed";
}

/* Every NRRD spelling of each type (NULL-terminated lists). */
static const char *const *nrrd_names(as_voxel_type t) {
    static const char *const u8[] = {"uchar", "unsigned char", "uint8", "uint8_t", NULL};
    static const char *const i8[] = {"signed char", "int8", "int8_t", NULL};
    static const char *const u16[] = {"ushort", "unsigned short", "unsigned short int",
                                      "uint16", "uint16_t",       NULL};
    static const char *const i16[] = {
        "short", "short int", "signed short", "signed short int", "int16", "int16_t", NULL};
    static const char *const u32[] = {"uint", "unsigned int", "uint32", "uint32_t", NULL};
    static const char *const i32[] = {"int", "signed int", "int32", "int32_t", NULL};
    static const char *const u64[] = {"ulonglong", "unsigned long long", "unsigned long long int",
                                      "uint64",    "uint64_t",           NULL};
    static const char *const i64[] = {"longlong",
                                      "long long",
                                      "long long int",
                                      "signed long long",
                                      "signed long long int",
                                      "int64",
                                      "int64_t",
                                      NULL};
    static const char *const f32[] = {"float", NULL};
    static const char *const f64[] = {"double", NULL};
    static const char *const *const all[] = {u8, i8, u16, i16, u32, i32, u64, i64, f32, f64};
    return all[t];
}

static const char *met_name(as_voxel_type t, int alt) {
    static const char *const n[] = {"MET_UCHAR", "MET_CHAR",  "MET_USHORT",     "MET_SHORT",
                                    "MET_UINT",  "MET_INT",   "MET_ULONG_LONG", "MET_LONG_LONG",
                                    "MET_FLOAT", "MET_DOUBLE"};
    if (alt && t == AS_VOXEL_U32) return "MET_ULONG"; /* 4 bytes in MetaIO */
    if (alt && t == AS_VOXEL_I32) return "MET_LONG";
    return n[t];
}

/* The synthetic geometry: anisotropic spacing, an origin and a rotation. */
static const double SYN_SPACING[3] = {0.5, 1.25, 2.0};
static const double SYN_ORIGIN[3] = {-3.5, 10.25, 7.0};

static void syn_rotation(double r[9]) {
    double ax[3] = {1, 2, 3}, n = sqrt(14.0), th = 0.7;
    for (int i = 0; i < 3; i++) ax[i] /= n;
    double c = cos(th), s = sin(th);
    double k[9] = {0, -ax[2], ax[1], ax[2], 0, -ax[0], -ax[1], ax[0], 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double kk = 0;
            for (int m = 0; m < 3; m++) kk += k[3 * i + m] * k[3 * m + j];
            r[3 * i + j] = (i == j) + s * k[3 * i + j] + (1 - c) * kk;
        }
}

static void check_geometry(const as_image *img, int with_dir) {
    double rot[9];
    syn_rotation(rot);
    for (int i = 0; i < 3; i++) {
        assert_double_equal(img->grid.spacing[i], SYN_SPACING[i], 1e-14);
        assert_double_equal(img->grid.origin[i], SYN_ORIGIN[i], 1e-14);
    }
    for (int i = 0; i < 9; i++)
        assert_double_equal(img->grid.dir[i], with_dir ? rot[i] : (i % 4 == 0), 1e-14);
    /* voxel (1,0,0) is one spacing along axis x's direction, and the map inverts. */
    double v[3] = {1, 0, 0}, p[3], w[3];
    as_grid_voxel_to_world(&img->grid, v, p);
    for (int r = 0; r < 3; r++)
        assert_double_equal(p[r], SYN_ORIGIN[r] + SYN_SPACING[0] * img->grid.dir[3 * r], 1e-13);
    double q[3] = {0.3, -1.7, 2.2};
    as_grid_voxel_to_world(&img->grid, q, p);
    as_grid_world_to_voxel(&img->grid, p, w);
    for (int r = 0; r < 3; r++) assert_double_equal(w[r], q[r], 1e-13);
}

static void check_voxels(const as_image *img, as_voxel_type t, const unsigned char *host) {
    assert_int_equal(img->nx, SX);
    assert_int_equal(img->ny, SY);
    assert_int_equal(img->nz, SZ);
    assert_int_equal(img->type, t);
    assert_int_equal(img->data_bytes, SN * as_voxel_size(t));
    assert_memory_equal(img->data, host, SN * as_voxel_size(t));
}

static void dir_text(int with_dir, char *buf, size_t n, int nrrd) {
    double rot[9];
    syn_rotation(rot);
    if (!with_dir)
        for (int i = 0; i < 9; i++) rot[i] = (i % 4 == 0);
    if (nrrd) /* columns scaled by the spacing */
        snprintf(buf, n, "(%.17g,%.17g,%.17g) (%.17g, %.17g, %.17g) (%.17g,%.17g,%.17g)",
                 rot[0] * SYN_SPACING[0], rot[3] * SYN_SPACING[0], rot[6] * SYN_SPACING[0],
                 rot[1] * SYN_SPACING[1], rot[4] * SYN_SPACING[1], rot[7] * SYN_SPACING[1],
                 rot[2] * SYN_SPACING[2], rot[5] * SYN_SPACING[2], rot[8] * SYN_SPACING[2]);
    else /* MetaImage: consecutive triples are the axis directions */
        snprintf(buf, n, "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g", rot[0], rot[3],
                 rot[6], rot[1], rot[4], rot[7], rot[2], rot[5], rot[8]);
}

static char *ascii_voxels(as_voxel_type t, const unsigned char *host) {
    size_t cap = SN * 40 + 16, len = 0;
    char *s = malloc(cap);
    assert_non_null(s);
    for (size_t i = 0; i < SN; i++) {
        char v[40];
        voxel_text(t, host + i * as_voxel_size(t), v, sizeof v);
        len += (size_t)snprintf(s + len, cap - len, "%s%s", v, (i % SX == SX - 1) ? "\n" : " ");
    }
    return s;
}

static void test_roundtrip_all_types(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {12345};
    char path[512], path2[512], hdr[2048], dirs[512];
    int files = 0;
    for (int t = 0; t < AS_VOXEL_TYPE_COUNT_; t++) {
        as_voxel_type type = (as_voxel_type)t;
        size_t vs = as_voxel_size(type);
        unsigned char host[SN * 8];
        make_voxels(type, &rng, host);
        for (int big = 0; big <= 1; big++) {
            unsigned char *file = to_order(host, SN, vs, big);
            as_image *img;
            /* INR: 256-byte header. */
            {
                int n = snprintf(hdr, sizeof hdr,
                                 "#INRIMAGE-4#{\nXDIM=%d\nYDIM=%d\nZDIM=%d\nVDIM=1\nTYPE=%s\n"
                                 "PIXSIZE=%zu bits\nSCALE=2**0\nCPU=%s\nVX=%.17g\nVY=%.17g\n"
                                 "VZ=%.17g\nTX=%.17g\nTY=%.17g\nTZ=%.17g\n#a comment\n",
                                 SX, SY, SZ, inr_type(type), vs * 8,
                                 big ? (t % 2 ? "sun" : "sgi")
                                     : (t % 3 == 0   ? "decm"
                                        : t % 3 == 1 ? "pc"
                                                     : "alpha"),
                                 SYN_SPACING[0], SYN_SPACING[1], SYN_SPACING[2], SYN_ORIGIN[0],
                                 SYN_ORIGIN[1], SYN_ORIGIN[2]);
                assert_true(n < 252);
                memset(hdr + n, '\n', (size_t)(252 - n));
                memcpy(hdr + 252, "##}\n", 4);
                fx_path(f, "syn.inr", path);
                write_file(path, hdr, 256, file, SN * vs);
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                check_geometry(img, 0);
                as_image_free(f->ctx, img);
                files++;
            }
            /* NRRD attached raw, every spelling of the type, with a rotation. */
            dir_text(1, dirs, sizeof dirs, 1);
            for (const char *const *nm = nrrd_names(type); *nm; nm++) {
                int n = snprintf(hdr, sizeof hdr,
                                 "NRRD0004\n# comment\ntype: %s\ndimension: 3\nspace: "
                                 "left-posterior-superior\nsizes: %d %d %d\nspace directions: "
                                 "%s\nkinds: domain domain domain\nendian: %s\nencoding: raw\n"
                                 "space origin: (%.17g,%.17g,%.17g)\nmy key:=my value\n\n",
                                 *nm, SX, SY, SZ, dirs, big ? "big" : "little", SYN_ORIGIN[0],
                                 SYN_ORIGIN[1], SYN_ORIGIN[2]);
                fx_path(f, "syn.nrrd", path);
                write_file(path, hdr, (size_t)n, file, SN * vs);
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                check_geometry(img, 1);
                as_image_free(f->ctx, img);
                files++;
            }
            /* NRRD ASCII ("ascii" / "text" / "txt"), spacings instead of directions. */
            {
                static const char *const enc[] = {"ascii", "text", "txt"};
                char *txt = ascii_voxels(type, host);
                int n = snprintf(hdr, sizeof hdr,
                                 "NRRD0005\ntype: %s\ndimension: 3\nsizes: %d %d %d\nspacings: "
                                 "%.17g %.17g %.17g\nencoding: %s\n\n",
                                 nrrd_names(type)[0], SX, SY, SZ, SYN_SPACING[0], SYN_SPACING[1],
                                 SYN_SPACING[2], enc[(t + big) % 3]);
                fx_path(f, "syn_ascii.nrrd", path);
                write_file(path, hdr, (size_t)n, txt, strlen(txt));
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                as_image_free(f->ctx, img);
                free(txt);
                files++;
            }
            /* NHDR detached, with a byte skip, data file relative to the header. */
            {
                int n = snprintf(hdr, sizeof hdr,
                                 "NRRD0004\ntype: %s\ndimension: 3\nspace dimension: 3\nsizes: "
                                 "%d %d %d\nspace directions: %s\nendian: %s\nencoding: raw\n"
                                 "space origin: (%.17g, %.17g, %.17g)\nbyte skip: 7\n"
                                 "data file: syn_data.raw\n",
                                 nrrd_names(type)[0], SX, SY, SZ, dirs, big ? "big" : "little",
                                 SYN_ORIGIN[0], SYN_ORIGIN[1], SYN_ORIGIN[2]);
                write_file(fx_path(f, "syn.nhdr", path), hdr, (size_t)n, NULL, 0);
                write_file(fx_path(f, "syn_data.raw", path2), "JUNK!!!", 7, file, SN * vs);
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                check_geometry(img, 1);
                as_image_free(f->ctx, img);
                files++;
            }
            /* MetaImage LOCAL with a TransformMatrix. */
            dir_text(1, dirs, sizeof dirs, 0);
            {
                int n = snprintf(hdr, sizeof hdr,
                                 "ObjectType = Image\nNDims = 3\nDimSize = %d %d %d\n"
                                 "ElementType = %s\nElementSpacing = %.17g %.17g %.17g\n"
                                 "Offset = %.17g %.17g %.17g\nTransformMatrix = %s\n"
                                 "AnatomicalOrientation = RAI\nBinaryData = True\n"
                                 "BinaryDataByteOrderMSB = %s\nCompressedData = False\n"
                                 "ElementDataFile = LOCAL\n",
                                 SX, SY, SZ, met_name(type, big), SYN_SPACING[0], SYN_SPACING[1],
                                 SYN_SPACING[2], SYN_ORIGIN[0], SYN_ORIGIN[1], SYN_ORIGIN[2], dirs,
                                 big ? "True" : "False");
                fx_path(f, "syn.mha", path);
                write_file(path, hdr, (size_t)n, file, SN * vs);
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                check_geometry(img, 1);
                as_image_free(f->ctx, img);
                files++;
            }
            /* MetaImage .mhd + .raw, HeaderSize -1 (data at the end, junk before). */
            {
                int n = snprintf(hdr, sizeof hdr,
                                 "NDims = 3\nDimSize = %d %d %d\nElementType = %s\n"
                                 "ElementSize = %.17g %.17g %.17g\nPosition = %.17g %.17g %.17g\n"
                                 "ElementByteOrderMSB = %s\nHeaderSize = -1\n"
                                 "ElementDataFile = syn_mhd.raw\n",
                                 SX, SY, SZ, met_name(type, 0), SYN_SPACING[0], SYN_SPACING[1],
                                 SYN_SPACING[2], SYN_ORIGIN[0], SYN_ORIGIN[1], SYN_ORIGIN[2],
                                 big ? "True" : "False");
                write_file(fx_path(f, "syn.mhd", path), hdr, (size_t)n, NULL, 0);
                write_file(fx_path(f, "syn_mhd.raw", path2), "0123456789abc", 13, file, SN * vs);
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                check_geometry(img, 0);
                as_image_free(f->ctx, img);
                files++;
            }
            /* MetaImage ASCII data (BinaryData = False). */
            {
                char *txt = ascii_voxels(type, host);
                int n = snprintf(hdr, sizeof hdr,
                                 "ObjectType = Image\nNDims = 3\nDimSize = %d %d %d\n"
                                 "ElementType = %s\nBinaryData = False\nElementDataFile = LOCAL\n",
                                 SX, SY, SZ, met_name(type, 0));
                fx_path(f, "syn_ascii.mha", path);
                write_file(path, hdr, (size_t)n, txt, strlen(txt));
                assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
                check_voxels(img, type, host);
                as_image_free(f->ctx, img);
                free(txt);
                files++;
            }
            /* Raw with a header offset, and with -1 (data at the end). */
            {
                write_file(fx_path(f, "syn.raw", path), "0123456789abcdef", 16, file, SN * vs);
                for (int off = 0; off < 2; off++) {
                    assert_int_equal(as_image_read_raw(f->ctx, path, SX, SY, SZ, type, big,
                                                       SYN_SPACING, SYN_ORIGIN, off ? -1 : 16,
                                                       &img),
                                     ANISTAR_OK);
                    check_voxels(img, type, host);
                    check_geometry(img, 0);
                    as_image_free(f->ctx, img);
                    files++;
                }
            }
            free(file);
        }
    }
    assert_true(files > 10 * 2 * 8);
    fx_free(f);
}

/* Format details: NRRD 4-D with a non-spatial axis of size 1, line skip, spacings with
 * nan, absolute data file paths, CRLF line ends, field names without spaces; MetaImage
 * synonyms repeated with the same value. */
static void test_format_variants(void **state) {
    (void)state;
    fixture *f = fx_new();
    char path[512], path2[512], hdr[1024];
    unsigned char vox[SN];
    for (int i = 0; i < SN; i++) vox[i] = (unsigned char)(7 * i + 3);
    as_image *img;

    int n = snprintf(hdr, sizeof hdr,
                     "NRRD0004\ntype: uchar\ndimension: 4\nspace: RAS\nsizes: 1 %d %d %d\n"
                     "space directions: none (2,0,0) (0,3,0) (0,0,4)\nkinds: scalar domain "
                     "domain domain\nencoding: raw\n\n",
                     SX, SY, SZ);
    write_file(fx_path(f, "four.nrrd", path), hdr, (size_t)n, vox, SN);
    assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
    assert_int_equal(img->nx, SX);
    assert_int_equal(img->nz, SZ);
    assert_memory_equal(img->data, vox, SN);
    assert_double_equal(img->grid.spacing[2], 4, 0);
    as_image_free(f->ctx, img);

    n = snprintf(hdr, sizeof hdr,
                 "NRRD0004\r\ntype: uchar\r\ndimension: 4\r\nsizes: %d %d 1 %d\r\n"
                 "spacings: 1.5 2.5 nan 3.5\r\nencoding: raw\r\nlineskip: 2\r\nbyteskip: 1\r\n\r\n"
                 "first line\nsecond line\n#",
                 SX, SY, SZ);
    write_file(fx_path(f, "skip.nrrd", path), hdr, (size_t)n, vox, SN);
    assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
    assert_memory_equal(img->data, vox, SN);
    assert_double_equal(img->grid.spacing[0], 1.5, 0);
    assert_double_equal(img->grid.spacing[2], 3.5, 0);
    as_image_free(f->ctx, img);

    /* MetaImage: a synonym repeated with the same value is accepted. */
    n = snprintf(hdr, sizeof hdr,
                 "NDims = 3\nDimSize = %d %d %d\nOffset = 1 2 3\nPosition = 1 2 3\n"
                 "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
                 SX, SY, SZ);
    write_file(fx_path(f, "dup.mha", path), hdr, (size_t)n, vox, SN);
    assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
    assert_double_equal(img->grid.origin[2], 3, 0);
    as_image_free(f->ctx, img);

    /* Absolute data file path, byte skip -1. */
    write_file(fx_path(f, "abs.raw", path2), "xyz", 3, vox, SN);
    n = snprintf(hdr, sizeof hdr,
                 "NRRD0004\ntype: uint8\ndimension: 3\nsizes: %d %d %d\nencoding: raw\n"
                 "byte skip: -1\ndatafile: %s\n",
                 SX, SY, SZ, path2);
    write_file(fx_path(f, "abs.nhdr", path), hdr, (size_t)n, NULL, 0);
    assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
    assert_memory_equal(img->data, vox, SN);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- hostile files ------------------------------------------------------------------ */

typedef struct hostile {
    const char *name;   /* file name (the extension selects the reader) */
    const char *header; /* text */
    size_t data_bytes;  /* bytes of 0x11 appended */
    anistar_status st;
    const char *needle; /* substring of the message */
} hostile;

#define INR_HEAD "#INRIMAGE-4#{\n"
#define INR_END "##}\n"

static void test_hostile_headers(void **state) {
    (void)state;
    static const hostile cases[] = {
        /* Inrimage */
        {"a.inr", "hello world\n", 0, ANISTAR_EFORMAT, "not an Inrimage"},
        {"a.inr", "", 0, ANISTAR_EFORMAT, "not an Inrimage"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n", 0,
         ANISTAR_EFORMAT, "##}"},
        {"a.inr", INR_HEAD "XDIM=0\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n" INR_END, 0,
         ANISTAR_EFORMAT, "XDIM"},
        {"a.inr", INR_HEAD "XDIM=-5\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n" INR_END, 0,
         ANISTAR_EFORMAT, "XDIM"},
        {"a.inr", INR_HEAD "XDIM=abc\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\n" INR_END, 0,
         ANISTAR_EFORMAT, "'XDIM': 'abc' is not an integer"},
        {"a.inr", INR_HEAD "XDIM=99999999999999999999\nYDIM=2\n" INR_END, 0, ANISTAR_EFORMAT,
         "XDIM"},
        {"a.inr", INR_HEAD "YDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n" INR_END, 0,
         ANISTAR_EFORMAT, "missing required field 'XDIM'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nPIXSIZE=32 bits\nCPU=pc\n" INR_END, 0, ANISTAR_EFORMAT,
         "missing required field 'TYPE'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nCPU=pc\n" INR_END, 0, ANISTAR_EFORMAT,
         "missing required field 'PIXSIZE'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=complex\nPIXSIZE=32 bits\n" INR_END, 0,
         ANISTAR_EFORMAT, "'TYPE': unsupported voxel type 'complex'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=12 bits\n" INR_END, 0,
         ANISTAR_EFORMAT, "PIXSIZE"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=16 bits\nCPU=pc\n" INR_END, 0,
         ANISTAR_EFORMAT, "PIXSIZE"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nVDIM=3\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n" INR_END,
         0, ANISTAR_EFORMAT, "VDIM"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nFOO=1\n" INR_END, 0, ANISTAR_EFORMAT,
         "unknown header field 'FOO'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\njunk line\n" INR_END, 0, ANISTAR_EFORMAT,
         "not KEY=VALUE"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=vax\n" INR_END, 0,
         ANISTAR_EFORMAT, "'CPU': unknown 'vax'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=signed fixed\nPIXSIZE=16 bits\n" INR_END, 8,
         ANISTAR_EFORMAT, "missing field 'CPU'"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\nRX=0.5\n" INR_END,
         0, ANISTAR_EFORMAT, "'RX' = 0.5 is unsupported"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\nVX=nan\n" INR_END,
         0, ANISTAR_EFORMAT, "'VX': 'nan' is not a finite number"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\nVX=-1\n" INR_END,
         16, ANISTAR_EFORMAT, "spacing must be > 0"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\nSCALE=3\n" INR_END,
         0, ANISTAR_EFORMAT, "SCALE"},
        {"a.inr",
         INR_HEAD "XDIM=4294967296\nYDIM=4294967296\nZDIM=4294967296\nTYPE=float\n"
                  "PIXSIZE=32 bits\nCPU=pc\n" INR_END,
         0, ANISTAR_EFORMAT, "overflow"},
        {"a.inr",
         INR_HEAD
         "XDIM=100000\nYDIM=100000\nZDIM=1000\nTYPE=float\nPIXSIZE=64 bits\nCPU=pc\n" INR_END,
         64, ANISTAR_EFORMAT, "truncated"},
        {"a.inr", INR_HEAD "XDIM=4\nYDIM=4\nZDIM=4\nTYPE=float\nPIXSIZE=32 bits\nCPU=pc\n" INR_END,
         64, ANISTAR_EFORMAT, "truncated"},
        {"a.inr", INR_HEAD "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=unsigned fixed\nPIXSIZE=8 bits\n" INR_END,
         9, ANISTAR_EFORMAT, "disagree"},
        /* NRRD */
        {"a.nrrd", "NRRD0009\n", 0, ANISTAR_EFORMAT, "unsupported NRRD version"},
        {"a.nrrd", "PNG\n", 0, ANISTAR_EFORMAT, "not a NRRD"},
        {"a.nrrd", "", 0, ANISTAR_EFORMAT, "not a NRRD"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nencoding: raw\n\n", 8, ANISTAR_EFORMAT,
         "missing required field 'sizes'"},
        {"a.nrrd", "NRRD0004\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 8, ANISTAR_EFORMAT,
         "missing required field 'type'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\nsizes: 2 2 2\nencoding: raw\n\n", 8, ANISTAR_EFORMAT,
         "missing required field 'dimension'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\n\n", 8, ANISTAR_EFORMAT,
         "missing required field 'encoding'"},
        {"a.nrrd", "NRRD0004\ntype: complex\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "unsupported voxel type 'complex'"},
        {"a.nrrd", "NRRD0004\ntype: block\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "unsupported voxel type 'block'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: gzip\n\n", 8,
         ANISTAR_EFORMAT, "'encoding': 'gzip' is unsupported"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: bz2\n\n", 8,
         ANISTAR_EFORMAT, "'encoding': 'bz2' is unsupported"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: hex\n\n", 8,
         ANISTAR_EFORMAT, "'encoding': 'hex' is unsupported"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nfoo: 1\n\n",
         8, ANISTAR_EFORMAT, "unknown NRRD field 'foo'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nno colon\n\n",
         8, ANISTAR_EFORMAT, "neither a field"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 2 2\nencoding: raw\n\n", 4,
         ANISTAR_EFORMAT, "spatial axes"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 0\nsizes: 2 2\nencoding: raw\n\n", 4,
         ANISTAR_EFORMAT, "'dimension'"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 4\nspace dimension: 3\nsizes: 3 2 2 2\n"
         "space directions: none (1,0,0) (0,1,0) (0,0,1)\nencoding: raw\n\n",
         24, ANISTAR_EFORMAT, "multi-component"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "'sizes'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 -2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "'sizes'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "more than 3 sizes"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 4294967296 4294967296 4294967296\n"
         "encoding: raw\n\n",
         8, ANISTAR_EFORMAT, "overflow"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "'type' appears twice"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nspace directions: (1,0,0) (0,1,0) "
         "(0,0,1)\nencoding: raw\n\n",
         8, ANISTAR_EFORMAT, "needs a 'space'"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nspace: RAS\nsizes: 2 2 2\nspace directions: "
         "(1,0,0) (0,1,0) (0,0,1)\nspacings: 1 1 1\nencoding: raw\n\n",
         8, ANISTAR_EFORMAT, "exclude each other"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nspace: RAS\nsizes: 2 2 2\nspace directions: "
         "(1,0,0) (0,1,0)\nencoding: raw\n\n",
         8, ANISTAR_EFORMAT, "'space directions'"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nspace: RAS\nsizes: 2 2 2\nspace directions: "
         "(1,0,0) (0,1,0) (1,1,0)\nencoding: raw\n\n",
         8, ANISTAR_EFORMAT, "singular"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nspace: RAST\nsizes: 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "4-D space is unsupported"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nspace: mars\nsizes: 2 2 2\nencoding: raw\n\n", 8,
         ANISTAR_EFORMAT, "unknown space 'mars'"},
        {"a.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 16,
         ANISTAR_EFORMAT, "missing field 'endian'"},
        {"a.nrrd",
         "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nendian: middle\nencoding: raw\n\n", 16,
         ANISTAR_EFORMAT, "'endian'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 7,
         ANISTAR_EFORMAT, "truncated"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n\n", 9,
         ANISTAR_EFORMAT, "disagree"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n", 0,
         ANISTAR_EFORMAT, "no data"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\nbyte skip: -1\n\n"
         "1 2 3 4 5 6 7 8",
         0, ANISTAR_EFORMAT, "'byte skip'"},
        {"a.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3", 0,
         ANISTAR_EFORMAT, "truncated"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5      ", 0,
         ANISTAR_EFORMAT, "only 5 of the 8 values"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5 6 7 300",
         0, ANISTAR_EFORMAT, "'300' in"},
        {"a.nrrd",
         "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5 6 7 1.5",
         0, ANISTAR_EFORMAT, "is not a valid int16"},
        {"a.nrrd",
         "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5 6 7 abc",
         0, ANISTAR_EFORMAT, "'abc'"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5 6 7 8 9",
         0, ANISTAR_EFORMAT, "more than the 8 values"},
        {"a.nrrd",
         "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 nan 5 6 7 8",
         0, ANISTAR_EFORMAT, "image has 1 non-finite voxels"},
        {"a.nrrd",
         "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n1 2 3 4 5 6 inf "
         "-inf",
         0, ANISTAR_EFORMAT, "2 non-finite voxels (NaN or infinite), the first at (0,1,1)"},
        {"a.nhdr",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
         "data file: does_not_exist.raw\n",
         0, ANISTAR_EIO, "does_not_exist.raw"},
        {"a.nhdr",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
         "data file: LIST\n",
         0, ANISTAR_EFORMAT, "'data file'"},
        {"a.nhdr",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
         "data file: slice%03d.raw 0 1 1\n",
         0, ANISTAR_EFORMAT, "'data file'"},
        {"a.nrrd",
         "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\nline skip: 5\n\n"
         "one\ntwo\n",
         0, ANISTAR_EFORMAT, "lines to skip"},
        /* MetaImage */
        {"a.mha", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n", 0, ANISTAR_EFORMAT,
         "not a MetaImage"},
        {"a.mha", "", 0, ANISTAR_EFORMAT, "not a MetaImage"},
        {"a.mha", "NDims = 2\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", 4,
         ANISTAR_EFORMAT, "'NDims'"},
        {"a.mha", "NDims = 3\nDimSize = 2 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", 4,
         ANISTAR_EFORMAT, "'DimSize'"},
        {"a.mha", "NDims = 3\nDimSize = 2 0 2\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
         4, ANISTAR_EFORMAT, "'DimSize'"},
        {"a.mha", "NDims = 3\nElementType = MET_UCHAR\nElementDataFile = LOCAL\n", 8,
         ANISTAR_EFORMAT, "missing required field 'DimSize'"},
        {"a.mha", "NDims = 3\nDimSize = 2 2 2\nElementDataFile = LOCAL\n", 8, ANISTAR_EFORMAT,
         "missing required field 'ElementType'"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_COMPLEX\nElementDataFile = LOCAL\n", 8,
         ANISTAR_EFORMAT, "unsupported type 'MET_COMPLEX'"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nCompressedData = True\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "'CompressedData': 'True' is unsupported"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementNumberOfChannels = 3\n"
         "ElementDataFile = LOCAL\n",
         24, ANISTAR_EFORMAT, "ElementNumberOfChannels"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nFoo = 1\nElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "unknown MetaImage field 'Foo'"},
        {"a.mha",
         "ObjectType = Mesh\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "'ObjectType'"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nOffset = 0 0 0\nOrigin = 1 1 1\nElementType = MET_UCHAR\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "appears twice with different values"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nTransformMatrix = 1 0 0 0 1 0 1 0 0\n"
         "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "singular"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementSpacing = 1 1\nElementType = MET_UCHAR\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "'ElementSpacing'"},
        {"a.mha", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_SHORT\nElementDataFile = LOCAL\n",
         15, ANISTAR_EFORMAT, "truncated"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_FLOAT\nHeaderSize = 40\n"
         "ElementDataFile = LOCAL\n",
         32, ANISTAR_EFORMAT, "truncated"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nHeaderSize = -2\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "'HeaderSize'"},
        {"a.mhd",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
         "ElementDataFile = does_not_exist.raw\n",
         0, ANISTAR_EIO, "does_not_exist.raw"},
        {"a.mhd", "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nElementDataFile = LIST\n",
         0, ANISTAR_EFORMAT, "'ElementDataFile'"},
        {"a.mhd",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
         "ElementDataFile = slice%03d.raw 1 2 1\n",
         0, ANISTAR_EFORMAT, "'ElementDataFile'"},
        {"a.mha",
         "NDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\nBinaryData = Maybe\n"
         "ElementDataFile = LOCAL\n",
         8, ANISTAR_EFORMAT, "'BinaryData'"},
        {"a.mha", "NDims = 3\nDimSize = 2 2 2\nno equal sign\nElementDataFile = LOCAL\n", 8,
         ANISTAR_EFORMAT, "not 'Key = Value'"},
        /* dispatch */
        {"a.png", "PNG", 0, ANISTAR_EFORMAT, "unknown image extension '.png'"},
        {"a.inr.gz", "x", 0, ANISTAR_EFORMAT, "compressed files are unsupported"},
        {"noext", "x", 0, ANISTAR_EFORMAT, "unknown image extension"},
    };
    fixture *f = fx_new();
    char path[512];
    unsigned char data[4096];
    memset(data, 0x11, sizeof data);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const hostile *c = &cases[i];
        assert_true(c->data_bytes <= sizeof data);
        fx_path(f, c->name, path);
        write_file(path, c->header, strlen(c->header), data, c->data_bytes);
        size_t peak_before = f->alloc.peak_bytes;
        expect_fail(f, path, c->st, c->needle);
        /* A header that lies about its sizes never makes the reader allocate them. */
        assert_true(f->alloc.peak_bytes <= peak_before + (2u << 20));
        unlink(path);
    }
    fx_free(f);
}

/* NaN/Inf voxels in binary float images, missing files, raw-reader argument checks. */
/* Readers accept regular files only: a header naming a device or a FIFO as its data file
 * (or a device named as the image itself) must fail at once, never block or read forever. */
static void test_not_regular_files(void **state) {
    (void)state;
    fixture *f = fx_new();
    char path[512], fifo[512], link[512];
    const char *devs[] = {"/dev/zero", "/dev/null"};
    for (size_t i = 0; i < 2; i++) {
        char hdr[256];
        snprintf(hdr, sizeof hdr,
                 "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                 "data file: %s\n\n", devs[i]);
        write_file(fx_path(f, "dev.nhdr", path), hdr, strlen(hdr), NULL, 0);
        expect_fail(f, path, ANISTAR_EIO, "not a regular file");
        snprintf(hdr, sizeof hdr,
                 "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementType = MET_UCHAR\n"
                 "ElementDataFile = %s\n", devs[i]);
        write_file(fx_path(f, "dev.mhd", path), hdr, strlen(hdr), NULL, 0);
        expect_fail(f, path, ANISTAR_EIO, "not a regular file");
    }
    /* A FIFO with no writer would block an open-and-read forever. */
    assert_int_equal(mkfifo(fx_path(f, "fifo.raw", fifo), 0600), 0);
    const char *hdr = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n"
                      "data file: fifo.raw\n\n";
    write_file(fx_path(f, "fifo.nhdr", path), hdr, strlen(hdr), NULL, 0);
    int fd = open(fifo, O_RDWR | O_NONBLOCK); /* keeps fopen from blocking on the open */
    assert_true(fd >= 0);
    expect_fail(f, path, ANISTAR_EIO, "not a regular file");
    close(fd);
    /* The image path itself naming a device. */
    assert_int_equal(symlink("/dev/zero", fx_path(f, "zero.inr", link)), 0);
    expect_fail(f, link, ANISTAR_EIO, "not a regular file");
    fx_free(f);
}

static void test_nonfinite_missing_raw(void **state) {
    (void)state;
    fixture *f = fx_new();
    char path[512], hdr[512];
    float v[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    v[5] = NAN;
    int n = snprintf(hdr, sizeof hdr,
                     INR_HEAD "XDIM=2\nYDIM=2\nZDIM=2\nTYPE=float\nPIXSIZE=32 bits\nCPU=%s\n",
                     host_big_endian() ? "sun" : "decm");
    memset(hdr + n, '\n', (size_t)(252 - n));
    memcpy(hdr + 252, INR_END, 4);
    write_file(fx_path(f, "nan.inr", path), hdr, 256, v, sizeof v);
    expect_fail(f, path, ANISTAR_EFORMAT,
                "image has 1 non-finite voxels (NaN or infinite), "
                "the first at (1,0,1)");
    v[5] = 6;
    v[0] = -INFINITY;
    write_file(path, hdr, 256, v, sizeof v);
    expect_fail(f, path, ANISTAR_EFORMAT, "the first at (0,0,0)");
    v[0] = 1;
    write_file(path, hdr, 256, v, sizeof v);
    as_image *img;
    assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
    assert_memory_equal(img->data, v, sizeof v);
    as_image_free(f->ctx, img);

    /* Missing files: EIO naming them, for every reader. */
    static const char *const missing[] = {"nope.inr", "nope.nrrd", "nope.nhdr", "nope.mha",
                                          "nope.mhd"};
    for (int i = 0; i < 5; i++) expect_fail(f, fx_path(f, missing[i], path), ANISTAR_EIO, "nope");
    img = (as_image *)(uintptr_t)1;
    assert_int_equal(as_image_read_raw(f->ctx, fx_path(f, "nope.raw", path), 2, 2, 2, AS_VOXEL_U8,
                                       0, NULL, NULL, 0, &img),
                     ANISTAR_EIO);
    assert_null(img);
    assert_non_null(strstr(anistar_last_error(f->ctx), "nope.raw"));

    /* Raw reader arguments and sizes. */
    write_file(fx_path(f, "r.raw", path), v, sizeof v, NULL, 0);
    assert_int_equal(as_image_read_raw(f->ctx, path, 0, 2, 2, AS_VOXEL_F32, 0, NULL, NULL, 0, &img),
                     ANISTAR_EINVAL);
    assert_int_equal(
        as_image_read_raw(f->ctx, path, 2, -2, 2, AS_VOXEL_F32, 0, NULL, NULL, 0, &img),
        ANISTAR_EINVAL);
    assert_int_equal(
        as_image_read_raw(f->ctx, path, 2, 2, 2, AS_VOXEL_TYPE_COUNT_, 0, NULL, NULL, 0, &img),
        ANISTAR_EINVAL);
    assert_int_equal(
        as_image_read_raw(f->ctx, path, 2, 2, 2, AS_VOXEL_F32, 0, NULL, NULL, -2, &img),
        ANISTAR_EINVAL);
    assert_int_equal(as_image_read_raw(f->ctx, path, 2, 2, 3, AS_VOXEL_F32, 0, NULL, NULL, 0, &img),
                     ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(f->ctx), "truncated"));
    assert_int_equal(as_image_read_raw(f->ctx, path, 2, 2, 2, AS_VOXEL_F32, 0, NULL, NULL, 4, &img),
                     ANISTAR_EFORMAT);
    assert_int_equal(as_image_read_raw(f->ctx, path, INT64_MAX, INT64_MAX, 2, AS_VOXEL_F32, 0, NULL,
                                       NULL, 0, &img),
                     ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(f->ctx), "overflow"));
    const double bad_spacing[3] = {1, 0, 1};
    assert_int_equal(
        as_image_read_raw(f->ctx, path, 2, 2, 1, AS_VOXEL_F64, 0, bad_spacing, NULL, 0, &img),
        ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(f->ctx), "spacing"));
    assert_int_equal(as_image_read_raw(f->ctx, path, 2, 2, 1, AS_VOXEL_F64, 0, NULL, NULL, 0, &img),
                     ANISTAR_OK);
    as_image_free(f->ctx, img);
    fx_free(f);
}

/* ---- fuzzing: every truncation, random mutations ------------------------------------- */

/* Valid small files of each format (binary data), built in memory. */
static size_t sample_file(int which, unsigned char *buf, size_t cap, const char **name) {
    char hdr[512];
    int n = 0;
    unsigned char vox[2 * 3 * 2 * 2];
    for (size_t i = 0; i < sizeof vox; i++) vox[i] = (unsigned char)(i * 37 + 1);
    switch (which) {
    case 0:
        *name = "f.inr";
        n = snprintf(hdr, sizeof hdr,
                     INR_HEAD "XDIM=2\nYDIM=3\nZDIM=2\nTYPE=signed fixed\nPIXSIZE=16 bits\n"
                              "CPU=decm\nVX=1.5\nTZ=-2\n");
        memset(hdr + n, '\n', (size_t)(252 - n));
        memcpy(hdr + 252, INR_END, 4);
        n = 256;
        break;
    case 1:
        *name = "f.nrrd";
        n = snprintf(hdr, sizeof hdr,
                     "NRRD0004\ntype: short\ndimension: 3\nspace: RAS\nsizes: 2 3 2\n"
                     "space directions: (1,0,0) (0,2,0) (0,0,3)\nspace origin: (1,2,3)\n"
                     "endian: little\nencoding: raw\n\n");
        break;
    default:
        *name = "f.mha";
        n = snprintf(hdr, sizeof hdr,
                     "ObjectType = Image\nNDims = 3\nDimSize = 2 3 2\nElementType = MET_SHORT\n"
                     "ElementSpacing = 1 2 3\nOffset = 1 2 3\nBinaryDataByteOrderMSB = False\n"
                     "ElementDataFile = LOCAL\n");
        break;
    }
    assert_true((size_t)n + sizeof vox <= cap);
    memcpy(buf, hdr, (size_t)n);
    memcpy(buf + n, vox, sizeof vox);
    return (size_t)n + sizeof vox;
}

static void test_fuzz_truncation_mutation(void **state) {
    (void)state;
    fixture *f = fx_new();
    tu_rng rng = {777};
    char path[512];
    unsigned char buf[1024], mut[1024];
    long ok_mutants = 0, bad_mutants = 0;
    for (int which = 0; which < 3; which++) {
        const char *name;
        size_t len = sample_file(which, buf, sizeof buf, &name);
        fx_path(f, name, path);
        as_image *img;
        write_file(path, buf, len, NULL, 0);
        assert_int_equal(as_image_read(f->ctx, path, &img), ANISTAR_OK);
        assert_int_equal(img->count, 12);
        as_image_free(f->ctx, img);
        /* Every strict prefix fails cleanly. */
        for (size_t l = 0; l < len; l++) {
            write_file(path, buf, l, NULL, 0);
            img = (as_image *)(uintptr_t)1;
            anistar_status st = as_image_read(f->ctx, path, &img);
            /* EIO when a cut MetaImage line names a data file that does not exist. */
            assert_true(st == ANISTAR_EFORMAT || st == ANISTAR_EIO);
            assert_null(img);
        }
        /* Random byte mutations: any status, never a crash or a leak; a success is a
         * consistent image. */
        for (int it = 0; it < 400; it++) {
            for (size_t k = 0; k < sizeof mut; k++) mut[k] = (unsigned char)tu_rng_u64(&rng);
            memcpy(mut, buf, len);
            int flips = 1 + (int)(tu_rng_u64(&rng) % 4);
            for (int k = 0; k < flips; k++) {
                size_t at = (size_t)(tu_rng_u64(&rng) % len);
                uint64_t r = tu_rng_u64(&rng);
                static const char interesting[] = "\n\r 0-9:=()#,%.\0eE";
                mut[at] = (r & 1) ? (unsigned char)(r >> 8)
                                  : (unsigned char)interesting[(r >> 8) % (sizeof interesting - 1)];
            }
            size_t mlen = len;
            if (tu_rng_u64(&rng) % 8 == 0) mlen += (size_t)(tu_rng_u64(&rng) % 9); /* junk tail */
            write_file(path, mut, mlen, NULL, 0);
            img = NULL;
            anistar_status st = as_image_read(f->ctx, path, &img);
            if (st == ANISTAR_OK) {
                ok_mutants++;
                assert_int_equal(img->count, img->nx * img->ny * img->nz);
                assert_int_equal(img->data_bytes, img->count * as_voxel_size(img->type));
                as_image_free(f->ctx, img);
            } else {
                bad_mutants++;
                assert_null(img);
                assert_true(st == ANISTAR_EFORMAT || st == ANISTAR_EIO);
                assert_true(strlen(anistar_last_error(f->ctx)) > 0);
            }
        }
    }
    assert_true(ok_mutants > 0 && bad_mutants > 0);
    fx_free(f);
}

/* ---- allocation failures ------------------------------------------------------------ */

static void test_alloc_failures(void **state) {
    (void)state;
    fixture *f = fx_new();
    char path[512], path2[512];
    /* One file per reader path: inr, nrrd raw, nrrd ascii, nhdr, mha, mhd, raw, real data. */
    const char *files[8];
    unsigned char buf[1024];
    const char *name;
    size_t len = sample_file(0, buf, sizeof buf, &name);
    char p0[512], p1[512], p2[512], p3[512], p4[512], p5[512];
    write_file(fx_path(f, name, p0), buf, len, NULL, 0);
    files[0] = p0;
    len = sample_file(1, buf, sizeof buf, &name);
    write_file(fx_path(f, name, p1), buf, len, NULL, 0);
    files[1] = p1;
    len = sample_file(2, buf, sizeof buf, &name);
    write_file(fx_path(f, name, p2), buf, len, NULL, 0);
    files[2] = p2;
    const char *asc = "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 2\nencoding: ascii\n\n"
                      "1.5 -2 3e3 4\n";
    write_file(fx_path(f, "asc.nrrd", p3), asc, strlen(asc), NULL, 0);
    files[3] = p3;
    const char *nhdr = "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 1\nencoding: raw\n"
                       "data file: d.raw\n";
    write_file(fx_path(f, "d.nhdr", p4), nhdr, strlen(nhdr), NULL, 0);
    write_file(fx_path(f, "d.raw", path), "abcd", 4, NULL, 0);
    files[4] = p4;
    const char *mhd =
        "NDims = 3\nDimSize = 2 2 1\nElementType = MET_UCHAR\nElementDataFile = d.raw\n";
    write_file(fx_path(f, "d.mhd", p5), mhd, strlen(mhd), NULL, 0);
    files[5] = p5;
    files[6] = AS_TEST_DATA_DIR "/brain_t1.nhdr";
    files[7] = AS_TEST_DATA_DIR "/liver_labels_half.inr";
    fx_path(f, "d.raw", path2);
    for (int which = 0; which < 9; which++) {
        long fail_at;
        for (fail_at = 1;; fail_at++) { /* allocation 0 is the context itself */
            tu_alloc a;
            tu_alloc_init(&a, fail_at);
            anistar_allocator al = tu_allocator(&a);
            anistar_context *ctx = anistar_context_new(&al);
            assert_non_null(ctx);
            as_image *img = NULL;
            anistar_status st;
            if (which < 8)
                st = as_image_read(ctx, files[which], &img);
            else
                st = as_image_read_raw(ctx, path2, 2, 2, 1, AS_VOXEL_U8, 0, NULL, NULL, 0, &img);
            if (st == ANISTAR_OK) {
                assert_non_null(img);
                as_image_free(ctx, img);
            } else {
                if (st != ANISTAR_ENOMEM)
                    print_error("file %d, failure at %ld: %s\n", which, fail_at,
                                anistar_last_error(ctx));
                assert_int_equal(st, ANISTAR_ENOMEM);
                assert_null(img);
                assert_true(a.failures > 0);
            }
            anistar_context_free(ctx);
            assert_int_equal(a.live_blocks, 0);
            assert_int_equal(a.live_bytes, 0);
            if (st == ANISTAR_OK) break;
            assert_true(fail_at < 100);
        }
        assert_true(fail_at >= 3); /* at least the image, its voxels and a header buffer */
    }
    fx_free(f);
}

/* ---- the image object and the grid -------------------------------------------------- */

static void test_image_object_and_grid(void **state) {
    (void)state;
    fixture *f = fx_new();
    as_image *img = (as_image *)(uintptr_t)1;
    assert_int_equal(as_image_new(f->ctx, SIZE_MAX / 2, 4, 1, AS_VOXEL_U8, &img), ANISTAR_EFORMAT);
    assert_null(img);
    assert_int_equal(as_image_new(f->ctx, 0, 4, 1, AS_VOXEL_U8, &img), ANISTAR_EINVAL);
    assert_int_equal(as_image_new(f->ctx, 7, 5, 3, AS_VOXEL_I16, &img), ANISTAR_OK);
    for (size_t i = 0; i < img->count; i++) assert_true(as_image_value(img, i) == 0);
    int16_t *d = img->data;
    for (size_t i = 0; i < img->count; i++) d[i] = (int16_t)(100 - (int)i);
    double buf[105];
    as_image_to_double(img, 3, 100, buf);
    for (size_t i = 0; i < 100; i++) assert_true(buf[i] == 100 - (double)(i + 3));
    assert_int_equal(as_image_count_nonfinite(img, NULL), 0);

    const double sp[3] = {0.5, 2, 3}, org[3] = {1, -2, 3};
    const double bad_sp[3] = {0.5, -2, 3}, nan_org[3] = {NAN, 0, 0};
    const double sing[9] = {1, 1, 0, 0, 0, 0, 0, 0, 1};
    double shear[9] = {1, 0.5, 0, 0, 1, 0.25, 0, 0, 1};
    assert_int_equal(as_image_set_geometry(f->ctx, img, bad_sp, NULL, NULL), ANISTAR_EINVAL);
    assert_int_equal(as_image_set_geometry(f->ctx, img, NULL, nan_org, NULL), ANISTAR_EINVAL);
    assert_int_equal(as_image_set_geometry(f->ctx, img, NULL, NULL, sing), ANISTAR_EINVAL);
    assert_true(img->grid.spacing[1] == 1); /* unchanged by the failures */
    assert_int_equal(as_image_set_geometry(f->ctx, img, sp, org, shear), ANISTAR_OK);
    /* Voxel <-> world, the box of the voxel centers and the bounding sphere. */
    double lo[3], hi[3], c[3], r;
    as_grid_world_box(&img->grid, 0, lo, hi);
    as_grid_bounding_sphere(&img->grid, 0, c, &r);
    double lo1[3], hi1[3], c1[3], r1;
    as_grid_world_box(&img->grid, 1.5, lo1, hi1);
    as_grid_bounding_sphere(&img->grid, 1.5, c1, &r1);
    assert_true(r1 > r);
    for (size_t k = 0; k < 3; k++)
        for (size_t j = 0; j < 5; j++)
            for (size_t i = 0; i < 7; i++) {
                double v[3] = {(double)i, (double)j, (double)k}, p[3], w[3];
                as_grid_voxel_to_world(&img->grid, v, p);
                as_grid_world_to_voxel(&img->grid, p, w);
                double dist = 0;
                for (int a = 0; a < 3; a++) {
                    assert_double_equal(w[a], v[a], 1e-13);
                    assert_true(p[a] >= lo[a] - 1e-12 && p[a] <= hi[a] + 1e-12);
                    assert_true(p[a] > lo1[a] && p[a] < hi1[a]);
                    dist += (p[a] - c[a]) * (p[a] - c[a]);
                }
                assert_true(sqrt(dist) <= r * (1 + 1e-12));
                /* world = origin + D diag(s) v */
                for (int a = 0; a < 3; a++) {
                    double e = org[a];
                    for (int b = 0; b < 3; b++) e += shear[3 * a + b] * sp[b] * v[b];
                    assert_double_equal(p[a], e, 1e-12);
                }
            }
    /* The box is tight: its corners are corner voxel centers. */
    double v0[3] = {0, 0, 0}, p0[3];
    as_grid_voxel_to_world(&img->grid, v0, p0);
    assert_true(p0[0] >= lo[0] && p0[0] <= hi[0]);
    assert_double_equal(lo[0], org[0], 1e-12); /* min x at voxel (0,0,0) (positive shear) */
    as_image_free(f->ctx, img);
    fx_free(f);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_skull),
        cmocka_unit_test(test_liver),
        cmocka_unit_test(test_brain_mhd_nhdr),
        cmocka_unit_test(test_roundtrip_all_types),
        cmocka_unit_test(test_format_variants),
        cmocka_unit_test(test_hostile_headers),
        cmocka_unit_test(test_not_regular_files),
        cmocka_unit_test(test_nonfinite_missing_raw),
        cmocka_unit_test(test_fuzz_truncation_mutation),
        cmocka_unit_test(test_alloc_failures),
        cmocka_unit_test(test_image_object_and_grid),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
