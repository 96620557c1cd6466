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

void ts__amp_context(const ts_raster *r, int x, int y, int p, float *out)
{
    int i, j, a, b, nb = 0;
    double m = 0, mean, rms;
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++) {
            double s = 0;
            int n = 0;
            for (b = 0; b < 3; b++)
                for (a = 0; a < 3; a++) {
                    int cx = x - p + 3 * i + a, cy = y - p + 3 * j + b;
                    float v;
                    cx = cx < 0 ? 0 : cx >= r->width ? r->width - 1 : cx;
                    cy = cy < 0 ? 0 : cy >= r->height ? r->height - 1 : cy;
                    v = TS_PIX(r, cx, cy);
                    if (!isnan(v)) {
                        s += v;
                        n++;
                    }
                }
            out[j * p + i] = n ? (float)(s / n) : NAN;
            if (n) {
                m += s / n;
                nb++;
            }
        }
    m = nb ? m / nb : 0.0;
    for (i = 0; i < p * p; i++)
        if (isnan(out[i]))
            out[i] = (float)m;
    ts__amp_normalise(out, p * p, out, &mean, &rms);
}

void ts__amp_weights(const ts_amplify_params *p, int use_l, int use_c, double w[AMP_NW])
{
    double sum = 0;
    int i;
    w[AMP_WH] = p->w_h;
    w[AMP_WA] = p->w_a;
    w[AMP_WS] = p->w_s;
    w[AMP_WU] = p->w_u;
    w[AMP_WL] = use_l ? p->w_l : 0.0;
    w[AMP_WC] = use_c ? p->w_c : 0.0;
    w[AMP_WX] = p->w_x;
    for (i = 0; i < AMP_NW; i++)
        sum += w[i];
    if (sum > 0)
        for (i = 0; i < AMP_NW; i++)
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
    free(d->dx);
    free(d->dl);
    free(d->dc);
    free(d->hc);
    free(d->ll);
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

TS_API void ts_dictionary_layers(const ts_dictionary *dict, int *n_layers, int *n_classes,
                                 int *has_irradiance)
{
    if (n_layers)
        *n_layers = dict ? dict->n_layers : 0;
    if (n_classes)
        *n_classes = dict ? dict->n_classes : 0;
    if (has_irradiance)
        *has_irradiance = dict && dict->dl;
}

TS_API size_t ts_dictionary_class_atoms(const ts_dictionary *dict, int code)
{
    size_t a, n = 0;
    if (!dict || !dict->dc || code < 1 || code > dict->n_classes)
        return 0;
    for (a = 0; a < dict->n; a++)
        n += dict->dc[a * (size_t)dict->n_classes + (size_t)(code - 1)] > 0.0f;
    return n;
}

TS_API const char *ts_dictionary_layer_name(const ts_dictionary *dict, int i)
{
    return dict && i >= 0 && i < dict->n_layers ? dict->layer_names[i] : NULL;
}

/* A class code as read: 0 for none (0 or NaN), the code 1..TS_MAX_CLASSES, or
 * -1 for anything else. */
int ts__class_code(float v)
{
    if (isnan(v) || v == 0.0f)
        return 0;
    if (v >= 1.0f && v <= (float)TS_MAX_CLASSES && v == floorf(v))
        return (int)v;
    return -1;
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

/* Check an exemplar's layers, classes and latitude against its DEM; the
 * highest class code into *max_class.  TS_OK or the failure. */
static ts_status check_exemplar(ts_ctx *ctx, const ts_exemplar *ex, int e, int n_layers, int F,
                                int *max_class)
{
    const ts_raster *dem = &ex->dem;
    int l, x, y;
    if (!dem->data)
        return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify", "exemplar %d: no DEM", e + 1);
    if (n_layers > 0 && !ex->layers)
        return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify",
                              "exemplar %d: gives none of the dictionary's %d layers", e + 1,
                              n_layers);
    for (l = 0; l < n_layers; l++)
        if (!ex->layers[l].data || ex->layers[l].width != dem->width ||
            ex->layers[l].height != dem->height)
            return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify",
                                  "exemplar %d: layer %d is not on its grid", e + 1, l + 1);
    if (ex->classes) {
        if (!ex->classes->data || ex->classes->width != dem->width ||
            ex->classes->height != dem->height)
            return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify",
                                  "exemplar %d: its classes are not on its grid", e + 1);
        for (y = 0; y < dem->height; y++)
            for (x = 0; x < dem->width; x++) {
                float v = TS_PIX(ex->classes, x, y);
                int c = ts__class_code(v);
                if (c < 0)
                    return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify",
                                          "exemplar %d: class %g at cell %d,%d is not a code "
                                          "1..%d (0 or nodata: none)",
                                          e + 1, (double)v, x, y, TS_MAX_CLASSES);
                if (c > *max_class)
                    *max_class = c;
            }
    }
    if (ex->lat || ex->north) {
        const ts_raster *r[2] = {ex->lat, ex->north};
        for (l = 0; l < 2; l++)
            if (r[l] && (!r[l]->data || r[l]->width != dem->width / F ||
                         r[l]->height != dem->height / F))
                return ts__fail_input(ctx, TS_ERR_ARG, e, "amplify",
                                      "exemplar %d: its latitude and north must be on its "
                                      "grid area-averaged by the factor",
                                      e + 1);
    }
    return TS_OK;
}

/* The mean annual irradiance of a low-resolution exemplar (cells of F dx x F dy). */
static ts_status low_irradiance(ts_ctx *ctx, const ts_exemplar *ex, const ts_raster *low, int F,
                                ts_raster *irr)
{
    double *mx = ts__malloc_array((size_t)low->height, sizeof *mx);
    double *my = ts__malloc_array((size_t)low->height, sizeof *my);
    ts_grid_metrics m;
    ts_status st;
    int y;
    if (!mx || !my) {
        free(mx);
        free(my);
        return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
    }
    for (y = 0; y < low->height; y++) {
        mx[y] = ex->dx * F;
        my[y] = ex->dy * F;
    }
    m.dx = mx;
    m.dy = my;
    st = ts_irradiance(ctx, low, &m, ex->lat, ex->north, irr);
    free(mx);
    free(my);
    return st;
}

/* One source of atoms: an exemplar area-averaged from a phase (ox, oy) of
 * its cells.  An exemplar whose every window (lattice step 1) gives fewer
 * atoms than asked for is averaged from more phases while the budget lasts:
 * the atoms then overlap by fractions of a low-resolution cell too (section
 * 4's "partially overlapping"). */
typedef struct amp_source {
    int e, ox, oy, step;
    ts_raster low, drain, irr;
} amp_source;

/* The k-th phase of an F x F cell: (0,0), the centre, the two half
 * shifts, then the rest in raster order. */
static void phase_offset(int F, int k, int *ox, int *oy)
{
    int first[4][2] = {{0, 0}, {F / 2, F / 2}, {F / 2, 0}, {0, F / 2}}, n = 0, i, j, q;
    for (q = 0; q < 4; q++)
        if (k == q) {
            *ox = first[q][0];
            *oy = first[q][1];
            return;
        }
    for (j = 0; j < F; j++)
        for (i = 0; i < F; i++) {
            int used = 0;
            for (q = 0; q < 4; q++)
                used |= first[q][0] == i && first[q][1] == j;
            if (used)
                continue;
            if (n++ == k - 4) {
                *ox = i;
                *oy = j;
                return;
            }
        }
    *ox = *oy = 0;
}

/* A view of r from cell (x, y) on. */
static ts_raster raster_from(const ts_raster *r, int x, int y, int w, int h)
{
    ts_raster v;
    v.width = w;
    v.height = h;
    v.stride = r->stride;
    v.data = r->data + (size_t)y * (size_t)r->stride + (size_t)x;
    return v;
}

/* Check the extra layers' count and names: each of letters, digits, _ or -,
 * none named twice.  TS_OK or the failure. */
static ts_status dict_check_names(ts_ctx *ctx, const char *const *layer_names, int n_layers)
{
    int l;
    if (n_layers < 0 || n_layers > TS_MAX_LAYERS || (n_layers > 0 && !layer_names))
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "at most %d extra layers, each named",
                        TS_MAX_LAYERS);
    for (l = 0; l < n_layers; l++) {
        int m;
        if (!layer_names[l] || !layer_names[l][0] || strlen(layer_names[l]) >= TS_LAYER_NAME ||
            layer_names[l][strspn(layer_names[l], "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstu"
                                                  "vwxyz0123456789_-")] != 0)
            return ts__fail(ctx, TS_ERR_ARG, "amplify",
                            "layer %d: a name of 1 to %d letters, digits, _ or - is needed", l + 1,
                            TS_LAYER_NAME - 1);
        for (m = 0; m < l; m++)
            if (!strcmp(layer_names[m], layer_names[l]))
                return ts__fail(ctx, TS_ERR_ARG, "amplify", "layer %s is named twice",
                                layer_names[l]);
    }
    return TS_OK;
}

/* The sources of exemplar e from src[*n_src] on: the low-resolution
 * exemplar of phase 0, its drainage and irradiance; when it gives every
 * window and fewer than the atoms asked for, more phases while the budget
 * lasts.  *n_src counts them, *cap their atoms. */
static ts_status dict_exemplar_sources(ts_ctx *ctx, const ts_exemplar *ex, int e,
                                       const ts_amplify_params *params, amp_source *src, int *n_src,
                                       size_t *cap)
{
    int F = params->factor, p = params->patch, P = p * F, want_l = params->w_l > 0;
    int lw = ex->dem.width / F, lh = ex->dem.height / F, ph, budget;
    if (lw < p || lh < p)
        return ts__fail_input(ctx, TS_ERR_SIZE, e, "amplify",
                              "exemplar %d: %d x %d cells is smaller than a patch of %d x %d "
                              "cells at the output's resolution",
                              e + 1, ex->dem.width, ex->dem.height, P, P);
    budget = params->atoms;
    for (ph = 0; ph < F * F && budget > 0; ph++) {
        amp_source *s_ = &src[*n_src];
        ts_raster shifted;
        int w, h;
        size_t count;
        if (ph == 1 && src[*n_src - 1].step > 1)
            break;
        s_->e = e;
        phase_offset(F, ph, &s_->ox, &s_->oy);
        w = (ex->dem.width - s_->ox) / F;
        h = (ex->dem.height - s_->oy) / F;
        if (w < p || h < p)
            continue;
        shifted = raster_from(&ex->dem, s_->ox, s_->oy, w * F, h * F);
        if (ts_raster_alloc(ctx, w, h, &s_->low) != TS_OK ||
            ts_raster_alloc(ctx, w, h, &s_->drain) != TS_OK ||
            ts_area_average(ctx, &shifted, F, &s_->low) != TS_OK ||
            ts_drainage_area(ctx, &s_->low, &s_->drain) != TS_OK)
            return ctx->status;
        if (want_l && ex->lat && ex->dx > 0 && ex->dy > 0) {
            /* the phase's cells are within a cell of phase 0's: its latitudes */
            ts_exemplar exv = *ex;
            ts_raster latv = raster_from(ex->lat, 0, 0, w, h), northv;
            exv.lat = &latv;
            if (ex->north) {
                northv = raster_from(ex->north, 0, 0, w, h);
                exv.north = &northv;
            }
            if (ts_raster_alloc(ctx, w, h, &s_->irr) != TS_OK ||
                low_irradiance(ctx, &exv, &s_->low, F, &s_->irr) != TS_OK)
                return ctx->status;
        }
        s_->step = lattice_step(w - p + 1, h - p + 1, budget);
        count = (size_t)((w - p + s_->step) / s_->step) * (size_t)((h - p + s_->step) / s_->step);
        *cap += count;
        budget -= (int)count;
        (*n_src)++;
    }
    return TS_OK;
}

/* The dictionary's arrays for cap atoms.  TS_OK or the failure. */
static ts_status dict_alloc(ts_ctx *ctx, ts_dictionary *d, size_t cap, int want_l)
{
    int K = d->n_classes, n_layers = d->n_layers;
    d->dh = ts__malloc_array(cap * (size_t)d->d, sizeof *d->dh);
    d->du = ts__malloc_array(cap * (size_t)d->d, sizeof *d->du);
    d->hh = ts__malloc_array(cap * (size_t)d->hd, sizeof *d->hh);
    d->a = ts__malloc_array(cap, sizeof *d->a);
    d->s = ts__malloc_array(cap, sizeof *d->s);
    d->exemplar = ts__malloc_array(cap, sizeof *d->exemplar);
    d->x = ts__malloc_array(cap, sizeof *d->x);
    d->y = ts__malloc_array(cap, sizeof *d->y);
    d->dx = ts__malloc_array(cap * (size_t)d->d, sizeof *d->dx);
    if (want_l)
        d->dl = ts__malloc_array(cap * (size_t)d->d, sizeof *d->dl);
    if (K > 0) {
        d->dc = ts__malloc_array(cap * (size_t)K, sizeof *d->dc);
        d->hc = ts__malloc_array(cap * (size_t)d->hd, sizeof *d->hc);
    }
    if (n_layers > 0)
        d->ll = ts__malloc_array(cap * (size_t)n_layers * (size_t)d->hd, sizeof *d->ll);
    if (!d->dh || !d->du || !d->hh || !d->a || !d->s || !d->exemplar || !d->x || !d->y || !d->dx ||
        (want_l && !d->dl) || (K > 0 && (!d->dc || !d->hc)) || (n_layers > 0 && !d->ll))
        return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for %zu atoms", cap);
    return TS_OK;
}

/* Atom k's irradiance descriptor D_l from the window at (x, y) of source
 * sr (0 where the exemplar had no latitude).  lwin: p * p work. */
static void dict_atom_irradiance(ts_dictionary *d, const amp_source *sr, int x, int y, size_t k,
                                 float *lwin)
{
    float *dl = d->dl + k * (size_t)d->d;
    int p = d->patch, ok = sr->irr.data != NULL, i, j;
    double um, urms;
    for (j = 0; j < p && ok; j++)
        for (i = 0; i < p; i++) {
            float v = TS_PIX(&sr->irr, x + i, y + j);
            if (isnan(v)) {
                ok = 0; /* no latitude there */
                break;
            }
            lwin[j * p + i] = v;
        }
    if (ok)
        ts__amp_normalise(lwin, d->d, dl, &um, &urms);
    else
        memset(dl, 0, (size_t)d->d * sizeof *dl);
}

/* Atom k's class codes and class vector from the fine window at (fx, fy)
 * of ex (the shares of its cells in each class, scaled to unit length). */
static void dict_atom_classes(ts_dictionary *d, const ts_exemplar *ex, int fx, int fy, size_t k)
{
    int K = d->n_classes, P = d->patch * d->factor, i, j;
    unsigned char *hc = d->hc + k * (size_t)d->hd;
    float *dc = d->dc + k * (size_t)K;
    double norm = 0;
    memset(dc, 0, (size_t)K * sizeof *dc);
    for (j = 0; j < P; j++)
        for (i = 0; i < P; i++) {
            int c = ex->classes ? ts__class_code(TS_PIX(ex->classes, fx + i, fy + j)) : 0;
            hc[j * P + i] = (unsigned char)c;
            if (c > 0)
                dc[c - 1] += 1.0f;
        }
    for (i = 0; i < K; i++)
        norm += (double)dc[i] * dc[i];
    for (i = 0; i < K && norm > 0; i++)
        dc[i] = (float)(dc[i] / sqrt(norm));
}

/* The atom of the window at (x, y) of source sr, appended to d when it and
 * its fine window are valid and it is not flat.  win, lwin: p * p work. */
static void dict_add_atom(ts_dictionary *d, const ts_exemplar *ex, const amp_source *sr, int x,
                          int y, float *win, float *lwin)
{
    const ts_raster *lowr = &sr->low;
    int p = d->patch, F = d->factor, P = p * F, n_layers = d->n_layers, i, j, l;
    int fx = x * F + sr->ox, fy = y * F + sr->oy; /* its fine window */
    size_t k = d->n;
    double mean, rms, um, urms;
    if (!window_valid(lowr, x, y, p) || !window_valid(&ex->dem, fx, fy, P))
        return;
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++) {
            win[j * p + i] = TS_PIX(lowr, x + i, y + j);
            lwin[j * p + i] = (float)log1p(TS_PIX(&sr->drain, x + i, y + j));
        }
    if (!ts__amp_normalise(win, d->d, d->dh + k * (size_t)d->d, &mean, &rms))
        return; /* a flat atom has no shape to match or give */
    ts__amp_normalise(lwin, d->d, d->du + k * (size_t)d->d, &um, &urms);
    ts__amp_context(lowr, x, y, p, d->dx + k * (size_t)d->d);
    if (d->dl)
        dict_atom_irradiance(d, sr, x, y, k, lwin);
    for (j = 0; j < P; j++)
        for (i = 0; i < P; i++)
            d->hh[k * (size_t)d->hd + (size_t)j * P + i] =
                (float)((TS_PIX(&ex->dem, fx + i, fy + j) - mean) / (rms * sqrt((double)d->d)));
    if (d->n_classes > 0)
        dict_atom_classes(d, ex, fx, fy, k);
    for (l = 0; l < n_layers; l++) {
        float *ll = d->ll + (k * (size_t)n_layers + (size_t)l) * (size_t)d->hd;
        for (j = 0; j < P; j++)
            for (i = 0; i < P; i++)
                ll[j * P + i] = TS_PIX(&ex->layers[l], fx + i, fy + j);
    }
    d->a[k] = mean;
    d->s[k] = rms;
    d->exemplar[k] = sr->e;
    d->x[k] = fx;
    d->y[k] = fy;
    d->n++;
}

TS_API ts_status ts_dictionary_build(ts_ctx *ctx, const ts_exemplar *exemplars, int n_exemplars,
                                     const char *const *layer_names, int n_layers,
                                     const ts_amplify_params *params, ts_dictionary **out)
{
    ts_dictionary *d;
    amp_source *src = NULL;
    int n_src = 0, si;
    size_t cap = 0;
    int e, F, p, P, l, K = 0;
    float *win = NULL, *lwin = NULL;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "no output given");
    *out = NULL;
    if (!exemplars || n_exemplars < 1 || !params)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "no exemplars given");
    if ((st = dict_check_names(ctx, layer_names, n_layers)) != TS_OK)
        return st;
    if (ts_params_validate(ctx, "amplify", params) != TS_OK)
        return ctx->status;
    F = params->factor;
    p = params->patch;
    P = p * F;
    for (e = 0; e < n_exemplars; e++)
        if ((st = check_exemplar(ctx, &exemplars[e], e, n_layers, F, &K)) != TS_OK)
            return st;
    d = calloc(1, sizeof *d);
    src = calloc((size_t)n_exemplars * (size_t)F * (size_t)F, sizeof *src);
    win = malloc((size_t)p * p * sizeof *win);
    lwin = malloc((size_t)p * p * sizeof *lwin);
    if (!d || !src || !win || !lwin) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    d->factor = F;
    d->patch = p;
    d->d = p * p;
    d->hd = P * P;
    d->n_layers = n_layers;
    d->n_classes = K;
    for (l = 0; l < n_layers; l++)
        strcpy(d->layer_names[l], layer_names[l]);
    /* the low-resolution exemplars (a phase or several), their drainage and irradiance,
     * and how many atoms */
    for (e = 0; e < n_exemplars; e++)
        if ((st = dict_exemplar_sources(ctx, &exemplars[e], e, params, src, &n_src, &cap)) !=
                TS_OK ||
            (st = ts__progress(ctx, 0.3 * (e + 1) / n_exemplars, "dictionary")) != TS_OK)
            goto done;
    if ((st = dict_alloc(ctx, d, cap, params->w_l > 0)) != TS_OK)
        goto done;
    for (si = 0; si < n_src; si++) {
        const amp_source *sr = &src[si];
        int x, y;
        for (y = 0; y + p <= sr->low.height; y += sr->step)
            for (x = 0; x + p <= sr->low.width; x += sr->step)
                dict_add_atom(d, &exemplars[sr->e], sr, x, y, win, lwin);
        if ((st = ts__progress(ctx, 0.3 + 0.7 * (si + 1) / n_src, "dictionary")) != TS_OK)
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
    for (si = 0; src && si < n_exemplars * F * F; si++) {
        ts_raster_free(&src[si].low);
        ts_raster_free(&src[si].drain);
        ts_raster_free(&src[si].irr);
    }
    free(src);
    free(win);
    free(lwin);
    if (st != TS_OK) {
        ts_dictionary_free(d);
        return st;
    }
    *out = d;
    return TS_OK;
}
