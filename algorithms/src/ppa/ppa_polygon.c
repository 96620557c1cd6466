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
 * by size.  tests/c/test_ppa.c checks it against naive repeated polygon
 * breaking on random DEMs.
 * Cost: O(n) sort + O(n alpha(n)) union-find; memory 12 bytes/segment +
 * 8 bytes/cell.
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

static uint32_t polygon_find(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    return v;
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
        uint32_t ra = polygon_find(parent, s->a), rb = polygon_find(parent, s->b);
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

ts_status ppa_spanning_forest(ts_ctx *ctx, const ts_raster *dem, const unsigned char *targets,
                              int kind, unsigned char *adj)
{
    static const int dir_of_k[4] = {0, 3, 2, 1}; /* E, SW, S, SE as ppa_dir */
    int w = dem->width, h = dem->height, pass;
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
    free(j.seg);
    j.seg = NULL;
    if ((st = ts__check_cancel(ctx)) != TS_OK)
        goto done;
    /* stable LSD radix sort on the key (the items are in index order already) */
    for (pass = 0; pass < 4; pass++) {
        size_t count[257] = {0};
        int shift = 32 + pass * 8, b;
        uint64_t *swap;
        for (i = 0; i < n_items; i++)
            count[((j.items[i] >> shift) & 0xffu) + 1]++;
        if (count[((j.items[0] >> shift) & 0xffu) + 1] == n_items)
            continue; /* one bucket: nothing moves */
        for (b = 0; b < 256; b++)
            count[b + 1] += count[b];
        for (i = 0; i < n_items; i++)
            tmp[count[(j.items[i] >> shift) & 0xffu]++] = j.items[i];
        swap = j.items;
        j.items = tmp;
        tmp = swap;
    }
    free(tmp);
    tmp = NULL;
    /* Kruskal: union-find with path halving and union by rank */
    parent = ts__malloc_array(n, sizeof *parent);
    rank = ts__calloc_array(n, 1);
    if (!parent || !rank) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa polygon breaking", "out of memory");
        goto done;
    }
    for (i = 0; i < n; i++)
        parent[i] = (uint32_t)i;
    for (i = 0; i < n_items; i++) {
        uint32_t idx = (uint32_t)j.items[i], a = idx >> 2, ra, rb;
        int k = (int)(idx & 3u), d = dir_of_k[k];
        uint32_t b =
            (uint32_t)((int64_t)a + (int64_t)ppa_connect_step[k][1] * w + ppa_connect_step[k][0]);
        ra = polygon_find(parent, a);
        rb = polygon_find(parent, b);
        if (ra == rb)
            continue; /* would close a polygon */
        if (rank[ra] < rank[rb]) {
            uint32_t t = ra;
            ra = rb;
            rb = t;
        }
        parent[rb] = ra;
        if (rank[ra] == rank[rb])
            rank[ra]++;
        adj[a] |= (unsigned char)(1u << d);
        adj[b] |= (unsigned char)(1u << ((d + 4) & 7));
        if ((i & 0xfffff) == 0 &&
            (st = ts__progress(ctx, (double)i / (double)n_items, "polygon breaking")) != TS_OK)
            goto done;
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
