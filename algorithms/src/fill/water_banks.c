/*
 * water_banks.c - the land beside water stays at or above the water (a
 * TerraSynth addition, named as such; not in Zhou et al.).
 *
 * Water cells are fixed at their level, and the fill matches patches to
 * them, but nothing kept the land next to them from ending lower: a lake
 * hung above part of its own shore (a third of the shore cells below the
 * level in a 600 x 500 run over Big Tujunga, free or sketched).  After the
 * synthesis every free cell within a patch of water is raised by a soft
 * maximum towards the bank
 *
 *     B(x) = level - k max(0, d(x) - 1.5),
 *
 * d the distance to the nearest water cell, level that cell's value, k the
 * output's median step between neighbouring cells: every cell touching
 * water (8 neighbours) ends at or above the level, and the bank falls away
 * at the terrain's usual steepness.  The soft maximum, h + w log(1 +
 * exp((B - h) / w)) with w = k, leaves land well above the bank as it is
 * (to within w exp(-(h - B) / w)) and raises land below it without a
 * crease; the change fades out over the last half patch.  Pinned cells,
 * nodata and the water itself never change.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "relief_guide.h"

double ts__median_step(const ts_raster *r, const unsigned char *flags)
{
    int w = r->width, h = r->height, x, y, step = 1;
    size_t n = 0;
    float *v;
    double med;
    while ((size_t)(w / step + 1) * (size_t)(h / step + 1) > ((size_t)1 << 16))
        step++;
    v = ts__malloc_array((size_t)(w / step + 1) * (size_t)(h / step + 1), sizeof *v);
    if (!v)
        return -1.0;
    for (y = 0; y + 1 < h; y += step)
        for (x = 0; x + 1 < w; x += step) {
            size_t c = (size_t)y * (size_t)w + (size_t)x;
            float z = TS_PIX(r, x, y), gx = TS_PIX(r, x + 1, y) - z, gy = TS_PIX(r, x, y + 1) - z;
            if ((flags ? flags[c] != 0 : gx == 0.0f && gy == 0.0f) || isnan(gx) || isnan(gy))
                continue;
            v[n++] = sqrtf(0.5f * (gx * gx + gy * gy));
        }
    if (!n) {
        free(v);
        return 0.0;
    }
    ts__sort_floats(v, n);
    med = v[n / 2];
    free(v);
    return med;
}

double ts__bank_raise(double z, double level, double k, double d, double reach)
{
    double bank = level - k * (d > 1.5 ? d - 1.5 : 0.0), t = (bank - z) / k, up, fade = 1.0;
    up = t > 30.0 ? t * k : k * log1p(exp(t)); /* soft maximum */
    if (d > 0.5 * reach) {
        double s = (reach - d) / (0.5 * reach);
        fade = s * s * (3.0 - 2.0 * s);
    }
    return z + fade * up;
}

ts_status ts__water_banks(ts_ctx *ctx, ts_raster *out, const unsigned char *flags, int patch)
{
    int w = out->width, h = out->height, x, y;
    size_t n = (size_t)w * (size_t)h, c, water = 0;
    unsigned char *m;
    float *dist;
    int32_t *nearest;
    double k, reach = patch > 4 ? patch : 4;
    if (!flags)
        return TS_OK;
    for (c = 0; c < n; c++)
        water += (flags[c] & TS_CELL_WATER) != 0;
    if (!water)
        return TS_OK;
    k = ts__median_step(out, flags);
    if (k < 0)
        return ts__fail(ctx, TS_ERR_NOMEM, "water banks", "out of memory");
    if (!(k > 1e-6))
        k = 1e-6;
    m = ts__malloc_array(n, 1);
    dist = ts__malloc_array(n, sizeof *dist);
    nearest = ts__malloc_array(n, sizeof *nearest);
    if (!m || !dist || !nearest) {
        free(m);
        free(dist);
        free(nearest);
        return ts__fail(ctx, TS_ERR_NOMEM, "water banks", "out of memory");
    }
    for (c = 0; c < n; c++)
        m[c] = (flags[c] & TS_CELL_WATER) != 0;
    if (ts__distance_transform_nearest(ctx, m, w, h, dist, nearest) != TS_OK) {
        free(m);
        free(dist);
        free(nearest);
        return ctx->status;
    }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double d, level;
            float *z = &TS_PIX(out, x, y);
            c = (size_t)y * (size_t)w + (size_t)x;
            d = dist[c];
            if (flags[c] || isnan(*z) || nearest[c] < 0 || !(d < reach))
                continue;
            level = TS_PIX(out, nearest[c] % w, nearest[c] / w);
            if (isnan(level))
                continue;
            *z = (float)ts__bank_raise(*z, level, k, d, reach);
        }
    free(m);
    free(dist);
    free(nearest);
    return ts__check_cancel(ctx);
}
