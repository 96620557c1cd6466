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
    int32_t **sim;      /* with coherence K > 1: L + 1 arrays of K - 1 similar cells per cell
                           (ids of ts__pix_similar; -1: none), usable cells only */
    float **app;        /* L + 1 arrays: each cell's appearance vector (dim[l] floats; 0 where not
                           usable) */
} pix_stack;

/* Candidate e as a map into its exemplar's stack: cell (u, v) of the
 * candidate (w x h) is cell (ox + mxu u + mxv v, oy + myu u + myv v) of the
 * exemplar (sw cells wide). */
typedef struct pix_turn {
    int w, h, sw, ox, oy, mxu, mxv, myu, myv;
} pix_turn;

/* The relief start's field (relief_start.c): the strata's values, the
 * field's sorted sample (its distribution) and the lattice spacing. */
typedef struct ts_pixel_relief {
    double strata[16];
    double *sorted; /* 16384 values */
    double scale;   /* S: the lattice spacing (cells of the output) that matches the
                       exemplars' relief at the coarsest spacing */
} ts_pixel_relief;

/* The exemplars' grain: the coherence of their gradients' orientation,
 * |sum g^2 e^(2 i theta)| / sum |g|^2 over every cell with its four
 * neighbours (0: no preferred direction, 1: all one way). */
double ts__pix_grain(const ts_raster *exemplars, int n);

struct ts_pixel_exemplars {
    int n;       /* candidates: the exemplars given x nv (coordinate e: exemplar e / nv, variant
                    e % nv, turned and mirrored as vturn and vmirror say) */
    int n_given; /* the exemplars given, each with a stack */
    int nv;      /* variants per exemplar: 1, 2, 4 or 8 */
    int vturn[8], vmirror[8]; /* variant v: its quarter turns (counter-clockwise), and
                                 whether it is mirrored left-right first */
    double grain;             /* the exemplars' gradient orientation coherence (ts__pix_grain) */
    int levels, window;
    int kl[12];             /* each level's window (the coarsest may be narrower) */
    pix_stack *stacks;      /* n_given */
    pix_turn *turn;         /* n */
    int coherence;          /* K of the k-coherence similarity sets (1: none) */
    int64_t *cell_base;     /* n_given: the first id of each exemplar's cells in the sets */
    int dim[12];            /* each level's appearance dimension: 1 + principal directions kept
                               (+ 1 with the roughness term: the last) */
    float rough;            /* the roughness term's sqrt(lambda) (0: none): an appearance vector's
                               last value is rough x the neighbourhood's roughness */
    float *basis[12];       /* each level's principal directions, (dim - 1) rows of k * k */
    ts_pixel_relief relief; /* the relief start (its sample NULL until built) */
};

struct ts_pixel_guide {
    int width, height, levels;
    float **level; /* levels + 1 rasters: the guide blurred as the exemplars' stacks */
};

/* A coordinate of the synthesis: exemplar e, cell (u, v). */
typedef struct pix_coord {
    int32_t e, u, v;
} pix_coord;

/* Candidate e's level l and usable mask at its cell (u, v) (NaN and 0 past
 * its edges): the exemplar's stack read turned (its nodata cells hold the
 * nearest valid cell's value, and are never usable). */
float ts__pix_candidate_height(const ts_pixel_exemplars *ex, int l, int e, int u, int v);
int ts__pix_candidate_usable(const ts_pixel_exemplars *ex, int l, int e, int u, int v);

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

/* The appearance vector of the k x k heights t (appearance_space.c): k x
 * their mean, then their shape (less the mean) on the m rows of basis (the
 * roughness slot, where there is one, is the caller's). */
void ts__pix_appearance(const float *basis, int m, int k, const float *t, float *out);
/* The roughness of the k x k heights t: the root sum of squares of t less
 * its mean (the shape's norm; the same under turns and mirrors). */
float ts__pix_roughness(int k, const float *t);
/* Every level's principal directions holding `energy` of the shapes'
 * variance (1: all) and every usable cell's appearance vector.  0, or -1
 * when out of memory. */
int ts__pix_appearance_build(const ts_ctx *ctx, ts_pixel_exemplars *ex, double energy);

/* A kd-tree over n points of dim floats (pts kept by the caller). */
typedef struct pix_kdtree pix_kdtree;
pix_kdtree *ts__pix_kdtree_build(const float *pts, size_t n, int dim);
void ts__pix_kdtree_free(pix_kdtree *t);
/* The K points nearest to q (squared Euclidean distance, ties by index)
 * among those `keep` accepts (NULL: all), ascending into out and d2; the
 * number found. */
int ts__pix_kdtree_knn(const pix_kdtree *t, const float *q, int K,
                       int (*keep)(void *arg, int32_t i), void *arg, int32_t *out, float *d2);

/* The k-coherence similarity sets of every level (K = coherence; 1: none):
 * 0, -1 when out of memory, -2 when the exemplars hold 2^31 cells or more,
 * -3 when cancelled (the failure recorded on ctx).  Reports progress and,
 * when the rest will take longer than notice_seconds (PIX_NOTICE_SECONDS),
 * a notice. */
#define PIX_NOTICE_SECONDS 30.0
int ts__pix_similarity_build(ts_ctx *ctx, ts_pixel_exemplars *ex, int coherence,
                             double notice_seconds);
/* A similarity set's id as exemplar and cell. */
void ts__pix_similar(const ts_pixel_exemplars *ex, int32_t id, int *e, int32_t *cell);

/* The relief start (relief_start.c): the field's distribution and the
 * lattice spacing matched to the exemplars' relief at the coarsest spacing;
 * 0, or -1 when out of memory. */
int ts__pix_relief_build(ts_pixel_exemplars *ex);
void ts__pix_relief_free(ts_pixel_relief *r);
/* The uniform cubic B-spline's four weights at t in [0, 1) (for the nodes
 * at -1, 0, 1, 2; they sum to 1). */
void ts__bspline_weights(double t, double w[4]);
/* The rank in [0, 1] of the field's value at (x, y) (cells of the output)
 * on a lattice of spacing S. */
double ts__pix_relief_rank(const ts_pixel_relief *r, double S, double x, double y, uint64_t seed);

/* The eigenvalues of the symmetric n x n matrix a (destroyed) by cyclic
 * Jacobi rotations, into ev (unordered); 0, or -1 when they did not converge. */
int ts__pix_eigenvalues(double *a, int n, double *ev);
/* The same with the eigenvectors: column j of vec (n x n) belongs to ev[j]. */
int ts__pix_eigen(double *a, int n, double *ev, double *vec);
/* The share of the principal components that hold 95 % of the variance of
 * the exemplars' mean-removed k x k neighbourhoods (at most about 4000 per
 * exemplar, on a lattice); -1 on failure. */
double ts__pix_pca_ratio(const ts_raster *ex, int n, int k);
/* The k in {3, 5, 7, 9} with the smallest ratio (Cruz et al.). */
int ts__pix_choose_window(const ts_raster *ex, int n);

#endif
