/*
 * tsio_grid.c - output grids: the grid of a raster, one made from a size, an
 * origin, a resolution and a CRS, its ground metrics, and the direction of
 * the sun and grid north for previews.
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
/* Output grids                                                        */
/* ------------------------------------------------------------------ */

int tsio_georef_metrics(const tsio_georef *geo, double **dx, double **dy, tsio_err *err)
{
    OGRSpatialReferenceH srs;
    char why[256];
    *dx = *dy = NULL;
    if (!geo->wkt || !geo->has_gt)
        return 0;
    srs = tsio__srs_from_wkt(geo->wkt);
    if (!srs) {
        tsio_errf(err, "output grid", "cannot read the CRS");
        return -1;
    }
    *dx = malloc((size_t)geo->height * sizeof **dx);
    *dy = malloc((size_t)geo->height * sizeof **dy);
    if (!*dx || !*dy ||
        tsio__compute_metrics(srs, geo->gt, geo->height, *dx, *dy, why, sizeof why)) {
        tsio_errf(err, "output grid", "%s", (*dx && *dy) ? why : "out of memory");
        free(*dx);
        free(*dy);
        *dx = *dy = NULL;
        OSRDestroySpatialReference(srs);
        return -1;
    }
    OSRDestroySpatialReference(srs);
    return 0;
}

int tsio_read_georef(const char *path, tsio_georef *geo, tsio_err *err)
{
    GDALDatasetH ds;
    const char *wkt;
    memset(geo, 0, sizeof *geo);
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    ds = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_READONLY, NULL, NULL, NULL);
    CPLPopErrorHandler();
    if (!ds) {
        VSIStatBufL st;
        if (VSIStatL(path, &st) != 0)
            tsio_errf(err, path, "no such file");
        else
            tsio_errf(err, path, "not a raster GDAL can open");
        return -1;
    }
    geo->width = GDALGetRasterXSize(ds);
    geo->height = GDALGetRasterYSize(ds);
    if (tsio__read_geotransform(ds, path, geo, err) != 0) {
        GDALClose(ds);
        return -1;
    }
    wkt = GDALGetProjectionRef(ds);
    if (wkt && wkt[0]) {
        OGRSpatialReferenceH srs = tsio__srs_from_wkt(wkt);
        if (srs) {
            geo->wkt = tsio__srs_to_wkt2(srs);
            geo->is_geographic = OSRIsGeographic(srs);
            OSRDestroySpatialReference(srs);
        }
    }
    GDALClose(ds);
    return 0;
}

/* A grid whose corners the Earth has: in a geographic CRS longitudes within +-540 degrees
 * (latitudes past the poles are the ground metrics' to refuse, naming the latitude), in a
 * projected one within +-1e8 of its units (2.5 times the Earth's circumference in metres),
 * without a CRS within +-1e15. */
static int grid_on_earth(const tsio_georef *geo, const char *crs, tsio_err *err)
{
    double x0 = geo->gt[0], y0 = geo->gt[3];
    double x1 = x0 + geo->width * geo->gt[1], y1 = y0 + geo->height * geo->gt[5];
    double bx = geo->is_geographic ? 540.0 : geo->wkt ? 1e8 : 1e15;
    double by = geo->is_geographic ? INFINITY : bx;
    int named = crs && crs[0] && strlen(crs) < 64 && !strchr(crs, '[');
    if (!(fabs(x0) <= bx && fabs(x1) <= bx && fabs(y0) <= by && fabs(y1) <= by)) {
        tsio_errf(err, "output grid",
                  "its corners %.6g, %.6g and %.6g, %.6g lie where no place is in %s (within "
                  "+-%g%s): check the origin and the resolution",
                  x0, y0, x1, y1,
                  named      ? crs
                  : geo->wkt ? "its CRS"
                             : "a grid without CRS",
                  bx, geo->is_geographic ? " degrees of longitude" : "");
        return -1;
    }
    return 0;
}

int tsio_georef_make(int width, int height, double origin_x, double origin_y, double res_x,
                     double res_y, const char *crs, tsio_georef *geo, tsio_err *err)
{
    memset(geo, 0, sizeof *geo);
    if (width <= 0 || height <= 0 || !(res_x > 0) || !(res_y > 0) || !isfinite(origin_x) ||
        !isfinite(origin_y)) {
        tsio_errf(err, "output grid", "invalid size, origin or resolution");
        return -1;
    }
    geo->width = width;
    geo->height = height;
    geo->has_gt = 1;
    geo->gt[0] = origin_x;
    geo->gt[1] = res_x;
    geo->gt[3] = origin_y;
    geo->gt[5] = -res_y;
    if (crs && crs[0]) {
        OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
        OGRErr e;
        tsio__ensure_registered();
        CPLPushErrorHandler(CPLQuietErrorHandler);
        e = srs ? OSRSetFromUserInput(srs, crs) : OGRERR_FAILURE;
        CPLErrorReset();
        CPLPopErrorHandler();
        if (e != OGRERR_NONE) {
            if (srs)
                OSRDestroySpatialReference(srs);
            tsio_errf(err, crs, "not a CRS PROJ knows");
            return -1;
        }
        if (!OSRIsProjected(srs) && !OSRIsGeographic(srs) && !OSRIsLocal(srs)) {
            OSRDestroySpatialReference(srs);
            tsio_errf(err, crs,
                      "not a horizontal CRS (vertical, geocentric or another kind): a grid "
                      "needs a projected or geographic one (EPSG:326xx, EPSG:4326, ...)");
            return -1;
        }
        OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
        geo->wkt = tsio__srs_to_wkt2(srs);
        geo->is_geographic = OSRIsGeographic(srs);
        OSRDestroySpatialReference(srs);
    }
    return grid_on_earth(geo, crs, err);
}

/* ------------------------------------------------------------------ */
/* Latitude and grid north, for the sun                                */
/* ------------------------------------------------------------------ */

int tsio_georef_sun_frame(const tsio_georef *geo, int factor, ts_raster *lat, ts_raster *north,
                          tsio_err *err)
{
    OGRSpatialReferenceH srs = NULL, geog = NULL;
    OGRCoordinateTransformationH ct = NULL;
    struct geod_geodesic g;
    double a, invf, f, *xs = NULL, *ys = NULL;
    int *okv = NULL;
    OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
    int w = lat->width, h = lat->height, x, y, rc = -1;
    if (!geo->wkt || !geo->has_gt)
        return 1; /* no CRS: no latitude */
    CPLPushErrorHandler(CPLQuietErrorHandler);
    srs = tsio__srs_from_wkt(geo->wkt);
    geog = srs ? OSRCloneGeogCS(srs) : NULL;
    if (!geog) {
        tsio_errf(err, "grid", "cannot find the geographic CRS of its CRS");
        goto done;
    }
    OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
    OSRSetAxisMappingStrategy(geog, OAMS_TRADITIONAL_GIS_ORDER);
    a = OSRGetSemiMajor(geog, &e1);
    invf = OSRGetInvFlattening(geog, &e2);
    f = (e2 == OGRERR_NONE && invf != 0.0 && isfinite(invf)) ? 1.0 / invf : 0.0;
    if (e1 != OGRERR_NONE || !(a > 0) || !(f < 1.0)) {
        tsio_errf(err, "grid", "the CRS has no usable ellipsoid");
        goto done;
    }
    geod_init(&g, a, f);
    ct = OCTNewCoordinateTransformation(srs, geog);
    xs = malloc((size_t)w * 2 * sizeof *xs);
    ys = malloc((size_t)w * 2 * sizeof *ys);
    okv = malloc((size_t)w * 2 * sizeof *okv);
    if (!ct || !xs || !ys || !okv) {
        tsio_errf(err, "grid", "cannot find the latitude of its cells");
        goto done;
    }
    for (y = 0; y < h; y++) {
        /* each cell's centre, and a point half a cell above it */
        for (x = 0; x < w; x++) {
            double px = ((double)x + 0.5) * factor, py = ((double)y + 0.5) * factor;
            xs[x] = geo->gt[0] + px * geo->gt[1] + py * geo->gt[2];
            ys[x] = geo->gt[3] + px * geo->gt[4] + py * geo->gt[5];
            xs[w + x] = geo->gt[0] + px * geo->gt[1] + (py - 0.5 * factor) * geo->gt[2];
            ys[w + x] = geo->gt[3] + px * geo->gt[4] + (py - 0.5 * factor) * geo->gt[5];
        }
        if (!OCTTransformEx(ct, 2 * w, xs, ys, NULL, okv))
            for (x = 0; x < 2 * w; x++)
                okv[x] = 0;
        for (x = 0; x < w; x++) {
            double azi1 = 0, azi2 = 0, s12 = 0;
            if (!okv[x] || !okv[w + x] || !isfinite(ys[x]) || fabs(ys[x]) > 90.0) {
                TS_PIX(lat, x, y) = NAN;
                if (north)
                    TS_PIX(north, x, y) = NAN;
                continue;
            }
            TS_PIX(lat, x, y) = (float)ys[x];
            if (north) {
                geod_inverse(&g, ys[x], xs[x], ys[w + x], xs[w + x], &s12, &azi1, &azi2);
                TS_PIX(north, x, y) = s12 > 0 && isfinite(azi1) ? (float)azi1 : 0.0f;
            }
        }
    }
    rc = 0;
done:
    CPLErrorReset();
    CPLPopErrorHandler();
    free(xs);
    free(ys);
    free(okv);
    if (ct)
        OCTDestroyCoordinateTransformation(ct);
    if (geog)
        OSRDestroySpatialReference(geog);
    if (srs)
        OSRDestroySpatialReference(srs);
    return rc;
}

/* ------------------------------------------------------------------ */
/* A raster on another's grid                                          */
/* ------------------------------------------------------------------ */

int tsio_same_grid(const char *path, const char *what, const tsio_georef *g,
                   const tsio_georef *grid, const char *grid_name, tsio_err *err)
{
    if (g->width != grid->width || g->height != grid->height) {
        tsio_errf(err, path, "%s is %d x %d cells, the %s %d x %d", what, g->width, g->height,
                  grid_name, grid->width, grid->height);
        return -1;
    }
    if (g->has_gt && grid->has_gt) {
        double cx = fabs(grid->gt[1]) + fabs(grid->gt[2]),
               cy = fabs(grid->gt[4]) + fabs(grid->gt[5]);
        int k, off = 0;
        for (k = 0; k < 6; k++) {
            double scale = (k == 0 || k == 1 || k == 2) ? cx : cy;
            /* corners within a thousandth of a cell, cell sizes within a millionth */
            double tol = (k == 0 || k == 3) ? 1e-3 * scale : 1e-6 * scale;
            if (!(fabs(g->gt[k] - grid->gt[k]) <= tol))
                off = 1;
        }
        if (off) {
            double x0 = grid->gt[0], y0 = grid->gt[3];
            double x1 = x0 + grid->width * grid->gt[1], y1 = y0 + grid->height * grid->gt[5];
            tsio_errf(err, path,
                      "%s is not on the %s's grid (its corner %.10g, %.10g, cells of %.6g; the "
                      "%s's %.10g, %.10g, cells of %.6g): warp it onto it (gdalwarp -te %.10g "
                      "%.10g %.10g %.10g -ts %d %d)",
                      what, grid_name, g->gt[0], g->gt[3], g->gt[1], grid_name, x0, y0, grid->gt[1],
                      x0 < x1 ? x0 : x1, y0 < y1 ? y0 : y1, x0 < x1 ? x1 : x0, y0 < y1 ? y1 : y0,
                      grid->width, grid->height);
            return -1;
        }
    }
    if (g->wkt && g->wkt[0] && grid->wkt && grid->wkt[0]) {
        OGRSpatialReferenceH a = tsio__srs_from_wkt(g->wkt), b = tsio__srs_from_wkt(grid->wkt);
        int same = a && b && OSRIsSame(a, b);
        if (a)
            OSRDestroySpatialReference(a);
        if (b)
            OSRDestroySpatialReference(b);
        if (!same) {
            tsio_errf(err, path,
                      "%s is in another CRS than the %s: warp it onto the %s's grid (gdalwarp "
                      "-t_srs, -te and -ts of the %s)",
                      what, grid_name, grid_name, grid_name);
            return -1;
        }
    }
    return 0;
}
