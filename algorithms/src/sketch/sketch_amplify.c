/*
 * sketch_amplify.c - a sketch in tiles (a TerraSynth addition): the sketch
 * pipeline of synth.c laid out once, whole, on a grid K times coarser with
 * patches K times smaller (the same ground size), the exemplars
 * area-averaged by K; then the result amplified K times (Argudo et al.
 * 2017, amplify/) back onto the output grid, with a dictionary built from
 * the exemplars at the output's resolution.  The coarse pass is the
 * sketch's global part (its feature tree, the layout, the drawn valleys'
 * ways out); the amplification is local, so any window of the output is a
 * function of the coarse terrain near it, and the cost of the sketch's
 * global stages falls by about K^2.
 *
 * The coarse grid is ceil(W / K) x ceil(H / K) cells, anchored at the
 * output's top-left corner; its cells average the output grid's K x K
 * blocks (the part of a block inside the grid): the sketch's grey levels
 * and wanted heights over their valid cells, a region's exemplar from the
 * block's centre, nodata where the whole block is.  The amplified grid is
 * cut to the output's size; the output's nodata cells are set back to NaN.
 * Before the amplification, the coarse pass's carved valley floors are
 * softened (sa_soften_floors).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "ppa_internal.h"
#include "sketch_amplify.h"

/* The atoms the amplification draws from each exemplar: half amplify's
 * default.  It adds only the detail finer than K cells to a coarse pass
 * that holds the rest, and matching every patch against every atom is half
 * the run: with 2048 the sketch matrices in tiles give the same figures
 * (bench/README.md) at four fifths of the time. */
#define SA_ATOMS 2048

/* What ts_sketch_tiles_new was given: a painted sketch, or else a feature
 * graph on the output grid (all borrowed). */
typedef struct sa_job {
    const ts_raster *sketch;
    const ts_features *features;
    const ts_raster *exemplars;
    int n_exemplars;
    const ts_sketch_params *sp;
    const ts_synth_params *params; /* lengths in cells */
    const ts_synth_constraints *constraints;
} sa_job;

TS_API int ts_sketch_amplify_factor(const ts_sketch_params *sp, int patch, int width, int height)
{
    int k = 1;
    if (sp->amplify_factor > 0)
        return sp->amplify_factor;
    while (2 * k <= 16 && patch / (2 * k) >= 32)
        k *= 2;
    if (k == 1 && patch >= 16)
        k = 2;
    /* a coarse grid of at most 2048^2 cells, while patches keep 8 cells */
    while (2 * k <= 16 && patch / (2 * k) >= 8 &&
           (double)((width + k - 1) / k) * (double)((height + k - 1) / k) > 2048.0 * 2048.0)
        k *= 2;
    return k;
}

/* The K x K block average of in over its valid cells (NaN where every
 * cell is NaN) into out (ceil(w / K) x ceil(h / K)). */
static void sa_average(const ts_raster *in, int K, ts_raster *out)
{
    int x, y, u, v;
    for (y = 0; y < out->height; y++)
        for (x = 0; x < out->width; x++) {
            double s = 0.0;
            int n = 0;
            for (v = y * K; v < TS_MIN((y + 1) * K, in->height); v++)
                for (u = x * K; u < TS_MIN((x + 1) * K, in->width); u++)
                    if (!isnan(TS_PIX(in, u, v))) {
                        s += TS_PIX(in, u, v);
                        n++;
                    }
            TS_PIX(out, x, y) = n ? (float)(s / n) : NAN;
        }
}

/* The feature graph f (W x H cells) as lines on a grid `scale` times as
 * fine (x' = (x + 1/2) scale), made a graph there (w x h cells). */
static ts_status sa_graph_scaled(ts_ctx *ctx, const ts_features *f, double scale, int w, int h,
                                 ts_features **out)
{
    ts_sketch_line *lines = ts__calloc_array(f->n_paths + 1, sizeof *lines);
    double *xy = ts__malloc_array(3 * (f->n_verts + 1), sizeof *xy);
    size_t k, j, at = 0, n = 0;
    ts_status st;
    if (!lines || !xy) {
        free(lines);
        free(xy);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    }
    for (k = 0; k < f->n_paths; k++) {
        const ts_feature_path *p = &f->paths[k];
        if (p->count < 1 || !(p->kind == TS_RIDGE || p->kind == TS_VALLEY))
            continue;
        lines[n].kind = p->kind;
        lines[n].n = p->count;
        lines[n].x = xy + at;
        lines[n].y = xy + at + p->count;
        lines[n].z = xy + at + 2 * p->count;
        for (j = 0; j < p->count; j++) {
            const ts_feature_vertex *v = &f->verts[p->first + j];
            xy[at + j] = (v->x + 0.5) * scale;
            xy[at + p->count + j] = (v->y + 0.5) * scale;
            xy[at + 2 * p->count + j] = v->z;
        }
        at += 3 * p->count;
        n++;
    }
    st = ts_features_from_lines(ctx, w, h, lines, n, 1.0, out);
    free(lines);
    free(xy);
    return st;
}

/* The coarse pass's constraints: wanted heights averaged, a region's
 * exemplar from each block's centre, nodata where the whole block is, fixed
 * (into the coarse output) where at least half the block is. */
typedef struct sa_coarse {
    int W, H, K, w, h;
    float *heights;
    int32_t *cell_exemplar;
    unsigned char *flags;
} sa_coarse;

static void sa_coarse_free(sa_coarse *c)
{
    free(c->heights);
    free(c->cell_exemplar);
    free(c->flags);
}

/* Coarse cell (x, y)'s flags from its block of in's flags and values: nodata
 * where the whole block is; fixed at the mean of the block's fixed cells where
 * they are at least half of it (into *v), water where most of those are. */
static unsigned char sa_block_flags(const sa_coarse *c, const ts_synth_constraints *in, int x,
                                    int y, float *v)
{
    int u, w, all = 1, n = 0, fixed = 0, water = 0;
    double s = 0.0;
    for (w = y * c->K; w < TS_MIN((y + 1) * c->K, c->H); w++)
        for (u = x * c->K; u < TS_MIN((x + 1) * c->K, c->W); u++) {
            size_t i = (size_t)w * c->W + (size_t)u;
            unsigned char f = in->cell_flags[i];
            all &= (f & TS_CELL_NODATA) != 0;
            n++;
            if ((f & TS_CELL_FIXED) && in->values && !isnan(in->values[i])) {
                s += in->values[i];
                fixed++;
                water += (f & TS_CELL_WATER) != 0;
            }
        }
    if (all)
        return TS_CELL_NODATA;
    if (2 * fixed < n)
        return 0;
    *v = (float)(s / fixed);
    return (unsigned char)(TS_CELL_FIXED | (2 * water > fixed ? TS_CELL_WATER : 0));
}

static ts_status sa_constraints(ts_ctx *ctx, sa_coarse *c, const ts_synth_constraints *in,
                                ts_synth_constraints *out, ts_raster *fixed)
{
    size_t n = (size_t)c->w * (size_t)c->h;
    int x, y;
    *out = ts_synth_constraints_default();
    if (!in)
        return TS_OK;
    out->alpha_h = in->alpha_h;
    if (in->heights) {
        ts_raster hf = ts_raster_wrap((float *)in->heights, c->W, c->H, c->W), hc;
        if (!(c->heights = ts__malloc_array(n, sizeof(float))))
            return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
        hc = ts_raster_wrap(c->heights, c->w, c->h, c->w);
        sa_average(&hf, c->K, &hc);
        out->heights = c->heights;
    }
    if (in->cell_exemplar) {
        if (!(c->cell_exemplar = ts__malloc_array(n, sizeof(int32_t))))
            return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
        for (y = 0; y < c->h; y++)
            for (x = 0; x < c->w; x++) {
                int cx = TS_MIN(x * c->K + c->K / 2, c->W - 1);
                int cy = TS_MIN(y * c->K + c->K / 2, c->H - 1);
                c->cell_exemplar[(size_t)y * c->w + x] = in->cell_exemplar[(size_t)cy * c->W + cx];
            }
        out->cell_exemplar = c->cell_exemplar;
    }
    if (in->cell_flags) {
        if (!(c->flags = ts__malloc_array(n, 1)))
            return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
        for (y = 0; y < c->h; y++)
            for (x = 0; x < c->w; x++)
                c->flags[(size_t)y * c->w + x] = sa_block_flags(c, in, x, y, &TS_PIX(fixed, x, y));
        out->cell_flags = c->flags;
    }
    return TS_OK;
}

TS_API void ts_sketch_tiles_free(ts_sketch_tiles *t)
{
    if (!t)
        return;
    ts_raster_free(&t->coarse);
    ts_raster_free(&t->drain);
    ts_dictionary_free(t->dict);
    free(t->nodata);
    free(t->ridges);
    free(t);
}

TS_API int ts_sketch_tiles_factor(const ts_sketch_tiles *t)
{
    return t ? t->K : 0;
}

/* Whether output cell i (of W a row) is nodata: NaN in the sketch, or flagged. */
static int sa_is_nodata(const sa_job *j, size_t i, int W)
{
    return (j->sketch && isnan(TS_PIX(j->sketch, (int)(i % (size_t)W), (int)(i / (size_t)W)))) ||
           (j->constraints && j->constraints->cell_flags &&
            (j->constraints->cell_flags[i] & TS_CELL_NODATA));
}

/* The output's nodata, kept when there is any. */
static ts_status sa_nodata(ts_ctx *ctx, ts_sketch_tiles *t, const sa_job *j)
{
    size_t n = (size_t)t->W * (size_t)t->H, i;
    for (i = 0; i < n; i++)
        if (sa_is_nodata(j, i, t->W)) {
            if (!t->nodata && !(t->nodata = ts__calloc_array(n, 1)))
                return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
            t->nodata[i] = 1;
        }
    return TS_OK;
}

/* The coarse pass's carved floors softened (ours): every cell within a
 * cell of a floor cell takes the mean of the 3 x 3 cells round it (valid
 * ones, the values before this step).  The floors are carved one cell wide,
 * and the amplification keeps that edge K cells wide: a sharp slot along
 * each drawn valley where the pipeline in one piece leaves a soft floor. */
static ts_status sa_soften_floors(ts_ctx *ctx, ts_raster *c, const unsigned char *floor)
{
    int w = c->width, h = c->height, x, y, u, v;
    float *z = ts__malloc_array((size_t)w * (size_t)h, sizeof *z);
    if (!z)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    memcpy(z, c->data, (size_t)w * (size_t)h * sizeof *z);
    for (y = 0; y < h; y++)
        for (x = 0; x < w; x++) {
            double s = 0.0;
            int n = 0, near = 0;
            for (v = TS_MAX(0, y - 1); v <= TS_MIN(h - 1, y + 1); v++)
                for (u = TS_MAX(0, x - 1); u <= TS_MIN(w - 1, x + 1); u++) {
                    near |= floor[(size_t)v * w + u];
                    if (!isnan(z[(size_t)v * w + u])) {
                        s += z[(size_t)v * w + u];
                        n++;
                    }
                }
            if (near && !isnan(z[(size_t)y * w + x]))
                c->data[(size_t)y * w + x] = (float)(s / n);
        }
    free(z);
    return TS_OK;
}

/* The coarse pass: the whole sketch pipeline K times coarser into t->coarse. */
static ts_status sa_coarse_pass(ts_ctx *ctx, ts_sketch_tiles *t, const sa_job *j, int P, int ov,
                                ts_features **cf, ts_sketch_info *info)
{
    ts_raster *cex = NULL, csk = {0, 0, 0, NULL};
    ts_features *cfeat = NULL;
    ts_synth_params cp = *j->params;
    ts_synth_constraints cc;
    ts_synth_maps maps;
    sa_coarse c;
    ts_status st = TS_OK;
    int e, K = t->K;
    memset(&c, 0, sizeof c);
    c.W = t->W;
    c.H = t->H;
    c.K = K;
    c.w = (t->W + K - 1) / K;
    c.h = (t->H + K - 1) / K;
    cp.tiled = 0;
    cp.patch_size.value = P / K;
    cp.overlap.value = TS_MIN(TS_MAX(2, ov / K), P / K / 2);
    /* patches of 16 cells or fewer on exemplars K >= 4 times coarser: without the usage
     * cost the fill far from the strokes takes the same few smooth windows again and
     * again, rows of terraces at the patch step (ours) */
    if (cp.usage < 0 && K >= 4)
        cp.usage = TS_SYNTH_USAGE_FREE;
    if (!(cex = ts__calloc_array((size_t)j->n_exemplars, sizeof *cex)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    /* the exemplars area-averaged by K, as the dictionary's low resolution */
    for (e = 0; e < j->n_exemplars && st == TS_OK; e++)
        if ((st = ts_raster_alloc(ctx, j->exemplars[e].width / K, j->exemplars[e].height / K,
                                  &cex[e])) == TS_OK)
            st = ts_area_average(ctx, &j->exemplars[e], K, &cex[e]);
    if (st == TS_OK)
        st = ts_raster_alloc(ctx, c.w, c.h, &t->coarse); /* NaN but the fixed blocks */
    if (st == TS_OK)
        st = sa_constraints(ctx, &c, j->constraints, &cc, &t->coarse);
    memset(&maps, 0, sizeof maps);
    if (st == TS_OK && !(maps.valley_floor = ts__calloc_array((size_t)c.w * (size_t)c.h, 1)))
        st = ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    if (st == TS_OK && j->sketch) {
        if ((st = ts_raster_alloc(ctx, c.w, c.h, &csk)) == TS_OK) {
            sa_average(j->sketch, K, &csk);
            st = ts_synth_sketch(ctx, &csk, cex, j->n_exemplars, j->sp, &cp, &cc, &t->coarse, &maps,
                                 cf, info);
        }
    } else if (st == TS_OK &&
               (st = sa_graph_scaled(ctx, j->features, 1.0 / K, c.w, c.h, &cfeat)) == TS_OK) {
        st = ts_synth_sketch_features(ctx, cfeat, cex, j->n_exemplars, j->sp, &cp, &cc, &t->coarse,
                                      &maps, info);
    }
    if (st == TS_OK && K > 1)
        st = sa_soften_floors(ctx, &t->coarse, maps.valley_floor);
    free(maps.valley_floor);
    for (e = 0; e < j->n_exemplars; e++)
        ts_raster_free(&cex[e]);
    free(cex);
    ts_raster_free(&csk);
    ts_features_free(cfeat);
    sa_coarse_free(&c);
    return st;
}

ts_status ts__sketch_tiles_guide(ts_ctx *ctx, ts_sketch_tiles *t)
{
    ts_status st;
    t->ap = ts_amplify_params_default();
    t->ap.factor = t->K;
    t->ap.w_l = 0.0; /* no latitudes here: the sun's term is off */
    t->ap.atoms = SA_ATOMS;
    if ((t->bank_step = ts__median_step(&t->coarse, NULL)) < 0)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    t->bank_step /= t->K;
    if (t->K == 1)
        return TS_OK;
    if ((st = ts_raster_alloc(ctx, t->coarse.width, t->coarse.height, &t->drain)) == TS_OK)
        st = ts_drainage_area(ctx, &t->coarse, &t->drain);
    return st;
}

/* The amplification's dictionary from the exemplars at the output's cells. */
static ts_status sa_dictionary(ts_ctx *ctx, ts_sketch_tiles *t, const ts_raster *exemplars,
                               int n_exemplars)
{
    ts_exemplar *ex = ts__calloc_array((size_t)n_exemplars, sizeof *ex);
    ts_status st;
    int e;
    if (!ex)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    for (e = 0; e < n_exemplars; e++)
        ex[e].dem = exemplars[e];
    st = ts_dictionary_build(ctx, ex, n_exemplars, NULL, 0, &t->ap, &t->dict);
    free(ex);
    return st;
}

/* The cells of graph f (the output grid's) on a drawn ridge. */
static ts_status sa_ridges(ts_ctx *ctx, ts_sketch_tiles *t, const ts_features *f)
{
    size_t n = (size_t)t->W * (size_t)t->H, i, k = 0;
    for (i = 0; i < n; i++)
        k += (f->mask[i] & TS_RIDGE) != 0;
    if (!k)
        return TS_OK;
    if (!(t->ridges = ts__malloc_array(k, sizeof *t->ridges)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    for (i = 0; i < n; i++)
        if (f->mask[i] & TS_RIDGE)
            t->ridges[t->n_ridges++] = i;
    return TS_OK;
}

TS_API void ts_sketch_tiles_ridges(const ts_sketch_tiles *t, int x0, int y0, int w, int h,
                                   unsigned char *flags, unsigned char bit)
{
    int y;
    if (!t || !flags || x0 < 0 || y0 < 0 || w < 1 || h < 1 || x0 > t->W - w || y0 > t->H - h)
        return;
    for (y = 0; y < h; y++) {
        uint64_t a = (uint64_t)(y0 + y) * (uint64_t)t->W + (uint64_t)x0, b = a + (uint64_t)w;
        size_t lo = ppa_u64_lower(t->ridges, t->n_ridges, a);
        for (; lo < t->n_ridges && t->ridges[lo] < b; lo++)
            flags[(size_t)y * (size_t)w + (size_t)(t->ridges[lo] - a)] |= bit;
    }
}

static ts_status sa_tiles_new(ts_ctx *ctx, const sa_job *j, int W, int H, ts_sketch_tiles **out,
                              ts_features **sketch_features, ts_sketch_info *info)
{
    ts_sketch_tiles *t;
    ts_features *cf = NULL;
    ts_progress_saved sv;
    ts_status st;
    int P, ov;
    *out = NULL;
    if (ts_params_validate(ctx, "sketch", j->sp) != TS_OK ||
        ts_params_validate(ctx, "synth", j->params) != TS_OK ||
        ts__synth_cells(ctx, j->params, &P, &ov) != TS_OK)
        return ts_ctx_status(ctx);
    if (!(t = calloc(1, sizeof *t)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    t->W = W;
    t->H = H;
    t->K = ts_sketch_amplify_factor(j->sp, P, W, H);
    if (P / t->K < 8) {
        st = ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                      "amplify_factor %d leaves patches of %d cells (a patch of %d): at most "
                      "a patch / 8",
                      t->K, P / t->K, P);
        goto done;
    }
    sv = ts__progress_push(ctx, 0.0, 0.8);
    st = sa_coarse_pass(ctx, t, j, P, ov, j->sketch ? &cf : NULL, info);
    ts__progress_pop(ctx, sv);
    if (st == TS_OK)
        st = ts__sketch_tiles_guide(ctx, t);
    if (st == TS_OK && t->K > 1)
        st = sa_dictionary(ctx, t, j->exemplars, j->n_exemplars);
    if (st == TS_OK)
        st = sa_nodata(ctx, t, j);
    if (st == TS_OK && cf) { /* a painted sketch's graph: the coarse pass's on this grid */
        ts_features *f = NULL;
        if ((st = sa_graph_scaled(ctx, cf, t->K, W, H, &f)) == TS_OK)
            st = sa_ridges(ctx, t, f);
        if (st == TS_OK && sketch_features)
            *sketch_features = f;
        else
            ts_features_free(f);
    } else if (st == TS_OK && j->features)
        st = sa_ridges(ctx, t, j->features);
    if (st == TS_OK)
        st = ts__progress(ctx, 1.0, "sketch tiles");
done:
    ts_features_free(cf);
    if (st != TS_OK)
        ts_sketch_tiles_free(t);
    else
        *out = t;
    return st;
}

/* The values of out's cells flagged fixed (NaN elsewhere), or NULL in
 * *values when none is; -1 when out of memory. */
static int sa_fixed_values(const ts_raster *out, const unsigned char *flags, float **values)
{
    size_t n = (size_t)out->width * (size_t)out->height, i, any = 0;
    *values = NULL;
    for (i = 0; flags && i < n; i++)
        any |= flags[i] & TS_CELL_FIXED;
    if (!any)
        return 0;
    if (!(*values = ts__malloc_array(n, sizeof **values)))
        return -1;
    for (i = 0; i < n; i++)
        (*values)[i] = (flags[i] & TS_CELL_FIXED) ? TS_PIX(out, (int)(i % (size_t)out->width),
                                                           (int)(i / (size_t)out->width))
                                                  : NAN;
    return 0;
}

/* ts_sketch_tiles_window with the fixed cells' values given (NULL: none). */
static ts_status sa_window(ts_ctx *ctx, const ts_sketch_tiles *t, int x0, int y0, ts_raster *out,
                           const unsigned char *flags, const float *values)
{
    ts_amplify_guide g;
    ts_status st = TS_OK;
    int x, y;
    if (t->K == 1) /* laid out at the output's cells: nothing to amplify */
        for (y = 0; y < out->height; y++)
            for (x = 0; x < out->width; x++)
                TS_PIX(out, x, y) = TS_PIX(&t->coarse, x0 + x, y0 + y);
    else {
        memset(&g, 0, sizeof g);
        g.drainage = &t->drain;
        st = ts_amplify_window(ctx, &t->coarse, &g, t->dict, &t->ap, x0, y0, out, NULL, NULL);
    }
    if (st == TS_OK && values)
        st = ts__sketch_tiles_fixed(ctx, t, out, flags, values);
    for (y = 0; st == TS_OK && t->nodata && y < out->height; y++)
        for (x = 0; x < out->width; x++)
            if (t->nodata[(size_t)(y0 + y) * t->W + (size_t)(x0 + x)])
                TS_PIX(out, x, y) = NAN;
    return st;
}

TS_API ts_status ts_sketch_tiles_window(ts_ctx *ctx, const ts_sketch_tiles *t, int x0, int y0,
                                        ts_raster *out, const unsigned char *flags)
{
    float *values = NULL;
    ts_status st;
    ts__clear(ctx);
    if (!t || !out || !out->data || x0 < 0 || y0 < 0 || out->width < 1 || out->height < 1 ||
        x0 > t->W - out->width || y0 > t->H - out->height)
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles", "a window off the grid");
    if (sa_fixed_values(out, flags, &values) != 0)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch tiles", "out of memory");
    st = sa_window(ctx, t, x0, y0, out, flags, values);
    free(values);
    return st;
}

TS_API ts_status ts_sketch_tiles_new(ts_ctx *ctx, const ts_raster *sketch,
                                     const ts_features *features, const ts_raster *exemplars,
                                     int n_exemplars, const ts_sketch_params *sp,
                                     const ts_synth_params *params,
                                     const ts_synth_constraints *constraints, int width, int height,
                                     ts_sketch_tiles **out, ts_features **sketch_features,
                                     ts_sketch_info *info)
{
    sa_job j;
    ts__clear(ctx);
    if (out)
        *out = NULL;
    if (sketch_features)
        *sketch_features = NULL;
    if (info)
        memset(info, 0, sizeof *info);
    if (constraints && constraints->cell_flags && !constraints->values)
        for (size_t i = 0; i < (size_t)width * (size_t)height; i++)
            if (constraints->cell_flags[i] & TS_CELL_FIXED)
                return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                                "fixed cells without their values (constraints->values)");
    if (!out || !sp || !params || !exemplars || n_exemplars < 1 || !sketch == !features ||
        (sketch && (!sketch->data || sketch->width != width || sketch->height != height)) ||
        (features && (!features->mask || features->width != width || features->height != height)))
        return ts__fail(ctx, TS_ERR_ARG, "sketch tiles",
                        "a sketch or a feature graph of the grid's size, exemplars and parameters");
    memset(&j, 0, sizeof j);
    j.sketch = sketch;
    j.features = features;
    j.exemplars = exemplars;
    j.n_exemplars = n_exemplars;
    j.sp = sp;
    j.params = params;
    j.constraints = constraints;
    return sa_tiles_new(ctx, &j, width, height, out, features ? NULL : sketch_features, info);
}

ts_status ts__synth_sketch_amplified(ts_ctx *ctx, const ts_raster *sketch,
                                     const ts_features *features, const ts_raster *exemplars,
                                     int n_exemplars, const ts_sketch_params *sp,
                                     const ts_synth_params *params,
                                     const ts_synth_constraints *constraints, ts_raster *out,
                                     ts_features **sketch_features, ts_sketch_info *info)
{
    ts_sketch_tiles *t = NULL;
    ts_synth_constraints c = constraints ? *constraints : ts_synth_constraints_default();
    ts_progress_saved sv;
    ts_status st;
    unsigned char *flags;
    float *values = NULL;
    size_t n, i, any = 0;
    if (!out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "missing sketch, exemplars or output");
    /* the cells given on entry are fixed, as in one piece */
    n = (size_t)out->width * (size_t)out->height;
    if (!(flags = ts__calloc_array(n, 1)))
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    for (i = 0; i < n; i++) {
        if (c.cell_flags)
            flags[i] = c.cell_flags[i];
        if (!isnan(TS_PIX(out, (int)(i % (size_t)out->width), (int)(i / (size_t)out->width))) &&
            !(flags[i] & TS_CELL_NODATA))
            flags[i] |= TS_CELL_FIXED;
        any |= flags[i];
    }
    if (any && sa_fixed_values(out, flags, &values) != 0) {
        free(flags);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    }
    c.cell_flags = any ? flags : NULL;
    c.values = values;
    sv = ts__progress_push(ctx, 0.0, 0.6);
    st = ts_sketch_tiles_new(ctx, sketch, features, exemplars, n_exemplars, sp, params, &c,
                             out->width, out->height, &t, sketch_features, info);
    ts__progress_pop(ctx, sv);
    if (st == TS_OK) {
        sv = ts__progress_push(ctx, 0.6, 1.0);
        st = sa_window(ctx, t, 0, 0, out, c.cell_flags, values);
        ts__progress_pop(ctx, sv);
    }
    ts_sketch_tiles_free(t);
    free(flags);
    free(values);
    return st;
}
