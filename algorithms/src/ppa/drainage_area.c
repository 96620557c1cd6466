/*
 * drainage_area.c - the drainage area of every cell (in cells), for the
 * PPA's `min_drainage`: valley targets that drain fewer cells are hollows
 * above the channel heads, not valleys where the water runs.
 *
 * The flow, defined cell by cell so that any tiling gives it exactly:
 *   1. F, the filled height: the least, over the paths from the cell to the
 *      boundary (valid cells on the DEM's edge or beside nodata), of the
 *      highest cell on the path (depressions fill to their spill height;
 *      Barnes, Lehman and Mulla 2014).
 *   2. D, on flats of F: 0 on boundary cells and cells with a lower
 *      neighbour, else 1 + the least D of the neighbours of equal F (the
 *      steps to the flat's way out).
 *   3. A boundary cell drains off the DEM; any other cell to its neighbour
 *      of least (F, D), ties to the first in ppa_dir order: (F, D) falls
 *      along every path, so the flow is a forest.
 *   4. The area of a cell: itself and every cell draining through it.
 * In tiles (bounded memory, tiles in parallel), after Barnes (2016, 2017):
 *   A. each tile flooded from its own perimeter and boundary cells, which
 *      label the cells they reach; the least spill height between two
 *      labels is an edge, and the tile keeps the minimum spanning forest of
 *      its labels; with the edges between perimeter cells of neighbouring
 *      tiles, one minimax search from the boundary gives F on every
 *      perimeter cell (F of a cell inside is then the flood of its tile
 *      from its perimeter at those heights);
 *   B. D on each tile from its own ways out and its neighbours' perimeter
 *      D, in rounds until no perimeter D falls (flats across tiles);
 *   C. each tile's flow and areas; where the flow leaves a tile: its area
 *      so far, where it enters, and for each perimeter cell the cell its
 *      flow leaves the tile by; summed over the tiles' exits in flow order;
 *   D. each tile's areas with what flows in from its neighbours.
 * Two ways through B-D.  Kept (in memory, `keep`): F, D and the flow of
 * every cell are held (9 bytes a cell), so no tile is routed: F is the
 * greater of the tile's own flood and its label's perimeter F, D is found
 * breadth-first on the flats and relaxed across tiles, the flow, exits and
 * areas follow in a topological order.  Routed (bounded memory, for
 * ppa_tiled.c): each round routes its tiles by one flood keyed (F, D) and
 * keeps their exits; a tile is routed again only when a neighbour's D that
 * its routing could read has changed; D routes each tile once more.
 * One tile is steps 1-4 at once, by one routing.  tests/c/ppa/test_ppa.c compares the areas
 * with the definition computed naively (F by relaxation, the flow cell by
 * cell) on several tilings.
 * Here the driver: the tiles, the phases in order and the rounds of B;
 * one tile's flood, routing and areas are drainage_tile.c's, the tiles'
 * perimeters and the phases run on the tiles drainage_perimeters.c's.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "ppa_internal.h"

ts_status ppa_drainage(ts_ctx *ctx, int W, int H, int tile, int keep, ts_window_read_fn read,
                       void *user, ppa_area_fn emit, void *emit_user)
{
    ppa_dr_job j;
    size_t t, i;
    ts_status st = TS_OK;
    int round;
    memset(&j, 0, sizeof j);
    atomic_init(&j.failed, 0);
    atomic_init(&j.next, 0);
    j.ctx = ctx;
    j.W = W;
    j.H = H;
    j.T = TS_MAX(2, TS_MIN(tile, TS_MAX(W, H)));
    if ((size_t)(j.T + 2) * (size_t)(j.T + 2) >= UINT32_MAX)
        return ts__fail(ctx, TS_ERR_SIZE, "ppa drainage", "tiles of %d cells are too large", tile);
    j.ntx = (W + j.T - 1) / j.T;
    j.nty = (H + j.T - 1) / j.T;
    j.ntiles = (size_t)j.ntx * (size_t)j.nty;
    j.read = read;
    j.user = user;
    j.emit = emit;
    j.emit_user = emit_user;
    pthread_mutex_init(&j.lock, NULL);
    j.pbase = ts__malloc_array(j.ntiles + 1, sizeof *j.pbase);
    j.hbase = ts__malloc_array(j.ntiles + 1, sizeof *j.hbase);
    j.due = ts__malloc_array(j.ntiles, 1);
    if (!j.pbase || !j.due || !j.hbase) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
        goto out;
    }
    j.hbase[0] = 0;
    for (t = 0; t < j.ntiles; t++) {
        int x0, y0, w, h;
        ppa_dr_tile_rect(&j, t, &x0, &y0, &w, &h);
        j.pbase[t] = j.np;
        j.np += ppa_dr_perim_count(w, h);
        j.hbase[t + 1] = j.hbase[t] + ppa_dr_halo_count(w, h);
    }
    j.pbase[j.ntiles] = j.np;
    j.hsens = ts__malloc_array(j.hbase[j.ntiles], 1);
    j.ph = ts__malloc_array(j.np, sizeof *j.ph);
    j.pbnd = ts__calloc_array(j.np, 1);
    j.G = ts__malloc_array(j.np, sizeof *j.G);
    j.D = ts__malloc_array(j.np, sizeof *j.D);
    j.Dnew = ts__malloc_array(j.np, sizeof *j.Dnew);
    j.target = ts__malloc_array(j.np, sizeof *j.target);
    j.link = ts__malloc_array(j.np, sizeof *j.link);
    j.A = ts__calloc_array(j.np, sizeof *j.A);
    j.in = ts__calloc_array(j.np, sizeof *j.in);
    if (keep && j.ntiles > 1) {
        j.Fc = ts__malloc_array((size_t)W * (size_t)H, sizeof *j.Fc);
        j.Dc = ts__malloc_array((size_t)W * (size_t)H, sizeof *j.Dc);
        j.dirs = ts__malloc_array((size_t)W * (size_t)H, 1);
    }
    if (!j.ph || !j.pbnd || !j.G || !j.D || !j.Dnew || !j.target || !j.link || !j.A || !j.in ||
        !j.hsens || (keep && j.ntiles > 1 && (!j.Fc || !j.Dc || !j.dirs))) {
        st =
            ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory for %zu tile borders", j.np);
        goto out;
    }
    for (i = 0; i < j.np; i++) {
        j.D[i] = j.Dnew[i] = PPA_DR_DINF;
        j.target[i] = j.link[i] = PPA_DR_NONE;
    }
    memset(j.due, 1, j.ntiles);
    if (j.ntiles > 1) {
        /* A: F on the tiles' perimeters */
        if ((st = ppa_dr_run_phase(&j, PPA_PH_LABELS)) != TS_OK)
            goto out;
        if (ppa_dr_solve_perimeter_f(&j) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
            goto out;
        }
        if ((st = ts__progress(ctx, 0.3, "drainage: spill heights")) != TS_OK)
            goto out;
        /* B: D across tiles, in rounds until it holds still, and C: each
         * routing's exits (the last routing of every tile reads the final D) */
        for (round = 0;; round++) {
            int any = 0;
            if ((st = ppa_dr_run_phase(&j, !j.Fc        ? PPA_PH_ROUTE
                                           : round == 0 ? PPA_PH_FLATS
                                                        : PPA_PH_RELAX)) != TS_OK)
                goto out;
            /* again: the tiles beside a perimeter cell whose D changed (Dnew
             * takes the old D for the test; D falls, round by round, to the
             * flow's D) */
            {
                uint32_t *old = j.D;
                j.D = j.Dnew;
                j.Dnew = old;
            }
            for (t = 0; t < j.ntiles; t++)
                any |= j.due[t] = (unsigned char)(j.Fc ? ppa_dr_flat_pairs(&j, t)
                                                       : ppa_dr_halo_changed(&j, t, j.Dnew));
            /* a round after the first that lowered no D: the next would be the same */
            if (round > 0 && memcmp(j.Dnew, j.D, j.np * sizeof *j.D) == 0)
                any = 0;
            memcpy(j.Dnew, j.D, j.np * sizeof *j.D);
            if (!any)
                break;
        }
        memset(j.due, 1, j.ntiles);
        if ((st = ts__progress(ctx, 0.6, "drainage: flats")) != TS_OK)
            goto out;
        /* C: the tiles' exits (kept: from F and D now), summed in flow order */
        if (j.Fc && (st = ppa_dr_run_phase(&j, PPA_PH_FLOW)) != TS_OK)
            goto out;
        if (ppa_dr_solve_inflow(&j) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "ppa drainage", "out of memory");
            goto out;
        }
    }
    /* D: the areas */
    st = ppa_dr_run_phase(&j, PPA_PH_AREAS);
    if (st == TS_OK)
        st = ts__progress(ctx, 1.0, "drainage");
out:
    pthread_mutex_destroy(&j.lock);
    free(j.pbase);
    free(j.due);
    free(j.ph);
    free(j.pbnd);
    free(j.G);
    free(j.D);
    free(j.Dnew);
    free(j.edges);
    free(j.target);
    free(j.link);
    free(j.A);
    free(j.in);
    free(j.Fc);
    free(j.Dc);
    free(j.dirs);
    free(j.hbase);
    free(j.hsens);
    return st;
}

/* ---- the drainage test: a bit a cell ---- */

typedef struct channel_io {
    uint64_t *bits;
    int width;
    double min_drainage;
} channel_io;

static void channel_emit(void *user, int x0, int y0, int w, int h, const float *area,
                         const unsigned char *dir)
{
    channel_io *io = user;
    int x, y;
    (void)dir;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (area[(size_t)y * (size_t)w + (size_t)x] >= io->min_drainage) {
                uint64_t g = (uint64_t)(y0 + y) * (uint64_t)io->width + (uint64_t)(x0 + x);
                io->bits[g >> 6] |= (uint64_t)1 << (g & 63);
            }
}

ts_status ppa_channels(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, double min_drainage, uint64_t **bits)
{
    size_t n = (size_t)width * (size_t)height;
    channel_io io;
    ts_status st;
    *bits = ts__calloc_array((n + 63) / 64, sizeof **bits);
    if (!*bits)
        return ts__fail(ctx, TS_ERR_NOMEM, "ppa",
                        "cannot allocate the drainage bits of %d x %d cells", width, height);
    io.bits = *bits;
    io.width = width;
    io.min_drainage = min_drainage;
    st = ppa_drainage(ctx, width, height, tile, keep, read, user, channel_emit, &io);
    if (st != TS_OK) {
        free(*bits);
        *bits = NULL;
    }
    return st;
}

/* ---- in memory ---- */

typedef struct mem_io {
    const ts_raster *dem;
    float *area;
} mem_io;

ts_status ppa_raster_window(void *dem, int x0, int y0, int w, int h, float *buf)
{
    const ts_raster *r = dem;
    int y;
    for (y = 0; y < h; y++)
        memcpy(buf + (size_t)y * (size_t)w, &TS_PIX(r, x0, y0 + y), (size_t)w * sizeof *buf);
    return TS_OK;
}

static void mem_emit(void *user, int x0, int y0, int w, int h, const float *area,
                     const unsigned char *dir)
{
    mem_io *m = user;
    int y;
    (void)dir;
    for (y = 0; y < h; y++)
        memcpy(m->area + (size_t)(y0 + y) * (size_t)m->dem->width + (size_t)x0,
               area + (size_t)y * (size_t)w, (size_t)w * sizeof *area);
}

ts_status ppa_drainage_area(ts_ctx *ctx, const ts_raster *dem, float *area, int tile, int keep)
{
    mem_io m;
    m.dem = dem;
    m.area = area;
    return ppa_drainage(ctx, dem->width, dem->height, tile, keep, ppa_raster_window, (void *)dem,
                        mem_emit, &m);
}
