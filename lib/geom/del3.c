/*
 * del3.c — incremental Bowyer-Watson 3D Delaunay triangulation on pooled arrays (del3.h).
 *
 * design: DESIGN.md 4.3 (the star triangulator), paper 3.1 (Del_M(V) is the Euclidean
 * Delaunay triangulation of the stretched points F_M V) and 5.3 (small star
 * triangulations, the 8 box corners).
 *
 * ---- The infinite vertex and the perturbation -------------------------------------------
 *
 * Perturbation. as_insphere_sos(a,b,c,d,e; ids) decides insphere ties as if each point x
 * were lifted to |x|^2 + eps_x, with infinitesimal eps_x ordered by global id (the
 * scheme of predicates.c: a weighted/regular triangulation with infinitesimal generic
 * weights; coordinates are not perturbed, so as_orient3d stays exact and unperturbed).
 * The triangulation we maintain is the regular triangulation T of the perturbed lifted
 * points: unique, independent of the insertion order, with every point a vertex (lifted
 * points lie on a strictly convex paraboloid, so none is hidden) and no flat tet.
 *
 * Infinite vertex. The hull faces of T are closed by tets (inf, a, b, c): T becomes a
 * triangulation of the 3-sphere, every face has two sides and every point of R^3 lies in
 * the closure of some tet. An infinite tet is oriented so that replacing inf by a point q
 * gives orient3d > 0 exactly when q is strictly beyond its hull face ("visible").
 *
 * Conflict rule (a tet is in conflict with p iff an insertion of p destroys it):
 *   finite tet t:            insphere_sos(t, p) > 0;
 *   infinite tet (inf,abc):  o = orient3d(abc with p in inf's slot);
 *                            o > 0 -> conflict (p sees the hull face: it stops being one);
 *                            o < 0 -> no conflict;
 *                            o = 0 -> conflict iff insphere_sos(t', p) > 0, t' = (abcd)
 *                                     the finite tet on the other side of abc.
 * Proof of the coplanar case. Let p lie on the plane H of abc. (i) Geometry: the ball of
 * every sphere through a, b, c meets H in the circumdisk of abc, so for the finite
 * neighbour t' (any d off H) insphere(t', p) > 0 iff p is strictly inside the circumcircle
 * of abc, and = 0 iff on it. (ii) Perturbation: with H rotated to z = 0, the 5x5 lifted
 * determinant of (a,b,c,d,p) has only one non-zero entry in its z column (row d), so it
 * equals +-z_d times the 4x4 lifted incircle determinant of (a,b,c,p) in H with the SAME
 * lifts |x|^2 + eps_x; every term of the eps-expansion factors the same way (the term of
 * eps_d is orient3d(a,b,c,p) = 0). Hence insphere_sos(t', p) is, up to the orientation
 * sign that the positive orientation of t' fixes, the perturbed 2D incircle test of p
 * against abc in H — independent of d. (iii) Hull: H is a supporting plane of the hull of
 * the old and of the new point set; the part of T's boundary in H is the regular
 * triangulation of the points in H with the restricted lifts (a face of a regular
 * subdivision restricted to a face of the hull), so the hull face abc survives the
 * insertion of p in H iff p is not in 2D perturbed conflict with abc, which is exactly
 * the rule. If p is off H, the facets in H do not change and the sign of o decides.
 * Consequences used below, each exact:
 *   - the conflict zone is the set of simplices of the old S^3 triangulation that are not
 *     in the new one; it is connected (the visible part of the lower hull of the lifted
 *     points, plus visible hull faces) and we grow it by adjacency from one conflict tet;
 *   - every cavity boundary face sees p strictly: for two finite tets, the two lifted
 *     hyperplanes agree over the face's plane, so p on that plane would be both strictly
 *     below one and strictly above the other at the same height — impossible; for a
 *     finite tet t' next to an infinite one across hull face abc, p coplanar with abc puts
 *     both on the same side of the rule (both decided by insphere_sos(t', p)); for two
 *     infinite tets sharing (inf, a, b), p collinear with a, b is either strictly inside
 *     both circumcircles (between a and b: both conflict) or outside both (not on the hull
 *     faces' circles: neither conflicts by the coplanar rule) — so the new infinite tet
 *     (inf, a, b, p) is never flat. New tets are therefore never flat and positively
 *     oriented by construction (they inherit the orientation of the tet they replace);
 *   - the walk ends in a finite tet whose closure contains p (then p is strictly inside its
 *     circumball unless p is one of its vertices — the duplicate test) or steps through a
 *     hull face that p strictly sees (an infinite tet in conflict): the start of the zone
 *     needs no predicate.
 * Local Delaunay (every tet versus the opposite vertex of each neighbour, with the rule
 * above) everywhere implies the empty-sphere property: the lifted lower hull is then
 * locally convex, hence convex; the infinite tets' local test makes the hull convex and
 * its coplanar parts 2D perturbed-Delaunay. as_del3_check_delaunay tests exactly that.
 *
 * ---- Memory --------------------------------------------------------------------------
 *
 * One 32-byte record per tet (4 vertices, then the 4 neighbour handles 8t'+j) and per
 * vertex (coordinates, an incident tet, a scratch number): a neighbour or a vertex costs
 * one cache line (the records are 64-byte aligned in their blocks). A free slot has
 * AS_DEL3_DEAD in its first word and the next free slot (-1: none) in its second. mark[t]
 * (one byte) is MARK_NONE between operations; during a search MARK_CONF (in conflict) or
 * MARK_OUT (visited, not in conflict); every operation clears the marks it set. The
 * search copies the records of the conflict tets (crec): the new tets may overwrite their
 * slots before the last boundary face is read. Vertex data and tet data live in one block
 * each (grown by copying, so a failed growth leaves everything as it was). An insertion
 * reserves everything it needs before it modifies anything: ANISTAR_ENOMEM always leaves
 * the triangulation unchanged.
 *
 * Slot numbering. The mesher's results depend, at the rounding level, on the numbering of
 * the tets of its stars (the order facets are enumerated in), so small triangulations
 * keep exactly the numbering of the first version: the walk's random face order and rng
 * use, the depth-first search order (faces 0..3), the k-th new tet in the slot of the k-th
 * conflict tet found, then the free list (LIFO), then new slots; a vertex's incident tet
 * is the last new tet holding it, the new point's the first. Big triangulations (more
 * than DEL3_PREFETCH_MIN slots) walk differently (walk), hence number differently.
 *
 * ---- Speed (measured with bench/bench_del3.c, callgrind and cachegrind --branch-sim) ----
 *
 *  - The work per insertion is fixed by the triangulation (bulk uniform points: ~21 tets
 *    removed, ~28 created, ~45 conflict tests; a 40-point star: 10, 16, 22): what is left
 *    to gain is instructions per test, per new tet and per visited face, branch
 *    mispredictions (coin flips: is a neighbour new, in conflict, out) and cache misses.
 *    Measured (cachegrind): a uniform bulk point ~22k instructions and 52 mispredictions
 *    (first version: 24k and 107), a star insertion ~11.5k and 34 (11.5k and 81 with its
 *    default sphere cache, 13k and 70 without); the IPC is already ~3 on stars and ~2.6
 *    on uniform points, so the instruction count is the limit there, and the cache
 *    misses on the torus.
 *  - Search: per popped tet, the unvisited neighbours are tested in a loop over the set
 *    bits of a mask built from the four marks (one table lookup), then the outcomes are
 *    recorded in face order without branches (search).
 *  - Conflict tests: the inline insphere filter first compares with a cheap bound (a
 *    square root and three products instead of 25 operations: isp_filter), proven to
 *    dominate the semi-static bound of predicates.h.
 *  - Cavity: the k-th new tet is written from the conflict tet's record copy; the new tets
 *    are glued in two branch-free passes through a table keyed on the oriented boundary
 *    edge (by vertex ids in star-sized triangulations, else by cavity-local numbers).
 *  - Walk: random face order for small triangulations (numbering), farthest face for big
 *    ones (half the steps on surface samples).
 *  - The sphere cache (optional, small triangulations): a lifted plane per tet with a
 *    proven bound, computed at creation, in a 64-byte line with its reference vertex: a
 *    test reads that line only. Off by default: since the inline filter got cheaper,
 *    building a star is ~5% faster without it; it pays for triangulations queried many
 *    times.
 *  - Prefetching of the neighbours' records in big triangulations (the torus: 18%); bulk
 *    insertion prefetches the next points of the sorted order (the input is read in a
 *    random order: one cache miss per point otherwise). The spatial sort's Hilbert index
 *    is a 24-state table machine (sort.c): 340 instructions per point instead of 1040.
 */
#include "geom/del3.h"

#include <float.h>
#include <math.h>
#include <string.h>

#include "geom/dd.h"
#include "geom/expansion.h"
#include "geom/predicates.h"
#include "geom/sort.h"


enum { MARK_NONE = 0, MARK_CONF = 1, MARK_OUT = 2 }; /* MARK_OUT - 1 == MARK_CONF */
enum { EDGE_EMPTY = INT32_MIN, EDGE_USED = INT32_MIN + 1 };
#define MAX_TETS ((size_t)(INT32_MAX / 8))
#define MAX_VERTS ((int32_t)(INT32_MAX - 2))

/* face_vtx[i]: the vertices of face i (opposite vertex i) so that (i, f0, f1, f2) is an
 * even permutation: the two tets of a face list it in opposite orientations. */
static const int8_t face_vtx[4][3] = {{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}};

static inline const double *pt(const as_del3 *d, int32_t v) { return d->vert[v].x; }

/* mark_todo[m] / mark_out[m]: for four 2-bit marks packed in m (mark i in bits 2i, 2i+1),
 * the mask of those MARK_NONE / MARK_OUT. */
#define MK1(m, i, v) ((unsigned)((((m) >> (2 * (i))) & 3u) == (v)) << (i))
#define MK4(m, v) (MK1(m, 0, v) | MK1(m, 1, v) | MK1(m, 2, v) | MK1(m, 3, v))
#define MK_ROW(v, b)                                                                         \
    MK4((b) + 0, v), MK4((b) + 1, v), MK4((b) + 2, v), MK4((b) + 3, v), MK4((b) + 4, v),   \
        MK4((b) + 5, v), MK4((b) + 6, v), MK4((b) + 7, v), MK4((b) + 8, v),                 \
        MK4((b) + 9, v), MK4((b) + 10, v), MK4((b) + 11, v), MK4((b) + 12, v),             \
        MK4((b) + 13, v), MK4((b) + 14, v), MK4((b) + 15, v)
#define MK_TABLE(v)                                                                          \
    MK_ROW(v, 0), MK_ROW(v, 16), MK_ROW(v, 32), MK_ROW(v, 48), MK_ROW(v, 64),              \
        MK_ROW(v, 80), MK_ROW(v, 96), MK_ROW(v, 112), MK_ROW(v, 128), MK_ROW(v, 144),       \
        MK_ROW(v, 160), MK_ROW(v, 176), MK_ROW(v, 192), MK_ROW(v, 208), MK_ROW(v, 224),     \
        MK_ROW(v, 240)
static const uint8_t mark_todo[256] = {MK_TABLE(MARK_NONE)};
static const uint8_t mark_out[256] = {MK_TABLE(MARK_OUT)};
#undef MK_TABLE
#undef MK_ROW
#undef MK4
#undef MK1

/* low_bit[m]: the lowest set bit of the 4-bit mask m (m > 0); bit_count[m]: its bits. */
static const int8_t low_bit[16] = {0, 0, 1, 0, 2, 0, 1, 0, 3, 0, 1, 0, 2, 0, 1, 0};
static const int8_t bit_count[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};

/* The record of tet t; its vertex i is r[i], the handle of its neighbour across face i
 * r[4 + i]. */
static inline int32_t *rec(const as_del3 *d, int32_t t) { return d->tet + 8 * (size_t)t; }

static inline int is_inf(const int32_t *r) { return (r[0] | r[1] | r[2] | r[3]) < 0; }

static inline int same_point(const double *a, const double *b) {
    return a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
}

/* ---- inlined filters ----------------------------------------------------------------------
 * A call into predicates.c costs about as much as its filter; the triangulations make
 * millions of these tests, so the first, semi-static stage is inlined here: predicates.h
 * exports it (as_orient3d_filter / as_insphere_filter, the same stage the adaptive
 * predicates start with). When it cannot decide we call the adaptive predicate (which
 * starts over and is always exact). */

static inline double max3(double a, double b, double c) {
    double m = a > b ? a : b;
    return m > c ? m : c;
}

#if defined(__GNUC__) || defined(__clang__)
#define DEL3_PREFETCH(p) __builtin_prefetch(p)
#define DEL3_NOINLINE __attribute__((noinline))
#define DEL3_INLINE static inline __attribute__((always_inline))
#else
#define DEL3_PREFETCH(p) ((void)(p))
#define DEL3_NOINLINE
#define DEL3_INLINE static inline
#endif

/* Prefetching pays only when the tet arrays outgrow the L1/L2 caches; below this many
 * tet slots (star-sized triangulations) it is skipped (measured: ~5% of a star's
 * instructions). */
#define DEL3_PREFETCH_MIN 4096

/* Exact orient3d: the inlined filter, then predicates.c. */
static inline double orient(const double *a, const double *b, const double *c,
                            const double *d) {
    double r = as_orient3d_filter(a, b, c, d);
    return r != 0 ? r : as_orient3d(a, b, c, d);
}

/* The inline insphere filter (predicates.h: a cheap bound first, then the full one):
 * +1 / -1 when it certifies the sign of insphere(a, b, c, d, e), else 0. */
DEL3_INLINE int isp_filter(const double *a, const double *b, const double *c,
                           const double *d, const double *e) {
    double det = as_insphere_filter(a, b, c, d, e);
    return (det > 0) - (det < 0);
}
/* ---- the cached sphere of a tet ------------------------------------------------------
 * For a finite tet (a, b, c, e) (positively oriented) and a query point p, let u = b - a,
 * v = c - a, w = e - a, x = p - a and
 *   D = u.(v x w),   N = |u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v),
 *   G(p) = |x|^2 D - x.N.
 * The circumcenter is a + N / (2D) (Cramer), so p is strictly inside the circumsphere iff
 * |x|^2 - x.N/D < 0; a positive tet has D < 0 (Shewchuk's orient3d(a,b,c,e) =
 * -u.(v x w)), hence: inside iff G(p) > 0, i.e. sign G = sign insphere(a,b,c,e,p).
 * N and D depend on the tet and on the choice of a among its vertices only: cached in
 * sph[8t..8t+7] = {N, D, m, a} (m below), one 64-byte line per tet. A new tet of an
 * insertion gets its sphere at creation, relative to the new point (then (a, b, c, e) =
 * the new point and the boundary triangle face_vtx[slot], an even permutation: positive);
 * the tets of the first insertions get it at their first test, relative to their vertex
 * 0. A test reads only that line: one subtraction per axis and two dot products.
 *
 * Error bound (eps = 2^-53, gamma_k = k eps / (1 - k eps); our derivation). Every
 * quantity is a polynomial in the exact differences x_i, u_i, v_i, w_i, each computed
 * with one rounding; evaluating a +,-,x expression tree from such leaves gives
 * |computed - exact| <= gamma_k * P, where P is the tree evaluated on the absolute values
 * of the leaves with every - replaced by + (the "permanent"), and k bounds the roundings
 * any monomial goes through (a sum adds 1 to the larger count of its operands, a product
 * adds 1 to the SUM of their counts). Counting, for the evaluation order of
 * sphere_compute and sphere_test: differences 1; v_j w_k 3, (v x w)_i 4; u_i^2 3, |u|^2 5;
 * |u|^2 (v x w)_i 10, N_i 12; u_i (v x w)_i 6, D 8; x_i N_i 14, x.N 16; |x|^2 5,
 * |x|^2 D 14; G 17. With m the largest |component| of u, v, w (computed), the
 * permanents satisfy P(N_i) <= 3 m^2 * 2 m^2 * 3 = 18 m^4, P(D) <= 3 m * 2 m^2 = 6 m^3,
 * so P(G) <= 18 m^4 S1 + 6 m^3 S2 with S1 = sum |x_i|, S2 = |x|^2 (exact values).
 * The computed m (stored), S1 = (|x0| + |x1|) + |x2|, S2 (the one G uses), e1 = C1 (m^2
 * m^2), e2 = C2 (m^2 m) (computed at each test) and bound = e1 S1 + e2 S2 underestimate
 * their exact counterparts by at most a factor (1 - eps)^13 altogether (term e2 S2: m^3
 * loses 3 (the rounded
 * differences), S2 5 (differences squared 2, squares and sums 3), e2's products 3, the
 * bound's product and sum 2; term e1 S1: 4 + 3 + 3 + 2 = 12), and
 * gamma_17 / (1 - eps)^13 < 18 eps; so C1 = 18 * 18 eps and
 * C2 = 6 * 18 eps make |G_computed - G| < bound, and G_computed > bound (< -bound)
 * certifies G > 0 (< 0). Undecided cases (ties included: then G_computed may be 0 and the
 * bound 0 when p = a, so the strict tests fail) go to as_insphere_sos. Valid for inputs in
 * the range of predicates.h (coordinates 0 or of magnitude in [1e-40, 1e40]): every
 * product of at most five nonzero differences then stays a normal double, so the
 * (1 + delta) model of rounding holds and nothing overflows. */
#define SPH_C1 (324.0 * AS_EPS)
#define SPH_C2 (108.0 * AS_EPS)

/* sph[8t + 4] (m) of a tet without a cached sphere: not computed yet, or infinite. */
#define SPH_NONE (-1.0)
#define SPH_INF (-2.0)

/* The cached sphere {N, D, m, a} of the positive tet (a, b, c, e) (see above). */
static inline void sphere_compute(const double *a, const double *b, const double *c,
                                  const double *e, double *s) {
    double u0 = b[0] - a[0], u1 = b[1] - a[1], u2 = b[2] - a[2];
    double v0 = c[0] - a[0], v1 = c[1] - a[1], v2 = c[2] - a[2];
    double w0 = e[0] - a[0], w1 = e[1] - a[1], w2 = e[2] - a[2];
    double vw0 = v1 * w2 - v2 * w1, vw1 = v2 * w0 - v0 * w2, vw2 = v0 * w1 - v1 * w0;
    double wu0 = w1 * u2 - w2 * u1, wu1 = w2 * u0 - w0 * u2, wu2 = w0 * u1 - w1 * u0;
    double uv0 = u1 * v2 - u2 * v1, uv1 = u2 * v0 - u0 * v2, uv2 = u0 * v1 - u1 * v0;
    double nu = (u0 * u0 + u1 * u1) + u2 * u2;
    double nv = (v0 * v0 + v1 * v1) + v2 * v2;
    double nw = (w0 * w0 + w1 * w1) + w2 * w2;
    s[0] = (nu * vw0 + nv * wu0) + nw * uv0;
    s[1] = (nu * vw1 + nv * wu1) + nw * uv1;
    s[2] = (nu * vw2 + nv * wu2) + nw * uv2;
    s[3] = (u0 * vw0 + u1 * vw1) + u2 * vw2;
    s[4] = max3(max3(fabs(u0), fabs(u1), fabs(u2)), max3(fabs(v0), fabs(v1), fabs(v2)),
                max3(fabs(w0), fabs(w1), fabs(w2)));
    s[5] = a[0];
    s[6] = a[1];
    s[7] = a[2];
}

/* +1 / -1 when the cached sphere s (computed: s[4] >= 0) certifies the sign of
 * insphere(tet, p), else 0. */
DEL3_INLINE int sphere_test(const double *s, const double *p) {
    double x0 = p[0] - s[5], x1 = p[1] - s[6], x2 = p[2] - s[7];
    double s2 = (x0 * x0 + x1 * x1) + x2 * x2;
    double g = s2 * s[3] - ((x0 * s[0] + x1 * s[1]) + x2 * s[2]);
    double m = s[4], m2 = m * m;
    double bound = SPH_C1 * (m2 * m2) * ((fabs(x0) + fabs(x1)) + fabs(x2)) +
                   SPH_C2 * (m2 * m) * s2;
    return g > bound ? 1 : -g > bound ? -1 : 0;
}

static inline int finite3(const double *p) {
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

static uint64_t mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}



/* ---- buffers and growth ------------------------------------------------------------------ */

void as_del3_buf_free(anistar_context *ctx, as_del3_buf *b) {
    as_free(ctx, b->a, b->cap * sizeof *b->a);
    b->a = NULL;
    b->n = b->cap = 0;
}

static inline void swap_i32p(int32_t **a, int32_t **b) { int32_t *t = *a; *a = *b; *b = t; }
static inline void swap_sz(size_t *a, size_t *b) { size_t t = *a; *a = *b; *b = t; }

void as_del3_swap_scratch(as_del3 *a, as_del3 *b) {
    swap_i32p(&a->stack, &b->stack);
    swap_sz(&a->cap_stack, &b->cap_stack);
    swap_i32p(&a->conf, &b->conf);
    swap_sz(&a->nconf, &b->nconf);
    swap_sz(&a->cap_conf, &b->cap_conf);
    swap_i32p(&a->crec, &b->crec);
    swap_sz(&a->cap_crec, &b->cap_crec);
    swap_i32p(&a->bf, &b->bf);
    swap_sz(&a->nbf, &b->nbf);
    swap_sz(&a->cap_bf, &b->cap_bf);
    as_del3_edge *et = a->etab;
    a->etab = b->etab;
    b->etab = et;
    swap_sz(&a->cap_etab, &b->cap_etab);
    swap_i32p(&a->etouch, &b->etouch);
    swap_sz(&a->cap_etouch, &b->cap_etouch);
    swap_i32p(&a->ltab, &b->ltab);
    swap_i32p(&a->gl, &b->gl);
    swap_sz(&a->cap_gl, &b->cap_gl);
    as_del3_buf t = a->removed;
    a->removed = b->removed;
    b->removed = t;
    t = a->created;
    a->created = b->created;
    b->created = t;
    swap_i32p(&a->phash, &b->phash);
    swap_sz(&a->cap_phash, &b->cap_phash);
}

static int buf_reserve(anistar_context *ctx, as_del3_buf *b, size_t need) {
    void *p = b->a;
    if (as_grow(ctx, &p, &b->cap, need, sizeof *b->a)) return -1;
    b->a = p;
    return 0;
}

/* The capacity to grow to: doubling, or need + 1/8 (+4) with d->tight_growth. */
static size_t grown_cap(const as_del3 *d, size_t cap, size_t need) {
    if (d->tight_growth && need < SIZE_MAX / 2) return need + need / 8 + 4;
    size_t c = cap ? cap : 16;
    while (c < need) c = c > SIZE_MAX / 4 ? need : 2 * c;
    return c;
}

/* The records of the vertex and tet blocks are aligned to ALIGN bytes inside their block
 * (allocators promise less): a 32-byte record then never straddles two cache lines. */
#define ALIGN 64

static inline void *align_up(void *p) {
    uintptr_t u = (uintptr_t)p;
    return (char *)p + ((ALIGN - (u & (ALIGN - 1))) & (ALIGN - 1));
}

enum { VBYTES = sizeof(as_del3_vertex) + sizeof(int64_t) };

/* One block per vertex capacity: ALIGN bytes of slack, the records vert[-1 .. cap-1]
 * (vert[-1]: the infinite vertex), then gid. */
static size_t vblock_bytes(size_t cap) { return ALIGN + (cap + 1) * VBYTES; }

/* Reallocate the vertex arrays to capacity cap >= nv. 0 or -1 (nothing changed). */
static int set_vertex_cap(as_del3 *d, size_t cap) {
    if (cap > (SIZE_MAX - ALIGN) / VBYTES - 1) return -1;
    char *blk = as_alloc(d->ctx, vblock_bytes(cap));
    if (!blk) return -1;
    /* vert[0] aligned to 32: vert[-1] starts the aligned area + 32 */
    as_del3_vertex *vert = (as_del3_vertex *)align_up(blk + sizeof(as_del3_vertex)) ;
    int64_t *gid = (int64_t *)(void *)(vert + cap);
    size_t n = (size_t)d->nv;
    if (d->cap_v) {
        memcpy(vert - 1, d->vert - 1, (n + 1) * sizeof *vert);
        memcpy(gid, d->gid, n * sizeof *gid);
    } else {
        memset(vert - 1, 0, sizeof *vert);
        vert[-1].loc = -1;
        vert[-1].tet = -1;
    }
    if (d->cap_v) as_free(d->ctx, d->vblk, vblock_bytes(d->cap_v));
    d->vblk = blk;
    d->vert = vert;
    d->gid = gid;
    d->cap_v = cap;
    return 0;
}

static int grow_vertices(as_del3 *d, size_t need) {
    if (need <= d->cap_v) return 0;
    return set_vertex_cap(d, grown_cap(d, d->cap_v, need));
}

/* Store point p with global id g as vertex v (capacity reserved). */
static inline void store_vertex(as_del3 *d, int32_t v, const double *p, int64_t g) {
    as_del3_vertex *x = &d->vert[v];
    x->x[0] = p[0];
    x->x[1] = p[1];
    x->x[2] = p[2];
    x->tet = -1;
    x->loc = -1;
    d->gid[v] = g;
}

enum { TBYTES = 8 * sizeof(int32_t) + sizeof(uint8_t) };

/* The sphere cache (when asked for) exists while the tet capacity is at most this: it
 * pays only on small, often queried triangulations; on big ones its 64 bytes per tet cost
 * more memory traffic than the filter work it saves (measured), so they use the plain
 * filter. */
#define SPH_MAX_TETS ((size_t)1 << 14)

static size_t sph_bytes(size_t cap) { return ALIGN + AS_DEL3_SPH * sizeof(double) * cap; }

static size_t tblock_bytes(size_t cap) { return cap ? ALIGN + cap * TBYTES : 0; }

/* Reallocate the tet arrays to capacity cap >= nt. 0 or -1 (nothing changed). */
static int set_tet_cap(as_del3 *d, size_t cap) {
    if (cap > (SIZE_MAX - ALIGN) / TBYTES) return -1;
    char *blk = as_alloc(d->ctx, tblock_bytes(cap));
    if (!blk) return -1;
    double *sph = NULL;
    void *sblk = NULL;
    if (cap <= SPH_MAX_TETS && d->sphere_cache && !d->no_sphere_cache &&
        (d->sph || d->nt == 0)) { /* once dropped, never back (shrink) */
        sblk = as_alloc(d->ctx, sph_bytes(cap));
        if (!sblk) {
            as_free(d->ctx, blk, tblock_bytes(cap));
            return -1;
        }
        sph = (double *)align_up(sblk);
    }
    int32_t *tet = (int32_t *)align_up(blk);
    uint8_t *mark = (uint8_t *)(tet + 8 * cap);
    size_t n = (size_t)d->nt;
    if (n) {
        memcpy(tet, d->tet, 8 * n * sizeof *tet);
        memcpy(mark, d->mark, n * sizeof *mark);
        if (sph) {
            if (d->sph) {
                memcpy(sph, d->sph, AS_DEL3_SPH * n * sizeof *sph);
            } else {
                for (size_t t = 0; t < n; t++) sph[AS_DEL3_SPH * t + 4] = SPH_NONE;
            }
        }
    }
    as_free(d->ctx, d->tblk, tblock_bytes(d->cap_t));
    if (d->sph) as_free(d->ctx, d->sblk, sph_bytes(d->cap_t));
    d->tblk = blk;
    d->sblk = sblk;
    d->tet = tet;
    d->mark = mark;
    d->sph = sph;
    d->cap_t = cap;
    return 0;
}

static int grow_tets(as_del3 *d, size_t need) {
    if (need <= d->cap_t) return 0;
    if (need > MAX_TETS) return -1;
    size_t cap = grown_cap(d, d->cap_t, need);
    if (cap > MAX_TETS) cap = MAX_TETS;
    return set_tet_cap(d, cap);
}

int as_del3_shrink(as_del3 *d) {
    size_t ct = d->nt > 0 ? (size_t)d->nt : 1, cv = d->nv > 0 ? (size_t)d->nv : 1;
    if (ct < d->cap_t && set_tet_cap(d, ct)) return -1;
    if (cv < d->cap_v && set_vertex_cap(d, cv)) return -1;
    return 0;
}

/* A fresh slot for a tet (capacity reserved): the free list first (LIFO), else the end. */
static int32_t alloc_tet(as_del3 *d) {
    int32_t t;
    if (d->free_head >= 0) {
        t = d->free_head;
        d->free_head = d->tet[8 * (size_t)t + 1];
    } else {
        t = d->nt++;
    }
    d->mark[t] = MARK_NONE;
    if (d->sph) d->sph[AS_DEL3_SPH * (size_t)t + 4] = SPH_NONE; /* no cached sphere yet */
    d->nlive++;
    return t;
}

/* ---- lifetime ------------------------------------------------------------------------------ */

static void clear_tets(as_del3 *d) {
    d->nt = 0;
    d->nlive = 0;
    d->free_head = -1;
    d->dim3 = 0;
    d->hint = -1;
    d->nconf = 0;
    d->nbf = 0;
}

void as_del3_init(as_del3 *d, anistar_context *ctx) {
    memset(d, 0, sizeof *d);
    d->ctx = ctx;
    d->boot[0] = d->boot[1] = d->boot[2] = -1;
    d->seed = 0;
    d->rng = mix64(0) | 1u;
    clear_tets(d);
}

void as_del3_destroy(as_del3 *d) {
    anistar_context *ctx = d->ctx;
    if (d->cap_v) as_free(ctx, d->vblk, vblock_bytes(d->cap_v));
    as_free(ctx, d->ltab, AS_DEL3_LMAX * AS_DEL3_LMAX * sizeof *d->ltab);
    if (d->sph) as_free(ctx, d->sblk, sph_bytes(d->cap_t));
    as_free(ctx, d->tblk, tblock_bytes(d->cap_t));
    as_free(ctx, d->phash, d->cap_phash * sizeof *d->phash);
    as_free(ctx, d->stack, d->cap_stack * sizeof *d->stack);
    as_free(ctx, d->conf, d->cap_conf * sizeof *d->conf);
    as_free(ctx, d->crec, d->cap_crec * sizeof *d->crec);
    as_free(ctx, d->gl, d->cap_gl * sizeof *d->gl);
    as_free(ctx, d->bf, d->cap_bf * sizeof *d->bf);
    as_free(ctx, d->etab, d->cap_etab * sizeof *d->etab);
    as_free(ctx, d->etouch, d->cap_etouch * sizeof *d->etouch);
    as_del3_buf_free(ctx, &d->removed);
    as_del3_buf_free(ctx, &d->created);
    as_del3_init(d, ctx);
}

static void phash_clear(as_del3 *d) {
    for (size_t i = 0; i < d->cap_phash; i++) d->phash[i] = -1;
}

void as_del3_reset(as_del3 *d) {
    d->nv = 0;
    clear_tets(d);
    d->boot[0] = d->boot[1] = d->boot[2] = -1;
    phash_clear(d);
    d->rng = mix64(d->seed) | 1u;
    d->removed.n = d->created.n = 0;
    d->rebuilt = 0;
    memset(&d->stats, 0, sizeof d->stats);
}

void as_del3_set_seed(as_del3 *d, uint64_t seed) {
    d->seed = seed;
    d->rng = mix64(seed) | 1u;
}

anistar_status as_del3_reserve(as_del3 *d, int32_t nv, int32_t nt) {
    if (nv < 0 || nt < 0) return as_fail(d->ctx, ANISTAR_EINVAL, "del3: negative reserve");
    if (grow_vertices(d, (size_t)nv) || grow_tets(d, (size_t)nt))
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory reserving %d vertices, %d tets",
                       (int)nv, (int)nt);
    return ANISTAR_OK;
}

void as_del3_count(const as_del3 *d, int32_t *finite_tets, int32_t *infinite_tets) {
    int32_t nf = 0, ni = 0;
    for (int32_t t = 0; t < d->nt; t++) {
        const int32_t *r = rec(d, t);
        if (r[0] == AS_DEL3_DEAD) continue;
        if (is_inf(r))
            ni++;
        else
            nf++;
    }
    if (finite_tets) *finite_tets = nf;
    if (infinite_tets) *infinite_tets = ni;
}

/* ---- predicates on tets --------------------------------------------------------------------- */

static inline int inf_slot(const int32_t *tv) {
    return tv[0] == AS_DEL3_INF ? 0 : tv[1] == AS_DEL3_INF ? 1 : tv[2] == AS_DEL3_INF ? 2 : 3;
}

/* The exact predicate on finite tet r (out of line: rare). */
static DEL3_NOINLINE int sphere_exact(const as_del3 *d, const int32_t *r, const double *p,
                                      int64_t g) {
    return as_insphere_sos(pt(d, r[0]), pt(d, r[1]), pt(d, r[2]), pt(d, r[3]), p, d->gid[r[0]],
                           d->gid[r[1]], d->gid[r[2]], d->gid[r[3]], g);
}

/* insphere_sos(finite tet r, p): the filter, then predicates.c. */
DEL3_INLINE int tet_insphere(const as_del3 *d, const int32_t *r, const double *p, int64_t g) {
    int s = isp_filter(pt(d, r[0]), pt(d, r[1]), pt(d, r[2]), pt(d, r[3]), p);
    if (s) return s;
    return sphere_exact(d, r, p, g);
}

/* The infinite-tet case of in_conflict (rare in the hot loop: kept out of line). */
static DEL3_NOINLINE int conflict_infinite(const as_del3 *d, const int32_t *r, const double *p,
                                           int64_t g) {
    int k = inf_slot(r);
    const double *q[4];
    for (int i = 0; i < 4; i++) q[i] = i == k ? p : pt(d, r[i]);
    double o = orient(q[0], q[1], q[2], q[3]);
    if (o > 0) return 1;
    if (o < 0) return 0;
    return tet_insphere(d, rec(d, r[4 + k] >> 3), p, g) > 0;
}

/* Is live tet t in conflict with p (global id g)? The rule at the top of this file.
 * Used by the validator: no cache (only the static filter and predicates.c). */
static int in_conflict(const as_del3 *d, int32_t t, const double *p, int64_t g) {
    const int32_t *r = rec(d, t);
    if (is_inf(r)) return conflict_infinite(d, r, p, g);
    return tet_insphere(d, r, p, g) > 0;
}

/* The exact predicate after the filters failed, counted. */
static DEL3_NOINLINE int conflict_exact(as_del3 *d, int32_t t, const double *p, int64_t g) {
    d->stats.sphere_exact++;
    return sphere_exact(d, rec(d, t), p, g) > 0;
}

/* in_conflict for a tet without a cached sphere in a triangulation with the cache: an
 * infinite tet, or a finite one not tested yet (its sphere is computed and stored). */
static DEL3_NOINLINE int conflict_nocache(as_del3 *d, int32_t t, const double *p, int64_t g) {
    const int32_t *r = rec(d, t);
    if (is_inf(r)) return conflict_infinite(d, r, p, g);
    double *c = d->sph + AS_DEL3_SPH * (size_t)t;
    sphere_compute(pt(d, r[0]), pt(d, r[1]), pt(d, r[2]), pt(d, r[3]), c);
    int s = sphere_test(c, p);
    if (s) return s > 0;
    return conflict_exact(d, t, p, g);
}

/* conflict_infinite for infinite tet r, the common case inline: (k, f0, f1, f2) (k the
 * infinite slot, f = face_vtx[k]) is an even permutation, so with A, B, C the points of
 * the hull face, orient3d(r's points with p in slot k) = orient3d(p, A, B, C) =
 * -orient3d(A, B, C, p): the filter's sign of the latter decides, else (filter undecided)
 * conflict_infinite decides exactly, as before. */
DEL3_INLINE int conflict_infinite_fast(const as_del3 *d, const int32_t *r, const double *p,
                                       int64_t g) {
    const int8_t *fv = face_vtx[inf_slot(r)];
    double o = as_orient3d_filter(pt(d, r[fv[0]]), pt(d, r[fv[1]]), pt(d, r[fv[2]]), p);
    if (o != 0) return o < 0;
    return conflict_infinite(d, r, p, g);
}

/* in_conflict through the sphere cache of t (which reads nothing but t's sphere), or the
 * inline filter when there is no cache. The insertion path. */
DEL3_INLINE int in_conflict_fast(as_del3 *d, const double *sph, int32_t t, const double *p,
                                 int64_t g) {
    int s;
    if (sph) {
        const double *c = sph + AS_DEL3_SPH * (size_t)t;
        if (AS_UNLIKELY(c[4] < 0)) return conflict_nocache(d, t, p, g);
        s = sphere_test(c, p);
    } else { /* big, or no cache wanted */
        const int32_t *r = rec(d, t);
        if (is_inf(r)) return conflict_infinite_fast(d, r, p, g);
        s = isp_filter(pt(d, r[0]), pt(d, r[1]), pt(d, r[2]), pt(d, r[3]), p);
    }
    if (AS_LIKELY(s != 0)) return s > 0;
    return conflict_exact(d, t, p, g);
}

/* ---- walk and conflict zone ------------------------------------------------------------------ */

static int32_t start_tet(const as_del3 *d, int32_t hint) {
    if (as_del3_is_live(d, hint)) return hint;
    if (as_del3_is_live(d, d->hint)) return d->hint;
    for (int32_t t = d->nt - 1; t >= 0; t--)
        if (d->tet[8 * (size_t)t] != AS_DEL3_DEAD) return t;
    return -1;
}

/*
 * Remembering stochastic walk from live tet t toward p.
 * Returns a finite tet whose closure contains p, or an infinite tet whose hull face p
 * strictly sees.
 * design: in tet t, test the faces in a random cyclic order (d->rng), skipping the face
 * we came through; cross the first face that has p strictly on its other side. The
 * triangulation is regular, so the walk cannot cycle (any choice among the faces p sees
 * terminates: the in-front relation of a regular triangulation is acyclic); the random
 * order shortens it. Big triangulations (> DEL3_PREFETCH_MIN slots) test every face
 * and cross the one p is farthest beyond (squared distance to its plane, rounded: only the
 * choice, not the orientation signs, uses it): on surface samples, where the tets near
 * the surface are thin, the random walk took 33 steps per point (10^6 torus points) and
 * this one 15 (the run 17% faster); on uniform points 5.2 and 4.4 steps (time unchanged).
 * Small triangulations keep the random walk: for a point on a face, or outside the hull,
 * the tet it ends in depends on the walk, and the mesher's results depend (at the
 * rounding level) on the tet numbering that follows. (Sharing the vertices' differences
 * to p among a tet's face tests was tried: more instructions and branch misses.)
 */
static int32_t walk(as_del3 *d, const double *p, int32_t t) {
    const int32_t *r = rec(d, t);
    if (is_inf(r)) t = r[4 + inf_slot(r)] >> 3;
    int32_t prev = -1;
    uint64_t steps = 0, rng = d->rng;
    const int pf = d->nt > DEL3_PREFETCH_MIN;
    const int greedy = pf; /* big triangulations (see the comment above) */
    for (;;) {
        r = rec(d, t);
        if (pf)
            for (int i = 0; i < 4; i++) DEL3_PREFETCH(d->tet + (r[4 + i] & ~7));
        const double *q[4] = {pt(d, r[0]), pt(d, r[1]), pt(d, r[2]), pt(d, r[3])};
        rng ^= rng << 13;
        rng ^= rng >> 7;
        rng ^= rng << 17;
        unsigned k0 = (unsigned)(rng >> 40);
        int32_t to = -1;
        if (greedy) { /* cross the face p is farthest beyond */
            double best = -1;
            for (unsigned i = 0; i < 4; i++) {
                int32_t n = r[4 + i] >> 3;
                if (n == prev) continue;
                const double *save = q[i];
                q[i] = p;
                double o = orient(q[0], q[1], q[2], q[3]);
                q[i] = save;
                if (o < 0) {
                    const double *f0 = q[face_vtx[i][0]], *f1 = q[face_vtx[i][1]];
                    const double *f2 = q[face_vtx[i][2]];
                    double u0 = f1[0] - f0[0], u1 = f1[1] - f0[1], u2 = f1[2] - f0[2];
                    double v0 = f2[0] - f0[0], v1 = f2[1] - f0[1], v2 = f2[2] - f0[2];
                    double n0 = u1 * v2 - u2 * v1, n1 = u2 * v0 - u0 * v2, n2 = u0 * v1 - u1 * v0;
                    double dist = o * o / ((n0 * n0 + n1 * n1) + n2 * n2);
                    if (dist > best) {
                        best = dist;
                        to = n;
                    }
                }
            }
        } else {
            for (unsigned k = 0; k < 4; k++) {
                unsigned i = (k0 + k) & 3u;
                int32_t n = r[4 + i] >> 3;
                if (n == prev) continue;
                const double *save = q[i];
                q[i] = p;
                double o = orient(q[0], q[1], q[2], q[3]);
                q[i] = save;
                if (o < 0) {
                    to = n;
                    break;
                }
            }
        }
        if (to < 0) break;
        prev = t;
        t = to;
        steps++;
        if (is_inf(rec(d, t))) break;
    }
    d->rng = rng;
    d->stats.walk_steps += steps;
    return t;
}

/* Unmark everything the last search marked. */
static void clear_marks(as_del3 *d) {
    for (size_t k = 0; k < d->nconf; k++) d->mark[d->conf[k]] = MARK_NONE;
    for (size_t k = 0; k < d->nbf; k++) d->mark[d->crec[d->bf[k] + 4] >> 3] = MARK_NONE;
    d->nconf = 0;
    d->nbf = 0;
}

static int reserve_i32(anistar_context *ctx, int32_t **a, size_t *cap, size_t need) {
    void *p = *a;
    if (as_grow(ctx, &p, cap, need, sizeof **a)) return -1;
    *a = p;
    return 0;
}

/* Room in the search scratch for nconf + 4 conflict tets, and the invariant the search
 * relies on to check cap_conf only: the stack holds at most cap_conf entries (it never
 * holds more than the conflict tets found), the record copies 8 cap_conf, the boundary
 * faces 3 cap_conf + 8 (each popped tet adds at most 3, the first 4: nbf <= 3 nconf + 1).
 * 0 or -1 (then the invariant may not hold: the next search restores it first). */
static int reserve_search(as_del3 *d, size_t nconf, size_t nbf) {
    size_t need = nconf + 4 > 64 ? nconf + 4 : 64;
    if (need > d->cap_conf && reserve_i32(d->ctx, &d->conf, &d->cap_conf, need)) return -1;
    size_t c = d->cap_conf, nb = 3 * c + 8 > nbf + 4 ? 3 * c + 8 : nbf + 4;
    if ((c > d->cap_stack && reserve_i32(d->ctx, &d->stack, &d->cap_stack, c)) ||
        (8 * c > d->cap_crec && reserve_i32(d->ctx, &d->crec, &d->cap_crec, 8 * c)) ||
        (nb > d->cap_bf && reserve_i32(d->ctx, &d->bf, &d->cap_bf, nb)))
        return -1;
    return 0;
}

/*
 * Locate p (global id g) and collect its conflict zone: the conflict tets in d->conf[0 ..
 * nconf) (discovery order, marked MARK_CONF) with a copy of each one's record in
 * d->crec[8k .. 8k+7], and the cavity boundary faces d->bf[0..nbf), each as b = 8k + i:
 * face i of conflict tet k (crec[b + 4] is the outside face); the outside neighbours are
 * marked MARK_OUT.
 * Returns ANISTAR_OK (marks set: the caller applies the cavity or calls clear_marks),
 * AS_DEL3_DUPLICATE (*dupv; nothing marked) or ANISTAR_ENOMEM (nothing marked).
 * design: walk from the hint; the tet found is in conflict without a test (see the top of
 * the file); grow the zone by adjacency with an explicit stack (depth first, faces in
 * order 0..3), testing each unvisited neighbour once; a face toward a non-conflict tet
 * is a boundary face. The order fixes the slots the new tets get (cavity_apply): keep it.
 * Per tet, the unvisited neighbours are tested in a loop over the set bits of a mask (one
 * hard-to-predict branch per tet rather than one per face), then the outcomes are
 * recorded in face order without branches (slots written always, kept by advancing the
 * counts): which neighbour is new, in conflict or a boundary are coin flips.
 */
static int search(as_del3 *d, const double *p, int64_t g, int32_t hint, int32_t *dupv) {
    int32_t t = walk(d, p, start_tet(d, hint));
    const int32_t *r = rec(d, t);
    if (!is_inf(r)) {
        for (int i = 0; i < 4; i++)
            if (same_point(pt(d, r[i]), p)) {
                *dupv = r[i];
                return AS_DEL3_DUPLICATE;
            }
    }
    if (reserve_search(d, 0, 0))
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (conflict zone)");
    uint8_t *restrict mark = d->mark;
    int32_t *restrict stack = d->stack, *restrict conf = d->conf, *restrict crec = d->crec;
    int32_t *restrict bf = d->bf;
    const double *sph = d->sph;
    size_t sp = 0, nconf = 0, nbf = 0;
    uint64_t ntests = 0;
    mark[t] = MARK_CONF;
    conf[nconf++] = t;
    stack[sp++] = 0;
    const int pf = d->nt > DEL3_PREFETCH_MIN;
    while (sp > 0) {
        int32_t k = stack[--sp];
        /* the stack and record copies follow cap_conf (reserve_search); nbf is checked too
         * (its bound through cap_conf is an argument, memory safety should not rest on it) */
        if (AS_UNLIKELY(nconf + 4 > d->cap_conf || nbf + 4 > d->cap_bf)) {
            d->nconf = nconf;
            d->nbf = nbf;
            if (reserve_search(d, nconf, nbf)) {
                clear_marks(d);
                return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (conflict zone)");
            }
            stack = d->stack;
            conf = d->conf;
            crec = d->crec;
            bf = d->bf;
        }
        int32_t *cr = crec + 8 * (size_t)k;
        memcpy(cr, rec(d, conf[k]), 8 * sizeof *cr);
        if (pf) /* the neighbours' records are usually cold: overlap their loads */
            for (int i = 0; i < 4; i++) DEL3_PREFETCH(d->tet + (cr[4 + i] & ~7));
        int32_t n[4];
        for (int i = 0; i < 4; i++) n[i] = cr[4 + i] >> 3;
        /* the four marks (2 bits each) -> which neighbours are new, which are out */
        unsigned mk = (unsigned)mark[n[0]] | (unsigned)mark[n[1]] << 2 |
                      (unsigned)mark[n[2]] << 4 | (unsigned)mark[n[3]] << 6;
        unsigned todo = mark_todo[mk], out = mark_out[mk];
        unsigned hit = 0, miss = todo;
        ntests += (unsigned)bit_count[todo];
        while (todo) {
            int i = low_bit[todo];
            todo &= todo - 1;
            unsigned c = (unsigned)in_conflict_fast(d, sph, n[i], p, g);
            mark[n[i]] = (uint8_t)(MARK_OUT - c); /* MARK_CONF or MARK_OUT */
            hit |= c << i;
        }
        out |= miss & ~hit; /* boundary faces: toward tets already out or found out now */
        for (int i = 0; i < 4; i++) {
            unsigned isc = (hit >> i) & 1u;
            stack[sp] = (int32_t)nconf;
            sp += isc;
            conf[nconf] = n[i];
            nconf += isc;
            bf[nbf] = 8 * k + i;
            nbf += (out >> i) & 1u;
        }
    }
    d->nconf = nconf;
    d->nbf = nbf;
    d->stats.sphere_tests += ntests;
    return ANISTAR_OK;
}

/* ---- cavity --------------------------------------------------------------------------------- */

static inline uint32_t edge_hash(int32_t x, int32_t y) {
    uint32_t h = (uint32_t)x * 0x9e3779b1u ^ ((uint32_t)y * 0x85ebca77u);
    return h ^ (h >> 15);
}

/* Make room for applying the cavity of the last search. 0 or -1 (nothing changed). */
static int reserve_cavity(as_del3 *d) {
    size_t nb = d->nbf;
    if ((size_t)d->nt + nb > MAX_TETS) return -1;
    if (grow_tets(d, (size_t)d->nt + nb)) return -1;
    if (buf_reserve(d->ctx, &d->removed, d->nconf) || buf_reserve(d->ctx, &d->created, nb))
        return -1;
    /* a boundary sphere of nb triangles has nb/2 + 2 vertices: the hash is needed only
     * when that exceeds the direct table */
    if (nb / 2 + 2 > AS_DEL3_LMAX) {
        size_t esz = 512;
        while (esz < 3 * nb) esz *= 2;
        if (esz > d->cap_etab) {
            as_del3_edge *e = as_alloc_array(d->ctx, esz, sizeof *e);
            if (!e) return -1;
            for (size_t i = 0; i < esz; i++) e[i].a = EDGE_EMPTY;
            as_free(d->ctx, d->etab, d->cap_etab * sizeof *d->etab);
            d->etab = e;
            d->cap_etab = esz;
        }
        if (2 * nb > d->cap_etouch &&
            reserve_i32(d->ctx, &d->etouch, &d->cap_etouch, 2 * nb))
            return -1;
    }
    if (6 * nb > d->cap_gl && reserve_i32(d->ctx, &d->gl, &d->cap_gl, 6 * nb)) return -1;
    if (!d->ltab) {
        d->ltab = as_alloc_array(d->ctx, AS_DEL3_LMAX * AS_DEL3_LMAX, sizeof *d->ltab);
        if (!d->ltab) return -1;
        memset(d->ltab, 0, AS_DEL3_LMAX * AS_DEL3_LMAX * sizeof *d->ltab);
    }
    return 0;
}

/* Glue the new tets of a cavity with more than AS_DEL3_LMAX boundary vertices through the
 * edge hash (rare: huge cavities of the first insertions or of degenerate inputs). Face j
 * (j != s) of a new tet holds the new point and the edge (x, y) of the boundary triangle
 * face_vtx[s] that does not hold vertex j, oriented along the triangle; its partner holds
 * (y, x). */
static DEL3_NOINLINE void glue_hashed(as_del3 *d, size_t nb) {
    int32_t *restrict T = d->tet;
    const int32_t *restrict created = d->created.a;
    const int32_t *restrict bf = d->bf;
    int32_t *restrict etouch = d->etouch;
    size_t ntouch = 0;
    d->stats.big_cavities++;
    uint32_t mask = (uint32_t)d->cap_etab - 1;
    as_del3_edge *restrict et = d->etab;
    for (size_t k = 0; k < nb; k++) {
        int32_t n = created[k];
        const int8_t *fv = face_vtx[bf[k] & 7];
        const int32_t *tv = T + 8 * (size_t)n;
        for (int a = 0; a < 3; a++) {
            int j = fv[a];
            int32_t x = tv[fv[(a + 1) % 3]], y = tv[fv[(a + 2) % 3]];
            int32_t f = 8 * n + j;
            /* The partner stored (y, x) under the hash of (y, x). */
            uint32_t h = edge_hash(y, x) & mask;
            for (;;) {
                as_del3_edge *e = &et[h];
                if (e->a == EDGE_EMPTY) break;
                if (e->a == y && e->b == x) {
                    int32_t link = e->link;
                    T[f + 4] = link;
                    T[link + 4] = f;
                    e->a = EDGE_USED;
                    goto glued;
                }
                h = (h + 1) & mask;
            }
            h = edge_hash(x, y) & mask;
            while (et[h].a != EDGE_EMPTY) h = (h + 1) & mask;
            et[h].a = x;
            et[h].b = y;
            et[h].link = f;
            etouch[ntouch++] = (int32_t)h;
        glued:;
        }
    }
    for (size_t k = 0; k < ntouch; k++) et[etouch[k]].a = EDGE_EMPTY;
    for (size_t k = 0; k < nb; k++) { /* the incident tet of the boundary vertices */
        const int32_t *tv = T + 8 * (size_t)created[k];
        for (int i = 0; i < 4; i++)
            if (tv[i] >= 0) d->vert[tv[i]].tet = created[k];
    }
}

/* The cavity-local number of vertex v (a new one, m, if it has none yet); records v, and
 * new tet n as v's incident tet. Branch-free (whether v is new is a coin flip): lverts[m]
 * is written always and kept only for a new vertex (lverts has a spare entry); m never
 * exceeds M (it cannot for a sphere boundary; the clamp keeps memory safe regardless). */
DEL3_INLINE int32_t number_vertex(as_del3_vertex *restrict vert, int32_t *restrict lverts,
                                  int32_t *m, int32_t M, int32_t v, int32_t n) {
    int32_t lv = vert[v].loc, mm = *m;
    int fresh = lv < 0;
    lv = fresh ? mm : lv;
    vert[v].loc = lv;
    vert[v].tet = n;
    lverts[mm] = v;
    *m = mm + (fresh & (mm < M));
    return lv;
}

/* Gluing the new tets to each other, in two passes. Pass 1 registers each face f through
 * the new point under its oriented boundary edge x -> y (lt[reg] = f, reg the table entry
 * of (x, y)) and keeps (f, look), look the entry of (y, x); pass 2 reads the partner's
 * registration: the adjacency of f is lt[look]. The boundary is a triangulated sphere, so
 * every edge is registered once in each direction: pass 2 reads only entries written by
 * this cavity's pass 1 (the table is never cleared), and there is no branch at all. */
DEL3_INLINE void glue_register(int32_t *restrict lt, int32_t *restrict gl, int32_t f,
                               int32_t reg, int32_t look) {
    lt[reg] = f;
    gl[0] = f;
    gl[1] = look;
}

static void glue_links(int32_t *restrict T, const int32_t *restrict lt,
                       const int32_t *restrict gl, size_t nface) {
    for (size_t j = 0; j < nface; j++) T[gl[2 * j] + 4] = lt[gl[2 * j + 1]];
}

/* The start of applying a cavity: record the removed tets (the conflict tets, last found
 * first); the conflict slots no new tet takes (the nconf - nbf last found, when there are
 * more conflict tets than boundary faces) go to the free list. */
static void cavity_release(as_del3 *d) {
    int32_t *restrict T = d->tet;
    const int32_t *restrict conf = d->conf;
    int32_t *restrict removed = d->removed.a;
    const size_t nc = d->nconf, nb = d->nbf;
    int32_t free_head = d->free_head;
    for (size_t k = 0; k < nc; k++) removed[k] = conf[nc - 1 - k];
    for (size_t k = nc; k-- > nb;) {
        int32_t t = conf[k];
        T[8 * (size_t)t] = AS_DEL3_DEAD;
        T[8 * (size_t)t + 1] = free_head;
        d->mark[t] = MARK_NONE;
        free_head = t;
    }
    d->free_head = free_head;
    d->removed.n = nc;
}

/* The slot of the k-th new tet: the slot of the k-th conflict tet found, then the free
 * list, then a new slot. */
DEL3_INLINE int32_t cavity_slot(int32_t *restrict T, const int32_t *restrict conf, size_t nc,
                                size_t k, int32_t *free_head, int32_t *nt) {
    if (k < nc) return conf[k];
    int32_t n = *free_head;
    if (n >= 0) {
        *free_head = T[8 * (size_t)n + 1];
        return n;
    }
    return (*nt)++;
}

/* Write new tet n from boundary face b = 8k + i (conflict tet k's record copy r = crec +
 * 8k: r's vertices with the new point newv at slot i) and glue it to the outside face
 * r[4 + i]; with the sphere cache, compute its sphere (relative to the new point: see
 * sphere_compute). Returns the record of n. */
DEL3_INLINE const int32_t *cavity_tet(const as_del3 *d, int32_t *restrict T,
                                      uint8_t *restrict mark, double *restrict sph,
                                      const int32_t *restrict crec, int32_t b, int32_t n,
                                      int32_t newv) {
    const int32_t *r = crec + 8 * (size_t)(b >> 3);
    const int i = b & 7;
    mark[n] = MARK_NONE;
    int32_t *tv = T + 8 * (size_t)n;
    memcpy(tv, r, 4 * sizeof *tv);
    tv[i] = newv;
    const int32_t out = r[4 + i];
    tv[4 + i] = out;
    T[out + 4] = 8 * n + i;
    mark[out >> 3] = MARK_NONE;
    if (sph) {
        double *c = sph + AS_DEL3_SPH * (size_t)n;
        if (is_inf(tv)) {
            c[4] = SPH_INF;
        } else {
            const int8_t *fv = face_vtx[i];
            sphere_compute(pt(d, newv), pt(d, tv[fv[0]]), pt(d, tv[fv[1]]), pt(d, tv[fv[2]]),
                           c);
        }
    }
    return tv;
}

/* The end of applying a cavity: counts, hint, statistics. */
static void cavity_finish(as_del3 *d, int32_t newv, int32_t free_head, int32_t nt) {
    size_t nc = d->nconf, nb = d->nbf;
    d->free_head = free_head;
    d->nt = nt;
    d->nlive += (int32_t)nb - (int32_t)nc;
    d->created.n = nb;
    d->vert[newv].tet = d->created.a[0];
    d->hint = d->created.a[0];
    d->nbf = 0;
    d->nconf = 0;
    d->rebuilt = 0;
    d->stats.conflict_tets += nc;
    d->stats.created_tets += nb;
}

/*
 * Replace the conflict zone of the last search by the cone of its boundary faces to the
 * new point. Cannot fail (reserve_cavity came first).
 * design: one new tet per boundary face (the old tet with the new point in the boundary
 * face's opposite slot: orientation inherited), glued to the outside; the k-th new tet
 * takes the slot of the k-th conflict tet found (then the free list, then new slots), so
 * the slots of the new tets follow the search order. The new tets are glued to each
 * other through a table keyed on the oriented boundary edge that each face through the
 * new point holds (the partner face holds the reversed edge): the boundary triangle
 * (x0, x1, x2) of a new tet is its face s listed by face_vtx[s] (seen from the new point,
 * all boundary triangles turn the same way), and its face opposite x_a holds the edge
 * x_{a+1} -> x_{a+2}. The boundary is a triangulated sphere with nb triangles, so it has
 * exactly M = nb/2 + 2 vertices (Euler): when M <= AS_DEL3_LMAX they are numbered 0 .. M-1
 * on the fly (vert[].loc) and an edge (x, y) is the entry AS_DEL3_LMAX x + y of a direct
 * table, all in one pass without data-dependent branches; bigger cavities go through the
 * hash (glue_hashed). Star-sized triangulations skip the numbering: cavity_small.
 * Each boundary vertex's incident tet becomes the last new tet holding it.
 */
static void cavity_big(as_del3 *d, int32_t newv) {
    int32_t *restrict T = d->tet;
    uint8_t *restrict mark = d->mark;
    double *restrict sph = d->sph;
    as_del3_vertex *restrict vert = d->vert;
    int32_t *restrict created = d->created.a;
    const int32_t *restrict conf = d->conf, *restrict crec = d->crec;
    const int32_t *restrict bf = d->bf;
    const size_t nc = d->nconf, nb = d->nbf;
    cavity_release(d);
    int32_t free_head = d->free_head, nt = d->nt;
    const int32_t M = (int32_t)(nb / 2 + 2);
    const int small = M <= AS_DEL3_LMAX;
    int32_t *restrict lt = d->ltab, *restrict lverts = d->lverts, *restrict gl = d->gl;
    int32_t m = 0;
    for (size_t k = 0; k < nb; k++) {
        int32_t n = cavity_slot(T, conf, nc, k, &free_head, &nt);
        const int32_t *tv = cavity_tet(d, T, mark, sph, crec, bf[k], n, newv);
        created[k] = n;
        if (!small) continue;
        const int8_t *fv = face_vtx[bf[k] & 7];
        int32_t l0 = number_vertex(vert, lverts, &m, M, tv[fv[0]], n);
        int32_t l1 = number_vertex(vert, lverts, &m, M, tv[fv[1]], n);
        int32_t l2 = number_vertex(vert, lverts, &m, M, tv[fv[2]], n);
        int32_t r0 = l0 * AS_DEL3_LMAX, r1 = l1 * AS_DEL3_LMAX, r2 = l2 * AS_DEL3_LMAX;
        int32_t f = 8 * n;
        glue_register(lt, gl + 6 * k, f + fv[0], r1 + l2, r2 + l1);
        glue_register(lt, gl + 6 * k + 2, f + fv[1], r2 + l0, r0 + l2);
        glue_register(lt, gl + 6 * k + 4, f + fv[2], r0 + l1, r1 + l0);
    }
    if (small) {
        glue_links(T, lt, gl, 3 * nb);
        for (int32_t i = 0; i < m; i++) vert[lverts[i]].loc = -1;
    } else {
        glue_hashed(d, nb);
    }
    cavity_finish(d, newv, free_head, nt);
}

/* cavity_big for triangulations of fewer than AS_DEL3_LMAX vertices (stars): the edge
 * (x, y) is the entry 2^sh (x + 1) + (y + 1) of the direct table (the infinite vertex is
 * -1; 2^sh >= nv + 1), no numbering needed. */
static void cavity_small(as_del3 *d, int32_t newv) {
    int32_t *restrict T = d->tet;
    uint8_t *restrict mark = d->mark;
    double *restrict sph = d->sph;
    as_del3_vertex *restrict vert = d->vert;
    int32_t *restrict created = d->created.a;
    const int32_t *restrict conf = d->conf, *restrict crec = d->crec;
    const int32_t *restrict bf = d->bf;
    const size_t nc = d->nconf, nb = d->nbf;
    cavity_release(d);
    int32_t free_head = d->free_head, nt = d->nt;
    /* row stride 2^sh >= nv + 1: the table part in use stays small (L1) */
    int sh = 1;
    while ((1 << sh) < d->nv + 1) sh++;
    int32_t *restrict lt = d->ltab + (1 << sh) + 1; /* lt[x 2^sh + y], x, y >= -1 */
    int32_t *restrict gl = d->gl;
    for (size_t k = 0; k < nb; k++) {
        int32_t n = cavity_slot(T, conf, nc, k, &free_head, &nt);
        const int32_t *tv = cavity_tet(d, T, mark, sph, crec, bf[k], n, newv);
        created[k] = n;
        const int8_t *fv = face_vtx[bf[k] & 7];
        int32_t x0 = tv[fv[0]], x1 = tv[fv[1]], x2 = tv[fv[2]];
        vert[x0].tet = n;
        vert[x1].tet = n;
        vert[x2].tet = n;
        int32_t r0 = x0 * (1 << sh), r1 = x1 * (1 << sh), r2 = x2 * (1 << sh);
        int32_t f = 8 * n;
        glue_register(lt, gl + 6 * k, f + fv[0], r1 + x2, r2 + x1);
        glue_register(lt, gl + 6 * k + 2, f + fv[1], r2 + x0, r0 + x2);
        glue_register(lt, gl + 6 * k + 4, f + fv[2], r0 + x1, r1 + x0);
    }
    glue_links(T, lt, gl, 3 * nb);
    cavity_finish(d, newv, free_head, nt);
}

static void cavity_apply(as_del3 *d, int32_t newv) {
    if (d->nv < AS_DEL3_LMAX && d->nbf / 2 + 2 <= AS_DEL3_LMAX)
        cavity_small(d, newv);
    else
        cavity_big(d, newv);
}

/* Insert the point p (global id g) as vertex newv: newv == d->nv for a new vertex (stored
 * here once nothing can fail; vertex capacity must be reserved), or an already stored
 * pending vertex. Returns ANISTAR_OK, AS_DEL3_DUPLICATE (*dupv) or ANISTAR_ENOMEM; on any
 * failure the triangulation is unchanged. */
static int insert_at(as_del3 *d, const double *p, int64_t g, int32_t newv, int32_t *dupv) {
    int r = search(d, p, g, -1, dupv);
    if (r != ANISTAR_OK) return r;
    if (reserve_cavity(d)) {
        clear_marks(d);
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (cavity of %zu faces)",
                       d->nbf);
    }
    if (newv == d->nv) {
        store_vertex(d, newv, p, g);
        d->nv++;
    }
    cavity_apply(d, newv);
    d->stats.inserted++;
    return ANISTAR_OK;
}
/* ---- the pending phase (fewer than 4 affinely independent points) ------------------------ */

static uint32_t point_hash(const double *p) {
    uint64_t h = 0;
    for (int i = 0; i < 3; i++) {
        double x = p[i] + 0.0; /* -0 -> +0: equal points hash equally */
        uint64_t u;
        memcpy(&u, &x, sizeof u);
        h = mix64(h ^ u);
    }
    return (uint32_t)(h >> 32);
}

static void phash_add(as_del3 *d, int32_t v) {
    size_t mask = d->cap_phash - 1, h = point_hash(pt(d, v)) & mask;
    while (d->phash[h] >= 0) h = (h + 1) & mask;
    d->phash[h] = v;
}

static int32_t phash_find(const as_del3 *d, const double *p) {
    if (d->cap_phash == 0) return -1;
    size_t mask = d->cap_phash - 1, h = point_hash(p) & mask;
    for (; d->phash[h] >= 0; h = (h + 1) & mask)
        if (same_point(pt(d, d->phash[h]), p)) return d->phash[h];
    return -1;
}

/* Room for n pending vertices (load <= 1/2). */
static int phash_reserve(as_del3 *d, size_t n) {
    if (2 * n <= d->cap_phash) return 0;
    size_t cap = 16;
    while (cap < 2 * n) cap *= 2;
    int32_t *h = as_alloc_array(d->ctx, cap, sizeof *h);
    if (!h) return -1;
    as_free(d->ctx, d->phash, d->cap_phash * sizeof *d->phash);
    d->phash = h;
    d->cap_phash = cap;
    phash_clear(d);
    for (int32_t v = 0; v < d->nv; v++) phash_add(d, v);
    return 0;
}

/* Exact: are a, b, c collinear? (orient2d of the three coordinate projections, each an
 * exact orient3d with the fourth point (0, 0, 1).) */
static int collinear(const double *a, const double *b, const double *c) {
    static const double up[3] = {0, 0, 1};
    for (int k = 0; k < 3; k++) {
        int i = k, j = (k + 1) % 3;
        double A[3] = {a[i], a[j], 0}, B[3] = {b[i], b[j], 0}, C[3] = {c[i], c[j], 0};
        if (as_orient3d(A, B, C, up) != 0) return 0;
    }
    return 1;
}

/* The first tets: t0 = (v0, v1, v2, v3) at slot 0 and, at slot 1 + m, the infinite tet
 * I_m = t0 with v_m replaced by inf and the slots (m+1)&3, (m+2)&3 swapped. boot_slot(m, i):
 * the slot of t0's vertex i in I_m (and, the swap being an involution, the t0 index of the
 * vertex at slot i of I_m). */
static inline int boot_slot(int m, int i) {
    int s1 = (m + 1) & 3, s2 = (m + 2) & 3;
    return i == s1 ? s2 : i == s2 ? s1 : i;
}

/*
 * The points became 3D with vertex v3: build the first tet from d->boot and v3, its four
 * infinite tets, then insert every other pending vertex (in index order). Returns
 * ANISTAR_OK or ANISTAR_ENOMEM (then no tet exists and d->dim3 == 0).
 */
static anistar_status bootstrap(as_del3 *d, int32_t v3) {
    int32_t a = d->boot[0], b = d->boot[1], c = d->boot[2];
    if (as_orient3d(pt(d, a), pt(d, b), pt(d, c), pt(d, v3)) < 0) {
        int32_t s = a;
        a = b;
        b = s;
    }
    if (grow_tets(d, 5)) goto nomem;
    clear_tets(d);
    int32_t t0 = alloc_tet(d);
    int32_t *tv = rec(d, t0);
    tv[0] = a;
    tv[1] = b;
    tv[2] = c;
    tv[3] = v3;
    for (int i = 0; i < 4; i++) {
        int32_t t = alloc_tet(d);
        int32_t *iv = rec(d, t);
        const int32_t *v0 = rec(d, t0);
        /* an odd permutation of the finite slots: the face of t0 is seen reversed */
        for (int k = 0; k < 4; k++) iv[k] = v0[boot_slot(i, k)];
        iv[i] = AS_DEL3_INF;
    }
    /* t0's face m is I_m's face m; I_m's face k (k != m) holds inf and t0 minus v_m and
     * the vertex i = boot_slot(m, k): it is I_i's face opposite v_m. */
    for (int m = 0; m < 4; m++) {
        int32_t im = 1 + m;
        rec(d, t0)[4 + m] = 8 * im + m;
        rec(d, im)[4 + m] = 8 * t0 + m;
        for (int k = 0; k < 4; k++) {
            if (k == m) continue;
            int i = boot_slot(m, k);
            rec(d, im)[4 + k] = 8 * (1 + i) + boot_slot(i, m);
        }
    }
    d->dim3 = 1;
    d->vert[a].tet = d->vert[b].tet = d->vert[c].tet = d->vert[v3].tet = t0;
    d->hint = t0;
    for (int32_t u = 0; u < d->nv; u++) {
        if (u == a || u == b || u == c || u == v3) continue;
        int32_t dup;
        if (insert_at(d, pt(d, u), d->gid[u], u, &dup) != ANISTAR_OK) goto nomem;
    }
    if (buf_reserve(d->ctx, &d->created, (size_t)d->nlive)) goto nomem;
    d->created.n = 0;
    for (int32_t t = 0; t < d->nt; t++)
        if (d->tet[8 * (size_t)t] != AS_DEL3_DEAD) d->created.a[d->created.n++] = t;
    d->removed.n = 0;
    d->rebuilt = 1;
    phash_clear(d);
    return ANISTAR_OK;
nomem:
    clear_tets(d);
    return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory building the first tets");
}

static int pending_insert(as_del3 *d, const double *p, int64_t g, int32_t *vertex) {
    int32_t dup = phash_find(d, p);
    if (dup >= 0) {
        *vertex = dup;
        d->stats.duplicates++;
        return AS_DEL3_DUPLICATE;
    }
    if (grow_vertices(d, (size_t)d->nv + 1) || phash_reserve(d, (size_t)d->nv + 1))
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (vertex %d)", (int)d->nv);
    int32_t v = d->nv;
    store_vertex(d, v, p, g);
    d->nv++;
    phash_add(d, v);
    d->removed.n = d->created.n = 0;
    d->rebuilt = 0;
    *vertex = v;
    d->stats.inserted++;
    if (d->boot[0] < 0) {
        d->boot[0] = v;
    } else if (d->boot[1] < 0) {
        d->boot[1] = v; /* distinct from boot[0]: not a duplicate */
    } else if (d->boot[2] < 0) {
        if (!collinear(pt(d, d->boot[0]), pt(d, d->boot[1]), p)) d->boot[2] = v;
    } else if (as_orient3d(pt(d, d->boot[0]), pt(d, d->boot[1]), pt(d, d->boot[2]), p) != 0) {
        anistar_status st = bootstrap(d, v);
        if (st != ANISTAR_OK) {
            d->nv--;
            d->stats.inserted--;
            phash_clear(d);
            for (int32_t u = 0; u < d->nv; u++) phash_add(d, u);
            *vertex = -1;
            return st;
        }
    }
    return ANISTAR_OK;
}

/* ---- insertion API -------------------------------------------------------------------------- */

#ifdef AS_DEL3_DEBUG
static int debug_check(as_del3 *d) {
    if (as_del3_check_combinatorics(d) != ANISTAR_OK) return ANISTAR_EINTERNAL;
    if (as_del3_check_delaunay(d) != ANISTAR_OK) return ANISTAR_EINTERNAL;
    return ANISTAR_OK;
}
#endif

int as_del3_insert(as_del3 *d, const double p[3], int64_t gid, int32_t *vertex) {
    int32_t vdummy;
    if (!vertex) vertex = &vdummy;
    *vertex = -1;
    if (!finite3(p))
        return as_fail(d->ctx, ANISTAR_EINVAL, "del3: point (%g, %g, %g) is not finite", p[0],
                       p[1], p[2]);
    if (d->nv >= MAX_VERTS)
        return as_fail(d->ctx, ANISTAR_EINVAL, "del3: too many vertices (%d)", (int)d->nv);
    int r;
    if (!d->dim3) {
        r = pending_insert(d, p, gid, vertex);
    } else {
        if (grow_vertices(d, (size_t)d->nv + 1))
            return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (vertex %d)",
                           (int)d->nv);
        int32_t dup = -1;
        r = insert_at(d, p, gid, d->nv, &dup);
        if (r == AS_DEL3_DUPLICATE) {
            *vertex = dup;
            d->stats.duplicates++;
        } else if (r == ANISTAR_OK) {
            *vertex = d->nv - 1;
        }
    }
#ifdef AS_DEL3_DEBUG
    if (r == ANISTAR_OK && debug_check(d) != ANISTAR_OK) return ANISTAR_EINTERNAL;
#endif
    return r;
}

int as_del3_insert_frame(as_del3 *d, const as_metric_frame *mf, const double q[3],
                         int64_t gid, int32_t *vertex) {
    if (!mf) return as_del3_insert(d, q, gid, vertex);
    double y[3];
    as_metric_apply(mf, q, y);
    return as_del3_insert(d, y, gid, vertex);
}

anistar_status as_del3_insert_points(as_del3 *d, const double *pts, const int64_t *gids,
                                     int32_t n, const as_metric_frame *mf, int32_t *vertex,
                                     int32_t *ndup) {
    if (ndup) *ndup = 0;
    if (n < 0) return as_fail(d->ctx, ANISTAR_EINVAL, "del3: negative point count");
    if (n == 0) return ANISTAR_OK;
    for (int32_t i = 0; i < n; i++)
        if (!finite3(pts + 3 * (size_t)i))
            return as_fail(d->ctx, ANISTAR_EINVAL, "del3: point %d is not finite", (int)i);
    if ((int64_t)d->nv + n > MAX_VERTS)
        return as_fail(d->ctx, ANISTAR_EINVAL, "del3: too many vertices");
    if (vertex)
        for (int32_t i = 0; i < n; i++) vertex[i] = -1;
    size_t nn = (size_t)n;
    double *ys = NULL;
    int32_t *order = NULL;
    anistar_status st = ANISTAR_OK;
    const double *y = pts;
    if (mf) {
        ys = as_alloc_array(d->ctx, 3 * nn, sizeof *ys);
        if (!ys) goto nomem;
        for (size_t i = 0; i < nn; i++) as_metric_apply(mf, pts + 3 * i, ys + 3 * i);
        y = ys;
    }
    if (n > 64) {
        order = as_alloc_array(d->ctx, nn, sizeof *order);
        if (!order) goto nomem;
        st = as_sort_brio(d->ctx, y, n, d->seed, order);
        if (st != ANISTAR_OK) goto done;
        /* about 6.5 tets per point for uniform points; more is grown on demand */
        size_t want = 7 * ((size_t)d->nv + nn) + 64;
        if (want > MAX_TETS) want = MAX_TETS;
        if (grow_vertices(d, (size_t)d->nv + nn) || grow_tets(d, want)) goto nomem;
    }
    int32_t dups = 0;
    for (int32_t k = 0; k < n; k++) {
        int32_t i = order ? order[k] : k;
        if (order && k + 8 < n) { /* the sorted order jumps around the input: a cache
                                     miss per point unless fetched ahead (measured 8%) */
            DEL3_PREFETCH(y + 3 * (size_t)order[k + 8]);
            if (gids) DEL3_PREFETCH(gids + order[k + 8]);
        }
        int32_t v;
        int r = as_del3_insert(d, y + 3 * (size_t)i, gids ? gids[i] : i, &v);
        if (r == AS_DEL3_DUPLICATE) {
            dups++;
        } else if (r != ANISTAR_OK) {
            st = (anistar_status)r;
            goto done;
        }
        if (vertex) vertex[i] = v;
    }
    if (ndup) *ndup = dups;
    goto done;
nomem:
    st = as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory inserting %d points", (int)n);
done:
    as_free(d->ctx, ys, 3 * nn * sizeof *ys);
    as_free(d->ctx, order, nn * sizeof *order);
    return st;
}

/* ---- queries -------------------------------------------------------------------------------- */

int as_del3_conflict_zone(as_del3 *d, const double p[3], int64_t gid, int32_t hint,
                          as_del3_buf *tets, int32_t *dupv) {
    int32_t vdummy;
    if (!dupv) dupv = &vdummy;
    *dupv = -1;
    tets->n = 0;
    if (!finite3(p)) return as_fail(d->ctx, ANISTAR_EINVAL, "del3: point is not finite");
    if (!d->dim3) return as_fail(d->ctx, ANISTAR_EINVAL, "del3: the points are not 3D yet");
    uint64_t rng = d->rng;
    as_del3_stats stats = d->stats;
    int r = search(d, p, gid, hint, dupv);
    d->rng = rng; /* a query leaves no trace */
    d->stats = stats;
    if (r != ANISTAR_OK) return r;
    if (buf_reserve(d->ctx, tets, d->nconf)) {
        clear_marks(d);
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (conflict zone)");
    }
    for (size_t k = d->nconf; k-- > 0;) tets->a[tets->n++] = d->conf[k];
    clear_marks(d);
    return ANISTAR_OK;
}

int as_del3_in_sphere(const as_del3 *d, int32_t t, const double p[3], int64_t gid) {
    if (!as_del3_is_live(d, t)) return 0;
    const int32_t *tv = rec(d, t);
    for (int i = 0; i < 4; i++)
        if (tv[i] >= 0 && same_point(pt(d, tv[i]), p)) return 0;
    if (is_inf(tv)) return conflict_infinite(d, tv, p, gid);
    const double *c = d->sph ? d->sph + AS_DEL3_SPH * (size_t)t : NULL;
    if (!c || c[4] < 0) return tet_insphere(d, tv, p, gid) > 0; /* no cached sphere */
    int r = sphere_test(c, p);
    if (r) return r > 0;
    return sphere_exact(d, tv, p, gid) > 0;
}

int as_del3_in_sphere_points(const double *const q[4], const int64_t g[4], const double p[3],
                             int64_t gid) {
    for (int i = 0; i < 4; i++)
        if (same_point(q[i], p)) return 0;
    int s = isp_filter(q[0], q[1], q[2], q[3], p);
    if (!s) s = as_insphere_sos(q[0], q[1], q[2], q[3], p, g[0], g[1], g[2], g[3], gid);
    return s > 0;
}

/* The walk of as_del3_vertex_tets (tets, in its order) and, when facets is not NULL,
 * each popped tet's facets incident to v taken as it is popped (as_del3_vertex_tets_facets:
 * collect_facets' list and order in the same pass). */
static inline anistar_status vertex_walk(as_del3 *d, int32_t v, as_del3_buf *tets,
                                         as_del3_buf *facets) {
    tets->n = 0;
    if (facets) facets->n = 0;
    if (!d->dim3 || v < 0 || v >= d->nv)
        return as_fail(d->ctx, ANISTAR_EINVAL, "del3: no vertex %d in a 3D triangulation",
                       (int)v);
    int32_t t0 = d->vert[v].tet;
    if (buf_reserve(d->ctx, tets, 32)) goto nomem;
    tets->a[tets->n++] = t0;
    d->mark[t0] = MARK_OUT;
    for (size_t k = 0; k < tets->n; k++) {
        int32_t t = tets->a[k];
        if ((tets->n + 4 > tets->cap && buf_reserve(d->ctx, tets, tets->n + 4)) ||
            (facets && facets->n + 4 > facets->cap &&
             buf_reserve(d->ctx, facets, facets->n + 4)))
            goto nomem;
        const int32_t *tv = rec(d, t);
        int inf = facets && is_inf(tv) ? inf_slot(tv) : -1;
        for (int j = 0; j < 4; j++) {
            if (tv[j] == v) continue; /* the only face without v */
            int32_t n = tv[4 + j] >> 3;
            if (facets && (inf < 0 || inf == j) && t < n) facets->a[facets->n++] = 4 * t + j;
            if (d->mark[n] != MARK_NONE) continue;
            d->mark[n] = MARK_OUT;
            tets->a[tets->n++] = n;
        }
    }
    for (size_t k = 0; k < tets->n; k++) d->mark[tets->a[k]] = MARK_NONE;
    return ANISTAR_OK;
nomem:
    for (size_t k = 0; k < tets->n; k++) d->mark[tets->a[k]] = MARK_NONE;
    tets->n = 0;
    if (facets) facets->n = 0;
    return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (tets of vertex %d)", (int)v);
}

anistar_status as_del3_vertex_tets(as_del3 *d, int32_t v, as_del3_buf *out) {
    return vertex_walk(d, v, out, NULL);
}

/* The facets of the tets tets[0..nt) incident to v (see as_del3_vertex_facets) into
 * out->a (room for 3 nt reserved; tets may lie after that room in the same array). */
static size_t collect_facets(const as_del3 *d, int32_t v, const int32_t *tets, size_t nt,
                             int32_t *out) {
    size_t nf = 0;
    for (size_t k = 0; k < nt; k++) {
        int32_t t = tets[k];
        const int32_t *tv = rec(d, t);
        int inf = is_inf(tv) ? inf_slot(tv) : -1;
        for (int j = 0; j < 4; j++) {
            if (tv[j] == v) continue;
            if (inf >= 0 && inf != j) continue; /* the facet holds the infinite vertex */
            int32_t n = tv[4 + j] >> 3;
            if (t < n) out[nf++] = 4 * t + j;
        }
    }
    return nf;
}

anistar_status as_del3_vertex_facets(as_del3 *d, int32_t v, as_del3_buf *out) {
    anistar_status st = as_del3_vertex_tets(d, v, out);
    if (st != ANISTAR_OK) return st;
    /* Rewrite in place: each tet gives at most 3 facets, so collect into a second pass over
     * a copy at the end of the buffer. */
    size_t nt = out->n;
    if (buf_reserve(d->ctx, out, 4 * nt)) {
        out->n = 0;
        return as_fail(d->ctx, ANISTAR_ENOMEM, "del3: out of memory (facets of vertex %d)",
                       (int)v);
    }
    int32_t *tets = out->a + 3 * nt; /* the copy lives after the room for 3 nt facets */
    memmove(tets, out->a, nt * sizeof *tets);
    out->n = collect_facets(d, v, tets, nt, out->a);
    return ANISTAR_OK;
}

anistar_status as_del3_vertex_tets_facets(as_del3 *d, int32_t v, as_del3_buf *tets,
                                          as_del3_buf *facets) {
    /* design: as_del3_vertex_tets, each tet's facets (collect_facets) taken as it is
     * popped: the lists and their orders of the two calls, one pass */
    return vertex_walk(d, v, tets, facets);
}

/* ---- circumcenter ------------------------------------------------------------------------ */

/* The center relative to a of the sphere through a, a+u, a+v, a+w, in double-double from
 * the exact differences. */
static void circumcenter_dd(const double *a, const double *b, const double *c,
                            const double *e, double out[3]) {
    as_dd u[3], v[3], w[3];
    for (int i = 0; i < 3; i++) {
        u[i] = as_dd_two_sum(b[i], -a[i]);
        v[i] = as_dd_two_sum(c[i], -a[i]);
        w[i] = as_dd_two_sum(e[i], -a[i]);
    }
    as_dd vw[3], wu[3], uv[3];
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        vw[i] = as_dd_sub(as_dd_mul(v[j], w[k]), as_dd_mul(v[k], w[j]));
        wu[i] = as_dd_sub(as_dd_mul(w[j], u[k]), as_dd_mul(w[k], u[j]));
        uv[i] = as_dd_sub(as_dd_mul(u[j], v[k]), as_dd_mul(u[k], v[j]));
    }
    as_dd nu = {0, 0}, nv = {0, 0}, nw = {0, 0}, det = {0, 0};
    for (int i = 0; i < 3; i++) {
        nu = as_dd_add(nu, as_dd_mul(u[i], u[i]));
        nv = as_dd_add(nv, as_dd_mul(v[i], v[i]));
        nw = as_dd_add(nw, as_dd_mul(w[i], w[i]));
        det = as_dd_add(det, as_dd_mul(u[i], vw[i]));
    }
    as_dd den = as_dd_add(det, det);
    for (int i = 0; i < 3; i++) {
        as_dd num = as_dd_add(as_dd_add(as_dd_mul(nu, vw[i]), as_dd_mul(nv, wu[i])),
                              as_dd_mul(nw, uv[i]));
        as_dd x = as_dd_div(num, den);
        out[i] = a[i] + (x.hi + x.lo);
    }
}

/* Exact arithmetic for the flattest tets: bounded expansions (compressed after every
 * operation; an operation that would not fit reports failure and the caller keeps the
 * double-double result). */
enum { XCAP = 64 };
typedef struct xexp {
    int n;
    double c[XCAP];
} xexp;

static void x_diff(double a, double b, xexp *r) {
    double hi, lo;
    as_two_diff(a, b, &hi, &lo);
    r->c[0] = lo;
    r->c[1] = hi;
    r->n = 2;
}

static int x_add(const xexp *e, const xexp *f, xexp *h) {
    if (e->n + f->n > XCAP) return -1;
    h->n = as_exp_sum(e->n, e->c, f->n, f->c, h->c);
    h->n = as_exp_compress(h->n, h->c);
    return 0;
}

static int x_sub(const xexp *e, const xexp *f, xexp *h) {
    xexp g = *f;
    as_exp_negate(g.n, g.c);
    return x_add(e, &g, h);
}

static int x_mul(const xexp *e, const xexp *f, xexp *h) {
    xexp acc, t;
    acc.n = 1;
    acc.c[0] = 0;
    if (2 * e->n > XCAP) return -1;
    for (int j = 0; j < f->n; j++) {
        t.n = as_exp_scale(e->n, e->c, f->c[j], t.c);
        if (x_add(&acc, &t, h)) return -1;
        acc = *h;
    }
    *h = acc;
    return 0;
}

/* The circumcenter from exact numerators and denominator, each rounded once: relative
 * error a few ulps. Returns 0, or -1 if an expansion outgrew XCAP (out untouched). */
static int circumcenter_exact(const double *a, const double *b, const double *c,
                              const double *e, double out[3]) {
    xexp u[3], v[3], w[3], vw[3], wu[3], uv[3], nu, nv, nw, det, t1, t2, t3;
    for (int i = 0; i < 3; i++) {
        x_diff(b[i], a[i], &u[i]);
        x_diff(c[i], a[i], &v[i]);
        x_diff(e[i], a[i], &w[i]);
    }
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        if (x_mul(&v[j], &w[k], &t1) || x_mul(&v[k], &w[j], &t2) || x_sub(&t1, &t2, &vw[i]) ||
            x_mul(&w[j], &u[k], &t1) || x_mul(&w[k], &u[j], &t2) || x_sub(&t1, &t2, &wu[i]) ||
            x_mul(&u[j], &v[k], &t1) || x_mul(&u[k], &v[j], &t2) || x_sub(&t1, &t2, &uv[i]))
            return -1;
    }
    xexp *sq[3] = {&nu, &nv, &nw}, *vec[3] = {u, v, w};
    for (int s = 0; s < 3; s++) {
        sq[s]->n = 1;
        sq[s]->c[0] = 0;
        for (int i = 0; i < 3; i++) {
            if (x_mul(&vec[s][i], &vec[s][i], &t1) || x_add(sq[s], &t1, &t2)) return -1;
            *sq[s] = t2;
        }
    }
    det.n = 1;
    det.c[0] = 0;
    for (int i = 0; i < 3; i++) {
        if (x_mul(&u[i], &vw[i], &t1) || x_add(&det, &t1, &t2)) return -1;
        det = t2;
    }
    double den = 2 * as_exp_value(det.n, det.c), x[3];
    if (den == 0) return -1;
    for (int i = 0; i < 3; i++) {
        if (x_mul(&nu, &vw[i], &t1) || x_mul(&nv, &wu[i], &t2) || x_add(&t1, &t2, &t3) ||
            x_mul(&nw, &uv[i], &t1) || x_add(&t3, &t1, &t2))
            return -1;
        x[i] = as_exp_value(t2.n, t2.c) / den;
    }
    for (int i = 0; i < 3; i++) out[i] = a[i] + x[i];
    return 0;
}

/*
 * design: relative to a = v0, with u, v, w the edge vectors to v1, v2, v3:
 *   x = a + (|u|^2 (v x w) + |v|^2 (w x u) + |w|^2 (u x v)) / (2 u.(v x w))   (Cramer).
 * Three tiers by kappa = L^3 / |u.(v x w)| (L the longest of u, v, w; a regular tet has
 * kappa ~ 1.4, a sliver large):
 *  - doubles: relative error (to the circumradius) about 2^5 eps kappa; used when
 *    kappa <= 2^8 (error < 2^-40);
 *  - double-double on the exact differences: error about 2^-100 kappa; used when
 *    kappa <= 2^50 (error < 2^-45);
 *  - exact: numerators and denominator as expansions, each rounded once, then one
 *    division and one addition: error a few ulps of the center's coordinates (flatter
 *    tets; if an expansion outgrows its bound, which needs coordinates spanning hundreds
 *    of binades, the double-double value stands).
 */
int as_del3_circumcenter(const as_del3 *d, int32_t t, double c[3]) {
    if (!as_del3_is_live(d, t) || as_del3_is_infinite(d, t)) return -1;
    const int32_t *tv = rec(d, t);
    as_del3_circumcenter_points(pt(d, tv[0]), pt(d, tv[1]), pt(d, tv[2]), pt(d, tv[3]), c);
    return 0;
}

void as_del3_circumcenter_points(const double a[3], const double b[3], const double p2[3],
                                 const double p3[3], double c[3]) {
    double u[3], v[3], w[3];
    for (int i = 0; i < 3; i++) {
        u[i] = b[i] - a[i];
        v[i] = p2[i] - a[i];
        w[i] = p3[i] - a[i];
    }
    double vw[3] = {v[1] * w[2] - v[2] * w[1], v[2] * w[0] - v[0] * w[2],
                    v[0] * w[1] - v[1] * w[0]};
    double wu[3] = {w[1] * u[2] - w[2] * u[1], w[2] * u[0] - w[0] * u[2],
                    w[0] * u[1] - w[1] * u[0]};
    double uv[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2],
                    u[0] * v[1] - u[1] * v[0]};
    double nu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    double nv = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    double nw = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
    double det = u[0] * vw[0] + u[1] * vw[1] + u[2] * vw[2];
    double l2 = nu > nv ? nu : nv;
    if (nw > l2) l2 = nw;
    /* kappa <= 2^8  <=>  det^2 >= 2^-16 L^6 */
    if (det * det * 65536.0 >= l2 * l2 * l2 && det != 0) {
        double s = 0.5 / det;
        for (int i = 0; i < 3; i++) c[i] = a[i] + (nu * vw[i] + nv * wu[i] + nw * uv[i]) * s;
        return;
    }
    circumcenter_dd(a, b, p2, p3, c);
    /* kappa > 2^50 (det^2 < 2^-100 L^6): exact. The tiers differ only in accuracy, so the
     * rounded det is good enough to choose. */
    if (det * det * 0x1p100 < l2 * l2 * l2) circumcenter_exact(a, b, p2, p3, c);
}

int as_del3_sphere_filter(const as_del3 *d, int32_t t, const double p[3]) {
    const int32_t *tv = rec(d, t);
    const double *s = d->sph ? d->sph + AS_DEL3_SPH * (size_t)t : NULL;
    double tmp[AS_DEL3_SPH];
    if (!s || s[4] < 0) {
        sphere_compute(pt(d, tv[0]), pt(d, tv[1]), pt(d, tv[2]), pt(d, tv[3]), tmp);
        s = tmp;
    }
    return sphere_test(s, p);
}

int as_del3_insphere_filter(const double a[3], const double b[3], const double c[3],
                            const double d[3], const double e[3]) {
    return isp_filter(a, b, c, d, e);
}

void as_del3_forget_spheres(as_del3 *d) {
    if (d->sph)
        for (int32_t t = 0; t < d->nt; t++) d->sph[AS_DEL3_SPH * (size_t)t + 4] = SPH_NONE;
}

/* ---- validators ------------------------------------------------------------------------- */

static int face_opposite(const int32_t *tv, int i, const int32_t *nv, int j) {
    int32_t x[3] = {tv[face_vtx[i][0]], tv[face_vtx[i][1]], tv[face_vtx[i][2]]};
    int32_t y[3] = {nv[face_vtx[j][0]], nv[face_vtx[j][1]], nv[face_vtx[j][2]]};
    /* y must be a rotation of (x0, x2, x1) */
    for (int r = 0; r < 3; r++)
        if (y[r] == x[0] && y[(r + 1) % 3] == x[2] && y[(r + 2) % 3] == x[1]) return 1;
    return 0;
}

anistar_status as_del3_check_combinatorics(as_del3 *d) {
    anistar_context *ctx = d->ctx;
    if (!d->dim3) {
        if (d->nt != 0 || d->nlive != 0)
            return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tets exist before 3D");
        return ANISTAR_OK;
    }
    /* free list */
    int32_t nfree = 0;
    for (int32_t t = d->free_head; t >= 0; t = d->tet[8 * (size_t)t + 1]) {
        if (t >= d->nt || d->tet[8 * (size_t)t] != AS_DEL3_DEAD || ++nfree > d->nt)
            return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: bad free list at %d", (int)t);
    }
    for (int32_t v = AS_DEL3_INF; v < d->nv; v++)
        if (d->vert[v].loc != -1)
            return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: vertex %d left numbered",
                           (int)v);
    int32_t nlive = 0, nfinite = 0;
    for (int32_t t = 0; t < d->nt; t++) {
        const int32_t *tv = rec(d, t);
        if (d->mark[t] != MARK_NONE)
            return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tet slot %d left marked", (int)t);
        if (tv[0] == AS_DEL3_DEAD) continue;
        nlive++;
        int ninf = 0;
        for (int i = 0; i < 4; i++) {
            if (tv[i] < AS_DEL3_INF || tv[i] >= d->nv)
                return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tet %d vertex %d", (int)t,
                               (int)tv[i]);
            if (tv[i] == AS_DEL3_INF) ninf++;
            for (int j = 0; j < i; j++)
                if (tv[i] == tv[j])
                    return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tet %d repeats %d",
                                   (int)t, (int)tv[i]);
        }
        if (ninf > 1)
            return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tet %d has %d infinite vertices",
                           (int)t, ninf);
        for (int i = 0; i < 4; i++) {
            int32_t a = tv[4 + i], n = a >> 3, j = a & 7;
            if (a < 0 || j > 3 || !as_del3_is_live(d, n) || n == t || d->tet[a + 4] != 8 * t + i)
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: adjacency of tet %d face %d not symmetric", (int)t, i);
            if (!face_opposite(tv, i, rec(d, n), j))
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: tets %d and %d disagree on their face", (int)t,
                               (int)n);
        }
        if (ninf == 0) {
            nfinite++;
            if (!(as_orient3d(pt(d, tv[0]), pt(d, tv[1]), pt(d, tv[2]), pt(d, tv[3])) > 0))
                return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: tet %d not positive",
                               (int)t);
            const double *cs = d->sph ? d->sph + AS_DEL3_SPH * (size_t)t : NULL;
            if (cs && cs[4] >= 0) { /* equal to a fresh one relative to the same vertex */
                int same = 0;
                for (int k = 0; k < 4 && !same; k++) {
                    if (!same_point(pt(d, tv[k]), cs + 5)) continue;
                    const int8_t *fv = face_vtx[k];
                    double fresh[AS_DEL3_SPH];
                    sphere_compute(pt(d, tv[k]), pt(d, tv[fv[0]]), pt(d, tv[fv[1]]),
                                   pt(d, tv[fv[2]]), fresh);
                    same = memcmp(cs, fresh, sizeof fresh) == 0;
                }
                if (!same)
                    return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: stale sphere of tet %d",
                                   (int)t);
            } else if (cs && cs[4] != SPH_NONE) {
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: finite tet %d marked infinite in the cache", (int)t);
            }
        } else {
            if (d->sph && d->sph[AS_DEL3_SPH * (size_t)t + 4] >= 0)
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: infinite tet %d with a cached sphere", (int)t);
            int k = inf_slot(tv);
            int32_t a = tv[4 + k], n = a >> 3;
            if (as_del3_is_infinite(d, n))
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: infinite tet %d beside an infinite tet", (int)t);
            const double *q[4];
            for (int i = 0; i < 4; i++)
                q[i] = i == k ? pt(d, d->tet[a]) : pt(d, tv[i]);
            if (!(as_orient3d(q[0], q[1], q[2], q[3]) < 0))
                return as_fail(ctx, ANISTAR_EINTERNAL,
                               "del3 check: hull face of tet %d does not see its inside",
                               (int)t);
        }
    }
    if (nlive != d->nlive || nlive + nfree != d->nt)
        return as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: counts live %d/%d free %d slots %d",
                       (int)nlive, (int)d->nlive, (int)nfree, (int)d->nt);

    /* Vertex links. cnt[v+1]: tets holding v (scan); a BFS from vert[v].tet must reach them all,
     * and the link must be a 2-sphere: neighbours = 2 + tets/2. */
    size_t nvv = (size_t)d->nv + 1;
    int32_t *cnt = as_alloc_array(ctx, nvv, sizeof *cnt);
    int32_t *stamp = as_alloc_array(ctx, nvv, sizeof *stamp);
    as_del3_buf buf = {0};
    anistar_status st = ANISTAR_OK;
    if (!cnt || !stamp) {
        st = as_fail(ctx, ANISTAR_ENOMEM, "del3 check: out of memory");
        goto out;
    }
    memset(cnt, 0, nvv * sizeof *cnt);
    for (size_t i = 0; i < nvv; i++) stamp[i] = -1;
    int32_t some_inf = -1;
    for (int32_t t = 0; t < d->nt; t++) {
        const int32_t *tv = rec(d, t);
        if (tv[0] == AS_DEL3_DEAD) continue;
        for (int i = 0; i < 4; i++) cnt[tv[i] + 1]++;
        if (some_inf < 0 && (tv[0] | tv[1] | tv[2] | tv[3]) < 0) some_inf = t;
    }
    int64_t sum_nb = 0;
    for (int32_t v = AS_DEL3_INF; v < d->nv; v++) {
        int32_t t0;
        if (v == AS_DEL3_INF) {
            t0 = some_inf;
        } else {
            t0 = d->vert[v].tet;
            if (cnt[v + 1] == 0) {
                st = as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: vertex %d in no tet", (int)v);
                goto out;
            }
            const int32_t *tv = as_del3_is_live(d, t0) ? rec(d, t0) : NULL;
            if (!tv ||
                (tv[0] != v && tv[1] != v && tv[2] != v && tv[3] != v)) {
                st = as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: incident tet of vertex %d wrong",
                             (int)v);
                goto out;
            }
        }
        if (t0 < 0) {
            st = as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: no infinite tet");
            goto out;
        }
        /* BFS over the tets around v (the same walk as as_del3_vertex_tets, which cannot
         * take the infinite vertex). */
        buf.n = 0;
        if (buf_reserve(ctx, &buf, 4)) goto nomem;
        buf.a[buf.n++] = t0;
        d->mark[t0] = MARK_OUT;
        for (size_t k = 0; k < buf.n; k++) {
            int32_t t = buf.a[k];
            if (buf.n + 4 > buf.cap && buf_reserve(ctx, &buf, buf.n + 4)) {
                for (size_t m = 0; m < buf.n; m++) d->mark[buf.a[m]] = MARK_NONE;
                goto nomem;
            }
            const int32_t *tv = rec(d, t);
            for (int j = 0; j < 4; j++) {
                if (tv[j] == v) continue;
                int32_t n = tv[4 + j] >> 3;
                if (d->mark[n] != MARK_NONE) continue;
                d->mark[n] = MARK_OUT;
                buf.a[buf.n++] = n;
            }
        }
        int32_t nb = 0;
        for (size_t k = 0; k < buf.n; k++) {
            const int32_t *tv = rec(d, buf.a[k]);
            d->mark[buf.a[k]] = MARK_NONE;
            for (int j = 0; j < 4; j++)
                if (tv[j] != v && stamp[tv[j] + 1] != v + 1) {
                    stamp[tv[j] + 1] = v + 1;
                    nb++;
                }
        }
        if ((int64_t)buf.n != cnt[v + 1] || (buf.n & 1u) || nb != 2 + (int32_t)(buf.n / 2)) {
            st = as_fail(ctx, ANISTAR_EINTERNAL,
                         "del3 check: link of vertex %d is not a sphere (%d tets reached of %d,"
                         " %d neighbours)",
                         (int)v, (int)buf.n, (int)cnt[v + 1], (int)nb);
            goto out;
        }
        sum_nb += nb;
    }
    /* Euler on the 3-sphere: V - E + F - T = 0 with F = 2T. */
    {
        int64_t V = (int64_t)d->nv + 1, E = sum_nb / 2, T = nlive, F = 2 * T;
        if ((sum_nb & 1) || V - E + F - T != 0)
            st = as_fail(ctx, ANISTAR_EINTERNAL, "del3 check: Euler V-E+F-T = %lld",
                         (long long)(V - E + F - T));
    }
    (void)nfinite;
    goto out;
nomem:
    st = as_fail(ctx, ANISTAR_ENOMEM, "del3 check: out of memory");
out:
    as_free(ctx, cnt, nvv * sizeof *cnt);
    as_free(ctx, stamp, nvv * sizeof *stamp);
    as_del3_buf_free(ctx, &buf);
    return st;
}

anistar_status as_del3_check_delaunay(as_del3 *d) {
    for (int32_t t = 0; t < d->nt; t++) {
        const int32_t *tv = rec(d, t);
        if (tv[0] == AS_DEL3_DEAD) continue;
        int inf = is_inf(tv) ? inf_slot(tv) : -1;
        for (int i = 0; i < 4; i++) {
            if (i == inf) continue; /* checked by as_del3_check_combinatorics */
            int32_t w = d->tet[tv[4 + i]];
            if (w == AS_DEL3_INF) continue;
            if (in_conflict(d, t, pt(d, w), d->gid[w]))
                return as_fail(d->ctx, ANISTAR_EINTERNAL,
                               "del3 check: vertex %d (gid %lld) in conflict with tet %d",
                               (int)w, (long long)d->gid[w], (int)t);
        }
    }
    return ANISTAR_OK;
}
