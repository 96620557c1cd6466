/*
 * recipe_overviews.c - a recipe zoomed out, for GDAL's overviews: what a
 * viewer or `gdal_translate -outsize` reads instead of every cell.
 *
 *   pixel     2^k for k = 1, 2, ... while the overview has 128 cells or more
 *             along its longer side: the synthesis stopped at the level of
 *             that spacing (tsjob_pixel_overview), before the drainage stage;
 *   amplify   F, 2F, 4F, ... (F the factor): the input itself, then its
 *             cells averaged (the output averaged by F is the input);
 *   synth, ppa, an amplify layer: none.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>

#include "recipe_internal.h"

#define OVERVIEW_MIN_SIDE 128

static int recipe_overview_kind(const tsrecipe *r)
{
    if (r->method == TSRECIPE_PIXEL)
        return TSRECIPE_PIXEL;
    if (r->method == TSRECIPE_AMPLIFY && !r->layer[0] && r->amplify.params.factor >= 2)
        return TSRECIPE_AMPLIFY;
    return 0;
}

int tsrecipe_overview_factor(const tsrecipe *r, int i)
{
    int kind = recipe_overview_kind(r);
    if (i < 0 || i > 29 || !kind)
        return 0;
    if (kind == TSRECIPE_PIXEL)
        return 1 << (i + 1);
    {
        long long f = (long long)r->amplify.params.factor << i;
        return f > 1 << 30 ? 0 : (int)f; /* (none past 2^30) */
    }
}

int tsrecipe_overview_count(const tsrecipe *r)
{
    const tsio_georef *g = tsrecipe_georef(r);
    int side = g->width > g->height ? g->width : g->height, n = 0, f;
    if (!recipe_overview_kind(r))
        return 0;
    /* the first always for amplify (its input, at no cost) */
    while ((f = tsrecipe_overview_factor(r, n)) > 0 &&
           ((side + f - 1) / f >= OVERVIEW_MIN_SIDE ||
            (n == 0 && recipe_overview_kind(r) == TSRECIPE_AMPLIFY)))
        n++;
    return n;
}

/* Cells [x0, x0+w) x [y0, y0+h) of the input averaged over blocks of b x b
 * (nodata and cells past its edge left out; none: nodata). */
static void input_averaged(const ts_raster *in, int b, int x0, int y0, int w, int h, float *out)
{
    int x, y, i, j;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double m = 0;
            int n = 0;
            for (j = 0; j < b; j++)
                for (i = 0; i < b; i++) {
                    int64_t ix = ((int64_t)x0 + x) * b + i, iy = ((int64_t)y0 + y) * b + j;
                    float v;
                    if (ix >= in->width || iy >= in->height)
                        continue;
                    v = TS_PIX(in, (int)ix, (int)iy);
                    if (!isnan(v)) {
                        m += v;
                        n++;
                    }
                }
            out[(size_t)y * w + x] = n ? (float)(m / n) : (float)TSIO_NODATA;
        }
}

int tsrecipe_read_overview(tsrecipe *r, int i, int x0, int y0, int w, int h, float *out,
                           tsio_err *err)
{
    int f = tsrecipe_overview_factor(r, i), rc;
    const tsio_georef *g = tsrecipe_georef(r);
    ts_ctx *ctx;
    tsio_offline guard;
    if (i >= tsrecipe_overview_count(r) || f < 2 || !r->computed) {
        tsio_errf(err, r->path, "no overview %d", i + 1);
        return -1;
    }
    if (x0 < 0 || y0 < 0 || w < 1 || h < 1 || x0 > (g->width + f - 1) / f - w ||
        y0 > (g->height + f - 1) / f - h) {
        tsio_errf(err, r->path, "overview window %d,%d %dx%d is off its grid", x0, y0, w, h);
        return -1;
    }
    if (recipe_overview_kind(r) == TSRECIPE_AMPLIFY) {
        input_averaged(&r->amplify_res.in.r, 1 << i, x0, y0, w, h, out);
        return 0;
    }
    if (!(ctx = ts_ctx_new())) {
        tsio_errf(err, r->path, "out of memory");
        return -1;
    }
    ts_ctx_set_seed(ctx, r->seed);
    tsio_offline_begin(&guard);
    rc = tsjob_pixel_overview(ctx, &r->pixel, &r->pixel_res, i + 1, x0, y0, w, h, out, err);
    tsio_offline_end(&guard);
    ts_ctx_free(ctx);
    return rc;
}
