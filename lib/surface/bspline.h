/*
 * bspline.h — internal: the cubic B-spline reconstruction of a 3D image (DESIGN.md 4.6:
 * "value = smooth reconstruction (cubic B-spline of the voxels) ... outside the image
 * counts as background, so a surface touching the border is closed").
 *
 * Pure functions on a voxel array: no surface oracle here; an image surface evaluates
 * f(p) - isovalue through these.
 *
 * The reconstruction. Let s be the voxel values extended to all of Z^3 by the background
 * value b (every voxel outside the image equals b). f is the unique cubic spline with
 * knots at the voxel centers that INTERPOLATES s on all of Z^3 and tends to b at
 * infinity:
 *     f(p) = b + sum_{k in Z^3} c_k beta3(v_x - k_x) beta3(v_y - k_y) beta3(v_z - k_z),
 * v = A^-1 (p - origin) the voxel coordinates of p (image_io.h, as_grid), beta3 the
 * centered cubic B-spline. The coefficients c of s - b are computed EXACTLY for the
 * infinite extension (Unser's recursive prefilter, pole z = sqrt(3) - 2, along x, y, z):
 * causal pass started from zero (the extended data is 0 before the first voxel), the
 * anticausal pass started from its closed form c-[n-1] = -z/(1 - z^2) c+[n-1] (the data
 * is 0 after the last voxel). Outside the grid the coefficients continue geometrically,
 *     c_k = z^(dx + dy + dz) c_clamp(k),   d = distance of k outside [0, n-1] per axis,
 * so only the nx*ny*nz coefficients inside are stored (no padding). Consequences:
 *  - f(voxel center (i,j,k)) = voxel value inside the image, = b at every integer
 *    position outside it (to rounding); f is C2 everywhere, across the border too;
 *  - a surface f = level with level != b is closed even where the object touches the
 *    border: |f - b| < |z|^(d-2) max|c| at d voxels beyond the grid (|z| = 0.268), see
 *    as_bspline_margin;
 *  - beyond AS_BSPLINE_REACH voxels outside the grid (along any axis) f returns exactly
 *    b with zero derivatives; the jump there is below |z|^29 max|c| ~ 3e-17 max|c|,
 *    i.e. rounding;
 *  - polynomials of degree <= 3 are reproduced exactly away from the border (the
 *    background's influence decays like |z|^d at d voxels from it: 2e-14 at 24).
 *
 * Memory and speed: coefficients are doubles, nx*ny*nz*8 bytes (a 256^3 image: 128 MiB;
 * 512^3: 1 GiB; the image's own voxels can be freed after as_bspline_create). float32
 * would halve that but limit the interpolation to ~1e-7 relative and make Hessians of
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

/* Beyond this many voxels outside the grid the reconstruction is exactly b. */
#define AS_BSPLINE_REACH 30

typedef struct as_bspline as_bspline;

/*
 * Prefilter img into the spline of its voxels with background value `background`
 * (the surface code passes a value on the outside side of its isovalue).
 * Returns ANISTAR_OK, ANISTAR_EINVAL (NULL image, non-finite background, image with
 * NaN/infinite voxels, values whose coefficients overflow), ANISTAR_ENOMEM.
 * The spline copies what it needs: img may be freed afterwards.
 * design: (DESIGN.md 4.6: smooth reconstruction, outside is background)
 *   - per x row: convert to double, subtract b, prefilter along x;
 *   - prefilter along y (each slab, all its rows at once), then z (whole slabs at once):
 *     causal and anticausal first-order recursions of pole z, gain 6 per axis;
 *   - record max |c| (as_bspline_margin) and reject overflowed coefficients.
 */
anistar_status as_bspline_create(anistar_context *ctx, const as_image *img, double background,
                                 as_bspline **out);
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

/* The grid geometry (dims, voxel <-> world: as_grid_voxel_to_world, as_grid_world_box,
 * as_grid_bounding_sphere in io/image_io.h). */
const as_grid *as_bspline_grid(const as_bspline *bs);
double as_bspline_background(const as_bspline *bs);
/* max |c| over the stored coefficients. */
double as_bspline_coef_max(const as_bspline *bs);

/*
 * The values on the lattice of voxel centers grown by one node per side: node (i, j, k),
 * 0 <= i < nx + 2 (and so on), is voxel coordinate (i - 1, j - 1, k - 1), and its value
 * is as_bspline_value at that node's world point (as_grid_voxel_to_world), to the bit.
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
 * A margin m in voxels (0 <= m <= AS_BSPLINE_REACH, an integer) such that
 * f(p) != level for every p whose voxel coordinates lie more than m voxels outside
 * [0, n-1] along some axis: the surface f = level lies inside the world box / sphere
 * of the grid grown by m voxels (as_grid_world_box(grid, m, ...)). For level == b it
 * returns AS_BSPLINE_REACH.
 * design: |f - b| < |z|^(d-2) max|c| beyond d voxels (the B-spline weights are >= 0 and
 *   sum to 1 along each axis; the extended coefficients shrink by |z| per voxel), so
 *   m = ceil(2 + log(|level - b| / max|c|) / log|z|), clamped.
 */
double as_bspline_margin(const as_bspline *bs, double level);

#endif /* ANISTAR_BSPLINE_H */
