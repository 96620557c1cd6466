/*
 * job_pixel.c - the pixel job: exemplar stacks, then the synthesis coarse to
 * fine, in one piece or window by window.
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
                         tsjob__grid_metrics(&res->geo, job->cell_size, &res->dx_m, &res->dy_m, err)
                   : tsjob__target_grid(&job->grid, job->exemplars[0], job->cell_size, &res->geo,
                                        &res->dx_m, &res->dy_m, err) != 0) {
        tsjob_pixel_result_free(res);
        return -1;
    }
    tsjob__warn_cell_sizes(&res->warning, job->cell_size, job->guide ? job->guide : job->grid.like,
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
        if (tsjob__exemplar_cells(job->exemplars[i], out_area, job->cell_size, &src, &tgt, NULL,
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
        tsjob__warn_sentinels(&res->warning, job->exemplars[i], &ex[i]);
        if (dx > 0 && !ex[i].dx_m && !res->exemplar_no_crs)
            res->exemplar_no_crs = i + 1;
        exr[i] = ex[i].r;
    }
    res->drainage = job->drainage;
    if (res->drainage.bank_slope == -1)
        res->drainage.bank_slope = ts_drainage_bank_slope_auto(exr, job->n_exemplars);
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
        tsjob__warn_sentinels(&res->warning, job->guide, &g);
        if (g.geo.width != res->geo.width || g.geo.height != res->geo.height) {
            tsio_errf(err, job->guide, "changed size since the job was prepared");
            tsio_raster_free(&g);
            goto done;
        }
        if (job->params.guide_heights == TS_GUIDE_AS_GIVEN && !res->warning.msg[0]) {
            /* a guide in other units (a grey-level sketch) is all but ignored: say so */
            double er[2], gr[2];
            if (ts_pixel_guide_ranges(&g.r, res->stacks, er, gr) == 0 &&
                (gr[1] < er[0] || gr[0] > er[1] || gr[1] - gr[0] < 0.1 * (er[1] - er[0])))
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

typedef struct pixel_raw_arg {
    const tsjob_pixel *job;
    const tsjob_pixel_result *res;
} pixel_raw_arg;

/* The window before the drainage stage (a tsjob_raw_fn). */
static int pixel_raw(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                     unsigned char *flags, tsio_err *err)
{
    const tsjob_pixel *job = ((pixel_raw_arg *)arg)->job;
    const tsjob_pixel_result *res = ((pixel_raw_arg *)arg)->res;
    ts_raster o = ts_raster_wrap(out, w, h, w);
    (void)flags;
    if ((res->guide
             ? ts_pixel_synthesize_guided(ctx, res->stacks, res->guide, &job->params, x0, y0, &o)
             : ts_pixel_synthesize(ctx, res->stacks, &job->params, x0, y0, &o)) != TS_OK) {
        tsio_errf(err, job->exemplars[0], "%s", ts_ctx_message(ctx));
        return -1;
    }
    return 0;
}

int tsjob_pixel_window_raw(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res,
                           int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    pixel_raw_arg a;
    a.job = job;
    a.res = res;
    return pixel_raw(&a, ctx, x0, y0, w, h, out, NULL, err);
}

int tsjob_pixel_window(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res, int x0,
                       int y0, int w, int h, float *out, tsio_err *err)
{
    pixel_raw_arg a;
    a.job = job;
    a.res = res;
    return tsjob_drained_window(ctx, &res->drainage, res->geo.width, res->geo.height, x0, y0, w, h,
                                pixel_raw, &a, out, job->exemplars[0], err);
}

int tsjob_pixel_overview(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res, int k,
                         int x0, int y0, int w, int h, float *out, tsio_err *err)
{
    int L = ts_pixel_levels(res->stacks), kk = k < L ? k : L, b = 1 << (k - kk);
    ts_raster o = ts_raster_wrap(out, w, h, w), fine = {0, 0, 0, NULL};
    if (k < 1 || k > 30 || (uint64_t)w * b > INT_MAX / 2 || (uint64_t)h * b > INT_MAX / 2) {
        tsio_errf(err, job->exemplars[0], "no overview of 2^%d for a window of %d x %d", k, w, h);
        return -1;
    }
    if (b > 1 && ts_raster_alloc(ctx, w * b, h * b, &fine) != TS_OK) {
        tsio_errf(err, job->exemplars[0], "out of memory for an overview's window");
        return -1;
    }
    if (ts_pixel_synthesize_overview(ctx, res->stacks, res->guide, &job->params, kk,
                                     (int64_t)x0 * b, (int64_t)y0 * b,
                                     b > 1 ? &fine : &o) != TS_OK) {
        tsio_errf(err, job->exemplars[0], "%s", ts_ctx_message(ctx));
        ts_raster_free(&fine);
        return -1;
    }
    /* past the coarsest level: its cells averaged over the blocks */
    if (b > 1 && ts_area_average(ctx, &fine, b, &o) != TS_OK) {
        tsio_errf(err, job->exemplars[0], "%s", ts_ctx_message(ctx));
        ts_raster_free(&fine);
        return -1;
    }
    ts_raster_free(&fine);
    return 0;
}

int tsjob_pixel_compute(ts_ctx *ctx, const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err)
{
    job_progress jp;
    struct timespec t0, t1;
    int rc = -1;
    ts_ctx_get_progress(ctx, &jp.fn, &jp.user);
    tsjob__progress_range(ctx, &jp, 0.0, 0.1);
    if (tsjob_pixel_setup(ctx, job, res, err) != 0)
        goto done;
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        tsio_errf(err, "pixel", "%s", ts_ctx_message(ctx));
        goto done;
    }
    tsjob__progress_range(ctx, &jp, 0.1, 0.95);
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
    } else {
        pixel_raw_arg a;
        a.job = job;
        a.res = res;
        if (pixel_raw(&a, ctx, 0, 0, res->geo.width, res->geo.height, res->out.data, NULL, err) !=
            0)
            goto done;
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    res->seconds_synthesis =
        (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    /* the drainage stage on the whole: the bytes of every drained window */
    tsjob__progress_range(ctx, &jp, 0.95, 1.0);
    if (tsjob_drain(ctx, &res->drainage, &res->out, NULL, 0, 0, res->geo.width, res->geo.height,
                    &res->drainage_info, job->exemplars[0], err) != 0)
        goto done;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    res->seconds_drainage =
        (double)(t0.tv_sec - t1.tv_sec) + 1e-9 * (double)(t0.tv_nsec - t1.tv_nsec);
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
    return tsjob__not_an_input(recipe, in, n, err) || tsio_check_output_file(recipe, err) ? -1 : 0;
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
    if (tsjob__not_an_input(o->output, in, n, err) || tsjob__not_an_input(o->preview, in, n, err) ||
        tsjob__distinct(outs, 2, err))
        return -1;
    if (tsio_write_float(o->output, &wo, &g1, &pr, TSIO_NODATA, err) != 0 ||
        (o->preview && tsio_write_byte(o->preview, &png, &g1, &bp, -1, err) != 0) ||
        tsjob__preview_name(o->preview, err))
        return -1;
    if (o->debug_dir) {
        char paths[3][4096];
        const char *all[5] = {o->output, o->preview, paths[0], paths[1], paths[2]};
        if (tsio_make_dir(o->debug_dir, err) != 0)
            return -1;
        for (i = 0; i < 3; i++)
            if (tsio_path(paths[i], sizeof paths[i], o->debug_dir, pixel_map_names[i], "tif",
                          err) != 0 ||
                tsjob__not_an_input(paths[i], in, n, err) != 0 ||
                tsio_check_output_file(paths[i], err) != 0)
                return -1;
        if (tsjob__distinct(all, 5, err) != 0)
            return -1;
    }
    {
        ts_grid_metrics m = {res->dx_m, res->dy_m};
        return tsjob__flow_check(o, in, n, outs, 2, &res->geo, res->dx_m ? &m : NULL, err);
    }
}

int tsjob_pixel_write(ts_ctx *ctx, const tsjob_pixel_result *res, const tsjob_outputs *o,
                      tsio_err *err)
{
    tsio_write_opts wo = {o->format, o->create_options, 0};
    if (tsio_write_float(o->output, &wo, &res->geo, &res->out, TSIO_NODATA, err) != 0)
        return -1;
    if (o->debug_dir && res->src_e) {
        const int32_t *maps[3] = {res->src_e, res->src_x, res->src_y};
        float *tmp = malloc((size_t)res->geo.width * (size_t)res->geo.height * sizeof *tmp);
        int i, bad = !tmp;
        for (i = 0; i < 3 && !bad; i++)
            bad = tsjob__int_map(o->debug_dir, pixel_map_names[i], &res->geo, maps[i], tmp, err);
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
        if (tsjob__preview(ctx, o->preview, &res->out, &res->geo, res->dx_m ? &m : NULL, NULL,
                           err) != 0)
            return -1;
    }
    {
        ts_grid_metrics m = {res->dx_m, res->dy_m};
        return tsjob__flow_write(ctx, o, &res->out, &res->geo, res->dx_m ? &m : NULL, err);
    }
}
