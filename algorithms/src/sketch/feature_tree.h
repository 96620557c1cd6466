/*
 * feature_tree.h - patch sites of a feature graph (Zhou et al. 2007 §4),
 * private to the library.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_FEATURE_TREE_H
#define TS_FEATURE_TREE_H

#include "internal.h"

#define TS_SITE_MAX_ARMS 8

enum { TS_SITE_BRANCH = 0, TS_SITE_ENDPOINT = 1, TS_SITE_PATH = 2 };

typedef struct ts_feature_site {
    int type;        /* TS_SITE_* */
    int kind;        /* TS_RIDGE or TS_VALLEY: the feature it stands on */
    int degree;      /* arms: branch >= 3, endpoint 1, path 2 */
    double cx, cy;   /* centre, cell coordinates */
    long node, path; /* the node (branch/endpoint) or path it stands on, else -1 */
    int n_ctrl;      /* control points: [0] the centre, then the arms */
    double px[TS_SITE_MAX_ARMS + 1], py[TS_SITE_MAX_ARMS + 1]; /* relative to the centre */
} ts_feature_site;

/*
 * The patch sites of the `kind` features of f (bits TS_RIDGE and/or
 * TS_VALLEY; each site takes the kind of its node or path):
 * control points where the paths cross a circle of `radius` cells; path
 * sites every `path_step` cells.  breadth_first: BFS over each tree from
 * its root (the highest-degree node); otherwise raster order.  *sites is
 * library-allocated (free()).
 */
ts_status ts__feature_sites(ts_ctx *ctx, const ts_features *f, int kind, double radius,
                            double path_step, int breadth_first, ts_feature_site **sites,
                            size_t *n_sites);

/*
 * Alignment of an exemplar site onto a sketch site with `arms` arms: the
 * control point of the exemplar that the sketch's control point i takes
 * (0, the centre, takes 0) in cyclic alignment `rot` (0..arms-1), mirrored
 * (the exemplar's y flipped, so its arms run the other way round) or not.
 * For every rot and mirror, a one-to-one map of the arms.
 */
int ts__feature_arm(int arms, int i, int rot, int mirror);

#endif
