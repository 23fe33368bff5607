/*
 * info.h — internal: what a triangle mesh or a 3D image holds (include/anistar.h "What a
 * file holds"; `anistar info`). On data already read: the readers are meshio.h and
 * image_io.h, the topology is as_topology_check's, the self-intersections as
 * as_self_intersections's (geom/selfx.h).
 */
#ifndef ANISTAR_INFO_H
#define ANISTAR_INFO_H

#include "core.h"
#include "io/image_io.h"
#include "io/meshio.h"

/*
 * as_trimesh_info — fill *info for the mesh m (as a reader returns it: indices in range,
 * finite coordinates). EINVAL for a coordinate whose nonzero magnitude is outside
 * [1e-40, 1e40] (the range of the exact predicates), ENOMEM.
 * design: (1) as_topology_check on the whole mesh (counts, borders, fans, chi);
 *   (2) components: union-find of vertices over the triangles without a repeated index,
 *   numbered in the order of their first triangle; each of the first
 *   ANISTAR_INFO_COMPONENTS is copied out with local vertex numbers and given its own
 *   as_topology_check (chi, closed, orientable, genus); (3) distinct edges: the sorted
 *   (lo, hi) keys of all corners, deduplicated, for the length range; (4)
 *   as_self_intersections with the cap ANISTAR_INFO_MAX_INTERSECTIONS.
 */
anistar_status as_trimesh_info(anistar_context *ctx, const as_trimesh *m, anistar_mesh_info *info);

/*
 * as_image_info — fill *info for img and the voxels inside iso (NaN: Otsu's threshold;
 * inside ANISTAR_INSIDE_GREATER: value > iso, ANISTAR_INSIDE_LESS: value < iso; NaN voxels
 * are never inside). EINVAL (iso infinite, inside not +-1, more than 2^32 - 2 voxels to
 * label), ENOMEM.
 * design: union-find over the voxel indices in raster order, each inside voxel joined to
 *   its inside neighbours at -x, -y and -z (6-connectivity: voxels sharing a face); one
 *   component per root. 4 bytes per voxel.
 */
anistar_status as_image_info(anistar_context *ctx, const as_image *img, double iso, int inside,
                             anistar_image_info *info);

/* The number of 6-connected components of the voxels of in[nx*ny*nz] that are nonzero (x
 * fastest), into *count. EINVAL (more than 2^32 - 2 voxels), ENOMEM. */
anistar_status as_voxel_components(anistar_context *ctx, const unsigned char *in, size_t nx,
                                   size_t ny, size_t nz, size_t *count);

#endif /* ANISTAR_INFO_H */
