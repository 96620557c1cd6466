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

/* The state of one window: its sizes, the coarse rectangles the passes
 * read, the patches over them (global lattice) with their descriptors and
 * matches, and the working rasters. */
typedef struct amp_state {
    int W, H, F, p, P, R, nd, K, use_l, use_c;
    amp_rect reg[12], base;
    int whole, c0, c1, r0, r1, ncols;
    int *xs, *ys, *best;
    size_t np;
    float *ph, *pu, *pl, *pc, *px, *coef, *score, *win, *lwin, *window, *resbuf;
    double *pa, *ps, *pnorm, *pab;
    ts_raster buf, *bufs;
} amp_state;

/* The window's sizes and what it uses; the coarse cells under the window,
 * and what each pass reads. */
static void amp_state_init(amp_state *a, const ts_raster *coarse, const ts_amplify_guide *guide,
                           const ts_dictionary *dict, int nd, const ts_amplify_params *params,
                           int X0, int Y0, const ts_raster *out)
{
    int W = coarse->width, H = coarse->height, F = params->factor, R = params->refine, pass;
    amp_rect foot;
    memset(a, 0, sizeof *a);
    a->W = W;
    a->H = H;
    a->F = F;
    a->p = params->patch;
    a->P = a->p * F;
    a->R = R;
    a->nd = nd;
    a->K = dict->n_classes;
    a->use_l = params->w_l > 0 && guide->irradiance && dict->dl;
    a->use_c = params->w_c > 0 && guide->classes && a->K > 0 && nd == 1;
    foot.x0 = X0 / F;
    foot.y0 = Y0 / F;
    foot.x1 = (X0 + out->width + F - 1) / F;
    foot.y1 = (Y0 + out->height + F - 1) / F;
    a->reg[R + 1] = foot;
    for (pass = R; pass >= 1; pass--)
        a->reg[pass] = rect_grow(a->reg[pass + 1], 2, W, H);
    a->base = R > 0 ? a->reg[1] : foot;
    a->whole = X0 == 0 && Y0 == 0 && out->width == W * F && out->height == H * F;
}

/* The patches over the base rectangle (global lattice): their origins, and
 * the columns and rows in use. */
static ts_status amp_lattice(ts_ctx *ctx, amp_state *a)
{
    int W = a->W, H = a->H, p = a->p, step = p / 2 > 0 ? p / 2 : 1, nx, ny, c0, c1, r0, r1;
    int *xs, *ys;
    a->xs = xs = malloc((size_t)(W / step + 2) * sizeof *xs);
    a->ys = ys = malloc((size_t)(H / step + 2) * sizeof *ys);
    if (!xs || !ys)
        return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
    nx = patch_origins(W, p, step, xs);
    ny = patch_origins(H, p, step, ys);
    for (c0 = 0; c0 < nx && xs[c0] + p <= a->base.x0; c0++)
        ;
    for (c1 = c0; c1 < nx && xs[c1] < a->base.x1; c1++)
        ;
    for (r0 = 0; r0 < ny && ys[r0] + p <= a->base.y0; r0++)
        ;
    for (r1 = r0; r1 < ny && ys[r1] < a->base.y1; r1++)
        ;
    a->c0 = c0;
    a->c1 = c1;
    a->r0 = r0;
    a->r1 = r1;
    a->ncols = c1 - c0;
    a->np = (size_t)a->ncols * (size_t)(r1 - r0);
    return TS_OK;
}

/* The patches' descriptors, their matches and the work arrays. */
static ts_status amp_alloc(ts_ctx *ctx, amp_state *a, const ts_amplify_params *params)
{
    size_t np = a->np;
    int p = a->p, nd = a->nd, K = a->K;
    a->ph = ts__malloc_array(np * (size_t)p * p, sizeof *a->ph);
    a->pu = ts__malloc_array(np * (size_t)p * p, sizeof *a->pu);
    a->pa = ts__malloc_array(np, sizeof *a->pa);
    a->ps = ts__malloc_array(np, sizeof *a->ps);
    a->pnorm = ts__malloc_array(np, sizeof *a->pnorm);
    a->best = ts__malloc_array(np * (size_t)nd, sizeof *a->best);
    a->coef = ts__malloc_array(np * (size_t)nd, sizeof *a->coef);
    a->score = ts__malloc_array(np * (size_t)nd, sizeof *a->score);
    if (nd > 1) {
        a->pab = ts__malloc_array(np, sizeof *a->pab);
        a->bufs = calloc((size_t)nd, sizeof *a->bufs);
    }
    a->win = malloc((size_t)p * p * sizeof *a->win);
    a->lwin = malloc((size_t)p * p * sizeof *a->lwin);
    a->window = malloc((size_t)a->P * sizeof *a->window);
    if (a->use_l)
        a->pl = ts__malloc_array(np * (size_t)p * p, sizeof *a->pl);
    if (a->use_c)
        a->pc = ts__malloc_array(np * (size_t)K, sizeof *a->pc);
    if (params->w_x > 0)
        a->px = ts__malloc_array(np * (size_t)p * p, sizeof *a->px);
    a->resbuf = ts__malloc_array(
        (size_t)(a->base.x1 - a->base.x0) * (size_t)(a->base.y1 - a->base.y0), sizeof *a->resbuf);
    if (!a->ph || !a->pu || !a->pa || !a->ps || !a->pnorm || !a->best || !a->coef || !a->score ||
        !a->win || !a->lwin || !a->window || !a->resbuf || (a->use_l && !a->pl) ||
        (a->use_c && !a->pc) || (params->w_x > 0 && !a->px) || (nd > 1 && (!a->pab || !a->bufs)))
        return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for %zu patches", np);
    return TS_OK;
}

/* The wanted classes' shares in the patch at (x0, y0), scaled to unit
 * length (0: any). */
static void amp_patch_classes(const amp_state *a, const ts_raster *cls, int x0, int y0, float *c)
{
    int p = a->p, K = a->K, i, j;
    double norm = 0;
    memset(c, 0, (size_t)K * sizeof *c);
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++) {
            int code = ts__class_code(TS_PIX(cls, x0 + i, y0 + j));
            if (code > 0 && code <= K)
                c[code - 1] += 1.0f;
        }
    for (i = 0; i < K; i++)
        norm += (double)c[i] * c[i];
    for (i = 0; i < K && norm > 0; i++)
        c[i] = (float)(c[i] / sqrt(norm));
}

/* The irradiance of the patch at (x0, y0), described as the drainage is,
 * into pl (nodata cells take the patch's mean). */
static void amp_patch_irradiance(const amp_state *a, const ts_raster *irr, int x0, int y0,
                                 float *pl)
{
    int p = a->p, nl = 0, i, j;
    double lm = 0, um, urms;
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++) {
            float v = TS_PIX(irr, x0 + i, y0 + j);
            if (!isnan(v)) {
                lm += v;
                nl++;
            }
        }
    lm = nl ? lm / nl : 0.0;
    for (j = 0; j < p; j++)
        for (i = 0; i < p; i++) {
            float v = TS_PIX(irr, x0 + i, y0 + j);
            a->lwin[j * p + i] = isnan(v) ? (float)lm : v;
        }
    ts__amp_normalise(a->lwin, p * p, pl, &um, &urms);
}

/* The patches described as the atoms are (nodata cells take the patch's mean). */
static void amp_describe(amp_state *a, const ts_raster *coarse, const ts_amplify_guide *guide)
{
    const ts_raster *drain = guide->drainage;
    int p = a->p, i, j, cx, cy;
    const int *xs = a->xs, *ys = a->ys;
    float *win = a->win, *lwin = a->lwin, *pl = a->pl, *px = a->px;
    for (cy = a->r0; cy < a->r1; cy++)
        for (cx = a->c0; cx < a->c1; cx++) {
            double m = 0, mu = 0, rms, um, urms;
            int nv = 0;
            size_t pi = (size_t)(cy - a->r0) * (size_t)a->ncols + (size_t)(cx - a->c0);
            for (j = 0; j < p; j++)
                for (i = 0; i < p; i++) {
                    float v = TS_PIX(coarse, xs[cx] + i, ys[cy] + j);
                    if (!isnan(v)) {
                        m += v;
                        mu += log1p(TS_PIX(drain, xs[cx] + i, ys[cy] + j));
                        nv++;
                    }
                }
            if (a->pc)
                amp_patch_classes(a, guide->classes, xs[cx], ys[cy], a->pc + pi * (size_t)a->K);
            if (!nv) {
                a->pa[pi] = NAN;
                a->ps[pi] = a->pnorm[pi] = 0;
                memset(a->ph + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *a->ph);
                memset(a->pu + pi * (size_t)p * p, 0, (size_t)p * p * sizeof *a->pu);
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
            ts__amp_normalise(win, p * p, a->ph + pi * (size_t)p * p, &a->pa[pi], &rms);
            ts__amp_normalise(lwin, p * p, a->pu + pi * (size_t)p * p, &um, &urms);
            if (px)
                ts__amp_context(coarse, xs[cx], ys[cy], p, px + pi * (size_t)p * p);
            if (pl)
                amp_patch_irradiance(a, guide->irradiance, xs[cx], ys[cy], pl + pi * (size_t)p * p);
            a->ps[pi] = rms;
            a->pnorm[pi] = rms * p; /* |P_e - P_a| */
        }
}

/* The patches biome b weighs on (within a cell of them: what the
 * interpolated shares reach) keep their mean altitude in pab; the others
 * take NaN and are not matched. */
static void amp_biome_patches(amp_state *a, const ts_raster *wts, int b)
{
    int W = a->W, H = a->H, p = a->p, nd = a->nd, cx, cy;
    for (cy = a->r0; cy < a->r1; cy++)
        for (cx = a->c0; cx < a->c1; cx++) {
            int on = 0, x, y;
            size_t pi = (size_t)(cy - a->r0) * (size_t)a->ncols + (size_t)(cx - a->c0);
            for (y = a->ys[cy] - 1; y <= a->ys[cy] + p && !on; y++)
                for (x = a->xs[cx] - 1; x <= a->xs[cx] + p; x++)
                    if (x >= 0 && y >= 0 && x < W && y < H && biome_share(wts, nd, b, x, y) > 0) {
                        on = 1;
                        break;
                    }
            a->pab[pi] = on ? a->pa[pi] : NAN;
        }
}

/* Every patch matched with the atoms of each biome's dictionary. */
static ts_status amp_match(ts_ctx *ctx, amp_state *a, const ts_dictionary *const *dicts,
                           const ts_raster *wts, const ts_amplify_params *params)
{
    size_t np = a->np;
    double w[AMP_NW];
    amp_patches pt;
    int b;
    ts__amp_weights(params, a->use_l, a->use_c, w);
    pt.n = np;
    pt.ph = a->ph;
    pt.pu = a->pu;
    pt.pl = a->pl;
    pt.pc = a->pc;
    pt.px = a->px;
    pt.pa = a->pa;
    pt.ps = a->ps;
    for (b = 0; b < a->nd; b++) {
        if (a->nd > 1) {
            amp_biome_patches(a, wts, b);
            pt.pa = a->pab;
        }
        if (ts__match_atoms(ctx, dicts[b], &pt, w, a->best + (size_t)b * np,
                            a->score + (size_t)b * np, a->coef + (size_t)b * np) != 0)
            return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory for matching");
    }
    return TS_OK;
}

/* What the row workers share, from the window's state; the working raster
 * from fine cell (bx, by). */
static void amp_work_init(amp_state *a, amp_work *wk, const ts_raster *coarse,
                          const ts_dictionary *dict)
{
    wk->coarse = coarse;
    wk->dict = dict;
    wk->F = a->F;
    wk->p = a->p;
    wk->P = a->P;
    wk->W = a->W;
    wk->H = a->H;
    wk->xs = a->xs;
    wk->ys = a->ys;
    wk->c0 = a->c0;
    wk->c1 = a->c1;
    wk->r0 = a->r0;
    wk->r1 = a->r1;
    wk->best = a->best;
    wk->pa = a->pa;
    wk->pnorm = a->pnorm;
    wk->coef = a->coef;
    wk->window = a->window;
    wk->buf = &a->buf;
    wk->bx = a->base.x0 * a->F;
    wk->by = a->base.y0 * a->F;
}

/* The matched atoms blended into the working raster: each biome's
 * reconstruction, then blended by the shares (section 5.5). */
static ts_status amp_reconstruct(ts_ctx *ctx, amp_state *a, amp_work *wk, const ts_raster *coarse,
                                 const ts_dictionary *const *dicts, const ts_raster *wts,
                                 const ts_raster *out)
{
    int P = a->P, F = a->F, nd = a->nd, i, b;
    size_t np = a->np;
    /* the falloff: sin^2 windows overlapping by half sum to one */
    for (i = 0; i < P; i++) {
        double sv = sin(3.14159265358979323846 * (i + 0.5) / P);
        a->window[i] = (float)(sv * sv);
    }
    /* the working raster: the output itself for the whole grid */
    if (a->whole) {
        a->buf = *out;
    } else if (ts_raster_alloc(ctx, (a->base.x1 - a->base.x0) * F, (a->base.y1 - a->base.y0) * F,
                               &a->buf) != TS_OK) {
        return ctx->status;
    }
    amp_work_init(a, wk, coarse, dicts[0]);
    if (nd == 1) {
        ts__parallel_for(ctx, (size_t)a->buf.height, recon_rows, wk);
    } else {
        amp_blend bl;
        for (b = 0; b < nd && !wk->fail; b++) {
            if (ts_raster_alloc(ctx, a->buf.width, a->buf.height, &a->bufs[b]) != TS_OK)
                return ctx->status;
            wk->dict = dicts[b];
            wk->best = a->best + (size_t)b * np;
            wk->coef = a->coef + (size_t)b * np;
            wk->buf = &a->bufs[b];
            ts__parallel_for(ctx, (size_t)a->buf.height, recon_rows, wk);
        }
        bl.coarse = coarse;
        bl.wts = wts;
        bl.bufs = a->bufs;
        bl.buf = &a->buf;
        bl.nd = nd;
        bl.F = F;
        bl.bx = wk->bx;
        bl.by = wk->by;
        ts__parallel_for(ctx, (size_t)a->buf.height, blend_rows, &bl);
        wk->dict = dicts[0];
        wk->best = a->best;
        wk->coef = a->coef;
        wk->buf = &a->buf;
    }
    if (wk->fail)
        return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
    return TS_OK;
}

/* The back-projection passes; each updates what the next one reads (the
 * last: the window). */
static ts_status amp_refine(ts_ctx *ctx, amp_state *a, amp_work *wk, int X0, int Y0,
                            const ts_raster *out)
{
    int F = a->F, R = a->R, pass;
    ts_raster res;
    ts_status st;
    res.data = a->resbuf;
    for (pass = 1; pass <= R; pass++) {
        if (pass < R) {
            wk->ux0 = a->reg[pass + 1].x0 * F;
            wk->uy0 = a->reg[pass + 1].y0 * F;
            wk->ux1 = a->reg[pass + 1].x1 * F;
            wk->uy1 = a->reg[pass + 1].y1 * F;
        } else {
            wk->ux0 = X0;
            wk->uy0 = Y0;
            wk->ux1 = X0 + out->width;
            wk->uy1 = Y0 + out->height;
        }
        back_project(ctx, wk, a->reg[pass], &res);
        if (wk->fail)
            return ts__fail(ctx, TS_ERR_NOMEM, "amplify", "out of memory");
        if ((st = ts__progress(ctx, 0.9 + 0.1 * pass / R, "back-projection")) != TS_OK)
            return st;
    }
    return TS_OK;
}

/* The figures of the window: its patches and atoms, the time spent and the
 * matches' mean score. */
static void amp_info_fill(const amp_state *a, const ts_dictionary *const *dicts, double t0,
                          double t1, ts_amplify_info *info)
{
    double sum = 0;
    size_t used = 0, pi;
    int b;
    info->n_patches = a->np;
    for (b = 0; b < a->nd; b++)
        info->n_atoms += dicts[b]->n;
    info->seconds_match = t1 - t0;
    info->seconds_synthesis = now_s() - t1;
    for (pi = 0; pi < a->np * (size_t)a->nd; pi++)
        if (a->best[pi] >= 0) {
            sum += a->score[pi];
            used++;
            if (a->coef[pi] < 0)
                info->n_inverted++;
        }
    info->mean_score = used ? sum / used : 0;
}

/* Everything the window allocated. */
static void amp_state_free(amp_state *a)
{
    int b;
    if (!a->whole)
        ts_raster_free(&a->buf);
    free(a->xs);
    free(a->ys);
    free(a->best);
    free(a->ph);
    free(a->pu);
    free(a->pa);
    free(a->ps);
    free(a->pnorm);
    free(a->coef);
    free(a->score);
    free(a->win);
    free(a->lwin);
    free(a->window);
    free(a->resbuf);
    free(a->pl);
    free(a->pc);
    free(a->px);
    free(a->pab);
    for (b = 0; a->bufs && b < a->nd; b++)
        ts_raster_free(&a->bufs[b]);
    free(a->bufs);
}

/* The fine cells [X0, X0 + out->width) x [Y0, Y0 + out->height) of the
 * amplified DEM: the patches over them and the coarse margin every
 * back-projection pass needs (two cells per pass, the cubic's reach) are
 * computed, nothing else.  Each cell is computed by the same operations in
 * the same order whatever the window, so a window is byte for byte the same
 * window of the whole. */
static ts_status amp_window(ts_ctx *ctx, const ts_raster *coarse, const ts_amplify_guide *guide,
                            const ts_dictionary *const *dicts, const ts_raster *wts, int nd,
                            const ts_amplify_params *params, int X0, int Y0, ts_raster *out,
                            const ts_amplify_layers *lay, ts_amplify_info *info)
{
    double t0, t1;
    amp_state a;
    amp_work wk;
    int j;
    ts_status st;
    memset(&wk, 0, sizeof wk);
    amp_state_init(&a, coarse, guide, dicts[0], nd, params, X0, Y0, out);
    if ((st = amp_lattice(ctx, &a)) != TS_OK || (st = amp_alloc(ctx, &a, params)) != TS_OK)
        goto done;
    t0 = now_s();
    amp_describe(&a, coarse, guide);
    if ((st = ts__progress(ctx, 0.05, "matching")) != TS_OK ||
        (st = amp_match(ctx, &a, dicts, wts, params)) != TS_OK ||
        (st = ts__check_cancel(ctx)) != TS_OK)
        goto done;
    t1 = now_s();
    if ((st = ts__progress(ctx, 0.6, "synthesis")) != TS_OK ||
        (st = amp_reconstruct(ctx, &a, &wk, coarse, dicts, wts, out)) != TS_OK ||
        (st = amp_refine(ctx, &a, &wk, X0, Y0, out)) != TS_OK)
        goto done;
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
    if (!a.whole)
        for (j = 0; j < out->height; j++)
            memcpy(&TS_PIX(out, 0, j), &TS_PIX(&a.buf, X0 - wk.bx, Y0 + j - wk.by),
                   (size_t)out->width * sizeof(float));
    if (info)
        amp_info_fill(&a, dicts, t0, t1, info);
    st = ts__progress(ctx, 1.0, "done");
done:
    amp_state_free(&a);
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
