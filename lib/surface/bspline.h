/*
 * bspline.h — internal: the cubic B-spline reconstruction of a 3D image (DESIGN.md 4.6:
 * "value = smooth reconstruction (cubic B-spline of the voxels) ... outside the image
 * counts as background, so a surface touching the border is closed").
 *
 * Pure functions on a voxel array: no surface oracle here; an image surface evaluates
 * f(p) - isovalue through these.
 *
 * The reconstruction. Let s be the voxel values extended to all of Z^3: beyond the image
 * the border voxels fade to the background value b over AS_BSPLINE_FADE voxels,
 *     s(k) = b + (s(clamp(k)) - b) F(d_x) F(d_y) F(d_z),
 * d_a the distance of k outside [0, n_a - 1] along axis a, F(0) = 1, F(d) = 1 - S(d / (FADE
 * + 1)) with S the quintic smoothstep 6t^5 - 15t^4 + 10t^3, F(d) = 0 from FADE + 1 on (so
 * s = b from the padded grid's last layer on: PAD = FADE + 1 voxels are stored beyond the
 * image on every side). f is the unique cubic spline with knots at the voxel
 * centers that INTERPOLATES s on all of Z^3 and tends to b at infinity:
 *     f(p) = b + sum_{k in Z^3} c_k beta3(v_x - k_x) beta3(v_y - k_y) beta3(v_z - k_z),
 * v = A^-1 (p - origin) the voxel coordinates of p (image_io.h, as_grid), beta3 the
 * centered cubic B-spline. The coefficients c of s - b are computed EXACTLY for the
 * infinite extension (Unser's recursive prefilter, pole z = sqrt(3) - 2, along x, y, z)
 * on the padded grid: causal pass started from zero (the
 * extended data is b before the padded grid's first voxel), the anticausal pass started
 * from its closed form c-[N-1] = -z/(1 - z^2) c+[N-1] (b after its last). Outside the
 * padded grid the coefficients continue geometrically,
 *     c_k = z^(dx + dy + dz) c_clamp(k),   d = distance of k outside [0, N-1] per axis,
 * so only the padded grid's coefficients are stored. Consequences:
 *  - f(voxel center (i,j,k)) = voxel value inside the image, = s(k) at every integer
 *    position outside it (to rounding); f is C2 everywhere, across the border too;
 *  - design: the fade, not a step to b at the border. An interpolating cubic spline rings
 *    at a step: 10.8% of the step's height beyond each side, decaying by |z| per voxel.
 *    With the step at the border, a float ball whose border voxels lay 1.3 below the
 *    isovalue and 14.3 above the background got six spurious pancakes half a voxel
 *    inside the grid's faces (8 components, certified), and the brain MRI at Otsu's
 *    threshold 12 components within a voxel of its faces. The quintic fade over 4 voxels
 *    rings at 0.11% of |s_border - b| (3 voxels: 0.26%, 2: 0.75%; measured on the 1D
 *    spline), and where the object touches the border its surface closes within the fade;
 *  - a surface f = level with level != b is closed even where the object touches the
 *    border: |f - b| < |z|^(d-2) max|c| at d voxels beyond the padded grid (|z| = 0.268),
 *    see as_bspline_margin;
 *  - beyond AS_BSPLINE_REACH voxels outside the padded grid (along any axis) f returns
 *    exactly b with zero derivatives; the jump there is below |z|^29 max|c| ~ 3e-17
 *    max|c|, i.e. rounding;
 *  - polynomials of degree <= 3 are reproduced exactly away from the border (the
 *    extension's influence decays like |z|^d at d voxels from it: 2e-14 at 24).
 *
 * The smoothing fit (AS_BSPLINE_SMOOTH): c = s - b itself, the approximating cubic
 * B-spline f = b + sum_k (s(k) - b) beta3(v - k). Its weights are >= 0 and sum to 1, so f
 * lies between the smallest and largest data of the 4^3 voxels around a point: no
 * overshoot at all, at the price of a blur (f(voxel) = the average of the voxel and its
 * neighbours with weights (1/6, 2/3, 1/6) per axis; a plane of a step is kept, corners
 * are rounded over about a voxel). For label images and masks, where every step is a
 * jump between labels: the interpolating fit rings at each (10.8% of the jump per side,
 * more where steps meet in 3D) and on the liver labels (values 0, 84, 85, 127, 255; iso
 * 105.6: voxels inside form 1 component with 9 cavities) it made 45 to 74 components,
 * most of them 4-vertex specks of a tenth of a voxel at 127/255 and 0/85 junctions; the
 * smoothing fit makes 1. Beyond the padded grid its coefficients are 0 (the last layer's
 * data is b), so the geometric continuation below reads 0 and the margin holds as well.
 *
 * Memory and speed: coefficients are doubles, (nx+10)(ny+10)(nz+10)*8 bytes with the pad (a
 * 256^3 image: 140 MiB; 512^3: 1.06 GiB; the image's own voxels can be freed after
 * as_bspline_create). float32 would halve that but limit the interpolation to ~1e-7 relative and make Hessians of
 * smooth images noisy (second differences of rounded coefficients divided by h^2), and
 * the curvature metric needs Hessians. Prefiltering costs 3 passes over the array (the
 * y and z passes run over whole rows / slabs, so they stream through memory).
 * A value costs 64 multiply-adds over 16 cache lines, a value+gradient+Hessian ~4x that.
 *
 * Evaluation functions take the spline const and touch no shared state: any number of
 * threads may evaluate one spline at once. A non-finite point gives NaN results.
 */
#ifndef ANISTAR_BSPLINE_H
#define ANISTAR_BSPLINE_H

#include "core.h"
#include "io/image_io.h"

/* Beyond this many voxels outside the padded grid the reconstruction is exactly b. */
#define AS_BSPLINE_REACH 30
/* Voxels over which the data beyond the image fades to the background (see above), and
 * the stored pad: the fade and one voxel of background. */
#define AS_BSPLINE_FADE 4
#define AS_BSPLINE_PAD (AS_BSPLINE_FADE + 1)
/* The fits: the coefficients interpolate the extended data, or are the data. */
enum { AS_BSPLINE_INTERPOLATE = 0, AS_BSPLINE_SMOOTH = 1 };

typedef struct as_bspline as_bspline;

/*
 * Prefilter img into the spline of its voxels with background value `background`
 * (the surface code passes a value on the outside side of its isovalue).
 * Returns ANISTAR_OK, ANISTAR_EINVAL (NULL image, non-finite background, image with
 * NaN/infinite voxels, values whose coefficients overflow), ANISTAR_ENOMEM.
 * The spline copies what it needs: img may be freed afterwards.
 * design: (DESIGN.md 4.6: smooth reconstruction, outside is background)
 *   - per padded x row: convert to double, subtract b, fade beyond the image (the row's
 *     ends along x, the whole row by its y and z distances), prefilter along x;
 *   - prefilter along y (each slab, all its rows at once), then z (whole slabs at once):
 *     causal and anticausal first-order recursions of pole z, gain 6 per axis;
 *   - record max |c| (as_bspline_margin) and reject overflowed coefficients.
 */
anistar_status as_bspline_create(anistar_context *ctx, const as_image *img, double background,
                                 as_bspline **out);
/* The same with the fit chosen (AS_BSPLINE_INTERPOLATE: as_bspline_create; SMOOTH: the
 * approximating spline, see above). EINVAL also for another fit. */
anistar_status as_bspline_create_fit(anistar_context *ctx, const as_image *img,
                                     double background, int fit, as_bspline **out);
/* The fit of bs. */
int as_bspline_fit(const as_bspline *bs);
void as_bspline_free(anistar_context *ctx, as_bspline *bs);

/* f(p) at a world point p: the fast value-only evaluation. */
double as_bspline_value(const as_bspline *bs, const double p[3]);
/* f(p) and its world-coordinate gradient g. */
double as_bspline_value_grad(const as_bspline *bs, const double p[3], double g[3]);
/* f(p), gradient g and Hessian h (m11 m12 m13 m22 m23 m33), world coordinates:
 * g = A^-T grad_v f, H = A^-T H_v A^-1 (spacing and direction matrix included). */
double as_bspline_value_grad_hess(const as_bspline *bs, const double p[3], double g[3],
                                  double h[6]);

/* The same in voxel coordinates v (voxel (i,j,k)'s center is v = (i,j,k)); derivatives
 * with respect to v. */
double as_bspline_value_voxel(const as_bspline *bs, const double v[3]);
double as_bspline_value_grad_hess_voxel(const as_bspline *bs, const double v[3], double g[3],
                                        double h[6]);

/* The image's grid geometry (dims, voxel <-> world: as_grid_voxel_to_world,
 * as_grid_world_box, as_grid_bounding_sphere in io/image_io.h); f differs from b up to
 * as_bspline_margin voxels beyond it. */
const as_grid *as_bspline_grid(const as_bspline *bs);
/* The padded grid: the image's with AS_BSPLINE_PAD voxels more on every side (its voxel
 * (i, j, k) is the image's (i, j, k) - PAD), where the coefficients are stored. */
const as_grid *as_bspline_padded_grid(const as_bspline *bs);
double as_bspline_background(const as_bspline *bs);
/* max |c| over the stored coefficients (the padded grid's). */
double as_bspline_coef_max(const as_bspline *bs);

/*
 * The values on the lattice of the padded grid's voxel centers (as_bspline_padded_grid,
 * nx ny nz its dimensions below) grown by one node per side: node (i, j, k), 0 <= i <
 * nx + 2 (and so on), is padded voxel coordinate (i - 1, j - 1, k - 1), and its value is
 * as_bspline_value at that node's world point (as_grid_voxel_to_world on the padded
 * grid), to the bit.
 * as_bspline_layers_new sets *out to NULL (and returns OK) when the grid's direction
 * matrix is not diagonal: then the caller evaluates node by node. Returns ENOMEM.
 * as_bspline_layers_get fills layer k's (nx + 2)(ny + 2) values, x fastest; layers are
 * meant to be taken in increasing k (each plane of coefficients is summed once for the
 * four consecutive layers that read it). The object keeps bs (which must outlive it) and
 * is not to be shared between threads.
 * design: separable sums. Per plane of coefficients, the x sums of its rows at every x
 *   node, then the y sums at every (x, y) node; per layer the z sums of its four planes:
 *   the same products and additions in the same order as a single value's evaluation,
 *   about 25 operations per node instead of 150 (the lattice of a 256^3 image is 17
 *   million values).
 */
typedef struct as_bspline_layers as_bspline_layers;
anistar_status as_bspline_layers_new(anistar_context *ctx, const as_bspline *bs,
                                     as_bspline_layers **out);
void as_bspline_layers_get(as_bspline_layers *L, size_t k, double *out);
void as_bspline_layers_free(anistar_context *ctx, as_bspline_layers *L);

/*
 * A margin m in voxels (an integer, 0 when f is b everywhere, else 1 <= m <= AS_BSPLINE_PAD
 * + AS_BSPLINE_REACH) such that f(p) != level for every p whose voxel coordinates lie
 * more than m voxels outside [0, n-1] along some axis: the surface f = level lies inside
 * the world box / sphere of the image's grid grown by m voxels (as_grid_world_box(grid, m,
 * ...)). For level == b it returns PAD + REACH.
 * design: such a p reads coefficients m - 1 or more voxels outside along that axis, and
 *   |f - b| is at most their largest |c| (the B-spline weights are >= 0 and sum to 1 along
 *   each axis; beyond the stored grid the coefficients shrink by |z| per voxel); the
 *   largest |c| of each layer along each axis is kept, so m is the first distance where
 *   that bound falls below |level - b|. Where the border voxels lie on b's side of the
 *   level, m is a voxel or two whatever the pad.
 */
double as_bspline_margin(const as_bspline *bs, double level);

#endif /* ANISTAR_BSPLINE_H */
