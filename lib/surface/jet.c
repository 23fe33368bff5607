/*
 * jet.c — jet fitting (Cazals-Pouget) for normals and principal curvatures of sampled
 * surfaces, and the Gaussian blending of per-vertex tensors (paper 5.2.3). See jet.h.
 */
#include "surface/jet.h"

#include "geom/linalg.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

static inline double v3_dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void v3_cross(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline void v3_normalize(double a[3]) {
    double l = sqrt(v3_dot(a, a));
    if (l > 0)
        for (int i = 0; i < 3; i++) a[i] /= l;
}

/* ---- jet fitting ------------------------------------------------------------------ */

/* The monomials x^(t-j) y^j, t = 0..degree, j = 0..t, in coefficient order. */
static void monomials(double x, double y, int degree, double *row) {
    double xp[5] = {1, x, x * x, x * x * x, x * x * x * x};
    double yp[5] = {1, y, y * y, y * y * y, y * y * y * y};
    int c = 0;
    for (int t = 0; t <= degree; t++)
        for (int j = 0; j <= t; j++) row[c++] = xp[t - j] * yp[j];
}

/* PCA frame of the points: w = least-variance axis, u1 = largest, u2 = w x u1. */
static int pca_frame(const double *pts, size_t n, double fr[9]) {
    double c[3] = {0, 0, 0};
    for (size_t i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) c[k] += pts[3 * i + k];
    for (int k = 0; k < 3; k++) c[k] /= (double)n;
    double cov[6] = {0, 0, 0, 0, 0, 0};
    for (size_t i = 0; i < n; i++) {
        double d[3] = {pts[3 * i] - c[0], pts[3 * i + 1] - c[1], pts[3 * i + 2] - c[2]};
        cov[0] += d[0] * d[0];
        cov[1] += d[0] * d[1];
        cov[2] += d[0] * d[2];
        cov[3] += d[1] * d[1];
        cov[4] += d[1] * d[2];
        cov[5] += d[2] * d[2];
    }
    double w[3], v[9];
    if (as_sym3_eigen(cov, w, v)) return -1;
    if (!(w[2] > 0)) return -1; /* all points equal */
    memcpy(fr + 6, v, 3 * sizeof(double)); /* w: smallest eigenvalue */
    memcpy(fr, v + 6, 3 * sizeof(double)); /* u1: largest */
    v3_cross(fr + 6, fr, fr + 3);          /* u2 = w x u1 */
    v3_normalize(fr + 3);
    return 0;
}

/* Eigen-decomposition of the symmetric 2x2 [[a, b], [b, c]]: w1 >= w2 and the unit
 * eigenvector (cs, sn) of w1. */
static void eig2(double a, double b, double c, double *w1, double *w2, double *cs, double *sn) {
    double mean = 0.5 * (a + c), r = hypot(0.5 * (a - c), b);
    double th = 0.5 * atan2(2 * b, a - c);
    *w1 = mean + r;
    *w2 = mean - r;
    *cs = cos(th);
    *sn = sin(th);
}

/* Local vector (frame coordinates) to world. */
static void to_world(const double fr[9], const double l[3], double w[3]) {
    for (int i = 0; i < 3; i++) w[i] = l[0] * fr[i] + l[1] * fr[3 + i] + l[2] * fr[6 + i];
}

int as_jet_fit(const double *pts, size_t n, const double origin[3], int degree,
               const double frame[9], const double orient[3], as_jet *out) {
    memset(out, 0, sizeof *out);
    if (n < 3 || n > AS_JET_MAX_POINTS || degree < 1) return -1;
    if (degree > 4) degree = 4;
    for (size_t i = 0; i < 3 * n; i++)
        if (!isfinite(pts[i])) return -1;
    if (!isfinite(origin[0]) || !isfinite(origin[1]) || !isfinite(origin[2])) return -1;
    /* 1. frame */
    double fr[9];
    if (frame) memcpy(fr, frame, sizeof fr);
    else if (pca_frame(pts, n, fr)) return -1;
    if (orient && v3_dot(fr + 6, orient) < 0)
        for (int i = 3; i < 9; i++) fr[i] = -fr[i]; /* flip w and u2: still right-handed */
    /* 2. local coordinates */
    double loc[3 * AS_JET_MAX_POINTS];
    double h = 0;
    for (size_t i = 0; i < n; i++) {
        double d[3] = {pts[3 * i] - origin[0], pts[3 * i + 1] - origin[1],
                       pts[3 * i + 2] - origin[2]};
        for (int k = 0; k < 3; k++) loc[3 * i + k] = v3_dot(d, fr + 3 * k);
        h = fmax(h, hypot(loc[3 * i], loc[3 * i + 1]));
    }
    if (!(h > 0) || !isfinite(h)) return -1;
    for (size_t i = 0; i < 3 * n; i++) loc[i] /= h;
    /* The points must spread in two directions of the tangent plane: collinear (x, y)
     * make the y-columns rounding noise, which the column equilibration of the least
     * squares would blow up to full rank. */
    double mx = 0, my = 0, cxx = 0, cxy = 0, cyy = 0;
    for (size_t i = 0; i < n; i++) {
        mx += loc[3 * i];
        my += loc[3 * i + 1];
    }
    mx /= (double)n;
    my /= (double)n;
    for (size_t i = 0; i < n; i++) {
        double dx = loc[3 * i] - mx, dy = loc[3 * i + 1] - my;
        cxx += dx * dx;
        cxy += dx * dy;
        cyy += dy * dy;
    }
    double lmin = 0.5 * (cxx + cyy) - hypot(0.5 * (cxx - cyy), cxy);
    if (!(lmin > 1e-12 * (cxx + cyy))) return -1;
    /* 3. least squares, lowering the degree while rank-deficient */
    double a[AS_JET_MAX_POINTS * 15], b[AS_JET_MAX_POINTS], work[AS_JET_MAX_POINTS * 16];
    double x[15];
    while (degree >= 1 && (size_t)as_jet_coef_count(degree) > n) degree--;
    int ok = 0;
    for (; degree >= 1 && !ok; degree--) {
        size_t nc = (size_t)as_jet_coef_count(degree);
        for (size_t i = 0; i < n; i++) {
            /* row i scaled by exp(-AS_JET_WEIGHT (x^2 + y^2)) (coordinates already / h) */
            double r2 = loc[3 * i] * loc[3 * i] + loc[3 * i + 1] * loc[3 * i + 1];
            double w = exp(-AS_JET_WEIGHT * r2);
            monomials(loc[3 * i], loc[3 * i + 1], degree, a + i * nc);
            for (size_t j = 0; j < nc; j++) a[i * nc + j] *= w;
            b[i] = w * loc[3 * i + 2];
        }
        int rank = as_lsq_solve(a, b, n, nc, x, work);
        if (rank == (int)nc) {
            ok = 1;
            out->degree = degree;
            memset(out->coef, 0, sizeof out->coef);
            memcpy(out->coef, x, nc * sizeof(double));
        }
    }
    if (!ok) return -1;
    const double *cf = out->coef;
    /* 4. Monge point and normal */
    double jx = cf[1], jy = cf[2];
    double jxx = 2 * cf[3] / h, jxy = cf[4] / h, jyy = 2 * cf[5] / h;
    double rho = sqrt(1 + jx * jx + jy * jy);
    double pl[3] = {0, 0, cf[0] * h}, pw[3];
    to_world(fr, pl, pw);
    for (int i = 0; i < 3; i++) out->point[i] = origin[i] + pw[i];
    double nl[3] = {-jx / rho, -jy / rho, 1 / rho};
    /* 5. shape operator on an orthonormal tangent basis */
    double t1[3] = {1, 0, jx}, t2[3];
    v3_normalize(t1);
    v3_cross(nl, t1, t2);
    double a1 = t1[0], b1 = t1[1], a2 = t2[0], b2 = t2[1];
    double B11 = -(jxx * a1 * a1 + 2 * jxy * a1 * b1 + jyy * b1 * b1) / rho;
    double B12 = -(jxx * a1 * a2 + jxy * (a1 * b2 + a2 * b1) + jyy * b1 * b2) / rho;
    double B22 = -(jxx * a2 * a2 + 2 * jxy * a2 * b2 + jyy * b2 * b2) / rho;
    double cs, sn;
    eig2(B11, B12, B22, &out->k[0], &out->k[1], &cs, &sn);
    double d0[3], d1[3];
    for (int i = 0; i < 3; i++) d0[i] = cs * t1[i] + sn * t2[i];
    v3_cross(nl, d0, d1);
    to_world(fr, nl, out->n);
    to_world(fr, d0, out->d);
    to_world(fr, d1, out->d + 3);
    memcpy(out->frame, fr, sizeof fr);
    out->h = h;
    return 0;
}

/* ---- Gaussian blending ------------------------------------------------------------ */

/* A cell of the hash grid: its integer coordinates and its vertices order[start ..
 * start + count). count == 0 marks an empty slot. */
typedef struct bl_cell {
    int32_t c[3];
    uint32_t start, count;
} bl_cell;

struct as_blend {
    anistar_context *ctx;
    const as_kdtree *kd; /* borrowed */
    const double *xyz;   /* borrowed */
    double *tensor;      /* 6 n, owned */
    size_t n;
    double rb, inv_rb2, cut2, floor_w; /* r_B, 1/r_B^2, (c r_B)^2, exp(-c^2) */
    /* hash grid of cell size c r_B over the vertices (grid == 0: kd-tree radius queries) */
    int grid;
    double lo[3], cell;
    int32_t ncell[3]; /* cells per axis holding vertices: coordinates in [0, ncell) */
    int32_t *order;   /* n vertex ids sorted by cell */
    bl_cell *table;   /* cap slots, open addressing */
    size_t cap;
};

static inline size_t bl_hash(const int32_t c[3], size_t cap) {
    uint64_t h = (uint64_t)(uint32_t)c[0] * 0x9E3779B97F4A7C15ULL;
    h ^= (uint64_t)(uint32_t)c[1] * 0xC2B2AE3D27D4EB4FULL;
    h ^= (uint64_t)(uint32_t)c[2] * 0x165667B19E3779F9ULL;
    h ^= h >> 29;
    return (size_t)h & (cap - 1);
}

static const bl_cell *bl_find(const as_blend *b, const int32_t c[3]) {
    size_t i = bl_hash(c, b->cap);
    for (;;) {
        const bl_cell *e = &b->table[i];
        if (e->count == 0) return NULL;
        if (e->c[0] == c[0] && e->c[1] == c[1] && e->c[2] == c[2]) return e;
        i = (i + 1) & (b->cap - 1);
    }
}

/* Sort key: cell coordinates then vertex id. */
typedef struct bl_key {
    int32_t c[3];
    int32_t id;
} bl_key;

static int bl_key_cmp(const void *pa, const void *pb) {
    const bl_key *a = pa, *b = pb;
    for (int i = 0; i < 3; i++)
        if (a->c[i] != b->c[i]) return a->c[i] < b->c[i] ? -1 : 1;
    return (a->id > b->id) - (a->id < b->id);
}

static inline void bl_cell_of(const as_blend *b, const double p[3], int32_t c[3]) {
    for (int i = 0; i < 3; i++) c[i] = (int32_t)floor((p[i] - b->lo[i]) / b->cell);
}

/* Build the hash grid; returns 0, or -1 when out of memory. A grid too fine for int32
 * cell coordinates leaves grid = 0 (radius queries through the kd-tree instead). */
static int bl_build_grid(anistar_context *ctx, as_blend *b) {
    double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (int i = 0; i < 3; i++) b->lo[i] = INFINITY;
    for (size_t v = 0; v < b->n; v++)
        for (int i = 0; i < 3; i++) {
            b->lo[i] = fmin(b->lo[i], b->xyz[3 * v + i]);
            hi[i] = fmax(hi[i], b->xyz[3 * v + i]);
        }
    b->cell = AS_BLEND_CUTOFF * b->rb;
    for (int i = 0; i < 3; i++) {
        double m = floor((hi[i] - b->lo[i]) / b->cell) + 1;
        if (!(m < 1e9)) return 0;
        b->ncell[i] = (int32_t)m;
    }
    bl_key *keys = as_alloc_array(ctx, b->n, sizeof(bl_key));
    b->order = as_alloc_array(ctx, b->n, sizeof(int32_t));
    if (!keys || !b->order) {
        as_free(ctx, keys, b->n * sizeof(bl_key));
        return -1;
    }
    for (size_t v = 0; v < b->n; v++) {
        bl_cell_of(b, b->xyz + 3 * v, keys[v].c);
        keys[v].id = (int32_t)v;
    }
    qsort(keys, b->n, sizeof(bl_key), bl_key_cmp);
    size_t cells = 0;
    for (size_t v = 0; v < b->n; v++) {
        b->order[v] = keys[v].id;
        if (v == 0 || memcmp(keys[v].c, keys[v - 1].c, sizeof keys[v].c) != 0) cells++;
    }
    b->cap = 16;
    while (b->cap < 2 * cells) b->cap *= 2;
    b->table = as_alloc_array(ctx, b->cap, sizeof(bl_cell));
    if (!b->table) {
        as_free(ctx, keys, b->n * sizeof(bl_key));
        b->cap = 0;
        return -1;
    }
    memset(b->table, 0, b->cap * sizeof(bl_cell));
    for (size_t v = 0; v < b->n;) {
        size_t w = v + 1;
        while (w < b->n && memcmp(keys[w].c, keys[v].c, sizeof keys[v].c) == 0) w++;
        size_t i = bl_hash(keys[v].c, b->cap);
        while (b->table[i].count != 0) i = (i + 1) & (b->cap - 1);
        memcpy(b->table[i].c, keys[v].c, sizeof keys[v].c);
        b->table[i].start = (uint32_t)v;
        b->table[i].count = (uint32_t)(w - v);
        v = w;
    }
    as_free(ctx, keys, b->n * sizeof(bl_key));
    b->grid = 1;
    return 0;
}

anistar_status as_blend_create(anistar_context *ctx, const as_kdtree *kd, const double *xyz,
                               size_t n, const double *tensors, double rb, as_blend **out) {
    *out = NULL;
    if (n == 0 || !kd || as_kdtree_size(kd) != n || !xyz || !tensors || n >= INT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "blending: no vertices, or the kd-tree does not "
                                            "match them");
    if (!(isfinite(rb) && rb > 0))
        return as_fail(ctx, ANISTAR_EINVAL, "blending: radius r_B must be finite and > 0, "
                                            "got %g", rb);
    as_blend *b = as_alloc(ctx, sizeof *b);
    if (!b) return as_fail(ctx, ANISTAR_ENOMEM, "blending: out of memory");
    memset(b, 0, sizeof *b);
    b->ctx = ctx;
    b->kd = kd;
    b->xyz = xyz;
    b->n = n;
    b->rb = rb;
    b->inv_rb2 = 1 / (rb * rb);
    b->cut2 = AS_BLEND_CUTOFF * AS_BLEND_CUTOFF * rb * rb;
    b->floor_w = exp(-AS_BLEND_CUTOFF * AS_BLEND_CUTOFF);
    b->tensor = as_alloc_array(ctx, n, 6 * sizeof(double));
    if (!b->tensor || bl_build_grid(ctx, b)) {
        as_blend_free(ctx, b);
        return as_fail(ctx, ANISTAR_ENOMEM, "blending: out of memory (%zu tensors)", n);
    }
    memcpy(b->tensor, tensors, n * 6 * sizeof(double));
    *out = b;
    return ANISTAR_OK;
}

void as_blend_free(anistar_context *ctx, as_blend *b) {
    if (!b) return;
    as_free(ctx, b->tensor, b->n * 6 * sizeof(double));
    as_free(ctx, b->order, b->n * sizeof(int32_t));
    as_free(ctx, b->table, b->cap * sizeof(bl_cell));
    as_free(ctx, b, sizeof *b);
}

double as_blend_radius(const as_blend *b) { return b->rb; }

double *as_blend_tensors(as_blend *b, size_t *n) {
    *n = b->n;
    return b->tensor;
}

/* The squared distance as the kd-tree computes it (kdtree.h: one formula). */
static inline double kd_d2(const double a[3], const double q[3]) {
    double dx = a[0] - q[0], dy = a[1] - q[1], dz = a[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* Accumulate vertex v at squared distance d2 when within the cutoff. */
static inline void bl_add(const as_blend *b, size_t v, double d2, double d02, double limit,
                          double acc[6], double *wsum) {
    if (d2 > limit) return;
    double w = exp(-(d2 - d02) * b->inv_rb2) - b->floor_w;
    if (!(w > 0)) return;
    const double *t = b->tensor + 6 * v;
    for (int i = 0; i < 6; i++) acc[i] += w * t[i];
    *wsum += w;
}

/* The squared distance from p to the slab of grid cells k along axis i (0 inside it). */
static inline double bl_gap2(const as_blend *b, int i, int32_t k, const double p[3]) {
    const double lo = b->lo[i] + b->cell * (double)k, hi = lo + b->cell;
    const double g = p[i] < lo ? lo - p[i] : p[i] > hi ? p[i] - hi : 0;
    return g * g;
}

/* Most grid cells one query visits before using a kd-tree radius query instead (points
 * far from the vertices, whose cutoff ball is large). */
#define BL_MAX_CELLS 512

/*
 * as_blend_eval — see jet.h.
 * design:
 *   1. d0: the nearest vertex (kd-tree, k = 1); the cutoff ball has radius
 *      R = sqrt(d0^2 + c^2 r_B^2);
 *   2. the grid cells (size c r_B) meeting the ball's box, clamped to the occupied
 *      range, looked up in the hash table (expected O(1) each; 27 cells for a point
 *      near the surface); every vertex within R is summed;
 *   3. when more than BL_MAX_CELLS cells would be visited (a point far away) or the grid
 *      could not be built: a kd-tree radius query (allocates the id list).
 */
anistar_status as_blend_eval(anistar_context *ctx, const as_blend *b, const double p[3],
                             double m[6]) {
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "blending: point is not finite");
    int32_t id0;
    double d02;
    as_kdtree_knn(b->kd, p, 1, &id0, &d02);
    double limit = d02 + b->cut2, R = sqrt(limit) * (1 + 1e-12) + 1e-9 * b->cell;
    double acc[6] = {0, 0, 0, 0, 0, 0}, wsum = 0;
    int32_t c0[3], c1[3];
    double ncells = 1;
    if (b->grid) {
        for (int i = 0; i < 3; i++) {
            double a = floor((p[i] - R - b->lo[i]) / b->cell);
            double z = floor((p[i] + R - b->lo[i]) / b->cell);
            if (a < 0) a = 0;
            if (z > b->ncell[i] - 1) z = b->ncell[i] - 1;
            c0[i] = (int32_t)fmin(a, 2e9);
            c1[i] = (int32_t)fmax(z, -2e9);
            ncells *= c1[i] >= c0[i] ? (double)(c1[i] - c0[i] + 1) : 0;
        }
    }
    if (b->grid && ncells <= BL_MAX_CELLS) {
        /* design: a cell whose box lies beyond the cutoff ball holds no vertex to sum (the
         * box's squared distance to p, over R^2: R holds a relative margin of 1e-12 and
         * 1e-9 cells against the rounding of both); on a surface about a quarter of the
         * 27 cells around p are skipped so */
        const double R2 = R * R;
        int32_t c[3];
        for (c[2] = c0[2]; c[2] <= c1[2]; c[2]++) {
            const double gz = bl_gap2(b, 2, c[2], p);
            for (c[1] = c0[1]; c[1] <= c1[1]; c[1]++) {
                const double gyz = gz + bl_gap2(b, 1, c[1], p);
                if (gyz > R2) continue;
                for (c[0] = c0[0]; c[0] <= c1[0]; c[0]++) {
                    if (gyz + bl_gap2(b, 0, c[0], p) > R2) continue;
                    const bl_cell *e = bl_find(b, c);
                    if (!e) continue;
                    for (uint32_t i = 0; i < e->count; i++) {
                        size_t v = (size_t)b->order[e->start + i];
                        bl_add(b, v, kd_d2(b->xyz + 3 * v, p), d02, limit, acc, &wsum);
                    }
                }
            }
        }
    } else {
        anistar_context *cx = ctx ? ctx : b->ctx;
        as_idlist list = {0};
        if (as_kdtree_radius(cx, b->kd, p, R, &list)) {
            as_idlist_free(cx, &list);
            return as_fail(ctx, ANISTAR_ENOMEM, "blending: out of memory");
        }
        for (size_t i = 0; i < list.n; i++) {
            size_t v = (size_t)list.ids[i];
            bl_add(b, v, kd_d2(b->xyz + 3 * v, p), d02, limit, acc, &wsum);
        }
        as_idlist_free(cx, &list);
    }
    if (!(wsum > 0)) { /* cannot happen: the nearest vertex has weight 1 - exp(-c^2) */
        memcpy(m, b->tensor + 6 * (size_t)id0, 6 * sizeof(double));
        return ANISTAR_OK;
    }
    for (int i = 0; i < 6; i++) m[i] = acc[i] / wsum;
    return ANISTAR_OK;
}

anistar_status as_blend_default_radius(anistar_context *ctx, const as_kdtree *kd,
                                       const double *xyz, size_t n, size_t k, double *rb) {
    return as_blend_default_radius_keep(ctx, kd, xyz, n, k, rb, NULL, 0, NULL);
}

anistar_status as_blend_default_radius_keep(anistar_context *ctx, const as_kdtree *kd,
                                            const double *xyz, size_t n, size_t k, double *rb,
                                            int32_t *keep, size_t keep_k, uint8_t *kept) {
    *rb = 0;
    if (n < 2 || k == 0)
        return as_fail(ctx, ANISTAR_EINVAL, "blending: the default radius needs two vertices");
    if (k > AS_JET_MAX_POINTS) k = AS_JET_MAX_POINTS;
    if (keep && (keep_k > k + 1 || keep_k > UINT8_MAX))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "blending: cannot keep %zu neighbours of a %zu-neighbour query", keep_k,
                       k + 1);
    int32_t ids[AS_JET_MAX_POINTS + 1];
    double d2[AS_JET_MAX_POINTS + 1];
    double total = 0;
    for (size_t v = 0; v < n; v++) {
        size_t got = as_kdtree_knn(kd, xyz + 3 * v, k + 1, ids, d2);
        if (keep) {
            for (size_t i = 0; i < keep_k; i++) keep[keep_k * v + i] = i < got ? ids[i] : -1;
            kept[v] = (uint8_t)(got < keep_k ? got : keep_k);
        }
        double s = 0;
        size_t cnt = 0;
        for (size_t i = 0; i < got; i++) {
            if (ids[i] == (int32_t)v) continue; /* the vertex itself */
            if (cnt == k) break;
            s += sqrt(d2[i]);
            cnt++;
        }
        if (cnt) total += s / (double)cnt;
    }
    *rb = total / (double)n;
    if (!(*rb > 0))
        return as_fail(ctx, ANISTAR_EINVAL, "blending: every vertex coincides with its "
                                            "neighbours");
    return ANISTAR_OK;
}
