/*
 * patch_merge.h - patch merging (Zhou et al. 2007 section 5), shared by the
 * feature and non-feature placement: write the cells a graph cut gave to a
 * new patch, then remove the seam with a guided Poisson solve.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PATCH_MERGE_H
#define TS_PATCH_MERGE_H

#include "internal.h"

/* Work buffers for P x P windows with their one-cell ring (M = P + 2). */
typedef struct ts_merger {
    int P;
    int band; /* old cells within `band` cells of new ones are smoothed */
    float *merged, *old_m, *new_m, *sgx, *sgy;
    unsigned char *mlabels, *region;
    int *dist;
} ts_merger;

ts_status ts__merger_init(ts_ctx *ctx, ts_merger *m, int P, int band);
void ts__merger_free(ts_merger *m);

/*
 * Merge a patch into `out` at window (wx, wy).  The caller has filled
 * m->new_m ((P+2)^2 floats, ring included, NaN where the patch has no
 * value).  old: the P x P window of `out` before the merge (NaN where
 * empty); labels: P x P, 1 where the cut took the patch.  TS_CELL_NODATA
 * cells are never written; TS_CELL_FIXED cells are never smoothed.  Maps
 * (may be NULL) get ex_index, the cells' source positions src_x/src_y (P x
 * P, may be NULL) and patch_index.
 */
ts_status ts__merger_apply(ts_ctx *ctx, ts_merger *m, ts_raster *out, const unsigned char *flags,
                           int wx, int wy, const float *old, const unsigned char *labels,
                           ts_synth_maps *maps, int ex_index, const int32_t *src_x,
                           const int32_t *src_y, int patch_index);

/* The height-constraint costs c_i of a P x P candidate window at (wx, wy)
 * of an output `width` cells wide: alpha_h * RMS(patch - heights) plus
 * alpha_r * RMS(patch - guide), each over the cells where both have a
 * value; 0 without constraints. */
double ts__height_cost(const ts__fill *p, int width, int wx, int wy, int P, const float *patch,
                       int stride);

/* Two-pass chamfer distance (Chebyshev) on a P x P grid, in place: cells
 * start at 0 (sources) or a large value. */
void ts__chamfer_chebyshev(int *d, int P);

/* Does window cell (x, y) of the P x P window at (wx, wy) lie on the
 * window's border next to a filled cell outside it?  Such a cell keeps its
 * old value in the graph cut, so every seam lies inside the window where it
 * is costed. */
int ts__border_keeps_old(const ts_raster *out, int wx, int wy, int P, int x, int y);

/* Number of 4-adjacent label changes inside a P x P window. */
int ts__label_cut_edges(const unsigned char *labels, int P);

#endif
