/*
 * nonfeature_placement.c - non-feature patch placement (Zhou et al. 2007
 * section 4.2) with patch merging (section 5): fills the empty cells of an
 * output raster with exemplar patches.
 *
 * Patch positions lie on a grid of step patch - overlap.  They are visited
 * in descending order of overlap with the filled area (grow) or in scan
 * order (raster).  For each, the k best exemplar windows by masked SSD are
 * found (FFT, match_ssd.c), optionally on exemplars downsampled by
 * coarse_factor and refined at full resolution in a +-factor window by
 * exact SSD; each candidate is cut in with a graph cut (seam_graphcut.c)
 * and the winner is the lowest RMS(SSD) + alpha_g * mean seam mismatch;
 * the seam is then smoothed by Poisson seam removal (poisson.c) over the
 * patch window with the cells around it as Dirichlet boundary.
 * Cost per position: one FFT match per exemplar + k graph cuts + one
 * Poisson solve.  Deterministic for a given seed.
 */
#include <stdlib.h>
#include <string.h>

#include "patch_merge.h"
#include "placement_queue.h"

typedef ts__placement placement;

#define PLACE_MAX_LEVELS 5 /* pyramid levels: factors 1, 2, 4, 8, 16 */

/* How much each window of an exemplar's matcher level is used: the sum,
 * over the windows the fill placed, of their overlap with it (in windows). */
typedef struct exemplar_usage {
    float *map;     /* nx * ny positions of the matcher's level */
    int nx, ny, PK; /* positions, window side on that level */
    double total;   /* sum of map */
    double detail2; /* the level's mean local variance (the cost's scale) */
} exemplar_usage;

typedef struct exemplar_data {
    const ts_raster *full;
    /* level[k]: box-downsampled by 2^k (NaN where any cell is); level[0] = *full */
    ts_raster level[PLACE_MAX_LEVELS];
    int K;                  /* coarsest level: the coarse factor is 2^K */
    ts_matcher *matcher;    /* on level[K] */
    int32_t *nodata_sat;    /* summed-area table of full-resolution nodata, (w+1)*(h+1) */
    int32_t *feature_sat;   /* likewise of its main feature cells, or NULL */
    unsigned char *allowed; /* level-K window positions not rich in main features, or NULL */
    int32_t feature_limit;  /* the most main feature cells an allowed window has */
    exemplar_usage *usage;  /* shared by the slots; NULL without a usage cost */
} exemplar_data;

typedef struct placer {
    ts_ctx *ctx;
    const ts__fill *p;
    ts_raster *out;
    const unsigned char *flags; /* TS_CELL_* per output cell, or NULL */
    ts_synth_maps *maps;
    exemplar_data *ex;
    int n_ex;
    int P;         /* patch size */
    uint64_t rng0; /* from the seed; each placement draws from its own stream */
    uint64_t rng;
    int shares_ex; /* a second slot: ex[] levels and tables belong to the first */
    double sec[3]; /* seconds matching, cutting, merging (for maps) */
    /* work buffers */
    float *target, *patch;
    float *cand_patch; /* one P x P window per candidate, for parallel cuts */
    ts_merger merger;
    int32_t *src_x, *src_y; /* P x P: where each cell of the chosen patch comes from */
    float *mtarget;         /* what is matched: the window, with wanted heights where empty */
    float *tlevel[PLACE_MAX_LEVELS]; /* matching pyramid (tlevel[0] = mtarget) */
    int *tknown[PLACE_MAX_LEVELS];   /* known cells per level */
    int n_tknown[PLACE_MAX_LEVELS];
    /* per level, the known cells' offsets in the current exemplar's level
     * (row * stride + column): no division in the SSD loop */
    ptrdiff_t *toff[PLACE_MAX_LEVELS];
    unsigned char *constraint, *labels, *best_labels;
    int *known; /* indices of known target cells */
    int *near;  /* P x P: distance to the cells this patch fills */
    ts_candidate *cands;
    int n_cands_cap;
    double *cand_lb; /* per candidate: a lower bound of its cost */
    double *cand_h;  /* per candidate: its height costs */
    double *cand_u;  /* per candidate: its usage cost (squared height units) */
    int *to_cut;     /* candidates to cut, in order */
} placer;

/* Add the time since *t0 to a stage counter (when stats are wanted). */
static void place_tick(placer *pl, double *counter, double *t0)
{
    double t = ts__now();
    if (pl->maps)
        *counter += t - *t0;
    *t0 = t;
}

/* splitmix64: the only randomness, seeded from the context */
static uint64_t place_rand(placer *pl)
{
    uint64_t z = (pl->rng += 0x9e3779b97f4a7c15ull);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
    return z ^ (z >> 31);
}

static int place_flag(const placer *pl, int x, int y, int bit)
{
    return pl->flags && (pl->flags[(size_t)y * (size_t)pl->out->width + (size_t)x] & bit);
}

static void place_count(const placer *pl, placement *q)
{
    int x, y, filled = 0, empty = 0;
    for (y = q->y; y < q->y + pl->P; y++)
        for (x = q->x; x < q->x + pl->P; x++) {
            if (!isnan(TS_PIX(pl->out, x, y)))
                filled++;
            else if (!(place_flag(pl, x, y, TS_CELL_NODATA)))
                empty++;
        }
    q->overlap = filled;
    q->needed = empty > 0;
}

/* Grid coordinates 0, step, 2 step, ..., with the last one flush with the end. */
static int place_axis(int size, int P, int step, int *coords)
{
    int n = 0, c;
    for (c = 0; c + P < size; c += step)
        coords[n++] = c;
    coords[n++] = size - P;
    return n;
}

static int32_t sat_sum(const int32_t *sat, int w, int x0, int y0, int x1, int y1)
{
    size_t W = (size_t)w + 1;
    return sat[(size_t)y1 * W + x1] - sat[(size_t)y0 * W + x1] - sat[(size_t)y1 * W + x0] +
           sat[(size_t)y0 * W + x0];
}

/* Main feature cells in the middle half of the full-resolution window at
 * (x, y) (0 without a feature mask). */
static int32_t place_feature_count(const placer *pl, const exemplar_data *e, int x, int y)
{
    int q = pl->P / 4;
    return e->feature_sat
               ? sat_sum(e->feature_sat, e->full->width, x + q, y + q, x + pl->P - q, y + pl->P - q)
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
                sat_sum(e->nodata_sat, w, fx, fy, fx + pl->P, fy + pl->P) == 0)
                counts[n_valid++] = place_feature_count(pl, e, fx, fy);
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
                fx + pl->P <= w && fy + pl->P <= h && place_feature_count(pl, e, fx, fy) <= limit;
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
static void place_usage_add(exemplar_usage *u, int K, int sx, int sy)
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
static double place_usage_of(const placer *pl, const exemplar_data *ed, int x, int y)
{
    const exemplar_usage *u = ed->usage;
    int px, py;
    if (!u)
        return 0.0;
    px = TS_MIN(x >> ed->K, u->nx - 1);
    py = TS_MIN(y >> ed->K, u->ny - 1);
    return place_usage_weight(pl, u, 1) * (double)u->map[(size_t)py * (size_t)u->nx + (size_t)px];
}

static ts_status place_prepare_exemplar(placer *pl, exemplar_data *e, const ts_raster *full,
                                        int index)
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
    /* coarse factor: as asked (rounded down to a power of two), or (0) the
     * smallest that brings the exemplar to at most 512 x 512 cells, keeping
     * at least 8 coarse cells a patch */
    e->K = 0;
    if (pl->p->s.coarse_factor == 0) {
        while ((double)(w >> e->K) * (double)(h >> e->K) > 512.0 * 512.0 &&
               (pl->P >> (e->K + 1)) >= 8 && e->K + 1 < PLACE_MAX_LEVELS)
            e->K++;
    } else {
        while ((2 << e->K) <= pl->p->s.coarse_factor && e->K + 1 < PLACE_MAX_LEVELS)
            e->K++;
    }
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
                    if (lv == 0 && sat_sum(ed->nodata_sat, w, x, y, x + pl->P, y + pl->P) != 0)
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
static ts_status place_search(placer *pl, int e, ts_candidate *out, int *n_out)
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
        /* the SSD alone: place_one adds the usage cost to every candidate */
        for (i = 0; i < found; i++)
            out[i].ssd = TS_MAX(0.0, out[i].ssd - (double)pl->n_tknown[0] *
                                                      place_usage_of(pl, ed, out[i].x, out[i].y));
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

static void place_copy_patch(const placer *pl, const ts_raster *ex, int sx, int sy)
{
    int x, y;
    for (y = 0; y < pl->P; y++)
        for (x = 0; x < pl->P; x++)
            pl->patch[y * pl->P + x] = TS_PIX(ex, sx + x, sy + y);
}

/* Merge the chosen window (sx, sy) of exemplar e at q: the patch with its
 * ring from the exemplar, then ts__merger_apply. */
static ts_status place_merge(placer *pl, const placement *q, int e, int sx, int sy, int index)
{
    const ts_raster *exr = pl->ex[e].full;
    int P = pl->P, M = P + 2, x, y;
    for (y = 0; y < M; y++)
        for (x = 0; x < M; x++) {
            int ex_x = sx + x - 1, ex_y = sy + y - 1;
            pl->merger.new_m[y * M + x] =
                (ex_x >= 0 && ex_y >= 0 && ex_x < exr->width && ex_y < exr->height)
                    ? TS_PIX(exr, ex_x, ex_y)
                    : NAN;
        }
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            pl->src_x[y * P + x] = sx + x;
            pl->src_y[y * P + x] = sy + y;
        }
    return ts__merger_apply(pl->ctx, &pl->merger, pl->out, pl->flags, q->x, q->y, pl->target,
                            pl->best_labels, pl->maps, e, pl->src_x, pl->src_y, index);
}

typedef struct cut_job {
    placer *pl;
    int wx, wy;        /* the window in the output */
    const int *to_cut; /* the candidates to cut: to_cut[b..e) */
    const int *cand_ex;
    double *cost;
    ts_status *status;
    int n_known;
} cut_job;

/* Graph cuts of candidates [b, e): each has its own window, labels and a
 * private context, so they run in parallel. */
static void place_cut_range(void *arg, size_t b, size_t e)
{
    cut_job *j = arg;
    placer *pl = j->pl;
    int P = pl->P;
    ts_ctx *c = ts__ctx_child(pl->ctx);
    size_t t;
    for (t = b; t < e; t++) {
        size_t i = (size_t)j->to_cut[t];
        float *win = pl->cand_patch + i * (size_t)P * P;
        unsigned char *lab = pl->labels + i * (size_t)P * P;
        ts_raster old = ts_raster_wrap(pl->target, P, P, P);
        ts_raster patch = ts_raster_wrap(win, P, P, P);
        double cg = 0.0;
        int cuts;
        if (!c) {
            j->status[i] = TS_ERR_NOMEM;
            continue;
        }
        if (ts__cancelled(c)) {
            j->status[i] = TS_ERR_CANCELLED; /* the caller reports it */
            continue;
        }
        /* win holds the candidate's window already (place_one) */
        j->status[i] = ts_seam_graphcut(c, &old, &patch, pl->constraint, lab, &cg);
        if (j->status[i] != TS_OK)
            continue;
        cuts = ts__label_cut_edges(lab, P);
        j->cost[i] = sqrt(pl->cands[i].ssd / j->n_known + pl->cand_u[i]) +
                     pl->p->s.alpha_g * cg / (2.0 * TS_MAX(1, cuts)) + pl->cand_h[i];
    }
    ts_ctx_free(c);
}

/* The exemplar the region at the window's centre takes, or -1 for any. */
static int place_region_exemplar(const placer *pl, const placement *q)
{
    int cx = q->x + pl->P / 2, cy = q->y + pl->P / 2, e;
    if (!pl->p->cell_exemplar)
        return -1;
    e = pl->p->cell_exemplar[(size_t)cy * (size_t)pl->out->width + (size_t)cx];
    return (e >= 0 && e < pl->n_ex) ? e : -1;
}

/* Candidate windows for the first patch. */
#define PLACE_START 15
typedef struct place_start {
    int e, x, y, order;
    float relief;
} place_start;

static int place_start_cmp(const void *a, const void *b)
{
    const place_start *p = a, *q = b;
    if (p->relief != q->relief)
        return p->relief < q->relief ? -1 : 1;
    return (p->order > q->order) - (p->order < q->order);
}

/* Highest minus lowest cell of a nodata-free P x P window. */
static float place_relief(const ts_raster *r, int x0, int y0, int P)
{
    float lo = INFINITY, hi = -INFINITY;
    int x, y;
    for (y = y0; y < y0 + P; y++)
        for (x = x0; x < x0 + P; x++) {
            float v = TS_PIX(r, x, y);
            lo = v < lo ? v : lo;
            hi = v > hi ? v : hi;
        }
    return hi - lo;
}

/* Record at q what was placed there. */
static void place_record(placement *q, int e, int sx, int sy)
{
    q->src_e = e;
    q->src_dx = sx - q->x;
    q->src_dy = sy - q->y;
}

/* Place one patch at q: the first ever (nothing to match) is random. */
static ts_status place_one(placer *pl, placement *q, int index)
{
    ts_ctx *ctx = pl->ctx;
    int P = pl->P, x, y, n_known = 0, e, i, total = 0, best = -1, W = pl->out->width;
    int *cand_ex;
    double *cost, best_cost = INFINITY, t0 = 0;
    ts_status *status;
    ts_status st = TS_OK;
    /* away from the sketch's features, windows without main features */
    int restrict_features =
        pl->p->exemplar_features && !place_flag(pl, q->x + P / 2, q->y + P / 2, TS__CELL_FEATURE);
    /* each placement's random stream depends only on the seed and its
     * index, so placements running side by side draw what they would alone */
    pl->rng = pl->rng0 ^ (0xd1b54a32d192ed03ull * (uint64_t)(index + 1));
    /* target window and the graph-cut constraints */
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++) {
            int ox = q->x + x, oy = q->y + y;
            float v = TS_PIX(pl->out, ox, oy);
            unsigned char c = TS_SEAM_FREE;
            pl->target[y * P + x] = v;
            pl->mtarget[y * P + x] = v;
            /* height constraints take part in the matching where nothing is placed */
            if (isnan(v) && pl->p->heights && pl->p->alpha_h > 0)
                pl->mtarget[y * P + x] = pl->p->heights[(size_t)oy * (size_t)W + (size_t)ox];
            if (isnan(pl->mtarget[y * P + x]) && pl->p->guide && pl->p->alpha_r > 0)
                pl->mtarget[y * P + x] = pl->p->guide[(size_t)oy * (size_t)W + (size_t)ox];
            if (!isnan(pl->mtarget[y * P + x]))
                pl->known[n_known++] = y * P + x;
            if (!isnan(v)) {
                if (ts__border_keeps_old(pl->out, q->x, q->y, P, x, y))
                    c = TS_SEAM_OLD;
            }
            /* keep_nodata cells take the patch in the cut (there is nothing
             * old there) but are never written */
            if (!isnan(v) && place_flag(pl, ox, oy, TS_CELL_FIXED))
                c = TS_SEAM_OLD;
            pl->constraint[y * P + x] = c;
        }
    /* the seam is sought in a band of `overlap` cells around what this
     * patch fills: placed cells farther away keep what they have (where
     * feature patches cover most of the window, the cut and the Poisson
     * seam removal stay near the gap instead of reworking the features'
     * flanks) */
    {
        int ov = (int)pl->p->s.overlap.value;
        for (y = 0; y < P; y++)
            for (x = 0; x < P; x++)
                pl->near[y * P + x] = (isnan(pl->target[y * P + x]) &&
                                       !place_flag(pl, q->x + x, q->y + y, TS_CELL_NODATA))
                                          ? 0
                                          : 2 * P;
        ts__chamfer_chebyshev(pl->near, P);
        for (i = 0; i < P * P; i++)
            if (!isnan(pl->target[i]) && pl->near[i] > ov)
                pl->constraint[i] = TS_SEAM_OLD;
    }
    pl->n_tknown[0] = n_known;
    cand_ex = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *cand_ex);
    cost = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *cost);
    status = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *status);
    if (!cand_ex || !cost || !status) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    if (n_known == 0) {
        /* nothing to match: a typical window to start from, the one of
         * median relief among PLACE_START random nodata-free windows, so a
         * rare corner (a flat valley floor in a mountain DEM) does not seed
         * the whole terrain */
        int tries, n_ok = 0, only = place_region_exemplar(pl, q);
        place_start found[PLACE_START];
        for (tries = 0; tries < 100000 && n_ok < PLACE_START; tries++) {
            exemplar_data *ed;
            e = only >= 0 ? only : (int)(place_rand(pl) % (uint64_t)pl->n_ex);
            ed = &pl->ex[e];
            x = (int)(place_rand(pl) % (uint64_t)(ed->full->width - P + 1));
            y = (int)(place_rand(pl) % (uint64_t)(ed->full->height - P + 1));
            if (sat_sum(ed->nodata_sat, ed->full->width, x, y, x + P, y + P) == 0 &&
                !(restrict_features && ed->allowed &&
                  place_feature_count(pl, ed, x, y) > ed->feature_limit)) {
                found[n_ok].e = e;
                found[n_ok].x = x;
                found[n_ok].y = y;
                found[n_ok].relief = place_relief(ed->full, x, y, P);
                found[n_ok].order = n_ok;
                n_ok++;
            }
        }
        if (n_ok == 0) {
            st = ts__fail(ctx, TS_ERR_NUMERIC, "synth", "no exemplar window free of nodata");
            goto done;
        }
        qsort(found, (size_t)n_ok, sizeof *found, place_start_cmp);
        e = found[n_ok / 2].e;
        x = found[n_ok / 2].x;
        y = found[n_ok / 2].y;
        place_copy_patch(pl, pl->ex[e].full, x, y);
        for (i = 0; i < P * P; i++)
            pl->best_labels[i] = isnan(pl->target[i]);
        place_record(q, e, x, y);
        st = place_merge(pl, q, e, x, y, index);
        goto done;
    }
    /* k candidates per exemplar, pooled */
    t0 = ts__now();
    for (e = 0; e < pl->n_ex; e++) {
        int n = 0, only = place_region_exemplar(pl, q);
        if (only >= 0 && e != only)
            continue;
        ts__matcher_restrict(pl->ex[e].matcher, restrict_features);
        st = place_search(pl, e, pl->cands + total, &n);
        if (st != TS_OK)
            goto done;
        for (i = 0; i < n; i++)
            cand_ex[total + i] = e;
        total += n;
    }
    if (total == 0) {
        st = ts__fail(ctx, TS_ERR_NUMERIC, "synth", "no exemplar window matches");
        goto done;
    }
    if (pl->maps)
        place_tick(pl, &pl->sec[0], &t0);
    /* graph cut each (in parallel); cost = RMS of the SSD + alpha_g * mean
     * mismatch across the seam + height costs.  The RMS of the SSD plus the
     * height costs is a lower bound of the cost, so after the most promising candidates
     * (one per thread) the others are cut only if that bound is within
     * (1 + variety) of the best cost so far: a candidate left out could be
     * neither the best nor in the variety pick, so the choice is the same as
     * cutting them all. */
    {
        cut_job job;
        int n_first = TS_MIN(total, ts__thread_count(ctx, (size_t)total)), n_to_cut = 0, w;
        double *lb = pl->cand_lb;
        job.pl = pl;
        job.cand_ex = cand_ex;
        job.cost = cost;
        job.status = status;
        job.n_known = n_known;
        job.wx = q->x;
        job.wy = q->y;
        job.to_cut = pl->to_cut;
        for (i = 0; i < total; i++) {
            const ts_raster *exr = pl->ex[cand_ex[i]].full;
            float *win = pl->cand_patch + (size_t)i * (size_t)P * P;
            for (y = 0; y < P; y++)
                for (x = 0; x < P; x++)
                    win[y * P + x] = TS_PIX(exr, pl->cands[i].x + x, pl->cands[i].y + y);
            pl->cand_h[i] = ts__height_cost(pl->p, W, q->x, q->y, P, win, P);
            pl->cand_u[i] = place_usage_of(pl, &pl->ex[cand_ex[i]], pl->cands[i].x, pl->cands[i].y);
            lb[i] = sqrt(pl->cands[i].ssd / n_known + pl->cand_u[i]) + pl->cand_h[i];
            cost[i] = INFINITY;
            status[i] = TS_OK;
            pl->to_cut[i] = i;
        }
        /* the n_first lowest bounds first (a partial selection sort: ties
         * by index, so the order is deterministic) */
        for (w = 0; w < n_first; w++) {
            int m = w, u;
            for (u = w + 1; u < total; u++)
                if (lb[pl->to_cut[u]] < lb[pl->to_cut[m]] ||
                    (lb[pl->to_cut[u]] == lb[pl->to_cut[m]] && pl->to_cut[u] < pl->to_cut[m]))
                    m = u;
            u = pl->to_cut[w];
            pl->to_cut[w] = pl->to_cut[m];
            pl->to_cut[m] = u;
        }
        for (w = 0; w < 2; w++) {
            int from = w == 0 ? 0 : n_first, to = w == 0 ? n_first : total;
            if (w == 1) {
                /* keep only those that could still matter */
                for (i = n_first, n_to_cut = n_first; i < total; i++)
                    if (lb[pl->to_cut[i]] <= best_cost * (1.0 + pl->p->s.variety))
                        pl->to_cut[n_to_cut++] = pl->to_cut[i];
                to = n_to_cut;
            }
            if (to <= from)
                continue;
            job.to_cut = pl->to_cut + from;
            ts__parallel_for(ctx, (size_t)(to - from), place_cut_range, &job);
            if ((st = ts__check_cancel(ctx)) != TS_OK)
                goto done;
            /* the best so far, lowest index on ties as when all are cut */
            best_cost = INFINITY;
            for (i = 0; i < total; i++) {
                if (status[i] != TS_OK) {
                    st = ts__fail(ctx, status[i], "synth", "graph cut failed for a candidate");
                    goto done;
                }
                if (cost[i] < best_cost) {
                    best_cost = cost[i];
                    best = i;
                }
            }
        }
    }
    /* variety: a seeded pick among the near-best */
    if (pl->p->s.variety > 0) {
        int n_ok = 0, pick;
        for (i = 0; i < total; i++)
            n_ok += cost[i] <= best_cost * (1.0 + pl->p->s.variety);
        pick = (int)(place_rand(pl) % (uint64_t)n_ok);
        for (i = 0; i < total; i++)
            if (cost[i] <= best_cost * (1.0 + pl->p->s.variety) && pick-- == 0) {
                best = i;
                break;
            }
    }
    {
        memcpy(pl->patch, pl->cand_patch + (size_t)best * P * P, (size_t)P * P * sizeof(float));
        memcpy(pl->best_labels, pl->labels + (size_t)best * P * P, (size_t)P * P);
        if (pl->maps)
            place_tick(pl, &pl->sec[1], &t0);
        if (st == TS_OK) {
            place_record(q, cand_ex[best], pl->cands[best].x, pl->cands[best].y);
            st = place_merge(pl, q, cand_ex[best], pl->cands[best].x, pl->cands[best].y, index);
        }
        if (pl->maps)
            place_tick(pl, &pl->sec[2], &t0);
    }
done:
    free(cand_ex);
    free(cost);
    free(status);
    return st;
}

static ts_status place_validate(ts_ctx *ctx, const ts_raster *ex, int n_ex,
                                const ts_synth_params *p, const ts_raster *out)
{
    int i, P, ov;
    if (!ex || n_ex < 1 || !p || !out || !out->data)
        return ts__fail(ctx, TS_ERR_ARG, "synth", "missing exemplars, parameters or output");
    if (ts_params_validate(ctx, "synth", p) != TS_OK || ts__synth_cells(ctx, p, &P, &ov) != TS_OK)
        return ctx->status;
    if (p->coarse_factor > 1 && P / p->coarse_factor < 4)
        return ts__fail(ctx, TS_ERR_ARG, "synth",
                        "patch_size %d / coarse_factor %d leaves fewer than 4 coarse cells", P,
                        p->coarse_factor);
    if (out->width < P || out->height < P)
        return ts__fail(ctx, TS_ERR_SIZE, "synth",
                        "the output (%d x %d) is smaller than a patch (%d x %d)", out->width,
                        out->height, P, P);
    for (i = 0; i < n_ex; i++)
        if (!ex[i].data || ex[i].width <= 0 || ex[i].height <= 0)
            return ts__fail_input(ctx, TS_ERR_ARG, i, "synth", "exemplar %d is empty", i + 1);
    return TS_OK;
}

static void placer_free(placer *pl)
{
    int e;
    if (pl->ex)
        for (e = 0; e < pl->n_ex; e++) {
            int k;
            ts_matcher_free(pl->ex[e].matcher);
            if (pl->shares_ex)
                continue;
            for (k = 1; k < PLACE_MAX_LEVELS; k++)
                ts_raster_free(&pl->ex[e].level[k]);
            free(pl->ex[e].nodata_sat);
            free(pl->ex[e].feature_sat);
            free(pl->ex[e].allowed);
            if (pl->ex[e].usage)
                free(pl->ex[e].usage->map);
            free(pl->ex[e].usage);
        }
    free(pl->ex);
    free(pl->target);
    free(pl->mtarget);
    {
        int k;
        for (k = 1; k < PLACE_MAX_LEVELS; k++) {
            free(pl->tlevel[k]);
            free(pl->tknown[k]);
        }
        for (k = 0; k < PLACE_MAX_LEVELS; k++)
            free(pl->toff[k]);
    }
    free(pl->patch);
    free(pl->cand_patch);
    ts__merger_free(&pl->merger);
    free(pl->src_x);
    free(pl->src_y);
    free(pl->constraint);
    free(pl->labels);
    free(pl->best_labels);
    free(pl->known);
    free(pl->near);
    free(pl->cands);
    free(pl->cand_lb);
    free(pl->cand_h);
    free(pl->cand_u);
    free(pl->to_cut);
}

/* Grow order: the queue's best (placement_queue.c); with `apart` >= 0 the
 * best of those whose windows (with their rings and the cells
 * ts__border_keeps_old reads) stay clear of position apart's. */
static int place_pick(const placer *pl, ts__pos_queue *q, const int *xs, int nx, const int *ys,
                      int ny, int apart)
{
    return ts__queue_best(q, xs, nx, ys, ny, apart, pl->P + 4);
}

/* Two placements side by side: slot i places q[i] as patch index + i. */
typedef struct pair_job {
    placer *slot[2];
    placement *q[2];
    int index;
    ts_status status[2];
} pair_job;

static void place_pair_run(void *arg, size_t b, size_t e)
{
    pair_job *j = arg;
    size_t i;
    for (i = b; i < e; i++)
        j->status[i] = place_one(j->slot[i], j->q[i], j->index + (int)i);
}

/* The work buffers of one placement slot (pl->P, p, n_ex, n_cands_cap set);
 * returns non-zero when out of memory (placer_free frees what was got). */
static int placer_alloc_work(placer *pl)
{
    size_t P2 = (size_t)pl->P * (size_t)pl->P;
    size_t nk = (size_t)pl->p->s.candidates * (size_t)pl->n_ex;
    int i, failed = 0;
    pl->target = ts__malloc_array(P2, sizeof(float));
    pl->mtarget = ts__malloc_array(P2, sizeof(float));
    for (i = 1; i < PLACE_MAX_LEVELS; i++) {
        pl->tlevel[i] = ts__malloc_array(P2, sizeof(float));
        pl->tknown[i] = ts__malloc_array(P2, sizeof(int));
        failed |= !pl->tlevel[i] || !pl->tknown[i];
    }
    for (i = 0; i < PLACE_MAX_LEVELS; i++)
        failed |= !(pl->toff[i] = ts__malloc_array(P2, sizeof(ptrdiff_t)));
    pl->patch = ts__malloc_array(P2, sizeof(float));
    pl->cand_patch = ts__malloc_array(P2 * nk, sizeof(float));
    failed |= ts__merger_init(pl->ctx, &pl->merger, pl->P, (int)pl->p->s.overlap.value) != TS_OK;
    pl->src_x = ts__malloc_array(P2, sizeof(int32_t));
    pl->src_y = ts__malloc_array(P2, sizeof(int32_t));
    pl->constraint = ts__malloc_array(P2, 1);
    pl->labels = ts__malloc_array(P2, nk);
    pl->best_labels = ts__malloc_array(P2, 1);
    pl->known = ts__malloc_array(P2, sizeof(int));
    pl->near = ts__malloc_array(P2, sizeof(int));
    pl->cands = ts__malloc_array((size_t)pl->n_cands_cap, sizeof *pl->cands);
    pl->cand_lb = ts__malloc_array((size_t)pl->n_cands_cap, sizeof *pl->cand_lb);
    pl->cand_h = ts__malloc_array((size_t)pl->n_cands_cap, sizeof *pl->cand_h);
    pl->cand_u = ts__malloc_array((size_t)pl->n_cands_cap, sizeof *pl->cand_u);
    pl->to_cut = ts__malloc_array((size_t)pl->n_cands_cap, sizeof *pl->to_cut);
    pl->tlevel[0] = pl->mtarget;
    pl->tknown[0] = pl->known;
    return failed || !pl->target || !pl->mtarget || !pl->patch || !pl->cand_patch || !pl->src_x ||
           !pl->src_y || !pl->constraint || !pl->labels || !pl->best_labels || !pl->known ||
           !pl->near || !pl->cands || !pl->cand_lb || !pl->cand_h || !pl->cand_u || !pl->to_cut;
}

/* A second slot for placements side by side: its own work buffers and
 * matchers (a matcher serves one thread at a time), the first slot's
 * exemplar levels and nodata tables. */
static ts_status placer_second(const placer *a, placer *b)
{
    int e;
    memset(b, 0, sizeof *b);
    b->ctx = a->ctx;
    b->p = a->p;
    b->out = a->out;
    b->flags = a->flags;
    b->maps = a->maps;
    b->n_ex = a->n_ex;
    b->P = a->P;
    b->rng0 = a->rng0;
    b->n_cands_cap = a->n_cands_cap;
    b->shares_ex = 1;
    b->ex = calloc((size_t)a->n_ex, sizeof *b->ex);
    if (!b->ex || placer_alloc_work(b))
        return ts__fail(a->ctx, TS_ERR_NOMEM, "synth", "out of memory");
    for (e = 0; e < a->n_ex; e++) {
        const exemplar_data *ed = &a->ex[e];
        b->ex[e] = *ed;
        b->ex[e].matcher = NULL;
        if (ts_matcher_new(a->ctx, &ed->level[ed->K], a->P >> ed->K, a->P >> ed->K,
                           &b->ex[e].matcher) != TS_OK ||
            (ed->allowed &&
             ts__matcher_set_allowed(a->ctx, b->ex[e].matcher, ed->allowed) != TS_OK))
            return a->ctx->status;
    }
    return TS_OK;
}

ts_status ts__fill_run(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars, const ts__fill *f,
                       ts_raster *out, ts_synth_maps *maps)
{
    const ts_synth_params *params = &f->s;
    placer pl, pl2;
    ts_ctx *ca = NULL, *cb = NULL;
    placement *pos = NULL;
    ts__pos_queue q;
    int *xs = NULL, *ys = NULL, nx, ny, n_pos, i, e, placed = 0, step, alloc_failed = 0;
    int n_needed = 0; /* positions still needed */
    size_t n_out;
    double t_start = ts__now();
    int first_index = maps ? maps->n_patches : 0;
    ts_status st;

    if ((st = place_validate(ctx, exemplars, n_exemplars, params, out)) != TS_OK)
        return st;
    memset(&pl, 0, sizeof pl);
    memset(&pl2, 0, sizeof pl2);
    memset(&q, 0, sizeof q);
    pl.ctx = ctx;
    pl.p = f;
    pl.out = out;
    pl.flags = f->cell_flags;
    pl.maps = maps;
    pl.n_ex = n_exemplars;
    pl.P = (int)params->patch_size.value; /* whole cells: checked by place_validate */
    pl.rng0 = ts_ctx_seed(ctx) ^ 0x5eed5eed5eedull;
    pl.n_cands_cap = 2 * (3 * params->candidates * n_exemplars + 8);
    pl.ex = calloc((size_t)n_exemplars, sizeof *pl.ex);
    alloc_failed = placer_alloc_work(&pl);
    step = pl.P - (int)params->overlap.value;
    xs = ts__malloc_array((size_t)out->width / (size_t)step + 2, sizeof *xs);
    ys = ts__malloc_array((size_t)out->height / (size_t)step + 2, sizeof *ys);
    if (alloc_failed || !pl.ex || !xs || !ys) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    n_out = (size_t)out->width * (size_t)out->height;
    if (maps) {
        size_t k;
        /* cells filled on entry keep what an earlier stage recorded */
        for (k = 0; k < n_out; k++) {
            if (!isnan(out->data[(k / (size_t)out->width) * (size_t)out->stride +
                                 k % (size_t)out->width]))
                continue;
            if (maps->source_exemplar)
                maps->source_exemplar[k] = -1;
            if (maps->source_x)
                maps->source_x[k] = -1;
            if (maps->source_y)
                maps->source_y[k] = -1;
            if (maps->order)
                maps->order[k] = -1;
            if (maps->seams)
                maps->seams[k] = 0;
        }
    }
    for (e = 0; e < n_exemplars; e++) {
        ts_progress_saved sv =
            ts__progress_push(ctx, 0.1 * e / n_exemplars, 0.1 * (e + 1) / n_exemplars);
        st = place_prepare_exemplar(&pl, &pl.ex[e], &exemplars[e], e);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK) {
            if (st == TS_ERR_SIZE || st == TS_ERR_NUMERIC)
                ts__fail_input(ctx, st, e, "synth", "exemplar %d: %s", e + 1,
                               strchr(ctx->message, ':') ? strchr(ctx->message, ':') + 2
                                                         : ctx->message);
            goto done;
        }
    }
    if (maps)
        maps->seconds_prepare += ts__now() - t_start;
    nx = place_axis(out->width, pl.P, step, xs);
    ny = place_axis(out->height, pl.P, step, ys);
    n_pos = nx * ny;
    pos = ts__malloc_array((size_t)n_pos, sizeof *pos);
    if (!pos) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    for (i = 0; i < n_pos; i++) {
        pos[i].x = xs[i % nx];
        pos[i].y = ys[i / nx];
        pos[i].src_e = -1;
        pos[i].src_dx = pos[i].src_dy = 0;
        place_count(&pl, &pos[i]);
        n_needed += pos[i].needed;
    }
    /* the grow order's queue (raster order scans: it is for comparisons) */
    if (params->order != TS_ORDER_RASTER &&
        ts__queue_init(&q, pos, n_pos, (out->width - pl.P) / 2, (out->height - pl.P) / 2) != 0) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    /* grow order places two patches at once when the best position has a
     * second one far enough away (their windows and rings disjoint): the
     * pairing depends only on the positions, so the result does not depend
     * on the thread count; two threads run a pair side by side */
    if (params->order != TS_ORDER_RASTER) {
        ts_progress_saved sv = ts__progress_push(ctx, 0.1, 0.1);
        st = placer_second(&pl, &pl2);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto done;
        ca = ts__ctx_child(ctx);
        cb = ts__ctx_child(ctx);
        if (!ca || !cb) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
            goto done;
        }
        ts_ctx_set_threads(ca, 1);
        ts_ctx_set_threads(cb, 1);
    }
    for (;;) {
        int pick = -1, pick2 = -1, j, n_run;
        if (params->order == TS_ORDER_RASTER) { /* grow and tree: the same here */
            for (j = 0; j < n_pos; j++)         /* (a scan: raster order is for comparisons) */
                if (pos[j].needed) {
                    pick = j;
                    break;
                }
        } else {
            pick = place_pick(&pl, &q, xs, nx, ys, ny, -1);
            /* a second that grows from what is placed, nearly as well */
            if (pick >= 0 && pos[pick].overlap > 0) {
                pick2 = place_pick(&pl, &q, xs, nx, ys, ny, pick);
                if (pick2 >= 0 && 2 * pos[pick2].overlap < pos[pick].overlap)
                    pick2 = -1;
            }
        }
        if (pick < 0)
            break;
        {
            /* the stages inside report at the current fraction (they can still cancel) */
            double frac;
            ts_progress_saved sv;
            frac = 0.1 + 0.9 * (double)placed / (double)(placed + n_needed);
            sv = ts__progress_push(ctx, frac, frac);
            if (pick2 < 0) {
                st = place_one(&pl, &pos[pick], placed + first_index);
            } else {
                pair_job pj;
                pj.slot[0] = &pl;
                pj.slot[1] = &pl2;
                pj.q[0] = &pos[pick];
                pj.q[1] = &pos[pick2];
                pj.index = placed + first_index;
                {
                    int side_by_side = ts__thread_count(ctx, 2) >= 2;
                    ts_ctx *used[2];
                    used[0] = side_by_side ? ca : ctx;
                    used[1] = side_by_side ? cb : ctx;
                    pl.ctx = used[0];
                    pl2.ctx = used[1];
                    if (side_by_side)
                        ts__parallel_for(ctx, 2, place_pair_run, &pj);
                    else
                        place_pair_run(&pj, 0, 2);
                    pl.ctx = ctx;
                    pl2.ctx = ctx;
                    st = TS_OK;
                    for (j = 0; j < 2 && st == TS_OK; j++) {
                        const char *msg = ts_ctx_message(used[j]);
                        if (pj.status[j] == TS_OK)
                            continue;
                        /* a private context's message moves to the caller's */
                        st = used[j] == ctx
                                 ? pj.status[j]
                                 : ts__fail(ctx, pj.status[j], "synth", "%s",
                                            strchr(msg, ':') ? strchr(msg, ':') + 2 : msg);
                    }
                }
            }
            ts__progress_pop(ctx, sv);
            if (st != TS_OK)
                goto done;
        }
        n_run = pick2 < 0 ? 1 : 2;
        placed += n_run;
        /* the usage of what was placed, after the pair (both placements
         * saw the same usage, whatever the thread count) */
        for (i = 0; i < n_run; i++) {
            const placement *w = &pos[i ? pick2 : pick];
            if (w->src_e >= 0 && pl.ex[w->src_e].usage)
                place_usage_add(pl.ex[w->src_e].usage, pl.ex[w->src_e].K, w->x + w->src_dx,
                                w->y + w->src_dy);
        }
        if (maps) {
            maps->n_patches = first_index + placed;
            maps->seconds_match += pl.sec[0] + pl2.sec[0];
            maps->seconds_cut += pl.sec[1] + pl2.sec[1];
            maps->seconds_poisson += pl.sec[2] + pl2.sec[2];
        }
        memset(pl.sec, 0, sizeof pl.sec);
        memset(pl2.sec, 0, sizeof pl2.sec);
        /* windows that intersect the new patches changed (found on the
         * position grid, not by a scan of every position) */
        for (i = 0; i < n_run; i++) {
            int w = i ? pick2 : pick, x0, x1, y0, y1, ix, iy;
            ts__axis_near(xs, nx, pos[w].x, pl.P, &x0, &x1);
            ts__axis_near(ys, ny, pos[w].y, pl.P, &y0, &y1);
            for (iy = y0; iy < y1; iy++)
                for (ix = x0; ix < x1; ix++) {
                    j = ix + nx * iy;
                    n_needed -= pos[j].needed;
                    place_count(&pl, &pos[j]);
                    n_needed += pos[j].needed;
                    ts__queue_fix(&q, j);
                }
        }
        for (i = 0; i < n_run; i++) {
            int w = i ? pick2 : pick;
            n_needed -= pos[w].needed;
            pos[w].needed = 0;
            ts__queue_fix(&q, w);
        }
        {
            st = ts__progress(ctx, 0.1 + 0.9 * (double)placed / (double)(placed + n_needed),
                              "patch placement");
            if (st != TS_OK)
                goto done;
        }
    }
    st = ts__progress(ctx, 1.0, "patch placement");
done:
    free(pos);
    ts__queue_free(&q);
    free(xs);
    free(ys);
    placer_free(&pl);
    placer_free(&pl2);
    ts_ctx_free(ca);
    ts_ctx_free(cb);
    return st;
}
