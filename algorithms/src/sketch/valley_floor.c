/*
 * valley_floor.c - where and how high a drawn valley's floor runs (a
 * TerraSynth addition, for valley_breach.c): along the valley's own lowest
 * line near the drawn one (a least-cost path, Dijkstra), its heights made
 * never to rise towards the outlet at the least cost (the weighted L1
 * isotonic fit on the floor's tree, by mergeable heaps of breakpoints).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include <stdlib.h>
#include <string.h>

#include "valley_breach.h"

/* The floor's fit: how many metres cut one metre filled costs (a filled
 * floor is flat and its valley shallower, a cut keeps the valley's form). */
#define TS_FLOOR_FILL 8

/* The floor follows the valley's own thalweg (ours): the synthesis puts a
 * valley's lowest line a few cells off the drawn one, and a floor carved
 * along the drawn cells is perched above it (the land between a closed
 * depression the floor dams).  Within `w` cells of each network's drawn
 * cells (the cells nearest that network; no fixed, nodata or channel cell),
 * the least-cost path from every head (an end, or a cell another network's
 * channel comes into) to the network's outlet, a step costing its length x
 * (its height above the lowest land within w of it + kappa (1 + (d / w)^2),
 * d its distance from the drawn line: on the valley's bottom a step costs
 * about kappa, beside it more, a flat floor follows the line), replaces the
 * drawn cells as
 * the floor; a head the corridor does not join to its outlet keeps its drawn
 * way down.  Dijkstra with ties by cell index: one result.  0, -1 out of
 * memory. */
int ts__valley_thalweg(ts_ctx *ctx, breach *b, const ts_raster *out, double w, double kappa)
{
    size_t n = (size_t)b->W * (size_t)b->H, n0 = b->n, i, hn = 0;
    unsigned char *m = ts__calloc_array(n, 1), *head = ts__calloc_array(n0 + 1, 1);
    float *dist = ts__malloc_array(n, sizeof *dist), *low = NULL;
    int32_t *nearest = ts__malloc_array(n, sizeof *nearest), *lab = NULL, *par = NULL;
    int32_t *odown = ts__malloc_array(n0 + 1, sizeof *odown), *ocomp = NULL, *keep = NULL;
    size_t *ocell = ts__malloc_array(n0 + 1, sizeof *ocell);
    fl_item *h = NULL;
    int rc = -1;
    if (!m || !head || !dist || !nearest || !odown || !ocell ||
        !(ocomp = ts__malloc_array(n0 + 1, sizeof *ocomp)) ||
        !(low = ts__malloc_array(n, sizeof *low)) || !(lab = ts__malloc_array(n, sizeof *lab)) ||
        !(par = ts__malloc_array(n, sizeof *par)) || !(keep = ts__malloc_array(n, sizeof *keep)) ||
        !(h = ts__malloc_array(n + 1, sizeof *h)))
        goto done;
    for (i = 0; i < n0; i++) {
        ocell[i] = b->cell[i];
        odown[i] = b->down[i];
        ocomp[i] = b->comp[i];
        m[b->cell[i]] = b->comp[i] >= 0;
    }
    if (ts__distance_transform_nearest(ctx, m, b->W, b->H, dist, nearest) != TS_OK)
        goto done;
    for (i = 0; i < n; i++) {
        float z = TS_PIX(out, (int)(i % (size_t)b->W), (int)(i / (size_t)b->W));
        int32_t o = b->id[i];
        lab[i] = -1;
        par[i] = -1;
        keep[i] = -1; /* the kept cell's downstream grid cell, -2 its old one */
        if (nearest[i] < 0 || !(dist[i] <= w) || isnan(z) || (o >= 0 && b->comp[o] < 0) ||
            (b->flags && (b->flags[i] & (TS_CELL_FIXED | TS_CELL_NODATA))))
            continue;
        lab[i] = b->comp[b->id[nearest[i]]];
        low[i] = (float)(kappa * (dist[i] / w) * (dist[i] / w)); /* off the line: dearer */
        dist[i] = INFINITY;                                      /* from here on: the path's cost */
    }
    /* the lowest land within w of each corridor cell, less the step's price
     * for leaving the drawn line (so a flat floor follows the line) */
    for (i = 0; i < n; i++)
        if (lab[i] >= 0) {
            int x = (int)(i % (size_t)b->W), y = (int)(i / (size_t)b->W), u, v, r = (int)w;
            float lo = TS_PIX(out, x, y);
            for (v = TS_MAX(0, y - r); v <= TS_MIN(b->H - 1, y + r); v++)
                for (u = TS_MAX(0, x - r); u <= TS_MIN(b->W - 1, x + r); u++)
                    lo = fminf(lo, TS_PIX(out, u, v)); /* (fminf passes NaN by) */
            low[i] = lo - low[i];
        }
    /* heads: the ends, and the cells a channel or another outlet comes into;
     * every cell of a network without one (a ring) */
    for (i = 0; i < n0; i++) {
        int32_t d = b->down[i];
        if (b->comp[i] >= 0 && popcount8(b->adj[i]) <= 1)
            head[i] = 1;
        if (d >= 0 && b->comp[d] >= 0 && b->comp[d] != b->comp[i])
            head[d] = 1;
    }
    {
        unsigned char *has = ts__calloc_array((size_t)b->n_comp + 1, 1);
        if (!has)
            goto done;
        for (i = 0; i < n0; i++)
            if (head[i] && b->comp[i] >= 0)
                has[b->comp[i]] = 1;
        for (i = 0; i < n0; i++)
            if (b->comp[i] >= 0 && !has[b->comp[i]])
                head[i] = 1;
        free(has);
    }
    /* Dijkstra from every outlet, within its network's corridor */
    for (i = 0; i < n0; i++) {
        int32_t d = b->down[i];
        size_t g = b->cell[i];
        if (b->comp[i] < 0 || (d >= 0 && b->comp[d] == b->comp[i]))
            continue;
        head[i] = 0;
        keep[g] = -2; /* an outlet is kept, its way out as before */
        if (lab[g] == b->comp[i]) {
            fl_item it = {0.0f, (uint32_t)g, (int32_t)g};
            dist[g] = 0.0f;
            fl_push(h, &hn, it);
        }
    }
    while (hn) {
        fl_item it = fl_pop(h, &hn);
        int cx = (int)((size_t)it.cell % (size_t)b->W), cy = (int)((size_t)it.cell / (size_t)b->W);
        int d;
        if (it.level > dist[it.cell])
            continue;
        for (d = 0; d < 8; d++) {
            int nx = cx + BX[d], ny = cy + BY[d];
            size_t c;
            float cost;
            if (nx < 0 || ny < 0 || nx >= b->W || ny >= b->H)
                continue;
            c = (size_t)ny * (size_t)b->W + (size_t)nx;
            if (lab[c] != lab[it.cell])
                continue;
            cost = it.level + (float)((d & 1 ? 1.4142135623730951 : 1.0) *
                                      ((double)TS_PIX(out, nx, ny) - low[c] + kappa));
            if (cost < dist[c]) {
                fl_item nt = {cost, (uint32_t)c, (int32_t)c};
                dist[c] = cost;
                par[c] = it.cell;
                fl_push(h, &hn, nt);
            }
        }
    }
    /* the kept cells: each head's path, or its drawn way down (down to a kept
     * cell) where the corridor does not join it to the outlet */
    for (i = 0; i < n0; i++) {
        size_t g = b->cell[i];
        int32_t a = (int32_t)i;
        if (!head[i])
            continue;
        if (lab[g] >= 0 && isfinite(dist[g])) {
            for (; g != (size_t)-1 && keep[g] == -1; g = par[g] >= 0 ? (size_t)par[g] : (size_t)-1)
                keep[g] = par[g] >= 0 ? par[g] : -2;
            continue;
        }
        for (; a >= 0 && ocomp[a] >= 0 && keep[ocell[a]] == -1; a = odown[a])
            keep[ocell[a]] = -2;
    }
    /* per kept cell its network (lab) and its downstream grid cell (par) */
    for (i = 0; i < n; i++)
        if (keep[i] != -1) {
            int32_t o = b->id[i];
            if (o >= 0 && ocomp[o] >= 0)
                lab[i] = ocomp[o];
            par[i] = keep[i] >= 0              ? keep[i]
                     : o >= 0 && odown[o] >= 0 ? (int32_t)ocell[odown[o]]
                                               : -1;
        }
    /* the carve cells again: the kept floors (raster order), then the channels */
    for (i = 0; i < n0; i++)
        b->id[ocell[i]] = -1;
    b->n = 0;
    for (i = 0; i < n; i++)
        if (keep[i] != -1) {
            int32_t a = ts__breach_add(b, i);
            if (a < 0)
                goto done;
            b->comp[a] = lab[i];
        }
    for (i = 0; i < n0; i++)
        if (ocomp[i] < 0 && ts__breach_add(b, ocell[i]) < 0)
            goto done;
    for (i = 0; i < n; i++)
        if (keep[i] != -1)
            b->down[b->id[i]] = par[i] >= 0 ? b->id[par[i]] : -1;
    for (i = 0; i < n0; i++)
        if (ocomp[i] < 0)
            b->down[b->id[ocell[i]]] = odown[i] >= 0 ? b->id[ocell[odown[i]]] : -1;
    rc = 0;
done:
    free(m);
    free(head);
    free(dist);
    free(low);
    free(nearest);
    free(lab);
    free(par);
    free(odown);
    free(ocomp);
    free(ocell);
    free(keep);
    free(h);
    return rc;
}

/* A leftist min-heap of breakpoints, in a pool (the floor's fit below). */
typedef struct lh_pool {
    float *key;
    int32_t *left, *right, *rank;
    int32_t n;
} lh_pool;

static int32_t lh_merge(lh_pool *h, int32_t a, int32_t b)
{
    int32_t t;
    if (a < 0)
        return b;
    if (b < 0)
        return a;
    if (h->key[b] < h->key[a] || (h->key[b] == h->key[a] && b < a)) {
        t = a;
        a = b;
        b = t;
    }
    h->right[a] = lh_merge(h, h->right[a], b); /* depth: the right spines, O(log n) */
    if (h->left[a] < 0 || h->rank[h->left[a]] < h->rank[h->right[a]]) {
        t = h->left[a];
        h->left[a] = h->right[a];
        h->right[a] = t;
    }
    h->rank[a] = h->right[a] < 0 ? 1 : h->rank[h->right[a]] + 1;
    return a;
}

static int32_t lh_push(lh_pool *h, int32_t root, float key)
{
    int32_t c = h->n++;
    h->key[c] = key;
    h->left[c] = h->right[c] = -1;
    h->rank[c] = 1;
    return lh_merge(h, root, c);
}

/* The floor's heights (z per grid cell, the carve cells' heights on entry)
 * made never to rise downstream at the least cost (ours: the weighted L1
 * isotonic fit on the floor's tree; Lindsay 2016's choice between filling and
 * breaching, by its cost): a cell cut by d costs d, filled by d costs
 * TS_FLOOR_FILL d.  A wall across the valley is cut; a deep pit on the floor
 * (where two patches' floors meet, say) is filled rather than a trench dug
 * down the valley to its level.  Each cell's cost is convex in its height t,
 * slope -1 below z and TS_FLOOR_FILL above; for a cell's upstream tree,
 * min over s >= t of the cost is kept as the slopes' breakpoints in a
 * mergeable heap (the "slope trick"): a cell adds z 1 + TS_FLOOR_FILL times
 * and takes out the lowest breakpoint, its own best height; from the outlet
 * down every cell takes max(its downstream's height, its own best) (the
 * lowest optimum: ties cut rather than fill).  Fixed and nodata cells keep
 * their heights, the rest is then carved below them as before.  order: the
 * carve cells upstream first (n of them).  0, -1 out of memory. */
int ts__valley_fit_floor(const breach *b, const unsigned char *flags, const size_t *order, size_t n,
                         float *z)
{
    lh_pool h;
    int32_t *root = ts__malloc_array(b->n + 1, sizeof *root);
    float *best = ts__malloc_array(b->n + 1, sizeof *best), *fit = NULL;
    size_t k;
    int rc = -1;
    memset(&h, 0, sizeof h);
    if (!root || !best || !(fit = ts__malloc_array(b->n + 1, sizeof *fit)) ||
        !(h.key = ts__malloc_array((TS_FLOOR_FILL + 1) * b->n + 1, sizeof *h.key)) ||
        !(h.left = ts__malloc_array((TS_FLOOR_FILL + 1) * b->n + 1, sizeof *h.left)) ||
        !(h.right = ts__malloc_array((TS_FLOOR_FILL + 1) * b->n + 1, sizeof *h.right)) ||
        !(h.rank = ts__malloc_array((TS_FLOOR_FILL + 1) * b->n + 1, sizeof *h.rank)))
        goto done;
    for (k = 0; k < b->n; k++) {
        root[k] = -1;
        fit[k] = -INFINITY; /* (a cell below the order's cells: none in a tree) */
    }
    for (k = 0; k < n; k++) { /* upstream first: the cell's term joins its upstream's */
        int32_t c = (int32_t)order[k], d = b->down[c];
        float zc = z[b->cell[c]];
        best[c] = -INFINITY;
        if (!isnan(zc)) {
            /* a metre filled costs TS_FLOOR_FILL metres cut: the breakpoint z
             * 1 + TS_FLOOR_FILL times, the lowest breakpoint the cell's best */
            int j;
            for (j = 0; j <= TS_FLOOR_FILL; j++)
                root[c] = lh_push(&h, root[c], zc);
            best[c] = h.key[root[c]];
            root[c] = lh_merge(&h, h.left[root[c]], h.right[root[c]]);
        }
        if (d >= 0)
            root[d] = lh_merge(&h, root[d], root[c]);
    }
    for (k = n; k-- > 0;) { /* outlet first */
        int32_t c = (int32_t)order[k], d = b->down[c];
        fit[c] = d >= 0 ? fmaxf(fit[d], best[c]) : best[c];
    }
    for (k = 0; k < n; k++) {
        size_t g = b->cell[order[k]];
        if (!isnan(z[g]) && !(flags && (flags[g] & (TS_CELL_FIXED | TS_CELL_NODATA))) &&
            isfinite(fit[order[k]]))
            z[g] = fit[order[k]];
    }
    for (k = 0; k < n; k++) { /* below fixed cells, carved as before */
        int32_t c = (int32_t)order[k], d = b->down[c];
        size_t gc = b->cell[c], gd;
        if (d < 0)
            continue;
        gd = b->cell[d];
        if (!(flags && (flags[gd] & (TS_CELL_FIXED | TS_CELL_NODATA))) && !isnan(z[gc]) &&
            !isnan(z[gd]) && z[gc] < z[gd])
            z[gd] = z[gc];
    }
    rc = 0;
done:
    free(root);
    free(best);
    free(fit);
    free(h.key);
    free(h.left);
    free(h.right);
    free(h.rank);
    return rc;
}
