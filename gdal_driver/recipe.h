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

enum { RECIPE_PPA = 1, RECIPE_SYNTH = 2, RECIPE_AMPLIFY = 3, RECIPE_PIXEL = 4 };

typedef struct ts_recipe ts_recipe;

/** Is this (file name, first bytes) a recipe? */
int recipe_identify(const char *filename, const unsigned char *header, int n_header);

/** Parse the recipe file `path` (read through GDAL's VSI layer).
 *  open_options: NULL-terminated "NAME=VALUE" overriding parameters (any
 *  case; SEED too) or NULL.  Resolves the output grid without computing.
 *  Caller frees with recipe_free. */
int recipe_open(const char *path, const char *const *open_options, ts_recipe **out,
                tsio_err *err);
void recipe_free(ts_recipe *r);

/** Output grid and pixel type (GDT_Byte for ppa, GDT_Float32 for synth). */
const tsio_georef *recipe_georef(const ts_recipe *r);
int recipe_gdal_type(const ts_recipe *r);
double recipe_nodata(const ts_recipe *r);

/** Run the method once (idempotent).  Not thread-safe: the driver locks.
 *  On success recipe_data gives width*height cells of recipe_gdal_type. */
int recipe_compute(ts_recipe *r, tsio_err *err);
const void *recipe_data(const ts_recipe *r);
/** A lazy recipe (amplify) keeps no whole output: after recipe_compute (what
 *  every block shares), recipe_read_window computes the cells [x0, x0+w) x
 *  [y0, y0+h) (Float32, nodata -9999), the same bytes as the whole would
 *  have; thread-safe. */
int recipe_lazy(const ts_recipe *r);
/* The side of the blocks the driver serves (a pixel recipe's are larger: each block
 * recomputes the margins its levels need). */
int recipe_block_size(const ts_recipe *r);
int recipe_read_window(ts_recipe *r, int x0, int y0, int w, int h, float *out, tsio_err *err);

/** Write a recipe for a job from what a front end was given (jobspec.h;
 *  temporary file + rename).  Input paths are stored relative to the
 *  recipe's folder when they lie under it, else absolute. */
struct tsj_values;
int recipe_write(const char *path, const struct tsj_values *values, tsio_err *err);

/** Open-option list XML for the driver metadata, from the descriptor
 *  tables (caller frees with free()). */
char *recipe_open_option_list(void);

#ifdef __cplusplus
}
#endif
#endif
