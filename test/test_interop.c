/*
 * test_interop.c — our outputs read back by an independent reader (issue 14): a real mesh
 * (the built-in sphere, coarse: well under a second) is written by anistar_mesh_write as
 * .vtk .vtu .mesh (+ .sol) .meshb (+ .solb) .ply, and python3-meshio (Debian's package,
 * run as /usr/bin/python3) reads them; an embedded script compares points, triangles,
 * the vertex tensors and the cell data with a reference dump written here from the mesh
 * object (%.17g; the tolerance only covers float printing).
 *
 * meshio 5.0 cannot read binary PLY files with per-face properties (its binary reader
 * takes one value per face property for the whole element), so the script reads our
 * .ply with its own header-driven reader (Python's struct, independent of ours), and
 * meshio reads a copy written without the face properties (points, triangles, tensors).
 *
 * When python3 or meshio is missing the test says so and skips: the only allowed skip.
 */
#include "test_util.h"

#include "anistar.h"
#include "core.h"
#include "io/meshio.h"
#include "mesher/mesher.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#define PY "/usr/bin/python3"

/* the script, in pieces (C99 compilers need only support 4095-byte strings) */
static const char *const script[] = {
    "import sys, struct\n"
    "import numpy as np\n"
    "import meshio\n"
    "d = sys.argv[1]\n"
    "ref = {}\n"
    "for line in open(d + '/ref.txt'):\n"
    "    k, *v = line.split()\n"
    "    ref.setdefault(k, []).append([float(x) for x in v])\n"
    "P = np.array(ref['v']); T = np.array(ref['t'], dtype=np.int64)\n"
    "M = np.array(ref['m']); R = np.array(ref['c'])[:, 0]; A = np.array(ref['c'])[:, 1]\n"
    "def close(a, b, what):\n"
    "    a = np.asarray(a, dtype=float); b = np.asarray(b, dtype=float)\n"
    "    if a.shape != b.shape: sys.exit('%s: shape %s != %s' % (what, a.shape, b.shape))\n"
    "    if not np.allclose(a, b, rtol=1e-15, atol=1e-300):\n"
    "        sys.exit('%s: values differ (max %g)' % (what, np.max(np.abs(a - b))))\n"
    "def full(m):\n"
    "    return np.array([[r[0], r[1], r[2], r[1], r[3], r[4], r[2], r[4], r[5]] for r in m])\n"
    "def tris(mesh, what):\n"
    "    if len(mesh.cells) != 1 or mesh.cells[0].type != 'triangle': sys.exit(what + ': cells')\n"
    "    if not np.array_equal(np.asarray(mesh.cells[0].data, dtype=np.int64), T):\n"
    "        sys.exit(what + ': triangles differ')\n"
    "for ext in ['vtk', 'vtu']:\n"
    "    m = meshio.read(d + '/s.' + ext)\n"
    "    close(m.points, P, ext + ' points'); tris(m, ext)\n"
    "    close(np.asarray(m.point_data['metric']).reshape(-1, 9), full(M), ext + ' metric')\n"
    "    close(np.asarray(m.cell_data['radius_edge'][0]).reshape(-1), R, ext + ' radius_edge')\n"
    "    close(np.asarray(m.cell_data['anisotropy'][0]).reshape(-1), A, ext + ' anisotropy')\n"
    ,
    "def medit_sol(path):\n"
    "    tok = open(path).read().split(); i = tok.index('SolAtVertices')\n"
    "    n, nf, ty = int(tok[i + 1]), int(tok[i + 2]), int(tok[i + 3])\n"
    "    assert nf == 1 and ty == 3\n"
    "    v = np.array([float(x) for x in tok[i + 4:i + 4 + 6 * n]]).reshape(n, 6)\n"
    "    return v[:, [0, 1, 3, 2, 4, 5]]\n"
    "def solb(path):\n"
    "    b = open(path, 'rb').read(); assert struct.unpack('<i', b[:4])[0] == 1\n"
    "    ver = struct.unpack('<i', b[4:8])[0]; ps = 8 if ver >= 3 else 4; isz = 8 if ver == 4 else 4\n"
    "    p = 8\n"
    "    while True:\n"
    "        kw = struct.unpack('<i', b[p:p + 4])[0]; nxt = int.from_bytes(b[p + 4:p + 4 + ps], 'little')\n"
    "        if kw == 62:\n"
    "            q = p + 4 + ps; n = int.from_bytes(b[q:q + isz], 'little'); q += isz\n"
    "            assert struct.unpack('<ii', b[q:q + 8]) == (1, 3); q += 8\n"
    "            v = np.frombuffer(b[q:q + 48 * n], dtype='<f8').reshape(n, 6)\n"
    "            return v[:, [0, 1, 3, 2, 4, 5]]\n"
    "        p = nxt\n"
    "for ext, solext, sol in [('mesh', 'sol', medit_sol), ('meshb', 'solb', solb)]:\n"
    "    m = meshio.read(d + '/s.' + ext)\n"
    "    close(m.points, P, ext + ' points'); tris(m, ext)\n"
    "    close(sol(d + '/s.' + solext), M, solext + ' tensors')\n"
    "m = meshio.read(d + '/plain.ply')\n"
    "close(m.points, P, 'plain.ply points'); tris(m, 'plain.ply')\n"
    "close(np.column_stack([m.point_data[k] for k in ['m11','m12','m13','m22','m23','m33']]), M,\n"
    "      'plain.ply tensors')\n"
    ,
    "b = open(d + '/s.ply', 'rb').read(); h = b.index(b'end_header\\n') + 11\n"
    "head = b[:h].decode().split('\\n'); props = {'vertex': [], 'face': []}; el = None\n"
    "for line in head:\n"
    "    w = line.split()\n"
    "    if w[:1] == ['element']: el = w[1]; props[el] = []\n"
    "    if w[:1] == ['property']: props[el].append(w[1:])\n"
    "assert 'format binary_little_endian 1.0' in head\n"
    "vn = [p[-1] for p in props['vertex']]; assert all(p[0] == 'double' for p in props['vertex'])\n"
    "nv, nt = len(P), len(T); p = h\n"
    "V = np.frombuffer(b[p:p + 8 * len(vn) * nv], dtype='<f8').reshape(nv, len(vn)); p += 8 * len(vn) * nv\n"
    "close(V[:, :3], P, 'ply points')\n"
    "close(V[:, [vn.index(k) for k in ['m11','m12','m13','m22','m23','m33']]], M, 'ply tensors')\n"
    "fn = [q[-1] for q in props['face']]\n"
    "assert props['face'][0] == ['list', 'uchar', 'int', 'vertex_indices'], props['face']\n"
    "F = {k: [] for k in fn[1:]}; TT = []\n"
    "for i in range(nt):\n"
    "    c = b[p]; TT.append(struct.unpack('<%di' % c, b[p + 1:p + 1 + 4 * c])); p += 1 + 4 * c\n"
    "    for k in fn[1:]: F[k].append(struct.unpack('<d', b[p:p + 8])[0]); p += 8\n"
    "if p != len(b): sys.exit('ply: %d bytes left' % (len(b) - p))\n"
    "if not np.array_equal(np.array(TT), T): sys.exit('ply triangles differ')\n"
    "close(F['radius_edge'], R, 'ply radius_edge'); close(F['anisotropy'], A, 'ply anisotropy')\n"
    "print('interop: %d points, %d triangles: vtk vtu mesh+sol meshb+solb ply agree' % (nv, nt))\n",
    NULL};

static int have_meshio(void) {
    if (access(PY, X_OK) != 0) {
        print_message("SKIP: %s not found (install python3-meshio to run this test)\n", PY);
        return 0;
    }
    if (system(PY " -c 'import meshio, numpy' >/dev/null 2>&1") != 0) {
        print_message("SKIP: %s cannot import meshio (install python3-meshio)\n", PY);
        return 0;
    }
    return 1;
}

static void test_meshio_reads_our_outputs(void **state) {
    (void)state;
    if (!have_meshio()) {
        skip();
        return;
    }
    char dir[64];
    snprintf(dir, sizeof dir, "/tmp/anistar-interop-%ld", (long)getpid());
    assert_int_equal(mkdir(dir, 0700), 0);
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    anistar_surface *s = NULL;
    anistar_metric *mt = NULL;
    anistar_mesher *mr = NULL;
    anistar_mesh *mesh = NULL;
    assert_int_equal(anistar_surface_builtin(ctx, "sphere", &s), ANISTAR_OK);
    assert_int_equal(anistar_metric_from_spec(ctx, s, "curvature", &mt), ANISTAR_OK);
    assert_int_equal(anistar_mesher_new(ctx, s, mt, &mr), ANISTAR_OK);
    assert_int_equal(anistar_mesher_set(mr, ANISTAR_PARAM_R0, 0.5), ANISTAR_OK);
    assert_int_equal(anistar_mesher_run(mr, &mesh), ANISTAR_OK);
    const as_trimesh *tm = &mesh->tm;
    assert_true(tm->nt > 20 && tm->tensor && mesh->nrho == tm->nt);
    static const char *const outs[] = {"s.vtk", "s.vtu", "s.mesh", "s.sol",
                                       "s.meshb", "s.solb", "s.ply"};
    char path[160];
    for (size_t i = 0; i < sizeof outs / sizeof outs[0]; i++) {
        snprintf(path, sizeof path, "%s/%s", dir, outs[i]);
        assert_int_equal(anistar_mesh_write(ctx, mesh, path), ANISTAR_OK);
    }
    snprintf(path, sizeof path, "%s/plain.ply", dir);
    assert_int_equal(as_mesh_write(ctx, path, tm, NULL, 0), ANISTAR_OK);
    /* the reference: the mesh object's own arrays, and the anisotropy as the API computes
     * it (anistar_triangle_values) */
    double *aniso = malloc(tm->nt * sizeof *aniso);
    assert_non_null(aniso);
    assert_int_equal(anistar_triangle_values(ctx, ANISTAR_COLOR_ANISOTROPY, tm->nv, tm->xyz,
                                             tm->nt, tm->tri, tm->tensor, aniso),
                     ANISTAR_OK);
    snprintf(path, sizeof path, "%s/ref.txt", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    for (size_t i = 0; i < tm->nv; i++) {
        const double *p = tm->xyz + 3 * i, *m = tm->tensor + 6 * i;
        fprintf(f, "v %.17g %.17g %.17g\nm %.17g %.17g %.17g %.17g %.17g %.17g\n", p[0], p[1],
                p[2], m[0], m[1], m[2], m[3], m[4], m[5]);
    }
    for (size_t i = 0; i < tm->nt; i++) {
        assert_true(mesh->rho[i] >= 1 / sqrt(3.0) - 1e-12 && mesh->rho[i] < 10);
        assert_true(aniso[i] >= 1);
        fprintf(f, "t %d %d %d\nc %.17g %.17g\n", (int)tm->tri[3 * i], (int)tm->tri[3 * i + 1],
                (int)tm->tri[3 * i + 2], mesh->rho[i], aniso[i]);
    }
    assert_int_equal(fclose(f), 0);
    snprintf(path, sizeof path, "%s/check.py", dir);
    f = fopen(path, "w");
    assert_non_null(f);
    for (size_t i = 0; script[i]; i++) fputs(script[i], f);
    assert_int_equal(fclose(f), 0);
    char cmd[400];
    snprintf(cmd, sizeof cmd, PY " %s/check.py %s 2>&1", dir, dir);
    int rc = system(cmd);
    free(aniso);
    anistar_mesh_free(mesh);
    anistar_mesher_free(mr);
    anistar_metric_free(mt);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    assert_int_equal(system(cmd), 0);
    assert_int_equal(rc, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {cmocka_unit_test(test_meshio_reads_our_outputs)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
