/*
 * anistar — anisotropic Delaunay meshes of surfaces.
 *
 * The one public header. Every public symbol starts with anistar_ or ANISTAR_.
 *
 * Conventions (all functions):
 *  - Handles are opaque and come in create/free pairs; free functions accept NULL.
 *  - Fallible functions return an anistar_status (ANISTAR_OK == 0). On failure the
 *    context that the call used keeps a one-line message: anistar_last_error(ctx).
 *  - Nothing is global: every object hangs off a context. A context and the objects
 *    made from it may be used by one thread at a time; two contexts in two threads
 *    never interfere.
 *  - The library never prints, never calls exit or abort, and installs no signal
 *    handlers.
 *  - Symmetric tensors are 6 doubles in the order m11 m12 m13 m22 m23 m33.
 *  - Points are double[3].
 *
 * MIT licence; see LICENSE.
 */
#ifndef ANISTAR_H
#define ANISTAR_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(_WIN32) && defined(ANISTAR_BUILDING_DLL)
#define ANISTAR_API __declspec(dllexport)
#elif defined(__GNUC__) || defined(__clang__)
#define ANISTAR_API __attribute__((visibility("default")))
#else
#define ANISTAR_API
#endif

/* ------------------------------------------------------------------------------------ */
/* Version                                                                                */
/* ------------------------------------------------------------------------------------ */

#define ANISTAR_VERSION_MAJOR 0
#define ANISTAR_VERSION_MINOR 1
#define ANISTAR_VERSION_PATCH 0
/* Encoded as MAJOR*10000 + MINOR*100 + PATCH: compare with anistar_version_number(). */
#define ANISTAR_VERSION_NUMBER \
    (ANISTAR_VERSION_MAJOR * 10000 + ANISTAR_VERSION_MINOR * 100 + ANISTAR_VERSION_PATCH)

/* The version of the library linked at run time, "MAJOR.MINOR.PATCH". Static string. */
ANISTAR_API const char *anistar_version(void);
/* The same as a number, comparable with ANISTAR_VERSION_NUMBER. */
ANISTAR_API int anistar_version_number(void);

/* ------------------------------------------------------------------------------------ */
/* Status                                                                                 */
/* ------------------------------------------------------------------------------------ */

/* X-macro table: name, value, message. One table feeds the enum and the strings. */
#define ANISTAR_STATUS_TABLE(X)                                                           \
    X(OK, 0, "success")                                                                   \
    X(INCOMPLETE, 1, "stopped at a limit; the mesh of consistent facets is valid")       \
    X(EINVAL, 2, "invalid argument")                                                      \
    X(ENOMEM, 3, "out of memory")                                                         \
    X(EIO, 4, "input/output error")                                                       \
    X(EFORMAT, 5, "malformed or unsupported file or expression")                          \
    X(ENOSURFACE, 6, "no surface found inside the bounding sphere")                       \
    X(ECANCELED, 7, "canceled by the caller")                                             \
    X(EINTERNAL, 8, "internal error (a bug in anistar: please report it)")

typedef enum anistar_status {
#define ANISTAR_STATUS_ENUM_(name, value, msg) ANISTAR_##name = value,
    ANISTAR_STATUS_TABLE(ANISTAR_STATUS_ENUM_)
#undef ANISTAR_STATUS_ENUM_
        ANISTAR_STATUS_COUNT_ /* not a status: the number of statuses */
} anistar_status;

/* A static message for a status, e.g. "out of memory"; "unknown status" otherwise. */
ANISTAR_API const char *anistar_status_string(anistar_status st);
/* The enumerator's name without prefix, e.g. "ENOMEM"; "UNKNOWN" otherwise. */
ANISTAR_API const char *anistar_status_name(anistar_status st);

/* ------------------------------------------------------------------------------------ */
/* Context                                                                                */
/* ------------------------------------------------------------------------------------ */

/*
 * A realloc-style allocator (as Lua's lua_Alloc):
 *   fn(user, NULL, 0, n)       allocate n > 0 bytes, NULL on failure;
 *   fn(user, p, old, n)        resize the block p of old bytes to n > 0 bytes; on failure
 *                              return NULL and leave p untouched;
 *   fn(user, p, old, 0)        free p (p may be NULL); the return value is ignored.
 * Blocks must be aligned for any object type (as malloc's). `old` is always the size
 * the block was last allocated with, so a pool or a counting allocator needs no header.
 */
typedef void *(*anistar_alloc_fn)(void *user, void *ptr, size_t old_size, size_t new_size);

typedef struct anistar_allocator {
    anistar_alloc_fn fn; /* in: required */
    void *user;          /* in: passed to fn, owned by the caller */
} anistar_allocator;

typedef struct anistar_context anistar_context;

/* Create a context. a == NULL uses malloc/realloc/free; otherwise *a is copied and must
 * stay usable until anistar_context_free. Returns NULL when memory runs out. */
ANISTAR_API anistar_context *anistar_context_new(const anistar_allocator *a);
/* Free the context. Every object made from it must have been freed before. NULL is ok. */
ANISTAR_API void anistar_context_free(anistar_context *ctx);
/* The message of the last failed call made with ctx ("" if none). Owned by ctx, valid
 * until the next call that uses ctx. ctx == NULL gives a static message. */
ANISTAR_API const char *anistar_last_error(const anistar_context *ctx);
/* The status of the last failed call made with ctx (ANISTAR_OK if none). */
ANISTAR_API anistar_status anistar_last_status(const anistar_context *ctx);

/* ------------------------------------------------------------------------------------ */
/* Exact geometric predicates                                                             */
/* ------------------------------------------------------------------------------------ */

/*
 * Adaptive exact predicates (Shewchuk's conventions). The sign is always exact; the
 * magnitude is an approximation of the determinant.
 *
 * anistar_orient3d(a,b,c,d) > 0 when d lies below the plane through a, b, c, where
 *   "below" is the side from which a, b, c appear clockwise; equivalently a, b, c appear
 *   counterclockwise seen from above. It is the determinant
 *   | a-d ; b-d ; c-d | (rows), 0 when the four points are coplanar.
 * anistar_insphere(a,b,c,d,e) > 0 when e lies inside the sphere through a, b, c, d,
 *   provided orient3d(a,b,c,d) > 0 (the sign flips otherwise); 0 when cospherical.
 *
 * Valid input range: finite coordinates whose nonzero magnitudes lie in
 * [1e-40, 1e+40] (no intermediate product of the exact evaluation underflows or
 * overflows there). NaN or infinite coordinates give a NaN result. Outside the range
 * the sign may be wrong.
 */
ANISTAR_API double anistar_orient3d(const double a[3], const double b[3], const double c[3],
                                    const double d[3]);
ANISTAR_API double anistar_insphere(const double a[3], const double b[3], const double c[3],
                                    const double d[3], const double e[3]);

/* ------------------------------------------------------------------------------------ */
/* Metric tensors                                                                         */
/* ------------------------------------------------------------------------------------ */

/*
 * A metric tensor M is symmetric positive definite, given as m11 m12 m13 m22 m23 m33.
 * These functions return ANISTAR_EINVAL (with a message in ctx) for NULL arguments,
 * non-finite entries, or a tensor that is not positive definite or whose condition
 * number exceeds 1e24.
 */

/* The distortion gamma(M, N) = max(|F_M F_N^-1|, |F_N F_M^-1|) >= 1 between two metrics
 * (F = M^(1/2)); 1 iff M == N (paper 2.2). */
ANISTAR_API anistar_status anistar_tensor_distortion(anistar_context *ctx, const double m[6],
                                                     const double n[6], double *gamma);
/* The M-distance |M^(1/2) (b - a)| between two points. */
ANISTAR_API anistar_status anistar_tensor_distance(anistar_context *ctx, const double m[6],
                                                   const double a[3], const double b[3],
                                                   double *dist);
/* The symmetric square root F = M^(1/2) (F^T F = M), as 6 doubles. */
ANISTAR_API anistar_status anistar_tensor_sqrt(anistar_context *ctx, const double m[6],
                                               double f[6]);

/* ==== SURFACES AND METRIC FIELDS (issue 4) — section owned by the surface layer ==== */

/* ------------------------------------------------------------------------------------ */
/* Surfaces                                                                               */
/* ------------------------------------------------------------------------------------ */

/*
 * A surface S (opaque) is the boundary of the inside region {p : |p - c| <= R, f(p) < 0}
 * of a function f inside a bounding sphere (center c, radius R): f < 0 inside, and
 * everything beyond the sphere counts as outside. S must lie strictly inside the sphere.
 *
 * Conventions of the queries below:
 *  - the normal is the OUTWARD unit normal +grad f/|grad f|;
 *  - principal curvatures are positive where S is convex (a sphere of radius r has
 *    1/r, 1/r) and of opposite signs at saddle points, k1 >= k2;
 *  - lengths are accurate to 1e-12 R (roots, projections);
 *  - a NaN or infinite value of f is an error (ANISTAR_EINVAL, the message names the
 *    point), never a sign.
 * A surface keeps a pointer to the context it was made with: the queries below take no
 * context and record their error messages there, so (as every object of a context) a
 * surface is queried from one thread at a time through this API. The surface itself is
 * never modified by a query (the mesher queries one surface from several threads, each
 * with its own context).
 */
typedef struct anistar_surface anistar_surface;

/*
 * An implicit function given by callbacks. value is required; gradient (g = grad f)
 * and hessian (h = m11 m12 m13 m22 m23 m33) are optional: when absent, central finite
 * differences with steps relative to R replace them (gradient: step 6e-6 R, relative
 * accuracy ~1e-10; Hessian from the gradient: ~1e-10; Hessian from values only: step
 * 1.2e-4 R, ~1e-8). The callbacks must be pure functions of p (called from several
 * threads when the surface is shared); user is passed back untouched and stays owned by
 * the caller, who keeps it alive as long as the surface.
 */
typedef struct anistar_implicit_fn {
    double (*value)(const double p[3], void *user);              /* in: required */
    void (*gradient)(const double p[3], double g[3], void *user); /* in: may be NULL */
    void (*hessian)(const double p[3], double h[6], void *user);  /* in: may be NULL */
    void *user;                                                    /* in: passed back */
} anistar_implicit_fn;

/* f(x,y,z) = 0 from callbacks, inside the sphere (center, radius > 0). *fn is copied. */
ANISTAR_API anistar_status anistar_surface_from_implicit(anistar_context *ctx,
                                                         const anistar_implicit_fn *fn,
                                                         const double center[3], double radius,
                                                         anistar_surface **out);

/* f(x,y,z) = 0 from an expression (syntax: docs/cli.md, e.g.
 * "R=10; r=1; (sqrt(x^2+y^2)-R)^2 + z^2 - r^2"), with exact first and second derivatives.
 * ANISTAR_EFORMAT for a malformed expression (the message names the column). */
ANISTAR_API anistar_status anistar_surface_from_expression(anistar_context *ctx,
                                                           const char *expr,
                                                           const double center[3],
                                                           double radius,
                                                           anistar_surface **out);

/* A built-in surface from "NAME[,PARAM=VALUE]..." (e.g. "torus,R=5,r=2"; every built-in
 * also takes bound=RADIUS). ANISTAR_EINVAL for an unknown name or parameter or a bad
 * value. See anistar_surface_builtin_info for the list. */
ANISTAR_API anistar_status anistar_surface_builtin(anistar_context *ctx, const char *spec,
                                                   anistar_surface **out);

/* The i-th built-in (i = 0, 1, ...): its name and a one-line description (formula,
 * parameters and defaults, bounding radius, genus). Static strings. Returns
 * ANISTAR_EINVAL past the last one. */
ANISTAR_API anistar_status anistar_surface_builtin_info(size_t i, const char **name,
                                                        const char **description);

/* Free a surface (NULL is ok). Every metric made on it must have been freed before. */
ANISTAR_API void anistar_surface_free(anistar_surface *s);

/* The bounding sphere. */
ANISTAR_API anistar_status anistar_surface_bound(const anistar_surface *s, double center[3],
                                                 double *radius);

/* f at p, and when g (h) is not NULL its gradient (Hessian, m11 m12 m13 m22 m23 m33). */
ANISTAR_API anistar_status anistar_surface_eval(const anistar_surface *s, const double p[3],
                                                double *f, double g[3], double h[6]);

/* *side = -1 inside, +1 outside (or beyond the bounding sphere), 0 exactly on S. */
ANISTAR_API anistar_status anistar_surface_side(const anistar_surface *s, const double p[3],
                                                int *side);

/* The crossing of the segment [a, b] with S nearest ref: *found = 1 and the point in x,
 * or *found = 0 when the segment does not meet S (a segment touching S tangentially is
 * reported at the touching point when that is found within 1e-12 R). */
ANISTAR_API anistar_status anistar_surface_crossing(const anistar_surface *s, const double a[3],
                                                    const double b[3], const double ref[3],
                                                    int *found, double x[3]);

/* The projection of p onto S: the closest point of S when p is closer to S than S's
 * local radius of curvature (otherwise a nearby foot point), with |f|/|grad f| <= 1e-12 R.
 * ANISTAR_ENOSURFACE when no zero of f is found near the lines through p tried. */
ANISTAR_API anistar_status anistar_surface_project(const anistar_surface *s, const double p[3],
                                                   double q[3]);

/* The outward unit normal of the level set of f through p (S when p is on S).
 * ANISTAR_EINVAL where grad f vanishes. */
ANISTAR_API anistar_status anistar_surface_normal(const anistar_surface *s, const double p[3],
                                                  double n[3]);

/* Principal curvatures k[0] >= k[1] and unit principal directions dir1 (of k[0]), dir2
 * (of k[1]) of the level set of f through p (dir1, dir2, normal: right-handed). At
 * umbilic points the directions are any orthonormal tangent pair. dir1, dir2 may be NULL.
 * ANISTAR_EINVAL where grad f vanishes. */
ANISTAR_API anistar_status anistar_surface_curvature(const anistar_surface *s,
                                                     const double p[3], double k[2],
                                                     double dir1[3], double dir2[3]);

/* ------------------------------------------------------------------------------------ */
/* Metric fields                                                                          */
/* ------------------------------------------------------------------------------------ */

/*
 * A metric field (opaque) maps points of a surface to metric tensors M (m11 m12 m13 m22
 * m23 m33). Every tensor it returns is symmetric positive definite with finite entries,
 * and the eigenvalues of F = M^(1/2) are within a ratio of 1e6 (smaller ones are raised).
 * A metric keeps a pointer to its surface, which must outlive it, and to the context it
 * was made with (anistar_metric_eval records its error message there).
 */
typedef struct anistar_metric anistar_metric;

/* A custom field: fill m at p (a point of S) given the outward unit normal there
 * ((0,0,0) where grad f vanishes). Return 0 on success, nonzero on failure (then
 * anistar_metric_eval fails with ANISTAR_EINVAL). Must be a pure function of its inputs. */
typedef int (*anistar_metric_fn)(const double p[3], const double normal[3], double m[6],
                                 void *user);

/* A field from a SPEC, the syntax of the command line's --metric (docs/cli.md):
 *   euclidean | uniform[,h=H] | curvature[,eps=E][,en=N][,power=P]
 *   | shock[,lambda=L][,phi=F][,en=N] | gradient:EXPR[,phi=F][,en=N]
 *   | hessian:EXPR[,eps=E][,en=N][,power=P] | sol:FILE
 * Options follow the name (or the expression) after commas at parenthesis depth 0:
 * "hessian:max(x,y)^2,eps=0.5". Defaults: curvature eps = 1/R (R the bounding radius),
 * power 1; shock lambda 0.6, phi 1; gradient phi 1; hessian power 0.5 and eps = 1e-3 x
 * the largest tangential |H| eigenvalue over the surface sample; e_n (F's eigenvalue
 * along the normal) = the largest tangential eigenvalue of F over a sample of S.
 * ANISTAR_EINVAL for an unknown name or option or a bad value, ANISTAR_EFORMAT for a
 * malformed expression or unbalanced parentheses; computing defaults samples S and may
 * return ANISTAR_ENOSURFACE. sol:FILE is ANISTAR_EINVAL for now (needs a triangle-mesh
 * surface). */
ANISTAR_API anistar_status anistar_metric_from_spec(anistar_context *ctx,
                                                    const anistar_surface *s, const char *spec,
                                                    anistar_metric **out);

/* Check a SPEC's syntax, names, options and values (compiling any expression) without
 * a surface: the errors of anistar_metric_from_spec that do not depend on the surface. */
ANISTAR_API anistar_status anistar_metric_spec_check(anistar_context *ctx, const char *spec);

/* A constant tensor m (must be finite and positive definite). s may be NULL. */
ANISTAR_API anistar_status anistar_metric_uniform(anistar_context *ctx, const anistar_surface *s,
                                                  const double m[6], anistar_metric **out);

/* A custom field on s; user is passed back to fn and stays owned by the caller. */
ANISTAR_API anistar_status anistar_metric_from_callback(anistar_context *ctx,
                                                        const anistar_surface *s,
                                                        anistar_metric_fn fn, void *user,
                                                        anistar_metric **out);

/* The tensor t at p, a point of S. Off S the field is evaluated at p as given (with the
 * normal and curvatures of the level set of f through p): project first
 * (anistar_surface_project) for the value on S. ANISTAR_EINVAL, with a message naming p,
 * when f is not finite at p or a custom callback fails or returns a non-finite or
 * non-positive-definite tensor. */
ANISTAR_API anistar_status anistar_metric_eval(const anistar_metric *m, const double p[3],
                                               double t[6]);

/* Free a metric (NULL is ok). */
ANISTAR_API void anistar_metric_free(anistar_metric *m);

/* ==== END SURFACES AND METRIC FIELDS ==== */

#ifdef __cplusplus
}
#endif

#endif /* ANISTAR_H */
