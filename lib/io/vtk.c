/*
 * vtk.c — VTK files for ParaView, meshio and VTK itself: legacy VTK (.vtk, ASCII,
 * DATASET UNSTRUCTURED_GRID, version 3.0) and VTK XML unstructured grid (.vtu, version
 * 1.0, UInt64 headers, inline base64 "binary" arrays): writers and readers.
 *
 * Both writers carry the per-vertex tensors as the point-data tensor "metric" (9
 * components, row-major full matrix: m11 m12 m13 m12 m22 m23 m13 m23 m33; meshio reads it
 * as an n x 3 x 3 array) and each as_cell_field as a scalar cell-data array of Float64.
 * Legacy numbers are written with %.17g, VTU data as little-endian bytes, so both are
 * exact. The triangles are VTK_TRIANGLE cells (type 5). Versions before this one wrote
 * the legacy file as POLYDATA (POLYGONS), which meshio refuses; the reader takes both.
 */
#include "io/meshio.h"

#include <math.h>
#include <string.h>

/* The full 3x3 row-major matrix of a symmetric tensor m11 m12 m13 m22 m23 m33. */
static void full9(const double *s, double f[9]) {
    f[0] = s[0], f[1] = s[1], f[2] = s[2];
    f[3] = s[1], f[4] = s[3], f[5] = s[4];
    f[6] = s[2], f[7] = s[4], f[8] = s[5];
}

anistar_status as_vtk_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    as_wfile_printf(&w, "# vtk DataFile Version 3.0\nanistar triangle mesh\nASCII\n"
                    "DATASET UNSTRUCTURED_GRID\nPOINTS %zu double\n", m->nv);
    for (size_t i = 0; i < m->nv; i++) {
        as_wfile_double(&w, m->xyz[3 * i], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 1], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 2], '\n');
    }
    as_wfile_printf(&w, "CELLS %zu %zu\n", m->nt, 4 * m->nt);
    for (size_t i = 0; i < m->nt; i++)
        as_wfile_printf(&w, "3 %ld %ld %ld\n", (long)m->tri[3 * i], (long)m->tri[3 * i + 1],
                        (long)m->tri[3 * i + 2]);
    as_wfile_printf(&w, "CELL_TYPES %zu\n", m->nt);
    for (size_t i = 0; i < m->nt; i++) as_wfile_puts(&w, "5\n"); /* VTK_TRIANGLE */
    if (m->tensor) {
        as_wfile_printf(&w, "POINT_DATA %zu\nTENSORS metric double\n", m->nv);
        for (size_t i = 0; i < m->nv; i++) {
            double f[9];
            full9(m->tensor + 6 * i, f);
            for (int k = 0; k < 9; k++) as_wfile_double(&w, f[k], k % 3 == 2 ? '\n' : ' ');
        }
    }
    if (ncells) {
        as_wfile_printf(&w, "CELL_DATA %zu\n", m->nt);
        for (size_t c = 0; c < ncells; c++) {
            as_wfile_printf(&w, "SCALARS %s double 1\nLOOKUP_TABLE default\n", cells[c].name);
            for (size_t i = 0; i < m->nt; i++) as_wfile_double(&w, cells[c].values[i], '\n');
        }
    }
    return as_wfile_close(&w);
}

/* ---- VTU ----------------------------------------------------------------------------- */

/* A streaming base64 encoder into w (pending: up to 2 bytes not yet encoded). */
typedef struct b64 {
    as_wfile *w;
    unsigned char pend[3];
    int npend;
    char out[4096];
    size_t nout;
} b64;

static const char b64_alphabet[] =
    "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

static void b64_flush_out(b64 *b) {
    as_wfile_write(b->w, b->out, b->nout);
    b->nout = 0;
}

static void b64_quad(b64 *b, const unsigned char *in, int n) {
    if (b->nout + 4 > sizeof b->out) b64_flush_out(b);
    uint32_t v = (uint32_t)in[0] << 16 | (uint32_t)(n > 1 ? in[1] : 0) << 8 | (n > 2 ? in[2] : 0);
    char *o = b->out + b->nout;
    o[0] = b64_alphabet[v >> 18 & 63];
    o[1] = b64_alphabet[v >> 12 & 63];
    o[2] = n > 1 ? b64_alphabet[v >> 6 & 63] : '=';
    o[3] = n > 2 ? b64_alphabet[v & 63] : '=';
    b->nout += 4;
}

static void b64_put(b64 *b, const unsigned char *p, size_t n) {
    for (size_t i = 0; i < n; i++) {
        b->pend[b->npend++] = p[i];
        if (b->npend == 3) {
            b64_quad(b, b->pend, 3);
            b->npend = 0;
        }
    }
}

static void b64_end(b64 *b) {
    if (b->npend) b64_quad(b, b->pend, b->npend);
    b->npend = 0;
    b64_flush_out(b);
}

static void b64_u64(b64 *b, uint64_t v) {
    unsigned char p[8];
    as_st_le(p, v, 8);
    b64_put(b, p, 8);
}

static void b64_f64(b64 *b, double x) {
    uint64_t u;
    memcpy(&u, &x, sizeof u);
    b64_u64(b, u);
}

/* <DataArray ...> header, then the byte count (the UInt64 header VTK expects in front
 * of uncompressed binary data, encoded in the same base64 stream as the data). */
static void array_begin(as_wfile *w, b64 *b, const char *type, const char *name, int ncomp,
                        uint64_t nbytes) {
    as_wfile_printf(w, "        <DataArray type=\"%s\"", type);
    if (name) as_wfile_printf(w, " Name=\"%s\"", name);
    if (ncomp > 1) as_wfile_printf(w, " NumberOfComponents=\"%d\"", ncomp);
    as_wfile_puts(w, " format=\"binary\">\n          ");
    b->w = w;
    b->npend = 0;
    b->nout = 0;
    b64_u64(b, nbytes);
}

static void array_end(as_wfile *w, b64 *b) {
    b64_end(b);
    as_wfile_puts(w, "\n        </DataArray>\n");
}

anistar_status as_vtu_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells) {
    as_wfile w;
    anistar_status st = as_wfile_open(ctx, &w, path);
    if (st) return st;
    b64 b;
    as_wfile_printf(&w, "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" "
                    "version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\">\n"
                    "  <UnstructuredGrid>\n    <Piece NumberOfPoints=\"%zu\" "
                    "NumberOfCells=\"%zu\">\n", m->nv, m->nt);
    if (m->tensor) {
        as_wfile_puts(&w, "      <PointData Tensors=\"metric\">\n");
        array_begin(&w, &b, "Float64", "metric", 9, (uint64_t)m->nv * 72);
        for (size_t i = 0; i < m->nv; i++) {
            double f[9];
            full9(m->tensor + 6 * i, f);
            for (int k = 0; k < 9; k++) b64_f64(&b, f[k]);
        }
        array_end(&w, &b);
        as_wfile_puts(&w, "      </PointData>\n");
    }
    if (ncells) {
        as_wfile_printf(&w, "      <CellData Scalars=\"%s\">\n", cells[0].name);
        for (size_t c = 0; c < ncells; c++) {
            array_begin(&w, &b, "Float64", cells[c].name, 1, (uint64_t)m->nt * 8);
            for (size_t i = 0; i < m->nt; i++) b64_f64(&b, cells[c].values[i]);
            array_end(&w, &b);
        }
        as_wfile_puts(&w, "      </CellData>\n");
    }
    as_wfile_puts(&w, "      <Points>\n");
    array_begin(&w, &b, "Float64", NULL, 3, (uint64_t)m->nv * 24);
    for (size_t i = 0; i < 3 * m->nv; i++) b64_f64(&b, m->xyz[i]);
    array_end(&w, &b);
    as_wfile_puts(&w, "      </Points>\n      <Cells>\n");
    array_begin(&w, &b, "Int64", "connectivity", 1, (uint64_t)m->nt * 24);
    for (size_t i = 0; i < 3 * m->nt; i++) b64_u64(&b, (uint64_t)(int64_t)m->tri[i]);
    array_end(&w, &b);
    array_begin(&w, &b, "Int64", "offsets", 1, (uint64_t)m->nt * 8);
    for (size_t i = 0; i < m->nt; i++) b64_u64(&b, 3 * (uint64_t)(i + 1));
    array_end(&w, &b);
    array_begin(&w, &b, "UInt8", "types", 1, (uint64_t)m->nt);
    for (size_t i = 0; i < m->nt; i++) {
        unsigned char five = 5; /* VTK_TRIANGLE */
        b64_put(&b, &five, 1);
    }
    array_end(&w, &b);
    as_wfile_puts(&w, "      </Cells>\n    </Piece>\n  </UnstructuredGrid>\n</VTKFile>\n");
    return as_wfile_close(&w);
}

/* ==================================================================================== */
/* Readers                                                                              */
/* ==================================================================================== */

/* Append the triangles of one cell with the k vertex ids v: VTK_TRIANGLE (5),
 * VTK_POLYGON (7), VTK_QUAD (9) and POLYDATA polygons (type -1) as fans (v0 vj-1 vj);
 * other cell types (vertices, lines, strips, pixels, volumes) are skipped. */
static anistar_status add_cell(anistar_context *ctx, as_trimesh *out, int64_t type,
                               const int32_t *v, int64_t k) {
    if (type != 5 && type != 7 && type != 9 && type != -1) return ANISTAR_OK;
    for (int64_t j = 2; j < k; j++) {
        anistar_status st = as_trimesh_add_triangle(ctx, out, v[0], v[j - 1], v[j]);
        if (st) return st;
    }
    return ANISTAR_OK;
}

/* The symmetric part of a 3x3 row-major matrix, as m11 m12 m13 m22 m23 m33. */
static void sym6(const double f[9], double *s) {
    s[0] = f[0];
    s[1] = 0.5 * (f[1] + f[3]);
    s[2] = 0.5 * (f[2] + f[6]);
    s[3] = f[4];
    s[4] = 0.5 * (f[5] + f[7]);
    s[5] = f[8];
}

/* Final checks shared by the readers: triangles exist, indices are below nv. */
static anistar_status check_indices(anistar_context *ctx, const char *name, as_trimesh *out) {
    if (out->nv == 0 || out->nt == 0)
        return as_io_fail(ctx, name, "no triangles (%zu points, %zu triangles)", out->nv,
                          out->nt);
    for (size_t i = 0; i < 3 * out->nt; i++)
        if ((size_t)out->tri[i] >= out->nv)
            return as_io_fail(ctx, name, "triangle %zu: point index %ld out of range [0, %zu)",
                              i / 3, (long)out->tri[i], out->nv);
    return ANISTAR_OK;
}

/* ---- legacy .vtk ----------------------------------------------------------------------- */

typedef struct vtk_reader {
    as_text t;
    anistar_context *ctx;
    as_trimesh *out;
    int kind;          /* 0 no DATASET yet, 1 POLYDATA, 2 UNSTRUCTURED_GRID */
    int32_t *conn;     /* UNSTRUCTURED_GRID: the CELLS lists, kept until CELL_TYPES */
    size_t nconn;
    uint64_t ncells;   /* cells of CELLS (unstructured) */
    int have_points, have_cells, have_types;
    int attr;          /* 0 none yet, 1 POINT_DATA, 2 CELL_DATA */
    uint64_t attr_n;   /* the tuple count of the current attribute section */
    int metric_named;  /* the tensors read so far came from an array named "metric" */
} vtk_reader;

static uint64_t vtk_left(const vtk_reader *r) { return (uint64_t)(r->t.end - r->t.p) + 1; }

/* A nonnegative count at the cursor (on the current line). */
static anistar_status vtk_count(vtk_reader *r, const char *what, uint64_t *n) {
    int64_t v = 0;
    *n = 0;
    anistar_status st = as_text_int(&r->t, 0, what, &v);
    if (st) return st;
    if (v < 0) return as_text_fail(&r->t, "negative %s %lld", what, (long long)v);
    *n = (uint64_t)v;
    return ANISTAR_OK;
}

/* Check that count values of at least 2 bytes each can be left in the file. */
static anistar_status vtk_fits(vtk_reader *r, const char *section, uint64_t count,
                               uint64_t per) {
    if (per && count > UINT64_MAX / per)
        return as_text_fail(&r->t, "%s: count %llu too large", section,
                            (unsigned long long)count);
    if (!as_fits(count * per, 2, vtk_left(r)))
        return as_text_fail(&r->t, "%s: %llu values exceed what the rest of the file (%zu "
                            "bytes) can hold", section, (unsigned long long)(count * per),
                            (size_t)(r->t.end - r->t.p));
    return ANISTAR_OK;
}

/* Skip n numbers (any value, NaN included: they are not used). */
static anistar_status vtk_skip_numbers(vtk_reader *r, const char *section, uint64_t n) {
    for (uint64_t i = 0; i < n; i++) {
        if (!as_text_skip_ws(&r->t))
            return as_text_fail(&r->t, "%s: the file ends after %llu of %llu values", section,
                                (unsigned long long)i, (unsigned long long)n);
        const char *tok;
        size_t len = as_text_token(&r->t, &tok);
        double d;
        if (as_parse_double(tok, &d) != len) {
            char show[32];
            return as_text_fail(&r->t, "%s: expected a number, found '%s'", section,
                                as_token_show(tok, len, show));
        }
    }
    return ANISTAR_OK;
}

/* A point or cell id list entry: an integer in [0, INT32_MAX). */
static anistar_status vtk_index(vtk_reader *r, int32_t *v) {
    int64_t x = 0;
    *v = 0;
    anistar_status st = as_text_int(&r->t, 1, "a point index", &x);
    if (st) return st;
    if (x < 0 || x >= INT32_MAX)
        return as_text_fail(&r->t, "point index %lld out of range", (long long)x);
    *v = (int32_t)x;
    return ANISTAR_OK;
}

/* The numeric type names of legacy VTK (checked, not used: every value is read as a
 * double). */
static int vtk_type_ok(const char *tok, size_t len) {
    static const char *const types[] = {"bit",   "unsigned_char", "char",   "unsigned_short",
                                        "short", "unsigned_int",  "int",    "unsigned_long",
                                        "long",  "float",         "double", "vtkIdType",
                                        "vtktypeint64", "vtktypeuint64", "vtktypeint32",
                                        "vtktypeuint32"};
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (as_token_is(tok, len, types[i])) return 1;
    return 0;
}

static anistar_status vtk_type(vtk_reader *r, const char *section) {
    const char *tok;
    size_t len = as_text_token(&r->t, &tok);
    char show[32];
    if (!vtk_type_ok(tok, len))
        return as_text_fail(&r->t, "%s: unknown data type '%s'", section,
                            as_token_show(tok, len, show));
    return ANISTAR_OK;
}

static anistar_status vtk_points(vtk_reader *r) {
    uint64_t n;
    anistar_status st;
    if (r->have_points) return as_text_fail(&r->t, "a second POINTS section");
    if ((st = vtk_count(r, "point count", &n)) || (st = vtk_type(r, "POINTS")) ||
        (st = vtk_fits(r, "POINTS", n, 3)))
        return st;
    if (n > AS_TRIMESH_MAX_VERTICES)
        return as_text_fail(&r->t, "too many points (%llu)", (unsigned long long)n);
    if ((st = as_trimesh_reserve(r->ctx, r->out, (size_t)n, r->out->nt))) return st;
    for (uint64_t i = 0; i < n; i++) {
        double *p = r->out->xyz + 3 * i;
        for (int k = 0; k < 3; k++)
            if ((st = as_text_double(&r->t, 1, "a point coordinate", p + k))) return st;
    }
    r->out->nv = (size_t)n;
    r->have_points = 1;
    return ANISTAR_OK;
}

/* POLYGONS (POLYDATA; triangulated at once) or VERTICES/LINES/TRIANGLE_STRIPS (skipped)
 * or CELLS (UNSTRUCTURED_GRID; kept until CELL_TYPES): n lists, size integers in all. */
static anistar_status vtk_lists(vtk_reader *r, const char *section, int mode) {
    uint64_t n = 0, size = 0;
    anistar_status st;
    if ((st = vtk_count(r, "cell count", &n)) || (st = vtk_count(r, "list size", &size)) ||
        (st = vtk_fits(r, section, size, 1)))
        return st;
    if (n > size)
        return as_text_fail(&r->t, "%s: %llu cells cannot fit in %llu integers", section,
                            (unsigned long long)n, (unsigned long long)size);
    if (mode == 0) return vtk_skip_numbers(r, section, size); /* not triangles */
    int32_t *conn = NULL;
    if (mode == 2) {
        if (r->have_cells) return as_text_fail(&r->t, "a second CELLS section");
        conn = as_alloc_array(r->ctx, (size_t)size ? (size_t)size : 1, sizeof *conn);
        if (!conn) return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->t.name);
        r->conn = conn;
        r->nconn = (size_t)size;
        r->ncells = n;
        r->have_cells = 1;
    }
    uint64_t used = 0;
    int32_t fan[3];
    for (uint64_t i = 0; i < n; i++) {
        int64_t k;
        if ((st = as_text_int(&r->t, 1, "a cell size", &k))) return st;
        if (k < 0 || used >= size || (uint64_t)k > size - used - 1)
            return as_text_fail(&r->t, "%s: cell %llu: size %lld overruns the list size %llu",
                                section, (unsigned long long)i, (long long)k,
                                (unsigned long long)size);
        if (conn) conn[used] = (int32_t)k;
        used++;
        for (int64_t j = 0; j < k; j++) {
            int32_t v = 0;
            if ((st = vtk_index(r, &v))) return st;
            if (conn) conn[used] = v;
            used++;
            if (mode == 1) { /* a POLYDATA polygon: fan as it goes */
                if (j < 2) {
                    fan[j] = v;
                } else {
                    if ((st = as_trimesh_add_triangle(r->ctx, r->out, fan[0], fan[1], v)))
                        return st;
                    fan[1] = v;
                }
            }
        }
    }
    if (used != size)
        return as_text_fail(&r->t, "%s: the lists hold %llu integers, the header says %llu",
                            section, (unsigned long long)used, (unsigned long long)size);
    return ANISTAR_OK;
}

static anistar_status vtk_cell_types(vtk_reader *r) {
    uint64_t n;
    anistar_status st;
    if ((st = vtk_count(r, "cell count", &n))) return st;
    if (!r->have_cells || r->have_types)
        return as_text_fail(&r->t, r->have_types ? "a second CELL_TYPES section"
                                                 : "CELL_TYPES before CELLS");
    if (n != r->ncells)
        return as_text_fail(&r->t, "CELL_TYPES: %llu types for %llu cells",
                            (unsigned long long)n, (unsigned long long)r->ncells);
    r->have_types = 1;
    size_t at = 0;
    for (uint64_t i = 0; i < n; i++) {
        int64_t type;
        if ((st = as_text_int(&r->t, 1, "a cell type", &type))) return st;
        int64_t k = r->conn[at];
        if ((type == 5 && k != 3) || (type == 9 && k != 4))
            return as_text_fail(&r->t, "cell %llu: type %lld with %lld points",
                                (unsigned long long)i, (long long)type, (long long)k);
        if ((st = add_cell(r->ctx, r->out, type, r->conn + at + 1, k))) return st;
        at += 1 + (size_t)k;
    }
    return ANISTAR_OK;
}

/* POINT_DATA n / CELL_DATA n. */
static anistar_status vtk_attr_section(vtk_reader *r, int which) {
    uint64_t n;
    anistar_status st = vtk_count(r, "tuple count", &n);
    if (st) return st;
    if (which == 1 && (!r->have_points || n != r->out->nv))
        return as_text_fail(&r->t, "POINT_DATA %llu for %zu points", (unsigned long long)n,
                            r->out->nv);
    r->attr = which;
    r->attr_n = n;
    return ANISTAR_OK;
}

/* One attribute array (SCALARS, VECTORS, TENSORS...) of the current section. */
static anistar_status vtk_attribute(vtk_reader *r, const char *kw, size_t kwlen) {
    anistar_status st;
    char show[32];
    const char *tok, *aname;
    size_t len, alen;
    if (as_token_is(kw, kwlen, "FIELD")) { /* anywhere: each array has its own count */
        uint64_t na;
        as_text_token(&r->t, &tok); /* the field's name */
        if ((st = vtk_count(r, "array count", &na))) return st;
        for (uint64_t a = 0; a < na; a++) {
            uint64_t nc, nt;
            if (!as_text_skip_ws(&r->t)) return as_text_fail(&r->t, "FIELD: the file ends");
            as_text_token(&r->t, &tok);
            if ((st = vtk_count(r, "component count", &nc)) ||
                (st = vtk_count(r, "tuple count", &nt)) || (st = vtk_type(r, "FIELD")))
                return st;
            if (nc > 1024) return as_text_fail(&r->t, "FIELD: %llu components",
                                               (unsigned long long)nc);
            if ((st = vtk_fits(r, "FIELD", nt, nc)) ||
                (st = vtk_skip_numbers(r, "FIELD", nt * nc)))
                return st;
        }
        return ANISTAR_OK;
    }
    if (!r->attr)
        return as_text_fail(&r->t, "unknown keyword '%s' (or an attribute outside POINT_DATA "
                            "and CELL_DATA)", as_token_show(kw, kwlen, show));
    uint64_t n = r->attr_n;
    alen = as_text_token(&r->t, &aname);
    if (alen == 0) return as_text_fail(&r->t, "an attribute without a name");
    int metric_name = as_token_is(aname, alen, "metric");
    if (as_token_is(kw, kwlen, "SCALARS")) {
        int64_t nc = 1;
        if ((st = vtk_type(r, "SCALARS"))) return st;
        if (!as_text_at_eol(&r->t) && (st = as_text_int(&r->t, 0, "a component count", &nc)))
            return st;
        if (nc < 1 || nc > 4)
            return as_text_fail(&r->t, "SCALARS: %lld components (1 to 4)", (long long)nc);
        if (!as_text_skip_ws(&r->t)) return as_text_fail(&r->t, "SCALARS: the file ends");
        len = as_text_token(&r->t, &tok);
        if (!as_token_is(tok, len, "LOOKUP_TABLE"))
            return as_text_fail(&r->t, "SCALARS: expected LOOKUP_TABLE, found '%s'",
                                as_token_show(tok, len, show));
        as_text_token(&r->t, &tok);
        if ((st = vtk_fits(r, "SCALARS", n, (uint64_t)nc))) return st;
        return vtk_skip_numbers(r, "SCALARS", n * (uint64_t)nc);
    }
    if (as_token_is(kw, kwlen, "COLOR_SCALARS")) {
        uint64_t nc;
        if ((st = vtk_count(r, "component count", &nc))) return st;
        if (nc > 1024) return as_text_fail(&r->t, "COLOR_SCALARS: %llu components",
                                           (unsigned long long)nc);
        if ((st = vtk_fits(r, "COLOR_SCALARS", n, nc))) return st;
        return vtk_skip_numbers(r, "COLOR_SCALARS", n * nc);
    }
    if (as_token_is(kw, kwlen, "TEXTURE_COORDINATES")) {
        uint64_t dim;
        if ((st = vtk_count(r, "dimension", &dim)) || (st = vtk_type(r, "TEXTURE_COORDINATES")))
            return st;
        if (dim < 1 || dim > 3) return as_text_fail(&r->t, "TEXTURE_COORDINATES: dimension %llu",
                                                    (unsigned long long)dim);
        if ((st = vtk_fits(r, "TEXTURE_COORDINATES", n, dim))) return st;
        return vtk_skip_numbers(r, "TEXTURE_COORDINATES", n * dim);
    }
    int tensors6 = as_token_is(kw, kwlen, "TENSORS6");
    int per = as_token_is(kw, kwlen, "VECTORS") || as_token_is(kw, kwlen, "NORMALS") ? 3
              : as_token_is(kw, kwlen, "TENSORS")                                ? 9
              : tensors6                                                           ? 6
                                                                                   : 0;
    if (!per)
        return as_text_fail(&r->t, "unknown keyword '%s'", as_token_show(kw, kwlen, show));
    if ((st = vtk_type(r, "an attribute")) || (st = vtk_fits(r, "an attribute", n, (uint64_t)per)))
        return st;
    /* point tensors: the array named "metric", else the first one */
    int take = r->attr == 1 && per >= 6 && (!r->out->tensor || (metric_name && !r->metric_named));
    if (!take) return vtk_skip_numbers(r, "an attribute", n * (uint64_t)per);
    if ((st = as_trimesh_alloc_tensors(r->ctx, r->out))) return st;
    for (uint64_t i = 0; i < n; i++) {
        double f[9];
        for (int k = 0; k < per; k++)
            if ((st = as_text_double(&r->t, 1, "a tensor component", f + k))) return st;
        if (tensors6) { /* VTK's order: XX YY ZZ XY YZ XZ */
            double *o = r->out->tensor + 6 * i;
            o[0] = f[0], o[1] = f[3], o[2] = f[5], o[3] = f[1], o[4] = f[4], o[5] = f[2];
        } else {
            sym6(f, r->out->tensor + 6 * i);
        }
    }
    r->metric_named = metric_name;
    return ANISTAR_OK;
}

/*
 * design: the three header lines; then a keyword loop (keywords are case-insensitive):
 *   DATASET, POINTS, the cell lists, CELL_TYPES, POINT_DATA/CELL_DATA and their arrays;
 *   every count is checked against the bytes left before anything is allocated or
 *   skipped; indices are checked against the point count at the end.
 */
anistar_status as_vtk_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    vtk_reader r;
    memset(&r, 0, sizeof r);
    r.ctx = ctx;
    r.out = out;
    as_text_init(&r.t, ctx, name, data, size, 0);
    anistar_status st = ANISTAR_OK;
    char show[32];
    const char *tok;
    size_t len;
    static const char magic[] = "# vtk DataFile Version";
    if ((size_t)(r.t.end - r.t.p) < sizeof magic - 1 ||
        memcmp(r.t.p, magic, sizeof magic - 1) != 0) {
        st = as_text_fail(&r.t, "not a legacy VTK file (no '# vtk DataFile Version' line)");
        goto done;
    }
    as_text_skip_line(&r.t); /* the version */
    as_text_skip_line(&r.t); /* the title */
    len = as_text_token(&r.t, &tok);
    if (as_token_is(tok, len, "BINARY")) {
        st = as_text_fail(&r.t, "binary legacy VTK is not supported (ASCII only)");
        goto done;
    }
    if (!as_token_is(tok, len, "ASCII")) {
        st = as_text_fail(&r.t, "expected ASCII or BINARY, found '%s'",
                          as_token_show(tok, len, show));
        goto done;
    }
    while (!st && as_text_skip_ws(&r.t)) {
        len = as_text_token(&r.t, &tok);
        if (as_token_is(tok, len, "DATASET")) {
            if (r.kind) {
                st = as_text_fail(&r.t, "a second DATASET");
                break;
            }
            len = as_text_token(&r.t, &tok);
            r.kind = as_token_is(tok, len, "POLYDATA")            ? 1
                     : as_token_is(tok, len, "UNSTRUCTURED_GRID") ? 2
                                                                   : 0;
            if (!r.kind)
                st = as_text_fail(&r.t, "DATASET '%s' is not supported (POLYDATA or "
                                  "UNSTRUCTURED_GRID)", as_token_show(tok, len, show));
            continue;
        }
        if (!r.kind) {
            st = as_text_fail(&r.t, "expected DATASET, found '%s'", as_token_show(tok, len, show));
            break;
        }
        if (as_token_is(tok, len, "POINTS"))
            st = vtk_points(&r);
        else if (r.kind == 1 && as_token_is(tok, len, "POLYGONS"))
            st = vtk_lists(&r, "POLYGONS", 1);
        else if (r.kind == 1 && (as_token_is(tok, len, "VERTICES") ||
                                 as_token_is(tok, len, "LINES") ||
                                 as_token_is(tok, len, "TRIANGLE_STRIPS")))
            st = vtk_lists(&r, "a cell list", 0);
        else if (r.kind == 2 && as_token_is(tok, len, "CELLS"))
            st = vtk_lists(&r, "CELLS", 2);
        else if (r.kind == 2 && as_token_is(tok, len, "CELL_TYPES"))
            st = vtk_cell_types(&r);
        else if (as_token_is(tok, len, "POINT_DATA"))
            st = vtk_attr_section(&r, 1);
        else if (as_token_is(tok, len, "CELL_DATA"))
            st = vtk_attr_section(&r, 2);
        else if (as_token_is(tok, len, "METADATA")) {
            /* VTK 9's information block: lines up to an empty one */
            as_text_skip_line(&r.t);
            while (r.t.p < r.t.end && !as_text_at_eol(&r.t)) as_text_skip_line(&r.t);
        } else
            st = vtk_attribute(&r, tok, len);
    }
    if (!st && r.kind == 2 && !r.have_types)
        st = as_io_fail(ctx, name, r.have_cells ? "CELLS without CELL_TYPES" : "no CELLS");
    if (!st) st = check_indices(ctx, name, out);
done:
    as_free(ctx, r.conn, (r.nconn ? r.nconn : 1) * sizeof *r.conn);
    if (st) as_trimesh_free(ctx, out);
    return st;
}

/* ---- .vtu ------------------------------------------------------------------------------ */

/* The value of attribute `key` in the tag text [p, end) (the text after the tag name, up
 * to its '>'): *val and *len, 1 if found. */
static int xml_attr(const char *p, const char *end, const char *key, const char **val,
                    size_t *len) {
    size_t kl = strlen(key);
    while (p < end) {
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
        const char *k = p;
        while (p < end && *p != '=' && *p != ' ' && *p != '\t' && *p != '\n' && *p != '\r' &&
               *p != '/' && *p != '>')
            p++;
        size_t klen = (size_t)(p - k);
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
        if (p >= end || *p != '=') {
            if (p < end) p++;
            continue;
        }
        p++;
        while (p < end && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
        if (p >= end || (*p != '"' && *p != '\'')) continue;
        char q = *p++;
        const char *v = p;
        while (p < end && *p != q) p++;
        if (p >= end) return 0;
        if (klen == kl && memcmp(k, key, kl) == 0) {
            *val = v;
            *len = (size_t)(p - v);
            return 1;
        }
        p++;
    }
    return 0;
}

static int xml_attr_is(const char *p, const char *end, const char *key, const char *word) {
    const char *v;
    size_t len;
    return xml_attr(p, end, key, &v, &len) && len == strlen(word) && memcmp(v, word, len) == 0;
}

/* An unsigned decimal attribute; -1 if absent, -2 if malformed. */
static int64_t xml_attr_count(const char *p, const char *end, const char *key) {
    const char *v;
    size_t len;
    if (!xml_attr(p, end, key, &v, &len)) return -1;
    if (len == 0 || len > 18) return -2;
    int64_t x = 0;
    for (size_t i = 0; i < len; i++) {
        if (v[i] < '0' || v[i] > '9') return -2;
        x = 10 * x + (v[i] - '0');
    }
    return x;
}

typedef enum vtu_type {
    VT_NONE, VT_I8, VT_U8, VT_I16, VT_U16, VT_I32, VT_U32, VT_I64, VT_U64, VT_F32, VT_F64
} vtu_type;

static vtu_type vtu_type_of(const char *v, size_t len) {
    static const struct {
        const char *name;
        vtu_type t;
    } tab[] = {{"Int8", VT_I8},     {"UInt8", VT_U8},    {"Int16", VT_I16},   {"UInt16", VT_U16},
               {"Int32", VT_I32},   {"UInt32", VT_U32},  {"Int64", VT_I64},   {"UInt64", VT_U64},
               {"Float32", VT_F32}, {"Float64", VT_F64}, {"Char", VT_I8},     {"UChar", VT_U8}};
    for (size_t i = 0; i < sizeof tab / sizeof tab[0]; i++)
        if (len == strlen(tab[i].name) && memcmp(v, tab[i].name, len) == 0) return tab[i].t;
    return VT_NONE;
}

static int vtu_size(vtu_type t) {
    static const int sz[] = {0, 1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
    return sz[t];
}

/* One binary value as a double; *i gets integers exactly (and *ok 0 for a uint64 above
 * INT64_MAX). */
static double vtu_value(const unsigned char *p, vtu_type t, int big, int64_t *i) {
    uint64_t u = as_ld_uint(p, vtu_size(t), big);
    switch (t) {
    case VT_I8: *i = (int8_t)u; break;
    case VT_U8: case VT_U16: case VT_U32: *i = (int64_t)u; break;
    case VT_I16: *i = (int16_t)u; break;
    case VT_I32: *i = (int32_t)u; break;
    case VT_I64: *i = (int64_t)u; break;
    case VT_U64: *i = u > (uint64_t)INT64_MAX ? -1 : (int64_t)u; break;
    case VT_F32: {
        uint32_t w = (uint32_t)u;
        float f;
        memcpy(&f, &w, sizeof f);
        *i = -1;
        return f;
    }
    default: {
        double d;
        memcpy(&d, &u, sizeof d);
        *i = -1;
        return d;
    }
    }
    return (double)*i;
}

static int b64_val(char c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+') return 62;
    if (c == '/') return 63;
    return -1;
}

/* Decode base64 text [p, end) into out (room for 3/4 of the text); whitespace is skipped
 * and '=' padding may end one block and another follow (header and data encoded
 * separately). Returns the byte count, or -1 on a character outside base64. */
static int64_t b64_decode(const char *p, const char *end, unsigned char *out) {
    size_t n = 0;
    uint32_t acc = 0;
    int k = 0;
    for (; p < end; p++) {
        char c = *p;
        if (c == ' ' || c == '\t' || c == '\n' || c == '\r') continue;
        if (c == '=') { /* the end of a block: keep its whole bytes */
            if (k == 2) out[n++] = (unsigned char)(acc >> 4);
            if (k == 3) {
                out[n++] = (unsigned char)(acc >> 10);
                out[n++] = (unsigned char)(acc >> 2);
            }
            k = 0;
            acc = 0;
            continue;
        }
        int v = b64_val(c);
        if (v < 0) return -1;
        acc = acc << 6 | (uint32_t)v;
        if (++k == 4) {
            out[n++] = (unsigned char)(acc >> 16);
            out[n++] = (unsigned char)(acc >> 8);
            out[n++] = (unsigned char)acc;
            k = 0;
            acc = 0;
        }
    }
    if (k == 1) return -1;
    if (k == 2) out[n++] = (unsigned char)(acc >> 4);
    if (k == 3) {
        out[n++] = (unsigned char)(acc >> 10);
        out[n++] = (unsigned char)(acc >> 2);
    }
    return (int64_t)n;
}

typedef struct vtu_reader {
    anistar_context *ctx;
    const char *name;
    int big;        /* byte_order="BigEndian" */
    int header8;    /* header_type="UInt64" */
    double *pts;    /* Points: 3 * npts */
    size_t npts;
    double *metric; /* 9 * nmetric */
    size_t nmetric;
    int64_t *conn, *offs, *types;
    size_t nconn, noffs, ntypes;
} vtu_reader;

static void vtu_reader_free(vtu_reader *r) {
    as_free(r->ctx, r->pts, 3 * r->npts * sizeof(double));
    as_free(r->ctx, r->metric, 9 * r->nmetric * sizeof(double));
    as_free(r->ctx, r->conn, r->nconn * sizeof(int64_t));
    as_free(r->ctx, r->offs, r->noffs * sizeof(int64_t));
    as_free(r->ctx, r->types, r->ntypes * sizeof(int64_t));
}

/*
 * Decode the DataArray whose attributes are [ap, aend) and content [cp, cend) into values:
 * doubles (ints == NULL) or integers (dbl == NULL), ncomp per tuple; allocates *out
 * (doubles or int64) from ctx with *count tuples. what names the array in messages.
 */
static anistar_status vtu_array(vtu_reader *r, const char *what, const char *ap,
                                const char *aend, const char *cp, const char *cend,
                                int ncomp_want, int integer, void **out, size_t *count) {
    const char *v;
    size_t len;
    *out = NULL;
    *count = 0;
    if (!xml_attr(ap, aend, "type", &v, &len))
        return as_io_fail(r->ctx, r->name, "%s: DataArray without a type", what);
    vtu_type t = vtu_type_of(v, len);
    if (t == VT_NONE) return as_io_fail(r->ctx, r->name, "%s: unsupported type", what);
    int64_t nc = xml_attr_count(ap, aend, "NumberOfComponents");
    if (nc == -1) nc = 1;
    if (nc != ncomp_want)
        return as_io_fail(r->ctx, r->name, "%s: %lld components (expected %d)", what,
                          (long long)nc, ncomp_want);
    int binary = xml_attr_is(ap, aend, "format", "binary");
    if (!binary && !xml_attr_is(ap, aend, "format", "ascii"))
        return as_io_fail(r->ctx, r->name, "%s: only format=\"ascii\" or \"binary\" (inline) "
                          "DataArrays are supported", what);
    size_t clen = (size_t)(cend - cp), cap = clen / 2 + 1; /* values: at most clen/2 (ascii) */
    unsigned char *bytes = NULL;
    size_t nvals = 0;
    int64_t nb = 0;
    if (binary) {
        bytes = as_alloc(r->ctx, clen / 4 * 3 + 4);
        if (!bytes) return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->name);
        nb = b64_decode(cp, cend, bytes);
        int hs = r->header8 ? 8 : 4, vs = vtu_size(t);
        uint64_t declared = nb >= hs ? as_ld_uint(bytes, hs, r->big) : 0;
        if (nb < hs || (uint64_t)(nb - hs) < declared || declared % (uint64_t)vs) {
            as_free(r->ctx, bytes, clen / 4 * 3 + 4);
            return as_io_fail(r->ctx, r->name, "%s: bad base64 data (or a header that does not "
                              "match it)", what);
        }
        nvals = (size_t)(declared / (uint64_t)vs);
        cap = nvals ? nvals : 1;
    }
    size_t esz = integer ? sizeof(int64_t) : sizeof(double);
    void *vals = as_alloc_array(r->ctx, cap, esz);
    if (!vals) {
        if (bytes) as_free(r->ctx, bytes, clen / 4 * 3 + 4);
        return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->name);
    }
    anistar_status st = ANISTAR_OK;
    if (binary) {
        int hs = r->header8 ? 8 : 4, vs = vtu_size(t);
        for (size_t i = 0; i < nvals && !st; i++) {
            int64_t iv;
            double d = vtu_value(bytes + hs + i * (size_t)vs, t, r->big, &iv);
            if (integer) {
                if (t == VT_F32 || t == VT_F64 || iv < 0)
                    st = as_io_fail(r->ctx, r->name, "%s: value %zu is not a nonnegative "
                                    "integer", what, i);
                else
                    ((int64_t *)vals)[i] = iv;
            } else {
                if (!isfinite(d))
                    st = as_io_fail(r->ctx, r->name, "%s: value %zu is not finite", what, i);
                ((double *)vals)[i] = d;
            }
        }
        as_free(r->ctx, bytes, clen / 4 * 3 + 4);
    } else {
        /* ascii: the content is NUL-free up to '<', parse numbers one by one */
        const char *p = cp;
        while (!st) {
            while (p < cend && (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')) p++;
            if (p >= cend) break;
            double d;
            size_t used = as_parse_double(p, &d);
            if (used == 0 || (p + used < cend && !(p[used] == ' ' || p[used] == '\t' ||
                                                   p[used] == '\n' || p[used] == '\r'))) {
                st = as_io_fail(r->ctx, r->name, "%s: value %zu is not a number", what, nvals);
                break;
            }
            p += used;
            if (nvals >= cap) { /* cannot happen: each value takes 2 bytes with its blank */
                st = as_io_fail(r->ctx, r->name, "%s: too many values", what);
                break;
            }
            if (integer) {
                if (!(d >= 0 && d < 9007199254740992.0) || d != floor(d))
                    st = as_io_fail(r->ctx, r->name, "%s: value %zu is not a nonnegative "
                                    "integer", what, nvals);
                else
                    ((int64_t *)vals)[nvals] = (int64_t)d;
            } else {
                if (!isfinite(d))
                    st = as_io_fail(r->ctx, r->name, "%s: value %zu is not finite", what, nvals);
                ((double *)vals)[nvals] = d;
            }
            nvals++;
        }
    }
    if (!st && nvals % (size_t)ncomp_want)
        st = as_io_fail(r->ctx, r->name, "%s: %zu values are not a whole number of %d-tuples",
                        what, nvals, ncomp_want);
    if (st) {
        as_free(r->ctx, vals, cap * esz);
        return st;
    }
    /* shrink to the exact size, so that the owner frees count * ncomp elements */
    if (nvals != cap) {
        void *q = as_realloc(r->ctx, vals, cap * esz, (nvals ? nvals : 1) * esz);
        if (!q) {
            as_free(r->ctx, vals, cap * esz);
            return as_fail(r->ctx, ANISTAR_ENOMEM, "%s: out of memory", r->name);
        }
        vals = q;
        if (!nvals) { /* keep one element allocated: free it here, report none */
            as_free(r->ctx, vals, esz);
            vals = NULL;
        }
    }
    *out = vals;
    *count = nvals / (size_t)ncomp_want;
    return ANISTAR_OK;
}

/*
 * design: a minimal XML scan (tags, attributes; comments and declarations skipped; text
 *   only inside DataArray); the arrays of interest are decoded whole (ascii numbers or
 *   base64 with a UInt32/UInt64 byte-count header); then cells -> triangles with
 *   add_cell, offsets checked increasing and within the connectivity.
 */
anistar_status as_vtu_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out) {
    vtu_reader r;
    memset(&r, 0, sizeof r);
    r.ctx = ctx;
    r.name = name;
    anistar_status st = ANISTAR_OK;
    const char *p = data, *end = data + size;
    int seen_file = 0, polydata = 0, pieces = 0;
    enum { S_NONE, S_POINTS, S_CELLS, S_POINTDATA, S_OTHER } sec = S_NONE;
    int64_t npoints = -1, ncells = -1;
    const char *tensors_name = NULL;
    size_t tensors_len = 0;
    while (!st) {
        const char *lt = memchr(p, '<', (size_t)(end - p));
        if (!lt) break;
        p = lt + 1;
        if (p < end && *p == '!') { /* comment or declaration */
            const char *q = (end - p >= 3 && memcmp(p, "!--", 3) == 0) ? strstr(p, "-->") : NULL;
            const char *gt = q ? q + 2 : memchr(p, '>', (size_t)(end - p));
            if (!gt) break;
            p = gt + 1;
            continue;
        }
        if (p < end && *p == '?') {
            const char *gt = memchr(p, '>', (size_t)(end - p));
            if (!gt) break;
            p = gt + 1;
            continue;
        }
        int closing = p < end && *p == '/';
        if (closing) p++;
        const char *tn = p;
        while (p < end && *p != ' ' && *p != '\t' && *p != '\n' && *p != '\r' && *p != '>' &&
               *p != '/')
            p++;
        size_t tl = (size_t)(p - tn);
        const char *gt = memchr(p, '>', (size_t)(end - p));
        if (!gt) {
            st = as_io_fail(ctx, name, "unterminated tag");
            break;
        }
        const char *ap = p, *aend = gt;
        int selfclose = gt > p && gt[-1] == '/';
        p = gt + 1;
#define TAG_IS(s) (tl == sizeof(s) - 1 && memcmp(tn, s, tl) == 0)
        if (!seen_file) {
            if (!TAG_IS("VTKFile") || closing) {
                st = as_io_fail(ctx, name, "not a VTK XML file (no VTKFile element first)");
                break;
            }
            seen_file = 1;
            polydata = xml_attr_is(ap, aend, "type", "PolyData");
            if (!polydata && !xml_attr_is(ap, aend, "type", "UnstructuredGrid")) {
                st = as_io_fail(ctx, name, "only UnstructuredGrid and PolyData VTK XML files "
                                "are supported");
                break;
            }
            r.big = xml_attr_is(ap, aend, "byte_order", "BigEndian");
            r.header8 = xml_attr_is(ap, aend, "header_type", "UInt64");
            const char *v;
            size_t len;
            if (xml_attr(ap, aend, "compressor", &v, &len) && len > 0) {
                st = as_io_fail(ctx, name, "compressed VTK XML data is not supported (anistar "
                                "links no zlib)");
                break;
            }
            continue;
        }
        if (closing) {
            if (TAG_IS("Points") || TAG_IS("Cells") || TAG_IS("Polys") || TAG_IS("PointData") ||
                TAG_IS("CellData") || TAG_IS("Verts") || TAG_IS("Lines") || TAG_IS("Strips") ||
                TAG_IS("FieldData"))
                sec = S_NONE;
            continue;
        }
        if (TAG_IS("Piece")) {
            if (++pieces > 1) {
                st = as_io_fail(ctx, name, "several Pieces are not supported");
                break;
            }
            npoints = xml_attr_count(ap, aend, "NumberOfPoints");
            ncells = xml_attr_count(ap, aend, polydata ? "NumberOfPolys" : "NumberOfCells");
            if (npoints < 0 || (!polydata && ncells < 0)) {
                st = as_io_fail(ctx, name, "Piece without valid NumberOfPoints/NumberOfCells");
                break;
            }
            if (ncells < 0) ncells = 0;
            continue;
        }
        if (TAG_IS("AppendedData")) {
            st = as_io_fail(ctx, name, "appended data is not supported (inline ascii or binary "
                            "DataArrays only)");
            break;
        }
        if (!selfclose) {
            if (TAG_IS("Points")) sec = S_POINTS;
            else if (polydata ? TAG_IS("Polys") : TAG_IS("Cells")) sec = S_CELLS;
            else if (TAG_IS("PointData")) {
                sec = S_POINTDATA;
                const char *v;
                size_t len;
                if (xml_attr(ap, aend, "Tensors", &v, &len)) tensors_name = v, tensors_len = len;
            } else if (TAG_IS("CellData") || TAG_IS("Verts") || TAG_IS("Lines") ||
                       TAG_IS("Strips") || TAG_IS("FieldData") || TAG_IS("Cells") ||
                       TAG_IS("Polys"))
                sec = S_OTHER;
        }
        if (!TAG_IS("DataArray")) continue;
        if (pieces == 0) {
            st = as_io_fail(ctx, name, "DataArray outside a Piece");
            break;
        }
        const char *cp = p, *cend = p;
        if (!selfclose) {
            const char *close = strstr(p, "</DataArray");
            if (!close) {
                st = as_io_fail(ctx, name, "DataArray without </DataArray>");
                break;
            }
            cend = close;
            p = close;
        }
        const char *v;
        size_t len;
        int has_name = xml_attr(ap, aend, "Name", &v, &len);
        void *arr;
        size_t cnt;
        if (sec == S_POINTS) {
            if (r.pts) {
                st = as_io_fail(ctx, name, "a second Points array");
                break;
            }
            st = vtu_array(&r, "Points", ap, aend, cp, cend, 3, 0, &arr, &cnt);
            r.pts = arr, r.npts = cnt;
        } else if (sec == S_CELLS && has_name) {
            int64_t **dst = len == 12 && memcmp(v, "connectivity", 12) == 0 ? &r.conn
                            : len == 7 && memcmp(v, "offsets", 7) == 0      ? &r.offs
                            : len == 5 && memcmp(v, "types", 5) == 0 && !polydata ? &r.types
                                                                                 : NULL;
            if (!dst) continue;
            if (*dst) {
                st = as_io_fail(ctx, name, "a second cell array '%.*s'", (int)len, v);
                break;
            }
            st = vtu_array(&r, "a cell array", ap, aend, cp, cend, 1, 1, &arr, &cnt);
            *dst = arr;
            if (dst == &r.conn) r.nconn = cnt;
            else if (dst == &r.offs) r.noffs = cnt;
            else r.ntypes = cnt;
        } else if (sec == S_POINTDATA && has_name && !r.metric) {
            int nine = xml_attr_count(ap, aend, "NumberOfComponents") == 9;
            int is_metric = (len == 6 && memcmp(v, "metric", 6) == 0) ||
                            (tensors_name && len == tensors_len && memcmp(v, tensors_name, len) == 0);
            if (!nine || !is_metric) continue;
            st = vtu_array(&r, "the metric", ap, aend, cp, cend, 9, 0, &arr, &cnt);
            r.metric = arr, r.nmetric = cnt;
        }
#undef TAG_IS
    }
    if (!st && !seen_file) st = as_io_fail(ctx, name, "not a VTK XML file");
    if (!st && (!r.pts || !r.conn || !r.offs || (!polydata && !r.types)))
        st = as_io_fail(ctx, name, "missing %s", !r.pts ? "Points" : !r.conn ? "connectivity"
                                                 : !r.offs ? "offsets" : "types");
    if (!st && (int64_t)r.npts != npoints)
        st = as_io_fail(ctx, name, "%zu points for NumberOfPoints=%lld", r.npts,
                        (long long)npoints);
    if (!st && ((int64_t)r.noffs != ncells || (!polydata && r.ntypes != r.noffs)))
        st = as_io_fail(ctx, name, "%zu offsets and %zu types for %lld cells", r.noffs,
                        r.ntypes, (long long)ncells);
    if (!st && r.metric && r.nmetric != r.npts)
        st = as_io_fail(ctx, name, "%zu metric tensors for %zu points", r.nmetric, r.npts);
    if (!st && r.npts > AS_TRIMESH_MAX_VERTICES)
        st = as_io_fail(ctx, name, "too many points (%zu)", r.npts);
    if (!st) st = as_trimesh_reserve(ctx, out, r.npts, r.noffs);
    if (!st && r.metric) st = as_trimesh_alloc_tensors(ctx, out);
    if (!st) {
        if (r.npts) memcpy(out->xyz, r.pts, 3 * r.npts * sizeof(double));
        out->nv = r.npts;
        for (size_t i = 0; r.metric && i < r.npts; i++) sym6(r.metric + 9 * i, out->tensor + 6 * i);
        int64_t prev = 0;
        int32_t tmp[64];
        for (size_t c = 0; c < r.noffs && !st; c++) {
            int64_t o = r.offs[c];
            if (o < prev || (uint64_t)o > r.nconn) {
                st = as_io_fail(ctx, name, "cell %zu: offset %lld out of order or beyond the "
                                "connectivity (%zu)", c, (long long)o, r.nconn);
                break;
            }
            int64_t k = o - prev, type = polydata ? -1 : r.types[c];
            if ((type == 5 && k != 3) || (type == 9 && k != 4)) {
                st = as_io_fail(ctx, name, "cell %zu: type %lld with %lld points", c,
                                (long long)type, (long long)k);
                break;
            }
            if ((type == 7 || type == -1) && k > 64) {
                st = as_io_fail(ctx, name, "cell %zu: a polygon of %lld points (at most 64)", c,
                                (long long)k);
                break;
            }
            if (type == 5 || type == 7 || type == 9 || type == -1) {
                for (int64_t j = 0; j < k; j++) {
                    int64_t id = r.conn[prev + j];
                    if (id >= INT32_MAX) {
                        st = as_io_fail(ctx, name, "cell %zu: point index %lld out of range", c,
                                        (long long)id);
                        break;
                    }
                    tmp[j] = (int32_t)id;
                }
                if (!st) st = add_cell(ctx, out, type, tmp, k);
            }
            prev = o;
        }
    }
    if (!st) st = check_indices(ctx, name, out);
    vtu_reader_free(&r);
    if (st) as_trimesh_free(ctx, out);
    return st;
}
