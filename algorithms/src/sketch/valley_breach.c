/*
 * valley_breach.c - drawn valleys that drain (a TerraSynth addition): after
 * every stage that moves heights, the floor along each drawn valley is
 * carved so that it never rises on the way to its outlet, and the outlet
 * drains on: into another valley within a patch, or else out of the grid
 * (its edge, nodata, the user's water), by a channel along the least-cost
 * way (the land's own low ground, through the lowest, narrowest rim),
 * carved the same way.  The layout is given the channels beforehand
 * (ts__valley_outlets), so that it lays out a valley along them and the
 * carving has little left to cut.  The floor runs along the valley's own
 * lowest line near the drawn one, its heights fitted at
 * the least cost (a wall cut, a deep pit on the floor filled:
 * valley_floor.c); the change fades out across the valley.  A lake (water
 * cells) is an outlet as the edge is: never carved into, the land beside
 * it left at or above its level, and the land below its level that it
 * reaches raised to it (its arms: a valley ending in a lake never runs
 * below it).
 *
 * The valley cells of the feature graph make a graph of cells (consecutive
 * vertices joined).  In each network the outlet is the end cell that is
 * nearest the grid's edge or another network within a patch (ties: the
 * lowest, then the first in raster order); networks that reach the edge
 * are joined first, and a network never drains into one that drains into
 * it (its channel passes such a network by).  Breadth first from the
 * outlet every cell gets its downstream cell; then the floor moves onto the
 * thalweg and its heights are fitted.
 * Cost: O(valley cells + patch^2 per network end), and per network its
 * channel's search: O(c log c), c the cells cheaper to reach than its way.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "valley_breach.h"

/* The rounded foot of a cut's walls, cells */
#define TS_WALL_ROUND 2.0
/* How far the land's relief on a cut's walls is kept: below this scale
 * (cells, a Gaussian's sigma) the walls keep the land's own spurs and
 * gullies, above it they follow the wall */
#define TS_WALL_RELIEF 4.0

int32_t ts__breach_add(breach *b, size_t c)
{
    if (b->id[c] >= 0)
        return b->id[c];
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 1024;
        size_t *ncell = realloc(b->cell, nc * sizeof *ncell);
        unsigned char *nadj = ncell ? realloc(b->adj, nc) : NULL;
        int32_t *ncomp = nadj ? realloc(b->comp, nc * sizeof *ncomp) : NULL;
        int32_t *ndown = ncomp ? realloc(b->down, nc * sizeof *ndown) : NULL;
        if (ncell)
            b->cell = ncell;
        if (nadj)
            b->adj = nadj;
        if (ncomp)
            b->comp = ncomp;
        if (!ndown)
            return -1;
        b->down = ndown;
        b->cap = nc;
    }
    b->cell[b->n] = c;
    b->adj[b->n] = 0;
    b->comp[b->n] = -1;
    b->down[b->n] = -1;
    b->id[c] = (int32_t)b->n;
    return (int32_t)b->n++;
}

static int br_dir(int dx, int dy)
{
    int d;
    for (d = 0; d < 8; d++)
        if (BX[d] == dx && BY[d] == dy)
            return d;
    return -1;
}

/* The valley cells and their joins; networks labelled breadth first. */
static int br_build(breach *b, const ts_features *f)
{
    size_t k, j, i, *queue;
    for (k = 0; k < f->n_paths; k++) {
        const ts_feature_path *p = &f->paths[k];
        if (p->kind != TS_VALLEY)
            continue;
        for (j = 0; j < p->count; j++) {
            const ts_feature_vertex *v = &f->verts[p->first + j];
            int32_t a;
            if (v->x < 0 || v->y < 0 || v->x >= b->W || v->y >= b->H)
                continue;
            if ((a = ts__breach_add(b, (size_t)v->y * (size_t)b->W + (size_t)v->x)) < 0)
                return -1;
            if (j) {
                const ts_feature_vertex *u = v - 1;
                int d = br_dir(v->x - u->x, v->y - u->y);
                int32_t pu = b->id[(size_t)u->y * (size_t)b->W + (size_t)u->x];
                if (d >= 0 && pu >= 0) {
                    b->adj[pu] |= (unsigned char)(1u << d);
                    b->adj[a] |= (unsigned char)(1u << ((d + 4) % 8));
                }
            }
        }
    }
    if (!(queue = ts__malloc_array(b->n + 1, sizeof *queue)))
        return -1;
    for (i = 0; i < b->n; i++) {
        size_t head = 0, tail = 0;
        if (b->comp[i] >= 0)
            continue;
        b->comp[i] = b->n_comp;
        queue[tail++] = i;
        for (head = 0; head < tail; head++) {
            size_t c = b->cell[queue[head]];
            int d;
            for (d = 0; d < 8; d++)
                if (b->adj[queue[head]] & (1u << d)) {
                    int32_t o = b->id[(size_t)((long)c + BY[d] * (long)b->W + BX[d])];
                    if (o >= 0 && b->comp[o] < 0) {
                        b->comp[o] = b->n_comp;
                        queue[tail++] = (size_t)o;
                    }
                }
        }
        b->n_comp++;
    }
    free(queue);
    return 0;
}

/* Whether network k drains (on) into network own (or is it) */
static int br_drains_into(const int32_t *drains, int32_t k, int32_t own)
{
    for (; k >= 0 && k != own; k = drains[k])
        ;
    return k == own;
}

/* The network the water of carve cell o reaches: its own, or the one its
 * channel leads into; -2 out at the edge or a lake. */
static int32_t br_dest(const breach *b, int32_t o)
{
    while (o >= 0 && b->comp[o] < 0)
        o = b->down[o];
    return o >= 0 ? b->comp[o] : -2;
}

/* Where a channel of network own met carve cell o: 1 it ends there (the
 * water joins o's network or channel, *reached the network it drains to),
 * 0 it passes by (o is own's, or drains (on) into own: joining it would
 * make water run in a ring). */
static int br_meets(const breach *b, int32_t o, int32_t own, const int32_t *drains,
                    int32_t *reached)
{
    int32_t t = br_dest(b, o);
    if (b->comp[o] == own || br_drains_into(drains, t, own))
        return 0;
    *reached = t;
    return 1;
}

/* The nearest cell of a network other than `own` within a patch of carve
 * cell a (its carve cell, or -1), and the distance (INT_MAX when none). */
static int br_other(const breach *b, int32_t a, int32_t own, const int32_t *drains, int32_t *hit)
{
    size_t c = b->cell[a];
    int x = (int)(c % (size_t)b->W), y = (int)(c / (size_t)b->W), u, v, best = INT_MAX;
    *hit = -1;
    for (v = TS_MAX(0, y - b->P); v <= TS_MIN(b->H - 1, y + b->P); v++)
        for (u = TS_MAX(0, x - b->P); u <= TS_MIN(b->W - 1, x + b->P); u++) {
            int32_t o = b->id[(size_t)v * (size_t)b->W + (size_t)u];
            int d;
            if (o < 0 || b->comp[o] < 0 || b->comp[o] == own)
                continue;
            if (br_drains_into(drains, b->comp[o], own))
                continue; /* never into a network that drains (on) into this one */
            d = (int)ceil(hypot(u - x, v - y));
            if (d <= b->P && d < best) {
                best = d;
                *hit = o;
            }
        }
    return best;
}

/* The search a channel's way is found by (ours, after Lindsay 2016's
 * least-cost breaching): per grid cell its cost so far, the lowest height
 * of its way, the cell it came from and whether it is done; the cells
 * touched, to reset (then the way found, walked back); the heap, grown as
 * needed. */
typedef struct br_search {
    float *cost, *zmin;
    int32_t *from, *touched;
    unsigned char *done;
    size_t n_touched;
    fl_item *heap;
    size_t cap;
} br_search;

static int br_search_init(br_search *s, size_t n)
{
    memset(s, 0, sizeof *s);
    s->cost = ts__malloc_array(n, sizeof *s->cost);
    s->from = ts__malloc_array(n, sizeof *s->from);
    s->zmin = ts__malloc_array(n, sizeof *s->zmin);
    s->done = ts__calloc_array(n, 1);
    s->touched = ts__malloc_array(n, sizeof *s->touched);
    s->cap = TS_MIN(n + 1, (size_t)65536);
    s->heap = ts__malloc_array(s->cap, sizeof *s->heap);
    if (!s->cost || !s->zmin || !s->from || !s->done || !s->touched || !s->heap)
        return -1;
    for (size_t i = 0; i < n; i++)
        s->cost[i] = INFINITY;
    return 0;
}

static void br_search_free(br_search *s)
{
    free(s->cost);
    free(s->from);
    free(s->zmin);
    free(s->done);
    free(s->touched);
    free(s->heap);
}

/* Whether water leaving by grid cell g is out: the grid's edge, a cell
 * beside nodata, or the user's water. */
static int br_out(const breach *b, const ts_raster *out, size_t g)
{
    int x = (int)(g % (size_t)b->W), y = (int)(g / (size_t)b->W), d;
    if (x == 0 || y == 0 || x == b->W - 1 || y == b->H - 1 ||
        (b->flags && (b->flags[g] & TS_CELL_WATER)))
        return 1;
    for (d = 0; d < 8; d++)
        if (isnan(TS_PIX(out, x + BX[d], y + BY[d])))
            return 1;
    return 0;
}

/* The channel from carve cell a (ours): the least-cost way, a step costing
 * its length x (how far the land there stands above the lowest cell of the
 * way so far, which the floor may not rise above, + kappa), so that the
 * channel runs down the land's own low ground and cuts through the lowest,
 * narrowest rim, to the first carve cell br_meets takes (its water joins
 * that one; *reached the network it drains to) or, with `leave`, out
 * (br_out: *reached -2).  Dijkstra with ties by arrival: one result.
 * The way's new cells become carve cells chained downstream; a carve cell
 * it passes by is skipped.  Returns 1 a way found, 0 none, -1 out of memory. */
static int br_route(breach *b, br_search *s, const ts_raster *out, int32_t a, int leave,
                    double kappa, const int32_t *drains, int32_t *reached)
{
    size_t src = b->cell[a], hn = 0, k, np = 0;
    int found = leave && br_out(b, out, src); /* the outlet is out already */
    int32_t own = b->comp[a], prev = a, goal = -1;
    uint32_t order = 0;
    fl_item it = {0.0f, 0, (int32_t)src};
    *reached = -2;
    s->n_touched = 0;
    s->cost[src] = 0.0f;
    s->from[src] = -1;
    s->zmin[src] = TS_PIX(out, (int)(src % (size_t)b->W), (int)(src / (size_t)b->W));
    s->touched[s->n_touched++] = (int32_t)src;
    s->heap[hn++] = it;
    while (hn && goal < 0 && !found) {
        int cx, cy, d;
        it = fl_pop(s->heap, &hn);
        if (s->done[it.cell])
            continue;
        s->done[it.cell] = 1;
        if ((size_t)it.cell != src) {
            int32_t o = b->id[it.cell];
            if ((o >= 0 && br_meets(b, o, own, drains, reached)) ||
                (o < 0 && leave && br_out(b, out, (size_t)it.cell))) {
                goal = it.cell;
                break;
            }
        }
        cx = (int)((size_t)it.cell % (size_t)b->W);
        cy = (int)((size_t)it.cell / (size_t)b->W);
        for (d = 0; d < 8; d++) {
            int nx = cx + BX[d], ny = cy + BY[d];
            size_t c;
            double z, cost;
            if (nx < 0 || ny < 0 || nx >= b->W || ny >= b->H)
                continue;
            c = (size_t)ny * (size_t)b->W + (size_t)nx;
            z = TS_PIX(out, nx, ny);
            if (s->done[c] || isnan(z))
                continue;
            cost = s->cost[it.cell] +
                   ((d & 1) ? 1.4142135623730951 : 1.0) * (fmax(0.0, z - s->zmin[it.cell]) + kappa);
            if (cost >= s->cost[c])
                continue;
            if (isinf(s->cost[c]))
                s->touched[s->n_touched++] = (int32_t)c;
            s->cost[c] = (float)cost;
            s->from[c] = it.cell;
            s->zmin[c] = fminf(s->zmin[it.cell], (float)z);
            if (hn == s->cap) {
                fl_item *nh = realloc(s->heap, 2 * s->cap * sizeof *nh);
                if (!nh)
                    return -1;
                s->heap = nh;
                s->cap *= 2;
            }
            fl_push(s->heap, &hn, (fl_item){(float)cost, order++, (int32_t)c});
        }
    }
    found |= goal >= 0;
    for (k = 0; k < s->n_touched; k++) {
        s->cost[s->touched[k]] = INFINITY;
        s->done[s->touched[k]] = 0;
    }
    for (; goal >= 0 && (size_t)goal != src; goal = s->from[goal]) /* the way, walked back */
        s->touched[np++] = goal;
    while (np--) {
        size_t g = (size_t)s->touched[np];
        int32_t o = b->id[g];
        if (o >= 0) {
            if (np)
                continue;      /* a carve cell passed by */
            b->down[prev] = o; /* the one it joins */
            return 1;
        }
        if ((o = ts__breach_add(b, g)) < 0)
            return -1;
        b->down[prev] = o;
        prev = o;
    }
    return found;
}

typedef struct br_outlet {
    int32_t comp, cell, score;
} br_outlet;

static int br_outlet_cmp(const void *pa, const void *pb)
{
    const br_outlet *a = pa, *b = pb;
    if (a->score != b->score)
        return a->score < b->score ? -1 : 1;
    return (a->comp > b->comp) - (a->comp < b->comp);
}

/* Each network's outlet, its channel, and every cell's downstream cell. */
static int br_orient(breach *b, const ts_raster *out, br_search *s, double kappa)
{
    int32_t n_comp = b->n_comp, c, *drains = NULL;
    size_t i, n0 = b->n, *queue = NULL;
    br_outlet *o = ts__malloc_array((size_t)n_comp + 1, sizeof *o);
    int rc = -1;
    drains = ts__malloc_array((size_t)n_comp + 1, sizeof *drains);
    queue = ts__malloc_array(n0 + 1, sizeof *queue);
    if (!o || !drains || !queue)
        goto done;
    for (c = 0; c < n_comp; c++) {
        o[c].comp = c;
        o[c].cell = -1;
        o[c].score = INT_MAX;
        drains[c] = -1;
    }
    /* the outlet by the edge alone first (networks that reach it lead) */
    for (i = 0; i < n0; i++) {
        size_t g = b->cell[i];
        int x = (int)(g % (size_t)b->W), y = (int)(g / (size_t)b->W);
        int border = TS_MIN(TS_MIN(x, b->W - 1 - x), TS_MIN(y, b->H - 1 - y));
        if (b->wdist) /* a lake is an outlet as the edge is */
            border = TS_MIN(border, b->wdist[g]);
        int32_t k = b->comp[i];
        int end = popcount8(b->adj[i]) <= 1;
        float zi = TS_PIX(out, x, y);
        if (!end)
            border += b->W + b->H; /* an end cell whenever the network has one */
        if (o[k].cell < 0 || border < o[k].score ||
            (border == o[k].score && zi < TS_PIX(out, (int)(b->cell[o[k].cell] % (size_t)b->W),
                                                 (int)(b->cell[o[k].cell] / (size_t)b->W)))) {
            o[k].cell = (int32_t)i;
            o[k].score = border;
        }
    }
    qsort(o, (size_t)n_comp, sizeof *o, br_outlet_cmp);
    for (c = 0; c < n_comp; c++) {
        int32_t k = o[c].comp, a = o[c].cell, hit = -1, best_end = a;
        int border = o[c].score, other = INT_MAX;
        size_t j;
        /* an end within a patch of another network drains into it, unless
         * an end is nearer the edge */
        for (j = 0; j < n0; j++)
            if (b->comp[j] == k && popcount8(b->adj[j]) <= 1) {
                int32_t h;
                int d = br_other(b, (int32_t)j, k, drains, &h);
                if (d < other) {
                    other = d;
                    hit = h;
                    best_end = (int32_t)j;
                }
            }
        {
            /* into the valley within a patch (nearer than the edge), else
             * out; the least-cost way either (or out when no way joins) */
            int r = hit >= 0 && other < border
                        ? br_route(b, s, out, best_end, 0, kappa, drains, &drains[k])
                        : 0;
            if (r > 0)
                a = best_end;
            else if (r == 0 && br_route(b, s, out, a, 1, kappa, drains, &drains[k]) < 0)
                goto done;
            if (r < 0)
                goto done;
        }
        /* breadth first from the outlet: every cell's downstream cell */
        {
            size_t head, tail = 0;
            unsigned char *seen = ts__calloc_array(n0 + 1, 1);
            if (!seen)
                goto done;
            queue[tail++] = (size_t)a;
            seen[a] = 1;
            for (head = 0; head < tail; head++) {
                size_t g = b->cell[queue[head]];
                int d;
                for (d = 0; d < 8; d++)
                    if (b->adj[queue[head]] & (1u << d)) {
                        int32_t q = b->id[(size_t)((long)g + BY[d] * (long)b->W + BX[d])];
                        if (q >= 0 && (size_t)q < n0 && !seen[q]) {
                            seen[q] = 1;
                            b->down[q] = (int32_t)queue[head];
                            queue[tail++] = (size_t)q;
                        }
                    }
            }
            free(seen);
        }
    }
    rc = 0;
done:
    free(o);
    free(drains);
    free(queue);
    return rc;
}

/* The land's steep slope: the 95th percentile of the height difference
 * between neighbouring cells (central differences, at most about 65536
 * cells sampled); work: width * height floats. */
static double breach_steep(const ts_raster *out, float *work)
{
    int W = out->width, H = out->height, x, y;
    double cells = (double)W * (double)H;
    int step = cells > 65536.0 ? (int)ceil(sqrt(cells / 65536.0)) : 1;
    size_t k = 0;
    for (y = 1; y + 1 < H; y += step)
        for (x = 1; x + 1 < W; x += step) {
            double gx = 0.5 * ((double)TS_PIX(out, x + 1, y) - TS_PIX(out, x - 1, y));
            double gy = 0.5 * ((double)TS_PIX(out, x, y + 1) - TS_PIX(out, x, y - 1));
            double g = sqrt(gx * gx + gy * gy);
            if (!isnan(g))
                work[k++] = (float)g;
        }
    if (!k)
        return 1.0;
    ts__sort_floats(work, k);
    return fmax(1e-3, (double)work[(size_t)(0.95 * (double)(k - 1))]);
}

/* Steps (8-neighbour) from every cell to the nearest water cell, breadth
 * first; NULL when there is no water (or no memory: *fail). */
static int *br_water_distance(const unsigned char *flags, int W, int H, int *fail)
{
    size_t n = (size_t)W * (size_t)H, i, head = 0, tail = 0;
    int *d = NULL, k;
    size_t *q = NULL;
    *fail = 0;
    for (i = 0; flags && i < n && !(flags[i] & TS_CELL_WATER); i++)
        ;
    if (!flags || i == n)
        return NULL;
    d = ts__malloc_array(n, sizeof *d);
    q = ts__malloc_array(n, sizeof *q);
    if (!d || !q) {
        free(d);
        free(q);
        *fail = 1;
        return NULL;
    }
    for (i = 0; i < n; i++) {
        d[i] = INT_MAX;
        if (flags[i] & TS_CELL_WATER) {
            d[i] = 0;
            q[tail++] = i;
        }
    }
    for (head = 0; head < tail; head++) {
        int x = (int)(q[head] % (size_t)W), y = (int)(q[head] / (size_t)W);
        for (k = 0; k < 8; k++) {
            int nx = x + BX[k], ny = y + BY[k];
            size_t c;
            if (nx < 0 || ny < 0 || nx >= W || ny >= H)
                continue;
            c = (size_t)ny * (size_t)W + (size_t)nx;
            if (d[c] == INT_MAX) {
                d[c] = d[q[head]] + 1;
                q[tail++] = c;
            }
        }
    }
    free(q);
    return d;
}

/* The lowest a cell may be carved to: the highest water level beside it
 * (the land beside water ends at or above it, as water_banks.c leaves
 * it); -inf away from water. */
static float br_bank_floor(const ts_raster *out, const unsigned char *flags, size_t i)
{
    int x = (int)(i % (size_t)out->width), y = (int)(i / (size_t)out->width), k;
    float lo = -INFINITY;
    for (k = 0; flags && k < 8; k++) {
        int nx = x + BX[k], ny = y + BY[k];
        if (nx < 0 || ny < 0 || nx >= out->width || ny >= out->height)
            continue;
        if (flags[(size_t)ny * (size_t)out->width + (size_t)nx] & TS_CELL_WATER)
            lo = fmaxf(lo, TS_PIX(out, nx, ny));
    }
    return lo;
}

/* A lake floods the land below its level that it reaches (a cell beside it,
 * or beside land it floods): raised to the level, the lake's arm, so a
 * valley ending in a lake never runs below it (lowest lakes first).  0, or
 * -1 out of memory. */
static int br_lake_arms(ts_raster *out, const unsigned char *flags)
{
    int W = out->width, H = out->height, d;
    size_t n = (size_t)W * (size_t)H, c, hn = 0;
    unsigned char *seen = ts__calloc_array(n, 1);
    fl_item *h = ts__malloc_array(n + 1, sizeof *h);
    uint32_t order = 0;
    if (!seen || !h) {
        free(seen);
        free(h);
        return -1;
    }
    for (c = 0; c < n; c++) {
        seen[c] = (flags[c] & (TS_CELL_FIXED | TS_CELL_NODATA)) != 0;
        if (flags[c] & TS_CELL_WATER) {
            fl_item it = {TS_PIX(out, (int)(c % (size_t)W), (int)(c / (size_t)W)), order++,
                          (int32_t)c};
            fl_push(h, &hn, it);
        }
    }
    while (hn) {
        fl_item it = fl_pop(h, &hn);
        int cx = (int)((size_t)it.cell % (size_t)W), cy = (int)((size_t)it.cell / (size_t)W);
        for (d = 0; d < 8; d++) {
            int nx = cx + BX[d], ny = cy + BY[d];
            if (nx < 0 || ny < 0 || nx >= W || ny >= H)
                continue;
            c = (size_t)ny * (size_t)W + (size_t)nx;
            if (seen[c] || !(TS_PIX(out, nx, ny) <= it.level))
                continue; /* fixed, nodata, flooded already, or land above the lake */
            seen[c] = 1;
            TS_PIX(out, nx, ny) = it.level;
            {
                fl_item nt = {it.level, order++, (int32_t)c};
                fl_push(h, &hn, nt);
            }
        }
    }
    free(seen);
    free(h);
    return 0;
}

/* Beside the carved cells (m; delta their change), from the nearest one:
 * a cut lowers the land to at most the floor's height plus a wall rising
 * at the land's steep slope (s_ref a cell), or by the cut fading out over
 * rr, whichever is lower (a carved floor becomes a valley bottom, a cut
 * through a pass a gorge with the land's own walls: the walls are the
 * floor's height plus the distance, smooth across the valley even where
 * the cut's depth changes from one floor cell to the next); the walls'
 * lowering is blurred over TS_WALL_RELIEF, so that they keep the land's
 * spurs and gullies finer than that instead of a plane; a fill fades out over
 * rr or over as far as s_ref takes to climb it, whichever is wider, and
 * raises the land beside it up to the floor at most; within three
 * times that reach; then smoothed over a cell and a half so that no
 * step of the line's staircase shows */
static ts_status br_beside(ts_ctx *ctx, const breach *b, ts_raster *out, const unsigned char *flags,
                           const float *delta, const unsigned char *m, double rr, double s_ref)
{
    size_t n = (size_t)b->W * (size_t)b->H, i;
    float *spread = ts__malloc_array(n, sizeof *spread), *dist = ts__malloc_array(n, sizeof *dist);
    float *distb = ts__malloc_array(n, sizeof *distb), *wall = ts__malloc_array(n, sizeof *wall);
    float *wallb = ts__malloc_array(n, sizeof *wallb);
    int32_t *nearest = ts__malloc_array(n, sizeof *nearest);
    ts_status st = TS_OK;
    if (!spread || !dist || !distb || !wall || !wallb || !nearest) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    if ((st = ts__distance_transform_nearest(ctx, m, b->W, b->H, dist, nearest)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++) {
        size_t q = (size_t)nearest[i];
        double dq = nearest[i] >= 0 ? delta[q] : 0.0, d = dist[i];
        double r = fmax(rr, 1.5 * fabs(dq) / s_ref), t = d / r, tb = d / rr;
        spread[i] = wall[i] = m[i] ? delta[i] : 0.0f;
        if (m[i] || nearest[i] < 0 || t >= 3.0)
            continue;
        if (dq >= 0.0) {
            spread[i] = (float)(exp(-t * t) * dq);
        } else {
            /* a cut: down to the floor's own height plus a wall rising at
             * the steep slope (rounded over TS_WALL_ROUND cells at its foot),
             * never more than the floor was cut, or the bottom's fade,
             * whichever is lower */
            double g = d <= TS_WALL_ROUND ? s_ref * d * d / (2.0 * TS_WALL_ROUND)
                                          : s_ref * (d - 0.5 * TS_WALL_ROUND);
            double zf = TS_PIX(out, (int)(q % (size_t)b->W), (int)(q / (size_t)b->W));
            double z0 = TS_PIX(out, (int)(i % (size_t)b->W), (int)(i / (size_t)b->W));
            wall[i] = (float)fmax(dq, fmin(0.0, zf + g - z0));
            spread[i] = (float)(tb < 3.0 ? exp(-tb * tb) * dq : 0.0);
        }
    }
    if ((st = ts__blur_nan(ctx, spread, b->W, b->W, b->H, 1.5, distb)) != TS_OK ||
        (st = ts__blur_nan(ctx, wall, b->W, b->W, b->H, TS_WALL_RELIEF, wallb)) != TS_OK)
        goto done;
    for (i = 0; i < n; i++)
        if (!isnan(wallb[i]) && wallb[i] < 0.0f)
            distb[i] = isnan(distb[i]) ? wallb[i] : fminf(distb[i], wallb[i]);
    for (i = 0; i < n; i++) {
        int x = (int)(i % (size_t)b->W), y = (int)(i / (size_t)b->W);
        float z0 = TS_PIX(out, x, y), z;
        if (isnan(z0) || (flags && (flags[i] & (TS_CELL_FIXED | TS_CELL_NODATA))) || m[i] ||
            isnan(distb[i]))
            continue; /* the carved cells are set above */
        z = (float)(z0 + fmin(0.0, distb[i]));
        if (distb[i] > 0.0f && nearest[i] >= 0)
            z = fminf(z0 + distb[i], fmaxf(z0, TS_PIX(out, (int)((size_t)nearest[i] % (size_t)b->W),
                                                      (int)((size_t)nearest[i] / (size_t)b->W))));
        if (b->wdist && b->wdist[i] == 1) /* never below the water beside it */
            z = fmaxf(z, fminf(z0, br_bank_floor(out, flags, i)));
        TS_PIX(out, x, y) = z;
    }
done:
    free(spread);
    free(dist);
    free(distb);
    free(wall);
    free(wallb);
    free(nearest);
    return st;
}

/* b set up for the valleys of f on out: the water's distance, the carve
 * cells and their networks (b zeroed first; freed by br_free). */
static ts_status br_setup(ts_ctx *ctx, breach *b, const ts_features *f, const ts_raster *out,
                          const unsigned char *flags, int patch)
{
    size_t n = (size_t)out->width * (size_t)out->height, i;
    int fail;
    b->W = out->width;
    b->H = out->height;
    b->P = patch;
    b->flags = flags;
    b->wdist = br_water_distance(flags, b->W, b->H, &fail);
    if (fail || !(b->id = ts__malloc_array(n, sizeof *b->id)))
        return ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
    for (i = 0; i < n; i++)
        b->id[i] = -1;
    if (br_build(b, f) != 0)
        return ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
    return TS_OK;
}

static void br_free(breach *b)
{
    free(b->wdist);
    free(b->id);
    free(b->cell);
    free(b->adj);
    free(b->comp);
    free(b->down);
}

/* Appends to g the channel of carve cells ch[0..len) out of the network end
 * at carve cell a as a valley path from a's node to a new end node; 0, or
 * -1 out of memory (a without a node of its own: nothing appended). */
static int br_append_channel(ts_features *g, const breach *b, const ts_raster *out, int32_t a,
                             const int32_t *ch, size_t len)
{
    int ax = (int)(b->cell[a] % (size_t)b->W), ay = (int)(b->cell[a] / (size_t)b->W);
    size_t k, na = g->n_nodes;
    ts_feature_path *p;
    ts_feature_node *nd;
    ts_feature_vertex *v;
    for (k = 0; k < g->n_nodes; k++)
        if (g->nodes[k].kind == TS_VALLEY && g->nodes[k].x == ax && g->nodes[k].y == ay)
            break;
    if (k == g->n_nodes)
        return 0;
    if (!(nd = realloc(g->nodes, (g->n_nodes + 1) * sizeof *nd)))
        return -1;
    g->nodes = nd;
    if (!(p = realloc(g->paths, (g->n_paths + 1) * sizeof *p)))
        return -1;
    g->paths = p;
    if (!(v = realloc(g->verts, (g->n_verts + len + 1) * sizeof *v)))
        return -1;
    g->verts = v;
    g->nodes[k].degree++;
    p = &g->paths[g->n_paths++];
    memset(p, 0, sizeof *p);
    p->kind = TS_VALLEY;
    p->node_a = k;
    p->node_b = na;
    p->first = g->n_verts;
    p->count = len + 1;
    p->zmin = INFINITY;
    p->zmax = -INFINITY;
    for (k = 0; k <= len; k++) {
        size_t c = b->cell[k ? ch[k - 1] : a];
        ts_feature_vertex *w = &g->verts[g->n_verts++];
        w->x = (int)(c % (size_t)b->W);
        w->y = (int)(c / (size_t)b->W);
        w->z = TS_PIX(out, w->x, w->y);
        g->mask[c] |= TS_VALLEY;
        p->zmin = fminf(p->zmin, w->z);
        p->zmax = fmaxf(p->zmax, w->z);
        p->zmean += w->z / (float)(len + 1);
        if (k)
            p->length += hypot(w->x - w[-1].x, w->y - w[-1].y);
    }
    nd = &g->nodes[g->n_nodes++];
    memset(nd, 0, sizeof *nd);
    nd->x = g->verts[g->n_verts - 1].x;
    nd->y = g->verts[g->n_verts - 1].y;
    nd->z = g->verts[g->n_verts - 1].z;
    nd->degree = 1;
    nd->kind = TS_VALLEY;
    return 0;
}

/* A copy of f. */
static ts_features *br_copy_features(const ts_features *f)
{
    ts_features *g = calloc(1, sizeof *g);
    size_t n = (size_t)f->width * (size_t)f->height;
    if (!g)
        return NULL;
    *g = *f;
    g->mask = ts__malloc_array(n, 1);
    g->nodes = ts__malloc_array(f->n_nodes + 1, sizeof *g->nodes);
    g->paths = ts__malloc_array(f->n_paths + 1, sizeof *g->paths);
    g->verts = ts__malloc_array(f->n_verts + 1, sizeof *g->verts);
    if (!g->mask || !g->nodes || !g->paths || !g->verts) {
        ts_features_free(g);
        return NULL;
    }
    memcpy(g->mask, f->mask, n);
    if (f->n_nodes)
        memcpy(g->nodes, f->nodes, f->n_nodes * sizeof *g->nodes);
    if (f->n_paths)
        memcpy(g->paths, f->paths, f->n_paths * sizeof *g->paths);
    if (f->n_verts)
        memcpy(g->verts, f->verts, f->n_verts * sizeof *g->verts);
    return g;
}

/* b set up for f on out (br_setup) and each network's outlet and channel
 * found (br_orient, the search freed after it); work: width * height
 * floats for breach_steep, *s_ref the land's steep slope. */
static ts_status br_ways(ts_ctx *ctx, breach *b, const ts_features *f, const ts_raster *out,
                         const unsigned char *flags, int patch, float *work, double *s_ref)
{
    br_search srch;
    int rc;
    ts_status st = br_setup(ctx, b, f, out, flags, patch);
    if (st != TS_OK || !b->n)
        return st;
    *s_ref = breach_steep(out, work);
    rc = br_search_init(&srch, (size_t)out->width * (size_t)out->height) != 0 ||
         br_orient(b, out, &srch, 0.25 * *s_ref) != 0;
    br_search_free(&srch);
    return rc ? ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory") : TS_OK;
}

ts_status ts__valley_outlets(ts_ctx *ctx, const ts_features *f, const ts_raster *out,
                             const unsigned char *flags, int patch, ts_features **with)
{
    breach b;
    size_t n = (size_t)out->width * (size_t)out->height, i;
    float *work = NULL;
    int32_t *ch = NULL;
    unsigned char *taken = NULL;
    double s_ref;
    ts_status st = TS_OK;
    memset(&b, 0, sizeof b);
    *with = NULL;
    if (!f)
        return TS_OK;
    if (!(work = ts__malloc_array(n, sizeof *work))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    if ((st = br_ways(ctx, &b, f, out, flags, patch, work, &s_ref)) != TS_OK || !b.n)
        goto done;
    if (!(ch = ts__malloc_array(b.n + 1, sizeof *ch)) || !(taken = ts__calloc_array(b.n + 1, 1)) ||
        !(*with = br_copy_features(f))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    /* every outlet's channel, out of the grid or into another valley (up to
     * the cells of a channel taken already: it ends beside them) */
    for (i = 0; i < b.n; i++) { /* (a channel cell is no outlet: comp < 0) */
        int32_t j = b.down[i];
        size_t len = 0, k;
        if (b.comp[i] < 0 || j < 0 || b.comp[j] >= 0)
            continue;
        for (; j >= 0 && b.comp[j] < 0 && !taken[j]; j = b.down[j]) {
            if (flags && (flags[b.cell[j]] & (TS_CELL_FIXED | TS_CELL_NODATA)))
                break; /* the water or nodata it runs into is no valley */
            ch[len++] = j;
        }
        for (k = 0; k < len; k++)
            taken[ch[k]] = 1;
        if (len && br_append_channel(*with, &b, out, (int32_t)i, ch, len) != 0) {
            st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
            goto done;
        }
    }
done:
    if (st != TS_OK) {
        ts_features_free(*with);
        *with = NULL;
    }
    br_free(&b);
    free(work);
    free(ch);
    free(taken);
    return st;
}

ts_status ts__valley_breach(ts_ctx *ctx, const ts_features *f, ts_raster *out,
                            const unsigned char *flags, int patch, unsigned char *floor_out)
{
    breach b;
    size_t n = (size_t)out->width * (size_t)out->height, i, head, tail = 0;
    int32_t *indeg = NULL;
    size_t *queue = NULL;
    float *delta = NULL, *carved = NULL;
    unsigned char *m = NULL;
    ts_status st = TS_OK;
    double rr = patch / 8.0, s_ref;
    memset(&b, 0, sizeof b);
    if (!f)
        return TS_OK;
    if (!(delta = ts__malloc_array(n, sizeof *delta))) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    if ((st = br_ways(ctx, &b, f, out, flags, patch, delta, &s_ref)) != TS_OK || !b.n)
        goto done;
    if (ts__valley_thalweg(ctx, &b, out, fmax(2.0, patch / 10.0), 0.25 * s_ref) != 0) {
        st = ts_ctx_status(ctx) != TS_OK
                 ? ts_ctx_status(ctx)
                 : ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    if (floor_out)
        for (i = 0; i < b.n; i++)
            if (b.comp[i] >= 0)
                floor_out[b.cell[i]] = 1;
    indeg = ts__calloc_array(b.n, sizeof *indeg);
    queue = ts__malloc_array(b.n, sizeof *queue);
    carved = ts__malloc_array(n, sizeof *carved);
    m = ts__malloc_array(n, 1);
    if (!indeg || !queue || !delta || !carved || !m) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    /* carved upstream first (Kahn's order over the downstream links) */
    for (i = 0; i < n; i++)
        delta[i] = NAN;
    for (i = 0; i < b.n; i++) {
        size_t g = b.cell[i];
        delta[g] = TS_PIX(out, (int)(g % (size_t)b.W), (int)(g / (size_t)b.W));
        if (b.down[i] >= 0)
            indeg[b.down[i]]++;
    }
    for (i = 0; i < b.n; i++)
        if (!indeg[i])
            queue[tail++] = i;
    for (head = 0; head < tail; head++) {
        int32_t d = b.down[queue[head]];
        if (d >= 0 && --indeg[d] == 0)
            queue[tail++] = (size_t)d;
    }
    if (tail != b.n) { /* every way down ends: br_orient joins no ring */
        st = ts__fail(ctx, TS_ERR_INTERNAL, "valley breach",
                      "the drawn valleys' ways down make a ring");
        goto done;
    }
    if (ts__valley_fit_floor(&b, flags, queue, tail, delta) != 0) {
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
        goto done;
    }
    /* the change: exact on the carved cells, blurred and fading out beside
     * them (as the layout's valley floors) */
    for (i = 0; i < n; i++) {
        float z = TS_PIX(out, (int)(i % (size_t)b.W), (int)(i / (size_t)b.W));
        carved[i] = delta[i]; /* the carved heights themselves, set as they are */
        delta[i] = isnan(delta[i]) || isnan(z) ? NAN : delta[i] - z;
        m[i] = !isnan(delta[i]);
    }
    for (i = 0; i < n; i++)
        if (m[i]) {
            int x = (int)(i % (size_t)b.W), y = (int)(i / (size_t)b.W);
            if (!(flags && (flags[i] & (TS_CELL_FIXED | TS_CELL_NODATA))))
                TS_PIX(out, x, y) =
                    b.wdist && b.wdist[i] == 1 /* never below the water beside it */
                        ? fmaxf(carved[i], fminf(TS_PIX(out, x, y), br_bank_floor(out, flags, i)))
                        : carved[i];
        }
    st = br_beside(ctx, &b, out, flags, delta, m, rr, s_ref);
    if (st == TS_OK && b.wdist && br_lake_arms(out, flags) != 0)
        st = ts__fail(ctx, TS_ERR_NOMEM, "valley breach", "out of memory");
done:
    br_free(&b);
    free(indeg);
    free(queue);
    free(delta);
    free(carved);
    free(m);
    return st;
}
