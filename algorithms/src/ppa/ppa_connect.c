/*
 * ppa_connect.c - PPA step 2, target connection (Zhou et al. 2007 section
 * 3, Fig. 4b).
 *
 * Every pair of 8-adjacent targets of one kind is joined by a segment whose
 * importance is the sum of its two heights (heights negated for valleys, so
 * that "lowest segment" always means "least important").  Where the two
 * diagonals of one 2 x 2 block cross, the less important one is cancelled.
 * A diagonal whose two flanking cells include nodata is never made, so
 * features are never bridged across holes.
 * Cost: two passes over the cells; output in a fixed row-major order
 * (cell a, then E, SW, S, SE), so results never depend on threads.
 */
#include <stdlib.h>

#include "internal.h"

/* Neighbour steps in segment order from cell a: E, SW, S, SE. */
const int ppa_connect_step[4][2] = {{1, 0}, {-1, 1}, {0, 1}, {1, 1}};
#define connect_step ppa_connect_step

static int connect_is_target(const unsigned char *t, int w, int h, int x, int y, int kind)
{
    return x >= 0 && y >= 0 && x < w && y < h && (t[(size_t)y * (size_t)w + (size_t)x] & kind);
}

/* Does segment k from (x, y) exist (before/after the crossing rule)? */
int ppa_segment_exists(const ts_raster *dem, const unsigned char *t, int kind, int x, int y, int k,
                       float sign)
{
    int w = dem->width, h = dem->height;
    int nx = x + connect_step[k][0], ny = y + connect_step[k][1];
    if (!connect_is_target(t, w, h, nx, ny, kind))
        return 0;
    if (k == 1 || k == 3) {
        /* diagonal: flanked by (x, ny) and (nx, y) */
        float fa = TS_PIX(dem, x, ny), fb = TS_PIX(dem, nx, y);
        float wself, wother;
        if (isnan(fa) || isnan(fb))
            return 0;
        /* the crossing diagonal joins (nx, y) and (x, ny) */
        if (!connect_is_target(t, w, h, nx, y, kind) || !connect_is_target(t, w, h, x, ny, kind))
            return 1;
        wself = sign * (TS_PIX(dem, x, y) + TS_PIX(dem, nx, ny));
        wother = sign * (fa + fb);
        if (wself != wother)
            return wself > wother;
        /* tie: keep the SE diagonal (k == 3) of the block */
        return k == 3;
    }
    return 1;
}

TS_API ts_status ts_ppa_target_connection(ts_ctx *ctx, const ts_raster *dem,
                                          const unsigned char *targets, int kind,
                                          ts_ppa_segment **segs, size_t *n_segs)
{
    int x, y, k, w, h;
    size_t n = 0, i = 0;
    float sign = kind == TS_VALLEY ? -1.0f : 1.0f;
    ts_ppa_segment *out;
    ts__clear(ctx);
    *segs = NULL;
    *n_segs = 0;
    if (!dem || !dem->data || !targets || (kind != TS_RIDGE && kind != TS_VALLEY))
        return ts__fail(ctx, TS_ERR_ARG, "ppa target connection", "bad arguments");
    w = dem->width;
    h = dem->height;
    if ((uint64_t)w * (uint64_t)h >= UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa target connection",
                        "%d x %d cells is more than this version handles (2^32)", w, h);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (targets[(size_t)y * (size_t)w + (size_t)x] & kind)
                for (k = 0; k < 4; k++)
                    n += (size_t)ppa_segment_exists(dem, targets, kind, x, y, k, sign);
    out = ts__malloc_array(n, sizeof *out);
    if (!out)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa target connection", "cannot allocate %zu segments",
                        n);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (targets[(size_t)y * (size_t)w + (size_t)x] & kind)
                for (k = 0; k < 4; k++)
                    if (ppa_segment_exists(dem, targets, kind, x, y, k, sign)) {
                        int nx = x + connect_step[k][0], ny = y + connect_step[k][1];
                        out[i].a = (uint32_t)((size_t)y * (size_t)w + (size_t)x);
                        out[i].b = (uint32_t)((size_t)ny * (size_t)w + (size_t)nx);
                        out[i].weight = sign * (TS_PIX(dem, x, y) + TS_PIX(dem, nx, ny));
                        i++;
                    }
    if (ts__progress(ctx, 1.0, "target connection") != TS_OK) {
        free(out);
        return ctx->status;
    }
    *segs = out;
    *n_segs = n;
    return TS_OK;
}
