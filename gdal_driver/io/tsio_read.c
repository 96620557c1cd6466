/*
 * tsio_read.c - rasters in: any GDAL raster as metres with NaN nodata, its
 * georeferencing and ground metrics (geodesic cell sizes).  Reading at a
 * ground resolution: tsio_resample.c; output grids and the sun: tsio_grid.c.
 *
 * Copyright (C) 2026 The TerraSynth developers
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
/* Reading                                                             */
/* ------------------------------------------------------------------ */

/* Metres per vertical unit named `u`; unknown names count as metres. */
static double vertical_unit_factor(const char *u, int *known)
{
    static const char *const intl_ft[] = {"ft",
                                          "foot",
                                          "feet",
                                          "international foot",
                                          "international feet",
                                          "foot (international)",
                                          "ft (international)",
                                          NULL};
    static const char *const us_ft[] = {"US survey foot", "ftUS",           "us-ft",
                                        "US survey feet", "us_survey_foot", "survey foot",
                                        "foot_us",        "US foot",        NULL};
    static const char *const metre[] = {"", "m", "metre", "meter", "metres", "meters", NULL};
    int i;
    *known = 1;
    for (i = 0; intl_ft[i]; i++)
        if (tsio__str_ieq(u, intl_ft[i]))
            return 0.3048;
    for (i = 0; us_ft[i]; i++)
        if (tsio__str_ieq(u, us_ft[i]))
            return 1200.0 / 3937.0;
    for (i = 0; metre[i]; i++)
        if (tsio__str_ieq(u, metre[i]))
            return 1.0;
    *known = 0;
    return 1.0;
}

static double clamp_lat(double lat)
{
    return lat < -90.0 ? -90.0 : (lat > 90.0 ? 90.0 : lat);
}

/* Per-row ground metrics of a north-up grid in `srs`.  0 or -1 (message in why). */
int tsio__compute_metrics(OGRSpatialReferenceH srs, const double gt[6], int height, double *dx,
                          double *dy, char *why, size_t whylen)
{
    int y;
    if (OSRIsGeographic(srs)) {
        OGRErr e1 = OGRERR_NONE, e2 = OGRERR_NONE;
        double a = OSRGetSemiMajor(srs, &e1);
        double invf = OSRGetInvFlattening(srs, &e2);
        double rad_per_unit = OSRGetAngularUnits(srs, NULL);
        double deg_per_unit, dlon, dlat, f;
        struct geod_geodesic g;
        if (e1 != OGRERR_NONE || !(a > 0.0) || !isfinite(a)) {
            snprintf(why, whylen, "the CRS has no usable ellipsoid");
            return -1;
        }
        f = (e2 == OGRERR_NONE && invf != 0.0 && isfinite(invf)) ? 1.0 / invf : 0.0;
        if (!(f < 1.0)) {
            snprintf(why, whylen, "the CRS has an invalid flattening");
            return -1;
        }
        if (!(rad_per_unit > 0.0) || !isfinite(rad_per_unit))
            rad_per_unit = TSIO_PI / 180.0;
        deg_per_unit = rad_per_unit * 180.0 / TSIO_PI;
        dlon = fabs(gt[1]) * deg_per_unit;
        dlat = fabs(gt[5]) * deg_per_unit;
        {
            /* one rule for every job: a grid past a pole has wrong georeferencing */
            double top = gt[3] * deg_per_unit, bottom = (gt[3] + height * gt[5]) * deg_per_unit;
            double worst = fabs(top) > fabs(bottom) ? top : bottom;
            if (!(fabs(worst) <= 90.0 + 1e-9)) {
                snprintf(why, whylen,
                         "the grid reaches latitude %.6g, past the pole: its georeferencing is "
                         "wrong (ground sizes in metres cannot be measured)",
                         worst);
                return -1;
            }
        }
        geod_init(&g, a, f);
        for (y = 0; y < height; y++) {
            double lat = clamp_lat((gt[3] + ((double)y + 0.5) * gt[5]) * deg_per_unit);
            double s = 0.0, step = dlon;
            int n = 1, i;
            /* a cell wider than half the globe: measure it in pieces */
            while (step > 180.0 && n < 1024) {
                n *= 2;
                step = dlon / n;
            }
            geod_inverse(&g, lat, 0.0, lat, step, &s, NULL, NULL);
            dx[y] = 0.0;
            for (i = 0; i < n; i++)
                dx[y] += s;
            geod_inverse(&g, clamp_lat(lat - dlat / 2.0), 0.0, clamp_lat(lat + dlat / 2.0), 0.0, &s,
                         NULL, NULL);
            dy[y] = s;
            if (!isfinite(dx[y]) || !isfinite(dy[y])) {
                snprintf(why, whylen, "cannot compute geodesic cell sizes");
                return -1;
            }
        }
    } else {
        double unit = OSRGetLinearUnits(srs, NULL);
        double w, h;
        if (!(unit > 0.0) || !isfinite(unit))
            unit = 1.0;
        w = fabs(gt[1]) * unit;
        h = fabs(gt[5]) * unit;
        for (y = 0; y < height; y++) {
            dx[y] = w;
            dy[y] = h;
        }
    }
    return 0;
}

/* An open raster band and how its values become metres with NaN nodata. */
struct tsio_reader { /* tsio.h: tsio_reader */
    GDALDatasetH ds;
    GDALRasterBandH band, mask_band;
    char *path;
    int width, height;
    double scale, offset, vscale, nodata;
    float nodata_f;
    int has_nodata, compare_float;
    double *buf;
    unsigned char *mask;
    size_t buf_cells;
};

static void reader_close(struct tsio_reader *rd)
{
    if (!rd)
        return;
    if (rd->ds)
        GDALClose(rd->ds);
    free(rd->buf);
    free(rd->mask);
    free(rd->path);
    free(rd);
}

/* GDAL's dataset of path, or NULL with a message saying why not. */
static GDALDatasetH open_dataset(const char *path, tsio_err *err)
{
    GDALDatasetH ds;
    CPLErrorReset();
    ds = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR, NULL, NULL,
                    NULL);
    if (!ds) {
        char g[768];
        tsio__gdal_last_msg(g, sizeof g);
        /* connection strings ("NETCDF:f.nc:z") are not files: keep GDAL's verdict */
        if (!tsio__path_exists(path, NULL) &&
            (!strchr(path, ':') || tsio__starts_with(path, "/vsi")))
            tsio_errf(err, path, "no such file");
        else if (g[0] && !strstr(g, "not recognized as a supported file format"))
            tsio_errf(err, path, "not a raster GDAL can open (%s)", g);
        else
            tsio_errf(err, path, "not a raster GDAL can open");
    }
    return ds;
}

/* The size and bands of the dataset: band_no exists, the cells can be counted. */
static int check_size(GDALDatasetH ds, const char *path, int band_no, tsio_err *err)
{
    int nbands = GDALGetRasterCount(ds), w, h;
    GDALDataType dt;
    if (nbands < 1) {
        tsio_errf(err, path, "the file has no raster bands");
        return -1;
    }
    if (band_no < 1 || band_no > nbands) {
        tsio_errf(err, path, "band %d does not exist (the file has %d band%s)", band_no, nbands,
                  nbands == 1 ? "" : "s");
        return -1;
    }
    dt = GDALGetRasterDataType(GDALGetRasterBand(ds, band_no));
    if (GDALDataTypeIsComplex(dt)) {
        tsio_errf(err, path, "band %d holds complex numbers (%s): a DEM's cells are real", band_no,
                  GDALGetDataTypeName(dt));
        return -1;
    }
    w = GDALGetRasterXSize(ds);
    h = GDALGetRasterYSize(ds);
    if (w <= 0 || h <= 0) {
        tsio_errf(err, path, "empty raster (%d x %d cells)", w, h);
        return -1;
    }
    if ((size_t)w > SIZE_MAX / (size_t)h ||
        (size_t)w * (size_t)h > (size_t)PTRDIFF_MAX / sizeof(double)) {
        tsio_errf(err, path, "raster too large (%d x %d cells)", w, h);
        return -1;
    }
    return 0;
}

/* The geotransform into geo (north-up, finite, no zero cell size; the identity
 * without one). */
int tsio__read_geotransform(GDALDatasetH ds, const char *path, tsio_georef *geo, tsio_err *err)
{
    if (GDALGetGeoTransform(ds, geo->gt) == CE_None) {
        int i;
        geo->has_gt = 1;
        if (geo->gt[2] != 0.0 || geo->gt[4] != 0.0) {
            tsio_errf(err, path, "rotated geotransforms are not supported");
            return -1;
        }
        for (i = 0; i < 6; i++)
            if (!isfinite(geo->gt[i])) {
                tsio_errf(err, path, "the geotransform is not finite");
                return -1;
            }
        if (geo->gt[1] == 0.0 || geo->gt[5] == 0.0) {
            tsio_errf(err, path, "the geotransform has a zero cell size");
            return -1;
        }
    } else {
        static const double identity[6] = {0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
        memcpy(geo->gt, identity, sizeof identity);
        geo->has_gt = 0;
    }
    CPLErrorReset();
    return 0;
}

/* The CRS (a clone in *srs, traditional axis order) and its WKT into geo; none: *srs NULL. */
static int read_crs(GDALDatasetH ds, const char *path, tsio_georef *geo, OGRSpatialReferenceH *srs,
                    tsio_err *err)
{
    OGRSpatialReferenceH s = GDALGetSpatialRef(ds);
    if (!s)
        return 0;
    *srs = OSRClone(s);
    if (!*srs) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    OSRSetAxisMappingStrategy(*srs, OAMS_TRADITIONAL_GIS_ORDER);
    geo->wkt = tsio__srs_to_wkt2(*srs);
    if (!geo->wkt) {
        tsio__set_err_gdal(err, path, "cannot export the CRS as WKT");
        return -1;
    }
    geo->is_geographic = OSRIsGeographic(*srs) ? 1 : 0;
    return 0;
}

/* How the band's values become metres: nodata, scale and offset, the vertical unit
 * (the band's, else a compound CRS's), the mask read when it adds to nodata. */
static void read_band_conversion(struct tsio_reader *rd, int band_no, OGRSpatialReferenceH srs,
                                 tsio_raster *out)
{
    GDALRasterBandH band = rd->band = GDALGetRasterBand(rd->ds, band_no);
    GDALDataType dt = GDALGetRasterDataType(band);
    double nodata;
    int ok = 0, mask_flags, known_unit;
    const char *unit;
    if (dt == GDT_Int64) {
        int64_t v = GDALGetRasterNoDataValueAsInt64(band, &ok);
        nodata = (double)v;
    } else if (dt == GDT_UInt64) {
        uint64_t v = GDALGetRasterNoDataValueAsUInt64(band, &ok);
        nodata = (double)v;
    } else {
        nodata = GDALGetRasterNoDataValue(band, &ok);
    }
    rd->has_nodata = ok ? 1 : 0;
    rd->nodata = nodata;
    if (rd->has_nodata) {
        out->has_nodata = 1;
        out->nodata = nodata;
        /* Float32 files store the nodata value as a float: compare as floats */
        if ((dt == GDT_Float32 || dt == GDT_CFloat32) && isfinite(nodata) &&
            fabs(nodata) <= FLT_MAX) {
            rd->compare_float = 1;
            rd->nodata_f = (float)nodata;
        }
    }
    rd->scale = GDALGetRasterScale(band, &ok);
    if (!ok || !isfinite(rd->scale))
        rd->scale = 1.0;
    rd->offset = GDALGetRasterOffset(band, &ok);
    if (!ok || !isfinite(rd->offset))
        rd->offset = 0.0;
    unit = GDALGetRasterUnitType(band);
    if (!unit)
        unit = "";
    while (*unit == ' ')
        unit++;
    rd->vscale = vertical_unit_factor(unit, &known_unit);
    if (!unit[0] && srs && OSRIsCompound(srs)) {
        double f = OSRGetTargetLinearUnits(srs, "VERT_CS", NULL);
        if (f > 0.0 && isfinite(f))
            rd->vscale = f;
    }
    out->vertical_scale = rd->vscale;
    CPLErrorReset();
    mask_flags = GDALGetMaskFlags(band);
    /* A mask derived only from the nodata value adds nothing to the nodata
     * test (and would read the data twice); any other mask is read. */
    if (!(mask_flags & GMF_ALL_VALID) && !(mask_flags == GMF_NODATA && rd->has_nodata))
        rd->mask_band = GDALGetMaskBand(band);
}

/* Open band band_no of path: georeferencing, CRS and ground metrics into
 * out (no cells), the conversion into the reader. */
static struct tsio_reader *open_impl(const char *path, int band_no, tsio_raster *out, tsio_err *err)
{
    struct tsio_reader *rd = calloc(1, sizeof *rd);
    OGRSpatialReferenceH srs = NULL;
    int h;

    if (!rd || !(rd->path = tsio__str_dup(path))) {
        tsio_errf(err, path, "out of memory");
        reader_close(rd);
        return NULL;
    }
    rd->ds = open_dataset(path, err);
    if (!rd->ds) {
        reader_close(rd);
        return NULL;
    }
    if (check_size(rd->ds, path, band_no, err) != 0)
        goto fail;
    rd->width = out->geo.width = GDALGetRasterXSize(rd->ds);
    rd->height = out->geo.height = h = GDALGetRasterYSize(rd->ds);
    if (tsio__read_geotransform(rd->ds, path, &out->geo, err) != 0 ||
        read_crs(rd->ds, path, &out->geo, &srs, err) != 0)
        goto fail;
    read_band_conversion(rd, band_no, srs, out);

    /* ground metrics */
    if (srs && out->geo.has_gt) {
        char why[256] = "";
        out->dx_m = malloc((size_t)h * sizeof(double));
        out->dy_m = malloc((size_t)h * sizeof(double));
        if (!out->dx_m || !out->dy_m) {
            tsio_errf(err, path, "out of memory");
            goto fail;
        }
        if (tsio__compute_metrics(srs, out->geo.gt, h, out->dx_m, out->dy_m, why, sizeof why) !=
            0) {
            tsio_errf(err, path, "%s", why);
            goto fail;
        }
    }
    if (srs)
        OSRDestroySpatialReference(srs);
    return rd;
fail:
    if (srs)
        OSRDestroySpatialReference(srs);
    reader_close(rd);
    return NULL;
}

/* Cells [x0, x0 + w) x [y0, y0 + h) as metres with NaN nodata into dst
 * (w x h, row-major), read in chunks of rows; *n_valid counts the others. */
static int reader_window(struct tsio_reader *rd, int x0, int y0, int w, int h, float *dst,
                         size_t *n_valid, tsio_err *err)
{
    size_t chunk_rows = TSIO_CHUNK_CELLS / (size_t)w;
    int r0, rows;
    if (chunk_rows < 1)
        chunk_rows = 1;
    if (chunk_rows > (size_t)h)
        chunk_rows = (size_t)h;
    if (chunk_rows * (size_t)w > rd->buf_cells) {
        free(rd->buf);
        free(rd->mask);
        rd->buf_cells = chunk_rows * (size_t)w;
        rd->buf = malloc(rd->buf_cells * sizeof(double));
        rd->mask = rd->mask_band ? malloc(rd->buf_cells) : NULL;
        if (!rd->buf || (rd->mask_band && !rd->mask)) {
            rd->buf_cells = 0;
            tsio_errf(err, rd->path, "out of memory (%d x %d cells)", w, h);
            return -1;
        }
    }
    for (r0 = 0; r0 < h; r0 += rows) {
        size_t i, n;
        float *out;
        rows = (int)((size_t)(h - r0) < chunk_rows ? (size_t)(h - r0) : chunk_rows);
        n = (size_t)rows * (size_t)w;
        if (GDALRasterIOEx(rd->band, GF_Read, x0, y0 + r0, w, rows, rd->buf, w, rows, GDT_Float64,
                           (GSpacing)sizeof(double), (GSpacing)sizeof(double) * w,
                           NULL) != CE_None) {
            tsio__set_err_gdal(err, rd->path, "read error");
            return -1;
        }
        if (rd->mask_band && GDALRasterIOEx(rd->mask_band, GF_Read, x0, y0 + r0, w, rows, rd->mask,
                                            w, rows, GDT_Byte, 1, (GSpacing)w, NULL) != CE_None) {
            tsio__set_err_gdal(err, rd->path, "cannot read the mask band");
            return -1;
        }
        out = dst + (size_t)r0 * (size_t)w;
        for (i = 0; i < n; i++) {
            double v = rd->buf[i];
            int bad = !isfinite(v);
            if (!bad && rd->has_nodata) {
                if (rd->compare_float)
                    bad = fabs(v) <= FLT_MAX && (float)v == rd->nodata_f;
                else
                    bad = (v == rd->nodata);
            }
            if (!bad && rd->mask && rd->mask[i] == 0)
                bad = 1;
            if (!bad) {
                v = (v * rd->scale + rd->offset) * rd->vscale;
                if (!isfinite(v) || fabs(v) > FLT_MAX)
                    bad = 1;
            }
            if (bad) {
                out[i] = NAN;
            } else {
                out[i] = (float)v;
                (*n_valid)++;
            }
        }
    }
    return 0;
}

static int read_impl(const char *path, int band_no, tsio_raster *out, tsio_err *err)
{
    struct tsio_reader *rd = open_impl(path, band_no, out, err);
    size_t n_valid = 0;
    int rc = -1;
    if (!rd)
        return -1;
    out->r.data = malloc((size_t)rd->width * (size_t)rd->height * sizeof(float));
    if (!out->r.data) {
        tsio_errf(err, path, "out of memory (%d x %d cells)", rd->width, rd->height);
        goto done;
    }
    out->r.width = rd->width;
    out->r.height = rd->height;
    out->r.stride = rd->width;
    if (reader_window(rd, 0, 0, rd->width, rd->height, out->r.data, &n_valid, err) != 0)
        goto done;
    if (n_valid == 0) {
        tsio_errf(err, path, "every cell is nodata");
        goto done;
    }
    rc = 0;
done:
    reader_close(rd);
    return rc;
}

int tsio_read_raster(const char *path, int band, tsio_raster *out, tsio_err *err)
{
    int rc;
    if (err)
        err->msg[0] = '\0';
    if (!out) {
        tsio_errf(err, path, "no output raster given");
        return -1;
    }
    memset(out, 0, sizeof *out);
    out->vertical_scale = 1.0;
    out->geo.gt[1] = out->geo.gt[5] = 1.0;
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no input file given");
        return -1;
    }
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = read_impl(path, band, out, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    if (rc != 0)
        tsio_raster_free(out);
    return rc;
}

/* Luminance of red, green and blue (Rec. 601), the grey a colour is drawn as. */
static double luminance(double r, double g, double b)
{
    return 0.299 * r + 0.587 * g + 0.114 * b;
}

/* How a drawing stores its grey levels: 0 as values, 1 as indices into band 1's palette
 * (*lut: each index's luminance, *n_lut entries, allocated here), 2 as red, green and
 * blue in bands 1-3; -1 when the file cannot be opened or out of memory. */
static int drawing_kind(const char *path, float **lut, int *n_lut)
{
    GDALDatasetH ds = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_READONLY, NULL, NULL, NULL);
    GDALRasterBandH b;
    GDALColorTableH ct;
    int kind = 0, i;
    if (!ds)
        return -1;
    b = GDALGetRasterBand(ds, 1);
    ct = b ? GDALGetRasterColorTable(b) : NULL;
    if (ct && GDALGetRasterColorInterpretation(b) == GCI_PaletteIndex) {
        *n_lut = GDALGetColorEntryCount(ct);
        *lut = malloc((size_t)(*n_lut > 0 ? *n_lut : 1) * sizeof **lut);
        for (i = 0; *lut && i < *n_lut; i++) {
            GDALColorEntry e;
            GDALGetColorEntryAsRGB(ct, i, &e);
            (*lut)[i] = (float)luminance(e.c1, e.c2, e.c3);
        }
        kind = *lut ? 1 : -1;
    } else if (GDALGetRasterCount(ds) >= 3 && GDALGetRasterColorInterpretation(b) == GCI_RedBand &&
               GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, 2)) == GCI_GreenBand &&
               GDALGetRasterColorInterpretation(GDALGetRasterBand(ds, 3)) == GCI_BlueBand) {
        kind = 2;
    }
    GDALClose(ds);
    return kind;
}

/* Band 1's palette indices into their colours' grey (out, w x h cells); -1 naming a cell
 * whose index has no colour. */
static int grey_from_palette(const char *path, ts_raster *r, const float *lut, int n_lut,
                             tsio_err *err)
{
    size_t i, n = (size_t)r->width * (size_t)r->height;
    for (i = 0; i < n; i++) {
        float v = r->data[i];
        if (isnan(v))
            continue;
        if (!(v >= 0 && v < (float)n_lut && v == floorf(v))) {
            tsio_errf(err, path,
                      "palette index %g at column %zu, row %zu has no colour (the palette has %d)",
                      (double)v, i % (size_t)r->width, i / (size_t)r->width, n_lut);
            return -1;
        }
        r->data[i] = lut[(int)v];
    }
    return 0;
}

/* Band 1 (red, in r) with bands 2 and 3 into their grey. */
static int grey_from_rgb(const char *path, ts_raster *r, tsio_err *err)
{
    size_t i, n = (size_t)r->width * (size_t)r->height;
    tsio_raster g, b;
    if (tsio_read_raster(path, 2, &g, err) != 0)
        return -1;
    if (tsio_read_raster(path, 3, &b, err) != 0) {
        tsio_raster_free(&g);
        return -1;
    }
    for (i = 0; i < n; i++)
        r->data[i] = (float)luminance(r->data[i], g.r.data[i], b.r.data[i]);
    tsio_raster_free(&g);
    tsio_raster_free(&b);
    return 0;
}

int tsio_read_drawing(const char *path, tsio_raster *out, tsio_err *err)
{
    float *lut = NULL;
    int n_lut = 0, kind, rc;
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    kind = drawing_kind(path, &lut, &n_lut);
    CPLPopErrorHandler();
    rc = tsio_read_raster(path, 1, out, err);
    if (rc == 0 && kind < 0) { /* read, so opened: the palette's memory failed */
        tsio_errf(err, path, "out of memory");
        rc = -1;
    } else if (rc == 0 && kind == 1)
        rc = grey_from_palette(path, &out->r, lut, n_lut, err);
    else if (rc == 0 && kind == 2)
        rc = grey_from_rgb(path, &out->r, err);
    if (rc != 0)
        tsio_raster_free(out);
    free(lut);
    return rc;
}

/* Elevations the Earth has (metres, with a margin): the deepest trench is
 * -10 994 m, the highest summit 8 849 m. */
#define TSIO_MIN_ELEVATION (-12000.0)
#define TSIO_MAX_ELEVATION 9000.0
/* A float's extreme values (+-3.4e38) stored as an undeclared nodata. */
#define TSIO_SENTINEL 1e38

/* The DEM checks on cells of a window (x0, y0, w wide): sentinels become
 * NaN (counted), elevations no terrain has are an error naming the first. */
static int dem_filter(const char *path, float *v, size_t n, int x0, int y0, int w,
                      size_t *n_sentinels, size_t *n_valid, tsio_err *err)
{
    size_t i, n_bad = 0, first = 0;
    for (i = 0; i < n; i++) {
        if (isnan(v[i]))
            continue;
        if (fabs(v[i]) >= TSIO_SENTINEL) {
            v[i] = NAN;
            (*n_sentinels)++;
        } else if (v[i] < TSIO_MIN_ELEVATION || v[i] > TSIO_MAX_ELEVATION) {
            if (!n_bad++)
                first = i;
        } else
            (*n_valid)++;
    }
    if (n_bad) {
        tsio_errf(err, path,
                  "%zu cells hold elevations no terrain has (%.6g m at column %zu, row %zu; "
                  "the Earth's are %g..%g m): declare them nodata (gdal_edit.py -a_nodata) or "
                  "check the units",
                  n_bad, (double)v[first], (size_t)x0 + first % (size_t)w,
                  (size_t)y0 + first / (size_t)w, TSIO_MIN_ELEVATION, TSIO_MAX_ELEVATION);
        return -1;
    }
    return 0;
}

int tsio_read_dem(const char *path, int band, tsio_raster *out, tsio_err *err)
{
    size_t n, n_valid = 0;
    if (tsio_read_raster(path, band, out, err) != 0)
        return -1;
    n = (size_t)out->r.width * (size_t)out->r.height;
    out->n_sentinels = 0;
    if (dem_filter(path, out->r.data, n, 0, 0, out->r.width, &out->n_sentinels, &n_valid, err) !=
        0) {
        tsio_raster_free(out);
        return -1;
    }
    if (n_valid == 0) {
        tsio_errf(err, path, "every cell is nodata (%zu cells of +-3.4e38 taken as nodata)",
                  out->n_sentinels);
        tsio_raster_free(out);
        return -1;
    }
    return 0;
}

tsio_reader *tsio_dem_open(const char *path, int band, tsio_raster *out, tsio_err *err)
{
    tsio_reader *rd;
    if (err)
        err->msg[0] = '\0';
    memset(out, 0, sizeof *out);
    out->vertical_scale = 1.0;
    out->geo.gt[1] = out->geo.gt[5] = 1.0;
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no input file given");
        return NULL;
    }
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rd = open_impl(path, band, out, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    if (!rd)
        tsio_raster_free(out);
    return rd;
}

int tsio_dem_window(tsio_reader *rd, int x0, int y0, int w, int h, float *dst, size_t *n_valid,
                    size_t *n_sentinels, tsio_err *err)
{
    size_t seen = 0;
    int rc;
    if (x0 < 0 || y0 < 0 || w <= 0 || h <= 0 || x0 + w > rd->width || y0 + h > rd->height) {
        tsio_errf(err, rd->path, "window %d,%d %dx%d outside the raster", x0, y0, w, h);
        return -1;
    }
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = reader_window(rd, x0, y0, w, h, dst, &seen, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    if (rc != 0)
        return -1;
    return dem_filter(rd->path, dst, (size_t)w * (size_t)h, x0, y0, w, n_sentinels, n_valid, err);
}

void tsio_reader_close(tsio_reader *rd)
{
    reader_close(rd);
}

void tsio_raster_free(tsio_raster *r)
{
    if (!r)
        return;
    free(r->r.data);
    free(r->dx_m);
    free(r->dy_m);
    tsio_georef_free(&r->geo);
    memset(r, 0, sizeof *r);
}

const ts_grid_metrics *tsio_metrics(const tsio_raster *r, ts_grid_metrics *storage)
{
    if (!r || !storage || !r->dx_m || !r->dy_m)
        return NULL;
    storage->dx = r->dx_m;
    storage->dy = r->dy_m;
    return storage;
}

int tsio_georef_copy(const tsio_georef *src, tsio_georef *out)
{
    if (!out)
        return -1;
    if (!src) {
        memset(out, 0, sizeof *out);
        return -1;
    }
    *out = *src;
    out->wkt = NULL;
    if (src->wkt) {
        out->wkt = tsio__str_dup(src->wkt);
        if (!out->wkt)
            return -1;
    }
    return 0;
}

void tsio_georef_free(tsio_georef *g)
{
    if (!g)
        return;
    free(g->wkt);
    g->wkt = NULL;
}
