/*
 * surface.c — the surface oracle shared by every surface kind (DESIGN.md 4.6): dispatch
 * through the kind's table, and the generic implementations for surfaces given by a
 * function f (f < 0 inside): side, segment crossing, projection, local frame
 * (normal, principal curvatures and directions, paper 5.2.2) and initial points.
 *
 * Everything here keeps its state on the caller's stack (crossing, projection, frame)
 * or in memory allocated for the call (sampling): a surface is never written after
 * creation, so concurrent queries are safe.
 */
#include "surface/surface.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ---- small vector helpers ------------------------------------------------------- */

static inline double v3_dot(const double a[3], const double b[3]) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline double v3_norm(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline double v3_dist2(const double a[3], const double b[3]) {
    double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return d0 * d0 + d1 * d1 + d2 * d2;
}
static inline void v3_cross(const double a[3], const double b[3], double c[3]) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}
static inline int v3_finite(const double a[3]) {
    return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}
static inline int sym_finite(const double h[6]) {
    for (int i = 0; i < 6; i++)
        if (!isfinite(h[i])) return 0;
    return 1;
}
/* h (m11 m12 m13 m22 m23 m33) times the vector v. */
static inline void sym_mul(const double h[6], const double v[3], double y[3]) {
    y[0] = h[0] * v[0] + h[1] * v[1] + h[2] * v[2];
    y[1] = h[1] * v[0] + h[3] * v[1] + h[4] * v[2];
    y[2] = h[2] * v[0] + h[4] * v[1] + h[5] * v[2];
}

/* The raw function value, no checks (NaN propagates). */
static inline double fs_value(const as_surface *s, const double p[3]) {
    return s->ops->eval(s, p, 0, NULL, NULL);
}

static anistar_status fail_nonfinite(anistar_context *ctx, const char *what, const double p[3]) {
    return as_fail(ctx, ANISTAR_EINVAL, "%s is not finite at (%.17g, %.17g, %.17g)", what, p[0],
                   p[1], p[2]);
}

static anistar_status fail_no_function(anistar_context *ctx, const as_surface *s) {
    return as_fail(ctx, ANISTAR_EINVAL, "surface of kind '%s' has no function to evaluate",
                   s->ops->kind);
}

/* ---- common header, dispatch ---------------------------------------------------- */

anistar_status as_surface_init(anistar_context *ctx, as_surface *s, const as_surface_ops *ops,
                               const double center[3], double radius) {
    if (!v3_finite(center))
        return as_fail(ctx, ANISTAR_EINVAL, "bounding sphere: center is not finite");
    if (!(isfinite(radius) && radius > 0))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "bounding sphere: radius must be finite and > 0, got %g", radius);
    s->ops = ops;
    s->ctx = ctx;
    memcpy(s->center, center, sizeof s->center);
    s->radius = radius;
    s->tol = AS_SURFACE_REL_TOL * radius;
    return ANISTAR_OK;
}

void as_surface_free(as_surface *s) {
    if (s) s->ops->destroy(s);
}

anistar_status as_surface_eval(anistar_context *ctx, const as_surface *s, const double p[3],
                               int order, double *f, double g[3], double h[6]) {
    if (!s->ops->eval) return fail_no_function(ctx, s);
    double gl[3] = {0, 0, 0}, hl[6] = {0, 0, 0, 0, 0, 0};
    double v = s->ops->eval(s, p, order, gl, hl);
    if (!isfinite(v)) return fail_nonfinite(ctx, "f", p);
    if (order >= 1 && !v3_finite(gl)) return fail_nonfinite(ctx, "the gradient of f", p);
    if (order >= 2 && !sym_finite(hl)) return fail_nonfinite(ctx, "the Hessian of f", p);
    if (f) *f = v;
    if (order >= 1 && g) memcpy(g, gl, sizeof gl);
    if (order >= 2 && h) memcpy(h, hl, sizeof hl);
    return ANISTAR_OK;
}

anistar_status as_surface_side(anistar_context *ctx, const as_surface *s, const double p[3],
                               int *side) {
    if (s->ops->side) return s->ops->side(ctx, s, p, side);
    return as_fsurface_side(ctx, s, p, side);
}

anistar_status as_surface_crossing(anistar_context *ctx, const as_surface *s, const double a[3],
                                   const double b[3], const double ref[3], int *found,
                                   double x[3]) {
    if (s->ops->crossing) return s->ops->crossing(ctx, s, a, b, ref, found, x);
    return as_fsurface_crossing(ctx, s, a, b, ref, found, x);
}

anistar_status as_surface_project(anistar_context *ctx, const as_surface *s, const double p[3],
                                  double q[3]) {
    if (s->ops->project) return s->ops->project(ctx, s, p, q);
    return as_fsurface_project(ctx, s, p, q);
}

anistar_status as_surface_frame_at(anistar_context *ctx, const as_surface *s, const double p[3],
                                   as_surface_frame *fr) {
    if (s->ops->frame) return s->ops->frame(ctx, s, p, fr);
    return as_fsurface_frame(ctx, s, p, fr);
}

anistar_status as_surface_normal_at(anistar_context *ctx, const as_surface *s,
                                    const double p[3], double n[3], int *singular) {
    *singular = 0;
    if (!s->ops->eval || s->ops->frame) {
        as_surface_frame fr;
        anistar_status st = as_surface_frame_at(ctx, s, p, &fr);
        if (st) return st;
        *singular = fr.singular;
        memcpy(n, fr.n, sizeof fr.n);
        return ANISTAR_OK;
    }
    double f, g[3];
    anistar_status st = as_surface_eval(ctx, s, p, 1, &f, g, NULL);
    if (st) return st;
    double gn = v3_norm(g);
    if (!(gn > DBL_MIN)) {
        *singular = 1;
        n[0] = n[1] = n[2] = 0;
        return ANISTAR_OK;
    }
    for (int i = 0; i < 3; i++) n[i] = g[i] / gn;
    return ANISTAR_OK;
}

anistar_status as_surface_normal(anistar_context *ctx, const as_surface *s, const double p[3],
                                 double n[3]) {
    int singular;
    double m[3];
    anistar_status st = as_surface_normal_at(ctx, s, p, m, &singular);
    if (st) return st;
    if (singular)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "the normal is undefined at (%.17g, %.17g, %.17g): grad f vanishes there",
                       p[0], p[1], p[2]);
    memcpy(n, m, sizeof m);
    return ANISTAR_OK;
}

anistar_status as_surface_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                 as_point_sample *out) {
    if (s->ops->sample) return s->ops->sample(ctx, s, max_points, out);
    return as_fsurface_sample(ctx, s, max_points, out);
}

void as_surface_sample_free(anistar_context *ctx, as_point_sample *smp) {
    if (!smp) return;
    as_free(ctx, smp->points, smp->n * 3 * sizeof(double));
    as_free(ctx, smp->component, smp->n * sizeof(int32_t));
    memset(smp, 0, sizeof *smp);
}

/* ---- side ----------------------------------------------------------------------- */

static inline int fs_in_ball(const as_surface *s, const double p[3]) {
    return v3_dist2(p, s->center) <= s->radius * s->radius;
}

anistar_status as_fsurface_side(anistar_context *ctx, const as_surface *s, const double p[3],
                                int *side) {
    if (!s->ops->eval) return fail_no_function(ctx, s);
    if (!v3_finite(p)) return as_fail(ctx, ANISTAR_EINVAL, "side: point is not finite");
    if (!fs_in_ball(s, p)) {
        *side = 1;
        return ANISTAR_OK;
    }
    double f = fs_value(s, p);
    if (!isfinite(f)) return fail_nonfinite(ctx, "f", p);
    *side = f < 0 ? -1 : (f > 0 ? 1 : 0);
    return ANISTAR_OK;
}

/* ---- crossing ------------------------------------------------------------------- */

/* The chord of [a, b] inside the ball, parametrised p(u) = (1-u) A + u B, u in [0, 1]
 * (this form gives A and B exactly at u = 0 and 1). */
typedef struct cr_chord {
    const as_surface *s;
    anistar_context *ctx;
    double A[3], B[3], D[3];
    double len;  /* |B - A| */
    double umin; /* shortest piece split (1e-7 radius) */
    double uval; /* pieces shorter than this are minimised when they hold a valley */
    int evals;   /* evaluations so far (budget AS_CROSSING_MAX_EVALS) */
} cr_chord;

static inline void cr_point(const cr_chord *c, double u, double p[3]) {
    for (int i = 0; i < 3; i++) p[i] = (1.0 - u) * c->A[i] + u * c->B[i];
}

/* One sample: f at p(u) and its derivative along the chord (per unit u). *dok = 0 when
 * the derivative is not finite (then only the value is used). */
static anistar_status cr_eval(cr_chord *c, double u, double *f, double *d, int *dok) {
    double p[3], g[3] = {0, 0, 0};
    cr_point(c, u, p);
    c->evals++;
    double v = c->s->ops->eval(c->s, p, 1, g, NULL);
    if (!isfinite(v)) return fail_nonfinite(c->ctx, "f", p);
    *f = v;
    *d = v3_dot(g, c->D);
    *dok = isfinite(*d);
    return ANISTAR_OK;
}

static anistar_status cr_value(cr_chord *c, double u, double *f) {
    double p[3];
    cr_point(c, u, p);
    c->evals++;
    double v = fs_value(c->s, p);
    if (!isfinite(v)) return fail_nonfinite(c->ctx, "f", p);
    *f = v;
    return ANISTAR_OK;
}

/* Candidates: brackets [ua, ub] with a sign change, or exact points (ua == ub). */
#define CR_MAX_CAND 16
typedef struct cr_cand {
    double ua, ub, fa, fb;
    double dlo; /* distance from ref to the piece (lower bound of the root's distance) */
} cr_cand;

typedef struct cr_cands {
    cr_cand c[CR_MAX_CAND];
    int n;
    double ref[3];
} cr_cands;

static double cr_piece_dist(const cr_chord *c, const double ref[3], double ua, double ub) {
    double pa[3], pb[3], d[3], w[3];
    cr_point(c, ua, pa);
    cr_point(c, ub, pb);
    for (int i = 0; i < 3; i++) {
        d[i] = pb[i] - pa[i];
        w[i] = ref[i] - pa[i];
    }
    double dd = v3_dot(d, d), t = dd > 0 ? v3_dot(w, d) / dd : 0;
    if (t < 0) t = 0;
    if (t > 1) t = 1;
    double q[3] = {pa[0] + t * d[0], pa[1] + t * d[1], pa[2] + t * d[2]};
    return sqrt(v3_dist2(q, ref));
}

/* Add a candidate; when full, it replaces the farthest one if it is nearer. */
static void cr_add(const cr_chord *c, cr_cands *cs, double ua, double fa, double ub, double fb) {
    cr_cand k = {ua, ub, fa, fb, cr_piece_dist(c, cs->ref, ua, ub)};
    if (cs->n < CR_MAX_CAND) {
        cs->c[cs->n++] = k;
        return;
    }
    int far = 0;
    for (int i = 1; i < cs->n; i++)
        if (cs->c[i].dlo > cs->c[far].dlo) far = i;
    if (k.dlo < cs->c[far].dlo) cs->c[far] = k;
}

/* Real roots of A s^2 + B s + C in (0, 1), ascending; returns their number. */
static int quad_roots01(double A, double B, double C, double r[2]) {
    int n = 0;
    double t[2];
    double scale = fabs(A) + fabs(B) + fabs(C);
    if (scale == 0) return 0;
    if (fabs(A) <= 1e-14 * scale) {
        if (B != 0) t[n++] = -C / B;
    } else {
        double disc = B * B - 4 * A * C;
        if (disc >= 0) {
            double q = -0.5 * (B + copysign(sqrt(disc), B));
            t[n++] = q / A;
            if (q != 0) t[n++] = C / q;
        }
    }
    int m = 0;
    for (int i = 0; i < n; i++)
        if (t[i] > 0 && t[i] < 1) r[m++] = t[i];
    if (m == 2 && r[0] > r[1]) {
        double x = r[0];
        r[0] = r[1];
        r[1] = x;
    }
    return m;
}

/*
 * The cubic Hermite interpolant on [0, 1] of (f0, D0) and (f1, D1) (slopes per unit s).
 * Fills its values at 0, its interior critical points and 1 (ascending); returns the
 * number of nodes (2 to 4).
 */
static int hermite_nodes(double f0, double D0, double f1, double D1, double v[4]) {
    double c2 = 3 * (f1 - f0) - 2 * D0 - D1;
    double c3 = 2 * (f0 - f1) + D0 + D1;
    double r[2];
    int m = quad_roots01(3 * c3, 2 * c2, D0, r);
    int n = 0;
    v[n++] = f0;
    for (int i = 0; i < m; i++) {
        double s = r[i];
        v[n++] = f0 + s * (D0 + s * (c2 + s * c3));
    }
    v[n++] = f1;
    return n;
}

static inline int sgn(double x) { return x < 0 ? -1 : (x > 0 ? 1 : 0); }

/* Illinois (modified regula falsi) on [ua, ub], fa and fb of strict opposite signs, to a
 * bracket narrower than tol_u; returns in *u the end with the smaller |f|. */
static anistar_status cr_refine(cr_chord *c, double ua, double fa, double ub, double fb,
                                double tol_u, double *u) {
    double ta = fa, tb = fb; /* true values (fa, fb get halved) */
    int last = 0;
    double w_prev = ub - ua;
    for (int it = 0; it < 200 && ub - ua > tol_u; it++) {
        double um;
        if (it % 4 == 3 && ub - ua > 0.5 * w_prev) {
            um = 0.5 * (ua + ub); /* slow progress: bisect */
        } else {
            um = (ua * fb - ub * fa) / (fb - fa);
            if (!(um > ua && um < ub)) um = 0.5 * (ua + ub);
        }
        if (it % 4 == 3) w_prev = ub - ua;
        if (um <= ua || um >= ub) break; /* no representable progress */
        double fm;
        anistar_status st = cr_value(c, um, &fm);
        if (st) return st;
        if (fm == 0) {
            *u = um;
            return ANISTAR_OK;
        }
        if (sgn(fm) == sgn(tb)) {
            ub = um;
            fb = tb = fm;
            if (last == 1) fa *= 0.5;
            last = 1;
        } else {
            ua = um;
            fa = ta = fm;
            if (last == -1) fb *= 0.5;
            last = -1;
        }
    }
    *u = fabs(ta) <= fabs(tb) ? ua : ub;
    return ANISTAR_OK;
}

/* Golden-section minimisation of q(u) = sg * f(p(u)) on [u0, u1]; stops early when q <= 0
 * is seen. Returns the best u and its q. */
static anistar_status cr_minimise(cr_chord *c, int sg, double u0, double u1, double *um,
                                  double *qm) {
    const double gr = 0.6180339887498949;
    double a = u0, b = u1;
    double x1 = b - gr * (b - a), x2 = a + gr * (b - a), f1, f2;
    anistar_status st = cr_value(c, x1, &f1);
    if (st) return st;
    st = cr_value(c, x2, &f2);
    if (st) return st;
    f1 *= sg;
    f2 *= sg;
    double wmin = 1e-3 * c->umin;
    for (int it = 0; it < 80 && b - a > wmin && f1 > 0 && f2 > 0; it++) {
        if (f1 <= f2) {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - gr * (b - a);
            st = cr_value(c, x1, &f1);
            f1 *= sg;
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + gr * (b - a);
            st = cr_value(c, x2, &f2);
            f2 *= sg;
        }
        if (st) return st;
    }
    if (f1 <= f2) {
        *um = x1;
        *qm = f1;
    } else {
        *um = x2;
        *qm = f2;
    }
    return ANISTAR_OK;
}

/* A piece [u0, u1] of the chord with end values and slopes (per unit u). */
typedef struct cr_piece {
    double u0, f0, d0, u1, f1, d1;
    int ok0, ok1;
} cr_piece;

#define CR_STACK 96

/* Analyse one base piece: split it where the Hermite test asks, record candidates. */
static anistar_status cr_piece_scan(cr_chord *c, cr_cands *cs, cr_piece base) {
    cr_piece stack[CR_STACK];
    int top = 0;
    stack[top++] = base;
    while (top > 0) {
        cr_piece pc = stack[--top];
        double w = pc.u1 - pc.u0;
        int s0 = sgn(pc.f0), s1 = sgn(pc.f1);
        if (s0 == 0 && s1 == 0) continue; /* both ends are roots, recorded already */
        int can_split = w > c->umin && c->evals < AS_CROSSING_MAX_EVALS && top + 2 <= CR_STACK;
        int suspicious = 0, valley = 0;
        if (pc.ok0 && pc.ok1) {
            double v[4];
            int nv = hermite_nodes(pc.f0, pc.d0 * w, pc.f1, pc.d1 * w, v);
            if (s0 * s1 < 0) {
                int changes = 0;
                for (int i = 0; i + 1 < nv; i++)
                    if (sgn(v[i]) * sgn(v[i + 1]) <= 0) changes++;
                suspicious = changes > 1;
            } else {
                int sg = s0 != 0 ? s0 : s1;
                double qend = fmin(sg * pc.f0, sg * pc.f1);
                for (int i = 1; i + 1 < nv; i++)
                    if (sg * v[i] < 0.5 * qend) suspicious = valley = 1;
            }
        }
        if (s0 * s1 < 0 && !suspicious) {
            cr_add(c, cs, pc.u0, pc.f0, pc.u1, pc.f1);
            continue;
        }
        if (!suspicious) continue; /* same signs, no valley predicted */
        if (valley && w <= c->uval) {
            /* A resolved valley: minimise, split at the minimum or report a touch. */
            int sg = s0 != 0 ? s0 : s1;
            double um, qm;
            anistar_status st = cr_minimise(c, sg, pc.u0, pc.u1, &um, &qm);
            if (st) return st;
            if (qm < 0) {
                double fm = sg * qm;
                if (s0 != 0) cr_add(c, cs, pc.u0, pc.f0, um, fm);
                if (s1 != 0) cr_add(c, cs, um, fm, pc.u1, pc.f1);
            } else if (qm == 0) {
                cr_add(c, cs, um, 0, um, 0);
            } else {
                double p[3], g[3] = {0, 0, 0};
                cr_point(c, um, p);
                double fv = c->s->ops->eval(c->s, p, 1, g, NULL);
                double gn = v3_norm(g);
                if (isfinite(fv) && isfinite(gn) && fabs(fv) <= c->s->tol * gn)
                    cr_add(c, cs, um, fv, um, fv);
            }
            continue;
        }
        if (!can_split) {
            if (s0 * s1 < 0) cr_add(c, cs, pc.u0, pc.f0, pc.u1, pc.f1);
            continue;
        }
        double um = 0.5 * (pc.u0 + pc.u1), fm, dm;
        int okm;
        anistar_status st = cr_eval(c, um, &fm, &dm, &okm);
        if (st) return st;
        if (fm == 0) cr_add(c, cs, um, 0, um, 0);
        cr_piece right = {um, fm, dm, pc.u1, pc.f1, pc.d1, okm, pc.ok1};
        cr_piece left = {pc.u0, pc.f0, pc.d0, um, fm, dm, pc.ok0, okm};
        stack[top++] = right;
        stack[top++] = left;
    }
    return ANISTAR_OK;
}

anistar_status as_fsurface_crossing(anistar_context *ctx, const as_surface *s,
                                    const double a[3], const double b[3], const double ref[3],
                                    int *found, double x[3]) {
    *found = 0;
    if (!s->ops->eval) return fail_no_function(ctx, s);
    if (!v3_finite(a) || !v3_finite(b) || !v3_finite(ref))
        return as_fail(ctx, ANISTAR_EINVAL, "crossing: segment or reference is not finite");
    double R = s->radius;
    /* 1. Clip [a, b] to the ball. Inside-ness of the ends uses the same test as side(). */
    double d[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double L2 = v3_dot(d, d);
    int ain = fs_in_ball(s, a), bin = fs_in_ball(s, b);
    if (L2 == 0) {
        if (!ain) return ANISTAR_OK;
        double f = fs_value(s, a);
        if (!isfinite(f)) return fail_nonfinite(ctx, "f", a);
        if (f == 0) {
            *found = 1;
            memcpy(x, a, 3 * sizeof(double));
        }
        return ANISTAR_OK;
    }
    double t0 = 0, t1 = 1;
    if (!ain || !bin) {
        double m[3] = {a[0] - s->center[0], a[1] - s->center[1], a[2] - s->center[2]};
        double B = v3_dot(m, d), C = v3_dot(m, m) - R * R;
        double disc = B * B - L2 * C;
        if (!(disc > 0)) return ANISTAR_OK;
        double sq = sqrt(disc);
        /* stable roots of L2 t^2 + 2 B t + C */
        double q = -(B + copysign(sq, B));
        double r1 = q / L2, r2 = q != 0 ? C / q : r1;
        double tin = fmin(r1, r2), tout = fmax(r1, r2);
        if (!ain) t0 = fmax(0.0, tin);
        if (!bin) t1 = fmin(1.0, tout);
        if (!(t0 < t1)) return ANISTAR_OK;
    }
    cr_chord c;
    c.s = s;
    c.ctx = ctx;
    for (int i = 0; i < 3; i++) {
        c.A[i] = ain ? a[i] : a[i] + t0 * d[i];
        c.B[i] = bin ? b[i] : a[i] + t1 * d[i];
        c.D[i] = c.B[i] - c.A[i];
    }
    c.len = v3_norm(c.D);
    c.evals = 0;
    if (!(c.len > 0)) {
        return ANISTAR_OK; /* the chord degenerated to a point on the sphere: f > 0 there */
    }
    double spacing = AS_CROSSING_SPACING * R;
    c.umin = fmin(0.25, 1e-7 * R / c.len);
    c.uval = fmin(1.0, spacing / 8 / c.len);
    int npieces = (int)ceil(c.len / spacing);
    if (npieces < 1) npieces = 1;
    if (npieces > 64) npieces = 64;

    cr_cands cs;
    cs.n = 0;
    memcpy(cs.ref, ref, sizeof cs.ref);

    /* 2. Base samples, analysed piece by piece. */
    double uprev = 0, fprev, dprev;
    int okprev;
    anistar_status st = cr_eval(&c, 0, &fprev, &dprev, &okprev);
    if (st) return st;
    if (fprev == 0 || (!ain && fprev < 0)) cr_add(&c, &cs, 0, 0, 0, 0);
    for (int i = 1; i <= npieces; i++) {
        double u = i == npieces ? 1.0 : (double)i / npieces, f, dd;
        int ok;
        st = cr_eval(&c, u, &f, &dd, &ok);
        if (st) return st;
        if (f == 0 || (i == npieces && !bin && f < 0)) cr_add(&c, &cs, u, 0, u, 0);
        cr_piece pc = {uprev, fprev, dprev, u, f, dd, okprev, ok};
        st = cr_piece_scan(&c, &cs, pc);
        if (st) return st;
        uprev = u;
        fprev = f;
        dprev = dd;
        okprev = ok;
    }
    if (cs.n == 0) return ANISTAR_OK;

    /* 3. Refine candidates nearest first; stop when the next cannot be nearer. */
    for (int i = 1; i < cs.n; i++) { /* insertion sort by dlo */
        cr_cand k = cs.c[i];
        int j = i - 1;
        while (j >= 0 && cs.c[j].dlo > k.dlo) {
            cs.c[j + 1] = cs.c[j];
            j--;
        }
        cs.c[j + 1] = k;
    }
    double tol_u = s->tol / c.len;
    double best = INFINITY, bx[3] = {0, 0, 0};
    for (int i = 0; i < cs.n; i++) {
        if (cs.c[i].dlo > best) break;
        double u = cs.c[i].ua;
        if (cs.c[i].ub > cs.c[i].ua) {
            st = cr_refine(&c, cs.c[i].ua, cs.c[i].fa, cs.c[i].ub, cs.c[i].fb, tol_u, &u);
            if (st) return st;
        }
        double p[3];
        cr_point(&c, u, p);
        double dist = sqrt(v3_dist2(p, ref));
        if (dist < best) {
            best = dist;
            memcpy(bx, p, sizeof bx);
        }
    }
    *found = 1;
    memcpy(x, bx, sizeof bx);
    return ANISTAR_OK;
}

/* ---- projection ----------------------------------------------------------------- */

/*
 * Newton steps along the gradient from x (in place) until |f|/|grad f| <= tol.
 * *ok = 1 on convergence; otherwise x is the best iterate. A non-finite value at the
 * start is an error; at trial points it only rejects the step.
 */
static anistar_status pj_newton(anistar_context *ctx, const as_surface *s, double x[3],
                                int *ok) {
    *ok = 0;
    double g[3];
    double f = s->ops->eval(s, x, 1, g, NULL);
    if (!isfinite(f)) return fail_nonfinite(ctx, "f", x);
    double maxstep = 0.25 * s->radius;
    for (int it = 0; it < 60; it++) {
        double gn2 = v3_dot(g, g);
        if (!(gn2 > 0) || !isfinite(gn2)) return ANISTAR_OK;
        double gn = sqrt(gn2);
        if (fabs(f) <= s->tol * gn) {
            *ok = 1;
            return ANISTAR_OK;
        }
        double len = fabs(f) / gn, lam = len > maxstep ? maxstep / len : 1.0;
        int accepted = 0;
        for (int k = 0; k < 40 && !accepted; k++, lam *= 0.5) {
            double y[3], gy[3];
            for (int i = 0; i < 3; i++) y[i] = x[i] - lam * f * g[i] / gn2;
            double fy = s->ops->eval(s, y, 1, gy, NULL);
            if (isfinite(fy) && fabs(fy) < fabs(f)) {
                memcpy(x, y, sizeof y);
                memcpy(g, gy, sizeof gy);
                f = fy;
                accepted = 1;
            }
        }
        if (!accepted) return ANISTAR_OK;
    }
    return ANISTAR_OK;
}

/* Bracketed fallback: the crossing nearest x along a few lines through x. */
static anistar_status pj_lines(anistar_context *ctx, const as_surface *s, double x[3],
                               int *found) {
    double dirs[5][3];
    int nd = 0;
    double g[3] = {0, 0, 0};
    double f = s->ops->eval(s, x, 1, g, NULL);
    if (!isfinite(f)) return fail_nonfinite(ctx, "f", x);
    double gn = v3_norm(g);
    if (gn > 0 && isfinite(gn)) {
        for (int i = 0; i < 3; i++) dirs[nd][i] = g[i] / gn;
        nd++;
    }
    double tc[3] = {s->center[0] - x[0], s->center[1] - x[1], s->center[2] - x[2]};
    double tn = v3_norm(tc);
    if (tn > 0) {
        for (int i = 0; i < 3; i++) dirs[nd][i] = tc[i] / tn;
        nd++;
    }
    for (int k = 0; k < 3; k++, nd++)
        for (int i = 0; i < 3; i++) dirs[nd][i] = i == k;
    double span = 2 * s->radius + sqrt(v3_dist2(x, s->center));
    for (int k = 0; k < nd; k++) {
        double a[3], b[3], q[3];
        for (int i = 0; i < 3; i++) {
            a[i] = x[i] - span * dirs[k][i];
            b[i] = x[i] + span * dirs[k][i];
        }
        anistar_status st = as_fsurface_crossing(ctx, s, a, b, x, found, q);
        if (st) return st;
        if (*found) {
            memcpy(x, q, sizeof q);
            return ANISTAR_OK;
        }
    }
    return ANISTAR_OK;
}

/* Onto S from y: Newton, then the bracketed fallback. *ok = 0 when nothing is found. */
static anistar_status pj_onto(anistar_context *ctx, const as_surface *s, double y[3], int *ok) {
    anistar_status st = pj_newton(ctx, s, y, ok);
    if (st || *ok) return st;
    st = pj_lines(ctx, s, y, ok);
    if (st || !*ok) return st;
    /* polish (the crossing is within tol along its line; make |f|/|grad f| <= tol) */
    int ok2;
    double z[3] = {y[0], y[1], y[2]};
    st = pj_newton(ctx, s, z, &ok2);
    if (st) return st;
    if (ok2) memcpy(y, z, sizeof z);
    return ANISTAR_OK;
}

anistar_status as_fsurface_project(anistar_context *ctx, const as_surface *s, const double p[3],
                                   double q[3]) {
    if (!s->ops->eval) return fail_no_function(ctx, s);
    if (!v3_finite(p)) return as_fail(ctx, ANISTAR_EINVAL, "project: point is not finite");
    double x[3] = {p[0], p[1], p[2]};
    int ok;
    anistar_status st = pj_onto(ctx, s, x, &ok);
    if (st) return st;
    if (!ok)
        return as_fail(ctx, ANISTAR_ENOSURFACE,
                       "project: no zero of f found from (%.17g, %.17g, %.17g) (along the "
                       "gradient, toward the center, along the axes)",
                       p[0], p[1], p[2]);
    /* Closest point: Newton steps in the tangent plane, t = (I + d W)^-1 v_t (W the
     * curvature matrix at x, d the normal offset of p), re-projected onto S; a step is
     * kept when it brings x nearer p, or keeps the distance and shrinks the tangential
     * residual (distances alone cannot resolve it below sqrt(eps)). */
    double dbest = sqrt(v3_dist2(p, x)), vtn = INFINITY;
    for (int it = 0; it < 100; it++) {
        as_surface_frame fr;
        if (as_fsurface_frame(NULL, s, x, &fr) || fr.singular) break;
        double v[3] = {p[0] - x[0], p[1] - x[1], p[2] - x[2]};
        double vn = v3_dot(v, fr.n), vt[3];
        for (int i = 0; i < 3; i++) vt[i] = v[i] - vn * fr.n[i];
        vtn = v3_norm(vt);
        if (vtn <= 0.25 * s->tol) break;
        double t[3] = {0, 0, 0};
        for (int j = 0; j < 2; j++) {
            const double *d = fr.d + 3 * j;
            double den = 1 + vn * fr.k[j], c = v3_dot(vt, d);
            if (den > 0.25) c /= den; /* beyond a focal point: plain gradient step */
            for (int i = 0; i < 3; i++) t[i] += c * d[i];
        }
        int improved = 0;
        double lam = 1;
        for (int k = 0; k < 30 && !improved; k++, lam *= 0.5) {
            double y[3], gy[3];
            for (int i = 0; i < 3; i++) y[i] = x[i] + lam * t[i];
            int ok3;
            st = pj_newton(ctx, s, y, &ok3);
            if (st) return st;
            if (!ok3) continue;
            double dy = sqrt(v3_dist2(p, y));
            double fy = s->ops->eval(s, y, 1, gy, NULL), gyn = v3_norm(gy);
            if (!isfinite(fy) || !(gyn > 0) || !isfinite(gyn)) continue;
            double w[3] = {p[0] - y[0], p[1] - y[1], p[2] - y[2]}, wn = v3_dot(w, gy) / gyn;
            double wt[3] = {w[0] - wn * gy[0] / gyn, w[1] - wn * gy[1] / gyn,
                            w[2] - wn * gy[2] / gyn};
            if (dy < dbest || (dy <= dbest * (1 + 1e-12) && v3_norm(wt) < 0.5 * vtn)) {
                dbest = fmin(dy, dbest);
                memcpy(x, y, sizeof y);
                improved = 1;
            }
        }
        if (!improved) break;
    }
    memcpy(q, x, sizeof x);
    return ANISTAR_OK;
}

/* ---- local frame ---------------------------------------------------------------- */

anistar_status as_fsurface_frame(anistar_context *ctx, const as_surface *s, const double p[3],
                                 as_surface_frame *fr) {
    memset(fr, 0, sizeof *fr);
    double f, g[3], h[6];
    anistar_status st = as_surface_eval(ctx, s, p, 2, &f, g, h);
    if (st) return st;
    double gn = v3_norm(g);
    fr->gnorm = gn;
    if (!(gn > DBL_MIN)) {
        fr->singular = 1;
        return ANISTAR_OK;
    }
    double n[3] = {g[0] / gn, g[1] / gn, g[2] / gn};
    /* tangent basis: t1 orthogonal to n from the axis least aligned with n; t2 = n x t1 */
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(n[i]) < fabs(n[k])) k = i;
    double e[3] = {0, 0, 0}, t1[3], t2[3];
    e[k] = 1;
    v3_cross(n, e, t1);
    double t1n = v3_norm(t1);
    for (int i = 0; i < 3; i++) t1[i] /= t1n;
    v3_cross(n, t1, t2);
    /* W = T^T H T / |grad f| (2x2) */
    double h1[3], h2[3];
    sym_mul(h, t1, h1);
    sym_mul(h, t2, h2);
    double wa = v3_dot(t1, h1) / gn, wb = 0.5 * (v3_dot(t1, h2) + v3_dot(t2, h1)) / gn,
           wc = v3_dot(t2, h2) / gn;
    double mean = 0.5 * (wa + wc), hd = 0.5 * (wa - wc), r = hypot(hd, wb);
    double th = 0.5 * atan2(2 * wb, wa - wc);
    double cs = cos(th), sn = sin(th);
    fr->k[0] = mean + r;
    fr->k[1] = mean - r;
    double d1[3], d2[3];
    for (int i = 0; i < 3; i++) d1[i] = cs * t1[i] + sn * t2[i];
    v3_cross(n, d1, d2);
    memcpy(fr->n, n, sizeof n);
    memcpy(fr->d, d1, sizeof d1);
    memcpy(fr->d + 3, d2, sizeof d2);
    if (!isfinite(fr->k[0]) || !isfinite(fr->k[1]))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "curvature is not finite at (%.17g, %.17g, %.17g)", p[0], p[1], p[2]);
    return ANISTAR_OK;
}

/* ---- initial points (sampling) -------------------------------------------------- */

/* One grid level. Vertex (i, j, k) is o + h (i, j, k), index i + nv (j + nv k). */
typedef struct sm_grid {
    size_t n, nv, count;
    double h, o[3];
    float *f;     /* values (FLT_MAX beyond the sphere) */
    int8_t *sg;   /* -1 inside (f < 0), +1 otherwise (beyond the sphere included) */
    int32_t *uf;  /* union-find parents */
    int8_t *ball; /* 1 if the vertex is inside the ball */
} sm_grid;

/* A grid edge with a sign change: its lower vertex, axis and the (inside, outside) region
 * roots it joins. */
typedef struct sm_edge {
    uint32_t v;
    uint32_t rin, rout;
    uint8_t axis;
} sm_edge;

/* Sub-grid components found by descent: one surface point each. */
typedef struct sm_extra {
    double p[3];     /* the point on S */
    double probe[3]; /* the point beyond S the descent reached (for de-duplication) */
} sm_extra;

typedef struct sm_state {
    anistar_context *ctx;
    const as_surface *s;
    sm_grid g;
    sm_edge *edges;
    size_t nedges, capedges;
    sm_extra *extra;
    size_t nextra, capextra;
    size_t npairs; /* distinct (rin, rout) pairs */
} sm_state;

static void sm_grid_free(anistar_context *ctx, sm_grid *g) {
    as_free(ctx, g->f, g->count * sizeof(float));
    as_free(ctx, g->sg, g->count);
    as_free(ctx, g->uf, g->count * sizeof(int32_t));
    as_free(ctx, g->ball, g->count);
    g->f = NULL;
    g->sg = NULL;
    g->uf = NULL;
    g->ball = NULL;
}

static void sm_state_free(sm_state *st) {
    sm_grid_free(st->ctx, &st->g);
    as_free(st->ctx, st->edges, st->capedges * sizeof(sm_edge));
    as_free(st->ctx, st->extra, st->capextra * sizeof(sm_extra));
    st->edges = NULL;
    st->extra = NULL;
    st->nedges = st->capedges = st->nextra = st->capextra = 0;
}

static inline void sm_vertex(const sm_grid *g, size_t idx, double p[3]) {
    size_t i = idx % g->nv, j = (idx / g->nv) % g->nv, k = idx / (g->nv * g->nv);
    p[0] = g->o[0] + g->h * (double)i;
    p[1] = g->o[1] + g->h * (double)j;
    p[2] = g->o[2] + g->h * (double)k;
}

static inline int32_t uf_find(int32_t *uf, int32_t x) {
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}
static inline void uf_union(int32_t *uf, int32_t a, int32_t b) {
    a = uf_find(uf, a);
    b = uf_find(uf, b);
    if (a < b) uf[b] = a;
    else if (b < a) uf[a] = b;
}

static int sm_edge_cmp(const void *pa, const void *pb) {
    const sm_edge *a = pa, *b = pb;
    if (a->rin != b->rin) return a->rin < b->rin ? -1 : 1;
    if (a->rout != b->rout) return a->rout < b->rout ? -1 : 1;
    if (a->v != b->v) return a->v < b->v ? -1 : 1;
    return (a->axis > b->axis) - (a->axis < b->axis);
}

/* Where the edge from inside-ball vertex p to beyond-ball vertex q meets the sphere. */
static void sm_sphere_point(const as_surface *s, const double p[3], const double q[3],
                            double x[3]) {
    double d[3] = {q[0] - p[0], q[1] - p[1], q[2] - p[2]};
    double m[3] = {p[0] - s->center[0], p[1] - s->center[1], p[2] - s->center[2]};
    double A = v3_dot(d, d), B = v3_dot(m, d), C = v3_dot(m, m) - s->radius * s->radius;
    double disc = B * B - A * C;
    double t = disc > 0 ? (-B + sqrt(disc)) / A : 1.0;
    if (!(t >= 0)) t = 0;
    if (t > 1) t = 1;
    for (int i = 0; i < 3; i++) x[i] = p[i] + t * d[i];
}

/*
 * Descend (sg = +1) or ascend (sg = -1) f from grid vertex x0 within radius 2h looking
 * for a point where sg * f < 0. *found = 1 and the point in y on success.
 */
static anistar_status sm_descend(sm_state *st, const double x0[3], int sg, int *found,
                                 double y[3]) {
    const as_surface *s = st->s;
    double h = st->g.h, x[3] = {x0[0], x0[1], x0[2]}, g[3];
    *found = 0;
    double f = s->ops->eval(s, x, 1, g, NULL);
    if (!isfinite(f)) return fail_nonfinite(st->ctx, "f", x);
    for (int it = 0; it < 40; it++) {
        if (sg * f < 0) {
            *found = 1;
            memcpy(y, x, sizeof x);
            return ANISTAR_OK;
        }
        double gn2 = v3_dot(g, g);
        if (!(gn2 > 0) || !isfinite(gn2)) return ANISTAR_OK;
        double gn = sqrt(gn2);
        int accepted = 0;
        /* try Newton toward f = 0 (slightly past it), then gradient steps */
        for (int k = 0; k < 12 && !accepted; k++) {
            double step[3], len;
            if (k == 0) {
                for (int i = 0; i < 3; i++) step[i] = -1.5 * f * g[i] / gn2;
            } else {
                double a = sg * h * ldexp(1.0, -(k - 1));
                for (int i = 0; i < 3; i++) step[i] = -a * g[i] / gn;
            }
            len = v3_norm(step);
            if (len > h) {
                for (int i = 0; i < 3; i++) step[i] *= h / len;
            }
            double z[3], gz[3];
            for (int i = 0; i < 3; i++) z[i] = x[i] + step[i];
            if (v3_dist2(z, x0) > 4 * h * h) continue;
            double fz = s->ops->eval(s, z, 1, gz, NULL);
            if (!isfinite(fz)) return fail_nonfinite(st->ctx, "f", z);
            if (sg * fz < sg * f) {
                memcpy(x, z, sizeof z);
                memcpy(g, gz, sizeof gz);
                f = fz;
                accepted = 1;
            }
        }
        if (!accepted) return ANISTAR_OK;
    }
    if (sg * f < 0) {
        *found = 1;
        memcpy(y, x, sizeof x);
    }
    return ANISTAR_OK;
}

/* Build one grid level and count components (pairs + sub-grid components). */
static anistar_status sm_level(sm_state *st, size_t n) {
    anistar_context *ctx = st->ctx;
    const as_surface *s = st->s;
    sm_grid *g = &st->g;
    sm_grid_free(ctx, g);
    st->nedges = 0;
    st->nextra = 0;
    st->npairs = 0;
    g->n = n;
    g->nv = n + 1;
    g->count = g->nv * g->nv * g->nv;
    g->h = 2 * s->radius / (double)n;
    for (int i = 0; i < 3; i++) g->o[i] = s->center[i] - s->radius;
    g->f = as_alloc_array(ctx, g->count, sizeof(float));
    g->sg = as_alloc(ctx, g->count);
    g->uf = as_alloc_array(ctx, g->count, sizeof(int32_t));
    g->ball = as_alloc(ctx, g->count);
    if (!g->f || !g->sg || !g->uf || !g->ball)
        return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory (grid of %zu^3)", g->nv);
    /* 1. values and signs */
    size_t nv = g->nv;
    for (size_t idx = 0; idx < g->count; idx++) {
        double p[3];
        sm_vertex(g, idx, p);
        g->uf[idx] = (int32_t)idx;
        if (!fs_in_ball(s, p)) {
            g->ball[idx] = 0;
            g->sg[idx] = 1;
            g->f[idx] = FLT_MAX;
            continue;
        }
        double f = fs_value(s, p);
        if (!isfinite(f)) return fail_nonfinite(ctx, "f", p);
        g->ball[idx] = 1;
        g->sg[idx] = f < 0 ? -1 : 1;
        g->f[idx] = f > FLT_MAX ? FLT_MAX : (f < -FLT_MAX ? -FLT_MAX : (float)f);
    }
    /* 2. regions, and the sphere check (f < 0 on the sphere: S is not inside it) */
    size_t stride[3] = {1, nv, nv * nv};
    for (size_t idx = 0; idx < g->count; idx++) {
        size_t c[3] = {idx % nv, (idx / nv) % nv, idx / (nv * nv)};
        for (int ax = 0; ax < 3; ax++) {
            if (c[ax] + 1 >= nv) continue;
            size_t jdx = idx + stride[ax];
            if (g->sg[idx] == g->sg[jdx]) {
                uf_union(g->uf, (int32_t)idx, (int32_t)jdx);
                continue;
            }
            if (g->ball[idx] != g->ball[jdx]) {
                size_t in = g->ball[idx] ? idx : jdx, outv = g->ball[idx] ? jdx : idx;
                double p[3], q[3], x[3];
                sm_vertex(g, in, p);
                sm_vertex(g, outv, q);
                sm_sphere_point(s, p, q, x);
                double fx = fs_value(s, x);
                if (!isfinite(fx)) return fail_nonfinite(ctx, "f", x);
                if (fx < 0)
                    return as_fail(ctx, ANISTAR_EINVAL,
                                   "f < 0 at (%.9g, %.9g, %.9g) on the bounding sphere: the "
                                   "surface must lie strictly inside the bounding sphere "
                                   "(enlarge its radius)",
                                   x[0], x[1], x[2]);
            }
        }
    }
    /* 3. sign-change edges and their (inside, outside) region pairs */
    for (size_t idx = 0; idx < g->count; idx++) {
        size_t c[3] = {idx % nv, (idx / nv) % nv, idx / (nv * nv)};
        for (int ax = 0; ax < 3; ax++) {
            if (c[ax] + 1 >= nv) continue;
            size_t jdx = idx + stride[ax];
            if (g->sg[idx] == g->sg[jdx]) continue;
            if (as_grow(ctx, (void **)&st->edges, &st->capedges, st->nedges + 1, sizeof(sm_edge)))
                return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory (edges)");
            size_t in = g->sg[idx] < 0 ? idx : jdx, outv = g->sg[idx] < 0 ? jdx : idx;
            sm_edge e = {(uint32_t)idx, (uint32_t)uf_find(g->uf, (int32_t)in),
                         (uint32_t)uf_find(g->uf, (int32_t)outv), (uint8_t)ax};
            st->edges[st->nedges++] = e;
        }
    }
    if (st->nedges) qsort(st->edges, st->nedges, sizeof(sm_edge), sm_edge_cmp);
    for (size_t i = 0; i < st->nedges; i++)
        if (i == 0 || st->edges[i].rin != st->edges[i - 1].rin ||
            st->edges[i].rout != st->edges[i - 1].rout)
            st->npairs++;
    /* 4. sub-grid components from local extrema */
    size_t descents = 0;
    for (size_t idx = 0; idx < g->count && descents < 4096; idx++) {
        size_t c[3] = {idx % nv, (idx / nv) % nv, idx / (nv * nv)};
        if (!g->ball[idx]) continue;
        int interior = 1, sgv = g->sg[idx], extremum = 1;
        float fv = g->f[idx];
        for (int ax = 0; ax < 3 && interior && extremum; ax++) {
            if (c[ax] == 0 || c[ax] + 1 >= nv) {
                interior = 0;
                break;
            }
            size_t nb[2] = {idx - stride[ax], idx + stride[ax]};
            for (int m = 0; m < 2; m++) {
                if (!g->ball[nb[m]] || g->sg[nb[m]] != sgv) {
                    extremum = 0;
                    break;
                }
                if (sgv > 0 ? g->f[nb[m]] < fv : g->f[nb[m]] > fv) extremum = 0;
            }
        }
        if (!interior || !extremum) continue;
        descents++;
        double x0[3], y[3];
        int found;
        sm_vertex(g, idx, x0);
        anistar_status rs = sm_descend(st, x0, sgv, &found, y);
        if (rs) return rs;
        if (!found) continue;
        /* skip if the cell reached already has a grid vertex of y's sign */
        int seen = 0;
        size_t cc[3];
        for (int i = 0; i < 3; i++) {
            double t = floor((y[i] - g->o[i]) / g->h);
            if (t < 0) t = 0;
            if (t > (double)(n - 1)) t = (double)(n - 1);
            cc[i] = (size_t)t;
        }
        for (int corner = 0; corner < 8 && !seen; corner++) {
            size_t v = (cc[0] + (corner & 1)) + nv * ((cc[1] + ((corner >> 1) & 1)) +
                                                      nv * (cc[2] + ((corner >> 2) & 1)));
            if (g->sg[v] == -sgv) seen = 1;
        }
        for (size_t e = 0; e < st->nextra && !seen; e++)
            if (v3_dist2(st->extra[e].probe, y) < g->h * g->h) seen = 1;
        if (seen) continue;
        int hit;
        double xs[3];
        rs = as_fsurface_crossing(ctx, s, x0, y, y, &hit, xs);
        if (rs) return rs;
        if (!hit) continue;
        if (as_grow(ctx, (void **)&st->extra, &st->capextra, st->nextra + 1, sizeof(sm_extra)))
            return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        memcpy(st->extra[st->nextra].p, xs, sizeof xs);
        memcpy(st->extra[st->nextra].probe, y, sizeof y);
        st->nextra++;
    }
    return ANISTAR_OK;
}

/* Pick up to q edges of edges[0..m) by farthest-point sampling of their midpoints (among
 * at most 8 q candidates, a regular stride through the list) and append their crossings to
 * out. work holds 4 m doubles. */
static anistar_status sm_pick(sm_state *st, const sm_edge *edges, size_t m, size_t q,
                              int32_t comp, double *work, as_point_sample *out) {
    const sm_grid *g = &st->g;
    size_t stride = m > 8 * q ? m / (8 * q) : 1;
    size_t nc = (m + stride - 1) / stride;
    if (q > nc) q = nc;
    for (size_t i = 0; i < nc; i++) {
        const sm_edge *e = &edges[i * stride];
        double *w = work + 4 * i;
        sm_vertex(g, e->v, w);
        w[e->axis] += 0.5 * g->h;
        w[3] = INFINITY;
    }
    size_t cur = 0;
    for (size_t pick = 0; pick < q; pick++) {
        const sm_edge *e = &edges[cur * stride];
        double a[3], b[3], mid[3] = {work[4 * cur], work[4 * cur + 1], work[4 * cur + 2]}, x[3];
        sm_vertex(g, e->v, a);
        memcpy(b, a, sizeof a);
        b[e->axis] += g->h;
        int hit;
        anistar_status rs = as_fsurface_crossing(st->ctx, st->s, a, b, mid, &hit, x);
        if (rs) return rs;
        if (hit) {
            memcpy(out->points + 3 * out->n, x, sizeof x);
            out->component[out->n] = comp;
            out->n++;
        }
        work[4 * cur + 3] = -1;
        /* update distances, choose the farthest */
        size_t next = 0;
        double far = -1;
        for (size_t i = 0; i < nc; i++) {
            double *w = work + 4 * i;
            if (w[3] < 0) continue;
            double d = v3_dist2(w, mid);
            if (d < w[3]) w[3] = d;
            if (w[3] > far) {
                far = w[3];
                next = i;
            }
        }
        if (far < 0) break;
        cur = next;
    }
    return ANISTAR_OK;
}

anistar_status as_fsurface_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                  as_point_sample *out) {
    memset(out, 0, sizeof *out);
    if (!s->ops->eval) return fail_no_function(ctx, s);
    if (max_points == 0) max_points = 64;
    sm_state st;
    memset(&st, 0, sizeof st);
    st.ctx = ctx;
    st.s = s;
    const size_t levels[3] = {32, 64, 128};
    size_t prev = (size_t)-1, ncomp = 0;
    anistar_status rs = ANISTAR_OK;
    for (int l = 0; l < 3; l++) {
        rs = sm_level(&st, levels[l]);
        if (rs) goto done;
        ncomp = st.npairs + st.nextra;
        if (ncomp > 0 && ncomp == prev) break;
        prev = ncomp;
    }
    if (ncomp == 0) {
        rs = as_fail(ctx, ANISTAR_ENOSURFACE,
                     "no surface found inside the bounding sphere (center %g %g %g, radius "
                     "%g): f keeps one sign on a %zu^3 grid (spacing %g) and near its local "
                     "extrema",
                     s->center[0], s->center[1], s->center[2], s->radius, st.g.nv, st.g.h);
        goto done;
    }
    /* Quotas: proportional to the edge count, at least one per component. The points go
     * to temporaries of capacity `total`, then to arrays of exactly n. */
    size_t total = max_points + ncomp;
    as_point_sample tmp;
    memset(&tmp, 0, sizeof tmp);
    tmp.points = as_alloc_array(ctx, total, 3 * sizeof(double));
    tmp.component = as_alloc_array(ctx, total, sizeof(int32_t));
    double *work = st.nedges ? as_alloc_array(ctx, st.nedges, 4 * sizeof(double)) : NULL;
    if (tmp.points && tmp.component && (work || !st.nedges)) {
        int32_t comp = 0;
        for (size_t i = 0; i < st.nedges && !rs;) {
            size_t j = i;
            while (j < st.nedges && st.edges[j].rin == st.edges[i].rin &&
                   st.edges[j].rout == st.edges[i].rout)
                j++;
            size_t m = j - i;
            size_t q = (size_t)((double)max_points * (double)m / (double)st.nedges);
            if (q < 1) q = 1;
            rs = sm_pick(&st, st.edges + i, m, q, comp++, work, &tmp);
            i = j;
        }
        for (size_t e = 0; e < st.nextra && !rs; e++) {
            memcpy(tmp.points + 3 * tmp.n, st.extra[e].p, 3 * sizeof(double));
            tmp.component[tmp.n++] = comp++;
        }
        if (!rs && tmp.n == 0)
            rs = as_fail(ctx, ANISTAR_EINTERNAL, "sampling: no crossing could be refined");
        if (!rs) {
            out->points = as_alloc_array(ctx, tmp.n, 3 * sizeof(double));
            out->component = as_alloc_array(ctx, tmp.n, sizeof(int32_t));
            if (out->points && out->component) {
                memcpy(out->points, tmp.points, tmp.n * 3 * sizeof(double));
                memcpy(out->component, tmp.component, tmp.n * sizeof(int32_t));
                out->n = tmp.n;
                out->ncomponents = (size_t)comp;
                out->spacing = st.g.h;
            } else {
                as_free(ctx, out->points, tmp.n * 3 * sizeof(double));
                as_free(ctx, out->component, tmp.n * sizeof(int32_t));
                rs = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
            }
        }
    } else {
        rs = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    }
    as_free(ctx, work, st.nedges * 4 * sizeof(double));
    as_free(ctx, tmp.points, total * 3 * sizeof(double));
    as_free(ctx, tmp.component, total * sizeof(int32_t));
done:
    sm_state_free(&st);
    if (rs) memset(out, 0, sizeof *out);
    return rs;
}
