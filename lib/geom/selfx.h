/*
 * selfx.h — internal: exact self-intersection test of a triangle mesh given as arrays
 * (`anistar info`, include/anistar.h "What a file holds").
 *
 * Two triangles of a mesh intersect when their closed point sets meet anywhere other than
 * in what their shared vertex indices make them share by construction:
 *   - no shared index: any common point (a touch at one point counts; so does a vertex
 *     of one triangle at the same coordinates as a vertex of the other);
 *   - one shared vertex p: any common point other than p;
 *   - a shared edge uv: any common point off the segment uv (they are coplanar and fold
 *     onto each other);
 *   - three shared indices (a duplicated triangle): always.
 * Degenerate triangles (a repeated index, or three exactly collinear points) have no
 * interior and are skipped; the topology report counts them.
 *
 * Every decision is exact: signs of as_orient3d and of exact 2D orientations in a
 * coordinate plane (bvh.h), on the caller's doubles, whose magnitudes must be within the
 * range of as_orient3d (0 or [1e-40, 1e40]; finite).
 */
#ifndef ANISTAR_SELFX_H
#define ANISTAR_SELFX_H

#include <stddef.h>
#include <stdint.h>

#include "core.h"

/*
 * as_tri_pair_intersect — 1 if triangles ta and tb (three vertex indices each into xyz)
 * intersect in the sense above, 0 if not (also when either is degenerate).
 * design: closed triangles without shared index meet iff an edge of one meets the other
 *   (their intersection is convex; a point of it farthest along any direction lies on a
 *   boundary): six exact segment/triangle tests (as_segment_triangle). With one shared
 *   vertex p, T1 = (p,a,b), T2 = (p,c,d): the intersection is convex and contains p, so
 *   it holds another point iff its boundary does: [a,b] meets T2, or [c,d] meets T1, or
 *   an edge from p (pa, pb, pc, pd) leaves p inside the other triangle — the edge's end
 *   lies in the other's plane and in the closed wedge of its angle at p. With a shared
 *   edge uv, T1 = (u,v,a), T2 = (u,v,b): non-coplanar planes meet in the line uv only;
 *   coplanar ones overlap iff a and b lie on the same side of uv.
 */
int as_tri_pair_intersect(const double *xyz, const int32_t *ta, const int32_t *tb);

/* 1 if the triangle (three vertex indices into xyz) is degenerate: a repeated index or
 * three exactly collinear points. */
int as_tri_degenerate(const double *xyz, const int32_t *t);

/*
 * as_self_intersections — the pairs (i, j), i < j, of intersecting triangles of the mesh
 * (nv vertices xyz, nt triangles tri, indices checked by the caller), in increasing
 * order of (i, j). Counting stops at cap pairs (*capped = 1 then, else 0); *count gets
 * the number found (<= cap); the first min(*count, npairs) pairs go to pairs[2k],
 * pairs[2k+1] (pairs may be NULL when npairs is 0).
 * Returns ANISTAR_OK, ANISTAR_EINVAL (a non-finite coordinate, nt >= INT32_MAX),
 * ANISTAR_ENOMEM.
 * design: a static AABB tree over the triangles (as_bvh_build_triangles); for each
 *   non-degenerate triangle i, the triangles whose boxes meet its box (as_bvh_query_box),
 *   and for each such j > i the exact pair test. O(n log n + candidate pairs): each
 *   triangle meets the boxes of its neighbours and of the triangles it really crosses.
 */
anistar_status as_self_intersections(anistar_context *ctx, const double *xyz, size_t nv,
                                     const int32_t *tri, size_t nt, size_t cap,
                                     int32_t *pairs, size_t npairs, size_t *count,
                                     int *capped);

#endif /* ANISTAR_SELFX_H */
