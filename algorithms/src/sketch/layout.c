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
 *            exemplar's main features of that kind, along ridges plus the
 *            exemplar's own peaks and saddles (crest_profile.c), faded
 *            with d (the part finer than sigma_l, which the blur would
 *            drop, is added as it is);
 *   crest    at sigma_c = P/8, after the layout, fading out as
 *            exp(-(2d/P)^2):
 *            T_c(x) = crest(p(x)) - s G_c f_{P/4}(d(x)), p(x) the nearest
 *            feature cell, crest() the output along the features smoothed
 *            over sigma_c (the crest profile's offsets unsmoothed, the
 *            flanks taking only their faded share): the crest keeps its
 *            own rises and saddles along the stroke, and stands out across
 *            it.
 *
 * G is chosen so that the guide, blurred at its scale, is on average as
 * steep as the exemplar blurred at that scale: the layout carries the
 * exemplar's steepness, no more; G_c likewise, measured within P/2 of the
 * features.  Both are then scaled together by the factor (0.35..2.5, or
 * 1..2.5 when the slope style follows) that
 * brings the output's distribution of slopes closest to the exemplars'
 * (patch merging flattens a little; a steep exemplar's guide adds to its
 * own slopes).  For valleys, the layout's level along the features is the
 * output's own floor made to descend to each network's outlet, and after
 * both corrections the floor is made to descend cell by cell.  The
 * output keeps every detail of the patches below each scale.  Both fade to
 * nothing at fixed cells (pinned windows, water), which never change.
 * Cost: O(cells) per blur, whatever sigma; blurs wider than 16 cells run on
 * a grid 2 to 8 times coarser (ts__blur_nan_coarse).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "layout.h"
#include "relief_guide.h"

/* Blur buffers reused by the layout's many blurs of the output's size. */
typedef struct layout_ws {
    double *v, *m;
    size_t cap;
} layout_ws;

static ts_status lblur(ts_ctx *ctx, const layout_ws *ws, const float *in, ptrdiff_t stride, int w,
                       int h, double sigma, float *out)
{
    if (ts__blur_coarse_factor(sigma, w, h) > 1)
        return ts__blur_nan_coarse(ctx, in, stride, w, h, sigma, out);
    if (!ws || (size_t)w * (size_t)h > ws->cap)
        return ts__blur_nan(ctx, in, stride, w, h, sigma, out);
    return ts__blur_nan_buffers(ctx, in, stride, w, h, sigma, out, ws->v, ws->m);
}

/* ---- the two corrections ------------------------------------------ */

/* f_c(d): rises like d near the features, levels off over about 2c */
static double layout_reach(double d, double c)
{
    return c * (1.0 - exp(-d / c));
}

/* Mean gradient of f_c(dist) (or of `shape`, when given) blurred at sigma,
 * over the cells within dmax of the features (all when dmax is infinite). */
static ts_status layout_reach_gradient(ts_ctx *ctx, const layout_ws *ws, const float *dist,
                                       const float *shape, const unsigned char *nodata, int W,
                                       int H, double c, double sigma, double dmax, double *g)
{
    size_t n = (size_t)W * (size_t)H, i;
    float *t = ts__malloc_array(n, sizeof(float)), *b = ts__malloc_array(n, sizeof(float));
    ts_status st = TS_OK;
    if (!t || !b) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    for (i = 0; i < n; i++)
        t[i] = (nodata && nodata[i]) || !isfinite(dist[i]) ? NAN
               : shape                                     ? shape[i]
                                                           : (float)layout_reach(dist[i], c);
    if ((st = lblur(ctx, ws, t, W, W, H, sigma, b)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        if (!(dist[i] <= dmax))
            b[i] = NAN; /* gradients next to these are left out */
    *g = ts__mean_gradient(b, W, H);
done:
    free(t);
    free(b);
    return st;
}

/* The steepness and level that cell i takes: its region's exemplar, or the
 * mean over the exemplars (those with a steepness). */
static void layout_pick(const ts_layout_spec *s, const double *gain, const double *levels, size_t i,
                        double *g, double *level)
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

/* The weight of a change at cell i: 1, fading out smoothly within 2 sigma
 * of fixed cells (fixd: the distance to them, or NULL). */
static double layout_fade(const float *fixd, size_t i, double sigma)
{
    double t;
    if (!fixd)
        return 1.0;
    t = fixd[i] / (2.0 * sigma);
    t = t > 1.0 ? 1.0 : t;
    return t * t * (3.0 - 2.0 * t);
}

/* out += strength * add, fading out within 2 sigma of fixed cells. */
static void layout_add(ts_raster *out, const float *add, double strength, const float *fixd,
                       double sigma)
{
    int W = out->width, H = out->height, x, y;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            size_t i = (size_t)y * (size_t)W + (size_t)x;
            if (!isnan(TS_PIX(out, x, y)))
                TS_PIX(out, x, y) =
                    (float)(TS_PIX(out, x, y) + strength * layout_fade(fixd, i, sigma) * add[i]);
        }
}

/* What layout_correct's second loop reads. */
typedef struct layout_apply_job {
    ts_raster *out;
    const float *corr, *fixd, *dist, *gate;
    double sigma, strength, near;
} layout_apply_job;

/* Rows [y0, y1) of out += weight * corr (layout_correct). */
static void layout_apply_rows(void *arg, size_t y0, size_t y1)
{
    const layout_apply_job *j = arg;
    ts_raster *out = j->out;
    int W = out->width, x, y;
    for (y = (int)y0; y < (int)y1; y++)
        for (x = 0; x < W; x++) {
            size_t i = (size_t)y * (size_t)W + (size_t)x;
            double w = j->strength, c = j->corr[i];
            if (isnan(TS_PIX(out, x, y)) || isnan(c))
                continue;
            w *= layout_fade(j->fixd, i, j->sigma);
            if (j->near > 0)
                w *= exp(-(j->dist[i] / j->near) * (j->dist[i] / j->near));
            if (j->gate)
                w *= j->gate[i];
            TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + w * c);
        }
}

/* out += weight * blur_sigma(guide - out), weight = strength *
 * fade(fixed) * (near > 0 ? exp(-(d / near)^2) : 1). */
static ts_status layout_correct(ts_ctx *ctx, const layout_ws *ws, ts_raster *out,
                                const float *guide, double sigma, double strength,
                                const float *fixd, const float *dist, double near,
                                const float *gate, float *work, float *corr)
{
    int W = out->width, H = out->height, x, y;
    layout_apply_job j;
    ts_status st;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            size_t i = (size_t)y * (size_t)W + (size_t)x;
            work[i] = guide[i] - TS_PIX(out, x, y); /* NaN where either is */
        }
    if ((st = lblur(ctx, ws, work, W, W, H, sigma, corr)) != TS_OK)
        return st;
    j.out = out;
    j.corr = corr;
    j.fixd = fixd;
    j.dist = dist;
    j.gate = gate;
    j.sigma = sigma;
    j.strength = strength;
    j.near = near;
    ts__parallel_for(ctx, (size_t)H, layout_apply_rows, &j);
    return TS_OK;
}

/* With both kinds: the distance to and the nearest cell of the ridges
 * (_r), the valleys (_vf), and the valleys less their heads near a crest
 * (_v: a valley's head stops short of the crest it comes down from); the
 * weight of the crest correction's slope (gate: 1 where a feature stands
 * alone, 0 where the other kind is within reach). */
typedef struct layout_both {
    float *dist_r, *dist_vf, *dist_v, *gate;
    int32_t *near_r, *near_vf, *near_v;
} layout_both;

static void layout_both_free(layout_both *b)
{
    free(b->dist_r);
    free(b->dist_vf);
    free(b->dist_v);
    free(b->gate);
    free(b->near_r);
    free(b->near_vf);
    free(b->near_v);
    memset(b, 0, sizeof *b);
}

/* What both corrections need, computed once.  kind: the kinds on the grid
 * (bits).  dist, nearest: to the nearest feature of any kind; near_v: the
 * nearest valley cell whose floor sets the level (valleys alone: nearest;
 * both kinds: b->near_v). */
typedef struct layout_run_data {
    const ts_layout_spec *s;
    int kind;
    double strength, sig_l, sig_c, c_l, c_c;
    const float *dist, *fixd;
    const int32_t *nearest, *near_v;
    const layout_both *b; /* with both kinds, else NULL */
    const double *gl, *gc, *levels;
    float *crest, *crest_hp; /* the ridges' peaks and saddles (ts__crest_field) and their
                                part finer than the layout's blur, or NULL (owned) */
    float *crest_s;          /* crest on the ridges smoothed as the crest pass smooths */
    float *vlev; /* the valley floors' level (layout_valley_levels), or NULL without valleys */
    float *guide, *work, *corr, *corr2, *blurred; /* blurred: layout_correct's blur */
    const layout_ws *ws;
} layout_run_data;

/* The layout's shape at cell i for a unit steepness (its height over the
 * level): ridges -f(d), valleys +f(d); both kinds f(d_v) - f(d_r) + c:
 * the valleys' own (0 on a floor far from ridges, c around it) less the
 * ridges' (0 on a crest, c around it): a crest stands c above the land far
 * from both and a floor c below it, a ridge next to a valley rises from it
 * all the way, and a valley's head near a crest shallows out towards it. */
static double layout_shape(const layout_run_data *d, size_t i, double c)
{
    if (d->kind == TS_RIDGE)
        return -layout_reach(d->dist[i], c);
    if (d->kind == TS_VALLEY)
        return layout_reach(d->dist[i], c);
    if (d->near_v[i] < 0 || !isfinite(d->b->dist_r[i]))
        return NAN;
    return layout_reach(d->b->dist_v[i], c) - layout_reach(d->b->dist_r[i], c) + c;
}

/* The output on the cells of the sketch's `kind` features, NaN elsewhere. */
static void layout_on_features(const layout_run_data *d, const ts_raster *r, int kind, float *work)
{
    int W = d->s->width;
    size_t n = (size_t)W * (size_t)d->s->height, i;
    for (i = 0; i < n; i++)
        work[i] = (d->s->sketch_mask[i] & kind)
                      ? r->data[(i / (size_t)W) * (size_t)r->stride + i % (size_t)W]
                      : NAN;
}

/* A guide's cells [b, e) for layout_run: the layout's (layout_guide_cells)
 * or the crest's (layout_crest_cells), the guides' steepness times lam. */
typedef struct layout_guide_job {
    const layout_run_data *d;
    double lam;
} layout_guide_job;

static void layout_guide_cells(void *arg, size_t b, size_t e)
{
    const layout_guide_job *j = arg;
    const layout_run_data *d = j->d;
    const ts_layout_spec *s = d->s;
    size_t i;
    for (i = b; i < e; i++) {
        double g, level;
        layout_pick(s, d->gl, d->levels, i, &g, &level);
        if (d->vlev && d->near_v[i] >= 0)
            level = d->vlev[d->near_v[i]];
        if (d->crest)
            level += d->crest[i];
        d->guide[i] = (s->nodata && s->nodata[i]) || !isfinite(d->dist[i])
                          ? NAN
                          : (float)(level + j->lam * g * layout_shape(d, i, d->c_l));
    }
}

static void layout_crest_cells(void *arg, size_t b, size_t e)
{
    const layout_guide_job *j = arg;
    const layout_run_data *d = j->d;
    const ts_layout_spec *s = d->s;
    size_t i;
    for (i = b; i < e; i++) {
        double g, level, sign = d->kind == TS_VALLEY ? -1.0 : 1.0, base;
        int32_t p = d->nearest[i];
        layout_pick(s, d->gc, d->levels, i, &g, &level);
        if ((s->nodata && s->nodata[i]) || p < 0) {
            d->guide[i] = NAN;
            continue;
        }
        base = d->corr[p];
        if (d->b && !(s->sketch_mask[p] & TS_RIDGE)) {
            base = d->corr2[p]; /* the floor of the nearest valley */
            sign = -1.0;
        } else if (d->crest) /* the peaks and saddles not smoothed along the
                              * crest; the flanks take only their faded share */
            base += d->crest[i] - d->crest_s[p];
        d->guide[i] = (float)(base - sign * j->lam * g * layout_reach(d->dist[i], d->c_c));
    }
}

/* The valley floors at the output's own level, smoothed along them over a
 * patch, made to descend to their outlets, smoothed again over half a patch
 * (filling and carving leave steps): d->vlev, the level the layout gives
 * the land beside them. */
static ts_status layout_valley_levels(ts_ctx *ctx, const layout_run_data *d, const ts_raster *r)
{
    const ts_layout_spec *s = d->s;
    int W = s->width, H = s->height;
    size_t n = (size_t)W * (size_t)H, i;
    ts_status st;
    layout_on_features(d, r, TS_VALLEY, d->work);
    if ((st = lblur(ctx, d->ws, d->work, W, W, H, s->patch, d->vlev)) != TS_OK ||
        (st = ts__valley_descend(ctx, s, d->vlev)) != TS_OK)
        return st;
    for (i = 0; i < n; i++)
        d->work[i] = (s->sketch_mask[i] & TS_VALLEY) ? d->vlev[i] : NAN;
    return lblur(ctx, d->ws, d->work, W, W, H, 0.5 * s->patch, d->vlev);
}

/* The layout correction on r, its guide's steepness times lam. */
static ts_status layout_pass(ts_ctx *ctx, const layout_run_data *d, ts_raster *r, double lam)
{
    layout_guide_job j;
    ts_status st;
    j.d = d;
    j.lam = lam;
    ts__parallel_for(ctx, (size_t)d->s->width * (size_t)d->s->height, layout_guide_cells, &j);
    if ((st = layout_correct(ctx, d->ws, r, d->guide, d->sig_l, d->strength, d->fixd, d->dist, 0.0,
                             NULL, d->work, d->blurred)) != TS_OK)
        return st;
    if (d->crest_hp) /* what the layout's blur leaves out of the peaks and saddles */
        layout_add(r, d->crest_hp, d->strength, d->fixd, d->sig_l);
    return TS_OK;
}

/* The crest's levels: r along the features of each kind, smoothed along
 * them over a quarter patch (d->corr; d->corr2 the valleys' with both). */
static ts_status layout_crest_levels(ts_ctx *ctx, const layout_run_data *d, const ts_raster *r)
{
    int W = d->s->width, H = d->s->height;
    ts_status st;
    layout_on_features(d, r, d->kind == (TS_RIDGE | TS_VALLEY) ? TS_RIDGE : d->kind, d->work);
    if ((st = lblur(ctx, d->ws, d->work, W, W, H, 2.0 * d->sig_c, d->corr)) != TS_OK)
        return st;
    if (d->kind != (TS_RIDGE | TS_VALLEY))
        return TS_OK;
    layout_on_features(d, r, TS_VALLEY, d->work);
    return lblur(ctx, d->ws, d->work, W, W, H, 2.0 * d->sig_c, d->corr2);
}

/* The crest correction on r from the levels of layout_crest_levels, its
 * guide's steepness times lam: the crest stands out across the features. */
static ts_status layout_crest_pass(ts_ctx *ctx, const layout_run_data *d, ts_raster *r, double lam)
{
    layout_guide_job j;
    j.d = d;
    j.lam = lam;
    ts__parallel_for(ctx, (size_t)d->s->width * (size_t)d->s->height, layout_crest_cells, &j);
    return layout_correct(ctx, d->ws, r, d->guide, d->sig_c, d->strength, d->fixd, d->dist,
                          0.5 * d->s->patch, d->b ? d->b->gate : NULL, d->work, d->blurred);
}

/* Both corrections, the layout everywhere, then the crest near the
 * features, on three copies of the output: out at both guides' steepness
 * 1, r0 at 0, r01 at the layout's 0 and the crest's 1.  The valleys' levels
 * come from the output as it is (the same for all three); r0 and r01 share
 * the layout pass and the crest's levels. */
static ts_status layout_runs(ts_ctx *ctx, const layout_run_data *d, ts_raster *out, ts_raster *r0,
                             ts_raster *r01)
{
    int y;
    ts_status st;
    if (d->vlev && (st = layout_valley_levels(ctx, d, out)) != TS_OK)
        return st;
    if ((st = layout_pass(ctx, d, out, 1.0)) != TS_OK ||
        (st = layout_crest_levels(ctx, d, out)) != TS_OK ||
        (st = layout_crest_pass(ctx, d, out, 1.0)) != TS_OK ||
        (st = layout_pass(ctx, d, r0, 0.0)) != TS_OK ||
        (st = layout_crest_levels(ctx, d, r0)) != TS_OK)
        return st;
    for (y = 0; y < r0->height; y++)
        memcpy(r01->data + (size_t)y * (size_t)r01->stride,
               r0->data + (size_t)y * (size_t)r0->stride, (size_t)r0->width * sizeof(float));
    if ((st = layout_crest_pass(ctx, d, r0, 0.0)) != TS_OK)
        return st;
    return layout_crest_pass(ctx, d, r01, 1.0);
}

/* The land's large-scale heights (out blurred at sigma) stay within the
 * exemplars' 1st to 99th percentile: beyond, they are pressed smoothly into
 * a margin of a tenth of that range, as a far lowland levels out; the
 * detail above them is kept; the change fades out within 2 sigma of fixed
 * cells (fixd: distance to them, or NULL).  work, blurred: W * H floats. */
static ts_status layout_press(ts_ctx *ctx, const layout_ws *ws, const ts_raster *exemplars,
                              int n_exemplars, ts_raster *out, const float *fixd, double sigma,
                              float *work, float *blurred)
{
    int W = out->width, H = out->height, x, y;
    double lo, hi, margin;
    ts_status st = TS_OK;
    if ((st = ts__exemplar_height_range(ctx, exemplars, n_exemplars, &lo, &hi)) != TS_OK)
        return st;
    margin = 0.1 * (hi - lo);
    for (y = 0; y < H; y++)
        memcpy(work + (size_t)y * (size_t)W, out->data + (size_t)y * (size_t)out->stride,
               (size_t)W * sizeof(float));
    if (isfinite(lo) && isfinite(hi) && margin > 0 &&
        (st = lblur(ctx, ws, work, W, W, H, sigma, blurred)) == TS_OK)
        for (y = 0; y < H; y++)
            for (x = 0; x < W; x++) {
                double L, w = 1.0, want;
                size_t i = (size_t)y * (size_t)W + (size_t)x;
                L = blurred[i];
                if (isnan(TS_PIX(out, x, y)) || isnan(L) || (L >= lo && L <= hi))
                    continue;
                want = L < lo ? lo - margin * (1.0 - exp((L - lo) / margin))
                              : hi + margin * (1.0 - exp((hi - L) / margin));
                w = layout_fade(fixd, i, sigma);
                TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + w * (want - L));
            }
    return st;
}

ts_status ts__layout_press_range(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                 ts_raster *out, const unsigned char *flags, int patch)
{
    size_t n = (size_t)out->width * (size_t)out->height, i;
    float *work = ts__malloc_array(n, sizeof(float)), *blurred = ts__malloc_array(n, sizeof(float));
    float *fixd = NULL;
    unsigned char *m = NULL;
    int any_fixed = 0;
    ts_status st = TS_OK;
    for (i = 0; flags && i < n; i++)
        any_fixed |= (flags[i] & TS_CELL_FIXED) != 0;
    if (any_fixed) {
        fixd = ts__malloc_array(n, sizeof(float));
        m = ts__malloc_array(n, 1);
    }
    if (!work || !blurred || (any_fixed && (!fixd || !m))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    if (any_fixed) {
        for (i = 0; i < n; i++)
            m[i] = (flags[i] & TS_CELL_FIXED) != 0;
        if ((st = ts__distance_transform(ctx, m, out->width, out->height, fixd)) != TS_OK)
            goto done;
    }
    st = layout_press(ctx, NULL, exemplars, n_exemplars, out, fixd, patch / 3.0, work, blurred);
done:
    free(work);
    free(blurred);
    free(fixd);
    free(m);
    return st;
}

/* The distances of both kinds (layout_both); nothing with one kind.
 * nearest: to any feature; m: work, width*height. */
static ts_status layout_kind_distances(ts_ctx *ctx, const ts_layout_spec *s, int kind, double P,
                                       unsigned char *m, const int32_t *nearest, layout_both *b)
{
    size_t n = (size_t)s->width * (size_t)s->height, i, kept = 0;
    ts_status st;
    if (kind != (TS_RIDGE | TS_VALLEY))
        return TS_OK;
    b->dist_r = ts__malloc_array(n, sizeof(float));
    b->dist_vf = ts__malloc_array(n, sizeof(float));
    b->dist_v = ts__malloc_array(n, sizeof(float));
    b->gate = ts__malloc_array(n, sizeof(float));
    b->near_r = ts__malloc_array(n, sizeof(int32_t));
    b->near_vf = ts__malloc_array(n, sizeof(int32_t));
    b->near_v = ts__malloc_array(n, sizeof(int32_t));
    if (!b->dist_r || !b->dist_vf || !b->dist_v || !b->gate || !b->near_r || !b->near_vf ||
        !b->near_v)
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    for (i = 0; i < n; i++)
        m[i] = (s->sketch_mask[i] & TS_RIDGE) != 0;
    if ((st = ts__distance_transform_nearest(ctx, m, s->width, s->height, b->dist_r, b->near_r)) !=
        TS_OK)
        return st;
    for (i = 0; i < n; i++)
        m[i] = (s->sketch_mask[i] & TS_VALLEY) != 0;
    if ((st = ts__distance_transform_nearest(ctx, m, s->width, s->height, b->dist_vf,
                                             b->near_vf)) != TS_OK)
        return st;
    /* the crest correction stands a feature out across it where it is
     * alone; where the other kind comes within 1.25 patches it fades out, and the
     * land takes the layout's slope between the two (two crests pulling
     * against each other, a ridge's down and a valley's up, made steps and
     * terraces between features drawn close) */
    for (i = 0; i < n; i++) {
        int32_t p = nearest[i];
        double o = p < 0 ? INFINITY : (s->sketch_mask[p] & TS_RIDGE) ? b->dist_vf[i] : b->dist_r[i];
        double t = o / (1.25 * P);
        t = t > 1.0 ? 1.0 : t;
        b->gate[i] = (float)(t * t * (3.0 - 2.0 * t));
    }
    /* a valley's head comes down from a crest, it does not notch it: the
     * valley cells within a quarter patch of a head (a valley end) that is
     * itself within a quarter patch of a ridge are left out */
    if (s->features) {
        const ts_features *f = s->features;
        int r = (int)ceil(0.25 * P), u, v;
        size_t k;
        for (k = 0; k < f->n_nodes; k++) {
            const ts_feature_node *nd = &f->nodes[k];
            if (nd->kind != TS_VALLEY || nd->degree != 1 || nd->x < 0 || nd->y < 0 ||
                nd->x >= s->width || nd->y >= s->height ||
                !(b->dist_r[(size_t)nd->y * (size_t)s->width + (size_t)nd->x] <= 0.25 * P))
                continue;
            for (v = TS_MAX(0, nd->y - r); v <= TS_MIN(s->height - 1, nd->y + r); v++)
                for (u = TS_MAX(0, nd->x - r); u <= TS_MIN(s->width - 1, nd->x + r); u++)
                    if ((u - nd->x) * (u - nd->x) + (v - nd->y) * (v - nd->y) <= r * r)
                        m[(size_t)v * (size_t)s->width + (size_t)u] = 0;
        }
    }
    for (i = 0; i < n; i++)
        kept += m[i];
    if (!kept)
        for (i = 0; i < n; i++)
            m[i] = (s->sketch_mask[i] & TS_VALLEY) != 0;
    return ts__distance_transform_nearest(ctx, m, s->width, s->height, b->dist_v, b->near_v);
}

/* The level of each exemplar's features: its main features of the kind,
 * or, when it has none, its mean height. */
static void layout_levels(ts_ctx *ctx, const ts_layout_spec *s, double *levels)
{
    int e;
    for (e = 0; e < s->n_exemplars; e++) {
        ts_raster_stats rs;
        if (s->profs && s->profs[e].valid)
            levels[e] = s->profs[e].level;
        else if (ts_raster_stats_compute(ctx, &s->exemplars[e], &rs) == TS_OK)
            levels[e] = rs.mean;
    }
    ts__clear(ctx);
}

/* Steepness of the guides and of the exemplars at both scales: gl and gc,
 * the exemplars' over the guides'.  *found: 0 when no feature is on the
 * grid.  shape: the layout's shape (both kinds), else NULL. */
static ts_status layout_calibrate(ts_ctx *ctx, const layout_run_data *d, const float *shape,
                                  double *gl, double *gc, int *found)
{
    const ts_layout_spec *s = d->s;
    int W = s->width, H = s->height, e;
    double g1, gc1;
    ts_status st;
    *found = 0;
    if ((st = layout_reach_gradient(ctx, d->ws, d->dist, shape, s->nodata, W, H, d->c_l, d->sig_l,
                                    INFINITY, &g1)) != TS_OK ||
        (st = layout_reach_gradient(ctx, d->ws, d->dist, NULL, s->nodata, W, H, d->c_c, d->sig_c,
                                    2.0 * d->c_c, &gc1)) != TS_OK ||
        (st = ts__exemplar_gradients(ctx, s->exemplars, s->n_exemplars, d->sig_l, gl)) != TS_OK ||
        (st = ts__exemplar_gradients(ctx, s->exemplars, s->n_exemplars, d->sig_c, gc)) != TS_OK)
        return st;
    if (!(g1 > 0) || !(gc1 > 0))
        return TS_OK; /* no feature on the grid */
    for (e = 0; e < s->n_exemplars; e++) {
        gl[e] /= g1;
        gc[e] /= gc1;
    }
    *found = 1;
    return TS_OK;
}

/* r0: a copy of out; returns the mean height of its cells away from fixed
 * ones. */
static double layout_copies(const layout_run_data *d, const ts_raster *out, float *r0)
{
    int W = d->s->width, H = d->s->height, y;
    size_t n = (size_t)W * (size_t)H, i, cnt = 0;
    double mean_before = 0.0;
    for (y = 0; y < H; y++) {
        memcpy(r0 + (size_t)y * (size_t)W, out->data + (size_t)y * (size_t)out->stride,
               (size_t)W * sizeof(float));
    }
    for (i = 0; i < n; i++)
        if (!isnan(r0[i]) && !(d->fixd && d->fixd[i] < 2.0 * d->sig_l)) {
            mean_before += r0[i];
            cnt++;
        }
    return cnt ? mean_before / (double)cnt : 0.0;
}

/* The layout moves heights about, not the land's mean height: the mean
 * (over the cells of r0 away from fixed ones) is put back where the
 * patches had it, mean_before (fading out near fixed cells). */
static void layout_keep_mean(const layout_run_data *d, ts_raster *out, const float *r0,
                             double mean_before)
{
    int W = d->s->width, H = d->s->height, x, y;
    size_t n = (size_t)W * (size_t)H, i, cnt = 0;
    const float *fixd = d->fixd;
    double after = 0.0, shift;
    for (i = 0; i < n; i++) {
        double z = out->data[(i / (size_t)W) * (size_t)out->stride + i % (size_t)W];
        if (isnan(z) || isnan(r0[i]) || (fixd && fixd[i] < 2.0 * d->sig_l))
            continue;
        after += z;
        cnt++;
    }
    shift = cnt ? (mean_before - after / (double)cnt) : 0.0;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            double w = 1.0;
            i = (size_t)y * (size_t)W + (size_t)x;
            if (isnan(TS_PIX(out, x, y)))
                continue;
            w = layout_fade(fixd, i, d->sig_l);
            TS_PIX(out, x, y) = (float)(TS_PIX(out, x, y) + w * shift);
        }
}

/* valleys: the floor along the sketch's features descends to the outlet
 * cell by cell, the change fading out across the valley over an eighth of
 * a patch (as a river would cut or fill its bed).  dist, nearest: to the
 * valleys (with both kinds d->b has them); d01: work, width*height. */
static ts_status layout_valley_floors(ts_ctx *ctx, const layout_run_data *d, ts_raster *out,
                                      const float *dist, const int32_t *nearest, float *d01)
{
    const ts_layout_spec *s = d->s;
    int W = s->width, H = s->height, x, y;
    size_t n = (size_t)W * (size_t)H, i;
    double P = s->patch, rr = P / 8.0;
    float *work = d->work, *corr = d->corr, *guide = d->guide;
    const float *fixd = d->fixd;
    ts_status st;
    for (i = 0; i < n; i++) {
        float v = out->data[(i / (size_t)W) * (size_t)out->stride + i % (size_t)W];
        work[i] = (s->sketch_mask[i] & TS_VALLEY) && !(fixd && fixd[i] < 1.0f) ? v : NAN;
        corr[i] = work[i];
    }
    if ((st = ts__valley_descend(ctx, s, corr)) != TS_OK)
        return st;
    /* the change on the floor line, and its normalised blur at rr / 2
     * (defined off the line too): the blur spreads across the valley,
     * the rest (the floor's own cell-to-cell bumps, levelled) stays on
     * the line, so the floor still descends cell by cell.  Spreading
     * the change itself from each cell's nearest floor cell made
     * stripes across the valley, one per step of the line's staircase */
    for (i = 0; i < n; i++)
        corr[i] = isnan(work[i]) || isnan(corr[i]) ? NAN : corr[i] - work[i];
    if ((st = lblur(ctx, d->ws, corr, W, W, H, 0.5 * rr, guide)) != TS_OK)
        return st;
    /* the fall-off across the valley from the distance blurred at 2
     * cells: the distance to a staircase of cells ripples along it (a
     * third of a cell, once a step), and a floor moved by tens of
     * metres drew those ripples as a ladder across the valley */
    if ((st = lblur(ctx, d->ws, dist, W, W, H, 2.0, d01)) != TS_OK)
        return st;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            double w;
            i = (size_t)y * (size_t)W + (size_t)x;
            if (nearest[i] < 0 || isnan(TS_PIX(out, x, y)) || isnan(guide[i]) ||
                !(dist[i] < 3.0 * rr))
                continue;
            /* on the floor line its own change (the floor descends cell
             * by cell), beside it the smooth part fading out */
            w = isnan(corr[i]) ? d->strength * exp(-(d01[i] / rr) * (d01[i] / rr)) : d->strength;
            w *= layout_fade(fixd, i, rr);
            TS_PIX(out, x, y) =
                (float)(TS_PIX(out, x, y) + w * (isnan(corr[i]) ? guide[i] : corr[i]));
        }
    return TS_OK;
}

/* The ridges' peaks and saddles (crest_profile.c) for the layout pass
 * and the crest pass: d->crest, d->crest_hp, and d->crest_s, the crest on
 * the ridges smoothed as the crest pass smooths the output's. */
static ts_status layout_crest_setup(ts_ctx *ctx, layout_run_data *d)
{
    const ts_layout_spec *s = d->s;
    size_t n = (size_t)s->width * (size_t)s->height;
    double P = s->patch;
    ts_raster cr;
    ts_status st = ts__crest_field(ctx, s->features, s->crest, s->n_exemplars, s->cell_exemplar,
                                   s->patch, d->b ? d->b->dist_vf : NULL, P / 4.0, d->sig_l,
                                   s->crest_relief, &d->crest, &d->crest_hp);
    if (st != TS_OK || !d->crest)
        return st;
    if (!(d->crest_s = ts__malloc_array(n, sizeof(float))))
        return ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
    cr = ts_raster_wrap(d->crest, s->width, s->height, s->width);
    layout_on_features(d, &cr, TS_RIDGE, d->work);
    return lblur(ctx, d->ws, d->work, s->width, s->width, s->height, 2.0 * d->sig_c, d->crest_s);
}

ts_status ts__layout_apply(ts_ctx *ctx, const ts_layout_spec *s, ts_raster *out,
                           const unsigned char *flags, double strength)
{
    int W = s->width, H = s->height, any_fixed = 0, found, x, y;
    size_t n = (size_t)W * (size_t)H, i;
    double P = s->patch, lam = 1.0, mean_before;
    unsigned char *m = ts__malloc_array(n, 1);
    float *dist = ts__malloc_array(n, sizeof(float));
    int32_t *nearest = ts__malloc_array(n, sizeof(int32_t));
    float *guide = ts__malloc_array(n, sizeof(float));
    float *work = ts__malloc_array(n, sizeof(float));
    float *corr = ts__malloc_array(n, sizeof(float));
    float *r0 = ts__malloc_array(n, sizeof(float)), *r01 = ts__malloc_array(n, sizeof(float));
    float *d01 = ts__malloc_array(n, sizeof(float));
    double *gl = ts__calloc_array((size_t)s->n_exemplars, sizeof(double));
    double *gc = ts__calloc_array((size_t)s->n_exemplars, sizeof(double));
    double *levels = ts__calloc_array((size_t)s->n_exemplars, sizeof(double));
    float *fixd = NULL, *shape = NULL;
    layout_both both;
    layout_run_data d;
    layout_ws ws;
    ts_raster r0r, r01r;
    ts_status st = TS_OK;
    memset(&d, 0, sizeof d);
    memset(&both, 0, sizeof both);
    ws.cap = n;
    ws.v = ts__malloc_array(n, sizeof(double));
    ws.m = ts__malloc_array(n, sizeof(double));
    if (!m || !dist || !nearest || !guide || !work || !corr || !r0 || !r01 || !d01 || !gl || !gc ||
        !levels || !ws.v || !ws.m) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    layout_levels(ctx, s, levels);
    for (i = 0; i < n; i++) {
        m[i] = (s->sketch_mask[i] & s->kind) != 0;
        d.kind |= s->sketch_mask[i] & s->kind & (TS_RIDGE | TS_VALLEY);
        any_fixed |= flags && (flags[i] & TS_CELL_FIXED);
    }
    if (!(strength > 0) || !d.kind)
        goto done;
    if ((st = ts__distance_transform_nearest(ctx, m, W, H, dist, nearest)) != TS_OK)
        goto done;
    if ((st = layout_kind_distances(ctx, s, d.kind, P, m, nearest, &both)) != TS_OK)
        goto done;
    if (any_fixed) {
        /* the corrections fade out towards fixed cells, which keep their values */
        if (!(fixd = ts__malloc_array(n, sizeof(float)))) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
            goto done;
        }
        for (i = 0; i < n; i++)
            m[i] = (flags[i] & TS_CELL_FIXED) != 0;
        if ((st = ts__distance_transform(ctx, m, W, H, fixd)) != TS_OK)
            goto done;
    }
    d.s = s;
    d.strength = strength;
    d.sig_l = P / 3.0;
    d.sig_c = P / 8.0;
    d.c_l = P;
    d.c_c = P / 4.0;
    d.dist = dist;
    d.b = d.kind == (TS_RIDGE | TS_VALLEY) ? &both : NULL;
    d.near_v = d.b ? both.near_v : nearest;
    d.fixd = fixd;
    d.nearest = nearest;
    d.gl = gl;
    d.gc = gc;
    d.levels = levels;
    d.guide = guide;
    d.work = work;
    d.corr = corr;
    d.ws = &ws;
    if (d.kind == (TS_RIDGE | TS_VALLEY)) {
        /* the layout's shape, for its steepness; the second kind's crest */
        if (!(shape = ts__malloc_array(n, sizeof(float))) ||
            !(d.corr2 = ts__malloc_array(n, sizeof(float)))) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
            goto done;
        }
        for (i = 0; i < n; i++)
            shape[i] = (float)layout_shape(&d, i, d.c_l);
    }
    if ((st = layout_calibrate(ctx, &d, shape, gl, gc, &found)) != TS_OK || !found)
        goto done;
    if ((d.kind & TS_VALLEY) && !(d.vlev = ts__malloc_array(n, sizeof(float)))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "layout", "out of memory");
        goto done;
    }
    if ((d.kind & TS_RIDGE) && (st = layout_crest_setup(ctx, &d)) != TS_OK)
        goto done;
    /* the corrections are linear in the guides' steepness: the layout's
     * and the crest's together (out: both at 1, r0: both at 0), or the
     * layout's alone under the crest's at 1 (r01: layout at 0) */
    mean_before = layout_copies(&d, out, r0);
    r0r = ts_raster_wrap(r0, W, H, W);
    r01r = ts_raster_wrap(r01, W, H, W);
    d.blurred = d01;
    if ((st = layout_runs(ctx, &d, out, &r0r, &r01r)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++) { /* the parts the steepness scales */
        float o = out->data[(i / (size_t)W) * (size_t)out->stride + i % (size_t)W];
        corr[i] = o - r0[i];
        d01[i] = o - r01[i];
    }
    if ((st = ts__layout_steepness(ctx, s, r0, corr, r01, d01, work, &lam)) != TS_OK)
        goto done;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            i = (size_t)y * (size_t)W + (size_t)x;
            if (!isnan(TS_PIX(out, x, y)))
                TS_PIX(out, x, y) =
                    (float)(lam >= 1.0 ? r0[i] + lam * corr[i] : r01[i] + lam * d01[i]);
        }
    layout_keep_mean(&d, out, r0, mean_before);
    if ((st = layout_press(ctx, &ws, s->exemplars, s->n_exemplars, out, fixd, d.sig_l, work,
                           corr)) != TS_OK)
        goto done;
    if (d.kind & TS_VALLEY)
        st = layout_valley_floors(ctx, &d, out, d.b ? both.dist_vf : dist,
                                  d.b ? both.near_vf : nearest, d01);
done:
    free(m);
    free(dist);
    free(nearest);
    layout_both_free(&both);
    free(shape);
    free(d.crest);
    free(d.crest_hp);
    free(d.crest_s);
    free(d.corr2);
    free(d.vlev);
    free(guide);
    free(work);
    free(corr);
    free(r0);
    free(r01);
    free(d01);
    free(gl);
    free(gc);
    free(levels);
    free(fixd);
    free(ws.v);
    free(ws.m);
    return st;
}
