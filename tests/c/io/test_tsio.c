/*
 * test_tsio.c - tests of the GDAL I/O layer (gdal_driver/tsio_*.c).
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * A plain C program: every CHECK counts as one test; the last line is
 * "N passed, M failed" and the exit status is non-zero on any failure.
 * Files go to a fresh directory from mkdtemp() under /tmp, removed at the end.
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1 /* struct stat64 behind GDAL's VSIStatBufL under -std=c11 */

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>

#include "terrasynth.h"
#include "tsio.h"

#define TEST_PI 3.14159265358979323846

static int n_pass, n_fail;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (cond) {                                                                  \
            n_pass++;                                                                \
        } else {                                                                     \
            n_fail++;                                                                \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                            \
    } while (0)

#define CHECK_NEAR(a, b, tol)                                                               \
    do {                                                                                    \
        double a_ = (a), b_ = (b);                                                          \
        if (fabs(a_ - b_) <= (tol)) {                                                       \
            n_pass++;                                                                       \
        } else {                                                                            \
            n_fail++;                                                                       \
            fprintf(stderr, "%s:%d: CHECK_NEAR failed: %s = %.9g, expected %.9g (+-%g)\n", \
                    __FILE__, __LINE__, #a, a_, b_, (double)(tol));                         \
        }                                                                                   \
    } while (0)

static char tmpdir[64];

/* "<tmpdir>/<name>" in a static rotating buffer (enough for one test). */
static const char *tp(const char *name)
{
    static char bufs[8][512];
    static int k;
    char *b = bufs[k++ % 8];
    snprintf(b, sizeof bufs[0], "%s/%s", tmpdir, name);
    return b;
}

static int file_exists(const char *p)
{
    VSIStatBufL st;
    return VSIStatL(p, &st) == 0;
}

/* No leftover temporary file in the test directory. */
static int no_tmp_files(void)
{
    char **e = VSIReadDir(tmpdir);
    int i, ok = 1;
    for (i = 0; e && e[i]; i++)
        if (strstr(e[i], ".tmp")) {
            fprintf(stderr, "leftover temporary file: %s\n", e[i]);
            ok = 0;
        }
    CSLDestroy(e);
    return ok;
}

static int count_entries(void)
{
    char **e = VSIReadDir(tmpdir);
    int i, n = 0;
    for (i = 0; e && e[i]; i++)
        if (strcmp(e[i], ".") && strcmp(e[i], ".."))
            n++;
    CSLDestroy(e);
    return n;
}

/* A message is one line that contains the path. */
static int good_msg(const tsio_err *err, const char *path)
{
    return err->msg[0] && strstr(err->msg, path) && !strchr(err->msg, '\n');
}

static int msg_has(const tsio_err *err, const char *s)
{
    if (strstr(err->msg, s))
        return 1;
    fprintf(stderr, "message \"%s\" lacks \"%s\"\n", err->msg, s);
    return 0;
}

/* Create a Float32 GTiff: w x h, values v[i] (row-major), CRS from user
 * input (NULL: none), geotransform (NULL: none), nodata (NAN: none). */
static int make_tif(const char *path, int w, int h, const float *v, const char *crs,
                    const double *gt, double nodata)
{
    GDALDriverH drv = GDALGetDriverByName("GTiff");
    GDALDatasetH ds = GDALCreate(drv, path, w, h, 1, GDT_Float32, NULL);
    GDALRasterBandH b;
    int rc = 0;
    if (!ds)
        return -1;
    b = GDALGetRasterBand(ds, 1);
    if (crs) {
        OGRSpatialReferenceH s = OSRNewSpatialReference(NULL);
        OSRSetAxisMappingStrategy(s, OAMS_TRADITIONAL_GIS_ORDER);
        if (OSRSetFromUserInput(s, crs) != OGRERR_NONE || GDALSetSpatialRef(ds, s) != CE_None)
            rc = -1;
        OSRDestroySpatialReference(s);
    }
    if (gt) {
        double g[6];
        memcpy(g, gt, sizeof g);
        if (GDALSetGeoTransform(ds, g) != CE_None)
            rc = -1;
    }
    if (!isnan(nodata))
        GDALSetRasterNoDataValue(b, nodata);
    if (GDALRasterIO(b, GF_Write, 0, 0, w, h, (void *)(size_t)v, w, h, GDT_Float32, 0, 0)
        != CE_None)
        rc = -1;
    GDALClose(ds);
    return rc;
}

static int same_crs(const char *wkt_a, const char *wkt_b)
{
    OGRSpatialReferenceH a = OSRNewSpatialReference(NULL), b = OSRNewSpatialReference(NULL);
    int same = 0;
    if (wkt_a && wkt_b && OSRSetFromUserInput(a, wkt_a) == OGRERR_NONE
        && OSRSetFromUserInput(b, wkt_b) == OGRERR_NONE)
        same = OSRIsSame(a, b);
    OSRDestroySpatialReference(a);
    OSRDestroySpatialReference(b);
    return same;
}

static double wgs84_parallel_arc(double lat_deg, double dlon_deg)
{
    const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2.0 - f);
    double phi = lat_deg * TEST_PI / 180.0, s = sin(phi);
    return a * cos(phi) / sqrt(1.0 - e2 * s * s) * dlon_deg * TEST_PI / 180.0;
}

static double wgs84_meridian_arc(double lat_deg, double dlat_deg)
{
    const double a = 6378137.0, f = 1.0 / 298.257223563, e2 = f * (2.0 - f);
    double phi = lat_deg * TEST_PI / 180.0, s = sin(phi);
    return a * (1.0 - e2) / pow(1.0 - e2 * s * s, 1.5) * dlat_deg * TEST_PI / 180.0;
}

/* ------------------------------------------------------------------ */

static void test_geographic_metrics(void)
{
    const double cell = 1.0 / 1200.0; /* 3 arc-seconds */
    float v[6] = {1, 2, 3, 4, 5, 6};
    double gt0[6] = {10.0, cell, 0.0, cell / 2.0, 0.0, -cell};        /* row 0 centred on 0 */
    double gt60[6] = {10.0, cell, 0.0, 60.0 + cell / 2.0, 0.0, -cell}; /* row 0 centred on 60 */
    tsio_raster r;
    tsio_err err;
    ts_grid_metrics m, *pm;

    CHECK(make_tif(tp("geo0.tif"), 3, 2, v, "EPSG:4326", gt0, NAN) == 0);
    CHECK(make_tif(tp("geo60.tif"), 3, 2, v, "EPSG:4326", gt60, NAN) == 0);

    CHECK(tsio_read_raster(tp("geo0.tif"), 1, &r, &err) == 0);
    CHECK(r.geo.is_geographic == 1);
    CHECK(r.geo.wkt && strstr(r.geo.wkt, "GEOGCRS"));
    CHECK(r.geo.has_gt && fabs(r.geo.gt[0] - 10.0) < 1e-12); /* x is longitude */
    pm = (ts_grid_metrics *)tsio_metrics(&r, &m);
    CHECK(pm == &m && m.dx == r.dx_m && m.dy == r.dy_m);
    if (r.dx_m && r.dy_m) {
        CHECK_NEAR(r.dx_m[0], 111319.49079327357 / 1200.0, 0.01);
        CHECK_NEAR(r.dx_m[0], wgs84_parallel_arc(0.0, cell), 0.01);
        CHECK_NEAR(r.dy_m[0], 110574.3 / 1200.0, 0.01);
        CHECK_NEAR(r.dy_m[0], wgs84_meridian_arc(0.0, cell), 0.01);
        CHECK(r.dx_m[1] > 0.0 && r.dx_m[1] <= r.dx_m[0]);
    }
    tsio_raster_free(&r);
    CHECK(r.r.data == NULL && r.dx_m == NULL && r.geo.wkt == NULL);

    CHECK(tsio_read_raster(tp("geo60.tif"), 1, &r, &err) == 0);
    if (r.dx_m && r.dy_m) {
        CHECK_NEAR(r.dx_m[0], wgs84_parallel_arc(60.0, cell), 0.01);
        CHECK_NEAR(r.dx_m[0], 55800.0 / 1200.0, 0.01); /* 46.50 m */
        CHECK_NEAR(r.dy_m[0], wgs84_meridian_arc(60.0, cell), 0.01);
        CHECK_NEAR(r.dx_m[1], wgs84_parallel_arc(60.0 - cell, cell), 0.01);
    } else {
        CHECK(!"no metrics for a geographic raster");
    }
    tsio_raster_free(&r);
}

static void test_projected_metrics(void)
{
    float v[6] = {1, 2, 3, 4, 5, 6};
    double gt_utm[6] = {500000.0, 30.0, 0.0, 5000000.0, 0.0, -30.0};
    double gt_ft[6] = {6000000.0, 100.0, 0.0, 2000000.0, 0.0, -100.0};
    tsio_raster r;
    tsio_err err;
    ts_grid_metrics m;

    CHECK(make_tif(tp("utm.tif"), 3, 2, v, "EPSG:32633", gt_utm, NAN) == 0);
    CHECK(tsio_read_raster(tp("utm.tif"), 1, &r, &err) == 0);
    CHECK(r.geo.is_geographic == 0);
    CHECK(tsio_metrics(&r, &m) == &m);
    if (r.dx_m) {
        CHECK_NEAR(r.dx_m[0], 30.0, 1e-9);
        CHECK_NEAR(r.dy_m[1], 30.0, 1e-9);
    }
    CHECK_NEAR(r.vertical_scale, 1.0, 0.0);
    tsio_raster_free(&r);

    /* California zone 3 in US survey feet */
    CHECK(make_tif(tp("ftus.tif"), 3, 2, v, "EPSG:2227", gt_ft, NAN) == 0);
    CHECK(tsio_read_raster(tp("ftus.tif"), 1, &r, &err) == 0);
    if (r.dx_m) {
        CHECK_NEAR(r.dx_m[0], 100.0 * 1200.0 / 3937.0, 1e-6);
        CHECK_NEAR(r.dy_m[1], 30.48006, 1e-5);
    } else {
        CHECK(!"no metrics for EPSG:2227");
    }
    CHECK_NEAR(r.vertical_scale, 1.0, 0.0);
    tsio_raster_free(&r);

    /* compound CRS with a vertical axis in US survey feet (NAVD88 ftUS) */
    CHECK(make_tif(tp("compd.tif"), 3, 2, v, "EPSG:2227+6360", gt_ft, NAN) == 0);
    CHECK(tsio_read_raster(tp("compd.tif"), 1, &r, &err) == 0);
    CHECK_NEAR(r.vertical_scale, 1200.0 / 3937.0, 1e-9);
    CHECK_NEAR(TS_PIX(&r.r, 2, 1), 6.0 * 1200.0 / 3937.0, 1e-5);
    if (r.dx_m)
        CHECK_NEAR(r.dx_m[0], 30.48006, 1e-5);
    tsio_raster_free(&r);
}

static void test_no_crs(void)
{
    float v[6] = {1, 2, 3, 4, 5, 6};
    tsio_raster r;
    tsio_err err;
    ts_grid_metrics m;

    CHECK(make_tif(tp("plain.tif"), 3, 2, v, NULL, NULL, NAN) == 0);
    CHECK(tsio_read_raster(tp("plain.tif"), 1, &r, &err) == 0);
    CHECK(r.dx_m == NULL && r.dy_m == NULL);
    CHECK(tsio_metrics(&r, &m) == NULL);
    CHECK(r.geo.wkt == NULL);
    CHECK(r.geo.has_gt == 0);
    CHECK(r.geo.gt[0] == 0.0 && r.geo.gt[1] == 1.0 && r.geo.gt[5] == 1.0);
    CHECK(r.r.width == 3 && r.r.height == 2 && r.r.stride >= 3);
    CHECK(TS_PIX(&r.r, 1, 1) == 5.0f);
    tsio_raster_free(&r);
}

static void test_nodata_scale_units(void)
{
    float v[6] = {1.5f, -9999.0f, NAN, 4.0f, INFINITY, 6.0f};
    double gt[6] = {500000.0, 30.0, 0.0, 5000000.0, 0.0, -30.0};
    tsio_raster r;
    tsio_err err;
    GDALDatasetH ds;

    CHECK(make_tif(tp("nd.tif"), 3, 2, v, "EPSG:32633", gt, -9999.0) == 0);
    CHECK(tsio_read_raster(tp("nd.tif"), 1, &r, &err) == 0);
    CHECK(r.has_nodata == 1 && r.nodata == -9999.0);
    CHECK(TS_PIX(&r.r, 0, 0) == 1.5f);
    CHECK(isnan(TS_PIX(&r.r, 1, 0)));
    CHECK(isnan(TS_PIX(&r.r, 2, 0)));
    CHECK(TS_PIX(&r.r, 0, 1) == 4.0f);
    CHECK(isnan(TS_PIX(&r.r, 1, 1)));
    CHECK(TS_PIX(&r.r, 2, 1) == 6.0f);
    tsio_raster_free(&r);

    /* scale/offset and a band unit in feet */
    CHECK(make_tif(tp("ft.tif"), 3, 2, v, "EPSG:32633", gt, -9999.0) == 0);
    ds = GDALOpen(tp("ft.tif"), GA_Update);
    CHECK(ds != NULL);
    if (ds) {
        GDALRasterBandH b = GDALGetRasterBand(ds, 1);
        GDALSetRasterScale(b, 2.0);
        GDALSetRasterOffset(b, 10.0);
        GDALSetRasterUnitType(b, "ft");
        GDALClose(ds);
    }
    CHECK(tsio_read_raster(tp("ft.tif"), 1, &r, &err) == 0);
    CHECK_NEAR(r.vertical_scale, 0.3048, 1e-12);
    CHECK_NEAR(TS_PIX(&r.r, 0, 0), (1.5 * 2.0 + 10.0) * 0.3048, 1e-5);
    CHECK_NEAR(TS_PIX(&r.r, 2, 1), (6.0 * 2.0 + 10.0) * 0.3048, 1e-5);
    CHECK(isnan(TS_PIX(&r.r, 1, 0))); /* nodata compares before scaling */
    tsio_raster_free(&r);

    /* US survey feet band unit */
    ds = GDALOpen(tp("ft.tif"), GA_Update);
    if (ds) {
        GDALSetRasterUnitType(GDALGetRasterBand(ds, 1), "US survey foot");
        GDALClose(ds);
    }
    CHECK(tsio_read_raster(tp("ft.tif"), 1, &r, &err) == 0);
    CHECK_NEAR(r.vertical_scale, 1200.0 / 3937.0, 1e-12);
    tsio_raster_free(&r);

    /* a mask band: masked cells become NaN */
    CHECK(make_tif(tp("mask.tif"), 3, 2, v, NULL, NULL, NAN) == 0);
    ds = GDALOpen(tp("mask.tif"), GA_Update);
    if (ds) {
        unsigned char m[6] = {255, 255, 255, 0, 255, 255};
        GDALRasterBandH b = GDALGetRasterBand(ds, 1);
        CHECK(GDALCreateMaskBand(b, GMF_PER_DATASET) == CE_None);
        CHECK(GDALRasterIO(GDALGetMaskBand(b), GF_Write, 0, 0, 3, 2, m, 3, 2, GDT_Byte, 0, 0)
              == CE_None);
        GDALClose(ds);
    }
    CHECK(tsio_read_raster(tp("mask.tif"), 1, &r, &err) == 0);
    CHECK(TS_PIX(&r.r, 0, 0) == 1.5f);
    CHECK(isnan(TS_PIX(&r.r, 0, 1))); /* masked */
    CHECK(TS_PIX(&r.r, 1, 0) == -9999.0f); /* no nodata declared here */
    tsio_raster_free(&r);
}

static void test_read_errors(void)
{
    float nd[4] = {-9999.0f, -9999.0f, NAN, -9999.0f};
    float v[4] = {1, 2, 3, 4};
    double rot[6] = {0.0, 30.0, 5.0, 100.0, 5.0, -30.0};
    tsio_raster r;
    tsio_err err;
    const char *p;
    FILE *fp;

    p = tp("missing.tif");
    CHECK(tsio_read_raster(p, 1, &r, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "no such file"));
    CHECK(r.r.data == NULL && r.geo.wkt == NULL);

    p = tp("notes.txt");
    fp = fopen(p, "w");
    CHECK(fp != NULL);
    if (fp) {
        fputs("this is not a raster\nreally not\n", fp);
        fclose(fp);
    }
    CHECK(tsio_read_raster(p, 1, &r, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "not a raster"));

    p = tp("allnd.tif");
    CHECK(make_tif(p, 2, 2, nd, NULL, NULL, -9999.0) == 0);
    CHECK(tsio_read_raster(p, 1, &r, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "every cell is nodata"));
    CHECK(r.r.data == NULL);

    p = tp("rot.tif");
    CHECK(make_tif(p, 2, 2, v, "EPSG:32633", rot, NAN) == 0);
    CHECK(tsio_read_raster(p, 1, &r, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "rotated geotransforms are not supported"));

    p = tp("plain.tif");
    CHECK(tsio_read_raster(p, 2, &r, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "band 2"));
    CHECK(tsio_read_raster(p, 0, &r, &err) == -1);
    CHECK(good_msg(&err, p));
}

static void test_write_raster(void)
{
    float v[12] = {1, 2, 3, 4, 5, NAN, 7, 8, 9, 10, 11, NAN};
    double gt[6] = {500000.0, 30.0, 0.0, 5000000.0, 0.0, -30.0};
    ts_raster view;
    tsio_raster src, back;
    tsio_write_opts opts;
    tsio_err err;
    const char *p;
    int before;

    view.width = 4;
    view.height = 3;
    view.stride = 4;
    view.data = v;
    CHECK(make_tif(tp("src.tif"), 4, 3, v, "EPSG:32633", gt, -9999.0) == 0);
    CHECK(tsio_read_raster(tp("src.tif"), 1, &src, &err) == 0);

    /* float GTiff round trip (written twice: overwriting works) */
    memset(&opts, 0, sizeof opts);
    p = tp("out.tif");
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -32768.0, &err) == 0);
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -32768.0, &err) == 0);
    CHECK(no_tmp_files());
    CHECK(tsio_read_raster(p, 1, &back, &err) == 0);
    CHECK(back.has_nodata && back.nodata == -32768.0);
    CHECK(back.geo.has_gt && memcmp(back.geo.gt, gt, sizeof gt) == 0);
    CHECK(same_crs(back.geo.wkt, src.geo.wkt));
    CHECK(isnan(TS_PIX(&back.r, 1, 1)) && isnan(TS_PIX(&back.r, 3, 2)));
    CHECK(TS_PIX(&back.r, 2, 2) == 11.0f && TS_PIX(&back.r, 0, 0) == 1.0f);
    tsio_raster_free(&back);

    /* a directory that does not exist: clean failure, nothing left behind */
    before = count_entries();
    p = tp("no/such/dir/out.tif");
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == -1);
    CHECK(good_msg(&err, p));
    CHECK(count_entries() == before);

    /* creation options */
    {
        const char *good[] = {"COMPRESS=DEFLATE", NULL};
        const char *bad[] = {"BOGUS=1", NULL};
        GDALDatasetH ds;
        opts.create_options = good;
        p = tp("deflate.tif");
        CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == 0);
        ds = GDALOpen(p, GA_ReadOnly);
        CHECK(ds != NULL);
        if (ds) {
            const char *c = GDALGetMetadataItem(ds, "COMPRESSION", "IMAGE_STRUCTURE");
            CHECK(c && strcmp(c, "DEFLATE") == 0);
            GDALClose(ds);
        }
        opts.create_options = bad;
        p = tp("bogus.tif");
        before = count_entries();
        CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == -1);
        CHECK(good_msg(&err, p) && msg_has(&err, "BOGUS"));
        CHECK(!file_exists(p));
        CHECK(count_entries() == before);
        opts.create_options = NULL;
    }

    /* unknown format, VRT refused */
    opts.format = "NoSuchFormat";
    p = tp("x.tif");
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "unknown output format NoSuchFormat"));
    opts.format = NULL;
    p = tp("x.vrt");
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == -1);
    CHECK(good_msg(&err, p));
    CHECK(!file_exists(p));

    /* AAIGrid goes through MEM + CreateCopy */
    p = tp("grid.asc");
    CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == 0);
    CHECK(file_exists(p));
    CHECK(no_tmp_files());
    CHECK(tsio_read_raster(p, 1, &back, &err) == 0);
    CHECK(back.r.width == 4 && back.r.height == 3);
    CHECK(TS_PIX(&back.r, 2, 2) == 11.0f && isnan(TS_PIX(&back.r, 1, 1)));
    CHECK_NEAR(back.geo.gt[0], 500000.0, 1e-6);
    CHECK_NEAR(back.geo.gt[1], 30.0, 1e-9);
    tsio_raster_free(&back);

    /* Byte raster (explicit format) */
    {
        unsigned char b[12] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 255};
        GDALDatasetH ds;
        opts.format = "GTiff";
        p = tp("mask.byte");
        CHECK(tsio_write_byte(p, &opts, &src.geo, b, 255, &err) == 0);
        ds = GDALOpen(p, GA_ReadOnly);
        CHECK(ds != NULL);
        if (ds) {
            int ok = 0;
            unsigned char rb[12];
            GDALRasterBandH band = GDALGetRasterBand(ds, 1);
            CHECK(GDALGetRasterDataType(band) == GDT_Byte);
            CHECK(GDALGetRasterNoDataValue(band, &ok) == 255.0 && ok);
            CHECK(GDALRasterIO(band, GF_Read, 0, 0, 4, 3, rb, 4, 3, GDT_Byte, 0, 0) == CE_None);
            CHECK(memcmp(rb, b, sizeof b) == 0);
            GDALClose(ds);
        }
        opts.format = NULL;
        /* Float32 data refused by PNG */
        p = tp("float.png");
        CHECK(tsio_write_float(p, &opts, &src.geo, &view, -9999.0, &err) == -1);
        CHECK(good_msg(&err, p));
        CHECK(!file_exists(p));
    }

    /* RGB PNG */
    {
        unsigned char rgb[3 * 4 * 3];
        int i;
        GDALDatasetH ds;
        for (i = 0; i < (int)sizeof rgb; i++)
            rgb[i] = (unsigned char)(i * 7);
        p = tp("preview.png");
        CHECK(tsio_write_png_rgb(p, 4, 3, rgb, &err) == 0);
        CHECK(tsio_write_png_rgb(p, 4, 3, rgb, &err) == 0);
        CHECK(no_tmp_files());
        CHECK(!file_exists(tp("preview.png.aux.xml")));
        ds = GDALOpen(p, GA_ReadOnly);
        CHECK(ds != NULL);
        if (ds) {
            unsigned char rb[3 * 4 * 3];
            CHECK(GDALGetRasterCount(ds) == 3);
            CHECK(strcmp(GDALGetDriverShortName(GDALGetDatasetDriver(ds)), "PNG") == 0);
            CHECK(GDALDatasetRasterIO(ds, GF_Read, 0, 0, 4, 3, rb, 4, 3, GDT_Byte, 3, NULL, 3,
                                      12, 1)
                  == CE_None);
            CHECK(memcmp(rb, rgb, sizeof rgb) == 0);
            GDALClose(ds);
        }
        p = tp("nodir/preview.png");
        CHECK(tsio_write_png_rgb(p, 4, 3, rgb, &err) == -1);
        CHECK(good_msg(&err, p));
    }
    CHECK(no_tmp_files());
    tsio_raster_free(&src);
}

/* Hand-built feature graph: 2 nodes, 1 ridge path of 3 vertices. */
static void make_features(ts_features *f, ts_feature_node *nodes, ts_feature_path *path,
                          ts_feature_vertex *verts)
{
    memset(f, 0, sizeof *f);
    nodes[0].x = 0, nodes[0].y = 0, nodes[0].z = 10.0f, nodes[0].degree = 1;
    nodes[0].kind = TS_RIDGE;
    nodes[1].x = 2, nodes[1].y = 2, nodes[1].z = 20.0f, nodes[1].degree = 3;
    nodes[1].kind = TS_RIDGE;
    verts[0].x = 0, verts[0].y = 0, verts[0].z = 10.0f;
    verts[1].x = 1, verts[1].y = 1, verts[1].z = 15.0f;
    verts[2].x = 2, verts[2].y = 2, verts[2].z = 20.0f;
    memset(path, 0, sizeof *path);
    path->kind = TS_RIDGE;
    path->node_a = 0;
    path->node_b = 1;
    path->first = 0;
    path->count = 3;
    path->zmin = 10.0f;
    path->zmax = 20.0f;
    path->zmean = 15.0f;
    f->width = 4;
    f->height = 3;
    f->n_nodes = 2;
    f->n_paths = 1;
    f->n_verts = 3;
    f->nodes = nodes;
    f->paths = path;
    f->verts = verts;
}

static void check_paths_layer(OGRLayerH l, const char *wkt, int with_metrics)
{
    OGRFeatureH ft;
    OGRFeatureDefnH d;
    OGRSpatialReferenceH s;
    CHECK(l != NULL);
    if (!l)
        return;
    CHECK(OGR_L_GetFeatureCount(l, TRUE) == 1);
    s = OGR_L_GetSpatialRef(l);
    if (wkt) {
        char *w = NULL;
        CHECK(s != NULL);
        if (s && OSRExportToWkt(s, &w) == OGRERR_NONE)
            CHECK(same_crs(w, wkt));
        CPLFree(w);
    }
    OGR_L_ResetReading(l);
    ft = OGR_L_GetNextFeature(l);
    CHECK(ft != NULL);
    if (!ft)
        return;
    d = OGR_L_GetLayerDefn(l);
    {
        OGRGeometryH g = OGR_F_GetGeometryRef(ft);
        CHECK(g && wkbFlatten(OGR_G_GetGeometryType(g)) == wkbLineString);
        CHECK(g && OGR_G_GetPointCount(g) == 3);
        if (g) {
            CHECK_NEAR(OGR_G_GetX(g, 0), 500015.0, 1e-6);
            CHECK_NEAR(OGR_G_GetY(g, 0), 4999985.0, 1e-6);
            CHECK_NEAR(OGR_G_GetX(g, 2), 500075.0, 1e-6);
            CHECK_NEAR(OGR_G_GetY(g, 2), 4999925.0, 1e-6);
        }
    }
    {
        int i_kind = OGR_FD_GetFieldIndex(d, "kind");
        int i_lm = OGR_FD_GetFieldIndex(d, "length_m");
        int i_lc = OGR_FD_GetFieldIndex(d, "length_cells");
        int i_mean = OGR_FD_GetFieldIndex(d, "mean_elev");
        int i_min = OGR_FD_GetFieldIndex(d, "min_elev");
        int i_max = OGR_FD_GetFieldIndex(d, "max_elev");
        int i_s = OGR_FD_GetFieldIndex(d, "start_kind");
        int i_e = OGR_FD_GetFieldIndex(d, "end_kind");
        CHECK(i_kind >= 0 && i_lm >= 0 && i_lc >= 0 && i_mean >= 0 && i_min >= 0 && i_max >= 0
              && i_s >= 0 && i_e >= 0);
        if (i_kind >= 0 && i_lm >= 0 && i_lc >= 0 && i_mean >= 0 && i_min >= 0 && i_max >= 0
            && i_s >= 0 && i_e >= 0) {
            CHECK(strcmp(OGR_F_GetFieldAsString(ft, i_kind), "ridge") == 0);
            if (with_metrics)
                CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_lm), 2.0 * sqrt(2.0) * 30.0, 1e-9);
            else
                CHECK(!OGR_F_IsFieldSetAndNotNull(ft, i_lm));
            CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_lc), 2.0 * sqrt(2.0), 1e-9);
            CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_mean), 15.0, 1e-9);
            CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_min), 10.0, 1e-9);
            CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_max), 20.0, 1e-9);
            CHECK(strcmp(OGR_F_GetFieldAsString(ft, i_s), "endpoint") == 0);
            CHECK(strcmp(OGR_F_GetFieldAsString(ft, i_e), "branch") == 0);
        }
    }
    OGR_F_Destroy(ft);
}

static void check_nodes_layer(OGRLayerH l)
{
    OGRFeatureH ft;
    int n = 0, branches = 0;
    CHECK(l != NULL);
    if (!l)
        return;
    CHECK(OGR_L_GetFeatureCount(l, TRUE) == 2);
    OGR_L_ResetReading(l);
    while ((ft = OGR_L_GetNextFeature(l)) != NULL) {
        OGRFeatureDefnH d = OGR_L_GetLayerDefn(l);
        OGRGeometryH g = OGR_F_GetGeometryRef(ft);
        int i_kind = OGR_FD_GetFieldIndex(d, "kind"), i_deg = OGR_FD_GetFieldIndex(d, "degree");
        int i_elev = OGR_FD_GetFieldIndex(d, "elev"), i_feat = OGR_FD_GetFieldIndex(d, "feature");
        CHECK(g && wkbFlatten(OGR_G_GetGeometryType(g)) == wkbPoint);
        CHECK(i_kind >= 0 && i_deg >= 0 && i_elev >= 0 && i_feat >= 0);
        if (i_kind >= 0 && i_deg >= 0 && i_elev >= 0 && i_feat >= 0) {
            int deg = OGR_F_GetFieldAsInteger(ft, i_deg);
            const char *kind = OGR_F_GetFieldAsString(ft, i_kind);
            CHECK(strcmp(OGR_F_GetFieldAsString(ft, i_feat), "ridge") == 0);
            if (deg == 3) {
                branches++;
                CHECK(strcmp(kind, "branch") == 0);
                CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_elev), 20.0, 1e-9);
                if (g) {
                    CHECK_NEAR(OGR_G_GetX(g, 0), 500075.0, 1e-6);
                    CHECK_NEAR(OGR_G_GetY(g, 0), 4999925.0, 1e-6);
                }
            } else {
                CHECK(deg == 1 && strcmp(kind, "endpoint") == 0);
                CHECK_NEAR(OGR_F_GetFieldAsDouble(ft, i_elev), 10.0, 1e-9);
            }
        }
        n++;
        OGR_F_Destroy(ft);
    }
    CHECK(n == 2 && branches == 1);
}

static void test_features(void)
{
    ts_features f;
    ts_feature_node nodes[2];
    ts_feature_path path;
    ts_feature_vertex verts[3];
    double dx[3] = {30, 30, 30}, dy[3] = {30, 30, 30};
    ts_grid_metrics m;
    tsio_georef geo;
    tsio_err err;
    OGRSpatialReferenceH s = OSRNewSpatialReference(NULL);
    char *wkt = NULL;
    const char *const wkt2[] = {"FORMAT=WKT2_2018", NULL};
    GDALDatasetH ds;
    const char *p;

    m.dx = dx;
    m.dy = dy;
    make_features(&f, nodes, &path, verts);
    OSRImportFromEPSG(s, 32633);
    OSRExportToWktEx(s, &wkt, wkt2);
    OSRDestroySpatialReference(s);
    memset(&geo, 0, sizeof geo);
    geo.width = 4;
    geo.height = 3;
    geo.gt[0] = 500000.0, geo.gt[1] = 30.0, geo.gt[3] = 5000000.0, geo.gt[5] = -30.0;
    geo.has_gt = 1;
    geo.wkt = wkt;

    /* GeoPackage: both layers in one file (written twice: overwrite) */
    p = tp("features.gpkg");
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == 0);
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == 0);
    CHECK(no_tmp_files());
    ds = GDALOpenEx(p, GDAL_OF_VECTOR, NULL, NULL, NULL);
    CHECK(ds != NULL);
    if (ds) {
        CHECK(GDALDatasetGetLayerCount(ds) == 2);
        check_paths_layer(GDALDatasetGetLayerByName(ds, "paths"), wkt, 1);
        check_nodes_layer(GDALDatasetGetLayerByName(ds, "nodes"));
        GDALClose(ds);
    }

    /* GeoJSON: nodes in a sibling file; no metrics -> null length_m */
    p = tp("features.geojson");
    CHECK(tsio_write_features(p, &geo, &f, NULL, &err) == 0);
    CHECK(no_tmp_files());
    ds = GDALOpenEx(p, GDAL_OF_VECTOR, NULL, NULL, NULL);
    CHECK(ds != NULL);
    if (ds) {
        CHECK(GDALDatasetGetLayerCount(ds) == 1);
        check_paths_layer(GDALDatasetGetLayer(ds, 0), wkt, 0);
        GDALClose(ds);
    }
    ds = GDALOpenEx(tp("features_nodes.geojson"), GDAL_OF_VECTOR, NULL, NULL, NULL);
    CHECK(ds != NULL);
    if (ds) {
        check_nodes_layer(GDALDatasetGetLayer(ds, 0));
        GDALClose(ds);
    }

    /* Shapefile: sidecar files renamed too */
    p = tp("features.shp");
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == 0);
    CHECK(no_tmp_files());
    CHECK(file_exists(tp("features.dbf")) && file_exists(tp("features.prj")));
    CHECK(file_exists(tp("features_nodes.shp")));
    ds = GDALOpenEx(p, GDAL_OF_VECTOR, NULL, NULL, NULL);
    CHECK(ds != NULL);
    if (ds) {
        OGRLayerH l = GDALDatasetGetLayer(ds, 0);
        CHECK(l && OGR_L_GetFeatureCount(l, TRUE) == 1);
        GDALClose(ds);
    }

    /* errors */
    p = tp("features.xyz");
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == -1);
    CHECK(good_msg(&err, p) && msg_has(&err, "cannot tell the vector format from the extension"));
    p = tp("nowhere/features.gpkg");
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == -1);
    CHECK(good_msg(&err, p));
    path.count = 4; /* beyond n_verts */
    p = tp("bad.gpkg");
    CHECK(tsio_write_features(p, &geo, &f, &m, &err) == -1);
    CHECK(good_msg(&err, p));
    CHECK(!file_exists(p));
    CHECK(no_tmp_files());

    /* georef copy */
    {
        tsio_georef copy;
        CHECK(tsio_georef_copy(&geo, &copy) == 0);
        CHECK(copy.wkt && copy.wkt != geo.wkt && strcmp(copy.wkt, geo.wkt) == 0);
        CHECK(copy.width == 4 && copy.gt[1] == 30.0 && copy.has_gt == 1);
        tsio_georef_free(&copy);
        CHECK(copy.wkt == NULL);
    }
    CPLFree(wkt);
}

/* The sun's frame of a grid (tsio_georef_sun_frame) against formulas written
 * here: a geographic grid's cell latitudes and north 0; on a UTM grid, the
 * latitude on the central meridian from the meridian arc (WGS 84, k0 0.9996)
 * solved by bisection, north 0 there, and off it the first-order meridian
 * convergence dlon sin(lat) (grid north east of true north, east of the
 * central meridian in the north). */
static double meridian_arc(double phi)
{
    const double a = 6378137.0, f = 1 / 298.257223563, e2 = f * (2 - f), e4 = e2 * e2, e6 = e4 * e2;
    return a * ((1 - e2 / 4 - 3 * e4 / 64 - 5 * e6 / 256) * phi -
                (3 * e2 / 8 + 3 * e4 / 32 + 45 * e6 / 1024) * sin(2 * phi) +
                (15 * e4 / 256 + 45 * e6 / 1024) * sin(4 * phi) - (35 * e6 / 3072) * sin(6 * phi));
}

static void test_sun_frame(void)
{
    tsio_georef g;
    tsio_err err;
    ts_raster lat, north;
    float lat_d[12], north_d[12];
    int x, y;
    memset(&g, 0, sizeof g);
    lat = ts_raster_wrap(lat_d, 4, 3, 4);
    north = ts_raster_wrap(north_d, 4, 3, 4);
    /* geographic: 0.5 degree cells from 10E 50N, averaged by 2 -> 1 degree cells */
    {
        OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
        char *wkt = NULL;
        OSRSetFromUserInput(srs, "EPSG:4326");
        OSRExportToWkt(srs, &wkt);
        g.width = 8;
        g.height = 6;
        g.has_gt = 1;
        g.gt[0] = 10.0, g.gt[1] = 0.5, g.gt[2] = 0, g.gt[3] = 50.0, g.gt[4] = 0, g.gt[5] = -0.5;
        free(g.wkt);
        g.wkt = strdup(wkt);
        CPLFree(wkt);
        OSRDestroySpatialReference(srs);
    }
    CHECK(tsio_georef_sun_frame(&g, 2, &lat, &north, &err) == 0);
    for (y = 0; y < 3; y++)
        for (x = 0; x < 4; x++) {
            CHECK_NEAR(TS_PIX(&lat, x, y), 50.0 - (y + 0.5), 1e-5);
            CHECK_NEAR(TS_PIX(&north, x, y), 0.0, 1e-6);
        }
    /* UTM 32N: the central meridian (9E) at x = 500000 */
    {
        OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
        char *wkt = NULL;
        OSRSetFromUserInput(srs, "EPSG:32632");
        OSRExportToWkt(srs, &wkt);
        free(g.wkt);
        g.wkt = strdup(wkt);
        CPLFree(wkt);
        OSRDestroySpatialReference(srs);
    }
    g.width = 4;
    g.height = 3;
    g.gt[0] = 500000.0 - 500.0; /* cell 0's centre on the central meridian */
    g.gt[1] = 1000.0;
    g.gt[3] = 5000000.0 + 1500.0;
    g.gt[5] = -1000.0;
    CHECK(tsio_georef_sun_frame(&g, 1, &lat, &north, &err) == 0);
    for (y = 0; y < 3; y++) {
        double northing = 5000000.0 + 1500.0 - (y + 0.5) * 1000.0, lo = 0, hi = 1.5, phi;
        int it;
        for (it = 0; it < 200; it++) { /* M(phi) = northing / k0 */
            double mid = 0.5 * (lo + hi);
            if (meridian_arc(mid) < northing / 0.9996)
                lo = mid;
            else
                hi = mid;
        }
        phi = 0.5 * (lo + hi);
        CHECK_NEAR(TS_PIX(&lat, 0, y), phi * 180 / TEST_PI, 1e-5);
        CHECK_NEAR(TS_PIX(&north, 0, y), 0.0, 1e-4);
        /* 3 km east: convergence dlon sin(lat), dlon = 3 km over the parallel's radius */
        {
            double dlon = 3000.0 / 0.9996 / (6378137.0 * cos(phi)) * 180 / TEST_PI;
            CHECK_NEAR(TS_PIX(&north, 3, y), dlon * sin(phi), 0.002);
            CHECK(TS_PIX(&north, 3, y) > 0);
        }
    }
    /* no CRS: nothing known */
    free(g.wkt);
    g.wkt = NULL;
    CHECK(tsio_georef_sun_frame(&g, 1, &lat, &north, &err) == 1);
}

int main(void)
{
    snprintf(tmpdir, sizeof tmpdir, "/tmp/test_tsio.XXXXXX");
    if (!mkdtemp(tmpdir)) {
        perror("mkdtemp");
        return 2;
    }
    GDALAllRegister();
    CPLPushErrorHandler(CPLQuietErrorHandler);

    test_geographic_metrics();
    test_projected_metrics();
    test_no_crs();
    test_nodata_scale_units();
    test_read_errors();
    test_write_raster();
    test_features();
    test_sun_frame();

    CPLPopErrorHandler();
    VSIRmdirRecursive(tmpdir);
    GDALDestroyDriverManager();
    OSRCleanup();
    printf("%d passed, %d failed\n", n_pass, n_fail);
    return n_fail ? 1 : 0;
}
