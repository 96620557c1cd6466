/*
 * recipe_internal.h - an open recipe (struct tsrecipe) as recipe.c,
 * recipe_tiles.c and recipe_write.c see it.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_RECIPE_INTERNAL_H
#define TS_RECIPE_INTERNAL_H

#include <pthread.h>
#include <stdint.h>

#include "jobspec.h"
#include "recipe.h"
#include "recipe_xml.h"

#define RECIPE_MAX_BYTES (1 << 20)
#define RECIPE_MAX_DEPTH 8

/* A tile of a tiled synth recipe: its window's cells (ts_synth_tile_window). */
typedef struct recipe_tile {
    int ti, tj;
    int x0, y0, w, h; /* the window */
    float *cells;
    uint64_t used; /* the last request that needed it */
} recipe_tile;

struct tsrecipe {
    char *path;
    int method;
    tsjob_ppa ppa;
    tsjob_synth synth;
    uint64_t seed;
    tsjob_values values; /* what the recipe (and the open options) give: the jobs point in */
    char **strings;      /* CSL list owning every path string the jobs point to */
    tsio_georef geo;     /* ppa: the input's grid */
    tsjob_ppa_result ppa_res;
    tsjob_synth_result synth_res;
    tsjob_amplify amplify;
    tsjob_amplify_result amplify_res;
    tsjob_pixel pixel;
    tsjob_pixel_result pixel_res;
    int map; /* synth: -1 the terrain, else the TSJOB_MAP_* served (open option MAP) */
    char layer[TS_LAYER_NAME]; /* amplify: the carried layer or "classes" served (LAYER), or "" */
    int computed;
    /* a tiled synth recipe: the tiles made so far, at most tile_limit bytes
     * of them between requests (least recently used go first) */
    pthread_mutex_t tile_lock;
    int has_tile_lock;
    recipe_tile *tiles;
    size_t n_tiles, cap_tiles, tile_bytes;
    uint64_t tile_clock; /* the request being served */
    /* pixel and amplify with the drainage stage: blocks of the method's output
     * (recipe_raw.c), at most raw_limit bytes between requests */
    pthread_mutex_t raw_lock;
    int has_raw_lock;
    recipe_tile *raw;
    size_t n_raw, cap_raw, raw_bytes, raw_limit;
    uint64_t raw_clock;
};

/* The cells [x0, x0+w) x [y0, y0+h) of a tiled synth recipe, from the tiles
 * that cover them (made as needed, the least recently used dropped past the
 * cache's limit); thread-safe (recipe_tiles.c). */
int tsrecipe__tiles_window(tsrecipe *r, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                           tsio_err *err);

/* The caches of made blocks (recipe_tiles.c): block (ti, tj) among t[0..n),
 * or NULL; the least recently used not needed by the request `clock` dropped
 * until *bytes <= limit; the limit TSYN_TILE_CACHE_MB sets (default 256 MB). */
recipe_tile *tsrecipe__cache_find(recipe_tile *t, size_t n, int ti, int tj);
void tsrecipe__cache_evict(recipe_tile *t, size_t *n, size_t *bytes, size_t limit, uint64_t clock);
int tsrecipe__cache_limit(const tsrecipe *r, size_t *bytes, tsio_err *err);

/* recipe_raw.c: the cache of a pixel or amplify recipe's blocks (init reads
 * TSYN_TILE_CACHE_MB), and a window after the drainage stage from them;
 * thread-safe. */
int tsrecipe__raw_init(tsrecipe *r, tsio_err *err);
void tsrecipe__raw_free(tsrecipe *r);
int tsrecipe__raw_drained(tsrecipe *r, ts_ctx *ctx, int x0, int y0, int w, int h, float *out,
                          tsio_err *err);

#endif
