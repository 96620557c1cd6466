/*
 * match_ssd.c - masked SSD of a patch against every window of an exemplar,
 * by FFT (Zhou et al. 2007 section 4.2); the k best separated candidates
 * are read from its map in match_candidates.c.
 *
 * SSD(x,y) = sum M T'^2 - 2 corr(E', M T')(x,y) + corr(E'^2, M)(x,y), M = 1 on
 * known target cells, ' = minus the exemplar mean (the SSD is unchanged and
 * float cancellation smaller).  The spectra of E' and E'^2 are made once; a
 * query transforms 2 x patch_h rows, then column blocks (forward, product,
 * one inverse), then the output rows: O(F log F) for F = fw * fh padded cells
 * (7-smooth, >= W x H).
 * Memory: ~13 bytes per padded cell (two half spectra 8, an H-row buffer 4,
 * validity 1): 210 MB for 4096 x 4096.  Thread-safety: one thread per matcher
 * at a time; FFTW planning runs under fft.c's mutex; results do not depend on
 * the thread count.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "match_ssd.h"

/* Complex columns per column block.  8 (64 bytes) keeps every block, row
 * and scratch buffer at the alignment the plans were made with, and was
 * the fastest of 4..32 (a block of 4096-point columns stays in L2). */
#define MATCH_BLOCK 8

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
int ts__match_workers(const ts_ctx *ctx, size_t n_items, size_t total_cost)
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

/* fn over items [0, n) of `cost` cells each, on ts__match_workers() threads.
 * Items are independent, so the split never changes a result. */
static void match_parallel(ts_ctx *ctx, size_t n, size_t cost, ts_range_fn fn, void *arg)
{
    match_group g;
    g.n = n;
    g.groups = (size_t)ts__match_workers(ctx, n, n * cost);
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
        return ts__fail(ctx, TS_ERR_NUMERIC, TS__MATCH_STAGE, "every exemplar cell is nodata");
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
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "cannot allocate the validity map");
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
        return ts__fail(ctx, TS_ERR_NUMERIC, TS__MATCH_STAGE,
                        "no %d x %d window of the exemplar is free of nodata", m->pw, m->ph);
    return TS_OK;
}

/* ---- transforms: rows, then column blocks ------------------------------ */

/* Worker scratch for up to `want` slots; returns how many exist (>= 1
 * once the matcher is built). */
static int match_scratch(ts_matcher *m, int want)
{
    while (m->n_scratch < want && m->n_scratch < TS__MATCH_MAX_SLOTS) {
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
    const int want = ts__match_workers(ctx, (size_t)m->nblk, (size_t)m->cols * (size_t)m->fh);
    int nslots = match_scratch(m, want);
    if (nslots < 1)
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "cannot allocate FFT scratch");
    nslots = TS_MIN(nslots, want);
    job->nslots = nslots;
    ts__parallel_for(ctx, (size_t)nslots, fn, job);
    return TS_OK;
}

/* The SSD map of a checked target with known cells into out (nx * ny),
 * or, if out is NULL, into rows1 (row y at (float *)rows1 + y * 2 * stride,
 * valid until the next query); *sum_t2 = sum M T'^2. */
ts_status ts__match_map(ts_ctx *ctx, ts_matcher *m, const ts_raster *t, float *out, double *sum_t2)
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

ts_status ts__match_check_target(ts_ctx *ctx, const ts_matcher *m, const ts_raster *t)
{
    if (!m)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing matcher");
    if (!t || !t->data)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing target");
    if (t->width != m->pw || t->height != m->ph)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE,
                        "the target is %d x %d but the matcher was planned for %d x %d patches",
                        t->width, t->height, m->pw, m->ph);
    if (t->stride < t->width)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "target stride %td is below its width %d",
                        t->stride, t->width);
    return TS_OK;
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
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "out of memory");
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
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing output pointer");
    *out = NULL;
    if (!exemplar || !exemplar->data)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing exemplar");
    if (exemplar->width < 1 || exemplar->height < 1)
        return ts__fail(ctx, TS_ERR_SIZE, TS__MATCH_STAGE, "the exemplar (%d x %d) is empty",
                        exemplar->width, exemplar->height);
    if (exemplar->stride < exemplar->width)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE,
                        "exemplar stride %td is below its width %d", exemplar->stride,
                        exemplar->width);
    if (patch_w < 1 || patch_h < 1)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "patch size %d x %d is not positive",
                        patch_w, patch_h);
    if (patch_w > exemplar->width || patch_h > exemplar->height)
        return ts__fail(ctx, TS_ERR_SIZE, TS__MATCH_STAGE,
                        "the exemplar (%d x %d) is smaller than a patch (%d x %d)", exemplar->width,
                        exemplar->height, patch_w, patch_h);
    fw = ts__fft_good_size((size_t)exemplar->width);
    fh = ts__fft_good_size((size_t)exemplar->height);
    if (fw == 0 || fh == 0 || fw / 2 + 1 > (size_t)INT32_MAX - MATCH_BLOCK)
        return ts__fail(ctx, TS_ERR_SIZE, TS__MATCH_STAGE, "the exemplar (%d x %d) is too large",
                        exemplar->width, exemplar->height);

    m = calloc(1, sizeof *m);
    if (!m)
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE, "cannot allocate a matcher");
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
        return ts__fail(ctx, TS_ERR_SIZE, TS__MATCH_STAGE, "the exemplar (%d x %d) is too large",
                        exemplar->width, exemplar->height);
    }
    spec_n *= fh;
    m->spec1 = ts__fft_alloc(spec_n, sizeof(fftwf_complex));
    m->spec2 = ts__fft_alloc(spec_n, sizeof(fftwf_complex));
    m->rows1 = ts__fft_alloc((size_t)exemplar->height * (size_t)m->stride, sizeof(fftwf_complex));
    m->rows2 = ts__fft_alloc((size_t)patch_h * (size_t)m->stride, sizeof(fftwf_complex));
    if (!m->spec1 || !m->spec2 || !m->rows1 || !m->rows2 || match_scratch(m, 1) < 1) {
        ts_matcher_free(m);
        return ts__fail(ctx, TS_ERR_NOMEM, TS__MATCH_STAGE,
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
        return ts__fail(ctx, TS_ERR_INTERNAL, TS__MATCH_STAGE,
                        "FFTW cannot plan %zu x %zu transforms", fw, fh);
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
    if ((st = ts__match_check_target(ctx, m, target)) != TS_OK)
        return st;
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, TS__MATCH_STAGE, "missing output map");
    return ts__match_map(ctx, m, target, out, &sum_t2);
}
