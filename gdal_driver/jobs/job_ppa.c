/*
 * job_ppa.c - the ppa job: a DEM's ridge and valley axes, in one piece or in
 * tiles, written as a raster, lines and a preview.
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

#include "job_internal.h"

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
    uint64_t tiles = side * side * JOB_MEM_PPA_TILE_CELL +
                     T * (uint64_t)g->width * JOB_MEM_PPA_STRIP + cells * JOB_MEM_PPA_CHAINS;
    /* the drainage (valleys where the water runs) is routed in tiles too,
     * before the axes: a tile per thread, the tiles' borders, a bit a cell */
    long threads = sysconf(_SC_NPROCESSORS_ONLN);
    uint64_t dt = T < 16384 ? T : 16384;
    uint64_t flow = drainage
                        ? (uint64_t)(threads > 0 ? threads : 1) * dt * dt * JOB_MEM_PPA_DRAINAGE +
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
        tsjob__warn_sentinels(&res->warning, job->input, &res->in);
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

int tsjob_ppa_check_outputs(const tsjob_ppa *job, const tsjob_ppa_result *res,
                            const tsjob_outputs *o, tsio_err *err)
{
    const char *in[1] = {job->input};
    unsigned char probe = 0;
    tsio_write_opts wo = {o->format, o->create_options, 1};
    tsio_write_opts png = {"PNG", NULL, 1};
    const char *outs[3] = {o->output, o->lines, o->preview};
    if (res->tile_size > 0 && (o->lines || o->preview || o->flow_lines)) {
        tsio_errf(err, job->input,
                  "mapped in tiles of %d cells (%s): lines, preview and flow_lines need the "
                  "whole DEM in memory; give none of them",
                  res->tile_size,
                  res->auto_tiles ? "too large for memory in one piece" : "as asked");
        return -1;
    }
    if (tsjob__not_an_input(o->output, in, 1, err) || tsjob__not_an_input(o->lines, in, 1, err) ||
        tsjob__not_an_input(o->preview, in, 1, err) || tsjob__distinct(outs, 3, err))
        return -1;
    if (tsio_write_byte(o->output, &wo, &res->in.geo, &probe, 255, err) != 0 ||
        (o->lines && tsio_check_vector_output(o->lines, err) != 0) ||
        (o->preview && tsio_write_byte(o->preview, &png, &res->in.geo, &probe, -1, err) != 0) ||
        tsjob__preview_name(o->preview, err))
        return -1;
    return tsjob__flow_check(o, in, 1, outs, 3, &res->in.geo, res->metrics, err);
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
    if (o->preview && tsjob__preview(ctx, o->preview, &res->in.r, &res->in.geo, res->metrics,
                                     res->features, err) != 0)
        return -1;
    return tsjob__flow_write(ctx, o, &res->in.r, &res->in.geo, res->metrics, err);
}

int tsjob_ppa_check_recipe(const tsjob_ppa *job, const char *recipe, tsio_err *err)
{
    const char *in[1] = {job->input};
    return tsjob__not_an_input(recipe, in, 1, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
}
