/*
 * terrasynth_drainage.h - the drainage stage every method ends with and the
 * stream network of a DEM (ours, after Lindsay 2016): part of terrasynth.h,
 * which includes it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TERRASYNTH_DRAINAGE_H
#define TERRASYNTH_DRAINAGE_H

#ifndef TERRASYNTH_H
#error "include terrasynth.h"
#endif

/* ------------------------------------------------------------------ */
/* Drainage: closed depressions removed after any method (ours, after  */
/* Lindsay 2016, least-cost breaching)                                  */
/* ------------------------------------------------------------------ */

/** Values of ts_drainage_params.mode. */
enum { TS_DRAINAGE_KEEP = 0, TS_DRAINAGE_BREACH = 1, TS_DRAINAGE_FILL = 2 };
/** The largest radius a pit's search reaches, in cells. */
#define TS_DRAINAGE_RADIUS_MAX 256

/** Parameters of the drainage stage (stage "drainage"). */
typedef struct ts_drainage_params {
    int mode;          /* TS_DRAINAGE_KEEP: as synthesised; _BREACH (default): a channel carved from
                          each pit to lower land; _FILL: each depression raised to its spill */
    int radius;        /* how far from its pit a channel or a fill reaches, in cells */
    double max_depth;  /* breach: the deepest a channel may cut, in height units; a depression
                          that needs a deeper one is kept; 0: no limit; -1 (automatic):
                          bank_slope times radius / 8 (no limit when bank_slope is 0) */
    double bank_slope; /* breach: the slope of a channel's banks, in height units per cell: a
                          cell within (cut / bank_slope) cells (at most radius / 2) of a channel
                          cell cut deeper than bank_slope is lowered to the channel's height
                          plus bank_slope times its distance (a gorge, not a slot); 0: none (a
                          channel one cell wide); -1 (automatic): a front end sets
                          ts_drainage_bank_slope_auto of the exemplars (the core takes -1 as 0) */
    double shallow_depth;     /* breach: the deepest cut from a pit on a TS_CELL_SHALLOW cell,
                                 and of such a cell by any channel, where the channel runs below
                                 the nearest TS_CELL_FIXED cell (within radius / 2 + 2 cells: a
                                 drawn valley's floor; a channel at or above it is a side gully
                                 down to the floor, cut as deep as max_depth allows); a front
                                 end's, not a user's parameter; 0: max_depth */
    double floodplain_relief; /* breach on the whole grid with flags (a front end's, not a
                                 user's parameter; 0: none; ours): after the breach, each basin
                                 it leaves beside a TS_CELL_SHALLOW cell (the band beside a
                                 drawn valley's floor), with no fixed cell not water below its
                                 spill in or beside it (a pin), deeper than this is raised to
                                 a plain graded to its pour point, at most this above its
                                 spill, and the grid is breached again */
    int basin_block;    /* breach on the whole grid (a front end's, not a user's parameter; 0: none;
                           ours): after the breach, the basins it leaves (wider than its reach) are
                           lifted and the grid breached again, twice: the grid's lowest cells over
                           blocks of basin_block cells a side are filled by a priority flood graded
                           basin_grade a block towards the way out, and every cell not fixed is
                           raised by that fill's depth (the first time less half the deepest cut,
                           which the breach then cuts through the rim) taken bilinearly from the
                           blocks' centres and smoothed over a block (the land's shape below a
                           block's scale kept) */
    double basin_grade; /* with basin_block: the fill's rise a block, in height units */
} ts_drainage_params;

TS_API ts_drainage_params ts_drainage_params_default(void);

/** The deepest cut a breach makes with these parameters: max_depth, or for -1 bank_slope times
 *  radius / 8 (0, no limit, when bank_slope is not above 0). */
TS_API double ts_drainage_depth_of(const ts_drainage_params *p);

/** The automatic bank_slope: the median of the exemplars' gradient magnitude (central
 *  differences, height units per cell; at most a million cells sampled in raster order):
 *  a channel's banks as steep as their typical land; 0 when they have no interior cell. */
TS_API double ts_drainage_bank_slope_auto(const ts_raster *exemplars, int n);

/** What the stage did: pits found, pits drained, cells changed and their mean change. */
typedef struct ts_drainage_info {
    size_t pits, resolved, cells_changed;
    double mean_change;
    size_t basins_raised, cells_raised; /* with floodplain_relief: the dammed basins raised */
    size_t cells_lifted;                /* with basin_block: the cells basins lifted raised */
} ts_drainage_info;

/** The margin a window needs on each side (clipped at the grid's edge) for
 *  ts_drainage_apply to give the cells inside it exactly as on the whole
 *  grid: 2 radius + 2, radius / 2 more for a breach with banks, and radius / 2 + 2 more for
 *  a breach with shallow_depth (0 for keep). */
TS_API int ts_drainage_margin(const ts_drainage_params *p);

/**
 * Remove closed depressions from `dem` (changed in place; NaN = nodata), the
 * window [gx0, gx0 + width) x [gy0, gy0 + height) of a gw x gh grid whose
 * edge, like nodata, drains out.  Each pit (a cell lower than its eight
 * neighbours, ties by grid index) is drained on the surface as given:
 * breach lowers the cells of the cheapest path (the sum of heights above the
 * pit) to lower land or out, each a little below the one before, and its
 * banks (bank_slope) to slopes falling to it, never raising a cell (with
 * max_depth, a depression needing a deeper cut is kept); fill raises the
 * cells of the depression to its spill height.  A pit with no way out within radius
 * cells is kept.  `flags` (width x height, row-major, or NULL):
 * TS_CELL_NODATA cells are nodata; TS_CELL_FIXED cells never change and are
 * crossed only as a channel's end (water at or below the pit), and the land
 * beside TS_CELL_WATER is never cut below the water; a channel
 * crosses TS_CELL_BARRIER cells (drawn ridges), or a diagonal between two,
 * only where it has no other way out.  Only cells ts_drainage_margin or more
 * from a side that is not the grid's edge are final: the same bytes as the
 * whole, on any thread count.  `info` may be NULL.
 */
TS_API ts_status ts_drainage_apply(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                                   int64_t gx0, int64_t gy0, int64_t gw, int64_t gh,
                                   const ts_drainage_params *params, ts_drainage_info *info);

/* ------------------------------------------------------------------ */
/* Streams: the flow lines of a DEM, with their Strahler order (ours)  */
/* ------------------------------------------------------------------ */

/** A link of a stream network: from a head or a confluence down to the
 *  next confluence (its last vertex, the first of the link it flows into)
 *  or to where the water leaves the DEM. */
typedef struct ts_stream_link {
    size_t first, count; /* its vertices, upstream to downstream (count >= 2) */
    int order;           /* Strahler order: 1 from a head; i + 1 below where two of order i meet */
    int64_t down;        /* the link it flows into; -1: it leaves the DEM */
    double area;         /* drainage area of its own lowest cell, in cells (itself included) */
} ts_stream_link;

/** The streams of a width x height DEM: links in the raster order of their first cell;
 *  vertices at cell centres (x, y) with the DEM's height z. */
typedef struct ts_stream_network {
    int width, height;
    size_t n_links, n_verts;
    ts_stream_link *links;
    ts_feature_vertex *verts;
} ts_stream_network;

/**
 * The stream network of a DEM: every cell draining at least min_area cells
 * (>= 1; itself included), the flow as the PPA's drainage test defines it
 * (depressions filled to their spill, flats crossed to their way out, each
 * cell to its neighbour of least filled height, the DEM's edge and nodata
 * as outlets), cut into links at confluences.  The DEM is read window by
 * window (read, under a lock; in tiles held 9 bytes a cell); the network
 * (16 bytes a stream cell while it is made) is caller-freed with
 * ts_stream_network_free.  The same network on any thread count.
 */
TS_API ts_status ts_stream_network_extract_read(ts_ctx *ctx, int width, int height,
                                                ts_window_read_fn read, void *user, double min_area,
                                                ts_stream_network **out);
/** The same of a DEM in memory. */
TS_API ts_status ts_stream_network_extract(ts_ctx *ctx, const ts_raster *dem, double min_area,
                                           ts_stream_network **out);
TS_API void ts_stream_network_free(ts_stream_network *net);

#endif /* TERRASYNTH_DRAINAGE_H */
