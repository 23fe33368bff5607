/*
 * feature.c — medial points and the local feature size (paper 2.3; DESIGN.md 4.5). See
 * feature.h.
 */
#include "mesher/feature.h"

#include <math.h>
#include <string.h>

void as_feature_free(anistar_context *ctx, as_feature *fe) {
    if (fe->kd) as_kdtree_free(ctx, fe->kd);
    as_free(ctx, fe->pts, (size_t)fe->cap * 3 * sizeof *fe->pts);
    as_free(ctx, fe->rad, (size_t)fe->cap * sizeof *fe->rad);
    memset(fe, 0, sizeof *fe);
}

static inline double dot3(const double a[3], const double b[3]) {
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2];
}

static anistar_status add_point(anistar_context *ctx, as_feature *fe, const double c[3],
                                double rho) {
    if (fe->n == fe->cap) {
        size_t cap = fe->cap ? 2 * (size_t)fe->cap : 1024;
        double *p = as_realloc(ctx, fe->pts, (size_t)fe->cap * 3 * sizeof *p, cap * 3 * sizeof *p);
        if (!p) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (medial points)");
        fe->pts = p;
        double *r = as_realloc(ctx, fe->rad, (size_t)fe->cap * sizeof *r, cap * sizeof *r);
        if (!r) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (medial points)");
        fe->rad = r;
        fe->cap = (int32_t)cap;
    }
    memcpy(fe->pts + 3 * (size_t)fe->n, c, 3 * sizeof *c);
    fe->rad[fe->n++] = rho;
    return ANISTAR_OK;
}

/*
 * The medial ball of sample point i (q, unit direction d into the side): *rho and the
 * cosine of the separation angle at its center; *rho = +inf when none was found below
 * the bounding radius.
 */
static anistar_status medial_ball(anistar_context *ctx, const as_surface *surf,
                                  const as_kdtree *kd, const double *pts, int32_t i,
                                  const double d[3], double *rho_out, double *cos_out) {
    const double *q = pts + 3 * (size_t)i;
    const double R = surf->radius;
    double rho = R, cosang = -1; /* the ray's crossing: opposite, 180 degrees */
    int touched = 0;
    {
        /* the ray starts off q, past the crossing at q itself: 1e-9 R, or 64 times the
         * surface's tolerance far from the origin (where 1e-9 R is below the coordinates'
         * spacing: a unit sphere at x = 1e7 found its own point, medial balls of 1e-9,
         * and 2,319 feature insertions) */
        const double off = fmax(1e-9 * R, 64 * surf->tol);
        double a[3], b[3], x[3];
        for (int k = 0; k < 3; k++) {
            a[k] = q[k] + off * d[k];
            b[k] = q[k] + 2.0 * R * d[k];
        }
        int hit = 0;
        anistar_status s = as_surface_crossing(ctx, surf, a, b, a, &hit, x);
        if (s != ANISTAR_OK) return s;
        if (hit) {
            double w[3] = {x[0] - q[0], x[1] - q[1], x[2] - q[2]};
            double t = dot3(w, d);
            if (t > 0 && 0.5 * t < rho) {
                rho = 0.5 * t;
                touched = 1;
            }
        }
    }
    /* design: shrinking ball against the sample: each step the ball tangent at q through
     * the nearest sample point inside it; the radius falls strictly, so it ends */
    for (int it = 0; it < 64; it++) {
        double c[3];
        for (int k = 0; k < 3; k++) c[k] = q[k] + rho * d[k];
        int32_t ids[2];
        double d2[2];
        size_t m = as_kdtree_knn(kd, c, 2, ids, d2);
        int32_t j = -1;
        double dj = 0;
        for (size_t k = 0; k < m && j < 0; k++)
            if (ids[k] != i) {
                j = ids[k];
                dj = d2[k];
            }
        if (j < 0 || !(dj < rho * rho * (1 - 1e-12))) break;
        const double *sp = pts + 3 * (size_t)j;
        double w[3] = {sp[0] - q[0], sp[1] - q[1], sp[2] - q[2]};
        double den = 2 * dot3(d, w);
        if (!(den > 0)) break;
        double r = dot3(w, w) / den;
        if (!(r < rho)) break;
        rho = r;
        touched = 1;
        /* the separation angle at the new center between q and s */
        double u[3], v[3];
        for (int k = 0; k < 3; k++) {
            u[k] = q[k] - (q[k] + rho * d[k]);
            v[k] = sp[k] - (q[k] + rho * d[k]);
        }
        double nu = sqrt(dot3(u, u)), nv = sqrt(dot3(v, v));
        cosang = nu > 0 && nv > 0 ? dot3(u, v) / (nu * nv) : 1;
    }
    *rho_out = touched && rho < R ? rho : INFINITY;
    *cos_out = cosang;
    return ANISTAR_OK;
}

/*
 * Keep one medial point per cube of side h (the first in sample order: deterministic):
 * the medial balls of many sample points share a center (all of a sphere's inner balls
 * meet at its center) and a box query would return them all.
 */
static anistar_status thin_points(anistar_context *ctx, as_feature *fe, double h) {
    int32_t n = fe->n;
    uint64_t *key = as_alloc_array(ctx, (size_t)n, sizeof *key);
    int32_t *ord = as_alloc_array(ctx, (size_t)n, sizeof *ord);
    if (!key || !ord) {
        as_free(ctx, key, (size_t)n * sizeof *key);
        as_free(ctx, ord, (size_t)n * sizeof *ord);
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (medial points)");
    }
    for (int32_t i = 0; i < n; i++) {
        uint64_t k = 1469598103934665603ull;
        for (int j = 0; j < 3; j++) {
            int64_t c = (int64_t)floor(fe->pts[3 * (size_t)i + j] / h);
            k = (k ^ (uint64_t)c) * 1099511628211ull;
        }
        key[i] = k;
        ord[i] = i;
    }
    /* shell sort of the indices by (key, index) */
    for (int32_t gap = n / 2; gap > 0; gap /= 2)
        for (int32_t i = gap; i < n; i++) {
            int32_t x = ord[i], j = i;
            while (j >= gap && (key[ord[j - gap]] > key[x] ||
                                (key[ord[j - gap]] == key[x] && ord[j - gap] > x))) {
                ord[j] = ord[j - gap];
                j -= gap;
            }
            ord[j] = x;
        }
    /* keep the first of each run of equal keys (a hash collision only drops a point):
     * key[] then holds the marks */
    uint64_t prev = 0;
    for (int32_t i = 0; i < n; i++) {
        int32_t x = ord[i];
        uint64_t k = key[x];
        key[x] = (i == 0 || k != prev); /* key[] now holds the marks */
        prev = k;
    }
    int32_t m = 0;
    for (int32_t i = 0; i < n; i++) {
        if (!key[i]) continue;
        memmove(fe->pts + 3 * (size_t)m, fe->pts + 3 * (size_t)i, 3 * sizeof *fe->pts);
        fe->rad[m] = fe->rad[i];
        m++;
    }
    fe->n = m;
    as_free(ctx, key, (size_t)n * sizeof *key);
    as_free(ctx, ord, (size_t)n * sizeof *ord);
    return ANISTAR_OK;
}

/* The medial balls of a sample (as_feature_build's threads). */
typedef struct as_fball {
    const as_surface *surf;
    const as_kdtree *kd;
    const as_point_sample *smp;
    struct as_fball_out {
        double c[3], rho; /* rho = +inf: none kept */
    } *out;               /* 2 per sample point: the sides -n, +n */
} as_fball;

static anistar_status fball_task(void *arg, int32_t i, int t, anistar_context *ctx) {
    (void)t;
    const as_fball *B = arg;
    const double *q = B->smp->points + 3 * (size_t)i;
    const double cos_max = cos(AS_FEATURE_ANGLE);
    struct as_fball_out *o = B->out + 2 * (size_t)i;
    o[0].rho = o[1].rho = INFINITY;
    double n[3];
    int sing = 0;
    anistar_status s = as_surface_normal_at(ctx, B->surf, q, n, &sing);
    if (s != ANISTAR_OK || sing) return s;
    for (int side = -1; side <= 1; side += 2) {
        double d[3] = {side * n[0], side * n[1], side * n[2]}, rho, cosang;
        if ((s = medial_ball(ctx, B->surf, B->kd, B->smp->points, i, d, &rho, &cosang)) !=
            ANISTAR_OK)
            return s;
        if (!isfinite(rho) || cosang > cos_max) continue;
        struct as_fball_out *x = &o[(side + 1) / 2];
        for (int k = 0; k < 3; k++) x->c[k] = q[k] + rho * d[k];
        x->rho = rho;
    }
    return ANISTAR_OK;
}

anistar_status as_feature_build(anistar_context *ctx, const as_surface *surf, as_sampler *sp,
                                as_pool *pool, as_feature *fe) {
    memset(fe, 0, sizeof *fe);
    struct as_fball_out *ball = NULL;
    as_point_sample smp;
    anistar_status s = sp ? as_sampler_sample(ctx, sp, AS_FEATURE_SAMPLE, &smp)
                          : as_surface_sample(ctx, surf, AS_FEATURE_SAMPLE, &smp);
    if (s != ANISTAR_OK) return s;
    as_kdtree *kd = NULL;
    if ((s = as_kdtree_build(ctx, smp.points, NULL, smp.n, &kd)) != ANISTAR_OK) goto done;
    /* design: the floor is the surface's own resolution: a fraction of the mean edge of
     * a triangle mesh, of a voxel of an image (about half the grid spacing); an implicit
     * function is exact, its floor only numerical: 1e-4 of its size, the bounding radius
     * or, when that is looser than the sample's extent, the diameter of the sample's box
     * (a unit sphere given a bounding radius of 1e4 had a floor of 1, so an hmin of 1, and
     * was "certified" with 9 vertices and a mean error of a quarter of its radius; the
     * usual bounds hold S within a diameter, and there the floor is unchanged) */
    double ext = surf->radius;
    if (smp.n > 0) {
        double lo[3], hi[3];
        memcpy(lo, smp.points, sizeof lo);
        memcpy(hi, smp.points, sizeof hi);
        for (size_t i = 1; i < smp.n; i++)
            for (int k = 0; k < 3; k++) {
                double x = smp.points[3 * i + (size_t)k];
                if (x < lo[k]) lo[k] = x;
                if (x > hi[k]) hi[k] = x;
            }
        double d2 = 0;
        for (int k = 0; k < 3; k++) d2 += (hi[k] - lo[k]) * (hi[k] - lo[k]);
        if (sqrt(d2) < ext) ext = sqrt(d2);
    }
    fe->floor_e = as_surface_is_mesh(surf)    ? smp.spacing / 8
                  : as_surface_is_image(surf) ? smp.spacing / 2
                                              : 1e-4 * ext;
    if (!(fe->floor_e > 0)) fe->floor_e = 1e-4 * surf->radius;
    /* design: the medial balls of the sample points on the threads (each reads only the
     * surface and the sample's kd-tree), then kept in the points' order: the same medial
     * points for any thread count */
    ball = as_alloc_array(ctx, smp.n ? 2 * smp.n : 1, sizeof *ball);
    if (!ball) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (medial points)");
        goto done;
    }
    as_fball B = {surf, kd, &smp, ball};
    if (pool) {
        s = as_pool_run(pool, (int32_t)smp.n, fball_task, &B);
    } else {
        for (size_t i = 0; i < smp.n && s == ANISTAR_OK; i++)
            s = fball_task(&B, (int32_t)i, 0, ctx);
    }
    for (size_t i = 0; i < 2 * smp.n && s == ANISTAR_OK; i++)
        if (isfinite(ball[i].rho)) s = add_point(ctx, fe, ball[i].c, ball[i].rho);
    if (s != ANISTAR_OK) goto done;
    if (fe->n > 0) s = thin_points(ctx, fe, 0.25 * (smp.spacing > 0 ? smp.spacing : fe->floor_e));
    if (s == ANISTAR_OK && fe->n > 0)
        s = as_kdtree_build(ctx, fe->pts, NULL, (size_t)fe->n, &fe->kd);
done:
    if (ball) as_free(ctx, ball, (smp.n ? 2 * smp.n : 1) * sizeof *ball);
    if (kd) as_kdtree_free(ctx, kd);
    as_surface_sample_free(ctx, &smp);
    if (s != ANISTAR_OK) as_feature_free(ctx, fe);
    return s;
}

anistar_status as_feature_lfs(anistar_context *ctx, const as_feature *fe,
                              const as_metric_frame *mf, const double p[3], double need,
                              as_idlist *scratch, double *lfs, int *exact) {
    *exact = 1;
    *lfs = INFINITY;
    if (!fe->kd) return ANISTAR_OK;
    const double floor_m = mf->e[2] * fe->floor_e;
    enum { K = 8 };
    int32_t ids[K];
    double d2[K];
    size_t m = as_kdtree_knn(fe->kd, p, K, ids, d2);
    if (m == 0) return ANISTAR_OK;
    double lb = mf->e[0] * sqrt(d2[0]);
    if (need > 0 && lb > need) {
        *exact = 0;
        *lfs = lb > floor_m ? lb : floor_m;
        return ANISTAR_OK;
    }
    /* design: an upper bound from the K Euclidean-nearest, then every medial point in
     * the box of the M-ball of that radius: the exact minimum */
    double ub = INFINITY;
    for (size_t k = 0; k < m; k++) {
        double d = as_metric_dist(mf, p, fe->pts + 3 * (size_t)ids[k]);
        if (d < ub) ub = d;
    }
    double h[3], lo[3], hi[3];
    as_metric_ellipsoid_box(mf, ub * (1 + 1e-9), h);
    for (int k = 0; k < 3; k++) {
        lo[k] = p[k] - h[k];
        hi[k] = p[k] + h[k];
    }
    anistar_status s = as_kdtree_box_any(ctx, fe->kd, lo, hi, 0, scratch);
    if (s != ANISTAR_OK) return s;
    double best = ub;
    for (size_t k = 0; k < scratch->n; k++) {
        double d = as_metric_dist(mf, p, fe->pts + 3 * (size_t)scratch->ids[k]);
        if (d < best) best = d;
    }
    *lfs = best > floor_m ? best : floor_m;
    return ANISTAR_OK;
}
