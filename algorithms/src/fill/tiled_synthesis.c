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

typedef struct tiled_job {
    ts_ctx *parent;
    const ts_raster *exemplars;
    int n_exemplars;
    ts_synth_params params; /* tiled 0: each tile in one piece */
    ts_raster *out;
    int T, G, nti, ntj;
    int32_t *tiles; /* the wave's tiles: i + nti * j */
    atomic_int failed;
    atomic_int status; /* the first failure's status */
    char msg[512];
    atomic_flag msg_taken;
} tiled_job;

/* Synthesise tile (i, j) into out (its core). */
static ts_status tile_run(tiled_job *j, ts_ctx *ctx, int ti, int tj)
{
    ts_raster *out = j->out;
    int W = out->width, H = out->height, T = j->T, G = j->G, w = tile_wave(ti, tj), di, dj,
        x, y;
    int x0 = TS_MAX(ti * T - G, 0), y0 = TS_MAX(tj * T - G, 0);
    int x1 = TS_MIN((ti + 1) * T + G, W), y1 = TS_MIN((tj + 1) * T + G, H);
    int rw = x1 - x0, rh = y1 - y0;
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
            if ((!di && !dj) || ni < 0 || nj < 0 || ni >= j->nti || nj >= j->ntj ||
                tile_wave(ni, nj) >= w)
                continue;
            cx0 = TS_MAX(ni * T, x0);
            cy0 = TS_MAX(nj * T, y0);
            cx1 = TS_MIN((ni + 1) * T, x1);
            cy1 = TS_MIN((nj + 1) * T, y1);
            for (y = cy0; y < cy1; y++)
                for (x = cx0; x < cx1; x++) {
                    TS_PIX(&r, x - x0, y - y0) = TS_PIX(out, x, y);
                    flags[(size_t)(y - y0) * (size_t)rw + (size_t)(x - x0)] = TS_CELL_FIXED;
                }
        }
    cons.cell_flags = flags;
    ts_ctx_set_seed(ctx, tile_seed(ts_ctx_seed(j->parent), ti, tj));
    st = ts_synth_patches(ctx, j->exemplars, j->n_exemplars, &j->params, &cons, &r, NULL);
    if (st == TS_OK) { /* the core */
        int cx0 = ti * T, cy0 = tj * T, cx1 = TS_MIN((ti + 1) * T, W), cy1 = TS_MIN((tj + 1) * T, H);
        for (y = cy0; y < cy1; y++)
            memcpy(&TS_PIX(out, cx0, y), &TS_PIX(&r, cx0 - x0, y - y0),
                   (size_t)(cx1 - cx0) * sizeof(float));
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
        int32_t t = j->tiles[k];
        ts_status st = tile_run(j, ctx, t % j->nti, t / j->nti);
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

TS_API ts_status ts_synth_tiled(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params, int tile, ts_raster *out)
{
    tiled_job j;
    int P, O, wave, ti, tj;
    size_t n;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!params || !out || !out->data || out->width < 1 || out->height < 1)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "missing parameters or output");
    if (ts__synth_cells(ctx, params, &P, &O) != TS_OK)
        return ctx->status;
    if (tile < 2 * P || tile > 16384)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                        "tiles of %d cells: give 2 x the patch (%d) to 16384", tile, 2 * P);
    memset(&j, 0, sizeof j);
    j.parent = ctx;
    j.exemplars = exemplars;
    j.n_exemplars = n_exemplars;
    j.params = *params;
    j.params.tiled = 0; /* each tile in one piece */
    j.out = out;
    j.T = tile;
    j.G = P;
    j.nti = (out->width + tile - 1) / tile;
    j.ntj = (out->height + tile - 1) / tile;
    atomic_flag_clear(&j.msg_taken);
    n = (size_t)j.nti * (size_t)j.ntj;
    j.tiles = ts__malloc_array(n, sizeof *j.tiles);
    if (!j.tiles)
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory");
    for (wave = 0; wave < 4 && st == TS_OK; wave++) {
        size_t m = 0;
        for (tj = 0; tj < j.ntj; tj++)
            for (ti = 0; ti < j.nti; ti++)
                if (tile_wave(ti, tj) == wave)
                    j.tiles[m++] = (int32_t)(ti + j.nti * tj);
        atomic_init(&j.failed, 0);
        atomic_init(&j.status, TS_OK);
        if (m)
            ts__parallel_for(ctx, m, tiles_range, &j);
        if (atomic_load(&j.failed)) {
            int s = atomic_load(&j.status);
            st = s == TS_ERR_CANCELLED && ts__cancelled(ctx) && !j.msg[0]
                     ? ts__check_cancel(ctx)
                     : ts__fail(ctx, (ts_status)(s ? s : TS_ERR_NOMEM), TILED_STAGE, "%s",
                                j.msg[0] ? j.msg : "a tile failed");
            break;
        }
        if ((st = ts__progress(ctx, (wave + 1) / 4.0, "synth tiles")) != TS_OK)
            break;
    }
    free(j.tiles);
    return st;
}
