/*
 * tsio_offline.c - what an untrusted recipe may read: names that reach no
 * network and no special file, the files those name in turn (VRTs, OGR
 * VRTs) checked the same way, and the offline guard that keeps GDAL off
 * the network while a recipe's inputs are opened and read.
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1

#include "tsio_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <cpl_conv.h>
#include <cpl_http.h>
#include <cpl_minixml.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>

#define ALLOW_HINT "(set the configuration option TSYN_ALLOW_NETWORK=YES to allow it)"

static int network_allowed(void)
{
    return CPLTestBool(CPLGetConfigOption("TSYN_ALLOW_NETWORK", "NO"));
}

int tsio_name_offline(const char *name, tsio_err *err)
{
    static const char *const net[] = {"/vsicurl",    "/vsis3",  "/vsigs",    "/vsiaz",
                                      "/vsiadls",    "/vsioss", "/vsiswift", "/vsihdfs",
                                      "/vsiwebhdfs", "://",     NULL};
    int i;
    if (network_allowed())
        return 0;
    for (i = 0; net[i]; i++)
        if (strstr(name, net[i])) {
            tsio_errf(err, name,
                      "names a network resource: a recipe reads local files only " ALLOW_HINT);
            return -1;
        }
    return 0;
}

int tsio_name_plain(const char *name, tsio_err *err)
{
    struct stat st;
    if (strstr(name, "/vsistdin")) {
        tsio_errf(err, name, "a recipe never reads standard input");
        return -1;
    }
    if (stat(name, &st) == 0 && !S_ISREG(st.st_mode) && !S_ISDIR(st.st_mode)) {
        tsio_errf(err, name,
                  "is not a regular file (a device, FIFO or socket): a recipe reads files only");
        return -1;
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* The files a name leads to                                           */
/* ------------------------------------------------------------------ */

/* Drivers whose datasets live on a server (their files, when they have
 * one, only say where), and the connection prefixes that open them. */
static const char *const net_drivers[] = {
    "WMS",          "WMTS",     "WCS",         "HTTP",          "EEDA",       "EEDAI",
    "PLMOSAIC",     "PLSCENES", "DAAS",        "OGCAPI",        "NGW",        "PostGISRaster",
    "GEORASTER",    "OCI",      "WFS",         "OAPIF",         "PostgreSQL", "MySQL",
    "MSSQLSpatial", "ODBC",     "PGeo",        "Elasticsearch", "CouchDB",    "Carto",
    "AmigoCloud",   "CSW",      "MongoDBv3",   "HANA",          "OGDI",       "DODS",
    "IDB",          "SDE",      "GNMDatabase", "WEBHDFS",       NULL};
static const char *const net_prefixes[] = {
    "PG:",         "MYSQL:",   "MSSQL:",    "ODBC:",      "WFS:",  "WMS:",    "WMTS:",  "WCS:",
    "EEDA:",       "EEDAI:",   "PLScenes:", "PLMosaic:",  "DAAS:", "OGCAPI:", "NGW:",   "CARTO:",
    "AMIGOCLOUD:", "CouchDB:", "ES:",       "MongoDBv3:", "HANA:", "CSW:",    "OAPIF:", "GEOR:",
    "OCI:",        "SDE:",     "IDB:",      "gltp:",      "DODS:", "PGeo:",   "GNM:",   NULL};

static int is_net_driver(GDALDriverH drv)
{
    const char *name = drv ? GDALGetDriverShortName(drv) : NULL;
    int i;
    for (i = 0; name && net_drivers[i]; i++)
        if (EQUAL(name, net_drivers[i]))
            return 1;
    return 0;
}

static int has_net_prefix(const char *name)
{
    int i;
    for (i = 0; net_prefixes[i]; i++)
        if (EQUALN(name, net_prefixes[i], strlen(net_prefixes[i])))
            return 1;
    return 0;
}

#define SCAN_DEPTH 16
#define SCAN_MAX_XML ((GIntBig)16 << 20)

static int scan_name(const char *name, int depth, tsio_err *err);

/* Every file an XML description (VRT, OGR VRT) names, checked. */
static int scan_xml_node(const CPLXMLNode *n, const char *dir, int depth, tsio_err *err)
{
    for (; n; n = n->psNext) {
        if (n->eType != CXT_Element)
            continue;
        if (EQUAL(n->pszValue, "SourceFilename") || EQUAL(n->pszValue, "SrcDataSource") ||
            EQUAL(n->pszValue, "SourceDataset") || EQUAL(n->pszValue, "OverviewFile")) {
            const char *v = CPLGetXMLValue((CPLXMLNode *)n, NULL, "");
            const char *rel = CPLGetXMLValue((CPLXMLNode *)n, "relativeToVRT", "0");
            const char *rel2 = CPLGetXMLValue((CPLXMLNode *)n, "relativetoVRT", rel);
            char *path;
            int rc;
            if (!*v)
                continue;
            path = CPLStrdup((CPLTestBool(rel2) && CPLIsFilenameRelative(v))
                                 ? CPLFormFilename(dir, v, NULL)
                                 : v);
            rc = scan_name(path, depth + 1, err);
            CPLFree(path);
            if (rc != 0)
                return -1; /* the message names the file that reaches out */
        }
        if (scan_xml_node(n->psChild, dir, depth, err) != 0)
            return -1;
    }
    return 0;
}

static int scan_xml_file(const char *path, int depth, tsio_err *err)
{
    GByte *buf = NULL;
    CPLXMLNode *root;
    char *dir;
    int rc;
    if (!VSIIngestFile(NULL, path, &buf, NULL, SCAN_MAX_XML)) {
        tsio_errf(err, path, "cannot be read (or is over 16 MB of XML)");
        return -1;
    }
    root = CPLParseXMLString((const char *)buf);
    VSIFree(buf);
    if (!root)
        return 0; /* not XML after all: the open says what it is */
    dir = CPLStrdup(CPLGetPath(path));
    rc = scan_xml_node(root, dir, depth, err);
    CPLFree(dir);
    CPLDestroyXMLNode(root);
    return rc;
}

static int scan_name(const char *name, int depth, tsio_err *err)
{
    struct stat st;
    GDALDriverH drv;
    if (depth > SCAN_DEPTH) {
        tsio_errf(err, name, "files naming files more than %d deep (a loop?)", SCAN_DEPTH);
        return -1;
    }
    if (tsio_name_offline(name, err) != 0 || tsio_name_plain(name, err) != 0)
        return -1;
    if (name[0] == '<') {
        tsio_errf(err, name, "a dataset written inline as XML: a recipe reads files only");
        return -1;
    }
    if (has_net_prefix(name)) {
        tsio_errf(err, name,
                  "opens a server connection: a recipe reads local files only " ALLOW_HINT);
        return -1;
    }
    if (stat(name, &st) != 0 || !S_ISREG(st.st_mode))
        return 0; /* a folder, a subdataset's name ("NETCDF:f.nc:z") or nothing: the open decides */
    drv = GDALIdentifyDriverEx(name, GDAL_OF_RASTER | GDAL_OF_VECTOR, NULL, NULL);
    if (is_net_driver(drv)) {
        tsio_errf(err, name,
                  "is a %s description, whose data live on a server: a recipe reads local "
                  "files only " ALLOW_HINT,
                  GDALGetDriverShortName(drv));
        return -1;
    }
    if (drv && (EQUAL(GDALGetDriverShortName(drv), "VRT") ||
                EQUAL(GDALGetDriverShortName(drv), "OGR_VRT")))
        return scan_xml_file(name, depth, err);
    return 0;
}

int tsio_input_offline(const char *name, tsio_err *err)
{
    tsio_offline g;
    int rc;
    if (network_allowed())
        return tsio_name_plain(name, err);
    tsio__ensure_registered();
    tsio_offline_begin(&g);
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = scan_name(name, 0, err);
    CPLPopErrorHandler();
    if (rc != 0 && strncmp(err->msg, name, strlen(name)) != 0) {
        /* found inside: say which input leads there */
        char inner[sizeof err->msg];
        snprintf(inner, sizeof inner, "%s", err->msg);
        tsio_errf(err, name, "leads to %s", inner);
    }
    tsio_offline_end(&g);
    return rc;
}

/* ------------------------------------------------------------------ */
/* The offline guard                                                   */
/* ------------------------------------------------------------------ */

/* On this thread only, /vsicurl/ and the file systems built on it
 * (/vsis3/, /vsigs/, ...) find no file, and every HTTP request GDAL makes
 * through CPLHTTPFetch (WMTS, WCS, OGR's web drivers) is answered with an
 * error before any connection. */
#define OFFLINE_NAME "/vsicurl/terrasynth-recipes-read-local-files-only"

static CPLHTTPResult *offline_fetch(const char *url, CSLConstList options,
                                    GDALProgressFunc progress, void *progress_arg,
                                    CPLHTTPFetchWriteFunc write, void *write_arg, void *user)
{
    CPLHTTPResult *res = CPLCalloc(1, sizeof *res);
    (void)progress;
    (void)progress_arg;
    (void)write;
    (void)write_arg;
    (void)user;
    if (CSLFetchNameValue((char **)options, "CLOSE_PERSISTENT"))
        return res; /* closing a session is no request */
    res->nStatus = 1;
    res->pszErrBuf = CPLStrdup(CPLSPrintf("%.200s: a network request while a recipe's inputs "
                                          "are read: a recipe reads local files only " ALLOW_HINT,
                                          url ? url : "?"));
    CPLError(CE_Failure, CPLE_AppDefined, "%s", res->pszErrBuf);
    return res;
}

void tsio_offline_begin(tsio_offline *g)
{
    const char *v;
    memset(g, 0, sizeof *g);
    if (network_allowed())
        return;
    g->active = 1;
    v = CPLGetThreadLocalConfigOption("CPL_VSIL_CURL_ALLOWED_FILENAME", NULL);
    g->saved = v ? CPLStrdup(v) : NULL;
    CPLSetThreadLocalConfigOption("CPL_VSIL_CURL_ALLOWED_FILENAME", OFFLINE_NAME);
    g->pushed = CPLHTTPPushFetchCallback(offline_fetch, NULL) != 0;
}

void tsio_offline_end(tsio_offline *g)
{
    if (!g->active)
        return;
    if (g->pushed)
        CPLHTTPPopFetchCallback();
    CPLSetThreadLocalConfigOption("CPL_VSIL_CURL_ALLOWED_FILENAME", g->saved);
    CPLFree(g->saved);
    g->saved = NULL;
    g->active = 0;
}

/* ------------------------------------------------------------------ */
/* A recipe's CRS                                                      */
/* ------------------------------------------------------------------ */

int tsio_crs_offline(const char *crs, tsio_err *err)
{
    const char *p = crs;
    struct stat st;
    while (*p == ' ' || *p == '\t' || *p == '\n' || *p == '\r')
        p++;
    /* WKT (KEYWORD[...) and PROJJSON are read as text */
    if (*p == '{')
        return 0;
    {
        const char *q = p;
        while ((*q >= 'A' && *q <= 'Z') || (*q >= '0' && *q <= '9') || *q == '_')
            q++;
        if (q > p && *q == '[')
            return 0;
    }
    /* the short forms (EPSG:4326, +proj=..., WGS84, urn:ogc:def:crs:...) name no file
     * and no address; SetFromUserInput would fetch a URL or read a file */
    if (strstr(p, "://") || strchr(p, '/') || strchr(p, '\\') || p[0] == '.' ||
        strstr(p, "init=") || stat(p, &st) == 0) {
        tsio_errf(err, crs,
                  "a recipe's CRS is a code (EPSG:32611), WKT, PROJJSON or a PROJ string; "
                  "never a file or an address");
        return -1;
    }
    return 0;
}
