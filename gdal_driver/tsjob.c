/*
 * tsjob.c - the jobs behind every front end (see tsjob.h).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "tsjob.h"

static void job_err(tsio_err *err, const char *path, const char *msg)
{
    snprintf(err->msg, sizeof err->msg, "%s: %s", path, msg);
}

/* ------------------------------------------------------------------ */
/* ppa                                                                 */
/* ------------------------------------------------------------------ */

int tsjob_ppa_prepare(const tsjob_ppa *job, tsjob_ppa_result *res, tsio_err *err)
{
    int y;
    memset(res, 0, sizeof *res);
    if (tsio_read_raster(job->input, job->band, &res->in, err) != 0)
        return -1;
    if (!res->in.dx_m && job->cell_size > 0) {
        res->in.dx_m = malloc((size_t)res->in.geo.height * sizeof *res->in.dx_m);
        res->in.dy_m = malloc((size_t)res->in.geo.height * sizeof *res->in.dy_m);
        if (!res->in.dx_m || !res->in.dy_m) {
            job_err(err, job->input, "out of memory");
            tsjob_ppa_result_free(res);
            return -1;
        }
        for (y = 0; y < res->in.geo.height; y++)
            res->in.dx_m[y] = res->in.dy_m[y] = job->cell_size;
    }
    res->no_crs = res->in.dx_m == NULL;
    if (res->no_crs && job->params.min_branch_length.unit == TS_UNIT_METRES) {
        job_err(err, job->input,
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
    if (ts_ppa_extract(ctx, &res->in.r, res->metrics, &job->params, &res->features) != TS_OK) {
        job_err(err, job->input, ts_ctx_message(ctx));
        return -1;
    }
    res->codes = malloc(n);
    if (!res->codes) {
        job_err(err, job->input, "out of memory");
        return -1;
    }
    if (ts_features_codes(ctx, res->features, &res->in.r, res->codes) != TS_OK) {
        job_err(err, job->input, ts_ctx_message(ctx));
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
    tsio_raster_free(&res->in);
    memset(res, 0, sizeof *res);
}

/* ------------------------------------------------------------------ */
/* synth                                                               */
/* ------------------------------------------------------------------ */

int tsjob_synth_prepare(const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err)
{
    const tsjob_grid *g = &job->grid;
    ts_ctx *ctx;
    int bad;
    memset(res, 0, sizeof *res);
    if (job->n_exemplars < 1 || job->n_exemplars > TSJOB_MAX_EXEMPLARS) {
        job_err(err, "synth", "needs 1 to 64 exemplars");
        return -1;
    }
    ctx = ts_ctx_new();
    bad = !ctx || ts_params_validate(ctx, "synth", &job->params) != TS_OK;
    if (bad) {
        job_err(err, "synth", ctx ? ts_ctx_message(ctx) : "out of memory");
        ts_ctx_free(ctx);
        return -1;
    }
    ts_ctx_free(ctx);
    if (job->params.overlap >= job->params.patch_size) {
        job_err(err, "synth", "the overlap must be smaller than the patch size");
        return -1;
    }
    if (job->sketch) {
        if (g->like || g->width || g->crs || g->has_origin || g->has_res) {
            job_err(err, job->sketch, "a sketch sets the output grid: give no other grid");
            return -1;
        }
        if (tsio_read_georef(job->sketch, &res->geo, err) != 0)
            return -1;
        if (res->geo.width < job->params.patch_size || res->geo.height < job->params.patch_size) {
            snprintf(err->msg, sizeof err->msg, "%s: %d x %d cells is smaller than a patch (%d)",
                     job->sketch, res->geo.width, res->geo.height, job->params.patch_size);
            tsjob_synth_result_free(res);
            return -1;
        }
    } else if (g->like) {
        if (tsio_read_georef(g->like, &res->geo, err) != 0)
            return -1;
    } else if (g->crs) {
        if (!g->has_origin || !g->has_res) {
            job_err(err, "synth", "a target CRS needs an origin and a resolution");
            return -1;
        }
        if (tsio_georef_make(g->width, g->height, g->origin_x, g->origin_y, g->res, g->res, g->crs,
                             &res->geo, err) != 0)
            return -1;
    } else {
        /* the first exemplar's CRS, resolution and origin unless given */
        tsio_georef g0;
        int rc;
        if (tsio_read_georef(job->exemplars[0], &g0, err) != 0)
            return -1;
        rc = tsio_georef_make(g->width, g->height, g->has_origin ? g->origin_x : g0.gt[0],
                              g->has_origin ? g->origin_y : g0.gt[3],
                              g->has_res ? g->res : fabs(g0.gt[1]),
                              g->has_res ? g->res : fabs(g0.gt[5]), g0.wkt, &res->geo, err);
        tsio_georef_free(&g0);
        if (rc != 0)
            return -1;
    }
    if (tsio_georef_metrics(&res->geo, &res->dx_m, &res->dy_m, err) != 0) {
        tsjob_synth_result_free(res);
        return -1;
    }
    if (res->dx_m) {
        res->mstore.dx = res->dx_m;
        res->mstore.dy = res->dy_m;
        res->metrics = &res->mstore;
    }
    return 0;
}

int tsjob_synth_compute(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                        ts_synth_maps *maps, tsio_err *err)
{
    tsio_raster ex[TSJOB_MAX_EXEMPLARS];
    ts_raster exr[TSJOB_MAX_EXEMPLARS];
    int i, rc = -1, cy = res->geo.height / 2;
    memset(ex, 0, sizeof ex);
    for (i = 0; i < job->n_exemplars; i++) {
        double factor = 1.0;
        if (tsio_read_raster_resampled(job->exemplars[i], job->band,
                                       res->dx_m ? res->dx_m[cy] : 0, res->dy_m ? res->dy_m[cy] : 0,
                                       &ex[i], &factor, err) != 0)
            goto done;
        if (res->dx_m && !ex[i].dx_m && !res->exemplar_no_crs)
            res->exemplar_no_crs = i + 1;
        if (ex[i].r.width < job->params.patch_size || ex[i].r.height < job->params.patch_size) {
            snprintf(err->msg, sizeof err->msg,
                     "%s: %d x %d cells at the target resolution is smaller than a patch (%d "
                     "cells)",
                     job->exemplars[i], ex[i].r.width, ex[i].r.height, job->params.patch_size);
            goto done;
        }
        exr[i] = ex[i].r;
    }
    if (ts_raster_alloc(ctx, res->geo.width, res->geo.height, &res->out) != TS_OK) {
        job_err(err, "synth", ts_ctx_message(ctx));
        goto done;
    }
    if (job->sketch) {
        tsio_raster sk;
        int bad;
        if (tsio_read_raster(job->sketch, 1, &sk, err) != 0)
            goto done;
        bad = ts_synth_sketch(ctx, &sk.r, exr, job->n_exemplars, &job->sketch_params,
                              &job->params, &res->out, maps, &res->sketch_features,
                              &res->sketch_info) != TS_OK;
        tsio_raster_free(&sk);
        if (bad) {
            const char *msg = ts_ctx_message(ctx);
            int which = 0;
            if (sscanf(msg, "synth: exemplar %d:", &which) == 1 && which >= 1 &&
                which <= job->n_exemplars)
                job_err(err, job->exemplars[which - 1], msg);
            else
                job_err(err, job->sketch, msg);
            goto done;
        }
    } else if (ts_synth_patches(ctx, exr, job->n_exemplars, &job->params, &res->out, NULL,
                                maps) != TS_OK) {
        const char *msg = ts_ctx_message(ctx);
        int which = 0;
        /* name the exemplar file when the core names its index */
        if (sscanf(msg, "synth: exemplar %d:", &which) == 1 && which >= 1 &&
            which <= job->n_exemplars)
            job_err(err, job->exemplars[which - 1], msg);
        else
            job_err(err, "synth", msg);
        goto done;
    }
    rc = 0;
done:
    for (i = 0; i < job->n_exemplars; i++)
        tsio_raster_free(&ex[i]);
    return rc;
}

void tsjob_synth_result_free(tsjob_synth_result *res)
{
    if (!res)
        return;
    tsio_georef_free(&res->geo);
    ts_features_free(res->sketch_features);
    free(res->dx_m);
    free(res->dy_m);
    ts_raster_free(&res->out);
    memset(res, 0, sizeof *res);
}
