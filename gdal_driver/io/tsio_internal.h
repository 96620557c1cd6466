/*
 * tsio_internal.h - private to the GDAL I/O layer (tsio_*.c): helpers its
 * files share.  The public side is tsio.h.
 *
 * Only the GDAL/OGR/OSR C API and PROJ's C geodesic API are used.  GDAL's
 * own error output is silenced with a quiet error handler pushed for the
 * duration of every public call (the handler stack is per thread); the
 * messages GDAL records are folded into the single-line tsio_err.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TSIO_INTERNAL_H
#define TSIO_INTERNAL_H

#include "tsio.h"

#include <gdal.h>
#include <ogr_srs_api.h>

#define TSIO_PI 3.14159265358979323846

/* Cells handled per GDAL I/O call when reading or writing in row chunks. */
#define TSIO_CHUNK_CELLS ((size_t)1 << 22)

typedef struct out_name {
    char *final; /* the path as given */
    char *dir;   /* directory part without the trailing '/', "" if none */
    char *stem;  /* file name without the extension */
    char *ext;   /* extension without the dot, "" if none */
    char *tstem; /* temporary stem ".<stem>.tmp<pid>[-k]" */
    char *temp;  /* temporary path */
} out_name;

/* The directory of `o` must exist, and the final name must not be a directory. */
int tsio__check_output_location(const out_name *o, const char *path, tsio_err *err);
int tsio__driver_has(GDALDriverH drv, const char *cap);
void tsio__ensure_registered(void);
/* The geotransform of ds into geo (north-up, finite, no zero cell size; the
 * identity without one, has_gt 0); -1 with a message naming path. */
int tsio__read_geotransform(GDALDatasetH ds, const char *path, tsio_georef *geo, tsio_err *err);
/* Copy GDAL's last error message (one line, maybe empty). */
void tsio__gdal_last_msg(char *buf, size_t n);
/* Does the space-separated `list` contain `word` (case-insensitive)? */
int tsio__list_has_word(const char *list, const char *word);
int tsio__out_name_for(const char *path, out_name *o);
void tsio__out_name_free(out_name *o);
/* Build from dir/stem/ext a final name, then pick an unused temporary name. */
int tsio__out_name_make(const char *dir, const char *stem, const char *ext, out_name *o);
int tsio__path_exists(const char *path, int *is_dir);
/* Remove an existing output (with its sidecar files) so the new one can
 * be renamed into place. */
int tsio__remove_existing(const char *final, const char *path, tsio_err *err);
/* Remove every file that belongs to the temporary dataset. */
void tsio__remove_temp_files(const out_name *o);
/* Rename every temporary file "<tstem><suffix>" to "<stem><suffix>". */
int tsio__rename_temp_files(const out_name *o, const char *path, tsio_err *err);
/* "<path>: <what>" followed by ": <GDAL's message>" when it has one. */
void tsio__set_err_gdal(tsio_err *err, const char *path, const char *what);
/* New SRS from WKT (any flavour GDAL reads), GIS axis order; NULL on error. */
OGRSpatialReferenceH tsio__srs_from_wkt(const char *wkt);
/* WKT2 (2018) of srs as a malloc'ed string; falls back to GDAL's default
 * WKT when the CRS cannot be expressed in WKT2.  NULL on failure. */
char *tsio__srs_to_wkt2(OGRSpatialReferenceH srs);
int tsio__starts_with(const char *s, const char *prefix);
char *tsio__str_dup(const char *s);
/* printf into a new malloc'ed string (NULL when out of memory). */
char *tsio__str_fmt(const char *fmt, ...);
int tsio__str_ieq(const char *a, const char *b);
/* Move a written temporary dataset to its final name (replacing a regular
 * file there): with gdal_rename, GDALRenameDataset first, else (or when it
 * fails) every "<tstem><suffix>" file renamed. */
int tsio__move_into_place(const out_name *o, const char *path, int gdal_rename, tsio_err *err);
/* The end of every output write: the temporary dataset `o` (registered as
 * `slot`) is moved into place now, or kept for tsio_stage_commit inside a
 * stage (ownership of o moves then). */
int tsio__finish_output(out_name *o, const char *path, int slot, int gdal_rename, tsio_err *err);

/* tsio_stage.c: temporary names a signal handler removes (slot, or -1). */
int tsio__temp_register(const out_name *o);
void tsio__temp_unregister(int slot);
int tsio__stage_active(void);
int tsio__stage_keep(out_name *o, const char *path, int slot, int gdal_rename, tsio_err *err);

/* Close a dataset and report whether GDAL flagged a failure while flushing. */
int tsio__close_checked(GDALDatasetH ds, const char *path, tsio_err *err);

/* tsio_read.c: per-row ground metrics of a north-up grid in `srs` (metres
 * per cell east, dx, and north, dy, geodesic).  0 or -1 (message in why). */
int tsio__compute_metrics(OGRSpatialReferenceH srs, const double gt[6], int height, double *dx,
                          double *dy, char *why, size_t whylen);

#endif
