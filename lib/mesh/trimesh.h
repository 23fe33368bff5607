/*
 * trimesh.h — internal: the in-memory triangle mesh (arrays of coordinates, 0-based
 * triangle indices, optional per-vertex tensors) and its topology check. The layer
 * between geom and io: the file readers and writers (lib/io), the mesh surfaces
 * (lib/surface) and the mesher's output (lib/mesher) all use it, and it uses only core.
 * Errors: ANISTAR_EINVAL (a bad index, a count too large, a non-finite value),
 * ANISTAR_ENOMEM, and for as_topology_require ANISTAR_EFORMAT.
 */
#ifndef ANISTAR_TRIMESH_H
#define ANISTAR_TRIMESH_H

#include "core.h"

#include <stdint.h>

/* ==================================================================================== */
/* The in-memory triangle mesh                                                          */
/* ==================================================================================== */

/* The largest vertex count (indices are int32_t). */
#define AS_TRIMESH_MAX_VERTICES ((size_t)INT32_MAX)

typedef struct as_trimesh {
    size_t nv;      /* number of vertices */
    size_t nt;      /* number of triangles */
    double *xyz;    /* 3*nv coordinates (x y z per vertex) */
    int32_t *tri;   /* 3*nt vertex indices, 0-based; counterclockwise seen from outside
                       once oriented */
    double *tensor; /* NULL, or 6*nv per-vertex tensors m11 m12 m13 m22 m23 m33 */
    /* Capacities (in vertices, triangles, tensors) of the three arrays; all allocated
     * from the context. Use the functions below rather than touching them. */
    size_t cap_v, cap_t, cap_m;
} as_trimesh;

/* An empty mesh (no allocation). */
void as_trimesh_init(as_trimesh *m);
/* Free the arrays of m (allocated from ctx) and make it empty. */
void as_trimesh_free(anistar_context *ctx, as_trimesh *m);
/* Make room for nv vertices and nt triangles in total. ENOMEM, or EINVAL if
 * nv > AS_TRIMESH_MAX_VERTICES. */
anistar_status as_trimesh_reserve(anistar_context *ctx, as_trimesh *m, size_t nv, size_t nt);
/* Append a vertex / a triangle (geometric growth). */
anistar_status as_trimesh_add_vertex(anistar_context *ctx, as_trimesh *m, double x, double y,
                                     double z);
anistar_status as_trimesh_add_triangle(anistar_context *ctx, as_trimesh *m, int32_t a,
                                       int32_t b, int32_t c);
/* Allocate m->tensor for the m->nv vertices (zero-filled) if it is NULL. */
anistar_status as_trimesh_alloc_tensors(anistar_context *ctx, as_trimesh *m);
/* Replace the content of m by copies of the arrays (tensor may be NULL). EINVAL if an
 * index is outside [0, nv) or nv is too large. */
anistar_status as_trimesh_set(anistar_context *ctx, as_trimesh *m, size_t nv,
                              const double *xyz, size_t nt, const int32_t *tri,
                              const double *tensor);
/* Validate m for writing: every index in [0, nv), coordinates and tensors finite.
 * Returns EINVAL naming `path` and the first offending triangle or vertex. */
anistar_status as_trimesh_check(anistar_context *ctx, const char *path, const as_trimesh *m);

/* ==================================================================================== */
/* Topology validation (topology.c), on arrays only                                     */
/* ==================================================================================== */

/*
 * What as_topology_check / as_topology_orient found. Triangles with a repeated vertex
 * index are counted and otherwise ignored (they are in neither E nor F). An "edge" is an
 * unordered pair of vertices of some triangle; a "patch" is a maximal set of triangles
 * connected through edges shared by exactly two triangles.
 */
typedef struct as_topology {
    size_t vertices;             /* nv as given */
    size_t used_vertices;        /* vertices of at least one triangle */
    size_t triangles;            /* nt as given */
    size_t edges;                /* distinct edges */
    size_t border_edges;         /* edges of exactly one triangle */
    size_t nonmanifold_edges;    /* edges of three or more triangles */
    size_t nonmanifold_vertices; /* vertices whose triangles form more than one fan */
    size_t repeated_index;       /* triangles with a repeated vertex index */
    size_t zero_area;            /* other triangles whose points are exactly collinear */
    size_t components;           /* connected components (through shared vertices) */
    size_t patches;              /* orientation patches (== components when manifold) */
    size_t nonorientable;        /* patches that admit no consistent orientation */
    size_t misoriented_edges;    /* two-triangle edges traversed twice in the same
                                    direction, as given */
    size_t inward_patches;       /* closed orientable patches with negative volume once
                                    made consistent */
    size_t flipped;              /* triangles reversed (orient) or to reverse (check) */
    long long euler;             /* chi = used_vertices - edges + (nt - repeated_index) */
    long long genus;             /* (2 components - chi) / 2 if closed_manifold and
                                    orientable, else -1 */
    double volume;               /* signed volume: as given (check), after (orient) */
    int closed_manifold;         /* no border or non-manifold edge, no non-manifold
                                    vertex, no repeated-index triangle */
    int oriented;                /* as given: consistent (no misoriented edge, no
                                    non-orientable patch) and no inward patch */
} as_topology;

/*
 * Analyse the triangle mesh (nv vertices xyz, nt triangles tri) without changing it.
 * Returns EINVAL if an index is outside [0, nv) or nt > AS_TOPOLOGY_MAX_TRIANGLES,
 * ENOMEM. Coordinates must be finite with nonzero magnitudes in [1e-100, 1e100] for the
 * zero-area test to be exact.
 * design: (1) half-edges sorted by (min, max) vertex with two counting sorts, so every
 *   edge's triangles are adjacent (O(n), no hashing); (2) fans: union-find of the
 *   corners at each vertex joined across two-triangle edges, one fan per root;
 *   (3) patches: breadth-first search across two-triangle edges giving each triangle a
 *   flip bit (flip the neighbour iff the shared edge is traversed in the same direction);
 *   a contradiction marks the patch non-orientable; (4) closed orientable patches with
 *   negative signed volume are flipped whole; (5) components: union-find of vertices;
 *   chi = V - E + F, genus = (2c - chi)/2; (6) zero area: exact sign of the three
 *   coordinate-plane projections of the cross product (all three zero iff collinear).
 */
anistar_status as_topology_check(anistar_context *ctx, size_t nv, const double *xyz, size_t nt,
                                 const int32_t *tri, as_topology *rep);
/* The same, then reverse (swap the last two indices of) every triangle that needs it so
 * that each orientable patch is consistent and each closed one has positive volume. The
 * report describes the mesh as given, except volume (after). */
anistar_status as_topology_orient(anistar_context *ctx, size_t nv, const double *xyz,
                                  size_t nt, int32_t *tri, as_topology *rep);
#define AS_TOPOLOGY_MAX_TRIANGLES ((size_t)(UINT32_MAX / 3 - 1))

/* 1 iff rep describes a closed, orientable 2-manifold without zero-area triangles. */
int as_topology_ok(const as_topology *rep);
/* ANISTAR_OK if as_topology_ok(rep) and (after orient) consistently oriented; else
 * EFORMAT with a message listing every problem, e.g.
 *   "bunny.off: not a closed 2-manifold: 12 border edges, 3 non-manifold edges". */
anistar_status as_topology_require(anistar_context *ctx, const char *name,
                                   const as_topology *rep);

/* Exact sign (-1, 0, +1) of orient2d(a, b, c) = (a - c) x (b - c), for finite
 * coordinates with nonzero magnitudes in [1e-100, 1e100]. */
int as_io_orient2d_sign(const double a[2], const double b[2], const double c[2]);
/* 1 iff the three points are exactly collinear (or two coincide). */
int as_io_collinear3(const double a[3], const double b[3], const double c[3]);

/* Union-find over uint32 nodes for the topology of a mesh (path halving; the root of a
 * set is its smallest node, so the result does not depend on the order of the unions). */
static inline uint32_t as_uf_find(uint32_t *p, uint32_t x) {
    while (p[x] != x) {
        p[x] = p[p[x]];
        x = p[x];
    }
    return x;
}
static inline void as_uf_union(uint32_t *p, uint32_t a, uint32_t b) {
    a = as_uf_find(p, a);
    b = as_uf_find(p, b);
    if (a < b) p[b] = a;
    else if (b < a) p[a] = b;
}
/* 1 iff triangle t (three indices) repeats a vertex. */
static inline int as_tri_repeated(const int32_t *t) {
    return t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
}

#endif
