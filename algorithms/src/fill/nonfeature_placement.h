/*
 * nonfeature_placement.h - non-feature patch placement (Zhou et al. 2007
 * section 4.2), shared by its files: the run over the placement queue
 * (nonfeature_placement.c), the candidate search (candidate_search.c) and
 * the placing of one patch with its graph cuts and merge
 * (patch_placement.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_NONFEATURE_PLACEMENT_H
#define TS_NONFEATURE_PLACEMENT_H

#include "patch_merge.h"
#include "placement_queue.h"

#define TS__PLACE_MAX_LEVELS 5 /* pyramid levels: factors 1, 2, 4, 8, 16 */

/* How much each window of an exemplar's matcher level is used: the sum,
 * over the windows the fill placed, of their overlap with it (in windows). */
typedef struct ts__exemplar_usage {
    float *map;     /* nx * ny positions of the matcher's level */
    int nx, ny, PK; /* positions, window side on that level */
    double total;   /* sum of map */
    double detail2; /* the level's mean local variance (the cost's scale) */
} ts__exemplar_usage;

typedef struct ts__exemplar_data {
    const ts_raster *full;
    /* level[k]: box-downsampled by 2^k (NaN where any cell is); level[0] = *full */
    ts_raster level[TS__PLACE_MAX_LEVELS];
    int K;                     /* coarsest level: the coarse factor is 2^K */
    ts_matcher *matcher;       /* on level[K] */
    int32_t *nodata_sat;       /* summed-area table of full-resolution nodata, (w+1)*(h+1) */
    int32_t *feature_sat;      /* likewise of its main feature cells, or NULL */
    unsigned char *allowed;    /* level-K window positions not rich in main features, or NULL */
    int32_t feature_limit;     /* the most main feature cells an allowed window has */
    ts__exemplar_usage *usage; /* shared by the slots; NULL without a usage cost */
} ts__exemplar_data;

/* One placement slot: the run, its exemplars and its work buffers. */
typedef struct ts__placer {
    ts_ctx *ctx;
    const ts__fill *p;
    ts_raster *out;
    const unsigned char *flags; /* TS_CELL_* per output cell, or NULL */
    ts_synth_maps *maps;
    int map_index0; /* the maps' index of the run's first patch (patches placed before it) */
    ts__exemplar_data *ex;
    int n_ex;
    int P;         /* patch size */
    uint64_t rng0; /* from the seed; each placement draws from its own stream */
    uint64_t rng;
    int shares_ex; /* a second slot: ex[] levels and tables belong to the first */
    double sec[3]; /* seconds matching, cutting, merging (for maps) */
    /* work buffers */
    float *target, *patch;
    float *cand_patch; /* one P x P window per candidate, for parallel cuts */
    ts_merger merger;
    int32_t *src_x, *src_y; /* P x P: where each cell of the chosen patch comes from */
    float *mtarget;         /* what is matched: the window, with wanted heights where empty */
    float *tlevel[TS__PLACE_MAX_LEVELS]; /* matching pyramid (tlevel[0] = mtarget) */
    int *tknown[TS__PLACE_MAX_LEVELS];   /* known cells per level */
    int n_tknown[TS__PLACE_MAX_LEVELS];
    /* per level, the known cells' offsets in the current exemplar's level
     * (row * stride + column): no division in the SSD loop */
    ptrdiff_t *toff[TS__PLACE_MAX_LEVELS];
    unsigned char *constraint, *labels, *best_labels;
    int *known; /* indices of known target cells */
    int *near;  /* P x P: distance to the cells this patch fills */
    ts_candidate *cands;
    int n_cands_cap;
    double *cand_lb; /* per candidate: a lower bound of its cost */
    double *cand_h;  /* per candidate: its height costs */
    double *cand_u;  /* per candidate: its usage cost (squared height units) */
    int *to_cut;     /* candidates to cut, in order */
} ts__placer;

/* Is `bit` set in the TS_CELL_* flags of output cell (x, y)? */
static inline int ts__place_flag(const ts__placer *pl, int x, int y, int bit)
{
    return pl->flags && (pl->flags[(size_t)y * (size_t)pl->out->width + (size_t)x] & bit);
}

/* The sum of a summed-area table ((w + 1) columns) over [x0, x1) x [y0, y1). */
static inline int32_t ts__sat_sum(const int32_t *sat, int w, int x0, int y0, int x1, int y1)
{
    size_t W = (size_t)w + 1;
    return sat[(size_t)y1 * W + x1] - sat[(size_t)y0 * W + x1] - sat[(size_t)y1 * W + x0] +
           sat[(size_t)y0 * W + x0];
}

/* candidate_search.c: the exemplars' pyramids, tables and usage, and each
 * position's candidate windows. */

/* Prepare exemplar `index` (full) for slot pl: its pyramid, nodata table,
 * matcher, usage map and feature windows. */
ts_status ts__place_prepare_exemplar(ts__placer *pl, ts__exemplar_data *e, const ts_raster *full,
                                     int index);
/* Main feature cells in the middle half of the full-resolution window at
 * (x, y) (0 without a feature mask). */
int32_t ts__place_feature_count(const ts__placer *pl, const ts__exemplar_data *e, int x, int y);
/* Add the window (sx, sy) of an exemplar, placed, to its usage. */
void ts__place_usage_add(ts__exemplar_usage *u, int K, int sx, int sy);
/* The usage cost (per cell) of the full-resolution window (x, y). */
double ts__place_usage_of(const ts__placer *pl, const ts__exemplar_data *ed, int x, int y);
/* The k best full-resolution windows of exemplar e for the current target
 * (exact SSD, without the usage cost). */
ts_status ts__place_search(ts__placer *pl, int e, ts_candidate *out, int *n_out);

/* patch_placement.c: place one patch at q as patch `index`. */
ts_status ts__place_one(ts__placer *pl, ts__placement *q, int index);

#endif
