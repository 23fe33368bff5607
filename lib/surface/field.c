/*
 * field.c — metric fields on a surface (DESIGN.md 4.7) and the SPEC parser of the
 * command line's --metric (DESIGN.md 3). See field.h for the conventions.
 */
#include "surface/field.h"

#include "geom/linalg.h"
#include "geom/kdtree.h"
#include "geom/metric.h"
#include "io/meshio.h"

#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- small helpers -------------------------------------------------------------- */

static inline double v3_dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline double v3_norm(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline void v3_cross(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline void sym_mul(const double h[6], const double v[3], double y[3]) {
    y[0] = h[0] * v[0] + h[1] * v[1] + h[2] * v[2];
    y[1] = h[1] * v[0] + h[3] * v[1] + h[4] * v[2];
    y[2] = h[2] * v[0] + h[4] * v[1] + h[5] * v[2];
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

/* Eigen-decomposition of the symmetric 2x2 [[a, b], [b, c]]: w1 >= w2, (cos, sin) of the
 * eigenvector of w1. */
static void eig2(double a, double b, double c, double *w1, double *w2, double *cs,
                 double *sn) {
    double mean = 0.5 * (a + c), r = hypot(0.5 * (a - c), b);
    double th = 0.5 * atan2(2 * b, a - c);
    *w1 = mean + r;
    *w2 = mean - r;
    *cs = cos(th);
    *sn = sin(th);
}

static anistar_status fail_at(anistar_context *ctx, const char *what, const double p[3]) {
    return as_fail(ctx, ANISTAR_EINVAL, "metric: %s at (%.17g, %.17g, %.17g)", what, p[0], p[1],
                   p[2]);
}

/* The same, naming the offending tensor too; note (may be "") follows the point. */
static anistar_status fail_tensor_at(anistar_context *ctx, const char *what, const double t[6],
                                     const double p[3], const char *note) {
    return as_fail(ctx, ANISTAR_EINVAL,
                   "metric: %s (%.17g %.17g %.17g %.17g %.17g %.17g) at (%.17g, %.17g, %.17g)%s",
                   what, t[0], t[1], t[2], t[3], t[4], t[5], p[0], p[1], p[2], note);
}

static int finite6(const double t[6]) {
    for (int i = 0; i < 6; i++)
        if (!isfinite(t[i])) return 0;
    return 1;
}

void as_field_tensor(const double u[9], const double e[3], double m[6]) {
    double emax = fmax(e[0], fmax(e[1], e[2])), lo = emax / AS_FIELD_MAX_ANISOTROPY;
    double w[3];
    for (int k = 0; k < 3; k++) {
        double ek = e[k] < lo ? lo : e[k];
        w[k] = ek * ek;
    }
    static const int ij[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int t = 0; t < 6; t++) {
        int i = ij[t][0], j = ij[t][1];
        m[t] = w[0] * u[i] * u[j] + w[1] * u[3 + i] * u[3 + j] + w[2] * u[6 + i] * u[6 + j];
    }
}

/*
 * as_field_check_tensor — validate m, then clamp its anisotropy in place.
 * design:
 *   1. validity is the mesher's own test, as_metric_frame_init (finite entries, positive
 *      definite, F's eigenvalue ratio <= 1e12): a tensor the mesher would refuse is
 *      refused here, before the clamp could make it acceptable;
 *   2. a valid tensor whose F has an eigenvalue ratio above AS_FIELD_MAX_ANISOTROPY is
 *      rebuilt from the frame's eigenpairs with its smaller eigenvalues raised
 *      (as_field_tensor); otherwise m is left bit for bit.
 */
int as_field_check_tensor(double m[6]) {
    double e[3], u[9];
    if (as_metric_frame_eigen(m, e, u)) return -1;
    if (e[2] <= AS_FIELD_MAX_ANISOTROPY * e[0]) return 0;
    as_field_tensor(u, e, m);
    return 0;
}

/* 1 if the mesher accepts m as it is (as_metric_frame_init), 0 otherwise. */
static int fl_frame_ok(const double m[6]) {
    double e[3], u[9];
    return as_metric_frame_eigen(m, e, u) == 0;
}

/* ---- SPEC parsing --------------------------------------------------------------- */

enum {
    OPT_EPS = 1,
    OPT_EN = 2,
    OPT_POWER = 4,
    OPT_PHI = 8,
    OPT_LAMBDA = 16,
    OPT_H = 32,
    OPT_DEGREE = 64, /* triangle meshes */
    OPT_K = 128,
    OPT_RB = 256,
    OPT_GRAD = 512
};

typedef struct fl_name {
    const char *name;
    as_field_kind kind;
    int arg;  /* 1: NAME:ARG required, 0: no ARG */
    int opts; /* allowed options */
    const char *optlist;
    const char *meshopts; /* options for triangle-mesh surfaces only, or "" */
} fl_name;

static const fl_name fl_names[] = {
    {"euclidean", AS_FIELD_UNIFORM, 0, 0, "none", ""},
    {"uniform", AS_FIELD_UNIFORM, 0, OPT_H, "h", ""},
    {"curvature", AS_FIELD_CURVATURE, 0,
     OPT_EPS | OPT_EN | OPT_POWER | OPT_DEGREE | OPT_K | OPT_RB | OPT_GRAD, "eps, en, power, grad",
     "degree, k, rb"},
    {"shock", AS_FIELD_GRADIENT, 0, OPT_LAMBDA | OPT_PHI | OPT_EN | OPT_GRAD,
     "lambda, phi, en, grad", ""},
    {"gradient", AS_FIELD_GRADIENT, 1, OPT_PHI | OPT_EN | OPT_GRAD, "phi, en, grad", ""},
    {"hessian", AS_FIELD_HESSIAN, 1, OPT_EPS | OPT_EN | OPT_POWER | OPT_GRAD,
     "eps, en, power, grad", ""},
    {"sol", AS_FIELD_SOL, 1, OPT_RB | OPT_GRAD, "rb, grad", ""},
};
#define FL_NAMES (sizeof fl_names / sizeof fl_names[0])

static const char *const fl_known =
    "euclidean, uniform, curvature, shock, gradient:EXPR, hessian:EXPR, sol:FILE";

/* Trim spaces: [*b, *e) */
static void trim(const char **b, const char **e) {
    while (*b < *e && isspace((unsigned char)**b)) (*b)++;
    while (*e > *b && isspace((unsigned char)(*e)[-1])) (*e)--;
}

static int clip_len(size_t n) { return (int)(n > 80 ? 80 : n); }

void as_field_spec_clear(anistar_context *ctx, as_field_spec *sp) {
    if (!sp) return;
    as_expr_free(ctx, sp->expr);
    as_free(ctx, sp->path, sp->path_size);
    memset(sp, 0, sizeof *sp);
}

/* Compile an expression, prefixing the compiler's message with the metric's name. */
static anistar_status compile_expr(anistar_context *ctx, const char *what, const char *src,
                                   as_expr **out) {
    anistar_status st = as_expr_compile(ctx, src, out);
    if (st) {
        char msg[AS_ERRMSG_SIZE];
        snprintf(msg, sizeof msg, "%s", ctx->last_error);
        return as_fail(ctx, st, "metric '%s': %s", what, msg);
    }
    return ANISTAR_OK;
}

static anistar_status parse_option(anistar_context *ctx, const fl_name *nm, const char *b,
                                   const char *e, as_field_spec *sp) {
    trim(&b, &e);
    const char *eq = memchr(b, '=', (size_t)(e - b));
    if (!eq)
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': expected OPTION=VALUE, got '%.*s'",
                       nm->name, clip_len((size_t)(e - b)), b);
    const char *kb = b, *ke = eq, *vb = eq + 1, *ve = e;
    trim(&kb, &ke);
    trim(&vb, &ve);
    static const struct {
        const char *key;
        int bit;
    } keys[] = {{"eps", OPT_EPS},       {"en", OPT_EN},         {"power", OPT_POWER},
                {"phi", OPT_PHI},       {"lambda", OPT_LAMBDA}, {"h", OPT_H},
                {"degree", OPT_DEGREE}, {"k", OPT_K},           {"rb", OPT_RB},
                {"grad", OPT_GRAD}};
    int bit = 0;
    for (size_t i = 0; i < sizeof keys / sizeof keys[0]; i++)
        if (strlen(keys[i].key) == (size_t)(ke - kb) && !strncmp(keys[i].key, kb, (size_t)(ke - kb)))
            bit = keys[i].bit;
    if (!(bit & nm->opts))
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': unknown option '%.*s' (options: %s)%s%s",
                       nm->name, clip_len((size_t)(ke - kb)), kb, nm->optlist,
                       nm->meshopts[0] ? ", and on triangle-mesh surfaces " : "", nm->meshopts);
    char buf[64];
    size_t vl = (size_t)(ve - vb);
    double v = 0;
    int ok = vl > 0 && vl < sizeof buf;
    if (ok) {
        memcpy(buf, vb, vl);
        buf[vl] = '\0';
        char *end;
        errno = 0;
        v = strtod(buf, &end);
        ok = end == buf + vl && errno != ERANGE && isfinite(v);
    }
    if (!ok)
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': option %.*s: '%.*s' is not a finite "
                       "number", nm->name, clip_len((size_t)(ke - kb)), kb, clip_len(vl), vb);
    double *dst;
    int *has;
    int positive = 1;
    switch (bit) {
    case OPT_EPS: dst = &sp->eps; has = &sp->has_eps; break;
    case OPT_EN: dst = &sp->en; has = &sp->has_en; break;
    case OPT_POWER: dst = &sp->power; has = &sp->has_power; break;
    case OPT_PHI: dst = &sp->phi; has = &sp->has_phi; positive = 0; break;
    case OPT_LAMBDA: dst = &sp->lambda; has = &sp->has_lambda; break;
    case OPT_DEGREE: dst = &sp->degree; has = &sp->has_degree; break;
    case OPT_K: dst = &sp->k; has = &sp->has_k; break;
    case OPT_RB: dst = &sp->rb; has = &sp->has_rb; break;
    case OPT_GRAD: dst = &sp->grad; has = &sp->has_grad; positive = 0; break;
    default: dst = &sp->h; has = &sp->has_h; break;
    }
    if (*has)
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': option %.*s given twice", nm->name,
                       clip_len((size_t)(ke - kb)), kb);
    if (positive ? !(v > 0) : !(v >= 0))
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': option %.*s must be %s, got %g",
                       nm->name, clip_len((size_t)(ke - kb)), kb, positive ? "> 0" : ">= 0", v);
    if (bit == OPT_GRAD && !(v > 1 || v == 0))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "metric '%s': option grad must be > 1 (or 0: none), got %g", nm->name, v);
    if (bit == OPT_DEGREE && !(v == 2 || v == 3 || v == 4))
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s': option degree must be 2, 3 or 4, got %g",
                       nm->name, v);
    if (bit == OPT_K && !(v == floor(v) && v <= AS_JET_MAX_POINTS))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "metric '%s': option k must be an integer in [1, %d], got %g", nm->name,
                       AS_JET_MAX_POINTS, v);
    *has = 1;
    *dst = v;
    return ANISTAR_OK;
}

anistar_status as_field_spec_parse(anistar_context *ctx, const char *spec, as_field_spec *out) {
    memset(out, 0, sizeof *out);
    if (!spec) return as_fail(ctx, ANISTAR_EINVAL, "metric: NULL spec");
    /* Items split at commas of parenthesis depth 0. */
    int depth = 0;
    for (const char *c = spec; *c; c++) {
        if (*c == '(') depth++;
        if (*c == ')' && --depth < 0) break;
    }
    if (depth != 0)
        return as_fail(ctx, ANISTAR_EFORMAT, "metric '%s': unbalanced parentheses", spec);
    const char *end = spec;
    for (depth = 0; *end && !(depth == 0 && *end == ','); end++) {
        if (*end == '(') depth++;
        if (*end == ')') depth--;
    }
    const char *hb = spec, *he = end;
    trim(&hb, &he);
    const char *colon = memchr(hb, ':', (size_t)(he - hb));
    const char *nb = hb, *ne = colon ? colon : he;
    trim(&nb, &ne);
    if (nb == ne)
        return as_fail(ctx, ANISTAR_EINVAL, "metric: empty name (expected %s)", fl_known);
    const fl_name *nm = NULL;
    for (size_t i = 0; i < FL_NAMES; i++)
        if (strlen(fl_names[i].name) == (size_t)(ne - nb) &&
            !strncmp(fl_names[i].name, nb, (size_t)(ne - nb)))
            nm = &fl_names[i];
    if (!nm)
        return as_fail(ctx, ANISTAR_EINVAL, "unknown metric '%.*s' (expected %s)",
                       clip_len((size_t)(ne - nb)), nb, fl_known);
    out->kind = nm->kind;
    out->name = nm->name;
    const char *ab = colon ? colon + 1 : he, *ae = he;
    trim(&ab, &ae);
    if (nm->arg && ab == ae) {
        as_fail(ctx, ANISTAR_EINVAL, "metric '%s' needs an argument: %s:%s", nm->name, nm->name,
                nm->kind == AS_FIELD_SOL ? "FILE" : "EXPR");
        return ANISTAR_EINVAL;
    }
    if (!nm->arg && colon)
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s' takes no ':' argument", nm->name);
    anistar_status st = ANISTAR_OK;
    for (const char *ob = end; *ob == ',' && !st;) {
        const char *oe = ob + 1;
        for (depth = 0; *oe && !(depth == 0 && *oe == ','); oe++) {
            if (*oe == '(') depth++;
            if (*oe == ')') depth--;
        }
        st = parse_option(ctx, nm, ob + 1, oe, out);
        ob = oe;
    }
    if (st) {
        as_field_spec_clear(ctx, out);
        return st;
    }
    size_t alen = (size_t)(ae - ab);
    if (nm->kind == AS_FIELD_GRADIENT || nm->kind == AS_FIELD_HESSIAN) {
        char small[256], *src = small;
        size_t srcsize = 0;
        if (!nm->arg) { /* shock: the paper's field E with lambda */
            double lambda = out->has_lambda ? out->lambda : 0.6;
            snprintf(small, sizeof small, "L=%.17g; tanh((2*x-sin(5*y))/L)+x^3+x*y^2", lambda);
        } else if (alen < sizeof small) {
            memcpy(small, ab, alen);
            small[alen] = '\0';
        } else {
            srcsize = alen + 1;
            src = as_alloc(ctx, srcsize);
            if (!src) return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
            memcpy(src, ab, alen);
            src[alen] = '\0';
        }
        st = compile_expr(ctx, nm->name, src, &out->expr);
        if (srcsize) as_free(ctx, src, srcsize);
    } else if (nm->kind == AS_FIELD_SOL) {
        out->path_size = alen + 1;
        out->path = as_alloc(ctx, out->path_size);
        if (!out->path) {
            out->path_size = 0;
            st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
        } else {
            memcpy(out->path, ab, alen);
            out->path[alen] = '\0';
        }
    }
    if (st) as_field_spec_clear(ctx, out);
    return st;
}

/* ---- local evaluation ----------------------------------------------------------- */

static inline int fl_usable(double e) { return isfinite(e) && e <= AS_FIELD_MAX_EIGENVALUE; }

/* A gradient or hessian eigenvalue of F that is not finite or above the limit. */
static anistar_status fl_too_large(anistar_context *ctx, const as_field *fl, double e,
                                   const double p[3]) {
    return as_fail(ctx, ANISTAR_EINVAL,
                   "metric: the %s field's eigenvalue %g is not finite or exceeds %g at "
                   "(%.17g, %.17g, %.17g)",
                   fl->kind == AS_FIELD_HESSIAN ? "hessian" : "gradient", e,
                   AS_FIELD_MAX_EIGENVALUE, p[0], p[1], p[2]);
}

/* The tangential part of a field at p. */
typedef struct fl_local {
    int singular;      /* grad f vanishes: no normal */
    double u[9];       /* u1, u2 (tangent eigenvectors), n */
    double e1, e2;     /* tangential eigenvalues of F */
    double raw;        /* largest raw tangential quantity: |k|, |g|, w */
    double eiso;       /* singular points: the largest eigenvalue computable without n */
} fl_local;

/*
 * fl_local_eval — the tangential eigenpairs of a curvature, gradient or hessian field at p.
 * Returns EINVAL (naming p) when E, its derivatives or the curvature of S are not finite,
 * and, for gradient and hessian, when an eigenvalue of F is not finite or exceeds
 * AS_FIELD_MAX_EIGENVALUE: E's derivatives do not depend on f, so such a value is E's
 * own and is never replaced. Curvature eigenvalues that large (|k| > 1e150: next to a
 * singular point of f, where |grad f| -> 0) are left to as_field_eval's e_n^2 I.
 */
static anistar_status fl_local_eval(anistar_context *ctx, const as_field *fl, const double p[3],
                                    fl_local *L) {
    memset(L, 0, sizeof *L);
    const as_surface *s = fl->surf;
    anistar_status st;
    if (fl->kind == AS_FIELD_CURVATURE) {
        as_surface_frame fr;
        st = as_surface_frame_at(ctx, s, p, &fr);
        if (st) return st;
        if (fr.singular) {
            L->singular = 1;
            return ANISTAR_OK;
        }
        if (!isfinite(fr.k[0]) || !isfinite(fr.k[1]))
            return fail_at(ctx, "the curvature of S is not finite", p);
        memcpy(L->u, fr.d, 6 * sizeof(double));
        memcpy(L->u + 6, fr.n, 3 * sizeof(double));
        L->e1 = pow(fmax(fl->eps, fabs(fr.k[0])), fl->power);
        L->e2 = pow(fmax(fl->eps, fabs(fr.k[1])), fl->power);
        L->raw = fmax(fabs(fr.k[0]), fabs(fr.k[1]));
        return ANISTAR_OK;
    }
    /* gradient and hessian: the normal of S, then E's derivatives */
    double *n = L->u + 6, *u1 = L->u, *u2 = L->u + 3;
    st = as_surface_normal_at(ctx, s, p, n, &L->singular);
    if (st) return st;
    if (fl->kind == AS_FIELD_GRADIENT) {
        double gE[3];
        double E = as_expr_value_grad(fl->expr, p, gE);
        if (!isfinite(E) || !isfinite(gE[0]) || !isfinite(gE[1]) || !isfinite(gE[2]))
            return fail_at(ctx, "the scalar field or its gradient is not finite", p);
        if (L->singular) {
            L->eiso = 1 + fl->phi * v3_norm(gE);
            return fl_usable(L->eiso) ? ANISTAR_OK : fl_too_large(ctx, fl, L->eiso, p);
        }
        double gnE = v3_dot(gE, n), gt[3];
        for (int i = 0; i < 3; i++) gt[i] = gE[i] - gnE * n[i];
        double gtn = v3_norm(gt);
        L->raw = gtn;
        if (gtn > 0) {
            for (int i = 0; i < 3; i++) u1[i] = gt[i] / gtn;
            v3_cross(n, u1, u2);
        } else {
            tangent_basis(n, u1, u2);
        }
        L->e1 = 1 + fl->phi * gtn;
        L->e2 = 1;
        return fl_usable(L->e1) ? ANISTAR_OK : fl_too_large(ctx, fl, L->e1, p);
    }
    /* hessian */
    double gE[3], hE[6];
    double E = as_expr_value_grad_hess(fl->expr, p, gE, hE);
    int fin = isfinite(E);
    for (int i = 0; i < 6; i++) fin = fin && isfinite(hE[i]);
    if (!fin) return fail_at(ctx, "the scalar field or its Hessian is not finite", p);
    double w[3], v[9], habs[6];
    if (as_sym3_eigen(hE, w, v)) return fail_at(ctx, "the Hessian is not finite", p);
    for (int k = 0; k < 3; k++) w[k] = fabs(w[k]);
    as_sym3_from_eigen(w, v, habs);
    if (L->singular) {
        double wm = fmax(w[0], fmax(w[1], w[2]));
        L->eiso = pow(fmax(fl->eps, wm), fl->power);
        return fl_usable(L->eiso) ? ANISTAR_OK : fl_too_large(ctx, fl, L->eiso, p);
    }
    double t1[3], t2[3], h1[3], h2[3];
    tangent_basis(n, t1, t2);
    sym_mul(habs, t1, h1);
    sym_mul(habs, t2, h2);
    double w1, w2, cs, sn;
    eig2(v3_dot(t1, h1), 0.5 * (v3_dot(t1, h2) + v3_dot(t2, h1)), v3_dot(t2, h2), &w1, &w2, &cs,
         &sn);
    if (w2 < 0) w2 = 0; /* T^T |H| T is positive semi-definite: only rounding goes below */
    for (int i = 0; i < 3; i++) u1[i] = cs * t1[i] + sn * t2[i];
    v3_cross(n, u1, u2);
    L->raw = w1;
    L->e1 = pow(fmax(fl->eps, w1), fl->power);
    L->e2 = pow(fmax(fl->eps, w2), fl->power);
    if (!fl_usable(L->e1)) return fl_too_large(ctx, fl, L->e1, p);
    if (!fl_usable(L->e2)) return fl_too_large(ctx, fl, L->e2, p);
    return ANISTAR_OK;
}

static void iso(double e, double m[6]) {
    m[0] = m[3] = m[5] = e * e;
    m[1] = m[2] = m[4] = 0;
}

static int fl_intersect_tol(const double a[6], const double b[6], double out[6], double tol);

/* The graded field at p (see fl_grade_sample): m, the tensor of the field at p, becomes
 * its intersection with the blend of the sample's graded tensors. */
static anistar_status fl_graded(anistar_context *ctx, const as_field *fl, const double p[3],
                                double m[6]) {
    double b[6], o[6];
    anistar_status st = as_blend_eval(ctx, fl->g.blend, p, b);
    if (st) return st;
    if (fl_intersect_tol(m, b, o, 0) < 0) /* m itself is not a metric: as_field_eval's error */
        return fail_tensor_at(ctx, "the tensor is not finite and positive definite", m, p,
                              " (eps or e_n too small or too large)");
    memcpy(m, o, sizeof o);
    return ANISTAR_OK;
}

/*
 * as_field_eval — the tensor of fl at p (field.h).
 * design:
 *   1. blended fields (triangle meshes): as_blend_eval of validated vertex tensors, then
 *      as_field_check_tensor;
 *   2. custom: the callback's tensor must pass as_field_check_tensor (the mesher's test,
 *      before any clamp); otherwise EINVAL naming p and the six values — never repaired;
 *   3. curvature, gradient, hessian: fl_local_eval (which refuses non-finite values and,
 *      for gradient and hessian, eigenvalues above AS_FIELD_MAX_EIGENVALUE); the
 *      documented special points: a singular point of f gives the isotropic e^2 I, a
 *      curvature eigenvalue above the limit (next to one) gives e_n^2 I; the result must
 *      pass as_metric_frame_init (it fails only by under- or overflow of tiny or huge
 *      eps, e_n), else EINVAL naming p and the tensor.
 */
anistar_status as_field_eval(anistar_context *ctx, const as_field *fl, const double p[3],
                             double m[6]) {
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "metric: point is not finite");
    if (fl->blend) { /* curvature and sol on triangle meshes, curvature on images */
        anistar_status st = as_blend_eval(ctx, fl->blend, p, m);
        if (st) return st;
        if (as_field_check_tensor(m)) /* m is left as it was on failure */
            return fail_tensor_at(ctx, "the blended tensor is not finite and positive definite",
                                  m, p, "");
        return ANISTAR_OK;
    }
    switch (fl->kind) {
    case AS_FIELD_UNIFORM:
        memcpy(m, fl->m, 6 * sizeof(double));
        return ANISTAR_OK;
    case AS_FIELD_CUSTOM: {
        double n[3];
        int singular;
        anistar_status st = as_surface_normal_at(ctx, fl->surf, p, n, &singular);
        if (st) return st;
        double t[6] = {0, 0, 0, 0, 0, 0};
        if (fl->fn(p, n, t, fl->user)) return fail_at(ctx, "the metric callback failed", p);
        if (!finite6(t))
            return fail_tensor_at(ctx, "the metric callback returned a non-finite tensor", t, p,
                                  "");
        if (as_field_check_tensor(t)) /* t is left as it was on failure */
            return fail_tensor_at(ctx,
                                  "the metric callback returned a tensor that is not "
                                  "positive definite",
                                  t, p, " (symmetric positive definite with a condition number "
                                        "<= 1e24 needed)");
        memcpy(m, t, sizeof t);
        return fl->g.blend ? fl_graded(ctx, fl, p, m) : ANISTAR_OK;
    }
    case AS_FIELD_CURVATURE:
    case AS_FIELD_GRADIENT:
    case AS_FIELD_HESSIAN: {
        fl_local L;
        anistar_status st = fl_local_eval(ctx, fl, p, &L);
        if (st) return st;
        if (L.singular) {
            iso(fmax(fl->en, L.eiso), m);
        } else if (!fl_usable(L.e1) || !fl_usable(L.e2)) {
            iso(fl->en, m); /* curvature only (fl_local_eval): next to a singular point */
        } else {
            double e[3] = {L.e1, L.e2, fl->en};
            as_field_tensor(L.u, e, m);
        }
        if (fl->g.blend && (st = fl_graded(ctx, fl, p, m))) return st;
        if (!fl_frame_ok(m))
            return fail_tensor_at(ctx, "the tensor is not finite and positive definite", m, p,
                                  " (eps or e_n too small or too large)");
        return ANISTAR_OK;
    }
    default:
        return as_fail(ctx, ANISTAR_EINTERNAL, "metric: unknown field kind");
    }
}

/* ---- creation ------------------------------------------------------------------- */

static anistar_status fl_new(anistar_context *ctx, const as_surface *s, as_field_kind kind,
                             as_field **out) {
    *out = NULL;
    as_field *fl = as_alloc(ctx, sizeof *fl);
    if (!fl) return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
    memset(fl, 0, sizeof *fl);
    fl->ctx = ctx;
    fl->surf = s;
    fl->kind = kind;
    *out = fl;
    return ANISTAR_OK;
}

static void gsample_free(anistar_context *ctx, as_field_gsample *g) {
    as_blend_free(ctx, g->blend);
    as_kdtree_free(ctx, g->kd);
    as_free(ctx, g->xyz, g->n * 3 * sizeof(double));
    memset(g, 0, sizeof *g);
}

/* The neighbour lists kept for the gradation (fl->bnb), if any. */
static void fl_free_neighbours(as_field *fl) {
    as_free(fl->ctx, fl->bnb, fl->bn * (AS_FIELD_GRAD_K + 1) * sizeof *fl->bnb);
    as_free(fl->ctx, fl->bnbn, fl->bn * sizeof *fl->bnbn);
    fl->bnb = NULL;
    fl->bnbn = NULL;
}

void as_field_free(as_field *fl) {
    if (!fl) return;
    anistar_context *ctx = fl->ctx;
    as_expr_free(ctx, fl->expr);
    as_blend_free(ctx, fl->blend);
    as_kdtree_free(ctx, fl->bkd);
    fl_free_neighbours(fl);
    as_free(ctx, fl->bxyz, fl->bn * 3 * sizeof(double));
    as_free(ctx, fl->braw, fl->nraw * 6 * sizeof(double));
    gsample_free(ctx, &fl->g);
    as_free(ctx, fl, sizeof *fl);
}

anistar_status as_field_uniform(anistar_context *ctx, const as_surface *s, const double m[6],
                                as_field **out) {
    *out = NULL;
    double t[6];
    memcpy(t, m, sizeof t);
    if (as_field_check_tensor(t))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "uniform metric: tensor (%.17g %.17g %.17g %.17g %.17g %.17g) is not "
                       "finite and positive definite (with a condition number <= 1e24)",
                       m[0], m[1], m[2], m[3], m[4], m[5]);
    as_field *fl;
    anistar_status st = fl_new(ctx, s, AS_FIELD_UNIFORM, &fl);
    if (st) return st;
    memcpy(fl->m, t, sizeof t);
    *out = fl;
    return ANISTAR_OK;
}

anistar_status as_field_custom(anistar_context *ctx, const as_surface *s, as_field_fn fn,
                               void *user, as_field **out) {
    *out = NULL;
    if (!s || !fn) return as_fail(ctx, ANISTAR_EINVAL, "custom metric: NULL surface or callback");
    as_field *fl;
    anistar_status st = fl_new(ctx, s, AS_FIELD_CUSTOM, &fl);
    if (st) return st;
    fl->fn = fn;
    fl->user = user;
    *out = fl;
    return ANISTAR_OK;
}

/*
 * fl_defaults — defaults from the initial sample (paper 5.4): hessian's eps when need_eps,
 * then e_n when need_en. spec names the field in messages.
 * design:
 *   1. eps = 1e-3 x the largest tangential |H| eigenvalue w over the sample's regular
 *      points; when that is 0 (E's Hessian vanishes tangentially at every sample point,
 *      e.g. a linear E) there is no size to derive: EINVAL naming a sample point, never
 *      a made-up eps (the user may give eps=E for a uniform metric);
 *   2. e_n = the largest tangential eigenvalue of F over the sample's regular points
 *      (curvature eigenvalues above AS_FIELD_MAX_EIGENVALUE left out); when no point
 *      gives one (every sample point singular), EINVAL: give en=N.
 */
static anistar_status fl_defaults(anistar_context *ctx, as_field *fl, const char *spec,
                                  int need_eps, int need_en) {
    as_point_sample smp;
    /* a sample that fails is the surface's error (no surface inside the bounding sphere,
     * a sphere too small, f not finite): its status and message go through unchanged */
    anistar_status st = as_surface_sample(ctx, fl->surf, AS_FIELD_SAMPLE_POINTS, &smp);
    if (st) return st;
    int sl = clip_len(strlen(spec));
    if (need_eps) {
        double raw = 0;
        const double *regular = NULL; /* a regular sample point, for the message */
        int usable = 0;
        fl->eps = 1; /* any positive value: raw does not depend on it */
        for (size_t i = 0; i < smp.n && !st; i++) {
            fl_local L;
            st = fl_local_eval(ctx, fl, smp.points + 3 * i, &L);
            if (st || L.singular) continue;
            if (!regular) regular = smp.points + 3 * i;
            if (!fl_usable(L.raw)) continue;
            usable = 1;
            if (L.raw > raw) raw = L.raw;
        }
        if (!st && !(1e-3 * raw > 0)) {
            const double *q = regular ? regular : smp.points;
            if (regular && !usable)
                st = as_fail(ctx, ANISTAR_EINVAL,
                             "metric '%.*s': the Hessian of E exceeds %g on S (tangentially, at "
                             "every sample point; e.g. at (%.17g, %.17g, %.17g))",
                             sl, spec, AS_FIELD_MAX_EIGENVALUE, q[0], q[1], q[2]);
            else if (regular)
                st = as_fail(ctx, ANISTAR_EINVAL,
                             "metric '%.*s': the Hessian of E is 0 on S (tangentially, at every "
                             "sample point; e.g. at (%.17g, %.17g, %.17g)): no size to derive; "
                             "give eps=E for a uniform metric",
                             sl, spec, q[0], q[1], q[2]);
            else
                st = as_fail(ctx, ANISTAR_EINVAL,
                             "metric '%.*s': every sample point of S is a singular point of f "
                             "(e.g. at (%.17g, %.17g, %.17g)): no size to derive; give eps=E",
                             sl, spec, q[0], q[1], q[2]);
        }
        if (!st) fl->eps = 1e-3 * raw;
    }
    if (need_en && !st) {
        double en = 0;
        for (size_t i = 0; i < smp.n && !st; i++) {
            fl_local L;
            st = fl_local_eval(ctx, fl, smp.points + 3 * i, &L);
            if (st || L.singular || !fl_usable(L.e1) || !fl_usable(L.e2)) continue;
            en = fmax(en, fmax(L.e1, L.e2));
        }
        if (!st && !(en > 0))
            st = as_fail(ctx, ANISTAR_EINVAL,
                         "metric '%.*s': no sample point of S gives a tangential eigenvalue "
                         "(e.g. at (%.17g, %.17g, %.17g)): no default e_n; give en=N",
                         sl, spec, smp.points[0], smp.points[1], smp.points[2]);
        if (!st) fl->en = en;
    }
    as_surface_sample_free(ctx, &smp);
    return st;
}

/*
 * The per-vertex tensors of a curvature or sol field on a triangle-mesh surface, blended
 * (paper 5.2.3; see field.h for the conventions).
 * design:
 *   1. curvature: the surface's own degree-2 jets (AS_JET_K2) or new ones for other
 *      degree/k; e_i = max(eps, |k_i|)^power; e_n = option or max_v e_1(v) (paper 5.4);
 *      M(v) = U diag(e^2) U^T, U = [d0, d1, n]; a curvature that is not finite or an
 *      e_i above AS_FIELD_MAX_EIGENVALUE is EINVAL naming the vertex (a mesh has no
 *      singular point to excuse it), as is an M(v) the mesher would refuse;
 *      sol: the file's tensors, count checked against the input's vertices, mapped past
 *      dropped (unused) vertices, each validated by as_field_check_tensor (EFORMAT naming
 *      the vertex, and its position when it is used);
 *   2. r_B = option rb or the mean distance to the k nearest vertices (paper's default);
 *   3. as_blend_create over the surface's kd-tree of vertices.
 */
/* out = the intersection of the metrics a and b: the largest tensor whose unit ball lies in
 * both unit balls (simultaneous reduction: with F = a^(1/2), C = F^-1 b F^-1 = V diag(w)
 * V^T, out = F V diag(max(w, 1)) V^T F). Returns 1 if out differs from b by more than a
 * relative tol in some eigenvalue (then out is computed), 0 if not (out = b), -1 if a is
 * not a valid metric. fl_intersect: tol 1e-3 (the gradation's). */
static int fl_intersect_tol(const double a[6], const double b[6], double out[6], double tol) {
    as_metric_frame fa;
    if (as_metric_frame_init(&fa, a)) return -1;
    const double B[9] = {b[0], b[1], b[2], b[1], b[3], b[4], b[2], b[4], b[5]};
    double T[9], C[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            T[3 * i + j] = (B[3 * i] * fa.finv[j] + B[3 * i + 1] * fa.finv[3 + j]) +
                           B[3 * i + 2] * fa.finv[6 + j];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            C[3 * i + j] = (fa.finv[3 * i] * T[j] + fa.finv[3 * i + 1] * T[3 + j]) +
                           fa.finv[3 * i + 2] * T[6 + j];
    double c6[6] = {C[0], 0.5 * (C[1] + C[3]), 0.5 * (C[2] + C[6]), C[4], 0.5 * (C[5] + C[7]),
                    C[8]};
    double w[3], v[9];
    if (as_sym3_eigen(c6, w, v)) return -1;
    int changed = 0;
    for (int k = 0; k < 3; k++)
        if (w[k] < 1) {
            if (w[k] < 1 - tol) changed = 1;
            w[k] = 1;
        }
    if (!changed) {
        memcpy(out, b, 6 * sizeof(double));
        return 0;
    }
    double r6[6], R[9], Q[9];
    as_sym3_from_eigen(w, v, r6);
    const double Rr[9] = {r6[0], r6[1], r6[2], r6[1], r6[3], r6[4], r6[2], r6[4], r6[5]};
    memcpy(R, Rr, sizeof R);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            Q[3 * i + j] = (R[3 * i] * fa.f[j] + R[3 * i + 1] * fa.f[3 + j]) + R[3 * i + 2] * fa.f[6 + j];
    double O[9];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            O[3 * i + j] = (fa.f[3 * i] * Q[j] + fa.f[3 * i + 1] * Q[3 + j]) + fa.f[3 * i + 2] * Q[6 + j];
    out[0] = O[0];
    out[1] = 0.5 * (O[1] + O[3]);
    out[2] = 0.5 * (O[2] + O[6]);
    out[3] = O[4];
    out[4] = 0.5 * (O[5] + O[7]);
    out[5] = O[8];
    return 1;
}

static int fl_intersect(const double a[6], const double b[6], double out[6]) {
    return fl_intersect_tol(a, b, out, 1e-3);
}

/* u^T m u for the symmetric m (m11 m12 m13 m22 m23 m33). */
static inline double sym_quad(const double m[6], const double u[3]) {
    return m[0] * u[0] * u[0] + m[3] * u[1] * u[1] + m[5] * u[2] * u[2] +
           2 * (m[1] * u[0] * u[1] + m[2] * u[0] * u[2] + m[4] * u[1] * u[2]);
}

/* The frames of a keep-frame gradation: per tensor its eigenvalues w (3) and eigenvectors
 * v (9), computed when first needed (have) and kept: a raise changes only eigenvalues. */
typedef struct grade_frames {
    double *w, *v;
    uint8_t *have;
} grade_frames;

/* One directed edge of the gradation: eta^2 M_i intersected into M_j (*any set when M_j
 * changes); with the frames gf (keep_frame), M_j's eigenvalues raised instead, each to
 * eta^2 M_i's value along its eigenvector, in M_j's own frame (as_field_gradation_edges). */
static anistar_status grade_edge(anistar_context *ctx, double *tens, const double *xyz,
                                 int32_t i, int32_t j, double lb, grade_frames *gf, int *any) {
    const double *mi = tens + 6 * (size_t)i, *xi = xyz + 3 * (size_t)i, *xj = xyz + 3 * (size_t)j;
    double d[3] = {xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]};
    double eta = 1 / (1 + sqrt(fmax(sym_quad(mi, d), 0)) * lb), p[6], o[6];
    for (int q = 0; q < 6; q++) p[q] = eta * eta * mi[q];
    /* design: M_j - eta^2 M_i positive definite (its leading minors) means every
     * eigenvalue of the reduction exceeds 1: M_j stays, as fl_intersect would decide,
     * without its two eigendecompositions (most edges, once the field has settled) */
    const double *mj = tens + 6 * (size_t)j;
    double D[6];
    for (int q = 0; q < 6; q++) D[q] = mj[q] - p[q];
    double m2 = D[0] * D[3] - D[1] * D[1];
    if (D[0] > 0 && m2 > 0 &&
        D[0] * (D[3] * D[5] - D[4] * D[4]) - D[1] * (D[1] * D[5] - D[4] * D[2]) +
                D[2] * (D[1] * D[4] - D[3] * D[2]) > 0)
        return ANISTAR_OK;
    if (gf) {
        /* design: M_j's frame is taken once and kept (the raises change only eigenvalues),
         * so an edge costs no eigendecomposition: on the skull CT's lattice they were 15%
         * of the whole run (798,157 of them for 2,904 vertices) */
        double *wj = gf->w + 3 * (size_t)j, *v = gf->v + 9 * (size_t)j;
        if (!gf->have[j]) {
            if (as_sym3_eigen(mj, wj, v))
                return fail_tensor_at(ctx, "the graded tensor is not a metric", mj, xj, "");
            gf->have[j] = 1;
        }
        double w[3] = {wj[0], wj[1], wj[2]};
        int raised = 0;
        for (int k = 0; k < 3; k++) {
            double q = sym_quad(p, v + 3 * k);
            if (q > w[k] * (1 + 1e-3)) {
                w[k] = q;
                raised = 1;
            }
        }
        if (!raised) return ANISTAR_OK;
        as_sym3_from_eigen(w, v, o);
        if (as_field_check_tensor(o))
            return fail_tensor_at(ctx, "the graded tensor is not a metric", o, xj, "");
        memcpy(tens + 6 * (size_t)j, o, sizeof o);
        memcpy(wj, w, sizeof w);
        *any = 1;
        return ANISTAR_OK;
    }
    int c = fl_intersect(p, tens + 6 * (size_t)j, o);
    if (c < 0) return fail_tensor_at(ctx, "the graded tensor is not a metric", p, xi, "");
    if (c) {
        if (as_field_check_tensor(o))
            return fail_tensor_at(ctx, "the graded tensor is not a metric", o, xj, "");
        memcpy(tens + 6 * (size_t)j, o, sizeof o);
        *any = 1;
    }
    return ANISTAR_OK;
}

/* as_field_gradation_edges (field.h): the same passes over the pairs of edges.
 * design: pass k skips an edge neither of whose ends changed in pass k - 1 or k so far:
 * it gave no change in pass k - 1 with the same tensors, so the result is that of full
 * passes. */
anistar_status as_field_gradation_edges(anistar_context *ctx, double *tens, const double *xyz,
                                        size_t ne, const int32_t *edges, double grad,
                                        int keep_frame, int *changed) {
    const double lb = log(grad);
    anistar_status st = ANISTAR_OK;
    if (changed) *changed = 0;
    size_t n = 0;
    for (size_t e = 0; e < 2 * ne; e++)
        if ((size_t)edges[e] + 1 > n) n = (size_t)edges[e] + 1;
    int32_t *last = as_alloc_array(ctx, n ? n : 1, sizeof *last);
    grade_frames gf = {NULL, NULL, NULL}, *pgf = NULL;
    if (last && keep_frame) {
        gf.w = as_alloc_array(ctx, n ? n : 1, 3 * sizeof *gf.w);
        gf.v = as_alloc_array(ctx, n ? n : 1, 9 * sizeof *gf.v);
        gf.have = as_alloc_array(ctx, n ? n : 1, sizeof *gf.have);
        pgf = &gf;
    }
    if (!last || (keep_frame && (!gf.w || !gf.v || !gf.have))) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
        goto done;
    }
    for (size_t v = 0; v < n; v++) last[v] = 0;
    if (keep_frame) memset(gf.have, 0, n);
    for (int pass = 0; pass < AS_FIELD_GRAD_PASSES && !st; pass++) {
        int any = 0;
        for (size_t e = 0; e < ne && !st; e++) {
            int32_t i = edges[2 * e], j = edges[2 * e + 1];
            if (pass > 0 && last[i] < pass - 1 && last[j] < pass - 1) continue;
            int ci = 0, cj = 0;
            if ((st = grade_edge(ctx, tens, xyz, i, j, lb, pgf, &cj)) ||
                (st = grade_edge(ctx, tens, xyz, j, i, lb, pgf, &ci)))
                break;
            if (cj) last[j] = pass;
            if (ci) last[i] = pass;
            any |= ci | cj;
        }
        if (!any) break;
        if (changed) *changed = 1;
    }
done:
    if (last) as_free(ctx, last, (n ? n : 1) * sizeof *last);
    if (gf.w) as_free(ctx, gf.w, (n ? n : 1) * 3 * sizeof *gf.w);
    if (gf.v) as_free(ctx, gf.v, (n ? n : 1) * 9 * sizeof *gf.v);
    if (gf.have) as_free(ctx, gf.have, (n ? n : 1) * sizeof *gf.have);
    return st;
}

/* The edges from each of the n points of kd (ids 0..n-1, coordinates xyz) to its
 * AS_FIELD_GRAD_K nearest others, each pair once (kept at its smaller end when both ends
 * list the other), in the order of i then of distance: *edges (2 ints each, room for
 * *cap pairs, allocated here: free 2 * *cap ints), *ne of them. The neighbour lists come
 * from nb_known and got_known when given (borrowed: as_kdtree_knn's answers, kept by
 * fl_image_blend), else from the tree. */
static anistar_status knn_edges(anistar_context *ctx, const as_kdtree *kd, const double *xyz,
                                size_t n, const int32_t *nb_known, const uint8_t *got_known,
                                int32_t **edges, size_t *ne, size_t *cap) {
    enum { K = AS_FIELD_GRAD_K + 1 }; /* a point's list holds itself */
    *edges = NULL;
    *ne = *cap = 0;
    const int known = nb_known && got_known;
    int32_t *own_nb = NULL;
    uint8_t *own_got = NULL;
    if (!known) {
        own_nb = as_alloc_array(ctx, n, K * sizeof *own_nb);
        own_got = as_alloc_array(ctx, n, sizeof *own_got);
    }
    int32_t *e = as_alloc_array(ctx, n, K * 2 * sizeof *e);
    if (!e || (!known && (!own_nb || !own_got))) {
        as_free(ctx, own_nb, n * K * sizeof *own_nb);
        as_free(ctx, own_got, n * sizeof *own_got);
        as_free(ctx, e, n * K * 2 * sizeof *e);
        return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
    }
    if (!known) {
        double d2[K];
        for (size_t i = 0; i < n; i++)
            own_got[i] = (uint8_t)as_kdtree_knn(kd, xyz + 3 * i, K, own_nb + K * i, d2);
    }
    const int32_t *nb = known ? nb_known : own_nb;
    const uint8_t *got = known ? got_known : own_got;
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        for (size_t q = 0; q < got[i]; q++) {
            int32_t j = nb[K * i + q];
            if (j == (int32_t)i) continue;
            if (j < (int32_t)i) {
                int listed = 0;
                for (size_t r = 0; r < got[j] && !listed; r++) listed = nb[K * (size_t)j + r] == (int32_t)i;
                if (listed) continue;
            }
            e[2 * m] = (int32_t)i;
            e[2 * m + 1] = j;
            m++;
        }
    as_free(ctx, own_nb, n * K * sizeof *own_nb);
    as_free(ctx, own_got, n * sizeof *own_got);
    *edges = e;
    *ne = m;
    *cap = n * K;
    return ANISTAR_OK;
}

static anistar_status fl_mesh_blend(anistar_context *ctx, const as_surface *s,
                                    const as_field_spec *sp, as_field *fl) {
    as_mesh_info mi;
    as_mesh_surface_info(s, &mi);
    int degree = sp->has_degree ? (int)sp->degree : 2;
    size_t k = sp->has_k ? (size_t)sp->k : (degree == 2 ? AS_JET_K2 : AS_JET_K4);
    if (k < (size_t)as_jet_coef_count(degree))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "metric '%s': k = %zu is too small for degree %d (at least %d)", sp->name,
                       k, degree, as_jet_coef_count(degree));
    size_t nv = mi.nv;
    double *tens = as_alloc_array(ctx, nv, 6 * sizeof(double));
    double *own = NULL;
    double *file = NULL;
    size_t nfile = 0;
    anistar_status st = ANISTAR_OK;
    if (!tens) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
        goto done;
    }
    if (sp->kind == AS_FIELD_CURVATURE) {
        const double *vj = mi.vjet;
        if (degree != 2 || k != AS_JET_K2) {
            own = as_alloc_array(ctx, nv, AS_MESH_VJET * sizeof(double));
            if (!own) {
                st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
                goto done;
            }
            st = as_mesh_surface_jets(ctx, s, degree, k, own);
            if (st) goto done;
            vj = own;
        }
        fl->eps = sp->has_eps ? sp->eps : 1.0 / s->radius;
        fl->power = sp->has_power ? sp->power : 1.0;
        double en = 0;
        for (size_t v = 0; v < nv; v++) {
            const double *J = vj + AS_MESH_VJET * v, *x = mi.xyz + 3 * v;
            double e1 = pow(fmax(fl->eps, fabs(J[3])), fl->power);
            double e2 = pow(fmax(fl->eps, fabs(J[4])), fl->power);
            if (!isfinite(J[3]) || !isfinite(J[4]) || !fl_usable(e1) || !fl_usable(e2)) {
                st = as_fail(ctx, ANISTAR_EINVAL,
                             "metric '%s': the curvatures (%g, %g) at the vertex (%.17g, "
                             "%.17g, %.17g) give an eigenvalue that is not finite or exceeds %g",
                             sp->name, J[3], J[4], x[0], x[1], x[2], AS_FIELD_MAX_EIGENVALUE);
                goto done;
            }
            en = fmax(en, fmax(e1, e2));
        }
        fl->en = sp->has_en ? sp->en : en;
        for (size_t v = 0; v < nv; v++) {
            const double *J = vj + AS_MESH_VJET * v;
            double u[9], e[3];
            memcpy(u, J + 5, 6 * sizeof(double));
            memcpy(u + 6, J, 3 * sizeof(double));
            e[0] = pow(fmax(fl->eps, fabs(J[3])), fl->power);
            e[1] = pow(fmax(fl->eps, fabs(J[4])), fl->power);
            e[2] = fl->en;
            as_field_tensor(u, e, tens + 6 * v);
            if (!fl_frame_ok(tens + 6 * v)) {
                st = fail_tensor_at(ctx, "the curvature tensor of a vertex is not finite and "
                                         "positive definite",
                                    tens + 6 * v, mi.xyz + 3 * v,
                                    " (eps or en too small or too large)");
                goto done;
            }
        }
    } else {
        st = as_sol_read(ctx, sp->path, &nfile, &file);
        if (st) goto done;
        if (nfile != mi.nv_in) {
            st = as_fail(ctx, ANISTAR_EFORMAT,
                         "%s: %zu tensors for a mesh of %zu vertices (one per vertex needed)",
                         sp->path, nfile, mi.nv_in);
            goto done;
        }
        for (size_t i = 0; i < nfile; i++) {
            double t[6];
            memcpy(t, file + 6 * i, sizeof t);
            int32_t v = mi.vmap ? mi.vmap[i] : (int32_t)i;
            if (as_field_check_tensor(t)) {
                char at[96] = " (a vertex of no triangle)";
                if (v >= 0) {
                    const double *x = mi.xyz + 3 * (size_t)v;
                    snprintf(at, sizeof at, " at (%.17g, %.17g, %.17g)", x[0], x[1], x[2]);
                }
                st = as_fail(ctx, ANISTAR_EFORMAT,
                             "%s: the tensor of vertex %zu%s (%.17g %.17g %.17g %.17g %.17g "
                             "%.17g) is not finite and positive definite (with a condition "
                             "number <= 1e24)",
                             sp->path, i + 1, at, t[0], t[1], t[2], t[3], t[4], t[5]);
                goto done;
            }
            if (v >= 0) memcpy(tens + 6 * (size_t)v, t, sizeof t);
        }
    }
    /* grad=G is applied afterwards (as_field_set_gradation) */
    double rb = sp->has_rb ? sp->rb : 0;
    if (!sp->has_rb) st = as_blend_default_radius(ctx, mi.kd, mi.xyz, nv, k, &rb);
    if (!st) st = as_blend_create(ctx, mi.kd, mi.xyz, nv, tens, rb, &fl->blend);
done:
    as_free(ctx, tens, nv * 6 * sizeof(double));
    as_free(ctx, own, nv * AS_MESH_VJET * sizeof(double));
    as_free(ctx, file, nfile * 6 * sizeof(double));
    return st;
}

/*
 * The curvature field of an image surface, blended (field.h).
 * design: the curvature of the B-spline isosurface is exact but it is the curvature of the
 * voxels' noise as much as of the object: between two points a voxel apart its frame
 * turns at random and its eigenvalues jump between the eps floor and the hmin cap (on the
 * skull, the facets that rule 3 refined had a distortion of 3.2 between their vertices,
 * that exact ratio, at a voxel spacing), and no refinement above a voxel reconciles the
 * stars there. So an image is treated as a triangle mesh is (paper 5.2.3): the field is
 * sampled where S crosses the lattice of voxel centers (as_image_surface_lattice, the
 * data's own resolution), the exact curvature tensor is taken at each sample, and the
 * tensors are blended by Gaussian weights with the paper's default radius (the mean
 * distance of a sample to its AS_JET_K2 nearest others: about a voxel and a half) or rb=R:
 * the field is smooth at that scale, and the automatic hmin is two voxels (hdata).
 */
static anistar_status fl_image_blend(anistar_context *ctx, const as_surface *s,
                                     const as_field_spec *sp, as_field *fl) {
    double voxel = 0;
    anistar_status st = as_image_surface_lattice(ctx, s, &fl->bxyz, &fl->bn, &voxel);
    if (st) return st;
    if (fl->bn < 2) return ANISTAR_OK; /* nothing to blend: the exact field */
    double *tens = as_alloc_array(ctx, fl->bn, 6 * sizeof(double));
    if (!tens) return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
    for (size_t i = 0; i < fl->bn && !st; i++)
        st = as_field_eval(ctx, fl, fl->bxyz + 3 * i, tens + 6 * i);
    if (!st) st = as_kdtree_build(ctx, fl->bxyz, NULL, fl->bn, &fl->bkd);
    /* grad=G is applied afterwards (as_field_set_gradation) */
    double rb = sp->has_rb ? sp->rb : 0;
    if (!st && !sp->has_rb) {
        /* design: the gradation's edges (knn_edges) need each point's AS_FIELD_GRAD_K + 1
         * nearest, the first of the AS_JET_K2 + 1 found here: kept, not asked again (the
         * liver: 0.43e9 instructions, 1.5% of the run) */
        fl->bnb = as_alloc_array(ctx, fl->bn, (AS_FIELD_GRAD_K + 1) * sizeof *fl->bnb);
        fl->bnbn = as_alloc_array(ctx, fl->bn, sizeof *fl->bnbn);
        if (!fl->bnb || !fl->bnbn) {
            fl_free_neighbours(fl);
            st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory");
        }
        if (!st)
            st = as_blend_default_radius_keep(ctx, fl->bkd, fl->bxyz, fl->bn, AS_JET_K2, &rb,
                                              fl->bnb, AS_FIELD_GRAD_K + 1, fl->bnbn);
    }
    if (!st) st = as_blend_create(ctx, fl->bkd, fl->bxyz, fl->bn, tens, rb, &fl->blend);
    if (!st) fl->hdata = 2 * voxel;
    as_free(ctx, tens, fl->bn * 6 * sizeof(double));
    return st;
}

/*
 * grad=G on a field given at every point (curvature, shock, gradient, hessian on implicit
 * surfaces and images): the field itself may jump (the curvature of a surface made of
 * pieces joined with continuous tangents only — max/min of smooth functions, a capsule's
 * cylinder and caps — jumps from 0 to 1/r across the seam), and the distortion rule cannot
 * refine a jump away: it cuts the facets across it down to hmin and the run never ends.
 * design:
 *   1. a sample of S, spread about uniformly in area, fine enough for the field: n points
 *      with n = AS_FIELD_GRAD_DENSITY x the integral over S of the largest eigenvalue of M
 *      (about two points per unit of M-length where M is strongest), clamped to
 *      [AS_FIELD_GRAD_MIN_POINTS, AS_FIELD_GRAD_MAX_POINTS]; the integral from the 256
 *      points of the defaults' sample;
 *   2. the field at each point, graded (as_field_gradation_edges) along the graph of each
 *      point's AS_FIELD_GRAD_K nearest others;
 *   3. the graded tensors are blended by Gaussian weights (as_blend, the mean distance to
 *      the AS_JET_K2 nearest as radius); the field at p is then its own tensor
 *      intersected with that blend (fl_graded). Where the field is smooth at the sample's
 *      scale the blend is about the field itself and the intersection changes little;
 *      near a jump the blend carries the strong side's tensor across it, shrinking by
 *      1 + l ln G over M-length l, so the field seen from either side differs by about the
 *      growth over one sample spacing instead of the jump. The result is never below the
 *      field (sizes only shrink). (Zeroing the points the gradation left alone, to keep
 *      the field exact away from jumps, failed: next to a jump the strong side's points
 *      are among them, and their zeros pulled the blend below the strong side's tensor,
 *      leaving the jump: on a capsule 1.57 against 4 a thousandth from the seam.)
 * No graded point: the field is left exactly as it was (no blend is kept).
 */
static anistar_status fl_grade_sample(anistar_context *ctx, const as_surface *s, double grad,
                                      as_field *fl) {
    as_point_sample pre, smp;
    memset(&smp, 0, sizeof smp);
    anistar_status st = as_surface_sample(ctx, s, AS_FIELD_SAMPLE_POINTS, &pre);
    if (st) return st;
    double integral = 0;
    double *aw = as_alloc_array(ctx, pre.n, sizeof *aw);
    if (!aw) st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
    if (!st) st = as_surface_sample_weights(ctx, &pre, aw);
    for (size_t i = 0; i < pre.n && !st; i++) {
        double m[6], w[3], v[9];
        if ((st = as_field_eval(ctx, fl, pre.points + 3 * i, m))) break;
        if (as_sym3_eigen(m, w, v)) continue;
        integral += aw[i] * w[2]; /* ascending: the largest */
    }
    as_free(ctx, aw, pre.n * sizeof *aw);
    as_surface_sample_free(ctx, &pre);
    if (st) return st;
    double want = AS_FIELD_GRAD_DENSITY * integral;
    size_t n = !(want > AS_FIELD_GRAD_MIN_POINTS) ? AS_FIELD_GRAD_MIN_POINTS
               : want > AS_FIELD_GRAD_MAX_POINTS  ? AS_FIELD_GRAD_MAX_POINTS
                                                  : (size_t)want;
    if ((st = as_surface_sample(ctx, s, n, &smp))) return st;
    n = smp.n;
    double *tens = as_alloc_array(ctx, n, 6 * sizeof(double));
    int32_t *edges = NULL;
    size_t ne = 0, cap = 0;
    as_kdtree *kd = NULL;
    int raised = 0;
    if (!tens) st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
    for (size_t i = 0; i < n && !st; i++) st = as_field_eval(ctx, fl, smp.points + 3 * i, tens + 6 * i);
    if (!st) st = as_kdtree_build(ctx, smp.points, NULL, n, &kd);
    if (!st) st = knn_edges(ctx, kd, smp.points, n, NULL, NULL, &edges, &ne, &cap);
    if (!st) st = as_field_gradation_edges(ctx, tens, smp.points, ne, edges, grad, 1, &raised);
    double rb = 0;
    if (!st && raised) st = as_blend_default_radius(ctx, kd, smp.points, n, AS_JET_K2, &rb);
    if (!st && raised) st = as_blend_create(ctx, kd, smp.points, n, tens, rb, &fl->g.blend);
    if (!st && raised) {
        /* the blend borrows the points and the tree: the field keeps them */
        fl->g.xyz = smp.points;
        fl->g.n = n;
        fl->g.kd = kd;
        smp.points = NULL;
        kd = NULL;
    }
    as_free(ctx, edges, cap * 2 * sizeof *edges);
    as_free(ctx, tens, n * 6 * sizeof(double));
    as_kdtree_free(ctx, kd);
    as_surface_sample_free(ctx, &smp);
    return st;
}

/* The blend's tensors as fitted, graded with G along the mesh's triangles or the lattice
 * points' nearest-neighbour graph, into the blend (G == 0: as fitted). The tensors as
 * fitted are the blend's own until a first gradation, which keeps a copy (braw). */
static anistar_status fl_regrade_blend(anistar_context *ctx, as_field *fl, double grad) {
    size_t n;
    double *bt = as_blend_tensors(fl->blend, &n);
    if (!fl->braw) {
        if (!(fl->braw = as_alloc_array(ctx, n, 6 * sizeof(double))))
            return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
        memcpy(fl->braw, bt, n * 6 * sizeof(double));
        fl->nraw = n;
    }
    double *t = as_alloc_array(ctx, n, 6 * sizeof(double));
    if (!t) return as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
    memcpy(t, fl->braw, n * 6 * sizeof(double));
    anistar_status st = ANISTAR_OK;
    if (grad > 0 && as_surface_is_mesh(fl->surf)) {
        /* design: a triangle mesh's vertex metrics are graded along its edges (each
         * once: i < j in one of its triangles), frames kept as everywhere (field.h) */
        as_mesh_info mi;
        as_mesh_surface_info(fl->surf, &mi);
        int32_t *edges = as_alloc_array(ctx, mi.nt, 3 * 2 * sizeof *edges);
        size_t ne = 0;
        if (!edges) st = as_fail(ctx, ANISTAR_ENOMEM, "metric: out of memory (gradation)");
        for (size_t f = 0; f < mi.nt && !st; f++)
            for (int k = 0; k < 3; k++) {
                int32_t i = mi.tri[3 * f + k], j = mi.tri[3 * f + (k + 1) % 3];
                if (i < j) {
                    edges[2 * ne] = i;
                    edges[2 * ne + 1] = j;
                    ne++;
                }
            }
        if (!st) st = as_field_gradation_edges(ctx, t, mi.xyz, ne, edges, grad, 1, NULL);
        as_free(ctx, edges, mi.nt * 3 * 2 * sizeof *edges);
    } else if (grad > 0) { /* an image's lattice points: along their nearest neighbours */
        int32_t *edges = NULL;
        size_t ne = 0, cap = 0;
        st = knn_edges(ctx, fl->bkd, fl->bxyz, fl->bn, fl->bnb, fl->bnbn, &edges, &ne, &cap);
        if (!st) st = as_field_gradation_edges(ctx, t, fl->bxyz, ne, edges, grad, 1, NULL);
        as_free(ctx, edges, cap * 2 * sizeof *edges);
    }
    if (!st) memcpy(bt, t, n * 6 * sizeof(double));
    as_free(ctx, t, n * 6 * sizeof(double));
    return st;
}

/*
 * as_field_set_gradation — grad=G, from the SPEC or the API (field.h).
 * design: one path for both, so that "curvature,grad=1.3" and the setter give the same
 * field, and a field as fitted is never lost (a gradation can be changed or removed):
 *   - uniform: nothing varies, G is only recorded;
 *   - blended (per-vertex tensors on meshes, lattice tensors on images): a copy of the
 *     tensors as fitted is graded and replaces the blend's (points, radius, grid kept);
 *   - every other field, callbacks included: the blend of a graded sample of the field
 *     without any earlier gradation (fl_grade_sample), intersected at evaluation.
 * The earlier gradation is kept until the new one has succeeded.
 */
anistar_status as_field_set_gradation(anistar_context *ctx, as_field *fl, double grad) {
    if (!(grad == 0 || (isfinite(grad) && grad > 1)))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "metric: gradation G must be > 1 (or 0: none), got %g", grad);
    anistar_status st = ANISTAR_OK;
    if (fl->kind == AS_FIELD_UNIFORM) {
        /* constant: already graded for every G */
    } else if (fl->blend) {
        st = fl_regrade_blend(ctx, fl, grad);
    } else {
        /* the sample is of the field without its earlier gradation */
        as_field_gsample old = fl->g;
        memset(&fl->g, 0, sizeof fl->g);
        if (grad > 0) st = fl_grade_sample(ctx, fl->surf, grad, fl);
        if (st) { /* fl_grade_sample keeps nothing on failure */
            fl->g = old;
        } else {
            gsample_free(ctx, &old);
        }
    }
    if (!st) fl->grad = grad;
    return st;
}

anistar_status as_field_from_spec(anistar_context *ctx, const as_surface *s, const char *spec,
                                  as_field **out) {
    *out = NULL;
    as_field_spec sp;
    anistar_status st = as_field_spec_parse(ctx, spec, &sp);
    if (st) return st;
    int mesh = s && as_surface_is_mesh(s);
    if (sp.kind == AS_FIELD_SOL && !mesh) {
        st = as_fail(ctx, ANISTAR_EINVAL,
                     "metric 'sol:%s': per-vertex tensors (.sol) need a triangle-mesh "
                     "surface; not supported yet for implicit surfaces (this one: '%s')",
                     sp.path, s ? s->ops->kind : "none");
        as_field_spec_clear(ctx, &sp);
        return st;
    }
    int image_curv = s && as_surface_is_image(s) && sp.kind == AS_FIELD_CURVATURE;
    if (!mesh && (sp.has_degree || sp.has_k || (sp.has_rb && !image_curv))) {
        st = as_fail(ctx, ANISTAR_EINVAL,
                     "metric '%s': options degree and k apply to triangle-mesh surfaces only, "
                     "rb to those and to the curvature of images (this one: '%s')",
                     sp.name, s ? s->ops->kind : "none");
        as_field_spec_clear(ctx, &sp);
        return st;
    }
    if (mesh && (sp.kind == AS_FIELD_SOL || sp.kind == AS_FIELD_CURVATURE)) {
        as_field *fl;
        st = fl_new(ctx, s, sp.kind, &fl);
        if (!st) st = fl_mesh_blend(ctx, s, &sp, fl);
        /* design: a field from data is graded unless the SPEC says otherwise (issue 13:
         * jets across creases and noisy scans jump; docs/algorithm.md has the measure) */
        double g = sp.has_grad ? sp.grad : AS_FIELD_DATA_GRAD;
        if (!st && g > 0) st = as_field_set_gradation(ctx, fl, g);
        as_field_spec_clear(ctx, &sp);
        if (st) {
            as_field_free(fl);
            return st;
        }
        *out = fl;
        return ANISTAR_OK;
    }
    if (sp.kind == AS_FIELD_UNIFORM) {
        double h = sp.has_h ? sp.h : 1.0, v = 1.0 / (h * h);
        double m[6] = {v, 0, 0, v, 0, v};
        as_field_spec_clear(ctx, &sp);
        return as_field_uniform(ctx, s, m, out);
    }
    if (!s) {
        as_field_spec_clear(ctx, &sp);
        return as_fail(ctx, ANISTAR_EINVAL, "metric '%s' needs a surface", sp.name);
    }
    as_field *fl;
    st = fl_new(ctx, s, sp.kind, &fl);
    if (st) {
        as_field_spec_clear(ctx, &sp);
        return st;
    }
    fl->expr = sp.expr;
    sp.expr = NULL;
    int need_eps = 0;
    switch (sp.kind) {
    case AS_FIELD_CURVATURE:
        fl->eps = sp.has_eps ? sp.eps : 1.0 / s->radius;
        fl->power = sp.has_power ? sp.power : 1.0;
        break;
    case AS_FIELD_GRADIENT:
        fl->phi = sp.has_phi ? sp.phi : 1.0;
        break;
    default: /* hessian */
        fl->power = sp.has_power ? sp.power : 0.5;
        if (sp.has_eps) fl->eps = sp.eps;
        else need_eps = 1;
        break;
    }
    fl->en = sp.has_en ? sp.en : 0;
    if (need_eps || !sp.has_en) st = fl_defaults(ctx, fl, spec, need_eps, !sp.has_en);
    if (!st && image_curv) st = fl_image_blend(ctx, s, &sp, fl);
    /* design: the curvature of an image is a field from data, graded unless the SPEC says
     * otherwise, as on meshes (docs/algorithm.md: as fitted, the skull and the liver do
     * not finish at r0 1); so is the curvature of an expression with kinks (abs, min,
     * max), which jumps at its creases: a gyroid clipped by a ball (the max of two
     * functions) grew to 141,815 vertices in 60 s as fitted; the fields given at every
     * point are graded when asked */
    int kinked_curv = sp.kind == AS_FIELD_CURVATURE && as_surface_has_kinks(s);
    double g = sp.has_grad ? sp.grad : image_curv || kinked_curv ? AS_FIELD_DATA_GRAD : 0;
    if (!st && g > 0) st = as_field_set_gradation(ctx, fl, g);
    fl_free_neighbours(fl); /* the gradation above used them; a later one asks the tree */
    as_field_spec_clear(ctx, &sp);
    if (st) {
        as_field_free(fl);
        return st;
    }
    *out = fl;
    return ANISTAR_OK;
}
