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
/* ==== END SURFACES AND METRIC FIELDS ==== */
