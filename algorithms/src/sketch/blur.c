/*
 * blur.c - the NaN-aware Gaussian blur the sketch stages share (three box
 * passes, so O(cells) for any sigma, on the thread pool), and the mean
 * gradients (the output's, the exemplars' blurred) they calibrate steepness
 * with.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "layout.h"

/* ---- NaN-aware blur ------------------------------------------------- */

#define BLUR_LINES 16 /* rows or columns a pass runs through together */

typedef struct blur_job {
    int w, h, r;   /* box radius */
    double *v, *m; /* value * weight and weight, w*h, blurred in place */
    int n_arr;     /* 2: both; 1: v alone (no NaN: the weights are separable) */
    const float *in;
    ptrdiff_t stride;      /* of in */
    float *out;            /* w*h, stride w */
    const double *mx, *my; /* the weights' blur along a row and a column, or NULL: m */
    atomic_int failed, has_nan;
} blur_job;

/* One box pass of radius R along n steps over bw interleaved lines (line c's
 * step i at src[i * bw + c]), from src into dst: running sums, all lines at
 * once (independent chains, along memory). */
static void box_pass(const double *src, double *dst, size_t n, size_t bw, size_t R)
{
    double acc[BLUR_LINES];
    size_t i, c;
    for (c = 0; c < bw; c++)
        acc[c] = 0.0;
    for (i = 0; i < R && i < n; i++)
        for (c = 0; c < bw; c++)
            acc[c] += src[i * bw + c];
    for (i = 0; i < n; i++) {
        if (i + R < n)
            for (c = 0; c < bw; c++)
                acc[c] += src[(i + R) * bw + c];
        if (i > R)
            for (c = 0; c < bw; c++)
                acc[c] -= src[(i - R - 1) * bw + c];
        memcpy(dst + i * bw, acc, bw * sizeof *acc);
    }
}

/* The three box passes over lines [b, e) of the array(s) of j: lines are
 * rows (vertical 0: step 1 along a line, w between lines) or columns
 * (vertical 1: w along a line, 1 between lines).  BLUR_LINES adjacent lines
 * at a time, gathered once into interleaved form, passed between two
 * buffers, written back once. */
static void blur_lines(blur_job *j, size_t b, size_t e, int vertical)
{
    size_t w = (size_t)j->w, n = vertical ? (size_t)j->h : w, R = (size_t)j->r, l0;
    size_t step = vertical ? w : 1, gap = vertical ? 1 : w;
    double *tmp = ts__malloc_array(2 * n * BLUR_LINES, sizeof *tmp);
    if (!tmp) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (l0 = b; l0 < e; l0 += BLUR_LINES) {
        size_t bw = TS_MIN((size_t)BLUR_LINES, e - l0), i, c;
        int arr, p;
        for (arr = 0; arr < j->n_arr; arr++) {
            double *a = (arr ? j->m : j->v) + l0 * gap, *src = tmp, *dst = tmp + n * bw;
            for (i = 0; i < n; i++)
                for (c = 0; c < bw; c++)
                    src[i * bw + c] = a[i * step + c * gap];
            for (p = 0; p < 3; p++) {
                double *t;
                box_pass(src, dst, n, bw, R);
                t = src;
                src = dst;
                dst = t;
            }
            for (i = 0; i < n; i++)
                for (c = 0; c < bw; c++)
                    a[i * step + c * gap] = src[i * bw + c];
        }
    }
    free(tmp);
}

static void blur_rows(void *arg, size_t b, size_t e)
{
    blur_lines(arg, b, e, 0);
}

static void blur_cols(void *arg, size_t b, size_t e)
{
    blur_lines(arg, b, e, 1);
}

/* The three box passes of j along its rows, then its columns (nothing at
 * radius 0). */
static void blur_box_passes(ts_ctx *ctx, blur_job *j)
{
    if (j->r <= 0)
        return;
    ts__parallel_for(ctx, (size_t)j->h, blur_rows, j);
    if (!atomic_load(&j->failed))
        ts__parallel_for(ctx, (size_t)j->w, blur_cols, j);
}

/* The three box passes of radius r over n ones, into a (n doubles; tmp:
 * 2 n more). */
static void blur_ones(double *a, size_t n, int r, double *tmp)
{
    size_t i;
    int p;
    for (i = 0; i < n; i++)
        tmp[i] = 1.0;
    for (p = 0; p < 3; p++)
        box_pass(p % 2 ? tmp + n : tmp, p % 2 ? tmp : tmp + n, n, 1, (size_t)r);
    memcpy(a, tmp + n, n * sizeof *a);
}

int ts__blur_radius(double sigma)
{
    /* three boxes of width n = 2r + 1 have variance 3 (n^2 - 1) / 12 */
    double n = sqrt(4.0 * sigma * sigma + 1.0);
    int r = (int)lround(0.5 * (n - 1.0));
    return r < 0 ? 0 : r;
}

/* Rows [b, e) of the input into v (0 on NaN) and m (its weight). */
static void blur_load(void *arg, size_t b, size_t e)
{
    blur_job *j = arg;
    size_t y, x, w = (size_t)j->w;
    int any = 0;
    for (y = b; y < e; y++) {
        const float *row = j->in + (ptrdiff_t)y * j->stride;
        double *vr = j->v + y * w, *mr = j->m + y * w;
        for (x = 0; x < w; x++) {
            int bad = isnan(row[x]);
            vr[x] = bad ? 0.0 : row[x];
            mr[x] = bad ? 0.0 : 1.0;
            any |= bad;
        }
    }
    if (any)
        atomic_store(&j->has_nan, 1);
}

/* Rows [b, e) of the output: v / m, m from mx and my when they are set. */
static void blur_store(void *arg, size_t b, size_t e)
{
    blur_job *j = arg;
    size_t y, x, w = (size_t)j->w;
    for (y = b; y < e; y++) {
        const double *vr = j->v + y * w, *mr = j->m + y * w;
        float *o = j->out + y * w;
        if (j->mx)
            for (x = 0; x < w; x++)
                o[x] = (float)(vr[x] / (j->mx[x] * j->my[y]));
        else
            for (x = 0; x < w; x++)
                o[x] = mr[x] > 1e-9 ? (float)(vr[x] / mr[x]) : NAN;
    }
}

/* ts__blur_nan with caller buffers v and m (w * h doubles each).  Without
 * NaN the weights are 1 everywhere, and their blur is the product of the
 * blurs of a row and a column of ones: whole numbers below 2^53 (boxes of
 * at most 2^8 cells: (2^8)^6), so both ways give the same doubles; only v
 * is blurred then. */
static void blur_nan_ws(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h, double sigma,
                        float *out, double *v, double *m, atomic_int *failed)
{
    blur_job j;
    j.w = w;
    j.h = h;
    j.r = ts__blur_radius(sigma);
    j.v = v;
    j.m = m;
    j.in = in;
    j.stride = stride;
    j.out = out;
    j.mx = j.my = NULL;
    atomic_init(&j.failed, 0);
    atomic_init(&j.has_nan, 0);
    ts__parallel_for(ctx, (size_t)h, blur_load, &j);
    j.n_arr = !atomic_load(&j.has_nan) && 2 * j.r + 1 <= 256 &&
                      (size_t)w * (size_t)h >= (size_t)(w + h) * 3
                  ? 1
                  : 2;
    blur_box_passes(ctx, &j);
    if (j.n_arr == 1 && j.r > 0) { /* m's first w + h cells: the row's and the column's */
        double *tmp = m + w + h;   /* 2 max(w, h) more */
        j.mx = m;
        j.my = m + w;
        blur_ones(m, (size_t)w, j.r, tmp);
        blur_ones(m + w, (size_t)h, j.r, tmp);
    }
    ts__parallel_for(ctx, (size_t)h, blur_store, &j);
    if (atomic_load(&j.failed))
        atomic_store(failed, 1);
}

ts_status ts__blur_nan_buffers(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                               double sigma, float *out, double *v, double *m)
{
    atomic_int failed;
    atomic_init(&failed, 0);
    blur_nan_ws(ctx, in, stride, w, h, sigma, out, v, m, &failed);
    return atomic_load(&failed) ? ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory") : TS_OK;
}

ts_status ts__blur_nan(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h, double sigma,
                       float *out)
{
    size_t n = (size_t)w * (size_t)h;
    double *v = ts__malloc_array(n, sizeof(double)), *m = ts__malloc_array(n, sizeof(double));
    atomic_int failed;
    atomic_init(&failed, 0);
    if (v && m)
        blur_nan_ws(ctx, in, stride, w, h, sigma, out, v, m, &failed);
    free(v);
    free(m);
    if (!v || !m || atomic_load(&failed))
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    return TS_OK;
}

/* ---- the same blur through a coarser grid, for wide blurs ----------- */

/* What the coarse blur's passes read: the fine input, the coarse sums. */
typedef struct coarse_job {
    const float *in;
    ptrdiff_t stride;
    float *out;
    int w, h, f, cw, ch;
    double *v, *m; /* cw * ch: sums of the valid values and their counts, blurred in place */
    int *x0;       /* w: the coarse column left of each fine column's centre (clamped) */
    double *tx;    /* w: the weight of the column right of it */
    atomic_int failed;
} coarse_job;

/* Coarse rows [b, e): each coarse cell the sum and the count of the valid
 * cells of its f x f block (clipped at the grid's edge). */
static void coarse_load(void *arg, size_t b, size_t e)
{
    coarse_job *j = arg;
    size_t cy, cx;
    for (cy = b; cy < e; cy++)
        for (cx = 0; cx < (size_t)j->cw; cx++) {
            double sum = 0.0, cnt = 0.0;
            int y, x, y1 = TS_MIN((int)(cy + 1) * j->f, j->h),
                      x1 = TS_MIN((int)(cx + 1) * j->f, j->w);
            for (y = (int)cy * j->f; y < y1; y++) {
                const float *row = j->in + (ptrdiff_t)y * j->stride;
                for (x = (int)cx * j->f; x < x1; x++)
                    if (!isnan(row[x])) {
                        sum += row[x];
                        cnt += 1.0;
                    }
            }
            j->v[cy * (size_t)j->cw + cx] = sum;
            j->m[cy * (size_t)j->cw + cx] = cnt;
        }
}

/* Where the centre of fine cell i lies between coarse cells of f cells
 * (n of them): the one before it, clamped, and the weight of the next. */
static void coarse_at(int i, int f, int n, int *i0, double *t)
{
    double p = ((double)i + 0.5) / f - 0.5;
    int k = (int)floor(p);
    *t = p - k;
    if (k < 0) {
        k = 0;
        *t = 0.0;
    } else if (k >= n - 1) {
        k = n - 1;
        *t = 0.0;
    }
    *i0 = k;
}

/* Fine rows [b, e): the blurred sums and counts taken bilinearly at the
 * cell's centre on the coarse grid (along the column first, into a coarse
 * row, then along the row), their ratio (NaN where no valid cell was in
 * reach). */
static void coarse_store(void *arg, size_t b, size_t e)
{
    coarse_job *j = arg;
    size_t y, x, cw = (size_t)j->cw, k;
    double *rv = ts__malloc_array(2 * cw, sizeof(double)), *rm = rv + cw;
    if (!rv) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (y = b; y < e; y++) {
        int y0;
        double ty;
        const double *v0, *v1, *m0, *m1;
        float *o = j->out + y * (size_t)j->w;
        coarse_at((int)y, j->f, j->ch, &y0, &ty);
        v0 = j->v + (size_t)y0 * cw;
        m0 = j->m + (size_t)y0 * cw;
        v1 = ty > 0.0 ? v0 + cw : v0;
        m1 = ty > 0.0 ? m0 + cw : m0;
        for (k = 0; k < cw; k++) {
            rv[k] = (1.0 - ty) * v0[k] + ty * v1[k];
            rm[k] = (1.0 - ty) * m0[k] + ty * m1[k];
        }
        for (x = 0; x < (size_t)j->w; x++) {
            size_t c = (size_t)j->x0[x], c1 = j->tx[x] > 0.0 ? c + 1 : c;
            double t = j->tx[x];
            double v = (1.0 - t) * rv[c] + t * rv[c1], m = (1.0 - t) * rm[c] + t * rm[c1];
            o[x] = m > 1e-9 ? (float)(v / m) : NAN;
        }
    }
    free(rv);
}

int ts__blur_coarse_factor(double sigma, int w, int h)
{
    int f = 1;
    while (2 * f <= sigma / 8.0 && w / (2 * f) >= 8 && h / (2 * f) >= 8)
        f *= 2;
    return f;
}

ts_status ts__blur_nan_coarse(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                              double sigma, float *out)
{
    int f = ts__blur_coarse_factor(sigma, w, h), x;
    coarse_job c;
    blur_job j;
    size_t n;
    double s2;
    if (f < 2)
        return ts__blur_nan(ctx, in, stride, w, h, sigma, out);
    c.in = in;
    c.stride = stride;
    c.out = out;
    c.w = w;
    c.h = h;
    c.f = f;
    c.cw = (w + f - 1) / f;
    c.ch = (h + f - 1) / f;
    n = (size_t)c.cw * (size_t)c.ch;
    c.v = ts__malloc_array(n, sizeof(double));
    c.m = ts__malloc_array(n, sizeof(double));
    c.x0 = ts__malloc_array((size_t)w, sizeof(int));
    c.tx = ts__malloc_array((size_t)w, sizeof(double));
    atomic_init(&c.failed, 0);
    if (!c.v || !c.m || !c.x0 || !c.tx) {
        free(c.v);
        free(c.m);
        free(c.x0);
        free(c.tx);
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    }
    for (x = 0; x < w; x++)
        coarse_at(x, f, c.cw, &c.x0[x], &c.tx[x]);
    ts__parallel_for(ctx, (size_t)c.ch, coarse_load, &c);
    /* the block's mean (variance f^2 / 12) and the bilinear taking back
     * (f^2 / 6) widen the blur: the coarse blur makes up the rest */
    s2 = sigma * sigma - 0.25 * (double)f * (double)f;
    memset(&j, 0, sizeof j);
    j.w = c.cw;
    j.h = c.ch;
    j.r = ts__blur_radius(sqrt(s2) / f);
    j.v = c.v;
    j.m = c.m;
    j.n_arr = 2;
    atomic_init(&j.failed, 0);
    atomic_init(&j.has_nan, 0);
    blur_box_passes(ctx, &j);
    if (!atomic_load(&j.failed))
        ts__parallel_for(ctx, (size_t)h, coarse_store, &c);
    free(c.v);
    free(c.m);
    free(c.x0);
    free(c.tx);
    return atomic_load(&j.failed) || atomic_load(&c.failed)
               ? ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory")
               : TS_OK;
}

/* Mean gradient (per cell) of every exemplar blurred at sigma (0 where
 * unknown), measured on the exemplar averaged over f x f cells first, f the
 * largest power of two up to sigma / 3 (a blur that wide hardly sees the
 * difference; a 4096 x 4096 exemplar would otherwise be blurred whole). */
ts_status ts__exemplar_gradients(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                 double sigma, double *g)
{
    int e, f = 1;
    while (2 * f <= sigma / 3.0)
        f *= 2;
    for (e = 0; e < n_exemplars; e++) {
        const ts_raster *ex = &exemplars[e];
        int cw = ex->width / f, ch = ex->height / f, x, y, u, v;
        float *small =
            cw > 2 && ch > 2 ? ts__malloc_array((size_t)cw * (size_t)ch, sizeof(float)) : NULL;
        float *eb = small ? ts__malloc_array((size_t)cw * (size_t)ch, sizeof(float)) : NULL;
        ts_status st;
        g[e] = 0.0;
        if (cw <= 2 || ch <= 2)
            continue;
        if (!small || !eb) {
            free(small);
            free(eb);
            return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        }
        for (y = 0; y < ch; y++)
            for (x = 0; x < cw; x++) {
                double sum = 0.0;
                int cnt = 0;
                for (v = 0; v < f; v++)
                    for (u = 0; u < f; u++) {
                        float z = TS_PIX(ex, x * f + u, y * f + v);
                        if (!isnan(z)) {
                            sum += z;
                            cnt++;
                        }
                    }
                small[(size_t)y * (size_t)cw + (size_t)x] = cnt ? (float)(sum / cnt) : NAN;
            }
        st = ts__blur_nan(ctx, small, cw, cw, ch, sigma / f, eb);
        if (st == TS_OK)
            g[e] = ts__mean_gradient(eb, cw, ch) / f;
        free(small);
        free(eb);
        if (st != TS_OK)
            return st;
    }
    return TS_OK;
}

double ts__mean_gradient(const float *a, int w, int h)
{
    double sum = 0.0;
    size_t cnt = 0;
    int x, y;
    for (y = 1; y + 1 < h; y++)
        for (x = 1; x + 1 < w; x++) {
            const float *p = a + (size_t)y * (size_t)w + (size_t)x;
            double gx = 0.5 * ((double)p[1] - (double)p[-1]);
            double gy = 0.5 * ((double)p[w] - (double)p[-w]);
            double g = sqrt(gx * gx + gy * gy);
            if (isnan(g))
                continue;
            sum += g;
            cnt++;
        }
    return cnt ? sum / (double)cnt : 0.0;
}
