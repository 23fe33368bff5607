/*
 * bvh.h — internal: a static bounding-volume hierarchy (AABB tree) over triangles or over
 * generic boxes (DESIGN.md 1 and 4.6: the triangle-mesh surface oracle — segment
 * crossings, side by ray parity, closest point).
 *
 * Structure. Items (triangles or boxes) are permuted into leaf order; nodes live in one
 * array in preorder (left child = index + 1) with the exact bounding box of their items;
 * a node of more than AS_BVH_LEAF items is split at the median of the item centroids
 * along the widest axis of the centroids' box (as_kdpoint_select). Build O(n log n);
 * every query uses an explicit stack, never recursion, and allocates nothing except to
 * grow the caller's output. A triangle tree stores a copy of each triangle's 9
 * coordinates in leaf order (exact copies: the exact predicates see the caller's doubles).
 * The tree is immutable after the build (and the optional side grid, as_bvh_side_grid):
 * several threads may query it at once.
 *
 * Exactness. Every combinatorial decision on a triangle uses the signs of as_orient3d,
 * which are exact (2D orientations in a coordinate plane are computed exactly as
 * as_orient3d of lifted points). Box culling is conservative (a segment/box test with
 * slack far above its rounding error), so it never drops a true answer. Only the
 * crossing parameter t and closest points are computed in floating point.
 *
 * Degenerate triangles (three exactly collinear vertices) have no interior: segment and
 * parity queries ignore them (in a closed mesh their edges belong to other triangles);
 * box and closest-point queries treat them as the segments they are.
 *
 * Query coordinates must be finite and within the range of as_orient3d (anistar.h:
 * magnitudes in [1e-40, 1e40]); other inputs give unspecified answers (never a memory
 * error). The build rejects non-finite data.
 */
#ifndef ANISTAR_BVH_H
#define ANISTAR_BVH_H

#include <stddef.h>
#include <stdint.h>

#include "core.h"
#include "geom/kdtree.h" /* as_idlist, as_kdpoint_select */

/* Largest number of items in a leaf. */
#define AS_BVH_LEAF 4

typedef struct as_bvh as_bvh;

/*
 * as_bvh_build_triangles — a tree over nt triangles tri[3i..3i+2] (0-based vertex
 * indices into xyz, nv vertices). Triangle i keeps id i in every answer. The data are
 * copied. Returns ANISTAR_OK; ANISTAR_EINVAL (index out of range, non-finite coordinate
 * of a used vertex, nt >= INT32_MAX); ANISTAR_ENOMEM. *out is NULL on failure.
 */
anistar_status as_bvh_build_triangles(anistar_context *ctx, const double *xyz, size_t nv,
                                      const int32_t *tri, size_t nt, as_bvh **out);

/*
 * as_bvh_build_boxes — a tree over n boxes, box i = [boxes[6i..6i+2], boxes[6i+3..6i+5]]
 * (lo then hi), id i. Returns ANISTAR_OK; ANISTAR_EINVAL (non-finite or lo > hi);
 * ANISTAR_ENOMEM. Triangle queries on such a tree find nothing.
 */
anistar_status as_bvh_build_boxes(anistar_context *ctx, const double *boxes, size_t n,
                                  as_bvh **out);

void as_bvh_free(anistar_context *ctx, as_bvh *b);

size_t as_bvh_count(const as_bvh *b);
/* Bounding box of all items (lo = +inf, hi = -inf when empty). */
void as_bvh_bounds(const as_bvh *b, double lo[3], double hi[3]);

/* ---- exact segment / triangle tests ---------------------------------------------------- */

/*
 * How a closed segment [a, b] meets a closed triangle (u, v, w). Exactly one kind applies:
 *   NONE      they do not meet (also: the triangle is degenerate);
 *   PROPER    a and b lie strictly on opposite sides of the plane and the segment
 *             crosses the open triangle;
 *   EDGE      ... strictly opposite sides, crossing point in the relative interior of an
 *             edge (the same crossing is reported by the neighbour across that edge);
 *   VERTEX    ... strictly opposite sides, crossing point at a vertex;
 *   ENDPOINT  exactly one of a, b lies on the plane, and it lies in the closed triangle;
 *   COPLANAR  a and b both lie on the plane and the segment meets the closed triangle.
 * Rule: a triangle is reported iff the closed segment and the closed triangle meet
 * (decided exactly); the kind says whether the contact is generic (PROPER) or not.
 */
typedef enum as_seg_hit {
    AS_HIT_NONE = 0,
    AS_HIT_PROPER,
    AS_HIT_EDGE,
    AS_HIT_VERTEX,
    AS_HIT_ENDPOINT,
    AS_HIT_COPLANAR
} as_seg_hit;

/*
 * as_segment_triangle — the exact kind of contact of [a, b] with (u, v, w); *t (may be
 * NULL) receives the parameter of the contact point a + t (b - a) in [0, 1], computed in
 * floating point: the crossing of the plane; exactly 0 or 1 for ENDPOINT; for COPLANAR
 * an approximation of the first parameter at which the segment touches the triangle.
 */
as_seg_hit as_segment_triangle(const double a[3], const double b[3], const double u[3],
                               const double v[3], const double w[3], double *t);

/*
 * as_segment_triangle_sos — does the segment [p, q'] cross the triangle (u, v, w), where
 * q' = q + eps e_x + eps^2 e_y + eps^3 e_z for an infinitesimal eps > 0 (symbolic
 * perturbation of q only)? Returns 1 (it crosses the triangle's interior), 0 (it does not)
 * or -1 (p itself lies in the closed triangle). Exact; never undecided.
 * design (DESIGN.md 4.6, side by ray parity):
 *   1. s_p = orient3d(u,v,w,p); 0: answer -1 if p lies in the closed triangle (exact 2D
 *      test in a coordinate plane where the triangle does not degenerate), else 0.
 *   2. orient3d(u,v,w,q') is affine in q': its sign is the first nonzero of
 *      orient3d(u,v,w,q), -N_x, -N_y, -N_z, with N = (v-u) x (w-u) (each N_k an exact 2D
 *      orientation). Same side as p: 0.
 *   3. For each edge (u,v): orient3d(p,q',u,v) = orient3d(p,q,u,v) + eps-terms with
 *      coefficients (u-v) x (p-v), again exact 2D orientations; all three signs equal:
 *      1. They cannot all vanish (p on the line uv would put p in the plane, step 1).
 * The perturbation is the same for every triangle, so the answers over a whole mesh are
 * those of one segment in general position: the crossing count of a closed mesh has the
 * parity of inside(p) xor inside(q) whenever q is not on the surface.
 */
int as_segment_triangle_sos(const double p[3], const double q[3], const double u[3],
                            const double v[3], const double w[3]);

/* Exact orientation of (a, b, c) projected on the coordinate plane (i, j):
 * sign of (b_i - a_i)(c_j - a_j) - (b_j - a_j)(c_i - a_i). */
double as_orient2d_proj(const double a[3], const double b[3], const double c[3], int i, int j);

/* The point c of the closed triangle (u, v, w) nearest to p (region method of Ericson,
 * "Real-Time Collision Detection" 5.1.5; degenerate triangles fall back to their edges).
 * c always lies in the triangle's bounding box. Returns |p - c|^2. */
double as_closest_on_triangle(const double p[3], const double u[3], const double v[3],
                              const double w[3], double c[3]);

/* ---- queries --------------------------------------------------------------------------- */

typedef struct as_bvh_hit {
    int32_t tri;  /* triangle id */
    int32_t kind; /* as_seg_hit, never AS_HIT_NONE */
    double t;     /* parameter along the segment, see as_segment_triangle */
} as_bvh_hit;

/* Caller-owned growable hit list; zero-initialise, free with as_bvh_hits_free. */
typedef struct as_bvh_hits {
    as_bvh_hit *h;
    size_t n, cap;
} as_bvh_hits;

void as_bvh_hits_free(anistar_context *ctx, as_bvh_hits *hits);

/*
 * as_bvh_segment — every triangle met by the closed segment [a, b] (as_segment_triangle
 * != NONE), sorted by (t, triangle id), into out (cleared first).
 * Returns ANISTAR_OK or ANISTAR_ENOMEM (out then partial).
 */
anistar_status as_bvh_segment(anistar_context *ctx, const as_bvh *b, const double a[3],
                              const double c[3], as_bvh_hits *out);

/* Number of triangles met by [a, b] (as above, no allocation); *proper (may be NULL)
 * receives how many of them are AS_HIT_PROPER. */
size_t as_bvh_segment_count(const as_bvh *b, const double a[3], const double c[3],
                            size_t *proper);

/*
 * as_bvh_segment_nearest — of the triangles met by [a, b] (as as_bvh_segment), the contact
 * point x = a + t (b - a) (x = b when t = 1) nearest ref: the least (|x - ref|^2, t,
 * triangle id), the same point as scanning as_bvh_segment's list for the first strict
 * minimum of the distance (but for a segment nearly parallel to a triangle, whose
 * computed t may stray beyond the pruning margin: bvh.c). Returns 1 (x set) or 0 (no
 * triangle met). No allocation. With the side grid: the segment's cells outward from
 * ref; else the tree's segment walk; both prune what lies farther from ref than the best
 * contact so far (with a margin far above the rounding of x).
 */
int as_bvh_segment_nearest(const as_bvh *b, const double a[3], const double c[3],
                           const double ref[3], double x[3]);

/*
 * as_bvh_ray_parity — parity of the number of triangles crossed by [p, q'] (q symbolically
 * perturbed as in as_segment_triangle_sos): 0 or 1, or -1 when p lies on a triangle.
 * For a closed mesh and q not on it the parity is inside(p) xor inside(q), exactly.
 */
int as_bvh_ray_parity(const as_bvh *b, const double p[3], const double q[3]);

/*
 * as_bvh_side — exact side of p with respect to the closed triangle mesh: +1 inside,
 * -1 outside, 0 on a triangle. Points outside the bounding box are outside; otherwise the
 * parity along a segment from p to a point strictly outside the bounding box, beyond its
 * nearest face in a slightly tilted direction (as_bvh_ray_parity, never undecided).
 */
int as_bvh_side(const as_bvh *b, const double p[3]);

/*
 * as_bvh_side_grid — reference points for as_bvh_side and a faster as_bvh_segment_nearest
 * on a triangle tree of a closed mesh: a regular grid of about max_nodes nodes (up to
 * twice that; 0: 8 per triangle, at most 2^24) over the bounding box and one cell beyond
 * it, each node's side decided once, exactly, and each cell's list of the triangles whose
 * box meets it. Then as_bvh_side(p) takes the parity along the short segment from p to a
 * corner of p's cell over that cell's triangles (the side of a point not on the mesh is a
 * fact, so every answer is the one the long segment gives; nodes on a triangle are left
 * out, and a query whose corners are all such takes the long segment), and a crossing
 * query scans the cells along its segment outward from its reference point (the same
 * answer as the tree's). Call it once, before the tree is shared between threads.
 * ANISTAR_OK (also when the box is too flat or too small for a grid: none is made) or
 * ANISTAR_ENOMEM (the tree is unchanged).
 */
anistar_status as_bvh_side_grid(anistar_context *ctx, as_bvh *b, size_t max_nodes);

/*
 * as_bvh_closest — the triangle nearest to p and the nearest point c on it; returns the
 * squared distance (+inf, *tri = -1 when there is no triangle). Ties (equal computed
 * squared distances) go to the smallest triangle id, so the answer does not depend on the
 * tree. Depth-first branch and bound, nearer child first, pruning boxes farther than the
 * best so far. c and tri may be NULL.
 */
double as_bvh_closest(const as_bvh *b, const double p[3], double c[3], int32_t *tri);

/* Ids of the items whose (closed) bounding box meets the closed box [lo, hi], or contains
 * the point p, sorted ascending, into out (cleared first). ANISTAR_OK / ANISTAR_ENOMEM. */
anistar_status as_bvh_query_box(anistar_context *ctx, const as_bvh *b, const double lo[3],
                                const double hi[3], as_idlist *out);
anistar_status as_bvh_query_point(anistar_context *ctx, const as_bvh *b, const double p[3],
                                  as_idlist *out);

/* Check the invariants (exact node boxes, preorder layout, leaf sizes, ids a
 * permutation). Returns 0 if valid, -1 otherwise (or when out of scratch memory: it
 * allocates a bitmap). For tests. */
int as_bvh_check(anistar_context *ctx, const as_bvh *b);

#endif /* ANISTAR_BVH_H */
