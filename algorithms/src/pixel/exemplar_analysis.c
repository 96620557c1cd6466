/*
 * exemplar_analysis.c - the exemplars analysed for multiresolution pixel
 * synthesis (Lefebvre and Hoppe 2005; Cruz et al. section II.A),
 * ts_pixel_prepare: the levels and each level's window, the turned and
 * mirrored candidates as affine maps into the exemplars, every exemplar's
 * Gaussian stack (its levels built in parallel), the appearance space, the
 * k-coherence similarity sets, the stacks' nodata filled and the relief
 * start; the coordinates are synthesised by coordinate_synthesis.c.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"
#include "relief_guide.h"

typedef struct stack_job {
    const ts_raster *exemplars;
    ts_pixel_exemplars *ex;
    int L, k, fail;
} stack_job;

/* Task t: exemplar t / (L + 1), level t % (L + 1), of the exemplars as given. */
static void stack_levels(void *arg, size_t begin, size_t end)
{
    stack_job *j = arg;
    size_t t;
    for (t = begin; t < end; t++) {
        int e = (int)(t / (size_t)(j->L + 1)), l = (int)(t % (size_t)(j->L + 1));
        if (ts__pix_stack_level(&j->exemplars[e], j->L, j->ex->kl[j->L - l], j->L - l,
                                &j->ex->stacks[e]) != 0)
            j->fail = 1;
    }
}

/* The window of a level of spacing sp: 3 x 3 from a spacing of 16 cells.
 * The coarse levels' neighbourhoods then reach as far as 5 x 5 at half the
 * spacing, so a fifth level fits the exemplar's safety margin and large
 * structures (a plain, a mountain front) come from coarser levels.
 * Measured on nine DEMs x three seeds: slope W1 2.2 degrees on average,
 * 21 of 27 within 3, against 2.6 and 19 of 27 with 5 x 5 at every level
 * and at most four levels. */
#define COARSE_WINDOW(k, sp) ((sp) >= 16 && (k) > 3 ? 3 : (k))

/* Every level's nodata cells take the value of the nearest valid cell (once
 * the usable cells, appearance vectors and similarity sets are made, which
 * read valid cells only).  The output's bands are read up to a spacing and a
 * half past a usable coordinate; a read that fell on nodata would drop its
 * corner from the blend, which would jump where the read crossed the
 * nodata's edge: straight steps in outputs of exemplars with a nodata
 * frame.  Filled,
 * the band runs on continuously, as past the raster's edges (clamped). */
static ts_status pix_fill_nodata(ts_ctx *ctx, ts_pixel_exemplars *ex)
{
    int i, l;
    for (i = 0; i < ex->n_given; i++) {
        pix_stack *s = &ex->stacks[i];
        size_t n = (size_t)s->width * (size_t)s->height, c, holes = 0;
        unsigned char *m;
        float *dist;
        int32_t *nearest;
        for (c = 0; c < n; c++)
            holes += isnan(s->level[ex->levels][c]);
        if (!holes || holes == n)
            continue;
        m = ts__malloc_array(n, 1);
        dist = ts__malloc_array(n, sizeof *dist);
        nearest = ts__malloc_array(n, sizeof *nearest);
        if (!m || !dist || !nearest) {
            free(m);
            free(dist);
            free(nearest);
            return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the stacks");
        }
        for (c = 0; c < n; c++)
            m[c] = !isnan(s->level[ex->levels][c]);
        if (ts__distance_transform_nearest(ctx, m, s->width, s->height, dist, nearest) != TS_OK) {
            free(m);
            free(dist);
            free(nearest);
            return ctx->status;
        }
        for (l = 0; l <= ex->levels; l++)
            for (c = 0; c < n; c++)
                if (!m[c] && nearest[c] >= 0)
                    s->level[l][c] = s->level[l][nearest[c]];
        free(m);
        free(dist);
        free(nearest);
    }
    return TS_OK;
}

/* The candidates of each exemplar: `rotations` of them, or (-1) as many as keep
 * the exemplars' grain: without a preferred direction (coherence below
 * TS_PIXEL_ISOTROPIC) the quarter turns, with one the half turn alone, which
 * keeps every feature's direction (a mirror image keeps the mean direction
 * of an axis-aligned grain but turns each oblique feature the other way: a
 * fault's scarps then cross in chevrons).  vturn[v], vmirror[v]: variant v's
 * quarter turns and mirror.  Returns nv. */
static int pix_variants(int rotations, double grain, int vturn[8], int vmirror[8])
{
    int v, nv = rotations >= 0 ? (rotations ? rotations : 1) : grain < TS_PIXEL_ISOTROPIC ? 4 : 2;
    for (v = 0; v < 8; v++) {
        vturn[v] = v < nv ? (nv == 2 ? 2 * v : v % 4) : 0;
        vmirror[v] = v < nv && v >= 4;
    }
    return nv;
}

TS_API ts_status ts_pixel_prepare(ts_ctx *ctx, const ts_raster *exemplars, int n,
                                  const ts_pixel_params *params, ts_pixel_exemplars **out)
{
    ts_pixel_exemplars *ex;
    int i, L, k, nv, minside = 1 << 30;
    double grain;
    int vturn[8], vmirror[8];
    ts__clear(ctx);
    if (!out)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "no output given");
    *out = NULL;
    if (!exemplars || n < 1 || !params)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "no exemplars given");
    if (ts_params_validate(ctx, "pixel", params) != TS_OK)
        return ctx->status;
    if (!ts_pixel_rotations_valid(params->rotations))
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "rotations must be -1, 0, 2, 4 or 8, not %d",
                        params->rotations);
    for (i = 0; i < n; i++)
        if (!exemplars[i].data)
            return ts__fail_input(ctx, TS_ERR_ARG, i, "pixel", "exemplar %d: no data", i + 1);
    grain = ts__pix_grain(exemplars, n);
    nv = pix_variants(params->rotations, grain, vturn, vmirror);
    /* 0: chosen as Cruz et al. do, by the neighbourhoods' principal components */
    k = params->window ? params->window : ts__pix_choose_window(exemplars, n);
    if (k % 2 == 0)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "window must be odd, not %d", k);
    for (i = 0; i < n; i++) {
        if (exemplars[i].width < minside)
            minside = exemplars[i].width;
        if (exemplars[i].height < minside)
            minside = exemplars[i].height;
    }
    L = params->levels;
    if (L == 0) {
        /* as many as leave a coarsest neighbourhood half the smallest exemplar, at most 5:
         * with more, the coarsest level's safety margin leaves only the exemplar's centre
         * to start from (measured: with 6, slope W1 3.6 degrees on average over nine DEMs,
         * against 2.2 with 5) */
        L = 1;
        while (L < 5 && (1 << (L + 1)) * (COARSE_WINDOW(k, 1 << (L + 1)) - 1) + 1 <= minside / 2)
            L++;
    }
    ex = calloc(1, sizeof *ex);
    if (!ex || !(ex->stacks = calloc((size_t)n, sizeof *ex->stacks))) {
        free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory");
    }
    ex->n = n * nv;
    ex->n_given = n;
    ex->nv = nv;
    ex->grain = grain;
    memcpy(ex->vturn, vturn, sizeof vturn);
    memcpy(ex->vmirror, vmirror, sizeof vmirror);
    for (i = 0; i <= L; i++)
        ex->kl[i] = COARSE_WINDOW(k, 1 << (L - i));
    if (!(ex->turn = calloc((size_t)n * (size_t)nv, sizeof *ex->turn))) {
        free(ex->stacks);
        free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory");
    }
    for (i = 0; i < n * nv; i++) {  /* the inverse of turned_target (coordinate_synthesis.c) */
        static const int m[4][6] = {/* ox, oy (in units of w - 1, h - 1), mxu, mxv, myu, myv */
                                    {0, 0, 1, 0, 0, 1},
                                    {1, 0, 0, -1, 1, 0},
                                    {1, 1, -1, 0, 0, -1},
                                    {0, 1, 0, 1, -1, 0}};
        int w = exemplars[i / nv].width, h = exemplars[i / nv].height;
        int q = vturn[i % nv];
        pix_turn *t = &ex->turn[i];
        t->w = q % 2 ? h : w;
        t->h = q % 2 ? w : h;
        t->sw = w;
        t->ox = m[q][0] * (w - 1);
        t->oy = m[q][1] * (h - 1);
        t->mxu = m[q][2];
        t->mxv = m[q][3];
        t->myu = m[q][4];
        t->myv = m[q][5];
        if (vmirror[i % nv]) { /* mirrored left-right first */
            t->ox = w - 1 - t->ox;
            t->mxu = -t->mxu;
            t->mxv = -t->mxv;
        }
    }
    ex->levels = L;
    ex->window = k;
    /* every exemplar's every level in parallel (the coarsest blur is the longest) */
    {
        stack_job sj = {exemplars, ex, L, k, 0};
        for (i = 0; i < n; i++)
            if (ts__pix_stack_alloc(&exemplars[i], L, &ex->stacks[i]) != 0)
                sj.fail = 1;
        if (!sj.fail)
            ts__parallel_for(ctx, (size_t)n * (size_t)(L + 1), stack_levels, &sj);
        for (i = 0; i < n && !sj.fail; i++)
            if (ts__pix_stack_finish(&ex->stacks[i]) != 0)
                sj.fail = 1;
        if (sj.fail) {
            ts_pixel_exemplars_free(ex);
            return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the stacks");
        }
    }
    for (i = 0; i < n; i++) {
        int l;
        for (l = 0; l <= L; l++)
            if (ex->stacks[i].n_usable[l] == 0) {
                ts_pixel_exemplars_free(ex);
                return ts__fail_input(ctx, TS_ERR_SIZE, i, "pixel",
                                      "exemplar %d (%d x %d cells) has no valid %d x %d "
                                      "neighbourhood at spacing %d: fewer levels or a larger "
                                      "exemplar",
                                      i + 1, exemplars[i].width, exemplars[i].height, k, k,
                                      1 << (L - l));
            }
    }
    ex->rough = params->roughness_weight > 0 ? (float)sqrt(params->roughness_weight) : 0.0f;
    if (ts__pix_appearance_build(ctx, ex, params->pca_energy) != 0) {
        ts_pixel_exemplars_free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the appearance space");
    }
    if (!(ex->cell_base = calloc((size_t)n, sizeof *ex->cell_base))) {
        ts_pixel_exemplars_free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory");
    }
    switch (ts__pix_similarity_build(ctx, ex, params->coherence, PIX_NOTICE_SECONDS)) {
    case 0:
        break;
    case -3:
        ts_pixel_exemplars_free(ex);
        return ctx->status;
    case -2:
        ts_pixel_exemplars_free(ex);
        return ts__fail(ctx, TS_ERR_SIZE, "pixel",
                        "the exemplars hold 2^31 cells or more: too many for similarity sets "
                        "(coherence 1 or smaller exemplars)");
    default:
        ts_pixel_exemplars_free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for the similarity sets");
    }
    if (pix_fill_nodata(ctx, ex) != TS_OK) {
        ts_pixel_exemplars_free(ex);
        return ctx->status;
    }
    if (ts__pix_relief_build(ex) != 0) {
        ts_pixel_exemplars_free(ex);
        return ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory");
    }
    if (ts__progress(ctx, 1.0, "stacks") != TS_OK) {
        ts_pixel_exemplars_free(ex);
        return ctx->status;
    }
    *out = ex;
    return TS_OK;
}

TS_API void ts_pixel_exemplars_free(ts_pixel_exemplars *ex)
{
    int i;
    if (!ex)
        return;
    for (i = 0; i < ex->n_given; i++)
        ts__pix_stack_free(&ex->stacks[i], ex->levels);
    for (i = 0; i < 12; i++)
        free(ex->basis[i]);
    free(ex->stacks);
    free(ex->turn);
    free(ex->cell_base);
    ts__pix_relief_free(&ex->relief);
    free(ex);
}

TS_API int ts_pixel_levels(const ts_pixel_exemplars *ex)
{
    return ex ? ex->levels : 0;
}

TS_API int ts_pixel_window(const ts_pixel_exemplars *ex)
{
    return ex ? ex->window : 0;
}

TS_API int ts_pixel_variants(const ts_pixel_exemplars *ex)
{
    return ex ? ex->nv : 0;
}

TS_API double ts_pixel_grain(const ts_pixel_exemplars *ex)
{
    return ex ? ex->grain : 0.0;
}

TS_API int ts_pixel_rotations_valid(int rotations)
{
    return rotations == -1 || rotations == 0 || rotations == 2 || rotations == 4 || rotations == 8;
}

double ts__pix_grain(const ts_raster *exemplars, int n)
{
    double jxx = 0.0, jyy = 0.0, jxy = 0.0;
    int i, x, y;
    for (i = 0; i < n; i++) {
        const ts_raster *r = &exemplars[i];
        for (y = 1; y + 1 < r->height; y++)
            for (x = 1; x + 1 < r->width; x++) {
                double gx = 0.5 * ((double)TS_PIX(r, x + 1, y) - TS_PIX(r, x - 1, y));
                double gy = 0.5 * ((double)TS_PIX(r, x, y + 1) - TS_PIX(r, x, y - 1));
                if (!isfinite(gx) || !isfinite(gy))
                    continue; /* a neighbour is nodata */
                jxx += gx * gx;
                jyy += gy * gy;
                jxy += gx * gy;
            }
    }
    return jxx + jyy > 0.0 ? sqrt((jxx - jyy) * (jxx - jyy) + 4.0 * jxy * jxy) / (jxx + jyy) : 0.0;
}
