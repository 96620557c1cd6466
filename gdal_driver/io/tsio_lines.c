/*
 * tsio_lines.c - a sketch drawn as lines, read from an OGR layer: each
 * line's points in the output's CRS, its kind (ridge, valley, river) and the
 * heights wanted along it (a numeric field, or the lines' Z values).
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1

#include "tsio_internal.h"

#include <ctype.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cpl_conv.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_api.h>
#include <ogr_srs_api.h>

int tsio_is_lines(const char *path)
{
    GDALDatasetH ds;
    int lines = 0;
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    ds = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_VECTOR | GDAL_OF_READONLY, NULL, NULL, NULL);
    if (ds) {
        lines = GDALGetRasterCount(ds) == 0 && GDALDatasetGetLayerCount(ds) > 0;
        GDALClose(ds);
    }
    CPLErrorReset();
    CPLPopErrorHandler();
    return lines;
}

static int is_line_type(OGRwkbGeometryType t)
{
    t = wkbFlatten(t);
    return t == wkbLineString || t == wkbMultiLineString || t == wkbCircularString ||
           t == wkbCompoundCurve || t == wkbMultiCurve;
}

/* "ridge", "valley" or "river" (any case, spaces around): TS_RIDGE or
 * TS_VALLEY (a river is a valley whose floor descends all the way, as every
 * drawn valley's does); 0 for anything else. */
static int kind_of(const char *s)
{
    char w[32];
    size_t n = 0;
    while (*s && isspace((unsigned char)*s))
        s++;
    while (*s && n + 1 < sizeof w)
        w[n++] = (char)tolower((unsigned char)*s++);
    while (n && isspace((unsigned char)w[n - 1]))
        n--;
    w[n] = '\0';
    if (!strcmp(w, "ridge") || !strcmp(w, "ridges"))
        return TS_RIDGE;
    if (!strcmp(w, "valley") || !strcmp(w, "valleys") || !strcmp(w, "river") ||
        !strcmp(w, "rivers"))
        return TS_VALLEY;
    return 0;
}

static int lines_push(tsio_lines *l, int kind, OGRGeometryH g, double height, int use_z)
{
    int n = OGR_G_GetPointCount(g), i;
    ts_sketch_line *nl;
    double *x, *y, *z;
    if (n < 2)
        return 0;
    nl = realloc(l->lines, (l->n + 1) * sizeof *nl);
    if (!nl)
        return -1;
    l->lines = nl;
    x = malloc((size_t)n * sizeof *x);
    y = malloc((size_t)n * sizeof *y);
    z = malloc((size_t)n * sizeof *z);
    if (!x || !y || !z) {
        free(x);
        free(y);
        free(z);
        return -1;
    }
    for (i = 0; i < n; i++) {
        double pz = 0.0;
        OGR_G_GetPoint(g, i, &x[i], &y[i], &pz);
        z[i] = !isnan(height) ? height : use_z ? pz : NAN;
        if (isfinite(x[i]) && isfinite(y[i])) {
            l->box[0] = fmin(l->box[0], x[i]);
            l->box[1] = fmin(l->box[1], y[i]);
            l->box[2] = fmax(l->box[2], x[i]);
            l->box[3] = fmax(l->box[3], y[i]);
        }
    }
    nl[l->n].kind = kind;
    nl[l->n].n = (size_t)n;
    nl[l->n].x = x;
    nl[l->n].y = y;
    nl[l->n].z = z;
    l->n++;
    return 0;
}

/* The layer: named, or the first whose geometries are lines. */
static OGRLayerH lines_layer(GDALDatasetH ds, const char *path, const char *name, tsio_err *err)
{
    int i, n = GDALDatasetGetLayerCount(ds);
    if (name) {
        OGRLayerH l = GDALDatasetGetLayerByName(ds, name);
        if (!l)
            tsio_errf(err, path, "has no layer \"%s\"", name);
        else if (!is_line_type(OGR_L_GetGeomType(l)) &&
                 wkbFlatten(OGR_L_GetGeomType(l)) != wkbUnknown)
            tsio_errf(err, path, "layer \"%s\" holds %ss, not lines", name,
                      OGRGeometryTypeToName(wkbFlatten(OGR_L_GetGeomType(l))));
        else
            return l;
        return NULL;
    }
    for (i = 0; i < n; i++) {
        OGRLayerH l = GDALDatasetGetLayer(ds, i);
        if (is_line_type(OGR_L_GetGeomType(l)))
            return l;
    }
    for (i = 0; i < n; i++) { /* a layer of mixed geometries: its features decide */
        OGRLayerH l = GDALDatasetGetLayer(ds, i);
        if (wkbFlatten(OGR_L_GetGeomType(l)) == wkbUnknown)
            return l;
    }
    if (n > 0)
        tsio_errf(err, path,
                  "has no layer of lines (its first layer holds %ss): draw the sketch "
                  "as lines",
                  OGRGeometryTypeToName(wkbFlatten(OGR_L_GetGeomType(GDALDatasetGetLayer(ds, 0)))));
    else
        tsio_errf(err, path, "has no layer");
    return NULL;
}

/* One feature's lines (every part of a multi-line, curves made straight). */
static int lines_feature(tsio_lines *out, OGRFeatureH f, OGRCoordinateTransformationH ct,
                         int i_kind, int i_height, const char *kind_field, const char *path,
                         tsio_err *err)
{
    OGRGeometryH g0 = OGR_F_GetGeometryRef(f), g = NULL;
    long long fid = (long long)OGR_F_GetFID(f);
    const char *ks;
    int kind, k, parts, rc = -1, use_z;
    double height = NAN;
    if (!g0 || OGR_G_IsEmpty(g0))
        return 0;
    if (!is_line_type(OGR_G_GetGeometryType(g0))) {
        tsio_errf(err, path, "feature %lld is a %s, not a line: draw the sketch as lines", fid,
                  OGRGeometryTypeToName(wkbFlatten(OGR_G_GetGeometryType(g0))));
        return -1;
    }
    ks = OGR_F_IsFieldSetAndNotNull(f, i_kind) ? OGR_F_GetFieldAsString(f, i_kind) : "";
    if (!(kind = kind_of(ks))) {
        tsio_errf(err, path, "feature %lld: %s is \"%.40s\", not ridge, valley or river", fid,
                  kind_field, ks);
        return -1;
    }
    if (i_height >= 0 && OGR_F_IsFieldSetAndNotNull(f, i_height))
        height = OGR_F_GetFieldAsDouble(f, i_height);
    use_z = i_height < 0 && OGR_G_Is3D(g0);
    g = OGR_G_GetLinearGeometry(g0, 0, NULL);
    if (!g) {
        tsio_errf(err, path, "feature %lld: out of memory", fid);
        return -1;
    }
    if (!OGR_G_IsSimple(g) && wkbFlatten(OGR_G_GetGeometryType(g)) == wkbLineString) {
        tsio_errf(err, path, "feature %lld: the line crosses itself: draw it as lines that meet",
                  fid);
        goto done;
    }
    if (ct && OGR_G_Transform(g, ct) != OGRERR_NONE) {
        tsio_errf(err, path, "feature %lld cannot be transformed to the output's CRS", fid);
        goto done;
    }
    parts = wkbFlatten(OGR_G_GetGeometryType(g)) == wkbLineString ? 0 : OGR_G_GetGeometryCount(g);
    if (!parts && lines_push(out, kind, g, height, use_z) != 0)
        goto oom;
    for (k = 0; k < parts; k++) {
        OGRGeometryH part = OGR_G_GetGeometryRef(g, k);
        if (!OGR_G_IsSimple(part)) {
            tsio_errf(err, path, "feature %lld: a line crosses itself: draw it as lines that meet",
                      fid);
            goto done;
        }
        if (lines_push(out, kind, part, height, use_z) != 0)
            goto oom;
    }
    rc = 0;
    goto done;
oom:
    tsio_errf(err, path, "out of memory");
done:
    OGR_G_DestroyGeometry(g);
    return rc;
}

int tsio_read_lines(const char *path, const char *layer_name, const char *kind_field,
                    const char *height_field, const char *to_wkt, tsio_lines *out, tsio_err *err)
{
    GDALDatasetH ds;
    OGRLayerH layer;
    OGRFeatureDefnH defn;
    OGRFeatureH f;
    OGRSpatialReferenceH src = NULL, dst = NULL;
    OGRCoordinateTransformationH ct = NULL;
    int i_kind, i_height = -1, rc = -1;
    memset(out, 0, sizeof *out);
    out->box[0] = out->box[1] = INFINITY;
    out->box[2] = out->box[3] = -INFINITY;
    kind_field = kind_field ? kind_field : "kind";
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    ds = GDALOpenEx(path, GDAL_OF_VECTOR | GDAL_OF_READONLY, NULL, NULL, NULL);
    if (!ds) {
        tsio_errf(err, path,
                  tsio__path_exists(path, NULL) ? "not a vector dataset GDAL can open"
                                                : "no such file");
        goto done;
    }
    if (!(layer = lines_layer(ds, path, layer_name, err)))
        goto done;
    defn = OGR_L_GetLayerDefn(layer);
    if ((i_kind = OGR_FD_GetFieldIndex(defn, kind_field)) < 0) {
        tsio_errf(err, path, "layer \"%s\" has no field \"%s\" saying ridge, valley or river%s",
                  OGR_L_GetName(layer), kind_field,
                  strcmp(kind_field, "kind") ? "" : " (kind_field names another)");
        goto done;
    }
    if (height_field) {
        OGRFieldType t;
        if ((i_height = OGR_FD_GetFieldIndex(defn, height_field)) < 0) {
            tsio_errf(err, path, "layer \"%s\" has no field \"%s\"", OGR_L_GetName(layer),
                      height_field);
            goto done;
        }
        t = OGR_Fld_GetType(OGR_FD_GetFieldDefn(defn, i_height));
        if (t != OFTReal && t != OFTInteger && t != OFTInteger64) {
            tsio_errf(err, path, "field \"%s\" is not numeric", height_field);
            goto done;
        }
    }
    if (OGR_L_GetSpatialRef(layer)) {
        src = OSRClone(OGR_L_GetSpatialRef(layer));
        OSRSetAxisMappingStrategy(src, OAMS_TRADITIONAL_GIS_ORDER);
        out->wkt = tsio__srs_to_wkt2(src);
        out->is_geographic = OSRIsGeographic(src);
    }
    if (src && to_wkt && to_wkt[0]) {
        dst = tsio__srs_from_wkt(to_wkt);
        ct = dst ? OCTNewCoordinateTransformation(src, dst) : NULL;
        if (!ct) {
            tsio_errf(err, path, "its CRS cannot be transformed to the output's");
            goto done;
        }
        free(out->wkt);
        out->wkt = tsio__srs_to_wkt2(dst);
        out->is_geographic = OSRIsGeographic(dst);
    }
    OGR_L_ResetReading(layer);
    while ((f = OGR_L_GetNextFeature(layer))) {
        int bad = lines_feature(out, f, ct, i_kind, i_height, kind_field, path, err);
        OGR_F_Destroy(f);
        if (bad)
            goto done;
    }
    if (!out->n) {
        tsio_errf(err, path, "layer \"%s\" holds no lines", OGR_L_GetName(layer));
        goto done;
    }
    rc = 0;
done:
    if (ct)
        OCTDestroyCoordinateTransformation(ct);
    if (src)
        OSRDestroySpatialReference(src);
    if (dst)
        OSRDestroySpatialReference(dst);
    if (ds)
        GDALClose(ds);
    CPLErrorReset();
    CPLPopErrorHandler();
    if (rc != 0)
        tsio_lines_free(out);
    return rc;
}

void tsio_lines_to_cells(tsio_lines *l, const tsio_georef *geo)
{
    size_t i, k;
    for (i = 0; i < l->n; i++) {
        double *x = (double *)(uintptr_t)l->lines[i].x, *y = (double *)(uintptr_t)l->lines[i].y;
        for (k = 0; k < l->lines[i].n; k++) {
            x[k] = (x[k] - geo->gt[0]) / geo->gt[1];
            y[k] = (y[k] - geo->gt[3]) / geo->gt[5];
        }
    }
}

void tsio_lines_free(tsio_lines *l)
{
    size_t i;
    if (!l)
        return;
    for (i = 0; i < l->n; i++) {
        free((void *)(uintptr_t)l->lines[i].x);
        free((void *)(uintptr_t)l->lines[i].y);
        free((void *)(uintptr_t)l->lines[i].z);
    }
    free(l->lines);
    free(l->wkt);
    memset(l, 0, sizeof *l);
}
