/*
 * job_synth.c - the synth job: the target grid, the exemplars, the constraints
 * (water, pins, regions, a sketch painted or drawn as lines), the synthesis in one
 * piece or in tiles.
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

#include <cpl_vsi.h>

#include "job_internal.h"

/* The row whose ground cell size the exemplars, pins and lengths in metres
 * take (on a geographic grid it varies by row): the middle row, or in tiles the
 * first tile row's middle, so a world in tiles is anchored at its origin and
 * keeps what it holds when it is made taller or wider. */
static int job_synth_ref_row(const tsjob_synth *job, const tsio_georef *geo)
{
    int T = job->params.tiled;
    if (T > 0)
        return T / 2 < geo->height ? T / 2 : geo->height - 1;
    return geo->height / 2;
}

/* The cells of an exemplar of tgt cells (taken square) at the level its
 * patches are matched on (ts_synth_match_level). */
static uint64_t job_synth_match_cells(const tsjob_synth_result *res, uint64_t tgt)
{
    double side = sqrt((double)tgt);
    int s = side < (double)INT_MAX ? (int)side : INT_MAX;
    int K =
        ts_synth_match_level(res->params.coarse_factor, (int)res->params.patch_size.value, s, s);
    return (tgt >> (2 * K)) + 1;
}

/* The whole job's memory against the limit, before any exemplar is read. */
static int job_synth_check_memory(const tsjob_synth *job, const tsjob_synth_result *res,
                                  tsio_err *err)
{
    uint64_t cells = (uint64_t)res->geo.width * (uint64_t)res->geo.height;
    uint64_t need = JOB_MEM_BASE, biggest = 0;
    int i;
    VSIStatBufL sb;
    if (job->sketch && res->params.tiled > 0 && job->lazy && job->coarse_pass &&
        VSIStatL(job->coarse_pass, &sb) == 0) {
        /* laid out before: the file, what it holds, the output's nodata (a sketch laid
         * out again is checked by tsjob_synth_compute) */
        need += 2 * (uint64_t)sb.st_size + cells;
    } else if (job->sketch && res->params.tiled > 0) {
        need += tsjob__sketch_tiles_need(job, res);
    } else if (job->lazy && res->params.tiled > 0) {
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
        need += cells *
                (JOB_MEM_SYNTH_CELL + (job->sketch ? JOB_MEM_SKETCH_CELL : 0) + JOB_MEM_MAPS_CELL);
    }
    int cy = job_synth_ref_row(job, &res->geo);
    double t_area = res->dx_m ? res->dx_m[cy] * res->dy_m[cy] : 0.0;
    for (i = 0; i < job->n_exemplars; i++) {
        uint64_t src, tgt;
        if (tsjob__exemplar_cells(job->exemplars[i], t_area, job->cell_size, &src, &tgt, NULL,
                                  err) != 0)
            return -1;
        need += tgt * JOB_MEM_EX_CELL + job_synth_match_cells(res, tgt) * JOB_MEM_EX_MATCH_CELL;
        if (src > biggest)
            biggest = src; /* read one at a time */
    }
    need += biggest * JOB_MEM_EX_SOURCE_CELL;
    return tsio_check_memory(need, "synth",
                             "a smaller target grid, or smaller or coarser exemplars", err);
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
    if (tsio_read_lines(job->sketch, job->sketch_layer, job->kind_field, job->height_field, crs.wkt,
                        &l, err) != 0) {
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
        const char *bad = g->like             ? "like"
                          : g->has_res        ? "resolution"
                          : g->crs            ? "crs"
                          : job->has_extent   ? "extent"
                          : job->sketch_layer ? "sketch_layer"
                          : job->kind_field   ? "kind_field"
                          : job->height_field ? "height_field"
                          : job->snap >= 0    ? "snap"
                                              : NULL;
        if (bad) {
            tsio_errf(err, job->sketch, "a painted sketch sets the output grid: give no %s", bad);
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
    return tsjob__grid_metrics(&res->geo, job->cell_size, &res->dx_m, &res->dy_m, err);
}

/* The job's rules live in build.c (tsjob_build_synth), which every front end
 * goes through; here only the guard that a job came that way. */
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
        tsio_errf(err, "synth", "internal error: a job not checked by tsjob_build_synth");
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
    } else if (tsjob__target_grid(g, job->exemplars[0], job->cell_size, &res->geo, &res->dx_m,
                                  &res->dy_m, err) != 0) {
        tsjob_synth_result_free(res);
        return -1;
    }
    if (res->dx_m) {
        res->mstore.dx = res->dx_m;
        res->mstore.dy = res->dy_m;
        res->metrics = &res->mstore;
    }
    tsjob__warn_cell_sizes(&res->warning, job->cell_size, job->sketch ? job->sketch : g->like,
                           &res->geo, (const char *const *)job->exemplars, job->n_exemplars);
    /* lengths in metres become cells of the target grid (its ground cell
     * size on the reference row: the exemplars are resampled to it too) */
    res->params = job->params;
    ctx = ts_ctx_new();
    {
        int cy = job_synth_ref_row(job, &res->geo);
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
    int i, cy = job_synth_ref_row(job, &res->geo), P = (int)res->params.patch_size.value;
    for (i = 0; i < job->n_exemplars; i++) {
        double factor = 1.0;
        if (tsio_read_raster_resampled(job->exemplars[i], job->band, res->dx_m ? res->dx_m[cy] : 0,
                                       res->dy_m ? res->dy_m[cy] : 0, job->cell_size, &ex[i],
                                       &factor, err) != 0)
            return -1;
        tsjob__warn_sentinels(&res->warning, job->exemplars[i], &ex[i]);
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

/* The pins at the target resolution with their windows, kept in res for
 * the windows read later (job_rect_flags). */
static int job_keep_pins(const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err)
{
    int i;
    for (i = 0; i < job->n_pins; i++) {
        int *wn = res->pin_win[i];
        if (!res->pin_ex[i].r.data &&
            job_pin_read(job, res, i, &res->pin_ex[i], &wn[0], &wn[1], &wn[2], &wn[3], err) != 0)
            return -1;
    }
    return 0;
}

/* The job's drainage stage with its automatic bank slope from the exemplars as read. */
static void job_drainage_banks(const tsjob_synth *job, tsjob_synth_result *res,
                               const ts_raster *exr)
{
    res->drainage = job->drainage;
    if (res->drainage.bank_slope == -1)
        res->drainage.bank_slope = ts_drainage_bank_slope_auto(exr, job->n_exemplars);
    /* in one piece (the whole grid at hand) with the automatic depth, the basins the breach
     * leaves beside a drawn valley's floor are raised to plains up to 3/4 of the banks' slope
     * above their spill (its pits, at most half of it, the second breach cuts) */
    if (!(res->params.tiled > 0) && res->drainage.mode == TS_DRAINAGE_BREACH &&
        res->drainage.max_depth == -1 && res->drainage.bank_slope > 0)
        res->drainage.floodplain_relief = 0.75 * res->drainage.bank_slope;
    /* free synthesis in one piece: the basins wider than the breach reaches (the patches'
     * own large-scale lows) lifted after it, over blocks of a sixteenth of the radius, graded
     * a twentieth of the banks' slope a block, and breached again */
    if (!(res->params.tiled > 0) && !job->sketch && res->drainage.mode == TS_DRAINAGE_BREACH &&
        res->drainage.max_depth == -1 && res->drainage.bank_slope > 0) {
        res->drainage.basin_block = res->drainage.radius >= 32 ? res->drainage.radius / 16 : 2;
        res->drainage.basin_grade = 0.05 * res->drainage.bank_slope;
    }
}

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
    job_drainage_banks(job, res, res->exr);
    return job_keep_pins(job, res, err);
}

/* Region ids (a label map's values) into the exemplar each takes, -1 for
 * any (--region-exemplar rules); the number of cells a rule gives one. */
static size_t job_region_exemplars(const tsjob_synth *job, int32_t *cell_ex, size_t n)
{
    size_t c, ruled = 0;
    int r;
    for (c = 0; c < n; c++) {
        int32_t id = cell_ex[c], ex_i = -1;
        for (r = 0; r < job->n_region_rules; r++)
            if (job->region_id[r] == id)
                ex_i = job->region_exemplar[r];
        cell_ex[c] = ex_i;
        ruled += ex_i >= 0;
    }
    return ruled;
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
    if (tsio_same_grid(path, what, &hdr.geo, &res->geo, "output", err) != 0) {
        tsio_reader_close(rd);
        tsio_raster_free(&hdr);
        return -1;
    }
    rc = tsio_dem_window(rd, x0, y0, w, h, dst, &nv, &ns, err);
    tsio_reader_close(rd);
    tsio_raster_free(&hdr);
    return rc;
}

/* The water and pins of window win = {x, y, w, h} of the output grid: their
 * TS_CELL_* into flags (w x h, zeroed), their values into `values` (the
 * window's cells; may be NULL). */
static int job_rect_flags(const tsjob_synth *job, const tsjob_synth_result *res, const int win[4],
                          unsigned char *flags, ts_raster *values, tsio_err *err)
{
    size_t n = (size_t)win[2] * (size_t)win[3], c;
    int i, x, y;
    if (job->water) {
        float *tmp = malloc(n * sizeof *tmp);
        if (!tmp) {
            tsio_errf(err, job->water, "out of memory for the water mask's window");
            return -1;
        }
        if (job_grid_window(job->water, "the water mask", res, win[0], win[1], win[2], win[3], tmp,
                            err) != 0) {
            free(tmp);
            return -1;
        }
        for (c = 0; c < n; c++)
            if (!isnan(tmp[c]) && tmp[c] != 0) {
                flags[c] |= TS_CELL_FIXED | TS_CELL_WATER;
                if (values)
                    TS_PIX(values, (int)(c % (size_t)win[2]), (int)(c / (size_t)win[2])) =
                        (float)job->water_level;
            }
        free(tmp);
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
                unsigned char *f =
                    &flags[(size_t)(y - win[1]) * (size_t)win[2] + (size_t)(x - win[0])];
                if (isnan(v))
                    continue;
                if (values)
                    TS_PIX(values, x - win[0], y - win[1]) = v;
                *f = (unsigned char)((*f | TS_CELL_FIXED) &
                                     ~TS_CELL_WATER); /* a pin over water: land */
            }
    }
    return 0;
}

int tsjob_synth_window_flags(const tsjob_synth *job, const tsjob_synth_result *res, int x0, int y0,
                             int w, int h, unsigned char *flags, ts_raster *values, tsio_err *err)
{
    int win[4];
    win[0] = x0;
    win[1] = y0;
    win[2] = w;
    win[3] = h;
    return job_rect_flags(job, res, win, flags, values, err);
}

/* The constraints of tile t's window, as job_constraints and
 * tsjob_synth_compute make them for the whole grid, cut to the window; the
 * fixed cells' values into t->window. */
static int job_window_constraints(ts_ctx *ctx, const tsjob_synth *job,
                                  const tsjob_synth_result *res, ts_synth_tile *t,
                                  job_window_cons *wc, tsio_err *err)
{
    int win[4];
    size_t n;
    if (ts_synth_tile_window(ctx, &res->params, res->params.tiled, res->geo.width, res->geo.height,
                             t->ti, t->tj, win, NULL) != TS_OK) {
        tsio_errf(err, "synth", "%s", ts_ctx_message(ctx));
        return -1;
    }
    n = (size_t)win[2] * (size_t)win[3];
    wc->cons = ts_synth_constraints_default();
    wc->flags = calloc(n, 1);
    if (!wc->flags)
        goto oom;
    wc->cons.cell_flags = wc->flags;
    if (job_rect_flags(job, res, win, wc->flags, &t->window, err) != 0)
        goto fail;
    if (job->heights) {
        if (!(wc->heights = malloc(n * sizeof *wc->heights)))
            goto oom;
        if (job_grid_window(job->heights, "the heights raster", res, win[0], win[1], win[2], win[3],
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
    return 0;
oom:
    tsio_errf(err, "synth", "out of memory for a tile's constraints");
fail:
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
    if (job->sketch && params->tiled > 0
            ? ts_sketch_tiles_new(ctx, NULL, f, exr, job->n_exemplars, &job->sketch_params, params,
                                  cons, res->geo.width, res->geo.height, &res->sketch_tiles, NULL,
                                  &res->sketch_info) != TS_OK
            : ts_synth_sketch_features(ctx, f, exr, job->n_exemplars, &job->sketch_params, params,
                                       cons, &res->out, maps, &res->sketch_info) != TS_OK) {
        job_core_err(ctx, job, job->sketch, err);
        goto done;
    }
    if (!(params->tiled > 0)) { /* in tiles the drawn ridges are kept by res->sketch_tiles */
        res->sketch_features = f;
        f = NULL;
    }
    rc = 0;
done:
    ts_features_free(f);
    free(hz);
    tsio_lines_free(&l);
    return rc;
}

/* The wanted heights and the region map into cons (their cells kept in
 * *heights and *cell_ex, the caller frees them). */
static int job_read_guides(const tsjob_synth *job, tsjob_synth_result *res,
                           ts_synth_constraints *cons, tsio_raster *heights, int32_t **cell_ex,
                           tsio_err *err)
{
    if (job->heights) {
        if (tsio_read_dem(job->heights, 1, heights, err) != 0)
            return -1;
        tsjob__warn_sentinels(&res->warning, job->heights, heights);
        if (tsio_same_grid(job->heights, "the heights raster", &heights->geo, &res->geo, "output",
                           err) != 0)
            return -1;
        cons->heights = heights->r.data;
        cons->alpha_h = job->alpha_h;
    }
    if (job->regions) {
        size_t n = (size_t)res->geo.width * (size_t)res->geo.height;
        *cell_ex = malloc(n * sizeof **cell_ex);
        if (!*cell_ex) {
            tsio_errf(err, job->regions, "out of memory");
            return -1;
        }
        if (tsio_read_label_map(job->regions, &res->geo, "region", INT32_MIN, *cell_ex, err) != 0)
            return -1;
        if (job_region_exemplars(job, *cell_ex, n) == 0) {
            tsio_errf(err, job->regions,
                      "no cell's region has a region_exemplar rule: the map changes nothing");
            return -1;
        }
        cons->cell_exemplar = *cell_ex;
    }
    return 0;
}

int tsjob_synth_compute(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res, int keep_maps,
                        tsio_err *err)
{
    ts_synth_maps *maps = NULL, floor_only;
    tsio_raster ex[TSJOB_MAX_EXEMPLARS];
    ts_raster exr[TSJOB_MAX_EXEMPLARS];
    unsigned char *flags = NULL;
    int32_t *cell_ex = NULL;
    tsio_raster heights;
    ts_synth_params params = res->params; /* lengths in cells */
    ts_synth_constraints cons = ts_synth_constraints_default();
    job_progress jp;
    int i, rc = -1, tiles = job->sketch && res->params.tiled > 0, adopted = 0;
    memset(ex, 0, sizeof ex);
    memset(&heights, 0, sizeof heights);
    ts_ctx_get_progress(ctx, &jp.fn, &jp.user);
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
    /* the floors the drawn valleys are carved along, for the drainage (in one piece) */
    if (job->sketch && !tiles) {
        res->maps.valley_floor = calloc((size_t)res->geo.width * (size_t)res->geo.height, 1);
        if (!res->maps.valley_floor) {
            tsio_errf(err, job->sketch, "out of memory");
            return -1;
        }
        if (!maps) {
            memset(&floor_only, 0, sizeof floor_only);
            floor_only.valley_floor = res->maps.valley_floor;
            maps = &floor_only;
        }
    }
    if (job_read_exemplars(job, res, ex, exr, err) != 0)
        goto done;
    job_drainage_banks(job, res, exr);
    /* a sketch in tiles laid out before; its windows read the pins */
    if (tiles && job->coarse_pass && (adopted = tsjob__synth_adopt_coarse(ctx, job, res, err)) < 0)
        goto done;
    if (tiles && job->lazy && job_keep_pins(job, res, err) != 0)
        goto done;
    if (adopted && job->lazy) {
        rc = 0;
        goto done;
    }
    if (tiles && job->lazy && job->coarse_pass && !adopted &&
        tsio_check_memory(JOB_MEM_BASE + tsjob__sketch_tiles_need(job, res), "synth",
                          "write the recipe again (its coarse pass), or a smaller target grid",
                          err) != 0)
        goto done;
    /* served window by window: no whole output, but the fixed cells' values to lay out */
    if ((!(tiles && job->lazy) || job->n_pins || job->water) &&
        ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
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
    cons.values = res->out.data;
    tsjob__progress_range(ctx, &jp, 0.0, job->drainage.mode ? 0.95 : 1.0);
    if (!adopted && job_read_guides(job, res, &cons, &heights, &cell_ex, err) != 0)
        goto done;
    if (adopted) {
        /* laid out before: what follows amplifies it */
    } else if (job->sketch && res->sketch_lines) {
        if (job_sketch_lines(ctx, job, res, exr, &params, &cons, maps, err) != 0)
            goto done;
    } else if (job->sketch) {
        tsio_raster sk;
        int bad;
        if (tsio_read_drawing(job->sketch, &sk, err) != 0)
            goto done;
        bad = tiles ? ts_sketch_tiles_new(ctx, &sk.r, NULL, exr, job->n_exemplars,
                                          &job->sketch_params, &params, &cons, res->geo.width,
                                          res->geo.height, &res->sketch_tiles, NULL,
                                          &res->sketch_info) != TS_OK
                    : ts_synth_sketch(ctx, &sk.r, exr, job->n_exemplars, &job->sketch_params,
                                      &params, &cons, &res->out, maps, &res->sketch_features,
                                      &res->sketch_info) != TS_OK;
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
    if (tiles && job->lazy) { /* the windows: tsjob_synth_sketch_window_raw, then drained */
        ts_raster_free(&res->out);
        rc = 0;
        goto done;
    }
    if (tiles && ts_sketch_tiles_window(ctx, res->sketch_tiles, 0, 0, &res->out, flags) != TS_OK) {
        job_core_err(ctx, job, job->sketch, err);
        goto done;
    }
    if (tsjob__synth_drain_whole(ctx, job, res, flags, &jp, err) != 0)
        goto done;
    rc = 0;
done:
    if (tiles && !job->lazy) {
        ts_sketch_tiles_free(res->sketch_tiles);
        res->sketch_tiles = NULL;
    }
    ts_ctx_set_progress(ctx, jp.fn, jp.user);
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
    int W = res->geo.width, H = res->geo.height, cy = job_synth_ref_row(job, &res->geo);
    double f = 1.0;
    if (tsio_read_raster_resampled(p->path, job->band, res->dx_m ? res->dx_m[cy] : 0,
                                   res->dy_m ? res->dy_m[cy] : 0, job->cell_size, ex, &f, err) != 0)
        return -1;
    tsjob__warn_sentinels(&res->warning, p->path, ex);
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
    if (*w < 1 || *h < 1 || (int64_t)*x0 + *w > ex->r.width || (int64_t)*y0 + *h > ex->r.height) {
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
        if (tsio_same_grid(job->water, "the water mask", &m.geo, &res->geo, "output", err) != 0) {
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
    ts_sketch_tiles_free(res->sketch_tiles);
    free(res->maps.source_exemplar);
    free(res->maps.source_x);
    free(res->maps.source_y);
    free(res->maps.order);
    free(res->maps.seams);
    free(res->maps.valley_floor);
    free(res->dx_m);
    free(res->dy_m);
    ts_raster_free(&res->out);
    for (int i = 0; i < TSJOB_MAX_EXEMPLARS; i++)
        tsio_raster_free(&res->ex[i]);
    for (int i = 0; i < TSJOB_MAX_PINS; i++)
        tsio_raster_free(&res->pin_ex[i]);
    memset(res, 0, sizeof *res);
}
