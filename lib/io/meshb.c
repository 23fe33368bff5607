/*
 * meshb.c — GMF binary files (libMeshb's .meshb and .solb, which MMG reads and writes):
 * readers and writers. Layout (from libMeshb's documentation and format tables):
 *
 *   int32 code word 1: the file's byte order (16777216 when read in the other order);
 *   int32 version: 1 float32 reals, int32 integers, int32 keyword positions;
 *                  2 float64 reals; 3 also int64 positions; 4 also int64 integers;
 *   keywords: int32 code, the file position of the next keyword (0 after the last),
 *     for keywords with lines their count (an integer), for solution keywords an int32
 *     number of fields and one int32 type per field, then the lines.
 *   Dimension (3): one int32 (3 here). Vertices (4): x y z reals, a reference integer.
 *   Triangles (6): three 1-based integers and a reference; Quadrilaterals (7) four.
 *   SolAtVertices (62): per line the fields' reals: 1 scalar, 3 vector, 6 symmetric
 *   tensor (m11 m12 m22 m13 m23 m33, the ASCII .sol's order), 9 matrix. End (54).
 *
 * The reader follows the keyword positions to skip keywords it does not use (each must
 * move forward and stay inside the file, so no file can loop), checks every count against
 * the bytes left before allocating, and accepts either byte order. The writers write
 * little endian.
 */
#include "io/meshio.h"

#include <float.h>
#include <math.h>
#include <string.h>

enum {
    GMF_DIMENSION = 3,
    GMF_VERTICES = 4,
    GMF_TRIANGLES = 6,
    GMF_QUADRILATERALS = 7,
    GMF_END = 54,
    GMF_SOL_AT_VERTICES = 62
};

typedef struct gmf {
    anistar_context *ctx;
    const char *name;
    const unsigned char *d;
    uint64_t size, pos;
    int big;                /* the file is big endian */
    int version, isz, rsz, psz;
} gmf;

static anistar_status gmf_short(gmf *g, const char *what) {
    return as_io_fail(g->ctx, g->name, "truncated: %s needs bytes beyond the end of the file "
                      "(%llu bytes)", what, (unsigned long long)g->size);
}

static uint64_t gmf_u(gmf *g, int n) {
    uint64_t v = as_ld_uint(g->d + g->pos, n, g->big);
    g->pos += (uint64_t)n;
    return v;
}

/* A signed integer of n bytes. */
static int64_t gmf_i(gmf *g, int n) {
    uint64_t u = gmf_u(g, n);
    if (n == 4) return (int32_t)(uint32_t)u;
    return (int64_t)u;
}

static double gmf_r(gmf *g) {
    uint64_t u = gmf_u(g, g->rsz);
    if (g->rsz == 4) {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        return f;
    }
    double x;
    memcpy(&x, &u, sizeof x);
    return x;
}

/* The header: code word, version, sizes. */
static anistar_status gmf_open(gmf *g, anistar_context *ctx, const char *name, const char *data,
                               size_t size) {
    memset(g, 0, sizeof *g);
    g->ctx = ctx;
    g->name = name;
    g->d = (const unsigned char *)data;
    g->size = size;
    if (size < 8) return as_io_fail(ctx, name, "not a GMF binary file (%zu bytes)", size);
    if (as_ld_uint(g->d, 4, 0) == 1)
        g->big = 0;
    else if (as_ld_uint(g->d, 4, 1) == 1)
        g->big = 1;
    else
        return as_io_fail(ctx, name, "not a GMF binary file (the code word is not 1 in either "
                          "byte order)");
    g->pos = 4;
    int64_t v = gmf_i(g, 4);
    if (v < 1 || v > 4)
        return as_io_fail(ctx, name, "unsupported GMF version %lld (1 to 4)", (long long)v);
    g->version = (int)v;
    g->rsz = v == 1 ? 4 : 8;
    g->psz = v >= 3 ? 8 : 4;
    g->isz = v == 4 ? 8 : 4;
    return ANISTAR_OK;
}

/* A line count at g->pos, checked against the bytes left for lines of rec bytes. */
static anistar_status gmf_count(gmf *g, const char *kw, uint64_t rec, uint64_t *n) {
    if (g->size - g->pos < (uint64_t)g->isz) return gmf_short(g, kw);
    int64_t c = gmf_i(g, g->isz);
    if (c < 0) return as_io_fail(g->ctx, g->name, "%s: negative count %lld", kw, (long long)c);
    if (!as_fits((uint64_t)c, rec, g->size - g->pos))
        return as_io_fail(g->ctx, g->name, "%s: %lld lines of %llu bytes exceed the %llu bytes "
                          "left", kw, (long long)c, (unsigned long long)rec,
                          (unsigned long long)(g->size - g->pos));
    *n = (uint64_t)c;
    return ANISTAR_OK;
}

/*
 * Walk the keywords. For each keyword of the wanted set, fn reads its data from g->pos
 * (after the code and the position). Others are skipped through their position.
 * design: a keyword's position must lie after the keyword itself and inside the file
 *   (so the walk always moves forward); a known keyword's data must end at or before
 *   it; position 0 ends the walk after that keyword, as End does.
 */
typedef anistar_status (*gmf_kw_fn)(gmf *g, int64_t code, void *user, int *used);

static anistar_status gmf_walk(gmf *g, gmf_kw_fn fn, void *user) {
    int dim = 0;
    while (g->pos < g->size) {
        uint64_t start = g->pos;
        if (g->size - g->pos < 4 + (uint64_t)g->psz) return gmf_short(g, "a keyword header");
        int64_t code = gmf_i(g, 4);
        uint64_t next = gmf_u(g, g->psz);
        if (g->psz == 4 && next > INT32_MAX)
            return as_io_fail(g->ctx, g->name, "keyword %lld at byte %llu: negative position",
                              (long long)code, (unsigned long long)start);
        if (code == GMF_END) return dim ? ANISTAR_OK
                                        : as_io_fail(g->ctx, g->name, "no Dimension keyword");
        if (next != 0 && (next <= start || next > g->size))
            return as_io_fail(g->ctx, g->name, "keyword %lld at byte %llu: next position %llu "
                              "outside (%llu, %llu]", (long long)code,
                              (unsigned long long)start, (unsigned long long)next,
                              (unsigned long long)start, (unsigned long long)g->size);
        int used = 0;
        if (code == GMF_DIMENSION) {
            if (g->size - g->pos < 4) return gmf_short(g, "Dimension");
            int64_t d = gmf_i(g, 4);
            if (d != 3)
                return as_io_fail(g->ctx, g->name, "Dimension %lld is not supported (only 3)",
                                  (long long)d);
            dim = 1;
            used = 1;
        } else if (code == GMF_VERTICES || code == GMF_TRIANGLES ||
                   code == GMF_QUADRILATERALS || code == GMF_SOL_AT_VERTICES) {
            if (!dim)
                return as_io_fail(g->ctx, g->name, "keyword %lld before Dimension",
                                  (long long)code);
            anistar_status st = fn(g, code, user, &used);
            if (st) return st;
        }
        if (used && next != 0 && g->pos > next)
            return as_io_fail(g->ctx, g->name, "keyword %lld at byte %llu: its data runs past "
                              "the next keyword's position %llu", (long long)code,
                              (unsigned long long)start, (unsigned long long)next);
        if (next == 0) break; /* the last keyword */
        g->pos = next;
    }
    return dim ? ANISTAR_OK : as_io_fail(g->ctx, g->name, "no Dimension keyword");
}

/* ---- .meshb ------------------------------------------------------------------------------ */

typedef struct meshb_state {
    as_trimesh *out;
    int seen_vertices;
} meshb_state;

static anistar_status meshb_kw(gmf *g, int64_t code, void *user, int *used) {
    meshb_state *s = user;
    as_trimesh *out = s->out;
    anistar_status st;
    uint64_t n;
    *used = 1;
    if (code == GMF_VERTICES) {
        if (s->seen_vertices) return as_io_fail(g->ctx, g->name, "a second Vertices keyword");
        s->seen_vertices = 1;
        if ((st = gmf_count(g, "Vertices", 3 * (uint64_t)g->rsz + (uint64_t)g->isz, &n)))
            return st;
        if (n > AS_TRIMESH_MAX_VERTICES)
            return as_io_fail(g->ctx, g->name, "too many vertices (%llu)", (unsigned long long)n);
        if ((st = as_trimesh_reserve(g->ctx, out, (size_t)n, out->nt))) return st;
        for (uint64_t i = 0; i < n; i++) {
            double *p = out->xyz + 3 * i;
            for (int k = 0; k < 3; k++) p[k] = gmf_r(g);
            g->pos += (uint64_t)g->isz; /* the reference */
            if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
                return as_io_fail(g->ctx, g->name, "vertex %llu: a coordinate is not finite",
                                  (unsigned long long)i + 1);
        }
        out->nv = (size_t)n;
        return ANISTAR_OK;
    }
    if (code == GMF_TRIANGLES || code == GMF_QUADRILATERALS) {
        int nc = code == GMF_TRIANGLES ? 3 : 4;
        const char *kw = nc == 3 ? "Triangles" : "Quadrilaterals";
        if ((st = gmf_count(g, kw, (uint64_t)(nc + 1) * (uint64_t)g->isz, &n))) return st;
        if ((st = as_trimesh_reserve(g->ctx, out, out->cap_v, out->nt + (size_t)n * (size_t)(nc - 2))))
            return st;
        for (uint64_t i = 0; i < n; i++) {
            int32_t v[4];
            for (int k = 0; k < nc; k++) {
                int64_t x = gmf_i(g, g->isz);
                if (x < 1 || (uint64_t)x > AS_TRIMESH_MAX_VERTICES)
                    return as_io_fail(g->ctx, g->name, "%s %llu: vertex index %lld out of range "
                                      "(indices start at 1)", kw, (unsigned long long)i + 1,
                                      (long long)x);
                v[k] = (int32_t)(x - 1);
            }
            g->pos += (uint64_t)g->isz; /* the reference */
            if ((st = as_trimesh_add_triangle(g->ctx, out, v[0], v[1], v[2]))) return st;
            if (nc == 4 && (st = as_trimesh_add_triangle(g->ctx, out, v[0], v[2], v[3])))
                return st;
        }
        return ANISTAR_OK;
    }
    *used = 0; /* SolAtVertices in a mesh file: skipped */
    return ANISTAR_OK;
}

anistar_status as_meshb_parse(anistar_context *ctx, const char *name, const char *data,
                              size_t size, as_trimesh *out) {
    gmf g;
    anistar_status st = gmf_open(&g, ctx, name, data, size);
    meshb_state s = {out, 0};
    if (!st) st = gmf_walk(&g, meshb_kw, &s);
    if (!st && (out->nv == 0 || out->nt == 0))
        st = as_io_fail(ctx, name, "no triangles (%zu vertices, %zu triangles)", out->nv, out->nt);
    for (size_t i = 0; !st && i < 3 * out->nt; i++)
        if ((size_t)out->tri[i] >= out->nv)
            st = as_io_fail(ctx, name, "triangle %zu: vertex index %ld out of range [1, %zu]",
                            i / 3 + 1, (long)out->tri[i] + 1, out->nv);
    if (st) as_trimesh_free(ctx, out);
    return st;
}

/* ---- .solb ------------------------------------------------------------------------------- */

typedef struct solb_state {
    double *m;
    size_t n;
} solb_state;

static anistar_status solb_kw(gmf *g, int64_t code, void *user, int *used) {
    solb_state *s = user;
    *used = 0;
    if (code != GMF_SOL_AT_VERTICES) return ANISTAR_OK;
    *used = 1;
    if (s->m) return as_io_fail(g->ctx, g->name, "a second SolAtVertices keyword");
    /* count, then the field types, then the lines (the count is checked after the
     * types, when the line size is known) */
    if (g->size - g->pos < (uint64_t)g->isz + 4) return gmf_short(g, "SolAtVertices");
    int64_t n = gmf_i(g, g->isz), nf = gmf_i(g, 4);
    if (n < 1 || (uint64_t)n > AS_TRIMESH_MAX_VERTICES || nf < 1 || nf > 64)
        return as_io_fail(g->ctx, g->name, "SolAtVertices: unsupported counts (%lld vertices, "
                          "%lld fields)", (long long)n, (long long)nf);
    if (g->size - g->pos < 4 * (uint64_t)nf) return gmf_short(g, "SolAtVertices' types");
    int64_t types[64];
    for (int64_t f = 0; f < nf; f++) types[f] = gmf_i(g, 4);
    int width, off, type;
    int pk = as_sol_pick(types, (size_t)nf, &width, &off, &type);
    if (pk == -1)
        return as_io_fail(g->ctx, g->name, "SolAtVertices: unknown solution type (1 scalar, 2 "
                          "vector, 3 symmetric tensor, 4 matrix)");
    if (pk == -2)
        return as_io_fail(g->ctx, g->name, "SolAtVertices: no scalar or tensor field (vectors "
                          "cannot be metrics)");
    if (!as_fits((uint64_t)n, (uint64_t)width * (uint64_t)g->rsz, g->size - g->pos))
        return as_io_fail(g->ctx, g->name, "SolAtVertices: %lld lines exceed the %llu bytes left",
                          (long long)n, (unsigned long long)(g->size - g->pos));
    s->m = as_alloc_array(g->ctx, (size_t)n, 6 * sizeof(double));
    if (!s->m)
        return as_fail(g->ctx, ANISTAR_ENOMEM, "%s: out of memory for %lld tensors", g->name,
                       (long long)n);
    s->n = (size_t)n;
    int nk = type == 3 ? 6 : 1;
    for (size_t i = 0; i < s->n; i++) {
        double v[6] = {0, 0, 0, 0, 0, 0};
        for (int k = 0; k < width; k++) {
            double x = gmf_r(g);
            if (k >= off && k < off + nk) {
                if (!isfinite(x))
                    return as_io_fail(g->ctx, g->name, "vertex %zu: a solution value is not "
                                      "finite", i + 1);
                v[k - off] = x;
            }
        }
        if (as_sol_tensor(type, v, s->m + 6 * i))
            return as_io_fail(g->ctx, g->name, "vertex %zu: size %g is not positive (or its "
                              "metric h^-2 overflows)", i + 1, v[0]);
    }
    return ANISTAR_OK;
}

anistar_status as_solb_parse(anistar_context *ctx, const char *name, const char *data,
                             size_t size, size_t *count, double **tensor) {
    *count = 0;
    *tensor = NULL;
    gmf g;
    solb_state s = {NULL, 0};
    anistar_status st = gmf_open(&g, ctx, name, data, size);
    if (!st) st = gmf_walk(&g, solb_kw, &s);
    if (!st && !s.m) st = as_io_fail(ctx, name, "no SolAtVertices keyword");
    if (st) {
        as_free(ctx, s.m, s.n * 6 * sizeof(double));
        return st;
    }
    *count = s.n;
    *tensor = s.m;
    return ANISTAR_OK;
}

/* ---- writers ----------------------------------------------------------------------------- */

typedef struct gmf_out {
    as_wfile w;
    int version, isz, rsz, psz;
    uint64_t pos;
    unsigned char buf[4096];
    size_t n;
} gmf_out;

static void go_flush(gmf_out *o) {
    as_wfile_write(&o->w, o->buf, o->n);
    o->n = 0;
}

static void go_u(gmf_out *o, uint64_t v, int nb) {
    if (o->n + (size_t)nb > sizeof o->buf) go_flush(o);
    as_st_le(o->buf + o->n, v, nb);
    o->n += (size_t)nb;
    o->pos += (uint64_t)nb;
}

static void go_r(gmf_out *o, double x) {
    if (o->rsz == 4) {
        float f = (float)x;
        uint32_t w;
        memcpy(&w, &f, sizeof w);
        go_u(o, w, 4);
    } else {
        uint64_t u;
        memcpy(&u, &x, sizeof u);
        go_u(o, u, 8);
    }
}

/* A keyword header whose data takes `bytes` after the header. */
static void go_kw(gmf_out *o, int code, uint64_t bytes, int has_count, uint64_t count) {
    uint64_t hdr = 4 + (uint64_t)o->psz + (has_count ? (uint64_t)o->isz : 0);
    uint64_t next = code == GMF_END ? 0 : o->pos + hdr + bytes;
    go_u(o, (uint64_t)code, 4);
    go_u(o, next, o->psz);
    if (has_count) go_u(o, count, o->isz);
}

/*
 * design: the file size is computed first (every keyword's size is known), which picks
 *   version 2 or 3 for version 0 and refuses a version whose positions or counts cannot
 *   hold it; version 1 refuses values that do not fit a float; then one sequential pass.
 */
static anistar_status gmf_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                                int version, int sol) {
    if (version < 0 || version > 4)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: GMF version %d (0 to 4)", path, version);
    if (sol && !m->tensor && m->nv > 0)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: the mesh has no per-vertex tensors to write",
                       path);
    uint64_t nv = m->nv, nt = m->nt;
    int v = version ? version : 2;
    for (;;) {
        int isz = v == 4 ? 8 : 4, rsz = v == 1 ? 4 : 8, psz = v >= 3 ? 8 : 4;
        uint64_t total = 8 + (4 + (uint64_t)psz + 4) + (4 + (uint64_t)psz); /* head, Dim, End */
        if (sol)
            total += 4 + (uint64_t)psz + (uint64_t)isz + 8 + nv * 6 * (uint64_t)rsz;
        else
            total += 2 * (4 + (uint64_t)psz + (uint64_t)isz) + nv * (3 * (uint64_t)rsz + (uint64_t)isz) +
                     nt * 4 * (uint64_t)isz;
        int fits = (psz == 8 || total <= INT32_MAX) && (isz == 8 || (nv <= INT32_MAX && nt <= INT32_MAX));
        if (fits) break;
        if (version)
            return as_fail(ctx, ANISTAR_EINVAL, "%s: the mesh is too large for GMF version %d",
                           path, version);
        v++;
    }
    if (v == 1) {
        const double *arr = sol ? m->tensor : m->xyz;
        size_t cnt = (sol ? 6 : 3) * m->nv;
        for (size_t i = 0; arr && i < cnt; i++)
            if (fabs(arr[i]) > FLT_MAX)
                return as_fail(ctx, ANISTAR_EINVAL, "%s: value %g does not fit GMF version 1's "
                               "float32", path, arr[i]);
    }
    gmf_out o;
    memset(&o, 0, sizeof o);
    o.version = v;
    o.isz = v == 4 ? 8 : 4;
    o.rsz = v == 1 ? 4 : 8;
    o.psz = v >= 3 ? 8 : 4;
    anistar_status st = as_wfile_open(ctx, &o.w, path);
    if (st) return st;
    go_u(&o, 1, 4);
    go_u(&o, (uint64_t)v, 4);
    go_kw(&o, GMF_DIMENSION, 4, 0, 0);
    go_u(&o, 3, 4);
    if (sol) {
        go_kw(&o, GMF_SOL_AT_VERTICES, 8 + nv * 6 * (uint64_t)o.rsz, 1, nv);
        go_u(&o, 1, 4); /* one field */
        go_u(&o, 3, 4); /* a symmetric tensor */
        static const int order[6] = {0, 1, 3, 2, 4, 5}; /* Medit order m11 m12 m22 m13 m23 m33 */
        for (size_t i = 0; i < m->nv; i++)
            for (int k = 0; k < 6; k++) go_r(&o, m->tensor[6 * i + (size_t)order[k]]);
    } else {
        go_kw(&o, GMF_VERTICES, nv * (3 * (uint64_t)o.rsz + (uint64_t)o.isz), 1, nv);
        for (size_t i = 0; i < m->nv; i++) {
            for (int k = 0; k < 3; k++) go_r(&o, m->xyz[3 * i + (size_t)k]);
            go_u(&o, 0, o.isz);
        }
        go_kw(&o, GMF_TRIANGLES, nt * 4 * (uint64_t)o.isz, 1, nt);
        for (size_t i = 0; i < m->nt; i++) {
            for (int k = 0; k < 3; k++) go_u(&o, (uint64_t)m->tri[3 * i + (size_t)k] + 1, o.isz);
            go_u(&o, 0, o.isz);
        }
    }
    go_kw(&o, GMF_END, 0, 0, 0);
    go_flush(&o);
    return as_wfile_close(&o.w);
}

anistar_status as_meshb_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                              int version) {
    return gmf_write(ctx, path, m, version, 0);
}

anistar_status as_solb_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                             int version) {
    return gmf_write(ctx, path, m, version, 1);
}
