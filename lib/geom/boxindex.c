/*
 * boxindex.c — dynamic boxes in a hierarchical hash grid with contiguous cells (see
 * boxindex.h).
 */
#include "geom/boxindex.h"

#include <math.h>
#include <string.h>

#define AS_BX_NONE UINT32_MAX
/* A box at level L has extent below 2^(L + AS_BX_SPAN_LOG2): its lower corner lies within
 * AS_BX_SPAN = 2^AS_BX_SPAN_LOG2 cells of any point it contains. boxindex.h describes the
 * value 0 (8 probes per level); 1 (27 probes, half the candidates) measured no faster. */
#define AS_BX_SPAN_LOG2 0
#define AS_BX_SPAN (1 << AS_BX_SPAN_LOG2)
/* Stored coordinates are below 2^(L + AS_BX_CELL_BITS) at level L, so cell indices stay
 * below 2^50 in magnitude. */
#define AS_BX_CELL_BITS 50
/* Levels: from the coordinate rule at the smallest subnormal (ilogb -1074 + 1 - 50) up to
 * boxes of extent 2^1000 (coordinates are limited to AS_BX_MAX_COORD). */
#define AS_BX_LMIN (-1123)
#define AS_BX_LMAX 1001
#define AS_BX_NLEVELS (AS_BX_LMAX - AS_BX_LMIN + 1)
/* Coordinates beyond this magnitude are rejected (keeps extents and levels finite). */
#define AS_BX_MAX_COORD 1e300
/* Cell indices of query coordinates saturate here (beyond every stored cell). */
#define AS_BX_SAT ((int64_t)1 << 62)
#define AS_BX_EMPTY INT32_MIN /* free hash entry */
#define AS_BX_NOBOX INT32_MIN /* record of an id without a box */
/* Cell blocks hold 2^cls entries, cls in [AS_BX_MIN_CLASS, AS_BX_CLASSES). */
#define AS_BX_MIN_CLASS 2
#define AS_BX_CLASSES 31

/* A stored box (in its cell's block). */
typedef struct as_bx_ent {
    double lo[3], hi[3];
    int32_t id; /* in a free block's first entry: the next free block's offset, or -1 */
    int32_t pad;
} as_bx_ent;

/* A hash table entry: the cell (level, c) and its block of entries. */
typedef struct as_bx_cell {
    int64_t c[3];
    int32_t level; /* AS_BX_EMPTY: free table entry */
    uint32_t off;  /* first entry of the block in the pool */
    uint32_t count;
    uint32_t cls; /* the block holds 2^cls entries */
} as_bx_cell;

/* Per id: where its box is. */
typedef struct as_bx_rec {
    int64_t cell[3];
    int32_t level; /* AS_BX_NOBOX when the id has no box */
    uint32_t pos;  /* its entry in the pool */
} as_bx_rec;

struct as_boxindex {
    as_bx_rec *rec; /* indexed by id */
    size_t idcap, n;
    as_bx_ent *pool; /* cell blocks */
    size_t pool_n, pool_cap;
    int32_t free_block[AS_BX_CLASSES]; /* free blocks per class, linked through .id */
    as_bx_cell *tab;                   /* open addressing, power-of-two capacity, load <= 1/2 */
    size_t tcap, tn;
    int32_t lvl_count[AS_BX_NLEVELS]; /* boxes per level */
    int16_t active[AS_BX_NLEVELS];    /* levels holding boxes, ascending */
    size_t nactive;
};

/* ---- levels and cells -------------------------------------------------------------------- */

/* The level of a box: the smallest L with (largest computed extent) < 2^L — which implies
 * the exact extent is below 2^L too, as rounding is monotone and 2^L representable —
 * raised to keep the coordinates below 2^(L + AS_BX_CELL_BITS). */
static int as_bx_level(const double lo[3], const double hi[3]) {
    double e = 0, m = 0;
    for (int k = 0; k < 3; k++) {
        double d = hi[k] - lo[k], a = fabs(lo[k]), b = fabs(hi[k]);
        if (d > e) e = d;
        if (a > m) m = a;
        if (b > m) m = b;
    }
    int L = AS_BX_LMIN;
    if (e > 0 && ilogb(e) + 1 - AS_BX_SPAN_LOG2 > L) L = ilogb(e) + 1 - AS_BX_SPAN_LOG2;
    if (m > 0 && ilogb(m) + 1 - AS_BX_CELL_BITS > L) L = ilogb(m) + 1 - AS_BX_CELL_BITS;
    return L;
}

/* floor(x / 2^L), exactly, saturated at +-AS_BX_SAT. Scaling by a power of two is exact
 * whenever the result is at least 1 in magnitude (no underflow) and not saturated;
 * below 1 in magnitude the floor is 0 or -1 by the sign of x. */
static inline int64_t as_bx_cell_of(double x, int L) {
    double s = ldexp(x, -L);
    if (s >= (double)AS_BX_SAT) return AS_BX_SAT;
    if (s <= -(double)AS_BX_SAT) return -AS_BX_SAT;
    if (s >= 1 || s <= -1) return (int64_t)floor(s);
    return x < 0 ? -1 : 0;
}

static inline uint64_t as_bx_hash(const int64_t c[3], int32_t L) {
    uint64_t h = (uint64_t)c[0] * 0x9E3779B97F4A7C15ULL;
    h = (h ^ (h >> 31)) + (uint64_t)c[1] * 0xC2B2AE3D27D4EB4FULL;
    h = (h ^ (h >> 29)) + (uint64_t)c[2] * 0x165667B19E3779F9ULL;
    h = (h ^ (h >> 32)) + (uint64_t)(uint32_t)L * 0x27D4EB2F165667C5ULL;
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ULL;
    h ^= h >> 32;
    return h;
}

/* Position of the cell (L, c) in the table, or SIZE_MAX. */
static size_t as_bx_find(const as_boxindex *bi, const int64_t c[3], int32_t L) {
    if (bi->tn == 0) return SIZE_MAX;
    size_t mask = bi->tcap - 1, i = (size_t)as_bx_hash(c, L) & mask;
    for (;;) {
        const as_bx_cell *e = &bi->tab[i];
        if (e->level == AS_BX_EMPTY) return SIZE_MAX;
        if (e->level == L && e->c[0] == c[0] && e->c[1] == c[1] && e->c[2] == c[2]) return i;
        i = (i + 1) & mask;
    }
}

/* Insert a table entry (capacity guaranteed, key absent); returns its position. */
static size_t as_bx_cell_put(as_boxindex *bi, const as_bx_cell *cell) {
    size_t mask = bi->tcap - 1, i = (size_t)as_bx_hash(cell->c, cell->level) & mask;
    while (bi->tab[i].level != AS_BX_EMPTY) i = (i + 1) & mask;
    bi->tab[i] = *cell;
    bi->tn++;
    return i;
}

/* Delete the table entry at position i (backward-shift deletion keeps every probe chain
 * unbroken without tombstones; entries move, so positions are never kept across calls). */
static void as_bx_cell_del(as_boxindex *bi, size_t i) {
    size_t mask = bi->tcap - 1, j = i;
    for (;;) {
        j = (j + 1) & mask;
        as_bx_cell *e = &bi->tab[j];
        if (e->level == AS_BX_EMPTY) break;
        size_t k = (size_t)as_bx_hash(e->c, e->level) & mask;
        /* e may stay if its home k lies cyclically in (i, j] */
        int stays = i <= j ? (i < k && k <= j) : (i < k || k <= j);
        if (stays) continue;
        bi->tab[i] = *e;
        i = j;
    }
    bi->tab[i].level = AS_BX_EMPTY;
    bi->tn--;
}

/* Make room for one more cell (load factor <= 1/2). */
static int as_bx_reserve_cell(anistar_context *ctx, as_boxindex *bi) {
    if (2 * (bi->tn + 1) <= bi->tcap) return 0;
    size_t ncap = bi->tcap ? 2 * bi->tcap : 64;
    as_bx_cell *nt = as_alloc_array(ctx, ncap, sizeof *nt);
    if (!nt) return -1;
    for (size_t i = 0; i < ncap; i++) nt[i].level = AS_BX_EMPTY;
    as_bx_cell *old = bi->tab;
    size_t ocap = bi->tcap;
    bi->tab = nt;
    bi->tcap = ncap;
    bi->tn = 0;
    for (size_t i = 0; i < ocap; i++)
        if (old[i].level != AS_BX_EMPTY) as_bx_cell_put(bi, &old[i]);
    as_free(ctx, old, ocap * sizeof *old);
    return 0;
}

/* ---- block pool -------------------------------------------------------------------------- */

/* Make sure a block of class k can be taken without allocating. */
static int as_bx_reserve_block(anistar_context *ctx, as_boxindex *bi, uint32_t k) {
    if (k >= AS_BX_CLASSES) return -1;
    if (bi->free_block[k] >= 0) return 0;
    size_t need = bi->pool_n + ((size_t)1 << k);
    if (need > (size_t)INT32_MAX) return -1;
    void *p = bi->pool;
    if (as_grow(ctx, &p, &bi->pool_cap, need, sizeof *bi->pool)) return -1;
    bi->pool = p;
    return 0;
}

static uint32_t as_bx_block_take(as_boxindex *bi, uint32_t k) {
    int32_t off = bi->free_block[k];
    if (off >= 0) {
        bi->free_block[k] = bi->pool[off].id;
        return (uint32_t)off;
    }
    uint32_t o = (uint32_t)bi->pool_n;
    bi->pool_n += (size_t)1 << k;
    return o;
}

static void as_bx_block_give(as_boxindex *bi, uint32_t off, uint32_t k) {
    bi->pool[off].id = bi->free_block[k];
    bi->free_block[k] = (int32_t)off;
}

/* ---- levels -------------------------------------------------------------------------------- */

static void as_bx_level_inc(as_boxindex *bi, int L) {
    if (bi->lvl_count[L - AS_BX_LMIN]++ > 0) return;
    size_t i = bi->nactive;
    while (i > 0 && bi->active[i - 1] > L) {
        bi->active[i] = bi->active[i - 1];
        i--;
    }
    bi->active[i] = (int16_t)L;
    bi->nactive++;
}

static void as_bx_level_dec(as_boxindex *bi, int L) {
    if (--bi->lvl_count[L - AS_BX_LMIN] > 0) return;
    size_t i = 0;
    while (bi->active[i] != L) i++;
    memmove(bi->active + i, bi->active + i + 1, (bi->nactive - i - 1) * sizeof *bi->active);
    bi->nactive--;
}

/* ---- entries in cells ---------------------------------------------------------------------- */

/* Append the entry of id (box lo, hi; record already holding level and cell) to its cell,
 * creating the cell or moving it to a block twice as large when full. Capacity (table and
 * pool) must have been reserved. */
static void as_bx_attach(as_boxindex *bi, int32_t id, const double lo[3], const double hi[3]) {
    as_bx_rec *r = &bi->rec[id];
    size_t t = as_bx_find(bi, r->cell, r->level);
    if (t == SIZE_MAX) {
        as_bx_cell cell;
        memcpy(cell.c, r->cell, sizeof cell.c);
        cell.level = r->level;
        cell.cls = AS_BX_MIN_CLASS;
        cell.off = as_bx_block_take(bi, AS_BX_MIN_CLASS);
        cell.count = 0;
        t = as_bx_cell_put(bi, &cell);
    }
    as_bx_cell *C = &bi->tab[t];
    if (C->count == (uint32_t)1 << C->cls) {
        uint32_t noff = as_bx_block_take(bi, C->cls + 1);
        memcpy(bi->pool + noff, bi->pool + C->off, C->count * sizeof *bi->pool);
        for (uint32_t i = 0; i < C->count; i++) bi->rec[bi->pool[noff + i].id].pos = noff + i;
        as_bx_block_give(bi, C->off, C->cls);
        C->off = noff;
        C->cls++;
    }
    uint32_t pos = C->off + C->count++;
    as_bx_ent *e = &bi->pool[pos];
    memcpy(e->lo, lo, sizeof e->lo);
    memcpy(e->hi, hi, sizeof e->hi);
    e->id = id;
    e->pad = 0;
    r->pos = pos;
    as_bx_level_inc(bi, r->level);
}

/* Take id's entry out of its cell (the cell's last entry fills the hole; an emptied cell
 * returns its block and leaves the table). */
static void as_bx_detach(as_boxindex *bi, int32_t id) {
    as_bx_rec *r = &bi->rec[id];
    size_t t = as_bx_find(bi, r->cell, r->level);
    as_bx_cell *C = &bi->tab[t];
    uint32_t last = C->off + C->count - 1;
    if (r->pos != last) {
        bi->pool[r->pos] = bi->pool[last];
        bi->rec[bi->pool[r->pos].id].pos = r->pos;
    }
    C->count--;
    if (C->count == 0) {
        as_bx_block_give(bi, C->off, C->cls);
        as_bx_cell_del(bi, t);
    }
    as_bx_level_dec(bi, r->level);
}

/* ---- life cycle and updates --------------------------------------------------------------- */

anistar_status as_boxindex_new(anistar_context *ctx, as_boxindex **out) {
    *out = NULL;
    as_boxindex *bi = as_alloc(ctx, sizeof *bi);
    if (!bi) return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory");
    memset(bi, 0, sizeof *bi);
    for (int k = 0; k < AS_BX_CLASSES; k++) bi->free_block[k] = -1;
    *out = bi;
    return ANISTAR_OK;
}

void as_boxindex_free(anistar_context *ctx, as_boxindex *bi) {
    if (!bi) return;
    as_free(ctx, bi->rec, bi->idcap * sizeof *bi->rec);
    as_free(ctx, bi->pool, bi->pool_cap * sizeof *bi->pool);
    as_free(ctx, bi->tab, bi->tcap * sizeof *bi->tab);
    as_free(ctx, bi, sizeof *bi);
}

static int as_bx_valid_box(const double lo[3], const double hi[3]) {
    for (int k = 0; k < 3; k++)
        if (!(fabs(lo[k]) <= AS_BX_MAX_COORD) || !(fabs(hi[k]) <= AS_BX_MAX_COORD) ||
            !(lo[k] <= hi[k]))
            return 0;
    return 1;
}

/*
 * as_boxindex_set — see boxindex.h.
 * design:
 *   1. Level L and lower-corner cell of the new box.
 *   2. Existing id with the same level and cell: rewrite its entry, done.
 *   3. Reserve everything that may be needed (id records, one table entry, one block:
 *      the target cell's next size, or a first block) before changing anything, so a
 *      failure leaves the index as it was.
 *   4. Detach the old entry (existing id); attach the new one to its cell.
 */
anistar_status as_boxindex_set(anistar_context *ctx, as_boxindex *bi, int32_t id,
                               const double lo[3], const double hi[3]) {
    if (id < 0 || id == INT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "boxindex: invalid id %ld", (long)id);
    if (!as_bx_valid_box(lo, hi))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "boxindex: box of id %ld is not a box with coordinates within 1e300",
                       (long)id);
    int L = as_bx_level(lo, hi);
    int64_t c[3];
    for (int k = 0; k < 3; k++) c[k] = as_bx_cell_of(lo[k], L);
    int has = (size_t)id < bi->idcap && bi->rec[id].level != AS_BX_NOBOX;
    if (has) {
        as_bx_rec *r = &bi->rec[id];
        if (r->level == L && r->cell[0] == c[0] && r->cell[1] == c[1] && r->cell[2] == c[2]) {
            as_bx_ent *e = &bi->pool[r->pos];
            memcpy(e->lo, lo, sizeof e->lo);
            memcpy(e->hi, hi, sizeof e->hi);
            return ANISTAR_OK;
        }
    } else if ((size_t)id >= bi->idcap) {
        size_t old = bi->idcap;
        void *p = bi->rec;
        if (as_grow(ctx, &p, &bi->idcap, (size_t)id + 1, sizeof *bi->rec))
            return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory (id %ld)", (long)id);
        bi->rec = p;
        for (size_t i = old; i < bi->idcap; i++) bi->rec[i].level = AS_BX_NOBOX;
    }
    /* what attaching will take: a table entry and a first block for a new cell, or the
     * next block size for a full one */
    size_t t = as_bx_find(bi, c, L);
    int need_cell = t == SIZE_MAX;
    uint32_t need_cls = need_cell ? AS_BX_MIN_CLASS
                        : bi->tab[t].count == (uint32_t)1 << bi->tab[t].cls ? bi->tab[t].cls + 1
                                                                            : AS_BX_NONE;
    if ((need_cell && as_bx_reserve_cell(ctx, bi)) ||
        (need_cls != AS_BX_NONE && as_bx_reserve_block(ctx, bi, need_cls)))
        return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory (%zu boxes)", bi->n);
    if (has)
        as_bx_detach(bi, id);
    else
        bi->n++;
    as_bx_rec *r = &bi->rec[id];
    memcpy(r->cell, c, sizeof r->cell);
    r->level = L;
    as_bx_attach(bi, id, lo, hi);
    return ANISTAR_OK;
}

int as_boxindex_remove(as_boxindex *bi, int32_t id) {
    if (id < 0 || (size_t)id >= bi->idcap || bi->rec[id].level == AS_BX_NOBOX) return 0;
    as_bx_detach(bi, id);
    bi->rec[id].level = AS_BX_NOBOX;
    bi->n--;
    return 1;
}

int as_boxindex_get(const as_boxindex *bi, int32_t id, double lo[3], double hi[3]) {
    if (id < 0 || (size_t)id >= bi->idcap || bi->rec[id].level == AS_BX_NOBOX) return 0;
    const as_bx_ent *e = &bi->pool[bi->rec[id].pos];
    memcpy(lo, e->lo, sizeof e->lo);
    memcpy(hi, e->hi, sizeof e->hi);
    return 1;
}

size_t as_boxindex_size(const as_boxindex *bi) { return bi->n; }

/* ---- queries ------------------------------------------------------------------------------- */

static inline int as_bx_meets(const as_bx_ent *e, const double lo[3], const double hi[3]) {
    return e->hi[0] >= lo[0] && e->lo[0] <= hi[0] && e->hi[1] >= lo[1] && e->lo[1] <= hi[1] &&
           e->hi[2] >= lo[2] && e->lo[2] <= hi[2];
}

/* Append the ids of the entries of table cell t that meet [lo, hi]. */
static int as_bx_scan(anistar_context *ctx, const as_boxindex *bi, const as_bx_cell *C,
                      const double lo[3], const double hi[3], as_idlist *out) {
    const as_bx_ent *e = bi->pool + C->off;
    for (uint32_t i = 0; i < C->count; i++)
        if (as_bx_meets(&e[i], lo, hi) && as_idlist_push(ctx, out, e[i].id)) return -1;
    return 0;
}

/*
 * as_bx_query — ids of the boxes meeting [lo, hi] (a point when lo == hi).
 * design:
 *   1. For each level L holding boxes: candidate lower-corner cells are
 *      floor(lo_k / 2^L) - 1 .. floor(hi_k / 2^L) on each axis (extents are < 2^L).
 *   2. If there are more candidate cells than boxes at that level, mark the level for a
 *      pass over the table instead; otherwise probe each cell and test its entries (one
 *      contiguous block per cell).
 *   3. One pass over the table for the marked levels; sort the ids.
 */
static anistar_status as_bx_query(anistar_context *ctx, const as_boxindex *bi,
                                  const double lo[3], const double hi[3], as_idlist *out) {
    out->n = 0;
    unsigned char scan[AS_BX_NLEVELS];
    int any_scan = 0;
    for (size_t a = 0; a < bi->nactive; a++) {
        int L = bi->active[a];
        int64_t c0[3], c1[3];
        double cells = 1;
        for (int k = 0; k < 3; k++) {
            c0[k] = as_bx_cell_of(lo[k], L) - AS_BX_SPAN;
            c1[k] = as_bx_cell_of(hi[k], L);
            cells *= (double)c1[k] - (double)c0[k] + 1; /* no int64 overflow */
        }
        if (cells > (AS_BX_SPAN + 1) * (AS_BX_SPAN + 1) * (AS_BX_SPAN + 1) &&
            cells > (double)bi->lvl_count[L - AS_BX_LMIN]) {
            if (!any_scan) memset(scan, 0, sizeof scan);
            any_scan = 1;
            scan[L - AS_BX_LMIN] = 1;
            continue;
        }
        int64_t c[3];
        for (c[0] = c0[0]; c[0] <= c1[0]; c[0]++)
            for (c[1] = c0[1]; c[1] <= c1[1]; c[1]++)
                for (c[2] = c0[2]; c[2] <= c1[2]; c[2]++) {
                    size_t t = as_bx_find(bi, c, L);
                    if (t != SIZE_MAX && as_bx_scan(ctx, bi, &bi->tab[t], lo, hi, out))
                        return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory in a query");
                }
    }
    if (any_scan)
        for (size_t t = 0; t < bi->tcap; t++) {
            const as_bx_cell *C = &bi->tab[t];
            if (C->level != AS_BX_EMPTY && scan[C->level - AS_BX_LMIN] &&
                as_bx_scan(ctx, bi, C, lo, hi, out))
                return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory in a query");
        }
    as_ids_sort(out->ids, out->n);
    return ANISTAR_OK;
}

anistar_status as_boxindex_query_point(anistar_context *ctx, const as_boxindex *bi,
                                       const double p[3], as_idlist *out) {
    out->n = 0;
    if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
        return as_fail(ctx, ANISTAR_EINVAL, "boxindex: query point not finite");
    return as_bx_query(ctx, bi, p, p, out);
}

anistar_status as_boxindex_query_box(anistar_context *ctx, const as_boxindex *bi,
                                     const double lo[3], const double hi[3], as_idlist *out) {
    out->n = 0;
    for (int k = 0; k < 3; k++)
        if (!isfinite(lo[k]) || !isfinite(hi[k]) || !(lo[k] <= hi[k]))
            return as_fail(ctx, ANISTAR_EINVAL, "boxindex: query box invalid");
    return as_bx_query(ctx, bi, lo, hi, out);
}

size_t as_boxindex_levels(const as_boxindex *bi) { return bi->nactive; }

/* ---- validation ---------------------------------------------------------------------------- */

int as_boxindex_check(anistar_context *ctx, const as_boxindex *bi) {
    /* records */
    size_t n = 0;
    int32_t *counts = as_alloc_array(ctx, AS_BX_NLEVELS, sizeof *counts);
    unsigned char *used = bi->pool_n ? as_alloc(ctx, bi->pool_n) : NULL;
    int ok = counts && (used || bi->pool_n == 0);
    if (ok) {
        memset(counts, 0, AS_BX_NLEVELS * sizeof *counts);
        if (used) memset(used, 0, bi->pool_n);
    }
    for (size_t id = 0; ok && id < bi->idcap; id++) {
        const as_bx_rec *r = &bi->rec[id];
        if (r->level == AS_BX_NOBOX) continue;
        n++;
        if (r->pos >= bi->pool_n) {
            ok = 0;
            break;
        }
        const as_bx_ent *e = &bi->pool[r->pos];
        if (e->id != (int32_t)id || r->level != as_bx_level(e->lo, e->hi)) ok = 0;
        for (int k = 0; k < 3 && ok; k++)
            if (r->cell[k] != as_bx_cell_of(e->lo[k], r->level) || !(e->lo[k] <= e->hi[k]))
                ok = 0;
        size_t t = ok ? as_bx_find(bi, r->cell, r->level) : SIZE_MAX;
        if (t == SIZE_MAX || r->pos < bi->tab[t].off ||
            r->pos >= bi->tab[t].off + bi->tab[t].count)
            ok = 0;
        if (ok) counts[r->level - AS_BX_LMIN]++;
    }
    if (ok && (n != bi->n || memcmp(counts, bi->lvl_count, AS_BX_NLEVELS * sizeof *counts)))
        ok = 0;
    /* active levels */
    size_t nact = 0;
    for (int L = 0; ok && L < AS_BX_NLEVELS; L++) nact += bi->lvl_count[L] > 0;
    if (ok && nact != bi->nactive) ok = 0;
    for (size_t a = 0; ok && a < bi->nactive; a++)
        if (bi->lvl_count[bi->active[a] - AS_BX_LMIN] <= 0 ||
            (a > 0 && bi->active[a - 1] >= bi->active[a]))
            ok = 0;
    /* cells: findable, non-empty, blocks disjoint inside the pool */
    size_t cells = 0, entries = 0;
    for (size_t t = 0; ok && t < bi->tcap; t++) {
        const as_bx_cell *C = &bi->tab[t];
        if (C->level == AS_BX_EMPTY) continue;
        cells++;
        entries += C->count;
        size_t size = (size_t)1 << C->cls;
        if (as_bx_find(bi, C->c, C->level) != t || C->count == 0 || C->count > size ||
            C->cls < AS_BX_MIN_CLASS || (size_t)C->off + size > bi->pool_n) {
            ok = 0;
            break;
        }
        for (size_t i = C->off; i < C->off + size && ok; i++) ok = !used[i]++;
        for (uint32_t i = 0; i < C->count && ok; i++) {
            const as_bx_ent *e = &bi->pool[C->off + i];
            if (e->id < 0 || (size_t)e->id >= bi->idcap || bi->rec[e->id].pos != C->off + i)
                ok = 0;
        }
    }
    if (ok && (cells != bi->tn || entries != bi->n || (bi->tcap && 2 * bi->tn > bi->tcap)))
        ok = 0;
    /* free blocks: disjoint from everything else, and everything is covered */
    for (int k = 0; ok && k < AS_BX_CLASSES; k++)
        for (int32_t off = bi->free_block[k]; ok && off >= 0; off = bi->pool[off].id) {
            size_t size = (size_t)1 << k;
            if ((size_t)off + size > bi->pool_n) {
                ok = 0;
                break;
            }
            for (size_t i = (size_t)off; i < (size_t)off + size && ok; i++) ok = !used[i]++;
        }
    for (size_t i = 0; ok && i < bi->pool_n; i++) ok = used[i] == 1;
    as_free(ctx, counts, AS_BX_NLEVELS * sizeof *counts);
    as_free(ctx, used, bi->pool_n);
    return ok ? 0 : -1;
}
