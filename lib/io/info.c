/*
 * info.c — what a triangle mesh or a 3D image holds (see info.h).
 */
#include "io/info.h"

#include "geom/selfx.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NONE UINT32_MAX



static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* The topology of component c (comp[v] == c for its vertices) as its own mesh. local:
 * nv entries of -1 on entry and on return; sx, st: room for the component's vertices and
 * triangles. */
static anistar_status component_topology(anistar_context *ctx, const as_trimesh *m,
                                         const uint32_t *comp, uint32_t c, int32_t *local,
                                         double *sx, int32_t *st, as_topology *rep) {
    size_t n = 0, k = 0;
    for (size_t t = 0; t < m->nt; t++) {
        const int32_t *tr = m->tri + 3 * t;
        if (as_tri_repeated(tr) || comp[tr[0]] != c) continue;
        for (int i = 0; i < 3; i++) {
            int32_t v = tr[i];
            if (local[v] < 0) {
                local[v] = (int32_t)n;
                memcpy(sx + 3 * n, m->xyz + 3 * (size_t)v, 3 * sizeof(double));
                n++;
            }
            st[3 * k + (size_t)i] = local[v];
        }
        k++;
    }
    anistar_status s = as_topology_check(ctx, n, sx, k, st, rep);
    for (size_t t = 0; t < m->nt; t++) {
        const int32_t *tr = m->tri + 3 * t;
        if (!as_tri_repeated(tr) && comp[tr[0]] == c)
            for (int i = 0; i < 3; i++) local[tr[i]] = -1;
    }
    return s;
}

anistar_status as_trimesh_info(anistar_context *ctx, const as_trimesh *m, anistar_mesh_info *info) {
    memset(info, 0, sizeof *info);
    for (size_t i = 0; i < 3 * m->nv; i++) {
        double a = fabs(m->xyz[i]);
        if (!isfinite(a) || (a != 0 && (a < 1e-40 || a > 1e40)))
            return as_fail(ctx, ANISTAR_EINVAL,
                           "vertex %zu: coordinate %.17g is outside the range of the exact "
                           "tests (0 or a magnitude in [1e-40, 1e40])",
                           i / 3, m->xyz[i]);
    }
    as_topology rep;
    anistar_status s = as_topology_check(ctx, m->nv, m->xyz, m->nt, m->tri, &rep);
    if (s != ANISTAR_OK) return s;
    info->vertices = m->nv;
    info->used_vertices = rep.used_vertices;
    info->triangles = m->nt;
    info->edges = rep.edges;
    info->components = rep.components;
    info->border_edges = rep.border_edges;
    info->nonmanifold_edges = rep.nonmanifold_edges;
    info->nonmanifold_vertices = rep.nonmanifold_vertices;
    info->degenerate_triangles = rep.repeated_index + rep.zero_area;
    info->nonorientable_components = rep.nonorientable;
    info->closed_manifold = rep.closed_manifold;
    info->euler_characteristic = rep.euler;

    size_t nv = m->nv, nt = m->nt;
    uint32_t *parent = as_alloc_array(ctx, nv, sizeof(uint32_t));
    uint32_t *comp = as_alloc_array(ctx, nv, sizeof(uint32_t));
    int32_t *local = as_alloc_array(ctx, nv, sizeof(int32_t));
    double *sx = as_alloc_array(ctx, 3 * nv, sizeof(double));
    int32_t *st = as_alloc_array(ctx, 3 * nt, sizeof(int32_t));
    uint64_t *keys = as_alloc_array(ctx, 3 * nt, sizeof(uint64_t));
    if (!parent || !comp || !local || !sx || !st || !keys) {
        s = as_fail(ctx, ANISTAR_ENOMEM, "info: out of memory for %zu triangles", nt);
        goto done;
    }

    /* (2) components in the order of their first triangle */
    for (size_t v = 0; v < nv; v++) {
        parent[v] = (uint32_t)v;
        comp[v] = NONE;
        local[v] = -1;
    }
    for (size_t t = 0; t < nt; t++) {
        const int32_t *tr = m->tri + 3 * t;
        if (as_tri_repeated(tr)) continue;
        as_uf_union(parent, (uint32_t)tr[0], (uint32_t)tr[1]);
        as_uf_union(parent, (uint32_t)tr[0], (uint32_t)tr[2]);
    }
    uint32_t ncomp = 0;
    for (size_t t = 0; t < nt; t++) {
        const int32_t *tr = m->tri + 3 * t;
        if (as_tri_repeated(tr)) continue;
        uint32_t r = as_uf_find(parent, (uint32_t)tr[0]);
        if (comp[r] == NONE) comp[r] = ncomp++;
    }
    for (size_t v = 0; v < nv; v++) comp[v] = comp[as_uf_find(parent, (uint32_t)v)];
    for (uint32_t c = 0; c < ncomp && c < ANISTAR_INFO_COMPONENTS; c++) {
        as_topology cr;
        s = component_topology(ctx, m, comp, c, local, sx, st, &cr);
        if (s != ANISTAR_OK) goto done;
        anistar_component_info *ci = &info->component[c];
        ci->vertices = cr.used_vertices;
        ci->edges = cr.edges;
        ci->triangles = cr.triangles;
        ci->euler_characteristic = cr.euler;
        ci->closed = cr.closed_manifold;
        ci->orientable = cr.nonorientable == 0;
        ci->genus = cr.genus;
        info->components_listed = c + 1;
    }

    /* bounding box of the used vertices; (3) distinct edges and their lengths */
    for (int k = 0; k < 3; k++) {
        info->bbox_min[k] = INFINITY;
        info->bbox_max[k] = -INFINITY;
    }
    size_t nk = 0;
    for (size_t t = 0; t < nt; t++) {
        const int32_t *tr = m->tri + 3 * t;
        for (int i = 0; i < 3; i++) {
            const double *p = m->xyz + 3 * (size_t)tr[i];
            for (int k = 0; k < 3; k++) {
                info->bbox_min[k] = fmin(info->bbox_min[k], p[k]);
                info->bbox_max[k] = fmax(info->bbox_max[k], p[k]);
            }
            uint32_t a = (uint32_t)tr[i], b = (uint32_t)tr[(i + 1) % 3];
            if (a == b) continue;
            keys[nk++] = a < b ? (uint64_t)a << 32 | b : (uint64_t)b << 32 | a;
        }
    }
    qsort(keys, nk, sizeof *keys, cmp_u64);
    double sum = 0;
    size_t ne = 0;
    info->edge_min = INFINITY;
    info->edge_max = 0;
    for (size_t i = 0; i < nk; i++) {
        if (i > 0 && keys[i] == keys[i - 1]) continue;
        const double *p = m->xyz + 3 * (size_t)(keys[i] >> 32);
        const double *q = m->xyz + 3 * (size_t)(keys[i] & 0xffffffffu);
        double dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
        double len = sqrt(dx * dx + dy * dy + dz * dz);
        info->edge_min = fmin(info->edge_min, len);
        info->edge_max = fmax(info->edge_max, len);
        sum += len;
        ne++;
    }
    if (ne == 0) info->edge_min = 0;
    info->edge_mean = ne ? sum / (double)ne : 0;

    /* (4) self-intersections */
    int32_t pairs[2 * ANISTAR_INFO_PAIRS];
    s = as_self_intersections(ctx, m->xyz, nv, m->tri, nt, ANISTAR_INFO_MAX_INTERSECTIONS, pairs,
                              ANISTAR_INFO_PAIRS, &info->self_intersections,
                              &info->self_intersections_capped);
    if (s != ANISTAR_OK) goto done;
    info->pairs_listed = info->self_intersections < ANISTAR_INFO_PAIRS ? info->self_intersections
                                                                       : ANISTAR_INFO_PAIRS;
    for (size_t i = 0; i < info->pairs_listed; i++) {
        info->pairs[i][0] = pairs[2 * i];
        info->pairs[i][1] = pairs[2 * i + 1];
    }
done:
    as_free(ctx, parent, nv * sizeof(uint32_t));
    as_free(ctx, comp, nv * sizeof(uint32_t));
    as_free(ctx, local, nv * sizeof(int32_t));
    as_free(ctx, sx, 3 * nv * sizeof(double));
    as_free(ctx, st, 3 * nt * sizeof(int32_t));
    as_free(ctx, keys, 3 * nt * sizeof(uint64_t));
    return s;
}

anistar_status as_voxel_components(anistar_context *ctx, const unsigned char *in, size_t nx,
                                   size_t ny, size_t nz, size_t *count) {
    *count = 0;
    size_t n = nx * ny * nz, plane = nx * ny;
    if (n == 0) return ANISTAR_OK;
    if (n >= NONE)
        return as_fail(ctx, ANISTAR_EINVAL,
                       "info: %zu voxels: too many to label (at most %u)", n, NONE - 1);
    uint32_t *p = as_alloc_array(ctx, n, sizeof(uint32_t));
    if (!p) return as_fail(ctx, ANISTAR_ENOMEM, "info: out of memory labelling %zu voxels", n);
    size_t idx = 0;
    for (size_t k = 0; k < nz; k++)
        for (size_t j = 0; j < ny; j++)
            for (size_t i = 0; i < nx; i++, idx++) {
                if (!in[idx]) continue;
                p[idx] = (uint32_t)idx;
                if (i > 0 && in[idx - 1]) as_uf_union(p, (uint32_t)idx, (uint32_t)(idx - 1));
                if (j > 0 && in[idx - nx]) as_uf_union(p, (uint32_t)idx, (uint32_t)(idx - nx));
                if (k > 0 && in[idx - plane]) as_uf_union(p, (uint32_t)idx, (uint32_t)(idx - plane));
            }
    for (idx = 0; idx < n; idx++)
        if (in[idx] && p[idx] == idx) ++*count;
    as_free(ctx, p, n * sizeof(uint32_t));
    return ANISTAR_OK;
}

anistar_status as_image_info(anistar_context *ctx, const as_image *img, double iso, int inside,
                             anistar_image_info *info) {
    memset(info, 0, sizeof *info);
    if (isinf(iso)) return as_fail(ctx, ANISTAR_EINVAL, "info: the isovalue must be finite");
    if (inside != ANISTAR_INSIDE_GREATER && inside != ANISTAR_INSIDE_LESS)
        return as_fail(ctx, ANISTAR_EINVAL, "info: inside must be +1 (greater) or -1 (less), "
                       "got %d", inside);
    const as_grid *g = &img->grid;
    for (int k = 0; k < 3; k++) {
        info->dims[k] = g->n[k];
        info->spacing[k] = g->spacing[k];
        info->origin[k] = g->origin[k];
    }
    memcpy(info->direction, g->dir, sizeof info->direction);
    info->voxel_type = as_voxel_type_name(img->type);
    as_grid_world_box(g, 0, info->bbox_min, info->bbox_max);
    as_image_range(img, &info->value_min, &info->value_max);
    info->nonfinite = as_image_count_nonfinite(img, NULL);
    if (as_image_otsu(img, &info->otsu)) info->otsu = NAN;
    info->iso_given = !isnan(iso);
    info->iso = info->iso_given ? iso : info->otsu;
    info->inside = inside;
    if (isnan(info->iso)) return ANISTAR_OK;
    size_t n = img->count;
    unsigned char *in = as_alloc(ctx, n);
    double *row = as_alloc_array(ctx, img->nx, sizeof(double));
    if (!in || !row) {
        as_free(ctx, in, n);
        as_free(ctx, row, img->nx * sizeof(double));
        return as_fail(ctx, ANISTAR_ENOMEM, "info: out of memory for %zu voxels", n);
    }
    for (size_t first = 0; first < n; first += img->nx) {
        as_image_to_double(img, first, img->nx, row);
        for (size_t i = 0; i < img->nx; i++) {
            double v = row[i];
            unsigned char b = inside > 0 ? v > info->iso : v < info->iso; /* NaN: 0 */
            in[first + i] = b;
            info->voxels_inside += b;
        }
    }
    as_free(ctx, row, img->nx * sizeof(double));
    anistar_status s = as_voxel_components(ctx, in, img->nx, img->ny, img->nz, &info->components);
    as_free(ctx, in, n);
    return s;
}
