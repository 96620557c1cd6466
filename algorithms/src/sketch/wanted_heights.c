/*
 * wanted_heights.c - the user's wanted heights kept at large scale after
 * the layout and the slope style, which know nothing of them (a TerraSynth
 * addition to Zhou et al. 2007, whose height constraints act on the patch
 * choice only).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>

#include "layout.h"

ts_status ts__layout_keep_heights(ts_ctx *ctx, ts_raster *out, const float *heights,
                                  double alpha_h, const unsigned char *flags, int patch)
{
    int W = out->width, H = out->height, x, y;
    size_t n = (size_t)W * (size_t)H, i, any = 0;
    double s = alpha_h < 1.0 ? alpha_h : 1.0, sigma = patch / 3.0;
    float *r, *c, *d;
    unsigned char *m;
    ts_status st;
    if (!heights || !(s > 0))
        return TS_OK;
    for (i = 0; i < n && !any; i++)
        any = !isnan(heights[i]);
    if (!any)
        return TS_OK;
    r = ts__malloc_array(n, sizeof *r);
    c = ts__malloc_array(n, sizeof *c);
    d = ts__malloc_array(n, sizeof *d);
    m = ts__malloc_array(n, 1);
    if (!r || !c || !d || !m) {
        free(r);
        free(c);
        free(d);
        free(m);
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    }
    /* the residual on the cells with a wanted height, its mean over them
     * within sigma (the NaN-aware blur: a region's local mean, a line's mean
     * along it), fading out over sigma away from them: regions and lines
     * alike come to their wanted heights, the detail below sigma stays */
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            float z = TS_PIX(out, x, y);
            i = (size_t)y * (size_t)W + (size_t)x;
            r[i] = isnan(z) || isnan(heights[i]) ? NAN : heights[i] - z;
            m[i] = !isnan(heights[i]);
        }
    st = ts__blur_nan(ctx, r, W, W, H, sigma, c);
    if (st == TS_OK)
        st = ts__distance_transform(ctx, m, W, H, d);
    if (st == TS_OK)
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double fade;
                i = (size_t)y * (size_t)W + (size_t)x;
                if ((flags && (flags[i] & (TS_CELL_FIXED | TS_CELL_NODATA))) ||
                    isnan(TS_PIX(out, x, y)) || isnan(c[i]))
                    continue;
                fade = d[i] / sigma;
                fade = exp(-fade * fade);
                TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + s * fade * c[i]);
            }
    free(r);
    free(c);
    free(d);
    free(m);
    return st;
}
