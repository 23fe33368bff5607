/*
 * image.c — isosurfaces of 3D images (DESIGN.md 4.6): f = the cubic B-spline
 * reconstruction of the voxels (surface/bspline.h) compared with an isovalue, with the
 * background value outside the image on the outside side of the isovalue, so a surface
 * touching the border of the image is still closed. The oracle is the generic one of
 * surface.c built on eval (crossings, projection, frame, curvature metrics, sampling).
 *
 * Sign: inside = +1 ("greater", CGAL's convention for gray-level images): the inside is
 * where the reconstruction exceeds iso, f = iso - value; inside = -1 ("less"):
 * f = value - iso. The background is the smallest voxel value for "greater", the largest
 * for "less" (so it lies strictly on the outside side: iso is required strictly inside
 * the value range).
 * Bounding sphere: the grid's voxel box grown by as_bspline_margin(iso) + 1 voxels
 * (as_grid_bounding_sphere): beyond the margin f keeps the background's sign, so f > 0 on
 * the sphere and S lies strictly inside it.
 */
#include "surface/surface.h"

#include "io/image_io.h"
#include "surface/bspline.h"

#include <math.h>
#include <string.h>

typedef struct as_image_surface {
    as_surface base;
    as_bspline *bs;
    double iso;
    double sign; /* f = sign * (iso - value) */
} as_image_surface;

static double im_eval(const as_surface *s, const double p[3], int order, double g[3],
                      double h[6]) {
    const as_image_surface *is = (const as_image_surface *)s;
    double v, sg = is->sign;
    if (order <= 0) {
        v = as_bspline_value(is->bs, p);
    } else if (order == 1) {
        v = as_bspline_value_grad(is->bs, p, g);
        for (int i = 0; i < 3; i++) g[i] = -sg * g[i];
    } else {
        v = as_bspline_value_grad_hess(is->bs, p, g, h);
        for (int i = 0; i < 3; i++) g[i] = -sg * g[i];
        for (int i = 0; i < 6; i++) h[i] = -sg * h[i];
    }
    return sg * (is->iso - v);
}

static void im_destroy(as_surface *s) {
    as_image_surface *is = (as_image_surface *)s;
    anistar_context *ctx = s->ctx;
    as_bspline_free(ctx, is->bs);
    as_free(ctx, is, sizeof *is);
}

static const as_surface_ops image_ops = {"image", im_eval, NULL, NULL, NULL, NULL, NULL,
                                         im_destroy};

int as_surface_is_image(const as_surface *s) { return s && s->ops == &image_ops; }

int as_image_surface_fit(const as_surface *s) {
    if (!as_surface_is_image(s)) return AS_IMAGE_FIT_AUTO;
    const as_image_surface *is = (const as_image_surface *)s;
    return as_bspline_fit(is->bs) == AS_BSPLINE_SMOOTH ? AS_IMAGE_FIT_SMOOTH
                                                       : AS_IMAGE_FIT_INTERPOLATE;
}

/* The distinct values of img's voxels, counted up to AS_IMAGE_LABELS_MAX + 1. */
static int count_values(const struct as_image *img) {
    double seen[AS_IMAGE_LABELS_MAX + 1];
    int n = 0;
    double buf[256];
    for (size_t first = 0; first < img->count; first += 256) {
        size_t m = img->count - first < 256 ? img->count - first : 256;
        as_image_to_double(img, first, m, buf);
        for (size_t i = 0; i < m; i++) {
            int k = 0;
            while (k < n && !(seen[k] == buf[i])) k++;
            if (k < n) continue;
            if (n == AS_IMAGE_LABELS_MAX + 1) return n;
            seen[n++] = buf[i];
        }
    }
    return n;
}

anistar_status as_image_surface_create(anistar_context *ctx, const char *name,
                                       const struct as_image *img, double iso, int inside,
                                       as_surface **out) {
    return as_image_surface_create_fit(ctx, name, img, iso, inside, AS_IMAGE_FIT_AUTO, out);
}

anistar_status as_image_surface_create_fit(anistar_context *ctx, const char *name,
                                           const struct as_image *img, double iso, int inside,
                                           int fit, as_surface **out) {
    *out = NULL;
    if (!name) name = "image";
    if (!img) return as_fail(ctx, ANISTAR_EINVAL, "%s: NULL image", name);
    if (fit != AS_IMAGE_FIT_AUTO && fit != AS_IMAGE_FIT_INTERPOLATE && fit != AS_IMAGE_FIT_SMOOTH)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "%s: the fit must be automatic (0), interpolating (1) or smoothing (2), "
                       "got %d",
                       name, fit);
    if (inside != 1 && inside != -1)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "%s: inside must be +1 (values greater than iso) or -1 (less), got %d",
                       name, inside);
    if (!isfinite(iso))
        return as_fail(ctx, ANISTAR_EINVAL, "%s: the isovalue must be finite", name);
    double lo, hi;
    as_image_range(img, &lo, &hi);
    if (!(lo < iso && iso < hi))
        return as_fail(ctx, ANISTAR_ENOSURFACE,
                       "%s: isovalue %g is not strictly inside the image's value range [%g, "
                       "%g]: no surface",
                       name, iso, lo, hi);
    as_image_surface *is = as_alloc(ctx, sizeof *is);
    if (!is) return as_fail(ctx, ANISTAR_ENOMEM, "%s: out of memory", name);
    memset(is, 0, sizeof *is);
    is->iso = iso;
    is->sign = inside > 0 ? 1.0 : -1.0;
    /* design: a label image or mask (few distinct values: every step is a jump between
     * labels) gets the smoothing fit, any other the interpolating one (bspline.h) */
    if (fit == AS_IMAGE_FIT_AUTO)
        fit = count_values(img) <= AS_IMAGE_LABELS_MAX ? AS_IMAGE_FIT_SMOOTH
                                                       : AS_IMAGE_FIT_INTERPOLATE;
    anistar_status st =
        as_bspline_create_fit(ctx, img, inside > 0 ? lo : hi,
                              fit == AS_IMAGE_FIT_SMOOTH ? AS_BSPLINE_SMOOTH : AS_BSPLINE_INTERPOLATE,
                              &is->bs);
    if (st) {
        as_free(ctx, is, sizeof *is);
        return st;
    }
    double m = as_bspline_margin(is->bs, iso), c[3], r;
    as_grid_bounding_sphere(as_bspline_grid(is->bs), m + 1, c, &r);
    st = as_surface_init(ctx, &is->base, &image_ops, c, r);
    if (st) {
        as_bspline_free(ctx, is->bs);
        as_free(ctx, is, sizeof *is);
        return st;
    }
    *out = &is->base;
    return ANISTAR_OK;
}

anistar_status as_image_surface_read(anistar_context *ctx, const char *path, double iso,
                                     int inside, as_surface **out) {
    return as_image_surface_read_fit(ctx, path, iso, inside, AS_IMAGE_FIT_AUTO, out);
}

anistar_status as_image_surface_read_fit(anistar_context *ctx, const char *path, double iso,
                                         int inside, int fit, as_surface **out) {
    *out = NULL;
    as_image *img = NULL;
    anistar_status st = as_image_read(ctx, path, &img);
    if (st) return st;
    st = as_image_surface_create_fit(ctx, path, img, iso, inside, fit, out);
    as_image_free(ctx, img);
    return st;
}

anistar_status as_image_surface_from_array(anistar_context *ctx, const double *voxels,
                                           const size_t dims[3], const double spacing[3],
                                           const double origin[3], double iso, int inside,
                                           as_surface **out) {
    return as_image_surface_from_array_fit(ctx, voxels, dims, spacing, origin, iso, inside,
                                           AS_IMAGE_FIT_AUTO, out);
}

anistar_status as_image_surface_from_array_fit(anistar_context *ctx, const double *voxels,
                                               const size_t dims[3], const double spacing[3],
                                               const double origin[3], double iso, int inside,
                                               int fit, as_surface **out) {
    *out = NULL;
    if (!voxels || !dims)
        return as_fail(ctx, ANISTAR_EINVAL, "image surface: NULL voxels or dimensions");
    as_image *img = NULL;
    anistar_status st = as_image_new(ctx, dims[0], dims[1], dims[2], AS_VOXEL_F64, &img);
    if (st) return st;
    st = as_image_set_geometry(ctx, img, spacing, origin, NULL);
    if (!st) {
        memcpy(img->data, voxels, img->count * sizeof(double));
        size_t first;
        size_t bad = as_image_count_nonfinite(img, &first);
        if (bad)
            st = as_fail(ctx, ANISTAR_EINVAL,
                         "image surface: %zu voxels are not finite, the first at index %zu",
                         bad, first);
    }
    if (!st) st = as_image_surface_create_fit(ctx, "image", img, iso, inside, fit, out);
    as_image_free(ctx, img);
    return st;
}

/* as_image_surface_lattice (surface.h). design: f at the lattice nodes, two z-layers at a
 * time (the nodes of layer z and z + 1: the image grid's and PAD + 1 more on every side,
 * (nx + 12)(ny + 12) values each), so memory stays O(nx ny) whatever the image; an edge
 * whose ends have opposite signs (f >= 0 against f < 0, the sign convention of the
 * sampler) holds a crossing, solved by as_surface_crossing between its ends. The points
 * grow in a doubling array. */
anistar_status as_image_surface_lattice(anistar_context *ctx, const as_surface *s, double **xyz,
                                        size_t *n, double *voxel) {
    *xyz = NULL;
    *n = 0;
    if (!as_surface_is_image(s))
        return as_fail(ctx, ANISTAR_EINVAL, "image lattice: not an image surface");
    const as_image_surface *is = (const as_image_surface *)s;
    const as_grid *g = as_bspline_grid(is->bs);
    double vmin = INFINITY;
    for (int c = 0; c < 3; c++) {
        double l = sqrt(g->a[c] * g->a[c] + g->a[3 + c] * g->a[3 + c] + g->a[6 + c] * g->a[6 + c]);
        vmin = fmin(vmin, l);
    }
    *voxel = vmin;
    /* the nodes: the padded grid's voxel centers and one node more on every side, a voxel
     * past the fade (bspline.h: where an object touches the image's border, its surface
     * closes there); as_bspline_layers' nodes, placed by the padded grid */
    const as_grid *pg = as_bspline_padded_grid(is->bs);
    const long lx = (long)pg->n[0] + 2, ly = (long)pg->n[1] + 2, lz = (long)pg->n[2] + 2;
    const size_t layer = (size_t)lx * (size_t)ly;
    double *val = as_alloc_array(ctx, 2 * layer, sizeof(double));
    if (!val) return as_fail(ctx, ANISTAR_ENOMEM, "image lattice: out of memory");
    as_bspline_layers *lay = NULL; /* NULL: a rotated grid, node by node */
    if (as_bspline_layers_new(ctx, is->bs, &lay)) {
        as_free(ctx, val, 2 * layer * sizeof(double));
        return ANISTAR_ENOMEM;
    }
    size_t cap = 0, cnt = 0;
    double *pts = NULL;
    anistar_status st = ANISTAR_OK;
#define LAT_NODE(i, j, k, out)                                                                 \
    do {                                                                                       \
        double v_[3] = {(double)(i) - 1, (double)(j) - 1, (double)(k) - 1};                    \
        as_grid_voxel_to_world(pg, v_, out);                                                   \
    } while (0)
    for (long k = 0; k < lz && !st; k++) {
        double *cur = val + (size_t)(k & 1) * layer, *prev = val + (size_t)((k + 1) & 1) * layer;
        if (lay) as_bspline_layers_get(lay, (size_t)k, cur); /* the spline's values */
        for (long j = 0; j < ly; j++)
            for (long i = 0; i < lx; i++) {
                double p[3], *q = &cur[(size_t)j * (size_t)lx + (size_t)i], f;
                if (lay) {
                    f = is->sign * (is->iso - *q); /* as im_eval (order 0) from the value */
                } else {
                    LAT_NODE(i, j, k, p);
                    f = im_eval(s, p, 0, NULL, NULL);
                }
                if (!isfinite(f)) {
                    LAT_NODE(i, j, k, p);
                    st = as_fail(ctx, ANISTAR_EINVAL,
                                 "image lattice: f is not finite at (%.17g, %.17g, %.17g)", p[0],
                                 p[1], p[2]);
                    break;
                }
                *q = f;
            }
        for (long j = 0; j < ly && !st; j++)
            for (long i = 0; i < lx && !st; i++) {
                const double f0 = cur[(size_t)j * (size_t)lx + (size_t)i];
                /* the edges to (i-1, j, k), (i, j-1, k), (i, j, k-1) */
                for (int e = 0; e < 3 && !st; e++) {
                    long a = i, b = j, c = k;
                    double f1;
                    if (e == 0) {
                        if (i == 0) continue;
                        a = i - 1;
                        f1 = cur[(size_t)j * (size_t)lx + (size_t)a];
                    } else if (e == 1) {
                        if (j == 0) continue;
                        b = j - 1;
                        f1 = cur[(size_t)b * (size_t)lx + (size_t)i];
                    } else {
                        if (k == 0) continue;
                        c = k - 1;
                        f1 = prev[(size_t)j * (size_t)lx + (size_t)i];
                    }
                    if ((f0 >= 0) == (f1 >= 0)) continue;
                    double p0[3], p1[3], x[3];
                    LAT_NODE(i, j, k, p0);
                    LAT_NODE(a, b, c, p1);
                    int found = 0;
                    if ((st = as_surface_crossing(ctx, s, p1, p0, p1, &found, x))) break;
                    if (!found) continue;
                    if (cnt == cap) {
                        void *q = pts;
                        if (as_grow(ctx, &q, &cap, cnt + 1, 3 * sizeof(double))) {
                            st = as_fail(ctx, ANISTAR_ENOMEM, "image lattice: out of memory");
                            break;
                        }
                        pts = q;
                    }
                    memcpy(pts + 3 * cnt, x, sizeof x);
                    cnt++;
                }
            }
    }
#undef LAT_NODE
    as_bspline_layers_free(ctx, lay);
    as_free(ctx, val, 2 * layer * sizeof(double));
    if (!st && cnt < cap) { /* the caller frees exactly 3 * cnt doubles */
        double *q = as_realloc(ctx, pts, cap * 3 * sizeof(double), cnt * 3 * sizeof(double));
        if (cnt && !q) st = as_fail(ctx, ANISTAR_ENOMEM, "image lattice: out of memory");
        else {
            pts = q;
            cap = cnt;
        }
    }
    if (st) {
        as_free(ctx, pts, cap * 3 * sizeof(double));
        return st;
    }
    *xyz = pts;
    *n = cnt;
    return ANISTAR_OK;
}
