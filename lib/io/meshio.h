/*
 * meshio.h — internal: triangle-mesh files to and from plain arrays (DESIGN.md 1, the io
 * layer). Knows nothing of surfaces, metrics or meshing: a mesh here is arrays of
 * coordinates, 0-based triangle indices and (optionally) per-vertex tensors.
 *
 * Readers and writers (by extension, case-insensitive): .off .obj .ply .stl .mesh .meshb
 * .vtk (legacy, ASCII) .vtu (XML), and .sol .solb for per-vertex tensors. .vtk and .vtu
 * carry the per-vertex tensors as a 9-component "metric" point tensor and per-triangle
 * scalars as cell data; .ply carries them as vertex properties m11..m33 and face
 * properties.
 *
 * Errors (all functions):
 *   ANISTAR_EIO      the file cannot be opened, read or written ("cannot open 'x.off':
 *                    No such file or directory");
 *   ANISTAR_EFORMAT  the content is malformed or unsupported; text formats name the line
 *                    ("x.off:12: face 3: vertex index 162 out of range [0, 162)");
 *   ANISTAR_ENOMEM   an allocation through the context failed;
 *   ANISTAR_EINVAL   a writer was given an invalid mesh (index out of range, NaN...).
 * A failed reader leaves its output mesh empty (nothing to free beyond as_trimesh_free).
 *
 * Hostile input: no reader allocates from a count found in a file before checking that
 * the rest of the file can hold that many records, so memory stays within a small
 * multiple of the file size; every loop consumes input, so none can hang; coordinates
 * must be finite (NaN, inf, 1e999 are EFORMAT).
 *
 * Tensors are 6 doubles m11 m12 m13 m22 m23 m33 (the public order); Medit's .sol order
 * m11 m12 m22 m13 m23 m33 is converted on the way in and out.
 *
 * The second half of this header (helpers shared by the readers and writers of lib/io)
 * is for the files of lib/io only.
 */
#ifndef ANISTAR_MESHIO_H
#define ANISTAR_MESHIO_H

#include "core.h"
#include "mesh/trimesh.h"

#include <stdint.h>
#include <stdio.h>

/* ==================================================================================== */
/* Reading and writing by extension                                                     */
/* ==================================================================================== */

typedef enum as_mesh_format {
    AS_FMT_UNKNOWN = 0,
    AS_FMT_OFF,
    AS_FMT_OBJ,
    AS_FMT_PLY,
    AS_FMT_STL,
    AS_FMT_MESH, /* Medit .mesh (ASCII) */
    AS_FMT_SOL,  /* Medit .sol (ASCII): per-vertex tensors */
    AS_FMT_VTK,  /* legacy VTK (ASCII; UNSTRUCTURED_GRID written, POLYDATA read too) */
    AS_FMT_VTU,  /* VTK XML unstructured grid */
    AS_FMT_MESHB, /* GMF binary .meshb (libMeshb, versions 1-4) */
    AS_FMT_SOLB   /* GMF binary .solb: per-vertex tensors */
} as_mesh_format;

/* The format named by the extension of path (case-insensitive), AS_FMT_UNKNOWN if none. */
as_mesh_format as_mesh_format_of(const char *path);

/*
 * Read the triangle mesh in the file path (.off .obj .ply .stl .mesh .meshb .vtk .vtu),
 * choosing the reader by extension. *out must be empty (as_trimesh_init); on success it
 * holds the mesh (nv >= 1, nt >= 1, every index in [0, nv), finite coordinates), on
 * failure it is empty. PLY files whose vertices carry the six properties m11 m12 m13 m22
 * m23 m33, and VTK files with a point tensor (the one named "metric", else the first),
 * also fill out->tensor.
 * Notes: STL vertices are welded by exact coordinate equality (first occurrence order);
 *   polygons are split into fans (v0 vi vi+1); polygons of fewer than 3 vertices are
 *   skipped (their indices are still checked). Validation of the topology is separate
 *   (as_topology_orient, mesh/trimesh.h).
 */
anistar_status as_mesh_read(anistar_context *ctx, const char *path, as_trimesh *out);

/*
 * The same on a buffer already in memory: data[size] must be readable and '\0' (the
 * parsers use it as a sentinel); name is used in messages only.
 */
anistar_status as_mesh_parse(anistar_context *ctx, as_mesh_format fmt, const char *name,
                             const char *data, size_t size, as_trimesh *out);

/* The per-format parsers behind as_mesh_parse (same contract). */
anistar_status as_off_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
anistar_status as_obj_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
anistar_status as_ply_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
anistar_status as_stl_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
anistar_status as_medit_parse(anistar_context *ctx, const char *name, const char *data,
                              size_t size, as_trimesh *out);
/* Legacy VTK, ASCII: DATASET UNSTRUCTURED_GRID (cells of type 5 triangle, 7 polygon and 9
 * quad become triangles; other cell types are skipped) or POLYDATA (POLYGONS; VERTICES,
 * LINES and TRIANGLE_STRIPS skipped); POINT_DATA TENSORS give the tensors; every other
 * attribute (SCALARS, VECTORS, NORMALS, TEXTURE_COORDINATES, FIELD) is skipped. */
anistar_status as_vtk_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
/* VTK XML UnstructuredGrid or PolyData (Polys), DataArrays in ascii or inline binary
 * (base64, UInt32 or UInt64 headers, either byte order, no compression); a 9-component
 * point array "metric" (else the PointData Tensors array) gives the tensors. */
anistar_status as_vtu_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, as_trimesh *out);
/* GMF binary (.meshb): versions 1-4, either byte order (see meshb.c). */
anistar_status as_meshb_parse(anistar_context *ctx, const char *name, const char *data,
                              size_t size, as_trimesh *out);

/*
 * Read per-vertex tensors from a Medit .sol file (SolAtVertices). Type 3 (symmetric
 * tensor, Medit order m11 m12 m22 m13 m23 m33) is converted to m11 m12 m13 m22 m23 m33;
 * type 1 (a scalar size h > 0) becomes the isotropic tensor h^-2 I (MMG's convention).
 * With several solution fields the first tensor field is used, else the first scalar
 * one. On success *tensor holds 6 * *count doubles allocated from ctx (free with
 * as_free(ctx, *tensor, 6 * *count * sizeof(double))); on failure *tensor is NULL.
 * Values must be finite; positive definiteness is the metric layer's business.
 */
anistar_status as_sol_read(anistar_context *ctx, const char *path, size_t *count,
                           double **tensor);
anistar_status as_sol_parse(anistar_context *ctx, const char *name, const char *data,
                            size_t size, size_t *count, double **tensor);
/* The same for the binary .solb (as_sol_read chooses by extension). */
anistar_status as_solb_parse(anistar_context *ctx, const char *name, const char *data,
                             size_t size, size_t *count, double **tensor);
/* Shared by the .sol and .solb readers. as_sol_pick: given the nf field types of a
 * SolAtVertices section (1 scalar, 2 vector, 3 symmetric tensor, 4 matrix), the reals
 * per line (*width), and the offset and type of the field used as the metric (the first
 * tensor, else the first scalar); returns 0, -1 for an unknown type, -2 if there is no
 * scalar or tensor field. as_sol_tensor: the tensor of that field's values s (Medit
 * order for type 3, h for type 1 -> h^-2 I); -1 if h is not positive or overflows. */
int as_sol_pick(const int64_t *types, size_t nf, int *width, int *off, int *type);
int as_sol_tensor(int type, const double *s, double out[6]);
/* Read path with as_sol_read and attach the tensors to m (replacing m->tensor). EFORMAT
 * if the file's vertex count differs from m->nv. */
anistar_status as_trimesh_read_sol(anistar_context *ctx, const char *path, as_trimesh *m);

/* A per-triangle scalar array written as cell data by the VTK writers and as a face
 * property by the PLY writer. */
typedef struct as_cell_field {
    const char *name;     /* [A-Za-z0-9_.-]+, e.g. "quality" */
    const double *values; /* one finite value per triangle */
} as_cell_field;

/*
 * Write m to path, the format chosen by extension:
 *   .off .obj .mesh   text, coordinates with %.17g (exact round trip);
 *   .ply              binary little endian, float64 x y z (+ m11..m33 when m->tensor),
 *                     face list uchar int32 (+ one float64 property per cell field);
 *   .meshb .solb      GMF binary version 2 (version 3 when the file would pass 2 GiB);
 *   .stl              binary (the 80-byte header does not start with "solid"); float32,
 *                     EINVAL if a coordinate does not fit a float;
 *   .sol              the tensors in Medit order (EINVAL if m->tensor is NULL);
 *   .vtk .vtu         geometry, "metric" (9 components) when m->tensor, and the cell
 *                     fields. Formats other than .vtk .vtu .ply ignore the cell fields.
 * EIO (with strerror) if the file cannot be created or a write or the close fails (the
 * partial file is removed); EINVAL for an invalid mesh or field name; EFORMAT for an
 * unknown extension.
 */
anistar_status as_mesh_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                             const as_cell_field *cells, size_t ncells);

/* The per-format writers behind as_mesh_write (m already checked by as_trimesh_check). */
anistar_status as_off_write(anistar_context *ctx, const char *path, const as_trimesh *m);
anistar_status as_obj_write(anistar_context *ctx, const char *path, const as_trimesh *m);
anistar_status as_ply_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells);
anistar_status as_stl_write(anistar_context *ctx, const char *path, const as_trimesh *m);
anistar_status as_medit_write(anistar_context *ctx, const char *path, const as_trimesh *m);
anistar_status as_sol_write(anistar_context *ctx, const char *path, const as_trimesh *m);
anistar_status as_vtk_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells);
anistar_status as_vtu_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                            const as_cell_field *cells, size_t ncells);
/* GMF binary writers of a given version (1: float32 reals, EINVAL if a value does not fit;
 * 2: float64; 3: 64-bit keyword positions; 4: 64-bit integers too), little endian.
 * version 0 picks 2, or 3 when the file would exceed INT32_MAX bytes. */
anistar_status as_meshb_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                              int version);
anistar_status as_solb_write(anistar_context *ctx, const char *path, const as_trimesh *m,
                             int version);

/* ==================================================================================== */
/* Helpers shared by the files of lib/io (not for other layers)                       */
/* ==================================================================================== */

/* Read the whole file: *data (size + 1 bytes from ctx, data[size] == '\0'). EIO with
 * strerror when it cannot be opened or read (a directory gives "Is a directory"). Free
 * with as_file_free. */
anistar_status as_file_read(anistar_context *ctx, const char *path, char **data, size_t *size);
void as_file_free(anistar_context *ctx, char *data, size_t size);

/*
 * Number parsing on a NUL-terminated buffer, locale-independent.
 * as_parse_double: [+-] digits [. digits] [(e|E) [+-] digits] with at least one mantissa
 *   digit, correctly rounded (exact fast path for short numbers, strtod on a
 *   decimal-point-free copy otherwise); also nan, inf, infinity (any case) and MSVC's
 *   1.#INF / 1.#QNAN, which give non-finite values so that callers can say so.
 *   Returns the number of bytes consumed, 0 if s does not start with a number.
 * as_parse_int: [+-] digits; *overflow set when the value does not fit int64_t (then
 *   *out saturates). Returns the bytes consumed, 0 if not an integer.
 */
size_t as_parse_double(const char *s, double *out);
size_t as_parse_int(const char *s, int64_t *out, int *overflow);

/* A cursor over a text buffer (data[size] == '\0') that counts lines for messages. */
typedef struct as_text {
    anistar_context *ctx;
    const char *name; /* file name for messages */
    const char *p;    /* current position */
    const char *end;  /* one past the last byte (*end == '\0') */
    size_t line;      /* 1-based line of p */
    char comment;     /* comment character ('#'), or 0 */
    int continuation; /* 1: backslash-newline is a blank (OBJ) */
} as_text;

/* Start at data (skipping a UTF-8 byte order mark). */
void as_text_init(as_text *t, anistar_context *ctx, const char *name, const char *data,
                  size_t size, char comment);
/* Skip blanks (not newlines) and a comment up to (not including) its newline. */
void as_text_skip_blanks(as_text *t);
/* Skip blanks, comments and newlines; returns 0 at the end of the data, 1 otherwise. */
int as_text_skip_ws(as_text *t);
/* After skipping blanks: 1 at a newline or the end of the data. */
int as_text_at_eol(as_text *t);
/* Skip the rest of the line and its newline. */
void as_text_skip_line(as_text *t);
/* The next token on the current line (after blanks): returns its length (0 at the end
 * of the line) and sets *tok; the cursor moves past it. */
size_t as_text_token(as_text *t, const char **tok);
/* Case-insensitive comparison of a token with a NUL-terminated word. */
int as_token_is(const char *tok, size_t len, const char *word);
/* EFORMAT "name:line: <message>". */
anistar_status as_text_fail(as_text *t, const char *fmt, ...) AS_PRINTF(2, 3);
/* EFORMAT "name: <message>" (for binary formats and whole-file problems). */
anistar_status as_io_fail(anistar_context *ctx, const char *name, const char *fmt, ...)
    AS_PRINTF(3, 4);
/*
 * Read a number / an integer at the cursor. cross_lines: 1 to skip newlines and comments
 * first, 0 to stay on the current line. On failure returns EFORMAT naming `what` and
 * what was found ("x.off:7: vertex 4: expected a coordinate, found 'abc'"; "... found
 * the end of the line"). as_text_double also rejects non-finite values.
 */
anistar_status as_text_double(as_text *t, int cross_lines, const char *what, double *out);
anistar_status as_text_int(as_text *t, int cross_lines, const char *what, int64_t *out);
/* A printable copy of at most 24 bytes of a token for messages (buf of 32 bytes). */
const char *as_token_show(const char *tok, size_t len, char buf[32]);

/*
 * Weld triangle soup: corners holds 9 doubles per triangle (three x y z). Equal
 * coordinates (exactly; -0 == +0) become one vertex, numbered by first occurrence;
 * appends to the empty mesh out. A hash table, O(n) expected.
 */
anistar_status as_weld_soup(anistar_context *ctx, const char *name, const double *corners,
                            size_t nt, as_trimesh *out);

/* Whether the remaining `avail` bytes can hold `count` records of at least `min_bytes`
 * each (the file-size check made before allocating from a count). */
static inline int as_fits(uint64_t count, uint64_t min_bytes, uint64_t avail) {
    if (min_bytes == 0) return 1;
    return count <= avail / min_bytes;
}

/* Little/big-endian loads and stores (byte by byte: any alignment, any host). */
static inline uint32_t as_ld_u32le(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static inline uint64_t as_ld_uint(const unsigned char *p, int nbytes, int big_endian) {
    uint64_t v = 0;
    if (big_endian)
        for (int i = 0; i < nbytes; i++) v = v << 8 | p[i];
    else
        for (int i = nbytes - 1; i >= 0; i--) v = v << 8 | p[i];
    return v;
}
static inline void as_st_le(unsigned char *p, uint64_t v, int nbytes) {
    for (int i = 0; i < nbytes; i++) p[i] = (unsigned char)(v >> (8 * i));
}

/* A file being written: every failure is remembered and reported once at close. */
typedef struct as_wfile {
    anistar_context *ctx;
    const char *path;
    FILE *f;
    int err;     /* errno of the first failure; -1 failure without errno; 0 none */
    char dp[8];  /* the locale's decimal point, replaced by '.' in formatted numbers */
    int created; /* 1 if path did not exist before as_wfile_open (then a failed write may
                    remove it; a pre-existing file, device or link is never removed) */
} as_wfile;

/* NULL if the open stream f is a regular file, otherwise why not ("Is a directory", "not a
 * regular file"). Readers accept only regular files: a device, FIFO or directory (e.g. a
 * hostile image header naming /dev/stdin or /dev/zero as its data file) could block or
 * never end. */
const char *as_not_regular_file(FILE *f);

/* Create/truncate path for writing. EIO "cannot create 'path': ...". */
anistar_status as_wfile_open(anistar_context *ctx, as_wfile *w, const char *path);
/* Give up on a file opened by as_wfile_open: close it and remove it if (and only if) this
 * writer created it. */
void as_wfile_abort(as_wfile *w);
void as_wfile_write(as_wfile *w, const void *p, size_t n);
void as_wfile_puts(as_wfile *w, const char *s);
void as_wfile_printf(as_wfile *w, const char *fmt, ...) AS_PRINTF(2, 3);
/* x with %.17g (shortest exact round trip is not needed: 17 digits always suffice),
 * always with '.' as the decimal point, followed by the character sep (0 for none). */
void as_wfile_double(as_wfile *w, double x, char sep);
/* Close; EIO "cannot write 'path': ..." if anything failed (the file is removed). */
anistar_status as_wfile_close(as_wfile *w);

#endif /* ANISTAR_MESHIO_H */
