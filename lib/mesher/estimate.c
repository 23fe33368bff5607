/*
 * estimate.c — the up-front estimate of a run's size (DESIGN.md 4.5). See refine.h.
 *
 * The count of a mesh that satisfies rule 1 everywhere follows from the sizing field: a
 * facet of circumradius h in the local metric covers an M-area of about that of the
 * ideal (equilateral) triangle of circumradius h, (3 sqrt 3 / 4) h^2, and a closed
 * triangulation has two facets per vertex, so
 *
 *     V ~ C * integral over S of sqrt(det M_tangent(p)) / ((3 sqrt 3 / 2) h(p)^2) dA
 *
 * with h(p) = min(r0, the distortion radius, alpha lfs(p), the approximation radius): the
 * sizes rule 1 enforces (r0; gamma0 through the rate at which the metric turns, paper
 * 2.2's distortion radius; the local feature size of paper 2.3; --approx through S's
 * curvature, est_task). C corrects for Delaunay refinement
 * ending with facets smaller than the bound (their circumradii spread over (h/2, h)):
 * it is measured, see AS_ESTIMATE_FILL. Rules 2 and 3 add a few percent.
 */
#include "mesher/refine.h"

#include <math.h>
#include <string.h>

/* Sample points of the integral (the surface's own sampler, area-weighted). */
#define AS_ESTIMATE_SAMPLE 1024

/* Measured ratio of the final vertex count to the ideal-triangle count on runs sized by
 * r0 alone (sphere and ellipsoid, euclidean, r0 from R/3 to R/100; docs/benchmarks.md). */
#define AS_ESTIMATE_FILL 1.7

/* Peak bytes per output vertex of a run (docs/benchmarks.md: 2.7-3.4 KB measured on the
 * torus, the shock sphere, the chair, knot1, fandisk, the bunny, the elephant and the
 * skull image). */
#define AS_ESTIMATE_BYTES_PER_VERTEX 3400.0

static inline double dot3(const double a[3], const double b[3]) {
    return (a[0] * b[0] + a[1] * b[1]) + a[2] * b[2];
}

/* An orthonormal tangent basis (t1, t2) of the unit normal n. */
static void tangent_basis(const double n[3], double t1[3], double t2[3]) {
    double a[3] = {0, 0, 0};
    int k = fabs(n[0]) <= fabs(n[1]) ? (fabs(n[0]) <= fabs(n[2]) ? 0 : 2)
                                     : (fabs(n[1]) <= fabs(n[2]) ? 1 : 2);
    a[k] = 1;
    double d = dot3(a, n);
    for (int i = 0; i < 3; i++) t1[i] = a[i] - d * n[i];
    double l = sqrt(dot3(t1, t1));
    for (int i = 0; i < 3; i++) t1[i] /= l;
    t2[0] = n[1] * t1[2] - n[2] * t1[1];
    t2[1] = n[2] * t1[0] - n[0] * t1[2];
    t2[2] = n[0] * t1[1] - n[1] * t1[0];
}

/* gamma between M_p and the metric at the point of S a step of M_p length d from p along
 * the tangent direction u (unit); *g = 1 when the projection finds no surface. */
static anistar_status gamma_at(const as_starset *ss, anistar_context *ctx, const double p[3],
                               const as_metric_frame *mf, const double u[3], double ulen, double d,
                               double *g) {
    double q[3];
    for (int i = 0; i < 3; i++) q[i] = p[i] + (d / ulen) * u[i];
    *g = 1;
    anistar_status s = as_surface_project(ctx, ss->surf, q, q);
    if (s == ANISTAR_ENOSURFACE) return ANISTAR_OK;
    if (s != ANISTAR_OK) return s;
    as_metric_frame mq;
    if ((s = as_starset_metric_in(ss, ctx, q, &mq)) != ANISTAR_OK) return s;
    *g = as_metric_distortion(mf, &mq);
    return ANISTAR_OK;
}

/*
 * The distortion radius at p in M_p units (frame mf, tangent basis t1, t2), capped at
 * cap: the smallest, over four tangent directions, M_p distance d at which the distortion
 * gamma(M_p, M_q) between p and the point q of S that far reaches gamma0 (paper 2.2's
 * dr, seen from p), taken on the ladder b/8, b/4, b/2 (b the best radius so far, cap at
 * first) and then bisected to 5%. The vertices of a facet of circumradius r lie up to
 * about sqrt 3 r apart, so rule 1's distortion bound holds for r up to dr / sqrt 3.
 * gamma is not a power of d (it grows quadratically while the frames turn by small
 * angles, linearly after), so dr is searched, not extrapolated from one step.
 * design: gamma is taken to grow with d on the ladder (the bracket assumes it too), so
 * the top rung is tried first: where it stays below gamma0, which is most of S when r0
 * sizes the mesh, the direction costs one projection and one metric instead of three
 * (on the skull image the estimate was 13% of the run, 12 metric queries per sample
 * point); otherwise the lower rungs are tried upwards as before and the result is the
 * same.
 */
static anistar_status distortion_radius(const as_starset *ss, anistar_context *ctx,
                                        const as_mesher_params *prm,
                                        const double p[3], const as_metric_frame *mf,
                                        const double t1[3], const double t2[3], double cap,
                                        double *out) {
    static const double dirs[4][2] = {{1, 0}, {0, 1}, {0.70710678118654752, 0.70710678118654752},
                                      {0.70710678118654752, -0.70710678118654752}};
    double best = cap;
    for (int j = 0; j < 4; j++) {
        double u[3], y[3];
        for (int i = 0; i < 3; i++) u[i] = dirs[j][0] * t1[i] + dirs[j][1] * t2[i];
        as_metric_apply(mf, u, y);
        double ulen = sqrt(dot3(y, y)), g;
        anistar_status s;
        /* the top rung: below gamma0 there, dr is taken to be at least best */
        const double top = best / 2;
        if ((s = gamma_at(ss, ctx, p, mf, u, ulen, top, &g)) != ANISTAR_OK) return s;
        if (g < prm->gamma0) continue;
        /* a bracket [lo, hi] with gamma(lo) < gamma0 <= gamma(hi): the lowest rung that
         * reaches gamma0 (the top one does) */
        double lo = 0, hi = best / 8;
        while (hi < top) {
            if ((s = gamma_at(ss, ctx, p, mf, u, ulen, hi, &g)) != ANISTAR_OK) return s;
            if (g >= prm->gamma0) break;
            lo = hi;
            hi *= 2;
        }
        while (hi - lo > 0.05 * hi) {
            double mid = 0.5 * (lo + hi);
            /* a field that jumps where p lies (a callback's step at z = 0 seen from a point
             * with z = 0 exactly) has gamma >= gamma0 at every d > 0 and not at 0: hi
             * shrinks to the least subnormal, where 0.05 hi is 0 and mid is lo; stop
             * when no double lies between lo and hi (dr is then 0 to the last bit) */
            if (!(mid > lo && mid < hi)) break;
            if ((s = gamma_at(ss, ctx, p, mf, u, ulen, mid, &g)) != ANISTAR_OK) return s;
            if (g >= prm->gamma0) hi = mid;
            else lo = mid;
        }
        if (hi < best) best = hi;
    }
    *out = best;
    return ANISTAR_OK;
}

/* The estimate's work on one sample point. */
typedef struct as_est {
    const as_starset *ss;
    const as_mesher_params *prm;
    const as_point_sample *smp;
    double *dens;     /* per sample point: vertices per unit area (-1: a singular point) */
    uint8_t *bygamma; /* per sample point: 1 when the distortion radius set its size */
    as_idlist *fids;  /* per thread slot: the feature-size queries' scratch */
} as_est;

/* The vertex density the sizes ask for at sample point i (threads: reads only). */
static anistar_status est_task(void *arg, int32_t i, int t, anistar_context *ctx) {
    const as_est *E = arg;
    const as_starset *ss = E->ss;
    const as_mesher_params *prm = E->prm;
    const double *p = E->smp->points + 3 * (size_t)i;
    const double ideal = 1.5 * sqrt(3.0); /* two ideal triangles per vertex, per h^2 */
    double n[3], t1[3], t2[3];
    int sing = 0;
    E->dens[i] = -1;
    anistar_status s = as_surface_normal_at(ctx, ss->surf, p, n, &sing);
    if (s != ANISTAR_OK || sing) return s;
    tangent_basis(n, t1, t2);
    as_metric_frame mf;
    if ((s = as_starset_metric_in(ss, ctx, p, &mf)) != ANISTAR_OK) return s;
    /* sqrt(det) of the metric restricted to the tangent plane: |F t1 x F t2| */
    double a[3], b[3], c[3];
    as_metric_apply(&mf, t1, a);
    as_metric_apply(&mf, t2, b);
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
    double dens = sqrt(dot3(c, c));
    double h = prm->r0;
    double dr;
    if ((s = distortion_radius(ss, ctx, prm, p, &mf, t1, t2, sqrt(3.0) * h, &dr)) != ANISTAR_OK)
        return s;
    int bygamma = 0;
    if (dr / sqrt(3.0) < h) {
        h = dr / sqrt(3.0);
        bygamma = 1;
    }
    double lfs;
    int exact;
    if ((s = as_feature_lfs(ctx, &ss->feat, &mf, p, h / ss->alpha, &E->fids[t], &lfs, &exact)) !=
        ANISTAR_OK)
        return s;
    if (ss->alpha * lfs < h) {
        h = ss->alpha * lfs;
        bygamma = 0;
    }
    if (prm->approx > 0) {
        /* design: rule 1's approximation bound (--approx delta: the distance from a
         * facet's centroid to S). A triangle equilateral in M with circumradius h, its
         * vertices on S, has its centroid (h^2 / 4) |tr(K M_t^-1)| off S to second order
         * (K = diag k_i in the principal frame, M_t the tangential metric: the vertices'
         * offsets v_i from the centroid have sum v_i v_i^T = (3/2) h^2 M_t^-1 whatever the
         * triangle's orientation, the centroid's distance is |sum v_i^T K v_i| / 6), so
         * the bound holds for h up to sqrt(4 delta / |tr(K M_t^-1)|) (none where the
         * trace vanishes: a saddle whose curvatures cancel in M). Without it the estimate
         * ignored --approx: the sphere with --approx 1e-4 made 40,022 vertices against 822
         * estimated, and --approx 1e-6 was not refused (307,294 vertices after 60 s) */
        as_surface_frame fr;
        if ((s = as_surface_frame_at(ctx, ss->surf, p, &fr)) != ANISTAR_OK) return s;
        if (!fr.singular) {
            double fa[3], fb[3];
            as_metric_apply(&mf, fr.d, fa);
            as_metric_apply(&mf, fr.d + 3, fb);
            double aa = dot3(fa, fa), bb = dot3(fb, fb), ab = dot3(fa, fb);
            double det = aa * bb - ab * ab;
            double tr = det > 0 ? fabs(fr.k[0] * bb + fr.k[1] * aa) / det : 0;
            if (tr > 0 && isfinite(tr)) {
                double ha = sqrt(4 * prm->approx / tr);
                if (ha < h) {
                    h = ha;
                    bygamma = 0;
                }
            }
        }
    }
    double d = dens / (ideal * h * h);
    /* the Euclidean bounds: edges of at least hmin and at most hmax (an equilateral
     * triangle of side L has circumradius L / sqrt 3) */
    if (ss->hmin > 0 && d > 3 / (ideal * ss->hmin * ss->hmin))
        d = 3 / (ideal * ss->hmin * ss->hmin);
    if (ss->hmax > 0 && d < 3 / (ideal * ss->hmax * ss->hmax))
        d = 3 / (ideal * ss->hmax * ss->hmax);
    E->dens[i] = d;
    E->bygamma[i] = (uint8_t)bygamma;
    return ANISTAR_OK;
}

anistar_status as_mesher_estimate(as_starset *ss, const as_mesher_params *prm, double *vertices,
                                  double *bytes, double *bygamma) {
    anistar_context *ctx = ss->ctx;
    const size_t bytes0 = ctx->bytes; /* before the estimate's own arrays */
    *vertices = 0;
    *bytes = 0;
    as_point_sample smp;
    anistar_status s = (ss->sampler ? as_sampler_sample(ctx, ss->sampler, AS_ESTIMATE_SAMPLE, &smp)
                                    : as_surface_sample(ctx, ss->surf, AS_ESTIMATE_SAMPLE, &smp));
    if (s != ANISTAR_OK) return s;
    const int T = ss->pool ? as_pool_threads(ss->pool) : 1;
    double *aw = as_alloc_array(ctx, smp.n ? smp.n : 1, sizeof *aw);
    double *dens = as_alloc_array(ctx, smp.n ? smp.n : 1, sizeof *dens);
    as_idlist *fids = as_alloc_array(ctx, (size_t)T, sizeof *fids);
    uint8_t *bg = as_alloc_array(ctx, smp.n ? smp.n : 1, sizeof *bg);
    if (!aw || !dens || !fids || !bg) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (estimate)");
        goto done;
    }
    memset(fids, 0, (size_t)T * sizeof *fids);
    if ((s = as_surface_sample_weights(ctx, &smp, aw)) != ANISTAR_OK) goto done;
    /* design: the sample points' densities on the threads (each reads only the surface,
     * the field and the feature points), then their sum in the points' order: the same
     * bits for any thread count */
    as_est E = {ss, prm, &smp, dens, bg, fids};
    if (ss->pool) {
        s = as_pool_run(ss->pool, (int32_t)smp.n, est_task, &E);
    } else {
        for (size_t i = 0; i < smp.n && s == ANISTAR_OK; i++) s = est_task(&E, (int32_t)i, 0, ctx);
    }
    double sum = 0, sumg = 0;
    for (size_t i = 0; i < smp.n && s == ANISTAR_OK; i++) {
        if (dens[i] < 0) continue;
        sum += aw[i] * dens[i];
        if (bg[i]) sumg += aw[i] * dens[i];
    }
    if (s == ANISTAR_OK) {
        *vertices = AS_ESTIMATE_FILL * sum;
        *bygamma = sum > 0 ? sumg / sum : 0;
        *bytes = (double)bytes0 + AS_ESTIMATE_BYTES_PER_VERTEX * *vertices;
    }
done:
    if (fids)
        for (int t = 0; t < T; t++) as_idlist_free(ctx, &fids[t]);
    as_free(ctx, fids, (size_t)T * sizeof *fids);
    as_free(ctx, dens, (smp.n ? smp.n : 1) * sizeof *dens);
    as_free(ctx, bg, (smp.n ? smp.n : 1) * sizeof *bg);
    as_free(ctx, aw, (smp.n ? smp.n : 1) * sizeof *aw);
    as_surface_sample_free(ctx, &smp);
    return s;
}
