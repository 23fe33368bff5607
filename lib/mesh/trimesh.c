/*
 * trimesh.c — the in-memory triangle mesh (see trimesh.h).
 */
#include "mesh/trimesh.h"

#include <math.h>
#include <string.h>

/* ==================================================================================== */
/* as_trimesh                                                                            */
/* ==================================================================================== */

void as_trimesh_init(as_trimesh *m) { memset(m, 0, sizeof *m); }

void as_trimesh_free(anistar_context *ctx, as_trimesh *m) {
    as_free(ctx, m->xyz, m->cap_v * 3 * sizeof(double));
    as_free(ctx, m->tri, m->cap_t * 3 * sizeof(int32_t));
    as_free(ctx, m->tensor, m->cap_m * 6 * sizeof(double));
    as_trimesh_init(m);
}

/* Grow one array of `per` elements of `elem` bytes per item to hold `need` items. */
static int grow_items(anistar_context *ctx, void **p, size_t *cap, size_t need, size_t per,
                      size_t elem) {
    if (need <= *cap) return 0;
    size_t ncap = *cap ? *cap : 16;
    while (ncap < need) ncap = ncap > SIZE_MAX / 2 ? need : ncap * 2;
    size_t old_bytes = *cap * per * elem, new_bytes;
    if (as_mul_size(ncap, per * elem, &new_bytes)) return -1;
    void *q = as_realloc(ctx, *p, old_bytes, new_bytes);
    if (!q) return -1;
    *p = q;
    *cap = ncap;
    return 0;
}

/* Grow to exactly `need` items when more room is needed (for reserve: no slack). */
static int reserve_items(anistar_context *ctx, void **p, size_t *cap, size_t need, size_t per,
                         size_t elem) {
    if (need <= *cap) return 0;
    size_t new_bytes;
    if (as_mul_size(need, per * elem, &new_bytes)) return -1;
    void *q = as_realloc(ctx, *p, *cap * per * elem, new_bytes);
    if (!q) return -1;
    *p = q;
    *cap = need;
    return 0;
}

anistar_status as_trimesh_reserve(anistar_context *ctx, as_trimesh *m, size_t nv, size_t nt) {
    if (nv > AS_TRIMESH_MAX_VERTICES)
        return as_fail(ctx, ANISTAR_EINVAL, "too many vertices (%zu > %zu)", nv,
                       AS_TRIMESH_MAX_VERTICES);
    if (reserve_items(ctx, (void **)&m->xyz, &m->cap_v, nv, 3, sizeof(double)) ||
        reserve_items(ctx, (void **)&m->tri, &m->cap_t, nt, 3, sizeof(int32_t)))
        return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for a mesh of %zu vertices and "
                       "%zu triangles", nv, nt);
    if (m->tensor && reserve_items(ctx, (void **)&m->tensor, &m->cap_m, nv, 6, sizeof(double)))
        return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for %zu tensors", nv);
    return ANISTAR_OK;
}

anistar_status as_trimesh_add_vertex(anistar_context *ctx, as_trimesh *m, double x, double y,
                                     double z) {
    if (m->nv >= AS_TRIMESH_MAX_VERTICES)
        return as_fail(ctx, ANISTAR_EINVAL, "too many vertices (more than %zu)",
                       AS_TRIMESH_MAX_VERTICES);
    if (m->nv == m->cap_v) {
        if (grow_items(ctx, (void **)&m->xyz, &m->cap_v, m->nv + 1, 3, sizeof(double)))
            return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for %zu vertices", m->nv + 1);
    }
    if (m->tensor && m->nv == m->cap_m) {
        if (grow_items(ctx, (void **)&m->tensor, &m->cap_m, m->nv + 1, 6, sizeof(double)))
            return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for %zu tensors", m->nv + 1);
        memset(m->tensor + 6 * m->nv, 0, (m->cap_m - m->nv) * 6 * sizeof(double));
    }
    double *p = m->xyz + 3 * m->nv++;
    p[0] = x;
    p[1] = y;
    p[2] = z;
    return ANISTAR_OK;
}

anistar_status as_trimesh_add_triangle(anistar_context *ctx, as_trimesh *m, int32_t a,
                                       int32_t b, int32_t c) {
    if (m->nt == m->cap_t &&
        grow_items(ctx, (void **)&m->tri, &m->cap_t, m->nt + 1, 3, sizeof(int32_t)))
        return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for %zu triangles", m->nt + 1);
    int32_t *t = m->tri + 3 * m->nt++;
    t[0] = a;
    t[1] = b;
    t[2] = c;
    return ANISTAR_OK;
}

anistar_status as_trimesh_alloc_tensors(anistar_context *ctx, as_trimesh *m) {
    if (m->tensor) return ANISTAR_OK;
    size_t n = m->cap_v > m->nv ? m->cap_v : m->nv;
    if (n == 0) return ANISTAR_OK;
    double *t = as_alloc_array(ctx, n, 6 * sizeof(double));
    if (!t) return as_fail(ctx, ANISTAR_ENOMEM, "out of memory for %zu tensors", n);
    memset(t, 0, n * 6 * sizeof(double));
    m->tensor = t;
    m->cap_m = n;
    return ANISTAR_OK;
}

anistar_status as_trimesh_set(anistar_context *ctx, as_trimesh *m, size_t nv,
                              const double *xyz, size_t nt, const int32_t *tri,
                              const double *tensor) {
    if (nv > AS_TRIMESH_MAX_VERTICES)
        return as_fail(ctx, ANISTAR_EINVAL, "too many vertices (%zu > %zu)", nv,
                       AS_TRIMESH_MAX_VERTICES);
    for (size_t i = 0; i < 3 * nt; i++)
        if (tri[i] < 0 || (size_t)tri[i] >= nv)
            return as_fail(ctx, ANISTAR_EINVAL, "triangle %zu: vertex index %ld out of range "
                           "[0, %zu)", i / 3, (long)tri[i], nv);
    as_trimesh_free(ctx, m);
    anistar_status st = as_trimesh_reserve(ctx, m, nv, nt);
    if (!st && tensor) st = as_trimesh_alloc_tensors(ctx, m);
    if (st) {
        as_trimesh_free(ctx, m);
        return st;
    }
    if (nv) memcpy(m->xyz, xyz, nv * 3 * sizeof(double));
    if (nt) memcpy(m->tri, tri, nt * 3 * sizeof(int32_t));
    if (tensor && nv) memcpy(m->tensor, tensor, nv * 6 * sizeof(double));
    m->nv = nv;
    m->nt = nt;
    return ANISTAR_OK;
}

anistar_status as_trimesh_check(anistar_context *ctx, const char *path, const as_trimesh *m) {
    if (m->nv > AS_TRIMESH_MAX_VERTICES)
        return as_fail(ctx, ANISTAR_EINVAL, "%s: too many vertices (%zu)", path, m->nv);
    if ((m->nv && !m->xyz) || (m->nt && !m->tri))
        return as_fail(ctx, ANISTAR_EINVAL, "%s: mesh arrays missing", path);
    for (size_t i = 0; i < 3 * m->nt; i++)
        if (m->tri[i] < 0 || (size_t)m->tri[i] >= m->nv)
            return as_fail(ctx, ANISTAR_EINVAL, "%s: triangle %zu: vertex index %ld out of "
                           "range [0, %zu)", path, i / 3, (long)m->tri[i], m->nv);
    for (size_t i = 0; i < 3 * m->nv; i++)
        if (!isfinite(m->xyz[i]))
            return as_fail(ctx, ANISTAR_EINVAL, "%s: vertex %zu has a non-finite coordinate",
                           path, i / 3);
    if (m->tensor)
        for (size_t i = 0; i < 6 * m->nv; i++)
            if (!isfinite(m->tensor[i]))
                return as_fail(ctx, ANISTAR_EINVAL, "%s: vertex %zu has a non-finite tensor",
                               path, i / 6);
    return ANISTAR_OK;
}

