/*
 * test_predicates — lib/geom/predicates.c and lib/geom/expansion.h: the expansion
 * arithmetic, orient3d and insphere (adaptive and _exact) against an exact GMP oracle on
 * random, near-degenerate and exactly degenerate inputs at magnitudes 1e-40 .. 1e+40,
 * the symbolically perturbed insphere_sos (never 0, antisymmetric, consistent with the
 * exact sign, and equal to an independent GMP evaluation of the perturbation scheme),
 * and the public wrappers on NaN / infinite / NULL input.
 *
 * The oracle turns every double into an exact integer after scaling all the coordinates
 * of a case by one power of two (m 2^e -> m 2^(e - emin)), so determinants are mpz
 * computations; the sign of the scaled determinant is the sign of the real one.
 */
#include "test_util.h"

#include "anistar.h"
#include "geom/expansion.h"
#include "geom/predicates.h"

#include <float.h>
#include <gmp.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

/* ====================================================================================== */
/* exact oracle                                                                           */
/* ====================================================================================== */

typedef struct oracle {
    mpz_t c[5][3]; /* scaled integer coordinates of the points of the case */
    mpz_t m[4][4]; /* matrix of the current determinant */
    mpz_t t[8];    /* temporaries */
    mpz_t r;       /* last determinant */
    long emin;     /* the coordinates were multiplied by 2^-emin */
} oracle;

static void oracle_init(oracle *o) {
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) mpz_init2(o->c[i][k], 256);
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 4; k++) mpz_init2(o->m[i][k], 512);
    for (int i = 0; i < 8; i++) mpz_init2(o->t[i], 1024);
    mpz_init2(o->r, 1024);
}

static void oracle_clear(oracle *o) {
    for (int i = 0; i < 5; i++)
        for (int k = 0; k < 3; k++) mpz_clear(o->c[i][k]);
    for (int i = 0; i < 4; i++)
        for (int k = 0; k < 4; k++) mpz_clear(o->m[i][k]);
    for (int i = 0; i < 8; i++) mpz_clear(o->t[i]);
    mpz_clear(o->r);
}

/* x = m 2^e with m an integer, |m| < 2^53. */
static void dbl_split(double x, long long *m, long *e) {
    int ex;
    double f = frexp(x, &ex);
    *m = (long long)ldexp(f, 53);
    *e = ex - 53;
}

/* Load n points as integers with a common power-of-two scale. */
static void oracle_load(oracle *o, const double *const *p, int n) {
    long emin = 0;
    int any = 0;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            if (p[i][k] == 0.0) continue;
            long long m;
            long e;
            dbl_split(p[i][k], &m, &e);
            if (!any || e < emin) emin = e;
            any = 1;
        }
    o->emin = emin;
    for (int i = 0; i < n; i++)
        for (int k = 0; k < 3; k++) {
            if (p[i][k] == 0.0) {
                mpz_set_ui(o->c[i][k], 0);
                continue;
            }
            long long m;
            long e;
            dbl_split(p[i][k], &m, &e);
            mpz_set_si(o->c[i][k], (long)m);
            mpz_mul_2exp(o->c[i][k], o->c[i][k], (mp_bitcnt_t)(e - emin));
        }
}

/* r = det of the 3x3 matrix (pointers to entries) by the rule of Sarrus. */
static void det3_sarrus(oracle *o, mpz_ptr r, mpz_srcptr m[3][3]) {
    static const int pos[3][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}};
    mpz_set_ui(r, 0);
    for (int s = 0; s < 3; s++) {
        mpz_mul(o->t[0], m[0][pos[s][0]], m[1][pos[s][1]]);
        mpz_addmul(r, o->t[0], m[2][pos[s][2]]);
        mpz_mul(o->t[0], m[0][pos[s][0]], m[1][pos[s][2]]);
        mpz_submul(r, o->t[0], m[2][pos[s][1]]);
    }
}

/* sign of orient3d(a, b, c, d) = det[a - d; b - d; c - d]; o->r gets the scaled value. */
static int gmp_orient3d(oracle *o, const double *a, const double *b, const double *c,
                        const double *d) {
    const double *p[4] = {a, b, c, d};
    oracle_load(o, p, 4);
    mpz_srcptr m[3][3];
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++) {
            mpz_sub(o->m[i][k], o->c[i][k], o->c[3][k]);
            m[i][k] = o->m[i][k];
        }
    det3_sarrus(o, o->r, m);
    return mpz_sgn(o->r);
}

/* sign of insphere(a, b, c, d, e) = det of the rows (p - e, |p - e|^2), by Laplace
 * along the first row with 3x3 minors by Sarrus (a different expansion from the code
 * under test). */
static int gmp_insphere(oracle *o, const double *a, const double *b, const double *c,
                        const double *d, const double *e) {
    const double *p[5] = {a, b, c, d, e};
    oracle_load(o, p, 5);
    for (int i = 0; i < 4; i++) {
        mpz_set_ui(o->m[i][3], 0);
        for (int k = 0; k < 3; k++) {
            mpz_sub(o->m[i][k], o->c[i][k], o->c[4][k]);
            mpz_addmul(o->m[i][3], o->m[i][k], o->m[i][k]);
        }
    }
    mpz_set_ui(o->r, 0);
    for (int j = 0; j < 4; j++) {
        mpz_srcptr m[3][3];
        for (int i = 1; i < 4; i++)
            for (int k = 0, kk = 0; k < 4; k++)
                if (k != j) m[i - 1][kk++] = o->m[i][k];
        det3_sarrus(o, o->t[1], m);
        if (j % 2 == 0)
            mpz_addmul(o->r, o->m[0][j], o->t[1]);
        else
            mpz_submul(o->r, o->m[0][j], o->t[1]);
    }
    return mpz_sgn(o->r);
}

/* The real value of o->r for a determinant of degree deg, as a double. */
static double oracle_value(const oracle *o, int deg) {
    long ex;
    double m = mpz_get_d_2exp(&ex, o->r);
    return ldexp(m, (int)(ex + deg * o->emin));
}

static int sgn(double x) { return (x > 0) - (x < 0); }

/* ====================================================================================== */
/* input generators                                                                       */
/* ====================================================================================== */

/* Keep a coordinate in the valid range: nonzero magnitudes in [1e-40, 1e40]. */
static double in_range(double x) {
    if (fabs(x) < 1e-40) return 0.0;
    if (fabs(x) > 1e40) return copysign(1e40, x);
    return x;
}

/* A random scale in [~1e-40, ~3e39]: a power of two or a decimal-ish factor. */
static double rand_scale(tu_rng *r) {
    if (tu_rng_u64(r) & 1) return ldexp(1.0, (int)(tu_rng_u64(r) % 264) - 132);
    double s = pow(10.0, (double)((int)(tu_rng_u64(r) % 80) - 40));
    return s * tu_rng_range(r, 1.0, 9.99);
}

/* A random offset vector for a case of scale s (0 half of the time). */
static void rand_offset(tu_rng *r, double s, double off[3]) {
    double m = 0;
    if (tu_rng_u64(r) % 2) m = fmin(ldexp(s, (int)(tu_rng_u64(r) % 40)), 5e39);
    for (int k = 0; k < 3; k++) off[k] = m * tu_rng_range(r, -1, 1);
}

static void rand_point(tu_rng *r, double s, const double off[3], double p[3]) {
    for (int k = 0; k < 3; k++) p[k] = in_range(off[k] + s * tu_rng_range(r, -1, 1));
}

/* Move x by k ulps (k may be negative). */
static double nudge(double x, int k) {
    for (; k > 0; k--) x = nextafter(x, INFINITY);
    for (; k < 0; k++) x = nextafter(x, -INFINITY);
    return in_range(x);
}

/* Nudge a few random coordinates of the n points by up to 3 ulps (sometimes none). */
static void nudge_some(tu_rng *r, double (*p)[3], int n) {
    int times = (int)(tu_rng_u64(r) % 4);
    for (int t = 0; t < times; t++) {
        int i = (int)(tu_rng_u64(r) % (unsigned)n), k = (int)(tu_rng_u64(r) % 3);
        p[i][k] = nudge(p[i][k], (int)(tu_rng_u64(r) % 7) - 3);
    }
}

/* ---- near-degenerate configurations ---------------------------------------------- */

/* n points: the first three random, the others (nearly) on their plane, nudged. */
static void gen_coplanar(tu_rng *r, double (*p)[3], int n) {
    double s = rand_scale(r), off[3];
    rand_offset(r, s, off);
    for (int i = 0; i < 3; i++) rand_point(r, s, off, p[i]);
    for (int i = 3; i < n; i++) {
        double u = tu_rng_range(r, -1, 2), v = tu_rng_range(r, -1, 2);
        for (int k = 0; k < 3; k++)
            p[i][k] = in_range(p[0][k] + u * (p[1][k] - p[0][k]) + v * (p[2][k] - p[0][k]));
    }
    nudge_some(r, p, n);
}

/* n points (nearly) on a random sphere, nudged. */
static void gen_cospherical(tu_rng *r, double (*p)[3], int n) {
    double s = rand_scale(r), off[3];
    rand_offset(r, s, off);
    for (int i = 0; i < n; i++) {
        double v[3], l;
        do {
            for (int k = 0; k < 3; k++) v[k] = tu_rng_range(r, -1, 1);
            l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        } while (l < 0.1 || l > 1);
        for (int k = 0; k < 3; k++) p[i][k] = in_range(off[k] + s * (v[k] / l));
    }
    nudge_some(r, p, n);
}

/* n points, some of them (nearly) collinear or coincident with others. */
static void gen_collinear(tu_rng *r, double (*p)[3], int n) {
    double s = rand_scale(r), off[3];
    rand_offset(r, s, off);
    for (int i = 0; i < n; i++) rand_point(r, s, off, p[i]);
    for (int i = 2; i < n; i++) {
        unsigned kind = (unsigned)(tu_rng_u64(r) % 3);
        if (kind == 0) {
            memcpy(p[i], p[tu_rng_u64(r) % (unsigned)i], sizeof p[i]);
        } else if (kind == 1) {
            double u = tu_rng_range(r, -2, 2);
            for (int k = 0; k < 3; k++)
                p[i][k] = in_range(p[0][k] + u * (p[1][k] - p[0][k]));
        }
    }
    nudge_some(r, p, n);
}

/* ---- exactly degenerate configurations ------------------------------------------- */

/* Integer points on the sphere x^2 + y^2 + z^2 = N (Pythagorean quadruples). */
typedef struct sphere_pts {
    int n;
    int v[512][3];
} sphere_pts;

static void sphere_points(int nsq, sphere_pts *sp) {
    sp->n = 0;
    int rmax = (int)sqrt((double)nsq) + 1;
    for (int x = -rmax; x <= rmax; x++)
        for (int y = -rmax; y <= rmax; y++)
            for (int z = -rmax; z <= rmax; z++)
                if (x * x + y * y + z * z == nsq && sp->n < 512) {
                    sp->v[sp->n][0] = x;
                    sp->v[sp->n][1] = y;
                    sp->v[sp->n][2] = z;
                    sp->n++;
                }
}

/* A scale for exactly degenerate sets: a power of two keeps them exact, a decimal
 * factor rounds them (nearly degenerate); both are within the valid range for integer
 * coordinates up to ~100. */
static double degen_scale(tu_rng *r) {
    if (tu_rng_u64(r) % 3 != 0) return ldexp(1.0, (int)(tu_rng_u64(r) % 250) - 126);
    return pow(10.0, (double)((int)(tu_rng_u64(r) % 75) - 37)) * tu_rng_range(r, 1, 9.9);
}

/* n points of one exactly degenerate family, kind 0..3: integer grid, points on an
 * integer sphere, corners of a random box, a symmetric set (octahedron / cube, centre). */
static void gen_degenerate(tu_rng *r, const sphere_pts *sp, int nsp, double (*p)[3], int n,
                           int kind) {
    double s = degen_scale(r);
    int ioff[3];
    for (int k = 0; k < 3; k++) ioff[k] = (int)(tu_rng_u64(r) % 41) - 20;
    if (tu_rng_u64(r) % 2) ioff[0] = ioff[1] = ioff[2] = 0;
    if (kind == 0) {
        for (int i = 0; i < n; i++)
            for (int k = 0; k < 3; k++)
                p[i][k] = in_range(s * (double)((int)(tu_rng_u64(r) % 5) - 2 + ioff[k]));
    } else if (kind == 1) {
        const sphere_pts *q = &sp[tu_rng_u64(r) % (unsigned)nsp];
        for (int i = 0; i < n; i++) {
            const int *v = q->v[tu_rng_u64(r) % (unsigned)q->n];
            for (int k = 0; k < 3; k++) p[i][k] = in_range(s * (double)(v[k] + ioff[k]));
        }
    } else if (kind == 2) {
        double lo[3], hi[3], off[3];
        rand_offset(r, s, off);
        for (int k = 0; k < 3; k++) {
            lo[k] = in_range(off[k] + s * tu_rng_range(r, -1, 1));
            hi[k] = in_range(off[k] + s * tu_rng_range(r, -1, 1));
        }
        for (int i = 0; i < n; i++) {
            unsigned c = (unsigned)(tu_rng_u64(r) % 8);
            for (int k = 0; k < 3; k++) p[i][k] = (c >> k) & 1u ? hi[k] : lo[k];
        }
    } else {
        static const int sym[15][3] = {{1, 0, 0},   {-1, 0, 0},   {0, 1, 0},  {0, -1, 0},
                                       {0, 0, 1},   {0, 0, -1},   {1, 1, 1},  {1, 1, -1},
                                       {1, -1, 1},  {1, -1, -1},  {-1, 1, 1}, {-1, 1, -1},
                                       {-1, -1, 1}, {-1, -1, -1}, {0, 0, 0}};
        int base = (int)(tu_rng_u64(r) % 2);
        for (int i = 0; i < n; i++) {
            unsigned j =
                base ? 6 + (unsigned)(tu_rng_u64(r) % 9) : (unsigned)(tu_rng_u64(r) % 6);
            if (tu_rng_u64(r) % 8 == 0) j = 14;
            for (int k = 0; k < 3; k++)
                p[i][k] = in_range(s * (double)(sym[j][k] + ioff[k]));
        }
    }
}

/* Five points in very degenerate position (for the coordinate phase of insphere_sos):
 * all on one line, or with coincident points (on a line or in a plane), scaled. */
static void gen_very_degenerate(tu_rng *r, double (*p)[3]) {
    double s = degen_scale(r);
    int base[3], dir[3], dir2[3];
    for (int k = 0; k < 3; k++) {
        base[k] = (int)(tu_rng_u64(r) % 21) - 10;
        dir[k] = (int)(tu_rng_u64(r) % 5) - 2;
        dir2[k] = (int)(tu_rng_u64(r) % 5) - 2;
    }
    unsigned kind = (unsigned)(tu_rng_u64(r) % 3);
    for (int i = 0; i < 5; i++) {
        int t = (int)(tu_rng_u64(r) % (kind == 0 ? 7 : 2)) - 3;
        int u = kind == 2 ? (int)(tu_rng_u64(r) % 2) : 0;
        for (int k = 0; k < 3; k++)
            p[i][k] = in_range(s * (double)(base[k] + t * dir[k] + u * dir2[k]));
    }
}

static void make_spheres(sphere_pts *sp, int *nsp) {
    static const int nsq[] = {3, 9, 11, 27, 49, 50, 81, 121, 225, 289};
    *nsp = (int)(sizeof nsq / sizeof nsq[0]);
    for (int i = 0; i < *nsp; i++) sphere_points(nsq[i], &sp[i]);
}

/* ====================================================================================== */
/* checks                                                                                 */
/* ====================================================================================== */

typedef struct tally {
    long cases, zero, pos, neg;
} tally;

static void tally_add(tally *t, int s) {
    t->cases++;
    if (s == 0)
        t->zero++;
    else if (s > 0)
        t->pos++;
    else
        t->neg++;
}

/* Check the adaptive and exact orient3d of one case against the oracle. */
static int check_orient(oracle *o, const double (*p)[3], long it, const char *what) {
    int want = gmp_orient3d(o, p[0], p[1], p[2], p[3]);
    double ad = as_orient3d(p[0], p[1], p[2], p[3]);
    double ex = as_orient3d_exact(p[0], p[1], p[2], p[3]);
    if (sgn(ad) != want || sgn(ex) != want) {
        fail_msg("%s orient3d case %ld: adaptive %d exact %d gmp %d\n"
                 "  a=(%a,%a,%a) b=(%a,%a,%a)\n  c=(%a,%a,%a) d=(%a,%a,%a)",
                 what, it, sgn(ad), sgn(ex), want, p[0][0], p[0][1], p[0][2], p[1][0],
                 p[1][1], p[1][2], p[2][0], p[2][1], p[2][2], p[3][0], p[3][1], p[3][2]);
    }
    return want;
}

static int check_insphere(oracle *o, const double (*p)[3], long it, const char *what) {
    int want = gmp_insphere(o, p[0], p[1], p[2], p[3], p[4]);
    double ad = as_insphere(p[0], p[1], p[2], p[3], p[4]);
    double ex = as_insphere_exact(p[0], p[1], p[2], p[3], p[4]);
    if (sgn(ad) != want || sgn(ex) != want) {
        fail_msg("%s insphere case %ld: adaptive %d exact %d gmp %d\n"
                 "  a=(%a,%a,%a) b=(%a,%a,%a) c=(%a,%a,%a)\n  d=(%a,%a,%a) e=(%a,%a,%a)",
                 what, it, sgn(ad), sgn(ex), want, p[0][0], p[0][1], p[0][2], p[1][0],
                 p[1][1], p[1][2], p[2][0], p[2][1], p[2][2], p[3][0], p[3][1], p[3][2],
                 p[4][0], p[4][1], p[4][2]);
    }
    return want;
}

/* ====================================================================================== */
/* expansion arithmetic                                                                   */
/* ====================================================================================== */

/* A double with a random exponent in [lo, hi] and a random sign and mantissa (sometimes
 * a short mantissa, so results are often exact or have long carries). */
static double rand_double(tu_rng *r, int lo, int hi) {
    double m = tu_rng_range(r, 1.0, 2.0);
    if (tu_rng_u64(r) % 4 == 0) m = 1.0 + ldexp((double)(tu_rng_u64(r) % 16), -4);
    if (tu_rng_u64(r) % 2) m = -m;
    return ldexp(m, lo + (int)(tu_rng_u64(r) % (unsigned)(hi - lo + 1)));
}

/* Exact sum of an expansion as an mpq. */
static void exp_to_mpq(mpq_t q, int n, const double *e) {
    mpq_t t;
    mpq_init(t);
    mpq_set_ui(q, 0, 1);
    for (int i = 0; i < n; i++) {
        mpq_set_d(t, e[i]);
        mpq_add(q, q, t);
    }
    mpq_clear(t);
}

/* e is nonoverlapping and increasing in magnitude, ignoring zeros: for consecutive
 * nonzero components x (smaller) and y, |x| < ulp(y) ... precisely, the lowest set bit
 * of y is above the highest bit of x. */
static void assert_nonoverlapping(int n, const double *e) {
    double prev = 0.0;
    for (int i = 0; i < n; i++) {
        if (e[i] == 0.0) continue;
        if (prev != 0.0) {
            /* lowest set bit of e[i]: |e[i]| = m 2^ex with m odd */
            long long m;
            long ex;
            dbl_split(e[i], &m, &ex);
            while (m % 2 == 0) {
                m /= 2;
                ex++;
            }
            int pe;
            frexp(prev, &pe); /* |prev| < 2^pe */
            if (!(pe <= ex)) fail_msg("overlapping components %a and %a", prev, e[i]);
        }
        prev = e[i];
    }
}

static void test_expansion_ops(void **state) {
    (void)state;
    tu_rng r = {11};
    mpq_t want, got, t;
    mpq_init(want);
    mpq_init(got);
    mpq_init(t);
    for (long it = 0; it < 20000; it++) {
        double a = rand_double(&r, -300, 300), b = rand_double(&r, -300, 300);
        if (it % 3 == 0)
            b = rand_double(&r, -30, 30) * ldexp(a, -(int)(tu_rng_u64(&r) % 60));
        double x, y;
        double h[2];
        /* two_sum, two_diff, fast_two_sum */
        as_two_sum(a, b, &x, &y);
        h[0] = y;
        h[1] = x;
        mpq_set_d(want, a);
        mpq_set_d(t, b);
        mpq_add(want, want, t);
        exp_to_mpq(got, 2, h);
        assert_true(mpq_equal(want, got));
        assert_true(x == a + b);
        if (fabs(a) >= fabs(b)) {
            as_fast_two_sum(a, b, &x, &y);
            h[0] = y;
            h[1] = x;
            exp_to_mpq(got, 2, h);
            assert_true(mpq_equal(want, got));
        }
        as_two_diff(a, b, &x, &y);
        h[0] = y;
        h[1] = x;
        mpq_set_d(want, a);
        mpq_set_d(t, b);
        mpq_sub(want, want, t);
        exp_to_mpq(got, 2, h);
        assert_true(mpq_equal(want, got));
        assert_true(as_two_diff_tail(a, b, a - b) == y);
        /* two_product, two_square (exponents kept clear of under/overflow) */
        double pa = rand_double(&r, -250, 250), pb = rand_double(&r, -250, 250);
        as_two_product(pa, pb, &x, &y);
        h[0] = y;
        h[1] = x;
        mpq_set_d(want, pa);
        mpq_set_d(t, pb);
        mpq_mul(want, want, t);
        exp_to_mpq(got, 2, h);
        assert_true(mpq_equal(want, got));
        assert_true(x == pa * pb);
        as_two_square(pa, &x, &y);
        h[0] = y;
        h[1] = x;
        mpq_set_d(want, pa);
        mpq_mul(want, want, want);
        exp_to_mpq(got, 2, h);
        assert_true(mpq_equal(want, got));
    }
    /* two_two_diff, exp_sum, exp_scale on random expansions built from products. */
    for (long it = 0; it < 5000; it++) {
        double e4[4], f4[4], h8[8], s16[16], sc[16];
        double p1, p0, q1, q0;
        int base = (int)(tu_rng_u64(&r) % 200) - 100;
        double v[8];
        for (int i = 0; i < 8; i++) v[i] = rand_double(&r, base - 20, base + 20);
        if (tu_rng_u64(&r) % 2) v[2] = v[0], v[3] = v[1] * (1 + ldexp(1, -40));
        as_two_product(v[0], v[1], &p1, &p0);
        as_two_product(v[2], v[3], &q1, &q0);
        as_two_two_diff(p1, p0, q1, q0, e4);
        as_two_product(v[4], v[5], &p1, &p0);
        as_two_product(v[6], v[7], &q1, &q0);
        as_two_two_diff(p1, p0, q1, q0, f4);
        mpq_set_d(want, v[0]);
        mpq_set_d(t, v[1]);
        mpq_mul(want, want, t);
        mpq_set_d(t, v[2]);
        mpq_set_d(got, v[3]);
        mpq_mul(t, t, got);
        mpq_sub(want, want, t);
        exp_to_mpq(got, 4, e4);
        assert_true(mpq_equal(want, got));
        assert_nonoverlapping(4, e4);
        /* e4 + f4 */
        int n = as_exp_sum(4, e4, 4, f4, h8);
        assert_true(n >= 1 && n <= 8);
        exp_to_mpq(want, 4, e4);
        exp_to_mpq(t, 4, f4);
        mpq_add(want, want, t);
        exp_to_mpq(got, n, h8);
        assert_true(mpq_equal(want, got));
        assert_nonoverlapping(n, h8);
        for (int i = 0; i < n; i++) assert_true(h8[i] != 0.0 || n == 1);
        assert_int_equal(as_exp_sign(n, h8), mpq_sgn(want));
        assert_int_equal(sgn(as_exp_value(n, h8)), mpq_sgn(want));
        /* (e4 + f4) * b, then the sum with itself negated is exactly 0 */
        double b = rand_double(&r, -60, 60);
        int m = as_exp_scale(n, h8, b, sc);
        assert_true(m >= 1 && m <= 2 * n);
        mpq_set_d(t, b);
        mpq_mul(want, want, t);
        exp_to_mpq(got, m, sc);
        assert_true(mpq_equal(want, got));
        assert_nonoverlapping(m, sc);
        /* compress keeps the value, shortens, stays nonoverlapping, no inner zeros */
        double cp[16];
        memcpy(cp, sc, sizeof cp);
        int cl = as_exp_compress(m, cp);
        assert_true(cl >= 1 && cl <= m);
        exp_to_mpq(got, cl, cp);
        assert_true(mpq_equal(want, got));
        assert_nonoverlapping(cl, cp);
        for (int i = 0; i < cl; i++) assert_true(cp[i] != 0.0 || cl == 1);
        assert_int_equal(as_exp_sign(cl, cp), mpq_sgn(want));
        double neg[16];
        memcpy(neg, sc, sizeof neg);
        as_exp_negate(m, neg);
        int z = as_exp_sum(m, sc, m, neg, s16);
        assert_int_equal(z, 1);
        assert_true(s16[0] == 0.0);
        assert_int_equal(as_exp_sign(z, s16), 0);
    }
    mpq_clear(want);
    mpq_clear(got);
    mpq_clear(t);
}

/* ====================================================================================== */
/* conventions                                                                            */
/* ====================================================================================== */

static void test_conventions(void **state) {
    (void)state;
    /* a, b, c counterclockwise seen from above (+z), d below: orient3d > 0. */
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0, 0, -1};
    double up[3] = {0, 0, 1};
    assert_true(as_orient3d(a, b, c, d) > 0);
    assert_true(as_orient3d(a, b, c, up) < 0);
    assert_true(as_orient3d(b, a, c, d) < 0);
    assert_true(as_orient3d(a, b, c, c) == 0);
    assert_true(as_orient3d(a, b, c, d) == 1.0); /* exact small-integer magnitude */
    /* e inside the sphere through a, b, c, d (positively oriented) -> insphere > 0. */
    double in[3] = {0.25, 0.25, -0.25}, out[3] = {3, 3, 3}, on[3] = {1, 1, -1};
    assert_true(as_insphere(a, b, c, d, in) > 0);
    assert_true(as_insphere(a, b, c, d, out) < 0);
    assert_true(as_insphere(a, b, c, d, on) == 0); /* box corner: cospherical */
    assert_true(as_insphere(b, a, c, d, in) < 0);  /* negative orientation */
    assert_true(as_insphere_exact(a, b, c, d, in) > 0);
    assert_true(as_insphere_exact(a, b, c, d, on) == 0);
    assert_true(as_orient3d_exact(a, b, c, d) == 1.0);
    /* the _fast variants compute the same determinant (approximately) */
    assert_true(as_orient3d_fast(a, b, c, d) == 1.0);
    assert_true(as_insphere_fast(a, b, c, d, in) > 0);
    assert_true(as_insphere_fast(a, b, c, d, out) < 0);
}

/* ====================================================================================== */
/* random inputs                                                                          */
/* ====================================================================================== */

#define N_RANDOM 1000000L

static void test_orient3d_random(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {101};
    double p[4][3], s = 1, off[3] = {0, 0, 0};
    tally t = {0, 0, 0, 0};
    double worst = 0;
    for (long it = 0; it < N_RANDOM; it++) {
        if (it % 16 == 0) {
            s = rand_scale(&r);
            rand_offset(&r, s, off);
        }
        for (int i = 0; i < 4; i++) rand_point(&r, s, off, p[i]);
        int want = check_orient(&o, (const double(*)[3])p, it, "random");
        tally_add(&t, want);
        if (it % 64 == 0 && want != 0) {
            /* the _exact value is the exact determinant rounded (to a few ulps) */
            double v = as_orient3d_exact(p[0], p[1], p[2], p[3]), x = oracle_value(&o, 3);
            double rel = fabs(v - x) / fabs(x);
            if (rel > worst) worst = rel;
        }
    }
    assert_true(t.pos > N_RANDOM / 3 && t.neg > N_RANDOM / 3);
    assert_true(worst < 1e-14);
    oracle_clear(&o);
}

static void test_insphere_random(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {202};
    double p[5][3], s = 1, off[3] = {0, 0, 0};
    tally t = {0, 0, 0, 0};
    double worst = 0;
    for (long it = 0; it < N_RANDOM; it++) {
        if (it % 16 == 0) {
            s = rand_scale(&r);
            rand_offset(&r, s, off);
        }
        for (int i = 0; i < 5; i++) rand_point(&r, s, off, p[i]);
        int want = check_insphere(&o, (const double(*)[3])p, it, "random");
        tally_add(&t, want);
        if (it % 64 == 0 && want != 0) {
            double v = as_insphere_exact(p[0], p[1], p[2], p[3], p[4]),
                   x = oracle_value(&o, 5);
            double rel = fabs(v - x) / fabs(x);
            if (rel > worst) worst = rel;
        }
    }
    assert_true(t.pos > N_RANDOM / 4 && t.neg > N_RANDOM / 4);
    assert_true(worst < 1e-14);
    oracle_clear(&o);
}

/* ====================================================================================== */
/* near-degenerate and exactly degenerate inputs                                          */
/* ====================================================================================== */

static void test_orient3d_near_degenerate(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {303};
    double p[5][3];
    tally t = {0, 0, 0, 0};
    for (long it = 0; it < 300000; it++) {
        if (it % 3 == 0)
            gen_coplanar(&r, p, 4);
        else if (it % 3 == 1)
            gen_collinear(&r, p, 4);
        else
            gen_cospherical(&r, p, 4);
        tally_add(&t, check_orient(&o, (const double(*)[3])p, it, "near-degenerate"));
    }
    /* The generator reaches all three outcomes (so the test can fail both ways). */
    assert_true(t.zero > 1000 && t.pos > 10000 && t.neg > 10000);
    oracle_clear(&o);
}

static void test_insphere_near_degenerate(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {404};
    double p[5][3];
    tally t = {0, 0, 0, 0};
    for (long it = 0; it < 300000; it++) {
        if (it % 3 == 0)
            gen_cospherical(&r, p, 5);
        else if (it % 3 == 1)
            gen_coplanar(&r, p, 5);
        else
            gen_collinear(&r, p, 5);
        tally_add(&t, check_insphere(&o, (const double(*)[3])p, it, "near-degenerate"));
    }
    assert_true(t.zero > 1000 && t.pos > 10000 && t.neg > 10000);
    oracle_clear(&o);
}

/* Stage B' (double-double) of the adaptive insphere, where the mesher meets it: five points
 * rounded onto one sphere (random directions normalised: what an isotropic metric on a
 * sphere gives; stage A fails for most), at random centres and scales; and integer points
 * within 2 of an integer sphere of radius 1000 (exact differences and determinants far
 * below B's bound relative to the permanent: B' must defer to the exact-differences rule).
 * Signs against the oracle. */
static void test_insphere_on_sphere(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {606};
    double p[5][3];
    tally t = {0, 0, 0, 0}, ti = {0, 0, 0, 0};
    for (long it = 0; it < 200000; it++) {
        double s = ldexp(1.0, (int)(tu_rng_u64(&r) % 40) - 20) * tu_rng_range(&r, 1, 2);
        double off[3];
        for (int k = 0; k < 3; k++)
            off[k] = it % 2 ? 0 : s * tu_rng_range(&r, -1e4, 1e4);
        for (int i = 0; i < 5; i++) {
            double v[3], l;
            do {
                for (int k = 0; k < 3; k++) v[k] = tu_rng_range(&r, -1, 1);
                l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
            } while (l < 0.1 || l > 1);
            for (int k = 0; k < 3; k++) p[i][k] = off[k] + s * (v[k] / l);
        }
        tally_add(&t, check_insphere(&o, (const double(*)[3])p, it, "on a sphere"));
    }
    for (long it = 0; it < 20000; it++) {
        for (int i = 0; i < 5; i++) {
            double v[3];
            for (;;) {
                double l;
                do {
                    for (int k = 0; k < 3; k++) v[k] = tu_rng_range(&r, -1, 1);
                    l = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                } while (l < 0.1 || l > 1);
                for (int k = 0; k < 3; k++) v[k] = round(1000.0 * v[k] / l);
                double n2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                if (fabs(n2 - 1e6) <= 2) break;
            }
            memcpy(p[i], v, sizeof v);
        }
        tally_add(&ti, check_insphere(&o, (const double(*)[3])p, it, "near an integer sphere"));
    }
    /* both families must reach every sign (the integer one is often exactly 0) */
    assert_true(t.pos > 10000 && t.neg > 10000);
    assert_true(ti.pos > 1000 && ti.neg > 1000 && ti.zero > 0);
    oracle_clear(&o);
}

static void test_degenerate(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {505};
    static sphere_pts sp[10];
    int nsp;
    make_spheres(sp, &nsp);
    double p[5][3];
    tally to = {0, 0, 0, 0}, ti = {0, 0, 0, 0};
    for (long it = 0; it < 200000; it++) {
        gen_degenerate(&r, sp, nsp, p, 5, (int)(it % 4));
        tally_add(&to, check_orient(&o, (const double(*)[3])p, it, "degenerate"));
        tally_add(&ti, check_insphere(&o, (const double(*)[3])p, it, "degenerate"));
    }
    assert_true(to.zero > 20000 && to.pos > 20000 && to.neg > 20000);
    assert_true(ti.zero > 50000 && ti.pos > 5000 && ti.neg > 5000);
    oracle_clear(&o);
}

/* The extremes of the valid range: coordinates of magnitude exactly 1e-40 and 1e40
 * (and their neighbours), mixed with zeros, in near-degenerate configurations. */
static void test_range_extremes(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    tu_rng r = {606};
    double p[5][3];
    static const double mags[] = {
        1e-40, 1.0000000000000002e-40, 1e40, 9.999999999999999e39, 0x1p-132, 0x1p132};
    for (long it = 0; it < 100000; it++) {
        double m = mags[tu_rng_u64(&r) % 6];
        for (int i = 0; i < 5; i++)
            for (int k = 0; k < 3; k++) {
                unsigned c = (unsigned)(tu_rng_u64(&r) % 8);
                double v = c < 2 ? 0.0 : (c < 5 ? m : -m);
                if (c == 7) v = nudge(m, (int)(tu_rng_u64(&r) % 5) - 2);
                if (c == 6)
                    v = nudge(m > 1 ? 0.5 * m : 2 * m, (int)(tu_rng_u64(&r) % 5) - 2);
                p[i][k] = v;
            }
        check_orient(&o, (const double(*)[3])p, it, "range extremes");
        check_insphere(&o, (const double(*)[3])p, it, "range extremes");
    }
    oracle_clear(&o);
}

/* ====================================================================================== */
/* symbolic perturbation                                                                  */
/* ====================================================================================== */

/* An independent evaluation of the scheme documented in predicates.c: the sign of
 * det(A + E) for the 5x5 rows (x, y, z, h, 1), E's entries ordered by id as there, by
 * walking all partial matchings in increasing mask order and evaluating each minor
 * with mpz (generic Laplace on the full minor, ones column included). */
typedef struct sos_oracle {
    int nmatch;
    unsigned mask[512];
    mpz_t a[5][5]; /* integer matrix (scaled) */
    mpz_t w[16];
} sos_oracle;

static int popcount20(unsigned m) {
    int n = 0;
    for (; m; m &= m - 1) n++;
    return n;
}

static void sos_oracle_init(sos_oracle *so) {
    so->nmatch = 0;
    for (unsigned m = 0; m < (1u << 20); m++) {
        if (popcount20(m) > 4) continue;
        unsigned rows = 0, cols = 0;
        int ok = 1;
        for (int b = 0; b < 20; b++) {
            if (!(m & (1u << b))) continue;
            int rank = b < 5 ? b : (b - 5) / 3, col = b < 5 ? 3 : (b - 5) % 3;
            if (((rows >> rank) & 1u) || ((cols >> col) & 1u)) ok = 0;
            rows |= 1u << rank;
            cols |= 1u << col;
        }
        if (ok) so->mask[so->nmatch++] = m;
    }
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++) mpz_init(so->a[i][j]);
    for (int i = 0; i < 16; i++) mpz_init(so->w[i]);
}

static void sos_oracle_clear(sos_oracle *so) {
    for (int i = 0; i < 5; i++)
        for (int j = 0; j < 5; j++) mpz_clear(so->a[i][j]);
    for (int i = 0; i < 16; i++) mpz_clear(so->w[i]);
}

/* det of the submatrix of so->a on rows[0..n-1] x cols[0..n-1], by Laplace along the
 * first row (recursive: test code, n <= 5). Result in out. */
static void mpz_det_sub(sos_oracle *so, mpz_ptr out, const int *rows, const int *cols,
                        int n, int depth) {
    if (n == 1) {
        mpz_set(out, so->a[rows[0]][cols[0]]);
        return;
    }
    mpz_ptr acc = so->w[2 * depth], sub = so->w[2 * depth + 1];
    mpz_set_ui(acc, 0);
    for (int j = 0; j < n; j++) {
        int c2[5], k = 0;
        for (int l = 0; l < n; l++)
            if (l != j) c2[k++] = cols[l];
        mpz_det_sub(so, sub, rows + 1, c2, n - 1, depth + 1);
        if (j % 2 == 0)
            mpz_addmul(acc, so->a[rows[0]][cols[j]], sub);
        else
            mpz_submul(acc, so->a[rows[0]][cols[j]], sub);
    }
    mpz_set(out, acc);
}

static int sos_oracle_sign(sos_oracle *so, oracle *o, const double (*p)[3],
                           const int64_t *ids) {
    const double *pp[5] = {p[0], p[1], p[2], p[3], p[4]};
    oracle_load(o, pp, 5);
    /* rows (X, Y, Z, X^2 + Y^2 + Z^2, 1) with X = x 2^-emin: the columns of A scaled by
     * positive factors, which keeps the sign of every minor. */
    for (int i = 0; i < 5; i++) {
        mpz_set_ui(so->a[i][3], 0);
        for (int k = 0; k < 3; k++) {
            mpz_set(so->a[i][k], o->c[i][k]);
            mpz_addmul(so->a[i][3], o->c[i][k], o->c[i][k]);
        }
        mpz_set_ui(so->a[i][4], 1);
    }
    int order[5] = {0, 1, 2, 3, 4};
    for (int i = 0; i < 5; i++)
        for (int j = i + 1; j < 5; j++)
            if (ids[order[j]] < ids[order[i]]) {
                int t = order[i];
                order[i] = order[j];
                order[j] = t;
            }
    for (int q = 0; q < so->nmatch; q++) {
        unsigned m = so->mask[q];
        int er[4], ec[4], n = 0;
        unsigned rows = 0, cols = 0;
        for (int b = 0; b < 20; b++) {
            if (!(m & (1u << b))) continue;
            er[n] = order[b < 5 ? b : (b - 5) / 3];
            ec[n] = b < 5 ? 3 : (b - 5) % 3;
            rows |= 1u << er[n];
            cols |= 1u << ec[n];
            n++;
        }
        /* sign of the term: (-1)^(sum rows + sum cols) times the matching's sign */
        int s = 1;
        for (int i = 0; i < n; i++) {
            if ((er[i] + ec[i]) % 2) s = -s;
            for (int j = 0; j < n; j++)
                if (er[i] < er[j] && ec[i] > ec[j]) s = -s;
        }
        int rr[5], cc[5], k = 0, l = 0;
        for (int i = 0; i < 5; i++)
            if (!((rows >> i) & 1u)) rr[k++] = i;
        for (int j = 0; j < 5; j++)
            if (!((cols >> j) & 1u)) cc[l++] = j;
        mpz_det_sub(so, so->w[15], rr, cc, k, 0);
        int d = mpz_sgn(so->w[15]);
        if (d != 0) return s * d;
    }
    return 0;
}

static int sos(const double (*p)[3], const int64_t *id) {
    return as_insphere_sos(p[0], p[1], p[2], p[3], p[4], id[0], id[1], id[2], id[3], id[4]);
}

/* Sign of a permutation of 0..n-1. */
static int perm_sign(const int *pi, int n) {
    int s = 1;
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++)
            if (pi[i] > pi[j]) s = -s;
    return s;
}

/* Random distinct ids (sometimes large, negative, or adjacent). */
static void rand_ids(tu_rng *r, int64_t *id) {
    for (int i = 0; i < 5; i++) {
        int again;
        do {
            uint64_t u = tu_rng_u64(r);
            id[i] = (u & 1) ? (int64_t)(u >> 1) - (INT64_MAX / 2) : (int64_t)(u % 10);
            again = 0;
            for (int j = 0; j < i; j++)
                if (id[j] == id[i]) again = 1;
        } while (again);
    }
}

static void test_sos_properties(void **state) {
    (void)state;
    oracle o;
    oracle_init(&o);
    static sos_oracle so;
    sos_oracle_init(&so);
    static sphere_pts sp[10];
    int nsp;
    make_spheres(sp, &nsp);
    tu_rng r = {707};
    double p[5][3], q[5][3];
    int64_t id[5], qid[5];
    long zero_exact = 0, coplanar5 = 0;
    for (long it = 0; it < 24000; it++) {
        unsigned kind = (unsigned)(it % 8);
        if (kind < 4)
            gen_degenerate(&r, sp, nsp, p, 5, (int)kind);
        else if (kind == 4)
            gen_coplanar(&r, p, 5);
        else if (kind == 5)
            gen_collinear(&r, p, 5);
        else if (kind == 6)
            gen_cospherical(&r, p, 5);
        else
            gen_very_degenerate(&r, p);
        rand_ids(&r, id);
        int s = sos((const double(*)[3])p, id);
        int exact = gmp_insphere(&o, p[0], p[1], p[2], p[3], p[4]);
        /* never 0; the exact sign whenever it is not 0 */
        if (s != 1 && s != -1) fail_msg("case %ld: insphere_sos returned %d", it, s);
        if (exact != 0 && s != exact) fail_msg("case %ld: sos %d exact %d", it, s, exact);
        if (exact == 0) {
            zero_exact++;
            int c = 1;
            for (int m = 0; m < 5 && c; m++) {
                const double *f[4];
                int n = 0;
                for (int j = 0; j < 5; j++)
                    if (j != m) f[n++] = p[j];
                if (gmp_orient3d(&o, f[0], f[1], f[2], f[3]) != 0) c = 0;
            }
            coplanar5 += c;
        }
        /* equal to the independent evaluation of the scheme */
        if (exact == 0 || it % 8 == 0) {
            int want = sos_oracle_sign(&so, &o, (const double(*)[3])p, id);
            if (s != want)
                fail_msg("case %ld: sos %d, oracle of the scheme %d", it, s, want);
        }
        /* permutations of the five points together with their ids: the sign follows the
         * permutation's sign (odd swaps of the first four flip it, even ones keep it) */
        for (int t = 0; t < 6; t++) {
            int pi[5] = {0, 1, 2, 3, 4};
            int lim = t < 4 ? 4 : 5; /* mostly permutations of the first four */
            for (int i = lim - 1; i > 0; i--) {
                int j = (int)(tu_rng_u64(&r) % (unsigned)(i + 1));
                int x = pi[i];
                pi[i] = pi[j];
                pi[j] = x;
            }
            for (int i = 0; i < 5; i++) {
                memcpy(q[i], p[pi[i]], sizeof q[i]);
                qid[i] = id[pi[i]];
            }
            int s2 = sos((const double(*)[3])q, qid);
            if (s2 != s * perm_sign(pi, 5))
                fail_msg("case %ld: permutation %d%d%d%d%d gives %d, expected %d", it,
                         pi[0], pi[1], pi[2], pi[3], pi[4], s2, s * perm_sign(pi, 5));
        }
    }
    /* the degenerate generators hit both phases of the perturbation */
    assert_true(zero_exact > 5000);
    assert_true(coplanar5 > 500);
    sos_oracle_clear(&so);
    oracle_clear(&o);
}

/* Coincident points with distinct ids: never 0, and the documented rule: the point with
 * the smaller id is lifted more, so e == a is outside (for orient3d(a,b,c,d) > 0) iff
 * id(e) < id(a). Also five coincident points. */
static void test_sos_coincident(void **state) {
    (void)state;
    tu_rng r = {808};
    double p[5][3];
    int64_t id[5];
    for (long it = 0; it < 20000; it++) {
        double s = rand_scale(&r), off[3];
        rand_offset(&r, s, off);
        for (int i = 0; i < 4; i++) rand_point(&r, s, off, p[i]);
        double o3 = as_orient3d(p[0], p[1], p[2], p[3]);
        if (o3 == 0) continue;
        if (o3 < 0) { /* make a, b, c, d positive */
            double t[3];
            memcpy(t, p[0], sizeof t);
            memcpy(p[0], p[1], sizeof t);
            memcpy(p[1], t, sizeof t);
        }
        int j = (int)(tu_rng_u64(&r) % 4);
        memcpy(p[4], p[j], sizeof p[4]);
        rand_ids(&r, id);
        int s5 = sos((const double(*)[3])p, id);
        assert_int_equal(s5, id[4] < id[j] ? -1 : 1);
    }
    for (long it = 0; it < 2000; it++) {
        double s = rand_scale(&r), off[3];
        rand_offset(&r, s, off);
        rand_point(&r, s, off, p[0]);
        for (int i = 1; i < 5; i++) memcpy(p[i], p[0], sizeof p[0]);
        if (it % 2) memcpy(p[2], p[3], sizeof p[0]), p[3][0] = nudge(p[3][0], 1);
        rand_ids(&r, id);
        int s5 = sos((const double(*)[3])p, id);
        assert_true(s5 == 1 || s5 == -1);
        int64_t sw[5] = {id[1], id[0], id[2], id[3], id[4]};
        double q[5][3];
        memcpy(q, p, sizeof q);
        memcpy(q[0], p[1], sizeof q[0]);
        memcpy(q[1], p[0], sizeof q[0]);
        assert_int_equal(sos((const double(*)[3])q, sw), -s5);
    }
}

/* ====================================================================================== */
/* bad input                                                                              */
/* ====================================================================================== */

static void test_nonfinite(void **state) {
    (void)state;
    const double bad[4] = {NAN, INFINITY, -INFINITY, -NAN};
    tu_rng r = {909};
    for (int it = 0; it < 2000; it++) {
        double p[5][3];
        for (int i = 0; i < 5; i++)
            for (int k = 0; k < 3; k++) p[i][k] = tu_rng_range(&r, -1, 1);
        int nb = 1 + (int)(tu_rng_u64(&r) % 3);
        for (int t = 0; t < nb; t++)
            p[tu_rng_u64(&r) % 5][tu_rng_u64(&r) % 3] = bad[tu_rng_u64(&r) % 4];
        /* orient3d sees only the first four points */
        int o_bad = 0;
        for (int i = 0; i < 4; i++)
            for (int k = 0; k < 3; k++) o_bad |= !isfinite(p[i][k]);
        double o = anistar_orient3d(p[0], p[1], p[2], p[3]);
        if (o_bad)
            assert_true(isnan(o));
        else
            assert_false(isnan(o));
        assert_true(isnan(anistar_insphere(p[0], p[1], p[2], p[3], p[4])));
        assert_true(isnan(as_insphere_exact(p[0], p[1], p[2], p[3], p[4])));
        if (o_bad) assert_true(isnan(as_orient3d_exact(p[0], p[1], p[2], p[3])));
    }
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0, 0, 1};
    double inf[3] = {INFINITY, 0, 0}, ninf[3] = {-INFINITY, INFINITY, 0};
    assert_true(isnan(anistar_orient3d(inf, b, c, d)));
    assert_true(isnan(anistar_orient3d(a, b, c, inf)));
    assert_true(isnan(anistar_orient3d(ninf, inf, c, d)));
    assert_true(isnan(anistar_insphere(a, b, c, d, inf)));
    assert_true(isnan(anistar_insphere(inf, inf, inf, inf, inf)));
    assert_true(isnan(anistar_orient3d(NULL, b, c, d)));
    assert_true(isnan(anistar_orient3d(a, b, c, NULL)));
    assert_true(isnan(anistar_insphere(a, b, c, d, NULL)));
    assert_true(isnan(anistar_insphere(NULL, b, c, d, a)));
}

int main(void) {
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_expansion_ops),
        cmocka_unit_test(test_conventions),
        cmocka_unit_test(test_orient3d_random),
        cmocka_unit_test(test_insphere_random),
        cmocka_unit_test(test_orient3d_near_degenerate),
        cmocka_unit_test(test_insphere_near_degenerate),
        cmocka_unit_test(test_insphere_on_sphere),
        cmocka_unit_test(test_degenerate),
        cmocka_unit_test(test_range_extremes),
        cmocka_unit_test(test_sos_properties),
        cmocka_unit_test(test_sos_coincident),
        cmocka_unit_test(test_nonfinite),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
