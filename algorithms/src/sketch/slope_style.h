/*
 * slope_style.h - private: the exemplars' distribution of slopes given to a
 * sketched terrain (a TerraSynth addition, see slope_style.c).  Not
 * installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_SLOPE_STYLE_H
#define TS_SLOPE_STYLE_H

#include "internal.h"
#include "relief_guide.h"

#define SLOPE_STYLE_PASSES 3
#define SLOPE_STYLE_TOLERANCE 3e-3

typedef struct ts_slope_style_spec {
    const ts_raster *exemplars; /* at the output's ground resolution */
    int n_exemplars;
    const int32_t *cell_exemplar; /* per output cell (stride = width), -1 = none; or NULL */
    const unsigned char *flags;   /* per output cell: TS_CELL_FIXED never change; or NULL */
    const unsigned char *features; /* per output cell: the sketch's feature bits; or NULL */
    int kind;                      /* the bit of `features` that counts (TS_RIDGE, TS_VALLEY) */
    double keep_radius;            /* within this many cells of them slopes are never gentled */
    double strength;              /* 0..1: the factors' exponent (0 = off) */
    double tolerance;             /* of the iterative Poisson solves (a grid with nodata or
                                     fixed cells); 0 = SLOPE_STYLE_TOLERANCE (loose: the
                                     largest scales lag a little, see slope_style.c) */
    double scale;                 /* cells: the heights change over about this far at most
                                     (a screened solve; 0 = an exact fit) */
} ts_slope_style_spec;

/* Quantile-map the output's gradient magnitudes onto the exemplars' and fit
 * the heights to the scaled differences (slope_style.c).  Nodata stays
 * nodata, fixed cells keep their values.  TS_ERR_NOMEM, TS_ERR_CANCELLED. */
ts_status ts__slope_style(ts_ctx *ctx, const ts_slope_style_spec *spec, ts_raster *out);

#endif
