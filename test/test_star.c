/*
 * test_star.c — one vertex star (lib/mesher/star.c) and the facet table of the star set
 * (lib/mesher/starset.c), against brute-force recomputations.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test_util.h"

#include "geom/del3.h"
#include "geom/metric.h"
#include "geom/predicates.h"
#include "mesher/star.h"
#include "mesher/starset.h"
#include "surface/field.h"
#include "surface/surface.h"

/* A random point on the unit sphere. */
static void sphere_point(tu_rng *r, double p[3]) {
    double n;
    do {
        for (int k = 0; k < 3; k++) p[k] = tu_rng_range(r, -1, 1);
        n = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    } while (n < 0.1 || n > 1);
    for (int k = 0; k < 3; k++) p[k] /= n;
}

/* A random metric frame: random orthonormal frame, eigenvalues of F in [1, amax]. */
static void random_frame(tu_rng *r, double amax, as_metric_frame *mf) {
    double u[9], a[3], b[3], c[3];
    sphere_point(r, a);
    sphere_point(r, b);
    double d = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for (int k = 0; k < 3; k++) b[k] -= d * a[k];
    double nb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    for (int k = 0; k < 3; k++) b[k] /= nb;
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
    memcpy(u, a, sizeof a);
    memcpy(u + 3, b, sizeof b);
    memcpy(u + 6, c, sizeof c);
    double e[3] = {tu_rng_range(r, 1, amax), tu_rng_range(r, 1, amax), tu_rng_range(r, 1, amax)};
    assert_int_equal(as_metric_frame_init(mf, (double[6]){0}), -1); /* sanity of the API */
    assert_int_equal(as_metric_frame_from_eigen(mf, u, e), 0);
}

static int cmp_tri(const void *a, const void *b) {
    const int32_t *x = a, *y = b;
    for (int k = 0; k < 3; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* Inside test of the unit sphere with bounding radius 1.25 (the builtin "sphere"), done
 * directly: strictly inside |x| < 1. */
static int inside_unit(const double x[3]) {
    return x[0] * x[0] + x[1] * x[1] + x[2] * x[2] < 1.0;
}

/* n points (malloc'd, ids 0..n-1): the 8 corners of the box [-2.5, 2.5]^3, then random
 * points of the unit sphere. */
static void sphere_sites(tu_rng *r, int32_t n, double **xyz_out, int64_t **ids_out) {
    double *xyz = malloc(3 * (size_t)n * sizeof *xyz);
    int64_t *ids = malloc((size_t)n * sizeof *ids);
    assert_non_null(xyz);
    assert_non_null(ids);
    for (int32_t c = 0; c < 8; c++) {
        for (int k = 0; k < 3; k++) xyz[3 * c + k] = (c >> k) & 1 ? 2.5 : -2.5;
        ids[c] = c;
    }
    for (int32_t i = 8; i < n; i++) {
        sphere_point(r, xyz + 3 * i);
        ids[i] = i;
    }
    *xyz_out = xyz;
    *ids_out = ids;
}

/*
 * Brute force: the facets incident to site v (index iv in pts) of the Delaunay
 * triangulation of F_v {corners, sites}, built from scratch by bulk insertion, whose two
 * tets have circumcenters (mapped back) on opposite sides of S. Sorted triples of ids.
 */
static size_t brute_restricted(anistar_context *ctx, const double *pts, const int64_t *ids,
                               int32_t n, int32_t iv, const as_metric_frame *mf, int32_t *out) {
    as_del3 d;
    as_del3_init(&d, ctx);
    int32_t *vx = malloc((size_t)n * sizeof *vx);
    assert_int_equal(as_del3_insert_points(&d, pts, ids, n, mf, vx, NULL), ANISTAR_OK);
    as_del3_buf faces = {0};
    assert_int_equal(as_del3_vertex_facets(&d, vx[iv], &faces), ANISTAR_OK);
    size_t m = 0;
    for (size_t k = 0; k < faces.n; k++) {
        int32_t f = faces.a[k], t1 = f >> 2, t2 = as_del3_mirror(&d, f) >> 2;
        double c1[3], c2[3], x1[3], x2[3];
        assert_int_equal(as_del3_circumcenter(&d, t1, c1), 0);
        assert_int_equal(as_del3_circumcenter(&d, t2, c2), 0);
        as_metric_unapply(mf, c1, x1);
        as_metric_unapply(mf, c2, x2);
        if (inside_unit(x1) == inside_unit(x2)) continue;
        int32_t *g = out + 3 * m;
        int q = 0;
        for (int j = 0; j < 4; j++)
            if (j != (f & 3)) g[q++] = (int32_t)d.gid[as_del3_tet_vertex(&d, t1, j)];
        for (int a = 0; a < 3; a++)
            for (int b = a + 1; b < 3; b++)
                if (g[b] < g[a]) {
                    int32_t t = g[a];
                    g[a] = g[b];
                    g[b] = t;
                }
        m++;
    }
    qsort(out, m, 3 * sizeof *out, cmp_tri);
    as_del3_buf_free(ctx, &faces);
    as_del3_destroy(&d);
    free(vx);
    return m;
}

static void test_restricted_vs_brute_force(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    tu_rng r = {12345};
    for (int trial = 0; trial < 24; trial++) {
        int32_t nsites = 8 + (int32_t)(tu_rng_u64(&r) % 40);
        int32_t n = 8 + nsites;
        double *xyz;
        int64_t *ids;
        sphere_sites(&r, n, &xyz, &ids);
        as_metric_frame mf;
        random_frame(&r, trial < 8 ? 1.0 + 1e-9 : 4.0, &mf);
        /* half the trials through the surface memo (star.h, as_star_memo) */
        as_star_env env = {ctx, s, xyz, 0, trial % 2};
        as_star_scratch sc;
        memset(&sc, 0, sizeof sc);
        as_star st;
        as_star_init(&st, ctx);
        int32_t v = 8;
        assert_int_equal(as_star_build(&env, &st, &mf, v, &sc), ANISTAR_OK);
        /* insert the others in a few random batches */
        int32_t *rest = malloc((size_t)nsites * sizeof *rest);
        int32_t nr = 0;
        for (int32_t i = 9; i < n; i++) rest[nr++] = i;
        for (int32_t i = nr - 1; i > 0; i--) {
            int32_t j = (int32_t)(tu_rng_u64(&r) % (uint64_t)(i + 1));
            int32_t t = rest[i];
            rest[i] = rest[j];
            rest[j] = t;
        }
        int32_t done = 0;
        while (done < nr) {
            int32_t b = 1 + (int32_t)(tu_rng_u64(&r) % 5);
            if (b > nr - done) b = nr - done;
            assert_int_equal(as_star_insert(&env, &st, &mf, rest + done, b, &sc, NULL), ANISTAR_OK);
            done += b;
        }
        int32_t *bf = malloc(3 * 64 * (size_t)n * sizeof *bf);
        size_t m = brute_restricted(ctx, xyz, ids, n, 8, &mf, bf);
        assert_int_equal((size_t)st.nrf, m);
        for (int32_t k = 0; k < st.nrf; k++) {
            assert_memory_equal(st.rf[k].g, bf + 3 * k, 3 * sizeof(int32_t));
            /* the surface center lies on S and is equidistant in M_v */
            const double *c = st.rf[k].c;
            double rc = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
            assert_true(fabs(rc - 1.0) <= 1e-10);
            for (int j = 0; j < 3; j++) {
                double dj = as_metric_dist(&mf, c, xyz + 3 * st.rf[k].g[j]);
                assert_true(fabs(dj - st.rf[k].r) <= 1e-8 * (1 + st.rf[k].r));
            }
        }
        /* with all sites inserted, a star of a well-spread sample is a closed fan iff its
         * link is a single cycle: cross-check the flag with the definition */
        assert_int_equal(st.closed, as_star_fan_closed(st.rf, st.nrf, v));
        free(bf);
        free(rest);
        as_star_destroy(ctx, &st);
        as_star_scratch_free(ctx, &sc);
        free(xyz);
        free(ids);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* as_star_probe: the facets of a star with more sites, the star itself unchanged. Stars of
 * the unit sphere's sites grown to half their sites; the probe with the other half gives
 * the brute-force restricted facets of all of them, leaves the packed star as it was
 * (facets, centers, version, block), and agrees with the star after a real insertion. */
static void test_probe_vs_brute_force(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    tu_rng r = {4242};
    as_star_scratch sc; /* one scratch for every trial, as a thread's workspace */
    memset(&sc, 0, sizeof sc);
    for (int trial = 0; trial < 24; trial++) {
        int32_t nsites = 10 + (int32_t)(tu_rng_u64(&r) % 60);
        int32_t n = 8 + nsites;
        double *xyz;
        int64_t *ids;
        sphere_sites(&r, n, &xyz, &ids);
        as_metric_frame mf;
        random_frame(&r, trial < 6 ? 1.0 + 1e-9 : 4.0, &mf);
        as_star_env env = {ctx, s, xyz, 0, trial % 2};
        as_star st;
        as_star_init(&st, ctx);
        int32_t half = nsites / 2, rest[128];
        for (int32_t i = 9; i < n; i++) rest[i - 9] = i;
        assert_int_equal(as_star_build_seeded(&env, &st, &mf, 8, rest, half - 1, &sc),
                         ANISTAR_OK);
        /* the star before the probe */
        const int32_t nrf0 = st.nrf;
        as_rfacet *rf0 = malloc(((size_t)nrf0 + 1) * sizeof *rf0);
        memcpy(rf0, st.rf, (size_t)nrf0 * sizeof *rf0);
        const uint32_t version0 = st.version;
        const void *blk0 = st.blk;
        void *bytes0 = malloc(st.blk_bytes + 1);
        memcpy(bytes0, st.blk, st.blk_bytes);
        const int32_t nmore = nsites - half;
        const as_rfacet *prf;
        int32_t pn;
        assert_int_equal(as_star_probe(&env, &st, &mf, rest + half - 1, nmore, &sc, &prf, &pn),
                         ANISTAR_OK);
        int32_t *bf = malloc(3 * 64 * (size_t)n * sizeof *bf);
        size_t m = brute_restricted(ctx, xyz, ids, n, 8, &mf, bf);
        assert_int_equal((size_t)pn, m);
        for (int32_t k = 0; k < pn; k++)
            for (int j = 0; j < 3; j++) assert_int_equal(prf[k].g[j], bf[3 * k + j]);
        /* the star is as it was */
        assert_int_equal(st.nrf, nrf0);
        assert_true(st.version == version0);
        assert_ptr_equal(st.blk, blk0);
        assert_memory_equal(st.blk, bytes0, st.blk_bytes);
        assert_null(st.d);
        for (int32_t k = 0; k < nrf0; k++) {
            assert_memory_equal(st.rf[k].g, rf0[k].g, sizeof rf0[k].g);
            assert_memory_equal(st.rf[k].c, rf0[k].c, sizeof rf0[k].c);
        }
        /* and inserting the sites for real gives the probe's triples */
        as_gid *ptri = malloc(3 * ((size_t)pn + 1) * sizeof *ptri);
        for (int32_t k = 0; k < pn; k++) memcpy(ptri + 3 * k, prf[k].g, 3 * sizeof *ptri);
        assert_int_equal(as_star_insert(&env, &st, &mf, rest + half - 1, nmore, &sc, NULL),
                         ANISTAR_OK);
        assert_int_equal(st.nrf, pn);
        for (int32_t k = 0; k < pn; k++)
            assert_memory_equal(st.rf[k].g, ptri + 3 * k, 3 * sizeof(as_gid));
        free(ptri);
        free(bf);
        free(bytes0);
        free(rf0);
        as_star_destroy(ctx, &st);
        free(xyz);
        free(ids);
    }
    as_star_scratch_free(ctx, &sc);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The surface memo (as_star_memo) changes no bit: a star built without it, then twice
 * with it (the second time from the memo's answers), on a polyhedral surface. */
static void test_memo_same_bits(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    assert_int_equal(as_mesh_surface_read(ctx, AS_TEST_DATA_DIR "/sphere_r0.5.off", &s),
                     ANISTAR_OK);
    tu_rng r = {777};
    for (int trial = 0; trial < 8; trial++) {
        int32_t n = 8 + 1 + 40;
        double *xyz = malloc(3 * (size_t)n * sizeof *xyz);
        for (int32_t c = 0; c < 8; c++)
            for (int k = 0; k < 3; k++) xyz[3 * c + k] = (c >> k) & 1 ? 1.5 : -1.5;
        for (int32_t i = 8; i < n; i++) {
            sphere_point(&r, xyz + 3 * i);
            for (int k = 0; k < 3; k++) xyz[3 * i + k] *= 0.5;
        }
        int32_t rest[40];
        for (int32_t i = 0; i < 40; i++) rest[i] = 9 + i;
        as_metric_frame mf;
        random_frame(&r, 3.0, &mf);
        as_star_scratch sc;
        memset(&sc, 0, sizeof sc);
        as_rfacet ref[256];
        int32_t nref = 0;
        for (int pass = 0; pass < 3; pass++) {
            as_star_env env = {ctx, s, xyz, 0, pass > 0};
            as_star st;
            as_star_init(&st, ctx);
            assert_int_equal(as_star_build(&env, &st, &mf, 8, &sc), ANISTAR_OK);
            for (int32_t done = 0; done < 40; done += 5)
                assert_int_equal(as_star_insert(&env, &st, &mf, rest + done, 5, &sc, NULL),
                                 ANISTAR_OK);
            assert_true(st.nrf > 0 && st.nrf <= 256);
            if (pass == 0) {
                nref = st.nrf;
                memcpy(ref, st.rf, (size_t)st.nrf * sizeof *ref);
            } else {
                assert_int_equal(st.nrf, nref);
                for (int32_t k = 0; k < nref; k++) {
                    assert_memory_equal(st.rf[k].g, ref[k].g, sizeof ref[k].g);
                    assert_memory_equal(st.rf[k].c, ref[k].c, sizeof ref[k].c);
                    assert_true(st.rf[k].r == ref[k].r);
                }
            }
            as_star_destroy(ctx, &st);
        }
        assert_non_null(sc.mside);
        as_star_scratch_free(ctx, &sc);
        free(xyz);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* A packed star is its triangulation, slot for slot (issue 15): a star built and grown in
 * batches against a del3 given the same points in the same order (same frame, same random
 * state): the same vertices (ids, recomputed stretched points, incident tets), the same
 * tet records and free list, in the three record formats (8, 12 and 32 bytes: stars of
 * 20, 150 and 400 sites) and with the points kept (as after an optimiser move); the
 * incident spheres recompute as del3's circumcenters, and the float balls contain them. */
static void test_packed_star_is_its_del3(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    tu_rng r = {777};
    const int32_t sizes[4] = {20, 150, 400, 20};
    int fmts_seen = 0;
    for (int trial = 0; trial < 4; trial++) {
        int32_t n = 9 + sizes[trial];
        double *xyz = malloc(3 * (size_t)n * sizeof *xyz);
        for (int32_t c = 0; c < 8; c++)
            for (int k = 0; k < 3; k++)
                xyz[3 * c + k] = ((c >> k) & 1 ? 2.5 : -2.5) + 0.01 * (c + k);
        for (int32_t i = 8; i < n; i++) sphere_point(&r, xyz + 3 * i);
        as_metric_frame mf;
        random_frame(&r, 3.0, &mf);
        as_star_env env = {ctx, s, xyz, trial == 3, 0};
        as_star_scratch sc;
        memset(&sc, 0, sizeof sc);
        as_star st;
        as_star_init(&st, ctx);
        as_del3 ref;
        as_del3_init(&ref, ctx);
        ref.no_sphere_cache = 1;
        assert_int_equal(as_star_build(&env, &st, &mf, 8, &sc), ANISTAR_OK);
        for (int32_t k = 0; k < 9; k++)
            assert_int_equal(as_del3_insert_frame(&ref, &mf, xyz + 3 * k, k, NULL), ANISTAR_OK);
        int32_t done = 9;
        while (done < n) {
            int32_t b = 1 + (int32_t)(tu_rng_u64(&r) % 7), ids[8];
            if (b > n - done) b = n - done;
            for (int32_t i = 0; i < b; i++) {
                ids[i] = done + i;
                int rc = as_del3_insert_frame(&ref, &mf, xyz + 3 * (done + i), done + i, NULL);
                assert_int_equal(rc, ANISTAR_OK);
            }
            assert_int_equal(as_star_insert(&env, &st, &mf, ids, b, &sc, NULL), ANISTAR_OK);
            done += b;
        }
        assert_null(st.d);
        assert_int_equal(st.nv, ref.nv);
        assert_int_equal(st.nt, ref.nt);
        assert_int_equal(st.nlive, ref.nlive);
        assert_int_equal(st.free_head, ref.free_head);
        assert_true((st.vx != NULL) == (trial == 3));
        fmts_seen |= 1 << st.fmt;
        for (int32_t k = 0; k < st.nv; k++) {
            double y[3];
            as_star_point(&st, xyz, &mf, k, y);
            assert_memory_equal(y, as_del3_point(&ref, k), sizeof y);
            assert_int_equal(as_star_vertex_gid(&st, k), ref.gid[k]);
            assert_int_equal(as_star_vertex_tet(&st, k), ref.vert[k].tet);
        }
        for (int32_t t = 0; t < st.nt; t++) {
            int32_t rec[8];
            as_star_tet(&st, t, rec);
            const int32_t *q = ref.tet + 8 * (size_t)t;
            if (q[0] == AS_DEL3_DEAD) {
                assert_int_equal(rec[0], AS_DEL3_DEAD);
                assert_int_equal(rec[1], q[1]);
            } else {
                assert_memory_equal(rec, q, sizeof rec);
            }
        }
        for (int32_t i = 0; i < st.nitet; i++) {
            double S[4], c[3];
            as_star_sphere(&st, xyz, &mf, i, S);
            if (as_del3_is_infinite(&ref, st.itet[i])) {
                assert_true(S[3] == -1);
                continue;
            }
            assert_int_equal(as_del3_circumcenter(&ref, st.itet[i], c), 0);
            assert_memory_equal(S, c, sizeof c);
            const float *F = st.fsph + 4 * (size_t)i;
            if (!(F[3] >= 0)) continue;
            /* the float ball around F_v v holds the sphere of radius sqrt(S[3]) */
            double e = 0;
            for (int k = 0; k < 3; k++) {
                double dk = st.fv[k] + (double)F[k] - S[k];
                e += dk * dk;
            }
            assert_true(sqrt(e) + sqrt(S[3]) <= (double)F[3]);
        }
        as_del3_destroy(&ref);
        as_star_destroy(ctx, &st);
        as_star_scratch_free(ctx, &sc);
        free(xyz);
    }
    assert_int_equal(fmts_seen, 7); /* wide, narrow and tiny all met */
    as_surface_free(s);
    anistar_context_free(ctx);
}

static void test_fan_closed(void **state) {
    (void)state;
    as_rfacet f[4];
    memset(f, 0, sizeof f);
    int32_t tri[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 1, 4}};
    for (int i = 0; i < 4; i++) memcpy(f[i].g, tri[i], sizeof tri[i]);
    assert_true(as_star_fan_closed(f, 4, 0));
    assert_false(as_star_fan_closed(f, 3, 0)); /* an open fan */
    int32_t two[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 1, 3}, {0, 4, 5}};
    for (int i = 0; i < 4; i++) memcpy(f[i].g, two[i], sizeof two[i]);
    assert_false(as_star_fan_closed(f, 4, 0)); /* a cycle and a stray facet */
}

/* The definition, independently: every facet holds v, every other vertex of the facets
 * lies on exactly two of them, and the link graph (one edge per facet) is connected. */
static int fan_closed_reference(const as_rfacet *f, int32_t n, as_gid v) {
    if (n < 3) return 0;
    as_gid a[128], b[128];
    for (int32_t i = 0; i < n; i++) {
        int m = 0, hv = 0;
        for (int k = 0; k < 3; k++) {
            if (f[i].g[k] == v) hv = 1;
            else if (m < 2) (m++ == 0 ? a : b)[i] = f[i].g[k];
            else return 0;
        }
        if (!hv || m != 2) return 0;
    }
    for (int32_t i = 0; i < n; i++) {
        const as_gid x[2] = {a[i], b[i]};
        for (int s = 0; s < 2; s++) {
            int deg = 0;
            for (int32_t j = 0; j < n; j++) deg += (a[j] == x[s]) + (b[j] == x[s]);
            if (deg != 2) return 0;
        }
    }
    /* connected: grow from facet 0 through shared link vertices */
    int reach[128] = {0}, grew = 1, cnt = 1;
    reach[0] = 1;
    while (grew) {
        grew = 0;
        for (int32_t i = 0; i < n; i++) {
            if (reach[i]) continue;
            for (int32_t j = 0; j < n && !reach[i]; j++)
                if (reach[j] && (a[i] == a[j] || a[i] == b[j] || b[i] == a[j] || b[i] == b[j])) {
                    reach[i] = 1;
                    cnt++;
                    grew = 1;
                }
        }
    }
    return cnt == n;
}

static int cmp_rfacet(const void *x, const void *y) {
    const as_rfacet *p = x, *q = y;
    for (int k = 0; k < 3; k++)
        if (p->g[k] != q->g[k]) return p->g[k] < q->g[k] ? -1 : 1;
    return 0;
}

/* as_star_fan_closed against the definition on random links (both of its paths: up to
 * 48 facets sorted, beyond scanned): cycles of 3 to 100 facets with shuffled labels and
 * v anywhere among them, and the same broken (a facet dropped, two cycles, a chord, a
 * facet without v, a vertex repeated). */
static void test_fan_closed_random(void **state) {
    (void)state;
    tu_rng r = {99};
    long closed = 0, open = 0;
    for (int trial = 0; trial < 4000; trial++) {
        int32_t len = 3 + (int32_t)(tu_rng_u64(&r) % 98);
        as_gid lab[128];
        for (int32_t i = 0; i < len + 2; i++) lab[i] = 10 + 3 * i;
        for (int32_t i = len + 1; i > 0; i--) { /* shuffle the labels */
            int32_t j = (int32_t)(tu_rng_u64(&r) % (uint64_t)(i + 1));
            as_gid t = lab[i];
            lab[i] = lab[j];
            lab[j] = t;
        }
        const as_gid v = lab[len + 1];
        as_rfacet f[130];
        memset(f, 0, sizeof f);
        int32_t n = 0;
        int split = (int)(tu_rng_u64(&r) % 6), cut = len >= 6 ? len / 2 : 0;
        for (int32_t i = 0; i < len; i++) {
            as_gid x = lab[i], y = lab[(i + 1) % len];
            if (split == 1 && cut && i == cut - 1) y = lab[0];    /* two cycles */
            if (split == 1 && cut && i == len - 1) x = lab[cut];
            f[n].g[0] = v;
            f[n].g[1] = x;
            f[n].g[2] = y;
            n++;
        }
        if (split == 2) n--;                                    /* a facet dropped */
        if (split == 3 && len >= 4) {                           /* a chord */
            f[n].g[0] = v;
            f[n].g[1] = lab[0];
            f[n].g[2] = lab[2];
            n++;
        }
        if (split == 4) f[tu_rng_u64(&r) % (uint64_t)n].g[0] = lab[len]; /* without v */
        if (split == 5 && n >= 4) f[1].g[1] = f[3].g[1];        /* a vertex repeated */
        for (int32_t i = 0; i < n; i++) as_sort_gid3(f[i].g);
        qsort(f, (size_t)n, sizeof *f, cmp_rfacet);
        int32_t m = 0; /* unique triples, as a star's facets are */
        for (int32_t i = 0; i < n; i++)
            if (m == 0 || cmp_rfacet(&f[m - 1], &f[i]) != 0) f[m++] = f[i];
        int want = fan_closed_reference(f, m, v);
        assert_int_equal(as_star_fan_closed(f, m, (int32_t)v), want);
        if (want) closed++;
        else open++;
    }
    assert_true(closed > 500 && open > 500); /* both answers exercised */
}

/* Random insertion sequences into a star set: after each insertion the table equals a
 * full rescan of every star (as_starset_check_table). */
static void test_facet_table_vs_rescan(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "sphere", &s), ANISTAR_OK);
    const char *specs[2] = {"euclidean", "shock"};
    for (int sp = 0; sp < 2; sp++) {
        assert_int_equal(as_field_from_spec(ctx, s, specs[sp], &f), ANISTAR_OK);
        for (int seq = 0; seq < 3; seq++) {
            tu_rng r = {(uint64_t)(777 + 31 * seq + 1000 * sp)};
            as_starset ss;
            assert_int_equal(as_starset_init(&ss, ctx, s, f), ANISTAR_OK);
            if (seq == 2) {
                /* with poles from a sample */
                double smp[3 * 64];
                for (int i = 0; i < 64; i++) sphere_point(&r, smp + 3 * i);
                assert_int_equal(as_starset_add_poles(&ss, smp, 64, 32), ANISTAR_OK);
                assert_true(ss.first_site > 8);
            }
            size_t maxinc = 0;
            for (int i = 0; i < 150; i++) {
                double p[3];
                sphere_point(&r, p);
                assert_int_equal(as_starset_insert(&ss, p, NULL), ANISTAR_OK);
                assert_int_equal(as_starset_check_table(&ss), ANISTAR_OK);
                if (ss.ninc > maxinc) maxinc = ss.ninc;
            }
            /* the anisotropic sequences do exercise inconsistencies (with the identity
             * metric every star is a piece of one Delaunay triangulation) */
            if (sp == 1) assert_true(maxinc > 0);
            as_starset_destroy(&ss);
        }
        as_field_free(f);
    }
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The 8 star corners enclose the box and are in general position: no 4 coplanar, by the
 * exact as_orient3d (checked against GMP in test_predicates), so no star frame, an affine
 * map, makes them coplanar and their insertions stay in the predicates' filters; for a
 * few surfaces. */
static void test_corners_generic(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    const char *names[3] = {"sphere", "torus", "ellipsoid"};
    for (int n = 0; n < 3; n++) {
        as_surface *s;
        as_field *f;
        assert_int_equal(as_implicit_builtin(ctx, names[n], &s), ANISTAR_OK);
        assert_int_equal(as_field_from_spec(ctx, s, "euclidean", &f), ANISTAR_OK);
        as_starset ss;
        assert_int_equal(as_starset_init(&ss, ctx, s, f), ANISTAR_OK);
        const double *x = ss.xyz;
        for (int c = 0; c < 8; c++)
            for (int k = 0; k < 3; k++) {
                double v = x[3 * c + k];
                if ((c >> k) & 1) assert_true(v >= ss.box_hi[k]);
                else assert_true(v <= ss.box_lo[k]);
                assert_true(ss.box_lo[k] < s->center[k] - s->radius);
                assert_true(ss.box_hi[k] > s->center[k] + s->radius);
            }
        int quads = 0;
        for (int a = 0; a < 8; a++)
            for (int b = a + 1; b < 8; b++)
                for (int c = b + 1; c < 8; c++)
                    for (int d = c + 1; d < 8; d++) {
                        assert_true(as_orient3d(x + 3 * a, x + 3 * b, x + 3 * c,
                                                x + 3 * d) != 0);
                        quads++;
                    }
        assert_int_equal(quads, 70);
        as_starset_destroy(&ss);
        as_field_free(f);
        as_surface_free(s);
    }
    anistar_context_free(ctx);
}

/* A metric on the torus R 5, r 1 that is nearly isotropic in the tangent plane (its two
 * tangent eigenvalues 1% apart) with a tangent frame that turns by 40 radians per radian
 * of azimuth, and a large normal eigenvalue. */
static int turning_frame(const double p[3], const double n[3], double m[6], void *user) {
    (void)user;
    double az = atan2(p[1], p[0]), a[3] = {-sin(az), cos(az), 0}, b[3];
    b[0] = n[1] * a[2] - n[2] * a[1];
    b[1] = n[2] * a[0] - n[0] * a[2];
    b[2] = n[0] * a[1] - n[1] * a[0];
    double th = 40 * az, u[3], v[3];
    for (int k = 0; k < 3; k++) {
        u[k] = cos(th) * a[k] + sin(th) * b[k];
        v[k] = -sin(th) * a[k] + cos(th) * b[k];
    }
    const double e1 = 0.04, e2 = 0.04 * 1.0201, en = 4; /* eigenvalues of M */
    int idx[6][2] = {{0, 0}, {0, 1}, {0, 2}, {1, 1}, {1, 2}, {2, 2}};
    for (int i = 0; i < 6; i++) {
        int r = idx[i][0], c = idx[i][1];
        m[i] = e1 * u[r] * u[c] + e2 * v[r] * v[c] + en * n[r] * n[c];
    }
    return 0;
}

/* The rotation floor (starset.c) is a function of S and of M, not of M's tangent frame:
 * where M is nearly isotropic in the tangent plane its frame is arbitrary (here it turns
 * 40 times as fast as the azimuth), and two points of the torus's outer equator whose
 * frames differ by 45 degrees get the same floored metric, raised by S's principal
 * curvatures (1 around the tube, 1/6 along the equator). When the floor was raised along
 * M's own frame, the first point was floored to |F u| 1.03 around the tube and 0.48 along
 * the equator, the second to 0.83 in both (the normal turns at the same rate along both
 * diagonals): gamma 1.75 between points 0.12 apart. */
static void test_rotation_floor_frame(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "torus,R=5,r=1", &s), ANISTAR_OK);
    assert_int_equal(as_field_custom(ctx, s, turning_frame, NULL, &f), ANISTAR_OK);
    as_starset ss;
    assert_int_equal(as_starset_init(&ss, ctx, s, f), ANISTAR_OK);
    ss.rot_r0 = 0.3;
    ss.rot_g = 1.5 - 1 / 1.5;
    const double az = atan(1.0) / 40; /* 45 degrees of the frame */
    const double p[2][3] = {{6, 0, 0}, {6 * cos(az), 6 * sin(az), 0}};
    as_metric_frame raw[2], fl[2];
    for (int i = 0; i < 2; i++) {
        double m[6], n[3];
        int sing = 0;
        assert_int_equal(as_surface_normal_at(ctx, s, p[i], n, &sing), ANISTAR_OK);
        assert_int_equal(as_field_eval(ctx, f, p[i], m), ANISTAR_OK);
        assert_int_equal(as_metric_frame_init(&raw[i], m), 0);
        assert_int_equal(as_starset_metric(&ss, p[i], &fl[i]), ANISTAR_OK);
        /* raised along the tube's circle (the normal turns at rate 1 there) far above
         * the raw 0.2, along the equator (rate 1/6) less */
        const double az_i = atan2(p[i][1], p[i][0]);
        double eq[3] = {-sin(az_i), cos(az_i), 0}, tube[3];
        tube[0] = n[1] * eq[2] - n[2] * eq[1];
        tube[1] = n[2] * eq[0] - n[0] * eq[2];
        tube[2] = n[0] * eq[1] - n[1] * eq[0];
        double lt = as_metric_dist(&fl[i], (const double[3]){0, 0, 0}, tube);
        double le = as_metric_dist(&fl[i], (const double[3]){0, 0, 0}, eq);
        print_message("point %d: |F tube| %.3f |F equator| %.3f (raw %.3f %.3f)\n", i, lt, le,
                      raw[i].e[0], raw[i].e[1]);
        assert_true(lt > 3 * raw[i].e[1]);
        assert_true(le > 1.2 * raw[i].e[1] && le < 0.8 * lt);
    }
    double g_raw = as_metric_distortion(&raw[0], &raw[1]);
    double g_fl = as_metric_distortion(&fl[0], &fl[1]);
    print_message("gamma between the points: raw %.4f, floored %.4f\n", g_raw, g_fl);
    /* the raw metrics differ by the normal's turn (0.02 rad, e_n / e_t = 10): 1.10 */
    assert_true(g_raw < 1.15);
    assert_true(g_fl < 1.05 && g_fl < g_raw);
    as_starset_destroy(&ss);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

/* The rotation floor is a continuous function of the point where S and the field are
 * smooth: on the flat top of the double torus's junction (the curvature field there is
 * its eps floor, isotropic in the tangent plane, with e_n about 42 times larger), the
 * normal's turn was measured by differences along M's tangent eigenvectors, which are
 * arbitrary where M is isotropic: sites 1e-4 apart were floored to 0.77 and 1.33, the
 * distortion rule cut facets 100 times below the metric's size (55,456 V at r0 0.2, no
 * end at r0 0.5). The floor now reads S from the surface (an implicit surface's own). */
static void test_rotation_floor_continuous(void **state) {
    (void)state;
    anistar_context *ctx = anistar_context_new(NULL);
    as_surface *s;
    as_field *f;
    assert_int_equal(as_implicit_builtin(ctx, "double_torus", &s), ANISTAR_OK);
    assert_int_equal(as_field_from_spec(ctx, s, "curvature", &f), ANISTAR_OK);
    as_starset ss;
    assert_int_equal(as_starset_init(&ss, ctx, s, f), ANISTAR_OK);
    ss.rot_r0 = 0.5;
    ss.rot_g = 1.5 - 1 / 1.5;
    as_metric_frame prev;
    double gmax = 1, rmin = INFINITY;
    for (int i = 0; i <= 40; i++) {
        double p[3] = {-0.067 + 1e-4 * i, 0.105, 0.11}, q[3], m[6];
        assert_int_equal(as_surface_project(ctx, s, p, q), ANISTAR_OK);
        as_metric_frame raw, fl;
        assert_int_equal(as_field_eval(ctx, f, q, m), ANISTAR_OK);
        assert_int_equal(as_metric_frame_init(&raw, m), 0);
        assert_int_equal(as_starset_metric(&ss, q, &fl), ANISTAR_OK);
        /* raised: the smallest eigenvalue of F above the raw field's */
        double r = fl.e[0] / raw.e[0];
        if (r < rmin) rmin = r;
        if (i > 0) {
            double g = as_metric_distortion(&prev, &fl);
            if (g > gmax) gmax = g;
        }
        prev = fl;
    }
    print_message("floored / raw smallest eigenvalue >= %.3f; gamma between neighbours <= %.5f\n",
                  rmin, gmax);
    assert_true(rmin > 1.2);
    assert_true(gmax < 1.01);
    as_starset_destroy(&ss);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fan_closed),
        cmocka_unit_test(test_fan_closed_random),
        cmocka_unit_test(test_packed_star_is_its_del3),
        cmocka_unit_test(test_corners_generic),
        cmocka_unit_test(test_restricted_vs_brute_force),
        cmocka_unit_test(test_probe_vs_brute_force),
        cmocka_unit_test(test_memo_same_bits),
        cmocka_unit_test(test_facet_table_vs_rescan),
        cmocka_unit_test(test_rotation_floor_frame),
        cmocka_unit_test(test_rotation_floor_continuous),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
