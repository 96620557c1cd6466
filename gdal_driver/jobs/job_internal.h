/*
 * job_internal.h - what the jobs' files share: the memory each job takes
 * per cell (its estimate before the work), and the helpers of job_common.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_JOB_INTERNAL_H
#define TS_JOB_INTERNAL_H

#include <stdint.h>

#include "tsjob.h"

/* Memory a job takes, estimated before the work (bytes; measured peaks of
 * the CLI with a margin: bench/README.md).  Libraries and buffers: */
#define JOB_MEM_BASE ((uint64_t)96 << 20)
#define JOB_MEM_PPA_CELL 24      /* per input cell: the DEM, profiles, masks, codes */
#define JOB_MEM_PPA_TILE_CELL 48 /* per cell of a tile with its margin (tiled ppa) */
#define JOB_MEM_PPA_STRIP 9      /* per cell of three tile rows: both forests, nodata (tiled ppa) */
#define JOB_MEM_PPA_CHAINS 1     /* per DEM cell: the chains held (76 k at 4096^2: far less) */
#define JOB_MEM_PPA_DRAINAGE                                                                       \
    24 /* per cell of a drainage tile (each thread has one): heights                               \
          and F, D, flow, order, areas (drainage_area.c) */
#define JOB_MEM_PPA_DRAINAGE_BORDER 64 /* per cell of the tiles' borders: heights, F, D, exits */
#define JOB_MEM_SYNTH_CELL 16          /* per output cell: terrain, flags, fill state */
#define JOB_MEM_MAPS_CELL 20           /* per output cell with the synthesis maps */
#define JOB_MEM_SKETCH_CELL                                                                        \
    128                           /* per output cell with a sketch: PPA, features, guides, the     \
                                     slope style's Poisson system (~110 B/cell at its peak) */
#define JOB_MEM_EX_SOURCE_CELL 12 /* per exemplar cell as read */
#define JOB_MEM_EX_CELL                                                                            \
    16                           /* per exemplar cell at the target resolution: it, its pyramid,   \
                                    nodata and feature tables */
#define JOB_MEM_EX_MATCH_CELL 32 /* per exemplar cell at its matching level: FFT spectra, rows */
#define JOB_MEM_TILE_CELL 8      /* per cell of a tile being made: its window, flags, copy */
#define JOB_MEM_TILED_CELL                                                                         \
    16 /* per output cell in tiles with debug maps: every tile's                                   \
          window (at most 4 x its core: tiles of 2 patches) */

/* Several core calls in one job: each reports on [lo, hi] of the job's progress. */
typedef struct job_progress {
    ts_progress_fn fn;
    void *user;
    double lo, hi;
} job_progress;

/* The first warning of a job: cells of a float's extreme value read as nodata. */
void tsjob__warn_sentinels(tsio_err *warning, const char *path, const tsio_raster *r);

/* Cells of an exemplar, as read and resampled to cells of target_area square
 * metres (0: as they are); *ratio (may be NULL) is the one between the two.  An
 * exemplar without CRS has cells of cell_size metres when that is given. */
int tsjob__exemplar_cells(const char *path, double target_area, double cell_size, uint64_t *source,
                          uint64_t *target, double *ratio, tsio_err *err);

/* The ground metrics of a grid (NULL without CRS unless cell_size > 0:
 * then every cell is cell_size metres). */
int tsjob__grid_metrics(const tsio_georef *geo, double cell_size, double **dx, double **dy,
                        tsio_err *err);

/* A raster without a CRS has cells of cell_size metres whatever its
 * geotransform says.  When the job's grid (a sketch, a guide, an input: file
 * `grid`, georeference g as the job read it) and an exemplar both lack a CRS
 * and their geotransforms give cells of different sizes, the user most likely
 * meant those sizes: say what is done instead. */
void tsjob__warn_cell_sizes(tsio_err *warning, double cell_size, const char *grid,
                            const tsio_georef *g, const char *const *exemplars, int n);

/* The target grid of a job (like; size with origin, resolution and CRS, or
 * the first exemplar's), and its ground metrics. */
int tsjob__target_grid(const tsjob_grid *g, const char *first_exemplar, double cell_size,
                       tsio_georef *geo, double **dx, double **dy, tsio_err *err);

/* Refuse an output that is one of the inputs (by identity: a link or
 * another spelling of the path counts too). */
int tsjob__not_an_input(const char *out, const char *const *inputs, int n, tsio_err *err);
/* Refuse a preview name that does not end in .png (case aside). */
int tsjob__preview_name(const char *preview, tsio_err *err);

/* Two outputs of a job must be two files (-d: refused). */
int tsjob__distinct(const char *const *outs, int n, tsio_err *err);

/* A hillshade PNG; with f, its axes drawn over it.  The metrics are the
 * grid's, or for a CRS-less grid its pixel size. */
int tsjob__preview(ts_ctx *ctx, const char *path, const ts_raster *dem, const tsio_georef *geo,
                   const ts_grid_metrics *metrics, const ts_features *f, tsio_err *err);

/* The streams of a job's DEM (flow_lines, with flow_cells or flow_km2):
 * before the work, the file checked (not an input, not one of the job's
 * other outputs, a vector format) and flow_km2 refused without ground
 * metrics; after it, the network of dem written.  metrics NULL: the grid's
 * own (geo's CRS).  Nothing without flow_lines. */
int tsjob__flow_check(const tsjob_outputs *o, const char *const *inputs, int n_in,
                      const char *const *outs, int n_outs, const tsio_georef *geo,
                      const ts_grid_metrics *metrics, tsio_err *err);
int tsjob__flow_write(ts_ctx *ctx, const tsjob_outputs *o, const ts_raster *dem,
                      const tsio_georef *geo, const ts_grid_metrics *metrics, tsio_err *err);

/* Write one int map as Float32 with nodata -1. */
int tsjob__int_map(const char *dir, const char *name, const tsio_georef *geo, const int32_t *v,
                   float *tmp, tsio_err *err);

int tsjob__progress_cb(double done, const char *msg, void *user);

/* The drainage stage on a synth job's whole output (job_synth_drain.c): flags (the
 * constraints' TS_CELL_*, grid-sized) get the sketch's valley floors, ridges and the land
 * beside drawn valleys; the time goes to res->seconds_drainage. */
int tsjob__synth_drain_whole(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                             unsigned char *flags, job_progress *jp, tsio_err *err);

void tsjob__progress_range(ts_ctx *ctx, job_progress *p, double lo, double hi);

/* The bytes a sketch in tiles takes to lay out and amplify, past JOB_MEM_BASE. */
uint64_t tsjob__sketch_tiles_need(const tsjob_synth *job, const tsjob_synth_result *res);
/* Window [x0, x0+w) x [y0, y0+h) grown by m on each side, cut to a W x H grid:
 * win = {x, y, w, h}. */
void tsjob__grow_window(int x0, int y0, int w, int h, int m, int W, int H, int win[4]);

/* A sketch in tiles read from job->coarse_pass into res->sketch_tiles when it was made
 * from this job's inputs (job_synth_coarse.c): 1; 0 when it is missing or was made from
 * others (a warning in res->warning); -1 when it cannot be read or is damaged. */
int tsjob__synth_adopt_coarse(ts_ctx *ctx, const tsjob_synth *job, tsjob_synth_result *res,
                              tsio_err *err);

#endif
