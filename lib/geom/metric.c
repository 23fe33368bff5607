/* PLACEHOLDER — being replaced by the real implementation (issue 2). */
#include "geom/metric.h"
#include <string.h>
int as_metric_frame_init(as_metric_frame *mf, const double m[6]) {
    memset(mf, 0, sizeof *mf);
    (void)m;
    return -1;
}
void as_metric_apply(const as_metric_frame *mf, const double x[3], double y[3]) {
    (void)mf; y[0] = x[0]; y[1] = x[1]; y[2] = x[2];
}
double as_metric_dist(const as_metric_frame *mf, const double a[3], const double b[3]) {
    (void)mf; (void)a; (void)b;
    return 0;
}
double as_metric_distortion(const as_metric_frame *a, const as_metric_frame *b) {
    (void)a; (void)b;
    return 1;
}
