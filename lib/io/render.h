/*
 * render.h — internal: a small software rasterizer that draws a triangle mesh (plain
 * arrays: coordinates, 0-based int32 triangles, optional per-triangle values) into an
 * 8-bit RGB image, and the per-triangle measures the renderer colours by. The io layer:
 * knows nothing of surfaces or meshing (DESIGN.md 1).
 *
 * The picture (all of it deterministic: the same input gives the same bytes):
 *  - View: orthographic. The `up` axis (default z) points up on screen; the viewer looks
 *    at the mesh from azimuth AZ (in the plane normal to `up`, from the next axis,
 *    counterclockwise seen from above: for up = z, AZ = 0 looks from +x and AZ = 90 from
 *    +y) and elevation EL (angle above that plane; 90 looks down). With (X, Y, Z) the
 *    axes cyclically permuted so that Z is `up` ((x,y,z) for z, (z,x,y) for y, (y,z,x)
 *    for x), the screen frame is
 *        right = (-sin AZ, cos AZ, 0), up = (-sin EL cos AZ, -sin EL sin AZ, cos EL),
 *        toward the viewer d = (cos EL cos AZ, cos EL sin AZ, sin EL).
 *  - Fit: the projection of the vertices used by triangles is scaled uniformly and
 *    centred in the area [m, W - L - m] x [m, H - m] (pixels, y down, pixel (i, j)
 *    covering [i, i+1) x [j, j+1)), m = floor(0.05 min(W, H)) the margin and L the width
 *    of the legend column (0 without legend). A flat projection (zero width or height)
 *    is fitted on its other side; a single point gets scale 1.
 *  - Visibility: a z-buffer over ss x ss samples per pixel (supersampling, ss 1..4,
 *    sample centres at ((i + 0.5)/ss, (j + 0.5)/ss)); a sample belongs to a triangle
 *    when it lies inside or on its border; the nearest triangle wins, ties go to the
 *    smaller triangle index (so the picture does not depend on the order of drawing).
 *    Edge functions are evaluated from a canonical vertex order, so the two triangles
 *    of a shared edge see exactly opposite values there: no sample falls between them.
 *  - Shading: flat per triangle, Lambert + ambient: colour x (ambient + diffuse
 *    max(0, n.l)), n the unit normal turned toward the viewer, l a light fixed in the
 *    view (from the upper left, in front: 0.35 left, 0.45 up, 1 toward the viewer).
 *    Front faces (normal toward the viewer, as a closed outward-oriented mesh shows
 *    them) get their colour; back faces get it mixed half and half with a brick red, so
 *    open or badly oriented meshes show their inside.
 *  - Colour: without values, light grey-blue. With values: the colormap (viridis,
 *    from 9 control points, linear in between: dark purple -> blue -> green -> yellow,
 *    luminance increasing) at t = (v - vmin) / (vmax - vmin) clamped to [0, 1];
 *    t = 0.5 when vmin == vmax; NaN values are mid grey; +inf is t = 1, -inf t = 0.
 *    The range [vmin, vmax] is given, or (NaN) the min and max of the finite values.
 *  - Edges (optional): a 1-pixel line along every edge of the VISIBLE triangles: a
 *    sample is on an edge when it lies within 0.5 px of one of its own triangle's edge
 *    lines, so hidden edges never show and there is no depth fighting. The edge colour
 *    is the face colour darkened (light faces) or lightened (dark faces), blended with
 *    opacity 0.8 x f, where f fades the edges of triangles whose projection is thin: f =
 *    clamp((h - 1.5) / 2.5, 0, 1), h the triangle's shortest projected altitude in
 *    pixels. So dense meshes (or triangles seen edge-on) do not turn black; edges are
 *    fully drawn on triangles at least 4 px high.
 *  - Legend (optional, with values): a vertical colour bar on the right with the max at
 *    the top, the min at the bottom and the middle value, and the title above it, in a
 *    built-in 5x7 bitmap font (scaled by max(1, round(min(W, H) / 400))). It is left out
 *    when there is no finite value or range, or when it would take more than a third of
 *    the width or the image is less than 120 pixels high.
 *  - Memory: the samples are rasterized in horizontal bands of about 2^18 samples (so
 *    that a band's depth and id buffers stay in cache), so the work space is ~3 MiB plus
 *    ~40 bytes per triangle and 24 per vertex, whatever the image size; the caller
 *    provides the W x H x 3 output.
 */
#ifndef ANISTAR_RENDER_H
#define ANISTAR_RENDER_H

#include "core.h"

#include <stddef.h>
#include <stdint.h>

/* The largest width and height (as the PNG writer's). */
#define AS_RENDER_MAX_SIDE 16384u

typedef struct as_render_params {
    uint32_t width, height;   /* pixels, 1..AS_RENDER_MAX_SIDE (default 1024 x 768) */
    double azimuth;           /* degrees, finite (default 30) */
    double elevation;         /* degrees, finite (default 20) */
    int up;                   /* 0 = x, 1 = y, 2 = z (default) */
    int supersample;          /* ss in 1..4 (default 3) */
    int edges;                /* 1 draw edges (default), 0 not */
    int legend;               /* 1 draw the colour bar when there are values (default) */
    double vmin, vmax;        /* colour range; both NaN (default): from the values */
    const char *label;        /* legend title (NULL: none); letters are shown lowercase,
                                 characters without a glyph as '?' */
    double ambient, diffuse;  /* lighting (default 0.35, 0.65), each in [0, 1] */
    unsigned char background[3]; /* default white */
} as_render_params;

/* Fill p with the defaults above. */
void as_render_params_init(as_render_params *p);
/* EINVAL (with a message) unless p is valid, as as_render checks it. */
anistar_status as_render_params_check(anistar_context *ctx, const as_render_params *p);

/*
 * Draw the mesh (nv vertices xyz, nt triangles tri, values NULL or one per triangle)
 * into rgb (p->width * p->height * 3 bytes, rows top first, written entirely).
 * Returns EINVAL for bad parameters (sizes, angles, supersample, up, lighting, a range
 * with vmin >= vmax or a non-finite end, only one end given), a triangle index outside
 * [0, nv), a non-finite coordinate, or NULL arrays with nonzero counts; ENOMEM. nt == 0
 * (or only zero-area triangles) gives the background (and no legend unless a range is
 * given).
 * design: (1) project the vertices, fit, compute each triangle's shaded colour and edge
 *   fade; (2) bucket triangles by their first band (counting sort); (3) for each band
 *   of rows keep the active triangles, rasterize them into the sample band (depth and
 *   triangle id), then resolve each pixel (mean of its samples' colours, with edges);
 *   (4) draw the legend.
 */
anistar_status as_render(anistar_context *ctx, const as_render_params *p, size_t nv,
                         const double *xyz, size_t nt, const int32_t *tri,
                         const double *values, unsigned char *rgb);

/* The colormap at t (clamped to [0, 1]; NaN gives the "no value" grey), components in
 * [0, 1]. */
void as_render_colormap(double t, double rgb[3]);

/*
 * Per-triangle measures (Euclidean), +inf for a triangle with zero area (collinear or
 * repeated points), NaN if a coordinate is not finite:
 *   radius-edge ratio = circumradius / shortest edge (1/sqrt(3) ~ 0.577 for an
 *     equilateral triangle; the shape measure of the mesher, paper 3.1 and 4.1 rule 2);
 *   aspect = longest edge / shortest altitude (2/sqrt(3) ~ 1.155 for an equilateral
 *     triangle).
 */
double as_tri_radius_edge(const double a[3], const double b[3], const double c[3]);
double as_tri_aspect(const double a[3], const double b[3], const double c[3]);

#endif /* ANISTAR_RENDER_H */
