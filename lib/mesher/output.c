/*
 * output.c — the output mesh: stitching of the surface stars, orientation, statistics
 * (DESIGN.md 4.8, paper 4.1 "stitched together", 6.2 Figures 8 and 10). See mesher.h.
 */
#include "geom/bvh.h"
#include "mesher/mesher.h"
#include "mesher/refine.h"

#include <math.h>
#include <string.h>

void as_mesh_free(anistar_mesh *m) {
    if (!m) return;
    anistar_context *ctx = m->ctx;
    as_free(ctx, m->gid, m->ngid * sizeof *m->gid);
    as_free(ctx, m->rho, m->nrho * sizeof *m->rho);
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
/* What the output needs of one facet, computed on the threads (ofacet_task). */
typedef struct as_ofacet {
    const as_rfacet *f; /* in the star of its lowest vertex */
    int flip;           /* its vertex order turned to face along S's normal */
    double rho[3];      /* radius-edge ratio in each vertex metric */
    double r[3];        /* its surface radius in each vertex's star (-inf: not there) */
    double area, esum, emax; /* approximation samples: area, sum and largest distance */
    int ns;             /* samples projected */
    double g;           /* the largest distortion between its vertices' metrics */
} as_ofacet;

typedef struct as_ofacets {
    const as_starset *ss;
    as_ofacet *of;
    size_t n;
    int errors; /* the approximation samples too */
} as_ofacets;

/* The approximation samples of the facet (a, b, c) (its vertices in the order of their
 * ids): 4 fixed barycentric samples projected on S, each distance into o->esum (summed
 * in the samples' order) and o->emax; o->ns samples projected; o->area its area. */
static anistar_status facet_errors(const as_starset *ss, anistar_context *ctx, const double *a,
                                   const double *b, const double *c, as_ofacet *o) {
    static const double bw[4][3] = {{1.0 / 3, 1.0 / 3, 1.0 / 3},
                                    {2.0 / 3, 1.0 / 6, 1.0 / 6},
                                    {1.0 / 6, 2.0 / 3, 1.0 / 6},
                                    {1.0 / 6, 1.0 / 6, 2.0 / 3}};
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                   u[0] * w[1] - u[1] * w[0]};
    o->area = 0.5 * sqrt((x[0] * x[0] + x[1] * x[1]) + x[2] * x[2]);
    o->esum = 0;
    o->emax = 0;
    o->ns = 0;
    for (int q = 0; q < 4; q++) {
        double p[3], pr[3];
        for (int k = 0; k < 3; k++) p[k] = (bw[q][0] * a[k] + bw[q][1] * b[k]) + bw[q][2] * c[k];
        anistar_status s = as_surface_project(ctx, ss->surf, p, pr);
        if (s == ANISTAR_ENOSURFACE) continue; /* no projection found: skipped */
        if (s != ANISTAR_OK) return s;
        double d[3] = {pr[0] - p[0], pr[1] - p[1], pr[2] - p[2]};
        double e = sqrt((d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]);
        if (e > o->emax) o->emax = e;
        o->esum += e;
        o->ns++;
    }
    return ANISTAR_OK;
}

/* Facets per task of ofacet_task. */
#define AS_OUTPUT_CHUNK 64
/* the facets whose records are held at once (a multiple of AS_OUTPUT_CHUNK) */
#define AS_OUTPUT_WINDOW 4096

/* Whether facet f of v's star is output from there: v is its lowest vertex and its table
 * entry is consistent. */
static int output_facet(const as_starset *ss, int32_t v, const as_rfacet *f) {
    if (f->g[0] != v) return 0;
    const as_ftab_entry *e = as_starset_lookup(ss, as_facet_key(f->g));
    return e && as_starset_consistent(ss, e->key, e->mask);
}

/* Run nchunks tasks of fn on ss's pool, or in order on ctx without one. */
static anistar_status run_chunks(const as_starset *ss, anistar_context *ctx, int32_t nchunks,
                                 as_pool_fn fn, void *arg) {
    if (ss->pool) return as_pool_run(ss->pool, nchunks, fn, arg);
    anistar_status s = ANISTAR_OK;
    for (int32_t c = 0; c < nchunks && s == ANISTAR_OK; c++) s = fn(arg, c, 0, ctx);
    return s;
}

/* Add facet o's approximation samples to the statistics (largest distance, and the
 * area-weighted sums of the mean), in the caller's facet order. */
static void add_errors(const as_ofacet *o, anistar_mesh_stats *S, double *err_sum,
                       double *area_sum) {
    if (o->emax > S->approx_error_max) S->approx_error_max = o->emax;
    if (o->ns) {
        *err_sum += o->area * o->esum / o->ns;
        *area_sum += o->area;
    }
}

static anistar_status ofacet_one(const as_starset *ss, anistar_context *ctx, int errors,
                                 as_ofacet *o) {
    const as_rfacet *f = o->f;
    const double *a = ss->xyz + 3 * (size_t)f->g[0], *b = ss->xyz + 3 * (size_t)f->g[1],
                 *c = ss->xyz + 3 * (size_t)f->g[2];
    double nrm[3];
    int sing = 0;
    anistar_status s = as_surface_normal_at(ctx, ss->surf, f->c, nrm, &sing);
    if (s != ANISTAR_OK) return s;
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                   u[0] * w[1] - u[1] * w[0]};
    o->flip = (x[0] * nrm[0] + x[1] * nrm[1]) + x[2] * nrm[2] < 0;
    for (int j = 0; j < 3; j++) {
        int32_t w3 = f->g[j];
        o->rho[j] = as_radius_edge(&ss->mf[w3], a, b, c, NULL);
        const as_star *sw = ss->stars[w3];
        int32_t idx = as_star_find(sw, f->g);
        o->r[j] = idx >= 0 ? sw->rf[idx].r : -INFINITY;
    }
    /* approximation error: weighted by the triangle's area (the mean over area-uniform
     * samples) */
    o->area = o->esum = o->emax = 0;
    o->ns = 0;
    if (errors && (s = facet_errors(ss, ctx, a, b, c, o)) != ANISTAR_OK) return s;
    double g01 = as_metric_distortion(&ss->mf[f->g[0]], &ss->mf[f->g[1]]);
    double g02 = as_metric_distortion(&ss->mf[f->g[0]], &ss->mf[f->g[2]]);
    double g12 = as_metric_distortion(&ss->mf[f->g[1]], &ss->mf[f->g[2]]);
    o->g = g01 > g02 ? g01 : g02;
    if (g12 > o->g) o->g = g12;
    return ANISTAR_OK;
}

/* The facets of chunk k (AS_OUTPUT_CHUNK each), in order: the first error stops it. */
static anistar_status ofacet_task(void *arg, int32_t k, int t, anistar_context *ctx) {
    (void)t;
    const as_ofacets *O = arg;
    size_t lo = (size_t)k * AS_OUTPUT_CHUNK, hi = lo + AS_OUTPUT_CHUNK;
    if (hi > O->n) hi = O->n;
    for (size_t i = lo; i < hi; i++) {
        anistar_status s = ofacet_one(O->ss, ctx, O->errors, &O->of[i]);
        if (s != ANISTAR_OK) return s;
    }
    return ANISTAR_OK;
}

anistar_status as_mesher_output(as_starset *ss, const as_mesher_params *prm,
                                const as_mesher_counters *cnt, int complete, int errors,
                                anistar_mesh **out) {
    anistar_context *ctx = ss->ctx;
    anistar_status s;
    *out = NULL;
    anistar_mesh *m = as_alloc(ctx, sizeof *m);
    if (!m) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
    memset(m, 0, sizeof *m);
    m->ctx = ctx;
    as_trimesh_init(&m->tm);
    anistar_mesh_stats *S = &m->stats;
    as_ofacet *of = NULL;
    int32_t *map = as_alloc_array(ctx, (size_t)ss->n, sizeof *map);
    if (!map) {
        as_mesh_free(m);
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
    }
    for (int32_t i = 0; i < ss->n; i++) map[i] = -1;
    /* pass 1: the used vertices (every vertex of an output facet) */
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        for (int32_t k = 0; k < st->nrf; k++)
            if (output_facet(ss, v, &st->rf[k]))
                for (int j = 0; j < 3; j++) map[st->rf[k].g[j]] = 0;
    }
    size_t nv = 0;
    for (int32_t i = 0; i < ss->n; i++)
        if (map[i] == 0) map[i] = (int32_t)nv++;
    if ((s = as_trimesh_reserve(ctx, &m->tm, nv, 2 * nv + 8)) != ANISTAR_OK) goto fail;
    if (nv && !(m->gid = as_alloc_array(ctx, nv, sizeof *m->gid))) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
        goto fail;
    }
    m->ngid = nv;
    for (int32_t i = 0; i < ss->n; i++)
        if (map[i] >= 0) m->gid[map[i]] = i;
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
    /* pass 2, a window of facets at a time (in the order of their lowest vertex's star).
     * design: each facet's normal, shape and approximation samples on the threads (they
     * read the stars, the points and the surface), then the triangles and the sums in
     * the facets' order: the same mesh and the same statistics, bit for bit, for any
     * thread count. The window bounds the scratch (AS_OUTPUT_WINDOW records, 0.4 MB):
     * a record for every facet at once raised the paper torus's peak from 2.8 to
     * 3.1 KB per vertex, the output being built while the stars are all alive. */
    of = as_alloc_array(ctx, AS_OUTPUT_WINDOW, sizeof *of);
    if (!of) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
        goto fail;
    }
    for (int32_t v = ss->first_site, k = 0; v < ss->n;) {
        size_t nof = 0;
        for (; v < ss->n && nof < AS_OUTPUT_WINDOW; v++, k = 0) {
            const as_star *st = ss->stars[v];
            for (; k < st->nrf && nof < AS_OUTPUT_WINDOW; k++)
                if (output_facet(ss, v, &st->rf[k])) of[nof++].f = &st->rf[k];
            if (k < st->nrf) break; /* the window is full: v's star goes on next time */
        }
        as_ofacets O = {ss, of, nof, errors};
        int32_t nchunks = (int32_t)((nof + AS_OUTPUT_CHUNK - 1) / AS_OUTPUT_CHUNK);
        if ((s = run_chunks(ss, ctx, nchunks, ofacet_task, &O)) != ANISTAR_OK) goto fail;
        for (size_t i = 0; i < nof; i++) {
            const as_ofacet *o = &of[i];
            const as_rfacet *f = o->f;
            int32_t i0 = map[f->g[0]], i1 = map[f->g[1]], i2 = map[f->g[2]];
            if ((s = as_trimesh_add_triangle(ctx, &m->tm, i0, o->flip ? i2 : i1,
                                             o->flip ? i1 : i2)) != ANISTAR_OK)
                goto fail;
            /* statistics in the three vertex metrics; a facet below hmin that exceeds r0,
             * rho0 or gamma0 is counted (the bound that held it) */
            int beyond = 0;
            for (int j = 0; j < 3; j++) {
                double rho = o->rho[j];
                if (rho > S->rho_max) S->rho_max = rho;
                double r2 = rho * rho / S->histogram_width;
                size_t bin =
                    r2 < ANISTAR_HISTOGRAM_BINS - 1 ? (size_t)r2 : ANISTAR_HISTOGRAM_BINS - 1;
                S->histogram[bin]++;
                rho2_sum += rho * rho;
                if (o->r[j] > S->r_max) S->r_max = o->r[j];
                if (rho > prm->rho0 || o->r[j] >= prm->r0) beyond = 1;
            }
            add_errors(o, S, &err_sum, &area_sum);
            if (o->g > S->gamma_max) S->gamma_max = o->g;
            if (o->g >= prm->gamma0) beyond = 1;
            if (beyond && as_facet_below_hmin(ss, f)) S->facets_below_hmin++;
        }
    }
    /* per triangle: the largest radius-edge ratio over its three vertex metrics (the cell
     * field "radius_edge" of the writers) */
    if (m->tm.nt) {
        if (!(m->rho = as_alloc_array(ctx, m->tm.nt, sizeof *m->rho))) {
            s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
            goto fail;
        }
        m->nrho = m->tm.nt;
        for (size_t t = 0; t < m->tm.nt; t++) {
            const int32_t *v = m->tm.tri + 3 * t;
            const double *a = m->tm.xyz + 3 * (size_t)v[0], *b = m->tm.xyz + 3 * (size_t)v[1],
                         *c = m->tm.xyz + 3 * (size_t)v[2];
            double r = 0;
            for (int j = 0; j < 3; j++) {
                double q = as_radius_edge(&ss->mf[m->gid[v[j]]], a, b, c, NULL);
                if (!(q <= r)) r = q;
            }
            m->rho[t] = r;
        }
    }
    S->hmin = ss->hmin;
    S->hmax = ss->hmax;
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
    S->insertions_hmax = cnt->cause[AS_CAUSE_HMAX];
    S->topology_below_hmin = cnt->topo_below_hmin;
    S->stars_delaunay_zone = (size_t)cnt->zones_opened;
    S->facets_swept = cnt->swept;
    S->batches = cnt->batches;
    S->batch_jobs = cnt->batch_jobs;
    S->batch_jobs_lost = cnt->batch_lost;
    S->batch_jobs_set_aside = cnt->batch_set_aside;
    S->sites_unused = 0;
    for (int32_t v = ss->first_site; v < ss->n; v++) S->sites_unused += ss->stars[v]->nrf == 0;
    S->stall_max = cnt->stall_max;
    S->components_below_resolution = cnt->specks;
    S->estimate_vertices = cnt->estimate_vertices;
    S->estimate_bytes = cnt->estimate_bytes;
    S->stop_reason = cnt->stop_reason;
    S->pick_valid_tries = cnt->pick_tries;
    S->pick_valid_failures = cnt->pick_failures;
    S->seconds_init = cnt->t_init;
    S->seconds_refine = cnt->t_refine;
    S->seconds_total = cnt->t_total;
    (void)prm;
    as_free(ctx, of, AS_OUTPUT_WINDOW * sizeof *of);
    as_free(ctx, map, (size_t)ss->n * sizeof *map);
    *out = m;
    return ANISTAR_OK;
fail:
    as_free(ctx, of, AS_OUTPUT_WINDOW * sizeof *of);
    as_free(ctx, map, (size_t)ss->n * sizeof *map);
    as_mesh_free(m);
    return s;
}

/* The approximation samples of triangles lo + [k * AS_OUTPUT_CHUNK, ...) of E->m, below
 * lo + n, into E->of from 0 (oerr_task). */
typedef struct as_oerrs {
    const as_starset *ss;
    const anistar_mesh *m;
    as_ofacet *of;
    size_t lo, n;
} as_oerrs;

static anistar_status oerr_task(void *arg, int32_t k, int t, anistar_context *ctx) {
    (void)t;
    const as_oerrs *E = arg;
    const anistar_mesh *m = E->m;
    size_t lo = (size_t)k * AS_OUTPUT_CHUNK, hi = lo + AS_OUTPUT_CHUNK;
    if (hi > E->n) hi = E->n;
    for (size_t i = lo; i < hi; i++) {
        const int32_t *tri = m->tm.tri + 3 * (E->lo + i);
        as_gid g[3];
        for (int j = 0; j < 3; j++) g[j] = (as_gid)m->gid[tri[j]];
        as_sort_gid3(g); /* the facet's own order (the triangle may have been turned) */
        const double *x = E->ss->xyz;
        anistar_status s = facet_errors(E->ss, ctx, x + 3 * (size_t)g[0], x + 3 * (size_t)g[1],
                                        x + 3 * (size_t)g[2], &E->of[i]);
        if (s != ANISTAR_OK) return s;
    }
    return ANISTAR_OK;
}

anistar_status as_mesher_output_errors(as_starset *ss, anistar_mesh *m) {
    anistar_context *ctx = ss->ctx;
    anistar_mesh_stats *S = &m->stats;
    S->approx_error_max = S->approx_error_mean = 0;
    if (m->tm.nt == 0) return ANISTAR_OK;
    as_ofacet *of = as_alloc_array(ctx, AS_OUTPUT_WINDOW, sizeof *of);
    if (!of) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (output)");
    /* the sums of as_mesher_output, in its order (the triangles are its facets), a window
     * of triangles at a time */
    double err_sum = 0, area_sum = 0;
    anistar_status s = ANISTAR_OK;
    for (size_t lo = 0; lo < m->tm.nt && s == ANISTAR_OK; lo += AS_OUTPUT_WINDOW) {
        size_t n = m->tm.nt - lo < AS_OUTPUT_WINDOW ? m->tm.nt - lo : AS_OUTPUT_WINDOW;
        as_oerrs E = {ss, m, of, lo, n};
        s = run_chunks(ss, ctx, (int32_t)((n + AS_OUTPUT_CHUNK - 1) / AS_OUTPUT_CHUNK),
                       oerr_task, &E);
        for (size_t i = 0; i < n && s == ANISTAR_OK; i++)
            add_errors(&of[i], S, &err_sum, &area_sum);
    }
    if (s == ANISTAR_OK) S->approx_error_mean = area_sum > 0 ? err_sum / area_sum : 0;
    as_free(ctx, of, AS_OUTPUT_WINDOW * sizeof *of);
    return s;
}

/* ---- the final checks (anistar_mesher_run's contract) --------------------------------- */

static int32_t uf_find(int32_t *uf, int32_t x) {
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}

/* Position of vertex a in triangle t (0..2), or -1. */
static int tri_pos(const int32_t *tri, int32_t t, int32_t a) {
    for (int k = 0; k < 3; k++)
        if (tri[3 * (size_t)t + k] == a) return k;
    return -1;
}

/* Append a refinement point x (with the Euclidean size r of what it refines) to ss->fix. */
static anistar_status add_fix(anistar_context *ctx, as_starset *ss, const double x[3], double r) {
    if (ss->nfix == ss->cap_fix &&
        as_grow(ctx, (void **)&ss->fix, &ss->cap_fix, ss->nfix + 1, 4 * sizeof *ss->fix))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (final checks)");
    double *F = ss->fix + 4 * ss->nfix++;
    memcpy(F, x, 3 * sizeof *x);
    F[3] = r;
    return ANISTAR_OK;
}

/* Append the ball (x, r) to ss->trouble: where the final checks failed (the refiner
 * halves alpha for the sites inside). */
static anistar_status add_trouble(anistar_context *ctx, as_starset *ss, const double x[3], double r) {
    if (ss->ntrouble == ss->cap_trouble &&
        as_grow(ctx, (void **)&ss->trouble, &ss->cap_trouble, ss->ntrouble + 1,
                4 * sizeof *ss->trouble))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (final checks)");
    double *T = ss->trouble + 4 * ss->ntrouble++;
    memcpy(T, x, 3 * sizeof *x);
    T[3] = r;
    return ANISTAR_OK;
}

/* The diagonal of a piece's box (lo[3] hi[3]). */
static double box_diagonal(const double box[6]) {
    double d2 = 0;
    for (int k = 0; k < 3; k++) d2 += (box[3 + k] - box[k]) * (box[3 + k] - box[k]);
    return sqrt(d2);
}

/*
 * Per piece of the mesh (tcomp: each triangle's piece, ncomp pieces): the reach of its
 * facets, the largest distance from a facet's surface center to one of its vertices.
 * Allocated in *reach on the first call (the caller frees ncomp entries).
 */
static anistar_status piece_reach(anistar_context *ctx, const as_starset *ss,
                                  const anistar_mesh *m, const int32_t *tcomp, size_t ncomp,
                                  double **reach) {
    if (*reach) return ANISTAR_OK;
    double *R = as_alloc_array(ctx, ncomp ? ncomp : 1, sizeof *R);
    if (!R) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (final checks)");
    for (size_t c = 0; c < ncomp; c++) R[c] = 0;
    const as_trimesh *tm = &m->tm;
    for (size_t t = 0; t < tm->nt; t++) {
        as_gid g[3];
        for (int i = 0; i < 3; i++) g[i] = m->gid[tm->tri[3 * t + i]];
        as_sort_gid3(g);
        const as_star *sv = ss->stars[g[0]];
        int32_t fi = as_star_find(sv, g);
        if (fi < 0) continue;
        const double *c = sv->rf[fi].c;
        for (int i = 0; i < 3; i++) {
            const double *x = ss->xyz + 3 * (size_t)g[i];
            double d = sqrt((c[0] - x[0]) * (c[0] - x[0]) + (c[1] - x[1]) * (c[1] - x[1]) +
                            (c[2] - x[2]) * (c[2] - x[2]));
            if (d > R[tcomp[t]]) R[tcomp[t]] = d;
        }
    }
    *reach = R;
    return ANISTAR_OK;
}

/* The ball around a piece of the mesh with box box (lo[3] hi[3]) and facet reach reach
 * (piece_reach): the box's center, half its diagonal plus the reach.
 * design: the piece is cut off from the part of S it belongs to where its facets, or the
 * facets across from it, span a part thinner than they resolve; the sites whose facets
 * can span it are the piece's own and those within one facet's reach of it. A larger ball
 * halves alpha over S's unrelated features around it (on a noisy scan, the noise's medial
 * axis: 14,500 feature insertions on the brain MRI with three times the diagonal). */
static anistar_status trouble_piece(anistar_context *ctx, as_starset *ss, const double box[6],
                                    double reach) {
    double c[3];
    for (int k = 0; k < 3; k++) c[k] = 0.5 * (box[k] + box[3 + k]);
    return add_trouble(ctx, ss, c, 0.5 * box_diagonal(box) + reach);
}

/*
 * 1 in *yes when a piece of the mesh (its box lo[3] hi[3], one of its vertices v0)
 * bounds a region of its own: from a point just off S at v0, on one side or the other,
 * each of the six axis rays meets S within one and a half times the diagonal of the
 * piece's box. From inside a separate blob (or inside a cavity) every ray leaves through
 * the piece; from inside a fragment of a plate, a tube or a larger part, a ray along the
 * part stays inside S past the fragment, and from the other side rays go away from S.
 */
static anistar_status piece_encloses(anistar_context *ctx, const as_surface *surf,
                                     const as_trimesh *tm, const double box[6], int32_t v0,
                                     int *yes) {
    *yes = 0;
    double diag = box_diagonal(box), len = 1.5 * diag;
    const double *x0 = tm->xyz + 3 * (size_t)v0;
    double n[3];
    int sing = 0;
    anistar_status s = as_surface_normal_at(ctx, surf, x0, n, &sing);
    if (s != ANISTAR_OK || sing) return s;
    for (int side = -1; side <= 1 && !*yes; side += 2) {
        double m[3];
        for (int k = 0; k < 3; k++) m[k] = x0[k] + side * 1e-3 * diag * n[k];
        int all = 1;
        for (int d = 0; d < 6 && all; d++) {
            double e[3] = {m[0], m[1], m[2]}, x[3];
            e[d >> 1] += (d & 1) ? -len : len;
            int hit = 0;
            if ((s = as_surface_crossing(ctx, surf, m, e, m, &hit, x)) != ANISTAR_OK) return s;
            all = hit;
        }
        *yes = all;
    }
    return ANISTAR_OK;
}

/*
 * 1 in *yes when a piece of the mesh that bounds no region of its own (piece_encloses)
 * is cut off from the rest of S only where S is thinner than its resolution: from a
 * point just inside the piece's own volume, each axis ray that does not meet S within one
 * and a half diagonals leaves the piece through a triangle that lies within floor of S.
 * design: a piece closes its volume where S goes on (a neck, the rim of a plate, the
 * cross-section of a tube). Where S's part is thicker than twice the floor the closing
 * triangles span it and lie far from S (a fragment the refinement must join to the
 * rest: the feature size resolves it); where it is thinner, the closing triangles lie
 * within floor of S and the feature rule, floored there, cannot resolve the part: the
 * piece is below the resolution, as an edge across such a gap or plate is in check 4.
 * The piece's volume is its oriented side: the side opposite its triangles' normals
 * when its signed volume is positive. ptri lists the piece's np triangles.
 */
static anistar_status piece_cut_below_floor(anistar_context *ctx, const as_surface *surf,
                                            const as_trimesh *tm, const int32_t *ptri,
                                            size_t np, const int32_t *start, const int32_t *inc,
                                            const double box[6], int32_t v0, double floor_e,
                                            int *yes) {
    *yes = 0;
    const double *o = tm->xyz + 3 * (size_t)v0;
    double vol = 0, nm[3] = {0, 0, 0};
    for (size_t i = 0; i < np; i++) {
        const int32_t *T = tm->tri + 3 * (size_t)ptri[i];
        double a[3], b[3], c[3];
        for (int k = 0; k < 3; k++) {
            a[k] = tm->xyz[3 * (size_t)T[0] + k] - o[k];
            b[k] = tm->xyz[3 * (size_t)T[1] + k] - o[k];
            c[k] = tm->xyz[3 * (size_t)T[2] + k] - o[k];
        }
        vol += a[0] * (b[1] * c[2] - b[2] * c[1]) + a[1] * (b[2] * c[0] - b[0] * c[2]) +
               a[2] * (b[0] * c[1] - b[1] * c[0]);
    }
    for (int32_t j = start[v0]; j < start[v0 + 1]; j++) {
        const int32_t *T = tm->tri + 3 * (size_t)inc[j];
        const double *a = tm->xyz + 3 * (size_t)T[0], *b = tm->xyz + 3 * (size_t)T[1],
                     *c = tm->xyz + 3 * (size_t)T[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        nm[0] += u[1] * w[2] - u[2] * w[1];
        nm[1] += u[2] * w[0] - u[0] * w[2];
        nm[2] += u[0] * w[1] - u[1] * w[0];
    }
    double l = sqrt(nm[0] * nm[0] + nm[1] * nm[1] + nm[2] * nm[2]);
    if (!(l > 0) || vol == 0) return ANISTAR_OK;
    const double diag = box_diagonal(box), len = 1.5 * diag, sg = vol > 0 ? -1 : 1;
    double m[3];
    for (int k = 0; k < 3; k++) m[k] = o[k] + sg * 1e-3 * diag * nm[k] / l;
    for (int d = 0; d < 6; d++) {
        double e[3] = {m[0], m[1], m[2]}, x[3], dir[3] = {0, 0, 0};
        dir[d >> 1] = (d & 1) ? -len : len;
        e[d >> 1] += dir[d >> 1];
        int hit = 0;
        anistar_status s = as_surface_crossing(ctx, surf, m, e, m, &hit, x);
        if (s != ANISTAR_OK) return s;
        if (hit) continue;
        /* the first triangle of the piece on the ray (the exact contact test of the
         * segment queries, as_segment_triangle) */
        double tbest = INFINITY;
        for (size_t i = 0; i < np; i++) {
            const int32_t *T = tm->tri + 3 * (size_t)ptri[i];
            double t;
            if (as_segment_triangle(m, e, tm->xyz + 3 * (size_t)T[0], tm->xyz + 3 * (size_t)T[1],
                                    tm->xyz + 3 * (size_t)T[2], &t) != AS_HIT_NONE &&
                t > 0 && t < tbest)
                tbest = t;
        }
        if (!(tbest <= 1)) return ANISTAR_OK;
        double p[3], q[3], d2 = 0;
        for (int k = 0; k < 3; k++) p[k] = m[k] + tbest * dir[k];
        s = as_surface_project(ctx, surf, p, q);
        if (s == ANISTAR_ENOSURFACE) return ANISTAR_OK;
        if (s != ANISTAR_OK) return s;
        for (int k = 0; k < 3; k++) d2 += (p[k] - q[k]) * (p[k] - q[k]);
        if (!(d2 <= floor_e * floor_e)) return ANISTAR_OK;
    }
    *yes = 1;
    return ANISTAR_OK;
}

/*
 * design:
 *  1. every site's star is one closed fan (the topology rule's invariant at the end);
 *  2. the mesh is non-empty and, by as_topology_check, a closed 2-manifold;
 *  3. orientation: the output orients each facet by the normal of S at its surface
 *     center; breadth-first search across edges makes each component consistent,
 *     keeping the orientation of the larger area (area-weighted vote); a component
 *     that admits none fails;
 *  4. no edge bridges a gap or cuts through a thin part: an edge does when its midpoint
 *     lies farther than AS_CERT_SAGITTA of its half length from S and the normals of S at
 *     its ends are nearly opposite (below AS_CERT_OPPOSITE): it joins two sides of S that
 *     face each other across a gap (outside S: two components joined, a handle closed) or
 *     face away from each other across a plate or a tube thinner than the facets (inside
 *     S: a plate cut through, a tube collapsed). A chord of a surface whose normal turns by
 *     at most 90 degrees along it has a sagitta of at most tan(22.5 deg) = 0.41 of its
 *     half length, and a chord across a crease joins faces at an angle: neither is
 *     flagged. An edge over the rim of a plate can be flagged too: the refiner then
 *     inserts the point of S it misses and the centers of its facets, which resolves the
 *     rim. This check needs no reference: it is how the mesh proves its topology against
 *     S itself (measured: a plate 0.02 thick meshed at r0 1 came out with genus 6 and
 *     passed every other check);
 *  5. components (union-find of the triangles' vertices) against the sample components
 *     of the initial sites: each sample component meshed. For a triangle-mesh surface the
 *     components are exact: each in exactly one piece, no piece holding two or none, and
 *     chi = V - F/2 of each equal to the input component's. For function kinds (implicit,
 *     image) the sampler's grid may merge components closer than a cell, split one at a
 *     neck thinner than a cell or miss one smaller than a cell: a join is accepted (step 4
 *     found no bridge), and a piece found by refinement or split off a sample component
 *     is accepted when it bounds a region of its own (piece_encloses: a separate blob or
 *     cavity does, a fragment of a plate or a tube does not). The counts are in the
 *     statistics.
 */
anistar_status as_mesher_certify(as_starset *ss, anistar_mesh *m, int *ok, int *refinable,
                                 uint64_t *sig) {
    anistar_context *ctx = ss->ctx;
    as_trimesh *tm = &m->tm;
    *ok = 0;
    *refinable = 0;
    *sig = 0;
    ss->nfix = 0;
    ss->ntrouble = 0;
    /* design: a star with no restricted facet at all is no vertex of the output (every
     * facet that uses a site is in its star): its site is a point whose cell met S only
     * where the topology rule could not refine above hmin (a corner of a CAD mesh). The
     * mesh without it is judged by the checks below (closed manifold, components and
     * their Euler characteristics, orientation, fidelity), which is what a missing piece
     * of S would fail; it is counted in stats.sites_unused. A star with facets that are
     * not one closed fan is a defect of the output itself. */
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        const as_star *st = ss->stars[v];
        if (!st->closed && st->nrf > 0) {
            const double *x = ss->xyz + 3 * (size_t)v;
            as_fail(ctx, ANISTAR_INCOMPLETE,
                    "mesher: uncertified: the star of site %d at (%.17g, %.17g, %.17g) is not "
                    "one closed fan (%d facets) and the topology rule found no point to insert "
                    "farther than hmin %g from the other sites (S is not smooth there, e.g. a "
                    "sharp crease or corner, or two parts of S come closer than about hmin, "
                    "or the metric is too distorted at that scale: lower hmin, grade the "
                    "metric with grad=, or lower r0)",
                    (int)v, x[0], x[1], x[2], (int)st->nrf, ss->hmin);
            return ANISTAR_OK;
        }
    }
    if (tm->nt == 0) {
        as_fail(ctx, ANISTAR_INCOMPLETE, "mesher: uncertified: the mesh is empty");
        return ANISTAR_OK;
    }
    as_topology top;
    anistar_status s = as_topology_check(ctx, tm->nv, tm->xyz, tm->nt, tm->tri, &top);
    if (s != ANISTAR_OK) return s;
    if (!top.closed_manifold) {
        as_fail(ctx, ANISTAR_INCOMPLETE,
                "mesher: uncertified: the stitched stars are not a closed 2-manifold (%zu border "
                "edges, %zu non-manifold edges, %zu non-manifold vertices)",
                top.border_edges, top.nonmanifold_edges, top.nonmanifold_vertices);
        return ANISTAR_OK;
    }
    size_t nv = tm->nv, nt = tm->nt;
    int32_t *start = as_alloc_array(ctx, nv + 1, sizeof *start);
    int32_t *inc = as_alloc_array(ctx, 3 * nt, sizeof *inc);
    int32_t *uf = as_alloc_array(ctx, nv, sizeof *uf);
    int32_t *queue = as_alloc_array(ctx, nt, sizeof *queue);
    int8_t *flip = as_alloc_array(ctx, nt, sizeof *flip);
    int32_t *tcomp = as_alloc_array(ctx, nt, sizeof *tcomp);
    int32_t *vmap = as_alloc_array(ctx, (size_t)ss->n, sizeof *vmap);
    size_t ncomp = 0, cap_c = 0;
    double *vote = NULL;     /* per component: area agreeing minus disagreeing */
    int32_t *cs = NULL;      /* per component: its sample component, -1 none, -2 several */
    int32_t *cvert = NULL;   /* per component: a vertex, for messages */
    long long *cchi = NULL;  /* per component: V - F/2 (times 2 during counting) */
    double *cbox = NULL;     /* per component: its box, lo[3] hi[3] */
    int32_t *sc_out = NULL;  /* per sample component: its output component, -1 none */
    uint8_t *split = NULL;   /* per sample component: its sites are in two pieces or more */
    int32_t *pstart = NULL;  /* per component: its first triangle in ptri (built on demand) */
    int32_t *ptri = NULL;    /* triangles sorted by component */
    double *creach = NULL;   /* per component: its facets' reach (built on demand) */
    s = ANISTAR_OK;
    if (!start || !inc || !uf || !queue || !flip || !tcomp || !vmap) goto nomem;
    /* vertex -> triangles (CSR) and components */
    memset(start, 0, (nv + 1) * sizeof *start);
    for (size_t i = 0; i < 3 * nt; i++) start[tm->tri[i] + 1]++;
    for (size_t v = 0; v < nv; v++) start[v + 1] += start[v];
    for (size_t t = 0; t < nt; t++)
        for (int k = 0; k < 3; k++) inc[start[tm->tri[3 * t + k]]++] = (int32_t)t;
    for (size_t v = nv; v > 0; v--) start[v] = start[v - 1];
    start[0] = 0;
    for (size_t v = 0; v < nv; v++) uf[v] = (int32_t)v;
    for (size_t t = 0; t < nt; t++)
        for (int k = 1; k < 3; k++) {
            int32_t a = uf_find(uf, tm->tri[3 * t]), b = uf_find(uf, tm->tri[3 * t + k]);
            if (a < b) uf[b] = a;
            else if (b < a) uf[a] = b;
        }
    /* label components in vertex order (roots are the smallest index of their set, so a
     * root is labelled before its members; every parent link is resolved first) */
    for (size_t v = 0; v < nv; v++) uf[v] = uf_find(uf, (int32_t)v);
    for (size_t v = 0; v < nv; v++) {
        int32_t r = uf[v]; /* the root (r <= v: already a label when r < v) */
        uf[v] = r == (int32_t)v ? (int32_t)ncomp++ : uf[r];
    }
    cap_c = ncomp ? ncomp : 1;
    vote = as_alloc_array(ctx, cap_c, sizeof *vote);
    cs = as_alloc_array(ctx, cap_c, sizeof *cs);
    cvert = as_alloc_array(ctx, cap_c, sizeof *cvert);
    cchi = as_alloc_array(ctx, cap_c, sizeof *cchi);
    cbox = as_alloc_array(ctx, cap_c, 6 * sizeof *cbox);
    sc_out = as_alloc_array(ctx, ss->nscomp > 0 ? (size_t)ss->nscomp : 1, sizeof *sc_out);
    split = as_alloc_array(ctx, ss->nscomp > 0 ? (size_t)ss->nscomp : 1, sizeof *split);
    if (!vote || !cs || !cvert || !cchi || !cbox || !sc_out || !split) goto nomem;
    for (size_t c = 0; c < ncomp; c++) {
        vote[c] = 0;
        cs[c] = -1;
        cvert[c] = -1;
        cchi[c] = 0;
        for (int k = 0; k < 3; k++) {
            cbox[6 * c + k] = INFINITY;
            cbox[6 * c + 3 + k] = -INFINITY;
        }
    }
    for (size_t v = 0; v < nv; v++) {
        if (cvert[uf[v]] < 0) cvert[uf[v]] = (int32_t)v;
        cchi[uf[v]] += 2;
        double *B = cbox + 6 * (size_t)uf[v];
        for (int k = 0; k < 3; k++) {
            double x = tm->xyz[3 * v + k];
            if (x < B[k]) B[k] = x;
            if (x > B[3 + k]) B[3 + k] = x;
        }
    }
    for (size_t t = 0; t < nt; t++) {
        tcomp[t] = uf[tm->tri[3 * t]];
        cchi[tcomp[t]] -= 1;
    }
    m->stats.components = ncomp;
    m->stats.components_found = m->stats.components_split = m->stats.components_joined = 0;
    m->stats.pieces_below_resolution = m->stats.edges_below_resolution = 0;
    *refinable = 1; /* from here on, every failure is one of topology */
    /* 3. consistent orientation by breadth-first search; flip[t] relative to the seed */
    for (size_t t = 0; t < nt; t++) flip[t] = -1;
    for (size_t seed = 0; seed < nt; seed++) {
        if (flip[seed] >= 0) continue;
        size_t head = 0, tail = 0;
        flip[seed] = 0;
        queue[tail++] = (int32_t)seed;
        while (head < tail) {
            int32_t t = queue[head++];
            const int32_t *T = tm->tri + 3 * (size_t)t;
            for (int k = 0; k < 3; k++) {
                /* t traverses a -> b (as oriented after its flip) */
                int32_t a = T[k], b = T[(k + 1) % 3];
                if (flip[t]) {
                    int32_t x = a;
                    a = b;
                    b = x;
                }
                for (int32_t j = start[a]; j < start[a + 1]; j++) {
                    int32_t u = inc[j];
                    if (u == t) continue;
                    int pa = tri_pos(tm->tri, u, a), pb = tri_pos(tm->tri, u, b);
                    if (pb < 0) continue;
                    /* u as given traverses a -> b iff pb follows pa */
                    int same = (pa + 1) % 3 == pb;
                    int want = same ? 1 : 0; /* u must traverse b -> a */
                    if (flip[u] < 0) {
                        flip[u] = (int8_t)want;
                        queue[tail++] = u;
                    } else if (flip[u] != want) {
                        const double *x = tm->xyz + 3 * (size_t)a;
                        *sig = AS_CERT_ORIENT;
                        const double everywhere[3] = {0, 0, 0};
                        if ((s = add_trouble(ctx, ss, everywhere, INFINITY)) != ANISTAR_OK)
                            goto done;
                        as_fail(ctx, ANISTAR_INCOMPLETE,
                                "mesher: uncertified: the mesh is not orientable near "
                                "(%.17g, %.17g, %.17g)",
                                x[0], x[1], x[2]);
                        goto done;
                    }
                }
            }
        }
    }
    /* the area-weighted vote: flip[t] = 1 disagrees with the normal-based orientation */
    for (size_t t = 0; t < nt; t++) {
        const int32_t *T = tm->tri + 3 * t;
        const double *a = tm->xyz + 3 * (size_t)T[0], *b = tm->xyz + 3 * (size_t)T[1],
                     *c = tm->xyz + 3 * (size_t)T[2];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double x[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2],
                       u[0] * w[1] - u[1] * w[0]};
        double area = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
        vote[tcomp[t]] += flip[t] ? -area : area;
    }
    size_t flipped = 0;
    for (size_t t = 0; t < nt; t++) {
        int f = flip[t] ^ (vote[tcomp[t]] < 0);
        if (!f) continue;
        int32_t *T = tm->tri + 3 * t, x = T[1];
        T[1] = T[2];
        T[2] = x;
        flipped++;
    }
    (void)flipped;
    /* 4. fidelity: every edge hugs S (see the design note) */
    const double floor2 = ss->feat.floor_e * ss->feat.floor_e;
    for (size_t t = 0; t < nt; t++) {
        const int32_t *T = tm->tri + 3 * t;
        for (int k = 0; k < 3; k++) {
            int32_t a = T[k], b = T[(k + 1) % 3];
            if (a > b) continue; /* each edge once (the other triangle has b -> a) */
            const double *x = tm->xyz + 3 * (size_t)a, *y = tm->xyz + 3 * (size_t)b;
            double mid[3], q[3], e2 = 0, d2 = 0;
            for (int j = 0; j < 3; j++) {
                mid[j] = 0.5 * (x[j] + y[j]);
                e2 += (y[j] - x[j]) * (y[j] - x[j]);
            }
            s = as_surface_project(ctx, ss->surf, mid, q);
            if (s == ANISTAR_ENOSURFACE) {
                s = ANISTAR_OK;
                continue;
            }
            if (s != ANISTAR_OK) goto done;
            for (int j = 0; j < 3; j++) d2 += (q[j] - mid[j]) * (q[j] - mid[j]);
            /* d > AS_CERT_SAGITTA * (half the edge), off S, between points whose normals of
             * S are nearly opposite (not a crease: its faces meet at an angle) */
            int mside = 0;
            if (d2 > AS_CERT_SAGITTA * AS_CERT_SAGITTA * 0.25 * e2 &&
                (s = as_surface_side(ctx, ss->surf, mid, &mside)) != ANISTAR_OK)
                goto done;
            if (mside != 0 && d2 > AS_CERT_SAGITTA * AS_CERT_SAGITTA * 0.25 * e2) {
                double nx[3], ny[3];
                int sx = 0, sy = 0;
                if ((s = as_surface_normal_at(ctx, ss->surf, x, nx, &sx)) != ANISTAR_OK ||
                    (s = as_surface_normal_at(ctx, ss->surf, y, ny, &sy)) != ANISTAR_OK)
                    goto done;
                if (sx || sy || nx[0] * ny[0] + nx[1] * ny[1] + nx[2] * ny[2] > AS_CERT_OPPOSITE)
                    continue;
                if (d2 <= floor2) {
                    /* the gap or the plate is narrower than twice the surface's own
                     * resolution (the feature size's floor): not resolved, by design */
                    m->stats.edges_below_resolution++;
                    continue;
                }
                if (!*sig) {
                    *sig = AS_CERT_FIDELITY;
                    as_fail(ctx, ANISTAR_INCOMPLETE,
                            "mesher: uncertified: the mesh edge from (%.17g, %.17g, %.17g) to "
                            "(%.17g, %.17g, %.17g) passes %.3g from S, %.2f of its half length: "
                            "it bridges a gap or cuts through a thin part of S",
                            x[0], x[1], x[2], y[0], y[1], y[2], sqrt(d2), sqrt(d2 / (0.25 * e2)));
                }
                /* refinement points (the refiner inserts them): the point of S the edge
                 * misses, and the surface centers of the two facets on the edge (a facet
                 * whose center is inserted dies, as in rule 1) */
                if ((s = add_fix(ctx, ss, q, 0.5 * sqrt(e2))) != ANISTAR_OK ||
                    (s = add_trouble(ctx, ss, mid, 4 * sqrt(e2))) != ANISTAR_OK)
                    goto done;
                for (int32_t j = start[a]; j < start[a + 1]; j++) {
                    int32_t u = inc[j];
                    if (tri_pos(tm->tri, u, b) < 0) continue;
                    as_gid g[3];
                    for (int i = 0; i < 3; i++) g[i] = m->gid[tm->tri[3 * (size_t)u + i]];
                    as_sort_gid3(g);
                    const as_star *sv = ss->stars[g[0]];
                    int32_t fi = as_star_find(sv, g);
                    if (fi < 0) continue;
                    const double *c = sv->rf[fi].c, *o = ss->xyz + 3 * (size_t)g[0];
                    double rc = sqrt((c[0] - o[0]) * (c[0] - o[0]) + (c[1] - o[1]) * (c[1] - o[1]) +
                                     (c[2] - o[2]) * (c[2] - o[2]));
                    if ((s = add_fix(ctx, ss, c, rc)) != ANISTAR_OK) goto done;
                }
            }
        }
    }
    if (*sig) goto done;
    /* 5. components against the sample components of the initial sites */
    for (int32_t i = 0; i < ss->n; i++) vmap[i] = -1;
    for (size_t k = 0; k < nv; k++) vmap[m->gid[k]] = (int32_t)k;
    for (int32_t c = 0; c < ss->nscomp; c++) {
        sc_out[c] = -1;
        split[c] = 0;
    }
    const int exact = as_surface_is_mesh(ss->surf);
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        int32_t c = ss->scomp[v];
        if (c < 0 || vmap[v] < 0) continue;
        int32_t oc = uf[vmap[v]];
        const double *x = ss->xyz + 3 * (size_t)v;
        if (sc_out[c] >= 0 && sc_out[c] != oc) {
            split[c] = 1;
            if (exact) {
                *sig = AS_CERT_SPLIT | (uint64_t)c;
                as_fail(ctx, ANISTAR_INCOMPLETE,
                        "mesher: uncertified: input component %d came out as two or more "
                        "pieces, one of them around (%.17g, %.17g, %.17g)",
                        (int)c, x[0], x[1], x[2]);
                if ((s = piece_reach(ctx, ss, m, tcomp, ncomp, &creach)) == ANISTAR_OK &&
                    (s = trouble_piece(ctx, ss, cbox + 6 * (size_t)oc, creach[oc])) ==
                        ANISTAR_OK)
                    s = trouble_piece(ctx, ss, cbox + 6 * (size_t)sc_out[c],
                                      creach[sc_out[c]]);
                goto done;
            }
        } else {
            sc_out[c] = oc;
        }
        if (cs[oc] >= 0 && cs[oc] != c) {
            if (exact) {
                *sig = AS_CERT_JOIN | ((uint64_t)cs[oc] << 24) | (uint64_t)c;
                as_fail(ctx, ANISTAR_INCOMPLETE,
                        "mesher: uncertified: input components %d and %d are joined in one "
                        "piece of the mesh around (%.17g, %.17g, %.17g)",
                        (int)cs[oc], (int)c, x[0], x[1], x[2]);
                if ((s = piece_reach(ctx, ss, m, tcomp, ncomp, &creach)) == ANISTAR_OK)
                    s = trouble_piece(ctx, ss, cbox + 6 * (size_t)oc, creach[oc]);
                goto done;
            }
            m->stats.components_joined++;
        } else {
            cs[oc] = c;
        }
    }
    for (int32_t c = 0; c < ss->nscomp; c++) m->stats.components_split += split[c];
    for (int32_t c = 0; c < ss->nscomp; c++)
        if (sc_out[c] < 0) {
            *refinable = 0;
            as_fail(ctx, ANISTAR_INCOMPLETE,
                    "mesher: uncertified: sample component %d of S has no mesh (its initial sites "
                    "are in no output facet)",
                    (int)c);
            goto done;
        }
    /* a piece that is not the whole mesh of one sample component (found by refinement, or
     * one of a split) must bound a region of its own (function kinds; exact kinds have
     * no such piece) */
    for (size_t oc = 0; oc < ncomp; oc++) {
        int alone = cs[oc] >= 0 && !split[cs[oc]];
        if (alone) continue;
        const double *x = tm->xyz + 3 * (size_t)cvert[oc];
        if (!exact) {
            /* a piece that fits in a ball of the floor's radius: whatever joins it to
             * the rest of S, or whether it bounds a region, is below the resolution */
            if (box_diagonal(cbox + 6 * oc) <= 2 * ss->feat.floor_e) {
                m->stats.pieces_below_resolution++;
                continue;
            }
            int yes = 0;
            if ((s = piece_encloses(ctx, ss->surf, tm, cbox + 6 * oc, cvert[oc], &yes)) !=
                ANISTAR_OK)
                goto done;
            if (yes) {
                if (cs[oc] < 0) m->stats.components_found++;
                continue;
            }
            if (!ptri) {
                /* the triangles of each piece (counting sort by component), once */
                pstart = as_alloc_array(ctx, ncomp + 1, sizeof *pstart);
                ptri = as_alloc_array(ctx, nt, sizeof *ptri);
                if (!pstart || !ptri) goto nomem;
                memset(pstart, 0, (ncomp + 1) * sizeof *pstart);
                for (size_t t = 0; t < nt; t++) pstart[tcomp[t] + 1]++;
                for (size_t c = 0; c < ncomp; c++) pstart[c + 1] += pstart[c];
                for (size_t t = 0; t < nt; t++) ptri[pstart[tcomp[t]]++] = (int32_t)t;
                for (size_t c = ncomp; c > 0; c--) pstart[c] = pstart[c - 1];
                pstart[0] = 0;
            }
            if ((s = piece_cut_below_floor(ctx, ss->surf, tm, ptri + pstart[oc],
                                           (size_t)(pstart[oc + 1] - pstart[oc]), start, inc,
                                           cbox + 6 * oc, cvert[oc], ss->feat.floor_e, &yes)) !=
                ANISTAR_OK)
                goto done;
            if (yes) {
                m->stats.pieces_below_resolution++;
                continue;
            }
        }
        if (!*sig) {
            *sig = AS_CERT_PIECE | (uint64_t)oc;
            as_fail(ctx, ANISTAR_INCOMPLETE,
                    "mesher: uncertified: a piece of the mesh around (%.17g, %.17g, %.17g) %s: "
                    "a fragment of a thinner part (plate, tube, neck) than the facets resolved",
                    x[0], x[1], x[2],
                    exact ? "covers no input component" : "bounds no region of its own");
        }
        if ((s = piece_reach(ctx, ss, m, tcomp, ncomp, &creach)) != ANISTAR_OK ||
            (s = trouble_piece(ctx, ss, cbox + 6 * oc, creach[oc])) != ANISTAR_OK)
            goto done;
    }
    if (*sig) goto done;
    if (as_surface_is_mesh(ss->surf)) {
        as_mesh_info mi;
        as_mesh_surface_info(ss->surf, &mi);
        for (size_t oc = 0; oc < ncomp; oc++) {
            const double *x = tm->xyz + 3 * (size_t)cvert[oc];
            long long chi = cchi[oc] / 2, want = mi.ceuler[cs[oc]];
            if (cchi[oc] % 2 != 0 || chi != want) {
                if (!*sig) {
                    *sig = AS_CERT_EULER | (uint64_t)oc;
                    as_fail(ctx, ANISTAR_INCOMPLETE,
                            "mesher: uncertified: the mesh component around (%.17g, %.17g, "
                            "%.17g) has Euler characteristic %lld, the input component %lld: "
                            "features finer than the sampling",
                            x[0], x[1], x[2], chi, want);
                }
                if ((s = piece_reach(ctx, ss, m, tcomp, ncomp, &creach)) != ANISTAR_OK ||
                    (s = trouble_piece(ctx, ss, cbox + 6 * oc, creach[oc])) != ANISTAR_OK)
                    goto done;
            }
        }
        if (*sig) goto done;
    }
    *ok = 1;
    *refinable = 0;
    goto done;
nomem:
    s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (final checks)");
done:
    as_free(ctx, start, (nv + 1) * sizeof *start);
    as_free(ctx, inc, 3 * nt * sizeof *inc);
    as_free(ctx, uf, nv * sizeof *uf);
    as_free(ctx, queue, nt * sizeof *queue);
    as_free(ctx, flip, nt * sizeof *flip);
    as_free(ctx, tcomp, nt * sizeof *tcomp);
    as_free(ctx, vmap, (size_t)ss->n * sizeof *vmap);
    as_free(ctx, vote, cap_c * sizeof *vote);
    as_free(ctx, cs, cap_c * sizeof *cs);
    as_free(ctx, cvert, cap_c * sizeof *cvert);
    as_free(ctx, cchi, cap_c * sizeof *cchi);
    as_free(ctx, cbox, cap_c * 6 * sizeof *cbox);
    as_free(ctx, sc_out, (ss->nscomp > 0 ? (size_t)ss->nscomp : 1) * sizeof *sc_out);
    as_free(ctx, split, (ss->nscomp > 0 ? (size_t)ss->nscomp : 1) * sizeof *split);
    if (pstart) as_free(ctx, pstart, (ncomp + 1) * sizeof *pstart);
    if (ptri) as_free(ctx, ptri, nt * sizeof *ptri);
    if (creach) as_free(ctx, creach, (ncomp ? ncomp : 1) * sizeof *creach);
    return s;
}
