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

/* The curve as a 24-state machine: in state s, the cell's octant o = (x bit, y bit, z bit)
 * of the current level gives the level's index digit hilbert_tab[s][o] & 7 and the next
 * state hilbert_tab[s][o] >> 3. The states are the 24 rotations of the cube the sub-curves
 * use; the table was derived from Skilling's transpose form (J. Skilling, "Programming
 * the Hilbert curve", 2004: undo the excess rotations level by level, Gray-encode,
 * interleave) by finding, for each octant, the signed axis permutation that maps the
 * octant's sub-curve onto the whole curve, and composing them from the identity; the two
 * agree on every input (test_del3 compares them). */
static const uint8_t hilbert_tab[24][8] = {
    {8, 17, 27, 2, 39, 46, 52, 5}, {56, 71, 73, 86, 91, 20, 10, 13},
    {48, 1, 103, 110, 115, 18, 12, 21}, {126, 129, 29, 26, 79, 80, 140, 3},
    {148, 43, 37, 34, 127, 128, 78, 81}, {156, 45, 35, 42, 31, 6, 160, 105},
    {72, 87, 139, 4, 57, 70, 50, 53}, {0, 171, 111, 76, 49, 58, 102, 61},
    {180, 143, 83, 184, 69, 54, 66, 97}, {16, 123, 9, 74, 47, 60, 38, 77},
    {132, 95, 85, 14, 67, 144, 82, 33}, {142, 55, 185, 96, 93, 116, 90, 11},
    {188, 107, 175, 176, 101, 98, 62, 65}, {164, 109, 119, 22, 99, 106, 152, 41},
    {174, 177, 63, 64, 117, 114, 92, 19}, {30, 125, 161, 122, 7, 172, 104, 75},
    {130, 25, 133, 166, 179, 136, 84, 191}, {94, 15, 141, 28, 145, 32, 138, 51},
    {146, 155, 149, 36, 137, 24, 190, 167}, {154, 157, 147, 44, 169, 182, 120, 135},
    {162, 165, 121, 134, 187, 108, 168, 183}, {118, 173, 23, 124, 153, 170, 40, 59},
    {178, 113, 131, 88, 181, 158, 68, 151}, {186, 163, 89, 112, 189, 100, 150, 159},
};

/* design: interleave the coordinates' bits (a Morton code), then run the state machine
 * from the coarsest level: one table load per level, no data-dependent branch (the bit
 * tests of a level loop are coin flips for the branch predictor). */
uint64_t as_hilbert3_index(uint32_t x, uint32_t y, uint32_t z, int bits) {
    uint32_t keep = bits >= 32 ? ~0u : ((uint32_t)1 << bits) - 1;
    uint64_t m = spread3(x & keep) << 2 | spread3(y & keep) << 1 | spread3(z & keep);
    uint64_t h = 0;
    unsigned s = 0;
    for (int l = 3 * (bits - 1); l >= 0; l -= 3) {
        unsigned e = hilbert_tab[s][(m >> l) & 7u];
        h = h << 3 | (e & 7u);
        s = e >> 3;
    }
    return h;
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
