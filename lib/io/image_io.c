/*
 * image_io.c — 3D images in memory and their readers (see image_io.h for the contract).
 *
 * Layout of this file: voxel types; grid geometry; the image object; text helpers
 * (spans and number parsing); the header reader (a growing buffer read line by line);
 * the voxel loader shared by every format (size checks, raw or ASCII data, byte order,
 * non-finite check); then one parser per format and the dispatcher.
 *
 * Every parser works in two passes: the first reads lines from the file until the
 * format's end-of-header mark (the buffer may grow and move meanwhile), the second
 * interprets the now stable header text, so fields may come in any order and values
 * are plain spans into the buffer.
 */
#include "io/image_io.h"
#include "io/meshio.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>

/* ---- voxel types -------------------------------------------------------------------- */

size_t as_voxel_size(as_voxel_type t) {
    switch (t) {
    case AS_VOXEL_U8:
    case AS_VOXEL_I8:
        return 1;
    case AS_VOXEL_U16:
    case AS_VOXEL_I16:
        return 2;
    case AS_VOXEL_U32:
    case AS_VOXEL_I32:
    case AS_VOXEL_F32:
        return 4;
    case AS_VOXEL_U64:
    case AS_VOXEL_I64:
    case AS_VOXEL_F64:
        return 8;
    default:
        return 0;
    }
}

const char *as_voxel_type_name(as_voxel_type t) {
    switch (t) {
    case AS_VOXEL_U8:
        return "uint8";
    case AS_VOXEL_I8:
        return "int8";
    case AS_VOXEL_U16:
        return "uint16";
    case AS_VOXEL_I16:
        return "int16";
    case AS_VOXEL_U32:
        return "uint32";
    case AS_VOXEL_I32:
        return "int32";
    case AS_VOXEL_U64:
        return "uint64";
    case AS_VOXEL_I64:
        return "int64";
    case AS_VOXEL_F32:
        return "float32";
    case AS_VOXEL_F64:
        return "float64";
    default:
        return "invalid";
    }
}

static int as_voxel_is_float(as_voxel_type t) { return t == AS_VOXEL_F32 || t == AS_VOXEL_F64; }

/* ---- grid geometry ------------------------------------------------------------------ */

static double as_col_norm(const double m[9], int c) {
    return sqrt(m[c] * m[c] + m[3 + c] * m[3 + c] + m[6 + c] * m[6 + c]);
}

/* Fill g's geometry from spacing/origin/dir (NULL = defaults). Returns NULL on success,
 * or a static reason (g unchanged). */
static const char *as_grid_set(as_grid *g, const double spacing[3], const double origin[3],
                               const double dir[9]) {
    static const double ident[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    double s[3] = {1, 1, 1}, o[3] = {0, 0, 0}, d[9];
    memcpy(d, dir ? dir : ident, sizeof d);
    for (int i = 0; i < 3; i++) {
        if (spacing) s[i] = spacing[i];
        if (origin) o[i] = origin[i];
        if (!isfinite(s[i])) return "spacing is not finite";
        if (!(s[i] > 0)) return "spacing must be > 0";
        if (!isfinite(o[i])) return "origin is not finite";
    }
    for (int i = 0; i < 9; i++)
        if (!isfinite(d[i])) return "direction matrix is not finite";
    double a[9];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++) a[3 * r + c] = d[3 * r + c] * s[c];
    double c0 = a[4] * a[8] - a[5] * a[7];
    double c1 = a[5] * a[6] - a[3] * a[8];
    double c2 = a[3] * a[7] - a[4] * a[6];
    double det = a[0] * c0 + a[1] * c1 + a[2] * c2;
    double scale = as_col_norm(a, 0) * as_col_norm(a, 1) * as_col_norm(a, 2);
    if (!isfinite(det) || !isfinite(scale) || !(fabs(det) > 1e-12 * scale))
        return "direction matrix is singular (axes are parallel or zero)";
    double inv[9] = {
        c0 / det, (a[2] * a[7] - a[1] * a[8]) / det, (a[1] * a[5] - a[2] * a[4]) / det,
        c1 / det, (a[0] * a[8] - a[2] * a[6]) / det, (a[2] * a[3] - a[0] * a[5]) / det,
        c2 / det, (a[1] * a[6] - a[0] * a[7]) / det, (a[0] * a[4] - a[1] * a[3]) / det};
    for (int i = 0; i < 9; i++)
        if (!isfinite(inv[i])) return "direction matrix is too ill-conditioned to invert";
    memcpy(g->spacing, s, sizeof s);
    memcpy(g->origin, o, sizeof o);
    memcpy(g->dir, d, sizeof d);
    memcpy(g->a, a, sizeof a);
    memcpy(g->ainv, inv, sizeof inv);
    return NULL;
}

void as_grid_voxel_to_world(const as_grid *g, const double v[3], double p[3]) {
    for (int r = 0; r < 3; r++)
        p[r] =
            g->origin[r] + (g->a[3 * r] * v[0] + g->a[3 * r + 1] * v[1] + g->a[3 * r + 2] * v[2]);
}

static void as_grid_corner(const as_grid *g, double margin, int corner, double p[3]) {
    double v[3];
    for (int i = 0; i < 3; i++) v[i] = (corner >> i & 1) ? (double)(g->n[i] - 1) + margin : -margin;
    as_grid_voxel_to_world(g, v, p);
}

void as_grid_world_box(const as_grid *g, double margin, double lo[3], double hi[3]) {
    for (int c = 0; c < 8; c++) {
        double p[3];
        as_grid_corner(g, margin, c, p);
        for (int i = 0; i < 3; i++) {
            if (c == 0 || p[i] < lo[i]) lo[i] = p[i];
            if (c == 0 || p[i] > hi[i]) hi[i] = p[i];
        }
    }
}

void as_grid_bounding_sphere(const as_grid *g, double margin, double c[3], double *r) {
    double v[3];
    for (int i = 0; i < 3; i++) v[i] = 0.5 * (double)(g->n[i] - 1);
    as_grid_voxel_to_world(g, v, c);
    double r2 = 0;
    for (int k = 0; k < 8; k++) {
        double p[3];
        as_grid_corner(g, margin, k, p);
        double d2 = (p[0] - c[0]) * (p[0] - c[0]) + (p[1] - c[1]) * (p[1] - c[1]) +
                    (p[2] - c[2]) * (p[2] - c[2]);
        if (d2 > r2) r2 = d2;
    }
    *r = sqrt(r2);
}

/* ---- the image object --------------------------------------------------------------- */

/* Voxel count and byte size of an image, overflow-checked: 0 or -1. */
static int as_image_sizes(size_t nx, size_t ny, size_t nz, as_voxel_type type, size_t *count,
                          size_t *bytes) {
    size_t nxy;
    if (as_mul_size(nx, ny, &nxy) || as_mul_size(nxy, nz, count)) return -1;
    if (as_mul_size(*count, as_voxel_size(type), bytes)) return -1;
    /* Voxel indices are also used as ptrdiff_t (strides in the B-spline). */
    if (*bytes > (size_t)PTRDIFF_MAX) return -1;
    return 0;
}

static anistar_status as_image_alloc(anistar_context *ctx, size_t nx, size_t ny, size_t nz,
                                     as_voxel_type type, int zero, as_image **out) {
    *out = NULL;
    if (nx == 0 || ny == 0 || nz == 0 || as_voxel_size(type) == 0)
        return as_fail(ctx, ANISTAR_EINVAL, "image: invalid size %zux%zux%zu or voxel type", nx, ny,
                       nz);
    size_t count, bytes;
    if (as_image_sizes(nx, ny, nz, type, &count, &bytes))
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "image dimensions %zux%zux%zu of %s overflow the address space", nx, ny, nz,
                       as_voxel_type_name(type));
    as_image *img = as_alloc(ctx, sizeof *img);
    if (!img) return as_fail(ctx, ANISTAR_ENOMEM, "image: out of memory");
    memset(img, 0, sizeof *img);
    img->data = as_alloc(ctx, bytes);
    if (!img->data) {
        as_free(ctx, img, sizeof *img);
        return as_fail(ctx, ANISTAR_ENOMEM, "image: out of memory for %zu bytes of voxels", bytes);
    }
    if (zero) memset(img->data, 0, bytes);
    img->nx = img->grid.n[0] = nx;
    img->ny = img->grid.n[1] = ny;
    img->nz = img->grid.n[2] = nz;
    img->count = count;
    img->type = type;
    img->data_bytes = bytes;
    (void)as_grid_set(&img->grid, NULL, NULL, NULL); /* defaults always succeed */
    *out = img;
    return ANISTAR_OK;
}

anistar_status as_image_new(anistar_context *ctx, size_t nx, size_t ny, size_t nz,
                            as_voxel_type type, as_image **out) {
    return as_image_alloc(ctx, nx, ny, nz, type, 1, out);
}

void as_image_free(anistar_context *ctx, as_image *img) {
    if (!img) return;
    as_free(ctx, img->data, img->data_bytes);
    as_free(ctx, img, sizeof *img);
}

anistar_status as_image_set_geometry(anistar_context *ctx, as_image *img, const double spacing[3],
                                     const double origin[3], const double dir[9]) {
    const char *why = as_grid_set(&img->grid, spacing, origin, dir);
    if (why) return as_fail(ctx, ANISTAR_EINVAL, "image geometry: %s", why);
    return ANISTAR_OK;
}

double as_image_value(const as_image *img, size_t idx) {
    const void *d = img->data;
    switch (img->type) {
    case AS_VOXEL_U8:
        return ((const uint8_t *)d)[idx];
    case AS_VOXEL_I8:
        return ((const int8_t *)d)[idx];
    case AS_VOXEL_U16:
        return ((const uint16_t *)d)[idx];
    case AS_VOXEL_I16:
        return ((const int16_t *)d)[idx];
    case AS_VOXEL_U32:
        return ((const uint32_t *)d)[idx];
    case AS_VOXEL_I32:
        return ((const int32_t *)d)[idx];
    case AS_VOXEL_U64:
        return (double)((const uint64_t *)d)[idx];
    case AS_VOXEL_I64:
        return (double)((const int64_t *)d)[idx];
    case AS_VOXEL_F32:
        return ((const float *)d)[idx];
    case AS_VOXEL_F64:
        return ((const double *)d)[idx];
    default:
        return NAN;
    }
}

void as_image_to_double(const as_image *img, size_t first, size_t n, double *out) {
    /* One loop per type, the switch outside: the conversion loops vectorise. */
    switch (img->type) {
    case AS_VOXEL_U8: {
        const uint8_t *src = (const uint8_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_I8: {
        const int8_t *src = (const int8_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_U16: {
        const uint16_t *src = (const uint16_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_I16: {
        const int16_t *src = (const int16_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_U32: {
        const uint32_t *src = (const uint32_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_I32: {
        const int32_t *src = (const int32_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_U64: {
        const uint64_t *src = (const uint64_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_I64: {
        const int64_t *src = (const int64_t *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_F32: {
        const float *src = (const float *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    case AS_VOXEL_F64: {
        const double *src = (const double *)img->data + first;
        for (size_t i = 0; i < n; i++) out[i] = (double)src[i];
        break;
    }
    default:
        for (size_t i = 0; i < n; i++) out[i] = NAN;
        break;
    }
}

void as_image_range(const as_image *img, double *lo, double *hi) {
    double a = NAN, b = NAN, buf[256];
    for (size_t first = 0; first < img->count; first += 256) {
        size_t n = img->count - first < 256 ? img->count - first : 256;
        as_image_to_double(img, first, n, buf);
        for (size_t i = 0; i < n; i++) {
            if (buf[i] < a || isnan(a)) a = buf[i];
            if (buf[i] > b || isnan(b)) b = buf[i];
        }
    }
    *lo = a;
    *hi = b;
}

void as_otsu_init(as_otsu_hist *h, double lo, double hi) {
    memset(h, 0, sizeof *h);
    h->lo = lo;
    h->hi = hi;
}

void as_otsu_add(as_otsu_hist *h, const double *v, size_t n) {
    const double w = h->hi - h->lo;
    if (!(w > 0)) return;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(v[i])) continue;
        double t = (v[i] - h->lo) / w * AS_OTSU_BINS;
        int b = t <= 0 ? 0 : t >= AS_OTSU_BINS ? AS_OTSU_BINS - 1 : (int)t;
        h->count[b]++;
    }
}

int as_otsu_pick(const as_otsu_hist *h, double *iso) {
    const double w = h->hi - h->lo;
    if (!(w > 0) || !isfinite(w)) return -1;
    /* class sums by bin centre; the split after bin k (k = 0 .. BINS-2) */
    double n = 0, m = 0;
    for (int k = 0; k < AS_OTSU_BINS; k++) {
        n += (double)h->count[k];
        m += (double)h->count[k] * (k + 0.5);
    }
    if (!(n > 0)) return -1;
    double n0 = 0, m0 = 0, best = -1;
    int at = AS_OTSU_BINS / 2 - 1, last = at;
    for (int k = 0; k < AS_OTSU_BINS - 1; k++) {
        n0 += (double)h->count[k];
        m0 += (double)h->count[k] * (k + 0.5);
        double n1 = n - n0;
        if (n0 <= 0 || n1 <= 0) continue;
        double d = m0 / n0 - (m - m0) / n1, var = n0 * n1 * d * d;
        if (var > best) { /* the first maximum */
            best = var;
            at = last = k;
        } else if (var == best && k == last + 1) {
            last = k; /* the same split, bit for bit: the bins between are empty */
        }
    }
    /* design: the middle of the maximum's run of empty bins. The splits between two
     * occupied bins with nothing between them all score the same, and the first of them
     * put the threshold one bin above the lower value: 0.39 for an image of 0s and 100s,
     * where the interpolating B-spline's undershoot near the edges crosses it (208
     * spurious components meshing a ball with the default iso; session 21's sweep) */
    at = (at + last) / 2;
    *iso = h->lo + w * (double)(at + 1) / AS_OTSU_BINS;
    return 0;
}

int as_image_otsu(const as_image *img, double *iso) {
    double lo = INFINITY, hi = -INFINITY, buf[256];
    for (size_t first = 0; first < img->count; first += 256) {
        size_t n = img->count - first < 256 ? img->count - first : 256;
        as_image_to_double(img, first, n, buf);
        for (size_t i = 0; i < n; i++) {
            if (!isfinite(buf[i])) continue;
            if (buf[i] < lo) lo = buf[i];
            if (buf[i] > hi) hi = buf[i];
        }
    }
    if (!(lo < hi)) return -1;
    as_otsu_hist h;
    as_otsu_init(&h, lo, hi);
    for (size_t first = 0; first < img->count; first += 256) {
        size_t n = img->count - first < 256 ? img->count - first : 256;
        as_image_to_double(img, first, n, buf);
        as_otsu_add(&h, buf, n);
    }
    return as_otsu_pick(&h, iso);
}

size_t as_image_count_nonfinite(const as_image *img, size_t *first_idx) {
    size_t bad = 0;
    if (img->type == AS_VOXEL_F32) {
        const float *d = img->data;
        for (size_t i = 0; i < img->count; i++)
            if (!isfinite(d[i]) && bad++ == 0 && first_idx) *first_idx = i;
    } else if (img->type == AS_VOXEL_F64) {
        const double *d = img->data;
        for (size_t i = 0; i < img->count; i++)
            if (!isfinite(d[i]) && bad++ == 0 && first_idx) *first_idx = i;
    }
    return bad;
}

/* ---- byte order --------------------------------------------------------------------- */

static int as_host_big_endian(void) {
    const uint16_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 0;
}

static void as_swap_bytes(void *data, size_t count, size_t size) {
    unsigned char *p = data;
    for (size_t i = 0; i < count; i++, p += size)
        for (size_t a = 0, b = size - 1; a < b; a++, b--) {
            unsigned char t = p[a];
            p[a] = p[b];
            p[b] = t;
        }
}

/* ---- text helpers ------------------------------------------------------------------- */

typedef struct as_span {
    const char *p;
    size_t n;
} as_span;

static int as_is_space(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

static char as_lower(char c) { return (c >= 'A' && c <= 'Z') ? (char)(c - 'A' + 'a') : c; }

static as_span as_span_trim(as_span s) {
    while (s.n && as_is_space(s.p[0])) s.p++, s.n--;
    while (s.n && as_is_space(s.p[s.n - 1])) s.n--;
    return s;
}

/* Case-insensitive (ASCII) equality with a literal. */
static int as_span_ieq(as_span s, const char *lit) {
    size_t n = strlen(lit);
    if (n != s.n) return 0;
    for (size_t i = 0; i < n; i++)
        if (as_lower(s.p[i]) != as_lower(lit[i])) return 0;
    return 1;
}

static int as_span_starts(as_span s, const char *lit) {
    size_t n = strlen(lit);
    return s.n >= n && memcmp(s.p, lit, n) == 0;
}

/* Next token of *rest separated by whitespace (and by commas when commas != 0):
 * 1 and *tok set, or 0 when only separators remain. */
static int as_span_token(as_span *rest, as_span *tok, int commas) {
    size_t i = 0;
    while (i < rest->n && (as_is_space(rest->p[i]) || (commas && rest->p[i] == ','))) i++;
    size_t j = i;
    while (j < rest->n && !as_is_space(rest->p[j]) && !(commas && rest->p[j] == ',')) j++;
    tok->p = rest->p + i;
    tok->n = j - i;
    rest->p += j;
    rest->n -= j;
    return tok->n > 0;
}

/* A printable, NUL-terminated, shortened copy of s for messages. */
#define AS_SHOW_MAX 48
typedef struct as_show {
    char s[AS_SHOW_MAX + 4];
} as_show;

static as_show as_span_show(as_span s) {
    as_show out;
    size_t n = s.n < AS_SHOW_MAX ? s.n : AS_SHOW_MAX;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)s.p[i];
        out.s[i] = (c >= 32 && c < 127) ? (char)c : '?';
    }
    if (s.n > AS_SHOW_MAX) {
        memcpy(out.s + n, "...", 4);
    } else {
        out.s[n] = '\0';
    }
    return out;
}

/* Copy a token into a NUL-terminated buffer of 64 bytes; -1 when too long or empty. */
static int as_token_cstr(as_span t, char buf[64]) {
    if (t.n == 0 || t.n >= 64) return -1;
    memcpy(buf, t.p, t.n);
    buf[t.n] = '\0';
    return 0;
}

static int as_parse_i64(as_span t, int64_t *v) {
    char buf[64];
    if (as_token_cstr(t, buf)) return -1;
    if (!((buf[0] >= '0' && buf[0] <= '9') || buf[0] == '-' || buf[0] == '+')) return -1;
    char *end;
    errno = 0;
    long long x = strtoll(buf, &end, 10);
    if (errno || *end != '\0' || end == buf) return -1;
    *v = (int64_t)x;
    return 0;
}

static int as_parse_u64(as_span t, uint64_t *v) {
    char buf[64];
    if (as_token_cstr(t, buf)) return -1;
    if (!((buf[0] >= '0' && buf[0] <= '9') || buf[0] == '+')) return -1;
    char *end;
    errno = 0;
    unsigned long long x = strtoull(buf, &end, 10);
    if (errno || *end != '\0' || end == buf) return -1;
    *v = (uint64_t)x;
    return 0;
}

/* A decimal floating-point number (strtod syntax without hex floats). Non-finite
 * values ("nan", "inf") are accepted only when allow_nonfinite. */
static int as_parse_f64(as_span t, double *v, int allow_nonfinite) {
    char buf[64];
    if (as_token_cstr(t, buf)) return -1;
    for (const char *c = buf; *c; c++)
        if (*c == 'x' || *c == 'X') return -1;
    char *end;
    errno = 0;
    double x = strtod(buf, &end);
    if (*end != '\0' || end == buf) return -1;
    if (errno == ERANGE && isinf(x)) return -1; /* overflow */
    if (!allow_nonfinite && !isfinite(x)) return -1;
    *v = x;
    return 0;
}

static int as_parse_f32(as_span t, float *v) {
    char buf[64];
    if (as_token_cstr(t, buf)) return -1;
    for (const char *c = buf; *c; c++)
        if (*c == 'x' || *c == 'X') return -1;
    char *end;
    errno = 0;
    float x = strtof(buf, &end);
    if (*end != '\0' || end == buf) return -1;
    if (errno == ERANGE && isinf(x)) return -1;
    *v = x;
    return 0;
}

/* ---- the header reader -------------------------------------------------------------- */

/* Headers longer than this are rejected (no real header comes close). */
#define AS_HEADER_MAX ((size_t)1 << 20)

typedef struct as_hreader {
    anistar_context *ctx;
    const char *path;
    FILE *f;
    char *buf; /* bytes 0 .. len-1 of the file */
    size_t cap, len;
    size_t pos; /* start of the next line */
    int eof;
} as_hreader;

static anistar_status as_hr_open(anistar_context *ctx, const char *path, as_hreader *hr) {
    memset(hr, 0, sizeof *hr);
    hr->ctx = ctx;
    hr->path = path;
    hr->f = fopen(path, "rb");
    if (!hr->f) return as_fail(ctx, ANISTAR_EIO, "%s: cannot open for reading", path);
    const char *why = as_not_regular_file(hr->f);
    if (why) {
        fclose(hr->f);
        hr->f = NULL;
        return as_fail(ctx, ANISTAR_EIO, "%s: cannot read: %s", path, why);
    }
    return ANISTAR_OK;
}

static void as_hr_close(as_hreader *hr) {
    if (hr->f) fclose(hr->f);
    as_free(hr->ctx, hr->buf, hr->cap);
    hr->f = NULL;
    hr->buf = NULL;
    hr->cap = 0;
}

/* Read more of the file into the buffer (growing it, up to AS_HEADER_MAX). */
static anistar_status as_hr_fill(as_hreader *hr) {
    if (hr->len == hr->cap) {
        if (hr->cap >= AS_HEADER_MAX)
            return as_fail(hr->ctx, ANISTAR_EFORMAT,
                           "%s: header longer than %zu bytes (or its end mark is missing)",
                           hr->path, AS_HEADER_MAX);
        size_t ncap = hr->cap ? 2 * hr->cap : 4096;
        char *nb = as_realloc(hr->ctx, hr->buf, hr->cap, ncap);
        if (!nb)
            return as_fail(hr->ctx, ANISTAR_ENOMEM, "%s: out of memory reading the header",
                           hr->path);
        hr->buf = nb;
        hr->cap = ncap;
    }
    size_t got = fread(hr->buf + hr->len, 1, hr->cap - hr->len, hr->f);
    if (got == 0) {
        if (ferror(hr->f)) return as_fail(hr->ctx, ANISTAR_EIO, "%s: read error", hr->path);
        hr->eof = 1;
    }
    hr->len += got;
    return ANISTAR_OK;
}

/* The next line (without its '\n' or "\r\n"): *got = 1 and *line set, or *got = 0 at the
 * end of the file. A header line holding a NUL byte is an error. */
static anistar_status as_hr_line(as_hreader *hr, as_span *line, int *got) {
    size_t scan = hr->pos;
    for (;;) {
        const char *nl = scan < hr->len ? memchr(hr->buf + scan, '\n', hr->len - scan) : NULL;
        size_t end;
        if (nl) {
            end = (size_t)(nl - hr->buf);
        } else if (!hr->eof) {
            scan = hr->len;
            anistar_status st = as_hr_fill(hr);
            if (st) return st;
            continue;
        } else if (hr->pos < hr->len) {
            end = hr->len; /* last line, unterminated */
        } else {
            *got = 0;
            return ANISTAR_OK;
        }
        line->p = hr->buf + hr->pos;
        line->n = end - hr->pos;
        if (memchr(line->p, '\0', line->n))
            return as_fail(hr->ctx, ANISTAR_EFORMAT, "%s: NUL byte in header text", hr->path);
        hr->pos = end < hr->len ? end + 1 : end;
        if (line->n && line->p[line->n - 1] == '\r') line->n--;
        *got = 1;
        return ANISTAR_OK;
    }
}

/* Iterate the lines of buf[0 .. end) (the second pass, over a stable buffer). */
static int as_lines_next(const char *buf, size_t end, size_t *pos, as_span *line) {
    if (*pos >= end) return 0;
    const char *nl = memchr(buf + *pos, '\n', end - *pos);
    size_t e = nl ? (size_t)(nl - buf) : end;
    line->p = buf + *pos;
    line->n = e - *pos;
    if (line->n && line->p[line->n - 1] == '\r') line->n--;
    *pos = nl ? e + 1 : end;
    return 1;
}

/* The data file named by a header: name relative to the header's folder unless
 * absolute. *out allocated from ctx (*out_size bytes). */
static anistar_status as_join_path(anistar_context *ctx, const char *hdr_path, as_span name,
                                   char **out, size_t *out_size) {
    size_t dir_len = 0;
    if (!(name.n && name.p[0] == '/')) {
        const char *slash = strrchr(hdr_path, '/');
        if (slash) dir_len = (size_t)(slash - hdr_path) + 1;
    }
    size_t n = dir_len + name.n + 1;
    char *s = as_alloc(ctx, n);
    if (!s) return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", hdr_path);
    memcpy(s, hdr_path, dir_len);
    memcpy(s + dir_len, name.p, name.n);
    s[n - 1] = '\0';
    *out = s;
    *out_size = n;
    return ANISTAR_OK;
}

/* ---- voxel loading ------------------------------------------------------------------ */

typedef struct as_data_desc {
    const char *hdr_path;  /* for messages */
    const char *data_path; /* the file holding the voxels (may be hdr_path) */
    int64_t dims[3];
    as_voxel_type type;
    int big_endian;
    int ascii;
    uint64_t offset;    /* where the data region starts in data_path */
    uint64_t line_skip; /* lines skipped from offset (NRRD) */
    int64_t byte_skip;  /* then bytes skipped; -1: raw data ends at the end of the file */
    double spacing[3], origin[3], dir[9];
} as_data_desc;

static anistar_status as_file_size(anistar_context *ctx, FILE *f, const char *path,
                                   uint64_t *size) {
    if (fseeko(f, 0, SEEK_END) != 0)
        return as_fail(ctx, ANISTAR_EIO, "%s: cannot seek (not a regular file?)", path);
    off_t s = ftello(f);
    if (s < 0) return as_fail(ctx, ANISTAR_EIO, "%s: cannot tell the file size", path);
    *size = (uint64_t)s;
    return ANISTAR_OK;
}

static anistar_status as_seek(anistar_context *ctx, FILE *f, const char *path, uint64_t pos) {
    if (pos > (uint64_t)INT64_MAX || (off_t)pos < 0 || fseeko(f, (off_t)pos, SEEK_SET) != 0)
        return as_fail(ctx, ANISTAR_EIO, "%s: cannot seek to byte %llu", path,
                       (unsigned long long)pos);
    return ANISTAR_OK;
}

/* Parse count ASCII numbers of type t from text into dst. */
static anistar_status as_parse_ascii(anistar_context *ctx, const as_data_desc *d, const char *text,
                                     size_t len, size_t count, void *dst) {
    as_span rest = {text, len}, tok;
    for (size_t i = 0; i < count; i++) {
        if (!as_span_token(&rest, &tok, 1))
            return as_fail(ctx, ANISTAR_EFORMAT,
                           "%s: ASCII data in '%s' holds only %zu of the %zu values the "
                           "header declares",
                           d->hdr_path, d->data_path, i, count);
        int bad = 0;
        int64_t si = 0;
        uint64_t ui = 0;
        switch (d->type) {
        case AS_VOXEL_U8:
            bad = as_parse_u64(tok, &ui) || ui > UINT8_MAX;
            if (!bad) ((uint8_t *)dst)[i] = (uint8_t)ui;
            break;
        case AS_VOXEL_U16:
            bad = as_parse_u64(tok, &ui) || ui > UINT16_MAX;
            if (!bad) ((uint16_t *)dst)[i] = (uint16_t)ui;
            break;
        case AS_VOXEL_U32:
            bad = as_parse_u64(tok, &ui) || ui > UINT32_MAX;
            if (!bad) ((uint32_t *)dst)[i] = (uint32_t)ui;
            break;
        case AS_VOXEL_U64:
            bad = as_parse_u64(tok, &ui);
            if (!bad) ((uint64_t *)dst)[i] = ui;
            break;
        case AS_VOXEL_I8:
            bad = as_parse_i64(tok, &si) || si < INT8_MIN || si > INT8_MAX;
            if (!bad) ((int8_t *)dst)[i] = (int8_t)si;
            break;
        case AS_VOXEL_I16:
            bad = as_parse_i64(tok, &si) || si < INT16_MIN || si > INT16_MAX;
            if (!bad) ((int16_t *)dst)[i] = (int16_t)si;
            break;
        case AS_VOXEL_I32:
            bad = as_parse_i64(tok, &si) || si < INT32_MIN || si > INT32_MAX;
            if (!bad) ((int32_t *)dst)[i] = (int32_t)si;
            break;
        case AS_VOXEL_I64:
            bad = as_parse_i64(tok, &si);
            if (!bad) ((int64_t *)dst)[i] = si;
            break;
        case AS_VOXEL_F32:
            bad = as_parse_f32(tok, &((float *)dst)[i]);
            break;
        case AS_VOXEL_F64:
            bad = as_parse_f64(tok, &((double *)dst)[i], 1);
            break;
        default:
            bad = 1;
            break;
        }
        if (bad)
            return as_fail(ctx, ANISTAR_EFORMAT,
                           "%s: ASCII value %zu '%s' in '%s' is not a valid %s", d->hdr_path, i,
                           as_span_show(tok).s, d->data_path, as_voxel_type_name(d->type));
    }
    if (as_span_token(&rest, &tok, 1))
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: ASCII data in '%s' holds more than the %zu values the header "
                       "declares ('%s' follows)",
                       d->hdr_path, d->data_path, count, as_span_show(tok).s);
    return ANISTAR_OK;
}

/*
 * Load the voxels described by d into a new image.
 * Returns ANISTAR_OK, EFORMAT (bad sizes or geometry, truncated or oversized data, bad
 * ASCII, non-finite voxels), EIO, ENOMEM.
 * design: every size is validated, and compared with the file size, before the voxel
 *   array is allocated; the ASCII text is bounded by the file size too.
 */
static anistar_status as_load_voxels(anistar_context *ctx, const as_data_desc *d, as_image **out) {
    *out = NULL;
    const char *hp = d->hdr_path;
    size_t n[3];
    for (int i = 0; i < 3; i++) {
        if (d->dims[i] <= 0)
            return as_fail(ctx, ANISTAR_EFORMAT, "%s: image sizes must be positive, got %lld", hp,
                           (long long)d->dims[i]);
        if ((uint64_t)d->dims[i] > (uint64_t)SIZE_MAX)
            return as_fail(ctx, ANISTAR_EFORMAT, "%s: image size %lld overflows", hp,
                           (long long)d->dims[i]);
        n[i] = (size_t)d->dims[i];
    }
    size_t count, bytes;
    if (as_image_sizes(n[0], n[1], n[2], d->type, &count, &bytes))
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: image dimensions %zux%zux%zu of %s overflow the address space", hp,
                       n[0], n[1], n[2], as_voxel_type_name(d->type));
    as_grid geom;
    const char *why = as_grid_set(&geom, d->spacing, d->origin, d->dir);
    if (why) return as_fail(ctx, ANISTAR_EFORMAT, "%s: %s", hp, why);

    FILE *f = fopen(d->data_path, "rb");
    if (!f) {
        if (d->data_path == hp || strcmp(d->data_path, hp) == 0)
            return as_fail(ctx, ANISTAR_EIO, "%s: cannot open for reading", hp);
        return as_fail(ctx, ANISTAR_EIO, "%s: cannot open the data file '%s' it names", hp,
                       d->data_path);
    }
    why = as_not_regular_file(f);
    if (why) {
        fclose(f);
        return as_fail(ctx, ANISTAR_EIO, "%s: cannot read the data file '%s' it names: %s", hp,
                       d->data_path, why);
    }
    as_image *img = NULL;
    char *text = NULL;
    size_t text_size = 0;
    uint64_t size = 0, start = d->offset;
    anistar_status st = as_file_size(ctx, f, d->data_path, &size);
    if (st) goto done;
    if (start > size) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: truncated: no voxel data after the header", hp);
        goto done;
    }
    if (d->line_skip > 0) {
        if ((st = as_seek(ctx, f, d->data_path, start))) goto done;
        for (uint64_t l = 0; l < d->line_skip; l++) {
            int c;
            while ((c = getc(f)) != EOF && c != '\n') start++;
            if (c == EOF) {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: truncated: '%s' ends within the %llu lines to skip", hp,
                             d->data_path, (unsigned long long)d->line_skip);
                goto done;
            }
            start++;
        }
    }
    uint64_t avail = size - start;
    if (!d->ascii) {
        if (d->byte_skip == -1) {
            if (avail < bytes) goto truncated;
            start = size - bytes;
        } else {
            if ((uint64_t)d->byte_skip > avail) goto truncated;
            start += (uint64_t)d->byte_skip;
            avail -= (uint64_t)d->byte_skip;
            if (avail < bytes) goto truncated;
            if (avail > bytes) {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: '%s' holds %llu bytes after the %zu bytes of voxel data the "
                             "header declares (%zux%zux%zu %s at byte %llu): the header's "
                             "sizes or type disagree with the file",
                             hp, d->data_path, (unsigned long long)(avail - bytes), bytes, n[0],
                             n[1], n[2], as_voxel_type_name(d->type), (unsigned long long)start);
                goto done;
            }
        }
    } else {
        if (d->byte_skip < 0 || (uint64_t)d->byte_skip > avail) goto truncated;
        start += (uint64_t)d->byte_skip;
        avail -= (uint64_t)d->byte_skip;
        /* Each value takes at least one character. */
        if (avail < count || avail >= (uint64_t)SIZE_MAX) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: truncated: %llu bytes of ASCII data in '%s' cannot hold the "
                         "%zu values the header declares",
                         hp, (unsigned long long)avail, d->data_path, count);
            goto done;
        }
    }

    if ((st = as_image_alloc(ctx, n[0], n[1], n[2], d->type, 0, &img))) goto done;
    if ((st = as_seek(ctx, f, d->data_path, start))) goto done;
    if (!d->ascii) {
        if (fread(img->data, 1, bytes, f) != bytes) {
            st = as_fail(ctx, ANISTAR_EIO, "%s: read error in '%s'", hp, d->data_path);
            goto done;
        }
        size_t vs = as_voxel_size(d->type);
        if (vs > 1 && (d->big_endian != 0) != as_host_big_endian())
            as_swap_bytes(img->data, count, vs);
    } else {
        text_size = (size_t)avail + 1;
        text = as_alloc(ctx, text_size);
        if (!text) {
            st = as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory for the ASCII data", hp);
            goto done;
        }
        if (fread(text, 1, (size_t)avail, f) != (size_t)avail) {
            st = as_fail(ctx, ANISTAR_EIO, "%s: read error in '%s'", hp, d->data_path);
            goto done;
        }
        text[avail] = '\0';
        if ((st = as_parse_ascii(ctx, d, text, (size_t)avail, count, img->data))) goto done;
    }
    if (as_voxel_is_float(d->type)) {
        size_t first = 0, bad = as_image_count_nonfinite(img, &first);
        if (bad) {
            size_t i = first % n[0], j = first / n[0] % n[1], k = first / n[0] / n[1];
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: image has %zu non-finite voxels (NaN or infinite), the first "
                         "at (%zu,%zu,%zu)",
                         hp, bad, i, j, k);
            goto done;
        }
    }
    img->grid = geom;
    img->grid.n[0] = n[0];
    img->grid.n[1] = n[1];
    img->grid.n[2] = n[2];
    goto done;

truncated:
    st = as_fail(ctx, ANISTAR_EFORMAT,
                 "%s: truncated voxel data: the header declares %zux%zux%zu %s = %zu bytes "
                 "but '%s' has %llu bytes (data from byte %llu)",
                 hp, n[0], n[1], n[2], as_voxel_type_name(d->type), bytes, d->data_path,
                 (unsigned long long)size, (unsigned long long)start);
done:
    fclose(f);
    as_free(ctx, text, text_size);
    if (st) {
        as_image_free(ctx, img);
        img = NULL;
    }
    *out = img;
    return st;
}

static void as_desc_init(as_data_desc *d, const char *path) {
    memset(d, 0, sizeof *d);
    d->hdr_path = path;
    d->data_path = path;
    for (int i = 0; i < 3; i++) {
        d->dims[i] = 1;
        d->spacing[i] = 1;
        d->origin[i] = 0;
        d->dir[4 * i] = 1;
    }
}

/* ---- Inrimage ----------------------------------------------------------------------- */

static anistar_status as_inr_number(anistar_context *ctx, const char *path, as_span key,
                                    as_span val, double *x) {
    if (as_parse_f64(val, x, 0))
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: field '%s': '%s' is not a finite number", path,
                       as_span_show(key).s, as_span_show(val).s);
    return ANISTAR_OK;
}

static anistar_status as_inr_int(anistar_context *ctx, const char *path, as_span key, as_span val,
                                 int64_t *x) {
    if (as_parse_i64(val, x))
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: field '%s': '%s' is not an integer", path,
                       as_span_show(key).s, as_span_show(val).s);
    if (*x <= 0)
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: field '%s': %lld must be positive", path,
                       as_span_show(key).s, (long long)*x);
    return ANISTAR_OK;
}

/*
 * Parse an Inrimage header and load its voxels (fields: image_io.h).
 * design: first pass reads lines up to "##}"; second pass maps KEY=VALUE lines to the
 *   data description; unknown keys and unsupported values are EFORMAT naming the key.
 */
anistar_status as_image_read_inr(anistar_context *ctx, const char *path, as_image **out) {
    *out = NULL;
    as_hreader hr;
    anistar_status st = as_hr_open(ctx, path, &hr);
    if (st) return st;
    as_span line;
    int got;
    size_t hdr_end = 0;
    if ((st = as_hr_line(&hr, &line, &got))) goto done;
    if (!got || !(as_span_starts(line, "#INRIMAGE-4#{") && line.n == 13)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: not an Inrimage file (no '#INRIMAGE-4#{' line)",
                     path);
        goto done;
    }
    size_t body = hr.pos;
    for (;;) {
        if ((st = as_hr_line(&hr, &line, &got))) goto done;
        if (!got) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: no '##}' line ending the header", path);
            goto done;
        }
        if (as_span_starts(line, "##}")) break;
    }
    hdr_end = hr.pos;

    as_data_desc d;
    as_desc_init(&d, path);
    int has_x = 0, has_y = 0, has_type = 0, has_pix = 0, has_cpu = 0;
    int kind = 0; /* 1 unsigned fixed, 2 signed fixed, 3 float */
    int64_t vdim = 1, bits = 0;
    size_t pos = body;
    while (as_lines_next(hr.buf, hdr_end, &pos, &line)) {
        if (as_span_starts(line, "##}")) break;
        as_span t = as_span_trim(line);
        if (t.n == 0 || t.p[0] == '#') continue;
        const char *eq = memchr(t.p, '=', t.n);
        if (!eq) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: header line '%s' is not KEY=VALUE", path,
                         as_span_show(t).s);
            goto done;
        }
        as_span key = as_span_trim((as_span){t.p, (size_t)(eq - t.p)});
        as_span val = as_span_trim((as_span){eq + 1, t.n - (size_t)(eq - t.p) - 1});
        double x;
        if (as_span_ieq(key, "XDIM")) {
            if ((st = as_inr_int(ctx, path, key, val, &d.dims[0]))) goto done;
            has_x = 1;
        } else if (as_span_ieq(key, "YDIM")) {
            if ((st = as_inr_int(ctx, path, key, val, &d.dims[1]))) goto done;
            has_y = 1;
        } else if (as_span_ieq(key, "ZDIM")) {
            if ((st = as_inr_int(ctx, path, key, val, &d.dims[2]))) goto done;
        } else if (as_span_ieq(key, "VDIM")) {
            if ((st = as_inr_int(ctx, path, key, val, &vdim))) goto done;
        } else if (as_span_ieq(key, "TYPE")) {
            if (as_span_ieq(val, "unsigned fixed"))
                kind = 1;
            else if (as_span_ieq(val, "signed fixed"))
                kind = 2;
            else if (as_span_ieq(val, "float"))
                kind = 3;
            else {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: field 'TYPE': unsupported voxel type '%s' (expected "
                             "'unsigned fixed', 'signed fixed' or 'float')",
                             path, as_span_show(val).s);
                goto done;
            }
            has_type = 1;
        } else if (as_span_ieq(key, "PIXSIZE")) {
            as_span rest = val, num, unit, extra;
            if (!as_span_token(&rest, &num, 0) || as_parse_i64(num, &bits) ||
                !as_span_token(&rest, &unit, 0) || !as_span_ieq(unit, "bits") ||
                as_span_token(&rest, &extra, 0) ||
                (bits != 8 && bits != 16 && bits != 32 && bits != 64)) {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: field 'PIXSIZE': '%s' is not '8 bits', '16 bits', '32 bits' "
                             "or '64 bits'",
                             path, as_span_show(val).s);
                goto done;
            }
            has_pix = 1;
        } else if (as_span_ieq(key, "SCALE")) {
            int64_t e;
            if (!as_span_starts(val, "2**") || as_parse_i64((as_span){val.p + 3, val.n - 3}, &e)) {
                st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'SCALE': '%s' is not '2**N'", path,
                             as_span_show(val).s);
                goto done;
            }
        } else if (as_span_ieq(key, "CPU")) {
            if (as_span_ieq(val, "decm") || as_span_ieq(val, "alpha") || as_span_ieq(val, "pc"))
                d.big_endian = 0;
            else if (as_span_ieq(val, "sun") || as_span_ieq(val, "sgi"))
                d.big_endian = 1;
            else {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: field 'CPU': unknown '%s' (expected decm, alpha, pc, sun or "
                             "sgi)",
                             path, as_span_show(val).s);
                goto done;
            }
            has_cpu = 1;
        } else if (key.n == 2 && (as_lower(key.p[0]) == 'v' || as_lower(key.p[0]) == 't') &&
                   as_lower(key.p[1]) >= 'x' && as_lower(key.p[1]) <= 'z') {
            /* VX VY VZ: spacing; TX TY TZ: origin (CGAL's ImageIO translation). */
            if ((st = as_inr_number(ctx, path, key, val, &x))) goto done;
            if (as_lower(key.p[0]) == 'v')
                d.spacing[as_lower(key.p[1]) - 'x'] = x;
            else
                d.origin[as_lower(key.p[1]) - 'x'] = x;
        } else if (as_span_ieq(key, "XO") || as_span_ieq(key, "YO") || as_span_ieq(key, "ZO") ||
                   as_span_ieq(key, "RX") || as_span_ieq(key, "RY") || as_span_ieq(key, "RZ")) {
            if ((st = as_inr_number(ctx, path, key, val, &x))) goto done;
            if (x != 0) {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: field '%s' = %g is unsupported (only 0 is accepted: "
                             "rotations and pixel offsets are not implemented)",
                             path, as_span_show(key).s, x);
                goto done;
            }
        } else {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: unknown header field '%s'", path,
                         as_span_show(key).s);
            goto done;
        }
    }
    const char *missing = !has_x      ? "XDIM"
                          : !has_y    ? "YDIM"
                          : !has_type ? "TYPE"
                          : !has_pix  ? "PIXSIZE"
                                      : NULL;
    if (missing) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: missing required field '%s'", path, missing);
        goto done;
    }
    if (vdim != 1) {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: field 'VDIM' = %lld: vector images are unsupported (VDIM must be 1)",
                     path, (long long)vdim);
        goto done;
    }
    if (kind == 3) {
        if (bits != 32 && bits != 64) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'PIXSIZE': TYPE=float needs 32 or 64 bits, got %lld", path,
                         (long long)bits);
            goto done;
        }
        d.type = bits == 32 ? AS_VOXEL_F32 : AS_VOXEL_F64;
    } else {
        static const as_voxel_type u[4] = {AS_VOXEL_U8, AS_VOXEL_U16, AS_VOXEL_U32, AS_VOXEL_U64};
        static const as_voxel_type s[4] = {AS_VOXEL_I8, AS_VOXEL_I16, AS_VOXEL_I32, AS_VOXEL_I64};
        int k = bits == 8 ? 0 : bits == 16 ? 1 : bits == 32 ? 2 : 3;
        d.type = kind == 1 ? u[k] : s[k];
    }
    if (bits > 8 && !has_cpu) {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: missing field 'CPU' (the byte order of %lld-bit voxels)", path,
                     (long long)bits);
        goto done;
    }
    d.offset = hdr_end;
    d.byte_skip = 0;
    as_hr_close(&hr);
    return as_load_voxels(ctx, &d, out);
done:
    as_hr_close(&hr);
    return st;
}

/* ---- NRRD --------------------------------------------------------------------------- */

/* NRRD field names are compared without spaces and case ("data file" == "datafile"). */
static int as_nrrd_name_is(as_span name, const char *canon) {
    size_t j = 0;
    for (size_t i = 0; i < name.n; i++) {
        if (name.p[i] == ' ' || name.p[i] == '\t') continue;
        if (canon[j] == '\0' || as_lower(name.p[i]) != canon[j]) return 0;
        j++;
    }
    return canon[j] == '\0';
}

static int as_nrrd_type(as_span v, as_voxel_type *t) {
    static const struct {
        const char *name;
        as_voxel_type type;
    } names[] = {
        {"signed char", AS_VOXEL_I8},
        {"int8", AS_VOXEL_I8},
        {"int8_t", AS_VOXEL_I8},
        {"uchar", AS_VOXEL_U8},
        {"unsigned char", AS_VOXEL_U8},
        {"uint8", AS_VOXEL_U8},
        {"uint8_t", AS_VOXEL_U8},
        {"short", AS_VOXEL_I16},
        {"short int", AS_VOXEL_I16},
        {"signed short", AS_VOXEL_I16},
        {"signed short int", AS_VOXEL_I16},
        {"int16", AS_VOXEL_I16},
        {"int16_t", AS_VOXEL_I16},
        {"ushort", AS_VOXEL_U16},
        {"unsigned short", AS_VOXEL_U16},
        {"unsigned short int", AS_VOXEL_U16},
        {"uint16", AS_VOXEL_U16},
        {"uint16_t", AS_VOXEL_U16},
        {"int", AS_VOXEL_I32},
        {"signed int", AS_VOXEL_I32},
        {"int32", AS_VOXEL_I32},
        {"int32_t", AS_VOXEL_I32},
        {"uint", AS_VOXEL_U32},
        {"unsigned int", AS_VOXEL_U32},
        {"uint32", AS_VOXEL_U32},
        {"uint32_t", AS_VOXEL_U32},
        {"longlong", AS_VOXEL_I64},
        {"long long", AS_VOXEL_I64},
        {"long long int", AS_VOXEL_I64},
        {"signed long long", AS_VOXEL_I64},
        {"signed long long int", AS_VOXEL_I64},
        {"int64", AS_VOXEL_I64},
        {"int64_t", AS_VOXEL_I64},
        {"ulonglong", AS_VOXEL_U64},
        {"unsigned long long", AS_VOXEL_U64},
        {"unsigned long long int", AS_VOXEL_U64},
        {"uint64", AS_VOXEL_U64},
        {"uint64_t", AS_VOXEL_U64},
        {"float", AS_VOXEL_F32},
        {"double", AS_VOXEL_F64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (as_span_ieq(v, names[i].name)) {
            *t = names[i].type;
            return 0;
        }
    return -1;
}

/* 3-D space names of NRRD (the "-time" ones are 4-D). Returns the space dimension, or 0
 * when unknown. */
static int as_nrrd_space_dim(as_span v) {
    static const char *const three[] = {"right-anterior-superior",
                                        "RAS",
                                        "left-anterior-superior",
                                        "LAS",
                                        "left-posterior-superior",
                                        "LPS",
                                        "scanner-xyz",
                                        "3D-right-handed",
                                        "3D-left-handed"};
    static const char *const four[] = {"right-anterior-superior-time",
                                       "RAST",
                                       "left-anterior-superior-time",
                                       "LAST",
                                       "left-posterior-superior-time",
                                       "LPST",
                                       "scanner-xyz-time",
                                       "3D-right-handed-time",
                                       "3D-left-handed-time"};
    for (size_t i = 0; i < sizeof three / sizeof three[0]; i++)
        if (as_span_ieq(v, three[i])) return 3;
    for (size_t i = 0; i < sizeof four / sizeof four[0]; i++)
        if (as_span_ieq(v, four[i])) return 4;
    return 0;
}

/* Parse "(a,b,c)" (spaces allowed) at the start of *rest into v[0..3); 1 for "none",
 * 0 for a vector, -1 on a syntax error. */
static int as_nrrd_vector(as_span *rest, double v[3]) {
    *rest = as_span_trim(*rest);
    if (rest->n >= 4 && as_span_ieq((as_span){rest->p, 4}, "none") &&
        (rest->n == 4 || as_is_space(rest->p[4]))) {
        rest->p += 4;
        rest->n -= 4;
        return 1;
    }
    if (rest->n == 0 || rest->p[0] != '(') return -1;
    const char *close = memchr(rest->p, ')', rest->n);
    if (!close) return -1;
    as_span inner = {rest->p + 1, (size_t)(close - rest->p) - 1}, tok;
    for (int i = 0; i < 3; i++)
        if (!as_span_token(&inner, &tok, 1) || as_parse_f64(tok, &v[i], 0)) return -1;
    if (as_span_token(&inner, &tok, 1)) return -1;
    size_t used = (size_t)(close - rest->p) + 1;
    rest->p += used;
    rest->n -= used;
    return 0;
}

enum {
    AS_NRRD_DIMENSION,
    AS_NRRD_TYPE,
    AS_NRRD_SIZES,
    AS_NRRD_ENDIAN,
    AS_NRRD_ENCODING,
    AS_NRRD_SPACINGS,
    AS_NRRD_SPACE_DIRECTIONS,
    AS_NRRD_SPACE_ORIGIN,
    AS_NRRD_SPACE_DIMENSION,
    AS_NRRD_SPACE,
    AS_NRRD_BYTE_SKIP,
    AS_NRRD_LINE_SKIP,
    AS_NRRD_DATA_FILE,
    AS_NRRD_NFIELDS
};

#define AS_NRRD_MAXDIM 16

/*
 * The geometry of a NRRD header: the space, per-axis directions or spacings, which axes
 * are spatial (exactly 3; the others must have size 1), the origin. Fills d->dims,
 * d->spacing, d->dir, d->origin. Returns ANISTAR_OK or ANISTAR_EFORMAT.
 */
static anistar_status as_nrrd_geometry(anistar_context *ctx, const char *path, int nd,
                                       const int64_t *sizes, const as_span *val, const int *seen,
                                       as_data_desc *d) {
    as_span tok, rest;
    /* Space. */
    int sdim = 0;
    if (seen[AS_NRRD_SPACE] && seen[AS_NRRD_SPACE_DIMENSION]) {
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: fields 'space' and 'space dimension' exclude each other", path);
    }
    if (seen[AS_NRRD_SPACE]) {
        sdim = as_nrrd_space_dim(val[AS_NRRD_SPACE]);
        if (sdim == 0) {
            return as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'space': unknown space '%s'", path,
                           as_span_show(val[AS_NRRD_SPACE]).s);
        }
    } else if (seen[AS_NRRD_SPACE_DIMENSION]) {
        int64_t s;
        if (as_parse_i64(val[AS_NRRD_SPACE_DIMENSION], &s) || s < 1 || s > AS_NRRD_MAXDIM) {
            return as_fail(ctx, ANISTAR_EFORMAT,
                           "%s: field 'space dimension': '%s' is not a positive integer", path,
                           as_span_show(val[AS_NRRD_SPACE_DIMENSION]).s);
        }
        sdim = (int)s;
    }
    if (sdim != 0 && sdim != 3) {
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: field '%s': a %d-D space is unsupported (only 3-D spaces)", path,
                       seen[AS_NRRD_SPACE] ? "space" : "space dimension", sdim);
    }
    if (sdim == 0 && (seen[AS_NRRD_SPACE_DIRECTIONS] || seen[AS_NRRD_SPACE_ORIGIN])) {
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: field '%s' needs a 'space' or 'space dimension' field", path,
                       seen[AS_NRRD_SPACE_DIRECTIONS] ? "space directions" : "space origin");
    }
    if (seen[AS_NRRD_SPACE_DIRECTIONS] && seen[AS_NRRD_SPACINGS]) {
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: fields 'space directions' and 'spacings' exclude each other", path);
    }

    /* Per-axis geometry: spatial[i] = 0 for a non-spatial axis. */
    int spatial[AS_NRRD_MAXDIM];
    double axdir[AS_NRRD_MAXDIM][3], axsp[AS_NRRD_MAXDIM];
    for (int i = 0; i < nd; i++) {
        spatial[i] = 1;
        axsp[i] = 1;
        axdir[i][0] = axdir[i][1] = axdir[i][2] = NAN;
    }
    if (seen[AS_NRRD_SPACE_DIRECTIONS]) {
        rest = val[AS_NRRD_SPACE_DIRECTIONS];
        for (int i = 0; i < nd; i++) {
            double v[3];
            int r = as_nrrd_vector(&rest, v);
            if (r < 0) {
                return as_fail(ctx, ANISTAR_EFORMAT,
                               "%s: field 'space directions': '%s' is not %d entries '(x,y,z)' or "
                               "'none'",
                               path, as_span_show(val[AS_NRRD_SPACE_DIRECTIONS]).s, nd);
            }
            if (r == 1) {
                spatial[i] = 0;
                continue;
            }
            double len = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            if (!(len > 0) || !isfinite(len)) {
                return as_fail(ctx, ANISTAR_EFORMAT,
                               "%s: field 'space directions': axis %d has a zero or non-finite "
                               "direction",
                               path, i);
            }
            axsp[i] = len;
            for (int c = 0; c < 3; c++) axdir[i][c] = v[c] / len;
        }
        if (as_span_trim(rest).n) {
            return as_fail(ctx, ANISTAR_EFORMAT,
                           "%s: field 'space directions': more than %d entries", path, nd);
        }
    } else if (seen[AS_NRRD_SPACINGS]) {
        rest = val[AS_NRRD_SPACINGS];
        for (int i = 0; i < nd; i++) {
            double s;
            if (!as_span_token(&rest, &tok, 0) || as_parse_f64(tok, &s, 1) || isinf(s) ||
                (!isnan(s) && !(s > 0))) {
                return as_fail(ctx, ANISTAR_EFORMAT,
                               "%s: field 'spacings': '%s' is not %d positive numbers (or nan)",
                               path, as_span_show(val[AS_NRRD_SPACINGS]).s, nd);
            }
            if (isnan(s))
                spatial[i] = 0;
            else
                axsp[i] = s;
        }
        if (as_span_token(&rest, &tok, 0)) {
            return as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'spacings': more than %d values", path,
                           nd);
        }
    }
    int nsp = 0, ax[3] = {0, 0, 0};
    for (int i = 0; i < nd; i++) {
        if (spatial[i]) {
            if (nsp < 3) ax[nsp] = i;
            nsp++;
        } else if (sizes[i] != 1) {
            return as_fail(ctx, ANISTAR_EFORMAT,
                           "%s: axis %d is non-spatial with size %lld: multi-component voxels "
                           "are unsupported",
                           path, i, (long long)sizes[i]);
        }
    }
    if (nsp != 3) {
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: field 'dimension': %d with %d spatial axes is unsupported (3-D "
                       "images only, plus non-spatial axes of size 1)",
                       path, nd, nsp);
    }
    for (int c = 0; c < 3; c++) {
        d->dims[c] = sizes[ax[c]];
        d->spacing[c] = axsp[ax[c]];
        if (seen[AS_NRRD_SPACE_DIRECTIONS])
            for (int r = 0; r < 3; r++) d->dir[3 * r + c] = axdir[ax[c]][r];
    }
    if (seen[AS_NRRD_SPACE_ORIGIN]) {
        rest = val[AS_NRRD_SPACE_ORIGIN];
        if (as_nrrd_vector(&rest, d->origin) != 0 || as_span_trim(rest).n) {
            return as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'space origin': '%s' is not '(x,y,z)'",
                           path, as_span_show(val[AS_NRRD_SPACE_ORIGIN]).s);
        }
    }

    return ANISTAR_OK;
}

/*
 * Parse a NRRD header and load its voxels (fields: image_io.h).
 * design: first pass reads lines up to the blank line (or the end of a detached header);
 *   second pass collects each field's value (duplicates are errors, as in teem), then
 *   interprets them together: axes, spatial axes, geometry, encoding, data location.
 */
anistar_status as_image_read_nrrd(anistar_context *ctx, const char *path, as_image **out) {
    static const char *const canon[AS_NRRD_NFIELDS] = {
        "dimension",       "type",        "sizes",          "endian", "encoding", "spacings",
        "spacedirections", "spaceorigin", "spacedimension", "space",  "byteskip", "lineskip",
        "datafile"};
    static const char *const shown[AS_NRRD_NFIELDS] = {
        "dimension",        "type",         "sizes",           "endian", "encoding",  "spacings",
        "space directions", "space origin", "space dimension", "space",  "byte skip", "line skip",
        "data file"};
    static const char *const ignored[] = {
        "content",    "kinds",       "labels",      "units",
        "spaceunits", "thicknesses", "centers",     "centerings",
        "axismins",   "axismaxs",    "min",         "max",
        "oldmin",     "oldmax",      "sampleunits", "measurementframe",
        "number"};
    *out = NULL;
    as_hreader hr;
    anistar_status st = as_hr_open(ctx, path, &hr);
    if (st) return st;
    char *data_path = NULL;
    size_t data_path_size = 0;
    as_span line;
    int got, blank = 0;
    if ((st = as_hr_line(&hr, &line, &got))) goto done;
    if (!got || !as_span_starts(line, "NRRD")) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: not a NRRD file (no 'NRRD000N' magic)", path);
        goto done;
    }
    if (!(line.n == 8 && as_span_starts(line, "NRRD000") && line.p[7] >= '1' && line.p[7] <= '5')) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: unsupported NRRD version '%s'", path,
                     as_span_show(line).s);
        goto done;
    }
    size_t body = hr.pos;
    for (;;) {
        if ((st = as_hr_line(&hr, &line, &got))) goto done;
        if (!got) break;
        if (line.n == 0) {
            blank = 1;
            break;
        }
    }
    size_t hdr_end = hr.pos;

    as_span val[AS_NRRD_NFIELDS] = {{NULL, 0}};
    int seen[AS_NRRD_NFIELDS] = {0};
    size_t pos = body;
    while (as_lines_next(hr.buf, hdr_end, &pos, &line)) {
        if (line.n == 0) break;
        if (line.p[0] == '#') continue;
        const char *colon = memchr(line.p, ':', line.n);
        if (!colon) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: header line '%s' is neither a field, a key/value pair nor a "
                         "comment",
                         path, as_span_show(line).s);
            goto done;
        }
        size_t at = (size_t)(colon - line.p);
        if (at + 1 < line.n && colon[1] == '=') continue; /* key:=value */
        as_span name = as_span_trim((as_span){line.p, at});
        as_span v = as_span_trim((as_span){colon + 1, line.n - at - 1});
        int f = -1;
        for (int i = 0; i < AS_NRRD_NFIELDS && f < 0; i++)
            if (as_nrrd_name_is(name, canon[i])) f = i;
        if (f < 0) {
            int ign = 0;
            for (size_t i = 0; i < sizeof ignored / sizeof ignored[0] && !ign; i++)
                ign = as_nrrd_name_is(name, ignored[i]);
            if (ign) continue;
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: unknown NRRD field '%s'", path,
                         as_span_show(name).s);
            goto done;
        }
        if (seen[f]) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field '%s' appears twice", path, shown[f]);
            goto done;
        }
        seen[f] = 1;
        val[f] = v;
    }
    for (int f = AS_NRRD_DIMENSION; f <= AS_NRRD_ENCODING; f++) {
        if (f == AS_NRRD_ENDIAN) continue;
        if (!seen[f]) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: missing required field '%s'", path, shown[f]);
            goto done;
        }
    }

    as_data_desc d;
    as_desc_init(&d, path);
    as_span tok, rest;
    int64_t dim;
    if (as_parse_i64(val[AS_NRRD_DIMENSION], &dim) || dim < 1 || dim > AS_NRRD_MAXDIM) {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: field 'dimension': '%s' is not an integer in "
                     "1..%d",
                     path, as_span_show(val[AS_NRRD_DIMENSION]).s, AS_NRRD_MAXDIM);
        goto done;
    }
    int nd = (int)dim;
    if (as_nrrd_type(val[AS_NRRD_TYPE], &d.type)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'type': unsupported voxel type '%s'", path,
                     as_span_show(val[AS_NRRD_TYPE]).s);
        goto done;
    }
    int64_t sizes[AS_NRRD_MAXDIM];
    rest = val[AS_NRRD_SIZES];
    for (int i = 0; i < nd; i++) {
        if (!as_span_token(&rest, &tok, 0) || as_parse_i64(tok, &sizes[i]) || sizes[i] <= 0) {
            st =
                as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'sizes': '%s' is not %d positive integers",
                        path, as_span_show(val[AS_NRRD_SIZES]).s, nd);
            goto done;
        }
    }
    if (as_span_token(&rest, &tok, 0)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'sizes': more than %d sizes ('%s')", path, nd,
                     as_span_show(val[AS_NRRD_SIZES]).s);
        goto done;
    }

    if ((st = as_nrrd_geometry(ctx, path, nd, sizes, val, seen, &d))) goto done;

    /* Encoding and byte order. */
    as_span enc = val[AS_NRRD_ENCODING];
    if (as_span_ieq(enc, "raw")) {
        d.ascii = 0;
    } else if (as_span_ieq(enc, "ascii") || as_span_ieq(enc, "text") || as_span_ieq(enc, "txt")) {
        d.ascii = 1;
    } else if (as_span_ieq(enc, "gzip") || as_span_ieq(enc, "gz") || as_span_ieq(enc, "bzip2") ||
               as_span_ieq(enc, "bz2")) {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: field 'encoding': '%s' is unsupported (anistar reads no compressed "
                     "data: decompress the file, e.g. unu save -e raw)",
                     path, as_span_show(enc).s);
        goto done;
    } else {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: field 'encoding': '%s' is unsupported (raw, ascii, text or txt)", path,
                     as_span_show(enc).s);
        goto done;
    }
    if (seen[AS_NRRD_ENDIAN]) {
        if (as_span_ieq(val[AS_NRRD_ENDIAN], "little"))
            d.big_endian = 0;
        else if (as_span_ieq(val[AS_NRRD_ENDIAN], "big"))
            d.big_endian = 1;
        else {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'endian': '%s' is neither 'little' nor 'big'", path,
                         as_span_show(val[AS_NRRD_ENDIAN]).s);
            goto done;
        }
    } else if (!d.ascii && as_voxel_size(d.type) > 1) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: missing field 'endian' (needed for raw %s voxels)",
                     path, as_voxel_type_name(d.type));
        goto done;
    }

    /* Where the data is. */
    d.byte_skip = 0;
    if (seen[AS_NRRD_BYTE_SKIP]) {
        if (as_parse_i64(val[AS_NRRD_BYTE_SKIP], &d.byte_skip) || d.byte_skip < -1 ||
            (d.byte_skip == -1 && d.ascii)) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'byte skip': '%s' is not an integer >= 0 (or -1 with raw "
                         "encoding)",
                         path, as_span_show(val[AS_NRRD_BYTE_SKIP]).s);
            goto done;
        }
    }
    if (seen[AS_NRRD_LINE_SKIP]) {
        int64_t ls;
        if (as_parse_i64(val[AS_NRRD_LINE_SKIP], &ls) || ls < 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'line skip': '%s' is not an integer "
                         ">= 0",
                         path, as_span_show(val[AS_NRRD_LINE_SKIP]).s);
            goto done;
        }
        d.line_skip = (uint64_t)ls;
    }
    if (seen[AS_NRRD_DATA_FILE]) {
        as_span name = val[AS_NRRD_DATA_FILE];
        int has_space = 0;
        for (size_t i = 0; i < name.n; i++) has_space |= as_is_space(name.p[i]);
        if (name.n == 0 || as_span_starts(name, "LIST") || memchr(name.p, '%', name.n) ||
            has_space) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'data file': '%s' is unsupported (one file name only: "
                         "lists and formats of several files are not read)",
                         path, as_span_show(name).s);
            goto done;
        }
        if ((st = as_join_path(ctx, path, name, &data_path, &data_path_size))) goto done;
        d.data_path = data_path;
        d.offset = 0;
    } else {
        if (!blank) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: no data: the header has no 'data file' field and no blank line "
                         "after which data would follow",
                         path);
            goto done;
        }
        d.offset = hdr_end;
    }
    as_hr_close(&hr);
    st = as_load_voxels(ctx, &d, out);
    as_free(ctx, data_path, data_path_size);
    return st;
done:
    as_hr_close(&hr);
    as_free(ctx, data_path, data_path_size);
    return st;
}

/* ---- MetaImage ---------------------------------------------------------------------- */

enum {
    AS_MHA_OBJECT_TYPE,
    AS_MHA_NDIMS,
    AS_MHA_DIM_SIZE,
    AS_MHA_ELEMENT_TYPE,
    AS_MHA_ELEMENT_SPACING,
    AS_MHA_ELEMENT_SIZE,
    AS_MHA_OFFSET,
    AS_MHA_TRANSFORM,
    AS_MHA_BINARY_DATA,
    AS_MHA_MSB,
    AS_MHA_COMPRESSED,
    AS_MHA_HEADER_SIZE,
    AS_MHA_CHANNELS,
    AS_MHA_DATA_FILE,
    AS_MHA_NFIELDS
};

static int as_mha_field(as_span key) {
    static const struct {
        const char *name;
        int field;
    } keys[] = {
        {"ObjectType", AS_MHA_OBJECT_TYPE},
        {"NDims", AS_MHA_NDIMS},
        {"DimSize", AS_MHA_DIM_SIZE},
        {"ElementType", AS_MHA_ELEMENT_TYPE},
        {"ElementSpacing", AS_MHA_ELEMENT_SPACING},
        {"ElementSize", AS_MHA_ELEMENT_SIZE},
        {"Offset", AS_MHA_OFFSET},
        {"Position", AS_MHA_OFFSET},
        {"Origin", AS_MHA_OFFSET},
        {"TransformMatrix", AS_MHA_TRANSFORM},
        {"Rotation", AS_MHA_TRANSFORM},
        {"Orientation", AS_MHA_TRANSFORM},
        {"BinaryData", AS_MHA_BINARY_DATA},
        {"BinaryDataByteOrderMSB", AS_MHA_MSB},
        {"ElementByteOrderMSB", AS_MHA_MSB},
        {"CompressedData", AS_MHA_COMPRESSED},
        {"HeaderSize", AS_MHA_HEADER_SIZE},
        {"ElementNumberOfChannels", AS_MHA_CHANNELS},
        {"ElementDataFile", AS_MHA_DATA_FILE},
    };
    static const char *const ignored[] = {"Comment",
                                          "ObjectSubType",
                                          "Name",
                                          "ID",
                                          "ParentID",
                                          "Color",
                                          "TransformType",
                                          "CenterOfRotation",
                                          "AnatomicalOrientation",
                                          "ElementMin",
                                          "ElementMax",
                                          "Modality",
                                          "AcquisitionDate",
                                          "CompressedDataSize",
                                          "ElementNBits"};
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        if (as_span_ieq(key, keys[i].name)) return keys[i].field;
    for (size_t i = 0; i < sizeof ignored / sizeof ignored[0]; i++)
        if (as_span_ieq(key, ignored[i])) return AS_MHA_NFIELDS; /* accepted, ignored */
    return -1;
}

static int as_mha_type(as_span v, as_voxel_type *t) {
    static const struct {
        const char *name;
        as_voxel_type type;
    } names[] = {
        {"MET_CHAR", AS_VOXEL_I8},       {"MET_UCHAR", AS_VOXEL_U8},
        {"MET_SHORT", AS_VOXEL_I16},     {"MET_USHORT", AS_VOXEL_U16},
        {"MET_INT", AS_VOXEL_I32},       {"MET_UINT", AS_VOXEL_U32},
        {"MET_LONG", AS_VOXEL_I32},      {"MET_ULONG", AS_VOXEL_U32},
        {"MET_LONG_LONG", AS_VOXEL_I64}, {"MET_ULONG_LONG", AS_VOXEL_U64},
        {"MET_FLOAT", AS_VOXEL_F32},     {"MET_DOUBLE", AS_VOXEL_F64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++)
        if (as_span_ieq(v, names[i].name)) {
            *t = names[i].type;
            return 0;
        }
    return -1;
}

/* "True"/"False" (or 1/0): 1, 0, or -1. */
static int as_mha_bool(as_span v) {
    if (as_span_ieq(v, "True") || as_span_ieq(v, "1")) return 1;
    if (as_span_ieq(v, "False") || as_span_ieq(v, "0")) return 0;
    return -1;
}

/* Exactly n finite numbers. */
static int as_parse_numbers(as_span v, double *x, int n) {
    as_span tok;
    for (int i = 0; i < n; i++)
        if (!as_span_token(&v, &tok, 0) || as_parse_f64(tok, &x[i], 0)) return -1;
    return as_span_token(&v, &tok, 0) ? -1 : 0;
}

/*
 * Parse a MetaImage header and load its voxels (fields: image_io.h).
 * design: first pass reads lines up to the ElementDataFile line (LOCAL data starts right
 *   after it); second pass collects values (synonyms count as one field; duplicates are
 *   errors), then interprets them.
 */
anistar_status as_image_read_metaimage(anistar_context *ctx, const char *path, as_image **out) {
    static const char *const shown[AS_MHA_NFIELDS] = {"ObjectType",
                                                      "NDims",
                                                      "DimSize",
                                                      "ElementType",
                                                      "ElementSpacing",
                                                      "ElementSize",
                                                      "Offset",
                                                      "TransformMatrix",
                                                      "BinaryData",
                                                      "BinaryDataByteOrderMSB",
                                                      "CompressedData",
                                                      "HeaderSize",
                                                      "ElementNumberOfChannels",
                                                      "ElementDataFile"};
    *out = NULL;
    as_hreader hr;
    anistar_status st = as_hr_open(ctx, path, &hr);
    if (st) return st;
    char *data_path = NULL;
    size_t data_path_size = 0;
    as_span line;
    int got, found = 0;
    for (;;) {
        if ((st = as_hr_line(&hr, &line, &got))) goto done;
        if (!got) break;
        const char *eq = memchr(line.p, '=', line.n);
        if (eq && as_span_ieq(as_span_trim((as_span){line.p, (size_t)(eq - line.p)}),
                              "ElementDataFile")) {
            found = 1;
            break;
        }
    }
    if (!found) {
        st = as_fail(ctx, ANISTAR_EFORMAT,
                     "%s: not a MetaImage header (no 'ElementDataFile = ...' line)", path);
        goto done;
    }
    size_t hdr_end = hr.pos;

    as_span val[AS_MHA_NFIELDS] = {{NULL, 0}};
    int seen[AS_MHA_NFIELDS] = {0};
    size_t pos = 0;
    while (as_lines_next(hr.buf, hdr_end, &pos, &line)) {
        as_span t = as_span_trim(line);
        if (t.n == 0) continue;
        const char *eq = memchr(t.p, '=', t.n);
        if (!eq) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: header line '%s' is not 'Key = Value'", path,
                         as_span_show(t).s);
            goto done;
        }
        as_span key = as_span_trim((as_span){t.p, (size_t)(eq - t.p)});
        as_span v = as_span_trim((as_span){eq + 1, t.n - (size_t)(eq - t.p) - 1});
        int f = as_mha_field(key);
        if (f < 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: unknown MetaImage field '%s'", path,
                         as_span_show(key).s);
            goto done;
        }
        if (f == AS_MHA_NFIELDS) continue;
        if (seen[f] && f == AS_MHA_MSB) {
            /* BinaryDataByteOrderMSB and ElementByteOrderMSB may both appear: agree. */
            if (as_mha_bool(v) != as_mha_bool(val[f])) {
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: 'BinaryDataByteOrderMSB' and 'ElementByteOrderMSB' disagree",
                             path);
                goto done;
            }
            continue;
        }
        if (seen[f]) {
            /* Writers may repeat a field under a synonym (Offset / Position): accepted
             * when the text is the same, an error when it differs. */
            if (v.n == val[f].n && memcmp(v.p, val[f].p, v.n) == 0) continue;
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field '%s' (or a synonym) appears twice with different values", path,
                         shown[f]);
            goto done;
        }
        seen[f] = 1;
        val[f] = v;
    }

    as_data_desc d;
    as_desc_init(&d, path);
    as_span tok, rest;
    if (seen[AS_MHA_OBJECT_TYPE] && !as_span_ieq(val[AS_MHA_OBJECT_TYPE], "Image")) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'ObjectType': '%s' is not 'Image'", path,
                     as_span_show(val[AS_MHA_OBJECT_TYPE]).s);
        goto done;
    }
    static const int required[] = {AS_MHA_NDIMS, AS_MHA_DIM_SIZE, AS_MHA_ELEMENT_TYPE};
    for (size_t i = 0; i < 3; i++)
        if (!seen[required[i]]) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: missing required field '%s'", path,
                         shown[required[i]]);
            goto done;
        }
    int64_t ndims;
    if (as_parse_i64(val[AS_MHA_NDIMS], &ndims) || ndims != 3) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'NDims': '%s' is unsupported (3 only)", path,
                     as_span_show(val[AS_MHA_NDIMS]).s);
        goto done;
    }
    rest = val[AS_MHA_DIM_SIZE];
    for (int i = 0; i < 3; i++)
        if (!as_span_token(&rest, &tok, 0) || as_parse_i64(tok, &d.dims[i]) || d.dims[i] <= 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'DimSize': '%s' is not 3 positive integers", path,
                         as_span_show(val[AS_MHA_DIM_SIZE]).s);
            goto done;
        }
    if (as_span_token(&rest, &tok, 0)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'DimSize': more than 3 sizes", path);
        goto done;
    }
    if (as_mha_type(val[AS_MHA_ELEMENT_TYPE], &d.type)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'ElementType': unsupported type '%s'", path,
                     as_span_show(val[AS_MHA_ELEMENT_TYPE]).s);
        goto done;
    }
    int fsp = seen[AS_MHA_ELEMENT_SPACING] ? AS_MHA_ELEMENT_SPACING
              : seen[AS_MHA_ELEMENT_SIZE]  ? AS_MHA_ELEMENT_SIZE
                                           : -1;
    if (fsp >= 0 && as_parse_numbers(val[fsp], d.spacing, 3)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field '%s': '%s' is not 3 numbers", path,
                     shown[fsp], as_span_show(val[fsp]).s);
        goto done;
    }
    if (seen[AS_MHA_OFFSET] && as_parse_numbers(val[AS_MHA_OFFSET], d.origin, 3)) {
        st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'Offset': '%s' is not 3 numbers", path,
                     as_span_show(val[AS_MHA_OFFSET]).s);
        goto done;
    }
    if (seen[AS_MHA_TRANSFORM]) {
        double m[9];
        if (as_parse_numbers(val[AS_MHA_TRANSFORM], m, 9)) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'TransformMatrix': '%s' is not 9 numbers",
                         path, as_span_show(val[AS_MHA_TRANSFORM]).s);
            goto done;
        }
        /* Triple c is the direction of axis c, i.e. column c of D. */
        for (int c = 0; c < 3; c++)
            for (int r = 0; r < 3; r++) d.dir[3 * r + c] = m[3 * c + r];
    }
    if (seen[AS_MHA_CHANNELS]) {
        int64_t ch;
        if (as_parse_i64(val[AS_MHA_CHANNELS], &ch) || ch != 1) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'ElementNumberOfChannels': '%s' is unsupported (1 only)", path,
                         as_span_show(val[AS_MHA_CHANNELS]).s);
            goto done;
        }
    }
    if (seen[AS_MHA_COMPRESSED]) {
        int b = as_mha_bool(val[AS_MHA_COMPRESSED]);
        if (b != 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'CompressedData': '%s' is unsupported (anistar reads no "
                         "compressed data)",
                         path, as_span_show(val[AS_MHA_COMPRESSED]).s);
            goto done;
        }
    }
    if (seen[AS_MHA_BINARY_DATA]) {
        int b = as_mha_bool(val[AS_MHA_BINARY_DATA]);
        if (b < 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT, "%s: field 'BinaryData': '%s' is not True/False",
                         path, as_span_show(val[AS_MHA_BINARY_DATA]).s);
            goto done;
        }
        d.ascii = !b;
    }
    if (seen[AS_MHA_MSB]) {
        int b = as_mha_bool(val[AS_MHA_MSB]);
        if (b < 0) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'BinaryDataByteOrderMSB': '%s' is not True/False", path,
                         as_span_show(val[AS_MHA_MSB]).s);
            goto done;
        }
        d.big_endian = b;
    }
    d.byte_skip = 0;
    if (seen[AS_MHA_HEADER_SIZE]) {
        if (as_parse_i64(val[AS_MHA_HEADER_SIZE], &d.byte_skip) || d.byte_skip < -1 ||
            (d.byte_skip == -1 && d.ascii)) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'HeaderSize': '%s' is not an integer >= -1 (-1 only for "
                         "binary data)",
                         path, as_span_show(val[AS_MHA_HEADER_SIZE]).s);
            goto done;
        }
    }
    as_span name = val[AS_MHA_DATA_FILE];
    if (as_span_ieq(name, "LOCAL")) {
        d.offset = hdr_end;
    } else {
        int has_space = 0;
        for (size_t i = 0; i < name.n; i++) has_space |= as_is_space(name.p[i]);
        if (name.n == 0 || as_span_ieq(name, "LIST") || memchr(name.p, '%', name.n) || has_space) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: field 'ElementDataFile': '%s' is unsupported (LOCAL or one file "
                         "name: lists and patterns of several files are not read)",
                         path, as_span_show(name).s);
            goto done;
        }
        if ((st = as_join_path(ctx, path, name, &data_path, &data_path_size))) goto done;
        d.data_path = data_path;
        d.offset = 0;
    }
    as_hr_close(&hr);
    st = as_load_voxels(ctx, &d, out);
    as_free(ctx, data_path, data_path_size);
    return st;
done:
    as_hr_close(&hr);
    as_free(ctx, data_path, data_path_size);
    return st;
}

/* ---- raw and dispatch --------------------------------------------------------------- */

anistar_status as_image_read_raw(anistar_context *ctx, const char *path, int64_t nx, int64_t ny,
                                 int64_t nz, as_voxel_type type, int big_endian,
                                 const double spacing[3], const double origin[3],
                                 int64_t header_offset, as_image **out) {
    *out = NULL;
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "raw image: NULL path");
    if (nx <= 0 || ny <= 0 || nz <= 0)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "%s: raw image sizes must be positive, got "
                       "%lldx%lldx%lld",
                       path, (long long)nx, (long long)ny, (long long)nz);
    if (as_voxel_size(type) == 0)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: invalid voxel type %d", path, (int)type);
    if (header_offset < -1)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: header offset %lld must be >= -1", path,
                       (long long)header_offset);
    as_data_desc d;
    as_desc_init(&d, path);
    d.dims[0] = nx;
    d.dims[1] = ny;
    d.dims[2] = nz;
    d.type = type;
    d.big_endian = big_endian != 0;
    d.offset = 0;
    d.byte_skip = header_offset;
    for (int i = 0; i < 3; i++) {
        if (spacing) d.spacing[i] = spacing[i];
        if (origin) d.origin[i] = origin[i];
    }
    return as_load_voxels(ctx, &d, out);
}

anistar_status as_image_read(anistar_context *ctx, const char *path, as_image **out) {
    *out = NULL;
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "image: NULL path");
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    as_span ext = {dot ? dot + 1 : "", dot ? strlen(dot + 1) : 0};
    if (as_span_ieq(ext, "inr")) return as_image_read_inr(ctx, path, out);
    if (as_span_ieq(ext, "nrrd") || as_span_ieq(ext, "nhdr"))
        return as_image_read_nrrd(ctx, path, out);
    if (as_span_ieq(ext, "mha") || as_span_ieq(ext, "mhd"))
        return as_image_read_metaimage(ctx, path, out);
    if (as_span_ieq(ext, "gz") || as_span_ieq(ext, "bz2") || as_span_ieq(ext, "zip"))
        return as_fail(ctx, ANISTAR_EFORMAT,
                       "%s: compressed files are unsupported (decompress it first)", path);
    return as_fail(ctx, ANISTAR_EFORMAT,
                   "%s: unknown image extension '.%s' (expected .inr, .nrrd, .nhdr, .mha or "
                   ".mhd)",
                   path, as_span_show(ext).s);
}
