/*
 * dictionary.c - the multi-resolution dictionary (D, D~) of Argudo et al.
 * 2017, section 4: exemplars (at the output's resolution) are area-averaged
 * by the amplification factor; atoms are windows of the low-resolution
 * exemplar with the windows of the exemplar above them, in one-to-one
 * correspondence, with their descriptors: the normalised elevation D_h,
 * the mean altitude D_a, the mean deviation D_s and the normalised log
 * upstream drainage area D_u (computed on the whole low-resolution
 * exemplar, so an atom knows what flows into it).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "amplify.h"

int ts__amp_normalise(const float *v, int d, float *out, double *mean, double *rms)
{
    double m = 0.0, ss = 0.0, norm;
    int i;
    for (i = 0; i < d; i++)
        m += v[i];
    m /= d;
    for (i = 0; i < d; i++)
        ss += (v[i] - m) * (v[i] - m);
    norm = sqrt(ss);
    *mean = m;
    *rms = norm / sqrt((double)d);
    if (!(norm > 1e-9 * (fabs(m) + 1.0))) {
        for (i = 0; i < d; i++)
            out[i] = 0.0f;
        *rms = 0.0;
        return 0;
    }
    for (i = 0; i < d; i++)
        out[i] = (float)((v[i] - m) / norm);
    return 1;
}

void ts__amp_weights(const ts_amplify_params *p, double w[4])
{
    double sum = p->w_h + p->w_a + p->w_s + p->w_u;
    w[0] = p->w_h;
    w[1] = p->w_a;
    w[2] = p->w_s;
    w[3] = p->w_u;
    if (sum > 0)
        for (int i = 0; i < 4; i++)
            w[i] /= sum;
}

TS_API ts_status ts_area_average(ts_ctx *ctx, const ts_raster *fine, int factor, ts_raster *coarse)
{
    int x, y, i, j;
    ts__clear(ctx);
    if (!fine || !coarse || !fine->data || !coarse->data || factor < 1 ||
        coarse->width != fine->width / factor || coarse->height != fine->height / factor)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "area average: mismatched rasters");
    for (y = 0; y < coarse->height; y++)
        for (x = 0; x < coarse->width; x++) {
            double s = 0.0;
            int bad = 0;
            for (j = 0; j < factor && !bad; j++)
                for (i = 0; i < factor; i++) {
                    float v = TS_PIX(fine, x * factor + i, y * factor + j);
                    if (isnan(v)) {
                        bad = 1;
                        break;
                    }
                    s += v;
                }
            TS_PIX(coarse, x, y) = bad ? NAN : (float)(s / ((double)factor * factor));
        }
    return TS_OK;
}

/* Is the p x p window at (x, y) of r all valid? */
static int window_valid(const ts_raster *r, int x, int y, int p)
{
    int i, j;
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++)
            if (isnan(TS_PIX(r, x + i, y + j)))
                return 0;
    return 1;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int ts__dict_sort(ts_dictionary *d)
{
    free(d->a_sorted);
    free(d->s_sorted);
    d->a_sorted = ts__malloc_array(d->n, sizeof *d->a_sorted);
    d->s_sorted = ts__malloc_array(d->n, sizeof *d->s_sorted);
    if (!d->a_sorted || !d->s_sorted)
        return -1;
    memcpy(d->a_sorted, d->a, d->n * sizeof *d->a);
    memcpy(d->s_sorted, d->s, d->n * sizeof *d->s);
    qsort(d->a_sorted, d->n, sizeof *d->a_sorted, cmp_double);
    qsort(d->s_sorted, d->n, sizeof *d->s_sorted, cmp_double);
    return 0;
}

static void dict_free_arrays(ts_dictionary *d)
{
    free(d->a_sorted);
    free(d->s_sorted);
    free(d->dh);
    free(d->du);
    free(d->hh);
    free(d->a);
    free(d->s);
    free(d->exemplar);
    free(d->x);
    free(d->y);
}

TS_API void ts_dictionary_free(ts_dictionary *dict)
{
    if (!dict)
        return;
    dict_free_arrays(dict);
    free(dict);
}

TS_API size_t ts_dictionary_size(const ts_dictionary *dict)
{
    return dict ? dict->n : 0;
}

/* Lattice step over a low-resolution exemplar so that at most max_atoms
 * windows are taken. */
static int lattice_step(int nx, int ny, int max_atoms)
{
    int step = 1;
    while ((size_t)((nx + step - 1) / step) * (size_t)((ny + step - 1) / step) > (size_t)max_atoms)
        step++;
    return step;
}

TS_API ts_status ts_dictionary_build(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                     const ts_amplify_params *params, ts_dictionary **out)
{
    ts_dictionary *d;
    ts_raster *low = NULL, *drain = NULL;
    size_t cap = 0;
    int e, F, p, P;
    float *win = NULL, *lwin = NULL;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "no output given");
    *out = NULL;
    if (!exemplars || n_exemplars < 1 || !params)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "no exemplars given");
    if (ts_params_validate(ctx, "amplify", params) != TS_OK)
        return ctx->status;
    F = params->factor;
    p = params->patch;
    P = p * F;
    d = calloc(1, sizeof *d);
    low = calloc((size_t)n_exemplars, sizeof *low);
    drain = calloc((size_t)n_exemplars, sizeof *drain);
    win = malloc((size_t)p * p * sizeof *win);
    lwin = malloc((size_t)p * p * sizeof *lwin);
    if (!d || !low || !drain || !win || !lwin) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    d->factor = F;
    d->patch = p;
    d->d = p * p;
    d->hd = P * P;
    /* the low-resolution exemplars and their drainage, and how many atoms */
    for (e = 0; e < n_exemplars; e++) {
        const ts_raster *ex = &exemplars[e];
        int lw = ex->width / F, lh = ex->height / F, step;
        if (lw < p || lh < p) {
            st = ts__fail_input(ctx, TS_ERR_SIZE, e, "amplify",
                                "exemplar %d: %d x %d cells is smaller than a patch of %d x %d "
                                "cells at the output's resolution",
                                e + 1, ex->width, ex->height, P, P);
            goto done;
        }
        if (ts_raster_alloc(ctx, lw, lh, &low[e]) != TS_OK ||
            ts_raster_alloc(ctx, lw, lh, &drain[e]) != TS_OK ||
            ts_area_average(ctx, ex, F, &low[e]) != TS_OK ||
            ts_drainage_area(ctx, &low[e], &drain[e]) != TS_OK) {
            st = ctx->status;
            goto done;
        }
        step = lattice_step(lw - p + 1, lh - p + 1, params->atoms);
        cap += (size_t)((lw - p + step) / step) * (size_t)((lh - p + step) / step);
        if ((st = ts__progress(ctx, 0.3 * (e + 1) / n_exemplars, "dictionary")) != TS_OK)
            goto done;
    }
    d->dh = ts__malloc_array(cap * (size_t)d->d, sizeof *d->dh);
    d->du = ts__malloc_array(cap * (size_t)d->d, sizeof *d->du);
    d->hh = ts__malloc_array(cap * (size_t)d->hd, sizeof *d->hh);
    d->a = ts__malloc_array(cap, sizeof *d->a);
    d->s = ts__malloc_array(cap, sizeof *d->s);
    d->exemplar = ts__malloc_array(cap, sizeof *d->exemplar);
    d->x = ts__malloc_array(cap, sizeof *d->x);
    d->y = ts__malloc_array(cap, sizeof *d->y);
    if (!d->dh || !d->du || !d->hh || !d->a || !d->s || !d->exemplar || !d->x || !d->y) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for %zu atoms", cap);
        goto done;
    }
    for (e = 0; e < n_exemplars; e++) {
        const ts_raster *ex = &exemplars[e];
        int lw = low[e].width, lh = low[e].height, x, y, i, j;
        int step = lattice_step(lw - p + 1, lh - p + 1, params->atoms);
        for (y = 0; y + p <= lh; y += step)
            for (x = 0; x + p <= lw; x += step) {
                size_t k = d->n;
                double mean, rms, um, urms;
                if (!window_valid(&low[e], x, y, p) || !window_valid(ex, x * F, y * F, P))
                    continue;
                for (j = 0; j < p; j++)
                    for (i = 0; i < p; i++) {
                        win[j * p + i] = TS_PIX(&low[e], x + i, y + j);
                        lwin[j * p + i] = (float)log1p(TS_PIX(&drain[e], x + i, y + j));
                    }
                if (!ts__amp_normalise(win, d->d, d->dh + k * (size_t)d->d, &mean, &rms))
                    continue; /* a flat atom has no shape to match or give */
                ts__amp_normalise(lwin, d->d, d->du + k * (size_t)d->d, &um, &urms);
                for (j = 0; j < P; j++)
                    for (i = 0; i < P; i++)
                        d->hh[k * (size_t)d->hd + (size_t)j * P + i] =
                            (float)((TS_PIX(ex, x * F + i, y * F + j) - mean) /
                                    (rms * sqrt((double)d->d)));
                d->a[k] = mean;
                d->s[k] = rms;
                d->exemplar[k] = e;
                d->x[k] = x;
                d->y[k] = y;
                d->n++;
            }
        if ((st = ts__progress(ctx, 0.3 + 0.7 * (e + 1) / n_exemplars, "dictionary")) != TS_OK)
            goto done;
    }
    if (d->n > 0 && ts__dict_sort(d) != 0) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    if (d->n == 0) {
        st = ts__fail(ctx, TS_ERR_NUMERIC, "amplify",
                      "the exemplars give no atom: no window of %d x %d cells is valid and "
                      "not flat",
                      P, P);
        goto done;
    }
done:
    for (e = 0; low && e < n_exemplars; e++)
        ts_raster_free(&low[e]);
    for (e = 0; drain && e < n_exemplars; e++)
        ts_raster_free(&drain[e]);
    free(low);
    free(drain);
    free(win);
    free(lwin);
    if (st != TS_OK) {
        ts_dictionary_free(d);
        return st;
    }
    *out = d;
    return TS_OK;
}
