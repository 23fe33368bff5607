/*
 * mesh.c — closed triangle meshes as surfaces (DESIGN.md 4.6): validation and
 * orientation, the oracle (side by ray parity, segment crossings and closest points
 * through an AABB tree), per-vertex jets (paper 5.2.3) for normals and curvatures, and
 * initial points from the vertices.
 *
 * What the oracle answers:
 *  - side(p): exact (as_bvh_side: ray parity with symbolic perturbation); beyond the
 *    bounding sphere: outside; on a triangle: 0;
 *  - crossing(a, b, ref): every point where the closed segment meets a triangle (exact
 *    contact test; the point itself in floating point), the one nearest ref (the list of
 *    contacts is allocated through ctx, or the surface's context when ctx is NULL: ENOMEM
 *    is possible; a tangential touch counts as meeting S);
 *  - project(p): the exact closest point of the mesh (as_bvh_closest), so the distance is
 *    the true distance to the polyhedron;
 *  - frame(p) (normal, curvatures, directions): at the closest point q of p, on the
 *    triangle holding q, the per-vertex jet normals and curvature tensors
 *    C_v = k0 d0 d0^T + k1 d1 d1^T interpolated barycentrically, the normal renormalised,
 *    C projected on its tangent plane and diagonalised. This normal is continuous on the
 *    mesh (the face normal is not) and smooth-ish like the underlying smooth surface; at a
 *    vertex it is the jet's normal, and the curvatures are the jet's;
 *  - sample: input vertices, spread over every connected component (farthest-point
 *    sampling per component, shares proportional to the vertex counts, at least one);
 *    `area` is the exact area of each component (the sum of its triangles' areas),
 *    `spacing` the mean edge length.
 * Per-vertex jets: degree 2 on the AS_JET_K2 nearest vertices (Euclidean, the vertex
 * included), skipping neighbours whose angle-weighted vertex normal points against the
 * vertex's (n_u . n_v <= -0.5: the other side of a thin plate), oriented by the
 * angle-weighted vertex normal of the oriented mesh. A fit whose normal is more than 45
 * degrees from the angle-weighted normal is redone over that normal's tangent plane; a
 * failed fit (degenerate or folded neighbourhood) gives the angle-weighted normal and
 * zero curvatures; a normal more than 30 degrees from the angle-weighted normal, or that
 * sees an incident face from behind (sharp creases), is replaced by the angle-weighted
 * normal (curvatures kept, directions projected).
 */
#include "surface/surface.h"

#include "geom/bvh.h"
#include "geom/kdtree.h"
#include "io/meshio.h"
#include "surface/jet.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* A jet whose normal is farther than 45 degrees from the angle-weighted vertex normal is
 * refitted over the latter's tangent plane (folded neighbourhoods: thin tips, ridges). */
#define AS_MESH_JET_COS 0.7071067811865476
/* A jet normal still farther than 30 degrees from the angle-weighted normal (sharp
 * creases, where the fit follows one side) is replaced by it: the angle-weighted normal
 * bisects creases, so a small step along it leaves S on the right side, which the
 * one-sided jet normal does not guarantee at non-convex crease vertices. */
#define AS_MESH_NORMAL_COS 0.8660254037844387

/* Doubles per vertex in the jet table: n[3], k[2], d[6]. */
#define VJ AS_MESH_VJET

typedef struct as_mesh_surface {
    as_surface base;
    size_t nv, nt;
    double *xyz;    /* 3 nv */
    int32_t *tri;   /* 3 nt, counterclockwise seen from outside */
    double *vjet;   /* VJ nv */
    double *vnorm;  /* 3 nv: angle-weighted vertex normals */
    int32_t *vcomp; /* nv: connected component */
    size_t ncomp;
    long long *ceuler; /* ncomp: Euler characteristic of each component */
    size_t nv_in;   /* input vertices */
    int32_t *vmap;  /* nv_in: input vertex -> vertex or -1 (unused); NULL: identity */
    as_bvh *bvh;
    as_kdtree *kd;
    double spacing; /* mean edge length */
} as_mesh_surface;

static inline double v3_dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline double v3_norm(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline void v3_cross(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline double v3_dist2(const double a[3], const double b[3]) {
    double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return d0 * d0 + d1 * d1 + d2 * d2;
}

/* An orthonormal tangent pair (t1, t2) with (t1, t2, n) right-handed. */
static void tangent_basis(const double n[3], double t1[3], double t2[3]) {
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(n[i]) < fabs(n[k])) k = i;
    double e[3] = {0, 0, 0};
    e[k] = 1;
    v3_cross(n, e, t1);
    double l = v3_norm(t1);
    for (int i = 0; i < 3; i++) t1[i] /= l;
    v3_cross(n, t1, t2);
}

static const as_surface_ops mesh_ops;

int as_surface_is_mesh(const as_surface *s) { return s && s->ops == &mesh_ops; }

/* ---- destruction ---------------------------------------------------------------- */

static void ms_free(as_mesh_surface *ms) {
    anistar_context *ctx = ms->base.ctx;
    as_free(ctx, ms->xyz, ms->nv * 3 * sizeof(double));
    as_free(ctx, ms->tri, ms->nt * 3 * sizeof(int32_t));
    as_free(ctx, ms->vjet, ms->nv * VJ * sizeof(double));
    as_free(ctx, ms->vnorm, ms->nv * 3 * sizeof(double));
    as_free(ctx, ms->vcomp, ms->nv * sizeof(int32_t));
    as_free(ctx, ms->ceuler, ms->ncomp * sizeof(long long));
    as_free(ctx, ms->vmap, ms->nv_in * sizeof(int32_t));
    as_bvh_free(ctx, ms->bvh);
    as_kdtree_free(ctx, ms->kd);
    as_free(ctx, ms, sizeof *ms);
}

static void ms_destroy(as_surface *s) { ms_free((as_mesh_surface *)s); }

/* ---- per-vertex quantities -------------------------------------------------------- */

/* Angle-weighted vertex normals (Thuermer and Wuethrich) of the oriented mesh. */
static void vertex_normals(const as_mesh_surface *ms, double *vn) {
    memset(vn, 0, ms->nv * 3 * sizeof(double));
    for (size_t t = 0; t < ms->nt; t++) {
        const int32_t *c = ms->tri + 3 * t;
        const double *p[3] = {ms->xyz + 3 * (size_t)c[0], ms->xyz + 3 * (size_t)c[1],
                              ms->xyz + 3 * (size_t)c[2]};
        double e1[3], e2[3], fn[3];
        for (int i = 0; i < 3; i++) {
            e1[i] = p[1][i] - p[0][i];
            e2[i] = p[2][i] - p[0][i];
        }
        v3_cross(e1, e2, fn);
        double l = v3_norm(fn);
        if (!(l > 0)) continue;
        for (int i = 0; i < 3; i++) fn[i] /= l;
        for (int k = 0; k < 3; k++) {
            const double *a = p[k], *b = p[(k + 1) % 3], *d = p[(k + 2) % 3];
            double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            double w[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
            double cr[3];
            v3_cross(u, w, cr);
            double ang = atan2(v3_norm(cr), v3_dot(u, w));
            double *o = vn + 3 * (size_t)c[k];
            for (int i = 0; i < 3; i++) o[i] += ang * fn[i];
        }
    }
    for (size_t v = 0; v < ms->nv; v++) {
        double *o = vn + 3 * v;
        double l = v3_norm(o);
        if (l > 0)
            for (int i = 0; i < 3; i++) o[i] /= l;
    }
}

/* Replace the normal of a jet-table entry by n (unit), keeping the curvatures and
 * projecting the directions on the new tangent plane. */
static void use_normal(double *J, const double n[3]) {
    memcpy(J, n, 3 * sizeof(double));
    double *d0 = J + 5, *d1 = J + 8, dn = v3_dot(d0, n);
    for (int i = 0; i < 3; i++) d0[i] -= dn * n[i];
    double l = v3_norm(d0);
    if (l > 1e-6) {
        for (int i = 0; i < 3; i++) d0[i] /= l;
        v3_cross(n, d0, d1);
    } else {
        tangent_basis(n, d0, d1);
    }
}

/* The jet of vertex v: out[0..2] normal, out[3..4] curvatures, out[5..10] directions. */
static void vertex_jet(const as_mesh_surface *ms, size_t v, int degree, size_t k, double *out) {
    const double *p = ms->xyz + 3 * v, *nv = ms->vnorm + 3 * v;
    int32_t ids[AS_JET_MAX_POINTS];
    double d2[AS_JET_MAX_POINTS], pts[3 * AS_JET_MAX_POINTS];
    /* the k nearest; if some face the other way, fetch up to 2k to replace them */
    size_t got = as_kdtree_knn(ms->kd, p, k, ids, d2), m = 0;
    for (int pass = 0; pass < 2; pass++) {
        m = 0;
        for (size_t i = 0; i < got && m < k; i++) {
            const double *nu = ms->vnorm + 3 * (size_t)ids[i];
            if (ids[i] != (int32_t)v && v3_dot(nu, nv) <= -0.5) continue;
            memcpy(pts + 3 * m, ms->xyz + 3 * (size_t)ids[i], 3 * sizeof(double));
            m++;
        }
        if (m == k || got < k || pass == 1) break;
        size_t want = 2 * k < AS_JET_MAX_POINTS ? 2 * k : AS_JET_MAX_POINTS;
        got = as_kdtree_knn(ms->kd, p, want, ids, d2);
    }
    as_jet jet;
    int ok = as_jet_fit(pts, m, p, degree, NULL, nv, &jet) == 0 && jet.degree >= 2;
    if (!ok || v3_dot(jet.n, nv) < AS_MESH_JET_COS) {
        /* the neighbourhood is no graph over its PCA plane (a fold, a thin tip): fit over
         * the tangent plane of the angle-weighted normal instead */
        double fr[9];
        tangent_basis(nv, fr, fr + 3);
        memcpy(fr + 6, nv, 3 * sizeof(double));
        ok = as_jet_fit(pts, m, p, degree, fr, nv, &jet) == 0 && jet.degree >= 2 &&
             v3_dot(jet.n, nv) >= AS_MESH_JET_COS;
    }
    if (ok) {
        memcpy(out, jet.n, 3 * sizeof(double));
        memcpy(out + 3, jet.k, 2 * sizeof(double));
        memcpy(out + 5, jet.d, 6 * sizeof(double));
        if (v3_dot(jet.n, nv) < AS_MESH_NORMAL_COS) use_normal(out, nv);
        return;
    }
    memcpy(out, nv, 3 * sizeof(double));
    out[3] = out[4] = 0;
    tangent_basis(nv, out + 5, out + 8);
}

anistar_status as_mesh_surface_jets(anistar_context *ctx, const as_surface *s, int degree,
                                    size_t k, double *out) {
    if (!as_surface_is_mesh(s))
        return as_fail(ctx, ANISTAR_EINVAL, "jets: the surface is not a triangle mesh");
    if (degree < 2 || degree > 4)
        return as_fail(ctx, ANISTAR_EINVAL, "jets: degree must be 2, 3 or 4, got %d", degree);
    if (k < (size_t)as_jet_coef_count(degree) || k > AS_JET_MAX_POINTS)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "jets: k must be in [%d, %d] for degree %d, got %zu",
                       as_jet_coef_count(degree), AS_JET_MAX_POINTS, degree, k);
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    for (size_t v = 0; v < ms->nv; v++) vertex_jet(ms, v, degree, k, out + VJ * v);
    /* A normal must lie in the cone where every incident face is seen from outside
     * (n . face normal >= 0); otherwise (at sharp creases, where the jet follows one
     * side) moving along it leaves S on the wrong side. Such vertices take the
     * angle-weighted normal (the bisector at a crease), their curvatures are kept and
     * their directions projected on the new tangent plane. */
    for (size_t t = 0; t < ms->nt; t++) {
        const int32_t *c = ms->tri + 3 * t;
        double e1[3], e2[3], fn[3];
        for (int i = 0; i < 3; i++) {
            e1[i] = ms->xyz[3 * (size_t)c[1] + i] - ms->xyz[3 * (size_t)c[0] + i];
            e2[i] = ms->xyz[3 * (size_t)c[2] + i] - ms->xyz[3 * (size_t)c[0] + i];
        }
        v3_cross(e1, e2, fn);
        for (int j = 0; j < 3; j++) {
            double *J = out + VJ * (size_t)c[j];
            const double *vn = ms->vnorm + 3 * (size_t)c[j];
            if (v3_dot(J, fn) >= 0 || memcmp(J, vn, 3 * sizeof(double)) == 0) continue;
            use_normal(J, vn);
        }
    }
    return ANISTAR_OK;
}

void as_mesh_surface_info(const as_surface *s, as_mesh_info *info) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    info->nv = ms->nv;
    info->nt = ms->nt;
    info->xyz = ms->xyz;
    info->tri = ms->tri;
    info->vjet = ms->vjet;
    info->kd = ms->kd;
    info->bvh = ms->bvh;
    info->nv_in = ms->nv_in;
    info->vmap = ms->vmap;
    info->ncomponents = ms->ncomp;
    info->vcomp = ms->vcomp;
    info->ceuler = ms->ceuler;
    info->spacing = ms->spacing;
}

/* ---- oracle --------------------------------------------------------------------- */

static anistar_status ms_side(anistar_context *ctx, const as_surface *s, const double p[3],
                              int *side) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "side: point is not finite");
    if (v3_dist2(p, s->center) > s->radius * s->radius) {
        *side = 1;
        return ANISTAR_OK;
    }
    int b = as_bvh_side(ms->bvh, p); /* +1 inside, -1 outside, 0 on */
    *side = -b;
    return ANISTAR_OK;
}

static anistar_status ms_crossing(anistar_context *ctx, const as_surface *s, const double a[3],
                                  const double b[3], const double ref[3], int *found,
                                  double x[3]) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    *found = 0;
    for (int i = 0; i < 3; i++)
        if (!isfinite(a[i]) || !isfinite(b[i]) || !isfinite(ref[i]))
            return as_fail(ctx, ANISTAR_EINVAL, "crossing: a point is not finite");
    *found = as_bvh_segment_nearest(ms->bvh, a, b, ref, x);
    return ANISTAR_OK;
}

static anistar_status ms_project(anistar_context *ctx, const as_surface *s, const double p[3],
                                 double q[3]) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "projection: point is not finite");
    int32_t t;
    as_bvh_closest(ms->bvh, p, q, &t);
    if (t < 0) return as_fail(ctx, ANISTAR_EINTERNAL, "projection: empty mesh");
    return ANISTAR_OK;
}

/* Barycentric coordinates of q (a point of the triangle a b c), clamped to the
 * triangle. */
static void barycentric(const double a[3], const double b[3], const double c[3],
                        const double q[3], double l[3]) {
    double v0[3], v1[3], v2[3];
    for (int i = 0; i < 3; i++) {
        v0[i] = b[i] - a[i];
        v1[i] = c[i] - a[i];
        v2[i] = q[i] - a[i];
    }
    double d00 = v3_dot(v0, v0), d01 = v3_dot(v0, v1), d11 = v3_dot(v1, v1);
    double d20 = v3_dot(v2, v0), d21 = v3_dot(v2, v1);
    double den = d00 * d11 - d01 * d01;
    if (!(den > 0)) {
        l[0] = l[1] = l[2] = 1.0 / 3;
        return;
    }
    l[1] = (d11 * d20 - d01 * d21) / den;
    l[2] = (d00 * d21 - d01 * d20) / den;
    l[0] = 1 - l[1] - l[2];
    double sum = 0;
    for (int i = 0; i < 3; i++) {
        if (!(l[i] > 0)) l[i] = 0;
        sum += l[i];
    }
    for (int i = 0; i < 3; i++) l[i] = sum > 0 ? l[i] / sum : 1.0 / 3;
}

static void eig2(double a, double b, double c, double *w1, double *w2, double *cs, double *sn) {
    double mean = 0.5 * (a + c), r = hypot(0.5 * (a - c), b);
    double th = 0.5 * atan2(2 * b, a - c);
    *w1 = mean + r;
    *w2 = mean - r;
    *cs = cos(th);
    *sn = sin(th);
}

/* The frame at the point q of triangle t (see the top of the file). */
static void frame_on_triangle(const as_mesh_surface *ms, int32_t t, const double q[3],
                              as_surface_frame *fr) {
    const int32_t *c = ms->tri + 3 * (size_t)t;
    const double *p[3];
    for (int i = 0; i < 3; i++) p[i] = ms->xyz + 3 * (size_t)c[i];
    double l[3];
    barycentric(p[0], p[1], p[2], q, l);
    double n[3] = {0, 0, 0}, C[6] = {0, 0, 0, 0, 0, 0};
    for (int v = 0; v < 3; v++) {
        const double *J = ms->vjet + VJ * (size_t)c[v];
        const double *d0 = J + 5, *d1 = J + 8;
        double k0 = J[3], k1 = J[4];
        static const int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
        for (int i = 0; i < 3; i++) n[i] += l[v] * J[i];
        for (int e = 0; e < 6; e++) {
            int a = ij[e][0], b = ij[e][1];
            C[e] += l[v] * (k0 * d0[a] * d0[b] + k1 * d1[a] * d1[b]);
        }
    }
    double nl = v3_norm(n);
    if (!(nl > 1e-8)) { /* opposite vertex normals: the face normal */
        double e1[3], e2[3];
        for (int i = 0; i < 3; i++) {
            e1[i] = p[1][i] - p[0][i];
            e2[i] = p[2][i] - p[0][i];
        }
        v3_cross(e1, e2, n);
        nl = v3_norm(n);
    }
    for (int i = 0; i < 3; i++) fr->n[i] = n[i] / nl;
    double t1[3], t2[3], h1[3], h2[3];
    tangent_basis(fr->n, t1, t2);
    h1[0] = C[0] * t1[0] + C[1] * t1[1] + C[2] * t1[2];
    h1[1] = C[1] * t1[0] + C[3] * t1[1] + C[4] * t1[2];
    h1[2] = C[2] * t1[0] + C[4] * t1[1] + C[5] * t1[2];
    h2[0] = C[0] * t2[0] + C[1] * t2[1] + C[2] * t2[2];
    h2[1] = C[1] * t2[0] + C[3] * t2[1] + C[4] * t2[2];
    h2[2] = C[2] * t2[0] + C[4] * t2[1] + C[5] * t2[2];
    double cs, sn;
    eig2(v3_dot(t1, h1), 0.5 * (v3_dot(t1, h2) + v3_dot(t2, h1)), v3_dot(t2, h2), &fr->k[0],
         &fr->k[1], &cs, &sn);
    for (int i = 0; i < 3; i++) fr->d[i] = cs * t1[i] + sn * t2[i];
    v3_cross(fr->n, fr->d, fr->d + 3);
    fr->gnorm = 1;
    fr->singular = 0;
}

static anistar_status ms_frame(anistar_context *ctx, const as_surface *s, const double p[3],
                               as_surface_frame *fr) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    memset(fr, 0, sizeof *fr);
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "frame: point is not finite");
    double q[3];
    int32_t t;
    as_bvh_closest(ms->bvh, p, q, &t);
    if (t < 0) return as_fail(ctx, ANISTAR_EINTERNAL, "frame: empty mesh");
    frame_on_triangle(ms, t, q, fr);
    return ANISTAR_OK;
}

anistar_status as_mesh_surface_signed_distance(anistar_context *ctx, const as_surface *s,
                                               const double p[3], double *d, double g[3]) {
    if (!as_surface_is_mesh(s))
        return as_fail(ctx, ANISTAR_EINVAL, "signed distance: not a triangle-mesh surface");
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "signed distance: point is not finite");
    double q[3];
    int32_t t;
    double d2 = as_bvh_closest(ms->bvh, p, q, &t);
    if (t < 0) return as_fail(ctx, ANISTAR_EINTERNAL, "signed distance: empty mesh");
    int side = -as_bvh_side(ms->bvh, p);
    double dist = sqrt(d2);
    *d = side * dist;
    if (g) {
        if (side != 0 && dist > 0) {
            for (int i = 0; i < 3; i++) g[i] = side * (p[i] - q[i]) / dist;
        } else {
            as_surface_frame fr;
            frame_on_triangle(ms, t, q, &fr);
            memcpy(g, fr.n, 3 * sizeof(double));
        }
    }
    return ANISTAR_OK;
}

/* ---- initial points ---------------------------------------------------------------- */

static anistar_status ms_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                as_point_sample *out) {
    const as_mesh_surface *ms = (const as_mesh_surface *)s;
    anistar_context *c = ctx ? ctx : s->ctx;
    memset(out, 0, sizeof *out);
    if (max_points == 0) max_points = 64;
    size_t nc = ms->ncomp, nv = ms->nv;
    /* vertices sorted by component (counting sort) */
    size_t *start = as_alloc_array(c, nc + 1, sizeof(size_t));
    int32_t *order = as_alloc_array(c, nv, sizeof(int32_t));
    size_t total = max_points + nc;
    size_t ncand_max = 8 * total < nv ? 8 * total : nv;
    double *work = as_alloc_array(c, ncand_max, 4 * sizeof(double));
    out->points = as_alloc_array(c, total, 3 * sizeof(double));
    out->component = as_alloc_array(c, total, sizeof(int32_t));
    out->area = as_alloc_array(c, nc, sizeof(double));
    anistar_status st = ANISTAR_OK;
    if (!start || !order || !work || !out->points || !out->component || !out->area) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        goto done;
    }
    /* the exact area of each component: its triangles' areas */
    memset(out->area, 0, nc * sizeof(double));
    for (size_t t = 0; t < ms->nt; t++) {
        const int32_t *T = ms->tri + 3 * t;
        const double *a = ms->xyz + 3 * (size_t)T[0], *b = ms->xyz + 3 * (size_t)T[1],
                     *d = ms->xyz + 3 * (size_t)T[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
               v[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]}, w[3];
        v3_cross(u, v, w);
        out->area[ms->vcomp[T[0]]] += 0.5 * v3_norm(w);
    }
    memset(start, 0, (nc + 1) * sizeof(size_t));
    for (size_t v = 0; v < nv; v++) start[ms->vcomp[v] + 1]++;
    for (size_t k = 0; k < nc; k++) start[k + 1] += start[k];
    {
        size_t *fill = start; /* reuse: fill positions then restore */
        for (size_t v = 0; v < nv; v++) order[fill[ms->vcomp[v]]++] = (int32_t)v;
        for (size_t k = nc; k > 0; k--) start[k] = start[k - 1];
        start[0] = 0;
    }
    size_t n = 0;
    for (size_t k = 0; k < nc; k++) {
        size_t m = start[k + 1] - start[k];
        size_t q = (size_t)((double)max_points * (double)m / (double)nv);
        if (q < 1) q = 1;
        if (q > m) q = m;
        size_t stride = m > 8 * q ? m / (8 * q) : 1;
        size_t ncand = (m + stride - 1) / stride;
        if (ncand > ncand_max) ncand = ncand_max;
        /* work (4 ncand doubles): the candidates, then their farthest-point order */
        int32_t *pick = (int32_t *)(work + 3 * ncand);
        for (size_t i = 0; i < ncand; i++)
            memcpy(work + 3 * i, ms->xyz + 3 * (size_t)order[start[k] + i * stride],
                   3 * sizeof(double));
        size_t np = 0;
        if ((st = as_farthest_order(c, work, ncand, q, pick, &np)) != ANISTAR_OK) goto done;
        for (size_t i = 0; i < np; i++) {
            memcpy(out->points + 3 * n, work + 3 * (size_t)pick[i], 3 * sizeof(double));
            out->component[n++] = (int32_t)k;
        }
    }
    /* shrink to exactly n */
    {
        double *pts = as_alloc_array(c, n, 3 * sizeof(double));
        int32_t *cmp = as_alloc_array(c, n, sizeof(int32_t));
        if (!pts || !cmp) {
            as_free(c, pts, n * 3 * sizeof(double));
            as_free(c, cmp, n * sizeof(int32_t));
            st = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
            goto done;
        }
        memcpy(pts, out->points, n * 3 * sizeof(double));
        memcpy(cmp, out->component, n * sizeof(int32_t));
        as_free(c, out->points, total * 3 * sizeof(double));
        as_free(c, out->component, total * sizeof(int32_t));
        out->points = pts;
        out->component = cmp;
        out->n = n;
        out->ncomponents = nc;
        out->spacing = ms->spacing;
    }
done:
    if (st) {
        as_free(c, out->points, total * 3 * sizeof(double));
        as_free(c, out->component, total * sizeof(int32_t));
        as_free(c, out->area, nc * sizeof(double));
        memset(out, 0, sizeof *out);
    }
    as_free(c, start, (nc + 1) * sizeof(size_t));
    as_free(c, order, nv * sizeof(int32_t));
    as_free(c, work, ncand_max * 4 * sizeof(double));
    return st;
}

static const as_surface_ops mesh_ops = {"mesh",   NULL,     ms_side,   ms_crossing, ms_project,
                                        ms_frame, ms_sample, ms_destroy};

/* ---- construction ------------------------------------------------------------------ */

static int32_t uf_find(int32_t *uf, int32_t x) {
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}

/* Components through shared vertices: vcomp and ncomp. */
static void components(as_mesh_surface *ms) {
    int32_t *uf = ms->vcomp;
    for (size_t v = 0; v < ms->nv; v++) uf[v] = (int32_t)v;
    for (size_t t = 0; t < ms->nt; t++)
        for (int k = 1; k < 3; k++) {
            int32_t a = uf_find(uf, ms->tri[3 * t]), b = uf_find(uf, ms->tri[3 * t + k]);
            if (a < b) uf[b] = a;
            else if (b < a) uf[a] = b;
        }
    /* roots are the smallest index of their set (a larger root always joins a smaller
     * one), so in ascending order a root is labelled before its members */
    for (size_t v = 0; v < ms->nv; v++) uf[v] = uf_find(uf, (int32_t)v);
    size_t nc = 0;
    for (size_t v = 0; v < ms->nv; v++) {
        int32_t r = uf[v];
        uf[v] = r == (int32_t)v ? (int32_t)nc++ : uf[r];
    }
    ms->ncomp = nc;
}

/*
 * Orientation of nested components: as_topology_orient gives every closed component
 * positive volume, which is right for a component inside an even number of others; a
 * component inside an odd number (the wall of a cavity) must face inward. The nesting
 * parity of component c is the parity of the crossings, with the other components only,
 * of a segment from a vertex of c to a point outside the bounding box (exact, with the
 * symbolic perturbation of as_segment_triangle_sos).
 */
static anistar_status orient_nested(anistar_context *ctx, as_mesh_surface *ms) {
    if (ms->ncomp < 2) return ANISTAR_OK;
    double lo[3], hi[3];
    as_bvh_bounds(ms->bvh, lo, hi);
    size_t nc = ms->ncomp;
    unsigned char *flip = as_alloc(ctx, nc);
    size_t *first = as_alloc_array(ctx, nc, sizeof(size_t));
    as_bvh_hits hits = {0};
    anistar_status st = ANISTAR_OK;
    if (!flip || !first) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "mesh surface: out of memory");
        goto done;
    }
    memset(flip, 0, nc);
    for (size_t k = 0; k < nc; k++) first[k] = SIZE_MAX;
    for (size_t v = 0; v < ms->nv; v++)
        if (first[ms->vcomp[v]] == SIZE_MAX) first[ms->vcomp[v]] = v;
    for (size_t k = 0; k < nc; k++) {
        const double *p = ms->xyz + 3 * first[k];
        double q[3] = {hi[0] + 0.5 * (hi[0] - lo[0]) + 1, p[1] + 0.3183 * (hi[1] - lo[1]),
                       p[2] + 0.2079 * (hi[2] - lo[2])};
        if (as_bvh_segment(ctx, ms->bvh, p, q, &hits)) {
            st = as_fail(ctx, ANISTAR_ENOMEM, "mesh surface: out of memory");
            goto done;
        }
        size_t count = 0;
        for (size_t i = 0; i < hits.n; i++) {
            int32_t t = hits.h[i].tri;
            const int32_t *c = ms->tri + 3 * (size_t)t;
            if ((size_t)ms->vcomp[c[0]] == k) continue;
            if (as_segment_triangle_sos(p, q, ms->xyz + 3 * (size_t)c[0],
                                        ms->xyz + 3 * (size_t)c[1],
                                        ms->xyz + 3 * (size_t)c[2]) == 1)
                count++;
        }
        flip[k] = (unsigned char)(count & 1);
    }
    for (size_t t = 0; t < ms->nt; t++) {
        int32_t *c = ms->tri + 3 * t;
        if (flip[ms->vcomp[c[0]]]) {
            int32_t x = c[1];
            c[1] = c[2];
            c[2] = x;
        }
    }
done:
    as_bvh_hits_free(ctx, &hits);
    as_free(ctx, flip, nc);
    as_free(ctx, first, nc * sizeof(size_t));
    return st;
}

/* Coordinates must be finite, and 0 or of magnitude in [1e-100, 1e100] (the range in
 * which the topology's exact zero-area test is exact). */
static int coord_ok(double x) {
    double a = fabs(x);
    return isfinite(x) && (a == 0 || (a >= 1e-100 && a <= 1e100));
}

anistar_status as_mesh_surface_create(anistar_context *ctx, const char *name, const double *xyz,
                                      size_t nv, const int32_t *tri, size_t nt,
                                      as_surface **out) {
    *out = NULL;
    if (!name) name = "triangle mesh";
    if (!xyz || !tri || nv < 3 || nt < 1)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: needs at least 3 vertices and 1 triangle", name);
    if (nv >= (size_t)INT32_MAX || nt > AS_TOPOLOGY_MAX_TRIANGLES)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: too many vertices or triangles", name);
    for (size_t i = 0; i < 3 * nv; i++)
        if (!coord_ok(xyz[i]))
            return as_fail(ctx, ANISTAR_EINVAL,
                           "%s: vertex %zu: coordinate %g is not finite, or not 0 and outside "
                           "[1e-100, 1e100] in magnitude",
                           name, i / 3, xyz[i]);
    for (size_t i = 0; i < 3 * nt; i++)
        if (tri[i] < 0 || (size_t)tri[i] >= nv)
            return as_fail(ctx, ANISTAR_EINVAL, "%s: triangle %zu: vertex index %ld out of "
                           "range [0, %zu)", name, i / 3, (long)tri[i], nv);
    as_mesh_surface *ms = as_alloc(ctx, sizeof *ms);
    if (!ms) return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", name);
    memset(ms, 0, sizeof *ms);
    ms->base.ctx = ctx;
    ms->base.ops = &mesh_ops;
    anistar_status st = ANISTAR_OK;
    int32_t *ot = as_alloc_array(ctx, nt, 3 * sizeof(int32_t));
    if (!ot) {
        as_free(ctx, ms, sizeof *ms);
        return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", name);
    }
    memcpy(ot, tri, nt * 3 * sizeof(int32_t));
    ms->tri = ot;
    ms->nt = nt;
    /* 1. topology: closed, manifold, orientable, no zero-area triangle; orient outward */
    as_topology rep;
    st = as_topology_orient(ctx, nv, xyz, nt, ot, &rep);
    if (!st) st = as_topology_require(ctx, name, &rep);
    if (st) goto fail;
    /* 2. drop unused vertices */
    ms->nv_in = nv;
    if (rep.used_vertices < nv) {
        ms->vmap = as_alloc_array(ctx, nv, sizeof(int32_t));
        if (!ms->vmap) goto nomem;
        for (size_t v = 0; v < nv; v++) ms->vmap[v] = -1;
        for (size_t i = 0; i < 3 * nt; i++) ms->vmap[ot[i]] = 1;
        int32_t next = 0;
        for (size_t v = 0; v < nv; v++)
            if (ms->vmap[v] == 1) ms->vmap[v] = next++;
        ms->nv = (size_t)next;
    } else {
        ms->nv = nv;
    }
    ms->xyz = as_alloc_array(ctx, ms->nv, 3 * sizeof(double));
    ms->vjet = as_alloc_array(ctx, ms->nv, VJ * sizeof(double));
    ms->vnorm = as_alloc_array(ctx, ms->nv, 3 * sizeof(double));
    ms->vcomp = as_alloc_array(ctx, ms->nv, sizeof(int32_t));
    if (!ms->xyz || !ms->vjet || !ms->vnorm || !ms->vcomp) goto nomem;
    if (ms->vmap) {
        for (size_t v = 0; v < nv; v++)
            if (ms->vmap[v] >= 0)
                memcpy(ms->xyz + 3 * (size_t)ms->vmap[v], xyz + 3 * v, 3 * sizeof(double));
        for (size_t i = 0; i < 3 * nt; i++) ot[i] = ms->vmap[ot[i]];
    } else {
        memcpy(ms->xyz, xyz, nv * 3 * sizeof(double));
    }
    /* 3. spatial indexes; components and the orientation of nested ones */
    st = as_bvh_build_triangles(ctx, ms->xyz, ms->nv, ot, nt, &ms->bvh);
    if (!st) st = as_bvh_side_grid(ctx, ms->bvh, 0); /* side(p) by short segments */
    if (!st) st = as_kdtree_build(ctx, ms->xyz, NULL, ms->nv, &ms->kd);
    if (!st) {
        components(ms);
        /* design: closed 2-manifold, so E = 3F/2 per component and chi = V - F/2 */
        ms->ceuler = as_alloc_array(ctx, ms->ncomp, sizeof(long long));
        if (!ms->ceuler) goto nomem;
        memset(ms->ceuler, 0, ms->ncomp * sizeof(long long));
        for (size_t v = 0; v < ms->nv; v++) ms->ceuler[ms->vcomp[v]] += 2;
        for (size_t t = 0; t < nt; t++) ms->ceuler[ms->vcomp[ot[3 * t]]] -= 1;
        for (size_t k = 0; k < ms->ncomp; k++) ms->ceuler[k] /= 2;
        st = orient_nested(ctx, ms);
    }
    if (st) goto fail;
    /* 4. bounding sphere (1.1 times the farthest vertex from the box center), spacing */
    double lo[3], hi[3], c[3], r2 = 0, elen = 0;
    as_bvh_bounds(ms->bvh, lo, hi);
    for (int i = 0; i < 3; i++) c[i] = 0.5 * (lo[i] + hi[i]);
    for (size_t v = 0; v < ms->nv; v++) r2 = fmax(r2, v3_dist2(ms->xyz + 3 * v, c));
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++)
            elen += sqrt(v3_dist2(ms->xyz + 3 * (size_t)ot[3 * t + k],
                                  ms->xyz + 3 * (size_t)ot[3 * t + (k + 1) % 3]));
    ms->spacing = elen / (3.0 * (double)nt);
    st = as_surface_init(ctx, &ms->base, &mesh_ops, c, 1.1 * sqrt(r2));
    if (st) goto fail;
    /* 5. per-vertex normals and jets */
    vertex_normals(ms, ms->vnorm);
    st = as_mesh_surface_jets(ctx, &ms->base, 2, AS_JET_K2, ms->vjet);
    if (st) goto fail;
    *out = &ms->base;
    return ANISTAR_OK;
nomem:
    st = as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", name);
fail:
    ms_free(ms);
    return st;
}

anistar_status as_mesh_surface_read(anistar_context *ctx, const char *path, as_surface **out) {
    *out = NULL;
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status st = as_mesh_read(ctx, path, &m);
    if (!st) st = as_mesh_surface_create(ctx, path, m.xyz, m.nv, m.tri, m.nt, out);
    as_trimesh_free(ctx, &m);
    return st;
}
