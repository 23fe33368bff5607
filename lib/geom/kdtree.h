/*
 * kdtree.h — internal: a kd-tree over points with k-nearest, radius and box queries, and
 * incremental insertion (DESIGN.md 1 and 4.4: jet fitting on the k nearest vertices, paper
 * 5.2.3; Gaussian metric blending; the mesher's kd-tree of sites).
 *
 * Structure. An as_kdtree is a FOREST of static kd-trees kept as a stack (the
 * "logarithmic method" of Bentley and Saxe) plus a small unsorted buffer:
 *   - every point lives in one array of slots {x, y, z, id}; each static tree owns a
 *     contiguous range of slots and a contiguous range of nodes, in stack order, and
 *     the buffer is the range after the last tree (at most AS_KD_LEAF points);
 *   - a static tree is built by median splits along the widest axis of the node's
 *     bounding box (nth_element-style selection), leaves hold AS_KD_LEAF/2 to AS_KD_LEAF
 *     points, nodes are stored in preorder in one array and carry their exact bounding
 *     box; build and queries use explicit stacks, never recursion;
 *   - insertion appends to the buffer; a full buffer becomes a tree, then while the tree
 *     below the top holds no more points than the top one, the two are merged (the
 *     slots and nodes of the top trees are a suffix of the arrays, so a merge rebuilds
 *     that suffix in place).
 * Complexity: static build O(n log n); insertion amortised O(log^2 n) (every point is
 *   rebuilt O(log n) times, each rebuild O(log n) per point); the forest has at most
 *   log2(n / AS_KD_LEAF) + 2 trees, so a nearest-neighbour query costs O(log^2 n)
 *   (O(log n) for a tree made by as_kdtree_build and not inserted into since).
 *
 * Determinism. Results depend only on the set of (point, id) pairs, never on the order
 * of insertion or on the forest's shape: k-nearest results are sorted by squared
 * distance then by id (ids should be distinct for the tie-break to mean something),
 * radius and box results by id. Squared distances are computed by one formula,
 * ((x-qx)^2 + (y-qy)^2) + (z-qz)^2, so callers can reproduce them bit for bit.
 *
 * Memory comes from the context; queries never allocate except to grow the caller's
 * as_idlist. Queries take the tree const and keep their state on the stack, so several
 * threads may query one tree at once (insertion needs exclusive access). Failed calls
 * leave the tree as it was (strong guarantee).
 */
#ifndef ANISTAR_KDTREE_H
#define ANISTAR_KDTREE_H

#include <stddef.h>
#include <stdint.h>

#include "core.h"

/* Largest number of points in a leaf (and in the insertion buffer). */
#define AS_KD_LEAF 16

/* A growable list of non-negative int32 ids owned by the caller, memory from a context.
 * Zero-initialise ({0}) and free with as_idlist_free. Also used by bvh.h and boxindex.h. */
typedef struct as_idlist {
    int32_t *ids;
    size_t n, cap;
} as_idlist;

void as_idlist_free(anistar_context *ctx, as_idlist *l);
/* Append id; returns 0, or -1 when memory runs out (l unchanged). */
int as_idlist_push(anistar_context *ctx, as_idlist *l, int32_t id);
/* Sort ids[0..n) ascending (heapsort: no recursion, no allocation). */
void as_ids_sort(int32_t *ids, size_t n);

/* One stored point (a slot). Exposed for as_kdpoint_select, which bvh.c reuses. */
typedef struct as_kdpoint {
    double x[3];
    int32_t id;
} as_kdpoint;

/* Reorder a[0..n) so that a[k] holds the element of rank k by coordinate axis, every
 * element before it has a coordinate <= and every element after it >= (nth_element).
 * Deterministic; O(n) expected, O(n log n) worst case (introselect: median-of-three
 * quickselect, heapsort after too many rounds). Coordinates must not be NaN. */
void as_kdpoint_select(as_kdpoint *a, size_t n, size_t k, int axis);

typedef struct as_kdtree as_kdtree;

/* An empty tree (for incremental insertion). Returns ANISTAR_OK or ANISTAR_ENOMEM. */
anistar_status as_kdtree_new(anistar_context *ctx, as_kdtree **out);

/*
 * as_kdtree_build — a tree over n points xyz[3i..3i+2] with ids ids[i] (ids == NULL:
 * id i). One static tree, O(n log n). The coordinates are copied.
 * Returns ANISTAR_OK; ANISTAR_EINVAL (a non-finite coordinate, a negative id, n >=
 * INT32_MAX, xyz == NULL with n > 0); ANISTAR_ENOMEM. *out is NULL on failure.
 */
anistar_status as_kdtree_build(anistar_context *ctx, const double *xyz, const int32_t *ids,
                               size_t n, as_kdtree **out);

void as_kdtree_free(anistar_context *ctx, as_kdtree *kd);

/* Make room for `more` further insertions so that they allocate nothing (optional). */
anistar_status as_kdtree_reserve(anistar_context *ctx, as_kdtree *kd, size_t more);

/*
 * as_kdtree_insert — add the point p with id `id` (>= 0). Amortised O(log^2 n).
 * Returns ANISTAR_OK; ANISTAR_EINVAL (non-finite p, negative id, too many points);
 * ANISTAR_ENOMEM (the tree is unchanged).
 */
anistar_status as_kdtree_insert(anistar_context *ctx, as_kdtree *kd, const double p[3],
                                int32_t id);

size_t as_kdtree_size(const as_kdtree *kd);
/* Number of static trees in the forest (not counting the buffer); for tests/benches. */
size_t as_kdtree_tree_count(const as_kdtree *kd);

/*
 * as_kdtree_knn — the min(k, size) points nearest to q, written to ids[0..) and their
 * squared distances to d2[0..), sorted by (d2, id). ids and d2 must both hold k entries:
 * they double as the working heap, so the query allocates nothing.
 * Returns the number of points written (0 when q is not finite).
 */
size_t as_kdtree_knn(const as_kdtree *kd, const double q[3], size_t k, int32_t *ids,
                     double *d2);

/* All ids whose point x satisfies |x - q|^2 <= r*r (squared distance as above), sorted
 * ascending, into out (cleared first). ANISTAR_OK or ANISTAR_ENOMEM (out then holds a
 * partial, unsorted result). r < 0 or NaN, or q not finite, gives an empty result. */
anistar_status as_kdtree_radius(anistar_context *ctx, const as_kdtree *kd, const double q[3],
                                double r, as_idlist *out);

/* All ids whose point lies in the closed box [lo, hi], sorted ascending, into out
 * (cleared first); empty when lo_k > hi_k (or NaN) on some axis. ANISTAR_OK or
 * ANISTAR_ENOMEM. */
anistar_status as_kdtree_box(anistar_context *ctx, const as_kdtree *kd, const double lo[3],
                             const double hi[3], as_idlist *out);

/* as_kdtree_box, sorted or in the tree's traversal order (sorted == 0: cheaper; the order
 * is still a deterministic function of the insertion history). */
anistar_status as_kdtree_box_any(anistar_context *ctx, const as_kdtree *kd, const double lo[3],
                                 const double hi[3], int sorted, as_idlist *out);

/*
 * as_farthest_order — the farthest-point order of n points xyz[3i..3i+2] (n < INT32_MAX):
 * out[0] = 0, then each time the point whose squared distance (the formula above) to the
 * nearest point picked so far is largest, ties to the lowest index, until q points are
 * picked or all are; *nout receives how many (out holds q entries, or n when q > n). The
 * same order as the scan that updates every distance after each pick, in about
 * O(n log n) for spread points: a kd-tree's nodes keep their points' largest distance, so
 * a pick enters only the nodes where a distance can shrink and the next pick is the
 * root's. ANISTAR_OK, ANISTAR_EINVAL (non-finite coordinates) or ANISTAR_ENOMEM.
 */
anistar_status as_farthest_order(anistar_context *ctx, const double *xyz, size_t n, size_t q,
                                 int32_t *out, size_t *nout);

/* Check the invariants (boxes contain their points, leaf sizes, preorder layout, tree
 * sizes of the forest, ids >= 0). Returns 0 if valid, -1 otherwise. For tests. */
int as_kdtree_check(const as_kdtree *kd);

#endif /* ANISTAR_KDTREE_H */
