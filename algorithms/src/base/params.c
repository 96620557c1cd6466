/*
 * params.c - parameter descriptor tables, one per stage, and the generic
 * parse/format/validate code that every front end (CLI, GDAL driver
 * recipes and open options, QGIS provider) goes through.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"

static const ts_param_desc ppa_desc[] = {
    {"features", TS_PARAM_ENUM, TS_PPA_RIDGES, 0, 2, TS_UNIT_CELLS, "", "ridges|valleys|both",
     "Which axes to extract.", offsetof(ts_ppa_params, features)},
    {"profile_length", TS_PARAM_INT, 11, 3, 1001, TS_UNIT_CELLS, "cells", NULL,
     "Length of the four profiles through each cell (odd); a target must dip on both sides "
     "within half of it.",
     offsetof(ts_ppa_params, profile_length)},
    {"threshold", TS_PARAM_DOUBLE, 0.0, 0.0, 1e6, TS_UNIT_CELLS, "elevation units", NULL,
     "Minimum dip on both sides of a profile, in elevation units (metres after unit conversion).",
     offsetof(ts_ppa_params, threshold)},
    {"threshold_fraction", TS_PARAM_DOUBLE, -1.0, -1.0, 1.0, TS_UNIT_CELLS, "fraction", NULL,
     "Minimum dip as a fraction of the DEM's elevation range; the larger of the two thresholds "
     "applies.  -1 (auto): 0.0025, and 0.0001 for valleys with the drainage test "
     "(min_drainage > 0: the test keeps the hollows out, a low dip lets in channels on "
     "gentle ground).",
     offsetof(ts_ppa_params, threshold_fraction)},
    {"min_branch_length", TS_PARAM_LENGTH, -1, -1, 1e7, TS_UNIT_CELLS, "cells or m", NULL,
     "Branches shorter than this are removed (branch reduction); a plain number is cells, "
     "a number with suffix m is metres.  -1 (auto): 40 cells, and 10 cells for valleys with "
     "the drainage test (min_drainage > 0).",
     offsetof(ts_ppa_params, min_branch_length)},
    {"min_drainage", TS_PARAM_DOUBLE, 200.0, 0.0, 1e9, TS_UNIT_CELLS, "cells", NULL,
     "Valleys where the water runs: valley cells draining fewer cells than this are not "
     "valley targets (hollows above the channel heads; the drainage: depressions filled, "
     "flats crossed, each cell to its lowest neighbour).  0: valleys by their profiles alone, "
     "as ridges.",
     offsetof(ts_ppa_params, min_drainage)},
};

/* The sizes of patches and overlaps in cells, whatever unit they are given in. */
#define PATCH_MIN 8
#define PATCH_MAX 1024
#define OVERLAP_MIN 2
#define OVERLAP_MAX 512
#define STR_(x) #x
#define STR(x) STR_(x)

static const ts_param_desc synth_desc[] = {
    {"patch_size", TS_PARAM_LENGTH, 64, PATCH_MIN, PATCH_MAX, TS_UNIT_CELLS, "cells or m", NULL,
     "Side of the square patches copied from the exemplars: a whole number of cells, or a "
     "number with suffix m for metres (turned into cells at the output grid's ground "
     "resolution; " STR(PATCH_MIN) ".." STR(PATCH_MAX) " cells either way).",
     offsetof(ts_synth_params, patch_size)},
    {"overlap", TS_PARAM_LENGTH, 16, OVERLAP_MIN, OVERLAP_MAX, TS_UNIT_CELLS, "cells or m", NULL,
     "Width shared by neighbouring patches, where seams are cut and smoothed: cells, or "
     "metres with suffix m; at most half the patch.",
     offsetof(ts_synth_params, overlap)},
    {"candidates", TS_PARAM_INT, 6, 1, 256, TS_UNIT_CELLS, "", NULL,
     "Best SSD matches examined per patch position (k).", offsetof(ts_synth_params, candidates)},
    {"order", TS_PARAM_ENUM, TS_ORDER_GROW, 0, 2, TS_UNIT_CELLS, "", "grow|raster|tree",
     "Placement order: grow out from what is filled (with a sketch: its feature tree breadth "
     "first), raster scan, or tree (= grow).",
     offsetof(ts_synth_params, order)},
    {"alpha_g", TS_PARAM_DOUBLE, 1.0, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the graph-cut seam cost against the SSD when choosing a candidate.",
     offsetof(ts_synth_params, alpha_g)},
    {"variety", TS_PARAM_DOUBLE, 0.1, 0.0, 10.0, TS_UNIT_CELLS, "fraction", NULL,
     "Pick at random (seeded) among candidates whose cost is within this fraction of the best.",
     offsetof(ts_synth_params, variety)},
    {"coarse_factor", TS_PARAM_INT, 0, 0, 16, TS_UNIT_CELLS, "", NULL,
     "Search on exemplars downsampled by this factor, then refine at full resolution "
     "(1 = exhaustive full-resolution search; 0 = automatic: exemplars brought to at most "
     "512 x 512 cells).",
     offsetof(ts_synth_params, coarse_factor)},
    {"tiled", TS_PARAM_INT, 0, 0, 16384, TS_UNIT_CELLS, "cells", NULL,
     "Free synthesis in tiles of this many cells, made in four waves (a tile is cut and "
     "smoothed against its finished neighbours, the tiles of a wave run in parallel); "
     "a recipe in tiles is served tile by tile, any window alone (256-512 suit that); "
     "0 = in one piece.  With a sketch: the sketch laid out coarser and amplified "
     "(amplify_factor).",
     offsetof(ts_synth_params, tiled)},
    {"usage", TS_PARAM_DOUBLE, -1.0, -1.0, 1000.0, TS_UNIT_CELLS, "", NULL,
     "Weight of the usage cost: a candidate pays this times the exemplar's detail variance "
     "times how much its window is already used, relative to the average, so the fill draws "
     "on the whole exemplar instead of the windows that match most easily (smooth ones) and "
     "does not copy the exemplar's layout; 0 = off, -1 = automatic: 32 for free synthesis, "
     "0 with a sketch (there it costs feature recall and seams).",
     offsetof(ts_synth_params, usage)},
};

static const ts_param_desc sketch_desc[] = {
    {"mode", TS_PARAM_ENUM, TS_SKETCH_AUTO, 0, 3, TS_UNIT_CELLS, "", "ridges|valleys|auto|both",
     "What the sketch draws: ridges (bright strokes), valleys (dark strokes), both (on a grey "
     "ground, strokes brighter are ridges and darker are valleys), or auto (both on a ground "
     "in the middle of the range with strokes either way, else the minority's kind).",
     offsetof(ts_sketch_params, mode)},
    {"alpha_d", TS_PARAM_DOUBLE, 1000.0, 0.0, 1e9, TS_UNIT_CELLS, "", NULL,
     "Weight of the warp deformation cost c_d of feature patches.",
     offsetof(ts_sketch_params, alpha_d)},
    {"alpha_f", TS_PARAM_DOUBLE, 3.0, 0.0, 1e9, TS_UNIT_CELLS, "", NULL,
     "Weight of the feature profile dissimilarity c_f of feature patches.",
     offsetof(ts_sketch_params, alpha_f)},
    {"alpha_s", TS_PARAM_DOUBLE, 0.0, 0.0, 1e9, TS_UNIT_CELLS, "", NULL,
     "Weight of the path smoothness constraint c_s: crest (valleys: thalweg) heights along "
     "the sketch's strokes bend less, within a feature patch and where it joins the placed "
     "ones; larger gives smoother, gentler crests (0 = off).",
     offsetof(ts_sketch_params, alpha_s)},
    {"alpha_p", TS_PARAM_DOUBLE, 1.0, 0.0, 1e9, TS_UNIT_CELLS, "", NULL,
     "Weight of the crest prominence c_p of feature patches: among the candidates that fit, "
     "those whose crest (valleys: thalweg) stands out most across the stroke, an eighth of a "
     "patch either side, so that sketched strokes read as main features (0 = off).",
     offsetof(ts_sketch_params, alpha_p)},
    {"alpha_r", TS_PARAM_DOUBLE, 0.5, 0.0, 1e9, TS_UNIT_CELLS, "", NULL,
     "Weight of the relief guide: sketched ridges stand high and sketched valleys lie low, "
     "falling away from the strokes as the exemplars' land falls away from their main "
     "features (0 = off: the exemplars alone decide the heights).",
     offsetof(ts_sketch_params, alpha_r)},
    {"layout", TS_PARAM_DOUBLE, 1.0, 0.0, 1.0, TS_UNIT_CELLS, "fraction", NULL,
     "How far the sketch sets the large-scale relief (scales above a third of a patch): "
     "the land rises to sketched ridges and falls to sketched valleys as steeply, at that "
     "scale, as the exemplars' land; smaller scales keep the patches' detail (0 = off).",
     offsetof(ts_sketch_params, layout)},
    {"slope_style", TS_PARAM_DOUBLE, 1.0, 0.0, 1.0, TS_UNIT_CELLS, "fraction", NULL,
     "How far the output's slopes take the exemplars' distribution of slopes at the "
     "output's resolution, after the layout: gradients rescaled by quantile mapping, "
     "directions kept, heights refitted by a Poisson solve (0 = off).",
     offsetof(ts_sketch_params, slope_style)},
    {"crest_relief", TS_PARAM_DOUBLE, 0.4, 0.0, 1.0, TS_UNIT_CELLS, "fraction", NULL,
     "How far drawn crests rise and fall with the exemplars' own peaks and saddles (their "
     "main ridges' heights between a quarter patch and two patches, laid along the strokes "
     "by the seed) on top of the patches' own: 0 one level along each ridge; at 1 the "
     "deepest saddles can break a drawn ridge.",
     offsetof(ts_sketch_params, crest_relief)},
    {"amplify_factor", TS_PARAM_INT, 0, 0, 16, TS_UNIT_CELLS, "", NULL,
     "In tiles (tiled > 0): the sketch is laid out whole on a grid this many times coarser, "
     "with patches and overlap this many times smaller (the same ground size), then "
     "amplified back onto the output grid (Argudo et al. 2017), window by window; 0 = "
     "automatic: the largest power of two up to 16 that leaves patches of 32 cells or more "
     "(2 for patches of 64), at least 2 (1 for patches under 16 cells), doubled while the "
     "coarse grid has more than 2048 x 2048 cells and patches keep 8; 1 = laid out at the "
     "output's cells, nothing amplified.",
     offsetof(ts_sketch_params, amplify_factor)},
};

static const ts_param_desc amplify_desc[] = {
    {"factor", TS_PARAM_INT, 4, 2, 16, TS_UNIT_CELLS, "", NULL,
     "Output cells per input cell along each axis: the output grid is this many times finer, "
     "on the same extent and CRS.",
     offsetof(ts_amplify_params, factor)},
    {"patch", TS_PARAM_INT, 6, 4, 64, TS_UNIT_CELLS, "input cells", NULL,
     "Side of the patches the input is cut into (they overlap by half), in input cells; an "
     "atom is this many cells of the area-averaged exemplar.",
     offsetof(ts_amplify_params, patch)},
    {"atoms", TS_PARAM_INT, 4096, 16, 262144, TS_UNIT_CELLS, "", NULL,
     "Most atoms taken from one exemplar (on a regular lattice over its valid windows).",
     offsetof(ts_amplify_params, atoms)},
    {"w_h", TS_PARAM_DOUBLE, 0.4, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the shape term g_h: (1 + P_h . D_h) / 2 on the normalised elevation.",
     offsetof(ts_amplify_params, w_h)},
    {"w_a", TS_PARAM_DOUBLE, 0.2, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the altitude term g_a: a Gaussian of the mean elevation difference.",
     offsetof(ts_amplify_params, w_a)},
    {"w_s", TS_PARAM_DOUBLE, 0.2, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the slope term g_s: a Gaussian of the difference of mean deviations.",
     offsetof(ts_amplify_params, w_s)},
    {"w_u", TS_PARAM_DOUBLE, 0.2, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the drainage term g_u: (1 + P_u . D_u) / 2 on the normalised log upstream "
     "drainage area.",
     offsetof(ts_amplify_params, w_u)},
    {"refine", TS_PARAM_INT, 3, 0, 10, TS_UNIT_CELLS, "", NULL,
     "Back-projection passes (our addition): the low-frequency difference between the input "
     "and the area-averaged output is added back, so the output averages to the input "
     "(0 = the paper's reconstruction alone).",
     offsetof(ts_amplify_params, refine)},
    {"w_l", TS_PARAM_DOUBLE, 0.0, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the irradiance term g_l: (1 + P_l . D_l) / 2 on the normalised mean annual "
     "solar irradiance with self-shadowing, from each cell's latitude (0: not computed).",
     offsetof(ts_amplify_params, w_l)},
    {"w_c", TS_PARAM_DOUBLE, 0.4, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the class term g_c: P_c . D_c on the class vectors, where the input gives "
     "wanted classes.",
     offsetof(ts_amplify_params, w_c)},
    {"w_x", TS_PARAM_DOUBLE, 0.0, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Weight of the context term g_x (section 5.3): (1 + P_x . D_x) / 2 on the normalised "
     "neighbourhood three patches wide, block-averaged to a patch.",
     offsetof(ts_amplify_params, w_x)},
};

static const ts_param_desc pixel_desc[] = {
    {"levels", TS_PARAM_INT, 0, 0, 10, TS_UNIT_CELLS, "", NULL,
     "Levels of the exemplars' Gaussian stacks above the finest (the coarsest spacing is "
     "2^levels cells); 0: as many as leave a coarsest neighbourhood half the smallest exemplar, "
     "at most 5.",
     offsetof(ts_pixel_params, levels)},
    {"passes", TS_PARAM_INT, 2, 0, 8, TS_UNIT_CELLS, "", NULL,
     "Correction passes per level (each of 4 sub-passes over the cells of one parity).",
     offsetof(ts_pixel_params, passes)},
    {"window", TS_PARAM_INT, 5, 0, 9, TS_UNIT_CELLS, "", NULL,
     "Side k of the k x k neighbourhoods compared in the corrections (odd; 3 at the levels of a "
     "spacing of 16 cells or more); 0: the k in "
     "3, 5, 7, 9 whose principal components holding 95 % of the neighbourhoods' variance are "
     "the smallest share of k x k (Cruz et al.).",
     offsetof(ts_pixel_params, window)},
    {"jitter", TS_PARAM_DOUBLE, 0.4, 0.0, 2.0, TS_UNIT_CELLS, "", NULL,
     "Jitter of the upsampled coordinates, in spacings of the level (from a hash of the "
     "absolute position and the seed).",
     offsetof(ts_pixel_params, jitter)},
    {"guide_weight", TS_PARAM_DOUBLE, 0.5, 0.0, 1.0, TS_UNIT_CELLS, "", NULL,
     "Weight of the guide in the corrections' target neighbourhoods (with a guide): 0 ignores "
     "it, 1 matches the guide's heights alone.",
     offsetof(ts_pixel_params, guide_weight)},
    {"guide_heights", TS_PARAM_ENUM, TS_GUIDE_AS_GIVEN, 0, 2, TS_UNIT_CELLS, "",
     "as-given|stretch|quantile",
     "How the guide's values are read: as heights in the exemplars' units (as-given), "
     "mapped linearly so that their 1st..99th percentiles span the exemplars' (stretch: a "
     "DEM of another relief), or each value to the exemplars' height of the same rank "
     "(quantile: a sketch drawn in grey levels, whose ground then takes the exemplars' most "
     "common heights).",
     offsetof(ts_pixel_params, guide_heights)},
    {"rotations", TS_PARAM_INT, -1, -1, 8, TS_UNIT_CELLS, "", NULL,
     "Candidates turned and mirrored (Cruz et al.): 0 the exemplars as given, 2 also turned "
     "by 180 degrees (every direction kept), 4 also by 90 and 270 degrees, 8 those and their "
     "mirror images; -1 (auto): 4 for exemplars without a preferred direction (orientation "
     "coherence of their gradients below 0.05), else 2, so a grained exemplar keeps its grain.",
     offsetof(ts_pixel_params, rotations)},
    {"coherence", TS_PARAM_INT, 1, 1, 8, TS_UNIT_CELLS, "", NULL,
     "K of the k-coherence search (Lefebvre and Hoppe): besides each neighbour's coherent "
     "coordinate, the corrections try the K - 1 exemplar cells whose neighbourhoods are "
     "nearest to its own (found once by a kd-tree); 1: coherent candidates only.",
     offsetof(ts_pixel_params, coherence)},
    {"pca_energy", TS_PARAM_DOUBLE, 0.95, 0.5, 1.0, TS_UNIT_CELLS, "", NULL,
     "Share of the variance of the neighbourhoods' shapes (each less its mean) kept by the "
     "principal directions the corrections compare (Cruz et al.: 0.95); the mean is always "
     "kept; 1 keeps every direction (plain sum of squared differences).",
     offsetof(ts_pixel_params, pca_energy)},
    {"guide_spacing", TS_PARAM_INT, 8, 1, 1024, TS_UNIT_CELLS, "", NULL,
     "The finest level the guide steers, as its spacing in cells: the corrections of finer "
     "levels leave the guide out and take their detail from the exemplars alone (a drawing or "
     "a coarse DEM, smooth between its lines, would flatten them); 1: every level.",
     offsetof(ts_pixel_params, guide_spacing)},
    {"start", TS_PARAM_ENUM, TS_PIXEL_START_RELIEF, 0, 1, TS_UNIT_CELLS, "", "relief|random",
     "Without a guide, where the coarsest level starts: a smooth random relief whose every "
     "value takes the exemplars' height of the same rank (relief: plains and mountains in "
     "the exemplars' proportions; ours), or a coordinate per cell at random (random: the "
     "corrections then keep middle heights).",
     offsetof(ts_pixel_params, start)},
    {"relief_scale", TS_PARAM_DOUBLE, 0.0, 0.0, 1e6, TS_UNIT_CELLS, "", NULL,
     "Lattice spacing of the relief start, in cells: the larger, the wider its plains and "
     "mountains; 0: the spacing whose relief matches the exemplars' at the coarsest level's "
     "spacing.",
     offsetof(ts_pixel_params, relief_scale)},
    {"guide_mode", TS_PARAM_ENUM, TS_GUIDE_PULL, 0, 1, TS_UNIT_CELLS, "", "pull|add",
     "How the guide steers the corrections of each level down to guide_spacing: their target "
     "neighbourhoods pulled towards the guide's heights at that level by guide_weight (pull; "
     "ours), or the guide's Laplacian band of that level added to the level's heights in full "
     "(add: Cruz et al.; the coarsest level is pulled by guide_weight in both).",
     offsetof(ts_pixel_params, guide_mode)},
    {"roughness_weight", TS_PARAM_DOUBLE, 8.0, 0.0, 1e4, TS_UNIT_CELLS, "", NULL,
     "Weight of the roughness term (ours): the corrections also compare the roughness of the "
     "target neighbourhood (the root sum of squares of its heights about their mean) with each "
     "candidate's, this weight times their difference squared, at the levels the guide does "
     "not steer. The sum of squared differences alone prefers smooth places where the target "
     "is a patchwork of several (outputs gentler than the exemplar); 0: off.",
     offsetof(ts_pixel_params, roughness_weight)},
};

static const ts_param_desc drainage_desc[] = {
    {"drainage", TS_PARAM_ENUM, TS_DRAINAGE_BREACH, 0, 2, TS_UNIT_CELLS, "", "keep|breach|fill",
     "What becomes of the closed depressions the synthesis leaves (ours, after Lindsay 2016): "
     "keep them; breach them (a channel cut from each pit along the cheapest path to lower "
     "land or the grid's edge, with banks falling to it where it cuts deep; by synth in one "
     "piece with the automatic depth, free synthesis then lifts the basins wider than the "
     "radius smoothly and breaches again, and a basin too deep to cut beside a drawn valley's "
     "floor is raised to a plain at its spill instead); or fill them to their spill height "
     "(flat lakes). "
     "Water and pinned windows never change; a channel crosses a drawn ridge only where the land "
     "inside has no other way out.",
     offsetof(ts_drainage_params, mode)},
    {"drainage_radius", TS_PARAM_INT, 128, 1, TS_DRAINAGE_RADIUS_MAX, TS_UNIT_CELLS, "cells", NULL,
     "How far from its pit a channel or a fill reaches; a depression with no way out within "
     "it is kept (a crater, a lake basin). Windows and tiles are computed with a margin of "
     "two and a half times this (twice with drainage_banks 0 or with fill).",
     offsetof(ts_drainage_params, radius)},
    {"drainage_depth", TS_PARAM_DOUBLE, -1.0, -1.0, 1e6, TS_UNIT_CELLS, "elevation units", NULL,
     "The deepest a breach channel may cut: a depression that needs a deeper one is kept "
     "(a basin the exemplars could hold: a lake, a crater, the inside of a ring drawn closed). "
     "-1 (auto): the bank slope times an eighth of the radius (a gorge whose banks reach at "
     "most that far each side; no limit without banks); 0: no limit.",
     offsetof(ts_drainage_params, max_depth)},
    {"drainage_banks", TS_PARAM_DOUBLE, -1.0, -1.0, 1e6, TS_UNIT_CELLS, "elevation units per cell",
     NULL,
     "The slope of a breach channel's banks (ours): where a channel cuts deeper than this, the "
     "land beside it is lowered to slopes falling to it at this slope, as far as the cut "
     "needs (at most half the radius): a gorge through the dam instead of a slot one cell "
     "wide. -1 (auto): the median gradient of the exemplars (amplify: of the input, divided "
     "by the factor), so the banks are as steep as their typical land; 0: no banks "
     "(Lindsay's breaching).",
     offsetof(ts_drainage_params, bank_slope)},
};

static const char *const stage_names[] = {"ppa",   "synth",    "sketch", "amplify",
                                          "pixel", "drainage", NULL};

TS_API const char *const *ts_params_stages(void)
{
    return stage_names;
}

TS_API const ts_param_desc *ts_params_describe(const char *stage, size_t *n)
{
    if (stage && strcmp(stage, "ppa") == 0) {
        *n = sizeof ppa_desc / sizeof ppa_desc[0];
        return ppa_desc;
    }
    if (stage && strcmp(stage, "synth") == 0) {
        *n = sizeof synth_desc / sizeof synth_desc[0];
        return synth_desc;
    }
    if (stage && strcmp(stage, "sketch") == 0) {
        *n = sizeof sketch_desc / sizeof sketch_desc[0];
        return sketch_desc;
    }
    if (stage && strcmp(stage, "amplify") == 0) {
        *n = sizeof amplify_desc / sizeof amplify_desc[0];
        return amplify_desc;
    }
    if (stage && strcmp(stage, "pixel") == 0) {
        *n = sizeof pixel_desc / sizeof pixel_desc[0];
        return pixel_desc;
    }
    if (stage && strcmp(stage, "drainage") == 0) {
        *n = sizeof drainage_desc / sizeof drainage_desc[0];
        return drainage_desc;
    }
    *n = 0;
    return NULL;
}

static const ts_param_desc *find_desc(ts_ctx *ctx, const char *stage, const char *name)
{
    size_t i, n;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    if (!d) {
        ts__fail(ctx, TS_ERR_ARG, "params", "unknown stage '%s'", stage ? stage : "(null)");
        return NULL;
    }
    for (i = 0; i < n; i++) {
        /* accept snake_case and dashed-case */
        const char *a = d[i].name, *b = name;
        while (*a && *b && (*a == *b || (*a == '_' && *b == '-')))
            a++, b++;
        if (!*a && !*b)
            return &d[i];
    }
    ts__fail(ctx, TS_ERR_ARG, stage, "unknown parameter '%s'", name);
    return NULL;
}

/* Index of `word` in "a|b|c", or -1. */
static int enum_index(const char *choices, const char *word)
{
    int idx = 0;
    size_t wl = strlen(word);
    const char *p = choices;
    while (*p) {
        const char *bar = strchr(p, '|');
        size_t len = bar ? (size_t)(bar - p) : strlen(p);
        if (len == wl && strncmp(p, word, len) == 0)
            return idx;
        idx++;
        if (!bar)
            break;
        p = bar + 1;
    }
    return -1;
}

static int enum_word(const char *choices, int index, char *buf, size_t buflen)
{
    int idx = 0;
    const char *p = choices;
    while (*p) {
        const char *bar = strchr(p, '|');
        size_t len = bar ? (size_t)(bar - p) : strlen(p);
        if (idx == index) {
            snprintf(buf, buflen, "%.*s", (int)len, p);
            return 0;
        }
        idx++;
        if (!bar)
            break;
        p = bar + 1;
    }
    return -1;
}

static ts_status check_range(ts_ctx *ctx, const char *stage, const ts_param_desc *d, double v)
{
    if (!(v >= d->min && v <= d->max))
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = %g is out of range [%g, %g]", d->name, v,
                        d->min, d->max);
    if (d->min == -1.0 && v < 0 && v != -1.0) /* -1 is "auto", not a value */
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = %g: give -1 (auto) or 0 .. %g", d->name, v,
                        d->max);
    if (d->type == TS_PARAM_INT && strcmp(d->name, "profile_length") == 0 && ((long)v % 2) == 0)
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = %g must be odd", d->name, v);
    return TS_OK;
}

/* A length's range is in cells; metres are checked once they are turned into
 * cells against a grid (ts_synth_params_resolve), here only for sign. */
static ts_status check_length(ts_ctx *ctx, const char *stage, const ts_param_desc *d, double v,
                              ts_length_unit unit)
{
    if (unit == TS_UNIT_CELLS)
        return check_range(ctx, stage, d, v);
    if (!(v >= 0.0) || !isfinite(v) || (d->min > 0 && !(v > 0.0)))
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = %gm must be %s", d->name, v,
                        d->min > 0 ? "positive" : "zero or more");
    return TS_OK;
}

TS_API ts_status ts_params_set(ts_ctx *ctx, const char *stage, void *params, const char *name,
                               const char *value)
{
    const ts_param_desc *d;
    char *end;
    double v;
    ts__clear(ctx);
    if (!(d = find_desc(ctx, stage, name)))
        return ctx->status;
    if (!value || !*value)
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s needs a value", d->name);
    if (d->type == TS_PARAM_ENUM) {
        int idx = enum_index(d->choices, value);
        if (idx < 0)
            return ts__fail(ctx, TS_ERR_ARG, stage, "%s = '%s' is not one of %s", d->name, value,
                            d->choices);
        *(int *)((char *)params + d->offset) = idx;
        return TS_OK;
    }
    errno = 0;
    v = strtod(value, &end);
    if (end == value || errno == ERANGE || !isfinite(v))
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = '%s' is not a number", d->name, value);
    while (isspace((unsigned char)*end))
        end++;
    if (d->type == TS_PARAM_LENGTH) {
        ts_length *L = (ts_length *)((char *)params + d->offset);
        ts_length_unit unit;
        if (!*end || !strcmp(end, "cells") || !strcmp(end, "cell") || !strcmp(end, "px"))
            unit = TS_UNIT_CELLS;
        else if (!strcmp(end, "m") || !strcmp(end, "metres") || !strcmp(end, "meters"))
            unit = TS_UNIT_METRES;
        else
            return ts__fail(ctx, TS_ERR_ARG, stage,
                            "%s = '%s': unit must be cells (no suffix) or m", d->name, value);
        if (check_length(ctx, stage, d, v, unit) != TS_OK)
            return ctx->status;
        L->value = v;
        L->unit = unit;
        return TS_OK;
    }
    if (*end)
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = '%s' is not a number", d->name, value);
    if (d->type == TS_PARAM_INT && v != floor(v))
        return ts__fail(ctx, TS_ERR_ARG, stage, "%s = '%s' must be a whole number", d->name, value);
    if (check_range(ctx, stage, d, v) != TS_OK)
        return ctx->status;
    if (d->type == TS_PARAM_INT)
        *(int *)((char *)params + d->offset) = (int)v;
    else
        *(double *)((char *)params + d->offset) = v;
    return TS_OK;
}

TS_API ts_status ts_params_get(ts_ctx *ctx, const char *stage, const void *params, const char *name,
                               char *buf, size_t buflen)
{
    const ts_param_desc *d;
    const char *p = (const char *)params;
    ts__clear(ctx);
    if (!(d = find_desc(ctx, stage, name)))
        return ctx->status;
    switch (d->type) {
    case TS_PARAM_ENUM:
        if (enum_word(d->choices, *(const int *)(p + d->offset), buf, buflen) != 0)
            return ts__fail(ctx, TS_ERR_ARG, stage, "%s has an invalid value", d->name);
        break;
    case TS_PARAM_INT:
        snprintf(buf, buflen, "%d", *(const int *)(p + d->offset));
        break;
    case TS_PARAM_DOUBLE: {
        /* the shortest of %.15g / %.17g that reads back to the same value */
        double v = *(const double *)(p + d->offset);
        snprintf(buf, buflen, "%.15g", v);
        if (strtod(buf, NULL) != v)
            snprintf(buf, buflen, "%.17g", v);
        break;
    }
    case TS_PARAM_LENGTH: {
        const ts_length *L = (const ts_length *)(p + d->offset);
        snprintf(buf, buflen, "%.15g%s", L->value, L->unit == TS_UNIT_METRES ? "m" : "");
        if (strtod(buf, NULL) != L->value)
            snprintf(buf, buflen, "%.17g%s", L->value, L->unit == TS_UNIT_METRES ? "m" : "");
        break;
    }
    }
    return TS_OK;
}

TS_API ts_status ts_params_validate(ts_ctx *ctx, const char *stage, const void *params)
{
    size_t i, n;
    const char *p = (const char *)params;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    ts__clear(ctx);
    if (!d)
        return ts__fail(ctx, TS_ERR_ARG, "params", "unknown stage '%s'", stage ? stage : "(null)");
    for (i = 0; i < n; i++) {
        double v = 0;
        switch (d[i].type) {
        case TS_PARAM_ENUM:
        case TS_PARAM_INT:
            v = *(const int *)(p + d[i].offset);
            break;
        case TS_PARAM_DOUBLE:
            v = *(const double *)(p + d[i].offset);
            break;
        case TS_PARAM_LENGTH: {
            const ts_length *L = (const ts_length *)(p + d[i].offset);
            if (L->unit != TS_UNIT_CELLS && L->unit != TS_UNIT_METRES)
                return ts__fail(ctx, TS_ERR_ARG, stage, "%s has an invalid unit", d[i].name);
            if (check_length(ctx, stage, &d[i], L->value, L->unit) != TS_OK)
                return ctx->status;
            continue;
        }
        }
        if (check_range(ctx, stage, &d[i], v) != TS_OK)
            return ctx->status;
    }
    if (!strcmp(stage, "synth")) {
        /* the rule between patch and overlap, when both are in cells (in metres it
         * waits for the grid: ts_synth_params_resolve) */
        const ts_synth_params *sp = params;
        int P, ov;
        if (sp->patch_size.unit == TS_UNIT_CELLS && sp->overlap.unit == TS_UNIT_CELLS)
            return ts__synth_cells(ctx, sp, &P, &ov);
    }
    return TS_OK;
}

/* Fill a params struct with the defaults of its descriptor table: one
 * place to change them. */
static void params_fill_defaults(const char *stage, void *params, size_t size)
{
    size_t i, n;
    const ts_param_desc *d = ts_params_describe(stage, &n);
    memset(params, 0, size);
    for (i = 0; i < n; i++) {
        char *f = (char *)params + d[i].offset;
        switch (d[i].type) {
        case TS_PARAM_ENUM:
        case TS_PARAM_INT:
            *(int *)f = (int)d[i].def;
            break;
        case TS_PARAM_DOUBLE:
            *(double *)f = d[i].def;
            break;
        case TS_PARAM_LENGTH:
            ((ts_length *)f)->value = d[i].def;
            ((ts_length *)f)->unit = d[i].def_unit;
            break;
        }
    }
}

TS_API ts_ppa_params ts_ppa_params_default(void)
{
    ts_ppa_params p;
    params_fill_defaults("ppa", &p, sizeof p);
    return p;
}

TS_API ts_sketch_params ts_sketch_params_default(void)
{
    ts_sketch_params p;
    params_fill_defaults("sketch", &p, sizeof p);
    return p;
}

TS_API ts_pixel_params ts_pixel_params_default(void)
{
    ts_pixel_params p;
    params_fill_defaults("pixel", &p, sizeof p);
    return p;
}

TS_API ts_drainage_params ts_drainage_params_default(void)
{
    ts_drainage_params p;
    params_fill_defaults("drainage", &p, sizeof p);
    return p;
}

TS_API ts_amplify_params ts_amplify_params_default(void)
{
    ts_amplify_params p;
    params_fill_defaults("amplify", &p, sizeof p);
    return p;
}

TS_API ts_synth_params ts_synth_params_default(void)
{
    ts_synth_params p;
    params_fill_defaults("synth", &p, sizeof p);
    return p;
}

/* A length that must come to a whole number of cells in [lo, hi]. */
static ts_status synth_cells_of(ts_ctx *ctx, const char *name, const ts_length *L, int lo, int hi,
                                int *cells)
{
    if (L->unit != TS_UNIT_CELLS)
        return ts__fail(ctx, TS_ERR_ARG, "synth",
                        "%s is %gm: resolve it against the grid first (ts_synth_params_resolve)",
                        name, L->value);
    if (!(L->value >= lo && L->value <= hi) || L->value != floor(L->value))
        return ts__fail(ctx, TS_ERR_ARG, "synth",
                        "%s = %g cells must be a whole number in [%d, %d]", name, L->value, lo, hi);
    *cells = (int)L->value;
    return TS_OK;
}

ts_status ts__synth_cells(ts_ctx *ctx, const ts_synth_params *p, int *patch, int *overlap)
{
    if (synth_cells_of(ctx, "patch_size", &p->patch_size, PATCH_MIN, PATCH_MAX, patch) != TS_OK ||
        synth_cells_of(ctx, "overlap", &p->overlap, OVERLAP_MIN, OVERLAP_MAX, overlap) != TS_OK)
        return ctx->status;
    /* at most half: every cell is then covered by at most 4 patches; an overlap
     * near the patch size multiplies the work without limit (31 of 32: 86x) */
    if (2 * *overlap > *patch)
        return ts__fail(ctx, TS_ERR_ARG, "synth",
                        "overlap %d must be at most half of patch_size %d (more multiplies the "
                        "work: every cell would be matched again and again)",
                        *overlap, *patch);
    return TS_OK;
}

TS_API ts_status ts_synth_params_resolve(ts_ctx *ctx, ts_synth_params *params, double cell_m)
{
    ts_length *L[2];
    const char *names[2] = {"patch_size", "overlap"};
    const int lo[2] = {PATCH_MIN, OVERLAP_MIN}, hi[2] = {PATCH_MAX, OVERLAP_MAX};
    int i, P, ov;
    ts__clear(ctx);
    if (!params)
        return ts__fail(ctx, TS_ERR_ARG, "synth", "missing parameters");
    L[0] = &params->patch_size;
    L[1] = &params->overlap;
    for (i = 0; i < 2; i++) {
        double cells;
        if (L[i]->unit != TS_UNIT_METRES)
            continue;
        if (!(cell_m > 0) || !isfinite(cell_m))
            return ts__fail(ctx, TS_ERR_ARG, "synth",
                            "%s is given in metres (%gm) but the output grid has no ground size "
                            "(no CRS): give it in cells",
                            names[i], L[i]->value);
        cells = floor(L[i]->value / cell_m + 0.5);
        if (!(cells >= lo[i] && cells <= hi[i]))
            return ts__fail(ctx, TS_ERR_ARG, "synth",
                            "%s = %gm is %.0f cells of %.4g m: must be %d..%d cells", names[i],
                            L[i]->value, cells, cell_m, lo[i], hi[i]);
        L[i]->value = cells;
        L[i]->unit = TS_UNIT_CELLS;
    }
    return ts__synth_cells(ctx, params, &P, &ov);
}
