/*
 * tsio_vector.c - vectors: the feature graph as line and point layers, and
 * label maps read from rasters or polygon layers.
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
/* Vector writing                                                      */
/* ------------------------------------------------------------------ */

static const char *vector_driver_for_ext(const char *ext)
{
    static const struct {
        const char *ext, *driver;
    } table[] = {
        {"gpkg", "GPKG"}, {"shp", "ESRI Shapefile"}, {"geojson", "GeoJSON"}, {"json", "GeoJSON"},
        {"kml", "KML"},   {"fgb", "FlatGeobuf"},     {"sqlite", "SQLite"},   {"gml", "GML"}};
    size_t i;
    for (i = 0; i < sizeof table / sizeof table[0]; i++)
        if (tsio__str_ieq(ext, table[i].ext))
            return table[i].driver;
    return NULL;
}

/* Formats that hold one layer per file. */
static int single_layer_driver(const char *name)
{
    return tsio__str_ieq(name, "ESRI Shapefile") || tsio__str_ieq(name, "GeoJSON") ||
           tsio__str_ieq(name, "FlatGeobuf");
}

static const char *kind_name(int kind)
{
    return kind == TS_RIDGE ? "ridge" : (kind == TS_VALLEY ? "valley" : "unknown");
}

static const char *node_kind_name(int degree)
{
    return degree >= 3 ? "branch" : "endpoint";
}

/* Check indices and coordinates before anything is written. */
static int check_features(const ts_features *f, const char *path, tsio_err *err)
{
    size_t i;
    if ((f->n_nodes && !f->nodes) || (f->n_paths && !f->paths) || (f->n_verts && !f->verts)) {
        tsio_errf(err, path, "the feature graph is missing arrays");
        return -1;
    }
    for (i = 0; i < f->n_paths; i++) {
        const ts_feature_path *p = &f->paths[i];
        size_t k;
        if (p->count < 1 || p->count > f->n_verts || p->first > f->n_verts - p->count) {
            tsio_errf(err, path, "path %zu has invalid vertex indices", i);
            return -1;
        }
        if (p->node_a >= f->n_nodes || p->node_b >= f->n_nodes) {
            tsio_errf(err, path, "path %zu refers to a missing node", i);
            return -1;
        }
        for (k = p->first; k < p->first + p->count; k++) {
            const ts_feature_vertex *v = &f->verts[k];
            if (v->x < 0 || v->y < 0 || v->x >= f->width || v->y >= f->height) {
                tsio_errf(err, path, "path %zu has a vertex outside the %d x %d grid", i, f->width,
                          f->height);
                return -1;
            }
        }
    }
    for (i = 0; i < f->n_nodes; i++) {
        const ts_feature_node *n = &f->nodes[i];
        if (n->x < 0 || n->y < 0 || n->x >= f->width || n->y >= f->height) {
            tsio_errf(err, path, "node %zu lies outside the %d x %d grid", i, f->width, f->height);
            return -1;
        }
    }
    return 0;
}

static int add_field(OGRLayerH layer, const char *name, OGRFieldType type, int *index)
{
    OGRFieldDefnH fd = OGR_Fld_Create(name, type);
    OGRErr e;
    if (!fd)
        return -1;
    e = OGR_L_CreateField(layer, fd, TRUE);
    OGR_Fld_Destroy(fd);
    if (e != OGRERR_NONE)
        return -1;
    /* the field was appended: its index is the last one (its name may
     * have been shortened, e.g. by the Shapefile driver) */
    *index = OGR_FD_GetFieldCount(OGR_L_GetLayerDefn(layer)) - 1;
    return *index >= 0 ? 0 : -1;
}

static void set_real_or_null(OGRFeatureH feat, int idx, double v)
{
    if (isfinite(v))
        OGR_F_SetFieldDouble(feat, idx, v);
    else
        OGR_F_SetFieldNull(feat, idx);
}

typedef struct vec_ctx {
    const char *path;
    const ts_features *f;           /* the PPA's features, or NULL for ... */
    const ts_stream_network *net;   /* ... a stream network */
    const ts_grid_metrics *metrics; /* NULL: no metric lengths */
    double gt[6];
    OGRSpatialReferenceH srs;
    tsio_err *err;
} vec_ctx;

static double cx(const vec_ctx *c, int x, int y)
{
    return c->gt[0] + ((double)x + 0.5) * c->gt[1] + ((double)y + 0.5) * c->gt[2];
}

static double cy(const vec_ctx *c, int x, int y)
{
    return c->gt[3] + ((double)x + 0.5) * c->gt[4] + ((double)y + 0.5) * c->gt[5];
}

/* The length of a chain of cells: in cells, and on the ground with metrics. */
static void chain_length(const vec_ctx *c, const ts_feature_vertex *v, size_t count, double *len_c,
                         double *len_m)
{
    size_t k;
    *len_c = *len_m = 0.0;
    for (k = 1; k < count; k++) {
        int ddx = v[k].x - v[k - 1].x, ddy = v[k].y - v[k - 1].y;
        *len_c += sqrt((double)ddx * ddx + (double)ddy * ddy);
        if (c->metrics) {
            double mx = 0.5 * (c->metrics->dx[v[k].y] + c->metrics->dx[v[k - 1].y]);
            double my = 0.5 * (c->metrics->dy[v[k].y] + c->metrics->dy[v[k - 1].y]);
            *len_m += sqrt((mx * ddx) * (mx * ddx) + (my * ddy) * (my * ddy));
        }
    }
}

/* A layer being written: its feature (reused for every row), the fields' indices and
 * whether a transaction is open. */
#define VEC_MAX_FIELDS 12
typedef struct vec_layer {
    OGRLayerH layer;
    OGRFeatureH feat;
    int tx;
    int idx[VEC_MAX_FIELDS];
} vec_layer;

typedef struct vec_field {
    const char *name;
    OGRFieldType type;
} vec_field;

/* Create layer `name` of geometry g with its fields, open a transaction where the format
 * has them, and the feature to fill; 0, or -1 with the error (naming `shown`). */
static int layer_open(GDALDatasetH ds, const vec_ctx *c, const char *shown, const char *name,
                      OGRwkbGeometryType g, const vec_field *fields, int n, vec_layer *L)
{
    int k;
    memset(L, 0, sizeof *L);
    CPLErrorReset();
    L->layer = GDALDatasetCreateLayer(ds, name, c->srs, g, NULL);
    if (!L->layer) {
        tsio__set_err_gdal(c->err, shown, CPLSPrintf("cannot create the layer \"%s\"", name));
        return -1;
    }
    for (k = 0; k < n; k++)
        if (add_field(L->layer, fields[k].name, fields[k].type, &L->idx[k])) {
            tsio__set_err_gdal(c->err, shown,
                               CPLSPrintf("cannot create the fields of layer \"%s\"", name));
            return -1;
        }
    L->tx = GDALDatasetStartTransaction(ds, FALSE) == OGRERR_NONE;
    L->feat = OGR_F_Create(OGR_L_GetLayerDefn(L->layer));
    if (!L->feat) {
        tsio_errf(c->err, shown, "out of memory");
        return -1;
    }
    return 0;
}

/* Write the feature as filled (geometry included) as a new row. */
static int layer_put(vec_layer *L, const vec_ctx *c, const char *shown, const char *what)
{
    CPLErrorReset();
    if (OGR_L_CreateFeature(L->layer, L->feat) != OGRERR_NONE) {
        tsio__set_err_gdal(c->err, shown, CPLSPrintf("cannot write a %s", what));
        return -1;
    }
    return 0;
}

/* After the rows (ok: all written): commit, else roll back; the feature freed.  0 when
 * ok and committed. */
static int layer_close(GDALDatasetH ds, vec_layer *L, const vec_ctx *c, const char *shown,
                       const char *what, int ok)
{
    int rc = ok ? 0 : -1;
    if (ok && L->tx) {
        L->tx = 0;
        CPLErrorReset();
        if (GDALDatasetCommitTransaction(ds) != OGRERR_NONE) {
            tsio__set_err_gdal(c->err, shown, CPLSPrintf("cannot commit the %ss", what));
            rc = -1;
        }
    }
    if (L->feat)
        OGR_F_Destroy(L->feat);
    if (L->tx && rc != 0)
        GDALDatasetRollbackTransaction(ds);
    return rc;
}

/* A LineString through the centres of count cells (one cell: drawn as a point twice). */
static OGRGeometryH chain_line(const vec_ctx *c, const ts_feature_vertex *v, size_t count)
{
    size_t k, npts = count < 2 ? 2 : count;
    OGRGeometryH line;
    if (npts > INT_MAX || !(line = OGR_G_CreateGeometry(wkbLineString)))
        return NULL;
    OGR_G_SetPointCount(line, (int)npts);
    for (k = 0; k < npts; k++) {
        const ts_feature_vertex *q = &v[k < count ? k : count - 1];
        OGR_G_SetPoint_2D(line, (int)k, cx(c, q->x, q->y), cy(c, q->x, q->y));
    }
    return line;
}

static int write_paths_layer(GDALDatasetH ds, const vec_ctx *c)
{
    enum { KIND, LEN_M, LEN_C, MEAN, MIN, MAX, START, END, NF };
    static const vec_field fields[NF] = {{"kind", OFTString},       {"length_m", OFTReal},
                                         {"length_cells", OFTReal}, {"mean_elev", OFTReal},
                                         {"min_elev", OFTReal},     {"max_elev", OFTReal},
                                         {"start_kind", OFTString}, {"end_kind", OFTString}};
    const ts_features *f = c->f;
    vec_layer L;
    size_t i;
    int ok = layer_open(ds, c, c->path, "paths", wkbLineString, fields, NF, &L) == 0;
    for (i = 0; ok && i < f->n_paths; i++) {
        const ts_feature_path *p = &f->paths[i];
        const ts_feature_vertex *v = &f->verts[p->first];
        OGRGeometryH line = chain_line(c, v, p->count);
        double len_c, len_m;
        if (!line) {
            tsio_errf(c->err, c->path, "cannot build the line of path %zu", i);
            ok = 0;
            break;
        }
        chain_length(c, v, p->count, &len_c, &len_m);
        OGR_F_SetFID(L.feat, OGRNullFID);
        OGR_F_SetFieldString(L.feat, L.idx[KIND], kind_name(p->kind));
        if (c->metrics)
            set_real_or_null(L.feat, L.idx[LEN_M], len_m);
        else
            OGR_F_SetFieldNull(L.feat, L.idx[LEN_M]);
        OGR_F_SetFieldDouble(L.feat, L.idx[LEN_C], len_c);
        set_real_or_null(L.feat, L.idx[MEAN], p->zmean);
        set_real_or_null(L.feat, L.idx[MIN], p->zmin);
        set_real_or_null(L.feat, L.idx[MAX], p->zmax);
        OGR_F_SetFieldString(L.feat, L.idx[START], node_kind_name(f->nodes[p->node_a].degree));
        OGR_F_SetFieldString(L.feat, L.idx[END], node_kind_name(f->nodes[p->node_b].degree));
        OGR_F_SetGeometryDirectly(L.feat, line);
        ok = layer_put(&L, c, c->path, "path") == 0;
    }
    return layer_close(ds, &L, c, c->path, "path", ok);
}

static int write_nodes_layer(GDALDatasetH ds, const vec_ctx *c, const char *shown_path)
{
    enum { KIND, DEGREE, ELEV, FEATURE, NF };
    static const vec_field fields[NF] = {
        {"kind", OFTString}, {"degree", OFTInteger}, {"elev", OFTReal}, {"feature", OFTString}};
    const ts_features *f = c->f;
    vec_layer L;
    size_t i;
    int ok = layer_open(ds, c, shown_path, "nodes", wkbPoint, fields, NF, &L) == 0;
    for (i = 0; ok && i < f->n_nodes; i++) {
        const ts_feature_node *n = &f->nodes[i];
        OGRGeometryH pt = OGR_G_CreateGeometry(wkbPoint);
        if (!pt) {
            tsio_errf(c->err, shown_path, "out of memory");
            ok = 0;
            break;
        }
        OGR_G_SetPoint_2D(pt, 0, cx(c, n->x, n->y), cy(c, n->x, n->y));
        OGR_F_SetFID(L.feat, OGRNullFID);
        OGR_F_SetFieldString(L.feat, L.idx[KIND], node_kind_name(n->degree));
        OGR_F_SetFieldInteger(L.feat, L.idx[DEGREE], n->degree);
        set_real_or_null(L.feat, L.idx[ELEV], n->z);
        OGR_F_SetFieldString(L.feat, L.idx[FEATURE], kind_name(n->kind));
        OGR_F_SetGeometryDirectly(L.feat, pt);
        ok = layer_put(&L, c, shown_path, "node") == 0;
    }
    return layer_close(ds, &L, c, shown_path, "node", ok);
}

/* Layer "streams": a LineString per link, downstream, with its network. */
static int write_streams_layer(GDALDatasetH ds, const vec_ctx *c)
{
    enum { LINK, DOWN, ORDER, AREA_C, AREA_KM2, LEN_M, LEN_C, TOP, BOTTOM, NF };
    static const vec_field fields[NF] = {
        {"link", OFTInteger64},    {"down", OFTInteger64}, {"strahler", OFTInteger},
        {"area_cells", OFTReal},   {"area_km2", OFTReal},  {"length_m", OFTReal},
        {"length_cells", OFTReal}, {"elev_top", OFTReal},  {"elev_bottom", OFTReal}};
    const ts_stream_network *net = c->net;
    vec_layer L;
    size_t i;
    int ok = layer_open(ds, c, c->path, "streams", wkbLineString, fields, NF, &L) == 0;
    for (i = 0; ok && i < net->n_links; i++) {
        const ts_stream_link *S = &net->links[i];
        const ts_feature_vertex *v = &net->verts[S->first], *low = &v[S->count - 1];
        OGRGeometryH line = chain_line(c, v, S->count);
        double len_c, len_m;
        if (!line) {
            tsio_errf(c->err, c->path, "cannot build the line of link %zu", i);
            ok = 0;
            break;
        }
        chain_length(c, v, S->count, &len_c, &len_m);
        OGR_F_SetFID(L.feat, OGRNullFID);
        OGR_F_SetFieldInteger64(L.feat, L.idx[LINK], (GIntBig)i);
        if (S->down >= 0)
            OGR_F_SetFieldInteger64(L.feat, L.idx[DOWN], (GIntBig)S->down);
        else
            OGR_F_SetFieldNull(L.feat, L.idx[DOWN]);
        OGR_F_SetFieldInteger(L.feat, L.idx[ORDER], S->order);
        OGR_F_SetFieldDouble(L.feat, L.idx[AREA_C], S->area);
        if (c->metrics) {
            set_real_or_null(L.feat, L.idx[AREA_KM2],
                             S->area * c->metrics->dx[low->y] * c->metrics->dy[low->y] / 1e6);
            set_real_or_null(L.feat, L.idx[LEN_M], len_m);
        } else {
            OGR_F_SetFieldNull(L.feat, L.idx[AREA_KM2]);
            OGR_F_SetFieldNull(L.feat, L.idx[LEN_M]);
        }
        OGR_F_SetFieldDouble(L.feat, L.idx[LEN_C], len_c);
        set_real_or_null(L.feat, L.idx[TOP], v[0].z);
        set_real_or_null(L.feat, L.idx[BOTTOM], low->z);
        OGR_F_SetGeometryDirectly(L.feat, line);
        ok = layer_put(&L, c, c->path, "stream") == 0;
    }
    return layer_close(ds, &L, c, c->path, "stream", ok);
}

/* A stream network output makes sense: links and vertices on the grid. */
static int check_streams(const char *path, const tsio_georef *geo, const ts_stream_network *net,
                         tsio_err *err)
{
    size_t i, k;
    if ((net->n_links && !net->links) || (net->n_verts && !net->verts) ||
        (geo && (geo->width != net->width || geo->height != net->height))) {
        tsio_errf(err, path, "the stream network does not fit the grid");
        return -1;
    }
    for (i = 0; i < net->n_links; i++) {
        const ts_stream_link *L = &net->links[i];
        if (L->count < 2 || L->count > net->n_verts || L->first > net->n_verts - L->count ||
            L->down >= (int64_t)net->n_links) {
            tsio_errf(err, path, "stream link %zu has invalid indices", i);
            return -1;
        }
        for (k = L->first; k < L->first + L->count; k++)
            if (net->verts[k].x < 0 || net->verts[k].y < 0 || net->verts[k].x >= net->width ||
                net->verts[k].y >= net->height) {
                tsio_errf(err, path, "stream link %zu has a vertex outside the grid", i);
                return -1;
            }
    }
    return 0;
}

/* A features output makes sense: a path, features on the georeference's grid. */
static int check_feature_args(const char *path, const tsio_georef *geo, const ts_features *f,
                              tsio_err *err)
{
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (!f) {
        tsio_errf(err, path, "no features given");
        return -1;
    }
    if (geo && geo->width > 0 && geo->height > 0 && f->width > 0 && f->height > 0 &&
        (geo->width != f->width || geo->height != f->height)) {
        tsio_errf(err, path, "the georeferencing is for %d x %d cells but the features for %d x %d",
                  geo->width, geo->height, f->width, f->height);
        return -1;
    }
    return check_features(f, path, err);
}

/* What the layer writers share: the features, the cells' ground metrics, the
 * geotransform (cells without one) and the CRS. */
static int vec_ctx_init(vec_ctx *c, const char *path, const tsio_georef *geo, const ts_features *f,
                        const ts_grid_metrics *metrics, tsio_err *err)
{
    int i;
    c->path = path;
    c->f = f;
    c->err = err;
    c->metrics = (metrics && metrics->dx && metrics->dy) ? metrics : NULL;
    if (geo && geo->has_gt) {
        memcpy(c->gt, geo->gt, sizeof c->gt);
        for (i = 0; i < 6; i++)
            if (!isfinite(c->gt[i])) {
                tsio_errf(err, path, "the geotransform is not finite");
                return -1;
            }
    } else {
        c->gt[1] = 1.0;
        c->gt[5] = 1.0;
    }
    if (geo && geo->wkt && geo->wkt[0]) {
        c->srs = tsio__srs_from_wkt(geo->wkt);
        if (!c->srs) {
            tsio_errf(err, path, "the CRS (WKT) is invalid");
            return -1;
        }
    }
    return 0;
}

/* The nodes in their own file (formats of one layer): its temporary dataset
 * written and closed. */
static int write_nodes_file(GDALDriverH drv, const out_name *nodes_n, vec_ctx *c)
{
    GDALDatasetH nds;
    CPLErrorReset();
    nds = GDALCreate(drv, nodes_n->temp, 0, 0, 0, GDT_Unknown, NULL);
    if (!nds) {
        tsio__set_err_gdal(c->err, nodes_n->final, "cannot create the file");
        return -1;
    }
    if (write_nodes_layer(nds, c, nodes_n->final) != 0) {
        GDALClose(nds);
        return -1;
    }
    return tsio__close_checked(nds, nodes_n->final, c->err);
}

static int write_features_impl(const char *path, const tsio_georef *geo, const ts_features *f,
                               const ts_stream_network *net, const ts_grid_metrics *metrics,
                               tsio_err *err)
{
    out_name main_n, nodes_n;
    char *nodes_stem = NULL;
    const char *drv_name;
    GDALDriverH drv;
    GDALDatasetH ds = NULL;
    vec_ctx c;
    int rc = -1, sibling, created = 0, ncreated = 0, i, slot = -1, nslot = -1, staged;

    memset(&main_n, 0, sizeof main_n);
    memset(&nodes_n, 0, sizeof nodes_n);
    memset(&c, 0, sizeof c);
    if (net && (!path || !path[0])) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (net ? check_streams(path, geo, net, err) != 0 : check_feature_args(path, geo, f, err) != 0)
        return -1;
    if (tsio__out_name_for(path, &main_n) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    drv_name = vector_driver_for_ext(main_n.ext);
    if (!drv_name) {
        tsio_errf(err, path, "cannot tell the vector format from the extension");
        goto done;
    }
    drv = GDALGetDriverByName(drv_name);
    if (!drv || !tsio__driver_has(drv, GDAL_DCAP_VECTOR) ||
        !tsio__driver_has(drv, GDAL_DCAP_CREATE)) {
        tsio_errf(err, path, "the %s driver is not available for writing", drv_name);
        goto done;
    }
    if (tsio__check_output_location(&main_n, path, err) != 0)
        goto done;

    if (vec_ctx_init(&c, path, geo, f, metrics, err) != 0)
        goto done;
    c.net = net;

    /* the paths (and, for multi-layer formats, the nodes) */
    CPLErrorReset();
    created = 1;
    slot = tsio__temp_register(&main_n);
    ds = GDALCreate(drv, main_n.temp, 0, 0, 0, GDT_Unknown, NULL);
    if (!ds) {
        tsio__set_err_gdal(err, path, "cannot create the file");
        goto done;
    }
    if ((net ? write_streams_layer(ds, &c) : write_paths_layer(ds, &c)) != 0)
        goto done;
    sibling =
        !net && (single_layer_driver(drv_name) || !GDALDatasetTestCapability(ds, ODsCCreateLayer));
    if (!net && !sibling && write_nodes_layer(ds, &c, path) != 0)
        goto done;
    i = tsio__close_checked(ds, path, err);
    ds = NULL;
    if (i != 0)
        goto done;

    /* the nodes in "<stem>_nodes.<ext>" */
    if (sibling) {
        nodes_stem = tsio__str_fmt("%s_nodes", main_n.stem);
        if (!nodes_stem || tsio__out_name_make(main_n.dir, nodes_stem, main_n.ext, &nodes_n) != 0) {
            tsio_errf(err, path, "out of memory");
            goto done;
        }
        ncreated = 1;
        nslot = tsio__temp_register(&nodes_n);
        if (write_nodes_file(drv, &nodes_n, &c) != 0)
            goto done;
    }

    /* move into place, now or with the job's other outputs (GDAL 3.6's
     * GDALRenameDataset reopens as raster only, so the files of the
     * temporary dataset are renamed) */
    if (!tsio__stage_active()) {
        /* both files or neither: check the second can go before moving the first */
        if (sibling && tsio__remove_existing(nodes_n.final, nodes_n.final, err) != 0)
            goto done;
    }
    staged = tsio__stage_active();
    created = 0;
    if (tsio__finish_output(&main_n, path, slot, 0, err) != 0) {
        created = 1;
        slot = -1;
        goto done;
    }
    slot = -1;
    if (sibling) {
        ncreated = 0;
        if (tsio__finish_output(&nodes_n, nodes_n.final, nslot, 0, err) != 0) {
            ncreated = 1;
            nslot = -1;
            if (!staged) {
                /* the nodes could not follow: do not leave half an output */
                GDALDriverH d = GDALIdentifyDriver(main_n.final, NULL);
                if (d)
                    GDALDeleteDataset(d, main_n.final);
                if (tsio__path_exists(main_n.final, NULL))
                    VSIUnlink(main_n.final);
            }
            goto done;
        }
        nslot = -1;
    }
    rc = 0;

done:
    if (ds)
        GDALClose(ds);
    if (rc != 0) {
        if (created && main_n.temp)
            tsio__remove_temp_files(&main_n);
        if (ncreated && nodes_n.temp)
            tsio__remove_temp_files(&nodes_n);
    }
    tsio__temp_unregister(slot);
    tsio__temp_unregister(nslot);
    if (c.srs)
        OSRDestroySpatialReference(c.srs);
    free(nodes_stem);
    tsio__out_name_free(&main_n);
    tsio__out_name_free(&nodes_n);
    return rc;
}

int tsio_check_vector_output(const char *path, tsio_err *err)
{
    out_name on;
    const char *drv_name;
    GDALDriverH drv;
    int rc = -1;
    memset(&on, 0, sizeof on);
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    tsio__ensure_registered();
    if (tsio__out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    drv_name = vector_driver_for_ext(on.ext);
    if (!drv_name)
        tsio_errf(err, path, "cannot tell the vector format from the extension");
    else if (!(drv = GDALGetDriverByName(drv_name)) || !tsio__driver_has(drv, GDAL_DCAP_VECTOR) ||
             !tsio__driver_has(drv, GDAL_DCAP_CREATE))
        tsio_errf(err, path, "the %s driver is not available for writing", drv_name);
    else
        rc = tsio__check_output_location(&on, path, err);
    tsio__out_name_free(&on);
    return rc;
}

int tsio_write_features(const char *path, const tsio_georef *geo, const ts_features *f,
                        const ts_grid_metrics *metrics, tsio_err *err)
{
    int rc;
    if (err)
        err->msg[0] = '\0';
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = write_features_impl(path, geo, f, NULL, metrics, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    return rc;
}

int tsio_write_streams(const char *path, const tsio_georef *geo, const ts_stream_network *net,
                       const ts_grid_metrics *metrics, tsio_err *err)
{
    int rc;
    if (err)
        err->msg[0] = '\0';
    if (!net) {
        tsio_errf(err, path ? path : "(empty path)", "no stream network given");
        return -1;
    }
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = write_features_impl(path, geo, NULL, net, metrics, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    return rc;
}

/* ------------------------------------------------------------------ */
/* Label maps (regions)                                                */
/* ------------------------------------------------------------------ */

int tsio_read_label_map(const char *path, const tsio_georef *geo, const char *field, int fill,
                        int32_t *values, tsio_err *err)
{
    size_t i, n = (size_t)geo->width * (size_t)geo->height;
    if (tsio_read_label_window(path, geo, 0, 0, geo->width, geo->height, field, fill, values,
                               err) != 0)
        return -1;
    for (i = 0; i < n && values[i] == fill; i++)
        ;
    if (i == n) {
        tsio_errf(err, path,
                  "labels no cell of the output grid (no %s, or none over the grid): a map "
                  "that labels nothing changes nothing",
                  field);
        return -1;
    }
    return 0;
}

/* A raster's labels: whole numbers (a float raster's 1.6 is not rounded to 2). */
static int label_raster(const char *path, GDALRasterBandH b, int x0, int y0, int w, int h, int fill,
                        int32_t *values, tsio_err *err)
{
    size_t i, n = (size_t)w * (size_t)h;
    int has_nd = 0;
    double nd = GDALGetRasterNoDataValue(b, &has_nd);
    double *v = malloc((n ? n : 1) * sizeof *v);
    if (!v) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    if (GDALRasterIO(b, GF_Read, x0, y0, w, h, v, w, h, GDT_Float64, 0, 0) != CE_None) {
        tsio__set_err_gdal(err, path, "cannot read the region map");
        free(v);
        return -1;
    }
    for (i = 0; i < n; i++) {
        if (isnan(v[i]) || (has_nd && v[i] == nd)) {
            values[i] = fill;
            continue;
        }
        if (v[i] != floor(v[i]) || v[i] < -2147483647.0 || v[i] > 2147483647.0) {
            tsio_errf(err, path,
                      "region %.6g at column %zu, row %zu is not a whole number: region ids "
                      "are integers",
                      v[i], (size_t)x0 + i % (size_t)w, (size_t)y0 + i / (size_t)w);
            free(v);
            return -1;
        }
        values[i] = (int32_t)v[i];
    }
    free(v);
    return 0;
}

/* A polygon layer whose field holds whole numbers: an Integer field, or a Real one whose
 * values all are. */
static int label_layer_ok(const char *path, OGRLayerH layer, const char *field, tsio_err *err)
{
    OGRFeatureDefnH defn = OGR_L_GetLayerDefn(layer);
    int fi = OGR_FD_GetFieldIndex(defn, field);
    OGRwkbGeometryType gt = wkbFlatten(OGR_L_GetGeomType(layer));
    OGRFieldType t;
    if (fi < 0) {
        tsio_errf(err, path, "the polygon layer has no integer field \"%s\"", field);
        return -1;
    }
    if (gt != wkbUnknown && gt != wkbPolygon && gt != wkbMultiPolygon &&
        gt != wkbGeometryCollection && gt != wkbCurvePolygon && gt != wkbMultiSurface) {
        tsio_errf(err, path, "its first layer holds %s, not polygons: draw the regions as polygons",
                  OGRGeometryTypeToName(gt));
        return -1;
    }
    t = OGR_Fld_GetType(OGR_FD_GetFieldDefn(defn, fi));
    if (t == OFTReal) {
        OGRFeatureH f;
        OGR_L_ResetReading(layer);
        while ((f = OGR_L_GetNextFeature(layer))) {
            double v = OGR_F_GetFieldAsDouble(f, fi);
            GIntBig fid = OGR_F_GetFID(f);
            OGR_F_Destroy(f);
            if (v != floor(v)) {
                tsio_errf(err, path,
                          "feature %lld: %s %.6g is not a whole number: region ids are integers",
                          (long long)fid, field, v);
                return -1;
            }
        }
        OGR_L_ResetReading(layer);
    } else if (t != OFTInteger && t != OFTInteger64) {
        tsio_errf(err, path, "field \"%s\" holds %s: region ids are integers (an Integer field)",
                  field, OGR_GetFieldTypeName(t));
        return -1;
    }
    return 0;
}

int tsio_read_label_window(const char *path, const tsio_georef *geo, int x0, int y0, int w, int h,
                           const char *field, int fill, int32_t *values, tsio_err *err)
{
    GDALDatasetH src, mem = NULL;
    double gt[6];
    int rc = -1;
    /* the window's own geotransform: its cells are the grid's */
    memcpy(gt, geo->gt, sizeof gt);
    gt[0] = geo->gt[0] + x0 * geo->gt[1] + y0 * geo->gt[2];
    gt[3] = geo->gt[3] + x0 * geo->gt[4] + y0 * geo->gt[5];
    tsio__ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    src = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_VECTOR | GDAL_OF_READONLY, NULL, NULL, NULL);
    if (!src) {
        VSIStatBufL st;
        tsio_errf(err, path,
                  VSIStatL(path, &st) != 0 ? "no such file"
                                           : "not a raster or vector GDAL can open");
        goto done;
    }
    if (GDALGetRasterCount(src) > 0) {
        tsio_georef rg;
        const char *wkt = GDALGetProjectionRef(src);
        int same;
        memset(&rg, 0, sizeof rg);
        rg.width = GDALGetRasterXSize(src);
        rg.height = GDALGetRasterYSize(src);
        rg.has_gt = GDALGetGeoTransform(src, rg.gt) == CE_None;
        rg.wkt = wkt && wkt[0] ? (char *)wkt : NULL;
        same = tsio_same_grid(path, "the region map", &rg, geo, "output", err);
        if (same != 0)
            goto done;
        rc = label_raster(path, GDALGetRasterBand(src, 1), x0, y0, w, h, fill, values, err);
    } else if (GDALDatasetGetLayerCount(src) > 0) {
        OGRLayerH layer = GDALDatasetGetLayer(src, 0);
        char *argv[] = {"-a", (char *)field, NULL};
        GDALRasterizeOptions *ro;
        int usage = 0;
        GDALDatasetH out;
        if (label_layer_ok(path, layer, field, err) != 0)
            goto done;
        mem = GDALCreate(GDALGetDriverByName("MEM"), "", w, h, 1, GDT_Int32, NULL);
        if (!mem) {
            tsio_errf(err, path, "out of memory");
            goto done;
        }
        GDALSetGeoTransform(mem, gt);
        if (geo->wkt)
            GDALSetProjection(mem, geo->wkt);
        GDALFillRaster(GDALGetRasterBand(mem, 1), fill, 0);
        ro = GDALRasterizeOptionsNew(argv, NULL);
        out = ro ? GDALRasterize(NULL, mem, src, ro, &usage) : NULL;
        if (ro)
            GDALRasterizeOptionsFree(ro);
        if (!out) {
            tsio__set_err_gdal(err, path, "cannot rasterise the region polygons");
            goto done;
        }
        if (GDALRasterIO(GDALGetRasterBand(mem, 1), GF_Read, 0, 0, w, h, values, w, h, GDT_Int32, 0,
                         0) != CE_None) {
            tsio__set_err_gdal(err, path, "cannot read the rasterised regions");
            goto done;
        }
        rc = 0;
    } else {
        tsio_errf(err, path, "has neither a raster band nor a layer");
    }
done:
    if (mem)
        GDALClose(mem);
    if (src)
        GDALClose(src);
    CPLErrorReset();
    CPLPopErrorHandler();
    return rc;
}
