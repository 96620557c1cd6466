/*
 * terrasynth_amplify.h - amplification with a dictionary (Argudo et al.
 * 2017) and the maps it reads: part of terrasynth.h, which includes it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TERRASYNTH_AMPLIFY_H
#define TERRASYNTH_AMPLIFY_H

#ifndef TERRASYNTH_H
#error "include terrasynth.h"
#endif

/* ------------------------------------------------------------------ */
/* Amplification with a dictionary (Argudo et al. 2017)               */
/* ------------------------------------------------------------------ */

/**
 * Parameters of `terrasynth amplify` (stage "amplify").  A coarse DEM is
 * cut into patches of `patch` x `patch` cells overlapping by half; each is
 * matched to the low-resolution atom of a dictionary that scores best on
 * g = sum_j w_j g_j / sum_j w_j (section 5): g_h = (1 + P_h . D_h) / 2 on
 * the normalised elevation (orientation kept: no atom is ever inverted),
 * g_a and g_s Gaussians of the mean altitude and of the mean deviation
 * (sigma: the Gaussian is 0.5 at the median difference over the atoms),
 * g_u = (1 + P_u . D_u) / 2 on the normalised log drainage area,
 * g_l = (1 + P_l . D_l) / 2 on the normalised mean annual solar irradiance,
 * g_c = P_c . D_c on the class vectors (scaled to unit length) and
 * g_x = (1 + P_x . D_x) / 2 on the normalised context (the 3p x 3p
 * neighbourhood block-averaged to p x p).  The
 * atom's high-resolution counterpart replaces the patch
 * (P~ = (P_h . D_h) P_s D~_h + P_a) and patches are blended with a falloff;
 * the atom's other layers come with it.
 */
typedef struct ts_amplify_params {
    int factor;                /* output cells per input cell along each axis, 2..16 */
    int patch;                 /* patch side in input cells (4..64); patches step by half of it */
    int atoms;                 /* at most this many atoms per exemplar */
    double w_h, w_a, w_s, w_u; /* matching weights (any scale; normalised to sum 1) */
    int refine;                /* back-projection passes: the output, area-averaged, gives back the
                                  input (our addition, 0 = the paper's reconstruction alone) */
    double w_l;                /* weight of the irradiance term (0: irradiance is not computed) */
    double w_c;                /* weight of the class term (used where classes are wanted) */
    double w_x;                /* weight of the context term (section 5.3) */
} ts_amplify_params;

TS_API ts_amplify_params ts_amplify_params_default(void);

/** A multi-resolution dictionary (D, D~): low- and high-resolution atoms in
 *  one-to-one correspondence, with their descriptors. */
typedef struct ts_dictionary ts_dictionary;

#define TS_MAX_LAYERS 8   /* extra layers a dictionary carries */
#define TS_LAYER_NAME 32  /* bytes of a layer's name, with its terminating 0 */
#define TS_MAX_CLASSES 64 /* class codes are 1..TS_MAX_CLASSES */

/** One exemplar of a dictionary, at the OUTPUT resolution (the caller
 *  resamples it).  Every raster but lat and north is on dem's grid. */
typedef struct ts_exemplar {
    ts_raster dem;
    double dx, dy; /* ground size of its cells in metres (0: unknown) */
    /* the dictionary's extra layers (n_layers of them, NaN = no value), or NULL */
    const ts_raster *layers;
    /* class codes 1..TS_MAX_CLASSES (0 or NaN: unlabelled), or NULL */
    const ts_raster *classes;
    /* latitude, and azimuth of the grid's up direction from true north
     * (degrees), on the grid of dem area-averaged by the factor (what the
     * irradiance is computed on); NULL: no irradiance for this exemplar */
    const ts_raster *lat, *north;
} ts_exemplar;

/**
 * Build a dictionary from exemplars: each is area-averaged by `factor`
 * into its low-resolution version, and atoms are the windows of `patch`
 * cells of it (all valid, on a regular lattice chosen to give at most
 * `atoms` of them) with the `patch * factor` windows of the exemplar (and
 * of its layers and classes) above them.  `layer_names` names the n_layers
 * extra layers every exemplar gives.  The irradiance descriptor is
 * computed when params->w_l > 0.
 */
TS_API ts_status ts_dictionary_build(ts_ctx *ctx, const ts_exemplar *exemplars, int n_exemplars,
                                     const char *const *layer_names, int n_layers,
                                     const ts_amplify_params *params, ts_dictionary **out);
TS_API size_t ts_dictionary_size(const ts_dictionary *dict);
TS_API void ts_dictionary_free(ts_dictionary *dict);

/** A dictionary as bytes, to build once and reuse (the caller writes and
 *  reads them: the core does no file I/O).  Little-endian whatever the
 *  machine, versioned; from_bytes checks every size against `len` (a file is
 *  untrusted).  *bytes is freed with free(). */
TS_API ts_status ts_dictionary_to_bytes(ts_ctx *ctx, const ts_dictionary *dict,
                                        unsigned char **bytes, size_t *len);
TS_API ts_status ts_dictionary_from_bytes(ts_ctx *ctx, const unsigned char *bytes, size_t len,
                                          ts_dictionary **out);
/** The factor and patch a dictionary was built for. */
TS_API void ts_dictionary_shape(const ts_dictionary *dict, int *factor, int *patch);
/** What a dictionary holds besides elevation: its extra layers, the highest
 *  class code of its classes (0: none), whether it has irradiance. */
TS_API void ts_dictionary_layers(const ts_dictionary *dict, int *n_layers, int *n_classes,
                                 int *has_irradiance);
/** How many atoms hold cells of class `code` (0 for a code out of 1..n_classes). */
TS_API size_t ts_dictionary_class_atoms(const ts_dictionary *dict, int code);
/** The name of extra layer i (NULL when out of range). */
TS_API const char *ts_dictionary_layer_name(const ts_dictionary *dict, int i);

/** What ts_amplify did (may be NULL). */
typedef struct ts_amplify_info {
    size_t n_patches, n_atoms;
    double seconds_match, seconds_synthesis;
    double mean_score; /* mean g of the chosen atoms */
    int n_inverted;    /* patches whose best atom had P_h . D_h < 0 (taken as flat) */
} ts_amplify_info;

/** What the input gives besides its elevation (every raster on its grid). */
typedef struct ts_amplify_guide {
    const ts_raster *drainage;   /* ts_drainage_area of the input (ts_amplify: NULL = computed) */
    const ts_raster *irradiance; /* ts_irradiance of the input; needed when w_l > 0 */
    const ts_raster *classes;    /* wanted class codes (0 or NaN: any), or NULL */
} ts_amplify_guide;

/** What ts_amplify writes besides the elevation (caller-allocated, on the
 *  output's grid or window; NULL = not wanted). */
typedef struct ts_amplify_layers {
    ts_raster *layers;  /* the dictionary's n_layers layers (NaN where no atom has a value) */
    ts_raster *classes; /* class codes (0 = unlabelled) of the atom that weighs most there */
} ts_amplify_layers;

/**
 * Amplify `coarse` (NaN = nodata) into `out` (caller-allocated,
 * coarse->width * factor x coarse->height * factor).  Cells under a nodata
 * coarse cell stay NaN.  `guide` and `layers` may be NULL.  Deterministic;
 * threads from the context.
 */
TS_API ts_status ts_amplify(ts_ctx *ctx, const ts_raster *coarse, const ts_amplify_guide *guide,
                            const ts_dictionary *dict, const ts_amplify_params *params,
                            ts_raster *out, const ts_amplify_layers *layers, ts_amplify_info *info);

/**
 * One window of what ts_amplify gives: the output cells [x0, x0 + out->width)
 * x [y0, y0 + out->height), byte for byte the same as that window of the
 * whole (amplification is local: only the patches over the window and the
 * margin back-projection needs are computed).  guide->drainage is required
 * (global: computed once, on the coarse grid).
 */
TS_API ts_status ts_amplify_window(ts_ctx *ctx, const ts_raster *coarse,
                                   const ts_amplify_guide *guide, const ts_dictionary *dict,
                                   const ts_amplify_params *params, int x0, int y0, ts_raster *out,
                                   const ts_amplify_layers *layers, ts_amplify_info *info);

/**
 * Several biomes (section 5.5): dictionary b weighs `weights[b]` (a raster
 * on the input's grid, >= 0; shares are the weights over their sum, equal
 * where all are 0).  Each patch is matched in every dictionary whose share
 * reaches it, and the reconstructions are blended by the shares
 * interpolated bilinearly to the output's cells, then back-projected.
 * Simplified, and named as such: a patch is matched whole in each
 * dictionary (the paper weighs the patch and the atoms by the shares cell
 * by cell, the Hadamard product: the same where a patch's shares are
 * uniform, not at a biome's edge).  A window of the output, as
 * ts_amplify_window (guide->drainage required; no layers or classes).
 */
TS_API ts_status ts_amplify_biomes(ts_ctx *ctx, const ts_raster *coarse,
                                   const ts_amplify_guide *guide, const ts_dictionary *const *dicts,
                                   const ts_raster *weights, int n_biomes,
                                   const ts_amplify_params *params, int x0, int y0, ts_raster *out,
                                   ts_amplify_info *info);

/** Area-average `fine` by `factor` into `coarse` (caller-allocated,
 *  fine->width / factor x fine->height / factor); a coarse cell with any
 *  nodata below it is nodata. */
TS_API ts_status ts_area_average(ts_ctx *ctx, const ts_raster *fine, int factor, ts_raster *coarse);

/** Upstream drainage area in cells, D8 (each cell drains to its steepest
 *  lower neighbour, diagonals at sqrt(2); ties to the first in the order
 *  E, SE, S, SW, W, NW, N, NE), deterministic.  `out` caller-allocated;
 *  NaN where the DEM is nodata. */
TS_API ts_status ts_drainage_area(ts_ctx *ctx, const ts_raster *dem, ts_raster *out);

/**
 * Mean annual direct solar irradiance (W/m^2, nights count as 0) with
 * self-shadowing (section 5.6): the sun's path over the year at each cell's
 * latitude `lat` (degrees), the grid turned by `north` (azimuth of the
 * grid's up direction from true north, degrees; NULL = 0), the terrain's
 * horizon along 16 directions and a clear-sky beam (Meinel's model).
 * `metrics` in metres (NULL: cells of 1 m).  NaN where dem or lat is NaN.
 */
TS_API ts_status ts_irradiance(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                               const ts_raster *lat, const ts_raster *north, ts_raster *out);

#endif /* TERRASYNTH_AMPLIFY_H */
