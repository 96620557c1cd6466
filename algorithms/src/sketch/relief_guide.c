/*
 * relief_guide.c - the relief a sketch implies (a TerraSynth addition to
 * Zhou et al. 2007, who let the exemplars alone decide the heights).
 *
 * A stroke drawn as a ridge means high ground along the stroke, falling
 * away on both sides; feature patches alone give a crest along the stroke
 * but its height drifts from patch to patch, so a sketched ridge can end up
 * a minor crest in a broad valley.  The guide says how high the land should
 * be near the sketch's features, learnt from the exemplars:
 *
 *   level     mean elevation on the exemplar's main feature cells
 *   drop(d)   level minus the mean elevation of the exemplar's cells d..d+1
 *             cells from the nearest main feature cell (Euclidean distance
 *             transform), made non-decreasing in d; valleys mirrored
 *   guide(x)  level - drop(d(x)), d(x) the distance from output cell x to
 *             the sketch's features, within max_d cells (NaN beyond).
 *
 * Candidates pay alpha_r * RMS(patch - guide) (feature_placement.c,
 * nonfeature_placement.c), a soft height constraint c_i of the paper's kind.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "internal.h"
#include "relief_guide.h"

/* 1-D squared distance transform of f[0..n) (Felzenszwalb and Huttenlocher
 * 2012): d[q] = min_p (q - p)^2 + f[p], arg[q] that p (may be NULL; -1
 * when every f is infinite).  v, z: work of n and n + 1. */
static void edt_1d(const double *f, int n, double *d, int *arg, int *v, double *z)
{
    int k = -1, q;
    for (q = 0; q < n; q++) {
        double s;
        if (!isfinite(f[q]))
            continue;
        for (;;) {
            if (k < 0) {
                s = -INFINITY;
                break;
            }
            s = ((f[q] + (double)q * q) - (f[v[k]] + (double)v[k] * v[k])) / (2.0 * (q - v[k]));
            if (s > z[k])
                break;
            k--;
        }
        k++;
        v[k] = q;
        z[k] = s;
        z[k + 1] = INFINITY;
    }
    if (k < 0) {
        for (q = 0; q < n; q++) {
            d[q] = INFINITY;
            if (arg)
                arg[q] = -1;
        }
        return;
    }
    {
        int j = 0;
        for (q = 0; q < n; q++) {
            while (z[j + 1] < q)
                j++;
            d[q] = (double)(q - v[j]) * (q - v[j]) + f[v[j]];
            if (arg)
                arg[q] = v[j];
        }
    }
}

typedef struct edt_job {
    const unsigned char *mask;
    int width, height;
    double *rows;     /* squared distances along the rows */
    int32_t *row_arg; /* their nearest column, or NULL */
    float *dist;
    int32_t *nearest;  /* index of the nearest mask cell, or NULL */
    atomic_int failed; /* a worker could not get its buffers */
} edt_job;

#define EDT_BLOCK 16 /* columns the vertical pass gathers together */

/* The vertical pass over columns [b, e), EDT_BLOCK adjacent columns at a
 * time: gathered row by row (along memory) into one line each, each line
 * transformed, the results scattered back row by row. */
static void edt_columns(edt_job *j, size_t b, size_t e, double *f, double *d, int *arg, int *v,
                        double *z)
{
    size_t W = (size_t)j->width, H = (size_t)j->height, k0, i, c;
    for (k0 = b; k0 < e; k0 += EDT_BLOCK) {
        size_t bw = TS_MIN((size_t)EDT_BLOCK, e - k0);
        for (i = 0; i < H; i++)
            for (c = 0; c < bw; c++)
                f[c * H + i] = j->rows[i * W + k0 + c];
        for (c = 0; c < bw; c++)
            edt_1d(f + c * H, (int)H, d + c * H, j->nearest ? arg + c * H : NULL, v, z);
        for (i = 0; i < H; i++)
            for (c = 0; c < bw; c++) {
                size_t o = i * W + k0 + c;
                j->dist[o] = (float)sqrt(d[c * H + i]);
                if (j->nearest) {
                    /* the nearest row, then that row's nearest column */
                    int r = arg[c * H + i];
                    int32_t col = r < 0 ? -1 : j->row_arg[(size_t)r * W + k0 + c];
                    j->nearest[o] = col < 0 ? -1 : (int32_t)((size_t)r * W + (size_t)col);
                }
            }
    }
}

/* Rows [b, e) (pass 0) or columns [b, e) (pass 1), with private buffers. */
static void edt_range(edt_job *j, size_t b, size_t e, int pass)
{
    int n = TS_MAX(j->width, j->height), i;
    size_t k, lines = pass ? EDT_BLOCK : 1;
    double *f = ts__malloc_array((size_t)n * lines, sizeof(double));
    double *d = ts__malloc_array((size_t)n * lines, sizeof(double));
    double *z = ts__malloc_array((size_t)n + 1, sizeof(double));
    int *v = ts__malloc_array((size_t)n, sizeof(int));
    int *arg = ts__malloc_array((size_t)n * lines, sizeof(int));
    if (!f || !d || !z || !v || !arg) {
        atomic_store(&j->failed, 1);
    } else if (pass == 0) {
        for (k = b; k < e; k++) {
            const unsigned char *m = j->mask + k * (size_t)j->width;
            for (i = 0; i < j->width; i++)
                f[i] = m[i] ? 0.0 : INFINITY;
            edt_1d(f, j->width, j->rows + k * (size_t)j->width, j->row_arg ? arg : NULL, v, z);
            if (j->row_arg)
                for (i = 0; i < j->width; i++)
                    j->row_arg[k * (size_t)j->width + (size_t)i] = arg[i];
        }
    } else {
        edt_columns(j, b, e, f, d, arg, v, z);
    }
    free(f);
    free(d);
    free(z);
    free(v);
    free(arg);
}

static void edt_rows(void *arg, size_t b, size_t e)
{
    edt_range(arg, b, e, 0);
}

static void edt_cols(void *arg, size_t b, size_t e)
{
    edt_range(arg, b, e, 1);
}

ts_status ts__distance_transform_nearest(ts_ctx *ctx, const unsigned char *mask, int width,
                                         int height, float *dist, int32_t *nearest)
{
    edt_job j;
    size_t n = (size_t)width * (size_t)height;
    j.mask = mask;
    j.width = width;
    j.height = height;
    j.dist = dist;
    j.nearest = nearest;
    atomic_init(&j.failed, 0);
    j.rows = ts__malloc_array(n, sizeof(double));
    j.row_arg = nearest ? ts__malloc_array(n, sizeof(int32_t)) : NULL;
    if (!j.rows || (nearest && !j.row_arg)) {
        free(j.rows);
        free(j.row_arg);
        return ts__fail(ctx, TS_ERR_NOMEM, "relief guide", "out of memory");
    }
    ts__parallel_for(ctx, (size_t)height, edt_rows, &j);
    if (!atomic_load(&j.failed))
        ts__parallel_for(ctx, (size_t)width, edt_cols, &j);
    free(j.rows);
    free(j.row_arg);
    if (atomic_load(&j.failed))
        return ts__fail(ctx, TS_ERR_NOMEM, "relief guide", "out of memory");
    return TS_OK;
}

ts_status ts__distance_transform(ts_ctx *ctx, const unsigned char *mask, int width, int height,
                                 float *dist)
{
    return ts__distance_transform_nearest(ctx, mask, width, height, dist, NULL);
}

ts_status ts__relief_profile_measure(ts_ctx *ctx, const ts_raster *dem, const unsigned char *mask,
                                     int kind, int max_d, ts_relief_profile *prof)
{
    size_t n = (size_t)dem->width * (size_t)dem->height, i, n_level = 0;
    double sign = kind == TS_VALLEY ? -1.0 : 1.0, level = 0.0;
    float *dist = ts__malloc_array(n, sizeof(float));
    unsigned char *m = ts__malloc_array(n, 1);
    double *sum = ts__calloc_array((size_t)max_d + 1, sizeof(double));
    size_t *cnt = ts__calloc_array((size_t)max_d + 1, sizeof(size_t));
    ts_status st;
    int d, x, y;
    memset(prof, 0, sizeof *prof);
    prof->max_d = max_d;
    prof->drop = ts__calloc_array((size_t)max_d + 1, sizeof(double));
    if (!dist || !m || !sum || !cnt || !prof->drop) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "relief guide", "out of memory");
        goto done;
    }
    for (y = 0; y < dem->height; y++)
        for (x = 0; x < dem->width; x++) {
            i = (size_t)y * (size_t)dem->width + (size_t)x;
            m[i] = (mask[i] & kind) && !isnan(TS_PIX(dem, x, y));
            if (m[i]) {
                level += TS_PIX(dem, x, y);
                n_level++;
            }
        }
    if (!n_level) {
        st = TS_OK; /* no such feature: not valid */
        goto done;
    }
    level /= (double)n_level;
    if ((st = ts__distance_transform(ctx, m, dem->width, dem->height, dist)) != TS_OK)
        goto done;
    for (y = 0; y < dem->height; y++)
        for (x = 0; x < dem->width; x++) {
            float v = TS_PIX(dem, x, y);
            double r = dist[(size_t)y * (size_t)dem->width + (size_t)x];
            if (isnan(v) || !(r <= max_d))
                continue;
            d = (int)r;
            sum[d] += sign * (level - v);
            cnt[d]++;
        }
    /* bins with too few cells to say anything hold the previous value */
    {
        double prev = 0.0;
        for (d = 0; d <= max_d; d++) {
            double v = cnt[d] >= 16 ? sum[d] / (double)cnt[d] : prev;
            if (d == 0)
                v = 0.0;
            prev = TS_MAX(prev, v);
            prof->drop[d] = prev;
        }
    }
    prof->level = level;
    prof->valid = 1;
    st = TS_OK;
done:
    free(dist);
    free(m);
    free(sum);
    free(cnt);
    if (st != TS_OK)
        ts__relief_profile_free(prof);
    return st;
}

void ts__relief_profile_free(ts_relief_profile *prof)
{
    if (!prof)
        return;
    free(prof->drop);
    prof->drop = NULL;
    prof->valid = 0;
}

/* drop at a fractional distance (linear between bins). */
static double profile_at(const ts_relief_profile *p, double d)
{
    int i = (int)d;
    double f = d - i;
    if (i >= p->max_d)
        return p->drop[p->max_d];
    return (1.0 - f) * p->drop[i] + f * p->drop[i + 1];
}

ts_status ts__relief_guide(ts_ctx *ctx, const unsigned char *sketch_mask, int kind, int width,
                           int height, const ts_relief_profile *profs, int n_profs,
                           const int32_t *cell_exemplar, const unsigned char *nodata, float *guide)
{
    size_t n = (size_t)width * (size_t)height, i;
    unsigned char *m = ts__malloc_array(n, 1);
    float *dist = ts__malloc_array(n, sizeof(float));
    double sign = kind == TS_VALLEY ? -1.0 : 1.0;
    int e, n_valid = 0, max_d = 0;
    ts_status st;
    if (!m || !dist) {
        free(m);
        free(dist);
        return ts__fail(ctx, TS_ERR_NOMEM, "relief guide", "out of memory");
    }
    for (e = 0; e < n_profs; e++)
        if (profs[e].valid) {
            n_valid++;
            max_d = TS_MAX(max_d, profs[e].max_d);
        }
    for (i = 0; i < n; i++)
        m[i] = (sketch_mask[i] & kind) != 0;
    st = ts__distance_transform(ctx, m, width, height, dist);
    for (i = 0; st == TS_OK && i < n; i++) {
        double d = dist[i], g = 0.0;
        int c = cell_exemplar ? cell_exemplar[i] : -1;
        guide[i] = NAN;
        if (!n_valid || !(d <= max_d) || (nodata && nodata[i]))
            continue;
        if (c >= 0 && c < n_profs && profs[c].valid) {
            g = profs[c].level - sign * profile_at(&profs[c], d);
        } else {
            for (e = 0; e < n_profs; e++)
                if (profs[e].valid)
                    g += profs[e].level - sign * profile_at(&profs[e], d);
            g /= n_valid;
        }
        guide[i] = (float)g;
    }
    free(m);
    free(dist);
    return st;
}

ts_status ts__relief_guide_both(ts_ctx *ctx, const unsigned char *sketch_mask, int width,
                                int height, const ts_relief_profile *profs_r,
                                const ts_relief_profile *profs_v, int n_profs,
                                const int32_t *cell_exemplar, const unsigned char *nodata,
                                float *guide)
{
    size_t n = (size_t)width * (size_t)height, i;
    float *gv = ts__malloc_array(n, sizeof(float));
    float *dr = ts__malloc_array(n, sizeof(float)), *dv = ts__malloc_array(n, sizeof(float));
    unsigned char *m = ts__malloc_array(n, 1);
    ts_status st = TS_OK;
    if (!gv || !dr || !dv || !m) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "relief guide", "out of memory");
        goto done;
    }
    if ((st = ts__relief_guide(ctx, sketch_mask, TS_RIDGE, width, height, profs_r, n_profs,
                               cell_exemplar, nodata, guide)) != TS_OK ||
        (st = ts__relief_guide(ctx, sketch_mask, TS_VALLEY, width, height, profs_v, n_profs,
                               cell_exemplar, nodata, gv)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        m[i] = (sketch_mask[i] & TS_RIDGE) != 0;
    if ((st = ts__distance_transform(ctx, m, width, height, dr)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        m[i] = (sketch_mask[i] & TS_VALLEY) != 0;
    if ((st = ts__distance_transform(ctx, m, width, height, dv)) != TS_OK)
        goto done;
    /* where both reach: the ridge's relief near the ridge, the valley's near
     * the valley, weighted by the distance to the other */
    for (i = 0; i < n; i++) {
        if (isnan(guide[i]))
            guide[i] = gv[i];
        else if (!isnan(gv[i])) {
            double w = dr[i] + dv[i] > 0 ? dv[i] / (dr[i] + dv[i]) : 0.5;
            guide[i] = (float)(w * guide[i] + (1.0 - w) * gv[i]);
        }
    }
done:
    free(gv);
    free(dr);
    free(dv);
    free(m);
    return st;
}
