/*
 * match_ssd.c - masked SSD of a patch against every window of an exemplar,
 * by FFT, and the k best separated candidates (Zhou et al. 2007 section 4.2).
 *
 * SSD(x,y) = sum M T'^2 - 2 corr(E', M T')(x,y) + corr(E'^2, M)(x,y) with
 * M = 1 on known target cells, E' = E - mean(E), T' = T - mean(E) (the
 * shift leaves the SSD unchanged and keeps float cancellation small).  The
 * spectra of E' and E'^2 are made once; a query is two forward transforms
 * of inputs with only patch_h nonzero rows, a product and one inverse:
 * O(F log F), F = fw * fh padded cells (fw >= W, fh >= H, 7-smooth).
 * ts_matcher_best rescores its candidates exactly in double.
 * Memory: ~13 bytes per padded cell (two half spectra 8, an H-row buffer 4,
 * validity 1): ~220 MB for a 4096 x 4096 exemplar.  Thread-safety: one
 * thread per matcher at a time; FFTW planning runs under fft.c's mutex.
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
    ts_raster ex;      /* borrowed */
    int pw, ph;        /* patch size */
    int nx, ny;        /* window positions */
    int fw, fh;        /* padded transform size */
    int cols;          /* fw / 2 + 1 complex columns of a half spectrum */
    int stride;        /* row stride of rows1/rows2, complex: cols rounded up to a block */
    int nblk;          /* column blocks */
    double mean;       /* mean of the exemplar's valid cells */
    double max_dev2;   /* max (E - mean)^2 over valid cells */
    size_t n_valid;    /* windows free of nodata */
    unsigned char *valid; /* nx * ny: 1 where the window is free of nodata */
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
    int square;           /* exemplar rows: 0 = E', 1 = E'^2 */
    fftwf_complex *dest;  /* exemplar columns: blocked spectrum */
    float scale;          /* exemplar columns: factor applied to the spectrum */
    float *out;           /* query: the SSD map */
    double sum_t2;        /* query: sum M T'^2 */
    int nslots;           /* column phases: worker slots */
} match_job;

/* ---- parallel helpers ---------------------------------------------------- */

/* Cells of work per worker below which a thread costs more than it saves. */
#define MATCH_MIN_WORK ((size_t)1 << 17)

/* Workers for n_items items of total_cost cells: ts_thread_count, but at
 * most one per MATCH_MIN_WORK cells. */
static int match_workers(const ts_ctx *ctx, size_t n_items, size_t total_cost)
{
    const size_t by_work = total_cost / MATCH_MIN_WORK;
    const int nt = ts_thread_count(ctx, n_items);
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
        ts_parallel_for(ctx, g.groups, match_group_run, &g);
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
        return ts_fail(ctx, TS_ERR_NUMERIC, MATCH_STAGE, "every exemplar cell is nodata");
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

    m->valid = ts_malloc_array((size_t)m->nx * (size_t)m->ny, 1);
    colcnt = ts_calloc_array((size_t)w, sizeof *colcnt);
    if (!m->valid || !colcnt) {
        free(colcnt);
        return ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate the validity map");
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
    m->n_valid = n_valid;
    if (n_valid == 0)
        return ts_fail(ctx, TS_ERR_NUMERIC, MATCH_STAGE,
                       "no %d x %d window of the exemplar is free of nodata", m->pw, m->ph);
    return TS_OK;
}

/* ---- transforms: rows, then column blocks ------------------------------ */

/* Worker scratch for up to `want` slots; returns how many exist (>= 1
 * once the matcher is built). */
static int match_scratch(ts_matcher *m, int want)
{
    while (m->n_scratch < want && m->n_scratch < MATCH_MAX_SLOTS) {
        fftwf_complex *p = ts_fft_alloc(2 * (size_t)m->fh * MATCH_BLOCK, sizeof *p);
        if (!p)
            break;
        if (m->n_scratch > 0 && fftwf_alignment_of((float *)p) !=
                                    fftwf_alignment_of((float *)m->scratch[0])) {
            ts_fft_free(p); /* cannot happen with fftwf_malloc; never run a plan misaligned */
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
        float *o = job->out + y * (size_t)m->nx;
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
        return ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate FFT scratch");
    nslots = TS_MIN(nslots, want);
    job->nslots = nslots;
    ts_parallel_for(ctx, (size_t)nslots, fn, job);
    return TS_OK;
}

/* The SSD map of a checked target into out (nx * ny); *sum_t2 = sum M T'^2. */
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
    if (n_known == 0) {
        /* nothing to compare: every valid window matches exactly */
        size_t k, n = (size_t)m->nx * (size_t)m->ny;
        for (k = 0; k < n; k++)
            out[k] = m->valid[k] ? 0.0f : INFINITY;
        return ts_progress(ctx, 1.0, "SSD map");
    }
    match_parallel(ctx, 2 * (size_t)m->ph, (size_t)m->fw, match_rows_target, &job);
    if ((st = ts_progress(ctx, 0.1, "SSD map")) != TS_OK)
        return st;
    if ((st = match_run_columns(ctx, m, &job, match_cols_query)) != TS_OK)
        return st;
    if ((st = ts_progress(ctx, 0.7, "SSD map")) != TS_OK)
        return st;
    match_parallel(ctx, (size_t)m->ny, (size_t)m->fw, match_rows_output, &job);
    return ts_progress(ctx, 1.0, "SSD map");
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
    if ((st = ts_progress(ctx, 0.4, "exemplar spectra")) != TS_OK)
        return st;
    if ((st = match_run_columns(ctx, m, &job, match_cols_exemplar)) != TS_OK)
        return st;
    return ts_progress(ctx, 1.0, "exemplar spectra");
}

static ts_status match_check_target(ts_ctx *ctx, const ts_matcher *m, const ts_raster *t)
{
    if (!m)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing matcher");
    if (!t || !t->data)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing target");
    if (t->width != m->pw || t->height != m->ph)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE,
                       "the target is %d x %d but the matcher was planned for %d x %d patches",
                       t->width, t->height, m->pw, m->ph);
    if (t->stride < t->width)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "target stride %td is below its width %d",
                       t->stride, t->width);
    return TS_OK;
}

/* ---- k best: pool, separation, exact rescoring ------------------------- */

typedef struct match_pick {
    float v;
    size_t idx; /* y * nx + x */
} match_pick;

typedef struct match_exact {
    double e;
    size_t idx;
} match_exact;

static int match_pick_cmp(const void *pa, const void *pb)
{
    const match_pick *a = pa, *b = pb;
    if (a->v != b->v)
        return a->v < b->v ? -1 : 1;
    return (a->idx > b->idx) - (a->idx < b->idx);
}

static int match_exact_cmp(const void *pa, const void *pb)
{
    const match_exact *a = pa, *b = pb;
    if (a->e != b->e)
        return a->e < b->e ? -1 : 1;
    return (a->idx > b->idx) - (a->idx < b->idx);
}

static int match_pick_greater(const match_pick *a, const match_pick *b)
{
    return a->v > b->v || (a->v == b->v && a->idx > b->idx);
}

/* The cap lowest finite entries of map[from, to) by (value, index), in a
 * bounded max-heap (unsorted); *n_finite = finite entries seen. */
static size_t match_heap_scan(const float *map, size_t from, size_t to, size_t cap,
                              match_pick *heap, size_t *n_finite)
{
    size_t n = 0, nf = 0, i, c, p;
    for (i = from; i < to; i++) {
        const float v = map[i];
        if (!(v < INFINITY))
            continue;
        nf++;
        if (n < cap) {
            const match_pick item = {v, i};
            c = n++;
            while (c > 0 && match_pick_greater(&item, &heap[(c - 1) / 2])) {
                heap[c] = heap[(c - 1) / 2];
                c = (c - 1) / 2;
            }
            heap[c] = item;
        } else if (v < heap[0].v) {
            /* below the largest kept entry: i exceeds every kept index, so
             * only the value decides.  Replace the top and sift down. */
            const match_pick item = {v, i};
            p = 0;
            for (;;) {
                size_t l = 2 * p + 1, big;
                if (l >= n)
                    break;
                big = (l + 1 < n && match_pick_greater(&heap[l + 1], &heap[l])) ? l + 1 : l;
                if (!match_pick_greater(&heap[big], &item))
                    break;
                heap[p] = heap[big];
                p = big;
            }
            heap[p] = item;
        }
    }
    *n_finite = nf;
    return n;
}

typedef struct match_pool_job {
    const float *map;
    size_t npos, cap;
    int nslots;
    match_pick *heaps;     /* nslots * cap */
    size_t *count, *finite; /* per slot */
} match_pool_job;

static void match_pool_slot(void *arg, size_t begin, size_t end)
{
    const match_pool_job *job = arg;
    size_t slot;
    for (slot = begin; slot < end; slot++)
        job->count[slot] = match_heap_scan(
            job->map, job->npos * slot / (size_t)job->nslots,
            job->npos * (slot + 1) / (size_t)job->nslots, job->cap, job->heaps + slot * job->cap,
            &job->finite[slot]);
}

/* The cap lowest finite map entries, sorted by (value, index), into
 * pool[0 ..] (room for nslots * cap entries: one heap per worker, each
 * over a slice of the map; the union holds the cap lowest of all, a set
 * that does not depend on the slicing).  *n_finite = finite entries. */
static size_t match_pool(ts_ctx *ctx, const float *map, size_t npos, size_t cap, int nslots,
                         match_pick *pool, size_t *n_finite)
{
    match_pool_job job;
    size_t count[MATCH_MAX_SLOTS], finite[MATCH_MAX_SLOTS], n = 0;
    int slot;
    job.map = map;
    job.npos = npos;
    job.cap = cap;
    job.nslots = nslots;
    job.heaps = pool;
    job.count = count;
    job.finite = finite;
    if (nslots > 1)
        ts_parallel_for(ctx, (size_t)nslots, match_pool_slot, &job);
    else
        match_pool_slot(&job, 0, 1);
    *n_finite = 0;
    for (slot = 0; slot < nslots; slot++) {
        memmove(pool + n, pool + (size_t)slot * cap, count[slot] * sizeof *pool);
        n += count[slot];
        *n_finite += finite[slot];
    }
    qsort(pool, n, sizeof *pool, match_pick_cmp);
    return TS_MIN(n, cap);
}

/* Taken positions for the Chebyshev separation test.  With sep x sep
 * buckets, two positions in one bucket are closer than sep, so a bucket
 * holds at most one taken position: a hash keyed by bucket finds the
 * candidates in the 3 x 3 neighbouring buckets in O(1). */
typedef struct match_sep {
    int sep;
    int64_t gx;     /* buckets per row */
    size_t cap;     /* power of two >= 2 * max taken */
    int64_t *key;   /* bucket id, -1 = empty */
    int *px, *py;   /* the taken position in that slot */
} match_sep;

static ts_status match_sep_init(match_sep *s, int sep, int nx, int k)
{
    size_t cap = 16;
    memset(s, 0, sizeof *s);
    s->sep = sep;
    if (sep <= 1)
        return TS_OK;
    s->gx = (nx + (int64_t)sep - 1) / sep;
    while (cap < 2 * (size_t)k)
        cap *= 2;
    s->cap = cap;
    s->key = ts_malloc_array(cap, sizeof *s->key);
    s->px = ts_malloc_array(cap, sizeof *s->px);
    s->py = ts_malloc_array(cap, sizeof *s->py);
    return (s->key && s->px && s->py) ? TS_OK : TS_ERR_NOMEM;
}

static void match_sep_free(match_sep *s)
{
    free(s->key);
    free(s->px);
    free(s->py);
}

static void match_sep_reset(match_sep *s)
{
    size_t i;
    for (i = 0; i < s->cap; i++)
        s->key[i] = -1;
}

static size_t match_sep_slot(const match_sep *s, int64_t key)
{
    size_t h = (size_t)(((uint64_t)key * 0x9e3779b97f4a7c15ull) >> 20) & (s->cap - 1);
    while (s->key[h] != -1 && s->key[h] != key)
        h = (h + 1) & (s->cap - 1);
    return h;
}

/* 1 if (x, y) is at least sep from every taken position. */
static int match_sep_ok(const match_sep *s, int x, int y)
{
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

static void match_sep_add(match_sep *s, int x, int y)
{
    size_t h;
    if (s->sep <= 1)
        return;
    h = match_sep_slot(s, (int64_t)(y / s->sep) * s->gx + x / s->sep);
    s->key[h] = (int64_t)(y / s->sep) * s->gx + x / s->sep;
    s->px[h] = x;
    s->py[h] = y;
}

/* Greedy selection over positions in the given order: take a position if
 * it is far enough from all taken ones, up to k.  taken[] receives indices
 * into order[]; returns how many were taken. */
static int match_greedy(match_sep *s, const size_t *order, size_t n, int nx, int k,
                        size_t *taken)
{
    size_t i;
    int nt = 0;
    if (s->sep > 1)
        match_sep_reset(s);
    for (i = 0; i < n && nt < k; i++) {
        const int x = (int)(order[i] % (size_t)nx), y = (int)(order[i] / (size_t)nx);
        if (!match_sep_ok(s, x, y))
            continue;
        match_sep_add(s, x, y);
        taken[nt++] = i;
    }
    return nt;
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
    kn->off = ts_malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->off);
    kn->val = ts_malloc_array((size_t)m->pw * (size_t)m->ph, sizeof *kn->val);
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

/* Exact rescoring of pool entries [begin, end) in double. */
typedef struct match_rescore_job {
    const ts_matcher *m;
    const match_known *kn;
    const match_pick *pool;
    double *exact;
    size_t base;
} match_rescore_job;

static void match_rescore(void *arg, size_t begin, size_t end)
{
    const match_rescore_job *job = arg;
    const ts_matcher *m = job->m;
    size_t i, c;
    for (i = job->base + begin; i < job->base + end; i++) {
        const size_t idx = job->pool[i].idx;
        const float *e = m->ex.data + (ptrdiff_t)(idx / (size_t)m->nx) * m->ex.stride +
                         (ptrdiff_t)(idx % (size_t)m->nx);
        double s = 0.0;
        for (c = 0; c < job->kn->n; c++) {
            const double d = job->kn->val[c] - e[job->kn->off[c]];
            s += d * d;
        }
        job->exact[i] = s;
    }
}

/* No known target cell: every valid window has SSD 0; take them in
 * row-major order. */
static int match_best_empty(const ts_matcher *m, match_sep *s, int k, ts_candidate *out)
{
    const size_t n = (size_t)m->nx * (size_t)m->ny;
    size_t i;
    int nt = 0;
    if (s->sep > 1)
        match_sep_reset(s);
    for (i = 0; i < n && nt < k; i++) {
        const int x = (int)(i % (size_t)m->nx), y = (int)(i / (size_t)m->nx);
        if (!m->valid[i] || !match_sep_ok(s, x, y))
            continue;
        match_sep_add(s, x, y);
        out[nt].x = x;
        out[nt].y = y;
        out[nt].ssd = 0.0;
        nt++;
    }
    return nt;
}

/*
 * Greedy k best on exact SSDs without rescoring every window.  With
 * |map - exact| <= delta, let R = {map <= tau}: positions outside R have
 * exact > tau - delta, so if the greedy on R (exact order) takes k
 * positions with the k-th at e_k <= tau - delta, it equals the greedy over
 * all windows.  tau starts at the k-th float-greedy value + 2 delta and
 * grows (with the pool of lowest map values) until that holds.
 */
static ts_status match_best_search(ts_ctx *ctx, const ts_matcher *m, const float *map,
                                   const match_known *kn, double delta, match_sep *s, int k,
                                   ts_candidate *out, int *n_found)
{
    const size_t npos = (size_t)m->nx * (size_t)m->ny;
    const double sep = s->sep > 1 ? s->sep : 1;
    double want = 4.0 * k * sep * sep + 1024.0;
    size_t cap = want < (double)m->n_valid ? (size_t)want : m->n_valid;
    const int nslots = TS_MIN(match_workers(ctx, npos, npos), MATCH_MAX_SLOTS);
    match_pick *pool = NULL;
    match_exact *rs = NULL;
    double *exact = NULL;
    size_t *order = NULL, *taken = NULL;
    ts_status st = TS_OK;
    int done = 0, nt = 0, i;

    taken = ts_malloc_array((size_t)k, sizeof *taken);
    if (!taken)
        return TS_ERR_NOMEM;
    while (!done) {
        size_t n_pool, n_finite, n_exact = 0, r = 0;
        int complete, na, ns;
        double tau;
        free(pool);
        free(rs);
        free(exact);
        free(order);
        ns = cap > npos / 16 ? 1 : nslots; /* big pools: one heap, bounded memory */
        pool = ts_malloc_array((size_t)ns * cap, sizeof *pool);
        rs = ts_malloc_array(cap, sizeof *rs);
        exact = ts_malloc_array(cap, sizeof *exact);
        order = ts_malloc_array(cap, sizeof *order);
        if (!pool || !rs || !exact || !order) {
            st = TS_ERR_NOMEM;
            break;
        }
        n_pool = match_pool(ctx, map, npos, cap, ns, pool, &n_finite);
        complete = n_pool == n_finite;
        for (r = 0; r < n_pool; r++)
            order[r] = pool[r].idx;
        na = match_greedy(s, order, n_pool, m->nx, k, taken);
        tau = na == k ? (double)pool[taken[k - 1]].v + 2.0 * delta : INFINITY;
        r = 0;
        for (;;) {
            match_rescore_job job;
            size_t q;
            while (r < n_pool && pool[r].v <= tau)
                r++;
            if (r == n_pool && !complete)
                break; /* windows outside the pool may be below tau */
            job.m = m;
            job.kn = kn;
            job.pool = pool;
            job.exact = exact;
            job.base = n_exact;
            match_parallel(ctx, r - n_exact, kn->n, match_rescore, &job);
            n_exact = r;
            for (q = 0; q < r; q++) {
                rs[q].e = exact[q];
                rs[q].idx = pool[q].idx;
            }
            qsort(rs, r, sizeof *rs, match_exact_cmp);
            for (q = 0; q < r; q++)
                order[q] = rs[q].idx;
            nt = match_greedy(s, order, r, m->nx, k, taken);
            if (r == n_pool && complete) {
                done = 1; /* R holds every window: nothing can be missing */
                break;
            }
            if (nt == k) {
                const double ek = rs[taken[k - 1]].e;
                if (ek + delta <= tau) {
                    done = 1;
                    break;
                }
                tau = ek + delta > tau ? ek + delta : INFINITY;
            } else {
                const double next = pool[TS_MIN(n_pool - 1, 2 * r + 64)].v;
                tau = next > tau ? next : INFINITY;
            }
        }
        if (!done)
            cap = cap > n_finite / 4 ? n_finite : cap * 4;
    }
    if (st == TS_OK) {
        for (i = 0; i < nt; i++) {
            const size_t idx = rs[taken[i]].idx;
            out[i].x = (int)(idx % (size_t)m->nx);
            out[i].y = (int)(idx / (size_t)m->nx);
            out[i].ssd = rs[taken[i]].e;
        }
        *n_found = nt;
    }
    free(pool);
    free(rs);
    free(exact);
    free(order);
    free(taken);
    return st;
}

/* ---- public API -------------------------------------------------------- */

TS_API void ts_matcher_free(ts_matcher *m)
{
    int i;
    if (!m)
        return;
    ts_fft_destroy(m->row_r2c);
    ts_fft_destroy(m->row_c2r);
    ts_fft_destroy(m->col_fwd);
    ts_fft_destroy(m->col_bwd);
    for (i = 0; i < m->n_scratch; i++)
        ts_fft_free(m->scratch[i]);
    ts_fft_free(m->spec1);
    ts_fft_free(m->spec2);
    ts_fft_free(m->rows1);
    ts_fft_free(m->rows2);
    free(m->valid);
    free(m);
}

TS_API ts_status ts_matcher_new(ts_ctx *ctx, const ts_raster *exemplar, int patch_w, int patch_h,
                                ts_matcher **out)
{
    ts_matcher *m;
    ts_status st;
    ts_progress_saved saved;
    size_t fw, fh, spec_n;
    ts_clear(ctx);
    if (!out)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output pointer");
    *out = NULL;
    if (!exemplar || !exemplar->data)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing exemplar");
    if (exemplar->width < 1 || exemplar->height < 1)
        return ts_fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is empty",
                       exemplar->width, exemplar->height);
    if (exemplar->stride < exemplar->width)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "exemplar stride %td is below its width %d",
                       exemplar->stride, exemplar->width);
    if (patch_w < 1 || patch_h < 1)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "patch size %d x %d is not positive",
                       patch_w, patch_h);
    if (patch_w > exemplar->width || patch_h > exemplar->height)
        return ts_fail(ctx, TS_ERR_SIZE, MATCH_STAGE,
                       "the exemplar (%d x %d) is smaller than a patch (%d x %d)",
                       exemplar->width, exemplar->height, patch_w, patch_h);
    fw = ts_fft_good_size((size_t)exemplar->width);
    fh = ts_fft_good_size((size_t)exemplar->height);
    if (fw == 0 || fh == 0 || fw / 2 + 1 > (size_t)INT32_MAX - MATCH_BLOCK)
        return ts_fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is too large",
                       exemplar->width, exemplar->height);

    m = calloc(1, sizeof *m);
    if (!m)
        return ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate a matcher");
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
        return ts_fail(ctx, TS_ERR_SIZE, MATCH_STAGE, "the exemplar (%d x %d) is too large",
                       exemplar->width, exemplar->height);
    }
    spec_n *= fh;
    m->spec1 = ts_fft_alloc(spec_n, sizeof(fftwf_complex));
    m->spec2 = ts_fft_alloc(spec_n, sizeof(fftwf_complex));
    m->rows1 = ts_fft_alloc((size_t)exemplar->height * (size_t)m->stride,
                             sizeof(fftwf_complex));
    m->rows2 = ts_fft_alloc((size_t)patch_h * (size_t)m->stride, sizeof(fftwf_complex));
    if (!m->spec1 || !m->spec2 || !m->rows1 || !m->rows2 || match_scratch(m, 1) < 1) {
        ts_matcher_free(m);
        return ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE,
                       "cannot allocate FFT buffers for a %d x %d exemplar (%zu x %zu padded)",
                       exemplar->width, exemplar->height, fw, fh);
    }
    m->row_r2c = ts_fft_plan_row_r2c(m->fw, m->rows1);
    m->row_c2r = ts_fft_plan_row_c2r(m->fw, m->rows1);
    m->col_fwd = ts_fft_plan_columns(m->fh, MATCH_BLOCK, m->scratch[0], FFTW_FORWARD);
    m->col_bwd = ts_fft_plan_columns(m->fh, MATCH_BLOCK, m->scratch[0], FFTW_BACKWARD);
    if (!m->row_r2c || !m->row_c2r || !m->col_fwd || !m->col_bwd ||
        fftwf_alignment_of((float *)m->rows2) != fftwf_alignment_of((float *)m->rows1)) {
        ts_matcher_free(m);
        return ts_fail(ctx, TS_ERR_INTERNAL, MATCH_STAGE, "FFTW cannot plan %zu x %zu transforms",
                       fw, fh);
    }

    /* -2/F and 1/F: the inverse is unnormalised, and the query spectrum is
     * then s1 conj(F(M T')) + s2 conj(F(M)) with nothing else to scale. */
    saved = ts_progress_push(ctx, 0.0, 0.5);
    st = match_spectrum(ctx, m, 0, m->spec1, (float)(-2.0 / ((double)fw * (double)fh)));
    ts_progress_pop(ctx, saved);
    if (st == TS_OK) {
        saved = ts_progress_push(ctx, 0.5, 1.0);
        st = match_spectrum(ctx, m, 1, m->spec2, (float)(1.0 / ((double)fw * (double)fh)));
        ts_progress_pop(ctx, saved);
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
    ts_clear(ctx);
    if ((st = match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (!out)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output map");
    return match_map(ctx, m, target, out, &sum_t2);
}

TS_API ts_status ts_matcher_best(ts_ctx *ctx, ts_matcher *m, const ts_raster *target, int k,
                                 int min_separation, ts_candidate *out, int *n_found)
{
    ts_status st;
    match_sep sep;
    match_known kn = {0, NULL, NULL};
    float *map = NULL;
    double sum_t2 = 0.0, delta;
    ts_progress_saved saved;
    ts_clear(ctx);
    if (n_found)
        *n_found = 0;
    if ((st = match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (k < 1)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "k must be at least 1, got %d", k);
    if (min_separation < 0)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "min_separation must be >= 0, got %d",
                       min_separation);
    if (!out || !n_found)
        return ts_fail(ctx, TS_ERR_ARG, MATCH_STAGE, "missing output candidates");
    if (match_sep_init(&sep, min_separation, m->nx, k) != TS_OK ||
        match_known_init(&kn, m, target) != TS_OK) {
        match_sep_free(&sep);
        match_known_free(&kn);
        return ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate for k = %d", k);
    }
    if (kn.n == 0) {
        *n_found = match_best_empty(m, &sep, k, out);
        match_sep_free(&sep);
        match_known_free(&kn);
        return ts_progress(ctx, 1.0, "best candidates");
    }
    map = ts_malloc_array((size_t)m->nx * (size_t)m->ny, sizeof *map);
    if (!map) {
        st = ts_fail(ctx, TS_ERR_NOMEM, MATCH_STAGE, "cannot allocate an SSD map of %d x %d",
                     m->nx, m->ny);
    } else {
        saved = ts_progress_push(ctx, 0.0, 0.9);
        st = match_map(ctx, m, target, map, &sum_t2);
        ts_progress_pop(ctx, saved);
    }
    if (st == TS_OK) {
        delta = MATCH_FLOAT_ERR * (sum_t2 + (double)kn.n * m->max_dev2);
        st = match_best_search(ctx, m, map, &kn, delta, &sep, k, out, n_found);
        if (st != TS_OK)
            st = ts_fail(ctx, st, MATCH_STAGE, "cannot allocate the candidate pool");
        else
            st = ts_progress(ctx, 1.0, "best candidates");
    }
    free(map);
    match_sep_free(&sep);
    match_known_free(&kn);
    return st;
}
