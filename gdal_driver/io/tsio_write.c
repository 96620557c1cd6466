/*
 * tsio_write.c - rasters out: Float32 and Byte rasters and PNG previews,
 * checked before the work and written all or nothing.
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
/* Raster writing                                                      */
/* ------------------------------------------------------------------ */

/* What to write: one Float32 band from a ts_raster, one Byte band, or
 * three pixel-interleaved Byte bands. */
typedef struct raster_src {
    int width, height, nbands;
    GDALDataType type;
    const ts_raster *fdata;     /* Float32 source */
    float nodata_f;             /* NaN is replaced by this */
    const unsigned char *bytes; /* Byte source, stride width*nbands */
    tsio_byte_producer produce; /* or one Byte band made window by window */
    void *produce_user;
} raster_src;

/* A window of a producer's cells into band 1 of the dataset. */
typedef struct window_sink {
    GDALDatasetH ds;
    const char *path;
    tsio_err *err;
} window_sink;

static int sink_window(void *arg, int x0, int y0, int w, int h, const unsigned char *bytes)
{
    window_sink *k = arg;
    CPLErrorReset();
    if (GDALRasterIOEx(GDALGetRasterBand(k->ds, 1), GF_Write, x0, y0, w, h,
                       (void *)(uintptr_t)bytes, w, h, GDT_Byte, 1, (GSpacing)w, NULL) != CE_None) {
        tsio__set_err_gdal(k->err, k->path, "write error");
        return -1;
    }
    return 0;
}

/* Output driver from the extension; NULL for ".vrt" (refused).  Unknown
 * extensions get GTiff: guessing from every driver's extension list picks
 * surprising formats (".dat" would be ZMap, ".xyz" cannot store nodata). */
static GDALDriverH raster_driver_for_ext(const char *ext, int *refused)
{
    static const struct {
        const char *ext, *driver;
    } table[] = {{"tif", "GTiff"}, {"tiff", "GTiff"},  {"png", "PNG"}, {"jpg", "JPEG"},
                 {"jpeg", "JPEG"}, {"asc", "AAIGrid"}, {"img", "HFA"}, {"nc", "netCDF"},
                 {"gpkg", "GPKG"}, {"bil", "EHdr"},    {"bt", "BT"}};
    size_t i;
    *refused = 0;
    if (tsio__str_ieq(ext, "vrt")) {
        *refused = 1;
        return NULL;
    }
    for (i = 0; i < sizeof table / sizeof table[0]; i++)
        if (tsio__str_ieq(ext, table[i].ext)) {
            GDALDriverH d = GDALGetDriverByName(table[i].driver);
            if (d)
                return d;
        }
    return GDALGetDriverByName("GTiff");
}

/* Apply georeferencing and nodata to a freshly created dataset.
 * *nodata_stored tells whether the format accepted the nodata value. */
static int apply_georef(GDALDatasetH ds, const tsio_georef *geo, int nbands, int has_nodata,
                        double nodata, int *nodata_stored, const char *path, tsio_err *err)
{
    int b;
    *nodata_stored = 0;
    if (geo && geo->has_gt) {
        double gt[6];
        memcpy(gt, geo->gt, sizeof gt);
        CPLErrorReset();
        if (GDALSetGeoTransform(ds, gt) != CE_None) {
            tsio__set_err_gdal(err, path, "cannot store the geotransform");
            return -1;
        }
    }
    if (geo && geo->wkt && geo->wkt[0]) {
        OGRSpatialReferenceH srs = tsio__srs_from_wkt(geo->wkt);
        CPLErr e;
        if (!srs) {
            tsio_errf(err, path, "the CRS (WKT) is invalid");
            return -1;
        }
        CPLErrorReset();
        e = GDALSetSpatialRef(ds, srs);
        OSRDestroySpatialReference(srs);
        if (e != CE_None) {
            tsio__set_err_gdal(err, path, "cannot store the CRS");
            return -1;
        }
    }
    if (has_nodata) {
        for (b = 1; b <= nbands; b++) {
            CPLErrorReset();
            if (GDALSetRasterNoDataValue(GDALGetRasterBand(ds, b), nodata) != CE_None)
                return 0;
        }
        *nodata_stored = 1;
    }
    CPLErrorReset();
    return 0;
}

/* After apply_georef: a Float32 output whose format refused the nodata
 * value keeps NaN for nodata (NaN is nodata to every reader); other types
 * cannot, and fail. */
static int settle_nodata(raster_src *src, int has_nodata, int nodata_stored, const char *drv_name,
                         const char *path, tsio_err *err)
{
    if (!has_nodata || nodata_stored)
        return 0;
    if (src->type == GDT_Float32) {
        src->nodata_f = NAN;
        return 0;
    }
    tsio_errf(err, path, "format %s cannot store the nodata value", drv_name);
    return -1;
}

/* Copy the source cells into the dataset's bands, in row chunks. */
static int fill_dataset(GDALDatasetH ds, const raster_src *src, const char *path, tsio_err *err)
{
    int w = src->width, h = src->height, y0, rows, flush;
    size_t chunk_rows = TSIO_CHUNK_CELLS / (size_t)w;
    float *fbuf = NULL;
    if (src->produce) {
        window_sink k;
        k.ds = ds;
        k.path = path;
        k.err = err;
        return src->produce(src->produce_user, sink_window, &k, err);
    }
    {
        /* whole blocks per chunk, each chunk flushed: GDAL's cache would otherwise
         * hold the written blocks, a second copy of the raster (130 MB of the
         * 615 MB peak of an 8192^2 terrain), until the close; a flush of whole
         * blocks writes each block once (a partial one would be written
         * again, leaving dead space in a compressed file) */
        int bw = 0, bh = 0;
        GDALDriverH drv = GDALGetDatasetDriver(ds);
        GDALGetBlockSize(GDALGetRasterBand(ds, 1), &bw, &bh);
        flush = drv && strcmp(GDALGetDriverShortName(drv), "MEM") != 0 && bh > 0 &&
                chunk_rows >= (size_t)bh;
        if (flush)
            chunk_rows -= chunk_rows % (size_t)bh;
    }
    if (chunk_rows < 1)
        chunk_rows = 1;
    if (chunk_rows > (size_t)h)
        chunk_rows = (size_t)h;
    if (src->type == GDT_Float32) {
        fbuf = malloc(chunk_rows * (size_t)w * sizeof(float));
        if (!fbuf) {
            tsio_errf(err, path, "out of memory");
            return -1;
        }
    }
    for (y0 = 0; y0 < h; y0 += rows) {
        CPLErr e;
        rows = (int)((size_t)(h - y0) < chunk_rows ? (size_t)(h - y0) : chunk_rows);
        CPLErrorReset();
        if (src->type == GDT_Float32) {
            int y, x;
            for (y = 0; y < rows; y++) {
                const float *s = &TS_PIX(src->fdata, 0, y0 + y);
                float *d = fbuf + (size_t)y * (size_t)w;
                for (x = 0; x < w; x++)
                    d[x] = isnan(s[x]) ? src->nodata_f : s[x];
            }
            e = GDALRasterIOEx(GDALGetRasterBand(ds, 1), GF_Write, 0, y0, w, rows, fbuf, w, rows,
                               GDT_Float32, (GSpacing)sizeof(float), (GSpacing)sizeof(float) * w,
                               NULL);
        } else {
            GSpacing nb = src->nbands;
            unsigned char *p = (unsigned char *)(uintptr_t)(src->bytes + (size_t)y0 * (size_t)w *
                                                                             (size_t)src->nbands);
            e = GDALDatasetRasterIOEx(ds, GF_Write, 0, y0, w, rows, p, w, rows, GDT_Byte,
                                      src->nbands, NULL, nb, nb * w, 1, NULL);
        }
        if (e == CE_None && flush) {
            GDALFlushCache(ds); /* (void in GDAL 3.6: its failure is the last error) */
            if (CPLGetLastErrorType() == CE_Failure || CPLGetLastErrorType() == CE_Fatal)
                e = CE_Failure;
        }
        if (e != CE_None) {
            tsio__set_err_gdal(err, path, "write error");
            free(fbuf);
            return -1;
        }
    }
    free(fbuf);
    return 0;
}

/* Close a dataset and report whether GDAL flagged a failure while flushing. */
int tsio__close_checked(GDALDatasetH ds, const char *path, tsio_err *err)
{
    CPLErrorReset();
    GDALClose(ds);
    if (CPLGetLastErrorType() == CE_Failure || CPLGetLastErrorType() == CE_Fatal) {
        tsio__set_err_gdal(err, path, "write error");
        return -1;
    }
    return 0;
}

static const char *type_name(GDALDataType t)
{
    const char *n = GDALGetDataTypeName(t);
    return n ? n : "?";
}

/* The raster and its georeferencing make sense: 0, or -1 with a message. */
static int check_raster_args(const char *path, const tsio_georef *geo, const raster_src *src,
                             tsio_err *err)
{
    int i;
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (src->width <= 0 || src->height <= 0) {
        tsio_errf(err, path, "empty raster (%d x %d cells)", src->width, src->height);
        return -1;
    }
    if (geo && geo->width > 0 && geo->height > 0 &&
        (geo->width != src->width || geo->height != src->height)) {
        tsio_errf(err, path, "the georeferencing is for %d x %d cells but the data has %d x %d",
                  geo->width, geo->height, src->width, src->height);
        return -1;
    }
    if (geo && geo->has_gt)
        for (i = 0; i < 6; i++)
            if (!isfinite(geo->gt[i])) {
                tsio_errf(err, path, "the geotransform is not finite");
                return -1;
            }
    return 0;
}

/* The driver that writes `path`: forced, asked for (-of) or from the extension, able to
 * write files of the source's type; NULL with a message. */
static GDALDriverH raster_driver(const char *path, const tsio_write_opts *opts,
                                 const char *forced_format, const out_name *on,
                                 const raster_src *src, tsio_err *err)
{
    GDALDriverH drv;
    const char *drv_name, *types;
    if (forced_format) {
        drv = GDALGetDriverByName(forced_format);
        if (!drv) {
            tsio_errf(err, path, "the %s driver is not available", forced_format);
            return NULL;
        }
    } else if (opts && opts->format && opts->format[0]) {
        drv = GDALGetDriverByName(opts->format);
        if (!drv) {
            tsio_errf(err, path, "unknown output format %s", opts->format);
            return NULL;
        }
    } else {
        int refused = 0;
        drv = raster_driver_for_ext(on->ext, &refused);
        if (refused) {
            tsio_errf(err, path, "cannot write VRT: choose a format that stores the cells");
            return NULL;
        }
        if (!drv) {
            tsio_errf(err, path, "the GTiff driver is not available");
            return NULL;
        }
    }
    drv_name = GDALGetDriverShortName(drv);
    if (!tsio__driver_has(drv, GDAL_DCAP_RASTER)) {
        tsio_errf(err, path, "format %s cannot write rasters", drv_name);
        return NULL;
    }
    if (tsio__str_ieq(drv_name, "MEM") || tsio__str_ieq(drv_name, "VRT") ||
        (!tsio__driver_has(drv, GDAL_DCAP_CREATE) &&
         !tsio__driver_has(drv, GDAL_DCAP_CREATECOPY))) {
        tsio_errf(err, path, "format %s cannot write files", drv_name);
        return NULL;
    }
    types = GDALGetMetadataItem(drv, GDAL_DMD_CREATIONDATATYPES, NULL);
    if (types && types[0] && !tsio__list_has_word(types, type_name(src->type))) {
        tsio_errf(err, path, "format %s cannot store %s data (it takes %s)", drv_name,
                  type_name(src->type), types);
        return NULL;
    }
    return drv;
}

/* The creation options given, checked against the driver (KEY=VALUE each), with the
 * table of a GeoPackage named after the final file; 0 with *copts, or -1. */
static int raster_create_options(const char *path, const tsio_write_opts *opts, GDALDriverH drv,
                                 const out_name *on, char ***copts, tsio_err *err)
{
    int i;
    if (opts && opts->create_options) {
        for (i = 0; opts->create_options[i]; i++) {
            const char *o = opts->create_options[i];
            const char *eq = strchr(o, '=');
            if (!eq || eq == o) {
                tsio_errf(err, path, "invalid creation option \"%s\" (expected KEY=VALUE)", o);
                return -1;
            }
            *copts = CSLAddString(*copts, o);
        }
        CPLErrorReset();
        if (*copts && !GDALValidateCreationOptions(drv, (CSLConstList)*copts)) {
            tsio__set_err_gdal(err, path, "invalid creation option");
            return -1;
        }
    }
    /* GeoPackage names its raster table after the file: use the final name */
    if (tsio__str_ieq(GDALGetDriverShortName(drv), "GPKG") &&
        !CSLFetchNameValue(*copts, "RASTER_TABLE") && on->stem[0])
        *copts = CSLSetNameValue(*copts, "RASTER_TABLE", on->stem);
    return 0;
}

/* The temporary file on.temp written: created and filled where the driver creates,
 * else copied from a filled MEM dataset.  0, or -1 (the caller removes the file). */
static int write_temp_raster(const char *path, GDALDriverH drv, const out_name *on, char **copts,
                             const tsio_georef *geo, raster_src *src, int has_nodata, double nodata,
                             tsio_err *err)
{
    const char *drv_name = GDALGetDriverShortName(drv);
    GDALDatasetH ds = NULL, mem = NULL, target;
    int nodata_stored = 0, rc = -1;
    CPLErrorReset();
    if (tsio__driver_has(drv, GDAL_DCAP_CREATE)) {
        ds = GDALCreate(drv, on->temp, src->width, src->height, src->nbands, src->type, copts);
        if (!ds) {
            tsio__set_err_gdal(err, path, "cannot create the file");
            return -1;
        }
        target = ds;
    } else {
        GDALDriverH mem_drv = GDALGetDriverByName("MEM");
        if (!mem_drv) {
            tsio_errf(err, path, "the MEM driver is not available");
            return -1;
        }
        mem = GDALCreate(mem_drv, "", src->width, src->height, src->nbands, src->type, NULL);
        if (!mem) {
            tsio__set_err_gdal(err, path, "cannot create the in-memory copy");
            return -1;
        }
        target = mem;
    }
    if (apply_georef(target, geo, src->nbands, has_nodata, nodata, &nodata_stored, path, err) !=
            0 ||
        settle_nodata(src, has_nodata, nodata_stored, drv_name, path, err) != 0 ||
        fill_dataset(target, src, path, err) != 0)
        goto done;
    if (mem) {
        CPLErrorReset();
        ds = GDALCreateCopy(drv, on->temp, mem, FALSE, copts, NULL, NULL);
        if (!ds) {
            tsio__set_err_gdal(err, path, "cannot create the file");
            goto done;
        }
    }
    rc = tsio__close_checked(ds, path, err);
    ds = NULL;
done:
    if (ds)
        GDALClose(ds);
    if (mem)
        GDALClose(mem);
    return rc;
}

static int write_raster_impl(const char *path, const tsio_write_opts *opts,
                             const char *forced_format, const tsio_georef *geo,
                             const raster_src *src_in, int has_nodata, double nodata, tsio_err *err)
{
    raster_src src_copy = *src_in;
    GDALDriverH drv;
    char **copts = NULL;
    out_name on;
    int rc = -1, created = 0, slot = -1;

    memset(&on, 0, sizeof on);
    if (check_raster_args(path, geo, &src_copy, err) != 0)
        return -1;
    if (tsio__out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    drv = raster_driver(path, opts, forced_format, &on, &src_copy, err);
    if (!drv || raster_create_options(path, opts, drv, &on, &copts, err) != 0 ||
        tsio__check_output_location(&on, path, err) != 0)
        goto done;
    if (opts && opts->check_only) {
        rc = 0;
        goto done;
    }
    /* write the temporary dataset, then move it into place, now or with the job's
     * other outputs */
    created = 1;
    slot = tsio__temp_register(&on);
    if (write_temp_raster(path, drv, &on, copts, geo, &src_copy, has_nodata, nodata, err) != 0)
        goto done;
    created = 0;
    if (tsio__finish_output(&on, path, slot, 1, err) != 0) {
        created = 1; /* not moved: its files go */
        slot = -1;
        goto done;
    }
    slot = -1;
    rc = 0;

done:
    if (rc != 0 && created && on.temp)
        tsio__remove_temp_files(&on);
    tsio__temp_unregister(slot);
    CSLDestroy(copts);
    tsio__out_name_free(&on);
    return rc;
}

/* Run a writer with GDAL's error output silenced. */
static int write_raster(const char *path, const tsio_write_opts *opts, const char *forced_format,
                        const tsio_georef *geo, const raster_src *src, int has_nodata,
                        double nodata, int pam_off, tsio_err *err)
{
    int rc;
    char *saved = NULL;
    if (err)
        err->msg[0] = '\0';
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    if (pam_off) {
        const char *prev = CPLGetThreadLocalConfigOption("GDAL_PAM_ENABLED", NULL);
        saved = prev ? CPLStrdup(prev) : NULL;
        CPLSetThreadLocalConfigOption("GDAL_PAM_ENABLED", "NO");
    }
    rc = write_raster_impl(path, opts, forced_format, geo, src, has_nodata, nodata, err);
    if (pam_off) {
        CPLSetThreadLocalConfigOption("GDAL_PAM_ENABLED", saved);
        CPLFree(saved);
    }
    CPLErrorReset();
    CPLPopErrorHandler();
    return rc;
}

int tsio_write_float(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                     const ts_raster *data, double nodata_value, tsio_err *err)
{
    raster_src src;
    if (!data || !data->data) {
        if (err)
            tsio_errf(err, path, "no raster data given");
        return -1;
    }
    if (data->width <= 0 || data->height <= 0 || data->stride < data->width) {
        if (err)
            tsio_errf(err, path, "invalid raster view (%d x %d, stride %td)", data->width,
                      data->height, data->stride);
        return -1;
    }
    if (!isnan(nodata_value) && !(fabs(nodata_value) <= FLT_MAX)) {
        if (err)
            tsio_errf(err, path, "the nodata value %g does not fit in Float32", nodata_value);
        return -1;
    }
    memset(&src, 0, sizeof src);
    src.width = data->width;
    src.height = data->height;
    src.nbands = 1;
    src.type = GDT_Float32;
    src.fdata = data;
    src.nodata_f = (float)nodata_value;
    return write_raster(path, opts, NULL, geo, &src, 1, nodata_value, 0, err);
}

int tsio_write_byte(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                    const unsigned char *data, int nodata, tsio_err *err)
{
    raster_src src;
    if (!data) {
        if (err)
            tsio_errf(err, path, "no raster data given");
        return -1;
    }
    if (!geo) {
        if (err)
            tsio_errf(err, path, "no georeferencing given (the size comes from it)");
        return -1;
    }
    if (nodata < -1 || nodata > 255) {
        if (err)
            tsio_errf(err, path, "the nodata value %d does not fit in a byte", nodata);
        return -1;
    }
    memset(&src, 0, sizeof src);
    src.width = geo->width;
    src.height = geo->height;
    src.nbands = 1;
    src.type = GDT_Byte;
    src.bytes = data;
    return write_raster(path, opts, NULL, geo, &src, nodata >= 0, (double)nodata, 0, err);
}

int tsio_write_byte_windows(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                            int nodata, tsio_byte_producer produce, void *user, tsio_err *err)
{
    raster_src src;
    if (!produce || !geo || nodata < -1 || nodata > 255) {
        if (err)
            tsio_errf(err, path, "no producer, georeferencing or valid nodata given");
        return -1;
    }
    memset(&src, 0, sizeof src);
    src.width = geo->width;
    src.height = geo->height;
    src.nbands = 1;
    src.type = GDT_Byte;
    src.produce = produce;
    src.produce_user = user;
    return write_raster(path, opts, NULL, geo, &src, nodata >= 0, (double)nodata, 0, err);
}

int tsio_write_png_rgb(const char *path, int width, int height, const unsigned char *rgb,
                       tsio_err *err)
{
    raster_src src;
    if (!rgb) {
        if (err)
            tsio_errf(err, path, "no image data given");
        return -1;
    }
    if (width <= 0 || height <= 0 || width > INT_MAX / 3) {
        if (err)
            tsio_errf(err, path, "invalid image size %d x %d", width, height);
        return -1;
    }
    memset(&src, 0, sizeof src);
    src.width = width;
    src.height = height;
    src.nbands = 3;
    src.type = GDT_Byte;
    src.bytes = rgb;
    return write_raster(path, NULL, "PNG", NULL, &src, 0, 0.0, 1, err);
}

int tsio_write_bytes(const char *path, const void *head, size_t head_len, const void *data,
                     size_t len, int check_only, tsio_err *err)
{
    out_name on;
    VSILFILE *fp;
    int slot, ok, rc = -1;
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (tsio__out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    if (tsio__check_output_location(&on, path, err) != 0)
        goto done;
    if (check_only) {
        rc = 0;
        goto done;
    }
    slot = tsio__temp_register(&on);
    fp = VSIFOpenL(on.temp, "wb");
    if (!fp) {
        tsio__temp_unregister(slot);
        tsio_errf(err, path, "cannot create the file");
        goto done;
    }
    ok = (!head_len || VSIFWriteL(head, 1, head_len, fp) == head_len) &&
         (!len || VSIFWriteL(data, 1, len, fp) == len);
    ok = VSIFCloseL(fp) == 0 && ok;
    if (!ok) {
        VSIUnlink(on.temp);
        tsio__temp_unregister(slot);
        tsio_errf(err, path, "cannot write the file (disk full?)");
        goto done;
    }
    if (tsio__finish_output(&on, path, slot, 0, err) != 0) {
        if (on.temp)
            VSIUnlink(on.temp);
        goto done;
    }
    rc = 0;
done:
    tsio__out_name_free(&on);
    return rc;
}
