/*
 * layout.h - private: the large-scale relief a sketch lays out (a
 * TerraSynth addition to Zhou et al. 2007, see layout.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_LAYOUT_H
#define TS_LAYOUT_H

#include "crest_profile.h"
#include "internal.h"
#include "relief_guide.h"

/* Radius of the three box passes that approximate a Gaussian of sigma. */
int ts__blur_radius(double sigma);

/*
 * NaN-aware Gaussian blur (three box passes, so O(cells) for any sigma):
 * out[i] = sum of weights * values / sum of weights over the valid cells,
 * NaN where no valid cell is in reach.  in: w x h at `stride`; out: w*h,
 * stride w.  Returns TS_ERR_NOMEM.
 */
ts_status ts__blur_nan(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h, double sigma,
                       float *out);

/* The same with the caller's work buffers v and m (w * h doubles each). */
ts_status ts__blur_nan_buffers(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                               double sigma, float *out, double *v, double *m);
/* The same blur of a wide sigma through a grid f times coarser (f the
 * largest power of two up to sigma / 8 leaving at least 8 x 8 coarse cells;
 * ts__blur_coarse_factor): the valid cells' sums and counts over f x f
 * blocks, both blurred there (the variance the blocks and the bilinear
 * taking back add taken off), taken back bilinearly, divided.  Within a
 * fraction of a percent of the full blur's relief, for f^2 times fewer
 * cells blurred; ts__blur_nan itself where f is 1. */
int ts__blur_coarse_factor(double sigma, int w, int h);
ts_status ts__blur_nan_coarse(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                              double sigma, float *out);
/* Mean gradient magnitude (central differences, per cell) over the cells
 * whose four neighbours are valid; 0 when there is none. */
double ts__mean_gradient(const float *a, int w, int h);
/* Mean gradient (per cell) of each of the n exemplars blurred at sigma, into g
 * (0 where unknown), measured on the exemplar averaged over f x f cells first
 * (f the largest power of two up to sigma / 3).  (blur.c) */
ts_status ts__exemplar_gradients(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                 double sigma, double *g);

typedef struct ts_layout_spec {
    const unsigned char *sketch_mask; /* width*height: the sketch's feature bits */
    int kind;                         /* the bits that count: TS_RIDGE, TS_VALLEY or both */
    int width, height;
    const unsigned char *nodata; /* width*height or NULL: non-zero = no guide there */
    const ts_raster *exemplars;  /* at the output's ground resolution */
    int n_exemplars;
    const ts_relief_profile *profs; /* per exemplar: the level of its main features (an
                                       exemplar without a valid one: its mean height) */
    const int32_t *cell_exemplar;   /* per output cell, or NULL */
    int patch;                      /* the patch size, cells: sets both scales */
    const ts_features *features;    /* the sketch's feature graph (valleys descend along
                                       its paths), or NULL */
    double steep_lo;                /* least steepness factor searched (0 = 0.35) */
    const ts__crest_library *crest; /* per exemplar: its crests' pieces (crest_profile.c),
                                       or NULL: ridges at one level */
    double crest_relief;            /* 0..1: the pieces' heights taken */
} ts_layout_spec;

/* Along the valley paths of spec->features (level: width*height,
 * NaN = no level), levels made non-increasing from every network's sources
 * to its outlet (the endpoint nearest the grid's edge): the mean of filling
 * and carving (layout.c).  Exposed for the tests. */
ts_status ts__valley_descend(ts_ctx *ctx, const ts_layout_spec *spec, float *level);

/* The steepness factor (0.35 or spec->steep_lo .. 2.5) that gives the
 * output the exemplars' distribution of slopes: r0 + lam corr above 1, r01
 * + lam d01 below (all spec's size); *lam is left as it is when no
 * distribution is found.  work: width * height floats.
 * (layout_steepness.c) */
ts_status ts__layout_steepness(ts_ctx *ctx, const ts_layout_spec *spec, const float *r0,
                               const float *corr, const float *r01, const float *d01, float *work,
                               double *lam);

/* The exemplars' 1st and 99th percentiles of height, over all of them
 * (lo > hi when none has a valid cell).  (layout_steepness.c) */
ts_status ts__exemplar_height_range(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                    double *lo, double *hi);

/* The layout and crest corrections of layout.c, applied to out (the
 * sketch's size) with `strength` (0..1); flags (may be NULL): TS_CELL_FIXED
 * cells never change and the corrections fade out near them. */
ts_status ts__layout_apply(ts_ctx *ctx, const ts_layout_spec *spec, ts_raster *out,
                           const unsigned char *flags, double strength);

/* The range press of the layout alone (its last step before valley floors
 * descend): the land's heights blurred at a third of `patch` pressed into
 * the exemplars' 1st..99th percentiles with a margin; flags as above.  For
 * a stage that moves heights after the layout (slope_style.c). */
ts_status ts__layout_press_range(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                 ts_raster *out, const unsigned char *flags, int patch);

/* The user's wanted heights kept at large scale after the layout and the
 * slope style, which know nothing of them: on and near the cells that have
 * a wanted height, out += min(1, alpha_h) x the mean of (wanted - out) over
 * those cells within a third of `patch`, fading out as exp(-(d / sigma)^2)
 * with the distance d to them, so a region's local mean and a line's mean
 * along it come to their wanted heights and the detail below that scale
 * stays; flags as above. */
ts_status ts__layout_keep_heights(ts_ctx *ctx, ts_raster *out, const float *heights, double alpha_h,
                                  const unsigned char *flags, int patch);

/* Drawn valleys that drain (valley_breach.c): the floor along every valley
 * of `f`, moved onto the valley's lowest line within patch / 10 cells of the
 * drawn one, carved so it never rises on the way to its outlet, the outlet
 * joined to the grid's edge or another valley within `patch` cells by a
 * carved channel; the floor's heights fitted at the least cost (cuts
 * and fills), the change fading out across the valley; flags (may be
 * NULL): TS_CELL_FIXED and TS_CELL_NODATA cells never change; floor_out
 * (may be NULL; width x height, 0 on entry) gets 1 on the floor cells. */
ts_status ts__valley_breach(ts_ctx *ctx, const ts_features *f, ts_raster *out,
                            const unsigned char *flags, int patch, unsigned char *floor_out);

/* The drawn valleys with their ways out (ours, for the layout): *with a
 * copy of f plus, for every valley network whose water runs on by a
 * channel (out of the grid: the edge, nodata, a lake; or into another
 * valley), that channel (as ts__valley_breach finds it on `out`) as a
 * valley path from the outlet: the layout then lays a valley out along the
 * way the water goes instead of closing the valley's end.  *with NULL when
 * f has no valleys. */
ts_status ts__valley_outlets(ts_ctx *ctx, const ts_features *f, const ts_raster *out,
                             const unsigned char *flags, int patch, ts_features **with);
#endif
