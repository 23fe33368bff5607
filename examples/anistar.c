/*
 * anistar — the command-line tool: one more client of the public API (DESIGN.md 3,
 * docs/cli.md). It parses options into API calls and nothing else.
 *
 *   anistar probe SURFACE [--metric SPEC] --at X,Y,Z
 *   anistar info FILE [--json] [--iso V] [--inside greater|less]
 *   anistar render MESH -o OUT.png [options]
 *   anistar mesh SURFACE [options] -o OUT [-o OUT2 ...]
 *   anistar --help | --version
 *
 * Exit status: 0 done (mesh: a certified mesh); 1 error (one line on stderr); 2 usage
 * error (one line on stderr); 3 (mesh) stopped before a certified mesh (a limit, a stall,
 * SIGINT/SIGTERM, a failed final check): every output written with the consistent facets,
 * one line on stderr saying why. docs/cli.md "Exit status" says what each guarantees.
 *
 * Unlike the library, the tool has process-wide state: the mesher that a SIGINT or SIGTERM
 * handler stops (set only while anistar_mesher_run runs).
 */
#include "anistar.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <signal.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

enum { EXIT_OK = 0, EXIT_ERROR = 1, EXIT_USAGE = 2, EXIT_INCOMPLETE = 3 };

/* One line on stderr, "anistar: ...". */
static void say(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("anistar: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* ---- option values ---------------------------------------------------------------- */

/* Parse exactly n comma-separated finite numbers filling the whole string. */
static int parse_numbers(const char *s, double *v, int n) {
    const char *p = s;
    for (int i = 0; i < n; i++) {
        char *end;
        errno = 0;
        if (*p == '\0' || *p == ',' || *p == ' ') return -1;
        v[i] = strtod(p, &end);
        if (end == p || errno == ERANGE || !isfinite(v[i])) return -1;
        p = end;
        if (i + 1 < n) {
            if (*p != ',') return -1;
            p++;
        }
    }
    return *p == '\0' ? 0 : -1;
}

/* ---- SURFACE (shared by probe and, later, mesh) ------------------------------------ */

typedef struct surface_opts {
    const char *implicit; /* --implicit EXPR */
    const char *builtin;  /* --builtin NAME[,P=V...] */
    const char *file;     /* FILE: a triangle mesh or a 3D image */
    double bound[4];      /* --bound CX,CY,CZ,R */
    int has_bound;
    double iso; /* --iso V (images) */
    int has_iso;
    int inside; /* --inside greater|less (images): ANISTAR_INSIDE_GREATER / _LESS, 0 unset */
    int fit;    /* --fit auto|interpolate|smooth (images): ANISTAR_FIT_*, -1 unset */
    int fit_used; /* images: the fit the surface uses (anistar_surface_image_fit) */
    int quiet;    /* --quiet: no note of the automatic fit */
} surface_opts;

/* What a SURFACE FILE is, by its extension (case-insensitive). */
enum { FILE_UNKNOWN, FILE_MESH, FILE_IMAGE };

static int file_kind(const char *path) {
    const char *slash = strrchr(path, '/'), *dot = strrchr(slash ? slash : path, '.');
    if (!dot) return FILE_UNKNOWN;
    static const struct {
        const char *ext;
        int kind;
    } exts[] = {{"off", FILE_MESH},   {"obj", FILE_MESH},   {"ply", FILE_MESH},
                {"stl", FILE_MESH},   {"mesh", FILE_MESH},  {"meshb", FILE_MESH},
                {"vtk", FILE_MESH},   {"vtu", FILE_MESH},   {"inr", FILE_IMAGE},
                {"nrrd", FILE_IMAGE}, {"nhdr", FILE_IMAGE}, {"mha", FILE_IMAGE},
                {"mhd", FILE_IMAGE}};
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++) {
        const char *a = dot + 1, *b = exts[i].ext;
        while (*a && *b && (*a | 0x20) == *b) {
            a++;
            b++;
        }
        if (!*a && !*b) return exts[i].kind;
    }
    return FILE_UNKNOWN;
}

/*
 * Try to consume a SURFACE option at argv[*i]. Returns 1 if consumed (*i advanced past
 * its value), 0 if argv[*i] is not a SURFACE option, -1 on a usage error (reported).
 */
static int surface_option(surface_opts *so, int argc, char **argv, int *i) {
    const char *a = argv[*i];
    int takes_value = !strcmp(a, "--implicit") || !strcmp(a, "--builtin") ||
                      !strcmp(a, "--bound") || !strcmp(a, "--iso") || !strcmp(a, "--inside") ||
                      !strcmp(a, "--fit");
    if (!takes_value) {
        if (a[0] == '-' && a[1] != '\0') return 0;
        if (so->file) {
            say("unexpected argument '%s' (only one SURFACE file)", a);
            return -1;
        }
        so->file = a;
        *i += 1;
        return 1;
    }
    if (*i + 1 >= argc) {
        say("%s needs a value", a);
        return -1;
    }
    const char *v = argv[*i + 1];
    if (!strcmp(a, "--implicit") || !strcmp(a, "--builtin")) {
        const char **dst = a[2] == 'i' ? &so->implicit : &so->builtin;
        if (*dst) {
            say("%s given twice", a);
            return -1;
        }
        *dst = v;
    } else if (!strcmp(a, "--bound")) {
        if (so->has_bound) {
            say("--bound given twice");
            return -1;
        }
        if (parse_numbers(v, so->bound, 4) || !(so->bound[3] > 0)) {
            say("--bound expects CX,CY,CZ,R with R > 0, got '%s'", v);
            return -1;
        }
        so->has_bound = 1;
    } else if (!strcmp(a, "--fit")) {
        if (so->fit >= 0) {
            say("--fit given twice");
            return -1;
        }
        if (!strcmp(v, "auto")) so->fit = ANISTAR_FIT_AUTO;
        else if (!strcmp(v, "interpolate")) so->fit = ANISTAR_FIT_INTERPOLATE;
        else if (!strcmp(v, "smooth")) so->fit = ANISTAR_FIT_SMOOTH;
        else {
            say("--fit expects auto, interpolate or smooth, got '%s'", v);
            return -1;
        }
    } else if (!strcmp(a, "--inside")) {
        if (so->inside) {
            say("--inside given twice");
            return -1;
        }
        if (!strcmp(v, "greater")) so->inside = ANISTAR_INSIDE_GREATER;
        else if (!strcmp(v, "less")) so->inside = ANISTAR_INSIDE_LESS;
        else {
            say("--inside expects greater or less, got '%s'", v);
            return -1;
        }
    } else {
        if (so->has_iso) {
            say("--iso given twice");
            return -1;
        }
        if (parse_numbers(v, &so->iso, 1)) {
            say("--iso expects a number, got '%s'", v);
            return -1;
        }
        so->has_iso = 1;
    }
    *i += 2;
    return 1;
}

/* Check the combination of SURFACE options (usage errors). */
static int surface_check(const surface_opts *so) {
    int kinds = !!so->implicit + !!so->builtin + !!so->file;
    if (kinds == 0) {
        say("missing SURFACE: FILE, --implicit \"EXPR\" --bound CX,CY,CZ,R or --builtin NAME");
        return -1;
    }
    if (kinds > 1) {
        say("give one SURFACE: FILE, --implicit or --builtin");
        return -1;
    }
    if (so->implicit && !so->has_bound) {
        say("--implicit needs --bound CX,CY,CZ,R");
        return -1;
    }
    if (so->has_bound && !so->implicit) {
        say("--bound goes with --implicit");
        return -1;
    }
    int kind = so->file ? file_kind(so->file) : FILE_UNKNOWN;
    if (so->file && kind == FILE_UNKNOWN) {
        say("%s: unknown SURFACE file extension (expected a mesh .off .obj .ply .stl .mesh "
            ".meshb .vtk .vtu or an image .inr .nrrd .nhdr .mha .mhd)",
            so->file);
        return -1;
    }
    if ((so->has_iso || so->inside || so->fit >= 0) && kind != FILE_IMAGE) {
        say("%s goes with an image FILE (.inr .nrrd .nhdr .mha .mhd)",
            so->has_iso ? "--iso" : so->inside ? "--inside" : "--fit");
        return -1;
    }
    return 0;
}

/* The advice appended to "no surface" when an image's smoothing fit was chosen for it:
 * the smoothing blurs away parts of a voxel or two, which the interpolating fit keeps. */
static const char *smooth_hint(const surface_opts *so, anistar_status st) {
    if (st != ANISTAR_ENOSURFACE || so->fit_used != ANISTAR_FIT_SMOOTH) return "";
    return " (the smoothing B-spline of a label image or mask blurs away parts a voxel or two "
           "across: --fit interpolate keeps them)";
}

/* Build the surface. Returns an exit status (EXIT_OK on success). */
static int surface_make(anistar_context *ctx, surface_opts *so, anistar_surface **s) {
    anistar_status st;
    if (so->builtin) {
        st = anistar_surface_builtin(ctx, so->builtin, s);
    } else if (so->implicit) {
        st = anistar_surface_from_expression(ctx, so->implicit, so->bound, so->bound[3], s);
    } else {
        /* files: every failure (unreadable, malformed, not closed, no surface at iso) is
         * an error, not a usage error */
        st = ANISTAR_OK;
        if (file_kind(so->file) == FILE_IMAGE && !so->has_iso) {
            /* no --iso: Otsu's threshold of the voxels (said on stderr, kept in --stats) */
            st = anistar_image_file_otsu(ctx, so->file, &so->iso);
            if (st == ANISTAR_OK) {
                so->has_iso = 1;
                fprintf(stderr, "anistar: %s: no --iso: Otsu's threshold %.17g\n", so->file,
                        so->iso);
            }
        }
        if (st != ANISTAR_OK)
            ;
        else if (file_kind(so->file) == FILE_IMAGE) {
            st = anistar_surface_from_image_file_fit(
                ctx, so->file, so->iso, so->inside ? so->inside : ANISTAR_INSIDE_GREATER,
                so->fit >= 0 ? so->fit : ANISTAR_FIT_AUTO, s);
            if (st == ANISTAR_OK) so->fit_used = anistar_surface_image_fit(*s);
            if (st == ANISTAR_OK && so->fit < 0 && so->fit_used == ANISTAR_FIT_SMOOTH &&
                !so->quiet)
                fprintf(stderr,
                        "anistar: %s: at most 16 distinct voxel values (labels or a mask): the "
                        "smoothing B-spline (--fit interpolate for the interpolating one)\n",
                        so->file);
        }
        else
            st = anistar_surface_read(ctx, so->file, s);
        if (st == ANISTAR_OK) return EXIT_OK;
        say("%s", anistar_last_error(ctx));
        return EXIT_ERROR;
    }
    if (st == ANISTAR_OK) return EXIT_OK;
    say("%s", anistar_last_error(ctx));
    /* a bad name, parameter or expression is a usage error; anything else is not */
    return st == ANISTAR_EINVAL || st == ANISTAR_EFORMAT ? EXIT_USAGE : EXIT_ERROR;
}

/* ---- JSON output ------------------------------------------------------------------- */

static void json_vec(const char *key, const double *v, int n, int last) {
    printf("  \"%s\": [", key);
    for (int i = 0; i < n; i++) printf("%s%.17g", i ? ", " : "", v[i]);
    printf("]%s\n", last ? "" : ",");
}

static void json_string(const char *s) {
    putchar('"');
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        if (*c == '"' || *c == '\\') printf("\\%c", *c);
        else if (*c < 0x20) printf("\\u%04x", *c);
        else putchar(*c);
    }
    putchar('"');
}

/* ---- probe ------------------------------------------------------------------------- */

static int cmd_probe(int argc, char **argv) {
    surface_opts so;
    memset(&so, 0, sizeof so);
    so.fit = -1;
    const char *metric = NULL;
    double at[3];
    int has_at = 0;
    for (int i = 0; i < argc;) {
        const char *a = argv[i];
        if (!strcmp(a, "--at") || !strcmp(a, "--metric")) {
            if (i + 1 >= argc) {
                say("%s needs a value", a);
                return EXIT_USAGE;
            }
            if (a[2] == 'a') {
                if (has_at) {
                    say("--at given twice");
                    return EXIT_USAGE;
                }
                if (parse_numbers(argv[i + 1], at, 3)) {
                    say("--at expects X,Y,Z (three finite numbers), got '%s'", argv[i + 1]);
                    return EXIT_USAGE;
                }
                has_at = 1;
            } else {
                if (metric) {
                    say("--metric given twice");
                    return EXIT_USAGE;
                }
                metric = argv[i + 1];
            }
            i += 2;
            continue;
        }
        int r = surface_option(&so, argc, argv, &i);
        if (r < 0) return EXIT_USAGE;
        if (r == 0) {
            say("probe: unknown option '%s' (try 'anistar --help')", a);
            return EXIT_USAGE;
        }
    }
    if (surface_check(&so)) return EXIT_USAGE;
    if (!has_at) {
        say("probe needs --at X,Y,Z");
        return EXIT_USAGE;
    }
    if (!metric) metric = "curvature";

    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        say("out of memory");
        return EXIT_ERROR;
    }
    int rc = EXIT_OK;
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    if (anistar_metric_spec_check(ctx, metric)) {
        say("--metric: %s", anistar_last_error(ctx));
        rc = EXIT_USAGE;
        goto done;
    }
    rc = surface_make(ctx, &so, &s);
    if (rc) goto done;
    double f, g[3], q[3], n[3], k[2], d1[3], d2[3], t[6];
    if (anistar_surface_eval(s, at, &f, g, NULL) || anistar_surface_project(s, at, q) ||
        anistar_surface_normal(s, q, n) || anistar_surface_curvature(s, q, k, d1, d2) ||
        anistar_metric_from_spec(ctx, s, metric, &m) || anistar_metric_eval(m, q, t)) {
        say("%s", anistar_last_error(ctx));
        rc = EXIT_ERROR;
        goto done;
    }
    double dist = sqrt((at[0] - q[0]) * (at[0] - q[0]) + (at[1] - q[1]) * (at[1] - q[1]) +
                       (at[2] - q[2]) * (at[2] - q[2]));
    printf("{\n");
    json_vec("point", at, 3, 0);
    printf("  \"f\": %.17g,\n", f);
    json_vec("gradient", g, 3, 0);
    json_vec("projection", q, 3, 0);
    printf("  \"distance\": %.17g,\n", dist);
    json_vec("normal", n, 3, 0);
    json_vec("curvatures", k, 2, 0);
    printf("  \"directions\": [[%.17g, %.17g, %.17g], [%.17g, %.17g, %.17g]],\n", d1[0], d1[1],
           d1[2], d2[0], d2[1], d2[2]);
    printf("  \"metric\": ");
    json_string(metric);
    printf(",\n");
    json_vec("tensor", t, 6, 1);
    printf("}\n");
    if (fflush(stdout) != 0) {
        say("cannot write the output");
        rc = EXIT_ERROR;
    }
done:
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return rc;
}

/* ---- info -------------------------------------------------------------------------- */

/* A JSON number: %.17g, or null when not finite. */
static void json_num(double x) {
    if (isfinite(x)) printf("%.17g", x);
    else printf("null");
}

static void json_num_array(const double *v, int n) {
    putchar('[');
    for (int i = 0; i < n; i++) {
        if (i) printf(", ");
        json_num(v[i]);
    }
    putchar(']');
}

static const char *yes_no(int b) { return b ? "yes" : "no"; }
static const char *true_false(int b) { return b ? "true" : "false"; }

static void info_mesh_json(const char *path, const anistar_mesh_info *mi) {
    printf("{\n  \"file\": ");
    json_string(path);
    printf(",\n  \"kind\": \"mesh\",\n");
    printf("  \"vertices\": %zu,\n  \"used_vertices\": %zu,\n  \"triangles\": %zu,\n"
           "  \"edges\": %zu,\n  \"components\": %zu,\n",
           mi->vertices, mi->used_vertices, mi->triangles, mi->edges, mi->components);
    printf("  \"closed_manifold\": %s,\n  \"border_edges\": %zu,\n  \"nonmanifold_edges\": %zu,\n"
           "  \"nonmanifold_vertices\": %zu,\n  \"degenerate_triangles\": %zu,\n"
           "  \"nonorientable_components\": %zu,\n  \"euler_characteristic\": %lld,\n",
           true_false(mi->closed_manifold), mi->border_edges, mi->nonmanifold_edges,
           mi->nonmanifold_vertices, mi->degenerate_triangles, mi->nonorientable_components,
           mi->euler_characteristic);
    printf("  \"self_intersections\": {\"count\": %zu, \"capped\": %s, \"pairs\": [",
           mi->self_intersections, true_false(mi->self_intersections_capped));
    for (size_t i = 0; i < mi->pairs_listed; i++)
        printf("%s[%ld, %ld]", i ? ", " : "", (long)mi->pairs[i][0], (long)mi->pairs[i][1]);
    printf("]},\n  \"bounding_box\": {\"min\": ");
    json_num_array(mi->bbox_min, 3);
    printf(", \"max\": ");
    json_num_array(mi->bbox_max, 3);
    printf("},\n  \"edge_length\": {\"min\": ");
    json_num(mi->edge_min);
    printf(", \"mean\": ");
    json_num(mi->edge_mean);
    printf(", \"max\": ");
    json_num(mi->edge_max);
    printf("},\n  \"per_component\": [");
    for (size_t c = 0; c < mi->components_listed; c++) {
        const anistar_component_info *ci = &mi->component[c];
        printf("%s\n    {\"vertices\": %zu, \"edges\": %zu, \"triangles\": %zu, "
               "\"euler_characteristic\": %lld, \"closed\": %s, \"orientable\": %s, \"genus\": ",
               c ? "," : "", ci->vertices, ci->edges, ci->triangles, ci->euler_characteristic,
               true_false(ci->closed), true_false(ci->orientable));
        if (ci->genus >= 0) printf("%lld}", ci->genus);
        else printf("null}");
    }
    printf("%s]\n}\n", mi->components_listed ? "\n  " : "");
}

static void info_mesh_text(const char *path, const anistar_mesh_info *mi) {
    printf("%s: triangle mesh\n", path);
    printf("  vertices                   %zu (%zu in triangles)\n", mi->vertices,
           mi->used_vertices);
    printf("  triangles                  %zu\n", mi->triangles);
    printf("  edges                      %zu\n", mi->edges);
    printf("  components                 %zu\n", mi->components);
    printf("  closed 2-manifold          %s\n", yes_no(mi->closed_manifold));
    printf("  border edges               %zu\n", mi->border_edges);
    printf("  non-manifold edges         %zu\n", mi->nonmanifold_edges);
    printf("  non-manifold vertices      %zu\n", mi->nonmanifold_vertices);
    printf("  degenerate triangles       %zu\n", mi->degenerate_triangles);
    printf("  non-orientable components  %zu\n", mi->nonorientable_components);
    printf("  Euler characteristic       %lld\n", mi->euler_characteristic);
    printf("  self-intersections         %zu%s", mi->self_intersections,
           mi->self_intersections_capped ? " or more (counting stopped)" : "");
    for (size_t i = 0; i < mi->pairs_listed; i++)
        printf("%s%ld-%ld", i ? ", " : ": triangles ", (long)mi->pairs[i][0],
               (long)mi->pairs[i][1]);
    printf("%s\n", mi->self_intersections > mi->pairs_listed ? ", ..." : "");
    printf("  bounding box               [%g, %g, %g] - [%g, %g, %g]\n", mi->bbox_min[0],
           mi->bbox_min[1], mi->bbox_min[2], mi->bbox_max[0], mi->bbox_max[1], mi->bbox_max[2]);
    printf("  edge length                min %g, mean %g, max %g\n", mi->edge_min,
           mi->edge_mean, mi->edge_max);
    for (size_t c = 0; c < mi->components_listed; c++) {
        const anistar_component_info *ci = &mi->component[c];
        printf("  component %-4zu             %zu vertices, %zu triangles, Euler "
               "characteristic %lld, %s, %s",
               c + 1, ci->vertices, ci->triangles, ci->euler_characteristic,
               ci->closed ? "closed" : "open or non-manifold",
               ci->orientable ? "orientable" : "non-orientable");
        if (ci->genus >= 0) printf(", genus %lld", ci->genus);
        printf("\n");
    }
    if (mi->components > mi->components_listed)
        printf("  (%zu more components)\n", mi->components - mi->components_listed);
}

static void info_image_json(const char *path, const anistar_image_info *ii) {
    printf("{\n  \"file\": ");
    json_string(path);
    printf(",\n  \"kind\": \"image\",\n  \"dims\": [%zu, %zu, %zu],\n  \"voxel_type\": ",
           ii->dims[0], ii->dims[1], ii->dims[2]);
    json_string(ii->voxel_type);
    printf(",\n  \"spacing\": ");
    json_num_array(ii->spacing, 3);
    printf(",\n  \"origin\": ");
    json_num_array(ii->origin, 3);
    printf(",\n  \"direction\": ");
    json_num_array(ii->direction, 9);
    printf(",\n  \"bounding_box\": {\"min\": ");
    json_num_array(ii->bbox_min, 3);
    printf(", \"max\": ");
    json_num_array(ii->bbox_max, 3);
    printf("},\n  \"value_range\": [");
    json_num(ii->value_min);
    printf(", ");
    json_num(ii->value_max);
    printf("],\n  \"nonfinite_voxels\": %zu,\n  \"otsu\": ", ii->nonfinite);
    json_num(ii->otsu);
    printf(",\n  \"iso\": ");
    json_num(ii->iso);
    printf(",\n  \"iso_source\": \"%s\",\n  \"inside\": \"%s\",\n", ii->iso_given ? "given" : "otsu",
           ii->inside == ANISTAR_INSIDE_LESS ? "less" : "greater");
    printf("  \"voxels_inside\": %zu,\n  \"components\": %zu,\n  \"connectivity\": 6\n}\n",
           ii->voxels_inside, ii->components);
}

static void info_image_text(const char *path, const anistar_image_info *ii) {
    printf("%s: 3D image\n", path);
    printf("  dimensions                 %zu x %zu x %zu voxels (%s)\n", ii->dims[0],
           ii->dims[1], ii->dims[2], ii->voxel_type);
    printf("  spacing                    %g, %g, %g\n", ii->spacing[0], ii->spacing[1],
           ii->spacing[2]);
    printf("  origin                     %g, %g, %g\n", ii->origin[0], ii->origin[1],
           ii->origin[2]);
    printf("  bounding box               [%g, %g, %g] - [%g, %g, %g] (voxel centers)\n",
           ii->bbox_min[0], ii->bbox_min[1], ii->bbox_min[2], ii->bbox_max[0], ii->bbox_max[1],
           ii->bbox_max[2]);
    printf("  values                     %g to %g", ii->value_min, ii->value_max);
    if (ii->nonfinite) printf(" (%zu voxels NaN or infinite)", ii->nonfinite);
    printf("\n  Otsu's threshold           %.17g\n", ii->otsu);
    printf("  isovalue                   %.17g (%s), inside: values %s\n", ii->iso,
           ii->iso_given ? "--iso" : "Otsu's threshold",
           ii->inside == ANISTAR_INSIDE_LESS ? "less" : "greater");
    printf("  voxels inside              %zu\n", ii->voxels_inside);
    printf("  components                 %zu (of the voxels inside, 6-connected: sharing a "
           "face)\n",
           ii->components);
}

static int cmd_info(int argc, char **argv) {
    const char *file = NULL;
    int json = 0, has_iso = 0, inside = 0;
    double iso = NAN;
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--json")) {
            json = 1;
        } else if (!strcmp(a, "--iso") || !strcmp(a, "--inside")) {
            if (i + 1 >= argc) {
                say("%s needs a value", a);
                return EXIT_USAGE;
            }
            const char *v = argv[++i];
            if (a[2] == 'i' && a[3] == 's') {
                if (has_iso++) {
                    say("--iso given twice");
                    return EXIT_USAGE;
                }
                if (parse_numbers(v, &iso, 1)) {
                    say("--iso expects a number, got '%s'", v);
                    return EXIT_USAGE;
                }
            } else {
                if (inside) {
                    say("--inside given twice");
                    return EXIT_USAGE;
                }
                if (!strcmp(v, "greater")) inside = ANISTAR_INSIDE_GREATER;
                else if (!strcmp(v, "less")) inside = ANISTAR_INSIDE_LESS;
                else {
                    say("--inside expects greater or less, got '%s'", v);
                    return EXIT_USAGE;
                }
            }
        } else if (a[0] == '-' && a[1] != '\0') {
            say("info: unknown option '%s' (try 'anistar --help')", a);
            return EXIT_USAGE;
        } else if (file) {
            say("info: unexpected argument '%s' (only one FILE)", a);
            return EXIT_USAGE;
        } else {
            file = a;
        }
    }
    if (!file) {
        say("info needs a FILE (a triangle mesh or a 3D image)");
        return EXIT_USAGE;
    }
    int image = file_kind(file) == FILE_IMAGE;
    if ((has_iso || inside) && !image) {
        say("%s goes with an image FILE (.inr .nrrd .nhdr .mha .mhd)",
            has_iso ? "--iso" : "--inside");
        return EXIT_USAGE;
    }
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        say("out of memory");
        return EXIT_ERROR;
    }
    int rc = EXIT_OK;
    if (image) {
        anistar_image_info *ii = malloc(sizeof *ii);
        if (!ii) {
            say("out of memory");
            rc = EXIT_ERROR;
        } else if (anistar_image_file_info(ctx, file, iso,
                                           inside ? inside : ANISTAR_INSIDE_GREATER, ii)) {
            say("%s", anistar_last_error(ctx));
            rc = EXIT_ERROR;
        } else if (json) {
            info_image_json(file, ii);
        } else {
            info_image_text(file, ii);
        }
        free(ii);
    } else {
        anistar_mesh_info *mi = malloc(sizeof *mi);
        if (!mi) {
            say("out of memory");
            rc = EXIT_ERROR;
        } else if (anistar_mesh_file_info(ctx, file, mi)) {
            say("%s", anistar_last_error(ctx));
            rc = EXIT_ERROR;
        } else if (json) {
            info_mesh_json(file, mi);
        } else {
            info_mesh_text(file, mi);
        }
        free(mi);
    }
    anistar_context_free(ctx);
    if (rc == EXIT_OK && fflush(stdout) != 0) {
        say("cannot write the output");
        rc = EXIT_ERROR;
    }
    return rc;
}

/* ---- render ------------------------------------------------------------------------ */

/* Case-insensitive "ends with ext" (ext lowercase, with its dot). */
static int has_extension(const char *path, const char *ext) {
    size_t n = strlen(path), k = strlen(ext);
    if (n <= k) return 0;
    for (size_t i = 0; i < k; i++) {
        char c = path[n - k + i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != ext[i]) return 0;
    }
    return 1;
}

/* "WxH" with 1 <= W, H <= ANISTAR_RENDER_MAX_SIDE. */
static int parse_size(const char *s, int *w, int *h) {
    char *end;
    errno = 0;
    if (*s < '0' || *s > '9') return -1;
    long a = strtol(s, &end, 10);
    if (errno || (*end != 'x' && *end != 'X')) return -1;
    const char *q = end + 1;
    if (*q < '0' || *q > '9') return -1;
    long b = strtol(q, &end, 10);
    if (errno || *end != '\0') return -1;
    if (a < 1 || b < 1 || a > ANISTAR_RENDER_MAX_SIDE || b > ANISTAR_RENDER_MAX_SIDE) return -1;
    *w = (int)a;
    *h = (int)b;
    return 0;
}

static int cmd_render(int argc, char **argv) {
    anistar_render_options opt;
    anistar_render_options_init(&opt);
    const char *mesh = NULL, *out = NULL;
    int seen[8] = {0};
    static const char *const valued[] = {"-o",     "--color", "--view", "--size",
                                         "--edges", "--sol",   "--range", "--up"};
    for (int i = 0; i < argc; i++) {
        const char *a = argv[i];
        int k = -1;
        for (int j = 0; j < 8; j++)
            if (!strcmp(a, valued[j])) k = j;
        if (k < 0) {
            if (a[0] == '-' && a[1] != '\0') {
                say("render: unknown option '%s' (try 'anistar --help')", a);
                return EXIT_USAGE;
            }
            if (mesh) {
                say("render: unexpected argument '%s' (only one MESH file)", a);
                return EXIT_USAGE;
            }
            mesh = a;
            continue;
        }
        if (i + 1 >= argc) {
            say("%s needs a value", a);
            return EXIT_USAGE;
        }
        if (seen[k]++) {
            say("%s given twice", a);
            return EXIT_USAGE;
        }
        const char *v = argv[++i];
        double num[2];
        switch (k) {
        case 0:
            out = v;
            break;
        case 1:
            if (!strcmp(v, "quality")) opt.color = ANISTAR_COLOR_QUALITY;
            else if (!strcmp(v, "anisotropy")) opt.color = ANISTAR_COLOR_ANISOTROPY;
            else if (!strcmp(v, "none")) opt.color = ANISTAR_COLOR_NONE;
            else {
                say("--color expects quality, anisotropy or none, got '%s'", v);
                return EXIT_USAGE;
            }
            break;
        case 2:
            if (parse_numbers(v, num, 2)) {
                say("--view expects AZ,EL (two finite numbers, degrees), got '%s'", v);
                return EXIT_USAGE;
            }
            opt.azimuth = num[0];
            opt.elevation = num[1];
            break;
        case 3:
            if (parse_size(v, &opt.width, &opt.height)) {
                say("--size expects WxH with W and H in [1, %d], got '%s'",
                    ANISTAR_RENDER_MAX_SIDE, v);
                return EXIT_USAGE;
            }
            break;
        case 4:
            if (!strcmp(v, "on")) opt.edges = 1;
            else if (!strcmp(v, "off")) opt.edges = 0;
            else {
                say("--edges expects on or off, got '%s'", v);
                return EXIT_USAGE;
            }
            break;
        case 5:
            opt.sol_path = v;
            break;
        case 6:
            if (parse_numbers(v, num, 2) || !(num[0] < num[1])) {
                say("--range expects MIN,MAX (finite, MIN < MAX), got '%s'", v);
                return EXIT_USAGE;
            }
            opt.range_min = num[0];
            opt.range_max = num[1];
            break;
        default:
            if (strlen(v) != 1 || v[0] < 'x' || v[0] > 'z') {
                say("--up expects x, y or z, got '%s'", v);
                return EXIT_USAGE;
            }
            opt.up = v[0] - 'x';
            break;
        }
    }
    if (!mesh) {
        say("render needs a MESH file (.off .obj .ply .stl .mesh .meshb .vtk .vtu)");
        return EXIT_USAGE;
    }
    if (!out) {
        say("render needs -o OUT.png");
        return EXIT_USAGE;
    }
    if (!has_extension(out, ".png")) {
        say("render: the output '%s' must end with .png", out);
        return EXIT_USAGE;
    }
    /* --sol alone means --color anisotropy; another explicit --color contradicts it */
    if (opt.sol_path && !seen[1]) opt.color = ANISTAR_COLOR_ANISOTROPY;
    if (opt.sol_path && opt.color != ANISTAR_COLOR_ANISOTROPY) {
        say("--sol goes with --color anisotropy (its default when --color is not given)");
        return EXIT_USAGE;
    }
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        say("out of memory");
        return EXIT_ERROR;
    }
    int rc = EXIT_OK;
    anistar_status st = anistar_render_file(ctx, mesh, out, &opt);
    if (st) {
        say("%s", anistar_last_error(ctx));
        rc = st == ANISTAR_EINVAL ? EXIT_USAGE : EXIT_ERROR;
    }
    anistar_context_free(ctx);
    return rc;
}

/* ---- mesh -------------------------------------------------------------------------- */

/* The numeric options of mesh, in the order of their anistar_param (DESIGN.md 3). */
static const struct mesh_param {
    const char *flag;
    const char *json; /* its key in the --stats "parameters" */
    anistar_param key;
    int integer; /* 1: an integer value */
} mesh_params[] = {
    {"--r0", "r0", ANISTAR_PARAM_R0, 0},
    {"--gamma0", "gamma0", ANISTAR_PARAM_GAMMA0, 0},
    {"--rho0", "rho0", ANISTAR_PARAM_RHO0, 0},
    {"--beta", "beta", ANISTAR_PARAM_BETA, 0},
    {"--delta", "delta", ANISTAR_PARAM_DELTA, 0},
    {"--approx", "approx", ANISTAR_PARAM_APPROX, 0},
    {"--max-vertices", "max_vertices", ANISTAR_PARAM_MAX_VERTICES, 1},
    {"--max-seconds", "max_seconds", ANISTAR_PARAM_MAX_SECONDS, 0},
    {"--seed", "seed", ANISTAR_PARAM_SEED, 1},
    {"--pick-tries", "pick_tries", ANISTAR_PARAM_PICK_TRIES, 1},
    {"--max-stall", "max_stall", ANISTAR_PARAM_MAX_STALL, 1},
    {"--hmin", "hmin", ANISTAR_PARAM_HMIN, 0},
    {"--hmax", "hmax", ANISTAR_PARAM_HMAX, 0},
    {"--aniso-cap", "aniso_cap", ANISTAR_PARAM_ANISO_CAP, 1},
    {"--threads", "threads", ANISTAR_PARAM_THREADS, 1},
};
#define NMESH_PARAMS (sizeof mesh_params / sizeof mesh_params[0])
#define MAX_OUTPUTS 16
enum { MESH_SEED = 8 }; /* the index of --seed in mesh_params */
enum { MESH_THREADS = 14 }; /* the index of --threads in mesh_params */

/* A JSON string on f. */
static void json_string_to(FILE *f, const char *s) {
    fputc('"', f);
    for (const unsigned char *c = (const unsigned char *)s; *c; c++) {
        if (*c == '"' || *c == '\\') fprintf(f, "\\%c", *c);
        else if (*c < 0x20) fprintf(f, "\\u%04x", *c);
        else fputc(*c, f);
    }
    fputc('"', f);
}

/* The output formats of -o (anistar_mesh_write picks the writer by extension). */
static int mesh_output_ok(const char *path) {
    static const char *const exts[] = {".off", ".obj", ".ply", ".stl", ".mesh", ".meshb",
                                       ".vtk", ".vtu"};
    for (size_t i = 0; i < sizeof exts / sizeof exts[0]; i++)
        if (has_extension(path, exts[i])) return 1;
    return 0;
}

/*
 * Check, before anything is meshed, that the output `path` (of option `opt`) can be
 * written. Returns 0, or -1 after one line naming the path and the reason.
 * design: create it exclusively (O_EXCL: it did not exist, so remove it again); if it
 * exists, open it for appending, which never truncates it.
 */
static int output_check(const char *opt, const char *path) {
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL, 0666);
    if (fd >= 0) {
        close(fd);
        remove(path);
        return 0;
    }
    if (errno == EEXIST) fd = open(path, O_WRONLY | O_APPEND);
    if (fd >= 0) {
        close(fd);
        return 0;
    }
    say("%s '%s': cannot open for writing: %s", opt, path, strerror(errno));
    return -1;
}

/* ---- SIGINT / SIGTERM during the run ------------------------------------------------ */

/*
 * design: the handlers live only while anistar_mesher_run runs. The handler records the
 * signal, puts both signals back to their default action (a second one kills the
 * process) and asks the mesher to stop, which is async-signal-safe (a lock-free atomic
 * store): the run ends after the insertion in progress with ANISTAR_INCOMPLETE and the
 * partial mesh, as at --max-seconds. A signal ignored when the tool started stays ignored.
 */
_Static_assert(ATOMIC_POINTER_LOCK_FREE == 2, "the signal handler needs a lock-free pointer");
static _Atomic(anistar_mesher *) stop_target; /* the running mesher, or NULL */
static volatile sig_atomic_t stop_signal;      /* the signal that stopped it, or 0 */
static const int stop_signals[2] = {SIGINT, SIGTERM};
static struct sigaction stop_saved[2]; /* the actions before the run */
static int stop_installed[2];          /* 1: our handler replaced stop_saved[i] */
static struct sigaction stop_default;  /* SIG_DFL, prepared outside the handler */

static void on_stop_signal(int sig) {
    stop_signal = sig;
    for (int i = 0; i < 2; i++)
        if (stop_installed[i]) sigaction(stop_signals[i], &stop_default, NULL);
    anistar_mesher_stop(atomic_load(&stop_target));
}

static void stop_handlers_install(anistar_mesher *m) {
    memset(&stop_default, 0, sizeof stop_default);
    stop_default.sa_handler = SIG_DFL;
    sigemptyset(&stop_default.sa_mask);
    stop_signal = 0;
    atomic_store(&stop_target, m);
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_stop_signal;
    sigemptyset(&sa.sa_mask);
    for (int i = 0; i < 2; i++) sigaddset(&sa.sa_mask, stop_signals[i]);
    sa.sa_flags = SA_RESETHAND | SA_RESTART;
    for (int i = 0; i < 2; i++) {
        stop_installed[i] = 0;
        if (sigaction(stop_signals[i], NULL, &stop_saved[i]) != 0) continue;
        if (!(stop_saved[i].sa_flags & SA_SIGINFO) && stop_saved[i].sa_handler == SIG_IGN)
            continue;
        stop_installed[i] = 1; /* before the handler can run */
        if (sigaction(stop_signals[i], &sa, NULL) != 0) stop_installed[i] = 0;
    }
}

static void stop_handlers_remove(void) {
    for (int i = 0; i < 2; i++)
        if (stop_installed[i]) sigaction(stop_signals[i], &stop_saved[i], NULL);
    for (int i = 0; i < 2; i++) stop_installed[i] = 0;
    atomic_store(&stop_target, NULL);
}

static const char *signal_name(int sig) {
    return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "a signal";
}

/* ---- progress ---------------------------------------------------------------------- */

/*
 * Progress on stderr (not with --quiet), from the first second of a run on:
 *   a terminal: one line rewritten with \r at most every PROGRESS_TTY_STEP seconds, ended
 *     with a newline when the run returns;
 *   anything else (a file, a pipe): one newline-terminated line at 1 s, then every
 *     PROGRESS_LOG_STEP seconds; never a \r.
 * A line: "anistar: mesh: V[ of ~E] vertices, I inconsistent facets, S s[, ETA T s]
 * [, stalled N/B insertions]" (progress_format).
 */
#define PROGRESS_FIRST 1.0
#define PROGRESS_TTY_STEP 0.2
#define PROGRESS_LOG_STEP 10.0

typedef struct progress_state {
    anistar_mesher *mesher; /* for anistar_mesher_get_progress */
    int tty;                /* stderr is a terminal */
    int shown;              /* a line is on screen (tty: not ended yet) */
    double next;            /* seconds of the next line */
    size_t width;           /* length of the last tty line (to blank its tail) */
} progress_state;

/* Append printf-style text to buf (capacity cap, *n characters so far), truncating. */
static void appendf(char *buf, size_t cap, size_t *n, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    int k = *n < cap ? vsnprintf(buf + *n, cap - *n, fmt, ap) : 0;
    va_end(ap);
    if (k > 0) *n = *n + (size_t)k < cap ? *n + (size_t)k : cap - 1;
}

/* The progress line (without "\r" or "\n") into buf. */
static void progress_format(char *buf, size_t cap, const anistar_progress *p) {
    size_t n = 0;
    buf[0] = '\0';
    appendf(buf, cap, &n, "anistar: mesh: %zu", p->vertices);
    if (p->estimate_vertices > 0) appendf(buf, cap, &n, " of ~%.0f", p->estimate_vertices);
    appendf(buf, cap, &n, " vertices, %zu inconsistent facets, %.1f s", p->inconsistent,
            p->seconds);
    if (p->estimate_vertices > 0 && p->eta_seconds >= 0.5)
        appendf(buf, cap, &n, ", ETA %.0f s", p->eta_seconds);
    if (p->max_stall > 0 && p->stalled > p->max_stall / 4)
        appendf(buf, cap, &n, ", stalled %llu/%llu insertions", (unsigned long long)p->stalled,
                (unsigned long long)p->max_stall);
}

static int mesh_progress(size_t vertices, size_t inconsistent, double seconds, void *user) {
    progress_state *ps = user;
    if (seconds < ps->next) return 0;
    anistar_progress p;
    if (anistar_mesher_get_progress(ps->mesher, &p) != ANISTAR_OK) {
        memset(&p, 0, sizeof p);
        p.eta_seconds = -1;
    }
    p.vertices = vertices; /* the callback's own values are the current ones */
    p.inconsistent = inconsistent;
    p.seconds = seconds;
    char line[256];
    progress_format(line, sizeof line, &p);
    if (ps->tty) {
        size_t len = strlen(line);
        int pad = ps->width > len ? (int)(ps->width - len) : 0;
        fprintf(stderr, "\r%s%*s", line, pad, "");
        ps->width = len;
        ps->next = seconds + PROGRESS_TTY_STEP;
        ps->shown = 1;
    } else {
        fprintf(stderr, "%s\n", line);
        while (ps->next <= seconds) ps->next += PROGRESS_LOG_STEP;
    }
    fflush(stderr);
    return 0;
}

/* ---- --stats ----------------------------------------------------------------------- */

/* Write the --stats JSON. Returns 0, or -1 if the file cannot be written. */
static int mesh_stats_write(const char *path, const anistar_mesh_stats *st,
                            const double *values, const char *metric, int complete,
                            int optimize, const surface_opts *so) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fprintf(f, "{\n");
    fprintf(f, "  \"vertices\": %zu,\n  \"facets\": %zu,\n  \"inconsistent_facets\": %zu,\n",
            st->vertices, st->facets, st->inconsistent_facets);
    fprintf(f, "  \"poles\": %zu,\n  \"euler_characteristic\": %lld,\n", st->poles,
            st->euler_characteristic);
    fprintf(f, "  \"closed_manifold\": %s,\n  \"components\": %zu,\n  \"complete\": %s,\n",
            st->closed_manifold ? "true" : "false", st->components,
            complete ? "true" : "false");
    fprintf(f, "  \"stop_reason\": ");
    json_string_to(f, anistar_stop_reason_name(st->stop_reason));
    fprintf(f, ",\n  \"seconds\": {\"total\": %.6g, \"init\": %.6g, \"refine\": %.6g, "
               "\"output\": %.6g, \"optimize\": %.6g},\n",
            st->seconds_total, st->seconds_init, st->seconds_refine, st->seconds_output,
            st->seconds_optimize);
    fprintf(f, "  \"insertions\": {\"initial\": %llu, \"rule1\": %llu, \"rule2\": %llu, "
               "\"rule3\": %llu, \"topology\": %llu,\n"
               "    \"rule1_causes\": {\"size\": %llu, \"distortion\": %llu, "
               "\"approximation\": %llu, \"feature\": %llu, \"hmax\": %llu}},\n",
            (unsigned long long)st->insertions_initial,
            (unsigned long long)st->insertions_rule[0],
            (unsigned long long)st->insertions_rule[1],
            (unsigned long long)st->insertions_rule[2],
            (unsigned long long)st->insertions_topology,
            (unsigned long long)st->insertions_size,
            (unsigned long long)st->insertions_distortion,
            (unsigned long long)st->insertions_approx,
            (unsigned long long)st->insertions_feature,
            (unsigned long long)st->insertions_hmax);
    fprintf(f, "  \"stall_max\": %llu,\n", (unsigned long long)st->stall_max);
    fprintf(f, "  \"hmin\": %.17g,\n  \"hmax\": %.17g,\n  \"facets_below_hmin\": %zu,\n",
            st->hmin, st->hmax, st->facets_below_hmin);
    fprintf(f, "  \"components_found\": %zu,\n  \"components_split\": %zu,\n"
               "  \"components_joined\": %zu,\n",
            st->components_found, st->components_split, st->components_joined);
    fprintf(f, "  \"components_below_resolution\": %zu,\n", st->components_below_resolution);
    fprintf(f, "  \"pieces_below_resolution\": %zu,\n  \"edges_below_resolution\": %zu,\n",
            st->pieces_below_resolution, st->edges_below_resolution);
    fprintf(f, "  \"feature_alpha\": %.17g,\n  \"feature_halvings\": %llu,\n",
            st->feature_alpha, (unsigned long long)st->feature_halvings);
    fprintf(f, "  \"topology_below_hmin\": %llu,\n  \"sites_unused\": %zu,\n",
            (unsigned long long)st->topology_below_hmin, st->sites_unused);
    fprintf(f, "  \"stars_delaunay_zone\": %zu,\n  \"facets_swept\": %llu,\n",
            st->stars_delaunay_zone, (unsigned long long)st->facets_swept);
    fprintf(f,
            "  \"batches\": {\"count\": %llu, \"jobs\": %llu, \"lost\": %llu, "
            "\"set_aside\": %llu},\n",
            (unsigned long long)st->batches, (unsigned long long)st->batch_jobs,
            (unsigned long long)st->batch_jobs_lost, (unsigned long long)st->batch_jobs_set_aside);
    fprintf(f, "  \"pick_valid\": {\"tries\": %llu, \"failures\": %llu},\n",
            (unsigned long long)st->pick_valid_tries,
            (unsigned long long)st->pick_valid_failures);
    fprintf(f, "  \"rho_max\": %.17g,\n  \"r_max\": %.17g,\n  \"gamma_max\": %.17g,\n",
            st->rho_max, st->r_max, st->gamma_max);
    fprintf(f, "  \"histogram_width\": %.17g,\n  \"histogram\": [", st->histogram_width);
    for (int i = 0; i < ANISTAR_HISTOGRAM_BINS; i++)
        fprintf(f, "%s%llu", i ? ", " : "", (unsigned long long)st->histogram[i]);
    fprintf(f, "],\n  \"rho2_mean\": %.17g,\n", st->rho2_mean);
    fprintf(f, "  \"approx_error\": {\"mean\": %.17g, \"max\": %.17g},\n",
            st->approx_error_mean, st->approx_error_max);
    /* vertex optimisation (paper 6.2): counters and the histogram before it */
    fprintf(f, "  \"optimize\": {\"done\": %s, \"moved\": %llu, \"tries\": %llu, "
               "\"passes\": %llu, \"seconds\": %.6g, \"rho2_mean_before\": %.17g,\n"
               "    \"histogram_before\": [",
            st->optimized ? "true" : "false", (unsigned long long)st->optimize_moved,
            (unsigned long long)st->optimize_tries, (unsigned long long)st->optimize_passes,
            st->seconds_optimize, st->rho2_mean_before);
    for (int i = 0; i < ANISTAR_HISTOGRAM_BINS; i++)
        fprintf(f, "%s%llu", i ? ", " : "", (unsigned long long)st->histogram_before[i]);
    fprintf(f, "]},\n");
    fprintf(f, "  \"estimate\": {\"vertices\": %.17g, \"bytes\": %.17g},\n",
            st->estimate_vertices, st->estimate_bytes);
    fprintf(f, "  \"peak_bytes\": %zu,\n", st->peak_bytes);
    fprintf(f, "  \"parameters\": {\"metric\": ");
    json_string_to(f, metric);
    for (size_t i = 0; i < NMESH_PARAMS; i++)
        fprintf(f, ", \"%s\": %.17g", mesh_params[i].json, values[i]);
    fprintf(f, ", \"optimize\": %s", optimize ? "true" : "false");
    if (so->has_iso) fprintf(f, ", \"iso\": %.17g", so->iso);
    if (so->fit_used)
        fprintf(f, ", \"fit\": \"%s\"",
                so->fit_used == ANISTAR_FIT_SMOOTH ? "smooth" : "interpolate");
    fprintf(f, "},\n  \"seed\": %.17g\n}\n", values[MESH_SEED]);
    int bad = ferror(f);
    if (fclose(f) != 0) bad = 1;
    return bad ? -1 : 0;
}

/* ---- the command ------------------------------------------------------------------- */

static int cmd_mesh(int argc, char **argv) {
    surface_opts so;
    memset(&so, 0, sizeof so);
    so.fit = -1;
    const char *metric = NULL, *sol = NULL, *stats = NULL, *outs[MAX_OUTPUTS];
    int nouts = 0, quiet = 0, optimize = 0, has_value[NMESH_PARAMS] = {0};
    double value[NMESH_PARAMS];
    for (int i = 0; i < argc;) {
        const char *a = argv[i];
        if (!strcmp(a, "--quiet")) {
            quiet = 1;
            i++;
            continue;
        }
        if (!strcmp(a, "--optimize")) { /* vertex optimisation (paper 6.2) */
            optimize = 1;
            i++;
            continue;
        }
        int k = -1;
        for (size_t j = 0; j < NMESH_PARAMS; j++)
            if (!strcmp(a, mesh_params[j].flag)) k = (int)j;
        int other = !strcmp(a, "-o") || !strcmp(a, "--metric") || !strcmp(a, "--sol") ||
                    !strcmp(a, "--stats");
        if (k < 0 && !other) {
            int r = surface_option(&so, argc, argv, &i);
            if (r < 0) return EXIT_USAGE;
            if (r == 0) {
                say("mesh: unknown option '%s' (try 'anistar --help')", a);
                return EXIT_USAGE;
            }
            continue;
        }
        if (i + 1 >= argc) {
            say("%s needs a value", a);
            return EXIT_USAGE;
        }
        const char *v = argv[i + 1];
        i += 2;
        if (k >= 0) {
            if (has_value[k]++) {
                say("%s given twice", a);
                return EXIT_USAGE;
            }
            if (parse_numbers(v, &value[k], 1) ||
                (mesh_params[k].integer && value[k] != floor(value[k]))) {
                say("%s expects %s, got '%s'", a,
                    mesh_params[k].integer ? "an integer" : "a number", v);
                return EXIT_USAGE;
            }
        } else if (!strcmp(a, "-o")) {
            if (!mesh_output_ok(v)) {
                say("-o '%s': unknown output extension (expected .off .obj .ply .stl .mesh "
                    ".meshb .vtk .vtu)",
                    v);
                return EXIT_USAGE;
            }
            if (nouts == MAX_OUTPUTS) {
                say("at most %d -o outputs", MAX_OUTPUTS);
                return EXIT_USAGE;
            }
            outs[nouts++] = v;
        } else {
            const char **dst = a[2] == 'm' ? &metric : a[3] == 'o' ? &sol : &stats;
            if (*dst) {
                say("%s given twice", a);
                return EXIT_USAGE;
            }
            *dst = v;
        }
    }
    if (surface_check(&so)) return EXIT_USAGE;
    if (nouts == 0) {
        say("mesh needs -o OUT (.off .obj .ply .stl .mesh .meshb .vtk .vtu)");
        return EXIT_USAGE;
    }
    if (sol && !has_extension(sol, ".sol") && !has_extension(sol, ".solb")) {
        say("--sol: the output '%s' must end with .sol or .solb", sol);
        return EXIT_USAGE;
    }
    if (!metric) metric = "curvature";

    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) {
        say("out of memory");
        return EXIT_ERROR;
    }
    int rc = EXIT_OK;
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *mr = NULL;
    anistar_mesh *mesh = NULL;
    if (anistar_metric_spec_check(ctx, metric)) {
        say("--metric: %s", anistar_last_error(ctx));
        rc = EXIT_USAGE;
        goto done;
    }
    /* every output must be writable before anything is built or meshed */
    for (int j = 0; j < nouts; j++)
        if (output_check("-o", outs[j])) {
            rc = EXIT_ERROR;
            goto done;
        }
    if ((sol && output_check("--sol", sol)) || (stats && output_check("--stats", stats))) {
        rc = EXIT_ERROR;
        goto done;
    }
    so.quiet = quiet;
    rc = surface_make(ctx, &so, &s);
    if (rc) goto done;
    anistar_status mst = anistar_metric_from_spec(ctx, s, metric, &m);
    if (mst == ANISTAR_OK) mst = anistar_mesher_new(ctx, s, m, &mr);
    if (mst != ANISTAR_OK) {
        say("%s%s", anistar_last_error(ctx), smooth_hint(&so, mst));
        rc = EXIT_ERROR;
        goto done;
    }
    if (!has_value[MESH_THREADS]) {
        /* the default: every online core (the output does not depend on it) */
        long cores = sysconf(_SC_NPROCESSORS_ONLN);
        value[MESH_THREADS] = cores < 1 ? 1 : cores > 1024 ? 1024 : (double)cores;
        has_value[MESH_THREADS] = 1;
    }
    for (size_t j = 0; j < NMESH_PARAMS; j++) {
        if (has_value[j] && anistar_mesher_set(mr, mesh_params[j].key, value[j])) {
            say("%s: %s", mesh_params[j].flag, anistar_last_error(ctx));
            rc = EXIT_USAGE;
            goto done;
        }
        if (anistar_mesher_get(mr, mesh_params[j].key, &value[j])) {
            say("%s", anistar_last_error(ctx));
            rc = EXIT_ERROR;
            goto done;
        }
    }
    if (optimize && anistar_mesher_set(mr, ANISTAR_PARAM_OPTIMIZE, 1)) {
        say("%s", anistar_last_error(ctx));
        rc = EXIT_ERROR;
        goto done;
    }
    progress_state prog;
    memset(&prog, 0, sizeof prog);
    prog.mesher = mr;
    prog.tty = isatty(STDERR_FILENO);
    prog.next = PROGRESS_FIRST;
    if (!quiet) anistar_mesher_set_progress(mr, mesh_progress, &prog);
    stop_handlers_install(mr);
    anistar_status st = anistar_mesher_run(mr, &mesh);
    stop_handlers_remove();
    int sig = stop_signal;
    if (prog.shown) fputc('\n', stderr);
    if (st != ANISTAR_OK && st != ANISTAR_INCOMPLETE) {
        say("%s%s", anistar_last_error(ctx), smooth_hint(&so, st));
        rc = EXIT_ERROR;
        goto done;
    }
    /* the reason of an INCOMPLETE run, before the writes reuse ctx */
    char reason[512];
    snprintf(reason, sizeof reason, "%s",
             st == ANISTAR_INCOMPLETE ? anistar_last_error(ctx) : "");
    for (int j = 0; j < nouts; j++)
        if (anistar_mesh_write(ctx, mesh, outs[j])) {
            say("%s", anistar_last_error(ctx));
            rc = EXIT_ERROR;
            goto done;
        }
    if (sol && anistar_mesh_write(ctx, mesh, sol)) {
        say("%s", anistar_last_error(ctx));
        rc = EXIT_ERROR;
        goto done;
    }
    anistar_mesh_stats ms;
    anistar_mesh_get_stats(mesh, &ms);
    if (stats && mesh_stats_write(stats, &ms, value, metric, st == ANISTAR_OK, optimize, &so)) {
        say("cannot write '%s'", stats);
        rc = EXIT_ERROR;
        goto done;
    }
    if (st == ANISTAR_INCOMPLETE) {
        /* the run's result: printed even with --quiet (which silences progress only) */
        if (sig && ms.stop_reason == ANISTAR_STOP_REQUESTED)
            say("stopped by %s: %zu vertices, %zu facets written, %zu inconsistent facets left "
                "out",
                signal_name(sig), ms.vertices, ms.facets, ms.inconsistent_facets);
        else
            say("incomplete (%s): %zu vertices, %zu facets written, %zu inconsistent facets "
                "left out%s%s",
                anistar_stop_reason_name(ms.stop_reason), ms.vertices, ms.facets,
                ms.inconsistent_facets, reason[0] ? "; " : "", reason);
        rc = EXIT_INCOMPLETE;
    }
done:
    anistar_mesh_free(mesh);
    anistar_mesher_free(mr);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return rc;
}

/* ---- commands ---------------------------------------------------------------------- */

typedef struct command {
    const char *name;
    const char *synopsis;
    int (*run)(int argc, char **argv); /* NULL: not available yet */
} command;

static const command commands[] = {
    {"probe", "probe SURFACE [--metric SPEC] --at X,Y,Z", cmd_probe},
    {"info", "info FILE [--json] [--iso V] [--inside greater|less]", cmd_info},
    {"mesh", "mesh SURFACE [--metric SPEC] [--r0 R] [--gamma0 G] [--rho0 P] [--beta B]\n"
             "                 [--delta D] [--approx A] [--max-vertices N] [--max-seconds S]\n"
             "                 [--max-stall N] [--seed N] [--pick-tries N] [--hmin H]\n"
             "                 [--hmax H] [--aniso-cap 0|1] [--threads N] [--optimize]\n"
             "                 [--quiet] [--sol FILE.sol|.solb] [--stats FILE.json]\n"
             "                 -o OUT [-o OUT2 ...]",
     cmd_mesh},
    {"render", "render MESH -o OUT.png [--color quality|anisotropy|none] [--view AZ,EL]\n"
               "                 [--size WxH] [--edges on|off] [--up x|y|z] [--range MIN,MAX]\n"
               "                 [--sol FILE.sol|.solb]",
     cmd_render},
};
#define NCOMMANDS (sizeof commands / sizeof commands[0])

static void help(void) {
    printf("anistar %s: anisotropic Delaunay meshes of surfaces\n\n", anistar_version());
    printf("usage: anistar COMMAND [options]\n       anistar --help | --version\n\n"
           "commands:\n");
    for (size_t i = 0; i < NCOMMANDS; i++) printf("  anistar %s\n", commands[i].synopsis);
    printf("\nprobe prints JSON: f and its gradient at the point, the projection of the point\n"
           "on S, and there the normal, principal curvatures and directions, and the metric\n"
           "tensor (m11 m12 m13 m22 m23 m33; default metric: curvature).\n\n"
           "info describes a triangle mesh (counts, borders, non-manifold edges and\n"
           "vertices, components with Euler characteristic and genus, exact\n"
           "self-intersections, bounding box, edge lengths) or a 3D image (grid, values,\n"
           "Otsu's threshold, 6-connected components of the voxels inside --iso V, default\n"
           "Otsu's); plain text, or JSON with --json.\n\n"
           "mesh builds an anisotropic Delaunay mesh of SURFACE for --metric (default\n"
           "curvature) and writes every -o OUT by extension (.off .obj .ply .stl .mesh .meshb\n"
           ".vtk .vtu; .vtk .vtu .ply also carry the vertex tensors and, per triangle,\n"
           "radius_edge and anisotropy); --sol writes the vertex tensors (Medit .sol or\n"
           "binary .solb), --stats a JSON of statistics.\n"
           "Defaults: r0 0.1, gamma0 1.5, rho0 3, beta 2.5, delta 0.3, approx 0 (off),\n"
           "max-vertices 1000000 (0: the hard limit 2147482623 = 2^31 - 1025, not 'no limit';\n"
           "a run whose up-front estimate exceeds it is refused, status 1), max-seconds 0\n"
           "(no limit), max-stall 0 (automatic, at least 50000; N: stop after N\n"
           "consistency (rule 3) insertions in a row without a new low of the\n"
           "inconsistent-facet count they face; other insertions are bounded by\n"
           "max-vertices and max-seconds), seed 0, pick-tries 20, hmin 0 (automatic: the\n"
           "surface's resolution; facets with a shorter longest edge get no size,\n"
           "distortion or shape refinement), hmax 0 (none; longer facets are refined),\n"
           "aniso-cap 1 (the metric's small eigenvalues are raised where its frame turns\n"
           "so fast that gamma0 would cut its facets; not on triangle meshes; 0: the\n"
           "metric as given), threads: the online cores (the output is the same, byte for\n"
           "byte, for every thread count).\n"
           "Progress goes to stderr (--quiet: none); SIGINT or SIGTERM stops the run after\n"
           "the insertion in progress and writes every output, as a limit does (status 3);\n"
           "a second signal kills.\n\n"
           "render draws a triangle mesh to a PNG image, each triangle coloured by --color:\n"
           "quality (radius-edge ratio, the default), anisotropy (sqrt(lmax/lmin) of the\n"
           "vertex tensors of a PLY, VTK or VTU file or of --sol, which implies this mode;\n"
           "else the triangle's aspect ratio) or none;\n"
           "--view AZ,EL in degrees (default 30,20) around the --up axis (default z);\n"
           "--size WxH (default 1024x768); --range MIN,MAX fixes the colour range.\n\n"
           "SURFACE:\n"
           "  --implicit \"EXPR\" --bound CX,CY,CZ,R   f(x,y,z) = 0, f < 0 inside, S inside the\n"
           "                                        sphere; EXPR e.g. \"R=10; r=1; "
           "(sqrt(x^2+y^2)-R)^2+z^2-r^2\"\n"
           "  --builtin NAME[,PARAM=V...][,bound=R]  a built-in surface (below)\n"
           "  FILE.off|.obj|.ply|.stl|.mesh|.meshb|.vtk|.vtu  a closed triangle mesh\n"
           "  FILE.inr|.nrrd|.nhdr|.mha|.mhd [--iso V] [--inside greater|less]\n"
           "       [--fit auto|interpolate|smooth]  an isosurface of a 3D image (inside:\n"
           "                                        values greater than V, the default;\n"
           "                                        no --iso: Otsu's threshold) of its cubic\n"
           "                                        B-spline, through the voxel values or\n"
           "                                        smoothing them (auto: smooth for at\n"
           "                                        most 16 distinct values, labels, masks)\n\n"
           "--metric SPEC:\n"
           "  euclidean | uniform[,h=H] | curvature[,eps=E][,en=N][,power=P]\n"
           "  | shock[,lambda=L][,phi=F][,en=N] | gradient:EXPR[,phi=F][,en=N]\n"
           "  | hessian:EXPR[,eps=E][,en=N][,power=P] | sol:FILE.sol|.solb[,rb=R] (meshes)\n"
           "  every field but euclidean and uniform also takes grad=G (gradation, G > 1:\n"
           "  sizes grow by at most about 1 + l ln G over metric length l; for fields that\n"
           "  jump, e.g. the curvature of surfaces joined with continuous tangents only;\n"
           "  default 1.5 for curvature and sol on triangle meshes and curvature on\n"
           "  images and on expressions with abs, min or max (creases), else none;\n"
           "  grad=0: none);\n"
           "  curvature on meshes also takes degree=2|3|4, k=K (neighbours), rb=R\n"
           "  (blending); on images rb=R\n\n"
           "built-in surfaces:\n");
    const char *name, *desc;
    for (size_t i = 0; anistar_surface_builtin_info(i, &name, &desc) == ANISTAR_OK; i++)
        printf("  %-13s %s\n", name, desc);
    printf("\nexit status: 0 done (mesh: a certified mesh), 1 error, 2 usage error, 3 (mesh)\n"
           "stopped before a certified mesh by a limit, a stall, a signal or a failed final\n"
           "check (every output written with the consistent facets; one line on stderr says\n"
           "why). See docs/cli.md.\n");
}

int main(int argc, char **argv) {
    if (argc < 2) {
        say("missing COMMAND (try 'anistar --help')");
        return EXIT_USAGE;
    }
    if (!strcmp(argv[1], "--version")) {
        printf("anistar %s\n", anistar_version());
        return EXIT_OK;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h")) {
        help();
        return EXIT_OK;
    }
    for (size_t i = 0; i < NCOMMANDS; i++) {
        if (strcmp(argv[1], commands[i].name)) continue;
        if (!commands[i].run) {
            say("'%s' is not available yet in this version", commands[i].name);
            return EXIT_ERROR;
        }
        return commands[i].run(argc - 2, argv + 2);
    }
    say("unknown command '%s' (try 'anistar --help')", argv[1]);
    return EXIT_USAGE;
}
