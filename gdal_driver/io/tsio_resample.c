/*
 * tsio_resample.c - rasters read at a ground resolution: warped to cells of a
 * given size (any CRS), or resampled cell for cell without one.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1 /* struct stat64 behind GDAL's VSIStatBufL under -std=c11 */

#include "tsio_internal.h"

#include <ctype.h>
#include <float.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <gdal_utils.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>

#include <geodesic.h>

/* ------------------------------------------------------------------ */
/* Reading at a ground resolution                                      */
/* ------------------------------------------------------------------ */

/* The raster as a Float32 MEM dataset (NaN nodata) with its georeferencing. */
static GDALDatasetH mem_from_raster(const tsio_raster *r)
{
    GDALDriverH mem = GDALGetDriverByName("MEM");
    GDALDatasetH ds;
    GDALRasterBandH b;
    if (!mem)
        return NULL;
    ds = GDALCreate(mem, "", r->geo.width, r->geo.height, 1, GDT_Float32, NULL);
    if (!ds)
        return NULL;
    GDALSetGeoTransform(ds, (double *)r->geo.gt);
    if (r->geo.wkt)
        GDALSetProjection(ds, r->geo.wkt);
    b = GDALGetRasterBand(ds, 1);
    GDALSetRasterNoDataValue(b, NAN);
    if (GDALRasterIOEx(b, GF_Write, 0, 0, r->geo.width, r->geo.height, r->r.data, r->geo.width,
                       r->geo.height, GDT_Float32, sizeof(float),
                       (GSpacing)r->r.stride * (GSpacing)sizeof(float), NULL) != CE_None) {
        GDALClose(ds);
        return NULL;
    }
    return ds;
}

/* Replace `out` by the warped dataset's contents and georeferencing. */
static int raster_from_mem(GDALDatasetH ds, tsio_raster *out, const char *path, tsio_err *err)
{
    int w = GDALGetRasterXSize(ds), h = GDALGetRasterYSize(ds);
    size_t i;
    double gt[6];
    OGRSpatialReferenceH srs = NULL;
    const char *wkt = GDALGetProjectionRef(ds);
    float *data = (w > 0 && h > 0 && (size_t)w <= SIZE_MAX / sizeof(float) / (size_t)h)
                      ? malloc((size_t)w * (size_t)h * sizeof *data)
                      : NULL;
    double *dx = h > 0 ? malloc((size_t)h * sizeof *dx) : NULL;
    double *dy = h > 0 ? malloc((size_t)h * sizeof *dy) : NULL;
    char why[256];
    if (!data || !dx || !dy) {
        tsio_errf(err, path, "out of memory");
        goto fail;
    }
    GDALGetGeoTransform(ds, gt);
    if (GDALRasterIO(GDALGetRasterBand(ds, 1), GF_Read, 0, 0, w, h, data, w, h, GDT_Float32, 0,
                     0) != CE_None) {
        tsio__set_err_gdal(err, path, "cannot read the resampled raster");
        goto fail;
    }
    srs = wkt && wkt[0] ? tsio__srs_from_wkt(wkt) : NULL;
    if (!srs || tsio__compute_metrics(srs, gt, h, dx, dy, why, sizeof why) != 0) {
        tsio_errf(err, path, "cannot measure the resampled grid");
        goto fail;
    }
    for (i = 0; i < (size_t)w * (size_t)h; i++)
        if (!isfinite(data[i]))
            data[i] = NAN;
    free(out->r.data);
    free(out->dx_m);
    free(out->dy_m);
    free(out->geo.wkt);
    out->r = ts_raster_wrap(data, w, h, w);
    out->dx_m = dx;
    out->dy_m = dy;
    out->geo.width = w;
    out->geo.height = h;
    memcpy(out->geo.gt, gt, sizeof gt);
    out->geo.has_gt = 1;
    out->geo.wkt = tsio__srs_to_wkt2(srs);
    out->geo.is_geographic = OSRIsGeographic(srs);
    OSRDestroySpatialReference(srs);
    return 0;
fail:
    if (srs)
        OSRDestroySpatialReference(srs);
    free(data);
    free(dx);
    free(dy);
    return -1;
}

/* A raster without CRS whose cells are cell_m metres: its metrics set to
 * that and, when the target's cells differ by more than 1 %, resampled to
 * them in its own pixel space (cubic when finer, average when coarser). */
static int resample_no_crs(const char *path, int categorical, double cell_m, double target_dx_m,
                           double target_dy_m, tsio_raster *out, double *factor, tsio_err *err)
{
    int w = out->geo.width, h = out->geo.height, nw, nh, y, rc = -1, usage = 0;
    double f = sqrt((cell_m * cell_m) / (target_dx_m * target_dy_m));
    GDALDatasetH src = NULL, dst = NULL;
    GDALTranslateOptions *to = NULL;
    char sw[32], sh[32];
    float *data = NULL;
    double *dx = NULL, *dy = NULL;
    if (factor)
        *factor = f;
    if (fabs(cell_m / target_dx_m - 1.0) < 1e-2 && fabs(cell_m / target_dy_m - 1.0) < 1e-2) {
        nw = w;
        nh = h;
    } else {
        char *argv[] = {"-of", "MEM", "-outsize", sw, sh, "-r", NULL, "-ot", "Float32", NULL};
        nw = (int)lround(w * cell_m / target_dx_m);
        nh = (int)lround(h * cell_m / target_dy_m);
        if (nw < 1 || nh < 1 || (double)nw * (double)nh > 4e9) {
            tsio_errf(err, path, "cannot be resampled to %.6g m cells", target_dx_m);
            return -1;
        }
        snprintf(sw, sizeof sw, "%d", nw);
        snprintf(sh, sizeof sh, "%d", nh);
        argv[6] = categorical ? (f > 1.0 ? "near" : "mode") : f > 1.0 ? "cubicspline" : "average";
        CPLPushErrorHandler(CPLQuietErrorHandler);
        src = mem_from_raster(out);
        to = src ? GDALTranslateOptionsNew(argv, NULL) : NULL;
        dst = to ? GDALTranslate("", src, to, &usage) : NULL;
        data = dst && (size_t)nw <= SIZE_MAX / sizeof(float) / (size_t)nh
                   ? malloc((size_t)nw * (size_t)nh * sizeof *data)
                   : NULL;
        if (!data || GDALRasterIO(GDALGetRasterBand(dst, 1), GF_Read, 0, 0, nw, nh, data, nw, nh,
                                  GDT_Float32, 0, 0) != CE_None) {
            tsio_errf(err, path, "resampling failed");
            goto done;
        }
        {
            size_t i;
            for (i = 0; i < (size_t)nw * (size_t)nh; i++)
                if (!isfinite(data[i]))
                    data[i] = NAN;
        }
    }
    dx = malloc((size_t)nh * sizeof *dx);
    dy = malloc((size_t)nh * sizeof *dy);
    if (!dx || !dy) {
        tsio_errf(err, path, "out of memory");
        goto done;
    }
    for (y = 0; y < nh; y++) {
        dx[y] = data ? target_dx_m : cell_m;
        dy[y] = data ? target_dy_m : cell_m;
    }
    if (data) {
        free(out->r.data);
        out->r = ts_raster_wrap(data, nw, nh, nw);
        data = NULL;
        out->geo.width = nw;
        out->geo.height = nh;
        out->geo.gt[1] *= (double)w / nw;
        out->geo.gt[5] *= (double)h / nh;
    }
    free(out->dx_m);
    free(out->dy_m);
    out->dx_m = dx;
    out->dy_m = dy;
    dx = dy = NULL;
    rc = 0;
done:
    if (src || to) {
        CPLErrorReset();
        CPLPopErrorHandler();
    }
    if (to)
        GDALTranslateOptionsFree(to);
    if (dst)
        GDALClose(dst);
    if (src)
        GDALClose(src);
    free(data);
    free(dx);
    free(dy);
    if (rc != 0)
        tsio_raster_free(out);
    return rc;
}

static int read_resampled(const char *path, int band, int categorical, double target_dx_m,
                          double target_dy_m, double no_crs_cell_m, tsio_raster *out,
                          double *factor, tsio_err *err);

int tsio_read_raster_resampled(const char *path, int band, double target_dx_m, double target_dy_m,
                               double no_crs_cell_m, tsio_raster *out, double *factor,
                               tsio_err *err)
{
    return read_resampled(path, band, 0, target_dx_m, target_dy_m, no_crs_cell_m, out, factor, err);
}

int tsio_read_classes_resampled(const char *path, int band, double target_dx_m, double target_dy_m,
                                double no_crs_cell_m, tsio_raster *out, tsio_err *err)
{
    return read_resampled(path, band, 1, target_dx_m, target_dy_m, no_crs_cell_m, out, NULL, err);
}

static int read_resampled(const char *path, int band, int categorical, double target_dx_m,
                          double target_dy_m, double no_crs_cell_m, tsio_raster *out,
                          double *factor, tsio_err *err)
{
    GDALDatasetH src = NULL, dst = NULL;
    GDALWarpAppOptions *wo = NULL;
    OGRSpatialReferenceH srs = NULL;
    char trx[64], try_[64], *t_srs = NULL;
    const char *alg;
    double gdx, gdy, f, unit = 1.0;
    int rc = -1, usage = 0, geographic;
    if (factor)
        *factor = 1.0;
    if ((categorical ? tsio_read_raster(path, band, out, err)
                     : tsio_read_dem(path, band, out, err)) != 0)
        return -1;
    if (!(target_dx_m > 0) || !(target_dy_m > 0))
        return 0; /* nothing asked: cells as they are */
    if (!out->dx_m)
        return no_crs_cell_m > 0 ? resample_no_crs(path, categorical, no_crs_cell_m, target_dx_m,
                                                   target_dy_m, out, factor, err)
                                 : 0; /* no CRS and no cell size: cells as they are */
    gdx = out->dx_m[out->geo.height / 2];
    gdy = out->dy_m[out->geo.height / 2];
    geographic = out->geo.is_geographic;
    f = sqrt((gdx * gdy) / (target_dx_m * target_dy_m));
    if (factor)
        *factor = f;
    /* within 1 % the cells are used as they are: no interpolation blur, and
     * pinned windows stay exact (a geographic grid's cells change by more than
     * that only far from its centre latitude) */
    (void)geographic;
    if (fabs(gdx / target_dx_m - 1.0) < 1e-2 && fabs(gdy / target_dy_m - 1.0) < 1e-2)
        return 0;
    CPLPushErrorHandler(CPLQuietErrorHandler);
    srs = tsio__srs_from_wkt(out->geo.wkt);
    if (!srs) {
        tsio_errf(err, path, "cannot read its CRS");
        goto done;
    }
    if (geographic) {
        /* stay in the geographic CRS: degrees per cell chosen so that a cell
         * measures target_dx_m x target_dy_m at the raster's centre latitude
         * (one projection for a large raster would distort far more) */
        int c = out->geo.height / 2;
        double mdeg_x = out->dx_m[c] / fabs(out->geo.gt[1]);
        double mdeg_y = out->dy_m[c] / fabs(out->geo.gt[5]);
        if (!(mdeg_x > 0) || !(mdeg_y > 0)) {
            tsio_errf(err, path, "cannot measure its cells on the ground");
            goto done;
        }
        snprintf(trx, sizeof trx, "%.17g", target_dx_m / mdeg_x);
        snprintf(try_, sizeof try_, "%.17g", target_dy_m / mdeg_y);
        t_srs = out->geo.wkt;
    } else {
        unit = OSRGetLinearUnits(srs, NULL);
        if (!(unit > 0))
            unit = 1.0;
        t_srs = out->geo.wkt;
        snprintf(trx, sizeof trx, "%.17g", target_dx_m / unit);
        snprintf(try_, sizeof try_, "%.17g", target_dy_m / unit);
    }
    /* finer target: interpolate; coarser: average (classes: the nearest, the most common) */
    alg = categorical ? (f > 1.0 ? "near" : "mode") : f > 1.0 ? "cubicspline" : "average";
    {
        char *argv[] = {"-of", "MEM",       "-t_srs",     t_srs, "-tr", trx,       try_,
                        "-r",  (char *)alg, "-dstnodata", "nan", "-ot", "Float32", NULL};
        src = mem_from_raster(out);
        wo = GDALWarpAppOptionsNew(argv, NULL);
        if (!src || !wo) {
            tsio_errf(err, path, "cannot prepare the resampling");
            goto done;
        }
        dst = GDALWarp("", NULL, 1, &src, wo, &usage);
        if (!dst) {
            tsio__set_err_gdal(err, path, "resampling failed");
            goto done;
        }
    }
    rc = raster_from_mem(dst, out, path, err);
done:
    CPLErrorReset();
    CPLPopErrorHandler();
    if (wo)
        GDALWarpAppOptionsFree(wo);
    if (dst)
        GDALClose(dst);
    if (src)
        GDALClose(src);
    if (srs)
        OSRDestroySpatialReference(srs);
    if (rc != 0)
        tsio_raster_free(out);
    return rc;
}
