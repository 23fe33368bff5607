/*
 * boxindex.h — internal: a dynamic index over axis-aligned boxes keyed by integer ids
 * (DESIGN.md 4.4: "stars whose conflict-zone box contains p", boxes that change at every
 * insertion of the mesher).
 *
 * Structure: a dynamic bounding-volume tree (the balanced AABB tree of Box2D / Bullet).
 * Each id's TRUE box is stored in an array indexed by id; its leaf in the tree holds a
 * FAT box (the true box grown by 1/8 of its largest extent on every side). Internal
 * nodes hold the exact union of their children's boxes and their height; nodes live in
 * one pool with a free list.
 *   - Insertion descends from the root by the surface-area heuristic (pair the leaf with
 *     the node whose union costs least, counting the growth of the ancestors), hangs the
 *     leaf there under a new internal node, then refits and rebalances the ancestors
 *     (AVL-style rotations by height). Removal replaces the parent by the sibling and
 *     refits/rebalances likewise. Both O(log n) (tree height), no allocation beyond
 *     amortised pool growth.
 *   - An update whose new box still fits in the leaf's fat box (and that fat box is at
 *     most twice too large) only rewrites the true box: O(1). Conflict zones that shrink
 *     and drift a little at each insertion mostly take this path.
 *   - Queries descend through the nodes whose boxes meet the query (fat boxes only filter)
 *     and test each reached id's TRUE box, so answers are exact: "box contains p" means
 *     lo_k <= p_k <= hi_k for k = 0, 1, 2 (closed boxes), "meets" means closed overlap.
 *     Cost O(log n + answer) for boxes of bounded overlap; results are sorted by id.
 * Why not a hash grid: with boxes of many sizes and aspect ratios (anisotropic conflict
 * zones), a grid keyed on box size scans 8-64 times more candidates than it reports,
 * through scattered memory; the tree adapts to sizes and shapes.
 *
 * Ids are non-negative int32 and should be dense (the id map has max id + 1 entries).
 * Memory from the context; failed calls leave the index unchanged. Queries take the index
 * const and keep their state on the stack (concurrent queries are fine; updates need
 * exclusive access).
 */
#ifndef ANISTAR_BOXINDEX_H
#define ANISTAR_BOXINDEX_H

#include <stddef.h>
#include <stdint.h>

#include "core.h"
#include "geom/kdtree.h" /* as_idlist */

typedef struct as_boxindex as_boxindex;

anistar_status as_boxindex_new(anistar_context *ctx, as_boxindex **out);
void as_boxindex_free(anistar_context *ctx, as_boxindex *bi);

/*
 * as_boxindex_set — insert the box [lo, hi] for id, or replace id's box.
 * Returns ANISTAR_OK; ANISTAR_EINVAL (id < 0 or INT32_MAX, a non-finite coordinate,
 * lo_k > hi_k, or an extent hi_k - lo_k that overflows); ANISTAR_ENOMEM (unchanged).
 */
anistar_status as_boxindex_set(anistar_context *ctx, as_boxindex *bi, int32_t id,
                               const double lo[3], const double hi[3]);

/* Remove id's box. Returns 1 if it was there, 0 otherwise. Never allocates. */
int as_boxindex_remove(as_boxindex *bi, int32_t id);

/* id's box into lo, hi; returns 1, or 0 if id has none. */
int as_boxindex_get(const as_boxindex *bi, int32_t id, double lo[3], double hi[3]);

size_t as_boxindex_size(const as_boxindex *bi);

/* Ids whose closed box contains p, sorted ascending, into out (cleared first).
 * ANISTAR_OK; ANISTAR_EINVAL (p not finite); ANISTAR_ENOMEM (out partial). */
anistar_status as_boxindex_query_point(anistar_context *ctx, const as_boxindex *bi,
                                       const double p[3], as_idlist *out);

/* Ids whose closed box meets the closed box [lo, hi], sorted ascending, into out (cleared
 * first). ANISTAR_OK; ANISTAR_EINVAL (non-finite, or lo_k > hi_k); ANISTAR_ENOMEM. */
anistar_status as_boxindex_query_box(anistar_context *ctx, const as_boxindex *bi,
                                     const double lo[3], const double hi[3], as_idlist *out);

/* Height of the tree (-1 when empty; 0 for one box). For tests and benches. */
int as_boxindex_height(const as_boxindex *bi);

/* Check every invariant (parent/child links, exact internal boxes and heights, fat leaf
 * boxes containing the true boxes, the id map, the free list). Returns 0 if valid, -1
 * otherwise. For tests. */
int as_boxindex_check(const as_boxindex *bi);

#endif /* ANISTAR_BOXINDEX_H */
