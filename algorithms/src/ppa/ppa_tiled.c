/*
 * ppa_tiled.c - the PPA of a DEM too large for memory, read window by
 * window, with the very output of the whole-raster run (ppa.c).
 *
 * Every step is either local or made exact across tiles:
 *   1. profile recognition is local: a tile's targets are computed on a
 *      window with a margin of half a profile and two cells;
 *   2-3. the maximum spanning forest (polygon breaking) of the whole is the
 *      forest of the union of the tiles' own forests and the segments that
 *      cross tile borders.  Each tile's forest is shrunk to what matters
 *      outside it: twigs that reach no border segment are final; the rest
 *      is contracted to the junctions and border cells, each contracted
 *      path weighted by its least important segment (any cycle through the
 *      path contains all of it, so that segment alone can be the one a
 *      cycle loses).  One Kruskal over the contracted paths and the border
 *      segments, in the same total order (weight, then the global index of
 *      the segment) as the whole-raster run, says which segments go;
 *   4. branch reduction runs on the forest's chain graph (vertices: cells
 *      of degree other than 2 and cells with a border segment; edges: the
 *      chains between them, with their lengths in fixed point), pass by
 *      pass exactly as ppa_branch.c walks cells.
 * Tiles are read three times (forest, chains, output); what is held for
 * the whole raster is the contracted forests (O(border cells)) and the
 * chain graph (O(chains): about 0.27 per cell per kind before branch
 * reduction, so still O(cells); running the first reduction pass inside
 * the tiles is the next step).
 * Here the pipeline and the sweeps over the tiles; ppa_tiled_polygon.c
 * holds steps 2-3, ppa_tiled_branch.c step 4.
 * tests/c/ppa/test_ppa.c compares the output with ts_ppa_extract.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

/* Passes of branch reduction run inside the tiles (each on the tile with a
 * halo), when every tile's are certain; fewer otherwise. */
#ifndef PPA_TILE_PASSES
#define PPA_TILE_PASSES 3
#endif

/* Read tile ti with its margin; targets of every kind on the window. */
static ts_status tile_load(ppa_tiled *t, int ti)
{
    int tx = ti % t->ntx, ty = ti / t->ntx, y;
    ts_raster wr;
    ts_status st;
    ts_progress_saved sv;
    t->x0 = tx * t->T;
    t->y0 = ty * t->T;
    t->w = TS_MIN(t->T, t->W - t->x0);
    t->h = TS_MIN(t->T, t->H - t->y0);
    t->wx0 = TS_MAX(0, t->x0 - t->margin);
    t->wy0 = TS_MAX(0, t->y0 - t->margin);
    t->ww = TS_MIN(t->W, t->x0 + t->w + t->margin) - t->wx0;
    t->wh = TS_MIN(t->H, t->y0 + t->h + t->margin) - t->wy0;
    if ((st = t->read(t->user, t->wx0, t->wy0, t->ww, t->wh, t->win)) != TS_OK)
        return t->ctx->status != TS_OK ? t->ctx->status
                                       : ts__fail(t->ctx, st, "ppa", "cannot read the DEM");
    wr.width = t->ww;
    wr.height = t->wh;
    wr.stride = t->ww;
    wr.data = t->win;
    /* the stages' own progress holds still at the tiles' */
    sv = ts__progress_push(t->ctx, t->frac, t->frac);
    st = ppa_profile_targets(t->ctx, &wr, 2 * t->half + 1, t->threshold[0], t->threshold[1],
                             t->kinds, t->wt);
    ts__progress_pop(t->ctx, sv);
    if (st != TS_OK)
        return st;
    if (t->channel) /* valleys where the water runs (as ts_ppa_extract) */
        for (y = 0; y < t->wh; y++) {
            int x;
            unsigned char *row = t->wt + (size_t)y * (size_t)t->ww;
            for (x = 0; x < t->ww; x++) {
                uint64_t g = ppa_gcell(t, t->wx0 + x, t->wy0 + y);
                if ((row[x] & TS_VALLEY) && !ppa_channel(t->channel, g))
                    row[x] &= (unsigned char)~TS_VALLEY;
            }
        }
    for (y = 0; y < t->h; y++) {
        size_t o = (size_t)(t->y0 - t->wy0 + y) * (size_t)t->ww + (size_t)(t->x0 - t->wx0);
        memcpy(t->core + (size_t)y * (size_t)t->w, t->win + o, (size_t)t->w * sizeof(float));
        memcpy(t->ct + (size_t)y * (size_t)t->w, t->wt + o, (size_t)t->w);
    }
    return TS_OK;
}

static void tile_rect(ppa_tiled *t, int ti)
{
    t->x0 = (ti % t->ntx) * t->T;
    t->y0 = (ti / t->ntx) * t->T;
    t->w = TS_MIN(t->T, t->W - t->x0);
    t->h = TS_MIN(t->T, t->H - t->y0);
}

/* Row y of the raster in a cache of three tile rows. */
static unsigned char *strip_row(const ppa_tiled *t, unsigned char *const *strips, int y)
{
    int r = y / t->T;
    return strips[r % 3] + (size_t)(y - r * t->T) * (size_t)t->W;
}

/* The whole's forest (and nodata) of tile row r into the cache. */
static ts_status strip_fill(ppa_tiled *t, int nk, int r)
{
    int tx, k, x, y;
    ts_status st;
    for (tx = 0; tx < t->ntx; tx++) {
        if ((st = tile_load(t, r * t->ntx + tx)) != TS_OK)
            return st;
        for (y = 0; y < t->h; y++) {
            unsigned char *nd = strip_row(t, t->strip_nd, t->y0 + y) + t->x0;
            for (x = 0; x < t->w; x++)
                nd[x] = isnan(t->core[(size_t)y * (size_t)t->w + (size_t)x]) ? 1 : 0;
        }
        for (k = 0; k < nk; k++) {
            if ((st = ppa_tile_whole_forest(t, &t->ks[k])) != TS_OK)
                return st;
            for (y = 0; y < t->h; y++)
                memcpy(strip_row(t, t->strip[k], t->y0 + y) + t->x0,
                       t->adj + (size_t)y * (size_t)t->w, (size_t)t->w);
        }
    }
    return TS_OK;
}

/* The tile's forest of kind k after t->passes passes of branch reduction
 * (on a window with a halo) into t->adj; *exact = 0 when a core cell of it
 * is uncertain. */
static ts_status tile_after_passes(ppa_tiled *t, int k, int *exact)
{
    ppa_window *wn = &t->wn;
    int y, x;
    if (t->passes == 0) {
        for (y = 0; y < t->h; y++)
            memcpy(t->adj + (size_t)y * (size_t)t->w, strip_row(t, t->strip[k], t->y0 + y) + t->x0,
                   (size_t)t->w);
        return TS_OK;
    }
    wn->x0 = TS_MAX(0, t->x0 - t->halo);
    wn->y0 = TS_MAX(0, t->y0 - t->halo);
    wn->w = TS_MIN(t->W, t->x0 + t->w + t->halo) - wn->x0;
    wn->h = TS_MIN(t->H, t->y0 + t->h + t->halo) - wn->y0;
    wn->m = t->ks[k].m;
    for (y = 0; y < wn->h; y++)
        memcpy(wn->adj + (size_t)y * (size_t)wn->w, strip_row(t, t->strip[k], wn->y0 + y) + wn->x0,
               (size_t)wn->w);
    if (ppa_win_passes(wn, t->passes, t->ks[k].min_q) != 0)
        return ts__fail(t->ctx, TS_ERR_NOMEM, "ppa", "out of memory for the branch reduction");
    for (y = 0; y < t->h; y++) {
        size_t o = (size_t)(t->y0 - wn->y0 + y) * (size_t)wn->w + (size_t)(t->x0 - wn->x0);
        for (x = 0; x < t->w; x++)
            if (wn->unc[o + (size_t)x])
                *exact = 0;
        memcpy(t->adj + (size_t)y * (size_t)t->w, wn->adj + o, (size_t)t->w);
    }
    return TS_OK;
}

/* Phases 2 (remove 0: the chains of the forest after the first passes,
 * for the whole's branch reduction) and 3 (remove 1: the dead chains
 * cleared, the codes written), tile row by tile row with the whole's forest
 * of three tile rows at hand.  *exact = 0: a tile's passes were uncertain
 * (phase 2 stops: the caller tries fewer passes). */
static ts_status sweep(ppa_tiled *t, int nk, int remove, int *exact, ts_window_write_fn write,
                       void *user)
{
    int r, tx, k, n_tiles = t->ntx * t->nty;
    size_t i;
    ts_status st = TS_OK;
    for (r = 0; r < t->nty && st == TS_OK; r++) {
        t->frac = (double)(r * t->ntx) / n_tiles;
        if (r == 0 && (st = strip_fill(t, nk, 0)) != TS_OK)
            break;
        if (r + 1 < t->nty && (st = strip_fill(t, nk, r + 1)) != TS_OK)
            break;
        for (tx = 0; tx < t->ntx && st == TS_OK; tx++) {
            int ti = r * t->ntx + tx, y;
            unsigned char *codes = t->work;
            t->frac = (double)ti / n_tiles;
            tile_rect(t, ti);
            if (remove)
                memset(codes, 0, (size_t)t->w * (size_t)t->h);
            for (k = 0; k < nk && st == TS_OK; k++) {
                if (!remove)
                    t->ks[k].chain_base[ti] = t->ks[k].n_chains;
                if ((st = tile_after_passes(t, k, exact)) != TS_OK || !*exact)
                    return st;
                if ((st = ppa_tile_chains(t, &t->ks[k], ti, remove)) != TS_OK)
                    return st;
                if (remove)
                    for (i = 0; i < (size_t)t->w * (size_t)t->h; i++)
                        if (t->adj[i])
                            codes[i] |= (unsigned char)t->ks[k].kind;
            }
            if (remove) {
                for (y = 0; y < t->h; y++) {
                    const unsigned char *nd = strip_row(t, t->strip_nd, t->y0 + y) + t->x0;
                    for (i = 0; i < (size_t)t->w; i++)
                        if (nd[i])
                            codes[(size_t)y * (size_t)t->w + i] = 255;
                }
                if ((st = write(user, t->x0, t->y0, t->w, t->h, codes)) != TS_OK) {
                    if (t->ctx->status == TS_OK)
                        ts__fail(t->ctx, st, "ppa", "cannot write the axes");
                    return t->ctx->status;
                }
            }
            st = ts__progress(t->ctx, (double)(ti + 1) / n_tiles,
                              remove ? "axes" : "branch reduction in tiles");
        }
    }
    return st;
}

/* ------------------------------------------------------------------ */
/* The pipeline                                                        */
/* ------------------------------------------------------------------ */

static void tiled_free(ppa_tiled *t)
{
    int k;
    free(t->win);
    free(t->wt);
    free(t->core);
    free(t->ct);
    free(t->adj);
    free(t->work);
    free(t->term);
    free(t->queue);
    free(t->channel);
    free(t->clears);
    free(t->wn.adj);
    free(t->wn.unc);
    free(t->wn.visit);
    for (k = 0; k < 3; k++) {
        free(t->strip[0][k]);
        free(t->strip[1][k]);
        free(t->strip_nd[k]);
    }
    for (k = 0; k < 2; k++) {
        free(t->ks[k].edges);
        free(t->ks[k].dropped);
        free(t->ks[k].border_chain);
        free(t->ks[k].chains);
        free(t->ks[k].chain_base);
        free(t->ks[k].dead);
    }
}

/* The arguments of ts_ppa_extract_tiled: TS_OK, or the failure. */
static ts_status tiled_check(ts_ctx *ctx, int width, int height, const ts_grid_metrics *metrics,
                             const ts_ppa_params *params, int tile_size, ts_window_read_fn read,
                             ts_window_write_fn write)
{
    if (!params || !read || !write)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "missing parameters or window callbacks");
    if (ts_params_validate(ctx, "ppa", params) != TS_OK)
        return ctx->status;
    if (width < 2 || height < 2)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa", "the DEM is %d x %d cells; at least 2 x 2 needed",
                        width, height);
    if (tile_size < TS_PPA_TILE_MIN || tile_size > TS_PPA_TILE_MAX)
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "tile size %d: %d..%d cells", tile_size,
                        TS_PPA_TILE_MIN, TS_PPA_TILE_MAX);
    if (metrics && (!metrics->dx || !metrics->dy))
        return ts__fail(ctx, TS_ERR_ARG, "ppa", "ground metrics without cell sizes");
    if (params->min_branch_length.unit == TS_UNIT_METRES && params->min_branch_length.value >= 0 &&
        !metrics)
        return ts__fail(ctx, TS_ERR_ARG, "ppa",
                        "min_branch_length is in metres but the DEM has no ground metrics "
                        "(no CRS): give it in cells");
    return TS_OK;
}

/* The run's state, the buffers of a tile and its window, and the kinds
 * asked for (*nk of them); on a failure everything is freed. */
static ts_status tiled_init(ppa_tiled *t, ts_ctx *ctx, int width, int height,
                            const ts_ppa_params *params, int tile_size, ts_window_read_fn read,
                            void *user, int *nk)
{
    int k, n_tiles;
    size_t wcap, tcap;
    memset(t, 0, sizeof *t);
    t->ctx = ctx;
    t->W = width;
    t->H = height;
    t->T = tile_size;
    t->ntx = (width + tile_size - 1) / tile_size;
    t->nty = (height + tile_size - 1) / tile_size;
    t->half = params->profile_length / 2;
    t->margin = t->half + 2;
    t->read = read;
    t->user = user;
    n_tiles = t->ntx * t->nty;
    wcap = (size_t)TS_MIN(width, tile_size + 2 * t->margin) *
           (size_t)TS_MIN(height, tile_size + 2 * t->margin);
    tcap = (size_t)tile_size * (size_t)tile_size;
    t->win = ts__malloc_array(wcap, sizeof *t->win);
    t->wt = ts__malloc_array(wcap, 1);
    t->core = ts__malloc_array(tcap, sizeof *t->core);
    t->ct = ts__malloc_array(tcap, 1);
    t->adj = ts__malloc_array(tcap, 1);
    t->work = ts__malloc_array(tcap, 1);
    t->term = ts__malloc_array(tcap, 1);
    t->queue = ts__malloc_array(tcap, sizeof *t->queue);
    if (!t->win || !t->wt || !t->core || !t->ct || !t->adj || !t->work || !t->term || !t->queue) {
        tiled_free(t);
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate for tiles of %d cells",
                        tile_size);
    }
    if (params->features != TS_PPA_VALLEYS)
        t->ks[(*nk)++].kind = TS_RIDGE;
    if (params->features != TS_PPA_RIDGES)
        t->ks[(*nk)++].kind = TS_VALLEY;
    for (k = 0; k < *nk; k++) {
        t->ks[k].sign = t->ks[k].kind == TS_VALLEY ? -1.0f : 1.0f;
        t->ks[k].chain_base = ts__calloc_array((size_t)n_tiles, sizeof *t->ks[k].chain_base);
        if (!t->ks[k].chain_base) {
            tiled_free(t);
            return ts__fail(ctx, TS_ERR_NOMEM, "ppa", "out of memory");
        }
        t->kinds |= t->ks[k].kind;
    }
    return TS_OK;
}

/* The elevation range, for the thresholds (a first read of every tile),
 * the kinds' minimum branch lengths, and the drainage test's channels. */
static ts_status tiled_thresholds(ppa_tiled *t, const ts_grid_metrics *metrics,
                                  const ts_ppa_params *params, int nk)
{
    ts_ctx *ctx = t->ctx;
    int ti, k, n_tiles = t->ntx * t->nty;
    double lo = INFINITY, hi = -INFINITY;
    ts_status st = TS_OK;
    ts_progress_saved sv;
    sv = ts__progress_push(ctx, 0.0, 0.1);
    for (ti = 0; ti < n_tiles && st == TS_OK; ti++) {
        int x0 = (ti % t->ntx) * t->T, y0 = (ti / t->ntx) * t->T;
        int w = TS_MIN(t->T, t->W - x0), h = TS_MIN(t->T, t->H - y0);
        size_t i;
        if ((st = t->read(t->user, x0, y0, w, h, t->win)) != TS_OK) {
            if (ctx->status == TS_OK)
                ts__fail(ctx, st, "ppa", "cannot read the DEM");
            st = ctx->status;
            break;
        }
        for (i = 0; i < (size_t)w * (size_t)h; i++)
            if (!isnan(t->win[i])) {
                lo = TS_MIN(lo, (double)t->win[i]);
                hi = TS_MAX(hi, (double)t->win[i]);
            }
        st = ts__progress(ctx, (double)(ti + 1) / n_tiles, "elevation range");
    }
    ts__progress_pop(ctx, sv);
    if (st == TS_OK && !(lo <= hi))
        st = ts__fail(ctx, TS_ERR_NUMERIC, "ppa", "every cell of the DEM is nodata");
    for (k = 0; k < 2; k++)
        t->threshold[k] =
            (float)TS_MAX(params->threshold, ppa_kind_fraction(params, k + 1) * (hi - lo));
    for (k = 0; k < nk; k++) {
        int in_metres;
        t->ks[k].min_q = ppa_length_q(ppa_kind_branch(params, t->ks[k].kind, &in_metres));
        t->ks[k].m = in_metres ? metrics : NULL;
    }
    /* valleys where the water runs: the drainage needs the whole DEM */
    if (st == TS_OK && (t->kinds & TS_VALLEY) && params->min_drainage > 0) {
        sv = ts__progress_push(ctx, 0.1, 0.1);
        st = ppa_channels(ctx, t->W, t->H, TS_MIN(t->T, PPA_DRAINAGE_TILE), 0, t->read, t->user,
                          params->min_drainage, &t->channel);
        ts__progress_pop(ctx, sv);
    }
    return st;
}

/* 1: tile forests contracted to their borders, one Kruskal for the whole
 * (from status st: nothing past a failure). */
static ts_status tiled_polygon_breaking(ppa_tiled *t, int nk, ts_status st)
{
    int ti, k, n_tiles = t->ntx * t->nty;
    ts_progress_saved sv = ts__progress_push(t->ctx, 0.1, 0.4);
    for (ti = 0; ti < n_tiles && st == TS_OK; ti++) {
        t->frac = (double)ti / n_tiles;
        if ((st = tile_load(t, ti)) != TS_OK)
            break;
        for (k = 0; k < nk && st == TS_OK; k++)
            st = ppa_tile_contract(t, &t->ks[k]);
        if (st == TS_OK)
            st = ts__progress(t->ctx, (double)(ti + 1) / n_tiles, "polygon breaking in tiles");
    }
    ts__progress_pop(t->ctx, sv);
    for (k = 0; k < nk && st == TS_OK; k++)
        st = ppa_global_forest(t, &t->ks[k]);
    return st;
}

/* 2: the forest after the first passes of branch reduction (exact in
 * every tile, else fewer passes) and its chain graph (from status st:
 * past a failure nothing but t->passes, which the stats report). */
static ts_status tiled_first_passes(ppa_tiled *t, int nk, ts_status st)
{
    ts_ctx *ctx = t->ctx;
    int k;
    ts_progress_saved sv;
    if (st == TS_OK) {
        size_t scap = (size_t)TS_MIN(t->T, t->H) * (size_t)t->W, wcap2;
        /* 256 cells kept the three passes certain on every tile of the mosaics measured
         * (128 too; 64 did not); fewer passes otherwise, never a wrong cell */
        t->halo = TS_MIN(t->T, TS_MAX(256, t->T / 8));
        wcap2 = (size_t)TS_MIN(t->W, t->T + 2 * t->halo) * (size_t)TS_MIN(t->H, t->T + 2 * t->halo);
        for (k = 0; k < 3 && st == TS_OK; k++) {
            t->strip_nd[k] = ts__malloc_array(scap, 1);
            t->strip[0][k] = ts__malloc_array(scap, 1);
            t->strip[1][k] = nk > 1 ? ts__malloc_array(scap, 1) : NULL;
            if (!t->strip_nd[k] || !t->strip[0][k] || (nk > 1 && !t->strip[1][k]))
                st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate three rows of tiles");
        }
        t->wn.adj = ts__malloc_array(wcap2, 1);
        t->wn.unc = ts__malloc_array(wcap2, 1);
        if (st == TS_OK && (!t->wn.adj || !t->wn.unc))
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa", "cannot allocate for a tile with its halo");
    }
    {
        /* a try with fewer passes goes on from where the last one stopped:
         * progress never goes back */
        double from = 0.4;
        for (t->passes = PPA_TILE_PASSES; st == TS_OK; t->passes--) {
            int exact = 1;
            for (k = 0; k < nk; k++)
                t->ks[k].n_chains = 0;
            t->frac = 0;
            sv = ts__progress_push(ctx, from, 0.7);
            st = sweep(t, nk, 0, &exact, NULL, NULL);
            ts__progress_pop(ctx, sv);
            if (st != TS_OK || exact)
                break;
            from += (0.7 - from) * t->frac;
        }
    }
    return st;
}

TS_API ts_status ts_ppa_extract_tiled(ts_ctx *ctx, int width, int height,
                                      const ts_grid_metrics *metrics, const ts_ppa_params *params,
                                      int tile_size, ts_window_read_fn read,
                                      ts_window_write_fn write, void *user,
                                      ts_ppa_tiled_stats *stats)
{
    ppa_tiled t;
    int k, nk = 0;
    ts_status st;
    ts_progress_saved sv;

    ts__clear(ctx);
    if ((st = tiled_check(ctx, width, height, metrics, params, tile_size, read, write)) != TS_OK)
        return st;
    if ((st = tiled_init(&t, ctx, width, height, params, tile_size, read, user, &nk)) != TS_OK)
        return st;
    st = tiled_thresholds(&t, metrics, params, nk);
    st = tiled_polygon_breaking(&t, nk, st);
    /* 2: the forest after the first passes in the tiles, its chain graph, the
     * rest of the reduction on it */
    st = tiled_first_passes(&t, nk, st);
    if (stats) {
        stats->passes_in_tiles = t.passes;
        stats->chains_held = t.ks[0].n_chains + t.ks[1].n_chains;
    }
    for (k = 0; k < nk && st == TS_OK; k++) {
        if (t.ks[k].n_chains >= UINT32_MAX)
            st = ts__fail(ctx, TS_ERR_SIZE, "ppa", "too many feature chains");
        else
            st = ppa_global_branches(&t, &t.ks[k]);
        free(t.ks[k].chains); /* phase 3 needs only which chains died */
        t.ks[k].chains = NULL;
    }
    /* 3: every tile's axes, written */
    sv = ts__progress_push(ctx, 0.7, 1.0);
    if (st == TS_OK) {
        int exact = 1;
        st = sweep(&t, nk, 1, &exact, write, user);
        if (st == TS_OK && !exact)
            st = ts__fail(ctx, TS_ERR_INTERNAL, "ppa", "tiles: the passes changed between sweeps");
    }
    ts__progress_pop(ctx, sv);
    tiled_free(&t);
    return st;
}
