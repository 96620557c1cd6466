/*
 * recipe_raw.c - the windows of a pixel, amplify or sketch-in-tiles recipe with the drainage
 * stage: each window is drained from the method's cells round it (the
 * stage's margin), which come from blocks of the method's output kept in a
 * cache (the least recently used dropped past TSYN_TILE_CACHE_MB), so
 * neighbouring windows do not compute the same cells again.  Any window
 * equals that window of the whole: the method's blocks are its cells, and
 * the stage depends only on the margin.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "recipe_internal.h"

#define RAW_BLOCK 512 /* cells: the side of a cached block of the method's output */

/* Block (bi, bj) of the method's output, computed if not cached. */
static recipe_tile *raw_block(tsrecipe *r, ts_ctx *ctx, int bi, int bj, tsio_err *err)
{
    const tsio_georef *g = tsrecipe_georef(r);
    recipe_tile *t = tsrecipe__cache_find(r->raw, r->n_raw, bi, bj), b;
    if (t) {
        t->used = r->raw_clock;
        return t;
    }
    memset(&b, 0, sizeof b);
    b.ti = bi;
    b.tj = bj;
    b.x0 = bi * RAW_BLOCK;
    b.y0 = bj * RAW_BLOCK;
    b.w = g->width - b.x0 < RAW_BLOCK ? g->width - b.x0 : RAW_BLOCK;
    b.h = g->height - b.y0 < RAW_BLOCK ? g->height - b.y0 : RAW_BLOCK;
    b.used = r->raw_clock;
    b.cells = malloc((size_t)b.w * (size_t)b.h * sizeof *b.cells);
    if (!b.cells) {
        tsio_errf(err, r->path, "out of memory for a block of %d x %d cells", b.w, b.h);
        return NULL;
    }
    if ((r->method == TSRECIPE_PIXEL ? tsjob_pixel_window_raw(ctx, &r->pixel, &r->pixel_res, b.x0,
                                                              b.y0, b.w, b.h, b.cells, err)
         : r->method == TSRECIPE_SYNTH
             ? tsjob_synth_sketch_window_raw(ctx, &r->synth, &r->synth_res, b.x0, b.y0, b.w, b.h,
                                             b.cells, err)
             : tsjob_amplify_window_raw(ctx, &r->amplify, &r->amplify_res, b.x0, b.y0, b.w, b.h,
                                        b.cells, err)) != 0) {
        free(b.cells);
        return NULL;
    }
    if (r->n_raw == r->cap_raw) {
        size_t c = r->cap_raw ? 2 * r->cap_raw : 16;
        recipe_tile *n = realloc(r->raw, c * sizeof *n);
        if (!n) {
            free(b.cells);
            tsio_errf(err, r->path, "out of memory for the block cache");
            return NULL;
        }
        r->raw = n;
        r->cap_raw = c;
    }
    r->raw[r->n_raw] = b;
    r->raw_bytes += (size_t)b.w * (size_t)b.h * sizeof(float);
    return &r->raw[r->n_raw++];
}

/* The method's cells [x0, x0+w) x [y0, y0+h) out of the cached blocks (a
 * tsjob_raw_fn; the caller holds raw_lock). */
static int raw_window(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *cells,
                      unsigned char *flags, tsio_err *err)
{
    tsrecipe *r = arg;
    int bi, bj, y;
    r->raw_clock++;
    /* every block first marked as needed (so none is dropped while the window is made) */
    for (bj = y0 / RAW_BLOCK; bj <= (y0 + h - 1) / RAW_BLOCK; bj++)
        for (bi = x0 / RAW_BLOCK; bi <= (x0 + w - 1) / RAW_BLOCK; bi++) {
            recipe_tile *t = tsrecipe__cache_find(r->raw, r->n_raw, bi, bj);
            if (t)
                t->used = r->raw_clock;
        }
    for (bj = y0 / RAW_BLOCK; bj <= (y0 + h - 1) / RAW_BLOCK; bj++)
        for (bi = x0 / RAW_BLOCK; bi <= (x0 + w - 1) / RAW_BLOCK; bi++) {
            recipe_tile *t = raw_block(r, ctx, bi, bj, err);
            int xa, xb, ya, yb;
            if (!t)
                return -1;
            xa = t->x0 > x0 ? t->x0 : x0;
            xb = t->x0 + t->w < x0 + w ? t->x0 + t->w : x0 + w;
            ya = t->y0 > y0 ? t->y0 : y0;
            yb = t->y0 + t->h < y0 + h ? t->y0 + t->h : y0 + h;
            for (y = ya; y < yb; y++)
                memcpy(cells + (size_t)(y - y0) * (size_t)w + (size_t)(xa - x0),
                       t->cells + (size_t)(y - t->y0) * (size_t)t->w + (size_t)(xa - t->x0),
                       (size_t)(xb - xa) * sizeof *cells);
        }
    tsrecipe__cache_evict(r->raw, &r->n_raw, &r->raw_bytes, r->raw_limit, r->raw_clock);
    if (flags && r->method == TSRECIPE_SYNTH) { /* a sketch's water, pins and drawn ridges */
        if (tsjob_synth_window_flags(&r->synth, &r->synth_res, x0, y0, w, h, flags, NULL, err) != 0)
            return -1;
        tsjob_synth_sketch_barriers(&r->synth_res, x0, y0, w, h, flags);
    }
    return 0;
}

int tsrecipe__raw_init(tsrecipe *r, tsio_err *err)
{
    if (tsrecipe__cache_limit(r, &r->raw_limit, err) != 0)
        return -1;
    if (pthread_mutex_init(&r->raw_lock, NULL) != 0) {
        tsio_errf(err, r->path, "out of resources for a lock");
        return -1;
    }
    r->has_raw_lock = 1;
    return 0;
}

void tsrecipe__raw_free(tsrecipe *r)
{
    size_t k;
    for (k = 0; k < r->n_raw; k++)
        free(r->raw[k].cells);
    free(r->raw);
    r->raw = NULL;
    r->n_raw = r->cap_raw = r->raw_bytes = 0;
    if (r->has_raw_lock)
        pthread_mutex_destroy(&r->raw_lock);
    r->has_raw_lock = 0;
}

int tsrecipe__raw_drained(tsrecipe *r, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                          tsio_err *err)
{
    const tsio_georef *g = tsrecipe_georef(r);
    const ts_drainage_params *p = r->method == TSRECIPE_PIXEL   ? &r->pixel_res.drainage
                                  : r->method == TSRECIPE_SYNTH ? &r->synth_res.drainage
                                                                : &r->amplify_res.drainage;
    int rc;
    pthread_mutex_lock(&r->raw_lock);
    rc = tsjob_drained_window(ctx, p, g->width, g->height, x0, y0, w, h, raw_window, r, out,
                              r->path, err);
    pthread_mutex_unlock(&r->raw_lock);
    return rc;
}
