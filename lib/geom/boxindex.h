/*
 * boxindex.h — internal: a dynamic index over axis-aligned boxes keyed by integer ids
 * (DESIGN.md 4.4: "stars whose conflict-zone box contains p", boxes that change at every
 * insertion of the mesher).
 *
 * Structure: a hierarchical hash grid with contiguous cells.
 *   - A box whose largest extent e satisfies e < 2^L (L the smallest such integer, raised
 *     if needed so that its coordinates are below 2^(L+50)) lives at level L, in the cell
 *     of level L holding its lower corner: cell index floor(lo_k / 2^L) on each axis,
 *     computed exactly (scaling by a power of two).
 *   - Because e < 2^L, a box containing the point p has its lower corner in one of the
 *     2^3 cells floor(p_k / 2^L) - {0, 1}; a box meeting the box [qlo, qhi] has it in the
 *     cells floor(qlo_k / 2^L) - 1 .. floor(qhi_k / 2^L).
 *   - Cells are entries of an open-addressing hash table (linear probing, backward-shift
 *     deletion) keyed by (level, cell); each owns one contiguous block of box entries
 *     {lo, hi, id} (2^k entries; blocks come from one pool with a free list per size and
 *     double when full), so a query scans memory sequentially. A record per id says
 *     where its entry is.
 *   - Every candidate is tested against its true box (stored in the entry), so answers
 *     are exact: "box contains p" means lo_k <= p_k <= hi_k for k = 0, 1, 2 (closed
 *     boxes), "meets" means closed overlap.
 * Complexity: set (insert or update) and remove O(1) expected — an update that keeps the
 * level and the cell (small moves and shrinks) only rewrites the entry; a point query costs
 * 8 hash probes per level holding boxes plus a sequential scan of the probed cells' boxes
 * (about 24 times the answer for boxes of one size and bounded aspect ratio: the probed
 * region is (2 * 2^L)^3 against e^3); a box query enumerates the candidate cells of each
 * level, or scans the table when that would be more work than the level holds. Results
 * are sorted by id.
 * Boxes are filed by their largest extent, so a box much thinner on some axis than on
 * another costs the scan about its aspect ratio more candidates.
 * Why not a dynamic AABB tree (Box2D-style, fattened leaves): tried; with ~30 boxes over
 * each point its incremental SAH insertions gave trees whose point queries visited ~80
 * nodes per answer through scattered memory, about twenty times slower than this grid in
 * bench_spatial, and its updates cost O(log n) rotations instead of O(1).
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

/* Number of grid levels holding boxes. For tests and benches. */
size_t as_boxindex_levels(const as_boxindex *bi);

/* Check every invariant (levels and cells of the boxes, the id records, the hash table,
 * the level counts, blocks and free blocks covering the pool exactly once). Returns 0 if
 * valid, -1 otherwise (also when out of memory for its scratch arrays). For tests. */
int as_boxindex_check(anistar_context *ctx, const as_boxindex *bi);

#endif /* ANISTAR_BOXINDEX_H */
