/*
 * implicit.c — implicit surfaces f(x, y, z) = 0 (f < 0 inside) given by callbacks or by
 * an expression, and the built-in surfaces (DESIGN.md 4.6). The oracle operations are
 * the generic ones of surface.c built on the eval function defined here.
 */
#include "surface/expr.h"
#include "surface/surface.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A built-in surface's native f with its gradient and Hessian (order as in
 * as_surface_ops.eval), its parameters in v. */
typedef double (*bi_native_fn)(const double *v, const double p[3], int order, double g[3],
                               double h[6]);

typedef struct as_implicit {
    as_surface base;    /* first member: the common header */
    as_implicit_fn fn;  /* callbacks (kind "implicit") */
    as_expr *expr;      /* compiled expression (kinds "expression" and "builtin"), owned */
    bi_native_fn native;/* kind "builtin": the native evaluation ... */
    double bv[4];       /* ... and its parameters */
    double hg, hh;      /* finite-difference steps (gradient, Hessian from values) */
} as_implicit;

/* ---- finite differences --------------------------------------------------------- */

/* Central difference of the value along axis i with step h. */
static double fd_diff(const as_implicit *im, const double p[3], int i, double h) {
    double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
    a[i] += h;
    b[i] -= h;
    double w = a[i] - b[i]; /* the step actually taken */
    return (im->fn.value(a, im->fn.user) - im->fn.value(b, im->fn.user)) / w;
}

static void fd_gradient(const as_implicit *im, const double p[3], double g[3]) {
    for (int i = 0; i < 3; i++) g[i] = fd_diff(im, p, i, im->hg);
}

/* Index of H_ij in m11 m12 m13 m22 m23 m33. */
static inline int sym_index(int i, int j) {
    static const int idx[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};
    return idx[i][j];
}

/* Hessian from the gradient callback: central differences of the gradient, symmetrised. */
static void fd_hessian_from_gradient(const as_implicit *im, const double p[3], double h[6]) {
    double m[3][3];
    for (int i = 0; i < 3; i++) {
        double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]}, ga[3], gb[3];
        a[i] += im->hg;
        b[i] -= im->hg;
        double w = a[i] - b[i];
        im->fn.gradient(a, ga, im->fn.user);
        im->fn.gradient(b, gb, im->fn.user);
        for (int j = 0; j < 3; j++) m[i][j] = (ga[j] - gb[j]) / w;
    }
    for (int i = 0; i < 3; i++)
        for (int j = i; j < 3; j++) h[sym_index(i, j)] = 0.5 * (m[i][j] + m[j][i]);
}

/* Hessian from values only: second differences (19 evaluations). */
static void fd_hessian_from_values(const as_implicit *im, const double p[3], double f0,
                                   double h[6]) {
    double s = im->hh;
    for (int i = 0; i < 3; i++) {
        double a[3] = {p[0], p[1], p[2]}, b[3] = {p[0], p[1], p[2]};
        a[i] += s;
        b[i] -= s;
        double w = 0.5 * (a[i] - b[i]);
        h[sym_index(i, i)] =
            (im->fn.value(a, im->fn.user) - 2 * f0 + im->fn.value(b, im->fn.user)) / (w * w);
    }
    for (int i = 0; i < 3; i++)
        for (int j = i + 1; j < 3; j++) {
            double v[4];
            for (int k = 0; k < 4; k++) {
                double q[3] = {p[0], p[1], p[2]};
                q[i] += (k & 1) ? -s : s;
                q[j] += (k & 2) ? -s : s;
                v[k] = im->fn.value(q, im->fn.user);
            }
            h[sym_index(i, j)] = (v[0] - v[1] - v[2] + v[3]) / (4 * s * s);
        }
}

/* ---- the two kinds -------------------------------------------------------------- */

static double cb_eval(const as_surface *s, const double p[3], int order, double g[3],
                      double h[6]) {
    const as_implicit *im = (const as_implicit *)s;
    double f = im->fn.value(p, im->fn.user);
    if (order >= 1) {
        if (im->fn.gradient) im->fn.gradient(p, g, im->fn.user);
        else fd_gradient(im, p, g);
    }
    if (order >= 2) {
        if (im->fn.hessian) im->fn.hessian(p, h, im->fn.user);
        else if (im->fn.gradient) fd_hessian_from_gradient(im, p, h);
        else fd_hessian_from_values(im, p, f, h);
    }
    return f;
}

static double ex_eval(const as_surface *s, const double p[3], int order, double g[3],
                      double h[6]) {
    const as_implicit *im = (const as_implicit *)s;
    if (order <= 0) return as_expr_value(im->expr, p);
    if (order == 1) return as_expr_value_grad(im->expr, p, g);
    return as_expr_value_grad_hess(im->expr, p, g, h);
}

/* design: a built-in surface is evaluated by its own C code (value, gradient and Hessian
 * written out), not by the expression interpreter, which took about a tenth of a run on
 * the paper's torus (issue 15); the compiled formula is kept, and test_surface checks
 * that the two agree. */
static double bi_eval(const as_surface *s, const double p[3], int order, double g[3],
                      double h[6]) {
    const as_implicit *im = (const as_implicit *)s;
    return im->native(im->bv, p, order, g, h);
}

static void im_destroy(as_surface *s) {
    as_implicit *im = (as_implicit *)s;
    anistar_context *ctx = s->ctx;
    as_expr_free(ctx, im->expr);
    as_free(ctx, im, sizeof *im);
}

static const as_surface_ops cb_ops = {"implicit", cb_eval, NULL, NULL, NULL, NULL, NULL,
                                      im_destroy};
static const as_surface_ops ex_ops = {"expression", ex_eval, NULL, NULL, NULL, NULL, NULL,
                                      im_destroy};
static const as_surface_ops bi_ops = {"builtin", bi_eval, NULL, NULL, NULL, NULL, NULL,
                                      im_destroy};

int as_surface_has_kinks(const as_surface *s) {
    return s && s->ops == &ex_ops && as_expr_has_kinks(((const as_implicit *)s)->expr);
}

static anistar_status im_new(anistar_context *ctx, const as_surface_ops *ops,
                             const double center[3], double radius, as_implicit **out) {
    *out = NULL;
    as_implicit *im = as_alloc(ctx, sizeof *im);
    if (!im) return as_fail(ctx, ANISTAR_ENOMEM, "implicit surface: out of memory");
    memset(im, 0, sizeof *im);
    anistar_status st = as_surface_init(ctx, &im->base, ops, center, radius);
    if (st) {
        as_free(ctx, im, sizeof *im);
        return st;
    }
    im->hg = 6e-6 * radius;
    im->hh = 1.2e-4 * radius;
    *out = im;
    return ANISTAR_OK;
}

anistar_status as_implicit_create(anistar_context *ctx, const as_implicit_fn *fn,
                                  const double center[3], double radius, as_surface **out) {
    *out = NULL;
    if (!fn || !fn->value)
        return as_fail(ctx, ANISTAR_EINVAL, "implicit surface: the value callback is required");
    as_implicit *im;
    anistar_status st = im_new(ctx, &cb_ops, center, radius, &im);
    if (st) return st;
    im->fn = *fn;
    *out = &im->base;
    return ANISTAR_OK;
}

anistar_status as_implicit_from_expression(anistar_context *ctx, const char *expr,
                                           const double center[3], double radius,
                                           as_surface **out) {
    *out = NULL;
    if (!expr) return as_fail(ctx, ANISTAR_EINVAL, "implicit surface: NULL expression");
    as_implicit *im;
    anistar_status st = im_new(ctx, &ex_ops, center, radius, &im);
    if (st) return st;
    st = as_expr_compile(ctx, expr, &im->expr);
    if (st) {
        as_free(ctx, im, sizeof *im);
        return st;
    }
    *out = &im->base;
    return ANISTAR_OK;
}

/* ---- built-in surfaces ---------------------------------------------------------- */

#define BI_MAX_PARAMS 4

typedef struct bi_param {
    const char *name;
    double def;
} bi_param;

typedef struct bi_surface {
    const char *name;
    const char *description;
    const char *formula; /* in x, y, z and the parameters */
    int nparams;
    bi_param params[BI_MAX_PARAMS];
    /* NULL if the parameters are valid, else a message naming the constraint */
    const char *(*check)(const double *v);
    double (*bound)(const double *v); /* default bounding radius (center: origin) */
    bi_native_fn native;
} bi_surface;

static const char *chk_sphere(const double *v) { return v[0] > 0 ? NULL : "r must be > 0"; }
static double bd_sphere(const double *v) { return 1.25 * v[0]; }

static const char *chk_ellipsoid(const double *v) {
    return v[0] > 0 && v[1] > 0 && v[2] > 0 ? NULL : "a, b and c must be > 0";
}
static double bd_ellipsoid(const double *v) { return 1.25 * fmax(v[0], fmax(v[1], v[2])); }

static const char *chk_torus(const double *v) {
    return v[1] > 0 && v[0] > v[1] ? NULL : "the torus needs R > r > 0";
}
static double bd_torus(const double *v) { return v[0] + 1.25 * v[1]; }

static const char *chk_chair(const double *v) {
    return v[2] > 0 && v[1] >= 0 ? NULL : "the chair needs k > 0 and b >= 0";
}
/* The default chair (a 0.8, b 0.4, k 1) reaches |p| = 1.034 k (measured along 20000
 * directions); the bound scales with k. Other a, b may need bound=... (the sampler
 * reports f < 0 on the sphere then). */
static double bd_chair(const double *v) { return 1.3 * v[2]; }

static const char *chk_none(const double *v) {
    (void)v;
    return NULL;
}
static double bd_tanglecube(const double *v) {
    (void)v;
    return 4.0;
}

static const char *chk_double_torus(const double *v) {
    return v[0] > 0 && v[0] < 0.25 ? NULL : "the double torus needs 0 < r < 0.25 (genus 2)";
}
static double bd_double_torus(const double *v) { return 1.2 + v[0]; }


/* The native evaluations (see bi_eval). h: m11 m12 m13 m22 m23 m33. */
static double nat_sphere(const double *v, const double p[3], int order, double g[3],
                         double h[6]) {
    const double x = p[0], y = p[1], z = p[2];
    if (order >= 1) {
        g[0] = 2 * x;
        g[1] = 2 * y;
        g[2] = 2 * z;
    }
    if (order >= 2) {
        h[0] = h[3] = h[5] = 2;
        h[1] = h[2] = h[4] = 0;
    }
    return x * x + y * y + z * z - v[0] * v[0];
}

static double nat_ellipsoid(const double *v, const double p[3], int order, double g[3],
                            double h[6]) {
    double f = -1;
    for (int i = 0; i < 3; i++) {
        double t = p[i] / v[i];
        f += t * t;
        if (order >= 1) g[i] = 2 * t / v[i];
    }
    if (order >= 2) {
        h[0] = 2 / (v[0] * v[0]);
        h[3] = 2 / (v[1] * v[1]);
        h[5] = 2 / (v[2] * v[2]);
        h[1] = h[2] = h[4] = 0;
    }
    return f;
}

/* (q - R)^2 + z^2 - r^2 with q = |(x, y)|; on the axis (q = 0) the gradient and Hessian
 * are NaN, as the expression's are. */
static double nat_torus(const double *v, const double p[3], int order, double g[3],
                        double h[6]) {
    const double R = v[0], r = v[1], x = p[0], y = p[1], z = p[2];
    const double q = sqrt(x * x + y * y), d = q - R;
    if (order >= 1) {
        double c = 2 * d / q;
        g[0] = c * x;
        g[1] = c * y;
        g[2] = 2 * z;
        if (order >= 2) {
            /* d2/dxi dxj of (q - R)^2 = 2 xi xj / q^2 + 2 d (dij / q - xi xj / q^3) */
            double q2 = q * q, a = 2 / q2 - 2 * d / (q2 * q);
            h[0] = a * x * x + c;
            h[1] = a * x * y;
            h[3] = a * y * y + c;
            h[2] = h[4] = 0;
            h[5] = 2;
        }
    }
    return d * d + z * z - r * r;
}

/* (s - a k^2)^2 - b A B with s = |p|^2, A = (z - k)^2 - 2 x^2, B = (z + k)^2 - 2 y^2. */
static double nat_chair(const double *v, const double p[3], int order, double g[3],
                        double h[6]) {
    const double a = v[0], b = v[1], k = v[2], x = p[0], y = p[1], z = p[2];
    const double P = x * x + y * y + z * z - a * k * k;
    const double A = (z - k) * (z - k) - 2 * x * x, B = (z + k) * (z + k) - 2 * y * y;
    if (order >= 1) {
        const double Pd[3] = {2 * x, 2 * y, 2 * z};
        const double Ad[3] = {-4 * x, 0, 2 * (z - k)}, Bd[3] = {0, -4 * y, 2 * (z + k)};
        for (int i = 0; i < 3; i++) g[i] = 2 * P * Pd[i] - b * (Ad[i] * B + A * Bd[i]);
        if (order >= 2) {
            const double Add[3] = {-4, 0, 2}, Bdd[3] = {0, -4, 2}; /* diagonal only */
            int n = 0;
            for (int i = 0; i < 3; i++)
                for (int j = i; j < 3; j++, n++) {
                    double dij = i == j;
                    h[n] = 2 * (Pd[i] * Pd[j] + 2 * P * dij) -
                           b * (dij * Add[i] * B + Ad[i] * Bd[j] + Ad[j] * Bd[i] +
                                A * dij * Bdd[i]);
                }
        }
    }
    return P * P - b * A * B;
}

static double nat_tanglecube(const double *v, const double p[3], int order, double g[3],
                             double h[6]) {
    double f = v[0];
    for (int i = 0; i < 3; i++) {
        double t = p[i], t2 = t * t;
        f += t2 * t2 - 5 * t2;
        if (order >= 1) g[i] = 4 * t2 * t - 10 * t;
    }
    if (order >= 2) {
        h[0] = 12 * p[0] * p[0] - 10;
        h[3] = 12 * p[1] * p[1] - 10;
        h[5] = 12 * p[2] * p[2] - 10;
        h[1] = h[2] = h[4] = 0;
    }
    return f;
}

/* u^2 + z^2 - r^2 with u = x^4 - x^2 + y^2. */
static double nat_double_torus(const double *v, const double p[3], int order, double g[3],
                               double h[6]) {
    const double r = v[0], x = p[0], y = p[1], z = p[2], x2 = x * x;
    const double u = x2 * x2 - x2 + y * y;
    if (order >= 1) {
        const double ux = 4 * x2 * x - 2 * x, uy = 2 * y;
        g[0] = 2 * u * ux;
        g[1] = 2 * u * uy;
        g[2] = 2 * z;
        if (order >= 2) {
            h[0] = 2 * (ux * ux + u * (12 * x2 - 2));
            h[1] = 2 * ux * uy;
            h[3] = 2 * (uy * uy + 2 * u);
            h[2] = h[4] = 0;
            h[5] = 2;
        }
    }
    return u * u + z * z - r * r;
}

static const bi_surface bi_table[] = {
    {"sphere", "sphere of radius r: x^2+y^2+z^2-r^2; r=1; bound 1.25 r; genus 0",
     "x^2+y^2+z^2-r^2", 1, {{"r", 1}}, chk_sphere, bd_sphere, nat_sphere},
    {"ellipsoid",
     "ellipsoid with semi-axes a, b, c: (x/a)^2+(y/b)^2+(z/c)^2-1; a=1.5, b=1, c=0.5; "
     "bound 1.25 max(a,b,c); genus 0",
     "(x/a)^2+(y/b)^2+(z/c)^2-1", 3, {{"a", 1.5}, {"b", 1}, {"c", 0.5}}, chk_ellipsoid,
     bd_ellipsoid, nat_ellipsoid},
    {"torus",
     "torus around the z axis: (sqrt(x^2+y^2)-R)^2+z^2-r^2; R=10, r=1 (the paper's); "
     "bound R + 1.25 r; genus 1",
     "(sqrt(x^2+y^2)-R)^2+z^2-r^2", 2, {{"R", 10}, {"r", 1}}, chk_torus, bd_torus, nat_torus},
    {"chair",
     "the paper's chair (Fig. 5): (x^2+y^2+z^2-a*k^2)^2-b*((z-k)^2-2*x^2)*((z+k)^2-2*y^2); "
     "a=0.8, b=0.4, k=1; bound 1.3 k; genus 3",
     "(x^2+y^2+z^2-a*k^2)^2-b*((z-k)^2-2*x^2)*((z+k)^2-2*y^2)", 3,
     {{"a", 0.8}, {"b", 0.4}, {"k", 1}}, chk_chair, bd_chair, nat_chair},
    {"tanglecube",
     "tangle cube: x^4-5*x^2+y^4-5*y^2+z^4-5*z^2+c; c=11.8; bound 4 (suits c near 11.8); "
     "genus 5",
     "x^4-5*x^2+y^4-5*y^2+z^4-5*z^2+c", 1, {{"c", 11.8}}, chk_none, bd_tanglecube, nat_tanglecube},
    {"double_torus",
     "genus-2 surface: a tube around Gerono's lemniscate y^2 = x^2 (1-x^2) (a figure "
     "eight in the xy plane): (x^4-x^2+y^2)^2+z^2-r^2; r=0.1 (0 < r < 0.25); bound 1.2 + r",
     "(x^4-x^2+y^2)^2+z^2-r^2", 1, {{"r", 0.1}}, chk_double_torus, bd_double_torus, nat_double_torus},
};
#define BI_COUNT (sizeof bi_table / sizeof bi_table[0])

int as_implicit_builtin_info(size_t i, const char **name, const char **description) {
    if (i >= BI_COUNT) return -1;
    if (name) *name = bi_table[i].name;
    if (description) *description = bi_table[i].description;
    return 0;
}

/* Parse a finite number filling the whole of [s, s + n). */
static int parse_number(const char *s, size_t n, double *v) {
    char buf[64];
    if (n == 0 || n >= sizeof buf) return -1;
    memcpy(buf, s, n);
    buf[n] = '\0';
    char *end;
    errno = 0;
    double x = strtod(buf, &end);
    if (end != buf + n || errno == ERANGE || !isfinite(x)) return -1;
    *v = x;
    return 0;
}

static anistar_status bi_create(anistar_context *ctx, const char *spec, int native_off,
                                as_surface **out) {
    *out = NULL;
    if (!spec) return as_fail(ctx, ANISTAR_EINVAL, "builtin: NULL name");
    size_t nlen = strcspn(spec, ",");
    const bi_surface *bi = NULL;
    for (size_t i = 0; i < BI_COUNT; i++)
        if (strlen(bi_table[i].name) == nlen && !strncmp(bi_table[i].name, spec, nlen))
            bi = &bi_table[i];
    if (!bi) {
        char names[256] = "";
        size_t used = 0;
        for (size_t i = 0; i < BI_COUNT && used < sizeof names; i++) {
            int w = snprintf(names + used, sizeof names - used, "%s%s", i ? ", " : "",
                             bi_table[i].name);
            if (w > 0) used += (size_t)w;
        }
        return as_fail(ctx, ANISTAR_EINVAL, "unknown builtin surface '%.*s' (built-ins: %s)",
                       (int)(nlen > 64 ? 64 : nlen), spec, names);
    }
    double v[BI_MAX_PARAMS], bound = 0;
    int has_bound = 0, seen[BI_MAX_PARAMS] = {0};
    for (int i = 0; i < bi->nparams; i++) v[i] = bi->params[i].def;
    const char *p = spec + nlen;
    while (*p == ',') {
        p++;
        size_t len = strcspn(p, ",");
        const char *eq = memchr(p, '=', len);
        if (!eq)
            return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': expected NAME=VALUE, got '%.*s'",
                           bi->name, (int)(len > 64 ? 64 : len), p);
        size_t klen = (size_t)(eq - p);
        double x;
        if (parse_number(eq + 1, len - klen - 1, &x))
            return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': '%.*s' is not a finite number",
                           bi->name, (int)((len - klen - 1) > 64 ? 64 : len - klen - 1),
                           eq + 1);
        int k = -1;
        for (int i = 0; i < bi->nparams; i++)
            if (strlen(bi->params[i].name) == klen && !strncmp(bi->params[i].name, p, klen))
                k = i;
        if (k >= 0) {
            if (seen[k])
                return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': parameter '%s' given twice",
                               bi->name, bi->params[k].name);
            seen[k] = 1;
            v[k] = x;
        } else if (klen == 5 && !strncmp(p, "bound", 5)) {
            if (has_bound)
                return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': bound given twice",
                               bi->name);
            if (!(x > 0))
                return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': bound must be > 0, got %g",
                               bi->name, x);
            has_bound = 1;
            bound = x;
        } else {
            char names[128] = "";
            size_t used = 0;
            for (int i = 0; i < bi->nparams; i++) {
                int w = snprintf(names + used, sizeof names - used, "%s, ", bi->params[i].name);
                if (w > 0) used += (size_t)w;
            }
            return as_fail(ctx, ANISTAR_EINVAL,
                           "builtin '%s' has no parameter '%.*s' (parameters: %sbound)", bi->name,
                           (int)(klen > 64 ? 64 : klen), p, names);
        }
        p += len;
    }
    const char *why = bi->check(v);
    if (why) return as_fail(ctx, ANISTAR_EINVAL, "builtin '%s': %s", bi->name, why);
    if (!has_bound) bound = bi->bound(v);
    /* The expression: parameter definitions, then the formula. */
    char src[512];
    size_t used = 0;
    for (int i = 0; i < bi->nparams; i++) {
        int w = snprintf(src + used, sizeof src - used, "%s=%.17g; ", bi->params[i].name, v[i]);
        if (w < 0 || (size_t)w >= sizeof src - used)
            return as_fail(ctx, ANISTAR_EINTERNAL, "builtin '%s': expression too long", bi->name);
        used += (size_t)w;
    }
    int w = snprintf(src + used, sizeof src - used, "%s", bi->formula);
    if (w < 0 || (size_t)w >= sizeof src - used)
        return as_fail(ctx, ANISTAR_EINTERNAL, "builtin '%s': expression too long", bi->name);
    const double center[3] = {0, 0, 0};
    anistar_status st = as_implicit_from_expression(ctx, src, center, bound, out);
    if (st != ANISTAR_OK || native_off) return st;
    as_implicit *im = (as_implicit *)*out;
    im->base.ops = &bi_ops;
    im->native = bi->native;
    for (int i = 0; i < bi->nparams; i++) im->bv[i] = v[i];
    return ANISTAR_OK;
}

anistar_status as_implicit_builtin(anistar_context *ctx, const char *spec, as_surface **out) {
    return bi_create(ctx, spec, 0, out);
}

anistar_status as_implicit_builtin_expr(anistar_context *ctx, const char *spec,
                                        as_surface **out) {
    return bi_create(ctx, spec, 1, out);
}
