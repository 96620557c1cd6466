/*
 * internal.h - private helpers of libterrasynth: the context layout, error
 * and progress helpers, a tiny parallel-for.  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_INTERNAL_H
#define TS_INTERNAL_H

#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "terrasynth.h"

/* The worker threads of a context (thread_pool.c), started on first use;
 * the slot's mutex guards that start. */
typedef struct ts__pool ts__pool;
typedef struct ts__pool_slot {
    pthread_mutex_t mu;
    ts__pool *pool;
} ts__pool_slot;

struct ts_ctx {
    ts_status status;
    char message[1024];
    int input; /* the failing input (e.g. exemplar index), or -1 */
    ts_progress_fn progress;
    void *progress_user;
    ts_notice_fn notice;
    void *notice_user;
    double prog_lo, prog_hi; /* current sub-range of the overall progress */
    uint64_t seed;
    int threads;
    atomic_int cancel_own;  /* set when the progress callback asked to stop */
    atomic_int *cancel;     /* the flag this context obeys: its own, or its parent's */
    ts__pool_slot pool_own; /* the threads of a context of its own */
    ts__pool_slot *pool;    /* the threads it uses: its own, or its parent's */
};

/* A context for a worker of `parent`'s call (caller frees with
 * ts_ctx_free, before the parent): the parent's seed, threads and thread
 * pool, no progress callback, and the parent's cancel flag, so a cancel reaches the worker at its
 * next ts__progress or ts__cancelled, and ts__cancel from the worker stops the others.  NULL if out
 * of memory. */
ts_ctx *ts__ctx_child(ts_ctx *parent);
/* Has the call been cancelled (by the callback, or by ts__cancel)? */
int ts__cancelled(const ts_ctx *ctx);
/* Ask every context sharing ctx's flag to stop (e.g. a worker failed). */
void ts__cancel(ts_ctx *ctx);
/* TS_OK, or the cancelled failure recorded on ctx when the call has been
 * cancelled (after parallel work whose workers stopped early). */
ts_status ts__check_cancel(ts_ctx *ctx);

/* Record a failure: "<stage>: <formatted text>"; returns status. */
ts_status ts__fail(ts_ctx *ctx, ts_status status, const char *stage, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 4, 5)))
#endif
    ;
/* The same, naming the failing input (an exemplar index, 0-based) that
 * ts_ctx_failed_input reports.  A plain ts__fail that wraps a failure keeps
 * the input it named. */
ts_status ts__fail_input(ts_ctx *ctx, ts_status status, int input, const char *stage,
                         const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 5, 6)))
#endif
    ;
/* Clear the status at the start of a public call. */
void ts__clear(ts_ctx *ctx);

/* Report progress `frac` (0..1) of the current sub-range; returns
 * TS_ERR_CANCELLED (message set) if the callback asked to stop. */
ts_status ts__progress(ts_ctx *ctx, double frac, const char *msg);

/* A note for the user (ts_ctx_set_notice): "<formatted text>" under stage. */
void ts__notice(ts_ctx *ctx, const char *stage, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Narrow the progress range to [lo, hi] of the current range; restore
 * with ts__progress_pop(ctx, saved). */
typedef struct ts_progress_saved {
    double lo, hi;
} ts_progress_saved;
ts_progress_saved ts__progress_push(ts_ctx *ctx, double lo, double hi);
void ts__progress_pop(ts_ctx *ctx, ts_progress_saved saved);

/* Number of worker threads to use for `work_items` independent items. */
int ts__thread_count(const ts_ctx *ctx, size_t work_items);

/* Run fn(arg, begin, end) over [0, n) split into contiguous chunks, one
 * per thread (the caller's thread takes the first).  Results must not
 * depend on the split.  A thread that cannot be started has its chunk run
 * on the calling thread, so this cannot fail. */
typedef void (*ts_range_fn)(void *arg, size_t begin, size_t end);
void ts__parallel_for(const ts_ctx *ctx, size_t n, ts_range_fn fn, void *arg);

/* thread_pool.c: fn over [0, n) in nt chunks on the slot's pool (started,
 * or grown to nt - 1 workers, as needed); the caller runs the first chunk
 * and helps with queued ones until its own are done.  Cannot fail: without
 * threads or memory the chunks run on the caller. */
void ts__pool_slot_init(ts__pool_slot *slot);
void ts__pool_slot_destroy(ts__pool_slot *slot); /* joins the workers */
void ts__pool_for(ts__pool_slot *slot, int nt, size_t n, ts_range_fn fn, void *arg);
int ts__pool_workers(ts__pool_slot *slot); /* workers started so far */

/* The synthesis lengths in whole cells, checked (patch 8..1024, overlap
 * 2..512 and smaller); fails for lengths still in metres. */
ts_status ts__synth_cells(ts_ctx *ctx, const ts_synth_params *p, int *patch, int *overlap);

/* A cell flag of the fill only (beside TS_CELL_NODATA and TS_CELL_FIXED):
 * a window whose centre is such a cell may take exemplar windows with main
 * features (see ts__fill.exemplar_features). */
#define TS__CELL_FEATURE 4 /* (TS_CELL_* take 1, 2 and 8) */

/* Everything the non-feature fill (nonfeature_placement.c) and the
 * candidates' costs read: the caller's parameters and constraints, and
 * what a sketch adds (synth.c builds it). */
typedef struct ts__fill {
    ts_synth_params s;               /* lengths in whole cells */
    const unsigned char *cell_flags; /* TS_CELL_* and TS__CELL_FEATURE, or NULL */
    const int32_t *cell_exemplar;    /* per cell: its region's exemplar or -1; or NULL */
    const float *heights;            /* wanted heights (NaN = none), or NULL */
    double alpha_h;
    /* the relief a sketch implies (NaN = none), or NULL: candidates gain
     * alpha_r * RMS(patch - guide) like the height constraints */
    const float *guide;
    double alpha_r;
    /* per exemplar a mask of its main feature cells (or NULL): away from
     * TS__CELL_FEATURE cells the fill leaves out the quarter of the
     * exemplar's windows with the most such cells in their middle half
     * (Zhou et al. section 4.2: non-feature patches from featureless
     * windows) */
    const unsigned char *const *exemplar_features;
} ts__fill;

/* The fill from the caller's parameters (lengths already in cells) and
 * constraints (may be NULL); nothing a sketch adds. */
ts__fill ts__fill_make(const ts_synth_params *p, const ts_synth_constraints *c);
/* The land within a patch of TS_CELL_WATER cells raised softly to banks at or
 * above the water's level (water_banks.c); flags may be NULL. */
ts_status ts__water_banks(ts_ctx *ctx, ts_raster *out, const unsigned char *flags, int patch);
/* z raised towards the bank level - k max(0, d - 1.5) of water d cells off by a soft
 * maximum (width k), faded out over the last half of reach (water_banks.c). */
double ts__bank_raise(double z, double level, double k, double d, double reach);
/* The median |step| between 4-neighbours of r's cells, from at most about 2^16 cells on a
 * fixed lattice: of the cells not flagged, or with flags NULL of those whose step is not
 * exactly 0 (flat fixed blocks); 0 when none, -1 when out of memory (water_banks.c). */
double ts__median_step(const ts_raster *r, const unsigned char *flags);
/* ts_synth_tiled with debug maps of the whole grid (maps may be NULL):
 * the same bytes as without; patch indices numbered wave by wave, tiles in
 * row-major order within a wave (tiled_synthesis.c). */
ts_status ts__synth_tiled_maps(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                               const ts_synth_params *params,
                               const ts_synth_constraints *constraints, int tile, ts_raster *out,
                               ts_synth_maps *maps);

/* The non-feature fill (nonfeature_placement.c): ts_synth_patches for a
 * checked ts__fill. */
ts_status ts__fill_run(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars, const ts__fill *f,
                       ts_raster *out, ts_synth_maps *maps);

/* Matcher restriction (match_ssd.c): `allowed` (nx * ny positions of the
 * matcher, copied; NULL clears) marks the windows a restricted query may
 * return; ts__matcher_restrict(m, 1) makes the following queries see only
 * those (when any is allowed), (m, 0) all of them again; it returns whether
 * the matcher was restricted before. */
ts_status ts__matcher_set_allowed(ts_ctx *ctx, ts_matcher *m, const unsigned char *allowed);
int ts__matcher_restrict(ts_matcher *m, int on);
/* A cost per window position (nx * ny, borrowed, finite, >= 0) that the
 * matcher's next best-k queries add, times weight, to the SSD they rank by
 * and return; NULL or weight <= 0 clears. */
void ts__matcher_cost(ts_matcher *m, const float *cost, double weight);

/* poisson.c: ts_poisson_solve with NaN cells of u left out (neither
 * unknowns nor boundary: the edges to them carry no guidance), so a grid
 * with nodata can be solved whole; screen > 0 adds screen (u - u0) to every
 * unknown's equation (u0: u on entry; the least-squares fit of the
 * differences plus screen times the squared change, as in
 * ts__poisson_screened_whole; no component floats then).  Does not clear
 * ctx. */
ts_status ts__poisson_solve_valid(ts_ctx *ctx, int w, int h, const unsigned char *mask,
                                  const float *gx, const float *gy, float *u, double tolerance,
                                  int max_iter, double screen);
/* poisson.c: every cell of a w x h grid (stride w, no NaN in u) an unknown: the u that
 * minimises sum over edges (u_q - u_p - g)^2 + screen sum (u - u0)^2 (u0: u on entry; g: gx,
 * gy as for ts_poisson_solve), exactly, by two cosine transforms; screen >= 0 (0: the pure
 * Neumann problem, the mean of u0 kept; > 0 damps changes wider than about 1 / sqrt(screen)
 * cells).  TS_ERR_ARG on non-finite input, u unchanged on failure. */
ts_status ts__poisson_screened_whole(ts_ctx *ctx, int w, int h, const float *gx, const float *gy,
                                     float *u, double screen);

/* Seconds on a monotonic clock (for stage timings). */
double ts__now(void);

/* Overflow-checked allocation helpers (NULL on overflow or failure). */
void *ts__malloc_array(size_t n, size_t size);
/* qsort comparator of floats, ascending (no NaN given) */
int ts__float_cmp(const void *a, const void *b);
/* Sorts n floats (no NaN) ascending in O(n): the same order as a stable sort by
 * ts__float_cmp (equal values, +0 and -0 among them, keep their order).  (raster.c) */
void ts__sort_floats(float *v, size_t n);

/* Per cell of a w x h grid, the height z of the nearest TS_CELL_FIXED cell with data in
 * `flags`, NaN where none is within `reach` cells: nearest by the chamfer distance (5 a step
 * along a row or column, 7 diagonally, at most 5 reach), ties to the first in raster order.
 * Exact (two raster passes: a cell's neighbour on its way to the nearest fixed cell holds
 * that cell or one as near and earlier), so a window with a margin of reach gives the
 * whole's values inside it.  malloc'ed; NULL out of memory.  (drainage) */
float *ts__nearest_fixed_levels(const float *z, const unsigned char *flags, int w, int h,
                                int reach);
/* The spill level of every cell of z (w x h, NaN nodata: NaN there), the lowest level at
 * which water on it flows out over the grid's edge or into nodata (a priority flood).  0, -1
 * out of memory.  (drainage) */
int ts__spill_levels(const float *z, int w, int h, float *level);
/* The basins of z below their spill beside a TS_CELL_SHALLOW cell, deeper than relief: raised to
 * plains graded to their pour points (dammed_basins.c). Never lowers a cell nor changes a fixed
 * one; the basins and cells raised counted.  0, -1 out of memory.  (drainage) */
int ts__raise_dammed_basins(float *z, const unsigned char *flags, int w, int h, double relief,
                            size_t *basins, size_t *cells_raised);
/* ts_drainage_apply's pass on dem, checked: every pit drained on the surface as given
 * (depression_breaching.c); the same on the whole grid, then its dammed basins raised to plains
 * and drained again, info against the surface as given (dammed_basins.c).  (drainage) */
ts_status ts__drain_pass(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags, int64_t gx0,
                         int64_t gy0, int64_t gw, int64_t gh, const ts_drainage_params *p,
                         ts_drainage_info *info);
ts_status ts__drain_with_plains(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                                const ts_drainage_params *p, ts_drainage_info *info);
/* z (NaN nodata; flags row-major, width x height) with its basins lifted
 * (ts_drainage_params.basin_block, dammed_basins.c): the minima over f x f blocks filled by a
 * priority flood graded `grade` a block (the blocks on the grid's edge or holding nodata or a fixed
 * cell drain out), the fill's depth less `keep` at the blocks' centres taken bilinearly, smoothed
 * by a box of f / 2 cells each side along rows then columns, and added to every cell neither nodata
 * nor fixed.  Never lowers a cell.  The cells raised set to 1 in `lifted` (width x height, or
 * NULL).  0, -1 out of memory. (drainage) */
int ts__lift_basins(ts_raster *z, const unsigned char *flags, int f, double grade, double keep,
                    unsigned char *lifted);
/* ts_drainage_apply on the whole grid with basin_block: drained as without (with plains as
 * ts__drain_with_plains), then twice the basins left lifted and the grid drained again; info
 * against the surface as given.  (drainage) */
ts_status ts__drain_lifted(ts_ctx *ctx, ts_raster *dem, const unsigned char *flags,
                           const ts_drainage_params *p, ts_drainage_info *info);
/* A 64-bit hash of seed and words[0..n) (splitmix64 steps, one a word):
 * the randomness of a stage that must not depend on order or threads. */
uint64_t ts__hash_words(uint64_t seed, const uint64_t *words, int n);
void *ts__calloc_array(size_t n, size_t size);

#define TS_PI 3.14159265358979323846
#define TS_MIN(a, b) ((a) < (b) ? (a) : (b))
#define TS_MAX(a, b) ((a) > (b) ? (a) : (b))

/* Ground size of a cell step (dx, dy in cells) starting on row y. */
static inline double ts_step_length(const ts_grid_metrics *m, int y, int ddx, int ddy)
{
    double wx, wy;
    if (!m)
        return (ddx && ddy) ? 1.4142135623730951 : 1.0;
    wx = m->dx[y] * ddx;
    wy = m->dy[y] * ddy;
    return sqrt(wx * wx + wy * wy);
}

/* The bytes of the core's file formats (bytes.c): little-endian whatever
 * the machine; n items of `size` bytes copied between host and file order. */
void ts__le_copy(unsigned char *dst, const void *src, size_t n, size_t size);
void ts__put_u32(unsigned char *p, uint32_t v);
void ts__put_u64(unsigned char *p, uint64_t v);
uint32_t ts__get_u32(const unsigned char *p);
uint64_t ts__get_u64(const unsigned char *p);

#endif
