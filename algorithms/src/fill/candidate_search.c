/*
 * candidate_search.c - candidate patches for non-feature patch placement
 * (Zhou et al. 2007 section 4.2): each exemplar's pyramid (box-downsampled
 * by coarse_factor), nodata and feature tables and usage map, and, for
 * each patch position, the k best exemplar windows by masked SSD (FFT,
 * match_ssd.c) on the coarsest level, refined level by level at full
 * resolution by exact SSD.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>

#include "nonfeature_placement.h"

typedef ts__placer placer;
typedef ts__exemplar_data exemplar_data;
typedef ts__exemplar_usage exemplar_usage;

/* Main feature cells in the middle half of the full-resolution window at
 * (x, y) (0 without a feature mask). */
int32_t ts__place_feature_count(const placer *pl, const exemplar_data *e, int x, int y)
{
    int q = pl->P / 4;
    return e->feature_sat ? ts__sat_sum(e->feature_sat, e->full->width, x + q, y + q, x + pl->P - q,
                                        y + pl->P - q)
                          : 0;
}

static int place_int32_cmp(const void *a, const void *b)
{
    int32_t x = *(const int32_t *)a, y = *(const int32_t *)b;
    return (x > y) - (x < y);
}

/* The windows the fill takes away from the sketch's features (Zhou et al.
 * section 4.2: non-feature patches come from regions without strong
 * features): level-K positions whose full-resolution window has no more
 * main feature cells in its middle half than three quarters of the
 * windows (the richest quarter is left out; where more than three quarters
 * have none, only those).  Leaving out every window that touches a feature
 * would leave a range-and-basin exemplar only its flat basin. */
static ts_status place_feature_windows(placer *pl, exemplar_data *e, int index)
{
    const unsigned char *mask = pl->p->exemplar_features ? pl->p->exemplar_features[index] : NULL;
    int w = e->full->width, h = e->full->height, nx, ny, x, y;
    size_t W = (size_t)w + 1, n_valid = 0;
    int32_t *counts, limit;
    if (!mask)
        return TS_OK;
    e->feature_sat = ts__calloc_array(W * ((size_t)h + 1), sizeof *e->feature_sat);
    if (!e->feature_sat)
        return ts__fail(pl->ctx, TS_ERR_NOMEM, "synth", "out of memory");
    for (y = 0; y < h; y++) {
        int32_t row = 0;
        for (x = 0; x < w; x++) {
            row += mask[(size_t)y * (size_t)w + (size_t)x] != 0;
            e->feature_sat[(size_t)(y + 1) * W + (size_t)(x + 1)] =
                e->feature_sat[(size_t)y * W + (size_t)(x + 1)] + row;
        }
    }
    ts_matcher_positions(e->matcher, &nx, &ny);
    e->allowed = ts__malloc_array((size_t)nx * (size_t)ny, 1);
    counts = ts__malloc_array((size_t)nx * (size_t)ny, sizeof *counts);
    if (!e->allowed || !counts) {
        free(counts);
        return ts__fail(pl->ctx, TS_ERR_NOMEM, "synth", "out of memory");
    }
    for (y = 0; y < ny; y++)
        for (x = 0; x < nx; x++) {
            int fx = x << e->K, fy = y << e->K;
            if (fx + pl->P <= w && fy + pl->P <= h &&
                ts__sat_sum(e->nodata_sat, w, fx, fy, fx + pl->P, fy + pl->P) == 0)
                counts[n_valid++] = ts__place_feature_count(pl, e, fx, fy);
        }
    if (!n_valid) {
        free(counts);
        free(e->allowed);
        e->allowed = NULL;
        return TS_OK;
    }
    qsort(counts, n_valid, sizeof *counts, place_int32_cmp);
    limit = counts[(3 * n_valid) / 4];
    free(counts);
    e->feature_limit = limit;
    for (y = 0; y < ny; y++)
        for (x = 0; x < nx; x++) {
            int fx = x << e->K, fy = y << e->K;
            e->allowed[(size_t)y * (size_t)nx + (size_t)x] =
                fx + pl->P <= w && fy + pl->P <= h &&
                ts__place_feature_count(pl, e, fx, fy) <= limit;
        }
    return ts__matcher_set_allowed(pl->ctx, e->matcher, e->allowed);
}

/* The usage map of exemplar e (zero) and its scale: the mean variance of
 * the matcher level's cells in windows of an eighth of a patch either side. */
static ts_status place_usage_init(placer *pl, exemplar_data *e)
{
    const ts_raster *lv = &e->level[e->K];
    exemplar_usage *u = calloc(1, sizeof *u);
    int r, x, y, dx, dy;
    double sum = 0.0;
    size_t n = 0;
    if (!u)
        return ts__fail(pl->ctx, TS_ERR_NOMEM, "synth", "out of memory");
    e->usage = u;
    u->PK = pl->P >> e->K;
    u->nx = lv->width - u->PK + 1;
    u->ny = lv->height - u->PK + 1;
    u->map = ts__calloc_array((size_t)u->nx * (size_t)u->ny, sizeof *u->map);
    if (!u->map)
        return ts__fail(pl->ctx, TS_ERR_NOMEM, "synth", "out of memory");
    r = TS_MAX(1, u->PK / 8);
    for (y = r; y < lv->height - r; y += 2)
        for (x = r; x < lv->width - r; x += 2) {
            double s1 = 0.0, s2 = 0.0;
            int m = 0;
            for (dy = -r; dy <= r; dy++)
                for (dx = -r; dx <= r; dx++) {
                    double v = TS_PIX(lv, x + dx, y + dy);
                    if (!isnan(v)) {
                        s1 += v;
                        s2 += v * v;
                        m++;
                    }
                }
            if (m == (2 * r + 1) * (2 * r + 1)) {
                sum += s2 / m - (s1 / m) * (s1 / m);
                n++;
            }
        }
    u->detail2 = n ? TS_MAX(sum / (double)n, 1e-12) : 1.0;
    return TS_OK;
}

/* Add the window (sx, sy) of exemplar e, placed, to its usage. */
void ts__place_usage_add(exemplar_usage *u, int K, int sx, int sy)
{
    int cx = sx >> K, cy = sy >> K, px, py;
    for (py = TS_MAX(0, cy - u->PK + 1); py <= TS_MIN(u->ny - 1, cy + u->PK - 1); py++) {
        double oy = (double)(u->PK - abs(py - cy)) / u->PK;
        for (px = TS_MAX(0, cx - u->PK + 1); px <= TS_MIN(u->nx - 1, cx + u->PK - 1); px++) {
            double o = oy * (double)(u->PK - abs(px - cx)) / u->PK;
            u->map[(size_t)py * (size_t)u->nx + (size_t)px] += (float)o;
            u->total += o;
        }
    }
}

/* The usage cost's weight per unit of the map, for a query of n cells:
 * usage x detail variance x n / the mean usage, or / 1 while the exemplar
 * is used less than once on average (a window's use then costs what it
 * is, not a ratio to a mean near zero, which would bar every window next
 * to a used one). */
static double place_usage_weight(const placer *pl, const exemplar_usage *u, int n)
{
    double mean;
    if (!u)
        return 0.0;
    mean = TS_MAX(1.0, u->total / ((double)u->nx * (double)u->ny));
    return pl->p->s.usage * u->detail2 * (double)n / mean;
}

/* The usage cost (per cell) of the full-resolution window (x, y). */
double ts__place_usage_of(const placer *pl, const exemplar_data *ed, int x, int y)
{
    const exemplar_usage *u = ed->usage;
    int px, py;
    if (!u)
        return 0.0;
    px = TS_MIN(x >> ed->K, u->nx - 1);
    py = TS_MIN(y >> ed->K, u->ny - 1);
    return place_usage_weight(pl, u, 1) * (double)u->map[(size_t)py * (size_t)u->nx + (size_t)px];
}

TS_API int ts_synth_match_level(int coarse_factor, int patch, int w, int h)
{
    int K = 0;
    if (coarse_factor == 0) {
        while ((double)(w >> K) * (double)(h >> K) > 512.0 * 512.0 && (patch >> (K + 1)) >= 8 &&
               K + 1 < TS__PLACE_MAX_LEVELS)
            K++;
    } else {
        while ((2 << K) <= coarse_factor && K + 1 < TS__PLACE_MAX_LEVELS)
            K++;
    }
    return K;
}

/* Prepare exemplar `index`: pyramid, nodata table, matcher, usage, feature windows. */
ts_status ts__place_prepare_exemplar(placer *pl, exemplar_data *e, const ts_raster *full, int index)
{
    ts_ctx *ctx = pl->ctx;
    int w = full->width, h = full->height, x, y, cw, ch, k;
    size_t W = (size_t)w + 1;
    ts_status st;
    e->full = full;
    if (w < pl->P || h < pl->P)
        return ts__fail(ctx, TS_ERR_SIZE, "synth",
                        "an exemplar (%d x %d) is smaller than a patch (%d x %d)", w, h, pl->P,
                        pl->P);
    e->nodata_sat = ts__calloc_array(W * ((size_t)h + 1), sizeof *e->nodata_sat);
    if (!e->nodata_sat)
        return ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
    for (y = 0; y < h; y++) {
        int32_t row = 0;
        for (x = 0; x < w; x++) {
            row += isnan(TS_PIX(full, x, y)) ? 1 : 0;
            e->nodata_sat[(size_t)(y + 1) * W + (size_t)(x + 1)] =
                e->nodata_sat[(size_t)y * W + (size_t)(x + 1)] + row;
        }
    }
    e->K = ts_synth_match_level(pl->p->s.coarse_factor, pl->P, w, h);
    e->level[0] = *full;
    for (k = 1; k <= e->K; k++) {
        const ts_raster *src = &e->level[k - 1];
        cw = src->width / 2;
        ch = src->height / 2;
        if ((st = ts_raster_alloc(ctx, cw, ch, &e->level[k])) != TS_OK)
            return st;
        for (y = 0; y < ch; y++)
            for (x = 0; x < cw; x++)
                TS_PIX(&e->level[k], x, y) =
                    0.25f * (TS_PIX(src, 2 * x, 2 * y) + TS_PIX(src, 2 * x + 1, 2 * y) +
                             TS_PIX(src, 2 * x, 2 * y + 1) + TS_PIX(src, 2 * x + 1, 2 * y + 1));
    }
    if ((st = ts_matcher_new(ctx, &e->level[e->K], pl->P >> e->K, pl->P >> e->K, &e->matcher)) !=
        TS_OK)
        return st;
    if (pl->p->s.usage > 0 && (st = place_usage_init(pl, e)) != TS_OK)
        return st;
    return place_feature_windows(pl, e, index);
}

/* The target pyramid: a coarse cell is known (the mean of its known
 * cells) where at least half of its four cells are. */
static void place_target_pyramid(placer *pl, int K)
{
    int k, x, y;
    for (k = 1; k <= K; k++) {
        int Pk = pl->P >> k, Ps = pl->P >> (k - 1), n = 0;
        const float *src = pl->tlevel[k - 1];
        float *dst = pl->tlevel[k];
        for (y = 0; y < Pk; y++)
            for (x = 0; x < Pk; x++) {
                float v[4];
                double sum = 0.0;
                int i, m = 0;
                v[0] = src[(2 * y) * Ps + 2 * x];
                v[1] = src[(2 * y) * Ps + 2 * x + 1];
                v[2] = src[(2 * y + 1) * Ps + 2 * x];
                v[3] = src[(2 * y + 1) * Ps + 2 * x + 1];
                for (i = 0; i < 4; i++)
                    if (!isnan(v[i])) {
                        sum += v[i];
                        m++;
                    }
                dst[y * Pk + x] = m >= 2 ? (float)(sum / m) : NAN;
                if (m >= 2)
                    pl->tknown[k][n++] = y * Pk + x;
            }
        pl->n_tknown[k] = n;
    }
}

/* SSD of target level k against exemplar level k at (x, y); stops early
 * above `bound`; INFINITY where the exemplar level has nodata. */
static double place_ssd_level(const placer *pl, const ts_raster *ex, int k, int x, int y,
                              double bound)
{
    int i, n = pl->n_tknown[k];
    const float *t = pl->tlevel[k], *base = &TS_PIX(ex, x, y);
    const int *idx = pl->tknown[k];
    const ptrdiff_t *off = pl->toff[k];
    double s = 0.0;
    for (i = 0; i < n; i++) {
        double d = (double)t[idx[i]] - (double)base[off[i]];
        s += d * d;
        if (!(s <= bound)) /* also catches NaN */
            return isnan(s) ? INFINITY : s;
    }
    return s;
}

static int cand_cmp(const void *a, const void *b)
{
    const ts_candidate *p = a, *q = b;
    if (p->ssd != q->ssd)
        return p->ssd < q->ssd ? -1 : 1;
    if (p->y != q->y)
        return p->y < q->y ? -1 : 1;
    return (p->x > q->x) - (p->x < q->x);
}

typedef struct refine_job {
    const placer *pl;
    const exemplar_data *ed;
    const ts_candidate *coarse;
    ts_candidate *out; /* out[i] for coarse[i]; x = -1 when nothing valid */
} refine_job;

/* Refine coarse candidates [b, e) level by level (read-only on the placer,
 * so ranges run in parallel). */
static void place_refine_range(void *arg, size_t b, size_t e)
{
    const refine_job *j = arg;
    const placer *pl = j->pl;
    const exemplar_data *ed = j->ed;
    int K = ed->K, w = ed->full->width, h = ed->full->height;
    size_t i;
    for (i = b; i < e; i++) {
        int cx = j->coarse[i].x, cy = j->coarse[i].y, lv;
        double best = INFINITY;
        for (lv = K - 1; lv >= 0; lv--) {
            const ts_raster *ex = &ed->level[lv];
            int Pk = pl->P >> lv, bx = -1, by = -1, x, y;
            /* +-2 below the matcher's level, then +-1: each level halves the doubt */
            int r = lv == K - 1 ? 2 : 1;
            best = INFINITY;
            for (y = TS_MAX(0, 2 * cy - r); y <= TS_MIN(ex->height - Pk, 2 * cy + r); y++)
                for (x = TS_MAX(0, 2 * cx - r); x <= TS_MIN(ex->width - Pk, 2 * cx + r); x++) {
                    double s;
                    if (lv == 0 && ts__sat_sum(ed->nodata_sat, w, x, y, x + pl->P, y + pl->P) != 0)
                        continue;
                    s = place_ssd_level(pl, ex, lv, x, y, best);
                    if (s < best) {
                        best = s;
                        bx = x;
                        by = y;
                    }
                }
            if (bx < 0)
                break;
            cx = bx;
            cy = by;
        }
        j->out[i].x = -1;
        if (lv < 0 && isfinite(best) && cx + pl->P <= w && cy + pl->P <= h) {
            j->out[i].x = cx;
            j->out[i].y = cy;
            j->out[i].ssd = best;
        }
    }
}

/* k best full-resolution windows of exemplar e: the matcher's candidates on
 * the coarsest level, each refined level by level by exact SSD (+-2 cells on
 * the first finer level, +-1 on the others), so the full-resolution SSD is
 * exact. */
ts_status ts__place_search(placer *pl, int e, ts_candidate *out, int *n_out)
{
    exemplar_data *ed = &pl->ex[e];
    int k = pl->p->s.candidates, found = 0, i, K = ed->K, nc = 0;
    ts_candidate *coarse = pl->cands + pl->n_cands_cap / 2;
    ts_raster tc;
    ts_status st;
    if (K == 0) {
        ts_raster t = ts_raster_wrap(pl->mtarget, pl->P, pl->P, pl->P);
        if (ed->usage)
            ts__matcher_cost(ed->matcher, ed->usage->map,
                             place_usage_weight(pl, ed->usage, pl->n_tknown[0]));
        st = ts_matcher_best(pl->ctx, ed->matcher, &t, k, 1, out, &found);
        ts__matcher_cost(ed->matcher, NULL, 0);
        /* the SSD alone: ts__place_one adds the usage cost to every candidate */
        for (i = 0; i < found; i++)
            out[i].ssd =
                TS_MAX(0.0, out[i].ssd - (double)pl->n_tknown[0] *
                                             ts__place_usage_of(pl, ed, out[i].x, out[i].y));
        *n_out = found;
        return st;
    }
    place_target_pyramid(pl, K);
    for (i = 0; i < K; i++) {
        int Pk = pl->P >> i, c;
        for (c = 0; c < pl->n_tknown[i]; c++)
            pl->toff[i][c] =
                (ptrdiff_t)(pl->tknown[i][c] / Pk) * ed->level[i].stride + pl->tknown[i][c] % Pk;
    }
    tc = ts_raster_wrap(pl->tlevel[K], pl->P >> K, pl->P >> K, pl->P >> K);
    if (ed->usage)
        ts__matcher_cost(ed->matcher, ed->usage->map,
                         place_usage_weight(pl, ed->usage, pl->n_tknown[K]));
    st = ts_matcher_best(pl->ctx, ed->matcher, &tc, 2 * k, 2, coarse, &nc);
    ts__matcher_cost(ed->matcher, NULL, 0);
    if (st != TS_OK)
        return st;
    {
        refine_job job;
        job.pl = pl;
        job.ed = ed;
        job.coarse = coarse;
        job.out = out;
        ts__parallel_for(pl->ctx, (size_t)nc, place_refine_range, &job);
    }
    for (i = 0; i < nc; i++)
        if (out[i].x >= 0)
            out[found++] = out[i];
    qsort(out, (size_t)found, sizeof *out, cand_cmp);
    /* two coarse candidates may refine to one window: keep it once */
    for (i = 1, nc = found ? 1 : 0; i < found; i++)
        if (out[i].x != out[nc - 1].x || out[i].y != out[nc - 1].y)
            out[nc++] = out[i];
    *n_out = TS_MIN(nc, k);
    return TS_OK;
}
