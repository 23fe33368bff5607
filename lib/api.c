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

/* ---- status ----------------------------------------------------------------------- */

ANISTAR_API const char *anistar_status_string(anistar_status st) {
    switch (st) {
#define AS_STATUS_MSG_(name, value, msg) \
    case ANISTAR_##name:                 \
        return msg;
        ANISTAR_STATUS_TABLE(AS_STATUS_MSG_)
#undef AS_STATUS_MSG_
    default:
        return "unknown status";
    }
}

ANISTAR_API const char *anistar_status_name(anistar_status st) {
    switch (st) {
#define AS_STATUS_NAME_(name, value, msg) \
    case ANISTAR_##name:                  \
        return #name;
        ANISTAR_STATUS_TABLE(AS_STATUS_NAME_)
#undef AS_STATUS_NAME_
    default:
        return "UNKNOWN";
    }
}

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

/* ==== SURFACES AND METRIC FIELDS (issue 4) ==== */

#include "surface/field.h"
#include "surface/surface.h"

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

ANISTAR_API void anistar_metric_free(anistar_metric *m) { as_field_free(m); }

/* ==== END SURFACES AND METRIC FIELDS ==== */
