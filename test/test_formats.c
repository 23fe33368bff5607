/*
 * test_formats.c — the formats of issue 14 (lib/io/meshb.c, lib/io/vtk.c): GMF binary
 * .meshb/.solb against files laid out by hand here (both byte orders, versions 2 and 4)
 * and against the ASCII .mesh/.sol for every version we write (1-4); the legacy VTK
 * reader on our UNSTRUCTURED_GRID output and on the old POLYDATA form; the VTU reader on
 * our output and on an ascii file; hostile inputs (truncated, huge counts, bad indices,
 * backward keyword positions) fail cleanly.
 */
#include "test_util.h"

#include "core.h"
#include "io/meshio.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

/* ---- a tetrahedron with tensors (values exact in float32, so version 1 is exact) ------- */

static const double tet_xyz[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
static const int32_t tet_tri[12] = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
static const double tet_ten[24] = {1,  0.5, 0.25, 2, 0.125, 3, 4, 0, 0, 4,    0,  4,
                                   2, -0.5, 0,    2, 0,     1, 8, 1, 2, 8.5, -1, 9};

static void tet_mesh(anistar_context *ctx, as_trimesh *m) {
    as_trimesh_init(m);
    assert_int_equal(as_trimesh_set(ctx, m, 4, tet_xyz, 4, tet_tri, tet_ten), ANISTAR_OK);
}

static void tmp_path(char *buf, size_t n, const char *ext) {
    static int k;
    snprintf(buf, n, "/tmp/anistar-formats-%ld-%d.%s", (long)getpid(), k++, ext);
}

static unsigned char *slurp(const char *path, size_t *size) {
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    unsigned char *b = malloc(1 << 20);
    assert_non_null(b);
    *size = fread(b, 1, 1 << 20, f);
    fclose(f);
    return b;
}

static void assert_same_mesh(const as_trimesh *a, const as_trimesh *b, int tensors) {
    assert_int_equal(a->nv, b->nv);
    assert_int_equal(a->nt, b->nt);
    assert_memory_equal(a->xyz, b->xyz, 3 * a->nv * sizeof(double));
    assert_memory_equal(a->tri, b->tri, 3 * a->nt * sizeof(int32_t));
    if (tensors) {
        assert_non_null(a->tensor);
        assert_non_null(b->tensor);
        assert_memory_equal(a->tensor, b->tensor, 6 * a->nv * sizeof(double));
    }
}

/* ---- a GMF file laid out by hand -------------------------------------------------------- */

typedef struct hb {
    unsigned char b[2048];
    size_t n;
    int big, psz, isz, rsz;
} hb;

static void hb_put(hb *h, uint64_t v, int nb) {
    for (int i = 0; i < nb; i++)
        h->b[h->n + (size_t)i] = (unsigned char)(v >> (8 * (h->big ? nb - 1 - i : i)));
    h->n += (size_t)nb;
}
static void hb_real(hb *h, double x) {
    uint64_t u;
    memcpy(&u, &x, 8);
    hb_put(h, u, 8);
}
/* keyword code and the position of the next keyword, which is data_bytes further */
static void hb_kw(hb *h, int code, size_t data_bytes) {
    size_t next = code == 54 ? 0 : h->n + 4 + (size_t)h->psz + data_bytes;
    hb_put(h, (uint64_t)code, 4);
    hb_put(h, next, h->psz);
}

/* The tetrahedron as libMeshb lays it out (version 2: int32 positions and integers,
 * float64 reals; version 4: int64 positions and integers); extra: an unknown keyword
 * (code 200, 12 bytes of junk) that the reader must skip through its position. */
static void hb_tet(hb *h, int version, int big, int extra) {
    memset(h, 0, sizeof *h);
    h->big = big;
    h->psz = version >= 3 ? 8 : 4;
    h->isz = version == 4 ? 8 : 4;
    hb_put(h, 1, 4);
    hb_put(h, (uint64_t)version, 4);
    hb_kw(h, 3, 4);
    hb_put(h, 3, 4);
    if (extra) {
        hb_kw(h, 200, 12);
        for (int i = 0; i < 12; i++) hb_put(h, 0xAB, 1);
    }
    hb_kw(h, 4, (size_t)h->isz + 4 * (24 + (size_t)h->isz));
    hb_put(h, 4, h->isz);
    for (int i = 0; i < 4; i++) {
        for (int k = 0; k < 3; k++) hb_real(h, tet_xyz[3 * i + k]);
        hb_put(h, 0, h->isz);
    }
    hb_kw(h, 6, (size_t)h->isz + 4 * 4 * (size_t)h->isz);
    hb_put(h, 4, h->isz);
    for (int i = 0; i < 4; i++) {
        for (int k = 0; k < 3; k++) hb_put(h, (uint64_t)tet_tri[3 * i + k] + 1, h->isz);
        hb_put(h, 0, h->isz);
    }
    hb_kw(h, 54, 0);
}

static anistar_status parse_meshb(anistar_context *ctx, const hb *h, size_t n, as_trimesh *out) {
    char *buf = malloc(n + 1);
    assert_non_null(buf);
    memcpy(buf, h->b, n);
    buf[n] = '\0';
    as_trimesh_init(out);
    anistar_status st = as_meshb_parse(ctx, "hand.meshb", buf, n, out);
    free(buf);
    return st;
}

static void test_meshb_by_hand(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh ref, m;
    tet_mesh(ctx, &ref);
    hb h;
    static const int cases[4][3] = {{2, 0, 0}, {2, 1, 1}, {4, 1, 0}, {4, 0, 1}};
    for (int c = 0; c < 4; c++) {
        hb_tet(&h, cases[c][0], cases[c][1], cases[c][2]);
        assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_OK);
        assert_same_mesh(&ref, &m, 0);
        as_trimesh_free(ctx, &m);
    }
    /* our writer lays version 2 out byte for byte as the hand-made file */
    hb_tet(&h, 2, 0, 0);
    char path[96];
    tmp_path(path, sizeof path, "meshb");
    as_trimesh plain;
    as_trimesh_init(&plain);
    assert_int_equal(as_trimesh_set(ctx, &plain, 4, tet_xyz, 4, tet_tri, NULL), ANISTAR_OK);
    assert_int_equal(as_mesh_write(ctx, path, &plain, NULL, 0), ANISTAR_OK);
    size_t n;
    unsigned char *b = slurp(path, &n);
    assert_int_equal(n, h.n);
    assert_memory_equal(b, h.b, n);
    free(b);
    remove(path);
    as_trimesh_free(ctx, &plain);
    as_trimesh_free(ctx, &ref);
    anistar_context_free(ctx);
}

static void test_meshb_hostile(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh m;
    hb h;
    /* every truncation fails with a message */
    hb_tet(&h, 4, 1, 1);
    for (size_t n = 0; n < h.n; n++) {
        anistar_status st = parse_meshb(ctx, &h, n, &m);
        if (n == h.n - 12) { /* only End is missing: End is optional, as in .mesh */
            assert_int_equal(st, ANISTAR_OK);
            assert_int_equal(m.nt, 4);
            as_trimesh_free(ctx, &m);
            continue;
        }
        assert_int_not_equal(st, ANISTAR_OK);
        assert_int_equal(m.nv + m.nt, 0);
        assert_true(strlen(anistar_last_error(ctx)) > 10);
    }
    /* a huge vertex count: refused before any allocation */
    hb_tet(&h, 2, 0, 0);
    size_t at = 8 + 12 + 8; /* the Vertices count */
    h.b[at] = 0xff, h.b[at + 1] = 0xff, h.b[at + 2] = 0xff, h.b[at + 3] = 0x7f;
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(ctx), "exceed"));
    /* a vertex index beyond the vertices */
    hb_tet(&h, 2, 0, 0);
    at = 8 + 12 + 12 + 4 * 28 + 12; /* the first index of Triangles */
    h.b[at] = 9;
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(ctx), "out of range"));
    /* a keyword position pointing backwards (would loop) */
    hb_tet(&h, 2, 0, 1);
    at = 8 + 12 + 4; /* the unknown keyword's next position */
    h.b[at] = 8, h.b[at + 1] = 0;
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(ctx), "position"));
    /* a bad code word, an unknown version, a NaN coordinate */
    hb_tet(&h, 2, 0, 0);
    h.b[0] = 2;
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    hb_tet(&h, 2, 0, 0);
    h.b[4] = 5;
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    hb_tet(&h, 2, 0, 0);
    memset(h.b + 8 + 12 + 12, 0xff, 8);
    assert_int_equal(parse_meshb(ctx, &h, h.n, &m), ANISTAR_EFORMAT);
    assert_non_null(strstr(anistar_last_error(ctx), "finite"));
    anistar_context_free(ctx);
}

/* Every version written, read back, equals the ASCII round trip (.mesh and .sol). */
static void test_meshb_solb_versions(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh m, a, b;
    tet_mesh(ctx, &m);
    char pa[96], ps[96], pb[96];
    tmp_path(pa, sizeof pa, "mesh");
    tmp_path(ps, sizeof ps, "sol");
    as_trimesh_init(&a);
    assert_int_equal(as_mesh_write(ctx, pa, &m, NULL, 0), ANISTAR_OK);
    assert_int_equal(as_mesh_write(ctx, ps, &m, NULL, 0), ANISTAR_OK);
    assert_int_equal(as_mesh_read(ctx, pa, &a), ANISTAR_OK);
    assert_int_equal(as_trimesh_read_sol(ctx, ps, &a), ANISTAR_OK);
    assert_same_mesh(&m, &a, 1);
    size_t sizes[5] = {0};
    for (int v = 1; v <= 4; v++) {
        tmp_path(pb, sizeof pb, "meshb");
        assert_int_equal(as_meshb_write(ctx, pb, &m, v), ANISTAR_OK);
        as_trimesh_init(&b);
        assert_int_equal(as_mesh_read(ctx, pb, &b), ANISTAR_OK);
        size_t n;
        free(slurp(pb, &n));
        sizes[v] = n;
        remove(pb);
        tmp_path(pb, sizeof pb, "solb");
        assert_int_equal(as_solb_write(ctx, pb, &m, v), ANISTAR_OK);
        assert_int_equal(as_trimesh_read_sol(ctx, pb, &b), ANISTAR_OK);
        remove(pb);
        assert_same_mesh(&a, &b, 1);
        as_trimesh_free(ctx, &b);
    }
    /* the layouts: 4 V x (3 reals + ref), 4 T x 4 ints, positions, counts */
    assert_int_equal(sizes[1], 8 + 12 + (12 + 4 * 16) + (12 + 64) + 8);
    assert_int_equal(sizes[2], 8 + 12 + (12 + 4 * 28) + (12 + 64) + 8);
    assert_int_equal(sizes[3], 8 + 16 + (16 + 4 * 28) + (16 + 64) + 12);
    assert_int_equal(sizes[4], 8 + 16 + (20 + 4 * 32) + (20 + 128) + 12);
    /* version 1 refuses a value beyond float32 */
    m.xyz[0] = 1e300;
    tmp_path(pb, sizeof pb, "meshb");
    assert_int_equal(as_meshb_write(ctx, pb, &m, 1), ANISTAR_EINVAL);
    assert_int_equal(access(pb, F_OK), -1);
    remove(pa);
    remove(ps);
    as_trimesh_free(ctx, &a);
    as_trimesh_free(ctx, &m);
    anistar_context_free(ctx);
}

/* A .solb by hand: version 3, big endian, two fields (a scalar, then a tensor): the tensor
 * is taken, converted from Medit's order. */
static void test_solb_by_hand(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    hb h;
    memset(&h, 0, sizeof h);
    h.big = 1, h.psz = 8, h.isz = 4;
    hb_put(&h, 1, 4);
    hb_put(&h, 3, 4);
    hb_kw(&h, 3, 4);
    hb_put(&h, 3, 4);
    hb_kw(&h, 62, 4 + 12 + 2 * 7 * 8);
    hb_put(&h, 2, 4);
    hb_put(&h, 2, 4), hb_put(&h, 1, 4), hb_put(&h, 3, 4);
    for (int i = 0; i < 2; i++) {
        hb_real(&h, 0.1); /* the scalar */
        static const double med[6] = {1, 2, 3, 4, 5, 6}; /* m11 m12 m22 m13 m23 m33 */
        for (int k = 0; k < 6; k++) hb_real(&h, med[k] * (i + 1));
    }
    hb_kw(&h, 54, 0);
    char *buf = malloc(h.n + 1);
    memcpy(buf, h.b, h.n);
    buf[h.n] = 0;
    size_t n;
    double *t;
    assert_int_equal(as_solb_parse(ctx, "hand.solb", buf, h.n, &n, &t), ANISTAR_OK);
    assert_int_equal(n, 2);
    static const double want[6] = {1, 2, 4, 3, 5, 6};
    for (int k = 0; k < 6; k++) {
        assert_true(t[k] == want[k]);
        assert_true(t[6 + k] == 2 * want[k]);
    }
    as_free(ctx, t, 12 * sizeof(double));
    /* a vector-only solution cannot be a metric; a truncated one fails */
    buf[8 + 16 + 12 + 8 + 3] = 2, buf[8 + 16 + 12 + 12 + 3] = 2; /* both types */
    assert_int_equal(as_solb_parse(ctx, "hand.solb", buf, h.n, &n, &t), ANISTAR_EFORMAT);
    assert_null(t);
    for (size_t k = 0; k + 1 < h.n; k += 7)
        assert_int_not_equal(as_solb_parse(ctx, "hand.solb", buf, k, &n, &t), ANISTAR_OK);
    free(buf);
    anistar_context_free(ctx);
}

/* ---- VTK --------------------------------------------------------------------------------- */

static anistar_status parse_text(anistar_context *ctx, as_mesh_format f, const char *s,
                                 as_trimesh *out) {
    as_trimesh_init(out);
    return as_mesh_parse(ctx, f, "t", s, strlen(s), out);
}

static void test_vtk_round_trip(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh m, b;
    tet_mesh(ctx, &m);
    double q[4] = {1, 2.5, 3, 4}, an[4] = {1, 1.5, 2, 7};
    as_cell_field cells[2] = {{"radius_edge", q}, {"anisotropy", an}};
    const char *exts[2] = {"vtk", "vtu"};
    for (int e = 0; e < 2; e++) {
        char p[96];
        tmp_path(p, sizeof p, exts[e]);
        assert_int_equal(as_mesh_write(ctx, p, &m, cells, 2), ANISTAR_OK);
        as_trimesh_init(&b);
        assert_int_equal(as_mesh_read(ctx, p, &b), ANISTAR_OK);
        assert_same_mesh(&m, &b, 1);
        as_trimesh_free(ctx, &b);
        size_t n;
        char *txt = (char *)slurp(p, &n);
        if (e == 0) {
            txt[n < 200 ? n : 200] = 0;
            assert_non_null(strstr(txt, "DATASET UNSTRUCTURED_GRID"));
        }
        free(txt);
        remove(p);
    }
    /* the old POLYDATA form (a quad as a polygon: two triangles), with attributes skipped */
    const char *old = "# vtk DataFile Version 3.0\nold\nASCII\nDATASET POLYDATA\n"
                      "FIELD FieldData 1\nTIME 1 1 double\n2.5\n"
                      "POINTS 5 float\n0 0 0 1 0 0 1 1 0 0 1 0 0 0 1\n"
                      "POLYGONS 2 9\n4 0 1 2 3\n3 0 1 4\n"
                      "CELL_DATA 2\nSCALARS quality double 1\nLOOKUP_TABLE default\n1 2\n"
                      "POINT_DATA 5\nVECTORS n float\n0 0 1 0 0 1 0 0 1 0 0 1 0 0 1\n"
                      "TENSORS metric double\n" "1 0 0 0 1 0 0 0 1\n1 0 0 0 1 0 0 0 1\n"
                      "1 0 0 0 1 0 0 0 1\n1 0 0 0 1 0 0 0 1\n2 1 0 1 2 0 0 0 3\n";
    assert_int_equal(parse_text(ctx, AS_FMT_VTK, old, &b), ANISTAR_OK);
    assert_int_equal(b.nv, 5);
    assert_int_equal(b.nt, 3);
    assert_int_equal(b.tri[6], 0);
    assert_int_equal(b.tri[8], 4);
    assert_non_null(b.tensor);
    assert_true(b.tensor[24] == 2 && b.tensor[25] == 1 && b.tensor[29] == 3);
    as_trimesh_free(ctx, &b);
    /* hostile: a huge CELLS size, an index past the points, a cell type that lies, a
     * count past the end, NaN */
    static const char *const bad[] = {
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 double\n"
        "0 0 0 1 0 0 0 1 0\nCELLS 1 4000000000\n3 0 1 2\n",
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 double\n"
        "0 0 0 1 0 0 0 1 0\nCELLS 1 4\n3 0 1 7\nCELL_TYPES 1\n5\n",
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 3 double\n"
        "0 0 0 1 0 0 0 1 0\nCELLS 1 5\n4 0 1 2 0\nCELL_TYPES 1\n5\n",
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 99999999 double\n0 0 0\n",
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 double\n"
        "0 0 nan 1 0 0 0 1 0\nPOLYGONS 1 4\n3 0 1 2\n",
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET POLYDATA\n",
        "# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 double\n"
        "0 0 0 1 0 0 0 1 0\nPOLYGONS 2 4\n3 0 1 2\n"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        assert_int_equal(parse_text(ctx, AS_FMT_VTK, bad[i], &b), ANISTAR_EFORMAT);
        assert_int_equal(b.nv + b.nt, 0);
    }
    as_trimesh_free(ctx, &m);
    anistar_context_free(ctx);
}

static void test_vtu_reader(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_trimesh b;
    /* ascii arrays, UInt32 default header, a quad cell and a line cell (skipped) */
    const char *ok =
        "<?xml version=\"1.0\"?>\n<!-- made by hand -->\n"
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
        "<UnstructuredGrid><Piece NumberOfPoints=\"4\" NumberOfCells=\"2\">\n"
        "<Points><DataArray type=\"Float32\" NumberOfComponents=\"3\" format=\"ascii\">"
        "0 0 0 1 0 0 1 1 0 0 1 0</DataArray></Points>\n"
        "<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">0 1 2 3 0 2"
        "</DataArray>\n<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">4 6"
        "</DataArray>\n<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">9 3"
        "</DataArray></Cells></Piece></UnstructuredGrid></VTKFile>\n";
    assert_int_equal(parse_text(ctx, AS_FMT_VTU, ok, &b), ANISTAR_OK);
    assert_int_equal(b.nv, 4);
    assert_int_equal(b.nt, 2);
    assert_null(b.tensor);
    assert_int_equal(b.tri[3], 0);
    assert_int_equal(b.tri[4], 2);
    assert_int_equal(b.tri[5], 3);
    as_trimesh_free(ctx, &b);
    /* hostile variants of it */
    const char *subst[][2] = {{"4 6</DataArray>", "4 99</DataArray>"},
                              {"0 1 2 3 0 2", "0 1 2 7 0 2"},
                              {"NumberOfPoints=\"4\"", "NumberOfPoints=\"5\""},
                              {"format=\"ascii\">9 3", "format=\"binary\">@@@@"},
                              {"byte_order", "compressor=\"vtkZLibDataCompressor\" byte_order"},
                              {"</Cells>", ""},
                              {"0 0 0 1 0 0", "0 0 0 1 nan 0"}};
    for (size_t i = 0; i < sizeof subst / sizeof subst[0]; i++) {
        char buf[2048];
        const char *at = strstr(ok, subst[i][0]);
        assert_non_null(at);
        snprintf(buf, sizeof buf, "%.*s%s%s", (int)(at - ok), ok, subst[i][1],
                 at + strlen(subst[i][0]));
        anistar_status st = parse_text(ctx, AS_FMT_VTU, buf, &b);
        if (i == 5) { /* no closing tag: still read (the scan does not need it) */
            assert_int_equal(st, ANISTAR_OK);
            as_trimesh_free(ctx, &b);
            continue;
        }
        if (st != ANISTAR_EFORMAT) fail_msg("vtu case %zu: status %d", i, (int)st);
        assert_int_equal(b.nv + b.nt, 0);
    }
    /* every truncation of our binary output fails cleanly or reads the whole mesh */
    as_trimesh m;
    tet_mesh(ctx, &m);
    char p[96];
    tmp_path(p, sizeof p, "vtu");
    assert_int_equal(as_mesh_write(ctx, p, &m, NULL, 0), ANISTAR_OK);
    size_t n;
    char *txt = (char *)slurp(p, &n);
    remove(p);
    for (size_t k = 0; k < n; k += 3) {
        char c = txt[k];
        txt[k] = 0;
        anistar_status st = as_vtu_parse(ctx, "t.vtu", txt, k, &b);
        if (st == ANISTAR_OK) {
            assert_same_mesh(&m, &b, 1);
            as_trimesh_free(ctx, &b);
        }
        txt[k] = c;
    }
    free(txt);
    as_trimesh_free(ctx, &m);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_meshb_by_hand),     cmocka_unit_test(test_meshb_hostile),
        cmocka_unit_test(test_meshb_solb_versions), cmocka_unit_test(test_solb_by_hand),
        cmocka_unit_test(test_vtk_round_trip),    cmocka_unit_test(test_vtu_reader)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
