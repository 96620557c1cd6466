/*
 * slope_style.c - the exemplars' distribution of slopes given to a sketched
 * terrain (a TerraSynth addition to Zhou et al. 2007, named as such).
 *
 * The feature patches, the fill and the layout stage place the exemplars'
 * landforms where the sketch wants them, but the mix of slopes drifts from
 * the exemplars': merging keeps gradients only, the layout adds regional
 * tilts (a volcano's flat crater floors and lava plains become gentle
 * ramps) and its single steepness factor matches the mean, not the shape.
 * This stage matches the shape, in the gradient domain (as histogram
 * matching is done on gradients rather than heights, so that the layout
 * stays where it is):
 *
 *   1. g(x) = |grad u|(x) (central differences, per cell), and F its
 *      distribution over the output's valid cells (per exemplar region
 *      when a region map chose the exemplars); G the distribution of the
 *      exemplar's gradient magnitude at the output's ground resolution;
 *   2. every cell's wanted magnitude is G^-1(F(g(x))) (quantile mapping),
 *      its factor f(x) = (G^-1(F(g)) / g)^strength, clamped to 1/4..4;
 *   3. each edge's wanted difference is the edge's own difference times its
 *      cells' factor (the one nearer 1 where both scale alike, 1 where one
 *      steepens and the other gentles): directions are kept, only
 *      steepness changes;
 *   4. the heights whose differences fit those best in least squares: the
 *      Poisson equation, solved by poisson.c (nodata cells left out, fixed
 *      cells as boundary values, the mean height of a free region kept).
 *
 * One pass moves the distribution most of the way (the least-squares fit
 * cannot honour every edge); SLOPE_STYLE_PASSES passes get within the
 * resampling floor on the cases measured (sketch.md).  Cost: one Poisson
 * solve per pass, screened: it minimises the misfit of the differences
 * plus 1 / scale^2 times the squared change of the heights, so the slopes
 * take the wanted mix while the layout's relief wider than about `scale`
 * cells (a patch) stays where the layout put it (an exact fit integrates
 * the steeper or gentler slopes across the whole grid: hundreds of metres
 * of large-scale change that undo the layout).  On a grid with no nodata
 * and no fixed cell (the usual sketch) the solve is direct (two cosine
 * transforms, poisson.c); otherwise iterative (MIC-PCG) to a loose
 * relative residual (3e-3), started from the current heights.
 *
 * Then no crease sharper than the exemplars' sharpest: a cell whose
 * |Laplacian| passes the exemplar's 99.99th percentile moves half-way
 * towards it, for at most CREASE_PASSES Jacobi sweeps.  Feature patches
 * warped and carved by the layout along the sketch's strokes made V-shaped
 * thalwegs sharper than any in an exemplar coarser than the output (a
 * 90 m canyon DEM on a 30 m grid); real valley floors are not.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "slope_style.h"

#define SLOPE_STAGE "slope style"
#define SLOPE_Q 1001          /* quantiles 0, 0.1, ..., 100 % */
#define SLOPE_SAMPLES 1048576 /* at most about this many cells sampled per distribution */
#define SLOPE_FACTOR_MAX 4.0
#define SLOPE_KEEP_Q 995 /* the quantile (of SLOPE_Q) near features: 99.5 % */
#define CREASE_QUANTILE 0.9999 /* no crease sharper than the exemplars' sharpest 0.01 % */
#define CREASE_PASSES 40

/* One component of the gradient at p along a step of `d` elements: the
 * central difference, or the one-sided one where the grid or the data end
 * on one side (NaN where they end on both). */
static inline double slope_axis(const float *p, ptrdiff_t d, int lo_ok, int hi_ok)
{
    double a = lo_ok ? (double)p[-d] : NAN, b = hi_ok ? (double)p[d] : NAN;
    if (!isnan(a) && !isnan(b))
        return 0.5 * (b - a);
    if (!isnan(b))
        return b - (double)p[0];
    if (!isnan(a))
        return (double)p[0] - a;
    return NAN;
}

/* Gradient magnitude per cell (central differences, one-sided at the
 * edges of the grid and of the data; NaN on nodata). */
static inline double slope_at(const float *a, ptrdiff_t stride, int w, int h, int x, int y)
{
    const float *p = a + (ptrdiff_t)y * stride + x;
    double gx, gy;
    if (isnan(p[0]))
        return NAN;
    gx = slope_axis(p, 1, x > 0, x + 1 < w);
    gy = slope_axis(p, stride, y > 0, y + 1 < h);
    if (isnan(gx) && isnan(gy))
        return NAN;
    gx = isnan(gx) ? 0.0 : gx;
    gy = isnan(gy) ? 0.0 : gy;
    return sqrt(gx * gx + gy * gy);
}

/* SLOPE_Q quantiles of the gradient magnitude of a (w x h at stride) over
 * the cells where `sel` (w*h, stride w; NULL = all) equals `group`, sampled
 * on a lattice of at most about SLOPE_SAMPLES cells.  Returns the number of
 * cells sampled (0: no distribution).  work: room for the samples. */
static size_t slope_quantiles(const float *a, ptrdiff_t stride, int w, int h, const int32_t *sel,
                              int32_t group, float *work, double *q)
{
    double cells = (double)w * (double)h;
    int step = cells > SLOPE_SAMPLES ? (int)ceil(sqrt(cells / SLOPE_SAMPLES)) : 1, x, y, k;
    size_t n = 0;
    for (y = 0; y < h; y += step)
        for (x = 0; x < w; x += step) {
            double g;
            if (sel && sel[(size_t)y * (size_t)w + (size_t)x] != group)
                continue;
            g = slope_at(a, stride, w, h, x, y);
            if (!isnan(g))
                work[n++] = (float)g;
        }
    if (n < 16)
        return 0;
    ts__sort_floats(work, n);
    for (k = 0; k < SLOPE_Q; k++) {
        double pos = (double)k / (SLOPE_Q - 1) * (double)(n - 1);
        size_t i0 = (size_t)pos;
        double f = pos - (double)i0;
        q[k] = i0 + 1 < n ? (1.0 - f) * work[i0] + f * work[i0 + 1] : work[n - 1];
    }
    return n;
}

/* G^-1(F(g)): g placed among the quantiles qo, the same place among qe. */
static double slope_map(double g, const double *qo, const double *qe)
{
    int lo = 0, hi = SLOPE_Q - 1;
    double t;
    if (g <= qo[0])
        return qe[0];
    if (g >= qo[SLOPE_Q - 1])
        return qe[SLOPE_Q - 1];
    /* the first k with qo[k] > g; ties (a flat share) take the middle of
     * their run, so that equal slopes map to one value */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (qo[mid] > g)
            hi = mid;
        else
            lo = mid;
    }
    if (qo[lo] == g) {
        int a = lo;
        while (a > 0 && qo[a - 1] == g)
            a--;
        return 0.5 * (qe[a] + qe[lo]);
    }
    t = (g - qo[lo]) / (qo[hi] - qo[lo]);
    return qe[lo] + t * (qe[hi] - qe[lo]);
}

/* An edge's factor from its two cells': the one nearer 1 when both scale
 * alike (so that a steepened wall does not sharpen the crease at its foot),
 * 1 across a change of direction. */
static inline double slope_edge(float a, float b)
{
    if (a >= 1.0f && b >= 1.0f)
        return TS_MIN(a, b);
    if (a <= 1.0f && b <= 1.0f)
        return TS_MAX(a, b);
    return 1.0;
}

/* Discrete Laplacian (5 points, per cell) at (x, y) of a (stride in
 * elements); NaN without four valid neighbours. */
static inline double crease_at(const float *a, ptrdiff_t stride, int w, int h, int x, int y)
{
    const float *p = a + (ptrdiff_t)y * stride + x;
    if (x < 1 || y < 1 || x + 1 >= w || y + 1 >= h)
        return NAN;
    return (double)p[1] + p[-1] + p[stride] + p[-stride] - 4.0 * (double)p[0];
}

/* The CREASE_QUANTILE quantile of |Laplacian| of a (w x h, stride w) over a
 * lattice of at most about SLOPE_SAMPLES cells; NaN when too few. */
static double crease_cap(const float *a, ptrdiff_t stride, int w, int h, float *work)
{
    double cells = (double)w * (double)h, pos;
    int step = cells > SLOPE_SAMPLES ? (int)ceil(sqrt(cells / SLOPE_SAMPLES)) : 1, x, y;
    size_t n = 0, i0;
    for (y = 1; y + 1 < h; y += step)
        for (x = 1; x + 1 < w; x += step) {
            double l = crease_at(a, stride, w, h, x, y);
            if (!isnan(l))
                work[n++] = (float)fabs(l);
        }
    if (n < 1024)
        return NAN;
    ts__sort_floats(work, n);
    pos = CREASE_QUANTILE * (double)(n - 1);
    i0 = (size_t)pos;
    return i0 + 1 < n ? work[i0] + (pos - (double)i0) * (work[i0 + 1] - work[i0]) : work[n - 1];
}

/* What the steps share: the spec, the grid, the heights u being styled,
 * mask (the cells that move), group (per cell its exemplar, or NULL: one
 * group), per group the wanted quantiles qe, the output's qo, the crease
 * cap and has (1: a wanted distribution, 2: none of the output), and the
 * work arrays. */
typedef struct slope_work {
    const ts_slope_style_spec *s;
    int W, H, n_groups;
    int whole; /* every cell moves (no nodata, none fixed): the direct solve */
    float *u, *gx, *gy, *fac, *work, *exwork, *keep;
    unsigned char *mask;
    int32_t *group;
    double *qe, *qo, *cap;
    char *has;
} slope_work;

/* The arrays of the passes (keep excepted).  TS_OK or the failure. */
static ts_status slope_alloc(ts_ctx *ctx, slope_work *sw)
{
    const ts_slope_style_spec *s = sw->s;
    size_t n = (size_t)sw->W * (size_t)sw->H, ex_cap = 0;
    int n_groups = sw->n_groups, grp;
    for (grp = 0; grp < s->n_exemplars; grp++) {
        const ts_raster *e = &s->exemplars[grp];
        ex_cap = TS_MAX(ex_cap, (size_t)e->width * (size_t)e->height);
    }
    ex_cap = TS_MIN(ex_cap, (size_t)SLOPE_SAMPLES * 2 + 4096);
    sw->u = ts__malloc_array(n, sizeof *sw->u);
    sw->gx = ts__malloc_array(n, sizeof *sw->gx);
    sw->gy = ts__malloc_array(n, sizeof *sw->gy);
    sw->fac = ts__malloc_array(n, sizeof *sw->fac);
    sw->work = ts__malloc_array(TS_MIN(n, (size_t)SLOPE_SAMPLES * 2 + 4096), sizeof *sw->work);
    sw->exwork = ts__malloc_array(ex_cap, sizeof *sw->exwork);
    sw->mask = ts__malloc_array(n, 1);
    sw->qe = ts__calloc_array((size_t)n_groups * SLOPE_Q, sizeof *sw->qe);
    sw->qo = ts__calloc_array((size_t)n_groups * SLOPE_Q, sizeof *sw->qo);
    sw->has = ts__calloc_array((size_t)n_groups, 1);
    sw->cap = ts__calloc_array((size_t)n_groups, sizeof *sw->cap);
    if (n_groups > 1)
        sw->group = ts__malloc_array(n, sizeof *sw->group);
    if (!sw->u || !sw->gx || !sw->gy || !sw->fac || !sw->work || !sw->exwork || !sw->mask ||
        !sw->qe || !sw->qo || !sw->has || !sw->cap || (n_groups > 1 && !sw->group))
        return ts__fail(ctx, TS_ERR_NOMEM, SLOPE_STAGE, "out of memory");
    return TS_OK;
}

/* The distances to the sketch's features, into keep.  mask: work. */
static ts_status slope_keep_distances(ts_ctx *ctx, slope_work *sw)
{
    const ts_slope_style_spec *s = sw->s;
    size_t n = (size_t)sw->W * (size_t)sw->H, i;
    if (!(sw->keep = ts__malloc_array(n, sizeof *sw->keep)))
        return ts__fail(ctx, TS_ERR_NOMEM, SLOPE_STAGE, "out of memory");
    for (i = 0; i < n; i++)
        sw->mask[i] = (s->features[i] & s->kind) != 0;
    return ts__distance_transform(ctx, sw->mask, sw->W, sw->H, sw->keep);
}

/* The wanted distributions: per exemplar, or all exemplars pooled; and
 * the sharpest crease of each group's exemplars. */
static void slope_targets(slope_work *sw)
{
    const ts_slope_style_spec *s = sw->s;
    int n_groups = sw->n_groups, grp;
    for (grp = 0; grp < n_groups; grp++) {
        double q[SLOPE_Q], c;
        int e, k, cnt = 0;
        for (e = 0; e < s->n_exemplars; e++) {
            const ts_raster *ex = &s->exemplars[e];
            if (n_groups > 1 && e != grp)
                continue;
            if (slope_quantiles(ex->data, ex->stride, ex->width, ex->height, NULL, 0, sw->exwork,
                                q)) {
                for (k = 0; k < SLOPE_Q; k++)
                    sw->qe[(size_t)grp * SLOPE_Q + (size_t)k] += q[k];
                cnt++;
            }
            c = crease_cap(ex->data, ex->stride, ex->width, ex->height, sw->exwork);
            if (!isnan(c))
                sw->cap[grp] = TS_MAX(sw->cap[grp], c);
        }
        if (cnt) {
            for (k = 0; k < SLOPE_Q; k++)
                sw->qe[(size_t)grp * SLOPE_Q + (size_t)k] /= cnt;
            sw->has[grp] = 1;
        }
    }
}

/* Every cell's factor (G^-1(F(g)) / g)^strength, clamped; near the
 * sketch's features never gentler than the exemplar's steepest half
 * percent (rows [y0, y1)). */
static void slope_factors(void *arg, size_t y0, size_t y1)
{
    slope_work *sw = arg;
    const ts_slope_style_spec *s = sw->s;
    int W = sw->W, H = sw->H, x, y;
    const double *qo = sw->qo, *qe = sw->qe;
    for (y = (int)y0; y < (int)y1; y++)
        for (x = 0; x < W; x++) {
            double g = slope_at(sw->u, W, W, H, x, y), f = 1.0;
            size_t i = (size_t)y * (size_t)W + (size_t)x;
            int32_t gi = sw->group ? sw->group[i] : 0;
            if (!isnan(g) && gi >= 0 && sw->has[gi] == 1 && g > 1e-9) {
                f = slope_map(g, qo + (size_t)gi * SLOPE_Q, qe + (size_t)gi * SLOPE_Q) / g;
                if (s->strength != 1.0) /* (the default: f itself) */
                    f = pow(TS_MAX(f, 1e-300), s->strength);
                f = TS_MIN(TS_MAX(f, 1.0 / SLOPE_FACTOR_MAX), SLOPE_FACTOR_MAX);
                if (sw->keep && sw->keep[i] < s->keep_radius && f < 1.0) {
                    /* the sketch's features keep standing out: near them
                     * slopes are gentled only down to the exemplar's
                     * steepest half percent */
                    double top = qe[(size_t)gi * SLOPE_Q + SLOPE_KEEP_Q];
                    f = g > top ? TS_MAX(f, top / g) : 1.0;
                }
            }
            sw->fac[i] = (float)f;
        }
}

/* Each edge's wanted difference: its own times its cells' factor (rows
 * [y0, y1)). */
static void slope_edges(void *arg, size_t y0, size_t y1)
{
    const slope_work *sw = arg;
    int W = sw->W, H = sw->H, x, y;
    const float *u = sw->u, *fac = sw->fac;
    for (y = (int)y0; y < (int)y1; y++)
        for (x = 0; x < W; x++) {
            size_t i = (size_t)y * (size_t)W + (size_t)x;
            sw->gx[i] = x + 1 < W && !isnan(u[i]) && !isnan(u[i + 1])
                            ? (float)(((double)u[i + 1] - u[i]) * slope_edge(fac[i], fac[i + 1]))
                            : 0.0f;
            sw->gy[i] = y + 1 < H && !isnan(u[i]) && !isnan(u[i + (size_t)W])
                            ? (float)(((double)u[i + (size_t)W] - u[i]) *
                                      slope_edge(fac[i], fac[i + (size_t)W]))
                            : 0.0f;
        }
}

/* The SLOPE_STYLE_PASSES passes: the output's distributions, the factors,
 * the wanted differences and the heights that fit them (a solve that does
 * not converge leaves u as it was and ends the passes). */
static ts_status slope_passes(ts_ctx *ctx, slope_work *sw)
{
    const ts_slope_style_spec *s = sw->s;
    int W = sw->W, H = sw->H, grp, pass;
    double screen = s->scale > 0 ? 1.0 / (s->scale * s->scale) : 0.0;
    ts_status st;
    for (pass = 0; pass < SLOPE_STYLE_PASSES; pass++) {
        ts_progress_saved sv;
        for (grp = 0; grp < sw->n_groups; grp++)
            if (sw->has[grp] && !slope_quantiles(sw->u, W, W, H, sw->group, grp, sw->work,
                                                 sw->qo + (size_t)grp * SLOPE_Q))
                sw->has[grp] = 2; /* no cell of the region has a gradient: left as it is */
        ts__parallel_for(ctx, (size_t)H, slope_factors, sw);
        ts__parallel_for(ctx, (size_t)H, slope_edges, sw);
        sv = ts__progress_push(ctx, (double)pass / SLOPE_STYLE_PASSES,
                               (double)(pass + 1) / SLOPE_STYLE_PASSES);
        if (sw->whole)
            st = ts__poisson_screened_whole(ctx, W, H, sw->gx, sw->gy, sw->u, screen);
        else
            st = ts__poisson_solve_valid(ctx, W, H, sw->mask, sw->gx, sw->gy, sw->u,
                                         s->tolerance > 0 ? s->tolerance : SLOPE_STYLE_TOLERANCE,
                                         1000 + 20 * (W + H), screen);
        ts__progress_pop(ctx, sv);
        if (st == TS_ERR_NUMERIC) { /* not converged: u is as it was; keep it */
            ts__clear(ctx);
            return TS_OK;
        }
        if (st != TS_OK)
            return st;
    }
    return TS_OK;
}

/* One crease sweep over the n_list cells of list: those past their cap
 * move half-way towards it, all at once; the next sweep's cells (the moved
 * ones and their neighbours, once each) into list.  Returns their count.
 * next, val: work; seen: zero, left zero. */
static size_t crease_sweep(slope_work *sw, int32_t *list, size_t n_list, int32_t *next, float *val,
                           unsigned char *seen)
{
    int W = sw->W, H = sw->H, x, y;
    float *u = sw->u;
    size_t n_moved = 0, k, n_next = 0, i;
    for (k = 0; k < n_list; k++) {
        double l;
        int32_t gi;
        i = (size_t)list[k];
        x = (int)(i % (size_t)W);
        y = (int)(i / (size_t)W);
        gi = sw->group ? sw->group[i] : 0;
        if (!sw->mask[i] || gi < 0 || !(sw->cap[gi] > 0))
            continue;
        l = crease_at(u, W, W, H, x, y);
        if (isnan(l) || fabs(l) <= sw->cap[gi])
            continue;
        next[n_moved] = (int32_t)i;
        val[n_moved++] = (float)(u[i] + 0.5 * (l - copysign(sw->cap[gi], l)) / 4.0);
    }
    for (k = 0; k < n_moved; k++)
        u[next[k]] = val[k];
    /* the next sweep's cells: the moved ones and their neighbours, once each
     * (a Jacobi sweep does not depend on the order it visits them) */
    for (k = 0; k < n_moved; k++) {
        size_t c = (size_t)next[k], d;
        static const int dx[5] = {0, -1, 1, 0, 0}, dy[5] = {0, 0, 0, -1, 1};
        for (d = 0; d < 5; d++) {
            long xx = (long)(c % (size_t)W) + dx[d], yy = (long)(c / (size_t)W) + dy[d];
            size_t q;
            if (xx < 0 || yy < 0 || xx >= W || yy >= H)
                continue;
            q = (size_t)yy * (size_t)W + (size_t)xx;
            if (!seen[q]) {
                seen[q] = 1;
                list[n_next++] = (int32_t)q;
            }
        }
    }
    for (k = 0; k < n_next; k++)
        seen[list[k]] = 0;
    return n_next;
}

/* No crease sharper than the exemplars' sharpest: a cell whose |Laplacian|
 * passes its exemplar's cap moves half-way towards it, all cells of a
 * sweep at once (Jacobi: the same result on any thread count).  A sweep
 * looks only at the cells whose Laplacian the last one changed (the cells
 * it moved and their four neighbours): the others were under the cap when
 * last looked at and have not changed since, so this is the full sweep,
 * exactly. */
static ts_status slope_creases(ts_ctx *ctx, slope_work *sw)
{
    size_t n = (size_t)sw->W * (size_t)sw->H, i, n_list = 0;
    int32_t *list = ts__malloc_array(n, sizeof *list), *next = ts__malloc_array(n, sizeof *next);
    float *val = ts__malloc_array(n, sizeof *val);
    unsigned char *seen = ts__calloc_array(n, 1);
    int pass;
    if (!list || !next || !val || !seen) {
        free(list);
        free(next);
        free(val);
        free(seen);
        return ts__fail(ctx, TS_ERR_NOMEM, SLOPE_STAGE, "out of memory");
    }
    for (i = 0; i < n; i++)
        list[n_list++] = (int32_t)i;
    for (pass = 0; pass < CREASE_PASSES && n_list; pass++)
        n_list = crease_sweep(sw, list, n_list, next, val, seen);
    free(list);
    free(next);
    free(val);
    free(seen);
    return TS_OK;
}

ts_status ts__slope_style(ts_ctx *ctx, const ts_slope_style_spec *s, ts_raster *out)
{
    int W = out->width, H = out->height, y;
    size_t n = (size_t)W * (size_t)H, i;
    slope_work sw;
    ts_status st = TS_OK;
    if (!(s->strength > 0) || W < 3 || H < 3 || s->n_exemplars < 1)
        return TS_OK;
    memset(&sw, 0, sizeof sw);
    sw.s = s;
    sw.W = W;
    sw.H = H;
    /* one group per exemplar when a region map chose them, else one */
    sw.n_groups = (s->cell_exemplar && s->n_exemplars > 1) ? s->n_exemplars : 1;
    if ((st = slope_alloc(ctx, &sw)) != TS_OK)
        goto done;
    if (s->features && s->keep_radius > 0 && (st = slope_keep_distances(ctx, &sw)) != TS_OK)
        goto done;
    for (y = 0; y < H; y++)
        memcpy(sw.u + (size_t)y * (size_t)W, out->data + (size_t)y * (size_t)out->stride,
               (size_t)W * sizeof *sw.u);
    for (i = 0; i < n; i++) {
        sw.mask[i] = !isnan(sw.u[i]) && !(s->flags && (s->flags[i] & TS_CELL_FIXED));
        if (sw.group)
            sw.group[i] = s->cell_exemplar[i] >= 0 && s->cell_exemplar[i] < s->n_exemplars
                              ? s->cell_exemplar[i]
                              : -1;
    }
    sw.whole = 1;
    for (i = 0; i < n && sw.whole; i++)
        sw.whole = sw.mask[i];
    slope_targets(&sw);
    if ((st = slope_passes(ctx, &sw)) != TS_OK || (st = slope_creases(ctx, &sw)) != TS_OK)
        goto done;
    for (y = 0; y < H; y++)
        memcpy(out->data + (size_t)y * (size_t)out->stride, sw.u + (size_t)y * (size_t)W,
               (size_t)W * sizeof *sw.u);
done:
    free(sw.u);
    free(sw.gx);
    free(sw.gy);
    free(sw.fac);
    free(sw.work);
    free(sw.exwork);
    free(sw.mask);
    free(sw.group);
    free(sw.qe);
    free(sw.qo);
    free(sw.has);
    free(sw.cap);
    free(sw.keep);
    return st;
}
