/*
 * pixel.h - private to multiresolution pixel synthesis (Lefebvre and Hoppe
 * 2005, as used for terrain by Cruz et al.): the exemplars' Gaussian stacks
 * and the correction kernel its tests compare with a plain loop.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_PIXEL_H
#define TS_PIXEL_H

#include "internal.h"

/* One exemplar's Gaussian stack: levels 0..L, each the exemplar's size
 * (level L the exemplar itself, level l blurred by a Gaussian of sigma
 * 2^(L-l-1)), and per level the cells a coordinate may take (its k x k
 * neighbourhood at the level's spacing inside the exemplar and valid). */
typedef struct pix_stack {
    int width, height;
    float **level;          /* L + 1 rasters, width * height (NaN = nodata) */
    unsigned char **usable; /* L + 1 masks */
    int32_t **usable_list;  /* L + 1 lists of usable cell indices (y * width + x) */
    size_t *n_usable;
    int32_t *by_height; /* level 0's usable cells in ascending order of height */
} pix_stack;

struct ts_pixel_exemplars {
    int n, levels, window;
    pix_stack *stacks;
};

struct ts_pixel_guide {
    int width, height, levels;
    float **level; /* levels + 1 rasters: the guide blurred as the exemplars' stacks */
};

/* A coordinate of the synthesis: exemplar e, cell (u, v). */
typedef struct pix_coord {
    int32_t e, u, v;
} pix_coord;

/* Fill stack s for exemplar ex (levels 0..L, window k).  0, or -1 when out
 * of memory. */
int ts__pix_stack_build(const ts_raster *ex, int L, int k, pix_stack *s);
/* The same in three steps, so levels can be built in parallel: the arrays,
 * one level (blur, usable cells), then the by-height order. */
int ts__pix_stack_alloc(const ts_raster *ex, int L, pix_stack *s);
int ts__pix_stack_level(const ts_raster *ex, int L, int k, int l, pix_stack *s);
int ts__pix_stack_finish(pix_stack *s);
void ts__pix_stack_free(pix_stack *s, int L);

/* The Gaussian blur of a raster with sigma (NaN left out, weights
 * renormalised; the kernel cut at 3 sigma, never wrapping). */
int ts__pix_blur(const float *in, int w, int h, double sigma, float *out);

/* The sum of squared differences between the target neighbourhood t (k*k
 * values) and the k x k neighbourhood of (u, v) in `level` at spacing h. */
double ts__pix_ssd(const float *level, int width, int u, int v, int k, int h, const float *t);

/* A 64-bit hash of an absolute position, a level, a stream and the seed
 * (SplitMix64 finaliser over the mixed words). */
uint64_t ts__pix_hash(int64_t x, int64_t y, int level, int stream, uint64_t seed);

/* The eigenvalues of the symmetric n x n matrix a (destroyed) by cyclic
 * Jacobi rotations, into ev (unordered); 0, or -1 when they did not converge. */
int ts__pix_eigenvalues(double *a, int n, double *ev);
/* The share of the principal components that hold 95 % of the variance of
 * the exemplars' mean-removed k x k neighbourhoods (at most about 4000 per
 * exemplar, on a lattice); -1 on failure. */
double ts__pix_pca_ratio(const ts_raster *ex, int n, int k);
/* The k in {3, 5, 7, 9} with the smallest ratio (Cruz et al.). */
int ts__pix_choose_window(const ts_raster *ex, int n);

#endif
