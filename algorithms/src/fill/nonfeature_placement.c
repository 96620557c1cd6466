/*
 * nonfeature_placement.c - non-feature patch placement (Zhou et al. 2007
 * section 4.2) with patch merging (section 5): fills the empty cells of an
 * output raster with exemplar patches.  This file runs over the placement
 * queue; candidate_search.c finds each position's candidates and
 * patch_placement.c places one patch.
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
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "nonfeature_placement.h"

typedef ts__placement placement;
typedef ts__placer placer;
typedef ts__exemplar_data exemplar_data;

static void place_count(const placer *pl, placement *q)
{
    int x, y, filled = 0, empty = 0;
    for (y = q->y; y < q->y + pl->P; y++)
        for (x = q->x; x < q->x + pl->P; x++) {
            if (!isnan(TS_PIX(pl->out, x, y)))
                filled++;
            else if (!(ts__place_flag(pl, x, y, TS_CELL_NODATA)))
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
            for (k = 1; k < TS__PLACE_MAX_LEVELS; k++)
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
        for (k = 1; k < TS__PLACE_MAX_LEVELS; k++) {
            free(pl->tlevel[k]);
            free(pl->tknown[k]);
        }
        for (k = 0; k < TS__PLACE_MAX_LEVELS; k++)
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
        j->status[i] = ts__place_one(j->slot[i], j->q[i], j->index + (int)i);
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
    for (i = 1; i < TS__PLACE_MAX_LEVELS; i++) {
        pl->tlevel[i] = ts__malloc_array(P2, sizeof(float));
        pl->tknown[i] = ts__malloc_array(P2, sizeof(int));
        failed |= !pl->tlevel[i] || !pl->tknown[i];
    }
    for (i = 0; i < TS__PLACE_MAX_LEVELS; i++)
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
    b->map_index0 = a->map_index0;
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

/* The first slot: the run's context, parameters, seed and work buffers;
 * returns non-zero when out of memory (pl->ex is NULL when that failed). */
static int placer_init(placer *pl, ts_ctx *ctx, const ts__fill *f, ts_raster *out,
                       ts_synth_maps *maps, int n_exemplars)
{
    const ts_synth_params *params = &f->s;
    pl->ctx = ctx;
    pl->p = f;
    pl->out = out;
    pl->flags = f->cell_flags;
    pl->maps = maps;
    pl->n_ex = n_exemplars;
    pl->P = (int)params->patch_size.value; /* whole cells: checked by place_validate */
    pl->rng0 = ts_ctx_seed(ctx) ^ 0x5eed5eed5eedull;
    pl->n_cands_cap = 2 * (3 * params->candidates * n_exemplars + 8);
    pl->ex = calloc((size_t)n_exemplars, sizeof *pl->ex);
    return placer_alloc_work(pl);
}

/* The maps of the cells empty on entry start with no source, order or
 * seam (cells filled on entry keep what an earlier stage recorded). */
static void place_clear_maps(ts_synth_maps *maps, const ts_raster *out)
{
    size_t n_out = (size_t)out->width * (size_t)out->height, k;
    for (k = 0; k < n_out; k++) {
        if (!isnan(
                out->data[(k / (size_t)out->width) * (size_t)out->stride + k % (size_t)out->width]))
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

/* Prepare every exemplar for the first slot (a size or numeric failure
 * names the exemplar). */
static ts_status place_prepare_all(placer *pl, const ts_raster *exemplars, int n_exemplars)
{
    ts_ctx *ctx = pl->ctx;
    ts_status st;
    int e;
    for (e = 0; e < n_exemplars; e++) {
        ts_progress_saved sv =
            ts__progress_push(ctx, 0.1 * e / n_exemplars, 0.1 * (e + 1) / n_exemplars);
        st = ts__place_prepare_exemplar(pl, &pl->ex[e], &exemplars[e], e);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK) {
            if (st == TS_ERR_SIZE || st == TS_ERR_NUMERIC)
                ts__fail_input(ctx, st, e, "synth", "exemplar %d: %s", e + 1,
                               strchr(ctx->message, ':') ? strchr(ctx->message, ':') + 2
                                                         : ctx->message);
            return st;
        }
    }
    return TS_OK;
}

/* The positions of the grid xs x ys, counted, none placed yet; returns
 * how many are needed. */
static int place_grid(const placer *pl, const int *xs, int nx, const int *ys, int ny,
                      placement *pos)
{
    int i, n_needed = 0;
    for (i = 0; i < nx * ny; i++) {
        pos[i].x = xs[i % nx];
        pos[i].y = ys[i / nx];
        pos[i].src_e = -1;
        pos[i].src_dx = pos[i].src_dy = 0;
        place_count(pl, &pos[i]);
        n_needed += pos[i].needed;
    }
    return n_needed;
}

/* The second slot of the grow order's pairs and the pair's private
 * single-thread contexts *ca and *cb. */
static ts_status place_pair_slots(placer *pl, placer *pl2, ts_ctx **ca, ts_ctx **cb)
{
    ts_ctx *ctx = pl->ctx;
    ts_progress_saved sv = ts__progress_push(ctx, 0.1, 0.1);
    ts_status st = placer_second(pl, pl2);
    ts__progress_pop(ctx, sv);
    if (st != TS_OK)
        return st;
    *ca = ts__ctx_child(ctx);
    *cb = ts__ctx_child(ctx);
    if (!*ca || !*cb)
        return ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
    ts_ctx_set_threads(*ca, 1);
    ts_ctx_set_threads(*cb, 1);
    return TS_OK;
}

/* The next position to place (-1: none left) and *pick2, a second one to
 * place beside it (-1: none). */
static int place_choose(const placer *pl, ts__pos_queue *q, const placement *pos, int n_pos,
                        const int *xs, int nx, const int *ys, int ny, int *pick2)
{
    int pick = -1, j;
    *pick2 = -1;
    if (pl->p->s.order == TS_ORDER_RASTER) { /* grow and tree: the same here */
        for (j = 0; j < n_pos; j++)          /* (a scan: raster order is for comparisons) */
            if (pos[j].needed) {
                pick = j;
                break;
            }
    } else {
        pick = place_pick(pl, q, xs, nx, ys, ny, -1);
        /* a second that grows from what is placed, nearly as well */
        if (pick >= 0 && pos[pick].overlap > 0) {
            *pick2 = place_pick(pl, q, xs, nx, ys, ny, pick);
            if (*pick2 >= 0 && 2 * pos[*pick2].overlap < pos[pick].overlap)
                *pick2 = -1;
        }
    }
    return pick;
}

/* Place qa and qb as patches index and index + 1 with slots pl and pl2:
 * side by side on the private contexts ca and cb when two threads are
 * free, else one after the other on the caller's. */
static ts_status place_pair(placer *pl, placer *pl2, ts_ctx *ca, ts_ctx *cb, placement *qa,
                            placement *qb, int index)
{
    ts_ctx *ctx = pl->ctx;
    pair_job pj;
    int side_by_side = ts__thread_count(ctx, 2) >= 2, j;
    ts_ctx *used[2];
    ts_status st = TS_OK;
    pj.slot[0] = pl;
    pj.slot[1] = pl2;
    pj.q[0] = qa;
    pj.q[1] = qb;
    pj.index = index;
    used[0] = side_by_side ? ca : ctx;
    used[1] = side_by_side ? cb : ctx;
    pl->ctx = used[0];
    pl2->ctx = used[1];
    if (side_by_side)
        ts__parallel_for(ctx, 2, place_pair_run, &pj);
    else
        place_pair_run(&pj, 0, 2);
    pl->ctx = ctx;
    pl2->ctx = ctx;
    for (j = 0; j < 2 && st == TS_OK; j++) {
        const char *msg = ts_ctx_message(used[j]);
        if (pj.status[j] == TS_OK)
            continue;
        /* a private context's message moves to the caller's */
        st = used[j] == ctx ? pj.status[j]
                            : ts__fail(ctx, pj.status[j], "synth", "%s",
                                       strchr(msg, ':') ? strchr(msg, ':') + 2 : msg);
    }
    return st;
}

/* After pos[pick] (and pos[pick2], when >= 0) are placed: the usage of
 * what was placed, and the maps' patch count (n_patches) and stage times. */
static void place_account(placer *pl, placer *pl2, ts_synth_maps *maps, const placement *pos,
                          int pick, int pick2, int n_patches)
{
    int i, n_run = pick2 < 0 ? 1 : 2;
    /* the usage of what was placed, after the pair (both placements
     * saw the same usage, whatever the thread count) */
    for (i = 0; i < n_run; i++) {
        const placement *w = &pos[i ? pick2 : pick];
        if (w->src_e >= 0 && pl->ex[w->src_e].usage)
            ts__place_usage_add(pl->ex[w->src_e].usage, pl->ex[w->src_e].K, w->x + w->src_dx,
                                w->y + w->src_dy);
    }
    if (maps) {
        maps->n_patches = n_patches;
        maps->seconds_match += pl->sec[0] + pl2->sec[0];
        maps->seconds_cut += pl->sec[1] + pl2->sec[1];
        maps->seconds_poisson += pl->sec[2] + pl2->sec[2];
    }
    memset(pl->sec, 0, sizeof pl->sec);
    memset(pl2->sec, 0, sizeof pl2->sec);
}

/* Windows that intersect the new patches at pos[pick] (and pos[pick2])
 * changed (found on the position grid, not by a scan of every position):
 * recount them and fix the queue; the placed positions are no longer
 * needed.  *n_needed follows. */
static void place_refresh(const placer *pl, ts__pos_queue *q, placement *pos, const int *xs, int nx,
                          const int *ys, int ny, int pick, int pick2, int *n_needed)
{
    int i, j, n_run = pick2 < 0 ? 1 : 2;
    for (i = 0; i < n_run; i++) {
        int w = i ? pick2 : pick, x0, x1, y0, y1, ix, iy;
        ts__axis_near(xs, nx, pos[w].x, pl->P, &x0, &x1);
        ts__axis_near(ys, ny, pos[w].y, pl->P, &y0, &y1);
        for (iy = y0; iy < y1; iy++)
            for (ix = x0; ix < x1; ix++) {
                j = ix + nx * iy;
                *n_needed -= pos[j].needed;
                place_count(pl, &pos[j]);
                *n_needed += pos[j].needed;
                ts__queue_fix(q, j);
            }
    }
    for (i = 0; i < n_run; i++) {
        int w = i ? pick2 : pick;
        *n_needed -= pos[w].needed;
        pos[w].needed = 0;
        ts__queue_fix(q, w);
    }
}

ts_status ts__fill_run(ts_ctx *ctx, const ts_raster *exemplars, int n_exemplars, const ts__fill *f,
                       ts_raster *out, ts_synth_maps *maps)
{
    const ts_synth_params *params = &f->s;
    placer pl, pl2;
    ts_ctx *ca = NULL, *cb = NULL;
    placement *pos = NULL;
    ts__pos_queue q;
    int *xs = NULL, *ys = NULL, nx, ny, n_pos, placed = 0, step, alloc_failed = 0;
    int n_needed = 0; /* positions still needed */
    double t_start = ts__now();
    int first_index = maps ? maps->n_patches : 0;
    ts_status st;

    if ((st = place_validate(ctx, exemplars, n_exemplars, params, out)) != TS_OK)
        return st;
    memset(&pl, 0, sizeof pl);
    memset(&pl2, 0, sizeof pl2);
    memset(&q, 0, sizeof q);
    alloc_failed = placer_init(&pl, ctx, f, out, maps, n_exemplars);
    /* a patch's random draws follow its place in this run, whatever the
     * maps count before it (the same terrain with and without maps) */
    pl.map_index0 = first_index;
    step = pl.P - (int)params->overlap.value;
    xs = ts__malloc_array((size_t)out->width / (size_t)step + 2, sizeof *xs);
    ys = ts__malloc_array((size_t)out->height / (size_t)step + 2, sizeof *ys);
    if (alloc_failed || !pl.ex || !xs || !ys) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "synth", "out of memory");
        goto done;
    }
    if (maps)
        place_clear_maps(maps, out);
    if ((st = place_prepare_all(&pl, exemplars, n_exemplars)) != TS_OK)
        goto done;
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
    n_needed = place_grid(&pl, xs, nx, ys, ny, pos);
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
    if (params->order != TS_ORDER_RASTER && (st = place_pair_slots(&pl, &pl2, &ca, &cb)) != TS_OK)
        goto done;
    for (;;) {
        int pick2, pick = place_choose(&pl, &q, pos, n_pos, xs, nx, ys, ny, &pick2);
        /* the stages inside report at the current fraction (they can still cancel) */
        double frac;
        ts_progress_saved sv;
        if (pick < 0)
            break;
        frac = 0.1 + 0.9 * (double)placed / (double)(placed + n_needed);
        sv = ts__progress_push(ctx, frac, frac);
        if (pick2 < 0)
            st = ts__place_one(&pl, &pos[pick], placed);
        else
            st = place_pair(&pl, &pl2, ca, cb, &pos[pick], &pos[pick2], placed);
        ts__progress_pop(ctx, sv);
        if (st != TS_OK)
            goto done;
        placed += pick2 < 0 ? 1 : 2;
        place_account(&pl, &pl2, maps, pos, pick, pick2, first_index + placed);
        place_refresh(&pl, &q, pos, xs, nx, ys, ny, pick, pick2, &n_needed);
        st = ts__progress(ctx, 0.1 + 0.9 * (double)placed / (double)(placed + n_needed),
                          "patch placement");
        if (st != TS_OK)
            goto done;
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
