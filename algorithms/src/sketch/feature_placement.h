/*
 * feature_placement.h - feature patch matching and placement (Zhou et al.
 * 2007 section 4.1), called by the sketch pipeline of synth.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_FEATURE_PLACEMENT_H
#define TS_FEATURE_PLACEMENT_H

#include "feature_tree.h"
#include "internal.h"

/* A feature patch site found in an exemplar. */
typedef struct ts__ex_site {
    int ex; /* exemplar index */
    ts_feature_site site;
} ts__ex_site;

/* What the placement reads (all borrowed). */
typedef struct ts__feature_job {
    const ts_sketch_params *sp;
    const ts__fill *fill; /* lengths in cells; constraints; relief guide */
    const ts_raster *exemplars;
    int n_exemplars;
    const ts_features *sketch_features; /* the sketch's PPA graph */
    int kind;                           /* TS_RIDGE or TS_VALLEY */
    const ts__ex_site *exemplar_sites;
    size_t n_exemplar_sites;
    const ts_feature_site *sites; /* the sketch's, in placement order */
    size_t n_sites;
} ts__feature_job;

/* Place a feature patch at every site in turn (a site without a valid
 * candidate is left to the fill) into `out`, whose flags (width*height)
 * gain TS_CELL_FIXED on the placed feature cores; maps (may be NULL) record
 * the cells' sources.  *n_placed: the patches placed.  Progress over the
 * whole call; TS_ERR_CANCELLED, TS_ERR_NOMEM. */
ts_status ts__place_features(ts_ctx *ctx, const ts__feature_job *j, ts_raster *out,
                             unsigned char *flags, ts_synth_maps *maps, size_t *n_placed);

/* TS_SKETCH_RIDGES when the strokes are bright (they are the minority of
 * the cells), TS_SKETCH_VALLEYS when dark. */
int ts__sketch_auto_mode(ts_ctx *ctx, const ts_raster *sketch);

#endif
