/*
 * anistar — the command-line tool: one more client of the public API (DESIGN.md 3,
 * docs/cli.md). It parses options into API calls and nothing else.
 *
 *   anistar probe SURFACE [--metric SPEC] --at X,Y,Z
 *   anistar mesh ... | anistar render ...        (coming: listed, not available yet)
 *   anistar --help | --version
 *
 * Exit status: 0 done; 1 error (one line on stderr); 2 usage error (one line on stderr).
 */
#include "anistar.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

enum { EXIT_OK = 0, EXIT_ERROR = 1, EXIT_USAGE = 2 };

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
    const char *file;     /* FILE (meshes, images: not supported yet) */
    double bound[4];      /* --bound CX,CY,CZ,R */
    int has_bound;
    double iso; /* --iso V (images) */
    int has_iso;
} surface_opts;

/*
 * Try to consume a SURFACE option at argv[*i]. Returns 1 if consumed (*i advanced past
 * its value), 0 if argv[*i] is not a SURFACE option, -1 on a usage error (reported).
 */
static int surface_option(surface_opts *so, int argc, char **argv, int *i) {
    const char *a = argv[*i];
    int takes_value = !strcmp(a, "--implicit") || !strcmp(a, "--builtin") ||
                      !strcmp(a, "--bound") || !strcmp(a, "--iso");
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
    if (so->has_iso && !so->file) {
        say("--iso goes with an image FILE");
        return -1;
    }
    return 0;
}

/* Build the surface. Returns an exit status (EXIT_OK on success). */
static int surface_make(anistar_context *ctx, const surface_opts *so, anistar_surface **s) {
    anistar_status st;
    if (so->builtin) {
        st = anistar_surface_builtin(ctx, so->builtin, s);
    } else if (so->implicit) {
        st = anistar_surface_from_expression(ctx, so->implicit, so->bound, so->bound[3], s);
    } else {
        say("%s: surface files (meshes .off .obj .ply .stl .mesh, images .inr .nrrd .mha .mhd) "
            "are not supported yet; use --implicit or --builtin",
            so->file);
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

/* ---- commands ---------------------------------------------------------------------- */

typedef struct command {
    const char *name;
    const char *synopsis;
    int (*run)(int argc, char **argv); /* NULL: not available yet */
} command;

static const command commands[] = {
    {"probe", "probe SURFACE [--metric SPEC] --at X,Y,Z", cmd_probe},
    {"mesh", "mesh SURFACE [options] -o OUT [-o OUT2 ...]   (coming)", NULL},
    {"render", "render MESH -o OUT.png [--color quality|anisotropy|none] [--view AZ,EL]   "
               "(coming)",
     NULL},
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
           "SURFACE:\n"
           "  --implicit \"EXPR\" --bound CX,CY,CZ,R   f(x,y,z) = 0, f < 0 inside, S inside the\n"
           "                                        sphere; EXPR e.g. \"R=10; r=1; "
           "(sqrt(x^2+y^2)-R)^2+z^2-r^2\"\n"
           "  --builtin NAME[,PARAM=V...][,bound=R]  a built-in surface (below)\n"
           "  FILE.off|.obj|.ply|.stl|.mesh, FILE.inr|.nrrd|.mha|.mhd --iso V   (coming)\n\n"
           "--metric SPEC:\n"
           "  euclidean | uniform[,h=H] | curvature[,eps=E][,en=N][,power=P]\n"
           "  | shock[,lambda=L][,phi=F][,en=N] | gradient:EXPR[,phi=F][,en=N]\n"
           "  | hessian:EXPR[,eps=E][,en=N][,power=P] | sol:FILE.sol (meshes, coming)\n\n"
           "built-in surfaces:\n");
    const char *name, *desc;
    for (size_t i = 0; anistar_surface_builtin_info(i, &name, &desc) == ANISTAR_OK; i++)
        printf("  %-13s %s\n", name, desc);
    printf("\nexit status: 0 done, 1 error, 2 usage error. See docs/cli.md.\n");
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
