/*
 * layout.c - the large-scale relief a sketch lays out (a TerraSynth
 * addition to Zhou et al. 2007, in the spirit of the guide of Cruz et al.,
 * whose coarse pyramid levels come from a guide and fine ones from the
 * exemplars).
 *
 * Feature patches put an exemplar ridge (valley) along every stroke, but
 * patch merging keeps only gradients, so the level of every patch drifts
 * with its neighbours, and the fill grows relief of its own between the
 * strokes: on a valley network drawn over rugged mountains the network
 * drowned in mountains as big as its valleys.  The layout stage fixes the
 * scales above a third of a patch after the synthesis:
 *
 *   d(x)     Euclidean distance from output cell x to the sketch's features
 *   f(d)     c (1 - exp(-d / c)), c = one patch: the land keeps rising (for
 *            valleys; falling for ridges) away from the strokes, ever more
 *            gently, over about two patches
 *   T(x)     level - s G f(d(x)), s = +1 for ridges, -1 for valleys;
 *            level the mean height of the exemplar's main features of that
 *            kind, G chosen so that T, blurred at the layout scale, is as
 *            steep on average as the exemplar blurred at that scale: the
 *            guide carries the exemplar's large-scale steepness, no more
 *   out     out + strength * w * B(T - out), B a Gaussian blur of sigma a
 *            third of a patch (three box passes, NaN-aware), w fading to 0
 *            at fixed cells (pinned windows, water), which never change.
 *
 * So the output keeps every detail the patches gave below the layout scale
 * (seams, crests, roughness) and takes its coarse shape from the sketch.
 * Cost: O(cells) per blur, whatever sigma.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "layout.h"
#include "relief_guide.h"

/* ---- NaN-aware blur ------------------------------------------------- */

typedef struct blur_job {
    int w, h, r;       /* box radius */
    double *v, *m;     /* value * weight and weight, w*h, blurred in place */
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
    double *tmp = ts_malloc_array((size_t)j->w, sizeof *tmp);
    size_t y;
    int p;
    if (!tmp) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (y = b; y < e; y++)
        for (p = 0; p < 3; p++) {
            box_line(j->v + y * (size_t)j->w, (size_t)j->w, 1, j->r, tmp);
            box_line(j->m + y * (size_t)j->w, (size_t)j->w, 1, j->r, tmp);
        }
    free(tmp);
}

static void blur_cols(void *arg, size_t b, size_t e)
{
    blur_job *j = arg;
    double *tmp = ts_malloc_array((size_t)j->h, sizeof *tmp);
    size_t x;
    int p;
    if (!tmp) {
        atomic_store(&j->failed, 1);
        return;
    }
    for (x = b; x < e; x++)
        for (p = 0; p < 3; p++) {
            box_line(j->v + x, (size_t)j->h, (size_t)j->w, j->r, tmp);
            box_line(j->m + x, (size_t)j->h, (size_t)j->w, j->r, tmp);
        }
    free(tmp);
}

int ts_blur_radius(double sigma)
{
    /* three boxes of width n = 2r + 1 have variance 3 (n^2 - 1) / 12 */
    double n = sqrt(4.0 * sigma * sigma + 1.0);
    int r = (int)lround(0.5 * (n - 1.0));
    return r < 0 ? 0 : r;
}

ts_status ts_blur_nan(ts_ctx *ctx, const float *in, ptrdiff_t stride, int w, int h,
                      double sigma, float *out)
{
    size_t n = (size_t)w * (size_t)h, i;
    blur_job j;
    j.w = w;
    j.h = h;
    j.r = ts_blur_radius(sigma);
    atomic_init(&j.failed, 0);
    j.v = ts_malloc_array(n, sizeof(double));
    j.m = ts_malloc_array(n, sizeof(double));
    if (!j.v || !j.m) {
        free(j.v);
        free(j.m);
        return ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    }
    for (i = 0; i < n; i++) {
        float v = in[(i / (size_t)w) * (size_t)stride + i % (size_t)w];
        j.v[i] = isnan(v) ? 0.0 : v;
        j.m[i] = isnan(v) ? 0.0 : 1.0;
    }
    if (j.r > 0) {
        ts_parallel_for(ctx, (size_t)h, blur_rows, &j);
        if (!atomic_load(&j.failed))
            ts_parallel_for(ctx, (size_t)w, blur_cols, &j);
    }
    for (i = 0; i < n; i++)
        out[i] = j.m[i] > 1e-9 ? (float)(j.v[i] / j.m[i]) : NAN;
    free(j.v);
    free(j.m);
    if (atomic_load(&j.failed))
        return ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    return TS_OK;
}

double ts_mean_gradient(const float *a, int w, int h)
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

/* ---- the guide ------------------------------------------------------ */

/* f(d): rises like d near the strokes, levels off over about 2c */
static double layout_reach(double d, double c)
{
    return c * (1.0 - exp(-d / c));
}

ts_status ts_layout_guide(ts_ctx *ctx, const ts_layout_spec *s, float *guide)
{
    int W = s->width, H = s->height, e, n_valid = 0;
    size_t n = (size_t)W * (size_t)H, i;
    double sign = s->kind == TS_VALLEY ? -1.0 : 1.0, m1, c = s->reach;
    double *G = ts_calloc_array((size_t)s->n_exemplars, sizeof *G);
    double *level = ts_calloc_array((size_t)s->n_exemplars, sizeof *level);
    int *ok = ts_calloc_array((size_t)s->n_exemplars, sizeof *ok);
    unsigned char *m = ts_malloc_array(n, 1);
    float *dist = ts_malloc_array(n, sizeof(float));
    float *tmp = NULL, *blurred = NULL;
    double G_all = 0.0, level_all = 0.0;
    ts_status st = TS_OK;
    if (!G || !level || !ok || !m || !dist) {
        st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (i = 0; i < n; i++)
        m[i] = (s->sketch_mask[i] & s->kind) != 0;
    if ((st = ts_distance_transform(ctx, m, W, H, dist)) != TS_OK)
        goto done;
    /* how steep f is at the layout scale on this grid */
    tmp = ts_malloc_array(n, sizeof(float));
    blurred = ts_malloc_array(n, sizeof(float));
    if (!tmp || !blurred) {
        st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (i = 0; i < n; i++)
        tmp[i] = (s->nodata && s->nodata[i]) || !isfinite(dist[i])
                     ? NAN
                     : (float)layout_reach(dist[i], c);
    if ((st = ts_blur_nan(ctx, tmp, W, W, H, s->sigma, blurred)) != TS_OK)
        goto done;
    m1 = ts_mean_gradient(blurred, W, H);
    /* how steep each exemplar is at that scale, and its features' level */
    for (e = 0; e < s->n_exemplars && m1 > 0; e++) {
        const ts_raster *ex = &s->exemplars[e];
        size_t ne = (size_t)ex->width * (size_t)ex->height;
        float *eb = ts_malloc_array(ne, sizeof(float));
        double mE;
        if (!eb) {
            st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
            goto done;
        }
        st = ts_blur_nan(ctx, ex->data, ex->stride, ex->width, ex->height, s->sigma, eb);
        mE = st == TS_OK ? ts_mean_gradient(eb, ex->width, ex->height) : 0.0;
        free(eb);
        if (st != TS_OK)
            goto done;
        if (!(mE > 0) || !s->profs || !s->profs[e].valid)
            continue;
        G[e] = mE / m1;
        level[e] = s->profs[e].level;
        ok[e] = 1;
        G_all += G[e];
        level_all += level[e];
        n_valid++;
    }
    if (!n_valid) {
        for (i = 0; i < n; i++)
            guide[i] = NAN;
        goto done;
    }
    G_all /= n_valid;
    level_all /= n_valid;
    for (i = 0; i < n; i++) {
        int ce = s->cell_exemplar ? s->cell_exemplar[i] : -1;
        double g = G_all, l = level_all;
        if ((s->nodata && s->nodata[i]) || !isfinite(dist[i])) {
            guide[i] = NAN;
            continue;
        }
        if (ce >= 0 && ce < s->n_exemplars && ok[ce]) {
            g = G[ce];
            l = level[ce];
        }
        guide[i] = (float)(l - sign * g * layout_reach(dist[i], c));
    }
done:
    free(G);
    free(level);
    free(ok);
    free(m);
    free(dist);
    free(tmp);
    free(blurred);
    return st;
}

ts_status ts_layout_apply(ts_ctx *ctx, ts_raster *out, const float *guide,
                          const unsigned char *flags, double sigma, double strength)
{
    int W = out->width, H = out->height, x, y;
    size_t n = (size_t)W * (size_t)H, i;
    float *res = ts_malloc_array(n, sizeof(float));
    float *corr = ts_malloc_array(n, sizeof(float));
    float *fixd = NULL;
    unsigned char *fm = NULL;
    int any_fixed = 0;
    ts_status st;
    if (!res || !corr) {
        st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            i = (size_t)y * (size_t)W + (size_t)x;
            res[i] = guide[i] - TS_PIX(out, x, y); /* NaN where either is */
            any_fixed |= flags && (flags[i] & TS_CELL_FIXED);
        }
    if ((st = ts_blur_nan(ctx, res, W, W, H, sigma, corr)) != TS_OK)
        goto done;
    /* the correction fades out towards fixed cells, which keep their values */
    if (any_fixed) {
        fixd = ts_malloc_array(n, sizeof(float));
        fm = ts_malloc_array(n, 1);
        if (!fixd || !fm) {
            st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
            goto done;
        }
        for (i = 0; i < n; i++)
            fm[i] = (flags[i] & TS_CELL_FIXED) != 0;
        if ((st = ts_distance_transform(ctx, fm, W, H, fixd)) != TS_OK)
            goto done;
    }
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            double wgt = strength, c;
            i = (size_t)y * (size_t)W + (size_t)x;
            c = corr[i];
            if (isnan(TS_PIX(out, x, y)) || isnan(c))
                continue;
            if (fixd) {
                double t = fixd[i] / (2.0 * sigma);
                t = t > 1.0 ? 1.0 : t;
                wgt *= t * t * (3.0 - 2.0 * t);
            }
            TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + wgt * c);
        }
done:
    free(res);
    free(corr);
    free(fixd);
    free(fm);
    return st;
}
