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
    int kind;                           /* bits TS_RIDGE, TS_VALLEY: the kinds drawn */
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

/* What a painted sketch draws (sketch_features.c): TS_SKETCH_BOTH on a
 * ground in the middle of its range with strokes both ways, else
 * TS_SKETCH_RIDGES when the strokes are bright (the minority of the cells
 * on a dark ground), TS_SKETCH_VALLEYS when dark; *ground: the median. */
int ts__sketch_auto_mode(ts_ctx *ctx, const ts_raster *sketch, double *ground);
/* The sketch's feature graph by PPA (pp: its parameters; features is set
 * here): one kind, or both (ridges brighter than `ground`, valleys darker)
 * in one forest.  *out: caller frees with ts_features_free. */
ts_status ts__sketch_graph(ts_ctx *ctx, const ts_raster *sketch, int mode, double ground,
                           const ts_ppa_params *pp, ts_features **out);
/* One forest of two graphs of the same grid (a's nodes, paths and
 * vertices first).  *out: caller frees with ts_features_free. */
ts_status ts__features_merge(ts_ctx *ctx, const ts_features *a, const ts_features *b,
                             ts_features **out);

#endif
