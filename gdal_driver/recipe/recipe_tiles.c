/*
 * recipe_tiles.c - the tiles of a tiled synth recipe: made on demand for the
 * driver's windows (a cache with a limit), and one by one for the Dask runner
 * (tsyn_tiles.h).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_minixml.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>

#include "recipe_internal.h"
#include "tsyn_tiles.h"

/* ---- a tiled synth recipe, tile by tile ---------------------------- */

recipe_tile *tsrecipe__cache_find(recipe_tile *t, size_t n, int ti, int tj)
{
    size_t k;
    for (k = 0; k < n; k++)
        if (t[k].ti == ti && t[k].tj == tj)
            return &t[k];
    return NULL;
}

static recipe_tile *tile_find(const tsrecipe *r, int ti, int tj)
{
    return tsrecipe__cache_find(r->tiles, r->n_tiles, ti, tj);
}

/* Add (ti, tj) to the list of wanted tiles unless there. */
static int want_add(int **list, size_t *n, size_t *cap, int ti, int tj)
{
    size_t k;
    for (k = 0; k < *n; k++)
        if ((*list)[2 * k] == ti && (*list)[2 * k + 1] == tj)
            return 0;
    if (*n == *cap) {
        size_t c = *cap ? 2 * *cap : 32;
        int *l = realloc(*list, c * 2 * sizeof **list);
        if (!l)
            return -1;
        *list = l;
        *cap = c;
    }
    (*list)[2 * *n] = ti;
    (*list)[2 * *n + 1] = tj;
    (*n)++;
    return 0;
}

void tsrecipe__cache_evict(recipe_tile *t, size_t *n, size_t *bytes, size_t limit, uint64_t clock)
{
    while (*bytes > limit) {
        size_t k, old = *n;
        for (k = 0; k < *n; k++)
            if (t[k].used != clock && (old == *n || t[k].used < t[old].used))
                old = k;
        if (old == *n)
            return;
        *bytes -= (size_t)t[old].w * (size_t)t[old].h * sizeof(float);
        free(t[old].cells);
        t[old] = t[--*n];
    }
}

int tsrecipe__cache_limit(const tsrecipe *r, size_t *bytes, tsio_err *err)
{
    const char *mb = CPLGetConfigOption("TSYN_TILE_CACHE_MB", "256");
    char *end = NULL;
    double v = strtod(mb, &end);
    if (end == mb || *end || !(v >= 0 && v <= 1e6)) {
        tsio_errf(err, r->path, "TSYN_TILE_CACHE_MB=%s: give megabytes, 0 to 1000000", mb);
        return -1;
    }
    *bytes = (size_t)(v * 1048576.0);
    return 0;
}

/* Where tile (ti, tj) lies: win and core = {x, y, w, h} (ts_synth_tile_window;
 * ctx for errors). */
static int tile_rect(const tsrecipe *r, ts_ctx *ctx, int ti, int tj, int win[4], int core[4])
{
    const tsjob_synth_result *res = &r->synth_res;
    return ts_synth_tile_window(ctx, &res->params, res->params.tiled, res->geo.width,
                                res->geo.height, ti, tj, win, core) == TS_OK
               ? 0
               : -1;
}

/* Make n (<= 64) tiles of one wave side by side and put them in the cache
 * (their earlier-wave neighbours are there). */
static int tiles_make(tsrecipe *r, ts_ctx *ctx, ts_synth_tile *batch, size_t n, tsio_err *err)
{
    const tsjob_synth_result *res = &r->synth_res;
    int di, dj, nv = 0;
    ts_raster views[9 * 64];
    int win[64][4];
    size_t g;
    for (g = 0; g < n; g++) {
        ts_synth_tile *t = &batch[g];
        float *cells;
        if (tile_rect(r, ctx, t->ti, t->tj, win[g], NULL) != 0) {
            tsio_errf(err, r->path, "%s", ts_ctx_message(ctx));
            goto fail;
        }
        cells = malloc((size_t)win[g][2] * (size_t)win[g][3] * sizeof(float));
        if (!cells)
            goto oom;
        t->window = ts_raster_wrap(cells, win[g][2], win[g][3], win[g][2]);
        for (dj = -1; dj <= 1; dj++)
            for (di = -1; di <= 1; di++) {
                recipe_tile *nb = tile_find(r, t->ti + di, t->tj + dj);
                if (nb) {
                    views[nv] = ts_raster_wrap(nb->cells, nb->w, nb->h, nb->w);
                    t->neighbours[(dj + 1) * 3 + di + 1] = &views[nv++];
                }
            }
    }
    if (r->n_tiles + n > r->cap_tiles) {
        size_t c = 2 * (r->n_tiles + n);
        recipe_tile *l = realloc(r->tiles, c * sizeof *l);
        if (!l)
            goto oom;
        r->tiles = l;
        r->cap_tiles = c;
    }
    if (tsjob_synth_tiles(ctx, &r->synth, res, batch, (int)n, err) != 0)
        goto fail;
    for (g = 0; g < n; g++) { /* into the cache */
        recipe_tile *e = &r->tiles[r->n_tiles++];
        e->ti = batch[g].ti;
        e->tj = batch[g].tj;
        e->x0 = win[g][0];
        e->y0 = win[g][1];
        e->w = batch[g].window.width;
        e->h = batch[g].window.height;
        e->cells = batch[g].window.data;
        e->used = r->tile_clock;
        r->tile_bytes += (size_t)e->w * (size_t)e->h * sizeof(float);
    }
    return 0;
oom:
    tsio_errf(err, r->path, "out of memory for the tiles");
fail:
    for (g = 0; g < n; g++)
        free(batch[g].window.data);
    return -1;
}

/* Cells [x0, x0+w) x [y0, y0+h) of a tiled synth recipe: the tiles under the
 * window, and before them the tiles of earlier waves they need (their cone),
 * made wave by wave (a wave's tiles side by side), kept for later requests. */
int tsrecipe__tiles_window(tsrecipe *r, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                           tsio_err *err)
{
    const tsjob_synth_result *res = &r->synth_res;
    int T = res->params.tiled, W = res->geo.width, H = res->geo.height;
    int nti = (W + T - 1) / T, ntj = (H + T - 1) / T, wave, ti, tj, di, dj, rc = -1;
    int *want = NULL;
    size_t n_want = 0, cap_want = 0, k, m;
    ts_synth_tile *batch = NULL;
    pthread_mutex_lock(&r->tile_lock);
    r->tile_clock++;
    for (tj = y0 / T; tj <= (y0 + h - 1) / T; tj++)
        for (ti = x0 / T; ti <= (x0 + w - 1) / T; ti++)
            if (want_add(&want, &n_want, &cap_want, ti, tj) != 0)
                goto oom;
    /* the cone: dependencies go to earlier waves only, so one pass from
     * the last wave down finds them all */
    for (wave = 3; wave > 0; wave--)
        for (k = 0; k < n_want; k++) {
            int i = want[2 * k], j = want[2 * k + 1];
            if (ts_synth_tile_wave(i, j) != wave)
                continue;
            for (dj = -1; dj <= 1; dj++)
                for (di = -1; di <= 1; di++)
                    if (i + di >= 0 && j + dj >= 0 && i + di < nti && j + dj < ntj &&
                        ts_synth_tile_wave(i + di, j + dj) < wave &&
                        want_add(&want, &n_want, &cap_want, i + di, j + dj) != 0)
                        goto oom;
        }
    for (k = 0; k < n_want; k++) {
        recipe_tile *t = tile_find(r, want[2 * k], want[2 * k + 1]);
        if (t)
            t->used = r->tile_clock;
    }
    batch = calloc(n_want ? n_want : 1, sizeof *batch);
    if (!batch)
        goto oom;
    for (wave = 0; wave < 4; wave++) {
        m = 0;
        for (k = 0; k < n_want; k++) {
            int i = want[2 * k], j = want[2 * k + 1];
            if (ts_synth_tile_wave(i, j) == wave && !tile_find(r, i, j)) {
                memset(&batch[m], 0, sizeof batch[m]);
                batch[m].ti = i;
                batch[m].tj = j;
                m++;
            }
        }
        for (k = 0; k < m; k += 64)
            if (tiles_make(r, ctx, &batch[k], m - k < 64 ? m - k : 64, err) != 0)
                goto done;
    }
    { /* the window out of its tiles */
        int y;
        for (y = y0; y < y0 + h; y++) {
            int x = x0;
            while (x < x0 + w) {
                const recipe_tile *t = tile_find(r, x / T, y / T);
                int end = (x / T + 1) * T < x0 + w ? (x / T + 1) * T : x0 + w;
                memcpy(out + (size_t)(y - y0) * (size_t)w + (size_t)(x - x0),
                       t->cells + (size_t)(y - t->y0) * (size_t)t->w + (size_t)(x - t->x0),
                       (size_t)(end - x) * sizeof(float));
                x = end;
            }
        }
    }
    rc = 0;
    goto done;
oom:
    tsio_errf(err, r->path, "out of memory for the tiles");
done:
    tsrecipe__cache_evict(r->tiles, &r->n_tiles, &r->tile_bytes, r->synth.tile_cache,
                          r->tile_clock);
    pthread_mutex_unlock(&r->tile_lock);
    free(batch);
    free(want);
    return rc;
}

/* ------------------------------------------------------------------ */
/* Tiles for the Dask runner                                           */
/* ------------------------------------------------------------------ */

#define TSYN_EXPORT __attribute__((visibility("default")))

static void copy_err(const tsio_err *e, char *msg, int n)
{
    if (msg && n > 0)
        snprintf(msg, (size_t)n, "%s", e->msg);
}

TSYN_EXPORT int tsyn_tiles_open(const char *path, void **handle, int *width, int *height, int *tile,
                                char *msg, int n)
{
    tsrecipe *r = NULL;
    tsio_err err;
    *handle = NULL;
    if (tsrecipe_open(path, NULL, &r, &err) != 0) {
        copy_err(&err, msg, n);
        return -1;
    }
    if (r->method != TSRECIPE_SYNTH || !r->synth.lazy) {
        tsio_errf(&err, path, "not a tiled synth recipe (give it <Param name=\"tiled\">)");
        tsrecipe_free(r);
        copy_err(&err, msg, n);
        return -1;
    }
    if (tsrecipe_compute(r, &err) != 0) {
        tsrecipe_free(r);
        copy_err(&err, msg, n);
        return -1;
    }
    *width = r->synth_res.geo.width;
    *height = r->synth_res.geo.height;
    *tile = r->synth_res.params.tiled;
    *handle = r;
    return 0;
}

TSYN_EXPORT int tsyn_tile_rect(void *handle, int ti, int tj, int win[4], int core[4], char *msg,
                               int n)
{
    tsrecipe *r = handle;
    ts_ctx *ctx = ts_ctx_new();
    int rc = ctx ? tile_rect(r, ctx, ti, tj, win, core) : -1;
    if (rc != 0 && msg && n > 0)
        snprintf(msg, (size_t)n, "%s: %s", r->path, ctx ? ts_ctx_message(ctx) : "out of memory");
    ts_ctx_free(ctx);
    return rc;
}

/* Tile (ti, tj)'s window into window (row by row, its own width: see
 * tsyn_tile_rect), from the windows of its neighbours, nb[(dj + 1) * 3 + di
 * + 1] (each row by row, its own width), NULL where not needed. */
TSYN_EXPORT int tsyn_tile_make(void *handle, int ti, int tj, const float *const nb[9],
                               float *window, char *msg, int n)
{
    tsrecipe *r = handle;
    int k, rc, win[4];
    ts_raster views[9];
    ts_synth_tile t;
    ts_ctx *ctx = ts_ctx_new();
    tsio_err err;
    memset(&t, 0, sizeof t);
    if (!ctx) {
        tsio_errf(&err, r->path, "out of memory");
        copy_err(&err, msg, n);
        return -1;
    }
    if (tile_rect(r, ctx, ti, tj, win, NULL) != 0) {
        tsio_errf(&err, r->path, "%s", ts_ctx_message(ctx));
        copy_err(&err, msg, n);
        ts_ctx_free(ctx);
        return -1;
    }
    t.ti = ti;
    t.tj = tj;
    t.window = ts_raster_wrap(window, win[2], win[3], win[2]);
    for (k = 0; k < 9; k++) {
        int nw[4];
        if (!nb[k] || tile_rect(r, ctx, ti + k % 3 - 1, tj + k / 3 - 1, nw, NULL) != 0)
            continue;
        views[k] = ts_raster_wrap((float *)(uintptr_t)nb[k], nw[2], nw[3], nw[2]);
        t.neighbours[k] = &views[k];
    }
    ts_ctx_set_seed(ctx, r->seed);
    ts_ctx_set_threads(ctx, 1);
    {
        tsio_offline g;
        tsio_offline_begin(&g);
        rc = tsjob_synth_tiles(ctx, &r->synth, &r->synth_res, &t, 1, &err);
        tsio_offline_end(&g);
    }
    ts_ctx_free(ctx);
    if (rc != 0) {
        copy_err(&err, msg, n);
        return -1;
    }
    return 0;
}

TSYN_EXPORT int tsyn_tile_reach(void *handle)
{
    tsrecipe *r = handle;
    int M = ts_drainage_margin(&r->synth.drainage), T = r->synth_res.params.tiled;
    return M ? (M + T - 1) / T : 0;
}

/* The tiles' cores the drained core of a tile reads (a tsjob_raw_fn). */
typedef struct tile_drain_arg {
    tsrecipe *r;
    ts_ctx *ctx;
    int ti, tj, reach;
    const float *const *nb;
} tile_drain_arg;

static int tile_drain_raw(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *cells,
                          unsigned char *flags, tsio_err *err)
{
    tile_drain_arg *a = arg;
    tsrecipe *r = a->r;
    int T = r->synth_res.params.tiled, side = 2 * a->reach + 1, i, j, x, y;
    /* each tile's part of the window out of its own window (the mosaic's
     * cell (x, y) is tile (x / T, y / T)'s) */
    for (j = y0 / T; j <= (y0 + h - 1) / T; j++)
        for (i = x0 / T; i <= (x0 + w - 1) / T; i++) {
            int di = i - a->ti, dj = j - a->tj, win[4];
            int xa = i * T > x0 ? i * T : x0, xb = (i + 1) * T < x0 + w ? (i + 1) * T : x0 + w;
            int ya = j * T > y0 ? j * T : y0, yb = (j + 1) * T < y0 + h ? (j + 1) * T : y0 + h;
            const float *t = NULL;
            if (di >= -a->reach && di <= a->reach && dj >= -a->reach && dj <= a->reach)
                t = a->nb[(dj + a->reach) * side + di + a->reach];
            if (!t || tile_rect(r, ctx, i, j, win, NULL) != 0) {
                tsio_errf(err, r->path, "tile %d,%d: the tile %d,%d it reads is not given", a->ti,
                          a->tj, i, j);
                return -1;
            }
            for (y = ya; y < yb; y++)
                for (x = xa; x < xb; x++)
                    cells[(size_t)(y - y0) * (size_t)w + (size_t)(x - x0)] =
                        t[(size_t)(y - win[1]) * (size_t)win[2] + (size_t)(x - win[0])];
        }
    return flags
               ? tsjob_synth_window_flags(&r->synth, &r->synth_res, x0, y0, w, h, flags, NULL, err)
               : 0;
}

TSYN_EXPORT int tsyn_tile_drain(void *handle, int ti, int tj, const float *const *nb, float *core,
                                char *msg, int n)
{
    tsrecipe *r = handle;
    ts_ctx *ctx = ts_ctx_new();
    tile_drain_arg a;
    int c[4], rc;
    tsio_err err;
    if (!ctx) {
        tsio_errf(&err, r->path, "out of memory");
        copy_err(&err, msg, n);
        return -1;
    }
    if (tile_rect(r, ctx, ti, tj, NULL, c) != 0) {
        tsio_errf(&err, r->path, "%s", ts_ctx_message(ctx));
        copy_err(&err, msg, n);
        ts_ctx_free(ctx);
        return -1;
    }
    a.r = r;
    a.ctx = ctx;
    a.ti = ti;
    a.tj = tj;
    a.reach = tsyn_tile_reach(handle);
    a.nb = nb;
    ts_ctx_set_threads(ctx, 1);
    rc = tsjob_drained_window(ctx, &r->synth_res.drainage, r->synth_res.geo.width,
                              r->synth_res.geo.height, c[0], c[1], c[2], c[3], tile_drain_raw, &a,
                              core, r->path, &err);
    ts_ctx_free(ctx);
    if (rc != 0)
        copy_err(&err, msg, n);
    return rc;
}

TSYN_EXPORT void tsyn_tiles_close(void *handle)
{
    tsrecipe_free(handle);
}
