/*
 * layout_steepness.c - the slope statistics the layout (layout.c) is tuned
 * with: the steepness factor that gives the output the exemplars'
 * distribution of slopes, and the exemplars' range of heights its press
 * keeps the land's large scale within.  Both sample at most about
 * LAYOUT_SAMPLES cells on a regular lattice.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "layout.h"

#define LAYOUT_QUANTILES 199
#define LAYOUT_SAMPLES 65536

/* The lattice step that samples a w x h grid with at most about
 * LAYOUT_SAMPLES cells, and how many cells it samples at most. */
static int layout_step(int w, int h)
{
    double cells = (double)w * (double)h;
    return cells > LAYOUT_SAMPLES ? (int)ceil(sqrt(cells / LAYOUT_SAMPLES)) : 1;
}

static size_t layout_samples(int w, int h)
{
    int st = layout_step(w, h);
    return ((size_t)w / (size_t)st + 1) * ((size_t)h / (size_t)st + 1);
}

/* Quantiles 0.5 %, 1 %, ..., 99.5 % of the gradient magnitude (central
 * differences, cells with four valid neighbours) of a + lam * b (b may be
 * NULL), over at most about LAYOUT_SAMPLES cells on a regular lattice;
 * returns 0 when no cell has a gradient.  work: w * h floats. */
static int layout_gradient_quantiles(const float *a, const float *b, ptrdiff_t stride, int w, int h,
                                     double lam, float *work, double *q)
{
    size_t n = 0, k;
    int step = layout_step(w, h), x, y;
    for (y = 1; y + 1 < h; y += step)
        for (x = 1; x + 1 < w; x += step) {
            size_t i = (size_t)y * (size_t)stride + (size_t)x;
            double gx = 0.5 * ((double)a[i + 1] - a[i - 1]);
            double gy = 0.5 * ((double)a[i + (size_t)stride] - a[i - (size_t)stride]);
            double g;
            if (b) {
                gx += lam * 0.5 * ((double)b[i + 1] - b[i - 1]);
                gy += lam * 0.5 * ((double)b[i + (size_t)stride] - b[i - (size_t)stride]);
            }
            g = sqrt(gx * gx + gy * gy);
            if (!isnan(g))
                work[n++] = (float)g;
        }
    if (!n)
        return 0;
    ts__sort_floats(work, n);
    for (k = 0; k < LAYOUT_QUANTILES; k++) {
        double pos = (0.5 + 0.5 * (double)k) / 100.0 * (double)(n - 1);
        size_t i0 = (size_t)pos;
        double f = pos - (double)i0;
        q[k] = i0 + 1 < n ? (1.0 - f) * work[i0] + f * work[i0 + 1] : work[n - 1];
    }
    return 1;
}

/* The p-th percentile (0..100) of the valid cells of r, over at most about
 * LAYOUT_SAMPLES cells on a regular lattice (NAN when none is valid). */
static double layout_percentile(const ts_raster *r, double p, float *work)
{
    double pos;
    int step = layout_step(r->width, r->height), x, y;
    size_t n = 0, i0;
    for (y = 0; y < r->height; y += step)
        for (x = 0; x < r->width; x += step)
            if (!isnan(TS_PIX(r, x, y)))
                work[n++] = TS_PIX(r, x, y);
    if (!n)
        return NAN;
    ts__sort_floats(work, n);
    pos = p / 100.0 * (double)(n - 1);
    i0 = (size_t)pos;
    return i0 + 1 < n ? work[i0] + (pos - (double)i0) * (work[i0 + 1] - work[i0]) : work[n - 1];
}

/* Mean distance between the output's gradient quantiles at lam and the
 * exemplars' (the Wasserstein-1 distance of the two distributions). */
static double layout_misfit(const float *r0, const float *diff, int W, int H, double lam,
                            const double *target, float *work)
{
    double q[LAYOUT_QUANTILES], sum = 0.0;
    int k;
    if (!layout_gradient_quantiles(r0, diff, W, W, H, lam, work, q))
        return 0.0;
    for (k = 0; k < LAYOUT_QUANTILES; k++)
        sum += fabs(q[k] - target[k]);
    return sum / LAYOUT_QUANTILES;
}

/* The steepness that gives the output the exemplars' distribution of
 * slopes (the patches' merging flattens a little; a steep exemplar's
 * guide adds to its own slopes): the least Wasserstein distance of the
 * gradient distributions, golden-section search over 0.35..2.5 times
 * the calibrated steepness.  Above 1 the layout and the crest steepen
 * together (r0 + lam corr); below 1 only the layout gentles (r01 + lam
 * d01): the sketched features keep standing out over an exemplar whose
 * land is mostly flat.  With the slope style after it (slope_style.c,
 * which matches the distribution itself and never gentles near the
 * strokes) the search starts at 1: the layout is never gentler than the
 * exemplar at its scale.  *lam is left as it is without a distribution. */
ts_status ts__layout_steepness(ts_ctx *ctx, const ts_layout_spec *s, const float *r0,
                               const float *corr, const float *r01, const float *d01, float *work,
                               double *lam)
{
    double target[LAYOUT_QUANTILES], q[LAYOUT_QUANTILES];
    int W = s->width, H = s->height, e, k, n_t = 0, it;
    double lo = log(s->steep_lo > 0 ? s->steep_lo : 0.35), hi = log(2.5);
    double g = 0.5 * (sqrt(5.0) - 1.0), x1, x2, f1, f2;
    memset(target, 0, sizeof target);
    for (e = 0; e < s->n_exemplars; e++) {
        const ts_raster *ex = &s->exemplars[e];
        float *wk = ts__malloc_array(layout_samples(ex->width, ex->height), sizeof(float));
        if (!wk)
            return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        if (layout_gradient_quantiles(ex->data, NULL, ex->stride, ex->width, ex->height, 0.0, wk,
                                      q)) {
            for (k = 0; k < LAYOUT_QUANTILES; k++)
                target[k] += q[k];
            n_t++;
        }
        free(wk);
    }
#define LAYOUT_MISFIT(lm)                                                                          \
    ((lm) >= 1.0 ? layout_misfit(r0, corr, W, H, (lm), target, work)                               \
                 : layout_misfit(r01, d01, W, H, (lm), target, work))
    if (n_t) {
        for (k = 0; k < LAYOUT_QUANTILES; k++)
            target[k] /= n_t;
        x1 = hi - g * (hi - lo);
        x2 = lo + g * (hi - lo);
        f1 = LAYOUT_MISFIT(exp(x1));
        f2 = LAYOUT_MISFIT(exp(x2));
        for (it = 0; it < 16; it++) {
            if (f1 <= f2) {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = LAYOUT_MISFIT(exp(x1));
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = LAYOUT_MISFIT(exp(x2));
            }
        }
        *lam = exp(0.5 * (lo + hi));
    }
#undef LAYOUT_MISFIT
    return TS_OK;
}

ts_status ts__exemplar_height_range(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                    double *lo, double *hi)
{
    int e;
    *lo = INFINITY;
    *hi = -INFINITY;
    for (e = 0; e < n_exemplars; e++) {
        const ts_raster *ex = &exemplars[e];
        float *wk = ts__malloc_array(layout_samples(ex->width, ex->height), sizeof(float));
        if (!wk)
            return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        *lo = fmin(*lo, layout_percentile(ex, 1.0, wk));
        *hi = fmax(*hi, layout_percentile(ex, 99.0, wk));
        free(wk);
    }
    return TS_OK;
}
