/*
 * surface.h — internal: the surface oracle (DESIGN.md 4.6, paper 5: "an oracle able to
 * compute a few initial points on the surface and to detect and compute the intersections
 * between a given line segment and the surface").
 *
 * Every surface kind (implicit functions and expressions now; triangle meshes and 3D
 * images later) is an as_surface whose first member is this common header and whose
 * behaviour is a table of operations (as_surface_ops). The public opaque handle
 * anistar_surface IS this structure.
 *
 * Conventions shared by every kind:
 *  - S is the boundary of the inside region {p : |p - center| <= radius and f(p) < 0}:
 *    f < 0 inside, and everything beyond the bounding sphere counts as outside. S must lie
 *    strictly inside the bounding sphere (f > 0 on the sphere); the sampler reports
 *    ANISTAR_EINVAL when it finds f < 0 on the sphere.
 *  - The normal is the OUTWARD unit normal +grad f/|grad f| (the paper's N of 5.2.2 is
 *    its opposite). Principal curvatures are the eigenvalues of P (H/|grad f|) P on the
 *    tangent plane (paper 5.2.2), so they are positive where S is convex (sphere of
 *    radius r: +1/r) and of opposite signs at saddle points.
 *  - Lengths are judged against tol = AS_SURFACE_REL_TOL * radius (roots, projections),
 *    or AS_SURFACE_ULP_TOL * (|center| + radius) when that is larger (far from 0).
 *  - A surface is immutable after creation. Every operation takes it const and keeps its
 *    state on the caller's stack, so one surface may be queried from several threads at
 *    once, each thread passing its own context (ctx receives error messages only; it may
 *    be NULL). Callback surfaces are as thread-safe as the user's callbacks.
 *  - A function value that is NaN or infinite is an error (ANISTAR_EINVAL naming the
 *    point), never a sign.
 */
#ifndef ANISTAR_SURFACE_H
#define ANISTAR_SURFACE_H

#include "core.h"
#include "geom/bvh.h"
#include "geom/kdtree.h"

#include <float.h>
#include <stddef.h>
#include <stdint.h>

/* Relative tolerance of roots and projections: |x - x*| <= 1e-12 * bounding radius, and
 * at least AS_SURFACE_ULP_TOL times the coordinates' magnitude (8 ulps: a surface far
 * from the origin cannot be resolved below its coordinates' spacing). */
#define AS_SURFACE_REL_TOL 1e-12
#define AS_SURFACE_ULP_TOL (8 * DBL_EPSILON)

typedef struct anistar_surface as_surface;

/* The local differential geometry of S (or of the level set of f) at a point. */
typedef struct as_surface_frame {
    double n[3];   /* outward unit normal */
    double k[2];   /* principal curvatures, k[0] >= k[1] */
    double d[6];   /* unit principal directions: d (of k[0]) and d + 3 (of k[1]); (d, d+3, n)
                      is a right-handed orthonormal frame */
    double gnorm;  /* |grad f| at the point */
    int singular;  /* 1 where grad f vanishes (|grad f| <= DBL_MIN): n, k, d are 0 then */
} as_surface_frame;

/*
 * Points on S from as_surface_sample (initial points), with area weights: for a function g
 * on S and a component c holding n_c of the points,
 *     sum over the points p of c of (area[c] / n_c) g(p)  ~  integral of g over c,
 * the points being spread about uniformly in area (see as_surface_sample for the accuracy).
 */
typedef struct as_point_sample {
    double *points;       /* 3 * n coordinates, each point on S within tol */
    int32_t *component;   /* n component ids in [0, ncomponents) */
    double *area;         /* ncomponents: the area of each component (an estimate, exact for
                             triangle meshes); allocated and freed with the points */
    size_t n;             /* number of points (>= ncomponents) */
    size_t ncomponents;   /* connected components found */
    double spacing;       /* the resolution: the grid spacing h of as_surface_sample for
                             function kinds, the mean edge length for triangle meshes */
} as_point_sample;

typedef struct as_surface_ops {
    const char *kind; /* "implicit", "expression", "builtin" (implicit.c), "mesh" (mesh.c),
                         "image" (image.c) */
    /*
     * f at p; with order >= 1 also grad f in g, with order 2 also the Hessian in h
     * (m11 m12 m13 m22 m23 m33). NULL for kinds not given by a function (triangle
     * meshes): such kinds must provide every operation below. May return NaN: callers
     * check. Must be const-safe (no writes to s).
     */
    double (*eval)(const as_surface *s, const double p[3], int order, double g[3],
                   double h[6]);
    /* Optional overrides; NULL selects the generic implementation built on eval (see the
     * functions of the same name below for their contracts). */
    anistar_status (*side)(anistar_context *ctx, const as_surface *s, const double p[3],
                           int *side);
    anistar_status (*crossing)(anistar_context *ctx, const as_surface *s, const double a[3],
                               const double b[3], const double ref[3], int *found,
                               double x[3]);
    anistar_status (*project)(anistar_context *ctx, const as_surface *s, const double p[3],
                              double q[3]);
    anistar_status (*frame)(anistar_context *ctx, const as_surface *s, const double p[3],
                            as_surface_frame *fr);
    anistar_status (*sample)(anistar_context *ctx, const as_surface *s, size_t max_points,
                             as_point_sample *out);
    /* Free the kind's data and the object itself (with s->ctx's allocator). */
    void (*destroy)(as_surface *s);
} as_surface_ops;

/* The common header: the first member of every surface kind. */
struct anistar_surface {
    const as_surface_ops *ops;
    anistar_context *ctx; /* the creating context: its allocator owns the object */
    double center[3];     /* bounding sphere */
    double radius;
    double tol;           /* AS_SURFACE_REL_TOL * radius, or 8 ulps of the coordinates */
    /* The sampler's analysis of S (kinds sampled through f): made by the first sample and
     * kept, so that the metric's defaults and the mesher's samples share it (as_surface_sample).
     * A cache: filled through a const surface, by the one thread that uses the surface
     * (docs/api.md), never by a mesher's worker threads. */
    struct as_sbasis *basis;
};

/* Fill the common header (kinds call it from their constructors). Returns EINVAL for a
 * non-finite center or a radius that is not finite and > 0. */
anistar_status as_surface_init(anistar_context *ctx, as_surface *s, const as_surface_ops *ops,
                               const double center[3], double radius);

/* Free a surface of any kind (NULL is ok). */
void as_surface_free(as_surface *s);

/*
 * f (and grad f with order >= 1, the Hessian with order 2; g, h may be NULL when not
 * requested) at p. Returns EINVAL, naming p, when a requested quantity is not finite or
 * when the surface has no function (eval == NULL).
 */
anistar_status as_surface_eval(anistar_context *ctx, const as_surface *s, const double p[3],
                               int order, double *f, double g[3], double h[6]);

/*
 * Side of p: *side = -1 inside (f < 0), +1 outside (f > 0 or p beyond the bounding
 * sphere), 0 on S (f == 0 exactly). EINVAL naming p when f(p) is NaN or infinite.
 */
anistar_status as_surface_side(anistar_context *ctx, const as_surface *s, const double p[3],
                               int *side);

/*
 * The crossing of the segment [a, b] with S nearest ref (usually a point near the
 * segment: the mesher passes a facet's circumcenter).
 * Returns OK with *found = 1 and the point in x, or *found = 0 when the segment does not
 * meet S; EINVAL when f is not finite at a point visited (named in the message).
 * notes:
 *  - Every sign change of f along the chord found by the sampling below is a crossing;
 *    each is refined by the Illinois method to |x - x*| <= tol.
 *  - A segment that touches S without crossing it (f keeps its sign, a double root) is
 *    reported as crossing it at the touching point when the sampling sees the valley and
 *    a minimisation of |f| there reaches |f|/|grad f| <= tol; a segment passing farther
 *    than that from S is reported as not meeting it.
 *  - Where f < 0 on the bounding sphere (S leaks out of it) the inside region is clipped
 *    by the sphere, so a chord entering the ball where f < 0 crosses at the sphere.
 * design:
 *  1. clip [a, b] to the bounding ball (the part beyond is outside, f > 0);
 *  2. sample the chord with spacing <= AS_CROSSING_SPACING * radius (1 to 64 pieces),
 *     f and its derivative along the chord at each sample;
 *  3. adaptive sampling: on each piece build the cubic Hermite interpolant of the two end
 *     values and slopes; split a piece (down to 1e-7 * radius) when the cubic predicts
 *     more roots than the end signs show: three roots where the signs differ, or a valley
 *     dipping below half the smaller end value where they agree; a valley piece shorter
 *     than 1/8 of the base spacing is minimised (golden section) and split at its
 *     minimum if f changes sign there;
 *  4. refine the bracket nearest ref first; other brackets only if they may hold a
 *     nearer root.
 * limits: two crossings closer together than the resolution of the Hermite test within
 *  one base piece can be missed (their valley must dip below half the end values to be
 *  seen); the evaluation budget is AS_CROSSING_MAX_EVALS per call, after which pieces
 *  are no longer split.
 */
#define AS_CROSSING_SPACING (1.0 / 32.0)
#define AS_CROSSING_MAX_EVALS 2048
anistar_status as_surface_crossing(anistar_context *ctx, const as_surface *s, const double a[3],
                                   const double b[3], const double ref[3], int *found,
                                   double x[3]);

/*
 * Projection of p onto S: a point q with |f(q)|/|grad f(q)| <= tol which is the closest
 * point of S to p whenever the iteration below converges (p closer to S than its local
 * radius of curvature and the nearest point unique); otherwise a nearby foot point.
 * Returns EINVAL (non-finite f), ENOSURFACE (no zero of f found along the gradient line
 * through p nor along the line to the center).
 * design:
 *  1. Newton steps along the gradient, x -= f grad f/|grad f|^2, each step at most
 *     radius/4, halved until |f| decreases;
 *  2. if Newton stalls: bracketed root finding (as_surface_crossing) along the gradient
 *     line through the best iterate, then along the line to the center;
 *  3. closest point: repeat x <- proj(x + P(p - x)) (P the tangent projector at x) while
 *     |p - x| decreases and the tangential part of p - x exceeds tol.
 */
anistar_status as_surface_project(anistar_context *ctx, const as_surface *s, const double p[3],
                                  double q[3]);

/* Outward unit normal at p (the gradient direction of the level set through p). EINVAL
 * when grad f vanishes or is not finite at p. */
anistar_status as_surface_normal(anistar_context *ctx, const as_surface *s, const double p[3],
                                 double n[3]);
/* The same for every kind, without failing at singular points: *singular = 1 and n = 0
 * where grad f vanishes (|grad f| <= DBL_MIN). Function kinds need only first
 * derivatives; kinds without eval use their frame op. */
anistar_status as_surface_normal_at(anistar_context *ctx, const as_surface *s,
                                    const double p[3], double n[3], int *singular);

/*
 * Normal, principal curvatures and directions of the level set of f through p (S itself
 * when p is on S): eigen-decomposition of the 2x2 matrix t_i^T H t_j / |grad f| in a
 * tangent basis (paper 5.2.2). At umbilic points any orthonormal tangent pair is
 * returned. Where grad f vanishes: OK with fr->singular = 1. EINVAL for non-finite f,
 * grad f or Hessian.
 */
anistar_status as_surface_frame_at(anistar_context *ctx, const as_surface *s, const double p[3],
                                   as_surface_frame *fr);

/*
 * Initial points: a coarse sample of S with points on every connected component found, and
 * the area of each component (as_point_sample). About max_points points (0 means 64): each
 * component gets a share proportional to its area and at least one, so
 * n <= max_points + ncomponents. The arrays are allocated with ctx's allocator: free them
 * with as_surface_sample_free(ctx, out). The result depends only on s and max_points.
 * Kinds with their own sampler keep this contract (triangle meshes: mesh vertices, exact
 * areas).
 * Returns ENOSURFACE when no component is found, EINVAL when f is not finite at a sample
 * or f < 0 on the bounding sphere (S not inside it), ENOMEM.
 * design:
 *  1. f on a grid of 64^3 cells of side h = R/32 over the bounding cube (vertices beyond
 *     the sphere count as outside);
 *  2. cells: one whose corners have both signs is near S, and unresolved where f bends
 *     across it (second differences above 3/4 of the first ones at its corners); one of a
 *     single sign may hide a part of S when its smallest |f| is within sqrt(3)/2 times the
 *     largest one-sided difference and the tangent planes of f at its corners do not keep
 *     f away from 0 on it;
 *  3. witnesses, points inside the parts the grid vertices miss: a descent of |f| in each
 *     such cell, centered between the part's two walls; then continuation along thin parts
 *     (steps of h along the part from each thin witness and from the grid vertices inside
 *     thin parts), which also follows a part into cells where f does not show it;
 *  4. union-find of the regions f < 0 and f >= 0 over the grid vertices and witnesses:
 *     along the grid edges, except the edges of unresolved cells that cross S (each is
 *     scanned for crossings as in as_surface_crossing), and along the chords that do not
 *     cross S from each witness, and each minority-sign corner of an unresolved cell, to
 *     the nearest nodes of its sign within two cells (two per region, up to 8 chords);
 *  5. every crossing between two nodes (a grid edge with a sign change; a chord from each
 *     witness to a node of the other sign) links an inside region to an outside region:
 *     each distinct (inside region, outside region) pair is one component;
 *  6. area: marching tetrahedra in the resolved cells S crosses (vertices placed by cubic
 *     interpolation along the grid lines); Crofton's lattice formula in the other cells
 *     near S: each crossing of a lattice edge adds h^2 / (|n_x| + |n_y| + |n_z|) (n the
 *     unit normal there), a quarter per cell around the edge; a component of area below
 *     8 h^2 lying within 2h of one of its points along the axes: marching tetrahedra on a
 *     12^3 grid over its extent;
 *  7. per component, farthest-point sampling of the crossings' midpoints (at most 8 times
 *     the quota of candidates) and the crossing refined on each.
 * guarantee:
 *  - a component whose inside (for a cavity: outside) region contains a ball of radius
 *    h sqrt(3)/2 = 0.027 R holds a grid vertex and is found;
 *  - a thinner or smaller component, or part, is found when f is convex near it on the
 *    side it encloses (f for a solid part, -f for a cavity: spheres, ellipsoids and other
 *    convex quadrics, convex distance-like functions, their min() away from where the
 *    pieces meet): the cell tests then miss no cell it meets, and the descent from the
 *    center of one of them must still reach it (Newton and gradient steps within the
 *    cell grown by h/2); for other f, when f shows the part at a corner of a cell it
 *    meets, the continuation following it from there;
 *  - a part thinner than the cells stays one piece when the chords between its witnesses,
 *    a cell or two apart, stay inside it: its mid-surface or axis bends by less than its
 *    thickness over two cells (curvature radius above about h^2 / thickness);
 *  - two components (or two sheets of one) closer than a cell stay apart where f bends
 *    between them (those edges are scanned, crossings resolved down to 1e-7 R).
 * limits: at most 32768 descents and 65536 witnesses per call (beyond, thin parts may be
 *  missed or split); a part that f hides at the corners of all the cells it meets (a
 *  cavity cut by max() that no grid vertex comes near) is missed.
 * area accuracy (measured, test_surface): resolved smooth surfaces about 0.1 (h/rho)^2,
 *  rho the smallest curvature radius (1.4e-4 for the unit sphere in a bound of 1.25,
 *  2.3e-4 for the torus R=10 r=1 in 11.25); parts thinner than a cell (Crofton): 2e-3 to
 *  2e-2 for plates, 1e-2 for a thin torus, up to 0.3 for tubes that few lattice lines meet
 *  (radius 0.06 h); pieces smaller than a cell 5e-3. The weights area[c] / n_c: the points
 *  are about uniform in area once their spacing sqrt(area / n) is small against the
 *  curvature radii (mean of z^2 over 256 points of the unit sphere within 2e-3; over the
 *  torus R=10 r=1 within 0.035 with 256 points, 2e-3 with 1024).
 */
anistar_status as_surface_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                 as_point_sample *out);
void as_surface_sample_free(anistar_context *ctx, as_point_sample *smp);
/* The area weight of each point of smp (w[i] = area of its component / the component's
 * point count: sum_i w[i] g(p_i) ~ the integral of g over S, as_point_sample); w holds
 * smp->n values. OK or ENOMEM. */
anistar_status as_surface_sample_weights(anistar_context *ctx, const as_point_sample *smp,
                                         double *w);

/* A sampler of s: as_sampler_sample(ctx, sp, n, out) gives exactly as_surface_sample(ctx,
 * s, n, out). With a pool (pool.h; NULL: none) the grid values of the analysis and the
 * crossings of a sample are computed on its threads: the points are the same (their
 * order is decided before). */
typedef struct as_sampler as_sampler;
struct as_pool;
anistar_status as_sampler_new(anistar_context *ctx, const as_surface *s, struct as_pool *pool,
                              as_sampler **out);
anistar_status as_sampler_sample(anistar_context *ctx, as_sampler *sp, size_t max_points,
                                 as_point_sample *out);
void as_sampler_free(anistar_context *ctx, as_sampler *sp);

/* ---- generic implementations for function-based kinds (used when an op is NULL) ---- */
anistar_status as_fsurface_side(anistar_context *ctx, const as_surface *s, const double p[3],
                                int *side);
anistar_status as_fsurface_crossing(anistar_context *ctx, const as_surface *s,
                                    const double a[3], const double b[3], const double ref[3],
                                    int *found, double x[3]);
/* The same answer computed in the original order (every piece of the chord scanned from
 * a to b before any refinement): for tests of the nearest-first order. */
anistar_status as_fsurface_crossing_full(anistar_context *ctx, const as_surface *s,
                                         const double a[3], const double b[3],
                                         const double ref[3], int *found, double x[3]);
anistar_status as_fsurface_project(anistar_context *ctx, const as_surface *s, const double p[3],
                                   double q[3]);
anistar_status as_fsurface_frame(anistar_context *ctx, const as_surface *s, const double p[3],
                                 as_surface_frame *fr);
anistar_status as_fsurface_sample(anistar_context *ctx, const as_surface *s, size_t max_points,
                                  as_point_sample *out);

/* ---- implicit surfaces (implicit.c) ---------------------------------------------- */

/* Callbacks of an implicit function (the public anistar_implicit_fn has this layout). */
typedef struct as_implicit_fn {
    double (*value)(const double p[3], void *user);
    void (*gradient)(const double p[3], double g[3], void *user);  /* may be NULL */
    void (*hessian)(const double p[3], double h[6], void *user);   /* may be NULL */
    void *user;
} as_implicit_fn;

/*
 * An implicit surface from callbacks. Missing derivatives come from central finite
 * differences with steps relative to the bounding radius R:
 *  - gradient from values: step 6e-6 R (about cbrt(DBL_EPSILON) R), relative accuracy
 *    about 1e-10 for functions smooth at scale R;
 *  - Hessian from the gradient callback: step 6e-6 R, accuracy about 1e-10;
 *  - Hessian from values only: step 1.2e-4 R (about DBL_EPSILON^(1/4) R), accuracy about
 *    1e-8 (second differences).
 */
anistar_status as_implicit_create(anistar_context *ctx, const as_implicit_fn *fn,
                                  const double center[3], double radius, as_surface **out);

/* An implicit surface f(x,y,z) = 0 from an expression (expr.h): exact derivatives. */
anistar_status as_implicit_from_expression(anistar_context *ctx, const char *expr,
                                           const double center[3], double radius,
                                           as_surface **out);

/*
 * A built-in surface from a spec "NAME[,PARAM=VALUE]...", e.g. "torus,R=5,r=2". Every
 * built-in also takes bound=RADIUS (its bounding sphere, centred at the origin).
 * EINVAL for an unknown name or parameter or an invalid value (message lists the valid
 * ones).
 */
anistar_status as_implicit_builtin(anistar_context *ctx, const char *spec, as_surface **out);
/* The same surface evaluated by its formula through the expression interpreter (kind
 * "expression") instead of its native code (kind "builtin"): the tests compare them. */
anistar_status as_implicit_builtin_expr(anistar_context *ctx, const char *spec,
                                        as_surface **out);

/* The i-th built-in: name and a one-line description (formula, parameters with
 * defaults, bounding radius, topology). Returns 0, or -1 past the last one. */
int as_implicit_builtin_info(size_t i, const char **name, const char **description);

/* ---- triangle meshes (mesh.c) ------------------------------------------------------ */

/*
 * A closed triangle-mesh surface from arrays (nv vertices xyz, nt triangles tri, 0-based;
 * both copied; name is used in messages, NULL for "triangle mesh").
 * Validation: coordinates finite and 0 or of magnitude in [1e-100, 1e100], indices in
 * range (EINVAL); the mesh must be a closed, orientable 2-manifold without zero-area
 * triangles (EFORMAT naming every problem and its count, e.g. "open.off: not a closed
 * 2-manifold: 12 border edges"). Triangles are reoriented consistently, every component
 * outward (a component nested inside an odd number of others faces inward: a cavity).
 * Vertices of no triangle are dropped (as_mesh_info.vmap maps input indices).
 * Self-intersections are not detected: the inside is then the region of odd ray parity.
 * See mesh.c for what each oracle operation answers. ENOMEM.
 */
anistar_status as_mesh_surface_create(anistar_context *ctx, const char *name, const double *xyz,
                                      size_t nv, const int32_t *tri, size_t nt,
                                      as_surface **out);
/* The same from a file (.off .obj .ply .stl .mesh, io/meshio.h); EIO, EFORMAT. */
anistar_status as_mesh_surface_read(anistar_context *ctx, const char *path, as_surface **out);
/* 1 iff s is a triangle-mesh surface. */
int as_surface_is_mesh(const as_surface *s);
/* 1 iff s is an expression surface whose function may have kinks (abs, min, max:
 * as_expr_has_kinks): S may have creases there, where its curvature jumps. */
int as_surface_has_kinks(const as_surface *s);

/* What a mesh surface holds (borrowed pointers, valid while the surface lives). */
typedef struct as_mesh_info {
    size_t nv, nt;
    const double *xyz;   /* 3 nv (after dropping unused vertices) */
    const int32_t *tri;  /* 3 nt, oriented outward */
    const double *vjet;  /* AS_MESH_VJET nv: normal n[3], curvatures k[2], directions d[6]
                            of the degree-2 jet at each vertex (AS_JET_K2 neighbours) */
    const as_kdtree *kd; /* the vertices, ids 0..nv-1 */
    const as_bvh *bvh;   /* the triangles, ids 0..nt-1 */
    size_t nv_in;        /* vertices of the input */
    const int32_t *vmap; /* nv_in: input vertex -> vertex or -1; NULL when the identity */
    size_t ncomponents;
    const int32_t *vcomp;    /* nv: connected component of each vertex (the component ids
                                of the surface's sample) */
    const long long *ceuler; /* ncomponents: Euler characteristic of each component */
    double spacing;      /* mean edge length */
} as_mesh_info;
#define AS_MESH_VJET 11
/* Fill info (s must be a mesh surface). */
void as_mesh_surface_info(const as_surface *s, as_mesh_info *info);
/* Per-vertex jets of the given degree (2..4) on the k nearest vertices (k in
 * [coefficients(degree), AS_JET_MAX_POINTS]), AS_MESH_VJET doubles per vertex into out
 * (nv of them), oriented outward. EINVAL for a bad degree or k, or a non-mesh surface. */
anistar_status as_mesh_surface_jets(anistar_context *ctx, const as_surface *s, int degree,
                                    size_t k, double *out);
/* The signed distance d from p to the mesh (negative inside, exact sign, distance to the
 * exact closest point) and its gradient g (may be NULL): the unit vector from the closest
 * point (outward), the surface normal when p is on the mesh. */
anistar_status as_mesh_surface_signed_distance(anistar_context *ctx, const as_surface *s,
                                               const double p[3], double *d, double g[3]);

/* ---- 3D images (image.c) ------------------------------------------------------------ */

struct as_image;

/*
 * The isosurface of a 3D image (io/image_io.h; its voxels are prefiltered into a copy:
 * img may be freed afterwards): f = iso - value for inside = +1 (the inside is where the
 * B-spline reconstruction exceeds iso), f = value - iso for inside = -1. Outside the grid
 * the reconstruction tends to the background, the smallest (inside = +1) or largest
 * (inside = -1) voxel value, so S is closed even where the object touches the border.
 * name is used in messages (NULL: "image"). Returns EINVAL (bad inside, non-finite iso,
 * NULL image), ENOSURFACE (iso not strictly between the smallest and largest voxel
 * values), ENOMEM, and as_bspline_create's errors.
 */
anistar_status as_image_surface_create(anistar_context *ctx, const char *name,
                                       const struct as_image *img, double iso, int inside,
                                       as_surface **out);
/* The same from a file (.inr .nrrd .nhdr .mha .mhd): as_image_read's errors (EIO...). */
anistar_status as_image_surface_read(anistar_context *ctx, const char *path, double iso,
                                     int inside, as_surface **out);
/* The same from voxels as doubles, x fastest (voxel (i,j,k) = voxels[i + nx (j + ny k)]),
 * dims nx ny nz, spacing (NULL: 1 1 1) and origin (NULL: 0 0 0, the world position of
 * voxel (0,0,0)'s center), axis-aligned. The voxels are copied. EINVAL for a zero
 * dimension, a bad spacing or origin, a non-finite voxel. */
anistar_status as_image_surface_from_array(anistar_context *ctx, const double *voxels,
                                           const size_t dims[3], const double spacing[3],
                                           const double origin[3], double iso, int inside,
                                           as_surface **out);
/* The same with the B-spline's fit chosen: AS_IMAGE_FIT_AUTO (what the functions above
 * use: SMOOTH for an image of at most AS_IMAGE_LABELS_MAX distinct voxel values, a label
 * image or a mask; INTERPOLATE for any other), INTERPOLATE or SMOOTH (surface/bspline.h;
 * the values are the public ANISTAR_FIT_*). EINVAL for another fit. */
enum { AS_IMAGE_FIT_AUTO = 0, AS_IMAGE_FIT_INTERPOLATE = 1, AS_IMAGE_FIT_SMOOTH = 2 };
#define AS_IMAGE_LABELS_MAX 16
anistar_status as_image_surface_create_fit(anistar_context *ctx, const char *name,
                                           const struct as_image *img, double iso, int inside,
                                           int fit, as_surface **out);
anistar_status as_image_surface_read_fit(anistar_context *ctx, const char *path, double iso,
                                         int inside, int fit, as_surface **out);
anistar_status as_image_surface_from_array_fit(anistar_context *ctx, const double *voxels,
                                               const size_t dims[3], const double spacing[3],
                                               const double origin[3], double iso, int inside,
                                               int fit, as_surface **out);
/* The fit an image surface uses (INTERPOLATE or SMOOTH; AUTO when s is not an image). */
int as_image_surface_fit(const as_surface *s);
/* 1 iff s is an image surface. */
int as_surface_is_image(const as_surface *s);
/*
 * The points where S crosses the edges of the lattice of voxel centers (extended by one
 * layer beyond the grid on every side, where the reconstruction is the background), each
 * solved on its edge by as_surface_crossing: a sample of S at the image's own resolution,
 * about 3 points per voxel face S crosses, in lattice order (deterministic). *xyz gets
 * 3 * *n coordinates allocated with ctx's allocator (free with as_free, 3 * *n doubles;
 * NULL when *n == 0). *voxel gets the smallest voxel edge (the length of A's shortest
 * column). Returns OK, EINVAL (s not an image surface, f not finite on a lattice node),
 * ENOMEM, or the errors of as_surface_crossing.
 */
anistar_status as_image_surface_lattice(anistar_context *ctx, const as_surface *s, double **xyz,
                                        size_t *n, double *voxel);

#endif /* ANISTAR_SURFACE_H */
