/*
 * star.h — internal: one vertex star of the anisotropic star set (DESIGN.md 4.3-4.4,
 * paper 3.1 and 5.3).
 *
 * The star of a site v is the del3 triangulation T'_v of the stretched points F_v q, q in
 * {8 corners of an enlarged bounding box (global ids 0-7)} u {v} u {the sites inserted
 * into this star}. F_v is linear, so the stretched box contains every stretched surface
 * point: every tet incident to v is finite.
 *
 * Restricted facets (the surface star S_v): a facet incident to v is restricted iff
 * exactly one of its two tets is "inside": the tet's stretched circumcenter, mapped back
 * by F_v^-1, lies strictly inside S (as_surface_side < 0; beyond the bounding sphere is
 * outside). The inside flag is cached per tet slot and recomputed only for tets created
 * since. For each restricted facet tau the star keeps its surface center c_v(tau) (the
 * crossing of the dual segment with S nearest the facet's own circumcenter) and radius
 * r_v(tau) = |F_v (c - v)|; both are reused while the two tets of the facet survive.
 *
 * The conflict zone Z_v is the union of the surface balls B_v(tau); while the surface
 * star is not a closed disk (one closed fan of restricted facets around v), the star uses
 * the union of the circumballs of its tets incident to v instead (a superset: paper 5.3's
 * rule needs a complete restricted Voronoi cell). lo/hi bound it (DESIGN.md 4.4).
 */
#ifndef ANISTAR_STAR_H
#define ANISTAR_STAR_H

#include <stdint.h>

#include "core.h"
#include "geom/del3.h"
#include "geom/metric.h"
#include "surface/surface.h"

/* A restricted facet of a star (always incident to the star's center). */
typedef struct as_rfacet {
    double c[3];   /* surface center c_v(tau) on S */
    double r;      /* r_v(tau) = |F_v (c - v)| */
    as_gid g[3];   /* global ids, ascending */
    uint8_t fresh; /* 1 if created or moved by the last update (center recomputed) */
    uint8_t queued;/* bit k: an entry of rule k+1's queue refers to this facet */
} as_rfacet;

/* A point a star takes from here instead of from the owner's array (a simulation's
 * candidate: every thread simulates its own under the same provisional id). */
typedef struct as_star_ovr {
    as_gid gid;
    double p[3];
} as_star_ovr;

/* What a star needs from its owner: the context, the surface, every point by global id. */
typedef struct as_star_env {
    anistar_context *ctx;
    const as_surface *surf;
    const double *xyz; /* 3 per global id (corners, poles, sites) */
    int keep_points;   /* pack the stretched points with the stars (see as_star): needed
                          once sites move (the optimiser), else recomputed */
    int memo;          /* remember surface answers in the scratch (as_star_memo): set by
                          the optimiser, whose rebuilds ask the same questions again */
} as_star_env;

/*
 * Memory (docs/algorithm.md, "Memory"): a star is idle nearly all the time, and an idle
 * star is packed: one block holds its triangulation (its vertices' global ids, each
 * vertex's incident tet, and per tet slot its four vertices in a byte each and
 * its four neighbour handles in 16 bits, 12 bytes instead of 33, while the star has at
 * most AS_STAR_NARROW_NV vertices and AS_STAR_NARROW_NT tet slots; 32 bits beyond), its
 * tet flags, restricted facets, incident tets and their spheres, each at its
 * exact size; the smallest stars (at most AS_STAR_TINY_NV vertices and AS_STAR_TINY_NT
 * slots, nearly all) take 8 bytes per slot: 6 bits per vertex, 10 per handle. A star is
 * unpacked into its owner's working triangulation (sc->work) for
 * the length of one operation (build, insert, rebuild) and packed again after it: the
 * same arrays, slot for slot, so the results do not depend on the packing.
 * The stretched points F_v q are not kept: as_metric_apply gives the same bits from the
 * point q (env->xyz) and the frame the star was built with (its center's) every time,
 * as del3 computed them at insertion. That holds while no site moves; the optimiser moves
 * sites, and a star may hold a site without being rebuilt when it moves (it keeps the old
 * position, as it always did): from the first move on (env->keep_points) every star
 * packs its points too (as_star_keep_points).
 */
#define AS_STAR_NARROW_NV 254
#define AS_STAR_NARROW_NT 8192
#define AS_STAR_TINY_NV 62
#define AS_STAR_TINY_NT 255

typedef struct as_star {
    as_gid gid;         /* the center v */
    int32_t vloc;       /* v's vertex in the triangulation */
    const as_star_ovr *ovr; /* NULL, or the point of id ovr->gid (see as_star_ovr) */
    as_del3 *d;         /* during an operation: the owner's working triangulation holding
                           this star (sc->work); NULL while packed */
    /* the packed triangulation (while d is NULL): nv vertices, nt tet slots (nlive live,
     * free list from free_head), the walk's hint and random state */
    int32_t nv, nt, nlive, free_head, hint;
    int fmt;            /* the record format (star.c): 8, 12 or 32 bytes per tet slot */
    uint64_t rng;
    void *blk;          /* the one block of the packed star */
    size_t blk_bytes;
    double *vx;         /* 3 per vertex: the stored (stretched) points, or NULL (then
                           recomputed: see above) */
    as_gid *vgid;       /* per vertex: its global id */
    void *vtet;         /* per vertex: an incident tet (+ 1 in 8 or 16 bits; or int32_t) */
    void *trec;         /* per tet slot: tiny, one uint64_t (vertex i + 2 in bits 6i..6i+5,
                           handle 8t'+j as 4t'+j in bits 24+10i..); narrow, 4 uint16_t
                           handles (tet[8t+4..7]) then, after all slots, 4 uint8_t vertices
                           (tet[8t..3] + 2); wide, del3's 8 int32_t. Vertex code 0 (DEAD)
                           marks a free slot, whose link + 1 is its first handle */
    uint8_t *tflag;     /* per tet slot: bits 0-1 inside state (0 unknown, 1 out, 2 in),
                           bit 2 created by the last insertion */
    size_t cap_tflag;
    as_rfacet *rf;      /* restricted facets, sorted by (g0, g1, g2) */
    int32_t nrf, cap_rf;
    int closed;         /* the restricted facets form one closed fan around v */
    uint8_t topo_queued;/* the refiner's topology queue holds this star */
    uint32_t version;   /* incremented by every change of the triangulation */
    uint32_t vz_version;/* as_starset_verify_zones found the star right at this version, */
    int32_t vz_n;       /* with the sites below this id, */
    double vz_reach;    /* within this reach (0: never verified) */
    uint8_t zfull;      /* its zone is its whole Delaunay region even when closed: the
                           surface-ball zone was found to miss a site that changes its
                           restricted facets (as_starset_verify_zones) */
    int32_t nv_base;    /* nv after the last (re)build: compaction trigger */
    int32_t *itet;      /* the live tets incident to v (after the last update) */
    int32_t nitet, cap_itet;
    double lo[3], hi[3];/* box of the conflict zone */
    /* closed stars: the inflated zone in the stretched frame (as_star_zone_ball of each
     * facet) lies in the ball of center F_v v and squared radius zr2 */
    double zr2;
    double fv[3];       /* F_v v, v's stored point (packed stars: the filters' origin) */
    /* while open, after an update: per itet[i], isph[4i..4i+2] its circumcenter
     * (stretched frame), isph[4i+3] a bound on its squared circumradius (-1 for an
     * infinite tet, -2 none); as_star_sphere recomputes them for a packed star */
    double *isph;
    int32_t cap_isph;
    /* packed: per itet[i], a float ball containing that circumsphere (center fv +
     * fsph[4i..4i+2], radius fsph[4i+3], -1: none): a proven filter in front of the exact
     * in-sphere test (as_star_conflicts; 16 bytes instead of 32 per incident tet) */
    float *fsph;
    /* the close that made the packed block: the scratch and its count of closes then
     * (star_open's reuse of the working triangulation, see as_star_scratch) */
    const void *pack_sc;
    uint64_t pack_serial;
} as_star;

/*
 * The last surface answers of an owner's stars (env->memo): the side of a tet's mapped
 * circumcenter and the crossing of a facet's dual segment, keyed by the exact bits of
 * their inputs (the surface is a fixed function of them), direct-mapped, overwritten on
 * collision. A hit returns the very bits the surface would compute, so the stars do not
 * depend on what the memo holds (determinism).
 * design: the optimiser rebuilds the ~9 stars around a site for each position it tries
 * (DESIGN.md 4.9); most of their tets and facets do not touch the moved site and come out
 * of del3 with the same vertices in the same order, hence the same circumcenters: on
 * knot1 64% of the side questions and 38% of the crossing ones are repeats, and each is a
 * BVH walk on a polyhedral surface. Many repeats are far apart (the same star rebuilt for
 * the moves of two of its neighbours): hits on knot1 were 14% / 11% of the side /
 * crossing questions with 2^12 entries, 17% / 13% with 2^14, 23% / 18% with 2^16, 45% /
 * 27% with 2^19; 2^14 costs 2.2 MB, once per owner that moves sites.
 */
#define AS_STAR_MEMO_BITS 14
typedef struct as_star_memo_side {
    double x[3];
    int side;  /* 0: empty slot */
} as_star_memo_side;
typedef struct as_star_memo_cross {
    double in[9]; /* a, b, ref */
    double c[3];
    int used;
} as_star_memo_cross;

/* Scratch shared by every star of one owner (never per star). */
typedef struct as_star_scratch {
    as_del3_buf tets, faces;
    as_rfacet *old;
    int32_t nold, cap_old;
    /* design: the working triangulation: a star is unpacked into it for one operation and
     * packed back after (see as_star), so its arrays and its insertion scratch (stack,
     * cavity faces, edge tables with the 16 KB direct table, created/removed lists) exist
     * once per owner, not once per star */
    as_del3 work;
    int work_init;
    /* the working arrays of the star being modified (lent to it, see as_star) */
    as_rfacet *rf;
    int32_t cap_rf;
    int32_t *itet;
    int32_t cap_itet;
    double *isph;
    int32_t cap_isph;
    uint8_t *tflag;
    size_t cap_tflag;
    /* the packed filter balls of the open star (its previous incident tets'), for its
     * close: the balls of tets an update did not change are kept, not recomputed (per
     * incident tet, sprev: the index of its ball there; sph_fresh 0: no update) */
    float *fsph;
    size_t cap_fsph;
    int sph_fresh;
    int probe;          /* as_star_probe: the facets' triples only (no surface centers) */
    double *pball;      /* as_star_probe: the filter balls of v's current tets (tet_sphere) */
    int32_t cap_pball;
    int32_t *sprev;
    int32_t cap_sprev;
    /* star_update: per tet slot, its index in the previous incident list (-1 between
     * updates) */
    int32_t *slot;
    int32_t cap_slot;
    /* env->memo: 2^AS_STAR_MEMO_BITS entries each (allocated at the first use) */
    as_star_memo_side *mside;
    as_star_memo_cross *mcross;
    /* design: the working triangulation still holds the star this scratch packed last
     * (work_star, NULL: none) until another star is opened here; when that star is
     * opened again here unchanged (its pack_sc and pack_serial are this scratch's last
     * close, with the same points: frame F, point array and override), star_open keeps
     * the work as it is instead of unpacking: the same records bit for bit (a star
     * growing in rounds of insertions and conflict tests is opened again right after
     * each close) */
    const as_star *work_star;
    uint64_t serial; /* closes so far */
    double work_f[9];
    const double *work_xyz;
    const as_star_ovr *work_ovr;
    as_star_ovr work_ovr_copy;
} as_star_scratch;

void as_star_scratch_free(anistar_context *ctx, as_star_scratch *s);

/* An empty star (allocates nothing). */
void as_star_init(as_star *st, anistar_context *ctx);
void as_star_destroy(anistar_context *ctx, as_star *st);

/*
 * (Re)build star st of site gid in the frame mf: corners[24] (ids 0-7), then v; restricted
 * facets are computed (none usually). Returns OK, ENOMEM, EINVAL/ENOSURFACE from the
 * surface, EINTERNAL (a del3 failure).
 */
anistar_status as_star_build(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                             int32_t gid, as_star_scratch *sc);

/*
 * as_star_build, then the sites seeds[0..n) inserted before the restricted facets are
 * computed: one update instead of two (the facets of the corners-only star are never
 * used). st->nv_base stays the count after corners and v, as with as_star_build. sc->nold
 * is 0 afterwards (a new star has no facets from before). Errors as as_star_build.
 */
anistar_status as_star_build_seeded(const as_star_env *env, as_star *st,
                                    const as_metric_frame *mf, int32_t gid,
                                    const int32_t *seeds, int32_t n, as_star_scratch *sc);

/*
 * Insert the sites gids[0..n) (points env->xyz) into star st, then recompute its
 * restricted facets, closed flag and box. sc->old/nold receive the restricted facets from
 * before (for the caller's diff). *changed (optional) = number of sites actually inserted
 * (duplicates are skipped). Errors as as_star_build.
 * design: del3 insertions; tets created get their flags reset; restricted facets from the
 *   facets incident to v (as_del3_vertex_facets) by the inside-parity test; centers reused
 *   when both tets of a facet survived (paper 5.3: a surface star changes only where its
 *   tets changed).
 */
anistar_status as_star_insert(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                              const int32_t *gids, int32_t n, as_star_scratch *sc,
                              int32_t *changed);

/*
 * The restricted facets star st would have with the sites gids[0..n) inserted, st itself
 * unchanged: st is unpacked into sc's working triangulation, the sites are inserted
 * there in the given order (nearest to v first is fastest), each only if it still
 * conflicts with a tet around v (the others cannot change v's tets), the facets are
 * recomputed where tets changed (as as_star_insert does), and nothing is packed back.
 * *rf, *nrf: the facets, sorted by (g0, g1, g2), in sc's scratch (valid until sc's next
 * use). The triangulation is unique (Delaunay with symbolic
 * perturbation), so the facets are those of a star built from scratch with st's sites
 * and these. Only their triples are computed: the new facets' surface centers are not
 * searched (c = v, r = 0). Errors as as_star_insert.
 */
anistar_status as_star_probe(const as_star_env *env, const as_star *st, const as_metric_frame *mf,
                             const int32_t *gids, int32_t n, as_star_scratch *sc,
                             const as_rfacet **rf, int32_t *nrf);

/*
 * Compact star st: rebuild it from scratch (freeing its arrays) from the corners, v, and
 * the sites seeds[0..n) (its current neighbours); the caller then grows it from the
 * kd-tree (as for a new star). sc->old receives the facets from before.
 */
anistar_status as_star_rebuild(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                               const int32_t *seeds, int32_t n, as_star_scratch *sc);

/*
 * Inflation of the surface balls in the conflict-zone test and box.
 * design: paper 5.3 says the conflict zone only shrinks as sites are inserted. That is
 * exact when S is a plane (q in B(x, |x - v|) is linear in x, and the new surface
 * centers lie in the convex hull of the old ones), only approximate on a curved S: a new
 * surface ball may bulge out of the old union and a site left out of T'_v then misses
 * from S_v (seen on tori with coarse r0). We test against the balls inflated by this
 * factor, AND require the exact conflict with a tet incident to v (necessary for any
 * change of S_v); inserting a superset of the needed sites into T'_v is harmless.
 */
#define AS_STAR_ZONE_INFLATE 1.5

/* Relative slack of the floating-point filters in front of exact tests (boxes, surface
 * ball distances): a filter may only let more candidates through, never fewer. */
#define AS_STAR_SLACK 1e-9

/* The inflated surface ball of facet f of a closed star with frame mf, in the stretched
 * frame: center z[0..2] = F_v c, radius z[3] (the conflict filter's; computed when needed,
 * not stored: 32 bytes per facet, the same numbers every time). */
static inline void as_star_zone_ball(const as_metric_frame *mf, const as_rfacet *f, double z[4]) {
    as_metric_apply(mf, f->c, z);
    z[3] = f->r * AS_STAR_ZONE_INFLATE * (1 + AS_STAR_SLACK);
}

/* 1 if st's conflict zone is the union of its inflated surface balls (paper 5.3): a
 * closed star not marked zfull. Otherwise its zone is its whole Delaunay region (the
 * union of the circumballs of its tets around v). */
#define AS_STAR_BALL_ZONE(st) ((st)->closed && !(st)->zfull)

/*
 * 1 if inserting the point p (global id gid, not in the star) may change star st's
 * surface star (DESIGN.md 4.4): p is in conflict (exact insphere) with a tet incident to
 * v, and, if AS_STAR_BALL_ZONE(st), p lies in some inflated surface ball
 * (|F_v(c - p)| < AS_STAR_ZONE_INFLATE r). 0 otherwise. *hint (optional) receives the
 * tet found in conflict: the start of the walk when p is then inserted (st->hint).
 */
int as_star_conflicts(const as_star *st, const as_metric_frame *mf, const double *xyz,
                      const double p[3], int64_t gid, int32_t *hint);
/* 1 if p (global id gid, not in the star) is in conflict (exact insphere) with a tet
 * incident to v, whatever the zone: p changes v's Delaunay star. */
int as_star_conflicts_delaunay(const as_star *st, const as_metric_frame *mf, const double *xyz,
                               const double p[3], int64_t gid, int32_t *hint);
/* Recompute st's zone box (st->lo, st->hi, and zr2 of a ball zone) from its current
 * facets and tets (packed: their spheres recomputed), after st->zfull changed. */
void as_star_rezone(as_star *st, const double *xyz, const as_metric_frame *mf);

/* Whether the facet with sorted ids g (incident to v) is a facet of st's triangulation
 * (*in_dt), and then its extent *ext: twice the larger distance (stretched frame) from v
 * to the circumcenters of its two tets, so that both circumballs lie in the ball of
 * radius *ext around v (+inf when a tet is infinite or the facet is absent). The star is
 * unpacked into sc for the walk and packed again. OK or ENOMEM. */
anistar_status as_star_facet_extent(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                    as_star_scratch *sc, const as_gid g[3], int *in_dt,
                                    double *ext);

/* The vertices of a packed star: their count, global ids and stored (stretched) points
 * (y = F_v q: xyz is every point by global id, mf the star's frame). */
static inline int32_t as_star_nv(const as_star *st) { return st->nv; }
static inline as_gid as_star_vertex_gid(const as_star *st, int32_t k) { return st->vgid[k]; }
/* The point of global id g as star st sees it (its override, else xyz's). */
static inline const double *as_star_xyz(const as_star *st, const double *xyz, as_gid g) {
    return st->ovr && g == st->ovr->gid ? st->ovr->p : xyz + 3 * (size_t)g;
}
static inline void as_star_point(const as_star *st, const double *xyz, const as_metric_frame *mf,
                                 int32_t k, double y[3]) {
    if (st->vx) {
        y[0] = st->vx[3 * (size_t)k];
        y[1] = st->vx[3 * (size_t)k + 1];
        y[2] = st->vx[3 * (size_t)k + 2];
    } else {
        as_metric_apply(mf, as_star_xyz(st, xyz, st->vgid[k]), y);
    }
}

/* Tet slot t of packed star st as del3's record r[8] (a free slot: r[0] AS_DEL3_DEAD, r[1]
 * its free-list link, the rest 0), and vertex k's incident tet. */
void as_star_tet(const as_star *st, int32_t t, int32_t r[8]);
int32_t as_star_vertex_tet(const as_star *st, int32_t k);

/* The sphere of the i-th incident tet of packed star st (frame mf) as an update computes
 * it (star.h, isph): center S[0..2], S[3] the squared radius bound or -1 / -2. */
void as_star_sphere(const as_star *st, const double *xyz, const as_metric_frame *mf, int32_t i,
                    double S[4]);

/* Repack star st (frame mf) with its points (env->keep_points must be set). ANISTAR_OK or
 * ENOMEM. */
anistar_status as_star_keep_points(const as_star_env *env, as_star *st, const as_metric_frame *mf,
                                   as_star_scratch *sc);

/* The index of the restricted facet with sorted ids g in st->rf, or -1. */
int32_t as_star_find(const as_star *st, const as_gid g[3]);

/* 1 if the facets rf[0..n) (all incident to v) form exactly one closed fan around v. */
int as_star_fan_closed(const as_rfacet *rf, int32_t n, int32_t v);

/* Radius-edge ratio of the triangle a, b, c in the frame mf (circumradius of F a, F b, F c
 * over its shortest edge); +inf for a degenerate triangle. The circumradius in r (opt). */
double as_radius_edge(const as_metric_frame *mf, const double a[3], const double b[3],
                      const double c[3], double *r);

#endif /* ANISTAR_STAR_H */
