/*
 * sketch_tiles_fixed.c - pinned windows and water in a sketch in tiles (a
 * TerraSynth addition, named as such; not in Zhou et al. or Argudo et al.).
 *
 * The coarse pass lays pins and water out as K x K blocks
 * (sketch_amplify.c); the amplification then adds detail the pinned cells
 * do not have.  On each window, after the amplification:
 *
 * - pins: the difference d = pinned - amplified on the pinned cells (not
 *   water) is spread round them as a normalised Gaussian average,
 *
 *       s(x) = sum_p G(x - p) d(p) / sum_p G(x - p),  sigma = R / 3,
 *
 *   over the pinned cells p within R (Chebyshev) of x, and each free cell
 *   within R (Euclidean) of the nearest pinned cell gains s(x) times a
 *   smoothstep from 1 beside the pin to 0 at R: the land meets the pin's
 *   heights without a step and keeps its own detail beyond R;
 * - water: every free cell within R of water is raised towards the bank of
 *   water_banks.c, level - k max(0, dist - 1.5), with level the highest
 *   water within R (Chebyshev) and k the coarse pass's median step between
 *   neighbouring cells over K (a number of the whole grid, so any window
 *   takes the same);
 * - the fixed cells are put back exactly.
 *
 * R = 8 K cells.  A cell depends only on the cells within R of it, so a
 * window grown by R + 1 (ts_sketch_tiles_margin) and cut gives the whole's
 * bytes: every sum runs over the same cells in the same order.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "relief_guide.h"
#include "sketch_amplify.h"

#define PIN_FINE 3 /* cells: the reach of the differences beside a pin (sigma 1) */

/* R: how far a pinned or water cell reaches into the land round it. */
static int fixed_reach(const ts_sketch_tiles *t)
{
    return 8 * t->K;
}

TS_API int ts_sketch_tiles_margin(const ts_sketch_tiles *t)
{
    return t ? fixed_reach(t) + 1 : 0;
}

/* The smoothstep weight of a free cell dist cells from the nearest pinned
 * cell: 1 beside it, 0 at R. */
static double pin_taper(double dist, int R)
{
    double s = (R - dist) / (R - 1.0);
    if (s <= 0.0)
        return 0.0;
    if (s >= 1.0)
        return 1.0;
    return s * s * (3.0 - 2.0 * s);
}

/* Separable Gaussian sums over offsets -R..R of a (w x h, zero outside):
 * rows into tmp, then columns into out; the same order for every cell. */
static void gauss_sums(const double *a, int w, int h, const double *g, int R, double *tmp,
                       double *out)
{
    int x, y, k;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double s = 0.0;
            for (k = -R; k <= R; k++)
                if (x + k >= 0 && x + k < w)
                    s += g[k + R] * a[(size_t)y * w + (size_t)(x + k)];
            tmp[(size_t)y * w + x] = s;
        }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double s = 0.0;
            for (k = -R; k <= R; k++)
                if (y + k >= 0 && y + k < h)
                    s += g[k + R] * tmp[(size_t)(y + k) * w + x];
            out[(size_t)y * w + x] = s;
        }
}

ts_status ts__pin_blend(ts_ctx *ctx, ts_raster *out, const unsigned char *flags,
                        const float *values, int R)
{
    int w = out->width, h = out->height, x, y, k;
    size_t n = (size_t)w * (size_t)h, c, pins = 0;
    double *num = NULL, *den = NULL, *tmp = NULL, *a = NULL, *fnum = NULL, *fden = NULL;
    double g[2 * 256 + 1], gf[2 * PIN_FINE + 1];
    unsigned char *m = NULL;
    float *dist = NULL;
    ts_status st = TS_OK;
    if (R < 2 || R > 256)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "a pin's reach of %d cells", R);
    for (c = 0; c < n; c++)
        pins += (flags[c] & (TS_CELL_FIXED | TS_CELL_WATER)) == TS_CELL_FIXED && !isnan(values[c]);
    if (!pins)
        return TS_OK;
    a = ts__malloc_array(n, sizeof *a);
    num = ts__malloc_array(n, sizeof *num);
    den = ts__malloc_array(n, sizeof *den);
    tmp = ts__malloc_array(n, sizeof *tmp);
    fnum = ts__malloc_array(n, sizeof *fnum);
    fden = ts__malloc_array(n, sizeof *fden);
    m = ts__malloc_array(n, 1);
    dist = ts__malloc_array(n, sizeof *dist);
    if (!a || !num || !den || !tmp || !fnum || !fden || !m || !dist) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory for the pins' blend");
        goto done;
    }
    for (k = -R; k <= R; k++) {
        double sg = R / 3.0;
        g[k + R] = exp(-0.5 * (k * k) / (sg * sg));
    }
    for (k = -PIN_FINE; k <= PIN_FINE; k++)
        gf[k + PIN_FINE] = exp(-0.5 * (k * k));
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            c = (size_t)y * w + x;
            m[c] = (flags[c] & (TS_CELL_FIXED | TS_CELL_WATER)) == TS_CELL_FIXED &&
                   !isnan(values[c]) && !isnan(TS_PIX(out, x, y));
            a[c] = m[c] ? (double)values[c] - (double)TS_PIX(out, x, y) : 0.0;
        }
    gauss_sums(a, w, h, g, R, tmp, num);
    gauss_sums(a, w, h, gf, PIN_FINE, tmp, fnum);
    for (c = 0; c < n; c++)
        a[c] = m[c];
    gauss_sums(a, w, h, g, R, tmp, den);
    gauss_sums(a, w, h, gf, PIN_FINE, tmp, fden);
    if ((st = ts__distance_transform(ctx, m, w, h, dist)) != TS_OK)
        goto done;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            float *z = &TS_PIX(out, x, y);
            double t, s;
            c = (size_t)y * w + x;
            if ((flags[c] & (TS_CELL_FIXED | TS_CELL_NODATA)) || isnan(*z) || !(den[c] > 0.0) ||
                !((t = pin_taper(dist[c], R)) > 0.0))
                continue;
            s = num[c] / den[c];
            if (fden[c] > 0.0) { /* beside the pin, its own cells' differences */
                double l = exp(-(dist[c] - 1.0) / PIN_FINE);
                s = l * fnum[c] / fden[c] + (1.0 - l) * s;
            }
            *z = (float)(*z + t * s);
        }
done:
    free(fnum);
    free(fden);
    free(a);
    free(num);
    free(den);
    free(tmp);
    free(m);
    free(dist);
    return st;
}

/* The highest water value within R (Chebyshev) of each cell (-inf where
 * none): a separable maximum, rows then columns. */
static void water_max(const float *values, const unsigned char *flags, int w, int h, int R,
                      float *tmp, float *out)
{
    int x, y, k;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            float v = -INFINITY;
            for (k = TS_MAX(0, x - R); k <= TS_MIN(w - 1, x + R); k++) {
                size_t c = (size_t)y * w + (size_t)k;
                if ((flags[c] & TS_CELL_WATER) && !isnan(values[c]) && values[c] > v)
                    v = values[c];
            }
            tmp[(size_t)y * w + x] = v;
        }
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            float v = -INFINITY;
            for (k = TS_MAX(0, y - R); k <= TS_MIN(h - 1, y + R); k++)
                if (tmp[(size_t)k * w + x] > v)
                    v = tmp[(size_t)k * w + x];
            out[(size_t)y * w + x] = v;
        }
}

ts_status ts__water_banks_window(ts_ctx *ctx, ts_raster *out, const unsigned char *flags,
                                 const float *values, double k, int R)
{
    int w = out->width, h = out->height, x, y;
    size_t n = (size_t)w * (size_t)h, c, water = 0;
    unsigned char *m = NULL;
    float *dist = NULL, *level = NULL, *tmp = NULL;
    ts_status st = TS_OK;
    for (c = 0; c < n; c++)
        water += (flags[c] & TS_CELL_WATER) && !isnan(values[c]);
    if (!water)
        return TS_OK;
    if (!(k > 1e-6))
        k = 1e-6;
    m = ts__malloc_array(n, 1);
    dist = ts__malloc_array(n, sizeof *dist);
    level = ts__malloc_array(n, sizeof *level);
    tmp = ts__malloc_array(n, sizeof *tmp);
    if (!m || !dist || !level || !tmp) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory for the water's banks");
        goto done;
    }
    for (c = 0; c < n; c++)
        m[c] = (flags[c] & TS_CELL_WATER) && !isnan(values[c]);
    water_max(values, flags, w, h, R, tmp, level);
    if ((st = ts__distance_transform(ctx, m, w, h, dist)) != TS_OK)
        goto done;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            float *z = &TS_PIX(out, x, y);
            c = (size_t)y * w + x;
            if ((flags[c] & (TS_CELL_FIXED | TS_CELL_NODATA)) || isnan(*z) || !(dist[c] < R) ||
                !isfinite(level[c]))
                continue;
            *z = (float)ts__bank_raise(*z, level[c], k, dist[c], R);
        }
done:
    free(m);
    free(dist);
    free(level);
    free(tmp);
    return st;
}

ts_status ts__sketch_tiles_fixed(ts_ctx *ctx, const ts_sketch_tiles *t, ts_raster *out,
                                 const unsigned char *flags, const float *values)
{
    /* at K = 1 laid out at the output's cells: the coarse pass kept them */
    int R = t->K == 1 ? 0 : fixed_reach(t), x, y;
    ts_status st;
    if (R && (st = ts__pin_blend(ctx, out, flags, values, R)) != TS_OK)
        return st;
    if (R && (st = ts__water_banks_window(ctx, out, flags, values, t->bank_step, R)) != TS_OK)
        return st;
    for (y = 0; y < out->height; y++)
        for (x = 0; x < out->width; x++) {
            size_t c = (size_t)y * (size_t)out->width + (size_t)x;
            if ((flags[c] & TS_CELL_FIXED) && !isnan(values[c]))
                TS_PIX(out, x, y) = values[c];
        }
    return ts__check_cancel(ctx);
}
