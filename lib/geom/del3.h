/*
 * del3.h — internal: incremental Bowyer-Watson 3D Delaunay triangulation on pooled arrays
 * (DESIGN.md 4.3 and 4.4; paper 3.1 and 5.3).
 *
 * One as_del3 is the triangulation of a set of points in a "stretched frame": the caller
 * gives points q and optionally a metric frame F; the structure stores and triangulates
 * F q (paper 3.1: Del_M(V) is the Euclidean Delaunay triangulation of F_M(V)). With no
 * frame the points are triangulated as given. The same code builds the tiny star
 * triangulations of the mesher (tens of points, 8 box corners first) and ordinary large
 * triangulations (10^6 points, bulk insertion with a spatial sort).
 *
 * Layout (0-based int32 indices; one 32-byte record per vertex and per tet, so that a
 * neighbour or a vertex costs one cache line):
 *  vertices  v = 0 .. nv-1   vert[v].x the stored (stretched) coordinates, vert[v].tet one
 *                            incident live tet, vert[v].loc scratch (-1 between
 *                            operations; vert[-1] is the infinite vertex's); gid[v] the
 *                            caller's global id (int64: the symbolic perturbation key);
 *  tets      t = 0 .. nt-1   tet[8t+i] (i < 4) vertex i (AS_DEL3_INF for the infinite
 *                            vertex, AS_DEL3_DEAD in tet[8t] for a free slot, whose
 *                            tet[8t+1] links the free list); tet[8t+4+i] = 8t'+j: the
 *                            neighbour t' across the face opposite vertex i, which is the
 *                            face of t' opposite its vertex j (a face "handle": tet[h] is
 *                            the vertex opposite the face, tet[h+4] its mirror, so
 *                            tet[tet[h+4]+4] == h); mark[t] scratch (0 between operations).
 * Read them through the accessors at the end of this file (as_del3_tet_vertices,
 * as_del3_mirror, ...): faces in the API are numbered 4t+i.
 * Every finite tet is positively oriented: as_orient3d(v0, v1, v2, v3) > 0. An infinite
 * tet has exactly one vertex AS_DEL3_INF; replacing it by a point q gives a positive tet
 * iff q lies strictly outside the convex hull beyond the tet's finite face. Together the
 * tets triangulate the 3-sphere R^3 + {inf}: V - E + F - T = 0 with V = nv + 1.
 *
 * Degeneracies: insphere ties are broken by as_insphere_sos keyed on the GLOBAL ids, so
 * every triangulation is the unique Delaunay triangulation of the perturbed set (the same
 * whatever the insertion order) and all stars break a tie the same way. See del3.c for
 * the infinite-vertex/perturbation scheme and its proof. Exact duplicates are reported,
 * not inserted. Until the points span 3D (no 4 of them affinely independent) they are
 * stored as pending vertices without tets; the first point that makes the set 3D builds
 * the triangulation of all of them.
 *
 * Lifetime: as_del3_init / as_del3_destroy; as_del3_reset empties it and keeps capacity
 * (a reset structure rebuilt with the same calls gives identical arrays). Memory comes
 * from the context allocator; no allocation per tet (amortised array growth): 33 bytes
 * per tet slot (plus 64 of cached sphere when asked for, while the capacity is at most
 * 2^14 slots: star-sized triangulations), 40 per vertex (about 260 bytes per point for
 * uniform random points).
 * All functions are reentrant (no globals); one structure is used by one thread at a time.
 *
 * Debug: build with -DAS_DEL3_DEBUG to run both validators after every insertion (an
 * insertion that leaves an invalid triangulation then returns ANISTAR_EINTERNAL).
 * `make check` exercises this mode: test/test_del3_debug.c links a copy of del3.c built
 * with -DAS_DEL3_DEBUG (its own Makefile rule) and inserts every point one by one.
 */
#ifndef ANISTAR_DEL3_H
#define ANISTAR_DEL3_H

#include <stddef.h>
#include <stdint.h>

#include "core.h"
#include "geom/metric.h"

#define AS_DEL3_INF (-1)  /* the infinite vertex, in the tet records */
#define AS_DEL3_DEAD (-2) /* tet[8t] of a free tet slot */

/* as_del3_insert's return value when the point equals an existing vertex (equal stored
 * coordinates after stretching, compared with ==, so -0 equals +0): nothing changed,
 * *vertex is that vertex. Not an anistar_status. */
#define AS_DEL3_DUPLICATE (-1)

/* A growable int32 array owned by the caller, memory from a context (the one of the
 * structure it is used with). Zero-initialise it ({0}); free with as_del3_buf_free. */
typedef struct as_del3_buf {
    int32_t *a;
    size_t n, cap;
} as_del3_buf;

void as_del3_buf_free(anistar_context *ctx, as_del3_buf *b);

/* Cavity-local vertex numbers: a cavity whose boundary has at most this many vertices is
 * glued through a direct table of AS_DEL3_LMAX^2 entries; bigger ones through a hash. */
#define AS_DEL3_LMAX 64

/* Doubles per tet slot in the sphere cache (del3.c: N[3], D, m, a[3]): 64 bytes. */
#define AS_DEL3_SPH 8

/* An entry of the cavity edge table (internal). */
typedef struct as_del3_edge {
    int32_t a, b, link;
} as_del3_edge;

/* A vertex record (32 bytes: one cache line holds two). */
typedef struct as_del3_vertex {
    double x[3];  /* stored (stretched) coordinates */
    int32_t tet;  /* an incident live tet (valid once the set is 3D) */
    int32_t loc;  /* cavity-local number during an insertion, -1 otherwise */
} as_del3_vertex;

/* Counters (always on; cheap). */
typedef struct as_del3_stats {
    uint64_t inserted, duplicates;
    uint64_t walk_steps;          /* tets visited by the walks */
    uint64_t conflict_tets;       /* tets removed by insertions */
    uint64_t created_tets;        /* tets created by insertions */
    uint64_t big_cavities;        /* cavities glued through the hash (> AS_DEL3_LMAX
                                     boundary vertices) */
    uint64_t sphere_tests;        /* conflict tests of neighbours by the insertions'
                                     searches (finite and infinite tets) */
    uint64_t sphere_exact;        /* finite-tet tests that the floating-point filters
                                     (cached sphere, or the inline filter) left to the
                                     exact predicate */
} as_del3_stats;

typedef struct as_del3 {
    anistar_context *ctx;

    /* vertices */
    int32_t nv;
    size_t cap_v;
    as_del3_vertex *vert; /* cap_v + 1 records from vert[-1] (the infinite vertex's: its
                             loc and tet are scratch) */
    int64_t *gid;         /* cap_v: global ids (perturbation keys) */
    void *vblk;           /* the block holding vert and gid */

    /* tets */
    int32_t nt;    /* slots in use (live or free): 0 .. nt-1 */
    int32_t nlive; /* live tets (finite + infinite) */
    size_t cap_t;
    int32_t *tet;  /* 8 * cap_t: the tet records (64-byte aligned) */
    uint8_t *mark; /* cap_t: visit marks of the current operation */
    void *tblk;    /* the block holding tet and mark */
    double *sph; /* cap_t * AS_DEL3_SPH (64-byte aligned) or NULL: the cached lifted plane
                    of each finite tet (its circumsphere as a linear test relative to one of
                    its vertices, with an error bound; see del3.c), computed when the tet is
                    created or at its first test; sph[AS_DEL3_SPH t + 4] < 0 while none.
                    Only when sphere_cache is set, and only while cap_t is at most 2^14
                    (dropped for good beyond) */
    void *sblk;  /* the block holding sph */
    int sphere_cache;    /* set by the owner before the first insertion: cache the spheres
                            of a small triangulation. Pays when its tets are tested many
                            times (repeated queries); off by default: building is faster
                            without it (measured: bench_del3), and it costs 64 bytes per tet */
    int no_sphere_cache; /* set by the owner: never cache the spheres, whatever
                            sphere_cache says (the mesher's stars) */
    int tight_growth;    /* set by the owner: grow the arrays by 1/8 instead of doubling
                            (the mesher's stars: thousands of small triangulations that
                            grow a few tets at a time; doubling left 20% of their slots
                            unused at the end of a run, 8.1 KB instead of 7.4 KB per
                            output vertex on the paper's torus) */
    int32_t free_head; /* first free slot or -1 */

    int dim3;        /* 1 once the points span 3D (tets exist) */
    int32_t boot[3]; /* pending phase: first point, first distinct, first non-collinear */
    int32_t *phash;  /* pending phase: open-addressing table of vertex ids by coordinates */
    size_t cap_phash;

    int32_t hint;   /* walk start of the next insertion (the caller may set it) */
    uint64_t rng;   /* xorshift state of the walks; reset by as_del3_reset */
    uint64_t seed;

    /* scratch, kept between insertions */
    int32_t *stack;
    size_t cap_stack;
    int32_t *conf; /* the conflict tets of the last search, in discovery order */
    size_t nconf, cap_conf;
    int32_t *crec; /* a copy of each one's record (8 per conflict tet) */
    size_t cap_crec;
    int32_t *bf; /* the cavity boundary faces: 8k + i, face i of conflict tet k */
    size_t nbf, cap_bf;
    as_del3_edge *etab; /* power-of-two size cap_etab */
    size_t cap_etab;
    int32_t *etouch;
    size_t cap_etouch;
    int32_t *ltab; /* AS_DEL3_LMAX^2 entries: the gluing table */
    int32_t *gl;   /* the faces registered in it (2 per face) */
    size_t cap_gl;
    int32_t lverts[AS_DEL3_LMAX + 1]; /* one spare entry: written branch-free */

    /* the last successful insertion (valid until the next modifying call): the tets it
     * removed and the tets it created. Ids may repeat between the two lists (slots are
     * reused): process `removed` first. When the insertion made the set 3D, `removed` is
     * empty, `created` holds every live tet and `rebuilt` is 1. */
    as_del3_buf removed, created;
    int rebuilt;

    as_del3_stats stats;
} as_del3;

/* ---- lifetime -------------------------------------------------------------------------- */

/* Initialise an empty structure using ctx's allocator. Allocates nothing. */
void as_del3_init(as_del3 *d, anistar_context *ctx);
/* Free every array. d may then be initialised again. */
void as_del3_destroy(as_del3 *d);
/* Empty the triangulation, keep the arrays (no allocation on rebuild up to the former
 * size), restore the walk's random state: the same calls after a reset give the same
 * arrays. */
void as_del3_reset(as_del3 *d);

/* Swap the per-insertion scratch buffers (conflict stack, boundary faces, gluing tables,
 * removed/created lists, point hash) of a and b; their triangulations stay put. Lets many
 * small triangulations share one set of scratch buffers (the mesher's stars): a
 * triangulation needs its scratch only during an operation. */
void as_del3_swap_scratch(as_del3 *a, as_del3 *b);
/* Set the seed of the walk's random face order (default 0); takes effect now and at
 * every reset. Results (the set of tets) never depend on it; tet numbering does. */
void as_del3_set_seed(as_del3 *d, uint64_t seed);
/* Make room for nv vertices and nt tets (about 6.5 nv for random points). Returns
 * ANISTAR_OK or ANISTAR_ENOMEM (nothing changed). */
anistar_status as_del3_reserve(as_del3 *d, int32_t nv, int32_t nt);

/* ---- insertion ------------------------------------------------------------------------- */

/*
 * Insert point p (already in the triangulation's frame) with global id gid.
 * Returns ANISTAR_OK (p is the new vertex *vertex = nv-1), AS_DEL3_DUPLICATE (p equals
 * vertex *vertex bit for bit; nothing changed), ANISTAR_EINVAL (non-finite coordinate,
 * too many vertices) or ANISTAR_ENOMEM (nothing changed). vertex may be NULL.
 * On ANISTAR_OK, d->removed and d->created list the tets removed and created.
 * notes: gid must differ from every other vertex's gid (not checked). The walk starts at
 *   d->hint (any live tet; set automatically to a tet of the last insertion).
 * design: hinted remembering walk (random face order from d->rng) -> conflict zone by an
 *   explicit stack (insphere_sos on global ids; infinite tets: see del3.c) -> cavity
 *   boundary faces -> new tets glued through an edge table (DESIGN.md 4.3).
 */
int as_del3_insert(as_del3 *d, const double p[3], int64_t gid, int32_t *vertex);

/* The same for the point F q: y = as_metric_apply(mf, q) is stored and inserted
 * (mf == NULL: the identity, y = q). F q is computed the same way every time, so a point
 * inserted in two structures with the same frame has the same stretched coordinates. */
int as_del3_insert_frame(as_del3 *d, const as_metric_frame *mf, const double q[3],
                         int64_t gid, int32_t *vertex);

/*
 * Bulk insertion of n points pts[3i..3i+2] (in the frame mf, NULL: identity) with global
 * ids gids[i] (gids == NULL: gid i). More than 64 points are inserted in BRIO order
 * (random rounds growing by 8, deterministic: as_sort_brio with d's seed) with a Hilbert
 * order inside each round; fewer are inserted in the given order (the next points of the
 * sorted order are prefetched). vertex (optional, n entries) receives the
 * vertex of each point (the existing vertex for a duplicate); *ndup (optional) the number
 * of duplicates. Returns ANISTAR_OK, ANISTAR_EINVAL (non-finite coordinates: nothing
 * inserted) or ANISTAR_ENOMEM (the triangulation holds a subset of the points, valid;
 * vertex[] entries of points not inserted are -1). d->removed/created are not meaningful
 * after a bulk insertion.
 */
anistar_status as_del3_insert_points(as_del3 *d, const double *pts, const int64_t *gids,
                                     int32_t n, const as_metric_frame *mf, int32_t *vertex,
                                     int32_t *ndup);

/* Release the capacity beyond the current tet slots and vertices (for a triangulation
 * kept a long time, like a mesher star; the next insertions grow it again). Returns 0, or
 * -1 when out of memory (nothing changed). */
int as_del3_shrink(as_del3 *d);

/* ---- queries that do not modify -------------------------------------------------------- */

/* The cached-sphere filter alone (tests): +1 / -1 when it certifies the sign of
 * insphere(tet t, p) (the unperturbed predicate, +1 inside), 0 when it leaves the decision
 * to the exact predicate. t must be a live finite tet. Uses t's cached sphere, or computes
 * one without storing it. */
int as_del3_sphere_filter(const as_del3 *d, int32_t t, const double p[3]);

/* The inline insphere filter of triangulations without the sphere cache (tests): +1 / -1
 * when it certifies the sign of as_insphere(a, b, c, d, e), 0 when it leaves the decision
 * to the exact predicate. */
int as_del3_insphere_filter(const double a[3], const double b[3], const double c[3],
                            const double d[3], const double e[3]);

/*
 * The conflict zone of a point p not (yet) inserted, with provisional global id gid:
 * the tets an insertion of p would remove, in *tets (cleared first), without modifying
 * the triangulation. Returns ANISTAR_OK, AS_DEL3_DUPLICATE (p equals vertex *dupv; tets
 * is empty), ANISTAR_EINVAL (non-finite p, or the set is not 3D yet: tets empty) or
 * ANISTAR_ENOMEM. hint: a live tet to start the walk from, or -1 (d->hint).
 */
int as_del3_conflict_zone(as_del3 *d, const double p[3], int64_t gid, int32_t hint,
                          as_del3_buf *tets, int32_t *dupv);

/* 1 if p (with provisional global id gid, not a vertex of t) is strictly inside the
 * perturbed circumsphere of live tet t, i.e. an insertion of p would remove t; 0 if not
 * (also when p equals a vertex of t, or t is not a live tet). Exact. Infinite tets: the
 * rule of del3.c. */
int as_del3_in_sphere(const as_del3 *d, int32_t t, const double p[3], int64_t gid);

/* as_del3_in_sphere for a finite tet given by its four stored points q (positively
 * oriented, as in a tet record) and their global ids g, without the structure (a caller
 * that keeps a triangulation in its own compact form: the mesher's idle stars). The same
 * answer, bit for bit: 0 when p equals one of the q, else the filter then
 * as_insphere_sos. */
int as_del3_in_sphere_points(const double *const q[4], const int64_t g[4], const double p[3],
                             int64_t gid);

/* The tets incident to vertex v (finite and infinite), in *out (cleared first).
 * Iterative; ANISTAR_OK, ANISTAR_EINVAL (v out of range or the set not 3D) or
 * ANISTAR_ENOMEM. */
anistar_status as_del3_vertex_tets(as_del3 *d, int32_t v, as_del3_buf *out);

/* The facets incident to vertex v whose three vertices are finite, each once, as 4t+i
 * (face of live tet t opposite its vertex i; its other side is as_del3_mirror), in *out.
 * Returns as as_del3_vertex_tets. */
anistar_status as_del3_vertex_facets(as_del3 *d, int32_t v, as_del3_buf *out);

/* as_del3_vertex_tets into *tets and as_del3_vertex_facets into *facets in one walk
 * around v (the same lists in the same orders). Returns as as_del3_vertex_tets (both
 * lists empty on failure). */
anistar_status as_del3_vertex_tets_facets(as_del3 *d, int32_t v, as_del3_buf *tets,
                                          as_del3_buf *facets);

/*
 * Circumcenter of finite tet t, in the stored (stretched) frame; mapping it back by F^-1
 * is the caller's job. Accuracy (relative to the circumradius), by the tet's condition
 * kappa = L^3/|det| (L its longest edge from vertex 0; ~1.4 for a regular tet): Cramer's
 * rule in doubles when kappa <= 2^8 (error < 2^-40); double-double on the exact edge
 * vectors when kappa <= 2^50 (error < 2^-45); beyond, exact numerators and denominator
 * (expansions) rounded once (error a few ulps). See del3.c. Returns 0, or -1 if t is
 * infinite or dead (c untouched).
 */
int as_del3_circumcenter(const as_del3 *d, int32_t t, double c[3]);
/* The same for the finite tet of the stored points a, b, p2, p3 in record order (the same
 * numbers as as_del3_circumcenter on that tet). */
void as_del3_circumcenter_points(const double a[3], const double b[3], const double p2[3],
                                 const double p3[3], double c[3]);

/* ---- small accessors -------------------------------------------------------------------- */

static inline int as_del3_is_live(const as_del3 *d, int32_t t) {
    return t >= 0 && t < d->nt && d->tet[8 * (size_t)t] != AS_DEL3_DEAD;
}
/* The 4 vertices of tet t (AS_DEL3_INF for the infinite one). */
static inline const int32_t *as_del3_tet_vertices(const as_del3 *d, int32_t t) {
    return d->tet + 8 * (size_t)t;
}
/* Vertex i (0..3) of tet t. */
static inline int32_t as_del3_tet_vertex(const as_del3 *d, int32_t t, int i) {
    return d->tet[8 * (size_t)t + (size_t)i];
}
/* 1 if live tet t has the infinite vertex. */
static inline int as_del3_is_infinite(const as_del3 *d, int32_t t) {
    const int32_t *v = d->tet + 8 * (size_t)t;
    return (v[0] | v[1] | v[2] | v[3]) < 0;
}
/* The face on the other side of face 4t+i: 4t'+j. */
static inline int32_t as_del3_mirror(const as_del3 *d, int32_t face) {
    int32_t h = d->tet[8 * (size_t)(face >> 2) + 4 + (size_t)(face & 3)];
    return 4 * (h >> 3) + (h & 3);
}
static inline int32_t as_del3_neighbor(const as_del3 *d, int32_t t, int i) {
    return d->tet[8 * (size_t)t + 4 + (size_t)i] >> 3;
}
static inline const double *as_del3_point(const as_del3 *d, int32_t v) {
    return d->vert[v].x;
}
/* Number of finite tets (live tets minus infinite ones) is not stored; count with
 * as_del3_count. */
void as_del3_count(const as_del3 *d, int32_t *finite_tets, int32_t *infinite_tets);

/* Drop every cached sphere (they are recomputed at the next test). Needed only after
 * changing stored coordinates vert[v].x in place (tests do; the library never does). */
void as_del3_forget_spheres(as_del3 *d);

/* ---- validators (tests; debug builds after every insertion) --------------------------- */

/*
 * Combinatorial and orientation validity: live slots and free list consistent; every
 * adjacency symmetric with equal vertex sets on both sides and opposite orientations;
 * at most one infinite vertex per tet; every finite tet positively oriented (exact
 * orient3d) and its cached sphere, if any, equal to a fresh one; every infinite tet's
 * neighbour across its finite face strictly inside; the link of every vertex (the
 * infinite one too) a triangulated 2-sphere reached from vert[v].tet (neighbours = 2 +
 * tets/2), every vertex reachable; all marks clear; V - E + F - T = 0 (with infinite
 * vertex). Returns ANISTAR_OK or ANISTAR_EINTERNAL with a message in the context;
 * ANISTAR_ENOMEM if scratch memory runs out.
 */
anistar_status as_del3_check_combinatorics(as_del3 *d);

/*
 * Local Delaunay test with the perturbation, exact: for every tet t and each neighbour's
 * opposite vertex w, w is not in conflict with t (finite t: insphere_sos < 0; infinite t:
 * the hull rule of del3.c, which makes the hull convex and its coplanar parts perturbed-
 * Delaunay). Local Delaunay everywhere implies global (empty perturbed spheres).
 * Returns ANISTAR_OK or ANISTAR_EINTERNAL with a message.
 */
anistar_status as_del3_check_delaunay(as_del3 *d);

#endif /* ANISTAR_DEL3_H */
