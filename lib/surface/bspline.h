/*
 * bspline.h — internal: the cubic B-spline reconstruction of a 3D image (DESIGN.md 4.6:
 * "value = smooth reconstruction (cubic B-spline of the voxels) ... outside the image
 * counts as background, so a surface touching the border is closed").
 *
 * Pure functions on a voxel array: no surface oracle here; an image surface evaluates
 * f(p) - isovalue through these.
 *
 * The reconstruction. Let s be the voxel values extended to all of Z^3: beyond the image
 * the border voxels fade to the background value b over AS_BSPLINE_PAD voxels,
 *     s(k) = b + (s(clamp(k)) - b) F(d_x) F(d_y) F(d_z),
 * d_a the distance of k outside [0, n_a - 1] along axis a, F(0) = 1, F(d) = 1 - S(d / (PAD
 * + 1)) with S the quintic smoothstep 6t^5 - 15t^4 + 10t^3, F(d) = 0 from PAD + 1 on (so
 * s = b beyond the padded grid). f is the unique cubic spline with knots at the voxel
 * centers that INTERPOLATES s on all of Z^3 and tends to b at infinity:
 *     f(p) = b + sum_{k in Z^3} c_k beta3(v_x - k_x) beta3(v_y - k_y) beta3(v_z - k_z),
 * v = A^-1 (p - origin) the voxel coordinates of p (image_io.h, as_grid), beta3 the
 * centered cubic B-spline. The coefficients c of s - b are computed EXACTLY for the
 * infinite extension (Unser's recursive prefilter, pole z = sqrt(3) - 2, along x, y, z)
 * on the padded grid (PAD voxels more on every side): causal pass started from zero (the
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
 * Memory and speed: coefficients are doubles, (nx+8)(ny+8)(nz+8)*8 bytes with the pad (a
 * 256^3 image: 138 MiB; 512^3: 1.05 GiB; the image's own voxels can be freed after
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
/* Voxels over which the data beyond the image fades to the background (see above). */
#define AS_BSPLINE_PAD 4

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
double as_bspline_background(const as_bspline *bs);
/* max |c| over the stored coefficients (the padded grid's). */
double as_bspline_coef_max(const as_bspline *bs);

/*
 * A margin m in voxels (an integer, 0 when f is b everywhere, else AS_BSPLINE_PAD <= m <=
 * AS_BSPLINE_PAD + AS_BSPLINE_REACH) such that f(p) != level for every p whose voxel
 * coordinates lie more than m voxels outside [0, n-1] along some axis: the surface
 * f = level lies inside the world box / sphere of the image's grid grown by m voxels
 * (as_grid_world_box(grid, m, ...)). For level == b it returns PAD + REACH.
 * design: |f - b| < |z|^(d-2) max|c| beyond d voxels outside the padded grid (the
 *   B-spline weights are >= 0 and sum to 1 along each axis; the extended coefficients
 *   shrink by |z| per voxel), so m = PAD + ceil(2 + log(|level - b| / max|c|) / log|z|),
 *   the ceil clamped to [0, REACH].
 */
double as_bspline_margin(const as_bspline *bs, double level);

#endif /* ANISTAR_BSPLINE_H */
