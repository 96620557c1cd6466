/*
 * tsio.h - TerraSynth's GDAL I/O layer: rasters in and out, georeferencing,
 * ground metrics, vector and preview output.  Everything that talks to GDAL,
 * OGR or PROJ lives behind this header; the core (terrasynth.h) never does.
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * Errors: every function that can fail returns 0 on success and -1 on
 * failure, filling a tsio_err with ONE line of the form
 *   "<file>: <problem>"
 * (no trailing newline).  No function prints, exits or leaves a partial
 * output file behind: outputs are written to a temporary name in the same
 * directory and renamed into place on success.
 */
#ifndef TSIO_H
#define TSIO_H

#include <stddef.h>
#include <stdint.h>

#include "terrasynth.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The nodata value of every Float32 raster TerraSynth writes (the core's
 * NaN), as a number and as text for messages and help. */
#define TSIO_NODATA (-9999.0)
#define TSIO_NODATA_TEXT "-9999"

typedef struct tsio_err {
    char msg[1024];
} tsio_err;

/**
 * A job's outputs, all or nothing.  After tsio_stage_begin every output
 * written stays under its temporary name until tsio_stage_commit moves
 * them all into place; tsio_stage_abort removes them, and the folders
 * registered with tsio_stage_dir_created (when empty).  One stage at a
 * time, from one thread (a command's main thread).
 */
void tsio_stage_begin(void);
int tsio_stage_commit(tsio_err *err);
void tsio_stage_abort(void);
int tsio_stage_dir_created(const char *dir);
/** SIGINT, SIGTERM, SIGHUP: remove every unfinished output (temporary
 *  files, created folders), say so on stderr as "<prog>: interrupted: ...",
 *  then die by the signal.  For programs (the CLI), never for a library. */
void tsio_cleanup_on_signals(const char *prog);

/** err->msg = "<path>: <formatted problem>" on one line (the one way every
 *  wrapper file reports a problem; arguments may point into err->msg). */
void tsio_errf(tsio_err *err, const char *path, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/** Georeferencing of a grid. */
typedef struct tsio_georef {
    int width, height;
    double gt[6]; /* GDAL geotransform; north-up (gt[2] == gt[4] == 0) */
    int has_gt;   /* 0: the file had none; gt is then 0,1,0,0,0,1 */
    char *wkt;    /* CRS as WKT2; NULL when the file has no CRS (owned) */
    int is_geographic;
} tsio_georef;

/** A raster read into float metres with NaN for nodata. */
typedef struct tsio_raster {
    tsio_georef geo;
    ts_raster r;   /* owned: free with tsio_raster_free */
    double nodata; /* the file's nodata value, if has_nodata */
    int has_nodata;
    double vertical_scale; /* factor applied to reach metres (1, 0.3048, 1200/3937) */
    /* Ground metrics: per-row cell width/height in metres (owned arrays of
     * geo.height entries), or NULL when the raster has no CRS. */
    double *dx_m, *dy_m;
    size_t n_sentinels; /* tsio_read_dem: cells of +-3.4e38 taken as nodata */
} tsio_raster;

/**
 * Read band `band` (1-based) of any GDAL raster.
 * - nodata values, NaN/Inf and masked cells (GDAL mask band) become NaN;
 * - band scale/offset are applied;
 * - vertical units are converted to metres when the band unit type or the
 *   CRS's vertical axis says feet (international or US survey);
 * - a rotated geotransform is an error ("rotated geotransforms are not
 *   supported");
 * - an all-nodata raster is an error ("every cell is nodata");
 * - ground metrics: projected CRSs through their linear unit; geographic
 *   CRSs by geodesic distances (PROJ geodesic.h) on the CRS's ellipsoid at
 *   each row's latitude; no CRS: dx_m = dy_m = NULL.
 */
int tsio_read_raster(const char *path, int band, tsio_raster *out, tsio_err *err);
/** Read a drawing (a raster sketch) as grey levels: as tsio_read_raster of band 1, but a
 *  paletted band gives its colours' luminance (0.299 R + 0.587 G + 0.114 B; an index with
 *  no colour is an error) and red, green and blue bands 1-3 give theirs, so a white stroke
 *  is bright whatever its index. */
int tsio_read_drawing(const char *path, tsio_raster *out, tsio_err *err);
/** Read an elevation raster: as tsio_read_raster, then the float's extreme
 *  values (|z| >= 1e38, an undeclared nodata) become NaN (counted in
 *  out->n_sentinels: the caller warns), and any other elevation outside
 *  -12000..9000 m (after units) is an error naming the first cell. */
int tsio_read_dem(const char *path, int band, tsio_raster *out, tsio_err *err);
void tsio_raster_free(tsio_raster *r);

/** A DEM read window by window (rasters larger than memory). */
typedef struct tsio_reader tsio_reader;
/** Open band `band` of a DEM: out gets what tsio_read_dem gives but the
 *  cells (out->r.data NULL; free with tsio_raster_free). */
tsio_reader *tsio_dem_open(const char *path, int band, tsio_raster *out, tsio_err *err);
/** Cells [x0, x0 + w) x [y0, y0 + h) into dst (w x h, row-major), with the
 *  conversions and checks of tsio_read_dem (sentinels counted into
 *  *n_sentinels, valid cells into *n_valid). */
int tsio_dem_window(tsio_reader *rd, int x0, int y0, int w, int h, float *dst, size_t *n_valid,
                    size_t *n_sentinels, tsio_err *err);
void tsio_reader_close(tsio_reader *rd);

/** Ground metrics view of a read raster; NULL when it has no CRS. */
const ts_grid_metrics *tsio_metrics(const tsio_raster *r, ts_grid_metrics *storage);

/** Deep copy of a georef (out owns its wkt). */
int tsio_georef_copy(const tsio_georef *src, tsio_georef *out);
void tsio_georef_free(tsio_georef *g);

/** Output options shared by all raster writers. */
typedef struct tsio_write_opts {
    const char *format;                /* GDAL driver short name; NULL = from the
                                          extension, GTiff when unknown */
    const char *const *create_options; /* NULL-terminated "KEY=VALUE" list or NULL */
    int check_only;                    /* 1: check format, creation options, data type and the
                                          output directory, then return without writing */
} tsio_write_opts;

/**
 * Write a Float32 raster (NaN written as nodata `nodata_value`) with the
 * georef's CRS and geotransform.  Drivers without Create() are served
 * through a MEM dataset and CreateCopy().
 */
int tsio_write_float(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                     const ts_raster *data, double nodata_value, tsio_err *err);

/** Where a producer hands its windows: 0, or -1 with the error set. */
typedef int (*tsio_window_sink_fn)(void *sink, int x0, int y0, int w, int h,
                                   const unsigned char *bytes);
/** Make every cell of the raster, window by window, through sink. */
typedef int (*tsio_byte_producer)(void *user, tsio_window_sink_fn sink, void *sink_arg,
                                  tsio_err *err);
/** As tsio_write_byte, the cells made by `produce` window by window while
 *  the file is open (a raster larger than memory; formats that can only
 *  copy a whole dataset hold it in memory at one byte per cell). */
int tsio_write_byte_windows(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                            int nodata, tsio_byte_producer produce, void *user, tsio_err *err);

/** Write a Byte raster (w*h bytes, stride w) with nodata value `nodata`
 *  (pass -1 for none), CRS and geotransform. */
int tsio_write_byte(const char *path, const tsio_write_opts *opts, const tsio_georef *geo,
                    const unsigned char *data, int nodata, tsio_err *err);

/** Write an RGB PNG (3*w*h bytes, pixel-interleaved, row-major). */
/** The first n bytes of a file into buf: the count read, or -1. */
int tsio_read_head(const char *path, unsigned char *buf, size_t n, tsio_err *err);
/** A whole file into *bytes (malloc'ed), refused past max_len bytes. */
int tsio_read_bytes(const char *path, size_t max_len, unsigned char **bytes, size_t *len,
                    tsio_err *err);
/** Write head then data as one file, all or nothing like every output (a
 *  temporary name, moved into place now or with the job's stage); with
 *  check_only, only check that it could be written. */
int tsio_write_bytes(const char *path, const void *head, size_t head_len, const void *data,
                     size_t len, int check_only, tsio_err *err);
int tsio_write_png_rgb(const char *path, int width, int height, const unsigned char *rgb,
                       tsio_err *err);

/**
 * Write the PPA feature graph as vectors: OGR driver from the extension
 * (.gpkg -> GPKG, .shp -> ESRI Shapefile, .geojson -> GeoJSON, ...).
 * Layer "paths" (LineString, one per path; fields kind ("ridge"/"valley"),
 * length_m (NULL without CRS), length_cells, mean_elev, min_elev, max_elev,
 * start_kind, end_kind ("endpoint"/"branch")) and layer "nodes" (Point;
 * kind, degree, elev, feature ("ridge"/"valley")), coordinates at cell centres
 * in the georef's CRS.  Formats with one layer per file (Shapefile, GeoJSON)
 * get the nodes in a sibling file "<stem>_nodes.<ext>".
 */
int tsio_write_features(const char *path, const tsio_georef *geo, const ts_features *f,
                        const ts_grid_metrics *metrics, tsio_err *err);

/**
 * Write a stream network (ts_stream_network_extract) as vectors, all or
 * nothing like tsio_write_features: layer "streams", a LineString per link
 * from upstream to downstream at cell centres, with fields link (its
 * number), down (the link it flows into, NULL where it leaves the grid),
 * strahler, area_cells, area_km2 (at its lower end's row; NULL without
 * CRS), length_m (NULL without CRS), length_cells, elev_top, elev_bottom.
 */
int tsio_write_streams(const char *path, const tsio_georef *geo, const ts_stream_network *net,
                       const ts_grid_metrics *metrics, tsio_err *err);

/**
 * Read like tsio_read_dem, then resample to cells of target_dx_m x
 * target_dy_m metres on the ground (for exemplars whose resolution differs
 * from the output's): a projected raster is warped in its own CRS; a
 * geographic one stays in its CRS with degrees per cell chosen so that a
 * cell has that ground size at its centre latitude.  Cells within 1 % of
 * the target size are returned as read.  Cubic interpolation when the
 * target is finer, averaging when it is coarser; nodata stays NaN.  A
 * raster without CRS has cells of no_crs_cell_m metres when that is > 0
 * (resampled in its own pixel space, metrics set); without it, it is
 * returned as read (its ground size is unknown, dx_m stays NULL).
 * *factor (may be NULL) = source cell size / target cell size.
 */
int tsio_read_raster_resampled(const char *path, int band, double target_dx_m, double target_dy_m,
                               double no_crs_cell_m, tsio_raster *out, double *factor,
                               tsio_err *err);
/** The same for class codes (as tsio_read_raster: no elevation checks):
 *  the nearest cell when finer, the most common code when coarser. */
int tsio_read_classes_resampled(const char *path, int band, double target_dx_m, double target_dy_m,
                                double no_crs_cell_m, tsio_raster *out, tsio_err *err);

/** Is g (the raster `path`, "the water mask") on grid (the job's, "output" or "input")?
 *  The same size, and where both have them, the same geotransform (corners within a
 *  thousandth of a cell, cell sizes within a millionth) and the same CRS; a raster with
 *  neither a geotransform nor a CRS is taken by size.  0, or -1 with err. */
int tsio_same_grid(const char *path, const char *what, const tsio_georef *g,
                   const tsio_georef *grid, const char *grid_name, tsio_err *err);

/** Georeferencing of a raster without reading its cells. */
int tsio_read_georef(const char *path, tsio_georef *geo, tsio_err *err);

/** A north-up grid: origin = top-left corner, res_x, res_y > 0 in the
 *  CRS's units; crs: anything OSRSetFromUserInput takes (EPSG:32633, WKT,
 *  PROJ string), or NULL/"" for none. */
int tsio_georef_make(int width, int height, double origin_x, double origin_y, double res_x,
                     double res_y, const char *crs, tsio_georef *geo, tsio_err *err);

/** Per-row ground metrics (metres) of a grid, as tsio_read_raster computes
 *  them; *dx = *dy = NULL without CRS.  Caller frees both with free(). */
/** For the sun (ts_irradiance): the latitude and the azimuth of the grid's
 *  up direction from true north (degrees) of each cell of `geo`'s grid
 *  area-averaged by `factor` (lat->width x lat->height cells; north may be
 *  NULL), NaN where the CRS cannot say.  0; 1 when geo has no CRS (nothing
 *  written); -1 on error. */
int tsio_georef_sun_frame(const tsio_georef *geo, int factor, ts_raster *lat, ts_raster *north,
                          tsio_err *err);
int tsio_georef_metrics(const tsio_georef *geo, double **dx, double **dy, tsio_err *err);

/**
 * An integer map on a grid: a raster (band 1, same size as geo) or a polygon
 * layer with an integer field `field`, rasterised onto geo (cell centres).
 * values: caller-allocated geo->width * geo->height ints; nodata and empty
 * cells get `fill`.
 */
int tsio_read_label_map(const char *path, const tsio_georef *geo, const char *field, int fill,
                        int32_t *values, tsio_err *err);
/** The same over the window [x0, x0 + w) x [y0, y0 + h) of the grid geo
 *  (values: w * h ints). */
int tsio_read_label_window(const char *path, const tsio_georef *geo, int x0, int y0, int w, int h,
                           const char *field, int fill, int32_t *values, tsio_err *err);

/** A sketch drawn as lines (tsio_read_lines): its lines (points, kinds,
 *  heights; all owned), the box of their points (xmin, ymin, xmax, ymax)
 *  and the CRS they are in (WKT2, owned; NULL when the layer has none). */
typedef struct tsio_lines {
    size_t n;
    ts_sketch_line *lines;
    double box[4];
    char *wkt;
    int is_geographic;
} tsio_lines;
/** Is `path` a vector dataset (layers, no raster band)? */
int tsio_is_lines(const char *path);
/** Read a layer of lines (layer NULL: the first of lines; kind_field NULL:
 *  "kind", whose values are ridge, valley or river; height_field NULL: the
 *  Z values, if any, are the heights) in the CRS to_wkt (NULL: the
 *  layer's).  One-line errors: no such layer or field, a feature that is
 *  not a line, an unknown kind, a line that crosses itself, a CRS that
 *  cannot be transformed, no lines. */
int tsio_read_lines(const char *path, const char *layer, const char *kind_field,
                    const char *height_field, const char *to_wkt, tsio_lines *out, tsio_err *err);
/** The lines' points into cell coordinates of `geo` (in place). */
void tsio_lines_to_cells(tsio_lines *l, const tsio_georef *geo);
void tsio_lines_free(tsio_lines *l);

/** Check that a vector output can be written (format from the extension,
 *  driver present, directory exists) without writing anything. */
int tsio_check_vector_output(const char *path, tsio_err *err);

/** Are a and b the same file (same device and inode: a link or another
 *  spelling of the path counts)?  When one does not exist yet: the same
 *  name in the same folder (its links and spelling resolved). */
int tsio_same_file(const char *a, const char *b);
/** What an untrusted recipe may name.  tsio_name_offline: no network
 *  dataset (/vsicurl/, /vsis3/, ..., any "scheme://") unless the
 *  configuration option TSYN_ALLOW_NETWORK=YES says so.  tsio_crs_offline:
 *  a CRS given as text (AUTH:CODE, WKT, PROJJSON, a PROJ string without
 *  init=), never a file name or a URL, which GDAL would read or fetch. */
int tsio_name_offline(const char *name, tsio_err *err);
int tsio_crs_offline(const char *crs, tsio_err *err);
/** tsio_name_plain: a name a recipe may read: never standard input, never
 *  a device, FIFO or socket (a read would block or never end). */
int tsio_name_plain(const char *name, tsio_err *err);
/** tsio_input_offline: the name and every file it leads to (the sources of
 *  a VRT or an OGR VRT, nested) pass tsio_name_offline and tsio_name_plain,
 *  and none is a server's description (WMS, WMTS, WCS, WFS, ...) or a
 *  database connection, unless TSYN_ALLOW_NETWORK=YES. */
int tsio_input_offline(const char *name, tsio_err *err);
/** The offline guard around everything a recipe opens or reads: between
 *  begin and end, on the calling thread, GDAL reaches no network whatever
 *  the files it opens say (a VRT naming /vsicurl/, a WMS or WMTS
 *  description, nested VRTs, OGR's web drivers), unless
 *  TSYN_ALLOW_NETWORK=YES.  Guards nest. */
typedef struct {
    int active, pushed;
    char *saved; /* the thread's earlier CPL_VSIL_CURL_ALLOWED_FILENAME */
} tsio_offline;
void tsio_offline_begin(tsio_offline *g);
void tsio_offline_end(tsio_offline *g);
/** Memory.  tsio_parse_memory reads "2G", "500M", "512" (MB, as
 *  GDAL_CACHEMAX), "64K", "1T" or "50%" (of the machine's memory).
 *  tsio_physical_memory: the machine's memory, or its container's limit
 *  when lower.  tsio_check_memory: refuses `need` bytes past the limit
 *  (the configuration option TSYN_MAX_MEMORY, else the machine's memory)
 *  with a message that says how much is needed. */
int tsio_parse_memory(const char *text, uint64_t *bytes);
uint64_t tsio_physical_memory(void);
int tsio_memory_limit(uint64_t *bytes, int *from_option, tsio_err *err);
int tsio_check_memory(uint64_t need, const char *what, const char *advice, tsio_err *err);
/** Can an output be written at path: its folder exists and is writable,
 *  and path is new or a regular file (not a folder, device, FIFO, socket). */
int tsio_check_output_file(const char *path, tsio_err *err);

/** Make sure the folder exists (created, one level, if need be). */
int tsio_make_dir(const char *dir, tsio_err *err);

/** "<dir>/<name>.<ext>" into buf; -1 (err set) if it does not fit. */
int tsio_path(char *buf, size_t n, const char *dir, const char *name, const char *ext,
              tsio_err *err);

#ifdef __cplusplus
}
#endif
#endif /* TSIO_H */
