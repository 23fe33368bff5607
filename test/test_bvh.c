/*
 * test_bvh — the AABB tree (lib/geom/bvh.c):
 *  - exact 2D orientations (lifted orient3d) against GMP;
 *  - the exact segment/triangle classification against an independent integer oracle
 *    (1D linear feasibility on barycentric coordinates) on small-integer configurations
 *    full of degeneracies (edges, vertices, endpoints, coplanar segments);
 *  - the symbolically perturbed crossing test against an explicit perturbation
 *    q + (h, h^2, h^3), h = 2^-12, checked by the exact classification;
 *  - tree queries equal brute force: segment hits (random soups, integer soups, closed
 *    meshes), closest point (exact against the library's brute force, 1e-12 relative
 *    against an independent long double computation), box and point queries;
 *  - inside/outside by ray parity on closed meshes against analytic answers: a convex
 *    icosphere (exact face-orientation oracle, |p| < r far from the surface, rays exactly
 *    through vertices), random voxel polycubes and a cube with integer coordinates (rays
 *    along axes and diagonals through vertices, edges and faces, points on the surface),
 *    a torus (analytic far from the surface); the same with the side grid (short segments
 *    to grid nodes; nodes on the surface for the cube), default, coarse and fine;
 *  - the crossing nearest a reference point (through the tree or the grid) against brute
 *    force, bit for bit: random, short and long segments, through vertices, along edges,
 *    between lattice points of polycubes;
 *  - invalid input, allocation-failure injection.
 */
#include "test_util.h"

#include "core.h"
#include "geom/bvh.h"
#include "geom/predicates.h"

#include <gmp.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- meshes ------------------------------------------------------------------------------ */

typedef struct mesh {
    double *xyz;
    int32_t *tri;
    size_t nv, nt, vcap, tcap;
} mesh;

static int32_t mesh_v(mesh *m, double x, double y, double z) {
    if (m->nv == m->vcap) {
        m->vcap = m->vcap ? 2 * m->vcap : 64;
        m->xyz = realloc(m->xyz, 3 * m->vcap * sizeof *m->xyz);
        assert_non_null(m->xyz);
    }
    m->xyz[3 * m->nv] = x;
    m->xyz[3 * m->nv + 1] = y;
    m->xyz[3 * m->nv + 2] = z;
    return (int32_t)m->nv++;
}

static void mesh_t(mesh *m, int32_t a, int32_t b, int32_t c) {
    if (m->nt == m->tcap) {
        m->tcap = m->tcap ? 2 * m->tcap : 64;
        m->tri = realloc(m->tri, 3 * m->tcap * sizeof *m->tri);
        assert_non_null(m->tri);
    }
    m->tri[3 * m->nt] = a;
    m->tri[3 * m->nt + 1] = b;
    m->tri[3 * m->nt + 2] = c;
    m->nt++;
}

static void mesh_free(mesh *m) {
    free(m->xyz);
    free(m->tri);
    memset(m, 0, sizeof *m);
}

static const double *tv(const mesh *m, size_t t, int k) {
    return m->xyz + 3 * (size_t)m->tri[3 * t + k];
}

/* Icosphere of radius r: the icosahedron subdivided `level` times, vertices projected on
 * the sphere. Midpoints are computed symmetrically in their two ends, so the faces of a
 * shared edge use bit-identical vertices (the mesh is geometrically closed). */
static void project(double *p, double r) {
    double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    for (int k = 0; k < 3; k++) p[k] = p[k] / l * r;
}

static void icosphere(mesh *m, int level, double r) {
    const double g = (1 + sqrt(5.0)) / 2;
    double v[12][3] = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                       {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
    static const int f[20][3] = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11},
                                 {1, 5, 9}, {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                 {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8}, {3, 8, 9},
                                 {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    size_t nf = 20;
    double *tris = malloc(20 * 9 * sizeof *tris);
    assert_non_null(tris);
    for (int i = 0; i < 12; i++) project(v[i], r);
    for (int i = 0; i < 20; i++)
        for (int k = 0; k < 3; k++) memcpy(tris + 9 * i + 3 * k, v[f[i][k]], 3 * sizeof(double));
    for (int l = 0; l < level; l++) {
        double *nt = malloc(4 * nf * 9 * sizeof *nt);
        assert_non_null(nt);
        for (size_t i = 0; i < nf; i++) {
            const double *a = tris + 9 * i, *b = a + 3, *c = a + 6;
            double ab[3], bc[3], ca[3];
            for (int k = 0; k < 3; k++) {
                ab[k] = 0.5 * (a[k] + b[k]);
                bc[k] = 0.5 * (b[k] + c[k]);
                ca[k] = 0.5 * (c[k] + a[k]);
            }
            project(ab, r);
            project(bc, r);
            project(ca, r);
            const double *q[4][3] = {{a, ab, ca}, {ab, b, bc}, {ca, bc, c}, {ab, bc, ca}};
            for (int s = 0; s < 4; s++)
                for (int k = 0; k < 3; k++)
                    memcpy(nt + 9 * (4 * i + s) + 3 * k, q[s][k], 3 * sizeof(double));
        }
        free(tris);
        tris = nt;
        nf *= 4;
    }
    for (size_t i = 0; i < nf; i++) {
        int32_t a = mesh_v(m, tris[9 * i], tris[9 * i + 1], tris[9 * i + 2]);
        int32_t b = mesh_v(m, tris[9 * i + 3], tris[9 * i + 4], tris[9 * i + 5]);
        int32_t c = mesh_v(m, tris[9 * i + 6], tris[9 * i + 7], tris[9 * i + 8]);
        mesh_t(m, a, b, c);
    }
    free(tris);
}

/* Torus: major radius R, minor r, nu x nv quads split in two (watertight by index). */
static void torus(mesh *m, double R, double r, int nu, int nv) {
    const double pi = 3.14159265358979323846;
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
            mesh_v(m, (R + r * cos(v)) * cos(u), (R + r * cos(v)) * sin(u), r * sin(v));
        }
    for (int i = 0; i < nu; i++)
        for (int j = 0; j < nv; j++) {
            int32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j;
            int32_t c = ((i + 1) % nu) * nv + (j + 1) % nv, d = i * nv + (j + 1) % nv;
            mesh_t(m, a, b, c);
            mesh_t(m, a, c, d);
        }
}

/* Voxel polycube: G^3 voxels (filled[(x*G + y)*G + z]), voxel (x,y,z) spans
 * s*[x+o, x+o+1] x ...; the boundary faces (filled/empty, outside = empty) are unit
 * squares split along alternating diagonals. Squares are recorded for the oracle. */
typedef struct voxels {
    int G, o, s;
    unsigned char *filled;
    int (*sq)[4]; /* axis, plane m, i, j (voxel units) */
    size_t nsq;
} voxels;

static int vox_at(const voxels *vx, int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= vx->G || y >= vx->G || z >= vx->G) return 0;
    return vx->filled[(x * vx->G + y) * vx->G + z];
}

static void vox_mesh(voxels *vx, mesh *m) {
    int G = vx->G;
    vx->sq = malloc((size_t)3 * (G + 1) * G * G * sizeof *vx->sq);
    assert_non_null(vx->sq);
    vx->nsq = 0;
    for (int k = 0; k < 3; k++)
        for (int pm = 0; pm <= G; pm++)
            for (int i = 0; i < G; i++)
                for (int j = 0; j < G; j++) {
                    int c0[3], c1[3];
                    c0[k] = pm - 1;
                    c1[k] = pm;
                    c0[(k + 1) % 3] = c1[(k + 1) % 3] = i;
                    c0[(k + 2) % 3] = c1[(k + 2) % 3] = j;
                    if (vox_at(vx, c0[0], c0[1], c0[2]) == vox_at(vx, c1[0], c1[1], c1[2]))
                        continue;
                    int *q = vx->sq[vx->nsq++];
                    q[0] = k;
                    q[1] = pm;
                    q[2] = i;
                    q[3] = j;
                    int32_t id[4];
                    for (int c = 0; c < 4; c++) {
                        double p[3];
                        p[k] = vx->s * (pm + vx->o);
                        p[(k + 1) % 3] = vx->s * (i + (c == 1 || c == 2) + vx->o);
                        p[(k + 2) % 3] = vx->s * (j + (c >= 2) + vx->o);
                        id[c] = mesh_v(m, p[0], p[1], p[2]);
                    }
                    if ((i + j + pm) & 1) {
                        mesh_t(m, id[0], id[1], id[2]);
                        mesh_t(m, id[0], id[2], id[3]);
                    } else {
                        mesh_t(m, id[0], id[1], id[3]);
                        mesh_t(m, id[1], id[2], id[3]);
                    }
                }
}

/* Oracle: -1 on the surface, else 1 inside / 0 outside, for a point with integer
 * coordinates (in mesh units). */
static int vox_oracle(const voxels *vx, const long p[3]) {
    for (size_t n = 0; n < vx->nsq; n++) {
        const int *q = vx->sq[n];
        int k = q[0], i = (k + 1) % 3, j = (k + 2) % 3;
        if (p[k] != (long)vx->s * (q[1] + vx->o)) continue;
        if (p[i] < (long)vx->s * (q[2] + vx->o) || p[i] > (long)vx->s * (q[2] + 1 + vx->o)) continue;
        if (p[j] < (long)vx->s * (q[3] + vx->o) || p[j] > (long)vx->s * (q[3] + 1 + vx->o)) continue;
        return -1;
    }
    int c[3];
    for (int k = 0; k < 3; k++) {
        long num = p[k] - (long)vx->s * vx->o; /* s * voxel coordinate */
        long f = num >= 0 ? num / vx->s : -((-num + vx->s - 1) / vx->s);
        c[k] = (int)f;
    }
    return vox_at(vx, c[0], c[1], c[2]);
}

/* ---- independent integer oracle for segment/triangle contact ------------------------------- */

typedef long long ll;

static ll o2i(const ll *a, const ll *b, const ll *c, int i, int j) {
    return (b[i] - a[i]) * (c[j] - a[j]) - (b[j] - a[j]) * (c[i] - a[i]);
}
static ll o3i(const ll *a, const ll *b, const ll *c, const ll *d) {
    ll m[3][3];
    for (int k = 0; k < 3; k++) {
        m[0][k] = a[k] - d[k];
        m[1][k] = b[k] - d[k];
        m[2][k] = c[k] - d[k];
    }
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

/* fraction n/d, d > 0 */
typedef struct frac {
    ll n, d;
} frac;
static int frac_cmp(frac a, frac b) {
    ll l = a.n * b.d, r = b.n * a.d;
    return (l > r) - (l < r);
}
static frac mkfrac(ll n, ll d) {
    frac f = {n, d};
    if (d < 0) {
        f.n = -n;
        f.d = -d;
    }
    return f;
}

/* The kind as_segment_triangle must return, from the set {t in [0,1] : X(t) on the plane,
 * all barycentric coordinates of X(t) >= 0} (affine constraints in t). */
static int oracle_kind(const ll *a, const ll *b, const ll *u, const ll *v, const ll *w) {
    int k = -1;
    ll D = 0;
    for (int kk = 0; kk < 3 && k < 0; kk++) {
        D = o2i(u, v, w, (kk + 1) % 3, (kk + 2) % 3);
        if (D) k = kk;
    }
    if (k < 0) return AS_HIT_NONE; /* degenerate triangle */
    int i = (k + 1) % 3, j = (k + 2) % 3;
    ll sa = o3i(u, v, w, a), sb = o3i(u, v, w, b);
    const ll *e[3][2] = {{v, w}, {w, u}, {u, v}};
    ll al[3], be[3];
    for (int m = 0; m < 3; m++) {
        ll la = o2i(e[m][0], e[m][1], a, i, j), lb = o2i(e[m][0], e[m][1], b, i, j);
        ll sg = D > 0 ? 1 : -1;
        al[m] = sg * la;
        be[m] = sg * (lb - la);
    }
    frac lo = {0, 1}, hi = {1, 1};
    int coplanar = (sa == 0 && sb == 0);
    if (!coplanar) {
        if (sa == sb) return AS_HIT_NONE; /* parallel, off the plane */
        frac ts = mkfrac(sa, sa - sb);  /* sa + t (sb - sa) = 0 */
        if (frac_cmp(ts, lo) < 0 || frac_cmp(ts, hi) > 0) return AS_HIT_NONE;
        lo = hi = ts;
    }
    for (int m = 0; m < 3; m++) { /* al + be t >= 0 */
        if (be[m] == 0) {
            if (al[m] < 0) return AS_HIT_NONE;
        } else if (be[m] > 0) {
            frac f = mkfrac(-al[m], be[m]);
            if (frac_cmp(f, lo) > 0) lo = f;
        } else {
            frac f = mkfrac(-al[m], be[m]);
            if (frac_cmp(f, hi) < 0) hi = f;
        }
    }
    if (frac_cmp(lo, hi) > 0) return AS_HIT_NONE;
    if (coplanar) return AS_HIT_COPLANAR;
    if (sa == 0 || sb == 0) return AS_HIT_ENDPOINT;
    int zeros = 0;
    for (int m = 0; m < 3; m++)
        if (al[m] * lo.d + be[m] * lo.n == 0) zeros++;
    return zeros == 0 ? AS_HIT_PROPER : zeros == 1 ? AS_HIT_EDGE : AS_HIT_VERTEX;
}

static void to_d(const ll *a, double *d) {
    for (int k = 0; k < 3; k++) d[k] = (double)a[k];
}

/* ---- tests: primitives -------------------------------------------------------------------- */

static int exact_o2_sign(const double *a, const double *b, const double *c, int i, int j) {
    mpq_t x, y, t, s;
    mpq_inits(x, y, t, s, NULL);
    mpq_set_d(x, b[i]);
    mpq_set_d(t, a[i]);
    mpq_sub(x, x, t); /* b_i - a_i */
    mpq_set_d(y, c[j]);
    mpq_set_d(t, a[j]);
    mpq_sub(y, y, t); /* c_j - a_j */
    mpq_mul(s, x, y);
    mpq_set_d(x, b[j]);
    mpq_set_d(t, a[j]);
    mpq_sub(x, x, t);
    mpq_set_d(y, c[i]);
    mpq_set_d(t, a[i]);
    mpq_sub(y, y, t);
    mpq_mul(x, x, y);
    mpq_sub(s, s, x);
    int sg = mpq_sgn(s);
    mpq_clears(x, y, t, s, NULL);
    return sg;
}

static void test_orient2d_proj(void **state) {
    (void)state;
    tu_rng r = {21};
    int zeros = 0;
    for (int it = 0; it < 20000; it++) {
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = tu_rng_range(&r, -1, 1);
            b[k] = tu_rng_range(&r, -1, 1);
        }
        double t = tu_rng_range(&r, -2, 2);
        int kind = it % 4;
        for (int k = 0; k < 3; k++) {
            if (kind == 0) c[k] = tu_rng_range(&r, -1, 1);
            else c[k] = a[k] + t * (b[k] - a[k]); /* nearly collinear */
            if (kind == 2) c[k] = a[k] + (double)(it % 7 - 3) * 0.125;
        }
        if (kind == 2) { /* exactly collinear small dyadics */
            b[0] = a[0] + 0.25; b[1] = a[1] + 0.5; b[2] = a[2] - 0.75;
            c[0] = a[0] + 0.5; c[1] = a[1] + 1.0; c[2] = a[2] - 1.5;
        }
        if (kind == 3) { /* huge and tiny magnitudes mixed */
            a[0] *= 1e20; b[0] *= 1e20; c[0] = a[0] + t * (b[0] - a[0]);
            a[1] *= 1e-20; b[1] *= 1e-20; c[1] = a[1] + t * (b[1] - a[1]);
        }
        for (int k = 0; k < 3; k++) {
            int i = (k + 1) % 3, j = (k + 2) % 3;
            double o = as_orient2d_proj(a, b, c, i, j);
            int s = (o > 0) - (o < 0);
            assert_int_equal(s, exact_o2_sign(a, b, c, i, j));
            zeros += s == 0;
        }
    }
    assert_true(zeros > 1000); /* degenerate cases were exercised */
}

/* The classification against the integer oracle, on random small-integer configurations
 * biased towards degeneracies (shared coordinates, points on edges, coplanar segments). */
static void test_segment_triangle_oracle(void **state) {
    (void)state;
    tu_rng r = {31};
    int count[6] = {0};
    for (int it = 0; it < 60000; it++) {
        ll P[5][3];
        int range = 1 + it % 4; /* coordinates in [-range, range] */
        for (int q = 0; q < 5; q++)
            for (int k = 0; k < 3; k++)
                P[q][k] = (ll)(tu_rng_u64(&r) % (uint64_t)(2 * range + 1)) - range;
        /* biases: a segment end on a triangle vertex/edge midpoint (doubled), coplanar */
        switch (it % 7) {
        case 1: /* force the plane z = 0 for the triangle and one end */
            P[2][2] = P[3][2] = P[4][2] = 0;
            P[0][2] = 0;
            break;
        case 2: /* fully coplanar */
            for (int q = 0; q < 5; q++) P[q][2] = 0;
            break;
        case 3: /* segment through a vertex: b = 2u - a */
            for (int k = 0; k < 3; k++) P[1][k] = 2 * P[2][k] - P[0][k];
            break;
        case 4: /* scale triangle by 2 and aim through an edge midpoint */
            for (int q = 2; q < 5; q++)
                for (int k = 0; k < 3; k++) P[q][k] *= 2;
            for (int k = 0; k < 3; k++) P[1][k] = (P[2][k] + P[3][k]) - P[0][k];
            break;
        case 5: /* degenerate triangle (collinear) */
            for (int k = 0; k < 3; k++) P[4][k] = 2 * P[3][k] - P[2][k];
            break;
        default:
            break;
        }
        double d[5][3];
        for (int q = 0; q < 5; q++) to_d(P[q], d[q]);
        double t = -1;
        int got = (int)as_segment_triangle(d[0], d[1], d[2], d[3], d[4], &t);
        int want = oracle_kind(P[0], P[1], P[2], P[3], P[4]);
        if (got != want) fail_msg("iteration %d: kind %d, oracle %d", it, got, want);
        count[got]++;
        if (got != AS_HIT_NONE) {
            assert_true(t >= 0 && t <= 1);
            if (got == AS_HIT_ENDPOINT) assert_true(t == 0 || t == 1);
            if (got == AS_HIT_PROPER || got == AS_HIT_EDGE || got == AS_HIT_VERTEX) {
                /* the float crossing point is close to the exact one (sa / (sa - sb)) */
                ll sa = o3i(P[2], P[3], P[4], P[0]), sb = o3i(P[2], P[3], P[4], P[1]);
                assert_true(fabs(t - (double)sa / (double)(sa - sb)) < 1e-13);
            }
        }
        /* symmetric in the segment's ends (t mirrored) and invariant under a cyclic
         * relabelling of the triangle */
        double t2;
        int got2 = (int)as_segment_triangle(d[1], d[0], d[3], d[4], d[2], &t2);
        assert_int_equal(got2, got);
        if (got != AS_HIT_NONE && got != AS_HIT_COPLANAR) assert_true(fabs(t2 - (1 - t)) < 1e-13);
    }
    for (int k = 0; k < 6; k++) assert_true(count[k] > 100); /* every kind occurred */
}

/* The perturbed test equals the exact test on an explicitly perturbed q. */
static void test_segment_triangle_sos(void **state) {
    (void)state;
    tu_rng r = {41};
    const double h = 0x1p-12;
    int cnt[3] = {0};
    for (int it = 0; it < 40000; it++) {
        double P[5][3];
        for (int q = 0; q < 5; q++)
            for (int k = 0; k < 3; k++) P[q][k] = (double)((int)(tu_rng_u64(&r) % 9) - 4);
        switch (it % 6) {
        case 1: /* p on the triangle's plane */
            P[0][2] = P[2][2] = P[3][2] = P[4][2] = 1;
            break;
        case 2: /* q on the plane */
            P[1][2] = P[2][2] = P[3][2] = P[4][2] = -1;
            break;
        case 3: /* p, q and the triangle coplanar */
            P[0][0] = P[1][0] = P[2][0] = P[3][0] = P[4][0] = 2;
            break;
        case 4: /* through a vertex */
            for (int k = 0; k < 3; k++) P[1][k] = 2 * P[2][k] - P[0][k];
            break;
        case 5: /* p on an edge's line */
            for (int k = 0; k < 3; k++) P[0][k] = 2 * P[3][k] - P[2][k];
            break;
        default:
            break;
        }
        double qq[3] = {P[1][0] + h, P[1][1] + h * h, P[1][2] + h * h * h};
        int s = as_segment_triangle_sos(P[0], P[1], P[2], P[3], P[4]);
        as_seg_hit k = as_segment_triangle(P[0], qq, P[2], P[3], P[4], NULL);
        if (s == 1) {
            if (k != AS_HIT_PROPER) fail_msg("it %d: sos 1, perturbed kind %d", it, (int)k);
        } else if (s == 0) {
            if (k != AS_HIT_NONE) fail_msg("it %d: sos 0, perturbed kind %d", it, (int)k);
        } else {
            assert_int_equal(s, -1);
            if (k != AS_HIT_ENDPOINT && k != AS_HIT_COPLANAR)
                fail_msg("it %d: sos -1, perturbed kind %d", it, (int)k);
            /* p on the closed triangle: the plain test with any q sees p there */
            assert_true(as_segment_triangle(P[0], P[0], P[2], P[3], P[4], NULL) ==
                        AS_HIT_COPLANAR);
        }
        cnt[s + 1]++;
    }
    for (int k = 0; k < 3; k++) assert_true(cnt[k] > 500);
}

/* Independent closest point distance, long double: the plane projection if inside, else
 * the nearest of the three edges. */
static long double ld_seg_d2(const double *p, const double *a, const double *b) {
    long double ab[3], ap[3], dd = 0, t = 0, d2 = 0;
    for (int k = 0; k < 3; k++) {
        ab[k] = (long double)b[k] - a[k];
        ap[k] = (long double)p[k] - a[k];
        dd += ab[k] * ab[k];
        t += ap[k] * ab[k];
    }
    t = dd > 0 ? t / dd : 0;
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    for (int k = 0; k < 3; k++) {
        long double x = ap[k] - t * ab[k];
        d2 += x * x;
    }
    return d2;
}

static long double ld_tri_d2(const double *p, const double *u, const double *v,
                             const double *w) {
    /* The nearest of the three edges; and, when the triangle is not too flat
     * (sin^2 of its angle at u above 1e-12), the projection on its plane if that lies
     * inside (sides tested with the normal n = e0 x e1). */
    long double d = ld_seg_d2(p, u, v), d1 = ld_seg_d2(p, v, w), d2 = ld_seg_d2(p, w, u);
    if (d1 < d) d = d1;
    if (d2 < d) d = d2;
    long double e0[3], e1[3], pu[3], n[3], nn = 0, a00 = 0, a11 = 0, h = 0;
    for (int k = 0; k < 3; k++) {
        e0[k] = (long double)v[k] - u[k];
        e1[k] = (long double)w[k] - u[k];
        pu[k] = (long double)p[k] - u[k];
        a00 += e0[k] * e0[k];
        a11 += e1[k] * e1[k];
    }
    n[0] = e0[1] * e1[2] - e0[2] * e1[1];
    n[1] = e0[2] * e1[0] - e0[0] * e1[2];
    n[2] = e0[0] * e1[1] - e0[1] * e1[0];
    for (int k = 0; k < 3; k++) {
        nn += n[k] * n[k];
        h += pu[k] * n[k];
    }
    if (!(nn > 1e-12L * a00 * a11)) return d;
    long double x[3];
    for (int k = 0; k < 3; k++) x[k] = p[k] - h / nn * n[k]; /* projection */
    const double *t[3] = {u, v, w};
    for (int e = 0; e < 3; e++) {
        const double *a = t[e], *b = t[(e + 1) % 3];
        long double ab[3], ax[3], s = 0;
        for (int k = 0; k < 3; k++) {
            ab[k] = (long double)b[k] - a[k];
            ax[k] = x[k] - a[k];
        }
        s += n[0] * (ab[1] * ax[2] - ab[2] * ax[1]);
        s += n[1] * (ab[2] * ax[0] - ab[0] * ax[2]);
        s += n[2] * (ab[0] * ax[1] - ab[1] * ax[0]);
        if (s < 0) return d;
    }
    long double hp = h * h / nn;
    return hp < d ? hp : d;
}

static void test_closest_on_triangle(void **state) {
    (void)state;
    tu_rng r = {51};
    for (int it = 0; it < 50000; it++) {
        double P[4][3];
        for (int q = 0; q < 4; q++)
            for (int k = 0; k < 3; k++) P[q][k] = tu_rng_range(&r, -1, 1);
        if (it % 10 == 1) memcpy(P[3], P[2], sizeof P[2]);        /* repeated vertex */
        if (it % 10 == 2)                                         /* collinear */
            for (int k = 0; k < 3; k++) P[3][k] = 2 * P[2][k] - P[1][k];
        if (it % 10 == 3) memcpy(P[0], P[1], sizeof P[1]);        /* query = vertex */
        if (it % 10 == 4) { /* flat triangles, sin(angle) from 1e-2 down to 1e-10 */
            double eps = pow(10.0, -2.0 - (double)(it / 10 % 9));
            for (int k = 0; k < 3; k++)
                P[3][k] = 2 * P[2][k] - P[1][k] + eps * tu_rng_range(&r, -1, 1);
        }
        double c[3];
        double d2 = as_closest_on_triangle(P[0], P[1], P[2], P[3], c);
        long double ref = ld_tri_d2(P[0], P[1], P[2], P[3]);
        double dr = sqrt((double)ref), dg = sqrt(d2);
        if (fabs(dg - dr) > 1e-12 * dr + 1e-15) fail_msg("it %d: %.17g vs %.17g", it, dg, dr);
        /* c lies on the triangle: its own distance to it is ~0 */
        double off = sqrt((double)ld_tri_d2(c, P[1], P[2], P[3]));
        if (off > 1e-14) fail_msg("it %d: closest point %.3g off the triangle", it, off);
        double dx = c[0] - P[0][0], dy = c[1] - P[0][1], dz = c[2] - P[0][2];
        assert_true(d2 == (dx * dx + dy * dy) + dz * dz);
    }
}

/* ---- tests: trees ------------------------------------------------------------------------- */

static int hit_cmp(const void *a, const void *b) {
    const as_bvh_hit *x = a, *y = b;
    if (x->t < y->t) return -1;
    if (x->t > y->t) return 1;
    return (x->tri > y->tri) - (x->tri < y->tri);
}

/* as_bvh_segment and as_bvh_segment_count against a loop over every triangle. */
static void check_segment(anistar_context *ctx, const as_bvh *b, const mesh *m,
                          const double *a, const double *c, as_bvh_hits *hits,
                          as_bvh_hit *ref) {
    size_t n = 0, proper = 0;
    for (size_t t = 0; t < m->nt; t++) {
        double par;
        as_seg_hit k = as_segment_triangle(a, c, tv(m, t, 0), tv(m, t, 1), tv(m, t, 2), &par);
        if (k == AS_HIT_NONE) continue;
        ref[n].tri = (int32_t)t;
        ref[n].kind = (int32_t)k;
        ref[n].t = par;
        proper += k == AS_HIT_PROPER;
        n++;
    }
    qsort(ref, n, sizeof *ref, hit_cmp);
    assert_int_equal(as_bvh_segment(ctx, b, a, c, hits), ANISTAR_OK);
    assert_int_equal(hits->n, n);
    for (size_t i = 0; i < n; i++) {
        assert_int_equal(hits->h[i].tri, ref[i].tri);
        assert_int_equal(hits->h[i].kind, ref[i].kind);
        assert_true(hits->h[i].t == ref[i].t);
    }
    size_t pr = 99;
    assert_int_equal(as_bvh_segment_count(b, a, c, &pr), n);
    assert_int_equal(pr, proper);
}

static void check_closest(const as_bvh *b, const mesh *m, const double *p) {
    double c[3];
    int32_t tri = -2;
    double d2 = as_bvh_closest(b, p, c, &tri);
    double best = INFINITY;
    int32_t bt = -1;
    long double ref = INFINITY;
    for (size_t t = 0; t < m->nt; t++) {
        double cc[3];
        double e = as_closest_on_triangle(p, tv(m, t, 0), tv(m, t, 1), tv(m, t, 2), cc);
        if (e < best) {
            best = e;
            bt = (int32_t)t;
        }
        long double l = ld_tri_d2(p, tv(m, t, 0), tv(m, t, 1), tv(m, t, 2));
        if (l < ref) ref = l;
    }
    if (m->nt == 0) {
        assert_true(isinf(d2) && tri == -1);
        return;
    }
    assert_true(d2 == best); /* exact: same per-triangle function, ties to smallest id */
    assert_int_equal(tri, bt);
    double dr = sqrt((double)ref);
    if (fabs(sqrt(d2) - dr) > 1e-12 * dr + 1e-15) fail_msg("closest %.17g vs %.17g", sqrt(d2), dr);
    double dx = c[0] - p[0], dy = c[1] - p[1], dz = c[2] - p[2];
    assert_true(d2 == (dx * dx + dy * dy) + dz * dz);
}

static void check_boxq(anistar_context *ctx, const as_bvh *b, const mesh *m, const double *lo,
                       const double *hi, as_idlist *out) {
    assert_int_equal(as_bvh_query_box(ctx, b, lo, hi, out), ANISTAR_OK);
    size_t n = 0;
    for (size_t t = 0; t < m->nt; t++) {
        int meet = 1;
        for (int k = 0; k < 3; k++) {
            double l = fmin(fmin(tv(m, t, 0)[k], tv(m, t, 1)[k]), tv(m, t, 2)[k]);
            double h = fmax(fmax(tv(m, t, 0)[k], tv(m, t, 1)[k]), tv(m, t, 2)[k]);
            if (h < lo[k] || l > hi[k]) meet = 0;
        }
        if (!meet) continue;
        assert_true(n < out->n);
        assert_int_equal(out->ids[n], (int32_t)t);
        n++;
    }
    assert_int_equal(out->n, n);
}

/* Random soups (continuous and small-integer), every query against brute force. */
static void test_soup_queries(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    tu_rng r = {61};
    as_bvh_hits hits = {0};
    as_idlist ids = {0};
    static const size_t sizes[] = {0, 1, 3, 4, 5, 50, 700};
    for (int integer = 0; integer < 2; integer++)
        for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++) {
            size_t nt = sizes[si];
            mesh m = {0};
            for (size_t t = 0; t < nt; t++) {
                double c[3];
                int32_t id[3];
                for (int k = 0; k < 3; k++) c[k] = tu_rng_range(&r, 0, 1);
                for (int q = 0; q < 3; q++) {
                    double p[3];
                    for (int k = 0; k < 3; k++)
                        p[k] = integer ? (double)(tu_rng_u64(&r) % 7)
                                       : c[k] + tu_rng_range(&r, -0.15, 0.15);
                    id[q] = mesh_v(&m, p[0], p[1], p[2]);
                }
                if (t % 17 == 3) id[2] = id[1]; /* degenerate triangles */
                mesh_t(&m, id[0], id[1], id[2]);
            }
            as_bvh *b = NULL;
            assert_int_equal(as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &b), ANISTAR_OK);
            assert_int_equal(as_bvh_check(ctx, b), 0);
            assert_int_equal(as_bvh_count(b), nt);
            as_bvh_hit *ref = malloc((nt + 1) * sizeof *ref);
            assert_non_null(ref);
            for (int it = 0; it < 150; it++) {
                double a[3], c[3];
                for (int k = 0; k < 3; k++) {
                    a[k] = integer ? (double)(tu_rng_u64(&r) % 9) - 1 : tu_rng_range(&r, -0.2, 1.2);
                    c[k] = integer ? (double)(tu_rng_u64(&r) % 9) - 1 : tu_rng_range(&r, -0.2, 1.2);
                }
                if (it % 5 == 0) c[1] = a[1]; /* axis-parallel in one coordinate */
                if (it % 10 == 0) c[2] = a[2];
                if (it % 25 == 0) memcpy(c, a, sizeof c); /* a point */
                check_segment(ctx, b, &m, a, c, &hits, ref);
                check_closest(b, &m, a);
                double lo[3], hi[3];
                for (int k = 0; k < 3; k++) {
                    lo[k] = fmin(a[k], c[k]);
                    hi[k] = lo[k] + 0.3 * fabs(a[k] - c[k]);
                }
                check_boxq(ctx, b, &m, lo, hi, &ids);
                check_boxq(ctx, b, &m, a, a, &ids);
                assert_int_equal(as_bvh_query_point(ctx, b, a, &ids), ANISTAR_OK);
            }
            free(ref);
            as_bvh_free(ctx, b);
            mesh_free(&m);
        }
    as_bvh_hits_free(ctx, &hits);
    as_idlist_free(ctx, &ids);
    anistar_context_free(ctx);
}

/* Convex polyhedron oracle: 1 inside, 0 outside, -1 on the boundary (exact). */
/* as_bvh_segment_nearest against brute force: the least (|x - ref|^2, t, triangle id) over
 * every triangle the segment meets, x computed as the function documents. */
static void check_nearest(const as_bvh *b, const mesh *m, const double *a, const double *c,
                          const double *ref) {
    double best = INFINITY, bt = 0, bx[3] = {0, 0, 0};
    int32_t btri = -1;
    for (size_t t = 0; t < m->nt; t++) {
        double par;
        if (as_segment_triangle(a, c, tv(m, t, 0), tv(m, t, 1), tv(m, t, 2), &par) ==
            AS_HIT_NONE)
            continue;
        double q[3];
        for (int k = 0; k < 3; k++) q[k] = par == 1 ? c[k] : a[k] + par * (c[k] - a[k]);
        double e0 = q[0] - ref[0], e1 = q[1] - ref[1], e2 = q[2] - ref[2];
        double d2 = e0 * e0 + e1 * e1 + e2 * e2;
        if (d2 < best || (d2 == best && (par < bt || (par == bt && (int32_t)t < btri)))) {
            best = d2;
            bt = par;
            btri = (int32_t)t;
            memcpy(bx, q, sizeof q);
        }
    }
    double x[3] = {7, 7, 7};
    int found = as_bvh_segment_nearest(b, a, c, ref, x);
    assert_int_equal(found, btri >= 0);
    if (found)
        for (int k = 0; k < 3; k++) assert_true(x[k] == bx[k]);
}

/* A point of the line through a and c (parameter s, not necessarily in [0, 1]) moved off
 * it by off in each coordinate: the reference points of the crossing queries. */
static void line_ref(tu_rng *r, const double *a, const double *c, double off, double *ref) {
    double s = tu_rng_range(r, -0.5, 1.5);
    for (int k = 0; k < 3; k++) ref[k] = a[k] + s * (c[k] - a[k]) + off * tu_rng_range(r, -1, 1);
}

/* A second tree over m with the side grid of about max_nodes nodes (0: the default). */
static as_bvh *grid_tree(anistar_context *ctx, const mesh *m, size_t max_nodes) {
    as_bvh *g = NULL;
    assert_int_equal(as_bvh_build_triangles(ctx, m->xyz, m->nv, m->tri, m->nt, &g), ANISTAR_OK);
    assert_int_equal(as_bvh_side_grid(ctx, g, max_nodes), ANISTAR_OK);
    assert_int_equal(as_bvh_side_grid(ctx, g, max_nodes), ANISTAR_OK); /* once only */
    assert_int_equal(as_bvh_check(ctx, g), 0);
    return g;
}

static int convex_oracle(const mesh *m, const double *p) {
    static const double o[3] = {0, 0, 0};
    int on = 0;
    for (size_t t = 0; t < m->nt; t++) {
        double si = as_orient3d(tv(m, t, 0), tv(m, t, 1), tv(m, t, 2), o);
        double sp = as_orient3d(tv(m, t, 0), tv(m, t, 1), tv(m, t, 2), p);
        if (sp == 0) on = 1;
        else if ((sp > 0) != (si > 0)) return 0;
    }
    return on ? -1 : 1;
}

static int side_to_oracle(int side) { return side == 0 ? -1 : side > 0 ? 1 : 0; }

static void test_icosphere(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    const double R = 0.5;
    mesh m = {0};
    icosphere(&m, 3, R);
    assert_int_equal(m.nt, 1280);
    as_bvh *b = NULL;
    assert_int_equal(as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &b), ANISTAR_OK);
    assert_int_equal(as_bvh_check(ctx, b), 0);
    /* the side grid: default, coarse (cells of many triangles) and fine */
    as_bvh *g[3] = {grid_tree(ctx, &m, 0), grid_tree(ctx, &m, 600), grid_tree(ctx, &m, 200000)};
    tu_rng r = {71};
    int seen[3] = {0};
    /* random points: exact convex oracle; far from the surface also |p| < R */
    for (int it = 0; it < 3000; it++) {
        double p[3];
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(&r, -0.8, 0.8);
        int want = convex_oracle(&m, p);
        int got = side_to_oracle(as_bvh_side(b, p));
        assert_int_equal(got, want);
        for (int i = 0; i < 3; i++) assert_int_equal(side_to_oracle(as_bvh_side(g[i], p)), want);
        double l = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if (l < 0.95 * R) assert_int_equal(got, 1);
        if (l > R) assert_int_equal(got, 0);
        seen[want + 1]++;
    }
    /* vertices (on), points next to vertices and edges (exact oracle) */
    for (size_t t = 0; t < m.nt; t += 3) {
        const double *u = tv(&m, t, 0), *v = tv(&m, t, 1);
        assert_int_equal(as_bvh_side(b, u), 0);
        double p[3], q[3], e[3];
        for (int k = 0; k < 3; k++) {
            p[k] = u[k] * (1 + 0x1p-45);
            q[k] = u[k] * (1 - 0x1p-45);
            e[k] = 0.5 * (u[k] + v[k]);
        }
        assert_int_equal(side_to_oracle(as_bvh_side(b, p)), convex_oracle(&m, p));
        assert_int_equal(side_to_oracle(as_bvh_side(b, q)), convex_oracle(&m, q));
        int we = convex_oracle(&m, e);
        assert_int_equal(side_to_oracle(as_bvh_side(b, e)), we);
        for (int i = 0; i < 3; i++) {
            assert_int_equal(as_bvh_side(g[i], u), 0);
            assert_int_equal(side_to_oracle(as_bvh_side(g[i], p)), convex_oracle(&m, p));
            assert_int_equal(side_to_oracle(as_bvh_side(g[i], q)), convex_oracle(&m, q));
            assert_int_equal(side_to_oracle(as_bvh_side(g[i], e)), we);
        }
        seen[we + 1]++;
        /* rays exactly through the vertex u: p = u/2 (inside) to 4u (outside) */
        for (int k = 0; k < 3; k++) {
            p[k] = 0.5 * u[k];
            q[k] = 4 * u[k];
        }
        assert_int_equal(as_bvh_ray_parity(b, p, q), 1);
        assert_int_equal(as_bvh_ray_parity(b, q, p), 1);
        for (int k = 0; k < 3; k++) q[k] = 0.25 * u[k]; /* both inside */
        assert_int_equal(as_bvh_ray_parity(b, p, q), 0);
        /* and the segment hits: the triangles around u, all as VERTEX */
        for (int k = 0; k < 3; k++) q[k] = 4 * u[k];
        as_bvh_hits hits = {0};
        assert_int_equal(as_bvh_segment(ctx, b, p, q, &hits), ANISTAR_OK);
        assert_true(hits.n >= 5);
        for (size_t i = 0; i < hits.n; i++) assert_int_equal(hits.h[i].kind, AS_HIT_VERTEX);
        as_bvh_hits_free(ctx, &hits);
    }
    assert_true(seen[0] > 100 && seen[2] > 100);
    /* segment hits and closest points on the closed mesh against brute force */
    as_bvh_hits hits = {0};
    as_bvh_hit *ref = malloc(m.nt * sizeof *ref);
    assert_non_null(ref);
    for (int it = 0; it < 200; it++) {
        double a[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = tu_rng_range(&r, -0.7, 0.7);
            c[k] = tu_rng_range(&r, -0.7, 0.7);
        }
        check_segment(ctx, b, &m, a, c, &hits, ref);
        /* the crossing nearest a reference point, on the line or off it, and short
         * segments (a few cells of the grids) as well as long ones */
        double rp[3], a2[3], c2[3];
        double f = it % 2 ? 1 : 0.02;
        for (int k = 0; k < 3; k++) {
            a2[k] = a[k];
            c2[k] = a[k] + f * (c[k] - a[k]);
        }
        for (int j = 0; j < 3; j++) {
            line_ref(&r, a2, c2, j == 2 ? 0.01 : 0, rp);
            if (j == 1) memcpy(rp, a2, sizeof rp);
            check_nearest(b, &m, a2, c2, rp);
            for (int i = 0; i < 3; i++) check_nearest(g[i], &m, a2, c2, rp);
        }
        /* closed mesh: the number of proper crossings of a generic segment has the parity
         * of inside(a) xor inside(c) */
        size_t proper;
        size_t all = as_bvh_segment_count(b, a, c, &proper);
        if (all == proper) {
            int ia = convex_oracle(&m, a), ic = convex_oracle(&m, c);
            if (ia >= 0 && ic >= 0) assert_int_equal((int)(proper & 1), ia ^ ic);
        }
        check_closest(b, &m, a);
    }
    /* segments from the center through each vertex (crossings exactly at vertices, met
     * by several triangles) and along edges */
    for (size_t t = 0; t < m.nt; t += 7) {
        const double *u = tv(&m, t, 0), *v = tv(&m, t, 1);
        double a[3] = {0, 0, 0}, c[3], rp[3];
        for (int k = 0; k < 3; k++) c[k] = 2 * u[k];
        line_ref(&r, a, c, 0, rp);
        check_nearest(b, &m, a, c, rp);
        for (int i = 0; i < 3; i++) check_nearest(g[i], &m, a, c, rp);
        for (int k = 0; k < 3; k++) {
            a[k] = 2 * u[k] - v[k];
            c[k] = 2 * v[k] - u[k];
        }
        check_nearest(b, &m, a, c, u);
        for (int i = 0; i < 3; i++) check_nearest(g[i], &m, a, c, u);
    }
    for (int i = 0; i < 3; i++) as_bvh_free(ctx, g[i]);
    free(ref);
    as_bvh_hits_free(ctx, &hits);
    as_bvh_free(ctx, b);
    mesh_free(&m);
    anistar_context_free(ctx);
}

static const long ray_dirs[][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1},
                                   {0, 0, -1}, {1, 1, 0},  {1, 0, 1}, {0, 1, 1},  {1, 1, 1},
                                   {-1, 1, 1}, {2, 1, 0},  {1, 2, 3}, {-1, -1, 0}};

/* Voxel polycubes (and the full cube): exact analytic inside/outside/on, for lattice
 * points and rays along axes and diagonals; integer segment hits against the oracle. */
static void test_voxels(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    tu_rng r = {81};
    as_bvh_hits hits = {0};
    int seen[3] = {0};
    int shapes = 14;
    for (int shape = 0; shape < shapes; shape++) {
        voxels vx;
        vx.G = shape == 0 ? 2 : 4;
        vx.o = -vx.G / 2;
        vx.s = 2;
        vx.filled = malloc((size_t)vx.G * vx.G * vx.G);
        assert_non_null(vx.filled);
        for (int i = 0; i < vx.G * vx.G * vx.G; i++)
            vx.filled[i] = shape == 0 ? 1 : (tu_rng_unit(&r) < 0.5); /* shape 0: a cube */
        mesh m = {0};
        vox_mesh(&vx, &m);
        as_bvh *b = NULL;
        assert_int_equal(as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &b), ANISTAR_OK);
        /* side grids whose nodes fall on the lattice (the cube: on its faces, sides
         * unknown) and off it */
        as_bvh *g[2] = {grid_tree(ctx, &m, 0), grid_tree(ctx, &m, 777)};
        long L = (long)vx.s * (vx.G + 2) * 2;
        long lim = (long)vx.s * (vx.G / 2 + 1);
        for (long x = -lim; x <= lim; x++)
            for (long y = -lim; y <= lim; y++)
                for (long z = -lim; z <= lim; z++) {
                    long p[3] = {x, y, z};
                    int want = vox_oracle(&vx, p);
                    seen[want + 1]++;
                    double pd[3] = {(double)x, (double)y, (double)z};
                    assert_int_equal(side_to_oracle(as_bvh_side(b, pd)), want);
                    for (int i = 0; i < 2; i++)
                        assert_int_equal(side_to_oracle(as_bvh_side(g[i], pd)), want);
                    /* a few rays per point (all for the cube) */
                    int nd = (int)(sizeof ray_dirs / sizeof *ray_dirs);
                    for (int di = 0; di < nd; di++) {
                        if (shape > 0 && (tu_rng_u64(&r) % 5) != 0) continue;
                        double q[3];
                        for (int k = 0; k < 3; k++) q[k] = (double)(p[k] + L * ray_dirs[di][k]);
                        int par = as_bvh_ray_parity(b, pd, q);
                        assert_int_equal(par, want);
                    }
                }
        /* segments between lattice points: every triangle's kind against the oracle */
        for (int it = 0; it < 40; it++) {
            ll a[3], c[3];
            for (int k = 0; k < 3; k++) {
                a[k] = (ll)(tu_rng_u64(&r) % (uint64_t)(2 * lim + 1)) - lim;
                c[k] = (ll)(tu_rng_u64(&r) % (uint64_t)(2 * lim + 1)) - lim;
            }
            if (it % 3 == 0) c[1] = a[1], c[2] = a[2]; /* along x */
            if (it % 3 == 1) c[2] = a[2];              /* in a z plane */
            double ad[3], cd[3];
            to_d(a, ad);
            to_d(c, cd);
            for (int j = 0; j < 3; j++) { /* references: lattice points of the segment's box */
                double rp[3];
                for (int k = 0; k < 3; k++)
                    rp[k] = j == 0 ? ad[k] : j == 1 ? cd[k] : (double)((a[k] + c[k]) / 2);
                check_nearest(b, &m, ad, cd, rp);
                for (int i = 0; i < 2; i++) check_nearest(g[i], &m, ad, cd, rp);
            }
            assert_int_equal(as_bvh_segment(ctx, b, ad, cd, &hits), ANISTAR_OK);
            size_t j = 0;
            for (size_t t = 0; t < m.nt; t++) {
                ll U[3], V[3], W[3];
                for (int k = 0; k < 3; k++) {
                    U[k] = (ll)tv(&m, t, 0)[k];
                    V[k] = (ll)tv(&m, t, 1)[k];
                    W[k] = (ll)tv(&m, t, 2)[k];
                }
                int want = oracle_kind(a, c, U, V, W);
                int got = AS_HIT_NONE;
                for (size_t i = 0; i < hits.n; i++)
                    if (hits.h[i].tri == (int32_t)t) got = hits.h[i].kind;
                assert_int_equal(got, want);
                j += want != AS_HIT_NONE;
            }
            assert_int_equal(hits.n, j);
        }
        for (int i = 0; i < 2; i++) as_bvh_free(ctx, g[i]);
        as_bvh_free(ctx, b);
        mesh_free(&m);
        free(vx.filled);
        free(vx.sq);
    }
    assert_true(seen[0] > 1000 && seen[1] > 1000 && seen[2] > 1000);
    as_bvh_hits_free(ctx, &hits);
    anistar_context_free(ctx);
}

/* A torus (not convex): far from the surface the side is the analytic one. */
static void test_torus(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    mesh m = {0};
    const double R = 1, rr = 0.4;
    torus(&m, R, rr, 64, 32);
    as_bvh *b = NULL;
    assert_int_equal(as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &b), ANISTAR_OK);
    assert_int_equal(as_bvh_check(ctx, b), 0);
    as_bvh *g = grid_tree(ctx, &m, 0);
    tu_rng r = {91};
    int n_in = 0, n_out = 0;
    for (int it = 0; it < 4000; it++) {
        double p[3];
        for (int k = 0; k < 2; k++) p[k] = tu_rng_range(&r, -1.6, 1.6);
        p[2] = tu_rng_range(&r, -0.6, 0.6);
        double dist = sqrt(pow(sqrt(p[0] * p[0] + p[1] * p[1]) - R, 2) + p[2] * p[2]) - rr;
        int s = as_bvh_side(b, p);
        assert_int_equal(as_bvh_side(g, p), s);
        if (it % 8 == 0) { /* a segment through p, the crossing nearest p */
            double c[3];
            for (int k = 0; k < 3; k++) c[k] = p[k] + tu_rng_range(&r, -0.3, 0.3);
            check_nearest(g, &m, p, c, p);
            check_nearest(b, &m, p, c, p);
        }
        if (fabs(dist) < 0.02) continue; /* chords: the polyhedron differs from the torus */
        assert_int_equal(s, dist < 0 ? 1 : -1);
        if (dist < 0) n_in++;
        else n_out++;
        /* any far point gives the same parity */
        double q[3] = {5, tu_rng_range(&r, -9, 9), tu_rng_range(&r, -9, 9)};
        assert_int_equal(as_bvh_ray_parity(b, p, q), dist < 0 ? 1 : 0);
    }
    assert_true(n_in > 500 && n_out > 500);
    as_bvh_free(ctx, g);
    as_bvh_free(ctx, b);
    mesh_free(&m);
    anistar_context_free(ctx);
}

/* A tree over generic boxes: point and box queries against brute force. */
static void test_boxes(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    tu_rng r = {101};
    as_idlist out = {0};
    static const size_t sizes[] = {0, 1, 2, 9, 300, 2000};
    for (size_t si = 0; si < sizeof sizes / sizeof *sizes; si++) {
        size_t n = sizes[si];
        double *bx = malloc((6 * n + 1) * sizeof *bx);
        assert_non_null(bx);
        for (size_t i = 0; i < n; i++)
            for (int k = 0; k < 3; k++) {
                double c = tu_rng_range(&r, 0, 1), h = tu_rng_range(&r, 0, 0.1);
                if (i % 11 == 0) h = 0; /* flat boxes */
                bx[6 * i + k] = c - h;
                bx[6 * i + 3 + k] = c + h;
            }
        as_bvh *b = NULL;
        assert_int_equal(as_bvh_build_boxes(ctx, bx, n, &b), ANISTAR_OK);
        assert_int_equal(as_bvh_check(ctx, b), 0);
        double lo[3], hi[3];
        as_bvh_bounds(b, lo, hi);
        if (n == 0) assert_true(lo[0] > hi[0]);
        for (int it = 0; it < 300; it++) {
            double qlo[3], qhi[3];
            for (int k = 0; k < 3; k++) {
                qlo[k] = tu_rng_range(&r, -0.1, 1.1);
                qhi[k] = qlo[k] + (it % 2 ? 0 : tu_rng_range(&r, 0, 0.2));
            }
            if (n > 0 && it % 7 == 0) /* corners of a stored box */
                for (int k = 0; k < 3; k++) qlo[k] = qhi[k] = bx[6 * (size_t)(it % (int)n) + 3 + k];
            assert_int_equal(as_bvh_query_box(ctx, b, qlo, qhi, &out), ANISTAR_OK);
            size_t m = 0;
            for (size_t i = 0; i < n; i++) {
                int meet = 1;
                for (int k = 0; k < 3; k++)
                    if (bx[6 * i + 3 + k] < qlo[k] || bx[6 * i + k] > qhi[k]) meet = 0;
                if (!meet) continue;
                assert_true(m < out.n);
                assert_int_equal(out.ids[m], (int32_t)i);
                m++;
            }
            assert_int_equal(out.n, m);
        }
        /* triangle queries on a box tree find nothing */
        double p[3] = {0.5, 0.5, 0.5}, q[3] = {2, 2, 2};
        assert_int_equal(as_bvh_segment_count(b, p, q, NULL), 0);
        int32_t tri = 0;
        assert_true(isinf(as_bvh_closest(b, p, NULL, &tri)));
        assert_int_equal(tri, -1);
        as_bvh_free(ctx, b);
        free(bx);
    }
    as_idlist_free(ctx, &out);
    anistar_context_free(ctx);
}

static void test_invalid(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    double xyz[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
    int32_t tri[6] = {0, 1, 2, 0, 1, 3};
    as_bvh *b = (as_bvh *)1;
    tri[5] = 4;
    assert_int_equal(as_bvh_build_triangles(ctx, xyz, 4, tri, 2, &b), ANISTAR_EINVAL);
    assert_null(b);
    tri[5] = -1;
    assert_int_equal(as_bvh_build_triangles(ctx, xyz, 4, tri, 2, &b), ANISTAR_EINVAL);
    tri[5] = 3;
    xyz[10] = NAN;
    assert_int_equal(as_bvh_build_triangles(ctx, xyz, 4, tri, 2, &b), ANISTAR_EINVAL);
    xyz[10] = 0;
    assert_int_equal(as_bvh_build_triangles(ctx, xyz, 4, tri, 2, &b), ANISTAR_OK);
    as_bvh_free(ctx, b);
    double bx[6] = {0, 0, 0, 1, -1, 1};
    assert_int_equal(as_bvh_build_boxes(ctx, bx, 1, &b), ANISTAR_EINVAL);
    bx[4] = INFINITY;
    assert_int_equal(as_bvh_build_boxes(ctx, bx, 1, &b), ANISTAR_EINVAL);
    as_bvh_free(ctx, NULL);
    /* an empty tree: outside everywhere, no hits */
    assert_int_equal(as_bvh_build_triangles(ctx, NULL, 0, NULL, 0, &b), ANISTAR_OK);
    double p[3] = {0, 0, 0};
    assert_int_equal(as_bvh_side(b, p), -1);
    as_bvh_free(ctx, b);
    anistar_context_free(ctx);
}

static void test_alloc_failure(void **state) {
    (void)state;
    tu_alloc ta;
    tu_alloc_init(&ta, -1);
    anistar_allocator al = tu_allocator(&ta);
    anistar_context *ctx = anistar_context_new(&al);
    assert_non_null(ctx);
    long base = ta.live_blocks;
    mesh m = {0};
    icosphere(&m, 2, 1);
    for (int kind = 0; kind < 2; kind++) {
        double *bx = malloc(6 * m.nt * sizeof *bx);
        assert_non_null(bx);
        for (size_t t = 0; t < m.nt; t++)
            for (int k = 0; k < 3; k++) {
                bx[6 * t + k] = fmin(fmin(tv(&m, t, 0)[k], tv(&m, t, 1)[k]), tv(&m, t, 2)[k]);
                bx[6 * t + 3 + k] = fmax(fmax(tv(&m, t, 0)[k], tv(&m, t, 1)[k]), tv(&m, t, 2)[k]);
            }
        int ok = 0;
        for (long f = 0; !ok; f++) {
            as_bvh *b = NULL;
            ta.fail_after = ta.count + f;
            anistar_status st = kind ? as_bvh_build_boxes(ctx, bx, m.nt, &b)
                                     : as_bvh_build_triangles(ctx, m.xyz, m.nv, m.tri, m.nt, &b);
            ta.fail_after = -1;
            if (st == ANISTAR_OK) {
                ok = 1;
                assert_int_equal(as_bvh_check(ctx, b), 0);
                /* output growth failures */
                as_bvh_hits hits = {0};
                as_idlist ids = {0};
                double a[3] = {-2, 0.01, 0.02}, c[3] = {2, 0.03, -0.01};
                double lo[3] = {-2, -2, -2}, hi[3] = {2, 2, 2};
                ta.fail_after = ta.count;
                assert_int_equal(as_bvh_segment(ctx, b, a, c, &hits),
                                 kind ? ANISTAR_OK : ANISTAR_ENOMEM);
                assert_int_equal(as_bvh_query_box(ctx, b, lo, hi, &ids), ANISTAR_ENOMEM);
                assert_int_equal(as_bvh_check(ctx, b), -1);
                ta.fail_after = -1;
                assert_int_equal(as_bvh_segment(ctx, b, a, c, &hits), ANISTAR_OK);
                assert_int_equal(hits.n, kind ? 0u : 2u);
                assert_int_equal(as_bvh_query_box(ctx, b, lo, hi, &ids), ANISTAR_OK);
                assert_int_equal(ids.n, m.nt);
                as_bvh_hits_free(ctx, &hits);
                as_idlist_free(ctx, &ids);
                if (!kind) { /* the side grid: failures leave the tree as it was */
                    double p[3] = {0.1, 0.2, 0.3};
                    for (long g = 0;; g++) {
                        ta.fail_after = ta.count + g;
                        anistar_status sg = as_bvh_side_grid(ctx, b, 0);
                        ta.fail_after = -1;
                        assert_int_equal(as_bvh_side(b, p), 1);
                        if (sg == ANISTAR_OK) break;
                        assert_int_equal(sg, ANISTAR_ENOMEM);
                    }
                    assert_int_equal(as_bvh_side(b, p), 1);
                }
                as_bvh_free(ctx, b);
            } else {
                assert_int_equal(st, ANISTAR_ENOMEM);
                assert_null(b);
            }
            assert_int_equal(ta.live_blocks, base);
        }
        free(bx);
    }
    mesh_free(&m);
    anistar_context_free(ctx);
    assert_int_equal(ta.live_blocks, 0);
    assert_int_equal(ta.live_bytes, 0);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_orient2d_proj),
        cmocka_unit_test(test_segment_triangle_oracle),
        cmocka_unit_test(test_segment_triangle_sos),
        cmocka_unit_test(test_closest_on_triangle),
        cmocka_unit_test(test_soup_queries),
        cmocka_unit_test(test_icosphere),
        cmocka_unit_test(test_voxels),
        cmocka_unit_test(test_torus),
        cmocka_unit_test(test_boxes),
        cmocka_unit_test(test_invalid),
        cmocka_unit_test(test_alloc_failure),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
