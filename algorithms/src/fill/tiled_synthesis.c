/*
 * tiled_synthesis.c - free patch synthesis in tiles, in four waves (a
 * TerraSynth addition for terrains past one run).
 *
 * The grid is cut into tiles of T x T cells, tile (i, j) covering columns
 * [iT, (i+1)T) and rows [jT, (j+1)T): its core.  Tile (i, j) belongs to
 * wave (i & 1) + 2 (j & 1) and is synthesised over its window, the core
 * grown by a margin G (the patch size) and clipped to the grid, starting
 * from its neighbours of earlier waves: wave 0 alone, wave 1 after its
 * left and right wave-0 tiles, wave 2 after its upper and lower wave-0
 * tiles and its diagonal wave-1 tiles, wave 3 after all eight.  Their
 * cores are fixed cells; their margins, the parts of their windows that
 * reach into this tile (made with their cores, so continuous with them),
 * are existing terrain that the fill matches against, may cut away and
 * smooths (a cell in the margins of two earlier tiles starts empty).  So
 * next to a fixed core lies the terrain that was made with it, and the
 * seams between tiles fall where new patches meet those margins, cut
 * (graph cut) and smoothed (Poisson seam removal) on both sides like any
 * seam: not along the tile border, where a fixed side would leave a kink.
 * The output is the union of the cores.  Each tile is a function of the
 * parameters, the seed mixed with (i, j), and its earlier neighbours'
 * windows only, so the result does not depend on the order tiles are made
 * in nor on the thread count: the tiles of one wave run in parallel, one
 * thread each (a wave of fewer tiles than threads shares them out: a
 * tile's fill gives the same bytes on any number).
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

/* Tile (ti, tj)'s core and window: [x0, x1) x [y0, y1) each. */
typedef struct tile_rect {
    int cx0, cy0, cx1, cy1; /* core */
    int x0, y0, x1, y1;     /* window */
} tile_rect;

static tile_rect rect_of(int W, int H, int T, int G, int ti, int tj)
{
    tile_rect r;
    r.cx0 = ti * T;
    r.cy0 = tj * T;
    r.cx1 = TS_MIN((ti + 1) * T, W);
    r.cy1 = TS_MIN((tj + 1) * T, H);
    r.x0 = TS_MAX(r.cx0 - G, 0);
    r.y0 = TS_MAX(r.cy0 - G, 0);
    r.x1 = TS_MIN(r.cx1 + G, W);
    r.y1 = TS_MIN(r.cy1 + G, H);
    return r;
}

/* A tile's debug maps over its window (ts_synth_maps, window-sized). */
typedef struct tile_maps {
    int32_t *se, *sx, *sy, *order;
    unsigned char *seams;
    int n_patches; /* placed by this tile */
    double sec[4]; /* prepare, match, cut, Poisson */
} tile_maps;

typedef struct tiled_job {
    ts_ctx *parent;
    const ts_raster *exemplars;
    int n_exemplars;
    ts_synth_params params; /* tiled 0: each tile in one piece */
    int W, H, T, G, nti, ntj;
    int tile_threads; /* threads per tile: the call's shared among the tiles run */
    /* the whole grid's constraints (or NULL) and its cells on entry (the
     * fixed cells' values: they never change) */
    const ts_synth_constraints *cons;
    const ts_raster *initial;
    ts_synth_tile *tiles;
    size_t n_tiles;
    atomic_size_t next; /* the next tile a worker takes */
    tile_maps *tm; /* per tile (tj * nti + ti) with debug maps, or NULL */
    atomic_int failed;
    atomic_int status; /* the first failure's status */
    char msg[512];
    atomic_flag msg_taken;
} tiled_job;

/* Is neighbour (ti + di, tj + dj) on the grid and of an earlier wave? */
static int earlier(const tiled_job *j, int ti, int tj, int di, int dj)
{
    int ni = ti + di, nj = tj + dj;
    return (di || dj) && ni >= 0 && nj >= 0 && ni < j->nti && nj < j->ntj &&
           tile_wave(ni, nj) < tile_wave(ti, tj);
}

/* A tile's window's constraints (ts_synth_tile.constraints, or the whole
 * grid's cut to the window) and the fixed cells' values. */
typedef struct window_cons {
    ts_synth_constraints c; /* window-sized arrays */
    unsigned char *flags;   /* owned by the cut (NULL otherwise) */
    int32_t *cell_ex;
    float *heights;
    float *fixed; /* the window's fixed cells' values */
} window_cons;

/* The whole grid's constraints cut to a tile's window me: flags, the
 * exemplar of each cell's region, the wanted heights, and the fixed cells'
 * values from the grid on entry.  Returns 0 when out of memory. */
static int tile_cut_constraints(const tiled_job *j, const tile_rect *me, window_cons *w)
{
    const ts_synth_constraints *g = j->cons;
    int rw = me->x1 - me->x0, rh = me->y1 - me->y0, x, y;
    size_t n = (size_t)rw * (size_t)rh;
    if ((g->cell_flags && (!(w->flags = ts__malloc_array(n, 1)) ||
                           !(w->fixed = ts__malloc_array(n, sizeof *w->fixed)))) ||
        (g->cell_exemplar && !(w->cell_ex = ts__malloc_array(n, sizeof *w->cell_ex))) ||
        (g->heights && !(w->heights = ts__malloc_array(n, sizeof *w->heights))))
        return 0;
    for (y = 0; y < rh; y++)
        for (x = 0; x < rw; x++) {
            size_t c = (size_t)y * (size_t)rw + (size_t)x;
            size_t gc = (size_t)(y + me->y0) * (size_t)j->W + (size_t)(x + me->x0);
            if (w->flags) {
                w->flags[c] = g->cell_flags[gc];
                w->fixed[c] = TS_PIX(j->initial, x + me->x0, y + me->y0);
            }
            if (w->cell_ex)
                w->cell_ex[c] = g->cell_exemplar[gc];
            if (w->heights)
                w->heights[c] = g->heights[gc];
        }
    w->c = ts_synth_constraints_default();
    w->c.cell_flags = w->flags;
    w->c.cell_exemplar = w->cell_ex;
    w->c.heights = w->heights;
    w->c.alpha_h = g->alpha_h;
    return 1;
}

static void window_cons_free(window_cons *w)
{
    free(w->flags);
    free(w->cell_ex);
    free(w->heights);
    free(w->fixed);
}

/* Empty the non-fixed cells of r within R cells (Chebyshev) of a cell
 * whose 4-neighbour holds another margin (cover: 1 + the neighbour's slot,
 * 0 none).  Returns 0 when out of memory. */
static int meet_empty(const unsigned char *cover, const unsigned char *flags, ts_raster *r, int rw,
                      int rh, int R)
{
    size_t n = (size_t)rw * (size_t)rh;
    int *row = ts__malloc_array(n, sizeof *row),
        *acc = ts__malloc_array((size_t)rw + 1, sizeof *acc);
    unsigned char *m = ts__calloc_array(n, 1);
    int x, y;
    if (!row || !acc || !m) {
        free(row);
        free(acc);
        free(m);
        return 0;
    }
    for (y = 0; y < rh; y++)
        for (x = 0; x < rw; x++) {
            size_t c = (size_t)y * (size_t)rw + (size_t)x;
            unsigned char o = cover[c];
            if (!o || flags[c])
                continue;
            if ((x + 1 < rw && cover[c + 1] && cover[c + 1] != o && !flags[c + 1]) ||
                (y + 1 < rh && cover[c + (size_t)rw] && cover[c + (size_t)rw] != o &&
                 !flags[c + (size_t)rw]))
                m[c] = 1;
        }
    /* box dilation by R: along rows, then along columns (prefix sums) */
    for (y = 0; y < rh; y++) {
        const unsigned char *mr = m + (size_t)y * (size_t)rw;
        acc[0] = 0;
        for (x = 0; x < rw; x++)
            acc[x + 1] = acc[x] + mr[x];
        for (x = 0; x < rw; x++)
            row[(size_t)y * (size_t)rw + (size_t)x] =
                acc[TS_MIN(x + R + 1, rw)] - acc[TS_MAX(x - R, 0)] > 0;
    }
    for (x = 0; x < rw; x++) {
        int run = 0;
        for (y = 0; y < TS_MIN(R, rh); y++)
            run += row[(size_t)y * (size_t)rw + (size_t)x];
        for (y = 0; y < rh; y++) {
            size_t c = (size_t)y * (size_t)rw + (size_t)x;
            if (y + R < rh)
                run += row[(size_t)(y + R) * (size_t)rw + (size_t)x];
            if (y - R - 1 >= 0)
                run -= row[(size_t)(y - R - 1) * (size_t)rw + (size_t)x];
            if (run > 0 && cover[c] && !flags[c])
                TS_PIX(r, x, y) = NAN;
        }
    }
    free(row);
    free(acc);
    free(m);
    return 1;
}

/* Cell c from no exemplar. */
static void tile_maps_none(tile_maps *m, size_t c)
{
    m->se[c] = m->sx[c] = m->sy[c] = m->order[c] = -1;
    m->seams[c] = 0;
}

/* Maps: every cell of a window from nothing. */
static void tile_maps_clear(tile_maps *m, size_t n)
{
    size_t c;
    for (c = 0; c < n; c++)
        tile_maps_none(m, c);
}

/* Cell c of m takes cell o of an earlier tile's maps.  Its patch index is
 * stored as -2 - index until the wave is done (tiled_maps_finish): the
 * fill numbers this tile's own patches from 0. */
static void tile_maps_take(tile_maps *m, size_t c, const tile_maps *from, size_t o)
{
    m->se[c] = from->se[o];
    m->sx[c] = from->sx[o];
    m->sy[c] = from->sy[o];
    m->order[c] = from->order[o] >= 0 ? -2 - from->order[o] : -1;
    m->seams[c] = from->seams[o];
}

/* Synthesise tile t over its window. */
static ts_status tile_run(tiled_job *j, ts_ctx *ctx, ts_synth_tile *t)
{
    int ti = t->ti, tj = t->tj, di, dj, x, y;
    tile_rect me = rect_of(j->W, j->H, j->T, j->G, ti, tj);
    int rw = me.x1 - me.x0, rh = me.y1 - me.y0;
    size_t n = (size_t)rw * (size_t)rh, c;
    ts_raster r = t->window; /* made in place */
    unsigned char *flags = ts__calloc_array(n, 1), *cover = ts__calloc_array(n, 1);
    ts_synth_constraints cons = ts_synth_constraints_default();
    tile_maps *tm = j->tm ? &j->tm[(size_t)tj * (size_t)j->nti + (size_t)ti] : NULL;
    /* the window's constraints: the tile's own (ts_synth_tiles: the fixed
     * cells' values in the window on entry) or the grid's cut to it */
    window_cons w;
    const ts_synth_constraints *wc = j->cons ? &w.c : t->constraints;
    ts_synth_maps maps;
    ts_status st;
    memset(&w, 0, sizeof w);
    if (!flags || !cover || (j->cons && !tile_cut_constraints(j, &me, &w)) ||
        (!j->cons && wc && wc->cell_flags && !(w.fixed = ts__malloc_array(n, sizeof *w.fixed)))) {
        free(flags);
        free(cover);
        window_cons_free(&w);
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory for a tile");
    }
    for (y = 0; y < rh; y++)
        for (x = 0; x < rw; x++) {
            if (!j->cons && w.fixed)
                w.fixed[(size_t)y * (size_t)rw + (size_t)x] = TS_PIX(&r, x, y);
            TS_PIX(&r, x, y) = NAN;
        }
    if (tm)
        tile_maps_clear(tm, n);
    /* the earlier neighbours: their cores fixed, their margins as terrain
     * to match and cut against; where several reach, the latest wave's (made
     * with the others' cores around it) */
    for (dj = -1; dj <= 1; dj++)
        for (di = -1; di <= 1; di++) {
            const ts_raster *nb = t->neighbours[(dj + 1) * 3 + di + 1];
            int k = (dj + 1) * 3 + di + 1, wn;
            tile_rect o;
            if (!earlier(j, ti, tj, di, dj))
                continue;
            wn = tile_wave(ti + di, tj + dj);
            o = rect_of(j->W, j->H, j->T, j->G, ti + di, tj + dj);
            for (y = TS_MAX(o.y0, me.y0); y < TS_MIN(o.y1, me.y1); y++)
                for (x = TS_MAX(o.x0, me.x0); x < TS_MIN(o.x1, me.x1); x++) {
                    float v = TS_PIX(nb, x - o.x0, y - o.y0);
                    int taken = 0;
                    c = (size_t)(y - me.y0) * (size_t)rw + (size_t)(x - me.x0);
                    if (x >= o.cx0 && x < o.cx1 && y >= o.cy0 && y < o.cy1) {
                        flags[c] = TS_CELL_FIXED;
                        TS_PIX(&r, x - me.x0, y - me.y0) = v;
                        taken = 1;
                    } else if (!flags[c] &&
                               (!cover[c] || tile_wave(ti + (cover[c] - 1) % 3 - 1,
                                                       tj + (cover[c] - 1) / 3 - 1) < wn)) {
                        cover[c] = (unsigned char)(k + 1);
                        TS_PIX(&r, x - me.x0, y - me.y0) = v;
                        taken = 1;
                    }
                    if (taken && tm)
                        tile_maps_take(
                            tm, c, &j->tm[(size_t)(tj + dj) * (size_t)j->nti + (size_t)(ti + di)],
                            (size_t)(y - o.y0) * (size_t)(o.x1 - o.x0) + (size_t)(x - o.x0));
                }
        }
    /* where two margins meet: empty within a quarter patch of the line, so
     * the fill lays whole patches across it and cuts irregular seams (a thin
     * strip would leave a straight line) */
    if (!meet_empty(cover, flags, &r, rw, rh, TS_MAX(2, j->G / 4))) {
        free(cover);
        free(flags);
        window_cons_free(&w);
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory for a tile");
    }
    free(cover);
    cons.cell_flags = flags;
    if (wc) {
        /* the user's fixed cells with their values, nodata cells empty (and
         * from no exemplar in the maps) */
        for (c = 0; c < n && wc->cell_flags; c++) {
            float *v = &r.data[(c / (size_t)rw) * (size_t)r.stride + c % (size_t)rw];
            if (wc->cell_flags[c] & TS_CELL_NODATA) {
                flags[c] = TS_CELL_NODATA;
                *v = NAN;
            } else if (wc->cell_flags[c] & TS_CELL_FIXED) {
                flags[c] = (unsigned char)(TS_CELL_FIXED | (wc->cell_flags[c] & TS_CELL_WATER));
                *v = w.fixed[c];
            }
            if (tm && (wc->cell_flags[c] & (TS_CELL_FIXED | TS_CELL_NODATA)))
                tile_maps_none(tm, c);
        }
        cons.cell_exemplar = wc->cell_exemplar;
        cons.heights = wc->heights;
        cons.alpha_h = wc->alpha_h;
    }
    if (tm) {
        memset(&maps, 0, sizeof maps);
        maps.source_exemplar = tm->se;
        maps.source_x = tm->sx;
        maps.source_y = tm->sy;
        maps.order = tm->order;
        maps.seams = tm->seams;
    }
    ts_ctx_set_seed(ctx, tile_seed(ts_ctx_seed(j->parent), ti, tj));
    /* (maps.n_patches 0: each placement's random stream is as without maps) */
    st = ts_synth_patches(ctx, j->exemplars, j->n_exemplars, &j->params, &cons, &r,
                          tm ? &maps : NULL);
    if (tm) {
        tm->n_patches = maps.n_patches;
        tm->sec[0] = maps.seconds_prepare;
        tm->sec[1] = maps.seconds_match;
        tm->sec[2] = maps.seconds_cut;
        tm->sec[3] = maps.seconds_poisson;
    }
    free(flags);
    window_cons_free(&w);
    return st;
}

/* One worker: it takes the tiles one by one, the next not yet taken (tiles
 * differ in cost, by wave and at the grid's edges; fixed shares of the list
 * left a thread idle at the end of each wave).  The bytes do not depend on
 * who makes which tile. */
static void tiles_range(void *arg, size_t begin, size_t end)
{
    tiled_job *j = arg;
    ts_ctx *ctx = ts__ctx_child(j->parent);
    size_t k;
    (void)begin;
    (void)end;
    if (!ctx) {
        atomic_store(&j->failed, 1);
        atomic_store(&j->status, TS_ERR_NOMEM);
        ts__cancel(j->parent);
        return;
    }
    ts_ctx_set_threads(ctx, j->tile_threads);
    while (!atomic_load(&j->failed) && (k = atomic_fetch_add(&j->next, 1)) < j->n_tiles) {
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

/* Run the list (independent tiles) in parallel. */
static ts_status tiles_run(tiled_job *j, ts_synth_tile *tiles, size_t n)
{
    ts_ctx *ctx = j->parent;
    int s, threads = ts__thread_count(ctx, 64);
    j->tiles = tiles;
    j->n_tiles = n;
    atomic_init(&j->next, 0);
    /* a wave of fewer tiles than threads: each tile's fill gets the rest (its
     * bytes do not depend on its thread count) */
    j->tile_threads = n ? TS_MAX(1, threads / (int)TS_MIN(n, 64)) : 1;
    atomic_init(&j->failed, 0);
    atomic_init(&j->status, TS_OK);
    atomic_flag_clear(&j->msg_taken);
    j->msg[0] = 0;
    if (n) /* as many workers as threads, at most one per tile */
        ts__parallel_for(ctx, TS_MIN(n, (size_t)threads), tiles_range, j);
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

TS_API ts_status ts_synth_tile_window(ts_ctx *ctx, const ts_synth_params *params, int tile,
                                      int width, int height, int ti, int tj, int window[4],
                                      int core[4])
{
    int P;
    tile_rect r;
    ts__clear(ctx);
    if (tiles_check(ctx, params, tile, width, height, &P) != TS_OK)
        return ctx->status;
    if (ti < 0 || tj < 0 || ti > (width - 1) / tile || tj > (height - 1) / tile)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "tile (%d, %d) is off the grid", ti, tj);
    r = rect_of(width, height, tile, P, ti, tj);
    if (window) {
        window[0] = r.x0;
        window[1] = r.y0;
        window[2] = r.x1 - r.x0;
        window[3] = r.y1 - r.y0;
    }
    if (core) {
        core[0] = r.cx0;
        core[1] = r.cy0;
        core[2] = r.cx1 - r.cx0;
        core[3] = r.cy1 - r.cy0;
    }
    return TS_OK;
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
        int w = tile_wave(t->ti, t->tj);
        tile_rect r;
        if (t->ti < 0 || t->tj < 0 || t->ti >= j.nti || t->tj >= j.ntj)
            return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "tile (%d, %d) is off the %d x %d tiles",
                            t->ti, t->tj, j.nti, j.ntj);
        r = rect_of(width, height, tile, P, t->ti, t->tj);
        if (!t->window.data || t->window.width != r.x1 - r.x0 || t->window.height != r.y1 - r.y0)
            return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "tile (%d, %d): its window is %d x %d",
                            t->ti, t->tj, r.x1 - r.x0, r.y1 - r.y0);
        for (dj = -1; dj <= 1; dj++)
            for (di = -1; di <= 1; di++) {
                const ts_raster *nb = t->neighbours[(dj + 1) * 3 + di + 1];
                tile_rect o;
                if (!earlier(&j, t->ti, t->tj, di, dj))
                    continue;
                o = rect_of(width, height, tile, P, t->ti + di, t->tj + dj);
                if (!nb || !nb->data || nb->width != o.x1 - o.x0 || nb->height != o.y1 - o.y0)
                    return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                                    "tile (%d, %d) needs the %d x %d window of tile (%d, %d)",
                                    t->ti, t->tj, o.x1 - o.x0, o.y1 - o.y0, t->ti + di, t->tj + dj);
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

/* The debug maps of tiled runs: each tile's window maps, freed with the
 * windows. */
static void tiled_maps_free(tile_maps *tm, size_t n)
{
    size_t k;
    if (!tm)
        return;
    for (k = 0; k < n; k++) {
        free(tm[k].se);
        free(tm[k].sx);
        free(tm[k].sy);
        free(tm[k].order);
        free(tm[k].seams);
    }
    free(tm);
}

/* After a wave: each tile's own patches numbered after all earlier tiles'
 * (waves in order, tiles in row-major order within a wave), the indices
 * taken from earlier tiles decoded, the cores into the whole grid's maps. */
static void tiled_maps_finish(const tiled_job *j, const ts_synth_tile *tiles, size_t m,
                              ts_synth_maps *maps)
{
    size_t k, c;
    int y;
    for (k = 0; k < m; k++) {
        const ts_synth_tile *t = &tiles[k];
        tile_maps *tm = &j->tm[(size_t)t->tj * (size_t)j->nti + (size_t)t->ti];
        tile_rect r = rect_of(j->W, j->H, j->T, j->G, t->ti, t->tj);
        size_t rw = (size_t)(r.x1 - r.x0), n = rw * (size_t)(r.y1 - r.y0);
        int base = maps->n_patches;
        for (c = 0; c < n; c++)
            tm->order[c] = tm->order[c] >= 0   ? tm->order[c] + base
                           : tm->order[c] < -1 ? -2 - tm->order[c]
                                               : -1;
        maps->n_patches += tm->n_patches;
        maps->seconds_prepare += tm->sec[0];
        maps->seconds_match += tm->sec[1];
        maps->seconds_cut += tm->sec[2];
        maps->seconds_poisson += tm->sec[3];
        for (y = r.cy0; y < r.cy1; y++) {
            size_t g = (size_t)y * (size_t)j->W + (size_t)r.cx0;
            size_t o = (size_t)(y - r.y0) * rw + (size_t)(r.cx0 - r.x0);
            size_t w = (size_t)(r.cx1 - r.cx0);
            if (maps->source_exemplar)
                memcpy(maps->source_exemplar + g, tm->se + o, w * sizeof(int32_t));
            if (maps->source_x)
                memcpy(maps->source_x + g, tm->sx + o, w * sizeof(int32_t));
            if (maps->source_y)
                memcpy(maps->source_y + g, tm->sy + o, w * sizeof(int32_t));
            if (maps->order)
                memcpy(maps->order + g, tm->order + o, w * sizeof(int32_t));
            if (maps->seams)
                memcpy(maps->seams + g, tm->seams + o, w);
        }
    }
}

/* Set up tile (ti, tj) of j as t over windows (its window allocated, its
 * earlier neighbours' pointed to) and, with debug maps, its maps. */
static ts_status tile_setup(tiled_job *j, ts_ctx *ctx, int ti, int tj, ts_raster *windows,
                            ts_synth_tile *t)
{
    tile_rect r = rect_of(j->W, j->H, j->T, j->G, ti, tj);
    size_t at = (size_t)tj * (size_t)j->nti + (size_t)ti;
    int di, dj;
    memset(t, 0, sizeof *t);
    t->ti = ti;
    t->tj = tj;
    if (ts_raster_alloc(ctx, r.x1 - r.x0, r.y1 - r.y0, &windows[at]) != TS_OK)
        return ctx->status;
    if (j->tm) {
        size_t wn = (size_t)(r.x1 - r.x0) * (size_t)(r.y1 - r.y0);
        tile_maps *tm = &j->tm[at];
        tm->se = ts__malloc_array(wn, sizeof *tm->se);
        tm->sx = ts__malloc_array(wn, sizeof *tm->sx);
        tm->sy = ts__malloc_array(wn, sizeof *tm->sy);
        tm->order = ts__malloc_array(wn, sizeof *tm->order);
        tm->seams = ts__malloc_array(wn, 1);
        if (!tm->se || !tm->sx || !tm->sy || !tm->order || !tm->seams)
            return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory for the debug maps");
    }
    t->window = windows[at];
    for (dj = -1; dj <= 1; dj++)
        for (di = -1; di <= 1; di++)
            if (earlier(j, ti, tj, di, dj)) {
                const ts_raster *nb = &windows[at + (size_t)((ptrdiff_t)dj * j->nti + di)];
                if (!nb->data) /* a schedule that runs a tile before its neighbour */
                    return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE,
                                    "internal error: tile (%d, %d) before tile (%d, %d)", ti, tj,
                                    ti + di, tj + dj);
                t->neighbours[(dj + 1) * 3 + di + 1] = nb;
            }
    return TS_OK;
}

/* The cores of the m tiles made into the output. */
static void tiles_to_output(const tiled_job *j, const ts_synth_tile *tiles, size_t m,
                            ts_raster *out)
{
    size_t k;
    int y;
    for (k = 0; k < m; k++) {
        const ts_synth_tile *t = &tiles[k];
        tile_rect r = rect_of(j->W, j->H, j->T, j->G, t->ti, t->tj);
        for (y = r.cy0; y < r.cy1; y++)
            memcpy(&TS_PIX(out, r.cx0, y), &TS_PIX(&t->window, r.cx0 - r.x0, y - r.y0),
                   (size_t)(r.cx1 - r.cx0) * sizeof(float));
    }
}

/* A step of at least threads x max(1, 2048 / T) tiles: the wait for a
 * step's last tile is then a small share of the step (small tiles make many
 * short steps: 2048^2 in tiles of 128 on 2 threads ran x1.58 with a tile a
 * thread a step, x1.75 with this, x1.79 in waves). */
TS_API int ts_synth_tiled_band(int threads, int width, int tile)
{
    long half, want;
    if (tile < 1 || width < 1)
        return 1;
    half = ((long)width + tile - 1) / tile;
    half = (half + 1) / 2; /* the tiles of one wave in a row */
    want = (long)TS_MAX(1, threads) * TS_MAX(1, 2048 / tile);
    return (int)TS_MIN(1L << 20, TS_MAX(1, (want + half - 1) / half));
}

/* One step of the rows' schedule: the tiles of columns of parity `pass` in
 * rows r0, r0 + 2, ... < r1 (one wave: none needs another), side by side,
 * their cores into out. */
static ts_status rows_step(tiled_job *j, ts_ctx *ctx, ts_synth_tile *tiles, ts_raster *windows,
                           ts_raster *out, int r0, int r1, int pass, size_t *done)
{
    size_t m = 0, n = (size_t)j->nti * (size_t)j->ntj;
    int tj, ti;
    ts_status st;
    for (tj = r0; tj < r1 && tj < j->ntj; tj += 2)
        for (ti = pass; ti < j->nti; ti += 2) {
            if ((st = tile_setup(j, ctx, ti, tj, windows, &tiles[m])) != TS_OK)
                return st;
            m++;
        }
    if ((st = tiles_run(j, tiles, m)) != TS_OK)
        return st;
    tiles_to_output(j, tiles, m, out);
    *done += m;
    return ts__progress(ctx, (double)*done / (double)n, "synth tiles");
}

/* Without debug maps: the tiles in bands of rows, so that the windows alive
 * at once are a few rows' (as many as the threads need), not the grid's.  A
 * tile needs only its earlier-wave neighbours: an even row's wave-0 tiles
 * none, its wave-1 tiles the wave-0 tiles beside them; an odd row's tiles
 * the even rows above and below and, for wave 3, the wave-2 tiles beside
 * them.  So: even row 0; then bands of B odd rows k, k + 2, ... with the
 * even rows between and below them: the even rows' wave 0, their wave 1,
 * the odd rows' wave 2, their wave 3 (each step one wave of the band, its
 * tiles side by side); after a band every window but its last even row's is
 * needed by no later tile.  B gives a step a tile per thread at least, and
 * more for small tiles.  Every tile sees the same neighbours' windows as in wave order,
 * so the bytes are the same. */
static ts_status tiled_by_rows(tiled_job *j, ts_ctx *ctx, ts_synth_tile *tiles,
                               ts_raster *windows, ts_raster *out)
{
    int B = ts_synth_tiled_band(ts__thread_count(ctx, 64), j->W, j->T), k, tj, ti;
    size_t done = 0;
    ts_status st = TS_OK;
    if ((st = rows_step(j, ctx, tiles, windows, out, 0, 1, 0, &done)) != TS_OK ||
        (st = rows_step(j, ctx, tiles, windows, out, 0, 1, 1, &done)) != TS_OK)
        return st;
    for (k = 1; k < j->ntj; k += 2 * B) {
        int end = k + 2 * B; /* the band: rows k .. end - 1 */
        if ((st = rows_step(j, ctx, tiles, windows, out, k + 1, end, 0, &done)) != TS_OK ||
            (st = rows_step(j, ctx, tiles, windows, out, k + 1, end, 1, &done)) != TS_OK ||
            (st = rows_step(j, ctx, tiles, windows, out, k, end, 0, &done)) != TS_OK ||
            (st = rows_step(j, ctx, tiles, windows, out, k, end, 1, &done)) != TS_OK)
            return st;
        /* rows k - 1 .. end - 2 are needed by no later tile (row end - 1, even, by the
         * next band's first row) */
        for (tj = k - 1; tj < end - 1 && tj < j->ntj; tj++)
            for (ti = 0; ti < j->nti; ti++)
                ts_raster_free(&windows[(size_t)tj * (size_t)j->nti + (size_t)ti]);
    }
    return st;
}

ts_status ts__synth_tiled_maps(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                               const ts_synth_params *params,
                               const ts_synth_constraints *constraints, int tile, ts_raster *out,
                               ts_synth_maps *maps)
{
    tiled_job j;
    ts_synth_tile *tiles;
    ts_raster *windows; /* every tile's window, until no later tile needs it */
    int P, wave, ti, tj;
    size_t n, k;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, TILED_STAGE, "missing parameters or output");
    if (tiles_check(ctx, params, tile, out->width, out->height, &P) != TS_OK)
        return ctx->status;
    job_init(&j, ctx, exemplars, n_exemplars, params, tile, out->width, out->height, P);
    if (constraints &&
        (constraints->cell_flags || constraints->cell_exemplar || constraints->heights)) {
        j.cons = constraints;
        j.initial = out;
    }
    n = (size_t)j.nti * (size_t)j.ntj;
    tiles = ts__malloc_array(n, sizeof *tiles);
    windows = ts__calloc_array(n, sizeof *windows);
    if (maps)
        j.tm = ts__calloc_array(n, sizeof *j.tm);
    if (!tiles || !windows || (maps && !j.tm)) {
        free(tiles);
        free(windows);
        free(j.tm);
        return ts__fail(ctx, TS_ERR_NOMEM, TILED_STAGE, "out of memory");
    }
    if (!maps)
        st = tiled_by_rows(&j, ctx, tiles, windows, out);
    /* with debug maps: wave by wave (each tile's patches are numbered after
     * every tile of earlier waves, so a wave's maps are finished before the
     * next takes from them); every window is kept */
    for (wave = 0; maps && wave < 4 && st == TS_OK; wave++) {
        size_t m = 0;
        for (tj = 0; tj < j.ntj && st == TS_OK; tj++)
            for (ti = 0; ti < j.nti; ti++) {
                if (tile_wave(ti, tj) != wave)
                    continue;
                if ((st = tile_setup(&j, ctx, ti, tj, windows, &tiles[m])) != TS_OK)
                    break;
                m++;
            }
        if (st != TS_OK || (st = tiles_run(&j, tiles, m)) != TS_OK)
            break;
        tiles_to_output(&j, tiles, m, out);
        tiled_maps_finish(&j, tiles, m, maps);
        st = ts__progress(ctx, (wave + 1) / 4.0, "synth tiles");
    }
    for (k = 0; k < n; k++)
        ts_raster_free(&windows[k]);
    tiled_maps_free(j.tm, n);
    free(tiles);
    free(windows);
    return st;
}

TS_API ts_status ts_synth_tiled(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params,
                                const ts_synth_constraints *constraints, int tile, ts_raster *out)
{
    return ts__synth_tiled_maps(ctx, exemplars, n_exemplars, params, constraints, tile, out, NULL);
}
