/*
 * amplify.c - terrain amplification (Argudo et al. 2017, sections 3.2 and
 * 5): the coarse DEM is cut into patches overlapping by half, each patch is
 * described as the atoms are (dictionary.c), matched (atom_matching.c) and
 * replaced by its atom's high-resolution counterpart,
 *   P~ = (P_h . D_h,k) P_s D~_h,k + P_a,
 * and the patches are blended with a falloff from their centres.  The
 * coefficient P_h . D_h,k is never negative (an atom is never inverted; a
 * patch whose best atom points the other way stays flat).
 *
 * Our addition, named as such: back-projection.  The paper's
 * reconstruction keeps only the part of a patch its atom explains; the rest
 * (the input minus the area-averaged output) is upsampled bilinearly and
 * added back, a few passes, so the output averages back to the input.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "amplify.h"

/* Most the matched atom's relief is scaled up (see recon_rows). */
#ifndef AMP_MAX_GAIN
#define AMP_MAX_GAIN 2.0
#endif

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* Patch origins along an axis of n cells: every step, and the last one
 * flush with the end so every cell is covered. */
static int patch_origins(int n, int p, int step, int *pos)
{
    int k = 0, x;
    for (x = 0; x + p < n; x += step)
        pos[k++] = x;
    pos[k++] = n - p;
    return k;
}

typedef struct recon_job {
    const ts_raster *coarse;
    const ts_dictionary *dict;
    const int *xs, *ys, *best;
    int nx, ny, F, P;
    const double *pa, *pnorm;
    const float *coef;
    const float *window; /* P falloff weights */
    ts_raster *out;
    int fail;
} recon_job;

static void recon_rows(void *arg, size_t begin, size_t end)
{
    recon_job *r = arg;
    int Wf = r->out->width, F = r->F, P = r->P, cx, X;
    double *acc = malloc((size_t)Wf * sizeof *acc), *wsum = malloc((size_t)Wf * sizeof *wsum);
    size_t Y;
    if (!acc || !wsum) {
        free(acc);
        free(wsum);
        r->fail = 1;
        return;
    }
    for (Y = begin; Y < end; Y++) {
        int ry;
        memset(acc, 0, (size_t)Wf * sizeof *acc);
        memset(wsum, 0, (size_t)Wf * sizeof *wsum);
        for (ry = 0; ry < r->ny; ry++) {
            int y0 = r->ys[ry] * F, ty = (int)Y - y0;
            if (ty < 0 || ty >= P)
                continue;
            for (cx = 0; cx < r->nx; cx++) {
                size_t pi = (size_t)ry * (size_t)r->nx + (size_t)cx;
                int k = r->best[pi], x0 = r->xs[cx] * F, tx;
                double c = r->coef[pi] > 0 ? r->coef[pi] : 0.0, scale, wy = r->window[ty];
                const float *hh;
                if (k < 0)
                    continue;
                scale = c * r->pnorm[pi];
                /* an atom far gentler than its patch would have its detail blown up
                 * into spikes: at most AMP_MAX_GAIN times its own relief */
                if (scale > AMP_MAX_GAIN * r->dict->s[k] * r->dict->patch)
                    scale = AMP_MAX_GAIN * r->dict->s[k] * r->dict->patch;
                hh = r->dict->hh + (size_t)k * (size_t)r->dict->hd + (size_t)ty * (size_t)P;
                for (tx = 0; tx < P; tx++) {
                    double w = wy * r->window[tx];
                    acc[x0 + tx] += w * (r->pa[pi] + scale * hh[tx]);
                    wsum[x0 + tx] += w;
                }
            }
        }
        for (X = 0; X < Wf; X++) {
            float parent = TS_PIX(r->coarse, X / F, (int)Y / F);
            TS_PIX(r->out, X, (int)Y) =
                isnan(parent) || !(wsum[X] > 0) ? NAN : (float)(acc[X] / wsum[X]);
        }
    }
    free(acc);
    free(wsum);
}

/* Keys' cubic convolution weights (a = -0.5) of the four taps around t in [0, 1). */
static void cubic_weights(double t, double w[4])
{
    const double a = -0.5;
    double t2 = t * t, t3 = t2 * t;
    w[0] = a * (t3 - 2 * t2 + t);
    w[1] = (a + 2) * t3 - (a + 3) * t2 + 1;
    w[2] = -(a + 2) * t3 + (2 * a + 3) * t2 - a * t;
    w[3] = -a * (t3 - t2);
}

static int clampi(int v, int lo, int hi)
{
    return v < lo ? lo : v > hi ? hi : v;
}

typedef struct bp_job {
    const ts_raster *res; /* the residual on the coarse grid */
    ts_raster *out;
    int F;
} bp_job;

static void bp_rows(void *arg, size_t begin, size_t end)
{
    bp_job *b = arg;
    int W = b->res->width, H = b->res->height, F = b->F, X, i, j;
    size_t Y;
    for (Y = begin; Y < end; Y++) {
        double v = ((double)Y + 0.5) / F - 0.5, wy[4];
        int y0 = (int)floor(v), yy[4];
        cubic_weights(v - y0, wy);
        for (j = 0; j < 4; j++)
            yy[j] = clampi(y0 - 1 + j, 0, H - 1);
        for (X = 0; X < b->out->width; X++) {
            double u = ((double)X + 0.5) / F - 0.5, wx[4], r = 0;
            int x0 = (int)floor(u), xx[4];
            float *o = &TS_PIX(b->out, X, (int)Y);
            if (isnan(*o))
                continue;
            cubic_weights(u - x0, wx);
            for (i = 0; i < 4; i++)
                xx[i] = clampi(x0 - 1 + i, 0, W - 1);
            for (j = 0; j < 4; j++) {
                double row = 0;
                for (i = 0; i < 4; i++)
                    row += wx[i] * TS_PIX(b->res, xx[i], yy[j]);
                r += wy[j] * row;
            }
            *o += (float)r;
        }
    }
}

/* out += the bicubic upsampling of (coarse - area average of out): smooth
 * (its gradient has no jumps at the coarse cells' edges, which a bilinear
 * one would draw as facets in a hillshade). */
static ts_status back_project(ts_ctx *ctx, const ts_raster *coarse, int F, ts_raster *out,
                              ts_raster *avg)
{
    int W = coarse->width, H = coarse->height, x, y;
    bp_job b;
    ts_status st = ts_area_average(ctx, out, F, avg);
    if (st != TS_OK)
        return st;
    for (y = 0; y < H; y++)
        for (x = 0; x < W; x++) {
            float c = TS_PIX(coarse, x, y), a = TS_PIX(avg, x, y);
            TS_PIX(avg, x, y) = isnan(c) || isnan(a) ? 0.0f : c - a; /* the residual */
        }
    b.res = avg;
    b.out = out;
    b.F = F;
    ts__parallel_for(ctx, (size_t)out->height, bp_rows, &b);
    return TS_OK;
}

TS_API ts_status ts_amplify(ts_ctx *ctx, const ts_raster *coarse, const ts_dictionary *dict,
                            const ts_amplify_params *params, ts_raster *out, ts_amplify_info *info)
{
    int W, H, F, p, P, step, nx, ny, i, j, cx, cy, pass;
    int *xs = NULL, *ys = NULL, *best = NULL;
    float *ph = NULL, *pu = NULL, *coef = NULL, *score = NULL, *win = NULL, *window = NULL;
    float *lwin = NULL;
    double *pa = NULL, *ps = NULL, *pnorm = NULL, w[4], t0, t1;
    ts_raster drain = {0, 0, 0, NULL}, avg = {0, 0, 0, NULL};
    size_t np, pi;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (info)
        memset(info, 0, sizeof *info);
    if (!coarse || !coarse->data || !dict || !params || !out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "missing input, dictionary or output");
    if (ts_params_validate(ctx, "amplify", params) != TS_OK)
        return ctx->status;
    F = params->factor;
    p = params->patch;
    P = p * F;
    if (dict->factor != F || dict->patch != p)
        return ts__fail(ctx, TS_ERR_ARG, "amplify",
                        "the dictionary was built for factor %d and patch %d, not %d and %d",
                        dict->factor, dict->patch, F, p);
    W = coarse->width;
    H = coarse->height;
    if (out->width != W * F || out->height != H * F)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "the output must be %d x %d cells", W * F,
                        H * F);
    if (W < p || H < p)
        return ts__fail(ctx, TS_ERR_SIZE, "amplify",
                        "the input (%d x %d cells) is smaller than a patch (%d cells)", W, H, p);
    step = p / 2 > 0 ? p / 2 : 1;
    xs = malloc((size_t)(W / step + 2) * sizeof *xs);
    ys = malloc((size_t)(H / step + 2) * sizeof *ys);
    if (!xs || !ys) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    nx = patch_origins(W, p, step, xs);
    ny = patch_origins(H, p, step, ys);
    np = (size_t)nx * (size_t)ny;
    ph = ts__malloc_array(np * (size_t)p * p, sizeof *ph);
    pu = ts__malloc_array(np * (size_t)p * p, sizeof *pu);
    pa = ts__malloc_array(np, sizeof *pa);
    ps = ts__malloc_array(np, sizeof *ps);
    pnorm = ts__malloc_array(np, sizeof *pnorm);
    best = ts__malloc_array(np, sizeof *best);
    coef = ts__malloc_array(np, sizeof *coef);
    score = ts__malloc_array(np, sizeof *score);
    win = malloc((size_t)p * p * sizeof *win);
    lwin = malloc((size_t)p * p * sizeof *lwin);
    window = malloc((size_t)P * sizeof *window);
    if (!ph || !pu || !pa || !ps || !pnorm || !best || !coef || !score || !win || !lwin ||
        !window) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for %zu patches", np);
        goto done;
    }
    if (ts_raster_alloc(ctx, W, H, &drain) != TS_OK ||
        ts_drainage_area(ctx, coarse, &drain) != TS_OK) {
        st = ctx->status;
        goto done;
    }
    /* the patches described as the atoms are (nodata cells take the patch's mean) */
    t0 = now_s();
    for (cy = 0; cy < ny; cy++)
        for (cx = 0; cx < nx; cx++) {
            double m = 0, mu = 0, rms, um, urms;
            int nv = 0;
            pi = (size_t)cy * (size_t)nx + (size_t)cx;
            for (j = 0; j < p; j++)
                for (i = 0; i < p; i++) {
                    float v = TS_PIX(coarse, xs[cx] + i, ys[cy] + j);
                    if (!isnan(v)) {
                        m += v;
                        mu += log1p(TS_PIX(&drain, xs[cx] + i, ys[cy] + j));
                        nv++;
                    }
                }
            if (!nv) {
                pa[pi] = NAN;
                ps[pi] = pnorm[pi] = 0;
                memset(ph + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *ph);
                memset(pu + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *pu);
                continue;
            }
            m /= nv;
            mu /= nv;
            for (j = 0; j < p; j++)
                for (i = 0; i < p; i++) {
                    float v = TS_PIX(coarse, xs[cx] + i, ys[cy] + j);
                    win[j * p + i] = isnan(v) ? (float)m : v;
                    lwin[j * p + i] =
                        isnan(v) ? (float)mu : (float)log1p(TS_PIX(&drain, xs[cx] + i, ys[cy] + j));
                }
            ts__amp_normalise(win, p * p, ph + pi * (size_t)p * p, &pa[pi], &rms);
            ts__amp_normalise(lwin, p * p, pu + pi * (size_t)p * p, &um, &urms);
            ps[pi] = rms;
            pnorm[pi] = rms * p; /* |P_e - P_a| */
        }
    if ((st = ts__progress(ctx, 0.05, "matching")) != TS_OK)
        goto done;
    ts__amp_weights(params, w);
    ts__match_atoms(ctx, dict, ph, pu, pa, ps, np, w, best, score, coef);
    if ((st = ts__check_cancel(ctx)) != TS_OK)
        goto done;
    t1 = now_s();
    if ((st = ts__progress(ctx, 0.6, "synthesis")) != TS_OK)
        goto done;
    /* the falloff: sin^2 windows overlapping by half sum to one */
    for (i = 0; i < P; i++) {
        double sv = sin(3.14159265358979323846 * (i + 0.5) / P);
        window[i] = (float)(sv * sv);
    }
    {
        recon_job r = {coarse, dict, xs, ys, best, nx, ny, F, P, pa, pnorm, coef, window, out, 0};
        ts__parallel_for(ctx, (size_t)out->height, recon_rows, &r);
        if (r.fail) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
            goto done;
        }
    }
    if (params->refine > 0) {
        if (ts_raster_alloc(ctx, W, H, &avg) != TS_OK) {
            st = ctx->status;
            goto done;
        }
        for (pass = 0; pass < params->refine; pass++) {
            if ((st = back_project(ctx, coarse, F, out, &avg)) != TS_OK)
                goto done;
            if ((st = ts__progress(ctx, 0.9 + 0.1 * (pass + 1) / params->refine,
                                   "back-projection")) != TS_OK)
                goto done;
        }
    }
    if (info) {
        double sum = 0;
        size_t used = 0;
        info->n_patches = np;
        info->n_atoms = dict->n;
        info->seconds_match = t1 - t0;
        info->seconds_synthesis = now_s() - t1;
        for (pi = 0; pi < np; pi++)
            if (best[pi] >= 0) {
                sum += score[pi];
                used++;
                if (coef[pi] < 0)
                    info->n_inverted++;
            }
        info->mean_score = used ? sum / used : 0;
    }
    st = ts__progress(ctx, 1.0, "done");
done:
    free(xs);
    free(ys);
    free(best);
    free(ph);
    free(pu);
    free(pa);
    free(ps);
    free(pnorm);
    free(coef);
    free(score);
    free(win);
    free(lwin);
    free(window);
    ts_raster_free(&drain);
    ts_raster_free(&avg);
    return st;
}
