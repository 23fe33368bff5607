/*
 * defaults_case.c — see defaults_case.h and the comment of test_defaults.c.
 */
#include "defaults_case.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "mesh_check.h"
#include "test_util.h"

#include "mesher/mesher.h"
#include "surface/field.h"
#include "surface/surface.h"

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

void dc_run_case(const dcase *c, int *certified) {
    anistar_context *ctx = anistar_context_new(NULL);
    assert_non_null(ctx);
    char path[512];
    snprintf(path, sizeof path, "%s/%s", AS_TEST_DATA_DIR, c->file);
    as_surface *s = NULL;
    double iso = 0;
    if (c->image) {
        if (anistar_image_file_otsu(ctx, path, &iso) != ANISTAR_OK)
            fail_msg("%s: %s", c->file, anistar_last_error(ctx));
        if (as_image_surface_read(ctx, path, iso, 1, &s) != ANISTAR_OK)
            fail_msg("%s: %s", c->file, anistar_last_error(ctx));
    } else if (as_mesh_surface_read(ctx, path, &s) != ANISTAR_OK) {
        fail_msg("%s: %s", c->file, anistar_last_error(ctx));
    }
    as_field *f;
    if (as_field_from_spec(ctx, s, "curvature", &f) != ANISTAR_OK)
        fail_msg("%s: %s", c->file, anistar_last_error(ctx));
    as_mesher_params p;
    as_mesher_params_default(&p);
    /* the cases that must be certified run to the end (under ASan they take several
     * times their 0.1-6 s); the others are bounded */
    if (!c->must) p.max_seconds = DC_MAX_SECONDS;
    anistar_mesh *mesh = NULL;
    as_starset *ss = NULL;
    double t0 = now();
    anistar_status st = as_mesher_run_keep(ctx, s, f, &p, NULL, &mesh, &ss);
    double t1 = now();
    const char *msg = anistar_last_error(ctx);
    if (st != ANISTAR_OK) {
        if (st != ANISTAR_INCOMPLETE)
            fail_msg("%s: %s: %s", c->file, anistar_status_name(st), msg);
        assert_true(msg[0] != '\0');
        assert_null(strchr(msg, '\n'));
        assert_non_null(mesh);
        assert_int_not_equal(mesh->stats.stop_reason, ANISTAR_STOP_DONE);
        assert_false(mesh->stats.complete);
        /* bounded: the stop comes at max_seconds or before (the checks of the last pass
         * may run past it) */
        assert_true(t1 - t0 < 4 * DC_MAX_SECONDS + 30);
        print_message("defaults %-22s %-10s %7zu V %5.1f s: %.160s\n", c->file,
                      anistar_status_name(st), mesh->stats.vertices, t1 - t0, msg);
        if (c->must) fail_msg("%s must end certified with the defaults: %s", c->file, msg);
    } else {
        const anistar_mesh_stats *S = &mesh->stats;
        assert_true(S->complete);
        assert_int_equal(S->stop_reason, ANISTAR_STOP_DONE);
        assert_int_equal(S->inconsistent_facets, 0);
        /* no facet escaped the queues (the last pass over the stars found none: knot1
         * had 2 before restar kept its survivors' queue flags) */
        assert_int_equal(S->facets_swept, 0);
        assert_true(mesh->tm.nv >= 4);
        if ((!c->image || c->comps) && S->components != c->comps)
            fail_msg("%s: %zu components, the input has %zu", c->file, S->components, c->comps);
        /* an image's Euler characteristic is what certification proved against S (the
         * sample's components) unless the case gives it (comps > 0); a mesh's is the
         * input's */
        mc_limits lim = {p.r0, p.rho0, p.gamma0,
                         c->image && !c->comps ? S->euler_characteristic : c->chi,
                         1e-9 * s->radius, S->hmin};
        mc_report rep;
        mc_report_init(&rep);
        mc_check_topology(ctx, &mesh->tm, &lim, &rep);
        mc_check_shape(&mesh->tm, &lim, &rep);
        mc_check_on_surface(ctx, s, &mesh->tm, &lim, &rep);
        mc_check_stars(ctx, s, ss->xyz, ss->first_site, &mesh->tm, &lim, 1, &rep);
        mc_assert_ok(&rep, c->file);
        print_message("defaults %-22s certified  %7zu V %5.1f s (checks %.1f s, %zu unused "
                      "sites, %zu of %zu triangles unresolved, %zu speck crossings)\n",
                      c->file, mesh->tm.nv, t1 - t0, now() - t1, S->sites_unused,
                      rep.orient_unresolved, mesh->tm.nt, rep.specks_unsampled);
        (*certified)++;
    }
    if (ss) {
        as_starset_destroy(ss);
        free(ss); /* the default allocator */
    }
    as_mesh_free(mesh);
    as_field_free(f);
    as_surface_free(s);
    anistar_context_free(ctx);
}


int dc_run_all(const dcase *cases, size_t n) {
    int certified = 0, must = 0;
    for (size_t i = 0; i < n; i++) {
        dc_run_case(&cases[i], &certified);
        must += cases[i].must;
    }
    print_message("defaults: %d of %zu certified (%d must)\n", certified, n, must);
    return certified >= must;
}
