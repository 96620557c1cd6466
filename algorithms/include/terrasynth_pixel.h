/*
 * terrasynth_pixel.h - multiresolution pixel synthesis (Lefebvre and Hoppe
 * 2005; Cruz et al.): part of terrasynth.h, which includes it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TERRASYNTH_PIXEL_H
#define TERRASYNTH_PIXEL_H

#ifndef TERRASYNTH_H
#error "include terrasynth.h"
#endif

/* ------------------------------------------------------------------ */
/* Multiresolution pixel synthesis (Lefebvre and Hoppe 2005; Cruz et al.) */
/* ------------------------------------------------------------------ */

/** Parameters of `terrasynth pixel` (stage "pixel"). */
typedef struct ts_pixel_params {
    int levels;    /* L: levels of the Gaussian stacks above the finest (0: as many as fit) */
    int passes;    /* correction passes per level */
    int window;    /* k: neighbourhoods of k x k cells (odd; 0: chosen from the exemplars) */
    double jitter; /* jitter of the upsampled coordinates, in the level's spacings */
    double guide_weight; /* weight of the guide in the corrections' target, 0..1 */
    int guide_heights;   /* TS_GUIDE_AS_GIVEN: the guide is in the exemplars' units;
                            TS_GUIDE_STRETCH: mapped linearly so that its 1st..99th
                            percentiles span the exemplars' (a drawing in grey levels);
                            TS_GUIDE_QUANTILE: each value to the exemplars' height of
                            the same rank (within their 1st..99th percentiles) */
    int rotations;       /* 0: the exemplars as given; 2: also turned by 180 degrees; 4: also
                            by 90 and 270; 8: and mirrored; -1 (default): 4 or 2 by the
                            exemplars' grain (ts_pixel_variants) */
    int coherence;       /* K of the k-coherence similarity sets: candidates also the K - 1
                            exemplar cells most like each neighbour's (1: none) */
    double pca_energy;   /* share of the neighbourhoods' shape variance the compared
                            appearance vectors keep (Cruz et al.: 0.95; 1: all, plain SSD) */
    int guide_spacing;   /* the finest level the guide steers, as its spacing in cells (finer
                            levels take their detail from the exemplars alone; 1: all) */
    int start;           /* without a guide, the coarsest level from: TS_PIXEL_START_RELIEF
                            a smooth random relief in the exemplars' heights (ours);
                            TS_PIXEL_START_RANDOM a coordinate per cell at random */
    double relief_scale; /* the relief's lattice spacing in cells (0: matched to the
                            exemplars' relief at the coarsest level's spacing) */
    int guide_mode;      /* TS_GUIDE_PULL: the corrections' target pulled towards the guide's
                            heights at each steered level by guide_weight (ours);
                            TS_GUIDE_ADD: the guide's Laplacian band of each steered level
                            added to the level's heights (Cruz et al. section II.B) */
    double roughness_weight; /* lambda of the roughness term (ours): the corrections also
                            compare the target's roughness (its k x k heights' root sum of
                            squares about their mean) with the candidate's, lambda times the
                            difference squared, at the levels the guide does not steer; 0: off.
                            A property of the prepared exemplars, like pca_energy */
    /* per-level jitter (not a declared parameter: a list): with n_jitter_levels > 0,
     * level l >= 1 is jittered by jitter_levels[min(l - 1, n - 1)] instead of jitter */
    int n_jitter_levels;
    double jitter_levels[10];
} ts_pixel_params;

enum { TS_GUIDE_AS_GIVEN = 0, TS_GUIDE_STRETCH = 1, TS_GUIDE_QUANTILE = 2 };
enum { TS_PIXEL_START_RELIEF = 0, TS_PIXEL_START_RANDOM = 1 };
enum { TS_GUIDE_PULL = 0, TS_GUIDE_ADD = 1 };

TS_API ts_pixel_params ts_pixel_params_default(void);

/** The exemplars' Gaussian stacks, prepared once for many windows. */
typedef struct ts_pixel_exemplars ts_pixel_exemplars;

/** Prepare the stacks of exemplars (at the output's resolution; NaN =
 *  nodata, never matched). */
TS_API ts_status ts_pixel_prepare(ts_ctx *ctx, const ts_raster *exemplars, int n,
                                  const ts_pixel_params *params, ts_pixel_exemplars **out);
TS_API void ts_pixel_exemplars_free(ts_pixel_exemplars *ex);
/** The number of levels L the stacks have. */
TS_API int ts_pixel_levels(const ts_pixel_exemplars *ex);
/** The neighbourhood side k the stacks were prepared for (chosen when params->window is 0). */
TS_API int ts_pixel_window(const ts_pixel_exemplars *ex);
/** The candidates each exemplar gives (1, 2, 4 or 8: rotations, or what auto chose), and
 *  the exemplars' grain: the coherence of their gradients' orientation, 0 (no preferred
 *  direction) .. 1 (all one way).  Auto (rotations -1) turns by quarters only below
 *  TS_PIXEL_ISOTROPIC, else by a half turn alone, which keeps the grain. */
TS_API int ts_pixel_variants(const ts_pixel_exemplars *ex);
TS_API double ts_pixel_grain(const ts_pixel_exemplars *ex);
#define TS_PIXEL_ISOTROPIC 0.05
/** Is `rotations` a value ts_pixel_params takes (-1 auto, 0, 2, 4, 8)? */
TS_API int ts_pixel_rotations_valid(int rotations);

/**
 * The output cells [x0, x0 + out->width) x [y0, y0 + out->height) of the
 * endless terrain the exemplars and the context's seed define (any
 * coordinates, negative too, within 2^40): byte for byte the same window of
 * any larger run, whatever the thread count.
 */
TS_API ts_status ts_pixel_synthesize(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                     const ts_pixel_params *params, int64_t x0, int64_t y0,
                                     ts_raster *out);

/** Where each output cell's finest coordinate points (caller-allocated,
 *  width * height of the window, row-major; any may be NULL): the candidate
 *  exemplar (exemplar index x ts_pixel_variants + the variant)
 *  and the cell in it. */
typedef struct ts_pixel_sources {
    int32_t *exemplar, *x, *y;
} ts_pixel_sources;

/** A guide (Cruz et al. section II.B): a DEM on the output grid, in the
 *  exemplars' units, prepared as a Gaussian stack with the exemplars'
 *  levels (NaN = no guidance there). */
typedef struct ts_pixel_guide ts_pixel_guide;
TS_API ts_status ts_pixel_guide_prepare(ts_ctx *ctx, const ts_raster *guide,
                                        const ts_pixel_exemplars *ex,
                                        const ts_pixel_params *params, ts_pixel_guide **out);
/** The 1st and 99th percentiles of the exemplars' heights (finest level, nodata left out),
 *  and the guide's (the guide as given); 0, or -1 when either has no value. */
TS_API int ts_pixel_guide_ranges(const ts_raster *guide, const ts_pixel_exemplars *ex,
                                 double ex_range[2], double guide_range[2]);
TS_API void ts_pixel_guide_free(ts_pixel_guide *g);

/**
 * ts_pixel_synthesize following a guide whose cell (0, 0) is output cell
 * (0, 0): at each level the corrections' target neighbourhood is
 * (1 - params->guide_weight) x the heights the neighbours' coordinates give plus
 * params->guide_weight x the guide blurred to the level (our formulation of the
 * paper's "add the level of the guide's Laplacian pyramid, then correct").
 * Cells past the guide's edge take its nearest cell.
 */
/** ts_pixel_synthesize(_guided) (guide may be NULL) with the sources of
 *  the window's cells. */
TS_API ts_status ts_pixel_synthesize_sources(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                             const ts_pixel_guide *guide,
                                             const ts_pixel_params *params, int64_t x0, int64_t y0,
                                             ts_raster *out, const ts_pixel_sources *src);

TS_API ts_status ts_pixel_synthesize_guided(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                            const ts_pixel_guide *guide,
                                            const ts_pixel_params *params, int64_t x0, int64_t y0,
                                            ts_raster *out);

/**
 * The terrain zoomed out by 2^k (1 <= k <= ts_pixel_levels; guide may be
 * NULL): cell (X, Y) of the window covers the output cells [X 2^k,
 * (X + 1) 2^k) x [Y 2^k, (Y + 1) 2^k).  The synthesis stopped at the level
 * whose spacing is 2^k cells, each cell the sum of that level's and the
 * coarser levels' bands at the block's middle: the same terrain without the
 * detail finer than 2^k cells (a coarse synthesis, ours: not the average of
 * the full-resolution cells).  Byte for byte the same window of any larger
 * overview; the cost of its own cells, not of the 4^k cells under them.
 */
TS_API ts_status ts_pixel_synthesize_overview(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                              const ts_pixel_guide *guide,
                                              const ts_pixel_params *params, int k, int64_t x0,
                                              int64_t y0, ts_raster *out);

#endif /* TERRASYNTH_PIXEL_H */
