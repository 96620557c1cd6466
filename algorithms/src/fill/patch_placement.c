/*
 * patch_placement.c - one patch of non-feature patch placement (Zhou et
 * al. 2007 section 4.2) with patch merging (section 5): the target window
 * and the seam constraints, the candidates of every exemplar
 * (candidate_search.c) each cut in with a graph cut (seam_graphcut.c), the
 * winner the lowest RMS(SSD) + alpha_g * mean seam mismatch (or a seeded
 * pick among the near-best), merged by Poisson seam removal
 * (patch_merge.c).  The first patch, with nothing to match, is a typical
 * random window.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "nonfeature_placement.h"

typedef ts__placement placement;
typedef ts__placer placer;
typedef ts__exemplar_data exemplar_data;

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
                            pl->best_labels, pl->maps, e, pl->src_x, pl->src_y,
                            pl->map_index0 + index);
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
        /* win holds the candidate's window already (place_cut_prepare) */
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

/* The target window at q and the graph-cut constraints; returns the number
 * of known cells (matched: placed, or wanted heights where empty), listed
 * in pl->known. */
static int place_target(placer *pl, const placement *q)
{
    int P = pl->P, x, y, n_known = 0, W = pl->out->width;
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
            if (!isnan(v) && ts__place_flag(pl, ox, oy, TS_CELL_FIXED))
                c = TS_SEAM_OLD;
            pl->constraint[y * P + x] = c;
        }
    return n_known;
}

/* The seam is sought in a band of `overlap` cells around what this patch
 * fills: placed cells farther away keep what they have (where feature
 * patches cover most of the window, the cut and the Poisson seam removal
 * stay near the gap instead of reworking the features' flanks). */
static void place_seam_band(placer *pl, const placement *q)
{
    int P = pl->P, x, y, i;
    int ov = (int)pl->p->s.overlap.value;
    for (y = 0; y < P; y++)
        for (x = 0; x < P; x++)
            pl->near[y * P + x] = (isnan(pl->target[y * P + x]) &&
                                   !ts__place_flag(pl, q->x + x, q->y + y, TS_CELL_NODATA))
                                      ? 0
                                      : 2 * P;
    ts__chamfer_chebyshev(pl->near, P);
    for (i = 0; i < P * P; i++)
        if (!isnan(pl->target[i]) && pl->near[i] > ov)
            pl->constraint[i] = TS_SEAM_OLD;
}

/* The first patch (nothing to match): a typical window to start from, the
 * one of median relief among PLACE_START random nodata-free windows, so a
 * rare corner (a flat valley floor in a mountain DEM) does not seed the
 * whole terrain. */
static ts_status place_start_patch(placer *pl, placement *q, int index, int restrict_features)
{
    int P = pl->P, x, y, e, i;
    int tries, n_ok = 0, only = place_region_exemplar(pl, q);
    place_start found[PLACE_START];
    for (tries = 0; tries < 100000 && n_ok < PLACE_START; tries++) {
        exemplar_data *ed;
        e = only >= 0 ? only : (int)(place_rand(pl) % (uint64_t)pl->n_ex);
        ed = &pl->ex[e];
        x = (int)(place_rand(pl) % (uint64_t)(ed->full->width - P + 1));
        y = (int)(place_rand(pl) % (uint64_t)(ed->full->height - P + 1));
        if (ts__sat_sum(ed->nodata_sat, ed->full->width, x, y, x + P, y + P) == 0 &&
            !(restrict_features && ed->allowed &&
              ts__place_feature_count(pl, ed, x, y) > ed->feature_limit)) {
            found[n_ok].e = e;
            found[n_ok].x = x;
            found[n_ok].y = y;
            found[n_ok].relief = place_relief(ed->full, x, y, P);
            found[n_ok].order = n_ok;
            n_ok++;
        }
    }
    if (n_ok == 0)
        return ts__fail(pl->ctx, TS_ERR_NUMERIC, "synth", "no exemplar window free of nodata");
    qsort(found, (size_t)n_ok, sizeof *found, place_start_cmp);
    e = found[n_ok / 2].e;
    x = found[n_ok / 2].x;
    y = found[n_ok / 2].y;
    place_copy_patch(pl, pl->ex[e].full, x, y);
    for (i = 0; i < P * P; i++)
        pl->best_labels[i] = isnan(pl->target[i]);
    place_record(q, e, x, y);
    return place_merge(pl, q, e, x, y, index);
}

/* k candidates per exemplar, pooled in pl->cands (cand_ex: each one's
 * exemplar); *total: how many. */
static ts_status place_gather(placer *pl, const placement *q, int restrict_features, int *cand_ex,
                              int *total)
{
    int e, i;
    ts_status st;
    *total = 0;
    for (e = 0; e < pl->n_ex; e++) {
        int n = 0, only = place_region_exemplar(pl, q);
        if (only >= 0 && e != only)
            continue;
        ts__matcher_restrict(pl->ex[e].matcher, restrict_features);
        st = ts__place_search(pl, e, pl->cands + *total, &n);
        if (st != TS_OK)
            return st;
        for (i = 0; i < n; i++)
            cand_ex[*total + i] = e;
        *total += n;
    }
    if (*total == 0)
        return ts__fail(pl->ctx, TS_ERR_NUMERIC, "synth", "no exemplar window matches");
    return TS_OK;
}

/* Each candidate's window, its height and usage costs and the lower bound
 * of its cost (RMS of the SSD plus height costs); none is cut yet. */
static void place_cut_prepare(placer *pl, const placement *q, int total, int n_known,
                              const int *cand_ex, double *cost, ts_status *status)
{
    int P = pl->P, W = pl->out->width, i, x, y;
    double *lb = pl->cand_lb;
    for (i = 0; i < total; i++) {
        const ts_raster *exr = pl->ex[cand_ex[i]].full;
        float *win = pl->cand_patch + (size_t)i * (size_t)P * P;
        for (y = 0; y < P; y++)
            for (x = 0; x < P; x++)
                win[y * P + x] = TS_PIX(exr, pl->cands[i].x + x, pl->cands[i].y + y);
        pl->cand_h[i] = ts__height_cost(pl->p, W, q->x, q->y, P, win, P);
        pl->cand_u[i] = ts__place_usage_of(pl, &pl->ex[cand_ex[i]], pl->cands[i].x, pl->cands[i].y);
        lb[i] = sqrt(pl->cands[i].ssd / n_known + pl->cand_u[i]) + pl->cand_h[i];
        cost[i] = INFINITY;
        status[i] = TS_OK;
        pl->to_cut[i] = i;
    }
}

/* The n_first lowest bounds first in pl->to_cut (a partial selection sort:
 * ties by index, so the order is deterministic). */
static void place_cut_order(placer *pl, int total, int n_first)
{
    const double *lb = pl->cand_lb;
    int w;
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
}

/* Graph cut each candidate (in parallel); cost = RMS of the SSD + alpha_g
 * * mean mismatch across the seam + height costs.  The RMS of the SSD
 * plus the height costs is a lower bound of the cost, so after the most
 * promising candidates (one per thread) the others are cut only if that
 * bound is within (1 + variety) of the best cost so far: a candidate left
 * out could be neither the best nor in the variety pick, so the choice is
 * the same as cutting them all.  *best, *best_cost: the best so far. */
static ts_status place_cut_all(placer *pl, const placement *q, int total, int n_known,
                               const int *cand_ex, double *cost, ts_status *status, int *best,
                               double *best_cost)
{
    ts_ctx *ctx = pl->ctx;
    cut_job job;
    int n_first = TS_MIN(total, ts__thread_count(ctx, (size_t)total)), n_to_cut = 0, w, i;
    double *lb = pl->cand_lb;
    ts_status st;
    job.pl = pl;
    job.cand_ex = cand_ex;
    job.cost = cost;
    job.status = status;
    job.n_known = n_known;
    job.wx = q->x;
    job.wy = q->y;
    job.to_cut = pl->to_cut;
    place_cut_prepare(pl, q, total, n_known, cand_ex, cost, status);
    place_cut_order(pl, total, n_first);
    for (w = 0; w < 2; w++) {
        int from = w == 0 ? 0 : n_first, to = w == 0 ? n_first : total;
        if (w == 1) {
            /* keep only those that could still matter */
            for (i = n_first, n_to_cut = n_first; i < total; i++)
                if (lb[pl->to_cut[i]] <= *best_cost * (1.0 + pl->p->s.variety))
                    pl->to_cut[n_to_cut++] = pl->to_cut[i];
            to = n_to_cut;
        }
        if (to <= from)
            continue;
        job.to_cut = pl->to_cut + from;
        ts__parallel_for(ctx, (size_t)(to - from), place_cut_range, &job);
        if ((st = ts__check_cancel(ctx)) != TS_OK)
            return st;
        /* the best so far, lowest index on ties as when all are cut */
        *best_cost = INFINITY;
        for (i = 0; i < total; i++) {
            if (status[i] != TS_OK)
                return ts__fail(ctx, status[i], "synth", "graph cut failed for a candidate");
            if (cost[i] < *best_cost) {
                *best_cost = cost[i];
                *best = i;
            }
        }
    }
    return TS_OK;
}

/* Variety: a seeded pick among the candidates within (1 + variety) of the
 * best cost. */
static int place_variety(placer *pl, int total, const double *cost, double best_cost, int best)
{
    int n_ok = 0, pick, i;
    for (i = 0; i < total; i++)
        n_ok += cost[i] <= best_cost * (1.0 + pl->p->s.variety);
    pick = (int)(place_rand(pl) % (uint64_t)n_ok);
    for (i = 0; i < total; i++)
        if (cost[i] <= best_cost * (1.0 + pl->p->s.variety) && pick-- == 0) {
            best = i;
            break;
        }
    return best;
}

/* Place one patch at q: the first ever (nothing to match) is random. */
ts_status ts__place_one(placer *pl, placement *q, int index)
{
    ts_ctx *ctx = pl->ctx;
    int P = pl->P, n_known, total = 0, best = -1;
    int *cand_ex;
    double *cost, best_cost = INFINITY, t0 = 0;
    ts_status *status;
    ts_status st = TS_OK;
    /* away from the sketch's features, windows without main features */
    int restrict_features = pl->p->exemplar_features &&
                            !ts__place_flag(pl, q->x + P / 2, q->y + P / 2, TS__CELL_FEATURE);
    /* each placement's random stream depends only on the seed and its
     * index, so placements running side by side draw what they would alone */
    pl->rng = pl->rng0 ^ (0xd1b54a32d192ed03ull * (uint64_t)(index + 1));
    n_known = place_target(pl, q);
    place_seam_band(pl, q);
    pl->n_tknown[0] = n_known;
    cand_ex = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *cand_ex);
    cost = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *cost);
    status = ts__malloc_array((size_t)pl->n_ex * (size_t)pl->p->s.candidates, sizeof *status);
    if (!cand_ex || !cost || !status) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    if (n_known == 0) {
        st = place_start_patch(pl, q, index, restrict_features);
        goto done;
    }
    t0 = ts__now();
    if ((st = place_gather(pl, q, restrict_features, cand_ex, &total)) != TS_OK)
        goto done;
    if (pl->maps)
        place_tick(pl, &pl->sec[0], &t0);
    st = place_cut_all(pl, q, total, n_known, cand_ex, cost, status, &best, &best_cost);
    if (st != TS_OK)
        goto done;
    if (pl->p->s.variety > 0)
        best = place_variety(pl, total, cost, best_cost, best);
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
