/*
 * drainage.c - upstream drainage area (Argudo et al. 2017, section 5.6):
 * the deterministic D8 flow accumulation stands for the paper's particle
 * simulation (named as such in the manual): each cell drains to its
 * steepest lower neighbour, and cells are visited from the highest down so
 * each passes its whole area on.
 *
 * Why not ppa/drainage_area.c: that one fills depressions and crosses
 * flats (priority flood) over DEMs of any size in tiles, for the channels
 * the PPA keeps as valleys.  Here the drainage is a descriptor of small
 * windows (an atom, a coarse input's patch) compared with each other: the
 * same plain D8 on both sides, without filling, as the paper's particles
 * run; flooding each window's pits would change what is compared.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "amplify.h"

typedef struct cell_z {
    uint32_t key; /* height_key of its height */
    uint32_t i;   /* the cell's index: 8 bytes a cell, twice over while sorting */
} cell_z;

/* The key that orders heights from the highest down as unsigned integers
 * (-0 as 0: equal heights tie). */
static uint32_t height_key(float z)
{
    uint32_t u;
    if (z == 0.0f)
        z = 0.0f;
    memcpy(&u, &z, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u); /* ascending */
    return ~u;
}

/* order[0..m) (in ascending i) sorted from the highest height down, ties in
 * ascending i: a stable least-significant-digit radix sort on the keys,
 * 8 bits a pass, through tmp (m cells).  The order a comparison sort by
 * (height descending, index ascending) gives, in O(m). */
static void sort_by_height_desc(cell_z *order, cell_z *tmp, size_t m)
{
    size_t count[256], j;
    int pass, b;
    for (pass = 0; pass < 4; pass++) {
        int shift = 8 * pass;
        size_t at = 0;
        memset(count, 0, sizeof count);
        for (j = 0; j < m; j++)
            count[(order[j].key >> shift) & 255u]++;
        for (b = 0; b < 256; b++) {
            size_t c = count[b];
            count[b] = at;
            at += c;
        }
        for (j = 0; j < m; j++)
            tmp[count[(order[j].key >> shift) & 255u]++] = order[j];
        memcpy(order, tmp, m * sizeof *order);
    }
}

TS_API ts_status ts_drainage_area(ts_ctx *ctx, const ts_raster *dem, ts_raster *out)
{
    static const int dx[8] = {1, 1, 0, -1, -1, -1, 0, 1}, dy[8] = {0, 1, 1, 1, 0, -1, -1, -1};
    int W, H, x, y, k;
    size_t n, m = 0, j;
    cell_z *order, *tmp;
    ts__clear(ctx);
    if (!dem || !out || !dem->data || !out->data || out->width != dem->width ||
        out->height != dem->height)
        return ts__fail(ctx, TS_ERR_ARG, "drainage", "missing or mismatched rasters");
    W = dem->width;
    H = dem->height;
    n = (size_t)W * (size_t)H;
    if (n > UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, "drainage", "%d x %d cells: at most 2^32 - 1", W, H);
    order = ts__malloc_array(n, sizeof *order);
    tmp = ts__malloc_array(n, sizeof *tmp);
    if (!order || !tmp) {
        free(order);
        free(tmp);
        return ts__fail(ctx, TS_ERR_NOMEM, "drainage", "out of memory");
    }
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            float z = TS_PIX(dem, x, y);
            TS_PIX(out, x, y) = isnan(z) ? NAN : 1.0f;
            if (!isnan(z)) {
                order[m].key = height_key(z);
                order[m].i = (uint32_t)((size_t)y * (size_t)W + (size_t)x);
                m++;
            }
        }
    sort_by_height_desc(order, tmp, m);
    free(tmp);
    for (j = 0; j < m; j++) {
        int cx = (int)(order[j].i % (size_t)W), cy = (int)(order[j].i / (size_t)W), to = -1;
        const float zc = TS_PIX(dem, cx, cy);
        double best = 0.0;
        for (k = 0; k < 8; k++) {
            int nx = cx + dx[k], ny = cy + dy[k];
            float zn;
            double drop;
            if (nx < 0 || ny < 0 || nx >= W || ny >= H)
                continue;
            zn = TS_PIX(dem, nx, ny);
            if (isnan(zn))
                continue;
            drop = (zc - zn) / ((k & 1) ? 1.4142135623730951 : 1.0);
            if (drop > best) {
                best = drop;
                to = k;
            }
        }
        if (to >= 0)
            TS_PIX(out, cx + dx[to], cy + dy[to]) += TS_PIX(out, cx, cy);
    }
    free(order);
    return TS_OK;
}
