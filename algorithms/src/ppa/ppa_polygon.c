/*
 * ppa_polygon.c - PPA step 3, polygon breaking (Zhou et al. 2007 section 3,
 * Fig. 4c).
 *
 * Chang's rule removes the least important segment of every closed polygon
 * until none is left.  With segments totally ordered by (weight descending,
 * index ascending) the result of that rule is unique and equals the maximum
 * spanning forest of the segment graph (the cycle property), so it is
 * computed here with Kruskal's algorithm: segments sorted by a stable LSD
 * radix sort on the weight, then a union-find with path halving and union
 * by size.  tests/c/ppa/test_ppa.c checks it against naive repeated polygon
 * breaking on random DEMs.
 * Cost: O(n) sort + O(n alpha(n)) union-find; memory 12 bytes/segment +
 * 8 bytes/cell.
 *
 * ppa_spanning_forest, the pipeline's way, runs on every thread: the rows
 * are cut into strips, each strip's own forest made by its own sort and
 * Kruskal side by side (strips share no cell), then shrunk to what matters
 * across strips (twigs reaching no strip border are final; the rest is
 * contracted to its junctions and border cells, each path weighted by its
 * least important segment, the only one a cycle through it can lose), and
 * one Kruskal over the contracted paths and the segments between strips
 * says which segments go: the same forest on any number of strips (it is
 * unique), as ppa_tiled.c does across tiles.
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

#define polygon_key ppa_weight_key

/* Stable LSD radix sort of segment indices by key, 4 passes of 8 bits. */
static ts_status polygon_sort(const ts_ppa_segment *segs, size_t n, uint32_t *order)
{
    uint32_t *keys = ts__malloc_array(n, sizeof *keys);
    uint32_t *tmp_keys = ts__malloc_array(n, sizeof *tmp_keys);
    uint32_t *tmp_order = ts__malloc_array(n, sizeof *tmp_order);
    size_t i;
    int pass;
    if (!keys || !tmp_keys || !tmp_order) {
        free(keys);
        free(tmp_keys);
        free(tmp_order);
        return TS_ERR_NOMEM;
    }
    for (i = 0; i < n; i++) {
        keys[i] = polygon_key(segs[i].weight);
        order[i] = (uint32_t)i;
    }
    for (pass = 0; pass < 4; pass++) {
        size_t count[257] = {0};
        int shift = pass * 8, b;
        for (i = 0; i < n; i++)
            count[((keys[i] >> shift) & 0xffu) + 1]++;
        for (b = 0; b < 256; b++)
            count[b + 1] += count[b];
        for (i = 0; i < n; i++) {
            size_t dst = count[(keys[i] >> shift) & 0xffu]++;
            tmp_keys[dst] = keys[i];
            tmp_order[dst] = order[i];
        }
        memcpy(keys, tmp_keys, n * sizeof *keys);
        memcpy(order, tmp_order, n * sizeof *order);
    }
    free(keys);
    free(tmp_keys);
    free(tmp_order);
    return TS_OK;
}

TS_API ts_status ts_ppa_polygon_breaking(ts_ctx *ctx, const ts_ppa_segment *segs, size_t n_segs,
                                         size_t n_cells, unsigned char *keep)
{
    uint32_t *order = NULL, *parent = NULL, *size = NULL;
    size_t i;
    ts__clear(ctx);
    if ((!segs && n_segs) || (!keep && n_segs))
        return ts__fail(ctx, TS_ERR_ARG, "ppa polygon breaking", "missing segments or output");
    if (n_cells >= UINT32_MAX || n_segs >= UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa polygon breaking", "too many cells or segments");
    for (i = 0; i < n_segs; i++)
        if (segs[i].a >= n_cells || segs[i].b >= n_cells || segs[i].a == segs[i].b ||
            isnan(segs[i].weight))
            return ts__fail(ctx, TS_ERR_ARG, "ppa polygon breaking", "segment %zu is invalid", i);
    if (n_segs == 0)
        return TS_OK;
    order = ts__malloc_array(n_segs, sizeof *order);
    parent = ts__malloc_array(n_cells, sizeof *parent);
    size = ts__calloc_array(n_cells, sizeof *size);
    if (!order || !parent || !size || polygon_sort(segs, n_segs, order) != TS_OK) {
        free(order);
        free(parent);
        free(size);
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking",
                        "cannot allocate for %zu segments", n_segs);
    }
    for (i = 0; i < n_cells; i++) {
        parent[i] = (uint32_t)i;
        size[i] = 1;
    }
    memset(keep, 0, n_segs);
    for (i = 0; i < n_segs; i++) {
        const ts_ppa_segment *s = &segs[order[i]];
        uint32_t ra = ppa_uf_find(parent, s->a), rb = ppa_uf_find(parent, s->b);
        if (ra == rb)
            continue; /* would close a polygon: this is its least important segment */
        if (size[ra] < size[rb]) {
            uint32_t t = ra;
            ra = rb;
            rb = t;
        }
        parent[rb] = ra;
        size[ra] += size[rb];
        keep[order[i]] = 1;
        if ((i & 0xfffff) == 0 &&
            ts__progress(ctx, (double)i / (double)n_segs, "polygon breaking") != TS_OK)
            break;
    }
    free(order);
    free(parent);
    free(size);
    if (ctx->status != TS_OK)
        return ctx->status;
    return ts__progress(ctx, 1.0, "polygon breaking");
}

/* ------------------------------------------------------------------ */
/* Steps 2 and 3 at once, lean                                         */
/* ------------------------------------------------------------------ */

/* A segment as one 64-bit item: the inverted weight key above, its index
 * in target connection's order (cell a x 4 + k) below, so that ascending
 * items are the total order (weight descending, index ascending). */
static uint64_t forest_item(const ts_raster *dem, float sign, size_t a, int k)
{
    int w = dem->width;
    size_t b = a + (size_t)((ptrdiff_t)ppa_connect_step[k][1] * w + ppa_connect_step[k][0]);
    float wt = sign * (TS_PIX(dem, a % (size_t)w, a / (size_t)w) +
                       TS_PIX(dem, b % (size_t)w, b / (size_t)w));
    return (uint64_t)polygon_key(wt) << 32 | (uint64_t)(a * 4 + (size_t)k);
}

typedef struct forest_job {
    const ts_raster *dem;
    const unsigned char *targets;
    int kind, phase;
    float sign;
    unsigned char *seg; /* bits 0-3: segment k exists; 4-7: segment k left out */
    size_t *row_count;
    uint64_t *items;
} forest_job;

static void forest_exists(void *arg, size_t begin, size_t end)
{
    forest_job *j = arg;
    int w = j->dem->width, x, k;
    size_t y;
    for (y = begin; y < end; y++)
        for (x = 0; x < w; x++) {
            size_t a = y * (size_t)w + (size_t)x;
            unsigned char bits = 0;
            if (j->targets[a] & j->kind)
                for (k = 0; k < 4; k++)
                    if (ppa_segment_exists(j->dem, j->targets, j->kind, x, (int)y, k, j->sign))
                        bits |= (unsigned char)(1u << k);
            j->seg[a] = bits;
        }
}

/* Leave out the least important segment of every triangle of one 2 x 2
 * block (cycle property: it is in no maximum spanning forest).  Blocks of
 * rows of one parity at a time, so no two threads touch one row. */
static void forest_triangles(void *arg, size_t begin, size_t end)
{
    forest_job *j = arg;
    int w = j->dem->width, x;
    size_t r;
    for (r = begin; r < end; r++) {
        size_t y = 2 * r + (size_t)j->phase;
        if (y + 1 >= (size_t)j->dem->height)
            continue;
        for (x = 0; x + 1 < w; x++) {
            size_t A = y * (size_t)w + (size_t)x, B = A + 1, C = A + (size_t)w; /* D = C + 1 */
            /* the block's six segments as (cell, k): AB, CD, AC, BD, AD, BC */
            const size_t cell[6] = {A, C, A, B, A, B};
            const int kk[6] = {0, 0, 2, 2, 3, 1};
            /* triangles by segment number: AD with AB, BD and with AC, CD; BC with AB, AC
             * and with BD, CD */
            static const int tri[4][3] = {{4, 0, 3}, {4, 2, 1}, {5, 0, 2}, {5, 3, 1}};
            int present[6], t, i;
            for (i = 0; i < 6; i++)
                present[i] = (j->seg[cell[i]] >> kk[i]) & 1;
            for (t = 0; t < 4; t++) {
                uint64_t worst = 0;
                int wi = -1;
                if (!present[tri[t][0]] || !present[tri[t][1]] || !present[tri[t][2]])
                    continue;
                for (i = 0; i < 3; i++) {
                    int s = tri[t][i];
                    uint64_t it = forest_item(j->dem, j->sign, cell[s], kk[s]);
                    if (wi < 0 || it > worst) {
                        worst = it;
                        wi = s;
                    }
                }
                j->seg[cell[wi]] |= (unsigned char)(16u << kk[wi]);
            }
        }
    }
}

static void forest_count(void *arg, size_t begin, size_t end)
{
    forest_job *j = arg;
    int w = j->dem->width, x;
    size_t y;
    for (y = begin; y < end; y++) {
        size_t c = 0;
        for (x = 0; x < w; x++) {
            unsigned char s = j->seg[y * (size_t)w + (size_t)x];
            c += (size_t)__builtin_popcount((unsigned)(s & ~(s >> 4) & 15u));
        }
        j->row_count[y] = c;
    }
}

static void forest_fill(void *arg, size_t begin, size_t end)
{
    forest_job *j = arg;
    int w = j->dem->width, x, k;
    size_t y;
    for (y = begin; y < end; y++) {
        size_t o = j->row_count[y];
        for (x = 0; x < w; x++) {
            size_t a = y * (size_t)w + (size_t)x;
            unsigned char s = (unsigned char)(j->seg[a] & ~(j->seg[a] >> 4) & 15u);
            for (k = 0; k < 4; k++)
                if (s & (1u << k))
                    j->items[o++] = forest_item(j->dem, j->sign, a, k);
        }
    }
}

/* Stable LSD radix sort of items[0, n) on their keys (the high 32 bits),
 * through tmp (the two swap roles each pass); the sorted items end in items. */
static void forest_sort(uint64_t *items, uint64_t *tmp, size_t n)
{
    uint64_t *src = items, *dst = tmp;
    int pass;
    size_t i;
    for (pass = 0; pass < 4 && n; pass++) {
        size_t count[257] = {0};
        int shift = 32 + pass * 8, b;
        uint64_t *t;
        for (i = 0; i < n; i++)
            count[((src[i] >> shift) & 0xffu) + 1]++;
        if (count[((src[0] >> shift) & 0xffu) + 1] == n)
            continue; /* one bucket: nothing moves */
        for (b = 0; b < 256; b++)
            count[b + 1] += count[b];
        for (i = 0; i < n; i++)
            dst[count[(src[i] >> shift) & 0xffu]++] = src[i];
        t = src;
        src = dst;
        dst = t;
    }
    if (src != items)
        memcpy(items, src, n * sizeof *items);
}

/* The cell at the other end of item's segment. */
static uint32_t forest_item_b(uint64_t item, int w)
{
    uint32_t idx = (uint32_t)item, a = idx >> 2;
    int k = (int)(idx & 3u);
    return (uint32_t)((int64_t)a + (int64_t)ppa_connect_step[k][1] * w + ppa_connect_step[k][0]);
}

/* Kruskal over sorted items: union-find with path halving and union by
 * rank; the segments kept go into adj.  Returns nonzero if cancelled. */
static int forest_kruskal(const ts_ctx *ctx, const uint64_t *items, size_t n, int w,
                          uint32_t *parent, unsigned char *rank, unsigned char *adj)
{
    size_t i;
    for (i = 0; i < n; i++) {
        uint32_t idx = (uint32_t)items[i], a = idx >> 2, b = forest_item_b(items[i], w), ra, rb;
        int d = ppa_dir_of_k[idx & 3u];
        if ((i & 0xfffff) == 0xfffff && ts__cancelled(ctx))
            return 1;
        ra = ppa_uf_find(parent, a);
        rb = ppa_uf_find(parent, b);
        if (ra == rb)
            continue; /* would close a polygon */
        ppa_uf_union(parent, rank, ra, rb);
        adj[a] |= (unsigned char)(1u << d);
        adj[b] |= (unsigned char)(1u << ((d + 4) & 7));
    }
    return 0;
}

/* An edge of the last Kruskal: a strip's contracted path (u, v: its end
 * cells; item: its least important segment, the one a cycle loses) or a
 * segment between two strips (u = a, v = b, item: itself). */
typedef struct strip_edge {
    uint64_t item;
    uint32_t u, v;
    int cross;
} strip_edge;

typedef struct strip_job {
    const forest_job *fj;
    int n_strips;
    const ts_ctx *ctx;
    uint64_t *tmp;
    uint32_t *parent;
    unsigned char *rank, *adj;
    unsigned char *mark; /* per cell: 1 border cell, 2 pruned */
    strip_edge **edges;  /* per strip: its contracted paths, then its lower border's segments */
    size_t *n_edges;
    int *strip_failed;
} strip_job;

/* The item of the segment from cell p in direction d (0..7). */
static uint64_t strip_link_item(const forest_job *fj, uint32_t p, int d)
{
    int w = fj->dem->width;
    uint32_t q = (uint32_t)((int64_t)p + (int64_t)ppa_dir[d][1] * w + ppa_dir[d][0]);
    if (d < 4)
        return forest_item(fj->dem, fj->sign, p, ppa_k_of_dir[d]);
    return forest_item(fj->dem, fj->sign, q, ppa_k_of_dir[d - 4]);
}

static int strip_push(strip_edge **e, size_t *n, size_t *cap, strip_edge x)
{
    if (*n == *cap) {
        size_t nc = *cap ? 2 * *cap : 256;
        strip_edge *ne = realloc(*e, nc * sizeof *ne);
        if (!ne)
            return -1;
        *e = ne;
        *cap = nc;
    }
    (*e)[(*n)++] = x;
    return 0;
}

static void strip_forests(void *arg, size_t begin, size_t end)
{
    strip_job *s = arg;
    const forest_job *fj = s->fj;
    int w = fj->dem->width, h = fj->dem->height;
    size_t k;
    for (k = begin; k < end; k++) {
        int y0, y1, y, x, d;
        size_t lo, hi, n_int, i, cap = 0;
        uint64_t *items;
        strip_edge *e = NULL;
        size_t ne = 0;
        uint32_t c, c0, c1;
        ppa_strip_rows(fj->dem->height, k, s->n_strips, &y0, &y1);
        lo = fj->row_count[y0];
        hi = fj->row_count[y1];
        items = fj->items + lo;
        /* the segments from the strip's last row down into the next strip
         * cross; the rest are the strip's own (stable partition, in place:
         * the crossing ones are all in the last row) */
        n_int = hi - lo;
        if (y1 < h) {
            size_t r0 = fj->row_count[y1 - 1] - lo, m = r0, n_x = 0;
            for (i = r0; i < hi - lo; i++) {
                if ((items[i] & 3u) == 0)
                    items[m++] = items[i];
                else
                    s->tmp[lo + n_x++] = items[i];
            }
            n_int = m;
            for (i = 0; i < n_x; i++) { /* the crossing ones, kept aside */
                strip_edge x1;
                x1.item = s->tmp[lo + i];
                x1.u = (uint32_t)x1.item >> 2;
                x1.v = forest_item_b(x1.item, w);
                x1.cross = 1;
                if (strip_push(&e, &ne, &cap, x1) != 0)
                    goto fail;
            }
        }
        forest_sort(items, s->tmp + lo, n_int);
        c0 = (uint32_t)((size_t)y0 * (size_t)w);
        c1 = (uint32_t)((size_t)y1 * (size_t)w);
        for (c = c0; c < c1; c++) {
            s->parent[c] = c;
            s->rank[c] = 0;
        }
        if (forest_kruskal(s->ctx, items, n_int, w, s->parent, s->rank, s->adj))
            goto fail;
        /* border cells: targets in the first and last rows that touch another strip */
        for (c = c0; c < c1; c++)
            s->mark[c] = 0;
        for (y = y0; y < y1; y += TS_MAX(1, y1 - 1 - y0)) {
            if ((y == y0 && y0 > 0) || (y == y1 - 1 && y1 < h))
                for (x = 0; x < w; x++) {
                    c = (uint32_t)((size_t)y * (size_t)w + (size_t)x);
                    if (fj->targets[c] & fj->kind)
                        s->mark[c] = 1;
                }
            if (y1 - 1 == y0)
                break;
        }
        /* prune twigs: a leaf that is no border cell is final, and so is the
         * path up to the first junction or border cell */
        for (c = c0; c < c1; c++) {
            uint32_t p = c;
            while (!s->mark[p] && ppa_degree_of[s->adj[p]] >= 1) {
                int deg = 0, nd = -1;
                for (d = 0; d < 8; d++)
                    if ((s->adj[p] >> d) & 1u) {
                        uint32_t q =
                            (uint32_t)((int64_t)p + (int64_t)ppa_dir[d][1] * w + ppa_dir[d][0]);
                        if (!(s->mark[q] & 2u)) {
                            deg++;
                            nd = d;
                        }
                    }
                if (deg != 1)
                    break;
                s->mark[p] = 2;
                p = (uint32_t)((int64_t)p + (int64_t)ppa_dir[nd][1] * w + ppa_dir[nd][0]);
            }
        }
        /* contract what is left: vertices are border cells and cells of
         * other than two links left; each path between two vertices becomes
         * one edge weighted by its least important segment (its largest
         * item), walked from its lower end only */
        for (c = c0; c < c1; c++) {
            int live = 0;
            if (s->mark[c] & 2u)
                continue;
            for (d = 0; d < 8; d++)
                if ((s->adj[c] >> d) & 1u) {
                    uint32_t q = (uint32_t)((int64_t)c + (int64_t)ppa_dir[d][1] * w + ppa_dir[d][0]);
                    live += !(s->mark[q] & 2u);
                }
            if (live == 0 || (!(s->mark[c] & 1u) && live == 2))
                continue; /* no edge, or inside a path */
            for (d = 0; d < 8; d++) {
                uint32_t prev = c, cur;
                uint64_t worst;
                strip_edge pe;
                if (!((s->adj[c] >> d) & 1u))
                    continue;
                cur = (uint32_t)((int64_t)c + (int64_t)ppa_dir[d][1] * w + ppa_dir[d][0]);
                if (s->mark[cur] & 2u)
                    continue;
                worst = strip_link_item(fj, c, d);
                for (;;) {
                    int dd, live2 = 0, nd = -1;
                    if (s->mark[cur] & 1u)
                        break;
                    for (dd = 0; dd < 8; dd++)
                        if ((s->adj[cur] >> dd) & 1u) {
                            uint32_t q = (uint32_t)((int64_t)cur + (int64_t)ppa_dir[dd][1] * w +
                                                    ppa_dir[dd][0]);
                            if (s->mark[q] & 2u)
                                continue;
                            live2++;
                            if (q != prev)
                                nd = dd;
                        }
                    if (live2 != 2)
                        break;
                    {
                        uint64_t it = strip_link_item(fj, cur, nd);
                        if (it > worst)
                            worst = it;
                    }
                    prev = cur;
                    cur = (uint32_t)((int64_t)cur + (int64_t)ppa_dir[nd][1] * w + ppa_dir[nd][0]);
                }
                if (cur < c)
                    continue; /* walked from the other end */
                pe.item = worst;
                pe.u = c;
                pe.v = cur;
                pe.cross = 0;
                if (strip_push(&e, &ne, &cap, pe) != 0)
                    goto fail;
            }
        }
        s->edges[k] = e;
        s->n_edges[k] = ne;
        continue;
    fail:
        free(e);
        s->strip_failed[k] = 1;
    }
}

static int strip_edge_cmp(const void *pa, const void *pb)
{
    const strip_edge *a = pa, *b = pb;
    return a->item < b->item ? -1 : a->item > b->item;
}

/* The forest from the items in strips (see the top of the file). */
static ts_status strip_forest(ts_ctx *ctx, forest_job *fj, int n_strips, uint64_t *tmp,
                              uint32_t *parent, unsigned char *rank, unsigned char *mark,
                              unsigned char *adj)
{
    strip_job s;
    int w = fj->dem->width, k;
    size_t total = 0, i;
    strip_edge *all = NULL;
    ts_status st = TS_OK;
    memset(&s, 0, sizeof s);
    s.fj = fj;
    s.n_strips = n_strips;
    s.ctx = ctx;
    s.tmp = tmp;
    s.parent = parent;
    s.rank = rank;
    s.adj = adj;
    s.mark = mark; /* the segment bits' bytes, no longer needed */
    s.edges = ts__calloc_array((size_t)n_strips, sizeof *s.edges);
    s.n_edges = ts__calloc_array((size_t)n_strips, sizeof *s.n_edges);
    s.strip_failed = ts__calloc_array((size_t)n_strips, sizeof *s.strip_failed);
    if (!s.edges || !s.n_edges || !s.strip_failed) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
        goto done;
    }
    ts__parallel_for(ctx, (size_t)n_strips, strip_forests, &s);
    if ((st = ts__check_cancel(ctx)) != TS_OK)
        goto done;
    for (k = 0; k < n_strips; k++) {
        if (s.strip_failed[k]) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
            goto done;
        }
        total += s.n_edges[k];
    }
    /* the last Kruskal, over the contracted paths and the crossing segments */
    all = ts__malloc_array(total ? total : 1, sizeof *all);
    if (!all) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
        goto done;
    }
    for (total = 0, k = 0; k < n_strips; k++) {
        if (s.n_edges[k])
            memcpy(all + total, s.edges[k], s.n_edges[k] * sizeof *all);
        total += s.n_edges[k];
    }
    qsort(all, total, sizeof *all, strip_edge_cmp); /* items are unique: a total order */
    for (i = 0; i < total; i++) {
        parent[all[i].u] = all[i].u;
        parent[all[i].v] = all[i].v;
        rank[all[i].u] = rank[all[i].v] = 0;
    }
    for (i = 0; i < total; i++) {
        uint32_t ra = ppa_uf_find(parent, all[i].u), rb = ppa_uf_find(parent, all[i].v);
        uint32_t idx = (uint32_t)all[i].item, a = idx >> 2, b = forest_item_b(all[i].item, w);
        int d = ppa_dir_of_k[idx & 3u];
        if (ra == rb) {
            if (!all[i].cross) { /* the path's least important segment goes */
                adj[a] &= (unsigned char)~(1u << d);
                adj[b] &= (unsigned char)~(1u << ((d + 4) & 7));
            }
            continue;
        }
        ppa_uf_union(parent, rank, ra, rb);
        if (all[i].cross) {
            adj[a] |= (unsigned char)(1u << d);
            adj[b] |= (unsigned char)(1u << ((d + 4) & 7));
        }
    }
done:
    if (s.edges)
        for (k = 0; k < n_strips; k++)
            free(s.edges[k]);
    free(s.edges);
    free(s.n_edges);
    free(s.strip_failed);
    free(all);
    return st;
}

ts_status ppa_spanning_forest(ts_ctx *ctx, const ts_raster *dem, const unsigned char *targets,
                              int kind, unsigned char *adj)
{
    return ppa_spanning_forest_strips(ctx, dem, targets, kind, adj,
                                      ts__thread_count(ctx, (size_t)dem->height / 64));
}

ts_status ppa_spanning_forest_strips(ts_ctx *ctx, const ts_raster *dem,
                                     const unsigned char *targets, int kind, unsigned char *adj,
                                     int n_strips)
{
    int w = dem->width, h = dem->height;
    size_t n = (size_t)w * (size_t)h, n_items = 0, i, y;
    forest_job j;
    uint64_t *tmp = NULL;
    uint32_t *parent = NULL;
    unsigned char *rank = NULL;
    ts_status st = TS_OK;
    memset(&j, 0, sizeof j);
    if (n >= ((size_t)1 << 30))
        return ts__fail(ctx, TS_ERR_SIZE, "ppa polygon breaking", "%d x %d cells: 2^30 at most", w,
                        h);
    j.dem = dem;
    j.targets = targets;
    j.kind = kind;
    j.sign = kind == TS_VALLEY ? -1.0f : 1.0f;
    j.seg = ts__malloc_array(n, 1);
    j.row_count = ts__malloc_array((size_t)h + 1, sizeof *j.row_count);
    if (!j.seg || !j.row_count) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
        goto done;
    }
    ts__parallel_for(ctx, (size_t)h, forest_exists, &j);
    for (j.phase = 0; j.phase < 2; j.phase++)
        ts__parallel_for(ctx, ((size_t)h + 1) / 2, forest_triangles, &j);
    ts__parallel_for(ctx, (size_t)h, forest_count, &j);
    for (y = 0; y < (size_t)h; y++) { /* counts to offsets */
        size_t c = j.row_count[y];
        j.row_count[y] = n_items;
        n_items += c;
    }
    j.items = ts__malloc_array(n_items ? n_items : 1, sizeof *j.items);
    tmp = ts__malloc_array(n_items ? n_items : 1, sizeof *tmp);
    if (!j.items || !tmp) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "cannot allocate for %zu segments",
                      n_items);
        goto done;
    }
    ts__parallel_for(ctx, (size_t)h, forest_fill, &j);
    if ((st = ts__check_cancel(ctx)) != TS_OK)
        goto done;
    j.row_count[h] = n_items;
    parent = ts__malloc_array(n, sizeof *parent);
    rank = ts__calloc_array(n, 1);
    if (!parent || !rank) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
        goto done;
    }
    n_strips = TS_MIN(TS_MAX(n_strips, 1), h);
    if (n_strips > 1) {
        st = strip_forest(ctx, &j, n_strips, tmp, parent, rank, j.seg, adj);
        if (st == TS_OK)
            st = ts__progress(ctx, 1.0, "polygon breaking");
        goto done;
    }
    free(j.seg);
    j.seg = NULL;
    /* one strip: sort all (the items are in index order already), then Kruskal */
    forest_sort(j.items, tmp, n_items);
    free(tmp);
    tmp = NULL;
    for (i = 0; i < n; i++)
        parent[i] = (uint32_t)i;
    for (i = 0; i < n_items; i += 0x100000) {
        size_t m = TS_MIN(n_items - i, (size_t)0x100000);
        if (forest_kruskal(ctx, j.items + i, m, w, parent, rank, adj) ||
            (st = ts__progress(ctx, (double)(i + m) / (double)n_items, "polygon breaking")) !=
                TS_OK) {
            st = st != TS_OK ? st : ts__check_cancel(ctx);
            goto done;
        }
    }
done:
    free(j.seg);
    free(j.row_count);
    free(j.items);
    free(tmp);
    free(parent);
    free(rank);
    return st;
}
