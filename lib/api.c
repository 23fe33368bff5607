/*
 * api.c — the implementation of include/anistar.h on top of the internal layers.
 * Public functions validate their arguments, call the layers, and turn failures into
 * a status plus a message in the context. Nothing else lives here.
 */
#include "anistar.h"
#include "core.h"
#include "geom/linalg.h"
#include "geom/metric.h"
#include "geom/predicates.h"
#include "io/meshio.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define AS_STR2_(x) #x
#define AS_STR_(x) AS_STR2_(x)

/* ---- version ---------------------------------------------------------------------- */

ANISTAR_API const char *anistar_version(void) {
    return AS_STR_(ANISTAR_VERSION_MAJOR) "." AS_STR_(ANISTAR_VERSION_MINOR) "." AS_STR_(
        ANISTAR_VERSION_PATCH);
}

ANISTAR_API int anistar_version_number(void) { return ANISTAR_VERSION_NUMBER; }

/* ---- status: anistar_status_string and anistar_status_name are in core.c (every layer
 * reports with them; the api is the top layer) */

/* ---- context ---------------------------------------------------------------------- */

static void *as_default_alloc(void *user, void *ptr, size_t old_size, size_t new_size) {
    (void)user;
    (void)old_size;
    if (new_size == 0) {
        free(ptr);
        return NULL;
    }
    return realloc(ptr, new_size);
}

ANISTAR_API anistar_context *anistar_context_new(const anistar_allocator *a) {
    anistar_allocator al;
    if (a) {
        if (!a->fn) return NULL;
        al = *a;
    } else {
        al.fn = as_default_alloc;
        al.user = NULL;
    }
    anistar_context *ctx = al.fn(al.user, NULL, 0, sizeof *ctx);
    if (!ctx) return NULL;
    memset(ctx, 0, sizeof *ctx);
    ctx->alloc = al;
    ctx->last_status = ANISTAR_OK;
    return ctx;
}

ANISTAR_API void anistar_context_free(anistar_context *ctx) {
    if (!ctx) return;
    anistar_allocator al = ctx->alloc;
    al.fn(al.user, ctx, sizeof *ctx, 0);
}

ANISTAR_API const char *anistar_last_error(const anistar_context *ctx) {
    if (!ctx) return "no context (anistar_context_new failed or was not called)";
    return ctx->last_error;
}

ANISTAR_API anistar_status anistar_last_status(const anistar_context *ctx) {
    return ctx ? ctx->last_status : ANISTAR_EINVAL;
}

/* ---- predicates ------------------------------------------------------------------- */

ANISTAR_API double anistar_orient3d(const double a[3], const double b[3], const double c[3],
                                    const double d[3]) {
    if (!a || !b || !c || !d) return NAN;
    return as_orient3d(a, b, c, d);
}

ANISTAR_API double anistar_insphere(const double a[3], const double b[3], const double c[3],
                                    const double d[3], const double e[3]) {
    if (!a || !b || !c || !d || !e) return NAN;
    return as_insphere(a, b, c, d, e);
}

/* ---- metric tensors --------------------------------------------------------------- */

static int as_finite_n(const double *v, int n) {
    for (int i = 0; i < n; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

static anistar_status as_frame_or_fail(anistar_context *ctx, const double m[6],
                                       as_metric_frame *mf, const char *what) {
    if (!as_finite_n(m, 6))
        return as_fail(ctx, ANISTAR_EINVAL, "%s: tensor has a non-finite entry", what);
    if (as_metric_frame_init(mf, m))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "%s: tensor (%g %g %g %g %g %g) is not symmetric positive definite "
                       "with condition number <= 1e24",
                       what, m[0], m[1], m[2], m[3], m[4], m[5]);
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_tensor_distortion(anistar_context *ctx, const double m[6],
                                                     const double n[6], double *gamma) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!m || !n || !gamma)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_tensor_distortion: NULL argument");
    as_metric_frame a, b;
    anistar_status st = as_frame_or_fail(ctx, m, &a, "anistar_tensor_distortion: m");
    if (st) return st;
    st = as_frame_or_fail(ctx, n, &b, "anistar_tensor_distortion: n");
    if (st) return st;
    *gamma = as_metric_distortion(&a, &b);
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_tensor_distance(anistar_context *ctx, const double m[6],
                                                   const double a[3], const double b[3],
                                                   double *dist) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!m || !a || !b || !dist)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_tensor_distance: NULL argument");
    if (!as_finite_n(a, 3) || !as_finite_n(b, 3))
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_tensor_distance: non-finite point");
    as_metric_frame mf;
    anistar_status st = as_frame_or_fail(ctx, m, &mf, "anistar_tensor_distance");
    if (st) return st;
    *dist = as_metric_dist(&mf, a, b);
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_tensor_sqrt(anistar_context *ctx, const double m[6],
                                               double f[6]) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!m || !f) return as_fail(ctx, ANISTAR_EINVAL, "anistar_tensor_sqrt: NULL argument");
    as_metric_frame mf;
    anistar_status st = as_frame_or_fail(ctx, m, &mf, "anistar_tensor_sqrt");
    if (st) return st;
    f[0] = mf.f[0];
    f[1] = mf.f[1];
    f[2] = mf.f[2];
    f[3] = mf.f[4];
    f[4] = mf.f[5];
    f[5] = mf.f[8];
    return ANISTAR_OK;
}

/* ==== MESHER (issue 6) ==== */

#include "mesher/mesher.h"

struct anistar_mesher {
    anistar_context *ctx;
    const as_surface *surf;
    const as_field *field;
    as_mesher_params prm;
    as_run_ctl ctl; /* progress callback, stop flag, published state */
};

ANISTAR_API anistar_status anistar_mesher_new(anistar_context *ctx, const anistar_surface *s,
                                              const anistar_metric *m, anistar_mesher **out) {
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesher_new: out is NULL");
    *out = NULL;
    if (!ctx) return ANISTAR_EINVAL;
    if (!s || !m) return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesher_new: NULL surface or metric");
    anistar_mesher *me = as_alloc(ctx, sizeof *me);
    if (!me) return as_fail(ctx, ANISTAR_ENOMEM, "anistar_mesher_new: out of memory");
    memset(me, 0, sizeof *me);
    me->ctx = ctx;
    me->surf = s;
    me->field = m;
    as_mesher_params_default(&me->prm);
    atomic_init(&me->ctl.stop, 0);
    me->ctl.state.eta_seconds = -1;
    *out = me;
    return ANISTAR_OK;
}

ANISTAR_API void anistar_mesher_free(anistar_mesher *m) {
    if (m) as_free(m->ctx, m, sizeof *m);
}

static int as_api_is_int(double v, double lo, double hi) {
    return isfinite(v) && v == floor(v) && v >= lo && v <= hi;
}

ANISTAR_API anistar_status anistar_mesher_set(anistar_mesher *m, anistar_param key,
                                              double value) {
    if (!m) return ANISTAR_EINVAL;
    anistar_context *ctx = m->ctx;
    as_mesher_params *p = &m->prm;
    switch (key) {
    case ANISTAR_PARAM_R0:
        if (!(isfinite(value) && value > 0))
            return as_fail(ctx, ANISTAR_EINVAL, "r0 must be a finite number > 0, got %g", value);
        p->r0 = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_GAMMA0:
        if (!(isfinite(value) && value > 1))
            return as_fail(ctx, ANISTAR_EINVAL, "gamma0 must be a finite number > 1, got %g", value);
        p->gamma0 = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_RHO0:
        if (!(isfinite(value) && value > 1))
            return as_fail(ctx, ANISTAR_EINVAL, "rho0 must be a finite number > 1, got %g", value);
        p->rho0 = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_BETA:
        if (!(isfinite(value) && value >= 1))
            return as_fail(ctx, ANISTAR_EINVAL, "beta must be a finite number >= 1, got %g", value);
        p->beta = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_DELTA:
        if (!(value > 0 && value < 1))
            return as_fail(ctx, ANISTAR_EINVAL, "delta must be in (0, 1), got %g", value);
        p->delta = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_APPROX:
        if (!(isfinite(value) && value >= 0))
            return as_fail(ctx, ANISTAR_EINVAL, "approx must be a finite number >= 0, got %g", value);
        p->approx = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_MAX_VERTICES:
        if (!as_api_is_int(value, 0, (double)AS_MESHER_MAX_SITES))
            return as_fail(ctx, ANISTAR_EINVAL,
                           "max_vertices must be an integer in [0, %lld], got %g",
                           (long long)AS_MESHER_MAX_SITES, value);
        p->max_vertices = (int64_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_MAX_SECONDS:
        if (!(isfinite(value) && value >= 0))
            return as_fail(ctx, ANISTAR_EINVAL, "max_seconds must be a finite number >= 0, got %g",
                           value);
        p->max_seconds = value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_SEED:
        if (!as_api_is_int(value, 0, 9007199254740992.0))
            return as_fail(ctx, ANISTAR_EINVAL, "seed must be an integer in [0, 2^53], got %g",
                           value);
        p->seed = (uint64_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_PICK_TRIES:
        if (!as_api_is_int(value, 1, 100000))
            return as_fail(ctx, ANISTAR_EINVAL, "pick_tries must be an integer in [1, 100000], got %g",
                           value);
        p->pick_tries = (int32_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_OPTIMIZE: /* optimize (vertex optimisation, optimize.c) */
        if (!(value == 0 || value == 1))
            return as_fail(ctx, ANISTAR_EINVAL, "optimize must be 0 or 1, got %g", value);
        p->optimize = (int32_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_MAX_STALL:
        if (!as_api_is_int(value, 0, 9007199254740992.0))
            return as_fail(ctx, ANISTAR_EINVAL, "max_stall must be an integer in [0, 2^53], got %g",
                           value);
        p->max_stall = (int64_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_ANISO_CAP:
        if (!(value == 0 || value == 1))
            return as_fail(ctx, ANISTAR_EINVAL, "aniso_cap must be 0 or 1, got %g", value);
        p->aniso_cap = (int32_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_THREADS:
        if (!as_api_is_int(value, 1, 1024))
            return as_fail(ctx, ANISTAR_EINVAL, "threads must be an integer in [1, 1024], got %g",
                           value);
        p->threads = (int32_t)value;
        return ANISTAR_OK;
    case ANISTAR_PARAM_HMIN:
    case ANISTAR_PARAM_HMAX:
        if (!(isfinite(value) && value >= 0))
            return as_fail(ctx, ANISTAR_EINVAL, "%s must be a finite number >= 0, got %g",
                           key == ANISTAR_PARAM_HMIN ? "hmin" : "hmax", value);
        if (key == ANISTAR_PARAM_HMIN) p->hmin = value;
        else p->hmax = value;
        return ANISTAR_OK;
    }
    return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesher_set: unknown parameter %d", (int)key);
}

ANISTAR_API anistar_status anistar_mesher_get(const anistar_mesher *m, anistar_param key,
                                              double *value) {
    if (!m || !value) return ANISTAR_EINVAL;
    const as_mesher_params *p = &m->prm;
    switch (key) {
    case ANISTAR_PARAM_R0: *value = p->r0; return ANISTAR_OK;
    case ANISTAR_PARAM_GAMMA0: *value = p->gamma0; return ANISTAR_OK;
    case ANISTAR_PARAM_RHO0: *value = p->rho0; return ANISTAR_OK;
    case ANISTAR_PARAM_BETA: *value = p->beta; return ANISTAR_OK;
    case ANISTAR_PARAM_DELTA: *value = p->delta; return ANISTAR_OK;
    case ANISTAR_PARAM_APPROX: *value = p->approx; return ANISTAR_OK;
    case ANISTAR_PARAM_MAX_VERTICES: *value = (double)p->max_vertices; return ANISTAR_OK;
    case ANISTAR_PARAM_MAX_SECONDS: *value = p->max_seconds; return ANISTAR_OK;
    case ANISTAR_PARAM_SEED: *value = (double)p->seed; return ANISTAR_OK;
    case ANISTAR_PARAM_PICK_TRIES: *value = p->pick_tries; return ANISTAR_OK;
    case ANISTAR_PARAM_OPTIMIZE: *value = p->optimize; return ANISTAR_OK; /* optimize.c */
    case ANISTAR_PARAM_MAX_STALL: *value = (double)p->max_stall; return ANISTAR_OK;
    case ANISTAR_PARAM_HMIN: *value = p->hmin; return ANISTAR_OK;
    case ANISTAR_PARAM_HMAX: *value = p->hmax; return ANISTAR_OK;
    case ANISTAR_PARAM_ANISO_CAP: *value = p->aniso_cap; return ANISTAR_OK;
    case ANISTAR_PARAM_THREADS: *value = p->threads; return ANISTAR_OK;
    }
    return as_fail(m->ctx, ANISTAR_EINVAL, "anistar_mesher_get: unknown parameter %d", (int)key);
}

ANISTAR_API void anistar_mesher_set_progress(anistar_mesher *m, anistar_progress_fn fn,
                                             void *user) {
    if (!m) return;
    m->ctl.progress = fn;
    m->ctl.user = user;
}

ANISTAR_API anistar_status anistar_mesher_get_progress(const anistar_mesher *m,
                                                       anistar_progress *p) {
    if (!m || !p) return ANISTAR_EINVAL;
    *p = m->ctl.state;
    return ANISTAR_OK;
}

ANISTAR_API void anistar_mesher_stop(anistar_mesher *m) {
    /* design: only a lock-free atomic store, so that a signal handler may call it */
    if (m) atomic_store(&m->ctl.stop, 1);
}

ANISTAR_API const char *anistar_stop_reason_name(int reason) {
    switch (reason) {
    case ANISTAR_STOP_DONE: return "done";
    case ANISTAR_STOP_MAX_VERTICES: return "max_vertices";
    case ANISTAR_STOP_MAX_SECONDS: return "max_seconds";
    case ANISTAR_STOP_STALL: return "stall";
    case ANISTAR_STOP_REQUESTED: return "requested";
    case ANISTAR_STOP_UNCERTIFIED: return "uncertified";
    }
    return "unknown";
}

ANISTAR_API anistar_status anistar_mesher_run(anistar_mesher *m, anistar_mesh **out) {
    if (out) *out = NULL;
    if (!m) return ANISTAR_EINVAL;
    if (!out) return as_fail(m->ctx, ANISTAR_EINVAL, "anistar_mesher_run: out is NULL");
    anistar_status st = as_mesher_run(m->ctx, m->surf, m->field, &m->prm, &m->ctl, out);
    atomic_store(&m->ctl.stop, 0);
    return st;
}

ANISTAR_API size_t anistar_mesh_vertex_count(const anistar_mesh *mesh) {
    return mesh ? mesh->tm.nv : 0;
}
ANISTAR_API size_t anistar_mesh_triangle_count(const anistar_mesh *mesh) {
    return mesh ? mesh->tm.nt : 0;
}
ANISTAR_API void anistar_mesh_get_vertices(const anistar_mesh *mesh, double *xyz) {
    if (mesh && xyz && mesh->tm.nv) memcpy(xyz, mesh->tm.xyz, 3 * mesh->tm.nv * sizeof *xyz);
}
ANISTAR_API void anistar_mesh_get_triangles(const anistar_mesh *mesh, int32_t *tri) {
    if (mesh && tri && mesh->tm.nt) memcpy(tri, mesh->tm.tri, 3 * mesh->tm.nt * sizeof *tri);
}
ANISTAR_API void anistar_mesh_get_metrics(const anistar_mesh *mesh, double *tensors) {
    if (mesh && tensors && mesh->tm.nv && mesh->tm.tensor)
        memcpy(tensors, mesh->tm.tensor, 6 * mesh->tm.nv * sizeof *tensors);
}
ANISTAR_API void anistar_mesh_get_stats(const anistar_mesh *mesh, anistar_mesh_stats *stats) {
    if (mesh && stats) *stats = mesh->stats;
}
static anistar_status as_api_tri_values(anistar_context *ctx, anistar_color_by by, size_t nv,
                                        const double *xyz, size_t nt, const int32_t *tri,
                                        const double *tensors, double *out);

/*
 * design: formats with cell data (.vtk .vtu .ply) get two per-triangle fields:
 *   "radius_edge" (the mesher's rho, the largest over the three vertex metrics) and
 *   "anisotropy" (the largest sqrt(lambda_max/lambda_min) of the three vertex tensors, as
 *   anistar_triangle_values / render --color anisotropy); a non-finite value (a degenerate
 *   triangle, never in a certified mesh) is written as -1.
 */
ANISTAR_API anistar_status anistar_mesh_write(anistar_context *ctx, const anistar_mesh *mesh,
                                              const char *path) {
    if (!mesh) return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesh_write: mesh is NULL");
    if (!ctx) ctx = mesh->ctx;
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesh_write: path is NULL");
    as_mesh_format fmt = as_mesh_format_of(path);
    const as_trimesh *tm = &mesh->tm;
    if ((fmt != AS_FMT_VTK && fmt != AS_FMT_VTU && fmt != AS_FMT_PLY) || tm->nt == 0 ||
        !tm->tensor || mesh->nrho != tm->nt)
        return as_mesh_write(ctx, path, tm, NULL, 0);
    double *vals = as_alloc_array(ctx, tm->nt, 2 * sizeof(double));
    if (!vals) return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory for the cell data", path);
    double *rho = vals, *aniso = vals + tm->nt;
    memcpy(rho, mesh->rho, tm->nt * sizeof *rho);
    anistar_status st = as_api_tri_values(ctx, ANISTAR_COLOR_ANISOTROPY, tm->nv, tm->xyz, tm->nt,
                                          tm->tri, tm->tensor, aniso);
    if (!st) {
        for (size_t i = 0; i < 2 * tm->nt; i++)
            if (!isfinite(vals[i])) vals[i] = -1;
        as_cell_field cells[2] = {{"radius_edge", rho}, {"anisotropy", aniso}};
        st = as_mesh_write(ctx, path, tm, cells, 2);
    }
    as_free(ctx, vals, tm->nt * 2 * sizeof(double));
    return st;
}
ANISTAR_API void anistar_mesh_free(anistar_mesh *mesh) { as_mesh_free(mesh); }

/* ==== END MESHER ==== */

/* ==== RENDERING (issue 5) ==== */

#include "io/meshio.h"
#include "io/png.h"
#include "io/render.h"

ANISTAR_API void anistar_render_options_init(anistar_render_options *opt) {
    if (!opt) return;
    memset(opt, 0, sizeof *opt);
    opt->width = 1024;
    opt->height = 768;
    opt->azimuth = 30;
    opt->elevation = 20;
    opt->up = 2;
    opt->color = ANISTAR_COLOR_QUALITY;
    opt->edges = 1;
    opt->legend = 1;
    opt->supersample = 3;
    opt->range_min = NAN;
    opt->range_max = NAN;
    opt->compress = 1;
    opt->sol_path = NULL;
}

/* Check the options and translate them into renderer parameters. */
static anistar_status as_api_render_params(anistar_context *ctx,
                                           const anistar_render_options *opt,
                                           as_render_params *p) {
    if (opt->width < 1 || opt->width > ANISTAR_RENDER_MAX_SIDE || opt->height < 1 ||
        opt->height > ANISTAR_RENDER_MAX_SIDE)
        return as_fail(ctx, ANISTAR_EINVAL, "render: image size %dx%d outside [1, %d]",
                       opt->width, opt->height, ANISTAR_RENDER_MAX_SIDE);
    if (opt->color != ANISTAR_COLOR_NONE && opt->color != ANISTAR_COLOR_QUALITY &&
        opt->color != ANISTAR_COLOR_ANISOTROPY)
        return as_fail(ctx, ANISTAR_EINVAL, "render: unknown colour mode %d", (int)opt->color);
    if ((opt->edges != 0 && opt->edges != 1) || (opt->legend != 0 && opt->legend != 1) ||
        (opt->compress != 0 && opt->compress != 1))
        return as_fail(ctx, ANISTAR_EINVAL, "render: edges, legend and compress must be 0 or 1");
    as_render_params_init(p);
    p->width = (uint32_t)opt->width;
    p->height = (uint32_t)opt->height;
    p->azimuth = opt->azimuth;
    p->elevation = opt->elevation;
    p->up = opt->up;
    p->supersample = opt->supersample;
    p->edges = opt->edges;
    p->legend = opt->legend;
    p->vmin = opt->range_min;
    p->vmax = opt->range_max;
    /* The renderer checks the rest (angles, up, supersample, range) with its messages. */
    return as_render_params_check(ctx, p);
}

/* Validate mesh arrays (indices and coordinates). */
static anistar_status as_api_mesh_arrays(anistar_context *ctx, const char *fn, size_t nv,
                                         const double *xyz, size_t nt, const int32_t *tri) {
    if ((nv && !xyz) || (nt && !tri))
        return as_fail(ctx, ANISTAR_EINVAL, "%s: NULL coordinates or triangles", fn);
    for (size_t i = 0; i < 3 * nv; i++)
        if (!isfinite(xyz[i]))
            return as_fail(ctx, ANISTAR_EINVAL, "%s: vertex %zu has a non-finite coordinate",
                           fn, i / 3);
    for (size_t i = 0; i < 3 * nt; i++)
        if (tri[i] < 0 || (size_t)tri[i] >= nv)
            return as_fail(ctx, ANISTAR_EINVAL,
                           "%s: triangle %zu: vertex index %ld out of range [0, %zu)", fn, i / 3,
                           (long)tri[i], nv);
    return ANISTAR_OK;
}

/* The per-triangle values of `by` (arrays already validated). */
static anistar_status as_api_tri_values(anistar_context *ctx, anistar_color_by by, size_t nv,
                                        const double *xyz, size_t nt, const int32_t *tri,
                                        const double *tensors, double *out) {
    if (by == ANISTAR_COLOR_QUALITY || (by == ANISTAR_COLOR_ANISOTROPY && !tensors)) {
        for (size_t t = 0; t < nt; t++) {
            const int32_t *v = tri + 3 * t;
            const double *a = xyz + 3 * (size_t)v[0], *b = xyz + 3 * (size_t)v[1],
                         *c = xyz + 3 * (size_t)v[2];
            out[t] = by == ANISTAR_COLOR_QUALITY ? as_tri_radius_edge(a, b, c)
                                                 : as_tri_aspect(a, b, c);
        }
        return ANISTAR_OK;
    }
    /* Anisotropy of the vertex tensors: sqrt(lambda_max / lambda_min). */
    double *va = as_alloc_array(ctx, nv, sizeof(double));
    if (nv && !va) return as_fail(ctx, ANISTAR_ENOMEM, "render: out of memory");
    for (size_t i = 0; i < nv; i++) {
        double w[3], vec[9];
        va[i] = NAN;
        if (as_sym3_eigen(tensors + 6 * i, w, vec) == 0 && w[0] > 0) va[i] = sqrt(w[2] / w[0]);
    }
    for (size_t t = 0; t < nt; t++) {
        double m = -INFINITY;
        for (int k = 0; k < 3; k++) {
            double x = va[tri[3 * t + (size_t)k]];
            m = isnan(x) || isnan(m) ? NAN : (x > m ? x : m);
        }
        out[t] = m;
    }
    as_free(ctx, va, nv * sizeof(double));
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_triangle_values(anistar_context *ctx, anistar_color_by by,
                                                   size_t nv, const double *xyz, size_t nt,
                                                   const int32_t *tri, const double *tensors,
                                                   double *out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (by != ANISTAR_COLOR_QUALITY && by != ANISTAR_COLOR_ANISOTROPY)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_triangle_values: `by` must be QUALITY or ANISOTROPY");
    if (nt && !out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_triangle_values: NULL out");
    anistar_status st = as_api_mesh_arrays(ctx, "anistar_triangle_values", nv, xyz, nt, tri);
    if (st) return st;
    return as_api_tri_values(ctx, by, nv, xyz, nt, tri, tensors, out);
}

/* Render validated arrays with validated parameters to png_path. */
static anistar_status as_api_render(anistar_context *ctx, const as_render_params *p,
                                    const anistar_render_options *opt, size_t nv,
                                    const double *xyz, size_t nt, const int32_t *tri,
                                    const double *tensors, const double *values,
                                    const char *label, const char *png_path) {
    double *own = NULL;
    as_render_params q = *p;
    if (!values && opt->color != ANISTAR_COLOR_NONE && nt > 0) {
        own = as_alloc_array(ctx, nt, sizeof(double));
        if (!own) return as_fail(ctx, ANISTAR_ENOMEM, "render: out of memory");
        anistar_status st = as_api_tri_values(ctx, opt->color, nv, xyz, nt, tri, tensors, own);
        if (st) {
            as_free(ctx, own, nt * sizeof(double));
            return st;
        }
        values = own;
        label = opt->color == ANISTAR_COLOR_QUALITY ? "radius-edge ratio"
                : tensors                           ? "anisotropy"
                                                    : "aspect ratio";
    }
    q.label = label;
    size_t n = (size_t)q.width * q.height * 3;
    unsigned char *rgb = as_alloc(ctx, n);
    anistar_status st;
    if (!rgb) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "render: out of memory (%zu bytes for the image)", n);
    } else {
        st = as_render(ctx, &q, nv, xyz, nt, tri, values, rgb);
        if (!st)
            st = as_png_write(ctx, png_path, rgb, q.width, q.height, 3,
                              opt->compress ? AS_PNG_DEFLATE : AS_PNG_STORED);
    }
    as_free(ctx, rgb, n);
    as_free(ctx, own, nt * sizeof(double));
    return st;
}

ANISTAR_API anistar_status anistar_render_arrays(anistar_context *ctx, size_t nv,
                                                 const double *xyz, size_t nt,
                                                 const int32_t *tri, const double *tensors,
                                                 const double *values, const char *label,
                                                 const char *png_path,
                                                 const anistar_render_options *opt) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!png_path) return as_fail(ctx, ANISTAR_EINVAL, "anistar_render_arrays: NULL path");
    anistar_render_options def;
    if (!opt) {
        anistar_render_options_init(&def);
        opt = &def;
    }
    as_render_params p;
    anistar_status st = as_api_render_params(ctx, opt, &p);
    if (st) return st;
    st = as_api_mesh_arrays(ctx, "anistar_render_arrays", nv, xyz, nt, tri);
    if (st) return st;
    if (nt && values == NULL && opt->color == ANISTAR_COLOR_NONE) label = NULL;
    return as_api_render(ctx, &p, opt, nv, xyz, nt, tri, tensors, values, label, png_path);
}

ANISTAR_API anistar_status anistar_render_file(anistar_context *ctx, const char *mesh_path,
                                               const char *png_path,
                                               const anistar_render_options *opt) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!mesh_path || !png_path)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_render_file: NULL path");
    anistar_render_options def;
    if (!opt) {
        anistar_render_options_init(&def);
        opt = &def;
    }
    as_render_params p;
    anistar_status st = as_api_render_params(ctx, opt, &p);
    if (st) return st;
    as_trimesh m;
    as_trimesh_init(&m);
    st = as_mesh_read(ctx, mesh_path, &m);
    if (!st && opt->sol_path && opt->color == ANISTAR_COLOR_ANISOTROPY)
        st = as_trimesh_read_sol(ctx, opt->sol_path, &m); /* .sol or .solb */
    if (!st)
        st = as_api_render(ctx, &p, opt, m.nv, m.xyz, m.nt, m.tri, m.tensor, NULL, NULL,
                           png_path);
    as_trimesh_free(ctx, &m);
    return st;
}

/* ==== END RENDERING ==== */

/* ==== SURFACES AND METRIC FIELDS (issue 4) ==== */

#include "surface/field.h"
#include "surface/surface.h"
#include "io/image_io.h"

#include <ctype.h>

static int as_api_finite3(const double p[3]) {
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

/* Common checks of the surface queries: s and the point; errors go to s->ctx. */
static anistar_status as_api_query(const anistar_surface *s, const double p[3],
                                   const void *outp, const char *fn) {
    if (!s) return ANISTAR_EINVAL;
    if (!p || !outp) return as_fail(s->ctx, ANISTAR_EINVAL, "%s: NULL argument", fn);
    if (!as_api_finite3(p))
        return as_fail(s->ctx, ANISTAR_EINVAL, "%s: the point is not finite", fn);
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_surface_from_implicit(anistar_context *ctx,
                                                         const anistar_implicit_fn *fn,
                                                         const double center[3], double radius,
                                                         anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_implicit: NULL out");
    *out = NULL;
    if (!fn || !fn->value || !center)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_surface_from_implicit: NULL callbacks, value callback or center");
    as_implicit_fn f = {fn->value, fn->gradient, fn->hessian, fn->user};
    return as_implicit_create(ctx, &f, center, radius, out);
}

ANISTAR_API anistar_status anistar_surface_from_expression(anistar_context *ctx,
                                                           const char *expr,
                                                           const double center[3],
                                                           double radius,
                                                           anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_expression: NULL out");
    *out = NULL;
    if (!expr || !center)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_surface_from_expression: NULL expression or center");
    return as_implicit_from_expression(ctx, expr, center, radius, out);
}

ANISTAR_API anistar_status anistar_surface_builtin(anistar_context *ctx, const char *spec,
                                                   anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_builtin: NULL out");
    *out = NULL;
    if (!spec) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_builtin: NULL name");
    return as_implicit_builtin(ctx, spec, out);
}

ANISTAR_API anistar_status anistar_surface_builtin_info(size_t i, const char **name,
                                                        const char **description) {
    return as_implicit_builtin_info(i, name, description) ? ANISTAR_EINVAL : ANISTAR_OK;
}

/* 1 iff path ends with one of the image extensions (case-insensitive). */
static int as_api_is_image_path(const char *path) {
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash : path, '.');
    if (!dot) return 0;
    static const char *const ext[] = {"inr", "nrrd", "nhdr", "mha", "mhd"};
    for (size_t i = 0; i < sizeof ext / sizeof ext[0]; i++) {
        const char *a = dot + 1, *b = ext[i];
        while (*a && *b && tolower((unsigned char)*a) == *b) {
            a++;
            b++;
        }
        if (!*a && !*b) return 1;
    }
    return 0;
}

ANISTAR_API anistar_status anistar_surface_read(anistar_context *ctx, const char *path,
                                                anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_read: NULL out");
    *out = NULL;
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_read: NULL path");
    if (as_api_is_image_path(path))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "%s: an image needs an isovalue: use anistar_surface_from_image_file",
                       path);
    return as_mesh_surface_read(ctx, path, out);
}

ANISTAR_API anistar_status anistar_surface_from_triangles(anistar_context *ctx,
                                                          const double *xyz, size_t nv,
                                                          const int32_t *tri, size_t nt,
                                                          anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_triangles: NULL out");
    *out = NULL;
    if (!xyz || !tri)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_surface_from_triangles: NULL vertices or triangles");
    return as_mesh_surface_create(ctx, "triangles", xyz, nv, tri, nt, out);
}

ANISTAR_API anistar_status anistar_surface_from_image_file(anistar_context *ctx,
                                                           const char *path, double iso,
                                                           int inside, anistar_surface **out) {
    return anistar_surface_from_image_file_fit(ctx, path, iso, inside, ANISTAR_FIT_AUTO, out);
}

ANISTAR_API anistar_status anistar_surface_from_image_file_fit(anistar_context *ctx,
                                                               const char *path, double iso,
                                                               int inside, int fit,
                                                               anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_image_file: NULL out");
    *out = NULL;
    if (!path) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_image_file: NULL path");
    if (inside != ANISTAR_INSIDE_GREATER && inside != ANISTAR_INSIDE_LESS)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_surface_from_image_file: inside must be ANISTAR_INSIDE_GREATER "
                       "(1) or ANISTAR_INSIDE_LESS (-1), got %d",
                       inside);
    return as_image_surface_read_fit(ctx, path, iso, inside, fit, out);
}

ANISTAR_API int anistar_surface_image_fit(const anistar_surface *s) {
    return as_image_surface_fit(s);
}

ANISTAR_API anistar_status anistar_surface_from_image(anistar_context *ctx,
                                                      const double *voxels,
                                                      const size_t dims[3],
                                                      const double spacing[3],
                                                      const double origin[3], double iso,
                                                      int inside, anistar_surface **out) {
    return anistar_surface_from_image_fit(ctx, voxels, dims, spacing, origin, iso, inside,
                                          ANISTAR_FIT_AUTO, out);
}

ANISTAR_API anistar_status anistar_surface_from_image_fit(anistar_context *ctx,
                                                          const double *voxels,
                                                          const size_t dims[3],
                                                          const double spacing[3],
                                                          const double origin[3], double iso,
                                                          int inside, int fit,
                                                          anistar_surface **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_image: NULL out");
    *out = NULL;
    if (!voxels || !dims)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_surface_from_image: NULL voxels or dims");
    return as_image_surface_from_array_fit(ctx, voxels, dims, spacing, origin, iso, inside, fit,
                                           out);
}

ANISTAR_API anistar_status anistar_image_file_otsu(anistar_context *ctx, const char *path,
                                                   double *iso) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!path || !iso) return as_fail(ctx, ANISTAR_EINVAL, "anistar_image_file_otsu: NULL argument");
    as_image *img = NULL;
    anistar_status s = as_image_read(ctx, path, &img);
    if (s != ANISTAR_OK) return s;
    int r = as_image_otsu(img, iso);
    as_image_free(ctx, img);
    if (r)
        return as_fail(ctx, ANISTAR_ENOSURFACE,
                       "%s: every voxel has the same value (or none is finite): no isovalue "
                       "splits it",
                       path);
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_image_otsu(anistar_context *ctx, const double *voxels,
                                              const size_t dims[3], double *iso) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!voxels || !dims || !iso)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_image_otsu: NULL argument");
    size_t n;
    if (!dims[0] || !dims[1] || !dims[2])
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_image_otsu: a zero dimension");
    if (as_mul_size(dims[0], dims[1], &n) || as_mul_size(n, dims[2], &n))
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_image_otsu: the voxel count overflows");
    double lo = INFINITY, hi = -INFINITY;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(voxels[i])) continue;
        if (voxels[i] < lo) lo = voxels[i];
        if (voxels[i] > hi) hi = voxels[i];
    }
    as_otsu_hist h;
    as_otsu_init(&h, lo, hi);
    as_otsu_add(&h, voxels, n);
    if (!(lo < hi) || as_otsu_pick(&h, iso))
        return as_fail(ctx, ANISTAR_ENOSURFACE,
                       "anistar_image_otsu: every voxel has the same value (or none is finite): "
                       "no isovalue splits it");
    return ANISTAR_OK;
}

ANISTAR_API void anistar_surface_free(anistar_surface *s) { as_surface_free(s); }

ANISTAR_API anistar_status anistar_surface_bound(const anistar_surface *s, double center[3],
                                                 double *radius) {
    if (!s) return ANISTAR_EINVAL;
    if (!center || !radius)
        return as_fail(s->ctx, ANISTAR_EINVAL, "anistar_surface_bound: NULL argument");
    memcpy(center, s->center, 3 * sizeof(double));
    *radius = s->radius;
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_surface_eval(const anistar_surface *s, const double p[3],
                                                double *f, double g[3], double h[6]) {
    anistar_status st = as_api_query(s, p, f, "anistar_surface_eval");
    if (st) return st;
    if (as_surface_is_mesh(s)) {
        if (h)
            return as_fail(s->ctx, ANISTAR_EINVAL,
                           "anistar_surface_eval: a triangle-mesh surface has no Hessian (its "
                           "f is the signed distance)");
        return as_mesh_surface_signed_distance(s->ctx, s, p, f, g);
    }
    return as_surface_eval(s->ctx, s, p, h ? 2 : (g ? 1 : 0), f, g, h);
}

ANISTAR_API anistar_status anistar_surface_side(const anistar_surface *s, const double p[3],
                                                int *side) {
    anistar_status st = as_api_query(s, p, side, "anistar_surface_side");
    if (st) return st;
    return as_surface_side(s->ctx, s, p, side);
}

ANISTAR_API anistar_status anistar_surface_crossing(const anistar_surface *s, const double a[3],
                                                    const double b[3], const double ref[3],
                                                    int *found, double x[3]) {
    anistar_status st = as_api_query(s, a, found, "anistar_surface_crossing");
    if (st) return st;
    if (!b || !ref || !x)
        return as_fail(s->ctx, ANISTAR_EINVAL, "anistar_surface_crossing: NULL argument");
    if (!as_api_finite3(b) || !as_api_finite3(ref))
        return as_fail(s->ctx, ANISTAR_EINVAL, "anistar_surface_crossing: a point is not finite");
    return as_surface_crossing(s->ctx, s, a, b, ref, found, x);
}

ANISTAR_API anistar_status anistar_surface_project(const anistar_surface *s, const double p[3],
                                                   double q[3]) {
    anistar_status st = as_api_query(s, p, q, "anistar_surface_project");
    if (st) return st;
    return as_surface_project(s->ctx, s, p, q);
}

ANISTAR_API anistar_status anistar_surface_normal(const anistar_surface *s, const double p[3],
                                                  double n[3]) {
    anistar_status st = as_api_query(s, p, n, "anistar_surface_normal");
    if (st) return st;
    return as_surface_normal(s->ctx, s, p, n);
}

ANISTAR_API anistar_status anistar_surface_curvature(const anistar_surface *s,
                                                     const double p[3], double k[2],
                                                     double dir1[3], double dir2[3]) {
    anistar_status st = as_api_query(s, p, k, "anistar_surface_curvature");
    if (st) return st;
    as_surface_frame fr;
    st = as_surface_frame_at(s->ctx, s, p, &fr);
    if (st) return st;
    if (fr.singular)
        return as_fail(s->ctx, ANISTAR_EINVAL,
                       "anistar_surface_curvature: grad f vanishes at (%.17g, %.17g, %.17g)",
                       p[0], p[1], p[2]);
    k[0] = fr.k[0];
    k[1] = fr.k[1];
    if (dir1) memcpy(dir1, fr.d, 3 * sizeof(double));
    if (dir2) memcpy(dir2, fr.d + 3, 3 * sizeof(double));
    return ANISTAR_OK;
}

ANISTAR_API anistar_status anistar_metric_from_spec(anistar_context *ctx,
                                                    const anistar_surface *s, const char *spec,
                                                    anistar_metric **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_from_spec: NULL out");
    *out = NULL;
    if (!s || !spec)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_from_spec: NULL surface or spec");
    return as_field_from_spec(ctx, s, spec, out);
}

ANISTAR_API anistar_status anistar_metric_spec_check(anistar_context *ctx, const char *spec) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!spec) return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_spec_check: NULL spec");
    as_field_spec sp;
    anistar_status st = as_field_spec_parse(ctx, spec, &sp);
    if (!st) as_field_spec_clear(ctx, &sp);
    return st;
}

ANISTAR_API anistar_status anistar_metric_uniform(anistar_context *ctx, const anistar_surface *s,
                                                  const double m[6], anistar_metric **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_uniform: NULL out");
    *out = NULL;
    if (!m) return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_uniform: NULL tensor");
    return as_field_uniform(ctx, s, m, out);
}

ANISTAR_API anistar_status anistar_metric_from_callback(anistar_context *ctx,
                                                        const anistar_surface *s,
                                                        anistar_metric_fn fn, void *user,
                                                        anistar_metric **out) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!out) return as_fail(ctx, ANISTAR_EINVAL, "anistar_metric_from_callback: NULL out");
    *out = NULL;
    if (!s || !fn)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "anistar_metric_from_callback: NULL surface or callback");
    return as_field_custom(ctx, s, fn, user, out);
}

ANISTAR_API anistar_status anistar_metric_eval(const anistar_metric *m, const double p[3],
                                               double t[6]) {
    if (!m) return ANISTAR_EINVAL;
    if (!p || !t) return as_fail(m->ctx, ANISTAR_EINVAL, "anistar_metric_eval: NULL argument");
    return as_field_eval(m->ctx, m, p, t);
}

ANISTAR_API anistar_status anistar_metric_set_gradation(anistar_metric *m, double grad) {
    if (!m) return ANISTAR_EINVAL;
    return as_field_set_gradation(m->ctx, m, grad);
}

ANISTAR_API void anistar_metric_free(anistar_metric *m) { as_field_free(m); }

/* ==== END SURFACES AND METRIC FIELDS ==== */

/* ==================================================================================== */
/* What a file holds                                                                     */
/* ==================================================================================== */

#include "io/info.h"

ANISTAR_API anistar_status anistar_mesh_file_info(anistar_context *ctx, const char *path,
                                                  anistar_mesh_info *info) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!path || !info) return as_fail(ctx, ANISTAR_EINVAL, "anistar_mesh_file_info: NULL argument");
    memset(info, 0, sizeof *info);
    as_trimesh m;
    as_trimesh_init(&m);
    anistar_status s = as_mesh_read(ctx, path, &m);
    if (s == ANISTAR_OK) {
        s = as_trimesh_info(ctx, &m, info);
        if (s != ANISTAR_OK) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s", anistar_last_error(ctx));
            as_fail(ctx, s, "%s: %s", path, msg);
        }
    }
    as_trimesh_free(ctx, &m);
    return s;
}

ANISTAR_API anistar_status anistar_image_file_info(anistar_context *ctx, const char *path,
                                                   double iso, int inside,
                                                   anistar_image_info *info) {
    if (!ctx) return ANISTAR_EINVAL;
    if (!path || !info)
        return as_fail(ctx, ANISTAR_EINVAL, "anistar_image_file_info: NULL argument");
    memset(info, 0, sizeof *info);
    as_image *img = NULL;
    anistar_status s = as_image_read(ctx, path, &img);
    if (s != ANISTAR_OK) return s;
    s = as_image_info(ctx, img, iso, inside, info);
    as_image_free(ctx, img);
    return s;
}

_Static_assert(ANISTAR_FIT_AUTO == AS_IMAGE_FIT_AUTO &&
                   ANISTAR_FIT_INTERPOLATE == AS_IMAGE_FIT_INTERPOLATE &&
                   ANISTAR_FIT_SMOOTH == AS_IMAGE_FIT_SMOOTH,
               "the public fits are the image surface's");
