/*
 * blur.c - the NaN-aware Gaussian blur the sketch stages share (three box
 * passes, so O(cells) for any sigma), and the mean gradient they calibrate
 * steepness with.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "layout.h"

/* ---- NaN-aware blur ------------------------------------------------- */

typedef struct blur_job {
    int w, h, r;   /* box radius */
    double *v, *m; /* value * weight and weight, w*h, blurred in place */
    int n_arr;     /* 2: both; 1: v alone (no NaN: the weights are separable) */
    atomic_int failed;
} blur_job;

/* One box pass of radius r over n samples at stride s (in place). */
static void box_line(double *a, size_t n, size_t s, int r, double *tmp)
{
    size_t i;
    double acc = 0.0;
    size_t R = (size_t)r;
    for (i = 0; i < n; i++)
        tmp[i] = a[i * s];
    for (i = 0; i < R && i < n; i++)
        acc += tmp[i];
    for (i = 0; i < n; i++) {
        if (i + R < n)
            acc += tmp[i + R];
        if (i > R)
            acc -= tmp[i - R - 1];
        a[i * s] = acc;
    }
}

static void blur_rows(void *arg, size_t b, size_t e)
{
    blur_job *j = arg;
    double *tmp = ts__malloc_array((size_t)j->w, sizeof *tmp);
    size_t y;
    int p;
    if (!tmp) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (y = b; y < e; y++)
        for (p = 0; p < 3; p++) {
            box_line(j->v + y * (size_t)j->w, (size_t)j->w, 1, j->r, tmp);
            if (j->n_arr > 1)
                box_line(j->m + y * (size_t)j->w, (size_t)j->w, 1, j->r, tmp);
        }
    free(tmp);
}

#define BLUR_BLOCK 32 /* columns a vertical pass runs through together */

/* The vertical passes, over blocks of adjacent columns so that every step
 * runs along memory: for each block a copy of its columns, then running
 * sums over the rows for all its columns at once. */
static void blur_cols(void *arg, size_t b, size_t e)
{
    blur_job *j = arg;
    size_t h = (size_t)j->h, w = (size_t)j->w, R = (size_t)j->r, x0;
    double *tmp = ts__malloc_array(h * BLUR_BLOCK, sizeof *tmp);
    double acc[BLUR_BLOCK];
    if (!tmp) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (x0 = b; x0 < e; x0 += BLUR_BLOCK) {
        size_t bw = TS_MIN((size_t)BLUR_BLOCK, e - x0), y, c;
        int arr, p;
        for (arr = 0; arr < j->n_arr; arr++) {
            double *a = arr ? j->m : j->v;
            for (p = 0; p < 3; p++) {
                for (y = 0; y < h; y++)
                    memcpy(tmp + y * bw, a + y * w + x0, bw * sizeof *tmp);
                for (c = 0; c < bw; c++)
                    acc[c] = 0.0;
                for (y = 0; y < R && y < h; y++)
                    for (c = 0; c < bw; c++)
                        acc[c] += tmp[y * bw + c];
                for (y = 0; y < h; y++) {
                    double *row = a + y * w + x0;
                    if (y + R < h)
                        for (c = 0; c < bw; c++)
                            acc[c] += tmp[(y + R) * bw + c];
                    if (y > R)
                        for (c = 0; c < bw; c++)
                            acc[c] -= tmp[(y - R - 1) * bw + c];
                    memcpy(row, acc, bw * sizeof *acc);
                }
            }
        }
    }
    free(tmp);
}

int ts__blur_radius(double sigma)
{
    /* three boxes of width n = 2r + 1 have variance 3 (n^2 - 1) / 12 */
    double n = sqrt(4.0 * sigma * sigma + 1.0);
    int r = (int)lround(0.5 * (n - 1.0));
    return r < 0 ? 0 : r;
}

/* The three box passes of radius r over n ones, into a (n doubles). */
static void blur_ones(double *a, size_t n, int r, double *tmp)
{
    size_t i;
    int p;
    for (i = 0; i < n; i++)
        a[i] = 1.0;
    for (p = 0; p < 3; p++)
        box_line(a, n, 1, r, tmp);
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
    int x, y;
    size_t n_nan = 0;
    j.w = w;
    j.h = h;
    j.r = ts__blur_radius(sigma);
    j.v = v;
    j.m = m;
    atomic_init(&j.failed, 0);
    for (y = 0; y < h; y++) {
        const float *row = in + (ptrdiff_t)y * stride;
        double *vr = v + (size_t)y * (size_t)w, *mr = m + (size_t)y * (size_t)w;
        for (x = 0; x < w; x++) {
            int bad = isnan(row[x]);
            vr[x] = bad ? 0.0 : row[x];
            mr[x] = bad ? 0.0 : 1.0;
            n_nan += (size_t)bad;
        }
    }
    j.n_arr = n_nan == 0 && 2 * j.r + 1 <= 256 && (size_t)w * (size_t)h >= (size_t)(w + h) * 2
                  ? 1
                  : 2;
    if (j.r > 0) {
        ts__parallel_for(ctx, (size_t)h, blur_rows, &j);
        if (!atomic_load(&j.failed))
            ts__parallel_for(ctx, (size_t)w, blur_cols, &j);
    }
    if (j.n_arr == 1 && j.r > 0) { /* m's first w + h cells: the row's and the column's */
        double *mx = m, *my = m + w, *tmp = m + w + h;
        blur_ones(mx, (size_t)w, j.r, tmp);
        blur_ones(my, (size_t)h, j.r, tmp);
        for (y = h - 1; y >= 0; y--) {
            double *vr = v + (size_t)y * (size_t)w, fy = my[y];
            float *o = out + (size_t)y * (size_t)w;
            for (x = 0; x < w; x++)
                o[x] = (float)(vr[x] / (mx[x] * fy));
        }
    } else {
        size_t i, n = (size_t)w * (size_t)h;
        for (i = 0; i < n; i++)
            out[i] = m[i] > 1e-9 ? (float)(v[i] / m[i]) : NAN;
    }
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

