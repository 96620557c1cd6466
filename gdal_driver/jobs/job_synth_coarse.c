/*
 * job_synth_coarse.c - a sketch in tiles (job_synth.c lays it out): its
 * windows, its drawn ridges as the drainage stage's barriers, and the file
 * it is kept in (coarse_pass): the coarse pass and what every window reads
 * (ts_sketch_tiles_to_bytes), laid out once when a recipe is written and
 * read back by every process that serves its windows, when it was made from
 * the same inputs.
 *
 *   "TSCFILE1" (8 bytes), then the core's bytes; their key is the checksum
 *   of the library's version, the job's values (job->coarse_params) and the
 *   bytes of every input file.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_vsi.h>

#include "job_internal.h"

#define COARSE_FILE_MAGIC "TSCFILE1"
#define COARSE_FILE_HEAD 8

/* The checksum of the bytes of file `path` chained on sum (its name when it
 * cannot be read: an input that is no file, e.g. a database). */
static uint64_t file_sum(uint64_t sum, const char *path)
{
    VSILFILE *fp = VSIFOpenL(path, "rb");
    unsigned char *buf;
    size_t got;
    if (!fp || !(buf = malloc(1 << 20))) {
        if (fp)
            VSIFCloseL(fp);
        return ts_checksum(sum, path, strlen(path) + 1);
    }
    while ((got = VSIFReadL(buf, 1, 1 << 20, fp)) > 0)
        sum = ts_checksum(sum, buf, got);
    VSIFCloseL(fp);
    free(buf);
    return sum;
}

uint64_t tsjob_synth_coarse_key(const tsjob_synth *job)
{
    const char *in[TSJOB_MAX_INPUTS];
    const char *v = ts_version();
    int n = tsjob_synth_inputs(job, in), i;
    uint64_t sum = ts_checksum(0, COARSE_FILE_MAGIC, COARSE_FILE_HEAD);
    sum = ts_checksum(sum, v, strlen(v) + 1);
    if (job->coarse_params)
        sum = ts_checksum(sum, job->coarse_params, strlen(job->coarse_params) + 1);
    for (i = 0; i < n; i++)
        if (in[i])
            sum = file_sum(sum, in[i]);
    return sum;
}

int tsjob__synth_adopt_coarse(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                              tsio_err *err)
{
    VSIStatBufL sb;
    unsigned char *b = NULL;
    size_t len = 0;
    uint64_t key = 0, limit;
    ts_sketch_tiles *t = NULL;
    int from_option, rc = -1;
    if (VSIStatL(job->coarse_pass, &sb) != 0) {
        if (!job->write_coarse)
            tsio_errf(&res->warning, job->coarse_pass,
                      "missing: the sketch is laid out again (write the recipe again to keep it)");
        return 0;
    }
    /* the file and what it holds both in memory, at most */
    if (tsio_memory_limit(&limit, &from_option, err) != 0 ||
        tsio_read_bytes(job->coarse_pass, (size_t)(limit / 2), &b, &len, err) != 0)
        return -1;
    if (len < COARSE_FILE_HEAD || memcmp(b, COARSE_FILE_MAGIC, COARSE_FILE_HEAD) != 0) {
        tsio_errf(err, job->coarse_pass,
                  "not a sketch in tiles laid out by TerraSynth (coarse_pass: what recipe "
                  "writes beside a recipe)");
        goto done;
    }
    if (ts_sketch_tiles_from_bytes(ctx, b + COARSE_FILE_HEAD, len - COARSE_FILE_HEAD, &key, &t) !=
        TS_OK) {
        tsio_errf(err, job->coarse_pass, "%s", ts_ctx_message(ctx));
        goto done;
    }
    if (key != tsjob_synth_coarse_key(job)) {
        if (!job->write_coarse)
            tsio_errf(&res->warning, job->coarse_pass,
                      "was laid out from other inputs, parameters or seed: the sketch is laid "
                      "out again (write the recipe again to keep it)");
        ts_sketch_tiles_free(t);
        rc = 0;
        goto done;
    }
    res->sketch_tiles = t;
    rc = 1;
done:
    free(b);
    return rc;
}

int tsjob_synth_write_coarse(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                             tsio_err *err)
{
    unsigned char *b = NULL;
    size_t len = 0;
    int rc;
    if (!res->sketch_tiles) {
        tsio_errf(err, job->coarse_pass, "internal error: no sketch in tiles to write");
        return -1;
    }
    if (ts_sketch_tiles_to_bytes(ctx, res->sketch_tiles, tsjob_synth_coarse_key(job), &b, &len) !=
        TS_OK) {
        tsio_errf(err, job->coarse_pass, "%s", ts_ctx_message(ctx));
        return -1;
    }
    rc = tsio_write_bytes(job->coarse_pass, COARSE_FILE_MAGIC, COARSE_FILE_HEAD, b, len, 0, err);
    free(b);
    return rc;
}

uint64_t tsjob__sketch_tiles_need(const tsjob_synth *job, const tsjob_synth_result *res)
{
    /* laid out whole K times coarser, then amplified: the coarse pass, the output and the
     * amplified grid, the amplification's input (sketch_amplify.c) */
    int P = (int)res->params.patch_size.value;
    uint64_t K =
        (uint64_t)ts_sketch_amplify_factor(&job->sketch_params, P, res->geo.width, res->geo.height);
    uint64_t coarse =
        ((uint64_t)res->geo.width + K - 1) / K * (((uint64_t)res->geo.height + K - 1) / K);
    return coarse * (JOB_MEM_SYNTH_CELL + JOB_MEM_SKETCH_CELL + 48) +
           (uint64_t)res->geo.width * (uint64_t)res->geo.height * 12;
}

int tsjob_synth_sketch_window_raw(ts_ctx *ctx, const tsjob_synth *job,
                                  const tsjob_synth_result *res, int x0, int y0, int w, int h,
                                  float *cells, tsio_err *err)
{
    ts_raster o = ts_raster_wrap(cells, w, h, w), g;
    unsigned char *flags = NULL;
    int win[4], y, rc = -1;
    if (!job->n_pins && !job->water) {
        if (ts_sketch_tiles_window(ctx, res->sketch_tiles, x0, y0, &o, NULL) != TS_OK) {
            tsio_errf(err, job->sketch, "%s", ts_ctx_message(ctx));
            return -1;
        }
        return 0;
    }
    /* with pins or water: the window grown by the margin their blend reads, then cut */
    tsjob__grow_window(x0, y0, w, h, ts_sketch_tiles_margin(res->sketch_tiles), res->geo.width,
                       res->geo.height, win);
    if (ts_raster_alloc(ctx, win[2], win[3], &g) != TS_OK ||
        !(flags = calloc((size_t)win[2] * (size_t)win[3], 1))) {
        tsio_errf(err, job->sketch, "out of memory for a window of %d x %d cells", win[2], win[3]);
        goto done;
    }
    if (tsjob_synth_window_flags(job, res, win[0], win[1], win[2], win[3], flags, &g, err) != 0)
        goto done;
    if (ts_sketch_tiles_window(ctx, res->sketch_tiles, win[0], win[1], &g, flags) != TS_OK) {
        tsio_errf(err, job->sketch, "%s", ts_ctx_message(ctx));
        goto done;
    }
    for (y = 0; y < h; y++)
        memcpy(cells + (size_t)y * (size_t)w, &TS_PIX(&g, x0 - win[0], y0 - win[1] + y),
               (size_t)w * sizeof *cells);
    rc = 0;
done:
    ts_raster_free(&g);
    free(flags);
    return rc;
}

void tsjob_synth_sketch_barriers(const tsjob_synth_result *res, int x0, int y0, int w, int h,
                                 unsigned char *flags)
{
    const ts_features *f = res->sketch_features;
    int x, y;
    if (res->sketch_tiles) {
        ts_sketch_tiles_ridges(res->sketch_tiles, x0, y0, w, h, flags, TS_CELL_BARRIER);
        return;
    }
    if (!f || !f->mask || f->width != res->geo.width || f->height != res->geo.height)
        return;
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++)
            if (f->mask[(size_t)(y0 + y) * (size_t)f->width + (size_t)(x0 + x)] & TS_RIDGE)
                flags[(size_t)y * (size_t)w + (size_t)x] |= TS_CELL_BARRIER;
}
