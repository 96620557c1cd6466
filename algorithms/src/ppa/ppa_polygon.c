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

#include "internal.h"

/* Order-preserving map of a float to an unsigned key, inverted so that
 * ascending keys mean descending weights. */
static uint32_t polygon_key(float w)
{
    uint32_t u;
    memcpy(&u, &w, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return ~u;
}

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
