/*
 * match_ssd.h - the masked-SSD matcher (Zhou et al. 2007 section 4.2),
 * shared by its FFT kernel (match_ssd.c) and its k best separated
 * candidates (match_candidates.c).  Not installed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef TS_MATCH_SSD_H
#define TS_MATCH_SSD_H

#include "fft.h"
#include "internal.h"

#define TS__MATCH_STAGE "matcher"
#define TS__MATCH_MAX_SLOTS 64

struct ts_matcher {
    ts_raster ex;         /* borrowed */
    int pw, ph;           /* patch size */
    int nx, ny;           /* window positions */
    int fw, fh;           /* padded transform size */
    int cols;             /* fw / 2 + 1 complex columns of a half spectrum */
    int stride;           /* row stride of rows1/rows2, complex: cols rounded up to a block */
    int nblk;             /* column blocks */
    double mean;          /* mean of the exemplar's valid cells */
    double max_dev2;      /* max (E - mean)^2 over valid cells */
    size_t n_valid;       /* windows free of nodata (and allowed, when restricted) */
    unsigned char *valid; /* nx * ny: 1 where the window is free of nodata; points at
                             all_valid or, when restricted, at allowed */
    unsigned char *all_valid, *allowed; /* the two maps (allowed may be NULL) */
    size_t n_all_valid, n_allowed;
    /* a cost per position added to the SSD by the best-k queries:
     * cost_w x cost[i] (borrowed; NULL: none), ts__matcher_cost */
    const float *cost;
    double cost_w;
    /* Half spectra of E' and E'^2, pre-scaled by -2/F and 1/F, stored by
     * column (transposed): element (row j, column c) at [c * fh + j],
     * for stride columns (those past cols are zero). */
    fftwf_complex *spec1, *spec2;
    fftwf_complex *rows1; /* H rows: exemplar rows, then target rows and output rows */
    fftwf_complex *rows2; /* patch_h rows: mask rows */
    fftwf_complex *scratch[TS__MATCH_MAX_SLOTS]; /* per worker: 2 transposed blocks */
    int n_scratch;
    fftwf_plan row_r2c, row_c2r, col_fwd, col_bwd;
};

/* Workers for n_items items of total_cost cells: ts__thread_count, but at
 * most one per MATCH_MIN_WORK (match_ssd.c) cells. */
int ts__match_workers(const ts_ctx *ctx, size_t n_items, size_t total_cost);

/* A target fit for the matcher's queries: present, patch-sized, strided. */
ts_status ts__match_check_target(ts_ctx *ctx, const ts_matcher *m, const ts_raster *t);

/* The SSD map of a checked target with known cells into out (nx * ny),
 * or, if out is NULL, into rows1 (row y at (float *)rows1 + y * 2 * stride,
 * valid until the next query); *sum_t2 = sum M T'^2. */
ts_status ts__match_map(ts_ctx *ctx, ts_matcher *m, const ts_raster *t, float *out, double *sum_t2);

#endif
