/*
 * boxindex.c — dynamic boxes in a balanced AABB tree with fattened leaves (see
 * boxindex.h).
 */
#include "geom/boxindex.h"

#include <math.h>
#include <string.h>

/* A leaf's box is the true box grown by AS_BI_FAT times its largest extent on each side,
 * so that small moves and shrinks need no tree update. */
#define AS_BI_FAT 0.125
/* An update keeps the leaf when the new box fits in the fat box and the fat box is not
 * more than AS_BI_LOOSE times as large (largest extent) as the new box's own fat box. */
#define AS_BI_LOOSE 2.0
/* Coordinates beyond this magnitude are rejected (keeps extents and margins finite). */
#define AS_BI_MAX_COORD 1e300
/* Depth-first stacks; a tree taller than this (never seen: the balancing keeps the height
 * logarithmic) is queried by a plain scan of the boxes instead. */
#define AS_BI_STACK 192
#define AS_BI_NIL (-1)

typedef struct as_bi_node {
    double lo[3], hi[3]; /* leaf: fat box; internal: exact union of the children's boxes */
    int32_t parent;      /* AS_BI_NIL at the root */
    int32_t child[2];    /* AS_BI_NIL for a leaf */
    int32_t height;      /* 0 for a leaf, -1 for a free node */
    int32_t id;          /* leaf: its id; free node: next free node */
    int32_t pad;
} as_bi_node;

typedef struct as_bi_entry {
    double box[6]; /* the true box: lo, hi */
    int32_t leaf;  /* its leaf node, or AS_BI_NIL when the id has no box */
    int32_t pad;
} as_bi_entry;

struct as_boxindex {
    as_bi_node *node;
    size_t ncap, nused; /* capacity; nodes ever handed out (free ones are on the list) */
    int32_t free_head;
    int32_t root;
    as_bi_entry *ent; /* indexed by id */
    size_t idcap;
    size_t n; /* boxes stored */
};

/* ---- box helpers ------------------------------------------------------------------------- */

static inline void as_bi_union(const double *alo, const double *ahi, const double *blo,
                               const double *bhi, double *lo, double *hi) {
    for (int k = 0; k < 3; k++) {
        lo[k] = alo[k] < blo[k] ? alo[k] : blo[k];
        hi[k] = ahi[k] > bhi[k] ? ahi[k] : bhi[k];
    }
}

/* Half the surface area, the insertion cost of a box (SAH). */
static inline double as_bi_area(const double *lo, const double *hi) {
    double x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
    return x * y + y * z + z * x;
}

static inline double as_bi_union_area(const as_bi_node *a, const double *lo, const double *hi) {
    double ulo[3], uhi[3];
    as_bi_union(a->lo, a->hi, lo, hi, ulo, uhi);
    return as_bi_area(ulo, uhi);
}

static inline double as_bi_max_extent(const double *lo, const double *hi) {
    double e = 0;
    for (int k = 0; k < 3; k++)
        if (hi[k] - lo[k] > e) e = hi[k] - lo[k];
    return e;
}

/* The fat box of [lo, hi]; it contains [lo, hi] also in floating point (a margin m >= 0
 * subtracted from lo cannot round above lo). */
static void as_bi_fatten(const double *lo, const double *hi, double *flo, double *fhi) {
    double m = AS_BI_FAT * as_bi_max_extent(lo, hi);
    for (int k = 0; k < 3; k++) {
        flo[k] = lo[k] - m;
        fhi[k] = hi[k] + m;
    }
}

static inline int as_bi_within(const double *alo, const double *ahi, const double *blo,
                               const double *bhi) {
    for (int k = 0; k < 3; k++)
        if (alo[k] < blo[k] || ahi[k] > bhi[k]) return 0;
    return 1;
}

static inline int as_bi_meets(const double *alo, const double *ahi, const double *blo,
                              const double *bhi) {
    for (int k = 0; k < 3; k++)
        if (ahi[k] < blo[k] || alo[k] > bhi[k]) return 0;
    return 1;
}

/* ---- node pool ----------------------------------------------------------------------------- */

/* Make sure `more` nodes can be taken without allocating. */
static int as_bi_reserve_nodes(anistar_context *ctx, as_boxindex *bi, size_t more) {
    size_t nfree = 0;
    for (int32_t f = bi->free_head; f != AS_BI_NIL && nfree < more; f = bi->node[f].id) nfree++;
    if (nfree >= more) return 0;
    size_t need = bi->nused + (more - nfree);
    if (need > (size_t)INT32_MAX) return -1;
    void *p = bi->node;
    if (as_grow(ctx, &p, &bi->ncap, need, sizeof *bi->node)) return -1;
    bi->node = p;
    return 0;
}

static int32_t as_bi_take(as_boxindex *bi) {
    int32_t i;
    if (bi->free_head != AS_BI_NIL) {
        i = bi->free_head;
        bi->free_head = bi->node[i].id;
    } else {
        i = (int32_t)bi->nused++;
    }
    as_bi_node *nd = &bi->node[i];
    nd->parent = nd->child[0] = nd->child[1] = AS_BI_NIL;
    nd->height = 0;
    nd->id = AS_BI_NIL;
    nd->pad = 0;
    return i;
}

static void as_bi_give(as_boxindex *bi, int32_t i) {
    bi->node[i].height = -1;
    bi->node[i].id = bi->free_head;
    bi->free_head = i;
}

/* ---- balancing ----------------------------------------------------------------------------- */

static void as_bi_refit(as_boxindex *bi, int32_t i) {
    as_bi_node *nd = &bi->node[i];
    const as_bi_node *a = &bi->node[nd->child[0]], *b = &bi->node[nd->child[1]];
    as_bi_union(a->lo, a->hi, b->lo, b->hi, nd->lo, nd->hi);
    nd->height = 1 + (a->height > b->height ? a->height : b->height);
}

static void as_bi_replace_child(as_boxindex *bi, int32_t parent, int32_t old, int32_t neu) {
    if (parent == AS_BI_NIL) {
        bi->root = neu;
        return;
    }
    as_bi_node *p = &bi->node[parent];
    p->child[p->child[0] == old ? 0 : 1] = neu;
}

/*
 * as_bi_balance — if the subtree at a is unbalanced (child heights differ by more than 1),
 * rotate its taller child c up: c takes a's place, a keeps its shorter child and the
 * shorter of c's children, c keeps its taller child and gets a. Returns the subtree's new
 * root. (The AVL-style rotation used by Box2D's dynamic tree.)
 */
static int32_t as_bi_balance(as_boxindex *bi, int32_t a) {
    as_bi_node *A = &bi->node[a];
    if (A->child[0] == AS_BI_NIL || A->height < 2) return a;
    int32_t b0 = A->child[0], b1 = A->child[1];
    int diff = bi->node[b1].height - bi->node[b0].height;
    if (diff >= -1 && diff <= 1) return a;
    int up = diff > 1 ? 1 : 0; /* the taller side */
    int32_t c = A->child[up];
    as_bi_node *C = &bi->node[c];
    int32_t f = C->child[0], g = C->child[1];
    int32_t tall = bi->node[f].height > bi->node[g].height ? f : g;
    int32_t shortc = tall == f ? g : f;
    /* c replaces a under a's parent */
    C->parent = A->parent;
    as_bi_replace_child(bi, A->parent, a, c);
    /* a becomes a child of c, with its own other child and c's shorter child */
    C->child[0] = a;
    C->child[1] = tall;
    A->parent = c;
    A->child[up] = shortc;
    bi->node[shortc].parent = a;
    as_bi_refit(bi, a);
    as_bi_refit(bi, c);
    return c;
}

/* Refit and rebalance every ancestor from i up to the root. */
static void as_bi_fix_upwards(as_boxindex *bi, int32_t i) {
    while (i != AS_BI_NIL) {
        i = as_bi_balance(bi, i);
        as_bi_refit(bi, i);
        i = bi->node[i].parent;
    }
}

/*
 * as_bi_insert_leaf — hang leaf l (its fat box set) into the tree.
 * design (SAH descent, as Box2D's dynamic tree):
 *   1. From the root, compare the cost of pairing l with the current node (twice the
 *      area of their union) with the cost of descending into each child (the child's area
 *      increase, plus what every ancestor on the way pays: twice its area increase);
 *      stop when pairing here is cheapest.
 *   2. A new internal node takes the sibling's place, with the sibling and l as children.
 *   3. Refit and rebalance up to the root.
 */
static void as_bi_insert_leaf(as_boxindex *bi, int32_t l) {
    if (bi->root == AS_BI_NIL) {
        bi->root = l;
        bi->node[l].parent = AS_BI_NIL;
        return;
    }
    const double *llo = bi->node[l].lo, *lhi = bi->node[l].hi;
    int32_t s = bi->root;
    while (bi->node[s].child[0] != AS_BI_NIL) {
        const as_bi_node *nd = &bi->node[s];
        double area = as_bi_area(nd->lo, nd->hi), comb = as_bi_union_area(nd, llo, lhi);
        double cost = 2 * comb, inherit = 2 * (comb - area), cc[2];
        for (int m = 0; m < 2; m++) {
            const as_bi_node *c = &bi->node[nd->child[m]];
            double u = as_bi_union_area(c, llo, lhi);
            cc[m] = (c->child[0] == AS_BI_NIL ? u : u - as_bi_area(c->lo, c->hi)) + inherit;
        }
        if (cost < cc[0] && cost < cc[1]) break;
        s = nd->child[cc[1] < cc[0] ? 1 : 0];
    }
    int32_t p = as_bi_take(bi);
    as_bi_node *P = &bi->node[p], *S = &bi->node[s];
    P->parent = S->parent;
    as_bi_replace_child(bi, S->parent, s, p);
    P->child[0] = s;
    P->child[1] = l;
    S->parent = p;
    bi->node[l].parent = p;
    as_bi_fix_upwards(bi, p);
}

/* Unhang leaf l (kept as a node); its parent is freed and the sibling takes its place. */
static void as_bi_remove_leaf(as_boxindex *bi, int32_t l) {
    if (bi->root == l) {
        bi->root = AS_BI_NIL;
        return;
    }
    int32_t p = bi->node[l].parent, g = bi->node[p].parent;
    int32_t s = bi->node[p].child[bi->node[p].child[0] == l ? 1 : 0];
    bi->node[s].parent = g;
    as_bi_replace_child(bi, g, p, s);
    as_bi_give(bi, p);
    bi->node[l].parent = AS_BI_NIL;
    as_bi_fix_upwards(bi, g);
}

/* ---- life cycle and updates --------------------------------------------------------------- */

anistar_status as_boxindex_new(anistar_context *ctx, as_boxindex **out) {
    *out = NULL;
    as_boxindex *bi = as_alloc(ctx, sizeof *bi);
    if (!bi) return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory");
    memset(bi, 0, sizeof *bi);
    bi->free_head = AS_BI_NIL;
    bi->root = AS_BI_NIL;
    *out = bi;
    return ANISTAR_OK;
}

void as_boxindex_free(anistar_context *ctx, as_boxindex *bi) {
    if (!bi) return;
    as_free(ctx, bi->node, bi->ncap * sizeof *bi->node);
    as_free(ctx, bi->ent, bi->idcap * sizeof *bi->ent);
    as_free(ctx, bi, sizeof *bi);
}

/* Grow the id array to hold id (new entries empty). */
static int as_bi_reserve_id(anistar_context *ctx, as_boxindex *bi, int32_t id) {
    if ((size_t)id < bi->idcap) return 0;
    size_t old = bi->idcap;
    void *p = bi->ent;
    if (as_grow(ctx, &p, &bi->idcap, (size_t)id + 1, sizeof *bi->ent)) return -1;
    bi->ent = p;
    for (size_t i = old; i < bi->idcap; i++) bi->ent[i].leaf = AS_BI_NIL;
    return 0;
}

static int as_bi_valid_box(const double lo[3], const double hi[3]) {
    for (int k = 0; k < 3; k++)
        if (!(fabs(lo[k]) <= AS_BI_MAX_COORD) || !(fabs(hi[k]) <= AS_BI_MAX_COORD) ||
            !(lo[k] <= hi[k]))
            return 0;
    return 1;
}

/*
 * as_boxindex_set — see boxindex.h.
 * design:
 *   1. Existing id whose new box fits in its leaf's fat box, that fat box not more than
 *      AS_BI_LOOSE times too large: store the new true box only, O(1).
 *   2. Otherwise reserve what may be needed (id arrays, two nodes) before changing
 *      anything; unhang the old leaf if any; set the fat box; insert the leaf (SAH
 *      descent, rebalancing up to the root), O(log n).
 */
anistar_status as_boxindex_set(anistar_context *ctx, as_boxindex *bi, int32_t id,
                               const double lo[3], const double hi[3]) {
    if (id < 0 || id == INT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "boxindex: invalid id %ld", (long)id);
    if (!as_bi_valid_box(lo, hi))
        return as_fail(ctx, ANISTAR_EINVAL,
                       "boxindex: box of id %ld is not a box with coordinates within 1e300",
                       (long)id);
    double flo[3], fhi[3];
    as_bi_fatten(lo, hi, flo, fhi);
    int32_t l = (size_t)id < bi->idcap ? bi->ent[id].leaf : AS_BI_NIL;
    if (l != AS_BI_NIL) {
        as_bi_node *nd = &bi->node[l];
        if (as_bi_within(lo, hi, nd->lo, nd->hi) &&
            as_bi_max_extent(nd->lo, nd->hi) <= AS_BI_LOOSE * as_bi_max_extent(flo, fhi)) {
            memcpy(bi->ent[id].box, lo, 3 * sizeof *lo);
            memcpy(bi->ent[id].box + 3, hi, 3 * sizeof *hi);
            return ANISTAR_OK;
        }
        if (as_bi_reserve_nodes(ctx, bi, 1))
            return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory (%zu boxes)", bi->n);
        as_bi_remove_leaf(bi, l);
    } else {
        if (as_bi_reserve_id(ctx, bi, id) || as_bi_reserve_nodes(ctx, bi, 2))
            return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory (id %ld)", (long)id);
        l = as_bi_take(bi);
        bi->node[l].id = id;
        bi->ent[id].leaf = l;
        bi->n++;
    }
    memcpy(bi->node[l].lo, flo, sizeof flo);
    memcpy(bi->node[l].hi, fhi, sizeof fhi);
    memcpy(bi->ent[id].box, lo, 3 * sizeof *lo);
    memcpy(bi->ent[id].box + 3, hi, 3 * sizeof *hi);
    as_bi_insert_leaf(bi, l);
    return ANISTAR_OK;
}

int as_boxindex_remove(as_boxindex *bi, int32_t id) {
    if (id < 0 || (size_t)id >= bi->idcap || bi->ent[id].leaf == AS_BI_NIL) return 0;
    int32_t l = bi->ent[id].leaf;
    as_bi_remove_leaf(bi, l);
    as_bi_give(bi, l);
    bi->ent[id].leaf = AS_BI_NIL;
    bi->n--;
    return 1;
}

int as_boxindex_get(const as_boxindex *bi, int32_t id, double lo[3], double hi[3]) {
    if (id < 0 || (size_t)id >= bi->idcap || bi->ent[id].leaf == AS_BI_NIL) return 0;
    memcpy(lo, bi->ent[id].box, 3 * sizeof *lo);
    memcpy(hi, bi->ent[id].box + 3, 3 * sizeof *hi);
    return 1;
}

size_t as_boxindex_size(const as_boxindex *bi) { return bi->n; }

/* ---- queries ------------------------------------------------------------------------------- */

/*
 * as_bi_query — ids whose true box meets [lo, hi] (a point when lo == hi).
 * design: depth-first over the nodes whose box meets the query (leaf boxes are fat, so
 * this is a filter); at a leaf, test the true box. Sort the ids.
 */
static anistar_status as_bi_query(anistar_context *ctx, const as_boxindex *bi,
                                  const double lo[3], const double hi[3], as_idlist *out) {
    out->n = 0;
    if (bi->root == AS_BI_NIL) return ANISTAR_OK;
    if (bi->node[bi->root].height >= AS_BI_STACK - 1) { /* never expected: plain scan */
        for (size_t id = 0; id < bi->idcap; id++) {
            const double *b = bi->ent[id].box;
            if (bi->ent[id].leaf != AS_BI_NIL && as_bi_meets(b, b + 3, lo, hi) &&
                as_idlist_push(ctx, out, (int32_t)id))
                return as_fail(ctx, ANISTAR_ENOMEM, "boxindex: out of memory in a query");
        }
        return ANISTAR_OK;
    }
    int32_t st[AS_BI_STACK];
    int sp = 0;
    st[sp++] = bi->root;
    while (sp > 0) {
        const as_bi_node *nd = &bi->node[st[--sp]];
        if (!as_bi_meets(nd->lo, nd->hi, lo, hi)) continue;
        if (nd->child[0] != AS_BI_NIL) {
            st[sp++] = nd->child[1];
            st[sp++] = nd->child[0];
            continue;
        }
        const double *b = bi->ent[nd->id].box;
        if (as_bi_meets(b, b + 3, lo, hi) && as_idlist_push(ctx, out, nd->id))
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
    return as_bi_query(ctx, bi, p, p, out);
}

anistar_status as_boxindex_query_box(anistar_context *ctx, const as_boxindex *bi,
                                     const double lo[3], const double hi[3], as_idlist *out) {
    out->n = 0;
    for (int k = 0; k < 3; k++)
        if (!isfinite(lo[k]) || !isfinite(hi[k]) || !(lo[k] <= hi[k]))
            return as_fail(ctx, ANISTAR_EINVAL, "boxindex: query box invalid");
    return as_bi_query(ctx, bi, lo, hi, out);
}

int as_boxindex_height(const as_boxindex *bi) {
    return bi->root == AS_BI_NIL ? -1 : bi->node[bi->root].height;
}

/* ---- validation ---------------------------------------------------------------------------- */

int as_boxindex_check(const as_boxindex *bi) {
    size_t leaves = 0, internal = 0, freed = 0;
    for (int32_t f = bi->free_head; f != AS_BI_NIL; f = bi->node[f].id) {
        if (f < 0 || (size_t)f >= bi->nused || bi->node[f].height != -1 || ++freed > bi->nused)
            return -1;
    }
    for (size_t i = 0; i < bi->nused; i++) {
        const as_bi_node *nd = &bi->node[i];
        if (nd->height < 0) continue;
        int32_t par = nd->parent;
        if (par == AS_BI_NIL) {
            if (bi->root != (int32_t)i) return -1;
        } else {
            if (par < 0 || (size_t)par >= bi->nused) return -1;
            const as_bi_node *p = &bi->node[par];
            if (p->child[0] != (int32_t)i && p->child[1] != (int32_t)i) return -1;
        }
        if (nd->child[0] == AS_BI_NIL) {
            if (nd->child[1] != AS_BI_NIL || nd->height != 0) return -1;
            int32_t id = nd->id;
            if (id < 0 || (size_t)id >= bi->idcap || bi->ent[id].leaf != (int32_t)i) return -1;
            const double *b = bi->ent[id].box;
            if (!as_bi_within(b, b + 3, nd->lo, nd->hi)) return -1; /* fat box holds box */
            for (int k = 0; k < 3; k++)
                if (!(b[k] <= b[3 + k])) return -1;
            leaves++;
            continue;
        }
        internal++;
        const as_bi_node *a = &bi->node[nd->child[0]], *b = &bi->node[nd->child[1]];
        if (a->parent != (int32_t)i || b->parent != (int32_t)i) return -1;
        if (a->height < 0 || b->height < 0) return -1;
        double lo[3], hi[3];
        as_bi_union(a->lo, a->hi, b->lo, b->hi, lo, hi);
        if (memcmp(lo, nd->lo, sizeof lo) || memcmp(hi, nd->hi, sizeof hi)) return -1;
        int h = 1 + (a->height > b->height ? a->height : b->height);
        if (nd->height != h) return -1;
    }
    if (leaves != bi->n || leaves + internal + freed != bi->nused) return -1;
    if (bi->n > 0 && internal != bi->n - 1) return -1;
    if (bi->n == 0 && bi->root != AS_BI_NIL) return -1;
    size_t ids = 0;
    for (size_t id = 0; id < bi->idcap; id++) ids += bi->ent[id].leaf != AS_BI_NIL;
    return ids == bi->n ? 0 : -1;
}
