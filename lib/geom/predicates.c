/* PLACEHOLDER — being replaced by the exact implementation (issue 2). */
#include "geom/predicates.h"
double as_orient3d_fast(const double *a, const double *b, const double *c, const double *d) {
    double adx = a[0] - d[0], bdx = b[0] - d[0], cdx = c[0] - d[0];
    double ady = a[1] - d[1], bdy = b[1] - d[1], cdy = c[1] - d[1];
    double adz = a[2] - d[2], bdz = b[2] - d[2], cdz = c[2] - d[2];
    return adx * (bdy * cdz - bdz * cdy) + bdx * (cdy * adz - cdz * ady) +
           cdx * (ady * bdz - adz * bdy);
}
double as_orient3d(const double *a, const double *b, const double *c, const double *d) {
    return as_orient3d_fast(a, b, c, d);
}
double as_orient3d_exact(const double *a, const double *b, const double *c, const double *d) {
    return as_orient3d_fast(a, b, c, d);
}
double as_insphere_fast(const double *a, const double *b, const double *c, const double *d,
                        const double *e) {
    (void)a; (void)b; (void)c; (void)d; (void)e;
    return 0.0;
}
double as_insphere(const double *a, const double *b, const double *c, const double *d,
                   const double *e) {
    return as_insphere_fast(a, b, c, d, e);
}
double as_insphere_exact(const double *a, const double *b, const double *c, const double *d,
                         const double *e) {
    return as_insphere_fast(a, b, c, d, e);
}
int as_insphere_sos(const double *a, const double *b, const double *c, const double *d,
                    const double *e, int64_t ia, int64_t ib, int64_t ic, int64_t id,
                    int64_t ie) {
    (void)ia; (void)ib; (void)ic; (void)id; (void)ie;
    return as_insphere(a, b, c, d, e) > 0 ? 1 : -1;
}
