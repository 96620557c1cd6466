/*
 * ppa_internal.h - private helpers shared by the PPA stages: the forest as
 * one byte of neighbour bits per cell.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PPA_INTERNAL_H
#define TS_PPA_INTERNAL_H

#include <math.h>
#include <string.h>

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

/* The number of links of a cell (a table: without -mpopcnt the builtin is
 * a library call). */
static const unsigned char ppa_degree_of[256] = {
    0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    1, 2, 2, 3, 2, 3, 3, 4, 2, 3, 3, 4, 3, 4, 4, 5, 2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    2, 3, 3, 4, 3, 4, 4, 5, 3, 4, 4, 5, 4, 5, 5, 6, 3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7,
    3, 4, 4, 5, 4, 5, 5, 6, 4, 5, 5, 6, 5, 6, 6, 7, 4, 5, 5, 6, 5, 6, 6, 7, 5, 6, 6, 7, 6, 7, 7, 8,
};
static inline int ppa_degree(unsigned char bits)
{
    return ppa_degree_of[bits];
}

/* Length of the step from cell (x, y) in direction d: cells or metres. */
static inline double ppa_step_length(const ts_grid_metrics *m, int y, int d)
{
    int dy = ppa_dir[d][1];
    return ts_step_length(m, dy < 0 ? y - 1 : y, ppa_dir[d][0] != 0, dy != 0);
}

/* Branch lengths are sums of steps in fixed point (1/1024 of a cell or a
 * metre): integer sums do not depend on the order of the steps, so a
 * branch measured in pieces (ppa_tiled.c) has the very length of the same
 * branch walked cell by cell (ppa_branch.c). */
#define PPA_LENGTH_SCALE 1024.0
static inline int64_t ppa_length_q(double len)
{
    return (int64_t)llround(len * PPA_LENGTH_SCALE);
}
static inline int64_t ppa_step_q(const ts_grid_metrics *m, int y, int d)
{
    return ppa_length_q(ppa_step_length(m, y, d));
}

/* Order-preserving map of a segment weight to an unsigned key, inverted so
 * that ascending keys mean descending weights (more important first). */
static inline uint32_t ppa_weight_key(float w)
{
    uint32_t u;
    memcpy(&u, &w, sizeof u);
    u = (u & 0x80000000u) ? ~u : (u | 0x80000000u);
    return ~u;
}

/* Rows [y0, y1) of strip k of n over h rows (strips side by side). */
static inline void ppa_strip_rows(int h, size_t k, int n, int *y0, int *y1)
{
    *y0 = (int)((int64_t)h * (int64_t)k / n);
    *y1 = (int)((int64_t)h * (int64_t)(k + 1) / n);
}

/* Union-find with path halving and union by rank (the spanning forests'). */
static inline uint32_t ppa_uf_find(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) {
        parent[v] = parent[parent[v]];
        v = parent[v];
    }
    return v;
}

/* Join the trees of roots ra != rb. */
static inline void ppa_uf_union(uint32_t *parent, unsigned char *rank, uint32_t ra, uint32_t rb)
{
    if (rank[ra] < rank[rb]) {
        uint32_t t = ra;
        ra = rb;
        rb = t;
    }
    parent[rb] = ra;
    if (rank[ra] == rank[rb])
        rank[ra]++;
}

/* Segment k (ppa_connect_step) from a cell is ppa_dir direction
 * ppa_dir_of_k[k]; the other way round, direction d (0..3) is segment
 * ppa_k_of_dir[d]. */
static const int ppa_dir_of_k[4] = {0, 3, 2, 1};
static const int ppa_k_of_dir[4] = {0, 3, 2, 1};

/* Target connection's segments from a cell: k = 0..3 for E, SW, S, SE
 * (ppa_connect_step); does segment k from target (x, y) exist (neighbour a
 * target, diagonals not over nodata, the crossing rule)?  sign: 1 for
 * ridges, -1 for valleys. */
extern const int ppa_connect_step[4][2];
int ppa_segment_exists(const ts_raster *dem, const unsigned char *t, int kind, int x, int y, int k,
                       float sign);

/* Steps 2 and 3 at once, lean (ppa_polygon.c): the maximum spanning forest
 * of the kind's segments straight into adj (one byte of neighbour bits per
 * cell, zeroed by the caller), without the segments that are the least
 * important of a triangle (never in the forest).  The same forest as
 * ts_ppa_target_connection + ts_ppa_polygon_breaking; DEMs under 2^30
 * cells. */
ts_status ppa_spanning_forest(ts_ctx *ctx, const ts_raster *dem, const unsigned char *targets,
                              int kind, unsigned char *adj);
/* The same in n_strips strips of rows (1..height), side by side: the same
 * forest on any number (ppa_spanning_forest takes one per thread, strips
 * of 64 rows at least). */
ts_status ppa_spanning_forest_strips(ts_ctx *ctx, const ts_raster *dem,
                                     const unsigned char *targets, int kind, unsigned char *adj,
                                     int n_strips);

/* Profile recognition (ppa_profile.c) with a threshold per kind. */
ts_status ppa_profile_targets(ts_ctx *ctx, const ts_raster *dem, int profile_length,
                              double threshold_ridges, double threshold_valleys, int kinds,
                              unsigned char *targets);

/* The drainage area of every valid cell, in cells (NaN on nodata), the flow
 * as drainage_area.c defines it, made in tiles of `tile` cells (the same
 * areas on any tiling): the DEM read window by window (read is called
 * under a lock), each tile's areas handed to emit (under the lock).  keep:
 * hold F, D and the flow of every cell (9 bytes a cell) so that each tile
 * is flooded once and never routed; else (bounded memory) tiles are routed
 * in rounds and once more for the areas. */
typedef void (*ppa_area_fn)(void *user, int x0, int y0, int w, int h, const float *area);
ts_status ppa_drainage(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, ppa_area_fn emit, void *emit_user);
/* The tiles of the flow routing: in one piece, one tile (one flood); in
 * ppa_tiled.c, the PPA's tiles, at most this. */
#ifndef PPA_DRAINAGE_TILE
#define PPA_DRAINAGE_TILE 16384
#endif
/* ... and from this many threads on, tiles of this size in one piece too,
 * their flow kept (4096^2 on one thread: one tile 2.24 s, tiles of 512
 * 2.23 s of work, side by side; both kinds on a 16-core machine,
 * 2026-11-26: tiles from 2 threads on against from 8, 3.57 / 3.64 s on 2
 * threads, 1.92 / 2.99 on 4, 1.18 / 1.40 on 8; tiles of 512 against 1024,
 * 1.40 / 1.34 s on 8 threads, 0.78-0.81 / 0.87 on 16) */
#ifndef PPA_DRAINAGE_TILES_FROM
#define PPA_DRAINAGE_TILES_FROM 4
#endif
#ifndef PPA_DRAINAGE_TILE_THREADS
#define PPA_DRAINAGE_TILE_THREADS 512
#endif
/* The drainage test: *bits (allocated here, a bit a cell, row-major) set on
 * the cells that drain at least min_drainage cells, by ppa_drainage. */
ts_status ppa_channels(ts_ctx *ctx, int width, int height, int tile, int keep,
                       ts_window_read_fn read, void *user, double min_drainage, uint64_t **bits);
static inline int ppa_channel(const uint64_t *bits, size_t c)
{
    return (int)(bits[c >> 6] >> (c & 63) & 1);
}
/* A window of a raster in memory (user: the const ts_raster *). */
ts_status ppa_raster_window(void *dem, int x0, int y0, int w, int h, float *buf);
/* The same of a DEM in memory into area (width x height). */
ts_status ppa_drainage_area(ts_ctx *ctx, const ts_raster *dem, float *area, int tile, int keep);

/* The parameters of one kind, "auto" resolved (ppa.c): valleys with the
 * drainage test (min_drainage > 0) are channels, mapped with a lower dip
 * and shorter branches than ridges (algorithms/docs/ppa.md). */
#define PPA_AUTO_FRACTION 0.0025
#define PPA_AUTO_FRACTION_CHANNELS 0.0001
#define PPA_AUTO_BRANCH 40.0
#define PPA_AUTO_BRANCH_CHANNELS 10.0
double ppa_kind_fraction(const ts_ppa_params *p, int kind);
/* The minimum branch length of the kind; *in_metres = 1 when it is in metres. */
double ppa_kind_branch(const ts_ppa_params *p, int kind, int *in_metres);

/* PPA step 4, branch reduction: remove branches shorter than min_length
 * (in metres when m != NULL, else cells) from the forest `adj`. */
ts_status ppa_branch_reduction(ts_ctx *ctx, int width, int height, unsigned char *adj,
                               const ts_grid_metrics *m, double min_length);

/* Append the nodes and paths of forest `adj` (kind TS_RIDGE/TS_VALLEY) to
 * the graph f, and set the kind's bit in f->mask. */
ts_status ppa_graph_collect(ts_ctx *ctx, const ts_raster *dem, const unsigned char *adj,
                            const ts_grid_metrics *m, int kind, ts_features *f);

#endif
