/*
 * terrasynth.h - public interface of libterrasynth, the TerraSynth core.
 *
 * Copyright (C) 2026 The TerraSynth developers
 * SPDX-License-Identifier: GPL-2.0-or-later
 *
 * The core is a plain C11 library: no file I/O, no printing, no globals.
 * Rasters are float views in which NaN means nodata.  Every fallible call
 * takes a ts_ctx (errors, progress/cancel, seed, threads) as its first
 * argument and returns a ts_status; the detailed message is
 * ts_ctx_message(ctx), prefixed with the stage name.
 *
 * Ownership is stated on every pointer: "borrowed" means the callee neither
 * keeps nor frees it; "caller frees with X" means the caller owns the result.
 */
#ifndef TERRASYNTH_H
#define TERRASYNTH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#if defined(TS_BUILDING_LIBRARY) && defined(__GNUC__)
#define TS_API __attribute__((visibility("default")))
#else
#define TS_API
#endif

/** Version string "MAJOR.MINOR.PATCH" (static storage): the project's
 *  version, set once in CMakeLists.txt. */
TS_API const char *ts_version(void);
/** The checksum the core's file formats end with (FNV-1a, 64 bits), of n
 *  bytes, chained: start from 0, pass the last sum for the next bytes. */
TS_API uint64_t ts_checksum(uint64_t sum, const void *bytes, size_t n);

/* ------------------------------------------------------------------ */
/* Status and context                                                 */
/* ------------------------------------------------------------------ */

typedef enum ts_status {
    TS_OK = 0,
    TS_ERR_NOMEM,     /* allocation failed */
    TS_ERR_ARG,       /* invalid argument or parameter */
    TS_ERR_SIZE,      /* raster too small / too large / empty */
    TS_ERR_CANCELLED, /* the progress callback asked to stop */
    TS_ERR_NUMERIC,   /* a solver failed, or the data are unusable (e.g. all nodata) */
    TS_ERR_INTERNAL   /* a bug: please report */
} ts_status;

/** Fixed English text for a status code (static storage). */
TS_API const char *ts_status_str(ts_status status);

/**
 * Progress callback, the shape of GDALProgressFunc.  `done` runs from 0 to
 * 1 over the whole call; `msg` may be NULL.  Return 0 to cancel: the running
 * call then returns TS_ERR_CANCELLED as soon as it can.
 */
typedef int (*ts_progress_fn)(double done, const char *msg, void *user);

/** Opaque per-thread context.  Never share one between threads. */
typedef struct ts_ctx ts_ctx;

/** New context (caller frees with ts_ctx_free); NULL if out of memory.
 *  Defaults: seed 0, threads 0 (= all online processors), no progress. */
TS_API ts_ctx *ts_ctx_new(void);
TS_API void ts_ctx_free(ts_ctx *ctx);

/** Progress callback and its user pointer (borrowed; may be NULL). */
TS_API void ts_ctx_set_progress(ts_ctx *ctx, ts_progress_fn fn, void *user);
/** The callback and user data set by ts_ctx_set_progress (to chain calls:
 *  a front end maps each call onto part of its own progress). */
TS_API void ts_ctx_get_progress(const ts_ctx *ctx, ts_progress_fn *fn, void **user);
/** A note for the user while a call works (a long stage ahead and what would
 *  shorten it); stage and msg are borrowed for the call.  Called on the
 *  caller's thread; never changes a result. */
typedef void (*ts_notice_fn)(const char *stage, const char *msg, void *user);
/** Notice callback and its user pointer (borrowed; may be NULL: no notices). */
TS_API void ts_ctx_set_notice(ts_ctx *ctx, ts_notice_fn fn, void *user);
TS_API void ts_ctx_set_seed(ts_ctx *ctx, uint64_t seed);
TS_API uint64_t ts_ctx_seed(const ts_ctx *ctx);
/** Worker threads; 0 = all online processors.  Results never depend on it. */
TS_API void ts_ctx_set_threads(ts_ctx *ctx, int threads);
TS_API int ts_ctx_threads(const ts_ctx *ctx);
/** Status and message of the last failed call (message: borrowed, valid
 *  until the next call on ctx; "" when the last call succeeded). */
TS_API ts_status ts_ctx_status(const ts_ctx *ctx);
TS_API const char *ts_ctx_message(const ts_ctx *ctx);
/** The input the last failure is about, when it is one: the 0-based index
 *  of an exemplar (in the array the failing call was given); -1 otherwise. */
TS_API int ts_ctx_failed_input(const ts_ctx *ctx);

/* ------------------------------------------------------------------ */
/* Rasters                                                            */
/* ------------------------------------------------------------------ */

/**
 * A float raster view.  `stride` is in elements (>= width).  NaN = nodata.
 * A view never owns `data` unless it came from ts_raster_alloc.
 */
typedef struct ts_raster {
    int width, height;
    ptrdiff_t stride;
    float *data;
} ts_raster;

#define TS_PIX(r, x, y) ((r)->data[(ptrdiff_t)(y) * (r)->stride + (x)])

/** Wrap caller memory (borrowed: the view does not own data). */
TS_API ts_raster ts_raster_wrap(float *data, int width, int height, ptrdiff_t stride);
/** Allocate a width x height raster filled with NaN; caller frees with
 *  ts_raster_free.  Returns TS_ERR_SIZE for non-positive or huge sizes. */
TS_API ts_status ts_raster_alloc(ts_ctx *ctx, int width, int height, ts_raster *out);
/** Free a raster from ts_raster_alloc and zero the view (NULL-safe). */
TS_API void ts_raster_free(ts_raster *r);

/** Statistics over the valid (non-NaN) cells.  Returns TS_ERR_NUMERIC when
 *  every cell is nodata. */
typedef struct ts_raster_stats {
    size_t n_valid, n_nodata;
    double min, max, mean, stddev;
} ts_raster_stats;
TS_API ts_status ts_raster_stats_compute(ts_ctx *ctx, const ts_raster *r, ts_raster_stats *out);

/**
 * Ground metrics of a grid: the width (dx) and height (dy) of a cell of
 * row y, in metres.  Per row, because geographic grids narrow towards the
 * poles.  Both arrays have `height` entries (borrowed).  Passing NULL
 * metrics to a stage means "cell units": every cell is 1 x 1.
 */
typedef struct ts_grid_metrics {
    const double *dx;
    const double *dy;
} ts_grid_metrics;

/* ------------------------------------------------------------------ */
/* Parameters: declared once, used by every front end                 */
/* ------------------------------------------------------------------ */

typedef enum ts_param_type {
    TS_PARAM_INT,    /* int */
    TS_PARAM_DOUBLE, /* double */
    TS_PARAM_ENUM,   /* int; value is the index into `choices` */
    TS_PARAM_LENGTH  /* ts_length: a number with unit cells or metres */
} ts_param_type;

typedef enum ts_length_unit { TS_UNIT_CELLS = 0, TS_UNIT_METRES = 1 } ts_length_unit;

/** A length that the user may give in cells ("12") or metres ("600m"). */
typedef struct ts_length {
    double value;
    ts_length_unit unit;
} ts_length;

/** One parameter of a stage.  All strings are static. */
typedef struct ts_param_desc {
    const char *name;    /* snake_case; CLI flag is --name-with-dashes */
    ts_param_type type;
    double def;          /* default (enum: index; length: value in def_unit) */
    double min, max;     /* inclusive range */
    ts_length_unit def_unit; /* TS_PARAM_LENGTH only */
    const char *units;   /* "cells", "m", "elevation units", "" */
    const char *choices; /* TS_PARAM_ENUM: "a|b|c"; NULL otherwise */
    const char *help;    /* one sentence */
    size_t offset;       /* offset of the field in the stage's params struct */
} ts_param_desc;

/** Descriptor table of a stage ("ppa", ...); NULL and *n = 0 if unknown.
 *  The table is static. */
TS_API const ts_param_desc *ts_params_describe(const char *stage, size_t *n);
/** Names of all stages with descriptor tables, NULL-terminated (static). */
TS_API const char *const *ts_params_stages(void);
/** Parse `value` and store it into the params struct of `stage`
 *  (borrowed).  Range-checked: TS_ERR_ARG with a message naming the
 *  parameter for unknown names, bad syntax or out-of-range values. */
TS_API ts_status ts_params_set(ts_ctx *ctx, const char *stage, void *params,
                               const char *name, const char *value);
/** Format the current value of a parameter into buf (for recipes, help). */
TS_API ts_status ts_params_get(ts_ctx *ctx, const char *stage, const void *params,
                               const char *name, char *buf, size_t buflen);
/** Check every parameter of `params` against its range. */
TS_API ts_status ts_params_validate(ts_ctx *ctx, const char *stage, const void *params);

/* ------------------------------------------------------------------ */
/* PPA: ridge and valley axes (Chang, Song & Hsu 1998; Zhou et al.    */
/* 2007 section 3)                                                    */
/* ------------------------------------------------------------------ */

/** Feature kinds; also the bits of ts_features.mask. */
enum { TS_RIDGE = 1, TS_VALLEY = 2 };
/** Values of ts_ppa_params.features. */
enum { TS_PPA_RIDGES = 0, TS_PPA_VALLEYS = 1, TS_PPA_BOTH = 2 };

typedef struct ts_ppa_params {
    int features;            /* TS_PPA_RIDGES, TS_PPA_VALLEYS or TS_PPA_BOTH */
    int profile_length;      /* cells, odd, >= 3: the profile spans +-(n-1)/2 cells */
    double threshold;        /* elevation units: the dip on each side must exceed */
    double threshold_fraction; /* ... and this fraction of the elevation range */
    ts_length min_branch_length; /* branches shorter than this are removed */
    double min_drainage;         /* cells: valley targets draining fewer are dropped (0: none) */
} ts_ppa_params;

/** Defaults that work on mountains, canyons, hills and volcanoes. */
TS_API ts_ppa_params ts_ppa_params_default(void);

/** A node of the feature graph: an endpoint (degree 1) or a branch
 *  point (degree >= 3).  x, y are the cell's column and row. */
typedef struct ts_feature_node {
    int x, y;
    float z;
    int degree;
    int kind; /* TS_RIDGE or TS_VALLEY */
} ts_feature_node;

typedef struct ts_feature_vertex {
    int x, y;
    float z;
} ts_feature_vertex;

/** A path: the chain of cells between two nodes (both included). */
typedef struct ts_feature_path {
    int kind;            /* TS_RIDGE or TS_VALLEY */
    size_t node_a, node_b; /* indices into nodes */
    size_t first, count; /* vertices verts[first .. first+count-1] */
    double length;       /* metres with metrics, else cells */
    float zmin, zmax, zmean;
} ts_feature_path;

/**
 * The PPA result: a forest.  Library-allocated; caller frees with
 * ts_features_free.  mask has width*height bytes (row-major, stride width):
 * bit TS_RIDGE and/or bit TS_VALLEY set on feature cells, 0 elsewhere.
 */
typedef struct ts_features {
    int width, height;
    unsigned char *mask;
    size_t n_nodes, n_paths, n_verts;
    ts_feature_node *nodes;
    ts_feature_path *paths;
    ts_feature_vertex *verts;
    double threshold_used;   /* effective profile threshold, elevation units (the ridges', or
                                the valleys' when only valleys are mapped) */
    double threshold_used_valleys; /* the valleys' (a lower one for channels: min_drainage) */
} ts_features;

TS_API void ts_features_free(ts_features *f);

/** The feature raster a GIS writes: codes (caller-allocated, width*height
 *  bytes) = the mask bits (1 ridge, 2 valley, 3 both, 0 none), 255 where
 *  `dem` (borrowed, same size) is nodata. */
TS_API ts_status ts_features_codes(ts_ctx *ctx, const ts_features *f, const ts_raster *dem,
                                   unsigned char *codes);

/**
 * Extract ridge and/or valley axes from `dem` (borrowed; NaN = nodata).
 * `metrics` may be NULL (cell units).  On success *out is a new feature
 * graph (caller frees with ts_features_free).  Returns TS_ERR_ARG for bad
 * parameters, TS_ERR_SIZE when the DEM is smaller than 2 x 2,
 * TS_ERR_NUMERIC when every cell is nodata, TS_ERR_CANCELLED, TS_ERR_NOMEM.
 */
TS_API ts_status ts_ppa_extract(ts_ctx *ctx, const ts_raster *dem,
                                const ts_grid_metrics *metrics,
                                const ts_ppa_params *params, ts_features **out);

/** Fill `buf` (w x h floats, row-major; NaN = nodata) with the DEM window
 *  at column x0, row y0.  Returns TS_OK, or an error (after setting it on
 *  the context, or not: the caller then reports a read error). */
typedef ts_status (*ts_window_read_fn)(void *user, int x0, int y0, int w, int h, float *buf);
/** Take the finished window at (x0, y0): w x h bytes, row-major. */
typedef ts_status (*ts_window_write_fn)(void *user, int x0, int y0, int w, int h,
                                        const unsigned char *bytes);

/**
 * ts_ppa_extract for a DEM too large for memory: the DEM (width x height)
 * is read through `read` in windows of tile_size cells (16..16384) plus a
 * margin, three times, and the axes are handed to `write` tile by tile, as
 * the codes of ts_features_codes; no feature graph.  The codes are those
 * of ts_ppa_extract on the whole DEM.  Held for the whole raster: the
 * border-contracted forests (small) and the chain graph of the forest
 * before branch reduction (about a quarter of a chain per cell per kind).
 * min_drainage (valleys) needs the whole DEM: TS_ERR_ARG.
 */
/* The tile sizes ts_ppa_extract_tiled takes (cells). */
#define TS_PPA_TILE_MIN 16
#define TS_PPA_TILE_MAX 16384
typedef struct ts_ppa_tiled_stats {
    int passes_in_tiles; /* branch reduction passes run inside the tiles (0..3) */
    size_t chains_held;  /* chains of the whole held for the rest of the reduction */
} ts_ppa_tiled_stats;
TS_API ts_status ts_ppa_extract_tiled(ts_ctx *ctx, int width, int height,
                                      const ts_grid_metrics *metrics, const ts_ppa_params *params,
                                      int tile_size, ts_window_read_fn read,
                                      ts_window_write_fn write, void *user,
                                      ts_ppa_tiled_stats *stats);

/* The PPA stages, exposed for tests and for callers that want the
 * intermediate results.  Masks are width*height bytes, stride width. */

/** Profile recognition: set bit `kinds` (TS_RIDGE|TS_VALLEY) on targets.
 *  `targets` is caller-allocated and fully overwritten. */
TS_API ts_status ts_ppa_profile_recognition(ts_ctx *ctx, const ts_raster *dem,
                                            int profile_length, double threshold,
                                            int kinds, unsigned char *targets);

/** A segment between two 8-adjacent target cells a < b (row-major index). */
typedef struct ts_ppa_segment {
    uint32_t a, b;
    float weight; /* importance: z(a) + z(b) (negated heights for valleys) */
} ts_ppa_segment;

/** Target connection for one kind: all 8-adjacent target pairs, dropping
 *  the lower of two crossing diagonals.  *segs is library-allocated
 *  (caller frees with free()).  Segments are returned in a fixed order. */
TS_API ts_status ts_ppa_target_connection(ts_ctx *ctx, const ts_raster *dem,
                                          const unsigned char *targets, int kind,
                                          ts_ppa_segment **segs, size_t *n_segs);

/** Polygon breaking as a maximum spanning forest (Kruskal + union-find).
 *  Segments are ordered by weight, ties broken by lower index first kept.
 *  keep[i] is set to 1 for kept segments, 0 otherwise (caller-allocated,
 *  n_segs entries).  n_cells bounds the vertex ids. */
TS_API ts_status ts_ppa_polygon_breaking(ts_ctx *ctx, const ts_ppa_segment *segs,
                                         size_t n_segs, size_t n_cells,
                                         unsigned char *keep);

/* ------------------------------------------------------------------ */
/* Patch machinery (Zhou et al. 2007 section 4.2, section 5, App. A-B)*/
/* ------------------------------------------------------------------ */

/** Masked SSD matcher (FFT), planned once per exemplar and patch size. */
typedef struct ts_matcher ts_matcher;

/** A candidate exemplar position (top-left corner of the window). */
typedef struct ts_candidate {
    int x, y;
    double ssd;
} ts_candidate;

/**
 * Plan FFT-accelerated masked SSD matching of patch_w x patch_h windows
 * against every position of `exemplar` (borrowed: it must outlive the
 * matcher and not change).  Caller frees with ts_matcher_free.
 * TS_ERR_SIZE when the exemplar is smaller than a patch; TS_ERR_NUMERIC
 * when no window of the exemplar is free of nodata.
 */
TS_API ts_status ts_matcher_new(ts_ctx *ctx, const ts_raster *exemplar, int patch_w, int patch_h,
                                ts_matcher **out);
TS_API void ts_matcher_free(ts_matcher *m);
/** Number of window positions: (ex_w - patch_w + 1) x (ex_h - patch_h + 1). */
TS_API void ts_matcher_positions(const ts_matcher *m, int *nx, int *ny);
/**
 * SSD map: out (caller-allocated, nx*ny floats, row-major) gets, for every
 * position (x, y), the sum over the known cells of `target` (patch_w x
 * patch_h; NaN = unknown) of (target(i,j) - exemplar(x+i, y+j))^2, computed
 * by FFT in O(n log n); +INFINITY where the exemplar window contains any
 * nodata.  Accuracy: relative error ~1e-5 of the SSD scale (float FFT);
 * use ts_matcher_best for exact values.
 */
TS_API ts_status ts_matcher_ssd(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, float *out);
/**
 * The k best positions (lowest SSD), exact SSD recomputed in double,
 * ascending (ties: lower y, then lower x), pairwise at least min_separation
 * cells apart (Chebyshev distance; 0 or 1 = any).  out: caller-allocated, k
 * entries; *n_found <= k.  A target with no known cell matches everywhere
 * with SSD 0.
 */
TS_API ts_status ts_matcher_best(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, int k,
                                 int min_separation, ts_candidate *out, int *n_found);

/** Per-cell constraints for the seam finder. */
enum { TS_SEAM_FREE = 0, TS_SEAM_OLD = 1, TS_SEAM_NEW = 2 };

/**
 * Graph-cut seam (Kwatra et al. 2003; Zhou et al. 2007 App. A) between the
 * output's current content `old` and a new `patch` over one window (both
 * the same size, borrowed).  Edge weight between 4-adjacent cells s, t of
 * the overlap is M = |a(s)-b(s)| + |a(t)-b(t)| (eq. 1).  Cells where old is
 * NaN must take the patch; cells where the patch is NaN must keep old;
 * `constraint` (may be NULL; w*h bytes) forces TS_SEAM_OLD / TS_SEAM_NEW
 * cells (infinite terminal weights).  The overlap may touch several earlier
 * patches and be disjoint.  labels (caller-allocated, w*h): 0 keep old,
 * 1 take the patch.  *cost = c_g, the summed M of the cut (eq. 2).
 * TS_ERR_ARG when constraints contradict (a cell forced both ways).
 */
TS_API ts_status ts_seam_graphcut(ts_ctx *ctx, const ts_raster *old, const ts_raster *patch,
                                  const unsigned char *constraint, unsigned char *labels,
                                  double *cost);

/**
 * Discrete Poisson solve with Dirichlet boundary: for every cell p with
 * mask[p] != 0, sum over its 4-neighbours q inside the grid of
 * (u_p - u_q) = sum of the guidance differences (g(p) - g(q)) where the
 * guidance difference to the right neighbour is gx[p] (desired
 * u(x+1,y) - u(x,y)) and to the neighbour below gy[p].  Cells with mask 0
 * keep their value in u and act as boundary.  Neighbours outside the grid
 * are left out (natural boundary).  u: w*h floats, in (initial guess /
 * boundary values) and out; gx, gy: w*h floats (last column of gx and last
 * row of gy unused).  Solved by preconditioned conjugate gradients to a
 * relative residual of `tolerance` (e.g. 1e-6) in at most max_iter
 * iterations; TS_ERR_NUMERIC if it does not converge.
 */
TS_API ts_status ts_poisson_solve(ts_ctx *ctx, int w, int h, const unsigned char *mask,
                                  const float *gx, const float *gy, float *u, double tolerance,
                                  int max_iter);

/**
 * Poisson seam removal (Zhou et al. 2007 App. B): in `merged` (w x h,
 * borrowed, modified in place), the gradients of the merged field inside
 * `region` (mask, w*h) are kept except across the seam, where `labels`
 * (w*h, 0 old / 1 new) changes, which are set to zero; the field inside the
 * region is then re-solved with Dirichlet boundary values from outside the
 * region.  NaN cells are never part of the region.
 */
TS_API ts_status ts_poisson_seam_remove(ts_ctx *ctx, ts_raster *merged,
                                        const unsigned char *labels,
                                        const unsigned char *region);

/**
 * As ts_poisson_seam_remove, but across the seam the wanted difference is
 * seam_gx[p] (to the right neighbour) / seam_gy[p] (to the one below),
 * w*h floats each (with the merged raster's width as stride), instead of
 * zero; NaN entries mean zero.  Passing the mean of the two sources'
 * gradients there keeps the terrain's slope across the seam while removing
 * the height step, where zero would flatten the slope along every seam.
 */
TS_API ts_status ts_poisson_seam_remove_guided(ts_ctx *ctx, ts_raster *merged,
                                               const unsigned char *labels,
                                               const unsigned char *region,
                                               const float *seam_gx, const float *seam_gy);

/* ------------------------------------------------------------------ */
/* Non-feature patch synthesis (Zhou et al. 2007 section 4.2)         */
/* ------------------------------------------------------------------ */

/** Values of ts_synth_params.order: grow out from what is filled (with a
 *  sketch: its feature tree breadth first, then grow), raster scan, or
 *  tree (the same as grow; the name the sketch-guided synthesis uses). */
enum { TS_ORDER_GROW = 0, TS_ORDER_RASTER = 1, TS_ORDER_TREE = 2 };

typedef struct ts_synth_params {
    ts_length patch_size; /* side of the square patches: cells (metres must be
                             turned into cells first: ts_synth_params_resolve) */
    ts_length overlap;    /* shared by neighbouring patch positions, likewise */
    int candidates;    /* k best SSD matches examined per position */
    int order;         /* TS_ORDER_GROW or TS_ORDER_RASTER */
    double alpha_g;    /* weight of the graph-cut seam cost against the SSD */
    double variety;    /* pick at random among candidates within (1+variety) of the best */
    int coarse_factor; /* match on exemplars downsampled by this factor, refine at full
                          resolution (1 = exhaustive full-resolution search, 0 = automatic) */
    int tiled;         /* free synthesis in tiles of this many cells, four waves
                          (ts_synth_tiled); 0 = in one piece */
    double usage;      /* weight of the exemplar usage cost: windows used more than the
                          average cost more, so the fill does not keep to the windows
                          that match easily (smooth ones) nor copy the exemplar's
                          layout; 0 = off, -1 = automatic (TS_SYNTH_USAGE_FREE for
                          free synthesis, 0 with a sketch) */
} ts_synth_params;

/** The usage weight of free synthesis when ts_synth_params.usage is -1. */
#define TS_SYNTH_USAGE_FREE 32.0

TS_API ts_synth_params ts_synth_params_default(void);

/**
 * Turn patch_size and overlap given in metres into whole cells of a grid
 * whose cells are `cell_m` metres on the ground (<= 0: the grid has no
 * ground size, and metres are an error), then check them: patch_size
 * 8..1024 cells, overlap 2..512 and at most half the patch.  The synthesis
 * calls need cells.
 */
TS_API ts_status ts_synth_params_resolve(ts_ctx *ctx, ts_synth_params *params, double cell_m);

/**
 * Optional per-cell records of a synthesis (each array caller-allocated,
 * width*height entries of the output, or NULL if not wanted).
 */
typedef struct ts_synth_maps {
    int32_t *source_exemplar; /* index of the exemplar a cell came from, -1 if none */
    int32_t *source_x, *source_y; /* its position in that exemplar */
    int32_t *order;           /* index of the placed patch the cell came from, -1 if none */
    unsigned char *seams;     /* 1 on cells next to a graph-cut seam */
    unsigned char *valley_floor; /* sketches: 1 on the floors the drawn valleys were carved
                                    along (0 on entry) */
    /* added to by the call: patches placed (also the index the next patch
     * gets in `order`) and seconds spent per stage (match, cut and Poisson
     * summed over placements that run side by side, so together they can
     * exceed the wall time) */
    int n_patches;
    double seconds_prepare, seconds_match, seconds_cut, seconds_poisson;
} ts_synth_maps;

/** Bits of ts_synth_constraints.cell_flags. */
enum {
    TS_CELL_NODATA = 1,
    TS_CELL_FIXED = 2,
    /* with TS_CELL_FIXED: water; the land beside it ends at or above its value
       (water_banks.c, a TerraSynth addition) */
    TS_CELL_WATER = 8,
    /* for the drainage stage: a drawn ridge, which a channel crosses only where the land
       has no other way out */
    TS_CELL_BARRIER = 16,
    /* for the drainage stage: beside a drawn valley's floor, a pit here lower than the
       floor is cut at most ts_drainage_params.shallow_depth deep, and no channel below the
       floor cuts the cell deeper */
    TS_CELL_SHALLOW = 32
};

/**
 * What the user asks of the output, beyond the exemplars' style: the same
 * for both synthesis calls.  Every array is borrowed, width*height of the
 * output, row-major, and may be NULL.
 */
typedef struct ts_synth_constraints {
    /* TS_CELL_NODATA cells stay NaN; TS_CELL_FIXED cells (filled in `out`
     * on entry: pinned windows, water) never change; those also flagged
     * TS_CELL_WATER are water, and the free land touching them ends at or
     * above their value */
    const unsigned char *cell_flags;
    /* Several styles in one terrain (Zhou et al. section 6.1): the index of
     * the exemplar each cell's region takes, or -1 for any.  A patch takes
     * the exemplar of its window's centre cell; graph cuts and Poisson
     * seam removal make the transitions. */
    const int32_t *cell_exemplar;
    /* User height constraints (Zhou et al. c_i): wanted elevations (NaN =
     * none); each candidate's cost gains alpha_h * RMS(patch - heights)
     * over the constrained cells of its window. */
    const float *heights;
    double alpha_h;
    /* The TS_CELL_FIXED cells' values for a call with no output filled on
     * entry (ts_sketch_tiles_new); NULL: none there */
    const float *values;
} ts_synth_constraints;

/** No constraints (alpha_h 1, every array NULL). */
TS_API ts_synth_constraints ts_synth_constraints_default(void);

/**
 * Fill the NaN cells of `out` (caller-allocated, borrowed) with patches of
 * the exemplars (borrowed array of n_exemplars rasters at the output's
 * ground resolution): positions on a grid of step patch_size - overlap,
 * visited in descending order of overlap with what is filled (grow) or in
 * scan order (raster); k candidates by masked SSD (FFT); the winner by
 * SSD + alpha_g * graph-cut cost; merged by graph cut and Poisson seam
 * removal.  Cells of `out` that are not NaN on entry are matched against
 * and may be replaced by the graph cut or smoothed by the seam remover
 * (within `overlap` cells of new content), unless fixed (`constraints`,
 * may be NULL).
 * The seed of ctx picks the first patch and breaks near-ties.
 * Returns TS_ERR_SIZE when an exemplar or the output is smaller than a
 * patch, TS_ERR_ARG for bad parameters, TS_ERR_CANCELLED, TS_ERR_NOMEM.
 */
TS_API ts_status ts_synth_patches(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                  const ts_synth_params *params,
                                  const ts_synth_constraints *constraints, ts_raster *out,
                                  ts_synth_maps *maps);

/**
 * Free synthesis of `out` (NaN on entry but its fixed cells) in tiles of `tile` cells
 * (tiled_synthesis.c): tile (i, j) in wave (i & 1) + 2 (j & 1), made over
 * its core grown by a patch with its earlier-wave neighbours' cores fixed
 * and their margins as terrain to cut against; the output is the union of
 * the cores.  Tiles of a wave run in parallel;
 * the result depends on the seed and the parameters only, not on the
 * thread count.  constraints (may be NULL) are the whole grid's, as for
 * ts_synth_patches: each tile takes its window's part (pinned and water
 * cells fixed with their values in `out`, nodata, regions, heights).
 * tile: 2 x the patch .. 16384.  params->tiled is not read.
 * ts_synth_patches calls this when params->tiled > 0.
 */
TS_API ts_status ts_synth_tiled(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params,
                                const ts_synth_constraints *constraints, int tile, ts_raster *out);

/** The wave of tile (ti, tj) in ts_synth_tiled: (ti & 1) + 2 (tj & 1). */
TS_API int ts_synth_tile_wave(int ti, int tj);

/** The odd rows of tiles in each band of ts_synth_tiled without debug maps
 * (B: a step holds threads x max(1, 2048 / tile) tiles at least), for a grid
 * `width` cells wide; 2 B + 1 rows of tiles' windows are alive at once. */
TS_API int ts_synth_tiled_band(int threads, int width, int tile);

/** The pyramid level K (a factor of 2^K) a w x h exemplar's patches of
 *  `patch` cells are matched on: coarse_factor rounded down to a power of
 *  two, or (0, automatic) the smallest that brings the exemplar to at most
 *  512 x 512 cells keeping 8 coarse cells a patch; at most 4.  The placement's
 *  rule, for a front end's memory estimate too. */
TS_API int ts_synth_match_level(int coarse_factor, int patch, int w, int h);

/** One tile of a tiled synthesis, made on its own (ts_synth_tiles). */
typedef struct ts_synth_tile {
    int ti, tj; /* tile (ti, tj): its core is columns [ti T, ti T + T), rows [tj T, tj T + T) */
    /* neighbours[(dj + 1) * 3 + di + 1]: the window of tile (ti + di, tj + dj),
     * needed (and only read) where that tile exists and is of an earlier wave */
    const ts_raster *neighbours[9];
    ts_raster window; /* written: the tile's window (ts_synth_tile_window) */
    /* what the user asks of the tile's window, or NULL: as ts_synth_constraints
     * but every array window-sized (the whole grid's arrays cut to the window),
     * the fixed cells' values in `window` on entry; the result is then the
     * same as ts_synth_tiled's with the whole grid's constraints */
    const ts_synth_constraints *constraints;
} ts_synth_tile;

/**
 * Where tile (ti, tj) of a width x height grid in tiles of `tile` cells
 * lies: window = {x, y, w, h} of the cells its synthesis makes (its core
 * grown by the patch size, clipped to the grid), core = {x, y, w, h} of
 * the cells it gives the output (either may be NULL).
 */
TS_API ts_status ts_synth_tile_window(ts_ctx *ctx, const ts_synth_params *params, int tile,
                                      int width, int height, int ti, int tj, int window[4],
                                      int core[4]);

/**
 * The tiles of ts_synth_tiled one by one: each given tile's window, made
 * from its earlier-wave neighbours' windows exactly as in the whole run
 * (the same bytes; the output is the union of the cores), for a width x
 * height grid in tiles of `tile` cells; the context's seed is the whole
 * run's.  The tiles of one call run in parallel, so no two of them may be
 * neighbours of different waves (TS_ERR_ARG).  Lets a front end make any
 * window of a tiled terrain from the tiles under it and the tiles those
 * need (the GDAL driver, the Dask runner).
 */
TS_API ts_status ts_synth_tiles(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                const ts_synth_params *params, int tile, int width, int height,
                                ts_synth_tile *tiles, int n_tiles);

/* ------------------------------------------------------------------ */
/* Sketch-guided synthesis (Zhou et al. 2007 sections 3-4)            */
/* ------------------------------------------------------------------ */

/** Values of ts_sketch_params.mode. */
enum { TS_SKETCH_RIDGES = 0, TS_SKETCH_VALLEYS = 1, TS_SKETCH_AUTO = 2, TS_SKETCH_BOTH = 3 };

typedef struct ts_sketch_params {
    int mode;        /* ridges (bright strokes), valleys (dark strokes), both (brighter and
                        darker than a grey ground), auto */
    double alpha_d;  /* weight of the warp's deformation cost c_d */
    double alpha_f;  /* weight of the feature profile dissimilarity c_f */
    double alpha_s;  /* weight of the path smoothness constraint c_s */
    double alpha_p;  /* weight of the crest prominence c_p (sketched strokes read as main features) */
    double alpha_r;  /* weight of the relief guide (sketched ridges stand high) */
    double layout;   /* 0..1: how far the sketch sets the relief above a third of a patch */
    double slope_style; /* 0..1: how far the output's slopes take the exemplars' distribution */
    double crest_relief; /* 0..1: how far drawn crests take the exemplars' peaks and saddles */
    int amplify_factor;  /* in tiles (ts_synth_params.tiled > 0): the sketch laid out this many
                            times coarser, then amplified back; 0 = automatic */
} ts_sketch_params;

TS_API ts_sketch_params ts_sketch_params_default(void);

/** The factor a sketch in tiles is laid out coarser by (amplify_factor, or
 *  its automatic value for patches of `patch` cells on a width x height
 *  grid). */
TS_API int ts_sketch_amplify_factor(const ts_sketch_params *sp, int patch, int width, int height);


/** What a sketch-guided synthesis did (all filled in by the call). */
typedef struct ts_sketch_info {
    int mode;                /* TS_SKETCH_RIDGES, _VALLEYS or _BOTH, as used */
    size_t n_sites;          /* feature patch sites in the sketch */
    size_t n_feature_patches;/* of which placed */
    size_t n_exemplar_sites; /* candidate feature patches found in the exemplars */
    /* wall seconds: PPA on the sketch, PPA (and relief profiles) on the
     * exemplars, feature patch placement, the non-feature fill, the layout,
     * the slope style, the rest (wanted heights, water banks, drawn valleys'
     * floors) */
    double seconds_sketch_ppa, seconds_exemplar_ppa, seconds_features, seconds_fill;
    double seconds_layout, seconds_slope_style, seconds_finish;
} ts_sketch_info;

/**
 * Synthesize `out` (caller-allocated, the sketch's size; cells that are not
 * NaN on entry, such as pinned windows or water, are kept as they are, as
 * are cells flagged TS_CELL_FIXED in `constraints`, which may be NULL)
 * following `sketch` (borrowed; a grey drawing, bright = high, NaN =
 * nodata, which stays nodata in the output) in the style of the exemplars
 * (at the output's ground resolution): PPA on the sketch and on the
 * exemplars; feature patches (branch points, endpoints, paths) matched by
 * deformation (thin-plate-spline warps), seam and profile costs and placed
 * breadth first over the sketch's feature tree (or in raster order); then
 * the non-feature fill of ts_synth_patches.  `sketch_features` (may be
 * NULL) receives the sketch's PPA graph (caller frees with
 * ts_features_free); `info` may be NULL.
 */
TS_API ts_status ts_synth_sketch(ts_ctx *ctx, const ts_raster *sketch, const ts_raster *exemplars,
                                 int n_exemplars, const ts_sketch_params *sp,
                                 const ts_synth_params *params,
                                 const ts_synth_constraints *constraints, ts_raster *out,
                                 ts_synth_maps *maps, ts_features **sketch_features,
                                 ts_sketch_info *info);

/** A line of a sketch drawn as lines (ts_features_from_lines): its points
 *  in cell coordinates of the output grid (cell (i, j) spans [i, i + 1) x
 *  [j, j + 1); points may lie off the grid), its kind, and the heights at
 *  its points (NaN or z == NULL: none).  All borrowed. */
typedef struct ts_sketch_line {
    int kind; /* TS_RIDGE or TS_VALLEY */
    size_t n;
    const double *x, *y, *z;
} ts_sketch_line;

/**
 * The feature graph of a sketch drawn as lines on a width x height grid:
 * the cells each line passes through (8-connected), nodes where lines of a
 * kind meet, cross or end, paths between them; a line end within `snap`
 * cells of another line of its kind (or of another end) is moved onto it.
 * Lines leave the grid at its edge; a ring is opened at its first cell.
 * Vertices take the heights interpolated along their line (z NaN where
 * none is given).  *out: caller frees with ts_features_free.  TS_ERR_ARG
 * for a bad kind, grid or snap.
 */
TS_API ts_status ts_features_from_lines(ts_ctx *ctx, int width, int height,
                                        const ts_sketch_line *lines, size_t n_lines, double snap,
                                        ts_features **out);

/**
 * ts_synth_sketch on a feature graph the caller made (a sketch drawn as
 * lines: ts_features_from_lines), instead of PPA on a painted sketch: the
 * output has the graph's size; `features` is borrowed; the kinds drawn are
 * those on the graph (sp->mode ridges or valleys keeps that kind alone,
 * auto and both keep what is there).  Nodata: the cells flagged
 * TS_CELL_NODATA in `constraints`.  TS_ERR_ARG when no feature of the
 * kinds is on the grid.
 */
TS_API ts_status ts_synth_sketch_features(ts_ctx *ctx, const ts_features *features,
                                          const ts_raster *exemplars, int n_exemplars,
                                          const ts_sketch_params *sp,
                                          const ts_synth_params *params,
                                          const ts_synth_constraints *constraints, ts_raster *out,
                                          ts_synth_maps *maps, ts_sketch_info *info);

/**
 * A sketch in tiles (sketch_amplify.c, ours): what every window of it reads.
 * ts_sketch_tiles_new lays the sketch out whole on a grid K times coarser
 * (K = ts_sketch_amplify_factor; patches and overlap K times smaller, the
 * sketch, wanted heights and exemplars averaged over K x K blocks) and
 * builds the dictionary that amplifies it K times (Argudo et al. 2017) from
 * the exemplars at the output's resolution.  Give a painted `sketch` or a
 * feature graph `features` (ts_features_from_lines), width x height either;
 * params->tiled is not read.  Pinned cells and water (TS_CELL_FIXED, their
 * values in constraints->values) are laid out as K x K blocks: a block at
 * least half fixed is fixed at the mean of its fixed cells (water where
 * most of those are).  *sketch_features (may be NULL; painted sketches)
 * receives the coarse pass's graph on the output grid.
 * ts_sketch_tiles_window then makes any window of the output alone, the
 * same bytes as that window of the whole (ts_synth_sketch with tiled > 0:
 * the window of the whole grid), NaN on the sketch's nodata.  With `flags`
 * (the window's TS_CELL_FIXED and TS_CELL_WATER, or NULL: none) and the
 * fixed cells' values in `out` on entry, those cells come out exactly as
 * given, the land within ts_sketch_tiles_margin of a pinned cell is shifted
 * towards it (the differences at the pinned cells, Gaussian-averaged, tapered
 * to nothing there; ours) and the land beside water is raised to a bank at or
 * above the highest water within that reach (water_banks.c's bank): only
 * cells that margin or more from a side that is not the grid's edge are
 * final, so a window is made grown by the margin and cut.
 */
typedef struct ts_sketch_tiles ts_sketch_tiles;
TS_API ts_status ts_sketch_tiles_new(ts_ctx *ctx, const ts_raster *sketch,
                                     const ts_features *features, const ts_raster *exemplars,
                                     int n_exemplars, const ts_sketch_params *sp,
                                     const ts_synth_params *params,
                                     const ts_synth_constraints *constraints, int width,
                                     int height, ts_sketch_tiles **out,
                                     ts_features **sketch_features, ts_sketch_info *info);
TS_API ts_status ts_sketch_tiles_window(ts_ctx *ctx, const ts_sketch_tiles *t, int x0, int y0,
                                        ts_raster *out, const unsigned char *flags);
/** The margin a window of t with fixed cells needs on each side (8 K + 1). */
TS_API int ts_sketch_tiles_margin(const ts_sketch_tiles *t);
/** K, the factor the sketch was laid out coarser by. */
TS_API int ts_sketch_tiles_factor(const ts_sketch_tiles *t);
/** The output cells of window [x0, x0 + w) x [y0, y0 + h) on a drawn ridge
 *  (the feature graph's ridges: the lines given, or the coarse pass's graph
 *  of a painted sketch on the output grid): flags[y * w + x] |= bit. */
TS_API void ts_sketch_tiles_ridges(const ts_sketch_tiles *t, int x0, int y0, int w, int h,
                                   unsigned char *flags, unsigned char bit);
/**
 * A sketch in tiles as bytes, to lay it out once and serve its windows
 * anywhere later (the caller writes and reads them: the core does no file
 * I/O): the coarse pass, the dictionary, the output's nodata and ridge
 * cells, and `key`, a number of the caller's (what it was made from).
 * Little-endian whatever the machine, versioned, with a checksum;
 * from_bytes checks every size and value (a file is untrusted) and
 * recomputes the coarse pass's drainage area: windows of the result are the
 * same bytes as the original's.  *bytes is freed with free().
 */
TS_API ts_status ts_sketch_tiles_to_bytes(ts_ctx *ctx, const ts_sketch_tiles *t, uint64_t key,
                                          unsigned char **bytes, size_t *len);
TS_API ts_status ts_sketch_tiles_from_bytes(ts_ctx *ctx, const unsigned char *bytes, size_t len,
                                            uint64_t *key, ts_sketch_tiles **out);
TS_API void ts_sketch_tiles_free(ts_sketch_tiles *t);

/* ------------------------------------------------------------------ */
/* Per-pixel operations (the kernels behind the VRT pixel functions)  */
/* ------------------------------------------------------------------ */

/**
 * Weighted blend of n_terms terrains: out[i] = sum_k w_k[i] t_k[i] /
 * sum_k w_k[i] over the terms whose terrain is not NaN and whose weight is
 * finite and > 0; NaN where no term counts.  All arrays borrowed, n cells.
 */
TS_API void ts_blend_weighted(size_t n, int n_terms, const float *const *terrain,
                              const float *const *weight, float *out);
/** Linear map of [from_min, from_max] onto [to_min, to_max]; NaN stays NaN.
 *  from_min == from_max maps everything to to_min. */
TS_API void ts_rescale_linear(size_t n, const float *in, double from_min, double from_max,
                              double to_min, double to_max, float *out);

/** Modes of ts_water_level. */
enum { TS_WATER_FILL = 0, TS_WATER_DEPTH = 1, TS_WATER_MASK = 2 };
/** A water level over a terrain: FILL gives max(z, level) (a lake surface),
 *  DEPTH gives max(level - z, 0), MASK gives 1 below the level, else 0.
 *  NaN stays NaN. */
TS_API void ts_water_level(size_t n, const float *in, double level, int mode, float *out);

/* ------------------------------------------------------------------ */
/* Rendering                                                          */
/* ------------------------------------------------------------------ */

/**
 * Hillshade of `dem` into `out` (caller-allocated, same size), values 0..1,
 * NaN where the DEM is nodata.  Azimuth and altitude in degrees (315, 45
 * is the cartographic default); z_factor exaggerates relief.
 */
TS_API ts_status ts_hillshade(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                              double azimuth_deg, double altitude_deg, double z_factor,
                              ts_raster *out);

/**
 * RGB preview (caller-allocated, 3*width*height bytes): hillshade tinted by
 * elevation, ridges of `features` in red and valleys in blue (features may
 * be NULL), nodata in white.
 */
TS_API ts_status ts_render_preview(ts_ctx *ctx, const ts_raster *dem, const ts_grid_metrics *metrics,
                                   const ts_features *features, unsigned char *rgb);

#include "terrasynth_amplify.h"
#include "terrasynth_drainage.h"
#include "terrasynth_pixel.h"

#ifdef __cplusplus
}
#endif
#endif /* TERRASYNTH_H */
