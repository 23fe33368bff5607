/*
 * selfx.c — exact self-intersection test of a triangle mesh (see selfx.h).
 */
#include "geom/selfx.h"

#include "geom/bvh.h"
#include "geom/kdtree.h"
#include "geom/predicates.h"

#include <math.h>

static inline int sgn(double x) { return (x > 0) - (x < 0); }

static inline const double *vtx(const double *xyz, int32_t i) { return xyz + 3 * (size_t)i; }

/* An axis k along which (u, v, w) projects to a non-degenerate triangle, and the sign of
 * that projection in the plane ((k+1)%3, (k+2)%3); -1 when the triangle is degenerate. */
static int proj_axis(const double *u, const double *v, const double *w, int *ns) {
    for (int k = 2; k >= 0; k--) {
        int s = sgn(as_orient2d_proj(u, v, w, (k + 1) % 3, (k + 2) % 3));
        if (s) {
            *ns = s;
            return k;
        }
    }
    return -1;
}

int as_tri_degenerate(const double *xyz, const int32_t *t) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) return 1;
    int ns;
    return proj_axis(vtx(xyz, t[0]), vtx(xyz, t[1]), vtx(xyz, t[2]), &ns) < 0;
}

/* The closed segment [a, b] meets the closed triangle (u, v, w). */
static int seg_meets(const double *a, const double *b, const double *u, const double *v,
                     const double *w) {
    return as_segment_triangle(a, b, u, v, w, NULL) != AS_HIT_NONE;
}

/* x lies in the plane of the non-degenerate triangle (p, c, d) and in the closed wedge of
 * its angle at p (so the segment [p, x] leaves p inside the triangle). */
static int in_wedge(const double *x, const double *p, const double *c, const double *d) {
    if (as_orient3d(p, c, d, x) != 0) return 0;
    int ns, k = proj_axis(p, c, d, &ns);
    if (k < 0) return 0;
    int i = (k + 1) % 3, j = (k + 2) % 3;
    return sgn(as_orient2d_proj(p, c, x, i, j)) * ns >= 0 &&
           sgn(as_orient2d_proj(p, x, d, i, j)) * ns >= 0;
}

int as_tri_pair_intersect(const double *xyz, const int32_t *ta, const int32_t *tb) {
    if (as_tri_degenerate(xyz, ta) || as_tri_degenerate(xyz, tb)) return 0;
    /* shared indices: sa[k] / sb[k] the corners of ta / tb holding the k-th one */
    int sa[3], sb[3], ns = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (ta[i] == tb[j]) {
                sa[ns] = i;
                sb[ns] = j;
                ns++;
            }
    const double *A[3], *B[3];
    for (int i = 0; i < 3; i++) {
        A[i] = vtx(xyz, ta[i]);
        B[i] = vtx(xyz, tb[i]);
    }
    if (ns >= 3) return 1;
    if (ns == 0) {
        for (int e = 0; e < 3; e++) {
            if (seg_meets(A[e], A[(e + 1) % 3], B[0], B[1], B[2])) return 1;
            if (seg_meets(B[e], B[(e + 1) % 3], A[0], A[1], A[2])) return 1;
        }
        return 0;
    }
    if (ns == 2) {
        /* T1 = (u, v, a), T2 = (u, v, b): the corners not shared */
        const double *u = A[sa[0]], *v = A[sa[1]];
        const double *a = A[3 - sa[0] - sa[1]], *b = B[3 - sb[0] - sb[1]];
        if (as_orient3d(u, v, a, b) != 0) return 0;
        int n1, k = proj_axis(u, v, a, &n1);
        int i = (k + 1) % 3, j = (k + 2) % 3;
        return sgn(as_orient2d_proj(u, v, a, i, j)) * sgn(as_orient2d_proj(u, v, b, i, j)) > 0;
    }
    /* one shared vertex p: T1 = (p, a1, a2), T2 = (p, b1, b2) */
    const double *p = A[sa[0]];
    const double *a1 = A[(sa[0] + 1) % 3], *a2 = A[(sa[0] + 2) % 3];
    const double *b1 = B[(sb[0] + 1) % 3], *b2 = B[(sb[0] + 2) % 3];
    if (seg_meets(a1, a2, B[0], B[1], B[2]) || seg_meets(b1, b2, A[0], A[1], A[2])) return 1;
    return in_wedge(a1, p, b1, b2) || in_wedge(a2, p, b1, b2) || in_wedge(b1, p, a1, a2) ||
           in_wedge(b2, p, a1, a2);
}

anistar_status as_self_intersections(anistar_context *ctx, const double *xyz, size_t nv,
                                     const int32_t *tri, size_t nt, size_t cap,
                                     int32_t *pairs, size_t npairs, size_t *count,
                                     int *capped) {
    *count = 0;
    *capped = 0;
    if (nt == 0) return ANISTAR_OK;
    as_bvh *b = NULL;
    anistar_status st = as_bvh_build_triangles(ctx, xyz, nv, tri, nt, &b);
    if (st != ANISTAR_OK) return st;
    as_idlist cand = {0};
    for (size_t i = 0; i < nt && !*capped; i++) {
        const int32_t *ti = tri + 3 * i;
        if (as_tri_degenerate(xyz, ti)) continue;
        double lo[3], hi[3];
        for (int k = 0; k < 3; k++) {
            lo[k] = hi[k] = vtx(xyz, ti[0])[k];
            for (int c = 1; c < 3; c++) {
                double x = vtx(xyz, ti[c])[k];
                lo[k] = fmin(lo[k], x);
                hi[k] = fmax(hi[k], x);
            }
        }
        st = as_bvh_query_box(ctx, b, lo, hi, &cand);
        if (st != ANISTAR_OK) break;
        for (size_t q = 0; q < cand.n; q++) {
            size_t j = (size_t)cand.ids[q];
            if (j <= i || !as_tri_pair_intersect(xyz, ti, tri + 3 * j)) continue;
            if (*count < npairs) {
                pairs[2 * *count] = (int32_t)i;
                pairs[2 * *count + 1] = (int32_t)j;
            }
            if (++*count == cap) {
                *capped = 1;
                break;
            }
        }
    }
    as_idlist_free(ctx, &cand);
    as_bvh_free(ctx, b);
    return st;
}
