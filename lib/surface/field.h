/*
 * field.h — internal: metric fields on a surface (DESIGN.md 4.7, paper 5.2.1, 5.2.2, 5.4),
 * and the SPEC strings of the command line's --metric (DESIGN.md 3).
 *
 * A field maps a point p of S to a metric tensor M_p = F^T F (6 doubles m11 m12 m13 m22
 * m23 m33). Every tensor it returns is symmetric positive definite with finite entries
 * (the mesher's own test, as_metric_frame_init, accepts it) and an eigenvalue ratio of F
 * of at most AS_FIELD_MAX_ANISOTROPY (M's: its square): smaller eigenvalues of F are
 * raised to (largest / AS_FIELD_MAX_ANISOTROPY). That clamp regularises valid tensors
 * only: a tensor that is not finite and SPD (or that as_metric_frame_init refuses, F's
 * condition number above 1e12) is an error naming the point (EINVAL; EFORMAT for .sol
 * files), never repaired or replaced (DESIGN.md 4.7).
 *
 * Kinds (F = U diag(e) U^T with U = [u1, u2, n], n the outward normal):
 *  - uniform: a constant tensor (euclidean: I; uniform,h=H: I/H^2);
 *  - custom: a callback (p, normal, m, user);
 *  - curvature (paper 5.2.2): u1, u2 the principal directions, e_i = max(eps, |k_i|)^power;
 *  - gradient:EXPR and shock (paper 5.2.1 corrected, DESIGN.md 4.7): g = the tangential
 *    part of grad E; e = 1 + phi |g| along g, 1 across it;
 *  - hessian:EXPR: |H| = V |Lambda| V^T of the Hessian of E, restricted to the tangent
 *    plane (2x2: T^T |H| T), its eigenvalues w_i: e_i = max(eps, w_i)^power; eps defaults
 *    to 1e-3 x the largest w over the initial sample, and when that is 0 (E's Hessian
 *    vanishes tangentially at every sample point, e.g. a linear E) creation fails with
 *    EINVAL naming a sample point: there is no size to derive (give eps=E: a uniform
 *    metric);
 *  - e_n, F's eigenvalue along the normal (paper 5.4), defaults to the largest tangential
 *    eigenvalue e_1 over the initial sample of S (as_surface_sample, 256 points) for the
 *    kinds curvature, gradient, shock, hessian; option en=N sets it.
 * Special points:
 *  - umbilic points (equal eigenvalues): any orthonormal tangent frame gives the same
 *    tensor, so the tensor is well defined;
 *  - flat and parabolic points: the eps clamp keeps the eigenvalues positive;
 *  - singular points of f (grad f = 0, no normal): the isotropic tensor e^2 I with e the
 *    largest eigenvalue the field would use there: max(e_n, tangential eigenvalues
 *    computed without projection); for curvature also where a curvature eigenvalue
 *    exceeds AS_FIELD_MAX_EIGENVALUE (|k| > 1e150: next to a singular point, where
 *    |grad f| -> 0): e_n^2 I.
 * Not special, errors (EINVAL naming the point): E, its derivatives or the curvature not
 * finite; a gradient or hessian eigenvalue not finite or above AS_FIELD_MAX_EIGENVALUE
 * (E's own, whatever f does); a result that as_metric_frame_init refuses (squares of
 * tiny or huge eps, e_n under- or overflowing).
 * Points off S: the field is evaluated at p as given, with the normal and curvatures of
 * the level set of f through p (project first for the value on S).
 *
 * Triangle-mesh surfaces (paper 5.2.3): curvature and sol:FILE are per-vertex tensors
 * M(v) blended by Gaussian weights (as_blend_eval, jet.h) with radius r_B:
 *  - curvature: the jet of degree `degree` (2 by default; 3 or 4) fitted on the k nearest
 *    vertices (default AS_JET_K2 = 16 for degree 2, AS_JET_K4 = 32 for 3 and 4; at most
 *    AS_JET_MAX_POINTS), oriented outward, gives k_i and u_i at each vertex;
 *    e_i = max(eps, |k_i|)^power as above; e_n defaults to the largest e_1 over the
 *    vertices (paper 5.4); a curvature or eigenvalue that is not finite or above
 *    AS_FIELD_MAX_EIGENVALUE at a vertex is EINVAL naming it (a mesh has no singular
 *    point to excuse it);
 *  - sol:FILE: one tensor per vertex of the input mesh (Medit .sol, io/meshio.h), the
 *    count must equal the input's vertex count (EFORMAT otherwise), each finite and SPD as
 *    as_field_check_tensor decides (EFORMAT naming the vertex and its position); blended the same way (so a vertex's own tensor is not
 *    reproduced exactly unless its neighbours agree; a constant field is);
 *  - r_B defaults to the paper's: the mean over the vertices of their mean distance to
 *    their k nearest other vertices; option rb=R sets it.
 * A blended field is continuous everywhere, SPD, and defined off S too (it only looks at
 * distances to the vertices).
 * Image surfaces: curvature is blended the same way over the points where S crosses the
 * edges of the lattice of voxel centers (as_image_surface_lattice), each carrying the exact
 * curvature tensor of the B-spline isosurface there (eps, power and e_n as for implicit
 * surfaces); r_B = option rb or the mean distance to the AS_JET_K2 nearest such points.
 * hdata is then two voxels (the smallest voxel edge doubled): the mesher's automatic hmin.
 *
 * A field keeps a pointer to its surface (not owned): the surface must outlive it.
 * A field is immutable after creation; evaluation is safe from several threads at once
 * (custom callbacks permitting), each thread passing its own context.
 */
#ifndef ANISTAR_FIELD_H
#define ANISTAR_FIELD_H

#include "core.h"
#include "surface/expr.h"
#include "surface/jet.h"
#include "surface/surface.h"

#define AS_FIELD_MAX_ANISOTROPY 1e6
#define AS_FIELD_MAX_EIGENVALUE 1e150
/* Points of the initial sample used for default e_n and eps. */
#define AS_FIELD_SAMPLE_POINTS 256

typedef struct anistar_metric as_field;

/* A custom field: fill m (6 doubles) at p; normal is the outward unit normal, or
 * (0, 0, 0) at a singular point. Returns 0 on success, nonzero on failure. */
typedef int (*as_field_fn)(const double p[3], const double normal[3], double m[6], void *user);

typedef enum as_field_kind {
    AS_FIELD_UNIFORM,
    AS_FIELD_CUSTOM,
    AS_FIELD_CURVATURE,
    AS_FIELD_GRADIENT, /* gradient:EXPR and shock */
    AS_FIELD_HESSIAN,
    AS_FIELD_SOL
} as_field_kind;

/* A parsed SPEC. Options not given keep has_* = 0. */
typedef struct as_field_spec {
    as_field_kind kind;
    const char *name; /* static: "euclidean", "uniform", "curvature", "shock", ... */
    double eps, en, power, phi, lambda, h;
    int has_eps, has_en, has_power, has_phi, has_lambda, has_h;
    double degree, k, rb; /* curvature on meshes (degree, k, rb) and sol (rb) */
    int has_degree, has_k, has_rb;
    double grad;          /* curvature on meshes and sol: the gradation (> 1) */
    int has_grad;
    as_expr *expr; /* gradient, hessian, shock (owned) */
    char *path;    /* sol (owned, path_size bytes) */
    size_t path_size;
} as_field_spec;

/*
 * Parse a SPEC (the command line's --metric):
 *   euclidean | uniform[,h=H] | curvature[,eps=E][,en=N][,power=P][,degree=D][,k=K][,rb=R]
 *   [,grad=G] | shock[,lambda=L][,phi=F][,en=N] | gradient:EXPR[,phi=F][,en=N]
 *   | hessian:EXPR[,eps=E][,en=N][,power=P] | sol:FILE[,rb=R][,grad=G]
 * Options follow the name (or the expression) after commas at parenthesis depth 0, as
 * NAME=VALUE with a finite number; spaces around names and values are allowed.
 * Returns EINVAL for an unknown metric name or option, a repeated option, a bad value
 * (eps, en, h, lambda, power, rb > 0, phi >= 0, grad > 1, degree 2, 3 or 4, k an integer
 * >= 1; degree, k, rb and grad are for triangle-mesh surfaces, rb also for the curvature of
 * images) or a missing expression; EFORMAT for a
 * malformed expression or unbalanced parentheses; ENOMEM. Messages name the culprit.
 */
anistar_status as_field_spec_parse(anistar_context *ctx, const char *spec, as_field_spec *out);

/*
 * The gradation of per-point tensors tens (6 per point, points xyz) along ne edges
 * (edges[2e], edges[2e + 1]), in place, each pass over them in order, both directions:
 * the metric M_i of each point, carried to a neighbour j at M_i-length l with its sizes
 * grown by the factor eta^-1 = 1 + l ln(grad) (Alauzet's anisotropic size gradation in
 * metric space, after Borouchaki, Hecht and Frey; MMG's hgrad), bounds M_j, until no
 * tensor changes by more than a relative 1e-3 (at most AS_FIELD_GRAD_PASSES passes).
 * keep_frame = 0: eta^2 M_i is intersected into M_j (the largest metric whose unit ball
 * lies in both), so afterwards M_j >= eta^2 M_i across every edge. keep_frame = 1 (what
 * the fields use): each M_j keeps its eigenvectors and only its eigenvalues are raised,
 * each to at least eta^2 u^T M_i u along its eigenvector u (so afterwards u^T M_j u >=
 * eta^2 u^T M_i u along M_j's axes): intersections of anisotropic metrics whose frames
 * turn are not idempotent, and repeated over passes they inflate every eigenvalue (on the
 * paper's torus, sampled, the normal eigenvalue 1 became 8.7 and the mesh 7 times
 * larger; knot1's jets graded along its edges, 6,805 vertices against 5,597); raising
 * eigenvalues in place cannot exceed the largest eta^2 u^T M_i u met, so the field's
 * largest eigenvalue never grows. Every tensor is at least its input. *changed (if not
 * NULL): 1 if some tensor changed. OK, ENOMEM, or EINVAL naming a point whose tensor
 * stops being a metric (only by overflow).
 */
#define AS_FIELD_GRAD_PASSES 200
anistar_status as_field_gradation_edges(anistar_context *ctx, double *tens, const double *xyz,
                                        size_t ne, const int32_t *edges, double grad,
                                        int keep_frame, int *changed);
/* The gradation fields from data get unless their SPEC says grad=G or grad=0 (none):
 * curvature and sol on triangle meshes, curvature on images (field.c,
 * as_field_from_spec; chosen by measurement: docs/algorithm.md). */
#define AS_FIELD_DATA_GRAD 1.5
/* grad=G on fields given at every point and on images' lattices (field.c,
 * fl_grade_sample): the neighbours of a point in the gradation graph, the sample points
 * per unit of (area x largest eigenvalue of M), and the bounds of the sample's size. */
#define AS_FIELD_GRAD_K 8
#define AS_FIELD_GRAD_DENSITY 4.0
#define AS_FIELD_GRAD_MIN_POINTS 16384
#define AS_FIELD_GRAD_MAX_POINTS 262144
void as_field_spec_clear(anistar_context *ctx, as_field_spec *sp);

/* The graded sample of a field given at every point (owned): the blend of its graded
 * tensors over its n points xyz (3 n) and their kd-tree, which the blend borrows. */
typedef struct as_field_gsample {
    as_blend *blend;
    double *xyz;
    size_t n;
    as_kdtree *kd;
} as_field_gsample;

struct anistar_metric {
    anistar_context *ctx;    /* the creating context (memory; public error messages) */
    const as_surface *surf;  /* not owned; may be NULL for uniform fields */
    as_field_kind kind;
    double m[6];             /* uniform */
    as_field_fn fn;          /* custom */
    void *user;
    as_expr *expr;           /* gradient, hessian (owned) */
    double eps, power, phi, en;
    as_blend *blend;         /* curvature and sol on triangle meshes, curvature on images
                                (owned) */
    double *bxyz;            /* images: the points the blend is over (owned, 3 * bn) */
    size_t bn;
    as_kdtree *bkd;          /* images: their kd-tree (owned) */
    int32_t *bnb;            /* images: each point's AS_FIELD_GRAD_K + 1 nearest (itself
                                included; bn of them, owned), as the default radius found
                                them, lent to the gradation's edges and freed when
                                as_field_from_spec ends (NULL: none) */
    uint8_t *bnbn;           /* how many of each are set (owned, bn) */
    double *braw;            /* once graded: the blend's tensors as fitted (owned, 6 *
                                nraw); as_field_set_gradation grades a copy of them */
    size_t nraw;
    as_field_gsample g;      /* grad=G on a field given at every point (fl_grade_sample;
                                g.blend NULL: none) */
    double grad;             /* the gradation G applied (0: none) */
    double hdata;            /* the resolution of the data the field is fitted to (the
                                automatic hmin; 0: none, the field is the user's own) */
};

/* A field parsed from spec on surface s (which must outlive it). Computes the default e_n
 * (and hessian's default eps) from the initial sample of s, so it may return the
 * sampler's errors (ENOSURFACE, EINVAL), and EINVAL (naming spec and a sample point) when
 * a default cannot be derived: hessian's eps when the Hessian of E is 0 on the sample,
 * e_n when no sample point has a usable tangential eigenvalue; and the evaluation errors
 * of as_field_eval met at sample points. sol:FILE needs a triangle-mesh surface (EINVAL
 * otherwise) and returns the .sol reader's errors (EIO, EFORMAT) and EFORMAT for a
 * vertex-count mismatch or a tensor that is not SPD; degree, k, rb on a surface that is
 * not a triangle mesh: EINVAL; k outside [coefficients(degree), AS_JET_MAX_POINTS]:
 * EINVAL. */
anistar_status as_field_from_spec(anistar_context *ctx, const as_surface *s, const char *spec,
                                  as_field **out);
/* A constant tensor (validated by as_field_check_tensor: EINVAL naming the six values;
 * anisotropy clamped). s may be NULL. */
anistar_status as_field_uniform(anistar_context *ctx, const as_surface *s, const double m[6],
                                as_field **out);
/* A custom callback field on s. */
anistar_status as_field_custom(anistar_context *ctx, const as_surface *s, as_field_fn fn,
                               void *user, as_field **out);
void as_field_free(as_field *f);

/* Grade fl with grad = G > 1 (or, G == 0, remove its gradation): the field becomes the
 * one the SPEC's grad=G gives (the same path: per-vertex and lattice tensors graded before
 * they are blended, every other field, callbacks included, graded on a sample of S and
 * intersected with its blend; a uniform field only records G). Replaces an earlier
 * gradation (the field as fitted is kept). EINVAL for G not 0 and not finite > 1; the
 * field's evaluation errors at the sample's points; ENOMEM. On failure fl is unchanged.
 * Not while fl is in use (a mesher made from it). */
anistar_status as_field_set_gradation(anistar_context *ctx, as_field *fl, double grad);

/*
 * The tensor at p. EINVAL (naming p, and the six values when a tensor is at fault) when f
 * or E is not finite there, when a custom callback fails or returns a tensor that
 * as_field_check_tensor refuses (never repaired), and in the error cases of the kinds
 * above. m is written only on success for custom fields.
 */
anistar_status as_field_eval(anistar_context *ctx, const as_field *f, const double p[3],
                             double m[6]);

/* M = U diag(e^2) U^T for the orthonormal frame u (u + 3k belongs to e[k]) after the
 * anisotropy clamp of e. */
void as_field_tensor(const double u[9], const double e[3], double m[6]);

/* Validate a tensor with the mesher's test, as_metric_frame_init (finite, SPD, M's
 * condition number <= 1e24), then clamp its anisotropy in place (M's eigenvalue ratio at
 * most AS_FIELD_MAX_ANISOTROPY^2; bit for bit untouched if within). Returns 0, or -1 if
 * invalid (m untouched): the clamp never makes an invalid tensor valid. */
int as_field_check_tensor(double m[6]);

#endif /* ANISTAR_FIELD_H */
