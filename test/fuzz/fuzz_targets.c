/*
 * fuzz_targets.c — see fuzz_targets.h. Test code (not library code): it may use stdio,
 * malloc and the file system freely.
 */
#include "fuzz_targets.h"

#include "anistar.h"
#include "core.h"
#include "io/image_io.h"
#include "io/meshio.h"
#include "surface/expr.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* ---- a counting allocator (live blocks and bytes; the size passed on free must be the
 * size the block was allocated with, which the count checks as a side effect) ---------- */

typedef struct ft_alloc {
    long live_blocks;
    size_t live_bytes;
    size_t peak_bytes;
} ft_alloc;

/* Hostile inputs may legitimately ask for a lot of memory before a reader notices that
 * the file is too short; the readers promise "a small multiple of the file size", so a
 * single request above this cap fails (the reader must then report ENOMEM cleanly). */
#define FT_ALLOC_CAP ((size_t)1 << 30)

static void *ft_alloc_fn(void *user, void *ptr, size_t old_size, size_t new_size) {
    ft_alloc *a = user;
    if (new_size == 0) {
        if (ptr) {
            a->live_blocks--;
            a->live_bytes -= old_size;
            free(ptr);
        }
        return NULL;
    }
    if (new_size > FT_ALLOC_CAP) return NULL;
    void *q = realloc(ptr, new_size);
    if (!q) return NULL;
    if (!ptr) a->live_blocks++;
    a->live_bytes = a->live_bytes - (ptr ? old_size : 0) + new_size;
    if (a->live_bytes > a->peak_bytes) a->peak_bytes = a->live_bytes;
    return q;
}

/* ---- names ---------------------------------------------------------------------------- */

static const char *const ft_names[FT_READER_COUNT] = {
    "off", "obj", "ply", "stl", "medit", "sol", "inr", "nrrd", "metaimage", "expr",
    "vtk", "vtu", "meshb", "solb"};

const char *ft_reader_name(ft_reader r) {
    return (r >= 0 && r < FT_READER_COUNT) ? ft_names[r] : "invalid";
}

ft_reader ft_reader_by_name(const char *name) {
    for (int i = 0; i < FT_READER_COUNT; i++)
        if (strcmp(ft_names[i], name) == 0) return (ft_reader)i;
    return FT_READER_COUNT;
}

static void ft_fail(ft_result *res, const char *what) {
    if (res->ok) {
        res->ok = 0;
        res->what = what;
    }
}

static void ft_failf(ft_result *res, const char *what, const char *detail) {
    if (res->ok) {
        res->ok = 0;
        snprintf(res->buf, sizeof res->buf, "%s: %s", what, detail);
        res->what = res->buf;
    }
}

/* ---- per-reader checks of a successful output ----------------------------------------- */

static void ft_check_mesh(const as_trimesh *m, ft_result *res) {
    if (m->nv < 1 || m->nt < 1) ft_fail(res, "mesh reader returned OK with an empty mesh");
    if (m->nv > m->cap_v || m->nt > m->cap_t) ft_fail(res, "mesh count exceeds capacity");
    for (size_t i = 0; i < 3 * m->nv; i++)
        if (!isfinite(m->xyz[i])) {
            ft_fail(res, "mesh reader returned a non-finite coordinate");
            break;
        }
    for (size_t i = 0; i < 3 * m->nt; i++)
        if (m->tri[i] < 0 || (size_t)m->tri[i] >= m->nv) {
            ft_fail(res, "mesh reader returned an index out of range");
            break;
        }
    if (m->tensor)
        for (size_t i = 0; i < 6 * m->nv; i++)
            if (!isfinite(m->tensor[i])) {
                ft_fail(res, "mesh reader returned a non-finite tensor");
                break;
            }
}

static void ft_check_image(const as_image *img, ft_result *res) {
    if (img->nx < 1 || img->ny < 1 || img->nz < 1) ft_fail(res, "image with a zero size");
    if (img->count != img->nx * img->ny * img->nz) ft_fail(res, "image count != nx*ny*nz");
    if (img->data_bytes != img->count * as_voxel_size(img->type))
        ft_fail(res, "image data_bytes != count * voxel size");
    if (img->grid.n[0] != img->nx || img->grid.n[1] != img->ny || img->grid.n[2] != img->nz)
        ft_fail(res, "image grid.n differs from nx ny nz");
    for (int i = 0; i < 9; i++)
        if (!isfinite(img->grid.a[i]) || !isfinite(img->grid.ainv[i]))
            ft_fail(res, "image grid matrix not finite");
    for (int i = 0; i < 3; i++)
        if (!(img->grid.spacing[i] > 0) || !isfinite(img->grid.origin[i]))
            ft_fail(res, "image spacing <= 0 or origin not finite");
    /* Touch every voxel (ASan sees an undersized buffer) and the range helpers. */
    double lo, hi;
    as_image_range(img, &lo, &hi);
    (void)as_image_count_nonfinite(img, NULL);
}

/* ---- the image readers take a path: the input goes through a temporary file in a
 * private per-process folder (a detached data file named by the header is then looked
 * up in that folder, where nothing else exists) -------------------------------------- */

static int ft_write_temp(const char *dir, const char *path, const uint8_t *data, size_t size) {
    if (mkdir(dir, 0700) != 0) {
        struct stat st;
        if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) return -1;
    }
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int ok = size == 0 || fwrite(data, 1, size, f) == size;
    if (fclose(f) != 0) ok = 0;
    return ok ? 0 : -1;
}

static anistar_status ft_run_image(anistar_context *ctx, ft_reader r, const uint8_t *data,
                                   size_t size, ft_result *res) {
    static const char *const ext[] = {"inr", "nrrd", "mha"};
    int k = r == FT_INR ? 0 : r == FT_NRRD ? 1 : 2;
    char dir[128], path[192];
    snprintf(dir, sizeof dir, "/tmp/anistar-fuzz-%ld", (long)getpid());
    snprintf(path, sizeof path, "%s/in.%s", dir, ext[k]);
    if (ft_write_temp(dir, path, data, size) != 0) {
        ft_fail(res, "cannot write the temporary input file (harness problem)");
        return ANISTAR_EIO;
    }
    as_image *img = NULL;
    anistar_status st = r == FT_INR    ? as_image_read_inr(ctx, path, &img)
                        : r == FT_NRRD ? as_image_read_nrrd(ctx, path, &img)
                                       : as_image_read_metaimage(ctx, path, &img);
    if (st == ANISTAR_OK) {
        if (!img)
            ft_fail(res, "image reader returned OK and no image");
        else
            ft_check_image(img, res);
    } else if (img) {
        ft_fail(res, "image reader failed but set *out");
    }
    as_image_free(ctx, img);
    remove(path);
    rmdir(dir);
    return st;
}

/* ---- the expression compiler: compile, then evaluate a few points ------------------- */

static anistar_status ft_run_expr(anistar_context *ctx, const char *src, ft_result *res) {
    as_expr *e = NULL;
    anistar_status st = as_expr_compile(ctx, src, &e);
    if (st != ANISTAR_OK) {
        if (e) ft_fail(res, "as_expr_compile failed but set *out");
        return st;
    }
    if (!e) {
        ft_fail(res, "as_expr_compile returned OK and no expression");
        return st;
    }
    int depth = as_expr_stack_depth(e);
    if (depth < 1 || depth > AS_EXPR_MAX_STACK) ft_fail(res, "stack depth out of range");
    static const double pts[4][3] = {{0, 0, 0}, {0.5, -1.25, 2}, {-3, 1e-3, 7}, {1e8, -1e-8, 0}};
    for (int i = 0; i < 4; i++) {
        double g[3], h[6], g2[3];
        double v0 = as_expr_value(e, pts[i]);
        double v1 = as_expr_value_grad(e, pts[i], g2);
        double v2 = as_expr_value_grad_hess(e, pts[i], g, h);
        /* Documented: the three values (and the two gradients) are bitwise equal. */
        if (memcmp(&v0, &v1, sizeof v0) != 0 || memcmp(&v1, &v2, sizeof v1) != 0)
            if (!(isnan(v0) && isnan(v1) && isnan(v2)))
                ft_fail(res, "as_expr_value / _grad / _grad_hess values differ");
        for (int j = 0; j < 3; j++)
            if (memcmp(&g[j], &g2[j], sizeof g[j]) != 0 && !(isnan(g[j]) && isnan(g2[j])))
                ft_fail(res, "as_expr_value_grad / _grad_hess gradients differ");
    }
    size_t np = as_expr_param_count(e);
    for (size_t i = 0; i < np; i++) {
        const char *name;
        double v;
        if (as_expr_param_at(e, i, &name, &v) != 0 || !name || !isfinite(v))
            ft_fail(res, "as_expr_param_at failed or gave a non-finite parameter");
    }
    as_expr_free(ctx, e);
    return st;
}

/* ---- one run ---------------------------------------------------------------------- */

void ft_run(ft_reader r, const uint8_t *data, size_t size, ft_result *res) {
    res->ok = 1;
    res->status = ANISTAR_OK;
    res->what = "ok";
    res->buf[0] = '\0';
    if (r < 0 || r >= FT_READER_COUNT) {
        ft_fail(res, "unknown reader");
        return;
    }
    /* The mesh parsers and the expression compiler need a '\0' after the data. */
    char *text = malloc(size + 1);
    if (!text) {
        ft_fail(res, "out of memory in the harness");
        return;
    }
    if (size) memcpy(text, data, size);
    text[size] = '\0';

    ft_alloc a = {0, 0, 0};
    anistar_allocator al = {ft_alloc_fn, &a};
    anistar_context *ctx = anistar_context_new(&al);
    if (!ctx) {
        free(text);
        ft_fail(res, "anistar_context_new failed");
        return;
    }

    anistar_status st = ANISTAR_OK;
    if (r <= FT_MEDIT || r == FT_VTK || r == FT_VTU || r == FT_MESHB) {
        static const as_mesh_format fmt[] = {AS_FMT_OFF, AS_FMT_OBJ, AS_FMT_PLY, AS_FMT_STL,
                                             AS_FMT_MESH};
        as_mesh_format f = r == FT_VTK ? AS_FMT_VTK : r == FT_VTU ? AS_FMT_VTU
                           : r == FT_MESHB ? AS_FMT_MESHB : fmt[r];
        as_trimesh m;
        as_trimesh_init(&m);
        st = as_mesh_parse(ctx, f, "fuzz", text, size, &m);
        if (st == ANISTAR_OK)
            ft_check_mesh(&m, res);
        else if (m.nv || m.nt || m.xyz || m.tri || m.tensor)
            ft_fail(res, "failed mesh reader left a non-empty mesh");
        as_trimesh_free(ctx, &m);
    } else if (r == FT_SOL || r == FT_SOLB) {
        size_t count = 0;
        double *t = NULL;
        st = r == FT_SOL ? as_sol_parse(ctx, "fuzz", text, size, &count, &t)
                         : as_solb_parse(ctx, "fuzz", text, size, &count, &t);
        if (st == ANISTAR_OK) {
            if (count && !t) ft_fail(res, "as_sol_parse returned OK, count > 0 and no tensors");
            for (size_t i = 0; t && i < 6 * count; i++)
                if (!isfinite(t[i])) {
                    ft_fail(res, "as_sol_parse returned a non-finite tensor");
                    break;
                }
            if (t) as_free(ctx, t, 6 * count * sizeof(double));
        } else if (t) {
            ft_fail(res, "as_sol_parse failed but set *tensor");
        }
    } else if (r == FT_EXPR) {
        st = ft_run_expr(ctx, text, res);
    } else {
        st = ft_run_image(ctx, r, data, size, res);
    }
    res->status = (int)st;

    if (st != ANISTAR_OK) {
        const char *msg = anistar_last_error(ctx);
        if (!msg || !msg[0]) ft_fail(res, "error status with an empty message");
        /* A reader's errors are EINVAL, ENOMEM, EIO or EFORMAT (EINTERNAL is a bug). */
        if (st != ANISTAR_EINVAL && st != ANISTAR_ENOMEM && st != ANISTAR_EIO &&
            st != ANISTAR_EFORMAT)
            ft_failf(res, "reader returned an unexpected status", anistar_status_name(st));
        if (anistar_last_status(ctx) != st) ft_fail(res, "anistar_last_status != returned status");
    }
    anistar_context_free(ctx);
    free(text);
    if (a.live_blocks != 0 || a.live_bytes != 0) {
        char d[96];
        snprintf(d, sizeof d, "%ld blocks, %zu bytes not freed", a.live_blocks, a.live_bytes);
        ft_failf(res, "leak", d);
    }
}
