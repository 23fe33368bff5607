/*
 * kdtree.c — a forest of static kd-trees with incremental insertion (the logarithmic
 * method), k-nearest / radius / box queries. See kdtree.h for the structure and its
 * guarantees.
 */
#include "geom/kdtree.h"

#include <math.h>
#include <string.h>

/* Most trees a forest can hold: the bottom tree has any size, the others hold
 * AS_KD_LEAF * 2^j points for distinct j, so n < 2^31 needs at most 30. */
#define AS_KD_MAX_TREES 64
/* Depth of the explicit stacks: a tree of n < 2^31 points is at most
 * ceil(log2(n / (AS_KD_LEAF / 2))) <= 28 levels deep; a traversal stack holds at most
 * depth + 1 entries. */
#define AS_KD_STACK 64
#define AS_KD_NONE UINT32_MAX

typedef struct as_kd_node {
    double lo[3], hi[3]; /* exact bounding box of the node's points */
    uint32_t begin;      /* first slot */
    uint32_t count;      /* number of slots */
    uint32_t right;      /* index of the right child; 0 for a leaf (left child = index + 1) */
    uint32_t axis;       /* split axis (internal nodes) */
} as_kd_node;

typedef struct as_kd_tree {
    uint32_t begin, count; /* slot range */
    uint32_t node;         /* root node index; the tree's nodes end where the next begins */
} as_kd_tree;

struct as_kdtree {
    as_kdpoint *pts; /* slots: trees in stack order, then the buffer */
    size_t n, cap;
    as_kd_node *nodes;
    size_t nnodes, ncap;
    as_kd_tree trees[AS_KD_MAX_TREES];
    size_t ntrees;
    double blo[3], bhi[3]; /* bounding box of the buffer (when not empty) */
};

/* ---- id lists ----------------------------------------------------------------------- */

void as_idlist_free(anistar_context *ctx, as_idlist *l) {
    as_free(ctx, l->ids, l->cap * sizeof *l->ids);
    l->ids = NULL;
    l->n = l->cap = 0;
}

int as_idlist_push(anistar_context *ctx, as_idlist *l, int32_t id) {
    if (l->n == l->cap) {
        void *p = l->ids;
        if (as_grow(ctx, &p, &l->cap, l->n + 1, sizeof *l->ids)) return -1;
        l->ids = p;
    }
    l->ids[l->n++] = id;
    return 0;
}

static void as_ids_sift(int32_t *a, size_t i, size_t n) {
    int32_t v = a[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && a[c + 1] > a[c]) c++;
        if (a[c] <= v) break;
        a[i] = a[c];
        i = c;
    }
    a[i] = v;
}

void as_ids_sort(int32_t *a, size_t n) {
    if (n < 2) return;
    if (n <= 16) {
        for (size_t i = 1; i < n; i++) {
            int32_t v = a[i];
            size_t j = i;
            while (j > 0 && a[j - 1] > v) {
                a[j] = a[j - 1];
                j--;
            }
            a[j] = v;
        }
        return;
    }
    for (size_t i = n / 2; i-- > 0;) as_ids_sift(a, i, n);
    for (size_t m = n - 1; m > 0; m--) {
        int32_t t = a[0];
        a[0] = a[m];
        a[m] = t;
        as_ids_sift(a, 0, m);
    }
}

/* ---- selection ------------------------------------------------------------------------ */

static inline void as_kp_swap(as_kdpoint *a, ptrdiff_t i, ptrdiff_t j) {
    as_kdpoint t = a[i];
    a[i] = a[j];
    a[j] = t;
}

static void as_kp_sift(as_kdpoint *a, size_t i, size_t n, int axis) {
    as_kdpoint v = a[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && a[c + 1].x[axis] > a[c].x[axis]) c++;
        if (a[c].x[axis] <= v.x[axis]) break;
        a[i] = a[c];
        i = c;
    }
    a[i] = v;
}

/* Heapsort of a[0..n) by coordinate axis (the introselect fallback). */
static void as_kp_heapsort(as_kdpoint *a, size_t n, int axis) {
    for (size_t i = n / 2; i-- > 0;) as_kp_sift(a, i, n, axis);
    for (size_t m = n - 1; m > 0; m--) {
        as_kp_swap(a, 0, (ptrdiff_t)m);
        as_kp_sift(a, 0, m, axis);
    }
}

/*
 * as_kdpoint_select — nth_element on coordinate `axis`.
 * design:
 *   1. Quickselect on [lo, hi] with the median of a[lo], a[mid], a[hi] as pivot (the
 *      three are ordered first, so a[lo] <= pivot <= a[hi] act as sentinels).
 *   2. Hoare partition in which both scans stop on keys equal to the pivot: equal keys
 *      are split evenly, so all-equal inputs cost O(n).
 *   3. Keep the side holding k; stop when k falls between the two sides (it then equals
 *      the pivot). Small ranges are insertion-sorted; after 2 log2 n + 8 rounds the
 *      range is heapsorted (worst case O(n log n), introselect).
 */
void as_kdpoint_select(as_kdpoint *a, size_t n, size_t k, int axis) {
    if (n < 2 || k >= n) return;
    ptrdiff_t lo = 0, hi = (ptrdiff_t)n - 1, kk = (ptrdiff_t)k;
    int budget = 8;
    for (size_t m = n; m > 1; m >>= 1) budget += 2;
    while (hi > lo) {
        if (hi - lo < 12) {
            for (ptrdiff_t i = lo + 1; i <= hi; i++) {
                as_kdpoint v = a[i];
                ptrdiff_t j = i;
                while (j > lo && a[j - 1].x[axis] > v.x[axis]) {
                    a[j] = a[j - 1];
                    j--;
                }
                a[j] = v;
            }
            return;
        }
        if (budget-- <= 0) {
            as_kp_heapsort(a + lo, (size_t)(hi - lo + 1), axis);
            return;
        }
        ptrdiff_t mid = lo + (hi - lo) / 2;
        if (a[mid].x[axis] < a[lo].x[axis]) as_kp_swap(a, mid, lo);
        if (a[hi].x[axis] < a[lo].x[axis]) as_kp_swap(a, hi, lo);
        if (a[hi].x[axis] < a[mid].x[axis]) as_kp_swap(a, hi, mid);
        double piv = a[mid].x[axis];
        ptrdiff_t i = lo, j = hi;
        while (i <= j) {
            while (a[i].x[axis] < piv) i++;
            while (a[j].x[axis] > piv) j--;
            if (i <= j) {
                as_kp_swap(a, i, j);
                i++;
                j--;
            }
        }
        /* now a[lo..j] <= piv <= a[i..hi], and anything between equals piv */
        if (kk <= j)
            hi = j;
        else if (kk >= i)
            lo = i;
        else
            return;
    }
}

/* ---- construction --------------------------------------------------------------------- */

/* Upper bound on the nodes of a tree of c points: 1 for c <= AS_KD_LEAF; otherwise every
 * leaf holds >= AS_KD_LEAF/2 points, so at most 2 c / (AS_KD_LEAF/2) - 1 nodes. */
static size_t as_kd_node_bound(size_t c) {
    return c <= AS_KD_LEAF ? 1 : 4 * c / AS_KD_LEAF;
}

static void as_kd_bbox(const as_kdpoint *p, size_t n, double lo[3], double hi[3]) {
    for (int a = 0; a < 3; a++) lo[a] = hi[a] = p[0].x[a];
    for (size_t i = 1; i < n; i++)
        for (int a = 0; a < 3; a++) {
            double v = p[i].x[a];
            if (v < lo[a]) lo[a] = v;
            if (v > hi[a]) hi[a] = v;
        }
}

/*
 * as_kd_build_range — build one static tree over slots [begin, begin + count) with its
 * nodes from index kd->nnodes on (capacity must already hold as_kd_node_bound(count)).
 * design:
 *   1. An explicit stack of (slot range, parent-waiting-for-its-right-child); a node's
 *      index is taken when it is popped and the left range is pushed last, so nodes come
 *      out in preorder (left child = index + 1).
 *   2. Each node gets the exact box of its points; a range above AS_KD_LEAF points is
 *      split at its median (count/2) along the widest axis of the box.
 */
static void as_kd_build_range(as_kdtree *kd, uint32_t begin, uint32_t count) {
    struct {
        uint32_t begin, count, parent;
    } st[AS_KD_STACK];
    int sp = 0;
    st[sp].begin = begin;
    st[sp].count = count;
    st[sp].parent = AS_KD_NONE;
    sp++;
    while (sp > 0) {
        sp--;
        uint32_t b = st[sp].begin, c = st[sp].count, parent = st[sp].parent;
        uint32_t ni = (uint32_t)kd->nnodes++;
        as_kd_node *nd = &kd->nodes[ni];
        if (parent != AS_KD_NONE) kd->nodes[parent].right = ni;
        as_kd_bbox(kd->pts + b, c, nd->lo, nd->hi);
        nd->begin = b;
        nd->count = c;
        nd->right = 0;
        nd->axis = 0;
        if (c <= AS_KD_LEAF) continue;
        int axis = 0;
        double w = nd->hi[0] - nd->lo[0];
        for (int a = 1; a < 3; a++)
            if (nd->hi[a] - nd->lo[a] > w) {
                w = nd->hi[a] - nd->lo[a];
                axis = a;
            }
        nd->axis = (uint32_t)axis;
        uint32_t half = c / 2;
        as_kdpoint_select(kd->pts + b, c, half, axis);
        st[sp].begin = b + half;
        st[sp].count = c - half;
        st[sp].parent = ni;
        sp++;
        st[sp].begin = b;
        st[sp].count = half;
        st[sp].parent = AS_KD_NONE;
        sp++;
    }
}

static size_t as_kd_buffer_begin(const as_kdtree *kd) {
    if (kd->ntrees == 0) return 0;
    const as_kd_tree *t = &kd->trees[kd->ntrees - 1];
    return (size_t)t->begin + t->count;
}

anistar_status as_kdtree_new(anistar_context *ctx, as_kdtree **out) {
    *out = NULL;
    as_kdtree *kd = as_alloc(ctx, sizeof *kd);
    if (!kd) return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory");
    memset(kd, 0, sizeof *kd);
    *out = kd;
    return ANISTAR_OK;
}

void as_kdtree_free(anistar_context *ctx, as_kdtree *kd) {
    if (!kd) return;
    as_free(ctx, kd->pts, kd->cap * sizeof *kd->pts);
    as_free(ctx, kd->nodes, kd->ncap * sizeof *kd->nodes);
    as_free(ctx, kd, sizeof *kd);
}

static int as_kd_grow_pts(anistar_context *ctx, as_kdtree *kd, size_t need) {
    void *p = kd->pts;
    if (as_grow(ctx, &p, &kd->cap, need, sizeof *kd->pts)) return -1;
    kd->pts = p;
    return 0;
}

static int as_kd_grow_nodes(anistar_context *ctx, as_kdtree *kd, size_t need) {
    void *p = kd->nodes;
    if (as_grow(ctx, &p, &kd->ncap, need, sizeof *kd->nodes)) return -1;
    kd->nodes = p;
    return 0;
}

static int as_kd_finite3(const double p[3]) {
    return isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2]);
}

anistar_status as_kdtree_build(anistar_context *ctx, const double *xyz, const int32_t *ids,
                               size_t n, as_kdtree **out) {
    *out = NULL;
    if (n >= (size_t)INT32_MAX || (n > 0 && !xyz))
        return as_fail(ctx, ANISTAR_EINVAL, "kdtree: invalid point array (n = %zu)", n);
    for (size_t i = 0; i < n; i++) {
        if (!as_kd_finite3(xyz + 3 * i))
            return as_fail(ctx, ANISTAR_EINVAL, "kdtree: point %zu is not finite", i);
        if (ids && ids[i] < 0)
            return as_fail(ctx, ANISTAR_EINVAL, "kdtree: negative id %d", (int)ids[i]);
    }
    as_kdtree *kd;
    anistar_status st = as_kdtree_new(ctx, &kd);
    if (st) return st;
    if (n == 0) {
        *out = kd;
        return ANISTAR_OK;
    }
    if (as_kd_grow_pts(ctx, kd, n) || as_kd_grow_nodes(ctx, kd, as_kd_node_bound(n))) {
        as_kdtree_free(ctx, kd);
        return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory for %zu points", n);
    }
    for (size_t i = 0; i < n; i++) {
        memcpy(kd->pts[i].x, xyz + 3 * i, sizeof kd->pts[i].x);
        kd->pts[i].id = ids ? ids[i] : (int32_t)i;
    }
    kd->n = n;
    as_kd_build_range(kd, 0, (uint32_t)n);
    kd->trees[0].begin = 0;
    kd->trees[0].count = (uint32_t)n;
    kd->trees[0].node = 0;
    kd->ntrees = 1;
    *out = kd;
    return ANISTAR_OK;
}

anistar_status as_kdtree_reserve(anistar_context *ctx, as_kdtree *kd, size_t more) {
    if (more > (size_t)INT32_MAX - kd->n)
        return as_fail(ctx, ANISTAR_EINVAL, "kdtree: cannot reserve %zu more points", more);
    /* Nodes: the whole forest never needs more than the bound of all its points plus
     * one per tree (each tree's bound is rounded independently). */
    size_t total = kd->n + more;
    if (as_kd_grow_pts(ctx, kd, total) ||
        as_kd_grow_nodes(ctx, kd, as_kd_node_bound(total) + AS_KD_MAX_TREES))
        return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory reserving %zu points",
                       total);
    return ANISTAR_OK;
}

/*
 * as_kdtree_insert — append p to the buffer; a full buffer becomes a tree and merges.
 * design:
 *   1. Plan first: if the buffer becomes full, the new tree covers the buffer and, while
 *      the tree below it holds no more points than it, that tree too (the logarithmic
 *      method's carry). Its nodes replace those of the merged trees.
 *   2. Grow the slot and node arrays for the plan (failure: nothing changed).
 *   3. Append the point; build the planned tree over the suffix of slots.
 */
anistar_status as_kdtree_insert(anistar_context *ctx, as_kdtree *kd, const double p[3],
                                int32_t id) {
    if (!as_kd_finite3(p)) return as_fail(ctx, ANISTAR_EINVAL, "kdtree: point not finite");
    if (id < 0) return as_fail(ctx, ANISTAR_EINVAL, "kdtree: negative id %d", (int)id);
    if (kd->n + 1 >= (size_t)INT32_MAX)
        return as_fail(ctx, ANISTAR_EINVAL, "kdtree: too many points");
    size_t bbeg = as_kd_buffer_begin(kd);
    size_t bn = kd->n - bbeg + 1; /* buffer size after appending */
    size_t keep = kd->ntrees;     /* trees kept below the new one */
    size_t tbeg = bbeg, tcount = bn, node0 = kd->nnodes;
    int build = bn >= AS_KD_LEAF;
    if (build) {
        while (keep > 0 && kd->trees[keep - 1].count <= tcount) {
            keep--;
            tbeg = kd->trees[keep].begin;
            tcount += kd->trees[keep].count;
            node0 = kd->trees[keep].node;
        }
        if (keep == AS_KD_MAX_TREES)
            return as_fail(ctx, ANISTAR_EINTERNAL, "kdtree: forest too deep");
    }
    if (as_kd_grow_pts(ctx, kd, kd->n + 1) ||
        (build && as_kd_grow_nodes(ctx, kd, node0 + as_kd_node_bound(tcount))))
        return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory inserting point %zu",
                       kd->n);
    as_kdpoint *s = &kd->pts[kd->n++];
    memcpy(s->x, p, sizeof s->x);
    s->id = id;
    if (!build) {
        for (int a = 0; a < 3; a++) {
            if (bn == 1 || p[a] < kd->blo[a]) kd->blo[a] = p[a];
            if (bn == 1 || p[a] > kd->bhi[a]) kd->bhi[a] = p[a];
        }
        return ANISTAR_OK;
    }
    kd->nnodes = node0;
    as_kd_build_range(kd, (uint32_t)tbeg, (uint32_t)tcount);
    kd->trees[keep].begin = (uint32_t)tbeg;
    kd->trees[keep].count = (uint32_t)tcount;
    kd->trees[keep].node = (uint32_t)node0;
    kd->ntrees = keep + 1;
    return ANISTAR_OK;
}

size_t as_kdtree_size(const as_kdtree *kd) { return kd->n; }
size_t as_kdtree_tree_count(const as_kdtree *kd) { return kd->ntrees; }

/* ---- queries -------------------------------------------------------------------------- */

/* Squared distance, the one formula used everywhere (see kdtree.h). */
static inline double as_kd_d2(const double x[3], const double q[3]) {
    double dx = x[0] - q[0], dy = x[1] - q[1], dz = x[2] - q[2];
    return (dx * dx + dy * dy) + dz * dz;
}

/* Squared distance from q to the box: a lower bound of as_kd_d2 for every point of the
 * box, also in floating point (each gap is a rounded difference no larger than the
 * point's, and rounding is monotone). */
static inline double as_kd_box_d2(const double lo[3], const double hi[3], const double q[3]) {
    double g[3];
    for (int a = 0; a < 3; a++) {
        if (q[a] < lo[a])
            g[a] = lo[a] - q[a];
        else if (q[a] > hi[a])
            g[a] = q[a] - hi[a];
        else
            g[a] = 0;
    }
    return (g[0] * g[0] + g[1] * g[1]) + g[2] * g[2];
}

/* Squared distance from q to the farthest corner of the box: an upper bound of as_kd_d2
 * for every point of the box, in floating point too. */
static inline double as_kd_box_far_d2(const double lo[3], const double hi[3],
                                      const double q[3]) {
    double g[3];
    for (int a = 0; a < 3; a++) {
        double u = fabs(lo[a] - q[a]), v = fabs(hi[a] - q[a]);
        g[a] = u > v ? u : v;
    }
    return (g[0] * g[0] + g[1] * g[1]) + g[2] * g[2];
}

/* (d2, id) lexicographic order. */
static inline int as_kd_less(double da, int32_t ia, double db, int32_t ib) {
    return da < db || (da == db && ia < ib);
}

typedef struct as_kd_heap {
    int32_t *ids;
    double *d2;
    size_t n, k;
} as_kd_heap;

static void as_kd_heap_sift_down(as_kd_heap *h, size_t i, size_t n) {
    int32_t vi = h->ids[i];
    double vd = h->d2[i];
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n && as_kd_less(h->d2[c], h->ids[c], h->d2[c + 1], h->ids[c + 1])) c++;
        if (!as_kd_less(vd, vi, h->d2[c], h->ids[c])) break;
        h->ids[i] = h->ids[c];
        h->d2[i] = h->d2[c];
        i = c;
    }
    h->ids[i] = vi;
    h->d2[i] = vd;
}

/* Offer a candidate to the max-heap of the k best. */
static inline void as_kd_heap_offer(as_kd_heap *h, double d2, int32_t id) {
    if (h->n < h->k) {
        size_t i = h->n++;
        while (i > 0) {
            size_t parent = (i - 1) / 2;
            if (!as_kd_less(h->d2[parent], h->ids[parent], d2, id)) break;
            h->ids[i] = h->ids[parent];
            h->d2[i] = h->d2[parent];
            i = parent;
        }
        h->ids[i] = id;
        h->d2[i] = d2;
    } else if (as_kd_less(d2, id, h->d2[0], h->ids[0])) {
        h->ids[0] = id;
        h->d2[0] = d2;
        as_kd_heap_sift_down(h, 0, h->n);
    }
}

/* A node may hold a better candidate unless the heap is full and the node's lower bound
 * exceeds the worst kept distance (equal bounds must be visited: a smaller id may tie). */
static inline int as_kd_heap_wants(const as_kd_heap *h, double bound) {
    return h->n < h->k || bound <= h->d2[0];
}

/*
 * as_kdtree_knn — best-first descent in each tree of the forest and a scan of the buffer,
 * sharing one bounded max-heap.
 * design:
 *   1. Explicit stack of (node, lower bound); at an internal node both children's box
 *      distances are computed and the nearer is pushed last (visited first).
 *   2. Entries popped with a bound beyond the current k-th distance are dropped.
 *   3. Heapsort the heap in place: ascending (d2, id).
 */
size_t as_kdtree_knn(const as_kdtree *kd, const double q[3], size_t k, int32_t *ids,
                     double *d2) {
    if (k == 0 || kd->n == 0 || !as_kd_finite3(q)) return 0;
    as_kd_heap h = {ids, d2, 0, k};
    struct {
        uint32_t node;
        double bound;
    } st[AS_KD_STACK];
    for (size_t t = 0; t < kd->ntrees; t++) {
        uint32_t root = kd->trees[t].node;
        double rb = as_kd_box_d2(kd->nodes[root].lo, kd->nodes[root].hi, q);
        if (!as_kd_heap_wants(&h, rb)) continue;
        int sp = 0;
        st[sp].node = root;
        st[sp].bound = rb;
        sp++;
        while (sp > 0) {
            sp--;
            if (!as_kd_heap_wants(&h, st[sp].bound)) continue;
            const as_kd_node *nd = &kd->nodes[st[sp].node];
            if (nd->right == 0) {
                const as_kdpoint *p = kd->pts + nd->begin;
                for (uint32_t i = 0; i < nd->count; i++)
                    as_kd_heap_offer(&h, as_kd_d2(p[i].x, q), p[i].id);
                continue;
            }
            uint32_t l = st[sp].node + 1, r = nd->right;
            double bl = as_kd_box_d2(kd->nodes[l].lo, kd->nodes[l].hi, q);
            double br = as_kd_box_d2(kd->nodes[r].lo, kd->nodes[r].hi, q);
            uint32_t nearer = l, farther = r;
            double bn = bl, bf = br;
            if (br < bl) {
                nearer = r;
                farther = l;
                bn = br;
                bf = bl;
            }
            if (as_kd_heap_wants(&h, bf)) {
                st[sp].node = farther;
                st[sp].bound = bf;
                sp++;
            }
            if (as_kd_heap_wants(&h, bn)) {
                st[sp].node = nearer;
                st[sp].bound = bn;
                sp++;
            }
        }
    }
    size_t bbeg = as_kd_buffer_begin(kd);
    if (bbeg < kd->n && as_kd_heap_wants(&h, as_kd_box_d2(kd->blo, kd->bhi, q)))
        for (size_t i = bbeg; i < kd->n; i++)
            as_kd_heap_offer(&h, as_kd_d2(kd->pts[i].x, q), kd->pts[i].id);
    size_t m = h.n;
    for (size_t e = m; e > 1; e--) {
        int32_t ti = ids[0];
        double td = d2[0];
        ids[0] = ids[e - 1];
        d2[0] = d2[e - 1];
        ids[e - 1] = ti;
        d2[e - 1] = td;
        as_kd_heap_sift_down(&h, 0, e - 1);
    }
    return m;
}

/* Range queries: the region is a closed ball (d2 <= r2) or a closed box. */
typedef struct as_kd_range {
    int ball;
    double q[3], r2;
    double lo[3], hi[3];
} as_kd_range;

/* 0: the node's box misses the region; 1: it may meet it; 2: it lies inside it. */
static inline int as_kd_range_class(const as_kd_range *rg, const double lo[3],
                                    const double hi[3]) {
    if (rg->ball) {
        if (as_kd_box_d2(lo, hi, rg->q) > rg->r2) return 0;
        return as_kd_box_far_d2(lo, hi, rg->q) <= rg->r2 ? 2 : 1;
    }
    int inside = 1;
    for (int a = 0; a < 3; a++) {
        if (hi[a] < rg->lo[a] || lo[a] > rg->hi[a]) return 0;
        if (lo[a] < rg->lo[a] || hi[a] > rg->hi[a]) inside = 0;
    }
    return inside ? 2 : 1;
}

static inline int as_kd_range_has(const as_kd_range *rg, const double x[3]) {
    if (rg->ball) return as_kd_d2(x, rg->q) <= rg->r2;
    for (int a = 0; a < 3; a++)
        if (x[a] < rg->lo[a] || x[a] > rg->hi[a]) return 0;
    return 1;
}

/* design: room for the c slots first, then plain stores (one growth check per node, not
 * per point) */
static int as_kd_range_slots(anistar_context *ctx, const as_kdtree *kd, size_t b, size_t c,
                             int all, const as_kd_range *rg, as_idlist *out) {
    if (out->n + c > out->cap) {
        void *p = out->ids;
        if (as_grow(ctx, &p, &out->cap, out->n + c, sizeof *out->ids)) return -1;
        out->ids = p;
    }
    int32_t *ids = out->ids;
    size_t n = out->n;
    const as_kdpoint *pts = kd->pts;
    if (all) {
        for (size_t i = b; i < b + c; i++) ids[n++] = pts[i].id;
    } else {
        for (size_t i = b; i < b + c; i++)
            if (as_kd_range_has(rg, pts[i].x)) ids[n++] = pts[i].id;
    }
    out->n = n;
    return 0;
}

static anistar_status as_kd_range_query(anistar_context *ctx, const as_kdtree *kd,
                                        const as_kd_range *rg, int sorted, as_idlist *out) {
    out->n = 0;
    uint32_t st[AS_KD_STACK];
    for (size_t t = 0; t < kd->ntrees; t++) {
        int sp = 0;
        st[sp++] = kd->trees[t].node;
        while (sp > 0) {
            uint32_t ni = st[--sp];
            const as_kd_node *nd = &kd->nodes[ni];
            int cl = as_kd_range_class(rg, nd->lo, nd->hi);
            if (cl == 0) continue;
            if (cl == 2 || nd->right == 0) {
                if (as_kd_range_slots(ctx, kd, nd->begin, nd->count, cl == 2, rg, out))
                    return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory in a query");
                continue;
            }
            st[sp++] = nd->right;
            st[sp++] = ni + 1;
        }
    }
    size_t bbeg = as_kd_buffer_begin(kd);
    if (bbeg < kd->n && as_kd_range_class(rg, kd->blo, kd->bhi) != 0 &&
        as_kd_range_slots(ctx, kd, bbeg, kd->n - bbeg, 0, rg, out))
        return as_fail(ctx, ANISTAR_ENOMEM, "kdtree: out of memory in a query");
    if (sorted) as_ids_sort(out->ids, out->n);
    return ANISTAR_OK;
}

anistar_status as_kdtree_radius(anistar_context *ctx, const as_kdtree *kd, const double q[3],
                                double r, as_idlist *out) {
    out->n = 0;
    if (!(r >= 0) || !as_kd_finite3(q)) return ANISTAR_OK;
    as_kd_range rg;
    memset(&rg, 0, sizeof rg);
    rg.ball = 1;
    memcpy(rg.q, q, sizeof rg.q);
    rg.r2 = r * r;
    return as_kd_range_query(ctx, kd, &rg, 1, out);
}

anistar_status as_kdtree_box(anistar_context *ctx, const as_kdtree *kd, const double lo[3],
                             const double hi[3], as_idlist *out) {
    return as_kdtree_box_any(ctx, kd, lo, hi, 1, out);
}

anistar_status as_kdtree_box_any(anistar_context *ctx, const as_kdtree *kd, const double lo[3],
                                 const double hi[3], int sorted, as_idlist *out) {
    out->n = 0;
    for (int a = 0; a < 3; a++)
        if (!(lo[a] <= hi[a])) return ANISTAR_OK; /* empty (or NaN) box */
    as_kd_range rg;
    memset(&rg, 0, sizeof rg);
    memcpy(rg.lo, lo, sizeof rg.lo);
    memcpy(rg.hi, hi, sizeof rg.hi);
    return as_kd_range_query(ctx, kd, &rg, sorted, out);
}

/* ---- validation ----------------------------------------------------------------------- */

int as_kdtree_check(const as_kdtree *kd) {
    size_t slot = 0, node = 0;
    for (size_t t = 0; t < kd->ntrees; t++) {
        const as_kd_tree *tr = &kd->trees[t];
        if (tr->begin != slot || tr->node != node || tr->count == 0) return -1;
        if (t > 0 && kd->trees[t - 1].count <= tr->count) return -1;
        size_t end_node = t + 1 < kd->ntrees ? kd->trees[t + 1].node : kd->nnodes;
        for (size_t ni = node; ni < end_node; ni++) {
            const as_kd_node *nd = &kd->nodes[ni];
            if (nd->begin < tr->begin || (size_t)nd->begin + nd->count > (size_t)tr->begin + tr->count)
                return -1;
            if (nd->count == 0) return -1;
            double lo[3], hi[3];
            as_kd_bbox(kd->pts + nd->begin, nd->count, lo, hi);
            for (int a = 0; a < 3; a++)
                if (lo[a] != nd->lo[a] || hi[a] != nd->hi[a]) return -1;
            if (nd->right == 0) {
                if (nd->count > AS_KD_LEAF) return -1;
                continue;
            }
            if (nd->count <= AS_KD_LEAF || nd->right <= ni + 1 || nd->right >= end_node)
                return -1;
            const as_kd_node *l = &kd->nodes[ni + 1], *r = &kd->nodes[nd->right];
            if (l->begin != nd->begin || l->count != nd->count / 2 ||
                r->begin != nd->begin + l->count || r->count != nd->count - l->count)
                return -1;
            if (l->hi[nd->axis] > r->lo[nd->axis]) return -1; /* median property */
        }
        slot += tr->count;
        node = end_node;
    }
    if (node != kd->nnodes || slot > kd->n || kd->n - slot >= AS_KD_LEAF) return -1;
    for (size_t i = 0; i < kd->n; i++)
        if (kd->pts[i].id < 0) return -1;
    if (slot < kd->n) {
        double lo[3], hi[3];
        as_kd_bbox(kd->pts + slot, kd->n - slot, lo, hi);
        for (int a = 0; a < 3; a++)
            if (lo[a] != kd->blo[a] || hi[a] != kd->bhi[a]) return -1;
    }
    return 0;
}

/* ---- farthest-point order ------------------------------------------------------------- */

/* design (as_farthest_order): every node of a kd-tree of the points keeps the largest
 * distance to the picks among its points (with the lowest index holding it), so the next
 * pick is the root's, and after a pick at x only the nodes whose box is not farther from x
 * than their largest distance are entered (no point of any other can get nearer: the box
 * distance is a lower bound of the point distances in floating point too, both summing
 * the same per-axis squares in the same order); the entered leaves' distances are updated
 * and the maxima recomputed on the way back. The order is the scan's. It replaced a
 * radius query at the largest distance plus a lazy heap, whose queries returned (and
 * sorted) ~n/k points at the k-th pick: on the shock sphere the feature sampler's 4,096
 * picks among 32,768 candidates took 5% of a run with 2 threads, all of it serial. */

/* The largest distance to the picks in a node and the lowest index holding it. */
typedef struct kd_far {
    double d;
    int32_t i;
} kd_far;

/* a before b: the farther, then the lower index (the first maximum of a scan) */
static inline int kd_far_before(const kd_far *a, const kd_far *b) {
    return a->d > b->d || (a->d == b->d && a->i < b->i);
}

static inline double kd_d2(const double *a, const double *b) {
    double d0 = a[0] - b[0], d1 = a[1] - b[1], d2 = a[2] - b[2];
    return d0 * d0 + d1 * d1 + d2 * d2;
}

/* After a pick at x: update the distances dist (picked points: -1) of the points of node
 * ni and its subtree that can get nearer, and the nodes' maxima fm. Depth: the tree's. */
static void kd_far_visit(const as_kdtree *kd, uint32_t ni, const double x[3], double *dist,
                         kd_far *fm) {
    const as_kd_node *nd = &kd->nodes[ni];
    if (as_kd_box_d2(nd->lo, nd->hi, x) > fm[ni].d) return;
    if (nd->right == 0) {
        kd_far best = {-1, INT32_MAX};
        for (uint32_t k = nd->begin; k < nd->begin + nd->count; k++) {
            const int32_t i = kd->pts[k].id;
            if (dist[i] < 0) continue;
            double d = kd_d2(kd->pts[k].x, x);
            if (d < dist[i]) dist[i] = d;
            kd_far c = {dist[i], i};
            if (kd_far_before(&c, &best)) best = c;
        }
        fm[ni] = best;
        return;
    }
    kd_far_visit(kd, ni + 1, x, dist, fm);
    kd_far_visit(kd, nd->right, x, dist, fm);
    fm[ni] = kd_far_before(&fm[ni + 1], &fm[nd->right]) ? fm[ni + 1] : fm[nd->right];
}

anistar_status as_farthest_order(anistar_context *ctx, const double *xyz, size_t n, size_t q,
                                 int32_t *out, size_t *nout) {
    *nout = 0;
    if (n == 0 || q == 0) return ANISTAR_OK;
    if (q > n) q = n;
    for (size_t i = 0; i < 3 * n; i++)
        if (!isfinite(xyz[i]))
            return as_fail(ctx, ANISTAR_EINVAL, "kd-tree: point %zu is not finite", i / 3);
    out[(*nout)++] = 0;
    if (q == 1) return ANISTAR_OK;
    double *dist = as_alloc_array(ctx, n, sizeof *dist);
    if (!dist) return as_fail(ctx, ANISTAR_ENOMEM, "kd-tree: out of memory (farthest points)");
    as_kdtree *kd = NULL;
    kd_far *fm = NULL;
    anistar_status rs = as_kdtree_build(ctx, xyz, NULL, n, &kd);
    if (rs == ANISTAR_OK && !(fm = as_alloc_array(ctx, kd->nnodes, sizeof *fm)))
        rs = as_fail(ctx, ANISTAR_ENOMEM, "kd-tree: out of memory (farthest points)");
    if (rs == ANISTAR_OK) {
        /* a fresh build is one tree of every point (root node 0), no buffer */
        for (size_t i = 0; i < n; i++) dist[i] = INFINITY;
        for (size_t k = 0; k < kd->nnodes; k++) fm[k] = (kd_far){INFINITY, 0};
        size_t cur = 0;
        for (;;) {
            dist[cur] = -1;
            if (*nout == q) break;
            kd_far_visit(kd, kd->trees[0].node, xyz + 3 * cur, dist, fm);
            if (fm[kd->trees[0].node].d < 0) break; /* every point picked */
            cur = (size_t)fm[kd->trees[0].node].i;
            out[(*nout)++] = (int32_t)cur;
        }
    }
    if (kd) as_free(ctx, fm, kd->nnodes * sizeof *fm);
    as_kdtree_free(ctx, kd);
    as_free(ctx, dist, n * sizeof *dist);
    return rs;
}
