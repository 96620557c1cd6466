/*
 * tsjob.c - the jobs behind every front end (see tsjob.h).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "tsjob.h"

/* ------------------------------------------------------------------ */
/* ppa                                                                 */
/* ------------------------------------------------------------------ */

/* The first warning of a job: cells of a float's extreme value read as nodata. */
static void job_warn_sentinels(tsio_err *warning, const char *path, const tsio_raster *r)
{
    if (r->n_sentinels && !warning->msg[0])
        tsio_errf(warning, path,
                  "%zu cells of +-3.4e38 (a float's extreme value, not declared nodata) taken "
                  "as nodata",
                  r->n_sentinels);
}

/* Memory a job takes, estimated before the work (bytes; measured peaks of
 * the CLI with a margin: bench/README.md).  Libraries and buffers: */
#define JOB_MEM_BASE ((uint64_t)96 << 20)
#define JOB_MEM_PPA_CELL 24       /* per input cell: the DEM, profiles, masks, codes */
#define JOB_MEM_PPA_TILE_CELL 48  /* per cell of a tile with its margin (tiled ppa) */
#define JOB_MEM_PPA_STRIP 9  /* per cell of three tile rows: both forests, nodata (tiled ppa) */
#define JOB_MEM_PPA_CHAINS 1 /* per DEM cell: the chains held (76 k at 4096^2: far less) */
#define JOB_MEM_PPA_DRAINAGE 24 /* per cell of a drainage tile (each thread has one): heights
                                   and F, D, flow, order, areas (drainage_area.c) */
#define JOB_MEM_PPA_DRAINAGE_BORDER 64 /* per cell of the tiles' borders: heights, F, D, exits */
#define JOB_MEM_SYNTH_CELL 16     /* per output cell: terrain, flags, fill state */
#define JOB_MEM_MAPS_CELL 20      /* per output cell with the synthesis maps */
#define JOB_MEM_SKETCH_CELL 128   /* per output cell with a sketch: PPA, features, guides, the
                                     slope style's Poisson system (~110 B/cell at its peak) */
#define JOB_MEM_EX_SOURCE_CELL 12 /* per exemplar cell as read */
#define JOB_MEM_EX_CELL 24        /* per exemplar cell at the target resolution: pyramid, FFT */
#define JOB_MEM_TILE_CELL 8       /* per cell of a tile being made: its window, flags, copy */
#define JOB_MEM_TILED_CELL 16     /* per output cell in tiles with debug maps: every tile's
                                     window (at most 4 x its core: tiles of 2 patches) */

int tsjob_ppa_check_memory(const tsio_georef *in, const char *path, tsio_err *err)
{
    uint64_t cells = (uint64_t)in->width * (uint64_t)in->height;
    return tsio_check_memory(JOB_MEM_BASE + cells * JOB_MEM_PPA_CELL, path,
                             "coarsen it (gdalwarp -tr) or allow more memory (not even tiles of 64 "
                             "cells fit)",
                             err);
}

/* The memory of the PPA in tiles of T cells (tsjob_ppa_prepare). */
static uint64_t ppa_tiled_need(const tsjob_ppa *job, const tsio_georef *g, uint64_t T)
{
    uint64_t side = T + 2 * (uint64_t)job->params.profile_length;
    uint64_t cells = (uint64_t)g->width * (uint64_t)g->height;
    int drainage = job->params.min_drainage > 0 && job->params.features != TS_PPA_RIDGES;
    uint64_t tiles = side * side * JOB_MEM_PPA_TILE_CELL + T * (uint64_t)g->width * JOB_MEM_PPA_STRIP +
                     cells * JOB_MEM_PPA_CHAINS;
    /* the drainage (valleys where the water runs) is routed in tiles too,
     * before the axes: a tile per thread, the tiles' borders, a bit a cell */
    long threads = sysconf(_SC_NPROCESSORS_ONLN);
    uint64_t dt = T < 16384 ? T : 16384;
    uint64_t flow = drainage ? (uint64_t)(threads > 0 ? threads : 1) * dt * dt * JOB_MEM_PPA_DRAINAGE +
                                   cells / dt * 4 * JOB_MEM_PPA_DRAINAGE_BORDER + cells / 8
                             : 0;
    return JOB_MEM_BASE + (flow > tiles ? flow : tiles);
}

int tsjob_ppa_prepare(const tsjob_ppa *job, tsjob_ppa_result *res, tsio_err *err)
{
    int y;
    tsio_georef g;
    uint64_t limit;
    int from_option;
    memset(res, 0, sizeof *res);
    /* the size before the cells: a huge raster is refused, not read */
    if (tsio_read_georef(job->input, &g, err) != 0)
        return -1;
    res->band = job->band;
    res->tile_size = job->tile_size;
    if (res->tile_size == 0 && tsio_memory_limit(&limit, &from_option, err) == 0 &&
        JOB_MEM_BASE + (uint64_t)g.width * (uint64_t)g.height * JOB_MEM_PPA_CELL > limit) {
        /* too large in one piece: the largest tiles that fit */
        static const int sizes[] = {8192, 4096, 2048, 1024, 512, 256, 128, 64};
        size_t i;
        for (i = 0; i < sizeof sizes / sizeof sizes[0]; i++)
            if ((sizes[i] < g.width || sizes[i] < g.height) &&
                ppa_tiled_need(job, &g, (uint64_t)sizes[i]) <= limit) {
                res->tile_size = sizes[i];
                res->auto_tiles = 1;
                break;
            }
    }
    if (res->tile_size > 0 && (res->tile_size < g.width || res->tile_size < g.height)) {
        y = tsio_check_memory(ppa_tiled_need(job, &g, (uint64_t)res->tile_size), job->input,
                              "give a smaller tile size (--tile-size)", err);
    } else {
        res->tile_size = 0; /* one tile: in one piece */
        y = tsjob_ppa_check_memory(&g, job->input, err);
    }
    tsio_georef_free(&g);
    if (y != 0)
        return -1;
    if (res->tile_size > 0) {
        if (!(res->reader = tsio_dem_open(job->input, job->band, &res->in, err)))
            return -1;
    } else {
        if (tsio_read_dem(job->input, job->band, &res->in, err) != 0)
            return -1;
        job_warn_sentinels(&res->warning, job->input, &res->in);
    }
    if (!res->in.dx_m && job->cell_size > 0) {
        res->in.dx_m = malloc((size_t)res->in.geo.height * sizeof *res->in.dx_m);
        res->in.dy_m = malloc((size_t)res->in.geo.height * sizeof *res->in.dy_m);
        if (!res->in.dx_m || !res->in.dy_m) {
            tsio_errf(err, job->input, "out of memory");
            tsjob_ppa_result_free(res);
            return -1;
        }
        for (y = 0; y < res->in.geo.height; y++)
            res->in.dx_m[y] = res->in.dy_m[y] = job->cell_size;
    }
    res->no_crs = res->in.dx_m == NULL;
    if (res->no_crs && job->params.min_branch_length.unit == TS_UNIT_METRES) {
        tsio_errf(
            err, job->input,
            "has no CRS, so the minimum branch length must be in cells (or give a cell size)");
        tsjob_ppa_result_free(res);
        return -1;
    }
    res->metrics = tsio_metrics(&res->in, &res->mstore);
    return 0;
}

int tsjob_ppa_compute(ts_ctx *ctx, const tsjob_ppa *job, tsjob_ppa_result *res, tsio_err *err)
{
    size_t n = (size_t)res->in.geo.width * (size_t)res->in.geo.height;
    if (res->tile_size > 0) { /* made tile by tile while the output is written */
        res->ctx = ctx;
        res->params = job->params;
        res->input = job->input;
        return 0;
    }
    if (ts_ppa_extract(ctx, &res->in.r, res->metrics, &job->params, &res->features) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        return -1;
    }
    res->codes = malloc(n);
    if (!res->codes) {
        tsio_errf(err, job->input, "out of memory");
        return -1;
    }
    if (ts_features_codes(ctx, res->features, &res->in.r, res->codes) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        return -1;
    }
    return 0;
}

void tsjob_ppa_result_free(tsjob_ppa_result *res)
{
    if (!res)
        return;
    ts_features_free(res->features);
    free(res->codes);
    tsio_reader_close(res->reader);
    tsio_raster_free(&res->in);
    memset(res, 0, sizeof *res);
}

/* ------------------------------------------------------------------ */
/* synth                                                               */
/* ------------------------------------------------------------------ */

/* Cells of an exemplar, as read and resampled to cells of target_area square
 * metres (0: as they are); *ratio (may be NULL) is the one between the two.  An
 * exemplar without CRS has cells of cell_size metres when that is given. */
static int job_exemplar_cells(const char *path, double target_area, double cell_size,
                              uint64_t *source, uint64_t *target, double *ratio, tsio_err *err)
{
    tsio_georef g;
    double *dx = NULL, *dy = NULL, r = 1.0;
    if (tsio_read_georef(path, &g, err) != 0)
        return -1;
    *source = (uint64_t)g.width * (uint64_t)g.height;
    if (target_area > 0 && tsio_georef_metrics(&g, &dx, &dy, err) == 0) {
        double ex_area = dx ? dx[g.height / 2] * dy[g.height / 2] : cell_size * cell_size;
        if (ex_area > 0)
            r = ex_area / target_area;
    }
    free(dx);
    free(dy);
    tsio_georef_free(&g);
    *target = (uint64_t)((double)*source * r + 1.0);
    if (ratio)
        *ratio = r;
    return 0;
}

/* The whole job's memory against the limit, before any exemplar is read. */
static int job_synth_check_memory(const tsjob_synth *job, const tsjob_synth_result *res,
                                  tsio_err *err)
{
    uint64_t cells = (uint64_t)res->geo.width * (uint64_t)res->geo.height;
    uint64_t need = JOB_MEM_BASE, biggest = 0;
    int i;
    if (job->lazy && res->params.tiled > 0) {
        /* tile by tile: the tiles a front end keeps (at least one request's
         * cone) and every thread's tile being made, with its margins */
        uint64_t T = (uint64_t)res->params.tiled, P = (uint64_t)res->params.patch_size.value;
        uint64_t cone = TSJOB_TILE_CONE * (T + 2 * P) * (T + 2 * P) * sizeof(float);
        long threads = sysconf(_SC_NPROCESSORS_ONLN);
        need += (uint64_t)job->tile_cache > cone ? (uint64_t)job->tile_cache : cone;
        need += (uint64_t)(threads > 0 ? threads : 1) * (T + 2 * P) * (T + 2 * P) *
                (JOB_MEM_SYNTH_CELL + JOB_MEM_TILE_CELL);
    } else if (res->params.tiled > 0) {
        /* tiles without maps are made in bands of rows: 2 B + 1 rows of tiles'
         * windows alive at once (ts_synth_tiled_band), and every thread's tile
         * being made (tiles with debug maps keep every window: checked again by
         * tsjob_synth_compute) */
        uint64_t T = (uint64_t)res->params.tiled, P = (uint64_t)res->params.patch_size.value;
        uint64_t nti = ((uint64_t)res->geo.width + T - 1) / T;
        long nproc = sysconf(_SC_NPROCESSORS_ONLN);
        uint64_t threads = (uint64_t)(nproc > 0 ? nproc : 1); /* (the most a run takes) */
        uint64_t B = (uint64_t)ts_synth_tiled_band((int)threads, res->geo.width, (int)T);
        need += cells * (JOB_MEM_SYNTH_CELL + (job->sketch ? JOB_MEM_SKETCH_CELL : 0)) +
                (2 * B + 1) * nti * (T + 2 * P) * (T + 2 * P) * sizeof(float) +
                threads * (T + 2 * P) * (T + 2 * P) * (JOB_MEM_SYNTH_CELL + JOB_MEM_TILE_CELL);
    } else {
        need += cells * (JOB_MEM_SYNTH_CELL + (job->sketch ? JOB_MEM_SKETCH_CELL : 0) +
                         JOB_MEM_MAPS_CELL);
    }
    int cy = res->geo.height / 2;
    double t_area = res->dx_m ? res->dx_m[cy] * res->dy_m[cy] : 0.0;
    for (i = 0; i < job->n_exemplars; i++) {
        uint64_t src, tgt;
        if (job_exemplar_cells(job->exemplars[i], t_area, job->cell_size, &src, &tgt, NULL, err) !=
            0)
            return -1;
        need += tgt * JOB_MEM_EX_CELL;
        if (src > biggest)
            biggest = src; /* read one at a time */
    }
    need += biggest * JOB_MEM_EX_SOURCE_CELL;
    return tsio_check_memory(need, "synth",
                             "a smaller target grid, or smaller or coarser exemplars", err);
}

/* The job's rules live in jobspec.c (tsj_build_synth), which every front end
 * goes through; here only the guard that a job came that way. */
/* The ground metrics of a grid (NULL without CRS unless cell_size > 0:
 * then every cell is cell_size metres). */
static int job_grid_metrics(const tsio_georef *geo, double cell_size, double **dx, double **dy,
                            tsio_err *err)
{
    int y;
    if (tsio_georef_metrics(geo, dx, dy, err) != 0)
        return -1;
    if (*dx || !(cell_size > 0))
        return 0;
    *dx = malloc((size_t)geo->height * sizeof **dx);
    *dy = malloc((size_t)geo->height * sizeof **dy);
    if (!*dx || !*dy) {
        free(*dx);
        free(*dy);
        *dx = *dy = NULL;
        tsio_errf(err, "grid", "out of memory");
        return -1;
    }
    for (y = 0; y < geo->height; y++)
        (*dx)[y] = (*dy)[y] = cell_size;
    return 0;
}

/* A raster without a CRS has cells of cell_size metres whatever its
 * geotransform says.  When the job's grid (a sketch, a guide, an input: file
 * `grid`, georeference g as the job read it) and an exemplar both lack a CRS
 * and their geotransforms give cells of different sizes, the user most likely
 * meant those sizes: say what is done instead. */
static void job_warn_cell_sizes(tsio_err *warning, double cell_size, const char *grid,
                                const tsio_georef *g, const char *const *exemplars, int n)
{
    tsio_georef e;
    tsio_err ignore;
    int i;
    if (!(cell_size > 0) || !grid || g->wkt || !g->has_gt)
        return;
    for (i = 0; i < n && !warning->msg[0]; i++) {
        double a, b;
        if (tsio_read_georef(exemplars[i], &e, &ignore) != 0)
            continue;
        a = fabs(g->gt[1]);
        b = fabs(e.gt[1]);
        if (!e.wkt && e.has_gt && fabs(a - b) > 0.01 * (a > b ? a : b))
            tsio_errf(warning, grid,
                      "no CRS, cells of %g in its geotransform and %g in %s's: both are taken "
                      "as %g m (--cell-size); give them a CRS (gdal_edit.py -a_srs) to use "
                      "their own cell sizes",
                      a, b, exemplars[i], cell_size);
        tsio_georef_free(&e);
    }
}

/* The target grid of a job (like; size with origin, resolution and CRS, or
 * the first exemplar's), and its ground metrics. */
static int job_target_grid(const tsjob_grid *g, const char *first_exemplar, double cell_size,
                           tsio_georef *geo, double **dx, double **dy, tsio_err *err)
{
    if (g->like) {
        if (tsio_read_georef(g->like, geo, err) != 0)
            return -1;
    } else if (g->crs) {
        if (tsio_georef_make(g->width, g->height, g->origin_x, g->origin_y, g->res, g->res, g->crs,
                             geo, err) != 0)
            return -1;
    } else {
        /* the first exemplar's CRS, resolution and origin unless given */
        tsio_georef g0;
        int rc;
        if (tsio_read_georef(first_exemplar, &g0, err) != 0)
            return -1;
        rc = tsio_georef_make(g->width, g->height, g->has_origin ? g->origin_x : g0.gt[0],
                              g->has_origin ? g->origin_y : g0.gt[3],
                              g->has_res ? g->res : fabs(g0.gt[1]),
                              g->has_res ? g->res : fabs(g0.gt[5]), g0.wkt, geo, err);
        tsio_georef_free(&g0);
        if (rc != 0)
            return -1;
    }
    return job_grid_metrics(geo, cell_size, dx, dy, err);
}

/* The grid of a sketch of lines drawn at resolution R: the extent given,
 * or the lines' box grown by a patch on each side, in the CRS given or the
 * lines'. */
static int job_lines_grid(const tsjob_synth *job, tsio_georef *geo, tsio_err *err)
{
    const tsjob_grid *g = &job->grid;
    tsio_georef crs;
    tsio_lines l;
    double box[4], margin, w, h, R = g->res;
    const ts_length *ps = &job->params.patch_size;
    int rc;
    memset(&crs, 0, sizeof crs);
    if (g->crs && tsio_georef_make(1, 1, 0.0, 0.0, 1.0, 1.0, g->crs, &crs, err) != 0)
        return -1;
    if (tsio_read_lines(job->sketch, job->sketch_layer, job->kind_field, job->height_field,
                        crs.wkt, &l, err) != 0) {
        tsio_georef_free(&crs);
        return -1;
    }
    if (job->has_extent) {
        memcpy(box, job->extent, sizeof box);
    } else {
        margin = ps->unit == TS_UNIT_METRES ? ps->value / (l.is_geographic ? 111320.0 : 1.0)
                                            : ps->value * R;
        /* on the lattice of the resolution, as a GIS aligns grids */
        box[0] = floor((l.box[0] - margin) / R) * R;
        box[1] = floor((l.box[1] - margin) / R) * R;
        box[2] = ceil((l.box[2] + margin) / R) * R;
        box[3] = ceil((l.box[3] + margin) / R) * R;
    }
    w = ceil((box[2] - box[0]) / R - 1e-9);
    h = ceil((box[3] - box[1]) / R - 1e-9);
    if (!(w >= 1 && h >= 1 && w <= 65536 && h <= 65536)) {
        tsio_errf(err, job->sketch,
                  "the grid at resolution %g would be %.0f x %.0f cells: give a coarser "
                  "resolution or an extent (at most 65536 cells a side)",
                  R, w, h);
        rc = -1;
    } else {
        rc = tsio_georef_make((int)w, (int)h, box[0], box[3], R, R, l.wkt, geo, err);
    }
    tsio_lines_free(&l);
    tsio_georef_free(&crs);
    return rc;
}

/* The output grid of a sketch: a raster's own; lines on like's grid or
 * drawn at a resolution. */
static int job_sketch_grid(const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err)
{
    const tsjob_grid *g = &job->grid;
    if (!tsio_is_lines(job->sketch)) {
        const char *bad = g->like          ? "like"
                          : g->has_res     ? "resolution"
                          : g->crs         ? "crs"
                          : job->has_extent ? "extent"
                          : job->sketch_layer ? "sketch_layer"
                          : job->kind_field   ? "kind_field"
                          : job->height_field ? "height_field"
                          : job->snap >= 0    ? "snap"
                                              : NULL;
        if (bad) {
            tsio_errf(err, job->sketch, "a painted sketch sets the output grid: give no %s",
                      bad);
            return -1;
        }
        if (tsio_read_georef(job->sketch, &res->geo, err) != 0)
            return -1;
    } else {
        res->sketch_lines = 1;
        if (!g->like && !g->has_res) {
            tsio_errf(err, job->sketch,
                      "a sketch of lines needs the output grid: give like, or resolution");
            return -1;
        }
        if (g->like ? tsio_read_georef(g->like, &res->geo, err) != 0
                    : job_lines_grid(job, &res->geo, err) != 0)
            return -1;
    }
    return job_grid_metrics(&res->geo, job->cell_size, &res->dx_m, &res->dy_m, err);
}

static int job_synth_built(const tsjob_synth *job)
{
    const tsjob_grid *g = &job->grid;
    if (job->n_exemplars < 1 || job->n_exemplars > TSJOB_MAX_EXEMPLARS)
        return 0;
    if (job->sketch && (g->width || g->has_origin))
        return 0;
    return !g->crs || (g->has_res && (g->has_origin || job->sketch));
}

int tsjob_synth_prepare(const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err)
{
    const tsjob_grid *g = &job->grid;
    ts_ctx *ctx;
    int bad;
    memset(res, 0, sizeof *res);
    if (!job_synth_built(job)) {
        tsio_errf(err, "synth", "internal error: a job not checked by tsj_build_synth");
        return -1;
    }
    ctx = ts_ctx_new();
    bad = !ctx || ts_params_validate(ctx, "synth", &job->params) != TS_OK;
    if (bad) {
        tsio_errf(err, "synth", "%s", ctx ? ts_ctx_message(ctx) : "out of memory");
        ts_ctx_free(ctx);
        return -1;
    }
    ts_ctx_free(ctx);
    if (job->sketch) {
        if (job_sketch_grid(job, res, err) != 0) {
            tsjob_synth_result_free(res);
            return -1;
        }
    } else if (job_target_grid(g, job->exemplars[0], job->cell_size, &res->geo, &res->dx_m,
                               &res->dy_m, err) != 0) {
        tsjob_synth_result_free(res);
        return -1;
    }
    if (res->dx_m) {
        res->mstore.dx = res->dx_m;
        res->mstore.dy = res->dy_m;
        res->metrics = &res->mstore;
    }
    job_warn_cell_sizes(&res->warning, job->cell_size, job->sketch ? job->sketch : g->like,
                        &res->geo, (const char *const *)job->exemplars, job->n_exemplars);
    /* lengths in metres become cells of the target grid (its ground cell
     * size on the middle row: the exemplars are resampled to it too) */
    res->params = job->params;
    ctx = ts_ctx_new();
    {
        int cy = res->geo.height / 2;
        double cell_m = res->dx_m ? sqrt(res->dx_m[cy] * res->dy_m[cy]) : 0.0;
        bad = !ctx || ts_synth_params_resolve(ctx, &res->params, cell_m) != TS_OK;
    }
    if (bad) {
        /* the grid's source: the sketch, --like, or the first exemplar */
        tsio_errf(err,
                  job->sketch ? job->sketch
                  : g->like   ? g->like
                              : job->exemplars[0],
                  "%s", ctx ? ts_ctx_message(ctx) : "out of memory");
        ts_ctx_free(ctx);
        tsjob_synth_result_free(res);
        return -1;
    }
    ts_ctx_free(ctx);
    if (res->params.tiled > 0) { /* the core's own check of the tile size, before the work */
        ctx = ts_ctx_new();
        bad = !ctx || ts_synth_tile_window(ctx, &res->params, res->params.tiled, res->geo.width,
                                           res->geo.height, 0, 0, NULL, NULL) != TS_OK;
        if (bad)
            tsio_errf(err, "synth", "%s", ctx ? ts_ctx_message(ctx) : "out of memory");
        ts_ctx_free(ctx);
        if (bad) {
            tsjob_synth_result_free(res);
            return -1;
        }
    }
    if (res->params.tiled > 0 && job->sketch) {
        tsio_errf(err, "synth", "tiles (tiled %d) are for free synthesis: not with a sketch yet",
                  res->params.tiled);
        tsjob_synth_result_free(res);
        return -1;
    }
    if (job_synth_check_memory(job, res, err) != 0) {
        tsjob_synth_result_free(res);
        return -1;
    }
    if (job->sketch && (res->geo.width < (int)res->params.patch_size.value ||
                        res->geo.height < (int)res->params.patch_size.value)) {
        tsio_errf(err, job->sketch, "%d x %d cells is smaller than a patch (%d)", res->geo.width,
                  res->geo.height, (int)res->params.patch_size.value);
        tsjob_synth_result_free(res);
        return -1;
    }
    return 0;
}

static int job_constraints(const tsjob_synth *job, tsjob_synth_result *res, unsigned char *flags,
                           tsio_err *err);

/* A failed core call as "<file>: <message>": the exemplar's file when the
 * core names an exemplar (ts_ctx_failed_input), else `fallback`. */
static void job_core_err(ts_ctx *ctx, const tsjob_synth *job, const char *fallback, tsio_err *err)
{
    int which = ts_ctx_failed_input(ctx);
    tsio_errf(err, which >= 0 && which < job->n_exemplars ? job->exemplars[which] : fallback, "%s",
              ts_ctx_message(ctx));
}

/* res->maps, allocated for the grid. */
static int job_alloc_maps(tsjob_synth_result *res, tsio_err *err)
{
    size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
    ts_synth_maps *m = &res->maps;
    m->source_exemplar = malloc(n * sizeof(int32_t));
    m->source_x = malloc(n * sizeof(int32_t));
    m->source_y = malloc(n * sizeof(int32_t));
    m->order = malloc(n * sizeof(int32_t));
    m->seams = malloc(n);
    res->has_maps = 1;
    if (!m->source_exemplar || !m->source_x || !m->source_y || !m->order || !m->seams) {
        tsio_errf(err, "synth", "out of memory for the debug maps");
        return -1;
    }
    return 0;
}

/* The exemplars at the target resolution, one at a time (ex[i] owned by
 * the caller, freed by it on failure too). */
static int job_read_exemplars(const tsjob_synth *job, tsjob_synth_result *res, tsio_raster *ex,
                              ts_raster *exr, tsio_err *err)
{
    int i, cy = res->geo.height / 2, P = (int)res->params.patch_size.value;
    for (i = 0; i < job->n_exemplars; i++) {
        double factor = 1.0;
        if (tsio_read_raster_resampled(job->exemplars[i], job->band, res->dx_m ? res->dx_m[cy] : 0,
                                       res->dy_m ? res->dy_m[cy] : 0, job->cell_size, &ex[i],
                                       &factor, err) != 0)
            return -1;
        job_warn_sentinels(&res->warning, job->exemplars[i], &ex[i]);
        if (res->dx_m && !ex[i].dx_m && !res->exemplar_no_crs)
            res->exemplar_no_crs = i + 1;
        if (ex[i].r.width < P || ex[i].r.height < P) {
            tsio_errf(err, job->exemplars[i],
                      "%d x %d cells at the target resolution is smaller than a patch (%d "
                      "cells)",
                      ex[i].r.width, ex[i].r.height, P);
            return -1;
        }
        exr[i] = ex[i].r;
    }
    return 0;
}

static int job_pin_read(const tsjob_synth *job, tsjob_synth_result *res, int i, tsio_raster *ex,
                        int *x0, int *y0, int *w, int *h, tsio_err *err);

int tsjob_synth_setup(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err)
{
    int i;
    (void)ctx;
    if (!(res->params.tiled > 0)) {
        tsio_errf(err, "synth", "internal error: tile by tile needs a tiled synthesis");
        return -1;
    }
    if (res->n_ex)
        return 0;
    if (job_read_exemplars(job, res, res->ex, res->exr, err) != 0) {
        for (i = 0; i < job->n_exemplars; i++)
            tsio_raster_free(&res->ex[i]);
        return -1;
    }
    res->n_ex = job->n_exemplars;
    for (i = 0; i < job->n_pins; i++) {
        int *wn = res->pin_win[i];
        if (job_pin_read(job, res, i, &res->pin_ex[i], &wn[0], &wn[1], &wn[2], &wn[3], err) != 0)
            return -1;
    }
    return 0;
}

/* Region ids (a label map's values) into the exemplar each takes, -1 for
 * any (--region-exemplar rules). */
static void job_region_exemplars(const tsjob_synth *job, int32_t *cell_ex, size_t n)
{
    size_t c;
    int r;
    for (c = 0; c < n; c++) {
        int32_t id = cell_ex[c], ex_i = -1;
        for (r = 0; r < job->n_region_rules; r++)
            if (job->region_id[r] == id)
                ex_i = job->region_exemplar[r];
        cell_ex[c] = ex_i;
    }
}

/* A tile's window's part of the job's constraints (tsjob_synth_tiles). */
typedef struct job_window_cons {
    ts_synth_constraints cons;
    unsigned char *flags;
    int32_t *cell_ex;
    float *heights;
} job_window_cons;

/* Read window [x0, x0 + w) x [y0, y0 + h) of a raster on the output grid
 * into dst (w x h): the same cells the whole-grid reads give. */
static int job_grid_window(const char *path, const char *what, const tsjob_synth_result *res,
                           int x0, int y0, int w, int h, float *dst, tsio_err *err)
{
    tsio_raster hdr;
    size_t nv, ns;
    tsio_reader *rd = tsio_dem_open(path, 1, &hdr, err);
    int rc;
    if (!rd)
        return -1;
    if (hdr.geo.width != res->geo.width || hdr.geo.height != res->geo.height) {
        tsio_errf(err, path, "%s is %d x %d cells, the output %d x %d", what, hdr.geo.width,
                  hdr.geo.height, res->geo.width, res->geo.height);
        tsio_reader_close(rd);
        tsio_raster_free(&hdr);
        return -1;
    }
    rc = tsio_dem_window(rd, x0, y0, w, h, dst, &nv, &ns, err);
    tsio_reader_close(rd);
    tsio_raster_free(&hdr);
    return rc;
}

/* The constraints of tile t's window, as job_constraints and
 * tsjob_synth_compute make them for the whole grid, cut to the window; the
 * fixed cells' values into t->window. */
static int job_window_constraints(ts_ctx *ctx, const tsjob_synth *job,
                                  const tsjob_synth_result *res, ts_synth_tile *t,
                                  job_window_cons *wc, tsio_err *err)
{
    int win[4], x, y, i;
    size_t n, c;
    float *tmp = NULL;
    if (ts_synth_tile_window(ctx, &res->params, res->params.tiled, res->geo.width, res->geo.height,
                             t->ti, t->tj, win, NULL) != TS_OK) {
        tsio_errf(err, "synth", "%s", ts_ctx_message(ctx));
        return -1;
    }
    n = (size_t)win[2] * (size_t)win[3];
    wc->cons = ts_synth_constraints_default();
    wc->flags = calloc(n, 1);
    tmp = malloc(n * sizeof *tmp);
    if (!wc->flags || !tmp)
        goto oom;
    wc->cons.cell_flags = wc->flags;
    if (job->water) {
        if (job_grid_window(job->water, "the water mask", res, win[0], win[1], win[2], win[3], tmp,
                            err) != 0)
            goto fail;
        for (c = 0; c < n; c++)
            if (!isnan(tmp[c]) && tmp[c] != 0) {
                wc->flags[c] |= TS_CELL_FIXED | TS_CELL_WATER;
                t->window
                    .data[(c / (size_t)win[2]) * (size_t)t->window.stride + c % (size_t)win[2]] =
                    (float)job->water_level;
            }
    }
    for (i = 0; i < job->n_pins; i++) {
        const tsjob_pin *p = &job->pins[i];
        const int *pw = res->pin_win[i];
        int ya = p->y > win[1] ? p->y : win[1], xa = p->x > win[0] ? p->x : win[0];
        int yb = p->y + pw[3] < win[1] + win[3] ? p->y + pw[3] : win[1] + win[3];
        int xb = p->x + pw[2] < win[0] + win[2] ? p->x + pw[2] : win[0] + win[2];
        for (y = ya; y < yb; y++)
            for (x = xa; x < xb; x++) {
                float v = TS_PIX(&res->pin_ex[i].r, pw[0] + x - p->x, pw[1] + y - p->y);
                if (isnan(v))
                    continue;
                TS_PIX(&t->window, x - win[0], y - win[1]) = v;
                wc->flags[(size_t)(y - win[1]) * (size_t)win[2] + (size_t)(x - win[0])] =
                    (unsigned char)((wc->flags[(size_t)(y - win[1]) * (size_t)win[2] +
                                               (size_t)(x - win[0])] |
                                     TS_CELL_FIXED) &
                                    ~TS_CELL_WATER); /* a pin over water: land */
            }
    }
    if (job->heights) {
        if (!(wc->heights = malloc(n * sizeof *wc->heights)))
            goto oom;
        if (job_grid_window(job->heights, "the heights", res, win[0], win[1], win[2], win[3],
                            wc->heights, err) != 0)
            goto fail;
        wc->cons.heights = wc->heights;
        wc->cons.alpha_h = job->alpha_h;
    }
    if (job->regions) {
        if (!(wc->cell_ex = malloc(n * sizeof *wc->cell_ex)))
            goto oom;
        if (tsio_read_label_window(job->regions, &res->geo, win[0], win[1], win[2], win[3],
                                   "region", INT32_MIN, wc->cell_ex, err) != 0)
            goto fail;
        job_region_exemplars(job, wc->cell_ex, n);
        wc->cons.cell_exemplar = wc->cell_ex;
    }
    free(tmp);
    return 0;
oom:
    tsio_errf(err, "synth", "out of memory for a tile's constraints");
fail:
    free(tmp);
    return -1;
}

int tsjob_synth_tiles(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                      ts_synth_tile *tiles, int n_tiles, tsio_err *err)
{
    if (!res->n_ex) {
        tsio_errf(err, "synth", "internal error: tiles before setup");
        return -1;
    }
    if (job->n_pins || job->water || job->heights || job->regions) {
        /* each tile with its window's part of the constraints, read window by window */
        job_window_cons wc[64];
        int k, rc = 0;
        if (n_tiles > 64) {
            tsio_errf(err, "synth", "internal error: more than 64 tiles in one call");
            return -1;
        }
        memset(wc, 0, sizeof wc);
        for (k = 0; k < n_tiles && rc == 0; k++) {
            rc = job_window_constraints(ctx, job, res, &tiles[k], &wc[k], err);
            tiles[k].constraints = &wc[k].cons;
        }
        if (rc == 0 && ts_synth_tiles(ctx, res->exr, res->n_ex, &res->params, res->params.tiled,
                                      res->geo.width, res->geo.height, tiles, n_tiles) != TS_OK) {
            job_core_err(ctx, job, "synth", err);
            rc = -1;
        }
        for (k = 0; k < n_tiles; k++) {
            tiles[k].constraints = NULL;
            free(wc[k].flags);
            free(wc[k].cell_ex);
            free(wc[k].heights);
        }
        return rc;
    }
    if (ts_synth_tiles(ctx, res->exr, res->n_ex, &res->params, res->params.tiled, res->geo.width,
                       res->geo.height, tiles, n_tiles) != TS_OK) {
        job_core_err(ctx, job, "synth", err);
        return -1;
    }
    return 0;
}

/* A sketch of lines: the lines on the output grid as a feature graph, the
 * heights they carry added to the wanted heights, the synthesis. */
static int job_sketch_lines(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                            const ts_raster *exr, const ts_synth_params *params,
                            ts_synth_constraints *cons, ts_synth_maps *maps, tsio_err *err)
{
    tsio_lines l;
    ts_features *f = NULL;
    float *hz = NULL;
    size_t n = (size_t)res->geo.width * (size_t)res->geo.height, i, k, any = 0;
    int rc = -1;
    if (tsio_read_lines(job->sketch, job->sketch_layer, job->kind_field, job->height_field,
                        res->geo.wkt, &l, err) != 0)
        return -1;
    tsio_lines_to_cells(&l, &res->geo);
    if (ts_features_from_lines(ctx, res->geo.width, res->geo.height, l.lines, l.n,
                               job->snap >= 0 ? job->snap : 2.0, &f) != TS_OK) {
        tsio_errf(err, job->sketch, "%s", ts_ctx_message(ctx));
        goto done;
    }
    for (i = 0; i < n && !any; i++)
        any = f->mask[i] != 0;
    if (!any) {
        tsio_errf(err, job->sketch, "no line crosses the output grid");
        goto done;
    }
    for (k = 0; k < f->n_verts && !hz; k++)
        if (!isnan(f->verts[k].z)) {
            if (!(hz = malloc(n * sizeof *hz))) {
                tsio_errf(err, job->sketch, "out of memory");
                goto done;
            }
            for (i = 0; i < n; i++)
                hz[i] = cons->heights ? cons->heights[i] : NAN;
        }
    for (k = 0; hz && k < f->n_verts; k++) {
        const ts_feature_vertex *v = &f->verts[k];
        size_t c = (size_t)v->y * (size_t)res->geo.width + (size_t)v->x;
        if (!isnan(v->z) && isnan(hz[c]))
            hz[c] = v->z;
    }
    if (hz) {
        cons->heights = hz;
        if (!job->heights)
            cons->alpha_h = job->alpha_h;
    }
    if (ts_synth_sketch_features(ctx, f, exr, job->n_exemplars, &job->sketch_params, params, cons,
                                 &res->out, maps, &res->sketch_info) != TS_OK) {
        job_core_err(ctx, job, job->sketch, err);
        goto done;
    }
    res->sketch_features = f;
    f = NULL;
    rc = 0;
done:
    ts_features_free(f);
    free(hz);
    tsio_lines_free(&l);
    return rc;
}

int tsjob_synth_compute(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res, int keep_maps,
                        tsio_err *err)
{
    ts_synth_maps *maps = NULL;
    tsio_raster ex[TSJOB_MAX_EXEMPLARS];
    ts_raster exr[TSJOB_MAX_EXEMPLARS];
    unsigned char *flags = NULL;
    int32_t *cell_ex = NULL;
    tsio_raster heights;
    ts_synth_params params = res->params; /* lengths in cells */
    ts_synth_constraints cons = ts_synth_constraints_default();
    int i, rc = -1;
    memset(ex, 0, sizeof ex);
    memset(&heights, 0, sizeof heights);
    if (keep_maps) {
        if (res->params.tiled > 0) {
            /* in tiles, the maps of every tile's window too (up to 4 x the grid:
             * tiles of 2 patches), beyond what the prepare checked */
            uint64_t cells = (uint64_t)res->geo.width * (uint64_t)res->geo.height;
            if (tsio_check_memory(JOB_MEM_BASE + cells * (JOB_MEM_SYNTH_CELL + JOB_MEM_TILED_CELL +
                                                          5 * JOB_MEM_MAPS_CELL),
                                  "synth", "no --debug-dir, or a smaller target grid", err) != 0)
                return -1;
        }
        if (job_alloc_maps(res, err) != 0)
            return -1;
        maps = &res->maps;
    }
    if (job_read_exemplars(job, res, ex, exr, err) != 0)
        goto done;
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        tsio_errf(err, "synth", "%s", ts_ctx_message(ctx));
        goto done;
    }
    flags = calloc((size_t)res->geo.width * (size_t)res->geo.height, 1);
    if (!flags) {
        tsio_errf(err, "synth", "out of memory");
        goto done;
    }
    if (job_constraints(job, res, flags, err) != 0)
        goto done;
    cons.cell_flags = flags;
    if (job->heights) {
        if (tsio_read_dem(job->heights, 1, &heights, err) != 0)
            goto done;
        job_warn_sentinels(&res->warning, job->heights, &heights);
        if (heights.geo.width != res->geo.width || heights.geo.height != res->geo.height) {
            tsio_errf(err, job->heights, "the heights are %d x %d cells, the output %d x %d",
                      heights.geo.width, heights.geo.height, res->geo.width, res->geo.height);
            goto done;
        }
        cons.heights = heights.r.data;
        cons.alpha_h = job->alpha_h;
    }
    if (job->regions) {
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
        cell_ex = malloc(n * sizeof *cell_ex);
        if (!cell_ex) {
            tsio_errf(err, job->regions, "out of memory");
            goto done;
        }
        if (tsio_read_label_map(job->regions, &res->geo, "region", INT32_MIN, cell_ex, err) != 0)
            goto done;
        job_region_exemplars(job, cell_ex, n);
        cons.cell_exemplar = cell_ex;
    }
    if (job->sketch && res->sketch_lines) {
        if (job_sketch_lines(ctx, job, res, exr, &params, &cons, maps, err) != 0)
            goto done;
    } else if (job->sketch) {
        tsio_raster sk;
        int bad;
        if (tsio_read_raster(job->sketch, 1, &sk, err) != 0)
            goto done;
        bad =
            ts_synth_sketch(ctx, &sk.r, exr, job->n_exemplars, &job->sketch_params, &params, &cons,
                            &res->out, maps, &res->sketch_features, &res->sketch_info) != TS_OK;
        tsio_raster_free(&sk);
        if (bad) {
            job_core_err(ctx, job, job->sketch, err);
            goto done;
        }
    } else if (ts_synth_patches(ctx, exr, job->n_exemplars, &params, &cons, &res->out, maps) !=
               TS_OK) {
        job_core_err(ctx, job, "synth", err);
        goto done;
    }
    rc = 0;
done:
    free(flags);
    free(cell_ex);
    tsio_raster_free(&heights);
    for (i = 0; i < job->n_exemplars; i++)
        tsio_raster_free(&ex[i]);
    return rc;
}

int tsjob_parse_pin(const char *spec, tsjob_pin *pin, char *path_buf, size_t path_len)
{
    const char *at = strrchr(spec, '@'), *colon;
    size_t n;
    if (!at)
        return -1;
    for (colon = at; colon > spec && *colon != ':'; colon--)
        ;
    if (colon == spec || (n = (size_t)(colon - spec)) >= path_len)
        return -1;
    memcpy(path_buf, spec, n);
    path_buf[n] = '\0';
    pin->path = path_buf;
    {
        /* six whole numbers in 0..INT_MAX, read without overflow (sscanf's %d
         * is undefined past INT_MAX) */
        int *dst[6] = {&pin->xoff, &pin->yoff, &pin->width, &pin->height, &pin->x, &pin->y};
        const char seps[6] = {',', ',', ',', '@', ',', '\0'};
        const char *s = colon + 1;
        for (n = 0; n < 6; n++) {
            char *end;
            long long v;
            if (!isdigit((unsigned char)*s))
                return -1;
            errno = 0;
            v = strtoll(s, &end, 10);
            if (errno == ERANGE || v > INT_MAX || *end != seps[n])
                return -1;
            *dst[n] = (int)v;
            s = end + (seps[n] ? 1 : 0);
        }
    }
    if (pin->width < 1 || pin->height < 1)
        return -1;
    return 0;
}

/* Water and pins go into `out` before the synthesis, as fixed cells. */
/* Pin i at the target resolution, checked: the raster and the pinned
 * window in its cells (ex owned by the caller on success). */
static int job_pin_read(const tsjob_synth *job, tsjob_synth_result *res, int i, tsio_raster *ex,
                        int *x0, int *y0, int *w, int *h, tsio_err *err)
{
    const tsjob_pin *p = &job->pins[i];
    int W = res->geo.width, H = res->geo.height, cy = H / 2;
    double f = 1.0;
    if (tsio_read_raster_resampled(p->path, job->band, res->dx_m ? res->dx_m[cy] : 0,
                                   res->dy_m ? res->dy_m[cy] : 0, job->cell_size, ex, &f, err) != 0)
        return -1;
    job_warn_sentinels(&res->warning, p->path, ex);
    /* the window in the file's cells, at the output's resolution; every sum in
     * 64 bits (the user's numbers reach INT_MAX) */
    double fx0 = (double)p->xoff * f, fy0 = (double)p->yoff * f;
    double fw = (double)p->width * f, fh = (double)p->height * f;
    if (!(fx0 + fw <= ex->r.width + 0.5 && fy0 + fh <= ex->r.height + 0.5) ||
        (int64_t)p->xoff + p->width > (int64_t)lround(ex->r.width / f) + 1) {
        *w = 0; /* refused below */
    } else {
        *x0 = (int)lround(fx0);
        *y0 = (int)lround(fy0);
        *w = (int)lround(fw);
        *h = (int)lround(fh);
    }
    if (*w < 1 || *h < 1 || (int64_t)*x0 + *w > ex->r.width ||
        (int64_t)*y0 + *h > ex->r.height) {
        tsio_errf(err, p->path,
                  "the pinned window %d,%d,%d,%d is not inside "
                  "the raster",
                  p->xoff, p->yoff, p->width, p->height);
        tsio_raster_free(ex);
        return -1;
    }
    if ((int64_t)p->x + *w > W || (int64_t)p->y + *h > H) {
        tsio_errf(err, p->path,
                  "the pinned window (%d x %d output cells) at %d,%d leaves the output "
                  "(%d x %d)",
                  *w, *h, p->x, p->y, W, H);
        tsio_raster_free(ex);
        return -1;
    }
    return 0;
}

static int job_constraints(const tsjob_synth *job, tsjob_synth_result *res, unsigned char *flags,
                           tsio_err *err)
{
    int i, x, y, W = res->geo.width, H = res->geo.height;
    if (job->water) {
        tsio_raster m;
        if (tsio_read_raster(job->water, 1, &m, err) != 0)
            return -1;
        if (m.geo.width != W || m.geo.height != H) {
            tsio_errf(err, job->water, "the water mask is %d x %d cells, the output %d x %d",
                      m.geo.width, m.geo.height, W, H);
            tsio_raster_free(&m);
            return -1;
        }
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                float v = TS_PIX(&m.r, x, y);
                if (!isnan(v) && v != 0) {
                    TS_PIX(&res->out, x, y) = (float)job->water_level;
                    flags[(size_t)y * (size_t)W + (size_t)x] |= TS_CELL_FIXED | TS_CELL_WATER;
                }
            }
        tsio_raster_free(&m);
    }
    for (i = 0; i < job->n_pins; i++) {
        const tsjob_pin *p = &job->pins[i];
        tsio_raster ex;
        int x0, y0, w, h;
        if (job_pin_read(job, res, i, &ex, &x0, &y0, &w, &h, err) != 0)
            return -1;
        for (y = 0; y < h; y++)
            for (x = 0; x < w; x++) {
                float v = TS_PIX(&ex.r, x0 + x, y0 + y);
                if (isnan(v))
                    continue; /* exemplar nodata: left to the synthesis */
                TS_PIX(&res->out, p->x + x, p->y + y) = v;
                flags[(size_t)(p->y + y) * (size_t)W + (size_t)(p->x + x)] =
                    (unsigned char)((flags[(size_t)(p->y + y) * (size_t)W + (size_t)(p->x + x)] |
                                     TS_CELL_FIXED) &
                                    ~TS_CELL_WATER); /* a pin over water: land */
            }
        tsio_raster_free(&ex);
    }
    return 0;
}

void tsjob_synth_result_free(tsjob_synth_result *res)
{
    if (!res)
        return;
    tsio_georef_free(&res->geo);
    ts_features_free(res->sketch_features);
    free(res->maps.source_exemplar);
    free(res->maps.source_x);
    free(res->maps.source_y);
    free(res->maps.order);
    free(res->maps.seams);
    free(res->dx_m);
    free(res->dy_m);
    ts_raster_free(&res->out);
    for (int i = 0; i < TSJOB_MAX_EXEMPLARS; i++)
        tsio_raster_free(&res->ex[i]);
    for (int i = 0; i < TSJOB_MAX_PINS; i++)
        tsio_raster_free(&res->pin_ex[i]);
    memset(res, 0, sizeof *res);
}

/* ------------------------------------------------------------------ */
/* what a job writes                                                   */
/* ------------------------------------------------------------------ */

/* Refuse an output that is one of the inputs (by identity: a link or
 * another spelling of the path counts too). */
static int job_not_an_input(const char *out, const char *const *inputs, int n, tsio_err *err)
{
    int i;
    if (!out)
        return 0;
    for (i = 0; i < n; i++)
        if (inputs[i] && (tsio_same_file(out, inputs[i]) || !strcmp(out, inputs[i]))) {
            tsio_errf(err, out, "is an input (%s): an output never overwrites an input", inputs[i]);
            return -1;
        }
    return 0;
}

/* Two outputs of a job must be two files (-d: refused). */
static int job_distinct(const char *const *outs, int n, tsio_err *err)
{
    int i, j;
    for (i = 0; i < n; i++)
        for (j = i + 1; j < n; j++)
            if (outs[i] && outs[j] && tsio_same_file(outs[i], outs[j])) {
                tsio_errf(err, outs[j], "is also an output (%s): each output needs its own file",
                          outs[i]);
                return -1;
            }
    return 0;
}

/* A hillshade PNG; with f, its axes drawn over it.  The metrics are the
 * grid's, or for a CRS-less grid its pixel size. */
static int job_preview(ts_ctx *ctx, const char *path, const ts_raster *dem, const tsio_georef *geo,
                       const ts_grid_metrics *metrics, const ts_features *f, tsio_err *err)
{
    size_t n = (size_t)dem->width * (size_t)dem->height;
    unsigned char *rgb = malloc(3 * n);
    double *rowdx = NULL, *rowdy = NULL;
    ts_grid_metrics pm;
    ts_status st;
    int y, rc;
    if (!metrics && geo->has_gt) {
        rowdx = malloc((size_t)dem->height * sizeof *rowdx);
        rowdy = malloc((size_t)dem->height * sizeof *rowdy);
        if (rowdx && rowdy) {
            for (y = 0; y < dem->height; y++) {
                rowdx[y] = fabs(geo->gt[1]);
                rowdy[y] = fabs(geo->gt[5]);
            }
            pm.dx = rowdx;
            pm.dy = rowdy;
            metrics = &pm;
        }
    }
    st = rgb ? ts_render_preview(ctx, dem, metrics, f, rgb) : TS_ERR_NOMEM;
    free(rowdx);
    free(rowdy);
    if (st != TS_OK) {
        tsio_errf(err, path, "%s", rgb ? ts_ctx_message(ctx) : "out of memory");
        free(rgb);
        return -1;
    }
    rc = tsio_write_png_rgb(path, dem->width, dem->height, rgb, err);
    free(rgb);
    return rc;
}

int tsjob_ppa_check_outputs(const tsjob_ppa *job, const tsjob_ppa_result *res,
                            const tsjob_outputs *o, tsio_err *err)
{
    const char *in[1] = {job->input};
    unsigned char probe = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    const char *outs[3] = {o->output, o->lines, o->preview};
    if (res->tile_size > 0 && (o->lines || o->preview)) {
        tsio_errf(err, job->input,
                  "mapped in tiles of %d cells (%s): lines and preview need the whole DEM in "
                  "memory; give neither",
                  res->tile_size,
                  res->auto_tiles ? "too large for memory in one piece" : "as asked");
        return -1;
    }
    if (job_not_an_input(o->output, in, 1, err) || job_not_an_input(o->lines, in, 1, err) ||
        job_not_an_input(o->preview, in, 1, err) || job_distinct(outs, 3, err))
        return -1;
    if (tsio_write_byte(o->output, &wo, &res->in.geo, &probe, 255, err) != 0 ||
        (o->lines && tsio_check_vector_output(o->lines, err) != 0) ||
        (o->preview && tsio_write_byte(o->preview, &png, &res->in.geo, &probe, -1, err) != 0))
        return -1;
    return 0;
}

/* The tiled PPA: windows read from the open DEM, tiles into the output. */
typedef struct ppa_tiles_io {
    const tsjob_ppa_result *res;
    tsio_window_sink_fn sink;
    void *sink_arg;
    tsio_err *err;
    int failed; /* err holds the reason */
    size_t n_valid, n_sentinels;
} ppa_tiles_io;

static ts_status ppa_tile_read(void *user, int x0, int y0, int w, int h, float *buf)
{
    ppa_tiles_io *io = user;
    if (tsio_dem_window(io->res->reader, x0, y0, w, h, buf, &io->n_valid, &io->n_sentinels,
                        io->err) != 0) {
        io->failed = 1;
        return TS_ERR_NUMERIC;
    }
    return TS_OK;
}

static ts_status ppa_tile_write(void *user, int x0, int y0, int w, int h,
                                const unsigned char *bytes)
{
    ppa_tiles_io *io = user;
    if (io->sink(io->sink_arg, x0, y0, w, h, bytes) != 0) {
        io->failed = 1;
        return TS_ERR_NUMERIC;
    }
    return TS_OK;
}

static int ppa_tiles_produce(void *user, tsio_window_sink_fn sink, void *sink_arg, tsio_err *err)
{
    ppa_tiles_io io;
    const tsjob_ppa_result *res = user;
    memset(&io, 0, sizeof io);
    io.res = res;
    io.sink = sink;
    io.sink_arg = sink_arg;
    io.err = err;
    if (ts_ppa_extract_tiled(res->ctx, res->in.geo.width, res->in.geo.height, res->metrics,
                             &res->params, res->tile_size, ppa_tile_read, ppa_tile_write, &io,
                             &((tsjob_ppa_result *)(uintptr_t)res)->tiled) != TS_OK) {
        if (!io.failed)
            tsio_errf(err, res->input, "%s", ts_ctx_message(res->ctx));
        return -1;
    }
    return 0;
}

int tsjob_ppa_write(ts_ctx *ctx, const tsjob_ppa_result *res, const tsjob_outputs *o, tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    if (res->tile_size > 0)
        return tsio_write_byte_windows(o->output, &wo, &res->in.geo, 255, ppa_tiles_produce,
                                       (void *)(uintptr_t)res, err);
    if (tsio_write_byte(o->output, &wo, &res->in.geo, res->codes, 255, err) != 0)
        return -1;
    if (o->lines &&
        tsio_write_features(o->lines, &res->in.geo, res->features, res->metrics, err) != 0)
        return -1;
    if (o->preview && job_preview(ctx, o->preview, &res->in.r, &res->in.geo, res->metrics,
                                  res->features, err) != 0)
        return -1;
    return 0;
}

int tsjob_ppa_check_recipe(const tsjob_ppa *job, const char *recipe, tsio_err *err)
{
    const char *in[1] = {job->input};
    return job_not_an_input(recipe, in, 1, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}

/* Every file a synth job reads. */
static int job_synth_inputs(const tsjob_synth *job, const char **in)
{
    int n = 0, i;
    for (i = 0; i < job->n_exemplars; i++)
        in[n++] = job->exemplars[i];
    in[n++] = job->sketch;
    in[n++] = job->grid.like;
    in[n++] = job->water;
    in[n++] = job->regions;
    in[n++] = job->heights;
    for (i = 0; i < job->n_pins; i++)
        in[n++] = job->pins[i].path;
    return n;
}

#define JOB_MAX_INPUTS (TSJOB_MAX_EXEMPLARS + TSJOB_MAX_PINS + 5)

int tsjob_synth_check_recipe(const tsjob_synth *job, const char *recipe, tsio_err *err)
{
    const char *in[JOB_MAX_INPUTS];
    int n = job_synth_inputs(job, in);
    return job_not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}

/* The names of the debug maps (debug_dir/<name>.tif, the driver's MAP). */
const char *const tsjob_map_names[TSJOB_N_MAPS] = {"seams", "source_exemplar", "source_x",
                                                   "source_y", "order"};

const int32_t *tsjob_synth_int_map(const tsjob_synth_result *res, int map)
{
    if (!res->has_maps)
        return NULL;
    switch (map) {
    case TSJOB_MAP_SOURCE_EXEMPLAR:
        return res->maps.source_exemplar;
    case TSJOB_MAP_SOURCE_X:
        return res->maps.source_x;
    case TSJOB_MAP_SOURCE_Y:
        return res->maps.source_y;
    case TSJOB_MAP_ORDER:
        return res->maps.order;
    default:
        return NULL;
    }
}

int tsjob_synth_check_outputs(const tsjob_synth *job, const tsjob_synth_result *res,
                              const tsjob_outputs *o, tsio_err *err)
{
    const char *in[JOB_MAX_INPUTS];
    int n = job_synth_inputs(job, in), i;
    float probe = 0;
    ts_raster pr = ts_raster_wrap(&probe, 1, 1, 1);
    unsigned char bp = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    tsio_georef g1 = res->geo;
    g1.width = g1.height = 1;
    if (job_not_an_input(o->output, in, n, err) || job_not_an_input(o->preview, in, n, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, -9999.0, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0))
        return -1;
    if (o->debug_dir) {
        char paths[TSJOB_N_MAPS + 2][4096];
        const char *outs[TSJOB_N_MAPS + 4];
        int k = 0;
        outs[k++] = o->output;
        outs[k++] = o->preview;
        if (tsio_make_dir(o->debug_dir, err) != 0)
            return -1;
        for (i = 0; i < TSJOB_N_MAPS + 2; i++) {
            const char *name = i < TSJOB_N_MAPS    ? tsjob_map_names[i]
                               : i == TSJOB_N_MAPS ? "sketch_features"
                                                   : "output_features";
            if (i >= TSJOB_N_MAPS && !job->sketch)
                break;
            if (tsio_path(paths[i], sizeof paths[i], o->debug_dir, name,
                          i < TSJOB_N_MAPS ? "tif" : "gpkg", err) != 0 ||
                job_not_an_input(paths[i], in, n, err) != 0)
                return -1;
            outs[k++] = paths[i];
        }
        if (job_distinct(outs, k, err) != 0)
            return -1;
        for (i = 2; i < k; i++)
            if (tsio_check_output_file(outs[i], err) != 0)
                return -1;
    } else {
        const char *outs[2] = {o->output, o->preview};
        if (job_distinct(outs, 2, err) != 0)
            return -1;
    }
    return 0;
}

/* Write one int map as Float32 with nodata -1. */
static int job_int_map(const char *dir, const char *name, const tsio_georef *geo, const int32_t *v,
                       float *tmp, tsio_err *err)
{
    char path[4096];
    size_t i, n = (size_t)geo->width * (size_t)geo->height;
    ts_raster r = ts_raster_wrap(tmp, geo->width, geo->height, geo->width);
    if (tsio_path(path, sizeof path, dir, name, "tif", err) != 0)
        return -1;
    for (i = 0; i < n; i++)
        tmp[i] = v[i] < 0 ? NAN : (float)v[i];
    return tsio_write_float(path, NULL, geo, &r, -1.0, err);
}

/* With a sketch: its feature graph and the output's PPA axes as lines. */
static int job_debug_features(ts_ctx *ctx, const char *dir, const tsjob_synth_result *res,
                              tsio_err *err)
{
    ts_ppa_params pp = ts_ppa_params_default();
    ts_features *of = NULL;
    pp.min_drainage = 0; /* the axes as the synthesis sees them: by profile */
    char a[4096], b[4096];
    int rc = -1;
    if (tsio_path(a, sizeof a, dir, "sketch_features", "gpkg", err) != 0 ||
        tsio_path(b, sizeof b, dir, "output_features", "gpkg", err) != 0)
        return -1;
    pp.features = res->sketch_info.mode == TS_SKETCH_BOTH      ? TS_PPA_BOTH
                  : res->sketch_info.mode == TS_SKETCH_VALLEYS ? TS_PPA_VALLEYS
                                                               : TS_PPA_RIDGES;
    if (res->sketch_features &&
        tsio_write_features(a, &res->geo, res->sketch_features, NULL, err) != 0)
        goto out;
    if (ts_ppa_extract(ctx, &res->out, res->metrics, &pp, &of) != TS_OK) {
        tsio_errf(err, b, "%s", ts_ctx_message(ctx));
        goto out;
    }
    if (tsio_write_features(b, &res->geo, of, res->metrics, err) != 0)
        goto out;
    rc = 0;
out:
    ts_features_free(of);
    return rc;
}

int tsjob_synth_write(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                      const tsjob_outputs *o, tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, -9999.0, err) != 0)
        return -1;
    if (o->preview &&
        job_preview(ctx, o->preview, &res->out, &res->geo, res->metrics, NULL, err) != 0)
        return -1;
    if (o->debug_dir && res->has_maps) {
        const ts_synth_maps *m = &res->maps;
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
        float *tmp = malloc(n * sizeof *tmp);
        char path[4096];
        int bad;
        if (!tmp) {
            tsio_errf(err, o->debug_dir, "out of memory");
            return -1;
        }
        int i;
        bad = tsio_path(path, sizeof path, o->debug_dir, tsjob_map_names[TSJOB_MAP_SEAMS], "tif",
                        err) != 0 ||
              tsio_write_byte(path, NULL, &res->geo, m->seams, -1, err) != 0;
        for (i = TSJOB_MAP_SOURCE_EXEMPLAR; i < TSJOB_N_MAPS && !bad; i++)
            bad = job_int_map(o->debug_dir, tsjob_map_names[i], &res->geo,
                              tsjob_synth_int_map(res, i), tmp, err) != 0;
        free(tmp);
        if (bad)
            return -1;
        if (job->sketch && job_debug_features(ctx, o->debug_dir, res, err) != 0)
            return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* amplify                                                             */
/* ------------------------------------------------------------------ */

/* Several core calls in one job: each reports on [lo, hi] of the job's progress. */
typedef struct job_progress {
    ts_progress_fn fn;
    void *user;
    double lo, hi;
} job_progress;

static int job_progress_cb(double done, const char *msg, void *user)
{
    job_progress *p = user;
    return p->fn ? p->fn(p->lo + (p->hi - p->lo) * done, msg, p->user) : 1; /* 1: go on */
}

static void job_progress_range(ts_ctx *ctx, job_progress *p, double lo, double hi)
{
    p->lo = lo;
    p->hi = hi;
    ts_ctx_set_progress(ctx, job_progress_cb, p);
}

/* Every cell of a class raster a code 1..TS_MAX_CLASSES, 0 or nodata. */
static int job_check_class_codes(const char *path, const ts_raster *r, tsio_err *err)
{
    int x, y;
    for (y = 0; y < r->height; y++)
        for (x = 0; x < r->width; x++) {
            float v = TS_PIX(r, x, y);
            if (!isnan(v) && v != 0.0f &&
                !(v >= 1.0f && v <= (float)TS_MAX_CLASSES && v == floorf(v))) {
                tsio_errf(err, path,
                          "%g at column %d, row %d is not a class code 1..%d (0 or nodata: "
                          "unlabelled)",
                          (double)v, x, y, TS_MAX_CLASSES);
                return -1;
            }
        }
    return 0;
}

int tsjob_amplify_prepare(const tsjob_amplify *job, tsjob_amplify_result *res, tsio_err *err)
{
    tsio_georef g;
    const ts_amplify_params *p = &job->params;
    uint64_t need, atoms_total = 0, biggest = 0, cells_out;
    double *dx = NULL, *dy = NULL, out_area = 0;
    int F = p->factor, i, rc;
    memset(res, 0, sizeof *res);
    if (tsio_read_georef(job->input, &g, err) != 0)
        return -1;
    cells_out = (uint64_t)g.width * F * (uint64_t)g.height * F;
    /* served window by window, the output is never whole in memory */
    need = JOB_MEM_BASE + (uint64_t)g.width * g.height * 48 + (job->lazy ? 0 : cells_out * 8);
    /* the carried layers and classes on the output (at most every layer a dictionary holds) */
    if (!job->lazy && job->n_out_layers)
        need += cells_out * 4 * (uint64_t)(job->dictionary ? TS_MAX_LAYERS : job->n_layers);
    if (!job->lazy && job->want_classes)
        need += cells_out * 5;
    need += (uint64_t)g.width * g.height * 4 * (uint64_t)job->n_biomes; /* their weights */
    if (job->n_biomes > 1 && !job->lazy) /* a reconstruction per biome */
        need += cells_out * 4 * (uint64_t)job->n_biomes;
    /* the ground size of an output cell, to count the exemplars' cells at it */
    if (tsio_georef_metrics(&g, &dx, &dy, err) == 0 && dx)
        out_area = dx[g.height / 2] * dy[g.height / 2] / ((double)F * F);
    else if (job->cell_size > 0)
        out_area = job->cell_size * job->cell_size / ((double)F * F);
    free(dx);
    free(dy);
    /* before the warning on coarse exemplars, which a cell size taken wrongly causes */
    job_warn_cell_sizes(&res->warning, job->cell_size, job->input, &g,
                        (const char *const *)job->exemplars, job->n_exemplars);
    tsio_georef_free(&g);
    for (i = 0; i < job->n_exemplars; i++) {
        uint64_t src, tgt;
        double ratio;
        if (job_exemplar_cells(job->exemplars[i], out_area, job->cell_size, &src, &tgt, &ratio,
                               err) != 0)
            return -1;
        atoms_total += (uint64_t)p->atoms;
        need += src * 4 + tgt * 16; /* as read, and at the output's resolution */
        need += (src * 4 + tgt * 8) * (uint64_t)job->n_layers; /* its layers, read one by one */
        if (job->exemplar_classes[i])
            need += src * 4 + tgt * 8;
        if (src > biggest)
            biggest = src;
        if (ratio > 4.0 && !res->warning.msg[0])
            tsio_errf(&res->warning, job->exemplars[i],
                      "its cells are %.1f times the output's on the ground: its detail is "
                      "interpolated, not real (an exemplar at the output's resolution or finer "
                      "gives real detail)",
                      sqrt(ratio));
    }
    need += biggest * JOB_MEM_EX_SOURCE_CELL;
    need += atoms_total * ((uint64_t)p->patch * p->patch * ((uint64_t)F * F + 2) * 4 + 64);
    need += atoms_total * (uint64_t)p->patch * p->patch * (uint64_t)F * F *
            (4 * (uint64_t)job->n_layers + (job->exemplar_classes[0] ? 1 : 0));
    if (tsio_check_memory(need, "amplify",
                          "a smaller input, a smaller factor, fewer atoms or "
                          "exemplars nearer the output's resolution",
                          err) != 0)
        return -1;
    {
        tsio_err keep = res->warning;
        if (tsio_read_dem(job->input, job->band, &res->in, err) != 0)
            return -1;
        res->warning = keep;
    }
    job_warn_sentinels(&res->warning, job->input, &res->in);
    if (res->in.geo.width < p->patch || res->in.geo.height < p->patch) {
        tsio_errf(err, job->input, "%d x %d cells is smaller than a patch (%d cells)",
                  res->in.geo.width, res->in.geo.height, p->patch);
        tsjob_amplify_result_free(res);
        return -1;
    }
    rc = tsio_georef_make(res->in.geo.width * F, res->in.geo.height * F, res->in.geo.gt[0],
                          res->in.geo.gt[3], fabs(res->in.geo.gt[1]) / F,
                          fabs(res->in.geo.gt[5]) / F, res->in.geo.wkt, &res->geo, err);
    if (rc != 0) {
        tsjob_amplify_result_free(res);
        return -1;
    }
    res->geo.has_gt = res->in.geo.has_gt;
    if (p->w_l > 0 && !res->in.dx_m) {
        tsio_errf(err, job->input,
                  "has no CRS: the irradiance term (w_l) needs each cell's latitude");
        tsjob_amplify_result_free(res);
        return -1;
    }
    if (job->classes) {
        if (tsio_read_raster(job->classes, 1, &res->classes, err) != 0) {
            tsjob_amplify_result_free(res);
            return -1;
        }
        if (res->classes.geo.width != res->in.geo.width ||
            res->classes.geo.height != res->in.geo.height) {
            tsio_errf(err, job->classes, "the classes are %d x %d cells, the input %d x %d",
                      res->classes.geo.width, res->classes.geo.height, res->in.geo.width,
                      res->in.geo.height);
            tsjob_amplify_result_free(res);
            return -1;
        }
        if (job_check_class_codes(job->classes, &res->classes.r, err) != 0) {
            tsjob_amplify_result_free(res);
            return -1;
        }
    }
    return 0;
}

/* A dictionary file: "TSDFILE1", f64 metres per output cell (little-endian), then the
 * core's bytes (ts_dictionary_to_bytes). */
#define DICT_FILE_MAGIC "TSDFILE1"
#define DICT_FILE_HEAD 16

int tsjob_dictionary_read(ts_ctx *ctx, const char *path, ts_dictionary **dict, double *resolution,
                          tsio_err *err)
{
    unsigned char *b = NULL;
    size_t len = 0;
    uint64_t bits = 0, limit;
    int k, from_option, rc = -1;
    *dict = NULL;
    /* the file and its dictionary both in memory, at most */
    if (tsio_memory_limit(&limit, &from_option, err) != 0)
        return -1;
    if (tsio_read_bytes(path, (size_t)(limit / 2), &b, &len, err) != 0)
        return -1;
    if (len < DICT_FILE_HEAD || memcmp(b, DICT_FILE_MAGIC, 8) != 0) {
        tsio_errf(err, path, "not a TerraSynth dictionary (made by terrasynth dictionary build)");
        goto done;
    }
    for (k = 7; k >= 0; k--)
        bits = bits << 8 | b[8 + k];
    memcpy(resolution, &bits, 8);
    if (!(*resolution > 0) || *resolution > 1e7) {
        tsio_errf(err, path, "damaged: no usable resolution");
        goto done;
    }
    if (ts_dictionary_from_bytes(ctx, b + DICT_FILE_HEAD, len - DICT_FILE_HEAD, dict) != TS_OK) {
        tsio_errf(err, path, "%s", ts_ctx_message(ctx));
        goto done;
    }
    rc = 0;
done:
    free(b);
    return rc;
}

int tsjob_amplify_adopt_dictionary(tsjob_amplify *job, tsio_err *err)
{
    unsigned char h[DICT_FILE_HEAD + 24];
    int got, factor, patch, b, n = job->n_biomes ? job->n_biomes : 1;
    int shape_given = job->shape_given;
    if (!job->dictionary && !job->n_biomes)
        return 0;
    for (b = 0; b < n; b++) {
        const char *path = job->n_biomes ? job->biome_dicts[b] : job->dictionary;
        got = tsio_read_head(path, h, sizeof h, err);
        if (got < 0)
            return -1;
        if (got < (int)sizeof h || memcmp(h, DICT_FILE_MAGIC, 8) != 0 ||
            memcmp(h + DICT_FILE_HEAD, "TSDICT\r\n", 8) != 0) {
            tsio_errf(err, path,
                      "not a TerraSynth dictionary (made by terrasynth dictionary build)");
            return -1;
        }
        factor = h[DICT_FILE_HEAD + 12] | h[DICT_FILE_HEAD + 13] << 8;
        patch = h[DICT_FILE_HEAD + 16] | h[DICT_FILE_HEAD + 17] << 8;
        if (shape_given && (factor != job->params.factor || patch != job->params.patch)) {
            tsio_errf(err, path,
                      "was built for factor %d and patch %d, not %d and %d: give %s, or "
                      "build another",
                      factor, patch, job->params.factor, job->params.patch,
                      b ? "dictionaries of one factor and patch" : "neither");
            return -1;
        }
        job->params.factor = factor;
        job->params.patch = patch;
        shape_given = 1; /* the other biomes' must be the same */
    }
    return 0;
}

/* Is `layer` on the grid of `exemplar` (as the files are, before any resampling)? */
static int job_same_grid(const char *layer, const char *exemplar, tsio_err *err)
{
    tsio_georef a, b;
    int same, k;
    if (tsio_read_georef(layer, &a, err) != 0)
        return -1;
    if (tsio_read_georef(exemplar, &b, err) != 0) {
        tsio_georef_free(&a);
        return -1;
    }
    same = a.width == b.width && a.height == b.height && a.has_gt == b.has_gt;
    for (k = 0; k < 6 && same; k++)
        same = fabs(a.gt[k] - b.gt[k]) <= 1e-9 * (fabs(b.gt[k]) + fabs(b.gt[1]) + 1e-300);
    if (!same)
        tsio_errf(err, layer, "is not on the grid of its exemplar %s (%d x %d cells)", exemplar,
                  b.width, b.height);
    tsio_georef_free(&a);
    tsio_georef_free(&b);
    return same ? 0 : -1;
}

/* One exemplar with everything the dictionary takes from it. */
typedef struct job_exemplar {
    tsio_raster dem, classes, layers[TS_MAX_LAYERS];
    ts_raster layer_views[TS_MAX_LAYERS], lat, north;
} job_exemplar;

static void job_exemplar_free(job_exemplar *e)
{
    int l;
    tsio_raster_free(&e->dem);
    tsio_raster_free(&e->classes);
    for (l = 0; l < TS_MAX_LAYERS; l++)
        tsio_raster_free(&e->layers[l]);
    ts_raster_free(&e->lat);
    ts_raster_free(&e->north);
}

/* Exemplar i of the job read at dx x dy metres per cell (0: as it is), its
 * layers and classes on the same cells, and with the irradiance term its
 * latitude and north on the grid the dictionary averages it to. */
static int job_read_exemplar(ts_ctx *ctx, const tsjob_amplify *job, int i, double dx, double dy,
                             job_exemplar *je, ts_exemplar *te, tsio_err *err)
{
    const char *path = job->exemplars[i];
    int l, F = job->params.factor;
    double f = 1.0;
    memset(te, 0, sizeof *te);
    if (tsio_read_raster_resampled(path, job->band, dx, dy, job->cell_size, &je->dem, &f, err) != 0)
        return -1;
    te->dem = je->dem.r;
    if (je->dem.dx_m) {
        te->dx = je->dem.dx_m[je->dem.geo.height / 2];
        te->dy = je->dem.dy_m[je->dem.geo.height / 2];
    }
    for (l = 0; l < job->n_layers; l++) {
        const char *lp = job->layer_files[i][l];
        if (job_same_grid(lp, path, err) != 0 ||
            tsio_read_raster_resampled(lp, 1, dx, dy, job->cell_size, &je->layers[l], &f, err) != 0)
            return -1;
        if (je->layers[l].geo.width != je->dem.geo.width ||
            je->layers[l].geo.height != je->dem.geo.height) {
            tsio_errf(err, lp, "is not on the grid of its exemplar %s", path);
            return -1;
        }
        je->layer_views[l] = je->layers[l].r;
    }
    if (job->n_layers)
        te->layers = je->layer_views;
    if (job->exemplar_classes[i]) {
        const char *cp = job->exemplar_classes[i];
        if (job_same_grid(cp, path, err) != 0 ||
            tsio_read_classes_resampled(cp, 1, dx, dy, job->cell_size, &je->classes, err) != 0)
            return -1;
        if (je->classes.geo.width != je->dem.geo.width ||
            je->classes.geo.height != je->dem.geo.height) {
            tsio_errf(err, cp, "is not on the grid of its exemplar %s", path);
            return -1;
        }
        if (job_check_class_codes(cp, &je->classes.r, err) != 0)
            return -1;
        te->classes = &je->classes.r;
    }
    if (job->params.w_l > 0 && je->dem.dx_m) {
        int lw = je->dem.geo.width / F, lh = je->dem.geo.height / F, rc;
        if (lw < 1 || lh < 1)
            return 0; /* too small: the core says so */
        if (ts_raster_alloc(ctx, lw, lh, &je->lat) != TS_OK ||
            ts_raster_alloc(ctx, lw, lh, &je->north) != TS_OK) {
            tsio_errf(err, path, "%s", ts_ctx_message(ctx));
            return -1;
        }
        rc = tsio_georef_sun_frame(&je->dem.geo, F, &je->lat, &je->north, err);
        if (rc < 0) {
            tsio_errf(err, path, "%s", err->msg);
            return -1;
        }
        if (rc == 0) {
            te->lat = &je->lat;
            te->north = &je->north;
        }
    }
    return 0;
}

/* The exemplars read at dx x dy metres per cell (0: as they are), and the
 * dictionary built from them.  With `warning`, sentinel cells are reported
 * there and *no_crs gets the index+1 of an exemplar used cell for cell. */
static int job_build_dictionary(ts_ctx *ctx, const tsjob_amplify *job, double dx, double dy,
                                const char *what, ts_dictionary **dict, tsio_err *warning,
                                int *no_crs, double *seconds, tsio_err *err)
{
    job_exemplar *ex = calloc(TSJOB_MAX_EXEMPLARS, sizeof *ex);
    ts_exemplar te[TSJOB_MAX_EXEMPLARS];
    const char *names[TS_MAX_LAYERS];
    struct timespec t0, t1;
    int i, rc = -1;
    if (!ex) {
        tsio_errf(err, what, "out of memory");
        return -1;
    }
    for (i = 0; i < job->n_layers; i++)
        names[i] = job->layer_names[i];
    for (i = 0; i < job->n_exemplars; i++) {
        if (job_read_exemplar(ctx, job, i, dx, dy, &ex[i], &te[i], err) != 0)
            goto done;
        if (warning)
            job_warn_sentinels(warning, job->exemplars[i], &ex[i].dem);
        if (no_crs && dx > 0 && !ex[i].dem.dx_m && !*no_crs)
            *no_crs = i + 1;
    }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    if (ts_dictionary_build(ctx, te, job->n_exemplars, names, job->n_layers, &job->params, dict) !=
        TS_OK) {
        int bad = ts_ctx_failed_input(ctx);
        tsio_errf(err, bad >= 0 && bad < job->n_exemplars ? job->exemplars[bad] : what, "%s",
                  ts_ctx_message(ctx));
        goto done;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    if (seconds)
        *seconds = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    rc = 0;
done:
    for (i = 0; i < job->n_exemplars; i++)
        job_exemplar_free(&ex[i]);
    free(ex);
    return rc;
}

/* Every file an amplify (or dictionary) job reads; returns the count. */
#define JOB_AMP_MAX_INPUTS (TSJOB_MAX_EXEMPLARS * (2 + TS_MAX_LAYERS) + 2 * TSJOB_MAX_BIOMES + 3)
static int job_amplify_inputs(const tsjob_amplify *job, const char **in)
{
    int n = 0, i, l;
    in[n++] = job->input;
    in[n++] = job->dictionary;
    in[n++] = job->classes;
    for (i = 0; i < job->n_biomes; i++) {
        in[n++] = job->biome_dicts[i];
        in[n++] = job->biome_weights[i];
    }
    for (i = 0; i < job->n_exemplars; i++) {
        in[n++] = job->exemplars[i];
        in[n++] = job->exemplar_classes[i];
        for (l = 0; l < job->n_layers; l++)
            in[n++] = job->layer_files[i][l];
    }
    return n;
}

int tsjob_dictionary_build(ts_ctx *ctx, const tsjob_amplify *job, const char *path, size_t *n_atoms,
                           tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS];
    int n = job_amplify_inputs(job, in), k, rc = -1;
    ts_dictionary *dict = NULL;
    unsigned char head[DICT_FILE_HEAD], *bytes = NULL;
    size_t len = 0;
    uint64_t bits;
    /* the destination, before the work */
    if (job_not_an_input(path, in, n, err) || tsio_write_bytes(path, NULL, 0, NULL, 0, 1, err) != 0)
        return -1;
    if (job_build_dictionary(ctx, job, job->resolution, job->resolution, "dictionary", &dict, NULL,
                             NULL, NULL, err) != 0)
        goto done;
    if (ts_dictionary_to_bytes(ctx, dict, &bytes, &len) != TS_OK) {
        tsio_errf(err, path, "%s", ts_ctx_message(ctx));
        goto done;
    }
    memcpy(head, DICT_FILE_MAGIC, 8);
    memcpy(&bits, &job->resolution, 8);
    for (k = 0; k < 8; k++)
        head[8 + k] = (unsigned char)(bits >> (8 * k));
    if (tsio_write_bytes(path, head, sizeof head, bytes, len, 0, err) != 0)
        goto done;
    *n_atoms = ts_dictionary_size(dict);
    rc = 0;
done:
    free(bytes);
    ts_dictionary_free(dict);
    return rc;
}

/* After the dictionary: the input's irradiance (with w_l), the layers and
 * classes asked for found in the dictionary. */
static int job_amplify_frame(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                             tsio_err *err)
{
    int L, K, has_l, i, l;
    ts_dictionary_layers(res->dict, &L, &K, &has_l);
    if (job->params.w_l > 0) {
        ts_raster lat = {0, 0, 0, NULL}, north = {0, 0, 0, NULL};
        ts_grid_metrics m;
        int rc = -1;
        if (!has_l) {
            tsio_errf(err, job->dictionary ? job->dictionary : job->input,
                      "the dictionary was built without the irradiance: build it with w_l > 0");
            return -1;
        }
        if (ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &lat) != TS_OK ||
            ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &north) != TS_OK ||
            ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &res->irr) != TS_OK)
            tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        else if (tsio_georef_sun_frame(&res->in.geo, 1, &lat, &north, err) != 0)
            tsio_errf(err, job->input, "%s", err->msg[0] ? err->msg : "has no CRS: no latitude");
        else if (ts_irradiance(ctx, &res->in.r, tsio_metrics(&res->in, &m), &lat, &north,
                               &res->irr) != TS_OK)
            tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        else
            rc = 0;
        ts_raster_free(&lat);
        ts_raster_free(&north);
        if (rc != 0)
            return -1;
    }
    for (i = 0; i < job->n_out_layers; i++) {
        for (l = 0; l < L; l++)
            if (!strcmp(ts_dictionary_layer_name(res->dict, l), job->out_layer_names[i]))
                break;
        if (l == L) {
            char have[TS_MAX_LAYERS * (TS_LAYER_NAME + 2) + 8] = "";
            for (l = 0; l < L; l++)
                snprintf(have + strlen(have), sizeof have - strlen(have), "%s%s", l ? ", " : "",
                         ts_dictionary_layer_name(res->dict, l));
            tsio_errf(err, job->dictionary ? job->dictionary : job->exemplars[0],
                      "out_layer %s: the atoms carry no layer %s (they carry: %s)",
                      job->out_layer_names[i], job->out_layer_names[i], L ? have : "none");
            return -1;
        }
        res->layer_of[i] = l;
    }
    if (job->want_classes && K == 0) {
        tsio_errf(err, job->dictionary ? job->dictionary : job->exemplars[0],
                  "out_classes: the atoms have no classes (give exemplar_classes)");
        return -1;
    }
    if (job->classes && K == 0) {
        tsio_errf(err, job->classes,
                  "wanted classes, but the atoms have none (give exemplar_classes)");
        return -1;
    }
    return 0;
}

int tsjob_amplify_setup(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                        tsio_err *err)
{
    int cy = res->in.geo.height / 2, F = job->params.factor;
    double in_dx = res->in.dx_m ? res->in.dx_m[cy] : job->cell_size;
    double in_dy = res->in.dy_m ? res->in.dy_m[cy] : job->cell_size;
    if (job->n_biomes) {
        int b;
        for (b = 0; b < job->n_biomes; b++) {
            double dres;
            if (tsjob_dictionary_read(ctx, job->biome_dicts[b], &res->biome_dicts[b], &dres, err) !=
                0)
                return -1;
            if (in_dx > 0 && fabs(sqrt(in_dx * in_dy) / F / dres - 1.0) > 0.02) {
                tsio_errf(err, job->biome_dicts[b],
                          "was built for cells of %.6g m; this input at factor %d gives cells "
                          "of %.6g m: build one for them (terrasynth dictionary build "
                          "--resolution)",
                          dres, F, sqrt(in_dx * in_dy) / F);
                return -1;
            }
            res->n_atoms += ts_dictionary_size(res->biome_dicts[b]);
            if (tsio_read_raster(job->biome_weights[b], 1, &res->biome_w[b], err) != 0)
                return -1;
            if (res->biome_w[b].geo.width != res->in.geo.width ||
                res->biome_w[b].geo.height != res->in.geo.height) {
                tsio_errf(err, job->biome_weights[b],
                          "the weights are %d x %d cells, the input %d x %d",
                          res->biome_w[b].geo.width, res->biome_w[b].geo.height, res->in.geo.width,
                          res->in.geo.height);
                return -1;
            }
            {
                size_t k, n = (size_t)res->in.geo.width * (size_t)res->in.geo.height;
                for (k = 0; k < n; k++) /* nodata: no weight */
                    if (isnan(res->biome_w[b].r.data[k]))
                        res->biome_w[b].r.data[k] = 0.0f;
            }
        }
        res->dict = res->biome_dicts[0];
        goto drainage;
    }
    if (job->dictionary) {
        double dres;
        if (tsjob_dictionary_read(ctx, job->dictionary, &res->dict, &dres, err) != 0)
            return -1;
        if (in_dx > 0 && fabs(sqrt(in_dx * in_dy) / F / dres - 1.0) > 0.02) {
            tsio_errf(err, job->dictionary,
                      "was built for cells of %.6g m; this input at factor %d gives cells of "
                      "%.6g m: build one for them (terrasynth dictionary build --resolution)",
                      dres, F, sqrt(in_dx * in_dy) / F);
            return -1;
        }
        res->n_atoms = ts_dictionary_size(res->dict);
        goto drainage;
    }
    if (job_build_dictionary(ctx, job, in_dx > 0 ? in_dx / F : 0, in_dy > 0 ? in_dy / F : 0,
                             "amplify", &res->dict, &res->warning, &res->exemplar_no_crs,
                             &res->seconds_dictionary, err) != 0)
        return -1;
    res->n_atoms = ts_dictionary_size(res->dict);
    if (res->n_atoms < 256 && !res->warning.msg[0])
        tsio_errf(&res->warning, job->exemplars[0],
                  "only %zu atoms: the exemplars cover little ground at the output's resolution "
                  "(%.3g m), so their patterns repeat; give larger exemplars",
                  res->n_atoms, in_dx > 0 ? in_dx / F : 0.0);
drainage:
    if (ts_raster_alloc(ctx, res->in.r.width, res->in.r.height, &res->drain) != TS_OK ||
        ts_drainage_area(ctx, &res->in.r, &res->drain) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        return -1;
    }
    return job_amplify_frame(ctx, job, res, err);
}

static ts_amplify_guide job_amplify_guide(const tsjob_amplify *job, const tsjob_amplify_result *res)
{
    ts_amplify_guide g;
    g.drainage = &res->drain;
    g.irradiance = job->params.w_l > 0 ? &res->irr : NULL;
    g.classes = res->classes.r.data ? &res->classes.r : NULL;
    return g;
}

/* The biomes' amplification of the window at x0, y0 (NaN in weights: 0). */
static ts_status job_amplify_biomes(ts_ctx *ctx, const tsjob_amplify *job,
                                    const tsjob_amplify_result *res, int x0, int y0, ts_raster *out,
                                    ts_amplify_info *info)
{
    ts_raster w[TSJOB_MAX_BIOMES];
    const ts_dictionary *d[TSJOB_MAX_BIOMES];
    ts_amplify_guide g = job_amplify_guide(job, res);
    int b;
    for (b = 0; b < job->n_biomes; b++) {
        w[b] = res->biome_w[b].r;
        d[b] = res->biome_dicts[b];
    }
    return ts_amplify_biomes(ctx, &res->in.r, &g, d, w, job->n_biomes, &job->params, x0, y0, out,
                             info);
}

int tsjob_amplify_window(ts_ctx *ctx, const tsjob_amplify *job, const tsjob_amplify_result *res,
                         int x0, int y0, int w, int h, int serve, float *out, tsio_err *err)
{
    ts_raster o = ts_raster_wrap(out, w, h, w), dem = {0, 0, 0, NULL}, cls = {0, 0, 0, NULL};
    ts_raster layers[TS_MAX_LAYERS];
    ts_amplify_guide g = job_amplify_guide(job, res);
    ts_amplify_layers lay = {NULL, NULL};
    int L = 0, l, rc = -1;
    memset(layers, 0, sizeof layers);
    if (serve != TSJOB_SERVE_DEM) {
        /* the DEM computed aside, the layers (every one the atoms carry) or classes kept */
        ts_dictionary_layers(res->dict, &L, NULL, NULL);
        if (ts_raster_alloc(ctx, w, h, &dem) != TS_OK)
            goto done;
        if (serve == TSJOB_SERVE_CLASSES) {
            cls = o;
            lay.classes = &cls;
        } else {
            for (l = 0; l < L; l++)
                if (l == res->layer_of[serve])
                    layers[l] = o;
                else if (ts_raster_alloc(ctx, w, h, &layers[l]) != TS_OK)
                    goto done;
            lay.layers = layers;
        }
    }
    if (job->n_biomes ? job_amplify_biomes(ctx, job, res, x0, y0, &o, NULL)
                      : ts_amplify_window(ctx, &res->in.r, &g, res->dict, &job->params, x0, y0,
                                          serve == TSJOB_SERVE_DEM ? &o : &dem, &lay, NULL))
        goto done;
    rc = 0;
done:
    if (rc != 0)
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
    ts_raster_free(&dem);
    for (l = 0; l < L; l++)
        if (serve < 0 || l != res->layer_of[serve])
            ts_raster_free(&layers[l]);
    return rc;
}

int tsjob_amplify_compute(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                          tsio_err *err)
{
    job_progress jp;
    ts_amplify_layers lay = {NULL, NULL};
    ts_amplify_guide g;
    int rc = -1;
    ts_ctx_get_progress(ctx, &jp.fn, &jp.user);
    job_progress_range(ctx, &jp, 0.0, 0.2);
    if (tsjob_amplify_setup(ctx, job, res, err) != 0)
        goto done;
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
        goto done;
    }
    if (job->n_out_layers) {
        int L, l;
        ts_dictionary_layers(res->dict, &L, NULL, NULL);
        for (l = 0; l < L; l++)
            if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->layers[l]) != TS_OK) {
                tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
                goto done;
            }
        lay.layers = res->layers;
    }
    if (job->want_classes) {
        if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out_classes) != TS_OK) {
            tsio_errf(err, "amplify", "%s", ts_ctx_message(ctx));
            goto done;
        }
        lay.classes = &res->out_classes;
    }
    g = job_amplify_guide(job, res);
    job_progress_range(ctx, &jp, 0.2, 1.0);
    if ((job->n_biomes ? job_amplify_biomes(ctx, job, res, 0, 0, &res->out, &res->info)
                       : ts_amplify_window(ctx, &res->in.r, &g, res->dict, &job->params, 0, 0,
                                           &res->out, &lay, &res->info)) != TS_OK) {
        tsio_errf(err, job->input, "%s", ts_ctx_message(ctx));
        goto done;
    }
    rc = 0;
done:
    ts_ctx_set_progress(ctx, jp.fn, jp.user);
    return rc;
}

void tsjob_amplify_result_free(tsjob_amplify_result *res)
{
    int l;
    for (l = 0; l < TS_MAX_LAYERS; l++)
        ts_raster_free(&res->layers[l]);
    ts_raster_free(&res->out_classes);
    ts_raster_free(&res->irr);
    tsio_raster_free(&res->classes);
    for (l = 0; l < TSJOB_MAX_BIOMES; l++) {
        if (res->biome_dicts[l] == res->dict)
            res->dict = NULL;
        ts_dictionary_free(res->biome_dicts[l]);
        tsio_raster_free(&res->biome_w[l]);
    }
    ts_dictionary_free(res->dict);
    ts_raster_free(&res->drain);
    tsio_raster_free(&res->in);
    tsio_georef_free(&res->geo);
    ts_raster_free(&res->out);
    memset(res, 0, sizeof *res);
}

int tsjob_amplify_check_recipe(const tsjob_amplify *job, const char *recipe, tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS];
    int n = job_amplify_inputs(job, in);
    return job_not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}

int tsjob_amplify_check_outputs(const tsjob_amplify *job, const tsjob_amplify_result *res,
                                const tsjob_outputs *o, tsio_err *err)
{
    const char *in[JOB_AMP_MAX_INPUTS],
        *outs[3 + TS_MAX_LAYERS] = {o->output, o->preview, o->out_classes};
    int n = job_amplify_inputs(job, in), n_out = 3, l;
    float probe = 0;
    ts_raster pr = ts_raster_wrap(&probe, 1, 1, 1);
    unsigned char bp = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    tsio_georef g1 = res->geo;
    g1.width = g1.height = 1;
    for (l = 0; o->out_layers && o->out_layers[l] && l < TS_MAX_LAYERS; l++)
        outs[n_out++] = strchr(o->out_layers[l], '=') + 1;
    for (l = 0; l < n_out; l++)
        if (job_not_an_input(outs[l], in, n, err))
            return -1;
    if (job_distinct(outs, n_out, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, -9999.0, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0) ||
        (o->out_classes && tsio_write_byte(o->out_classes, &wo, &g1, &bp, -1, err) != 0))
        return -1;
    for (l = 3; l < n_out; l++)
        if (tsio_write_float(outs[l], &wo, &g1, &pr, -9999.0, err) != 0)
            return -1;
    return 0;
}

int tsjob_amplify_write(ts_ctx *ctx, const tsjob_amplify_result *res, const tsjob_outputs *o,
                        tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    int l;
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, -9999.0, err) != 0)
        return -1;
    for (l = 0; o->out_layers && o->out_layers[l] && l < TS_MAX_LAYERS; l++)
        if (tsio_write_float(strchr(o->out_layers[l], '=') + 1, &wo, &res->geo,
                             &res->layers[res->layer_of[l]], -9999.0, err) != 0)
            return -1;
    if (o->out_classes) {
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height, k;
        unsigned char *b = malloc(n ? n : 1);
        int rc;
        if (!b) {
            tsio_errf(err, o->out_classes, "out of memory");
            return -1;
        }
        for (k = 0; k < n; k++)
            b[k] = (unsigned char)res->out_classes.data[k];
        rc = tsio_write_byte(o->out_classes, &wo, &res->geo, b, -1, err);
        free(b);
        if (rc != 0)
            return -1;
    }
    if (o->preview) {
        /* the hillshade on the ground: cell sizes in metres (a geographic grid's too) */
        double *dx = NULL, *dy = NULL;
        ts_grid_metrics m;
        int rc;
        if (tsio_georef_metrics(&res->geo, &dx, &dy, err) != 0)
            return -1;
        m.dx = dx;
        m.dy = dy;
        rc = job_preview(ctx, o->preview, &res->out, &res->geo, dx ? &m : NULL, NULL, err);
        free(dx);
        free(dy);
        if (rc != 0)
            return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* pixel                                                               */
/* ------------------------------------------------------------------ */

int tsjob_pixel_prepare(const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err)
{
    uint64_t need, cells, need_guide = 0;
    int i, L = job->params.levels ? job->params.levels : 10;
    int k = job->params.window ? job->params.window : 9;
    int dim = (job->params.pca_energy >= 1 ? 1 + k * k : (1 + k * k < 16 ? 1 + k * k : 16)) +
              (job->params.roughness_weight > 0); /* the roughness's value */
    double out_area = 0;
    memset(res, 0, sizeof *res);
    if (job->guide ? tsio_read_georef(job->guide, &res->geo, err) != 0 ||
                         job_grid_metrics(&res->geo, job->cell_size, &res->dx_m, &res->dy_m, err)
                   : job_target_grid(&job->grid, job->exemplars[0], job->cell_size, &res->geo,
                                     &res->dx_m, &res->dy_m, err) != 0) {
        tsjob_pixel_result_free(res);
        return -1;
    }
    job_warn_cell_sizes(&res->warning, job->cell_size, job->guide ? job->guide : job->grid.like,
                        &res->geo, (const char *const *)job->exemplars, job->n_exemplars);
    cells = (uint64_t)res->geo.width * (uint64_t)res->geo.height;
    if (job->guide) /* as read, and its stack */
        need_guide = cells * 4 * (uint64_t)(L + 3);
    /* the output (none when served window by window), the levels' coordinates over a
     * window with its margins, and each exemplar's stack at the grid's resolution */
    need = JOB_MEM_BASE + (job->lazy ? 0 : cells * 4) +
           (uint64_t)(job->lazy ? 300 * 300 : (cells < 4096 * 4096 ? cells : 4096 * 4096)) * 40 +
           need_guide;
    if (res->dx_m)
        out_area = res->dx_m[0] * res->dy_m[0];
    for (i = 0; i < job->n_exemplars; i++) {
        uint64_t src, tgt;
        if (job_exemplar_cells(job->exemplars[i], out_area, job->cell_size, &src, &tgt, NULL,
                               err) != 0) {
            tsjob_pixel_result_free(res);
            return -1;
        }
        /* per level and cell: the level, the usable mask and list, the appearance vector
         * (measured 4 to 13 floats at pca_energy 0.95 on ../shared/data/dem; 1 + k^2 at 1),
         * the similarity sets (coherence - 1 cells) */
        need += src * JOB_MEM_EX_SOURCE_CELL +
                tgt * (uint64_t)(L + 1) *
                    (9 + 4 * (uint64_t)dim + 4 * (uint64_t)(job->params.coherence - 1)) +
                /* the similarity sets' search: a level's points and kd-tree at a time */
                (job->params.coherence > 1 ? tgt * (4 * (uint64_t)dim + 20) : 0);
    }
    if (tsio_check_memory(need, "pixel", "a smaller grid, fewer levels or smaller exemplars",
                          err) != 0) {
        tsjob_pixel_result_free(res);
        return -1;
    }
    return 0;
}

int tsjob_pixel_setup(ts_ctx *ctx, const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err)
{
    tsio_raster ex[TSJOB_MAX_EXEMPLARS];
    ts_raster exr[TSJOB_MAX_EXEMPLARS];
    int i, rc = -1;
    /* the ground size of the grid's top row: a terrain whose cells do not depend on how far
     * the grid goes down (a geographic grid's cells shrink towards the pole) */
    double dx = res->dx_m ? res->dx_m[0] : 0, dy = res->dy_m ? res->dy_m[0] : 0;
    struct timespec t0, t1;
    memset(ex, 0, sizeof ex);
    for (i = 0; i < job->n_exemplars; i++) {
        double f = 1.0;
        if (tsio_read_raster_resampled(job->exemplars[i], job->band, dx, dy, job->cell_size, &ex[i],
                                       &f, err) != 0)
            goto done;
        job_warn_sentinels(&res->warning, job->exemplars[i], &ex[i]);
        if (dx > 0 && !ex[i].dx_m && !res->exemplar_no_crs)
            res->exemplar_no_crs = i + 1;
        exr[i] = ex[i].r;
    }
    clock_gettime(CLOCK_MONOTONIC, &t0);
    if (ts_pixel_prepare(ctx, exr, job->n_exemplars, &job->params, &res->stacks) != TS_OK) {
        int bad = ts_ctx_failed_input(ctx);
        tsio_errf(err, bad >= 0 && bad < job->n_exemplars ? job->exemplars[bad] : "pixel", "%s",
                  ts_ctx_message(ctx));
        goto done;
    }
    if (job->guide) {
        tsio_raster g;
        ts_status st;
        if (tsio_read_dem(job->guide, 1, &g, err) != 0)
            goto done;
        job_warn_sentinels(&res->warning, job->guide, &g);
        if (g.geo.width != res->geo.width || g.geo.height != res->geo.height) {
            tsio_errf(err, job->guide, "changed size since the job was prepared");
            tsio_raster_free(&g);
            goto done;
        }
        if (job->params.guide_heights == TS_GUIDE_AS_GIVEN && !res->warning.msg[0]) {
            /* a guide in other units (a grey-level sketch) is all but ignored: say so */
            double er[2], gr[2];
            if (ts_pixel_guide_ranges(&g.r, res->stacks, er, gr) == 0 &&
                (gr[1] < er[0] || gr[0] > er[1] ||
                 gr[1] - gr[0] < 0.1 * (er[1] - er[0])))
                tsio_errf(&res->warning, job->guide,
                          "its values (%.4g..%.4g, 1st..99th percentiles) are not on the "
                          "exemplars' heights (%.4g..%.4g): if it is a drawing, give "
                          "--guide-heights quantile",
                          gr[0], gr[1], er[0], er[1]);
        }
        st = ts_pixel_guide_prepare(ctx, &g.r, res->stacks, &job->params, &res->guide);
        tsio_raster_free(&g);
        if (st != TS_OK) {
            tsio_errf(err, job->guide, "%s", ts_ctx_message(ctx));
            goto done;
        }
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    res->seconds_stacks =
        (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    rc = 0;
done:
    for (i = 0; i < job->n_exemplars; i++)
        tsio_raster_free(&ex[i]);
    return rc;
}

int tsjob_pixel_window(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res, int x0,
                       int y0, int w, int h, float *out, tsio_err *err)
{
    ts_raster o = ts_raster_wrap(out, w, h, w);
    if ((res->guide
             ? ts_pixel_synthesize_guided(ctx, res->stacks, res->guide, &job->params, x0, y0, &o)
             : ts_pixel_synthesize(ctx, res->stacks, &job->params, x0, y0, &o)) != TS_OK) {
        tsio_errf(err, job->exemplars[0], "%s", ts_ctx_message(ctx));
        return -1;
    }
    return 0;
}

int tsjob_pixel_compute(ts_ctx *ctx, const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err)
{
    job_progress jp;
    struct timespec t0, t1;
    int rc = -1;
    ts_ctx_get_progress(ctx, &jp.fn, &jp.user);
    job_progress_range(ctx, &jp, 0.0, 0.1);
    if (tsjob_pixel_setup(ctx, job, res, err) != 0)
        goto done;
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        tsio_errf(err, "pixel", "%s", ts_ctx_message(ctx));
        goto done;
    }
    job_progress_range(ctx, &jp, 0.1, 1.0);
    clock_gettime(CLOCK_MONOTONIC, &t0);
    if (job->keep_sources) {
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
        ts_pixel_sources src;
        res->src_e = malloc(n * sizeof *res->src_e);
        res->src_x = malloc(n * sizeof *res->src_x);
        res->src_y = malloc(n * sizeof *res->src_y);
        if (!res->src_e || !res->src_x || !res->src_y) {
            tsio_errf(err, "pixel", "out of memory for the source maps");
            goto done;
        }
        src.exemplar = res->src_e;
        src.x = res->src_x;
        src.y = res->src_y;
        if (ts_pixel_synthesize_sources(ctx, res->stacks, res->guide, &job->params, 0, 0, &res->out,
                                        &src) != TS_OK) {
            tsio_errf(err, job->exemplars[0], "%s", ts_ctx_message(ctx));
            goto done;
        }
    } else if (tsjob_pixel_window(ctx, job, res, 0, 0, res->geo.width, res->geo.height,
                                  res->out.data, err) != 0)
        goto done;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    res->seconds_synthesis =
        (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    rc = 0;
done:
    ts_ctx_set_progress(ctx, jp.fn, jp.user);
    return rc;
}

void tsjob_pixel_result_free(tsjob_pixel_result *res)
{
    free(res->src_e);
    free(res->src_x);
    free(res->src_y);
    ts_pixel_guide_free(res->guide);
    ts_pixel_exemplars_free(res->stacks);
    tsio_georef_free(&res->geo);
    free(res->dx_m);
    free(res->dy_m);
    ts_raster_free(&res->out);
    memset(res, 0, sizeof *res);
}

/* Every file a pixel job reads; returns the count. */
static int job_pixel_inputs(const tsjob_pixel *job, const char **in)
{
    int n = 0, i;
    for (i = 0; i < job->n_exemplars; i++)
        in[n++] = job->exemplars[i];
    in[n++] = job->grid.like;
    in[n++] = job->guide;
    return n;
}

int tsjob_pixel_check_recipe(const tsjob_pixel *job, const char *recipe, tsio_err *err)
{
    const char *in[TSJOB_MAX_EXEMPLARS + 2];
    int n = job_pixel_inputs(job, in);
    return job_not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}

static const char *const pixel_map_names[3] = {"source_exemplar", "source_x", "source_y"};

int tsjob_pixel_check_outputs(const tsjob_pixel *job, const tsjob_pixel_result *res,
                              const tsjob_outputs *o, tsio_err *err)
{
    const char *in[TSJOB_MAX_EXEMPLARS + 2], *outs[2] = {o->output, o->preview};
    int n = job_pixel_inputs(job, in), i;
    float probe = 0;
    ts_raster pr = ts_raster_wrap(&probe, 1, 1, 1);
    unsigned char bp = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    tsio_georef g1 = res->geo;
    g1.width = g1.height = 1;
    if (job_not_an_input(o->output, in, n, err) || job_not_an_input(o->preview, in, n, err) ||
        job_distinct(outs, 2, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, -9999.0, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0))
        return -1;
    if (o->debug_dir) {
        char paths[3][4096];
        const char *all[5] = {o->output, o->preview, paths[0], paths[1], paths[2]};
        if (tsio_make_dir(o->debug_dir, err) != 0)
            return -1;
        for (i = 0; i < 3; i++)
            if (tsio_path(paths[i], sizeof paths[i], o->debug_dir, pixel_map_names[i], "tif",
                          err) != 0 ||
                job_not_an_input(paths[i], in, n, err) != 0 ||
                tsio_check_output_file(paths[i], err) != 0)
                return -1;
        if (job_distinct(all, 5, err) != 0)
            return -1;
    }
    return 0;
}

int tsjob_pixel_write(ts_ctx *ctx, const tsjob_pixel_result *res, const tsjob_outputs *o,
                      tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, -9999.0, err) != 0)
        return -1;
    if (o->debug_dir && res->src_e) {
        const int32_t *maps[3] = {res->src_e, res->src_x, res->src_y};
        float *tmp = malloc((size_t)res->geo.width * (size_t)res->geo.height * sizeof *tmp);
        int i, bad = !tmp;
        for (i = 0; i < 3 && !bad; i++)
            bad = job_int_map(o->debug_dir, pixel_map_names[i], &res->geo, maps[i], tmp, err);
        free(tmp);
        if (bad) {
            if (!tmp)
                tsio_errf(err, o->debug_dir, "out of memory");
            return -1;
        }
    }
    if (o->preview) {
        ts_grid_metrics m;
        m.dx = res->dx_m;
        m.dy = res->dy_m;
        if (job_preview(ctx, o->preview, &res->out, &res->geo, res->dx_m ? &m : NULL, NULL, err) !=
            0)
            return -1;
    }
    return 0;
}
