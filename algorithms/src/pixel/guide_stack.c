/*
 * guide_stack.c - the guide of multiresolution pixel synthesis
 * (ts_pixel_guide_prepare): its heights taken onto the exemplars' (their
 * 1st..99th percentiles stretched, or quantile by quantile) and blurred as
 * the exemplars' Gaussian stacks, one level for each level the
 * corrections of coordinate_synthesis.c read.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

/* The lattice step that samples `total` values with at most about 2^18. */
static size_t pix_step(size_t total)
{
    size_t step = 1;
    while (total / (step * step) > ((size_t)1 << 18))
        step++;
    return step;
}

/* Sorted samples of the exemplars' usable heights at the finest level (their nodata is
 * filled; every step-th of their lists one after the other) into *es, and of the guide's
 * values on a lattice into *gs, each about 2^18 at most; 0, or -1 (out of memory, or
 * either without a value; nothing is then allocated). */
static int pix_samples(const ts_raster *guide, const ts_pixel_exemplars *ex, float **es, size_t *ne,
                       float **gs, size_t *ng)
{
    size_t total = 0, j, step, lat;
    int i, n, x, y;
    *ne = *ng = 0;
    n = TS_MIN(ex->n_given, 64);
    for (i = 0; i < n; i++)
        total += ex->stacks[i].n_usable[ex->levels];
    step = pix_step(total);
    lat = pix_step((size_t)guide->width * (size_t)guide->height); /* the guide's lattice */
    *es = ts__malloc_array(total / step + 1, sizeof **es);
    *gs = ts__malloc_array(((size_t)guide->width / lat + 1) * ((size_t)guide->height / lat + 1),
                           sizeof **gs);
    if (!*es || !*gs)
        goto fail;
    for (i = 0, j = 0; i < n; i++) {
        const pix_stack *st = &ex->stacks[i];
        size_t q;
        for (q = 0; q < st->n_usable[ex->levels]; q++, j++)
            if (j % step == 0)
                (*es)[(*ne)++] = st->level[ex->levels][st->usable_list[ex->levels][q]];
    }
    for (y = 0; y < guide->height; y += (int)lat)
        for (x = 0; x < guide->width; x += (int)lat)
            if (!isnan(TS_PIX(guide, x, y)))
                (*gs)[(*ng)++] = TS_PIX(guide, x, y);
    if (!*ne || !*ng)
        goto fail;
    ts__sort_floats(*es, *ne);
    ts__sort_floats(*gs, *ng);
    return 0;
fail:
    free(*es);
    free(*gs);
    *es = *gs = NULL;
    return -1;
}

/* The 1st and 99th percentiles of sorted v[0, n). */
static void pix_range_sorted(const float *v, size_t n, double range[2])
{
    size_t k = (size_t)(0.01 * (double)(n - 1) + 0.5);
    range[0] = v[k];
    range[1] = v[n - 1 - k];
}

TS_API int ts_pixel_guide_ranges(const ts_raster *guide, const ts_pixel_exemplars *ex,
                                 double ex_range[2], double guide_range[2])
{
    float *es, *gs;
    size_t ne, ng;
    if (!guide || !guide->data || !ex || pix_samples(guide, ex, &es, &ne, &gs, &ng) != 0)
        return -1;
    pix_range_sorted(es, ne, ex_range);
    pix_range_sorted(gs, ng, guide_range);
    free(es);
    free(gs);
    return 0;
}

/* Where v falls among sorted s[0, n): the first index not below it and the first above. */
static void pix_rank(const float *s, size_t n, float v, size_t *lo, size_t *hi)
{
    size_t a = 0, b = n;
    while (a < b) {
        size_t m = a + (b - a) / 2;
        if (s[m] < v)
            a = m + 1;
        else
            b = m;
    }
    *lo = a;
    b = n;
    while (a < b) {
        size_t m = a + (b - a) / 2;
        if (s[m] <= v)
            a = m + 1;
        else
            b = m;
    }
    *hi = a;
}

/* The exemplars' height at quantile q of sorted e[0, n) (linear between samples). */
static float pix_quantile(const float *e, size_t n, double q)
{
    double t = q * (double)(n - 1), f = floor(t);
    size_t i = (size_t)f;
    if (i + 1 >= n)
        return e[n - 1];
    return (float)(e[i] + (t - f) * (e[i + 1] - e[i]));
}

TS_API ts_status ts_pixel_guide_prepare(ts_ctx *ctx, const ts_raster *guide,
                                        const ts_pixel_exemplars *ex, const ts_pixel_params *params,
                                        ts_pixel_guide **out)
{
    ts_pixel_guide *g;
    float *base, *es = NULL, *gs = NULL;
    size_t ne = 0, ng = 0;
    int l, y, L;
    double scale = 1.0, shift = 0.0;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "no output given");
    *out = NULL;
    if (!guide || !guide->data || !ex)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "missing guide or exemplars");
    if (params && params->guide_heights == TS_GUIDE_STRETCH) {
        /* the guide's 1st..99th percentiles onto the exemplars' */
        double er[2], gr[2];
        if (ts_pixel_guide_ranges(guide, ex, er, gr) != 0)
            return ts__fail(ctx, TS_ERR_ARG, "pixel", "the guide or the exemplars have no value");
        if (!(gr[1] > gr[0]))
            return ts__fail(ctx, TS_ERR_ARG, "pixel",
                            "the guide is flat (%g at its 1st and 99th percentiles): nothing "
                            "to stretch",
                            gr[0]);
        scale = (er[1] - er[0]) / (gr[1] - gr[0]);
        shift = er[0] - scale * gr[0];
    }
    if (params && params->guide_heights == TS_GUIDE_QUANTILE &&
        pix_samples(guide, ex, &es, &ne, &gs, &ng) != 0)
        return ts__fail(ctx, TS_ERR_ARG, "pixel",
                        "the guide or the exemplars have no value (or out of memory)");
    L = ex->levels;
    g = calloc(1, sizeof *g);
    base = ts__malloc_array((size_t)guide->width * (size_t)guide->height, sizeof *base);
    if (!g || !base || !(g->level = calloc((size_t)L + 1, sizeof *g->level))) {
        free(g);
        free(base);
        free(es);
        free(gs);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the guide");
    }
    g->width = guide->width;
    g->height = guide->height;
    g->levels = L;
    for (y = 0; y < guide->height; y++) {
        float *row = base + (size_t)y * guide->width;
        int x;
        memcpy(row, &TS_PIX(guide, 0, y), (size_t)guide->width * sizeof *base);
        if (scale != 1.0 || shift != 0.0)
            for (x = 0; x < guide->width; x++)
                row[x] = (float)(scale * row[x] + shift);
        if (es)
            for (x = 0; x < guide->width; x++) {
                /* the value's rank among the guide's (the middle of its ties), taken to
                 * the exemplars' height of that rank, within their 1st..99th percentiles */
                size_t lo, hi;
                double q;
                if (isnan(row[x]))
                    continue;
                pix_rank(gs, ng, row[x], &lo, &hi);
                q = TS_MIN(0.99, TS_MAX(0.01, 0.5 * (double)(lo + hi) / (double)ng));
                row[x] = pix_quantile(es, ne, q);
            }
    }
    free(es);
    free(gs);
    for (l = 0; l <= L; l++) {
        g->level[l] = ts__malloc_array((size_t)g->width * (size_t)g->height, sizeof **g->level);
        if (!g->level[l] || ts__pix_blur(base, g->width, g->height,
                                         l == L ? 0.0 : 0.5 * (1 << (L - l)), g->level[l]) != 0) {
            free(base);
            ts_pixel_guide_free(g);
            return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the guide");
        }
    }
    free(base);
    *out = g;
    return TS_OK;
}

TS_API void ts_pixel_guide_free(ts_pixel_guide *g)
{
    int l;
    if (!g)
        return;
    for (l = 0; g->level && l <= g->levels; l++)
        free(g->level[l]);
    free(g->level);
    free(g);
}
