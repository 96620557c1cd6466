/*
 * ppa_internal.h - private helpers shared by the PPA stages: the forest as
 * one byte of neighbour bits per cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PPA_INTERNAL_H
#define TS_PPA_INTERNAL_H

#include "internal.h"

/* Neighbour directions: bit d of a cell's byte links it to the neighbour at
 * ppa_dir[d].  The opposite direction is (d + 4) & 7. */
static const int ppa_dir[8][2] = {{1, 0},  {1, 1},   {0, 1},  {-1, 1},
                                  {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};

static inline int ppa_dir_of(int dx, int dy)
{
    int d;
    for (d = 0; d < 8; d++)
        if (ppa_dir[d][0] == dx && ppa_dir[d][1] == dy)
            return d;
    return -1;
}

static inline int ppa_degree(unsigned char bits)
{
    return __builtin_popcount(bits);
}

/* Length of the step from cell (x, y) in direction d: cells or metres. */
static inline double ppa_step_length(const ts_grid_metrics *m, int y, int d)
{
    int dy = ppa_dir[d][1];
    return ts_step_length(m, dy < 0 ? y - 1 : y, ppa_dir[d][0] != 0, dy != 0);
}

/* PPA step 4, branch reduction: remove branches shorter than min_length
 * (in metres when m != NULL, else cells) from the forest `adj`. */
ts_status ppa_branch_reduction(ts_ctx *ctx, int width, int height, unsigned char *adj,
                               const ts_grid_metrics *m, double min_length);

/* Append the nodes and paths of forest `adj` (kind TS_RIDGE/TS_VALLEY) to
 * the graph f, and set the kind's bit in f->mask. */
ts_status ppa_graph_collect(ts_ctx *ctx, const ts_raster *dem, const unsigned char *adj,
                            const ts_grid_metrics *m, int kind, ts_features *f);

#endif
