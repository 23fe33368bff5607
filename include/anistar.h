/*
 * anistar — anisotropic Delaunay meshes of surfaces.
 *
 * The one public header. Every public symbol starts with anistar_ or ANISTAR_.
 *
 * anistar builds a triangle mesh of a surface S whose every vertex star is Delaunay for that
 * vertex's own metric tensor. A program makes a context, a surface (an implicit function, a
 * closed triangle mesh or an isosurface of a 3D image), a metric field on it and a mesher,
 * runs the mesher and takes the output mesh; the sections below follow that order:
 *   Version, Status, Context          what every program needs
 *   Exact geometric predicates        orient3d and insphere, usable on their own
 *   Metric tensors                    distortion, distance and square root of tensors
 *   Surfaces                          what is meshed, and the queries on it
 *   Metric fields                     the tensor at each point of a surface
 *   Mesher                            parameters, progress, stopping, the run and its outcomes
 *   Output mesh                       statistics, copy-out getters, writers
 *   What a file holds                 a mesh's or an image's properties before meshing
 *   Rendering meshes to PNG           pictures of meshes, without dependencies
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

/*
 * The version this header belongs to (compile time) and the version of the library a
 * program runs with (run time): compare the two to detect a mismatched shared library.
 * Versions before 1.0 may change the API between minor versions.
 */

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

/*
 * Every fallible function returns one of these statuses; ANISTAR_OK is 0, so
 * `if (anistar_...(...))` tests for failure. ANISTAR_INCOMPLETE is the mesher's "stopped
 * early, the partial mesh is valid"; every other nonzero status is an error whose one-line
 * message is in the context (anistar_last_error).
 */

/* X-macro table: name, value, message. One table feeds the enum and the strings. */
#define ANISTAR_STATUS_TABLE(X)                                                           \
    X(OK, 0, "success")                                                                   \
    X(INCOMPLETE, 1, "stopped before a certified mesh; the mesh of consistent facets is valid") \
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
 * A context owns the allocator every object made from it uses, and the message and status
 * of the last failed call. Make one per thread of work; free it last.
 */

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
 * Valid input range: finite coordinates, each either 0 or of magnitude in
 * [1e-40, 1e+40]. There every intermediate value of the exact evaluation is a multiple
 * of 2^-1074 (so underflow loses nothing) and stays far below overflow; the sign is
 * proved exact and is checked against exact rational arithmetic at magnitudes from
 * 1e-40 to 1e+40. (In practice exactness holds further, to about [1e-90, 1e+100] for
 * orient3d and [1e-48, 1e+60] for insphere, but that is not promised.) Outside the
 * range the sign may be wrong; an overflow of the evaluation usually returns NaN.
 * NaN or infinite coordinates return NaN, and so does a NULL argument.
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
 * with its own context); the first sample of S taken for it (by a metric's defaults or a
 * mesher) is kept in it for the next ones (72 bytes per grid edge S crosses: 0.3-0.6 MB
 * on the images of test/data; freed with the surface).
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

/*
 * A closed triangle mesh read from a file, the format chosen by the extension
 * (case-insensitive): .off .obj .ply .stl .mesh .meshb (Medit) .vtk .vtu. The mesh must
 * be a closed, orientable 2-manifold without zero-area triangles; its triangles are
 * reoriented consistently (outward) and vertices of no triangle are ignored. Triangle-mesh
 * surfaces have no function f: anistar_surface_eval gives the signed distance to the mesh
 * (negative inside) and its gradient, and no Hessian (ANISTAR_EINVAL if h is asked); side,
 * crossing and projection are exact queries on the triangles (the projection is the
 * closest point of the mesh); normals, curvatures and directions come from per-vertex
 * polynomial fits ("jets", degree 2 on the 16 nearest vertices, paper 5.2.3)
 * interpolated over the triangle of the closest point.
 * Returns ANISTAR_EIO (the file cannot be read), ANISTAR_EFORMAT (malformed file, unknown
 * extension, or a mesh that is not a closed 2-manifold: the message names every problem
 * with its count, e.g. "open.off: not a closed 2-manifold: 12 border edges"),
 * ANISTAR_EINVAL for an image extension (.inr .nrrd .nhdr .mha .mhd: "an image needs an
 * isovalue: use anistar_surface_from_image_file"), ANISTAR_ENOMEM.
 */
ANISTAR_API anistar_status anistar_surface_read(anistar_context *ctx, const char *path,
                                                anistar_surface **out);

/* The same from arrays: nv vertices xyz (x y z each), nt triangles tri (three 0-based
 * vertex indices each). Both are copied. ANISTAR_EINVAL for an index out of range or a
 * coordinate that is not finite (or not 0 and outside [1e-100, 1e100] in magnitude),
 * ANISTAR_EFORMAT for a mesh that is not a closed 2-manifold (as above). */
ANISTAR_API anistar_status anistar_surface_from_triangles(anistar_context *ctx,
                                                          const double *xyz, size_t nv,
                                                          const int32_t *tri, size_t nt,
                                                          anistar_surface **out);

/* Which side of an isovalue is inside an image surface. */
#define ANISTAR_INSIDE_GREATER 1 /* inside where the image value exceeds iso (gray images) */
#define ANISTAR_INSIDE_LESS (-1) /* inside where the image value is below iso */

/* How an image is reconstructed (the fit of its cubic B-spline; docs/api.md, images). */
#define ANISTAR_FIT_AUTO 0        /* SMOOTH for an image of at most 16 distinct voxel values
                                     (a label image, a mask), INTERPOLATE for any other */
#define ANISTAR_FIT_INTERPOLATE 1 /* through every voxel value; rings (overshoots) by up to
                                     11% of a jump on each side of it */
#define ANISTAR_FIT_SMOOTH 2      /* the approximating spline: between the values of the
                                     4x4x4 voxels around each point (no overshoot), blurred
                                     by about a voxel */

/*
 * The isosurface value = iso of a 3D image file (.inr .nrrd .nhdr .mha .mhd; gzip and
 * bzip2 encodings are not supported): the image is reconstructed by a cubic B-spline of
 * its voxels (C2; the fit ANISTAR_FIT_AUTO: smoothing for label images and masks,
 * interpolating for others), f = iso - value with inside = ANISTAR_INSIDE_GREATER
 * (f < 0 where the value exceeds iso), f = value - iso with ANISTAR_INSIDE_LESS. Outside
 * the image the reconstruction tends to a background value on the outside side of iso
 * (the smallest voxel value for GREATER, the largest for LESS), so an object touching the
 * border of the image still gives a closed surface. The bounding sphere is computed
 * (the grid grown by a margin that provably contains S). f, its gradient and Hessian are
 * exact derivatives of the spline (world coordinates: spacing and directions included).
 * The voxels are prefiltered into a copy (8 bytes per voxel); the file is not kept.
 * Returns ANISTAR_EIO, ANISTAR_EFORMAT (the image readers' errors), ANISTAR_EINVAL (inside
 * not +1 or -1, iso not finite), ANISTAR_ENOSURFACE (iso not strictly between the
 * smallest and largest voxel values), ANISTAR_ENOMEM.
 */
ANISTAR_API anistar_status anistar_surface_from_image_file(anistar_context *ctx,
                                                           const char *path, double iso,
                                                           int inside, anistar_surface **out);

/* The same from voxels in memory: dims[0] x dims[1] x dims[2] doubles, x fastest (voxel
 * (i,j,k) = voxels[i + dims[0] (j + dims[1] k)]), spacing[3] > 0 (NULL: 1 1 1) and
 * origin[3] (NULL: 0 0 0) the world position of voxel (0,0,0)'s center; axis-aligned.
 * Everything is copied. ANISTAR_EINVAL also for a zero dimension or a non-finite voxel. */
ANISTAR_API anistar_status anistar_surface_from_image(anistar_context *ctx,
                                                      const double *voxels,
                                                      const size_t dims[3],
                                                      const double spacing[3],
                                                      const double origin[3], double iso,
                                                      int inside, anistar_surface **out);

/* The two above with the fit chosen (ANISTAR_FIT_*; EINVAL for another value). */
ANISTAR_API anistar_status anistar_surface_from_image_file_fit(anistar_context *ctx,
                                                               const char *path, double iso,
                                                               int inside, int fit,
                                                               anistar_surface **out);
ANISTAR_API anistar_status anistar_surface_from_image_fit(anistar_context *ctx,
                                                          const double *voxels,
                                                          const size_t dims[3],
                                                          const double spacing[3],
                                                          const double origin[3], double iso,
                                                          int inside, int fit,
                                                          anistar_surface **out);
/* The fit an image surface uses: ANISTAR_FIT_INTERPOLATE or ANISTAR_FIT_SMOOTH (what
 * ANISTAR_FIT_AUTO chose); ANISTAR_FIT_AUTO (0) when s is not an image surface or NULL. */
ANISTAR_API int anistar_surface_image_fit(const anistar_surface *s);

/*
 * An automatic isovalue: Otsu's threshold of the voxels (the value that best splits them
 * into two classes, maximising the between-class variance; 256 equal bins over the range
 * of the finite values; the threshold is a bin boundary strictly inside the range). For
 * a CT or MRI scan it separates the object from the background; for a label image it
 * splits the labels in two groups, so give the isovalue yourself there. The file form
 * reads the image (as anistar_surface_from_image_file). ANISTAR_ENOSURFACE when every
 * finite voxel has the same value, and the readers' errors (EIO, EFORMAT, ENOMEM);
 * EINVAL for NULL arguments or a zero dimension.
 */
ANISTAR_API anistar_status anistar_image_file_otsu(anistar_context *ctx, const char *path,
                                                   double *iso);
ANISTAR_API anistar_status anistar_image_otsu(anistar_context *ctx, const double *voxels,
                                              const size_t dims[3], double *iso);

/* Free a surface (NULL is ok). Every metric made on it must have been freed before. */
ANISTAR_API void anistar_surface_free(anistar_surface *s);

/* The bounding sphere. */
ANISTAR_API anistar_status anistar_surface_bound(const anistar_surface *s, double center[3],
                                                 double *radius);

/* f at p, and when g (h) is not NULL its gradient (Hessian, m11 m12 m13 m22 m23 m33).
 * Triangle-mesh surfaces: f is the signed distance to the mesh (negative inside) and g
 * its gradient (the unit vector from the closest point, the normal on the mesh); asking
 * for h is ANISTAR_EINVAL. */
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
 *   euclidean | uniform[,h=H] | curvature[,eps=E][,en=N][,power=P][,degree=D][,k=K][,rb=R]
 *   | shock[,lambda=L][,phi=F][,en=N] | gradient:EXPR[,phi=F][,en=N]
 *   | hessian:EXPR[,eps=E][,en=N][,power=P] | sol:FILE[,rb=R]
 *   and on every one but euclidean and uniform [,grad=G] (below)
 * Options follow the name (or the expression) after commas at parenthesis depth 0:
 * "hessian:max(x,y)^2,eps=0.5". Defaults: curvature eps = 1/R (R the bounding radius),
 * power 1; shock lambda 0.6, phi 1; gradient phi 1; hessian power 0.5 and eps = 1e-3 x
 * the largest tangential |H| eigenvalue over the surface sample (ANISTAR_EINVAL naming a
 * sample point when that is 0: give eps); e_n (F's eigenvalue along the normal) = the
 * largest tangential eigenvalue of F over a sample of S.
 * ANISTAR_EINVAL for an unknown name or option or a bad value, ANISTAR_EFORMAT for a
 * malformed expression or unbalanced parentheses; computing defaults samples S and may
 * return ANISTAR_ENOSURFACE.
 * On triangle-mesh surfaces (paper 5.2.3), curvature and sol are per-vertex tensors M(v)
 * blended with Gaussian weights exp(-|p - v|^2 / rb^2) (normalised; vertices whose weight
 * is below exp(-3.5^2) times the nearest vertex's are left out, a relative change of
 * ~6e-5, and the weights are lowered by that amount so the field stays continuous).
 * curvature: jets of degree D (2, 3 or 4; default 2) fitted on the K nearest vertices
 * (default 16 for degree 2, 28 for 3 and 4; at most 64), e_n defaulting to the largest
 * e_1 over the vertices (paper 5.4); sol:FILE reads one tensor per vertex of the input mesh (Medit
 * .sol; ANISTAR_EFORMAT when the count differs or a tensor is not positive definite).
 * rb defaults to the mean distance from a vertex to its K nearest vertices. The blended
 * field is continuous and defined off the surface too.
 * On image surfaces curvature is blended the same way: the exact curvature tensors of the
 * B-spline isosurface at the points where it crosses the edges of the lattice of voxel
 * centers, rb defaulting to the mean distance from such a point to its 16 nearest (about
 * a voxel and a half; rb=R sets it). sol:FILE on a surface that is not a triangle mesh,
 * degree or k there, and rb on an implicit surface are ANISTAR_EINVAL.
 * grad=G (G > 1; grad=0: none) grades the field (Alauzet's anisotropic size gradation,
 * MMG's hgrad): sizes grow by at most about 1 + l ln G over metric length l, so a field
 * that jumps (jets across a CAD crease, a .sol, the curvature of a surface whose pieces
 * meet with continuous tangents only) becomes one the refinement can finish on. The
 * fields from data (curvature and sol on triangle meshes, curvature on images) and the
 * curvature of an expression with abs, min or max (whose creases make it jump) are graded
 * with G = 1.5 unless the SPEC says otherwise; the others only when asked. Per-vertex and
 * lattice tensors are graded along the mesh's edges or the lattice points' nearest
 * neighbours (each tensor's eigenvalues raised in its own frame) before they are blended;
 * a field given at every point is graded on a sample of S (about 12,000 to 262,144
 * points) and becomes the intersection of itself with the blend of the graded sample
 * (its sizes never exceed the ungraded ones). Creating such a field costs the sample
 * (0.1-0.3 s on the builtins). anistar_metric_set_gradation below changes it later. */
ANISTAR_API anistar_status anistar_metric_from_spec(anistar_context *ctx,
                                                    const anistar_surface *s, const char *spec,
                                                    anistar_metric **out);

/* Check a SPEC's syntax, names, options and values (compiling any expression) without
 * a surface: the errors of anistar_metric_from_spec that do not depend on the surface. */
ANISTAR_API anistar_status anistar_metric_spec_check(anistar_context *ctx, const char *spec);

/* A constant tensor m: finite and positive definite with condition number <= 1e24, else
 * ANISTAR_EINVAL giving the six values (never repaired). s may be NULL. */
ANISTAR_API anistar_status anistar_metric_uniform(anistar_context *ctx, const anistar_surface *s,
                                                  const double m[6], anistar_metric **out);

/* A custom field on s; user is passed back to fn and stays owned by the caller. */
ANISTAR_API anistar_status anistar_metric_from_callback(anistar_context *ctx,
                                                        const anistar_surface *s,
                                                        anistar_metric_fn fn, void *user,
                                                        anistar_metric **out);

/* The tensor t at p, a point of S. Off S the field is evaluated at p as given (with the
 * normal and curvatures of the level set of f through p): project first
 * (anistar_surface_project) for the value on S. ANISTAR_EINVAL, with a message naming p
 * (and the six values of a tensor at fault), when f is not finite at p or a custom
 * callback fails or returns a tensor that is not finite and positive definite with
 * condition number <= 1e24: never repaired. */
ANISTAR_API anistar_status anistar_metric_eval(const anistar_metric *m, const double p[3],
                                               double t[6]);

/* Grade m with G > 1, or with G = 0 remove its gradation: m becomes the field its SPEC
 * with grad=G gives (anistar_metric_from_spec above, the same code), and a metric from a
 * callback is graded as a field given at every point is: the callback is called at a
 * sample of S (16,384 to 262,144 points asked of the sampler: 12,622 calls in all on the
 * unit sphere; their cost plus ~0.2 s) and the field becomes its own tensor intersected
 * with the blend of the graded sample (sizes never grow). An earlier gradation (from the
 * SPEC or this call) is replaced: the field as made is kept. A uniform field is left as
 * it is. ANISTAR_EINVAL for G neither 0 nor finite and > 1, and for the field's evaluation
 * errors at a sample point (a callback that fails, a tensor not positive definite: the
 * message names the point); ANISTAR_ENOMEM. On failure m is unchanged. Not thread-safe
 * with other uses of m: call it before making a mesher from m (a mesher reads m while
 * it exists). The message goes to m's context. */
ANISTAR_API anistar_status anistar_metric_set_gradation(anistar_metric *m, double grad);

/* Free a metric (NULL is ok). */
ANISTAR_API void anistar_metric_free(anistar_metric *m);

/* ------------------------------------------------------------------------------------ */
/* Mesher                                                                                 */
/* ------------------------------------------------------------------------------------ */

/*
 * The mesher (opaque) builds an anisotropic Delaunay mesh of a surface S for a metric
 * field (Boissonnat, Shi, Tournois, Yvinec): the star of every output vertex v is the
 * restricted Delaunay star of v for v's own metric M_v; every facet has radius-edge ratio
 * <= rho0 and surface circumradius < r0 in the metric of each of its three vertices, and
 * the metric distortion between its vertices is below gamma0. The mesher keeps pointers to
 * the surface and the metric (both must outlive it) and uses the context it was created
 * with for memory and messages. Two meshers on two contexts run in two threads at once.
 */
typedef struct anistar_mesher anistar_mesher;
typedef struct anistar_mesh anistar_mesh;
typedef struct anistar_surface anistar_surface;
typedef struct anistar_metric anistar_metric;

/* Parameters of anistar_mesher_set (ranges checked; ANISTAR_EINVAL names the rule). */
typedef enum anistar_param {
    ANISTAR_PARAM_R0 = 0,       /* size bound: surface circumradius in vertex metrics; > 0
                                   (default 0.1) */
    ANISTAR_PARAM_GAMMA0,       /* distortion bound between a facet's vertex metrics; > 1
                                   (default 1.5) */
    ANISTAR_PARAM_RHO0,         /* radius-edge ratio bound; > 1 (default 3) */
    ANISTAR_PARAM_BETA,         /* Pick_valid: "small" configurations; >= 1 (default 2.5) */
    ANISTAR_PARAM_DELTA,        /* Pick_valid: picking ratio; in (0, 1) (default 0.3) */
    ANISTAR_PARAM_APPROX,       /* approximation bound (distance facet-S); >= 0, 0 = off
                                   (default 0) */
    ANISTAR_PARAM_MAX_VERTICES, /* stop (ANISTAR_INCOMPLETE) at this many vertices, and
                                   refuse at once (ANISTAR_EINVAL) a run whose up-front
                                   estimate exceeds it; integer in [0, 2147482623], 0 = the
                                   hard limit of the star set, 2147482623 sites
                                   (2^31 - 1025: 32-bit global ids) (default 1000000) */
    ANISTAR_PARAM_MAX_SECONDS,  /* stop (ANISTAR_INCOMPLETE) after this many seconds of
                                   refinement, its final checks included (they test it
                                   between stars); >= 0, 0 = no limit (default) */
    ANISTAR_PARAM_SEED,         /* seed of Pick_valid's random points; integer in
                                   [0, 2^53] (default 0) */
    ANISTAR_PARAM_PICK_TRIES,   /* Pick_valid tries before the center is taken; integer
                                   in [1, 100000] (default 20) */
    ANISTAR_PARAM_OPTIMIZE,     /* 1: vertex optimisation after a complete run (paper
                                   6.2; moves vertices toward the area-weighted mean of
                                   their facets' surface centers while every guarantee
                                   holds and quality improves); 0 or 1 (default 0) */
    ANISTAR_PARAM_MAX_STALL,    /* stall budget: stop (ANISTAR_INCOMPLETE, stop reason
                                   ANISTAR_STOP_STALL) after this many consistency (rule 3)
                                   insertions in a row without the inconsistent-facet count
                                   they face reaching a new low (rule 3 runs when no other
                                   rule applies: in a converging run that count falls to 0);
                                   integer in [0, 2^53], 0 = automatic (default: the larger
                                   of 50000 and 2 x the vertices at the last new low) */
    ANISTAR_PARAM_HMIN,         /* Euclidean size floor, as MMG's hmin: the metric is clamped
                                   (every eigenvalue of F at most r0/hmin, at least r0/hmax
                                   with ANISTAR_PARAM_HMAX), and a facet whose longest
                                   edge is shorter gets no size, distortion, approximation
                                   or shape refinement (the feature size and consistency
                                   still apply, and the topology rule except on triangle
                                   meshes; stats.facets_below_hmin counts the facets it held
                                   beyond r0, rho0 or gamma0); >= 0, 0 = automatic
                                   (default): the resolution of what the metric is made
                                   from: half a triangle mesh's mean edge for a field
                                   fitted to its vertices (curvature, sol); otherwise the
                                   floor of the feature size (an eighth of the mean edge,
                                   about a voxel for an image, 1e-4 of the bounding radius
                                   for an implicit surface) */
    ANISTAR_PARAM_HMAX,         /* Euclidean size ceiling, as MMG's hmax: a facet whose
                                   longest edge is longer is refined (rule 1, counted in
                                   stats.insertions_hmax); >= 0, 0 = none (default) */
    ANISTAR_PARAM_ANISO_CAP,    /* 1: the anisotropy that pays: where the metric's
                                   eigenframe turns along S, each small eigenvalue of F is
                                   raised until a facet of the size the metric asks for
                                   keeps its vertices' distortion within gamma0 (the
                                   elongation the distortion rule would undo is not asked
                                   for; docs/algorithm.md); no effect on triangle-mesh
                                   surfaces (their normals are piecewise); 0: the metric
                                   as the field gives it; 0 or 1 (default 1) */
    ANISTAR_PARAM_THREADS       /* threads the run may use, the caller's included; integer
                                   in [1, 1024] (default 1). The output is the same for
                                   every count (byte for byte); with more than one, the
                                   context's allocator and the surface's and metric's
                                   callbacks are called from several threads at once and
                                   must be thread-safe (docs/algorithm.md, "Threads") */
} anistar_param;

/* A mesher for surface s and metric field m (both not owned). */
ANISTAR_API anistar_status anistar_mesher_new(anistar_context *ctx, const anistar_surface *s,
                                              const anistar_metric *m, anistar_mesher **out);
ANISTAR_API void anistar_mesher_free(anistar_mesher *m);

/* Set a parameter. ANISTAR_EINVAL (message in the mesher's context) for an unknown key or
 * a value out of range; the parameter then keeps its value. */
ANISTAR_API anistar_status anistar_mesher_set(anistar_mesher *m, anistar_param key,
                                              double value);
/* Read a parameter's current value. */
ANISTAR_API anistar_status anistar_mesher_get(const anistar_mesher *m, anistar_param key,
                                              double *value);

/* Progress callback: called during anistar_mesher_run every few hundred insertions and
 * at least every 0.25 s of refinement, with the number of vertices, of inconsistent
 * facets, and the seconds elapsed; return nonzero to cancel the run
 * (anistar_mesher_run then returns ANISTAR_ECANCELED and no mesh). The callback may call
 * anistar_mesher_get_progress for more (the estimate, the stall count). */
typedef int (*anistar_progress_fn)(size_t vertices, size_t inconsistent, double seconds,
                                   void *user);
ANISTAR_API void anistar_mesher_set_progress(anistar_mesher *m, anistar_progress_fn fn,
                                             void *user);

/* The state of a run (anistar_mesher_get_progress): all outputs. */
typedef struct anistar_progress {
    size_t vertices;          /* surface vertices (sites) so far */
    size_t inconsistent;      /* inconsistent facets now */
    double seconds;           /* since the run started */
    double estimate_vertices; /* up-front estimate of the final vertex count from the
                                 metric and the sizing field (0 until it is made) */
    double estimate_bytes;    /* ... and of the run's peak memory */
    double eta_seconds;       /* estimated seconds left (< 0: unknown) */
    uint64_t stalled;         /* consistency (rule 3) insertions since the inconsistent-
                                 facet count they face last reached a new low */
    uint64_t max_stall;       /* the stall budget in force (ANISTAR_PARAM_MAX_STALL) */
} anistar_progress;

/* Copy the state of the current (or last) run of m into *p: from the progress callback
 * (the thread running anistar_mesher_run) or after the run; not from another thread
 * while a run goes on. */
ANISTAR_API anistar_status anistar_mesher_get_progress(const anistar_mesher *m,
                                                       anistar_progress *p);

/* Ask the current run of m to stop after the insertion in progress: anistar_mesher_run
 * then returns ANISTAR_INCOMPLETE with the mesh of the consistent facets so far (stop
 * reason ANISTAR_STOP_REQUESTED), as at a limit. During the vertex optimisation it ends
 * the optimisation between two moves: the mesh returned is then the certified mesh
 * optimised so far, still with ANISTAR_INCOMPLETE. Async-signal-safe and thread-safe: it
 * only sets a lock-free atomic flag, so a SIGINT handler or another thread may call it.
 * A call made while no run is going on makes the next run stop at its first check; each
 * run clears the flag when it ends. */
ANISTAR_API void anistar_mesher_stop(anistar_mesher *m);

/* Why a run ended: anistar_mesh_stats.stop_reason. */
typedef enum anistar_stop_reason {
    ANISTAR_STOP_DONE = 0,         /* refinement finished and the mesh is certified
                                      (ANISTAR_OK) */
    ANISTAR_STOP_MAX_VERTICES = 1, /* ANISTAR_PARAM_MAX_VERTICES reached */
    ANISTAR_STOP_MAX_SECONDS = 2,  /* ANISTAR_PARAM_MAX_SECONDS reached */
    ANISTAR_STOP_STALL = 3,        /* the inconsistent-facet count reached no new low for
                                      ANISTAR_PARAM_MAX_STALL insertions */
    ANISTAR_STOP_REQUESTED = 4,    /* anistar_mesher_stop */
    ANISTAR_STOP_UNCERTIFIED = 5   /* no rule applies any more, but the mesh fails one of
                                      the final checks of anistar_mesher_run (the message
                                      names the check and the place) */
} anistar_stop_reason;

/* The reason's name: "done", "max_vertices", "max_seconds", "stall", "requested",
 * "uncertified"; "unknown" otherwise. Static strings. */
ANISTAR_API const char *anistar_stop_reason_name(int reason);

/*
 * Run the mesher. The three outcomes, and what each guarantees:
 *
 * ANISTAR_OK — a certified mesh: non-empty; every restricted facet consistent (in the
 *   surface star of each of its three vertices); every vertex star one closed fan; the
 *   mesh a closed, oriented (outward), 2-manifold triangulation; one mesh component for
 *   each connected component of S that the surface sample found, and no component
 *   bridging two of them; for a triangle-mesh surface, each component's Euler
 *   characteristic equal to that of the input component it covers. Every facet then has
 *   surface circumradius < r0, radius-edge ratio <= rho0 and distortion < gamma0 in the
 *   metric of each of its three vertices (and meets approx when set).
 * ANISTAR_INCOMPLETE — *out holds the consistent facets only (its statistics count the
 *   others; it need not be closed) and anistar_last_error says why: a limit
 *   (max_vertices, max_seconds), a stall (max_stall), anistar_mesher_stop, or a final
 *   check that failed (stop reason ANISTAR_STOP_UNCERTIFIED: e.g. a component whose
 *   Euler characteristic differs from the input's, named with a point on it).
 * An error — *out is NULL: ANISTAR_EINVAL for a metric that is not finite and positive
 *   definite at a point of S (the message names the point), or a run refused at once
 *   because its estimated vertex count exceeds max_vertices (the message gives the
 *   estimate); ANISTAR_ENOSURFACE, surface errors; ANISTAR_ENOMEM; ANISTAR_ECANCELED
 *   (the progress callback returned nonzero); ANISTAR_EINTERNAL for a broken invariant
 *   (e.g. a refinement point within a relative 1e-9 of an existing site, which would
 *   otherwise refine forever), naming the facet.
 *
 * *out is set (to a mesh to free with anistar_mesh_free) for OK and INCOMPLETE, NULL
 * otherwise. The result depends only on the inputs and the seed (not on the time limit
 * unless it is reached).
 */
ANISTAR_API anistar_status anistar_mesher_run(anistar_mesher *m, anistar_mesh **out);

/* ------------------------------------------------------------------------------------ */
/* Output mesh                                                                            */
/* ------------------------------------------------------------------------------------ */

/*
 * The result of anistar_mesher_run (opaque): vertices, triangles oriented outward, a
 * metric tensor per vertex, and the run's statistics. Data leave it through copy-out
 * getters into arrays the caller sizes from the counts, or through anistar_mesh_write.
 */

#define ANISTAR_HISTOGRAM_BINS 64

/* Statistics of a mesh (copied out by anistar_mesh_get_stats). */
typedef struct anistar_mesh_stats {
    size_t vertices;              /* output vertices (sites of output facets) */
    size_t facets;                /* output triangles */
    size_t inconsistent_facets;   /* facets left out because inconsistent (0 when OK) */
    size_t poles;                 /* internal sites near the medial axis (not output) */
    long long euler_characteristic; /* V - E + F of the output */
    int closed_manifold;          /* every edge in 2 triangles, every vertex link 1 cycle */
    int complete;                 /* 1 if the run finished (ANISTAR_OK) */
    double rho_max;               /* largest radius-edge ratio of a facet in the metric
                                     of one of its vertices */
    double r_max;                 /* largest surface circumradius r_v(tau) over the facets
                                     and their three vertex metrics */
    double gamma_max;             /* largest distortion between two vertices of a facet */
    double histogram_width;       /* bin width of histogram */
    /* squared radius-edge ratios of every facet in each of its 3 vertex metrics: bin i
     * counts values in [i w, (i+1) w), the last bin also everything above */
    uint64_t histogram[ANISTAR_HISTOGRAM_BINS];
    uint64_t insertions_initial;  /* initial surface points */
    uint64_t insertions_rule[3];  /* rule 1 (size, distortion), 2 (shape), 3 (consistency) */
    uint64_t pick_valid_tries;    /* random candidates tested by Pick_valid */
    uint64_t pick_valid_failures; /* Pick_valid calls that fell back to the center */
    double seconds_total, seconds_init, seconds_refine, seconds_output;
    double rho2_mean;             /* mean of the 3 F squared radius-edge ratios above */
    double approx_error_mean;     /* distance from the facets to S: samples at 4 fixed
                                     barycentric points of each facet projected on S,
                                     mean weighted by area (so over area-uniform points) */
    double approx_error_max;      /* ... and the largest of those distances */
    /* vertex optimisation (paper 6.2; ANISTAR_PARAM_OPTIMIZE = 1 and a complete run,
     * else all zero): optimized is 1 when it ran; histogram_before and rho2_mean_before
     * describe the mesh before it (histogram, rho2_mean: after) */
    int optimized;
    uint64_t optimize_moved;      /* vertices moved (accepted moves) */
    uint64_t optimize_tries;      /* candidate positions tested */
    uint64_t optimize_passes;     /* passes over the vertices */
    double seconds_optimize;      /* included in seconds_total and seconds_output */
    double rho2_mean_before;
    uint64_t histogram_before[ANISTAR_HISTOGRAM_BINS];
    /* how the run ended and what it cost */
    int stop_reason;              /* anistar_stop_reason */
    size_t components;            /* connected components of the output (counted by the
                                     final checks of a complete run; 0 otherwise) */
    size_t components_found;      /* implicit and image surfaces: components of the output
                                     that the surface sample missed (refinement found
                                     them), and ... */
    size_t components_split;      /* ... sample components that came out as several (the
                                     sampler's grid merges components closer than a cell),
                                     and ... */
    size_t components_joined;     /* ... sample components joined in one (a neck thinner
                                     than a cell); the final checks prove the mesh against
                                     S itself, the grid is only a sample */
    size_t components_below_resolution; /* image isosurfaces: components of the sample
                                     smaller than about half a voxel across (noise a hair
                                     above the isovalue), not meshed */
    size_t pieces_below_resolution; /* implicit and image surfaces: pieces of the output
                                     that fit in a ball of the surface's resolution (the
                                     feature size's floor): accepted without proving that
                                     they bound a region of their own */
    size_t edges_below_resolution; /* edges across a gap or a plate (opposite normals at
                                     their ends) whose midpoint is within the resolution
                                     of S: accepted, the gap is not resolved */
    double hmin, hmax;            /* the Euclidean size bounds in force (hmin: the one given
                                     or the automatic one; 0: none) */
    size_t facets_below_hmin;     /* facets shorter than hmin (longest edge) that exceed
                                     r0, rho0 or gamma0 in a vertex metric: hmin held them */
    double estimate_vertices;     /* the up-front estimate (anistar_progress) */
    double estimate_bytes;
    size_t peak_bytes;            /* the most bytes the run held through the context's
                                     allocator at once */
    /* why the mesh is as dense as it is: insertions by rule and cause. insertions_rule[0]
     * is the sum of the four rule-1 causes; a facet violating several counts once, for
     * its largest ratio */
    uint64_t insertions_topology; /* topology rule: a vertex star empty or not one closed
                                     fan */
    uint64_t insertions_size;     /* rule 1: surface circumradius >= r0 */
    uint64_t insertions_distortion; /* rule 1: distortion >= gamma0 */
    uint64_t insertions_approx;   /* rule 1: distance to S > approx */
    uint64_t insertions_feature;  /* rule 1: circumradius >= a fraction of the local
                                     feature size (the sizing field's lfs part) */
    uint64_t insertions_hmax;     /* rule 1: longest edge > hmax */
    uint64_t stall_max;           /* the longest stretch of consistency (rule 3) insertions
                                     without a new low of the inconsistent-facet count */
    double feature_alpha;         /* facets were kept below this fraction of the local
                                     feature size: 1, halved each time the final checks
                                     found the topology wrong (down to 1/8) */
    uint64_t feature_halvings;    /* how many times that happened */
    uint64_t topology_below_hmin; /* topology refinement points not inserted because they
                                     lay nearer than hmin to a site (the star was left to
                                     the final checks) */
    size_t sites_unused;          /* sites whose star holds no restricted facet: no facet
                                     uses them, they are not output vertices (a complete
                                     run accepts them; their cells met S only where the
                                     topology rule could not refine above hmin) */
    size_t stars_delaunay_zone;   /* stars whose surface balls were found not to bound the
                                     sites that change their restricted facets (S crosses
                                     their Voronoi cell away from their disk: specks of S
                                     meshed at hmin); they took their whole Delaunay
                                     region as their conflict zone */
    /* the batches of refinement points (docs/algorithm.md §11; the same for every thread
     * count): jobs taken in batches, those that lost a star to an earlier job of their
     * batch after their point was computed, and those set aside before (sharing a star or
     * a vertex with an earlier job); both go back to their queue */
    uint64_t batches;
    uint64_t batch_jobs;
    uint64_t batch_jobs_lost;
    uint64_t batch_jobs_set_aside;
    uint64_t facets_swept;        /* facets violating rules 1-2 that no queue held when the
                                     queues ran dry (found by a last pass over every star
                                     and refined: 0 unless the refinement lost track of one) */
} anistar_mesh_stats;

ANISTAR_API size_t anistar_mesh_vertex_count(const anistar_mesh *mesh);
ANISTAR_API size_t anistar_mesh_triangle_count(const anistar_mesh *mesh);
/* Copy out the vertices (3 per vertex), the triangles (3 0-based indices each,
 * counterclockwise seen from outside) and the per-vertex metric tensors (6 each). The
 * arrays must hold the counts above. */
ANISTAR_API void anistar_mesh_get_vertices(const anistar_mesh *mesh, double *xyz);
ANISTAR_API void anistar_mesh_get_triangles(const anistar_mesh *mesh, int32_t *tri);
ANISTAR_API void anistar_mesh_get_metrics(const anistar_mesh *mesh, double *tensors);
ANISTAR_API void anistar_mesh_get_stats(const anistar_mesh *mesh, anistar_mesh_stats *stats);
/* Write the mesh, the format chosen by the extension of path: .off .obj .ply .stl .mesh
 * .meshb .vtk .vtu (with the tensors where the format holds them; .vtk .vtu .ply also get
 * the per-triangle fields "radius_edge" and "anisotropy", see docs/formats.md) or .sol
 * .solb (the tensors alone).
 * ctx receives the message (NULL: the mesh's context). ANISTAR_EFORMAT for an unknown
 * extension, ANISTAR_EIO, ANISTAR_EINVAL (e.g. .stl with coordinates beyond float). */
ANISTAR_API anistar_status anistar_mesh_write(anistar_context *ctx, const anistar_mesh *mesh,
                                              const char *path);
ANISTAR_API void anistar_mesh_free(anistar_mesh *mesh);

/* ------------------------------------------------------------------------------------ */
/* What a file holds                                                                      */
/* ------------------------------------------------------------------------------------ */

/*
 * What a user checks before meshing a file (the command line's `anistar info`): for a
 * triangle mesh its counts, its topology (borders, non-manifold edges and vertices,
 * components with their Euler characteristic and genus), an exact self-intersection test,
 * its bounding box and edge lengths; for a 3D image its grid, its value range, Otsu's
 * threshold and the connected components of the voxels inside an isovalue. The file is
 * read by the same readers as anistar_surface_read and anistar_surface_from_image_file,
 * but a mesh need not be closed or manifold here: saying what is wrong is the point. The
 * caller owns the struct; every field is an output; nothing is kept.
 */

#define ANISTAR_INFO_COMPONENTS 16            /* components described one by one */
#define ANISTAR_INFO_PAIRS 8                  /* intersecting triangle pairs listed */
#define ANISTAR_INFO_MAX_INTERSECTIONS 10000  /* the intersection count stops there */

/* One connected component of a triangle mesh (triangles joined through shared
 * vertices). */
typedef struct anistar_component_info {
    size_t vertices, edges, triangles;
    long long euler_characteristic; /* V - E + F */
    int closed;                     /* every edge in exactly two triangles, every vertex
                                       one fan of triangles, no repeated index */
    int orientable;                 /* its triangles can be oriented consistently */
    long long genus;                /* (2 - chi) / 2 when closed and orientable, else -1 */
} anistar_component_info;

typedef struct anistar_mesh_info {
    size_t vertices;             /* as read */
    size_t used_vertices;        /* vertices of at least one triangle */
    size_t triangles;            /* as read (polygons split into fans) */
    size_t edges;                /* distinct vertex pairs of a triangle */
    size_t components;           /* connected components */
    size_t border_edges;         /* edges of exactly one triangle */
    size_t nonmanifold_edges;    /* edges of three or more triangles */
    size_t nonmanifold_vertices; /* vertices whose triangles form more than one fan */
    size_t degenerate_triangles; /* a repeated vertex index or three collinear points
                                    (exactly); skipped by the intersection test */
    size_t nonorientable_components;
    int closed_manifold;         /* no border or non-manifold edge or vertex, no repeated
                                    index */
    long long euler_characteristic; /* V - E + F over the whole mesh */
    /* Pairs of triangles whose closed point sets meet other than in the vertices or the
     * edge that their indices share (a touch at one point counts, so does a duplicated
     * triangle), decided exactly; counting stops at ANISTAR_INFO_MAX_INTERSECTIONS
     * (self_intersections_capped = 1). The first pairs_listed pairs (i < j, 0-based
     * triangle numbers in file order, increasing) are in pairs. */
    size_t self_intersections;
    int self_intersections_capped;
    size_t pairs_listed;
    int32_t pairs[ANISTAR_INFO_PAIRS][2];
    double bbox_min[3], bbox_max[3]; /* of the used vertices */
    double edge_min, edge_mean, edge_max; /* Euclidean lengths of the distinct edges */
    /* the first components_listed components, in the order of their first triangle */
    size_t components_listed;
    anistar_component_info component[ANISTAR_INFO_COMPONENTS];
} anistar_mesh_info;

/* Describe the triangle mesh in the file path (.off .obj .ply .stl .mesh, or any other
 * format the mesh readers take). ANISTAR_EIO, ANISTAR_EFORMAT (the readers' errors, the
 * message naming the file and the line), ANISTAR_EINVAL (NULL arguments, a coordinate
 * beyond 1e40 in magnitude: the exact tests need it), ANISTAR_ENOMEM. */
ANISTAR_API anistar_status anistar_mesh_file_info(anistar_context *ctx, const char *path,
                                                  anistar_mesh_info *info);

typedef struct anistar_image_info {
    size_t dims[3];                  /* voxels per axis */
    double spacing[3], origin[3];    /* origin: the world position of voxel (0,0,0) */
    double direction[9];             /* row-major: direction[3r + c] = component r of
                                        axis c's direction */
    const char *voxel_type;          /* "uint8", "int16", "float32", ... (static) */
    double bbox_min[3], bbox_max[3]; /* world box of the voxel centers */
    double value_min, value_max;     /* of the finite voxels (NaN if none) */
    size_t nonfinite;                /* NaN or infinite voxels */
    double otsu;                     /* Otsu's threshold (anistar_image_otsu); NaN when
                                        every finite voxel has the same value */
    double iso;                      /* the isovalue used: the one given, else otsu */
    int iso_given;                   /* 1: iso was given */
    int inside;                      /* ANISTAR_INSIDE_GREATER or _LESS */
    size_t voxels_inside;            /* voxels strictly beyond iso on the inside side */
    size_t components;               /* connected components of those voxels, 6-connected
                                        (voxels sharing a face); 0 when iso is NaN */
} anistar_image_info;

/* Describe the 3D image in the file path (.inr .nrrd .nhdr .mha .mhd) and the voxels
 * inside the isovalue iso (NaN: Otsu's threshold), inside = ANISTAR_INSIDE_GREATER or
 * ANISTAR_INSIDE_LESS. ANISTAR_EIO, ANISTAR_EFORMAT (the readers' errors), ANISTAR_EINVAL
 * (NULL arguments, iso infinite, a bad inside), ANISTAR_ENOMEM (4 bytes per voxel are
 * needed for the labelling). */
ANISTAR_API anistar_status anistar_image_file_info(anistar_context *ctx, const char *path,
                                                   double iso, int inside,
                                                   anistar_image_info *info);

/* ------------------------------------------------------------------------------------ */
/* Rendering meshes to PNG                                                                */
/* ------------------------------------------------------------------------------------ */

/*
 * A dependency-free renderer: a triangle mesh drawn orthographically with flat shading,
 * a z-buffer and supersampling, optionally coloured per triangle through a perceptual
 * colormap (viridis) with a colour bar, written as an 8-bit RGB PNG. The output is a
 * pure function of the input (the same mesh and options give the same bytes).
 *
 * Per-triangle values (ANISTAR_COLOR_...):
 *   QUALITY     the radius-edge ratio circumradius / shortest edge, Euclidean
 *               (1/sqrt(3) ~ 0.577 for an equilateral triangle; larger is worse);
 *   ANISOTROPY  with per-vertex tensors: the largest over the triangle's three vertices
 *               of sqrt(lambda_max / lambda_min) of the tensor (the ratio of the longest
 *               to the shortest prescribed edge length; 1 for an isotropic metric; NaN,
 *               drawn grey, where a tensor is not positive definite); without tensors:
 *               the triangle's own aspect ratio, longest edge / shortest altitude
 *               (2/sqrt(3) ~ 1.155 for an equilateral triangle);
 *   NONE        no colour (a light grey-blue), no legend.
 * A degenerate triangle (zero area) has an infinite QUALITY and aspect: it takes the top
 * colour and does not widen the automatic range.
 */
typedef enum anistar_color_by {
    ANISTAR_COLOR_NONE = 0,
    ANISTAR_COLOR_QUALITY = 1,
    ANISTAR_COLOR_ANISOTROPY = 2
} anistar_color_by;

/* The largest image width and height. */
#define ANISTAR_RENDER_MAX_SIDE 16384

/*
 * Rendering options: all inputs; fill with anistar_render_options_init, then change
 * fields. The view is orthographic: the `up` axis points up on screen, the viewer sits
 * at azimuth `azimuth` (degrees, in the plane normal to `up`; for up = z, 0 looks from
 * +x and 90 from +y) and elevation `elevation` (degrees above that plane). The mesh is
 * fitted to the image with a 5% margin. Edges are 1-pixel lines on the visible
 * triangles (hidden edges never show); they fade out on triangles whose projection is
 * less than 4 pixels high and vanish below 1.5 pixels, so dense meshes do not turn black.
 */
typedef struct anistar_render_options {
    int width, height;          /* pixels, 1..ANISTAR_RENDER_MAX_SIDE (1024 x 768) */
    double azimuth, elevation;  /* degrees, finite (30, 20) */
    int up;                     /* the vertical axis: 0 = x, 1 = y, 2 = z (2) */
    anistar_color_by color;     /* per-triangle values (ANISTAR_COLOR_QUALITY) */
    int edges;                  /* 1: draw the edges (1), 0: not */
    int legend;                 /* 1: colour bar with min, middle, max and title (1) */
    int supersample;            /* samples per pixel side, 1..4 (3) */
    double range_min, range_max; /* colour range; both NaN (default): the min and max of
                                    the finite values; else finite with min < max
                                    (values outside are clamped to the ends) */
    int compress;               /* 1: deflate (fixed Huffman codes) (1), 0: stored */
    const char *sol_path;       /* anistar_render_file: a Medit .sol/.solb of per-vertex
                                   tensors for ANISOTROPY (NULL); borrowed for the call */
} anistar_render_options;

/* Fill *opt with the defaults above. */
ANISTAR_API void anistar_render_options_init(anistar_render_options *opt);

/*
 * Render the triangle mesh in the file mesh_path (.off .obj .ply .stl .mesh .meshb .vtk
 * .vtu; PLY vertex properties m11 m12 m13 m22 m23 m33 and the VTK point tensor "metric"
 * are read as tensors) to the PNG file png_path. Tensors for ANISOTROPY come from
 * opt->sol_path when given (they replace the file's).
 * opt == NULL uses the defaults. Returns EINVAL (bad options, NULL paths), EIO (a file
 * that cannot be read or written: the message names it; a partial PNG is removed),
 * EFORMAT (a malformed mesh or .sol, a .sol whose vertex count differs), ENOMEM.
 */
ANISTAR_API anistar_status anistar_render_file(anistar_context *ctx, const char *mesh_path,
                                               const char *png_path,
                                               const anistar_render_options *opt);

/*
 * Render a mesh given as arrays: nv vertices xyz (3 nv doubles), nt triangles tri
 * (3 nt 0-based indices), tensors NULL or 6 nv doubles (m11 m12 m13 m22 m23 m33). When
 * values is not NULL it holds nt per-triangle values that are drawn instead of
 * opt->color (NaN: grey, +-inf: the ends of the colormap) and label titles the legend
 * (NULL: none; letters, digits and . - + ( ) / _ : = are drawn, others as '?').
 * nt == 0 gives an image of the background. EINVAL for bad options, a NULL array with
 * a nonzero count, an index outside [0, nv), a non-finite coordinate; EIO; ENOMEM.
 */
ANISTAR_API anistar_status anistar_render_arrays(anistar_context *ctx, size_t nv,
                                                 const double *xyz, size_t nt,
                                                 const int32_t *tri, const double *tensors,
                                                 const double *values, const char *label,
                                                 const char *png_path,
                                                 const anistar_render_options *opt);

/*
 * The per-triangle values of `by` (QUALITY or ANISOTROPY, as above) for the arrays of
 * anistar_render_arrays, into out[nt]. EINVAL for NONE or an invalid mesh.
 */
ANISTAR_API anistar_status anistar_triangle_values(anistar_context *ctx, anistar_color_by by,
                                                   size_t nv, const double *xyz, size_t nt,
                                                   const int32_t *tri, const double *tensors,
                                                   double *out);


#ifdef __cplusplus
}
#endif

#endif /* ANISTAR_H */
