/*
 * starset.c — the star set: points, stars, facet table, indexes, Insert(p), poles
 * (DESIGN.md 4.4, paper 4.1 and 5.3). See starset.h.
 */
#include "mesher/starset.h"

#include "surface/field.h"

#include <math.h>
#include <string.h>

/* ---- points ------------------------------------------------------------------------ */

/* The per-id arrays share one block, the 8-byte ones first: their bytes for cap ids. */
static size_t points_bytes(size_t cap) {
    return cap * (sizeof(as_metric_frame) + 3 * sizeof(double) + 2 * sizeof(double) +
                  sizeof(as_star *) + sizeof(uint32_t) + sizeof(int32_t));
}

/* Point the per-id arrays into block blk laid out for cap ids. */
static void points_layout(as_starset *ss, char *blk, size_t cap) {
    ss->mf = (as_metric_frame *)(void *)blk;
    ss->xyz = (double *)(void *)(blk + cap * sizeof(as_metric_frame));
    ss->lfs = ss->xyz + 3 * cap;
    ss->ascale = ss->lfs + cap;
    ss->stars = (as_star **)(void *)(ss->ascale + cap);
    ss->ws.stamp = (uint32_t *)(void *)(ss->stars + cap);
    ss->scomp = (int32_t *)(void *)(ss->ws.stamp + cap);
    ss->env.xyz = ss->xyz;
}

/*
 * Room for need ids. design: one block for every per-id array, grown by half (not
 * doubled: a run ends on average a quarter, not half, above its ids) with one realloc
 * (the allocator may extend it in place, and a failure changes nothing); the arrays are
 * then moved up to their new offsets, the last first (memmove: they overlap).
 */
static anistar_status grow_points(as_starset *ss, int64_t need) {
    if (need < 0 || need > ss->max_ids)
        return as_fail(ss->ctx, ANISTAR_EINVAL,
                       "mesher: too many points (the limit of global ids is %ld: "
                       "docs/algorithm.md, memory)",
                       (long)ss->max_ids);
    if (need <= ss->cap) return ANISTAR_OK;
    size_t cap = ss->cap ? (size_t)ss->cap : 256;
    while (cap < (size_t)need) cap += cap / 2;
    if (cap > (size_t)ss->max_ids) cap = (size_t)ss->max_ids;
    size_t old = (size_t)ss->cap;
    char *blk = as_realloc(ss->ctx, ss->pblk, points_bytes(old), points_bytes(cap));
    if (!blk) return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (points)");
    /* the old arrays, in the grown block at their old offsets */
    points_layout(ss, blk, old);
    as_metric_frame *m0 = ss->mf;
    double *x0 = ss->xyz, *lf0 = ss->lfs, *as0 = ss->ascale;
    as_star **st0 = ss->stars;
    uint32_t *sp0 = ss->ws.stamp;
    int32_t *sc0 = ss->scomp;
    points_layout(ss, blk, cap);
    memmove(ss->scomp, sc0, old * sizeof *sc0);
    memmove(ss->ws.stamp, sp0, old * sizeof *sp0);
    memmove(ss->stars, st0, old * sizeof *st0);
    memmove(ss->ascale, as0, old * sizeof *as0);
    memmove(ss->lfs, lf0, old * sizeof *lf0);
    memmove(ss->xyz, x0, old * 3 * sizeof *x0);
    (void)m0; /* mf stays at offset 0 */
    for (size_t i = old; i < cap; i++) {
        ss->stars[i] = NULL;
        ss->ws.stamp[i] = 0;
        ss->lfs[i] = NAN;
        ss->scomp[i] = -1;
        ss->ascale[i] = 1;
    }
    ss->pblk = blk;
    ss->cap = (int32_t)cap;
    return ANISTAR_OK;
}

static void identity_frame(as_metric_frame *mf) {
    static const double u[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
    static const double e[3] = {1, 1, 1};
    (void)as_metric_frame_from_eigen(mf, u, e);
}

/* x^T M y for the symmetric M (m11 m12 m13 m22 m23 m33) */
static double as_sym3_quad(const double m[6], const double x[3], const double y[3]) {
    return m[0] * x[0] * y[0] + m[3] * x[1] * y[1] + m[5] * x[2] * y[2] +
           m[1] * (x[0] * y[1] + x[1] * y[0]) + m[2] * (x[0] * y[2] + x[2] * y[0]) +
           m[4] * (x[1] * y[2] + x[2] * y[1]);
}

/* The tangent frame of M at a point of normal n: t[0], t[1] the eigenvectors of M restricted
 * to the tangent plane (from the projection of a fixed axis where it is isotropic there, so
 * the frame is continuous but at the isolated points where that projection vanishes) */
static void tangent_frame(const double m[6], const double n[3], double t[2][3]) {
    double a[3] = {1, 0, 0}, t0[3], t1[3];
    if (fabs(n[0]) > 0.6) a[0] = 0, a[1] = 1;
    double dn = a[0] * n[0] + a[1] * n[1] + a[2] * n[2];
    for (int k = 0; k < 3; k++) t0[k] = a[k] - dn * n[k];
    double l = sqrt(t0[0] * t0[0] + t0[1] * t0[1] + t0[2] * t0[2]);
    for (int k = 0; k < 3; k++) t0[k] /= l;
    t1[0] = n[1] * t0[2] - n[2] * t0[1];
    t1[1] = n[2] * t0[0] - n[0] * t0[2];
    t1[2] = n[0] * t0[1] - n[1] * t0[0];
    double qa = as_sym3_quad(m, t0, t0), qb = as_sym3_quad(m, t0, t1), qc = as_sym3_quad(m, t1, t1);
    double ang = 0.5 * atan2(2 * qb, qa - qc), cs = cos(ang), sn = sin(ang);
    for (int k = 0; k < 3; k++) {
        t[0][k] = cs * t0[k] + sn * t1[k];
        t[1][k] = -sn * t0[k] + cs * t1[k];
    }
}

/* The eigenvalues (ascending) of the symmetric 2 x 2 [[a, b], [b, c]] and a unit
 * eigenvector of each (v[i] belongs to l[i]). */
static void sym2_eigen(double a, double b, double c, double l[2], double v[2][2]) {
    double mean = 0.5 * (a + c), r = hypot(0.5 * (a - c), b);
    double th = 0.5 * atan2(2 * b, a - c), cs = cos(th), sn = sin(th);
    l[0] = mean - r;
    l[1] = mean + r;
    v[1][0] = cs, v[1][1] = sn;
    v[0][0] = -sn, v[0][1] = cs;
}

/* The least f in (0, ej] with 2 r0 w (ej / f - f / ej) / f <= G; 0 when w is 0.
 * design: the left side is 2 r0 w (ej / f^2 - 1 / ej), decreasing in f and 0 at ej, so
 * the bound is met from f^2 = ej / (G / (2 r0 w) + 1 / ej) on, which lies below ej^2 (a
 * bisection of 60 steps found the same root: 3.6% of the torus's run) */
static double floor_value(double r0, double w, double ej, double G) {
    if (!(w > 0) || !isfinite(w)) return 0;
    double f = sqrt(ej / (G / (2 * r0 * w) + 1 / ej));
    return f < ej ? f : ej;
}

/* m += sum_ab d[a][b] t_a t_b^T (d symmetric 2 x 2, t two vectors). */
static void add_tangent(double m[6], double d[2][2], double t[2][3]) {
    double w[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            w[i][j] = 0;
            for (int a = 0; a < 2; a++)
                for (int b = 0; b < 2; b++) w[i][j] += d[a][b] * t[a][i] * t[b][j];
        }
    m[0] += w[0][0], m[1] += w[0][1], m[2] += w[0][2];
    m[3] += w[1][1], m[4] += w[1][2], m[5] += w[2][2];
}

/*
 * The rotation floor of the metric at p (the anisotropy that pays, issue 13): raises, in
 * place, M where its frame turns as one walks along S.
 * design: in the frame (t0, t1, n) of M at p (t_k the eigenvectors of M restricted to the
 * tangent plane, e_k = |F t_k|, e_n = |F n|), walking along a tangent direction the frame
 * turns; a turn by a small angle a that mixes a direction of eigenvalue e with one of
 * larger eigenvalue e_j makes F_p F_q^-1 a shear of amount x = a (e_j / e - e / e_j), whose
 * norm gamma satisfies gamma - 1 / gamma = x. A facet of the size the metric asks for spans
 * up to 2 r0 / e along a direction of eigenvalue e, so with w the rate of the turn along it
 * the distortion rule leaves it alone only if 2 r0 w (e_j / e - e / e_j) / e <= gamma0 -
 * 1 / gamma0 =: G. A smaller e asks for an elongation that the distortion rule then undoes
 * by cutting the facet (on the torus R 10, r 1 with the default curvature at r0 0.1 and
 * gamma0 1.5, 99% of the facets were sized by distortion and the mesh had 3.6 times the
 * paper's vertices): so e is raised to the least value meeting it (floor_value). Two turns:
 *  - the principal frame turning about the normal mixes t_k with the other tangent
 *    direction: walking along t_k, its rate is measured as the angle between t_j(p) and
 *    q's tangent vector nearest it, and e_k is raised along t_k, M <- M + (f^2 - e_k^2)
 *    t_k t_k^T (x is 0 where the tangent eigenvalues are equal: the frame's arbitrary
 *    turn there costs nothing);
 *  - the normal turning with S mixes a tangent direction with n: its rate along a tangent
 *    direction u is |S u|, S the shape operator, whose principal directions need not be
 *    M's. S is the surface's own (as_surface_frame_at: for an implicit surface from f's
 *    Hessian, exact); measuring it by the normal's differences along M's t0 and t1, as
 *    before session 20, made it depend on that frame, arbitrary where M is isotropic in
 *    the tangent plane (the flat top of the double torus's junction, where the field is
 *    its eps floor and e_n is 42 times larger: sites 1e-4 apart floored to 0.77 and 1.33,
 *    gamma 1.76 between them, 55,456 V at r0 0.2 and no end at r0 0.5); the differences
 *    remain for a surface without a frame. Along S's principal directions d_i (rates
 *    |kappa_i|) the floors f_i give
 *    the tensor Q = sum f_i^2 d_i d_i^T, and M's tangent part A becomes the intersection
 *    of A and Q (simultaneous reduction: A = L L^T, C = L^-1 Q L^-T = V diag(c) V^T,
 *    A <- L V diag(max(c, 1)) V^T L^T), whose unit disk is the largest of that family
 *    inside both. Raising along M's own t_k instead (as before session 19) made the
 *    floor depend on M's tangent frame, which is arbitrary where M's tangent eigenvalues
 *    are close: on the skull CT (curvature, r0 3) neighbours 2-4 units apart, their raw
 *    tangent eigenvalues within 6%, were floored to (0.19, 0.22) and (0.08, 0.22) in
 *    different frames, gamma 2-3 between them below hmin, and rule 3 inserted without
 *    end (73,543 V in 120 s, estimate 6,295; without the floor 2,991 V in 0.6 s).
 * The frame's rates come from the field itself, by differences: the frame at
 * q = proj(p + h t_k), h a twentieth of the span (at most 1e-2 R), built the same way
 * from M_q and the normal at q (measured only where e_k < e_j: elsewhere x is 0). Both
 * raises add positive semidefinite terms: M stays a metric, and the result is continuous
 * where M, S and the rates are.
 */
static anistar_status rotation_floor(const as_starset *ss, anistar_context *ctx, const double p[3],
                                     double m[6]) {
    /* S, the shape operator, and the normal: the surface's own frame where it has one (an
     * implicit surface: from f's Hessian, exact); where its curvature is not finite, S is
     * measured below by the normal's differences */
    as_surface_frame sf;
    anistar_status s = as_surface_frame_at(ctx, ss->surf, p, &sf);
    if (s == ANISTAR_EINVAL) { /* a curvature that is not finite: no own S */
        sf.singular = 1;
        s = ANISTAR_OK;
    }
    if (s != ANISTAR_OK) return s;
    const int own_s = !sf.singular;
    int sing = 0;
    double n[3];
    if (own_s)
        memcpy(n, sf.n, sizeof n);
    else if ((s = as_surface_normal_at(ctx, ss->surf, p, n, &sing)) != ANISTAR_OK || sing)
        return s;
    double t[2][3];
    tangent_frame(m, n, t);
    const double *fr[3] = {t[0], t[1], n};
    double e[3];
    for (int k = 0; k < 3; k++) e[k] = sqrt(fmax(as_sym3_quad(m, fr[k], fr[k]), 0));
    const double G = ss->rot_g, r0 = ss->rot_r0;
    double raise[2] = {0, 0};
    double dn[2][2]; /* dn[k][a]: the normal's turn along t_k, its component along t_a */
    int have = 0;    /* bit k: dn[k] measured */
    for (int k = 0; k < 2; k++) {
        if (!(e[k] > 0) || (own_s && !(e[k] < e[1 - k]))) continue; /* nothing to measure */
        const double *tk = t[k];
        double h = fmin(0.1 * r0 / e[k], 1e-2 * ss->surf->radius);
        double y[3] = {p[0] + h * tk[0], p[1] + h * tk[1], p[2] + h * tk[2]}, q[3];
        s = as_surface_project(ctx, ss->surf, y, q);
        if (s == ANISTAR_ENOSURFACE) continue;
        if (s != ANISTAR_OK) return s;
        double d = sqrt((q[0] - p[0]) * (q[0] - p[0]) + (q[1] - p[1]) * (q[1] - p[1]) +
                        (q[2] - p[2]) * (q[2] - p[2]));
        if (!(d > 0)) continue;
        double mq[6], nq[3], tq[2][3];
        int sq = 0;
        if ((s = as_field_eval(ctx, ss->field, q, mq)) != ANISTAR_OK) return s;
        if ((s = as_surface_normal_at(ctx, ss->surf, q, nq, &sq)) != ANISTAR_OK) return s;
        if (sq) continue;
        for (int a = 0; a < 2; a++)
            dn[k][a] = (t[a][0] * nq[0] + t[a][1] * nq[1] + t[a][2] * nq[2]) / d;
        if (isfinite(dn[k][0]) && isfinite(dn[k][1])) have |= 1 << k;
        const int j = 1 - k;
        if (!(e[k] < e[j])) continue;
        tangent_frame(mq, nq, tq);
        /* q's tangent vector nearest p's t_j */
        double c0 = fabs(tq[0][0] * t[j][0] + tq[0][1] * t[j][1] + tq[0][2] * t[j][2]);
        double c1 = fabs(tq[1][0] * t[j][0] + tq[1][1] * t[j][1] + tq[1][2] * t[j][2]);
        const double *sj = c0 >= c1 ? tq[0] : tq[1];
        double w = fabs(tk[0] * sj[0] + tk[1] * sj[1] + tk[2] * sj[2]) / d;
        double f = floor_value(r0, w, e[j], G);
        if (f > e[k]) raise[k] = f * f - e[k] * e[k];
    }
    double tr[2][2] = {{raise[0], 0}, {0, raise[1]}};
    add_tangent(m, tr, t);
    if (!(e[2] > 0)) return ANISTAR_OK;
    /* S's principal rates and directions in (t0, t1): the surface's own, or the normal's
     * differences along t0 and t1, symmetrised */
    double kap[2], dir[2][2];
    if (own_s) {
        for (int i = 0; i < 2; i++) {
            kap[i] = sf.k[i];
            for (int a = 0; a < 2; a++)
                dir[i][a] = t[a][0] * sf.d[3 * i] + t[a][1] * sf.d[3 * i + 1] +
                            t[a][2] * sf.d[3 * i + 2];
        }
    } else {
        if (have != 3) return ANISTAR_OK;
        sym2_eigen(dn[0][0], 0.5 * (dn[0][1] + dn[1][0]), dn[1][1], kap, dir);
    }
    double Q[2][2] = {{0, 0}, {0, 0}};
    for (int i = 0; i < 2; i++) {
        double f = floor_value(r0, fabs(kap[i]), e[2], G);
        for (int a = 0; a < 2; a++)
            for (int b = 0; b < 2; b++) Q[a][b] += f * f * dir[i][a] * dir[i][b];
    }
    /* A, M's tangent part (raised above), and its Cholesky factor L */
    double a00 = as_sym3_quad(m, t[0], t[0]), a01 = as_sym3_quad(m, t[0], t[1]);
    double a11 = as_sym3_quad(m, t[1], t[1]);
    if (!(a00 > 0)) return ANISTAR_OK;
    double l00 = sqrt(a00), l10 = a01 / l00, l11 = a11 - l10 * l10;
    if (!(l11 > 0)) return ANISTAR_OK;
    l11 = sqrt(l11);
    /* C = L^-1 Q L^-T (L^-1 = [[1/l00, 0], [-l10/(l00 l11), 1/l11]]) */
    double i00 = 1 / l00, i10 = -l10 / (l00 * l11), i11 = 1 / l11;
    double c00 = i00 * i00 * Q[0][0];
    double c01 = i00 * (i10 * Q[0][0] + i11 * Q[0][1]);
    double c11 = i10 * i10 * Q[0][0] + 2 * i10 * i11 * Q[0][1] + i11 * i11 * Q[1][1];
    double c[2], v[2][2];
    sym2_eigen(c00, c01, c11, c, v);
    if (!(c[1] > 1)) return ANISTAR_OK;
    /* the raise L V diag(max(c - 1, 0)) V^T L^T */
    double r[2][2] = {{0, 0}, {0, 0}};
    for (int i = 0; i < 2; i++) {
        if (!(c[i] > 1)) continue;
        double lv[2] = {l00 * v[i][0], l10 * v[i][0] + l11 * v[i][1]};
        for (int a = 0; a < 2; a++)
            for (int b = 0; b < 2; b++) r[a][b] += (c[i] - 1) * lv[a] * lv[b];
    }
    add_tangent(m, r, t);
    return ANISTAR_OK;
}

anistar_status as_starset_metric_in(const as_starset *ss, anistar_context *ctx, const double p[3],
                                    as_metric_frame *mf) {
    double m[6];
    anistar_status s = as_field_eval(ctx, ss->field, p, m);
    if (s != ANISTAR_OK) return s;
    if (as_metric_frame_init(mf, m) != 0)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "mesher: the metric at (%.17g, %.17g, %.17g) is not finite and positive "
                       "definite",
                       p[0], p[1], p[2]);
    /* design: hmin and hmax bound the metric itself (MMG's semantics): an eigenvalue e of
     * F asks for edges of r0/e, so e is clamped to [r0/hmax, r0/hmin] */
    if (ss->ecap_hi > 0 || ss->ecap_lo > 0) {
        double e[3], u[9];
        int changed = 0;
        memcpy(u, mf->u, sizeof u);
        for (int k = 0; k < 3; k++) {
            e[k] = mf->e[k];
            if (ss->ecap_hi > 0 && e[k] > ss->ecap_hi) {
                e[k] = ss->ecap_hi;
                changed = 1;
            }
            if (ss->ecap_lo > 0 && e[k] < ss->ecap_lo) {
                e[k] = ss->ecap_lo;
                changed = 1;
            }
        }
        if (changed && as_metric_frame_from_eigen(mf, u, e) != 0)
            return as_fail(ctx, ANISTAR_EINTERNAL,
                           "mesher: the clamped metric at (%.17g, %.17g, %.17g) is invalid",
                           p[0], p[1], p[2]);
    }
    /* design: the rotation floor after the clamp: it compares the eigenvalues the mesher
     * will use (a normal eigenvalue above r0/hmin would ask for floors the clamp then
     * undoes), and it raises an eigenvalue at most to a larger one, so the clamp holds */
    if (ss->rot_g > 0) {
        double m2[6];
        memcpy(m2, mf->m, sizeof m2);
        anistar_status sr = rotation_floor(ss, ctx, p, m2);
        if (sr != ANISTAR_OK) return sr;
        if (memcmp(m2, mf->m, sizeof m2) != 0 && as_metric_frame_init(mf, m2) != 0)
            return as_fail(ctx, ANISTAR_EINTERNAL,
                           "mesher: the metric raised at (%.17g, %.17g, %.17g) is invalid",
                           p[0], p[1], p[2]);
    }
    return ANISTAR_OK;
}

anistar_status as_starset_metric(as_starset *ss, const double p[3], as_metric_frame *mf) {
    return as_starset_metric_in(ss, ss->ctx, p, mf);
}

/* ---- facet table --------------------------------------------------------------------- */

/* design: the three ids mixed into one word (a multiply-xorshift per id), then the
 * murmur3 finalizer: any id width, no packing limit */
static inline size_t hash_key(const as_fkey *key) {
    uint64_t k = (uint64_t)key->g[0] * 0x9E3779B97F4A7C15ULL;
    k = (k ^ (k >> 29)) + (uint64_t)key->g[1] * 0xC2B2AE3D27D4EB4FULL;
    k = (k ^ (k >> 29)) + (uint64_t)key->g[2] * 0x165667B19E3779F9ULL;
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ULL;
    k ^= k >> 33;
    return (size_t)k;
}

as_ftab_entry *as_starset_lookup(const as_starset *ss, as_fkey key) {
    if (!ss->tab_cap) return NULL;
    size_t m = ss->tab_cap - 1, i = hash_key(&key) & m;
    for (;;) {
        as_ftab_entry *e = &ss->tab[i];
        if (!e->mask) return NULL;
        if (as_fkey_eq(&e->key, &key)) return e;
        i = (i + 1) & m;
    }
}

int as_starset_consistent(const as_starset *ss, as_fkey key, uint8_t mask) {
    return mask == 7 && key.g[0] >= ss->first_site;
}

static anistar_status tab_rehash(as_starset *ss, size_t cap) {
    as_ftab_entry *t = as_alloc_array(ss->ctx, cap, sizeof *t);
    if (!t) return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (facet table)");
    memset(t, 0, cap * sizeof *t);
    for (size_t i = 0; i < ss->tab_cap; i++) {
        as_ftab_entry *e = &ss->tab[i];
        if (!e->mask) continue;
        size_t j = hash_key(&e->key) & (cap - 1);
        while (t[j].mask) j = (j + 1) & (cap - 1);
        t[j] = *e;
    }
    as_free(ss->ctx, ss->tab, ss->tab_cap * sizeof *ss->tab);
    ss->tab = t;
    ss->tab_cap = cap;
    return ANISTAR_OK;
}

static anistar_status inc_add(as_starset *ss, as_ftab_entry *e) {
    if (ss->ninc >= (size_t)INT32_MAX)
        return as_fail(ss->ctx, ANISTAR_EINVAL,
                       "mesher: too many inconsistent facets (limit %d)", (int)INT32_MAX);
    if (ss->ninc == ss->cap_inc &&
        as_grow(ss->ctx, (void **)&ss->inc, &ss->cap_inc, ss->ninc + 1, sizeof *ss->inc))
        return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (inconsistent set)");
    e->incpos = (int32_t)ss->ninc;
    ss->inc[ss->ninc++] = e->key;
    return ANISTAR_OK;
}

static void inc_remove(as_starset *ss, as_ftab_entry *e) {
    size_t pos = (size_t)e->incpos;
    as_fkey last = ss->inc[--ss->ninc];
    if (pos != ss->ninc) {
        ss->inc[pos] = last;
        as_ftab_entry *o = as_starset_lookup(ss, last);
        o->incpos = (int32_t)pos;
    }
    e->incpos = -1;
}

/* Delete the entry at slot i (backward-shift deletion keeps probe chains intact). */
static void tab_delete(as_starset *ss, as_ftab_entry *e) {
    size_t m = ss->tab_cap - 1, i = (size_t)(e - ss->tab);
    size_t j = i;
    for (;;) {
        j = (j + 1) & m;
        if (!ss->tab[j].mask) break;
        size_t h = hash_key(&ss->tab[j].key) & m;
        /* can the entry at j move to i? yes if h is not in the cyclic range (i, j] */
        int move = (i <= j) ? (h <= i || h > j) : (h <= i && h > j);
        if (move) {
            ss->tab[i] = ss->tab[j]; /* the inconsistent set refers by key */
            i = j;
        }
    }
    memset(&ss->tab[i], 0, sizeof ss->tab[i]);
    ss->tab_n--;
}

static anistar_status push_newinc(as_starset *ss, as_fkey key) {
    if (ss->nnewinc == ss->cap_newinc &&
        as_grow(ss->ctx, (void **)&ss->newinc, &ss->cap_newinc, ss->nnewinc + 1,
                sizeof *ss->newinc))
        return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (events)");
    ss->newinc[ss->nnewinc++] = key;
    return ANISTAR_OK;
}

/* Set (on = 1) or clear the bit of star v in the entry of triple g. */
static anistar_status tab_bit(as_starset *ss, const as_gid g[3], int32_t v, int on) {
    as_fkey key = as_facet_key(g);
    int bit = g[0] == v ? 0 : g[1] == v ? 1 : 2;
    anistar_status s;
    as_ftab_entry *e = as_starset_lookup(ss, key);
    if (!e) {
        if (!on) return as_fail(ss->ctx, ANISTAR_EINTERNAL, "mesher: facet table out of sync");
        if ((ss->tab_n + 1) * 4 > ss->tab_cap * 3 || ss->tab_cap == 0) {
            if ((s = tab_rehash(ss, ss->tab_cap ? ss->tab_cap * 2 : 1024)) != ANISTAR_OK) return s;
        }
        size_t m = ss->tab_cap - 1, i = hash_key(&key) & m;
        while (ss->tab[i].mask) i = (i + 1) & m;
        e = &ss->tab[i];
        e->key = key;
        e->mask = 0;
        e->incpos = -1;
        e->queued = 0;
        ss->tab_n++;
    }
    uint8_t mask = on ? (uint8_t)(e->mask | (1u << bit)) : (uint8_t)(e->mask & ~(1u << bit));
    /* design: a mask of 0 marks an empty slot, so an entry that empties keeps its old
     * mask until tab_delete (inc_remove still looks other keys up through it) */
    if (mask) e->mask = mask;
    int now_inc = mask != 0 && !as_starset_consistent(ss, key, mask);
    int was_inc = e->incpos >= 0;
    if (now_inc && !was_inc) {
        if ((s = inc_add(ss, e)) != ANISTAR_OK) return s;
        if ((s = push_newinc(ss, key)) != ANISTAR_OK) return s;
    } else if (!now_inc && was_inc) {
        inc_remove(ss, e);
    }
    if (mask == 0) tab_delete(ss, e);
    return ANISTAR_OK;
}

static int cmp_g3(const as_gid a[3], const as_gid b[3]) {
    for (int k = 0; k < 3; k++)
        if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
    return 0;
}

static anistar_status push_event(as_starset *ss, int32_t v, const as_gid g[3]) {
    if (ss->nev == ss->cap_ev &&
        as_grow(ss->ctx, (void **)&ss->ev, &ss->cap_ev, ss->nev + 1, sizeof *ss->ev))
        return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (events)");
    as_fevent *e = &ss->ev[ss->nev++];
    e->star = v;
    memcpy(e->g, g, sizeof e->g);
    return ANISTAR_OK;
}

/* Apply the difference between old[0..nold) and star v's current facets (both sorted)
 * to the table; events for fresh facets; the star's box to the box index. */
static anistar_status apply_diff(as_starset *ss, int32_t v, const as_rfacet *old, int32_t nold) {
    as_star *st = ss->stars[v];
    anistar_status s;
    int32_t i = 0, j = 0;
    while (i < nold || j < st->nrf) {
        int c = i >= nold ? 1 : j >= st->nrf ? -1 : cmp_g3(old[i].g, st->rf[j].g);
        if (c < 0) {
            if ((s = tab_bit(ss, old[i].g, v, 0)) != ANISTAR_OK) return s;
            i++;
        } else if (c > 0) {
            if ((s = tab_bit(ss, st->rf[j].g, v, 1)) != ANISTAR_OK) return s;
            j++;
        } else {
            i++;
            j++;
        }
    }
    for (int32_t k = 0; k < st->nrf; k++)
        if (st->rf[k].fresh && (s = push_event(ss, v, st->rf[k].g)) != ANISTAR_OK) return s;
    if (!st->closed && !st->topo_queued) {
        if (ss->nopen == ss->cap_open &&
            as_grow(ss->ctx, (void **)&ss->open, &ss->cap_open, ss->nopen + 1, sizeof *ss->open))
            return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (events)");
        ss->open[ss->nopen++] = v;
        st->topo_queued = 1;
    }
    if ((s = as_boxindex_set(ss->ctx, ss->bi, v, st->lo, st->hi)) != ANISTAR_OK) return s;
    return ANISTAR_OK;
}

/* ---- lifetime ------------------------------------------------------------------------ */

static anistar_status set_threads(as_starset *ss, int n);

anistar_status as_starset_init(as_starset *ss, anistar_context *ctx, const as_surface *surf,
                               const as_field *field) {
    return as_starset_init_threads(ss, ctx, surf, field, 1);
}

anistar_status as_starset_init_threads(as_starset *ss, anistar_context *ctx,
                                       const as_surface *surf, const as_field *field,
                                       int threads) {
    memset(ss, 0, sizeof *ss);
    ss->max_ids = AS_STARSET_MAX_IDS;
    ss->ctx = ctx;
    ss->surf = surf;
    ss->field = field;
    ss->env.ctx = ctx;
    ss->env.surf = surf;
    anistar_status s;
    if ((s = set_threads(ss, threads)) != ANISTAR_OK) return s;
    if ((s = grow_points(ss, 1024)) != ANISTAR_OK) return s;
    double R = surf->radius, h = 2.0 * R;
    for (int k = 0; k < 3; k++) {
        ss->box_lo[k] = surf->center[k] - h;
        ss->box_hi[k] = surf->center[k] + h;
    }
    /* design: the corners of the box, each coordinate pushed out by its own fraction of h
     * (0 to 9.7%). Exact box corners make 4-point planes (the faces, in every frame:
     * coplanarity is affine invariant) and every star's first insertions go to the exact
     * predicates (3 times the cost of a star's corners). Pushed apart, no 4 are coplanar
     * (test_star checks it exactly), so the filters settle them. */
    for (int32_t c = 0; c < 8; c++) {
        for (int k = 0; k < 3; k++) {
            double push = h * (0.02 * ((c * 7 + k * 3) % 5) + 0.002 * c + 0.001 * k);
            ss->xyz[3 * c + k] = (c >> k) & 1 ? ss->box_hi[k] + push : ss->box_lo[k] - push;
        }
        identity_frame(&ss->mf[c]);
    }
    ss->n = 8;
    ss->first_site = 8;
    if ((s = as_kdtree_new(ctx, &ss->kd)) != ANISTAR_OK) return s;
    /* design: the three samples of the run's start (feature points, estimate, initial
     * sites) draw from the surface's one analysis of S (as_surface_sample: made by the
     * first sample, usually the metric's defaults, and kept in the surface); the sampler
     * only brings the pool to the crossings */
    if ((s = as_sampler_new(ctx, surf, ss->pool, &ss->sampler)) != ANISTAR_OK) return s;
    if ((s = as_feature_build(ctx, surf, ss->sampler, ss->pool, &ss->feat)) != ANISTAR_OK) return s;
    ss->alpha = AS_FEATURE_ALPHA;
    if ((s = as_boxindex_new(ctx, &ss->bi)) != ANISTAR_OK) return s;
    ss->ws.spare = as_alloc(ctx, sizeof *ss->ws.spare);
    if (!ss->ws.spare) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
    as_star_init(ss->ws.spare, ctx);
    return ANISTAR_OK;
}

/* Free a thread's workspace (its own stamp array, lists and spare star). */
static void ws_free(anistar_context *ctx, as_simws *w) {
    as_free(ctx, w->stamp, w->cap_stamp * sizeof *w->stamp);
    as_idlist_free(ctx, &w->cand);
    as_idlist_free(ctx, &w->ids);
    as_free(ctx, w->list, w->cap_list * sizeof *w->list);
    as_free(ctx, w->batch, w->cap_batch * sizeof *w->batch);
    as_free(ctx, w->hints, w->cap_hints * sizeof *w->hints);
    as_free(ctx, w->bdist, w->cap_bdist * sizeof *w->bdist);
    as_free(ctx, w->seeds, w->cap_seeds * sizeof *w->seeds);
    if (w->spare) {
        as_star_destroy(ctx, w->spare);
        as_free(ctx, w->spare, sizeof *w->spare);
    }
    memset(w, 0, sizeof *w);
}

void as_starset_destroy(as_starset *ss) {
    anistar_context *ctx = ss->ctx;
    if (!ctx) return;
    for (int32_t i = 0; i < ss->n; i++)
        if (ss->stars && ss->stars[i]) {
            as_star_destroy(ctx, ss->stars[i]);
            as_free(ctx, ss->stars[i], sizeof *ss->stars[i]);
        }
    if (ss->ws.spare) {
        as_star_destroy(ctx, ss->ws.spare);
        as_free(ctx, ss->ws.spare, sizeof *ss->ws.spare);
    }
    as_free(ctx, ss->pblk, points_bytes((size_t)ss->cap));
    as_feature_free(ctx, &ss->feat);
    as_free(ctx, ss->fix, ss->cap_fix * 4 * sizeof *ss->fix);
    as_free(ctx, ss->trouble, ss->cap_trouble * 4 * sizeof *ss->trouble);
    as_free(ctx, ss->tab, ss->tab_cap * sizeof *ss->tab);
    as_free(ctx, ss->inc, ss->cap_inc * sizeof *ss->inc);
    as_free(ctx, ss->ev, ss->cap_ev * sizeof *ss->ev);
    as_free(ctx, ss->newinc, ss->cap_newinc * sizeof *ss->newinc);
    as_free(ctx, ss->open, ss->cap_open * sizeof *ss->open);
    as_free(ctx, ss->ws.list, ss->ws.cap_list * sizeof *ss->ws.list);
    as_free(ctx, ss->ws.batch, ss->ws.cap_batch * sizeof *ss->ws.batch);
    as_free(ctx, ss->ws.bdist, ss->ws.cap_bdist * sizeof *ss->ws.bdist);
    as_free(ctx, ss->rebuild, ss->cap_rebuild * sizeof *ss->rebuild);
    as_free(ctx, ss->regrow, ss->cap_regrow * sizeof *ss->regrow);
    as_free(ctx, ss->regrow_box, ss->cap_regrow_box * 6 * sizeof *ss->regrow_box);
    as_free(ctx, ss->ws.hints, ss->ws.cap_hints * sizeof *ss->ws.hints);
    as_free(ctx, ss->ws.seeds, ss->ws.cap_seeds * sizeof *ss->ws.seeds);
    as_free(ctx, ss->keep, ss->cap_keep * sizeof *ss->keep);
    as_idlist_free(ctx, &ss->ws.cand);
    as_idlist_free(ctx, &ss->ws.ids);
    as_idlist_free(ctx, &ss->fids);
    as_star_scratch_free(ctx, &ss->sc);
    as_sampler_free(ctx, ss->sampler);
    if (ss->pool) {
        for (int t = 0; t < ss->nthreads; t++) {
            as_star_scratch_free(ctx, &ss->tsc[t]);
            as_free(ctx, ss->parena[t].f, ss->parena[t].cap * sizeof *ss->parena[t].f);
            ws_free(ctx, &ss->tws[t]);
        }
        as_free(ctx, ss->tws, (size_t)ss->nthreads * sizeof *ss->tws);
        as_free(ctx, ss->tenv, (size_t)ss->nthreads * sizeof *ss->tenv);
        as_free(ctx, ss->tsc, (size_t)ss->nthreads * sizeof *ss->tsc);
        as_free(ctx, ss->parena, (size_t)ss->nthreads * sizeof *ss->parena);
        as_free(ctx, ss->ptask, ss->cap_ptask * sizeof *ss->ptask);
        as_pool_free(ss->pool);
    }
    as_free(ctx, ss->btask, ss->cap_btask * sizeof *ss->btask);
    if (ss->kd) as_kdtree_free(ctx, ss->kd);
    if (ss->bi) as_boxindex_free(ctx, ss->bi);
    memset(ss, 0, sizeof *ss);
}

/* ---- poles ----------------------------------------------------------------------------- */

anistar_status as_starset_add_poles(as_starset *ss, const double *smp, int32_t n,
                                    int32_t max_poles) {
    anistar_context *ctx = ss->ctx;
    if (ss->n != ss->first_site || n < 5 || max_poles <= 0) return ANISTAR_OK;
    as_del3 d;
    as_del3_init(&d, ctx);
    as_del3_buf tets = {0};
    double *cand = NULL;
    size_t ncand = 0, cap_cand = 0;
    double *best = NULL;
    anistar_status s = as_del3_insert_points(&d, smp, NULL, n, NULL, NULL, NULL);
    if (s != ANISTAR_OK) goto done;
    if (!d.dim3) goto done;
    double margin = 0.25 * ss->surf->radius;
    for (int32_t v = 0; v < d.nv; v++) {
        if ((s = as_del3_vertex_tets(&d, v, &tets)) != ANISTAR_OK) goto done;
        const double *p = as_del3_point(&d, v);
        int hull = 0;
        double far[3] = {0, 0, 0}, fd = -1;
        for (size_t k = 0; k < tets.n; k++) {
            double c[3];
            if (as_del3_circumcenter(&d, tets.a[k], c)) {
                hull = 1;
                continue;
            }
            double dd = (c[0] - p[0]) * (c[0] - p[0]) + (c[1] - p[1]) * (c[1] - p[1]) +
                        (c[2] - p[2]) * (c[2] - p[2]);
            if (dd > fd) {
                fd = dd;
                memcpy(far, c, sizeof far);
            }
        }
        double dir[3];
        double out[2][3];
        int nout = 0;
        if (hull) {
            int sing = 0;
            if ((s = as_surface_normal_at(ctx, ss->surf, p, dir, &sing)) != ANISTAR_OK) goto done;
            if (sing) continue;
        } else {
            if (fd < 0) continue;
            for (int k = 0; k < 3; k++) dir[k] = far[k] - p[k];
            memcpy(out[nout++], far, sizeof far);
        }
        double od = -1, opp[3] = {0, 0, 0};
        for (size_t k = 0; k < tets.n; k++) {
            double c[3];
            if (as_del3_circumcenter(&d, tets.a[k], c)) continue;
            double w[3] = {c[0] - p[0], c[1] - p[1], c[2] - p[2]};
            if (w[0] * dir[0] + w[1] * dir[1] + w[2] * dir[2] >= 0) continue;
            double dd = w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
            if (dd > od) {
                od = dd;
                memcpy(opp, c, sizeof opp);
            }
        }
        if (od >= 0) memcpy(out[nout++], opp, sizeof opp);
        for (int q = 0; q < nout; q++) {
            int inside = 1;
            for (int k = 0; k < 3; k++)
                inside &= out[q][k] > ss->box_lo[k] + margin && out[q][k] < ss->box_hi[k] - margin;
            if (!inside) continue;
            if (ncand == cap_cand &&
                as_grow(ctx, (void **)&cand, &cap_cand, ncand + 1, 3 * sizeof *cand)) {
                s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (poles)");
                goto done;
            }
            memcpy(cand + 3 * ncand, out[q], 3 * sizeof(double));
            ncand++;
        }
    }
    if (ncand == 0) goto done;
    /* design: farthest-point sampling from candidate 0 keeps the poles spread out. */
    best = as_alloc_array(ctx, ncand, sizeof *best);
    if (!best) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (poles)");
        goto done;
    }
    for (size_t i = 0; i < ncand; i++) best[i] = INFINITY;
    size_t pick = 0;
    int32_t npoles = 0;
    while (npoles < max_poles) {
        const double *c = cand + 3 * pick;
        if ((s = grow_points(ss, (int64_t)ss->n + 1)) != ANISTAR_OK) goto done;
        int32_t g = ss->n++;
        memcpy(ss->xyz + 3 * (size_t)g, c, 3 * sizeof(double));
        identity_frame(&ss->mf[g]);
        if ((s = as_kdtree_insert(ctx, ss->kd, c, g)) != ANISTAR_OK) goto done;
        npoles++;
        best[pick] = -1;
        size_t nx = 0;
        double nd = -1;
        for (size_t i = 0; i < ncand; i++) {
            if (best[i] < 0) continue;
            const double *x = cand + 3 * i;
            double dd = (x[0] - c[0]) * (x[0] - c[0]) + (x[1] - c[1]) * (x[1] - c[1]) +
                        (x[2] - c[2]) * (x[2] - c[2]);
            if (dd < best[i]) best[i] = dd;
            if (best[i] > nd) {
                nd = best[i];
                nx = i;
            }
        }
        if (nd <= 0) break;
        pick = nx;
    }
    ss->first_site = ss->n;
done:
    as_free(ctx, best, ncand * sizeof *best);
    as_free(ctx, cand, cap_cand * 3 * sizeof *cand);
    as_del3_buf_free(ctx, &tets);
    as_del3_destroy(&d);
    return s;
}

/* ---- Insert(p) -------------------------------------------------------------------------- */

/* Candidates inserted per round of grow_star (nearest first); 2, 4, 8 and 16 measured on
 * the paper's torus: 4 and 8 are fastest, 16 is 40% slower, all of the first zone at once
 * 2.4 times slower. */
#define AS_STARSET_BATCH 4

/* A closed star whose zone reaches beyond sqrt(AS_STARSET_FAR_ZONE) times its first
 * search radius (twice v's nearest-site distance, in M_v) is searched by growing balls
 * like an open star (grow_star_box). */
#define AS_STARSET_FAR_ZONE 4.0

/* The reach of as_starset_verify_zones, in largest surface radii (see there). */
#define AS_STARSET_VERIFY_REACH 4.0

static anistar_status push_i32(anistar_context *ctx, int32_t **a, size_t *cap, size_t n,
                               int32_t x) {
    if (n == *cap && as_grow(ctx, (void **)a, cap, n + 1, sizeof **a))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
    (*a)[n] = x;
    return ANISTAR_OK;
}

/* Sort ids b[0..n) with their distances d[] by (distance, id): heapsort (n may be large on
 * a hostile input; deterministic, as the order is total). */
static void sort_by_dist(int32_t *b, double *d, size_t n) {
#define AS_SBD_LESS(i, j) (d[i] < d[j] || (d[i] == d[j] && b[i] < b[j]))
#define AS_SBD_SWAP(i, j)                                                                   \
    do {                                                                                    \
        int32_t tb = b[i];                                                                  \
        b[i] = b[j];                                                                        \
        b[j] = tb;                                                                          \
        double td = d[i];                                                                   \
        d[i] = d[j];                                                                        \
        d[j] = td;                                                                          \
    } while (0)
    for (size_t end = n, start = n / 2; end > 1;) {
        size_t root;
        if (start > 0) {
            root = --start; /* building the max-heap */
        } else {
            AS_SBD_SWAP(0, end - 1); /* the largest to the end */
            root = 0;
            end--;
        }
        for (size_t child; (child = 2 * root + 1) < end; root = child) {
            if (child + 1 < end && AS_SBD_LESS(child, child + 1)) child++;
            if (!AS_SBD_LESS(root, child)) break;
            AS_SBD_SWAP(root, child);
        }
    }
#undef AS_SBD_LESS
#undef AS_SBD_SWAP
}

/* A new epoch of workspace w's marks (cleared when the counter wraps). */
static uint32_t ws_epoch(as_starset *ss, as_simws *w) {
    if (++w->epoch == 0) {
        memset(w->stamp, 0, (w->cap_stamp ? w->cap_stamp : (size_t)ss->cap) * sizeof *w->stamp);
        w->epoch = 1;
    }
    return w->epoch;
}

static uint32_t next_epoch(as_starset *ss) { return ws_epoch(ss, &ss->ws); }

/*
 * Grow star st of center gid (frame mf) from the sites of the kd-tree in its conflict-zone
 * box until no candidate conflicts. Sites already stamped with ep are skipped (they are
 * in the star or were tested). p (id pid, not yet in the kd-tree) is not a candidate.
 * design (paper 5.3): one kd-tree query with the zone's box: the zone only shrinks as
 * sites are inserted, so later zones lie in it. Then rounds: drop (and stamp) the
 * candidates outside the current zone, insert the few nearest to v in M_v (ties by id) and
 * test the rest again against the smaller zone. Inserting every candidate of the first,
 * large zone at once would fill the star with sites its final zone does not hold (the
 * star's Delaunay work grows with them).
 */
/* The first search radius (in M_v) for the candidates of an open star: twice the distance
 * from v to its nearest site in the star, or 3 times its largest restricted facet radius
 * when it has no site yet; 0 when it has neither (no limit). A facet's radius can be far
 * larger than the spacing around v (its dual edge may cross S far away), and the ball
 * grows by doubling anyway. */
static double open_radius(const as_starset *ss, const as_star *st, const as_metric_frame *mf) {
    const double *c = as_star_xyz(st, ss->xyz, st->gid);
    double best = INFINITY;
    for (int32_t k = 0; k < as_star_nv(st); k++) {
        as_gid g = as_star_vertex_gid(st, k);
        if (g < 8 || g == st->gid) continue;
        double dd = as_metric_dist(mf, c, ss->xyz + 3 * (size_t)g);
        if (dd < best) best = dd;
    }
    if (isfinite(best) && best > 0) return 2 * best;
    double r = 0;
    for (int32_t i = 0; i < st->nrf; i++)
        if (st->rf[i].r > r) r = st->rf[i].r;
    return 3 * r;
}

/* The fresh facets of closed star st whose inflated surface ball is not inside the
 * inflated ball of one of the facets old[0..nold) it replaced (a sufficient test of
 * containment in their union): 1 and the box of those balls in lo, hi, or 0. */
static int zone_grew(const as_star *st, const as_metric_frame *mf, const as_rfacet *old,
                     int32_t nold, double lo[3], double hi[3]) {
    if (!AS_STAR_BALL_ZONE(st)) return 0;
    int grew = 0;
    for (int32_t i = 0; i < st->nrf; i++) {
        const as_rfacet *f = &st->rf[i];
        if (!f->fresh) continue;
        int in = 0;
        for (int32_t j = 0; j < nold && !in; j++)
            in = as_metric_dist(mf, f->c, old[j].c) + AS_STAR_ZONE_INFLATE * f->r <=
                 AS_STAR_ZONE_INFLATE * old[j].r;
        if (in) continue;
        double h[3];
        as_metric_ellipsoid_box(mf, f->r * AS_STAR_ZONE_INFLATE * (1 + 1e-9), h);
        for (int k = 0; k < 3; k++) {
            double a = f->c[k] - h[k], b = f->c[k] + h[k];
            if (!grew || a < lo[k]) lo[k] = a;
            if (!grew || b > hi[k]) hi[k] = b;
        }
        grew = 1;
    }
    return grew;
}

static anistar_status grow_star_box(as_starset *ss, as_simws *w, const as_star_env *env,
                                    as_star_scratch *sc, as_star *st, const as_metric_frame *mf,
                                    uint32_t ep, const double *box);

/* Grow star st of center gid (frame mf) on workspace w (the design: above open_radius);
 * box (lo then hi), when not NULL, replaces the first query's box. env and sc: the
 * environment and scratch of the thread that grows st (its context takes the allocations
 * and the errors); the star set's search lists and marks are lent to one growth at a
 * time. */
static anistar_status grow_star_box(as_starset *ss, as_simws *w, const as_star_env *env,
                                    as_star_scratch *sc, as_star *st, const as_metric_frame *mf,
                                    uint32_t ep, const double *box) {
    anistar_context *ctx = env->ctx;
    anistar_status s;
    const double *c = as_star_xyz(st, ss->xyz, st->gid);
    size_t nc = 0;
    int query = 1, limited = 0;
    double rho = 0;
    for (;;) {
        if (query) {
            /* design: an open star's zone is its whole Delaunay region, which reaches far
             * from S (to the box corners): its box holds a large part of all the sites.
             * Search it by growing M_v-balls around v instead (doubling the radius when a
             * ball holds no conflicting site), and query again after each round. A closed
             * star's zone is searched the same way when it reaches far beyond v's nearest
             * sites (a facet whose dual edge crosses S far away: its ball, inflated, can
             * hold thousands of sites that one nearby site would cut off), else its box
             * once. */
            double lo[3], hi[3];
            memcpy(lo, box ? box : st->lo, sizeof lo);
            memcpy(hi, box ? box + 3 : st->hi, sizeof hi);
            box = NULL;
            limited = 0;
            if (rho == 0) rho = open_radius(ss, st, mf);
            if (rho > 0 && (!AS_STAR_BALL_ZONE(st) || st->zr2 > AS_STARSET_FAR_ZONE * rho * rho)) {
                double h[3];
                as_metric_ellipsoid_box(mf, rho, h);
                for (int k = 0; k < 3; k++) {
                    if (c[k] - h[k] > lo[k]) {
                        lo[k] = c[k] - h[k];
                        limited = 1;
                    }
                    if (c[k] + h[k] < hi[k]) {
                        hi[k] = c[k] + h[k];
                        limited = 1;
                    }
                }
            }
            if ((s = as_kdtree_box_any(ctx, ss->kd, lo, hi, 0, &w->ids)) != ANISTAR_OK)
                return s;
            if (w->ids.n > w->cap_bdist &&
                as_grow(ctx, (void **)&w->bdist, &w->cap_bdist, w->ids.n,
                        sizeof *w->bdist))
                return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
            nc = 0;
            for (size_t k = 0; k < w->ids.n; k++) {
                int32_t q = w->ids.ids[k];
                if (w->stamp[q] == ep) continue;
                double dq = -1; /* M_v distance to v, computed when first needed */
                if (limited) {
                    /* beyond the ball: left for a larger radius (not stamped) */
                    dq = as_metric_dist(mf, c, ss->xyz + 3 * (size_t)q);
                    if (!(dq <= rho)) continue;
                }
                if ((s = push_i32(ctx, &w->batch, &w->cap_batch, nc, q)) != ANISTAR_OK)
                    return s;
                w->bdist[nc++] = dq;
            }
        }
        query = !AS_STAR_BALL_ZONE(st) || limited;
        size_t nb = 0;
        for (size_t k = 0; k < nc; k++) {
            int32_t q = w->batch[k];
            w->conflict_tests++;
            if (!as_star_conflicts(st, mf, ss->xyz, ss->xyz + 3 * (size_t)q, q, NULL)) {
                /* design: zones only shrink, so a site outside it now stays outside */
                w->stamp[q] = ep;
                continue;
            }
            double dq = w->bdist[k];
            if (dq < 0) dq = as_metric_dist(mf, c, ss->xyz + 3 * (size_t)q);
            w->batch[nb] = q;
            w->bdist[nb++] = dq;
        }
        nc = nb;
        if (nc == 0) {
            if (limited) {
                rho *= 2; /* nothing conflicts in this ball: a larger one */
                query = 1;
                continue;
            }
            return ANISTAR_OK;
        }
        size_t take = AS_STARSET_BATCH;
        if (nc > take) {
            int32_t *b = w->batch;
            double *bd = w->bdist;
            for (size_t i = 0; i < take; i++) {
                size_t best = i;
                for (size_t j = i + 1; j < nc; j++)
                    if (bd[j] < bd[best] || (bd[j] == bd[best] && b[j] < b[best])) best = j;
                int32_t t = b[i];
                b[i] = b[best];
                b[best] = t;
                double u = bd[i];
                bd[i] = bd[best];
                bd[best] = u;
            }
        } else {
            take = nc;
        }
        for (size_t k = 0; k < take; k++) w->stamp[w->batch[k]] = ep;
        const int was_closed = st->closed;
        if ((s = as_star_insert(env, st, mf, w->batch, (int32_t)take, sc, NULL)) !=
            ANISTAR_OK)
            return s;
        double glo[3], ghi[3];
        if (zone_grew(st, mf, sc->old, sc->nold, glo, ghi) || (was_closed && !st->closed)) {
            /* design: the zone grew (a new facet's dual edge crosses S far away, or the
             * star opened): the candidates rejected so far were rejected by a smaller
             * zone. Forget them (a new epoch, the star's own sites stamped again) and
             * search the whole current zone again. Without this, a site stamped early
             * stays out of the star while its far facet's surface ball holds it, and
             * rule 1 inserts that ball's center on the site (seen on the skull at
             * r0 = 4 when a star was compacted). */
            ep = ws_epoch(ss, w);
            for (int32_t k = 0; k < as_star_nv(st); k++) w->stamp[as_star_vertex_gid(st, k)] = ep;
            nc = 0;
            query = 1;
            box = NULL;
            continue;
        }
        /* the rest stays in the list, in order, for the next round */
        memmove(w->batch, w->batch + take, (nc - take) * sizeof *w->batch);
        memmove(w->bdist, w->bdist + take, (nc - take) * sizeof *w->bdist);
        nc -= take;
    }
}

/* The stars that p (id gid) conflicts with, into ss->ws.list; returns their count. */
static anistar_status conflicting_stars(as_starset *ss, as_simws *w, anistar_context *ctx,
                                        const double p[3], int32_t gid,
                                        size_t *count) {
    anistar_status s;
    *count = 0;
    if ((s = as_boxindex_query_point(ctx, ss->bi, p, &w->cand)) != ANISTAR_OK) return s;
    size_t nl = 0;
    for (size_t k = 0; k < w->cand.n; k++) {
        int32_t v = w->cand.ids[k];
        w->conflict_tests++;
        int32_t hint = -1;
        if (!as_star_conflicts(ss->stars[v], &ss->mf[v], ss->xyz, p, gid, &hint)) continue;
        if ((s = push_i32(ctx, &w->list, &w->cap_list, nl, v)) != ANISTAR_OK) return s;
        if ((s = push_i32(ctx, &w->hints, &w->cap_hints, nl, hint)) != ANISTAR_OK) return s;
        nl++;
    }
    *count = nl;
    return ANISTAR_OK;
}

/*
 * The seeds of the star of p (id gid) from the stars list[0..nl) that p conflicts with
 * (into ss->ws.batch, stamped with a new epoch: *ep_out, *nb_out); build_seeded then builds
 * and grows the star.
 * Seeds: the stars' centers, and
 *   - simulate = 0 (p is already a site of those stars): the vertices of their facets
 *     that contain p: p's neighbours as those stars see it;
 *   - simulate = 1 (p is in no star): the vertices of their facets whose inflated
 *     surface ball contains F_v p (every facet of an open star): the facets p destroys,
 *     whose vertices are p's neighbours-to-be.
 * design: the seeds close the surface star at once, so growth starts from the small zone
 * of a closed star and not from the whole Delaunay region of an open one. Seeds are only
 * a start: growth offers every site of the zone. (Seeding with every vertex of those
 * stars' surface stars, 20 sites for ~6 neighbours on the paper's torus, cost 25% more
 * instructions: bench_mesher torus,R=10,r=2 under callgrind.)
 */
static anistar_status star_seeds(as_starset *ss, as_simws *w, anistar_context *ctx,
                                 const double p[3], int32_t gid, size_t nl,
                                 int simulate, uint32_t *ep_out, size_t *nb_out) {
    anistar_status s;
    uint32_t ep = ws_epoch(ss, w);
    size_t nb = 0;
    w->stamp[gid] = ep;
    for (size_t k = 0; k < nl; k++) {
        int32_t v = w->list[k];
        if (w->stamp[v] != ep) {
            w->stamp[v] = ep;
            if ((s = push_i32(ctx, &w->batch, &w->cap_batch, nb++, v)) != ANISTAR_OK) return s;
        }
        const as_star *sv = ss->stars[v];
        double y[3] = {0, 0, 0};
        const int by_zone = simulate && AS_STAR_BALL_ZONE(sv);
        if (by_zone) as_metric_apply(&ss->mf[v], p, y);
        for (int32_t i = 0; i < sv->nrf; i++) {
            const as_gid *g = sv->rf[i].g;
            if (!simulate && g[0] != gid && g[1] != gid && g[2] != gid) continue;
            if (by_zone) {
                double z[4];
                as_star_zone_ball(&ss->mf[v], &sv->rf[i], z);
                double dx = y[0] - z[0], dy = y[1] - z[1], dz = y[2] - z[2];
                if (dx * dx + dy * dy + dz * dz > z[3] * z[3]) continue;
            }
            for (int j = 0; j < 3; j++) {
                int32_t q = g[j];
                if (q < 8 || w->stamp[q] == ep) continue;
                w->stamp[q] = ep;
                if ((s = push_i32(ctx, &w->batch, &w->cap_batch, nb++, q)) != ANISTAR_OK)
                    return s;
            }
        }
    }
    *ep_out = ep;
    *nb_out = nb;
    return ANISTAR_OK;
}

/* Build star st of gid (frame mf) from the nb seeds in ss->ws.batch (epoch ep: star_seeds),
 * then grow it; on env and sc (see grow_star_box). */
static anistar_status build_seeded(as_starset *ss, as_simws *w, const as_star_env *env,
                                   as_star_scratch *sc,
                                   as_star *st, const as_metric_frame *mf, int32_t gid,
                                   size_t nb, uint32_t ep) {
    anistar_status s;
    if ((s = as_star_build_seeded(env, st, mf, gid, w->batch, (int32_t)nb, sc)) != ANISTAR_OK)
        return s;
    w->star_builds++;
    return grow_star_box(ss, w, env, sc, st, mf, ep, NULL);
}

static anistar_status build_star(as_starset *ss, as_simws *w, const as_star_env *env,
                                 as_star_scratch *sc, as_star *st, const double p[3],
                                 int32_t gid, const as_metric_frame *mf, size_t nl, int simulate) {
    uint32_t ep;
    size_t nb;
    anistar_status s = star_seeds(ss, w, env->ctx, p, gid, nl, simulate, &ep, &nb);
    if (s != ANISTAR_OK) return s;
    return build_seeded(ss, w, env, sc, st, mf, gid, nb, ep);
}

/* Position of triple g in the sorted facets keep[0..n), or -1. */
static int32_t find_keep(const as_rfacet *keep, int32_t n, const as_gid g[3]) {
    int32_t lo = 0, hi = n;
    while (lo < hi) {
        int32_t mid = lo + (hi - lo) / 2;
        int c = cmp_g3(keep[mid].g, g);
        if (c == 0) return mid;
        if (c < 0) lo = mid + 1;
        else hi = mid;
    }
    return -1;
}

/*
 * Star v anew, on workspace w (env, sc): regrown (compact = 0: offered the sites of box,
 * lo and hi where its zone grew, see zone_grew; NULL: its whole zone) or compacted
 * (compact = 1: rebuilt from its own vertices, then grown). Its facets from before are
 * appended to arena A (*off, *nold); the fresh flags are set, the queue flags of the
 * facets that survived a compaction kept. It reads only the star, the points and the
 * kd-tree: the table, the events and the counters are the caller's (restar_finish).
 */
static anistar_status restar_on(as_starset *ss, as_simws *w, const as_star_env *env,
                                as_star_scratch *sc, as_parena *A, int32_t v, const double *box,
                                int compact, size_t *off, int32_t *nold) {
    anistar_context *ctx = env->ctx;
    as_star *st = ss->stars[v];
    anistar_status s;
    const int32_t nkeep = st->nrf;
    if (as_grow(ctx, (void **)&A->f, &A->cap, A->n + (size_t)nkeep, sizeof *A->f))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
    *off = A->n;
    *nold = nkeep;
    if (nkeep) memcpy(A->f + A->n, st->rf, (size_t)nkeep * sizeof *st->rf);
    A->n += (size_t)nkeep;
    const as_rfacet *keep = A->f + *off;
    uint32_t ep = ws_epoch(ss, w);
    if (compact) {
        size_t nb = 0;
        w->stamp[v] = ep;
        for (int32_t k = 0; k < nkeep; k++)
            for (int j = 0; j < 3; j++) {
                int32_t q = keep[k].g[j];
                if (q < 8 || w->stamp[q] == ep) continue;
                w->stamp[q] = ep;
                if ((s = push_i32(ctx, &w->batch, &w->cap_batch, nb, q)) != ANISTAR_OK) return s;
                nb++;
            }
        if ((s = as_star_rebuild(env, st, &ss->mf[v], w->batch, (int32_t)nb, sc)) != ANISTAR_OK)
            return s;
        box = NULL;
    } else {
        for (int32_t k = 0; k < as_star_nv(st); k++) w->stamp[as_star_vertex_gid(st, k)] = ep;
    }
    if ((s = grow_star_box(ss, w, env, sc, st, &ss->mf[v], ep, box)) != ANISTAR_OK) return s;
    if (compact) st->nv_base = st->nv;
    /* design: the queue flags of the facets that survived stay theirs (their entries are
     * still queued: the star update that recomputed a facet whose tets changed cleared
     * them, and take_entry then dropped the entry: on knot1 with the graded default field
     * a facet with r 1.2% above r0 was left so, and the run ended "certified" with it);
     * a survivor whose surface center moved (the grown or rebuilt star gave its dual
     * segment other ends) is an event like a new facet, as its rules' verdicts may have
     * changed; the others are new since before (events) */
    for (int32_t k = 0; k < st->nrf; k++) {
        as_rfacet *f = &st->rf[k];
        int32_t o = find_keep(keep, nkeep, f->g);
        if (o >= 0) f->queued = keep[o].queued;
        f->fresh = o < 0 || f->r != keep[o].r ||
                   memcmp(f->c, keep[o].c, sizeof f->c) != 0;
    }
    return ANISTAR_OK;
}

/* Regrow or compact star v on the caller's workspace, then apply the difference. */
static anistar_status restar(as_starset *ss, int32_t v, const double *box, int compact) {
    as_parena A = {ss->keep, 0, ss->cap_keep};
    size_t off = 0;
    int32_t nold = 0;
    anistar_status s = restar_on(ss, &ss->ws, &ss->env, &ss->sc, &A, v, box, compact, &off, &nold);
    ss->keep = A.f;
    ss->cap_keep = A.cap;
    if (s != ANISTAR_OK) return s;
    if (compact) ss->star_rebuilds++;
    else ss->zone_regrowths++;
    return apply_diff(ss, v, ss->keep + off, nold);
}

/* Offer star v the sites of box (lo, hi: where its zone grew, see zone_grew) and apply
 * the difference with its facets from before. */
static anistar_status regrow_star(as_starset *ss, int32_t v, const double *box) {
    return restar(ss, v, box, 0);
}

/* Record that star st is right within reach with the sites so far. */
static anistar_status verified(as_starset *ss, as_star *st, double reach) {
    st->vz_version = st->version;
    st->vz_n = ss->n;
    st->vz_reach = reach;
    return ANISTAR_OK;
}

/*
 * Whether closed star v (on its ball zone) has the restricted facets it would have with
 * every site: *wrong = 1 when not. design: the sites within M_v distance `reach` of v
 * that conflict with the star are inserted into the spare star with the star's own
 * sites. A facet whose surface ball (centre x on S, radius r = |x - v|) lies within the
 * reach (2 r <= reach) is decided there exactly: every site that could fall in its ball
 * is in the spare. So the star is wrong when it has a facet the spare lacks (its radius
 * is at most r_max, reach/4) or the spare has a decided facet the star lacks; a facet
 * of the spare beyond the reach is undecided and the reach is doubled past it (up to the
 * corner box, where every facet is decided).
 */
static anistar_status verify_star(as_starset *ss, as_simws *w, const as_star_env *env,
                                  as_star_scratch *sc, const as_kdtree *recent, int32_t v,
                                  double reach, double diag, int *wrong) {
    anistar_status s;
    anistar_context *ctx = env->ctx;
    as_star *st = ss->stars[v];
    const as_metric_frame *mf = &ss->mf[v];
    const double *c = ss->xyz + 3 * (size_t)v;
    *wrong = 0;
    /* verified before, unchanged since, and no new site within the reach then used:
     * still right */
    const int again = st->vz_reach > 0 && st->vz_version == st->version && reach <= st->vz_reach;
    if (again) reach = st->vz_reach;
    for (int first = 1;; first = 0) {
        uint32_t ep = ws_epoch(ss, w);
        for (int32_t k = 0; k < as_star_nv(st); k++) w->stamp[as_star_vertex_gid(st, k)] = ep;
        double h[3], lo[3], hi[3];
        as_metric_ellipsoid_box(mf, reach * (1 + 1e-9), h);
        int whole = 1; /* the reach's box holds the corner box */
        for (int k = 0; k < 3; k++) {
            lo[k] = c[k] - h[k];
            hi[k] = c[k] + h[k];
            if (lo[k] > ss->box_lo[k] || hi[k] < ss->box_hi[k]) whole = 0;
        }
        if (again && first) {
            /* the sites inserted since, from the tree of the recent sites when there is
             * one: still right if none lies in the reach (the sites the check reads) */
            if ((s = as_kdtree_box_any(ctx, recent ? recent : ss->kd, lo, hi, 0, &w->ids)) !=
                ANISTAR_OK)
                return s;
            int fresh = 0;
            for (size_t k = 0; k < w->ids.n && !fresh; k++) {
                int32_t q = w->ids.ids[k];
                fresh = q >= st->vz_n &&
                        (whole || as_metric_dist(mf, c, ss->xyz + 3 * (size_t)q) <= reach);
            }
            if (!fresh) return ANISTAR_OK;
        }
        if ((s = as_kdtree_box_any(ctx, ss->kd, lo, hi, 0, &w->ids)) != ANISTAR_OK)
            return s;
        /* the sites of the reach left out of the star that conflict with it */
        size_t nc = 0;
        for (size_t k = 0; k < w->ids.n; k++) {
            int32_t q = w->ids.ids[k];
            if (w->stamp[q] == ep) continue;
            const double *x = ss->xyz + 3 * (size_t)q;
            if (!whole && !(as_metric_dist(mf, c, x) <= reach)) continue;
            w->conflict_tests++;
            if (!as_star_conflicts_delaunay(st, mf, ss->xyz, x, q, NULL)) continue;
            if ((s = push_i32(ctx, &w->batch, &w->cap_batch, nc, q)) != ANISTAR_OK)
                return s;
            if (nc == w->cap_bdist &&
                as_grow(ctx, (void **)&w->bdist, &w->cap_bdist, nc + 1, sizeof *w->bdist))
                return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
            w->bdist[nc++] = as_metric_dist(mf, c, x);
        }
        if (nc == 0) return verified(ss, st, reach);
        sort_by_dist(w->batch, w->bdist, nc); /* nearest first: as_star_probe skips more */
        /* design: the star with those sites inserted (a probe of its own triangulation:
         * the same Delaunay star as one built from scratch, at the cost of the few tets
         * the sites change instead of every tet and facet of the star); when its facets
         * are the star's, nothing is undecided. Otherwise the spare star below decides. */
        {
            const as_rfacet *prf;
            int32_t pn;
            if ((s = as_star_probe(env, st, mf, w->batch, (int32_t)nc, sc, &prf, &pn)) !=
                ANISTAR_OK)
                return s;
            int same = pn == st->nrf;
            for (int32_t k = 0; same && k < pn; k++)
                same = memcmp(prf[k].g, st->rf[k].g, sizeof prf[k].g) == 0;
            if (same) return verified(ss, st, reach);
        }
        if (!w->spare) {
            w->spare = as_alloc(ctx, sizeof *w->spare);
            if (!w->spare) return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory");
            as_star_init(w->spare, ctx);
        }
        as_star *sp = w->spare;
        sp->ovr = NULL; /* a real star's sites (a simulation left its candidate) */
        size_t nseed = 0;
        for (int32_t k = 0; k < as_star_nv(st); k++) {
            int32_t g = (int32_t)as_star_vertex_gid(st, k);
            if (g < 8 || g == v) continue;
            if ((s = push_i32(ctx, &w->list, &w->cap_list, nseed++, g)) != ANISTAR_OK)
                return s;
        }
        for (size_t k = 0; k < nc; k++)
            if ((s = push_i32(ctx, &w->list, &w->cap_list, nseed++, w->batch[k])) !=
                ANISTAR_OK)
                return s;
        if ((s = as_star_build_seeded(env, sp, mf, v, w->list, (int32_t)nseed,
                                      sc)) != ANISTAR_OK)
            return s;
        /* the facets of either star that the other lacks; need: the reach that decides
         * every such difference (0: none undecided). A facet of the star that is not a
         * Delaunay facet of a subset of the sites is not one of all of them. */
        double need = 0;
        for (int pass = 0; pass < 2; pass++) {
            const as_star *a = pass ? sp : st, *b = pass ? st : sp;
            for (int32_t k = 0; k < a->nrf; k++) {
                if (as_star_find(b, a->rf[k].g) >= 0) continue;
                int in_dt;
                double ext;
                if ((s = as_star_facet_extent(env, sp, mf, sc, a->rf[k].g, &in_dt,
                                                &ext)) !=
                    ANISTAR_OK)
                    return s;
                if (!in_dt || whole || ext <= reach) {
                    *wrong = 1;
                    return ANISTAR_OK;
                }
                if (ext > need) need = ext;
            }
        }
        if (need == 0) return verified(ss, st, reach);
        reach = isfinite(need) ? need * (1 + 1e-6) : diag;
        if (reach > diag) reach = diag;
    }
}

/*
 * design (our departure from paper 5.3; docs/algorithm.md): a closed star takes as its
 * conflict zone the union of its inflated surface balls, on the paper's argument that a
 * site outside them leaves its restricted facets unchanged. The argument needs S to meet
 * v's Voronoi cell only in the disk around v that those balls cover, which an epsilon-
 * sample guarantees and a sample held by hmin does not: on a noisy image a speck of four
 * sites sits beside a sheet of S sampled coarser than the gap, the sheet crosses the
 * speck's cells far from their disks, and the sites of the sheet never enter the specks'
 * stars (the brain at Otsu's threshold: 111 stars whose restricted Delaunay star, rebuilt
 * from every vertex, held facets the output lacked). So when no rule applies, every star
 * the caller selects (need; all when NULL) that is still on the ball zone is compared
 * with its restricted star among the sites within a reach (verify_star); a star found
 * wrong keeps its whole Delaunay region as its zone from then on (zfull), is regrown, and
 * the refinement goes on. A per-star record (version, sites, reach) skips the stars
 * unchanged since they were found right.
 */
/* One star of the zone check (as_starset_verify_zones) on thread slot t. */
typedef struct vz_job {
    as_starset *ss;
    int32_t *sel;
    uint8_t *wrong;
    const as_kdtree *recent;
    double reach, diag;
    as_halt *halt;
} vz_job;

static anistar_status vz_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)tctx;
    vz_job *J = arg;
    if (J->halt && as_halt_due(J->halt)) return ANISTAR_OK; /* wrong[k] stays 0 */
    as_starset *ss = J->ss;
    int wrong = 0;
    anistar_status s = verify_star(ss, &ss->tws[t], &ss->tenv[t], &ss->tsc[t], J->recent,
                                   J->sel[k], J->reach, J->diag, &wrong);
    J->wrong[k] = (uint8_t)wrong;
    return s;
}

anistar_status as_starset_verify_zones(as_starset *ss, int (*need)(void *, int32_t), void *arg,
                                       as_halt *halt, size_t *opened) {
    anistar_status s = ANISTAR_OK;
    *opened = 0;
    size_t nsel = 0, cap = 0;
    int32_t *sel = NULL;
    uint8_t *wrong = NULL;
    as_kdtree *recent = NULL; /* the sites inserted since the stars' last checks */
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        as_star *st = ss->stars[v];
        if (!st || !AS_STAR_BALL_ZONE(st)) continue;
        if (need && !need(arg, v)) continue;
        if ((s = push_i32(ss->ctx, &sel, &cap, nsel, v)) != ANISTAR_OK) goto done;
        nsel++;
    }
    if (nsel == 0) goto done;
    wrong = as_alloc(ss->ctx, nsel);
    if (!wrong) {
        s = as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (zone check)");
        goto done;
    }
    /* the reach: a point x of S in v's cell has v as its nearest site, so |x - v| is at
     * most the distance from x to the sample, which the size rule bounds by the largest
     * surface radius r_max (up to the distortion between neighbouring metrics, taken as
     * 2); a site that changes v's surface star lies in a ball through v centred at such
     * an x: within 2 |x - v| <= 4 r_max of v */
    double rmax = 0;
    for (int32_t u = ss->first_site; u < ss->n; u++)
        for (int32_t k = 0; ss->stars[u] && k < ss->stars[u]->nrf; k++)
            if (ss->stars[u]->rf[k].r > rmax) rmax = ss->stars[u]->rf[k].r;
    const double diag = 4 * sqrt(3.0) * ss->surf->radius; /* the corner box's diagonal */
    /* design: a star found right before and unchanged since is checked again only if a
     * site inserted since lies in its reach. Those sites are few after the first check
     * (the brain: 145,000 such tests over five checks, a few hundred sites new at each),
     * so they get a tree of their own: a query of the whole tree returned ~500 sites per
     * star, most of them old. Built when they are at most a quarter of the sites. */
    int32_t m = ss->n;
    for (size_t k = 0; k < nsel; k++) {
        const as_star *st = ss->stars[sel[k]];
        if (st->vz_reach > 0 && st->vz_version == st->version && st->vz_n < m) m = st->vz_n;
    }
    if (m < ss->n && (size_t)(ss->n - m) <= (size_t)ss->n / 4) {
        size_t nr = (size_t)(ss->n - m);
        int32_t *ids = as_alloc(ss->ctx, nr * sizeof *ids);
        if (!ids) {
            s = as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (zone check)");
            goto done;
        }
        for (size_t k = 0; k < nr; k++) ids[k] = m + (int32_t)k;
        s = as_kdtree_build(ss->ctx, ss->xyz + 3 * (size_t)m, ids, nr, &recent);
        as_free(ss->ctx, ids, nr * sizeof *ids);
        if (s != ANISTAR_OK) goto done;
    }
    vz_job J = {ss, sel, wrong, recent, AS_STARSET_VERIFY_REACH * rmax, diag, halt};
    /* design: every selected star is checked first (in parallel with threads, each on its
     * thread's workspace: a check reads only its star and the sites), then the wrong ones
     * are opened and regrown in the stars' order (a regrowth changes only its own star,
     * so no check depends on another's regrowth) */
    if (ss->pool) {
        if ((s = as_starset_simulate_prepare(ss)) != ANISTAR_OK) goto done;
        s = as_pool_run(ss->pool, (int32_t)nsel, vz_task, &J);
        as_starset_collect_counts(ss);
    } else {
        for (size_t k = 0; k < nsel && s == ANISTAR_OK; k++) {
            if (halt && as_halt_due(halt)) break;
            int w = 0;
            s = verify_star(ss, &ss->ws, &ss->env, &ss->sc, recent, sel[k], J.reach, diag,
                            &w);
            wrong[k] = (uint8_t)w;
        }
    }
    /* design: a halted check opens nothing: the stars it did not reach are unjudged, and
     * the run stops with the consistent facets it has (issue 12's contract) */
    if (s != ANISTAR_OK || (halt && atomic_load(&halt->halted))) goto done;
    for (size_t k = 0; k < nsel; k++) {
        if (!wrong[k]) continue;
        /* the ball zone missed sites that change v's surface star: v takes its whole
         * Delaunay region from now on, and is grown over it */
        int32_t v = sel[k];
        as_star *st = ss->stars[v];
        (*opened)++;
        st->zfull = 1;
        as_star_rezone(st, ss->xyz, &ss->mf[v]);
        if ((s = regrow_star(ss, v, NULL)) != ANISTAR_OK) goto done;
    }
done:
    if (recent) as_kdtree_free(ss->ctx, recent);
    as_free(ss->ctx, sel, cap * sizeof *sel);
    as_free(ss->ctx, wrong, nsel);
    return s;
}

/* Rebuild star v from its neighbours and the kd-tree (as a new star), then apply the
 * difference with its facets from before. */
static anistar_status compact_star(as_starset *ss, int32_t v) { return restar(ss, v, NULL, 1); }

/* Whether star v's zone grew when a point entered it (its facets before in old[0..nold)):
 * zone_grew's box in zb; reads only the star (the threads of an insertion run it). */
static int entry_grew(const as_starset *ss, int32_t v, const as_rfacet *old, int32_t nold,
                      double zb[6]) {
    return zone_grew(ss->stars[v], &ss->mf[v], old, nold, zb, zb + 3);
}

/* Each thread slot's environment: the star set's (its points may have moved since:
 * grow_points) with the slot's context. */
static void thread_envs(as_starset *ss) {
    for (int t = 0; t < ss->nthreads; t++) {
        ss->tenv[t] = ss->env;
        ss->tenv[t].ctx = as_pool_context(ss->pool, t);
    }
}

static anistar_status set_threads(as_starset *ss, int n) {
    if (n < 1 || n > AS_POOL_MAX_THREADS)
        return as_fail(ss->ctx, ANISTAR_EINVAL, "threads must be in [1, %d], got %d",
                       AS_POOL_MAX_THREADS, n);
    if (ss->pool || n == 1) return ANISTAR_OK;
    anistar_status s = as_pool_new(ss->ctx, n, &ss->pool);
    if (s != ANISTAR_OK) return s;
    ss->tenv = as_alloc_array(ss->ctx, (size_t)n, sizeof *ss->tenv);
    ss->tsc = as_alloc_array(ss->ctx, (size_t)n, sizeof *ss->tsc);
    ss->parena = as_alloc_array(ss->ctx, (size_t)n, sizeof *ss->parena);
    ss->tws = as_alloc_array(ss->ctx, (size_t)n, sizeof *ss->tws);
    if (!ss->tenv || !ss->tsc || !ss->parena || !ss->tws) {
        as_free(ss->ctx, ss->tenv, (size_t)n * sizeof *ss->tenv);
        as_free(ss->ctx, ss->tsc, (size_t)n * sizeof *ss->tsc);
        as_free(ss->ctx, ss->parena, (size_t)n * sizeof *ss->parena);
        as_free(ss->ctx, ss->tws, (size_t)n * sizeof *ss->tws);
        ss->tenv = NULL;
        ss->tsc = NULL;
        ss->parena = NULL;
        ss->tws = NULL;
        as_pool_free(ss->pool);
        ss->pool = NULL;
        return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (threads)");
    }
    memset(ss->tsc, 0, (size_t)n * sizeof *ss->tsc);
    memset(ss->parena, 0, (size_t)n * sizeof *ss->parena);
    memset(ss->tws, 0, (size_t)n * sizeof *ss->tws);
    ss->nthreads = n;
    return ANISTAR_OK;
}

/* After p entered star v (its facets before in old[0..nold), was_closed: whether it was
 * closed before, grew and zb: entry_grew's answer): the table and the events, and the
 * star's zone regrowth or compaction queued for after p's own star (ss->regrow,
 * ss->rebuild). */
static anistar_status after_insert(as_starset *ss, int32_t v, const as_rfacet *old, int32_t nold,
                                   int was_closed, int grew, const double zb_in[6]) {
    as_star *sv = ss->stars[v];
    anistar_status s;
    ss->star_updates++;
    if ((s = apply_diff(ss, v, old, nold)) != ANISTAR_OK) return s;
    /* design: a star whose point count doubled since it was built holds points that
     * entered while its conflict zone was large; compact it after this insertion.
     * Rebuild it too when its zone grew: paper 5.3 says zones only shrink, but on a
     * curved or thin surface a new facet's dual edge can cross S far away, and the
     * sites of its surface ball were never offered to this star. */
    double zb[6];
    if (grew) memcpy(zb, zb_in, sizeof zb);
    if (!grew && was_closed && !sv->closed) {
        /* design: a closed star that opens (a facet lost) has a zone no longer bounded
         * by surface balls: the union of the circumballs of its tets around v, which
         * holds sites never offered to it while it was closed. Offer it that zone
         * (searched by growing balls, as any open star). */
        memcpy(zb, sv->lo, sizeof sv->lo);
        memcpy(zb + 3, sv->hi, sizeof sv->hi);
        grew = 1;
    }
    if (grew) {
        if ((s = push_i32(ss->ctx, &ss->regrow, &ss->cap_regrow, ss->nregrow, v)) !=
            ANISTAR_OK)
            return s;
        if (ss->nregrow + 1 > ss->cap_regrow_box &&
            as_grow(ss->ctx, (void **)&ss->regrow_box, &ss->cap_regrow_box,
                    ss->nregrow + 1, 6 * sizeof *ss->regrow_box))
            return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory");
        memcpy(ss->regrow_box + 6 * ss->nregrow, zb, sizeof zb);
        ss->nregrow++;
    }
    if (AS_STAR_BALL_ZONE(sv) && sv->nv > 24 && sv->nv > 2 * sv->nv_base) {
        if ((s = push_i32(ss->ctx, &ss->rebuild, &ss->cap_rebuild, ss->nrebuild, v)) !=
            ANISTAR_OK)
            return s;
        ss->nrebuild++;
    }
    return ANISTAR_OK;
}

/* One task of restars: star k of the regrowths or compactions. */
static anistar_status restar_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)tctx;
    as_starset *ss = arg;
    const int compact = ss->restar_compact;
    int32_t v = compact ? ss->rebuild[k] : ss->regrow[k];
    as_ptask *pt = &ss->ptask[k];
    pt->thread = t;
    return restar_on(ss, &ss->tws[t], &ss->tenv[t], &ss->tsc[t], &ss->parena[t], v,
                     compact ? NULL : ss->regrow_box + 6 * k, compact, &pt->off, &pt->nold);
}

/* The zone regrowths (compact = 0) or the compactions (1) queued by the insertions just
 * made, in their order. design: with threads, one task per star (each reads only its star,
 * the points and the kd-tree; no star is queued twice), then the table and the events in
 * the stars' order, as the serial loop has them. */
static anistar_status restars(as_starset *ss, int compact) {
    anistar_status s = ANISTAR_OK;
    const size_t n = compact ? ss->nrebuild : ss->nregrow;
    if (!ss->pool || n < 2) {
        for (size_t k = 0; k < n && s == ANISTAR_OK; k++)
            s = compact ? compact_star(ss, ss->rebuild[k])
                        : regrow_star(ss, ss->regrow[k], ss->regrow_box + 6 * k);
    } else {
        if (n > ss->cap_ptask &&
            as_grow(ss->ctx, (void **)&ss->ptask, &ss->cap_ptask, n, sizeof *ss->ptask))
            return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (parallel insertion)");
        if ((s = as_starset_simulate_prepare(ss)) != ANISTAR_OK) return s;
        for (int t = 0; t < ss->nthreads; t++) ss->parena[t].n = 0;
        ss->restar_compact = compact;
        s = as_pool_run(ss->pool, (int32_t)n, restar_task, ss);
        as_starset_collect_counts(ss);
        for (size_t k = 0; k < n && s == ANISTAR_OK; k++) {
            const as_ptask *pt = &ss->ptask[k];
            int32_t v = compact ? ss->rebuild[k] : ss->regrow[k];
            if (compact) ss->star_rebuilds++;
            else ss->zone_regrowths++;
            s = apply_diff(ss, v, ss->parena[pt->thread].f + pt->off, pt->nold);
        }
    }
    if (compact) ss->nrebuild = 0;
    else ss->nregrow = 0;
    return s;
}

anistar_status as_starset_insert(as_starset *ss, const double p[3], int32_t *gid_out) {
    /* design: a batch of one point (as_starset_insert_batch): its frame, the stars it
     * conflicts with (searched with the id it will get), then the batch's steps; with
     * threads, its star updates are the parallel tasks. (Building p's star at the same
     * time as the updates, seeded from the stars before p enters them as a simulation is,
     * gave other stars than the seeds do: the elephant's output then failed the
     * independent check's size test at one facet, whose surface center depends on sites
     * beyond its surface ball; not pursued.) */
    as_bpoint b;
    memset(&b, 0, sizeof b);
    memcpy(b.p, p, sizeof b.p);
    b.lfs = NAN;
    anistar_status s = as_starset_metric(ss, p, &b.mf);
    if (s != ANISTAR_OK) return s;
    size_t nl;
    if ((s = conflicting_stars(ss, &ss->ws, ss->ctx, p, ss->n, &nl)) != ANISTAR_OK) return s;
    b.list = ss->ws.list; /* borrowed: the batch reads them before the workspace is reused */
    b.hints = ss->ws.hints;
    b.nl = nl;
    s = as_starset_insert_batch(ss, &b, 1);
    if (s == ANISTAR_OK && gid_out) *gid_out = b.gid;
    return s;
}

/* ---- batches of insertions (issue 15) ------------------------------------------------- */

anistar_status as_starset_conflicts_on(as_starset *ss, int t, anistar_context *ctx,
                                       const double p[3], as_bpoint *b) {
    as_simws *w = t < 0 ? &ss->ws : &ss->tws[t];
    size_t nl;
    anistar_status s = conflicting_stars(ss, w, ctx, p, ss->n, &nl);
    if (s != ANISTAR_OK) return s;
    if ((nl > b->cap_list && as_grow(ctx, (void **)&b->list, &b->cap_list, nl, sizeof *b->list)) ||
        (nl > b->cap_hints &&
         as_grow(ctx, (void **)&b->hints, &b->cap_hints, nl, sizeof *b->hints)))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
    if (nl) {
        memcpy(b->list, w->list, nl * sizeof *b->list);
        memcpy(b->hints, w->hints, nl * sizeof *b->hints);
    }
    b->nl = nl;
    return ANISTAR_OK;
}

anistar_status as_starset_lfs_point(as_starset *ss, int t, anistar_context *ctx, as_bpoint *b) {
    as_simws *w = t < 0 ? &ss->ws : &ss->tws[t];
    int exact = 0;
    double lfs;
    b->lfs = NAN;
    anistar_status s = as_feature_lfs(ctx, &ss->feat, &b->mf, b->p, 0, &w->ids, &lfs, &exact);
    if (s == ANISTAR_OK && exact) b->lfs = lfs;
    return s;
}

void as_bpoint_free(anistar_context *ctx, as_bpoint *b) {
    as_free(ctx, b->list, b->cap_list * sizeof *b->list);
    as_free(ctx, b->hints, b->cap_hints * sizeof *b->hints);
    b->list = b->hints = NULL;
    b->cap_list = b->cap_hints = b->nl = 0;
}

/* One task of a batch's first step: insert site btask[k].gid into star btask[k].v (on
 * the thread's scratch; the star's facets before go to the thread's arena). */
static anistar_status binsert_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    as_starset *ss = arg;
    const as_btask *bt = &ss->btask[k];
    as_star *sv = ss->stars[bt->v];
    as_star_scratch *sc = &ss->tsc[t];
    as_ptask *pt = &ss->ptask[k];
    int32_t gid = bt->gid;
    pt->was_closed = sv->closed;
    sv->hint = bt->hint;
    anistar_status s = as_star_insert(&ss->tenv[t], sv, &ss->mf[bt->v], &gid, 1, sc, NULL);
    if (s != ANISTAR_OK) return s;
    as_parena *A = &ss->parena[t];
    if (as_grow(tctx, (void **)&A->f, &A->cap, A->n + (size_t)sc->nold, sizeof *A->f))
        return as_fail(tctx, ANISTAR_ENOMEM, "mesher: out of memory (parallel insertion)");
    if (sc->nold) memcpy(A->f + A->n, sc->old, (size_t)sc->nold * sizeof *A->f);
    pt->thread = t;
    pt->off = A->n;
    pt->nold = sc->nold;
    pt->grew = entry_grew(ss, bt->v, sc->old, sc->nold, pt->zb);
    A->n += (size_t)sc->nold;
    return ANISTAR_OK;
}

/* Build the star of point k of the batch on workspace w (env, sc). */
static anistar_status bstar_on(as_starset *ss, as_simws *w, const as_star_env *env,
                               as_star_scratch *sc, const as_bpoint *b) {
    anistar_context *ctx = env->ctx;
    if (b->nl > w->cap_list &&
        as_grow(ctx, (void **)&w->list, &w->cap_list, b->nl, sizeof *w->list))
        return as_fail(ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
    if (b->nl && w->list != b->list) memcpy(w->list, b->list, b->nl * sizeof *w->list);
    int32_t gid = b->gid;
    return build_star(ss, w, env, sc, ss->stars[gid], ss->xyz + 3 * (size_t)gid, gid,
                      &ss->mf[gid], b->nl, 0);
}

static anistar_status bstar_task(void *arg, int32_t k, int t, anistar_context *tctx) {
    (void)tctx;
    as_starset *ss = arg;
    return bstar_on(ss, &ss->tws[t], &ss->tenv[t], &ss->tsc[t], &ss->bpts[k]);
}

anistar_status as_starset_insert_batch(as_starset *ss, as_bpoint *b, int32_t np) {
    anistar_status s;
    if (np <= 0) return ANISTAR_OK;
    if ((s = grow_points(ss, (int64_t)ss->n + np)) != ANISTAR_OK) return s;
    size_t nt = 0;
    for (int32_t j = 0; j < np; j++) {
        int32_t gid = ss->n;
        memcpy(ss->xyz + 3 * (size_t)gid, b[j].p, 3 * sizeof(double));
        ss->mf[gid] = b[j].mf;
        if (!isnan(b[j].lfs)) ss->lfs[gid] = b[j].lfs;
        as_star *st = as_alloc(ss->ctx, sizeof *st);
        if (!st) return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (star)");
        as_star_init(st, ss->ctx);
        ss->n++;
        ss->stars[gid] = st;
        b[j].gid = gid;
        nt += b[j].nl;
    }
    /* 1. every point into its conflicting stars (no star is in two lists): one task per
     * star, then the table and the events in the tasks' order (as as_starset_insert) */
    if (nt > ss->cap_btask &&
        as_grow(ss->ctx, (void **)&ss->btask, &ss->cap_btask, nt, sizeof *ss->btask))
        return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (batch)");
    nt = 0;
    for (int32_t j = 0; j < np; j++)
        for (size_t k = 0; k < b[j].nl; k++) {
            as_btask *bt = &ss->btask[nt++];
            bt->v = b[j].list[k];
            bt->gid = b[j].gid;
            bt->hint = b[j].hints[k];
        }
    const int par = ss->pool && nt >= 2;
    if (par) {
        if (nt > ss->cap_ptask &&
            as_grow(ss->ctx, (void **)&ss->ptask, &ss->cap_ptask, nt, sizeof *ss->ptask))
            return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (parallel insertion)");
        thread_envs(ss);
        for (int t = 0; t < ss->nthreads; t++) ss->parena[t].n = 0;
        if ((s = as_pool_run(ss->pool, (int32_t)nt, binsert_task, ss)) != ANISTAR_OK) return s;
    }
    for (size_t k = 0; k < nt; k++) {
        const as_btask *bt = &ss->btask[k];
        as_star *sv = ss->stars[bt->v];
        const as_rfacet *old;
        int32_t nold;
        int was_closed, grew;
        double zb[6];
        if (par) {
            const as_ptask *pt = &ss->ptask[k];
            old = ss->parena[pt->thread].f + pt->off;
            nold = pt->nold;
            was_closed = pt->was_closed;
            grew = pt->grew;
            memcpy(zb, pt->zb, sizeof zb);
        } else {
            int32_t gid = bt->gid;
            was_closed = sv->closed;
            sv->hint = bt->hint;
            if ((s = as_star_insert(&ss->env, sv, &ss->mf[bt->v], &gid, 1, &ss->sc, NULL)) !=
                ANISTAR_OK)
                return s;
            old = ss->sc.old;
            nold = ss->sc.nold;
            grew = entry_grew(ss, bt->v, old, nold, zb);
        }
        if ((s = after_insert(ss, bt->v, old, nold, was_closed, grew, zb)) != ANISTAR_OK) return s;
    }
    /* 2. the points' own stars, each from its seeds and grown from the kd-tree, which
     * holds every point of the batch: a point in conflict with another's star is found
     * there as any site (one task per point: a build reads only its seeding stars, which
     * no other point of the batch entered) */
    for (int32_t j = 0; j < np; j++)
        if ((s = as_kdtree_insert(ss->ctx, ss->kd, b[j].p, b[j].gid)) != ANISTAR_OK) return s;
    if (ss->pool && np >= 2) {
        if ((s = as_starset_simulate_prepare(ss)) != ANISTAR_OK) return s;
        ss->bpts = b;
        s = as_pool_run(ss->pool, np, bstar_task, ss);
        ss->bpts = NULL;
        as_starset_collect_counts(ss);
        if (s != ANISTAR_OK) return s;
    } else {
        for (int32_t j = 0; j < np; j++)
            if ((s = bstar_on(ss, &ss->ws, &ss->env, &ss->sc, &b[j])) != ANISTAR_OK) return s;
    }
    for (int32_t j = 0; j < np; j++) {
        as_star *st = ss->stars[b[j].gid];
        for (int32_t k = 0; k < st->nrf; k++) st->rf[k].fresh = 1;
        if ((s = apply_diff(ss, b[j].gid, NULL, 0)) != ANISTAR_OK) return s;
    }
    if ((s = restars(ss, 0)) != ANISTAR_OK) return s;
    return restars(ss, 1);
}

/* A simulation on workspace w with env and sc (the caller's or a thread's). design: the
 * candidate takes the provisional id n (the same on every thread: the perturbation of
 * ties sees the same ids whatever the thread count) and stays out of the points array:
 * the spare star takes it from its override (as_star_ovr), so simulations of different
 * candidates can run at once. */
static anistar_status simulate_on(as_starset *ss, as_simws *w, const as_star_env *env,
                                  as_star_scratch *sc, const double p[3],
                                  const as_metric_frame *mf, as_star **out) {
    anistar_status s;
    int32_t gid = ss->n; /* provisional: the id past the last point */
    if (!w->spare) {
        w->spare = as_alloc(env->ctx, sizeof *w->spare);
        if (!w->spare) return as_fail(env->ctx, ANISTAR_ENOMEM, "mesher: out of memory");
        as_star_init(w->spare, env->ctx);
    }
    w->ovr.gid = gid;
    memcpy(w->ovr.p, p, sizeof w->ovr.p);
    w->spare->ovr = &w->ovr;
    size_t nl;
    if ((s = conflicting_stars(ss, w, env->ctx, p, gid, &nl)) != ANISTAR_OK) return s;
    if ((s = build_star(ss, w, env, sc, w->spare, p, gid, mf, nl, 1)) != ANISTAR_OK) return s;
    *out = w->spare;
    return ANISTAR_OK;
}

anistar_status as_starset_simulate(as_starset *ss, const double p[3], const as_metric_frame *mf,
                                   as_star **out) {
    anistar_status s;
    if ((s = grow_points(ss, (int64_t)ss->n + 1)) != ANISTAR_OK) return s;
    return simulate_on(ss, &ss->ws, &ss->env, &ss->sc, p, mf, out);
}

anistar_status as_starset_simulate_prepare(as_starset *ss) {
    anistar_status s;
    if ((s = grow_points(ss, (int64_t)ss->n + 1)) != ANISTAR_OK) return s;
    for (int t = 0; t < ss->nthreads; t++) {
        as_simws *w = &ss->tws[t];
        size_t need = (size_t)ss->n + 1;
        if (need > w->cap_stamp) {
            size_t cap = (size_t)ss->cap, old = w->cap_stamp;
            uint32_t *a = as_realloc(ss->ctx, w->stamp, old * sizeof *a, cap * sizeof *a);
            if (!a) return as_fail(ss->ctx, ANISTAR_ENOMEM, "mesher: out of memory (threads)");
            memset(a + old, 0, (cap - old) * sizeof *a);
            w->stamp = a;
            w->cap_stamp = cap;
        }
    }
    thread_envs(ss);
    return ANISTAR_OK;
}

anistar_status as_starset_simulate_thread(as_starset *ss, int t, const double p[3],
                                          const as_metric_frame *mf, as_star **out) {
    return simulate_on(ss, &ss->tws[t], &ss->tenv[t], &ss->tsc[t], p, mf, out);
}

void as_starset_collect_counts(as_starset *ss) {
    for (int t = 0; t < ss->nthreads; t++) {
        ss->ws.conflict_tests += ss->tws[t].conflict_tests;
        ss->ws.star_builds += ss->tws[t].star_builds;
        ss->tws[t].conflict_tests = ss->tws[t].star_builds = 0;
    }
}

/* ---- validator --------------------------------------------------------------------------- */

anistar_status as_starset_check_table(as_starset *ss) {
    /* every star facet has its bit; every entry's bits are backed by star facets */
    size_t total_bits = 0;
    for (int32_t v = ss->first_site; v < ss->n; v++) {
        as_star *st = ss->stars[v];
        if (!st) continue;
        for (int32_t k = 0; k < st->nrf; k++) {
            const as_gid *g = st->rf[k].g;
            as_ftab_entry *e = as_starset_lookup(ss, as_facet_key(g));
            int bit = g[0] == v ? 0 : g[1] == v ? 1 : 2;
            if (!e || !(e->mask & (1u << bit)))
                return as_fail(ss->ctx, ANISTAR_EINTERNAL,
                               "facet table: (%lld %lld %lld) of star %d missing", (long long)g[0],
                               (long long)g[1], (long long)g[2], (int)v);
            total_bits++;
        }
    }
    size_t entries = 0, bits = 0, incs = 0;
    for (size_t i = 0; i < ss->tab_cap; i++) {
        as_ftab_entry *e = &ss->tab[i];
        if (!e->mask) continue; /* an empty slot */
        entries++;
        for (int b = 0; b < 3; b++) bits += (e->mask >> b) & 1;
        int inc = !as_starset_consistent(ss, e->key, e->mask);
        if (inc != (e->incpos >= 0))
            return as_fail(ss->ctx, ANISTAR_EINTERNAL, "facet table: inconsistent flag wrong");
        if (inc) {
            incs++;
            if ((size_t)e->incpos >= ss->ninc || !as_fkey_eq(&ss->inc[e->incpos], &e->key))
                return as_fail(ss->ctx, ANISTAR_EINTERNAL, "facet table: bad set position");
        }
        if (as_starset_lookup(ss, e->key) != e)
            return as_fail(ss->ctx, ANISTAR_EINTERNAL, "facet table: unreachable entry");
    }
    if (entries != ss->tab_n || bits != total_bits || incs != ss->ninc)
        return as_fail(ss->ctx, ANISTAR_EINTERNAL,
                       "facet table: counts differ (entries %zu/%zu, bits %zu/%zu, inc %zu/%zu)",
                       entries, ss->tab_n, bits, total_bits, incs, ss->ninc);
    return ANISTAR_OK;
}

/* ---- exported for starmove.c ---- */

anistar_status as_starset_apply_diff(as_starset *ss, int32_t v, const as_rfacet *old,
                                     int32_t nold) {
    return apply_diff(ss, v, old, nold);
}

uint32_t as_starset_next_epoch(as_starset *ss) { return next_epoch(ss); }

anistar_status as_starset_rebuild_on(as_starset *ss, int t, int32_t w, const as_star *old,
                                     int32_t skip, as_star *st) {
    as_simws *ws = t < 0 ? &ss->ws : &ss->tws[t];
    const as_star_env *env = t < 0 ? &ss->env : &ss->tenv[t];
    as_star_scratch *sc = t < 0 ? &ss->sc : &ss->tsc[t];
    anistar_context *ctx = env->ctx;
    uint32_t ep = ws_epoch(ss, ws);
    ws->stamp[w] = ep;
    size_t ns = 0;
    for (int32_t i = 0; i < old->nrf; i++)
        for (int j = 0; j < 3; j++) {
            int32_t q = old->rf[i].g[j];
            if (q < 8 || q == skip || ws->stamp[q] == ep) continue;
            ws->stamp[q] = ep;
            if (ns == ws->cap_seeds &&
                as_grow(ctx, (void **)&ws->seeds, &ws->cap_seeds, ns + 1, sizeof *ws->seeds))
                return as_fail(ctx, ANISTAR_ENOMEM, "optimize: out of memory (seeds)");
            ws->seeds[ns++] = q;
        }
    const as_metric_frame *mf = &ss->mf[w];
    anistar_status s = as_star_build(env, st, mf, w, sc);
    if (s == ANISTAR_OK && ns) s = as_star_insert(env, st, mf, ws->seeds, (int32_t)ns, sc, NULL);
    if (s == ANISTAR_OK) s = grow_star_box(ss, ws, env, sc, st, mf, ep, NULL);
    if (s == ANISTAR_OK) st->nv_base = st->nv;
    return s;
}

anistar_status as_starset_threads_prepare(as_starset *ss) {
    return ss->pool ? as_starset_simulate_prepare(ss) : ANISTAR_OK;
}

anistar_status as_starset_lfs(as_starset *ss, int32_t v, double need, double *lfs) {
    if (!isnan(ss->lfs[v])) {
        *lfs = ss->lfs[v];
        return ANISTAR_OK;
    }
    /* design: the exact value once per site (one kd-tree query for a bound, one box query),
     * cached: cheaper than a bound per facet event (need is then only a hint) */
    (void)need;
    int exact = 0;
    anistar_status s = as_feature_lfs(ss->ctx, &ss->feat, &ss->mf[v], ss->xyz + 3 * (size_t)v,
                                      0, &ss->fids, lfs, &exact);
    if (s == ANISTAR_OK && exact) ss->lfs[v] = *lfs;
    return s;
}
