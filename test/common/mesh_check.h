/*
 * mesh_check.h — shared by the mesher tests (test_mesher, test_e2e): checks of a mesher
 * output that do not use the mesher's internal state, only the output mesh (vertices,
 * triangles, per-vertex tensors), the surface oracle, and the sites every star holds
 * besides the output vertices (the 8 box corners and the poles, paper 5.3).
 *
 * Every check adds what it finds to an mc_report (counts, worst values, the first
 * violation described) instead of asserting, so tests can also show that a damaged mesh
 * is caught. mc_assert_ok fails the current cmocka test with the first message.
 */
#ifndef ANISTAR_MESH_CHECK_H
#define ANISTAR_MESH_CHECK_H

#include <stddef.h>
#include <stdint.h>

#include "anistar.h"
#include "io/meshio.h"
#include "surface/surface.h"

/* The bounds of the run and what S is. */
typedef struct mc_limits {
    double r0, rho0, gamma0; /* the mesher's parameters */
    long long chi;           /* Euler characteristic of S (2 - 2 genus) */
    double on_tol;           /* how far (absolute length) an output vertex may be from S */
    double hmin;             /* the run's hmin (0: none): a facet it held is exempt from
                                r0 (its surface center within hmin of one of its vertices,
                                the mesher's criterion), and from rho0 and gamma0 when its
                                longest edge is below 2 A hmin (A the largest anisotropy
                                ratio of its vertex metrics: every facet the mesher holds
                                is, so the exemption never hides less than the mesher's) */
} mc_limits;

/* What the checks found. */
typedef struct mc_report {
    size_t failures;        /* violations found (0: everything holds) */
    char first[512];        /* the first violation, described (with MC_VERBOSE set in the
                             * environment, every violation is printed to stderr) */
    double rho_max;         /* largest radius-edge ratio over facets x vertex metrics */
    double r_max;           /* largest surface circumradius r_v(tau) of a star facet */
    double gamma_max;       /* largest distortion between two vertices of a facet */
    double dist_max;        /* largest distance from a vertex to S (as measured) */
    size_t stars_checked;   /* vertices whose star was rebuilt and compared */
    size_t orient_tested;   /* (star, triangle) pairs whose orientation was checked against the dual segment */
    size_t orient_unresolved; /* triangles left out of the outward-normal test: S unresolved over them */
    size_t specks_unsampled; /* restricted facets left out: their crossing is on a closed speck of S below hmin that no vertex samples */
    size_t stars_full;      /* of which rebuilt from every point (no local certificate) */
    size_t star_points_max; /* most points one local rebuild needed */
} mc_report;

void mc_report_init(mc_report *r);

/* Closed, oriented (outward) 2-manifold with Euler characteristic lim->chi, and
 * F = 2V - 2chi; as_topology_check on the arrays. */
void mc_check_topology(anistar_context *ctx, const as_trimesh *m, const mc_limits *lim,
                       mc_report *r);

/* Every facet's radius-edge ratio <= rho0 in the metric of each of its three vertices
 * (own computation: circumradius over shortest edge of the stretched triangle), and the
 * distortion between its vertices' metrics < gamma0. */
void mc_check_shape(const as_trimesh *m, const mc_limits *lim, mc_report *r);

/* Every vertex on S: for surfaces given by a function, |f| / |grad f| <= lim->on_tol;
 * for every kind, the distance to the surface's own projection of the vertex <= on_tol.
 * Outward as fidelity: at least 99% of the triangles over which S is resolved (S's
 * normals at their three vertices pairwise within 90 degrees) face as S's normal at the
 * projection of their centroid; the others are counted in r->orient_unresolved. */
void mc_check_on_surface(anistar_context *ctx, const as_surface *s, const as_trimesh *m,
                         const mc_limits *lim, mc_report *r);

/*
 * The independent star check, for every vertex i with i % stride == 0 (stride >= 1):
 * the Delaunay triangulation of F_i applied to {extra sites, output vertices} (global
 * ids: extra sites 0..nextra-1, then output vertices in output order, the ids the
 * mesher's symbolic perturbation uses) is rebuilt, and the dual-edge test with the
 * surface's side oracle gives i's restricted Delaunay star; it must equal the output
 * triangles incident to i. The surface circumradius r_i(tau) of each of its facets (the
 * M_i-distance from i to the crossing of the dual segment with S nearest the facet's
 * circumcenter, as the mesher defines it) must be < r0 (relative slack 1e-9: the
 * crossing is recomputed here, accurate to 1e-12 R, not copied), unless the crossing
 * lies within hmin of one of the facet's vertices (refinement is held there). Each output
 * triangle of i's star must face along its dual segment from the end inside S to the end
 * outside (the exact orientation test; r->orient_tested counts the pairs). Below the
 * resolution: a facet with a corner or pole, or beyond r0, whose crossing lies on an
 * unsampled speck (a closed piece of S within 2.125 hmin of it, found by a flood over the
 * signs of S on a grid of spacing hmin/4, that holds no output vertex) is left out when
 * an end of its dual segment is inside the speck, and otherwise not sized by that
 * crossing (r->specks_unsampled counts both): the contract leaves such pieces unmeshed.
 * design: the rebuild is local when that is provably the same: the K nearest output
 * vertices in the M_i distance (K = 48, doubled while needed) plus every extra site are
 * triangulated; when no vertex left out lies in or on the circumball of a tet around i
 * (only vertices within 2 rho_max of i can), those tets are empty in the full set, hence
 * Delaunay there, and they close around i: the star is the full triangulation's.
 * Otherwise K grows, up to every point.
 */
void mc_check_stars(anistar_context *ctx, const as_surface *s, const double *extra,
                    int32_t nextra, const as_trimesh *m, const mc_limits *lim, size_t stride,
                    mc_report *r);

/* All four checks above (stars with stride 1). */
void mc_check_all(anistar_context *ctx, const as_surface *s, const double *extra,
                  int32_t nextra, const as_trimesh *m, const mc_limits *lim, mc_report *r);

/* Fail the running cmocka test (naming what) when r holds a violation. */
void mc_assert_ok(const mc_report *r, const char *what);

#endif /* ANISTAR_MESH_CHECK_H */
