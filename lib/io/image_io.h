/*
 * image_io.h — internal: 3D images in memory and their readers (.inr, NRRD .nrrd/.nhdr,
 * MetaImage .mha/.mhd, headerless raw). Files to plain voxel arrays: this layer knows
 * nothing of surfaces (DESIGN.md 1, "io").
 *
 * In-memory image (as_image):
 *  - nx, ny, nz voxels, x fastest: voxel (i, j, k) is element i + nx * (j + ny * k).
 *  - The voxels keep their NATIVE type (uint8 ... float64), converted to host byte order
 *    on load, and are converted to double on access (as_image_value, as_image_to_double).
 *    Why: a label or MRI image stays 1 or 2 bytes per voxel (a 512^3 uint8 image is
 *    128 MiB instead of 512 MiB as float32 or 1 GiB as double), no value is rounded
 *    (float32 storage would round int32 and float64 images), and the only consumer
 *    that reads every voxel (the B-spline prefilter, surface/bspline.c) converts once.
 *    64-bit integers beyond 2^53 round when converted to double; their native values
 *    stay exact in img->data.
 *  - Geometry (as_grid): the world position of voxel (i, j, k)'s center is
 *        p = origin + A (i, j, k)^T,   A = D diag(spacing),
 *    D the 3x3 direction matrix (column c = direction of axis c; identity when the file
 *    gives none). D may be any non-singular matrix (NRRD "space directions" and MetaImage
 *    "TransformMatrix" are honoured, rotations and shears alike); A^-1 is precomputed.
 *
 * Readers (all): return ANISTAR_EIO when a file cannot be opened or read (the message
 * names it), ANISTAR_EFORMAT for a malformed or unsupported file (the message names the
 * file, the header field and the problem), ANISTAR_ENOMEM when the context allocator
 * fails. On failure *out is NULL and nothing leaks. They are strict:
 *  - every header field must be known (metadata that does not change the voxels or
 *    their positions is accepted and ignored; the list is in image_io.c);
 *  - sizes must be positive and their product (in bytes) must fit in size_t;
 *  - binary data must fill the file exactly from its offset to the end (missing bytes:
 *    "truncated"; extra bytes: the header's sizes or type disagree with the file),
 *    except when the header says "data at the end of the file" (byte skip / HeaderSize
 *    -1); the file size is checked BEFORE the voxel array is allocated, so a header that
 *    claims huge sizes costs nothing;
 *  - ASCII data must hold exactly nx*ny*nz numbers, each in range of the voxel type;
 *  - float images with a NaN or infinite voxel are rejected (ANISTAR_EFORMAT "image has
 *    N non-finite voxels, the first at (i,j,k)"): one NaN would spread through the whole
 *    B-spline prefilter, and a surface cannot be defined there;
 *  - compressed data (gzip, bzip2, MetaImage CompressedData) is reported as unsupported
 *    (anistar links no zlib).
 * Numbers in headers are parsed with strtod: the C locale's decimal point is assumed.
 */
#ifndef ANISTAR_IMAGE_IO_H
#define ANISTAR_IMAGE_IO_H

#include "core.h"

/* Voxel types. */
typedef enum as_voxel_type {
    AS_VOXEL_U8,
    AS_VOXEL_I8,
    AS_VOXEL_U16,
    AS_VOXEL_I16,
    AS_VOXEL_U32,
    AS_VOXEL_I32,
    AS_VOXEL_U64,
    AS_VOXEL_I64,
    AS_VOXEL_F32,
    AS_VOXEL_F64,
    AS_VOXEL_TYPE_COUNT_ /* not a type */
} as_voxel_type;

/* Bytes per voxel (0 for an invalid type). */
size_t as_voxel_size(as_voxel_type t);
/* "uint8", "int8", ... "float32", "float64" ("invalid" otherwise). Static string. */
const char *as_voxel_type_name(as_voxel_type t);

/* The voxel grid's placement in world coordinates (see the top of this file). */
typedef struct as_grid {
    size_t n[3];       /* voxels per axis (nx, ny, nz) */
    double origin[3];  /* world position of voxel (0,0,0)'s center */
    double spacing[3]; /* > 0 */
    double dir[9];     /* D, row-major: dir[3*r + c] = component r of axis c's direction */
    double a[9];       /* A = D diag(spacing), row-major: p = origin + A v */
    double ainv[9];    /* A^-1, row-major: v = A^-1 (p - origin) */
} as_grid;

/* Voxel coordinates v (voxel (i,j,k)'s center is v = (i,j,k)) to world p, and back. */
void as_grid_voxel_to_world(const as_grid *g, const double v[3], double p[3]);
/* Inline: every B-spline evaluation of an image surface starts here. */
static inline void as_grid_world_to_voxel(const as_grid *g, const double p[3], double v[3]) {
    double d[3] = {p[0] - g->origin[0], p[1] - g->origin[1], p[2] - g->origin[2]};
    for (int r = 0; r < 3; r++)
        v[r] = g->ainv[3 * r] * d[0] + g->ainv[3 * r + 1] * d[1] + g->ainv[3 * r + 2] * d[2];
}

/* The axis-aligned world box of the voxel-coordinate box [-margin, n-1+margin] per axis
 * (margin in voxels, >= 0; margin 0 is the box of the voxel centers, 0.5 the box of the
 * voxels' cells). With a non-diagonal D it is the box of the 8 mapped corners. */
void as_grid_world_box(const as_grid *g, double margin, double lo[3], double hi[3]);
/* A sphere (center c, radius *r) containing the same voxel-coordinate box: centered on
 * the mapped center of the box, radius the largest distance to its 8 mapped corners. */
void as_grid_bounding_sphere(const as_grid *g, double margin, double c[3], double *r);

typedef struct as_image {
    size_t nx, ny, nz;  /* == grid.n */
    size_t count;       /* nx * ny * nz */
    as_voxel_type type; /* native voxel type */
    void *data;         /* count * as_voxel_size(type) bytes, host byte order, owned */
    size_t data_bytes;
    as_grid grid;
} as_image;

/*
 * A new image of nx*ny*nz voxels of the given type, all 0, with unit spacing, zero
 * origin and identity directions. Returns ANISTAR_EINVAL for a zero size or an invalid
 * type, ANISTAR_EFORMAT when the voxel count or byte size overflows size_t (message
 * "image dimensions NxNxN overflow"), ANISTAR_ENOMEM.
 */
anistar_status as_image_new(anistar_context *ctx, size_t nx, size_t ny, size_t nz,
                            as_voxel_type type, as_image **out);
void as_image_free(anistar_context *ctx, as_image *img);

/*
 * Set the geometry of img: spacing (> 0, finite; NULL = 1 1 1), origin (finite; NULL =
 * 0 0 0), dir (row-major, column c = direction of axis c, finite; NULL = identity).
 * The columns of dir are used as given (not normalised). Returns ANISTAR_EINVAL (img
 * unchanged) when a value is not finite, a spacing is <= 0, or A = D diag(spacing) is
 * singular or too ill-conditioned to invert (|det A| <= 1e-12 |a1| |a2| |a3|).
 */
anistar_status as_image_set_geometry(anistar_context *ctx, as_image *img, const double spacing[3],
                                     const double origin[3], const double dir[9]);

/* Voxel number idx (< count) as a double. */
double as_image_value(const as_image *img, size_t idx);
/* Voxels first .. first+n-1 (first + n <= count) as doubles into out. */
void as_image_to_double(const as_image *img, size_t first, size_t n, double *out);
/* Smallest and largest voxel values (as doubles; NaN voxels are skipped, both NaN when
 * every voxel is NaN). Useful to pick a background value below or above an isovalue. */
void as_image_range(const as_image *img, double *lo, double *hi);
/* Number of NaN or infinite voxels (0 for integer types); *first_idx gets the index of
 * the first one when there is one (first_idx may be NULL). */
size_t as_image_count_nonfinite(const as_image *img, size_t *first_idx);

/*
 * Otsu's threshold (Otsu 1979: the value that maximises the between-class variance of
 * the two classes it splits the voxels into), on a histogram of AS_OTSU_BINS equal bins
 * over [lo, hi] (the finite voxel range): fill h with as_otsu_init, feed every voxel
 * with as_otsu_add (non-finite values are skipped), then as_otsu_pick. The threshold is
 * a bin boundary strictly between lo and hi.
 * as_otsu_pick returns 0, or -1 when lo == hi or no voxel was finite.
 */
#define AS_OTSU_BINS 256
typedef struct as_otsu_hist {
    double lo, hi;
    uint64_t count[AS_OTSU_BINS];
} as_otsu_hist;
void as_otsu_init(as_otsu_hist *h, double lo, double hi);
void as_otsu_add(as_otsu_hist *h, const double *v, size_t n);
int as_otsu_pick(const as_otsu_hist *h, double *iso);
/* Otsu's threshold of an image's voxels. 0, or -1 (constant image, or no finite voxel). */
int as_image_otsu(const as_image *img, double *iso);

/* ---- readers ----------------------------------------------------------------------- */

/* By extension (case-insensitive): .inr, .nrrd, .nhdr, .mha, .mhd. Another extension:
 * ANISTAR_EFORMAT. */
anistar_status as_image_read(anistar_context *ctx, const char *path, as_image **out);

/*
 * INRIA Inrimage 4: "#INRIMAGE-4#{\n", lines KEY=VALUE, padding, "##}\n" (conforming
 * writers pad the header to a multiple of 256 bytes; the data starts right after the
 * "##}\n" line in any case). Fields: XDIM YDIM (required), ZDIM (default 1), VDIM (must
 * be 1), TYPE (unsigned fixed | signed fixed | float; required), PIXSIZE ("N bits",
 * N = 8/16/32/64, float 32/64; required), CPU (decm | alpha | pc: little-endian; sun |
 * sgi: big-endian; required when PIXSIZE > 8), VX VY VZ (spacing, default 1), TX TY TZ
 * (origin, default 0, as CGAL's ImageIO reads them), SCALE (2**n, ignored as CGAL does),
 * XO YO ZO and RX RY RZ (accepted only when 0: a nonzero value is unsupported).
 * Lines starting with '#' are comments.
 */
anistar_status as_image_read_inr(anistar_context *ctx, const char *path, as_image **out);

/*
 * NRRD (magic NRRD0001..NRRD0005), data attached (.nrrd: after the blank line ending the
 * header) or detached (.nhdr: "data file: NAME", NAME relative to the header's folder
 * unless absolute). Fields: dimension (3, or 4 with one non-spatial axis of size 1 marked
 * "none" in space directions or "nan" in spacings), type (every C type name NRRD allows;
 * "block" is unsupported), sizes, endian (required for multi-byte raw data), encoding
 * (raw | ascii | text | txt; gzip/gz, bzip2/bz2 and hex are unsupported), spacings,
 * space directions, space origin, space dimension / space (3-D spaces only), byte skip
 * (-1 = data at the end of the file, raw only), line skip; "data file" lists and
 * formats are unsupported. Without space directions the directions are the identity;
 * world coordinates are those of the file's space, unconverted. Key/value pairs (":=")
 * and comments are ignored; so are content, kinds, labels, units, space units,
 * thicknesses, centers, centerings, axis mins/maxs, min, max, old min/max, sample units,
 * measurement frame, number.
 */
anistar_status as_image_read_nrrd(anistar_context *ctx, const char *path, as_image **out);

/*
 * MetaImage (.mha, .mhd): lines "Key = Value", ElementDataFile last. Fields (keys are
 * case-insensitive): ObjectType (Image), NDims (3), DimSize, ElementType (MET_CHAR,
 * MET_UCHAR, MET_SHORT, MET_USHORT, MET_INT, MET_UINT, MET_LONG, MET_ULONG (4 bytes as in
 * MetaIO), MET_LONG_LONG, MET_ULONG_LONG, MET_FLOAT, MET_DOUBLE), ElementSpacing (else
 * ElementSize, else 1), Offset / Position / Origin, TransformMatrix / Rotation /
 * Orientation (9 numbers: consecutive triples are the directions of axes x, y, z, as
 * ITK reads them), BinaryData (False = ASCII numbers), BinaryDataByteOrderMSB /
 * ElementByteOrderMSB, CompressedData (True is unsupported), HeaderSize (bytes skipped
 * before the data; -1 = data at the end of the file), ElementNumberOfChannels (1),
 * ElementDataFile (LOCAL = data after the header; or a file name relative to the header's
 * folder; LIST and patterns are unsupported). Ignored: Comment, ObjectSubType, Name, ID,
 * ParentID, Color, TransformType, CenterOfRotation, AnatomicalOrientation, ElementMin,
 * ElementMax, Modality, AcquisitionDate, CompressedDataSize, ElementNBits.
 */
anistar_status as_image_read_metaimage(anistar_context *ctx, const char *path, as_image **out);

/*
 * Headerless raw voxels: nx*ny*nz voxels of the given type and byte order (big_endian
 * 0 or 1), starting at byte header_offset (>= 0), or ending at the end of the file when
 * header_offset == -1. spacing / origin may be NULL (1 1 1 / 0 0 0). The file must hold
 * exactly header_offset + the voxel bytes. Sizes <= 0 are ANISTAR_EINVAL.
 */
anistar_status as_image_read_raw(anistar_context *ctx, const char *path, int64_t nx, int64_t ny,
                                 int64_t nz, as_voxel_type type, int big_endian,
                                 const double spacing[3], const double origin[3],
                                 int64_t header_offset, as_image **out);

#endif /* ANISTAR_IMAGE_IO_H */
