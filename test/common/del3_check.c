/* del3_check.c — see del3_check.h. */
#include "del3_check.h"

#include "test_util.h"

#include <stdlib.h>

static int cmp_i64(const void *a, const void *b) {
    int64_t x = *(const int64_t *)a, y = *(const int64_t *)b;
    return (x > y) - (x < y);
}

static int cmp_quad(const void *a, const void *b) {
    const int64_t *x = a, *y = b;
    for (int i = 0; i < 4; i++)
        if (x[i] != y[i]) return x[i] < y[i] ? -1 : 1;
    return 0;
}

void tu_sort4(int64_t q[4]) {
    for (int i = 1; i < 4; i++)
        for (int j = i; j > 0 && q[j - 1] > q[j]; j--) {
            int64_t t = q[j];
            q[j] = q[j - 1];
            q[j - 1] = t;
        }
}

int64_t *tu_del3_canon(const as_del3 *d, size_t *count) {
    int64_t *q = malloc(4 * (size_t)(d->nlive + 1) * sizeof *q);
    assert_non_null(q);
    size_t n = 0;
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t)) continue;
        for (int i = 0; i < 4; i++) {
            int32_t v = as_del3_tet_vertex(d, t, i);
            q[4 * n + i] = v < 0 ? -1 : d->gid[v];
        }
        tu_sort4(q + 4 * n);
        n++;
    }
    qsort(q, n, 4 * sizeof *q, cmp_quad);
    *count = n;
    return q;
}

void tu_del3_assert_same(const as_del3 *a, const as_del3 *b) {
    size_t na, nb;
    int64_t *qa = tu_del3_canon(a, &na), *qb = tu_del3_canon(b, &nb);
    assert_int_equal(na, nb);
    assert_memory_equal(qa, qb, 4 * na * sizeof *qa);
    free(qa);
    free(qb);
}

int64_t tu_count_unique(int64_t *keys, size_t n) {
    if (n == 0) return 0;
    qsort(keys, n, sizeof *keys, cmp_i64);
    int64_t u = 1;
    for (size_t i = 1; i < n; i++) u += keys[i] != keys[i - 1];
    return u;
}

void tu_del3_assert_euler(const as_del3 *d) {
    int32_t nf, ni;
    as_del3_count(d, &nf, &ni);
    size_t ne = 0, nfc = 0;
    int64_t *edges = malloc(6 * (size_t)(nf + 1) * sizeof *edges);
    int64_t *faces = malloc(4 * (size_t)(nf + 1) * sizeof *faces);
    assert_non_null(edges);
    assert_non_null(faces);
    const int64_t B = (int64_t)d->nv + 1;
    for (int32_t t = 0; t < d->nt; t++) {
        if (!as_del3_is_live(d, t) || as_del3_is_infinite(d, t)) continue;
        int64_t v[4];
        for (int i = 0; i < 4; i++) v[i] = as_del3_tet_vertex(d, t, i);
        tu_sort4(v);
        for (int i = 0; i < 4; i++)
            for (int j = i + 1; j < 4; j++) edges[ne++] = v[i] * B + v[j];
        for (int i = 0; i < 4; i++) {
            int64_t f[3];
            int k = 0;
            for (int j = 0; j < 4; j++)
                if (j != i) f[k++] = v[j];
            faces[nfc++] = (f[0] * B + f[1]) * B + f[2];
        }
    }
    int64_t E = tu_count_unique(edges, ne), F = tu_count_unique(faces, nfc);
    int64_t V = d->nv, T = nf;
    assert_int_equal(V - E + F - T, 1);
    free(edges);
    free(faces);
}
