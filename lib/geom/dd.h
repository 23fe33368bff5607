/*
 * dd.h — internal: double-double arithmetic (a value hi + lo with |lo| <= ulp(hi)/2), for
 * del3's circumcenters of nearly flat tets and the insphere predicate's double-double
 * stage. Needs IEEE-754 binary64, round to nearest, no extended precision and no
 * contraction into fma (the build sets -ffp-contract=off; never -ffast-math).
 *
 * The algorithms are the classical error-free transformations (Knuth's two-sum, Dekker's
 * quick-two-sum and split product); their relative error bounds, used by predicates.c,
 * are those proved by Joldes, Muller and Popescu ("Tight and rigorous error bounds for
 * basic building blocks of double-word arithmetic", ACM TOMS 2017): as_dd_add (their
 * AccurateDWPlusDW) <= 3u^2 / (1 - 4u), as_dd_mul_d (DWTimesFP1) <= 3u^2 / 2 + 4u^3,
 * as_dd_mul (DWTimesDW1) <= 7u^2, u = 2^-53, for double-word inputs and no underflow.
 */
#ifndef ANISTAR_DD_H
#define ANISTAR_DD_H

typedef struct as_dd {
    double hi, lo;
} as_dd;

/* a + b exactly, for any a, b (Knuth). */
static inline as_dd as_dd_two_sum(double a, double b) {
    double s = a + b, bb = s - a;
    as_dd r = {s, (a - (s - bb)) + (b - bb)};
    return r;
}
/* a + b exactly when |a| >= |b| or a == 0 (Dekker). */
static inline as_dd as_dd_quick(double a, double b) {
    double s = a + b;
    as_dd r = {s, b - (s - a)};
    return r;
}
static inline void as_dd_split(double a, double *hi, double *lo) {
    double c = 134217729.0 * a; /* 2^27 + 1 */
    *hi = c - (c - a);
    *lo = a - *hi;
}
/* a * b exactly (Dekker's product). */
static inline as_dd as_dd_two_prod(double a, double b) {
    double p = a * b, ah, al, bh, bl;
    as_dd_split(a, &ah, &al);
    as_dd_split(b, &bh, &bl);
    as_dd r = {p, ((ah * bh - p) + ah * bl + al * bh) + al * bl};
    return r;
}
static inline as_dd as_dd_add(as_dd a, as_dd b) {
    as_dd s = as_dd_two_sum(a.hi, b.hi), t = as_dd_two_sum(a.lo, b.lo);
    s.lo += t.hi;
    s = as_dd_quick(s.hi, s.lo);
    s.lo += t.lo;
    return as_dd_quick(s.hi, s.lo);
}
static inline as_dd as_dd_neg(as_dd a) {
    as_dd r = {-a.hi, -a.lo};
    return r;
}
static inline as_dd as_dd_sub(as_dd a, as_dd b) { return as_dd_add(a, as_dd_neg(b)); }
static inline as_dd as_dd_mul(as_dd a, as_dd b) {
    as_dd p = as_dd_two_prod(a.hi, b.hi);
    p.lo += a.hi * b.lo + a.lo * b.hi;
    return as_dd_quick(p.hi, p.lo);
}
/* a * b for a double b. */
static inline as_dd as_dd_mul_d(as_dd a, double b) {
    as_dd p = as_dd_two_prod(a.hi, b);
    p.lo += a.lo * b;
    return as_dd_quick(p.hi, p.lo);
}
static inline as_dd as_dd_div(as_dd a, as_dd b) {
    double q1 = a.hi / b.hi;
    as_dd r = as_dd_sub(a, as_dd_mul(b, (as_dd){q1, 0}));
    double q2 = r.hi / b.hi;
    r = as_dd_sub(r, as_dd_mul(b, (as_dd){q2, 0}));
    double q3 = r.hi / b.hi;
    as_dd q = as_dd_quick(q1, q2);
    return as_dd_add(q, (as_dd){q3, 0});
}

#endif /* ANISTAR_DD_H */
