/*
 * recipe.h - TerraSynth recipes (.tsyn): a small XML file that names a
 * method, its inputs (GDAL dataset names, relative to the recipe or
 * absolute, /vsi paths included), its parameters by the CLI's names, and
 * the seed.  The GDAL driver opens recipes; `terrasynth ... --recipe`
 * writes them.  Format: gdal_driver/docs/recipes.md.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_RECIPE_H
#define TS_RECIPE_H

#include <stdint.h>

#include "tsjob.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { TSRECIPE_PPA = 1, TSRECIPE_SYNTH = 2, TSRECIPE_AMPLIFY = 3, TSRECIPE_PIXEL = 4 };

typedef struct tsrecipe tsrecipe;

/** Is this (file name, first bytes) a recipe? */
int tsrecipe_identify(const char *filename, const unsigned char *header, int n_header);

/** Parse the recipe file `path` (read through GDAL's VSI layer).
 *  open_options: NULL-terminated "NAME=VALUE" overriding parameters (any
 *  case; SEED too) or NULL.  Resolves the output grid without computing.
 *  Caller frees with tsrecipe_free. */
int tsrecipe_open(const char *path, const char *const *open_options, tsrecipe **out, tsio_err *err);
void tsrecipe_free(tsrecipe *r);

/** Output grid and pixel type (GDT_Byte for ppa, GDT_Float32 for synth). */
const tsio_georef *tsrecipe_georef(const tsrecipe *r);
int tsrecipe_gdal_type(const tsrecipe *r);
double tsrecipe_nodata(const tsrecipe *r);

/** Run the method once (idempotent).  Not thread-safe: the driver locks.
 *  On success tsrecipe_data gives width*height cells of tsrecipe_gdal_type. */
int tsrecipe_compute(tsrecipe *r, tsio_err *err);
const void *tsrecipe_data(const tsrecipe *r);
/** A lazy recipe (amplify) keeps no whole output: after tsrecipe_compute (what
 *  every block shares), tsrecipe_read_window computes the cells [x0, x0+w) x
 *  [y0, y0+h) (Float32, nodata TSIO_NODATA), the same bytes as the whole would
 *  have; thread-safe. */
int tsrecipe_lazy(const tsrecipe *r);
/* The side of the blocks the driver serves (a pixel recipe's are larger: each block
 * recomputes the margins its levels need). */
int tsrecipe_block_size(const tsrecipe *r);
int tsrecipe_read_window(tsrecipe *r, int x0, int y0, int w, int h, float *out, tsio_err *err);

/** Overviews (recipe_overviews.c): how many (0: none), the i-th's factor
 *  (grid cells a cell covers along each axis; its grid is ceil(width /
 *  factor) x ceil(height / factor)), and after tsrecipe_compute the cells
 *  [x0, x0+w) x [y0, y0+h) of the i-th (Float32, nodata TSIO_NODATA). */
int tsrecipe_overview_count(const tsrecipe *r);
int tsrecipe_overview_factor(const tsrecipe *r, int i);
int tsrecipe_read_overview(tsrecipe *r, int i, int x0, int y0, int w, int h, float *out,
                           tsio_err *err);

/** How a scheduler makes the recipe: its job ("PPA", "Synth", "Amplify",
 *  "Pixel": the recipe's element), how its windows are made ("any": any
 *  window alone, the same bytes as in the whole; "tiles": tile by tile, see
 *  tsyn_tiles.h; "whole": the whole raster on the first read), the tile size
 *  ("tiles", else 0), and the files it reads as GDAL opens them
 *  (NULL-ended, owned by r). */
const char *tsrecipe_job_name(const tsrecipe *r);
const char *tsrecipe_schedule(const tsrecipe *r);
int tsrecipe_tile_size(const tsrecipe *r);
/* The cells round a window its drainage stage reads (0: none). */
int tsrecipe_drainage_margin(const tsrecipe *r);
const char *const *tsrecipe_inputs(const tsrecipe *r);

/** Write a recipe for a job from what a front end was given (jobspec.h;
 *  temporary file + rename).  Input paths are stored relative to the
 *  recipe's folder when they lie under it, else absolute. */
struct tsjob_values;
int tsrecipe_write(const char *path, const struct tsjob_values *values, tsio_err *err);

/** Open-option list XML for the driver metadata, from the descriptor
 *  tables (caller frees with free()). */
char *tsrecipe_open_option_list(void);

#ifdef __cplusplus
}
#endif
#endif
