/*
 * tsjob.h - the jobs behind every front end: read the inputs with tsio, run
 * a core stage, hand back the result with its georeferencing.  The CLI
 * writes the result to files; the GDAL driver serves it block by block.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * Errors: 0 on success, -1 with one line "<file>: <problem>" in err.
 */
#ifndef TSJOB_H
#define TSJOB_H

#include <stdint.h>

#include "terrasynth.h"
#include "tsio.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- what a job writes ---- */

/* The files of a job.  Every front end that writes files (the CLI; QGIS
 * through it) hands these over, so previews and debug maps are written the
 * same way everywhere; the GDAL driver serves the raster and writes none. */
typedef struct tsjob_outputs {
    const char *output;                /* the raster */
    const char *format;                /* GDAL driver, NULL = from the extension */
    const char *const *create_options; /* NULL-terminated KEY=VALUE, or NULL */
    const char *preview;               /* hillshade PNG (ppa: with the axes), or NULL */
    const char *lines;                 /* ppa: the axes as vector lines, or NULL */
    const char *debug_dir;             /* synth: the synthesis maps, or NULL */
    /* amplify: "NAME=FILE" of the carried layers wanted (NULL-terminated, or NULL),
     * and the atoms' classes */
    const char *const *out_layers;
    const char *out_classes;
    /* the DEM's streams as lines (NULL: none), a stream draining at least flow_cells
     * cells (0: 1000) or flow_km2 square kilometres (0: by cells) */
    const char *flow_lines;
    double flow_cells, flow_km2;
} tsjob_outputs;

/* ---- the drainage stage after every method ---- */

/** ts_drainage_apply on dem (a window at gx0, gy0 of a W x H grid); errors
 *  name `what`. */
int tsjob_drain(ts_ctx *ctx, const ts_drainage_params *p, ts_raster *dem,
                const unsigned char *flags, int64_t gx0, int64_t gy0, int W, int H,
                ts_drainage_info *info, const char *what, tsio_err *err);
/** A method's window before the drainage stage: cells [x0, x0+w) x [y0,
 *  y0+h) of the grid into cells (w*h), and TS_CELL_* into flags (w*h,
 *  zeroed; NULL when not wanted). */
typedef int (*tsjob_raw_fn)(void *arg, ts_ctx *ctx, int x0, int y0, int w, int h, float *cells,
                            unsigned char *flags, tsio_err *err);
/** Window [x0, x0+w) x [y0, y0+h) of a W x H grid after the drainage
 *  stage: raw's window grown by ts_drainage_margin, drained, cut: the same
 *  bytes as that window of the whole grid drained. */
int tsjob_drained_window(ts_ctx *ctx, const ts_drainage_params *p, int W, int H, int x0, int y0,
                         int w, int h, tsjob_raw_fn raw, void *arg, float *out, const char *what,
                         tsio_err *err);

/* ---- ppa ---- */

typedef struct tsjob_ppa {
    const char *input;
    int band;         /* 1-based */
    double cell_size; /* > 0: metres per cell for a raster without CRS */
    int tile_size;    /* > 0: in tiles of this many cells; 0: tiles only when too large */
    ts_ppa_params params;
} tsjob_ppa;

typedef struct tsjob_ppa_result {
    tsio_raster in; /* the DEM as read (metres, NaN nodata) */
    ts_features *features;
    unsigned char *codes; /* w*h: 1 ridge, 2 valley, 3 both, 0 none, 255 nodata */
    ts_grid_metrics mstore;
    const ts_grid_metrics *metrics; /* NULL without CRS */
    int no_crs;                     /* the input has no CRS (lengths in cells) */
    tsio_err warning;               /* "" or one line a front end shows as a warning */
    int tile_size;                  /* > 0: the DEM is read and mapped in tiles (no features,
                                       no codes: tsjob_ppa_write makes the raster tile by tile) */
    int auto_tiles;                 /* the tiles were chosen: too large for memory in one piece */
    tsio_reader *reader;            /* the DEM, open, when in tiles */
    int band;
    ts_ctx *ctx;              /* borrowed for the tiled write */
    ts_ppa_tiled_stats tiled; /* how the tiled run split the work */
    ts_ppa_params params;
    const char *input;
} tsjob_ppa_result;

/** The memory a ppa of a grid takes, against the limit (tsio_check_memory). */
int tsjob_ppa_check_memory(const tsio_georef *in, const char *path, tsio_err *err);
/** Read and check the input (no computation); res->in is filled.  A grid
 *  that would take more memory than allowed is refused before it is read
 *  (as synth's prepare refuses its grid and exemplars). */
int tsjob_ppa_prepare(const tsjob_ppa *job, tsjob_ppa_result *res, tsio_err *err);
/** Extract the axes (after prepare); progress and cancel through ctx. */
int tsjob_ppa_compute(ts_ctx *ctx, const tsjob_ppa *job, tsjob_ppa_result *res, tsio_err *err);
void tsjob_ppa_result_free(tsjob_ppa_result *res);
/** Before the work (after prepare): every output can be written and none
 *  is the input. */
int tsjob_ppa_check_outputs(const tsjob_ppa *job, const tsjob_ppa_result *res,
                            const tsjob_outputs *o, tsio_err *err);
/** After compute: the codes raster, the lines and the preview. */
int tsjob_ppa_write(ts_ctx *ctx, const tsjob_ppa_result *res, const tsjob_outputs *o,
                    tsio_err *err);

/* ---- synth ---- */

#define TSJOB_MAX_EXEMPLARS 64
#define TSJOB_MAX_BIOMES 8

typedef struct tsjob_grid {
    const char *like;  /* raster whose grid to use, or NULL */
    int width, height; /* with like == NULL */
    int has_origin, has_res;
    double origin_x, origin_y, res;
    const char *crs; /* needs origin and res */
} tsjob_grid;

#define TSJOB_MAX_PINS 16

/* A window of an exemplar pinned into the output (Zhou et al. section 6.1:
 * Mount St. Helens as Mount Doom). */
typedef struct tsjob_pin {
    const char *path;
    int xoff, yoff, width, height; /* window in the file's own cells */
    int x, y;                      /* top-left output cell it goes to */
} tsjob_pin;

typedef struct tsjob_synth {
    const char *exemplars[TSJOB_MAX_EXEMPLARS];
    int n_exemplars;
    int band;
    double cell_size; /* > 0: metres per cell of every input (and a target grid) without CRS */
    tsjob_grid grid;  /* unused with a sketch: the output is on its grid */
    ts_synth_params params;
    const char *sketch; /* sketch-guided synthesis when not NULL: a raster or lines */
    ts_sketch_params sketch_params;
    ts_drainage_params drainage; /* the drainage stage after the synthesis */
    /* a sketch of lines: its layer (NULL: the first of lines), the field of
     * the kinds (NULL: "kind") and of the heights (NULL: the Z values), the
     * snapping distance in cells (< 0: 2), and with grid.has_res the extent
     * (xmin, ymin, xmax, ymax in the grid's CRS; else the lines' box grown
     * by a patch) */
    const char *sketch_layer, *kind_field, *height_field;
    double snap;
    int has_extent;
    double extent[4];
    tsjob_pin pins[TSJOB_MAX_PINS];
    int n_pins;
    const char *water; /* mask raster on the output grid: non-zero cells are water */
    double water_level;
    /* several styles: a region map (integer raster on the output grid, or a
     * polygon layer with an integer field "region") and, per region id, the
     * index of its exemplar; other regions take any exemplar */
    const char *heights; /* wanted elevations on the output grid (c_i), or NULL */
    double alpha_h;      /* their weight */
    const char *regions;
    int n_region_rules;
    int region_id[TSJOB_MAX_EXEMPLARS], region_exemplar[TSJOB_MAX_EXEMPLARS];
    /* served tile by tile (the driver, a tiled free synthesis): no whole
     * output; the memory estimate is one request's tiles and the cache */
    int lazy;
    size_t tile_cache; /* with lazy: the bytes of tiles a front end keeps */
    /* a sketch in tiles: the file its coarse pass is kept in (read when it
     * matches, written by tsjob_synth_write_coarse), and what it must have
     * been made with besides the inputs' bytes (the job's values as text) */
    const char *coarse_pass;
    const char *coarse_params;
    int write_coarse; /* the file is to be written: no warning when it is missing */
} tsjob_synth;

/** Parse "FILE:XOFF,YOFF,W,H@X,Y" into pin (path points into spec). */
int tsjob_parse_pin(const char *spec, tsjob_pin *pin, char *path_buf, size_t path_len);

typedef struct tsjob_synth_result {
    tsio_georef geo;     /* the target grid */
    double *dx_m, *dy_m; /* its ground metrics, NULL without CRS */
    ts_grid_metrics mstore;
    const ts_grid_metrics *metrics;
    ts_raster out;                /* the terrain (owned) */
    int exemplar_no_crs;          /* index+1 of an exemplar without CRS used cell for cell, or 0 */
    ts_synth_params params;       /* the job's, lengths turned into cells of this grid */
    ts_features *sketch_features; /* the sketch's feature graph (sketch-guided only) */
    int sketch_lines;             /* the sketch is a layer of lines */
    ts_sketch_info sketch_info;
    ts_drainage_params drainage;    /* the job's, its automatic bank slope set (setup, compute) */
    ts_drainage_info drainage_info; /* after compute */
    double seconds_drainage;
    ts_synth_maps maps;            /* with keep_maps: where each cell came from (owned) */
    ts_sketch_tiles *sketch_tiles; /* a sketch in tiles served window by window (owned) */
    int has_maps;
    tsio_err warning; /* "" or one line a front end shows as a warning */
    /* after tsjob_synth_setup: the exemplars at the target resolution (owned) */
    tsio_raster ex[TSJOB_MAX_EXEMPLARS];
    ts_raster exr[TSJOB_MAX_EXEMPLARS];
    int n_ex;
    /* and the pins at the target resolution with their windows (x0, y0, w, h
     * in the raster's cells at that resolution), for the tiles (owned) */
    tsio_raster pin_ex[TSJOB_MAX_PINS];
    int pin_win[TSJOB_MAX_PINS][4];
} tsjob_synth_result;

/** Check the job and resolve the target grid (cheap: no exemplar is read). */
int tsjob_synth_prepare(const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err);
/** Read the exemplars at the target's resolution and synthesize; with
 *  keep_maps, res->maps records where each cell came from. */
/** TS_CELL_FIXED and TS_CELL_WATER of the water and pins over window
 *  [x0, x0+w) x [y0, y0+h) of the output grid into flags (w*h, zeroed), and
 *  their values into values (w x h; may be NULL). */
int tsjob_synth_window_flags(const tsjob_synth *job, const tsjob_synth_result *res, int x0, int y0,
                             int w, int h, unsigned char *flags, ts_raster *values,
                             tsio_err *err);
int tsjob_synth_compute(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res, int keep_maps,
                        tsio_err *err);
/** The most input files a synth job reads, and those it reads (NULL where
 *  none is given) into in: their count. */
#define TSJOB_MAX_INPUTS (TSJOB_MAX_EXEMPLARS + TSJOB_MAX_PINS + 5)
int tsjob_synth_inputs(const tsjob_synth *job, const char **in);
/** What a sketch in tiles kept in job->coarse_pass must carry to be read:
 *  the checksum of the library's version, job->coarse_params and every
 *  input file's bytes. */
uint64_t tsjob_synth_coarse_key(const tsjob_synth *job);
/** After compute of a sketch in tiles (job->lazy: res->sketch_tiles kept),
 *  write it to job->coarse_pass (all or nothing). */
int tsjob_synth_write_coarse(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                             tsio_err *err);
void tsjob_synth_result_free(tsjob_synth_result *res);
/** The most tiles one window inside one tile needs: itself and its cone of
 *  earlier waves (a wave-3 tile: 2 of wave 2, 6 of wave 1, 8 of wave 0). */
#define TSJOB_TILE_CONE 17
/** A tiled free synthesis (params.tiled > 0) tile by tile: after prepare,
 *  read the exemplars at the target resolution (what every tile shares). */
int tsjob_synth_setup(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res, tsio_err *err);
/** After setup: the given tiles (ts_synth_tiles: independent of each
 *  other, their earlier-wave neighbours given), the same bytes as in the
 *  whole run; the seed is ctx's. */
int tsjob_synth_tiles(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                      ts_synth_tile *tiles, int n_tiles, tsio_err *err);
/** A sketch in tiles served window by window (job->lazy): after compute,
 *  which laid it out and kept res->sketch_tiles, cells [x0, x0+w) x [y0,
 *  y0+h) before the drainage stage, the same bytes as that window of the
 *  whole run. */
int tsjob_synth_sketch_window_raw(ts_ctx *ctx, const tsjob_synth *job,
                                  const tsjob_synth_result *res, int x0, int y0, int w, int h,
                                  float *cells, tsio_err *err);
/** The sketch's drawn ridges over [x0, x0+w) x [y0, y0+h) as TS_CELL_BARRIER
 *  into flags (w*h): barriers the drainage stage crosses only where it must
 *  (nothing without a feature graph on the output grid). */
void tsjob_synth_sketch_barriers(const tsjob_synth_result *res, int x0, int y0, int w, int h,
                                 unsigned char *flags);
/** Before the work (after prepare): every output can be written, none is
 *  an input, the debug folder exists (created if need be). */
int tsjob_synth_check_outputs(const tsjob_synth *job, const tsjob_synth_result *res,
                              const tsjob_outputs *o, tsio_err *err);
/** Before writing a recipe: it is no input of the job and can be written. */
int tsjob_ppa_check_recipe(const tsjob_ppa *job, const char *recipe, tsio_err *err);
int tsjob_synth_check_recipe(const tsjob_synth *job, const char *recipe, tsio_err *err);

/** The synthesis maps by name: TSJOB_MAP_SEAMS (Byte, 1 next to a seam),
 *  then the Int32 maps (-1 where no patch put the cell). */
enum {
    TSJOB_MAP_SEAMS,
    TSJOB_MAP_SOURCE_EXEMPLAR,
    TSJOB_MAP_SOURCE_X,
    TSJOB_MAP_SOURCE_Y,
    TSJOB_MAP_ORDER,
    TSJOB_N_MAPS
};
extern const char *const tsjob_map_names[TSJOB_N_MAPS];
/** One of res->maps' int maps (TSJOB_MAP_SOURCE_EXEMPLAR..ORDER), or NULL. */
const int32_t *tsjob_synth_int_map(const tsjob_synth_result *res, int map);

/** After compute: the DEM, the preview, and in debug_dir the maps
 *  (seams, source_exemplar, source_x, source_y, order; with a sketch its
 *  feature graph and the output's PPA axes as GeoPackages, and
 *  valley_floor: Byte, 1 on the floors of the drawn valleys). */
int tsjob_synth_write(ts_ctx *ctx, const tsjob_synth *job, const tsjob_synth_result *res,
                      const tsjob_outputs *o, tsio_err *err);

/* ------------------------------------------------------------------ */
/* amplify                                                             */
/* ------------------------------------------------------------------ */

typedef struct tsjob_amplify {
    const char *input;
    const char *exemplars[TSJOB_MAX_EXEMPLARS];
    int n_exemplars;
    int band;
    double cell_size;
    ts_amplify_params params;
    ts_drainage_params drainage; /* the drainage stage after the amplification */
    int lazy;                    /* served window by window (the driver): no whole output */
    const char *dictionary;      /* a dictionary file instead of exemplars */
    int shape_given;             /* factor or patch given: they must be the dictionary's */
    double resolution;           /* `terrasynth dictionary build`: metres per output cell */
    /* the exemplars' extra layers: layer_files[k][l] is exemplar k's layer l */
    char layer_names[TS_MAX_LAYERS][TS_LAYER_NAME];
    int n_layers;
    const char *layer_files[TSJOB_MAX_EXEMPLARS][TS_MAX_LAYERS];
    const char *exemplar_classes[TSJOB_MAX_EXEMPLARS]; /* NULL: none */
    const char *classes; /* wanted classes on the input's grid, or NULL */
    /* biomes: dictionary files and their weight rasters (instead of exemplars) */
    const char *biome_dicts[TSJOB_MAX_BIOMES], *biome_weights[TSJOB_MAX_BIOMES];
    int n_biomes;
    /* the carried layers and the classes wanted on the output (out_layer, out_classes) */
    char out_layer_names[TS_MAX_LAYERS][TS_LAYER_NAME];
    int n_out_layers, want_classes;
} tsjob_amplify;

typedef struct tsjob_amplify_result {
    tsio_raster in;  /* the coarse DEM as read */
    tsio_georef geo; /* the output grid: the input's extent and CRS, factor finer */
    ts_raster out;   /* the amplified DEM (owned) */
    ts_amplify_info info;
    ts_drainage_params drainage;    /* the job's, its automatic bank slope set (setup, compute) */
    ts_drainage_info drainage_info; /* after compute */
    double seconds_drainage;
    size_t n_atoms;
    double seconds_dictionary;
    int exemplar_no_crs; /* index+1 of an exemplar used cell for cell, or 0 */
    tsio_err warning;
    ts_dictionary *dict;             /* after tsjob_amplify_setup (owned) */
    ts_raster drain;                 /* the input's drainage area (owned) */
    ts_raster irr;                   /* the input's irradiance, with w_l > 0 (owned) */
    tsio_raster classes;             /* the wanted classes, on the input's grid */
    ts_raster layers[TS_MAX_LAYERS]; /* every carried layer, when one is asked for (owned) */
    int layer_of[TS_MAX_LAYERS];     /* out_layer i is the dictionary's layer layer_of[i] */
    ts_raster out_classes;           /* with out_classes (owned) */
    ts_dictionary *biome_dicts[TSJOB_MAX_BIOMES]; /* with biomes (owned; dict is the first) */
    tsio_raster biome_w[TSJOB_MAX_BIOMES];
} tsjob_amplify_result;

/** Read and check the input, resolve the output grid, estimate the memory. */
int tsjob_amplify_prepare(const tsjob_amplify *job, tsjob_amplify_result *res, tsio_err *err);
/** Read the exemplars at the output's ground resolution, build the
 *  dictionary and the input's drainage area (what every window shares). */
int tsjob_amplify_setup(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                        tsio_err *err);
/** What tsjob_amplify_window serves: the DEM, the atoms' classes, or (>= 0)
 *  the job's out layer of that index. */
#define TSJOB_SERVE_DEM (-1)
#define TSJOB_SERVE_CLASSES (-2)
/** After setup: output cells [x0, x0+w) x [y0, y0+h) of what `serve` says
 *  into out (w*h floats, NaN = nodata), the same bytes as that window of the
 *  whole. */
int tsjob_amplify_window(ts_ctx *ctx, const tsjob_amplify *job, const tsjob_amplify_result *res,
                         int x0, int y0, int w, int h, int serve, float *out, tsio_err *err);
/** The DEM's window before the drainage stage (what tsjob_amplify_window drains). */
int tsjob_amplify_window_raw(ts_ctx *ctx, const tsjob_amplify *job, const tsjob_amplify_result *res,
                             int x0, int y0, int w, int h, float *out, tsio_err *err);
/** Setup, then the whole output into res->out. */
int tsjob_amplify_compute(ts_ctx *ctx, const tsjob_amplify *job, tsjob_amplify_result *res,
                          tsio_err *err);
void tsjob_amplify_result_free(tsjob_amplify_result *res);
/** `terrasynth dictionary build` (the same job, the "dictionary" options):
 *  the exemplars at job->resolution, the dictionary, written as one file. */
int tsjob_dictionary_build(ts_ctx *ctx, const tsjob_amplify *job, const char *path, size_t *n_atoms,
                           tsio_err *err);
/** With job->dictionary: the job takes the dictionary's factor and patch
 *  (an error if others were given).  Before prepare. */
int tsjob_amplify_adopt_dictionary(tsjob_amplify *job, tsio_err *err);
/** A dictionary file: its dictionary and the ground size (m) of the cells
 *  it is for. */
int tsjob_dictionary_read(ts_ctx *ctx, const char *path, ts_dictionary **dict, double *resolution,
                          tsio_err *err);
int tsjob_amplify_check_recipe(const tsjob_amplify *job, const char *recipe, tsio_err *err);
int tsjob_amplify_check_outputs(const tsjob_amplify *job, const tsjob_amplify_result *res,
                                const tsjob_outputs *o, tsio_err *err);
int tsjob_amplify_write(ts_ctx *ctx, const tsjob_amplify_result *res, const tsjob_outputs *o,
                        tsio_err *err);

/* ------------------------------------------------------------------ */
/* pixel                                                               */
/* ------------------------------------------------------------------ */

typedef struct tsjob_pixel {
    const char *exemplars[TSJOB_MAX_EXEMPLARS];
    int n_exemplars;
    int band;
    double cell_size;
    tsjob_grid grid;
    const char *guide; /* a DEM on the output grid the terrain follows, or NULL */
    ts_pixel_params params;
    ts_drainage_params drainage; /* the drainage stage after the synthesis */
    int lazy;                    /* served window by window (the driver): no whole output */
    int keep_sources;            /* compute keeps where each cell's coordinate points (debug_dir) */
} tsjob_pixel;

typedef struct tsjob_pixel_result {
    tsio_georef geo; /* the target grid */
    double *dx_m, *dy_m;
    ts_pixel_exemplars *stacks; /* after setup (owned) */
    ts_pixel_guide *guide;      /* after setup, with a guide (owned) */
    ts_raster out;              /* the terrain (owned) */
    double seconds_stacks, seconds_synthesis;
    int32_t *src_e, *src_x, *src_y; /* with keep_sources (owned) */
    ts_drainage_params drainage;    /* the job's, its automatic bank slope set (setup, compute) */
    ts_drainage_info drainage_info; /* after compute */
    double seconds_drainage;
    int exemplar_no_crs;
    tsio_err warning;
} tsjob_pixel_result;

/** Resolve the target grid, estimate the memory. */
int tsjob_pixel_prepare(const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err);
/** Read the exemplars at the grid's ground resolution and build their stacks. */
int tsjob_pixel_setup(ts_ctx *ctx, const tsjob_pixel *job, tsjob_pixel_result *res, tsio_err *err);
/** After setup: cells [x0, x0+w) x [y0, y0+h) of the grid into out (the seed
 *  is the context's), the same bytes as that window of the whole. */
int tsjob_pixel_window(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res, int x0,
                       int y0, int w, int h, float *out, tsio_err *err);
/** The window before the drainage stage (what tsjob_pixel_window drains). */
int tsjob_pixel_window_raw(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res,
                           int x0, int y0, int w, int h, float *out, tsio_err *err);
/** After setup: cells [x0, x0+w) x [y0, y0+h) of the grid zoomed out by 2^k
 *  (k >= 1; a cell covers 2^k x 2^k cells of the grid): the synthesis stopped
 *  at the level of that spacing (ts_pixel_synthesize_overview), past the
 *  coarsest level the coarsest one's cells averaged; before the drainage stage. */
int tsjob_pixel_overview(ts_ctx *ctx, const tsjob_pixel *job, const tsjob_pixel_result *res, int k,
                         int x0, int y0, int w, int h, float *out, tsio_err *err);
/** Setup, then the whole grid into res->out. */
int tsjob_pixel_compute(ts_ctx *ctx, const tsjob_pixel *job, tsjob_pixel_result *res,
                        tsio_err *err);
void tsjob_pixel_result_free(tsjob_pixel_result *res);
int tsjob_pixel_check_recipe(const tsjob_pixel *job, const char *recipe, tsio_err *err);
int tsjob_pixel_check_outputs(const tsjob_pixel *job, const tsjob_pixel_result *res,
                              const tsjob_outputs *o, tsio_err *err);
int tsjob_pixel_write(ts_ctx *ctx, const tsjob_pixel_result *res, const tsjob_outputs *o,
                      tsio_err *err);

#ifdef __cplusplus
}
#endif
#endif
