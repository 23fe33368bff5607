/*
 * estimate.c — the up-front estimate of a run's size (DESIGN.md 4.5). See refine.h.
 */
#include "mesher/refine.h"

anistar_status as_mesher_estimate(as_starset *ss, const as_mesher_params *prm, double *vertices,
                                  double *bytes) {
    (void)ss;
    (void)prm;
    *vertices = 0;
    *bytes = 0;
    return ANISTAR_OK;
}
