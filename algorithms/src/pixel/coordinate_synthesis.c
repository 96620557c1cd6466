/*
 * coordinate_synthesis.c - multiresolution synthesis of exemplar
 * coordinates (Lefebvre and Hoppe 2005; Cruz et al. section II.A), coarse
 * to fine over the exemplars' Gaussian stacks:
 *
 *   level 0    every cell a usable coordinate of an exemplar chosen by a
 *              hash of its absolute position and the seed;
 *   upsample   a cell's coordinate is its parent's plus the child's offset
 *              at the level's spacing h = 2^(L-l);
 *   jitter     plus a displacement of up to `jitter` x h in each axis, from
 *              a hash of the absolute position (kept only if usable);
 *   correct    `passes` passes of 4 sub-passes (the cells of one parity of
 *              x and y each): a cell takes, among the k-coherence candidates
 *              S(p + d) - h d of its k x k neighbours (and its own), the one
 *              whose k x k neighbourhood in the level's stack is nearest
 *              (sum of squared differences, in the appearance space, plus
 *              our roughness term where the guide does not steer:
 *              appearance_space.c) to the heights its neighbours'
 *              coordinates give.  Each sub-pass reads the state before it,
 *              so the result does not depend on the order or the threads.
 *
 * The heights: not the finest level's exemplar heights (a seam between two
 * coherent regions would step by the whole height difference) but the sum
 * over the levels of each level's band (its stack level less the coarser
 * one), read at the cell's own place in the frames of the four level cells
 * around it and blended with smoothstep weights: where they agree, the sum
 * is the exemplar's height there; across a seam each band blends.  (Our
 * reconstruction, named as such: the papers copy the finest level's
 * colours.)
 *
 * Every cell is a function of the seed and its absolute position: a window
 * is computed on its own, with at each level the margin the corrections
 * read (passes x 4 x k/2 cells) and its parents' cover, and equals the same
 * window of any larger run byte for byte.
 *
 * The exemplars are analysed by exemplar_analysis.c (ts_pixel_prepare),
 * the guide's levels made by guide_stack.c (ts_pixel_guide_prepare).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "pixel.h"

uint64_t ts__pix_hash(int64_t x, int64_t y, int level, int stream, uint64_t seed)
{
    uint64_t words[4] = {(uint64_t)x, (uint64_t)y, (uint64_t)level, (uint64_t)stream};
    return ts__hash_words(seed, words, 4);
}

double ts__pix_ssd(const float *level, int width, int u, int v, int k, int h, const float *t)
{
    int r = k / 2, a, b;
    double s = 0;
    for (b = -r; b <= r; b++) {
        const float *row = level + (size_t)(v + b * h) * width + u;
        const float *tr = t + (size_t)(b + r) * k + r;
        for (a = -r; a <= r; a++) {
            double d = (double)tr[a] - row[a * h];
            s += d * d;
        }
    }
    return s;
}

/* [x0, x1) x [y0, y1) of absolute cells of a level. */
typedef struct pix_region {
    int64_t x0, y0, x1, y1;
} pix_region;

static int64_t floor_half(int64_t a)
{
    return a >= 0 ? a / 2 : -((-a + 1) / 2);
}

static pix_region grow(pix_region r, int64_t m)
{
    pix_region g = {r.x0 - m, r.y0 - m, r.x1 + m, r.y1 + m};
    return g;
}

static pix_region parent_cover(pix_region r)
{
    pix_region p = {floor_half(r.x0), floor_half(r.y0), floor_half(r.x1 - 1) + 1,
                    floor_half(r.y1 - 1) + 1};
    return p;
}

/* The coordinates of a level over a region. */
typedef struct pix_level {
    pix_region reg;
    int w, h;
    pix_coord *s, *tmp;
    float *hc; /* the level's heights at s (the corrections' targets read them k x k times) */
} pix_level;

typedef struct corr_job {
    const ts_pixel_exemplars *ex;
    pix_level *lv;
    int l, hsp, k, px, py;
    const ts_pixel_guide *guide;
    double gw; /* the guide's weight (0: the level is not steered) */
    int add;   /* TS_GUIDE_ADD: the guide's band of the level added (levels >= 1) */
    int fail;
} corr_job;

/* The guide at level l, cell (ax, ay) of the level (spacing hsp output
 * cells): the blurred guide at the cell's centre, the nearest guide cell
 * past its edge. */
static float guide_at(const ts_pixel_guide *g, int l, int hsp, int64_t ax, int64_t ay)
{
    int64_t x = ax * hsp + hsp / 2, y = ay * hsp + hsp / 2;
    x = x < 0 ? 0 : x >= g->width ? g->width - 1 : x;
    y = y < 0 ? 0 : y >= g->height ? g->height - 1 : y;
    return g->level[l][(size_t)y * g->width + (size_t)x];
}

/* The cell of exemplar w x h's copy turned by q quarter turns (counter-
 * clockwise), mirrored left-right first when `mirror`, that the exemplar's
 * cell (sx, sy) goes to. */
static void turned_target(int w, int h, int q, int mirror, int sx, int sy, int *x, int *y)
{
    if (mirror)
        sx = w - 1 - sx;
    switch (q) {
    case 0:
        *x = sx, *y = sy;
        break;
    case 1:
        *x = sy, *y = w - 1 - sx;
        break;
    case 2:
        *x = w - 1 - sx, *y = h - 1 - sy;
        break;
    default:
        *x = h - 1 - sy, *y = sx;
        break;
    }
}

/* Where coordinate c (in its candidate's frame) lies in its exemplar's
 * stack; -1 past the edge.  The turned and mirrored candidates are the
 * exemplar's stack read turned: a Gaussian blur and the usable test are
 * symmetric under these turns, so they need no stacks of their own. */
static inline ptrdiff_t cell_of(const ts_pixel_exemplars *ex, pix_coord c)
{
    const pix_turn *t = &ex->turn[c.e];
    if (c.u < 0 || c.v < 0 || c.u >= t->w || c.v >= t->h)
        return -1;
    return (ptrdiff_t)(t->oy + t->myu * c.u + t->myv * c.v) * t->sw + t->ox + t->mxu * c.u +
           t->mxv * c.v;
}

float ts__pix_candidate_height(const ts_pixel_exemplars *ex, int l, int e, int u, int v)
{
    pix_coord c = {e, u, v};
    ptrdiff_t i = cell_of(ex, c);
    return i < 0 ? NAN : ex->stacks[e / ex->nv].level[l][i];
}

int ts__pix_candidate_usable(const ts_pixel_exemplars *ex, int l, int e, int u, int v)
{
    pix_coord c = {e, u, v};
    ptrdiff_t i = cell_of(ex, c);
    return i >= 0 && ex->stacks[e / ex->nv].usable[l][i];
}

static int usable(const ts_pixel_exemplars *ex, int l, pix_coord c)
{
    return ts__pix_candidate_usable(ex, l, c.e, c.u, c.v);
}

/* The stack cell of c, c clamped to its candidate's edges first. */
static ptrdiff_t clamped_cell(const ts_pixel_exemplars *ex, pix_coord c)
{
    const pix_turn *t = &ex->turn[c.e];
    c.u = c.u < 0 ? 0 : c.u >= t->w ? t->w - 1 : c.u;
    c.v = c.v < 0 ? 0 : c.v >= t->h ? t->h - 1 : c.v;
    return cell_of(ex, c);
}

/* Level l at c, clamped. */
static float height_at(const ts_pixel_exemplars *ex, int l, pix_coord c)
{
    return ex->stacks[c.e / ex->nv].level[l][clamped_cell(ex, c)];
}

/* Level l's band at c (the level less the coarser one; level 0 itself), clamped. */
static double band_at(const ts_pixel_exemplars *ex, int l, pix_coord c)
{
    const pix_stack *s = &ex->stacks[c.e / ex->nv];
    ptrdiff_t i = clamped_cell(ex, c);
    return l ? (double)s->level[l][i] - s->level[l - 1][i] : (double)s->level[0][i];
}

/* The squared distance between the appearance vector at (of the target
 * turned back into the exemplar's frame) and usable coordinate c's at level l,
 * over their first nd values (all, or all but the roughness). */
static double app_distance(const ts_pixel_exemplars *ex, int l, pix_coord c, const float *at,
                           int nd)
{
    const pix_stack *s = &ex->stacks[c.e / ex->nv];
    int dim = ex->dim[l], i;
    const float *a = s->app[l] + (size_t)cell_of(ex, c) * (size_t)dim;
    float d = 0;
    for (i = 0; i < nd; i++) {
        float e = at[i] - a[i];
        d += e * e;
    }
    return d;
}

/* The appearance vector of target t turned back for variant v (into at's
 * slot v, marked in have), ending with the roughness tr where there is one. */
static const float *target_turned(const ts_pixel_exemplars *ex, int l, const float *t, float tr,
                                  float *tv, const int *perm, int v, int *have, float *at)
{
    int k = ex->kl[l], i, dim = ex->dim[l];
    for (i = 0; i < k * k; i++)
        tv[perm[v * k * k + i]] = t[i];
    ts__pix_appearance(ex->basis[l], dim - 1 - (ex->rough > 0), k, tv, at + (size_t)v * dim);
    if (ex->rough > 0)
        at[(size_t)v * dim + dim - 1] = tr;
    have[v] = 1;
    return at + (size_t)v * dim;
}

/* One sub-pass on the rows [begin, end) of the level's region: new values
 * into tmp for the cells of parity (px, py) whose neighbourhood lies in the
 * region. */
static void correct_rows(void *arg, size_t begin, size_t end)
{
    corr_job *j = arg;
    pix_level *lv = j->lv;
    int k = j->k, r = k / 2, hsp = j->hsp, l = j->l, x, dim = j->ex->dim[l], nv = j->ex->nv;
    int K1 = j->ex->coherence - 1;
    /* the values compared: all, or all but the roughness where the guide steers (a guide's
     * pull is smooth between its lines: the term would fight it) */
    int nd = dim - (j->ex->rough > 0 && j->guide && j->gw > 0);
    int v, have[8], *perm = malloc((size_t)nv * (size_t)k * k * sizeof *perm);
    float *t = malloc(((size_t)k * k * 2 + (size_t)nv * dim) * sizeof *t), *tv = t + k * k;
    float *at = tv + k * k;
    size_t y;
    if (!t || !perm) {
        free(t);
        free(perm);
        j->fail = 1;
        return;
    }
    /* perm[v]: where each cell of a target neighbourhood lands in exemplar's frame when
     * compared with candidate variant v (|R N - t| = |N - R^-1 t|) */
    for (v = 0; v < nv; v++) {
        int a, b, sa, sb;
        for (b = -r; b <= r; b++)
            for (a = -r; a <= r; a++) {
                /* the turn's linear part: an offset of the candidate as one of the exemplar */
                const pix_turn *tn = &j->ex->turn[v];
                sa = tn->mxu * a + tn->mxv * b;
                sb = tn->myu * a + tn->myv * b;
                perm[(v * k + b + r) * k + a + r] = (sb + r) * k + sa + r;
            }
    }
    for (y = begin; y < end; y++) {
        int64_t ay = lv->reg.y0 + (int64_t)y;
        if ((ay & 1) != j->py)
            continue;
        for (x = 0; x < lv->w; x++) {
            int64_t ax = lv->reg.x0 + x;
            pix_coord cur = lv->s[y * (size_t)lv->w + x], best = cur;
            double bc;
            float tr;
            int a, b;
            if ((ax & 1) != j->px)
                continue;
            if (x < r || x + r >= lv->w || (int)y < r || (int)y + r >= lv->h)
                continue; /* at the region's edge: outside every exact window */
            if (!K1) {    /* every candidate the cell's own (a coherent region): it stays */
                int other = 0;
                for (b = -r; b <= r && !other; b++)
                    for (a = -r; a <= r; a++) {
                        pix_coord n = lv->s[(y + b) * (size_t)lv->w + x + a];
                        if (n.e != cur.e || n.u - a * hsp != cur.u || n.v - b * hsp != cur.v) {
                            other = 1;
                            break;
                        }
                    }
                if (!other) {
                    lv->tmp[y * (size_t)lv->w + x] = cur;
                    continue;
                }
            }
            for (b = -r; b <= r; b++)
                for (a = -r; a <= r; a++) {
                    float hv = lv->hc[(y + b) * (size_t)lv->w + x + a];
                    if (j->guide && j->gw > 0) {
                        float gv = guide_at(j->guide, l, hsp, ax + a, ay + b);
                        if (j->add && l > 0) { /* + the guide's band of this level */
                            float gc = guide_at(j->guide, l - 1, hsp, ax + a, ay + b);
                            if (!isnan(gv) && !isnan(gc))
                                hv += gv - gc;
                        } else if (!isnan(gv))
                            hv = (float)((1.0 - j->gw) * hv + j->gw * gv);
                    }
                    t[(b + r) * k + a + r] = hv;
                }
            if (nd < dim || !(j->ex->rough > 0))
                tr = 0;
            else { /* the roughness of the heights the neighbours' coordinates give */
                for (b = -r; b <= r; b++)
                    for (a = -r; a <= r; a++)
                        tv[(b + r) * k + a + r] = lv->hc[(y + b) * (size_t)lv->w + x + a];
                tr = j->ex->rough * ts__pix_roughness(k, tv);
            }
            memset(have, 0, sizeof have);
#define TARGET_FOR(cand)                                                                           \
    (v = (cand).e % nv,                                                                            \
     have[v] ? at + (size_t)v * dim : target_turned(j->ex, l, t, tr, tv, perm, v, have, at))
            bc =
                usable(j->ex, l, cur) ? app_distance(j->ex, l, cur, TARGET_FOR(cur), nd) : INFINITY;
            for (b = -r; b <= r; b++)
                for (a = -r; a <= r; a++) {
                    pix_coord n = lv->s[(y + b) * (size_t)lv->w + x + a], c = n;
                    double cost;
                    int i;
                    c.u -= a * hsp;
                    c.v -= b * hsp;
#define SAME(p, q) ((p).e == (q).e && (p).u == (q).u && (p).v == (q).v)
                    /* in a coherent region most candidates are the cell's own coordinate */
                    if ((a || b) && !SAME(c, cur) && !SAME(c, best) && usable(j->ex, l, c)) {
                        cost = app_distance(j->ex, l, c, TARGET_FOR(c), nd);
                        if (cost < bc) {
                            bc = cost;
                            best = c;
                        }
                    }
                    /* the neighbour's similarity set, shifted alike (k-coherence) */
                    for (i = 0; i < K1; i++) {
                        const pix_stack *ns = &j->ex->stacks[n.e / nv];
                        int32_t id = ns->sim[l][(size_t)cell_of(j->ex, n) * K1 + i], cell;
                        int e2, q = n.e % nv;
                        if (id < 0)
                            break;
                        ts__pix_similar(j->ex, id, &e2, &cell);
                        ns = &j->ex->stacks[e2];
                        c.e = e2 * nv + q;
                        turned_target(ns->width, ns->height, j->ex->vturn[q], j->ex->vmirror[q],
                                      cell % ns->width, cell / ns->width, &c.u, &c.v);
                        c.u -= a * hsp;
                        c.v -= b * hsp;
                        if (SAME(c, cur) || SAME(c, best) || !usable(j->ex, l, c))
                            continue;
                        cost = app_distance(j->ex, l, c, TARGET_FOR(c), nd);
                        if (cost < bc) {
                            bc = cost;
                            best = c;
                        }
                    }
                }
            lv->tmp[y * (size_t)lv->w + x] = best;
        }
    }
#undef TARGET_FOR
#undef SAME
    free(t);
    free(perm);
}

static void height_rows(void *arg, size_t begin, size_t end)
{
    corr_job *j = arg;
    pix_level *lv = j->lv;
    size_t i;
    for (i = begin * (size_t)lv->w; i < end * (size_t)lv->w; i++)
        lv->hc[i] = height_at(j->ex, j->l, lv->s[i]);
}

static void commit_rows(void *arg, size_t begin, size_t end)
{
    corr_job *j = arg;
    pix_level *lv = j->lv;
    int r = j->k / 2, x;
    size_t y;
    for (y = begin; y < end; y++) {
        int64_t ay = lv->reg.y0 + (int64_t)y;
        if ((ay & 1) != j->py || (int)y < r || (int)y + r >= lv->h)
            continue;
        for (x = r; x + r < lv->w; x++)
            if (((lv->reg.x0 + x) & 1) == j->px)
                lv->s[y * (size_t)lv->w + x] = lv->tmp[y * (size_t)lv->w + x];
    }
}

/* A usable coordinate chosen by the hash h. */
static pix_coord random_coord(const ts_pixel_exemplars *ex, int l, uint64_t h)
{
    pix_coord c;
    const pix_stack *s;
    int32_t idx;
    c.e = (int32_t)(h % (uint64_t)ex->n);
    s = &ex->stacks[c.e / ex->nv];
    idx = s->usable_list[l][(h >> 20) % s->n_usable[l]];
    turned_target(s->width, s->height, ex->vturn[c.e % ex->nv], ex->vmirror[c.e % ex->nv],
                  idx % s->width, idx / s->width, &c.u, &c.v);
    return c;
}

/* In exemplar candidate e (chosen by the hash h), one of the 16 usable cells
 * of level 0 whose ranks in height lie around rank i (chosen by h too). */
static pix_coord by_height_pick(const ts_pixel_exemplars *ex, int32_t e, size_t i, uint64_t h)
{
    pix_coord c;
    const pix_stack *s = &ex->stacks[e / ex->nv];
    size_t n = s->n_usable[0], pick;
    c.e = e;
    i = i >= 8 ? i - 8 : 0;
    if (i + 16 > n)
        i = n > 16 ? n - 16 : 0;
    pick = i + (size_t)((h >> 24) % (uint64_t)(n - i < 16 ? n - i : 16));
    turned_target(s->width, s->height, ex->vturn[e % ex->nv], ex->vmirror[e % ex->nv],
                  s->by_height[pick] % s->width, s->by_height[pick] / s->width, &c.u, &c.v);
    return c;
}

/* With a guide, level 0 starts from coordinates of the guide's heights: in
 * an exemplar chosen by the hash, one of the 16 usable cells of level 0
 * nearest in height to g (chosen by the hash too). */
static pix_coord guided_coord(const ts_pixel_exemplars *ex, float g, uint64_t h)
{
    int32_t e = (int32_t)(h % (uint64_t)ex->n);
    const pix_stack *s = &ex->stacks[e / ex->nv];
    size_t lo = 0, hi = s->n_usable[0];
    while (lo < hi) { /* the first cell not below g */
        size_t mid = lo + (hi - lo) / 2;
        if (s->level[0][s->by_height[mid]] < g)
            lo = mid + 1;
        else
            hi = mid;
    }
    return by_height_pick(ex, e, lo, h);
}

/* Without a guide (the relief start, relief_start.c): the same around rank
 * q in [0, 1] of the exemplar's level-0 heights. */
static pix_coord relief_coord(const ts_pixel_exemplars *ex, double q, uint64_t h)
{
    int32_t e = (int32_t)(h % (uint64_t)ex->n);
    return by_height_pick(ex, e, (size_t)(q * (double)ex->stacks[e / ex->nv].n_usable[0]), h);
}

static int level_alloc(pix_level *lv, pix_region reg)
{
    lv->reg = reg;
    lv->w = (int)(reg.x1 - reg.x0);
    lv->h = (int)(reg.y1 - reg.y0);
    lv->s = ts__malloc_array((size_t)lv->w * (size_t)lv->h, sizeof *lv->s);
    lv->tmp = ts__malloc_array((size_t)lv->w * (size_t)lv->h, sizeof *lv->tmp);
    lv->hc = ts__malloc_array((size_t)lv->w * (size_t)lv->h, sizeof *lv->hc);
    return lv->s && lv->tmp && lv->hc ? 0 : -1;
}

static void level_free(pix_level *lv)
{
    free(lv->s);
    free(lv->tmp);
    free(lv->hc);
    lv->s = lv->tmp = NULL;
    lv->hc = NULL;
}

static ts_status pix_run(ts_ctx *ctx, const ts_pixel_exemplars *ex, const ts_pixel_guide *guide,
                         const ts_pixel_params *params, int k, int64_t x0, int64_t y0,
                         ts_raster *out, const ts_pixel_sources *src);

TS_API ts_status ts_pixel_synthesize(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                     const ts_pixel_params *params, int64_t x0, int64_t y0,
                                     ts_raster *out)
{
    return pix_run(ctx, ex, NULL, params, 0, x0, y0, out, NULL);
}

TS_API ts_status ts_pixel_synthesize_guided(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                            const ts_pixel_guide *guide,
                                            const ts_pixel_params *params, int64_t x0, int64_t y0,
                                            ts_raster *out)
{
    ts__clear(ctx);
    if (!guide || (ex && guide->levels != ex->levels))
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "the guide was prepared for other stacks");
    return pix_run(ctx, ex, guide, params, 0, x0, y0, out, NULL);
}

TS_API ts_status ts_pixel_synthesize_sources(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                             const ts_pixel_guide *guide,
                                             const ts_pixel_params *params, int64_t x0, int64_t y0,
                                             ts_raster *out, const ts_pixel_sources *src)
{
    ts__clear(ctx);
    if (guide && ex && guide->levels != ex->levels)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "the guide was prepared for other stacks");
    return pix_run(ctx, ex, guide, params, 0, x0, y0, out, src);
}

TS_API ts_status ts_pixel_synthesize_overview(ts_ctx *ctx, const ts_pixel_exemplars *ex,
                                              const ts_pixel_guide *guide,
                                              const ts_pixel_params *params, int k, int64_t x0,
                                              int64_t y0, ts_raster *out)
{
    ts__clear(ctx);
    if (guide && ex && guide->levels != ex->levels)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "the guide was prepared for other stacks");
    if (ex && (k < 1 || k > ex->levels))
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "an overview of 2^%d: the stacks have %d levels",
                        k, ex->levels);
    return pix_run(ctx, ex, guide, params, k, x0, y0, out, NULL);
}

/* What a level's initialisation and the output's rows read. */
typedef struct run_job {
    const ts_pixel_exemplars *ex;
    const ts_pixel_guide *guide;
    const ts_pixel_params *params;
    pix_coord **coords;
    const pix_region *pre;
    pix_level *lv;
    ts_raster *out;
    int l, L, hsp;
    double jit;
    uint64_t seed;
    int64_t x0, y0, M;
    const ts_pixel_sources *src;
    double relief_scale; /* the relief start's lattice spacing (level 0) */
    int relief;          /* level 0 from the relief start */
    int top, k;          /* the output: levels 0..top summed, cells of 2^k output cells */
} run_job;

/* Rows [begin, end) of level l: level 0 from the hash (or the guide), finer
 * levels from the parent's coordinate upsampled and jittered. */
static void init_rows(void *arg, size_t begin, size_t end)
{
    run_job *j = arg;
    const ts_pixel_exemplars *ex = j->ex;
    const ts_pixel_guide *guide = j->guide;
    const ts_pixel_params *params = j->params;
    pix_coord **coords = j->coords;
    const pix_region *pre = j->pre;
    pix_level cur = *j->lv;
    int l = j->l, hsp = j->hsp, x;
    double jit = j->jit;
    uint64_t seed = j->seed;
    size_t y;
    for (y = begin; y < end; y++)
        for (x = 0; x < cur.w; x++) {
            int64_t ax = cur.reg.x0 + x, ay = cur.reg.y0 + y;
            pix_coord c;
            if (l == 0) {
                float gv = guide ? guide_at(guide, 0, hsp, ax, ay) : NAN;
                uint64_t h0 = ts__pix_hash(ax, ay, 0, 0, seed);
                if (!isnan(gv) && params->guide_weight > 0)
                    c = guided_coord(ex, gv, h0);
                else if (j->relief)
                    c = relief_coord(ex,
                                     ts__pix_relief_rank(&ex->relief, j->relief_scale,
                                                         ((double)ax + 0.5) * hsp,
                                                         ((double)ay + 0.5) * hsp, seed),
                                     h0);
                else
                    c = random_coord(ex, 0, h0);
            } else {
                int64_t qx = floor_half(ax), qy = floor_half(ay);
                pix_coord j;
                uint64_t hh = ts__pix_hash(ax, ay, l, 1, seed);
                double ju = ((double)(hh & 0xffffff) / 16777215.0) * 2 - 1;
                double jv = ((double)((hh >> 24) & 0xffffff) / 16777215.0) * 2 - 1;
                c = coords[l - 1]
                          [(size_t)(qy - pre[l - 1].y0) * (size_t)(pre[l - 1].x1 - pre[l - 1].x0) +
                           (size_t)(qx - pre[l - 1].x0)];
                c.u += (int32_t)((ax - 2 * qx) * hsp);
                c.v += (int32_t)((ay - 2 * qy) * hsp);
                j = c;
                j.u += (int32_t)lround(jit * hsp * ju);
                j.v += (int32_t)lround(jit * hsp * jv);
                if (usable(ex, l, j))
                    c = j;
                else if (!usable(ex, l, c))
                    c = random_coord(ex, l, ts__pix_hash(ax, ay, l, 2, seed));
            }
            cur.s[y * (size_t)cur.w + (size_t)x] = c;
        }
}

/* Rows [begin, end) of the output (and the sources' maps). */
static void output_rows(void *arg, size_t begin, size_t end)
{
    run_job *j = arg;
    const ts_pixel_exemplars *ex = j->ex;
    pix_coord **coords = j->coords;
    const pix_region *pre = j->pre;
    ts_raster *out = j->out;
    const ts_pixel_sources *src = j->src;
    int L = j->L, l, x, y, k = j->k;
    int64_t x0 = j->x0, y0 = j->y0, M = j->M, half = k ? (int64_t)1 << (k - 1) : 0;
    for (y = (int)begin; y < (int)end; y++)
        for (x = 0; x < out->width; x++) {
            double hsum = 0;
            /* the output cell, or an overview cell's middle (its level-(L - k) cell) */
            int64_t ax = (x0 + x) * ((int64_t)1 << k) + half;
            int64_t ay = (y0 + y) * ((int64_t)1 << k) + half;
            for (l = 0; l <= j->top; l++) {
                int64_t sp = (int64_t)1 << (L - l);
                double fx = ((double)ax + 0.5) / (double)sp - 0.5;
                double fy = ((double)ay + 0.5) / (double)sp - 0.5;
                int64_t qx = (int64_t)floor(fx), qy = (int64_t)floor(fy);
                double tx = fx - (double)qx, ty = fy - (double)qy, acc = 0, wsum = 0;
                int w = (int)(pre[l].x1 - pre[l].x0), a, b, nk, o;
                double wx[4], wy[4];
                if (l == 0 && j->relief) {
                    /* the relief start's level 0: coherent regions of the relief's heights,
                     * blended by a cubic B-spline over the 4 x 4 cells around (a smoothstep
                     * across the level's lattice lines drew straight scarps along them where
                     * a plain meets a massif; the weights sum to 1, so a coherent region is
                     * still the exemplar's band exactly) */
                    ts__bspline_weights(tx, wx);
                    ts__bspline_weights(ty, wy);
                    nk = 4;
                    o = -1;
                } else if (l == L) {
                    /* the finest level: a tent over the 3 x 3 cells around, each cell's
                     * coordinate saying what this cell would be (one coordinate, the cell's
                     * own, switched hard between unrelated sources: creases, 99.9th
                     * percentile |Laplacian| up to 1.33 x the exemplar's at 384^2; in a
                     * coherent region the nine agree, so it is the exemplar exactly) */
                    wx[0] = wy[0] = 0.25;
                    wx[1] = wy[1] = 0.5;
                    wx[2] = wy[2] = 0.25;
                    nk = 3;
                    o = -1;
                } else {
                    /* smoothstep weights over the 2 x 2 cells around: no crease at the
                     * cells' borders in a hillshade */
                    wx[1] = tx * tx * (3 - 2 * tx);
                    wy[1] = ty * ty * (3 - 2 * ty);
                    wx[0] = 1 - wx[1];
                    wy[0] = 1 - wy[1];
                    nk = 2;
                    o = 0;
                }
                for (b = 0; b < nk; b++)
                    for (a = 0; a < nk; a++) {
                        size_t i = (size_t)(qy + o + b - pre[l].y0) * (size_t)w +
                                   (size_t)(qx + o + a - pre[l].x0);
                        pix_coord c = coords[l][i];
                        double wgt = wx[a] * wy[b], val;
                        if (wgt == 0)
                            continue; /* (a smoothstep's zero weight) */
                        c.u = (int32_t)(c.u + (ax - (qx + o + a) * sp));
                        c.v = (int32_t)(c.v + (ay - (qy + o + b) * sp));
                        val = band_at(ex, l, c);
                        if (isnan(val))
                            continue; /* past the valid cells: the others' */
                        acc += wgt * val;
                        wsum += wgt;
                    }
                if (!(wsum > 0)) { /* all past: the nearest cell's own (always valid) */
                    size_t i = (size_t)(qy + (ty >= 0.5) - pre[l].y0) * (size_t)w +
                               (size_t)(qx + (tx >= 0.5) - pre[l].x0);
                    pix_coord c = coords[l][i];
                    acc = band_at(ex, l, c);
                    wsum = 1;
                }
                hsum += acc / wsum;
            }
            TS_PIX(out, x, y) = (float)hsum;
            if (src) { /* where the finest level's coordinate points */
                pix_coord c =
                    coords[L][(size_t)(y + M) * (size_t)(pre[L].x1 - pre[L].x0) + (size_t)(x + M)];
                size_t o = (size_t)y * (size_t)out->width + (size_t)x;
                if (src->exemplar)
                    src->exemplar[o] = c.e;
                if (src->x)
                    src->x[o] = c.u;
                if (src->y)
                    src->y[o] = c.v;
            }
        }
}

static ts_status pix_run(ts_ctx *ctx, const ts_pixel_exemplars *ex, const ts_pixel_guide *guide,
                         const ts_pixel_params *params, int k, int64_t x0, int64_t y0,
                         ts_raster *out, const ts_pixel_sources *src)
{
    int L, l, pass, sub, relief, top;
    int64_t M;
    pix_region need[12], pre[12];
    pix_level cur = {{0, 0, 0, 0}, 0, 0, NULL, NULL, NULL};
    pix_coord *coords[12] = {NULL}; /* each level's corrected coordinates over pre[l] */
    static const int order[4][2] = {{0, 0}, {1, 1}, {1, 0}, {0, 1}};
    uint64_t seed;
    ts_status st = TS_OK;
    ts__clear(ctx);
    if (!ex || !params || !out || !out->data || out->width < 1 || out->height < 1)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "missing exemplars, parameters or output");
    if (ts_params_validate(ctx, "pixel", params) != TS_OK)
        return ctx->status;
    if ((params->window && params->window != ex->window) ||
        (params->levels && params->levels != ex->levels))
        return ts__fail(ctx, TS_ERR_ARG, "pixel",
                        "the stacks were prepared for window %d and %d levels", ex->window,
                        ex->levels);
    if (params->n_jitter_levels < 0 || params->n_jitter_levels > 10)
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "at most 10 per-level jitters, not %d",
                        params->n_jitter_levels);
    for (l = 0; l < params->n_jitter_levels; l++)
        if (!(params->jitter_levels[l] >= 0 && params->jitter_levels[l] <= 2))
            return ts__fail(ctx, TS_ERR_ARG, "pixel", "per-level jitter %d is %g, not in 0..2",
                            l + 1, params->jitter_levels[l]);
    if (x0 < -((int64_t)1 << 40) || y0 < -((int64_t)1 << 40) || x0 > ((int64_t)1 << 40) ||
        y0 > ((int64_t)1 << 40))
        return ts__fail(ctx, TS_ERR_ARG, "pixel", "the window's origin is beyond 2^40 cells");
    L = ex->levels;
    top = L - k; /* an overview of 2^k stops at the level of that spacing */
    seed = ctx->seed;
    relief = (!guide || !(params->guide_weight > 0)) && params->start == TS_PIXEL_START_RELIEF;
    /* what the corrections read, and a cell more for the bands' interpolation */
    M = (int64_t)params->passes * 4 * (ex->kl[L] / 2) + 2;
    /* the regions each level computes, finest to coarsest */
    need[top].x0 = x0;
    need[top].y0 = y0;
    need[top].x1 = x0 + out->width;
    need[top].y1 = y0 + out->height;
    for (l = top; l >= 0; l--) {
        pre[l] = grow(need[l], (int64_t)params->passes * 4 * (ex->kl[l] / 2) + 2);
        if (l > 0)
            need[l - 1] = parent_cover(pre[l]);
    }
    for (l = 0; l <= top; l++) {
        int hsp = 1 << (L - l);
        double jit = params->n_jitter_levels > 0
                         ? params->jitter_levels[l - 1 < params->n_jitter_levels - 1
                                                     ? (l > 0 ? l - 1 : 0)
                                                     : params->n_jitter_levels - 1]
                         : params->jitter;
        if (level_alloc(&cur, pre[l]) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory for level %d", l);
            goto done;
        }
        /* initialise (level 0) or upsample and jitter */
        {
            run_job rj = {ex,
                          guide,
                          params,
                          coords,
                          pre,
                          &cur,
                          NULL,
                          l,
                          L,
                          hsp,
                          jit,
                          seed,
                          0,
                          0,
                          0,
                          NULL,
                          params->relief_scale > 0 ? params->relief_scale : ex->relief.scale,
                          relief,
                          top,
                          k};
            ts__parallel_for(ctx, (size_t)cur.h, init_rows, &rj);
        }
        /* correction */
        for (pass = 0; pass < params->passes; pass++)
            for (sub = 0; sub < 4; sub++) {
                corr_job j = {ex, &cur, l, hsp, ex->kl[l], order[sub][0], order[sub][1], guide,
                              /* the guide steers the levels down to guide_spacing; the
                               * finer ones take their detail from the exemplars alone */
                              hsp >= params->guide_spacing ? params->guide_weight : 0.0,
                              params->guide_mode == TS_GUIDE_ADD, 0};
                ts__parallel_for(ctx, (size_t)cur.h, height_rows, &j);
                ts__parallel_for(ctx, (size_t)cur.h, correct_rows, &j);
                if (j.fail) {
                    st = ts__fail(ctx, TS_ERR_NOMEM, "pixel", "out of memory");
                    goto done;
                }
                ts__parallel_for(ctx, (size_t)cur.h, commit_rows, &j);
            }
        if ((st = ts__check_cancel(ctx)) != TS_OK)
            goto done;
        if ((st = ts__progress(ctx, (l + 1.0) / (top + 1), "synthesis")) != TS_OK)
            goto done;
        /* the level's coordinates, kept for the next level and the output's bands */
        coords[l] = cur.s;
        free(cur.tmp);
        free(cur.hc);
        cur.s = cur.tmp = NULL;
        cur.hc = NULL;
    }
    /* the window: the sum of the levels' bands (a level's stack less the coarser one),
     * each at the output cell's own place in the frames of the four level cells around
     * it (a cell's coordinate plus the cell's offset from it), weighed bilinearly: where
     * the four agree this is the exemplar's band there; across a seam between coherent
     * regions it blends, and the step is one band's, not the whole heights' */
    {
        run_job rj = {ex, guide, params, coords, pre, &cur, out, L, L, 1,  0,
                      seed, x0,  y0,    M,      src,  0,   relief, top, k};
        ts__parallel_for(ctx, (size_t)out->height, output_rows, &rj);
    }
done:
    level_free(&cur);
    for (l = 0; l < 12; l++)
        free(coords[l]);
    return st;
}
