/*
 * tsyn_tiles.h - the tiles of a tiled synth recipe, one by one: the C
 * interface gdal_TSYN.so exports for the Dask runner (dask/terrasynth_dask.py
 * loads it with ctypes and declares these functions as here).
 *
 * A tiled synth recipe (<Param name="tiled">T</Param>) is made in four
 * waves of tiles (algorithms/docs/synth.md); a tile's window takes the
 * cells of its finished neighbours of earlier waves.  Each call is a pure
 * function of the recipe and the neighbours' windows given, so a tile made
 * twice, on any worker, has the same bytes.  Errors: -1 with one line in msg
 * (n bytes, may be NULL), the recipe's name first.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TSYN_TILES_H
#define TSYN_TILES_H

#ifdef __cplusplus
extern "C" {
#endif

/* Open the recipe at `path` (read through GDAL, never the network) and
 * read what every tile shares (its exemplars): *handle for the calls
 * below, the output's *width x *height cells and the *tile size.  A recipe
 * that is not a tiled synth recipe is refused. */
int tsyn_tiles_open(const char *path, void **handle, int *width, int *height, int *tile, char *msg,
                    int n);

/* Where tile (ti, tj) lies: win and core = {x, y, w, h}, its window (the
 * cells it computes) and its core (the cells it owns in the output). */
int tsyn_tile_rect(void *handle, int ti, int tj, int win[4], int core[4], char *msg, int n);

/* Tile (ti, tj)'s window into `window` (row by row, its own width), from the
 * windows of its neighbours, nb[(dj + 1) * 3 + di + 1] (each row by row, its
 * own width), NULL where not needed. */
int tsyn_tile_make(void *handle, int ti, int tj, const float *const nb[9], float *window, char *msg,
                   int n);

/* How many rings of tiles round a tile the drainage stage reads for its
 * core (0: the recipe keeps its depressions: the cores are the tiles'). */
int tsyn_tile_reach(void *handle);

/* Tile (ti, tj)'s core after the drainage stage into `core` (row by row, its
 * own width), from the windows tsyn_tile_make gave of the tiles within
 * `reach` rings of it, nb[(dj + reach) * (2 reach + 1) + di + reach], NULL
 * off the grid. */
int tsyn_tile_drain(void *handle, int ti, int tj, const float *const *nb, float *core, char *msg,
                    int n);

/* Close the handle (NULL: nothing). */
void tsyn_tiles_close(void *handle);

#ifdef __cplusplus
}
#endif
#endif
