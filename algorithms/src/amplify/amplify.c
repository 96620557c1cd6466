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
 * (the input minus the area-averaged output) is upsampled (cubic convolution) and
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

/* A rectangle of coarse cells [x0, x1) x [y0, y1). */
typedef struct amp_rect {
    int x0, y0, x1, y1;
} amp_rect;

static amp_rect rect_grow(amp_rect r, int by, int W, int H)
{
    amp_rect g = {r.x0 - by, r.y0 - by, r.x1 + by, r.y1 + by};
    if (g.x0 < 0)
        g.x0 = 0;
    if (g.y0 < 0)
        g.y0 = 0;
    if (g.x1 > W)
        g.x1 = W;
    if (g.y1 > H)
        g.y1 = H;
    return g;
}

/* Everything the passes share.  The working raster `buf` holds the fine
 * cells of the coarse rectangle `base`, from fine cell (bx, by). */
typedef struct amp_work {
    const ts_raster *coarse;
    const ts_dictionary *dict;
    int F, p, P, W, H;
    const int *xs, *ys; /* global patch origins */
    int c0, c1, r0, r1; /* the patch columns and rows in use */
    const int *best;
    const double *pa, *pnorm;
    const float *coef;
    const float *window; /* P falloff weights */
    ts_raster *buf;
    int bx, by;
    /* back-projection */
    const ts_raster *res; /* the residual on the coarse rectangle rr */
    amp_rect rr;
    int ux0, uy0, ux1, uy1; /* the fine cells it updates (global) */
    /* the atoms' other layers, on the window */
    const ts_amplify_layers *lay;
    int X0, Y0, ww, wh;
    int fail;
} amp_work;

static void recon_rows(void *arg, size_t begin, size_t end)
{
    amp_work *r = arg;
    int Wb = r->buf->width, F = r->F, P = r->P, ncols = r->c1 - r->c0, cx, X;
    double *acc = malloc((size_t)Wb * sizeof *acc), *wsum = malloc((size_t)Wb * sizeof *wsum);
    size_t Yb;
    if (!acc || !wsum) {
        free(acc);
        free(wsum);
        r->fail = 1;
        return;
    }
    for (Yb = begin; Yb < end; Yb++) {
        int Y = r->by + (int)Yb, ry;
        memset(acc, 0, (size_t)Wb * sizeof *acc);
        memset(wsum, 0, (size_t)Wb * sizeof *wsum);
        /* every patch over this row, in the same order whatever the window */
        for (ry = r->r0; ry < r->r1; ry++) {
            int ty = Y - r->ys[ry] * F;
            if (ty < 0 || ty >= P)
                continue;
            for (cx = r->c0; cx < r->c1; cx++) {
                size_t pi = (size_t)(ry - r->r0) * (size_t)ncols + (size_t)(cx - r->c0);
                int k = r->best[pi], x0 = r->xs[cx] * F, tx, t0, t1;
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
                t0 = r->bx - x0 > 0 ? r->bx - x0 : 0;
                t1 = r->bx + Wb - x0 < P ? r->bx + Wb - x0 : P;
                for (tx = t0; tx < t1; tx++) {
                    double w = wy * r->window[tx];
                    acc[x0 + tx - r->bx] += w * (r->pa[pi] + scale * hh[tx]);
                    wsum[x0 + tx - r->bx] += w;
                }
            }
        }
        for (X = 0; X < Wb; X++) {
            float parent = TS_PIX(r->coarse, (r->bx + X) / F, Y / F);
            TS_PIX(r->buf, X, (int)Yb) =
                isnan(parent) || !(wsum[X] > 0) ? NAN : (float)(acc[X] / wsum[X]);
        }
    }
    free(acc);
    free(wsum);
}

/* The atoms' extra layers and classes on the window's rows: layers blended
 * with the same falloff as the elevation (cells where an atom has no value
 * left out), classes those of the atom that weighs most at the cell (ties:
 * the first in patch order). */
static void layer_rows(void *arg, size_t begin, size_t end)
{
    amp_work *r = arg;
    const ts_dictionary *D = r->dict;
    int L = r->lay->layers ? D->n_layers : 0, Ww = r->ww, F = r->F, P = r->P, l, X;
    int want_c = r->lay->classes && D->hc, ncols = r->c1 - r->c0;
    double *acc = ts__malloc_array((size_t)(L + 1) * (size_t)Ww, 2 * sizeof *acc);
    double *wsum = acc ? acc + (size_t)(L + 1) * Ww : NULL, *wbest;
    unsigned char *cbest = malloc((size_t)Ww + 1);
    size_t k;
    if (!acc || !cbest) {
        free(acc);
        free(cbest);
        r->fail = 1;
        return;
    }
    wbest = acc + (size_t)L * Ww;
    for (k = begin; k < end; k++) {
        int Y = r->Y0 + (int)k, ry, cx;
        memset(acc, 0, (size_t)(L + 1) * (size_t)Ww * 2 * sizeof *acc);
        memset(cbest, 0, (size_t)Ww);
        for (ry = r->r0; ry < r->r1; ry++) {
            int ty = Y - r->ys[ry] * F;
            if (ty < 0 || ty >= P)
                continue;
            for (cx = r->c0; cx < r->c1; cx++) {
                size_t pi = (size_t)(ry - r->r0) * (size_t)ncols + (size_t)(cx - r->c0);
                int a = r->best[pi], x0 = r->xs[cx] * F, tx, t0, t1;
                double wy = r->window[ty];
                if (a < 0)
                    continue;
                t0 = r->X0 - x0 > 0 ? r->X0 - x0 : 0;
                t1 = r->X0 + Ww - x0 < P ? r->X0 + Ww - x0 : P;
                for (tx = t0; tx < t1; tx++) {
                    double w = wy * r->window[tx];
                    int o = x0 + tx - r->X0;
                    for (l = 0; l < L; l++) {
                        float v = D->ll[((size_t)a * L + l) * D->hd + (size_t)ty * P + tx];
                        if (!isnan(v)) {
                            acc[(size_t)l * Ww + o] += w * v;
                            wsum[(size_t)l * Ww + o] += w;
                        }
                    }
                    if (want_c && w > wbest[o]) {
                        wbest[o] = w;
                        cbest[o] = D->hc[(size_t)a * D->hd + (size_t)ty * P + tx];
                    }
                }
            }
        }
        for (X = 0; X < Ww; X++) {
            int nodata = isnan(TS_PIX(r->coarse, (r->X0 + X) / F, Y / F));
            for (l = 0; l < L; l++) {
                double ws = wsum[(size_t)l * Ww + X];
                TS_PIX(&r->lay->layers[l], X, (int)k) =
                    nodata || !(ws > 0) ? NAN : (float)(acc[(size_t)l * Ww + X] / ws);
            }
            if (r->lay->classes)
                TS_PIX(r->lay->classes, X, (int)k) = nodata ? 0.0f : (float)cbest[X];
        }
    }
    free(acc);
    free(cbest);
}

static void bp_rows(void *arg, size_t begin, size_t end)
{
    amp_work *b = arg;
    int F = b->F, X, i, j, rw = b->rr.x1 - b->rr.x0;
    double *col = malloc((size_t)rw * sizeof *col);
    size_t k;
    if (!col) {
        b->fail = 1;
        return;
    }
    for (k = begin; k < end; k++) {
        int Y = b->uy0 + (int)k, x;
        double v = ((double)Y + 0.5) / F - 0.5, wy[4];
        int y0 = (int)floor(v), yy[4];
        cubic_weights(v - y0, wy);
        for (j = 0; j < 4; j++)
            yy[j] = clampi(y0 - 1 + j, 0, b->H - 1) - b->rr.y0;
        /* separable: the residual interpolated down each coarse column, then across */
        for (x = 0; x < rw; x++) {
            double c = 0;
            for (j = 0; j < 4; j++)
                c += wy[j] * TS_PIX(b->res, x, yy[j]);
            col[x] = c;
        }
        for (X = b->ux0; X < b->ux1; X++) {
            double u = ((double)X + 0.5) / F - 0.5, wx[4], r = 0;
            int x0 = (int)floor(u);
            float *o = &TS_PIX(b->buf, X - b->bx, Y - b->by);
            if (isnan(*o))
                continue;
            cubic_weights(u - x0, wx);
            for (i = 0; i < 4; i++)
                r += wx[i] * col[clampi(x0 - 1 + i, 0, b->W - 1) - b->rr.x0];
            *o += (float)r;
        }
    }
    free(col);
}

/* One back-projection pass: the residual (input minus the area average of
 * buf) on the coarse rectangle rr, its bicubic upsampling added to the fine
 * cells [ux0, ux1) x [uy0, uy1) (global).  Smooth: a bilinear one would draw
 * the coarse cells' edges as facets in a hillshade. */
static void back_project(ts_ctx *ctx, amp_work *w, amp_rect rr, ts_raster *res)
{
    int x, y, i, j, F = w->F;
    res->width = rr.x1 - rr.x0;
    res->height = rr.y1 - rr.y0;
    res->stride = res->width;
    for (y = rr.y0; y < rr.y1; y++)
        for (x = rr.x0; x < rr.x1; x++) {
            double sum = 0.0;
            int bad = 0;
            float c = TS_PIX(w->coarse, x, y);
            for (j = 0; j < F && !bad; j++)
                for (i = 0; i < F; i++) {
                    float v = TS_PIX(w->buf, x * F + i - w->bx, y * F + j - w->by);
                    if (isnan(v)) {
                        bad = 1;
                        break;
                    }
                    sum += v;
                }
            TS_PIX(res, x - rr.x0, y - rr.y0) =
                isnan(c) || bad ? 0.0f : c - (float)(sum / ((double)F * F));
        }
    w->res = res;
    w->rr = rr;
    ts__parallel_for(ctx, (size_t)(w->uy1 - w->uy0), bp_rows, w);
}

/* The fine cells [X0, X0 + out->width) x [Y0, Y0 + out->height) of the
 * amplified DEM: the patches over them and the coarse margin every
 * back-projection pass needs (two cells per pass, the cubic's reach) are
 * computed, nothing else.  Each cell is computed by the same operations in
 * the same order whatever the window, so a window is byte for byte the same
 * window of the whole. */
/* Biome b's share of coarse cell (x, y): its weight over the sum of all
 * (equal shares where every weight is 0). */
static double biome_share(const ts_raster *wts, int nd, int b, int x, int y)
{
    double sum = 0;
    int k;
    for (k = 0; k < nd; k++)
        sum += TS_PIX(&wts[k], x, y);
    return sum > 0 ? TS_PIX(&wts[b], x, y) / sum : 1.0 / nd;
}

/* Biome b's share at fine cell (X, Y): the coarse shares interpolated
 * bilinearly between cell centres. */
static double biome_weight(const ts_raster *wts, int nd, int b, int W, int H, int F, int X, int Y)
{
    double u = ((double)X + 0.5) / F - 0.5, v = ((double)Y + 0.5) / F - 0.5;
    int x0 = (int)floor(u), y0 = (int)floor(v);
    double fx = u - x0, fy = v - y0;
    int xa = clampi(x0, 0, W - 1), xb = clampi(x0 + 1, 0, W - 1);
    int ya = clampi(y0, 0, H - 1), yb = clampi(y0 + 1, 0, H - 1);
    return (1 - fy) *
               ((1 - fx) * biome_share(wts, nd, b, xa, ya) + fx * biome_share(wts, nd, b, xb, ya)) +
           fy * ((1 - fx) * biome_share(wts, nd, b, xa, yb) + fx * biome_share(wts, nd, b, xb, yb));
}

/* Blending the biomes' reconstructions (section 5.5). */
typedef struct amp_blend {
    const ts_raster *coarse, *wts;
    ts_raster *bufs; /* nd reconstructions, on the working raster */
    ts_raster *buf;
    int nd, F, bx, by;
} amp_blend;

static void blend_rows(void *arg, size_t begin, size_t end)
{
    amp_blend *bl = arg;
    int W = bl->coarse->width, H = bl->coarse->height, X, b;
    size_t k;
    for (k = begin; k < end; k++)
        for (X = 0; X < bl->buf->width; X++) {
            int gx = bl->bx + X, gy = bl->by + (int)k;
            double acc = 0, ws = 0, any = 0;
            int n = 0;
            for (b = 0; b < bl->nd; b++) {
                float v = TS_PIX(&bl->bufs[b], X, (int)k);
                double a;
                if (isnan(v))
                    continue;
                a = biome_weight(bl->wts, bl->nd, b, W, H, bl->F, gx, gy);
                acc += a * v;
                ws += a;
                any += v;
                n++;
            }
            TS_PIX(bl->buf, X, (int)k) = !n ? NAN : ws > 0 ? (float)(acc / ws) : (float)(any / n);
        }
}

static ts_status amp_window(ts_ctx *ctx, const ts_raster *coarse, const ts_amplify_guide *guide,
                            const ts_dictionary *const *dicts, const ts_raster *wts, int nd,
                            const ts_amplify_params *params, int X0, int Y0, ts_raster *out,
                            const ts_amplify_layers *lay, ts_amplify_info *info)
{
    const ts_dictionary *dict = dicts[0];
    const ts_raster *drain = guide->drainage, *irr = guide->irradiance, *cls = guide->classes;
    ts_raster *bufs = NULL;
    double *pab = NULL;
    int b;
    int K = dict->n_classes;
    int use_l = params->w_l > 0 && irr && dict->dl;
    int use_c = params->w_c > 0 && cls && K > 0 && nd == 1;
    float *pl = NULL, *pc = NULL, *px = NULL;
    amp_patches pt;
    int W = coarse->width, H = coarse->height, F = params->factor, p = params->patch;
    int P = p * F, step = p / 2 > 0 ? p / 2 : 1, nx, ny, i, j, cx, cy, pass, R = params->refine;
    int *xs = NULL, *ys = NULL, *best = NULL, c0, c1, r0, r1;
    float *ph = NULL, *pu = NULL, *coef = NULL, *score = NULL, *win = NULL, *window = NULL;
    float *lwin = NULL, *resbuf = NULL;
    double *pa = NULL, *ps = NULL, *pnorm = NULL, w[AMP_NW], t0, t1;
    ts_raster buf = {0, 0, 0, NULL}, res;
    amp_rect foot, reg[12], base;
    size_t np, pi;
    int whole, ncols;
    ts_status st = TS_OK;
    amp_work wk;
    memset(&wk, 0, sizeof wk);
    /* the coarse cells under the window, and what each pass reads */
    foot.x0 = X0 / F;
    foot.y0 = Y0 / F;
    foot.x1 = (X0 + out->width + F - 1) / F;
    foot.y1 = (Y0 + out->height + F - 1) / F;
    reg[R + 1] = foot;
    for (pass = R; pass >= 1; pass--)
        reg[pass] = rect_grow(reg[pass + 1], 2, W, H);
    base = R > 0 ? reg[1] : foot;
    whole = X0 == 0 && Y0 == 0 && out->width == W * F && out->height == H * F;
    /* the patches over the base rectangle (global lattice) */
    xs = malloc((size_t)(W / step + 2) * sizeof *xs);
    ys = malloc((size_t)(H / step + 2) * sizeof *ys);
    if (!xs || !ys) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    nx = patch_origins(W, p, step, xs);
    ny = patch_origins(H, p, step, ys);
    for (c0 = 0; c0 < nx && xs[c0] + p <= base.x0; c0++)
        ;
    for (c1 = c0; c1 < nx && xs[c1] < base.x1; c1++)
        ;
    for (r0 = 0; r0 < ny && ys[r0] + p <= base.y0; r0++)
        ;
    for (r1 = r0; r1 < ny && ys[r1] < base.y1; r1++)
        ;
    ncols = c1 - c0;
    np = (size_t)ncols * (size_t)(r1 - r0);
    ph = ts__malloc_array(np * (size_t)p * p, sizeof *ph);
    pu = ts__malloc_array(np * (size_t)p * p, sizeof *pu);
    pa = ts__malloc_array(np, sizeof *pa);
    ps = ts__malloc_array(np, sizeof *ps);
    pnorm = ts__malloc_array(np, sizeof *pnorm);
    best = ts__malloc_array(np * (size_t)nd, sizeof *best);
    coef = ts__malloc_array(np * (size_t)nd, sizeof *coef);
    score = ts__malloc_array(np * (size_t)nd, sizeof *score);
    if (nd > 1) {
        pab = ts__malloc_array(np, sizeof *pab);
        bufs = calloc((size_t)nd, sizeof *bufs);
    }
    win = malloc((size_t)p * p * sizeof *win);
    lwin = malloc((size_t)p * p * sizeof *lwin);
    window = malloc((size_t)P * sizeof *window);
    if (use_l)
        pl = ts__malloc_array(np * (size_t)p * p, sizeof *pl);
    if (use_c)
        pc = ts__malloc_array(np * (size_t)K, sizeof *pc);
    if (params->w_x > 0)
        px = ts__malloc_array(np * (size_t)p * p, sizeof *px);
    resbuf =
        ts__malloc_array((size_t)(base.x1 - base.x0) * (size_t)(base.y1 - base.y0), sizeof *resbuf);
    if (!ph || !pu || !pa || !ps || !pnorm || !best || !coef || !score || !win || !lwin ||
        !window || !resbuf || (use_l && !pl) || (use_c && !pc) || (params->w_x > 0 && !px) ||
        (nd > 1 && (!pab || !bufs))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for %zu patches", np);
        goto done;
    }
    /* the patches described as the atoms are (nodata cells take the patch's mean) */
    t0 = now_s();
    for (cy = r0; cy < r1; cy++)
        for (cx = c0; cx < c1; cx++) {
            double m = 0, mu = 0, rms, um, urms;
            int nv = 0;
            pi = (size_t)(cy - r0) * (size_t)ncols + (size_t)(cx - c0);
            for (j = 0; j < p; j++)
                for (i = 0; i < p; i++) {
                    float v = TS_PIX(coarse, xs[cx] + i, ys[cy] + j);
                    if (!isnan(v)) {
                        m += v;
                        mu += log1p(TS_PIX(drain, xs[cx] + i, ys[cy] + j));
                        nv++;
                    }
                }
            if (pc) { /* the wanted classes' shares, scaled to unit length (0: any) */
                float *c = pc + pi * (size_t)K;
                double norm = 0;
                memset(c, 0, (size_t)K * sizeof *c);
                for (j = 0; j < p; j++)
                    for (i = 0; i < p; i++) {
                        int code = ts__class_code(TS_PIX(cls, xs[cx] + i, ys[cy] + j));
                        if (code > 0 && code <= K)
                            c[code - 1] += 1.0f;
                    }
                for (i = 0; i < K; i++)
                    norm += (double)c[i] * c[i];
                for (i = 0; i < K && norm > 0; i++)
                    c[i] = (float)(c[i] / sqrt(norm));
            }
            if (!nv) {
                pa[pi] = NAN;
                ps[pi] = pnorm[pi] = 0;
                memset(ph + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *ph);
                memset(pu + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *pu);
                if (pl)
                    memset(pl + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *pl);
                if (px)
                    memset(px + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *px);
                continue;
            }
            m /= nv;
            mu /= nv;
            for (j = 0; j < p; j++)
                for (i = 0; i < p; i++) {
                    float v = TS_PIX(coarse, xs[cx] + i, ys[cy] + j);
                    win[j * p + i] = isnan(v) ? (float)m : v;
                    lwin[j * p + i] =
                        isnan(v) ? (float)mu : (float)log1p(TS_PIX(drain, xs[cx] + i, ys[cy] + j));
                }
            ts__amp_normalise(win, p * p, ph + pi * (size_t)p * p, &pa[pi], &rms);
            ts__amp_normalise(lwin, p * p, pu + pi * (size_t)p * p, &um, &urms);
            if (px)
                ts__amp_context(coarse, xs[cx], ys[cy], p, px + pi * (size_t)p * p);
            if (pl) { /* the irradiance, described as the drainage is */
                double lm = 0;
                int nl = 0;
                for (j = 0; j < p; j++)
                    for (i = 0; i < p; i++) {
                        float v = TS_PIX(irr, xs[cx] + i, ys[cy] + j);
                        if (!isnan(v)) {
                            lm += v;
                            nl++;
                        }
                    }
                lm = nl ? lm / nl : 0.0;
                for (j = 0; j < p; j++)
                    for (i = 0; i < p; i++) {
                        float v = TS_PIX(irr, xs[cx] + i, ys[cy] + j);
                        lwin[j * p + i] = isnan(v) ? (float)lm : v;
                    }
                ts__amp_normalise(lwin, p * p, pl + pi * (size_t)p * p, &um, &urms);
            }
            ps[pi] = rms;
            pnorm[pi] = rms * p; /* |P_e - P_a| */
        }
    if ((st = ts__progress(ctx, 0.05, "matching")) != TS_OK)
        goto done;
    ts__amp_weights(params, use_l, use_c, w);
    pt.n = np;
    pt.ph = ph;
    pt.pu = pu;
    pt.pl = pl;
    pt.pc = pc;
    pt.px = px;
    pt.pa = pa;
    pt.ps = ps;
    for (b = 0; b < nd; b++) {
        if (nd > 1) {
            /* the patches this biome weighs on (within a cell of them: what the
             * interpolated shares reach); the others are not matched */
            for (cy = r0; cy < r1; cy++)
                for (cx = c0; cx < c1; cx++) {
                    int on = 0, x, y;
                    pi = (size_t)(cy - r0) * (size_t)ncols + (size_t)(cx - c0);
                    for (y = ys[cy] - 1; y <= ys[cy] + p && !on; y++)
                        for (x = xs[cx] - 1; x <= xs[cx] + p; x++)
                            if (x >= 0 && y >= 0 && x < W && y < H &&
                                biome_share(wts, nd, b, x, y) > 0) {
                                on = 1;
                                break;
                            }
                    pab[pi] = on ? pa[pi] : NAN;
                }
            pt.pa = pab;
        }
        if (ts__match_atoms(ctx, dicts[b], &pt, w, best + (size_t)b * np, score + (size_t)b * np,
                            coef + (size_t)b * np) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for matching");
            goto done;
        }
    }
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
    /* the working raster: the output itself for the whole grid */
    if (whole) {
        buf = *out;
    } else if (ts_raster_alloc(ctx, (base.x1 - base.x0) * F, (base.y1 - base.y0) * F, &buf) !=
               TS_OK) {
        st = ctx->status;
        goto done;
    }
    wk.coarse = coarse;
    wk.dict = dict;
    wk.F = F;
    wk.p = p;
    wk.P = P;
    wk.W = W;
    wk.H = H;
    wk.xs = xs;
    wk.ys = ys;
    wk.c0 = c0;
    wk.c1 = c1;
    wk.r0 = r0;
    wk.r1 = r1;
    wk.best = best;
    wk.pa = pa;
    wk.pnorm = pnorm;
    wk.coef = coef;
    wk.window = window;
    wk.buf = &buf;
    wk.bx = base.x0 * F;
    wk.by = base.y0 * F;
    if (nd == 1) {
        ts__parallel_for(ctx, (size_t)buf.height, recon_rows, &wk);
    } else {
        /* each biome's reconstruction, then blended by the shares (section 5.5) */
        amp_blend bl;
        for (b = 0; b < nd && !wk.fail; b++) {
            if (ts_raster_alloc(ctx, buf.width, buf.height, &bufs[b]) != TS_OK) {
                st = ctx->status;
                goto done;
            }
            wk.dict = dicts[b];
            wk.best = best + (size_t)b * np;
            wk.coef = coef + (size_t)b * np;
            wk.buf = &bufs[b];
            ts__parallel_for(ctx, (size_t)buf.height, recon_rows, &wk);
        }
        bl.coarse = coarse;
        bl.wts = wts;
        bl.bufs = bufs;
        bl.buf = &buf;
        bl.nd = nd;
        bl.F = F;
        bl.bx = wk.bx;
        bl.by = wk.by;
        ts__parallel_for(ctx, (size_t)buf.height, blend_rows, &bl);
        wk.dict = dict;
        wk.best = best;
        wk.coef = coef;
        wk.buf = &buf;
    }
    if (wk.fail) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        goto done;
    }
    res.data = resbuf;
    for (pass = 1; pass <= R; pass++) {
        /* this pass updates what the next one reads (the last: the window) */
        if (pass < R) {
            wk.ux0 = reg[pass + 1].x0 * F;
            wk.uy0 = reg[pass + 1].y0 * F;
            wk.ux1 = reg[pass + 1].x1 * F;
            wk.uy1 = reg[pass + 1].y1 * F;
        } else {
            wk.ux0 = X0;
            wk.uy0 = Y0;
            wk.ux1 = X0 + out->width;
            wk.uy1 = Y0 + out->height;
        }
        back_project(ctx, &wk, reg[pass], &res);
        if (wk.fail) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
            goto done;
        }
        if ((st = ts__progress(ctx, 0.9 + 0.1 * pass / R, "back-projection")) != TS_OK)
            goto done;
    }
    if (lay && (lay->layers || lay->classes)) {
        wk.lay = lay;
        wk.X0 = X0;
        wk.Y0 = Y0;
        wk.ww = out->width;
        wk.wh = out->height;
        ts__parallel_for(ctx, (size_t)out->height, layer_rows, &wk);
        if (wk.fail) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
            goto done;
        }
    }
    if (!whole)
        for (j = 0; j < out->height; j++)
            memcpy(&TS_PIX(out, 0, j), &TS_PIX(&buf, X0 - wk.bx, Y0 + j - wk.by),
                   (size_t)out->width * sizeof(float));
    if (info) {
        double sum = 0;
        size_t used = 0;
        info->n_patches = np;
        for (b = 0; b < nd; b++)
            info->n_atoms += dicts[b]->n;
        info->seconds_match = t1 - t0;
        info->seconds_synthesis = now_s() - t1;
        for (pi = 0; pi < np * (size_t)nd; pi++)
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
    if (!whole)
        ts_raster_free(&buf);
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
    free(resbuf);
    free(pl);
    free(pc);
    free(px);
    free(pab);
    for (b = 0; bufs && b < nd; b++)
        ts_raster_free(&bufs[b]);
    free(bufs);
    return st;
}

/* The checks both entry points share. */
static ts_status amp_check(ts_ctx *ctx, const ts_raster *coarse, const ts_amplify_guide *guide,
                           const ts_dictionary *dict, const ts_amplify_params *params,
                           const ts_raster *out, const ts_amplify_layers *lay)
{
    int F, p, l, x, y;
    if (!coarse || !coarse->data || !dict || !params || !out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "missing input, dictionary or output");
    if (ts_params_validate(ctx, "amplify", params) != TS_OK)
        return ctx->status;
    F = params->factor;
    p = params->patch;
    if (dict->factor != F || dict->patch != p)
        return ts__fail(ctx, TS_ERR_ARG, "amplify",
                        "the dictionary was built for factor %d and patch %d, not %d and %d",
                        dict->factor, dict->patch, F, p);
    if (coarse->width < p || coarse->height < p)
        return ts__fail(ctx, TS_ERR_SIZE, "amplify",
                        "the input (%d x %d cells) is smaller than a patch (%d cells)",
                        coarse->width, coarse->height, p);
    if (guide) {
        const ts_raster *r[3] = {guide->drainage, guide->irradiance, guide->classes};
        for (l = 0; l < 3; l++)
            if (r[l] && (!r[l]->data || r[l]->width != coarse->width ||
                         r[l]->height != coarse->height))
                return ts__fail(ctx, TS_ERR_ARG, "amplify",
                                "the drainage, irradiance and classes must be on the input's "
                                "grid");
        if (guide->classes)
            for (y = 0; y < coarse->height; y++)
                for (x = 0; x < coarse->width; x++)
                    if (ts__class_code(TS_PIX(guide->classes, x, y)) < 0)
                        return ts__fail(ctx, TS_ERR_ARG, "amplify",
                                        "class %g at input cell %d,%d is not a code 1..%d (0 or "
                                        "nodata: any)",
                                        (double)TS_PIX(guide->classes, x, y), x, y,
                                        TS_MAX_CLASSES);
    }
    if (params->w_l > 0 && !dict->dl)
        return ts__fail(ctx, TS_ERR_ARG, "amplify",
                        "the irradiance term (w_l %g) needs a dictionary built with it (w_l > 0)",
                        params->w_l);
    if (params->w_l > 0 && !(guide && guide->irradiance))
        return ts__fail(ctx, TS_ERR_ARG, "amplify",
                        "the irradiance term (w_l %g) needs the input's irradiance", params->w_l);
    if (lay && lay->layers)
        for (l = 0; l < dict->n_layers; l++)
            if (!lay->layers[l].data || lay->layers[l].width != out->width ||
                lay->layers[l].height != out->height)
                return ts__fail(ctx, TS_ERR_ARG, "amplify",
                                "output layer %s is not on the output's window",
                                dict->layer_names[l]);
    if (lay && lay->classes &&
        (!lay->classes->data || lay->classes->width != out->width ||
         lay->classes->height != out->height))
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "the output classes are not on its window");
    return TS_OK;
}

TS_API ts_status ts_amplify(ts_ctx *ctx, const ts_raster *coarse, const ts_amplify_guide *guide,
                            const ts_dictionary *dict, const ts_amplify_params *params,
                            ts_raster *out, const ts_amplify_layers *layers,
                            ts_amplify_info *info)
{
    ts_raster drain = {0, 0, 0, NULL};
    ts_amplify_guide g = {NULL, NULL, NULL};
    ts_status st;
    ts__clear(ctx);
    if (info)
        memset(info, 0, sizeof *info);
    if ((st = amp_check(ctx, coarse, guide, dict, params, out, layers)) != TS_OK)
        return st;
    if (out->width != coarse->width * params->factor ||
        out->height != coarse->height * params->factor)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "the output must be %d x %d cells",
                        coarse->width * params->factor, coarse->height * params->factor);
    if (guide)
        g = *guide;
    if (!g.drainage) {
        if (ts_raster_alloc(ctx, coarse->width, coarse->height, &drain) != TS_OK ||
            ts_drainage_area(ctx, coarse, &drain) != TS_OK) {
            ts_raster_free(&drain);
            return ctx->status;
        }
        g.drainage = &drain;
    }
    st = amp_window(ctx, coarse, &g, &dict, NULL, 1, params, 0, 0, out, layers, info);
    ts_raster_free(&drain);
    return st;
}

/* What a window needs besides amp_check: the drainage, and to lie in the output. */
static ts_status amp_window_check(ts_ctx *ctx, const ts_raster *coarse,
                                  const ts_amplify_guide *guide, const ts_amplify_params *params,
                                  int x0, int y0, const ts_raster *out)
{
    if (!guide || !guide->drainage)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "the drainage area must be on the input grid");
    if (x0 < 0 || y0 < 0 || x0 + out->width > coarse->width * params->factor ||
        y0 + out->height > coarse->height * params->factor)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "the window %d,%d %dx%d is outside the output",
                        x0, y0, out->width, out->height);
    return TS_OK;
}

TS_API ts_status ts_amplify_window(ts_ctx *ctx, const ts_raster *coarse,
                                   const ts_amplify_guide *guide, const ts_dictionary *dict,
                                   const ts_amplify_params *params, int x0, int y0, ts_raster *out,
                                   const ts_amplify_layers *layers, ts_amplify_info *info)
{
    ts_status st;
    ts__clear(ctx);
    if (info)
        memset(info, 0, sizeof *info);
    if ((st = amp_check(ctx, coarse, guide, dict, params, out, layers)) != TS_OK)
        return st;
    if ((st = amp_window_check(ctx, coarse, guide, params, x0, y0, out)) != TS_OK)
        return st;
    return amp_window(ctx, coarse, guide, &dict, NULL, 1, params, x0, y0, out, layers, info);
}

TS_API ts_status ts_amplify_biomes(ts_ctx *ctx, const ts_raster *coarse,
                                   const ts_amplify_guide *guide, const ts_dictionary *const *dicts,
                                   const ts_raster *weights, int n_biomes,
                                   const ts_amplify_params *params, int x0, int y0, ts_raster *out,
                                   ts_amplify_info *info)
{
    ts_status st;
    int b, x, y;
    ts__clear(ctx);
    if (info)
        memset(info, 0, sizeof *info);
    if (n_biomes < 1 || !dicts || !weights)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "no biomes given");
    for (b = 0; b < n_biomes; b++) {
        if ((st = amp_check(ctx, coarse, guide, dicts[b], params, out, NULL)) != TS_OK)
            return st;
        if (!weights[b].data || weights[b].width != coarse->width ||
            weights[b].height != coarse->height)
            return ts__fail(ctx, TS_ERR_ARG, "amplify",
                            "biome %d: its weights are not on the input's grid", b + 1);
        for (y = 0; y < coarse->height; y++)
            for (x = 0; x < coarse->width; x++) {
                float v = TS_PIX(&weights[b], x, y);
                if (!(v >= 0.0f) || !(v <= 1e30f))
                    return ts__fail_input(ctx, TS_ERR_ARG, b, "amplify",
                                          "biome %d: weight %g at cell %d,%d is not a number "
                                          ">= 0",
                                          b + 1, (double)v, x, y);
            }
    }
    if (guide && guide->classes && n_biomes > 1)
        return ts__fail(ctx, TS_ERR_ARG, "amplify", "wanted classes go with one dictionary");
    if ((st = amp_window_check(ctx, coarse, guide, params, x0, y0, out)) != TS_OK)
        return st;
    return amp_window(ctx, coarse, guide, dicts, weights, n_biomes, params, x0, y0, out, NULL,
                      info);
}
