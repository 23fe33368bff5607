/*
 * expansion.h — internal: exact arithmetic on floating-point expansions (DESIGN.md 4.1).
 *
 * An expansion is an array e[0..n-1] of doubles whose exact (unrounded) sum is the value
 * it represents. The routines here keep expansions nonoverlapping (no two components
 * share a bit position) and sorted by increasing magnitude, zeros allowed anywhere on
 * input; outputs of the *_zeroelim-style routines (as_exp_sum, as_exp_scale) hold no zero
 * component except a single 0 when the value is 0, so their length is always >= 1 and
 * their last component carries the sign of the value.
 *
 * The facts used (error-free transformations two_sum / two_product with Dekker's split,
 * and the merge-then-propagate expansion sum) are Knuth's, Dekker's and Shewchuk's
 * ("Adaptive precision floating-point arithmetic and fast robust geometric predicates",
 * 1997); the code is ours.
 *
 * Requirements: IEEE-754 binary64 with round-to-nearest-even, no extended precision
 * (SSE2 on x86-64), no contraction of a*b+c into an fma (the build uses
 * -ffp-contract=off; never -ffast-math). Exactness also needs every intermediate
 * product to stay clear of overflow and every component to be a multiple of 2^-1074;
 * see the valid input range in predicates.c / anistar.h.
 *
 * Aliasing: the scalar transforms take inputs by value and write their outputs through
 * distinct pointers (x and y must not be the same object). The array routines say for
 * each whether the output may alias an input.
 */
#ifndef ANISTAR_EXPANSION_H
#define ANISTAR_EXPANSION_H

#include <float.h>
#include <math.h>

/* Unit roundoff of binary64: u = 2^-53 (half the spacing of doubles just above 1). */
#define AS_EPS (DBL_EPSILON * 0.5)
/* 2^ceil(53/2) + 1: multiplying by it splits a double into two halves of <= 26 bits. */
#define AS_SPLITTER 134217729.0

/* ---- error-free transformations on scalars ------------------------------------------ */

/* x = fl(a + b), y = (a + b) - x exactly. Needs |a| >= |b| or a == 0 (true whenever the
 * exponent of a is at least the exponent of b). */
static inline void as_fast_two_sum(double a, double b, double *x, double *y) {
    double s = a + b;
    double bv = s - a;
    *x = s;
    *y = b - bv;
}

/* x = fl(a + b), y = (a + b) - x exactly, for any a, b (Knuth's six-operation sum). */
static inline void as_two_sum(double a, double b, double *x, double *y) {
    double s = a + b;
    double bv = s - a;
    double av = s - bv;
    double br = b - bv;
    double ar = a - av;
    *x = s;
    *y = ar + br;
}

/* The rounding error of x = fl(a - b): returns (a - b) - x exactly. */
static inline double as_two_diff_tail(double a, double b, double x) {
    double bv = a - x;
    double av = x + bv;
    double br = bv - b;
    double ar = a - av;
    return ar + br;
}

/* x = fl(a - b), y = (a - b) - x exactly. */
static inline void as_two_diff(double a, double b, double *x, double *y) {
    double d = a - b;
    *x = d;
    *y = as_two_diff_tail(a, b, d);
}

/* Dekker's split: a = hi + lo exactly, hi and lo with at most 26 significant bits each
 * (the sign of lo may differ from a's). Overflows for |a| > ~2^996. */
static inline void as_split(double a, double *hi, double *lo) {
    double c = AS_SPLITTER * a;
    double big = c - a;
    double h = c - big;
    *hi = h;
    *lo = a - h;
}

/* The rounding error of x = fl(a * b) when a = ahi + alo and b = bhi + blo are already
 * split: returns a*b - x exactly. */
static inline double as_two_product_tail_split(double x, double ahi, double alo, double bhi,
                                               double blo) {
    double r1 = x - ahi * bhi;
    double r2 = r1 - alo * bhi;
    double r3 = r2 - ahi * blo;
    return alo * blo - r3;
}

/* x = fl(a * b), y = a*b - x exactly (Dekker's product; no fma). */
static inline void as_two_product(double a, double b, double *x, double *y) {
    double ahi, alo, bhi, blo;
    double p = a * b;
    as_split(a, &ahi, &alo);
    as_split(b, &bhi, &blo);
    *x = p;
    *y = as_two_product_tail_split(p, ahi, alo, bhi, blo);
}

/* x = fl(a * b), y = a*b - x exactly, with b already split into bhi + blo. */
static inline void as_two_product_presplit(double a, double b, double bhi, double blo,
                                           double *x, double *y) {
    double ahi, alo;
    double p = a * b;
    as_split(a, &ahi, &alo);
    *x = p;
    *y = as_two_product_tail_split(p, ahi, alo, bhi, blo);
}

/* x = fl(a * a), y = a*a - x exactly. */
static inline void as_two_square(double a, double *x, double *y) {
    double ahi, alo;
    double p = a * a;
    as_split(a, &ahi, &alo);
    double r1 = p - ahi * ahi;
    double r3 = r1 - (ahi + ahi) * alo;
    *x = p;
    *y = alo * alo - r3;
}

/* h[0..3] = (a1 + a0) - (b1 + b0) exactly, where (a1, a0) and (b1, b0) are two-component
 * expansions (a0, b0 the small parts). h is nonoverlapping, increasing, may hold zeros.
 * Used for the exact 2x2 minors a1 = fl(p*q), a0 = its error, etc. */
static inline void as_two_two_diff(double a1, double a0, double b1, double b0,
                                   double h[4]) {
    double m, m0, s1, s0, t;
    /* (a1, a0) - b0: three components (s1, s0, h[0]). */
    as_two_diff(a0, b0, &m, &h[0]);
    as_two_sum(a1, m, &s1, &s0);
    /* (s1, s0) - b1: three components (h[3], h[2], h[1]). */
    as_two_diff(s0, b1, &t, &h[1]);
    as_two_sum(s1, t, &m0, &h[2]);
    h[3] = m0;
}

/* ---- operations on expansions -------------------------------------------------------- */

/* h = e + f (Shewchuk's fast expansion sum with zero elimination). e and f are
 * nonoverlapping and sorted by increasing magnitude (zeros allowed); h gets at most
 * elen + flen components, at least 1. h must not alias e or f. Returns h's length. */
static inline int as_exp_sum(int elen, const double *e, int flen, const double *f,
                             double *h) {
    int i = 0, j = 0, k = 0;
    double q, qn, hh;
    /* Merge by magnitude, propagating the running sum q through two_sum. The loop is
     * written without data-dependent branches (the order of e and f components is
     * unpredictable); h[k] is written every step, which stays within h's elen + flen. */
    if (j >= flen || (i < elen && !(fabs(f[j]) < fabs(e[i])))) {
        q = e[i++];
    } else {
        q = f[j++];
    }
    while (i < elen && j < flen) {
        double ei = e[i], fj = f[j];
        int tf = fabs(fj) < fabs(ei);
        double next = tf ? fj : ei;
        j += tf;
        i += 1 - tf;
        as_two_sum(q, next, &qn, &hh);
        q = qn;
        h[k] = hh;
        k += hh != 0.0;
    }
    while (i < elen) {
        as_two_sum(q, e[i++], &qn, &hh);
        q = qn;
        h[k] = hh;
        k += hh != 0.0;
    }
    while (j < flen) {
        as_two_sum(q, f[j++], &qn, &hh);
        q = qn;
        h[k] = hh;
        k += hh != 0.0;
    }
    if (q != 0.0 || k == 0) h[k++] = q;
    return k;
}

/* h = b * e (Shewchuk's scale expansion with zero elimination). e nonoverlapping and
 * increasing (zeros allowed); h gets at most 2*elen components, at least 1. h must not
 * alias e. Returns h's length. */
static inline int as_exp_scale(int elen, const double *e, double b, double *h) {
    double bhi, blo, q, p1, p0, s, hh;
    int k = 0;
    as_split(b, &bhi, &blo);
    as_two_product_presplit(e[0], b, bhi, blo, &q, &hh);
    if (hh != 0.0) h[k++] = hh;
    for (int i = 1; i < elen; i++) {
        as_two_product_presplit(e[i], b, bhi, blo, &p1, &p0);
        as_two_sum(q, p0, &s, &hh);
        if (hh != 0.0) h[k++] = hh;
        as_fast_two_sum(p1, s, &q, &hh);
        if (hh != 0.0) h[k++] = hh;
    }
    if (q != 0.0 || k == 0) h[k++] = q;
    return k;
}

/* Compress e in place (Shewchuk's compress): the same value in as few components as one
 * top-down and one bottom-up pass of two_sum find (usually a handful: about the value's
 * significant bits / 53). Output nonoverlapping, increasing, no zeros except a single 0
 * for the value 0. Returns the new length (<= elen). In place by design; e must be
 * nonoverlapping and increasing (zeros allowed). */
static inline int as_exp_compress(int elen, double *e) {
    int bottom = elen - 1, top = 0;
    double q = e[bottom], s, t;
    /* Top-down: each write goes to index bottom > i, above everything not yet read. */
    for (int i = elen - 2; i >= 0; i--) {
        as_two_sum(q, e[i], &s, &t);
        if (t != 0.0) {
            e[bottom--] = s;
            q = t;
        } else {
            q = s;
        }
    }
    /* Bottom-up: each write goes to index top < h, below what is still to be read. */
    for (int h = bottom + 1; h < elen; h++) {
        as_two_sum(e[h], q, &s, &t);
        if (t != 0.0) e[top++] = t;
        q = s;
    }
    e[top] = q;
    return top + 1;
}

/* e = -e in place (aliasing is the point). */
static inline void as_exp_negate(int elen, double *e) {
    for (int i = 0; i < elen; i++) e[i] = -e[i];
}

/* An approximation of the value of e (the components summed from the smallest). */
static inline double as_exp_estimate(int elen, const double *e) {
    double s = e[0];
    for (int i = 1; i < elen; i++) s += e[i];
    return s;
}

/* The sign (-1, 0, +1) of a nonoverlapping expansion: the sign of its largest nonzero
 * component. */
static inline int as_exp_sign(int elen, const double *e) {
    for (int i = elen - 1; i >= 0; i--) {
        if (e[i] > 0.0) return 1;
        if (e[i] < 0.0) return -1;
    }
    return 0;
}

/* A double with the sign of e and about its value: the estimate, corrected to the sign
 * of the largest component if rounding ever disagreed (it cannot for nonoverlapping
 * expansions; the check is cheap insurance on the slow paths that call it). */
static inline double as_exp_value(int elen, const double *e) {
    int s = as_exp_sign(elen, e);
    double v = as_exp_estimate(elen, e);
    if (s == 0) return 0.0;
    if ((s > 0 && !(v > 0.0)) || (s < 0 && !(v < 0.0))) {
        for (int i = elen - 1; i >= 0; i--)
            if (e[i] != 0.0) return e[i];
    }
    return v;
}

#endif /* ANISTAR_EXPANSION_H */
