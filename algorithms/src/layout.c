/*
 * layout.c - the relief a sketch lays out (a TerraSynth addition to Zhou et
 * al. 2007, in the spirit of the guide of Cruz et al., whose coarse pyramid
 * levels come from a guide and the fine ones from the exemplars).
 *
 * Feature patches put an exemplar ridge (valley) along every stroke, but
 * patch merging keeps only gradients, so the level of every patch drifts
 * with its neighbours, and the fill grows relief of its own between the
 * strokes: a valley network drawn over rugged mountains drowned in
 * mountains as big as its valleys, and a sketched crest was one crest among
 * many.  After the synthesis, two corrections, each the blur of a guide
 * minus the output, added to the output:
 *
 *   layout   at sigma_l = P/3 (P the patch), everywhere:
 *            T(x) = level - s G f_P(d(x)), d the distance to the sketch's
 *            features, s = +1 for ridges, -1 for valleys, f_c(d) =
 *            c (1 - exp(-d / c)) (the land keeps falling away from a ridge,
 *            ever more gently, over about 2c), level the mean height of the
 *            exemplar's main features of that kind;
 *   crest    at sigma_c = P/8, after the layout, fading out as
 *            exp(-(2d/P)^2):
 *            T_c(x) = crest(p(x)) - s G_c f_{P/4}(d(x)), p(x) the nearest
 *            feature cell, crest() the output along the features smoothed
 *            over sigma_c: the crest keeps its own rises and saddles along
 *            the stroke, and stands out across it.
 *
 * G is chosen so that the guide, blurred at its scale, is on average as
 * steep as the exemplar blurred at that scale: the layout carries the
 * exemplar's steepness, no more.  G_c likewise (measured within P/2 of the
 * features), times LAYOUT_CREST_GAIN: sketched crests are main features,
 * sharper than most of the land.  The
 * output keeps every detail of the patches below each scale.  Both fade to
 * nothing at fixed cells (pinned windows, water), which never change.
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

/* ---- the two corrections ------------------------------------------ */

/* The crest stands out 1.5 times as steeply as the exemplar's land falls on
 * average at its scale: sketched strokes are the main features, so they
 * are sharper than most of the land (measured over the quality matrix of
 * bench/quality: 1 left a quarter of the sketched crests as soft as the
 * land around, 2 dug trenches in steep exemplars). */
#define LAYOUT_CREST_GAIN 1.5

/* f_c(d): rises like d near the features, levels off over about 2c */
static double layout_reach(double d, double c)
{
    return c * (1.0 - exp(-d / c));
}

/* Mean gradient of f_c(dist) blurred at sigma, over the cells within dmax
 * of the features (all when dmax is infinite). */
static ts_status layout_reach_gradient(ts_ctx *ctx, const float *dist, const unsigned char *nodata,
                                       int W, int H, double c, double sigma, double dmax,
                                       double *g)
{
    size_t n = (size_t)W * (size_t)H, i;
    float *t = ts_malloc_array(n, sizeof(float)), *b = ts_malloc_array(n, sizeof(float));
    ts_status st = TS_OK;
    if (!t || !b) {
        st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (i = 0; i < n; i++)
        t[i] = (nodata && nodata[i]) || !isfinite(dist[i]) ? NAN : (float)layout_reach(dist[i], c);
    if ((st = ts_blur_nan(ctx, t, W, W, H, sigma, b)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        if (!(dist[i] <= dmax))
            b[i] = NAN; /* gradients next to these are left out */
    *g = ts_mean_gradient(b, W, H);
done:
    free(t);
    free(b);
    return st;
}

/* Mean gradient of every exemplar blurred at sigma (0 where unknown). */
static ts_status layout_exemplar_gradients(ts_ctx *ctx, const ts_layout_spec *s, double sigma,
                                           double *g)
{
    int e;
    for (e = 0; e < s->n_exemplars; e++) {
        const ts_raster *ex = &s->exemplars[e];
        float *eb = ts_malloc_array((size_t)ex->width * (size_t)ex->height, sizeof(float));
        ts_status st;
        if (!eb)
            return ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        st = ts_blur_nan(ctx, ex->data, ex->stride, ex->width, ex->height, sigma, eb);
        g[e] = st == TS_OK ? ts_mean_gradient(eb, ex->width, ex->height) : 0.0;
        free(eb);
        if (st != TS_OK)
            return st;
    }
    return TS_OK;
}

/* The steepness and level that cell i takes: its region's exemplar, or the
 * mean over the exemplars (those with a steepness). */
static void layout_pick(const ts_layout_spec *s, const double *gain, const double *levels,
                        size_t i, double *g, double *level)
{
    int e, n = 0, ce = s->cell_exemplar ? s->cell_exemplar[i] : -1;
    if (ce >= 0 && ce < s->n_exemplars && gain[ce] > 0) {
        *g = gain[ce];
        *level = levels[ce];
        return;
    }
    *g = *level = 0.0;
    for (e = 0; e < s->n_exemplars; e++)
        if (gain[e] > 0) {
            *g += gain[e];
            *level += levels[e];
            n++;
        }
    if (n) {
        *g /= n;
        *level /= n;
    }
}

/* out += weight * blur_sigma(guide - out), weight = strength *
 * fade(fixed) * (near > 0 ? exp(-(d / near)^2) : 1). */
static ts_status layout_correct(ts_ctx *ctx, ts_raster *out, const float *guide, double sigma,
                                double strength, const float *fixd, const float *dist,
                                double near, float *work, float *corr)
{
    int W = out->width, H = out->height, x, y;
    size_t i;
    ts_status st;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            i = (size_t)y * (size_t)W + (size_t)x;
            work[i] = guide[i] - TS_PIX(out, x, y); /* NaN where either is */
        }
    if ((st = ts_blur_nan(ctx, work, W, W, H, sigma, corr)) != TS_OK)
        return st;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            double w = strength, c;
            i = (size_t)y * (size_t)W + (size_t)x;
            c = corr[i];
            if (isnan(TS_PIX(out, x, y)) || isnan(c))
                continue;
            if (fixd) {
                double t = fixd[i] / (2.0 * sigma);
                t = t > 1.0 ? 1.0 : t;
                w *= t * t * (3.0 - 2.0 * t);
            }
            if (near > 0)
                w *= exp(-(dist[i] / near) * (dist[i] / near));
            TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + w * c);
        }
    return TS_OK;
}

ts_status ts_layout_apply(ts_ctx *ctx, const ts_layout_spec *s, ts_raster *out,
                          const unsigned char *flags, double strength)
{
    int W = s->width, H = s->height, any_fixed = 0, e;
    size_t n = (size_t)W * (size_t)H, i;
    double P = s->patch, sig_l = P / 3.0, sig_c = P / 8.0, c_l = P, c_c = P / 4.0, g1, gc1;
    double sign = s->kind == TS_VALLEY ? -1.0 : 1.0;
    unsigned char *m = ts_malloc_array(n, 1);
    float *dist = ts_malloc_array(n, sizeof(float));
    int32_t *nearest = ts_malloc_array(n, sizeof(int32_t));
    float *guide = ts_malloc_array(n, sizeof(float));
    float *work = ts_malloc_array(n, sizeof(float));
    float *corr = ts_malloc_array(n, sizeof(float));
    double *gl = ts_calloc_array((size_t)s->n_exemplars, sizeof(double));
    double *gc = ts_calloc_array((size_t)s->n_exemplars, sizeof(double));
    double *levels = ts_calloc_array((size_t)s->n_exemplars, sizeof(double));
    float *fixd = NULL;
    ts_status st = TS_OK;
    if (!m || !dist || !nearest || !guide || !work || !corr || !gl || !gc || !levels) {
        st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    /* the level of the features: the exemplar's main features of the kind,
     * or, when it has none, its mean height */
    for (e = 0; e < s->n_exemplars; e++) {
        ts_raster_stats rs;
        if (s->profs && s->profs[e].valid)
            levels[e] = s->profs[e].level;
        else if (ts_raster_stats_compute(ctx, &s->exemplars[e], &rs) == TS_OK)
            levels[e] = rs.mean;
    }
    ts_clear(ctx);
    for (i = 0; i < n; i++) {
        m[i] = (s->sketch_mask[i] & s->kind) != 0;
        any_fixed |= flags && (flags[i] & TS_CELL_FIXED);
    }
    if (!(strength > 0))
        goto done;
    if ((st = ts_distance_transform_nearest(ctx, m, W, H, dist, nearest)) != TS_OK)
        goto done;
    if (any_fixed) {
        /* the corrections fade out towards fixed cells, which keep their values */
        if (!(fixd = ts_malloc_array(n, sizeof(float)))) {
            st = ts_fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
            goto done;
        }
        for (i = 0; i < n; i++)
            m[i] = (flags[i] & TS_CELL_FIXED) != 0;
        if ((st = ts_distance_transform(ctx, m, W, H, fixd)) != TS_OK)
            goto done;
    }
    /* steepness of the guides and of the exemplars at both scales */
    if ((st = layout_reach_gradient(ctx, dist, s->nodata, W, H, c_l, sig_l, INFINITY, &g1)) !=
            TS_OK ||
        (st = layout_reach_gradient(ctx, dist, s->nodata, W, H, c_c, sig_c, 2.0 * c_c, &gc1)) !=
            TS_OK ||
        (st = layout_exemplar_gradients(ctx, s, sig_l, gl)) != TS_OK ||
        (st = layout_exemplar_gradients(ctx, s, sig_c, gc)) != TS_OK)
        goto done;
    if (!(g1 > 0) || !(gc1 > 0))
        goto done; /* no feature on the grid */
    for (e = 0; e < s->n_exemplars; e++) {
        gl[e] /= g1;
        gc[e] /= gc1;
        gc[e] *= LAYOUT_CREST_GAIN;
    }
    /* the layout */
    for (i = 0; i < n; i++) {
        double g, level;
        layout_pick(s, gl, levels, i, &g, &level);
        guide[i] = (s->nodata && s->nodata[i]) || !isfinite(dist[i])
                       ? NAN
                       : (float)(level - sign * g * layout_reach(dist[i], c_l));
    }
    if ((st = layout_correct(ctx, out, guide, sig_l, strength, fixd, dist, 0.0, work, corr)) !=
        TS_OK)
        goto done;
    /* the crest: the output along the features, smoothed along them */
    for (i = 0; i < n; i++)
        work[i] = (s->sketch_mask[i] & s->kind)
                      ? out->data[(i / (size_t)W) * (size_t)out->stride + i % (size_t)W]
                      : NAN;
    if ((st = ts_blur_nan(ctx, work, W, W, H, sig_c, corr)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++) {
        double g, level;
        layout_pick(s, gc, levels, i, &g, &level);
        guide[i] = (s->nodata && s->nodata[i]) || nearest[i] < 0
                       ? NAN
                       : (float)(corr[nearest[i]] - sign * g * layout_reach(dist[i], c_c));
    }
    st = layout_correct(ctx, out, guide, sig_c, strength, fixd, dist, 0.5 * P, work, corr);
done:
    free(m);
    free(dist);
    free(nearest);
    free(guide);
    free(work);
    free(corr);
    free(gl);
    free(gc);
    free(levels);
    free(fixd);
    return st;
}
