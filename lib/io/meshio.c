/*
 * meshio.c — the in-memory triangle mesh, dispatch of readers and writers by extension,
 * and the helpers every reader and writer of lib/io shares: whole-file reading, a
 * line-counting text cursor, locale-independent number parsing, welding of triangle
 * soup, and a write stream that remembers its first error (see meshio.h).
 */
#include "io/meshio.h"

#include <errno.h>
#include <sys/stat.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

/* ==================================================================================== */
/* Dispatch                                                                              */
/* ==================================================================================== */

as_mesh_format as_mesh_format_of(const char *path) {
    if (!path) return AS_FMT_UNKNOWN;
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    if (!dot || (slash && dot < slash)) return AS_FMT_UNKNOWN;
    const char *ext = dot + 1;
    size_t n = strlen(ext);
    static const struct {
        const char *ext;
        as_mesh_format fmt;
    } table[] = {{"off", AS_FMT_OFF}, {"obj", AS_FMT_OBJ},   {"ply", AS_FMT_PLY},
                 {"stl", AS_FMT_STL}, {"mesh", AS_FMT_MESH}, {"sol", AS_FMT_SOL},
                 {"vtk", AS_FMT_VTK}, {"vtu", AS_FMT_VTU},   {"meshb", AS_FMT_MESHB},
                 {"solb", AS_FMT_SOLB}};
    for (size_t i = 0; i < sizeof table / sizeof table[0]; i++)
        if (as_token_is(ext, n, table[i].ext)) return table[i].fmt;
    return AS_FMT_UNKNOWN;
}

static const char *ext_of(const char *path) {
    const char *dot = strrchr(path, '.');
    const char *slash = strrchr(path, '/');
    return (!dot || (slash && dot < slash)) ? "" : dot;
}

anistar_status as_mesh_parse(anistar_context *ctx, as_mesh_format fmt, const char *name,
                             const char *data, size_t size, as_trimesh *out) {
    switch (fmt) {
    case AS_FMT_OFF: return as_off_parse(ctx, name, data, size, out);
    case AS_FMT_OBJ: return as_obj_parse(ctx, name, data, size, out);
    case AS_FMT_PLY: return as_ply_parse(ctx, name, data, size, out);
    case AS_FMT_STL: return as_stl_parse(ctx, name, data, size, out);
    case AS_FMT_MESH: return as_medit_parse(ctx, name, data, size, out);
    case AS_FMT_MESHB: return as_meshb_parse(ctx, name, data, size, out);
    case AS_FMT_VTK: return as_vtk_parse(ctx, name, data, size, out);
    case AS_FMT_VTU: return as_vtu_parse(ctx, name, data, size, out);
    default:
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: cannot read a triangle mesh from %s%s%s "
                       "(expected .off .obj .ply .stl .mesh .meshb .vtk .vtu)", name,
                       *ext_of(name) ? "a '" : "a file without extension",
                       ext_of(name), *ext_of(name) ? "' file" : "");
    }
}

anistar_status as_mesh_read(anistar_context *ctx, const char *path, as_trimesh *out) {
    as_mesh_format fmt = as_mesh_format_of(path);
    if (fmt != AS_FMT_OFF && fmt != AS_FMT_OBJ && fmt != AS_FMT_PLY && fmt != AS_FMT_STL &&
        fmt != AS_FMT_MESH && fmt != AS_FMT_MESHB && fmt != AS_FMT_VTK && fmt != AS_FMT_VTU)
        return as_mesh_parse(ctx, fmt, path, "", 0, out); /* the message for the extension */
    char *data;
    size_t size;
    anistar_status st = as_file_read(ctx, path, &data, &size);
    if (st) return st;
    st = as_mesh_parse(ctx, fmt, path, data, size, out);
    as_file_free(ctx, data, size);
    return st;
}

anistar_status as_sol_read(anistar_context *ctx, const char *path, size_t *count,
                           double **tensor) {
    *count = 0;
    *tensor = NULL;
    char *data;
    size_t size;
    anistar_status st = as_file_read(ctx, path, &data, &size);
    if (st) return st;
    st = as_mesh_format_of(path) == AS_FMT_SOLB
             ? as_solb_parse(ctx, path, data, size, count, tensor)
             : as_sol_parse(ctx, path, data, size, count, tensor);
    as_file_free(ctx, data, size);
    return st;
}

anistar_status as_trimesh_read_sol(anistar_context *ctx, const char *path, as_trimesh *m) {
    size_t n;
    double *t;
    anistar_status st = as_sol_read(ctx, path, &n, &t);
    if (st) return st;
    if (n != m->nv) {
        as_free(ctx, t, n * 6 * sizeof(double));
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: %zu tensors for a mesh of %zu vertices",
                       path, n, m->nv);
    }
    as_free(ctx, m->tensor, m->cap_m * 6 * sizeof(double));
    m->tensor = t;
    m->cap_m = n;
    return ANISTAR_OK;
}

static int field_name_ok(const char *s) {
    if (!s || !*s) return 0;
    for (; *s; s++) {
        char c = *s;
        if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
              c == '_' || c == '.' || c == '-'))
            return 0;
    }
    return 1;
}

anistar_status as_mesh_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                             const as_cell_field *cells, size_t ncells) {
    as_mesh_format fmt = as_mesh_format_of(path);
    if (fmt == AS_FMT_UNKNOWN)
        return as_fail(ctx, ANISTAR_EFORMAT, "%s: unknown extension '%s' (expected .off .obj "
                       ".ply .stl .mesh .meshb .sol .solb .vtk .vtu)", path, ext_of(path));
    anistar_status st = as_trimesh_check(ctx, path, m);
    if (st) return st;
    if (fmt == AS_FMT_VTK || fmt == AS_FMT_VTU || fmt == AS_FMT_PLY) {
        if (ncells && !cells)
            return as_fail(ctx, ANISTAR_EINVAL, "%s: cell fields missing", path);
        for (size_t k = 0; k < ncells; k++) {
            if (!field_name_ok(cells[k].name))
                return as_fail(ctx, ANISTAR_EINVAL, "%s: cell field %zu: invalid name (use "
                               "letters, digits, '_', '.', '-')", path, k);
            if (strcmp(cells[k].name, "metric") == 0 && m->tensor)
                return as_fail(ctx, ANISTAR_EINVAL, "%s: cell field name 'metric' is taken",
                               path);
            if (fmt == AS_FMT_PLY && (strcmp(cells[k].name, "vertex_indices") == 0 ||
                                      strcmp(cells[k].name, "vertex_index") == 0))
                return as_fail(ctx, ANISTAR_EINVAL, "%s: cell field name '%s' is taken", path,
                               cells[k].name);
            for (size_t j = 0; j < k; j++)
                if (strcmp(cells[j].name, cells[k].name) == 0)
                    return as_fail(ctx, ANISTAR_EINVAL, "%s: two cell fields named '%s'", path,
                                   cells[k].name);
            if (m->nt && !cells[k].values)
                return as_fail(ctx, ANISTAR_EINVAL, "%s: cell field '%s' has no values", path,
                               cells[k].name);
            for (size_t t = 0; t < m->nt; t++)
                if (!isfinite(cells[k].values[t]))
                    return as_fail(ctx, ANISTAR_EINVAL, "%s: cell field '%s': triangle %zu "
                                   "has a non-finite value", path, cells[k].name, t);
        }
    }
    switch (fmt) {
    case AS_FMT_OFF: return as_off_write(ctx, path, m);
    case AS_FMT_OBJ: return as_obj_write(ctx, path, m);
    case AS_FMT_PLY: return as_ply_write(ctx, path, m, cells, ncells);
    case AS_FMT_STL: return as_stl_write(ctx, path, m);
    case AS_FMT_MESH: return as_medit_write(ctx, path, m);
    case AS_FMT_SOL: return as_sol_write(ctx, path, m);
    case AS_FMT_MESHB: return as_meshb_write(ctx, path, m, 0);
    case AS_FMT_SOLB: return as_solb_write(ctx, path, m, 0);
    case AS_FMT_VTK: return as_vtk_write(ctx, path, m, cells, ncells);
    case AS_FMT_VTU: return as_vtu_write(ctx, path, m, cells, ncells);
    default: return as_fail(ctx, ANISTAR_EINTERNAL, "%s: unhandled format", path);
    }
}

/* ==================================================================================== */
/* Whole-file reading                                                                    */
/* ==================================================================================== */

anistar_status as_file_read(anistar_context *ctx, const char *path, char **data,
                            size_t *size) {
    *data = NULL;
    *size = 0;
    errno = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return as_fail(ctx, ANISTAR_EIO, "cannot open '%s': %s", path,
                       errno ? strerror(errno) : "unknown error");
    const char *why = as_not_regular_file(f);
    if (why) {
        fclose(f);
        return as_fail(ctx, ANISTAR_EIO, "cannot read '%s': %s", path, why);
    }
    /* A size hint, when the file is seekable; the loop below does not trust it. */
    size_t cap = 0, n = 0;
    if (fseek(f, 0, SEEK_END) == 0) {
        long end = ftell(f);
        if (end > 0 && (unsigned long)end < SIZE_MAX / 2) cap = (size_t)end + 1;
    }
    rewind(f);
    char *buf = NULL;
    anistar_status st = ANISTAR_OK;
    if (cap) {
        buf = as_alloc(ctx, cap);
        if (!buf) cap = 0;
    }
    for (;;) {
        if (n + 1 >= cap) {
            /* Full (or nothing yet): probe for the end before growing, so that a file of
             * exactly the hinted size is read into one block of size + 1. */
            int c = EOF;
            if (cap) {
                errno = 0;
                c = fgetc(f);
                if (c == EOF) {
                    if (ferror(f))
                        st = as_fail(ctx, ANISTAR_EIO, "cannot read '%s': %s", path,
                                     errno ? strerror(errno) : "read error");
                    break;
                }
            }
            size_t ncap = cap < 4096 ? 4096 : (cap > SIZE_MAX / 2 ? SIZE_MAX : 2 * cap);
            char *q = as_realloc(ctx, buf, cap, ncap);
            if (!q) {
                st = as_fail(ctx, ANISTAR_ENOMEM, "out of memory reading '%s' (%zu bytes)",
                             path, ncap);
                break;
            }
            buf = q;
            cap = ncap;
            if (c != EOF) buf[n++] = (char)c;
        }
        size_t want = cap - 1 - n;
        errno = 0;
        size_t got = fread(buf + n, 1, want, f);
        n += got;
        if (got < want) { /* end of file or error */
            if (ferror(f))
                st = as_fail(ctx, ANISTAR_EIO, "cannot read '%s': %s", path,
                             errno ? strerror(errno) : "read error");
            break;
        }
    }
    fclose(f);
    if (st) {
        as_free(ctx, buf, cap);
        return st;
    }
    /* Shrink to size + 1 so that as_file_free knows the block's size. */
    if (cap != n + 1) {
        char *q = as_realloc(ctx, buf, cap, n + 1);
        if (!q) {
            as_free(ctx, buf, cap);
            return as_fail(ctx, ANISTAR_ENOMEM, "out of memory reading '%s'", path);
        }
        buf = q;
    }
    buf[n] = '\0';
    *data = buf;
    *size = n;
    return ANISTAR_OK;
}

void as_file_free(anistar_context *ctx, char *data, size_t size) { as_free(ctx, data, size + 1); }

/* ==================================================================================== */
/* Numbers                                                                               */
/* ==================================================================================== */

static inline int is_digit(char c) { return c >= '0' && c <= '9'; }
static inline char lower(char c) { return (c >= 'A' && c <= 'Z') ? (char)(c + 32) : c; }

/* Case-insensitive prefix test of s against the lowercase word w. */
static size_t match_word(const char *s, const char *w) {
    size_t i = 0;
    for (; w[i]; i++)
        if (lower(s[i]) != w[i]) return 0;
    return i;
}

/* Significant digits kept for strtod: correct rounding needs at most 768; the rest only
 * matter as a sticky nonzero digit. */
#define AS_MAX_DIGITS 780

size_t as_parse_double(const char *s, double *out) {
    const char *p = s;
    int neg = 0;
    if (*p == '+' || *p == '-') neg = *p++ == '-';
    size_t k;
    if ((k = match_word(p, "nan"))) {
        *out = NAN;
        return (size_t)(p - s) + k;
    }
    if ((k = match_word(p, "infinity")) || (k = match_word(p, "inf"))) {
        *out = neg ? -INFINITY : INFINITY;
        return (size_t)(p - s) + k;
    }
    char digits[AS_MAX_DIGITS + 2];
    int nd = 0, any = 0, sticky = 0;
    long long exp10 = 0;
    for (; is_digit(*p); p++) {
        any = 1;
        if (nd == 0 && *p == '0') continue;
        if (nd < AS_MAX_DIGITS)
            digits[nd++] = *p;
        else {
            sticky |= *p != '0';
            exp10++;
        }
    }
    if (*p == '.') {
        p++;
        for (; is_digit(*p); p++) {
            any = 1;
            if (nd == 0 && *p == '0') {
                exp10--;
                continue;
            }
            if (nd < AS_MAX_DIGITS) {
                digits[nd++] = *p;
                exp10--;
            } else
                sticky |= *p != '0';
        }
    }
    if (!any) return 0;
    if (*p == 'e' || *p == 'E') {
        const char *q = p + 1;
        int eneg = 0;
        if (*q == '+' || *q == '-') eneg = *q++ == '-';
        if (is_digit(*q)) {
            long long e = 0;
            for (; is_digit(*q); q++)
                if (e < 100000000) e = 10 * e + (*q - '0');
            exp10 += eneg ? -e : e;
            p = q;
        }
    }
    if (*p == '#') { /* MSVC: 1.#INF, -1.#IND, 1.#QNAN */
        while (*p == '#' || is_digit(*p) || (lower(*p) >= 'a' && lower(*p) <= 'z')) p++;
        *out = NAN;
        return (size_t)(p - s);
    }
    size_t used = (size_t)(p - s);
    double v = 0.0;
    int done = nd == 0;
    if (!done && nd <= 19 && !sticky && exp10 >= -22 && exp10 <= 22) {
        /* Clinger's fast path: an integer mantissa of at most 2^53 times or divided by an
         * exact power of ten is one correctly rounded operation. */
        static const double p10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                       1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                       1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
        uint64_t mant = 0;
        for (int i = 0; i < nd; i++) mant = 10 * mant + (uint64_t)(digits[i] - '0');
        if (mant <= (UINT64_C(1) << 53)) {
            v = exp10 >= 0 ? (double)mant * p10[exp10] : (double)mant / p10[-exp10];
            done = 1;
        }
    }
    if (!done) {
        /* digits, a sticky digit, 'e', the exponent: no decimal point, so the locale's
         * LC_NUMERIC cannot matter; glibc's strtod rounds correctly. */
        char buf[AS_MAX_DIGITS + 40];
        memcpy(buf, digits, (size_t)nd);
        int n = nd;
        if (sticky) {
            buf[n++] = '1';
            exp10--;
        }
        if (exp10 > 100000000) exp10 = 100000000;
        if (exp10 < -100000000) exp10 = -100000000;
        snprintf(buf + n, sizeof buf - (size_t)n, "e%lld", exp10);
        v = strtod(buf, NULL);
    }
    *out = neg ? -v : v;
    return used;
}

size_t as_parse_int(const char *s, int64_t *out, int *overflow) {
    const char *p = s;
    int neg = 0;
    *overflow = 0;
    if (*p == '+' || *p == '-') neg = *p++ == '-';
    if (!is_digit(*p)) return 0;
    uint64_t v = 0;
    for (; is_digit(*p); p++) {
        unsigned d = (unsigned)(*p - '0');
        if (v > (UINT64_MAX - d) / 10)
            *overflow = 1;
        else
            v = 10 * v + d;
    }
    uint64_t lim = neg ? (uint64_t)INT64_MAX + 1 : (uint64_t)INT64_MAX;
    if (v > lim) *overflow = 1;
    if (*overflow)
        *out = neg ? INT64_MIN : INT64_MAX;
    else
        *out = neg ? (int64_t)(0 - v) : (int64_t)v;
    return (size_t)(p - s);
}

/* ==================================================================================== */
/* Text cursor                                                                           */
/* ==================================================================================== */

static inline int is_blank(char c) {
    return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f';
}

void as_text_init(as_text *t, anistar_context *ctx, const char *name, const char *data,
                  size_t size, char comment) {
    t->ctx = ctx;
    t->name = name;
    t->p = data;
    t->end = data + size;
    t->line = 1;
    t->comment = comment;
    t->continuation = 0;
    if (size >= 3 && (unsigned char)data[0] == 0xEF && (unsigned char)data[1] == 0xBB &&
        (unsigned char)data[2] == 0xBF)
        t->p += 3;
}

void as_text_skip_blanks(as_text *t) {
    const char *p = t->p, *end = t->end;
    for (;;) {
        while (p < end && is_blank(*p)) p++;
        if (p < end && t->comment && *p == t->comment) {
            while (p < end && *p != '\n') p++;
            break;
        }
        if (t->continuation && p < end && *p == '\\') {
            const char *q = p + 1;
            while (q < end && *q == '\r') q++;
            if (q < end && *q == '\n') {
                p = q + 1;
                t->line++;
                continue;
            }
            if (q == end) { /* a backslash at the very end: nothing to continue */
                p = q;
                break;
            }
        }
        break;
    }
    t->p = p;
}

int as_text_skip_ws(as_text *t) {
    for (;;) {
        as_text_skip_blanks(t);
        if (t->p >= t->end) return 0;
        if (*t->p != '\n') return 1;
        t->p++;
        t->line++;
    }
}

int as_text_at_eol(as_text *t) {
    as_text_skip_blanks(t);
    return t->p >= t->end || *t->p == '\n';
}

void as_text_skip_line(as_text *t) {
    const char *p = t->p, *end = t->end;
    for (;;) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        if (!nl) {
            t->p = end;
            return;
        }
        t->line++;
        /* An OBJ statement continues past a newline escaped by a backslash. */
        if (t->continuation) {
            const char *q = nl;
            while (q > p && q[-1] == '\r') q--;
            if (q > p && q[-1] == '\\') {
                p = nl + 1;
                continue;
            }
        }
        t->p = nl + 1;
        return;
    }
}

size_t as_text_token(as_text *t, const char **tok) {
    as_text_skip_blanks(t);
    const char *p = t->p, *end = t->end;
    *tok = p;
    while (p < end && !is_blank(*p) && *p != '\n') {
        if (t->comment && *p == t->comment) break;
        p++;
    }
    t->p = p;
    return (size_t)(p - *tok);
}

int as_token_is(const char *tok, size_t len, const char *word) {
    size_t i = 0;
    for (; i < len; i++)
        if (!word[i] || lower(tok[i]) != lower(word[i])) return 0;
    return word[i] == '\0';
}

const char *as_token_show(const char *tok, size_t len, char buf[32]) {
    size_t n = len > 24 ? 24 : len, k = 0;
    for (size_t i = 0; i < n; i++) {
        unsigned char c = (unsigned char)tok[i];
        buf[k++] = (c >= 0x20 && c < 0x7f) ? (char)c : '?';
    }
    if (len > n) buf[k++] = '.', buf[k++] = '.', buf[k++] = '.';
    buf[k] = '\0';
    return buf;
}

anistar_status as_text_fail(as_text *t, const char *fmt, ...) {
    char msg[AS_ERRMSG_SIZE];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return as_fail(t->ctx, ANISTAR_EFORMAT, "%s:%zu: %s", t->name, t->line, msg);
}

anistar_status as_io_fail(anistar_context *ctx, const char *name, const char *fmt, ...) {
    char msg[AS_ERRMSG_SIZE];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    return as_fail(ctx, ANISTAR_EFORMAT, "%s: %s", name, msg);
}

/* The end of a number token: blank, newline, comment or end of data. */
static inline int at_delim(const as_text *t, const char *p) {
    return p >= t->end || is_blank(*p) || *p == '\n' || (t->comment && *p == t->comment);
}

static anistar_status found_fail(as_text *t, const char *what) {
    const char *tok;
    size_t len = as_text_token(t, &tok);
    if (len == 0)
        return as_text_fail(t, "expected %s, found %s", what,
                            t->p >= t->end ? "the end of the file" : "the end of the line");
    char buf[32];
    return as_text_fail(t, "expected %s, found '%s'", what, as_token_show(tok, len, buf));
}

anistar_status as_text_double(as_text *t, int cross_lines, const char *what, double *out) {
    if (cross_lines)
        as_text_skip_ws(t);
    else
        as_text_skip_blanks(t);
    size_t n = t->p < t->end ? as_parse_double(t->p, out) : 0;
    if (n == 0 || !at_delim(t, t->p + n)) return found_fail(t, what);
    if (!isfinite(*out)) {
        char buf[32];
        return as_text_fail(t, "%s is not a finite number: '%s'", what,
                            as_token_show(t->p, n, buf));
    }
    t->p += n;
    return ANISTAR_OK;
}

anistar_status as_text_int(as_text *t, int cross_lines, const char *what, int64_t *out) {
    if (cross_lines)
        as_text_skip_ws(t);
    else
        as_text_skip_blanks(t);
    int ovf;
    size_t n = t->p < t->end ? as_parse_int(t->p, out, &ovf) : 0;
    if (n == 0 || !at_delim(t, t->p + n)) return found_fail(t, what);
    if (ovf) {
        char buf[32];
        return as_text_fail(t, "%s out of range: '%s'", what, as_token_show(t->p, n, buf));
    }
    t->p += n;
    return ANISTAR_OK;
}

/* ==================================================================================== */
/* Welding                                                                               */
/* ==================================================================================== */

static inline uint64_t dbits(double x) {
    x += 0.0; /* -0 becomes +0 (round to nearest) */
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    return u;
}

static inline uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

static inline uint64_t hash3(const double *p) {
    return mix64(dbits(p[0]) ^ mix64(dbits(p[1]) ^ mix64(dbits(p[2]))));
}

/* Rebuild the table (cap slots) from the vertices so far. */
static void weld_rehash(int32_t *table, size_t cap, const as_trimesh *m) {
    for (size_t i = 0; i < cap; i++) table[i] = -1;
    for (size_t v = 0; v < m->nv; v++) {
        size_t slot = (size_t)hash3(m->xyz + 3 * v) & (cap - 1);
        while (table[slot] >= 0) slot = (slot + 1) & (cap - 1);
        table[slot] = (int32_t)v;
    }
}

/*
 * design: open addressing (linear probing) on a hash of the coordinates' bits, the table
 *   kept at most half full and sized for the usual V ~ T/2 of closed meshes, doubled and
 *   rebuilt when the vertices outgrow it (a small table stays in cache).
 */
anistar_status as_weld_soup(anistar_context *ctx, const char *name, const double *corners,
                            size_t nt, as_trimesh *out) {
    size_t nc;
    if (as_mul_size(nt, 3, &nc) || nc > SIZE_MAX / 8)
        return as_fail(ctx, ANISTAR_ENOMEM, "%s: too many triangles (%zu)", name, nt);
    size_t guess = nt / 2 + 16; /* closed meshes: V ~ T / 2 */
    if (guess > AS_TRIMESH_MAX_VERTICES) guess = AS_TRIMESH_MAX_VERTICES;
    size_t cap = 64;
    while (cap < 2 * guess) cap *= 2;
    int32_t *table = as_alloc_array(ctx, cap, sizeof *table);
    if (!table)
        return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory welding %zu triangles", name, nt);
    for (size_t i = 0; i < cap; i++) table[i] = -1;
    anistar_status st = as_trimesh_reserve(ctx, out, guess, nt);
    int32_t id[3] = {0, 0, 0};
    for (size_t c = 0; c < nc && !st; c++) {
        const double *p = corners + 3 * c;
        size_t slot = (size_t)hash3(p) & (cap - 1);
        for (;;) {
            int32_t v = table[slot];
            if (v < 0) {
                v = (int32_t)out->nv;
                st = as_trimesh_add_vertex(ctx, out, p[0] + 0.0, p[1] + 0.0, p[2] + 0.0);
                if (st) break;
                table[slot] = v;
                id[c % 3] = v;
                if (2 * out->nv > cap) {
                    int32_t *bigger = as_alloc_array(ctx, 2 * cap, sizeof *table);
                    if (!bigger) {
                        st = as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory welding %zu "
                                     "triangles", name, nt);
                        break;
                    }
                    as_free(ctx, table, cap * sizeof *table);
                    table = bigger;
                    cap *= 2;
                    weld_rehash(table, cap, out);
                }
                break;
            }
            const double *q = out->xyz + 3 * (size_t)v;
            if (q[0] == p[0] && q[1] == p[1] && q[2] == p[2]) {
                id[c % 3] = v;
                break;
            }
            slot = (slot + 1) & (cap - 1);
        }
        if (!st && c % 3 == 2) st = as_trimesh_add_triangle(ctx, out, id[0], id[1], id[2]);
    }
    as_free(ctx, table, cap * sizeof *table);
    if (st) {
        as_trimesh_free(ctx, out);
        if (st == ANISTAR_EINVAL) st = as_io_fail(ctx, name, "too many distinct vertices");
    }
    return st;
}

/* ==================================================================================== */
/* Writing                                                                               */
/* ==================================================================================== */

static void wfile_error(as_wfile *w) {
    if (!w->err) w->err = errno ? errno : -1;
}

anistar_status as_wfile_open(anistar_context *ctx, as_wfile *w, const char *path) {
    w->ctx = ctx;
    w->path = path;
    w->err = 0;
    /* The decimal point printf will use (LC_NUMERIC is the program's business). */
    const struct lconv *lc = localeconv();
    const char *dp = (lc && lc->decimal_point && *lc->decimal_point) ? lc->decimal_point : ".";
    size_t n = strlen(dp);
    if (n >= sizeof w->dp) n = sizeof w->dp - 1;
    memcpy(w->dp, dp, n);
    w->dp[n] = '\0';
    /* Remember whether we create the file: only then may a failure remove it (the path
     * may name a device such as /dev/full, or a file or link the caller cares about). */
    struct stat sb;
    w->created = lstat(path, &sb) != 0 && errno == ENOENT;
    errno = 0;
    w->f = fopen(path, "wb");
    if (!w->f)
        return as_fail(ctx, ANISTAR_EIO, "cannot create '%s': %s", path,
                       errno ? strerror(errno) : "unknown error");
    return ANISTAR_OK;
}

void as_wfile_write(as_wfile *w, const void *p, size_t n) {
    if (w->err || n == 0) return;
    errno = 0;
    if (fwrite(p, 1, n, w->f) != n) wfile_error(w);
}

void as_wfile_puts(as_wfile *w, const char *s) { as_wfile_write(w, s, strlen(s)); }

void as_wfile_printf(as_wfile *w, const char *fmt, ...) {
    if (w->err) return;
    char buf[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (n < 0 || (size_t)n >= sizeof buf) {
        w->err = EINVAL; /* a bug: our lines are short */
        return;
    }
    as_wfile_write(w, buf, (size_t)n);
}

void as_wfile_double(as_wfile *w, double x, char sep) {
    if (w->err) return;
    char buf[48];
    int n = snprintf(buf, sizeof buf - 1, "%.17g", x);
    if (n < 0 || n >= (int)sizeof buf - 8) {
        w->err = EINVAL;
        return;
    }
    if (!(w->dp[0] == '.' && w->dp[1] == '\0')) {
        /* Replace the locale's decimal point (possibly several bytes) by '.'. */
        char *d = strstr(buf, w->dp);
        if (d) {
            size_t dl = strlen(w->dp);
            *d = '.';
            memmove(d + 1, d + dl, strlen(d + dl) + 1);
            n -= (int)dl - 1;
        }
    }
    if (sep) buf[n++] = sep;
    as_wfile_write(w, buf, (size_t)n);
}

const char *as_not_regular_file(FILE *f) {
    struct stat sb;
    if (fstat(fileno(f), &sb) != 0) return "cannot stat it";
    if (S_ISREG(sb.st_mode)) return NULL;
    if (S_ISDIR(sb.st_mode)) return strerror(EISDIR);
    return "not a regular file (a device, pipe or socket)";
}

void as_wfile_abort(as_wfile *w) {
    if (w->f) fclose(w->f);
    w->f = NULL;
    if (w->created) remove(w->path);
}

anistar_status as_wfile_close(as_wfile *w) {
    if (!w->f) return as_fail(w->ctx, ANISTAR_EIO, "cannot write '%s'", w->path);
    errno = 0;
    if (!w->err && ferror(w->f)) wfile_error(w);
    errno = 0;
    if (fclose(w->f) != 0) wfile_error(w);
    w->f = NULL;
    if (w->err) {
        int e = w->err;
        if (w->created) remove(w->path);
        return as_fail(w->ctx, ANISTAR_EIO, "cannot write '%s': %s", w->path,
                       e > 0 ? strerror(e) : "write error");
    }
    return ANISTAR_OK;
}
