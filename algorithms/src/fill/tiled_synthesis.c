/*
 * tiled_synthesis.c - free patch synthesis in tiles, in four waves (a
 * TerraSynth addition for terrains past one run: issue 16).
 *
 * The grid is cut into tiles of T x T cells, tile (i, j) covering columns
 * [iT, (i+1)T) and rows [jT, (j+1)T): its core.  Tile (i, j) belongs to
 * wave (i & 1) + 2 (j & 1) and is synthesised over its core grown by a
 * margin G (the patch size), with the cores of its neighbours of earlier
 * waves, where they fall in that window, as fixed cells: wave 0 alone,
 * wave 1 against its left and right wave-0 cores, wave 2 against its upper
 * and lower wave-0 cores and its diagonal wave-1 cores, wave 3 against all
 * eight neighbours.  The fill grows from the fixed cells as from pinned
 * windows, so every border between two cores is cut (graph cut) and
 * smoothed (Poisson seam removal) inside the later tile, like any seam.
 * The output is the union of the cores.  Each tile is a function of the
 * parameters, the seed mixed with (i, j), and its earlier neighbours'
 * cores only, so the result does not depend on the order tiles are made
 * in nor on the thread count: the tiles of one wave run in parallel, one
 * thread each.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

#define TILED_STAGE "synth tiles"

static int tile_wave(int i, int j)
{
    return (i & 1) + 2 * (j & 1);
}

/* The seed of tile (i, j): the run's seed mixed with the tile's index
 * (splitmix64 finaliser). */
static uint64_t tile_seed(uint64_t seed, int i, int j)
{
    uint64_t z = seed ^ (0x9e3779b97f4a7c15ull * ((uint64_t)(uint32_t)i + 1)) ^
                 (0xc2b2ae3d27d4eb4full * ((uint64_t)(uint32_t)j + 1));
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

TS_API int ts_synth_tile_wave(int ti, int tj)
{
    return tile_wave(ti, tj);
}

typedef struct tiled_job {
    ts_ctx *parent;
    const ts_raster *exemplars;
    int n_exemplars;
    ts_synth_params params; /* tiled 0: each tile in one piece */
    int W, H, T, G, nti, ntj;
    ts_synth_tile *tiles;
    atomic_int failed;
    atomic_int status; /* the first failure's status */
    char msg[512];
    atomic_flag msg_taken;
} tiled_job;

/* The size of tile (ti, tj)'s core. */
static void core_size(int W, int H, int T, int ti, int tj, int *cw, int *ch)
{
    *cw = TS_MIN(T, W - ti * T);
    *ch = TS_MIN(T, H - tj * T);
}

/* Synthesise tile t into its core. */
static ts_status tile_run(tiled_job *j, ts_ctx *ctx, ts_synth_tile *t)
{
    int T = j->T, G = j->G, ti = t->ti, tj = t->tj, w = tile_wave(ti, tj), di, dj, x, y;
    int x0 = TS_MAX(ti * T - G, 0), y0 = TS_MAX(tj * T - G, 0);
    int x1 = TS_MIN((ti + 1) * T + G, j->W), y1 = TS_MIN((tj + 1) * T + G, j->H);
    int rw = x1 - x0, rh = y1 - y0, cw, ch;
    ts_raster r;
    unsigned char *flags = ts__calloc_array((size_t)rw * (size_t)rh, 1);
    ts_synth_constraints cons = ts_synth_constraints_default();
    ts_status st;
    if (!flags || ts_raster_alloc(ctx, rw, rh, &r) != TS_OK) {
        free(flags);
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory for a tile");
    }
    for (y = 0; y < rh; y++)
        for (x = 0; x < rw; x++)
            TS_PIX(&r, x, y) = NAN;
    /* the cores of the earlier waves' neighbours, fixed */
    for (dj = -1; dj <= 1; dj++)
        for (di = -1; di <= 1; di++) {
            int ni = ti + di, nj = tj + dj, cx0, cy0, cx1, cy1;
            const ts_raster *nb = t->neighbours[(dj + 1) * 3 + di + 1];
            if ((!di && !dj) || ni < 0 || nj < 0 || ni >= j->nti || nj >= j->ntj ||
                tile_wave(ni, nj) >= w)
                continue;
            cx0 = TS_MAX(ni * T, x0);
            cy0 = TS_MAX(nj * T, y0);
            cx1 = TS_MIN((ni + 1) * T, x1);
            cy1 = TS_MIN((nj + 1) * T, y1);
            for (y = cy0; y < cy1; y++)
                for (x = cx0; x < cx1; x++) {
                    TS_PIX(&r, x - x0, y - y0) = TS_PIX(nb, x - ni * T, y - nj * T);
                    flags[(size_t)(y - y0) * (size_t)rw + (size_t)(x - x0)] = TS_CELL_FIXED;
                }
        }
    cons.cell_flags = flags;
    ts_ctx_set_seed(ctx, tile_seed(ts_ctx_seed(j->parent), ti, tj));
    st = ts_synth_patches(ctx, j->exemplars, j->n_exemplars, &j->params, &cons, &r, NULL);
    if (st == TS_OK) { /* the core */
        core_size(j->W, j->H, T, ti, tj, &cw, &ch);
        for (y = 0; y < ch; y++)
            memcpy(&TS_PIX(&t->core, 0, y), &TS_PIX(&r, ti * T - x0, tj * T + y - y0),
                   (size_t)cw * sizeof(float));
    }
    ts_raster_free(&r);
    free(flags);
    return st;
}

static void tiles_range(void *arg, size_t begin, size_t end)
{
    tiled_job *j = arg;
    ts_ctx *ctx = ts__ctx_child(j->parent);
    size_t k;
    if (!ctx) {
        atomic_store(&j->failed, 1);
        atomic_store(&j->status, TS_ERR_NOMEM);
        ts__cancel(j->parent);
        return;
    }
    ts_ctx_set_threads(ctx, 1);
    for (k = begin; k < end && !atomic_load(&j->failed); k++) {
        ts_status st = tile_run(j, ctx, &j->tiles[k]);
        if (st != TS_OK) {
            if (!atomic_flag_test_and_set(&j->msg_taken)) {
                snprintf(j->msg, sizeof j->msg, "%s", ts_ctx_message(ctx));
                atomic_store(&j->status, st);
            }
            atomic_store(&j->failed, 1);
            ts__cancel(j->parent);
        }
    }
    ts_ctx_free(ctx);
}

/* Check the call's shape; fills P. */
static ts_status tiles_check(ts_ctx *ctx, const ts_synth_params *params, int tile, int width,
                             int height, int *P)
{
    int O;
    if (!params || width < 1 || height < 1)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "missing parameters or output");
    if (ts__synth_cells(ctx, params, P, &O) != TS_OK)
        return ctx->status;
    if (tile < 2 * *P || tile > 16384)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                        "tiles of %d cells: give 2 x the patch (%d) to 16384", tile, 2 * *P);
    return TS_OK;
}

/* Run the list (independent tiles) in parallel, one thread each. */
static ts_status tiles_run(tiled_job *j, ts_synth_tile *tiles, size_t n)
{
    ts_ctx *ctx = j->parent;
    int s;
    j->tiles = tiles;
    atomic_init(&j->failed, 0);
    atomic_init(&j->status, TS_OK);
    atomic_flag_clear(&j->msg_taken);
    j->msg[0] = 0;
    if (n)
        ts__parallel_for(ctx, n, tiles_range, j);
    if (!atomic_load(&j->failed))
        return TS_OK;
    s = atomic_load(&j->status);
    return s == TS_ERR_CANCELLED && ts__cancelled(ctx) && !j->msg[0]
               ? ts__check_cancel(ctx)
               : ts__fail(ctx, (ts_status)(s ? s : TS_ERR_NOMEM), TILED_STAGE, "%s",
                          j->msg[0] ? j->msg : "a tile failed");
}

static void job_init(tiled_job *j, ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                     const ts_synth_params *params, int tile, int width, int height, int P)
{
    memset(j, 0, sizeof *j);
    j->parent = ctx;
    j->exemplars = exemplars;
    j->n_exemplars = n_exemplars;
    j->params = *params;
    j->params.tiled = 0; /* each tile in one piece */
    j->W = width;
    j->H = height;
    j->T = tile;
    j->G = P;
    j->nti = (width + tile - 1) / tile;
    j->ntj = (height + tile - 1) / tile;
}

TS_API ts_status ts_synth_tiles(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params, int tile, int width, int height,
                                ts_synth_tile *tiles, int n_tiles)
{
    tiled_job j;
    int P, k, a, di, dj;
    ts__clear(ctx);
    if (tiles_check(ctx, params, tile, width, height, &P) != TS_OK)
        return ctx->status;
    if (n_tiles < 0 || (n_tiles && !tiles))
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "no tiles");
    job_init(&j, ctx, exemplars, n_exemplars, params, tile, width, height, P);
    for (k = 0; k < n_tiles; k++) {
        const ts_synth_tile *t = &tiles[k];
        int cw, ch, w = tile_wave(t->ti, t->tj);
        if (t->ti < 0 || t->tj < 0 || t->ti >= j.nti || t->tj >= j.ntj)
            return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "tile (%d, %d) is off the %d x %d tiles",
                            t->ti, t->tj, j.nti, j.ntj);
        core_size(width, height, tile, t->ti, t->tj, &cw, &ch);
        if (!t->core.data || t->core.width != cw || t->core.height != ch)
            return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "tile (%d, %d): its core is %d x %d",
                            t->ti, t->tj, cw, ch);
        for (dj = -1; dj <= 1; dj++)
            for (di = -1; di <= 1; di++) {
                int ni = t->ti + di, nj = t->tj + dj, nw, nh;
                const ts_raster *nb = t->neighbours[(dj + 1) * 3 + di + 1];
                if ((!di && !dj) || ni < 0 || nj < 0 || ni >= j.nti || nj >= j.ntj ||
                    tile_wave(ni, nj) >= w)
                    continue;
                core_size(width, height, tile, ni, nj, &nw, &nh);
                if (!nb || !nb->data || nb->width != nw || nb->height != nh)
                    return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                                    "tile (%d, %d) needs the %d x %d core of tile (%d, %d)", t->ti,
                                    t->tj, nw, nh, ni, nj);
            }
        /* tiles of one call run side by side: none may need another */
        for (a = 0; a < k; a++)
            if (abs(tiles[a].ti - t->ti) <= 1 && abs(tiles[a].tj - t->tj) <= 1 &&
                tile_wave(tiles[a].ti, tiles[a].tj) != w)
                return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                                "tiles (%d, %d) and (%d, %d) are neighbours of two waves: "
                                "give them in two calls",
                                tiles[a].ti, tiles[a].tj, t->ti, t->tj);
    }
    return tiles_run(&j, tiles, (size_t)n_tiles);
}

TS_API ts_status ts_synth_tiled(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params, int tile, ts_raster *out)
{
    tiled_job j;
    ts_synth_tile *tiles;
    ts_raster *views; /* every tile's core in out */
    int P, wave, ti, tj, di, dj;
    size_t n;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "missing parameters or output");
    if (tiles_check(ctx, params, tile, out->width, out->height, &P) != TS_OK)
        return ctx->status;
    job_init(&j, ctx, exemplars, n_exemplars, params, tile, out->width, out->height, P);
    n = (size_t)j.nti * (size_t)j.ntj;
    tiles = ts__malloc_array(n, sizeof *tiles);
    views = ts__malloc_array(n, sizeof *views);
    if (!tiles || !views) {
        free(tiles);
        free(views);
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory");
    }
    for (tj = 0; tj < j.ntj; tj++)
        for (ti = 0; ti < j.nti; ti++) {
            int cw, ch;
            core_size(j.W, j.H, tile, ti, tj, &cw, &ch);
            views[(size_t)tj * (size_t)j.nti + (size_t)ti] =
                ts_raster_wrap(&TS_PIX(out, ti * tile, tj * tile), cw, ch, out->stride);
        }
    for (wave = 0; wave < 4 && st == TS_OK; wave++) {
        size_t m = 0;
        for (tj = 0; tj < j.ntj; tj++)
            for (ti = 0; ti < j.nti; ti++) {
                ts_synth_tile *t = &tiles[m];
                if (tile_wave(ti, tj) != wave)
                    continue;
                memset(t, 0, sizeof *t);
                t->ti = ti;
                t->tj = tj;
                t->core = views[(size_t)tj * (size_t)j.nti + (size_t)ti];
                for (dj = -1; dj <= 1; dj++)
                    for (di = -1; di <= 1; di++)
                        if (ti + di >= 0 && tj + dj >= 0 && ti + di < j.nti && tj + dj < j.ntj)
                            t->neighbours[(dj + 1) * 3 + di + 1] =
                                &views[(size_t)(tj + dj) * (size_t)j.nti + (size_t)(ti + di)];
                m++;
            }
        if ((st = tiles_run(&j, tiles, m)) != TS_OK)
            break;
        st = ts__progress(ctx, (wave + 1) / 4.0, "synth tiles");
    }
    free(tiles);
    free(views);
    return st;
}
