/*
 * match_ssd.c - masked SSD of a patch against every window of an exemplar,
 * by FFT, and the k best separated candidates (Zhou et al. 2007 section 4.2).
 *
 * SSD(x,y) = sum M T'^2 - 2 corr(E', M T')(x,y) + corr(E'^2, M)(x,y), M = 1 on
 * known target cells, ' = minus the exemplar mean (the SSD is unchanged and
 * float cancellation smaller).  The spectra of E' and E'^2 are made once; a
 * query transforms 2 x patch_h rows, then column blocks (forward, product,
 * one inverse), then the output rows: O(F log F) for F = fw * fh padded cells
 * (7-smooth, >= W x H).  ts_matcher_best reads the float map in order and
 * rescores in double only what the float error bound cannot rule out.
 * Memory: ~13 bytes per padded cell (two half spectra 8, an H-row buffer 4,
 * validity 1): 210 MB for 4096 x 4096.  Thread-safety: one thread per matcher
 * at a time; FFTW planning runs under fft.c's mutex; results do not depend on
 * the thread count.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "fft.h"
#include "internal.h"

#define MATCH_STAGE "matcher"
/* Complex columns per column block.  8 (64 bytes) keeps every block, row
 * and scratch buffer at the alignment the plans were made with, and was
 * the fastest of 4..32 (a block of 4096-point columns stays in L2). */
#define MATCH_BLOCK 8
#define MATCH_MAX_SLOTS 64
/* Bound on |float map - exact SSD| relative to sum M T'^2 + known * max E'^2
 * (observed <= ~1e-6 in tests/c/test_match_ssd.c; float eps is 6e-8). */
#define MATCH_FLOAT_ERR 1e-5

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
    fftwf_complex *scratch[MATCH_MAX_SLOTS]; /* per worker: 2 transposed blocks */
    int n_scratch;
    fftwf_plan row_r2c, row_c2r, col_fwd, col_bwd;
};

/* Work shared by the parallel phases. */
typedef struct match_job {
    ts_matcher *m;
    const ts_raster *target;
    int square;          /* exemplar rows: 0 = E', 1 = E'^2 */
    fftwf_complex *dest; /* exemplar columns: the spectrum to fill */
    float scale;         /* exemplar columns: factor applied to the spectrum */
    float *out;          /* query: the SSD map, or NULL to leave it in rows1 */
    double sum_t2;       /* query: sum M T'^2 */
    int nslots;          /* column phases: worker slots */
} match_job;

/* ---- parallel helpers ---------------------------------------------------- */

/* Cells of work per worker below which a thread costs more than it saves. */
#define MATCH_MIN_WORK ((size_t)1 << 17)

/* Workers for n_items items of total_cost cells: ts__thread_count, but at
 * most one per MATCH_MIN_WORK cells. */
static int match_workers(const ts_ctx *ctx, size_t n_items, size_t total_cost)
{
    const size_t by_work = total_cost / MATCH_MIN_WORK;
    const int nt = ts__thread_count(ctx, n_items);
    return by_work < 1 ? 1 : (by_work < (size_t)nt ? (int)by_work : nt);
}

typedef struct match_group {
    size_t n, groups;
    ts_range_fn fn;
    void *arg;
} match_group;

static void match_group_run(void *arg, size_t begin, size_t end)
{
    const match_group *g = arg;
    g->fn(g->arg, g->n * begin / g->groups, g->n * end / g->groups);
}

/* fn over items [0, n) of `cost` cells each, on match_workers() threads.
 * Items are independent, so the split never changes a result. */
static void match_parallel(ts_ctx *ctx, size_t n, size_t cost, ts_range_fn fn, void *arg)
{
    match_group g;
    g.n = n;
    g.groups = (size_t)match_workers(ctx, n, n * cost);
    g.fn = fn;
    g.arg = arg;
    if (n == 0)
        return;
    if (g.groups <= 1)
        fn(arg, 0, n);
    else
        ts__parallel_for(ctx, g.groups, match_group_run, &g);
}

/* ---- validity, mean ---------------------------------------------------- */

/* Mean and spread of the valid cells, and the windows free of nodata:
 * box sums of the nodata indicator (a summed-area table kept as running
 * column counts over patch_h rows, then a running sum over patch_w). */
static ts_status match_validity(ts_ctx *ctx, ts_matcher *m)
{
    const ts_raster *e = &m->ex;
    const int w = e->width, h = e->height;
    double sum = 0.0, max_dev2 = 0.0;
    size_t n = 0, n_valid = 0;
    int *colcnt;
    int x, y;
    for (y = 0; y < h; y++) {
        const float *row = e->data + (ptrdiff_t)y * e->stride;
        for (x = 0; x < w; x++)
            if (isfinite(row[x])) {
                sum += row[x];
                n++;
            }
    }
    if (n == 0)
        return ts__fail(ctx, TS_ERR_NUMERIC, MATCH_STAGE, "every exemplar cell is nodata");
    /* rounded to float so that E' and T' are shifted by the same value */
    m->mean = (float)(sum / (double)n);
    for (y = 0; y < h; y++) {
        const float *row = e->data + (ptrdiff_t)y * e->stride;
        for (x = 0; x < w; x++)
            if (isfinite(row[x])) {
                double d = row[x] - m->mean;
                if (d * d > max_dev2)
                    max_dev2 = d * d;
            }
    }
    m->max_dev2 = max_dev2;

    m->valid = m->all_valid = ts__malloc_array((size_t)m->nx * (size_t)m->ny, 1);
    colcnt = ts__calloc_array((size_t)w, sizeof *colcnt);
    if (!m->valid || !colcnt) {
        free(colcnt);
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate the validity map");
    }
    for (y = 0; y < m->ph; y++)
        for (x = 0; x < w; x++)
            colcnt[x] += !isfinite(e->data[(ptrdiff_t)y * e->stride + x]);
    for (y = 0; y < m->ny; y++) {
        unsigned char *v = m->valid + (size_t)y * (size_t)m->nx;
        int s = 0;
        if (y > 0) {
            const float *add = e->data + (ptrdiff_t)(y + m->ph - 1) * e->stride;
            const float *sub = e->data + (ptrdiff_t)(y - 1) * e->stride;
            for (x = 0; x < w; x++)
                colcnt[x] += !isfinite(add[x]) - !isfinite(sub[x]);
        }
        for (x = 0; x < m->pw; x++)
            s += colcnt[x];
        for (x = 0; x < m->nx; x++) {
            if (x > 0)
                s += colcnt[x + m->pw - 1] - colcnt[x - 1];
            v[x] = s == 0;
            n_valid += s == 0;
        }
    }
    free(colcnt);
    m->n_valid = m->n_all_valid = n_valid;
    if (n_valid == 0)
        return ts__fail(ctx, TS_ERR_NUMERIC, MATCH_STAGE,
                        "no %d x %d window of the exemplar is free of nodata", m->pw, m->ph);
    return TS_OK;
}

/* ---- transforms: rows, then column blocks ------------------------------ */

/* Worker scratch for up to `want` slots; returns how many exist (>= 1
 * once the matcher is built). */
static int match_scratch(ts_matcher *m, int want)
{
    while (m->n_scratch < want && m->n_scratch < MATCH_MAX_SLOTS) {
        fftwf_complex *p = ts__fft_alloc(2 * (size_t)m->fh * MATCH_BLOCK, sizeof *p);
        if (!p)
            break;
        if (m->n_scratch > 0 &&
            fftwf_alignment_of((float *)p) != fftwf_alignment_of((float *)m->scratch[0])) {
            ts__fft_free(p); /* cannot happen with fftwf_malloc; never run a plan misaligned */
            break;
        }
        m->scratch[m->n_scratch++] = p;
    }
    return m->n_scratch;
}

/* Column block b of the first nrows rows of `rows` into blk, transposed
 * (column c of the block is blk[c * fh .. c * fh + fh - 1]), zero below. */
static void match_gather(const ts_matcher *m, const fftwf_complex *rows, int nrows, int b,
                         fftwf_complex *blk)
{
    const int c0 = b * MATCH_BLOCK, nc = TS_MIN(MATCH_BLOCK, m->cols - c0);
    const size_t fh = (size_t)m->fh;
    int j, c;
    for (j = 0; j < nrows; j++) {
        const fftwf_complex *src = rows + (size_t)j * m->stride + c0;
        for (c = 0; c < nc; c++) {
            blk[c * fh + (size_t)j][0] = src[c][0];
            blk[c * fh + (size_t)j][1] = src[c][1];
        }
    }
    for (c = 0; c < MATCH_BLOCK; c++) {
        const size_t from = c < nc ? (size_t)nrows : 0;
        memset(blk + c * fh + from, 0, (fh - from) * sizeof *blk);
    }
}

/* Exemplar rows [begin, end): E' or E'^2 (nodata -> 0), forward along x. */
static void match_rows_exemplar(void *arg, size_t begin, size_t end)
{
    const match_job *job = arg;
    const ts_matcher *m = job->m;
    size_t y;
    for (y = begin; y < end; y++) {
        fftwf_complex *row = m->rows1 + y * (size_t)m->stride;
        float *r = (float *)row;
        const float *src = m->ex.data + (ptrdiff_t)y * m->ex.stride;
        int x;
        for (x = 0; x < m->ex.width; x++) {
            double d = src[x] - m->mean;
            r[x] = isfinite(src[x]) ? (float)(job->square ? d * d : d) : 0.0f;
        }
        memset(r + m->ex.width, 0, (size_t)(2 * m->stride - m->ex.width) * sizeof *r);
        fftwf_execute_dft_r2c(m->row_r2c, r, row);
    }
}

/* Exemplar column slots [begin, end): forward along y, scale, store. */
static void match_cols_exemplar(void *arg, size_t begin, size_t end)
{
    const match_job *job = arg;
    const ts_matcher *m = job->m;
    const size_t blk_n = (size_t)m->fh * MATCH_BLOCK;
    size_t slot, i;
    for (slot = begin; slot < end; slot++) {
        fftwf_complex *blk = m->scratch[slot];
        int b = (int)((size_t)m->nblk * slot / (size_t)job->nslots);
        int b_end = (int)((size_t)m->nblk * (slot + 1) / (size_t)job->nslots);
        for (; b < b_end; b++) {
            fftwf_complex *dst = job->dest + (size_t)b * blk_n;
            match_gather(m, m->rows1, m->ex.height, b, blk);
            fftwf_execute_dft(m->col_fwd, blk, blk);
            for (i = 0; i < blk_n; i++) {
                dst[i][0] = blk[i][0] * job->scale;
                dst[i][1] = blk[i][1] * job->scale;
            }
        }
    }
}

/* Target rows: items [0, ph) are M T' rows into rows1, [ph, 2 ph) are M
 * rows into rows2; forward along x. */
static void match_rows_target(void *arg, size_t begin, size_t end)
{
    const match_job *job = arg;
    const ts_matcher *m = job->m;
    const double mean = m->mean;
    size_t item;
    for (item = begin; item < end; item++) {
        const int mask_row = item >= (size_t)m->ph;
        const int j = (int)(item % (size_t)m->ph);
        fftwf_complex *row = (mask_row ? m->rows2 : m->rows1) + (size_t)j * m->stride;
        float *r = (float *)row;
        const float *src = job->target->data + (ptrdiff_t)j * job->target->stride;
        int i;
        for (i = 0; i < m->pw; i++)
            r[i] = isfinite(src[i]) ? (mask_row ? 1.0f : (float)((double)src[i] - mean)) : 0.0f;
        memset(r + m->pw, 0, (size_t)(2 * m->stride - m->pw) * sizeof *r);
        fftwf_execute_dft_r2c(m->row_r2c, r, row);
    }
}

/* Query column slots: forward along y, product with the exemplar spectra
 * (-2 corr(E', M T') + corr(E'^2, M) in one spectrum), inverse along y,
 * output rows back into rows1. */
static void match_cols_query(void *arg, size_t begin, size_t end)
{
    const match_job *job = arg;
    const ts_matcher *m = job->m;
    const size_t blk_n = (size_t)m->fh * MATCH_BLOCK;
    size_t slot, i;
    for (slot = begin; slot < end; slot++) {
        fftwf_complex *a = m->scratch[slot], *q = a + blk_n;
        int b = (int)((size_t)m->nblk * slot / (size_t)job->nslots);
        int b_end = (int)((size_t)m->nblk * (slot + 1) / (size_t)job->nslots);
        for (; b < b_end; b++) {
            const fftwf_complex *s1 = m->spec1 + (size_t)b * blk_n;
            const fftwf_complex *s2 = m->spec2 + (size_t)b * blk_n;
            const int c0 = b * MATCH_BLOCK, nc = TS_MIN(MATCH_BLOCK, m->cols - c0);
            int y;
            match_gather(m, m->rows1, m->ph, b, a);
            match_gather(m, m->rows2, m->ph, b, q);
            fftwf_execute_dft(m->col_fwd, a, a);
            fftwf_execute_dft(m->col_fwd, q, q);
            for (i = 0; i < blk_n; i++) {
                /* s1 conj(a) + s2 conj(q) */
                const float ar = a[i][0], ai = a[i][1], qr = q[i][0], qi = q[i][1];
                a[i][0] = s1[i][0] * ar + s1[i][1] * ai + s2[i][0] * qr + s2[i][1] * qi;
                a[i][1] = s1[i][1] * ar - s1[i][0] * ai + s2[i][1] * qr - s2[i][0] * qi;
            }
            fftwf_execute_dft(m->col_bwd, a, a);
            for (y = 0; y < m->ny; y++) {
                fftwf_complex *d = m->rows1 + (size_t)y * m->stride + c0;
                int c;
                for (c = 0; c < nc; c++) {
                    d[c][0] = a[(size_t)c * m->fh + (size_t)y][0];
                    d[c][1] = a[(size_t)c * m->fh + (size_t)y][1];
                }
            }
        }
    }
}

/* Output rows [begin, end): inverse along x, add sum M T'^2, mask. */
static void match_rows_output(void *arg, size_t begin, size_t end)
{
    const match_job *job = arg;
    const ts_matcher *m = job->m;
    size_t y;
    for (y = begin; y < end; y++) {
        fftwf_complex *row = m->rows1 + y * (size_t)m->stride;
        float *r = (float *)row;
        float *o = job->out ? job->out + y * (size_t)m->nx : r;
        const unsigned char *v = m->valid + y * (size_t)m->nx;
        int x;
        fftwf_execute_dft_c2r(m->row_c2r, row, r);
        for (x = 0; x < m->nx; x++) {
            double s = job->sum_t2 + r[x];
            o[x] = v[x] ? (s > 0.0 ? (float)s : 0.0f) : INFINITY;
        }
    }
}

/* Run a column phase over the worker slots.  A fixed block partition and
 * one plan per direction make the result independent of the thread count. */
static ts_status match_run_columns(ts_ctx *ctx, ts_matcher *m, match_job *job, ts_range_fn fn)
{
    const int want = match_workers(ctx, (size_t)m->nblk, (size_t)m->cols * (size_t)m->fh);
    int nslots = match_scratch(m, want);
    if (nslots < 1)
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate FFT scratch");
    nslots = TS_MIN(nslots, want);
    job->nslots = nslots;
    ts__parallel_for(ctx, (size_t)nslots, fn, job);
    return TS_OK;
}

/* The SSD map of a checked target with known cells into out (nx * ny),
 * or, if out is NULL, into rows1 (row y at (float *)rows1 + y * 2 * stride,
 * valid until the next query); *sum_t2 = sum M T'^2. */
static ts_status match_map(ts_ctx *ctx, ts_matcher *m, const ts_raster *t, float *out,
                           double *sum_t2)
{
    match_job job;
    ts_status st;
    size_t n_known = 0;
    double s = 0.0;
    int i, j;
    for (j = 0; j < m->ph; j++)
        for (i = 0; i < m->pw; i++) {
            float v = TS_PIX(t, i, j);
            if (isfinite(v)) {
                double d = (double)v - m->mean;
                s += d * d;
                n_known++;
            }
        }
    *sum_t2 = s;
    memset(&job, 0, sizeof job);
    job.m = m;
    job.target = t;
    job.out = out;
    job.sum_t2 = s;
    if (n_known == 0 && out) {
        /* nothing to compare: every valid window matches exactly */
        size_t k, n = (size_t)m->nx * (size_t)m->ny;
        for (k = 0; k < n; k++)
            out[k] = m->valid[k] ? 0.0f : INFINITY;
        return ts__progress(ctx, 1.0, "SSD map");
    }
    match_parallel(ctx, 2 * (size_t)m->ph, (size_t)m->fw, match_rows_target, &job);
    if ((st = ts__progress(ctx, 0.1, "SSD map")) != TS_OK)
        return st;
    if ((st = match_run_columns(ctx, m, &job, match_cols_query)) != TS_OK)
        return st;
    if ((st = ts__progress(ctx, 0.7, "SSD map")) != TS_OK)
        return st;
    match_parallel(ctx, (size_t)m->ny, (size_t)m->fw, match_rows_output, &job);
    return ts__progress(ctx, 1.0, "SSD map");
}

/* Spectrum of E' (square 0) or E'^2 (square 1) into dest, times scale. */
static ts_status match_spectrum(ts_ctx *ctx, ts_matcher *m, int square, fftwf_complex *dest,
                                float scale)
{
    match_job job;
    ts_status st;
    memset(&job, 0, sizeof job);
    job.m = m;
    job.square = square;
    job.dest = dest;
    job.scale = scale;
    match_parallel(ctx, (size_t)m->ex.height, (size_t)m->fw, match_rows_exemplar, &job);
    if ((st = ts__progress(ctx, 0.4, "exemplar spectra")) != TS_OK)
        return st;
    if ((st = match_run_columns(ctx, m, &job, match_cols_exemplar)) != TS_OK)
        return st;
    return ts__progress(ctx, 1.0, "exemplar spectra");
}

static ts_status match_check_target(ts_ctx *ctx, const ts_matcher *m, const ts_raster *t)
{
    if (!m)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing matcher");
    if (!t || !t->data)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing target");
    if (t->width != m->pw || t->height != m->ph)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE,
                        "the target is %d x %d but the matcher was planned for %d x %d patches",
                        t->width, t->height, m->pw, m->ph);
    if (t->stride < t->width)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "target stride %td is below its width %d",
                        t->stride, t->width);
    return TS_OK;
}

/* ---- k best: a stream of map entries, separation, exact rescoring ------ */

typedef struct match_pick {
    float v;    /* float map value */
    size_t idx; /* y * nx + x */
} match_pick;

typedef struct match_exact {
    double e; /* exact SSD */
    size_t idx;
} match_exact;

/* Total orders: by value, ties by index (lower y, then lower x). */
static int match_pick_less(const match_pick *a, const match_pick *b)
{
    return a->v < b->v || (a->v == b->v && a->idx < b->idx);
}

static int match_pick_cmp(const void *a, const void *b)
{
    return match_pick_less(a, b) ? -1 : match_pick_less(b, a);
}

static int match_exact_less(const match_exact *a, const match_exact *b)
{
    return a->e < b->e || (a->e == b->e && a->idx < b->idx);
}

/* Rearrange a[0, n) so that a[k] is the k-th lowest, lower ones before it
 * and higher ones after (quickselect, median-of-three pivots; keys are
 * distinct because indices are). */
static void match_select(match_pick *a, ptrdiff_t n, ptrdiff_t k)
{
    ptrdiff_t lo = 0, hi = n - 1;
    while (hi > lo) {
        const ptrdiff_t mid = lo + (hi - lo) / 2;
        match_pick t, pivot;
        ptrdiff_t i = lo, j = hi;
        if (match_pick_less(&a[mid], &a[lo])) {
            t = a[mid], a[mid] = a[lo], a[lo] = t;
        }
        if (match_pick_less(&a[hi], &a[lo])) {
            t = a[hi], a[hi] = a[lo], a[lo] = t;
        }
        if (match_pick_less(&a[hi], &a[mid])) {
            t = a[hi], a[hi] = a[mid], a[mid] = t;
        }
        pivot = a[mid];
        while (i <= j) {
            while (match_pick_less(&a[i], &pivot))
                i++;
            while (match_pick_less(&pivot, &a[j]))
                j--;
            if (i <= j) {
                t = a[i], a[i] = a[j], a[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            return;
    }
}

/* The cap lowest finite entries of positions [from, to) of the map (row y
 * at map + y * pitch, nx entries) above `after` (NULL: no bound), unsorted,
 * in buf (room for 2 * cap).  Candidates are appended; when buf is full a
 * quickselect keeps the cap lowest and raises the bar: O(1) amortised per
 * entry whatever the order of the values (a smooth map in scan order is
 * the worst case of a bounded heap). */
static size_t match_scan(const float *map, size_t pitch, size_t nx, size_t from, size_t to,
                         size_t cap, const match_pick *after, match_pick *buf)
{
    const float *row = map + from / nx * pitch;
    float bar = INFINITY; /* entries come in index order: the value decides */
    size_t n = 0, i, x = from % nx;
    for (i = from; i < to; i++, x++) {
        match_pick item;
        if (x == nx) {
            x = 0;
            row += pitch;
        }
        item.v = row[x];
        item.idx = i;
        if (!(item.v < bar) || (after && !match_pick_less(after, &item)))
            continue;
        buf[n++] = item;
        if (n == 2 * cap) {
            match_select(buf, (ptrdiff_t)n, (ptrdiff_t)cap - 1);
            n = cap;
            bar = buf[cap - 1].v;
        }
    }
    if (n > cap)
        match_select(buf, (ptrdiff_t)n, (ptrdiff_t)cap - 1);
    return TS_MIN(n, cap);
}

typedef struct match_batch_job {
    const float *map; /* row y at map + y * pitch */
    size_t pitch, nx;
    const match_pick *after;
    size_t npos, cap;
    int nslots;
    match_pick *heaps; /* nslots * 2 * cap: a selection buffer per slice */
    size_t count[MATCH_MAX_SLOTS];
} match_batch_job;

static void match_batch_slot(void *arg, size_t begin, size_t end)
{
    match_batch_job *job = arg;
    size_t slot;
    for (slot = begin; slot < end; slot++)
        job->count[slot] =
            match_scan(job->map, job->pitch, job->nx, job->npos * slot / (size_t)job->nslots,
                       job->npos * (slot + 1) / (size_t)job->nslots, job->cap, job->after,
                       job->heaps + slot * 2 * job->cap);
}

/* Min-heap of exact entries. */
static void match_exact_push(match_exact *h, size_t *n, match_exact item)
{
    size_t c = (*n)++;
    while (c > 0 && match_exact_less(&item, &h[(c - 1) / 2])) {
        h[c] = h[(c - 1) / 2];
        c = (c - 1) / 2;
    }
    h[c] = item;
}

static match_exact match_exact_pop(match_exact *h, size_t *n)
{
    const match_exact top = h[0], item = h[--*n];
    size_t p = 0;
    for (;;) {
        size_t l = 2 * p + 1, small;
        if (l >= *n)
            break;
        small = (l + 1 < *n && match_exact_less(&h[l + 1], &h[l])) ? l + 1 : l;
        if (!match_exact_less(&h[small], &item))
            break;
        h[p] = h[small];
        p = small;
    }
    if (*n > 0)
        h[p] = item;
    return top;
}

/* Taken positions for the Chebyshev separation test.  With sep x sep
 * buckets, two positions in one bucket are closer than sep, so a bucket
 * holds at most one taken position: a hash keyed by bucket finds the
 * candidates in the 3 x 3 neighbouring buckets in O(1). */
typedef struct match_sep {
    int sep;
    int64_t gx;   /* buckets per row */
    size_t cap;   /* power of two >= 2 * max taken */
    int64_t *key; /* bucket id, -1 = empty */
    int *px, *py; /* the taken position in that slot */
} match_sep;

static ts_status match_sep_init(match_sep *s, int sep, int nx, int k)
{
    size_t cap = 16, i;
    memset(s, 0, sizeof *s);
    s->sep = sep;
    if (sep <= 1)
        return TS_OK;
    s->gx = (nx + (int64_t)sep - 1) / sep;
    while (cap < 2 * (size_t)k)
        cap *= 2;
    s->cap = cap;
    s->key = ts__malloc_array(cap, sizeof *s->key);
    s->px = ts__malloc_array(cap, sizeof *s->px);
    s->py = ts__malloc_array(cap, sizeof *s->py);
    if (!s->key || !s->px || !s->py)
        return TS_ERR_NOMEM;
    for (i = 0; i < cap; i++)
        s->key[i] = -1;
    return TS_OK;
}

static void match_sep_free(match_sep *s)
{
    free(s->key);
    free(s->px);
    free(s->py);
}

static size_t match_sep_slot(const match_sep *s, int64_t key)
{
    size_t h = (size_t)(((uint64_t)key * 0x9e3779b97f4a7c15ull) >> 20) & (s->cap - 1);
    while (s->key[h] != -1 && s->key[h] != key)
        h = (h + 1) & (s->cap - 1);
    return h;
}

/* 1 if position idx is at least sep from every taken position. */
static int match_sep_ok(const match_sep *s, int nx, size_t idx)
{
    const int x = (int)(idx % (size_t)nx), y = (int)(idx / (size_t)nx);
    int64_t bx, by, dx, dy;
    if (s->sep <= 1)
        return 1;
    bx = x / s->sep;
    by = y / s->sep;
    for (dy = -1; dy <= 1; dy++)
        for (dx = -1; dx <= 1; dx++) {
            size_t h;
            if (bx + dx < 0 || by + dy < 0 || bx + dx >= s->gx)
                continue;
            h = match_sep_slot(s, (by + dy) * s->gx + bx + dx);
            if (s->key[h] != -1 && abs(s->px[h] - x) < s->sep && abs(s->py[h] - y) < s->sep)
                return 0;
        }
    return 1;
}

/* The added cost of position idx (0 without a cost map). */
static double match_cost(const ts_matcher *m, size_t idx)
{
    return m->cost ? m->cost_w * (double)m->cost[idx] : 0.0;
}

/* Add the cost map to the float SSD map left in rows1; returns the
 * largest cost added. */
static double match_add_cost(const ts_matcher *m)
{
    const size_t pitch = 2 * (size_t)m->stride;
    float *map = (float *)m->rows1;
    double most = 0.0;
    int x, y;
    if (!m->cost)
        return 0.0;
    for (y = 0; y < m->ny; y++)
        for (x = 0; x < m->nx; x++) {
            const double c = match_cost(m, (size_t)y * (size_t)m->nx + (size_t)x);
            float *v = map + (size_t)y * pitch + (size_t)x;
            if (isfinite(*v))
                *v = (float)((double)*v + c);
            most = c > most ? c : most;
        }
    return most;
}

/* Take position idx if it is far enough from the taken ones. */
static int match_take(match_sep *s, int nx, size_t idx, double ssd, ts_candidate *out, int *nt)
{
    if (!match_sep_ok(s, nx, idx))
        return 0;
    out[*nt].x = (int)(idx % (size_t)nx);
    out[*nt].y = (int)(idx / (size_t)nx);
    out[*nt].ssd = ssd;
    (*nt)++;
    if (s->sep > 1) {
        const int64_t key = (int64_t)(out[*nt - 1].y / s->sep) * s->gx + out[*nt - 1].x / s->sep;
        const size_t h = match_sep_slot(s, key);
        s->key[h] = key;
        s->px[h] = out[*nt - 1].x;
        s->py[h] = out[*nt - 1].y;
    }
    return 1;
}

/* Known target cells as offsets into the exemplar and values in double. */
typedef struct match_known {
    size_t n;
    ptrdiff_t *off;
    double *val;
} match_known;

static ts_status match_known_init(match_known *kn, const ts_matcher *m, const ts_raster *t)
{
    int i, j;
    kn->n = 0;
    kn->off = ts__malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->off);
    kn->val = ts__malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->val);
    if (!kn->off || !kn->val)
        return TS_ERR_NOMEM;
    for (j = 0; j < m->ph; j++)
        for (i = 0; i < m->pw; i++)
            if (isfinite(TS_PIX(t, i, j))) {
                kn->off[kn->n] = (ptrdiff_t)j * m->ex.stride + i;
                kn->val[kn->n] = TS_PIX(t, i, j);
                kn->n++;
            }
    return TS_OK;
}

static void match_known_free(match_known *kn)
{
    free(kn->off);
    free(kn->val);
}

/* The exact SSD of window idx, in double, in the target's row-major order. */
static double match_exact_ssd(const ts_matcher *m, const match_known *kn, size_t idx)
{
    const float *e = m->ex.data + (ptrdiff_t)(idx / (size_t)m->nx) * m->ex.stride +
                     (ptrdiff_t)(idx % (size_t)m->nx);
    double s = 0.0;
    size_t c;
    for (c = 0; c < kn->n; c++) {
        const double d = kn->val[c] - e[kn->off[c]];
        s += d * d;
    }
    return s;
}

/* qsort's order of match_exact_less. */
static int match_exact_cmp(const void *a, const void *b)
{
    return match_exact_less(a, b) ? -1 : match_exact_less(b, a);
}

/* No known target cell: every valid window has SSD 0; take them in
 * row-major order, or with a cost map in order of cost (then index); -1
 * when out of memory. */
static int match_best_empty(const ts_matcher *m, match_sep *s, int k, ts_candidate *out)
{
    const size_t n = (size_t)m->nx * (size_t)m->ny;
    size_t i, nv = 0;
    match_exact *order;
    int nt = 0;
    if (!m->cost) {
        for (i = 0; i < n && nt < k; i++)
            if (m->valid[i])
                match_take(s, m->nx, i, 0.0, out, &nt);
        return nt;
    }
    if (!(order = ts__malloc_array(n, sizeof *order)))
        return -1;
    for (i = 0; i < n; i++)
        if (m->valid[i])
            order[nv++] = (match_exact){match_cost(m, i), i};
    qsort(order, nv, sizeof *order, match_exact_cmp);
    for (i = 0; i < nv && nt < k; i++)
        match_take(s, m->nx, order[i].idx, order[i].e, out, &nt);
    free(order);
    return nt;
}

/*
 * The greedy k best in exact order (exact SSD, then index), reading the
 * float map as a stream in (value, index) order with |map - exact| <=
 * delta.  Rescored entries wait in a heap; the lowest is decided (taken if
 * far enough from the taken ones, else dropped) once it is below the next
 * stream value minus delta, as no unseen window can then precede it.  A
 * stream entry already too close to a taken window is dropped unscored:
 * that window precedes it, so the full greedy would drop it too.  The
 * stream comes in batches of the cap lowest entries above the last one
 * read (one pass over the map per batch, cap x 4 each time).
 */
static ts_status match_best_search(ts_ctx *ctx, const ts_matcher *m, const match_known *kn,
                                   double delta, match_sep *s, int k, ts_candidate *out,
                                   int *n_found)
{
    const size_t npos = (size_t)m->nx * (size_t)m->ny;
    const int nslots = TS_MIN(match_workers(ctx, npos, npos), MATCH_MAX_SLOTS);
    size_t cap = TS_MIN(m->n_valid, 1024 + 64 * (size_t)k);
    match_batch_job *job = malloc(sizeof *job);
    match_exact *wait = NULL;
    size_t n_wait = 0, cap_wait = 0;
    match_pick last;
    int have_last = 0, nt = 0, exhausted = 0;
    ts_status st = TS_OK;
    if (!job)
        return TS_ERR_NOMEM;
    job->heaps = NULL;
    while (st == TS_OK && nt < k && !exhausted) {
        size_t n = 0, i, slot;
        job->map = (const float *)m->rows1; /* where match_map left it */
        job->pitch = 2 * (size_t)m->stride;
        job->nx = (size_t)m->nx;
        job->after = have_last ? &last : NULL;
        job->npos = npos;
        job->cap = cap;
        job->nslots = cap > npos / 16 ? 1 : nslots; /* big batches: one slice, bounded memory */
        free(job->heaps);
        job->heaps = ts__malloc_array((size_t)job->nslots * 2 * cap, sizeof *job->heaps);
        if (!job->heaps) {
            st = TS_ERR_NOMEM;
            break;
        }
        if (job->nslots > 1)
            ts__parallel_for(ctx, (size_t)job->nslots, match_batch_slot, job);
        else
            match_batch_slot(job, 0, 1);
        /* the union of the slices' cap lowest holds the cap lowest overall */
        for (slot = 0; slot < (size_t)job->nslots; slot++) {
            memmove(job->heaps + n, job->heaps + slot * 2 * cap,
                    job->count[slot] * sizeof *job->heaps);
            n += job->count[slot];
        }
        qsort(job->heaps, n, sizeof *job->heaps, match_pick_cmp);
        exhausted = n < cap; /* every remaining entry is in this batch */
        n = TS_MIN(n, cap);
        for (i = 0; i < n && nt < k; i++) {
            const match_pick p = job->heaps[i];
            last = p;
            have_last = 1;
            while (n_wait > 0 && nt < k && wait[0].e < (double)p.v - delta) {
                const match_exact a = match_exact_pop(wait, &n_wait);
                match_take(s, m->nx, a.idx, a.e, out, &nt);
            }
            if (nt == k || !match_sep_ok(s, m->nx, p.idx))
                continue;
            if (n_wait == cap_wait) {
                size_t grow = cap_wait ? 2 * cap_wait : 256;
                match_exact *w = realloc(wait, grow * sizeof *w);
                if (!w) {
                    st = TS_ERR_NOMEM;
                    break;
                }
                wait = w;
                cap_wait = grow;
            }
            match_exact_push(
                wait, &n_wait,
                (match_exact){match_exact_ssd(m, kn, p.idx) + match_cost(m, p.idx), p.idx});
        }
        cap = cap > m->n_valid / 4 ? m->n_valid : 4 * cap;
    }
    /* the stream is exhausted: what waits is in exact order */
    while (st == TS_OK && nt < k && n_wait > 0) {
        const match_exact a = match_exact_pop(wait, &n_wait);
        match_take(s, m->nx, a.idx, a.e, out, &nt);
    }
    if (st == TS_OK)
        *n_found = nt;
    free(job->heaps);
    free(job);
    free(wait);
    return st;
}

/* ---- public API -------------------------------------------------------- */

ts_status ts__matcher_set_allowed(ts_ctx *ctx, ts_matcher *m, const unsigned char *allowed)
{
    size_t n = (size_t)m->nx * (size_t)m->ny, i, k = 0;
    unsigned char *a;
    ts__matcher_restrict(m, 0);
    free(m->allowed);
    m->allowed = NULL;
    m->n_allowed = 0;
    if (!allowed)
        return TS_OK;
    if (!(a = ts__malloc_array(n, 1)))
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "out of memory");
    for (i = 0; i < n; i++) {
        a[i] = m->all_valid[i] && allowed[i];
        k += a[i];
    }
    if (k == 0) {
        free(a); /* nothing would be left: no restriction */
        return TS_OK;
    }
    m->allowed = a;
    m->n_allowed = k;
    return TS_OK;
}

void ts__matcher_cost(ts_matcher *m, const float *cost, double weight)
{
    m->cost = weight > 0 ? cost : NULL;
    m->cost_w = weight;
}

int ts__matcher_restrict(ts_matcher *m, int on)
{
    int was = m->valid != m->all_valid;
    if (on && m->allowed) {
        m->valid = m->allowed;
        m->n_valid = m->n_allowed;
    } else {
        m->valid = m->all_valid;
        m->n_valid = m->n_all_valid;
    }
    return was;
}

TS_API void ts_matcher_free(ts_matcher *m)
{
    int i;
    if (!m)
        return;
    ts__fft_destroy(m->row_r2c);
    ts__fft_destroy(m->row_c2r);
    ts__fft_destroy(m->col_fwd);
    ts__fft_destroy(m->col_bwd);
    for (i = 0; i < m->n_scratch; i++)
        ts__fft_free(m->scratch[i]);
    ts__fft_free(m->spec1);
    ts__fft_free(m->spec2);
    ts__fft_free(m->rows1);
    ts__fft_free(m->rows2);
    free(m->all_valid);
    free(m->allowed);
    free(m);
}

TS_API ts_status ts_matcher_new(ts_ctx *ctx, const ts_raster *exemplar, int patch_w, int patch_h,
                                ts_matcher **out)
{
    ts_matcher *m;
    ts_status st;
    ts_progress_saved saved;
    size_t fw, fh, spec_n;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output pointer");
    *out = NULL;
    if (!exemplar || !exemplar->data)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing exemplar");
    if (exemplar->width < 1 || exemplar->height < 1)
        return ts__fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is empty",
                        exemplar->width, exemplar->height);
    if (exemplar->stride < exemplar->width)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "exemplar stride %td is below its width %d",
                        exemplar->stride, exemplar->width);
    if (patch_w < 1 || patch_h < 1)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "patch size %d x %d is not positive", patch_w,
                        patch_h);
    if (patch_w > exemplar->width || patch_h > exemplar->height)
        return ts__fail(ctx, TS_ERR_SIZE, MATCH_STAGE,
                        "the exemplar (%d x %d) is smaller than a patch (%d x %d)", exemplar->width,
                        exemplar->height, patch_w, patch_h);
    fw = ts__fft_good_size((size_t)exemplar->width);
    fh = ts__fft_good_size((size_t)exemplar->height);
    if (fw == 0 || fh == 0 || fw / 2 + 1 > (size_t)INT32_MAX - MATCH_BLOCK)
        return ts__fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is too large",
                        exemplar->width, exemplar->height);

    m = calloc(1, sizeof *m);
    if (!m)
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate a matcher");
    m->ex = *exemplar;
    m->pw = patch_w;
    m->ph = patch_h;
    m->nx = exemplar->width - patch_w + 1;
    m->ny = exemplar->height - patch_h + 1;
    m->fw = (int)fw;
    m->fh = (int)fh;
    m->cols = (int)(fw / 2 + 1);
    m->nblk = (m->cols + MATCH_BLOCK - 1) / MATCH_BLOCK;
    m->stride = m->nblk * MATCH_BLOCK;
    if ((st = match_validity(ctx, m)) != TS_OK) {
        ts_matcher_free(m);
        return st;
    }

    spec_n = (size_t)m->nblk * MATCH_BLOCK; /* = stride; overflow-checked below */
    if (spec_n > SIZE_MAX / fh) {
        ts_matcher_free(m);
        return ts__fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is too large",
                        exemplar->width, exemplar->height);
    }
    spec_n *= fh;
    m->spec1 = ts__fft_alloc(spec_n, sizeof(fftwf_complex));
    m->spec2 = ts__fft_alloc(spec_n, sizeof(fftwf_complex));
    m->rows1 = ts__fft_alloc((size_t)exemplar->height * (size_t)m->stride, sizeof(fftwf_complex));
    m->rows2 = ts__fft_alloc((size_t)patch_h * (size_t)m->stride, sizeof(fftwf_complex));
    if (!m->spec1 || !m->spec2 || !m->rows1 || !m->rows2 || match_scratch(m, 1) < 1) {
        ts_matcher_free(m);
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE,
                        "cannot allocate FFT buffers for a %d x %d exemplar (%zu x %zu padded)",
                        exemplar->width, exemplar->height, fw, fh);
    }
    m->row_r2c = ts__fft_plan_row_r2c(m->fw, m->rows1);
    m->row_c2r = ts__fft_plan_row_c2r(m->fw, m->rows1);
    m->col_fwd = ts__fft_plan_columns(m->fh, MATCH_BLOCK, m->scratch[0], FFTW_FORWARD);
    m->col_bwd = ts__fft_plan_columns(m->fh, MATCH_BLOCK, m->scratch[0], FFTW_BACKWARD);
    if (!m->row_r2c || !m->row_c2r || !m->col_fwd || !m->col_bwd ||
        fftwf_alignment_of((float *)m->rows2) != fftwf_alignment_of((float *)m->rows1)) {
        ts_matcher_free(m);
        return ts__fail(ctx, TS_ERR_INTERNAL, MATCH_STAGE, "FFTW cannot plan %zu x %zu transforms",
                        fw, fh);
    }

    /* -2/F and 1/F: the inverse is unnormalised, and the query spectrum is
     * then s1 conj(F(M T')) + s2 conj(F(M)) with nothing else to scale. */
    saved = ts__progress_push(ctx, 0.0, 0.5);
    st = match_spectrum(ctx, m, 0, m->spec1, (float)(-2.0 / ((double)fw * (double)fh)));
    ts__progress_pop(ctx, saved);
    if (st == TS_OK) {
        saved = ts__progress_push(ctx, 0.5, 1.0);
        st = match_spectrum(ctx, m, 1, m->spec2, (float)(1.0 / ((double)fw * (double)fh)));
        ts__progress_pop(ctx, saved);
    }
    if (st != TS_OK) {
        ts_matcher_free(m);
        return st;
    }
    *out = m;
    return TS_OK;
}

TS_API void ts_matcher_positions(const ts_matcher *m, int *nx, int *ny)
{
    if (nx)
        *nx = m ? m->nx : 0;
    if (ny)
        *ny = m ? m->ny : 0;
}

TS_API ts_status ts_matcher_ssd(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, float *out)
{
    ts_status st;
    double sum_t2;
    ts__clear(ctx);
    if ((st = match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output map");
    return match_map(ctx, m, target, out, &sum_t2);
}

TS_API ts_status ts_matcher_best(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, int k,
                                 int min_separation, ts_candidate *out, int *n_found)
{
    ts_status st;
    match_sep sep;
    match_known kn = {0, NULL, NULL};
    double sum_t2 = 0.0, delta;
    ts_progress_saved saved;
    ts__clear(ctx);
    if (n_found)
        *n_found = 0;
    if ((st = match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (k < 1)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "k must be at least 1, got %d", k);
    if (min_separation < 0)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "min_separation must be >= 0, got %d",
                        min_separation);
    if (!out || !n_found)
        return ts__fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output candidates");
    if (match_sep_init(&sep, min_separation, m->nx, k) != TS_OK ||
        match_known_init(&kn, m, target) != TS_OK) {
        match_sep_free(&sep);
        match_known_free(&kn);
        return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate for k = %d", k);
    }
    if (kn.n == 0) {
        int nt = match_best_empty(m, &sep, k, out);
        match_sep_free(&sep);
        match_known_free(&kn);
        if (nt < 0)
            return ts__fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate for k = %d", k);
        *n_found = nt;
        return ts__progress(ctx, 1.0, "best candidates");
    }
    saved = ts__progress_push(ctx, 0.0, 0.9);
    st = match_map(ctx, m, target, NULL, &sum_t2);
    ts__progress_pop(ctx, saved);
    if (st == TS_OK) {
        delta = MATCH_FLOAT_ERR * (sum_t2 + (double)kn.n * m->max_dev2 + match_add_cost(m));
        st = match_best_search(ctx, m, &kn, delta, &sep, k, out, n_found);
        if (st != TS_OK)
            st = ts__fail(ctx, st, MATCH_STAGE, "cannot allocate the candidate stream");
        else
            st = ts__progress(ctx, 1.0, "best candidates");
    }
    match_sep_free(&sep);
    match_known_free(&kn);
    return st;
}
