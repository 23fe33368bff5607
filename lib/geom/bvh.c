/*
 * bvh.c — static AABB tree over triangles or boxes; exact segment/triangle contact,
 * symbolically perturbed ray parity, closest point, box queries. See bvh.h.
 */
#include "geom/bvh.h"

#include "geom/predicates.h"

#include <math.h>
#include <string.h>

/* Traversal stack depth: a tree of n < 2^31 items is at most ceil(log2(n / 2)) + 1 levels
 * deep (median splits, leaves of AS_BVH_LEAF/2 .. AS_BVH_LEAF items); a depth-first stack
 * holds at most depth + 1 entries. */
#define AS_BVH_STACK 80
/* Slack of the segment/box culling test, in units of the segment parameter t in [0, 1].
 * The computed slab parameters are within ~4e-16 of the true ones in [0, 1] (one
 * subtraction and one division on top of the rounded direction), so a box met by the
 * segment is never culled; the slack only makes a few extra boxes visited. */
#define AS_BVH_SEG_SLACK 1e-9
#define AS_BVH_NONE UINT32_MAX
/* Triangles with |ab x ac|^2 <= AS_BVH_FLAT |ab|^2 |ac|^2 (sin^2 of the angle at u) are
 * treated as flat by as_closest_on_triangle: the region method's signed areas are
 * differences of products that lose about log10(1/sin^2) digits there. */
#define AS_BVH_FLAT 1e-10

typedef struct as_bvh_node {
    double lo[3], hi[3]; /* exact bounding box of the node's item boxes */
    uint32_t begin;      /* first slot */
    uint32_t count;      /* number of slots */
    uint32_t right;      /* right child; 0 for a leaf (left child = index + 1) */
    uint32_t pad;
} as_bvh_node;

struct as_bvh {
    as_bvh_node *nodes;
    size_t nnodes, ncap;
    size_t n;   /* items */
    int32_t *id; /* original id of each slot */
    double *tc;  /* triangles: 9 coordinates per slot (u, v, w), else NULL */
    double *bx;  /* boxes: lo[3], hi[3] per slot, else NULL */
    /* as_bvh_side_grid: node (i, j, k) at g0 + (i, j, k) gh, ng[0] ng[1] ng[2] nodes, the
     * side of each (+1 inside, -1 outside, 0 unknown: on a triangle); NULL: no grid */
    int8_t *gside;
    double g0[3], gh, ginv; /* ginv = 1 / gh */
    int32_t ng[3];
    /* the slots of the triangles whose box meets cell (i, j, k) (stored at its lowest
     * node): gslot[gstart[c] .. gstart[c + 1]) */
    uint32_t *gstart, *gslot;
    size_t gnslot;
    double *gbox; /* each slot's triangle box: lo[3], hi[3] */
};

/* ---- small exact helpers --------------------------------------------------------------- */

static inline int as_sgn(double x) { return (x > 0) - (x < 0); }

double as_orient2d_proj(const double a[3], const double b[3], const double c[3], int i, int j) {
    /* det[A-D; B-D; C-D] with A, B, C lifted to z = 0 and D = (a_i, a_j, -1): the first
     * row is (0, 0, 1), so the determinant is the 2x2 orientation, evaluated exactly. */
    const double A[3] = {a[i], a[j], 0}, B[3] = {b[i], b[j], 0}, C[3] = {c[i], c[j], 0};
    const double D[3] = {a[i], a[j], -1};
    return as_orient3d(A, B, C, D);
}

/* Sign of N_k = ((v-u) x (w-u))_k, the orientation of the triangle projected along k. */
static inline int as_tri_nsign(const double *u, const double *v, const double *w, int k) {
    return as_sgn(as_orient2d_proj(u, v, w, (k + 1) % 3, (k + 2) % 3));
}

/* A coordinate axis along which the triangle projects to a nondegenerate triangle, and
 * the sign of that projection; -1 if the triangle is degenerate (collinear). */
static int as_tri_proj_axis(const double *u, const double *v, const double *w, int *nsign) {
    for (int k = 2; k >= 0; k--) { /* z first: most meshes' first guess */
        int s = as_tri_nsign(u, v, w, k);
        if (s) {
            *nsign = s;
            return k;
        }
    }
    return -1;
}

/* p (coplanar with the nondegenerate triangle) lies in the closed triangle; k, ns from
 * as_tri_proj_axis. */
static int as_in_tri_proj(const double *p, const double *u, const double *v, const double *w,
                          int k, int ns) {
    int i = (k + 1) % 3, j = (k + 2) % 3;
    return as_sgn(as_orient2d_proj(u, v, p, i, j)) * ns >= 0 &&
           as_sgn(as_orient2d_proj(v, w, p, i, j)) * ns >= 0 &&
           as_sgn(as_orient2d_proj(w, u, p, i, j)) * ns >= 0;
}

/* r, collinear with p and q in projection (i, j), lies on the closed segment [p, q]. */
static int as_on_seg_proj(const double *p, const double *q, const double *r, int i, int j) {
    int ax[2] = {i, j};
    for (int m = 0; m < 2; m++) {
        int a = ax[m];
        double lo = p[a] < q[a] ? p[a] : q[a], hi = p[a] < q[a] ? q[a] : p[a];
        if (r[a] < lo || r[a] > hi) return 0;
    }
    return 1;
}

/* Closed segments [p1, p2] and [p3, p4] (coplanar) meet, in projection (i, j). */
static int as_seg_seg_proj(const double *p1, const double *p2, const double *p3,
                           const double *p4, int i, int j) {
    int d1 = as_sgn(as_orient2d_proj(p3, p4, p1, i, j));
    int d2 = as_sgn(as_orient2d_proj(p3, p4, p2, i, j));
    int d3 = as_sgn(as_orient2d_proj(p1, p2, p3, i, j));
    int d4 = as_sgn(as_orient2d_proj(p1, p2, p4, i, j));
    if (d1 * d2 < 0 && d3 * d4 < 0) return 1;
    if (d1 == 0 && as_on_seg_proj(p3, p4, p1, i, j)) return 1;
    if (d2 == 0 && as_on_seg_proj(p3, p4, p2, i, j)) return 1;
    if (d3 == 0 && as_on_seg_proj(p1, p2, p3, i, j)) return 1;
    if (d4 == 0 && as_on_seg_proj(p1, p2, p4, i, j)) return 1;
    return 0;
}

static inline void as_sub3(const double *a, const double *b, double *r) {
    r[0] = a[0] - b[0];
    r[1] = a[1] - b[1];
    r[2] = a[2] - b[2];
}
static inline double as_dot3(const double *a, const double *b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void as_cross3(const double *a, const double *b, double *r) {
    r[0] = a[1] * b[2] - a[2] * b[1];
    r[1] = a[2] * b[0] - a[0] * b[2];
    r[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double as_clamp01(double t) {
    if (!(t > 0)) return 0; /* also NaN */
    return t < 1 ? t : 1;
}

/* Approximate first parameter at which the coplanar segment [a, b] touches the triangle
 * (the exact decision that it does was made before). */
static double as_coplanar_t(const double *a, const double *b, const double *tri[3], int k,
                            int ns) {
    if (as_in_tri_proj(a, tri[0], tri[1], tri[2], k, ns)) return 0;
    int i = (k + 1) % 3, j = (k + 2) % 3;
    double d[2] = {b[i] - a[i], b[j] - a[j]}, best = 1;
    for (int e = 0; e < 3; e++) {
        const double *p = tri[e], *q = tri[(e + 1) % 3];
        if (!as_seg_seg_proj(a, b, p, q, i, j)) continue;
        double f[2] = {q[i] - p[i], q[j] - p[j]}, g[2] = {p[i] - a[i], p[j] - a[j]};
        double den = d[0] * f[1] - d[1] * f[0], s;
        if (den != 0) {
            s = (g[0] * f[1] - g[1] * f[0]) / den;
        } else { /* collinear overlap: the nearer edge end projected on [a, b] */
            double dd = d[0] * d[0] + d[1] * d[1];
            double sp = dd > 0 ? (g[0] * d[0] + g[1] * d[1]) / dd : 0;
            double sq = dd > 0 ? ((q[i] - a[i]) * d[0] + (q[j] - a[j]) * d[1]) / dd : 0;
            s = sp < sq ? sp : sq;
        }
        s = as_clamp01(s);
        if (s < best) best = s;
    }
    return best;
}

/*
 * as_segment_triangle — see bvh.h.
 * design:
 *   1. s_a, s_b = orient3d(u,v,w,a), orient3d(u,v,w,b). Same strict sign: NONE.
 *   2. Both 0 (coplanar): project on a coordinate plane where the triangle does not
 *      degenerate (none: degenerate triangle, NONE); meet iff an end lies in the closed
 *      triangle or [a, b] meets a closed edge (exact 2D tests).
 *   3. Otherwise the line ab crosses the plane once, at a point of [a, b]; it lies in the
 *      closed triangle iff the orientations orient3d(a,b,u,v), (a,b,v,w), (a,b,w,u) have
 *      no two strictly opposite signs; the zeros say edge (1) or vertex (2) (three zeros
 *      would need a degenerate triangle, which step 2 caught: s_a = s_b = 0 then).
 */
as_seg_hit as_segment_triangle(const double a[3], const double b[3], const double u[3],
                               const double v[3], const double w[3], double *t) {
    int sa = as_sgn(as_orient3d(u, v, w, a)), sb = as_sgn(as_orient3d(u, v, w, b));
    if (sa == sb && sa != 0) return AS_HIT_NONE;
    if (sa == 0 && sb == 0) {
        int ns, k = as_tri_proj_axis(u, v, w, &ns);
        if (k < 0) return AS_HIT_NONE;
        int i = (k + 1) % 3, j = (k + 2) % 3;
        int meet = as_in_tri_proj(a, u, v, w, k, ns) || as_in_tri_proj(b, u, v, w, k, ns) ||
                   as_seg_seg_proj(a, b, u, v, i, j) || as_seg_seg_proj(a, b, v, w, i, j) ||
                   as_seg_seg_proj(a, b, w, u, i, j);
        if (!meet) return AS_HIT_NONE;
        if (t) {
            const double *tri[3] = {u, v, w};
            *t = as_coplanar_t(a, b, tri, k, ns);
        }
        return AS_HIT_COPLANAR;
    }
    int e1 = as_sgn(as_orient3d(a, b, u, v));
    int e2 = as_sgn(as_orient3d(a, b, v, w));
    int e3 = as_sgn(as_orient3d(a, b, w, u));
    if ((e1 > 0 || e2 > 0 || e3 > 0) && (e1 < 0 || e2 < 0 || e3 < 0)) return AS_HIT_NONE;
    int zeros = (e1 == 0) + (e2 == 0) + (e3 == 0);
    if (zeros == 3) return AS_HIT_NONE; /* unreachable for exact signs; defensive */
    if (sa == 0 || sb == 0) {
        if (t) *t = sa == 0 ? 0 : 1;
        return AS_HIT_ENDPOINT;
    }
    if (t) {
        double e[3], f[3], n[3], pa[3], pb[3];
        as_sub3(v, u, e);
        as_sub3(w, u, f);
        as_cross3(e, f, n);
        as_sub3(a, u, pa);
        as_sub3(b, u, pb);
        double da = as_dot3(n, pa), db = as_dot3(n, pb);
        *t = as_clamp01(da / (da - db));
    }
    return zeros == 0 ? AS_HIT_PROPER : zeros == 1 ? AS_HIT_EDGE : AS_HIT_VERTEX;
}

/* Sign of orient3d(p, q', u, v) with q' = q + eps e_x + eps^2 e_y + eps^3 e_z: the
 * coefficient of eps^(k+1) is ((u - v) x (p - v))_k, the orientation of (v, u, p)
 * projected along k. 0 only when p lies on the line uv. */
static int as_sos_edge(const double *p, const double *q, const double *u, const double *v) {
    int s = as_sgn(as_orient3d(p, q, u, v));
    for (int k = 0; k < 3 && s == 0; k++)
        s = as_sgn(as_orient2d_proj(v, u, p, (k + 1) % 3, (k + 2) % 3));
    return s;
}

int as_segment_triangle_sos(const double p[3], const double q[3], const double u[3],
                            const double v[3], const double w[3]) {
    int sp = as_sgn(as_orient3d(u, v, w, p));
    if (sp == 0) {
        int ns, k = as_tri_proj_axis(u, v, w, &ns);
        if (k < 0) return 0;
        return as_in_tri_proj(p, u, v, w, k, ns) ? -1 : 0;
    }
    /* sp != 0: the triangle is not degenerate */
    int sq = as_sgn(as_orient3d(u, v, w, q));
    for (int k = 0; k < 3 && sq == 0; k++) sq = -as_tri_nsign(u, v, w, k);
    if (sq == 0 || sq == sp) return 0;
    int e1 = as_sos_edge(p, q, u, v);
    if (e1 == 0) return 0;
    if (as_sos_edge(p, q, v, w) != e1) return 0;
    if (as_sos_edge(p, q, w, u) != e1) return 0;
    return 1;
}

/* Closest point of the segment [a, b] to p; returns the parameter's point in c. */
static void as_closest_on_segment(const double *p, const double *a, const double *b,
                                  double *c) {
    double ab[3], ap[3];
    as_sub3(b, a, ab);
    as_sub3(p, a, ap);
    double dd = as_dot3(ab, ab), s = 0;
    if (dd > 0) s = as_clamp01(as_dot3(ap, ab) / dd);
    for (int k = 0; k < 3; k++) c[k] = a[k] + s * ab[k];
}

static inline double as_d2(const double *a, const double *b) {
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/*
 * as_closest_on_triangle — see bvh.h.
 * design (Ericson 5.1.5, Voronoi regions of the triangle's features):
 *   1. With d1 = ab.ap, d2 = ac.ap, d3 = ab.bp, d4 = ac.bp, d5 = ab.cp, d6 = ac.cp, test
 *      the vertex regions (a: d1, d2 <= 0; b: d3 >= 0, d4 <= d3; c: d6 >= 0, d5 <= d6),
 *      then the edge regions through the signed areas vc = d1 d4 - d3 d2 (ab),
 *      vb = d5 d2 - d1 d6 (ac), va = d3 d6 - d5 d4 (bc), projecting on the edge;
 *   2. otherwise the face: barycentrics (va, vb, vc) / (va + vb + vc);
 *   3. a flat triangle (sin^2 of its angle at u below AS_BVH_FLAT: va, vb, vc would
 *      lose too many digits to cancellation) or one left with no positive face
 *      denominator after rounding takes the best of its three edges (off by at most its
 *      width, below 1e-5 of its size, which changes distances to second order only);
 *   4. clamp the point into the triangle's box (a rounding guard that keeps the distance
 *      at or above any box lower bound used by the tree's pruning).
 */
double as_closest_on_triangle(const double p[3], const double u[3], const double v[3],
                              const double w[3], double c[3]) {
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    as_sub3(v, u, ab);
    as_sub3(w, u, ac);
    as_sub3(p, u, ap);
    double d1 = as_dot3(ab, ap), d2 = as_dot3(ac, ap);
    as_sub3(p, v, bp);
    double d3 = as_dot3(ab, bp), d4 = as_dot3(ac, bp);
    as_sub3(p, w, cp);
    double d5 = as_dot3(ab, cp), d6 = as_dot3(ac, cp);
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    double nrm[3];
    as_cross3(ab, ac, nrm);
    int degenerate = !(as_dot3(nrm, nrm) > AS_BVH_FLAT * as_dot3(ab, ab) * as_dot3(ac, ac));
    if (!degenerate) {
        if (d1 <= 0 && d2 <= 0) {
            memcpy(c, u, 3 * sizeof *c);
        } else if (d3 >= 0 && d4 <= d3) {
            memcpy(c, v, 3 * sizeof *c);
        } else if (d6 >= 0 && d5 <= d6) {
            memcpy(c, w, 3 * sizeof *c);
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            double s = d1 - d3 > 0 ? as_clamp01(d1 / (d1 - d3)) : 0;
            for (int k = 0; k < 3; k++) c[k] = u[k] + s * ab[k];
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            double s = d2 - d6 > 0 ? as_clamp01(d2 / (d2 - d6)) : 0;
            for (int k = 0; k < 3; k++) c[k] = u[k] + s * ac[k];
        } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
            double den = (d4 - d3) + (d5 - d6);
            double s = den > 0 ? as_clamp01((d4 - d3) / den) : 0;
            for (int k = 0; k < 3; k++) c[k] = v[k] + s * (w[k] - v[k]);
        } else if (va + vb + vc > 0) {
            double den = va + vb + vc, bv = vb / den, bw = vc / den;
            for (int k = 0; k < 3; k++) c[k] = u[k] + ab[k] * bv + ac[k] * bw;
        } else {
            degenerate = 1; /* nearly flat: rounding left no face region */
        }
    }
    if (degenerate) {
        double c1[3], best;
        as_closest_on_segment(p, u, v, c);
        best = as_d2(p, c);
        const double *ends[2][2] = {{v, w}, {w, u}};
        for (int e = 0; e < 2; e++) {
            as_closest_on_segment(p, ends[e][0], ends[e][1], c1);
            double d = as_d2(p, c1);
            if (d < best) {
                best = d;
                memcpy(c, c1, sizeof c1);
            }
        }
    }
    for (int k = 0; k < 3; k++) {
        double lo = u[k], hi = u[k];
        if (v[k] < lo) lo = v[k];
        if (v[k] > hi) hi = v[k];
        if (w[k] < lo) lo = w[k];
        if (w[k] > hi) hi = w[k];
        if (c[k] < lo) c[k] = lo;
        if (c[k] > hi) c[k] = hi;
    }
    return as_d2(p, c);
}

/* ---- build ------------------------------------------------------------------------------ */

typedef struct as_bvh_input {
    const double *xyz;
    const int32_t *tri;
    const double *boxes;
} as_bvh_input;

static void as_bvh_item_box(const as_bvh_input *in, int32_t i, double lo[3], double hi[3]) {
    if (in->tri) {
        const int32_t *t = in->tri + 3 * (size_t)i;
        const double *p = in->xyz + 3 * (size_t)t[0];
        for (int k = 0; k < 3; k++) lo[k] = hi[k] = p[k];
        for (int m = 1; m < 3; m++) {
            p = in->xyz + 3 * (size_t)t[m];
            for (int k = 0; k < 3; k++) {
                if (p[k] < lo[k]) lo[k] = p[k];
                if (p[k] > hi[k]) hi[k] = p[k];
            }
        }
    } else {
        memcpy(lo, in->boxes + 6 * (size_t)i, 3 * sizeof *lo);
        memcpy(hi, in->boxes + 6 * (size_t)i + 3, 3 * sizeof *hi);
    }
}

/* Nodes of a tree of n items: a node above AS_BVH_LEAF items has halves of at least
 * AS_BVH_LEAF/2 = 2, so at most n/2 leaves and n - 1 nodes; 1 for n <= AS_BVH_LEAF. */
static size_t as_bvh_node_bound(size_t n) { return n <= AS_BVH_LEAF ? 1 : n; }

static size_t as_bvh_gcount(const as_bvh *b) {
    return (size_t)b->ng[0] * (size_t)b->ng[1] * (size_t)b->ng[2];
}

/* Coordinate c of grid node index i (the same expression at the build and in queries). */
static inline double as_bvh_gcoord(const as_bvh *b, int c, int32_t i) {
    return b->g0[c] + (double)i * b->gh;
}

static inline size_t as_bvh_gnode(const as_bvh *b, int32_t i, int32_t j, int32_t k) {
    return ((size_t)k * (size_t)b->ng[1] + (size_t)j) * (size_t)b->ng[0] + (size_t)i;
}

/* The margin by which a cell is grown for its triangle list (and for the test that p is
 * in the cell): far above the rounding of the node coordinates. */
#define AS_BVH_CELL_MARGIN 1e-6
/* Grid nodes per triangle by default (as_bvh_side_grid), and at most (by default) 2^24
 * nodes: 21 bytes each with the cell lists' offsets, beside the tree's ~150 bytes per
 * triangle. */
#define AS_BVH_GRID_PER_TRI 8
#define AS_BVH_GRID_MAX ((size_t)1 << 24)

void as_bvh_free(anistar_context *ctx, as_bvh *b) {
    if (!b) return;
    as_free(ctx, b->nodes, b->ncap * sizeof *b->nodes);
    as_free(ctx, b->id, b->n * sizeof *b->id);
    if (b->tc) as_free(ctx, b->tc, 9 * b->n * sizeof *b->tc);
    if (b->bx) as_free(ctx, b->bx, 6 * b->n * sizeof *b->bx);
    if (b->gside) {
        as_free(ctx, b->gside, as_bvh_gcount(b));
        as_free(ctx, b->gstart, (as_bvh_gcount(b) + 1) * sizeof *b->gstart);
        as_free(ctx, b->gslot, b->gnslot * sizeof *b->gslot);
        as_free(ctx, b->gbox, 6 * b->n * sizeof *b->gbox);
    }
    as_free(ctx, b, sizeof *b);
}

/*
 * as_bvh_build — common build of both kinds.
 * design:
 *   1. Item centroids (box midpoints) in an as_kdpoint array (temporary).
 *   2. Explicit stack of (range, parent waiting for its right child); a node's index is
 *      taken when popped, the left range pushed last: preorder. Node box = union of the
 *      item boxes (exact min/max); above AS_BVH_LEAF items, split at the median centroid
 *      along the widest axis of the centroids' box (as_kdpoint_select).
 *   3. Copy the items' data into slot order; free the temporary.
 */
static anistar_status as_bvh_build(anistar_context *ctx, const as_bvh_input *in, size_t n,
                                   as_bvh **out) {
    as_bvh *b = as_alloc(ctx, sizeof *b);
    if (!b) return as_fail(ctx, ANISTAR_ENOMEM, "bvh: out of memory");
    memset(b, 0, sizeof *b);
    if (n == 0) {
        *out = b;
        return ANISTAR_OK;
    }
    size_t per = in->tri ? 9 : 6, nb = as_bvh_node_bound(n);
    as_kdpoint *kp = as_alloc_array(ctx, n, sizeof *kp);
    as_bvh_node *nodes = as_alloc_array(ctx, nb, sizeof *nodes);
    int32_t *id = as_alloc_array(ctx, n, sizeof *id);
    double *data = as_alloc_array(ctx, per * n, sizeof *data);
    if (!kp || !nodes || !id || !data) {
        as_free(ctx, kp, n * sizeof *kp);
        as_free(ctx, nodes, nb * sizeof *nodes);
        as_free(ctx, id, n * sizeof *id);
        as_free(ctx, data, per * n * sizeof *data);
        as_free(ctx, b, sizeof *b);
        return as_fail(ctx, ANISTAR_ENOMEM, "bvh: out of memory for %zu items", n);
    }
    b->nodes = nodes;
    b->ncap = nb;
    b->id = id;
    b->n = n;
    if (in->tri)
        b->tc = data;
    else
        b->bx = data;
    for (size_t i = 0; i < n; i++) {
        double lo[3], hi[3];
        as_bvh_item_box(in, (int32_t)i, lo, hi);
        for (int k = 0; k < 3; k++) kp[i].x[k] = 0.5 * lo[k] + 0.5 * hi[k];
        kp[i].id = (int32_t)i;
    }
    struct {
        uint32_t begin, count, parent;
    } st[AS_BVH_STACK];
    int sp = 0;
    st[0].begin = 0;
    st[0].count = (uint32_t)n;
    st[0].parent = AS_BVH_NONE;
    sp = 1;
    while (sp > 0) {
        sp--;
        uint32_t bg = st[sp].begin, c = st[sp].count, parent = st[sp].parent;
        uint32_t ni = (uint32_t)b->nnodes++;
        as_bvh_node *nd = &b->nodes[ni];
        if (parent != AS_BVH_NONE) b->nodes[parent].right = ni;
        double clo[3] = {0, 0, 0}, chi[3] = {0, 0, 0};
        for (uint32_t s = bg; s < bg + c; s++) {
            double lo[3], hi[3];
            as_bvh_item_box(in, kp[s].id, lo, hi);
            for (int k = 0; k < 3; k++) {
                if (s == bg || lo[k] < nd->lo[k]) nd->lo[k] = lo[k];
                if (s == bg || hi[k] > nd->hi[k]) nd->hi[k] = hi[k];
                if (s == bg || kp[s].x[k] < clo[k]) clo[k] = kp[s].x[k];
                if (s == bg || kp[s].x[k] > chi[k]) chi[k] = kp[s].x[k];
            }
        }
        nd->begin = bg;
        nd->count = c;
        nd->right = 0;
        nd->pad = 0;
        if (c <= AS_BVH_LEAF) continue;
        int axis = 0;
        for (int k = 1; k < 3; k++)
            if (chi[k] - clo[k] > chi[axis] - clo[axis]) axis = k;
        uint32_t half = c / 2;
        as_kdpoint_select(kp + bg, c, half, axis);
        st[sp].begin = bg + half;
        st[sp].count = c - half;
        st[sp].parent = ni;
        sp++;
        st[sp].begin = bg;
        st[sp].count = half;
        st[sp].parent = AS_BVH_NONE;
        sp++;
    }
    for (size_t s = 0; s < n; s++) {
        int32_t i = kp[s].id;
        b->id[s] = i;
        if (in->tri) {
            for (int m = 0; m < 3; m++)
                memcpy(b->tc + 9 * s + 3 * m, in->xyz + 3 * (size_t)in->tri[3 * (size_t)i + m],
                       3 * sizeof *b->tc);
        } else {
            memcpy(b->bx + 6 * s, in->boxes + 6 * (size_t)i, 6 * sizeof *b->bx);
        }
    }
    as_free(ctx, kp, n * sizeof *kp);
    *out = b;
    return ANISTAR_OK;
}

anistar_status as_bvh_build_triangles(anistar_context *ctx, const double *xyz, size_t nv,
                                      const int32_t *tri, size_t nt, as_bvh **out) {
    *out = NULL;
    if (nt >= (size_t)INT32_MAX || (nt > 0 && (!xyz || !tri)))
        return as_fail(ctx, ANISTAR_EINVAL, "bvh: invalid triangle arrays (%zu triangles)", nt);
    for (size_t i = 0; i < 3 * nt; i++) {
        if (tri[i] < 0 || (size_t)tri[i] >= nv)
            return as_fail(ctx, ANISTAR_EINVAL,
                           "bvh: triangle %zu has vertex index %ld out of range [0, %zu)",
                           i / 3, (long)tri[i], nv);
        const double *p = xyz + 3 * (size_t)tri[i];
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return as_fail(ctx, ANISTAR_EINVAL, "bvh: vertex %ld is not finite", (long)tri[i]);
    }
    as_bvh_input in = {xyz, tri, NULL};
    return as_bvh_build(ctx, &in, nt, out);
}

anistar_status as_bvh_build_boxes(anistar_context *ctx, const double *boxes, size_t n,
                                  as_bvh **out) {
    *out = NULL;
    if (n >= (size_t)INT32_MAX || (n > 0 && !boxes))
        return as_fail(ctx, ANISTAR_EINVAL, "bvh: invalid box array (%zu boxes)", n);
    for (size_t i = 0; i < n; i++) {
        const double *bx = boxes + 6 * i;
        for (int k = 0; k < 3; k++)
            if (!isfinite(bx[k]) || !isfinite(bx[3 + k]) || !(bx[k] <= bx[3 + k]))
                return as_fail(ctx, ANISTAR_EINVAL, "bvh: box %zu is not a finite box", i);
    }
    as_bvh_input in = {NULL, NULL, boxes};
    return as_bvh_build(ctx, &in, n, out);
}

size_t as_bvh_count(const as_bvh *b) { return b->n; }

void as_bvh_bounds(const as_bvh *b, double lo[3], double hi[3]) {
    for (int k = 0; k < 3; k++) {
        lo[k] = b->nnodes ? b->nodes[0].lo[k] : INFINITY;
        hi[k] = b->nnodes ? b->nodes[0].hi[k] : -INFINITY;
    }
}

/* ---- segment queries --------------------------------------------------------------------- */

/* Conservative test: may the closed segment a + t d, t in [0, 1], meet the closed box?
 * (Slab clipping with AS_BVH_SEG_SLACK; an axis with d_k == 0 exactly — which holds iff
 * the two endpoints share that coordinate — is tested exactly.) inv[k] = 1 / d[k]: a
 * product instead of two divisions per axis (a relative error of one more rounding in
 * t, far below the slack where the decision is made, t0 and t1 in [0, 1]). */
static inline int as_bvh_seg_box(const double *a, const double *d, const double *inv,
                                 const double *lo, const double *hi) {
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0) {
            if (a[k] < lo[k] || a[k] > hi[k]) return 0;
            continue;
        }
        double ta = (lo[k] - a[k]) * inv[k], tb = (hi[k] - a[k]) * inv[k];
        if (ta > tb) {
            double x = ta;
            ta = tb;
            tb = x;
        }
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
        if (t0 > t1 + AS_BVH_SEG_SLACK) return 0;
    }
    return 1;
}

/* The same test against the bounding box of triangle u v w: a segment that misses the
 * box misses the closed triangle, and a symbolically perturbed crossing is within it, so
 * the exact tests (several orientation predicates, about ten times the cost) are only
 * run on the triangles that pass; most triangles of a leaf the segment meets do not. */
static inline int as_bvh_seg_tri_box(const double *a, const double *d, const double *inv,
                                     const double *u, const double *v, const double *w) {
    double lo[3], hi[3];
    for (int k = 0; k < 3; k++) {
        double m = u[k] < v[k] ? u[k] : v[k], M = u[k] < v[k] ? v[k] : u[k];
        lo[k] = w[k] < m ? w[k] : m;
        hi[k] = w[k] > M ? w[k] : M;
    }
    return as_bvh_seg_box(a, d, inv, lo, hi);
}

enum { AS_WALK_HITS, AS_WALK_COUNT, AS_WALK_PARITY, AS_WALK_NEAREST };

typedef struct as_bvh_walk {
    int mode;
    anistar_context *ctx;
    as_bvh_hits *out;
    int oom;
    size_t count, proper;
    int parity, on;
    /* AS_WALK_NEAREST (as_bvh_segment_nearest): the reference point, the best contact so
     * far (squared distance, t, triangle id, point), the box bound from it, the margin */
    const double *ref;
    double best, bt, lim, tol, *x;
    int32_t btri;
} as_bvh_walk;

static int as_bvh_hit_push(anistar_context *ctx, as_bvh_hits *out, int32_t tri, int kind,
                           double t) {
    if (out->n == out->cap) {
        void *p = out->h;
        if (as_grow(ctx, &p, &out->cap, out->n + 1, sizeof *out->h)) return -1;
        out->h = p;
    }
    as_bvh_hit *h = &out->h[out->n++];
    h->tri = tri;
    h->kind = kind;
    h->t = t;
    return 0;
}

/* Depth-first walk of the boxes the segment [a, c] may meet, classifying their
 * triangles according to w->mode. Stops early on memory failure or (parity) when a
 * lies on a triangle. */
static inline double as_box_d2(const double *lo, const double *hi, const double *q);
static inline void as_near_try(const as_bvh *b, uint32_t s, const double *a, const double *c,
                               const double *d, const double *ref, double *best, double *bt,
                               int32_t *btri, double x[3]);
static inline double as_near_lim(double best, double tol);

static void as_bvh_seg_walk(const as_bvh *b, const double *a, const double *c, as_bvh_walk *w) {
    if (!b->tc || b->nnodes == 0) return;
    double d[3], inv[3];
    as_sub3(c, a, d);
    for (int k = 0; k < 3; k++) inv[k] = d[k] != 0 ? 1.0 / d[k] : 0.0;
    uint32_t st[AS_BVH_STACK];
    int sp = 0;
    st[sp++] = 0;
    while (sp > 0) {
        uint32_t ni = st[--sp];
        const as_bvh_node *nd = &b->nodes[ni];
        if (!as_bvh_seg_box(a, d, inv, nd->lo, nd->hi)) continue;
        if (w->mode == AS_WALK_NEAREST && as_box_d2(nd->lo, nd->hi, w->ref) > w->lim) continue;
        if (nd->right) {
            st[sp++] = nd->right;
            st[sp++] = ni + 1;
            continue;
        }
        for (uint32_t s = nd->begin; s < nd->begin + nd->count; s++) {
            const double *u = b->tc + 9 * (size_t)s, *v = u + 3, *x = u + 6;
            if (!as_bvh_seg_tri_box(a, d, inv, u, v, x)) continue;
            if (w->mode == AS_WALK_NEAREST) {
                double was = w->best;
                as_near_try(b, s, a, c, d, w->ref, &w->best, &w->bt, &w->btri, w->x);
                if (w->best != was) w->lim = as_near_lim(w->best, w->tol);
                continue;
            }
            if (w->mode == AS_WALK_PARITY) {
                int r = as_segment_triangle_sos(a, c, u, v, x);
                if (r < 0) {
                    w->on = 1;
                    return;
                }
                w->parity ^= r;
                continue;
            }
            double t;
            as_seg_hit k = as_segment_triangle(a, c, u, v, x, w->mode == AS_WALK_HITS ? &t : NULL);
            if (k == AS_HIT_NONE) continue;
            w->count++;
            if (k == AS_HIT_PROPER) w->proper++;
            if (w->mode == AS_WALK_HITS && as_bvh_hit_push(w->ctx, w->out, b->id[s], (int)k, t)) {
                w->oom = 1;
                return;
            }
        }
    }
}

void as_bvh_hits_free(anistar_context *ctx, as_bvh_hits *hits) {
    as_free(ctx, hits->h, hits->cap * sizeof *hits->h);
    hits->h = NULL;
    hits->n = hits->cap = 0;
}

static inline int as_hit_less(const as_bvh_hit *x, const as_bvh_hit *y) {
    return x->t < y->t || (x->t == y->t && x->tri < y->tri);
}

static void as_hits_sift(as_bvh_hit *h, size_t i, size_t n) {
    as_bvh_hit v = h[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && as_hit_less(&h[c], &h[c + 1])) c++;
        if (!as_hit_less(&v, &h[c])) break;
        h[i] = h[c];
        i = c;
    }
    h[i] = v;
}

static void as_hits_sort(as_bvh_hit *h, size_t n) {
    if (n < 2) return;
    for (size_t i = n / 2; i-- > 0;) as_hits_sift(h, i, n);
    for (size_t m = n - 1; m > 0; m--) {
        as_bvh_hit x = h[0];
        h[0] = h[m];
        h[m] = x;
        as_hits_sift(h, 0, m);
    }
}

anistar_status as_bvh_segment(anistar_context *ctx, const as_bvh *b, const double a[3],
                              const double c[3], as_bvh_hits *out) {
    out->n = 0;
    as_bvh_walk w;
    memset(&w, 0, sizeof w);
    w.mode = AS_WALK_HITS;
    w.ctx = ctx;
    w.out = out;
    as_bvh_seg_walk(b, a, c, &w);
    if (w.oom) return as_fail(ctx, ANISTAR_ENOMEM, "bvh: out of memory in a segment query");
    as_hits_sort(out->h, out->n);
    return ANISTAR_OK;
}

static inline double as_dmin(double x, double y) { return x < y ? x : y; }
static inline double as_dmax(double x, double y) { return x > y ? x : y; }

/* Whether a box at squared distance bd2 from ref may hold a contact at squared distance
 * <= best (lim: the bound on bd2 from best, see as_bvh_segment_nearest). */
static inline double as_near_lim(double best, double tol) {
    double r = sqrt(best) * (1 + 1e-9) + tol;
    return r * r;
}

/* The point of [a, c] at parameter t (c itself at t = 1, a at t = 0). */
static inline void as_seg_at(const double *a, const double *c, const double *d, double t,
                             double p[3]) {
    for (int k = 0; k < 3; k++) p[k] = t == 1 ? c[k] : a[k] + t * d[k];
}

/* The contact of [a, a + d] with triangle slot s nearest ref so far (see
 * as_bvh_segment_nearest): *best, *bt, *btri and x updated when it is nearer. */
static inline void as_near_try(const as_bvh *b, uint32_t s, const double *a, const double *c,
                               const double *d, const double *ref, double *best, double *bt,
                               int32_t *btri, double x[3]) {
    const double *u = b->tc + 9 * (size_t)s, *v = u + 3, *w = u + 6;
    double t;
    if (as_segment_triangle(a, c, u, v, w, &t) == AS_HIT_NONE) return;
    double q[3];
    as_seg_at(a, c, d, t, q);
    double e0 = q[0] - ref[0], e1 = q[1] - ref[1], e2 = q[2] - ref[2];
    double dq = e0 * e0 + e1 * e1 + e2 * e2;
    int32_t id = b->id[s];
    if (dq < *best || (dq == *best && (t < *bt || (t == *bt && id < *btri)))) {
        *best = dq;
        *bt = t;
        *btri = id;
        memcpy(x, q, sizeof q);
    }
}

/* The range of cells along axis k that may hold points of [lo, hi] (see the build's
 * lists): cells i with x_i - m <= hi and x_{i+1} + m >= lo, clamped to the grid. */
static inline void as_bvh_cell_range(const as_bvh *b, int k, double lo, double hi, int32_t *r0,
                                     int32_t *r1) {
    const double m = AS_BVH_CELL_MARGIN * b->gh;
    const int32_t top = b->ng[k] - 2;
    /* a guess by one product each, then moved to the exact ends (a step or two): a0 the
     * first cell with x_{i+1} + m >= lo, a1 the last with x_i - m <= hi */
    double f0 = (lo - b->g0[k]) * b->ginv, f1 = (hi - b->g0[k]) * b->ginv;
    int32_t a0 = !(f0 > 0) ? 0 : (f0 > top ? top : (int32_t)f0);
    int32_t a1 = !(f1 > 0) ? 0 : (f1 > top ? top : (int32_t)f1);
    while (a0 > 0 && as_bvh_gcoord(b, k, a0) + m >= lo) a0--;
    while (a0 < top && as_bvh_gcoord(b, k, a0 + 1) + m < lo) a0++;
    while (a1 < top && as_bvh_gcoord(b, k, a1 + 1) - m <= hi) a1++;
    while (a1 > 0 && as_bvh_gcoord(b, k, a1) - m > hi) a1--;
    *r0 = a0;
    *r1 = a1;
}

/* Segments of more pieces than this walk the tree (a piece is 0.9 cells long at most, so
 * its box, grown by the margins, meets at most two cells per axis). */
#define AS_BVH_SEG_PIECES 4096

/*
 * as_bvh_segment_nearest on the side grid: the segment cut into np pieces of at most 0.9
 * cells, visited outward from the piece nearest ref (the distance to ref is convex along
 * the segment, so it grows piece by piece in each direction); each direction stops at the
 * first piece farther from ref than the best contact by more than the rounding margin.
 * A piece's triangles: those listed by the cells its box (grown by tol, beyond the
 * rounding of its end points) meets (at most two per axis) whose box meets the piece's; a
 * triangle the segment meets in another piece is listed by that piece's cells. A
 * triangle is tested once per query (the first 16 tested are remembered).
 */
static void as_bvh_near_grid(const as_bvh *b, const double *a, const double *c,
                             const double *d, const double *inv, const double *ref, double tol,
                             int32_t np, double *best, double *bt, int32_t *btri, double x[3]) {
    double dd = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    double ts = 0;
    if (dd > 0)
        ts = ((ref[0] - a[0]) * d[0] + (ref[1] - a[1]) * d[1] + (ref[2] - a[2]) * d[2]) / dd;
    ts = ts < 0 ? 0 : (ts > 1 ? 1 : ts);
    int32_t i0 = (int32_t)(ts * np);
    if (i0 > np - 1) i0 = np - 1;
    uint32_t tried[16];
    int ntri = 0;
    int32_t lo_i = i0, hi_i = i0 + 1; /* next piece downward: lo_i - 1; upward: hi_i */
    int down = 1, up = 1, first = 1;
    while (first || down || up) {
        int32_t i;
        if (first) {
            i = i0;
            first = 0;
        } else if (up && (!down || hi_i - i0 <= i0 - lo_i + 1)) {
            i = hi_i;
        } else {
            i = lo_i - 1;
        }
        int upward = i >= hi_i;
        if (i < 0 || i >= np) {
            if (i < 0) down = 0;
            else up = 0;
            continue;
        }
        double t0 = (double)i / np, t1 = i + 1 == np ? 1.0 : (double)(i + 1) / np;
        if (i != i0) { /* the piece's nearest point to ref: its end toward ts */
            double tn = upward ? t0 : t1, pn[3];
            as_seg_at(a, c, d, tn, pn);
            double e0 = pn[0] - ref[0], e1 = pn[1] - ref[1], e2 = pn[2] - ref[2];
            double dn = sqrt(e0 * e0 + e1 * e1 + e2 * e2);
            if (dn > sqrt(*best) * (1 + 1e-9) + 2 * tol) { /* this way is done */
                if (upward) up = 0;
                else down = 0;
                continue;
            }
        }
        if (upward && i != i0) hi_i = i + 1;
        if (!upward && i != i0) lo_i = i;
        double p0[3], p1[3];
        as_seg_at(a, c, d, t0, p0);
        as_seg_at(a, c, d, t1, p1);
        int32_t r0[3], r1[3];
        double qlo[3], qhi[3]; /* the piece's box */
        for (int k = 0; k < 3; k++) {
            qlo[k] = as_dmin(p0[k], p1[k]) - tol;
            qhi[k] = as_dmax(p0[k], p1[k]) + tol;
            as_bvh_cell_range(b, k, qlo[k], qhi[k], &r0[k], &r1[k]);
        }
        for (int32_t kk = r0[2]; kk <= r1[2]; kk++)
            for (int32_t j = r0[1]; j <= r1[1]; j++)
                for (int32_t ii = r0[0]; ii <= r1[0]; ii++) {
                    size_t cell = as_bvh_gnode(b, ii, j, kk);
                    for (uint32_t e = b->gstart[cell]; e < b->gstart[cell + 1]; e++) {
                        uint32_t sl = b->gslot[e];
                        const double *tb = b->gbox + 6 * (size_t)sl;
                        /* the piece's box first: a triangle the segment meets elsewhere
                         * is listed by that piece's cells */
                        if (tb[0] > qhi[0] || tb[1] > qhi[1] || tb[2] > qhi[2] ||
                            tb[3] < qlo[0] || tb[4] < qlo[1] || tb[5] < qlo[2])
                            continue;
                        if (!as_bvh_seg_box(a, d, inv, tb, tb + 3)) continue;
                        /* a triangle met in several cells is tested once (up to 16) */
                        int again = 0;
                        for (int q = 0; q < ntri && !again; q++) again = tried[q] == sl;
                        if (again) continue;
                        if (ntri < 16) tried[ntri++] = sl;
                        as_near_try(b, sl, a, c, d, ref, best, bt, btri, x);
                    }
                }
    }
}

/*
 * as_bvh_segment_nearest — see bvh.h.
 * design: a contact x is computed from the rounded t of as_segment_triangle, so it may lie
 * outside its triangle's box by a few ulps of the coordinates; a box (or a piece of the
 * segment) is pruned only when its distance to ref exceeds the best distance by more than
 * tol = 1e-9 of the coordinates' magnitude (and a relative 1e-9), so no contact at or
 * below the best distance is skipped and the answer is the exhaustive scan's — unless a
 * computed t is off by more than that, which only a segment nearly parallel to a triangle
 * can cause (its crossing point is then ill-conditioned whichever way it is found).
 */
int as_bvh_segment_nearest(const as_bvh *b, const double a[3], const double c[3],
                           const double ref[3], double x[3]) {
    if (!b->tc || b->nnodes == 0) return 0;
    double d[3], inv[3], mag = 0;
    as_sub3(c, a, d);
    for (int k = 0; k < 3; k++) {
        inv[k] = d[k] != 0 ? 1.0 / d[k] : 0.0;
        mag = as_dmax(mag, as_dmax(fabs(a[k]), as_dmax(fabs(c[k]), fabs(ref[k]))));
    }
    double best = INFINITY, bt = 0;
    int32_t btri = -1;
    const double tol = 1e-9 * mag;
    if (b->gside) {
        double len = as_dmax(fabs(d[0]), as_dmax(fabs(d[1]), fabs(d[2])));
        double np = ceil(len * b->ginv * (1 / 0.9));
        if (np < 1) np = 1;
        if (np <= AS_BVH_SEG_PIECES) {
            as_bvh_near_grid(b, a, c, d, inv, ref, tol, (int32_t)np, &best, &bt, &btri, x);
            return btri >= 0;
        }
    }
    as_bvh_walk w; /* the tree, pruning boxes farther from ref than the best contact */
    memset(&w, 0, sizeof w);
    w.mode = AS_WALK_NEAREST;
    w.ref = ref;
    w.best = INFINITY;
    w.lim = INFINITY;
    w.tol = tol;
    w.btri = -1;
    w.x = x;
    as_bvh_seg_walk(b, a, c, &w);
    return w.btri >= 0;
}

size_t as_bvh_segment_count(const as_bvh *b, const double a[3], const double c[3],
                            size_t *proper) {
    as_bvh_walk w;
    memset(&w, 0, sizeof w);
    w.mode = AS_WALK_COUNT;
    as_bvh_seg_walk(b, a, c, &w);
    if (proper) *proper = w.proper;
    return w.count;
}

int as_bvh_ray_parity(const as_bvh *b, const double p[3], const double q[3]) {
    as_bvh_walk w;
    memset(&w, 0, sizeof w);
    w.mode = AS_WALK_PARITY;
    as_bvh_seg_walk(b, p, q, &w);
    return w.on ? -1 : w.parity;
}

/* ---- side ------------------------------------------------------------------------------- */

static int as_bvh_side_far(const as_bvh *b, const double p[3]);

/*
 * The side of p from the grid: the parity along [p, q], q the corner of p's cell nearest p
 * whose side is known (else another corner), over the triangles of that cell only: the
 * segment lies in the cell (convex), and every triangle whose box meets the grown cell is
 * in its list. 2 when p is not in the grown cell (rounding) or no corner's side is known.
 */
static int as_bvh_side_near(const as_bvh *b, const double p[3]) {
    int32_t base[3], near[3];
    for (int c = 0; c < 3; c++) {
        double u = (p[c] - b->g0[c]) * b->ginv;
        int32_t i = u < 0 ? 0 : (int32_t)u;
        if (i > b->ng[c] - 2) i = b->ng[c] - 2;
        double m = AS_BVH_CELL_MARGIN * b->gh;
        if (!(p[c] >= as_bvh_gcoord(b, c, i) - m && p[c] <= as_bvh_gcoord(b, c, i + 1) + m))
            return 2;
        base[c] = i;
        near[c] = u - (double)i >= 0.5;
    }
    const size_t cell = as_bvh_gnode(b, base[0], base[1], base[2]);
    for (int m = 0; m < 8; m++) {
        int32_t ix[3];
        for (int c = 0; c < 3; c++) ix[c] = base[c] + (near[c] ^ ((m >> c) & 1));
        int sq = b->gside[as_bvh_gnode(b, ix[0], ix[1], ix[2])];
        if (sq == 0) continue;
        const double q[3] = {as_bvh_gcoord(b, 0, ix[0]), as_bvh_gcoord(b, 1, ix[1]),
                             as_bvh_gcoord(b, 2, ix[2])};
        double d[3], inv[3];
        as_sub3(q, p, d);
        for (int k = 0; k < 3; k++) inv[k] = d[k] != 0 ? 1.0 / d[k] : 0.0;
        int parity = 0;
        for (uint32_t e = b->gstart[cell]; e < b->gstart[cell + 1]; e++) {
            uint32_t sl = b->gslot[e];
            const double *tb = b->gbox + 6 * (size_t)sl;
            if (!as_bvh_seg_box(p, d, inv, tb, tb + 3)) continue;
            const double *u = b->tc + 9 * (size_t)sl, *v = u + 3, *w = u + 6;
            int r = as_segment_triangle_sos(p, q, u, v, w);
            if (r < 0) return 0;
            parity ^= r;
        }
        return parity ? -sq : sq;
    }
    return 2;
}

/*
 * as_bvh_side_grid — see bvh.h.
 * design:
 *   1. The cell: the side of the cube holding the box's volume divided by the node budget
 *      (the box's thin sides counted as a thousandth of its longest, so that a flat box
 *      still gets a grid); nodes from one cell below the box to at least one cell above
 *      it, so the first node of every line along x lies strictly outside the box: outside
 *      the closed mesh, checked exactly (no grid when rounding defeats it).
 *   2. Along each line, the side of node i+1 is that of the last node whose side is known
 *      xor the parity of the segment between them (as_bvh_ray_parity: exact, that node
 *      perturbed); a node on a triangle is marked unknown. Each segment is one or a few
 *      cells long, so the whole grid costs about one short walk per node.
 *   3. Each cell lists the triangles whose bounding box meets the cell grown by
 *      AS_BVH_CELL_MARGIN cells (closed comparisons), so a query walks no tree at all.
 *   design: the long segment of as_bvh_side crosses the whole model: on knot1.off (6,400
 *   triangles, a thin tube in a large box) 227,237 side queries took 16% of a run's
 *   instructions, about 6,000 each.
 */
anistar_status as_bvh_side_grid(anistar_context *ctx, as_bvh *b, size_t max_nodes) {
    if (!b->tc || b->nnodes == 0 || b->gside) return ANISTAR_OK;
    if (max_nodes == 0)
        max_nodes = b->n < AS_BVH_GRID_MAX / AS_BVH_GRID_PER_TRI ? AS_BVH_GRID_PER_TRI * b->n
                                                                : AS_BVH_GRID_MAX;
    if (max_nodes < 512) max_nodes = 512;
    const double *lo = b->nodes[0].lo, *hi = b->nodes[0].hi;
    double ext = 0;
    for (int c = 0; c < 3; c++) ext = fmax(ext, hi[c] - lo[c]);
    if (!(ext > 0) || !isfinite(ext)) return ANISTAR_OK;
    double vol = 1;
    for (int c = 0; c < 3; c++) vol *= fmax(hi[c] - lo[c], 1e-3 * ext);
    double h = cbrt(vol / (double)max_nodes);
    int32_t ng[3];
    for (;;) { /* the thin sides' extra nodes may be too many: grow h until they fit */
        double cnt = 1;
        for (int c = 0; c < 3; c++) {
            double m = ceil((hi[c] - lo[c]) / h) + 3;
            ng[c] = (int32_t)fmin(m, 1e9);
            cnt *= m;
        }
        if (cnt <= (double)max_nodes * 2 || !isfinite(h)) break;
        h *= 1.1;
    }
    if (!isfinite(h) || !(h > 0)) return ANISTAR_OK;
    as_bvh G = *b; /* the grid is built here and given to b at the end */
    G.gh = h;
    G.ginv = 1 / h;
    for (int c = 0; c < 3; c++) {
        G.g0[c] = lo[c] - h;
        G.ng[c] = ng[c];
        /* node 0 strictly below the box and the last one strictly above it */
        if (!(as_bvh_gcoord(&G, c, 0) < lo[c]) || !(as_bvh_gcoord(&G, c, ng[c] - 1) > hi[c]))
            return ANISTAR_OK;
    }
    const size_t n = as_bvh_gcount(&G);
    G.gside = as_alloc(ctx, n);
    G.gstart = as_alloc_array(ctx, n + 1, sizeof *G.gstart);
    G.gslot = NULL;
    G.gbox = as_alloc_array(ctx, b->n, 6 * sizeof *G.gbox);
    if (!G.gside || !G.gstart || !G.gbox) goto nomem;
    for (size_t t = 0; t < b->n; t++) {
        const double *u = b->tc + 9 * t;
        double *tb = G.gbox + 6 * t;
        for (int c = 0; c < 3; c++) {
            tb[c] = fmin(fmin(u[c], u[3 + c]), u[6 + c]);
            tb[3 + c] = fmax(fmax(u[c], u[3 + c]), u[6 + c]);
        }
    }
    /* 2. the nodes' sides */
    for (int32_t k = 0; k < ng[2]; k++)
        for (int32_t j = 0; j < ng[1]; j++) {
            int8_t *line = G.gside + as_bvh_gnode(&G, 0, j, k);
            double q[3] = {as_bvh_gcoord(&G, 0, 0), as_bvh_gcoord(&G, 1, j),
                           as_bvh_gcoord(&G, 2, k)};
            int sq = -1; /* node 0: outside the box */
            line[0] = -1;
            for (int32_t i = 1; i < ng[0]; i++) {
                const double p[3] = {as_bvh_gcoord(&G, 0, i), q[1], q[2]};
                int r = as_bvh_ray_parity(b, p, q);
                if (r < 0) {
                    line[i] = 0;
                    continue;
                }
                sq = r ? -sq : sq;
                line[i] = (int8_t)sq;
                q[0] = p[0];
            }
        }
    /* 3. the cells' triangles (CSR: count, prefix sums, fill); a cell (i, j, k) is the
     * box of nodes i..i+1, j..j+1, k..k+1 and is stored at node (i, j, k) */
    memset(G.gstart, 0, (n + 1) * sizeof *G.gstart);
    size_t total = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t t = 0; t < b->n; t++) {
            const double *tb = G.gbox + 6 * t;
            int32_t r0[3], r1[3]; /* the cells whose grown box meets the triangle's */
            for (int c = 0; c < 3; c++)
                as_bvh_cell_range(&G, c, tb[c], tb[3 + c], &r0[c], &r1[c]);
            for (int32_t k = r0[2]; k <= r1[2]; k++)
                for (int32_t j = r0[1]; j <= r1[1]; j++)
                    for (int32_t i = r0[0]; i <= r1[0]; i++) {
                        size_t id = as_bvh_gnode(&G, i, j, k);
                        if (pass == 0) G.gstart[id + 1]++;
                        else G.gslot[G.gstart[id]++] = (uint32_t)t;
                    }
        }
        if (pass == 0) {
            for (size_t id = 0; id < n; id++) {
                if (G.gstart[id + 1] > UINT32_MAX - G.gstart[id]) {
                    as_free(ctx, G.gside, n);
                    as_free(ctx, G.gstart, (n + 1) * sizeof *G.gstart);
                    as_free(ctx, G.gbox, 6 * b->n * sizeof *G.gbox);
                    return ANISTAR_OK; /* too many entries for 32-bit offsets: no grid */
                }
                G.gstart[id + 1] += G.gstart[id];
            }
            total = G.gstart[n];
            G.gslot = as_alloc_array(ctx, total ? total : 1, sizeof *G.gslot);
            if (!G.gslot) goto nomem;
        } else { /* the fill advanced each start to the next cell's: shift back */
            for (size_t id = n; id > 0; id--) G.gstart[id] = G.gstart[id - 1];
            G.gstart[0] = 0;
        }
    }
    G.gnslot = total ? total : 1;
    *b = G;
    return ANISTAR_OK;
nomem:
    as_free(ctx, G.gside, n);
    as_free(ctx, G.gstart, (n + 1) * sizeof *G.gstart);
    as_free(ctx, G.gbox, 6 * b->n * sizeof *G.gbox);
    return as_fail(ctx, ANISTAR_ENOMEM, "bvh: out of memory (side grid)");
}

/*
 * as_bvh_side — see bvh.h.
 * design:
 *   1. Outside the bounding box: outside (no triangle there).
 *   2. Pick the nearest face of the box (axis k, direction s); q = p moved along k to a
 *      coordinate strictly beyond that face (checked exactly; the margin doubles until it
 *      is), tilted on the other axes by fixed irrational-looking fractions of the
 *      length, so that axis-aligned meshes rarely need the symbolic perturbation.
 *   3. q is outside the box, hence outside the closed surface: the parity of
 *      as_bvh_ray_parity(p, q) is the side of p (exact; -1 means p is on a triangle).
 */
int as_bvh_side(const as_bvh *b, const double p[3]) {
    if (!b->tc || b->nnodes == 0) return -1;
    const double *lo = b->nodes[0].lo, *hi = b->nodes[0].hi;
    for (int k = 0; k < 3; k++)
        if (p[k] < lo[k] || p[k] > hi[k]) return -1;
    if (b->gside) {
        int r = as_bvh_side_near(b, p);
        if (r != 2) return r;
    }
    return as_bvh_side_far(b, p);
}

/* as_bvh_side by the long segment (p inside the bounding box). */
static int as_bvh_side_far(const as_bvh *b, const double p[3]) {
    const double *lo = b->nodes[0].lo, *hi = b->nodes[0].hi;
    int axis = 0, dir = 1;
    double best = INFINITY, ext = 0;
    for (int k = 0; k < 3; k++) {
        if (hi[k] - lo[k] > ext) ext = hi[k] - lo[k];
        if (p[k] - lo[k] < best) {
            best = p[k] - lo[k];
            axis = k;
            dir = -1;
        }
        if (hi[k] - p[k] < best) {
            best = hi[k] - p[k];
            axis = k;
            dir = 1;
        }
    }
    double face = dir > 0 ? hi[axis] : lo[axis];
    double margin = 0.25 * ext + 1e-6 * fabs(face) + 1e-300;
    double q[3];
    for (;;) {
        q[axis] = face + dir * margin;
        if (dir > 0 ? q[axis] > face : q[axis] < face) break;
        margin *= 2;
    }
    double len = fabs(q[axis] - p[axis]);
    static const double tilt[2] = {0.3183098861837907, 0.2078795763507619};
    q[(axis + 1) % 3] = p[(axis + 1) % 3] + tilt[0] * len;
    q[(axis + 2) % 3] = p[(axis + 2) % 3] - tilt[1] * len;
    int r = as_bvh_ray_parity(b, p, q);
    return r < 0 ? 0 : (r ? 1 : -1);
}

/* ---- closest point ----------------------------------------------------------------------- */

static inline double as_box_d2(const double *lo, const double *hi, const double *q) {
    double g[3];
    for (int a = 0; a < 3; a++) {
        if (q[a] < lo[a])
            g[a] = lo[a] - q[a];
        else if (q[a] > hi[a])
            g[a] = q[a] - hi[a];
        else
            g[a] = 0;
    }
    return (g[0] * g[0] + g[1] * g[1]) + g[2] * g[2];
}

/*
 * as_bvh_closest — see bvh.h.
 * design: stack of (node, box lower bound); pop, drop if bound > best (equal bounds are
 * visited: a smaller id may tie); at a leaf run as_closest_on_triangle on each triangle;
 * at an internal node push the farther child, then the nearer (visited first).
 */
double as_bvh_closest(const as_bvh *b, const double p[3], double c[3], int32_t *tri) {
    double best = INFINITY, bc[3] = {NAN, NAN, NAN};
    int32_t bid = -1;
    if (b->tc && b->nnodes > 0) {
        struct {
            uint32_t node;
            double bound;
        } st[AS_BVH_STACK];
        int sp = 0;
        st[0].node = 0;
        st[0].bound = as_box_d2(b->nodes[0].lo, b->nodes[0].hi, p);
        sp = 1;
        while (sp > 0) {
            sp--;
            if (st[sp].bound > best) continue;
            uint32_t ni = st[sp].node;
            const as_bvh_node *nd = &b->nodes[ni];
            if (nd->right == 0) {
                for (uint32_t s = nd->begin; s < nd->begin + nd->count; s++) {
                    const double *u = b->tc + 9 * (size_t)s;
                    double cc[3];
                    double d2 = as_closest_on_triangle(p, u, u + 3, u + 6, cc);
                    if (d2 < best || (d2 == best && b->id[s] < bid)) {
                        best = d2;
                        bid = b->id[s];
                        memcpy(bc, cc, sizeof bc);
                    }
                }
                continue;
            }
            uint32_t l = ni + 1, r = nd->right;
            double bl = as_box_d2(b->nodes[l].lo, b->nodes[l].hi, p);
            double br = as_box_d2(b->nodes[r].lo, b->nodes[r].hi, p);
            if (br < bl) {
                uint32_t x = l;
                double y = bl;
                l = r;
                r = x;
                bl = br;
                br = y;
            }
            if (br <= best) {
                st[sp].node = r;
                st[sp].bound = br;
                sp++;
            }
            if (bl <= best) {
                st[sp].node = l;
                st[sp].bound = bl;
                sp++;
            }
        }
    }
    if (c) memcpy(c, bc, sizeof bc);
    if (tri) *tri = bid;
    return best;
}

/* ---- box queries ------------------------------------------------------------------------- */

static void as_bvh_slot_box(const as_bvh *b, size_t s, double lo[3], double hi[3]) {
    if (b->bx) {
        memcpy(lo, b->bx + 6 * s, 3 * sizeof *lo);
        memcpy(hi, b->bx + 6 * s + 3, 3 * sizeof *hi);
        return;
    }
    const double *u = b->tc + 9 * s;
    for (int k = 0; k < 3; k++) {
        lo[k] = hi[k] = u[k];
        for (int m = 1; m < 3; m++) {
            double x = u[3 * m + k];
            if (x < lo[k]) lo[k] = x;
            if (x > hi[k]) hi[k] = x;
        }
    }
}

static inline int as_box_meets(const double *alo, const double *ahi, const double *blo,
                               const double *bhi) {
    for (int k = 0; k < 3; k++)
        if (ahi[k] < blo[k] || alo[k] > bhi[k]) return 0;
    return 1;
}

static inline int as_box_within(const double *alo, const double *ahi, const double *blo,
                                const double *bhi) {
    for (int k = 0; k < 3; k++)
        if (alo[k] < blo[k] || ahi[k] > bhi[k]) return 0;
    return 1;
}

anistar_status as_bvh_query_box(anistar_context *ctx, const as_bvh *b, const double lo[3],
                                const double hi[3], as_idlist *out) {
    out->n = 0;
    if (b->nnodes == 0) return ANISTAR_OK;
    uint32_t st[AS_BVH_STACK];
    int sp = 0;
    st[sp++] = 0;
    while (sp > 0) {
        uint32_t ni = st[--sp];
        const as_bvh_node *nd = &b->nodes[ni];
        if (!as_box_meets(nd->lo, nd->hi, lo, hi)) continue;
        int all = as_box_within(nd->lo, nd->hi, lo, hi);
        if (nd->right && !all) {
            st[sp++] = nd->right;
            st[sp++] = ni + 1;
            continue;
        }
        for (uint32_t s = nd->begin; s < nd->begin + nd->count; s++) {
            double ilo[3], ihi[3];
            if (!all) {
                as_bvh_slot_box(b, s, ilo, ihi);
                if (!as_box_meets(ilo, ihi, lo, hi)) continue;
            }
            if (as_idlist_push(ctx, out, b->id[s]))
                return as_fail(ctx, ANISTAR_ENOMEM, "bvh: out of memory in a box query");
        }
    }
    as_ids_sort(out->ids, out->n);
    return ANISTAR_OK;
}

anistar_status as_bvh_query_point(anistar_context *ctx, const as_bvh *b, const double p[3],
                                  as_idlist *out) {
    return as_bvh_query_box(ctx, b, p, p, out);
}

/* ---- validation -------------------------------------------------------------------------- */

int as_bvh_check(anistar_context *ctx, const as_bvh *b) {
    if (b->n == 0) return b->nnodes == 0 ? 0 : -1;
    if (b->nnodes == 0 || b->nodes[0].begin != 0 || b->nodes[0].count != b->n) return -1;
    for (size_t ni = 0; ni < b->nnodes; ni++) {
        const as_bvh_node *nd = &b->nodes[ni];
        if (nd->count == 0 || (size_t)nd->begin + nd->count > b->n) return -1;
        double lo[3], hi[3];
        as_bvh_slot_box(b, nd->begin, lo, hi);
        for (uint32_t s = nd->begin + 1; s < nd->begin + nd->count; s++) {
            double ilo[3], ihi[3];
            as_bvh_slot_box(b, s, ilo, ihi);
            for (int k = 0; k < 3; k++) {
                if (ilo[k] < lo[k]) lo[k] = ilo[k];
                if (ihi[k] > hi[k]) hi[k] = ihi[k];
            }
        }
        for (int k = 0; k < 3; k++)
            if (lo[k] != nd->lo[k] || hi[k] != nd->hi[k]) return -1;
        if (nd->right == 0) {
            if (nd->count > AS_BVH_LEAF) return -1;
            continue;
        }
        if (nd->count <= AS_BVH_LEAF || nd->right <= ni + 1 || nd->right >= b->nnodes)
            return -1;
        const as_bvh_node *l = &b->nodes[ni + 1], *r = &b->nodes[nd->right];
        if (l->begin != nd->begin || l->count != nd->count / 2 ||
            r->begin != nd->begin + l->count || r->count != nd->count - l->count)
            return -1;
    }
    unsigned char *seen = as_alloc(ctx, b->n);
    if (!seen) return -1;
    memset(seen, 0, b->n);
    int ok = 1;
    for (size_t s = 0; s < b->n && ok; s++) {
        int32_t i = b->id[s];
        if (i < 0 || (size_t)i >= b->n || seen[i]) ok = 0;
        else seen[i] = 1;
    }
    as_free(ctx, seen, b->n);
    return ok ? 0 : -1;
}
