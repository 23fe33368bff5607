/*
 * sort.c — spatial sorts for incremental insertion: Hilbert order and BRIO (sort.h).
 */
#include "geom/sort.h"

#include <math.h>
#include <string.h>

/* The 21 low bits of x spread to every third bit (bit k -> bit 3k). */
static inline uint64_t spread3(uint32_t x) {
    uint64_t v = x & 0x1fffffu;
    v = (v | v << 32) & 0x1f00000000ffffULL;
    v = (v | v << 16) & 0x1f0000ff0000ffULL;
    v = (v | v << 8) & 0x100f00f00f00f00fULL;
    v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
    v = (v | v << 2) & 0x1249249249249249ULL;
    return v;
}

/* design: no data-dependent branch (the bit tests of the level loop are coin flips for the
 * branch predictor: they cost more than the arithmetic), masks instead; the interleave by
 * bit spreading. Same result as the textbook loops. */
uint64_t as_hilbert3_index(uint32_t x, uint32_t y, uint32_t z, int bits) {
    uint32_t c0 = x, c1 = y, c2 = z;
    uint32_t top = (uint32_t)1 << (bits - 1);
    /* From the coarsest level down: where the bit of axis i is set, flip the lower bits of
     * axis 0; otherwise swap the lower bits of axes 0 and i. This undoes the reflections
     * and rotations the curve applies in the sub-cubes. */
    for (uint32_t q = top; q > 1; q >>= 1) {
        uint32_t low = q - 1, m, t;
        m = 0u - ((c0 & q) != 0); /* axis 0: flip if set (a swap with itself is nothing) */
        c0 ^= low & m;
        m = 0u - ((c1 & q) != 0);
        t = (c0 ^ c1) & low & ~m;
        c0 ^= (low & m) | t;
        c1 ^= t;
        m = 0u - ((c2 & q) != 0);
        t = (c0 ^ c2) & low & ~m;
        c0 ^= (low & m) | t;
        c2 ^= t;
    }
    /* Gray code across the axes. */
    c1 ^= c0;
    c2 ^= c1;
    uint32_t g = 0;
    for (uint32_t q = top; q > 1; q >>= 1) g ^= (q - 1) & (0u - ((c2 & q) != 0));
    c0 ^= g;
    c1 ^= g;
    c2 ^= g;
    /* Interleave: level by level, axis 0 first (bit l of axis i -> bit 3l + 2 - i). */
    uint32_t keep = bits >= 32 ? ~0u : ((uint32_t)1 << bits) - 1;
    return spread3(c0 & keep) << 2 | spread3(c1 & keep) << 1 | spread3(c2 & keep);
}

static uint64_t mix64(uint64_t z) {
    z += 0x9e3779b97f4a7c15ULL;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}

enum { HBITS = 21 };

/* LSD radix sort of (key, idx) pairs by key, 8-bit digits, skipping the digits on which all
 * keys agree. k/ix hold the input and receive the output; k2/ix2 are scratch. Stable. */
static void radix_sort(uint64_t *k, int32_t *ix, uint64_t *k2, int32_t *ix2, size_t n) {
    uint64_t all_or = 0, all_and = ~(uint64_t)0;
    for (size_t i = 0; i < n; i++) {
        all_or |= k[i];
        all_and &= k[i];
    }
    uint64_t varying = all_or ^ all_and;
    uint64_t *src = k, *dst = k2;
    int32_t *isrc = ix, *idst = ix2;
    for (int shift = 0; shift < 64; shift += 8) {
        if (((varying >> shift) & 0xffu) == 0) continue;
        size_t count[257];
        memset(count, 0, sizeof count);
        for (size_t i = 0; i < n; i++) count[((src[i] >> shift) & 0xffu) + 1]++;
        for (int b = 0; b < 256; b++) count[b + 1] += count[b];
        for (size_t i = 0; i < n; i++) {
            size_t pos = count[(src[i] >> shift) & 0xffu]++;
            dst[pos] = src[i];
            idst[pos] = isrc[i];
        }
        uint64_t *tk = src;
        src = dst;
        dst = tk;
        int32_t *ti = isrc;
        isrc = idst;
        idst = ti;
    }
    if (src != k) {
        memcpy(k, src, n * sizeof *k);
        memcpy(ix, isrc, n * sizeof *ix);
    }
}

/*
 * Shared by both sorts: brio == 0 sorts along the curve only.
 * design: Hilbert index of each point on a 2^21 grid over the bounding cube; BRIO round of
 * each point from a hash (level 0, the last round, with probability 7/8, level 1 with
 * 7/64, ...: rounds grow by 8, as CGAL's multiscale sort; the first round holds about 64
 * points); counting sort by round, then a radix sort of the Hilbert keys inside each round
 * (stable: ties keep the input order). Ratio 1/8 rather than 1/2: most points go in one
 * coherent sweep, so the walks are shorter (a torus sample: 24 steps per point instead of
 * 40) and the tets they touch are still in cache.
 */
static anistar_status spatial_sort(anistar_context *ctx, const double *pts, int32_t n,
                                   int brio, uint64_t seed, int32_t *order) {
    if (n < 0) return as_fail(ctx, ANISTAR_EINVAL, "spatial sort: negative count %d", (int)n);
    if (n == 0) return ANISTAR_OK;
    double lo[3], hi[3];
    for (int a = 0; a < 3; a++) lo[a] = hi[a] = pts[a];
    for (int32_t i = 0; i < n; i++) {
        for (int a = 0; a < 3; a++) {
            double x = pts[3 * (size_t)i + (size_t)a];
            if (!isfinite(x))
                return as_fail(ctx, ANISTAR_EINVAL,
                               "spatial sort: point %d has a non-finite coordinate", (int)i);
            if (x < lo[a]) lo[a] = x;
            if (x > hi[a]) hi[a] = x;
        }
    }
    double side = 0;
    for (int a = 0; a < 3; a++)
        if (hi[a] - lo[a] > side) side = hi[a] - lo[a];
    const double cells = (double)((1u << HBITS) - 1);
    double scale = side > 0 ? cells / side : 0;
    if (!isfinite(scale)) scale = 0; /* a subnormal extent: every point in one cell */

    size_t nn = (size_t)n;
    uint64_t *keys = as_alloc_array(ctx, 3 * nn, sizeof *keys); /* keys, scratch, round keys */
    int32_t *tmp = as_alloc_array(ctx, nn, sizeof *tmp);
    if (!keys || !tmp) {
        as_free(ctx, keys, 3 * nn * sizeof *keys);
        as_free(ctx, tmp, nn * sizeof *tmp);
        return as_fail(ctx, ANISTAR_ENOMEM, "spatial sort: out of memory for %d points",
                       (int)n);
    }
    int maxlevel = 0;
    if (brio)
        while (maxlevel < 10 && ((int64_t)64 << (3 * (maxlevel + 1))) <= (int64_t)n) maxlevel++;
    size_t start[33];
    memset(start, 0, sizeof start);
    uint64_t *hk = keys + 2 * nn;
    for (size_t i = 0; i < nn; i++) {
        uint32_t c[3];
        for (int a = 0; a < 3; a++) {
            double u = (pts[3 * i + (size_t)a] - lo[a]) * scale;
            if (!(u >= 0)) u = 0;
            if (u > cells) u = cells;
            c[a] = (uint32_t)u;
        }
        int round = 0;
        if (brio) {
            uint64_t h = mix64(seed ^ mix64((uint64_t)i));
            int level = 0;
            while (level < maxlevel && (h & 7u) == 0) {
                level++;
                h >>= 3;
            }
            round = maxlevel - level;
        }
        hk[i] = as_hilbert3_index(c[0], c[1], c[2], HBITS);
        tmp[i] = round;
        start[round + 1]++;
    }
    for (int r = 0; r <= maxlevel; r++) start[r + 1] += start[r];
    size_t pos[32];
    memcpy(pos, start, sizeof pos);
    for (size_t i = 0; i < nn; i++) {
        size_t q = pos[tmp[i]]++;
        order[q] = (int32_t)i;
        keys[q] = hk[i];
    }
    for (int r = 0; r <= maxlevel; r++)
        radix_sort(keys + start[r], order + start[r], keys + nn + start[r], tmp + start[r],
                   start[r + 1] - start[r]);
    as_free(ctx, keys, 3 * nn * sizeof *keys);
    as_free(ctx, tmp, nn * sizeof *tmp);
    return ANISTAR_OK;
}

anistar_status as_sort_hilbert(anistar_context *ctx, const double *pts, int32_t n,
                               int32_t *order) {
    return spatial_sort(ctx, pts, n, 0, 0, order);
}

anistar_status as_sort_brio(anistar_context *ctx, const double *pts, int32_t n, uint64_t seed,
                            int32_t *order) {
    return spatial_sort(ctx, pts, n, 1, seed, order);
}
