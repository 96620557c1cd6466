/*
 * drainage_area.c - the drainage area of every cell (in cells), for the
 * PPA's `min_drainage`: valley targets that drain fewer cells are hollows
 * above the channel heads, not valleys where the water runs.
 *
 * Flow is routed by priority-flood (Barnes, Lehman and Mulla 2014): from
 * the seeds (valid cells on the raster's edge or beside nodata) cells are
 * taken lowest first, a cell's height raised to the height it was reached
 * from (so depressions fill and spill), ties first come first served; every
 * cell drains to the cell it was reached from.  The areas are then summed
 * down that tree in the reverse order of taking.  Deterministic: the
 * neighbours are visited in a fixed order and ties are broken by a counter.
 * tests/c/test_ppa.c compares it with the same rule by a plain scan for the
 * lowest frontier cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

/* The flood's order: height, then the order of arrival, as one 64-bit key
 * (the float's bits made to sort as unsigned, then a counter). */
static uint64_t flood_key(float h, uint32_t count)
{
    uint32_t u;
    h += 0.0f; /* -0 and +0 are one height */
    memcpy(&u, &h, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return (uint64_t)u << 32 | count;
}

/* A radix heap (Ahuja et al. 1990) of unique keys: the keys taken never go
 * down (a cell is flooded at or above the level it is reached from), so an
 * item waits in the bucket of the highest bit where its key differs from
 * the last key taken and only moves down.  The same order as a binary heap
 * of (height, count), at a fraction of the cost: no comparisons of floats
 * and a few sequential moves per item. */
typedef struct flood_item {
    uint64_t key;
    uint32_t cell;
} flood_item;

typedef struct radix_heap {
    flood_item *b[65];
    size_t n[65], cap[65];
    uint64_t last;
    size_t size;
} radix_heap;

static int rh_bucket(const radix_heap *q, uint64_t key)
{
    return key == q->last ? 0 : 64 - __builtin_clzll(key ^ q->last);
}

static int rh_append(radix_heap *q, int i, flood_item it)
{
    if (q->n[i] == q->cap[i]) {
        size_t nc = q->cap[i] ? 2 * q->cap[i] : 256;
        flood_item *g = realloc(q->b[i], nc * sizeof *g);
        if (!g)
            return -1;
        q->b[i] = g;
        q->cap[i] = nc;
    }
    q->b[i][q->n[i]++] = it;
    return 0;
}

static int rh_push(radix_heap *q, flood_item it)
{
    if (rh_append(q, rh_bucket(q, it.key), it) != 0)
        return -1;
    q->size++;
    return 0;
}

/* Take the least item (q->size > 0) into *out; -1 when out of memory. */
static int rh_pop(radix_heap *q, flood_item *out)
{
    if (q->n[0] == 0) {
        int i = 1;
        size_t j, m = 0;
        flood_item *src;
        size_t cnt;
        while (q->n[i] == 0)
            i++;
        for (j = 1; j < q->n[i]; j++)
            if (q->b[i][j].key < q->b[i][m].key)
                m = j;
        q->last = q->b[i][m].key;
        /* every item of bucket i goes to a lower bucket */
        src = q->b[i];
        cnt = q->n[i];
        q->n[i] = 0;
        for (j = 0; j < cnt; j++)
            if (rh_append(q, rh_bucket(q, src[j].key), src[j]) != 0) {
                /* put the rest back where it was: the heap stays whole */
                memmove(src, src + j, (cnt - j) * sizeof *src);
                q->n[i] = cnt - j;
                return -1;
            }
    }
    q->size--;
    *out = q->b[0][--q->n[0]];
    return 0;
}

static void rh_free(radix_heap *q)
{
    int i;
    for (i = 0; i < 65; i++)
        free(q->b[i]);
}

#define FROM_NONE 8    /* a seed: drains off the DEM */
#define FROM_UNSEEN 9  /* not reached yet */
#define FROM_NODATA 10

/* A cell as the flood sees it: its height and the direction it was reached
 * from, side by side (the flood visits cells in height order, all over the
 * DEM: one cache line a row of neighbours instead of two). */
typedef struct flood_cell {
    float h;
    uint32_t from;
} flood_cell;

int ppa_drainage_area(const ts_raster *dem, float *area)
{
    int w = dem->width, h = dem->height, x, y, d;
    size_t n = (size_t)w * (size_t)h, taken = 0, i;
    uint32_t counter = 0;
    int fail = 0;
    radix_heap q;
    flood_cell *cell = ts__malloc_array(n ? n : 1, sizeof *cell);
    uint32_t *order = ts__malloc_array(n ? n : 1, sizeof *order);
    memset(&q, 0, sizeof q);
    if (!cell || !order || n >= UINT32_MAX) {
        free(cell);
        free(order);
        return -1;
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            flood_cell *fc = &cell[(size_t)y * (size_t)w + (size_t)x];
            fc->h = TS_PIX(dem, x, y);
            fc->from = isnan(fc->h) ? FROM_NODATA : FROM_UNSEEN;
        }
    /* seeds: valid cells on the edge or beside nodata, in row-major order */
    for (y = 0; y < h && !fail; y++)
        for (x = 0; x < w; x++) {
            size_t c = (size_t)y * (size_t)w + (size_t)x;
            int edge = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            area[c] = NAN;
            if (cell[c].from == FROM_NODATA)
                continue;
            for (d = 0; d < 8 && !edge; d++)
                edge = cell[c + (size_t)((ptrdiff_t)ppa_dir[d][1] * w + ppa_dir[d][0])].from ==
                       FROM_NODATA;
            if (edge) {
                flood_item it = {flood_key(cell[c].h, counter++), (uint32_t)c};
                cell[c].from = FROM_NONE;
                if (rh_push(&q, it) != 0) {
                    fail = 1;
                    break;
                }
            }
        }
    while (q.size && !fail) {
        flood_item it;
        int cx, cy;
        float level;
        if (rh_pop(&q, &it) != 0) {
            fail = 1;
            break;
        }
        cx = (int)(it.cell % (uint32_t)w);
        cy = (int)(it.cell / (uint32_t)w);
        {
            uint32_t u = (uint32_t)(it.key >> 32);
            u = (u & 0x80000000u) ? (u & 0x7fffffffu) : ~u;
            memcpy(&level, &u, sizeof level);
        }
        order[taken++] = it.cell;
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            flood_cell *nc;
            if (nx < 0 || ny < 0 || nx >= w || ny >= h)
                continue;
            nc = &cell[(size_t)ny * (size_t)w + (size_t)nx];
            if (nc->from != FROM_UNSEEN) /* taken, waiting, or nodata */
                continue;
            nc->from = (uint32_t)((d + 4) & 7); /* back towards the cell taken */
            {
                flood_item next = {flood_key(nc->h > level ? nc->h : level, counter++),
                                   (uint32_t)((size_t)ny * (size_t)w + (size_t)nx)};
                if (rh_push(&q, next) != 0) {
                    fail = 1;
                    break;
                }
            }
        }
    }
    if (!fail) {
        /* the areas, summed down the flood's tree in the reverse order of taking */
        for (i = 0; i < taken; i++)
            cell[order[i]].h = 1;
        for (i = taken; i-- > 0;) {
            uint32_t c = order[i];
            uint32_t fd = cell[c].from;
            area[c] = cell[c].h;
            if (fd != FROM_NONE)
                cell[(size_t)((int)(c / (uint32_t)w) + ppa_dir[fd][1]) * (size_t)w +
                     (size_t)((int)(c % (uint32_t)w) + ppa_dir[fd][0])]
                    .h += cell[c].h;
        }
    }
    rh_free(&q);
    free(cell);
    free(order);
    return fail ? -1 : 0;
}
