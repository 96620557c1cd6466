/*
 * tsio.c - TerraSynth's GDAL I/O layer (see tsio.h).
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * Only the GDAL/OGR/OSR C API and PROJ's C geodesic API are used.  GDAL's
 * own error output is silenced with a quiet error handler pushed for the
 * duration of every public call (the handler stack is per thread); the
 * messages GDAL records are folded into the single-line tsio_err.
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1 /* struct stat64 behind GDAL's VSIStatBufL under -std=c11 */

#include "tsio.h"

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

#define TSIO_PI 3.14159265358979323846

/* Cells handled per GDAL I/O call when reading or writing in row chunks. */
#define TSIO_CHUNK_CELLS ((size_t)1 << 22)

/* ------------------------------------------------------------------ */
/* Small helpers: strings, errors                                      */
/* ------------------------------------------------------------------ */

static char *str_dup(const char *s)
{
    size_t n;
    char *d;
    if (!s)
        return NULL;
    n = strlen(s) + 1;
    d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

/* printf into a new malloc'ed string (NULL when out of memory). */
static char *str_fmt(const char *fmt, ...)
{
    va_list ap;
    int n;
    char *s;
    va_start(ap, fmt);
    n = vsnprintf(NULL, 0, fmt, ap);
    va_end(ap);
    if (n < 0)
        return NULL;
    s = malloc((size_t)n + 1);
    if (!s)
        return NULL;
    va_start(ap, fmt);
    vsnprintf(s, (size_t)n + 1, fmt, ap);
    va_end(ap);
    return s;
}

static int str_ieq(const char *a, const char *b)
{
    for (; *a && *b; a++, b++)
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b))
            return 0;
    return *a == *b;
}

static int starts_with(const char *s, const char *prefix)
{
    return strncmp(s, prefix, strlen(prefix)) == 0;
}

/* Replace line breaks and tabs by spaces so a message stays on one line. */
static void one_line(char *s)
{
    for (; *s; s++)
        if (*s == '\n' || *s == '\r' || *s == '\t')
            *s = ' ';
}

/* err->msg = "<path>: <formatted problem>" on one line; the arguments may
 * point into err->msg (a message wrapped in a new one): formatted aside first. */
void tsio_errf(tsio_err *err, const char *path, const char *fmt, ...)
{
    char buf[sizeof err->msg];
    va_list ap;
    size_t used;
    int n;
    if (!err)
        return;
    n = snprintf(buf, sizeof buf, "%s: ", path ? path : "(null)");
    used = (n < 0) ? 0 : (size_t)n;
    if (used >= sizeof buf)
        used = sizeof buf - 1;
    va_start(ap, fmt);
    vsnprintf(buf + used, sizeof buf - used, fmt, ap);
    va_end(ap);
    one_line(buf);
    memcpy(err->msg, buf, sizeof buf);
}

/* Copy GDAL's last error message (one line, maybe empty). */
static void gdal_last_msg(char *buf, size_t n)
{
    const char *m = CPLGetLastErrorMsg();
    snprintf(buf, n, "%s", m ? m : "");
    one_line(buf);
}

/* "<path>: <what>" followed by ": <GDAL's message>" when it has one. */
static void set_err_gdal(tsio_err *err, const char *path, const char *what)
{
    char g[768];
    gdal_last_msg(g, sizeof g);
    if (g[0])
        tsio_errf(err, path, "%s: %s", what, g);
    else
        tsio_errf(err, path, "%s", what);
}

static void ensure_registered(void)
{
    if (GDALGetDriverCount() == 0)
        GDALAllRegister();
}

static int driver_has(GDALDriverH drv, const char *cap)
{
    const char *v = GDALGetMetadataItem(drv, cap, NULL);
    return v && (str_ieq(v, "YES") || str_ieq(v, "TRUE"));
}

/* Does the space-separated `list` contain `word` (case-insensitive)? */
static int list_has_word(const char *list, const char *word)
{
    size_t wl = strlen(word);
    const char *p = list;
    while (p && *p) {
        const char *e;
        while (*p == ' ')
            p++;
        e = p;
        while (*e && *e != ' ')
            e++;
        if ((size_t)(e - p) == wl) {
            size_t i;
            int same = 1;
            for (i = 0; i < wl; i++)
                if (tolower((unsigned char)p[i]) != tolower((unsigned char)word[i])) {
                    same = 0;
                    break;
                }
            if (same)
                return 1;
        }
        p = e;
    }
    return 0;
}

static int path_exists(const char *path, int *is_dir)
{
    VSIStatBufL st;
    if (VSIStatExL(path, &st, VSI_STAT_EXISTS_FLAG | VSI_STAT_NATURE_FLAG) != 0)
        return 0;
    if (is_dir)
        *is_dir = VSI_ISDIR(st.st_mode) ? 1 : 0;
    return 1;
}

/* ------------------------------------------------------------------ */
/* Output names: "<dir>/<stem>.<ext>" and "<dir>/.<stem>.tmp<pid>.<ext>" */
/* ------------------------------------------------------------------ */

typedef struct out_name {
    char *final;   /* the path as given */
    char *dir;     /* directory part without the trailing '/', "" if none */
    char *stem;    /* file name without the extension */
    char *ext;     /* extension without the dot, "" if none */
    char *tstem;   /* temporary stem ".<stem>.tmp<pid>[-k]" */
    char *temp;    /* temporary path */
} out_name;

static void out_name_free(out_name *o)
{
    free(o->final);
    free(o->dir);
    free(o->stem);
    free(o->ext);
    free(o->tstem);
    free(o->temp);
    memset(o, 0, sizeof *o);
}

/* Join a directory ("" = current) and a file name. */
static char *join_dir(const char *dir, const char *name)
{
    if (!dir[0])
        return str_dup(name);
    if (strcmp(dir, "/") == 0)
        return str_fmt("/%s", name);
    return str_fmt("%s/%s", dir, name);
}

/* Split `path` into dir/stem/ext; 0 on success, -1 when out of memory. */
static int out_name_split(const char *path, out_name *o)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    memset(o, 0, sizeof *o);
    if (dot == base)
        dot = NULL; /* ".hidden" has no extension */
    o->final = str_dup(path);
    if (slash == path)
        o->dir = str_dup("/");
    else if (slash) {
        size_t n = (size_t)(slash - path);
        o->dir = malloc(n + 1);
        if (o->dir) {
            memcpy(o->dir, path, n);
            o->dir[n] = '\0';
        }
    } else
        o->dir = str_dup("");
    if (dot) {
        size_t n = (size_t)(dot - base);
        o->stem = malloc(n + 1);
        if (o->stem) {
            memcpy(o->stem, base, n);
            o->stem[n] = '\0';
        }
        o->ext = str_dup(dot + 1);
    } else {
        o->stem = str_dup(base);
        o->ext = str_dup("");
    }
    if (!o->final || !o->dir || !o->stem || !o->ext) {
        out_name_free(o);
        return -1;
    }
    return 0;
}

/* Build from dir/stem/ext a final name, then pick an unused temporary name. */
static int out_name_make(const char *dir, const char *stem, const char *ext, out_name *o)
{
    char *base;
    int k;
    memset(o, 0, sizeof *o);
    o->dir = str_dup(dir);
    o->stem = str_dup(stem);
    o->ext = str_dup(ext);
    if (!o->dir || !o->stem || !o->ext)
        goto nomem;
    base = ext[0] ? str_fmt("%s.%s", stem, ext) : str_dup(stem);
    if (!base)
        goto nomem;
    o->final = join_dir(dir, base);
    free(base);
    if (!o->final)
        goto nomem;
    for (k = 0; k < 1000; k++) {
        long pid = (long)getpid();
        o->tstem = k ? str_fmt(".%s.tmp%ld-%d", stem, pid, k) : str_fmt(".%s.tmp%ld", stem, pid);
        if (!o->tstem)
            goto nomem;
        base = ext[0] ? str_fmt("%s.%s", o->tstem, ext) : str_dup(o->tstem);
        if (!base)
            goto nomem;
        o->temp = join_dir(dir, base);
        free(base);
        if (!o->temp)
            goto nomem;
        if (!path_exists(o->temp, NULL))
            return 0;
        free(o->tstem);
        free(o->temp);
        o->tstem = o->temp = NULL;
    }
nomem:
    out_name_free(o);
    return -1;
}

static int out_name_for(const char *path, out_name *o)
{
    out_name parts;
    int rc;
    if (out_name_split(path, &parts) != 0)
        return -1;
    rc = out_name_make(parts.dir, parts.stem, parts.ext, o);
    out_name_free(&parts);
    if (rc == 0) {
        /* keep the caller's spelling of the final path */
        char *f = str_dup(path);
        if (!f) {
            out_name_free(o);
            return -1;
        }
        free(o->final);
        o->final = f;
    }
    return rc;
}

/* Is `name` (a directory entry) one of the temporary files of `o`:
 * the temporary stem followed by nothing or by '.'?  Returns the suffix. */
static const char *temp_suffix(const out_name *o, const char *name)
{
    size_t n = strlen(o->tstem);
    if (strncmp(name, o->tstem, n) != 0)
        return NULL;
    if (name[n] != '\0' && name[n] != '.')
        return NULL;
    return name + n;
}

/* Remove every file that belongs to the temporary dataset. */
static void remove_temp_files(const out_name *o)
{
    char **entries = VSIReadDir(o->dir[0] ? o->dir : ".");
    int i;
    for (i = 0; entries && entries[i]; i++) {
        if (temp_suffix(o, entries[i])) {
            char *full = join_dir(o->dir, entries[i]);
            int is_dir = 0;
            if (full && path_exists(full, &is_dir)) {
                if (is_dir)
                    VSIRmdirRecursive(full);
                else
                    VSIUnlink(full);
            }
            free(full);
        }
    }
    CSLDestroy(entries);
    if (o->temp && path_exists(o->temp, NULL))
        VSIUnlink(o->temp);
}

/* Rename every temporary file "<tstem><suffix>" to "<stem><suffix>". */
static int rename_temp_files(const out_name *o, const char *path, tsio_err *err)
{
    char **entries = VSIReadDir(o->dir[0] ? o->dir : ".");
    int i, rc = 0, found = 0;
    for (i = 0; entries && entries[i] && rc == 0; i++) {
        const char *suffix = temp_suffix(o, entries[i]);
        char *from, *to, *newname;
        if (!suffix)
            continue;
        found = 1;
        newname = str_fmt("%s%s", o->stem, suffix);
        from = join_dir(o->dir, entries[i]);
        to = newname ? join_dir(o->dir, newname) : NULL;
        if (!from || !to) {
            tsio_errf(err, path, "out of memory");
            rc = -1;
        } else if (VSIRename(from, to) != 0) {
            tsio_errf(err, path, "cannot rename %s to %s", from, to);
            rc = -1;
        }
        free(newname);
        free(from);
        free(to);
    }
    CSLDestroy(entries);
    if (rc == 0 && !found) {
        tsio_errf(err, path, "the temporary file %s disappeared", o->temp);
        rc = -1;
    }
    return rc;
}

/* The directory of `o` must exist, and the final name must not be a directory. */
static int check_output_location(const out_name *o, const char *path, tsio_err *err)
{
    int is_dir = 0;
    const char *dir = o->dir[0] ? o->dir : ".";
    if (path_exists(o->final, &is_dir) && is_dir) {
        tsio_errf(err, path, "is a directory");
        return -1;
    }
    if (starts_with(o->final, "/vsi"))
        return 0; /* virtual file systems may have implicit directories */
    if (!path_exists(dir, &is_dir)) {
        tsio_errf(err, path, "directory %s does not exist", dir);
        return -1;
    }
    if (!is_dir) {
        tsio_errf(err, path, "%s is not a directory", dir);
        return -1;
    }
    return 0;
}

/* Remove an existing output (with its sidecar files) so the new one can
 * be renamed into place. */
static int remove_existing(const char *final, const char *path, tsio_err *err)
{
    int is_dir = 0;
    GDALDriverH drv;
    if (!path_exists(final, &is_dir))
        return 0;
    if (is_dir) {
        tsio_errf(err, path, "is a directory");
        return -1;
    }
    drv = GDALIdentifyDriver(final, NULL);
    if (drv)
        GDALDeleteDataset(drv, final);
    if (path_exists(final, NULL))
        VSIUnlink(final);
    if (path_exists(final, NULL)) {
        tsio_errf(err, path, "cannot replace the existing file %s", final);
        return -1;
    }
    CPLErrorReset();
    return 0;
}

/* ------------------------------------------------------------------ */
/* Spatial references                                                  */
/* ------------------------------------------------------------------ */

/* New SRS from WKT (any flavour GDAL reads), GIS axis order; NULL on error. */
static OGRSpatialReferenceH srs_from_wkt(const char *wkt)
{
    OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
    char *copy = str_dup(wkt);
    char *p = copy;
    if (!srs || !copy || OSRImportFromWkt(srs, &p) != OGRERR_NONE) {
        if (srs)
            OSRDestroySpatialReference(srs);
        free(copy);
        return NULL;
    }
    free(copy);
    OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
    return srs;
}

/* WKT2 (2018) of srs as a malloc'ed string; falls back to GDAL's default
 * WKT when the CRS cannot be expressed in WKT2.  NULL on failure. */
static char *srs_to_wkt2(OGRSpatialReferenceH srs)
{
    const char *const wkt2[] = {"FORMAT=WKT2_2018", NULL};
    char *w = NULL, *out;
    if (OSRExportToWktEx(srs, &w, wkt2) != OGRERR_NONE || !w || !w[0]) {
        CPLFree(w);
        w = NULL;
        if (OSRExportToWkt(srs, &w) != OGRERR_NONE || !w || !w[0]) {
            CPLFree(w);
            return NULL;
        }
    }
    out = str_dup(w);
    CPLFree(w);
    return out;
}

/* ------------------------------------------------------------------ */
/* Reading                                                             */
/* ------------------------------------------------------------------ */

/* Metres per vertical unit named `u`; unknown names count as metres. */
static double vertical_unit_factor(const char *u, int *known)
{
    static const char *const intl_ft[] = {"ft", "foot", "feet", "international foot",
                                          "international feet", "foot (international)",
                                          "ft (international)", NULL};
    static const char *const us_ft[] = {"US survey foot", "ftUS", "us-ft", "US survey feet",
                                        "us_survey_foot", "survey foot", "foot_us",
                                        "US foot", NULL};
    static const char *const metre[] = {"", "m", "metre", "meter", "metres", "meters", NULL};
    int i;
    *known = 1;
    for (i = 0; intl_ft[i]; i++)
        if (str_ieq(u, intl_ft[i]))
            return 0.3048;
    for (i = 0; us_ft[i]; i++)
        if (str_ieq(u, us_ft[i]))
            return 1200.0 / 3937.0;
    for (i = 0; metre[i]; i++)
        if (str_ieq(u, metre[i]))
            return 1.0;
    *known = 0;
    return 1.0;
}

static double clamp_lat(double lat)
{
    return lat < -90.0 ? -90.0 : (lat > 90.0 ? 90.0 : lat);
}

/* Per-row ground metrics of a north-up grid in `srs`.  0 or -1 (message in why). */
static int compute_metrics(OGRSpatialReferenceH srs, const double gt[6], int height,
                           double *dx, double *dy, char *why, size_t whylen)
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
            geod_inverse(&g, clamp_lat(lat - dlat / 2.0), 0.0, clamp_lat(lat + dlat / 2.0), 0.0,
                         &s, NULL, NULL);
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

static int read_impl(const char *path, int band_no, tsio_raster *out, tsio_err *err)
{
    GDALDatasetH ds = NULL;
    GDALRasterBandH band, mask_band = NULL;
    OGRSpatialReferenceH srs = NULL;
    double *buf = NULL;
    unsigned char *mask = NULL;
    int rc = -1, w, h, nbands, ok = 0, mask_flags, y0, rows;
    double scale, offset, vscale = 1.0, nodata = 0.0;
    float nodata_f = 0.0f;
    int has_nodata = 0, compare_float = 0, known_unit;
    size_t ncells, chunk_rows, n_valid = 0;
    GDALDataType dt;
    const char *unit;

    CPLErrorReset();
    ds = GDALOpenEx(path, GDAL_OF_RASTER | GDAL_OF_READONLY | GDAL_OF_VERBOSE_ERROR, NULL, NULL,
                    NULL);
    if (!ds) {
        char g[768];
        gdal_last_msg(g, sizeof g);
        /* connection strings ("NETCDF:f.nc:z") are not files: keep GDAL's verdict */
        if (!path_exists(path, NULL) && (!strchr(path, ':') || starts_with(path, "/vsi")))
            tsio_errf(err, path, "no such file");
        else if (g[0] && !strstr(g, "not recognized as a supported file format"))
            tsio_errf(err, path, "not a raster GDAL can open (%s)", g);
        else
            tsio_errf(err, path, "not a raster GDAL can open");
        return -1;
    }

    nbands = GDALGetRasterCount(ds);
    if (nbands < 1) {
        tsio_errf(err, path, "the file has no raster bands");
        goto done;
    }
    if (band_no < 1 || band_no > nbands) {
        tsio_errf(err, path, "band %d does not exist (the file has %d band%s)", band_no, nbands,
                  nbands == 1 ? "" : "s");
        goto done;
    }
    w = GDALGetRasterXSize(ds);
    h = GDALGetRasterYSize(ds);
    if (w <= 0 || h <= 0) {
        tsio_errf(err, path, "empty raster (%d x %d cells)", w, h);
        goto done;
    }
    if ((size_t)w > SIZE_MAX / (size_t)h
        || (size_t)w * (size_t)h > (size_t)PTRDIFF_MAX / sizeof(double)) {
        tsio_errf(err, path, "raster too large (%d x %d cells)", w, h);
        goto done;
    }
    ncells = (size_t)w * (size_t)h;
    out->geo.width = w;
    out->geo.height = h;

    /* geotransform */
    if (GDALGetGeoTransform(ds, out->geo.gt) == CE_None) {
        int i;
        out->geo.has_gt = 1;
        if (out->geo.gt[2] != 0.0 || out->geo.gt[4] != 0.0) {
            tsio_errf(err, path, "rotated geotransforms are not supported");
            goto done;
        }
        for (i = 0; i < 6; i++)
            if (!isfinite(out->geo.gt[i])) {
                tsio_errf(err, path, "the geotransform is not finite");
                goto done;
            }
        if (out->geo.gt[1] == 0.0 || out->geo.gt[5] == 0.0) {
            tsio_errf(err, path, "the geotransform has a zero cell size");
            goto done;
        }
    } else {
        static const double identity[6] = {0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
        memcpy(out->geo.gt, identity, sizeof identity);
        out->geo.has_gt = 0;
    }
    CPLErrorReset();

    /* CRS */
    {
        OGRSpatialReferenceH s = GDALGetSpatialRef(ds);
        if (s) {
            srs = OSRClone(s);
            if (!srs) {
                tsio_errf(err, path, "out of memory");
                goto done;
            }
            OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
            out->geo.wkt = srs_to_wkt2(srs);
            if (!out->geo.wkt) {
                set_err_gdal(err, path, "cannot export the CRS as WKT");
                goto done;
            }
            out->geo.is_geographic = OSRIsGeographic(srs) ? 1 : 0;
        }
    }

    /* band properties */
    band = GDALGetRasterBand(ds, band_no);
    dt = GDALGetRasterDataType(band);
    if (dt == GDT_Int64) {
        int64_t v = GDALGetRasterNoDataValueAsInt64(band, &ok);
        nodata = (double)v;
    } else if (dt == GDT_UInt64) {
        uint64_t v = GDALGetRasterNoDataValueAsUInt64(band, &ok);
        nodata = (double)v;
    } else {
        nodata = GDALGetRasterNoDataValue(band, &ok);
    }
    has_nodata = ok ? 1 : 0;
    if (has_nodata) {
        out->has_nodata = 1;
        out->nodata = nodata;
        /* Float32 files store the nodata value as a float: compare as floats */
        if ((dt == GDT_Float32 || dt == GDT_CFloat32) && isfinite(nodata)
            && fabs(nodata) <= FLT_MAX) {
            compare_float = 1;
            nodata_f = (float)nodata;
        }
    }
    scale = GDALGetRasterScale(band, &ok);
    if (!ok || !isfinite(scale))
        scale = 1.0;
    offset = GDALGetRasterOffset(band, &ok);
    if (!ok || !isfinite(offset))
        offset = 0.0;
    unit = GDALGetRasterUnitType(band);
    if (!unit)
        unit = "";
    while (*unit == ' ')
        unit++;
    vscale = vertical_unit_factor(unit, &known_unit);
    if (!unit[0] && srs && OSRIsCompound(srs)) {
        double f = OSRGetTargetLinearUnits(srs, "VERT_CS", NULL);
        if (f > 0.0 && isfinite(f))
            vscale = f;
    }
    out->vertical_scale = vscale;
    CPLErrorReset();

    /* buffers */
    out->r.data = malloc(ncells * sizeof(float));
    chunk_rows = TSIO_CHUNK_CELLS / (size_t)w;
    if (chunk_rows < 1)
        chunk_rows = 1;
    if (chunk_rows > (size_t)h)
        chunk_rows = (size_t)h;
    buf = malloc(chunk_rows * (size_t)w * sizeof(double));
    mask_flags = GDALGetMaskFlags(band);
    /* A mask derived only from the nodata value adds nothing to the nodata
     * test below (and would read the data twice); any other mask is read. */
    if (!(mask_flags & GMF_ALL_VALID) && !(mask_flags == GMF_NODATA && has_nodata)) {
        mask_band = GDALGetMaskBand(band);
        if (mask_band)
            mask = malloc(chunk_rows * (size_t)w);
    }
    if (!out->r.data || !buf || (mask_band && !mask)) {
        tsio_errf(err, path, "out of memory (%d x %d cells)", w, h);
        goto done;
    }
    out->r.width = w;
    out->r.height = h;
    out->r.stride = w;

    for (y0 = 0; y0 < h; y0 += rows) {
        size_t i, n;
        float *dst;
        rows = (int)((size_t)(h - y0) < chunk_rows ? (size_t)(h - y0) : chunk_rows);
        n = (size_t)rows * (size_t)w;
        if (GDALRasterIOEx(band, GF_Read, 0, y0, w, rows, buf, w, rows, GDT_Float64,
                           (GSpacing)sizeof(double), (GSpacing)sizeof(double) * w, NULL)
            != CE_None) {
            set_err_gdal(err, path, "read error");
            goto done;
        }
        if (mask_band
            && GDALRasterIOEx(mask_band, GF_Read, 0, y0, w, rows, mask, w, rows, GDT_Byte, 1,
                              (GSpacing)w, NULL)
                   != CE_None) {
            set_err_gdal(err, path, "cannot read the mask band");
            goto done;
        }
        dst = out->r.data + (size_t)y0 * (size_t)w;
        for (i = 0; i < n; i++) {
            double v = buf[i];
            int bad = !isfinite(v);
            if (!bad && has_nodata) {
                if (compare_float)
                    bad = fabs(v) <= FLT_MAX && (float)v == nodata_f;
                else
                    bad = (v == nodata);
            }
            if (!bad && mask && mask[i] == 0)
                bad = 1;
            if (!bad) {
                v = (v * scale + offset) * vscale;
                if (!isfinite(v) || fabs(v) > FLT_MAX)
                    bad = 1;
            }
            if (bad) {
                dst[i] = NAN;
            } else {
                dst[i] = (float)v;
                n_valid++;
            }
        }
    }
    if (n_valid == 0) {
        tsio_errf(err, path, "every cell is nodata");
        goto done;
    }

    /* ground metrics */
    if (srs && out->geo.has_gt) {
        char why[256] = "";
        out->dx_m = malloc((size_t)h * sizeof(double));
        out->dy_m = malloc((size_t)h * sizeof(double));
        if (!out->dx_m || !out->dy_m) {
            tsio_errf(err, path, "out of memory");
            goto done;
        }
        if (compute_metrics(srs, out->geo.gt, h, out->dx_m, out->dy_m, why, sizeof why) != 0) {
            tsio_errf(err, path, "%s", why);
            goto done;
        }
    }
    rc = 0;

done:
    free(buf);
    free(mask);
    if (srs)
        OSRDestroySpatialReference(srs);
    if (ds)
        GDALClose(ds);
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
    ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = read_impl(path, band, out, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    if (rc != 0)
        tsio_raster_free(out);
    return rc;
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
        out->wkt = str_dup(src->wkt);
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

/* ------------------------------------------------------------------ */
/* Raster writing                                                      */
/* ------------------------------------------------------------------ */

/* What to write: one Float32 band from a ts_raster, one Byte band, or
 * three pixel-interleaved Byte bands. */
typedef struct raster_src {
    int width, height, nbands;
    GDALDataType type;
    const ts_raster *fdata; /* Float32 source */
    float nodata_f;         /* NaN is replaced by this */
    const unsigned char *bytes; /* Byte source, stride width*nbands */
} raster_src;

/* Output driver from the extension; NULL for ".vrt" (refused).  Unknown
 * extensions get GTiff: guessing from every driver's extension list picks
 * surprising formats (".dat" would be ZMap, ".xyz" cannot store nodata). */
static GDALDriverH raster_driver_for_ext(const char *ext, int *refused)
{
    static const struct {
        const char *ext, *driver;
    } table[] = {{"tif", "GTiff"},   {"tiff", "GTiff"},  {"png", "PNG"}, {"jpg", "JPEG"},
                 {"jpeg", "JPEG"},   {"asc", "AAIGrid"}, {"img", "HFA"}, {"nc", "netCDF"},
                 {"gpkg", "GPKG"},   {"bil", "EHdr"},    {"bt", "BT"}};
    size_t i;
    *refused = 0;
    if (str_ieq(ext, "vrt")) {
        *refused = 1;
        return NULL;
    }
    for (i = 0; i < sizeof table / sizeof table[0]; i++)
        if (str_ieq(ext, table[i].ext)) {
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
            set_err_gdal(err, path, "cannot store the geotransform");
            return -1;
        }
    }
    if (geo && geo->wkt && geo->wkt[0]) {
        OGRSpatialReferenceH srs = srs_from_wkt(geo->wkt);
        CPLErr e;
        if (!srs) {
            tsio_errf(err, path, "the CRS (WKT) is invalid");
            return -1;
        }
        CPLErrorReset();
        e = GDALSetSpatialRef(ds, srs);
        OSRDestroySpatialReference(srs);
        if (e != CE_None) {
            set_err_gdal(err, path, "cannot store the CRS");
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
    int w = src->width, h = src->height, y0, rows;
    size_t chunk_rows = TSIO_CHUNK_CELLS / (size_t)w;
    float *fbuf = NULL;
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
            e = GDALRasterIOEx(GDALGetRasterBand(ds, 1), GF_Write, 0, y0, w, rows, fbuf, w,
                               rows, GDT_Float32, (GSpacing)sizeof(float),
                               (GSpacing)sizeof(float) * w, NULL);
        } else {
            GSpacing nb = src->nbands;
            unsigned char *p = (unsigned char *)(uintptr_t)(src->bytes
                                                            + (size_t)y0 * (size_t)w
                                                                  * (size_t)src->nbands);
            e = GDALDatasetRasterIOEx(ds, GF_Write, 0, y0, w, rows, p, w, rows, GDT_Byte,
                                      src->nbands, NULL, nb, nb * w, 1, NULL);
        }
        if (e != CE_None) {
            set_err_gdal(err, path, "write error");
            free(fbuf);
            return -1;
        }
    }
    free(fbuf);
    return 0;
}

/* Close a dataset and report whether GDAL flagged a failure while flushing. */
static int close_checked(GDALDatasetH ds, const char *path, tsio_err *err)
{
    CPLErrorReset();
    GDALClose(ds);
    if (CPLGetLastErrorType() == CE_Failure || CPLGetLastErrorType() == CE_Fatal) {
        set_err_gdal(err, path, "write error");
        return -1;
    }
    return 0;
}

static const char *type_name(GDALDataType t)
{
    const char *n = GDALGetDataTypeName(t);
    return n ? n : "?";
}

static int write_raster_impl(const char *path, const tsio_write_opts *opts,
                             const char *forced_format, const tsio_georef *geo,
                             const raster_src *src_in, int has_nodata, double nodata,
                             tsio_err *err)
{
    raster_src src_copy = *src_in;
    raster_src *src = &src_copy;
    int nodata_stored = 0;
    GDALDriverH drv = NULL, mem_drv;
    GDALDatasetH ds = NULL, mem = NULL;
    char **copts = NULL;
    const char *drv_name, *types;
    out_name on;
    int rc = -1, created = 0, i, can_create, can_copy;

    memset(&on, 0, sizeof on);
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (src->width <= 0 || src->height <= 0) {
        tsio_errf(err, path, "empty raster (%d x %d cells)", src->width, src->height);
        return -1;
    }
    if (geo && geo->width > 0 && geo->height > 0
        && (geo->width != src->width || geo->height != src->height)) {
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
    if (out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }

    /* driver */
    if (forced_format) {
        drv = GDALGetDriverByName(forced_format);
        if (!drv) {
            tsio_errf(err, path, "the %s driver is not available", forced_format);
            goto done;
        }
    } else if (opts && opts->format && opts->format[0]) {
        drv = GDALGetDriverByName(opts->format);
        if (!drv) {
            tsio_errf(err, path, "unknown output format %s", opts->format);
            goto done;
        }
    } else {
        int refused = 0;
        drv = raster_driver_for_ext(on.ext, &refused);
        if (refused) {
            tsio_errf(err, path, "cannot write VRT: choose a format that stores the cells");
            goto done;
        }
        if (!drv) {
            tsio_errf(err, path, "the GTiff driver is not available");
            goto done;
        }
    }
    drv_name = GDALGetDriverShortName(drv);
    if (!driver_has(drv, GDAL_DCAP_RASTER)) {
        tsio_errf(err, path, "format %s cannot write rasters", drv_name);
        goto done;
    }
    if (str_ieq(drv_name, "MEM") || str_ieq(drv_name, "VRT")) {
        tsio_errf(err, path, "format %s cannot write files", drv_name);
        goto done;
    }
    can_create = driver_has(drv, GDAL_DCAP_CREATE);
    can_copy = driver_has(drv, GDAL_DCAP_CREATECOPY);
    if (!can_create && !can_copy) {
        tsio_errf(err, path, "format %s cannot write files", drv_name);
        goto done;
    }
    types = GDALGetMetadataItem(drv, GDAL_DMD_CREATIONDATATYPES, NULL);
    if (types && types[0] && !list_has_word(types, type_name(src->type))) {
        tsio_errf(err, path, "format %s cannot store %s data (it takes %s)", drv_name,
                  type_name(src->type), types);
        goto done;
    }

    /* creation options */
    if (opts && opts->create_options) {
        for (i = 0; opts->create_options[i]; i++) {
            const char *o = opts->create_options[i];
            const char *eq = strchr(o, '=');
            if (!eq || eq == o) {
                tsio_errf(err, path, "invalid creation option \"%s\" (expected KEY=VALUE)", o);
                goto done;
            }
            copts = CSLAddString(copts, o);
        }
        CPLErrorReset();
        if (copts && !GDALValidateCreationOptions(drv, (CSLConstList)copts)) {
            set_err_gdal(err, path, "invalid creation option");
            goto done;
        }
    }
    /* GeoPackage names its raster table after the file: use the final name */
    if (str_ieq(drv_name, "GPKG") && !CSLFetchNameValue(copts, "RASTER_TABLE") && on.stem[0])
        copts = CSLSetNameValue(copts, "RASTER_TABLE", on.stem);

    if (check_output_location(&on, path, err) != 0)
        goto done;
    if (opts && opts->check_only) {
        rc = 0;
        goto done;
    }

    /* write the temporary dataset */
    CPLErrorReset();
    created = 1;
    if (can_create) {
        ds = GDALCreate(drv, on.temp, src->width, src->height, src->nbands, src->type, copts);
        if (!ds) {
            set_err_gdal(err, path, "cannot create the file");
            goto done;
        }
        if (apply_georef(ds, geo, src->nbands, has_nodata, nodata, &nodata_stored, path, err)
                != 0
            || settle_nodata(src, has_nodata, nodata_stored, drv_name, path, err) != 0
            || fill_dataset(ds, src, path, err) != 0)
            goto done;
        i = close_checked(ds, path, err);
        ds = NULL;
        if (i != 0)
            goto done;
    } else {
        mem_drv = GDALGetDriverByName("MEM");
        if (!mem_drv) {
            tsio_errf(err, path, "the MEM driver is not available");
            goto done;
        }
        mem = GDALCreate(mem_drv, "", src->width, src->height, src->nbands, src->type, NULL);
        if (!mem) {
            set_err_gdal(err, path, "cannot create the in-memory copy");
            goto done;
        }
        if (apply_georef(mem, geo, src->nbands, has_nodata, nodata, &nodata_stored, path, err)
                != 0
            || settle_nodata(src, has_nodata, nodata_stored, drv_name, path, err) != 0
            || fill_dataset(mem, src, path, err) != 0)
            goto done;
        CPLErrorReset();
        ds = GDALCreateCopy(drv, on.temp, mem, FALSE, copts, NULL, NULL);
        if (!ds) {
            set_err_gdal(err, path, "cannot create the file");
            goto done;
        }
        i = close_checked(ds, path, err);
        ds = NULL;
        if (i != 0)
            goto done;
    }

    /* move it into place */
    if (remove_existing(on.final, path, err) != 0)
        goto done;
    CPLErrorReset();
    if (GDALRenameDataset(drv, on.final, on.temp) != CE_None) {
        /* e.g. a driver whose rename cannot reopen the file: move the files ourselves */
        CPLErrorReset();
        if (rename_temp_files(&on, path, err) != 0)
            goto done;
    }
    rc = 0;

done:
    if (ds)
        GDALClose(ds);
    if (mem)
        GDALClose(mem);
    if (rc != 0 && created)
        remove_temp_files(&on);
    CSLDestroy(copts);
    out_name_free(&on);
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
    ensure_registered();
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

/* ------------------------------------------------------------------ */
/* Vector writing                                                      */
/* ------------------------------------------------------------------ */

static const char *vector_driver_for_ext(const char *ext)
{
    static const struct {
        const char *ext, *driver;
    } table[] = {{"gpkg", "GPKG"},         {"shp", "ESRI Shapefile"}, {"geojson", "GeoJSON"},
                 {"json", "GeoJSON"},      {"kml", "KML"},            {"fgb", "FlatGeobuf"},
                 {"sqlite", "SQLite"},     {"gml", "GML"}};
    size_t i;
    for (i = 0; i < sizeof table / sizeof table[0]; i++)
        if (str_ieq(ext, table[i].ext))
            return table[i].driver;
    return NULL;
}

/* Formats that hold one layer per file. */
static int single_layer_driver(const char *name)
{
    return str_ieq(name, "ESRI Shapefile") || str_ieq(name, "GeoJSON")
           || str_ieq(name, "FlatGeobuf");
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
    const ts_features *f;
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

static int write_paths_layer(GDALDatasetH ds, const vec_ctx *c)
{
    const ts_features *f = c->f;
    OGRLayerH layer;
    OGRFeatureH feat = NULL;
    int i_kind, i_len_m, i_len_c, i_mean, i_min, i_max, i_start, i_end, rc = -1, tx = 0;
    size_t i;

    CPLErrorReset();
    layer = GDALDatasetCreateLayer(ds, "paths", c->srs, wkbLineString, NULL);
    if (!layer) {
        set_err_gdal(c->err, c->path, "cannot create the layer \"paths\"");
        return -1;
    }
    if (add_field(layer, "kind", OFTString, &i_kind) || add_field(layer, "length_m", OFTReal, &i_len_m)
        || add_field(layer, "length_cells", OFTReal, &i_len_c)
        || add_field(layer, "mean_elev", OFTReal, &i_mean)
        || add_field(layer, "min_elev", OFTReal, &i_min)
        || add_field(layer, "max_elev", OFTReal, &i_max)
        || add_field(layer, "start_kind", OFTString, &i_start)
        || add_field(layer, "end_kind", OFTString, &i_end)) {
        set_err_gdal(c->err, c->path, "cannot create the fields of layer \"paths\"");
        return -1;
    }
    tx = GDALDatasetStartTransaction(ds, FALSE) == OGRERR_NONE;
    feat = OGR_F_Create(OGR_L_GetLayerDefn(layer));
    if (!feat) {
        tsio_errf(c->err, c->path, "out of memory");
        goto done;
    }
    for (i = 0; i < f->n_paths; i++) {
        const ts_feature_path *p = &f->paths[i];
        const ts_feature_vertex *v = &f->verts[p->first];
        OGRGeometryH line = OGR_G_CreateGeometry(wkbLineString);
        double len_c = 0.0, len_m = 0.0;
        size_t k, npts = p->count < 2 ? 2 : p->count;
        if (!line || npts > INT_MAX) {
            if (line)
                OGR_G_DestroyGeometry(line);
            tsio_errf(c->err, c->path, "cannot build the line of path %zu", i);
            goto done;
        }
        OGR_G_SetPointCount(line, (int)npts);
        for (k = 0; k < npts; k++) {
            const ts_feature_vertex *q = &v[k < p->count ? k : p->count - 1];
            OGR_G_SetPoint_2D(line, (int)k, cx(c, q->x, q->y), cy(c, q->x, q->y));
        }
        for (k = 1; k < p->count; k++) {
            int ddx = v[k].x - v[k - 1].x, ddy = v[k].y - v[k - 1].y;
            len_c += sqrt((double)ddx * ddx + (double)ddy * ddy);
            if (c->metrics) {
                double mx = 0.5 * (c->metrics->dx[v[k].y] + c->metrics->dx[v[k - 1].y]);
                double my = 0.5 * (c->metrics->dy[v[k].y] + c->metrics->dy[v[k - 1].y]);
                len_m += sqrt((mx * ddx) * (mx * ddx) + (my * ddy) * (my * ddy));
            }
        }
        OGR_F_SetFID(feat, OGRNullFID);
        OGR_F_SetFieldString(feat, i_kind, kind_name(p->kind));
        if (c->metrics)
            set_real_or_null(feat, i_len_m, len_m);
        else
            OGR_F_SetFieldNull(feat, i_len_m);
        OGR_F_SetFieldDouble(feat, i_len_c, len_c);
        set_real_or_null(feat, i_mean, p->zmean);
        set_real_or_null(feat, i_min, p->zmin);
        set_real_or_null(feat, i_max, p->zmax);
        OGR_F_SetFieldString(feat, i_start, node_kind_name(f->nodes[p->node_a].degree));
        OGR_F_SetFieldString(feat, i_end, node_kind_name(f->nodes[p->node_b].degree));
        OGR_F_SetGeometryDirectly(feat, line);
        CPLErrorReset();
        if (OGR_L_CreateFeature(layer, feat) != OGRERR_NONE) {
            set_err_gdal(c->err, c->path, "cannot write a path");
            goto done;
        }
    }
    if (tx) {
        tx = 0;
        CPLErrorReset();
        if (GDALDatasetCommitTransaction(ds) != OGRERR_NONE) {
            set_err_gdal(c->err, c->path, "cannot commit the paths");
            goto done;
        }
    }
    rc = 0;
done:
    if (feat)
        OGR_F_Destroy(feat);
    if (tx)
        GDALDatasetRollbackTransaction(ds);
    return rc;
}

static int write_nodes_layer(GDALDatasetH ds, const vec_ctx *c, const char *shown_path)
{
    const ts_features *f = c->f;
    OGRLayerH layer;
    OGRFeatureH feat = NULL;
    int i_kind, i_degree, i_elev, i_feature, rc = -1, tx = 0;
    size_t i;

    CPLErrorReset();
    layer = GDALDatasetCreateLayer(ds, "nodes", c->srs, wkbPoint, NULL);
    if (!layer) {
        set_err_gdal(c->err, shown_path, "cannot create the layer \"nodes\"");
        return -1;
    }
    if (add_field(layer, "kind", OFTString, &i_kind) || add_field(layer, "degree", OFTInteger, &i_degree)
        || add_field(layer, "elev", OFTReal, &i_elev)
        || add_field(layer, "feature", OFTString, &i_feature)) {
        set_err_gdal(c->err, shown_path, "cannot create the fields of layer \"nodes\"");
        return -1;
    }
    tx = GDALDatasetStartTransaction(ds, FALSE) == OGRERR_NONE;
    feat = OGR_F_Create(OGR_L_GetLayerDefn(layer));
    if (!feat) {
        tsio_errf(c->err, shown_path, "out of memory");
        goto done;
    }
    for (i = 0; i < f->n_nodes; i++) {
        const ts_feature_node *n = &f->nodes[i];
        OGRGeometryH pt = OGR_G_CreateGeometry(wkbPoint);
        if (!pt) {
            tsio_errf(c->err, shown_path, "out of memory");
            goto done;
        }
        OGR_G_SetPoint_2D(pt, 0, cx(c, n->x, n->y), cy(c, n->x, n->y));
        OGR_F_SetFID(feat, OGRNullFID);
        OGR_F_SetFieldString(feat, i_kind, node_kind_name(n->degree));
        OGR_F_SetFieldInteger(feat, i_degree, n->degree);
        set_real_or_null(feat, i_elev, n->z);
        OGR_F_SetFieldString(feat, i_feature, kind_name(n->kind));
        OGR_F_SetGeometryDirectly(feat, pt);
        CPLErrorReset();
        if (OGR_L_CreateFeature(layer, feat) != OGRERR_NONE) {
            set_err_gdal(c->err, shown_path, "cannot write a node");
            goto done;
        }
    }
    if (tx) {
        tx = 0;
        CPLErrorReset();
        if (GDALDatasetCommitTransaction(ds) != OGRERR_NONE) {
            set_err_gdal(c->err, shown_path, "cannot commit the nodes");
            goto done;
        }
    }
    rc = 0;
done:
    if (feat)
        OGR_F_Destroy(feat);
    if (tx)
        GDALDatasetRollbackTransaction(ds);
    return rc;
}

static int write_features_impl(const char *path, const tsio_georef *geo, const ts_features *f,
                               const ts_grid_metrics *metrics, tsio_err *err)
{
    out_name main_n, nodes_n;
    char *nodes_stem = NULL;
    const char *drv_name;
    GDALDriverH drv;
    GDALDatasetH ds = NULL, nds = NULL;
    vec_ctx c;
    int rc = -1, sibling, created = 0, ncreated = 0, renamed = 0, i;

    memset(&main_n, 0, sizeof main_n);
    memset(&nodes_n, 0, sizeof nodes_n);
    memset(&c, 0, sizeof c);
    if (!path || !path[0]) {
        tsio_errf(err, "(empty path)", "no output file given");
        return -1;
    }
    if (!f) {
        tsio_errf(err, path, "no features given");
        return -1;
    }
    if (geo && geo->width > 0 && geo->height > 0 && f->width > 0 && f->height > 0
        && (geo->width != f->width || geo->height != f->height)) {
        tsio_errf(err, path, "the georeferencing is for %d x %d cells but the features for %d x %d",
                  geo->width, geo->height, f->width, f->height);
        return -1;
    }
    if (check_features(f, path, err) != 0)
        return -1;
    if (out_name_for(path, &main_n) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    drv_name = vector_driver_for_ext(main_n.ext);
    if (!drv_name) {
        tsio_errf(err, path, "cannot tell the vector format from the extension");
        goto done;
    }
    drv = GDALGetDriverByName(drv_name);
    if (!drv || !driver_has(drv, GDAL_DCAP_VECTOR) || !driver_has(drv, GDAL_DCAP_CREATE)) {
        tsio_errf(err, path, "the %s driver is not available for writing", drv_name);
        goto done;
    }
    if (check_output_location(&main_n, path, err) != 0)
        goto done;

    c.path = path;
    c.f = f;
    c.err = err;
    c.metrics = (metrics && metrics->dx && metrics->dy) ? metrics : NULL;
    if (geo && geo->has_gt) {
        memcpy(c.gt, geo->gt, sizeof c.gt);
        for (i = 0; i < 6; i++)
            if (!isfinite(c.gt[i])) {
                tsio_errf(err, path, "the geotransform is not finite");
                goto done;
            }
    } else {
        c.gt[1] = 1.0;
        c.gt[5] = 1.0;
    }
    if (geo && geo->wkt && geo->wkt[0]) {
        c.srs = srs_from_wkt(geo->wkt);
        if (!c.srs) {
            tsio_errf(err, path, "the CRS (WKT) is invalid");
            goto done;
        }
    }

    /* the paths (and, for multi-layer formats, the nodes) */
    CPLErrorReset();
    created = 1;
    ds = GDALCreate(drv, main_n.temp, 0, 0, 0, GDT_Unknown, NULL);
    if (!ds) {
        set_err_gdal(err, path, "cannot create the file");
        goto done;
    }
    if (write_paths_layer(ds, &c) != 0)
        goto done;
    sibling = single_layer_driver(drv_name) || !GDALDatasetTestCapability(ds, ODsCCreateLayer);
    if (!sibling && write_nodes_layer(ds, &c, path) != 0)
        goto done;
    i = close_checked(ds, path, err);
    ds = NULL;
    if (i != 0)
        goto done;

    /* the nodes in "<stem>_nodes.<ext>" */
    if (sibling) {
        nodes_stem = str_fmt("%s_nodes", main_n.stem);
        if (!nodes_stem || out_name_make(main_n.dir, nodes_stem, main_n.ext, &nodes_n) != 0) {
            tsio_errf(err, path, "out of memory");
            goto done;
        }
        CPLErrorReset();
        ncreated = 1;
        nds = GDALCreate(drv, nodes_n.temp, 0, 0, 0, GDT_Unknown, NULL);
        if (!nds) {
            set_err_gdal(err, nodes_n.final, "cannot create the file");
            goto done;
        }
        if (write_nodes_layer(nds, &c, nodes_n.final) != 0)
            goto done;
        i = close_checked(nds, nodes_n.final, err);
        nds = NULL;
        if (i != 0)
            goto done;
    }

    /* move into place (GDAL 3.6's GDALRenameDataset reopens as raster only,
     * so the files of the temporary dataset are renamed here) */
    if (remove_existing(main_n.final, path, err) != 0)
        goto done;
    if (sibling && remove_existing(nodes_n.final, nodes_n.final, err) != 0)
        goto done;
    if (rename_temp_files(&main_n, path, err) != 0)
        goto done;
    renamed = 1;
    if (sibling && rename_temp_files(&nodes_n, nodes_n.final, err) != 0)
        goto done;
    rc = 0;

done:
    if (ds)
        GDALClose(ds);
    if (nds)
        GDALClose(nds);
    if (rc != 0) {
        if (created)
            remove_temp_files(&main_n);
        if (ncreated)
            remove_temp_files(&nodes_n);
        if (renamed) {
            /* the nodes could not follow: do not leave half an output */
            GDALDriverH d = GDALIdentifyDriver(main_n.final, NULL);
            if (d)
                GDALDeleteDataset(d, main_n.final);
            if (path_exists(main_n.final, NULL))
                VSIUnlink(main_n.final);
        }
    }
    if (c.srs)
        OSRDestroySpatialReference(c.srs);
    free(nodes_stem);
    out_name_free(&main_n);
    out_name_free(&nodes_n);
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
    ensure_registered();
    if (out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    drv_name = vector_driver_for_ext(on.ext);
    if (!drv_name)
        tsio_errf(err, path, "cannot tell the vector format from the extension");
    else if (!(drv = GDALGetDriverByName(drv_name)) || !driver_has(drv, GDAL_DCAP_VECTOR) ||
             !driver_has(drv, GDAL_DCAP_CREATE))
        tsio_errf(err, path, "the %s driver is not available for writing", drv_name);
    else
        rc = check_output_location(&on, path, err);
    out_name_free(&on);
    return rc;
}

int tsio_write_features(const char *path, const tsio_georef *geo, const ts_features *f,
                        const ts_grid_metrics *metrics, tsio_err *err)
{
    int rc;
    if (err)
        err->msg[0] = '\0';
    ensure_registered();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    rc = write_features_impl(path, geo, f, metrics, err);
    CPLErrorReset();
    CPLPopErrorHandler();
    return rc;
}

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
        set_err_gdal(err, path, "cannot read the resampled raster");
        goto fail;
    }
    srs = wkt && wkt[0] ? srs_from_wkt(wkt) : NULL;
    if (!srs || compute_metrics(srs, gt, h, dx, dy, why, sizeof why) != 0) {
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
    out->geo.wkt = srs_to_wkt2(srs);
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
static int resample_no_crs(const char *path, double cell_m, double target_dx_m,
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
        argv[6] = f > 1.0 ? "cubicspline" : "average";
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

int tsio_read_raster_resampled(const char *path, int band, double target_dx_m,
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
    if (tsio_read_raster(path, band, out, err) != 0)
        return -1;
    if (!(target_dx_m > 0) || !(target_dy_m > 0))
        return 0; /* nothing asked: cells as they are */
    if (!out->dx_m)
        return no_crs_cell_m > 0 ? resample_no_crs(path, no_crs_cell_m, target_dx_m, target_dy_m,
                                                     out, factor, err)
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
    srs = srs_from_wkt(out->geo.wkt);
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
    alg = f > 1.0 ? "cubicspline" : "average"; /* finer target: interpolate; coarser: average */
    {
        char *argv[] = {"-of", "MEM", "-t_srs", t_srs, "-tr", trx, try_, "-r", (char *)alg,
                        "-dstnodata", "nan", "-ot", "Float32", NULL};
        src = mem_from_raster(out);
        wo = GDALWarpAppOptionsNew(argv, NULL);
        if (!src || !wo) {
            tsio_errf(err, path, "cannot prepare the resampling");
            goto done;
        }
        dst = GDALWarp("", NULL, 1, &src, wo, &usage);
        if (!dst) {
            set_err_gdal(err, path, "resampling failed");
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
    srs = srs_from_wkt(geo->wkt);
    if (!srs) {
        tsio_errf(err, "output grid", "cannot read the CRS");
        return -1;
    }
    *dx = malloc((size_t)geo->height * sizeof **dx);
    *dy = malloc((size_t)geo->height * sizeof **dy);
    if (!*dx || !*dy || compute_metrics(srs, geo->gt, geo->height, *dx, *dy, why, sizeof why)) {
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
    ensure_registered();
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
    geo->has_gt = GDALGetGeoTransform(ds, geo->gt) == CE_None;
    if (!geo->has_gt) {
        double id[6] = {0, 1, 0, 0, 0, 1};
        memcpy(geo->gt, id, sizeof id);
    }
    if (geo->gt[2] != 0.0 || geo->gt[4] != 0.0) {
        tsio_errf(err, path, "rotated geotransforms are not supported");
        GDALClose(ds);
        return -1;
    }
    wkt = GDALGetProjectionRef(ds);
    if (wkt && wkt[0]) {
        OGRSpatialReferenceH srs = srs_from_wkt(wkt);
        if (srs) {
            geo->wkt = srs_to_wkt2(srs);
            geo->is_geographic = OSRIsGeographic(srs);
            OSRDestroySpatialReference(srs);
        }
    }
    GDALClose(ds);
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
        ensure_registered();
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
        OSRSetAxisMappingStrategy(srs, OAMS_TRADITIONAL_GIS_ORDER);
        geo->wkt = srs_to_wkt2(srs);
        geo->is_geographic = OSRIsGeographic(srs);
        OSRDestroySpatialReference(srs);
    }
    return 0;
}

/* ------------------------------------------------------------------ */
/* Label maps (regions)                                                */
/* ------------------------------------------------------------------ */

int tsio_read_label_map(const char *path, const tsio_georef *geo, const char *field, int fill,
                        int32_t *values, tsio_err *err)
{
    GDALDatasetH src, mem = NULL;
    size_t i, n = (size_t)geo->width * (size_t)geo->height;
    int rc = -1;
    ensure_registered();
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
        GDALRasterBandH b = GDALGetRasterBand(src, 1);
        int has_nd = 0;
        double nd = GDALGetRasterNoDataValue(b, &has_nd);
        if (GDALGetRasterXSize(src) != geo->width || GDALGetRasterYSize(src) != geo->height) {
            tsio_errf(err, path, "the region map is %d x %d cells, the output %d x %d",
                      GDALGetRasterXSize(src), GDALGetRasterYSize(src), geo->width, geo->height);
            goto done;
        }
        if (GDALRasterIO(b, GF_Read, 0, 0, geo->width, geo->height, values, geo->width,
                         geo->height, GDT_Int32, 0, 0) != CE_None) {
            set_err_gdal(err, path, "cannot read the region map");
            goto done;
        }
        if (has_nd)
            for (i = 0; i < n; i++)
                if ((double)values[i] == nd)
                    values[i] = fill;
        rc = 0;
    } else if (GDALDatasetGetLayerCount(src) > 0) {
        OGRLayerH layer = GDALDatasetGetLayer(src, 0);
        OGRFeatureDefnH defn = OGR_L_GetLayerDefn(layer);
        char *argv[] = {"-a", (char *)field, NULL};
        GDALRasterizeOptions *ro;
        int usage = 0;
        GDALDatasetH out;
        if (OGR_FD_GetFieldIndex(defn, field) < 0) {
            tsio_errf(err, path, "the polygon layer has no integer field \"%s\"", field);
            goto done;
        }
        mem = GDALCreate(GDALGetDriverByName("MEM"), "", geo->width, geo->height, 1, GDT_Int32,
                         NULL);
        if (!mem) {
            tsio_errf(err, path, "out of memory");
            goto done;
        }
        GDALSetGeoTransform(mem, (double *)geo->gt);
        if (geo->wkt)
            GDALSetProjection(mem, geo->wkt);
        GDALFillRaster(GDALGetRasterBand(mem, 1), fill, 0);
        ro = GDALRasterizeOptionsNew(argv, NULL);
        out = ro ? GDALRasterize(NULL, mem, src, ro, &usage) : NULL;
        if (ro)
            GDALRasterizeOptionsFree(ro);
        if (!out) {
            set_err_gdal(err, path, "cannot rasterise the region polygons");
            goto done;
        }
        if (GDALRasterIO(GDALGetRasterBand(mem, 1), GF_Read, 0, 0, geo->width, geo->height,
                         values, geo->width, geo->height, GDT_Int32, 0, 0) != CE_None) {
            set_err_gdal(err, path, "cannot read the rasterised regions");
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

int tsio_same_file(const char *a, const char *b)
{
    struct stat sa, sb;
    if (!a || !b)
        return 0;
    if (stat(a, &sa) != 0 || stat(b, &sb) != 0)
        return 0;
    return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

int tsio_make_dir(const char *dir, tsio_err *err)
{
    VSIStatBufL sb;
    if (VSIStatL(dir, &sb) == 0) {
        if (VSI_ISDIR(sb.st_mode))
            return 0;
        tsio_errf(err, dir, "exists and is not a folder");
        return -1;
    }
    if (VSIMkdir(dir, 0755) != 0) {
        tsio_errf(err, dir, "cannot create the folder");
        return -1;
    }
    return 0;
}

int tsio_path(char *buf, size_t n, const char *dir, const char *name, const char *ext,
              tsio_err *err)
{
    int k = snprintf(buf, n, "%s/%s.%s", dir, name, ext);
    if (k < 0 || (size_t)k >= n) {
        tsio_errf(err, dir, "the path is too long");
        return -1;
    }
    return 0;
}
