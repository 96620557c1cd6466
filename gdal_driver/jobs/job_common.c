/*
 * job_common.c - what every job shares: warnings about the data read, the exemplars' and
 * target grid's cells, outputs that must not be inputs, previews, progress over
 * several core calls.
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
#include <strings.h>
#include <time.h>
#include <unistd.h>

#include "job_internal.h"

/* ------------------------------------------------------------------ */
/* ppa                                                                 */
/* ------------------------------------------------------------------ */

/* The first warning of a job: cells of a float's extreme value read as nodata. */
void tsjob__warn_sentinels(tsio_err *warning, const char *path, const tsio_raster *r)
{
    if (r->n_sentinels && !warning->msg[0])
        tsio_errf(warning, path,
                  "%zu cells of +-3.4e38 (a float's extreme value, not declared nodata) taken "
                  "as nodata",
                  r->n_sentinels);
}

/* ------------------------------------------------------------------ */
/* synth                                                               */
/* ------------------------------------------------------------------ */

/* Cells of an exemplar, as read and resampled to cells of target_area square
 * metres (0: as they are); *ratio (may be NULL) is the one between the two.  An
 * exemplar without CRS has cells of cell_size metres when that is given. */
int tsjob__exemplar_cells(const char *path, double target_area, double cell_size, uint64_t *source,
                          uint64_t *target, double *ratio, tsio_err *err)
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
    /* resampled to the target's cells, a side past what a raster can hold is refused here
     * (the cast below would wrap, and GDAL would be asked for a negative size) */
    if ((double)g.width * sqrt(r) > (double)INT_MAX ||
        (double)g.height * sqrt(r) > (double)INT_MAX) {
        tsio_errf(err, path,
                  "at the target's cells of %.3g m it would be %.3g x %.3g cells, more than a "
                  "raster holds: give cells nearer its own",
                  sqrt(target_area), (double)g.width * sqrt(r), (double)g.height * sqrt(r));
        tsio_georef_free(&g);
        return -1;
    }
    tsio_georef_free(&g);
    *target = (uint64_t)((double)*source * r + 1.0);
    if (ratio)
        *ratio = r;
    return 0;
}

/* The ground metrics of a grid (NULL without CRS unless cell_size > 0:
 * then every cell is cell_size metres). */
int tsjob__grid_metrics(const tsio_georef *geo, double cell_size, double **dx, double **dy,
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
void tsjob__warn_cell_sizes(tsio_err *warning, double cell_size, const char *grid,
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
int tsjob__target_grid(const tsjob_grid *g, const char *first_exemplar, double cell_size,
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
    return tsjob__grid_metrics(geo, cell_size, dx, dy, err);
}

/* ------------------------------------------------------------------ */
/* what a job writes                                                   */
/* ------------------------------------------------------------------ */

/* Refuse an output that is one of the inputs (by identity: a link or
 * another spelling of the path counts too). */
int tsjob__not_an_input(const char *out, const char *const *inputs, int n, tsio_err *err)
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

/* A preview is written as PNG: its name must say so (a .jpg holding PNG
 * bytes would fool the next program that opens it). */
int tsjob__preview_name(const char *preview, tsio_err *err)
{
    const char *dot, *slash;
    if (!preview)
        return 0;
    dot = strrchr(preview, '.');
    slash = strrchr(preview, '/');
    if (!dot || (slash && dot < slash) || strcasecmp(dot, ".png") != 0) {
        tsio_errf(err, preview, "a preview is a PNG image: give a name ending in .png");
        return -1;
    }
    return 0;
}

/* Two outputs of a job must be two files (-d: refused). */
int tsjob__distinct(const char *const *outs, int n, tsio_err *err)
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
int tsjob__preview(ts_ctx *ctx, const char *path, const ts_raster *dem, const tsio_georef *geo,
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

/* The ground metrics the streams are measured with: the job's, else the grid's own
 * (*dx, *dy allocated here, NULL without CRS); -1 on error. */
static int flow_metrics(const tsio_georef *geo, const ts_grid_metrics *given, double **dx,
                        double **dy, ts_grid_metrics *own, const ts_grid_metrics **use,
                        tsio_err *err)
{
    *dx = *dy = NULL;
    *use = given;
    if (given)
        return 0;
    if (tsio_georef_metrics(geo, dx, dy, err) != 0)
        return -1;
    own->dx = *dx;
    own->dy = *dy;
    *use = *dx ? own : NULL;
    return 0;
}

/* The least drainage area of a stream in cells: flow_km2 over the mean cell's ground
 * area (metrics: flow_metrics'), or flow_cells (default 1000); -1 when flow_km2 has no
 * metrics or is below two cells. */
static double flow_threshold(const tsjob_outputs *o, const tsio_georef *geo,
                             const ts_grid_metrics *metrics, tsio_err *err)
{
    double mean = 0, cells;
    int y;
    if (!(o->flow_km2 > 0))
        return o->flow_cells > 0 ? o->flow_cells : 1000.0;
    if (!metrics) {
        tsio_errf(err, o->flow_lines,
                  "flow_km2 needs the ground size of the cells: the grid has no CRS (give "
                  "flow_cells, or cell_size)");
        return -1;
    }
    for (y = 0; y < geo->height; y++)
        mean += metrics->dx[y] * metrics->dy[y];
    mean /= geo->height;
    cells = o->flow_km2 * 1e6 / mean;
    if (!(cells >= 2)) {
        tsio_errf(err, o->flow_lines,
                  "flow_km2 %g is %g cells of %g m2: a stream drains at least 2", o->flow_km2,
                  cells, mean);
        return -1;
    }
    return cells;
}

int tsjob__flow_check(const tsjob_outputs *o, const char *const *inputs, int n_in,
                      const char *const *outs, int n_outs, const tsio_georef *geo,
                      const ts_grid_metrics *metrics, tsio_err *err)
{
    const char *all[16];
    const ts_grid_metrics *use;
    ts_grid_metrics own;
    double *dx, *dy;
    int i, rc;
    if (!o->flow_lines)
        return 0;
    if (tsjob__not_an_input(o->flow_lines, inputs, n_in, err) != 0)
        return -1;
    for (i = 0; i < n_outs && i < 15; i++)
        all[i] = outs[i];
    all[i] = o->flow_lines;
    if (tsjob__distinct(all, i + 1, err) != 0 || tsio_check_vector_output(o->flow_lines, err) != 0)
        return -1;
    /* after the method: its DEM, the flow (9 bytes a cell) and the stream cells (16 bytes
     * each, a quarter of the cells at most but with the least thresholds) */
    if (tsio_check_memory((uint64_t)geo->width * (uint64_t)geo->height * 17u, o->flow_lines,
                          "a larger flow_cells, or no flow_lines", err) != 0)
        return -1;
    if (flow_metrics(geo, metrics, &dx, &dy, &own, &use, err) != 0)
        return -1;
    rc = flow_threshold(o, geo, use, err) < 0 ? -1 : 0;
    free(dx);
    free(dy);
    return rc;
}

int tsjob__flow_write(ts_ctx *ctx, const tsjob_outputs *o, const ts_raster *dem,
                      const tsio_georef *geo, const ts_grid_metrics *metrics, tsio_err *err)
{
    const ts_grid_metrics *use;
    ts_grid_metrics own;
    double *dx, *dy, thr;
    ts_stream_network *net = NULL;
    int rc = -1;
    if (!o->flow_lines)
        return 0;
    if (flow_metrics(geo, metrics, &dx, &dy, &own, &use, err) != 0)
        return -1;
    thr = flow_threshold(o, geo, use, err);
    if (thr >= 0 && ts_stream_network_extract(ctx, dem, thr, &net) != TS_OK)
        tsio_errf(err, o->flow_lines, "%s", ts_ctx_message(ctx));
    else if (thr >= 0)
        rc = tsio_write_streams(o->flow_lines, geo, net, use, err);
    ts_stream_network_free(net);
    free(dx);
    free(dy);
    return rc;
}

/* Write one int map as Float32 with nodata -1. */
int tsjob__int_map(const char *dir, const char *name, const tsio_georef *geo, const int32_t *v,
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

/* ------------------------------------------------------------------ */
/* amplify                                                             */
/* ------------------------------------------------------------------ */

int tsjob__progress_cb(double done, const char *msg, void *user)
{
    job_progress *p = user;
    return p->fn ? p->fn(p->lo + (p->hi - p->lo) * done, msg, p->user) : 1; /* 1: go on */
}

void tsjob__progress_range(ts_ctx *ctx, job_progress *p, double lo, double hi)
{
    p->lo = lo;
    p->hi = hi;
    ts_ctx_set_progress(ctx, tsjob__progress_cb, p);
}

/* ---- the drainage stage after every method ------------------------- */

int tsjob_drain(ts_ctx *ctx, const ts_drainage_params *p, ts_raster *dem,
                const unsigned char *flags, int64_t gx0, int64_t gy0, int W, int H,
                ts_drainage_info *info, const char *what, tsio_err *err)
{
    if (ts_drainage_apply(ctx, dem, flags, gx0, gy0, W, H, p, info) != TS_OK) {
        tsio_errf(err, what, "%s", ts_ctx_message(ctx));
        return -1;
    }
    return 0;
}

void tsjob__grow_window(int x0, int y0, int w, int h, int m, int W, int H, int win[4])
{
    win[0] = x0 - m > 0 ? x0 - m : 0;
    win[1] = y0 - m > 0 ? y0 - m : 0;
    win[2] = (x0 + w + m < W ? x0 + w + m : W) - win[0];
    win[3] = (y0 + h + m < H ? y0 + h + m : H) - win[1];
}

int tsjob_drained_window(ts_ctx *ctx, const ts_drainage_params *p, int W, int H, int x0, int y0,
                         int w, int h, tsjob_raw_fn raw, void *arg, float *out, const char *what,
                         tsio_err *err)
{
    int M = ts_drainage_margin(p), e[4], ex0, ey0, ew, eh, y, rc = -1;
    float *cells = NULL;
    unsigned char *flags = NULL;
    ts_raster r;
    if (M == 0)
        return raw(arg, ctx, x0, y0, w, h, out, NULL, err);
    tsjob__grow_window(x0, y0, w, h, M, W, H, e);
    ex0 = e[0];
    ey0 = e[1];
    ew = e[2];
    eh = e[3];
    cells = malloc((size_t)ew * (size_t)eh * sizeof *cells);
    flags = calloc((size_t)ew * (size_t)eh, 1);
    if (!cells || !flags) {
        tsio_errf(err, what, "out of memory for a window of %d x %d cells and its margin", w, h);
        goto done;
    }
    if (raw(arg, ctx, ex0, ey0, ew, eh, cells, flags, err) != 0)
        goto done;
    r = ts_raster_wrap(cells, ew, eh, ew);
    if (tsjob_drain(ctx, p, &r, flags, ex0, ey0, W, H, NULL, what, err) != 0)
        goto done;
    for (y = 0; y < h; y++)
        memcpy(out + (size_t)y * (size_t)w,
               cells + (size_t)(y0 - ey0 + y) * (size_t)ew + (size_t)(x0 - ex0),
               (size_t)w * sizeof *out);
    rc = 0;
done:
    free(cells);
    free(flags);
    return rc;
}
