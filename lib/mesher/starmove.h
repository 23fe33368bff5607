/*
 * starmove.h — internal: moving one site of the star set to a new position, with an
 * exact undo (DESIGN.md 4.9, paper 6.2). Used by the vertex optimisation (optimize.c).
 *
 * A move of site v from x to p:
 *  - the touched stars T are v's own star and every other star w that holds v in its
 *    triangulation T'_w (found among the stars whose conflict-zone box contains x) or
 *    whose zone p conflicts with (the stars whose box contains p, tested exactly);
 *  - v's coordinates and metric change (the metric is evaluated at p), p is added to the
 *    kd-tree under id v (see "kd-tree" below);
 *  - every star of T is rebuilt from scratch into a NEW star structure: the corners, its
 *    center, the sites of its old restricted facets (minus v), then grown from the kd-tree
 *    as a new star (so v at p enters if it conflicts; zones may grow when v leaves);
 *  - the facet table, the inconsistent set and the box index follow each star's diff.
 * The old star structures are kept aside until as_starmove_commit (frees them) or
 * as_starmove_undo (puts them back and applies the reverse diffs): undo restores the
 * exact previous stars (same del3, same surface centers, bit for bit) and the same facet
 * table contents, so a rejected move leaves no trace in the result (determinism).
 *
 * design (the choices, DESIGN.md 4.9):
 *  - rebuild rather than delete: del3 has no vertex removal; a star is small (tens of
 *    sites), so rebuilding the few touched stars costs about as much as one insertion;
 *  - holders of v are looked for among the stars whose box contains x. A star w holding v
 *    whose box does not contain x keeps a stale copy of v: v lies outside every inflated
 *    surface ball of w, hence (the balls of w's restricted facets are empty and stay so)
 *    removing it cannot change S_w; the stale copy disappears at w's next rebuild. Such a
 *    w is rebuilt (never inserted into) if a later move reaches it, so one star never
 *    holds two copies of one id;
 *  - kd-tree: it has no removal, so a move inserts (p, v) and leaves (x, v) in place.
 *    Box queries may return v twice or at a stale position; every candidate is tested at
 *    its current position (ss->xyz), so stale entries only cost time. as_starmove_flush
 *    rebuilds the tree from the current positions (the optimiser calls it when stale
 *    entries pile up and at the end).
 */
#ifndef ANISTAR_STARMOVE_H
#define ANISTAR_STARMOVE_H

#include <stdint.h>

#include "core.h"
#include "mesher/starset.h"

/* A move in progress (zero-initialise; free with as_starmove_free). */
typedef struct as_starmove {
    int32_t v;              /* the site moved, -1 when no move is pending */
    double old_x[3];        /* its position before */
    as_metric_frame old_mf; /* its metric before */
    int32_t *ids;           /* the touched stars (v first, then ascending ids) */
    as_star **old;          /* their structures before the move (owned until commit/undo) */
    size_t n, cap;
    int32_t *seeds;         /* scratch: the ids of as_starmove_flush's rebuild */
    size_t cap_seeds;
    int32_t *bid;           /* stars built ahead on the threads: their sites ... */
    as_star **bst;          /* ... and structures (nbuilt of them, room for cap) */
    size_t nbuilt;
    size_t stale;           /* kd-tree entries at positions that are no longer current */
    int early;              /* set by the caller: stop at the first final inconsistency */
    int doomed;             /* out: the move stopped early (see as_starmove_apply) */
} as_starmove;

void as_starmove_free(anistar_context *ctx, as_starmove *mv);

/*
 * Move site v (a surface site with a star) to p (which should lie on S). On ANISTAR_OK the
 * move is pending: mv->ids[0..mv->n) are the touched stars (ss->stars[id] their new
 * structures), ss->ninc and the stars tell whether it is acceptable; then call
 * as_starmove_commit or as_starmove_undo. Returns OK; EINVAL (the metric at p is not SPD
 * or not finite, surface errors); ENOMEM; EINTERNAL. On an error the old stars are put
 * back where possible, but the star set is then only fit for destruction (its facet table
 * may be out of step); no memory leaks either way.
 * With mv->early set, the stars are rebuilt one at a time and the move stops (mv->doomed
 * = 1, still pending: undo it) as soon as an inconsistent facet is final: none of its
 * vertices' stars is left to rebuild, so the full move would end with ss->ninc > 0.
 * design: the rebuild of one star reads only its old structure, the positions, the
 *   metrics and the kd-tree, never another touched star, so stopping early (and the order
 *   of the rebuilds) changes nothing in the stars that are rebuilt; a move that is not
 *   doomed ends exactly as without mv->early. Nearly every move the optimiser undoes is
 *   undone for an inconsistent facet (11,485 of 11,631 on knot1: docs/algorithm.md §9).
 */
anistar_status as_starmove_apply(as_starset *ss, as_starmove *mv, int32_t v, const double p[3]);

/* Keep the pending move: free the old star structures. */
void as_starmove_commit(as_starset *ss, as_starmove *mv);

/*
 * Revert the pending move: the old stars, position and metric come back, the facet table
 * gets the reverse diffs. Returns OK, ENOMEM (the table could not grow; the star set is
 * then only fit for destruction) or EINTERNAL.
 */
anistar_status as_starmove_undo(as_starset *ss, as_starmove *mv);

/* Rebuild ss's kd-tree from the current positions of the poles and sites (drops stale
 * entries). OK or ENOMEM (the old tree is kept). */
anistar_status as_starmove_flush(as_starset *ss, as_starmove *mv);

/* Defined in the "exported for starmove.c" block at the end of starset.c (wrappers of
 * its static apply_diff and next_epoch, and the rebuild of a star; see there). */
anistar_status as_starset_apply_diff(as_starset *ss, int32_t v, const as_rfacet *old,
                                     int32_t nold);
uint32_t as_starset_next_epoch(as_starset *ss);
/* A new star of site w (its current position and metric) from scratch into st
 * (initialised, empty), on thread slot t's workspace (-1: the caller's): the corners, w,
 * the sites of old's restricted facets other than skip, then growth from the kd-tree. It
 * reads old, the positions, the metrics and the kd-tree only, so the rebuilds of one move
 * may run at once (slot workspaces need as_starset_threads_prepare first). */
anistar_status as_starset_rebuild_on(as_starset *ss, int t, int32_t w, const as_star *old,
                                     int32_t skip, as_star *st);
/* Size the thread slots' workspaces to the sites and copy the environment to them (no-op
 * without a pool). */
anistar_status as_starset_threads_prepare(as_starset *ss);

#endif /* ANISTAR_STARMOVE_H */
