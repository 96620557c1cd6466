/*
 * relief_guide.h - private: the relief a sketch implies (a TerraSynth
 * addition to Zhou et al. 2007, see relief_guide.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_RELIEF_GUIDE_H
#define TS_RELIEF_GUIDE_H

#include "terrasynth.h"

/*
 * Exact Euclidean distance transform: dist[i] = distance in cells from cell
 * i to the nearest cell with mask[i] != 0 (INFINITY when there is none).
 * Felzenszwalb and Huttenlocher's lower envelope of parabolas, rows then
 * columns: O(width * height).  Returns TS_ERR_NOMEM.
 */
ts_status ts__distance_transform(ts_ctx *ctx, const unsigned char *mask, int width, int height,
                                 float *dist);
/* The same, and nearest[i] = the index (y * width + x) of a nearest mask
 * cell (-1 when there is none); any one of them on ties. */
ts_status ts__distance_transform_nearest(ts_ctx *ctx, const unsigned char *mask, int width,
                                         int height, float *dist, int32_t *nearest);

/*
 * How the land falls away from the main features of one exemplar.
 * level: the mean elevation on the feature cells; drop[d] (d = 0..max_d)
 * how far the mean elevation of the cells d..d+1 cells from the nearest
 * feature cell lies below the level (above it for valleys), made
 * non-decreasing with d.  valid = 0 when the exemplar has no such feature.
 */
typedef struct ts_relief_profile {
    int valid;
    int max_d;
    double level;
    double *drop; /* max_d + 1 entries */
} ts_relief_profile;

/* The profile of `dem` around the cells with (mask & kind) != 0. */
ts_status ts__relief_profile_measure(ts_ctx *ctx, const ts_raster *dem, const unsigned char *mask,
                                     int kind, int max_d, ts_relief_profile *prof);
void ts__relief_profile_free(ts_relief_profile *prof);

/*
 * The guide: for every output cell within max_d cells of the sketch's
 * features (sketch_mask & kind), level - drop(d) (valleys: + drop) from the
 * exemplar its region takes (cell_exemplar, may be NULL) or the mean over
 * the exemplars with a valid profile; NaN farther away, on nodata cells
 * (nodata != NULL and non-zero) and when no profile is valid.
 * guide: caller-allocated width*height floats.
 */
ts_status ts__relief_guide(ts_ctx *ctx, const unsigned char *sketch_mask, int kind, int width,
                           int height, const ts_relief_profile *profs, int n_profs,
                           const int32_t *cell_exemplar, const unsigned char *nodata, float *guide);

/* The guide of both kinds: each kind's (ts__relief_guide with its own
 * profiles), blended where both reach by the distance to the other kind
 * (the ridge's near ridges, the valley's near valleys). */
ts_status ts__relief_guide_both(ts_ctx *ctx, const unsigned char *sketch_mask, int width,
                                int height, const ts_relief_profile *profs_r,
                                const ts_relief_profile *profs_v, int n_profs,
                                const int32_t *cell_exemplar, const unsigned char *nodata,
                                float *guide);
#endif
