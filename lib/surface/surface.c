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
#include "pool.h"
#include "geom/kdtree.h"

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
    /* design: and never below a few ulps of the coordinates: a unit sphere centred at
     * (1e7, 0, 0) has points 1.9e-9 apart, so |f|/|grad f| <= 1e-12 could not be met,
     * projections failed and the feature size and estimate went wrong (2,319 feature
     * insertions and an estimate of 2.1e6 vertices for 829; refused at 1e8). Around the
     * origin (a centre within about 560 radii) the tolerance is unchanged. */
    double cmax = fmax(fabs(center[0]), fmax(fabs(center[1]), fabs(center[2])));
    s->tol = fmax(AS_SURFACE_REL_TOL * radius, AS_SURFACE_ULP_TOL * (cmax + radius));
    s->basis = NULL;
    return ANISTAR_OK;
}

static void sb_free(anistar_context *ctx, struct as_sbasis *b);

void as_surface_free(as_surface *s) {
    if (!s) return;
    sb_free(s->ctx, s->basis);
    s->basis = NULL;
    s->ops->destroy(s);
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
    as_free(ctx, smp->area, smp->ncomponents * sizeof(double));
    memset(smp, 0, sizeof *smp);
}

anistar_status as_surface_sample_weights(anistar_context *ctx, const as_point_sample *smp,
                                         double *w) {
    const size_t nc = smp->ncomponents ? smp->ncomponents : 1;
    size_t *count = as_alloc_array(ctx, nc, sizeof *count);
    if (!count) return as_fail(ctx, ANISTAR_ENOMEM, "surface: out of memory (sample weights)");
    memset(count, 0, nc * sizeof *count);
    for (size_t i = 0; i < smp->n; i++) count[smp->component[i]]++;
    for (size_t i = 0; i < smp->n; i++)
        w[i] = smp->area[smp->component[i]] / (double)count[smp->component[i]];
    as_free(ctx, count, nc * sizeof *count);
    return ANISTAR_OK;
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
static anistar_status cr_eval_at(cr_chord *c, const double p[3], double *f, double *d,
                                 int *dok) {
    double g[3] = {0, 0, 0};
    c->evals++;
    double v = c->s->ops->eval(c->s, p, 1, g, NULL);
    if (!isfinite(v)) return fail_nonfinite(c->ctx, "f", p);
    *f = v;
    *d = v3_dot(g, c->D);
    *dok = isfinite(*d);
    return ANISTAR_OK;
}

/* The same at p(u). */
static anistar_status cr_eval(cr_chord *c, double u, double *f, double *d, int *dok) {
    double p[3];
    cr_point(c, u, p);
    return cr_eval_at(c, p, f, d, dok);
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
    int step, seq; /* when a scan of the chord from A to B would have recorded it */
} cr_cand;

typedef struct cr_cands {
    cr_cand c[CR_MAX_CAND];
    int n;
    int step, seq; /* the key of the next candidate added */
    double ref[3];
} cr_cands;

/* The order in which candidates are refined: by distance, then in the order a scan of the
 * chord from A to B records them. */
static inline int cr_cand_before(const cr_cand *a, const cr_cand *b) {
    if (a->dlo != b->dlo) return a->dlo < b->dlo;
    if (a->step != b->step) return a->step < b->step;
    return a->seq < b->seq;
}

/* The distance from ref to the segment [pa, pb]. */
static inline double cr_seg_dist(const double pa[3], const double pb[3], const double ref[3]) {
    double d[3], w[3];
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

/* The distance from ref to the piece [p(ua), p(ub)]. */
static double cr_piece_dist(const cr_chord *c, const double ref[3], double ua, double ub) {
    double pa[3], pb[3];
    cr_point(c, ua, pa);
    cr_point(c, ub, pb);
    return cr_seg_dist(pa, pb, ref);
}

/* Add a candidate; when full, it replaces the farthest one if it is nearer. */
static void cr_add(const cr_chord *c, cr_cands *cs, double ua, double fa, double ub, double fb) {
    cr_cand k = {ua, ub, fa, fb, cr_piece_dist(c, cs->ref, ua, ub), cs->step, cs->seq++};
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

/*
 * The base pieces 1..n (piece i between the base points bp + 3(i-1) and bp + 3i) by their
 * distance to ref, ties by index: pd[i] and order[0..n-1] (full = 1: by index only).
 * design: the pieces lie on a line, so their distances usually fall strictly to the
 *   first minimum m and then rise (ties allowed): the two runs are merged from m
 *   outwards, a tie going to the left piece (the lower index), which is the sort by
 *   (distance, index). Any other sequence is sorted by insertion, as before: both give
 *   the one order of the distinct keys (distance, index), and the distances are the same
 *   numbers (cr_seg_dist on the same points as cr_piece_dist).
 */
static void cr_order_pieces(const double *bp, int n, const double ref[3], int full, double *pd,
                            int *order) {
    int m = 1;
    for (int i = 1; i <= n; i++) {
        pd[i] = cr_seg_dist(bp + 3 * (i - 1), bp + 3 * i, ref);
        if (pd[i] < pd[m]) m = i;
    }
    int runs = !full;
    for (int i = 2; i <= m && runs; i++) runs = pd[i - 1] > pd[i];
    for (int i = m + 1; i <= n && runs; i++) runs = pd[i] >= pd[i - 1];
    if (runs) {
        int l = m - 1, r = m + 1, k = 0;
        order[k++] = m;
        while (l >= 1 || r <= n)
            order[k++] = r > n || (l >= 1 && pd[l] <= pd[r]) ? l-- : r++;
        return;
    }
    for (int i = 1; i <= n; i++) { /* insertion sort */
        int j = i - 1;
        while (j > 0 && !full && pd[order[j - 1]] > pd[i]) {
            order[j] = order[j - 1];
            j--;
        }
        order[j] = i;
    }
}

/* The crossing; full = 1 scans every piece from A to B before refining (the order of the
 * original implementation, kept to test that the nearest-first order gives the same
 * answers), full = 0 scans the pieces nearest ref first (step 2-3 below). */
static anistar_status fs_crossing(anistar_context *ctx, const as_surface *s, const double a[3],
                                  const double b[3], const double ref[3], int *found,
                                  double x[3], int full) {
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
    /* design: the base samples lie on a lattice of the chord's LINE, not of the chord: at
     * the points o + k spacing w (w the line's direction with its largest component
     * positive, o the foot of the ball's center), plus the chord's two ends. Which of two
     * crossings closer than a piece the scan sees depends on where the samples fall; with
     * samples placed from the chord's ends, two segments of one line (a facet's dual
     * segment in the mesher's star and in an independent check, which differ in extent)
     * could report different crossings of a close pair and size the facet differently
     * (the graded brain: one within hmin, the other 1.05 r0). On the lattice, pieces
     * that both segments hold whole are the same pieces. The clipped chord spans at most
     * the ball's diameter, 64 spacings: at most 65 pieces. */
    enum { CR_MAX_PIECES = 66 };
    double ub[CR_MAX_PIECES + 1];
    int npieces = 0;
    {
        double w[3] = {c.D[0] / c.len, c.D[1] / c.len, c.D[2] / c.len};
        int big = fabs(w[0]) >= fabs(w[1]) ? (fabs(w[0]) >= fabs(w[2]) ? 0 : 2)
                                           : (fabs(w[1]) >= fabs(w[2]) ? 1 : 2);
        double sg = w[big] < 0 ? -1.0 : 1.0;
        for (int i = 0; i < 3; i++) w[i] *= sg;
        double ca[3] = {c.A[0] - s->center[0], c.A[1] - s->center[1], c.A[2] - s->center[2]};
        double sa = v3_dot(ca, w), sb = sa + sg * c.len; /* the ends' line coordinates */
        double lo = fmin(sa, sb), hi = fmax(sa, sb);
        double k0 = floor(lo / spacing) + 1, k1 = ceil(hi / spacing) - 1;
        ub[npieces++] = 0; /* then the lattice points inside, from A towards B */
        if (k0 <= k1) {
            long n = (long)(k1 - k0) + 1;
            if (n > CR_MAX_PIECES - 1) n = CR_MAX_PIECES - 1;
            for (long j = 0; j < n; j++) {
                double k = sg > 0 ? k0 + (double)j : k1 - (double)j;
                double u = (k * spacing - sa) / (sb - sa);
                if (u > ub[npieces - 1] && u < 1) ub[npieces++] = u;
            }
        }
        ub[npieces] = 1;
    }

    cr_cands cs;
    cs.n = 0;
    cs.step = cs.seq = 0;
    memcpy(cs.ref, ref, sizeof cs.ref);

    /*
     * 2-3. Base pieces scanned nearest ref first, candidates refined as soon as no piece
     * left can hold a nearer one.
     * design: this computes what scanning the whole chord from A to B and then refining
     * the candidates by increasing distance (stopping at the first farther than the best
     * root) computed — the answer the mesher needs is the crossing nearest the dual
     * segment's reference point (the facet's circumcenter, on the segment's line), so the
     * far pieces were sampled for nothing: on the skull with the defaults a crossing
     * sampled 8.6 base points on average (up to 51) and now samples about 3 (issue 13).
     * Why the result is the same: a piece's scan depends only on its two end samples,
     * whatever the order of the pieces, and every candidate of piece i lies at distance
     * >= pd[i] (the piece's own distance to ref). Once every piece with pd < T has been
     * scanned, every candidate nearer than T is known, and the refinement loop can run
     * over them in the full scan's order: by distance, ties in the order the full scan
     * would have recorded them (key: step, then rank within the step). It ends when a
     * candidate is farther than the best root, or when the best root is nearer than
     * every unscanned piece (all later candidates are then farther: the full loop would
     * stop there too). Two limits can still make the answers differ: more than
     * CR_MAX_CAND candidates (the full scan drops its farthest ones), and a chord using
     * the whole evaluation budget (the budget then stops the splits of other pieces).
     * Neither occurs on the test inputs (outputs byte-identical); a non-finite f where
     * the search never looks is no longer reported.
     */
    double bf[CR_MAX_PIECES + 1], bd[CR_MAX_PIECES + 1], pd[CR_MAX_PIECES + 1];
    double bp[CR_MAX_PIECES + 1][3]; /* the base points p(ub[k]) */
    int bok[CR_MAX_PIECES + 1], order[CR_MAX_PIECES];
    unsigned char have[CR_MAX_PIECES + 1], done[CR_MAX_CAND];
    memset(have, 0, sizeof have);
    memset(done, 0, sizeof done);
#define CR_BASE_U(k) (ub[k])
    for (int k = 0; k <= npieces; k++) cr_point(&c, CR_BASE_U(k), bp[k]);
    cr_order_pieces(&bp[0][0], npieces, ref, full, pd, order);
    double tol_u = s->tol / c.len;
    double best = INFINITY, bx[3] = {0, 0, 0};
    int next = 0; /* order[next] is the nearest piece not scanned */
    anistar_status st = ANISTAR_OK;
    for (;;) {
        /* Scan the next group of pieces at the same distance. */
        if (next < npieces) {
            double dgroup = pd[order[next]];
            while (next < npieces && (full || pd[order[next]] == dgroup)) {
                int i = order[next++];
                for (int k = i - 1; k <= i; k++) { /* the piece's end samples */
                    if (have[k]) continue;
                    double u = CR_BASE_U(k);
                    if ((st = cr_eval_at(&c, bp[k], &bf[k], &bd[k], &bok[k]))) return st;
                    have[k] = 1;
                    /* the full scan recorded an end zero (or an inside end on the
                     * sphere) at its step k, before piece k's candidates */
                    int inside_end = (k == 0 && !ain) || (k == npieces && !bin);
                    if (bf[k] == 0 || (inside_end && bf[k] < 0)) {
                        cs.step = k;
                        cs.seq = 0;
                        cr_add(&c, &cs, u, 0, u, 0);
                    }
                }
                cs.step = i;
                cs.seq = 1;
                cr_piece pc = {CR_BASE_U(i - 1), bf[i - 1], bd[i - 1], CR_BASE_U(i), bf[i],
                               bd[i], bok[i - 1], bok[i]};
                if ((st = cr_piece_scan(&c, &cs, pc))) return st;
            }
        }
        double horizon = next < npieces ? pd[order[next]] : INFINITY;
        /* Refine the known candidates nearer than every unscanned piece, in order. */
        for (;;) {
            int kmin = -1;
            for (int k = 0; k < cs.n; k++) {
                if (done[k] || !(cs.c[k].dlo < horizon || horizon == INFINITY)) continue;
                if (kmin < 0 || cr_cand_before(&cs.c[k], &cs.c[kmin])) kmin = k;
            }
            if (kmin < 0) break;
            if (cs.c[kmin].dlo > best) goto finish; /* the full loop stopped here */
            done[kmin] = 1;
            double u = cs.c[kmin].ua;
            if (cs.c[kmin].ub > cs.c[kmin].ua) {
                st = cr_refine(&c, cs.c[kmin].ua, cs.c[kmin].fa, cs.c[kmin].ub, cs.c[kmin].fb,
                               tol_u, &u);
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
        if (horizon == INFINITY || best < horizon) break;
    }
finish:
#undef CR_BASE_U
    if (best == INFINITY) return ANISTAR_OK;
    *found = 1;
    memcpy(x, bx, sizeof bx);
    return ANISTAR_OK;
}

anistar_status as_fsurface_crossing(anistar_context *ctx, const as_surface *s,
                                    const double a[3], const double b[3], const double ref[3],
                                    int *found, double x[3]) {
    return fs_crossing(ctx, s, a, b, ref, found, x, 0);
}

anistar_status as_fsurface_crossing_full(anistar_context *ctx, const as_surface *s,
                                         const double a[3], const double b[3],
                                         const double ref[3], int *found, double x[3]) {
    return fs_crossing(ctx, s, a, b, ref, found, x, 1);
}

/* ---- projection ----------------------------------------------------------------- */

/*
 * Newton steps along the gradient from x (in place) until |f|/|grad f| <= tol.
 * *ok = 1 on convergence; otherwise x is the best iterate. A non-finite value at the
 * start is an error; at trial points it only rejects the step. On convergence f and its
 * gradient at x are returned in fx and gx when not NULL (the closest-point loop needs
 * them: evaluating them again was an eighth of a projection's evaluations).
 */
static anistar_status pj_newton_fg(anistar_context *ctx, const as_surface *s, double x[3],
                                   int *ok, double *fx, double gx[3]) {
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
            if (fx) *fx = f;
            if (gx) memcpy(gx, g, sizeof g);
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

static anistar_status pj_newton(anistar_context *ctx, const as_surface *s, double x[3],
                                int *ok) {
    return pj_newton_fg(ctx, s, x, ok, NULL, NULL);
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
            double fy;
            st = pj_newton_fg(ctx, s, y, &ok3, &fy, gy);
            if (st) return st;
            if (!ok3) continue;
            double dy = sqrt(v3_dist2(p, y));
            double gyn = v3_norm(gy);
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

/*
 * The sampler (contract: as_surface_sample in surface.h). One grid of SM_N^3 cells over
 * the bounding cube; its vertices and the witnesses (points found off the grid, inside
 * parts thinner than a cell) are the nodes of a union-find of the regions f < 0 and
 * f >= 0; every crossing of S between two nodes links an inside region to an outside
 * region, and each such pair is one component of S.
 */
#define SM_N 64
#define SM_NV (SM_N + 1) /* vertices per axis (index arithmetic with constants: no divisions) */
/* A cell is resolved when the second differences of f at its corners (the largest sum
 * over the axes) are at most SM_RESOLVED times their largest first differences: f bends
 * little across the cell, its corner signs tell where S is. A torus tube of radius 2.8
 * cells is resolved (ratio about 0.55); parts thinner than about two cells are not. */
#define SM_RESOLVED 0.75
/* At most this many descents per call (each costs about 10 to 70 evaluations). */
#define SM_MAX_DESCENTS 32768
#define SM_MAX_WITNESSES 65536
/* Evaluations per descent, chords tried per witness to join its neighbours and to find
 * its crossing. */
#define SM_DESCENT_EVALS 64
#define SM_LINK_TRIES 8
#define SM_PAIR_TRIES 4
/* Components of area below SM_SMALL_AREA h^2 (a sphere of radius 0.8 h) that lie within
 * 2h of one of their points along the axes get their area from a local grid of SM_SMALL_N
 * cells per axis over their extent (the lattice sees them with a few crossings at best),
 * for at most SM_SMALL_MAX of them. */
#define SM_SMALL_AREA 8.0
#define SM_SMALL_N 12
#define SM_SMALL_MAX 256

enum { SM_NEAR = 1, SM_UNRES = 2, SM_MIXED = 4, SM_FRAG = 8 };

/* The grid. Vertex (i, j, k) is o + h (i, j, k), index i + nv (j + nv k); cell (i, j, k)
 * has that vertex as its lowest corner, index i + n (j + n k). */
typedef struct sm_grid {
    size_t n, nv, count, ncells;
    double h, o[3];
    double *f;      /* values (0 beyond the sphere) */
    int8_t *sg;     /* -1 inside (f < 0), +1 otherwise (beyond the sphere included) */
    int8_t *ball;   /* 1 if the vertex is inside the ball */
    float *K;       /* sum over the axes of |second difference of f| */
    float *L;       /* norm over the axes of the larger one-sided |first difference| */
    uint8_t *cell;  /* cell flags: SM_NEAR (S may meet it), SM_UNRES (not resolved),
                       SM_MIXED (its corners have both signs) */
    int32_t *whead; /* per cell: first witness inside it, -1 */
    int32_t *xhead; /* per cell: first crossing record with its midpoint inside it, -1 */
    uint8_t *ek;    /* 3 per vertex: unresolved cells around its edges along +x, +y, +z */
    int32_t *groot; /* per vertex: its region's root after the unions along grid edges */
} sm_grid;

/* A witness: a point off the grid standing for the region of its sign around it. */
typedef struct sm_wit {
    double p[3];
    double n[3];    /* the thin direction (across the part) when thin */
    int32_t next;   /* next witness of the same cell, -1 */
    int8_t sg;      /* sign of f at p (-1 or +1, as sm_grid.sg) */
    int8_t thin;    /* 1: S crosses both ways along n within 2h (a part thinner than 4h) */
} sm_wit;

/* A crossing record: a segment with exactly one crossing of S, between the inside node
 * nin (f < 0 at a) and the outside node nout (at b). */
typedef struct sm_rec {
    double a[3], b[3];
    uint32_t nin, nout;
    int32_t comp; /* component, after sm_components */
    int32_t next; /* next record of the same cell (by midpoint), -1 */
    uint32_t ord; /* creation order (ties of the sort) */
} sm_rec;

/* A crossing of a lattice edge (of an unresolved cell): the Crofton estimate of the area. */
typedef struct sm_crof {
    double x[3];
    size_t edge;  /* 3 v + axis: the edge from vertex v along the axis */
    int32_t rec;  /* the edge's record when it is that edge's only crossing, else -1 */
    int32_t comp; /* after sm_components (-1: find the nearest record's) */
} sm_crof;

/* A distinct (inside root, outside root) pair: one component. */
typedef struct sm_pair {
    uint32_t rin, rout, rec;
} sm_pair;

typedef struct sm_state {
    anistar_context *ctx;
    const as_surface *s;
    sm_grid g;
    int32_t *uf; /* union-find over the nodes: grid vertices, then witnesses */
    size_t capuf;
    sm_wit *wit;
    size_t nwit, capwit;
    sm_rec *rec;
    size_t nrec, caprec;
    sm_crof *crof;
    size_t ncrof, capcrof;
    sm_pair *pairs; /* nrec entries; the first ncomp, after sm_components, the distinct ones */
    size_t ncomp;
    int32_t *gidx;  /* per vertex: its gradient in gval, -1 */
    double *gval;
    size_t ngval, capgval;
    int frag_candidates; /* some resolved mixed cell has a corner where K > SM_RESOLVED L
                            (sm_areas' fragment cells, only then) */
    as_pool *pool;       /* threads for the grid values (NULL: none) */
} sm_state;

static void sm_state_free(sm_state *st) {
    anistar_context *ctx = st->ctx;
    sm_grid *g = &st->g;
    as_free(ctx, g->f, g->count * sizeof(double));
    as_free(ctx, g->sg, g->count);
    as_free(ctx, g->ball, g->count);
    as_free(ctx, g->K, g->count * sizeof(float));
    as_free(ctx, g->L, g->count * sizeof(float));
    as_free(ctx, g->cell, g->ncells);
    as_free(ctx, g->whead, g->ncells * sizeof(int32_t));
    as_free(ctx, g->xhead, g->ncells * sizeof(int32_t));
    as_free(ctx, g->ek, 3 * g->count);
    as_free(ctx, g->groot, g->count * sizeof(int32_t));
    as_free(ctx, st->uf, st->capuf * sizeof(int32_t));
    as_free(ctx, st->wit, st->capwit * sizeof(sm_wit));
    as_free(ctx, st->rec, st->caprec * sizeof(sm_rec));
    as_free(ctx, st->crof, st->capcrof * sizeof(sm_crof));
    as_free(ctx, st->pairs, st->nrec * sizeof(sm_pair));
    as_free(ctx, st->gidx, g->count * sizeof(int32_t));
    as_free(ctx, st->gval, st->capgval * sizeof(double));
    memset(st, 0, sizeof *st);
}

static inline void sm_vertex(const sm_grid *g, size_t idx, double p[3]) {
    size_t i = idx % SM_NV, j = (idx / SM_NV) % SM_NV, k = idx / (SM_NV * SM_NV);
    p[0] = g->o[0] + g->h * (double)i;
    p[1] = g->o[1] + g->h * (double)j;
    p[2] = g->o[2] + g->h * (double)k;
}

/* The position and sign of a node. */
static inline void sm_node(const sm_state *st, uint32_t node, double p[3], int *sg) {
    if (node < st->g.count) {
        sm_vertex(&st->g, node, p);
        *sg = st->g.sg[node];
    } else {
        const sm_wit *w = &st->wit[node - st->g.count];
        memcpy(p, w->p, 3 * sizeof(double));
        *sg = w->sg;
    }
}

/* The cell holding p (clamped to the grid). */
static inline size_t sm_cell_of(const sm_grid *g, const double p[3], size_t c[3]) {
    for (int i = 0; i < 3; i++) {
        double t = floor((p[i] - g->o[i]) / g->h);
        if (!(t >= 0)) t = 0;
        if (t > (double)(g->n - 1)) t = (double)(g->n - 1);
        c[i] = (size_t)t;
    }
    return c[0] + g->n * (c[1] + g->n * c[2]);
}

static inline int32_t uf_find(int32_t *uf, int32_t x) {
    while (uf[x] != x) {
        uf[x] = uf[uf[x]];
        x = uf[x];
    }
    return x;
}
/* The root of a set is its smallest node: the result does not depend on the order of
 * the unions. */
static inline void uf_union(int32_t *uf, int32_t a, int32_t b) {
    a = uf_find(uf, a);
    b = uf_find(uf, b);
    if (a < b) uf[b] = a;
    else if (b < a) uf[a] = b;
}

/* ---- crossings along a short segment ---- */

#define SM_SCAN_MAX CR_MAX_CAND
/* The crossings of S along [a, b] (both inside the ball), in order from a: brackets
 * [ua, ub] of the parameter (ua == ub for an exact zero), found by the sampling of
 * as_surface_crossing (Hermite tests on value and slope, splitting down to 1e-7 R).
 * Touching points (double roots) and zeros at the ends are not counted. */
typedef struct sm_scan {
    int n;
    double ua[SM_SCAN_MAX], ub[SM_SCAN_MAX], fa[SM_SCAN_MAX], fb[SM_SCAN_MAX];
} sm_scan;

static anistar_status sm_scan_segment(sm_state *st, const double a[3], const double b[3],
                                      sm_scan *out) {
    const as_surface *s = st->s;
    out->n = 0;
    cr_chord c;
    c.s = s;
    c.ctx = st->ctx;
    for (int i = 0; i < 3; i++) {
        c.A[i] = a[i];
        c.B[i] = b[i];
        c.D[i] = b[i] - a[i];
    }
    c.len = v3_norm(c.D);
    c.evals = 0;
    if (!(c.len > 0)) return ANISTAR_OK;
    double spacing = AS_CROSSING_SPACING * s->radius;
    c.umin = fmin(0.25, 1e-7 * s->radius / c.len);
    c.uval = fmin(1.0, spacing / 8 / c.len);
    int npieces = (int)ceil(c.len / spacing * (1 - 1e-9));
    if (npieces < 1) npieces = 1;
    if (npieces > 64) npieces = 64;
    cr_cands cs;
    cs.n = 0;
    cs.step = cs.seq = 0;
    memcpy(cs.ref, a, sizeof cs.ref);
    double uprev = 0, fprev, dprev;
    int okprev;
    anistar_status rs = cr_eval(&c, 0, &fprev, &dprev, &okprev);
    if (rs) return rs;
    for (int i = 1; i <= npieces; i++) {
        double u = i == npieces ? 1.0 : (double)i / npieces, f, dd;
        int ok;
        rs = cr_eval(&c, u, &f, &dd, &ok);
        if (rs) return rs;
        if (f == 0 && i < npieces) cr_add(&c, &cs, u, 0, u, 0);
        cr_piece pc = {uprev, fprev, dprev, u, f, dd, okprev, ok};
        rs = cr_piece_scan(&c, &cs, pc);
        if (rs) return rs;
        uprev = u;
        fprev = f;
        dprev = dd;
        okprev = ok;
    }
    for (int i = 0; i < cs.n; i++) {
        const cr_cand *k = &cs.c[i];
        if (k->ua == k->ub && (k->fa != 0 || k->ua <= 0 || k->ua >= 1)) continue;
        int j = out->n++;
        /* insertion by ua */
        while (j > 0 && out->ua[j - 1] > k->ua) {
            out->ua[j] = out->ua[j - 1];
            out->ub[j] = out->ub[j - 1];
            out->fa[j] = out->fa[j - 1];
            out->fb[j] = out->fb[j - 1];
            j--;
        }
        out->ua[j] = k->ua;
        out->ub[j] = k->ub;
        out->fa[j] = k->fa;
        out->fb[j] = k->fb;
    }
    return ANISTAR_OK;
}

/* The crossing of bracket i of a scan of [a, b], refined (Illinois) to 1e-3 h. */
static anistar_status sm_scan_point(sm_state *st, const sm_scan *sc, int i, const double a[3],
                                    const double b[3], double x[3]) {
    double u = sc->ua[i];
    if (sc->ub[i] > sc->ua[i]) {
        cr_chord c;
        c.s = st->s;
        c.ctx = st->ctx;
        for (int k = 0; k < 3; k++) {
            c.A[k] = a[k];
            c.B[k] = b[k];
            c.D[k] = b[k] - a[k];
        }
        c.len = v3_norm(c.D);
        c.evals = 0;
        anistar_status rs =
            cr_refine(&c, sc->ua[i], sc->fa[i], sc->ub[i], sc->fb[i], 1e-3 * st->g.h / c.len, &u);
        if (rs) return rs;
    }
    for (int k = 0; k < 3; k++) x[k] = (1 - u) * a[k] + u * b[k];
    return ANISTAR_OK;
}

/* ---- records ---- */

static anistar_status sm_add_rec(sm_state *st, const double a[3], const double b[3],
                                 uint32_t nin, uint32_t nout, int32_t *index) {
    if (as_grow(st->ctx, (void **)&st->rec, &st->caprec, st->nrec + 1, sizeof(sm_rec)))
        return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory (crossings)");
    sm_rec *r = &st->rec[st->nrec];
    memcpy(r->a, a, sizeof r->a);
    memcpy(r->b, b, sizeof r->b);
    r->nin = nin;
    r->nout = nout;
    r->comp = -1;
    r->next = -1;
    r->ord = (uint32_t)st->nrec;
    if (index) *index = (int32_t)st->nrec;
    st->nrec++;
    return ANISTAR_OK;
}

/* A record for bracket i of the scan of the segment from node p (point pa) to node q
 * (point pb), oriented inside -> outside. */
static anistar_status sm_add_bracket(sm_state *st, const sm_scan *sc, int i, const double pa[3],
                                     const double pb[3], uint32_t p, int sgp, uint32_t q,
                                     int32_t *index) {
    double x0[3], x1[3];
    for (int k = 0; k < 3; k++) {
        x0[k] = (1 - sc->ua[i]) * pa[k] + sc->ua[i] * pb[k];
        x1[k] = (1 - sc->ub[i]) * pa[k] + sc->ub[i] * pb[k];
    }
    if (sc->ua[i] == sc->ub[i]) { /* an exact zero: the whole segment brackets it */
        memcpy(x0, pa, sizeof x0);
        memcpy(x1, pb, sizeof x1);
    }
    return sgp < 0 ? sm_add_rec(st, x0, x1, p, q, index) : sm_add_rec(st, x1, x0, q, p, index);
}

/* The record of the grid edge from vertex u (at a, sign su) to vertex v (at b). */
static anistar_status sm_add_edge_rec(sm_state *st, const double a[3], const double b[3],
                                      size_t u, size_t v, int su) {
    return su < 0 ? sm_add_rec(st, a, b, (uint32_t)u, (uint32_t)v, NULL)
                  : sm_add_rec(st, b, a, (uint32_t)v, (uint32_t)u, NULL);
}

static anistar_status sm_add_crof(sm_state *st, const double x[3], size_t edge, int32_t rec) {
    if (as_grow(st->ctx, (void **)&st->crof, &st->capcrof, st->ncrof + 1, sizeof(sm_crof)))
        return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory (crossings)");
    sm_crof *c = &st->crof[st->ncrof++];
    memcpy(c->x, x, sizeof c->x);
    c->edge = edge;
    c->rec = rec;
    c->comp = -1;
    return ANISTAR_OK;
}

/* ---- 1. values, 2. differences, 3. cells ---- */

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

/* f at the grid vertices of z-slab k (sm_values). */
static anistar_status sm_values_task(void *arg, int32_t k, int t, anistar_context *ctx) {
    (void)t;
    sm_state *st = arg;
    const as_surface *s = st->s;
    sm_grid *g = &st->g;
    const size_t slab = g->nv * g->nv;
    for (size_t idx = (size_t)k * slab; idx < ((size_t)k + 1) * slab; idx++) {
        double p[3] = {g->o[0] + g->h * (double)(idx % SM_NV),
                       g->o[1] + g->h * (double)((idx / SM_NV) % SM_NV),
                       g->o[2] + g->h * (double)(idx / (SM_NV * SM_NV))};
        st->uf[idx] = (int32_t)idx;
        st->gidx[idx] = -1;
        if (!fs_in_ball(s, p)) {
            g->ball[idx] = 0;
            g->sg[idx] = 1;
            g->f[idx] = 0;
            continue;
        }
        double f = fs_value(s, p);
        if (!isfinite(f)) return fail_nonfinite(ctx, "f", p);
        g->ball[idx] = 1;
        g->sg[idx] = f < 0 ? -1 : 1;
        g->f[idx] = f;
    }
    return ANISTAR_OK;
}

static anistar_status sm_values(sm_state *st) {
    anistar_context *ctx = st->ctx;
    const as_surface *s = st->s;
    sm_grid *g = &st->g;
    g->n = SM_N;
    g->nv = g->n + 1;
    g->count = g->nv * g->nv * g->nv;
    g->ncells = g->n * g->n * g->n;
    g->h = 2 * s->radius / (double)g->n;
    for (int i = 0; i < 3; i++) g->o[i] = s->center[i] - s->radius;
    g->f = as_alloc_array(ctx, g->count, sizeof(double));
    g->sg = as_alloc(ctx, g->count);
    g->ball = as_alloc(ctx, g->count);
    g->K = as_alloc_array(ctx, g->count, sizeof(float));
    g->L = as_alloc_array(ctx, g->count, sizeof(float));
    g->cell = as_alloc(ctx, g->ncells);
    g->whead = as_alloc_array(ctx, g->ncells, sizeof(int32_t));
    g->xhead = as_alloc_array(ctx, g->ncells, sizeof(int32_t));
    g->ek = as_alloc_array(ctx, g->count, 3);
    g->groot = as_alloc_array(ctx, g->count, sizeof(int32_t));
    st->gidx = as_alloc_array(ctx, g->count, sizeof(int32_t));
    st->capuf = g->count;
    st->uf = as_alloc_array(ctx, st->capuf, sizeof(int32_t));
    if (!g->f || !g->sg || !g->ball || !g->K || !g->L || !g->cell || !g->whead || !g->xhead ||
        !g->ek || !g->groot || !st->gidx || !st->uf) {
        if (!st->uf) st->capuf = 0;
        return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory (grid of %zu^3)", g->nv);
    }
    /* design: f at the grid vertices, one task per z-slab (each writes only its slab): the
     * same values, and the same first non-finite one, for any thread count */
    anistar_status rs = ANISTAR_OK;
    if (st->pool) {
        rs = as_pool_run(st->pool, (int32_t)g->nv, sm_values_task, st);
    } else {
        for (size_t k = 0; k < g->nv && !rs; k++) rs = sm_values_task(st, (int32_t)k, 0, ctx);
    }
    if (rs) return rs;
    for (size_t c = 0; c < g->ncells; c++) g->whead[c] = g->xhead[c] = -1;
    /* the sphere check: f < 0 on the sphere means S is not inside it */
    size_t nv = g->nv, stride[3] = {1, nv, nv * nv};
    for (size_t idx = 0; idx < g->count; idx++) {
        size_t c[3] = {idx % SM_NV, (idx / SM_NV) % SM_NV, idx / (SM_NV * SM_NV)};
        for (int ax = 0; ax < 3; ax++) {
            if (c[ax] + 1 >= nv) continue;
            size_t jdx = idx + stride[ax];
            if (g->ball[idx] == g->ball[jdx] || g->sg[g->ball[idx] ? idx : jdx] > 0) continue;
            size_t in = g->ball[idx] ? idx : jdx, outv = g->ball[idx] ? jdx : idx;
            double p[3], q[3], x[3];
            sm_vertex(g, in, p);
            sm_vertex(g, outv, q);
            sm_sphere_point(s, p, q, x);
            double fx = fs_value(s, x);
            if (!isfinite(fx)) return fail_nonfinite(ctx, "f", x);
            if (fx < 0)
                return as_fail(ctx, ANISTAR_ENOSURFACE,
                               "surface: f < 0 at (%.9g, %.9g, %.9g) on the bounding sphere: "
                               "the surface must lie strictly inside the bounding sphere "
                               "(enlarge its radius)",
                               x[0], x[1], x[2]);
        }
    }
    return ANISTAR_OK;
}

static void sm_differences(sm_state *st) {
    sm_grid *g = &st->g;
    size_t nv = g->nv, stride[3] = {1, nv, nv * nv}, idx = 0;
    for (size_t k = 0; k < nv; k++)
        for (size_t j = 0; j < nv; j++)
            for (size_t i = 0; i < nv; i++, idx++) {
                g->K[idx] = g->L[idx] = 0;
                if (!g->ball[idx]) continue;
                size_t c[3] = {i, j, k};
                double K = 0, L2 = 0, f = g->f[idx];
                for (int ax = 0; ax < 3; ax++) {
                    int lo = c[ax] > 0 && g->ball[idx - stride[ax]];
                    int hi = c[ax] + 1 < nv && g->ball[idx + stride[ax]];
                    double fl = lo ? g->f[idx - stride[ax]] : 0;
                    double fh = hi ? g->f[idx + stride[ax]] : 0;
                    if (lo && hi) K += fabs(fl - 2 * f + fh);
                    double dl = lo ? fabs(f - fl) : 0, dh = hi ? fabs(fh - f) : 0,
                           d = dl > dh ? dl : dh;
                    L2 += d * d;
                }
                g->K[idx] = (float)fmin(K, FLT_MAX);
                g->L[idx] = (float)fmin(sqrt(L2), FLT_MAX);
            }
}

/* Offsets of the 8 corners of a cell from its lowest corner (bit 0: +x, 1: +y, 2: +z). */
static inline void sm_corner_offsets(const sm_grid *g, size_t off[8]) {
    for (int c = 0; c < 8; c++)
        off[c] = (size_t)(c & 1) +
                 g->nv * ((size_t)((c >> 1) & 1) + g->nv * (size_t)((c >> 2) & 1));
}
static inline size_t sm_cell_base(const sm_grid *g, size_t cell) {
    (void)g;
    return cell % SM_N + SM_NV * ((cell / SM_N) % SM_N + SM_NV * (cell / (SM_N * SM_N)));
}
static inline size_t sm_corner(const sm_grid *g, size_t cell, int corner) {
    return sm_cell_base(g, cell) + (size_t)(corner & 1) +
           SM_NV * ((size_t)((corner >> 1) & 1) + SM_NV * (size_t)((corner >> 2) & 1));
}

/* The cells around the grid edge from vertex idx along axis ax (up to 4). */
static int sm_edge_cells(const sm_grid *g, size_t idx, int ax, size_t cells[4]) {
    size_t n = g->n;
    size_t c[3] = {idx % SM_NV, (idx / SM_NV) % SM_NV, idx / (SM_NV * SM_NV)};
    int b1 = (ax + 1) % 3, b2 = (ax + 2) % 3, m = 0;
    if (c[ax] >= n) return 0;
    for (int d1 = 0; d1 < 2; d1++)
        for (int d2 = 0; d2 < 2; d2++) {
            size_t cc[3] = {c[0], c[1], c[2]};
            if ((d1 && cc[b1] == 0) || (d2 && cc[b2] == 0)) continue;
            cc[b1] -= (size_t)d1;
            cc[b2] -= (size_t)d2;
            if (cc[b1] >= n || cc[b2] >= n) continue;
            cells[m++] = cc[0] + n * (cc[1] + n * cc[2]);
        }
    return m;
}

/* grad f at grid vertex v (computed once). */
static anistar_status sm_grad(sm_state *st, size_t v, const double **gp) {
    if (st->gidx[v] < 0) {
        if (as_grow(st->ctx, (void **)&st->gval, &st->capgval, 3 * (st->ngval + 1), sizeof(double)))
            return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory (gradients)");
        double p[3], *g = st->gval + 3 * st->ngval;
        sm_vertex(&st->g, v, p);
        g[0] = g[1] = g[2] = 0;
        double f = st->s->ops->eval(st->s, p, 1, g, NULL);
        if (!isfinite(f)) return fail_nonfinite(st->ctx, "f", p);
        st->gidx[v] = (int32_t)st->ngval++;
    }
    *gp = st->gval + 3 * (size_t)st->gidx[v];
    return ANISTAR_OK;
}

/* *maybe = 1 when q = sg f may vanish in the cell, sg the sign of its corners: the
 * largest over its corners c of the minimum over the cell of the tangent plane
 * q(c) + sg grad f(c) . (x - c) is <= 0. For q convex the tangent planes lie below q, so a
 * zero of q in the cell makes every plane's minimum <= 0: the test misses nothing then. */
static anistar_status sm_plane_test(sm_state *st, size_t base, const size_t off[8], int sg,
                                    int *maybe) {
    const sm_grid *g = &st->g;
    double best = -INFINITY, h = g->h;
    for (int c = 0; c < 8; c++) {
        size_t v = base + off[c];
        if (!g->ball[v]) continue;
        const double *gr = NULL;
        anistar_status rs = sm_grad(st, v, &gr);
        if (rs) return rs;
        double m = sg * g->f[v];
        for (int i = 0; i < 3; i++) {
            double gi = sg * gr[i];
            if ((c >> i) & 1) m -= gi > 0 ? h * gi : 0; /* x_i - c_i in [-h, 0] */
            else m += gi < 0 ? h * gi : 0;              /* x_i - c_i in [0, h] */
        }
        if (m == m && m > best) best = m;
    }
    *maybe = !(best > 0);
    return ANISTAR_OK;
}

/*
 * Cell flags, from the corners inside the ball. A mixed cell (corners of both signs, the
 * ones beyond the sphere counting as outside) is near S; it is unresolved when
 * max K > SM_RESOLVED max L over its corners, or when it reaches beyond the sphere. A
 * cell of one sign may hide a part of S (near and unresolved) when
 *  - its smallest |f| at a corner is at most sqrt(3)/2 max L (a first-order bound of the
 *    drop of |f| inside it: for |f| convex its one-sided differences bound the gradient),
 *    and
 *  - the tangent planes at its corners do not keep |f| > 0 on it (sm_plane_test). The
 *    first test alone keeps every cell within a cell of S, and those near steep functions
 *    (x^8 and the like) even farther; this one dismisses them where f is nearly linear.
 * Both are exact (they miss no zero) for |f| convex on the cell.
 */
static anistar_status sm_classify(sm_state *st) {
    sm_grid *g = &st->g;
    size_t n = g->n, nv = g->nv, off[8], cell = 0;
    sm_corner_offsets(g, off);
    for (size_t k = 0; k < n; k++)
        for (size_t j = 0; j < n; j++)
            for (size_t i = 0; i < n; i++, cell++) {
                size_t base = i + nv * (j + nv * k);
                int neg = 0, nin = 0;
                double mn = INFINITY, K = 0, L = 0;
                for (int c = 0; c < 8; c++) {
                    size_t v = base + off[c];
                    if (!g->ball[v]) continue;
                    nin++;
                    neg += g->sg[v] < 0;
                    double a = fabs(g->f[v]);
                    if (a < mn) mn = a;
                    if (g->K[v] > K) K = g->K[v];
                    if (g->L[v] > L) L = g->L[v];
                }
                uint8_t fl = 0;
                if (nin == 0) {
                    fl = 0;
                } else if (neg > 0 && neg < 8) {
                    fl = SM_NEAR | SM_MIXED | (K > SM_RESOLVED * L || nin < 8 ? SM_UNRES : 0);
                    if (!(fl & SM_UNRES))
                        for (int c = 0; c < 8 && !st->frag_candidates; c++)
                            if (g->K[base + off[c]] > SM_RESOLVED * g->L[base + off[c]])
                                st->frag_candidates = 1;
                } else if (mn <= 0.8660254037844386 * L) {
                    int maybe;
                    anistar_status rs = sm_plane_test(st, base, off, neg ? -1 : 1, &maybe);
                    if (rs) return rs;
                    if (maybe) fl = SM_NEAR | SM_UNRES;
                }
                g->cell[cell] = fl;
            }
    return ANISTAR_OK;
}

/* ---- 4. grid edges ---- */

/*
 * Unions along the grid edges and crossing records of their sign changes. The edges of
 * unresolved cells are scanned for every crossing: no union across an edge that crosses
 * S (twice: a part thinner than the cell between its ends); their crossings are kept for
 * the Crofton estimate of the area. An edge to a vertex beyond the sphere (outside)
 * crosses S between its inside vertex and the sphere.
 */
static anistar_status sm_edges(sm_state *st) {
    sm_grid *g = &st->g;
    size_t nv = g->nv, stride[3] = {1, nv, nv * nv}, idx = 0;
    double h = g->h;
    for (size_t kk = 0; kk < nv; kk++)
        for (size_t jj = 0; jj < nv; jj++)
            for (size_t ii = 0; ii < nv; ii++, idx++) {
                size_t c[3] = {ii, jj, kk};
                for (int ax = 0; ax < 3; ax++) {
                    if (c[ax] + 1 >= nv) continue;
                    size_t jdx = idx + stride[ax];
                    int su = g->sg[idx], sv = g->sg[jdx];
                    if (su == sv && g->ball[idx] && g->ball[jdx] &&
                        g->ek[3 * idx + (size_t)ax] == 0) { /* the common case */
                        uf_union(st->uf, (int32_t)idx, (int32_t)jdx);
                        continue;
                    }
                    anistar_status rs = ANISTAR_OK;
                    double a[3] = {g->o[0] + h * (double)ii, g->o[1] + h * (double)jj,
                                   g->o[2] + h * (double)kk},
                           b[3] = {a[0], a[1], a[2]};
                    b[ax] += h;
                    if (!g->ball[idx] || !g->ball[jdx]) {
                        size_t in = g->ball[idx] ? idx : jdx;
                        if (!g->ball[in] || g->sg[in] > 0) {
                            uf_union(st->uf, (int32_t)idx, (int32_t)jdx);
                            continue;
                        }
                        double x[3];
                        if (in == idx) sm_sphere_point(st->s, a, b, x);
                        else sm_sphere_point(st->s, b, a, x);
                        rs = sm_add_rec(st, in == idx ? a : b, x, (uint32_t)in,
                                        (uint32_t)(in == idx ? jdx : idx), NULL);
                        if (rs) return rs;
                        continue;
                    }
                    if (g->ek[3 * idx + (size_t)ax] == 0) {
                        if (su == sv) uf_union(st->uf, (int32_t)idx, (int32_t)jdx);
                        else if ((rs = sm_add_edge_rec(st, a, b, idx, jdx, su))) return rs;
                        continue;
                    }
                    sm_scan sc;
                    if ((rs = sm_scan_segment(st, a, b, &sc))) return rs;
                    int32_t ri = -1;
                    if (su == sv) {
                        if (sc.n == 0) uf_union(st->uf, (int32_t)idx, (int32_t)jdx);
                    } else if (sc.n == 1) {
                        rs = sm_add_bracket(st, &sc, 0, a, b, (uint32_t)idx, su, (uint32_t)jdx,
                                            &ri);
                    } else {
                        rs = sm_add_edge_rec(st, a, b, idx, jdx, su);
                    }
                    if (rs) return rs;
                    for (int i = 0; i < sc.n; i++) {
                        double x[3];
                        if ((rs = sm_scan_point(st, &sc, i, a, b, x)) ||
                            (rs = sm_add_crof(st, x, 3 * idx + (size_t)ax, ri)))
                            return rs;
                    }
                }
            }
    if (st->frag_candidates)
        for (size_t v = 0; v < g->count; v++) g->groot[v] = uf_find(st->uf, (int32_t)v);
    return ANISTAR_OK;
}

/* ---- 5. witnesses ---- */

/*
 * Descend (sg = +1) or ascend (sg = -1) f from x0 within the box [lo, hi], by Newton steps
 * toward f = 0 (slightly past it) and gradient steps; *found = 1 and the point in y when
 * sg * f < 0 is reached.
 */
static anistar_status sm_descend(sm_state *st, const double x0[3], int sg, const double lo[3],
                                 const double hi[3], int *found, double y[3]) {
    const as_surface *s = st->s;
    double h = st->g.h, x[3] = {x0[0], x0[1], x0[2]}, g[3];
    *found = 0;
    double f = s->ops->eval(s, x, 1, g, NULL);
    if (!isfinite(f)) return fail_nonfinite(st->ctx, "f", x);
    int evals = 1;
    while (evals < SM_DESCENT_EVALS) {
        if (sg * f < 0) {
            *found = 1;
            memcpy(y, x, sizeof x);
            return ANISTAR_OK;
        }
        double gn2 = v3_dot(g, g);
        if (!(gn2 > 0) || !isfinite(gn2)) return ANISTAR_OK;
        double gn = sqrt(gn2);
        int accepted = 0;
        for (int k = 0; k < 12 && !accepted && evals < SM_DESCENT_EVALS; k++) {
            double step[3];
            if (k == 0) {
                for (int i = 0; i < 3; i++) step[i] = -1.5 * f * g[i] / gn2;
            } else {
                double a = sg * h * ldexp(1.0, -(k - 1));
                for (int i = 0; i < 3; i++) step[i] = -a * g[i] / gn;
            }
            double len = v3_norm(step);
            if (len > h)
                for (int i = 0; i < 3; i++) step[i] *= h / len;
            double z[3], gz[3];
            for (int i = 0; i < 3; i++) z[i] = x[i] + step[i];
            if (z[0] < lo[0] || z[1] < lo[1] || z[2] < lo[2] || z[0] > hi[0] || z[1] > hi[1] ||
                z[2] > hi[2] || !fs_in_ball(s, z))
                continue;
            double fz = s->ops->eval(s, z, 1, gz, NULL);
            evals++;
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

/* The first crossing of S from p along the unit direction d within 2h (clipped to the
 * ball): *found and its point in x. */
static anistar_status sm_ray(sm_state *st, const double p[3], const double d[3], int *found,
                             double x[3]) {
    const as_surface *s = st->s;
    double b[3], len = 2 * st->g.h;
    *found = 0;
    for (int it = 0; it < 8; it++, len *= 0.5) {
        for (int i = 0; i < 3; i++) b[i] = p[i] + len * d[i];
        if (fs_in_ball(s, b)) break;
    }
    if (!fs_in_ball(s, b)) return ANISTAR_OK;
    sm_scan sc;
    anistar_status rs = sm_scan_segment(st, p, b, &sc);
    if (rs || sc.n == 0) return rs;
    *found = 1;
    return sm_scan_point(st, &sc, 0, p, b, x);
}

/* The direction across a thin part of sign sg with walls x1, x2 (x1 - x2 along d): from
 * the gradients there (they point out of the part for sg = -1, into it for +1); d when
 * they do not give one. */
static anistar_status sm_across(sm_state *st, int sg, const double x1[3], const double x2[3],
                                const double d[3], double n[3]) {
    double g1[3] = {0, 0, 0}, g2[3] = {0, 0, 0};
    double f1 = st->s->ops->eval(st->s, x1, 1, g1, NULL);
    double f2 = st->s->ops->eval(st->s, x2, 1, g2, NULL);
    if (!isfinite(f1)) return fail_nonfinite(st->ctx, "f", x1);
    if (!isfinite(f2)) return fail_nonfinite(st->ctx, "f", x2);
    double m[3], l1 = v3_norm(g1), l2 = v3_norm(g2);
    if (l1 > 0 && l2 > 0 && isfinite(l1) && isfinite(l2)) {
        for (int i = 0; i < 3; i++) m[i] = -sg * (g1[i] / l1 - g2[i] / l2);
        double l = v3_norm(m);
        if (l > 1e-3 && v3_dot(m, d) > 0) {
            for (int i = 0; i < 3; i++) n[i] = m[i] / l;
            return ANISTAR_OK;
        }
    }
    double l = v3_norm(d);
    for (int i = 0; i < 3; i++) n[i] = d[i] / l;
    return ANISTAR_OK;
}

/* Center the point p (f of sign sg there) in its part along the direction d: halfway
 * between the first crossings of S both ways along d within 2h (the mid-plane of a plate,
 * the axis of a tube: *thin = 1, the direction across in n); when only one is found, h
 * away from it (a thick part: *thin = 0). p is kept where the sign would change. */
static anistar_status sm_center(sm_state *st, double p[3], int sg, const double dir[3],
                                int *thin, double n[3]) {
    double d[3], m[3], x1[3], x2[3], z[3], dn = v3_norm(dir);
    *thin = 0;
    if (!(dn > 0) || !isfinite(dn)) return ANISTAR_OK;
    for (int i = 0; i < 3; i++) {
        d[i] = dir[i] / dn;
        m[i] = -d[i];
    }
    int f1, f2;
    anistar_status rs = sm_ray(st, p, d, &f1, x1);
    if (!rs) rs = sm_ray(st, p, m, &f2, x2);
    if (rs || (!f1 && !f2)) return rs;
    if (f1 && f2) {
        for (int i = 0; i < 3; i++) z[i] = 0.5 * (x1[i] + x2[i]);
        if ((rs = sm_across(st, sg, x1, x2, d, n))) return rs;
    } else {
        const double *x = f1 ? x1 : x2, *away = f1 ? m : d;
        for (int i = 0; i < 3; i++) z[i] = x[i] + st->g.h * away[i];
    }
    if (!fs_in_ball(st->s, z)) return ANISTAR_OK;
    double fz = fs_value(st->s, z);
    if (!isfinite(fz)) return fail_nonfinite(st->ctx, "f", z);
    if ((fz < 0 ? -1 : 1) != sg) return ANISTAR_OK;
    memcpy(p, z, sizeof z);
    *thin = f1 && f2;
    return ANISTAR_OK;
}

/* A witness at p of sign sg (thin along n when thin); its cell becomes near and
 * unresolved. */
static anistar_status sm_add_witness(sm_state *st, const double p[3], int sg, int thin,
                                     const double n[3]) {
    sm_grid *g = &st->g;
    size_t node = g->count + st->nwit, cc[3];
    if (as_grow(st->ctx, (void **)&st->wit, &st->capwit, st->nwit + 1, sizeof(sm_wit)) ||
        as_grow(st->ctx, (void **)&st->uf, &st->capuf, node + 1, sizeof(int32_t)))
        return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory (witnesses)");
    size_t cell = sm_cell_of(g, p, cc);
    sm_wit *w = &st->wit[st->nwit++];
    memcpy(w->p, p, sizeof w->p);
    if (thin) memcpy(w->n, n, sizeof w->n);
    else w->n[0] = w->n[1] = w->n[2] = 0;
    w->sg = (int8_t)sg;
    w->thin = (int8_t)thin;
    w->next = g->whead[cell];
    g->whead[cell] = (int32_t)(node - g->count);
    g->cell[cell] |= SM_NEAR | SM_UNRES;
    st->uf[node] = (int32_t)node;
    return ANISTAR_OK;
}

/* 1 when a witness of sign sg lies within r of p (the cells around p's). */
static int sm_witness_near(const sm_state *st, const double p[3], int sg, double r) {
    const sm_grid *g = &st->g;
    size_t cc[3], n = g->n;
    sm_cell_of(g, p, cc);
    for (size_t k = cc[2] > 0 ? cc[2] - 1 : 0; k <= cc[2] + 1 && k < n; k++)
        for (size_t j = cc[1] > 0 ? cc[1] - 1 : 0; j <= cc[1] + 1 && j < n; j++)
            for (size_t i = cc[0] > 0 ? cc[0] - 1 : 0; i <= cc[0] + 1 && i < n; i++)
                for (int32_t w = g->whead[i + n * (j + n * k)]; w >= 0; w = st->wit[w].next)
                    if (st->wit[w].sg == sg && v3_dist2(st->wit[w].p, p) < r * r) return 1;
    return 0;
}

/* Continuation from p (of sign sg, in a part thin along n): steps of length `step` in 8
 * directions across n; at a step q into a cell not yet near S, farther than h/2 from the
 * witnesses there, the chord q -/+ h n is scanned: the interval of sign sg between two
 * crossings nearest q (the part, found again even where n is only roughly across it)
 * gives a witness at its middle. */
static anistar_status sm_expand(sm_state *st, const double p[3], const double n[3], int sg,
                                double step) {
    sm_grid *g = &st->g;
    double h = g->h, t1[3], t2[3], e[3] = {0, 0, 0};
    int k = 0;
    for (int i = 1; i < 3; i++)
        if (fabs(n[i]) < fabs(n[k])) k = i;
    e[k] = 1;
    v3_cross(n, e, t1);
    double l = v3_norm(t1);
    for (int i = 0; i < 3; i++) t1[i] /= l;
    v3_cross(n, t1, t2);
    for (int a = 0; a < 8 && st->nwit < SM_MAX_WITNESSES; a++) {
        double ca = cos(a * 0.7853981633974483), sa = sin(a * 0.7853981633974483), q[3];
        double qa[3], qb[3];
        size_t cc[3];
        for (int i = 0; i < 3; i++) {
            q[i] = p[i] + step * (ca * t1[i] + sa * t2[i]);
            qa[i] = q[i] - h * n[i];
            qb[i] = q[i] + h * n[i];
        }
        if (!fs_in_ball(st->s, qa) || !fs_in_ball(st->s, qb) ||
            (g->cell[sm_cell_of(g, q, cc)] & SM_NEAR) || sm_witness_near(st, q, sg, 0.5 * h))
            continue;
        sm_scan sc;
        anistar_status rs = sm_scan_segment(st, qa, qb, &sc);
        if (rs) return rs;
        if (sc.n < 2) continue;
        double fa = fs_value(st->s, qa);
        if (!isfinite(fa)) return fail_nonfinite(st->ctx, "f", qa);
        int s0 = fa < 0 ? -1 : 1, best = -1;
        double bd = INFINITY;
        for (int j = 1; j < sc.n; j++) { /* interval j: between brackets j-1 and j */
            int sj = (j % 2) ? -s0 : s0;
            if (sj != sg) continue;
            double um = 0.25 * (sc.ua[j - 1] + sc.ub[j - 1] + sc.ua[j] + sc.ub[j]);
            double d = fabs(um - 0.5);
            if (d < bd) {
                bd = d;
                best = j;
            }
        }
        if (best < 0) continue;
        double x1[3], x2[3], z[3], m[3], dir[3];
        if ((rs = sm_scan_point(st, &sc, best, qa, qb, x1)) ||
            (rs = sm_scan_point(st, &sc, best - 1, qa, qb, x2)))
            return rs;
        for (int i = 0; i < 3; i++) {
            z[i] = 0.5 * (x1[i] + x2[i]);
            dir[i] = x1[i] - x2[i];
        }
        double fz = fs_value(st->s, z);
        if (!isfinite(fz)) return fail_nonfinite(st->ctx, "f", z);
        if ((fz < 0 ? -1 : 1) != sg || sm_witness_near(st, z, sg, 0.25 * h)) continue;
        if ((rs = sm_across(st, sg, x1, x2, v3_norm(dir) > 0 ? dir : n, m))) return rs;
        if ((rs = sm_add_witness(st, z, sg, 1, m))) return rs;
    }
    return ANISTAR_OK;
}

/*
 * Witnesses: points inside parts thinner or smaller than a cell.
 *  1. descents from the near cells of one sign: from the cell's center (its lowest corner
 *     in the ball when the center is beyond the sphere), within the cell grown by h/2; the
 *     point reached is centered in its part (sm_center along grad f);
 *  2. continuation along thin parts (sm_expand), from the thin witnesses (those of step 1,
 *     and those it adds) and from the grid vertices inside thin parts (the corners of
 *     unresolved mixed cells of the minority sign there, centered along grad f): it
 *     follows a part through the cells where f does not show it at the corners (a thin
 *     cavity cut by max(), say) once any of its cells shows it.
 * At most SM_MAX_DESCENTS descents and SM_MAX_WITNESSES witnesses.
 */
static anistar_status sm_witnesses(sm_state *st) {
    sm_grid *g = &st->g;
    double h = g->h;
    size_t descents = 0, off[8];
    sm_corner_offsets(g, off);
    anistar_status rs;
    for (size_t cell = 0; cell < g->ncells && descents < SM_MAX_DESCENTS; cell++) {
        if ((g->cell[cell] & (SM_NEAR | SM_MIXED)) != SM_NEAR) continue;
        descents++;
        int sg = 0, found, thin;
        for (int c = 0; c < 8 && !sg; c++) {
            size_t v = sm_corner(g, cell, c);
            if (g->ball[v]) sg = g->sg[v];
        }
        double x0[3], y[3], lo[3], hi[3], gr[3] = {0, 0, 0}, n[3] = {0, 0, 0};
        sm_vertex(g, sm_cell_base(g, cell), lo);
        for (int i = 0; i < 3; i++) {
            x0[i] = lo[i] + 0.5 * h;
            hi[i] = lo[i] + 1.5 * h;
            lo[i] -= 0.5 * h;
        }
        if (!fs_in_ball(st->s, x0))
            for (int c = 0; c < 8; c++) {
                size_t v = sm_corner(g, cell, c);
                if (g->ball[v]) {
                    sm_vertex(g, v, x0);
                    break;
                }
            }
        if ((rs = sm_descend(st, x0, sg, lo, hi, &found, y))) return rs;
        if (!found) continue;
        double fy = st->s->ops->eval(st->s, y, 1, gr, NULL);
        if (!isfinite(fy)) return fail_nonfinite(st->ctx, "f", y);
        if ((rs = sm_center(st, y, -sg, gr, &thin, n))) return rs;
        if (sm_witness_near(st, y, -sg, 0.25 * h)) continue;
        if (st->nwit >= SM_MAX_WITNESSES) break;
        if ((rs = sm_add_witness(st, y, -sg, thin, n))) return rs;
    }
    /* continuation from the grid vertices inside thin parts */
    uint8_t *seen = as_alloc(st->ctx, g->count);
    if (!seen) return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    memset(seen, 0, g->count);
    rs = ANISTAR_OK;
    for (size_t cell = 0; cell < g->ncells && !rs && st->nwit < SM_MAX_WITNESSES; cell++) {
        if ((g->cell[cell] & (SM_UNRES | SM_MIXED)) != (SM_UNRES | SM_MIXED)) continue;
        size_t base = sm_cell_base(g, cell);
        int neg = 0;
        for (int c = 0; c < 8; c++) neg += g->sg[base + off[c]] < 0;
        int minority = neg <= 4 ? -1 : 1;
        for (int c = 0; c < 8 && !rs; c++) {
            size_t v = base + off[c];
            if (!g->ball[v] || g->sg[v] != minority || seen[v]) continue;
            seen[v] = 1;
            const double *gr = NULL;
            if ((rs = sm_grad(st, v, &gr))) break;
            double p[3], n[3] = {0, 0, 0};
            int thin;
            sm_vertex(g, v, p);
            if ((rs = sm_center(st, p, minority, gr, &thin, n))) break;
            /* steps of 2h: out of the 8 cells around the vertex */
            if (thin) rs = sm_expand(st, p, n, minority, 2 * h);
        }
    }
    as_free(st->ctx, seen, g->count);
    if (rs) return rs;
    /* continuation from the thin witnesses, the new ones included */
    for (size_t wi = 0; wi < st->nwit && st->nwit < SM_MAX_WITNESSES; wi++) {
        if (!st->wit[wi].thin) continue;
        double p[3], n[3];
        memcpy(p, st->wit[wi].p, sizeof p);
        memcpy(n, st->wit[wi].n, sizeof n);
        if ((rs = sm_expand(st, p, n, st->wit[wi].sg, h))) return rs;
    }
    return ANISTAR_OK;
}

/* ek: the unresolved cells around each edge (3 per vertex: its edges along +x, +y, +z). */
static void sm_edge_counts(sm_state *st) {
    sm_grid *g = &st->g;
    size_t off[8];
    sm_corner_offsets(g, off);
    memset(g->ek, 0, 3 * g->count);
    for (size_t cell = 0; cell < g->ncells; cell++) {
        if (!(g->cell[cell] & SM_UNRES)) continue;
        size_t base = sm_cell_base(g, cell);
        for (int c = 0; c < 8; c++)
            for (int ax = 0; ax < 3; ax++)
                if (!((c >> ax) & 1)) g->ek[3 * (base + off[c]) + (size_t)ax]++;
    }
}

/* ---- 6. links off the grid edges ---- */

typedef struct sm_cand {
    uint32_t node;
    double d2;
} sm_cand;

/* Nodes of sign sg other than self around p (the corners and witnesses of the 125 cells
 * within two of p's cell), in no particular order; at most cap. */
static size_t sm_gather(const sm_state *st, const double p0[3], uint32_t self, int sg,
                        sm_cand *cand, size_t cap) {
    const sm_grid *g = &st->g;
    size_t cc[3], n = g->n, nv = g->nv, m = 0;
    sm_cell_of(g, p0, cc);
    size_t lo[3], hi[3];
    for (int i = 0; i < 3; i++) {
        lo[i] = cc[i] > 1 ? cc[i] - 2 : 0;
        hi[i] = cc[i] + 2 < n ? cc[i] + 2 : n - 1;
    }
    for (size_t k = lo[2]; k <= hi[2] + 1; k++)
        for (size_t j = lo[1]; j <= hi[1] + 1; j++)
            for (size_t i = lo[0]; i <= hi[0] + 1 && m < cap; i++) {
                size_t v = i + nv * (j + nv * k);
                if (!g->ball[v] || g->sg[v] != sg || v == self) continue;
                double p[3];
                sm_vertex(g, v, p);
                cand[m].node = (uint32_t)v;
                cand[m++].d2 = v3_dist2(p, p0);
            }
    for (size_t k = lo[2]; k <= hi[2]; k++)
        for (size_t j = lo[1]; j <= hi[1]; j++)
            for (size_t i = lo[0]; i <= hi[0]; i++)
                for (int32_t x = g->whead[i + n * (j + n * k)]; x >= 0 && m < cap;
                     x = st->wit[x].next) {
                    const sm_wit *o = &st->wit[x];
                    if (o->sg != sg || g->count + (size_t)x == self) continue;
                    cand[m].node = (uint32_t)(g->count + (size_t)x);
                    cand[m++].d2 = v3_dist2(o->p, p0);
                }
    return m;
}

static inline int sm_cand_less(const sm_cand *a, const sm_cand *b) {
    return a->d2 < b->d2 || (a->d2 == b->d2 && a->node < b->node);
}

/* The nearest candidates of each region (root) other than w's: up to 2 per region, for at
 * most SM_GROUPS regions, nearest regions first. */
#define SM_GROUPS 16
typedef struct sm_group {
    int32_t root;
    int nc;
    sm_cand c[2];
} sm_group;

static int sm_groups(sm_state *st, int32_t wroot, const sm_cand *cand, size_t m, sm_group *gr) {
    int ng = 0;
    for (size_t i = 0; i < m; i++) {
        int32_t r = uf_find(st->uf, (int32_t)cand[i].node);
        if (r == wroot) continue;
        int k = 0;
        while (k < ng && gr[k].root != r) k++;
        if (k == ng) {
            if (ng < SM_GROUPS) {
                ng++;
            } else { /* replace the farthest region when nearer */
                int far = 0;
                for (int j = 1; j < ng; j++)
                    if (sm_cand_less(&gr[far].c[0], &gr[j].c[0])) far = j;
                if (!sm_cand_less(&cand[i], &gr[far].c[0])) continue;
                k = far;
            }
            gr[k].root = r;
            gr[k].nc = 0;
        }
        sm_group *G = &gr[k];
        if (G->nc < 2) {
            G->c[G->nc++] = cand[i];
        } else if (sm_cand_less(&cand[i], &G->c[1])) {
            G->c[1] = cand[i];
        } else {
            continue;
        }
        if (G->nc == 2 && sm_cand_less(&G->c[1], &G->c[0])) {
            sm_cand t = G->c[0];
            G->c[0] = G->c[1];
            G->c[1] = t;
        }
    }
    for (int a = 1; a < ng; a++) { /* nearest regions first */
        sm_group k = gr[a];
        int b = a;
        while (b > 0 && sm_cand_less(&k.c[0], &gr[b - 1].c[0])) {
            gr[b] = gr[b - 1];
            b--;
        }
        gr[b] = k;
    }
    return ng;
}

/* Node `node` (at p, of sign sg) joins the regions of its sign around it that it sees
 * without crossing S: the chords to their nearest nodes (two per region, nearest regions
 * first, at most SM_LINK_TRIES chords). */
#define SM_AROUND_CAP 512
static anistar_status sm_link_node(sm_state *st, uint32_t node, const double p[3], int sg,
                                   sm_cand *cand, sm_group *gr) {
    int tries = 0;
    size_t m = sm_gather(st, p, node, sg, cand, SM_AROUND_CAP);
    int ng = sm_groups(st, uf_find(st->uf, (int32_t)node), cand, m, gr);
    for (int k = 0; k < ng && tries < SM_LINK_TRIES; k++) {
        for (int c = 0; c < gr[k].nc && tries < SM_LINK_TRIES; c++) {
            if (uf_find(st->uf, (int32_t)node) == uf_find(st->uf, (int32_t)gr[k].c[c].node))
                break;
            double q[3];
            int sq;
            sm_node(st, gr[k].c[c].node, q, &sq);
            sm_scan sc;
            anistar_status rs = sm_scan_segment(st, p, q, &sc);
            if (rs) return rs;
            tries++;
            if (sc.n == 0) {
                uf_union(st->uf, (int32_t)node, (int32_t)gr[k].c[c].node);
                break;
            }
        }
    }
    return ANISTAR_OK;
}

/*
 * Joins across the cells that do not resolve S. Linked nodes: every witness, and the
 * corners of unresolved mixed cells whose sign is the minority there (at most 4 of the 8:
 * the vertices inside a part thinner than the cells, which the grid edges leave in
 * pieces). Each witness also gets a crossing record with one of the nearest nodes of the
 * other sign (a chord crossing S once; at most SM_PAIR_TRIES tried).
 */
static anistar_status sm_link(sm_state *st) {
    sm_grid *g = &st->g;
    sm_cand cand[SM_AROUND_CAP];
    sm_group gr[SM_GROUPS];
    size_t off[8];
    sm_corner_offsets(g, off);
    /* each minority corner once */
    uint8_t *mark = as_alloc(st->ctx, g->count);
    if (!mark) return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    memset(mark, 0, g->count);
    anistar_status rs = ANISTAR_OK;
    for (size_t cell = 0; cell < g->ncells && !rs; cell++) {
        if ((g->cell[cell] & (SM_UNRES | SM_MIXED)) != (SM_UNRES | SM_MIXED)) continue;
        size_t base = sm_cell_base(g, cell);
        int neg = 0;
        for (int c = 0; c < 8; c++) neg += g->sg[base + off[c]] < 0;
        int minority = neg <= 4 ? -1 : 1;
        for (int c = 0; c < 8 && !rs; c++) {
            size_t v = base + off[c];
            if (!g->ball[v] || g->sg[v] != minority || mark[v]) continue;
            mark[v] = 1;
            double p[3];
            sm_vertex(g, v, p);
            rs = sm_link_node(st, (uint32_t)v, p, minority, cand, gr);
        }
    }
    as_free(st->ctx, mark, g->count);
    for (size_t wi = 0; wi < st->nwit && !rs; wi++) {
        uint32_t node = (uint32_t)(g->count + wi);
        double p[3];
        memcpy(p, st->wit[wi].p, sizeof p);
        int sg = st->wit[wi].sg;
        if ((rs = sm_link_node(st, node, p, sg, cand, gr))) break;
        /* the crossing: the nearest nodes of the other sign */
        size_t m = sm_gather(st, p, node, -sg, cand, SM_AROUND_CAP);
        for (int t = 0; t < SM_PAIR_TRIES && m > 0; t++) {
            size_t best = 0;
            for (size_t i = 1; i < m; i++)
                if (sm_cand_less(&cand[i], &cand[best])) best = i;
            sm_cand c = cand[best];
            cand[best] = cand[--m];
            double q[3];
            int sq;
            sm_node(st, c.node, q, &sq);
            sm_scan sc;
            if ((rs = sm_scan_segment(st, p, q, &sc))) break;
            if (sc.n != 1) continue;
            rs = sm_add_bracket(st, &sc, 0, p, q, node, sg, c.node, NULL);
            break;
        }
    }
    return rs;
}

/* ---- 7. components ---- */

static int sm_pair_cmp(const void *pa, const void *pb) {
    const sm_pair *a = pa, *b = pb;
    if (a->rin != b->rin) return a->rin < b->rin ? -1 : 1;
    if (a->rout != b->rout) return a->rout < b->rout ? -1 : 1;
    return (a->rec > b->rec) - (a->rec < b->rec);
}

static int sm_rec_cmp(const void *pa, const void *pb) {
    const sm_rec *a = pa, *b = pb;
    if (a->comp != b->comp) return a->comp < b->comp ? -1 : 1;
    return (a->ord > b->ord) - (a->ord < b->ord);
}

/* The component of the pair of roots (rin, rout), -1 if there is none. */
static int32_t sm_pair_comp(const sm_state *st, uint32_t rin, uint32_t rout) {
    size_t lo = 0, hi = st->ncomp;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        const sm_pair *p = &st->pairs[mid];
        if (p->rin < rin || (p->rin == rin && p->rout < rout)) lo = mid + 1;
        else hi = mid;
    }
    if (lo < st->ncomp && st->pairs[lo].rin == rin && st->pairs[lo].rout == rout)
        return (int32_t)lo;
    return -1;
}

/* Distinct root pairs -> components (in the order of the pairs); records sorted by
 * component; the record buckets; the components of the Crofton crossings. */
static anistar_status sm_components(sm_state *st) {
    sm_grid *g = &st->g;
    if (st->nrec == 0) return ANISTAR_OK;
    st->pairs = as_alloc_array(st->ctx, st->nrec, sizeof(sm_pair));
    if (!st->pairs) return as_fail(st->ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    for (size_t i = 0; i < st->nrec; i++) {
        st->pairs[i].rin = (uint32_t)uf_find(st->uf, (int32_t)st->rec[i].nin);
        st->pairs[i].rout = (uint32_t)uf_find(st->uf, (int32_t)st->rec[i].nout);
        st->pairs[i].rec = (uint32_t)i;
    }
    qsort(st->pairs, st->nrec, sizeof(sm_pair), sm_pair_cmp);
    size_t m = 0;
    for (size_t i = 0; i < st->nrec; i++) {
        if (i > 0 && st->pairs[i].rin == st->pairs[i - 1].rin &&
            st->pairs[i].rout == st->pairs[i - 1].rout) {
            st->rec[st->pairs[i].rec].comp = (int32_t)(m - 1);
            continue;
        }
        st->rec[st->pairs[i].rec].comp = (int32_t)m;
        st->pairs[m++] = st->pairs[i];
    }
    st->ncomp = m;
    for (size_t i = 0; i < st->ncrof; i++)
        if (st->crof[i].rec >= 0) st->crof[i].comp = st->rec[st->crof[i].rec].comp;
    if (st->nrec) qsort(st->rec, st->nrec, sizeof(sm_rec), sm_rec_cmp);
    for (size_t i = st->nrec; i-- > 0;) {
        double mid[3];
        size_t cc[3];
        for (int k = 0; k < 3; k++) mid[k] = 0.5 * (st->rec[i].a[k] + st->rec[i].b[k]);
        size_t cell = sm_cell_of(g, mid, cc);
        st->rec[i].next = g->xhead[cell];
        g->xhead[cell] = (int32_t)i;
    }
    return ANISTAR_OK;
}

/* The component of the record nearest x among those of the cells within r cells of x's
 * cell, -1 if none. */
static int32_t sm_nearest_comp(const sm_state *st, const double x[3], size_t r) {
    const sm_grid *g = &st->g;
    size_t cc[3], n = g->n;
    sm_cell_of(g, x, cc);
    double best = INFINITY;
    int32_t comp = -1;
    for (size_t k = cc[2] > r ? cc[2] - r : 0; k <= cc[2] + r && k < n; k++)
        for (size_t j = cc[1] > r ? cc[1] - r : 0; j <= cc[1] + r && j < n; j++)
            for (size_t i = cc[0] > r ? cc[0] - r : 0; i <= cc[0] + r && i < n; i++)
                for (int32_t e = g->xhead[i + n * (j + n * k)]; e >= 0; e = st->rec[e].next) {
                    const sm_rec *rc = &st->rec[e];
                    double mid[3] = {0.5 * (rc->a[0] + rc->b[0]), 0.5 * (rc->a[1] + rc->b[1]),
                                     0.5 * (rc->a[2] + rc->b[2])};
                    double d2 = v3_dist2(mid, x);
                    if (d2 < best) {
                        best = d2;
                        comp = rc->comp;
                    }
                }
    return comp;
}

/* ---- 8. areas ---- */

static double sm_tri_area(const double a[3], const double b[3], const double c[3]) {
    double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]},
           v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]}, w[3];
    v3_cross(u, v, w);
    return 0.5 * v3_norm(w);
}

/* The root in [0, 1] of the cubic through (-1, fm), (0, fa), (1, fb), (2, fp) (fa, fb of
 * opposite signs), by Newton from the linear root t0; t0 when it leaves [0, 1]. */
static double sm_cubic_root(double fm, double fa, double fb, double fp, double t0) {
    double c1 = -fm / 3 - fa / 2 + fb - fp / 6, c2 = fm / 2 - fa + fb / 2,
           c3 = -fm / 6 + fa / 2 - fb / 2 + fp / 6, t = t0;
    for (int it = 0; it < 6; it++) {
        double v = fa + t * (c1 + t * (c2 + t * c3)), d = c1 + t * (2 * c2 + 3 * t * c3);
        if (!(d != 0)) return t0;
        double tn = t - v / d;
        if (!(tn >= 0 && tn <= 1)) return t0;
        if (fabs(tn - t) < 1e-7) return tn; /* 1e-7 of the edge: far below the area error */
        t = tn;
    }
    return t;
}

/* A grid of values for marching tetrahedra: nv^3 vertices o + h (i, j, k), values f,
 * ball flags (NULL: all in). */
typedef struct sm_mtgrid {
    size_t nv;
    double h, o[3];
    const double *f;
    const int8_t *ball;
} sm_mtgrid;

/* The point where S crosses the segment between vertices ia and ib (indices (i, j, k)),
 * by cubic interpolation along their line through the next vertices on both sides
 * (linear where they are missing). */
static void sm_mt_point(const sm_mtgrid *m, const size_t ia[3], const size_t ib[3], double x[3]) {
    size_t nv = m->nv;
    size_t a = ia[0] + nv * (ia[1] + nv * ia[2]), b = ib[0] + nv * (ib[1] + nv * ib[2]);
    double fa = m->f[a], fb = m->f[b], t = fa / (fa - fb);
    long im[3], ip[3];
    int ok = 1;
    for (int k = 0; k < 3; k++) {
        im[k] = 2 * (long)ia[k] - (long)ib[k];
        ip[k] = 2 * (long)ib[k] - (long)ia[k];
        if (im[k] < 0 || ip[k] < 0 || im[k] >= (long)nv || ip[k] >= (long)nv) ok = 0;
    }
    if (ok) {
        size_t vm = (size_t)im[0] + nv * ((size_t)im[1] + nv * (size_t)im[2]),
               vp = (size_t)ip[0] + nv * ((size_t)ip[1] + nv * (size_t)ip[2]);
        if (!m->ball || (m->ball[vm] && m->ball[vp]))
            t = sm_cubic_root(m->f[vm], fa, fb, m->f[vp], t);
    }
    for (int k = 0; k < 3; k++)
        x[k] = m->o[k] + m->h * ((double)ia[k] + t * ((double)ib[k] - (double)ia[k]));
}

/* The area of S inside cell (i, j, k) of m by marching tetrahedra: the 6 tetrahedra of
 * the cell around its diagonal from corner 0 to corner 7 (corner bits: +x, +y, +z), one
 * or two triangles in each with a sign change; each crossing point once per cell. */
static double sm_mt_cell(const sm_mtgrid *m, size_t i, size_t j, size_t k) {
    static const int perm[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2},
                                   {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    size_t nv = m->nv, idx[8][3];
    double f[8], x[8][8][3];
    unsigned char done[8][8];
    memset(done, 0, sizeof done);
    for (int c = 0; c < 8; c++) {
        idx[c][0] = i + (size_t)(c & 1);
        idx[c][1] = j + (size_t)((c >> 1) & 1);
        idx[c][2] = k + (size_t)((c >> 2) & 1);
        f[c] = m->f[idx[c][0] + nv * (idx[c][1] + nv * idx[c][2])];
    }
    double area = 0;
    for (int t = 0; t < 6; t++) {
        int corner[4] = {0, 1 << perm[t][0], (1 << perm[t][0]) | (1 << perm[t][1]), 7};
        int in[4], nin = 0, out[4], nout = 0;
        for (int q = 0; q < 4; q++) {
            if (f[corner[q]] < 0) in[nin++] = corner[q];
            else out[nout++] = corner[q];
        }
        if (!nin || !nout) continue;
        int pa[4], pb[4], np;
        if (nin == 1 || nout == 1) {
            int lone = nin == 1 ? in[0] : out[0];
            const int *oth = nin == 1 ? out : in;
            for (int q = 0; q < 3; q++) {
                pa[q] = lone;
                pb[q] = oth[q];
            }
            np = 3;
        } else {
            int qa[4] = {in[0], in[0], in[1], in[1]}, qb[4] = {out[0], out[1], out[1], out[0]};
            memcpy(pa, qa, sizeof pa);
            memcpy(pb, qb, sizeof pb);
            np = 4;
        }
        const double *v[4];
        for (int q = 0; q < np; q++) {
            int a = pa[q] < pb[q] ? pa[q] : pb[q], b = pa[q] < pb[q] ? pb[q] : pa[q];
            if (!done[a][b]) {
                sm_mt_point(m, idx[a], idx[b], x[a][b]);
                done[a][b] = 1;
            }
            v[q] = x[a][b];
        }
        area += sm_tri_area(v[0], v[1], v[2]);
        if (np == 4) area += sm_tri_area(v[0], v[2], v[3]);
    }
    return area;
}

/* The component of a mixed cell: that of one of its sign-change edges. */
static int32_t sm_cell_comp(sm_state *st, size_t cell) {
    const sm_grid *g = &st->g;
    for (int c = 0; c < 8; c++)
        for (int ax = 0; ax < 3; ax++) {
            if ((c >> ax) & 1) continue;
            size_t u = sm_corner(g, cell, c), v = sm_corner(g, cell, c | 1 << ax);
            if (g->sg[u] == g->sg[v]) continue;
            size_t in = g->sg[u] < 0 ? u : v, out = g->sg[u] < 0 ? v : u;
            return sm_pair_comp(st, (uint32_t)uf_find(st->uf, (int32_t)in),
                                (uint32_t)uf_find(st->uf, (int32_t)out));
        }
    return -1;
}

/* The area of a small component around p0, a point of its thin side (a witness): its
 * extent along the axes from the crossings of the six half-axes from p0 within 2h, then
 * marching tetrahedra on a grid of SM_SMALL_N^3 cells over that box. *area = 0 when a
 * half-axis has no crossing (the component is not small). */
static anistar_status sm_small_area(sm_state *st, const double p0[3], double *area) {
    const as_surface *s = st->s;
    anistar_context *ctx = st->ctx;
    double h = st->g.h, lo[3], hi[3];
    *area = 0;
    for (int ax = 0; ax < 3; ax++)
        for (int dir = -1; dir <= 1; dir += 2) {
            double b[3] = {p0[0], p0[1], p0[2]}, x[3];
            b[ax] += dir * 2 * h;
            int found;
            anistar_status rs = as_fsurface_crossing(ctx, s, p0, b, p0, &found, x);
            if (rs) return rs;
            if (!found) return ANISTAR_OK;
            if (dir < 0) lo[ax] = x[ax];
            else hi[ax] = x[ax];
        }
    double side = 0, c[3];
    for (int i = 0; i < 3; i++) {
        side = fmax(side, hi[i] - lo[i]);
        c[i] = 0.5 * (lo[i] + hi[i]);
    }
    side *= 1.3;
    if (!(side > 0)) return ANISTAR_OK;
    size_t nv = SM_SMALL_N + 1, count = nv * nv * nv;
    double *f = as_alloc_array(ctx, count, sizeof(double));
    if (!f) return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    sm_mtgrid m = {nv, side / SM_SMALL_N, {c[0] - side / 2, c[1] - side / 2, c[2] - side / 2}, f,
                   NULL};
    anistar_status rs = ANISTAR_OK;
    for (size_t idx = 0; idx < count && !rs; idx++) {
        double p[3] = {m.o[0] + m.h * (double)(idx % nv), m.o[1] + m.h * (double)((idx / nv) % nv),
                       m.o[2] + m.h * (double)(idx / (nv * nv))};
        f[idx] = fs_in_ball(s, p) ? fs_value(s, p) : 1;
        if (!isfinite(f[idx])) rs = fail_nonfinite(ctx, "f", p);
    }
    for (size_t k = 0; k < SM_SMALL_N && !rs; k++)
        for (size_t j = 0; j < SM_SMALL_N; j++)
            for (size_t i = 0; i < SM_SMALL_N; i++) *area += sm_mt_cell(&m, i, j, k);
    as_free(ctx, f, count * sizeof(double));
    return rs;
}

/* The Crofton weight of a crossing at x of an edge with k unresolved cells around it (of
 * its 4): k/4 h^2 / (|n_x| + |n_y| + |n_z|) (n the unit normal at x). 0 where the
 * gradient vanishes. */
static double sm_crofton(const sm_state *st, const double x[3], int k) {
    double gr[3] = {0, 0, 0};
    double fx = st->s->ops->eval(st->s, x, 1, gr, NULL);
    double l1 = fabs(gr[0]) + fabs(gr[1]) + fabs(gr[2]);
    if (!isfinite(fx) || !(l1 > 0) || !isfinite(l1)) return 0;
    return 0.25 * k * st->g.h * st->g.h * v3_norm(gr) / l1;
}

/* The cells around an edge that use the Crofton estimate: all but the resolved mixed
 * cells (marching tetrahedra). */
static int sm_crofton_cells(const sm_grid *g, size_t edge) {
    size_t cells[4];
    int m = sm_edge_cells(g, edge / 3, (int)(edge % 3), cells), k = 0;
    for (int i = 0; i < m; i++)
        k += (g->cell[cells[i]] & (SM_MIXED | SM_UNRES | SM_FRAG)) != SM_MIXED;
    return k;
}

/*
 * area[ncomp]. Resolved mixed cells: marching tetrahedra (vertices by cubic interpolation
 * along the grid lines). The other cells near S: Crofton's formula on the lattice, each
 * crossing of an edge weighted as in sm_crofton. A resolved mixed cell is a fragment cell
 * (Crofton too) when a corner bends (K > SM_RESOLVED L there) and its region was joined
 * from several pieces of the grid (a part thinner than the cells, where marching
 * tetrahedra see bubbles around the vertices inside it). Components with neither (smaller
 * than a cell) get sm_small_area.
 */
static anistar_status sm_areas(sm_state *st, double *area) {
    sm_grid *g = &st->g;
    anistar_context *ctx = st->ctx;
    size_t n = g->n, nodes = g->count + st->nwit;
    memset(area, 0, st->ncomp * sizeof(double));
    if (st->frag_candidates) {
        /* regions joined from several grid regions (fragment cells need such a region) */
        int32_t *first = as_alloc_array(ctx, nodes, sizeof(int32_t));
        uint8_t *joined = as_alloc(ctx, nodes);
        if (!first || !joined) {
            as_free(ctx, first, nodes * sizeof(int32_t));
            as_free(ctx, joined, nodes);
            return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        }
        for (size_t i = 0; i < nodes; i++) {
            first[i] = -1;
            joined[i] = 0;
        }
        for (size_t v = 0; v < g->count; v++) {
            if (!g->ball[v]) continue;
            int32_t r = uf_find(st->uf, (int32_t)v);
            if (first[r] < 0) first[r] = g->groot[v];
            else if (first[r] != g->groot[v]) joined[r] = 1;
        }
        for (size_t cell = 0; cell < g->ncells; cell++) {
            if ((g->cell[cell] & (SM_MIXED | SM_UNRES)) != SM_MIXED) continue;
            for (int c = 0; c < 8; c++) {
                size_t v = sm_corner(g, cell, c);
                if (g->K[v] > SM_RESOLVED * g->L[v] && joined[uf_find(st->uf, (int32_t)v)]) {
                    g->cell[cell] |= SM_FRAG;
                    break;
                }
            }
        }
        as_free(ctx, first, nodes * sizeof(int32_t));
        as_free(ctx, joined, nodes);
    }
    /* marching tetrahedra */
    sm_mtgrid m = {g->nv, g->h, {g->o[0], g->o[1], g->o[2]}, g->f, g->ball};
    for (size_t cell = 0; cell < g->ncells; cell++) {
        if ((g->cell[cell] & (SM_MIXED | SM_UNRES | SM_FRAG)) != SM_MIXED) continue;
        int32_t comp = sm_cell_comp(st, cell);
        if (comp < 0) continue;
        area[comp] += sm_mt_cell(&m, cell % n, (cell / n) % n, cell / (n * n));
    }
    /* the edges of fragment cells not scanned yet (no unresolved cell around them) */
    for (size_t cell = 0; cell < g->ncells; cell++) {
        if (!(g->cell[cell] & SM_FRAG)) continue;
        for (int c = 0; c < 8; c++)
            for (int ax = 0; ax < 3; ax++) {
                if ((c >> ax) & 1) continue;
                size_t u = sm_corner(g, cell, c), e = 3 * u + (size_t)ax;
                if (g->ek[e] != 0) continue; /* scanned (or done: 255) */
                g->ek[e] = 255;
                double a[3], b[3];
                sm_vertex(g, u, a);
                memcpy(b, a, sizeof b);
                b[ax] += g->h;
                sm_scan sc;
                anistar_status rs = sm_scan_segment(st, a, b, &sc);
                if (rs) return rs;
                for (int i = 0; i < sc.n; i++) {
                    double x[3];
                    if ((rs = sm_scan_point(st, &sc, i, a, b, x)) ||
                        (rs = sm_add_crof(st, x, e, -1)))
                        return rs;
                    /* a single crossing of a sign change: the component of its ends */
                    size_t v = u + (ax == 0 ? 1 : (ax == 1 ? g->nv : g->nv * g->nv));
                    if (sc.n == 1 && g->sg[u] != g->sg[v]) {
                        size_t in = g->sg[u] < 0 ? u : v, out = g->sg[u] < 0 ? v : u;
                        st->crof[st->ncrof - 1].comp =
                            sm_pair_comp(st, (uint32_t)uf_find(st->uf, (int32_t)in),
                                         (uint32_t)uf_find(st->uf, (int32_t)out));
                    }
                }
            }
    }
    for (size_t i = 0; i < st->ncrof; i++) {
        sm_crof *c = &st->crof[i];
        if (c->comp < 0) c->comp = sm_nearest_comp(st, c->x, 1);
        if (c->comp < 0) c->comp = sm_nearest_comp(st, c->x, 3);
        if (c->comp >= 0) area[c->comp] += sm_crofton(st, c->x, sm_crofton_cells(g, c->edge));
    }
    size_t small = 0;
    for (size_t i = 0; i < st->nrec && small < SM_SMALL_MAX;) {
        int32_t comp = st->rec[i].comp;
        size_t j = i;
        while (j < st->nrec && st->rec[j].comp == comp) j++;
        if (area[comp] < SM_SMALL_AREA * g->h * g->h) {
            /* from the node of its record on the side that is not a grid vertex (a witness
             * inside the small part), else the inside one */
            const sm_rec *r = &st->rec[i];
            uint32_t node = r->nin >= g->count ? r->nin : (r->nout >= g->count ? r->nout : r->nin);
            double p[3], a;
            int sg;
            sm_node(st, node, p, &sg);
            anistar_status rs = sm_small_area(st, p, &a);
            if (rs) return rs;
            if (a > 0) area[comp] = a;
            small++;
        }
        i = j;
    }
    return ANISTAR_OK;
}

/* ---- 9. points ---- */

/* One pick of a sample: the record bracketing the crossing and the point to refine from. */
typedef struct sm_job {
    const sm_rec *rec;
    double mid[3], x[3];
    int32_t comp;
    int hit;
} sm_job;

/*
 * The picks of up to q points of component comp from its m records rec (appended to
 * jobs[*nj..]): the farthest-point order (as_farthest_order) of the records' midpoints (a
 * stride of them when there are many: at most 8 q candidates). work holds 4 m doubles.
 * design: the order depends on the midpoints only, not on the refined crossings, so the
 * crossings can then be refined in any order (in parallel). It was a scan of every
 * candidate after each pick: 4096 picks among 32,768 candidates took 13% of the shock
 * sphere's run; the kd-tree and heap of as_farthest_order give the same order.
 */
static anistar_status sm_order(anistar_context *ctx, const sm_rec *rec, size_t m, size_t q,
                               int32_t comp, double *work, sm_job *jobs, size_t *nj) {
    size_t stride = m > 8 * q ? m / (8 * q) : 1;
    size_t nc = (m + stride - 1) / stride;
    if (q > nc) q = nc;
    /* work (4 m doubles) holds the candidates' midpoints, then their order */
    double *pts = work;
    int32_t *order = (int32_t *)(work + 3 * nc);
    for (size_t i = 0; i < nc; i++) {
        const sm_rec *r = &rec[i * stride];
        for (int k = 0; k < 3; k++) pts[3 * i + k] = 0.5 * (r->a[k] + r->b[k]);
    }
    size_t no = 0;
    anistar_status rs = as_farthest_order(ctx, pts, nc, q, order, &no);
    if (rs) return rs;
    for (size_t p = 0; p < no; p++) {
        size_t cur = (size_t)order[p];
        sm_job *j = &jobs[(*nj)++];
        j->rec = &rec[cur * stride];
        memcpy(j->mid, pts + 3 * cur, sizeof j->mid);
        j->comp = comp;
        j->hit = 0;
    }
    return ANISTAR_OK;
}

typedef struct sm_jobs {
    const as_surface *s;
    sm_job *job;
} sm_jobs;

static anistar_status sm_job_run(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)t;
    sm_jobs *J = arg;
    sm_job *j = &J->job[k];
    return as_fsurface_crossing(tctx, J->s, j->rec->a, j->rec->b, j->mid, &j->hit, j->x);
}

/* The analysis of S on the grid (values, classification, witnesses, crossings,
 * components, areas): the part of a sample that does not depend on its size. *area
 * receives st->ncomp areas (ctx's). */
static anistar_status sm_analyse(sm_state *st, double **area) {
    anistar_context *ctx = st->ctx;
    const as_surface *s = st->s;
    *area = NULL;
    anistar_status rs = sm_values(st);
    if (!rs) {
        sm_differences(st);
        rs = sm_classify(st);
    }
    if (!rs) rs = sm_witnesses(st);
    if (!rs) {
        sm_edge_counts(st);
        rs = sm_edges(st);
    }
    if (!rs) rs = sm_link(st);
    if (!rs) rs = sm_components(st);
    if (rs) return rs;
    if (st->ncomp == 0)
        return as_fail(ctx, ANISTAR_ENOSURFACE,
                       "surface: no surface found inside the bounding sphere (center %g %g %g, "
                       "radius %g): f keeps one sign on a %zu^3 grid (spacing %g) and near its "
                       "vertices where it bends",
                       s->center[0], s->center[1], s->center[2], s->radius, st->g.nv, st->g.h);
    *area = as_alloc_array(ctx, st->ncomp, sizeof(double));
    if (!*area) return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    if ((rs = sm_areas(st, *area))) {
        as_free(ctx, *area, st->ncomp * sizeof(double));
        *area = NULL;
    }
    return rs;
}

/* The sample of about max_points points from an analysis (st, its areas area0: not
 * changed); the crossings refined on pool (NULL: here). */
static anistar_status sm_sample(sm_state *st, const double *area0, size_t max_points,
                                as_pool *pool, as_point_sample *out) {
    anistar_context *ctx = st->ctx;
    memset(out, 0, sizeof *out);
    as_point_sample tmp;
    memset(&tmp, 0, sizeof tmp);
    double *work = NULL, *area = NULL;
    sm_job *jobs = NULL;
    size_t total = 0, nwork = 0, nj = 0;
    anistar_status rs = ANISTAR_OK;
    area = as_alloc_array(ctx, st->ncomp, sizeof(double));
    if (!area) return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    memcpy(area, area0, st->ncomp * sizeof(double));
    /* Quotas: proportional to the areas, at least one per component. The points go to
     * temporaries of capacity `total`, then to arrays of exactly n. */
    double atotal = 0;
    for (size_t k = 0; k < st->ncomp; k++) atotal += area[k];
    total = max_points + st->ncomp;
    nwork = st->nrec;
    tmp.points = as_alloc_array(ctx, total, 3 * sizeof(double));
    tmp.component = as_alloc_array(ctx, total, sizeof(int32_t));
    work = as_alloc_array(ctx, nwork, 4 * sizeof(double));
    jobs = as_alloc_array(ctx, total, sizeof *jobs);
    if (!tmp.points || !tmp.component || !work || !jobs) {
        rs = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        goto done;
    }
    for (size_t i = 0; i < st->nrec;) {
        int32_t comp = st->rec[i].comp;
        size_t j = i;
        while (j < st->nrec && st->rec[j].comp == comp) j++;
        double share = atotal > 0 ? area[comp] / atotal : (double)(j - i) / (double)st->nrec;
        size_t q = (size_t)((double)max_points * share);
        if (q < 1) q = 1;
        if ((rs = sm_order(ctx, st->rec + i, j - i, q, comp, work, jobs, &nj)) != ANISTAR_OK)
            goto done;
        i = j;
    }
    {
        sm_jobs J = {st->s, jobs};
        if (pool) {
            rs = as_pool_run(pool, (int32_t)nj, sm_job_run, &J);
        } else {
            for (size_t k = 0; k < nj && !rs; k++)
                rs = as_fsurface_crossing(ctx, st->s, jobs[k].rec->a, jobs[k].rec->b, jobs[k].mid,
                                          &jobs[k].hit, jobs[k].x);
        }
    }
    if (rs) goto done;
    for (size_t k = 0; k < nj; k++)
        if (jobs[k].hit) {
            memcpy(tmp.points + 3 * tmp.n, jobs[k].x, sizeof jobs[k].x);
            tmp.component[tmp.n] = jobs[k].comp;
            tmp.n++;
        }
    /* A component whose crossings all failed to refine (none should: each record brackets
     * one sign change) is dropped and the others renumbered. work (4 nrec >= ncomp
     * doubles) holds the new numbers. */
    size_t ncomp = 0;
    {
        int32_t *renum = (int32_t *)work;
        for (size_t k = 0; k < st->ncomp; k++) renum[k] = -1;
        for (size_t i = 0; i < tmp.n; i++) renum[tmp.component[i]] = 0;
        for (size_t k = 0; k < st->ncomp; k++)
            if (renum[k] == 0) {
                area[ncomp] = area[k];
                renum[k] = (int32_t)ncomp++;
            }
        for (size_t i = 0; i < tmp.n; i++) tmp.component[i] = renum[tmp.component[i]];
    }
    if (ncomp == 0) {
        rs = as_fail(ctx, ANISTAR_EINTERNAL, "sampling: no crossing could be refined");
        goto done;
    }
    out->points = as_alloc_array(ctx, tmp.n, 3 * sizeof(double));
    out->component = as_alloc_array(ctx, tmp.n, sizeof(int32_t));
    out->area = as_alloc_array(ctx, ncomp, sizeof(double));
    if (!out->points || !out->component || !out->area) {
        as_free(ctx, out->points, tmp.n * 3 * sizeof(double));
        as_free(ctx, out->component, tmp.n * sizeof(int32_t));
        as_free(ctx, out->area, ncomp * sizeof(double));
        memset(out, 0, sizeof *out);
        rs = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        goto done;
    }
    memcpy(out->points, tmp.points, tmp.n * 3 * sizeof(double));
    memcpy(out->component, tmp.component, tmp.n * sizeof(int32_t));
    memcpy(out->area, area, ncomp * sizeof(double));
    out->n = tmp.n;
    out->ncomponents = ncomp;
    out->spacing = st->g.h;
done:
    as_free(ctx, jobs, total * sizeof *jobs);
    as_free(ctx, work, nwork * 4 * sizeof(double));
    as_free(ctx, tmp.points, total * 3 * sizeof(double));
    as_free(ctx, tmp.component, total * sizeof(int32_t));
    as_free(ctx, area, st->ncomp * sizeof(double));
    if (rs) memset(out, 0, sizeof *out);
    return rs;
}

/* ---- the analysis kept in the surface: samples of several sizes from one ------------ */

/* What sm_sample needs of an analysis: the crossing records (sorted by component), the
 * components' areas and the grid spacing. 72 bytes per grid edge crossing S (the
 * grid values and classes, 45 bytes per node, 12 MB, are freed after the analysis). */
struct as_sbasis {
    sm_rec *rec;
    size_t nrec;
    double *area;
    size_t ncomp;
    double h;
};

static void sb_free(anistar_context *ctx, struct as_sbasis *b) {
    if (!b) return;
    as_free(ctx, b->rec, b->nrec * sizeof(sm_rec));
    as_free(ctx, b->area, b->ncomp * sizeof(double));
    as_free(ctx, b, sizeof *b);
}

/*
 * The analysis of S for sampling, made once per surface: the first call analyses S (grid
 * values on pool when given) and keeps the result in s->basis, allocated with the
 * surface's own context (which frees it with the surface); later calls return it. Errors
 * go to ctx and are not kept (a failed analysis is made again on the next call).
 * design: the metric's defaults (256 points), the mesher's initial points (256), its
 * estimate (1,024) and its feature sample (4,096) all sample S: one analysis instead of
 * two saved 4.5% of the instructions of a skull run and 2.8% of the paper's torus. The
 * surface is used by one thread at a time (docs/api.md), so the cache needs no lock.
 */
static anistar_status sb_get(anistar_context *ctx, const as_surface *s, as_pool *pool,
                             const struct as_sbasis **out) {
    *out = s->basis;
    if (s->basis) return ANISTAR_OK;
    sm_state st;
    memset(&st, 0, sizeof st);
    st.ctx = ctx;
    st.s = s;
    st.pool = pool;
    double *area = NULL;
    anistar_status rs = sm_analyse(&st, &area);
    if (!rs && st.nrec == 0) /* cannot happen: every component has a crossing record */
        rs = as_fail(ctx, ANISTAR_EINTERNAL, "sampling: components without a crossing");
    if (!rs) {
        anistar_context *sx = s->ctx;
        struct as_sbasis *b = as_alloc(sx, sizeof *b);
        sm_rec *rec = as_alloc_array(sx, st.nrec, sizeof(sm_rec));
        double *ar = as_alloc_array(sx, st.ncomp, sizeof(double));
        if (!b || !rec || !ar) {
            as_free(sx, b, sizeof *b);
            as_free(sx, rec, st.nrec * sizeof(sm_rec));
            as_free(sx, ar, st.ncomp * sizeof(double));
            rs = as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
        } else {
            memcpy(rec, st.rec, st.nrec * sizeof(sm_rec));
            memcpy(ar, area, st.ncomp * sizeof(double));
            b->rec = rec;
            b->nrec = st.nrec;
            b->area = ar;
            b->ncomp = st.ncomp;
            b->h = st.g.h;
            ((as_surface *)s)->basis = b; /* the cache of a logically const surface */
            *out = b;
        }
    }
    if (area) as_free(ctx, area, st.ncomp * sizeof(double));
    sm_state_free(&st);
    return rs;
}

/* A sample of max_points points from the kept analysis; crossings on pool (NULL: here). */
static anistar_status sb_sample(anistar_context *ctx, const as_surface *s, as_pool *pool,
                                size_t max_points, as_point_sample *out) {
    memset(out, 0, sizeof *out);
    if (!s->ops->eval) return fail_no_function(ctx, s);
    if (max_points == 0) max_points = 64;
    const struct as_sbasis *b;
    anistar_status rs = sb_get(ctx, s, pool, &b);
    if (rs) return rs;
    sm_state st; /* the part of a state that sm_sample reads */
    memset(&st, 0, sizeof st);
    st.ctx = ctx;
    st.s = s;
    st.rec = b->rec;
    st.nrec = b->nrec;
    st.ncomp = b->ncomp;
    st.g.h = b->h;
    return sm_sample(&st, b->area, max_points, pool, out);
}

anistar_status as_fsurface_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                  as_point_sample *out) {
    return sb_sample(ctx, s, NULL, max_points, out);
}

/* ---- a sampler: the surface's samples with the mesher's threads --------------------- */

struct as_sampler {
    const as_surface *s;
    as_pool *pool; /* threads for the grid values and the crossings (NULL: none) */
};

anistar_status as_sampler_new(anistar_context *ctx, const as_surface *s, as_pool *pool,
                              as_sampler **out) {
    *out = as_alloc(ctx, sizeof **out);
    if (!*out) return as_fail(ctx, ANISTAR_ENOMEM, "sampling: out of memory");
    memset(*out, 0, sizeof **out);
    (*out)->s = s;
    (*out)->pool = pool;
    return ANISTAR_OK;
}

anistar_status as_sampler_sample(anistar_context *ctx, as_sampler *sp, size_t max_points,
                                 as_point_sample *out) {
    const as_surface *s = sp->s;
    if (s->ops->sample || !s->ops->eval) return as_surface_sample(ctx, s, max_points, out);
    return sb_sample(ctx, s, sp->pool, max_points, out);
}

void as_sampler_free(anistar_context *ctx, as_sampler *sp) {
    if (!sp) return;
    as_free(ctx, sp, sizeof *sp);
}
