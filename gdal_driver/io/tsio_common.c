/*
 * tsio_common.c - what the GDAL I/O layer's files share (tsio_internal.h):
 * strings, one-line errors, output names and temporary files (all or
 * nothing), CRS helpers, file identity and folders.
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _POSIX_C_SOURCE 200809L
#define _LARGEFILE64_SOURCE 1 /* struct stat64 behind GDAL's VSIStatBufL under -std=c11 */

#include "tsio_internal.h"

#include <ctype.h>
#include <errno.h>
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
/* Small helpers: strings, errors                                      */
/* ------------------------------------------------------------------ */

char *tsio__str_dup(const char *s)
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
char *tsio__str_fmt(const char *fmt, ...)
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

int tsio__str_ieq(const char *a, const char *b)
{
    for (; *a && *b; a++, b++)
        if (tolower((unsigned char)*a) != tolower((unsigned char)*b))
            return 0;
    return *a == *b;
}

int tsio__starts_with(const char *s, const char *prefix)
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
    if (path && strlen(path) > 300) /* a name that would crowd out the problem: its ends */
        n = snprintf(buf, sizeof buf, "%.140s...%s: ", path, path + strlen(path) - 140);
    else
        n = snprintf(buf, sizeof buf, "%s: ", path ? path : "(null)");
    used = (n < 0) ? 0 : (size_t)n;
    if (used >= sizeof buf)
        used = sizeof buf - 1;
    va_start(ap, fmt);
    vsnprintf(buf + used, sizeof buf - used, fmt, ap);
    va_end(ap);
    one_line(buf);
    /* a message that already names the same thing is not prefixed twice
     * ("synth: synth: ...") */
    if (used > 0 && used < sizeof buf && !strncmp(buf + used, buf, used))
        memmove(buf, buf + used, strlen(buf + used) + 1);
    memcpy(err->msg, buf, sizeof buf);
}

/* Copy GDAL's last error message (one line, maybe empty). */
void tsio__gdal_last_msg(char *buf, size_t n)
{
    const char *m = CPLGetLastErrorMsg();
    snprintf(buf, n, "%s", m ? m : "");
    one_line(buf);
}

/* "<path>: <what>" followed by ": <GDAL's message>" when it has one. */
void tsio__set_err_gdal(tsio_err *err, const char *path, const char *what)
{
    char g[768];
    tsio__gdal_last_msg(g, sizeof g);
    if (g[0])
        tsio_errf(err, path, "%s: %s", what, g);
    else
        tsio_errf(err, path, "%s", what);
}

void tsio__ensure_registered(void)
{
    if (GDALGetDriverCount() == 0)
        GDALAllRegister();
}

int tsio__driver_has(GDALDriverH drv, const char *cap)
{
    const char *v = GDALGetMetadataItem(drv, cap, NULL);
    return v && (tsio__str_ieq(v, "YES") || tsio__str_ieq(v, "TRUE"));
}

/* Does the space-separated `list` contain `word` (case-insensitive)? */
int tsio__list_has_word(const char *list, const char *word)
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

int tsio__path_exists(const char *path, int *is_dir)
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

void tsio__out_name_free(out_name *o)
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
        return tsio__str_dup(name);
    if (strcmp(dir, "/") == 0)
        return tsio__str_fmt("/%s", name);
    return tsio__str_fmt("%s/%s", dir, name);
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
    o->final = tsio__str_dup(path);
    if (slash == path)
        o->dir = tsio__str_dup("/");
    else if (slash) {
        size_t n = (size_t)(slash - path);
        o->dir = malloc(n + 1);
        if (o->dir) {
            memcpy(o->dir, path, n);
            o->dir[n] = '\0';
        }
    } else
        o->dir = tsio__str_dup("");
    if (dot) {
        size_t n = (size_t)(dot - base);
        o->stem = malloc(n + 1);
        if (o->stem) {
            memcpy(o->stem, base, n);
            o->stem[n] = '\0';
        }
        o->ext = tsio__str_dup(dot + 1);
    } else {
        o->stem = tsio__str_dup(base);
        o->ext = tsio__str_dup("");
    }
    if (!o->final || !o->dir || !o->stem || !o->ext) {
        tsio__out_name_free(o);
        return -1;
    }
    return 0;
}

/* Does a file "<tstem>" or "<tstem>.<anything>" exist in dir?  Several
 * outputs of one job may share a stem (axes.tif, axes.png, axes.gpkg), and
 * a temporary dataset is renamed by its stem. */
static int stem_in_use(const char *dir, const char *tstem)
{
    char **entries = VSIReadDir(dir[0] ? dir : ".");
    size_t n = strlen(tstem);
    int i, used = 0;
    for (i = 0; entries && entries[i] && !used; i++)
        used = !strncmp(entries[i], tstem, n) && (entries[i][n] == '\0' || entries[i][n] == '.');
    CSLDestroy(entries);
    return used;
}

/* Build from dir/stem/ext a final name, then pick an unused temporary name. */
int tsio__out_name_make(const char *dir, const char *stem, const char *ext, out_name *o)
{
    char *base, *short_stem = NULL;
    int k;
    memset(o, 0, sizeof *o);
    o->dir = tsio__str_dup(dir);
    o->stem = tsio__str_dup(stem);
    o->ext = tsio__str_dup(ext);
    if (!o->dir || !o->stem || !o->ext)
        goto nomem;
    base = ext[0] ? tsio__str_fmt("%s.%s", stem, ext) : tsio__str_dup(stem);
    if (!base)
        goto nomem;
    o->final = join_dir(dir, base);
    free(base);
    if (!o->final)
        goto nomem;
    {
        /* the temporary name and GDAL's sidecars beside it (".aux.xml", "-journal": 12
         * bytes kept) within a file name's 255 bytes: a long stem is cut (at a whole UTF-8
         * character) in the temporary name, never in the final one */
        size_t keep = 255 - 12 - (1 + 4 + 20 + 4) - (ext[0] ? 1 + strlen(ext) : 0), len;
        len = strlen(stem);
        if (strlen(ext) > 64)
            keep = 64;
        if (len > keep) {
            while (keep > 0 && ((unsigned char)stem[keep] & 0xC0) == 0x80)
                keep--;
            short_stem = tsio__str_fmt("%.*s", (int)keep, stem);
            if (!short_stem)
                goto nomem;
            stem = short_stem;
        }
    }
    for (k = 0; k < 1000; k++) {
        long pid = (long)getpid();
        o->tstem = k ? tsio__str_fmt(".%s.tmp%ld-%d", stem, pid, k)
                     : tsio__str_fmt(".%s.tmp%ld", stem, pid);
        if (!o->tstem)
            goto nomem;
        base = ext[0] ? tsio__str_fmt("%s.%s", o->tstem, ext) : tsio__str_dup(o->tstem);
        if (!base)
            goto nomem;
        o->temp = join_dir(dir, base);
        free(base);
        if (!o->temp)
            goto nomem;
        if (!tsio__path_exists(o->temp, NULL) && !stem_in_use(dir, o->tstem)) {
            free(short_stem);
            return 0;
        }
        free(o->tstem);
        free(o->temp);
        o->tstem = o->temp = NULL;
    }
nomem:
    free(short_stem);
    tsio__out_name_free(o);
    return -1;
}

int tsio__out_name_for(const char *path, out_name *o)
{
    out_name parts;
    int rc;
    if (out_name_split(path, &parts) != 0)
        return -1;
    rc = tsio__out_name_make(parts.dir, parts.stem, parts.ext, o);
    tsio__out_name_free(&parts);
    if (rc == 0) {
        /* keep the caller's spelling of the final path */
        char *f = tsio__str_dup(path);
        if (!f) {
            tsio__out_name_free(o);
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
void tsio__remove_temp_files(const out_name *o)
{
    char **entries = VSIReadDir(o->dir[0] ? o->dir : ".");
    int i;
    for (i = 0; entries && entries[i]; i++) {
        if (temp_suffix(o, entries[i])) {
            char *full = join_dir(o->dir, entries[i]);
            int is_dir = 0;
            if (full && tsio__path_exists(full, &is_dir)) {
                if (is_dir)
                    VSIRmdirRecursive(full);
                else
                    VSIUnlink(full);
            }
            free(full);
        }
    }
    CSLDestroy(entries);
    if (o->temp && tsio__path_exists(o->temp, NULL))
        VSIUnlink(o->temp);
}

/* Rename every temporary file "<tstem><suffix>" to "<stem><suffix>". */
int tsio__rename_temp_files(const out_name *o, const char *path, tsio_err *err)
{
    char **entries = VSIReadDir(o->dir[0] ? o->dir : ".");
    int i, rc = 0, found = 0;
    for (i = 0; entries && entries[i] && rc == 0; i++) {
        const char *suffix = temp_suffix(o, entries[i]);
        char *from, *to, *newname;
        if (!suffix)
            continue;
        found = 1;
        newname = tsio__str_fmt("%s%s", o->stem, suffix);
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

/* The directory of `o` must exist and be writable; the final name must be
 * new or a regular file (never a directory, a device, a FIFO or a socket:
 * replacing /dev/null as root would destroy it). */
int tsio__check_output_location(const out_name *o, const char *path, tsio_err *err)
{
    int is_dir = 0;
    const char *dir = o->dir[0] ? o->dir : ".";
    struct stat st;
    if (tsio__path_exists(o->final, &is_dir) && is_dir) {
        tsio_errf(err, path, "is a directory");
        return -1;
    }
    if (tsio__starts_with(o->final, "/vsi") && !tsio__starts_with(o->final, "/vsimem/")) {
        /* archives (/vsizip/ ...), object stores and streams: no temporary name to rename
         * into place (a /vsizip/ output failed after the work, leaving an empty archive) */
        size_t n = strcspn(o->final + 1, "/") + 2;
        tsio_errf(err, path,
                  "is inside %.*s: outputs are written under a temporary name and moved into "
                  "place, which archives, object stores and streams cannot do; write a plain "
                  "file (and zip or upload it after)",
                  (int)n, o->final);
        return -1;
    }
    if (tsio__starts_with(o->final, "/vsi"))
        return 0; /* /vsimem/ may have implicit directories */
    if (stat(o->final, &st) == 0 && !S_ISREG(st.st_mode)) {
        tsio_errf(err, path,
                  "is not a regular file (a device, FIFO or socket): outputs are "
                  "written to regular files only");
        return -1;
    }
    if (lstat(o->final, &st) == 0 && S_ISLNK(st.st_mode) && stat(o->final, &st) != 0) {
        tsio_errf(err, path, "is a broken symbolic link");
        return -1;
    }
    if (!tsio__path_exists(dir, &is_dir)) {
        tsio_errf(err, path, "directory %s does not exist", dir);
        return -1;
    }
    if (!is_dir) {
        tsio_errf(err, path, "%s is not a directory", dir);
        return -1;
    }
    if (access(dir, W_OK | X_OK) != 0) {
        tsio_errf(err, path, "cannot write in directory %s: %s", dir, strerror(errno));
        return -1;
    }
    return 0;
}

int tsio__move_into_place(const out_name *o, const char *path, int gdal_rename, tsio_err *err)
{
    GDALDriverH drv;
    if (tsio__remove_existing(o->final, path, err) != 0)
        return -1;
    CPLErrorReset();
    CPLPushErrorHandler(CPLQuietErrorHandler);
    drv = gdal_rename ? GDALIdentifyDriver(o->temp, NULL) : NULL;
    if (drv && GDALRenameDataset(drv, o->final, o->temp) == CE_None) {
        CPLErrorReset();
        CPLPopErrorHandler();
        return 0;
    }
    CPLErrorReset();
    CPLPopErrorHandler();
    /* e.g. a driver whose rename cannot reopen the file: move the files ourselves */
    return tsio__rename_temp_files(o, path, err);
}

int tsio__finish_output(out_name *o, const char *path, int slot, int gdal_rename, tsio_err *err)
{
    int rc;
    if (tsio__stage_active())
        return tsio__stage_keep(o, path, slot, gdal_rename, err);
    rc = tsio__move_into_place(o, path, gdal_rename, err);
    tsio__temp_unregister(slot);
    return rc;
}

/* Remove an existing output (with its sidecar files) so the new one can
 * be renamed into place. */
int tsio__remove_existing(const char *final, const char *path, tsio_err *err)
{
    int is_dir = 0;
    GDALDriverH drv;
    if (!tsio__path_exists(final, &is_dir))
        return 0;
    if (is_dir) {
        tsio_errf(err, path, "is a directory");
        return -1;
    }
    drv = GDALIdentifyDriver(final, NULL);
    if (drv)
        GDALDeleteDataset(drv, final);
    if (tsio__path_exists(final, NULL))
        VSIUnlink(final);
    if (tsio__path_exists(final, NULL)) {
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
OGRSpatialReferenceH tsio__srs_from_wkt(const char *wkt)
{
    OGRSpatialReferenceH srs = OSRNewSpatialReference(NULL);
    char *copy = tsio__str_dup(wkt);
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
char *tsio__srs_to_wkt2(OGRSpatialReferenceH srs)
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
    out = tsio__str_dup(w);
    CPLFree(w);
    return out;
}

/* dir/base with dir resolved (links, "..", another spelling); NULL when the
 * folder does not exist. */
static char *canonical_name(const char *path)
{
    const char *slash = strrchr(path, '/');
    char dir[PATH_MAX], *d;
    if (!slash)
        d = realpath(".", dir);
    else if (slash == path)
        d = realpath("/", dir);
    else {
        char *part = tsio__str_dup(path);
        if (!part)
            return NULL;
        part[slash - path] = '\0';
        d = realpath(part, dir);
        free(part);
    }
    if (!d)
        return NULL;
    return tsio__str_fmt("%s/%s", strcmp(dir, "/") ? dir : "", slash ? slash + 1 : path);
}

int tsio_same_file(const char *a, const char *b)
{
    struct stat sa, sb;
    char *ca, *cb;
    int same;
    if (!a || !b)
        return 0;
    if (!strcmp(a, b))
        return 1;
    if (stat(a, &sa) == 0 && stat(b, &sb) == 0)
        return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    /* one does not exist (yet): the same name once the folders are resolved */
    ca = canonical_name(a);
    cb = canonical_name(b);
    same = ca && cb && !strcmp(ca, cb);
    free(ca);
    free(cb);
    return same;
}

int tsio_check_output_file(const char *path, tsio_err *err)
{
    out_name on;
    int rc;
    if (tsio__out_name_for(path, &on) != 0) {
        tsio_errf(err, path, "out of memory");
        return -1;
    }
    rc = tsio__check_output_location(&on, path, err);
    tsio__out_name_free(&on);
    return rc;
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
    if (tsio__stage_active())
        tsio_stage_dir_created(dir); /* removed again if the job fails */
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

/* ------------------------------------------------------------------ */
/* Memory                                                              */
/* ------------------------------------------------------------------ */

int tsio_parse_memory(const char *text, uint64_t *bytes)
{
    char *end;
    double v, ram;
    if (!text || !*text)
        return -1;
    errno = 0;
    v = strtod(text, &end);
    if (end == text || errno || !(v > 0) || !isfinite(v))
        return -1;
    while (*end == ' ')
        end++;
    ram = (double)tsio_physical_memory();
    if (!*end || tsio__str_ieq(end, "MB") || tsio__str_ieq(end, "M"))
        v *= 1048576.0; /* a plain number is in MB, as GDAL_CACHEMAX */
    else if (tsio__str_ieq(end, "K") || tsio__str_ieq(end, "KB"))
        v *= 1024.0;
    else if (tsio__str_ieq(end, "G") || tsio__str_ieq(end, "GB"))
        v *= 1073741824.0;
    else if (tsio__str_ieq(end, "T") || tsio__str_ieq(end, "TB"))
        v *= 1099511627776.0;
    else if (!strcmp(end, "%") && v <= 100.0)
        v = ram * v / 100.0;
    else
        return -1;
    if (!(v >= 1.0) || v > 1.8e19)
        return -1;
    *bytes = (uint64_t)v;
    return 0;
}

uint64_t tsio_physical_memory(void)
{
    long pages = sysconf(_SC_PHYS_PAGES), size = sysconf(_SC_PAGESIZE);
    uint64_t ram = pages > 0 && size > 0 ? (uint64_t)pages * (uint64_t)size : ((uint64_t)1 << 32);
    /* a container's own limit (cgroup v2, then v1) when it is lower */
    static const char *const files[] = {"/sys/fs/cgroup/memory.max",
                                        "/sys/fs/cgroup/memory/memory.limit_in_bytes", NULL};
    int i;
    for (i = 0; files[i]; i++) {
        FILE *f = fopen(files[i], "r");
        unsigned long long lim;
        if (!f)
            continue;
        if (fscanf(f, "%llu", &lim) == 1 && lim > 0 && lim < ram)
            ram = lim;
        fclose(f);
    }
    return ram;
}

int tsio_memory_limit(uint64_t *bytes, int *from_option, tsio_err *err)
{
    const char *opt = CPLGetConfigOption("TSYN_MAX_MEMORY", NULL);
    *from_option = 0;
    if (opt && opt[0]) {
        if (tsio_parse_memory(opt, bytes) != 0) {
            tsio_errf(err, "TSYN_MAX_MEMORY",
                      "'%s' is not an amount of memory (e.g. 2G, 500M, 512 = MB, 50%%)", opt);
            return -1;
        }
        *from_option = 1;
        return 0;
    }
    *bytes = tsio_physical_memory();
    return 0;
}

int tsio_check_memory(uint64_t need, const char *what, const char *advice, tsio_err *err)
{
    uint64_t limit;
    int from_option;
    if (tsio_memory_limit(&limit, &from_option, err) != 0)
        return -1;
    if (need <= limit)
        return 0;
    tsio_errf(err, what,
              "needs about %.3g GB of memory, more than the %.3g GB %s (--max-memory, or the "
              "configuration option TSYN_MAX_MEMORY): %s",
              need / 1073741824.0, limit / 1073741824.0,
              from_option ? "allowed" : "this machine has", advice);
    return -1;
}

int tsio_read_bytes(const char *path, size_t max_len, unsigned char **bytes, size_t *len,
                    tsio_err *err)
{
    VSILFILE *fp = VSIFOpenL(path, "rb");
    vsi_l_offset size;
    unsigned char *b;
    *bytes = NULL;
    *len = 0;
    if (!fp) {
        tsio_errf(err, path, tsio__path_exists(path, NULL) ? "cannot open" : "no such file");
        return -1;
    }
    VSIFSeekL(fp, 0, SEEK_END);
    size = VSIFTellL(fp);
    VSIFSeekL(fp, 0, SEEK_SET);
    if (size > (vsi_l_offset)max_len) {
        VSIFCloseL(fp);
        tsio_errf(err, path, "is %llu bytes, more than %zu", (unsigned long long)size, max_len);
        return -1;
    }
    b = malloc(size ? (size_t)size : 1);
    if (!b || VSIFReadL(b, 1, (size_t)size, fp) != (size_t)size) {
        VSIFCloseL(fp);
        free(b);
        tsio_errf(err, path, b ? "cannot read it" : "out of memory");
        return -1;
    }
    VSIFCloseL(fp);
    *bytes = b;
    *len = (size_t)size;
    return 0;
}

int tsio_read_head(const char *path, unsigned char *buf, size_t n, tsio_err *err)
{
    VSILFILE *fp = VSIFOpenL(path, "rb");
    size_t got;
    if (!fp) {
        tsio_errf(err, path, tsio__path_exists(path, NULL) ? "cannot open" : "no such file");
        return -1;
    }
    got = VSIFReadL(buf, 1, n, fp);
    VSIFCloseL(fp);
    return (int)got;
}
