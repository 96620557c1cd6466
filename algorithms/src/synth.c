/*
 * synth.c - the two synthesis pipelines of Zhou et al. 2007, each a
 * sequence of the stages in the other files:
 *
 * ts_synth_patches: the non-feature fill alone (section 4.2 and 5:
 *    nonfeature_placement.c, match_ssd.c, seam_graphcut.c, poisson.c).
 *
 * ts_synth_sketch (sections 3 and 4):
 * 1. PPA on the sketch (ridges or valleys: ppa.c) and the patch sites in
 *    breadth-first order over its feature tree, or in raster order
 *    (feature_tree.c).
 * 2. PPA on every exemplar, only its main features: their patch sites,
 *    their relief profiles (relief_guide.c) and a mask of them that the
 *    fill keeps away from.
 * 3. The relief the sketch implies (relief_guide.c), a soft height
 *    constraint of every candidate from here on.
 * 4. Feature patches at the sites (feature_placement.c).
 * 5. The non-feature fill around the fixed features, which may take
 *    windows with main features only near the sketch's strokes.
 * 6. The layout (layout.c, a TerraSynth addition): the large-scale relief
 *    rises to sketched ridges and falls to sketched valleys; then the slope
 *    style (slope_style.c) and the water banks (water_banks.c), ours too.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "feature_placement.h"
#include "feature_tree.h"
#include "layout.h"
#include "relief_guide.h"
#include "sketch_amplify.h"
#include "slope_style.h"

TS_API ts_synth_constraints ts_synth_constraints_default(void)
{
    ts_synth_constraints c;
    memset(&c, 0, sizeof c);
    c.alpha_h = 1.0;
    return c;
}

ts__fill ts__fill_make(const ts_synth_params *p, const ts_synth_constraints *c)
{
    ts__fill f;
    memset(&f, 0, sizeof f);
    f.s = *p;
    if (c) {
        f.cell_flags = c->cell_flags;
        f.cell_exemplar = c->cell_exemplar;
        f.heights = c->heights;
        f.alpha_h = c->alpha_h;
    }
    return f;
}

static ts_status synth_check_constraints(ts_ctx *ctx, const ts_synth_constraints *c)
{
    if (c && c->heights && !(c->alpha_h >= 0.0 && c->alpha_h <= 1e9))
        return ts__fail(ctx, TS_ERR_ARG, "synth", "alpha_h = %g must be in [0, 1e9]", c->alpha_h);
    return TS_OK;
}

TS_API ts_status ts_synth_patches(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars,
                                  const ts_synth_params *params,
                                  const ts_synth_constraints *constraints, ts_raster *out,
                                  ts_synth_maps *maps)
{
    ts__fill f;
    ts__clear(ctx);
    if (!params)
        return ts__fail(ctx, TS_ERR_ARG, "synth", "missing exemplars, parameters or output");
    if (synth_check_constraints(ctx, constraints) != TS_OK)
        return ctx->status;
    if (params->tiled > 0)
        return ts__synth_tiled_maps(ctx, exemplars, n_exemplars, params, constraints, params->tiled,
                                    out, maps);
    f = ts__fill_make(params, constraints);
    if (f.s.usage < 0) /* automatic: on in free synthesis */
        f.s.usage = TS_SYNTH_USAGE_FREE;
    if (ts__fill_run(ctx, exemplars, n_exemplars, &f, out, maps) != TS_OK)
        return ctx->status;
    {
        int P, ov;
        if (ts__synth_cells(ctx, params, &P, &ov) != TS_OK)
            return ctx->status;
        return ts__water_banks(ctx, out, constraints ? constraints->cell_flags : NULL, P);
    }
}

/* ---- the sketch pipeline ------------------------------------------- */

/* What the pipeline owns. */
typedef struct sketch_run {
    unsigned char *flags;      /* the fill's and the placement's cell flags */
    unsigned char *user_flags; /* what the caller fixed (pins, water), before any feature */
    const ts_features *sf;     /* the sketch's feature graph */
    ts_features *own_sf;       /* ... when made here (PPA on a painted sketch) */
    int kind;                  /* the kinds it draws: bits TS_RIDGE, TS_VALLEY */
    ts_feature_site *sites;
    size_t n_sites;
    ts__ex_site *es; /* the exemplars' sites */
    size_t n_es;
    ts_relief_profile *profs[2]; /* per exemplar: [0] ridges, [1] valleys */
    unsigned char **ex_features; /* per exemplar: its main features of the kinds (or NULL) */
    ts__crest_library *crest;    /* per exemplar: its crests' pieces (ridges, with the layout) */
    float *guide;
    int n_ex;
} sketch_run;

static void sketch_run_free(sketch_run *r)
{
    int e, k;
    free(r->flags);
    free(r->user_flags);
    free(r->sites);
    free(r->es);
    free(r->guide);
    for (k = 0; k < 2; k++) {
        if (r->profs[k])
            for (e = 0; e < r->n_ex; e++)
                ts__relief_profile_free(&r->profs[k][e]);
        free(r->profs[k]);
    }
    if (r->ex_features)
        for (e = 0; e < r->n_ex; e++)
            free(r->ex_features[e]);
    free(r->ex_features);
    if (r->crest)
        for (e = 0; e < r->n_ex; e++)
            ts__crest_library_free(&r->crest[e]);
    free(r->crest);
    ts_features_free(r->own_sf);
}

/* Step 2 for exemplar e: its main features of the kinds (profiles a third
 * of a patch long, a dip of 2 % of the relief, branches of a patch length:
 * a sketch's stroke stands for a major ridge or valley, not any crease). */
static ts_status sketch_exemplar(ts_ctx *ctx, sketch_run *r, const ts_raster *ex, int e,
                                 const ts_ppa_params *pp, const ts_sketch_params *sp, int P)
{
    ts_ppa_params epp = *pp;
    ts_features *ef = NULL;
    ts_feature_site *es = NULL;
    size_t n_es = 0, j, ne, c;
    ts__ex_site *grown;
    ts_status st;
    int k;
    epp.features = r->kind == (TS_RIDGE | TS_VALLEY) ? TS_PPA_BOTH
                   : r->kind == TS_VALLEY            ? TS_PPA_VALLEYS
                                                     : TS_PPA_RIDGES;
    epp.profile_length = TS_MAX(11, (P / 3) | 1);
    epp.threshold_fraction = 0.02;
    epp.min_branch_length.value = P;
    st = ts_ppa_extract(ctx, ex, NULL, &epp, &ef);
    if (st == TS_ERR_CANCELLED || st == TS_ERR_NOMEM)
        return st;
    if (st != TS_OK) {
        ts__clear(ctx);
        return TS_OK; /* no features in this exemplar: it still serves the fill */
    }
    st = ts__feature_sites(ctx, ef, r->kind, 0.5 * P - 1.0, 6.0, 0, &es, &n_es);
    for (k = 0; k < 2 && st == TS_OK; k++)
        if ((r->kind & (k ? TS_VALLEY : TS_RIDGE)) && (sp->alpha_r > 0 || sp->layout > 0))
            st = ts__relief_profile_measure(ctx, ex, ef->mask, k ? TS_VALLEY : TS_RIDGE, P,
                                            &r->profs[k][e]);
    if (st == TS_OK && (r->kind & TS_RIDGE) && sp->layout > 0 && sp->crest_relief > 0)
        st = ts__crest_library_measure(ctx, ef, P, &r->crest[e]);
    if (st == TS_OK) {
        /* the fill keeps away from these (section 4.2) */
        ne = (size_t)ef->width * (size_t)ef->height;
        if (!(r->ex_features[e] = ts__malloc_array(ne, 1)))
            st = ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
        for (c = 0; st == TS_OK && c < ne; c++)
            r->ex_features[e][c] = (ef->mask[c] & r->kind) != 0;
    }
    ts_features_free(ef);
    if (st != TS_OK) {
        free(es);
        return st;
    }
    grown = realloc(r->es, (r->n_es + n_es + 1) * sizeof *grown);
    if (!grown) {
        free(es);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    }
    r->es = grown;
    for (j = 0; j < n_es; j++) {
        r->es[r->n_es].ex = e;
        r->es[r->n_es].site = es[j];
        r->n_es++;
    }
    free(es);
    return TS_OK;
}

/* *d (W x H floats, the caller frees it): each cell's distance in cells to
 * the nearest cell of f of the kinds. */
static ts_status sketch_distance(ts_ctx *ctx, const ts_features *f, int kinds, float **d)
{
    size_t n = (size_t)f->width * (size_t)f->height, i;
    unsigned char *m = ts__malloc_array(n, 1);
    ts_status st;
    *d = ts__malloc_array(n, sizeof **d);
    if (!*d || !m) {
        free(m);
        free(*d);
        *d = NULL;
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    }
    for (i = 0; i < n; i++)
        m[i] = (f->mask[i] & kinds) != 0;
    st = ts__distance_transform(ctx, m, f->width, f->height, *d);
    free(m);
    return st;
}

/* Step 5's flags: windows within a patch of the sketch's features may take
 * any exemplar window; farther away only featureless ones. */
static ts_status sketch_feature_zone(ts_ctx *ctx, const sketch_run *r, int P)
{
    size_t n = (size_t)r->sf->width * (size_t)r->sf->height, i;
    float *d;
    ts_status st = sketch_distance(ctx, r->sf, r->kind, &d);
    for (i = 0; st == TS_OK && i < n; i++)
        if (d[i] <= P)
            r->flags[i] |= TS__CELL_FEATURE;
    free(d);
    return st;
}

/* The checks and the cell flags every sketch synthesis starts from: the
 * sketch's nodata (NaN in `sketch`, which may be NULL, or flagged) stays
 * nodata; the caller's fixed cells (pins, water: flagged, or filled on
 * entry) are kept; the rest is made. */
static ts_status sketch_begin(ts_ctx *ctx, sketch_run *r, const ts_raster *sketch, int W, int H,
                              const ts_raster *exemplars, int n_exemplars,
                              const ts_sketch_params *sp, const ts_synth_params *params,
                              const ts_synth_constraints *constraints, ts_raster *out, int *P)
{
    size_t i, n_cells;
    int ov = 0, k;
    if (!out || !out->data || !sp || !params || !exemplars || n_exemplars < 1)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "missing sketch, exemplars or output");
    if (out->width != W || out->height != H)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "the output must have the sketch's size");
    if (ts_params_validate(ctx, "sketch", sp) != TS_OK ||
        ts_params_validate(ctx, "synth", params) != TS_OK ||
        ts__synth_cells(ctx, params, P, &ov) != TS_OK ||
        synth_check_constraints(ctx, constraints) != TS_OK)
        return ctx->status;
    if (W < *P || H < *P)
        return ts__fail(ctx, TS_ERR_SIZE, "sketch", "the sketch (%d x %d) is smaller than a patch",
                        W, H);
    n_cells = (size_t)W * (size_t)H;
    r->n_ex = n_exemplars;
    r->flags = ts__calloc_array(n_cells, 1);
    r->user_flags = ts__malloc_array(n_cells, 1);
    for (k = 0; k < 2; k++)
        r->profs[k] = ts__calloc_array((size_t)n_exemplars, sizeof *r->profs[k]);
    r->ex_features = ts__calloc_array((size_t)n_exemplars, sizeof *r->ex_features);
    r->crest = ts__calloc_array((size_t)n_exemplars, sizeof *r->crest);
    if (!r->flags || !r->user_flags || !r->profs[0] || !r->profs[1] || !r->ex_features || !r->crest)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    for (i = 0; i < n_cells; i++) {
        size_t y = i / (size_t)W, x = i % (size_t)W;
        float *o = &out->data[y * (size_t)out->stride + x];
        unsigned char cf = constraints && constraints->cell_flags ? constraints->cell_flags[i] : 0;
        if ((sketch && isnan(sketch->data[y * (size_t)sketch->stride + x])) ||
            (cf & TS_CELL_NODATA)) {
            r->flags[i] = TS_CELL_NODATA;
            *o = NAN;
        } else if (!isnan(*o))
            r->flags[i] = TS_CELL_FIXED;
    }
    /* the layout keeps away from these, not from the feature cores fixed later;
     * the valley breach also knows the water among them (an outlet) */
    memcpy(r->user_flags, r->flags, n_cells);
    for (i = 0; constraints && constraints->cell_flags && i < n_cells; i++)
        if (r->flags[i] == TS_CELL_FIXED && (constraints->cell_flags[i] & TS_CELL_WATER))
            r->user_flags[i] |= TS_CELL_WATER;
    return TS_OK;
}

/* Steps 2-4: the exemplars' main features, the relief the sketch implies,
 * the feature patches.  times[1], times[2]: their seconds. */
static ts_status sketch_features_placed(ts_ctx *ctx, sketch_run *r, ts__fill *fill,
                                        const ts_raster *exemplars, int n_exemplars,
                                        const ts_sketch_params *sp, const ts_ppa_params *pp,
                                        const ts_synth_params *params, ts_raster *out,
                                        ts_synth_maps *maps, int P, size_t *n_placed, double *times)
{
    ts_progress_saved sv;
    ts_status st;
    double t0 = ts__now();
    int e;
    st = ts__feature_sites(ctx, r->sf, r->kind, 0.5 * P - 1.0, 0.5 * P,
                           params->order != TS_ORDER_RASTER, &r->sites, &r->n_sites);
    /* 2. the exemplars' main features */
    for (e = 0; st == TS_OK && e < n_exemplars; e++) {
        sv = ts__progress_push(ctx, 0.05 + 0.15 * e / n_exemplars,
                               0.05 + 0.15 * (e + 1) / n_exemplars);
        st = sketch_exemplar(ctx, r, &exemplars[e], e, pp, sp, P);
        ts__progress_pop(ctx, sv);
    }
    times[1] = ts__now() - t0;
    t0 = ts__now();
    /* 3. the relief the sketch implies, learnt from the exemplars */
    if (st == TS_OK && sp->alpha_r > 0) {
        size_t n_cells = (size_t)out->width * (size_t)out->height;
        if (!(r->guide = ts__malloc_array(n_cells, sizeof(float))))
            return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
        st = r->kind == (TS_RIDGE | TS_VALLEY)
                 ? ts__relief_guide_both(ctx, r->sf->mask, out->width, out->height, r->profs[0],
                                         r->profs[1], n_exemplars, fill->cell_exemplar, NULL,
                                         r->guide)
                 : ts__relief_guide(ctx, r->sf->mask, r->kind, out->width, out->height,
                                    r->profs[r->kind == TS_VALLEY], n_exemplars,
                                    fill->cell_exemplar, NULL, r->guide);
        fill->guide = r->guide;
        fill->alpha_r = sp->alpha_r;
    }
    /* 4. feature patches */
    if (st == TS_OK) {
        ts__feature_job j;
        j.sp = sp;
        j.fill = fill;
        j.exemplars = exemplars;
        j.n_exemplars = n_exemplars;
        j.sketch_features = r->sf;
        j.kind = r->kind;
        j.exemplar_sites = r->es;
        j.n_exemplar_sites = r->n_es;
        j.sites = r->sites;
        j.n_sites = r->n_sites;
        sv = ts__progress_push(ctx, 0.2, 0.6);
        st = ts__place_features(ctx, &j, out, r->flags, maps, n_placed);
        ts__progress_pop(ctx, sv);
    }
    times[2] = ts__now() - t0;
    return st;
}

/* The floor map keeps the drawn valleys' floors, not their ways out: the
 * floor cells within the thalweg's reach (patch / 10 cells) of a drawn
 * valley cell. */
static ts_status sketch_floor_drawn(ts_ctx *ctx, const ts_features *f, unsigned char *floor, int P)
{
    size_t n = (size_t)f->width * (size_t)f->height, i;
    double reach = TS_MAX(2.0, P / 10.0);
    float *d;
    ts_status st = sketch_distance(ctx, f, TS_VALLEY, &d);
    for (i = 0; st == TS_OK && i < n; i++)
        if (floor[i] && !(d[i] <= reach))
            floor[i] = 0;
    free(d);
    return st;
}

/* Steps 6-10, after the fill: the layout, the slope style, the wanted
 * heights, the water banks, the drawn valleys' floors; times[0..2]: the
 * seconds of the layout, of the slope style and of the rest. */
static ts_status sketch_finish(ts_ctx *ctx, const sketch_run *r, const ts__fill *fill,
                               const ts_raster *exemplars, int n_exemplars,
                               const ts_sketch_params *sp, const ts_synth_constraints *constraints,
                               ts_raster *out, int P, ts_synth_maps *maps, double *times)
{
    ts_status st = TS_OK;
    double t0 = ts__now();
    ts_features *way = NULL; /* the drawn valleys with their ways out */
    /* 6. the relief the sketch lays out, the valleys with their ways out */
    if (sp->layout > 0) {
        ts_layout_spec ls;
        if ((r->kind & TS_VALLEY) &&
            (st = ts__valley_outlets(ctx, r->sf, out, r->user_flags, P, &way)) != TS_OK)
            return st;
        memset(&ls, 0, sizeof ls);
        ls.sketch_mask = way ? way->mask : r->sf->mask;
        ls.kind = r->kind;
        ls.width = out->width;
        ls.height = out->height;
        ls.exemplars = exemplars;
        ls.n_exemplars = n_exemplars;
        ls.profs = r->profs[r->kind == TS_VALLEY];
        ls.cell_exemplar = fill->cell_exemplar;
        ls.patch = P;
        ls.features = way ? way : r->sf;
        ls.steep_lo = sp->slope_style > 0 ? 1.0 : 0.35;
        ls.crest = sp->crest_relief > 0 ? r->crest : NULL;
        ls.crest_relief = sp->crest_relief;
        st = ts__layout_apply(ctx, &ls, out, r->user_flags, sp->layout);
        if (st == TS_OK)
            st = ts__progress(ctx, sp->slope_style > 0 ? 0.97 : 1.0, "layout");
    }
    times[0] = ts__now() - t0;
    t0 = ts__now();
    /* 7. the exemplars' distribution of slopes (ours, slope_style.c) */
    if (st == TS_OK && sp->slope_style > 0) {
        ts_slope_style_spec ss;
        ts_progress_saved sv2;
        memset(&ss, 0, sizeof ss);
        ss.exemplars = exemplars;
        ss.n_exemplars = n_exemplars;
        ss.cell_exemplar = fill->cell_exemplar;
        ss.flags = r->user_flags;
        ss.strength = sp->slope_style;
        ss.features = r->sf->mask;
        ss.kind = r->kind;
        ss.keep_radius = P / 2.0;
        ss.scale = P;
        sv2 = ts__progress_push(ctx, 0.97, 1.0);
        st = ts__slope_style(ctx, &ss, out);
        /* steeper slopes over a grid larger than the exemplar can carry the
         * land past the exemplars' heights: pressed back as the layout does */
        if (st == TS_OK)
            st = ts__layout_press_range(ctx, exemplars, n_exemplars, out, r->user_flags, P);
        ts__progress_pop(ctx, sv2);
    }
    times[1] = ts__now() - t0;
    t0 = ts__now();
    /* 8. the user's wanted heights, which the layout and the slope style do
     * not know, kept at large scale (ours, layout.c) */
    if (st == TS_OK && constraints && (sp->layout > 0 || sp->slope_style > 0))
        st = ts__layout_keep_heights(ctx, out, constraints->heights, constraints->alpha_h,
                                     r->user_flags, P);
    /* 9. the land beside water at or above it (ours, water_banks.c) */
    if (st == TS_OK && constraints)
        st = ts__water_banks(ctx, out, constraints->cell_flags, P);
    /* 10. drawn valleys that drain to their outlets along their ways out
     * (ours, valley_breach.c) */
    if (st == TS_OK && (r->kind & TS_VALLEY) && sp->layout > 0) {
        unsigned char *floor = maps ? maps->valley_floor : NULL;
        st = ts__valley_breach(ctx, way ? way : r->sf, out, r->user_flags, P, floor);
        if (st == TS_OK && floor && way)
            st = sketch_floor_drawn(ctx, r->sf, floor, P);
    }
    ts_features_free(way);
    times[2] = ts__now() - t0;
    return st;
}

/* Steps 2-9 on the sketch's feature graph r->sf. */
static ts_status sketch_stages(ts_ctx *ctx, sketch_run *r, const ts_raster *exemplars,
                               int n_exemplars, const ts_sketch_params *sp, const ts_ppa_params *pp,
                               const ts_synth_params *params,
                               const ts_synth_constraints *constraints, ts_raster *out,
                               ts_synth_maps *maps, int P, ts_sketch_info *info, double *times)
{
    ts__fill fill = ts__fill_make(params, constraints);
    ts_progress_saved sv;
    size_t n_placed = 0;
    double t0;
    ts_status st;
    if (fill.s.usage < 0) /* automatic: off with a sketch (feature recall, seams) */
        fill.s.usage = 0.0;
    st = sketch_features_placed(ctx, r, &fill, exemplars, n_exemplars, sp, pp, params, out, maps, P,
                                &n_placed, times);
    if (info) {
        info->n_sites = r->n_sites;
        info->n_feature_patches = n_placed;
        info->n_exemplar_sites = r->n_es;
    }
    if (st != TS_OK)
        return st;
    /* 5. the non-feature fill around the fixed features (the order
     * parameter reorders the feature sites only: the fill always grows out
     * from them) */
    t0 = ts__now();
    if ((st = sketch_feature_zone(ctx, r, P)) != TS_OK)
        return st;
    fill.s.order = TS_ORDER_GROW;
    fill.cell_flags = r->flags;
    fill.exemplar_features = (const unsigned char *const *)r->ex_features;
    sv = ts__progress_push(ctx, 0.6, 0.95);
    st = ts__fill_run(ctx, exemplars, n_exemplars, &fill, out, maps);
    ts__progress_pop(ctx, sv);
    times[3] = ts__now() - t0;
    if (st == TS_OK)
        st = sketch_finish(ctx, r, &fill, exemplars, n_exemplars, sp, constraints, out, P, maps,
                           times + 4);
    return st;
}

static void sketch_info_times(ts_sketch_info *info, const double *times)
{
    if (!info)
        return;
    info->seconds_sketch_ppa = times[0];
    info->seconds_exemplar_ppa = times[1];
    info->seconds_features = times[2];
    info->seconds_fill = times[3];
    info->seconds_layout = times[4];
    info->seconds_slope_style = times[5];
    info->seconds_finish = times[6];
}

/* PPA parameters for the sketch and, changed per exemplar, for them. */
static ts_ppa_params sketch_ppa_params(int P)
{
    ts_ppa_params pp = ts_ppa_params_default();
    pp.min_drainage = 0; /* a drawing's valleys and an exemplar's main ones: by profile */
    pp.min_branch_length.value = TS_MIN(40.0, 0.5 * P);
    return pp;
}

static int sketch_mode_of(int kind)
{
    return kind == (TS_RIDGE | TS_VALLEY) ? TS_SKETCH_BOTH
           : kind == TS_VALLEY            ? TS_SKETCH_VALLEYS
                                          : TS_SKETCH_RIDGES;
}

TS_API ts_status ts_synth_sketch(ts_ctx *ctx, const ts_raster *sketch, const ts_raster *exemplars,
                                 int n_exemplars, const ts_sketch_params *sp,
                                 const ts_synth_params *params,
                                 const ts_synth_constraints *constraints, ts_raster *out,
                                 ts_synth_maps *maps, ts_features **sketch_features,
                                 ts_sketch_info *info)
{
    sketch_run r;
    ts_ppa_params pp;
    ts_progress_saved sv;
    ts_status st;
    int P = 0, mode;
    double t0 = ts__now(), times[7] = {0, 0, 0, 0, 0, 0, 0}, ground = NAN;
    ts__clear(ctx);
    memset(&r, 0, sizeof r);
    if (sketch_features)
        *sketch_features = NULL;
    if (info)
        memset(info, 0, sizeof *info);
    if (!sketch || !sketch->data)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "missing sketch, exemplars or output");
    if (params && params->tiled > 0) /* in tiles: laid out coarser, amplified */
        return ts__synth_sketch_amplified(ctx, sketch, NULL, exemplars, n_exemplars, sp, params,
                                          constraints, out, sketch_features, info);
    st = sketch_begin(ctx, &r, sketch, sketch->width, sketch->height, exemplars, n_exemplars, sp,
                      params, constraints, out, &P);
    if (st != TS_OK)
        goto done;
    /* 1. the sketch's features and sites */
    pp = sketch_ppa_params(P);
    mode = sp->mode;
    {
        int auto_mode = ts__sketch_auto_mode(ctx, sketch, &ground);
        if (mode == TS_SKETCH_AUTO)
            mode = auto_mode;
    }
    r.kind = mode == TS_SKETCH_BOTH      ? TS_RIDGE | TS_VALLEY
             : mode == TS_SKETCH_VALLEYS ? TS_VALLEY
                                         : TS_RIDGE;
    if (info)
        info->mode = mode;
    sv = ts__progress_push(ctx, 0.0, 0.05);
    st = ts__sketch_graph(ctx, sketch, mode, ground, &pp, &r.own_sf);
    ts__progress_pop(ctx, sv);
    times[0] = ts__now() - t0;
    if (st != TS_OK) {
        ts__fail(ctx, st, "sketch", "PPA on the sketch: %s", ctx->message);
        goto done;
    }
    r.sf = r.own_sf;
    st = sketch_stages(ctx, &r, exemplars, n_exemplars, sp, &pp, params, constraints, out, maps, P,
                       info, times);
    sketch_info_times(info, times);
done:
    if (st == TS_OK && sketch_features) {
        *sketch_features = r.own_sf;
        r.own_sf = NULL;
    }
    sketch_run_free(&r);
    return st;
}

TS_API ts_status ts_synth_sketch_features(ts_ctx *ctx, const ts_features *features,
                                          const ts_raster *exemplars, int n_exemplars,
                                          const ts_sketch_params *sp, const ts_synth_params *params,
                                          const ts_synth_constraints *constraints, ts_raster *out,
                                          ts_synth_maps *maps, ts_sketch_info *info)
{
    sketch_run r;
    ts_ppa_params pp;
    ts_status st;
    int P = 0;
    size_t i, n;
    double times[7] = {0, 0, 0, 0, 0, 0, 0};
    ts__clear(ctx);
    memset(&r, 0, sizeof r);
    if (info)
        memset(info, 0, sizeof *info);
    if (!features || !features->mask)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "missing feature graph");
    if (params && params->tiled > 0) /* in tiles: laid out coarser, amplified */
        return ts__synth_sketch_amplified(ctx, NULL, features, exemplars, n_exemplars, sp, params,
                                          constraints, out, NULL, info);
    st = sketch_begin(ctx, &r, NULL, features->width, features->height, exemplars, n_exemplars, sp,
                      params, constraints, out, &P);
    if (st == TS_OK) {
        n = (size_t)features->width * (size_t)features->height;
        for (i = 0; i < n; i++)
            r.kind |= features->mask[i] & (TS_RIDGE | TS_VALLEY);
        if (sp->mode == TS_SKETCH_RIDGES || sp->mode == TS_SKETCH_VALLEYS)
            r.kind &= sp->mode == TS_SKETCH_VALLEYS ? TS_VALLEY : TS_RIDGE;
        if (!r.kind)
            st = ts__fail(ctx, TS_ERR_ARG, "sketch", "the sketch holds no %s on the grid",
                          sp->mode == TS_SKETCH_RIDGES    ? "ridge"
                          : sp->mode == TS_SKETCH_VALLEYS ? "valley"
                                                          : "ridge or valley");
    }
    if (st == TS_OK) {
        if (info)
            info->mode = sketch_mode_of(r.kind);
        pp = sketch_ppa_params(P);
        r.sf = features;
        st = sketch_stages(ctx, &r, exemplars, n_exemplars, sp, &pp, params, constraints, out, maps,
                           P, info, times);
        sketch_info_times(info, times);
    }
    sketch_run_free(&r);
    return st;
}
