/*
 * layout.h - private: the large-scale relief a sketch lays out (a
 * TerraSynth addition to Zhou et al. 2007, see layout.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_LAYOUT_H
#define TS_LAYOUT_H

#include "internal.h"
#include "relief_guide.h"

/* Radius of the three box passes that approximate a Gaussian of sigma. */
int ts_blur_radius(double sigma);

/*
 * NaN-aware Gaussian blur (three box passes, so O(cells) for any sigma):
 * out[i] = sum of weights * values / sum of weights over the valid cells,
 * NaN where no valid cell is in reach.  in: w x h at `stride`; out: w*h,
 * stride w.  Returns TS_ERR_NOMEM.
 */
ts_status ts_blur_nan(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                      double sigma, float *out);

/* Mean gradient magnitude (central differences, per cell) over the cells
 * whose four neighbours are valid; 0 when there is none. */
double ts_mean_gradient(const float *a, int w, int h);

typedef struct ts_layout_spec {
    const unsigned char *sketch_mask; /* width*height: bit `kind` on the sketch's features */
    int kind;                         /* TS_RIDGE or TS_VALLEY */
    int width, height;
    const unsigned char *nodata;      /* width*height or NULL: non-zero = no guide there */
    const ts_raster *exemplars;       /* at the output's ground resolution */
    int n_exemplars;
    const ts_relief_profile *profs;   /* per exemplar: the level of its main features */
    const int32_t *cell_exemplar;     /* per output cell, or NULL */
    double sigma;                     /* the layout scale, cells */
    double reach;                     /* c of f(d), cells */
} ts_layout_spec;

/* The layout guide T (layout.c) into guide (width*height floats; NaN on
 * nodata, everywhere when no exemplar has the feature kind). */
ts_status ts_layout_guide(ts_ctx *ctx, const ts_layout_spec *spec, float *guide);

/* out += strength * w * blur_sigma(guide - out); w fades from 0 on
 * TS_CELL_FIXED cells (flags may be NULL) to 1 at 2 sigma from them. */
ts_status ts_layout_apply(ts_ctx *ctx, ts_raster *out, const float *guide,
                          const unsigned char *flags, double sigma, double strength);

#endif
