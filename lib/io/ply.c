/*
 * ply.c — Stanford PLY: reader (ascii, binary_little_endian, binary_big_endian) and
 * writer (binary little endian).
 *
 * The writer adds one float64 face property per cell field (after vertex_indices).
 *
 * Reader notes:
 *  - types char/int8 uchar/uint8 short/int16 ushort/uint16 int/int32 uint/uint32
 *    float/float32 double/float64 (and int64/uint64, an extension some tools write);
 *  - element "vertex" needs scalar x, y, z of any numeric type; if it also has scalar
 *    m11 m12 m13 m22 m23 m33 they are read as the per-vertex tensors;
 *  - element "face" needs a list "vertex_indices" (or "vertex_index") whose count and
 *    index types are integers; polygons become fans;
 *  - every other property and element (normals, colours, "edge", "material"...) is
 *    skipped by its size, lists included; comment and obj_info lines are ignored;
 *  - before anything is allocated, the element counts are checked against the bytes
 *    after the header (each binary record has a known minimum size; each ASCII value
 *    takes at least 2 bytes).
 */
#include "io/meshio.h"

#include <math.h>
#include <string.h>

typedef enum ply_type {
    PLY_NONE = 0,
    PLY_I8,
    PLY_U8,
    PLY_I16,
    PLY_U16,
    PLY_I32,
    PLY_U32,
    PLY_I64,
    PLY_U64,
    PLY_F32,
    PLY_F64
} ply_type;

static const struct {
    const char *name;
    ply_type type;
} ply_type_names[] = {{"char", PLY_I8},    {"int8", PLY_I8},     {"uchar", PLY_U8},
                      {"uint8", PLY_U8},   {"short", PLY_I16},   {"int16", PLY_I16},
                      {"ushort", PLY_U16}, {"uint16", PLY_U16},  {"int", PLY_I32},
                      {"int32", PLY_I32},  {"uint", PLY_U32},    {"uint32", PLY_U32},
                      {"int64", PLY_I64},  {"uint64", PLY_U64},  {"float", PLY_F32},
                      {"float32", PLY_F32}, {"double", PLY_F64}, {"float64", PLY_F64}};

static int ply_size(ply_type t) {
    switch (t) {
    case PLY_I8: case PLY_U8: return 1;
    case PLY_I16: case PLY_U16: return 2;
    case PLY_I32: case PLY_U32: case PLY_F32: return 4;
    case PLY_I64: case PLY_U64: case PLY_F64: return 8;
    default: return 0;
    }
}
static int ply_is_int(ply_type t) { return t != PLY_NONE && t != PLY_F32 && t != PLY_F64; }

static ply_type ply_type_of(const char *tok, size_t len) {
    for (size_t i = 0; i < sizeof ply_type_names / sizeof ply_type_names[0]; i++)
        if (len == strlen(ply_type_names[i].name) &&
            memcmp(tok, ply_type_names[i].name, len) == 0)
            return ply_type_names[i].type;
    return PLY_NONE;
}

/* What a property is used for. */
enum { ROLE_SKIP = 0, ROLE_X, ROLE_Y, ROLE_Z, ROLE_M0 /* ..ROLE_M0+5 */, ROLE_INDICES = 10 };

typedef struct ply_prop {
    ply_type type;  /* the value type (of the entries for a list) */
    ply_type count; /* the list count type; PLY_NONE for a scalar */
    int role;
} ply_prop;

typedef struct ply_elem {
    char name[32];  /* truncated copy for messages */
    int kind;       /* 0 other, 1 vertex, 2 face */
    uint64_t count;
    size_t first, nprops; /* range in the property array */
} ply_elem;

typedef struct ply_reader {
    anistar_context *ctx;
    const char *name;
    ply_elem *elems;
    size_t nelems, cap_elems;
    ply_prop *props;
    size_t nprops, cap_props;
    int format; /* 0 ascii, 1 little endian, 2 big endian */
    /* binary cursor */
    const unsigned char *p, *end;
    as_text t; /* ascii cursor (and the header's) */
} ply_reader;

static void ply_reader_free(ply_reader *r) {
    as_free(r->ctx, r->elems, r->cap_elems * sizeof *r->elems);
    as_free(r->ctx, r->props, r->cap_props * sizeof *r->props);
}

static const char *const tensor_names[6] = {"m11", "m12", "m13", "m22", "m23", "m33"};

/*
 * Parse the header up to end_header; leaves r->t (ascii) or r->p (binary) at the data.
 */
static anistar_status ply_header(ply_reader *r) {
    as_text *t = &r->t;
    char show[32];
    const char *tok;
    size_t len = as_text_token(t, &tok);
    if (!(len == 3 && memcmp(tok, "ply", 3) == 0) || !as_text_at_eol(t))
        return as_text_fail(t, "not a PLY file (the first line must be 'ply')");
    as_text_skip_line(t);
    int have_format = 0;
    for (;;) {
        if (t->p >= t->end) return as_text_fail(t, "end of file inside the header (no "
                                                "end_header)");
        len = as_text_token(t, &tok);
        if (len == 0) { /* blank line */
            as_text_skip_line(t);
            continue;
        }
        if (as_token_is(tok, len, "comment") || as_token_is(tok, len, "obj_info")) {
            as_text_skip_line(t);
            continue;
        }
        if (as_token_is(tok, len, "end_header")) {
            if (!as_text_at_eol(t)) return as_text_fail(t, "unexpected text after end_header");
            if (t->p < t->end) t->p++; /* the newline; data follows */
            t->line++;
            break;
        }
        if (as_token_is(tok, len, "format")) {
            len = as_text_token(t, &tok);
            if (as_token_is(tok, len, "ascii"))
                r->format = 0;
            else if (as_token_is(tok, len, "binary_little_endian"))
                r->format = 1;
            else if (as_token_is(tok, len, "binary_big_endian"))
                r->format = 2;
            else
                return as_text_fail(t, "unknown PLY format '%s'", as_token_show(tok, len, show));
            have_format = 1;
            as_text_skip_line(t);
            continue;
        }
        if (!have_format) return as_text_fail(t, "expected 'format' after 'ply'");
        if (as_token_is(tok, len, "element")) {
            if (as_grow(r->ctx, (void **)&r->elems, &r->cap_elems, r->nelems + 1,
                        sizeof *r->elems))
                return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->name);
            ply_elem *e = &r->elems[r->nelems];
            memset(e, 0, sizeof *e);
            len = as_text_token(t, &tok);
            if (len == 0) return as_text_fail(t, "element without a name");
            memcpy(e->name, tok, len < sizeof e->name - 1 ? len : sizeof e->name - 1);
            e->kind = as_token_is(tok, len, "vertex") ? 1 : as_token_is(tok, len, "face") ? 2 : 0;
            int64_t count;
            anistar_status st = as_text_int(t, 0, "an element count", &count);
            if (st) return st;
            if (count < 0) return as_text_fail(t, "negative element count %lld", (long long)count);
            e->count = (uint64_t)count;
            e->first = r->nprops;
            for (size_t i = 0; i < r->nelems; i++)
                if (e->kind && r->elems[i].kind == e->kind)
                    return as_text_fail(t, "element '%s' appears twice", e->name);
            r->nelems++;
            as_text_skip_line(t);
            continue;
        }
        if (as_token_is(tok, len, "property")) {
            if (r->nelems == 0) return as_text_fail(t, "property before any element");
            ply_elem *e = &r->elems[r->nelems - 1];
            ply_prop pr = {PLY_NONE, PLY_NONE, ROLE_SKIP};
            len = as_text_token(t, &tok);
            if (as_token_is(tok, len, "list")) {
                len = as_text_token(t, &tok);
                pr.count = ply_type_of(tok, len);
                if (pr.count == PLY_NONE)
                    return as_text_fail(t, "unknown list count type '%s'",
                                        as_token_show(tok, len, show));
                if (!ply_is_int(pr.count))
                    return as_text_fail(t, "list count type '%s' is not an integer type",
                                        as_token_show(tok, len, show));
                len = as_text_token(t, &tok);
            }
            pr.type = ply_type_of(tok, len);
            if (pr.type == PLY_NONE)
                return as_text_fail(t, "unknown property type '%s'",
                                    as_token_show(tok, len, show));
            len = as_text_token(t, &tok);
            if (len == 0) return as_text_fail(t, "property without a name");
            int list = pr.count != PLY_NONE;
            if (e->kind == 1) {
                int role = as_token_is(tok, len, "x")   ? ROLE_X
                           : as_token_is(tok, len, "y") ? ROLE_Y
                           : as_token_is(tok, len, "z") ? ROLE_Z
                                                        : ROLE_SKIP;
                for (int k = 0; k < 6; k++)
                    if (as_token_is(tok, len, tensor_names[k])) role = ROLE_M0 + k;
                if (role != ROLE_SKIP && list)
                    return as_text_fail(t, "vertex property '%s' must be a scalar, not a list",
                                        as_token_show(tok, len, show));
                pr.role = role;
            } else if (e->kind == 2 && (as_token_is(tok, len, "vertex_indices") ||
                                        as_token_is(tok, len, "vertex_index"))) {
                if (!list)
                    return as_text_fail(t, "face property '%s' must be a list",
                                        as_token_show(tok, len, show));
                if (!ply_is_int(pr.type))
                    return as_text_fail(t, "face indices must have an integer type");
                pr.role = ROLE_INDICES;
            }
            for (size_t i = e->first; i < e->first + e->nprops; i++)
                if (pr.role != ROLE_SKIP && r->props[i].role == pr.role)
                    return as_text_fail(t, "property '%s' appears twice",
                                        as_token_show(tok, len, show));
            if (as_grow(r->ctx, (void **)&r->props, &r->cap_props, r->nprops + 1,
                        sizeof *r->props))
                return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->name);
            r->props[r->nprops++] = pr;
            e->nprops++;
            as_text_skip_line(t);
            continue;
        }
        return as_text_fail(t, "unknown header line '%s'", as_token_show(tok, len, show));
    }
    return ANISTAR_OK;
}

static inline uint32_t ld32(const unsigned char *p, int big) {
    return big ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
               : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}
static inline uint64_t ld64(const unsigned char *p, int big) {
    uint64_t a = ld32(p, big), b = ld32(p + 4, big);
    return big ? a << 32 | b : b << 32 | a;
}
static inline uint16_t ld16(const unsigned char *p, int big) {
    return big ? (uint16_t)(p[0] << 8 | p[1]) : (uint16_t)(p[1] << 8 | p[0]);
}

/* One binary value as a double (integers exactly up to 2^53) and as an integer; *big_u
 * is set for a uint64 above INT64_MAX (then *i saturates). */
static inline void bin_value(const unsigned char *p, ply_type ty, int big, double *d,
                             int64_t *i, int *big_u) {
    *big_u = 0;
    switch (ty) {
    case PLY_I8: *i = (int8_t)p[0]; break;
    case PLY_U8: *i = p[0]; break;
    case PLY_I16: *i = (int16_t)ld16(p, big); break;
    case PLY_U16: *i = ld16(p, big); break;
    case PLY_I32: *i = (int32_t)ld32(p, big); break;
    case PLY_U32: *i = ld32(p, big); break;
    case PLY_I64: *i = (int64_t)ld64(p, big); break;
    case PLY_U64: {
        uint64_t u = ld64(p, big);
        *big_u = u > (uint64_t)INT64_MAX;
        *i = *big_u ? INT64_MAX : (int64_t)u;
        break;
    }
    case PLY_F32: {
        uint32_t w = ld32(p, big);
        float f;
        memcpy(&f, &w, sizeof f);
        *d = f;
        *i = 0;
        return;
    }
    default: { /* PLY_F64 */
        uint64_t u = ld64(p, big);
        double x;
        memcpy(&x, &u, sizeof x);
        *d = x;
        *i = 0;
        return;
    }
    }
    *d = (double)*i;
}

/* Minimum bytes of one record of element e (binary) or values (ascii). */
static uint64_t elem_min_size(const ply_reader *r, const ply_elem *e) {
    uint64_t n = 0;
    for (size_t i = e->first; i < e->first + e->nprops; i++) {
        const ply_prop *pr = &r->props[i];
        n += r->format ? (uint64_t)ply_size(pr->count != PLY_NONE ? pr->count : pr->type) : 2;
    }
    return n;
}

typedef struct face_state {
    int64_t k, first, prev;
} face_state;

/* Receive value k of a face's index list (fans as it goes). */
static anistar_status face_index(ply_reader *r, as_trimesh *out, uint64_t fi, int64_t v,
                                 int bad, face_state *fs) {
    if (bad || v < 0 || (uint64_t)v >= AS_TRIMESH_MAX_VERTICES) {
        if (r->format == 0)
            return as_text_fail(&r->t, "face %llu: vertex index %lld out of range",
                                (unsigned long long)fi, (long long)v);
        return as_io_fail(r->ctx, r->name, "face %llu: vertex index %lld out of range",
                          (unsigned long long)fi, (long long)v);
    }
    anistar_status st = ANISTAR_OK;
    if (fs->k == 0)
        fs->first = v;
    else if (fs->k >= 2)
        st = as_trimesh_add_triangle(r->ctx, out, (int32_t)fs->first, (int32_t)fs->prev,
                                     (int32_t)v);
    fs->prev = v;
    fs->k++;
    return st;
}

static anistar_status truncated(ply_reader *r, const ply_elem *e, uint64_t i) {
    return as_io_fail(r->ctx, r->name, "truncated: the data ends in %s %llu of %llu", e->name,
                      (unsigned long long)i, (unsigned long long)e->count);
}

static anistar_status check_vertex(ply_reader *r, uint64_t i, const double xyz[3],
                                   const double m[6], int have_tensor) {
    for (int k = 0; k < 3; k++)
        if (!isfinite(xyz[k]))
            goto bad;
    if (have_tensor)
        for (int k = 0; k < 6; k++)
            if (!isfinite(m[k])) goto bad;
    return ANISTAR_OK;
bad:
    if (r->format == 0)
        return as_text_fail(&r->t, "vertex %llu: value is not a finite number",
                            (unsigned long long)i);
    return as_io_fail(r->ctx, r->name, "vertex %llu: value is not a finite number",
                      (unsigned long long)i);
}

static void store_vertex(as_trimesh *out, const double xyz[3], const double m[6],
                         int have_tensor) {
    double *p = out->xyz + 3 * out->nv;
    p[0] = xyz[0];
    p[1] = xyz[1];
    p[2] = xyz[2];
    if (have_tensor) memcpy(out->tensor + 6 * out->nv, m, 6 * sizeof(double));
    out->nv++;
}

/* Read every instance of element e (binary). */
static anistar_status read_elem_binary(ply_reader *r, const ply_elem *e, as_trimesh *out,
                                       int have_tensor) {
    int big = r->format == 2;
    const ply_prop *props = r->props + e->first;
    anistar_status st;
    for (uint64_t i = 0; i < e->count; i++) {
        double xyz[3] = {0, 0, 0}, m[6] = {0, 0, 0, 0, 0, 0};
        face_state fs = {0, 0, 0};
        for (size_t j = 0; j < e->nprops; j++) {
            const ply_prop *pr = &props[j];
            double d;
            int64_t iv;
            int bad;
            if (pr->count == PLY_NONE) {
                int sz = ply_size(pr->type);
                if (r->end - r->p < sz) return truncated(r, e, i);
                if (pr->role != ROLE_SKIP) {
                    bin_value(r->p, pr->type, big, &d, &iv, &bad);
                    if (pr->role <= ROLE_Z)
                        xyz[pr->role - ROLE_X] = d;
                    else
                        m[pr->role - ROLE_M0] = d;
                }
                r->p += sz;
                continue;
            }
            int csz = ply_size(pr->count), sz = ply_size(pr->type);
            if (r->end - r->p < csz) return truncated(r, e, i);
            int64_t cnt;
            bin_value(r->p, pr->count, big, &d, &cnt, &bad);
            r->p += csz;
            if (bad || cnt < 0)
                return as_io_fail(r->ctx, r->name, "%s %llu: negative list length", e->name,
                                  (unsigned long long)i);
            if ((uint64_t)cnt > (uint64_t)(r->end - r->p) / (uint64_t)sz)
                return truncated(r, e, i);
            if (pr->role == ROLE_INDICES) {
                for (int64_t k = 0; k < cnt; k++) {
                    bin_value(r->p + (size_t)k * (size_t)sz, pr->type, big, &d, &iv, &bad);
                    if ((st = face_index(r, out, i, iv, bad, &fs))) return st;
                }
            }
            r->p += (size_t)cnt * (size_t)sz;
        }
        if (e->kind == 1) {
            if ((st = check_vertex(r, i, xyz, m, have_tensor))) return st;
            store_vertex(out, xyz, m, have_tensor);
        }
    }
    return ANISTAR_OK;
}

/* Skip one ASCII value that must be a number. */
static anistar_status skip_ascii_value(ply_reader *r, const ply_elem *e, uint64_t i) {
    as_text *t = &r->t;
    if (!as_text_skip_ws(t))
        return as_text_fail(t, "truncated: the data ends in %s %llu of %llu", e->name,
                            (unsigned long long)i, (unsigned long long)e->count);
    const char *tok;
    size_t len = as_text_token(t, &tok);
    double d;
    if (as_parse_double(tok, &d) != len) {
        char show[32];
        return as_text_fail(t, "%s %llu: expected a number, found '%s'", e->name,
                            (unsigned long long)i, as_token_show(tok, len, show));
    }
    return ANISTAR_OK;
}

/* Read every instance of element e (ascii: whitespace-separated values, lines are not
 * significant). */
static anistar_status read_elem_ascii(ply_reader *r, const ply_elem *e, as_trimesh *out,
                                      int have_tensor) {
    as_text *t = &r->t;
    const ply_prop *props = r->props + e->first;
    anistar_status st;
    for (uint64_t i = 0; i < e->count; i++) {
        double xyz[3] = {0, 0, 0}, m[6] = {0, 0, 0, 0, 0, 0};
        face_state fs = {0, 0, 0};
        for (size_t j = 0; j < e->nprops; j++) {
            const ply_prop *pr = &props[j];
            if (!as_text_skip_ws(t))
                return as_text_fail(t, "truncated: the data ends in %s %llu of %llu", e->name,
                                    (unsigned long long)i, (unsigned long long)e->count);
            if (pr->count == PLY_NONE) {
                if (pr->role == ROLE_SKIP) {
                    if ((st = skip_ascii_value(r, e, i))) return st;
                    continue;
                }
                double d;
                if ((st = as_text_double(t, 1, "a vertex value", &d))) return st;
                if (pr->role <= ROLE_Z)
                    xyz[pr->role - ROLE_X] = d;
                else
                    m[pr->role - ROLE_M0] = d;
                continue;
            }
            int64_t cnt;
            if ((st = as_text_int(t, 1, "a list length", &cnt))) return st;
            if (cnt < 0)
                return as_text_fail(t, "%s %llu: negative list length %lld", e->name,
                                    (unsigned long long)i, (long long)cnt);
            for (int64_t k = 0; k < cnt; k++) {
                if (pr->role != ROLE_INDICES) {
                    if ((st = skip_ascii_value(r, e, i))) return st;
                    continue;
                }
                int64_t v;
                if ((st = as_text_int(t, 1, "a vertex index", &v))) return st;
                if ((st = face_index(r, out, i, v, 0, &fs))) return st;
            }
        }
        if (e->kind == 1) {
            if ((st = check_vertex(r, i, xyz, m, have_tensor))) return st;
            store_vertex(out, xyz, m, have_tensor);
        }
    }
    return ANISTAR_OK;
}

/*
 * Parse a PLY file (see the file comment).
 * design: header -> element/property tables with roles -> the counts checked against
 *   the data size (sum of count x minimum record size) -> one allocation for the
 *   vertices and one (grown for fans) for the triangles -> elements read in file order,
 *   unknown ones skipped -> indices checked against the vertex count at the end (the
 *   face element may come first).
 */
anistar_status as_ply_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    ply_reader r;
    memset(&r, 0, sizeof r);
    r.ctx = ctx;
    r.name = name;
    as_text_init(&r.t, ctx, name, data, size, 0);
    anistar_status st = ply_header(&r);
    if (st) goto done;
    ply_elem *ve = NULL, *fe = NULL;
    for (size_t i = 0; i < r.nelems; i++) {
        ply_elem *e = &r.elems[i];
        if (e->kind == 1) ve = e;
        if (e->kind == 2) fe = e;
        if (e->nprops == 0 && e->count > 0) {
            st = as_io_fail(ctx, name, "element '%s' has no properties", e->name);
            goto done;
        }
    }
    if (!ve || !fe) {
        st = as_io_fail(ctx, name, "no '%s' element in the header", ve ? "face" : "vertex");
        goto done;
    }
    int roles[16] = {0};
    for (size_t i = ve->first; i < ve->first + ve->nprops; i++) roles[r.props[i].role] = 1;
    for (size_t i = fe->first; i < fe->first + fe->nprops; i++) roles[r.props[i].role] = 1;
    if (!roles[ROLE_X] || !roles[ROLE_Y] || !roles[ROLE_Z]) {
        st = as_io_fail(ctx, name, "the vertex element lacks property x, y or z");
        goto done;
    }
    if (!roles[ROLE_INDICES]) {
        st = as_io_fail(ctx, name, "the face element has no list vertex_indices");
        goto done;
    }
    int have_tensor = 1;
    for (int k = 0; k < 6; k++) have_tensor &= roles[ROLE_M0 + k];
    /* Counts against the data size, before any allocation. */
    uint64_t avail = (uint64_t)(r.t.end - r.t.p) + (r.format == 0);
    for (size_t i = 0; i < r.nelems; i++) {
        uint64_t ms = elem_min_size(&r, &r.elems[i]);
        if (!as_fits(r.elems[i].count, ms, avail)) {
            st = as_io_fail(ctx, name, "element '%s' count %llu exceeds what the %llu bytes of "
                            "data can hold", r.elems[i].name,
                            (unsigned long long)r.elems[i].count,
                            (unsigned long long)(r.t.end - r.t.p));
            goto done;
        }
        avail -= r.elems[i].count * ms;
    }
    if (ve->count > AS_TRIMESH_MAX_VERTICES) {
        st = as_io_fail(ctx, name, "too many vertices (%llu)", (unsigned long long)ve->count);
        goto done;
    }
    if (ve->count == 0 || fe->count == 0) {
        st = as_io_fail(ctx, name, "no triangles (%llu vertices, %llu faces)",
                        (unsigned long long)ve->count, (unsigned long long)fe->count);
        goto done;
    }
    st = as_trimesh_reserve(ctx, out, (size_t)ve->count, (size_t)fe->count);
    if (!st && have_tensor) st = as_trimesh_alloc_tensors(ctx, out);
    if (st) goto done;
    r.p = (const unsigned char *)r.t.p;
    r.end = (const unsigned char *)r.t.end;
    for (size_t i = 0; i < r.nelems && !st; i++)
        st = r.format ? read_elem_binary(&r, &r.elems[i], out, have_tensor)
                      : read_elem_ascii(&r, &r.elems[i], out, have_tensor);
    if (st) goto done;
    for (size_t i = 0; i < 3 * out->nt; i++)
        if ((size_t)out->tri[i] >= out->nv) {
            st = as_io_fail(ctx, name, "triangle %zu: vertex index %ld out of range [0, %zu)",
                            i / 3, (long)out->tri[i], out->nv);
            goto done;
        }
    if (out->nt == 0)
        st = as_io_fail(ctx, name, "no triangles (every face has fewer than 3 vertices)");
done:
    ply_reader_free(&r);
    if (st) as_trimesh_free(ctx, out);
    return st;
}

/* ---- writer -------------------------------------------------------------------------- */

static void put_f64(unsigned char *p, double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    as_st_le(p, u, 8);
}

anistar_status as_ply_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "ply\nformat binary_little_endian 1.0\ncomment written by anistar\n"
                    "element vertex %zu\nproperty double x\nproperty double y\n"
                    "property double z\n", m->nv);
    if (m->tensor)
        for (int k = 0; k < 6; k++) as_wfile_printf(&w, "property double %s\n", tensor_names[k]);
    as_wfile_printf(&w, "element face %zu\nproperty list uchar int vertex_indices\n", m->nt);
    for (size_t c = 0; c < ncells; c++) as_wfile_printf(&w, "property double %s\n", cells[c].name);
    as_wfile_puts(&w, "end_header\n");
    unsigned char buf[4096];
    size_t n = 0, rec = m->tensor ? 72 : 24;
    for (size_t i = 0; i < m->nv; i++) {
        if (n + rec > sizeof buf) {
            as_wfile_write(&w, buf, n);
            n = 0;
        }
        for (int k = 0; k < 3; k++) put_f64(buf + n + 8 * k, m->xyz[3 * i + k]);
        if (m->tensor)
            for (int k = 0; k < 6; k++) put_f64(buf + n + 24 + 8 * k, m->tensor[6 * i + k]);
        n += rec;
    }
    for (size_t i = 0; i < m->nt; i++) {
        /* a face record: 13 bytes of indices and 8 per field (written in pieces when the
         * fields do not fit the buffer together) */
        if (n + 13 > sizeof buf) {
            as_wfile_write(&w, buf, n);
            n = 0;
        }
        buf[n] = 3;
        for (int k = 0; k < 3; k++) as_st_le(buf + n + 1 + 4 * k, (uint32_t)m->tri[3 * i + k], 4);
        n += 13;
        for (size_t c = 0; c < ncells; c++) {
            if (n + 8 > sizeof buf) {
                as_wfile_write(&w, buf, n);
                n = 0;
            }
            put_f64(buf + n, cells[c].values[i]);
            n += 8;
        }
    }
    as_wfile_write(&w, buf, n);
    return as_wfile_close(&w);
}
