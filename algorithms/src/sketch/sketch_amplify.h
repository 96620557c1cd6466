/*
 * sketch_amplify.h - a sketch in tiles (sketch_amplify.c): the sketch laid
 * out on a coarser grid, then amplified onto the output grid.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_SKETCH_AMPLIFY_H
#define TS_SKETCH_AMPLIFY_H

#include <stdint.h>

#include "terrasynth.h"

/* What every window of a sketch in tiles reads (sketch_amplify.c; as bytes:
 * sketch_tiles_io.c). */
struct ts_sketch_tiles {
    int W, H, K;
    ts_raster coarse;    /* the coarse pass, ceil(W / K) x ceil(H / K) */
    ts_raster drain;     /* its drainage area (the amplification's guide) */
    ts_dictionary *dict; /* NULL when K = 1 */
    ts_amplify_params ap;
    unsigned char *nodata; /* per output cell, or NULL: none */
    uint64_t *ridges;      /* the output cells on a drawn ridge, ascending */
    size_t n_ridges;
    double bank_step; /* the water's bank slope: the coarse pass's median step / K */
};

/* The amplification's parameters, the coarse pass's drainage area and the
 * water's bank slope, from t->K and t->coarse. */
ts_status ts__sketch_tiles_guide(ts_ctx *ctx, ts_sketch_tiles *t);

/* sketch_tiles_fixed.c: a window's fixed cells (flags TS_CELL_FIXED, their
 * values; water also TS_CELL_WATER) after its amplification: the pins'
 * blend, the water's banks, the fixed cells put back. */
ts_status ts__sketch_tiles_fixed(ts_ctx *ctx, const ts_sketch_tiles *t, ts_raster *out,
                                 const unsigned char *flags, const float *values);
/* The pinned cells' differences (values - out) spread over the free cells
 * within R, tapered (R: 2..256). */
ts_status ts__pin_blend(ts_ctx *ctx, ts_raster *out, const unsigned char *flags,
                        const float *values, int R);
/* The free cells within R of water raised towards its bank (k: the bank's
 * slope, height a cell). */
ts_status ts__water_banks_window(ts_ctx *ctx, ts_raster *out, const unsigned char *flags,
                                 const float *values, double k, int R);

/* ts_synth_sketch (a painted sketch) or ts_synth_sketch_features (a
 * feature graph) with params->tiled > 0: the sketch laid out whole on a
 * grid K times coarser, then amplified K times onto out through
 * ts_sketch_tiles_new and the window of the whole grid: the cells of out not
 * NaN on entry and those flagged TS_CELL_FIXED are kept, water as flagged. */
ts_status ts__synth_sketch_amplified(ts_ctx *ctx, const ts_raster *sketch,
                                     const ts_features *features, const ts_raster *exemplars,
                                     int n_exemplars, const ts_sketch_params *sp,
                                     const ts_synth_params *params,
                                     const ts_synth_constraints *constraints, ts_raster *out,
                                     ts_features **sketch_features, ts_sketch_info *info);

#endif
