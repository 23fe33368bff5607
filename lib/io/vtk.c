/*
 * vtk.c — writers for ParaView: legacy VTK (.vtk, ASCII POLYDATA, version 3.0) and VTK XML
 * unstructured grid (.vtu, version 1.0, UInt64 headers, inline base64 "binary" arrays).
 *
 * Both carry the per-vertex tensors as the point-data tensor "metric" (9 components,
 * row-major full matrix: m11 m12 m13 m12 m22 m23 m13 m23 m33) and each as_cell_field as
 * a scalar cell-data array of Float64. Legacy numbers are written with %.17g, VTU data
 * as little-endian bytes, so both are exact.
 */
#include "io/meshio.h"

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
                    "DATASET POLYDATA\nPOINTS %zu double\n", m->nv);
    for (size_t i = 0; i < m->nv; i++) {
        as_wfile_double(&w, m->xyz[3 * i], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 1], ' ');
        as_wfile_double(&w, m->xyz[3 * i + 2], '\n');
    }
    as_wfile_printf(&w, "POLYGONS %zu %zu\n", m->nt, 4 * m->nt);
    for (size_t i = 0; i < m->nt; i++)
        as_wfile_printf(&w, "3 %ld %ld %ld\n", (long)m->tri[3 * i], (long)m->tri[3 * i + 1],
                        (long)m->tri[3 * i + 2]);
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
