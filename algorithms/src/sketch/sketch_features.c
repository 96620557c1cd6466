/*
 * sketch_features.c - the feature graph of a painted sketch (Zhou et al.
 * 2007 section 3: PPA on the sketch), for sketches of one kind and of both:
 * on a grey ground, strokes brighter than the ground are ridges and
 * strokes darker are valleys (ours: the paper's sketches draw one kind).
 * The ground is the sketch's median; PPA maps ridges on the sketch with
 * everything darker than the ground raised to it, and valleys on the
 * sketch with everything brighter lowered to it, so neither kind's strokes
 * make features of the other (the ground between two valleys is no
 * ridge); the two graphs make one forest.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "feature_placement.h"

/* Sampled on a lattice: at most about this many cells. */
#define AUTO_SAMPLES ((size_t)1 << 20)

/* The valid values of the sketch on a lattice (sorted), at most
 * AUTO_SAMPLES of them; *n = 0 when none is valid or out of memory. */
static float *sketch_sample(const ts_raster *s, size_t *n)
{
    double cells = (double)s->width * (double)s->height;
    int step = cells > (double)AUTO_SAMPLES ? (int)ceil(sqrt(cells / (double)AUTO_SAMPLES)) : 1;
    size_t cap = ((size_t)(s->width / step) + 1) * ((size_t)(s->height / step) + 1);
    float *v = ts__malloc_array(cap, sizeof(float));
    int x, y;
    *n = 0;
    if (!v)
        return NULL;
    for (y = 0; y < s->height; y += step)
        for (x = 0; x < s->width; x += step)
            if (!isnan(TS_PIX(s, x, y)) && *n < cap)
                v[(*n)++] = TS_PIX(s, x, y);
    ts__sort_floats(v, *n);
    return v;
}

int ts__sketch_auto_mode(ts_ctx *ctx, const ts_raster *sketch, double *ground)
{
    size_t n = 0;
    float *v = sketch_sample(sketch, &n);
    double lo, hi, med;
    int mode;
    (void)ctx;
    if (!n) {
        free(v);
        *ground = 0.0;
        return TS_SKETCH_RIDGES;
    }
    lo = v[0];
    hi = v[n - 1];
    med = v[n / 2];
    free(v);
    *ground = med;
    /* a ground in the middle with strokes both ways (60 grey levels of 255
     * either side), else the strokes are the minority: bright ones draw
     * ridges on a dark ground, dark ones valleys on a bright ground */
    if (hi > lo && hi - med >= 0.235 * (hi - lo) && med - lo >= 0.235 * (hi - lo))
        mode = TS_SKETCH_BOTH;
    else
        mode = med <= 0.5 * (lo + hi) ? TS_SKETCH_RIDGES : TS_SKETCH_VALLEYS;
    return mode;
}

ts_status ts__features_merge(ts_ctx *ctx, const ts_features *a, const ts_features *b,
                             ts_features **out)
{
    ts_features *f;
    size_t n = (size_t)a->width * (size_t)a->height, i;
    *out = NULL;
    if (a->width != b->width || a->height != b->height)
        return ts__fail(ctx, TS_ERR_ARG, "sketch", "feature graphs of different sizes");
    f = calloc(1, sizeof *f);
    if (!f)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    f->width = a->width;
    f->height = a->height;
    f->n_nodes = a->n_nodes + b->n_nodes;
    f->n_paths = a->n_paths + b->n_paths;
    f->n_verts = a->n_verts + b->n_verts;
    f->mask = ts__malloc_array(n, 1);
    f->nodes = ts__malloc_array(f->n_nodes + 1, sizeof *f->nodes);
    f->paths = ts__malloc_array(f->n_paths + 1, sizeof *f->paths);
    f->verts = ts__malloc_array(f->n_verts + 1, sizeof *f->verts);
    if (!f->mask || !f->nodes || !f->paths || !f->verts) {
        ts_features_free(f);
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    }
    for (i = 0; i < n; i++)
        f->mask[i] = (unsigned char)(a->mask[i] | b->mask[i]);
    if (a->n_nodes)
        memcpy(f->nodes, a->nodes, a->n_nodes * sizeof *f->nodes);
    if (b->n_nodes)
        memcpy(f->nodes + a->n_nodes, b->nodes, b->n_nodes * sizeof *f->nodes);
    if (a->n_verts)
        memcpy(f->verts, a->verts, a->n_verts * sizeof *f->verts);
    if (b->n_verts)
        memcpy(f->verts + a->n_verts, b->verts, b->n_verts * sizeof *f->verts);
    if (a->n_paths)
        memcpy(f->paths, a->paths, a->n_paths * sizeof *f->paths);
    for (i = 0; i < b->n_paths; i++) {
        ts_feature_path p = b->paths[i];
        p.node_a += a->n_nodes;
        p.node_b += a->n_nodes;
        p.first += a->n_verts;
        f->paths[a->n_paths + i] = p;
    }
    f->threshold_used = a->threshold_used;
    f->threshold_used_valleys = b->threshold_used_valleys;
    *out = f;
    return TS_OK;
}

/* PPA of one kind on the sketch clamped at the ground (from below for
 * ridges, from above for valleys; no clamp when ground is NaN). */
static ts_status sketch_ppa_kind(ts_ctx *ctx, const ts_raster *sketch, const ts_ppa_params *pp,
                                 int kind, double ground, ts_features **out)
{
    ts_ppa_params p = *pp;
    ts_raster c;
    float *buf;
    int x, y;
    ts_status st;
    p.features = kind == TS_VALLEY ? TS_PPA_VALLEYS : TS_PPA_RIDGES;
    if (isnan(ground))
        return ts_ppa_extract(ctx, sketch, NULL, &p, out);
    buf = ts__malloc_array((size_t)sketch->width * (size_t)sketch->height, sizeof(float));
    if (!buf)
        return ts__fail(ctx, TS_ERR_NOMEM, "sketch", "out of memory");
    c = ts_raster_wrap(buf, sketch->width, sketch->height, sketch->width);
    for (y = 0; y < sketch->height; y++)
        for (x = 0; x < sketch->width; x++) {
            float v = TS_PIX(sketch, x, y);
            TS_PIX(&c, x, y) = isnan(v)              ? v
                               : kind == TS_VALLEY ? (float)fmin(v, ground)
                                                   : (float)fmax(v, ground);
        }
    st = ts_ppa_extract(ctx, &c, NULL, &p, out);
    free(buf);
    return st;
}

ts_status ts__sketch_graph(ts_ctx *ctx, const ts_raster *sketch, int mode, double ground,
                           const ts_ppa_params *pp, ts_features **out)
{
    ts_features *r = NULL, *v = NULL;
    ts_status st;
    *out = NULL;
    if (mode != TS_SKETCH_BOTH)
        return sketch_ppa_kind(ctx, sketch, pp, mode == TS_SKETCH_VALLEYS ? TS_VALLEY : TS_RIDGE,
                               NAN, out);
    if ((st = sketch_ppa_kind(ctx, sketch, pp, TS_RIDGE, ground, &r)) == TS_OK &&
        (st = sketch_ppa_kind(ctx, sketch, pp, TS_VALLEY, ground, &v)) == TS_OK)
        st = ts__features_merge(ctx, r, v, out);
    ts_features_free(r);
    ts_features_free(v);
    return st;
}
