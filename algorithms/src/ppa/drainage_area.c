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
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

typedef struct flood_item {
    float h;
    uint32_t count, cell;
} flood_item;

static int flood_before(const flood_item *a, const flood_item *b)
{
    return a->h < b->h || (a->h == b->h && a->count < b->count);
}

/* The heap grows as the frontier does (a frontier is about the DEM's
 * perimeter, not its area). */
static int heap_push(flood_item **heap, size_t *n, size_t *cap, flood_item it)
{
    size_t i = (*n)++;
    flood_item *hp;
    if (*n > *cap) {
        size_t ncap = *cap * 2;
        flood_item *g = realloc(*heap, ncap * sizeof *g);
        if (!g) {
            (*n)--;
            return -1;
        }
        *heap = g;
        *cap = ncap;
    }
    hp = *heap;
    while (i > 0) {
        size_t p = (i - 1) / 2;
        if (!flood_before(&it, &hp[p]))
            break;
        hp[i] = hp[p];
        i = p;
    }
    hp[i] = it;
    return 0;
}

static flood_item heap_pop(flood_item *heap, size_t *n)
{
    flood_item top = heap[0], last = heap[--(*n)];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= *n)
            break;
        if (c + 1 < *n && flood_before(&heap[c + 1], &heap[c]))
            c++;
        if (!flood_before(&heap[c], &last))
            break;
        heap[i] = heap[c];
        i = c;
    }
    if (*n)
        heap[i] = last;
    return top;
}

#define FROM_NONE 8    /* a seed: drains off the DEM */
#define FROM_UNSEEN 255

int ppa_drainage_area(const ts_raster *dem, float *area)
{
    int w = dem->width, h = dem->height, x, y, d;
    size_t n = (size_t)w * (size_t)h, nh = 0, cap = 4 * ((size_t)w + (size_t)h) + 16, taken = 0, i;
    uint32_t counter = 0;
    int fail = 0;
    flood_item *heap = ts__malloc_array(cap, sizeof *heap);
    /* the direction each cell was reached from: a byte, not a cell index */
    unsigned char *from = ts__malloc_array(n ? n : 1, 1);
    uint32_t *order = ts__malloc_array(n ? n : 1, sizeof *order);
    if (!heap || !from || !order || n >= UINT32_MAX) {
        free(heap);
        free(from);
        free(order);
        return -1;
    }
    memset(from, FROM_UNSEEN, n);
    /* seeds: valid cells on the edge or beside nodata, in row-major order */
    for (y = 0; y < h && !fail; y++)
        for (x = 0; x < w; x++) {
            size_t c = (size_t)y * (size_t)w + (size_t)x;
            int edge = x == 0 || y == 0 || x == w - 1 || y == h - 1;
            area[c] = NAN;
            if (isnan(TS_PIX(dem, x, y)))
                continue;
            for (d = 0; d < 8 && !edge; d++)
                edge = isnan(TS_PIX(dem, x + ppa_dir[d][0], y + ppa_dir[d][1]));
            if (edge) {
                flood_item it = {TS_PIX(dem, x, y), counter++, (uint32_t)c};
                from[c] = FROM_NONE;
                if (heap_push(&heap, &nh, &cap, it) != 0) {
                    fail = 1;
                    break;
                }
            }
        }
    while (nh && !fail) {
        flood_item it = heap_pop(heap, &nh);
        int cx = (int)(it.cell % (uint32_t)w), cy = (int)(it.cell / (uint32_t)w);
        order[taken++] = it.cell;
        for (d = 0; d < 8; d++) {
            int nx = cx + ppa_dir[d][0], ny = cy + ppa_dir[d][1];
            size_t c;
            float nhgt;
            if (nx < 0 || ny < 0 || nx >= w || ny >= h)
                continue;
            c = (size_t)ny * (size_t)w + (size_t)nx;
            nhgt = TS_PIX(dem, nx, ny);
            if (from[c] != FROM_UNSEEN || isnan(nhgt))
                continue;
            from[c] = (unsigned char)((d + 4) & 7); /* back towards the cell taken */
            {
                flood_item next = {nhgt > it.h ? nhgt : it.h, counter++, (uint32_t)c};
                if (heap_push(&heap, &nh, &cap, next) != 0) {
                    fail = 1;
                    break;
                }
            }
        }
    }
    if (!fail) {
        for (i = 0; i < taken; i++)
            area[order[i]] = 1;
        for (i = taken; i-- > 0;) {
            uint32_t c = order[i];
            int fd = from[c];
            if (fd != FROM_NONE)
                area[(size_t)((int)(c / (uint32_t)w) + ppa_dir[fd][1]) * (size_t)w +
                     (size_t)((int)(c % (uint32_t)w) + ppa_dir[fd][0])] += area[c];
        }
    }
    free(heap);
    free(from);
    free(order);
    return fail ? -1 : 0;
}
